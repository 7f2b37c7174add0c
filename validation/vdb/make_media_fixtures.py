#!/usr/bin/python3
"""Write the grid-media test fixtures of tests/fixtures/vdb_media/ with OpenVDB itself.

    /usr/bin/python3 validation/vdb/make_media_fixtures.py     # needs Debian's python3-openvdb

Lengths in these files are millimetres (OpenVDB refuses voxels below ~1e-3 in its scale maps, so
micrometre voxels cannot be stored in metres); the test configs place them with a scale of 1e-3.

* constant.vdb: FloatGrid "density", background 0.7, and the box [-40, 40) x [-40, 40) x [0, 20)
  of 0.05 mm voxels filled with 0.7 (tree.fill: active tiles at the leaf and internal levels).
  The density is 0.7 everywhere, inside the box and out: a grid medium of it must equal the
  homogeneous medium with 0.7 times the coefficients.
* tube.vdb: Vec3SGrid "velocity" of a Poiseuille tube (radius R = 0.05 mm, axis a = (1, 0, 1)/sqrt(2)
  through (0, 0, 0.2) mm, v_max = 1 mm/s = 1e-3 m/s along the axis) on h = 0.00625 mm voxels
  (R/h = 8) within R + 2h of the axis, over x in [-0.3, 0.3], z in [-0.02, 0.42] mm; stored as
  half floats (saveFloatAsHalf: 11 significant bits, 5e-4 relative). The parabola
  v = v_max (1 - r^2/R^2) is stored unclipped (negative just beyond the wall) so that trilinear
  interpolation inside the tube only sees the quadratic: its error is at most
  (h^2/8) sum_i |d2v/dx_i^2| = (h^2/8) (2 v_max/R^2) sum_i (1 - a_i^2) = 0.5 v_max (h/R)^2
  = 0.008 v_max, a sixth of a spectrum bin of the test that uses it (the same scene as
  tests/it/doppler.rs's analytic tube).
"""

import math
import os
import sys

import numpy as np
import pyopenvdb as vdb

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "..", "tests", "fixtures", "vdb_media")


def constant(path):
    g = vdb.FloatGrid(0.7)
    g.fill((-40, -40, 0), (39, 39, 19), 0.7, active=True)
    g.name = "density"
    g.gridClass = vdb.GridClass.FOG_VOLUME
    g.transform = vdb.createLinearTransform(voxelSize=0.05)
    vdb.write(path, grids=[g])
    print(f"{path}: {g.activeVoxelCount()} active voxels, {os.path.getsize(path)} bytes")


def tube(path):
    h, radius, vmax = 0.00625, 0.05, 1e-3
    axis = np.array([1.0, 0.0, 1.0]) / math.sqrt(2.0)
    centre = np.array([0.0, 0.0, 0.2])
    lo = np.array([-0.3, -0.08, -0.02])
    n = np.round((np.array([0.3, 0.08, 0.42]) - lo) / h).astype(int) + 1
    i0 = np.round(lo / h).astype(int)
    idx = np.stack(np.meshgrid(*(np.arange(k) for k in n), indexing="ij"), axis=-1)
    x = (idx + i0) * h - centre
    along = x @ axis
    r2 = np.sum(x * x, axis=-1) - along**2
    speed = vmax * (1.0 - r2 / radius**2)
    field = (speed[..., None] * axis).astype(np.float32)
    field[r2 > (radius + 2.0 * h) ** 2] = 0.0  # background: inactive, not stored
    g = vdb.Vec3SGrid((0.0, 0.0, 0.0))
    g.copyFromArray(field, ijk=tuple(int(v) for v in i0))
    g.name = "velocity"
    g.saveFloatAsHalf = True
    g.transform = vdb.createLinearTransform(voxelSize=h)
    vdb.write(path, grids=[g])
    print(f"{path}: {tuple(n)} points from {tuple(i0)}, {g.activeVoxelCount()} active voxels, "
          f"{os.path.getsize(path)} bytes")


if __name__ == "__main__":
    out = sys.argv[1] if len(sys.argv) > 1 else OUT
    os.makedirs(out, exist_ok=True)
    constant(os.path.join(out, "constant.vdb"))
    tube(os.path.join(out, "tube.vdb"))
