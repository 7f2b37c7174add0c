#!/usr/bin/env python3
"""Mitsuba 3's BSDFs as reference lobes for ohd's (issue 38): `roughconductor`, `roughdielectric`
and `diffuse`, each sampled at 3 incidence angles (and the rough ones at 3 roughnesses), the
sampled weights histogrammed over the directions they go to.

    python3 validation/peers/bsdf_lobes.py            # writes validation/peers/mitsuba_bsdf_lobes.json

The JSON is what `cargo test --test it peers::` holds ohd's BSDFs against (by χ² over the bins and
their albedos within σ), so that the tests need no Mitsuba; this script regenerates it. Installs
mitsuba==3.9.1 into validation/.venv (as validation/peers/run.py does).

Each case: Mitsuba's `scalar_rgb` variant, `TransportMode.Importance` (the power weights a light
path carries, as ohd's forward walk: a refraction's weight has no η² factor), GGX with visible
normals (Mitsuba's default); `wi = (sin θi, 0, cos θi)` in the surface's frame; N draws; in bin
(μ = cos θo over [−1, 1] in 20 bins, φo over [0, 2π) in 18 bins) the mean of `w·[wo in bin]`
over the N draws and its variance of the mean. The sum over bins is the albedo.
"""

import json
import math
import os
import random
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import ohdpy  # noqa: E402

MITSUBA_VERSION = "3.9.1"
# Copper at 1550 nm (Johnson & Christy 1972, ohd's table): n + ik relative to air.
COPPER = (0.7158, 10.66)
GLASS = 1.5
ALPHAS = [0.05, 0.3, 0.7]
ANGLES = [0.0, 40.0, 75.0]
MU_BINS, PHI_BINS = 20, 18
DRAWS = 400_000


def cases():
    out = []
    for a in ALPHAS:
        for t in ANGLES:
            out.append({"bsdf": "roughconductor", "alpha": a, "theta_deg": t, "eta": COPPER[0], "k": COPPER[1]})
    for a in ALPHAS:
        for t in ANGLES:
            out.append({"bsdf": "roughdielectric", "alpha": a, "theta_deg": t, "ext_ior": 1.0, "int_ior": GLASS})
    for t in ANGLES:
        out.append({"bsdf": "diffuse", "theta_deg": t, "reflectance": 0.5})
    return out


def plugin(mi, c):
    if c["bsdf"] == "roughconductor":
        return mi.load_dict({"type": "roughconductor", "distribution": "ggx", "alpha": c["alpha"],
                             "eta": c["eta"], "k": c["k"]})
    if c["bsdf"] == "roughdielectric":
        return mi.load_dict({"type": "roughdielectric", "distribution": "ggx", "alpha": c["alpha"],
                             "int_ior": c["int_ior"], "ext_ior": c["ext_ior"]})
    return mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": [c["reflectance"]] * 3}})


def lobe(mi, c, draws, rng):
    bsdf = plugin(mi, c)
    ctx = mi.BSDFContext(mi.TransportMode.Importance)
    si = mi.SurfaceInteraction3f()
    t = math.radians(c["theta_deg"])
    si.wi = mi.Vector3f(math.sin(t), 0.0, math.cos(t))
    si.n = mi.Normal3f(0, 0, 1)
    si.sh_frame = mi.Frame3f(si.n)
    n_bins = MU_BINS * PHI_BINS
    s1, s2 = [0.0] * n_bins, [0.0] * n_bins
    for _ in range(draws):
        bs, w = bsdf.sample(ctx, si, rng.random(), mi.Point2f(rng.random(), rng.random()))
        w = float(w[0])
        if not (w > 0.0):
            continue
        wo = bs.wo
        mu = min(max(float(wo[2]), -1.0), 1.0)
        phi = math.atan2(float(wo[1]), float(wo[0])) % (2 * math.pi)
        i = min(int((mu + 1.0) / 2.0 * MU_BINS), MU_BINS - 1)
        j = min(int(phi / (2 * math.pi) * PHI_BINS), PHI_BINS - 1)
        k = i * PHI_BINS + j
        s1[k] += w
        s2[k] += w * w
    bins = []
    for k in range(n_bins):
        if s1[k] > 0.0:
            mean = s1[k] / draws
            var = max(s2[k] / draws - mean * mean, 0.0) / draws
            bins.append([k, float(f"{mean:.7g}"), float(f"{var:.5g}")])
    total1 = sum(s1) / draws
    total_var = max(sum(s2) / draws - total1 * total1, 0.0) / draws  # one weight per draw
    return {**c, "draws": draws, "albedo": total1, "albedo_stderr": math.sqrt(total_var), "bins": bins}


def main():
    ohdpy.use_venv(f"mitsuba=={MITSUBA_VERSION}")
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    rng = random.Random(38)
    out = {
        "mitsuba": mi.__version__,
        "variant": "scalar_rgb",
        "mode": "Importance",
        "bins": {"mu": [-1.0, 1.0, MU_BINS], "phi": [0.0, 2 * math.pi, PHI_BINS], "index": "i_mu * phi_bins + j_phi"},
        "cases": [lobe(mi, c, DRAWS, rng) for c in cases()],
    }
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "mitsuba_bsdf_lobes.json")
    with open(path, "w") as f:
        json.dump(out, f, separators=(",", ":"))
        f.write("\n")
    for c in out["cases"]:
        print(f"{c['bsdf']:16s} α {c.get('alpha', '-'):>5} θi {c['theta_deg']:4.0f}°: albedo {c['albedo']:.5f} ± {c['albedo_stderr']:.5f}, {len(c['bins'])} bins")
    print(f"→ {path}")


if __name__ == "__main__":
    main()
