#!/usr/bin/env python3
"""Issue 53, "the estimator becomes a type": instructions per path of two builds, side by side.

Each case runs once per binary under callgrind, one thread, counting only the instructions inside the
batch loop (`--toggle-collect=*run_batch*`: transport and tallies, without start-up and output), the
repeatable figure on a loaded machine; the ratio is candidate / baseline. The cases are the shipped
configs the issue names (the van de Hulst slab, the built-in default, retina_ldh, fmcw_target,
wind_sunny), a surfaces fixture (opaque solids and rough faces), and the estimators the walk is
generic over: camera paths (vessels_ldh with `estimator = "camera"`), the layered control variate
(vessels_ldh as shipped) and weight windows.

    python3 validation/estimator/instructions.py --baseline OLD/ohd --candidate NEW/ohd [--only REGEX]

Counts are cached per binary (its path, size and modification time) and case in
/tmp/ohd_instructions.json, so a baseline is measured once across candidates.
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent.parent

# (name, config or None for the built-in default, --set values, paths under callgrind)
CASES = [
    ("vdh_slab", "validation/vdh_slab.toml", [], 50_000),
    ("default", None, [], 4_000),
    ("retina_ldh", "configs/retina_ldh.toml", [], 400),
    ("fmcw_target", "configs/fmcw_target.toml", [], 4_000),
    ("wind_sunny", "configs/wind_sunny.toml", [], 1_000),
    ("surfaces (opaque_rough)", "tests/configs/good/opaque_rough.toml", [], 20_000),
    ("vessels_ldh (control variate)", "configs/vessels_ldh.toml", [], 4_000),
    (
        "vessels_ldh camera paths",
        "configs/vessels_ldh.toml",
        ['detectors.0.estimator="camera"', 'run.control_variate="off"'],
        4_000,
    ),
    ("vessels_ldh weight windows", "configs/vessels_ldh.toml", ['run.importance="windows"'], 4_000),
]


CACHE = Path(tempfile.gettempdir()) / "ohd_instructions.json"


def instructions(ohd, case, work):
    st = os.stat(ohd)
    key = f"{os.path.abspath(ohd)}:{st.st_size}:{st.st_mtime_ns}:{case!r}"
    cache = json.loads(CACHE.read_text()) if CACHE.exists() else {}
    if key not in cache:
        cache[key] = measure(ohd, case, work)
        CACHE.write_text(json.dumps(cache, indent=1))
    return tuple(cache[key])


def measure(ohd, case, work):
    name, cfg, sets, paths = case
    out = Path(work) / re.sub(r"\W+", "_", name)
    f = Path(work) / "cg.out"
    cmd = [str(ohd), "run"] + ([str(ROOT / cfg)] if cfg else [])
    cmd += ["--out", str(out), "--threads", "1", "--samples", str(paths)]
    for s in sets:
        cmd += ["--set", s]
    full = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={f}", "--toggle-collect=*run_batch*"] + cmd
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    r = subprocess.run(full, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, text=True)
    if r.returncode != 0:
        sys.exit(f"{name}: {' '.join(cmd)} failed:\n{r.stderr[-2000:]}")
    text = f.read_text(errors="replace")
    m = re.search(r"^summary:\s+(\d+)", text, re.M) or re.search(r"^totals:\s+(\d+)", text, re.M)
    f.unlink()
    # (Per path of the run's --samples: a scan's pointings each trace them.)
    return int(m.group(1)), paths


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--baseline", required=True)
    ap.add_argument("--candidate", required=True)
    ap.add_argument("--only", help="regular expression on the case names")
    a = ap.parse_args()
    print("| case | paths | baseline instr./path | candidate instr./path | ratio |")
    print("|---|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory(prefix="ohd_instr_") as work:
        for case in CASES:
            if a.only and not re.search(a.only, case[0]):
                continue
            (ib, pb), (ic, _) = (instructions(a.baseline, case, work), instructions(a.candidate, case, work))
            print(f"| {case[0]} | {pb} | {ib / pb:,.0f} | {ic / pb:,.0f} | {ic / ib:.4f} |", flush=True)


if __name__ == "__main__":
    main()
