#!/usr/bin/env python3
"""Issue 7, "leave out what a scene does not need — measured": each feature against the same scene
without it, one thread, run interleaved (A B C A B C …) so that every variant sees the same machine
load; and the bare random walk (examples/bare_walk.rs) against ohd on the van de Hulst slab.

    python3 validation/features/run.py                 # build once, 5 rounds, markdown tables on stdout
    python3 validation/features/run.py --rounds 9 --callgrind --markdown out.md

Per variant: whole-process wall (min / median / max, s), ohd's own transport time (the manifest's
`wall_seconds`, median), the ratio of medians to the group's first variant, scattering events and
the peak resident memory of the process (GNU time's max RSS, when /usr/bin/time exists). With --callgrind every variant also
runs once under callgrind (fewer paths, one thread) and the instructions inside the batch loop
(`--toggle-collect=*run_batch*`: transport and tallies, without start-up and output) are compared:
the repeatable figure on a noisy machine. Measures --binary PATH as ohd, else builds it; the bare walk
is always built from this tree (cargo); --callgrind needs valgrind.
"""

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(ROOT / "validation"))
import ohdpy  # noqa: E402

# (group, [(label, config, extra --set values)], paths per run, paths under callgrind)
GROUPS = [
    (
        "velocity field (vdH slab)",
        [
            ("absent", "vdh_plain.toml", []),
            ("present, zero (uniform 0)", "vdh_velocity_zero.toml", []),
            ("present, moving (uniform 1 mm/s): feature used", "vdh_velocity_moving.toml", []),
        ],
        2_000_000,
        100_000,
    ),
    (
        "velocity field (default vessel scene)",
        [
            ("Poiseuille v_max = 0", "../../configs/default.toml", ["media.blood.velocity.v_max_mm_per_s=0"]),
            ("Poiseuille v_max = 34 mm/s (as shipped): feature used", "../../configs/default.toml", []),
        ],
        50_000,
        5_000,
    ),
    (
        "density (vdH slab)",
        [
            ("homogeneous", "vdh_plain.toml", []),
            ("constant ramp (1 → 1)", "vdh_density_ramp_constant.toml", []),
            ("constant VDB grid (constant.vdb, 0.7)", "vdh_density_vdb_constant.toml", []),
        ],
        2_000_000,
        100_000,
    ),
    (
        "chirp (vdH slab with a spectrum detector)",
        [
            ("no chirp", "vdh_spectrum.toml", []),
            ("chirp: feature used", "vdh_spectrum_chirp.toml", []),
        ],
        2_000_000,
        100_000,
    ),
    (
        "chirp (FMCW hard target, next-event receiver)",
        [
            ("no chirp", "fmcw_target_no_chirp.toml", []),
            ("chirp (configs/fmcw_target.toml): feature used", "../../configs/fmcw_target.toml", []),
        ],
        200_000,
        20_000,
    ),
    (
        "time axis (vdH slab with a spectrum detector)",
        [
            ("no time axis", "vdh_spectrum.toml", []),
            (
                "TPSF, 100 bins over 0–0.05 ns: feature used",
                "vdh_spectrum.toml",
                ["detectors.0.time.t_min_ns=0", "detectors.0.time.t_max_ns=0.05", "detectors.0.time.bins=100"],
            ),
        ],
        2_000_000,
        100_000,
    ),
    (
        "correlation (DCS semi-infinite, ring at 10 mm)",
        [
            ("power only", "dcs_semi_infinite.toml", []),
            (
                "g1, g2, K (41 delays, 5 exposures): feature used",
                "dcs_semi_infinite.toml",
                [
                    "detectors.0.correlation.tau_min_s=1e-7",
                    "detectors.0.correlation.tau_max_s=1e-2",
                    "detectors.0.correlation.points=41",
                    "detectors.0.correlation.exposures_s=[1e-6, 1e-5, 1e-4, 1e-3, 1e-2]",
                ],
            ),
        ],
        1_000_000,
        50_000,
    ),
    (
        "speckle contrast per pixel (uniform field, 16 × 16 camera)",
        [
            ("intensity image only", "lsci_camera.toml", []),
            (
                "K of the camera (41 delays, 4 exposures)",
                "lsci_camera.toml",
                [
                    "detectors.0.correlation.tau_min_s=1e-7",
                    "detectors.0.correlation.tau_max_s=1e-2",
                    "detectors.0.correlation.points=41",
                    "detectors.0.correlation.exposures_s=[1e-5, 1e-4, 1e-3, 1e-2]",
                ],
            ),
            (
                "K per pixel too: feature used",
                "lsci_camera.toml",
                [
                    "detectors.0.correlation.tau_min_s=1e-7",
                    "detectors.0.correlation.tau_max_s=1e-2",
                    "detectors.0.correlation.points=41",
                    "detectors.0.correlation.exposures_s=[1e-5, 1e-4, 1e-3, 1e-2]",
                ] + ["detectors.0.correlation.pixels=true"],
            ),
        ],
        500_000,
        25_000,
    ),
    (
        "LDH camera (retina scene, 128² pixels)",
        [
            ("M0± images only", "ldh_m0_only.toml", []),
            ("+ M1, classes, ROI spectra, per-pixel spectra: feature used", "ldh_full_spectra.toml", []),
        ],
        100_000,
        10_000,
    ),
    (
        "lateral bounds (vdH slab)",
        [
            ("no [lateral]", "vdh_plain.toml", []),
            ("[lateral] 1 m wide, faces never reached: feature used", "vdh_lateral.toml", []),
            ("[lateral] ±0.5 mm, n_outside = 1.4: faces reached", "vdh_lateral.toml", ["lateral.x_mm=[-0.5, 0.5]", "lateral.y_mm=[-0.5, 0.5]", "lateral.n_outside=1.4"]),
        ],
        2_000_000,
        100_000,
    ),
    (
        "volume tally (vdH slab, 40 × 40 × 20 voxels)",
        [
            ("no [volume]", "vdh_plain.toml", []),
            ("[volume], track-length fluence: feature used", "vdh_volume.toml", []),
            ("[volume], both fluence estimators", "vdh_volume.toml", ["volume.fluence=\"both\""]),
            (
                "[volume] + [volume.time], 20 bins over 0–10 ps",
                "vdh_volume.toml",
                ["volume.time.t_min_ns=0", "volume.time.t_max_ns=0.01", "volume.time.bins=20"],
            ),
        ],
        2_000_000,
        100_000,
    ),
    (
        "time gate (vdH slab)",
        [
            ("no gate", "vdh_plain.toml", []),
            ("run.time_gate_ns = [0, 1e6] (path length tracked): feature used", "vdh_plain.toml", ["run.time_gate_ns=[0, 1e6]"]),
        ],
        2_000_000,
        100_000,
    ),
]

BARE_PHOTONS = 2_000_000




TIME = shutil.which("time", path="/usr/bin:/bin")


def run_child(cmd):
    """Run `cmd`; return (wall seconds, peak resident memory in MiB or None).

    The peak memory is GNU time's `%M` (/usr/bin/time, if installed). Not the ru_maxrss of a child
    of this script: Linux carries the parent's high-water mark across fork and exec into the
    child's ru_maxrss (here 15 MiB of Python), which would hide a small peak.
    """
    with tempfile.NamedTemporaryFile(mode="r") as rss, tempfile.TemporaryFile() as err:
        full = ([TIME, "-f", "%M", "-o", rss.name] if TIME else []) + [str(c) for c in cmd]
        t0 = time.perf_counter()
        p = subprocess.run(full, stdout=subprocess.DEVNULL, stderr=err)
        wall = time.perf_counter() - t0
        if p.returncode != 0:
            err.seek(0)
            sys.exit(f"failed ({p.returncode}): {' '.join(full)}\n{err.read().decode()}")
        kib = rss.read().strip().splitlines()
    return wall, (int(kib[-1]) / 1024.0 if kib else None)


def ohd_cmd(ohd, cfg, sets, samples, out):
    cmd = [str(ohd), "run", str(HERE / cfg), "--out", str(out), "--threads", "1", "--samples", str(samples)]
    for s in sets:
        cmd += ["--set", s]
    return cmd


def mmm(v):
    return min(v), statistics.median(v), max(v)


def callgrind_instructions(cmd, workdir):
    f = Path(workdir) / "cg.out"
    full = [
        "valgrind",
        "--tool=callgrind",
        f"--callgrind-out-file={f}",
        "--toggle-collect=*run_batch*",
    ] + cmd
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    subprocess.run(full, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    text = f.read_text(errors="replace")
    m = re.search(r"^summary:\s+(\d+)", text, re.M) or re.search(r"^totals:\s+(\d+)", text, re.M)
    f.unlink()
    return int(m.group(1))


def groups_table(ohd, rounds, use_callgrind, only):
    lines = []
    work = Path(tempfile.mkdtemp(prefix="ohd_features_"))
    try:
        for gi, (group, variants, paths, cg_paths) in enumerate(GROUPS):
            if only and not any(o in group for o in only):
                continue
            walls = [[] for _ in variants]
            transport = [[] for _ in variants]
            rss = [None for _ in variants]
            events = [0 for _ in variants]
            for r in range(rounds):
                for k, (_, cfg, sets) in enumerate(variants):
                    out = work / f"g{gi}v{k}"
                    w, m = run_child(ohd_cmd(ohd, cfg, sets, paths, out))
                    man = json.loads((out / "manifest.json").read_text())
                    walls[k].append(w)
                    transport[k].append(man["wall_seconds"])
                    rss[k] = m if rss[k] is None or m is None else max(rss[k], m)
                    events[k] = man["run_statistics"]["scattering_events"]
                    shutil.rmtree(out)
                print(f"  {group}: round {r + 1}/{rounds}", file=sys.stderr)
            cg = []
            if use_callgrind:
                for k, (_, cfg, sets) in enumerate(variants):
                    out = work / f"cg{gi}v{k}"
                    cg.append(callgrind_instructions(ohd_cmd(ohd, cfg, sets, cg_paths, out), work))
                    shutil.rmtree(out, ignore_errors=True)
            lines.append(f"**{group}** ({paths:,} paths per run, {rounds} rounds, 1 thread)")
            lines.append("")
            head = "| variant | process s (min / median / max) | ratio | transport s (median) | ratio | events/path | peak RSS MiB |"
            sep = "|---|---|---|---|---|---|---|"
            if use_callgrind:
                head += f" instructions/path ({cg_paths:,} paths) | ratio |"
                sep += "---|---|"
            lines += [head, sep]
            base_w = statistics.median(walls[0])
            base_t = statistics.median(transport[0])
            for k, (label, _, _) in enumerate(variants):
                a, b, c = mmm(walls[k])
                t = statistics.median(transport[k])
                row = (
                    f"| {label} | {a:.3f} / {b:.3f} / {c:.3f} | {b / base_w:.3f} | {t:.3f} | {t / base_t:.3f} "
                    f"| {events[k] / paths:.2f} | {'n/a' if rss[k] is None else f'{rss[k]:.1f}'} |"
                )
                if use_callgrind:
                    row += f" {cg[k] / cg_paths:,.0f} | {cg[k] / cg[0]:.4f} |"
                lines.append(row)
            lines.append("")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return lines


def bare_table(ohd, bare, rounds, use_callgrind):
    lines = []
    # In one process, alternating: transport only (ohd's Experiment::run against the bare loop).
    res = subprocess.run(
        [str(bare), "--photons", str(BARE_PHOTONS), "--rounds", str(rounds)], check=True, capture_output=True, text=True
    )
    lines.append(f"**Bare random walk against ohd, in one process** (`examples/bare_walk.rs`; {BARE_PHOTONS:,} photons, {rounds} rounds, alternating, 1 thread)")
    lines.append("")
    lines += [l for l in res.stdout.splitlines() if l.startswith("|")]
    ratio = [l for l in res.stdout.splitlines() if l.startswith("ohd / bare")]
    lines.append("")
    lines += ratio
    lines.append("")
    # Whole processes, alternating.
    work = Path(tempfile.mkdtemp(prefix="ohd_bare_"))
    try:
        w_bare, w_ohd = [], []
        for _ in range(rounds):
            w, _ = run_child([str(bare), "--mode", "bare", "--photons", str(BARE_PHOTONS), "--rounds", "1"])
            w_bare.append(w)
            w, _ = run_child(ohd_cmd(ohd, "../vdh_slab.toml", [], BARE_PHOTONS, work / "o"))
            w_ohd.append(w)
        a, b, c = mmm(w_bare)
        d, e, f = mmm(w_ohd)
        lines.append("Whole processes, alternating (start-up, configuration and output included):")
        lines.append("")
        lines.append("| code | s (min / median / max) | ohd / bare photons/s |")
        lines.append("|---|---|---|")
        lines.append(f"| bare walk | {a:.3f} / {b:.3f} / {c:.3f} | |")
        lines.append(f"| `ohd run validation/vdh_slab.toml --threads 1` | {d:.3f} / {e:.3f} / {f:.3f} | {b / e:.3f} |")
        lines.append("")
        if use_callgrind:
            n = 200_000
            env = dict(os.environ, RAYON_NUM_THREADS="1")
            counts = {}
            for mode in ["bare", "ohd"]:
                f_ = work / f"cg_{mode}.out"
                subprocess.run(
                    ["valgrind", "--tool=callgrind", f"--callgrind-out-file={f_}", str(bare), "--mode", mode,
                     "--photons", str(n), "--rounds", "1"],
                    check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
                )
                m = re.search(r"^summary:\s+(\d+)", f_.read_text(errors="replace"), re.M)
                counts[mode] = int(m.group(1))
            lines.append(
                f"Callgrind, {n:,} photons in the example (whole process): bare {counts['bare'] / n:,.0f}, "
                f"ohd {counts['ohd'] / n:,.0f} instructions per photon (bare / ohd = {counts['bare'] / counts['ohd']:.3f})."
            )
            lines.append("")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=5, help="interleaved rounds per group (default 5)")
    ap.add_argument("--callgrind", action="store_true", help="also count instructions with callgrind")
    ap.add_argument("--only", action="append", help="run only groups whose name contains this (repeatable); 'bare' for the bare walk")
    ap.add_argument("--no-build", action="store_true", help="use the binaries already built")
    ohdpy.add_binary_argument(ap)
    ap.add_argument("--markdown", help="also write the tables to this file")
    args = ap.parse_args()
    # The bare walk (examples/bare_walk.rs) is always this source tree's; --binary replaces ohd only.
    want_bare = not args.only or "bare" in args.only
    if args.no_build or (args.binary is not None and not want_bare):
        rel = ohdpy.target_dir() / "release"
    else:
        rel = ohdpy.build("--example", "bare_walk")
    ohd, bare = rel / "ohd", rel / "examples" / "bare_walk"
    if args.binary is not None:
        ohd = Path(ohdpy.binary(args.binary))
    lines = []
    if not args.only or "bare" in args.only:
        lines += bare_table(ohd, bare, args.rounds, args.callgrind)
    only = [o for o in (args.only or []) if o != "bare"]
    if not args.only or only:
        lines += groups_table(ohd, args.rounds, args.callgrind, only)
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(text + "\n")


if __name__ == "__main__":
    main()
