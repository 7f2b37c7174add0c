#!/usr/bin/env python3
"""Forward against camera-side estimation of retina_ldh's artery, over many seeds (issue 54, item 1):
is the 4σ difference of the multiple-Doppler M0+ between the two estimators a bias, or the
forward estimator's heavy tail making a typical run read low?

The quantity is the mean over the artery's rectangle (52 × 13 pixels of the shipped 256² camera,
x in [-243.75, 243.75] µm, y in [440.625, 562.5] µm: pixel edges of the shipped grid, so both
estimators integrate the same area), per mm², of the intensity and of M0+ with its three classes
(static, single, multiple Doppler).
- forward: configs/retina_ldh.toml as shipped (layered control variate), `--seeds` seeds of
  `--forward-samples` paths each; the rectangle is cut out of its 256² images;
- camera: the same scene with a camera of exactly that rectangle (52 × 13 pixels, no ROI and
  no speckle, which an ROI needs), `estimator = "camera"`, `--camera-seeds` seeds of
  `--camera-samples` camera paths each.
Both at each pupil half-angle of `--cones` (10° shipped). Each run's own batch error of the
rectangle mean is computed from its per-pixel standard errors as if the pixels were independent
(they are not: a path scores several), so the seed-to-seed spread is the error quoted:
mean ± s/√n over seeds, and the z of the difference of the two estimators' means. The forward
seeds' median against their mean says whether a typical run reads low.

    python3 validation/camera/artery.py [--binary PATH] [--seeds 16] [--forward-samples 2.5e6]
        [--camera-seeds 4] [--camera-samples 5e5] [--cones 10,20,30] [--work DIR] [--json FILE]
"""
import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "validation"))
import ohdpy  # noqa: E402

ohdpy.use_venv("numpy")
import numpy as np  # noqa: E402
CONFIG = os.path.join(ROOT, "configs", "retina_ldh.toml")

# The rectangle, in pixels of the shipped 2.4 mm / 256 grid (pixel k spans -1200 + k·Δ µm).
DELTA_UM = 2400 / 256
COLS = range(102, 154)  # x from -243.75 to 243.75 µm
KY = range(175, 188)  # y from 440.625 to 562.5 µm; image row = 255 - ky (row 0 = largest y)
ROWS = [255 - k for k in KY]
AREA_MM2 = len(COLS) * len(KY) * (DELTA_UM * 1e-3) ** 2
CENTER_MM = (0.0, (-1200 + (KY[0] + KY[-1] + 1) / 2 * DELTA_UM) * 1e-3)
SIZE_MM = (len(COLS) * DELTA_UM * 1e-3, len(KY) * DELTA_UM * 1e-3)

QUANTITIES = {
    "intensity": "image",
    "m0_plus": "m0_plus",
    "static": "m0_plus_static",
    "single": "m0_plus_single_doppler",
    "multiple": "m0_plus_multiple_doppler",
}


def camera_config():
    """retina_ldh with its camera cut to the rectangle and turned around: no ROIs, no speckle."""
    text = open(CONFIG).read()
    head = text[: text.index("[[detectors]]")]
    return head + f"""[[detectors]]
name = "camera"
area = {{ type = "rect", size_mm = [{SIZE_MM[0]!r}, {SIZE_MM[1]!r}], center_mm = [0, {CENTER_MM[1]!r}] }}
acceptance_half_angle_deg = 10
include_specular = false
estimator = "camera"
[detectors.image]
pixels = [{len(COLS)}, {len(KY)}]
[detectors.ldh]
frame_rate_khz = 39
window_samples = 512
window = "hann"
band_khz = [6, 18.3]
by_class = true
"""


def rectangle(out, cut):
    """Each quantity's rectangle mean per mm², and its error from the per-pixel errors."""
    res = {}
    for q, name in QUANTITIES.items():
        v = np.load(os.path.join(out, f"camera_{name}.npy"))
        s = np.load(os.path.join(out, f"camera_{name}_stderr.npy"))
        if cut:
            v, s = v[np.ix_(ROWS, list(COLS))], s[np.ix_(ROWS, list(COLS))]
        assert v.shape == (len(KY), len(COLS)), v.shape
        res[q] = (float(v.sum()) / AREA_MM2, float(math.sqrt((s**2).sum())) / AREA_MM2)
    return res


def run(binary, config, out, samples, seed, cone):
    cmd = [binary, "run", config, "--out", out, "--samples", str(int(samples)), "--seed", str(seed),
           "--set", f"detectors.0.acceptance_half_angle_deg={cone}", "--quiet"]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{p.stderr}")
    m = json.load(open(os.path.join(out, "manifest.json")))
    return m.get("timing", {}).get("transport_seconds")


def summary(values):
    n = len(values)
    mean = statistics.fmean(values)
    err = statistics.stdev(values) / math.sqrt(n) if n > 1 else float("nan")
    return mean, err, statistics.median(values), min(values), max(values)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--binary", default=os.path.join(ROOT, "target", "release", "ohd"))
    ap.add_argument("--seeds", type=int, default=16)
    ap.add_argument("--forward-samples", type=float, default=2.5e6)
    ap.add_argument("--camera-seeds", type=int, default=4)
    ap.add_argument("--camera-samples", type=float, default=5e5)
    ap.add_argument("--cones", default="10,20,30")
    ap.add_argument("--work", default=None, help="keep the runs here (default: a temporary directory)")
    ap.add_argument("--json", default=None, help="write every run's rectangle values here")
    args = ap.parse_args()

    work = args.work or tempfile.mkdtemp(prefix="ohd-artery-")
    os.makedirs(work, exist_ok=True)
    cam_config = os.path.join(work, "camera.toml")
    open(cam_config, "w").write(camera_config())
    record = {"area_mm2": AREA_MM2, "runs": []}
    for cone in [float(c) for c in args.cones.split(",")]:
        per = {"forward": [], "camera": []}
        plan = [("camera", cam_config, args.camera_samples, s) for s in range(1, args.camera_seeds + 1)]
        plan += [("forward", CONFIG, args.forward_samples, s) for s in range(1, args.seeds + 1)]
        for est, config, samples, seed in plan:
            out = os.path.join(work, f"{est}_{cone:g}_{seed}")
            t = run(args.binary, config, out, samples, seed, cone)
            r = rectangle(out, cut=est == "forward")
            per[est].append(r)
            record["runs"].append({"cone": cone, "estimator": est, "seed": seed, "samples": samples,
                                   "transport_s": t, "values": r})
            print(f"  {cone:g}° {est} seed {seed}: M0+ multiple {r['multiple'][0]:.4e} ± {r['multiple'][1]:.1e}",
                  file=sys.stderr, flush=True)
        print(f"\n## {cone:g}° half-angle: rectangle means per mm² (×1e-5); mean ± s/√n over seeds "
              f"(forward {args.seeds} × {args.forward_samples:.3g} paths, camera {args.camera_seeds} × "
              f"{args.camera_samples:.3g} camera paths)\n")
        print("| quantity | forward mean ± σ | forward median (min–max) of seeds | forward own σ (median) "
              "| camera mean ± σ | camera own σ (median) | z (forward − camera) |")
        print("|---|---|---|---|---|---|---|")
        for q in QUANTITIES:
            f = summary([r[q][0] * 1e5 for r in per["forward"]])
            c = summary([r[q][0] * 1e5 for r in per["camera"]])
            fo = statistics.median(r[q][1] * 1e5 for r in per["forward"])
            co = statistics.median(r[q][1] * 1e5 for r in per["camera"])
            spread = math.hypot(f[1], c[1])
            z = (f[0] - c[0]) / spread if spread > 0 else float("nan")
            print(f"| {q} | {f[0]:.3f} ± {f[1]:.3f} | {f[2]:.3f} ({f[3]:.3f}–{f[4]:.3f}) | {fo:.3f} "
                  f"| {c[0]:.3f} ± {c[1]:.3f} | {co:.3f} | {z:+.2f} |", flush=True)
    if args.json:
        json.dump(record, open(args.json, "w"), indent=1)


if __name__ == "__main__":
    main()
