#!/usr/bin/env python3
"""Run the validation cases and tabulate reference, measured ± σ, z, samples and seconds.

Usage: python3 validation/validate.py [--samples N] [--markdown FILE]
Runs --binary PATH, else builds ohd (cargo build --release). Standard library only.
Exit status 1 if any |z| > 3 (3σ), so the script can gate a release.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import ohdpy  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
C = 299_792_458.0


def run(binary, config, out, samples=None):
    cmd = [binary, "run", os.path.join(ROOT, config), "--out", out, "--quiet"]
    if samples:
        cmd += ["--samples", str(samples)]
    subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL)
    with open(os.path.join(out, "manifest.json")) as f:
        return json.load(f)


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--samples", type=int, default=None, help="override every case's sample count")
    ap.add_argument("--markdown", default=None, help="also write the table to this file")
    ohdpy.add_binary_argument(ap)
    args = ap.parse_args()
    binary = ohdpy.binary(args.binary)
    rows = []  # (case, quantity, reference, value, stderr, samples, seconds)
    with tempfile.TemporaryDirectory() as tmp:
        def case(config):
            m = run(binary, config, os.path.join(tmp, os.path.basename(config)), args.samples)
            return m, m["estimates"]

        m, e = case("validation/vdh_slab.toml")
        for key, ref in [("reflectance_diffuse", 0.09739), ("transmittance_total", 0.66096),
                         ("transmittance_unscattered", math.exp(-2.0))]:
            rows.append(("van de Hulst slab", key, ref, e[key]["value"], e[key]["stderr"], m["samples"], m["wall_seconds"]))

        m, e = case("validation/fresnel_slab.toml")
        r0, ex = 0.04, math.exp(-0.5)
        den = 1 - r0 * r0 * ex * ex
        for key, ref in [("reflectance_specular", r0), ("transmittance_total", (1 - r0) ** 2 * ex / den),
                         ("reflectance_diffuse", (1 - r0) ** 2 * r0 * ex * ex / den)]:
            rows.append(("Fresnel absorbing slab", key, ref, e[key]["value"], e[key]["stderr"], m["samples"], m["wall_seconds"]))

        m, e = case("validation/energy_albedo1.toml")
        keys = ["reflectance_specular", "reflectance_diffuse", "transmittance_total"]
        total = sum(e[k]["value"] for k in keys)
        rows.append(("albedo 1, Fresnel both sides", "R + T", 1.0, total, None, m["samples"], m["wall_seconds"]))

        # FMCW: the program's own estimates (manifest estimates.detectors.receiver). The σ column is
        # a resolution, not a standard error: for the hard target half a range/velocity bin (every
        # path falls into one bin per chirp, so each peak is a bin centre off by at most Δf/2), for
        # the cloud half a range bin (centroid range) and one velocity bin (centroid velocity).
        m, e = case("configs/fmcw_target.toml")
        d = e["detectors"]["receiver"]
        for key, ref, tol in [("range_m", 10.0, d["range_bin_m"] / 2),
                              ("radial_velocity_m_per_s", 1.0, d["velocity_bin_m_per_s"] / 2)]:
            rows.append(("FMCW target (± ½ bin)", key, ref, d[key], tol, m["samples"], m["wall_seconds"]))
        m, e = case("configs/fmcw_cloud.toml")
        d = e["detectors"]["receiver"]
        cloud = m["media"]["cloud"]
        sigma_t = cloud["sigma_s_per_m"] + cloud["sigma_a_per_m"]
        # Single-scattering lidar equation: power per unit range ∝ exp(−2σt(R − 10))/R² on 10–11 m.
        n = 2000
        rs = [10.0 + i / n for i in range(n + 1)]
        w = [math.exp(-2 * sigma_t * (r - 10.0)) / r ** 2 * (1 if i in (0, n) else 4 if i % 2 else 2)
             for i, r in enumerate(rs)]
        mean_range = sum(r * x for r, x in zip(rs, w)) / sum(w)
        for key, ref, tol in [("range_centroid_m", mean_range, d["range_bin_m"] / 2),
                              ("radial_velocity_centroid_m_per_s", 1.0, d["velocity_bin_m_per_s"])]:
            rows.append(("FMCW cloud (centroid)", key, ref, d[key], tol, m["samples"], m["wall_seconds"]))

    lines = ["| case | quantity | reference | measured ± σ | z | samples | seconds |",
             "|---|---|---|---|---|---|---|"]
    worst = 0.0
    for name, q, ref, v, se, n, sec in rows:
        if se:
            z = (v - ref) / se
            worst = max(worst, abs(z)) if "FMCW" not in name else worst
            meas, zs = f"{v:.6f} ± {se:.6f}", f"{z:+.2f}"
        else:
            meas, zs = f"{v:.9f}", f"|Δ| = {abs(v - ref):.1e}"
        lines.append(f"| {name} | {q} | {ref:.6f} | {meas} | {zs} | {n:,} | {sec:.2f} |")
    table = "\n".join(lines)
    print(table)
    if args.markdown:
        with open(args.markdown, "w") as f:
            f.write(table + "\n")
    # FMCW rows carry a resolution (a bin or half of one), not a standard error: they are checked to be
    # within it.
    fm = [r for r in rows if "FMCW" in r[0]]
    ok = worst <= 3.0 and all(abs(v - ref) <= se for _, _, ref, v, se, _, _ in fm) and abs(total - 1) < 1e-3
    print(f"\nlargest |z| = {worst:.2f}; {'PASS' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
