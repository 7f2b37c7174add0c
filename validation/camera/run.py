#!/usr/bin/env python3
"""Forward against camera-side estimation of the shipped LDH cameras, side by side in one run: for
each scene, R repeats of a run with `estimator = "forward"` and one with `"camera"`, alternating
(same samples and seed per repeat), reading the per-pixel relative errors the run reports
(manifest `pixel_errors`: median and p90 of stderr/|value| over the pixels) and its wall time.
Efficiency is 1/(σ²·t) with σ the per-pixel median; the table gives, per output, min/median/max
of each estimator and the ratio camera/forward of the median efficiencies, plus the min–max of
the ratio of each adjacent pair (a shared machine drifts).

Usage: python3 validation/camera/run.py [--repeats R] [--binary PATH] [--samples N] [--scenes a,b]
       [--pixels NX] [--json FILE]
Builds ohd (cargo build --release) unless --binary is given. The defaults run each scene at a
tenth of its shipped paths (retina 2.4·10⁶, vessels 4·10⁵ → --samples overrides both).
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

SCENES = {
    "retina_ldh": ("configs/retina_ldh.toml", 2_400_000),
    "vessels_ldh": ("configs/vessels_ldh.toml", 400_000),
}
OUTPUTS = ["camera.image", "camera.m0_plus"]


def run(binary, config, samples, seed, estimator, out, pixels):
    cmd = [binary, "run", os.path.join(ROOT, config), "--samples", str(samples), "--seed", str(seed), "-q",
           "--out", out, "--set", f'detectors.0.estimator="{estimator}"']
    if pixels:
        cmd += ["--set", f"detectors.0.image.pixels=[{pixels},{pixels}]"]
    t = time.monotonic()
    subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL)
    wall = time.monotonic() - t
    with open(os.path.join(out, "manifest.json")) as f:
        m = json.load(f)
    return wall, {k: (m["pixel_errors"][k]["median"], m["pixel_errors"][k]["p90"]) for k in OUTPUTS}


def spread(xs, fmt="{:.3g}"):
    return " / ".join(fmt.format(x) for x in (min(xs), statistics.median(xs), max(xs)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ohdpy.add_binary_argument(ap)
    ap.add_argument("--samples", type=int)
    ap.add_argument("--pixels", type=int, help="override the image to NX × NX pixels")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--json")
    a = ap.parse_args()
    binary = ohdpy.binary(a.binary)
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for scene in a.scenes.split(","):
            config, samples = SCENES[scene]
            samples = a.samples or samples
            rows = {"forward": [], "camera": []}
            for r in range(a.repeats):
                for est in ("forward", "camera"):
                    wall, errs = run(binary, config, samples, 1 + r, est, os.path.join(tmp, f"{scene}_{est}_{r}"),
                                     a.pixels)
                    rows[est].append((wall, errs))
            results[scene] = {"samples": samples, "runs": rows}
            print(f"\n{scene}: {samples} paths per run, {a.repeats} repeats (min / median / max)")
            print(f"  wall s        forward {spread([w for w, _ in rows['forward']])}   "
                  f"camera {spread([w for w, _ in rows['camera']])}")
            for k in OUTPUTS:
                eff = {e: [1.0 / (errs[k][0] ** 2 * w) for w, errs in rows[e]] for e in rows}
                pair = [c / f for c, f in zip(eff["camera"], eff["forward"])]
                print(f"  {k:<15} median σ forward {spread([e[k][0] for _, e in rows['forward']])}"
                      f"  camera {spread([e[k][0] for _, e in rows['camera']])}")
                print(f"  {'':<15} p90 σ    forward {spread([e[k][1] for _, e in rows['forward']])}"
                      f"  camera {spread([e[k][1] for _, e in rows['camera']])}")
                print(f"  {'':<15} efficiency camera/forward: {statistics.median(eff['camera']) / statistics.median(eff['forward']):.3g}"
                      f" (pairs {min(pair):.3g}–{max(pair):.3g})")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
