//! The importance table `I*(z, μ)` of a detector for the layered stack (`run.importance =
//! "table"`): what a unit of weight at depth `z`, leaving a scattering event along a direction of
//! polar angle θ (`μ = cos θ`; θ = 0 down into the stack, π up out of it), goes on to bring the
//! detector. It is the adjoint solution that guided directions and weight windows steer by
//! (issue 36; shared/reference/variance-reduction.md §3: CADIS, and CADIS-Ω's angular importance
//! for collimated beams): in g 0.95–0.97 tissue under a small pupil, what a path brings the
//! camera depends mostly on its direction and depth.
//!
//! **How.** A pilot of forward paths, on its own random streams (the run's seed mixed with
//! [`IMPORTANCE_SEED`]: the table is the same whatever the threads, shards or resumes), through the
//! layered twin of the scene (its regions replaced by their layers' media: the stack the table is
//! of) into the detector alone (its power: the light it receives, whatever its parts). Each path
//! records its states after each scattering event and, when it ends, credits each with the
//! detected weight that came after it over the path's weight there
//! ([`crate::detect::importance`]): an unbiased sample of the state's value. A bin's importance is
//! the mean of its samples (a ratio of the pilot's per-path means: the values' sum over the
//! states' count). Binned by layer, depth ([`DEPTH_BINS`] per layer) and θ ([`ANGLE_BINS`]).
//!
//! **Its cost** is part of the run's time (reported as `importance.seconds`): [`PILOT_PATHS`]
//! paths, fewer than a hundredth of a shipped LDH run's.

use crate::detect::importance::{ANGLE_BINS, DEPTH_BINS, ImportanceGrid};
use crate::detect::{DetectorKind, Estimator};
use crate::experiment::{Experiment, Silent};
use crate::sampling::rng::mix64;
use crate::transport::ControlVariate;

/// Paths of the pilot.
pub const PILOT_PATHS: u64 = 200_000;
/// Its batches.
const PILOT_BATCHES: u64 = 8;
/// Mixed into the seed for the pilot's streams, which the run's never share.
pub const IMPORTANCE_SEED: u64 = 0x494d_504f_5254;

/// The importance table of one detector ([`table`]).
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
    /// The pilot's paths and wall time (s).
    pub paths: u64,
    pub seconds: f64,
}

impl ImportanceTable {
    /// The table's shape: layers, depth bins, angle bins.
    pub fn shape(&self) -> [usize; 3] {
        [self.grid.layers.len(), DEPTH_BINS, ANGLE_BINS]
    }

    /// The value of bin (`layer`, `depth`, `angle`).
    pub fn at(&self, layer: usize, depth: usize, angle: usize) -> f64 {
        self.value[(layer * DEPTH_BINS + depth) * ANGLE_BINS + angle]
    }
}

/// Why `exp` has no importance table (`None`: it has one, [`table`]): it needs a main output of a
/// detector scored by forward paths (a surface detector with the forward estimator, or a lidar
/// receiver).
pub fn obstacle(exp: &Experiment) -> Option<String> {
    let main = exp.main_output();
    let Some(d) = main.detector else {
        return Some(format!("the main output `{}` is not a detector's", main.name));
    };
    match &exp.detectors[d].kind {
        DetectorKind::Surface(s) if s.estimator() == Estimator::Camera => Some(format!(
            "detector `{}` is estimated from the camera's side (the table is of forward paths)",
            exp.detectors[d].name
        )),
        _ => None,
    }
}

/// The importance table of the main output's detector of `exp` (`None` where [`obstacle`] finds
/// one), from a pilot of [`PILOT_PATHS`] paths on its own streams.
pub fn table(exp: &Experiment) -> Option<ImportanceTable> {
    if obstacle(exp).is_some() {
        return None;
    }
    let detector = exp.main_output().detector?;
    let start = std::time::Instant::now();
    let mut pilot = exp.clone();
    if !pilot.scene.regions.is_empty() {
        pilot.scene = exp.scene.layered_twin();
    }
    // The detector alone, its power alone (the light it receives), scored as the run scores it.
    let mut d = exp.detectors[detector].clone();
    if let DetectorKind::Surface(s) = &mut d.kind {
        s.parts.clear();
    }
    pilot.detectors = vec![d];
    pilot.volume = None;
    pilot.references.clear();
    pilot.plan.seed = mix64(exp.plan.seed ^ IMPORTANCE_SEED);
    pilot.plan.batches = PILOT_BATCHES;
    pilot.plan.paths_per_batch = PILOT_PATHS / PILOT_BATCHES;
    pilot.plan.walk.control_variate = ControlVariate::Off;
    pilot.plan.walk.launches = None;
    pilot.plan.importance = false;
    pilot.plan.importance_trace = Some(0);
    let out = pilot.run(&Silent);
    let lay = out.layout.importance.as_ref().expect("the pilot lays out its sums");
    let mean = out.estimates.mean();
    let paths = (out.estimates.batches() as u64 * out.paths_per_batch) as f64;
    let bins = lay.grid.len();
    let (mut value, mut states) = (vec![f64::NAN; bins], vec![0; bins]);
    for b in 0..bins {
        let (sum, count) = (mean[lay.start + 2 * b], mean[lay.start + 2 * b + 1]);
        states[b] = (count * paths).round() as u64;
        if count > 0.0 {
            value[b] = sum / count;
        }
    }
    Some(ImportanceTable {
        grid: lay.grid.clone(),
        detector,
        value,
        states,
        paths: paths as u64,
        seconds: start.elapsed().as_secs_f64(),
    })
}
