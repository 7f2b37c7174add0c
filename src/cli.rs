//! Argument parsing and the `run` / `check` commands.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use ohd::error::Error;
use ohd::experiment::{Experiment, Progress};
use ohd::io::manifest::{Invocation, write_run};

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
    Run {
        /// Experiment file (TOML). Omit to run the built-in default (configs/default.toml).
        config: Option<PathBuf>,
        /// Output directory [default: out/<config name>].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Number of paths (same as --set run.samples=N).
        #[arg(long)]
        samples: Option<u64>,
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
        /// No progress bar.
        #[arg(long, short)]
        quiet: bool,
    },
    /// Validate an experiment and print it as resolved (SI units), without running it.
    Check {
        /// Experiment file (TOML). Omit to check the built-in default.
        config: Option<PathBuf>,
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
    },
}

/// Read the configuration text and a name for it.
fn read_config(config: Option<&Path>) -> Result<(String, String, String), Error> {
    match config {
        None => {
            Ok((ohd::DEFAULT_CONFIG.to_string(), "built-in default (configs/default.toml)".into(), "default".into()))
        }
        Some(p) => {
            let text = std::fs::read_to_string(p).map_err(|source| Error::Read { path: p.to_path_buf(), source })?;
            let stem = p.file_stem().map_or("experiment".into(), |s| s.to_string_lossy().into_owned());
            Ok((text, p.display().to_string(), stem))
        }
    }
}

fn load(config: Option<&Path>, sets: &[String]) -> Result<(toml::Table, Experiment, String, String), Error> {
    let (text, origin, stem) = read_config(config)?;
    let (table, exp) = ohd::config::load(&text, &origin, sets)?;
    Ok((table, exp, origin, stem))
}

struct Bar(indicatif::ProgressBar);

impl Progress for Bar {
    fn advance(&self, paths: u64) {
        self.0.inc(paths);
    }
}

fn fail(e: &Error) -> ExitCode {
    eprintln!("ohd: {e}");
    ExitCode::from(if e.is_input_error() { 2 } else { 1 })
}

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Check { config, set } => match load(config.as_deref(), &set) {
            Ok((_, exp, origin, _)) => {
                print!("{}", describe(&exp, &origin));
                ExitCode::SUCCESS
            }
            Err(e) => fail(&e),
        },
        Command::Run { config, out, samples, seed, threads, mut set, quiet } => {
            set.extend(samples.map(|v| format!("run.samples={v}")));
            set.extend(seed.map(|v| format!("run.seed={v}")));
            set.extend(threads.map(|v| format!("run.threads={v}")));
            let (table, exp, origin, stem) = match load(config.as_deref(), &set) {
                Ok(x) => x,
                Err(e) => return fail(&e),
            };
            let dir = out.unwrap_or_else(|| PathBuf::from("out").join(&stem));
            let output = if !quiet && std::io::stderr().is_terminal() {
                let bar = indicatif::ProgressBar::new(exp.plan.samples());
                bar.set_style(
                    indicatif::ProgressStyle::with_template(
                        "{spinner} {bar:40} {percent:>3}% {human_pos}/{human_len} paths, ETA {eta}",
                    )
                    .expect("valid template"),
                );
                let bar = Bar(bar);
                let o = exp.run(&bar);
                bar.0.finish_and_clear();
                o
            } else {
                exp.run(&ohd::experiment::Silent)
            };
            let inv = Invocation { config_source: origin, overrides: set };
            match write_run(&dir, &exp, &output, &table, &inv) {
                Ok(manifest) => {
                    let est = &manifest["estimates"];
                    eprintln!(
                        "ohd: {} paths in {:.2} s ({:.0} paths/ms) → {}",
                        exp.plan.samples(),
                        output.wall_seconds,
                        exp.plan.samples() as f64 / output.wall_seconds.max(1e-9) / 1e3,
                        dir.display()
                    );
                    for k in ["reflectance_specular", "reflectance_diffuse", "transmittance_total", "absorbed_fraction"]
                    {
                        eprintln!(
                            "  {k:<24} {:.6} ± {:.6}",
                            est[k]["value"].as_f64().unwrap_or(f64::NAN),
                            est[k]["stderr"].as_f64().unwrap_or(f64::NAN)
                        );
                    }
                    ExitCode::SUCCESS
                }
                Err(e) => fail(&e),
            }
        }
    }
}

/// A human-readable account of the resolved experiment.
fn describe(exp: &Experiment, origin: &str) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let mm = |v: f64| v * 1e3;
    let _ = writeln!(s, "experiment \"{}\" from {origin}: valid", exp.name);
    let src = &exp.source;
    let _ = writeln!(
        s,
        "source: λ0 = {:.1} nm, {:?}, from {:?} mm along {:?}{}",
        src.wavelength * 1e9,
        src.profile,
        (src.position * 1e3).to_array(),
        src.direction.to_array(),
        src.chirp.map_or(String::new(), |c| format!(", chirp B = {} Hz over T = {} s", c.bandwidth, c.duration))
    );
    let _ = writeln!(s, "ambient: n above = {}, n below = {}", exp.scene.n_above, exp.scene.n_below);
    let _ = writeln!(s, "media:");
    for m in &exp.scene.media {
        let _ = writeln!(
            s,
            "  {:<12} σa = {:.4} /mm, σs = {:.4} /mm, albedo = {:.5}, phase {:?}, velocity {:?}",
            m.name,
            m.sigma_a() / 1e3,
            m.sigma_s() / 1e3,
            m.albedo(),
            m.phase,
            m.velocity
        );
    }
    let _ = writeln!(s, "layers:");
    for l in &exp.scene.layers {
        let _ = writeln!(
            s,
            "  {:<12} z = {:.4} … {:.4} mm, n = {}, medium {}, majorant {:.4} /mm, {} region(s)",
            l.name,
            mm(l.z_top),
            mm(l.z_bottom),
            l.n,
            exp.scene.media[l.medium].name,
            l.majorant / 1e3,
            l.regions.len()
        );
    }
    if !exp.scene.regions.is_empty() {
        let _ = writeln!(s, "regions:");
        for r in &exp.scene.regions {
            let _ = writeln!(
                s,
                "  {:<12} in {}, medium {}, {:?}",
                r.name, exp.scene.layers[r.layer].name, exp.scene.media[r.medium].name, r.shape
            );
        }
    }
    let _ = writeln!(s, "detectors:");
    for d in &exp.detectors {
        let _ = writeln!(
            s,
            "  {:<12} {:?} side, area {:?}, acceptance cos ≥ {:.4} about {:?}, plane at {} mm{}{}",
            d.name,
            d.side,
            d.area,
            d.cos_acceptance,
            d.axis.to_array(),
            mm(d.distance),
            d.spectrum.as_ref().map_or(String::new(), |sp| format!(
                ", spectrum {} bins over [{}, {}) Hz, split by order {:?}, by Doppler events {:?}",
                sp.axis.bins, sp.axis.f_min, sp.axis.f_max, sp.by_order, sp.by_doppler_events
            )),
            d.image.map_or(String::new(), |im| format!(", image {}×{} px", im.nx, im.ny))
        );
    }
    if exp.detectors.is_empty() {
        let _ = writeln!(s, "  (none: only the scalar tallies)");
    }
    let p = &exp.plan;
    let _ = writeln!(
        s,
        "run: {} paths ({} batches × {}), seed {}, {} thread(s), tracking {:?}, walk with{} Doppler, with{} path length",
        p.samples(),
        p.batches,
        p.paths_per_batch,
        p.seed,
        p.effective_threads(),
        p.walk.tracking,
        if exp.needs_doppler() { "" } else { "out" },
        if exp.needs_length() { "" } else { "out" }
    );
    let _ = writeln!(s, "memory estimate: {:.1} MiB of tallies", exp.memory_estimate() as f64 / (1 << 20) as f64);
    s
}
