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

    use ohd::io::table::{Normalisation, TableOptics, phase_table_text};
    use ohd::mie::{MieSolution, angle_grid};

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
            ohd::medium::relative_sphere(d * 1e-6, np, kp, nm, wl * 1e-9)
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
        ohd::io::write_atomic(path, text.as_bytes())?;
    }
    let json = serde_json::json!({ "x": x, "qext": q.qext, "qsca": q.qsca, "qback": q.qback, "g": q.g });
    println!("{json}");
    Ok(())
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
        Command::Mie(a) => match mie(&a) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => fail(&e),
        },
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
            let inv = Invocation { config_source: origin, overrides: set };
            let result = if exp.source.pointings.len() > 1 {
                run_scan(&exp, &dir, &table, &inv, quiet)
            } else {
                run_one(&exp, &dir, &table, &inv, quiet).map(|_| ())
            };
            match result {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => fail(&e),
            }
        }
    }
}

/// Run `exp`, write its outputs into `dir` and report on stderr.
fn run_one(
    exp: &Experiment,
    dir: &Path,
    table: &toml::Table,
    inv: &Invocation,
    quiet: bool,
) -> Result<ohd::experiment::RunOutput, Error> {
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
    let manifest = write_run(dir, exp, &output, table, inv)?;
    let est = &manifest["estimates"];
    eprintln!(
        "ohd: {} paths in {:.2} s ({:.0} paths/ms) → {}",
        exp.plan.samples(),
        output.wall_seconds,
        exp.plan.samples() as f64 / output.wall_seconds.max(1e-9) / 1e3,
        dir.display()
    );
    for k in ["reflectance_specular", "reflectance_diffuse", "transmittance_total", "absorbed_fraction"] {
        eprintln!(
            "  {k:<24} {:.6} ± {:.6}",
            est[k]["value"].as_f64().unwrap_or(f64::NAN),
            est[k]["stderr"].as_f64().unwrap_or(f64::NAN)
        );
    }
    for d in &exp.detectors {
        let (e, fmcw) = (&est["detectors"][&d.name], &manifest["detectors"][&d.name]["fmcw"]);
        if let (Some(r), Some(v)) = (e["range_m"].as_f64(), e["radial_velocity_m_per_s"].as_f64()) {
            eprintln!(
                "  {}: FMCW range {r:.4} m, radial velocity {v:+.4} m/s (bins {:.4} m, {:.4} m/s)",
                d.name,
                e["range_bin_m"].as_f64().unwrap_or(f64::NAN),
                e["velocity_bin_m_per_s"].as_f64().unwrap_or(f64::NAN)
            );
        }
        if let Some(note) = fmcw["note"].as_str() {
            eprintln!("  {}: FMCW {note}", d.name);
        }
    }
    Ok(output)
}

/// A scan: one run per pointing into `dir/pointing_NN`, then the VAD wind per range gate.
fn run_scan(exp: &Experiment, dir: &Path, table: &toml::Table, inv: &Invocation, quiet: bool) -> Result<(), Error> {
    let pointings = &exp.source.pointings;
    let (mut runs, mut velocities) = (Vec::new(), Vec::new());
    let mut ranges = Vec::new();
    for (i, p) in pointings.iter().enumerate() {
        let name = format!("pointing_{i:02}");
        eprintln!("ohd: pointing {i}: azimuth {}°, elevation {}°", p.azimuth_deg, p.elevation_deg);
        let e = exp.pointed(p);
        let output = run_one(&e, &dir.join(&name), table, inv, quiet)?;
        if let Some(v) = ohd::scan::gate_peak_velocities(&e, &output) {
            velocities.push(v);
        }
        if let Some(l) = e.detectors.iter().find_map(|d| d.lidar.as_ref()) {
            ranges = (0..l.gates).map(|g| l.gate_range(g)).collect();
        }
        runs.push(name);
    }
    if velocities.len() == pointings.len() {
        let gates = ohd::scan::vad_per_gate(pointings, exp.source.position.z, &ranges, &velocities);
        ohd::io::scan::write_scan(dir, pointings, &runs, &gates)?;
        eprintln!("ohd: VAD wind per gate → {}", dir.join("vad.csv").display());
    }
    Ok(())
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
    if src.divergence > 0.0 {
        let _ = writeln!(s, "  divergence (1/e² half-angle) {:.1} µrad", src.divergence * 1e6);
    }
    if src.pointings.len() > 1 {
        let list: Vec<String> =
            src.pointings.iter().map(|p| format!("({}°, {}°)", p.azimuth_deg, p.elevation_deg)).collect();
        let _ = writeln!(s, "  scan of {} pointings (azimuth, elevation): {}", list.len(), list.join(", "));
    }
    let _ = writeln!(s, "ambient: n above = {}, n below = {}", exp.scene.n_above, exp.scene.n_below);
    let _ = writeln!(s, "media:");
    let mut shown = std::collections::BTreeSet::new();
    for m in exp.scene.media.iter().filter(|m| shown.insert(m.name.clone())) {
        let phase = match &m.population().phase {
            ohd::phase::PhaseFunction::Tabulated(t) => format!("{t:?}"),
            p => format!("{p:?}"),
        };
        let _ = writeln!(
            s,
            "  {:<12} σa = {:.6e} /m, σs = {:.6e} /m, albedo = {:.5}, g = {:.6}, phase {phase}, velocity {}",
            m.name,
            m.sigma_a(),
            m.sigma_s(),
            m.albedo(),
            m.info.g,
            m.population().velocity.describe()
        );
        if m.populations().len() > 1 {
            for p in m.populations() {
                let _ = writeln!(
                    s,
                    "  {:<14} population {}: σs = {:.6e} /m, g = {:.4}, velocity {}",
                    "",
                    p.name,
                    p.sigma_s,
                    p.phase.mean_cosine(),
                    p.velocity.describe()
                );
            }
        }
        if let Some(h) = m.heterogeneity() {
            let d = &h.info;
            let _ = writeln!(
                s,
                "  {:<12} density {} in [{}, {}] (σ above at density 1), majorant {:?}{}{}{}{}",
                "",
                d.kind,
                d.min,
                d.max,
                d.majorant,
                d.voxels.map_or(String::new(), |v| format!(", voxels {v:?}")),
                d.majorant_cells.map_or(String::new(), |c| format!(", majorant cells {c:?}")),
                if d.negative_voxels_clamped > 0 {
                    format!(", {} negative voxels clamped to 0", d.negative_voxels_clamped)
                } else {
                    String::new()
                },
                if d.albedo_grid { ", albedo grid" } else { "" }
            );
        }
        if let Some(p) = &m.info.particles {
            let _ = writeln!(
                s,
                "  {:<12} Mie: σs = {:.6e} /m, σa = {:.6e} /m, g = {:.6}, backscatter β = {:.4e} /(m sr), lidar ratio {:.2} sr",
                "", p.sigma_s, p.sigma_a, p.g, p.backscatter, p.lidar_ratio
            );
            for c in &p.components {
                let _ = writeln!(
                    s,
                    "  {:<14} {}: N = {:.4e} /m³, volume fraction {:.4e}, r_eff = {:.4} µm, σs = {:.4e} /m, σa = {:.4e} /m, g = {:.4}",
                    "",
                    c.name,
                    c.number_density,
                    c.volume_fraction,
                    c.effective_radius * 1e6,
                    c.sigma_s,
                    c.sigma_a,
                    c.g
                );
            }
        }
    }
    let _ = writeln!(s, "layers:");
    for l in &exp.scene.layers {
        let _ = writeln!(
            s,
            "  {:<12} z = {:.4} … {:.4} mm, n = {}, medium {}, majorant {:.4} /mm, {} region(s){}",
            l.name,
            mm(l.z_top),
            mm(l.z_bottom),
            l.n,
            exp.scene.media[l.medium].name,
            l.majorant / 1e3,
            l.regions.len(),
            if l.heterogeneous { ", heterogeneous" } else { "" }
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
        if let Some(l) = &d.lidar {
            let _ = writeln!(
                s,
                "  {:<12} lidar: {} gates of {} samples at {:.3} MHz from {:.1} m, {}-point DFT, pulse {:.1} ns, {:.3e} J, η = {} × {}: shot-noise floor {:.4e} per bin ({:.1} dB)",
                "",
                l.gates,
                l.gate_points,
                l.sample_rate * 1e-6,
                0.5 * ohd::SPEED_OF_LIGHT * l.first_sample_time,
                l.fft_points,
                l.pulse_fwhm * 1e9,
                l.pulse_energy,
                l.quantum_efficiency,
                l.heterodyne_efficiency,
                l.noise_floor_per_bin(),
                10.0 * l.noise_floor_per_bin().log10()
            );
        }
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
    let _ = writeln!(
        s,
        "memory estimate: {:.1} MiB of tallies (budget {:.1} GiB)",
        exp.memory_estimate() as f64 / (1 << 20) as f64,
        p.memory_budget as f64 / (1u64 << 30) as f64
    );
    s
}
