#!/usr/bin/env python3
"""Byte identity of two ohd builds on every shipped config and validation case.

A refactoring that must not change behaviour is checked by running each case with a baseline
binary and a candidate binary and comparing every file they write, byte for byte. The only
exceptions are the numbers that measure time (wall seconds, paths per second, ...): in JSON
files they are masked by key name before comparing, and the figures and CSV files of
`ohd converge` (drawn from timings) are left out.

    python3 validation/identity/check.py --baseline OLD/ohd [--candidate NEW/ohd]

The candidate (alias --binary) defaults to a fresh release build of this tree (cargo build --release).

Cases (see `cases()`): `ohd run` on every configs/*.toml, validation/*.toml,
validation/features/*.toml, validation/vdb/vessels_bench.toml and tests/configs/good/*.toml
(with --samples N, default 20000, unless the case sets fewer), the built-in default, an LDH
camera with the sign flipped (mirrored spectra) and speckle, a run in
3 shards merged, a run with --target-error, a checkpointed run, `ohd converge` with a fixed
ladder, the pilots' decisions (`estimator = "auto"`, each `run.importance`, both in shards merged
and in a checkpointed run), and `ohd mie` with a table. Baseline outputs are cached in --work/baseline (delete it,
or pass --fresh, after changing the baseline binary).

Exit status 0 when every case matches, 1 otherwise (the differing files are listed).
"""

import argparse
import glob
import json
import os
import re
import shutil
import subprocess
import sys
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "validation"))
import ohdpy  # noqa: E402

# JSON keys whose values measure time, not physics: masked before comparing.
TIMING_KEY = re.compile(r"(seconds|per_second|wall|elapsed|^slope)")
# Files that are drawn from timings (ohd converge's fits, table and figure), and the shard files
# (intermediate, with their timings inside: the merged outputs are compared instead).
TIMING_FILES = {"converge.csv", "converge.png", "converge.svg", "shard.ohd"}


def cases(samples):
    """(name, [argument lists of ohd, run in order, each with {out} for the output directory])."""
    out = []
    configs = sorted(
        glob.glob(os.path.join(ROOT, "configs", "*.toml"))
        + glob.glob(os.path.join(ROOT, "validation", "*.toml"))
        + glob.glob(os.path.join(ROOT, "validation", "features", "*.toml"))
        + glob.glob(os.path.join(ROOT, "validation", "vdb", "*.toml"))
        + glob.glob(os.path.join(ROOT, "tests", "configs", "good", "*.toml"))
    )
    for c in configs:
        rel = os.path.relpath(c, ROOT)
        name = rel.replace("/", "__")[:-5]
        out.append((name, [["run", c, "--samples", str(samples), "--quiet", "--out", "{out}"]]))
    out.append(("builtin_default", [["run", "--samples", str(samples), "--quiet", "--out", "{out}"]]))
    retina = os.path.join(ROOT, "configs", "retina_ldh.toml")
    out.append(
        (
            "shards_merged",
            [["run", retina, "--samples", str(samples), "--quiet", "--shard", f"{i}/3", "--out", "{out}/s%d" % i]
             for i in range(3)]
            + [["merge", "{out}/s0", "{out}/s1", "{out}/s2", "--out", "{out}/merged"]],
        )
    )
    full = os.path.join(ROOT, "validation", "features", "ldh_full_spectra.toml")
    out.append(
        (
            "ldh_flip_sign_speckle",
            [["run", full, "--samples", str(samples), "--quiet", "--set", "detectors.0.ldh.flip_sign=true",
              "--set", "detectors.0.ldh.speckle={ windows = 4 }", "--out", "{out}"]],
        )
    )
    wind = os.path.join(ROOT, "configs", "wind_sunny.toml")
    out.append(
        (
            "scan_shards_merged",
            [["run", wind, "--samples", str(samples), "--quiet", "--shard", f"{i}/2", "--out", "{out}/s%d" % i]
             for i in range(2)]
            + [["merge", "{out}/s0", "{out}/s1", "--out", "{out}/merged"]],
        )
    )
    default = os.path.join(ROOT, "configs", "default.toml")
    out.append(
        (
            "target_error",
            [["run", default, "--samples", str(samples), "--quiet", "--target-error", "0.05",
              "--max-samples", str(16 * samples), "--out", "{out}"]],
        )
    )
    out.append(
        (
            "checkpointed",
            [["run", default, "--samples", str(samples), "--quiet", "--checkpoint-seconds", "0.001",
              "--out", "{out}"]],
        )
    )
    slab = os.path.join(ROOT, "validation", "vdh_slab.toml")
    out.append(
        (
            "converge",
            [["converge", slab, "--samples", str(4 * samples), "--rungs", "3", "--quiet", "--out", "{out}"]],
        )
    )
    # The pilots' decisions (`estimator = "auto"`, `run.importance`), recorded in the manifest, in
    # a run, in shards merged and in a checkpointed run.
    camera = os.path.join(ROOT, "tests", "configs", "good", "camera_estimator.toml")
    auto = ["--set", 'detectors.0.estimator="auto"']
    out.append(("pilot_estimator_auto", [["run", camera, "--samples", str(samples), "--quiet"] + auto
                                         + ["--out", "{out}"]]))
    for importance in ["auto", "windows", "guided", "table"]:
        out.append(
            (
                f"pilot_importance_{importance}",
                [["run", default, "--samples", str(samples), "--quiet", "--set", f'run.importance="{importance}"',
                  "--out", "{out}"]],
            )
        )
    dcs = os.path.join(ROOT, "configs", "dcs_forearm.toml")
    out.append(("pilot_importance_auto_dcs", [["run", dcs, "--samples", str(samples), "--quiet", "--set",
                                              'run.importance="auto"', "--out", "{out}"]]))
    both = auto + ["--set", 'run.importance="auto"']
    out.append(
        (
            "pilots_shards_merged",
            [["run", camera, "--samples", str(samples), "--quiet", "--shard", f"{i}/2", "--out", "{out}/s%d" % i]
             + both for i in range(2)]
            + [["merge", "{out}/s0", "{out}/s1", "--out", "{out}/merged"]],
        )
    )
    out.append(
        (
            "pilots_checkpointed",
            [["run", default, "--samples", str(samples), "--quiet", "--checkpoint-seconds", "0.001", "--set",
              'run.importance="auto"', "--out", "{out}"]],
        )
    )
    out.append(
        (
            "mie_table",
            [["mie", "--m-real", "1.06", "--m-imag", "0.001", "--x", "25", "--angles", "181",
              "--table", "{out}/table.csv"]],
        )
    )
    return out


def run_case(binary, steps, dest):
    """Run `steps` into `dest`; returns (exit codes, stdout of the steps)."""
    if os.path.exists(dest):
        shutil.rmtree(dest)
    os.makedirs(dest)
    codes, stdout = [], []
    for args in steps:
        args = [a.replace("{out}", dest) for a in args]
        p = subprocess.run([os.path.abspath(binary)] + args, capture_output=True, text=True, cwd=ROOT)
        codes.append(p.returncode)
        # Paths and timings in the printed text differ by construction; keep it only for `mie`,
        # whose stdout is its output.
        stdout.append(p.stdout if args[0] == "mie" else "")
        if p.returncode != 0:
            with open(os.path.join(dest, "_stderr.txt"), "a") as f:
                f.write(p.stderr)
    return codes, stdout


def mask(v):
    if isinstance(v, dict):
        return {k: ("<time>" if TIMING_KEY.search(k) else mask(x)) for k, x in v.items()}
    if isinstance(v, list):
        return [mask(x) for x in v]
    return v


def read(path, names):
    """A file's bytes with the run's own paths (`names`: binary, output directory) blanked."""
    with open(path, "rb") as f:
        data = f.read()
    for n in names:
        data = data.replace(n.encode(), b"<path>")
    return data


def without_additions(base, cand):
    """`cand` without the dictionary keys (at any depth) that `base` does not have."""
    if isinstance(base, dict) and isinstance(cand, dict):
        return {k: without_additions(base[k], x) for k, x in cand.items() if k in base}
    if isinstance(base, list) and isinstance(cand, list) and len(base) == len(cand):
        return [without_additions(x, y) for x, y in zip(base, cand)]
    return cand


def differing(a, b, names_a, names_b, additions=False):
    """Relative paths of files that differ between trees `a` and `b` (or exist in one only);
    `names_a`, `names_b`: strings (binary, directory) that may appear in the files and differ.
    With `additions`, files only in `b` and JSON keys only in `b` are allowed (new outputs); a
    manifest's `files` list is then compared without them."""
    bad = []
    fa, fb = set(), set()
    for base, acc in ((a, fa), (b, fb)):
        for d, _, files in os.walk(base):
            for f in files:
                if f == "_stderr.txt":
                    continue
                acc.add(os.path.relpath(os.path.join(d, f), base))
    for rel in sorted(fa ^ fb):
        if additions and rel in fb:
            continue
        bad.append(rel + " (only in " + ("baseline" if rel in fa else "candidate") + ")")
    for rel in sorted(fa & fb):
        pa, pb = os.path.join(a, rel), os.path.join(b, rel)
        if os.path.basename(rel) in TIMING_FILES:
            continue
        da, db = read(pa, names_a), read(pb, names_b)
        if rel.endswith(".json"):
            ja, jb = json.loads(da), json.loads(db)
            if additions:
                jb = without_additions(ja, jb)
                if isinstance(jb, dict) and isinstance(jb.get("files"), list):
                    jb["files"] = [f for f in jb["files"] if f in ja.get("files", [])]
            if mask(ja) != mask(jb):
                bad.append(rel)
        elif da != db:
            bad.append(rel)
    return bad


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--baseline", required=True, help="ohd binary of the reference commit")
    ap.add_argument("--candidate", "--binary", metavar="PATH",
                    help="ohd binary under test (default: cargo build --release, then target/release/ohd)")
    ap.add_argument("--samples", type=int, default=20000)
    ap.add_argument("--work", default="/tmp/ohd_identity")
    ap.add_argument("--only", help="regular expression on case names")
    ap.add_argument("--fresh", action="store_true", help="re-run the baseline even if cached")
    ap.add_argument("--additions", action="store_true",
                    help="allow files and JSON keys that only the candidate writes (new outputs)")
    a = ap.parse_args()
    a.candidate = ohdpy.binary(a.candidate)
    failed = 0
    all_cases = [c for c in cases(a.samples) if not a.only or re.search(a.only, c[0])]
    t0 = time.time()
    for name, steps in all_cases:
        bdir = os.path.join(a.work, "baseline", name)
        cdir = os.path.join(a.work, "candidate", name)
        stamp = os.path.join(bdir, "_codes.json")
        if a.fresh or not os.path.exists(stamp):
            codes, stdout = run_case(a.baseline, steps, bdir)
            with open(stamp, "w") as f:
                json.dump({"codes": codes, "stdout": stdout}, f)
        with open(stamp) as f:
            base = json.load(f)
        codes, stdout = run_case(a.candidate, steps, cdir)
        with open(os.path.join(cdir, "_codes.json"), "w") as f:
            json.dump({"codes": codes, "stdout": stdout}, f)
        problems = []
        if codes != base["codes"]:
            problems.append(f"exit codes {codes} (baseline {base['codes']})")
        if stdout != base["stdout"]:
            problems.append("stdout differs")
        problems += differing(bdir, cdir, [os.path.abspath(a.baseline), bdir], [os.path.abspath(a.candidate), cdir],
                              a.additions)
        nfiles = sum(len(f) for _, _, f in os.walk(cdir))
        if problems:
            failed += 1
            print(f"DIFF {name}: " + "; ".join(problems[:8]) + (" ..." if len(problems) > 8 else ""))
        else:
            print(f"same {name} ({nfiles} files, exit {codes})")
        sys.stdout.flush()
    print(f"{len(all_cases) - failed} identical, {failed} differing ({time.time() - t0:.0f} s)")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
