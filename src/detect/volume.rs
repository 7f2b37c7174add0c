//! Volume tallies (`[volume]`): a voxel grid over an axis-aligned box of the scene, scoring where
//! the light goes inside the medium rather than where it leaves.
//!
//! Three estimates per voxel, each a sum over a batch's paths divided by the paths emitted (as
//! every tally), so per watt emitted:
//!
//! * `volume.absorbed` — the weight the walk's absorption weighting deposits at each real
//!   collision in the voxel, `w·(1 − a)` (`a` the single-scattering albedo there; the same
//!   number `absorbed_fraction` adds up): absorbed power, fraction of the emitted power. Summed
//!   over a box covering the medium it is `absorbed_fraction`, up to the summation order.
//! * `volume.fluence_collision` — the collision estimator of the fluence rate: `w/σt` at each real
//!   collision, over the voxel volume `V`. At a collision `w/σt = w(1 − a)/σa`: it is the
//!   absorbed power over `σa·V` wherever `σa > 0`, and stays defined where `σa = 0` as long as
//!   there are collisions (`σs > 0`).
//! * `volume.fluence_track` — the track-length estimator: `Σ w·ℓ` over the path's segments in
//!   the voxel, over `V`. The walk weights absorption at collisions (MCML), so a path's weight is
//!   constant between two collisions and every segment carries the weight it flew with. Defined
//!   everywhere, clear layers (σt = 0) included, and of lower variance in voxels that are thin
//!   against the mean free path. The default.
//!
//! Both fluences are unbiased estimates of the same `φ = ∫L dΩ` averaged over the voxel (the
//! collision density is `σt·φ`, and `E[Σ w ℓ] = ∫φ dV`), in W/m² per W emitted, i.e. m⁻²
//! (`tests/it/volume.rs` checks that they agree within σ and against the diffusion solution).
//! Only forward paths from the laser score (camera paths, `estimator = "camera"`, carry
//! radiance toward a pixel, not power from the laser).
//!
//! The walk is compiled with this hook only when `[volume]` is given (`VOLUME` in
//! `transport::walk`); without it nothing is looked up or scored.
//!
//! Layout ([`VOLUME_LAYOUT`]): `[nz, ny, nx]`, `z` (depth) ascending from the box's top, rows `y`
//! descending as in every image ([`crate::output::Kind::Image`]), columns `x` ascending — an
//! `[iz]` slice shows as the image a top camera would.

use glam::DVec3;

use crate::output::{Kind, Output, Registry, Slots};

/// The layout of the volume files.
pub const VOLUME_LAYOUT: &str =
    "[nz, ny, nx]: z (depth) ascending from the box's top, y descending (row 0 = largest y), x ascending";

/// Units of the fluence volumes.
pub const FLUENCE_UNITS: &str = "W/m² per W emitted (1/m²)";

/// Which fluence estimators a volume tally scores (`volume.fluence`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FluenceEstimator {
    TrackLength,
    Collision,
    Both,
}

impl FluenceEstimator {
    pub fn track(self) -> bool {
        self != FluenceEstimator::Collision
    }

    pub fn collision(self) -> bool {
        self != FluenceEstimator::TrackLength
    }
}

/// A voxel grid over the box `[min, max]` (m), `voxels = [nx, ny, nz]`.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeGrid {
    pub min: DVec3,
    pub max: DVec3,
    pub voxels: [usize; 3],
    pub fluence: FluenceEstimator,
    /// Voxel edges, m.
    edge: DVec3,
    inv_edge: DVec3,
    inv_volume: f64,
}

/// Where a volume tally's outputs start in the tally vector (`usize::MAX`: not scored).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VolumeSlots {
    pub absorbed: usize,
    pub fluence_collision: usize,
    pub fluence_track: usize,
}

/// The grid and the slots the walk scores it into.
#[derive(Debug, Clone, Copy)]
pub struct VolumeTally<'a> {
    pub grid: &'a VolumeGrid,
    pub slots: VolumeSlots,
}

impl VolumeGrid {
    /// The grid; `min < max` and every count ≥ 1 (validated by the configuration).
    pub fn new(min: DVec3, max: DVec3, voxels: [usize; 3], fluence: FluenceEstimator) -> Self {
        let n = DVec3::new(voxels[0] as f64, voxels[1] as f64, voxels[2] as f64);
        let edge = (max - min) / n;
        VolumeGrid {
            min,
            max,
            voxels,
            fluence,
            edge,
            inv_edge: n / (max - min),
            inv_volume: 1.0 / edge.element_product(),
        }
    }

    /// Voxels in the grid.
    pub fn count(&self) -> usize {
        self.voxels.iter().product()
    }

    /// Edges of a voxel, m.
    pub fn edge(&self) -> DVec3 {
        self.edge
    }

    /// The written shape `[nz, ny, nx]`.
    pub fn shape(&self) -> Vec<usize> {
        vec![self.voxels[2], self.voxels[1], self.voxels[0]]
    }

    /// The flat index ([`VOLUME_LAYOUT`]) of voxel `(ix, iy, iz)`.
    #[inline(always)]
    fn flat(&self, c: [usize; 3]) -> usize {
        let [nx, ny, _] = self.voxels;
        (c[2] * ny + (ny - 1 - c[1])) * nx + c[0]
    }

    /// The flat index of the voxel holding `p`, `None` outside the box.
    #[inline(always)]
    pub fn index(&self, p: DVec3) -> Option<usize> {
        let f = (p - self.min) * self.inv_edge;
        let mut c = [0usize; 3];
        for a in 0..3 {
            // `contains` also refuses NaN.
            if !(0.0..self.voxels[a] as f64).contains(&f[a]) {
                return None;
            }
            c[a] = f[a] as usize;
        }
        Some(self.flat(c))
    }

    /// Declare the outputs (global, after the detectors') and return their slots.
    pub fn declare(&self, reg: &mut Registry) -> VolumeSlots {
        let n = self.count();
        let kind = Kind::Volume { voxels: self.voxels, min: self.min.to_array(), max: self.max.to_array() };
        let budget = Some(("volume.voxels".to_string(), format!("= {:?}", self.voxels)));
        let mut add = |what: &str, units: &'static str| {
            let start = reg.take(n);
            reg.declare(Output {
                file: format!("volume_{what}.npy"),
                units,
                budget_key: budget.clone(),
                ..Output::new(format!("volume.{what}"), kind.clone(), Slots::contiguous(start, n), self.shape())
            });
            start
        };
        let absorbed = add("absorbed", "fraction of emitted power per voxel");
        let fluence_collision =
            if self.fluence.collision() { add("fluence_collision", FLUENCE_UNITS) } else { usize::MAX };
        let fluence_track = if self.fluence.track() { add("fluence_track", FLUENCE_UNITS) } else { usize::MAX };
        VolumeSlots { absorbed, fluence_collision, fluence_track }
    }

    /// The slots of the outputs [`declare`](Self::declare) made in `reg`.
    pub fn slots(reg: &Registry) -> VolumeSlots {
        let at = |name: &str| reg.get(name).map_or(usize::MAX, |o| o.slots.start);
        VolumeSlots {
            absorbed: at("volume.absorbed"),
            fluence_collision: at("volume.fluence_collision"),
            fluence_track: at("volume.fluence_track"),
        }
    }
}

impl VolumeTally<'_> {
    /// A real collision at `p` of a path of weight `w` (before the absorption weighting) in a
    /// medium of extinction `sigma_t` and albedo `albedo` there.
    #[inline(always)]
    pub fn collision(&self, acc: &mut [f64], p: DVec3, w: f64, albedo: f64, sigma_t: f64) {
        let Some(i) = self.grid.index(p) else { return };
        // The same product `absorb` adds to the path's absorbed weight.
        acc[self.slots.absorbed + i] += w * (1.0 - albedo);
        if self.slots.fluence_collision != usize::MAX {
            acc[self.slots.fluence_collision + i] += w / sigma_t * self.grid.inv_volume;
        }
    }

    /// A segment `p + t·d`, `0 ≤ t ≤ len` (`len` may be ∞), flown with weight `w`: its length in
    /// each voxel it crosses (a 3-D DDA, Amanatides & Woo 1987) times `w / V`.
    #[inline(always)]
    pub fn track(&self, acc: &mut [f64], p: DVec3, d: DVec3, len: f64, w: f64) {
        if self.slots.fluence_track != usize::MAX && w > 0.0 {
            track_segment(self.grid, &mut acc[self.slots.fluence_track..], p, d, len, w * self.grid.inv_volume);
        }
    }
}

/// Add `scale × length` of the segment in each voxel into `acc[flat index]`.
#[inline(never)]
fn track_segment(g: &VolumeGrid, acc: &mut [f64], p: DVec3, d: DVec3, len: f64, scale: f64) {
    // Clip to the box (slabs).
    let (mut t0, mut t1) = (0.0f64, len);
    for a in 0..3 {
        if d[a] == 0.0 {
            if !(p[a] >= g.min[a] && p[a] < g.max[a]) {
                return;
            }
            continue;
        }
        let inv = 1.0 / d[a];
        let (ta, tb) = ((g.min[a] - p[a]) * inv, (g.max[a] - p[a]) * inv);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    // (A NaN bound is dropped by `max`/`min`: the segment stays within its finite part.)
    if t0 >= t1 {
        return;
    }
    // The voxel the clipped segment starts in (clamped: the entry point lies on the box's face).
    let q = p + t0 * d;
    let mut cell = [0usize; 3];
    let mut step = [0isize; 3];
    let (mut next, mut delta) = ([f64::INFINITY; 3], [f64::INFINITY; 3]);
    for a in 0..3 {
        let n = g.voxels[a];
        let c = (((q[a] - g.min[a]) * g.inv_edge[a]).floor().max(0.0) as usize).min(n - 1);
        cell[a] = c;
        if d[a] > 0.0 {
            step[a] = 1;
            next[a] = (g.min[a] + (c + 1) as f64 * g.edge[a] - p[a]) / d[a];
            delta[a] = g.edge[a] / d[a];
        } else if d[a] < 0.0 {
            step[a] = -1;
            next[a] = (g.min[a] + c as f64 * g.edge[a] - p[a]) / d[a];
            delta[a] = -g.edge[a] / d[a];
        }
    }
    let mut t = t0;
    loop {
        let a = if next[0] <= next[1] && next[0] <= next[2] {
            0
        } else if next[1] <= next[2] {
            1
        } else {
            2
        };
        let end = next[a].min(t1);
        if end > t {
            acc[g.flat(cell)] += scale * (end - t);
            t = end;
        }
        if next[a] >= t1 {
            return;
        }
        let c = cell[a] as isize + step[a];
        if c < 0 || c >= g.voxels[a] as isize {
            return;
        }
        cell[a] = c as usize;
        next[a] += delta[a];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{PathRng, Purpose};

    fn grid() -> VolumeGrid {
        VolumeGrid::new(DVec3::new(-1.0, -2.0, 0.5), DVec3::new(1.0, 2.0, 3.5), [4, 5, 3], FluenceEstimator::Both)
    }

    /// The lengths a segment leaves in the voxels add up to its length inside the box, and each
    /// voxel gets its own share (checked against fine sampling along the segment).
    #[test]
    fn track_lengths_add_up_and_land_in_their_voxels() {
        let g = grid();
        let mut rng = PathRng::new(3, Purpose::Test, 0, 0);
        for _ in 0..2000 {
            let p = DVec3::new(rng.uniform() * 4.0 - 2.0, rng.uniform() * 6.0 - 3.0, rng.uniform() * 5.0 - 0.5);
            let d = crate::sampling::warp::uniform_sphere(rng.uniform(), rng.uniform());
            let len = rng.uniform() * 6.0;
            let mut acc = vec![0.0; g.count()];
            track_segment(&g, &mut acc, p, d, len, 1.0);
            // Midpoint sampling of the segment at 20000 points.
            let k = 20_000;
            let mut want = vec![0.0; g.count()];
            for j in 0..k {
                if let Some(i) = g.index(p + (j as f64 + 0.5) / k as f64 * len * d) {
                    want[i] += len / k as f64;
                }
            }
            for (a, b) in acc.iter().zip(&want) {
                assert!((a - b).abs() < 2.0 * len / k as f64 + 1e-12, "{p} {d} {len}: {a} vs {b}");
            }
        }
        // An infinite segment is clipped to the box; an axis-parallel one too.
        let mut acc = vec![0.0; g.count()];
        track_segment(&g, &mut acc, DVec3::new(0.1, 0.1, 0.0), DVec3::Z, f64::INFINITY, 1.0);
        assert!((acc.iter().sum::<f64>() - 3.0).abs() < 1e-12);
    }

    /// The written layout: z major from the top, y descending, x ascending.
    #[test]
    fn voxel_index_follows_the_layout() {
        let g = grid();
        let e = g.edge();
        let at = |ix: f64, iy: f64, iz: f64| g.min + DVec3::new((ix + 0.5) * e.x, (iy + 0.5) * e.y, (iz + 0.5) * e.z);
        assert_eq!(g.index(at(0.0, 4.0, 0.0)), Some(0));
        assert_eq!(g.index(at(3.0, 4.0, 0.0)), Some(3));
        assert_eq!(g.index(at(0.0, 0.0, 0.0)), Some(4 * 4));
        assert_eq!(g.index(at(0.0, 4.0, 1.0)), Some(20));
        assert_eq!(g.index(g.max), None);
        assert_eq!(g.index(DVec3::NAN), None);
    }
}
