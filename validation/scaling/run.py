#!/usr/bin/env python3
"""1 → 2 thread scaling of `ohd run`, interleaved in one run: for each scene, R repeats of a run on
1 thread and one on 2 threads, alternating, each long enough (a few seconds) that start-up does
not count; paths/s from the manifest (transport only). Reports min/median/max of each and the ratio
of the medians, plus the ratio of each adjacent pair (min–max), since a shared machine drifts.

Usage: python3 validation/scaling/run.py [--repeats R] [--binary target/release/ohd] [--before OTHER_BINARY] [--scenes a,b]
Builds ohd (cargo build --release) unless --binary is given. With --before, an earlier build is
measured too, interleaved with this one (before/after of a change). Needs an otherwise idle machine with
at least 2 cores; the result is printed as a table (and as JSON with --json FILE).
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "validation"))
import ohdpy  # noqa: E402

# name: (config or None for the built-in default, paths for a run of a few seconds on one thread)
SCENES = {
    "vdh_slab": ("validation/vdh_slab.toml", 30_000_000),
    "default": (None, 1_500_000),
    "fmcw_target": ("configs/fmcw_target.toml", 2_000_000),
}


def run(binary, config, paths, threads, out):
    cmd = [binary, "run"] + ([os.path.join(ROOT, config)] if config else [])
    cmd += ["--samples", str(paths), "--threads", str(threads), "--seed", "1", "-q", "--out", out]
    subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL)
    with open(os.path.join(out, "manifest.json")) as f:
        return json.load(f)["run_statistics"]["paths_per_second"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ohdpy.add_binary_argument(ap)
    ap.add_argument("--before", help="an earlier ohd binary, measured interleaved with --binary")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--json")
    a = ap.parse_args()
    binary = ohdpy.binary(a.binary)
    builds = [("before", a.before), ("after", binary)] if a.before else [("", binary)]
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in a.scenes.split(","):
            config, paths = SCENES[name]
            one = {label: [] for label, _ in builds}
            two = {label: [] for label, _ in builds}
            for _ in range(a.repeats):
                for label, b in builds:
                    one[label].append(run(b, config, paths, 1, os.path.join(tmp, name)))
                    two[label].append(run(b, config, paths, 2, os.path.join(tmp, name)))
            for label, _ in builds:
                o, t = one[label], two[label]
                pairs = [y / x for x, y in zip(o, t)]
                r = {
                    "paths": paths,
                    "one_thread": o,
                    "two_threads": t,
                    "ratio_of_medians": statistics.median(t) / statistics.median(o),
                    "pair_ratios": pairs,
                }
                results[f"{name} {label}".strip()] = r
                print(f"{name:<12}{label:>7} 1 thread {min(o)/1e3:8.0f} {statistics.median(o)/1e3:8.0f} {max(o)/1e3:8.0f}"
                      f"   2 threads {min(t)/1e3:8.0f} {statistics.median(t)/1e3:8.0f} {max(t)/1e3:8.0f} paths/ms"
                      f"   ratio {r['ratio_of_medians']:.3f} (pairs {min(pairs):.3f}–{max(pairs):.3f})", flush=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
