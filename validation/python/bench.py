"""The Python package's cost against the CLI (issue 23's note).

    python validation/python/bench.py [--repeats 7] [--binary PATH]

1. Per-run overhead on the default experiment (10⁶ paths, figures on, as `ohd run`): wall time of
   `ohd run --out DIR --quiet` (a process: start-up, run, files written) against `ohd.run()`
   (in memory) and `ohd.run()` + `save(DIR)`, alternated, `--repeats` each; min and median.
   Compare builds of the same optimisation (the CLI of `cargo build --profile ci` and the package
   as .ci/run builds it, or both release).
2. Memory of a result of configs/retina_ldh.toml (the LDH camera): the bytes it holds (its files)
   and the process's resident-memory growth from making it.

Measured 2026-11-24 on the shared 2-core machine (load ≈ 5 from other builds, so ±5 % noise), CLI
and package both of the `ci` profile, 7 runs each: CLI min 3.680 s, median 3.932 s; `ohd.run()`
min 3.656 s (−0.7 %), median 3.731 s (−5.1 %); with `save()` min 3.835 s (+4.2 %), median 3.892 s
(−1.0 %). A retina_ldh result (2·10⁵ paths, figures on): 67 files, 16.4 MiB held (10.8 MiB of
them .npy, which the arrays view without a copy), resident memory +11.0 MiB.

Needs the package installed (pip install ./python). The binary is --binary, else $OHD_BINARY,
else a release build (validation/ohdpy.py).
"""
import argparse
import gc
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import ohd

ROOT = Path(__file__).resolve().parents[2]


def rss_mib():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--binary")
    ap.add_argument("--ldh-samples", type=int, default=200_000)
    a = ap.parse_args()
    binary = a.binary or os.environ.get("OHD_BINARY")
    if not binary:
        sys.path.insert(0, str(ROOT / "validation"))
        import ohdpy

        binary = ohdpy.binary()

    times = {"cli": [], "python": [], "python+save": []}
    with tempfile.TemporaryDirectory() as tmp:
        ohd.run(progress=False)  # warm-up: page cache, the extension loaded
        for i in range(a.repeats):
            t = time.perf_counter()
            subprocess.run([binary, "run", "--out", f"{tmp}/cli", "--quiet"], check=True, capture_output=True)
            times["cli"].append(time.perf_counter() - t)
            t = time.perf_counter()
            r = ohd.run(progress=False)
            times["python"].append(time.perf_counter() - t)
            r.save(f"{tmp}/py")
            times["python+save"].append(time.perf_counter() - t)
            del r
    print(f"default experiment, {a.repeats} runs each (s):")
    base = min(times["cli"]), statistics.median(times["cli"])
    for k, v in times.items():
        lo, med = min(v), statistics.median(v)
        print(f"  {k:12s} min {lo:.3f}  median {med:.3f}  ({100 * (lo / base[0] - 1):+.1f} % / {100 * (med / base[1] - 1):+.1f} % against the CLI)")

    gc.collect()
    before = rss_mib()
    r = ohd.run(ROOT / "configs" / "retina_ldh.toml", samples=a.ldh_samples, progress=False)
    _ = r.outputs  # the arrays: views of the files' bytes, no copies
    gc.collect()
    after = rss_mib()
    held = sum(len(b) for b in r.files.values())
    npy = sum(len(b) for n, b in r.files.items() if n.endswith(".npy"))
    print(
        f"retina_ldh result ({a.ldh_samples} paths, figures on): {len(r.files)} files, {held / 2**20:.1f} MiB held "
        f"({npy / 2**20:.1f} MiB of .npy), {len(r.outputs)} outputs; resident memory +{after - before:.1f} MiB"
    )


if __name__ == "__main__":
    main()
