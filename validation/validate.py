#!/usr/bin/env python3
"""Run the validation cases and tabulate reference, measured ± σ, z, samples and seconds.

Usage: python3 validation/validate.py [--samples N] [--markdown FILE]
Builds ohd in release mode if needed (cargo). Standard library only.
Exit status 1 if any |z| > 3 (3σ), so the script can gate a release.
"""
import argparse
import json
import math
import os
import struct
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
C = 299_792_458.0


def ohd_binary():
    subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    return os.path.join(ROOT, "target", "release", "ohd")


def run(binary, config, out, samples=None):
    cmd = [binary, "run", os.path.join(ROOT, config), "--out", out, "--quiet"]
    if samples:
        cmd += ["--samples", str(samples)]
    subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL)
    with open(os.path.join(out, "manifest.json")) as f:
        return json.load(f)


def read_npy(path):
    """Minimal reader for the little-endian f8 C-order arrays ohd writes."""
    with open(path, "rb") as f:
        data = f.read()
    hlen = struct.unpack("<H", data[8:10])[0]
    header = data[10:10 + hlen].decode()
    shape = tuple(int(s) for s in header.split("'shape': (")[1].split(")")[0].split(",") if s.strip())
    body = data[10 + hlen:]
    return shape, list(struct.unpack("<%dd" % (len(body) // 8), body))


def peak(values, freqs, half=3):
    k = max(range(len(values)), key=values.__getitem__)
    idx = range(max(0, k - half), min(len(values), k + half + 1))
    w = sum(values[j] for j in idx)
    return sum(values[j] * freqs[j] for j in idx) / w


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--samples", type=int, default=None, help="override every case's sample count")
    ap.add_argument("--markdown", default=None, help="also write the table to this file")
    args = ap.parse_args()
    binary = ohd_binary()
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

        out = os.path.join(tmp, "fmcw")
        m = run(binary, "configs/fmcw_target.toml", out, args.samples)
        _, freqs = read_npy(os.path.join(out, "receiver_frequency_hz.npy"))
        _, up = read_npy(os.path.join(out, "receiver_up_spectrum.npy"))
        _, down = read_npy(os.path.join(out, "receiver_down_spectrum.npy"))
        f_up, f_down = peak(up, freqs), peak(down, freqs)
        b, t, lam = 1e9, 10e-6, 1550e-9
        bin_w = freqs[1] - freqs[0]
        rows.append(("FMCW target (peak ± 1 bin)", "range_m", 10.0, C * t * (f_up + f_down) / (4 * b),
                     C * t * bin_w / (4 * b), m["samples"], m["wall_seconds"]))
        rows.append(("FMCW target (peak ± 1 bin)", "radial_velocity_m_per_s", 1.0, lam * (f_up - f_down) / 4,
                     lam * bin_w / 4, m["samples"], m["wall_seconds"]))

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
    # FMCW rows carry a resolution (one bin), not a standard error: they are checked to be within it.
    fm = [r for r in rows if "FMCW" in r[0]]
    ok = worst <= 3.0 and all(abs(v - ref) <= se for _, _, ref, v, se, _, _ in fm) and abs(total - 1) < 1e-3
    print(f"\nlargest |z| = {worst:.2f}; {'PASS' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
