//! Running an experiment as the command line does: a configuration read and resolved
//! ([`Loaded`]), then one run, or a scan of pointings (one run each, then the VAD wind), each to a
//! target error, with checkpoints or resumed ([`run`]); a part of a run's batches into a shard file,
//! and the shards merged into the whole run ([`shard`]); the convergence study ([`converge`]).
//!
//! Every run's outputs are written into its directory ([`crate::io::write::manifest::write_run`]). What
//! happens along the way is told to an [`Observer`] — the progress of each run and [`Event`]s (a
//! pointing starts, a run resumes, a run is written) — so that the caller decides what to print;
//! nothing here prints.

pub mod checkpoint;
pub mod converge;
pub mod scan;
pub mod shard;

use std::path::{Path, PathBuf};

use crate::converge::Target;
use crate::error::{Error, Result};
use crate::experiment::{Experiment, Progress, RunOutput, RunState, Silent};
use crate::io::outdir::OutDir;
use crate::io::write::dir::{DirWriter, Output};
use crate::io::write::manifest::{Invocation, Timing, write_run_with};
use crate::scan::GateWind;
use crate::source::Pointing;

use checkpoint::FileCheckpoint;
pub use scan::{CHECKPOINT, Part, parts, pointing_dir, pointing_name};
pub use shard::{ShardSummary, merge, run_shard};

/// Longest experiment name kept in a default output directory's name, characters.
const MAX_FOLDER_NAME: usize = 100;

/// A configuration read and resolved, with what a run records about it.
#[derive(Debug, Clone)]
pub struct Loaded {
    /// The configuration's text.
    pub text: String,
    /// Where it came from, for the manifest (a path as given, or the built-in default).
    pub origin: String,
    /// The file's stem (or `default`): names the default output directory of an experiment
    /// without a `name`.
    pub stem: String,
    /// The file's absolute path (relative media paths resolve against it), else `origin`.
    pub source_path: String,
    /// The `--set` overrides applied, in order.
    pub overrides: Vec<String>,
    /// The configuration as run (overrides applied) and the experiment it resolves to.
    pub table: toml::Table,
    pub exp: Experiment,
}

impl Loaded {
    /// Read the configuration file `config` (the built-in default without one), apply the
    /// `--set` overrides `sets` and resolve it.
    pub fn read(config: Option<&Path>, sets: &[String]) -> Result<Loaded> {
        let (text, origin, stem) = match config {
            None => {
                (crate::DEFAULT_CONFIG.to_string(), "built-in default (configs/default.toml)".into(), "default".into())
            }
            Some(p) => {
                let text = crate::io::read_text_limited(p, crate::config::MAX_FILE_BYTES, "a configuration file")?;
                let stem = p.file_stem().map_or("experiment".into(), |s| s.to_string_lossy().into_owned());
                (text, p.display().to_string(), stem)
            }
        };
        let (table, exp) = crate::config::load(&text, &origin, sets)?;
        let source_path = match config.map(std::fs::canonicalize) {
            Some(Ok(p)) => p.display().to_string(),
            _ => origin.clone(),
        };
        Ok(Loaded { text, origin, stem, source_path, overrides: sets.to_vec(), table, exp })
    }

    /// The default output directory: `out/<name><suffix>` from the experiment's `name` (as run,
    /// after `--set`), or from the file's stem when it has none. Both are free text: characters
    /// other than letters, digits, `_` and `-` become `_`, so that it stays one folder in `out/`
    /// (issue 33: a file `..toml` named the directory `out/..`).
    pub fn default_dir(&self, suffix: &str) -> PathBuf {
        let folder = |n: &str| -> String {
            n.chars()
                .take(MAX_FOLDER_NAME)
                .map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' })
                .collect()
        };
        let name = self.table.get("name").and_then(toml::Value::as_str).map(folder);
        let name = name.filter(|n| !n.is_empty()).unwrap_or_else(|| folder(&self.stem));
        let name = if name.is_empty() { "experiment".to_string() } else { name };
        PathBuf::from("out").join(format!("{name}{suffix}"))
    }

    /// What the manifest records about how the run was invoked.
    pub fn invocation(&self) -> Invocation {
        Invocation { config_source: self.origin.clone(), overrides: self.overrides.clone(), figures: true }
    }
}

/// What a run tells its caller as it goes (a cold seam: a few calls per run).
pub trait Observer {
    /// A progress reporter for a run of `paths` paths, to the relative error `target` if any;
    /// dropped when the run ends.
    fn progress(&self, _paths: u64, _target: Option<f64>) -> Box<dyn Progress + '_> {
        Box::new(Silent)
    }
    /// A progress reporter for a run's post-processing (its total set to the steps, e.g. lidar
    /// gates, once known); dropped when the run's outputs are written.
    fn postprocess(&self) -> Box<dyn Progress + '_> {
        Box::new(Silent)
    }
    /// Something happened.
    fn event(&self, _event: Event<'_>) {}
}

/// Observes nothing.
pub struct Unobserved;

impl Observer for Unobserved {}

/// What happens during [`run`], [`merge`] and [`converge::converge`].
#[derive(Debug, Clone, Copy)]
pub enum Event<'a> {
    /// Pointing `index` of a scan starts.
    Pointing { index: usize, pointing: &'a Pointing },
    /// A run continues from the checkpoint at `path`.
    Resuming { state: &'a RunState, path: &'a Path },
    /// A run (or one pointing of a scan) is complete and its outputs written into `dir`.
    Written { exp: &'a Experiment, output: &'a RunOutput, dir: &'a Path, timing: &'a Timing },
    /// The shards of a run (or of one pointing) are merged and its outputs written into `dir`.
    Merged { exp: &'a Experiment, output: &'a RunOutput, dir: &'a Path, shards: usize, timing: &'a Timing },
    /// A shard file is written.
    ShardWritten(&'a ShardSummary),
    /// A scan's own outputs are written: `what` they hold (the VAD wind per gate, `vad.csv`, or
    /// the FMCW range and velocity per pointing, `fmcw_scan.csv`) at `path`, `scan.json` beside it.
    ScanWritten { what: &'a str, path: &'a Path, timing: &'a Timing },
    /// A convergence study of a scan studies its first pointing only.
    StudyingFirstPointing(&'a Pointing),
}

/// How `ohd run` runs: where to, to a target error, with checkpoints, resumed, or one shard.
#[derive(Debug, Clone, Default)]
pub struct RunRequest {
    /// The output directory (of a scan: `pointing_NN/` per pointing inside, and the VAD wind).
    pub dir: PathBuf,
    /// Run until the main output's relative error is at most this ([`target`]).
    pub target_error: Option<f64>,
    /// With a target error: stop at this many paths [default: 1000 × run.samples].
    pub max_samples: Option<u64>,
    /// Save the run's state to `dir/checkpoint.ohd` this often, seconds.
    pub checkpoint_seconds: Option<f64>,
    /// Continue the run from `dir/checkpoint.ohd`.
    pub resume: bool,
    /// Run only part `I` of `N` of the batches into `dir/shard.ohd`, for [`merge`].
    pub shard: Option<(u64, u64)>,
    /// Write no figures (`--no-figures`).
    pub no_figures: bool,
}

/// What [`run`] and [`merge`] finished.
#[derive(Debug, Clone)]
pub enum Finished {
    /// One run, written.
    Run(Box<RunOutput>),
    /// A scan: every pointing written (and told as [`Event::Written`] or [`Event::Merged`]),
    /// then the VAD wind per gate when every pointing has gate velocities.
    Scan { pointings: usize, vad: Option<Vec<GateWind>> },
    /// Shards written, one per part of the run.
    Shards(Vec<ShardSummary>),
}

/// The stopping rule of a run to the relative error `e` of its main output (at most
/// `max_samples` paths, by default 1000 rounds), checked.
pub fn target(exp: &Experiment, e: f64, max_samples: Option<u64>) -> Result<Target> {
    if !(e.is_finite() && e > 0.0 && e < 1.0) {
        return Err(Error::Input(format!(
            "--target-error {e}: expected a relative error between 0 and 1 (e.g. 0.01 for 1 %)"
        )));
    }
    let max_samples = max_samples.unwrap_or(exp.plan.samples().saturating_mul(1000));
    if max_samples < exp.plan.samples() {
        return Err(Error::Input(format!(
            "--max-samples {max_samples}: expected at least run.samples = {} (one round)",
            exp.plan.samples()
        )));
    }
    Ok(Target { output: exp.main_output(), relative_error: e, max_samples })
}

/// How each part of a run runs (the checked form of a [`RunRequest`]).
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    pub target: Option<Target>,
    pub checkpoint_seconds: Option<f64>,
    pub resume: bool,
}

impl RunOptions {
    /// Whether the run saves checkpoints.
    fn saving(&self) -> bool {
        self.checkpoint_seconds.is_some() || self.resume
    }
}

/// Run `loaded` as `req` asks: one run, or every pointing of a scan and then its VAD wind, or
/// one shard of each. Outputs are written into `req.dir`.
pub fn run(loaded: &Loaded, req: &RunRequest, obs: &dyn Observer) -> Result<Finished> {
    let exp = &loaded.exp;
    let target = req.target_error.map(|e| target(exp, e, req.max_samples)).transpose()?;
    if let Some(s) = req.checkpoint_seconds.filter(|s| !(s.is_finite() && *s >= 0.0)) {
        return Err(Error::Input(format!("--checkpoint-seconds {s}: expected a time ≥ 0 s")));
    }
    // The directory, locked for the whole run; every path written is inside it.
    let out = OutDir::create(&req.dir)?;
    DirWriter::check(&out, Output::Run)?;
    let parts = parts(exp, &loaded.table, &out)?;
    if let Some((index, count)) = req.shard {
        let shards = parts.iter().map(|part| run_shard(loaded, part, index, count, obs)).collect::<Result<_>>()?;
        return Ok(Finished::Shards(shards));
    }
    if req.resume && parts.len() > 1 && !parts.iter().any(|p| p.checkpoint().exists()) {
        return Err(Error::invalid_file(parts[0].checkpoint(), "no checkpoint of any pointing of this scan to resume"));
    }
    let opts = RunOptions { target, checkpoint_seconds: req.checkpoint_seconds, resume: req.resume };
    let inv = Invocation { figures: !req.no_figures, ..loaded.invocation() };
    if let [part] = parts.as_slice() {
        let output = run_part(part, &loaded.table, &inv, &opts, false, obs)?;
        interrupted(part, &output)?;
        return Ok(Finished::Run(Box::new(output)));
    }
    let mut scan = scan::Scan::default();
    for part in &parts {
        let output = simulate_part(part, &opts, true, obs)?;
        scan.writing(&out, &parts, part)?;
        let timing = write_part(part, &output, &loaded.table, &inv, &opts, true, obs)?;
        // The scan's directory stays marked incomplete: `--resume` finishes it.
        interrupted(part, &output)?;
        scan.add(part, &output, timing);
    }
    let vad = scan.finish(exp, inv.figures, obs)?;
    // The whole scan is written: the pointings' checkpoints have served.
    parts.iter().for_each(|p| drop(p.dir.remove_file(CHECKPOINT)));
    Ok(Finished::Scan { pointings: parts.len(), vad })
}

/// [`Error::Interrupted`] if `output` of `part` ended early (written, with its checkpoint).
fn interrupted(part: &Part, output: &RunOutput) -> Result<()> {
    match output.interrupted {
        Some(planned) => {
            Err(Error::Interrupted { dir: part.dir.path().to_path_buf(), batches: output.batches, planned })
        }
        None => Ok(()),
    }
}

/// Run `part` (to a target error, with checkpoints, resumed: `opts`) and write its outputs into
/// its directory, with `config` and `inv` in the manifest. A pointing of a scan (`keep`) keeps
/// its checkpoint, saved as complete, until the whole scan is written, so that a resumed scan
/// finds its finished pointings; a plain run removes its checkpoint once written. A run that
/// ended early ([`RunOutput::interrupted`]) is written as it is, and its checkpoint saved.
pub fn run_part(
    part: &Part,
    config: &toml::Table,
    inv: &Invocation,
    opts: &RunOptions,
    keep: bool,
    obs: &dyn Observer,
) -> Result<RunOutput> {
    let output = simulate_part(part, opts, keep, obs)?;
    write_part(part, &output, config, inv, opts, keep, obs)?;
    Ok(output)
}

/// Run `part` (to a target error, with checkpoints, resumed: `opts`; a pointing of a scan,
/// `keep`, resumed only if it has a checkpoint), writing only its checkpoints.
fn simulate_part(part: &Part, opts: &RunOptions, keep: bool, obs: &dyn Observer) -> Result<RunOutput> {
    let exp = &part.exp;
    let path = part.checkpoint();
    if let Some(index) = part.pointing {
        obs.event(Event::Pointing { index, pointing: &exp.source.pointings[index] });
    }
    // A scan resumes the pointings it has a checkpoint of and starts the others.
    let resume = if opts.resume && (!keep || path.exists()) {
        let tallies = exp.output_layout().tallies();
        let limit = crate::io::persist::checkpoint::max_bytes(tallies, exp.plan.memory_budget);
        let state = crate::io::persist::checkpoint::read(&path, part.fingerprint, tallies, limit)?;
        obs.event(Event::Resuming { state: &state, path: &path });
        Some(state)
    } else {
        None
    };
    let checkpoint = opts.checkpoint_seconds.map(|s| FileCheckpoint::new(part, s)).transpose()?;
    let checkpoint = checkpoint.as_ref().map(|c| c as &dyn crate::experiment::Checkpoint);
    let target = opts.target.as_ref();
    let progress = obs.progress(exp.plan.samples(), target.map(|t| t.relative_error));
    exp.run_resumable(&part.decisions, &*progress, target, resume, checkpoint)
}

/// Write the outputs of `part` (run as `opts` asked) into its directory and keep (a pointing of
/// a scan) or remove its checkpoint, as [`run_part`] says.
fn write_part(
    part: &Part,
    output: &RunOutput,
    config: &toml::Table,
    inv: &Invocation,
    opts: &RunOptions,
    keep: bool,
    obs: &dyn Observer,
) -> Result<Timing> {
    let exp = &part.exp;
    let manifest = write_run_with(&part.dir, exp, output, config, inv, &*obs.postprocess())?;
    if keep || output.interrupted.is_some() {
        // A pointing of a scan keeps its state until the whole scan is written, so that a scan
        // interrupted later resumes past it; an interrupted run keeps it for `--resume`.
        checkpoint::save_final(part, output)?;
    } else if opts.saving() {
        // The run is complete and written: its checkpoint has served.
        let _ = part.dir.remove_file(CHECKPOINT);
    }
    obs.event(Event::Written { exp, output, dir: part.dir.path(), timing: &manifest.timing });
    Ok(manifest.timing)
}
