//! The `ohd` command line: argument parsing, the commands, progress, printing and exit codes. No
//! physics here. It lives in the library so that the binary (`src/main.rs`) and the Python
//! package's `ohd` console script (one build for both) run the same code ([`status_from`]).
//! Exit status: 0 success, 2 bad input (configuration or unreadable file; nothing is written),
//! 1 failure while running or writing, 130 a run stopped by Ctrl-C (143 by SIGTERM).

use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::{Parser, Subcommand};

use crate::converge::StudyLog;
use crate::error::Error;
use crate::experiment::{Experiment, Progress, RunOutput};
use crate::retrieval::{FmcwEstimate, RetrievalError};
use crate::run::converge::{ConvergeRequest, StudyWritten};
use crate::run::{Event, Loaded, Observer, RunRequest};

/// Whether writing to standard output or standard error failed (a closed pipe, a full disk;
/// issue 33: `ohd check > /dev/full` and `ohd run 2>/dev/full` panicked): the command goes on and
/// writes its outputs, then exits with status 1.
static STREAM_FAILED: AtomicBool = AtomicBool::new(false);

/// Write `args` (and a newline if `line`) to the stream `w` and flush it; a failure is noted in
/// [`STREAM_FAILED`], never a panic.
fn emit(mut w: impl Write, args: std::fmt::Arguments<'_>, line: bool) {
    let end: &[u8] = if line { b"\n" } else { b"" };
    if w.write_fmt(args).and_then(|()| w.write_all(end)).and_then(|()| w.flush()).is_err() {
        STREAM_FAILED.store(true, Ordering::Relaxed);
    }
}

/// A line on standard error (messages, the run report).
macro_rules! say {
    ($($t:tt)*) => { emit(std::io::stderr(), format_args!($($t)*), true) };
}

/// A line on standard output (what a command prints as its result: `check`, `mie`, a run's
/// report, a study's table).
macro_rules! out {
    ($($t:tt)*) => { emit(std::io::stdout(), format_args!($($t)*), true) };
}

/// Text on standard output, as it is.
macro_rules! out_part {
    ($($t:tt)*) => { emit(std::io::stdout(), format_args!($($t)*), false) };
}

#[derive(Parser)]
#[command(
    name = "ohd",
    version,
    about = "Monte Carlo simulation of optical heterodyne detection in participating media"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run an experiment and write its outputs (the built-in default experiment without CONFIG).
    Run(RunArgs),
    /// Merge the shards of one run (`ohd run --shard I/N --out DIR`, every I) into the outputs
    /// of the whole run, identical to a single `ohd run` (the manifest's timings aside).
    Merge {
        /// The shards' output directories (each holding a shard.ohd), in any order.
        #[arg(required = true, value_name = "DIR")]
        dirs: Vec<PathBuf>,
        /// Output directory of the merged run.
        #[arg(long)]
        out: PathBuf,
        /// Write no figures (PNG/SVG), only the data files.
        #[arg(long)]
        no_figures: bool,
    },
    /// Error against run time: run a ladder of sample counts (independent seeds), measure every
    /// output's error against a reference, and write converge.csv, converge.json, converge.png.
    /// Rung k runs with seed + 1 + k; a reference run made on the fly uses the seed itself.
    Converge {
        /// Experiment file (TOML). Omit for the built-in default.
        config: Option<PathBuf>,
        /// Output directory [default: out/<experiment name>_converge].
        #[arg(long)]
        out: Option<PathBuf>,
        /// A run directory of the same experiment (from `ohd run`) as the reference. Without it,
        /// outputs without an analytic `[reference]` in the config get a reference run made on the
        /// fly with 4× the paths of the largest rung.
        #[arg(long, value_name = "RUN_DIR")]
        reference: Option<PathBuf>,
        /// Wall-time budget of the whole study, seconds (the ladder and an on-the-fly reference).
        #[arg(long, default_value_t = 120.0, allow_negative_numbers = true)]
        budget_seconds: f64,
        /// Paths of the largest rung (instead of sizing the ladder from the budget; `1e6` is
        /// taken).
        #[arg(long, value_parser = whole_count)]
        samples: Option<u64>,
        /// Number of rungs, each twice the paths of the one before.
        #[arg(long, default_value_t = 6)]
        rungs: usize,
        #[command(flatten)]
        overrides: Overrides,
        /// No log of each run.
        #[arg(long, short)]
        quiet: bool,
        /// Write no figure (converge.png/.svg).
        #[arg(long)]
        no_figures: bool,
    },
    /// Mie scattering by one homogeneous sphere: prints {"x", "qext", "qsca", "qback", "g"} as JSON
    /// (qback = 4|S1(180°)|²/x²). Give the relative index and size parameter (--m-real, --m-imag,
    /// --x), or the physical sphere (--diameter-um, --n-particle, --k-particle, --n-medium,
    /// --wavelength-nm). With --angles N --table FILE, also writes its phase table.
    Mie(MieArgs),
    /// Validate an experiment and print it as resolved (SI units), without running it.
    Check {
        /// Experiment file (TOML). Omit to check the built-in default.
        config: Option<PathBuf>,
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
    },
}

/// The arguments of `ohd run`.
#[derive(clap::Args)]
struct RunArgs {
    /// Experiment file (TOML). Omit to run the built-in default (configs/default.toml).
    config: Option<PathBuf>,
    /// Output directory [default: out/<experiment name>, else out/<config file stem>].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Number of paths (same as --set run.samples=N; `1e6` is taken).
    #[arg(long, value_parser = whole_count)]
    samples: Option<u64>,
    #[command(flatten)]
    overrides: Overrides,
    /// Run until the main output's estimated relative error is at most E (e.g. 0.01): whole
    /// rounds of run.samples paths are added, the number of rounds extrapolated from 1/√paths.
    #[arg(long, value_name = "E", allow_negative_numbers = true)]
    target_error: Option<f64>,
    /// With --target-error: stop at this many paths even if the target is not met
    /// [default: 1000 × run.samples].
    #[arg(long, requires = "target_error", value_parser = whole_count)]
    max_samples: Option<u64>,
    /// Save the run's state to OUT/checkpoint.ohd every S seconds (atomically), so that
    /// `--resume` can finish it after the process dies. Removed when the run completes.
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    checkpoint_seconds: Option<f64>,
    /// Continue the run from OUT/checkpoint.ohd (same config and --set; any --threads): the
    /// result equals an uninterrupted run's.
    #[arg(long)]
    resume: bool,
    /// Run only part I (from 0) of N of the run's batches and write them to OUT/shard.ohd, for
    /// `ohd merge` (N at most run.batches; every part with the same config, --set, seed and
    /// samples). See validation/slurm/ for a Slurm job array.
    #[arg(long, value_name = "I/N", value_parser = parse_shard, conflicts_with_all = ["target_error", "checkpoint_seconds", "resume"])]
    shard: Option<(u64, u64)>,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
    /// Write no figures (PNG/SVG), only the data files (for batch work).
    #[arg(long)]
    no_figures: bool,
}

/// A count of paths: an integer (`1000000`, `1_000_000`) or a float of a whole value (`1e6`).
fn whole_count(s: &str) -> Result<u64, String> {
    let t = s.trim().replace('_', "");
    t.parse::<u64>()
        .ok()
        .or_else(|| t.parse::<f64>().ok().and_then(crate::config::schema::whole))
        .ok_or_else(|| format!("expected a whole number of paths such as 1000000 or 1e6; got {s:?}"))
}

/// `I/N` with 0 ≤ I < N.
fn parse_shard(s: &str) -> Result<(u64, u64), String> {
    let parsed =
        s.split_once('/').and_then(|(i, n)| Some((i.trim().parse::<u64>().ok()?, n.trim().parse::<u64>().ok()?)));
    match parsed {
        Some((i, n)) if i < n => Ok((i, n)),
        _ => Err(format!("expected I/N with 0 ≤ I < N (part I, from 0, of N), e.g. 3/8; got {s:?}")),
    }
}

/// The run plan and configuration overrides shared by `run` and `converge`.
#[derive(clap::Args)]
struct Overrides {
    /// Random seed (same as --set run.seed=S).
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads, 0 = all cores (same as --set run.threads=N). Results do not depend on it.
    #[arg(long)]
    threads: Option<u64>,
    /// Override a configuration value before validation: dotted key path = TOML value,
    /// e.g. --set layers.0.thickness_mm=0.2 --set source.profile=disk. Repeatable.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
}

impl Overrides {
    /// The `--set` list with `--seed` and `--threads` (and `samples`) appended.
    fn sets(self, samples: Option<u64>) -> Vec<String> {
        let mut set = self.set;
        set.extend(samples.map(|v| format!("run.samples={v}")));
        set.extend(self.seed.map(|v| format!("run.seed={v}")));
        set.extend(self.threads.map(|v| format!("run.threads={v}")));
        set
    }
}

#[derive(clap::Args)]
struct MieArgs {
    /// Real part n of the relative refractive index m = n − ik.
    #[arg(long, allow_negative_numbers = true, requires = "x", conflicts_with_all = ["diameter_um", "n_particle", "k_particle", "n_medium", "wavelength_nm"])]
    m_real: Option<f64>,
    /// Imaginary part k ≥ 0 of m = n − ik (absorbing when > 0) [default: 0].
    #[arg(long, allow_negative_numbers = true, requires = "m_real")]
    m_imag: Option<f64>,
    /// Size parameter x = 2π r n_medium / λ0.
    #[arg(long, allow_negative_numbers = true, requires = "m_real")]
    x: Option<f64>,
    /// Sphere diameter, µm.
    #[arg(long, allow_negative_numbers = true, requires_all = ["n_particle", "n_medium", "wavelength_nm"])]
    diameter_um: Option<f64>,
    /// Real refractive index of the sphere.
    #[arg(long, allow_negative_numbers = true, requires = "diameter_um")]
    n_particle: Option<f64>,
    /// Absorption index k ≥ 0 of the sphere (index n − ik) [default: 0].
    #[arg(long, allow_negative_numbers = true, requires = "diameter_um")]
    k_particle: Option<f64>,
    /// Refractive index of the host medium.
    #[arg(long, allow_negative_numbers = true, requires = "diameter_um")]
    n_medium: Option<f64>,
    /// Vacuum wavelength, nm.
    #[arg(long, allow_negative_numbers = true, requires = "diameter_um")]
    wavelength_nm: Option<f64>,
    /// Number of angles of the phase table (dense near forward).
    #[arg(long, requires = "table")]
    angles: Option<usize>,
    /// Write the phase table (format: media/README.md) to this file.
    #[arg(long, requires = "angles")]
    table: Option<PathBuf>,
}

fn mie(a: &MieArgs) -> Result<(), Error> {
    use std::collections::BTreeMap;

    use crate::io::formats::table::{Normalisation, TableOptics, phase_table_text};
    use crate::mie::{MieSolution, angle_grid};

    let input = |m: String| Error::Input(m);
    let finite = |name: &str, v: f64, ok: bool, expected: &str| -> Result<f64, Error> {
        if v.is_finite() && ok { Ok(v) } else { Err(input(format!("--{name} {v}: expected {expected}"))) }
    };
    let mut optics = TableOptics::default();
    let (n, k, x) = match (a.m_real, a.diameter_um) {
        (Some(n), None) => {
            let k = a.m_imag.unwrap_or(0.0);
            let n = finite("m-real", n, n > 0.0, "a real part > 0")?;
            let k = finite("m-imag", k, k >= 0.0, "k ≥ 0 (m = n − ik; k > 0 absorbs)")?;
            let x = a.x.unwrap_or(f64::NAN);
            (n, k, finite("x", x, x > 0.0, "a size parameter > 0")?)
        }
        (None, Some(d)) => {
            let d = finite("diameter-um", d, d > 0.0, "a diameter > 0 µm")?;
            let np = a.n_particle.unwrap_or(f64::NAN);
            let np = finite("n-particle", np, np > 0.0, "a refractive index > 0")?;
            let kp = a.k_particle.unwrap_or(0.0);
            let kp = finite("k-particle", kp, kp >= 0.0, "k ≥ 0 (index n − ik; k > 0 absorbs)")?;
            let nm = a.n_medium.unwrap_or(f64::NAN);
            let nm = finite("n-medium", nm, nm > 0.0, "a refractive index > 0")?;
            let wl = a.wavelength_nm.unwrap_or(f64::NAN);
            let wl = finite("wavelength-nm", wl, wl > 0.0, "a vacuum wavelength > 0 nm")?;
            optics = TableOptics {
                wavelength_nm: Some(wl),
                n_medium: Some(nm),
                n_particle: Some(np),
                k_particle: Some(kp),
                size_distribution: Some(format!("monodisperse, diameter {d} µm")),
                ..Default::default()
            };
            crate::medium::relative_sphere(d * 1e-6, np, kp, nm, wl * 1e-9)
        }
        _ => {
            return Err(input(
                "give either --m-real and --x (with --m-imag), or --diameter-um, --n-particle, --n-medium and --wavelength-nm"
                    .into(),
            ));
        }
    };
    let sol = MieSolution::new(n, k, x).map_err(|e| input(e.to_string()))?;
    let q = sol.efficiencies();
    if let (Some(angles), Some(path)) = (a.angles, &a.table) {
        if !(16..=100_000).contains(&angles) {
            return Err(input(format!("--angles {angles}: expected 16 to 100000")));
        }
        let theta = angle_grid(angles, x);
        let mut p = vec![0.0; angles];
        sol.phase_function(&theta, &mut p);
        optics.size_parameter = Some(x);
        optics.qext = Some(q.qext);
        optics.qsca = Some(q.qsca);
        optics.qback = Some(q.qback);
        optics.g = Some(q.g);
        let args: Vec<String> = std::env::args().collect();
        let provenance = BTreeMap::from([
            ("generator".to_string(), format!("ohd {} (Lorenz–Mie, src/mie)", env!("CARGO_PKG_VERSION"))),
            ("command".to_string(), args.join(" ")),
            ("relative_index".to_string(), format!("m = {n} − {k}i")),
        ]);
        let degrees: Vec<f64> = theta.iter().map(|t| t.to_degrees()).collect();
        let description = format!("Mie phase function of one sphere, x = {x}, m = {n} − {k}i");
        let text = phase_table_text(&description, Normalisation::PerSr, &optics, &provenance, &degrees, &p);
        crate::io::write_atomic(path, text.as_bytes())?;
    }
    let json = serde_json::json!({ "x": x, "qext": q.qext, "qsca": q.qsca, "qback": q.qback, "g": q.g });
    out!("{json}");
    Ok(())
}

/// The progress bar: paths, the main output's running relative error (and the target), ETA.
struct Bar {
    bar: indicatif::ProgressBar,
    target: Option<f64>,
}

impl Bar {
    fn new(total: u64, target: Option<f64>) -> Bar {
        let bar = indicatif::ProgressBar::new(total);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} {bar:40} {percent:>3}% {human_pos}/{human_len} paths, {msg}, ETA {eta}",
            )
            .expect("valid template"),
        );
        bar.set_message("error: …");
        Bar { bar, target }
    }
}

impl Drop for Bar {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

impl Progress for Bar {
    fn advance(&self, paths: u64) {
        self.bar.inc(paths);
    }

    fn set_total(&self, paths: u64) {
        self.bar.set_length(paths);
    }

    fn error(&self, relative: f64) {
        let e = if relative.is_finite() { format!("{:.3}%", 100.0 * relative) } else { "…".into() };
        self.bar.set_message(match self.target {
            Some(t) => format!("error {e} (target {:.3}%)", 100.0 * t),
            None => format!("error {e}"),
        });
    }
}

/// A progress bar over post-processing steps (lidar gates), shown once their number is known;
/// cleared when dropped.
struct Steps {
    bar: indicatif::ProgressBar,
}

impl Steps {
    fn new(what: &str) -> Steps {
        let bar = indicatif::ProgressBar::hidden();
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} {bar:40} {pos}/{len} {msg}, ETA {eta}")
                .expect("valid template"),
        );
        bar.set_message(what.to_string());
        Steps { bar }
    }
}

impl Drop for Steps {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

impl Progress for Steps {
    fn advance(&self, steps: u64) {
        self.bar.inc(steps);
    }

    fn set_total(&self, steps: u64) {
        if steps > 0 {
            self.bar.set_length(steps);
            self.bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
        }
    }
}

/// `, post-processing 0.12 s (gate fits 0.11 s), writing 0.05 s`: where a run's time went after
/// its transport (which the caller prints), so that the transport's time is not taken for the run's.
fn after_transport(t: &crate::io::write::manifest::Timing) -> String {
    let fits =
        if t.gate_fit_seconds > 0.0 { format!(" (gate fits {:.2} s)", t.gate_fit_seconds) } else { String::new() };
    format!(", post-processing {:.2} s{fits}, writing {:.2} s", t.postprocess_seconds, t.writing_seconds)
}

fn fail(e: &Error) -> u8 {
    say!("ohd: {e}");
    match e {
        _ if e.is_input_error() => 2,
        // 128 + the signal's number, as a shell reports a command ended by it.
        Error::Interrupted { .. } | Error::Cancelled if TERMINATED.load(Ordering::SeqCst) => 143,
        Error::Interrupted { .. } | Error::Cancelled => 130,
        _ => 1,
    }
}

/// Set by the first Ctrl-C (SIGINT) or SIGTERM of `ohd run`: the run ends at its next batch
/// boundary and writes what it has ([`crate::experiment::Progress::stopping`]); the second of
/// either ends the process at once (status 130, or 143 for SIGTERM).
static STOP: AtomicBool = AtomicBool::new(false);

/// Set by SIGTERM: the stop was asked by a batch system or `kill`, not by Ctrl-C (the exit status
/// is then 143, and the message says which).
static TERMINATED: AtomicBool = AtomicBool::new(false);

/// Whether the first stop has been answered on stderr.
static STOP_TOLD: AtomicBool = AtomicBool::new(false);

/// Ctrl-C and SIGTERM as `ohd run` takes them ([`STOP`]): a batch system's SIGTERM before its
/// SIGKILL is the common way a job ends, and keeps the work as Ctrl-C does. The second signal
/// exits from the signal handler, before the first one's flag is set again (signal-hook runs a
/// signal's actions in the order registered).
fn keep_work_on_ctrl_c() {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let registered = signal_hook::flag::register_conditional_shutdown(SIGINT, 130, &STOP)
        .and_then(|_| signal_hook::flag::register(SIGINT, &STOP))
        .and_then(|_| signal_hook::flag::register_conditional_shutdown(SIGTERM, 143, &STOP))
        .and_then(|_| signal_hook::flag::register(SIGTERM, &TERMINATED))
        .and_then(|_| signal_hook::flag::register(SIGTERM, &STOP));
    if let Err(e) = registered {
        say!("ohd: Ctrl-C and SIGTERM will stop the run without keeping its work (the handler could not be set: {e})");
    }
}

/// A run's progress reporter that also passes on the first Ctrl-C ([`STOP`]).
struct CtrlC<'a>(Box<dyn Progress + 'a>);

impl Progress for CtrlC<'_> {
    fn advance(&self, paths: u64) {
        self.0.advance(paths);
    }

    fn set_total(&self, paths: u64) {
        self.0.set_total(paths);
    }

    fn error(&self, relative: f64) {
        self.0.error(relative);
    }

    fn stopping(&self) -> bool {
        let stop = STOP.load(Ordering::SeqCst);
        if stop && !STOP_TOLD.swap(true, Ordering::SeqCst) {
            let what = if TERMINATED.load(Ordering::SeqCst) { "SIGTERM" } else { "Ctrl-C" };
            say!(
                "\nohd: {what}: finishing the batches in flight, then writing the result of the batches done and a checkpoint for --resume ({what} again stops at once, and nothing more is written)"
            );
        }
        stop
    }
}

/// The `ohd` command with the process's arguments.
pub fn main() -> ExitCode {
    ExitCode::from(status_from(std::env::args_os()))
}

/// The `ohd` command with the arguments `args` (the command's name first); returns its exit
/// status. `--help`, `--version` and argument errors end the process, as for any clap command.
pub fn status_from<I, T>(args: I) -> u8
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    // A file-size limit (`ulimit -f`) makes a write fail with EFBIG, reported as a write error
    // (exit 1, the directory marked incomplete), instead of killing the process by SIGXFSZ.
    let _ = signal_hook::flag::register(signal_hook::consts::SIGXFSZ, std::sync::Arc::new(AtomicBool::new(false)));
    let cli = Cli::parse_from(args);
    let result = match cli.command {
        Command::Mie(a) => mie(&a),
        Command::Converge { config, out, reference, budget_seconds, samples, rungs, overrides, quiet, no_figures } => {
            let req = ConvergeRequest {
                config,
                overrides: overrides.sets(None),
                out,
                reference,
                budget_seconds,
                samples,
                rungs,
                no_figures,
            };
            converge(&req, quiet)
        }
        Command::Check { config, set } => Loaded::read(config.as_deref(), &set).map(|l| {
            out!("experiment \"{}\" from {}: valid", l.exp.name, l.origin);
            out_part!("{}", l.exp);
        }),
        Command::Run(a) => run(a),
        Command::Merge { dirs, out, no_figures } => {
            crate::run::merge(&dirs, &out, !no_figures, &Terminal { quiet: false }).map(drop)
        }
    };
    match result {
        Ok(()) if STREAM_FAILED.load(Ordering::Relaxed) => {
            // Said where it can still be said (stderr may be the stream that failed).
            let _ = writeln!(
                std::io::stderr(),
                "ohd: standard output or standard error could not be written (closed or full): messages were lost; the files were written"
            );
            1
        }
        Ok(()) => 0,
        Err(e) => fail(&e),
    }
}

/// `ohd run`: one experiment, a scan of pointings, or one shard of an experiment.
fn run(a: RunArgs) -> Result<(), Error> {
    let set = a.overrides.sets(a.samples);
    let loaded = Loaded::read(a.config.as_deref(), &set)?;
    let req = RunRequest {
        dir: a.out.unwrap_or_else(|| loaded.default_dir("")),
        target_error: a.target_error,
        max_samples: a.max_samples,
        checkpoint_seconds: a.checkpoint_seconds,
        resume: a.resume,
        shard: a.shard,
        no_figures: a.no_figures,
    };
    if req.shard.is_none() {
        keep_work_on_ctrl_c();
    }
    crate::run::run(&loaded, &req, &Terminal { quiet: a.quiet }).map(drop)
}

/// Tells the user: a progress bar per run on stderr (when stderr is a terminal and not `quiet`;
/// cleared after), a line per event (on stdout what was written and the run's report, on stderr
/// what happens on the way).
struct Terminal {
    quiet: bool,
}

impl Observer for Terminal {
    fn progress(&self, paths: u64, target: Option<f64>) -> Box<dyn Progress + '_> {
        if self.quiet || !std::io::stderr().is_terminal() {
            return Box::new(CtrlC(Box::new(crate::experiment::Silent)));
        }
        Box::new(CtrlC(Box::new(Bar::new(paths, target))))
    }

    fn postprocess(&self) -> Box<dyn Progress + '_> {
        if self.quiet || !std::io::stderr().is_terminal() {
            return Box::new(crate::experiment::Silent);
        }
        Box::new(Steps::new("gate fits"))
    }

    fn event(&self, event: Event<'_>) {
        match event {
            Event::Pointing { index, pointing: p } => {
                say!("ohd: pointing {index}: azimuth {}°, elevation {}°", p.azimuth_deg, p.elevation_deg);
            }
            Event::Resuming { state, path } => {
                say!("ohd: resuming at batch {} of {} from {}", state.next, state.end, path.display());
            }
            Event::Written { exp, output, dir, timing } => {
                out!(
                    "ohd: {} paths in {:.2} s ({:.0} paths/ms){} → {}",
                    output.samples(),
                    output.wall_seconds,
                    output.samples() as f64 / output.wall_seconds.max(1e-9) / 1e3,
                    after_transport(timing),
                    dir.display()
                );
                report(exp, output);
            }
            Event::Merged { exp, output, dir, shards, timing } => {
                out!(
                    "ohd: merged {shards} shards ({} batches){} → {}",
                    output.batches,
                    after_transport(timing),
                    dir.display()
                );
                report(exp, output);
            }
            Event::ShardWritten(s) => out!(
                "ohd: shard {}/{}: batches {}..{} of {}, {} paths in {:.2} s → {}",
                s.index,
                s.count,
                s.range.start,
                s.range.end,
                s.batches,
                s.paths,
                s.seconds,
                s.path.display()
            ),
            Event::ScanWritten { what, path, timing } => {
                out!("ohd: {what} → {}", path.display());
                out!("ohd: the scan's time: transport {:.2} s{}", timing.transport_seconds, after_transport(timing));
            }
            Event::StudyingFirstPointing(p) => {
                say!("ohd converge: a scan: studying its first pointing ({}°, {}°)", p.azimuth_deg, p.elevation_deg);
            }
        }
    }
}

/// What the run report shows, read off the typed results of a run: the scalar estimates (name,
/// value, standard error) and per chirped spectrum detector its FMCW retrieval.
struct Figures {
    scalars: Vec<(String, f64, f64)>,
    fmcw: Vec<(String, Result<FmcwEstimate, RetrievalError>)>,
}

/// The one place the report reads its numbers.
fn figures(exp: &Experiment, output: &RunOutput) -> Figures {
    let (mean, se) = (output.estimates.mean(), output.estimates.stderr());
    use crate::detect::{LATERAL_SCALAR, Scalar};
    let scalar = |s: Scalar| (s.name(), Some(s as usize));
    // A box phantom's side faces after the transmittance (its slot only where it is declared).
    let lateral = exp.scene.lateral.map(|_| (LATERAL_SCALAR, output.layout.lateral));
    let scalars = [Scalar::ReflectanceSpecular, Scalar::ReflectanceDiffuse, Scalar::TransmittanceTotal]
        .map(scalar)
        .into_iter()
        .chain(lateral)
        .chain([scalar(Scalar::AbsorbedFraction)])
        .map(|(k, slot)| match slot {
            Some(s) => (k.to_string(), mean[s], se[s]),
            None => (k.to_string(), f64::NAN, f64::NAN),
        })
        .collect();
    let fmcw = (0..exp.detectors.len())
        .filter_map(|i| Some((exp.detectors[i].name.clone(), exp.fmcw_estimates(output, i)?)))
        .collect();
    Figures { scalars, fmcw }
}

/// The terminal's line of a tail check: the slope of the largest path scores and what MCNP reads
/// into it.
fn tail_line(t: &crate::stats::TailCheck) -> String {
    match t.slope {
        Some(s) => {
            let verdict = if s >= 3.0 {
                "≥ 3: a finite variance"
            } else {
                "< 3: not yet sampled, a typical run reads these pixels low"
            };
            format!(
                "largest scores of {} paths there: slope {s:.1} of their density's tail ({verdict}; from the largest {})",
                t.scores, t.largest
            )
        }
        None => format!("largest scores: {} paths scored there, too few for a slope", t.scores),
    }
}

/// The main output's error, the target's outcome, the scalar estimates and FMCW retrievals of a
/// written run: on stdout, as the command's result (`ohd run x.toml > log` keeps it); warnings on
/// stderr.
fn report(exp: &Experiment, output: &RunOutput) {
    let (main, err) = &output.main_output;
    out!("  main output {main}: relative error {:.4}% (all values together)", 100.0 * err);
    for e in &output.decisions.estimators {
        if let Some(a) = e.figures {
            out!(
                "  {}: estimator auto chose {} (pilot: camera-side efficiency {:.2}× forward)",
                exp.detectors[e.detector].name,
                e.estimator.name(),
                a.forward / a.camera
            );
        }
    }
    // Images are read pixel by pixel: each main image's per-pixel relative errors.
    let (mean, stderr) = (output.estimates.mean(), output.estimates.stderr());
    let speckle: std::collections::BTreeMap<usize, (f64, usize)> = exp.m0_speckle(&output.layout).collect();
    let tails = output.tail_checks();
    let pct = |x: Option<f64>| x.map_or("–".to_string(), |x| format!("{:.1}%", 100.0 * x));
    let num = |x: Option<f64>| x.map_or("–".to_string(), |x| format!("{x:.3}"));
    for o in output.layout.registry.outputs.iter().filter(|o| o.primary) {
        if let Some(pe) = o.pixel_errors(mean, &stderr) {
            let blank = if pe.without_signal > 0 {
                format!(", {} pixels without signal", pe.without_signal)
            } else {
                String::new()
            };
            out!(
                "  {}: per-pixel relative error median {:.1}%, p90 {:.1}%{blank}",
                o.name,
                100.0 * pe.median,
                100.0 * pe.p90
            );
            // Split by the regions' footprints (`NAME_region_mask.npy`).
            let regions = exp.region_mask_of(o).map(|mask| {
                let (v, e) = o.slice(mean, &stderr);
                crate::output::RegionErrors::of(v, e, &mask)
                    .with_run(tails.get(&o.slots.start).copied(), output.paths() as f64)
            });
            if let Some(r) = &regions {
                out!(
                    "    regions' footprints ({} px): median {}, rest {} (rest σ / region mean {}), top 1% of region pixels {} of their variance",
                    r.region_pixels,
                    pct(r.median_region),
                    pct(r.median_rest),
                    pct(r.rest_sigma_over_region_mean),
                    pct(r.region_top_percent_variance_share)
                );
                out!(
                    "    regions' footprints: RMS relative error ε {} (√(mean σ²)/mean; the median reads low), variance per path N·ε² {}",
                    num(r.region_rms),
                    r.region_variance_per_path.map_or("–".to_string(), |v| format!("{v:.3e}"))
                );
                if let Some(t) = r.tail {
                    out!("    {}", tail_line(&t));
                }
            }
            // An M0+ image against the camera's own noise: the speckle of how many windows.
            if let Some(&(c, frames)) = speckle.get(&o.slots.start) {
                let s = crate::output::SpeckleScale::new(c, frames, pe.median, regions.as_ref());
                let split = if regions.is_some() {
                    format!(
                        " (regions' footprints {}, at their RMS ε {}; rest {})",
                        num(s.windows_at_region_median),
                        num(s.windows_at_region_rms),
                        num(s.windows_at_rest_median)
                    )
                } else {
                    String::new()
                };
                out!(
                    "    speckle of one {frames}-frame window {:.1}%: the median error is that of {} windows{split}",
                    100.0 * c,
                    num(s.windows_at_median)
                );
            }
        }
    }
    if let Some(t) = &output.target {
        if t.met {
            out!(
                "  target error {:.4}% met after {} round(s) of {} paths",
                100.0 * t.target,
                t.rounds,
                exp.plan.samples()
            );
        } else {
            say!(
                "ohd: warning: target error {:.4}% not met: stopped at --max-samples {} ({} rounds)",
                100.0 * t.target,
                t.max_samples,
                t.rounds
            );
        }
    }
    let f = figures(exp, output);
    for (k, v, s) in &f.scalars {
        out!("  {k:<24} {v:.6} ± {s:.6}");
    }
    for (name, result) in &f.fmcw {
        if let Ok(e) = result {
            out!(
                "  {name}: FMCW range {:.4} m, radial velocity {:+.4} m/s (bins {:.4} m, {:.4} m/s)",
                e.range_m,
                e.radial_velocity_m_per_s,
                e.range_bin_m,
                e.velocity_bin_m_per_s
            );
        }
        if let Some(note) = crate::io::write::fmcw::note(result) {
            out!("  {name}: FMCW {note}");
        }
    }
    // Last, where they are seen: what the run could not get right (also in the manifest).
    for w in crate::post::warnings(exp, output) {
        say!("ohd: warning: {}", w.message);
    }
}

/// `ohd converge`: the study, then a table of its outputs on stdout.
fn converge(req: &ConvergeRequest, quiet: bool) -> Result<(), Error> {
    let StudyWritten { study, dir } =
        crate::run::converge::converge(req, &Terminal { quiet }, &mut StderrLog { quiet })?;
    out!("ohd converge: → {}", dir.display());
    out!("  {:<28} {:>9} {:>7} {:>12} {:>12} {:>8}", "output", "reference", "slope", "s to 1%", "s to 0.1%", "σ ratio");
    let fmt = |v: Option<f64>| v.map_or("—".to_string(), |t| format!("{t:.3e}"));
    for o in &study.outputs {
        out!(
            "  {:<28} {:>9} {:>7.3} {:>12} {:>12} {:>8.3}{}",
            o.output.name,
            o.reference_kind,
            o.fit.map_or(f64::NAN, |f| f.0),
            fmt(o.seconds_to(0.01)),
            fmt(o.seconds_to(0.001)),
            o.sigma_ratio_rms(),
            if study.is_main(&o.output) { "  (main)" } else { "" }
        );
    }
    for (name, why) in &study.skipped {
        out!("  {name:<28} skipped: {why}");
    }
    Ok(())
}

/// `ohd converge`'s log: one line per run on stderr (none when quiet).
struct StderrLog {
    quiet: bool,
}

impl StudyLog for StderrLog {
    fn line(&mut self, text: &str) {
        if !self.quiet {
            say!("ohd converge: {text}");
        }
    }

    fn progress(&self) -> &dyn Progress {
        &crate::experiment::Silent
    }
}
