"""Diffuse correlation spectroscopy: g1(τ) of configs/dcs_forearm.toml at ρ = 2.5 cm, fitted for
the Brownian diffusion coefficient D_B with the semi-infinite correlation diffusion solution
(Boas & Yodh 1997; Durduran et al. 2010, Rep. Prog. Phys. 73, 076701, Eq. 19 with an extrapolated
boundary), against the D_B the scene was given.

    python python/examples/dcs_fit.py [--samples N] [OUT_DIR]

Writes dcs_fit.png into OUT_DIR (default: the current directory) and prints the fitted D_B. The
configuration's paths take about a minute on 2 cores.
"""
import argparse
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import ohd  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("out", nargs="?", default=".")
parser.add_argument("--samples", type=float, default=None, help="paths (default: the configuration's)")
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)

r = ohd.run(ROOT / "configs" / "dcs_forearm.toml", samples=args.samples, seed=1, figures=False)
cfg = r.manifest["config"]
medium = next(iter(cfg["media"].values()))
n = cfg["layers"][0]["n"]
mua = 1e3 * medium["sigma_a_per_mm"]  # m⁻¹
musp = 1e3 * medium["sigma_s_per_mm"] * (1 - medium["phase"]["g"])  # μs' (m⁻¹)
area = cfg["detectors"][0]["area"]
rho = 1e-3 * 0.5 * (area["inner_radius_mm"] + area["outer_radius_mm"])
k0 = 2 * math.pi * n / (1e-9 * cfg["source"]["wavelength_nm"])
d_true = medium["motion"]["diffusion_m2_per_s"]

# The semi-infinite solution: a source at z0 = 1/μs' and its image beyond the extrapolated
# boundary zb = 2(1 + Reff)/(3μs'(1 − Reff)), Reff of the index mismatch (Haskell et al. 1994).
reff = -1.440 / n**2 + 0.710 / n + 0.668 + 0.0636 * n
z0, zb = 1 / musp, 2 * (1 + reff) / (3 * musp * (1 - reff))
r1, r2 = math.hypot(rho, z0), math.hypot(rho, z0 + 2 * zb)


def g1_model(tau, d):
    k = np.sqrt(3 * mua * musp + 6 * musp**2 * k0**2 * d * tau)
    G = np.exp(-k * r1) / r1 - np.exp(-k * r2) / r2
    k_0 = math.sqrt(3 * mua * musp)
    return G / (math.exp(-k_0 * r1) / r1 - math.exp(-k_0 * r2) / r2)


g1 = r["fibre_g1"]
tau = g1.axes["tau_s"]
value, err = g1.values[0], g1.stderr[0]  # the real part
use = (value > 0.05) & (err > 0)


def misfit(log_d):
    return float(np.sum(((value[use] - g1_model(tau[use], 10**log_d)) / err[use]) ** 2))


# Golden-section search for log10 D_B over 10⁻¹⁶ … 10⁻¹⁰ m²/s (the misfit is unimodal in it).
lo, hi = -16.0, -10.0
phi = (math.sqrt(5) - 1) / 2
for _ in range(80):
    a, b = hi - phi * (hi - lo), lo + phi * (hi - lo)
    lo, hi = (lo, b) if misfit(a) < misfit(b) else (a, hi)
d_fit = 10 ** (0.5 * (lo + hi))

fig, ax = plt.subplots(figsize=(7, 4.5))
ax.errorbar(tau, value, yerr=err, fmt="o", ms=3, label=f"ohd, {r.manifest['samples']:.3g} paths")
ax.semilogx(tau, g1_model(tau, d_fit), "-", label=f"diffusion fit: D_B = {d_fit:.3g} m²/s")
ax.semilogx(tau, g1_model(tau, d_true), "--", label=f"diffusion, the scene's D_B = {d_true:.3g} m²/s")
ax.set(xlabel="τ (s)", ylabel="g1(τ)", title=f"{r.manifest['name']}: g1 at ρ = {100 * rho:.1f} cm")
ax.legend(fontsize=8)
fig.tight_layout()
fig.savefig(out / "dcs_fit.png", dpi=110)
print(f"fitted D_B = {d_fit:.4g} m²/s (scene {d_true:.4g}); wrote {out / 'dcs_fit.png'}")
