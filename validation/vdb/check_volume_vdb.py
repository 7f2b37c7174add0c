#!/usr/bin/python3
"""Check ohd's OpenVDB writer (`[volume] vdb = true`, core/src/io/formats/vdb_write.rs) with OpenVDB
itself: Debian's pyopenvdb (OpenVDB 10.0.1, `apt-get install python3-openvdb`, run with
/usr/bin/python3) reads `volume.vdb` and every grid must equal the run's `.npy` files voxel by
voxel (as f32, the index j counting up from the smallest y), with the voxel size and transform of
the box, non-zero voxels active and zero voxels inactive. Two grids: 24 × 20 × 40 voxels (both
fluence estimators), and a sparse 260 × 2 × 4100 one (several internal nodes along x, two root
children along z).

    /usr/bin/python3 validation/vdb/check_volume_vdb.py [path/to/ohd]

Builds nothing: give the binary (default target/ci/ohd). Prints one line per grid; exits 1 on a
mismatch.
"""
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pyopenvdb as vdb

ROOT = Path(__file__).resolve().parents[2]
CONFIG = """
schema_version = 1
[run]
samples = 20000
seed = 7
batches = 16
[source]
wavelength_nm = 800
profile = "pencil"
position_mm = [0, 0, -1]
direction = [0, 0, 1]
[media.tissue]
sigma_a_per_mm = 0.01
sigma_s_per_mm = 10
phase = { type = "hg", g = 0.9 }
[[layers]]
thickness_mm = inf
n = 1.0
medium = "tissue"
[volume]
center_mm = [1, -1, 5]
size_mm = [12, 10, 10]
voxels = [24, 20, 40]
fluence = "both"
vdb = true
"""


SPARSE = [
    "--set", "volume.voxels=[260, 2, 4100]",
    "--set", "volume.size_mm=[26, 0.2, 41]",
    "--set", "volume.center_mm=[0, 0, 20.5]",
    "--set", "volume.fluence=\"track_length\"",
    "--samples", "2000",
]


def main():
    ohd = sys.argv[1] if len(sys.argv) > 1 else str(ROOT / "target/ci/ohd")
    bad = 0
    for sets in ([], SPARSE):
        bad += check(ohd, sets)
    sys.exit(1 if bad else 0)


def check(ohd, sets):
    bad = 0
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "v.toml").write_text(CONFIG)
        subprocess.run([ohd, "run", "-q", "v.toml", "--out", "o", *sets], cwd=tmp, check=True, capture_output=True)
        out = tmp / "o"
        m = json.loads((out / "manifest.json").read_text())["volume"]
        nx, ny, nz = m["voxels"]
        lo = np.array([m["x_range_m"][0], m["y_range_m"][0], m["z_range_m"][0]])
        hi = np.array([m["x_range_m"][1], m["y_range_m"][1], m["z_range_m"][1]])
        edge = (hi - lo) / np.array([nx, ny, nz])
        grids, meta = vdb.readAll(str(out / "volume.vdb"))
        print(f"OpenVDB {vdb.LIBRARY_VERSION}: {len(grids)} grids, file metadata {meta}")
        for g in grids:
            a = np.load(out / f"volume_{g.name}.npy")
            want = np.transpose(a[:, ::-1, :], (2, 1, 0)).astype(np.float32)  # [z][row][x] → [i][j][k]
            got = np.zeros((nx, ny, nz), dtype=np.float32)
            g.copyToArray(got, ijk=(0, 0, 0))
            active = np.zeros((nx, ny, nz), dtype=bool)
            for it in g.citerOnValues():
                assert it.count == 1, "no tiles are written"
                active[it.min] = True
            size = np.array(g.transform.voxelSize())
            centre0 = np.array(g.transform.indexToWorld((0, 0, 0)))
            ok = (
                np.array_equal(got, want)
                and np.array_equal(active, want != 0)
                and np.allclose(size, edge, rtol=1e-12, atol=0)
                and np.allclose(centre0, lo + 0.5 * edge, rtol=0, atol=1e-15)
                and g.background == 0.0
            )
            bad += not ok
            print(
                f"{g.name:26s} {'ok' if ok else 'MISMATCH'}: {int(active.sum())} active of {want.size}, "
                f"max |Δ| {np.abs(got - want).max():.3g}, voxel {size}, centre (0,0,0) {centre0}"
            )
    return bad


if __name__ == "__main__":
    main()
