#!/usr/bin/env python3
"""ohd against Mitsuba 3 (scalar_rgb, volpath) on the same scenes, intensity only, in one run:
paths/s of each (interleaved repeats, min/median/max), their ratio, and a z-score check that the
two agree on the transmittance of a normally incident pencil beam.

Scenes (lengths in mm, n = 1 everywhere, albedo 0.9, HG g = 0.7, at most 63 scattering events):
  slab     homogeneous slab, thickness 1, sigma_t = 2 /mm (tau = 2), laterally infinite
  grid16   1 mm cube of a random density (seeded numpy, uniform [0, 1)) on 16^3 voxels plus a
           border of empty voxels, sigma_t = 4 /mm x density, in clear space
  grid64   the same on 64^3 voxels

The estimated quantity is the total transmittance T (unscattered + diffuse) of a pencil beam
entering the top face at its centre, along +z:
  ohd      forward packets from a pencil source, `estimates.transmittance_total` (weight crossing
           the plane z = 1 mm downward; the cube sits in a clear layer 1 mm thick).
  Mitsuba  by reciprocity: a `radiancemeter` shooting the same ray (+z through the same point) into
           the scene lit by an environment map of radiance 1 on the lower hemisphere (directions
           with z > 0) and 0 above. The radiance it measures is the weight of every path that
           leaves toward z > 0, i.e. the same T. volpath's next-event estimation and MIS change its
           variance, not its expectation. See README.md for the depth cap and roulette.

Usage: python3 validation/peers/run.py [--repeats R] [--mitsuba-paths N] [--ohd-paths N] [--scenes LIST] [--seed S] [--binary PATH]
Runs --binary PATH, else builds ohd (cargo build --release). Installs mitsuba==3.9.1 and numpy into
validation/.venv (validation/ohdpy.py: python3 -m venv on first use) and re-runs itself there; the .vdb files are written by Debian's python3-openvdb (/usr/bin/python3).
"""
import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.dirname(HERE))
import ohdpy  # noqa: E402

MITSUBA_VERSION = "3.9.1"  # drjit 1.5.0 comes with it


ALBEDO, G, MAX_DEPTH = 0.9, 0.7, 64
L = 1.0  # mm: cube side and slab thickness
SLAB_SIGMA_T = 2.0  # /mm
GRID_SIGMA_T = 4.0  # /mm at density 1


def density_grid(n, seed):
    """n^3 uniform random densities with a border of zeros: (n+2)^3 values, indexed [x, y, z]."""
    import numpy as np

    d = np.zeros((n + 2,) * 3, dtype=np.float32)
    d[1:-1, 1:-1, 1:-1] = np.random.default_rng(seed).random((n,) * 3, dtype=np.float32)
    return d


# ----------------------------------------------------------------------------------------------
# ohd
# ----------------------------------------------------------------------------------------------

def ohd_config(name, sigma_t, density_line):
    return f"""schema_version = 1
name = "{name}"

[run]
samples = 1_000_000
seed = 1
batches = 32
max_scattering_events = {MAX_DEPTH}

[source]
wavelength_nm = 633
profile = "pencil"
position_mm = [0, 0, 0]
direction = [0, 0, 1]

[ambient]
n_above = 1.0
n_below = 1.0

[media.m]
sigma_s_per_mm = {ALBEDO * sigma_t!r}
sigma_a_per_mm = {(1 - ALBEDO) * sigma_t!r}
phase = {{ type = "hg", g = {G} }}
{density_line}

[[layers]]
name = "slab"
thickness_mm = {L}
n = 1.0
medium = "m"
"""


def ensure_pyopenvdb():
    """Install Debian's python3-openvdb (for the system interpreter) if it is missing."""
    probe = subprocess.run(["/usr/bin/python3", "-c", "import pyopenvdb"], capture_output=True)
    if probe.returncode != 0:
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        subprocess.run(["apt-get", "update", "-qq"], check=True, env=env)
        subprocess.run(["apt-get", "install", "-y", "-qq", "python3-openvdb"], check=True, env=env)


def write_ohd_scene(tmp, name, grid):
    """Write the experiment file (and for a grid its .vdb); return the file's path."""
    import numpy as np

    if grid is None:
        text = ohd_config(name, SLAB_SIGMA_T, "")
    else:
        h = L / grid.shape[0]
        np.save(os.path.join(tmp, f"{name}.npy"), grid)
        ensure_pyopenvdb()
        subprocess.run(["/usr/bin/python3", os.path.join(HERE, "write_vdb.py"), os.path.join(tmp, f"{name}.npy"),
                        os.path.join(tmp, f"{name}.vdb"), repr(h)], check=True)
        # Index i of the file sits at i*h mm; Mitsuba puts voxel i's value at its centre, (i + 1/2) h
        # from the cube's corner (-L/2, -L/2, 0).
        t = [-L / 2 + h / 2, -L / 2 + h / 2, h / 2]
        text = ohd_config(name, GRID_SIGMA_T, f'density = {{ type = "vdb", file = "{name}.vdb", grid = "density", '
                                              f'scale = 1e-3, translate_mm = {t!r} }}')
    path = os.path.join(tmp, f"{name}.toml")
    with open(path, "w") as f:
        f.write(text)
    return path


def run_ohd(binary, config, paths, seed, out):
    """One ohd run: (transport seconds as ohd measures them, whole-process seconds, estimates)."""
    t0 = time.perf_counter()
    subprocess.run([binary, "run", config, "--samples", str(paths), "--seed", str(seed), "--threads", "1",
                    "--out", out, "--quiet"], check=True, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    with open(os.path.join(out, "manifest.json")) as f:
        m = json.load(f)
    return m["wall_seconds"], wall, m["estimates"]


# ----------------------------------------------------------------------------------------------
# Mitsuba
# ----------------------------------------------------------------------------------------------

def mitsuba_scene(mi, grid):
    import numpy as np

    T = mi.ScalarTransform4f
    hg = {"type": "hg", "g": G}
    if grid is None:
        medium = {"type": "homogeneous", "albedo": ALBEDO, "sigma_t": SLAB_SIGMA_T, "phase": hg}
        # 40 mm wide: at sigma_t = 2 /mm (absorption 0.2 /mm) nothing reaches the sides, and
        # single-precision positions stay fine.
        shape_to_world = T().translate([0, 0, L / 2]).scale([20.0, 20.0, L / 2])
    else:
        zyx = np.ascontiguousarray(grid.transpose(2, 1, 0))  # Mitsuba's grids are indexed [z, y, x]
        medium = {"type": "heterogeneous", "albedo": ALBEDO, "scale": GRID_SIGMA_T, "phase": hg,
                  "sigma_t": {"type": "gridvolume", "grid": mi.VolumeGrid(zyx), "filter_type": "trilinear",
                              "to_world": T().translate([-L / 2, -L / 2, 0]).scale(L)}}
        shape_to_world = T().translate([0, 0, L / 2]).scale(L / 2)
    # Radiance 1 from the lower hemisphere: a ray leaving toward z > 0 (transmitted) sees 1. The
    # lat-long map's poles (its +y axis) are turned to +x, off the beam axis; then z > 0 is the
    # middle half of the columns (longitudes 90°-270°). (Mitsuba still returns a NaN sample now
    # and then with this envmap and an HG phase function: see README.md and main().)
    env = np.zeros((8, 8192, 3), dtype=np.float32)
    env[:, 2048:6144] = 1.0
    return mi.load_dict({
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": MAX_DEPTH, "rr_depth": 100_000},
        "sensor": {"type": "radiancemeter", "origin": [0.0, 0.0, -0.5], "direction": [0.0, 0.0, 1.0],
                   "film": {"type": "hdrfilm", "width": 1, "height": 1, "pixel_format": "rgb",
                            "rfilter": {"type": "box"}},
                   "sampler": {"type": "independent", "sample_count": 1}},
        "sky": {"type": "envmap", "bitmap": mi.Bitmap(env), "to_world": T().rotate([0, 0, 1], -90)},
        "volume": {"type": "cube", "bsdf": {"type": "null"}, "interior": medium, "to_world": shape_to_world},
    })


def run_mitsuba(mi, scene, paths, batches, seed):
    """`batches` renders of paths/batches samples each; returns (seconds, [batch means])."""
    import numpy as np

    spp = paths // batches
    means = []
    t0 = time.perf_counter()
    for b in range(batches):
        img = mi.render(scene, spp=spp, seed=seed * 1000 + b)
        means.append(float(np.mean(np.array(img)[0, 0, :3])))
    return time.perf_counter() - t0, means


def check_mitsuba_grid(mi, grid):
    """Mitsuba's gridvolume against the field ohd reads from the .vdb (trilinear between voxel
    centres, zero in the empty border): the largest difference at random points in the cube."""
    import numpy as np

    vol = mi.load_dict({"type": "gridvolume", "grid": mi.VolumeGrid(np.ascontiguousarray(grid.transpose(2, 1, 0))),
                        "to_world": mi.ScalarTransform4f().translate([-L / 2, -L / 2, 0]).scale(L)})
    rng = np.random.default_rng(7)
    h = L / grid.shape[0]
    worst = 0.0
    for p in rng.random((200, 3)):
        x = np.array([-L / 2, -L / 2, 0]) + p * L
        it = mi.Interaction3f()
        it.p = mi.Point3f(*x)
        got = float(vol.eval_1(it))
        u = (x - np.array([-L / 2, -L / 2, 0])) / h - 0.5  # continuous index
        i0 = np.clip(np.floor(u).astype(int), 0, grid.shape[0] - 2)
        f = np.clip(u - i0, 0, 1)
        c = grid[i0[0]:i0[0] + 2, i0[1]:i0[1] + 2, i0[2]:i0[2] + 2].astype(float)
        c = c[0] * (1 - f[0]) + c[1] * f[0]
        c = c[0] * (1 - f[1]) + c[1] * f[1]
        want = c[0] * (1 - f[2]) + c[1] * f[2]
        worst = max(worst, abs(got - want))
    return worst


# ----------------------------------------------------------------------------------------------

def pooled(values_and_errors):
    """Mean of equal-size independent estimates and its standard error."""
    v = [x for x, _ in values_and_errors]
    se = math.sqrt(sum(e * e for _, e in values_and_errors)) / len(v)
    return sum(v) / len(v), se


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--mitsuba-paths", type=int, default=400_000, help="paths per Mitsuba run (16 renders)")
    ap.add_argument("--ohd-paths", type=int, default=4_000_000, help="paths per ohd run")
    ap.add_argument("--scenes", default="slab,grid16,grid64")
    ap.add_argument("--seed", type=int, default=1, help="repeat r uses seed + r (ohd) and (seed + r)·1000 + batch (Mitsuba)")
    ohdpy.add_binary_argument(ap)
    args = ap.parse_args()
    ohdpy.use_venv(f"mitsuba=={MITSUBA_VERSION}", "numpy")
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    mi.set_variant("scalar_rgb")
    dr.set_thread_count(1)
    binary = ohdpy.binary(args.binary)

    rows = []
    with tempfile.TemporaryDirectory(prefix="ohd-peers-") as tmp:
        for name in args.scenes.split(","):
            grid = None if name == "slab" else density_grid(int(name[4:]), seed=int(name[4:]))
            if grid is not None:
                err = check_mitsuba_grid(mi, grid)
                assert err < 1e-5, f"{name}: Mitsuba's grid differs from the trilinear field by {err}"
            config = write_ohd_scene(tmp, name, grid)
            scene = mitsuba_scene(mi, grid)
            run_mitsuba(mi, scene, 1600, 16, 999)  # warm-up outside the timing
            o_t, o_proc, m_t, o_est, m_means, unscat = [], [], [], [], [], []
            for r in range(args.repeats):  # interleaved: ohd, Mitsuba, ohd, Mitsuba, ...
                t, wall, e = run_ohd(binary, config, args.ohd_paths, args.seed + r, os.path.join(tmp, f"{name}_{r}"))
                o_t.append(t)
                o_proc.append(wall)
                o_est.append((e["transmittance_total"]["value"], e["transmittance_total"]["stderr"]))
                unscat.append((e["transmittance_unscattered"]["value"], e["transmittance_unscattered"]["stderr"]))
                t, means = run_mitsuba(mi, scene, args.mitsuba_paths, 16, args.seed + r)
                m_t.append(t)
                m_means.extend(means)
            o_val, o_se = pooled(o_est)
            # A non-finite render (Mitsuba warns "Invalid sample value") would poison the mean: such
            # batches are dropped and counted.
            dropped = sum(not math.isfinite(v) for v in m_means)
            m_means = [v for v in m_means if math.isfinite(v)]
            m_val = float(np.mean(m_means))
            m_se = float(np.std(m_means, ddof=1) / math.sqrt(len(m_means)))
            z = (o_val - m_val) / math.hypot(o_se, m_se)
            # Seconds to a 1 % relative standard error, from all runs of each code together.
            o_1pct = sum(o_t) * (o_se / (0.01 * o_val)) ** 2
            m_1pct = sum(m_t) * (m_se / (0.01 * m_val)) ** 2
            rows.append(dict(name=name, o_t=o_t, o_proc=o_proc, m_t=m_t, o_val=o_val, o_se=o_se, m_val=m_val, m_se=m_se, z=z,
                             o_1pct=o_1pct, m_1pct=m_1pct, dropped=dropped, unscat=pooled(unscat)))
            print(f"{name}: done", file=sys.stderr)

    n_o, n_m = args.ohd_paths, args.mitsuba_paths
    rate = lambda n, ts: (n / max(ts), n / statistics.median(ts), n / min(ts))  # noqa: E731
    print(f"Mitsuba {mi.__version__} scalar_rgb volpath vs ohd, 1 thread each; {args.repeats} interleaved repeats; "
          f"paths per run: ohd {n_o:,}, Mitsuba {n_m:,}")
    print()
    print("| scene | ohd paths/s (min / median / max) | Mitsuba paths/s (min / median / max) | ratio (median) "
          "| ratio, ohd whole process | ohd T | Mitsuba T | z | s to 1 % ohd / Mitsuba |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        o, m, p = rate(n_o, r["o_t"]), rate(n_m, r["m_t"]), rate(n_o, r["o_proc"])
        print(f"| {r['name']} | {o[0]:,.0f} / {o[1]:,.0f} / {o[2]:,.0f} | {m[0]:,.0f} / {m[1]:,.0f} / {m[2]:,.0f} "
              f"| {o[1] / m[1]:.1f}× | {p[1] / m[1]:.1f}× | {r['o_val']:.5f} ± {r['o_se']:.5f} | {r['m_val']:.5f} ± {r['m_se']:.5f} "
              f"| {r['z']:+.2f} | {r['o_1pct']:.3g} / {r['m_1pct']:.3g} |")
    for r in rows:
        if r["name"] == "slab":
            u, se = r["unscat"]
            ref = math.exp(-SLAB_SIGMA_T * L)
            print(f"\nslab, unscattered T: ohd {u:.5f} ± {se:.5f}, e^-2 = {ref:.5f} (z = {(u - ref) / se:+.2f})")
    for r in rows:
        if r["dropped"]:
            print(f"{r['name']}: {r['dropped']} Mitsuba batches dropped (non-finite)")
    bad = [r["name"] for r in rows if not abs(r["z"]) <= 3]
    print("agreement: " + ("all |z| ≤ 3" if not bad else f"|z| > 3 for {', '.join(bad)}"))


if __name__ == "__main__":
    main()
