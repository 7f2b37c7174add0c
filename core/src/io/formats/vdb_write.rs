//! A writer of our own for OpenVDB files: dense `f32` volumes as `FloatGrid`s
//! (`Tree_float_5_4_3`), the subset [`super::vdb`] reads, in the layout OpenVDB itself writes
//! (`io/Archive.cc` `write`/`writeGrid`, `tree/RootNode.h`, `tree/InternalNode.h`,
//! `tree/LeafNode.h` `writeTopology`/`writeBuffers`, `io/Compression.h` `writeCompressedValues`;
//! the format facts are listed in [`super::vdb`]'s module docs).
//!
//! What is written: file format version 224 (library 10.0), grid offsets, one descriptor and grid
//! per volume. Each grid: compression flags `0x2` (active-mask compression, no zip or blosc: the
//! values are raw `f32`), metadata (`class` = `unknown`, `name`, `units`, `is_saved_as_half_float`
//! and the statistics `file_bbox_min/max`, `file_voxel_count`), a `ScaleTranslateMap`, then the
//! tree: background 0, no tiles, a root child per 4096³ block holding a non-zero voxel, internal
//! nodes with their child masks and no active tiles, leaves (8³) for every block with a non-zero
//! voxel. **Non-zero voxels are active, zero voxels inactive** (the background), so a sparse
//! volume stays small and OpenVDB's active-voxel iteration visits the voxels that hold light.
//! Node values go through the value codec with metadata byte 0 (every inactive value is the
//! background): only the active values are stored.
//!
//! Index space: voxel `(i, j, k)` of a dense `[nx, ny, nz]` block is index `(i, j, k)`, its
//! centre at world `origin + (i, j, k)·voxel_size` (OpenVDB's cell-centred convention), so the
//! world coordinates are the caller's.

use std::collections::BTreeMap;

use glam::DVec3;

/// The file format version written (OpenVDB 6–11 write 224).
pub const FORMAT_VERSION: u32 = 224;

/// One dense volume to write as a `FloatGrid`.
#[derive(Debug, Clone, Copy)]
pub struct DenseFloatGrid<'a> {
    pub name: &'a str,
    /// Free text stored as the grid's `units` metadata.
    pub units: &'a str,
    /// `[nx, ny, nz]`, each < 2³¹.
    pub dims: [usize; 3],
    /// `nx·ny·nz` values, `x` fastest, then `y`, then `z`: `values[(k·ny + j)·nx + i]`.
    pub values: &'a [f32],
    /// Voxel edges, m (> 0).
    pub voxel_size: DVec3,
    /// World position of the centre of voxel (0, 0, 0), m.
    pub origin: DVec3,
}

/// `log2` of the children per axis of the root's children (5: 32³), of theirs (4: 16³) and of a
/// leaf's voxels (3: 8³); and the voxels per axis a node covers (4096, 128, 8).
const LOG2: [u32; 3] = [5, 4, 3];
const SPAN: [u32; 3] = [12, 7, 3];

/// The slot of index `ijk` in a node covering `2^span` voxels per axis with `2^log2` children
/// per axis: `(x << 2·log2) | (y << log2) | z` of the child's coordinates within the node.
fn slot(ijk: [i32; 3], span: u32, log2: u32) -> usize {
    let child = span - log2;
    let c = |v: i32| ((v & ((1 << span) - 1)) >> child) as usize;
    (c(ijk[0]) << (2 * log2)) | (c(ijk[1]) << log2) | c(ijk[2])
}

/// A node origin: `ijk` rounded down to a multiple of `2^span`.
fn origin(ijk: [i32; 3], span: u32) -> [i32; 3] {
    ijk.map(|v| v & !((1 << span) - 1))
}

struct Out(Vec<u8>);

impl Out {
    fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    fn u32(&mut self, v: u32) {
        self.0.extend(v.to_le_bytes());
    }
    fn i32(&mut self, v: i32) {
        self.0.extend(v.to_le_bytes());
    }
    fn i64(&mut self, v: i64) {
        self.0.extend(v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.0.extend(v.to_le_bytes());
    }
    fn vec3d(&mut self, v: DVec3) {
        for x in v.to_array() {
            self.0.extend(x.to_le_bytes());
        }
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32);
        self.0.extend(s.as_bytes());
    }
    fn coord(&mut self, c: [i32; 3]) {
        for v in c {
            self.i32(v);
        }
    }
    fn mask(&mut self, bits: &[u64]) {
        for w in bits {
            self.0.extend(w.to_le_bytes());
        }
    }
    /// One metadata entry: name, type name, byte size, bytes.
    fn meta(&mut self, name: &str, ty: &str, bytes: &[u8]) {
        self.string(name);
        self.string(ty);
        self.u32(bytes.len() as u32);
        self.0.extend(bytes);
    }
    /// `io::writeCompressedValues` with active-mask compression and every inactive value the
    /// background: metadata byte 0, then the active values only, raw.
    fn values(&mut self, values: &[f32], mask: &[u64]) {
        self.u8(0);
        for (n, v) in values.iter().enumerate() {
            if mask[n / 64] >> (n % 64) & 1 == 1 {
                self.f32(*v);
            }
        }
    }
}

/// A leaf: its value mask and 512 values.
struct Leaf {
    origin: [i32; 3],
    mask: [u64; 8],
    values: Vec<f32>,
}

/// The grid's leaves under their nodes: root children by origin, their children and then leaves by
/// slot — the order OpenVDB writes them in (depth first, slot order).
type Tree = BTreeMap<[i32; 3], BTreeMap<usize, BTreeMap<usize, Leaf>>>;

/// The smallest and largest index of the active voxels.
type Bbox = ([i32; 3], [i32; 3]);

/// The sparse tree of the non-zero voxels, their count and bounding box.
fn build(g: &DenseFloatGrid) -> (Tree, u64, Option<Bbox>) {
    let [nx, ny, nz] = g.dims;
    let mut tree = Tree::new();
    let (mut count, mut lo, mut hi) = (0u64, [i32::MAX; 3], [i32::MIN; 3]);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let v = g.values[(k * ny + j) * nx + i];
                if v == 0.0 {
                    continue;
                }
                let ijk = [i as i32, j as i32, k as i32];
                let leaf = tree
                    .entry(origin(ijk, SPAN[0]))
                    .or_default()
                    .entry(slot(ijk, SPAN[0], LOG2[0]))
                    .or_default()
                    .entry(slot(ijk, SPAN[1], LOG2[1]))
                    .or_insert_with(|| Leaf { origin: origin(ijk, SPAN[2]), mask: [0; 8], values: vec![0.0; 512] });
                let n = slot(ijk, SPAN[2], LOG2[2]);
                leaf.mask[n / 64] |= 1 << (n % 64);
                leaf.values[n] = v;
                count += 1;
                for a in 0..3 {
                    lo[a] = lo[a].min(ijk[a]);
                    hi[a] = hi[a].max(ijk[a]);
                }
            }
        }
    }
    (tree, count, (count > 0).then_some((lo, hi)))
}

/// Write one grid (from its compression flags to the end of its buffers); returns where its
/// buffers start.
fn write_grid(o: &mut Out, g: &DenseFloatGrid) -> usize {
    let (tree, count, bbox) = build(g);
    o.u32(0x2);
    // Metadata, sorted by name as OpenVDB's MetaMap keeps it.
    let (lo, hi) = bbox.unwrap_or(([0; 3], [0; 3]));
    let vec3i = |c: [i32; 3]| -> Vec<u8> { c.iter().flat_map(|v| v.to_le_bytes()).collect() };
    o.i32(if bbox.is_some() { 7 } else { 4 });
    o.meta("class", "string", b"unknown");
    if bbox.is_some() {
        o.meta("file_bbox_max", "vec3i", &vec3i(hi));
        o.meta("file_bbox_min", "vec3i", &vec3i(lo));
        o.meta("file_voxel_count", "int64", &(count as i64).to_le_bytes());
    }
    o.meta("is_saved_as_half_float", "bool", &[0]);
    o.meta("name", "string", g.name.as_bytes());
    o.meta("units", "string", g.units.as_bytes());
    // ScaleTranslateMap: translation, scale, voxel size, 1/scale, 1/scale², 1/(2·scale).
    o.string("ScaleTranslateMap");
    let s = g.voxel_size;
    o.vec3d(g.origin);
    o.vec3d(s);
    o.vec3d(s);
    o.vec3d(1.0 / s);
    o.vec3d(1.0 / (s * s));
    o.vec3d(0.5 / s);
    // Topology: one buffer per leaf, the background, no tiles, the root's children.
    o.i32(1);
    o.f32(0.0);
    o.u32(0);
    o.u32(tree.len() as u32);
    let node_values = |o: &mut Out, slots: usize| {
        // No active tiles: every slot inactive, its value (0 under a child) the background.
        o.mask(&vec![0u64; slots / 64]);
        o.values(&vec![0.0; slots], &vec![0u64; slots / 64]);
    };
    let child_mask = |slots: usize, on: &mut dyn Iterator<Item = usize>| -> Vec<u64> {
        let mut m = vec![0u64; slots / 64];
        for n in on {
            m[n / 64] |= 1 << (n % 64);
        }
        m
    };
    for (root_origin, upper) in &tree {
        o.coord(*root_origin);
        o.mask(&child_mask(32768, &mut upper.keys().copied()));
        node_values(o, 32768);
        for lower in upper.values() {
            o.mask(&child_mask(4096, &mut lower.keys().copied()));
            node_values(o, 4096);
            for leaf in lower.values() {
                o.mask(&leaf.mask);
            }
        }
    }
    // Buffers: every leaf, depth first: its value mask again, then its values.
    let block = o.0.len();
    for leaf in tree.values().flat_map(|u| u.values()).flat_map(|l| l.values()) {
        debug_assert!(leaf.origin.iter().all(|v| v & 7 == 0));
        o.mask(&leaf.mask);
        o.values(&leaf.values, &leaf.mask);
    }
    block
}

/// A UUID-shaped identifier (36 characters) derived from the file's contents, so that the same
/// volumes give the same bytes.
fn uuid(grids: &[DenseFloatGrid]) -> String {
    // FNV-1a over the names and value bits: an identifier, not a checksum.
    let mut h: [u64; 2] = [0xcbf2_9ce4_8422_2325, 0x8422_2325_cbf2_9ce4];
    let mut eat = |b: &[u8]| {
        for &x in b {
            for (n, v) in h.iter_mut().enumerate() {
                *v = (*v ^ u64::from(x) ^ n as u64).wrapping_mul(0x100_0000_01b3);
            }
        }
    };
    for g in grids {
        eat(g.name.as_bytes());
        for v in g.values {
            eat(&v.to_le_bytes());
        }
    }
    let hex = format!("{:016x}{:016x}", h[0], h[1]);
    format!("{}-{}-4{}-8{}-{}", &hex[0..8], &hex[8..12], &hex[13..16], &hex[17..20], &hex[20..32])
}

/// An OpenVDB file holding `grids` as `FloatGrid`s (names must differ).
pub fn to_bytes(grids: &[DenseFloatGrid], creator: &str) -> Vec<u8> {
    let mut o = Out(Vec::new());
    // Header: magic, format version, library version, grid offsets stored, UUID.
    o.i64(0x5644_4220);
    o.u32(FORMAT_VERSION);
    o.u32(10);
    o.u32(0);
    o.u8(1);
    o.0.extend(uuid(grids).as_bytes());
    // File metadata, then the grid count.
    o.i32(1);
    o.meta("creator", "string", creator.as_bytes());
    o.i32(grids.len() as i32);
    for g in grids {
        // Descriptor: unique name, tree type, instance parent, then the grid, block and end
        // offsets, filled in once known.
        o.string(g.name);
        o.string("Tree_float_5_4_3");
        o.string("");
        let at = o.0.len();
        o.0.extend([0u8; 24]);
        let grid_pos = o.0.len() as i64;
        let block = write_grid(&mut o, g) as i64;
        let end = o.0.len() as i64;
        o.0[at..at + 8].copy_from_slice(&grid_pos.to_le_bytes());
        o.0[at + 8..at + 16].copy_from_slice(&block.to_le_bytes());
        o.0[at + 16..at + 24].copy_from_slice(&end.to_le_bytes());
    }
    o.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_match_the_reader_convention() {
        assert_eq!(slot([1, 2, 3], SPAN[2], LOG2[2]), (1 << 6) | (2 << 3) | 3);
        assert_eq!(slot([8 * 3 + 1, 8 * 5, 8 * 15 + 7], SPAN[1], LOG2[1]), (3 << 8) | (5 << 4) | 15);
        assert_eq!(slot([128 * 31, 0, 127], SPAN[0], LOG2[0]), 31 << 10);
        assert_eq!(origin([4097, 130, 9], SPAN[0]), [4096, 0, 0]);
        assert_eq!(origin([4097, 130, 9], SPAN[2]), [4096, 128, 8]);
    }

    #[test]
    fn uuid_is_36_characters() {
        let g = DenseFloatGrid {
            name: "a",
            units: "",
            dims: [1, 1, 1],
            values: &[1.0],
            voxel_size: DVec3::ONE,
            origin: DVec3::ZERO,
        };
        assert_eq!(uuid(&[g]).len(), 36);
    }

    /// A sparse grid spanning two root children (x ≥ 4096) and several internal nodes, written
    /// and read back by the reader (itself checked against OpenVDB's files): every value, the
    /// active set (the non-zero voxels) and the map.
    #[test]
    fn sparse_grid_across_nodes_reads_back() {
        let dims = [4100, 3, 140];
        let mut values = vec![0.0f32; dims.iter().product()];
        let mut set = |i: usize, j: usize, k: usize, v: f32| values[(k * dims[1] + j) * dims[0] + i] = v;
        for (n, &(i, j, k)) in
            [(0, 0, 0), (7, 2, 8), (8, 1, 127), (129, 0, 128), (4095, 2, 139), (4096, 0, 1), (4099, 2, 139)]
                .iter()
                .enumerate()
        {
            set(i, j, k, n as f32 + 0.5);
        }
        set(5, 1, 5, -3.25);
        let g = DenseFloatGrid {
            name: "fluence",
            units: "1/m²",
            dims,
            values: &values,
            voxel_size: DVec3::new(1e-3, 2e-3, 5e-4),
            origin: DVec3::new(-0.5, 0.25, 1e-3),
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.vdb");
        std::fs::write(&path, to_bytes(&[g], "test")).unwrap();
        let info = crate::io::formats::vdb::grids(&path).unwrap();
        assert_eq!(info.len(), 1);
        assert_eq!((info[0].name.as_str(), info[0].file_voxel_count), ("fluence", Some(8)));
        let tree = crate::io::formats::vdb::read_tree::<f32>(&path, Some("fluence"), &Default::default()).unwrap();
        assert_eq!(tree.transform.voxel_size, g.voxel_size);
        assert_eq!(tree.transform.translation, g.origin);
        assert_eq!(tree.background, 0.0);
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let v = values[(k * dims[1] + j) * dims[0] + i];
                    let ijk = [i as i32, j as i32, k as i32];
                    assert_eq!(tree.probe(ijk), (v, v != 0.0), "{ijk:?}");
                }
            }
        }
        assert_eq!(tree.active_stats().0, 8);
    }
}
