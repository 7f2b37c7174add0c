#!/usr/bin/env python3
"""Cost of the deterministic unscattered reflections against the number of interfaces (issue 52,
item 6): whole-process times of `ohd run` on a stack of N thin clear layers of alternating index
(1.40 / 1.41, 1 µm each, over water) under a pencil beam and a forward camera, with
`run.reflections = "deterministic"`, "auto" and "sampled", for two builds interleaved (before and
after a change), R repeats each. Reports min/median/max seconds per case; a run past --timeout is
stopped and reported as such.

Before issue 52 the way up from each interface was traced layer by layer: N²/2 crossings per
path (1,000 interfaces: 17–37 s against 0.1–0.25 s sampled; 3,000 timed out). After, a stack of
homogeneous layers costs 2N steps per path (`core/src/transport/nee.rs`, `reflections_below`).

Measured (issue 52; a8c4817 before, after the change; 1,000 paths, 3 repeats, whole-process
seconds min / median / max, on a shared 2-core machine; a run stopped at 150 s is not repeated):

    interfaces  reflections          after                   before
            10  deterministic  0.066 0.070 0.070     0.069 0.071 0.071
            10  auto           0.064 0.068 0.070     0.070 0.071 0.073
            10  sampled        0.038 0.067 0.070     0.068 0.071 0.071
           100  deterministic  0.070 0.071 0.071     0.122 0.130 0.174
           100  auto           0.068 0.071 0.072     0.122 0.172 0.172
           100  sampled        0.038 0.070 0.071     0.064 0.072 0.072
         1,000  deterministic  0.171 0.217 0.226     4.665 4.674 4.694
         1,000  auto           0.131 0.139 0.174     4.772 4.940 6.032
         1,000  sampled        0.121 0.126 0.132     0.122 0.130 0.176
         3,000  deterministic  0.625 1.476 1.554     > 150 (stopped)
         3,000  auto           1.372 1.556 1.727     > 150 (stopped)
         3,000  sampled        0.569 0.723 0.752     0.648 0.727 0.839

Usage: python3 validation/scaling/reflections.py --binary NEW/ohd [--before OLD/ohd]
           [--interfaces 10,100,1000,3000] [--samples 1000] [--repeats 3] [--timeout 120]
           [--modes deterministic,auto,sampled] [--json FILE]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time


def config(n, mode, samples):
    """The stack of `n` layers (n interfaces below the surface) with `run.reflections = mode`."""
    lines = [
        "schema_version = 1",
        f'name = "interfaces_{n}"',
        "[run]",
        f"samples = {samples}",
        "seed = 11",
        "batches = 16",
        f'reflections = "{mode}"',
        "[source]",
        "wavelength_nm = 785",
        "position_mm = [0, 0, -1]",
        "[ambient]",
        "n_above = 1.0",
        "n_below = 1.33",
        "[media.clear]",
        "sigma_a_per_mm = 0.1",
        "sigma_s_per_mm = 0",
        'phase = { type = "hg", g = 0.9 }',
    ]
    for j in range(n):
        lines += ["[[layers]]", "thickness_um = 1", f"n = {1.40 if j % 2 == 0 else 1.41}", 'medium = "clear"']
    lines += [
        "[[detectors]]",
        'name = "camera"',
        'area = { type = "rect", size_mm = [1, 1] }',
        "acceptance_half_angle_deg = 20",
        "include_specular = false",
        "image = { pixels = [8, 8] }",
    ]
    return "\n".join(lines) + "\n"


def timed(binary, cfg, out, timeout):
    """Whole-process seconds of `ohd run`, or None past `timeout` (the run is stopped)."""
    t = time.perf_counter()
    try:
        subprocess.run([binary, "run", cfg, "--quiet", "--out", out], check=True, timeout=timeout,
                       stdout=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return None
    return time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--binary", required=True, help="the build measured (after the change)")
    ap.add_argument("--before", help="an earlier build, measured interleaved with --binary")
    ap.add_argument("--interfaces", default="10,100,1000,3000")
    ap.add_argument("--modes", default="deterministic,auto,sampled")
    ap.add_argument("--samples", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("--json", help="write the times here too")
    a = ap.parse_args()
    builds = [("after", a.binary)] + ([("before", a.before)] if a.before else [])
    counts = [int(x) for x in a.interfaces.split(",")]
    modes = a.modes.split(",")
    times = {}
    with tempfile.TemporaryDirectory() as tmp:
        for n in counts:
            for mode in modes:
                cfg = os.path.join(tmp, f"stack_{n}_{mode}.toml")
                with open(cfg, "w") as f:
                    f.write(config(n, mode, a.samples))
                for r in range(a.repeats):
                    for name, binary in builds:
                        # One build's timeout is not repeated: its later repeats would time out too.
                        key = (name, n, mode)
                        if None in times.get(key, []):
                            continue
                        out = os.path.join(tmp, f"out_{name}_{n}_{mode}_{r}")
                        times.setdefault(key, []).append(timed(binary, cfg, out, a.timeout))
                        subprocess.run(["rm", "-rf", out], check=True)
    print(f"{a.samples} paths, {a.repeats} repeats, whole-process seconds (min / median / max)")
    print(f"{'interfaces':>10} {'reflections':>14} " + " ".join(f"{name:>26}" for name, _ in builds))
    for n in counts:
        for mode in modes:
            cells = []
            for name, _ in builds:
                ts = times[(name, n, mode)]
                if None in ts:
                    cells.append(f"{'> ' + format(a.timeout, 'g') + ' s (stopped)':>26}")
                else:
                    cells.append(f"{min(ts):8.3f} {statistics.median(ts):8.3f} {max(ts):8.3f}")
            print(f"{n:>10} {mode:>14} " + " ".join(cells))
    if a.json:
        with open(a.json, "w") as f:
            json.dump([{"build": k[0], "interfaces": k[1], "reflections": k[2], "seconds": v}
                       for k, v in times.items()], f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
