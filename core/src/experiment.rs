//! An experiment: the resolved scene, source and detectors, and the plan to run them.
//!
//! Work is split into `batches` equal batches of paths. Path `i` of batch `b` draws from the
//! stream `(seed, Path, b, i)`; batches run in parallel on a rayon pool and are folded into the
//! statistics in batch order, so the output does not depend on the number of threads.
//! The random walk is compiled once per scene kind ([`Features`]); each batch hands its paths to
//! the one dispatch there.

use std::borrow::Cow;
use std::sync::Arc;

use crate::detect::importance::ImportanceTable;
use crate::detect::volume::{VolumeGrid, VolumeTally};
use crate::detect::{
    AutoChoice, BeatModel, Detector, DetectorKind, EstimatorChoice, RecordedLine, Recorder, TallyLayout,
};
use crate::error::Result;
use crate::medium::Scene;
use crate::output::Output;
use crate::retrieval::{FmcwEstimate, RetrievalError, fmcw_estimates};
use crate::sampling::{Purpose, StreamKey};
use crate::source::{Pointing, Source};
use crate::stats::{BatchAccumulator, RunStats};
use crate::transport::windows::{AutoWindows, Importance, Windows};
use crate::transport::{
    CameraTarget, ControlVariate, Features, NeeTarget, WalkContext, WalkSettings, control_variate_obstacle,
};

/// How many paths and how they are split.
#[derive(Debug, Clone, PartialEq)]
pub struct RunPlan {
    pub requested_samples: u64,
    pub batches: u64,
    pub paths_per_batch: u64,
    pub seed: u64,
    /// Worker threads; 0 = all available cores.
    pub threads: usize,
    pub walk: WalkSettings,
    /// Largest [`Experiment::memory_estimate`] accepted, bytes (`run.memory_budget_gib`, or less
    /// under a limit of the process: `memory_limited_by`).
    pub memory_budget: u64,
    /// The process's memory limit that lowered `memory_budget` below `run.memory_budget_gib`
    /// ([`crate::sys::memory_limit`]), if one did.
    pub memory_limited_by: Option<&'static str>,
    /// Camera paths are traced from every `camera_pixel_stride`-th pixel only: 1, but in the
    /// pilot of `estimator = "auto"`'s own run ([`crate::pilot::pilot_run`]).
    pub camera_pixel_stride: usize,
    /// What resolving counted against the budget besides the tallies (the media of the layers
    /// and regions, voxel grids, speckle records), in the order it was counted.
    pub memory: Vec<MemoryBlock>,
    /// `run.importance`: the importance table of the main output's detector, and the weight
    /// windows it gives ([`Experiment::importance_table`], [`crate::transport::windows`]); what
    /// `"auto"` chose is a [`Decisions`] value, not written here.
    pub importance: Importance,
    /// In the importance table's pilot's own run ([`Experiment::importance_pilot_run`]): the
    /// detector whose states' values it tallies ([`crate::detect::importance`]); `None` in any
    /// other run.
    pub importance_trace: Option<usize>,
}

/// What the pilots decided for a run of an experiment ([`crate::pilot::decide`]), as a value:
/// the run applies it when it builds its walk context ([`Experiment::decided`], and the weight
/// windows of [`Decisions::steering`]); the experiment stays as configured. Every shard, merge
/// and resume of a run decides again, the same (the pilots count work, never time), and a run's
/// output keeps the decisions it ran with ([`RunOutput::decisions`]) for the manifest. The
/// default decides nothing: an `estimator = "auto"` detector is estimated forward, `run.importance
/// = "auto"` follows no windows, `"windows"` and `"guided"` make their table when the run starts.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Decisions {
    /// The estimator of each detector decided for the run, in detector order.
    pub estimators: Vec<EstimatorDecision>,
    /// The importance table made before the run and what the forward walk does with it.
    pub importance: Option<ImportanceDecision>,
}

/// The estimator a run uses for a surface detector configured `estimator = "auto"`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimatorDecision {
    /// The detector's index.
    pub detector: usize,
    pub estimator: crate::detect::Estimator,
    /// The pilot's figures that chose it ([`AutoChoice::chosen`]); `None` in the pilot's own
    /// runs, which impose each estimator in turn.
    pub figures: Option<AutoChoice>,
}

/// The importance table of a run and what its forward walk does with it.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportanceDecision {
    /// [`Importance::Off`] (the table only written), [`Importance::Windows`] or
    /// [`Importance::Guided`].
    pub steering: Importance,
    /// The figures of `run.importance = "auto"`'s pilot that chose `steering`
    /// ([`AutoWindows::choice`]); `None` in that pilot's own runs, which impose each in turn.
    pub figures: Option<AutoWindows>,
    pub table: Arc<ImportanceTable>,
}

impl Decisions {
    /// The decision on detector `i`'s estimator, if one was made.
    pub fn estimator(&self, i: usize) -> Option<&EstimatorDecision> {
        self.estimators.iter().find(|d| d.detector == i)
    }

    /// What the forward walk of a run of `plan` does with the importance table: the decision's,
    /// else `run.importance = "windows"` or `"guided"` as configured (their table made when the
    /// run starts); an undecided `"auto"` follows no windows.
    pub fn steering(&self, plan: &RunPlan) -> Importance {
        match (&self.importance, plan.importance) {
            (Some(d), _) => d.steering,
            (None, i @ (Importance::Windows | Importance::Guided)) => i,
            (None, Importance::Off | Importance::Table | Importance::Auto) => Importance::Off,
        }
    }
}

/// A block of memory an experiment holds, as counted against `run.memory_budget_gib`.
#[derive(Debug, Clone, PartialEq)]
pub struct MemoryBlock {
    /// What it is, with the key that asks for it (e.g. "media of layers[0] (100 sublayers)").
    pub what: String,
    pub bytes: u64,
}

impl RunPlan {
    /// Paths actually traced: the request rounded up to a whole number per batch.
    pub fn samples(&self) -> u64 {
        self.batches * self.paths_per_batch
    }

    /// Set the total number of paths (rounded up to equal batches).
    pub fn set_samples(&mut self, samples: u64) {
        self.requested_samples = samples;
        self.paths_per_batch = samples.div_ceil(self.batches).max(1);
    }

    /// The thread count that will be used.
    pub fn effective_threads(&self) -> usize {
        if self.threads == 0 { std::thread::available_parallelism().map_or(1, |n| n.get()) } else { self.threads }
    }
}

/// A validated experiment, ready to run.
#[derive(Debug, Clone, PartialEq)]
pub struct Experiment {
    pub name: String,
    pub scene: Scene,
    pub source: Source,
    pub detectors: Vec<Detector>,
    pub plan: RunPlan,
    /// Analytic values of named outputs (`[reference]`), for `ohd converge`, in the tally's
    /// convention.
    pub references: Vec<(String, Vec<f64>)>,
    /// The voxel grid of `[volume]` (`None`: no volume tally; the walk is compiled without it).
    pub volume: Option<VolumeGrid>,
}

/// A stopping rule for [`Experiment::run_until`]: run whole rounds of the configured batches
/// until the main output's estimated relative error is at most `relative_error`, or the run
/// would exceed `max_samples` paths.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    pub output: Output,
    pub relative_error: f64,
    pub max_samples: u64,
}

/// How a run with a [`Target`] ended.
#[derive(Debug, Clone, PartialEq)]
pub struct TargetOutcome {
    pub output: String,
    pub target: f64,
    /// The estimated relative error reached.
    pub reached: f64,
    pub met: bool,
    /// Rounds of the configured batches run.
    pub rounds: u64,
    /// The cap on paths (whole rounds).
    pub max_samples: u64,
}

/// `f` run on a pool of `threads` threads (at least one) — post-processing in parallel with the
/// run's thread count — or on the global pool if no pool can be made.
pub fn on_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    match rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build() {
        Ok(pool) => pool.install(f),
        Err(_) => f(),
    }
}

/// How many rounds a run with `rounds` done at relative error `err` needs to reach `target`
/// (errors fall as `1/√paths`), at least one more, at most `max_rounds`.
/// Without an error estimate yet (a zero output) the run doubles.
pub fn rounds_needed(rounds: u64, err: f64, target: f64, max_rounds: u64) -> u64 {
    let want = if err.is_finite() { (rounds as f64 * (err / target).powi(2)).ceil() } else { 2.0 * rounds as f64 };
    (want.min(max_rounds as f64) as u64).clamp(rounds + 1, max_rounds.max(rounds + 1))
}

/// Progress reports from a running experiment (a cold seam: called every few thousand paths).
pub trait Progress: Sync {
    fn advance(&self, paths: u64);
    /// The run's total number of paths changed (a run to a target error extends itself).
    fn set_total(&self, _paths: u64) {}
    /// The estimated relative error of the main output, after each batch is folded in.
    fn error(&self, _relative: f64) {}
    /// Whether the caller wants the run stopped (the Python package on a second Ctrl-C): checked as each
    /// batch is handed over, which then fails with [`crate::error::Error::Cancelled`], and every
    /// [`PROGRESS_EVERY`] paths inside a batch, which then ends early (its result is discarded).
    fn cancelled(&self) -> bool {
        false
    }
    /// Whether the caller wants the run to end early and keep its work (the first Ctrl-C of
    /// `ohd run`, and in the Python package): no batch starts after it is seen, the batches in
    /// flight finish and are folded, and the run ends as [`RunOutput::interrupted`].
    fn stopping(&self) -> bool {
        false
    }
}

/// No progress reporting.
pub struct Silent;

impl Progress for Silent {
    fn advance(&self, _: u64) {}
}

/// What a run produced: the per-estimate batch statistics and the counters.
#[derive(Debug, Clone)]
pub struct RunOutput {
    pub layout: TallyLayout,
    pub beat: BeatModel,
    pub estimates: BatchAccumulator,
    pub stats: RunStats,
    pub threads: usize,
    pub wall_seconds: f64,
    /// Paths detected in LDH regions of interest, in batch order (only when speckle is asked for;
    /// the speckle is synthesised from them after the run, [`crate::post::speckle_of`]).
    pub lines: Vec<RecordedLine>,
    /// Batches run (more than the plan's with a target error) of `paths_per_batch` paths each.
    pub batches: u64,
    pub paths_per_batch: u64,
    /// The main output's name and estimated relative error at the end.
    pub main_output: (String, f64),
    /// How a run to a target error ended.
    pub target: Option<TargetOutcome>,
    /// The importance table its weight windows followed (`run.importance = "windows"`; `None`
    /// otherwise, and after a merge of shards: the writer computes it again).
    pub importance: Option<ImportanceTable>,
    /// The pilots' decisions it ran with (for the manifest and the report).
    pub decisions: Decisions,
    /// `Some(planned batches)` when the run ended early because its caller asked
    /// ([`Progress::stopping`]): its estimates and errors are those of the `batches` done, and
    /// [`final_state`](Self::final_state) continues it to the plan.
    pub interrupted: Option<u64>,
}

impl RunOutput {
    /// The paths the run traced (its batches done, of `paths_per_batch` each).
    pub fn paths(&self) -> u64 {
        self.estimates.batches() as u64 * self.paths_per_batch
    }

    /// The tail checks of the cameras' regions ([`crate::detect::tail`]), by the first slot of
    /// the image each one pools.
    pub fn tail_checks(&self) -> std::collections::BTreeMap<usize, crate::stats::TailCheck> {
        let paths = self.paths() as f64;
        let mean = self.estimates.mean();
        self.layout
            .detectors
            .iter()
            .filter_map(|d| d.tail.as_ref())
            .flat_map(|t| {
                t.images.iter().enumerate().filter_map(move |(c, &image)| Some((image?, t.check(c, mean, paths))))
            })
            .collect()
    }

    /// The state of this run, as a checkpoint holds it: resumed, it finishes at once with this
    /// output, or an interrupted run goes on to its planned batches.
    pub fn final_state(&self) -> RunState {
        RunState {
            estimates: self.estimates.clone(),
            stats: self.stats,
            lines: self.lines.clone(),
            next: self.batches,
            end: self.interrupted.unwrap_or(self.batches).max(self.batches),
            err: self.main_output.1,
            elapsed: self.wall_seconds,
        }
    }

    /// Paths traced.
    pub fn samples(&self) -> u64 {
        self.batches * self.paths_per_batch
    }

    /// The estimated spectrum (power per bin, without the out-of-range tallies) of detector `i`,
    /// chirp `chirp` (0 = up-chirp or single frequency, 1 = down-chirp) and channel `channel` (0 =
    /// total, then the splits; see [`SpectrumSpec::channels`](crate::detect::SpectrumSpec::channels)).
    /// `None` if the detector has no spectrum or there is no such chirp or channel.
    pub fn spectrum(&self, i: usize, chirp: usize, channel: usize) -> Option<&[f64]> {
        let lay = self.layout.detectors.get(i)?.spectrum()?;
        if chirp >= self.beat.chirps() || channel >= lay.channels {
            return None;
        }
        let start = lay.start + (chirp * lay.channels + channel) * lay.stride;
        // The bins of the row, without its two out-of-range tallies.
        Some(&self.estimates.mean()[start..start + lay.stride - 2])
    }
}

/// Paths between progress reports (and checks for cancellation) of a batch.
const PROGRESS_EVERY: u64 = crate::transport::PATHS_PER_TICK;

/// A run at a batch boundary: everything needed to continue it to the same result.
#[derive(Debug, Clone)]
pub struct RunState {
    pub estimates: BatchAccumulator,
    pub stats: RunStats,
    pub lines: Vec<RecordedLine>,
    /// The next batch to run, and the end of the batches planned so far (a run to a target
    /// error plans more).
    pub next: u64,
    pub end: u64,
    /// The main output's estimated relative error after batch `next − 1`.
    pub err: f64,
    /// Wall seconds spent on the run before this state was (re)loaded.
    pub elapsed: f64,
}

/// Where a run saves its state from time to time (atomically), to be resumed after a crash.
pub trait Checkpoint: Sync {
    /// Whether a save is due now (called after each batch is folded in).
    fn due(&self) -> bool;
    /// Save `state`; an error stops the run.
    fn save(&self, state: &RunState) -> Result<()>;
}

/// Takes each batch's tally sums, counters and recorded lines, in batch order
/// ([`Experiment::run_batches`]).
pub type BatchSink<'a> = dyn FnMut(&[f64], RunStats, Vec<RecordedLine>) -> Result<()> + 'a;

/// One batch's tally sums, counters and recorded lines.
type BatchResult = (Tallies, RunStats, Vec<RecordedLine>);

/// A batch's tally sums with a cache line of padding on each side. Batches running on different
/// threads add to their sums at every detection; two small vectors sharing a cache line would
/// make the cores fight over it (false sharing). Measured on the vdH slab (five scalar tallies,
/// 40 bytes a batch), 2 threads against 1: 1.71× unpadded, as the allocator happened to place
/// them, against 1.93× padded (`validation/scaling/run.py`, medians of 5 interleaved runs).
struct Tallies(Vec<f64>);

/// `f64`s in a cache line (64 bytes).
const LINE: usize = 8;

impl Tallies {
    fn new(len: usize) -> Self {
        Tallies(vec![0.0; len + 2 * LINE])
    }

    fn sums(&self) -> &[f64] {
        &self.0[LINE..self.0.len() - LINE]
    }

    fn sums_mut(&mut self) -> &mut [f64] {
        let n = self.0.len();
        &mut self.0[LINE..n - LINE]
    }
}

/// What a batch's walks follow beyond the experiment: the weight windows and the light field,
/// both made when the run starts.
#[derive(Clone, Copy)]
struct Steer<'a> {
    windows: Option<&'a Windows>,
    field: Option<&'a crate::transport::field::FieldTable>,
}

/// Runs batches on a thread pool and hands their results over in batch order, reusing their
/// tally vectors: a large camera's (O(pixels × bins)) would otherwise be fresh pages, faulted in
/// and zeroed by the kernel, every batch.
struct BatchRunner<'a> {
    exp: &'a Experiment,
    /// `None` when a pool cannot be built (no threads available): the batches then run on this
    /// thread, with the same numbers.
    pool: Option<rayon::ThreadPool>,
    layout: TallyLayout,
    beat: BeatModel,
    /// Batches run but not yet handed over, at most: enough to keep every thread busy while one
    /// batch runs long, few enough to bound memory.
    in_flight: u64,
    spare: Vec<Tallies>,
    /// The importance table the weight windows follow (the decision's, or from a pilot run
    /// here for `run.importance = "windows"`), and the windows.
    table: Option<ImportanceTable>,
    windows: Option<Windows>,
    /// The layered twin's light field camera paths connect to (`[detectors.footprints]
    /// light_field`), made when the run starts.
    field: Option<crate::transport::field::FieldTable>,
}

impl<'a> BatchRunner<'a> {
    /// The runner of `exp`, with `decisions` applied ([`Experiment::decided`]) to it, and its
    /// weight windows.
    fn new(exp: &'a Experiment, decisions: &Decisions) -> Self {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(exp.plan.effective_threads()).build().ok();
        let layout = exp.tally_layout();
        let (beat, in_flight) = (exp.beat_model(), exp.batches_in_flight());
        let steering = decisions.steering(&exp.plan);
        let table = match &decisions.importance {
            _ if steering == Importance::Off => None,
            Some(d) => Some(d.table.as_ref().clone()),
            None => exp.importance_table(),
        };
        let windows = table.as_ref().map(|t| {
            let w = Windows::new(t.grid.clone(), &t.value, t.response);
            if steering == Importance::Guided { w.guided(&exp.scene, &t.value) } else { w }
        });
        let field = exp.field_paths().map(|paths| {
            let build = || {
                crate::transport::field_pass::build(
                    &exp.scene,
                    &exp.source,
                    &exp.plan.walk,
                    exp.field_reach(),
                    paths,
                    exp.plan.seed,
                )
            };
            match &pool {
                Some(p) => p.install(build),
                None => build(),
            }
        });
        BatchRunner { exp, pool, layout, beat, in_flight, spare: Vec::new(), table, windows, field }
    }

    /// Run the batches `range` and give each result to `sink` in batch order, stopping at its
    /// first error. A pipeline, not rounds: as each batch is handed over the next one starts, so
    /// no thread waits for the slowest batch of a group (this thread only receives and folds).
    fn run(&mut self, range: std::ops::Range<u64>, progress: &dyn Progress, sink: &mut BatchSink) -> Result<()> {
        let BatchRunner { exp, pool, layout, beat, in_flight, spare, windows, field, .. } = self;
        let (exp, layout, beat, in_flight) = (*exp, &*layout, *beat, *in_flight);
        let steer = Steer { windows: windows.as_ref(), field: field.as_ref() };
        let len = layout.tallies();
        let Some(pool) = pool else {
            for b in range {
                let sums = spare.pop().unwrap_or_else(|| Tallies::new(len));
                let (sums, s, l) = exp.run_batch(b, sums, layout, beat, steer, progress);
                if progress.cancelled() {
                    return Err(crate::error::Error::Cancelled);
                }
                sink(sums.sums(), s, l)?;
                spare.push(sums);
                if progress.stopping() {
                    break;
                }
            }
            return Ok(());
        };
        // Every batch started sends exactly one message, its result or its panic (re-raised
        // here, as rayon would): this thread never waits for a batch that is gone.
        type Sent = std::thread::Result<BatchResult>;
        let (tx, rx) = std::sync::mpsc::channel::<(u64, Sent)>();
        pool.in_place_scope(|scope| {
            let spawn = |b: u64, sums: Tallies| {
                let tx = tx.clone();
                scope.spawn(move |_| {
                    let run = std::panic::AssertUnwindSafe(|| exp.run_batch(b, sums, layout, beat, steer, progress));
                    // The receiver outlives the scope, so the send cannot fail.
                    let _ = tx.send((b, std::panic::catch_unwind(run)));
                });
            };
            let (mut started, mut handed) = (range.start, range.start);
            while started < range.end && started - handed < in_flight {
                spawn(started, spare.pop().unwrap_or_else(|| Tallies::new(len)));
                started += 1;
            }
            // Finished batches waiting for an earlier one, by index.
            let mut waiting = std::collections::BTreeMap::new();
            // Once the caller asks to stop, nothing more starts; every batch started is handed over.
            let mut stop = false;
            while handed < started {
                let Ok((b, sent)) = rx.recv() else {
                    unreachable!("a sender is held here and every batch started sends once");
                };
                waiting.insert(b, sent.unwrap_or_else(|panic| std::panic::resume_unwind(panic)));
                while let Some((sums, s, l)) = waiting.remove(&handed) {
                    // On an error the batches already started finish (the scope waits for them)
                    // and nothing more starts. Cancellation is sticky, so a batch cut short by it
                    // (see `Progress::cancelled`) is never handed over.
                    if progress.cancelled() {
                        return Err(crate::error::Error::Cancelled);
                    }
                    sink(sums.sums(), s, l)?;
                    handed += 1;
                    stop = stop || progress.stopping();
                    if started < range.end && !stop {
                        spawn(started, sums);
                        started += 1;
                    } else {
                        spare.push(sums);
                    }
                }
            }
            Ok(())
        })
    }
}

impl Experiment {
    /// The LDH cameras' M0+ images (by their first tally slot in `layout`) with the speckle
    /// contrast of one window of their set-up over their band and its frames
    /// ([`crate::output::SpeckleScale`]; M0−'s speckle is on the scale of M0+, not of itself).
    pub fn m0_speckle<'a>(&'a self, layout: &'a TallyLayout) -> impl Iterator<Item = (usize, (f64, usize))> + 'a {
        self.detectors.iter().zip(&layout.detectors).filter_map(|(d, lay)| {
            let (spec, ll) = d.ldh().zip(lay.ldh())?;
            Some((ll.m0_plus, (spec.stft.flat_band_contrast(spec.band)?, spec.stft.samples())))
        })
    }

    /// The mask of the regions' footprints over the pixels of the image-shaped output `o` of a
    /// camera, in the tally's order ([`crate::detect::image::region_mask`]); `None` for other
    /// outputs and where no region is seen.
    pub fn region_mask_of(&self, o: &Output) -> Option<Vec<bool>> {
        let im = o.detector.and_then(|d| self.detectors[d].surface()).and_then(|s| s.image())?;
        (o.slots.len == im.nx * im.ny).then(|| crate::detect::image::region_mask(&self.scene, im)).flatten()
    }

    /// Every named output of this experiment ([`crate::output::Registry::named`]): the five
    /// scalar tallies, then per detector its power, its total spectrum (per chirp), image, LDH
    /// M0± images and lidar range–Doppler spectra.
    pub fn outputs(&self) -> Vec<Output> {
        self.output_layout().registry.named().cloned().collect()
    }

    /// The run's main output ([`TallyLayout::main`]), whose error `ohd run --target-error`
    /// controls and the progress bar shows.
    pub fn main_output(&self) -> Output {
        self.output_layout().main().clone()
    }

    /// The same experiment with the beam (and the axes of the lidar receiver and of monostatic
    /// detectors) along `p`.
    pub fn pointed(&self, p: &Pointing) -> Experiment {
        let mut e = self.clone();
        e.source = self.source.pointed(p.direction);
        for d in &mut e.detectors {
            match &mut d.kind {
                DetectorKind::Lidar(l) => l.axis = e.source.direction,
                DetectorKind::Surface(s) if s.monostatic => s.axis = -e.source.direction,
                DetectorKind::Surface(_) => {}
            }
        }
        e
    }

    pub fn beat_model(&self) -> BeatModel {
        BeatModel::new(self.source.wavelength, self.source.chirp.map(|c| c.slope()))
    }

    /// The layout of the run's tallies and outputs, with the control variate's kernels and their
    /// FFT plans and footprint transforms ([`crate::detect::twin`]) where it applies: what a run
    /// needs.
    pub fn tally_layout(&self) -> TallyLayout {
        let mut layout = self.output_layout();
        // Outside the tally vector: the layout of the outputs is the same with or without it.
        if self.control_variate()
            && let Some(fp) = self.source.footprint()
        {
            layout.declare_twins(&self.detectors, fp);
        }
        layout
    }

    /// The layout of the tallies and outputs alone, without the control variate's kernels: what
    /// counting, describing and reading the outputs need. (The kernels' FFT buffers are made with
    /// them: a 2048² camera's took 207 MB to estimate its memory, and under `ulimit -v` aborted
    /// the process before the budget was checked.)
    pub fn output_layout(&self) -> TallyLayout {
        let mut layout = TallyLayout::new(&self.detectors, &self.beat_model());
        // After every detector's block: a volume tally moves no other output.
        if let Some(v) = &self.volume {
            layout.volume = Some(v.declare(&mut layout.registry));
        }
        // Last, so that a run without lateral bounds lays out what it did before.
        if self.scene.lateral.is_some() {
            layout.declare_lateral();
        }
        // After them all: the regions' tail checks move no output.
        layout.declare_tails(&self.detectors, |im| crate::detect::image::region_mask(&self.scene, im));
        if let Some(d) = self.plan.importance_trace {
            let grid = self.importance_grid(d);
            layout.importance =
                Some(crate::detect::importance::ImportanceLayout::declare(grid, d, &mut layout.registry));
        }
        layout
    }

    /// Whether the forward-estimated cameras get the layered control variate
    /// (`run.control_variate`, [`crate::detect::twin`]).
    pub fn control_variate(&self) -> bool {
        self.plan.walk.control_variate != ControlVariate::Off
            && control_variate_obstacle(&self.scene, &self.source, &self.detectors).is_none()
    }

    /// Why this experiment has no importance table (`None`: it has one,
    /// [`importance_table`](Self::importance_table)): it needs a main output of a detector scored
    /// by forward paths: a surface detector with the forward estimator (not a lidar receiver).
    pub fn importance_obstacle(&self) -> Option<String> {
        if self.scene.cycle.is_some() {
            return Some("the scene's flows pulse ([cardiac]): split copies do not carry the harmonics yet".into());
        }
        let main = self.main_output();
        let Some(d) = main.detector else {
            return Some(format!("the main output `{}` is not a detector's", main.name));
        };
        match &self.detectors[d].kind {
            DetectorKind::Surface(s) if s.estimator() == crate::detect::Estimator::Camera => Some(format!(
                "detector `{}` is estimated from the camera's side (the table is of forward paths)",
                self.detectors[d].name
            )),
            // Measured (validation/README.md, issue 36): the plain walk's own batch errors of a
            // lidar's multiply scattered gates are not reliable (two seeds of a fog differ by
            // 5–6σ), so windows there cannot be shown to agree with it, and on wind_rainy they
            // act on the 2–4 % of each gate's light that is not single scattering only.
            DetectorKind::Lidar(_) => Some(format!(
                "detector `{}` is a lidar receiver: weight windows on its multiply scattered light are not validated",
                self.detectors[d].name
            )),
            _ => None,
        }
    }

    /// The bins of detector `d`'s importance table: the stack's, and lateral ones if the beam
    /// enters the stack outside the area of a surface detector.
    pub fn importance_grid(&self, d: usize) -> crate::detect::importance::ImportanceGrid {
        use crate::detect::importance::{ImportanceGrid, Lateral};
        let lateral = match (self.detectors[d].surface(), self.source.footprint()) {
            (Some(s), Some(fp)) => Lateral::new(s.area, fp.center),
            _ => None,
        };
        ImportanceGrid::new(&self.scene, lateral)
    }

    /// The run of the importance table's pilot for detector `detector`, built here alone: every
    /// field said, so that a new one is decided for the pilot too. The detector alone, its power
    /// alone (the light it receives), scored as the run scores it, through the scene without its
    /// regions (the layered stack), on streams of its own, without the control variate, launches
    /// near the regions, a volume tally or windows, tallying its states' values
    /// ([`RunPlan::importance_trace`]).
    pub fn importance_pilot_run(&self, detector: usize) -> Experiment {
        use crate::detect::importance::{IMPORTANCE_SEED, PILOT_BATCHES, pilot_paths};
        let mut d = self.detectors[detector].clone();
        if let DetectorKind::Surface(s) = &mut d.kind {
            s.parts.clear();
        }
        let (plan, walk) = (&self.plan, &self.plan.walk);
        Experiment {
            name: self.name.clone(),
            scene: if self.scene.regions.is_empty() { self.scene.clone() } else { self.scene.layered_twin() },
            source: self.source.clone(),
            detectors: vec![d],
            plan: RunPlan {
                requested_samples: plan.requested_samples,
                batches: PILOT_BATCHES,
                paths_per_batch: pilot_paths(plan.samples()) / PILOT_BATCHES,
                seed: crate::sampling::rng::mix64(plan.seed ^ IMPORTANCE_SEED),
                threads: plan.threads,
                walk: WalkSettings {
                    tracking: walk.tracking,
                    roulette_threshold: walk.roulette_threshold,
                    roulette_survival: walk.roulette_survival,
                    max_events: walk.max_events,
                    gate: walk.gate,
                    reflections: walk.reflections,
                    control_variate: ControlVariate::Off,
                    launches: None,
                },
                memory_budget: plan.memory_budget,
                memory_limited_by: plan.memory_limited_by,
                camera_pixel_stride: plan.camera_pixel_stride,
                memory: plan.memory.clone(),
                importance: Importance::Off,
                importance_trace: Some(0),
            },
            references: Vec::new(),
            volume: None,
        }
    }

    /// This experiment as a run with `decisions` runs it: each detector whose estimator was
    /// decided estimated by it (the configured `"auto"` stays in `self` and in the decision);
    /// `self` where no estimator was decided. The one place a decision reaches the detectors.
    pub fn decided(&self, decisions: &Decisions) -> Cow<'_, Experiment> {
        if decisions.estimators.is_empty() {
            return Cow::Borrowed(self);
        }
        let mut exp = self.clone();
        for d in &decisions.estimators {
            if let DetectorKind::Surface(s) = &mut exp.detectors[d.detector].kind {
                s.choice = match d.estimator {
                    crate::detect::Estimator::Forward => EstimatorChoice::Forward,
                    crate::detect::Estimator::Camera => EstimatorChoice::Camera,
                    crate::detect::Estimator::Footprints => EstimatorChoice::Footprints,
                };
            }
        }
        Cow::Owned(exp)
    }

    /// The importance table of the main output's detector ([`crate::detect::importance`]; `None`
    /// where [`importance_obstacle`](Self::importance_obstacle) finds one), from a pilot of
    /// [`pilot_paths`](crate::detect::importance::pilot_paths) paths on its own streams.
    pub fn importance_table(&self) -> Option<ImportanceTable> {
        if self.importance_obstacle().is_some() {
            return None;
        }
        let detector = self.main_output().detector?;
        let start = std::time::Instant::now();
        let out = self.importance_pilot_run(detector).run(&Silent);
        let lay = out.layout.importance.as_ref().expect("the pilot lays out its sums");
        let mean = out.estimates.mean();
        let paths = (out.estimates.batches() as u64 * out.paths_per_batch) as f64;
        let bins = lay.grid.len();
        let (mut value, mut states, mut relative_error) =
            (vec![f64::NAN; bins], vec![0; bins], vec![f64::INFINITY; bins]);
        for b in 0..bins {
            let at = lay.start + crate::detect::importance::SLOTS * b;
            let (sum, sum2, count) = (mean[at], mean[at + 1], mean[at + 2]);
            states[b] = (count * paths).round() as u64;
            if count > 0.0 {
                let m = sum / count;
                value[b] = m;
                // The σ of the mean of the bin's `n` values, over it.
                let n = count * paths;
                if n >= 2.0 && m > 0.0 {
                    let var = ((sum2 / count - m * m).max(0.0)) / (n - 1.0);
                    relative_error[b] = var.sqrt() / m;
                }
            }
        }
        Some(ImportanceTable {
            grid: lay.grid.clone(),
            detector,
            value,
            states,
            relative_error,
            response: mean[out.layout.detectors[0].power],
            paths: paths as u64,
            seconds: start.elapsed().as_secs_f64(),
            work: out.stats.forward_work(),
        })
    }

    /// Whether the walk needs the Doppler term (something moves).
    pub fn needs_doppler(&self) -> bool {
        self.scene.is_moving()
    }

    /// Whether the walk needs the optical path length (a chirp, range gates, or a time axis).
    pub fn needs_length(&self) -> bool {
        self.source.chirp.is_some()
            || self.detectors.iter().any(|d| d.lidar().is_some() || d.surface().is_some_and(|s| s.time().is_some()))
            || self.plan.walk.gate.is_some()
            || self.volume.as_ref().is_some_and(|v| v.time.is_some())
    }

    /// The detectors scored by next-event estimation.
    pub fn next_event_targets(&self) -> Vec<NeeTarget> {
        self.detectors
            .iter()
            .enumerate()
            .filter(|(_, d)| d.next_event())
            .map(|(i, d)| match &d.kind {
                DetectorKind::Lidar(l) => NeeTarget::receiver(i, l.position, l.aperture_radius, l.axis, l.cos_fov),
                DetectorKind::Surface(s) => NeeTarget::new(i, s.axis, s.cos_acceptance),
            })
            .collect()
    }

    /// The detectors scored by camera paths ([`crate::transport::camera`]).
    pub fn camera_targets(&self) -> Vec<CameraTarget> {
        self.detectors
            .iter()
            .enumerate()
            .filter_map(|(i, d)| {
                let s = d.surface()?;
                let im = *s.image()?;
                (s.estimator() != crate::detect::Estimator::Forward).then(|| CameraTarget {
                    include_specular: s.include_specular,
                    stride: self.plan.camera_pixel_stride.max(1),
                    ..CameraTarget::new(i, im, s.area, s.distance, s.axis, s.cos_acceptance)
                })
            })
            .collect()
    }

    /// Camera paths traced per batch (all camera-estimated detectors together).
    pub fn camera_paths_per_batch(&self) -> u64 {
        let ppb = self.plan.paths_per_batch;
        self.camera_targets()
            .iter()
            .map(|c| self.camera_paths_per_pixel(c, ppb) * self.camera_pixels(c).len() as u64)
            .sum()
    }

    /// The pixels camera paths leave from for `cam`: every `stride`-th of its image, or of its
    /// camera pixels with `estimator = "footprints"` ([`crate::detect::image::Footprints`]).
    pub fn camera_pixels(&self, cam: &CameraTarget) -> Vec<usize> {
        match self.footprints_of(cam) {
            Some(f) => f.pixels.iter().map(|&p| p as usize).step_by(cam.stride).collect(),
            None => (0..cam.pixels()).step_by(cam.stride).collect(),
        }
    }

    /// Camera paths per pixel of `cam` in a batch of `paths_per_batch` forward paths.
    pub fn camera_paths_per_pixel(&self, cam: &CameraTarget, paths_per_batch: u64) -> u64 {
        self.footprints_of(cam)
            .map_or_else(|| cam.paths_per_pixel(paths_per_batch), |f| f.paths_per_pixel(paths_per_batch))
    }

    /// The pre-pass paths of the light field (`[detectors.footprints] light_field`), the most
    /// any camera asks for; `None` if none connects to it.
    pub fn field_paths(&self) -> Option<u64> {
        self.detectors.iter().filter_map(|d| d.surface()?.footprints.as_ref()?.light_field).max()
    }

    /// How far from the beam's axis the light field is tabulated: the farthest corner of the
    /// images whose camera paths connect to it, and [`crate::transport::field::REACH_MARGIN`].
    pub fn field_reach(&self) -> f64 {
        let axis = (self.source.position.x, self.source.position.y);
        let corners = self.detectors.iter().filter_map(|d| {
            let s = d.surface()?;
            s.footprints.as_ref()?.light_field?;
            let im = s.image()?;
            let far = |lo: f64, hi: f64, c: f64| (lo - c).abs().max((hi - c).abs());
            Some(far(im.min[0], im.max[0], axis.0).hypot(far(im.min[1], im.max[1], axis.1)))
        });
        corners.fold(0.0, f64::max) + crate::transport::field::REACH_MARGIN
    }

    fn footprints_of(&self, cam: &CameraTarget) -> Option<&crate::detect::image::Footprints> {
        self.detectors[cam.detector].surface()?.footprints.as_deref()
    }

    /// FMCW range and radial velocity of detector `i` from its total up- and down-chirp spectra
    /// in `out` ([`fmcw_estimates`]). `None` without a chirp or without a spectrum on the detector;
    /// an error when they cannot be read off (no signal).
    pub fn fmcw_estimates(&self, out: &RunOutput, i: usize) -> Option<Result<FmcwEstimate, RetrievalError>> {
        let chirp = self.source.chirp?;
        let axis = self.detectors.get(i)?.surface()?.spectrum()?.axis;
        let (up, down) = (out.spectrum(i, 0, 0)?, out.spectrum(i, 1, 0)?);
        Some(fmcw_estimates(&axis, up, down, self.source.wavelength, chirp.bandwidth, chirp.duration))
    }

    /// Whether detected paths are kept for speckle synthesis.
    pub fn records_lines(&self) -> bool {
        self.detectors.iter().any(|d| d.ldh().is_some_and(|l| l.speckle.is_some()))
    }

    /// Batches folded at a time: enough to keep every thread busy, few enough to bound memory.
    fn batches_in_flight(&self) -> u64 {
        (2 * self.plan.effective_threads() as u64).min(self.plan.batches).max(1)
    }

    /// Estimated peak memory of the tallies, bytes: the mean and the variance, and the larger of
    /// the batches in flight while running and the four vectors' worth writing makes (the
    /// standard errors, an output's values and errors, its file's bytes).
    pub fn memory_estimate(&self) -> u64 {
        let len = self.output_layout().tallies() as u64;
        len.saturating_mul(8 * (2 + self.batches_in_flight().max(4)))
    }

    /// Everything counted against `run.memory_budget_gib`, bytes: the tallies
    /// ([`memory_estimate`](Self::memory_estimate)) and [`RunPlan::memory`].
    pub fn memory_total(&self) -> u64 {
        self.plan.memory.iter().fold(self.memory_estimate(), |a, b| a.saturating_add(b.bytes))
    }

    /// Run every batch and reduce them in batch order, nothing decided ([`Decisions`]'s default).
    pub fn run(&self, progress: &dyn Progress) -> RunOutput {
        self.run_until(progress, None)
    }

    /// Run every batch with `decisions` applied and reduce them in batch order.
    pub fn run_decided(&self, decisions: &Decisions, progress: &dyn Progress) -> RunOutput {
        self.run_resumable(decisions, progress, None, None, None).expect("a run without checkpoints cannot fail")
    }

    /// Run every batch and reduce them in batch order; with a `target`, keep adding rounds of
    /// the plan's batches (batch indices continue, so every path has its own stream) until the
    /// target's output reaches its relative error. The number of rounds is decided only from
    /// folded results, so the output still does not depend on the thread count.
    pub fn run_until(&self, progress: &dyn Progress, target: Option<&Target>) -> RunOutput {
        self.run_resumable(&Decisions::default(), progress, target, None, None)
            .expect("a run without checkpoints cannot fail")
    }

    /// As [`run_until`](Self::run_until) with `decisions` applied, continuing from `resume` (a
    /// state saved by an earlier process of the same experiment) and saving states through
    /// `checkpoint`. Batches are folded in batch order whatever the process, so a resumed run
    /// equals an uninterrupted one.
    pub fn run_resumable(
        &self,
        decisions: &Decisions,
        progress: &dyn Progress,
        target: Option<&Target>,
        resume: Option<RunState>,
        checkpoint: Option<&dyn Checkpoint>,
    ) -> Result<RunOutput> {
        let decided = self.decided(decisions);
        decided.run_applied(decisions, progress, target, resume, checkpoint)
    }

    /// [`run_resumable`](Self::run_resumable) of this experiment, `decisions` already applied to
    /// it.
    fn run_applied(
        &self,
        decisions: &Decisions,
        progress: &dyn Progress,
        target: Option<&Target>,
        resume: Option<RunState>,
        checkpoint: Option<&dyn Checkpoint>,
    ) -> Result<RunOutput> {
        let start = std::time::Instant::now();
        let round = self.plan.batches;
        let mut runner = BatchRunner::new(self, decisions);
        let mut st = resume.unwrap_or_else(|| RunState {
            estimates: BatchAccumulator::new(runner.layout.tallies()),
            stats: RunStats::default(),
            lines: Vec::new(),
            next: 0,
            end: round,
            err: f64::INFINITY,
            elapsed: 0.0,
        });
        let elapsed = st.elapsed;
        progress.set_total(st.end * self.plan.paths_per_batch);
        progress.advance(st.next * self.plan.paths_per_batch);
        let main = target.map_or_else(|| self.main_output(), |t| t.output.clone());
        let max_rounds = target.map_or(1, |t| (t.max_samples / self.plan.samples()).max(1));
        let mut interrupted = None;
        loop {
            if st.next == st.end {
                let rounds = st.end / round;
                match target {
                    Some(t) if st.err > t.relative_error && rounds < max_rounds && progress.stopping() => {
                        interrupted = Some(st.end);
                        break;
                    }
                    Some(t) if st.err > t.relative_error && rounds < max_rounds => {
                        st.end = round * rounds_needed(rounds, st.err, t.relative_error, max_rounds);
                        progress.set_total(st.end * self.plan.paths_per_batch);
                    }
                    _ => break,
                }
            }
            runner.run(st.next..st.end, progress, &mut |sums, s, l| {
                st.estimates.push(sums, self.plan.paths_per_batch);
                st.stats.merge(&s);
                st.lines.extend(l);
                st.next += 1;
                st.err = main.relative_error(&st.estimates);
                progress.error(st.err);
                if let Some(c) = checkpoint.filter(|c| c.due()) {
                    st.elapsed = elapsed + start.elapsed().as_secs_f64();
                    c.save(&st)?;
                }
                Ok(())
            })?;
            if st.next < st.end && progress.stopping() {
                interrupted = Some(st.end);
                break;
            }
        }
        if st.next == 0 && interrupted.is_some() {
            // Stopped before a batch was done: there is no result to keep.
            return Err(crate::error::Error::Cancelled);
        }
        let RunState { estimates, stats, lines, end, err, .. } = st;
        let mut out = self.output(decisions, estimates, stats, lines, elapsed + start.elapsed().as_secs_f64());
        out.importance = runner.table.take();
        out.interrupted = interrupted;
        out.main_output = (main.name, err);
        out.target = target.map(|t| TargetOutcome {
            output: t.output.name.clone(),
            target: t.relative_error,
            reached: err,
            met: err <= t.relative_error,
            rounds: end / round,
            max_samples: max_rounds * self.plan.samples(),
        });
        Ok(out)
    }

    /// The batches of shard `index` of `count` (`index < count ≤ plan.batches`): the `index`-th
    /// of `count` contiguous, nearly equal parts of `0..plan.batches`.
    pub fn shard_batches(&self, index: u64, count: u64) -> std::ops::Range<u64> {
        let part = |i: u64| (u128::from(i) * u128::from(self.plan.batches) / u128::from(count.max(1))) as u64;
        part(index)..part(index + 1)
    }

    /// Run the batches `range` (once each, in parallel) with `decisions` applied and hand each
    /// one's tally sums, counters and recorded lines to `sink` in batch order: the pieces of a run
    /// that other processes run the rest of (`ohd run --shard`). Stops at the first error of
    /// `sink`.
    pub fn run_batches(
        &self,
        decisions: &Decisions,
        range: std::ops::Range<u64>,
        progress: &dyn Progress,
        sink: &mut BatchSink,
    ) -> Result<()> {
        progress.set_total((range.end - range.start) * self.plan.paths_per_batch);
        let (mut handed, end) = (range.start, range.end);
        let decided = self.decided(decisions);
        BatchRunner::new(&decided, decisions).run(range, progress, &mut |sums, s, l| {
            handed += 1;
            sink(sums, s, l)
        })?;
        // A part of a run is whole or nothing: stopped early, it is not handed on.
        if handed < end { Err(crate::error::Error::Cancelled) } else { Ok(()) }
    }

    /// The output of a run with `decisions` whose batches (`estimates.batches()` of them) were
    /// folded into `estimates` in batch order, with its counters and recorded lines: the main
    /// output's error read off. `threads` is the plan's.
    pub fn finish(
        &self,
        decisions: &Decisions,
        estimates: BatchAccumulator,
        stats: RunStats,
        lines: Vec<RecordedLine>,
        wall_seconds: f64,
    ) -> RunOutput {
        self.decided(decisions).output(decisions, estimates, stats, lines, wall_seconds)
    }

    /// [`finish`](Self::finish) of this experiment, `decisions` already applied to it.
    fn output(
        &self,
        decisions: &Decisions,
        estimates: BatchAccumulator,
        stats: RunStats,
        lines: Vec<RecordedLine>,
        wall_seconds: f64,
    ) -> RunOutput {
        let mut estimates = estimates;
        let batches = estimates.batches() as u64;
        let layout = self.tally_layout();
        layout.finish_run(&mut estimates);
        let main = layout.main();
        let main_output = (main.name.clone(), main.relative_error(&estimates));
        RunOutput {
            layout,
            beat: self.beat_model(),
            estimates,
            stats,
            threads: self.plan.effective_threads(),
            wall_seconds,
            lines,
            batches,
            paths_per_batch: self.plan.paths_per_batch,
            main_output,
            target: None,
            importance: None,
            decisions: decisions.clone(),
            interrupted: None,
        }
    }

    /// Run batch `batch` into `sums` (any contents: it is zeroed first).
    fn run_batch(
        &self,
        batch: u64,
        mut sums: Tallies,
        layout: &TallyLayout,
        beat: BeatModel,
        Steer { windows, field }: Steer,
        progress: &dyn Progress,
    ) -> BatchResult {
        sums.sums_mut().fill(0.0);
        let mut stats = RunStats::default();
        let mut lines = Vec::new();
        let record = self.records_lines();
        let nee = self.next_event_targets();
        let mut rec = Recorder {
            detectors: &self.detectors,
            layout,
            beat,
            acc: sums.sums_mut(),
            stats: &mut stats,
            lines: if record { Some(&mut lines) } else { None },
            scratch: Vec::new(),
            kernels: layout.twin_kernels(),
            path_scores: layout.tail_scores(),
            trace: layout.importance.as_ref().map(|_| crate::detect::importance::Trace::default()),
            line_draws: None,
            pulse: Vec::new(),
            window_draws: self.scene.cycle.map(|_| StreamKey::new(self.plan.seed, Purpose::Windows, batch).path(0)),
        };
        let launches = self.plan.walk.launches.and_then(|l| l.launches(&self.scene, &self.source));
        let twin = layout.detectors.iter().any(|d| d.twin.is_some());
        let twin_scene = (twin || field.is_some()).then(|| self.scene.layered_twin());
        let volume = self.volume.as_ref().map(|grid| VolumeTally {
            grid,
            slots: layout.volume.expect("a volume tally lays out its outputs"),
            gate: self.plan.walk.gate,
        });
        let walk = WalkContext {
            scene: &self.scene,
            source: &self.source,
            settings: &self.plan.walk,
            nee: &nee,
            shot: None,
            volume,
            reflections: crate::transport::policy::deterministic_reflections(
                &self.scene,
                &self.source,
                &self.plan.walk,
                &self.detectors,
            ),
            twin,
            twin_scene: twin_scene.as_ref(),
            launches: launches.as_ref(),
            windows,
            field: None,
        };
        let key = StreamKey::new(self.plan.seed, Purpose::Path, batch);
        let ppb = self.plan.paths_per_batch;
        let cameras = self.camera_targets();
        // Progress counts forward paths; with camera paths, which cost the most, it follows them.
        let forward_progress = cameras.is_empty();
        let features = Features::new(&walk, self.needs_length());
        let cancelled = features.forward_paths(&walk, &mut rec, &key, ppb, || {
            if forward_progress {
                progress.advance(PROGRESS_EVERY);
            }
            progress.cancelled()
        });
        if cancelled {
            return (sums, stats, lines);
        }
        if forward_progress {
            progress.advance(ppb % PROGRESS_EVERY);
        }
        let camera_total = self.camera_paths_per_batch().max(1);
        let (mut done, mut reported) = (0u64, 0u64);
        for cam in &cameras {
            // Pixel-major: every pixel gets `spp` paths, each weighing `ppb/spp` in the batch's
            // per-path mean, so each pixel's batch estimate is the mean of its own paths.
            let spp = self.camera_paths_per_pixel(cam, ppb);
            let batch_weight = ppb as f64 / spp as f64;
            let element = batch | (cam.detector as u64) << 48;
            let key = StreamKey::new(self.plan.seed, Purpose::Camera, element);
            rec.line_draws = Some(StreamKey::new(self.plan.seed, Purpose::Lines, element).path(0));
            let lit = self.footprints_of(cam).is_some_and(|f| f.light_field.is_some());
            let walk = WalkContext { field: field.filter(|_| lit), ..walk };
            for pixel in self.camera_pixels(cam) {
                features.camera_paths(&walk, cam, pixel, spp, batch_weight, &mut rec, &key);
                done += spp;
                if progress.cancelled() {
                    return (sums, stats, lines);
                }
                let due = done * ppb / camera_total;
                if due - reported >= PROGRESS_EVERY {
                    progress.advance(due - reported);
                    reported = due;
                }
            }
        }
        if !cameras.is_empty() {
            progress.advance(ppb - reported);
        }
        let kernels = std::mem::take(&mut rec.kernels);
        layout.convolve_twins(&kernels, sums.sums_mut());
        layout.finish_batch(&self.detectors, sums.sums_mut(), batch);
        (sums, stats, lines)
    }
}
