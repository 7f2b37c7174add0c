//! Writing a finished run: `manifest.json` (version, config as run, seed, samples, threads, wall
//! time and its split into transport, post-processing and writing, run statistics, every scalar estimate with its standard error) plus, per detector, its
//! outputs as its [`Registry`](crate::output::Registry) declares them: spectra (`.npy`, with
//! per-bin standard errors and the frequency axis), FMCW range and velocity estimates with a chirp
//! (`NAME_fmcw_estimates.csv`, see [`super::fmcw`]), images (`.exr`, `.npy`), an LDH camera's maps and
//! a lidar receiver's range–Doppler spectra. Data files are written first and the manifest last,
//! each atomically, through a [`DirWriter`]: the directory holds this run's files only, or is
//! marked incomplete.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Serialize;
use serde_json::Value;

use super::dir::DirWriter;
use super::{Entry, Writer};
use crate::detect::{DetectorKind, LATERAL_SCALAR, Scalar, Side};
use crate::error::Result;
use crate::experiment::{Experiment, Progress, RunOutput};
use crate::io::outdir::OutDir;
use crate::post::Finished;

/// What the manifest records about how the run was invoked.
#[derive(Debug, Clone)]
pub struct Invocation {
    /// Where the configuration came from (a path, or "built-in default").
    pub config_source: String,
    /// `--set` overrides in the order given.
    pub overrides: Vec<String>,
    /// Whether figures are written (`--no-figures`: none).
    pub figures: bool,
}

impl Default for Invocation {
    /// No source, no overrides, figures written (as by default on the command line).
    fn default() -> Self {
        Invocation { config_source: String::new(), overrides: Vec::new(), figures: true }
    }
}

/// `manifest.json`. Written with its keys sorted (as a JSON object, at every level).
#[derive(Debug, Clone, Serialize)]
pub struct Manifest {
    pub ohd_version: &'static str,
    pub name: String,
    pub config_source: String,
    pub overrides: Vec<String>,
    /// The configuration as run (after `--set`), as a table and as TOML text.
    pub config: toml::Table,
    pub config_toml: String,
    pub seed: u64,
    pub samples: u64,
    pub samples_requested: u64,
    pub batches: u64,
    pub main_output: MainOutput,
    pub target_error: Option<TargetEntry>,
    /// A run that ended early at its caller's request (the first Ctrl-C): the batches done of
    /// those planned. Its estimates and errors are those of the batches done; absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interrupted: Option<InterruptedEntry>,
    pub threads: usize,
    pub wall_seconds: f64,
    pub timing: Timing,
    pub run_statistics: RunStatistics,
    /// Each named medium once.
    pub media: BTreeMap<String, MediumEntry>,
    /// The scalar tallies, ROI values and derived numbers, and per detector (`detectors`) its
    /// power, out-of-range tallies and read-offs.
    pub estimates: BTreeMap<String, Entry>,
    /// Per detector: what its files hold (axes, units, layout).
    pub detectors: BTreeMap<String, DetectorEntry>,
    /// Per main image output: the median and 90th percentile of its per-pixel relative errors,
    /// and the file of the map.
    pub pixel_errors: BTreeMap<String, super::PixelErrorEntry>,
    /// The volume tally's grid and files (`[volume]`; absent without one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume: Option<super::volume::VolumeEntry>,
    /// `run.importance = "table"`: the importance table's files and bins.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub importance: Option<super::importance::ImportanceEntry>,
    /// Every output written, by file (a `.npy` name, or a JSON pointer into this manifest for a
    /// scalar): its kind, shape, units, axes, standard-error file and figure
    /// ([`super::OutputEntry`]).
    pub outputs: BTreeMap<String, super::OutputEntry>,
    /// Every file written, in order.
    pub files: Vec<String>,
    /// What the run could not get right ([`crate::post::warnings`]), `[]` when nothing.
    pub warnings: Vec<crate::post::Warning>,
}

impl Manifest {
    /// As a JSON value (keys sorted).
    pub fn json(&self) -> Value {
        serde_json::to_value(self).expect("a manifest serialises")
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct MainOutput {
    pub name: String,
    pub relative_error: Option<f64>,
}

/// How a run to a target error ended.
#[derive(Debug, Clone, Serialize)]
pub struct TargetEntry {
    pub output: String,
    pub target: f64,
    pub reached: Option<f64>,
    pub met: bool,
    pub rounds: u64,
    pub max_samples: u64,
}

/// How far an interrupted run got ([`Manifest::interrupted`]).
#[derive(Debug, Clone, Serialize)]
pub struct InterruptedEntry {
    pub batches: u64,
    pub planned_batches: u64,
}

#[derive(Debug, Clone, Serialize)]
pub struct RunStatistics {
    pub paths: u64,
    pub scattering_events: u64,
    pub events_per_second: f64,
    pub paths_per_second: f64,
    /// Paths traced from the pixels of camera-estimated detectors (besides `paths`).
    pub camera_paths: u64,
    pub null_collisions: u64,
    pub roulette_terminations: u64,
    pub truncated_paths: u64,
    pub non_finite: u64,
    pub speckle_seconds: f64,
    /// Weight of paths outside the spectra's frequency axes (total channel, every chirp).
    pub out_of_range_weight: f64,
    /// Whether the walk tracked the Doppler term and the optical path length.
    pub doppler: bool,
    pub path_length: bool,
}

#[derive(Debug, Clone, Serialize)]
pub struct MediumEntry {
    pub sigma_a_per_m: f64,
    pub sigma_s_per_m: f64,
    pub albedo: f64,
    pub optics: Value,
    /// A heterogeneous medium's density (σa and σs above are at density 1), else `null`.
    pub density: Value,
}

/// What one detector's files hold.
#[derive(Debug, Clone, Serialize)]
pub struct DetectorEntry {
    pub side: &'static str,
    /// How its scattered light was estimated (`"forward"` or `"camera"`; absent for a lidar).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimator: Option<&'static str>,
    /// With `estimator = "auto"`: the pilot's relative variance × work of each estimator (the
    /// lower was chosen).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimator_pilot: Option<crate::detect::AutoChoice>,
    /// With `estimator = "footprints"`: the pixels camera paths estimated.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub footprints: Option<FootprintsEntry>,
    /// Per part of a surface detector (`spectrum`, `fmcw`, `image`, `time`, `correlation`,
    /// `ldh`) or a lidar receiver (`lidar`): what its files hold ([`super::parts`]).
    #[serde(flatten)]
    pub parts: BTreeMap<&'static str, Value>,
}

/// The camera pixels of `estimator = "footprints"` (`NAME_camera_pixels.npy`).
#[derive(Debug, Clone, Serialize)]
pub struct FootprintsEntry {
    /// How many pixels camera paths estimated (the regions' footprints, their halo, the ROIs').
    pub camera_pixels: usize,
    pub halo_m: f64,
    /// Camera paths per forward path, as configured.
    pub camera_paths_per_forward_path: f64,
    /// Camera paths traced from each camera pixel over the run.
    pub camera_paths_per_pixel: u64,
    /// With `light_field = true`: the forward paths of the light field's pre-pass (its seed is
    /// the run's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub light_field_paths: Option<u64>,
}

/// Where a run's wall time went, seconds (`timing` in the manifest; like `wall_seconds`, the only
/// fields that differ between runs of the same configuration and seed).
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Timing {
    /// The Monte Carlo transport (`wall_seconds`; summed over the shards of a merged run).
    pub transport_seconds: f64,
    /// What the outputs need computed from the tallies after the transport: the LDH speckle and
    /// the lidar gate fits.
    pub postprocess_seconds: f64,
    /// Of which the lidar gate fits ([`super::lidar::retrieve_gates`]).
    pub gate_fit_seconds: f64,
    /// Writing the files (figures included) and the manifest.
    pub writing_seconds: f64,
}

impl Timing {
    /// The sum of several runs' timings (a scan's pointings).
    pub fn sum<'a>(all: impl IntoIterator<Item = &'a Timing>) -> Timing {
        all.into_iter().fold(Timing::default(), |a, t| Timing {
            transport_seconds: a.transport_seconds + t.transport_seconds,
            postprocess_seconds: a.postprocess_seconds + t.postprocess_seconds,
            gate_fit_seconds: a.gate_fit_seconds + t.gate_fit_seconds,
            writing_seconds: a.writing_seconds + t.writing_seconds,
        })
    }
}

/// Write all outputs of `out` into `dir` (created if needed, locked while written). Returns the
/// manifest as written.
pub fn write_run(
    dir: &Path,
    exp: &Experiment,
    out: &RunOutput,
    config: &toml::Table,
    inv: &Invocation,
) -> Result<Manifest> {
    write_run_with(&OutDir::create(dir)?, exp, out, config, inv, &crate::experiment::Silent)
}

/// [`write_run`], telling `progress` how far the post-processing is: its total set to the gates of
/// every lidar receiver, advanced by one per gate fitted.
pub fn write_run_with(
    dir: &OutDir,
    exp: &Experiment,
    out: &RunOutput,
    config: &toml::Table,
    inv: &Invocation,
    progress: &dyn Progress,
) -> Result<Manifest> {
    // As the run ran: its pilots' decisions applied.
    let exp = exp.decided(&out.decisions);
    let finished = Finished::new(&exp, out, progress)?;
    let open = || DirWriter::begin(dir, super::dir::Output::Run, &[]);
    let (writer, manifest, text) = write_run_to(open, &finished, config, inv)?;
    writer.finish(Some((super::dir::MANIFEST, text.as_bytes())))?;
    Ok(manifest)
}

/// [`write_run_with`] into memory: every file as `(name, bytes)` in the order written, the
/// manifest last ([`super::memory::Memory::files`]) — the bytes `ohd run --out` writes (the manifest's timings aside), which
/// [`super::memory::save`] writes into a directory as a run does.
pub fn write_run_memory(
    exp: &Experiment,
    out: &RunOutput,
    config: &toml::Table,
    inv: &Invocation,
    progress: &dyn Progress,
) -> Result<(Manifest, super::memory::Memory)> {
    let exp = exp.decided(&out.decisions);
    let finished = Finished::new(&exp, out, progress)?;
    let open = || Ok(super::memory::Memory::default());
    let (mut memory, manifest, text) = write_run_to(open, &finished, config, inv)?;
    memory.files.push((super::dir::MANIFEST.to_string(), text.into_bytes()));
    Ok((manifest, memory))
}

/// The one writer of a run's outputs: the files of the checked and post-processed run `f` into
/// the sink `open` makes (opened only now, when nothing can fail before writing); returns the
/// sink, the manifest and its text, for the caller to write last.
fn write_run_to<S: super::Sink>(
    open: impl FnOnce() -> Result<S>,
    f: &Finished,
    config: &toml::Table,
    inv: &Invocation,
) -> Result<(S, Manifest, String)> {
    let (exp, out, stderr) = (f.exp, f.out, &f.stderr);
    let t = std::time::Instant::now();
    let mut writer = open()?;
    let mut put = |name: String, bytes: Vec<u8>| -> Result<()> { writer.put_file(name, bytes) };
    let mut w = Writer::new(&mut put, &out.layout.registry, out.estimates.mean(), stderr);
    w.figures = inv.figures;
    // The cameras' masks of the regions' footprints, before their images (which are split by them).
    for (i, d) in exp.detectors.iter().enumerate() {
        let Some(im) = d.surface().and_then(|s| s.image()) else { continue };
        // The layout's (its tail check pools the same pixels).
        let Some(mask) = out.layout.detectors[i].tail.as_ref().map(|t| &t.mask) else { continue };
        let written =
            crate::output::rows_reversed(&mask.iter().map(|&m| f64::from(u8::from(m))).collect::<Vec<_>>(), im.nx);
        let file = format!("{}_region_mask.npy", d.name);
        w.put(file.clone(), crate::io::formats::npy::to_bytes(&[im.ny, im.nx], &written))?;
        // On the image's axes.
        let axes =
            out.layout.detectors[i].image().map_or_else(Vec::new, |slot| out.layout.registry.at(slot).axes.clone());
        let entry = super::OutputEntry::made(
            "region_mask",
            &[im.ny, im.nx],
            "1 (1: the pixel's vertical line meets a region; row 0 = the largest y)",
            axes,
        );
        w.table.insert(file.clone(), entry);
        w.masks.insert(i, (file, written.iter().map(|&m| m != 0.0).collect()));
    }
    // The camera pixels of `estimator = "footprints"`.
    for (i, d) in exp.detectors.iter().enumerate() {
        let (Some(im), Some(fp)) =
            (d.surface().and_then(|s| s.image()), d.surface().and_then(|s| s.footprints.as_ref()))
        else {
            continue;
        };
        let written =
            crate::output::rows_reversed(&fp.mask.iter().map(|&m| f64::from(u8::from(m))).collect::<Vec<_>>(), im.nx);
        let file = format!("{}_camera_pixels.npy", d.name);
        w.put(file.clone(), crate::io::formats::npy::to_bytes(&[im.ny, im.nx], &written))?;
        let entry = super::OutputEntry::made(
            "camera_pixels",
            &[im.ny, im.nx],
            "1 (1: camera paths estimated the pixel, estimator = \"footprints\"; row 0 = the largest y)",
            out.layout.detectors[i].image().map_or_else(Vec::new, |slot| out.layout.registry.at(slot).axes.clone()),
        );
        w.table.insert(file, entry);
    }
    w.speckle = exp.m0_speckle(&out.layout).collect();
    w.tails = out.tail_checks();
    w.paths = out.paths() as f64;
    let reg = &out.layout.registry;
    let mut estimates: BTreeMap<String, Entry> =
        Scalar::ALL.iter().map(|&s| (s.name().to_string(), Entry::Estimate(w.estimate(reg.at(s as usize))))).collect();
    if let Some(slot) = out.layout.lateral {
        estimates.insert(LATERAL_SCALAR.to_string(), Entry::Estimate(w.estimate(reg.at(slot))));
    }
    let mut det_estimates = BTreeMap::new();
    let mut det_info = BTreeMap::new();
    let mut out_of_range_total = 0.0;
    for (i, d) in exp.detectors.iter().enumerate() {
        let mut de = BTreeMap::new();
        let lay = &out.layout.detectors[i];
        let power = w.estimate(reg.at(lay.power));
        de.insert("detected_power".to_string(), Entry::Estimate(power));
        let mut info = DetectorEntry {
            side: if d.side() == Side::Top { "top" } else { "bottom" },
            estimator: d.surface().map(|s| s.estimator().name()),
            estimator_pilot: out.decisions.estimator(i).and_then(|e| e.figures),
            footprints: d.surface().and_then(|s| s.footprints.as_deref()).map(|fp| FootprintsEntry {
                camera_pixels: fp.pixels.len(),
                halo_m: fp.halo,
                camera_paths_per_forward_path: fp.camera_paths,
                camera_paths_per_pixel: fp.paths_per_pixel(out.paths_per_batch) * out.estimates.batches() as u64,
                light_field_paths: fp.light_field,
            }),
            parts: BTreeMap::new(),
        };
        match &d.kind {
            DetectorKind::Surface(s) => {
                let mut cx = super::parts::Context {
                    i,
                    name: &d.name,
                    surface: s,
                    finished: f,
                    detector: &mut de,
                    estimates: &mut estimates,
                    entries: &mut info.parts,
                    out_of_range: 0.0,
                };
                for part in &lay.parts {
                    super::parts::write_part(&mut w, part, &mut cx)?;
                }
                out_of_range_total += cx.out_of_range;
            }
            DetectorKind::Lidar(spec) => {
                let ll = lay.lidar.as_ref().expect("a lidar receiver's layout");
                let entry = super::lidar::write_lidar(&mut w, &d.name, spec, ll, &f.retrievals[i])?;
                info.parts.insert("lidar", entry);
            }
        }
        w.rest(i, &mut de)?;
        det_estimates.insert(d.name.clone(), Entry::Group(de));
        det_info.insert(d.name.clone(), info);
    }
    let volume = match &exp.volume {
        Some(g) => {
            let slots = out.layout.volume.expect("a volume tally lays out its outputs");
            Some(super::volume::write_volume(&mut w, g, slots, exp.source.position.y)?)
        }
        None => None,
    };
    let asked = exp.plan.importance != crate::transport::windows::Importance::Off;
    let decided = out.decisions.importance.as_ref();
    let table = || {
        out.importance.clone().or_else(|| decided.map(|d| d.table.as_ref().clone())).or_else(|| exp.importance_table())
    };
    let importance = match asked.then(table).flatten() {
        Some(t) => {
            let name = &exp.detectors[t.detector].name;
            let mut entry = super::importance::write_importance(&mut w, &t, &exp.scene, name)?;
            let steering = out.decisions.steering(&exp.plan);
            entry.auto = decided.and_then(|d| d.figures);
            entry.windows = steering != crate::transport::windows::Importance::Off;
            entry.guided = steering == crate::transport::windows::Importance::Guided;
            Some(entry)
        }
        None => None,
    };
    let pixel_errors = std::mem::take(&mut w.pixel_errors);
    let table = std::mem::take(&mut w.table);
    drop(w);
    let files = writer.written();
    let outputs = super::with_figures(table, &files);
    if !det_estimates.is_empty() {
        estimates.insert("detectors".into(), Entry::Group(det_estimates));
    }

    // Each named medium once (a medium used by several layers appears once per use in the scene).
    let mut media = BTreeMap::new();
    for m in &exp.scene.media {
        media.entry(m.name.clone()).or_insert_with(|| MediumEntry {
            sigma_a_per_m: m.sigma_a(),
            sigma_s_per_m: m.sigma_s(),
            albedo: m.albedo(),
            optics: serde_json::to_value(&m.info).unwrap_or(Value::Null),
            density: m.heterogeneity().map_or(Value::Null, |h| serde_json::to_value(&h.info).unwrap_or(Value::Null)),
        });
    }

    let st = &out.stats;
    let wall = out.wall_seconds.max(1e-9);
    let finite = |v: f64| v.is_finite().then_some(v);
    let manifest = Manifest {
        ohd_version: env!("CARGO_PKG_VERSION"),
        name: exp.name.clone(),
        config_source: inv.config_source.clone(),
        overrides: inv.overrides.clone(),
        config: config.clone(),
        config_toml: toml::to_string(config).unwrap_or_default(),
        seed: exp.plan.seed,
        samples: out.samples(),
        samples_requested: exp.plan.requested_samples,
        batches: out.batches,
        main_output: MainOutput { name: out.main_output.0.clone(), relative_error: finite(out.main_output.1) },
        target_error: out.target.as_ref().map(|t| TargetEntry {
            output: t.output.clone(),
            target: t.target,
            reached: finite(t.reached),
            met: t.met,
            rounds: t.rounds,
            max_samples: t.max_samples,
        }),
        interrupted: out.interrupted.map(|planned| InterruptedEntry { batches: out.batches, planned_batches: planned }),
        threads: out.threads,
        wall_seconds: out.wall_seconds,
        timing: Timing {
            transport_seconds: out.wall_seconds,
            postprocess_seconds: f.speckle_seconds + f.gate_fit_seconds,
            gate_fit_seconds: f.gate_fit_seconds,
            // Up to the manifest itself, whose writing is not timed (it holds the time).
            writing_seconds: t.elapsed().as_secs_f64(),
        },
        run_statistics: RunStatistics {
            paths: st.paths,
            scattering_events: st.scattering_events,
            events_per_second: st.scattering_events as f64 / wall,
            paths_per_second: st.paths as f64 / wall,
            camera_paths: exp.camera_paths_per_batch() * out.batches,
            null_collisions: st.null_collisions,
            roulette_terminations: st.roulette_terminations,
            truncated_paths: st.truncated_paths,
            non_finite: st.non_finite,
            speckle_seconds: f.speckle_seconds,
            out_of_range_weight: out_of_range_total,
            doppler: exp.needs_doppler(),
            path_length: exp.needs_length(),
        },
        media,
        estimates,
        detectors: det_info,
        pixel_errors,
        volume,
        importance,
        outputs,
        files,
        warnings: f.warnings.clone(),
    };
    let text = serde_json::to_string_pretty(&manifest.json()).expect("a JSON value serialises");
    Ok((writer, manifest, text))
}
