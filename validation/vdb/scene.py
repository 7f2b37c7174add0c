#!/usr/bin/python3
"""Build the OpenVDB fixture scenes with Debian's pyopenvdb (OpenVDB 10) and dump their truth.

Usage (from make_fixtures.sh):
    scene.py build OUT_DIR        # writes scene.vdb and root_tile.vdb (OpenVDB's default codec)
    scene.py truth VDB OUT.gz [light]  # reads VDB back with OpenVDB and writes what OpenVDB returns
    scene.py bench OUT.vdb N      # a dense N^3 density for load-time measurements (not committed)

The scenes are designed so that every case of OpenVDB's per-node value codec (io/Compression.h:
the seven mask-compression metadata values) occurs in some leaf, with tiles at the leaf, internal
and root levels, negative coordinates and non-zero backgrounds (validation/vdb/README.md).
"""
import gzip
import math
import struct
import sys

import numpy as np
import pyopenvdb as vdb


def f32(x):
    return float(np.float32(x))


def bits(v):
    """Hex bit patterns of a float or a 3-vector of floats (as OpenVDB returned them, f32)."""
    if isinstance(v, (tuple, list)):
        return " ".join(bits(c) for c in v)
    return "%08x" % struct.unpack("<I", struct.pack("<f", v))[0]


def smooth(i, j, k, salt):
    return f32(3.0 * math.sin(0.37 * i + 0.71 * j + 1.13 * k + salt))


class Kind:
    """How values of one grid type are made: scalar or 3-vector."""

    def __init__(self, vec):
        self.vec = vec

    def val(self, i, j, k):
        if self.vec:
            return tuple(smooth(i, j, k, s) for s in (0.0, 1.0, 2.0))
        return smooth(i, j, k, 0.5)

    def const(self, c):
        if self.vec:
            return (f32(c), f32(c + 0.5), f32(-c))
        return f32(c)

    def neg(self, v):
        if self.vec:
            return tuple(-c for c in v)
        return -v


# Every leaf and leaf-level tile is shifted by this, so that the whole scene lies in the octant of
# negative coordinates (one level-2 internal node: the uncompressed fixtures stay small).
SHIFT = (-64, -16, -16)


def leaf_cases(grid, kind, bg):
    """Leaves at x in [-64, 0), y, z in [-32, -8): one per mask-compression case. Returns their origins."""
    acc = grid.getAccessor()
    origins = []

    def leaf(ox, oy, oz, active, inactive):
        ox, oy, oz = ox + SHIFT[0], oy + SHIFT[1], oz + SHIFT[2]
        origins.append((ox, oy, oz))
        for lx in range(8):
            for ly in range(8):
                for lz in range(8):
                    ijk = (ox + lx, oy + ly, oz + lz)
                    if active(lx, ly, lz):
                        acc.setValueOn(ijk, kind.val(*ijk))
                    else:
                        v = inactive(lx, ly, lz)
                        if v is not None:
                            acc.setValueOff(ijk, v)

    minus_bg = kind.neg(bg)
    c3, c4, c75, c5 = kind.const(3.0), kind.const(4.0), kind.const(7.5), kind.const(5.0)
    # NO_MASK_OR_INACTIVE_VALS, every voxel active (the codec reads all 512 values).
    leaf(0, -16, -16, lambda x, y, z: True, lambda x, y, z: None)
    # NO_MASK_OR_INACTIVE_VALS with inactive voxels at the background.
    leaf(8, -16, -16, lambda x, y, z: (x + y + z) % 3 == 0, lambda x, y, z: None)
    # NO_MASK_AND_MINUS_BG.
    leaf(16, -16, -16, lambda x, y, z: (x + y) % 2 == 0, lambda x, y, z: minus_bg)
    # NO_MASK_AND_ONE_INACTIVE_VAL.
    leaf(24, -16, -16, lambda x, y, z: z % 4 == 0, lambda x, y, z: c75)
    # MASK_AND_NO_INACTIVE_VALS (inactive -bg and +bg).
    leaf(0, -8, -16, lambda x, y, z: (x * y) % 5 == 0, lambda x, y, z: minus_bg if z < 4 else None)
    # MASK_AND_ONE_INACTIVE_VAL, first inactive voxel at the background.
    leaf(8, -8, -16, lambda x, y, z: x == y, lambda x, y, z: c3 if x >= 4 else None)
    # MASK_AND_ONE_INACTIVE_VAL, first inactive voxel at the other value.
    leaf(16, -8, -16, lambda x, y, z: x == y, lambda x, y, z: c3 if x < 4 else None)
    # MASK_AND_TWO_INACTIVE_VALS.
    leaf(24, -8, -16, lambda x, y, z: (x + z) % 4 == 0, lambda x, y, z: c3 if y < 4 else c4)
    # NO_MASK_AND_ALL_VALS (more than two distinct inactive values).
    leaf(0, 0, -16, lambda x, y, z: z == 0, lambda x, y, z: kind.const(0.125 * (x + 1)))
    # No active voxel, every voxel at one non-background value (the codec stores zero values).
    leaf(8, 0, -16, lambda x, y, z: False, lambda x, y, z: c5)
    # A sparse leaf with positive coordinates, inactive at the background.
    leaf(40, 0, 0, lambda x, y, z: (x * 7 + y * 3 + z) % 4 == 1, lambda x, y, z: None)
    # A leaf with no active voxel and every voxel at the background.
    empty = (48 + SHIFT[0], SHIFT[1], SHIFT[2])
    acc.setValueOn(empty, kind.const(1.0))
    acc.setValueOff(empty, bg)
    origins.append(empty)
    return origins


def tiles(grid, kind, big):
    # Leaf-level (8^3) tiles inside a level-1 internal node: one active, one inactive non-background.
    sx, sy, sz = SHIFT
    grid.fill((32 + sx, -16 + sy, -16 + sz), (39 + sx, -9 + sy, -9 + sz), kind.const(1.5), True)
    grid.fill((32 + sx, -8 + sy, -16 + sz), (39 + sx, -1 + sy, -9 + sz), kind.const(2.5), False)
    if big:
        # A 128^3 tile inside the level-2 internal node (beside the level-1 node of the leaves).
        grid.fill((-256, -128, -128), (-129, -1, -1), kind.const(0.75), True)


def sample_points(origins, rng, extra_boxes, n_random=2000):
    pts = set()
    for (ox, oy, oz) in origins:
        for lx in range(8):
            for ly in range(8):
                for lz in range(8):
                    pts.add((ox + lx, oy + ly, oz + lz))
    for _ in range(n_random):
        pts.add(tuple(int(c) for c in rng.integers(-100, 20, size=3)))
    for (lo, hi, n) in extra_boxes:
        for _ in range(n):
            pts.add(tuple(int(c) for c in rng.integers(lo, hi + 1, size=3)))
    # Points far outside and at the corners of the 32-bit index range.
    for p in [(2**31 - 1,) * 3, (-(2**31),) * 3, (5000, -5000, 123456), (-4097, 4096, 0)]:
        pts.add(p)
    return sorted(pts)


def make_scene(path):
    rng = np.random.default_rng(6)
    fkind, vkind = Kind(False), Kind(True)

    density = vdb.FloatGrid(0.25)
    density.name = "density"
    density.gridClass = vdb.GridClass.UNKNOWN  # zip would be dropped for FOG_VOLUME / LEVEL_SET
    density.transform = vdb.createLinearTransform(voxelSize=0.05)  # UniformScaleMap
    o1 = leaf_cases(density, fkind, 0.25)
    tiles(density, fkind, True)

    vbg = (0.5, -1.0, 2.0)
    velocity = vdb.Vec3SGrid(vbg)
    velocity.name = "velocity"
    velocity.transform = vdb.createLinearTransform(
        np.array([[0.1, 0, 0, 0], [0, 0.2, 0, 0], [0, 0, 0.3, 0], [1.0, -2.0, 3.0, 1]]))  # ScaleTranslateMap
    o2 = leaf_cases(velocity, vkind, vbg)
    tiles(velocity, vkind, True)

    vzero = vdb.Vec3SGrid((0.0, 0.0, 0.0))
    vzero.name = "velocity_zero_bg"
    vzero.transform = vdb.createLinearTransform(
        np.array([[0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 0.5, 0], [0.25, 0.25, 0.25, 1]]))  # UniformScaleTranslateMap
    acc = vzero.getAccessor()
    for i in range(-8, 0):
        for j in range(-8, 0):
            acc.setValueOn((i, j, -3), vkind.val(i, j, -3))
    tiles(vzero, vkind, False)

    fog = vdb.FloatGrid(0.0)
    fog.name = "fog"
    fog.gridClass = vdb.GridClass.FOG_VOLUME
    fog.transform = vdb.createLinearTransform(
        np.array([[0.1, 0, 0, 0], [0, 0.2, 0, 0], [0, 0, 0.4, 0], [0, 0, 0, 1]]))  # ScaleMap
    acc = fog.getAccessor()
    for i in range(-20, -4):
        for j in range(-3, 0):
            acc.setValueOn((i, j, 2 * i), f32(abs(smooth(i, j, 0, 0.1))))

    vdb.write(path, grids=[density, velocity])
    vdb.write(path.replace("scene.vdb", "extra.vdb"), grids=[vzero, fog])


def make_root_tile(path):
    fkind, vkind = Kind(False), Kind(True)
    density = vdb.FloatGrid(0.25)
    density.name = "density"
    density.transform = vdb.createLinearTransform(voxelSize=0.5)
    density.fill((-4096, -4096, -4096), (-1, -1, -1), 0.5, True)        # active root tile
    density.fill((0, 0, -4096), (4095, 4095, -1), 0.125, False)        # inactive root tile, not background
    acc = density.getAccessor()
    for i in range(8, 12):
        acc.setValueOn((i, 8, 8), fkind.val(i, 8, 8))
    velocity = vdb.Vec3SGrid((0.0, 0.0, 1.0))
    velocity.name = "velocity"
    velocity.fill((0, -4096, 0), (4095, -1, 4095), (1.0, -2.0, 0.5), True)
    acc = velocity.getAccessor()
    acc.setValueOn((-3, 5, 7), vkind.val(-3, 5, 7))
    vdb.write(path, grids=[density, velocity])


def make_bench(path, n):
    """A dense n^3 FloatGrid (every voxel active, smooth values), for load-time measurements."""
    x = np.arange(n, dtype=np.float32)
    a = (np.sin(0.05 * x)[:, None, None] * np.cos(0.07 * x)[None, :, None]
         + 0.5 * np.sin(0.03 * x)[None, None, :]).astype(np.float32) + np.float32(1.5)
    g = vdb.FloatGrid(0.0)
    g.name = "density"
    g.gridClass = vdb.GridClass.FOG_VOLUME
    g.copyFromArray(a, ijk=(-n // 2, -n // 2, -n // 2), tolerance=0)
    g.transform = vdb.createLinearTransform(voxelSize=0.01)
    vdb.write(path, grids=[g])


def grid_origins(grid):
    """Origins of every leaf node (from the on/off value iterators at leaf depth)."""
    origins = set()
    for it in grid.iterAllValues():
        if it["depth"] == 3:
            mn = it["min"]
            origins.add(tuple(c & ~7 for c in mn))
    return sorted(origins)


def dump_truth(vdb_path, out_path, light=False):
    rng = np.random.default_rng(2024)
    grids, _meta = vdb.readAll(vdb_path)
    lines = []
    for g in grids:
        acc = g.getConstAccessor()
        lines.append("grid %s" % g.name)
        lines.append("type %s" % g.valueTypeName)
        lines.append("class %s" % g.gridClass)
        lines.append("half %d" % int(g.saveFloatAsHalf))
        lines.append("background %s" % bits(g.background))
        t = g.transform
        w0 = t.indexToWorld((0, 0, 0))
        w1 = t.indexToWorld((1, 1, 1))
        lines.append("map %s" % t.typeName)
        lines.append("world0 %s" % " ".join(repr(float(c)) for c in w0))
        lines.append("world1 %s" % " ".join(repr(float(c)) for c in w1))
        lines.append("active_count %d" % g.activeVoxelCount())
        lo, hi = g.evalActiveVoxelBoundingBox()
        lines.append("active_bbox %d %d %d %d %d %d" % (tuple(lo) + tuple(hi)))
        for it in g.iterOnValues():
            lines.append("on %d %d %d %d %d %d %s" % (tuple(it["min"]) + tuple(it["max"]) + (bits(it["value"]),)))
        origins = grid_origins(g)
        boxes = [(-8, 8, 100)] if light else [(-260, 2, 600), (-4100, 4100, 300)]
        for p in sample_points(origins, rng, boxes, n_random=0 if light else 2000):
            lines.append("s %d %d %d %d %s" % (p + (int(acc.isValueOn(p)), bits(acc.getValue(p)))))
        lines.append("end")
    data = ("\n".join(lines) + "\n").encode()
    with open(out_path, "wb") as raw:
        with gzip.GzipFile(fileobj=raw, mode="wb", compresslevel=9, mtime=0) as f:
            f.write(data)


if __name__ == "__main__":
    if sys.argv[1] == "build":
        out = sys.argv[2]
        make_scene(out + "/scene.vdb")
        make_root_tile(out + "/root_tile.vdb")
    elif sys.argv[1] == "bench":
        make_bench(sys.argv[2], int(sys.argv[3]))
    elif sys.argv[1] == "truth":
        dump_truth(sys.argv[2], sys.argv[3], light=len(sys.argv) > 4 and sys.argv[4] == "light")
    else:
        sys.exit("usage: scene.py build OUT_DIR | truth VDB OUT.gz [light] | bench OUT.vdb N")
