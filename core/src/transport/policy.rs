//! The run's policy for its walks: the walk's knobs (`WalkSettings`), how forward paths start
//! (`run.launches`), whether the layered control variate applies (`run.control_variate`) and how
//! the unscattered reflections are scored (`run.reflections`). Decided once per run, at resolve
//! time and before the batches; the walk ([`super::walk`]) only reads the outcome.

use glam::DVec3;

use crate::detect::Side;
use crate::medium::Scene;
use crate::source::Source;

use super::fresnel;
use super::tracking::Tracking;

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
    if scene.cycle.is_some() {
        return Some("the scene's flows pulse ([cardiac]): the twin does not carry the harmonics yet".into());
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

/// Whether forward paths in `scene` with `settings` and these `detectors` score their
/// unscattered reflections deterministically (see `WalkContext::reflections`).
pub fn deterministic_reflections(
    scene: &Scene,
    source: &Source,
    settings: &WalkSettings,
    detectors: &[crate::detect::Detector],
) -> bool {
    let seen = detectors.iter().any(|d| d.surface().is_some_and(|s| s.side == Side::Top && s.estimator().forward()));
    let mismatched = scene
        .layers
        .iter()
        .enumerate()
        .any(|(j, l)| l.z_bottom.is_finite() && l.n != scene.layers.get(j + 1).map_or(scene.n_below, |b| b.n));
    // (Opaque solids would shade the reflections' straight ways down and up, and a rough face
    // scatters them.)
    let smooth = scene.layers.iter().all(|l| !l.face.is_rough());
    let possible = seen && mismatched && scene.lateral.is_none() && scene.opaque.is_empty() && smooth;
    match settings.reflections {
        Reflections::Sampled => false,
        Reflections::Deterministic => possible,
        Reflections::Auto => possible && reflection_second_moment(scene, source) >= AUTO_REFLECTIONS,
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
