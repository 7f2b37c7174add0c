#!/usr/bin/python3
"""Write the example OpenVDB assets of media/vdb/ with OpenVDB itself (Debian python3-openvdb 10).

    bash media/vdb/make_assets.sh        # installs python3-openvdb, then runs this script

Two assets, both deterministic (fixed seeds), both small:

* vessels.vdb: a retinal arteriole that bifurcates twice (1 -> 2 -> 4 segments), radii by Murray's
  law (r_daughter = r_parent / 2^(1/3) for a symmetric split), in a 1.6 x 1.6 x 0.32 mm box of
  10 um voxels (the vessels fill 1.8 % of it). Grid "density" (FloatGrid, 1 inside a vessel, background 0) and grid "velocity"
  (Vec3SGrid, m/s, background 0): Poiseuille profile v = 2 v_mean (1 - (d/R)^2) along each
  segment's axis, flow conserved at every split (Q_daughter = Q_parent / 2). The root has D = 105 um
  and centre-line speed 34 mm/s (Guan et al. 2003, media/references.md A3). Every segment runs 5 deg
  out of the x-y plane (the retinal surface), away from the camera (+z) along the flow, so its
  Doppler shift is that of v_axial = v sin 5 deg.
  Index (0,0,0) is the box's corner; the file's map is index * 0.01 (UniformScaleMap) in
  millimetres, because OpenVDB refuses a voxel as small as 1e-5; the config places it with a
  scale of 1e-3 (mm -> m).
* wind_box.vdb: a 320 m cube of 10 m voxels (32^3) of turbulent wind. Grid "velocity" (Vec3SGrid,
  m/s): a mean wind of 8 m/s toward +x (from the west) plus a synthetic divergence-free
  turbulence, the curl of a random vector potential: v' = sum_n (k_n x a_n) cos(k_n . x + phi_n),
  whose divergence vanishes term by term. 96 modes, |k| log-uniform over wavelengths 40-320 m,
  amplitudes |a_n| ~ |k_n|^(-4/3), so that each mode's velocity
  |k x a| ~ |k|^(-1/3) and, with log-spaced |k|, E(k) dk ~ |k|^(-2/3) per log step, i.e.
  E(k) ~ k^(-5/3) (Kolmogorov), scaled to an rms of 0.8 m/s per component (turbulence
  intensity 0.1 at 8 m/s, IEC 61400-1 class C-like, media/references.md B5). The background is the
  mean wind (8, 0, 0): outside the box the wind is uniform. ScaleTranslateMap centring the box on
  x = y = 0, from z = 0 (the ground) to 320 m.

The truth the tests compare with (the analytic fields at sample points) is recomputed in Rust from
the same formulas where needed; the mode table of the wind box is written beside it
(wind_box_modes.csv) so the field can be evaluated anywhere.
"""

import csv
import math
import os
import sys

import numpy as np
import pyopenvdb as vdb

HERE = os.path.dirname(os.path.abspath(__file__))


def vessels(path):
    h = 10e-6
    nx, ny, nz = 160, 160, 32
    tilt = math.radians(5.0)
    r0, vmax0 = 52.5e-6, 34e-3
    q0 = 0.5 * vmax0 * math.pi * r0**2  # v_mean = v_max / 2
    # Segments (start, end, radius, flow), each rising `tilt` out of the x-y plane along its flow.
    segs = []

    def branch(a, heading, length, r, q, level):
        d = np.array([math.cos(heading) * math.cos(tilt), math.sin(heading) * math.cos(tilt), math.sin(tilt)])
        b = a + length * d
        segs.append((a, b, r, q))
        if level < 2:
            rd = r / 2.0 ** (1.0 / 3.0)
            for side in (-1.0, 1.0):
                branch(b, heading + side * math.radians(38.0), 0.8 * length, rd, 0.5 * q, level + 1)

    branch(np.array([0.0, 0.5 * ny * h, 0.3 * nz * h]), 0.0, 0.55e-3, r0, q0, 0)
    density = np.zeros((nx, ny, nz), dtype=np.float32)
    velocity = np.zeros((nx, ny, nz, 3), dtype=np.float32)
    ii, jj, kk = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    pts = np.stack([ii * h, jj * h, kk * h], axis=-1)
    best = np.full((nx, ny, nz), np.inf)
    for a, b, r, q in segs:
        axis = (b - a) / np.linalg.norm(b - a)
        rel = pts - a
        t = np.clip(rel @ axis, 0.0, np.linalg.norm(b - a))
        dist = np.linalg.norm(rel - t[..., None] * axis, axis=-1)
        inside = (dist <= r) & (dist / r < best)
        best = np.where(inside, dist / r, best)
        vmean = q / (math.pi * r * r)
        speed = 2.0 * vmean * (1.0 - (dist / r) ** 2)
        density[inside] = 1.0
        velocity[inside] = (speed[inside, None] * axis[None, :]).astype(np.float32)
    fill = density.mean()
    dg = vdb.FloatGrid(0.0)
    dg.copyFromArray(density, ijk=(0, 0, 0), tolerance=0.0)
    dg.name = "density"
    dg.gridClass = vdb.GridClass.FOG_VOLUME
    vg = vdb.Vec3SGrid((0.0, 0.0, 0.0))
    vg.copyFromArray(velocity, ijk=(0, 0, 0))
    vg.name = "velocity"
    # The file's lengths are millimetres: OpenVDB refuses a 1e-5 voxel ("Non-zero scale values
    # required": its scale map tests the determinant h^3 against an absolute tolerance), so the
    # config places the grid with scale 1e-3. Velocities stay in m/s.
    for g in (dg, vg):
        g.transform = vdb.createLinearTransform(voxelSize=h * 1e3)
    vdb.write(path, grids=[dg, vg])
    print(f"{path}: {nx}x{ny}x{nz} voxels of {h * 1e6} um, {len(segs)} segments, "
          f"fill fraction {fill:.4f}, {dg.activeVoxelCount()} active density voxels, "
          f"{os.path.getsize(path)} bytes")


def wind_box(path, modes_path):
    h, n = 10.0, 32
    rng = np.random.default_rng(20261122)
    nmodes = 96
    lam = np.exp(rng.uniform(math.log(40.0), math.log(320.0), nmodes))
    kmag = 2.0 * math.pi / lam
    khat = rng.normal(size=(nmodes, 3))
    khat /= np.linalg.norm(khat, axis=1, keepdims=True)
    k = khat * kmag[:, None]
    a = rng.normal(size=(nmodes, 3)) * (kmag ** (-4.0 / 3.0))[:, None]
    phi = rng.uniform(0.0, 2.0 * math.pi, nmodes)
    amp = np.cross(k, a)  # divergence-free direction of each mode
    origin = np.array([-0.5 * n * h, -0.5 * n * h, 0.0])
    idx = np.stack(np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij"), axis=-1)
    x = origin + idx * h
    phase = x @ k.T + phi
    v = np.cos(phase) @ amp
    scale = 0.8 / math.sqrt(np.mean(v**2))
    amp *= scale
    v *= scale
    mean = np.array([8.0, 0.0, 0.0])
    field = (v + mean).astype(np.float32)
    g = vdb.Vec3SGrid(tuple(mean))
    g.copyFromArray(field, ijk=(0, 0, 0))
    g.name = "velocity"
    m = np.eye(4) * h
    m[3, :3] = origin
    m[3, 3] = 1.0
    g.transform = vdb.createLinearTransform(m.tolist())
    vdb.write(path, grids=[g])
    with open(modes_path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["kx_per_m", "ky_per_m", "kz_per_m", "ax_m_per_s", "ay_m_per_s", "az_m_per_s", "phase_rad"])
        for i in range(nmodes):
            w.writerow([repr(float(c)) for c in (*k[i], *amp[i], phi[i])])
    rms = np.sqrt(np.mean(v**2, axis=(0, 1, 2)))
    print(f"{path}: {n}^3 voxels of {h} m, mean wind {mean} m/s, turbulence rms per component "
          f"{np.round(rms, 3)} m/s, {os.path.getsize(path)} bytes")


if __name__ == "__main__":
    out = sys.argv[1] if len(sys.argv) > 1 else HERE
    vessels(os.path.join(out, "vessels.vdb"))
    wind_box(os.path.join(out, "wind_box.vdb"), os.path.join(out, "wind_box_modes.csv"))
