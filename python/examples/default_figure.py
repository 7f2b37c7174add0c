"""The README's figures of the default experiment, from Python.

    python python/examples/default_figure.py [OUT_DIR]

Runs the built-in default experiment (10⁶ paths, seed 1, as `ohd run`) and writes into OUT_DIR
(default: the current directory) the two figures the README shows, default_m0_plus.png and
default_spectrum.png — the run's own figures, the same bytes as media/readme/ — and the spectrum
drawn again with matplotlib from the arrays, with its ±σ band (default_spectrum_matplotlib.png).
"""
import sys
from pathlib import Path

import numpy as np

import ohd

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
out.mkdir(parents=True, exist_ok=True)
r = ohd.run()  # the default experiment, with a progress bar on a terminal
(out / "default_spectrum.png").write_bytes(r.files["camera_spectrum.png"])
(out / "default_m0_plus.png").write_bytes(r.files["camera_m0_plus.png"])

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

s = r["camera_spectrum"]
f = s.axes["frequency_hz"] / 1e3
db = lambda x: 10 * np.log10(np.where(x > 0, x, np.nan))  # noqa: E731  (empty bins left out)
fig, ax = plt.subplots(figsize=(8, 5))
ax.plot(f, db(s.values))
ax.fill_between(f, db(s.values - s.stderr), db(s.values + s.stderr), alpha=0.3)
ax.set(xlabel="beat frequency (kHz)", ylabel=f"{s.units} (dB)", ylim=(db(s.values.max()) - 50, db(s.values.max()) + 3))
ax.set_title(f"{r.manifest['name']}: diffuse reflectance {r.estimates['reflectance_diffuse'].value:.4f}")
fig.savefig(out / "default_spectrum_matplotlib.png", dpi=120)
print(f"wrote {out / 'default_m0_plus.png'}, {out / 'default_spectrum.png'}, {out / 'default_spectrum_matplotlib.png'}")
