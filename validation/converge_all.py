#!/usr/bin/env python3
"""Error against run time on every shipped experiment: `ohd converge` on each of configs/*.toml
and validation/vdh_slab.toml, then one markdown table of the main outputs and the agreement of each
run's own σ with its measured error.

    python3 validation/converge_all.py [--budget-seconds 60] [--out out/converge_all] [--binary PATH | --no-build]

Runs --binary PATH, else builds ohd once (cargo build --release; --no-build: use the last build). Prints the table to stdout.
"""

import argparse
import json
import math
import pathlib
import subprocess
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import ohdpy  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parent.parent


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--budget-seconds", type=float, default=60.0)
    ap.add_argument("--out", default=str(ROOT / "out" / "converge_all"))
    ap.add_argument("--no-build", action="store_true", help="without --binary: the last release build, not rebuilt")
    ohdpy.add_binary_argument(ap)
    args = ap.parse_args()
    if args.no_build and args.binary is None:
        ohd = ohdpy.target_dir() / "release" / "ohd"
    else:
        ohd = pathlib.Path(ohdpy.binary(args.binary))
    configs = sorted((ROOT / "configs").glob("*.toml")) + [ROOT / "validation" / "vdh_slab.toml"]
    rows = []
    for cfg in configs:
        out = pathlib.Path(args.out) / cfg.stem
        print(f"converge {cfg.relative_to(ROOT)} …", file=sys.stderr)
        subprocess.run(
            [str(ohd), "converge", str(cfg), "--out", str(out), "--budget-seconds", str(args.budget_seconds), "-q"],
            cwd=ROOT,
            check=True,
            stderr=subprocess.DEVNULL,
        )
        rows.append((cfg, json.loads((out / "converge.json").read_text())))

    def fmt(v, f="{:.3g}"):
        return "—" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f.format(v)

    print("| experiment | main output | rungs (paths) | reference | slope vs s | σ slope vs paths | σ ratio per rung (min–max) | σ ratio rms | s to 1 % | s to 0.1 % | arrays in [0.5, 2] | scalars: pooled σ ratio (n) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for cfg, j in rows:
        main = j["main_output"]
        o = j["outputs"].get(main, {})
        rungs = j["rungs"]
        ratios = [r for r in (o.get("sigma_ratio") or []) if r is not None]
        arrays = [(k, v) for k, v in j["outputs"].items() if v["metric"] == "relative_rms"]
        ok = sum(1 for _, v in arrays if v["sigma_agrees"])
        scal = [r for v in j["outputs"].values() if v["metric"] == "absolute" for r in v["sigma_ratio"] if r is not None]
        pooled = math.sqrt(sum(r * r for r in scal) / len(scal)) if scal else float("nan")
        ref = j["reference_run"]
        print(
            f"| `{cfg.relative_to(ROOT)}` | `{main}` | {rungs[0]['samples']:,}–{rungs[-1]['samples']:,} "
            f"| {o.get('reference', '—')}{' (' + format(ref['samples'], ',') + ')' if ref else ''} "
            f"| {fmt(o.get('slope'), '{:+.2f}')} | {fmt(o.get('stderr_slope'), '{:+.3f}')} "
            f"| {fmt(min(ratios) if ratios else None, '{:.2f}')}–{fmt(max(ratios) if ratios else None, '{:.2f}')} "
            f"| {fmt(o.get('sigma_ratio_rms'), '{:.2f}')} | {fmt(o.get('seconds_to_1_percent'))} "
            f"| {fmt(o.get('seconds_to_0_1_percent'))} | {ok} of {len(arrays)} | {fmt(pooled, '{:.2f}')} ({len(scal)}) |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
