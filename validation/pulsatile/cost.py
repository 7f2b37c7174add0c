#!/usr/bin/env python3
"""Issue 55's cost target: a whole cardiac cycle (configs/retina_pulsatile.toml, 65 windows of
512 frames) against the steady run of the same paths, as whole processes (wall seconds, writing
and post-processing included), alternating over repeats on the same machine:

- `cycle`: the shipped config (its paths carry the harmonics and are scored in every window);
- `no_windows`: the same pulsing scene without [detectors.ldh.acquisition] (the same walk and
  paths, scored once);
- `frozen`: the flows frozen at their cycle means' instant `--frozen-ms` (a steady scene: the
  ordinary walk, without harmonics), the layered control variate and weight windows off as the
  pulsing run has them.

Prints min / median / max per arm and the ratios of medians to `cycle`, and the artery and vein
ROIs' resistivity index with its jackknife σ and the median relative σ per window of M0+ and of
M0+(t)/mean from the `cycle` runs.

    python3 validation/pulsatile/cost.py [--binary PATH] [--samples N] [--repeats 3] [--work DIR]
"""
import argparse
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

ohdpy.use_venv("numpy")
import numpy as np  # noqa: E402

CONFIG = os.path.join(ROOT, "configs", "retina_pulsatile.toml")


def without_acquisition(text):
    head, tail = text.split("[detectors.ldh.acquisition]", 1)
    rest = tail.split("\n[", 1)
    return head + ("[" + rest[1] if len(rest) > 1 else "")


def timed(binary, config, out, sets):
    args = [binary, "run", config, "--out", out, "-q"]
    for s in sets:
        args += ["--set", s]
    t = time.perf_counter()
    p = subprocess.run(args, capture_output=True, text=True)
    dt = time.perf_counter() - t
    if p.returncode != 0:
        sys.exit(f"{' '.join(args)}: {p.stderr}")
    return dt


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ohdpy.add_binary_argument(ap)
    ap.add_argument("--samples", type=float, default=1e6)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--frozen-ms", type=float, default=430.0)
    ap.add_argument("--work", default=None)
    args = ap.parse_args()
    binary = ohdpy.binary(args.binary)
    work = args.work or tempfile.mkdtemp(prefix="ohd-pulsatile-cost-")
    os.makedirs(work, exist_ok=True)
    text = open(CONFIG).read()
    steady = os.path.join(work, "no_windows.toml")
    with open(steady, "w") as f:
        f.write(without_acquisition(text))
    samples = [f"run.samples={int(args.samples)}"]
    off = ['run.control_variate="off"', 'run.importance="off"']
    arms = [
        ("cycle", CONFIG, samples),
        ("no_windows", steady, samples),
        ("frozen", steady, samples + off + [f"cardiac.frozen_at_ms={args.frozen_ms}"]),
    ]
    times = {name: [] for name, _, _ in arms}
    for r in range(args.repeats):
        for name, config, sets in arms:
            times[name].append(timed(binary, config, os.path.join(work, f"{name}_{r}"), sets))
    base = statistics.median(times["cycle"])
    print(f"retina_pulsatile, {int(args.samples)} paths, {args.repeats} repeats, whole-process wall seconds")
    print("| arm | min | median | max | cycle / arm (medians) |\n|---|---|---|---|---|")
    for name, _, _ in arms:
        t = times[name]
        print(f"| {name} | {min(t):.2f} | {statistics.median(t):.2f} | {max(t):.2f} | {base / statistics.median(t):.2f} |")
    for roi in ["artery", "vein"]:
        rows = []
        for r in range(args.repeats):
            d = os.path.join(work, f"cycle_{r}")
            v = np.load(os.path.join(d, f"camera_roi_{roi}_m0_plus_windows.npy"))
            e = np.load(os.path.join(d, f"camera_roi_{roi}_m0_plus_windows_stderr.npy"))
            w = np.load(os.path.join(d, f"camera_roi_{roi}_m0_plus_waveform.npy"))
            we = np.load(os.path.join(d, f"camera_roi_{roi}_m0_plus_waveform_stderr.npy"))
            rows.append((w[2], we[2], float(np.median(e / v))))
        print(
            f"{roi}: RI " + ", ".join(f"{a:.3f} ± {b:.3f}" for a, b, _ in rows)
            + "; median relative σ of M0+ per window " + ", ".join(f"{c:.3f}" for _, _, c in rows)
        )


if __name__ == "__main__":
    main()
