//! Density fields of heterogeneous media.
//!
//! A medium with a density `d(x) ≥ 0` has `σa(x) = d(x)·σa` and `σs(x) = d(x)·σs` (so
//! `σt(x) = d(x)·σt` and the albedo stays `σs/σt`, unless an albedo grid overrides it at the
//! collision point: then `σs(x) = a(x)·σt(x)`). The set of fields is closed and dispatched by
//! `match` once per ray span; the tracking loops are generic over [`Field`] and so compiled per
//! field type (see `transport::tracking`).
//!
//! Voxel grids with negative values are clamped to 0 when the density is built, and the number
//! of clamped voxels is kept in [`DensityInfo`] for the manifest (a negative density has no
//! meaning; exporters write small negative values from filtering and resampling). NaN or infinite
//! voxels are refused.

use std::sync::Arc;

use glam::DVec3;
use serde::Serialize;

use super::grid::VoxelGrid;
use super::majorant::{MajorantGrid, Segment, cell_bounds};

/// How a voxel grid is read between its points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    /// Trilinear between the eight surrounding voxel points.
    Trilinear,
    /// The value of the nearest voxel point.
    Nearest,
}

/// Where a grid goes in the scene: its own index-to-world map, then scaled by `scale` about the
/// world origin and moved by `translation` (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    pub translation: DVec3,
    pub scale: f64,
}

impl Default for Placement {
    fn default() -> Self {
        Placement { translation: DVec3::ZERO, scale: 1.0 }
    }
}

/// Which majorant delta and ratio tracking use in a heterogeneous medium.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MajorantKind {
    /// Per-cell bounds of a coarse grid, traversed by DDA (the default).
    Grid,
    /// One bound for the whole field (for comparisons).
    Global,
}

/// Majorant settings of a grid density.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MajorantSpec {
    pub kind: MajorantKind,
    /// Edge of a majorant cell.
    pub cell: CellSize,
}

/// The edge of a majorant cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CellSize {
    /// A fixed number of voxels (≥ 1).
    Voxels(usize),
    /// The cheapest of [`DEFAULT_CELL_VOXELS`] and its power-of-two multiples, up to one cell over
    /// the whole grid, for a medium of extinction `sigma_t` (1/m) at density 1: see
    /// [`STEP_COST`].
    Auto { sigma_t: f64 },
}

/// The cost of one DDA step (crossing into the next majorant cell, the segment handed to the
/// tracker) in units of one tentative collision (a density lookup and two draws). Callgrind on
/// the 64³ random-density grid of `validation/peers/` (1 MB, in cache) counts about 130 against
/// 295 instructions, 0.45; but a lookup in a larger grid also misses the cache, and on the
/// sparse vessels of `validation/vdb/vessels_bench.toml` (2.2 MB of voxels, beside its tissue
/// layers) 4-voxel cells beat 8-voxel ones by 13 % in wall time (1.41–1.46 against
/// 1.26–1.27 paths/µs, 3 runs each), which needs a ratio below 0.35. Hence 0.3.
///
/// The automatic cell size ([`CellSize::Auto`]) minimises the expected cost per unit length of
/// a ray inside the grid, `STEP_COST · Σ_a ⟨|d_a|⟩/h_a + σt · ⟨max⟩`, with ⟨|d_a|⟩ = ½ for
/// isotropic directions, `h_a` the cell edges and ⟨max⟩ the mean over cells of their upper
/// density bound: small cells keep the majorant tight where the density varies (sparse
/// vessels: 4 voxels), large ones save steps where it does not (a dense random grid, whose
/// every cell reaches nearly the global maximum: one cell).
pub const STEP_COST: f64 = 0.3;

/// Default edge of a majorant cell, in voxels, and the finest that [`CellSize::Auto`] considers. Measured on the sparse-vessel scenes
/// (`benches/grid.rs`, a 128³ grid: 4 voxels 1.26 s, 8 voxels 1.33 s, 16 voxels 1.44 s;
/// `validation/vdb/vessels_bench.toml`, three runs each: 2 voxels 0.50–0.52 s, 4 voxels
/// 0.48–0.50 s, 8 voxels 0.55–0.57 s, 16 voxels 0.79–0.80 s, global 1.65–1.68 s). A cell holds 8 bytes (min and max as f32): 4-voxel
/// cells add 1/8 byte per voxel.
pub const DEFAULT_CELL_VOXELS: usize = 4;

impl Default for MajorantSpec {
    fn default() -> Self {
        MajorantSpec { kind: MajorantKind::Grid, cell: CellSize::Voxels(DEFAULT_CELL_VOXELS) }
    }
}

/// A field sampled by the trackers: its value at a point and the majorant segments of a ray.
pub trait Field {
    type Segments<'a>: Iterator<Item = Segment>
    where
        Self: 'a;

    /// The density at `p` (≥ 0).
    fn density(&self, p: DVec3) -> f64;

    /// Bounds of the density along `pos + t·dir` over `[t0, t1]` as consecutive segments.
    fn segments(&self, pos: DVec3, dir: DVec3, t0: f64, t1: f64) -> Self::Segments<'_>;
}

/// A linear ramp along one world axis: `from` at the plane `coordinate = from_at`, `to` at
/// `coordinate = to_at`, linear between and clamped beyond. Its optical depth along any ray is in
/// closed form ([`Ramp::integral`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ramp {
    /// 0, 1, 2 for x, y, z.
    pub axis: usize,
    /// The two planes in increasing order with their values.
    lo: f64,
    hi: f64,
    v_lo: f64,
    v_hi: f64,
    /// The majorant: per piece of the ray (before, between and after the planes), or one bound.
    kind: MajorantKind,
}

impl Ramp {
    /// `None` unless the planes differ and the values are finite and ≥ 0.
    pub fn new(axis: usize, from_at: f64, to_at: f64, from: f64, to: f64, kind: MajorantKind) -> Option<Self> {
        let ok = axis < 3 && from_at.is_finite() && to_at.is_finite() && from_at != to_at;
        if !(ok && from >= 0.0 && to >= 0.0 && from.is_finite() && to.is_finite()) {
            return None;
        }
        let (lo, hi, v_lo, v_hi) =
            if from_at < to_at { (from_at, to_at, from, to) } else { (to_at, from_at, to, from) };
        Some(Ramp { axis, lo, hi, v_lo, v_hi, kind })
    }

    /// The density at coordinate `x` along the axis.
    #[inline]
    pub fn at(&self, x: f64) -> f64 {
        if x <= self.lo {
            self.v_lo
        } else if x >= self.hi {
            self.v_hi
        } else {
            self.v_lo + (self.v_hi - self.v_lo) * (x - self.lo) / (self.hi - self.lo)
        }
    }

    /// `∫_lo^x d`: the antiderivative of the clamped ramp.
    fn antiderivative(&self, x: f64) -> f64 {
        let w = self.hi - self.lo;
        if x <= self.lo {
            self.v_lo * (x - self.lo)
        } else if x >= self.hi {
            0.5 * (self.v_lo + self.v_hi) * w + self.v_hi * (x - self.hi)
        } else {
            let s = x - self.lo;
            self.v_lo * s + 0.5 * (self.v_hi - self.v_lo) * s * s / w
        }
    }

    /// `∫_{t0}^{t1} d(pos + t·dir) dt` (unit `dir`), in closed form.
    pub fn integral(&self, pos: DVec3, dir: DVec3, t0: f64, t1: f64) -> f64 {
        let (p, d) = (pos[self.axis], dir[self.axis]);
        if d == 0.0 {
            return self.at(p) * (t1 - t0);
        }
        (self.antiderivative(p + t1 * d) - self.antiderivative(p + t0 * d)) / d
    }

    /// Smallest and largest value.
    pub fn range(&self) -> (f64, f64) {
        (self.v_lo.min(self.v_hi), self.v_lo.max(self.v_hi))
    }
}

/// Up to three majorant segments of a ray through a ramp.
#[derive(Debug, Clone)]
pub struct RampSegments {
    segs: [Segment; 3],
    i: usize,
    n: usize,
}

impl Iterator for RampSegments {
    type Item = Segment;
    #[inline]
    fn next(&mut self) -> Option<Segment> {
        (self.i < self.n).then(|| {
            self.i += 1;
            self.segs[self.i - 1]
        })
    }
}

impl Field for Ramp {
    type Segments<'a> = RampSegments;

    #[inline]
    fn density(&self, p: DVec3) -> f64 {
        self.at(p[self.axis])
    }

    fn segments(&self, pos: DVec3, dir: DVec3, t0: f64, t1: f64) -> RampSegments {
        let empty = Segment { t0, t1, min: 0.0, max: 0.0 };
        let mut out = RampSegments { segs: [empty; 3], i: 0, n: 0 };
        if t1 <= t0 {
            return out;
        }
        let (p, d) = (pos[self.axis], dir[self.axis]);
        let (lo, hi) = self.range();
        // A constant ramp (equal ends) is one exact segment, as is a ray along the planes.
        if self.kind == MajorantKind::Global || d == 0.0 || self.v_lo == self.v_hi {
            let (min, max) = if d == 0.0 { (self.at(p), self.at(p)) } else { (lo, hi) };
            out.segs[0] = Segment { t0, t1, min, max };
            out.n = 1;
            return out;
        }
        // Cut at the two planes; the density is linear on each piece, so its bounds are the
        // values at the piece's ends (exact, and conservative for the unbounded ends too since
        // the ramp is constant there).
        let (mut a, mut b) = ((self.lo - p) / d, (self.hi - p) / d);
        if a > b {
            std::mem::swap(&mut a, &mut b);
        }
        let mut cuts = [t0, a.clamp(t0, t1), b.clamp(t0, t1), t1];
        cuts.sort_by(f64::total_cmp);
        let mut start = t0;
        for &end in &cuts[1..] {
            if end > start {
                let (va, vb) = (self.at(p + start * d), self.at(p + end * d));
                // Beyond a plane the ramp is constant: bound by the values inside.
                let (va, vb) = if end.is_finite() { (va, vb) } else { (va, va) };
                out.segs[out.n] = Segment { t0: start, t1: end, min: va.min(vb), max: va.max(vb) };
                out.n += 1;
                start = end;
            }
        }
        out
    }
}

/// What a voxel holds, and the `f64` value it is read as (a density or albedo as `f64`, a
/// velocity as `DVec3`).
pub trait Voxel: Copy {
    type Value: Copy
        + std::ops::Add<Output = Self::Value>
        + std::ops::Sub<Output = Self::Value>
        + std::ops::Mul<f64, Output = Self::Value>;
    fn value(self) -> Self::Value;
}

impl Voxel for f32 {
    type Value = f64;
    #[inline(always)]
    fn value(self) -> f64 {
        f64::from(self)
    }
}

impl Voxel for [f32; 3] {
    type Value = DVec3;
    #[inline(always)]
    fn value(self) -> DVec3 {
        DVec3::new(f64::from(self[0]), f64::from(self[1]), f64::from(self[2]))
    }
}

/// A voxel grid placed in the world and read by trilinear or nearest lookup.
#[derive(Debug, Clone, PartialEq)]
pub struct GridField<T = f32> {
    pub grid: Arc<VoxelGrid<T>>,
    pub interpolation: Interpolation,
    /// World = index·`scale` + `offset` per axis (the grid's map and the placement combined).
    scale: DVec3,
    offset: DVec3,
    inv_scale: DVec3,
    /// Continuous-index box outside which every lookup is the background: `min − 1 ..= max + 1`.
    outer_lo: DVec3,
    outer_hi: DVec3,
}

impl<T: Voxel> GridField<T> {
    pub fn new(grid: Arc<VoxelGrid<T>>, interpolation: Interpolation, placement: Placement) -> Self {
        let t = grid.transform;
        let scale = t.voxel_size * placement.scale;
        let offset = t.translation * placement.scale + placement.translation;
        let (outer_lo, outer_hi) = match grid.index_bounds() {
            Some((lo, hi)) => (
                DVec3::new(f64::from(lo[0]), f64::from(lo[1]), f64::from(lo[2])) - 1.0,
                DVec3::new(f64::from(hi[0]), f64::from(hi[1]), f64::from(hi[2])) + 1.0,
            ),
            None => (DVec3::INFINITY, DVec3::NEG_INFINITY),
        };
        GridField { grid, interpolation, scale, offset, inv_scale: scale.recip(), outer_lo, outer_hi }
    }

    /// The same placement and lookup over the values `f(v)` of every voxel and the background.
    pub fn map(&self, f: impl Fn(T) -> T) -> Self {
        let mut grid = (*self.grid).clone();
        grid.background = f(grid.background);
        for v in grid.data.iter_mut() {
            *v = f(*v);
        }
        GridField { grid: Arc::new(grid), ..self.clone() }
    }

    /// World position of index-space point `u`.
    pub fn to_world(&self, u: DVec3) -> DVec3 {
        u * self.scale + self.offset
    }

    /// World size of one voxel, m.
    pub fn voxel_world(&self) -> DVec3 {
        self.scale
    }

    /// The value at world point `p`.
    #[inline]
    pub fn value(&self, p: DVec3) -> T::Value {
        let u = (p - self.offset) * self.inv_scale;
        let g = &*self.grid;
        // Outside the padded block (or NaN): the background, without integer conversions.
        if !(u.cmpgt(self.outer_lo).all() && u.cmplt(self.outer_hi).all()) {
            return g.background.value();
        }
        match self.interpolation {
            Interpolation::Nearest => {
                let r = u.round();
                g.get([r.x as i32, r.y as i32, r.z as i32]).value()
            }
            Interpolation::Trilinear => {
                // `u` lies in (−1, dims) here: a truncation corrects to the floor without the
                // libm call `f64::floor` makes on baseline x86-64 (4 % of a grid run's profile).
                let f = DVec3::new(floor_small(u.x), floor_small(u.y), floor_small(u.z));
                let w = u - f;
                let i0 = [f.x as i32, f.y as i32, f.z as i32];
                let rel = [i0[0] - g.min[0], i0[1] - g.min[1], i0[2] - g.min[2]];
                let (nx, ny) = (g.dims[0], g.dims[1]);
                let inner = (0..3).all(|a| rel[a] >= 0 && (rel[a] as usize) + 1 < g.dims[a]);
                let c = if inner {
                    // All eight corners in the block: direct reads.
                    let o = (rel[2] as usize * ny + rel[1] as usize) * nx + rel[0] as usize;
                    let (sy, sz) = (nx, nx * ny);
                    let d = &g.data;
                    [
                        d[o],
                        d[o + 1],
                        d[o + sy],
                        d[o + sy + 1],
                        d[o + sz],
                        d[o + sz + 1],
                        d[o + sz + sy],
                        d[o + sz + sy + 1],
                    ]
                } else {
                    let at = |dx: i32, dy: i32, dz: i32| g.get([i0[0] + dx, i0[1] + dy, i0[2] + dz]);
                    [
                        at(0, 0, 0),
                        at(1, 0, 0),
                        at(0, 1, 0),
                        at(1, 1, 0),
                        at(0, 0, 1),
                        at(1, 0, 1),
                        at(0, 1, 1),
                        at(1, 1, 1),
                    ]
                };
                let c = c.map(T::value);
                let x00 = c[0] + (c[1] - c[0]) * w.x;
                let x10 = c[2] + (c[3] - c[2]) * w.x;
                let x01 = c[4] + (c[5] - c[4]) * w.x;
                let x11 = c[6] + (c[7] - c[6]) * w.x;
                let y0 = x00 + (x10 - x00) * w.y;
                let y1 = x01 + (x11 - x01) * w.y;
                y0 + (y1 - y0) * w.z
            }
        }
    }
}

/// Why a voxel grid cannot serve as a density or albedo.
#[derive(Debug, Clone, PartialEq)]
pub enum GridError {
    /// A voxel (or the background) is NaN or infinite: its index (`None` for the background).
    NotFinite(Option<[i32; 3]>),
    /// An albedo outside [0, 1]: the index (`None` for the background) and the value.
    AlbedoRange(Option<[i32; 3]>, f32),
    /// Placement scale not finite and > 0, or a translation not finite.
    Placement,
    /// `cell_voxels` out of range.
    CellVoxels(usize),
}

/// A voxel-grid density with its majorant.
#[derive(Debug, Clone, PartialEq)]
pub struct GridDensity {
    pub field: GridField,
    /// `None` for a global majorant.
    pub majorant: Option<MajorantGrid>,
    /// Bounds of the whole field, background included.
    pub min: f64,
    pub max: f64,
}

/// `x.floor()` for finite `|x| < 2³¹`.
#[inline(always)]
fn floor_small(x: f64) -> f64 {
    let t = f64::from(x as i32);
    if t > x { t - 1.0 } else { t }
}

impl GridDensity {
    /// A density from `grid` (negative voxels clamped to 0; the count is returned beside it).
    pub fn new(
        mut grid: VoxelGrid<f32>,
        interpolation: Interpolation,
        placement: Placement,
        spec: MajorantSpec,
    ) -> Result<(Self, usize), GridError> {
        if !(placement.scale.is_finite() && placement.scale > 0.0 && placement.translation.is_finite()) {
            return Err(GridError::Placement);
        }
        if let CellSize::Voxels(n) = spec.cell
            && !(1..=4096).contains(&n)
        {
            return Err(GridError::CellVoxels(n));
        }
        if !grid.background.is_finite() {
            return Err(GridError::NotFinite(None));
        }
        if let Some(o) = grid.data.iter().position(|v| !v.is_finite()) {
            return Err(GridError::NotFinite(Some(grid.index_of(o))));
        }
        let mut clamped = 0;
        for v in grid.data.iter_mut() {
            if *v < 0.0 {
                *v = 0.0;
                clamped += 1;
            }
        }
        if grid.background < 0.0 {
            grid.background = 0.0;
            clamped += 1;
        }
        let bg = grid.background;
        let (mut min, mut max) = (bg, bg);
        for &v in &grid.data {
            min = min.min(v);
            max = max.max(v);
        }
        let field = GridField::new(Arc::new(grid), interpolation, placement);
        let majorant = match spec.kind {
            MajorantKind::Global => None,
            MajorantKind::Grid => Some(Self::majorant_grid(&field, spec.cell)),
        };
        Ok((GridDensity { field, majorant, min: f64::from(min), max: f64::from(max) }, clamped))
    }

    /// Per-cell bounds over the block padded by one voxel each side (where a lookup can differ
    /// from the background): under trilinear lookup a point in the index cube `[i, i + 1]³`
    /// is a convex combination of its eight corners, so the bounds of the voxel points
    /// `lo + c·n ..= lo + (c + 1)·n` bound every lookup in the cell, and nearest lookup reads one
    /// of those points too.
    fn majorant_grid(field: &GridField, size: CellSize) -> MajorantGrid {
        let g = &*field.grid;
        let bg = f64::from(g.background);
        let Some((lo, hi)) = g.index_bounds() else {
            return MajorantGrid {
                origin: DVec3::ZERO,
                cell: DVec3::ONE,
                dims: [1, 1, 1],
                bounds: vec![(g.background, g.background)],
                outside: bg,
            };
        };
        let lo = [i64::from(lo[0]) - 1, i64::from(lo[1]) - 1, i64::from(lo[2]) - 1];
        let hi = [i64::from(hi[0]) + 1, i64::from(hi[1]) + 1, i64::from(hi[2]) + 1];
        let n = match size {
            CellSize::Voxels(n) => n,
            CellSize::Auto { .. } => DEFAULT_CELL_VOXELS,
        };
        let cells = std::array::from_fn(|a| ((hi[a] - lo[a]) as usize).div_ceil(n).max(1));
        let bounds = cell_bounds(lo, n, cells, |i, j, k| g.get([i as i32, j as i32, k as i32]));
        let origin = field.to_world(DVec3::new(lo[0] as f64, lo[1] as f64, lo[2] as f64));
        let mut best = MajorantGrid { origin, cell: field.scale * n as f64, dims: cells, bounds, outside: bg };
        let CellSize::Auto { sigma_t } = size else { return best };
        // Coarsen by halving until one cell is left; keep the cheapest. A parent's bounds are its
        // (up to eight) children's: their voxel points are the parent's, shared planes included,
        // and a child missing past the block's end would only have held the background, which
        // the padded edge cells already hold.
        // ⟨max⟩ is over the padded block: a coarse cell reaching past it counts for the part
        // inside, where rays through the grid run.
        let extent: [usize; 3] = std::array::from_fn(|a| (hi[a] - lo[a]) as usize);
        let cost = |m: &MajorantGrid, n: usize| {
            let steps: f64 = (0..3).map(|a| 0.5 / m.cell[a]).sum();
            let inside = |a: usize, c: usize| ((c + 1) * n).min(extent[a]).saturating_sub(c * n) as f64;
            let [nx, ny, _] = m.dims;
            let mean_max = m
                .bounds
                .iter()
                .enumerate()
                .map(|(i, b)| f64::from(b.1) * inside(0, i % nx) * inside(1, (i / nx) % ny) * inside(2, i / (nx * ny)))
                .sum::<f64>()
                / (extent[0] * extent[1] * extent[2]) as f64;
            STEP_COST * steps + sigma_t * mean_max
        };
        let (mut level, mut n) = (best.clone(), DEFAULT_CELL_VOXELS);
        let mut best_cost = cost(&best, n);
        while level.dims != [1, 1, 1] {
            (level, n) = (level.coarsened(), 2 * n);
            let c = cost(&level, n);
            if c < best_cost {
                (best, best_cost) = (level.clone(), c);
            }
        }
        best
    }

    /// The edge of a majorant cell in voxels (`None` for a global majorant).
    pub fn majorant_cell_voxels(&self) -> Option<usize> {
        self.majorant.as_ref().map(|m| (m.cell.x / self.field.scale.x).round() as usize)
    }
}

/// Segments of a ray through a grid density: by DDA, or one global bound.
#[derive(Debug, Clone)]
pub enum GridSegments<'a> {
    Dda(super::majorant::Dda<'a>),
    Global(Option<Segment>),
}

impl Iterator for GridSegments<'_> {
    type Item = Segment;
    #[inline]
    fn next(&mut self) -> Option<Segment> {
        match self {
            GridSegments::Dda(d) => d.next(),
            GridSegments::Global(s) => s.take(),
        }
    }
}

impl Field for GridDensity {
    type Segments<'a> = GridSegments<'a>;

    #[inline]
    fn density(&self, p: DVec3) -> f64 {
        self.field.value(p)
    }

    #[inline]
    fn segments(&self, pos: DVec3, dir: DVec3, t0: f64, t1: f64) -> GridSegments<'_> {
        match &self.majorant {
            // A constant field (every voxel and the background alike) is one exact segment: no
            // DDA through cells that all hold the same bounds.
            Some(m) if self.min != self.max => GridSegments::Dda(m.segments(pos, dir, t0, t1)),
            _ => GridSegments::Global((t1 > t0).then_some(Segment { t0, t1, min: self.min, max: self.max })),
        }
    }
}

/// A medium's density field (a closed set). Held once per medium behind its `Arc`, so the size
/// of the grid variant costs nothing; boxing it would add a pointer chase per lookup.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum Density {
    Ramp(Ramp),
    Grid(GridDensity),
}

impl Density {
    /// The density at `p`.
    pub fn at(&self, p: DVec3) -> f64 {
        match self {
            Density::Ramp(r) => r.density(p),
            Density::Grid(g) => g.density(p),
        }
    }

    /// Smallest and largest density anywhere.
    pub fn range(&self) -> (f64, f64) {
        match self {
            Density::Ramp(r) => r.range(),
            Density::Grid(g) => (g.min, g.max),
        }
    }
}

/// A medium's spatial variation: its density and, optionally, an albedo grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Heterogeneity {
    pub density: Density,
    /// Single-scattering albedo per voxel (values in [0, 1]), overriding σs/σt at a collision.
    pub albedo: Option<GridField>,
    pub info: DensityInfo,
}

impl Heterogeneity {
    /// An albedo grid for this medium (values and background must lie in [0, 1]).
    pub fn albedo_grid(
        grid: VoxelGrid<f32>,
        interpolation: Interpolation,
        placement: Placement,
    ) -> Result<GridField, GridError> {
        if !(placement.scale.is_finite() && placement.scale > 0.0 && placement.translation.is_finite()) {
            return Err(GridError::Placement);
        }
        let bad = |v: f32| !(0.0..=1.0).contains(&v);
        if bad(grid.background) {
            return Err(GridError::AlbedoRange(None, grid.background));
        }
        if let Some(o) = grid.data.iter().position(|&v| bad(v)) {
            return Err(GridError::AlbedoRange(Some(grid.index_of(o)), grid.data[o]));
        }
        Ok(GridField::new(Arc::new(grid), interpolation, placement))
    }
}

/// What the manifest records of a density.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DensityInfo {
    /// "ramp", "grid" or "vdb".
    pub kind: String,
    /// Where a grid came from: `file:grid` for a VDB file.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    pub interpolation: Option<Interpolation>,
    pub majorant: Option<MajorantKind>,
    pub majorant_cells: Option<[usize; 3]>,
    pub majorant_cell_voxels: Option<usize>,
    /// Points of the stored voxel block.
    pub voxels: Option<[usize; 3]>,
    pub negative_voxels_clamped: usize,
    pub min: f64,
    pub max: f64,
    pub albedo_grid: bool,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::medium::grid::IndexTransform;
    use crate::sampling::{PathRng, Purpose, warp};

    fn random_grid(r: &mut PathRng, dims: [usize; 3], bg: f32) -> VoxelGrid<f32> {
        let t = IndexTransform { voxel_size: DVec3::new(0.1, 0.2, 0.15), translation: DVec3::new(-0.3, 0.1, 0.2) };
        let mut g = VoxelGrid::new([-3, 2, 0], dims, bg, t);
        for v in g.data.iter_mut() {
            // Sparse: most voxels 0, some large.
            let u = r.uniform();
            *v = if u < 0.6 { 0.0 } else { (r.uniform() * 10.0) as f32 };
        }
        g
    }

    #[test]
    fn trilinear_reproduces_voxels_and_linear_fields() {
        let t = IndexTransform { voxel_size: DVec3::splat(0.5), translation: DVec3::new(1.0, -1.0, 0.0) };
        let mut g = VoxelGrid::new([0, 0, 0], [4, 5, 6], 0.0f32, t);
        for k in 0..6 {
            for j in 0..5 {
                for i in 0..4 {
                    g.set([i, j, k], (1 + i + 2 * j + 3 * k) as f32);
                }
            }
        }
        let place = Placement { translation: DVec3::new(0.0, 0.0, 1.0), scale: 2.0 };
        let f = GridField::new(Arc::new(g), Interpolation::Trilinear, place);
        // Index (1, 2, 3) sits at world (1·0.5 + 1)·2, (2·0.5 − 1)·2, (3·0.5)·2 + 1.
        assert_eq!(f.value(DVec3::new(3.0, 0.0, 4.0)), 15.0);
        // Linear in between.
        let u = DVec3::new(1.3, 2.6, 3.9);
        assert!((f.value(f.to_world(u)) - (1.0 + 1.3 + 5.2 + 11.7)).abs() < 1e-5);
        let n = GridField { interpolation: Interpolation::Nearest, ..f.clone() };
        assert_eq!(n.value(n.to_world(u)), (1 + 1 + 6 + 12) as f64);
        // Far away: the background.
        assert_eq!(f.value(DVec3::splat(1e30)), 0.0);
    }

    #[test]
    fn negative_voxels_are_clamped_and_nan_refused() {
        let t = IndexTransform { voxel_size: DVec3::ONE, translation: DVec3::ZERO };
        let mut g = VoxelGrid::new([0, 0, 0], [2, 2, 2], 0.0f32, t);
        g.set([1, 0, 0], -2.0);
        let (d, clamped) =
            GridDensity::new(g.clone(), Interpolation::Trilinear, Placement::default(), MajorantSpec::default())
                .unwrap();
        assert_eq!((clamped, d.min), (1, 0.0));
        g.set([0, 1, 1], f32::NAN);
        let e = GridDensity::new(g, Interpolation::Trilinear, Placement::default(), MajorantSpec::default());
        assert_eq!(e.unwrap_err(), GridError::NotFinite(Some([0, 1, 1])));
    }

    /// Property: the majorant segments bound the density at every point of every ray, for random
    /// sparse grids, both lookups, several cell sizes, and non-zero backgrounds.
    #[test]
    fn majorant_bounds_density_everywhere() {
        let mut r = PathRng::new(11, Purpose::Test, 0, 0);
        let mut checked = 0u64;
        for case in 0..24 {
            let dims = [
                1 + (r.uniform() * 12.0) as usize,
                1 + (r.uniform() * 12.0) as usize,
                1 + (r.uniform() * 12.0) as usize,
            ];
            let bg = if case % 3 == 0 { 0.5 } else { 0.0 };
            let g = random_grid(&mut r, dims, bg);
            let interp = if case % 2 == 0 { Interpolation::Trilinear } else { Interpolation::Nearest };
            // Every fourth case an automatic cell (coarsened bounds), from fine to one cell.
            let cell = match case % 4 {
                3 => CellSize::Auto { sigma_t: [0.0, 0.3, 3.0, 30.0, 300.0, 3000.0][case / 4] },
                _ => CellSize::Voxels(1 + case % 5),
            };
            let spec = MajorantSpec { kind: MajorantKind::Grid, cell };
            let place = Placement { translation: DVec3::new(0.05, -0.02, 0.3), scale: 1.5 };
            let (d, _) = GridDensity::new(g, interp, place, spec).unwrap();
            let m = d.majorant.as_ref().unwrap();
            let (lo, hi) = m.world_bounds();
            let size = hi - lo;
            for _ in 0..300 {
                let pos = lo - 0.2 * size + DVec3::new(r.uniform(), r.uniform(), r.uniform()) * 1.4 * size;
                let dir = warp::uniform_sphere(r.uniform(), r.uniform());
                let len = size.length();
                for s in d.segments(pos, dir, 0.0, len) {
                    for _ in 0..8 {
                        let t = s.t0 + r.uniform() * (s.t1 - s.t0);
                        let v = d.density(pos + t * dir);
                        assert!(v <= s.max * (1.0 + 1e-6) + 1e-6, "case {case}: {v} > {}", s.max);
                        assert!(v >= s.min * (1.0 - 1e-6) - 1e-6, "case {case}: {v} < {}", s.min);
                        checked += 1;
                    }
                }
            }
            // Random points anywhere: within their cell's bounds.
            for _ in 0..2000 {
                let p = lo + DVec3::new(r.uniform(), r.uniform(), r.uniform()) * size;
                let c = ((p - lo) / m.cell)
                    .floor()
                    .min(DVec3::new(m.dims[0] as f64, m.dims[1] as f64, m.dims[2] as f64) - 1.0);
                let (bmin, bmax) = m.cell_bounds([c.x as usize, c.y as usize, c.z as usize]);
                let v = d.density(p);
                assert!(v <= bmax * (1.0 + 1e-6) + 1e-6 && v >= bmin * (1.0 - 1e-6) - 1e-6);
            }
        }
        assert!(checked > 100_000, "{checked}");
    }

    /// The automatic majorant cell: one cell over a dense random grid (every cell reaches nearly
    /// the maximum, so steps are pure cost), 4 voxels over a sparse grid when collisions are
    /// frequent (σt ≫ 1/voxel), coarser when they are rare.
    #[test]
    fn automatic_cell_size_follows_the_cost_model() {
        let mut r = PathRng::new(13, Purpose::Test, 0, 0);
        let t = IndexTransform { voxel_size: DVec3::splat(1e-5), translation: DVec3::ZERO };
        let mut dense = VoxelGrid::new([0, 0, 0], [32, 32, 32], 0.0f32, t);
        let mut sparse = dense.clone();
        for (d, s) in dense.data.iter_mut().zip(sparse.data.iter_mut()) {
            *d = (0.5 + 0.5 * r.uniform()) as f32;
            *s = if r.uniform() < 0.002 { 10.0 } else { 0.0 };
        }
        let cells = |g: &VoxelGrid<f32>, sigma_t: f64| {
            let spec = MajorantSpec { kind: MajorantKind::Grid, cell: CellSize::Auto { sigma_t } };
            let (d, _) = GridDensity::new(g.clone(), Interpolation::Trilinear, Placement::default(), spec).unwrap();
            (d.majorant_cell_voxels(), d.majorant.unwrap().dims)
        };
        // Per voxel: σt = 1e5 /m is one collision per voxel at density 1.
        assert_eq!(cells(&dense, 1e5), (Some(64), [1, 1, 1]));
        assert_eq!(cells(&sparse, 1e5), (Some(4), [9, 9, 9]));
        assert_eq!(cells(&sparse, 1.0), (Some(64), [1, 1, 1]));
    }

    #[test]
    fn ramp_integral_matches_quadrature() {
        let ramp = Ramp::new(2, 1.0, 0.2, 3.0, 0.5, MajorantKind::Grid).unwrap();
        assert_eq!(ramp.at(0.0), 0.5);
        assert_eq!(ramp.at(2.0), 3.0);
        assert!((ramp.at(0.6) - 1.75).abs() < 1e-12);
        let mut r = PathRng::new(12, Purpose::Test, 0, 0);
        for _ in 0..200 {
            let pos = DVec3::new(r.uniform(), r.uniform(), r.uniform() * 2.0 - 0.5);
            let dir = warp::uniform_sphere(r.uniform(), r.uniform());
            let (t0, t1) = (r.uniform() * 0.3, 0.3 + r.uniform() * 2.0);
            let n = 20_000;
            let h = (t1 - t0) / n as f64;
            let quad: f64 = (0..n).map(|i| ramp.density(pos + (t0 + (i as f64 + 0.5) * h) * dir) * h).sum();
            assert!((ramp.integral(pos, dir, t0, t1) - quad).abs() < 1e-6, "{pos} {dir}");
            // Segments tile and bound.
            let segs: Vec<_> = ramp.segments(pos, dir, t0, t1).collect();
            assert_eq!((segs[0].t0, segs.last().unwrap().t1), (t0, t1));
            for s in &segs {
                for k in 0..=10 {
                    let v = ramp.density(pos + (s.t0 + (s.t1 - s.t0) * k as f64 / 10.0) * dir);
                    assert!(v <= s.max + 1e-12 && v >= s.min - 1e-12);
                }
            }
        }
    }
}
