//! Voxel grids: values at the integer points of an index lattice, placed in the world by a
//! scale-and-translate map (OpenVDB's convention: the value of voxel `ijk` sits at the world point
//! `ijk·voxel_size + translation`, the voxel's centre).
//!
//! A [`VoxelGrid`] stores a dense block of the lattice (the bounding box of a file's active voxels,
//! say); every point outside it takes the background value. The OpenVDB reader (`io::formats::vdb`) and
//! the synthetic media both produce this one type, and the media sample it.

use glam::DVec3;

/// World position of index-space point `p`: `p·voxel_size + translation` (per axis).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IndexTransform {
    /// Voxel edge per axis, m (all > 0).
    pub voxel_size: DVec3,
    /// World position of index (0, 0, 0), m.
    pub translation: DVec3,
}

impl IndexTransform {
    /// Index space to world.
    #[inline]
    pub fn to_world(&self, index: DVec3) -> DVec3 {
        index * self.voxel_size + self.translation
    }

    /// World to (continuous) index space.
    #[inline]
    pub fn to_index(&self, world: DVec3) -> DVec3 {
        (world - self.translation) / self.voxel_size
    }
}

/// A dense block of a voxel lattice, `min ..= min + dims − 1` in index space, with a background
/// value everywhere else. Values are stored x-fastest: `data[(k·ny + j)·nx + i]` for the point
/// `min + (i, j, k)`.
#[derive(Debug, Clone, PartialEq)]
pub struct VoxelGrid<T> {
    /// Smallest index of the stored block.
    pub min: [i32; 3],
    /// Points per axis of the stored block (each ≥ 1, or all 0 for a grid of background only).
    pub dims: [usize; 3],
    pub data: Vec<T>,
    /// The value outside the stored block.
    pub background: T,
    pub transform: IndexTransform,
}

/// Offset of index `ijk` in an x-fastest block of `dims` points from `min`, or `None` outside it.
#[inline]
pub fn block_offset(min: [i32; 3], dims: [usize; 3], ijk: [i32; 3]) -> Option<usize> {
    let mut rel = [0usize; 3];
    for a in 0..3 {
        let r = i64::from(ijk[a]) - i64::from(min[a]);
        if r < 0 || r >= dims[a] as i64 {
            return None;
        }
        rel[a] = r as usize;
    }
    Some((rel[2] * dims[1] + rel[1]) * dims[0] + rel[0])
}

impl<T: Copy> VoxelGrid<T> {
    /// A block of `dims` points from `min`, all set to `background`.
    pub fn new(min: [i32; 3], dims: [usize; 3], background: T, transform: IndexTransform) -> Self {
        VoxelGrid { min, dims, data: vec![background; dims[0] * dims[1] * dims[2]], background, transform }
    }

    /// Offset into `data` of index `ijk`, or `None` outside the stored block.
    #[inline]
    pub fn offset(&self, ijk: [i32; 3]) -> Option<usize> {
        block_offset(self.min, self.dims, ijk)
    }

    /// The index of `data[offset]`.
    pub fn index_of(&self, offset: usize) -> [i32; 3] {
        let [nx, ny, _] = self.dims;
        let rel = [offset % nx, (offset / nx) % ny, offset / (nx * ny)];
        std::array::from_fn(|a| self.min[a] + rel[a] as i32)
    }

    /// The value at index `ijk` (the background outside the stored block).
    #[inline]
    pub fn get(&self, ijk: [i32; 3]) -> T {
        self.offset(ijk).map_or(self.background, |o| self.data[o])
    }

    /// Set the value at index `ijk`; `false` (and nothing changed) outside the stored block.
    pub fn set(&mut self, ijk: [i32; 3], value: T) -> bool {
        match self.offset(ijk) {
            Some(o) => {
                self.data[o] = value;
                true
            }
            None => false,
        }
    }

    /// Smallest and largest stored index (`None` for an empty block).
    pub fn index_bounds(&self) -> Option<([i32; 3], [i32; 3])> {
        if self.dims.contains(&0) {
            return None;
        }
        let max = std::array::from_fn(|a| self.min[a] + self.dims[a] as i32 - 1);
        Some((self.min, max))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lookups_inside_and_outside_the_block() {
        let t = IndexTransform { voxel_size: DVec3::splat(0.5), translation: DVec3::new(1.0, 0.0, -1.0) };
        let mut g = VoxelGrid::new([-2, 0, 3], [3, 2, 2], 7.0f32, t);
        assert!(g.set([0, 1, 4], 1.5));
        assert!(!g.set([1, 0, 3], 2.0));
        assert_eq!(g.get([0, 1, 4]), 1.5);
        assert_eq!(g.get([-2, 0, 3]), 7.0);
        assert_eq!(g.get([-3, 0, 3]), 7.0);
        assert_eq!(g.offset([0, 1, 4]), Some((2 + 1) * 3 + 2));
        assert_eq!(g.index_of((2 + 1) * 3 + 2), [0, 1, 4]);
        assert_eq!(g.index_bounds(), Some(([-2, 0, 3], [0, 1, 4])));
        assert_eq!(t.to_world(DVec3::new(2.0, 2.0, 2.0)), DVec3::new(2.0, 1.0, 0.0));
        assert_eq!(t.to_index(DVec3::new(2.0, 1.0, 0.0)), DVec3::new(2.0, 2.0, 2.0));
    }
}
