//! The random walk of one photon packet (forward transport with absorption weighting and Russian
//! roulette, as MCML: Wang, Jacques & Zheng 1995).
//!
//! Why this estimator: the quantities asked for (reflectance, transmittance, spectra over a
//! detector area with an angular acceptance) are all *boundary* fluxes of a forward problem with a
//! collimated source, which packet tracing scores exactly where the packet leaves; absorption
//! weighting removes the variance of the absorb/scatter choice; Russian roulette ends low-weight
//! packets without bias. Narrow-aperture detectors (lidar) will want next-event estimation later.
//!
//! The walk is compiled per scene kind: `DOPPLER = false` drops every velocity lookup (nothing
//! moves), `LENGTH = false` drops the optical-path-length bookkeeping (no chirp, no gates),
//! `VOLUME = false` drops the volume tally's hooks (no `[volume]`), `GATE = false` the time gate's
//! checks (no `run.time_gate_ns`; a gated walk also tracks the length), `LATERAL = false` the
//! side faces of a box phantom (no `[lateral]`: the layers are infinite slabs).

use glam::DVec3;

use crate::detect::twin::{Split, TwinPath};
use crate::detect::volume::VolumeTally;
use crate::detect::{Exit, PathState, Pending, Recorder, Scalar, Shot, Side, Twin};
use crate::medium::{Medium, Population, Scene};
use crate::phase::Deflection;
use crate::sampling::{PathRng, warp};
use crate::source::Source;

use super::camera::CameraTarget;
use super::fresnel;
use super::nee::{Crossing, NeeTarget, reflections_below};
use super::tracking::{Flight, LayerRay, Tracking, free_flight, free_flight_to};
use super::windows::{Action, MAX_PENDING, Windows};

/// Knobs of the random walk.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WalkSettings {
    pub tracking: Tracking,
    /// Packets lighter than this play Russian roulette.
    pub roulette_threshold: f64,
    /// Survival probability of the roulette (the survivor's weight is divided by it).
    pub roulette_survival: f64,
    /// Hard cap on real collisions per path (counted as truncated when reached).
    pub max_events: u32,
    /// The time gate `run.time_gate_ns` as optical path lengths `[l0, l1]` (m; time of flight =
    /// `l/c` from the emission point), `None`: no gate. Forward paths record only what happens
    /// within it (escapes, deposits) and end at `l1` (as MCX); read only by walks that track `l`.
    pub gate: Option<(f64, f64)>,
    /// How the forward paths' unscattered reflections at the interfaces below the surface reach
    /// the detectors (`run.reflections`).
    pub reflections: Reflections,
    /// Whether forward-estimated cameras get the layered control variate
    /// (`run.control_variate`, [`crate::detect::twin`]).
    pub control_variate: ControlVariate,
    /// Launches near the regions (`run.launches = "near_regions"`, [`crate::source::Launches`]);
    /// `None`: from the profile.
    pub launches: Option<LaunchSettings>,
}

/// `run.launches = "near_regions"`: the margin around the regions (m) and the profile's share of
/// the paths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaunchSettings {
    pub margin: f64,
    pub profile_share: f64,
}

impl LaunchSettings {
    /// The launches of `source` near the regions of `scene` (`None` where there is nothing to
    /// bias: a pencil beam, no regions, or near cells holding none or all of the profile).
    pub fn launches(&self, scene: &Scene, source: &Source) -> Option<crate::source::Launches> {
        let regions: Vec<_> = scene
            .regions
            .iter()
            .map(|r| (r.shape, (scene.layers[r.layer].z_top, scene.layers[r.layer].z_bottom)))
            .collect();
        if regions.is_empty() {
            return None;
        }
        crate::source::Launches::new(source, &regions, self.margin, self.profile_share)
    }
}

/// `run.control_variate`: the layered twin's control variate of forward-estimated cameras
/// ([`crate::detect::twin`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ControlVariate {
    /// Wherever it applies ([`control_variate_obstacle`] finds nothing).
    #[default]
    Auto,
    /// Asked for: a run where it does not apply is refused, naming why.
    Layered,
    /// The plain forward estimate.
    Off,
}

/// The most offsets a twin kernel may have per map (`(pixels + footprint cells)²`): 2²⁴, 128 MiB of
/// one map and its transform; retina_ldh's are 619², and a 8192² image over a 0.6 mm beam would
/// need 14,335².
pub const MAX_TWIN_OFFSETS: usize = 1 << 24;

/// Why the layered control variate cannot cover this scene, source and detectors (`None`: it
/// can). It needs a camera to cover (a forward-estimated top detector whose image spans its
/// rectangular area), a twin that is laterally invariant (infinite layers of homogeneous media:
/// no box phantom, no density field filling a layer; regions may hold one, without an albedo
/// grid; a bottom surface that does not rotate; opaque solids, which the twin has not, part
/// from it where the path meets them), a beam whose entry points have its profile's density
/// (normal incidence, no divergence), and every path of the twin among the path's possible ones:
/// a region's medium scatters wherever its layer's does.
pub fn control_variate_obstacle(
    scene: &Scene,
    source: &Source,
    detectors: &[crate::detect::Detector],
) -> Option<String> {
    if !detectors.iter().any(|d| crate::detect::twin_camera(d).is_some()) {
        return Some(
            "no camera to cover (a forward-estimated top detector with an image over its whole rectangular area)"
                .into(),
        );
    }
    if scene.lateral.is_some() {
        return Some("the layers end at the box's side faces ([lateral]): the twin is not laterally invariant".into());
    }
    if scene.bottom.as_ref().is_some_and(|b| b.angular_velocity != DVec3::ZERO) {
        return Some(
            "the [bottom] surface rotates: its Doppler shift depends on where light meets it, so the twin is not laterally invariant"
                .into(),
        );
    }
    if let Some(l) = scene.layers.iter().find(|l| scene.media[l.medium].density().is_some()) {
        return Some(format!("layer `{}`'s medium has a density field: its twin is not laterally invariant", l.name));
    }
    if let Some(r) = scene.regions.iter().find(|r| scene.media[r.medium].has_albedo_field()) {
        return Some(format!(
            "region `{}`'s medium has an albedo grid: its collisions cannot be coupled to its twin's",
            r.name
        ));
    }
    let Some(fp) = source.footprint() else {
        return Some("the beam is tilted or diverges: its footprint on the surface is not its profile".into());
    };
    for d in detectors {
        let Some(im) = crate::detect::twin_camera(d) else { continue };
        let offsets = crate::detect::twin::kernel_offsets(im, fp);
        if offsets > MAX_TWIN_OFFSETS {
            return Some(format!(
                "detector `{}`'s kernels would hold {offsets} offsets per map (its pixels against the beam's footprint), more than {MAX_TWIN_OFFSETS}",
                d.name
            ));
        }
    }
    for r in &scene.regions {
        let fill = &scene.media[scene.layers[r.layer].medium];
        if fill.sigma_s() > 0.0 && scene.media[r.medium].sigma_s() <= 0.0 {
            return Some(format!(
                "region `{}` does not scatter where its layer does: the twin's paths through it cannot be weighted",
                r.name
            ));
        }
    }
    None
}

/// How the laser's unscattered reflections at the interfaces below the surface reach the
/// forward-estimated detectors (`run.reflections`; the scalar tallies always count the walk's).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Reflections {
    /// Deterministic where the sampled reflections would add enough variance to pay for it: the
    /// second moment per path of the sampled once-reflected unscattered escapes, summed over the
    /// interfaces along the beam's axis, at least [`AUTO_REFLECTIONS`].
    #[default]
    Auto,
    /// Scored from each path before its walk ([`unscattered_reflections`]), the walk's own
    /// unscattered once-reflected escapes left out of the detectors.
    Deterministic,
    /// As the walk meets them: a path reflects at an interface with probability `R`.
    Sampled,
}

impl Default for WalkSettings {
    fn default() -> Self {
        WalkSettings {
            tracking: Tracking::Analytic,
            roulette_threshold: 1e-4,
            roulette_survival: 0.1,
            max_events: 1_000_000,
            gate: None,
            reflections: Reflections::Auto,
            control_variate: ControlVariate::Auto,
            launches: None,
        }
    }
}

/// What every path of a run walks through: the scene, the source, the walk's knobs and the
/// detectors scored by next-event estimation (empty: none; the walk is then compiled without
/// shadow rays, `NEE = false`). A camera path ([`trace_camera_path`]) also carries its pixel
/// (`shot`; `None` for forward paths). `volume`: the voxel grid forward paths score into
/// (`[volume]`; read only by the walk compiled with `VOLUME = true`).
#[derive(Debug, Clone, Copy)]
pub struct WalkContext<'a> {
    pub scene: &'a Scene,
    pub source: &'a Source,
    pub settings: &'a WalkSettings,
    pub nee: &'a [NeeTarget],
    pub shot: Option<Shot>,
    pub volume: Option<VolumeTally<'a>>,
    /// Forward paths score their unscattered reflections at the interfaces below the surface
    /// deterministically ([`unscattered_reflections`]): `run.reflections = "deterministic"` (or
    /// `"auto"` where they pay), a forward-estimated top detector to see them, an interface with a
    /// change of index below the surface, and no box phantom
    /// ([`WalkContext::deterministic_reflections`]).
    pub reflections: bool,
    /// Forward paths carry their layered twin for the control variate of the cameras that have
    /// one (`run.control_variate`, [`crate::detect::twin`]): the likelihood ratio `Λ` of the
    /// path under the twin (each flight through a region: the twin's transmittance over the
    /// path's) until the twin parts from it at the path's first collision in a region
    /// ([`Split`]), in [`Recorder::twin`].
    pub twin: bool,
    /// The twin's scene (the regions removed), where a twin walks on once it parts from its path
    /// ([`Split`]); `None` without a control variate.
    pub twin_scene: Option<&'a Scene>,
    /// Forward paths start near the regions ([`crate::source::Launches`]; `None`: from the
    /// profile).
    pub launches: Option<&'a crate::source::Launches>,
    /// The weight windows of `run.importance = "windows"` ([`super::windows`]; `None`: none, and
    /// in a twin's own walk).
    pub windows: Option<&'a super::windows::Windows>,
}

impl WalkContext<'_> {
    /// Whether forward paths in `scene` with `settings` and these `detectors` score their
    /// unscattered reflections deterministically (see [`WalkContext::reflections`]).
    pub fn deterministic_reflections(
        scene: &Scene,
        source: &Source,
        settings: &WalkSettings,
        detectors: &[crate::detect::Detector],
    ) -> bool {
        let seen = detectors.iter().any(|d| {
            d.surface().is_some_and(|s| s.side == Side::Top && s.estimator() == crate::detect::Estimator::Forward)
        });
        let mismatched = scene
            .layers
            .iter()
            .enumerate()
            .any(|(j, l)| l.z_bottom.is_finite() && l.n != scene.layers.get(j + 1).map_or(scene.n_below, |b| b.n));
        // (Opaque solids would shade the reflections' straight ways down and up, and a rough face
        // scatters them.)
        let smooth = scene.layers.iter().all(|l| l.roughness == 0.0);
        let possible = seen && mismatched && scene.lateral.is_none() && scene.opaque.is_empty() && smooth;
        match settings.reflections {
            Reflections::Sampled => false,
            Reflections::Deterministic => possible,
            Reflections::Auto => possible && reflection_second_moment(scene, source) >= AUTO_REFLECTIONS,
        }
    }
}

/// `run.reflections = "auto"` scores the reflections deterministically from this second moment per
/// path of the sampled ones (in units of the emitted power squared; [`reflection_second_moment`]).
/// Scoring them costs a trace through the layers and a detection per interface and path, about
/// 1,400 instructions on the built-in default (5 % of its path), and removes that second moment
/// from the detectors' variance per path, which was 2·10⁻³ (default) and 5·10⁻⁴ (vessels_ldh)
/// for their detected power: below 10⁻⁵ it removes less than it costs. Measured: on vessels_ldh
/// deterministic reflections divided the power variance by 6.6 and the median pixel's by 2.4 in
/// the same time; on the default they cost 5.4 % and changed nothing measurable.
pub const AUTO_REFLECTIONS: f64 = 1e-5;

/// The second moment per path of the walk's unscattered once-reflected escapes, summed over the
/// interfaces below the surface, along the beam's axis through the layers' filling media
/// (regions left out): `Σ_j T0·T_j²·R_j·exp(−2τ_j)·w0²`, the probability of reflecting at `j` and
/// leaving unscattered (through the interfaces between, `T_j²`, and the surface, `T0`) times the
/// square of the weight it carries (`w0 = T0 = 1 − R_surface`).
pub fn reflection_second_moment(scene: &Scene, source: &Source) -> f64 {
    let (n0, b) = (scene.n_above, source.direction);
    let (mut t, mut tau, mut sum, mut n_prev, mut w0) = (1.0, 0.0, 0.0, n0, 1.0);
    for (j, layer) in scene.layers.iter().enumerate() {
        if !layer.z_bottom.is_finite() {
            break;
        }
        let Some(d) = super::camera::refracted_down(b, n0, layer.n) else { break };
        let r_in = fresnel::reflectance(n_prev, layer.n, d.z).0;
        if j == 0 {
            w0 = 1.0 - r_in;
        } else {
            t *= 1.0 - r_in;
        }
        tau += scene.media[layer.medium].sigma_t() * (layer.z_bottom - layer.z_top) / d.z;
        let n_below = scene.layers.get(j + 1).map_or(scene.n_below, |l| l.n);
        let r = fresnel::reflectance(layer.n, n_below, d.z).0;
        sum += w0 * t * t * r * (-2.0 * tau).exp() * w0 * w0;
        n_prev = layer.n;
    }
    sum
}

/// A real collision as the event loop hands it to [`collide`]: the medium collided in, its albedo
/// there and the refractive index `n` of the layer.
#[derive(Debug, Clone, Copy)]
struct Vertex<'a> {
    medium: &'a Medium,
    albedo: f64,
    n: f64,
    /// Its layer.
    li: usize,
}

/// Rotate `dir` by the deflection `d` at azimuth `(cos φ, sin φ)`.
///
/// Returns the new direction and `dir_in − dir_out`, computed directly as
/// `(1 − cos θ)·dir_in − sin θ·(cos φ t + sin φ b)` so that it keeps its relative precision for
/// the milliradian deflections of forward-peaked media (a difference of two nearly equal unit
/// vectors would not).
///
/// The new direction is as unit as `dir` up to rounding, not renormalised: rounding makes
/// `|dir|² − 1` drift by a few 1e-16 per event, which the walk removes every
/// [`RENORMALISE_EVERY`] events with [`renormalise`].
///
/// `(t, b)` is the basis of [`warp::orthonormal_basis`] (Duff et al. 2017), but not built: with
/// `s = sign(dir.z)`, `a = −1/(s + dir.z)`, `c = sin θ cos φ`, `c′ = sin θ sin φ` and
/// `w = s·c·x + c′·y`, its terms collect into
/// `sin θ·(cos φ t + sin φ b) = (c + a·x·w, s·c′ + a·y·w, −w)`, about half the arithmetic of
/// forming `t` and `b` (measured: 131 → 118 instructions per collision).
#[inline(always)]
pub fn scatter_direction(dir: DVec3, d: Deflection, cos_phi: f64, sin_phi: f64) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(dir.z);
    let a = -1.0 / (sign + dir.z);
    let (c, c_prime) = (d.sin * cos_phi, d.sin * sin_phi);
    let w = sign * c * dir.x + c_prime * dir.y;
    let aw = a * w;
    let perp_sin = DVec3::new(c + aw * dir.x, sign * c_prime + aw * dir.y, -w);
    (dir * d.cos + perp_sin, dir * d.one_minus_cos - perp_sin)
}

/// Reflections at interfaces without a real collision in between after which a path is
/// truncated (counted in `truncated_paths`). Only total internal reflection repeats: a scattering
/// region in a clear layer of higher index than both neighbours sends some packets along the
/// layer at grazing angles, reflected between its faces for ever (issue 21: a run that never
/// ended). A partial reflection (R < 1) repeats 10⁴ times with probability `R^10⁴`.
pub const MAX_REFLECTIONS_WITHOUT_COLLISION: u32 = 10_000;

/// How many scattering events the walk lets pass between renormalisations of the direction.
///
/// Renormalising after every event cost 14 instructions per collision (callgrind, 4% of a van
/// de Hulst path). Without it, `||dir|² − 1|` measured over 2·10⁷ events stays below 1e-14 for
/// |g| ≤ 0.99 and reaches 1e-12 for g = 0.999999 (tiny deflections let the rounding errors
/// accumulate); renormalising every 32 events bounds it by the drift of 32 events (test
/// `direction_stays_unit_over_many_events`).
pub const RENORMALISE_EVERY: u32 = 32;

/// One Newton step towards `|dir| = 1`, for a `dir` whose length is already 1 up to rounding.
#[inline(always)]
pub fn renormalise(dir: DVec3) -> DVec3 {
    dir * (1.5 - 0.5 * dir.length_squared())
}

/// Change of `dl/dt` at a real scattering event on a particle of velocity `v` in a medium of index
/// `n`, given `dir_in − dir_out`: `n · v · (dir_in − dir_out)` (positive = path lengthening).
#[inline(always)]
pub fn doppler_increment(n: f64, v: DVec3, dir_in_minus_out: DVec3) -> f64 {
    n * v.dot(dir_in_minus_out)
}

/// How a walk ended; [`trace_path`] records it.
#[derive(Debug, Clone, Copy, PartialEq)]
enum End {
    /// Left the stack through `side` into the ambient medium of index `n_ambient`;
    /// `reflected_once`: without scattering, after one reflection (at an interface below the
    /// surface, on the way down).
    Escaped { side: Side, n_ambient: f64, reflected_once: bool },
    /// Left a box phantom through one of its side faces.
    Lateral,
    /// Went down through a transparent semi-infinite last layer: transmitted to depth.
    ToDepth,
    /// Lost all its weight at a collision (albedo 0).
    Absorbed,
    /// Lost the Russian roulette.
    Roulette,
    /// Reached the end of the time gate (`WalkSettings::gate`): nothing after it is recorded.
    Gated,
    /// Hit the event cap, runs parallel to the layers in a transparent semi-infinite layer, or
    /// is trapped by total internal reflection ([`MAX_REFLECTIONS_WITHOUT_COLLISION`]).
    Truncated,
    /// Reached the opaque surface under the last layer (`Scene::bottom`), where `s.pos` now is:
    /// [`walk_to_the_end`] reflects it there and walks on.
    AtBottom,
    /// Reached the boundary of the opaque solid `Scene::opaque[k]`, where `s.pos` now is:
    /// [`walk_to_the_end`] reflects it there and walks on.
    AtOpaque(usize),
    /// Reached the rough top face of layer `face` (where `s.pos` now is): [`walk_to_the_end`]
    /// draws its reflection or refraction ([`cross_rough_face`]) and walks on.
    AtRough(usize),
}

/// Trace one path from the source until it leaves the stack or ends, recording it into `rec`.
///
/// The walk itself (`walk`) does not touch the recorder: it accumulates the absorbed weight in
/// a local and reports how it ended, and the path is recorded once here. Keeping the tally
/// vector and counters out of the event loop frees registers there and removes a bounds-checked
/// read-modify-write of `acc[AbsorbedFraction]` and a counter increment per collision.
///
/// Inlined into the batch's loop over paths: left to itself, the compiler stopped inlining it once
/// the surfaces' calls were added, and the vdH slab took 7.7 % more instructions (its generator
/// and path state passed through memory).
#[inline(always)]
pub fn trace_path<
    const DOPPLER: bool,
    const LENGTH: bool,
    const NEE: bool,
    const VOLUME: bool,
    const GATE: bool,
    const LATERAL: bool,
>(
    ctx: &WalkContext,
    rec: &mut Recorder,
    rng: &mut PathRng,
) {
    let WalkContext { scene, source, .. } = *ctx;
    rec.stats.paths += 1;
    let (start, w0) = match ctx.launches {
        None => (source.emit(rng), 1.0),
        Some(l) => l.emit(source, rng),
    };
    let dir = source.emit_direction(rng);
    // Travel through the ambient medium to the top surface (dir.z > 0 is validated).
    let t0 = (0.0 - start.z) / dir.z;
    let pos = DVec3::new(start.x + t0 * dir.x, start.y + t0 * dir.y, 0.0);
    let mut s = PathState::new(pos, dir, w0, if LENGTH { scene.n_above * t0 } else { 0.0 });
    if NEE && ctx.twin {
        rec.twin = Some(TwinPath::new(pos.x, pos.y));
    }
    // A rough top surface: the walk starts at its face, which reflects or refracts the beam.
    let n_top = scene.layers[0].n;
    let rough_entry = scene.layers[0].roughness > 0.0 && n_top != scene.n_above;
    // Specular reflection at entry, scored deterministically (as MCML).
    let (r_sp, cos_t) = fresnel::reflectance(scene.n_above, n_top, dir.z);
    if r_sp > 0.0 && !rough_entry {
        let reflected = PathState { dir: DVec3::new(dir.x, dir.y, -dir.z), weight: w0 * r_sp, ..s };
        if in_gate::<GATE>(ctx.settings, s.l) {
            rec.escape(Side::Top, reflected, Exit::Specular, scene.n_above);
        }
        s.weight = w0 * (1.0 - r_sp);
        if s.weight <= 0.0 {
            return;
        }
    }
    if !rough_entry {
        s.dir = fresnel::refract(dir, scene.n_above, n_top, cos_t);
    }
    if ctx.reflections {
        // The path by value and the generator on a copy handed back, as the walk's: the address
        // of neither leaves this inlined function (else it lives in memory through the walk;
        // `&s` measured +54 instructions per path on the vdH slab, where this never runs).
        let mut local = rng.clone();
        unscattered_reflections::<NEE, LENGTH, GATE>(ctx, s, dir, &mut local, rec);
        *rng = local;
    }

    let mut absorbed = 0.0;
    let mut null_collisions = 0;
    // The walk draws from a copy local to this path, handed back at the end (a clone repeats its
    // original's numbers: the stream is unchanged). With `rng` itself (a local of the batch
    // loop, into which this function is inlined twice: with and without next-event targets)
    // the walk stored and reloaded the generator's state around its draws: callgrind, vdH slab
    // 2·10⁵ paths, 192.0M → 175.7M instructions (166.1M before next-event estimation, c3d5384).
    let mut local = rng.clone();
    let end = walk_to_the_end::<DOPPLER, LENGTH, NEE, VOLUME, GATE, LATERAL, false>(
        ctx,
        0,
        &mut s,
        &mut local,
        &mut absorbed,
        &mut null_collisions,
        rec,
        rough_entry,
    );
    *rng = local;
    finish_walk::<DOPPLER, LENGTH, NEE, GATE>(ctx, rec, &s, end, (absorbed, null_collisions, 0));
    // The copies its weight windows split off, each walked on from where it was made.
    while let Some(c) = rec.copies.pop() {
        rec.twin = c.twin;
        let (mut s, mut local, order) = (c.s, c.rng, c.s.order);
        let (mut absorbed, mut null_collisions) = (0.0, 0);
        let end = walk_to_the_end::<DOPPLER, LENGTH, NEE, VOLUME, GATE, LATERAL, false>(
            ctx,
            c.li,
            &mut s,
            &mut local,
            &mut absorbed,
            &mut null_collisions,
            rec,
            false,
        );
        finish_walk::<DOPPLER, LENGTH, NEE, GATE>(ctx, rec, &s, end, (absorbed, null_collisions, order));
    }
}

/// Record how the walk of `s` ended (`end`), with its absorbed weight, its null collisions and
/// the scattering order it started its walk with (0 for a path from the source, a copy's order
/// at its split), and walk the layered twin that parted from it.
#[inline(always)]
fn finish_walk<const DOPPLER: bool, const LENGTH: bool, const NEE: bool, const GATE: bool>(
    ctx: &WalkContext,
    rec: &mut Recorder,
    s: &PathState,
    end: End,
    (absorbed, null_collisions, order): (f64, u64, u32),
) {
    let s = *s;
    rec.stats.null_collisions += null_collisions;
    // Every real collision increments `order`, except one that leaves no weight to go on with.
    rec.stats.scattering_events += u64::from(s.order - order) + u64::from(end == End::Absorbed);
    rec.add(Scalar::AbsorbedFraction, absorbed);
    match end {
        End::Escaped { side, n_ambient, reflected_once } => {
            if in_gate::<GATE>(ctx.settings, s.l) {
                // With deterministic reflections their detectors' share is scored already.
                let exit = if reflected_once && ctx.reflections { Exit::ScalarsOnly } else { Exit::Walked };
                rec.escape(side, s, exit, n_ambient);
            }
        }
        End::Lateral => {
            if in_gate::<GATE>(ctx.settings, s.l) {
                rec.lateral(s.weight);
            }
        }
        // Depth is reached at t = ∞: beyond any gate.
        End::ToDepth if GATE => {}
        End::ToDepth => {
            rec.add(Scalar::TransmittanceTotal, s.weight);
            if s.order == 0 {
                rec.add(Scalar::TransmittanceUnscattered, s.weight);
            }
        }
        End::Absorbed | End::Gated => {}
        End::Roulette => rec.stats.roulette_terminations += 1,
        // (`walk_to_the_end` never ends at the surface.)
        End::Truncated | End::AtBottom | End::AtOpaque(_) | End::AtRough(_) => rec.stats.truncated_paths += 1,
    }
    if NEE && let Some(split) = rec.split.take() {
        twin_walk::<DOPPLER, LENGTH, GATE>(ctx, split, rec);
    }
}

/// The weight window of `s` after a scattering event in layer `li` (`run.importance =
/// "windows"`, [`super::windows`]): split it, play roulette (`Some`: it has ended) or keep it.
#[inline]
fn window(ctx: &WalkContext, rec: &mut Recorder, s: &mut PathState, li: usize, rng: &mut PathRng) -> Option<End> {
    let w = ctx.windows?;
    if w.guide.is_some() {
        rec.stats.work.guided += 1;
    }
    match w.check(li, s) {
        Action::Keep => {}
        Action::Split(n) => split(rec, s, li, n, rng.split_key()),
        Action::Roulette { p, w } => {
            if rng.uniform() >= p {
                return Some(End::Roulette);
            }
            s.weight = w;
        }
    }
    None
}

/// Split `s` (in layer `li`) into `n` paths of equal weight ([`super::windows`]): `s` goes on
/// with its share, `n − 1` copies wait in `rec` to walk on after it, copy `k` on the stream
/// `PathRng::copy(key, k)`, each with the path's layered twin as it is now. No split once
/// [`MAX_PENDING`] copies wait.
#[cold]
#[inline(never)]
fn split(rec: &mut Recorder, s: &mut PathState, li: usize, n: u32, key: u64) {
    if rec.copies.len() + n as usize > MAX_PENDING {
        return;
    }
    s.weight /= f64::from(n);
    for k in 1..n {
        rec.copies.push(Pending { s: *s, li, rng: PathRng::copy(key, u64::from(k)), twin: rec.twin });
    }
}

/// The unscattered reflections of the forward path `s` (just refracted into the first layer
/// along the ambient direction `b`, not yet scattered), scored into the detectors
/// ([`Recorder::reflection`]): for the bottom `j` of every finite layer, the beam's straight way
/// down to it, its reflection `R_j` and the way back up through the surface, leaving along the
/// mirror image `(b_x, b_y, −b_z)` with the weight `w·Π(1 − R_i)·R_j·exp(−τ)` (Fresnel
/// transmittances of the interfaces crossed, the optical depth of both ways: analytic segments,
/// ratio tracking in density layers), as the camera-side estimator scores them
/// ([`super::camera::unscattered`]). This is the expectation, given the launch, of what the walk's
/// escapes without scattering and with one reflection bring the detectors, which are then left
/// out of them ([`Exit::ScalarsOnly`]); light reflected more than once stays in the walk. A
/// delta-like beam that the walk meets by a rare Fresnel draw (`R ≈ 10⁻³` between tissue layers)
/// becomes a sure, small contribution per path.
#[cold]
#[inline(never)]
fn unscattered_reflections<const NEE: bool, const LENGTH: bool, const GATE: bool>(
    ctx: &WalkContext,
    s: PathState,
    b: DVec3,
    rng: &mut PathRng,
    rec: &mut Recorder,
) {
    let n0 = ctx.scene.n_above;
    let down = |n: f64| super::camera::refracted_down(b, n0, n);
    let up = |n: f64| down(n).map(|d| DVec3::new(d.x, d.y, -d.z));
    // The surface's transmittance on the way in is in the path's weight.
    let start = Crossing { pos: s.pos, length: s.l, ..Crossing::START };
    let steps = reflections_below(ctx.scene, start, false, down, up, rng, |c| {
        let l = if LENGTH { c.length } else { 0.0 };
        let weight = s.weight * c.transmit * (-c.tau).exp();
        // The twin's way down and up meets no region: without their excess optical depth.
        let twin = match rec.twin {
            Some(_) if NEE && (c.excess != 0.0 || c.twin_transmit != c.transmit) => Twin::Other(PathState::new(
                c.pos,
                DVec3::new(b.x, b.y, -b.z),
                s.weight * c.twin_transmit * (c.excess - c.tau).exp(),
                l,
            )),
            Some(_) if NEE => Twin::Same,
            _ => Twin::Off,
        };
        if (weight > 0.0 || twin != Twin::Off) && in_gate::<GATE>(ctx.settings, l) {
            let e = PathState::new(c.pos, DVec3::new(b.x, b.y, -b.z), weight, l);
            rec.reflection(&e, twin, n0);
        }
    });
    rec.stats.work.reflection_steps += steps;
}

/// Trace one camera path of pixel `pixel` of `cam` ([`super::camera`]), recording its
/// connections to the laser into `rec` with the tally weight `batch_weight` per path.
pub fn trace_camera_path<const DOPPLER: bool, const LENGTH: bool>(
    ctx: &WalkContext,
    cam: &CameraTarget,
    pixel: usize,
    batch_weight: f64,
    rec: &mut Recorder,
    rng: &mut PathRng,
) {
    let mut local = rng.clone();
    let (area, x, y) = cam.point(pixel, &mut local);
    let (u1, u2) = (local.uniform(), local.uniform());
    if !cam.area.contains(x, y) {
        *rng = local;
        return;
    }
    // The laser's unscattered reflections, scored from the point.
    let reflected = Shot { detector: cam.detector, pixel, x, y, scale: 0.0 };
    super::camera::unscattered(cam, ctx.scene, ctx.source, (x, y), &mut local, |e, l| {
        let e = PathState::new(DVec3::new(x, y, 0.0), cam.axis, e * area * batch_weight, if LENGTH { l } else { 0.0 });
        rec.camera(&reflected, &e);
    });
    let Some((shot, pos, dir, weight, l)) =
        super::camera::start(cam, ctx.scene, pixel, (area, x, y), batch_weight, u1, u2)
    else {
        *rng = local;
        return;
    };
    let mut s = PathState::new(pos, dir, weight, if LENGTH { l } else { 0.0 });
    let ctx = WalkContext { shot: Some(shot), ..*ctx };
    let (mut absorbed, mut null_collisions) = (0.0, 0);
    let end = walk_to_the_end::<DOPPLER, LENGTH, false, false, false, false, true>(
        &ctx,
        0,
        &mut s,
        &mut local,
        &mut absorbed,
        &mut null_collisions,
        rec,
        ctx.scene.rough_top(0),
    );
    *rng = local;
    rec.stats.work.camera_events += u64::from(s.order) + u64::from(end == End::Absorbed) + null_collisions;
    if end == End::Truncated {
        rec.stats.truncated_paths += 1;
    }
}

/// The random walk of `s` from the top surface (`start = 0`), or from inside layer `start` (a
/// layered twin parting from its path there), until it ends; the weight deposited by
/// absorption is added to `absorbed`. A camera path (`CAMERA`) connects to the laser at every
/// real collision and carries radiance across interfaces (see [`super::camera`]).
///
/// The loop is nested: the outer one runs once per visit of a layer and reads what the event
/// loop needs from the layer and its filling medium (bounds, index, `1/σt`, the medium itself)
/// once, the inner one runs once per event. In a layer without regions the free flight is
/// sampled right here, so the collision's medium is the hoisted one (no index, no bounds
/// check, no [`Flight`] value in between); layers with regions go through [`free_flight`].
///
/// With `VOLUME` every straight piece of the path inside the stack (to a collision, to an
/// interface, to depth) is scored into the volume tally's track lengths with the weight it is
/// flown with, and every real collision's deposit and collision estimate before the collision
/// is handled ([`VolumeTally`]).
///
/// With `LATERAL` the layers end at the side faces of a box phantom (`Scene::lateral`): a
/// flight that would leave the box stops at the face ahead, where Fresnel's law against
/// `n_outside` reflects the path back in or lets it out (`End::Lateral`). Shadow rays and
/// camera paths are not run in a box (refused at resolve time), so `NEE` and `CAMERA` never
/// come with it.
#[inline(always)]
fn walk<
    const DOPPLER: bool,
    const LENGTH: bool,
    const NEE: bool,
    const CAMERA: bool,
    const VOLUME: bool,
    const GATE: bool,
    const LATERAL: bool,
>(
    ctx: &WalkContext,
    start: usize,
    s: &mut PathState,
    rng: &mut PathRng,
    absorbed: &mut f64,
    null_collisions: &mut u64,
    rec: &mut Recorder,
) -> End {
    let WalkContext { scene, settings, .. } = *ctx;
    // The box's bounds (read only by the walk compiled with `LATERAL`).
    let bounds = match scene.lateral {
        Some(b) if LATERAL => b,
        _ => crate::medium::Lateral { x: (0.0, 0.0), y: (0.0, 0.0), n_outside: 1.0 },
    };
    let mut li = start;
    let (mut reflected_at, mut reflections) = (u32::MAX, 0u32);
    // The next event count at which `collide` looks at the event cap and renormalises.
    let mut checkpoint = RENORMALISE_EVERY.min(settings.max_events);
    loop {
        let layer = &scene.layers[li];
        let fill = &scene.media[layer.medium];
        // A layer without regions whose medium has the same density everywhere samples its
        // flights right here: a homogeneous medium, and (with analytic tracking; delta tracking
        // keeps its inflated majorants) a constant density field, known to be constant at
        // resolve time, at rate `c·σt`. Through the majorant segments, even as one segment, a
        // constant ramp cost 2.2× the homogeneous slab (callgrind, `validation/features/`).
        // (An opaque solid in the layer ends flights at its boundary: the general flights.)
        let uniform = if layer.plain { fill.uniform_density() } else { None };
        let (homogeneous, fill_inv_sigma_t) = match uniform {
            Some(_) if !layer.heterogeneous => (true, fill.inv_sigma_t()),
            Some(c) if settings.tracking == Tracking::Analytic => (true, 1.0 / (c * fill.sigma_t())),
            _ => (false, fill.inv_sigma_t()),
        };
        // Only a layer with density media can hold an albedo grid (a uniform one has none).
        let albedo_grid = layer.heterogeneous;
        let (z_top, z_bottom, n) = (layer.z_top, layer.z_bottom, layer.n);
        loop {
            let (t, medium, albedo) = if homogeneous {
                // A collision iff its point is still in the layer, `z_top ≤ z < z_bottom`: two
                // comparisons on the new depth, which the collision needs anyway, instead of
                // selecting the plane ahead and comparing `t·|dir.z|` with its distance
                // (measured: 8 instructions per flight). The distance to the plane, and its
                // division, only when the plane is reached. A vacuum (t = ∞) gives z = ±∞ or NaN
                // and goes to the boundary.
                let t = rng.exponential() * fill_inv_sigma_t;
                let z = s.pos.z + t * s.dir.z;
                if !(z_top <= z && z < z_bottom) {
                    break;
                }
                if LATERAL && !bounds.contains(s.pos.x + t * s.dir.x, s.pos.y + t * s.dir.y) {
                    break;
                }
                (t, fill, fill.albedo())
            } else {
                // Distance along z to the boundary plane ahead (either one for a horizontal ray).
                let dz = if s.dir.z >= 0.0 { z_bottom - s.pos.z } else { s.pos.z - z_top };
                // The first opaque solid ahead, if any: the flight ends at it.
                let (t_opaque, opaque) = if layer.opaque.is_empty() {
                    (f64::INFINITY, usize::MAX)
                } else {
                    scene.first_opaque(layer, s.pos, s.dir)
                };
                let ray = LayerRay { scene, layer, pos: s.pos, dir: s.dir };
                // A layer with density regions flies the path and its coupled layered twin
                // together (`coupled_flight`), the others weight the twin by its flights'
                // transmittance over the path's.
                let coupled = NEE && layer.heterogeneous && rec.twin.is_some_and(|t| !t.only);
                let flight = if LATERAL {
                    // The nearer of the plane ahead and the side face ahead (`min` takes the face
                    // for a horizontal ray, whose distance to the plane is ∞ or NaN).
                    let t_end = bounds.exit(s.pos, s.dir).0.min(dz / s.dir.z.abs()).min(t_opaque);
                    free_flight_to(ray, t_end, settings.tracking, rng, null_collisions)
                } else if coupled {
                    let t_end = (dz / s.dir.z.abs()).min(t_opaque);
                    let (flight, parting) =
                        super::tracking::coupled_flight(&ray, t_end, fill.sigma_t(), rng, null_collisions);
                    match parting {
                        Some(p) => part_in_flight::<LENGTH>(s, li, n, p, rec),
                        // A collision of both in a region: the coupled collision of `collide_nee`,
                        // whose `σs,fill/σs` holds the collision densities' ratio that this flight
                        // has not weighted: `σt/σt,fill` takes it back out.
                        None => {
                            if let (Flight::Collision { medium, .. }, Some(tw)) = (flight, rec.twin.as_mut())
                                && medium != layer.medium
                            {
                                tw.lambda *= scene.media[medium].sigma_t() / fill.sigma_t();
                            }
                        }
                    }
                    flight
                } else if t_opaque < f64::INFINITY {
                    free_flight_to(ray, (dz / s.dir.z.abs()).min(t_opaque), settings.tracking, rng, null_collisions)
                } else {
                    free_flight(ray, dz, s.dir.z.abs(), settings.tracking, rng, null_collisions)
                };
                let t = match flight {
                    Flight::Collision { t, .. } | Flight::Boundary { t } => t,
                };
                if NEE
                    && !coupled
                    && !layer.regions.is_empty()
                    && let Some(tw) = rec.twin.as_mut()
                {
                    tw.flight(super::nee::region_excess(scene, layer, s.pos, s.dir, t));
                }
                match flight {
                    Flight::Collision { t, medium } => {
                        let m = &scene.media[medium];
                        (t, m, if albedo_grid { m.albedo_at(s.pos + t * s.dir) } else { m.albedo() })
                    }
                    // The flight ends at an opaque solid's boundary (before the plane and a side
                    // face): there the surface reflects it, outside the walk.
                    // (A flight to depth has t = ∞, and so has `t_opaque` without a solid ahead.)
                    Flight::Boundary { t } if t_opaque <= t && opaque != usize::MAX => {
                        if VOLUME && let Some(v) = ctx.volume {
                            v.track::<GATE>(rec.acc, s.pos, s.dir, t, s.weight, s.l, n);
                        }
                        if GATE
                            && let Some((_, l1)) = settings.gate
                            && s.l + n * t > l1
                        {
                            return End::Gated;
                        }
                        s.pos += t * s.dir;
                        if LENGTH {
                            s.l += n * t;
                        }
                        if NEE && rec.twin.is_some() {
                            part_at_solid(s, li, rng, rec);
                        }
                        return End::AtOpaque(opaque);
                    }
                    Flight::Boundary { .. } => break,
                }
            };
            let mut before_gate = false;
            if GATE && let Some((l0, l1)) = settings.gate {
                // The collision happens at `l`: after the gate the path ends unrecorded (its
                // track scored up to `l1`); before it the deposit `absorb` will add is taken back
                // out of the absorbed weight (and the volume tally's).
                let l = s.l + n * t;
                if l > l1 {
                    if VOLUME && let Some(v) = ctx.volume {
                        v.track::<GATE>(rec.acc, s.pos, s.dir, t, s.weight, s.l, n);
                    }
                    return End::Gated;
                }
                if l < l0 {
                    *absorbed -= s.weight * (1.0 - albedo);
                    before_gate = true;
                }
            }
            if VOLUME && let Some(v) = ctx.volume {
                let p = s.pos + t * s.dir;
                v.track::<GATE>(rec.acc, s.pos, s.dir, t, s.weight, s.l, n);
                if !before_gate {
                    v.collision(rec.acc, p, s.l + n * t, s.weight, albedo, medium.sigma_t_at(p));
                }
            }
            if CAMERA {
                s.pos += t * s.dir;
                if LENGTH {
                    s.l += n * t;
                }
                if let Some(end) =
                    collide_camera::<DOPPLER, LENGTH>(ctx, li, s, medium, albedo, n, rng, &mut checkpoint, rec)
                {
                    return end;
                }
            } else if NEE {
                s.pos += t * s.dir;
                if LENGTH {
                    s.l += n * t;
                }
                if let Some(end) = collide_nee::<DOPPLER, LENGTH>(
                    scene,
                    ctx.nee,
                    ctx.windows,
                    li,
                    s,
                    medium,
                    albedo,
                    n,
                    settings,
                    rng,
                    absorbed,
                    &mut checkpoint,
                    rec,
                ) {
                    return end;
                }
                rec.scattered(li, s);
                if let Some(end) = window(ctx, rec, s, li, rng) {
                    return end;
                }
            } else if let Some(end) =
                collide::<DOPPLER, LENGTH>(s, t, Vertex { medium, albedo, n, li }, ctx, rng, absorbed, &mut checkpoint)
            {
                return end;
            } else {
                rec.scattered(li, s);
                if let Some(end) = window(ctx, rec, s, li, rng) {
                    return end;
                }
            }
        }

        // Reached the boundary plane ahead: the bottom one going down, else the top one. The
        // distance is the one `free_flight` reports, `|Δz| / |dir.z|` (signs cancel exactly);
        // a horizontal ray gets ±∞ or NaN and is truncated.
        let down = s.dir.z > 0.0;
        let (plane, next) = if down { (z_bottom, li + 1) } else { (z_top, li.wrapping_sub(1)) };
        let t_boundary = (plane - s.pos.z) / s.dir.z;
        if LATERAL {
            let (t_side, axis) = bounds.exit(s.pos, s.dir);
            // The side face comes first, or the ray is horizontal (`t_boundary` −∞ or NaN; +∞
            // is a way to depth, taken unless a face comes first).
            if t_side < t_boundary || t_boundary.is_nan() || t_boundary < 0.0 {
                match side_face::<LENGTH, VOLUME, GATE>(ctx, s, t_side, axis, n, bounds, rng, rec) {
                    Some(end) => return end,
                    None => {
                        if s.order != reflected_at {
                            (reflected_at, reflections) = (s.order, 0);
                        }
                        reflections += 1;
                        if reflections > MAX_REFLECTIONS_WITHOUT_COLLISION {
                            return End::Truncated;
                        }
                        continue;
                    }
                }
            }
        }
        if VOLUME && let Some(v) = ctx.volume {
            // To depth (t = ∞) the track is clipped to the grid's box (and to the gate's end).
            let len = if t_boundary.is_finite() { t_boundary } else { f64::INFINITY };
            v.track::<GATE>(rec.acc, s.pos, s.dir, len, s.weight, s.l, n);
        }
        if GATE
            && let Some((_, l1)) = settings.gate
            && s.l + n * t_boundary > l1
        {
            return End::Gated;
        }
        if !t_boundary.is_finite() {
            // Only a semi-infinite last layer lets a path go to depth; an overflow towards a
            // finite plane (|dir.z| of order 1e-308) is a ray that never arrives.
            return if down && z_bottom == f64::INFINITY { End::ToDepth } else { End::Truncated };
        }
        if LENGTH {
            s.l += n * t_boundary;
        }
        s.pos += t_boundary * s.dir;
        s.pos.z = plane;
        // Beyond the plane: the next layer, or the ambient medium (above layer 0, `next` wraps to
        // `usize::MAX`).
        let beyond = scene.layers.get(next);
        let n2 = match beyond {
            Some(l) => l.n,
            None => scene.ambient_n(down),
        };
        // A rough face (the top of the layer below going down, this layer's going up; the stack's
        // bottom face is smooth) between different indices is crossed outside the walk.
        if layer.rough_faces
            && n2 != n
            && (if down { beyond.map_or(0.0, |l| l.roughness) } else { layer.roughness }) > 0.0
        {
            return End::AtRough(if down { next } else { li });
        }
        let (r, cos_t) = fresnel::reflectance(n, n2, s.dir.z.abs());
        if r > 0.0 && (r >= 1.0 || rng.uniform() < r) {
            // Reflections since the last real collision (counted here, so that a collision
            // costs nothing): only total internal reflection keeps a path bouncing that long.
            if s.order != reflected_at {
                (reflected_at, reflections) = (s.order, 0);
            }
            reflections += 1;
            if reflections > MAX_REFLECTIONS_WITHOUT_COLLISION {
                return End::Truncated;
            }
            s.dir.z = -s.dir.z;
            if NEE || CAMERA {
                s.mis = -1.0;
            }
            continue;
        }
        s.dir = fresnel::refract(s.dir, n, n2, cos_t);
        if beyond.is_none() {
            // An opaque surface under the last layer (whose `n_below` is the layer's own index:
            // no Fresnel step on the way to it), reflected outside the walk: a call here, with
            // the walk's state live across it, cost the vdH slab 1.4 % of its instructions.
            if down && scene.bottom.is_some() {
                return End::AtBottom;
            }
            let side = if down { Side::Bottom } else { Side::Top };
            // Without scattering `reflections` counts every reflection (it restarts at a
            // collision).
            let reflected_once = s.order == 0 && reflections == 1;
            return End::Escaped { side, n_ambient: n2, reflected_once };
        }
        if CAMERA {
            // Radiance across the interface: `L/n²` is invariant. The beam-lobe connection
            // crosses it deterministically: its density ratio takes the transmittance.
            s.weight *= (n / n2) * (n / n2);
            if s.mis >= 0.0 {
                s.mis *= 1.0 - r;
            }
        }
        li = next;
    }
}

/// A forward path's walk from layer `start` to its end, with its reflections at opaque surfaces
/// in between (under the stack, or an opaque solid's in a layer; [`reflect_at_surface`]: the walk
/// stops there and starts again in the surface's layer).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn walk_to_the_end<
    const DOPPLER: bool,
    const LENGTH: bool,
    const NEE: bool,
    const VOLUME: bool,
    const GATE: bool,
    const LATERAL: bool,
    const CAMERA: bool,
>(
    ctx: &WalkContext,
    start: usize,
    s: &mut PathState,
    rng: &mut PathRng,
    absorbed: &mut f64,
    null_collisions: &mut u64,
    rec: &mut Recorder,
    entering: bool,
) -> End {
    let scene = ctx.scene;
    let mut li = start;
    // Rough faces met since the last scattering event (a path trapped between rough faces by
    // total internal reflection ends as one between smooth faces does).
    let (mut crossed_at, mut crossings) = (u32::MAX, 0u32);
    // Entering through a rough top surface: the walk starts below its face. (One call of the
    // walk, which is inlined, and its end straight from it: a second call site doubled its code,
    // and an end that could also come from here was kept in memory and dispatched there, +12
    // instructions per path on the vdH slab.)
    if entering {
        let (deposit, next) = if CAMERA {
            (0.0, camera_rough_face::<LENGTH>(ctx, 0, s, rng, rec))
        } else {
            cross_rough_face::<LENGTH, NEE>(ctx, 0, s, rng, rec)
        };
        *absorbed += deposit;
        match next {
            Ok(l) => li = l,
            Err(end) => return end,
        }
    }
    loop {
        let end = walk::<DOPPLER, LENGTH, NEE, CAMERA, VOLUME, GATE, LATERAL>(
            ctx,
            li,
            s,
            rng,
            absorbed,
            null_collisions,
            rec,
        );

        // (The deposits come back by value: `absorbed`'s address handed to a call kept it in
        // memory through every collision of the walk, +1 instruction each.)
        let (deposit, ended) = match end {
            End::AtRough(face) => {
                if s.order != crossed_at {
                    (crossed_at, crossings) = (s.order, 0);
                }
                crossings += 1;
                if crossings > MAX_REFLECTIONS_WITHOUT_COLLISION {
                    return End::Truncated;
                }
                let (deposit, next) = if CAMERA {
                    (0.0, camera_rough_face::<LENGTH>(ctx, face, s, rng, rec))
                } else {
                    cross_rough_face::<LENGTH, NEE>(ctx, face, s, rng, rec)
                };
                match next {
                    Ok(l) => {
                        li = l;
                        (deposit, None)
                    }
                    Err(end) => (deposit, Some(end)),
                }
            }
            End::AtBottom => {
                let Some(bottom) = &scene.bottom else { return end };
                li = scene.layers.len() - 1;
                let frame = crate::medium::Surface::bottom_frame();
                reflect_at_surface::<DOPPLER, LENGTH, NEE, CAMERA>(ctx, bottom, &frame, li, s, rng, rec)
            }
            End::AtOpaque(k) => {
                let o = &scene.opaque[k];
                li = o.layer;
                let frame = crate::surface::Frame::new(o.shape.outward_normal(s.pos, -s.dir));
                reflect_at_surface::<DOPPLER, LENGTH, NEE, CAMERA>(ctx, &o.surface, &frame, li, s, rng, rec)
            }
            _ => return end,
        };
        *absorbed += deposit;
        if let Some(end) = ended {
            return end;
        }
    }
}

/// The path `s` reaches the rough top face of layer `face` at `s.pos`: shadow rays from there
/// toward the next-event detectors above (the interface's reflection toward them when it came
/// down, its transmission when it came up; balanced against the direct escapes by the sampling
/// density), then a reflection or refraction drawn from its microfacets
/// ([`crate::surface::RoughDielectric`]: visible normals, each with its Fresnel reflectance),
/// whose weight `G1` multiplies the path's (the masked rest is returned as absorbed). A face is
/// no scattering event: the order stays. `Ok` the layer the path goes on in, else how it ended
/// (through the stack's top surface: an escape).
#[inline(never)]
fn cross_rough_face<const LENGTH: bool, const NEE: bool>(
    ctx: &WalkContext,
    face: usize,
    s: &mut PathState,
    rng: &mut PathRng,
    rec: &mut Recorder,
) -> (f64, Result<usize, End>) {
    let scene = ctx.scene;
    let down = s.dir.z > 0.0;
    let (n_above, n_below) = (scene.n_above_layer(face), scene.layers[face].n);
    let (n_i, n_t) = if down { (n_above, n_below) } else { (n_below, n_above) };
    // The normal on the side the light comes from.
    let frame = if down {
        crate::medium::Surface::bottom_frame()
    } else {
        crate::surface::Frame { n: DVec3::Z, t: DVec3::X, b: DVec3::Y }
    };
    let interface = crate::surface::RoughDielectric { alpha: scene.layers[face].roughness };
    let wi = frame.to_local(-s.dir);
    if NEE {
        // Up from the face: into the layer above, or out of the stack.
        let density = |d: DVec3| {
            let wo = frame.to_local(d);
            (interface.eval(wi, wo, n_i, n_t), interface.pdf(wi, wo, n_i, n_t))
        };
        surface_shadow_rays::<LENGTH>(ctx, face.checked_sub(1), s, density, s.order, None, rng, rec);
    }
    let u = [rng.uniform(), rng.uniform(), rng.uniform()];
    let Some(c) = interface.sample(wi, n_i, n_t, u) else {
        return (s.weight, Err(End::Absorbed));
    };
    let deposit = s.weight * (1.0 - c.weight);
    s.weight *= c.weight;
    if s.weight <= 0.0 {
        return (deposit, Err(End::Absorbed));
    }
    s.dir = frame.to_world(c.wo);
    if NEE {
        // The density of the direction drawn over `n²|cos|` in the medium it goes on in.
        let n = if c.transmitted { n_t } else { n_i };
        s.mis = interface.pdf(wi, c.wo, n_i, n_t) / (n * n * c.wo.z.abs());
    }
    if s.dir.z > 0.0 {
        (deposit, Ok(face))
    } else if face > 0 {
        (deposit, Ok(face - 1))
    } else {
        (deposit, Err(End::Escaped { side: Side::Top, n_ambient: scene.n_above, reflected_once: false }))
    }
}

/// Shadow rays from a vertex on a surface at `s.pos` toward every next-event target, starting
/// in layer `from` (`None`: on the stack's top surface, straight into the ambient medium);
/// `density(ω)` is the surface's `(f, q)` toward `ω` there (see [`super::nee::shadow_ray`]).
/// Each hit is recorded at scattering order `order`, with the Doppler term `n v·(dir_in − ω)` of
/// a surface of index `n` moving at `v` (`doppler`).
#[allow(clippy::too_many_arguments)]
fn surface_shadow_rays<const LENGTH: bool>(
    ctx: &WalkContext,
    from: Option<usize>,
    s: &PathState,
    density: impl Fn(DVec3) -> (f64, f64),
    order: u32,
    doppler: Option<(f64, DVec3)>,
    rng: &mut PathRng,
    rec: &mut Recorder,
) {
    let boost = connection_roulette(ctx.scene, from.unwrap_or(0), s, rng);
    let targets = if boost > 0.0 { ctx.nee } else { &[] };
    rec.stats.work.shadow_rays += targets.len() as u64;
    for target in targets {
        let (u1, u2) = (rng.uniform(), rng.uniform());
        let hit = match (from, &target.aperture) {
            (Some(li), None) => super::nee::shadow_ray(ctx.scene, li, s.pos, &density, target, u1, u2, rng),
            (Some(li), Some(a)) => super::nee::receiver_ray(ctx.scene, li, s.pos, &density, target, a, u1, u2, rng),
            (None, aperture) => super::nee::exit_ray(s.pos, &density, target, aperture.as_ref(), u1, u2),
        };
        let Some(h) = hit else { continue };
        let mut e = PathState {
            pos: h.pos,
            dir: h.dir,
            weight: s.weight * h.factor * boost,
            l: if LENGTH { s.l + h.length } else { 0.0 },
            order,
            mis: -1.0,
            ..*s
        };
        if let Some((n, v)) = doppler {
            e.dldt += doppler_increment(n, v, s.dir - h.dir_vertex);
            e.doppler_events += 1;
        }
        // The layered twin has the same planar surface (the bottom, a rough face): its shadow ray
        // is the path's without the regions' excess optical depth, weighted by `Λ`.
        let twin = match rec.twin {
            None => Twin::Off,
            Some(tw) if tw.only => Twin::Only,
            Some(tw) if !tw.touched && h.twin_is_path() => Twin::Same,
            Some(tw) => {
                let mut t = tw.state(&e);
                t.weight = s.weight * tw.lambda * boost * h.twin_factor(density(h.dir_vertex).0);
                Twin::Other(t)
            }
        };
        rec.next_event(target.detector, &e, twin, ctx.scene.n_above);
    }
}

/// The path `s` in layer `li` reaches an opaque surface of local frame `frame` (its normal
/// pointing into the layer) at `s.pos` (a camera path: [`camera_surface_connection`] first, and
/// the reflection carries radiance as it carries power, the BSDFs being reciprocal):
/// shadow rays toward the next-event detectors (the BSDF's value toward each, balanced against
/// its own density where a direct escape can also reach the detector), then a direction from the
/// BSDF, whose weight multiplies the path's (the rest is absorbed by the surface: returned, to be
/// counted with the absorbed power, as is a rough surface's masked share), and the surface's
/// Doppler term. A reflection is a scattering event: one more order, the event cap and Russian
/// roulette. `Some` end if the path ends here.
#[inline(never)]
fn reflect_at_surface<const DOPPLER: bool, const LENGTH: bool, const NEE: bool, const CAMERA: bool>(
    ctx: &WalkContext,
    surface: &crate::medium::Surface,
    frame: &crate::surface::Frame,
    li: usize,
    s: &mut PathState,
    rng: &mut PathRng,
    rec: &mut Recorder,
) -> (f64, Option<End>) {
    let n = ctx.scene.layers[li].n;
    let wi = frame.to_local(-s.dir);
    if wi.z <= 0.0 {
        // Arrived from behind its face (rounding at a solid's edge): nothing reflects it.
        return (s.weight, Some(End::Absorbed));
    }
    let moving = DOPPLER && surface.is_moving();
    let v = if moving { surface.velocity_at(s.pos) } else { DVec3::ZERO };
    if CAMERA {
        camera_surface_connection::<LENGTH>(ctx, surface, frame, wi, li, s, (moving, v), rng, rec);
    } else if NEE && surface.bsdf.has_continuous_part() {
        let density = |d: DVec3| {
            let wo = frame.to_local(d);
            (surface.bsdf.eval(wi, wo), surface.bsdf.pdf(wi, wo))
        };
        let doppler = moving.then_some((n, v));
        surface_shadow_rays::<LENGTH>(ctx, Some(li), s, density, s.order + 1, doppler, rng, rec);
    }
    let u = [rng.uniform(), rng.uniform(), rng.uniform()];
    let Some(smp) = surface.bsdf.sample(wi, u) else {
        return (s.weight, Some(End::Absorbed));
    };
    let out = frame.to_world(smp.wo);
    let deposit = s.weight * (1.0 - smp.weight);
    s.weight *= smp.weight;
    if s.weight <= 0.0 {
        return (deposit, Some(End::Absorbed));
    }
    if CAMERA {
        // Below the first rough face, against the face-lobe connection ([`face_mis`]).
        let beyond = li >= ctx.scene.first_rough_face && !smp.delta;
        s.mis = if beyond { face_mis(ctx, li, out, surface.bsdf.pdf(wi, smp.wo)) } else { -1.0 };
    } else if NEE {
        // The density of the direction drawn, in the layer's solid angle over `n²|cos|` (as a
        // collision's phase-function density): a direct escape weighs itself against the
        // shadow rays by it; a mirror's Dirac lobe is no shadow ray's (full weight).
        s.mis = if smp.delta { -1.0 } else { surface.bsdf.pdf(wi, smp.wo) / (n * n * out.z.abs()) };
    }
    if moving {
        s.dldt += doppler_increment(n, v, s.dir - out);
        s.doppler_events += 1;
    }
    // The walk's next checkpoint is due at once (it renormalises and looks at the event cap).
    let mut checkpoint = s.order.min(ctx.settings.max_events);
    (deposit, turn(s, out, ctx.settings, rng, &mut checkpoint))
}

/// A camera path ([`super::camera`]) reaches the rough top face of layer `face` at `s.pos`. The
/// stack's first rough face is where the laser's beam stops being a Dirac direction, so there
/// the path connects to it: the beam of irradiance `E` arriving from above along `b` leaves the
/// face toward the camera path with the radiance `E·cos θ_b·F(−b → −dir)/|cos θ_out|`, `F` the
/// face's power per steradian ([`crate::surface::RoughDielectric::eval`]: its reflection when
/// the path came down, its transmission when it came up). Coming down, no other way reaches that
/// light (the beam-lobe connection crosses no rough face): full weight; coming up, the vertex
/// before also connected through the face's lobe ([`face_connection`]), and the two are
/// balanced by `s.mis` ([`face_mis`]). Then the
/// crossing is drawn as a forward path's, carrying radiance: a refraction from `n_i` into `n_t`
/// multiplies the weight by `(n_i/n_t)²` (`L/n²` is invariant, as across a smooth face). `Ok`
/// the layer the path goes on in, else how it ended.
#[inline(never)]
fn camera_rough_face<const LENGTH: bool>(
    ctx: &WalkContext,
    face: usize,
    s: &mut PathState,
    rng: &mut PathRng,
    rec: &mut Recorder,
) -> Result<usize, End> {
    let scene = ctx.scene;
    let down = s.dir.z > 0.0;
    let (n_above, n_below) = (scene.n_above_layer(face), scene.layers[face].n);
    let interface = crate::surface::RoughDielectric { alpha: scene.layers[face].roughness };
    // The face's frame with its normal up, on the beam's side.
    let up = crate::medium::Surface::bottom_frame();
    if let Some(shot) = ctx.shot
        && face == scene.first_rough_face
    {
        let boost = connection_roulette(scene, face, s, rng);
        rec.stats.work.camera_connections += 1;
        if boost > 0.0
            && let Some(b) = super::camera::beam_at_face(scene, ctx.source, face, s.pos, rng)
        {
            let (to_light, to_camera) = (up.to_local(-b.dir), up.to_local(-s.dir));
            let f = interface.eval(to_light, to_camera, n_above, n_below);
            if f > 0.0 {
                let radiance = b.irradiance * to_light.z * f / to_camera.z.abs();
                // From below, weighted against the face-lobe connection of the vertex before
                // (`s.mis`, [`face_mis`]); from above no other way reaches it.
                let w = if !down && s.mis >= 0.0 { s.mis / (s.mis + 1.0) } else { 1.0 };
                let e = PathState {
                    dir: -s.dir,
                    weight: s.weight * w * boost * radiance * shot.scale,
                    l: if LENGTH { s.l + b.length } else { 0.0 },
                    mis: -1.0,
                    ..*s
                };
                rec.camera(&shot, &e);
            }
        }
    }
    // The crossing, drawn on the side the path comes from.
    let (n_i, n_t) = if down { (n_above, n_below) } else { (n_below, n_above) };
    let frame = if down { up } else { crate::surface::Frame { n: DVec3::Z, t: DVec3::X, b: DVec3::Y } };
    let wi = frame.to_local(-s.dir);
    let u = [rng.uniform(), rng.uniform(), rng.uniform()];
    let c = interface.sample(wi, n_i, n_t, u).ok_or(End::Absorbed)?;
    s.weight *= if c.transmitted { c.weight * (n_i / n_t) * (n_i / n_t) } else { c.weight };
    if s.weight <= 0.0 {
        return Err(End::Absorbed);
    }
    s.dir = frame.to_world(c.wo);
    // The next vertex is no beam-lobe connection's (none crosses a rough face): full weight.
    s.mis = -1.0;
    if s.dir.z > 0.0 {
        Ok(face)
    } else if face > 0 {
        Ok(face - 1)
    } else {
        Err(End::Escaped { side: Side::Top, n_ambient: scene.n_above, reflected_once: false })
    }
}

/// The face-lobe connection of a camera path's vertex at `s.pos` in layer `li`, at or below the
/// stack's first rough face ([`super::camera::face_lobe`]): `density(u)` is the vertex's
/// `(f, q)` toward the upward direction `u` (the phase function's value and density, or a
/// surface's `f|cos|` and sampling density). Weighted by the balance heuristic against the walk's
/// own way to the face (which [`face_mis`] prepares): `f·L/(q_lobe + q·ΠT)`. Scored at
/// scattering order `order`; `mark` adds the vertex's Doppler term for light arriving along a
/// direction.
#[allow(clippy::too_many_arguments)]
#[cold]
#[inline(never)]
fn face_connection<const LENGTH: bool>(
    ctx: &WalkContext,
    li: usize,
    shot: &Shot,
    s: &PathState,
    density: impl Fn(DVec3) -> (f64, f64),
    boost: f64,
    mark: impl Fn(&mut PathState, DVec3),
    rng: &mut PathRng,
    rec: &mut Recorder,
) {
    let u = [rng.uniform(), rng.uniform(), rng.uniform()];
    rec.stats.work.camera_connections += 1;
    let Some(h) = super::camera::face_lobe(ctx.scene, ctx.source, li, s.pos, u, rng) else { return };
    let (f, q) = density(h.dir);
    if f <= 0.0 {
        return;
    }
    let mut e = PathState {
        dir: -s.dir,
        weight: s.weight * boost * f * h.radiance / (h.density + q * h.transmit) * shot.scale,
        l: if LENGTH { s.l + h.length } else { 0.0 },
        order: s.order + 1,
        mis: -1.0,
        ..*s
    };
    mark(&mut e, -h.dir);
    rec.camera(shot, &e);
}

/// A camera path's `mis` after a vertex in layer `li` (at or below the stack's first rough face)
/// sent it along `out` with the density `q`: `q/q_lobe`, the ratio of its density to the
/// face-lobe connection's ([`super::camera::face_lobe_density`]), which the crossings of smooth
/// faces on the way multiply by their transmittances and the rough face's connection from below
/// turns into its weight; −1 (full weight) where no face-lobe connection takes that way. (The
/// density is evaluated in here: a phase function's evaluation added to `collide_camera` made
/// the compiler outline it from there, +1 % of the camera walk's instructions.)
#[cold]
#[inline(never)]
fn face_mis(ctx: &WalkContext, li: usize, out: DVec3, q: f64) -> f64 {
    let lobe = super::camera::face_lobe_density(ctx.scene, ctx.source, li, out);
    if lobe > 0.0 { q / lobe } else { -1.0 }
}

/// A camera path's ([`super::camera`]) connection to the laser from its reflection at an opaque
/// surface (local frame `frame`, the path arriving from `wi`) in layer `li`, moving at `v` if
/// `moving`. Above the stack's first rough face the surface connects to the beam as a collision
/// does ([`super::camera::beam_connection`]): the radiance toward the camera path is
/// `f·cos θ_b·E`, which the BSDF's value toward the beam gives (`eval`, reciprocal:
/// `f(ω_cam, ω_b)·cos θ_b`), with the surface's Doppler term `n v·(b + dir)`; full weight, as no
/// beam-lobe path ends on a surface. Below the first rough face it connects through that face's
/// lobe instead ([`face_connection`]).
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn camera_surface_connection<const LENGTH: bool>(
    ctx: &WalkContext,
    surface: &crate::medium::Surface,
    frame: &crate::surface::Frame,
    wi: DVec3,
    li: usize,
    s: &PathState,
    (moving, v): (bool, DVec3),
    rng: &mut PathRng,
    rec: &mut Recorder,
) {
    let scene = ctx.scene;
    let Some(shot) = ctx.shot else { return };
    let n = scene.layers[li].n;
    let boost = connection_roulette(scene, li, s, rng);
    let dir_in = s.dir;
    let mark = |e: &mut PathState, arrive: DVec3| {
        if moving {
            e.dldt += doppler_increment(n, v, arrive + dir_in);
            e.doppler_events += 1;
        }
    };
    if li >= scene.first_rough_face {
        if boost > 0.0 {
            let density = |u: DVec3| {
                let wo = frame.to_local(u);
                (surface.bsdf.eval(wi, wo), surface.bsdf.pdf(wi, wo))
            };
            face_connection::<LENGTH>(ctx, li, &shot, s, density, boost, mark, rng, rec);
        }
        return;
    }
    rec.stats.work.camera_connections += 1;
    if boost > 0.0
        && let Some(b) = super::camera::beam_connection(scene, ctx.source, li, s.pos, rng)
    {
        let f = surface.bsdf.eval(wi, frame.to_local(-b.dir));
        if f > 0.0 {
            let mut e = PathState {
                dir: -s.dir,
                weight: s.weight * boost * f * b.irradiance * shot.scale,
                l: if LENGTH { s.l + b.length } else { 0.0 },
                order: s.order + 1,
                mis: -1.0,
                ..*s
            };
            mark(&mut e, b.dir);
            rec.camera(&shot, &e);
        }
    }
}

/// The path `s` in a layer of index `n` reaches the side face `axis` (0: x, 1: y) of the box
/// `b`, `t` away: the gate, the volume tally's track, then Fresnel against `b.n_outside` at
/// incidence `|dir·normal|` (unpolarised, as at the layer interfaces). `None`: reflected back in
/// (the normal component of `dir` reversed); else how the path ended.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn side_face<const LENGTH: bool, const VOLUME: bool, const GATE: bool>(
    ctx: &WalkContext,
    s: &mut PathState,
    t: f64,
    axis: usize,
    n: f64,
    b: crate::medium::Lateral,
    rng: &mut PathRng,
    rec: &mut Recorder,
) -> Option<End> {
    if VOLUME && let Some(v) = ctx.volume {
        // Clipped to the gate's end if the path ends there.
        v.track::<GATE>(rec.acc, s.pos, s.dir, t, s.weight, s.l, n);
    }
    if GATE
        && let Some((_, l1)) = ctx.settings.gate
        && s.l + n * t > l1
    {
        return Some(End::Gated);
    }
    if !t.is_finite() {
        return Some(End::Truncated);
    }
    if LENGTH {
        s.l += n * t;
    }
    s.pos += t * s.dir;
    // On the face exactly, so that the next flight starts inside.
    let (lo, hi) = if axis == 0 { b.x } else { b.y };
    let outward = s.dir[axis] > 0.0;
    s.pos[axis] = if outward { hi } else { lo };
    let (r, cos_t) = fresnel::reflectance(n, b.n_outside, s.dir[axis].abs());
    if r > 0.0 && (r >= 1.0 || rng.uniform() < r) {
        s.dir[axis] = -s.dir[axis];
        return None;
    }
    // Refracted out (Snell across the face's normal; nothing records the direction, but the
    // state stays a physical one).
    if n != b.n_outside {
        let eta = n / b.n_outside;
        s.dir *= eta;
        s.dir[axis] = cos_t.copysign(if outward { 1.0 } else { -1.0 });
    }
    Some(End::Lateral)
}

/// A real collision `v` of `s` at distance `t` in layer `li`: absorption weighting, a new
/// direction (guided where the weight windows have a guide), the Doppler term, the event cap and
/// Russian roulette. `Some` if the path ends here.
#[inline(always)]
fn collide<const DOPPLER: bool, const LENGTH: bool>(
    s: &mut PathState,
    t: f64,
    v: Vertex,
    ctx: &WalkContext,
    rng: &mut PathRng,
    absorbed: &mut f64,
    checkpoint: &mut u32,
) -> Option<End> {
    let Vertex { medium: m, albedo, n, li } = v;
    s.pos += t * s.dir;
    if LENGTH {
        s.l += n * t;
    }
    if absorb(s, albedo, absorbed) {
        return Some(End::Absorbed);
    }
    let (pop, dynamic) = m.pick_dynamic(rng);
    let (out, delta) = match ctx.windows {
        Some(w) if w.guide.is_some() => {
            let cell = w.guide_cell(li, s.pos, s.dir, &pop.phase);
            let (_, out, delta) = continue_guided(s, &pop.phase, cell, rng);
            (out, delta)
        }
        _ => {
            let (_, out, delta) = deflect(s.dir, &pop.phase, rng);
            (out, delta)
        }
    };
    if DOPPLER && dynamic {
        let v = particle_velocity(pop, s.pos, rng);
        doppler_event(s, pop, n, v, delta);
    }
    turn(s, out, ctx.settings, rng, checkpoint)
}

/// The continuation of `s` from a scatterer of phase function `phase` where the guide acts with
/// the table's values `cell` ([`super::guide`]): one of several directions drawn from the phase
/// function, resampled on their importance, and the weight times the resampling's factor; the
/// phase function's draw alone (weight unchanged) where it does not (`cell` `None`). Returns
/// `(cos θ, out, dir − out)` of the deflection.
#[inline(never)]
fn continue_guided(
    s: &mut PathState,
    phase: &crate::phase::PhaseFunction,
    cell: Option<&[f64]>,
    rng: &mut PathRng,
) -> (f64, DVec3, DVec3) {
    let dir = s.dir;
    let draw = |rng: &mut PathRng| {
        let (d, out, delta) = deflect(dir, phase, rng);
        (d.cos, out, delta)
    };
    let Some(cell) = cell else { return draw(rng) };
    let (chosen, factor) = super::guide::resample(cell, rng, draw);
    s.weight *= factor;
    chosen
}

/// [`collide`] with next-event estimation: after the absorption weighting, a shadow ray toward
/// every next-event detector (see [`super::nee`]) is scored with the velocity the vertex's
/// particle has; then the path scatters on as usual. `s.pos` is already at the vertex.
//
// The allow is the measured exception of issue 19: taking `(ctx: &WalkContext, s, v: Vertex,
// rng, absorbed, checkpoint, rec)` instead (with the shadow rays taking their vertex as one
// `ShadowOrigin` struct, `nee::shadow_ray`/`receiver_ray`) cost, in callgrind instructions of
// `run_batch`, vessels_ldh 337.15M → 343.04M (+1.75 %), retina_ldh 446.17M → 453.31M (+1.60 %),
// fmcw_target 587.64M → 593.53M (+1.00 %): this function alone 33.9M → 38.6M on vessels_ldh
// (it is outlined, so the grouped arguments go through memory).
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn collide_nee<const DOPPLER: bool, const LENGTH: bool>(
    scene: &Scene,
    nee: &[NeeTarget],
    windows: Option<&Windows>,
    li: usize,
    s: &mut PathState,
    m: &Medium,
    albedo: f64,
    n: f64,
    settings: &WalkSettings,
    rng: &mut PathRng,
    absorbed: &mut f64,
    checkpoint: &mut u32,
    rec: &mut Recorder,
) -> Option<End> {
    // The layered twin collides in the layer's filling medium where the path collides in a region.
    // While `Λ` stays within [1/TWIN_BAND, TWIN_BAND] it shares the path's collision (below);
    // beyond, it parts from the path here and walks on by itself ([`Split`], traced after the
    // path) from the path's state arriving here, weighted by `Λ` and the collision densities'
    // ratio `σt,fill / σt,medium`; the path goes on without a twin.
    let fill = &scene.media[scene.layers[li].medium];
    let in_region = rec.twin.is_some_and(|t| !t.only) && !std::ptr::eq(m, fill);
    if in_region
        && let Some(tw) = rec.twin
        && !(1.0 / TWIN_BAND..=TWIN_BAND).contains(&tw.lambda)
    {
        let weight = s.weight * fill.sigma_t() / m.sigma_t();
        rec.split =
            Some(Split { s: tw.state(&PathState { weight, ..*s }), li, twin: tw, rng: rng.clone(), flying: false });
        rec.twin = None;
    }
    if absorb(s, albedo, absorbed) {
        return Some(End::Absorbed);
    }
    // One population serves the shadow rays and the continuation (so that the balance heuristic
    // of `shadow_ray` weighs against the density the continuation is drawn from).
    let (pop, dynamic) = m.pick_dynamic(rng);
    let dynamic = DOPPLER && dynamic;
    let v = if dynamic { particle_velocity(pop, s.pos, rng) } else { DVec3::ZERO };
    // The coupled twin's particles here (drawn by the fill's shares, on its own: no ratio), their
    // velocity, and its collision and weight after it over the path's: `σt,fill·a_fill / (σt·a)
    // = σs,fill/σs` (the flight's share is in from the flight). Not over the population's σs:
    // the path's draw of its particles is no part of the twin's density (measured: a vessel of
    // two populations, 14 and 6 /mm, gave an image 19 % low, χ² 57 over 16 pixels).
    let coupled = (in_region && rec.twin.is_some()).then(|| {
        let (tpop, tdyn) = fill.pick_dynamic(rng);
        let tdyn = DOPPLER && tdyn;
        (tpop, tdyn, if tdyn { particle_velocity(tpop, s.pos, rng) } else { DVec3::ZERO })
    });
    if let (Some(tw), true) = (rec.twin.as_mut(), coupled.is_some()) {
        tw.lambda *= fill.sigma_s() / m.sigma_s();
        tw.touched = true;
    }
    // (Without next-event targets this walk runs for the layered twin alone: no roulette draw, no
    // shadow ray, no density for the escapes' weights against them.)
    let boost = if nee.is_empty() { 0.0 } else { connection_roulette(scene, li, s, rng) };
    let targets = if boost > 0.0 { nee } else { &[] };
    rec.stats.work.shadow_rays += targets.len() as u64;
    // The particle scatters toward `d` with the phase function's density, which is also the
    // density its continuation is drawn from.
    let phase_density = |d: DVec3| {
        let p = pop.phase.eval(s.dir.dot(d));
        (p, p)
    };
    for target in targets {
        let (u1, u2) = (rng.uniform(), rng.uniform());
        let hit = match &target.aperture {
            None => super::nee::shadow_ray(scene, li, s.pos, phase_density, target, u1, u2, rng),
            Some(a) => super::nee::receiver_ray(scene, li, s.pos, phase_density, target, a, u1, u2, rng),
        };
        let Some(h) = hit else { continue };
        let mut e = PathState {
            pos: h.pos,
            dir: h.dir,
            weight: s.weight * h.factor * boost,
            l: if LENGTH { s.l + h.length } else { 0.0 },
            order: s.order + 1,
            mis: -1.0,
            ..*s
        };
        let in_out = s.dir - h.dir_vertex;
        // The twin's shadow ray: its phase function (its own particles' where it shares a
        // collision in a region), without the regions' excess optical depth, its Doppler state.
        let twin = match rec.twin {
            None => Twin::Off,
            Some(tw) if tw.only => Twin::Only,
            Some(tw) if !tw.touched && coupled.is_none() && h.twin_is_path() => Twin::Same,
            Some(tw) => {
                let mut t = tw.state(&e);
                let p = coupled.map_or(&pop.phase, |(tpop, ..)| &tpop.phase);
                t.weight = s.weight * tw.lambda * boost * h.twin_factor(p.eval(s.dir.dot(h.dir_vertex)));
                match coupled {
                    Some((tpop, true, tv)) => doppler_event(&mut t, tpop, n, tv, in_out),
                    Some(_) => {}
                    None if dynamic => doppler_event(&mut t, pop, n, v, in_out),
                    None => {}
                }
                Twin::Other(t)
            }
        };
        if dynamic {
            doppler_event(&mut e, pop, n, v, in_out);
        }
        rec.next_event(target.detector, &e, twin, scene.n_above);
    }
    // The continuation: guided where the weight windows have a guide that acts here, but not at
    // a collision the twin shares in a region (its likelihood ratio takes the phase function's own
    // draw).
    let (cos, out, delta) = match windows {
        Some(w) if w.guide.is_some() && coupled.is_none() => {
            let cell = w.guide_cell(li, s.pos, s.dir, &pop.phase);
            continue_guided(s, &pop.phase, cell, rng)
        }
        _ => {
            let (d, out, delta) = deflect(s.dir, &pop.phase, rng);
            (d.cos, out, delta)
        }
    };
    if !nee.is_empty() {
        s.mis = pop.phase.eval(cos) / (n * n * out.z.abs());
    }
    if let (Some(tw), Some((tpop, tdyn, tv))) = (rec.twin.as_mut(), coupled) {
        // The coupled twin's density of the direction drawn over the path's, and its Doppler
        // event instead of the path's.
        tw.lambda *= tpop.phase.eval(cos) / pop.phase.eval(cos);
        let mut shift = PathState::new(s.pos, s.dir, 0.0, 0.0);
        if tdyn {
            doppler_event(&mut shift, tpop, n, tv, delta);
        }
        let mut own = PathState::new(s.pos, s.dir, 0.0, 0.0);
        if dynamic {
            doppler_event(&mut own, pop, n, v, delta);
        }
        tw.dldt += shift.dldt - own.dldt;
        tw.brownian += shift.brownian - own.brownian;
        tw.doppler_events += i64::from(shift.doppler_events) - i64::from(own.doppler_events);
    }
    if dynamic {
        doppler_event(s, pop, n, v, delta);
    }
    turn(s, out, settings, rng, checkpoint)
}

/// The layered twin shares its path's collisions in regions while its likelihood ratio `Λ` stays
/// within `[1/TWIN_BAND, TWIN_BAND]`, and parts from it at the first collision in a region beyond
/// ([`Split`]): a bound on `Λ`, a product of a phase-function ratio per collision through a vessel.
/// Measured on retina_ldh (validation/README.md, issue 35): parting at the first collision lost the
/// correlation of the path and its twin that makes the vessels' intensity converge (vessel-pixel
/// median 0.44 against 0.11), a band of 2 kept half of it (0.18); at 8 no path parted.
pub const TWIN_BAND: f64 = 8.0;

/// Where a [`coupled_flight`](super::tracking::coupled_flight) of the path `s` in layer `li` (of
/// index `n`) parted it from its twin: the twin walks on from there once the path has ended
/// ([`Split`]), colliding there or flying on, with the path's weight and Doppler state under
/// `Λ` and the generator as it was there.
#[cold]
#[inline(never)]
fn part_in_flight<const LENGTH: bool>(
    s: &PathState,
    li: usize,
    n: f64,
    p: super::tracking::Parting,
    rec: &mut Recorder,
) {
    let Some(tw) = rec.twin.take() else { return };
    let at = PathState { pos: s.pos + p.t * s.dir, l: if LENGTH { s.l + n * p.t } else { 0.0 }, ..*s };
    rec.split =
        Some(Split { s: tw.state(&at), li, twin: TwinPath { touched: true, ..tw }, rng: p.rng, flying: !p.collides });
}

/// The path `s` in layer `li` has flown to an opaque solid's boundary, which its layered twin
/// (without solids, `Scene::layered_twin`) does not have: the twin parts from it there and, once
/// the path has ended, flies on from that point (the path's flight ran that far without a
/// collision, and the rest of the twin's is a fresh exponential) on a copy of the generator
/// ([`Split`]); the path goes on without a twin.
#[cold]
#[inline(never)]
fn part_at_solid(s: &PathState, li: usize, rng: &PathRng, rec: &mut Recorder) {
    let Some(tw) = rec.twin.take() else { return };
    rec.split =
        Some(Split { s: tw.state(s), li, twin: TwinPath { touched: true, ..tw }, rng: rng.clone(), flying: true });
}

/// The twin's own walk from where it parted from its path ([`Split`]), in the twin's scene
/// (`ctx.twin_scene`: the regions removed): its collision there (or, parted in flight, its
/// flight on from there), then its walk, every
/// contribution scored as the twin's alone ([`Twin::Only`]); nothing of it reaches the scalar
/// tallies or the volume tally.
#[cold]
#[inline(never)]
fn twin_walk<const DOPPLER: bool, const LENGTH: bool, const GATE: bool>(
    ctx: &WalkContext,
    split: Split,
    rec: &mut Recorder,
) {
    let Some(scene) = ctx.twin_scene else { return };
    let ctx = WalkContext { scene, volume: None, reflections: false, windows: None, ..*ctx };
    let Split { mut s, li, twin, mut rng, flying } = split;
    rec.twin = Some(TwinPath { only: true, ..twin });
    let layer = &scene.layers[li];
    let fill = &scene.media[layer.medium];
    let (mut absorbed, mut nulls) = (0.0, 0);
    let mut checkpoint = s.order.saturating_add(RENORMALISE_EVERY).min(ctx.settings.max_events);
    let first = if flying {
        None
    } else {
        collide_nee::<DOPPLER, LENGTH>(
            scene,
            ctx.nee,
            None,
            li,
            &mut s,
            fill,
            fill.albedo(),
            layer.n,
            ctx.settings,
            &mut rng,
            &mut absorbed,
            &mut checkpoint,
            rec,
        )
    };
    let end = match first {
        Some(end) => end,
        None => walk_to_the_end::<DOPPLER, LENGTH, true, false, GATE, false, false>(
            &ctx,
            li,
            &mut s,
            &mut rng,
            &mut absorbed,
            &mut nulls,
            rec,
            false,
        ),
    };
    if let End::Escaped { side, n_ambient, .. } = end
        && in_gate::<GATE>(ctx.settings, s.l)
    {
        rec.escape(side, s, Exit::Walked, n_ambient);
    }
    rec.twin = None;
}

/// A real collision of a camera path at `s.pos`: the absorption weighting, the connection to the
/// laser scored into the path's pixel, the beam-lobe connection through a vertex further up, then
/// a new direction as [`collide`] (see [`super::camera`], "Two ways to the last vertex"). One
/// particle velocity serves the connections and the continuation.
//
// Outlined, as `collide_nee`: the connections are traces through every layer above.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn collide_camera<const DOPPLER: bool, const LENGTH: bool>(
    ctx: &WalkContext,
    li: usize,
    s: &mut PathState,
    m: &Medium,
    albedo: f64,
    n: f64,
    rng: &mut PathRng,
    checkpoint: &mut u32,
    rec: &mut Recorder,
) -> Option<End> {
    s.weight *= albedo;
    if s.weight <= 0.0 {
        return Some(End::Absorbed);
    }
    let scene = ctx.scene;
    if li >= scene.first_rough_face {
        return collide_camera_beyond::<DOPPLER, LENGTH>(ctx, li, s, m, n, rng, checkpoint, rec);
    }
    let (pop, dynamic) = m.pick_dynamic(rng);
    let dynamic = DOPPLER && dynamic;
    let v = if dynamic { particle_velocity(pop, s.pos, rng) } else { DVec3::ZERO };
    // The beam reaches the vertex through at least the same optical depth as a shadow ray.
    let boost = connection_roulette(scene, li, s, rng);
    // The guide lobe about the beam's reversed direction in this layer.
    let guide = super::camera::guide();
    let up = super::camera::refracted_down(ctx.source.direction, scene.n_above, n).map(|b| -b);
    if let (Some(shot), true) = (ctx.shot, boost > 0.0) {
        // This vertex as the walk's last: weighted against the lobe connection from the vertex
        // before, `s.mis` = (walk density · Fresnel transmittances)/(guide density) of the way
        // here (−1 when the lobe connection cannot make it).
        let w = if s.mis >= 0.0 { s.mis / (s.mis + 1.0) } else { 1.0 };
        let here = Link { pos: s.pos, dir_in: s.dir, pop, v, dynamic, n };
        let tail = *s;
        rec.stats.work.camera_connections += 1;
        connect::<LENGTH>(ctx, li, &shot, here, tail, s.weight * w * boost, rng, rec);
        // The beam-lobe connection: a direction from the guide lobe, the straight refracted way
        // through the layers to a real collision there, and its connection.
        if let Some(up) = up {
            let dd = guide.sample(rng.uniform());
            let (cos_phi, sin_phi) = warp::azimuth_i32(|| rng.pair_i32());
            let (dir, _) = scatter_direction(up, dd, cos_phi, sin_phi);
            let (p_walk, p_guide) = (pop.phase.eval(s.dir.dot(dir)), guide.eval(dd.cos));
            rec.stats.work.camera_connections += 1;
            if let Some(h) = super::camera::lobe_flight(scene, li, s.pos, dir, ctx.settings.tracking, rng) {
                let m2 = &scene.media[h.medium];
                let albedo2 = if scene.layers[h.layer].heterogeneous { m2.albedo_at(h.pos) } else { m2.albedo() };
                let (pop2, dynamic2) = m2.pick_dynamic(rng);
                let dynamic2 = DOPPLER && dynamic2;
                let v2 = if dynamic2 { particle_velocity(pop2, h.pos, rng) } else { DVec3::ZERO };
                let mut tail = tail;
                if dynamic {
                    doppler_event(&mut tail, pop, n, v, s.dir - dir);
                }
                tail.order += 1;
                tail.l += if LENGTH { h.length } else { 0.0 };
                let n2 = scene.layers[h.layer].n;
                let there = Link { pos: h.pos, dir_in: h.dir, pop: pop2, v: v2, dynamic: dynamic2, n: n2 };
                let pt = p_walk * h.transmit;
                let w = s.weight * boost * pt / (pt + p_guide) * h.radiance * albedo2;
                rec.stats.work.camera_connections += 1;
                connect::<LENGTH>(ctx, h.layer, &shot, there, tail, w, rng, rec);
            }
        }
    }
    let (d, out, delta) = deflect(s.dir, &pop.phase, rng);
    s.mis = match up {
        Some(up) => pop.phase.eval(d.cos) / guide.eval(up.dot(out)),
        None => -1.0,
    };
    if dynamic {
        doppler_event(s, pop, n, v, delta);
    }
    turn(s, out, ctx.settings, rng, checkpoint)
}

/// [`collide_camera`] at or below the stack's first rough face, where the beam's light arrives
/// through the face's lobe: the connection through it ([`face_connection`]), a new direction and
/// its density against the lobe's ([`face_mis`]). (A function of its own: as branches in
/// `collide_camera` they cost the camera walk 1.2 % of its instructions where no face is rough.)
#[allow(clippy::too_many_arguments)]
#[cold]
#[inline(never)]
fn collide_camera_beyond<const DOPPLER: bool, const LENGTH: bool>(
    ctx: &WalkContext,
    li: usize,
    s: &mut PathState,
    m: &Medium,
    n: f64,
    rng: &mut PathRng,
    checkpoint: &mut u32,
    rec: &mut Recorder,
) -> Option<End> {
    let (pop, dynamic) = m.pick_dynamic(rng);
    let dynamic = DOPPLER && dynamic;
    let v = if dynamic { particle_velocity(pop, s.pos, rng) } else { DVec3::ZERO };
    let boost = connection_roulette(ctx.scene, li, s, rng);
    if boost > 0.0
        && let Some(shot) = ctx.shot
    {
        let dir_in = s.dir;
        let density = |u: DVec3| {
            let p = pop.phase.eval(dir_in.dot(u));
            (p, p)
        };
        let mark = |e: &mut PathState, arrive: DVec3| {
            if dynamic {
                doppler_event(e, pop, n, v, arrive + dir_in);
            }
        };
        face_connection::<LENGTH>(ctx, li, &shot, s, density, boost, mark, rng, rec);
    }
    let (d, out, delta) = deflect(s.dir, &pop.phase, rng);
    s.mis = face_mis(ctx, li, out, pop.phase.eval(d.cos));
    if dynamic {
        doppler_event(s, pop, n, v, delta);
    }
    turn(s, out, ctx.settings, rng, checkpoint)
}

/// A vertex a camera path connects to the laser from: where, the walk's direction into it, the
/// particle scattering there (and its velocity), and the layer's index.
#[derive(Clone, Copy)]
struct Link<'a> {
    pos: DVec3,
    dir_in: DVec3,
    pop: &'a Population,
    v: DVec3,
    dynamic: bool,
    n: f64,
}

/// Connect `at` (in layer `li`) to the laser and score the path into `shot`'s pixel with the
/// weight `w` (the walk's weight, with every factor but the phase function and the irradiance).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn connect<const LENGTH: bool>(
    ctx: &WalkContext,
    li: usize,
    shot: &Shot,
    at: Link,
    tail: PathState,
    w: f64,
    rng: &mut PathRng,
    rec: &mut Recorder,
) {
    let Some(b) = super::camera::beam_connection(ctx.scene, ctx.source, li, at.pos, rng) else { return };
    // The light arrives along `b.dir` and leaves towards the camera along `−dir_in`.
    let p = at.pop.phase.eval(-b.dir.dot(at.dir_in));
    let mut e = PathState {
        pos: at.pos,
        dir: -at.dir_in,
        weight: w * p * b.irradiance * shot.scale,
        l: if LENGTH { tail.l + b.length } else { 0.0 },
        order: tail.order + 1,
        mis: -1.0,
        ..tail
    };
    if at.dynamic {
        doppler_event(&mut e, at.pop, at.n, at.v, b.dir + at.dir_in);
    }
    rec.camera(shot, &e);
}

/// The roulette of a vertex's connections (shadow rays to a detector, or a camera path's to the
/// laser): none carries more than `weight·exp(−τ_min)`, `τ_min` being the optical depth straight
/// up through the least dense media. Below `SHADOW_ROULETTE_WEIGHT` they are traced with
/// probability `bound/threshold`; returns the factor they are weighted by (its inverse, or 1;
/// 0: not traced), which keeps them unbiased. Deep vertices (under a pigmented layer) then cost a
/// free flight and a phase sample, not a connection through every layer above.
#[inline(always)]
fn connection_roulette(scene: &Scene, li: usize, s: &PathState, rng: &mut PathRng) -> f64 {
    let q = s.weight * (-scene.layers[li].min_optical_depth_up(s.pos.z)).exp() / super::nee::SHADOW_ROULETTE_WEIGHT;
    if q >= 1.0 {
        1.0
    } else if rng.uniform() < q {
        1.0 / q
    } else {
        0.0
    }
}

/// Whether a path recorded at optical path length `l` is inside the time gate (always in walks
/// compiled without one, `GATE = false`).
#[inline(always)]
fn in_gate<const GATE: bool>(settings: &WalkSettings, l: f64) -> bool {
    match settings.gate {
        Some((l0, l1)) if GATE => l0 <= l && l <= l1,
        _ => true,
    }
}

/// Absorption weighting: deposit `(1 − albedo)` of the weight, carry on with the rest. `true` if
/// no weight is left.
#[inline(always)]
fn absorb(s: &mut PathState, albedo: f64, absorbed: &mut f64) -> bool {
    *absorbed += s.weight * (1.0 - albedo);
    s.weight *= albedo;
    s.weight <= 0.0
}

/// A scattering event on a particle of velocity `v` with `dir_in − dir_out = delta`: the Doppler
/// term, the Brownian `q²D` term and the event count. The scattering vector is
/// `q = (2πn/λ0)·delta`, so `D·q² = (2π/λ0)²·D n²|delta|²` and only the wavelength-free part is
/// carried.
#[inline(always)]
fn doppler_event(s: &mut PathState, m: &Population, n: f64, v: DVec3, delta: DVec3) {
    s.dldt += doppler_increment(n, v, delta);
    if m.motion.diffusion > 0.0 {
        s.brownian += m.motion.diffusion * n * n * delta.length_squared();
    }
    s.doppler_events += 1;
}

/// A new direction about `dir` drawn from `phase` (its deflection, then the azimuth): the
/// deflection, the direction and `dir − out` ([`scatter_direction`]).
#[inline(always)]
fn deflect(dir: DVec3, phase: &crate::phase::PhaseFunction, rng: &mut PathRng) -> (Deflection, DVec3, DVec3) {
    let d = phase.sample(rng.uniform());
    let (cos_phi, sin_phi) = warp::azimuth_i32(|| rng.pair_i32());
    let (out, delta) = scatter_direction(dir, d, cos_phi, sin_phi);
    (d, out, delta)
}

/// The path turns to `out` at a real collision: one more scattering order, then the end of the
/// event ([`end_of_event`]).
#[inline(always)]
fn turn(
    s: &mut PathState,
    out: DVec3,
    settings: &WalkSettings,
    rng: &mut PathRng,
    checkpoint: &mut u32,
) -> Option<End> {
    s.dir = out;
    s.order += 1;
    end_of_event(s, settings, rng, checkpoint)
}

/// The velocity of the particle a path scatters on at `p`: the flow plus, for a medium with a
/// velocity dispersion, a Gaussian random velocity drawn for this event.
#[inline(always)]
fn particle_velocity(m: &Population, p: DVec3, rng: &mut PathRng) -> DVec3 {
    let mut v = m.velocity.velocity(p, rng);
    let sd = m.motion.dispersion;
    if sd > 0.0 {
        v += sd * DVec3::new(rng.normal(), rng.normal(), rng.normal());
    }
    v
}

/// The end of every real collision: event cap, periodic renormalisation, Russian roulette.
#[inline(always)]
fn end_of_event(s: &mut PathState, settings: &WalkSettings, rng: &mut PathRng, checkpoint: &mut u32) -> Option<End> {
    // One comparison per event serves both the event cap and the periodic renormalisation (a
    // separate `order % RENORMALISE_EVERY` test cost 5 instructions per collision).
    if s.order >= *checkpoint {
        if s.order >= settings.max_events {
            return Some(End::Truncated);
        }
        s.dir = renormalise(s.dir);
        *checkpoint = s.order.saturating_add(RENORMALISE_EVERY).min(settings.max_events);
    }
    if s.weight < settings.roulette_threshold {
        if rng.uniform() < settings.roulette_survival {
            s.weight /= settings.roulette_survival;
        } else {
            return Some(End::Roulette);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::{HenyeyGreenstein, PhaseFunction};
    use crate::sampling::Purpose;

    #[test]
    fn scattering_matches_the_explicit_basis() {
        // The collected form equals sin θ·(cos φ t + sin φ b) with the basis built, to rounding,
        // for directions in every octant and at the poles, and deflections down to 1e-9 rad,
        // where `dir_in − dir_out` must keep its relative precision.
        let mut rng = PathRng::new(6, Purpose::Test, 0, 0);
        let mut dirs = vec![DVec3::Z, -DVec3::Z, DVec3::X, DVec3::new(1e-9, 0.0, -1.0).normalize()];
        for _ in 0..2000 {
            dirs.push(warp::uniform_sphere(rng.uniform(), rng.uniform()));
        }
        for dir in dirs {
            for theta in [1e-9, 1e-4, 0.3, 2.0, 3.1] {
                let d = Deflection {
                    cos: f64::cos(theta),
                    one_minus_cos: 2.0 * (0.5 * theta).sin().powi(2),
                    sin: theta.sin(),
                };
                let (cos_phi, sin_phi) = warp::azimuth_i32(|| rng.pair_i32());
                let (out, delta) = scatter_direction(dir, d, cos_phi, sin_phi);
                let (t, b) = warp::orthonormal_basis(dir);
                let perp = t * cos_phi + b * sin_phi;
                let (out_ref, delta_ref) = (dir * d.cos + perp * d.sin, dir * d.one_minus_cos - perp * d.sin);
                assert!((out - out_ref).length() < 1e-15, "{dir} θ={theta}: {out} vs {out_ref}");
                assert!((delta - delta_ref).length() <= 1e-15 * delta_ref.length(), "{dir} θ={theta}");
                assert!((out.length() - 1.0).abs() < 1e-15 && (out.dot(dir) - d.cos).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn direction_stays_unit_over_many_events() {
        // The walk's sequence of rotations and periodic renormalisations, 10⁶ events per g.
        for &g in &[0.0, 0.75, -0.9, 0.99, 0.999999] {
            let phase = PhaseFunction::HenyeyGreenstein(HenyeyGreenstein::new(g).unwrap());
            let mut rng = PathRng::new(5, Purpose::Test, 0, 0);
            let mut dir = DVec3::new(0.3, -0.5, 0.7).normalize();
            let mut worst = 0.0f64;
            for order in 1..=1_000_000u32 {
                let d = phase.sample(rng.uniform());
                let (cos_phi, sin_phi) = warp::azimuth_i32(|| rng.pair_i32());
                dir = scatter_direction(dir, d, cos_phi, sin_phi).0;
                if order % RENORMALISE_EVERY == 0 {
                    dir = renormalise(dir);
                }
                worst = worst.max((dir.length_squared() - 1.0).abs());
            }
            assert!(worst < 1e-14, "g = {g}: ||dir|² − 1| reached {worst:e}");
        }
    }
}
