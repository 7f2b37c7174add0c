"""Coherent Doppler wind lidar: the VAD scan of configs/wind_sunny.toml (four azimuths at 60°
elevation), the wind retrieved per range gate against the log-law profile the scene carries.

    python python/examples/lidar_vad.py [--samples N] [OUT_DIR]

Writes lidar_vad.png into OUT_DIR (default: the current directory). The configuration's 2·10⁶
paths per pointing take about 10 s on 2 cores.
"""
import argparse
import csv
import io
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
parser.add_argument("--samples", type=float, default=None, help="paths per pointing (default: the configuration's)")
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)

r = ohd.run(ROOT / "configs" / "wind_sunny.toml", samples=args.samples, seed=1, figures=False)
rows = list(csv.DictReader(io.StringIO(r.files["vad.csv"].decode())))
z = np.array([float(row["height_m"]) for row in rows])
col = lambda k: np.array([float(row[k]) if row[k] else np.nan for row in rows])  # noqa: E731
# The scene's wind: a log law u(z) = U_ref ln(z/z0)/ln(z_ref/z0), blowing from direction_from_deg.
wind = r.pointings[0].manifest["config"]["wind"]
u_ref, z_ref, z0 = wind["speed_m_per_s"], wind["reference_height_m"], wind["roughness_length_m"]
speed = u_ref * np.log(np.maximum(z, z0) / z0) / math.log(z_ref / z0)
to = math.radians(wind["direction_from_deg"] + 180.0)  # where it blows to, clockwise from north
fig, ax = plt.subplots(figsize=(6.5, 6))
for key, label, truth, color in (
    ("u_east_m_per_s", "u (east)", speed * math.sin(to), "C0"),
    ("v_north_m_per_s", "v (north)", speed * math.cos(to), "C1"),
    ("w_up_m_per_s", "w (up)", 0 * z, "C2"),
):
    ax.errorbar(col(key), z, xerr=col(key.split("_")[0] + "_stderr"), fmt="o", ms=3, color=color, label=f"{label}, retrieved")
    ax.plot(truth, z, "-", color=color, alpha=0.5, label=f"{label}, the scene's")
ax.set(xlabel="wind component (m/s)", ylabel="height (m)", title=f"{r.pointings[0].manifest['name']}: VAD wind per gate")
ax.legend(fontsize=8, loc="center right")
fig.tight_layout()
fig.savefig(out / "lidar_vad.png", dpi=110)
print(f"wrote {out / 'lidar_vad.png'}")
