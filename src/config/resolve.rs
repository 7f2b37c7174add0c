//! The one step from the schema to validated SI runtime objects, and the only producer of
//! configuration errors. Each check names the key path, the value and the expected range and unit.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use glam::DVec3;

use super::schema::*;
use super::units::unit_of;
use crate::detect::{
    Area, Detector, DetectorKind, ImageSpec, LdhSpec, LidarSpec, Roi, Side, SpeckleSpec, SpectrumSpec, Surface,
};
use crate::error::ConfigError;
use crate::experiment::{Experiment, RunPlan};
use crate::flow::{FallSpeeds, VON_KARMAN, VelocityField, WindProfile, atlas_fall_speed};
use crate::io::formats::table::read_phase_table;
use crate::medium::density::{
    CellSize, Density, DensityInfo, GridDensity, GridError, GridField, Interpolation, MajorantKind, MajorantSpec,
    Placement, Ramp,
};
use crate::medium::grid::VoxelGrid;
use crate::medium::{
    Heterogeneity, Layer, MAX_REGIONS_PER_LAYER, Medium, MediumInfo, Motion, ParticleOptics, Population, Region, Scene,
    Shape, TableInfo, mixture_optics, stokes_einstein,
};
use crate::mie::{Concentration, DEFAULT_SIZE_POINTS, EnsembleSpec, Packing, SizeDistribution};
use crate::phase::{HenyeyGreenstein, PhaseFunction, TabulatedPhase};
use crate::source::{Chirp, Pointing, Profile, Source};
use crate::spectrum::{FrequencyAxis, Stft, Window};
use crate::transport::{Tracking, WalkSettings};

type R<T> = Result<T, ConfigError>;

fn err<T>(path: impl Into<String>, msg: impl Into<String>) -> R<T> {
    Err(ConfigError::new(path, msg))
}

fn join(prefix: &str, key: &str) -> String {
    if prefix.is_empty() { key.to_string() } else { format!("{prefix}.{key}") }
}

/// A quantity as given: its SI value, the key path it came from and the number as written.
type Given = (f64, String, f64);

/// A quantity that may be given under one of several unit-suffixed keys.
fn pick(prefix: &str, options: &[(&str, Option<f64>, f64)]) -> R<Option<Given>> {
    let given: Vec<_> = options.iter().filter(|o| o.1.is_some()).collect();
    match given.as_slice() {
        [] => Ok(None),
        [(key, Some(v), scale)] => {
            let path = join(prefix, key);
            if v.is_nan() {
                return err(path, "= nan: expected a number");
            }
            Ok(Some((v * scale, path, *v)))
        }
        _ => err(
            prefix.to_string(),
            format!("give only one of {}", given.iter().map(|o| o.0).collect::<Vec<_>>().join(", ")),
        ),
    }
}

fn require(prefix: &str, options: &[(&str, Option<f64>, f64)], what: &str) -> R<Given> {
    pick(prefix, options)?.map_or_else(
        || {
            err(
                prefix.to_string(),
                format!("missing {what}: give one of {}", options.iter().map(|o| o.0).collect::<Vec<_>>().join(", ")),
            )
        },
        Ok,
    )
}

/// Same as [`pick`] for fixed-size arrays.
fn pick_arr<const N: usize>(prefix: &str, options: &[(&str, Option<[f64; N]>, f64)]) -> R<Option<([f64; N], String)>> {
    let given: Vec<_> = options.iter().filter(|o| o.1.is_some()).collect();
    match given.as_slice() {
        [] => Ok(None),
        [(key, Some(v), scale)] => {
            let path = join(prefix, key);
            if v.iter().any(|x| !x.is_finite()) {
                return err(path, format!("= {v:?}: expected finite numbers"));
            }
            Ok(Some((v.map(|x| x * scale), path)))
        }
        _ => err(
            prefix.to_string(),
            format!("give only one of {}", given.iter().map(|o| o.0).collect::<Vec<_>>().join(", ")),
        ),
    }
}

fn require_arr<const N: usize>(
    prefix: &str,
    options: &[(&str, Option<[f64; N]>, f64)],
    what: &str,
) -> R<([f64; N], String)> {
    pick_arr(prefix, options)?.map_or_else(
        || {
            err(
                prefix.to_string(),
                format!("missing {what}: give one of {}", options.iter().map(|o| o.0).collect::<Vec<_>>().join(", ")),
            )
        },
        Ok,
    )
}

fn positive(v: Given, what: &str) -> R<f64> {
    if v.0.is_finite() && v.0 > 0.0 {
        Ok(v.0)
    } else {
        let unit = unit_of(&v.1);
        err(v.1, format!("= {}: expected {what} > 0 {unit}", v.2))
    }
}

fn non_negative(v: Given, what: &str) -> R<f64> {
    if v.0.is_finite() && v.0 >= 0.0 {
        Ok(v.0)
    } else {
        let unit = unit_of(&v.1);
        err(v.1, format!("= {}: expected {what} ≥ 0 {unit}", v.2))
    }
}

fn unit_vector(path: &str, v: [f64; 3]) -> R<DVec3> {
    let d = DVec3::from_array(v);
    if !d.is_finite() || d.length() < 1e-12 {
        return err(path, format!("= {v:?}: expected a non-zero direction vector [x, y, z]"));
    }
    Ok(d.normalize())
}

fn index_of_refraction(path: &str, n: f64) -> R<f64> {
    if n.is_finite() && (1.0..=10.0).contains(&n) {
        Ok(n)
    } else {
        err(path, format!("= {}: expected a refractive index in [1, 10]", n))
    }
}

const LENGTH_UNITS: [(&str, f64); 3] = [("um", 1e-6), ("mm", 1e-3), ("m", 1.0)];

fn length_opts<'a>(
    name: &str,
    um: Option<f64>,
    mm: Option<f64>,
    m: Option<f64>,
    keys: &'a mut Vec<String>,
) -> Vec<(&'a str, Option<f64>, f64)> {
    *keys = LENGTH_UNITS.iter().map(|(u, _)| format!("{name}_{u}")).collect();
    vec![(keys[0].as_str(), um, 1e-6), (keys[1].as_str(), mm, 1e-3), (keys[2].as_str(), m, 1.0)]
}

fn length_arr_opts<'a, const N: usize>(
    name: &str,
    um: Option<[f64; N]>,
    mm: Option<[f64; N]>,
    m: Option<[f64; N]>,
    keys: &'a mut Vec<String>,
) -> Vec<(&'a str, Option<[f64; N]>, f64)> {
    *keys = LENGTH_UNITS.iter().map(|(u, _)| format!("{name}_{u}")).collect();
    vec![(keys[0].as_str(), um, 1e-6), (keys[1].as_str(), mm, 1e-3), (keys[2].as_str(), m, 1.0)]
}

fn length(prefix: &str, name: &str, um: Option<f64>, mm: Option<f64>, m: Option<f64>) -> R<Option<Given>> {
    let mut keys = Vec::new();
    let opts = length_opts(name, um, mm, m, &mut keys);
    pick(prefix, &opts)
}

fn length_req(prefix: &str, name: &str, um: Option<f64>, mm: Option<f64>, m: Option<f64>) -> R<Given> {
    let mut keys = Vec::new();
    let opts = length_opts(name, um, mm, m, &mut keys);
    require(prefix, &opts, name)
}

fn length_arr<const N: usize>(
    prefix: &str,
    name: &str,
    um: Option<[f64; N]>,
    mm: Option<[f64; N]>,
    m: Option<[f64; N]>,
) -> R<Option<([f64; N], String)>> {
    let mut keys = Vec::new();
    let opts = length_arr_opts(name, um, mm, m, &mut keys);
    pick_arr(prefix, &opts)
}

fn length_arr_req<const N: usize>(
    prefix: &str,
    name: &str,
    um: Option<[f64; N]>,
    mm: Option<[f64; N]>,
    m: Option<[f64; N]>,
) -> R<([f64; N], String)> {
    let mut keys = Vec::new();
    let opts = length_arr_opts(name, um, mm, m, &mut keys);
    require_arr(prefix, &opts, name)
}

/// A required frequency given as `NAME_hz`, `NAME_khz`, `NAME_mhz` or `NAME_ghz` (values in that order).
fn frequency(prefix: &str, name: &str, values: [Option<f64>; 4], what: &str) -> R<Given> {
    let keys = ["hz", "khz", "mhz", "ghz"].map(|u| format!("{name}_{u}"));
    let scales = [1.0, 1e3, 1e6, 1e9];
    let opts: Vec<(&str, Option<f64>, f64)> = (0..4).map(|i| (keys[i].as_str(), values[i], scales[i])).collect();
    require(prefix, &opts, what)
}

/// Resolve a deserialised experiment file into a validated experiment; files it names are found
/// relative to the working directory.
pub fn resolve(f: &ExperimentFile) -> R<Experiment> {
    resolve_in(f, Path::new("."))
}

/// As [`resolve`], with files named by the configuration found relative to `base`.
pub fn resolve_in(f: &ExperimentFile, base: &Path) -> R<Experiment> {
    let plan = resolve_run(&f.run)?;
    let source = resolve_source(&f.source)?;
    let n_above = index_of_refraction("ambient.n_above", f.ambient.n_above.unwrap_or(1.0))?;
    let n_below = index_of_refraction("ambient.n_below", f.ambient.n_below.unwrap_or(n_above))?;
    let ctx = Ctx { base, wavelength: source.wavelength, files: GridFiles::default() };
    let scene = resolve_scene(f, n_above, n_below, &ctx)?;
    let mut detectors = resolve_detectors(&f.detectors, &scene)?;
    for (i, d) in f.detectors.iter().enumerate() {
        if let Some(l) = &d.lidar {
            let path = format!("detectors[{i}].lidar");
            if detectors.iter().any(|o| o.lidar().is_some()) {
                return err(path, "only one detector may be a lidar receiver");
            }
            if source.chirp.is_some() {
                return err(path, "a pulsed lidar receiver needs a single-frequency laser: remove source.chirp");
            }
            let spec = resolve_lidar(&path, l, &source, &scene)?;
            let given = [
                ("side", d.side.is_some()),
                ("area", d.area.is_some()),
                ("acceptance_half_angle_deg", d.acceptance_half_angle_deg.is_some()),
                ("axis", d.axis.is_some()),
                ("include_specular", d.include_specular.is_some()),
                ("next_event", d.next_event.is_some()),
                ("spectrum", d.spectrum.is_some()),
                ("image", d.image.is_some()),
                ("ldh", d.ldh.is_some()),
            ];
            if let Some((key, _)) = given.iter().find(|g| g.1) {
                return err(
                    format!("detectors[{i}].{key}"),
                    "is not used by a lidar receiver (it sits at the source, looks along the beam and writes range-gate spectra): remove it",
                );
            }
            detectors[i].kind = DetectorKind::Lidar(spec);
        }
    }
    if source.chirp.is_some()
        && let Some(i) = detectors.iter().position(|d| d.ldh().is_some())
    {
        return err(
            format!("detectors[{i}].ldh"),
            "an LDH camera needs a single-frequency laser: remove source.chirp (FMCW) or the ldh section",
        );
    }
    let mut exp = Experiment {
        name: f.name.clone().unwrap_or_else(|| "experiment".to_string()),
        scene,
        source,
        detectors,
        plan,
        references: Vec::new(),
    };
    check_memory(&exp)?;
    exp.references = resolve_references(&f.reference, &exp)?;
    Ok(exp)
}

/// `[reference]`: each key a named output of the experiment, each value finite and of its size;
/// stored in the tally's convention (an M0− written with `flip_sign` is negated back).
fn resolve_references(refs: &BTreeMap<String, ReferenceValue>, exp: &Experiment) -> R<Vec<(String, Vec<f64>)>> {
    if refs.is_empty() {
        return Ok(Vec::new());
    }
    let outputs = exp.outputs();
    let mut out = Vec::with_capacity(refs.len());
    for (name, value) in refs {
        let path = format!("reference.{name}");
        let Some(o) = outputs.iter().find(|o| &o.name == name) else {
            let names: Vec<&str> = outputs.iter().map(|o| o.name.as_str()).collect();
            return err(path, format!("is not an output of this experiment; expected one of {}", names.join(", ")));
        };
        let values = match value {
            ReferenceValue::Scalar(v) => vec![*v],
            ReferenceValue::Array(v) => v.clone(),
        };
        if values.len() != o.range().len() {
            return err(path, format!("has {} values: expected {} (the output's size)", values.len(), o.range().len()));
        }
        if let Some(v) = values.iter().find(|v| !v.is_finite()) {
            return err(path, format!("contains {v}: expected finite values"));
        }
        out.push((name.clone(), values.iter().map(|v| v * o.sign).collect()));
    }
    Ok(out)
}

/// Default of `run.memory_budget_gib`.
pub const DEFAULT_MEMORY_BUDGET_GIB: f64 = 8.0;

/// Refuse an experiment whose tallies ([`Experiment::memory_estimate`]: the tally vector times
/// the batches in flight, the mean and the variance) exceed `run.memory_budget_gib`, before
/// anything is allocated. The error names the key of the largest block of tallies.
fn check_memory(exp: &Experiment) -> R<()> {
    let need = exp.memory_estimate();
    if need <= exp.plan.memory_budget {
        return Ok(());
    }
    let layout = exp.tally_layout();
    let blocks = layout.registry.budget_blocks();
    let (key, value) = blocks
        .into_iter()
        .max_by_key(|b| b.2)
        .map_or(("run.memory_budget_gib".to_string(), String::new()), |b| (b.0, b.1));
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    err(
        key,
        format!(
            "{value}: the tallies need {:.1} GiB ({} tallies × 8 bytes × (2 + batches in flight)), above the memory budget of {:.1} GiB (run.memory_budget_gib)",
            gib(need),
            layout.len,
            gib(exp.plan.memory_budget)
        ),
    )
}

fn resolve_run(r: &RunSection) -> R<RunPlan> {
    let batches = r.batches.unwrap_or(32);
    if !(16..=65_536).contains(&batches) {
        return err("run.batches", format!("= {batches}: expected 16 to 65536 independent batches"));
    }
    let samples = r.samples.unwrap_or(1_000_000);
    if samples == 0 || samples > 1 << 48 {
        return err("run.samples", format!("= {samples}: expected 1 to 2^48 paths"));
    }
    let threads = r.threads.unwrap_or(0);
    if threads > 1024 {
        return err("run.threads", format!("= {threads}: expected 0 (all cores) to 1024"));
    }
    let tracking = match r.tracking.unwrap_or(TrackingKind::Analytic) {
        TrackingKind::Analytic => {
            if r.majorant_scale.is_some() {
                return err("run.majorant_scale", "only applies with run.tracking = \"delta\"");
            }
            Tracking::Analytic
        }
        TrackingKind::Delta => {
            let s = r.majorant_scale.unwrap_or(1.0);
            if !(s.is_finite() && (1.0..=1e6).contains(&s)) {
                return err("run.majorant_scale", format!("= {s}: expected a factor in [1, 1e6]"));
            }
            Tracking::Delta { majorant_scale: s }
        }
    };
    let roulette_threshold = r.roulette_threshold.unwrap_or(1e-4);
    if !(roulette_threshold.is_finite() && (0.0..1.0).contains(&roulette_threshold)) {
        return err("run.roulette_threshold", format!("= {roulette_threshold}: expected a weight in [0, 1)"));
    }
    let roulette_survival = r.roulette_survival.unwrap_or(0.1);
    if !(roulette_survival > 0.0 && roulette_survival <= 1.0) {
        return err("run.roulette_survival", format!("= {roulette_survival}: expected a probability in (0, 1]"));
    }
    let max_events = r.max_scattering_events.unwrap_or(1_000_000);
    if max_events == 0 || max_events > u32::MAX as u64 {
        return err("run.max_scattering_events", format!("= {max_events}: expected 1 to {}", u32::MAX));
    }
    let budget = r.memory_budget_gib.unwrap_or(DEFAULT_MEMORY_BUDGET_GIB);
    if !(budget.is_finite() && budget > 0.0 && budget <= 1e6) {
        return err("run.memory_budget_gib", format!("= {budget}: expected a budget in (0, 10^6] GiB"));
    }
    let paths_per_batch = samples.div_ceil(batches);
    Ok(RunPlan {
        requested_samples: samples,
        batches,
        paths_per_batch,
        seed: r.seed.unwrap_or(1),
        threads: threads as usize,
        walk: WalkSettings { tracking, roulette_threshold, roulette_survival, max_events: max_events as u32 },
        memory_budget: (budget * (1u64 << 30) as f64) as u64,
    })
}

fn resolve_source(s: &SourceSection) -> R<Source> {
    let wl = require(
        "source",
        &[("wavelength_nm", s.wavelength_nm, 1e-9), ("wavelength_um", s.wavelength_um, 1e-6)],
        "the vacuum wavelength",
    )?;
    if !(wl.0.is_finite() && (1e-8..=1e-3).contains(&wl.0)) {
        return err(wl.1, format!("= {}: expected a vacuum wavelength from 10 nm to 1 mm", wl.2));
    }
    let radius = length("source", "radius", s.radius_um, s.radius_mm, s.radius_m)?;
    let waist = length("source", "waist", s.waist_um, s.waist_mm, s.waist_m)?;
    let profile = match s.profile.unwrap_or(ProfileKind::Pencil) {
        ProfileKind::Pencil => {
            if let Some(r) = radius.as_ref().or(waist.as_ref()) {
                return err(r.1.clone(), "only applies to profile = \"disk\" (radius) or \"gaussian\" (waist)");
            }
            Profile::Pencil
        }
        ProfileKind::Disk => {
            if let Some(w) = waist {
                return err(w.1, "only applies to profile = \"gaussian\"; a disk has a radius");
            }
            let r = radius.ok_or_else(|| {
                ConfigError::new("source", "profile = \"disk\" needs radius_um, radius_mm or radius_m")
            })?;
            Profile::Disk { radius: positive(r, "a beam radius")? }
        }
        ProfileKind::Gaussian => {
            if let Some(r) = radius {
                return err(r.1, "only applies to profile = \"disk\"; a Gaussian beam has a waist (1/e² radius)");
            }
            let w = waist.ok_or_else(|| {
                ConfigError::new(
                    "source",
                    "profile = \"gaussian\" needs waist_um, waist_mm or waist_m (1/e² intensity radius)",
                )
            })?;
            Profile::Gaussian { waist: positive(w, "a 1/e² beam radius")? }
        }
    };
    let position = length_arr("source", "position", s.position_um, s.position_mm, s.position_m)?;
    let position = match position {
        Some((p, path)) => {
            if p[2] > 0.0 {
                return err(path, format!("= {p:?} m: the laser must start above or on the top surface (z ≤ 0)"));
            }
            DVec3::from_array(p)
        }
        None => DVec3::ZERO,
    };
    let pointings = resolve_pointings(s)?;
    let direction = match pointings.first() {
        Some(p) => p.direction,
        None => unit_vector("source.direction", s.direction.unwrap_or([0.0, 0.0, 1.0]))?,
    };
    if direction.z < 1e-6 {
        return err(
            "source.direction",
            format!(
                "= {:?}: the beam must point into the stack, not graze it (z component of the unit vector > 1e-6; +z is depth)",
                direction.to_array()
            ),
        );
    }
    let divergence = match pick(
        "source",
        &[("divergence_urad", s.divergence_urad, 1e-6), ("divergence_mrad", s.divergence_mrad, 1e-3)],
    )? {
        None => 0.0,
        Some(d) => {
            if !(d.0.is_finite() && (0.0..=0.1).contains(&d.0)) {
                return err(d.1, format!("= {}: expected a 1/e² half-angle divergence from 0 to 0.1 rad", d.2));
            }
            if direction.z < 5.0 * d.0 {
                return err(
                    d.1,
                    format!(
                        "= {}: too wide for a beam {:.2}° above the surface (the beam's z component must exceed 5× the divergence)",
                        d.2,
                        direction.z.asin().to_degrees()
                    ),
                );
            }
            d.0
        }
    };
    let chirp = match &s.chirp {
        None => None,
        Some(c) => {
            let b = require(
                "source.chirp",
                &[
                    ("bandwidth_hz", c.bandwidth_hz, 1.0),
                    ("bandwidth_mhz", c.bandwidth_mhz, 1e6),
                    ("bandwidth_ghz", c.bandwidth_ghz, 1e9),
                ],
                "the chirp bandwidth B",
            )?;
            let t = require(
                "source.chirp",
                &[
                    ("duration_s", c.duration_s, 1.0),
                    ("duration_ms", c.duration_ms, 1e-3),
                    ("duration_us", c.duration_us, 1e-6),
                ],
                "the chirp duration T",
            )?;
            // B = 0 is accepted: a chirp of zero bandwidth is a single-frequency laser, and its up-
            // and down-chirp spectra are the CW Doppler spectrum and its mirror (f = ±(dl/dt)/λ0).
            // Only the range retrieval needs B > 0, and says so (`retrieval::fmcw`).
            Some(Chirp { bandwidth: non_negative(b, "a bandwidth")?, duration: positive(t, "a chirp duration")? })
        }
    };
    let mut source = Source::new(wl.0, profile, position, direction, chirp);
    source.divergence = divergence;
    source.pointings = pointings;
    Ok(source)
}

/// The pointing of the beam by azimuth and elevation (degrees), or a scan of several.
fn resolve_pointings(s: &SourceSection) -> R<Vec<Pointing>> {
    let angles = |path: &str, az: f64, el: f64| -> R<Pointing> {
        if !(az.is_finite() && (-360.0..=360.0).contains(&az)) {
            return err(path, format!("azimuth = {az}°: expected −360 to 360 degrees clockwise from north"));
        }
        if !(el.is_finite() && el > 0.0 && el <= 90.0) {
            return err(
                path,
                format!("elevation = {el}°: expected above 0 and at most 90 degrees (the beam must point up, +z)"),
            );
        }
        Ok(Pointing::new(az, el))
    };
    let single = s.azimuth_deg.is_some() || s.elevation_deg.is_some();
    if single && s.direction.is_some() {
        return err("source", "give the pointing as direction or as azimuth_deg/elevation_deg, not both");
    }
    if let Some(list) = &s.pointings_deg {
        if single || s.direction.is_some() {
            return err(
                "source.pointings_deg",
                "a scan replaces direction, azimuth_deg and elevation_deg: remove them",
            );
        }
        if list.is_empty() || list.len() > 10_000 {
            return err("source.pointings_deg", format!("{} pointings: expected 1 to 10000", list.len()));
        }
        return list
            .iter()
            .enumerate()
            .map(|(i, p)| angles(&format!("source.pointings_deg[{i}]"), p[0], p[1]))
            .collect();
    }
    if single {
        let el = s.elevation_deg.unwrap_or(90.0);
        return Ok(vec![angles("source", s.azimuth_deg.unwrap_or(0.0), el)?]);
    }
    Ok(Vec::new())
}

/// What a velocity field may draw on besides its own keys: the region's cylinder (Poiseuille), the
/// file's `[wind]` and the particle sizes of the population (terminal fall).
#[derive(Clone, Copy)]
struct FlowCtx<'a> {
    /// Where relative file names start, and the grids read so far.
    base: &'a Path,
    files: &'a GridFiles,
    cylinder: Option<&'a Shape>,
    wind: Option<&'a WindProfile>,
    /// Radii (m) with their σs weights.
    sizes: &'a [(f64, f64)],
}

fn resolve_velocity(path: &str, v: &VelocitySection, fc: FlowCtx) -> R<VelocityField> {
    let cylinder = fc.cylinder;
    Ok(match v {
        VelocitySection::None {} => VelocityField::Static,
        VelocitySection::Wind {} => match fc.wind {
            Some(w) => VelocityField::Wind(w.clone()),
            None => return err(join(path, "type"), "= \"wind\" needs a [wind] table (the wind profile)"),
        },
        VelocitySection::TerminalFall {} => {
            if fc.sizes.is_empty() {
                return err(
                    join(path, "type"),
                    "= \"terminal_fall\" needs the medium's particles: the drop sizes give the fall speeds",
                );
            }
            let pairs: Vec<(f64, f64)> = fc.sizes.iter().map(|&(r, w)| (atlas_fall_speed(2.0 * r), w)).collect();
            let fall = FallSpeeds::new(&pairs)
                .ok_or_else(|| ConfigError::new(path, "the particles scatter nothing: no drop sizes to fall"))?;
            let wind = fc.wind.cloned().unwrap_or(WindProfile::Uniform(DVec3::ZERO));
            VelocityField::TerminalFall { wind, fall: Arc::new(fall) }
        }
        VelocitySection::Uniform { velocity_mm_per_s, velocity_m_per_s } => {
            let (v, _) = require_arr(
                path,
                &[("velocity_mm_per_s", *velocity_mm_per_s, 1e-3), ("velocity_m_per_s", *velocity_m_per_s, 1.0)],
                "the velocity vector",
            )?;
            VelocityField::Uniform(DVec3::from_array(v))
        }
        VelocitySection::RandomDirection { speed_mm_per_s, speed_m_per_s } => {
            let s = require(
                path,
                &[("speed_mm_per_s", *speed_mm_per_s, 1e-3), ("speed_m_per_s", *speed_m_per_s, 1.0)],
                "the speed",
            )?;
            VelocityField::RandomDirection { speed: non_negative(s, "a speed")? }
        }
        VelocitySection::Poiseuille { v_max_mm_per_s, v_max_m_per_s, mean_mm_per_s, mean_m_per_s } => {
            let Some(&Shape::Cylinder { center, axis, radius, .. }) = cylinder else {
                return err(
                    join(path, "type"),
                    "= \"poiseuille\": a Poiseuille profile needs a cylinder region (its axis and radius); use it on a region with shape.type = \"cylinder\"",
                );
            };
            let v = require(
                path,
                &[
                    ("v_max_mm_per_s", *v_max_mm_per_s, 1e-3),
                    ("v_max_m_per_s", *v_max_m_per_s, 1.0),
                    // Mean over the cross-section of v_max(1 − r²/R²) is v_max/2.
                    ("mean_mm_per_s", *mean_mm_per_s, 2e-3),
                    ("mean_m_per_s", *mean_m_per_s, 2.0),
                ],
                "the centre-line (v_max) or mean speed",
            )?;
            if !v.0.is_finite() {
                return err(v.1, "expected a finite speed (negative reverses the flow along the axis)");
            }
            VelocityField::Poiseuille { origin: center, axis, radius, v_max: v.0 }
        }
        VelocitySection::Vdb { file, grid, interpolation: i, scale, translate_um, translate_mm, translate_m } => {
            let g = fc.files.vec3(path, fc.base, file, grid.as_deref())?;
            let place = resolve_placement(path, *scale, *translate_um, *translate_mm, *translate_m)?;
            if !g.background.iter().all(|c| c.is_finite()) {
                return err(join(path, "file"), format!("{file}: the velocity grid's background is not finite"));
            }
            if let Some(o) = g.data.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
                let ijk = g.index_of(o);
                return err(join(path, "file"), format!("{file}: voxel {ijk:?} of the velocity grid is not finite"));
            }
            VelocityField::Grid(Arc::new(GridField::new(g, interpolation(*i), place)))
        }
    })
}

/// `[wind]`: the wind profile.
fn resolve_wind(w: &WindSection) -> R<WindProfile> {
    let finite = |key: &str, v: f64, what: &str| -> R<f64> {
        if v.is_finite() { Ok(v) } else { err(join("wind", key), format!("= {v}: expected a finite {what}")) }
    };
    let horizontal = |deg: f64| -> R<DVec3> {
        let d = finite("direction_from_deg", deg, "direction in degrees clockwise from north")?.to_radians();
        // Blowing *from* azimuth d, i.e. toward d + 180°: (−sin d, −cos d, 0) in (east, north, up).
        Ok(DVec3::new(-d.sin(), -d.cos(), 0.0))
    };
    let speed = |key: &str, v: f64| -> R<f64> {
        if v.is_finite() && (0.0..=200.0).contains(&v) {
            Ok(v)
        } else {
            err(join("wind", key), format!("= {v}: expected a wind speed from 0 to 200 m/s"))
        }
    };
    let vertical = |v: Option<f64>| -> R<f64> {
        let v = v.unwrap_or(0.0);
        if v.is_finite() && v.abs() <= 100.0 {
            Ok(v)
        } else {
            err("wind.vertical_m_per_s", format!("= {v}: expected a vertical velocity within ±100 m/s"))
        }
    };
    let height = |key: &str, v: f64| -> R<f64> {
        if v.is_finite() && v > 0.0 { Ok(v) } else { err(join("wind", key), format!("= {v}: expected a height > 0 m")) }
    };
    Ok(match w {
        WindSection::Uniform { velocity_m_per_s } => {
            let v = DVec3::from_array(*velocity_m_per_s);
            if !v.is_finite() || v.length() > 200.0 {
                return err(
                    "wind.velocity_m_per_s",
                    format!("= {velocity_m_per_s:?}: expected finite components, |v| ≤ 200 m/s"),
                );
            }
            WindProfile::Uniform(v)
        }
        WindSection::PowerLaw { speed_m_per_s, reference_height_m, exponent, direction_from_deg, vertical_m_per_s } => {
            if !(exponent.is_finite() && (0.0..=1.0).contains(exponent)) {
                return err(
                    "wind.exponent",
                    format!("= {exponent}: expected a shear exponent α in [0, 1] (1/7 onshore)"),
                );
            }
            WindProfile::PowerLaw {
                direction: horizontal(*direction_from_deg)?,
                speed_ref: speed("speed_m_per_s", *speed_m_per_s)?,
                height_ref: height("reference_height_m", *reference_height_m)?,
                exponent: *exponent,
                vertical: vertical(*vertical_m_per_s)?,
            }
        }
        WindSection::LogLaw {
            friction_velocity_m_per_s,
            speed_m_per_s,
            reference_height_m,
            roughness_length_m,
            displacement_height_m,
            direction_from_deg,
            vertical_m_per_s,
        } => {
            let z0 = height("roughness_length_m", *roughness_length_m)?;
            let d = displacement_height_m.unwrap_or(0.0);
            if !(d.is_finite() && d >= 0.0) {
                return err("wind.displacement_height_m", format!("= {d}: expected a height ≥ 0 m"));
            }
            let u_star = match (friction_velocity_m_per_s, speed_m_per_s, reference_height_m) {
                (Some(u), None, None) => speed("friction_velocity_m_per_s", *u)?,
                (None, Some(u), Some(h)) => {
                    let h = height("reference_height_m", *h)?;
                    if h - d <= z0 {
                        return err(
                            "wind.reference_height_m",
                            format!(
                                "= {h}: the reference height must lie above displacement + roughness ({} m)",
                                d + z0
                            ),
                        );
                    }
                    // u(h) = (u*/κ) ln((h − d)/z0), solved for u*.
                    speed("speed_m_per_s", *u)? * VON_KARMAN / ((h - d) / z0).ln()
                }
                _ => {
                    return err(
                        "wind",
                        "a log-law wind needs friction_velocity_m_per_s, or speed_m_per_s with reference_height_m (not both)",
                    );
                }
            };
            WindProfile::LogLaw {
                direction: horizontal(*direction_from_deg)?,
                friction_velocity: u_star,
                roughness: z0,
                displacement: d,
                vertical: vertical(*vertical_m_per_s)?,
            }
        }
        WindSection::Table { heights_m, velocities_m_per_s } => {
            if velocities_m_per_s.is_empty() || heights_m.len() != velocities_m_per_s.len() + 1 {
                return err(
                    "wind.heights_m",
                    format!(
                        "{} heights for {} velocities: give the n + 1 layer edges of n ≥ 1 velocities",
                        heights_m.len(),
                        velocities_m_per_s.len()
                    ),
                );
            }
            if heights_m.iter().any(|h| !h.is_finite()) || heights_m.windows(2).any(|w| w[1] <= w[0]) {
                return err("wind.heights_m", "expected finite heights in strictly increasing order (m)");
            }
            if let Some(i) = velocities_m_per_s
                .iter()
                .position(|v| !DVec3::from_array(*v).is_finite() || DVec3::from_array(*v).length() > 200.0)
            {
                return err(
                    format!("wind.velocities_m_per_s[{i}]"),
                    format!("= {:?}: expected finite components, |v| ≤ 200 m/s", velocities_m_per_s[i]),
                );
            }
            WindProfile::Table {
                edges: heights_m.as_slice().into(),
                velocities: velocities_m_per_s.iter().map(|v| DVec3::from_array(*v)).collect(),
            }
        }
    })
}

/// A factor on σs and σa as a function of height.
enum HeightProfile {
    Exponential { scale: f64 },
    BoundaryLayer { top: f64, scale: f64 },
    Table { heights: Vec<f64>, factors: Vec<f64> },
}

impl HeightProfile {
    fn factor(&self, h: f64) -> f64 {
        match self {
            HeightProfile::Exponential { scale } => (-h / scale).exp(),
            HeightProfile::BoundaryLayer { top, scale } => {
                if h <= *top {
                    1.0
                } else {
                    (-(h - top) / scale).exp()
                }
            }
            HeightProfile::Table { heights, factors } => {
                let i = heights.partition_point(|&x| x <= h);
                if i == 0 {
                    factors[0]
                } else if i == heights.len() {
                    factors[i - 1]
                } else {
                    let t = (h - heights[i - 1]) / (heights[i] - heights[i - 1]);
                    factors[i - 1] + t * (factors[i] - factors[i - 1])
                }
            }
        }
    }
}

fn resolve_height_profile(path: &str, h: &HeightProfileSection) -> R<HeightProfile> {
    let length = |key: &str, v: f64| -> R<f64> {
        if v.is_finite() && v > 0.0 { Ok(v) } else { err(join(path, key), format!("= {v}: expected a length > 0 m")) }
    };
    Ok(match h {
        HeightProfileSection::Exponential { scale_height_m } => {
            HeightProfile::Exponential { scale: length("scale_height_m", *scale_height_m)? }
        }
        HeightProfileSection::BoundaryLayer { top_m, scale_height_m } => HeightProfile::BoundaryLayer {
            top: length("top_m", *top_m)?,
            scale: length("scale_height_m", *scale_height_m)?,
        },
        HeightProfileSection::Table { heights_m, factors } => {
            if heights_m.is_empty() || heights_m.len() != factors.len() {
                return err(
                    join(path, "factors"),
                    format!(
                        "{} factors for {} heights: expected one factor per height",
                        factors.len(),
                        heights_m.len()
                    ),
                );
            }
            if heights_m.iter().any(|h| !h.is_finite()) || heights_m.windows(2).any(|w| w[1] <= w[0]) {
                return err(join(path, "heights_m"), "expected finite heights in strictly increasing order (m)");
            }
            if let Some(f) = factors.iter().find(|f| !(f.is_finite() && **f >= 0.0 && **f <= 1e6)) {
                return err(join(path, "factors"), format!("contains {f}: expected factors in [0, 1e6]"));
            }
            HeightProfile::Table { heights: heights_m.clone(), factors: factors.clone() }
        }
    })
}

/// `[media.X.motion]`: a per-event velocity dispersion and a diffusion coefficient, given directly
/// or by Stokes–Einstein from radius, temperature and viscosity.
fn resolve_motion(path: &str, m: &MotionSection) -> R<Motion> {
    let dispersion = pick(
        path,
        &[("dispersion_mm_per_s", m.dispersion_mm_per_s, 1e-3), ("dispersion_m_per_s", m.dispersion_m_per_s, 1.0)],
    )?
    .map_or(Ok(0.0), |v| non_negative(v, "a velocity standard deviation"))?;
    let direct = pick(
        path,
        &[("diffusion_m2_per_s", m.diffusion_m2_per_s, 1.0), ("diffusion_um2_per_s", m.diffusion_um2_per_s, 1e-12)],
    )?;
    let radius = pick(path, &[("radius_um", m.radius_um, 1e-6), ("radius_nm", m.radius_nm, 1e-9)])?;
    let temperature = pick(path, &[("temperature_k", m.temperature_k, 1.0)])?;
    let viscosity =
        pick(path, &[("viscosity_mpa_s", m.viscosity_mpa_s, 1e-3), ("viscosity_pa_s", m.viscosity_pa_s, 1.0)])?;
    let stokes = radius.is_some() || temperature.is_some() || viscosity.is_some();
    let diffusion = match (direct, stokes) {
        (Some(d), false) => non_negative(d, "a diffusion coefficient")?,
        (None, false) => 0.0,
        (Some(d), true) => {
            return err(d.1, "give either the diffusion coefficient or radius, temperature and viscosity, not both");
        }
        (None, true) => {
            let missing = |what: &str, keys: &str| {
                ConfigError::new(
                    path,
                    format!("missing {what} for the Stokes–Einstein diffusion coefficient: give {keys}"),
                )
            };
            let r =
                positive(radius.ok_or_else(|| missing("the particle radius", "radius_um or radius_nm"))?, "a radius")?;
            let t = positive(temperature.ok_or_else(|| missing("the temperature", "temperature_k"))?, "a temperature")?;
            let eta = positive(
                viscosity.ok_or_else(|| missing("the fluid viscosity", "viscosity_mpa_s or viscosity_pa_s"))?,
                "a viscosity",
            )?;
            stokes_einstein(r, t, eta)
        }
    };
    Ok(Motion { dispersion, diffusion })
}

/// What resolving needs besides the file: where relative paths start, and the wavelength media
/// are computed for.
struct Ctx<'a> {
    base: &'a Path,
    wavelength: f64,
    files: GridFiles,
}

/// The OpenVDB grids read so far, by file and grid name: a file is read once however many layers,
/// sublayers and regions use its grids.
#[derive(Default)]
struct GridFiles {
    float: GridCache<f32>,
    vec3: GridCache<[f32; 3]>,
}

/// Grids by (file, grid name).
type GridCache<T> = std::cell::RefCell<BTreeMap<(std::path::PathBuf, Option<String>), Arc<VoxelGrid<T>>>>;

impl GridFiles {
    /// The float grid `grid` (or the first) of `file` (relative to `base`); errors name `key`.
    fn float(&self, key: &str, base: &Path, file: &str, grid: Option<&str>) -> R<Arc<VoxelGrid<f32>>> {
        Self::get(&self.float, key, base, file, grid, crate::io::formats::vdb::read_float)
    }

    /// The vec3 grid `grid` (or the first) of `file`.
    fn vec3(&self, key: &str, base: &Path, file: &str, grid: Option<&str>) -> R<Arc<VoxelGrid<[f32; 3]>>> {
        Self::get(&self.vec3, key, base, file, grid, crate::io::formats::vdb::read_vec3)
    }

    fn get<T>(
        cache: &GridCache<T>,
        key: &str,
        base: &Path,
        file: &str,
        grid: Option<&str>,
        read: impl Fn(std::path::PathBuf, Option<&str>) -> crate::error::Result<crate::io::formats::vdb::VdbGrid<T>>,
    ) -> R<Arc<VoxelGrid<T>>> {
        let path = base.join(file);
        let id = (path.clone(), grid.map(str::to_string));
        if let Some(g) = cache.borrow().get(&id) {
            return Ok(g.clone());
        }
        let g = Arc::new(read(path, grid).map_err(|e| ConfigError::new(join(key, "file"), e.to_string()))?.grid);
        cache.borrow_mut().insert(id, g.clone());
        Ok(g)
    }
}

/// A grid's placement from its keys `scale` and `translate_*` under `path`.
fn resolve_placement(
    path: &str,
    scale: Option<f64>,
    um: Option<[f64; 3]>,
    mm: Option<[f64; 3]>,
    m: Option<[f64; 3]>,
) -> R<Placement> {
    let scale = match scale {
        None => 1.0,
        Some(s) if s.is_finite() && s > 0.0 => s,
        Some(s) => {
            return err(
                join(path, "scale"),
                format!("= {s}: expected the file's length unit in metres, > 0 (1e-3 for millimetres)"),
            );
        }
    };
    // Finite numbers are checked where the unit is picked.
    let translation = length_arr(path, "translate", um, mm, m)?.map_or(DVec3::ZERO, |(t, _)| DVec3::from_array(t));
    Ok(Placement { translation, scale })
}

fn interpolation(i: Option<InterpolationSection>) -> Interpolation {
    match i {
        None | Some(InterpolationSection::Trilinear) => Interpolation::Trilinear,
        Some(InterpolationSection::Nearest) => Interpolation::Nearest,
    }
}

/// The optics of a named medium (everything but its velocity), resolved once per name however many
/// layers and regions use it.
#[derive(Debug, Clone)]
struct Optics {
    sigma_a: f64,
    sigma_s: f64,
    phase: PhaseFunction,
    info: MediumInfo,
    /// Particle radii (m) with the σs (m⁻¹) each contributes, when the medium has particles.
    sizes: Vec<(f64, f64)>,
    /// With `size_classes`: one population per class (then the fields above are their sums).
    classes: Vec<ClassOptics>,
}

/// The optics of one size class of a medium's particles.
#[derive(Debug, Clone)]
struct ClassOptics {
    sigma_s: f64,
    phase: PhaseFunction,
    sizes: Vec<(f64, f64)>,
}

/// Default number of angles of a Mie phase table, and the grid used when only σ and g are needed.
const MIE_ANGLES: u64 = 1000;
const MIE_ANGLES_UNUSED: usize = 16;

/// Values computed for one wavelength must not be used at another (1 % tolerance).
fn check_wavelength(path: &str, what: &str, given: f64, source: f64) -> R<()> {
    if (given / source - 1.0).abs() > 0.01 {
        return err(
            path,
            format!(
                "{what} λ0 = {:.1} nm but source.wavelength is {:.1} nm: use values for the source wavelength",
                given * 1e9,
                source * 1e9
            ),
        );
    }
    Ok(())
}

fn resolve_optics(path: &str, m: &MediumSection, ctx: &Ctx) -> R<Optics> {
    if let Some(wl) = pick(path, &[("wavelength_nm", m.wavelength_nm, 1e-9), ("wavelength_um", m.wavelength_um, 1e-6)])?
    {
        check_wavelength(&wl.1, "this medium's values are for", wl.0, ctx.wavelength)?;
    }
    // Only a Mie phase function needs the full angle grid; σ and g alone need very few angles.
    let mie_angles = match &m.phase {
        None => Some(MIE_ANGLES),
        Some(PhaseSection::Mie { angles }) => Some(angles.unwrap_or(MIE_ANGLES)),
        _ => None,
    };
    if let Some(a) = mie_angles.filter(|a| !(16..=100_000).contains(a)) {
        return err(join(path, "phase.angles"), format!("= {a}: expected 16 to 100000 angles"));
    }
    if let Some(classes) = m.size_classes {
        return resolve_classes(path, m, classes, mie_angles, ctx);
    }
    let particles = match &m.particles {
        None => None,
        Some(list) => {
            let angles = mie_angles.map_or(MIE_ANGLES_UNUSED, |a| a as usize);
            Some(resolve_particles(&join(path, "particles"), list, angles, ctx)?)
        }
    };
    let coeff = |key: &str, per_m: Option<f64>, per_cm: Option<f64>, per_mm: Option<f64>, mie: Option<f64>| -> R<f64> {
        let keys = [format!("{key}_per_m"), format!("{key}_per_cm"), format!("{key}_per_mm")];
        let opts =
            [(keys[0].as_str(), per_m, 1.0), (keys[1].as_str(), per_cm, 100.0), (keys[2].as_str(), per_mm, 1000.0)];
        let Some(v) = pick(path, &opts)? else {
            return mie.ok_or_else(|| {
                ConfigError::new(
                    path,
                    format!("missing {key} (a coefficient): give one of {}, or particles", keys.join(", ")),
                )
            });
        };
        if !(v.0.is_finite() && (0.0..=1e12).contains(&v.0)) {
            return err(v.1, format!("= {} m⁻¹: expected a coefficient in [0, 1e12] m⁻¹", v.0));
        }
        Ok(v.0)
    };
    let sigma_a =
        coeff("sigma_a", m.sigma_a_per_m, m.sigma_a_per_cm, m.sigma_a_per_mm, particles.as_ref().map(|p| p.sigma_a))?;
    let sigma_s =
        coeff("sigma_s", m.sigma_s_per_m, m.sigma_s_per_cm, m.sigma_s_per_mm, particles.as_ref().map(|p| p.sigma_s))?;
    let scale = m.sigma_s_scale.unwrap_or(1.0);
    if !(scale.is_finite() && scale >= 0.0) {
        return err(join(path, "sigma_s_scale"), format!("= {scale}: expected a factor ≥ 0"));
    }
    let needs_particles = |what: &str| {
        ConfigError::new(
            join(path, "phase"),
            format!("{what} needs the medium's particles (add a particles table, or give the phase function)"),
        )
    };
    let mut table = None;
    let (phase, kind) = match &m.phase {
        None if particles.is_none() => (PhaseFunction::Isotropic, "isotropic"),
        Some(PhaseSection::Isotropic {}) => (PhaseFunction::Isotropic, "isotropic"),
        Some(PhaseSection::Hg { g }) => {
            let g = match (g, &particles) {
                (Some(g), _) => *g,
                (None, Some(p)) => p.g,
                (None, None) => return Err(needs_particles("type = \"hg\" without g")),
            };
            let hg = HenyeyGreenstein::new(g).ok_or_else(|| {
                ConfigError::new(
                    join(path, "phase.g"),
                    format!("= {g}: expected an asymmetry parameter with −1 < g < 1"),
                )
            })?;
            (PhaseFunction::HenyeyGreenstein(hg), "hg")
        }
        Some(PhaseSection::Table { file }) => {
            let key = join(path, "phase.file");
            let loaded = read_phase_table(&ctx.base.join(file)).map_err(|e| ConfigError::new(&key, e))?;
            if let Some(nm) = loaded.file.optics.wavelength_nm {
                check_wavelength(&key, &format!("the table `{file}` is for"), nm * 1e-9, ctx.wavelength)?;
            }
            table = Some(TableInfo {
                origin: loaded.phase.origin().to_string(),
                angles: loaded.phase.len(),
                source_normalisation: Some(loaded.file.normalisation.name().to_string()),
                source_integral: loaded.phase.source_integral(),
                provenance: loaded.file.provenance.clone(),
            });
            (PhaseFunction::Tabulated(Arc::new(loaded.phase)), "table")
        }
        None | Some(PhaseSection::Mie { .. }) => {
            let p = particles.as_ref().ok_or_else(|| needs_particles("type = \"mie\""))?;
            let origin = format!("Mie, {} component(s), λ0 = {:.1} nm", p.components.len(), ctx.wavelength * 1e9);
            let t = TabulatedPhase::from_angles(&p.theta, &p.phase, origin).map_err(|e| {
                ConfigError::new(join(path, "particles"), format!("the Mie phase function is not a distribution: {e}"))
            })?;
            table = Some(TableInfo {
                origin: t.origin().to_string(),
                angles: t.len(),
                source_normalisation: None,
                source_integral: t.source_integral(),
                provenance: Default::default(),
            });
            (PhaseFunction::Tabulated(Arc::new(t)), "mie")
        }
    };
    let sizes = particles.as_ref().map_or(Vec::new(), |p| p.sizes.iter().map(|&(r, s)| (r, s * scale)).collect());
    let info = MediumInfo {
        preset: m.preset.clone(),
        phase: kind.to_string(),
        g: phase.mean_cosine(),
        table,
        particles,
        sigma_s_scale: scale,
    };
    Ok(Optics { sigma_a, sigma_s: sigma_s * scale, phase, info, sizes, classes: Vec::new() })
}

/// A medium whose particles are split into `classes` size classes, each its own population with
/// its own Mie phase function (σs, σa and the phase functions all come from Mie theory).
fn resolve_classes(path: &str, m: &MediumSection, classes: u64, mie_angles: Option<u64>, ctx: &Ctx) -> R<Optics> {
    let key = join(path, "size_classes");
    if !(2..=64).contains(&classes) {
        return err(key, format!("= {classes}: expected 2 to 64 size classes"));
    }
    let Some(list) = &m.particles else {
        return err(key, "splits the medium's particles into size classes: add a particles table");
    };
    if let Some((k, _)) = coefficient_keys(m).iter().find(|(_, given)| *given) {
        return err(join(path, k), "with size_classes σs and σa come from the Mie classes: remove this key");
    }
    let Some(angles) = mie_angles else {
        return err(
            join(path, "phase"),
            "with size_classes each class has its Mie phase function: remove phase or give type = \"mie\"",
        );
    };
    let scale = m.sigma_s_scale.unwrap_or(1.0);
    if !(scale.is_finite() && scale >= 0.0) {
        return err(join(path, "sigma_s_scale"), format!("= {scale}: expected a factor ≥ 0"));
    }
    let optics = particle_classes(&join(path, "particles"), list, classes as usize, angles as usize, ctx)?;
    let mut out = Vec::with_capacity(optics.len());
    for (i, o) in optics.iter().enumerate() {
        let origin = format!("Mie, size class {i} of {classes}, λ0 = {:.1} nm", ctx.wavelength * 1e9);
        let t = TabulatedPhase::from_angles(&o.theta, &o.phase, origin).map_err(|e| {
            ConfigError::new(
                join(path, "particles"),
                format!("size class {i}: the Mie phase function is not a distribution: {e}"),
            )
        })?;
        out.push(ClassOptics {
            sigma_s: o.sigma_s * scale,
            phase: PhaseFunction::Tabulated(Arc::new(t)),
            sizes: o.sizes.iter().map(|&(r, s)| (r, s * scale)).collect(),
        });
    }
    // The whole ensemble, for the record: sums over the classes.
    let sigma_s: f64 = optics.iter().map(|o| o.sigma_s).sum();
    let sigma_a: f64 = optics.iter().map(|o| o.sigma_a).sum();
    let backscatter: f64 = optics.iter().map(|o| o.backscatter).sum();
    let g = optics.iter().map(|o| o.sigma_s * o.g).sum::<f64>() / sigma_s;
    let whole = ParticleOptics {
        sigma_s,
        sigma_a,
        g,
        backscatter,
        lidar_ratio: (sigma_s + sigma_a) / backscatter,
        components: optics.iter().flat_map(|o| o.components.clone()).collect(),
        theta: Vec::new(),
        phase: Vec::new(),
        sizes: optics.iter().flat_map(|o| o.sizes.clone()).collect(),
    };
    let info = MediumInfo {
        preset: m.preset.clone(),
        phase: format!("mie, {} size classes", out.len()),
        g,
        table: None,
        particles: Some(whole),
        sigma_s_scale: scale,
    };
    Ok(Optics { sigma_a, sigma_s: sigma_s * scale, phase: out[0].phase.clone(), info, sizes: Vec::new(), classes: out })
}

/// A positive length given as `NAME_um`, `NAME_mm` or `NAME_m`, if given.
fn positive_length(prefix: &str, name: &str, um: Option<f64>, mm: Option<f64>, m: Option<f64>) -> R<Option<Given>> {
    let Some(v) = length(prefix, name, um, mm, m)? else { return Ok(None) };
    positive(v.clone(), &format!("a {}", name.replace('_', " ")))?;
    Ok(Some(v))
}

/// A size range `[lo, hi]` (m) from its two length keys (`names`, each in µm, mm or m), with
/// defaults when both are optional.
fn size_range(
    prefix: &str,
    names: (&str, &str),
    lo: [Option<f64>; 3],
    hi: [Option<f64>; 3],
    default: Option<(f64, f64)>,
) -> R<(f64, f64)> {
    let lo = positive_length(prefix, names.0, lo[0], lo[1], lo[2])?;
    let hi = positive_length(prefix, names.1, hi[0], hi[1], hi[2])?;
    let (lo, hi) = match (lo, hi, default) {
        (Some(a), Some(b), _) => (a, b),
        (a, b, Some((da, db))) => {
            (a.unwrap_or((da, join(prefix, names.0), da)), b.unwrap_or((db, join(prefix, names.1), db)))
        }
        _ => {
            return err(prefix, format!("missing the size range: give {}_um and {}_um (or _mm, _m)", names.0, names.1));
        }
    };
    if lo.0 >= hi.0 {
        let key = |p: &str| p.rsplit('.').next().unwrap_or(p).to_string();
        return err(
            lo.1.clone(),
            format!("= {} is not below {} = {}: the size range is empty", lo.2, key(&hi.1), hi.2),
        );
    }
    Ok((lo.0, hi.0))
}

fn resolve_particles(path: &str, list: &OneOrMany<ParticlesSection>, angles: usize, ctx: &Ctx) -> R<ParticleOptics> {
    let specs = particle_specs(path, list, ctx)?;
    mixture_optics(&specs, angles).map_err(|e| ConfigError::new(path, e.to_string()))
}

/// The Mie optics of each of `classes` size classes of one Marshall–Palmer component, with
/// diameters log-spaced over its range and the quadrature nodes shared among them. Classes that
/// hold essentially no drops (far in the tail) are left out.
fn particle_classes(
    path: &str,
    list: &OneOrMany<ParticlesSection>,
    classes: usize,
    angles: usize,
    ctx: &Ctx,
) -> R<Vec<ParticleOptics>> {
    let specs = particle_specs(path, list, ctx)?;
    let [(name, spec)] = specs.as_slice() else {
        return err(path, "size_classes splits one particle component: give a single particles table");
    };
    let SizeDistribution::MarshallPalmer { rain_rate_mm_per_h, d_min, d_max } = spec.distribution else {
        return err(
            join(path, "size.type"),
            "size_classes needs an absolute size distribution: use type = \"marshall_palmer\" (the others are normalised to their whole range)",
        );
    };
    let size_points = (spec.size_points / classes).max(16);
    let mut out = Vec::with_capacity(classes);
    let edge = |j: usize| d_min * (d_max / d_min).powf(j as f64 / classes as f64);
    for i in 0..classes {
        let class = EnsembleSpec {
            distribution: SizeDistribution::MarshallPalmer { rain_rate_mm_per_h, d_min: edge(i), d_max: edge(i + 1) },
            size_points,
            ..*spec
        };
        match mixture_optics(&[(format!("{name}[{i}]"), class)], angles) {
            Ok(o) if o.sigma_s > 0.0 => out.push(o),
            Ok(_) | Err(crate::mie::MieError::EmptyDistribution(_)) => {}
            Err(e) => return err(path, format!("size class {i}: {e}")),
        }
    }
    if out.is_empty() {
        return err(path, "no size class holds any drops");
    }
    Ok(out)
}

/// The ensemble specification of every particle component.
fn particle_specs(path: &str, list: &OneOrMany<ParticlesSection>, ctx: &Ctx) -> R<Vec<(String, EnsembleSpec)>> {
    let items = list.items();
    if items.is_empty() {
        return err(path, "an empty list: give at least one particle component");
    }
    let mut specs = Vec::with_capacity(items.len());
    for (suffix, p) in items {
        let here = format!("{path}{suffix}");
        let name = p.name.clone().unwrap_or_else(|| format!("component{}", specs.len()));
        let k = p.k_particle.unwrap_or(0.0);
        if !(p.n_particle.is_finite() && p.n_particle > 0.0 && p.n_particle <= 20.0) {
            return err(
                join(&here, "n_particle"),
                format!("= {}: expected a real refractive index in (0, 20]", p.n_particle),
            );
        }
        if !(k.is_finite() && (0.0..=20.0).contains(&k)) {
            return err(
                join(&here, "k_particle"),
                format!("= {k}: expected an absorption index k in [0, 20] (index n − ik, k ≥ 0 absorbs)"),
            );
        }
        let n_medium = index_of_refraction(&join(&here, "n_medium"), p.n_medium)?;
        let sp = join(&here, "size");
        let distribution = match &p.size {
            SizeSection::Monodisperse { diameter_um, diameter_mm, diameter_m, radius_um, radius_mm, radius_m } => {
                let d = positive_length(&sp, "diameter", *diameter_um, *diameter_mm, *diameter_m)?;
                let r = positive_length(&sp, "radius", *radius_um, *radius_mm, *radius_m)?;
                let radius = match (d, r) {
                    (Some(d), None) => 0.5 * d.0,
                    (None, Some(r)) => r.0,
                    (Some(_), Some(_)) => return err(&sp, "give the diameter or the radius, not both"),
                    (None, None) => {
                        return err(&sp, "missing the particle size: give diameter_um or radius_um (or _mm, _m)");
                    }
                };
                SizeDistribution::Monodisperse { radius }
            }
            SizeSection::LogNormal {
                median_radius_um,
                median_radius_mm,
                median_radius_m,
                sigma_g,
                min_radius_um,
                min_radius_mm,
                min_radius_m,
                max_radius_um,
                max_radius_mm,
                max_radius_m,
            } => {
                let median_radius =
                    positive_length(&sp, "median_radius", *median_radius_um, *median_radius_mm, *median_radius_m)?
                        .ok_or_else(|| ConfigError::new(&sp, "missing median_radius_um (or _mm, _m)"))?;
                if !(sigma_g.is_finite() && *sigma_g > 1.0 && *sigma_g <= 10.0) {
                    return err(
                        join(&sp, "sigma_g"),
                        format!("= {sigma_g}: expected a geometric standard deviation in (1, 10]"),
                    );
                }
                let (r_min, r_max) = size_range(
                    &sp,
                    ("min_radius", "max_radius"),
                    [*min_radius_um, *min_radius_mm, *min_radius_m],
                    [*max_radius_um, *max_radius_mm, *max_radius_m],
                    None,
                )?;
                SizeDistribution::LogNormal { median_radius: median_radius.0, sigma_g: *sigma_g, r_min, r_max }
            }
            SizeSection::ModifiedGamma {
                mode_radius_um,
                mode_radius_mm,
                mode_radius_m,
                alpha,
                gamma,
                min_radius_um,
                min_radius_mm,
                min_radius_m,
                max_radius_um,
                max_radius_mm,
                max_radius_m,
            } => {
                let mode_radius =
                    positive_length(&sp, "mode_radius", *mode_radius_um, *mode_radius_mm, *mode_radius_m)?
                        .ok_or_else(|| ConfigError::new(&sp, "missing mode_radius_um (or _mm, _m)"))?;
                if !(alpha.is_finite() && *alpha > 0.0 && *alpha <= 100.0) {
                    return err(join(&sp, "alpha"), format!("= {alpha}: expected a shape exponent α in (0, 100]"));
                }
                if !(gamma.is_finite() && *gamma > 0.0 && *gamma <= 100.0) {
                    return err(join(&sp, "gamma"), format!("= {gamma}: expected an exponent γ in (0, 100]"));
                }
                let (r_min, r_max) = size_range(
                    &sp,
                    ("min_radius", "max_radius"),
                    [*min_radius_um, *min_radius_mm, *min_radius_m],
                    [*max_radius_um, *max_radius_mm, *max_radius_m],
                    None,
                )?;
                SizeDistribution::ModifiedGamma {
                    alpha: *alpha,
                    gamma: *gamma,
                    mode_radius: mode_radius.0,
                    r_min,
                    r_max,
                }
            }
            SizeSection::MarshallPalmer {
                rain_rate_mm_per_h,
                min_diameter_um,
                min_diameter_mm,
                min_diameter_m,
                max_diameter_um,
                max_diameter_mm,
                max_diameter_m,
            } => {
                if !(rain_rate_mm_per_h.is_finite() && *rain_rate_mm_per_h > 0.0 && *rain_rate_mm_per_h <= 500.0) {
                    return err(
                        join(&sp, "rain_rate_mm_per_h"),
                        format!("= {rain_rate_mm_per_h} mm/h: expected a rain rate in (0, 500] mm/h"),
                    );
                }
                // Defaults: 0.05–6 mm, the range of scene-parameters §B4.
                let (d_min, d_max) = size_range(
                    &sp,
                    ("min_diameter", "max_diameter"),
                    [*min_diameter_um, *min_diameter_mm, *min_diameter_m],
                    [*max_diameter_um, *max_diameter_mm, *max_diameter_m],
                    Some((0.05e-3, 6e-3)),
                )?;
                SizeDistribution::MarshallPalmer { rain_rate_mm_per_h: *rain_rate_mm_per_h, d_min, d_max }
            }
        };
        let conc = pick(
            &here,
            &[
                ("number_density_per_m3", p.number_density_per_m3, 1.0),
                ("number_density_per_cm3", p.number_density_per_cm3, 1e6),
                ("volume_fraction", p.volume_fraction, 1.0),
            ],
        )?;
        let concentration = match (&distribution, conc) {
            (SizeDistribution::MarshallPalmer { .. }, Some(c)) => {
                return err(c.1, "Marshall–Palmer fixes the drop concentration (N0 = 8000 m⁻³ mm⁻¹); remove this key");
            }
            (SizeDistribution::MarshallPalmer { .. }, None) => None,
            (_, None) => {
                return err(
                    &here,
                    "missing the concentration: give number_density_per_cm3, number_density_per_m3 or volume_fraction",
                );
            }
            (_, Some(c)) if c.1.ends_with("volume_fraction") => {
                if !(c.0 > 0.0 && c.0 < 1.0) {
                    return err(c.1, format!("= {}: expected a volume fraction in (0, 1)", c.2));
                }
                Some(Concentration::VolumeFraction(c.0))
            }
            (_, Some(c)) => Some(Concentration::NumberDensity(positive(c, "a number density")?)),
        };
        let packing = match p.packing.unwrap_or(PackingKind::None) {
            PackingKind::None => None,
            PackingKind::Twersky => Some(Packing::Twersky),
        };
        let size_points = p.size_points.unwrap_or(DEFAULT_SIZE_POINTS as u64);
        if !(8..=4096).contains(&size_points) {
            return err(join(&here, "size_points"), format!("= {size_points}: expected 8 to 4096 quadrature nodes"));
        }
        specs.push((
            name,
            EnsembleSpec {
                n_particle: p.n_particle,
                k_particle: k,
                n_medium,
                wavelength: ctx.wavelength,
                distribution,
                concentration,
                packing,
                size_points: size_points as usize,
            },
        ));
    }
    Ok(specs)
}

fn resolve_shape(path: &str, s: &ShapeSection) -> R<Shape> {
    let p = join(path, "shape");
    Ok(match s {
        ShapeSection::Sphere { center_um, center_mm, center_m, radius_um, radius_mm, radius_m } => {
            let (c, _) = length_arr_req(&p, "center", *center_um, *center_mm, *center_m)?;
            let r = positive(length_req(&p, "radius", *radius_um, *radius_mm, *radius_m)?, "a radius")?;
            Shape::Sphere { center: DVec3::from_array(c), radius: r }
        }
        ShapeSection::Box { center_um, center_mm, center_m, size_um, size_mm, size_m } => {
            let (c, _) = length_arr_req(&p, "center", *center_um, *center_mm, *center_m)?;
            let (sz, sp) = length_arr_req(&p, "size", *size_um, *size_mm, *size_m)?;
            if sz.iter().any(|&x| x <= 0.0) {
                return err(sp, format!("= {sz:?} m: expected three edge lengths > 0"));
            }
            let (c, h) = (DVec3::from_array(c), DVec3::from_array(sz) * 0.5);
            Shape::Box { min: c - h, max: c + h }
        }
        ShapeSection::Cylinder {
            center_um,
            center_mm,
            center_m,
            axis,
            radius_um,
            radius_mm,
            radius_m,
            length_um,
            length_mm,
            length_m,
        } => {
            let (c, _) = length_arr_req(&p, "center", *center_um, *center_mm, *center_m)?;
            let axis = unit_vector(&join(&p, "axis"), *axis)?;
            let r = positive(length_req(&p, "radius", *radius_um, *radius_mm, *radius_m)?, "a radius")?;
            let half_length = match length(&p, "length", *length_um, *length_mm, *length_m)? {
                None => f64::INFINITY,
                Some(l) => 0.5 * positive(l, "a length (omit it for a tube crossing its whole layer)")?,
            };
            Shape::Cylinder { center: DVec3::from_array(c), axis, radius: r, half_length }
        }
    })
}

fn resolve_scene(f: &ExperimentFile, n_above: f64, n_below: f64, ctx: &Ctx) -> R<Scene> {
    if f.media.is_empty() {
        return err("media", "no media defined: add a [media.NAME] table with sigma_a_* and sigma_s_*");
    }
    if f.layers.is_empty() {
        return err("layers", "no layers: add at least one [[layers]] with thickness, n and medium");
    }
    let known = f.media.keys().cloned().collect::<Vec<_>>().join(", ");
    let lookup = |path: String, name: &str| -> R<&MediumSection> {
        f.media
            .get(name)
            .ok_or_else(|| ConfigError::new(path, format!("= \"{name}\": unknown medium; defined media: {known}")))
    };
    let wind = f.wind.as_ref().map(resolve_wind).transpose()?;
    // Optics are resolved once per named medium (a Mie ensemble can take seconds), on first use.
    let mut optics: BTreeMap<String, Optics> = BTreeMap::new();
    // Densities likewise (a grid's majorant is built once).
    let mut densities: BTreeMap<String, Arc<Heterogeneity>> = BTreeMap::new();
    // A medium at height `height` (for its height profile); `velocity` overrides the medium's
    // own (a region's), `cylinder` is the region's shape if it is one.
    let mut make = |path: &str,
                    name: &str,
                    ms: &MediumSection,
                    velocity: Option<(String, &VelocitySection)>,
                    cylinder: Option<&Shape>,
                    height: f64|
     -> R<Medium> {
        let Some(list) = &ms.populations else {
            let velocity = velocity.or_else(|| ms.velocity.as_ref().map(|v| (join(path, "velocity"), v)));
            let (sigma_a, populations, info) =
                populations_of(&mut optics, ctx, wind.as_ref(), path, name, ms, velocity, cylinder, height)?;
            let mut m = Medium::mixture(name, sigma_a, populations);
            m.info = info;
            attach_density(path, ms, &mut m, ctx, &mut densities)?;
            return Ok(m);
        };
        check_mixture(path, ms)?;
        if let Some((p, _)) = velocity {
            return err(p, format!("medium \"{name}\" is a mixture: each population keeps its own velocity"));
        }
        if list.is_empty() {
            return err(join(path, "populations"), "an empty list: name at least one medium");
        }
        let (mut sigma_a, mut all, mut names) = (0.0, Vec::new(), Vec::new());
        for (j, pname) in list.iter().enumerate() {
            let key = format!("{}[{j}]", join(path, "populations"));
            let pms = lookup(key.clone(), pname)?;
            if pms.populations.is_some() {
                return err(key, format!("= \"{pname}\" is itself a mixture: list its populations here instead"));
            }
            if pms.density.is_some() {
                return err(
                    format!("media.{pname}.density"),
                    format!(
                        "medium \"{pname}\" is a population of the mixture \"{name}\": give the density on the mixture"
                    ),
                );
            }
            let ppath = format!("media.{pname}");
            let pv = pms.velocity.as_ref().map(|v| (join(&ppath, "velocity"), v));
            let (sa, pops, _) =
                populations_of(&mut optics, ctx, wind.as_ref(), &ppath, pname, pms, pv, cylinder, height)?;
            sigma_a += sa;
            all.extend(pops);
            names.push(pname.clone());
        }
        let mut m = Medium::mixture(name, sigma_a, all);
        let g =
            m.populations().iter().map(|p| p.sigma_s * p.phase.mean_cosine()).sum::<f64>() / m.sigma_s().max(1e-300);
        m.info = MediumInfo {
            preset: ms.preset.clone(),
            phase: format!("mixture of {}", names.join(", ")),
            g,
            sigma_s_scale: 1.0,
            ..MediumInfo::default()
        };
        attach_density(path, ms, &mut m, ctx, &mut densities)?;
        Ok(m)
    };
    let mut media: Vec<Medium> = Vec::new();
    let mut layers: Vec<Layer> = Vec::new();
    let mut layer_index: BTreeMap<String, usize> = BTreeMap::new();
    let mut split: Vec<String> = Vec::new();
    let mut z = 0.0;
    for (i, l) in f.layers.iter().enumerate() {
        let path = format!("layers[{i}]");
        let name = l.name.clone().unwrap_or_else(|| format!("layer{i}"));
        if layer_index.contains_key(&name) || split.contains(&name) {
            return err(join(&path, "name"), format!("= \"{name}\": layer names must be unique"));
        }
        let parts = l.sublayers.unwrap_or(1);
        if !(1..=100_000).contains(&parts) {
            return err(join(&path, "sublayers"), format!("= {parts}: expected 1 to 100000 layers"));
        }
        let th = length_req(&path, "thickness", l.thickness_um, l.thickness_mm, l.thickness_m)?;
        let last = i + 1 == f.layers.len();
        let thickness = if th.0 == f64::INFINITY && last {
            f64::INFINITY
        } else if th.0 == f64::INFINITY {
            return err(th.1, "= inf: only the last layer may be semi-infinite");
        } else {
            positive(th, "a thickness (or inf for a semi-infinite last layer)")?
        };
        let n = index_of_refraction(
            &join(&path, "n"),
            l.n.ok_or_else(|| ConfigError::new(join(&path, "n"), "missing: the refractive index of the layer"))?,
        )?;
        let ms = lookup(join(&path, "medium"), &l.medium)?;
        let mpath = format!("media.{}", l.medium);
        if parts > 1 && thickness == f64::INFINITY {
            return err(join(&path, "sublayers"), "a semi-infinite layer cannot be split");
        }
        let step = thickness / parts as f64;
        for j in 0..parts {
            // (The last bottom is exact, and a single semi-infinite layer never forms 0·∞.)
            let top = if j == 0 { z } else { z + j as f64 * step };
            let bottom = if j + 1 == parts { z + thickness } else { z + (j + 1) as f64 * step };
            let height = if bottom.is_finite() { 0.5 * (top + bottom) } else { top };
            let m = make(&mpath, &l.medium, ms, None, None, height)
                .map_err(|e| ConfigError::new(e.path, format!("{} (used by {path}, a layer)", e.message)))?;
            media.push(m);
            layers.push(Layer {
                name: if parts > 1 { format!("{name}[{j}]") } else { name.clone() },
                z_top: top,
                z_bottom: bottom,
                n,
                medium: media.len() - 1,
                regions: Vec::new(),
                majorant: 0.0,
                minorant: 0.0,
                heterogeneous: false,
                tau_above: 0.0,
            });
        }
        if parts > 1 {
            split.push(name);
        } else {
            layer_index.insert(name, layers.len() - 1);
        }
        z += thickness;
    }
    let mut regions: Vec<Region> = Vec::new();
    for (i, r) in f.regions.iter().enumerate() {
        let path = format!("regions[{i}]");
        let name = r.name.clone().unwrap_or_else(|| format!("region{i}"));
        if split.contains(&r.layer) {
            return err(
                join(&path, "layer"),
                format!("= \"{}\" is split into sublayers: regions need an unsplit layer", r.layer),
            );
        }
        let li = *layer_index.get(&r.layer).ok_or_else(|| {
            ConfigError::new(
                join(&path, "layer"),
                format!(
                    "= \"{}\": unknown layer; layers are {}",
                    r.layer,
                    layer_index.keys().cloned().collect::<Vec<_>>().join(", ")
                ),
            )
        })?;
        let shape = resolve_shape(&path, &r.shape)?;
        let (zmin, zmax) = shape.z_range();
        let layer = &layers[li];
        if zmax <= layer.z_top || zmin >= layer.z_bottom {
            return err(
                join(&path, "shape"),
                format!(
                    "lies outside its layer \"{}\" (z from {} to {} m; the shape spans {} to {} m)",
                    layer.name, layer.z_top, layer.z_bottom, zmin, zmax
                ),
            );
        }
        if layers[li].regions.len() == MAX_REGIONS_PER_LAYER {
            return err(
                path,
                format!(
                    "layer \"{}\" already holds {MAX_REGIONS_PER_LAYER} regions, the most one layer may hold",
                    layer.name
                ),
            );
        }
        let ms = lookup(join(&path, "medium"), &r.medium)?;
        let mpath = format!("media.{}", r.medium);
        let velocity = r.velocity.as_ref().map(|v| (join(&path, "velocity"), v));
        media.push(make(&mpath, &r.medium, ms, velocity, Some(&shape), 0.5 * (zmin + zmax))?);
        regions.push(Region { name, shape, medium: media.len() - 1, layer: li });
        layers[li].regions.push(regions.len() - 1);
    }
    let mut scene = Scene { layers, regions, media, n_above, n_below };
    scene.update_layers();
    Ok(scene)
}

/// The explicit σa and σs keys of a medium, with whether each is given.
fn coefficient_keys(m: &MediumSection) -> [(&'static str, bool); 6] {
    [
        ("sigma_a_per_m", m.sigma_a_per_m.is_some()),
        ("sigma_a_per_cm", m.sigma_a_per_cm.is_some()),
        ("sigma_a_per_mm", m.sigma_a_per_mm.is_some()),
        ("sigma_s_per_m", m.sigma_s_per_m.is_some()),
        ("sigma_s_per_cm", m.sigma_s_per_cm.is_some()),
        ("sigma_s_per_mm", m.sigma_s_per_mm.is_some()),
    ]
}

/// A mixture medium (`populations`) takes everything from its populations.
fn check_mixture(path: &str, ms: &MediumSection) -> R<()> {
    let particles = [("particles", ms.particles.is_some())];
    let others = [
        ("sigma_s_scale", ms.sigma_s_scale.is_some()),
        ("phase", ms.phase.is_some()),
        ("velocity", ms.velocity.is_some()),
        ("motion", ms.motion.is_some()),
        ("size_classes", ms.size_classes.is_some()),
        ("height_profile", ms.height_profile.is_some()),
    ];
    match particles.iter().chain(&coefficient_keys(ms)).chain(&others).find(|g| g.1) {
        Some((key, _)) => err(
            join(path, key),
            "a mixture medium (populations) takes its optics, velocity and profile from its populations: give this key there",
        ),
        None => Ok(()),
    }
}

/// The populations of a medium that is not a mixture: one, or one per size class; with its total
/// σa and its provenance. σs and σa are scaled by the height profile at `height`.
#[allow(clippy::too_many_arguments)]
fn populations_of(
    optics: &mut BTreeMap<String, Optics>,
    ctx: &Ctx,
    wind: Option<&WindProfile>,
    path: &str,
    name: &str,
    ms: &MediumSection,
    velocity: Option<(String, &VelocitySection)>,
    cylinder: Option<&Shape>,
    height: f64,
) -> R<(f64, Vec<Population>, MediumInfo)> {
    if !optics.contains_key(name) {
        let o = resolve_optics(path, ms, ctx)?;
        optics.insert(name.to_string(), o);
    }
    let o = &optics[name];
    let factor = match &ms.height_profile {
        Some(h) => resolve_height_profile(&join(path, "height_profile"), h)?.factor(height),
        None => 1.0,
    };
    let motion = match &ms.motion {
        Some(m) => resolve_motion(&join(path, "motion"), m)?,
        None => Motion::default(),
    };
    let field = |sizes: &[(f64, f64)]| -> R<VelocityField> {
        match &velocity {
            None => Ok(VelocityField::Static),
            Some((p, v)) => {
                resolve_velocity(p, v, FlowCtx { base: ctx.base, files: &ctx.files, cylinder, wind, sizes })
            }
        }
    };
    if o.classes.is_empty() {
        let population = Population {
            name: name.to_string(),
            phase: o.phase.clone(),
            velocity: field(&o.sizes)?,
            motion,
            sigma_s: o.sigma_s * factor,
        };
        return Ok((o.sigma_a * factor, vec![population], o.info.clone()));
    }
    let mut populations = Vec::with_capacity(o.classes.len());
    for (i, c) in o.classes.iter().enumerate() {
        populations.push(Population {
            name: format!("{name}[{i}]"),
            phase: c.phase.clone(),
            velocity: field(&c.sizes)?,
            motion,
            sigma_s: c.sigma_s * factor,
        });
    }
    Ok((o.sigma_a * factor, populations, o.info.clone()))
}

/// `name` names output files: a non-empty word of letters, digits, `_` and `-`.
fn file_name(path: &str, name: &str) -> R<()> {
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
        return err(
            join(path, "name"),
            format!("= \"{name}\": expected a non-empty name of letters, digits, _ and - (it names output files)"),
        );
    }
    Ok(())
}

/// A rectangle of the detector plane from `center_*` (default the origin) and `size_*` (µm, mm,
/// m): its `(min, max)` corners.
fn rectangle(path: &str, center: [Option<[f64; 2]>; 3], size: [Option<[f64; 2]>; 3]) -> R<([f64; 2], [f64; 2])> {
    let c = length_arr(path, "center", center[0], center[1], center[2])?.map_or([0.0; 2], |c| c.0);
    let (s, sp) = length_arr_req(path, "size", size[0], size[1], size[2])?;
    if s.iter().any(|&x| x <= 0.0) {
        return err(sp, format!("= {s:?} m: expected two edge lengths > 0"));
    }
    Ok(([c[0] - 0.5 * s[0], c[1] - 0.5 * s[1]], [c[0] + 0.5 * s[0], c[1] + 0.5 * s[1]]))
}

/// Defaults of an LDH camera: Kim et al. 2025's replica of Puyo et al. 2018 (39 kHz, N_w = 512)
/// with HoloDoppler's M0 band (6–18.3 kHz); see `scene-parameters.md` §A4.
pub const LDH_DEFAULT_FRAME_RATE_HZ: f64 = 39_000.0;
pub const LDH_DEFAULT_WINDOW_SAMPLES: u64 = 512;
pub const LDH_DEFAULT_BAND_HZ: [f64; 2] = [6_000.0, 18_300.0];
pub const LDH_DEFAULT_SPECKLE_WINDOWS: u64 = 16;

fn resolve_ldh(path: &str, l: &LdhSection, im: &ImageSpec) -> R<LdhSpec> {
    let fs = pick(path, &[("frame_rate_hz", l.frame_rate_hz, 1.0), ("frame_rate_khz", l.frame_rate_khz, 1e3)])?
        .map_or(Ok(LDH_DEFAULT_FRAME_RATE_HZ), |v| positive(v, "a camera frame rate"))?;
    let n = l.window_samples.unwrap_or(LDH_DEFAULT_WINDOW_SAMPLES);
    if !(2..=1 << 20).contains(&n) || n % 2 != 0 {
        return err(join(path, "window_samples"), format!("= {n}: expected an even number of samples from 2 to 2^20"));
    }
    let window = match l.window.unwrap_or(WindowKind::Hann) {
        WindowKind::Rect => Window::Rect,
        WindowKind::Hann => Window::Hann,
    };
    let stft = Stft::new(fs, n as usize, window)
        .ok_or_else(|| ConfigError::new(join(path, "frame_rate_hz"), format!("= {fs}: expected a finite rate > 0")))?;
    let (band, band_path) = pick_arr(path, &[("band_hz", l.band_hz, 1.0), ("band_khz", l.band_khz, 1e3)])?
        .unwrap_or((LDH_DEFAULT_BAND_HZ, join(path, "band_hz")));
    let nyquist = 0.5 * fs;
    if !(0.0 < band[0] && band[0] < band[1] && band[1] <= nyquist) {
        let unit = unit_of(&band_path);
        return err(
            band_path,
            format!(
                "= {:?} {}: expected 0 < f1 < f2 ≤ f_s/2 = {nyquist} Hz (the camera's Nyquist frequency)",
                l.band_khz.or(l.band_hz).unwrap_or(band),
                unit
            ),
        );
    }
    let bin = stft.bin_width();
    let axis = match &l.spectrum {
        // The STFT's own frequencies, odd-centred on DC: N_w + 1 bins of f_s/N_w.
        None => FrequencyAxis::new(-(0.5 * n as f64 + 0.5) * bin, (0.5 * n as f64 + 0.5) * bin, n as usize + 1)
            .expect("a valid default axis"),
        Some(s) => {
            let p = join(path, "spectrum");
            let fmin = frequency(&p, "f_min", [s.f_min_hz, s.f_min_khz, None, None], "the lower edge")?;
            let fmax = frequency(&p, "f_max", [s.f_max_hz, s.f_max_khz, None, None], "the upper edge")?;
            let bins = s.bins.unwrap_or(n + 1);
            if !(1..=1_000_000).contains(&bins) {
                return err(join(&p, "bins"), format!("= {bins}: expected 1 to 10^6 bins"));
            }
            FrequencyAxis::new(fmin.0, fmax.0, bins as usize).ok_or_else(|| {
                ConfigError::new(fmax.1.clone(), format!("= {} Hz: expected f_min ({} Hz) < f_max", fmax.0, fmin.0))
            })?
        }
    };
    let mut rois: Vec<Roi> = Vec::new();
    for (i, r) in l.roi.iter().enumerate() {
        let p = format!("{path}.roi[{i}]");
        file_name(&p, &r.name)?;
        if rois.iter().any(|o| o.name == r.name) {
            return err(join(&p, "name"), format!("= \"{}\": ROI names must be unique", r.name));
        }
        let (min, max) = rectangle(&p, [r.center_um, r.center_mm, r.center_m], [r.size_um, r.size_mm, r.size_m])?;
        let roi = Roi { name: r.name.clone(), min, max };
        let inside = |x: f64, y: f64| im.min[0] <= x && x <= im.max[0] && im.min[1] <= y && y <= im.max[1];
        if !(inside(roi.min[0], roi.min[1]) && inside(roi.max[0], roi.max[1])) {
            return err(
                p,
                format!(
                    "the ROI spans x {:?}, y {:?} m, not inside the image (x {:?}, y {:?} m)",
                    [roi.min[0], roi.max[0]],
                    [roi.min[1], roi.max[1]],
                    [im.min[0], im.max[0]],
                    [im.min[1], im.max[1]]
                ),
            );
        }
        rois.push(roi);
    }
    let speckle = match &l.speckle {
        None => None,
        Some(sp) => {
            if rois.is_empty() {
                return err(
                    join(path, "speckle"),
                    "speckle is synthesised for ROIs: add [[detectors.ldh.roi]] entries",
                );
            }
            let w = sp.windows.unwrap_or(LDH_DEFAULT_SPECKLE_WINDOWS);
            if !(1..=1_000_000).contains(&w) {
                return err(join(path, "speckle.windows"), format!("= {w}: expected 1 to 10^6 windows"));
            }
            Some(SpeckleSpec { windows: w as u32 })
        }
    };
    LdhSpec::new(
        stft,
        (band[0], band[1]),
        l.flip_sign.unwrap_or(false),
        l.m1.unwrap_or(false),
        l.by_class.unwrap_or(false),
        rois,
        axis,
        l.pixel_spectra.unwrap_or(false),
        speckle,
    )
    .ok_or_else(|| {
        ConfigError::new(
            join(path, "band_hz"),
            format!("= [{}, {}] Hz holds no STFT bin (bins are {bin} Hz wide): widen the band", band[0], band[1]),
        )
    })
}

/// A monostatic lidar receiver at the source. Its local estimate traces straight shadow rays, so
/// every index in the scene must be 1 (the atmosphere; 1.0003 is within the model's accuracy).
fn resolve_lidar(path: &str, l: &LidarSection, source: &Source, scene: &Scene) -> R<LidarSpec> {
    if scene.n_above != 1.0 {
        return err("ambient.n_above", format!("= {}: a lidar receiver needs n = 1 above the stack", scene.n_above));
    }
    if let Some((i, layer)) = scene.layers.iter().enumerate().find(|(_, l)| l.n != 1.0) {
        return err(
            format!("layers[{i}].n"),
            format!("= {}: a lidar receiver traces straight rays and needs n = 1 in every layer", layer.n),
        );
    }
    let radius = positive(
        require(
            path,
            &[("aperture_radius_mm", l.aperture_radius_mm, 1e-3), ("aperture_radius_m", l.aperture_radius_m, 1.0)],
            "the aperture radius",
        )?,
        "an aperture radius",
    )?;
    let fov = require(
        path,
        &[
            ("field_of_view_urad", l.field_of_view_urad, 1e-6),
            ("field_of_view_mrad", l.field_of_view_mrad, 1e-3),
            ("field_of_view_deg", l.field_of_view_deg, std::f64::consts::PI / 180.0),
        ],
        "the field-of-view half-angle",
    )?;
    if !(fov.0 > 0.0 && fov.0 <= std::f64::consts::FRAC_PI_2) {
        return err(fov.1, format!("= {}: expected a half-angle in (0, 90°]", fov.2));
    }
    let fwhm = positive(
        require(
            path,
            &[("pulse_fwhm_ns", l.pulse_fwhm_ns, 1e-9), ("pulse_fwhm_us", l.pulse_fwhm_us, 1e-6)],
            "the pulse FWHM",
        )?,
        "a pulse width",
    )?;
    let rate = positive(
        require(
            path,
            &[("sample_rate_hz", l.sample_rate_hz, 1.0), ("sample_rate_mhz", l.sample_rate_mhz, 1e6)],
            "the digitiser rate",
        )?,
        "a sample rate",
    )?;
    let first = match l.first_gate_m {
        None => 0.0,
        Some(v) if v.is_finite() && v >= 0.0 => v,
        Some(v) => return err(join(path, "first_gate_m"), format!("= {v}: expected a range ≥ 0 m")),
    };
    let count = |key: &str, v: Option<u64>, default: u64, max: u64| -> R<usize> {
        let v = v.unwrap_or(default);
        if (1..=max).contains(&v) {
            Ok(v as usize)
        } else {
            err(join(path, key), format!("= {v}: expected 1 to {max}"))
        }
    };
    let gate_points = count("gate_points", l.gate_points, 10, 4096)?;
    let gates = count("gates", l.gates, 32, 100_000)?;
    let fft_points = count("fft_points", l.fft_points, gate_points.next_power_of_two().max(64) as u64, 65_536)?;
    if fft_points < gate_points {
        return err(join(path, "fft_points"), format!("= {fft_points}: expected at least gate_points ({gate_points})"));
    }
    if gates * fft_points > 20_000_000 {
        return err(join(path, "gates"), format!("= {gates}: gates × fft_points must stay below 2·10^7 (memory)"));
    }
    let pulse_energy = match pick(
        path,
        &[("pulse_energy_uj", l.pulse_energy_uj, 1e-6), ("pulse_energy_mj", l.pulse_energy_mj, 1e-3)],
    )? {
        Some(v) => positive(v, "a pulse energy")?,
        None => crate::detect::lidar::DEFAULT_PULSE_ENERGY,
    };
    let efficiency = |key: &str, v: Option<f64>, default: f64| -> R<f64> {
        match v {
            None => Ok(default),
            Some(v) if v > 0.0 && v <= 1.0 => Ok(v),
            Some(v) => err(join(path, key), format!("= {v}: expected an efficiency in (0, 1]")),
        }
    };
    let quantum_efficiency =
        efficiency("quantum_efficiency", l.quantum_efficiency, crate::detect::lidar::DEFAULT_QUANTUM_EFFICIENCY)?;
    let heterodyne_efficiency = efficiency(
        "heterodyne_efficiency",
        l.heterodyne_efficiency,
        crate::detect::lidar::DEFAULT_HETERODYNE_EFFICIENCY,
    )?;
    Ok(LidarSpec {
        position: source.position,
        axis: source.direction,
        aperture_radius: radius,
        cos_fov: fov.0.cos(),
        pulse_fwhm: fwhm,
        sample_rate: rate,
        first_sample_time: 2.0 * first / crate::SPEED_OF_LIGHT,
        gate_points,
        gates,
        fft_points,
        wavelength: source.wavelength,
        pulse_energy,
        quantum_efficiency,
        heterodyne_efficiency,
    })
}

fn resolve_detectors(ds: &[DetectorSection], scene: &Scene) -> R<Vec<Detector>> {
    let mut out: Vec<Detector> = Vec::new();
    for (i, d) in ds.iter().enumerate() {
        let path = format!("detectors[{i}]");
        file_name(&path, &d.name)?;
        if out.iter().any(|o| o.name == d.name) {
            return err(join(&path, "name"), format!("= \"{}\": detector names must be unique", d.name));
        }
        let side = match d.side.unwrap_or(SideKind::Top) {
            SideKind::Top => Side::Top,
            SideKind::Bottom => {
                if !scene.z_bottom().is_finite() {
                    return err(
                        join(&path, "side"),
                        "= \"bottom\": the stack ends in a semi-infinite layer, so nothing leaves through a bottom",
                    );
                }
                Side::Bottom
            }
        };
        let outward = if side == Side::Top { DVec3::NEG_Z } else { DVec3::Z };
        let axis = match d.axis {
            None => outward,
            Some(a) => {
                let a = unit_vector(&join(&path, "axis"), a)?;
                if a.dot(outward) <= 0.0 {
                    return err(
                        join(&path, "axis"),
                        format!(
                            "= {:?}: must point away from the stack ({} z for a {} detector)",
                            d.axis.unwrap(),
                            if side == Side::Top { "negative" } else { "positive" },
                            if side == Side::Top { "top" } else { "bottom" }
                        ),
                    );
                }
                a
            }
        };
        let half = d.acceptance_half_angle_deg.unwrap_or(90.0);
        if !(half > 0.0 && half <= 90.0) {
            return err(
                join(&path, "acceptance_half_angle_deg"),
                format!("= {half}: expected a half-angle in (0, 90] degrees"),
            );
        }
        let distance = match length(&path, "distance", d.distance_um, d.distance_mm, d.distance_m)? {
            None => 0.0,
            Some(v) => non_negative(v, "a distance from the surface")?,
        };
        let area = match d.area.as_ref().unwrap_or(&AreaSection::All {}) {
            AreaSection::All {} => Area::All,
            AreaSection::Disk { center_um, center_mm, center_m, radius_um, radius_mm, radius_m } => {
                let p = join(&path, "area");
                let c = length_arr(&p, "center", *center_um, *center_mm, *center_m)?.map_or([0.0; 2], |c| c.0);
                let r = positive(length_req(&p, "radius", *radius_um, *radius_mm, *radius_m)?, "a radius")?;
                Area::Disk { center: c, radius: r }
            }
            AreaSection::Rect { center_um, center_mm, center_m, size_um, size_mm, size_m } => {
                let (min, max) = rectangle(
                    &join(&path, "area"),
                    [*center_um, *center_mm, *center_m],
                    [*size_um, *size_mm, *size_m],
                )?;
                Area::Rect { min, max }
            }
        };
        let spectrum = match &d.spectrum {
            None => None,
            Some(s) => {
                let p = join(&path, "spectrum");
                let fmin = frequency(
                    &p,
                    "f_min",
                    [s.f_min_hz, s.f_min_khz, s.f_min_mhz, s.f_min_ghz],
                    "the lower edge of the frequency axis",
                )?;
                let fmax = frequency(
                    &p,
                    "f_max",
                    [s.f_max_hz, s.f_max_khz, s.f_max_mhz, s.f_max_ghz],
                    "the upper edge of the frequency axis",
                )?;
                let bins = s.bins.unwrap_or(256);
                if !(1..=10_000_000).contains(&bins) {
                    return err(join(&p, "bins"), format!("= {bins}: expected 1 to 10^7 bins"));
                }
                let axis = FrequencyAxis::new(fmin.0, fmax.0, bins as usize).ok_or_else(|| {
                    ConfigError::new(
                        fmax.1.clone(),
                        format!("= {} Hz: expected finite edges with f_min ({} Hz) < f_max", fmax.0, fmin.0),
                    )
                })?;
                let split = |key: &str, v: Option<u64>| -> R<Option<u32>> {
                    match v {
                        None => Ok(None),
                        Some(k) if (1..=1000).contains(&k) => Ok(Some(k as u32)),
                        Some(k) => {
                            err(join(&p, key), format!("= {k}: expected K from 1 to 1000 (channels 0 … K−1 and ≥ K)"))
                        }
                    }
                };
                Some(SpectrumSpec {
                    axis,
                    by_order: split("by_order", s.by_order)?,
                    by_doppler_events: split("by_doppler_events", s.by_doppler_events)?,
                })
            }
        };
        let image = match &d.image {
            None => None,
            Some(im) => {
                let Some((min, max)) = area.bounds() else {
                    return err(
                        join(&path, "image"),
                        "an image needs a bounded detector area (area.type = \"disk\" or \"rect\")",
                    );
                };
                let [nx, ny] = im.pixels;
                if !(1..=16_384).contains(&nx) || !(1..=16_384).contains(&ny) {
                    return err(
                        join(&path, "image.pixels"),
                        format!("= {:?}: expected [nx, ny], each 1 to 16384", im.pixels),
                    );
                }
                Some(ImageSpec { nx: nx as usize, ny: ny as usize, min, max })
            }
        };
        let next_event = d.next_event.unwrap_or(false);
        if next_event && side != Side::Top {
            return err(
                join(&path, "next_event"),
                "= true: next-event estimation scores top detectors only (shadow rays leave through z = 0)",
            );
        }
        out.push(Detector {
            name: d.name.clone(),
            kind: DetectorKind::Surface(Surface {
                side,
                distance,
                area,
                axis,
                cos_acceptance: if half >= 90.0 { 0.0 } else { half.to_radians().cos() },
                include_specular: d.include_specular.unwrap_or(true),
                spectrum,
                image,
                ldh: None,
                next_event,
            }),
        });
        if let Some(l) = &d.ldh {
            let p = join(&path, "ldh");
            let Some(im) = image else {
                return err(p, "an LDH camera needs the detector's image (add [detectors.image] pixels = [nx, ny])");
            };
            if out.iter().any(|o| o.ldh().is_some()) {
                return err(p, "only one detector may be an LDH camera");
            }
            let ldh = resolve_ldh(&p, l, &im)?;
            if let Some(DetectorKind::Surface(s)) = out.last_mut().map(|d| &mut d.kind) {
                s.ldh = Some(Box::new(ldh));
                s.next_event = true;
            }
        }
    }
    Ok(out)
}

/// Give `m` the density of its section, if it has one: built once per named medium (`built`),
/// shared by every layer, sublayer and region that uses it.
fn attach_density(
    path: &str,
    ms: &MediumSection,
    m: &mut Medium,
    ctx: &Ctx,
    built: &mut BTreeMap<String, Arc<Heterogeneity>>,
) -> R<()> {
    let Some(d) = &ms.density else { return Ok(()) };
    let h = match built.get(&m.name) {
        Some(h) => h.clone(),
        None => {
            let h = Arc::new(resolve_density(&join(path, "density"), d, m.sigma_t(), ctx)?);
            built.insert(m.name.clone(), h.clone());
            h
        }
    };
    m.set_shared_heterogeneity(h);
    Ok(())
}

fn majorant_kind(m: Option<MajorantSection>) -> MajorantKind {
    match m {
        None | Some(MajorantSection::Grid) => MajorantKind::Grid,
        Some(MajorantSection::Global) => MajorantKind::Global,
    }
}

/// `density = { type = "ramp" | "vdb", … }`.
fn resolve_density(path: &str, d: &DensitySection, sigma_t: f64, ctx: &Ctx) -> R<Heterogeneity> {
    match d {
        DensitySection::Vdb {
            file,
            grid,
            albedo_grid,
            interpolation: i,
            scale,
            translate_um,
            translate_mm,
            translate_m,
            majorant,
            majorant_cell_voxels,
        } => {
            let density = ctx.files.float(path, ctx.base, file, grid.as_deref())?;
            let albedo = match albedo_grid {
                Some(name) => Some(ctx.files.float(path, ctx.base, file, Some(name))?),
                None => None,
            };
            let place = resolve_placement(path, *scale, *translate_um, *translate_mm, *translate_m)?;
            let majorant = resolve_majorant(path, *majorant, *majorant_cell_voxels, sigma_t)?;
            let mut h = grid_heterogeneity(
                path,
                Arc::unwrap_or_clone(density),
                albedo.map(Arc::unwrap_or_clone),
                place,
                interpolation(*i),
                majorant,
            )?;
            h.info.kind = "vdb".into();
            h.info.source = Some(format!("{file}:{}", grid.as_deref().unwrap_or("(first float grid)")));
            Ok(h)
        }
        DensitySection::Ramp {
            axis,
            from_um,
            from_mm,
            from_m,
            to_um,
            to_mm,
            to_m,
            density_from,
            density_to,
            majorant,
        } => {
            let a = match axis.as_str() {
                "x" => 0,
                "y" => 1,
                "z" => 2,
                other => return err(join(path, "axis"), format!("= \"{other}\": expected \"x\", \"y\" or \"z\"")),
            };
            let from = length_req(path, "from", *from_um, *from_mm, *from_m)?;
            let to = length_req(path, "to", *to_um, *to_mm, *to_m)?;
            for g in [&from, &to] {
                if !g.0.is_finite() {
                    return err(g.1.clone(), format!("= {}: expected a finite position {}", g.2, unit_of(&g.1)));
                }
            }
            if from.0 == to.0 {
                return err(
                    to.1,
                    format!("= {}: the ramp's two planes coincide (from = to); give two different positions", to.2),
                );
            }
            for (key, v) in [("density_from", density_from), ("density_to", density_to)] {
                if !(v.is_finite() && *v >= 0.0) {
                    return err(
                        join(path, key),
                        format!("= {v}: expected a density ≥ 0 (a factor on σa and σs, no unit)"),
                    );
                }
            }
            let kind = majorant_kind(*majorant);
            let ramp = Ramp::new(a, from.0, to.0, *density_from, *density_to, kind)
                .ok_or_else(|| ConfigError::new(path, "not a valid ramp"))?;
            let (min, max) = ramp.range();
            let info = DensityInfo { kind: "ramp".into(), majorant: Some(kind), min, max, ..DensityInfo::default() };
            Ok(Heterogeneity { density: Density::Ramp(ramp), albedo: None, info })
        }
    }
}

/// The majorant settings of a grid density from its keys `majorant` and `majorant_cell_voxels`
/// under `path` (for the file-backed densities), of a medium with extinction `sigma_t` (1/m) at
/// density 1: without `majorant_cell_voxels` the cell size is chosen for it ([`CellSize::Auto`]).
pub fn resolve_majorant(
    path: &str,
    kind: Option<MajorantSection>,
    cell_voxels: Option<u64>,
    sigma_t: f64,
) -> R<MajorantSpec> {
    let kind = majorant_kind(kind);
    let cell = match cell_voxels {
        None => CellSize::Auto { sigma_t },
        Some(_) if kind == MajorantKind::Global => {
            return err(join(path, "majorant_cell_voxels"), "only applies with majorant = \"grid\"");
        }
        Some(n) if (1..=4096).contains(&n) => CellSize::Voxels(n as usize),
        Some(n) => {
            return err(
                join(path, "majorant_cell_voxels"),
                format!("= {n}: expected 1 to 4096 voxels per majorant cell edge"),
            );
        }
    };
    Ok(MajorantSpec { kind, cell })
}

/// The medium fields of a voxel-grid density: the hook the file loaders call (`path` is the key
/// of the `density` table, for messages). `density` is scaled onto σa and σs (negative voxels
/// are clamped to 0 and counted in the manifest), `albedo` (values in [0, 1]) overrides the
/// single-scattering albedo at a collision; both are placed by their own index-to-world map and
/// then `placement`, and read with `interpolation`.
pub fn grid_heterogeneity(
    path: &str,
    density: VoxelGrid<f32>,
    albedo: Option<VoxelGrid<f32>>,
    placement: Placement,
    interpolation: Interpolation,
    majorant: MajorantSpec,
) -> R<Heterogeneity> {
    let voxels = density.dims;
    let describe = |e: GridError, what: &str| -> ConfigError {
        let (key, msg) = match e {
            GridError::NotFinite(None) => (what.to_string(), "the background value is not a finite number".to_string()),
            GridError::NotFinite(Some(ijk)) => (what.to_string(), format!("voxel {ijk:?} is not a finite number")),
            GridError::AlbedoRange(None, v) => (what.to_string(), format!("background albedo {v}: expected 0 to 1")),
            GridError::AlbedoRange(Some(ijk), v) => {
                (what.to_string(), format!("voxel {ijk:?} = {v}: expected an albedo from 0 to 1"))
            }
            GridError::Placement => (
                "placement".to_string(),
                format!(
                    "scale {} / translation {:?}: expected a finite scale > 0 and a finite translation in m",
                    placement.scale,
                    placement.translation.to_array()
                ),
            ),
            GridError::CellVoxels(n) => ("majorant_cell_voxels".to_string(), format!("= {n}: expected 1 to 4096")),
        };
        ConfigError::new(join(path, &key), msg)
    };
    let (grid, clamped) =
        GridDensity::new(density, interpolation, placement, majorant).map_err(|e| describe(e, "density"))?;
    let albedo = albedo
        .map(|a| Heterogeneity::albedo_grid(a, interpolation, placement))
        .transpose()
        .map_err(|e| describe(e, "albedo"))?;
    let info = DensityInfo {
        kind: "grid".into(),
        interpolation: Some(interpolation),
        majorant: Some(majorant.kind),
        majorant_cells: grid.majorant.as_ref().map(|m| m.dims),
        majorant_cell_voxels: grid.majorant_cell_voxels(),
        voxels: Some(voxels),
        negative_voxels_clamped: clamped,
        min: grid.min,
        max: grid.max,
        albedo_grid: albedo.is_some(),
        source: None,
    };
    Ok(Heterogeneity { density: Density::Grid(grid), albedo, info })
}
