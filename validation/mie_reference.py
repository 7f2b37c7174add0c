#!/usr/bin/env python3
"""Generate tests/data/mie_reference.json: Mie reference values from miepython for tests/it/mie.rs.

Usage: python3 validation/mie_reference.py [OUTPUT]   (default: tests/data/mie_reference.json)

Uses the standard library and miepython only (tested with miepython 3.3.0, whose version is written
into the output). Runtime: about a minute, most of it the Marshall-Palmer integral.

Conventions, and how miepython's are converted to ohd's (each one is checked at run time below):

* Refractive index. ohd and miepython both take m = n - ik with k >= 0 absorbing (miepython
  conjugates an index with positive imaginary part). The JSON stores n and k (k >= 0).
* Size parameter x = 2 pi r n_medium / lambda0 in both.
* Qback. miepython's qback is |sum (2n+1)(-1)^n (a_n - b_n)|^2 / x^2 = 4|S1(180 deg)|^2 / x^2, the
  radar convention ohd uses (m = 0.75, x = 10 -> 0.046584, validation-values section 3). Checked.
* Amplitudes. miepython.S1_S2(m, x, mu, norm="wiscombe") returns the raw series without a
  normalisation factor (checked: 4 Re S(0)/x^2 = Qext and 4|S1(pi)|^2/x^2 = Qback). Its imaginary
  parts have the opposite sign to Bohren & Huffman's e^{-i omega t} convention that ohd returns: for a
  small non-absorbing sphere B&H give S(0) ~ -i x^3 (m^2-1)/(m^2+2) (negative imaginary part), while
  miepython returns a positive imaginary part (checked for m = 1.5, x = 0.5). So the JSON stores
  conj(S_miepython) = S in the B&H convention.
* Small spheres. For |m| x < 0.1 miepython uses Wiscombe's small-sphere expansion instead of the
  series; each case records this as "small_sphere_expansion".

Accuracy note (measured while writing the tests, see tests/it/mie.rs): at x = 1e4, m = 1.33 - 1e-5i,
miepython's a_1 differs from a 40-digit mpmath evaluation by 3e-11 (ohd's by 7e-13), and its a_n differ
from ohd's by ~7e-11 for all n. Quantities formed by strong cancellation (Qback, S near 180 deg)
therefore carry miepython errors up to ~1e-5 relative at x >= 3e3.
"""

import cmath
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import ohdpy  # noqa: E402

if __name__ == "__main__":
    ohdpy.use_venv("miepython==3.3.0")  # into validation/.venv, never the caller's interpreter
import miepython  # noqa: E402

XS = [1e-3, 1e-2, 0.1, 0.5, 1.0, 2.5, 5.21282, 10.0, 30.0, 100.0, 300.0, 1e3, 3e3, 1e4, 2e4]
# (n, k): m = n - ik.
MS = [
    (1.0001, 0.0),  # nearly index-matched
    (0.75, 0.0),  # m < 1 (air bubble in water)
    (1.33, 0.0),
    (1.33, 1e-5),  # weakly absorbing water drop (Wiscombe's case)
    (1.5, 0.01),
    (1.55, 0.0),
    (1.5, 1.0),  # strongly absorbing
    (2.0, 1e-3),
    (10.0, 10.0),  # |m| ~ 14
]
# Scattering angles (radians) for S1, S2.
THETAS = [0.0, 1e-7, 1e-3, 0.1, 0.5, 1.0, 2.0, 3.0, math.pi]


def efficiencies(n, k, x):
    qext, qsca, qback, g = miepython.efficiencies_mx(complex(n, -k), x)
    return float(qext), float(qsca), float(qback), float(g)


def amplitudes(n, k, x, thetas):
    mus = [math.cos(t) for t in thetas]
    s1, s2 = miepython.S1_S2(complex(n, -k), x, mus, norm="wiscombe")
    # B&H convention: complex conjugate of miepython's amplitudes (see module docstring).
    return [[complex(v).real, -complex(v).imag] for v in s1], [[complex(v).real, -complex(v).imag] for v in s2]


def check_conventions():
    qext, qsca, qback, g = efficiencies(0.75, 0.0, 10.0)
    assert abs(qback - 0.046584) < 5e-7, qback
    assert abs(qext - 2.232265) < 5e-7 and abs(g - 0.896473) < 5e-7, (qext, g)
    s1, s2 = amplitudes(0.75, 0.0, 10.0, [0.0, math.pi])
    assert abs(4 * s1[0][0] / 100 - qext) < 1e-9 * qext
    assert abs(4 * (s1[1][0] ** 2 + s1[1][1] ** 2) / 100 - qback) < 1e-9 * qback
    # Sign of Im S(0) for a small dielectric sphere, B&H: S(0) ~ -i x^3 (m^2 - 1)/(m^2 + 2).
    s1, _ = amplitudes(1.5, 0.0, 0.5, [0.0])
    rayleigh = -1j * 0.5**3 * (1.5**2 - 1) / (1.5**2 + 2)
    assert s1[0][1] < 0 and abs(complex(*s1[0]) - rayleigh) < 0.2 * abs(rayleigh), s1


def marshall_palmer(rain_rate, d_min, d_max, wavelength, n, k, points=3000):
    """Marshall-Palmer rain at one wavelength, trapezoid in ln D over [d_min, d_max] (metres).

    N(D) = N0 exp(-Lambda D), N0 = 8000 m^-3 mm^-1 = 8e6 m^-4, Lambda = 4.1 R^-0.21 mm^-1.
    Returns sigma_ext, sigma_sca (m^-1), g (sigma_s weighted) and beta = sum N C_back / (4 pi).
    """
    n0 = 8.0e6
    lam = 4.1e3 * rain_rate**-0.21
    lo, hi = math.log(d_min), math.log(d_max)
    ext = sca = gsum = back = 0.0
    for i in range(points):
        u = lo + (hi - lo) * i / (points - 1)
        w = (hi - lo) / (points - 1) * (0.5 if i in (0, points - 1) else 1.0)
        d = math.exp(u)
        dens = d * n0 * math.exp(-lam * d)  # dN/dlnD, m^-3
        r = d / 2
        x = 2 * math.pi * r / wavelength
        qe, qs, qb, g = efficiencies(n, k, x)
        area = math.pi * r * r
        ext += w * dens * qe * area
        sca += w * dens * qs * area
        gsum += w * dens * qs * area * g
        back += w * dens * qb * area / (4 * math.pi)
    return {"sigma_ext": ext, "sigma_sca": sca, "g": gsum / sca, "backscatter": back}


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "tests/data/mie_reference.json"
    check_conventions()
    cases = []
    for x in XS:
        for n, k in MS:
            qext, qsca, qback, g = efficiencies(n, k, x)
            s1, s2 = amplitudes(n, k, x, THETAS)
            cases.append(
                {
                    "n": n,
                    "k": k,
                    "x": x,
                    "qext": qext,
                    "qsca": qsca,
                    "qback": qback,
                    "g": g,
                    "small_sphere_expansion": abs(complex(n, -k)) * x < 0.1,
                    "theta": THETAS,
                    "s1": s1,
                    "s2": s2,
                }
            )
    mp = {
        "rain_rate_mm_per_h": 5.0,
        "d_min": 0.05e-3,
        "d_max": 6e-3,
        "wavelength": 1.55e-6,
        "n": 1.3109,
        "k": 1.35e-4,
        "n_medium": 1.0,
        "points": 3000,
        "rule": "trapezoid in ln D",
    }
    mp.update(marshall_palmer(5.0, mp["d_min"], mp["d_max"], mp["wavelength"], mp["n"], mp["k"], mp["points"]))
    doc = {
        "generator": "validation/mie_reference.py",
        "miepython_version": miepython.__version__,
        "conventions": {
            "index": "m = n - ik, k >= 0 absorbing (miepython's convention too)",
            "qback": "4|S1(pi)|^2/x^2 (radar); miepython's qback is the same (checked: m=0.75, x=10 -> 0.046584)",
            "amplitudes": "Bohren & Huffman (e^{-i omega t}): stored s = conj(miepython S1_S2(norm='wiscombe'))",
            "s1_s2_layout": "[[re, im], ...] at the angles 'theta' (radians)",
        },
        "cases": cases,
        "marshall_palmer": mp,
    }
    with open(out, "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    print(f"wrote {len(cases)} cases and the Marshall-Palmer integral to {out}")


if __name__ == "__main__":
    main()
