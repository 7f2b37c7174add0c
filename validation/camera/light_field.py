#!/usr/bin/env python3
"""The vessel pixels of retina_ldh: camera paths from the footprints as shipped against the same
camera paths connected to the layered scene's light field below the regions
(`[detectors.footprints] light_field = true`, issue 54 item 3), side by side in one sitting.

Each seed runs both, alternating, as whole processes (wall seconds), with the figures of
`footprints.py` over the 1,170 pixels of the vessels' footprints: the RMS relative error eps of
M0+ and of the intensity, the efficiency 1/(eps^2 t) and its ratio light field / shipped per seed,
the tail slope and the top-1 % share of the footprints' variance, the pixels below -3 sigma, the
footprints' mean M0+, and the background's median errors. The agreement of the two estimators'
means over the footprints (M0+ and intensity, z from the runs' own errors) is printed per seed:
the light field's table is a fixed estimate (its seed is the run's), so a difference beyond the
runs' errors is its bias.

    python3 validation/camera/light_field.py [--binary PATH] [--seeds 1,2,3] [--samples N]
        [--field-paths N] [--config retina_ldh|vessels_ldh|PATH] [--work DIR] [--json FILE]
"""
import argparse
import json
import os
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import footprints  # noqa: E402
from footprints import ROOT, figures, np, spread  # noqa: E402


def mean_and_error(out, name):
    mask = np.load(os.path.join(out, "camera_region_mask.npy")) > 0
    v = np.load(os.path.join(out, f"camera_{name}.npy"))[mask]
    s = np.load(os.path.join(out, f"camera_{name}_stderr.npy"))[mask]
    return float(v.mean()), float(np.sqrt((s**2).sum()) / mask.sum())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--binary", default=os.path.join(ROOT, "target", "release", "ohd"))
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--samples", type=float, default=None)
    ap.add_argument("--field-paths", type=float, default=None)
    ap.add_argument("--config", default="retina_ldh")
    ap.add_argument("--work", default=None)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    config = args.config if args.config.endswith(".toml") else os.path.join(ROOT, "configs", args.config + ".toml")
    footprints.CONFIG = config
    work = args.work or tempfile.mkdtemp(prefix="ohd-light-field-")
    os.makedirs(work, exist_ok=True)
    common = [f"run.samples={int(args.samples)}"] if args.samples else []
    field = common + ["detectors.0.footprints.light_field=true"]
    if args.field_paths:
        field.append(f"detectors.0.footprints.field_paths={int(args.field_paths)}")
    arms = [("shipped", common), ("light_field", field)]
    rows = {name: [] for name, _ in arms}
    agree = []
    for seed in [int(s) for s in args.seeds.split(",")]:
        outs = {}
        for name, sets in arms:
            out = os.path.join(work, f"{name}_{seed}")
            wall = footprints.run(args.binary, out, seed, sets)
            f = figures(out, wall)
            rows[name].append(f)
            outs[name] = out
            print(f"  seed {seed} {name}: {wall:.1f} s, eps M0+ {f['eps_m0']:.3f}, slope {f['slope_m0']:.2f}",
                  file=sys.stderr, flush=True)
        for what in ["m0_plus", "image"]:
            (a, sa), (b, sb) = (mean_and_error(outs[n], what) for n, _ in arms)
            z = (b - a) / np.hypot(sa, sb)
            agree.append((seed, what, a, sa, b, sb, z))
    print(f"\n{os.path.basename(config)}, footprints' pixels: camera paths from the footprints as shipped against "
          f"light_field = true ({' '.join(field)}), seeds {args.seeds}; min / median / max\n")
    print("| figure | shipped | light field |")
    print("|---|---|---|")
    for k in rows["shipped"][0]:
        print(f"| {k} | {spread([r[k] for r in rows['shipped']])} | {spread([r[k] for r in rows['light_field']])} |")
    ratios = [b["efficiency"] / a["efficiency"] for a, b in zip(rows["shipped"], rows["light_field"])]
    print(f"\nefficiency 1/(eps^2 t) of M0+ at the footprints, light field / shipped per seed: {spread(ratios)}")
    print("\nmeans over the footprints (light field - shipped, in the runs' own errors):")
    for seed, what, a, sa, b, sb, z in agree:
        print(f"  seed {seed} {what}: {a:.4e} ± {sa:.1e} against {b:.4e} ± {sb:.1e}, z {z:+.2f}")
    if args.json:
        json.dump({"sets": field, "rows": rows, "ratios": ratios, "agree": agree}, open(args.json, "w"), indent=1)


if __name__ == "__main__":
    main()
