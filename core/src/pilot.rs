//! The pilot that decides `estimator = "auto"`: before a run, a short run of each estimator on
//! its own random numbers, and the one with the lower per-pixel variance × work is kept. The
//! same for `run.importance = "auto"`: with and without the weight windows
//! ([`importance_pilot`]).
//!
//! **What is compared.** For a camera detector, the figure of each estimator is the squared
//! relative error of the image its users read — M0+ for an LDH camera, the intensity image
//! otherwise — as the project states an image's error (`src/lib.rs`, "Estimates"): `V = Σ_p σ_p²
//! / Σ_p m_p²` (σ_p the standard error of pixel `p` from the pilot's batches, `m_p` the mean of
//! the two estimators' values, one reference for both), times the work of the run that gave it,
//! both scaled to the full run. `V · work` is what a run of either estimator pays for a given
//! error: variance falls as 1/paths and work grows with them, so the figure does not depend on
//! the pilot's size. Pooled over pixels, not a median of per-pixel ratios: a batch variance is
//! unbiased however heavy-tailed the contributions are, but a pixel's ratio to its own noisy
//! value is not, and in a short pilot most pixels have seen none of the rare large
//! contributions (a pixel the forward pilot missed would count as error-free). The pooled figure
//! weighs pixels by their value²: it can disagree with the per-pixel median, measured on the
//! shipped LDH scenes (validation/README.md).
//!
//! **Work, not time.** The choice must be the same on any number of threads, in every shard and
//! on resuming, so it is made from counted steps ([`crate::stats::Work`]), never from a clock:
//! real and null collisions of every path plus [`crate::stats::CONNECTION_STEPS`] per connection traced
//! (a shadow ray, a camera path's connection to the laser). The weight was measured on the
//! shipped LDH scenes (validation/README.md, "Camera-side estimation"): time per step
//! agrees within the stated spread across forward and camera runs.
//!
//! **Its size.** The forward pilot traces `1/PILOT_SHARE` of the run's paths in
//! [`PILOT_BATCHES`] batches (at least [`PILOT_MIN_PATHS`] per batch); the camera pilot traces
//! about a quarter as many camera paths (each costs ~2.5 forward paths), from every `stride`-th
//! pixel
//! ([`crate::experiment::RunPlan::camera_pixel_stride`]), and its cost is scaled to every pixel.
//! Both compare over the camera pilot's pixels. The pilot's paths are not part of the run's
//! estimate (they would make its batches unequal); its time is reported.

use std::sync::Arc;

use crate::detect::importance::ImportanceTable;
use crate::detect::{AutoChoice, Estimator, EstimatorChoice};
pub use crate::experiment::{Decisions, EstimatorDecision, ImportanceDecision};
use crate::experiment::{Experiment, RunOutput, RunPlan, Silent};
use crate::sampling::rng::mix64;
use crate::transport::windows::{AutoWindows, Importance};

/// The forward pilot traces `1/PILOT_SHARE` of the run's paths.
pub const PILOT_SHARE: u64 = 64;
/// Batches of each pilot (a standard error per pixel needs several).
pub const PILOT_BATCHES: u64 = 8;
/// Fewest paths per pilot batch.
pub const PILOT_MIN_PATHS: u64 = 2_000;
/// The three runs of the pilot of `run.importance = "auto"` trace at most `1/IMPORTANCE_PILOT_SHARE`
/// of the run's paths together ([`importance_pilot`]): [`PILOT_MIN_PATHS`] per batch would make
/// them 48,000 paths, more than a small run's (unchanged from 192,000 paths up).
pub const IMPORTANCE_PILOT_SHARE: u64 = 4;
/// Mixed into the seed for the pilot's streams, which the run's never share.
const PILOT_SEED: u64 = 0x0050_494c_4f54;
/// Mixed in besides for the pilot of `run.importance = "auto"`.
const IMPORTANCE_PILOT_SEED: u64 = 0x5757_494e;

/// What the pilots decide for a run of `exp`, as a value the run applies ([`Decisions`]; `exp`
/// itself is not changed): every `estimator = "auto"` detector's estimator, chosen by [`pilot`]
/// (its figures kept in the decision), then for `run.importance = "auto"` the importance table
/// and whether the walk follows its windows, or its windows and guided directions
/// ([`importance_pilot`]; where the experiment has no importance table nothing is decided: no
/// windows). Deterministic: every shard, merge and resume of the run decides the same.
pub fn decide(exp: &Experiment) -> Decisions {
    let estimators = pilot(exp)
        .into_iter()
        .map(|(detector, figures)| EstimatorDecision { detector, estimator: figures.chosen(), figures: Some(figures) })
        .collect();
    let mut decisions = Decisions { estimators, importance: None };
    if exp.plan.importance == Importance::Auto
        && let Some(table) = exp.decided(&decisions).importance_table()
    {
        let table = Arc::new(table);
        let figures = importance_pilot(exp, &decisions, &table);
        decisions.importance = Some(ImportanceDecision { steering: figures.choice(), figures: Some(figures), table });
    }
    decisions
}

/// The run of a pilot of `exp`, built here alone, every field said (a new one is decided for the
/// pilots too): `exp`'s scene, source, detectors and walk on the pilot's own streams (`seed`), in
/// [`PILOT_BATCHES`] batches of `paths_per_batch` paths, its camera paths from every
/// `camera_pixel_stride`-th pixel. What it estimates with (an estimator imposed on each `"auto"`
/// detector, the windows) is the [`Decisions`] it is run with.
pub fn pilot_run(exp: &Experiment, seed: u64, paths_per_batch: u64, camera_pixel_stride: usize) -> Experiment {
    let plan = &exp.plan;
    Experiment {
        name: exp.name.clone(),
        scene: exp.scene.clone(),
        source: exp.source.clone(),
        detectors: exp.detectors.clone(),
        plan: RunPlan {
            requested_samples: paths_per_batch * PILOT_BATCHES,
            batches: PILOT_BATCHES,
            paths_per_batch,
            seed,
            threads: plan.threads,
            walk: plan.walk,
            memory_budget: plan.memory_budget,
            memory_limited_by: plan.memory_limited_by,
            camera_pixel_stride,
            memory: plan.memory.clone(),
            importance: plan.importance,
            importance_trace: None,
        },
        references: exp.references.clone(),
        volume: exp.volume.clone(),
    }
}

/// The pilot of `run.importance = "auto"`: the run without the weight windows of `table`
/// ([`crate::transport::windows`]), with them, and with them and guided directions
/// ([`crate::transport::guide`]), on the same paths (`1/PILOT_SHARE` of the run's in
/// [`PILOT_BATCHES`] batches, at least [`PILOT_MIN_PATHS`] per batch, and the three together at
/// most [`IMPORTANCE_PILOT_SHARE`] of the run's), and for each the squared relative error of the
/// main output (`Σσ²/Σm²`, `m` the three pilots' mean: one reference for all) × its work in
/// collision steps (the windows' copies and roulette in it, the guide's vertices). Like the
/// estimators' pilot: counted, not timed, so the choice is the same on any threads, shard or
/// resume; the figures do not depend on the pilot's size (variance ∝ 1/paths, work ∝ paths).
///
/// The windows' and guided figures carry their table's work too ([`ImportanceTable::work`], its
/// share at the pilot's size: `C·P/N` for a table of work `C`, a pilot of `P` paths and a run of
/// `N`): over the run, error × work is `v·(w + C/N)` with the table, `v·w` without. The table is
/// made before the choice, but the figures are also what a user reads to set the key for the
/// next runs of the experiment: windows are chosen where they pay for their table.
///
/// `decided`: the decisions made before it (the estimators), which its runs apply.
pub fn importance_pilot(exp: &Experiment, decided: &Decisions, table: &Arc<ImportanceTable>) -> AutoWindows {
    let samples = exp.plan.samples();
    let most = (samples / IMPORTANCE_PILOT_SHARE / 3 / PILOT_BATCHES).max(1);
    let ppb = (samples / PILOT_SHARE / PILOT_BATCHES).max(PILOT_MIN_PATHS).min(most);
    let seed = mix64(exp.plan.seed ^ PILOT_SEED ^ IMPORTANCE_PILOT_SEED);
    let run = pilot_run(exp, seed, ppb, exp.plan.camera_pixel_stride);
    let imposed = |steering: Importance| Decisions {
        importance: Some(ImportanceDecision { steering, figures: None, table: Arc::clone(table) }),
        ..decided.clone()
    };
    let runs =
        [Importance::Off, Importance::Windows, Importance::Guided].map(|i| run.run_decided(&imposed(i), &Silent));
    let range = exp.main_output().range();
    let means = runs.each_ref().map(|o| o.estimates.mean());
    let m2: f64 = range.clone().map(|k| (means.iter().map(|m| m[k]).sum::<f64>() / 3.0).powi(2)).sum();
    let var = |o: &RunOutput| o.estimates.stderr()[range.clone()].iter().map(|s| s * s).sum::<f64>();
    let table_share = table.work * (ppb * PILOT_BATCHES) as f64 / samples.max(1) as f64;
    let figure = |o: &RunOutput, table: f64| {
        if m2 > 0.0 { var(o) / m2 * (o.stats.forward_work() + table) } else { f64::INFINITY }
    };
    let [off, windows, guided] = [figure(&runs[0], 0.0), figure(&runs[1], table_share), figure(&runs[2], table_share)];
    AutoWindows { off, windows, guided }
}

/// The pilot's figures for every `estimator = "auto"` detector of `exp`, by detector index (none
/// when there is none to decide, without a pilot run); each chooses by [`AutoChoice::chosen`].
pub fn pilot(exp: &Experiment) -> Vec<(usize, AutoChoice)> {
    let autos: Vec<usize> = (0..exp.detectors.len()).filter(|&i| undecided(exp, i)).collect();
    if autos.is_empty() {
        return Vec::new();
    }
    let ppb = (exp.plan.samples() / PILOT_SHARE / PILOT_BATCHES).max(PILOT_MIN_PATHS);
    // The camera pilot traces about a quarter as many camera paths as the forward pilot traces
    // paths, one per traced pixel and batch.
    let pixels = autos.iter().map(|&i| pixels_of(exp, i)).sum::<usize>() as u64;
    let stride = (4 * pixels).div_ceil(ppb).max(1) as usize;
    let run = pilot_run(exp, mix64(exp.plan.seed ^ PILOT_SEED), ppb, stride);
    let imposed = |estimator: Estimator| Decisions {
        estimators: autos.iter().map(|&detector| EstimatorDecision { detector, estimator, figures: None }).collect(),
        importance: None,
    };
    let (on_forward, on_camera) = (imposed(Estimator::Forward), imposed(Estimator::Camera));
    let (forward, camera) = (run.run_decided(&on_forward, &Silent), run.run_decided(&on_camera, &Silent));
    // Work per path of each kind (forward paths of each pilot, camera paths), in steps.
    let forward_paths = (ppb * PILOT_BATCHES) as f64;
    let camera_paths = (run.decided(&on_camera).camera_paths_per_batch() * PILOT_BATCHES) as f64;
    let per_forward = forward.stats.forward_work() / forward_paths;
    let per_forward_beside = camera.stats.forward_work() / forward_paths;
    let per_camera = camera.stats.camera_work() / camera_paths;
    let run_ppb = exp.plan.paths_per_batch;
    let figures = |i: usize| {
        let (vf, vc) = relative_variances(i, stride, &forward, &camera);
        // Relative variance × work of a run of either estimator, at any number of paths: per
        // forward path (forward); per camera path per pixel, with the forward paths traced
        // beside the camera paths in the run's proportion (camera).
        let (pilot_spp, run_spp) = (per_pixel(exp, i, ppb), per_pixel(exp, i, run_ppb));
        let forward_figure = vf * forward_paths * per_forward;
        let camera_figure = vc
            * (pilot_spp * PILOT_BATCHES) as f64
            * (per_forward_beside * run_ppb as f64 / run_spp as f64 + per_camera * pixels_of(exp, i) as f64);
        (i, AutoChoice { forward: forward_figure, camera: camera_figure })
    };
    autos.iter().map(|&i| figures(i)).collect()
}

/// Whether detector `i` is configured `estimator = "auto"`.
fn undecided(exp: &Experiment, i: usize) -> bool {
    exp.detectors[i].surface().is_some_and(|s| s.choice == EstimatorChoice::Auto)
}

fn pixels_of(exp: &Experiment, i: usize) -> usize {
    exp.detectors[i].surface().and_then(|s| s.image()).map_or(0, |im| im.nx * im.ny)
}

/// Camera paths per pixel of detector `i` in a batch of `ppb` paths (as
/// [`crate::transport::CameraTarget::paths_per_pixel`]).
fn per_pixel(exp: &Experiment, i: usize, ppb: u64) -> u64 {
    ppb.div_ceil(pixels_of(exp, i).max(1) as u64).max(1)
}

/// The squared relative errors `Σσ²/Σm²` of detector `i`'s main image (M0+ of an LDH camera,
/// else the intensity image) by the forward and the camera pilot, over the pixels the camera
/// pilot traced (every `stride`-th); infinite (neither chosen for it) when neither reached any.
fn relative_variances(i: usize, stride: usize, f: &RunOutput, c: &RunOutput) -> (f64, f64) {
    // In the tally's pixel order, which the camera pilot's stride counts in.
    let image = |o: &RunOutput| {
        let (mean, stderr) = (o.estimates.mean(), o.estimates.stderr());
        let lay = &o.layout.detectors[i];
        let start = lay.ldh().map(|l| l.m0_plus).or(lay.image())?;
        let out = o.layout.registry.at(start);
        Some((mean[out.range()].to_vec(), stderr[out.range()].to_vec()))
    };
    let (Some((mf, sf)), Some((mc, sc))) = (image(f), image(c)) else { return (f64::INFINITY, f64::INFINITY) };
    let (mut m2, mut vf, mut vc) = (0.0, 0.0, 0.0);
    for p in (0..mf.len()).step_by(stride) {
        m2 += (0.5 * (mf[p] + mc[p])).powi(2);
        vf += sf[p] * sf[p];
        vc += sc[p] * sc[p];
    }
    if m2 > 0.0 { (vf / m2, vc / m2) } else { (f64::INFINITY, f64::INFINITY) }
}
