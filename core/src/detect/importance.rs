//! The importance table `I*(z, θ)` of a detector for the layered stack (`run.importance =
//! "table"` or `"windows"`): what a unit of weight at depth `z`, leaving a scattering event along a direction of
//! polar angle θ (`μ = cos θ`; θ = 0 down into the stack, π up out of it), goes on to bring the
//! detector. It is the adjoint solution that guided directions and weight windows steer by
//! (issue 36; CADIS, and CADIS-Ω's angular importance
//! for collimated beams): in g 0.95–0.97 tissue under a small pupil, what a path brings the
//! camera depends mostly on its direction and depth.
//!
//! **How.** A pilot of forward paths, on its own random streams (the run's seed mixed with
//! [`IMPORTANCE_SEED`]: the table is the same whatever the threads, shards or resumes), through the
//! layered twin of the scene (its regions replaced by their layers' media: the stack the table is
//! of) into the detector alone (its power: the light it receives, whatever its parts). Each path
//! records its states after each scattering event and, when it ends, credits each with the
//! detected weight that came after it over the path's weight there
//! ([`Trace`]): an unbiased sample of the state's value. A bin's importance is
//! the mean of its samples (a ratio of the pilot's per-path means: the values' sum over the
//! states' count). Binned by layer, depth ([`DEPTH_BINS`] per layer) and θ ([`ANGLE_BINS`]), [`ImportanceGrid`],
//! and for a detector away from the beam (a DCS fibre centimetres from the source) by the
//! state's lateral distance to the detector's area too ([`LATERAL_BINS`], [`Lateral`]): there what a
//! path brings depends as much on how far it has still to go sideways as on its depth.
//!
//! **Its cost** is part of the run's time (reported as `importance.seconds`): [`pilot_paths`], half
//! the run's paths, at least [`PILOT_MIN_PATHS`] and at most [`PILOT_PATHS`] (fewer than a
//! hundredth of a shipped LDH run's). A fixed 2·10⁵ paths cost more than the run itself where the
//! run is small or its paths long (issue 52: 20,000 paths of an albedo-1 scene went past 300 s, the
//! pilot ten times the run); half bounds the table's cost by about half the run's (a pilot path
//! goes through the same stack as a run's, without the run's copies, twins or other detectors).
//! Not less: every shipped config (4·10⁵ paths and more) keeps its pilot of 2·10⁵, and a smaller
//! table steers worse (measured: a quarter of 3·10⁵ paths for the DCS fibre of the importance
//! tests took the windows' power σ from below half the plain walk's to 0.71 of it, and a quarter
//! of 4·10⁵ for the control variate's retina moved its ROI spectrum to p = 8·10⁻⁵ against the
//! plain walk's). The table's work is counted in the choice of `run.importance = "auto"`
//! ([`crate::pilot::importance_pilot`]).
//!
//! The pilot itself is [`crate::experiment::Experiment::importance_table`]; the weight windows it
//! feeds are `transport::windows`.

use glam::DVec3;

use crate::detect::Area;
use crate::medium::Scene;
use crate::output::{Kind, Registry, Slots};

/// Depth bins per layer.
pub const DEPTH_BINS: usize = 16;
/// Bins of the lateral distance to a detector away from the beam ([`Lateral`]).
pub const LATERAL_BINS: usize = 16;
/// Polar-angle bins of the direction (uniform in θ: finer in `μ = cos θ` near ±1, where the
/// pupil's cone and the laser's direction lie), θ = 0 down into the stack, π up out of it.
pub const ANGLE_BINS: usize = 48;
/// Transport lengths of a semi-infinite last layer the depth bins span at most (deeper states
/// fall into the last bin).
pub const OPEN_DEPTH_TRANSPORT_LENGTHS: f64 = 20.0;
/// Diffusion lengths `1/μ_eff` of a semi-infinite absorbing layer they span at most.
pub const OPEN_DEPTH_DIFFUSION_LENGTHS: f64 = 10.0;

/// Most paths of the pilot: a run of at least `PILOT_SHARE · PILOT_PATHS` (4·10⁵) paths gets this
/// many, as every run did before issue 52 ([`pilot_paths`]).
pub const PILOT_PATHS: u64 = 200_000;
/// The pilot traces `1/PILOT_SHARE` of the run's paths ([`pilot_paths`]).
pub const PILOT_SHARE: u64 = 2;
/// Fewest paths of the pilot (500 a batch): below, the table's bins would be mostly empty. A run
/// of fewer than `PILOT_SHARE · PILOT_MIN_PATHS` (8,000) paths pays more than half for it.
pub const PILOT_MIN_PATHS: u64 = 4_000;
/// Its batches.
pub const PILOT_BATCHES: u64 = 8;
/// Mixed into the seed for the pilot's streams, which the run's never share.
pub const IMPORTANCE_SEED: u64 = 0x494d_504f_5254;

/// Paths of the importance pilot of a run of `samples` paths: `samples / PILOT_SHARE`, within
/// [`PILOT_MIN_PATHS`] … [`PILOT_PATHS`], a whole number per batch ([`PILOT_BATCHES`]).
pub fn pilot_paths(samples: u64) -> u64 {
    (samples / PILOT_SHARE).clamp(PILOT_MIN_PATHS, PILOT_PATHS) / PILOT_BATCHES * PILOT_BATCHES
}

/// The importance table of one detector ([`crate::experiment::Experiment::importance_table`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ImportanceTable {
    pub grid: ImportanceGrid,
    /// The detector's index.
    pub detector: usize,
    /// Per bin (`[layer][depth][angle]`): the mean value of a unit weight in it (fraction of
    /// the weight the detector receives); NaN where the pilot had no state.
    pub value: Vec<f64>,
    /// Per bin: the pilot's states in it.
    pub states: Vec<u64>,
    /// Per bin: the relative error of its value (∞ where it has fewer than two states or no
    /// value).
    pub relative_error: Vec<f64>,
    /// The detector's response: its detected weight per pilot path (the windows' scale,
    /// `transport::windows`).
    pub response: f64,
    /// The pilot's paths and wall time (s).
    pub paths: u64,
    pub seconds: f64,
    /// The pilot's work in collision steps (counted as the pilots count it, [`crate::pilot`]):
    /// what `run.importance = "auto"` charges the windows for their table.
    pub work: f64,
}

impl ImportanceTable {
    /// The table's shape: layers, (lateral bins, when the grid has them,) depth bins, angle bins.
    pub fn shape(&self) -> Vec<usize> {
        match self.grid.lateral {
            None => vec![self.grid.layers.len(), DEPTH_BINS, ANGLE_BINS],
            Some(_) => vec![self.grid.layers.len(), LATERAL_BINS, DEPTH_BINS, ANGLE_BINS],
        }
    }

    /// The value of bin (`layer`, `lateral`, `depth`, `angle`) (`lateral` 0 without lateral bins).
    pub fn at(&self, layer: usize, lateral: usize, depth: usize, angle: usize) -> f64 {
        self.value[((layer * self.grid.lateral_bins() + lateral) * DEPTH_BINS + depth) * ANGLE_BINS + angle]
    }
}

/// The bins of the importance table: per layer, [`DEPTH_BINS`] depth bins (uniform over a finite
/// layer; over [`OPEN_DEPTH_TRANSPORT_LENGTHS`] transport lengths or
/// [`OPEN_DEPTH_DIFFUSION_LENGTHS`] diffusion lengths of a semi-infinite one) times
/// [`ANGLE_BINS`] polar-angle bins.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportanceGrid {
    /// Per layer: its top depth, bin width (m).
    pub layers: Vec<(f64, f64)>,
    /// The lateral bins, for a detector away from the beam.
    pub lateral: Option<Lateral>,
}

/// The lateral bins of a detector whose area the beam enters outside: [`LATERAL_BINS`] bins
/// of the distance (in the detector's plane, x and y) to its area, uniform from 0 (over it) to
/// the beam's entry (farther in the last bin).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lateral {
    pub area: Area,
    /// Bin width (m).
    pub width: f64,
}

impl Lateral {
    /// The lateral bins of a detector of area `area` for a beam entering at `entry` (x, y in
    /// m): `None` if it enters over the area (or the area is the whole plane).
    pub fn new(area: Area, entry: (f64, f64)) -> Option<Self> {
        let d = area.distance(entry.0, entry.1);
        (d > 0.0 && d.is_finite()).then_some(Lateral { area, width: d / LATERAL_BINS as f64 })
    }

    #[inline]
    fn bin(&self, x: f64, y: f64) -> usize {
        ((self.area.distance(x, y) / self.width) as usize).min(LATERAL_BINS - 1)
    }
}

impl ImportanceGrid {
    /// The grid of `scene`'s stack, with `lateral` bins or none.
    pub fn new(scene: &Scene, lateral: Option<Lateral>) -> Self {
        let layers = scene
            .layers
            .iter()
            .map(|l| {
                let depth = if l.z_bottom.is_finite() {
                    l.z_bottom - l.z_top
                } else {
                    // Where the light still is: the nearer of 20 transport lengths and 10
                    // diffusion lengths `1/μ_eff` (an absorbing layer's light is gone by then).
                    let m = &scene.media[l.medium];
                    let transport = m.sigma_a() + m.sigma_s() * (1.0 - m.info.g);
                    let mu_eff = (3.0 * m.sigma_a() * transport).sqrt();
                    let span = (OPEN_DEPTH_TRANSPORT_LENGTHS / transport).min(OPEN_DEPTH_DIFFUSION_LENGTHS / mu_eff);
                    if span.is_finite() && span > 0.0 { span } else { 1.0 }
                };
                (l.z_top, depth / DEPTH_BINS as f64)
            })
            .collect();
        ImportanceGrid { layers, lateral }
    }

    /// Lateral bins: [`LATERAL_BINS`] or 1 (none).
    pub fn lateral_bins(&self) -> usize {
        if self.lateral.is_some() { LATERAL_BINS } else { 1 }
    }

    /// Bins in all.
    pub fn len(&self) -> usize {
        self.layers.len() * self.lateral_bins() * DEPTH_BINS * ANGLE_BINS
    }

    pub fn is_empty(&self) -> bool {
        self.layers.is_empty()
    }

    /// The bin of a state in layer `li` at `pos` going along a direction of z-component
    /// `dir_z`.
    #[inline]
    pub fn bin(&self, li: usize, pos: DVec3, dir_z: f64) -> usize {
        let (top, width) = self.layers[li];
        let r = self.lateral.as_ref().map_or(0, |l| l.bin(pos.x, pos.y));
        let k = (((pos.z - top) / width).max(0.0) as usize).min(DEPTH_BINS - 1);
        let a = Self::angle_bin(dir_z);
        ((li * self.lateral_bins() + r) * DEPTH_BINS + k) * ANGLE_BINS + a
    }

    /// The angle bin of a direction of z-component `dir_z` (θ from +z, uniform in θ).
    #[inline]
    pub fn angle_bin(dir_z: f64) -> usize {
        let theta = dir_z.clamp(-1.0, 1.0).acos();
        ((theta * (ANGLE_BINS as f64 / std::f64::consts::PI)) as usize).min(ANGLE_BINS - 1)
    }

    /// The polar angle (rad) at the centre of angle bin `a`.
    pub fn angle(a: usize) -> f64 {
        (a as f64 + 0.5) * std::f64::consts::PI / ANGLE_BINS as f64
    }

    /// The bins in words (for `ohd check`): per layer (of `scene`) its depth range.
    pub fn describe(&self, scene: &Scene) -> String {
        let layers: Vec<String> = scene
            .layers
            .iter()
            .zip(&self.layers)
            .map(|(l, &(top, width))| {
                format!("{} {:.0}–{:.0} µm", l.name, 1e6 * top, 1e6 * (top + width * DEPTH_BINS as f64))
            })
            .collect();
        let lateral = match &self.lateral {
            None => String::new(),
            Some(l) => format!(
                " × {LATERAL_BINS} bins of the distance to the detector's area, 0–{:.1} mm",
                1e3 * l.width * LATERAL_BINS as f64
            ),
        };
        format!(
            "{DEPTH_BINS} depth bins per layer ({}) × {ANGLE_BINS} polar-angle bins of {:.2}°{lateral}",
            layers.join(", "),
            180.0 / ANGLE_BINS as f64
        )
    }

    /// The depth (m) at the centre of depth bin `k` of layer `li`.
    pub fn depth(&self, li: usize, k: usize) -> f64 {
        let (top, width) = self.layers[li];
        top + (k as f64 + 0.5) * width
    }
}

/// Tally slots per bin: `Σ x`, `Σ x²`, the count (`x` a state's credited value).
pub const SLOTS: usize = 3;

/// Where the pilot's sums lie: per bin of `grid`, `Σ x`, `Σ x²` and the count, from slot `start`;
/// the detector whose score is credited.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportanceLayout {
    pub grid: ImportanceGrid,
    pub detector: usize,
    pub start: usize,
}

impl ImportanceLayout {
    /// Lay out the sums for detector `detector` from `reg`'s end.
    pub fn declare(grid: ImportanceGrid, detector: usize, reg: &mut Registry) -> Self {
        let len = SLOTS * grid.len();
        let start = reg.take(len);
        reg.declare(crate::output::Output::new(
            "importance.pilot".to_string(),
            Kind::Internal,
            Slots::contiguous(start, len),
            vec![grid.len(), SLOTS],
        ));
        ImportanceLayout { grid, detector, start }
    }
}

/// One path's states and score, as the pilot records them ([`ImportanceLayout`]).
#[derive(Debug, Clone, Default)]
pub struct Trace {
    /// Per state: its bin, the path's weight and its score so far.
    states: Vec<(u32, f64, f64)>,
    score: f64,
}

impl Trace {
    /// A state after a scattering event.
    #[inline]
    pub fn state(&mut self, lay: &ImportanceLayout, li: usize, pos: DVec3, dir_z: f64, weight: f64) {
        self.states.push((lay.grid.bin(li, pos, dir_z) as u32, weight, self.score));
    }

    /// A detection of weight `w` by the traced detector.
    #[inline]
    pub fn scored(&mut self, w: f64) {
        self.score += w;
    }

    /// The path has ended: credit each state with what came after it, per unit weight.
    pub fn end(&mut self, lay: &ImportanceLayout, acc: &mut [f64]) {
        for &(bin, w, before) in &self.states {
            if w > 0.0 {
                let slot = lay.start + SLOTS * bin as usize;
                let x = (self.score - before) / w;
                acc[slot] += x;
                acc[slot + 1] += x * x;
                acc[slot + 2] += 1.0;
            }
        }
        self.states.clear();
        self.score = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each state is credited with the detected weight that came after it over its weight, into
    /// its bin; a second path starts from nothing.
    #[test]
    fn a_state_is_credited_with_what_came_after_it_per_unit_weight() {
        let grid = ImportanceGrid { layers: vec![(0.0, 1e-5)], lateral: None };
        let mut reg = Registry::default();
        let lay = ImportanceLayout::declare(grid, 0, &mut reg);
        let mut acc = vec![0.0; reg.len];
        let mut t = Trace::default();
        // Down at 5 µm, weight 0.5; 0.1 detected; up at 25 µm, weight 0.25; 0.05 detected.
        let at = |z: f64| DVec3::new(0.0, 0.0, z);
        t.state(&lay, 0, at(5e-6), 1.0, 0.5);
        t.scored(0.1);
        t.state(&lay, 0, at(25e-6), -1.0, 0.25);
        t.scored(0.05);
        t.end(&lay, &mut acc);
        let (down, up) = (lay.grid.bin(0, at(5e-6), 1.0), lay.grid.bin(0, at(25e-6), -1.0));
        assert_eq!((down, up), (0, 2 * ANGLE_BINS + ANGLE_BINS - 1));
        assert!((acc[lay.start + SLOTS * down] - 0.15 / 0.5).abs() < 1e-15);
        assert!((acc[lay.start + SLOTS * up] - 0.05 / 0.25).abs() < 1e-15);
        assert_eq!((acc[lay.start + SLOTS * down + 2], acc[lay.start + SLOTS * up + 2]), (1.0, 1.0));
        t.state(&lay, 0, at(5e-6), 1.0, 1.0);
        t.end(&lay, &mut acc);
        assert!((acc[lay.start + SLOTS * down] - 0.3).abs() < 1e-15, "nothing detected after: credited 0");
        assert_eq!(acc[lay.start + SLOTS * down + 2], 2.0);
        assert!((acc[lay.start + SLOTS * down + 1] - 0.09).abs() < 1e-15, "Σ x²: 0.3² + 0²");
    }
}
