//! The one step from the schema to validated SI runtime objects, and the only producer of
//! configuration errors. Each check names the key path, the value and the expected range and unit.
//!
//! One submodule per part of the runtime it builds: `run` (the run plan),
//! `source` (laser, pointings), `flow` (velocity fields, wind, height profiles, motion), `media`
//! (optics, Mie particles, size classes, mixtures, populations), `scene` (shapes, layers,
//! regions), `density` (ramps, voxel grids, majorants) and `detectors` (areas, spectra, images,
//! LDH, lidar). This module holds the entry points, the cross-checks between parts (lidar, LDH
//! and chirp; references; the memory budget) and the helpers they share.

mod cardiac;
mod density;
mod detectors;
mod flow;
mod lateral;
mod media;
mod run;
mod scene;
mod source;
mod surfaces;
mod volume;

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use glam::DVec3;

pub use self::density::{grid_heterogeneity, resolve_majorant};
pub use self::detectors::{
    LDH_DEFAULT_BAND_HZ, LDH_DEFAULT_FRAME_RATE_HZ, LDH_DEFAULT_SPECKLE_WINDOWS, LDH_DEFAULT_WINDOW_SAMPLES,
};
use self::detectors::{resolve_detectors, resolve_lidar};
use self::lateral::resolve_lateral;
use self::run::resolve_run;
pub use self::run::{budget_key, lowered_budget};
use self::scene::resolve_scene;
use self::source::resolve_source;
use self::surfaces::{camera_lobes, resolve_bottom, resolve_opaque};
use self::volume::resolve_volume;
use super::schema::*;
use super::units::{Quantity, UnitSet, unit_of};
use crate::detect::{DetectorKind, EstimatorChoice};
use crate::error::ConfigError;
use crate::experiment::Experiment;
use crate::medium::grid::VoxelGrid;

type R<T> = Result<T, ConfigError>;

fn err<T>(path: impl Into<String>, msg: impl Into<String>) -> R<T> {
    Err(ConfigError::new(path, msg))
}

fn join(prefix: &str, key: &str) -> String {
    if prefix.is_empty() { key.to_string() } else { format!("{prefix}.{key}") }
}

/// A number as a message shows it: as written for ordinary magnitudes, in exponent form beyond
/// (`1e100`, not a hundred digits).
fn shown(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e9).contains(&x.abs()) { format!("{x}") } else { format!("{x:e}") }
}

/// The factor of a key's unit to SI (1 without a unit).
fn factor(key: &str) -> f64 {
    super::units::split_key(key).map_or(1.0, |(_, u)| u.factor)
}

/// The last part of a key path (`f_max_hz` of `detectors[0].spectrum.f_max_hz`).
fn last(key: &str) -> &str {
    key.rsplit('.').next().unwrap_or(key)
}

/// A quantity as given: its SI value, the key path it came from and the number as written.
type Given = (f64, String, f64);

/// A quantity, if given: its SI value with the key path as written; NaN is refused.
fn given<S>(prefix: &str, q: &Option<Quantity<S>>) -> R<Option<Given>> {
    let Some(q) = q else { return Ok(None) };
    let path = join(prefix, &q.key);
    if q.value.is_nan() {
        return err(path, "= nan: expected a number");
    }
    Ok(Some((q.si(), path, q.value)))
}

/// A required quantity `name` (`what` for the message that lists its keys).
fn require<S: UnitSet>(prefix: &str, name: &str, q: &Option<Quantity<S>>, what: &str) -> R<Given> {
    given(prefix, q)?
        .map_or_else(|| err(prefix, format!("missing {what}: give one of {}", S::keys(name).join(", "))), Ok)
}

/// Same as [`given`] for fixed-size arrays, whose numbers must all be finite.
fn given_arr<S, const N: usize>(prefix: &str, q: &Option<Quantity<S, [f64; N]>>) -> R<Option<([f64; N], String)>> {
    let Some(q) = q else { return Ok(None) };
    let path = join(prefix, &q.key);
    if q.value.iter().any(|x| !x.is_finite()) {
        return err(path, format!("= {:?}: expected finite numbers", q.value));
    }
    Ok(Some((q.si(), path)))
}

fn require_arr<S: UnitSet, const N: usize>(
    prefix: &str,
    name: &str,
    q: &Option<Quantity<S, [f64; N]>>,
    what: &str,
) -> R<([f64; N], String)> {
    given_arr(prefix, q)?
        .map_or_else(|| err(prefix, format!("missing {what}: give one of {}", S::keys(name).join(", "))), Ok)
}

fn positive(v: Given, what: &str) -> R<f64> {
    if v.0.is_finite() && v.0 > 0.0 {
        Ok(v.0)
    } else {
        let unit = unit_of(&v.1);
        err(v.1, format!("= {}: expected {what} > 0 {unit}", shown(v.2)))
    }
}

fn non_negative(v: Given, what: &str) -> R<f64> {
    if v.0.is_finite() && v.0 >= 0.0 {
        Ok(v.0)
    } else {
        let unit = unit_of(&v.1);
        err(v.1, format!("= {}: expected {what} ≥ 0 {unit}", shown(v.2)))
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
    let ctx = Ctx {
        base,
        wavelength: source.wavelength,
        files: GridFiles::default(),
        memory: Memory::new(plan.memory_budget, plan.memory_limited_by),
        scene_copies: 1 + source.pointings.len().max(1) as u64,
        cardiac: cardiac::resolve_cardiac(f.cardiac.as_ref(), base)?,
    };
    let mut scene = resolve_scene(f, n_above, n_below, &ctx)?;
    scene.cycle = cardiac::scene_cycle(ctx.cardiac.as_ref(), &scene);
    let mut detectors = resolve_detectors(&f.detectors, &scene, &source)?;
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
            let distance = d.distance.as_ref().map(|q| q.key.as_str());
            let given = [
                ("side", d.side.is_some()),
                ("area", d.area.is_some()),
                ("acceptance_half_angle_deg", d.acceptance_half_angle.is_some()),
                ("axis", d.axis.is_some()),
                ("monostatic", d.monostatic.is_some()),
                (distance.unwrap_or("distance"), distance.is_some()),
                ("include_specular", d.include_specular.is_some()),
                ("next_event", d.next_event.is_some()),
                ("estimator", d.estimator.is_some()),
                ("spectrum", d.spectrum.is_some()),
                ("image", d.image.is_some()),
                ("time", d.time.is_some()),
                ("correlation", d.correlation.is_some()),
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
    check_chirp_ranges(f, &source, &detectors)?;
    let scene = scene;
    if plan.walk.gate.is_some()
        && let Some(i) =
            detectors.iter().position(|d| d.surface().is_some_and(|s| s.choice != EstimatorChoice::Forward))
    {
        return err(
            format!("detectors[{i}].estimator"),
            "a time gate (run.time_gate_ns) applies to the paths from the laser: use estimator = \"forward\"",
        );
    }
    let mut scene = scene;
    scene.lateral = resolve_lateral(f.lateral.as_ref(), n_above, &source, &detectors)?;
    scene.bottom = resolve_bottom(f.bottom.as_ref(), &scene, source.wavelength, &detectors)?;
    resolve_opaque(&f.opaque, &mut scene, source.wavelength, &detectors)?;
    camera_lobes(&scene, &detectors)?;
    if scene.bottom.is_some() {
        // The surface lies on the last layer's bottom plane: no interface of index there (the
        // walk meets the surface where it would refract out; reflections below see no step).
        scene.n_below = scene.layers.last().map_or(scene.n_below, |l| l.n);
    }
    if scene.cycle.is_some() {
        cardiac::check_pulsatile_run(f, &plan, &detectors)?;
    }
    let mut exp = Experiment {
        name: f.name.clone().unwrap_or_else(|| "experiment".to_string()),
        scene,
        source,
        detectors,
        plan,
        references: Vec::new(),
        volume: resolve_volume(f.volume.as_ref())?,
    };
    if exp.plan.walk.control_variate == crate::transport::ControlVariate::Layered
        && let Some(why) = crate::transport::control_variate_obstacle(&exp.scene, &exp.source, &exp.detectors)
    {
        return err(
            "run.control_variate",
            format!("= \"layered\": the layered control variate does not apply here: {why}; use \"auto\" or \"off\""),
        );
    }
    // As `"layered"` above: a table asked for by name where none can be made (no detector is the
    // main output, or the one that is cannot be steered) would do nothing (issue 52, item 8);
    // `"auto"` applies where it can, and `ohd check` says why not.
    {
        use crate::transport::windows::Importance;
        let asked = match exp.plan.importance {
            Importance::Table => Some("table"),
            Importance::Windows => Some("windows"),
            Importance::Guided => Some("guided"),
            Importance::Off | Importance::Auto => None,
        };
        if let Some(asked) = asked
            && let Some(why) = exp.importance_obstacle()
        {
            return err(
                "run.importance",
                format!(
                    "= \"{asked}\": no importance table can be made here: {why} (the table is of the main output's \
                     detector, a forward-estimated surface detector); use \"auto\" or \"off\""
                ),
            );
        }
    }
    check_speckle_memory(&exp, &ctx.memory)?;
    check_memory(&exp, &ctx.memory)?;
    exp.plan.memory = ctx.memory.blocks.take();
    exp.references = resolve_references(&f.reference, &exp)?;
    Ok(exp)
}

/// With a chirp of bandwidth `B > 0` over `T`, the ranges the FMCW retrieval reads off a
/// detector's spectrum axis finite (issue 33, item 8): the range of one bin, `c·T·Δf/(2B)`, and of
/// the beats at the axis's ends, `c·T·(f_up + f_down)/(4B)`, computed as
/// [`crate::retrieval::fmcw`] computes them.
fn check_chirp_ranges(
    f: &ExperimentFile,
    source: &crate::source::Source,
    detectors: &[crate::detect::Detector],
) -> R<()> {
    let Some(chirp) = source.chirp.as_ref().filter(|c| c.bandwidth > 0.0) else { return Ok(()) };
    let (b, t) = (chirp.bandwidth, chirp.duration);
    let ct = crate::SPEED_OF_LIGHT * t;
    for (i, d) in detectors.iter().enumerate() {
        let Some(axis) = d.surface().and_then(|s| s.spectrum()).map(|s| s.axis) else { continue };
        let edge = axis.f_min.abs().max(axis.f_max.abs());
        if (ct * axis.bin_width() / (2.0 * b)).is_finite() && (ct * (2.0 * edge) / (4.0 * b)).is_finite() {
            continue;
        }
        let q = f.detectors[i].spectrum.as_ref().and_then(|s| s.f_max.as_ref());
        let (key, written) = q.map_or_else(
            || (format!("detectors[{i}].spectrum"), String::new()),
            |q| (format!("detectors[{i}].spectrum.{}", q.key), format!("= {} {}: ", shown(q.value), unit_of(&q.key))),
        );
        return err(
            key,
            format!(
                "{written}expected an axis whose beat frequencies convert to finite ranges with source.chirp (B = {} Hz, T = {} s): c·T·(f_up + f_down)/(4B) at the axis's ends and c·T·Δf/(2B) for one bin overflow; narrow the axis",
                shown(b),
                shown(t)
            ),
        );
    }
    Ok(())
}

/// `[reference]`: each key a named output of the experiment, each value finite and of its size,
/// given as its file holds it; stored in the tally's convention (an M0− written with `flip_sign`
/// is negated back, an image's rows put back to row 0 = the lowest `y`).
fn resolve_references(refs: &BTreeMap<String, ReferenceValue>, exp: &Experiment) -> R<Vec<(String, Vec<f64>)>> {
    if refs.is_empty() {
        return Ok(Vec::new());
    }
    let outputs = exp.outputs();
    let mut out = Vec::with_capacity(refs.len());
    for (name, value) in refs {
        let path = format!("reference.{name}");
        let Some(o) = outputs.iter().find(|o| &o.name == name) else {
            let names = crate::error::list(outputs.iter().map(|o| &o.name));
            return err(path, format!("is not an output of this experiment; expected one of {names}"));
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
        out.push((name.clone(), o.to_tally(&values)));
    }
    Ok(out)
}

/// Default of `run.memory_budget_gib`.
pub const DEFAULT_MEMORY_BUDGET_GIB: f64 = 8.0;

/// Refuse an experiment whose tallies ([`Experiment::memory_estimate`]: the tally vector times
/// the mean, the variance and the larger of the batches in flight and what writing makes),
/// together with what was counted before them (`memory`: media, grids), exceed
/// `run.memory_budget_gib`, before anything is allocated. The error names the key of the largest
/// block of tallies.
fn check_memory(exp: &Experiment, memory: &Memory) -> R<()> {
    let need = exp.memory_estimate();
    let Some(over) = memory.over(need) else { return Ok(()) };
    let layout = exp.output_layout();
    let blocks = layout.registry.budget_blocks();
    let (key, value) = blocks
        .into_iter()
        .max_by_key(|b| b.2)
        .map_or(("run.memory_budget_gib".to_string(), String::new()), |b| (b.0, b.1));
    err(
        key,
        format!(
            "{value}: the tallies need {} ({} tallies × 8 bytes × (2 + the larger of the batches in flight and 4 for writing)){over}",
            bytes_shown(need),
            layout.tallies(),
        ),
    )
}

/// Bytes of one recorded detection for speckle ([`crate::detect::RecordedLine`]).
const RECORDED_LINE_BYTES: u64 = std::mem::size_of::<crate::detect::RecordedLine>() as u64;

/// Count what an LDH camera's speckle keeps and makes: the detections in its regions of
/// interest, recorded for the whole run (estimated as one per path: a path reaches the camera
/// at most once, but may fall in several overlapping regions) and the spectra synthesised from
/// them (expected periodogram and both algorithms' windows per region).
fn check_speckle_memory(exp: &Experiment, memory: &Memory) -> R<()> {
    for (i, d) in exp.detectors.iter().enumerate() {
        let Some(ldh) = d.ldh() else { continue };
        let Some(sp) = ldh.speckle else { continue };
        let samples = exp.plan.samples();
        let lines = samples.saturating_mul(RECORDED_LINE_BYTES);
        let n = ldh.stft.samples() as u64;
        let windows = u64::from(sp.windows);
        let spectra = (ldh.rois.len() as u64).saturating_mul(n.saturating_mul(1 + 2 * windows) * 8);
        // Per pixel: M0± of every window and the expected M0+.
        let pixels = d.surface().and_then(|s| s.image()).map_or(0, |im| (im.nx * im.ny) as u64);
        let per_pixel = if sp.pixels { pixels.saturating_mul((2 * windows + 1) * 8) } else { 0 };
        memory.charge(
            &format!("detectors[{i}].ldh.speckle"),
            "",
            &format!("the speckle of detectors[{i}] (run.samples = {samples})"),
            &format!(
                "{RECORDED_LINE_BYTES} bytes per detection recorded in a region of interest, one per path, and the synthesised windows"
            ),
            lines.saturating_add(spectra).saturating_add(per_pixel),
        )?;
    }
    Ok(())
}

/// What resolving needs besides the file: where relative paths start, the wavelength media
/// are computed for, the grids read so far and the memory counted so far.
struct Ctx<'a> {
    base: &'a Path,
    wavelength: f64,
    files: GridFiles,
    memory: Memory,
    /// How many copies of the scene a run holds: the experiment as resolved, and one per part it
    /// runs (a plain run's part is a copy; a scan makes one per pointing).
    scene_copies: u64,
    /// `[cardiac]`: the heart rate and waveforms of pulsatile flows.
    cardiac: Option<cardiac::Cardiac>,
}

/// What an experiment will hold in memory, counted while it is resolved (issue 21, item 3: four
/// layers of 10⁵ sublayers each grew to 5.8 GB in `ohd check` and aborted; the budget counted the
/// tallies only). Each sizeable block — the media of the layers and regions, voxel grids, speckle
/// records, the tallies — is charged, with the key that asks for it, *before* it is allocated,
/// and the experiment is refused (a configuration error, exit status 2) once the blocks together
/// exceed `run.memory_budget_gib`. Small things (phase tables of at most 10⁵ angles, the source,
/// the detectors' settings) are not counted.
struct Memory {
    budget: u64,
    /// The process's limit that lowered the budget, if one did.
    limited_by: Option<&'static str>,
    blocks: std::cell::RefCell<Vec<crate::experiment::MemoryBlock>>,
}

/// `bytes` in binary units (`21.8 KiB`, `4.3 GiB`).
fn bytes_shown(bytes: u64) -> String {
    let b = bytes as f64;
    match bytes {
        0..1024 => format!("{bytes} B"),
        1024..1_048_576 => format!("{:.1} KiB", b / 1024.0),
        1_048_576..1_073_741_824 => format!("{:.1} MiB", b / 1_048_576.0),
        _ => format!("{:.1} GiB", b / 1_073_741_824.0),
    }
}

impl Memory {
    fn new(budget: u64, limited_by: Option<&'static str>) -> Self {
        Memory { budget, limited_by, blocks: Default::default() }
    }

    /// Bytes counted so far.
    fn used(&self) -> u64 {
        self.blocks.borrow().iter().fold(0, |a, b| a.saturating_add(b.bytes))
    }

    /// Bytes left under the budget.
    fn remaining(&self) -> u64 {
        self.budget.saturating_sub(self.used())
    }

    /// What is refused when `bytes` more would exceed the budget: the blocks counted before and
    /// the budget, for the end of a message.
    fn over(&self, bytes: u64) -> Option<String> {
        let before = self.used();
        if before.saturating_add(bytes) <= self.budget {
            return None;
        }
        let counted = if before == 0 {
            String::new()
        } else {
            let blocks = self.blocks.borrow();
            let list: Vec<String> =
                blocks.iter().take(4).map(|b| format!("{} {}", b.what, bytes_shown(b.bytes))).collect();
            let more = if blocks.len() > 4 { format!(", and {} more", blocks.len() - 4) } else { String::new() };
            format!("; with the {} counted before it ({}{more}) that is", bytes_shown(before), list.join(", "))
        };
        // The budget in GiB, as the key gives it: to 0.1 GiB, or 3 significant digits below.
        let gib = self.budget as f64 / (1u64 << 30) as f64;
        // (The budget in bytes is truncated: 0.1 GiB comes back as 0.09999999963.)
        let digits = if gib >= 0.095 { 1 } else { (2 - gib.log10().floor() as i32).max(1) as usize };
        let gib = format!("{gib:.digits$}");
        let gib = if digits > 1 { gib.trim_end_matches('0').to_string() } else { gib };
        let key = run::budget_key(self.limited_by);
        Some(format!("{counted} above the memory budget of {gib} GiB ({key})"))
    }

    /// Count `bytes` for `what` (named for `ohd check` and messages), asked for by the key `key`
    /// (written `value`), or refuse it above the budget with a message naming the key, what needs
    /// the memory (`how`: how it is counted) and the budget.
    fn charge(&self, key: &str, value: &str, what: &str, how: &str, bytes: u64) -> R<()> {
        self.charge_ahead(key, value, what, how, bytes, 0)
    }

    /// [`Memory::charge`] `bytes`, refusing them already if with `ahead` — bytes that follow from
    /// them and are charged once made (a `.npy` density's majorant grid) — they would be above the
    /// budget: nothing is read that would then be refused, and nothing is counted twice.
    fn charge_ahead(&self, key: &str, value: &str, what: &str, how: &str, bytes: u64, ahead: u64) -> R<()> {
        let all = bytes.saturating_add(ahead);
        if let Some(over) = self.over(all) {
            let value = if value.is_empty() { String::new() } else { format!("{value}: ") };
            return err(key, format!("{value}{what} would take {} ({how}){over}", bytes_shown(all)));
        }
        let mut blocks = self.blocks.borrow_mut();
        match blocks.last_mut() {
            // One block for many charges of the same thing (the regions' media).
            Some(last) if last.what == what => last.bytes = last.bytes.saturating_add(bytes),
            _ => blocks.push(crate::experiment::MemoryBlock { what: what.to_string(), bytes }),
        }
        Ok(())
    }
}

/// A voxel of a `.npy` volume: `C` floats per voxel of the array.
trait NpyVoxel: Copy + Default {
    const C: usize;
    /// Set component `c` (< `C`) to `v`.
    fn set(&mut self, c: usize, v: f32);
}

impl NpyVoxel for f32 {
    const C: usize = 1;
    fn set(&mut self, _: usize, v: f32) {
        *self = v;
    }
}

impl NpyVoxel for [f32; 3] {
    const C: usize = 3;
    fn set(&mut self, c: usize, v: f32) {
        self[c] = v;
    }
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
    /// The `.npy` volume `file` (relative to `base`) as a voxel grid of [`NpyVoxel::C`]
    /// components per voxel (1: a density, a `(nx, ny, nz)` array; 3: a velocity,
    /// `(nx, ny, nz, 3)`), indexed `array[i, j, k]` = voxel `(i, j, k)` along x, y, z, with voxel
    /// `(0, 0, 0)`'s centre at `transform.translation` and 0 outside the array. Errors name `key`.
    ///
    /// Only the header is read before the grid is counted in `memory` — `copies` times (as a VDB
    /// grid, [`GridFiles::get`]), with what the caller builds from it (`derived`: what it is and
    /// its bytes for the grid's dimensions, such as a majorant grid) — so a volume above the
    /// budget is refused before anything is allocated (issue 52, item 3: one read whole, then
    /// converted, took four times the budget and aborted). The data then stream into the grid.
    fn npy<T: NpyVoxel>(
        key: &str,
        (base, memory): (&Path, &Memory),
        file: &str,
        transform: crate::medium::grid::IndexTransform,
        copies: u64,
        derived: impl Fn([usize; 3]) -> Option<(String, u64)>,
    ) -> R<VoxelGrid<T>> {
        let path = base.join(file);
        let key = join(key, "file");
        let volume = crate::io::formats::npy::open_volume(&path).map_err(|m| ConfigError::new(&key, m))?;
        let shape = volume.header.shape.clone();
        let expected = if T::C == 1 { "(nx, ny, nz)" } else { "(nx, ny, nz, 3)" };
        let shape_ok = shape.len() == if T::C == 1 { 3 } else { 4 } && (T::C == 1 || shape[3] == 3);
        let dims = [
            shape.first().copied().unwrap_or(0),
            shape.get(1).copied().unwrap_or(0),
            shape.get(2).copied().unwrap_or(0),
        ];
        if !shape_ok || dims.iter().any(|&d| d == 0 || d > i32::MAX as usize) {
            return err(
                &key,
                format!("{}: an array of shape {shape:?}: expected {expected}, each size ≥ 1", path.display()),
            );
        }
        // (The header's size was checked not to overflow: the voxels are at most that.)
        let voxels = (volume.header.count / T::C) as u64;
        let grid = voxels.saturating_mul(std::mem::size_of::<T>() as u64).saturating_mul(copies);
        let (more, more_bytes) = match derived(dims) {
            Some((what, bytes)) => (format!(", and {what}"), bytes),
            None => (String::new(), 0),
        };
        // The derived bytes (a density's majorant grid) are charged once made (`density::attach_density`).
        memory.charge_ahead(
            &key,
            &format!("= \"{file}\""),
            &format!("the volume {file}"),
            &format!(
                "{voxels} voxels × {} bytes{}{more}",
                std::mem::size_of::<T>(),
                if copies > 1 { format!(", {copies} copies while resolving") } else { String::new() }
            ),
            grid,
            more_bytes,
        )?;
        let mut g = VoxelGrid::new([0, 0, 0], dims, T::default(), transform);
        let [nx, ny, _] = dims;
        // Array index `[i][j][k]` (and the component last) into the grid's x-fastest block.
        volume
            .for_each(|ix, v| {
                let at = (ix[2] * ny + ix[1]) * nx + ix[0];
                g.data[at].set(if T::C == 1 { 0 } else { ix[3] }, v);
            })
            .map_err(|m| ConfigError::new(&key, m))?;
        Ok(g)
    }

    /// The float grid `grid` (or the first) of `file` (relative to `base`); errors name `key`.
    /// Counted in `memory` `copies` times (see [`GridFiles::get`]).
    fn float(
        &self,
        key: &str,
        at: (&Path, &Memory),
        file: &str,
        grid: Option<&str>,
        copies: u64,
    ) -> R<Arc<VoxelGrid<f32>>> {
        Self::get(&self.float, key, at, file, grid, copies)
    }

    /// The vec3 grid `grid` (or the first) of `file`.
    fn vec3(&self, key: &str, at: (&Path, &Memory), file: &str, grid: Option<&str>) -> R<Arc<VoxelGrid<[f32; 3]>>> {
        Self::get(&self.vec3, key, at, file, grid, 1)
    }

    /// Read a grid once: its sparse tree, held to what is left of the memory budget, then its
    /// dense block, counted in `memory` before it is made — `copies` times, for a grid of which
    /// the medium makes its own copy (a density: the cache holds the one read until resolving
    /// ends).
    fn get<T: crate::io::formats::vdb::VdbValue>(
        cache: &GridCache<T>,
        key: &str,
        (base, memory): (&Path, &Memory),
        file: &str,
        grid: Option<&str>,
        copies: u64,
    ) -> R<Arc<VoxelGrid<T>>> {
        use crate::io::formats::vdb::{DEFAULT_MAX_DENSE_BYTES, ReadOptions, read_tree};
        let path = base.join(file);
        let id = (path.clone(), grid.map(str::to_string));
        if let Some(g) = cache.borrow().get(&id) {
            return Ok(g.clone());
        }
        let key = join(key, "file");
        let left = memory.remaining();
        let options = ReadOptions { max_dense_bytes: left.min(DEFAULT_MAX_DENSE_BYTES) };
        let tree = read_tree::<T>(&path, grid, &options).map_err(|e| {
            let budget = if left < DEFAULT_MAX_DENSE_BYTES {
                format!(" (what is left of run.memory_budget_gib: {})", bytes_shown(left))
            } else {
                String::new()
            };
            ConfigError::new(&key, format!("{e}{budget}"))
        })?;
        let bytes = tree.dense_bytes();
        memory.charge(
            &key,
            &format!("= \"{file}\""),
            &format!("the grid {file}:{}", tree.info.name),
            &format!(
                "its dense block, {} bytes per voxel and an active mask{}",
                std::mem::size_of::<T>(),
                if copies > 1 { format!(", {copies} copies while resolving") } else { String::new() }
            ),
            bytes.saturating_mul(copies),
        )?;
        let dense = tree.to_dense(options.max_dense_bytes).map_err(|m| {
            ConfigError::new(&key, format!("VDB file {}, grid \"{}\": {m}", path.display(), tree.info.unique_name))
        })?;
        let g = Arc::new(dense.grid);
        cache.borrow_mut().insert(id, g.clone());
        Ok(g)
    }
}
