#!/usr/bin/env python3
"""The seed's FMCW copper-and-treadmill experiment (configs/fmcw_copper_treadmill.toml) at two
plate roughnesses: each scan position's retrieved range and radial velocity against the
geometry's closed form away from the plate's edge, the transition region's width, and the README
figure.

    python3 validation/fmcw_copper/run.py --binary target/release/ohd            # both scans, ~2 min
    python3 validation/fmcw_copper/run.py --figure media/readme/fmcw_copper_treadmill.png

Closed forms (the config's comments): at elevation e the beam descends at β = 90° − e from the
transceiver s onto the floor (the plate's top face x = x_f) at z = s_z + h/tan β, h = s_x − x_f.
On the plate the belt is seen in it: from the mirror image s′ = (2x_f − s_x, s_y, s_z) along
d′ = (sin β, 0, cos β) the belt's plane (centre c, normal n) lies at R = (c − s′)·n/(d′·n), with
radial velocity v·d′; beyond the plate the fabric at R = h/sin β, static. "Away from the edge"
means the beam meets the floor more than the receiver's view of it, ±(R θ + w)/sin β (θ the
field of view's half-angle, w the beam's 1/e² radius), from the plate's far edge.

Where both returns are present: per pointing, the belt's share of the detected power is the
up-chirp spectrum's power within ±3 bins of the belt's closed-form beat f_R + f_D over the whole,
and the spot's share the same around the beat of the spot's own range h/sin β (static: the
plate's own backscatter, or the fabric's). The edge's transition region is where the belt's
return (its power, not its share) falls from 90 % to 10 % of its level on the plate just before
the edge, measured on a second, finer scan across the edge (elevations 85.86° … 85.96° by 0.004°,
1.5 cm of floor; linear between scan positions), its width along the floor and in elevation. The
belt is lit only through the plate: were its return proportional to the beam's power that lands
on the plate, it would follow the Gaussian beam's profile across the edge (σ = w/(2 sin β) along
the floor, a 90 %–10 % width of 2·1.2816·σ, printed beside); the light crosses the edge a second
time on its way back through the plate to the receiver, whose view of the floor is wider than
the beam, which widens the region and moves it before the edge; "mixed" positions are those
where each return holds at least 10 %. A pointing whose (R, v) matches neither return's closed
form within a bin is a wrong reconstruction.

Needs numpy (and matplotlib for --figure).
"""

import argparse
import csv
import math
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "configs" / "fmcw_copper_treadmill.toml"
C = 299_792_458.0


def geometry(cfg):
    """What the closed forms need from the config."""
    solids = {o["name"]: o for o in cfg["opaque"]}
    s = np.array(cfg["source"]["position_m"], float)
    plate = solids["copper"]["shape"]
    pc, ps = np.array(plate["center_m"]), np.array(plate["size_m"])
    belt = solids["belt"]
    det = cfg["detectors"][0]
    return {
        "s": s,
        "x_f": pc[0] + ps[0] / 2,
        "plate_z": (pc[2] - ps[2] / 2, pc[2] + ps[2] / 2),
        "belt_c": np.array(belt["shape"]["center_m"], float),
        "belt_n": np.array(belt["shape"]["axis"], float) / np.linalg.norm(belt["shape"]["axis"]),
        "belt_v": np.array(belt["velocity_m_per_s"], float),
        "fov": math.radians(det["acceptance_half_angle_deg"]),
        "waist": cfg["source"]["waist_mm"] * 1e-3,
        "chirp": (cfg["source"]["chirp"]["bandwidth_ghz"] * 1e9, cfg["source"]["chirp"]["duration_us"] * 1e-6),
        "wavelength": cfg["source"]["wavelength_nm"] * 1e-9,
    }


def closed_form(g, el):
    """(range, velocity, on the plate, floor position z ahead of the transceiver, belt range, belt velocity)."""
    beta = math.radians(90.0 - el)
    s, x_f = g["s"], g["x_f"]
    h = s[0] - x_f
    spot = s[2] + h / math.tan(beta)
    mirror = np.array([2 * x_f - s[0], s[1], s[2]])
    d = np.array([math.sin(beta), 0.0, math.cos(beta)])
    r_belt = float((g["belt_c"] - mirror) @ g["belt_n"] / (d @ g["belt_n"]))
    v_belt = float(g["belt_v"] @ d)
    lo, hi = g["plate_z"]
    if lo <= spot <= hi:
        return r_belt, v_belt, True, spot - s[2], r_belt, v_belt
    return h / math.sin(beta), 0.0, False, spot - s[2], r_belt, v_belt


FINE = [round(85.86 + 0.004 * i, 3) for i in range(26)]


def run(binary, alpha, out, samples, threads, elevations=None):
    if (out / "scan.json").exists():
        return
    cmd = [str(binary), "run", str(CONFIG), "--out", str(out), "-q", "--no-figures",
           "--set", f"opaque.0.surface.roughness={alpha}"]
    if elevations:
        cmd += ["--set", "source.pointings_deg=[" + ", ".join(f"[270, {e}]" for e in elevations) + "]"]
    if samples:
        cmd += ["--samples", str(samples)]
    if threads:
        cmd += ["--threads", str(threads)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({done.returncode}):\n{done.stderr}")


def analyse(g, out):
    rows = list(csv.DictReader(open(out / "fmcw_scan.csv")))
    bw, dur = g["chirp"]
    res = []
    for r in rows:
        el = float(r["elevation_deg"])
        want_r, want_v, plate, floor, r_belt, v_belt = closed_form(g, el)
        d = out / f"pointing_{int(r['pointing']):02d}"
        f = np.load(d / "receiver_frequency_hz.npy")
        up = np.load(d / "receiver_up_spectrum.npy")
        df = f[1] - f[0]
        beta = math.radians(90 - el)
        f_belt = 2 * r_belt * bw / (C * dur) + 2 * v_belt / g["wavelength"]
        f_spot = 2 * (g["s"][0] - g["x_f"]) / math.sin(beta) * bw / (C * dur)
        total = up.sum()
        belt_power = up[np.abs(f - f_belt) <= 3 * df].sum()
        share, spot_share = ((up[np.abs(f - fc) <= 3 * df].sum() / total) if total > 0 else math.nan
                             for fc in (f_belt, f_spot))
        view = (want_r * g["fov"] + g["waist"]) / math.sin(math.radians(90 - el))
        edge = g["plate_z"][1] - g["s"][2]
        res.append({
            "el": el, "floor": floor, "plate": plate, "share": share, "spot_share": spot_share,
            "belt_power": belt_power, "edge": edge,
            "r_belt": r_belt, "v_belt": v_belt, "r_spot": (g["s"][0] - g["x_f"]) / math.sin(beta),
            "range": float(r["range_m"] or "nan"), "v": float(r["radial_velocity_m_per_s"] or "nan"),
            "want_r": want_r, "want_v": want_v,
            "rbin": float(r["range_bin_m"] or "nan"), "vbin": float(r["velocity_bin_m_per_s"] or "nan"),
            "away": abs(floor - edge) > view, "view": view,
        })
    return res


def edge_transition(g, fine):
    """The edge's transition region on the fine scan `fine`: (floor from, floor to, elevation
    from, elevation to, the closed form's width) where the belt's return falls from 90 % to 10 %
    of its mean over the positions more than 4σ before the edge."""
    pts = sorted(fine, key=lambda r: r["floor"])
    edge = pts[0]["edge"]
    beta = math.atan((g["s"][0] - g["x_f"]) / edge)
    sigma = g["waist"] / (2 * math.sin(beta))
    before = [r["belt_power"] for r in pts if r["floor"] < edge - 4 * sigma]
    plateau = float(np.mean(before))
    def crossing(level):
        found = (math.nan, math.nan)
        for a, b in zip(pts, pts[1:]):
            fa, fb = a["belt_power"] / plateau - level, b["belt_power"] / plateau - level
            if fa >= 0 > fb:  # the last fall through the level, nearest the edge
                t = fa / (fa - fb)
                found = (a["floor"] + t * (b["floor"] - a["floor"]), a["el"] + t * (b["el"] - a["el"]))
        return found
    (z0, e0), (z1, e1) = crossing(0.9), crossing(0.1)
    return z0, z1, e0, e1, 2 * 1.2816 * sigma


def transitions(res, level=0.1):
    """The transition regions: [(floor from, floor to, elevation from, elevation to, open)], `open`
    where a region reaches an end of the scan."""
    pts = sorted(res, key=lambda r: r["floor"])
    m = [min(r["share"], r["spot_share"]) - level for r in pts]
    def cross(i, j):  # between pts[i] (m < 0) and pts[j] (m ≥ 0), or the other way
        t = m[i] / (m[i] - m[j])
        return (pts[i]["floor"] + t * (pts[j]["floor"] - pts[i]["floor"]), pts[i]["el"] + t * (pts[j]["el"] - pts[i]["el"]))
    out, i = [], 0
    while i < len(pts):
        if m[i] < 0:
            i += 1
            continue
        j = i
        while j + 1 < len(pts) and m[j + 1] >= 0:
            j += 1
        lo = cross(i - 1, i) if i > 0 else (pts[0]["floor"], pts[0]["el"])
        hi = cross(j + 1, j) if j + 1 < len(pts) else (pts[-1]["floor"], pts[-1]["el"])
        out.append((lo[0], hi[0], lo[1], hi[1], i == 0 or j + 1 == len(pts)))
        i = j + 1
    return out


def reads(r):
    """What a pointing's retrieval reads: "belt", "spot" or "wrong" (neither within a bin)."""
    ok = lambda want_r, want_v: abs(r["range"] - want_r) <= r["rbin"] and abs(r["v"] - want_v) <= r["vbin"]
    return "belt" if ok(r["r_belt"], r["v_belt"]) else "spot" if ok(r["r_spot"], 0.0) else "wrong"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--binary", default=str(ROOT / "target" / "release" / "ohd"))
    ap.add_argument("--work", default=str(ROOT / "out" / "fmcw_copper_validation"))
    ap.add_argument("--roughness", type=float, nargs="+", default=[0.02, 0.04])
    ap.add_argument("--samples", type=int, default=0, help="paths per pointing (default: the config's)")
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--figure", help="write the README figure (range and velocity along the scan) here")
    a = ap.parse_args()
    cfg = tomllib.load(open(CONFIG, "rb"))
    g = geometry(cfg)
    work = Path(a.work)
    failures = 0
    results = {}
    for alpha in a.roughness:
        out = work / f"roughness_{alpha}"
        run(a.binary, alpha, out, a.samples, a.threads)
        res = analyse(g, out)
        fine_out = work / f"roughness_{alpha}_edge"
        run(a.binary, alpha, fine_out, a.samples, a.threads, FINE)
        fine = analyse(g, fine_out)
        results[alpha] = (res, fine)
        away = [r for r in res if r["away"]]
        bad = [r for r in away if not (abs(r["range"] - r["want_r"]) <= r["rbin"] and abs(r["v"] - r["want_v"]) <= r["vbin"])]
        dr = max(abs(r["range"] - r["want_r"]) / r["rbin"] for r in away)
        dv = max(abs(r["v"] - r["want_v"]) / r["vbin"] for r in away)
        print(f"roughness α = {alpha}: {len(res)} pointings, {len(away)} away from the edge "
              f"({sum(r['plate'] for r in away)} on the plate, {sum(not r['plate'] for r in away)} beyond); "
              f"within a bin of the closed form: {len(away) - len(bad)} of {len(away)} "
              f"(largest |ΔR| {dr:.2f} bins, |Δv| {dv:.2f} bins)")
        kinds = [reads(r) for r in res]
        print(f"  retrievals: belt {kinds.count('belt')}, the spot's own range {kinds.count('spot')}, "
              f"wrong reconstructions {kinds.count('wrong')}")
        z0, z1, e0, e1, want = edge_transition(g, fine)
        top = np.median([r["share"] for r in res if r["plate"] and r["away"]])
        plate_share = np.median([r["spot_share"] for r in res if r["plate"] and r["away"]])
        print(f"  on the plate: the belt holds {top:.0%} of the power, the plate's own backscatter {plate_share:.0%} (medians)")
        print(f"  the edge's transition region (the belt's return 90 % → 10 %): floor {z0:.3f} → {z1:.3f} m ahead, "
              f"width {z1 - z0:.3f} m (the beam's profile alone: {want:.3f} m), elevation {abs(e1 - e0):.4f}°")
        for z0, z1, e0, e1, open_ in transitions(res):
            print(f"  mixed (belt and spot each ≥ 10 % of the power): floor {z0:.3f} → {z1:.3f} m ahead, "
                  f"{z1 - z0:.3f} m, elevation {abs(e1 - e0):.3f}°" + (" (reaches the scan's end)" if open_ else ""))
        for r in bad:
            print(f"  off: elevation {r['el']}°: R {r['range']:.3f} (closed form {r['want_r']:.3f}), "
                  f"v {r['v']:.4f} (closed form {r['want_v']:.4f})")
        failures += len(bad)
    if a.figure:
        figure(g, results, a.figure)
    return 1 if failures else 0


def figure(g, results, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax_r, ax_v) = plt.subplots(2, 1, figsize=(8, 6.4), sharex=True)
    edge = g["plate_z"][1] - g["s"][2]
    colours = ["#0072b2", "#d55e00", "#009e73"]
    for (alpha, (res, fine)), c in zip(results.items(), colours):
        z0, z1, *_ = edge_transition(g, fine)
        res = sorted(res, key=lambda r: r["floor"])
        z = [r["floor"] for r in res]
        ax_r.plot(z, [r["range"] for r in res], "o-", ms=3, color=c, label=f"ohd, copper α = {alpha}")
        ax_v.plot(z, [r["v"] for r in res], "o-", ms=3, color=c, label=f"ohd, copper α = {alpha}")
        for ax in (ax_r, ax_v):
            ax.axvspan(z0, z1, color=c, alpha=0.15, lw=0)
    res = sorted(next(iter(results.values()))[0], key=lambda r: r["floor"])
    z = [r["floor"] for r in res]
    ax_r.plot(z, [r["want_r"] for r in res], "k--", lw=1, label="closed form")
    ax_v.plot(z, [r["want_v"] for r in res], "k--", lw=1, label="closed form")
    for ax in (ax_r, ax_v):
        ax.axvline(edge, color="0.4", lw=0.8, ls=":")
    ax_r.set_ylabel("range (m)")
    ax_v.set_ylabel("radial velocity (m/s, + receding)")
    ax_v.set_xlabel("where the beam meets the floor (m ahead of the transceiver)")
    ax_r.set_title("FMCW scan across a copper plate's edge: the belt seen in the plate, then the floor")
    ax_r.legend(fontsize=8, loc="lower right")
    ax_v.text(edge, ax_v.get_ylim()[1], " plate's edge", va="top", fontsize=8, color="0.3")
    ax_v.text(0.99, 0.62, "shaded: the edge's transition region\n(the belt's return 90 % → 10 %)",
              transform=ax_v.transAxes, fontsize=8, color="0.3", ha="right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"figure → {path}")


if __name__ == "__main__":
    sys.exit(main())
