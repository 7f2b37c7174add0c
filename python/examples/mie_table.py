"""Mie scattering: the phase functions of a red blood cell's equal-volume sphere and of an aerosol
droplet, from `ohd.mie` (the same solver as `ohd mie`), with their asymmetry parameters.

    python python/examples/mie_table.py [OUT_DIR]

Writes mie_table.png into OUT_DIR (default: the current directory); about a second.
"""
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import ohd  # noqa: E402

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
out.mkdir(parents=True, exist_ok=True)
spheres = {
    # A red blood cell's volume (90 fL) as a sphere of 5.56 µm, n 1.40 in plasma 1.345, at 785 nm.
    "red blood cell (5.56 µm, 785 nm)": dict(diameter_um=5.56, n_particle=1.40, n_medium=1.345, wavelength_nm=785),
    # A haze droplet of 1 µm, n 1.45 − 0.001i in air, at 1.55 µm.
    "aerosol (1 µm, 1.55 µm)": dict(diameter_um=1.0, n_particle=1.45, k_particle=0.001, n_medium=1.0, wavelength_nm=1550),
}
fig, ax = plt.subplots(figsize=(7, 4.5))
for label, sphere in spheres.items():
    m = ohd.mie(angles=2000, **sphere)
    ax.semilogy(m["theta_deg"], m["phase_per_sr"], label=f"{label}: g = {m['g']:.3f}, x = {m['x']:.1f}")
ax.set(xlabel="scattering angle θ (°)", ylabel="phase function (sr⁻¹)", title="Mie phase functions (ohd.mie)")
ax.legend(fontsize=8)
fig.tight_layout()
fig.savefig(out / "mie_table.png", dpi=110)
print(f"wrote {out / 'mie_table.png'}")
