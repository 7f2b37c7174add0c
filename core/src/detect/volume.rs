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
//! `transport::forward`); without it nothing is looked up or scored.
//!
//! **Time bins** (`[volume.time]`, the axis type of a detector's TPSF): each estimate is also
//! scored per time-of-flight bin, `volume.<what>_time`, [`VOLUME_TIME_LAYOUT`]. The time of an
//! event is the path's optical length there over `c` (`l = Σ nᵢ ℓᵢ` from the emission point, as
//! the TPSF's), so a collision lands in the bin of `l/c`; a straight piece of length `ℓ` from
//! optical length `l` spans `[l, l + nℓ]` and its length is split over the bins exactly (the
//! share in a bin is the part of that interval inside it over `n`), not at its centre. Events
//! outside `[t_min, t_max)` are left out of the binned estimates only: the untimed ones keep
//! everything, and a bin axis covering every event sums to them (`tests/it/volume.rs`).
//!
//! **The global time gate** (`run.time_gate_ns = [t0, t1]` as optical lengths `[l0, l1]`): a
//! gated walk scores only what happens inside it — collisions with `l0 ≤ l ≤ l1`, and each piece
//! of track clipped to the part with its optical length in `[l0, l1]` (the last piece before the
//! walk ends at `l1` included) — the same events `absorbed_fraction` counts under a gate.
//!
//! Layout ([`VOLUME_LAYOUT`]): `[nz, ny, nx]`, `z` (depth) ascending from the box's top, rows `y`
//! descending as in every image ([`crate::output::Kind::Image`]), columns `x` ascending — an
//! `[iz]` slice shows as the image a top camera would.

use glam::DVec3;

use crate::SPEED_OF_LIGHT;
use crate::output::{Axis, Kind, Output, Registry, Slots};
use crate::spectrum::{FrequencyAxis, Slot};

/// The layout of the volume files.
pub const VOLUME_LAYOUT: &str =
    "[nz, ny, nx]: z (depth) ascending from the box's top, y descending (row 0 = largest y), x ascending";

/// The layout of the time-binned volume files: a [`VOLUME_LAYOUT`] volume per time bin.
pub const VOLUME_TIME_LAYOUT: &str = "[nt, nz, ny, nx]: time bins ascending, then each bin's volume as [nz, ny, nx]";

/// Units of the fluence volumes.
pub const FLUENCE_UNITS: &str = "W/m² per W emitted (1/m²)";

/// Units of the absorbed-power volume.
pub const ABSORBED_UNITS: &str = "fraction of emitted power per voxel";

/// Units of the time-binned volumes: each bin holds the part of the untimed estimate whose events
/// fall in it (the time integral of the pulse response over the bin).
pub const ABSORBED_TIME_UNITS: &str = "fraction of emitted energy per voxel and time bin";
pub const FLUENCE_TIME_UNITS: &str = "J/m² per J emitted (1/m²) per time bin: ∫ fluence rate dt over the bin";

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

/// A voxel grid over the box `[min, max]` (m), `voxels = [nx, ny, nz]`, with an optional time
/// axis.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeGrid {
    pub min: DVec3,
    pub max: DVec3,
    pub voxels: [usize; 3],
    pub fluence: FluenceEstimator,
    /// Time-of-flight bins (s), `None`: untimed only.
    pub time: Option<FrequencyAxis>,
    /// The time axis as optical lengths (m): what the walk's `l` is binned on.
    length_axis: Option<FrequencyAxis>,
    /// Also write `volume.vdb` (`volume.vdb = true`).
    pub vdb: bool,
    /// Voxel edges, m.
    edge: DVec3,
    inv_edge: DVec3,
    inv_volume: f64,
}

/// Where a volume tally's outputs start in the tally vector (`usize::MAX`: not scored); the
/// `_time` ones are the time-binned estimates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VolumeSlots {
    pub absorbed: usize,
    pub fluence_collision: usize,
    pub fluence_track: usize,
    pub absorbed_time: usize,
    pub fluence_collision_time: usize,
    pub fluence_track_time: usize,
}

/// The grid and the slots the walk scores it into; `gate`: the global time gate as optical
/// lengths `[l0, l1]` (m), read only by walks compiled with the gate.
#[derive(Debug, Clone, Copy)]
pub struct VolumeTally<'a> {
    pub grid: &'a VolumeGrid,
    pub slots: VolumeSlots,
    pub gate: Option<(f64, f64)>,
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
            time: None,
            length_axis: None,
            vdb: false,
            edge,
            inv_edge: n / (max - min),
            inv_volume: 1.0 / edge.element_product(),
        }
    }

    /// The grid with time-of-flight bins `time` (s).
    pub fn with_time(mut self, time: FrequencyAxis) -> Self {
        let c = SPEED_OF_LIGHT;
        self.length_axis = FrequencyAxis::new(c * time.f_min, c * time.f_max, time.bins);
        self.time = self.length_axis.is_some().then_some(time);
        self
    }

    /// Time bins (1 without a time axis).
    pub fn time_bins(&self) -> usize {
        self.time.map_or(1, |a| a.bins)
    }

    /// The written shape of the time-binned outputs, `[nt, nz, ny, nx]`.
    pub fn time_shape(&self) -> Vec<usize> {
        let mut s = vec![self.time_bins()];
        s.extend(self.shape());
        s
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

    /// Declare the outputs (global, after the detectors') and return their slots: the untimed
    /// estimates, then (with a time axis) the time-binned ones.
    pub fn declare(&self, reg: &mut Registry) -> VolumeSlots {
        let n = self.count();
        let kind = Kind::Volume { voxels: self.voxels, min: self.min.to_array(), max: self.max.to_array() };
        let budget = Some(("volume.voxels".to_string(), format!("= {:?}", self.voxels)));
        let mut add = |what: &str, units: &'static str, timed: bool| {
            let (len, shape, budget) = if timed {
                let nt = self.time_bins();
                (nt * n, self.time_shape(), Some(("volume.time.bins".to_string(), format!("= {nt}"))))
            } else {
                (n, self.shape(), budget.clone())
            };
            let start = reg.take(len);
            let mut o = Output::new(format!("volume.{what}"), kind.clone(), Slots::contiguous(start, len), shape);
            if let (true, Some(t)) = (timed, self.time) {
                o.axes[0] = Axis::bins("time_s", "s", t.f_min, t.bin_width(), t.bins);
            }
            reg.declare(Output { file: format!("volume_{what}.npy"), units, budget_key: budget, ..o });
            start
        };
        let (col, track) = (self.fluence.collision(), self.fluence.track());
        let absorbed = add("absorbed", ABSORBED_UNITS, false);
        let fluence_collision = if col { add("fluence_collision", FLUENCE_UNITS, false) } else { usize::MAX };
        let fluence_track = if track { add("fluence_track", FLUENCE_UNITS, false) } else { usize::MAX };
        let mut slots = VolumeSlots {
            absorbed,
            fluence_collision,
            fluence_track,
            absorbed_time: usize::MAX,
            fluence_collision_time: usize::MAX,
            fluence_track_time: usize::MAX,
        };
        if self.time.is_some() {
            slots.absorbed_time = add("absorbed_time", ABSORBED_TIME_UNITS, true);
            if col {
                slots.fluence_collision_time = add("fluence_collision_time", FLUENCE_TIME_UNITS, true);
            }
            if track {
                slots.fluence_track_time = add("fluence_track_time", FLUENCE_TIME_UNITS, true);
            }
        }
        slots
    }
}

impl VolumeTally<'_> {
    /// A real collision at `p`, optical length `l` from the emission (0 in walks that do not
    /// track it; read only with a time axis), of a path of weight `w` (before the absorption
    /// weighting) in a medium of extinction `sigma_t` and albedo `albedo` there. The walk calls it
    /// only for collisions inside the time gate.
    #[inline(always)]
    pub fn collision(&self, acc: &mut [f64], p: DVec3, l: f64, w: f64, albedo: f64, sigma_t: f64) {
        let Some(i) = self.grid.index(p) else { return };
        // The same product `absorb` adds to the path's absorbed weight.
        let deposit = w * (1.0 - albedo);
        acc[self.slots.absorbed + i] += deposit;
        let fluence = (self.slots.fluence_collision != usize::MAX).then(|| w / sigma_t * self.grid.inv_volume);
        if let Some(f) = fluence {
            acc[self.slots.fluence_collision + i] += f;
        }
        if let Some(axis) = &self.grid.length_axis
            && let Slot::Bin(k) = axis.locate(l)
        {
            let at = k * self.grid.count() + i;
            acc[self.slots.absorbed_time + at] += deposit;
            if let Some(f) = fluence {
                acc[self.slots.fluence_collision_time + at] += f;
            }
        }
    }

    /// A segment `p + t·d`, `0 ≤ t ≤ len` (`len` may be ∞), flown with weight `w` from optical
    /// length `l` in a layer of index `n`: its length in each voxel it crosses (a 3-D DDA,
    /// Amanatides & Woo 1987) times `w / V`; with a time axis also split over the bins of the
    /// optical length `l + n·t`; with `GATE` only its part with `l + n·t` inside the gate.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub fn track<const GATE: bool>(&self, acc: &mut [f64], p: DVec3, d: DVec3, len: f64, w: f64, l: f64, n: f64) {
        if self.slots.fluence_track == usize::MAX || w <= 0.0 {
            return;
        }
        let (mut from, mut to) = (0.0, len);
        if GATE && let Some((l0, l1)) = self.gate {
            from = ((l0 - l) / n).max(0.0);
            to = to.min((l1 - l) / n);
            if from >= to {
                return;
            }
        }
        self.score_track(acc, p, d, (from, to), w * self.grid.inv_volume, l, n);
    }

    /// [`track`](Self::track)'s scoring of the piece `range` of the segment, `scale = w / V`.
    /// Out of line: the walk's event loop stays as small as without the volume tally.
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    fn score_track(&self, acc: &mut [f64], p: DVec3, d: DVec3, range: (f64, f64), scale: f64, l: f64, n: f64) {
        let (untimed, timed) = (self.slots.fluence_track, self.slots.fluence_track_time);
        let (from, to) = range;
        match &self.grid.length_axis {
            None => track_segment(self.grid, p, d, from, to, |i, a, b| acc[untimed + i] += scale * (b - a)),
            Some(axis) => {
                let count = self.grid.count();
                track_segment(self.grid, p, d, from, to, |i, a, b| {
                    acc[untimed + i] += scale * (b - a);
                    split_over_bins(axis, l + n * a, l + n * b, |k, dl| acc[timed + k * count + i] += scale * dl / n);
                })
            }
        }
    }
}

/// Split the optical-length interval `[la, lb]` over the bins of `axis`: `add(k, length of
/// its part in bin k)`; the parts outside the axis are dropped.
#[inline(always)]
fn split_over_bins(axis: &FrequencyAxis, la: f64, lb: f64, mut add: impl FnMut(usize, f64)) {
    let (lo, hi) = (la.max(axis.f_min), lb.min(axis.f_max));
    if lo >= hi {
        return;
    }
    let Slot::Bin(mut k) = axis.locate(lo) else { return };
    let width = axis.bin_width();
    let mut a = lo;
    loop {
        // The bin's upper edge, computed as `locate` places its lower one.
        let edge = if k + 1 == axis.bins { axis.f_max } else { axis.f_min + (k + 1) as f64 * width };
        let b = edge.min(hi);
        if b > a {
            add(k, b - a);
            a = b;
        }
        if edge >= hi || k + 1 == axis.bins {
            return;
        }
        k += 1;
    }
}

/// Call `add(flat index, t_a, t_b)` for each voxel the piece `t_from ≤ t ≤ t_to` of the ray
/// `p + t·d` crosses, with the part `[t_a, t_b]` inside it.
#[inline(always)]
fn track_segment(g: &VolumeGrid, p: DVec3, d: DVec3, t_from: f64, t_to: f64, mut add: impl FnMut(usize, f64, f64)) {
    // Clip to the box (slabs).
    let (mut t0, mut t1) = (t_from, t_to);
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
            add(g.flat(cell), t, end);
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
            track_segment(&g, p, d, 0.0, len, |i, a, b| acc[i] += b - a);
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
        track_segment(&g, DVec3::new(0.1, 0.1, 0.0), DVec3::Z, 0.0, f64::INFINITY, |i, a, b| acc[i] += b - a);
        assert!((acc.iter().sum::<f64>() - 3.0).abs() < 1e-12);
    }

    /// An optical-length interval split over the bins: each part inside its bin, the parts
    /// adding up to the interval's overlap with the axis (against a fine sampling).
    #[test]
    fn intervals_split_over_the_bins_exactly() {
        let axis = FrequencyAxis::new(1.0, 4.0, 7).unwrap();
        let mut rng = PathRng::new(5, Purpose::Test, 0, 0);
        for _ in 0..2000 {
            let la = rng.uniform() * 6.0 - 0.5;
            let lb = la + rng.uniform() * rng.uniform() * 5.0;
            let mut got = [0.0; 7];
            split_over_bins(&axis, la, lb, |k, dl| got[k] += dl);
            let k = 20_000;
            let mut want = [0.0; 7];
            for j in 0..k {
                if let Slot::Bin(b) = axis.locate(la + (j as f64 + 0.5) / k as f64 * (lb - la)) {
                    want[b] += (lb - la) / k as f64;
                }
            }
            for (a, b) in got.iter().zip(&want) {
                assert!((a - b).abs() < 2.0 * (lb - la) / k as f64 + 1e-12, "[{la}, {lb}]: {a} vs {b}");
            }
            let total: f64 = got.iter().sum();
            assert!((total - (lb.min(4.0) - la.max(1.0)).max(0.0)).abs() < 1e-12);
        }
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
