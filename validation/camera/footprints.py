#!/usr/bin/env python3
"""The vessel pixels of retina_ldh: the shipped forward estimator with its layered control variate
against `estimator = "footprints"` (camera paths from the regions' footprints, their halo and the
ROIs; the forward paths elsewhere), side by side in one sitting (issue 54, items 2 and 5).

Each seed runs both, alternating; each run is timed as a whole process (wall seconds). From each
run's manifest (`pixel_errors`), over the 1,170 pixels of the vessels' footprints:
- eps: the RMS relative error sqrt(mean sigma^2)/mean of M0+ (and of the intensity), which a heavy
  tail cannot make read low the way the median of sigma/value does;
- the efficiency 1/(eps^2 t), and its ratio footprints/forward within each seed's pair;
- the tail slope of the largest path scores into the footprints (>= 3: their variance sampled),
  the share of the footprints' variance in their top 1 % of pixels, and the footprint pixels of
  M0+ below -3 sigma (counted from the images);
- the background: the median per-pixel relative error of M0+ and of the intensity off the
  footprints (the forward paths' in both runs).

    python3 validation/camera/footprints.py [--binary PATH] [--seeds 1,2,3]
        [--samples N] [--camera-paths R] [--halo-um H] [--work DIR] [--json FILE]

`--samples` and `--camera-paths` set the footprints runs (default: the shipped samples, one camera
path per forward path); the forward runs are the shipped config as is.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "validation"))
import ohdpy  # noqa: E402

ohdpy.use_venv("numpy")
import numpy as np  # noqa: E402

CONFIG = os.path.join(ROOT, "configs", "retina_ldh.toml")


def run(binary, out, seed, sets):
    cmd = [binary, "run", CONFIG, "--out", out, "--seed", str(seed), "--quiet"]
    for s in sets:
        cmd += ["--set", s]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{p.stderr}")
    return wall


def figures(out, wall):
    m = json.load(open(os.path.join(out, "manifest.json")))
    pe = m["pixel_errors"]
    p, i = pe["camera.m0_plus"]["regions"], pe["camera.image"]["regions"]
    mask = np.load(os.path.join(out, "camera_region_mask.npy")) > 0
    v = np.load(os.path.join(out, "camera_m0_plus.npy"))
    s = np.load(os.path.join(out, "camera_m0_plus_stderr.npy"))
    z = np.where(s[mask] > 0, v[mask] / np.where(s[mask] > 0, s[mask], 1), 0)
    return {
        "wall_s": wall,
        "eps_m0": p["region_rms"],
        "eps_image": i["region_rms"],
        "efficiency": 1.0 / (p["region_rms"] ** 2 * wall),
        "slope_m0": p.get("tail", {}).get("slope", float("nan")),
        "top1_m0": p["region_top_percent_variance_share"],
        "below_3sigma": int((z < -3).sum()),
        "mean_m0": float(v[mask].mean()),
        "rest_m0": p["median_rest"],
        "rest_image": i["median_rest"],
    }


def spread(xs):
    xs = sorted(xs)
    return f"{xs[0]:.4g} / {statistics.median(xs):.4g} / {xs[-1]:.4g}"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--binary", default=os.path.join(ROOT, "target", "release", "ohd"))
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--samples", type=float, default=None)
    ap.add_argument("--camera-paths", type=float, default=1.0)
    ap.add_argument("--halo-um", type=float, default=None)
    ap.add_argument("--work", default=None)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    work = args.work or tempfile.mkdtemp(prefix="ohd-footprints-")
    os.makedirs(work, exist_ok=True)
    fp_sets = ['detectors.0.estimator="footprints"', f"detectors.0.footprints.camera_paths={args.camera_paths}"]
    if args.samples:
        fp_sets.append(f"run.samples={int(args.samples)}")
    if args.halo_um is not None:
        fp_sets.append(f"detectors.0.footprints.halo_um={args.halo_um}")
    rows = {"forward": [], "footprints": []}
    for seed in [int(s) for s in args.seeds.split(",")]:
        for est, sets in [("forward", []), ("footprints", fp_sets)]:
            out = os.path.join(work, f"{est}_{seed}")
            wall = run(args.binary, out, seed, sets)
            f = figures(out, wall)
            rows[est].append(f)
            print(f"  seed {seed} {est}: {wall:.1f} s, eps M0+ {f['eps_m0']:.3f}, slope {f['slope_m0']:.2f}",
                  file=sys.stderr, flush=True)
    print(f"\nretina_ldh, footprints' pixels (1,170): shipped forward + control variate against "
          f"estimator = \"footprints\" ({' '.join(fp_sets)}), seeds {args.seeds}; min / median / max\n")
    print("| figure | forward | footprints |")
    print("|---|---|---|")
    for k in rows["forward"][0]:
        print(f"| {k} | {spread([r[k] for r in rows['forward']])} | {spread([r[k] for r in rows['footprints']])} |")
    ratios = [b["efficiency"] / a["efficiency"] for a, b in zip(rows["forward"], rows["footprints"])]
    print(f"\nefficiency 1/(eps^2 t) of M0+ at the footprints, footprints / forward per seed: {spread(ratios)}")
    if args.json:
        json.dump({"sets": fp_sets, "rows": rows, "ratios": ratios}, open(args.json, "w"), indent=1)


if __name__ == "__main__":
    main()
