"""Retinal laser Doppler holography: the M0+ and M0− images of configs/retina_ldh.toml, drawn with
matplotlib from the arrays, with the camera's pixel coordinates on the axes.

    python python/examples/ldh_image.py [--samples N] [OUT_DIR]

Writes ldh_image.png into OUT_DIR (default: the current directory). The configuration's
5·10⁶ paths take about 2 minutes on 2 cores; fewer give noisier images.
"""
import argparse
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

r = ohd.run(ROOT / "configs" / "retina_ldh.toml", samples=args.samples, seed=1, figures=False)
fig, axes = plt.subplots(1, 2, figsize=(11, 4.8))
for ax, name, cmap in zip(axes, ("camera_m0_plus", "camera_m0_minus"), ("inferno", "RdBu_r")):
    o = r[name]
    x, y = 1e3 * o.axes["x_m"], 1e3 * o.axes["y_m"]  # mm; y descends with the rows
    extent = (x[0], x[-1], y[-1], y[0])
    top = np.percentile(np.abs(o.values), 99.5) or 1.0
    lo = -top if name.endswith("minus") else 0.0
    im = ax.imshow(o.values, extent=extent, cmap=cmap, vmin=lo, vmax=top, origin="upper")
    ax.set(title=f"{name.replace('camera_', '').replace('_', ' ')}", xlabel="x (mm)", ylabel="y (mm)")
    fig.colorbar(im, ax=ax, label=o.units.split(" (")[0])  # the unit without its gloss
err = r.manifest["main_output"]["relative_error"]
fig.suptitle(f"{r.manifest['name']}: {r.manifest['samples']:.3g} paths, main output error {100 * err:.2g} %")
fig.tight_layout()
fig.savefig(out / "ldh_image.png", dpi=110)
print(f"wrote {out / 'ldh_image.png'}")
