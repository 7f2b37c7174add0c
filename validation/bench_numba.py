#!/usr/bin/env python3
"""Photons/ms per core on the van de Hulst slab: ohd against an optimised numba Monte Carlo,
measured in the same run (alternating, median of repeats), reported as a ratio.

The numba reference is our own MCML-style code for the same physics: pencil beam at normal
incidence, matched boundaries (n = 1), HG g = 0.75, absorption weighting, Russian roulette at
weight 1e-4 with survival 0.1. It prints its Rd and Tt as a sanity check.

Usage: python3 validation/bench_numba.py [--photons N] [--repeats R] [--binary PATH]
Runs --binary PATH, else builds ohd (cargo build --release). numba and numpy are installed into
validation/.venv (validation/ohdpy.py), where the script re-runs itself.
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

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import ohdpy  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
np = None  # numpy, imported in main() once inside the venv


def vdh_numba(n_photons, seed):  # compiled by numba.njit in main()
    np.random.seed(seed)
    mua, mus, g, d = 10.0, 90.0, 0.75, 0.02  # cm⁻¹, cm
    mut = mua + mus
    albedo = mus / mut
    rd = 0.0
    tt = 0.0
    for _ in range(n_photons):
        x = y = z = 0.0
        ux = uy = 0.0
        uz = 1.0
        w = 1.0
        while True:
            s = -math.log(1.0 - np.random.random()) / mut
            if uz > 0.0:
                db = (d - z) / uz
            elif uz < 0.0:
                db = -z / uz
            else:
                db = 1e300
            if s >= db:
                if uz > 0.0:
                    tt += w
                else:
                    rd += w
                break
            x += s * ux
            y += s * uy
            z += s * uz
            w *= albedo
            # Henyey–Greenstein deflection and azimuth (MCML's rotation).
            xi = np.random.random()
            tmp = (1.0 - g * g) / (1.0 - g + 2.0 * g * xi)
            ct = (1.0 + g * g - tmp * tmp) / (2.0 * g)
            st = math.sqrt(max(0.0, 1.0 - ct * ct))
            phi = 2.0 * math.pi * np.random.random()
            cp = math.cos(phi)
            sp = math.sin(phi)
            if abs(uz) > 0.99999:
                ux, uy, uz = st * cp, st * sp, ct * (1.0 if uz > 0 else -1.0)
            else:
                t = math.sqrt(1.0 - uz * uz)
                nux = st * (ux * uz * cp - uy * sp) / t + ux * ct
                nuy = st * (uy * uz * cp + ux * sp) / t + uy * ct
                nuz = -st * cp * t + uz * ct
                ux, uy, uz = nux, nuy, nuz
            if w < 1e-4:
                if np.random.random() < 0.1:
                    w /= 0.1
                else:
                    break
    return rd / n_photons, tt / n_photons


def time_ohd(binary, photons, out):
    t0 = time.perf_counter()
    subprocess.run([binary, "run", os.path.join(ROOT, "validation/vdh_slab.toml"), "--samples", str(photons),
                    "--threads", "1", "--out", out, "--quiet"], check=True, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    with open(os.path.join(out, "manifest.json")) as f:
        m = json.load(f)
    # Transport time as ohd measures it, and the whole process (start-up and writing included).
    return m["wall_seconds"], wall, m["estimates"]


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--photons", type=int, default=4_000_000)
    ap.add_argument("--repeats", type=int, default=5)
    ohdpy.add_binary_argument(ap)
    args = ap.parse_args()
    ohdpy.use_venv("numba", "numpy")
    global np, vdh_numba
    import numba
    import numpy as np

    vdh_numba = numba.njit(cache=False, fastmath=False)(vdh_numba)
    binary = ohdpy.binary(args.binary)
    vdh_numba(1000, 1)  # JIT compile outside the timing
    ohd_t, ohd_proc, nb_t = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.repeats):
            t, w, est = time_ohd(binary, args.photons, os.path.join(tmp, str(r)))
            ohd_t.append(t)
            ohd_proc.append(w)
            t0 = time.perf_counter()
            rd, tt = vdh_numba(args.photons, r + 1)
            nb_t.append(time.perf_counter() - t0)
    n = args.photons
    rate = lambda ts: n / statistics.median(ts) / 1e3  # noqa: E731
    print(f"photons per run: {n:,}; repeats: {args.repeats}; 1 thread each")
    print(f"numba:          {rate(nb_t):8.0f} photons/ms  (min/median/max s: {min(nb_t):.3f}/{statistics.median(nb_t):.3f}/{max(nb_t):.3f}); Rd {rd:.5f} Tt {tt:.5f}")
    print(f"ohd transport:  {rate(ohd_t):8.0f} photons/ms  (min/median/max s: {min(ohd_t):.3f}/{statistics.median(ohd_t):.3f}/{max(ohd_t):.3f}); "
          f"Rd {est['reflectance_diffuse']['value']:.5f} Tt {est['transmittance_total']['value']:.5f}")
    print(f"ohd process:    {rate(ohd_proc):8.0f} photons/ms  (start-up and output writing included)")
    print(f"ratio ohd/numba (transport): {statistics.median(nb_t) / statistics.median(ohd_t):.2f}×")


if __name__ == "__main__":
    main()
