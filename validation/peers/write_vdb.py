#!/usr/bin/python3
"""Write a density array (.npy, indexed [i, j, k] = [x, y, z]) as an OpenVDB FloatGrid "density".

    /usr/bin/python3 validation/peers/write_vdb.py IN.npy OUT.vdb VOXEL_SIZE

Runs under the system interpreter: Debian's python3-openvdb is built for it (see validation/vdb/).
Index (i, j, k) sits at (i, j, k)·VOXEL_SIZE in the file; the experiment's translate_* places it.
"""
import sys

import numpy as np
import pyopenvdb as vdb

src, dst, h = sys.argv[1], sys.argv[2], float(sys.argv[3])
data = np.ascontiguousarray(np.load(src), dtype=np.float32)
g = vdb.FloatGrid(0.0)
g.copyFromArray(data, ijk=(0, 0, 0))
g.name = "density"
g.gridClass = vdb.GridClass.FOG_VOLUME
g.transform = vdb.createLinearTransform(voxelSize=h)
vdb.write(dst, grids=[g])
