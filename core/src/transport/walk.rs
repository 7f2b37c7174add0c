//! The random walk of one path: the physics alone, generic over the estimator that scores it.
//!
//! [`walk`] flies a path through the layers (homogeneous flights inline, tracked media through
//! [`free_flight`]), meets their interfaces (Fresnel's choice, total internal reflection), the box
//! phantom's side faces, the depth and time gates, and at every real collision hands the path to its
//! estimator; [`walk_to_the_end`] takes it across rough faces ([`cross_rough_face`]) and off opaque
//! surfaces ([`reflect_at_surface`]) until it ends. What is scored, and where, is the estimator's:
//! a type implementing [`Estimator`], whose hooks the walk calls at a collision, a smooth face, a
//! rough face and an opaque surface, and whose associated consts say what the path must track
//! (the Doppler term, the optical path length, the time gate, a box phantom's faces, the volume
//! tally), and whose values hold what the estimator carries along the path. The walk is
//! monomorphised per estimator type, so a scene in which nothing moves never looks up a velocity and one without a chirp never
//! tracks the path length. The estimators, a file each:
//!
//! | estimator | file | hooks it fills |
//! |---|---|---|
//! | forward packets (escapes, next-event estimation, unscattered reflections, the volume tally) | [`super::forward`] | collision, rough face, surface |
//! | adjoint camera paths (beam, beam-lobe and face-lobe connections) | [`super::adjoint`] | collision, refraction, rough face, surface |
//! | the layered twin of the control variate (rides on forward paths, in their state) | [`super::twin`] | flights through regions, solids, its part of a collision (called by the forward estimator), its own walk |
//! | steering: weight windows and the guide | [`super::steering`] | the end of a forward collision |
//!
//! Forward transport is packet tracing with absorption weighting and Russian roulette, as MCML
//! (Wang, Jacques & Zheng 1995): the quantities asked for are boundary fluxes of a forward problem
//! with a collimated source, which packet tracing scores exactly where the packet leaves.

use glam::DVec3;

use crate::detect::volume::VolumeTally;
use crate::detect::{PathState, Recorder, Shot, Side};
use crate::medium::{Medium, Scene};
use crate::sampling::PathRng;
use crate::source::Source;

use super::event::{Particle, RENORMALISE_EVERY, doppler_increment, renormalise};
use super::fresnel;
use super::nee::NeeTarget;
use super::policy::WalkSettings;
use super::tracking::{Flight, LayerRay, Tracking, free_flight, free_flight_to};

/// What every path of a run walks through: the scene, the source, the walk's knobs and the
/// detectors scored by next-event estimation (empty: none; the forward estimator is then compiled
/// without shadow rays, `NEE = false`). A camera path ([`super::adjoint::trace_camera_path`]) also
/// carries its pixel (`shot`; `None` for forward paths). `volume`: the voxel grid forward paths
/// score into (`[volume]`; read only by the estimators compiled with `VOLUME = true`).
#[derive(Debug, Clone, Copy)]
pub struct WalkContext<'a> {
    pub scene: &'a Scene,
    pub source: &'a Source,
    pub settings: &'a WalkSettings,
    pub nee: &'a [NeeTarget],
    pub shot: Option<Shot>,
    pub volume: Option<VolumeTally<'a>>,
    /// Forward paths score their unscattered reflections at the interfaces below the surface
    /// deterministically ([`super::forward::unscattered_reflections`]): `run.reflections = "deterministic"` (or
    /// `"auto"` where they pay), a forward-estimated top detector to see them, an interface with a
    /// change of index below the surface, and no box phantom
    /// ([`super::policy::deterministic_reflections`]).
    pub reflections: bool,
    /// Forward paths carry their layered twin for the control variate of the cameras that have
    /// one (`run.control_variate`, [`crate::detect::twin`]): the likelihood ratio `Λ` of the
    /// path under the twin (each flight through a region: the twin's transmittance over the
    /// path's) until the twin parts from it at the path's first collision in a region
    /// ([`super::carried::Split`]), in the forward estimator's state ([`super::forward::Forward`]).
    pub twin: bool,
    /// The twin's scene (the regions removed), where a twin walks on once it parts from its path
    /// ([`super::carried::Split`]); `None` without a control variate.
    pub twin_scene: Option<&'a Scene>,
    /// Forward paths start near the regions ([`crate::source::Launches`]; `None`: from the
    /// profile).
    pub launches: Option<&'a crate::source::Launches>,
    /// The weight windows of `run.importance = "windows"` ([`super::windows`]; `None`: none, and
    /// in a twin's own walk).
    pub windows: Option<&'a super::windows::Windows>,
    /// The layered twin's light field camera paths connect to below the regions
    /// (`[detectors.footprints] light_field`, [`super::field`]; `None`: none, and in a twin's own
    /// walk).
    pub field: Option<&'a super::field::FieldTable>,
}

/// A real collision as the walk hands it to [`Estimator::collide`]: the medium collided in, its
/// albedo there, the refractive index `n` of the layer and the layer.
#[derive(Debug, Clone, Copy)]
pub(super) struct Vertex<'a> {
    pub medium: &'a Medium,
    pub albedo: f64,
    pub n: f64,
    pub li: usize,
}

/// What scores a path, and what the path must track for it: the walk ([`walk_to_the_end`]) is
/// generic over one such type and calls its hooks at the path's events, monomorphised per type (as
/// pbrt-v4's `SampleT_maj` takes its integrator's callback). The consts are folded at compile time:
/// a walk that does not track the optical path length carries none of its arithmetic. A value of
/// the type is the estimator's state along the path it scores (the forward estimator's layered
/// twin and weight-window copies, a camera path's balance against its connections); the walk
/// holds it by reference and hands it to every hook.
///
/// A new estimator is a type implementing this trait in a file of its own, plus its entry (how
/// its paths start and end) and one arm in [`super::features`] that picks it.
pub(super) trait Estimator {
    /// Something moves: the Doppler term at every scattering event and moving surface.
    const DOPPLER: bool;
    /// The optical path length is tracked (a chirp, range gates, a time axis, a time gate).
    const LENGTH: bool;
    /// The time gate `WalkSettings::gate` cuts the path (only with `LENGTH`).
    const GATE: bool;
    /// The layers end at the side faces of a box phantom (`Scene::lateral`).
    const LATERAL: bool;
    /// The volume tally (`[volume]`) scores the path's track lengths and collisions.
    const VOLUME: bool;

    /// A real collision `v` at distance `t` along `s` (the path not yet moved there): the
    /// absorption weighting, the estimator's connections, a new direction, the Doppler term, the
    /// event cap and Russian roulette ([`end_of_event`]). `Some` if the path ends here.
    #[allow(clippy::too_many_arguments)]
    fn collide(
        &mut self,
        ctx: &WalkContext,
        s: &mut PathState,
        t: f64,
        v: Vertex,
        rng: &mut PathRng,
        absorbed: &mut f64,
        checkpoint: &mut u32,
        rec: &mut Recorder,
    ) -> Option<End>;

    /// The straight piece of `s` of length `t` in a layer of index `n` (to a collision, a face,
    /// depth), flown with the path's weight: the volume tally's track length.
    #[inline(always)]
    fn track(&self, _ctx: &WalkContext, _rec: &mut Recorder, _s: &PathState, _t: f64, _n: f64) {}

    /// A flight of `s` along `ray` in layer `li` up to `t_end` that the estimator flies itself
    /// (the path with its layered twin through density regions, [`super::twin`]); `None`: the
    /// walk's own flight.
    #[inline(always)]
    fn own_flight(
        &mut self,
        _ray: &LayerRay,
        _t_end: f64,
        _li: usize,
        _s: &PathState,
        _rng: &mut PathRng,
        _null_collisions: &mut u64,
    ) -> Option<Flight> {
        None
    }

    /// The walk's own flight of `s` through `layer`, which holds regions, went `t`.
    #[inline(always)]
    fn flew(&mut self, _scene: &Scene, _layer: &crate::medium::Layer, _s: &PathState, _t: f64) {}

    /// `s` in layer `li` has flown to an opaque solid's boundary (where it now is).
    #[inline(always)]
    fn at_solid(&mut self, _s: &PathState, _li: usize, _rng: &PathRng) {}

    /// `s` has just refracted from index `n` into `n2` through a smooth face of reflectance `r`.
    #[inline(always)]
    fn refracted(&mut self, _s: &mut PathState, _n: f64, _n2: f64, _r: f64) {}

    /// The path has just been reflected by a smooth face (by Fresnel's draw, or totally): no
    /// connection of an estimator's takes that way, so its balance against them ends.
    #[inline(always)]
    fn mirrored(&mut self) {}

    /// `s` is at the rough top face of layer `face`, about to cross it: the connections from there.
    #[inline(always)]
    fn at_rough_face(
        &mut self,
        _ctx: &WalkContext,
        _face: usize,
        _s: &PathState,
        _at: &RoughFace,
        _rng: &mut PathRng,
        _rec: &mut Recorder,
    ) {
    }

    /// The factor on the path's weight of a crossing of weight `w` (`G1`), `transmitted` from
    /// index `n_i` into `n_t` or reflected: `w` for a path carrying power.
    #[inline(always)]
    fn crossing_weight(w: f64, _transmitted: bool, _n_i: f64, _n_t: f64) -> f64 {
        w
    }

    /// `s` has crossed the rough face `at` as `c` drew it (its new direction set).
    #[inline(always)]
    fn crossed(&mut self, _s: &mut PathState, _at: &RoughFace, _c: &crate::surface::Crossed) {}

    /// `s` is at the opaque surface `hit`, about to reflect: the connections from there.
    #[inline(always)]
    fn at_surface(
        &mut self,
        _ctx: &WalkContext,
        _hit: &SurfaceHit,
        _s: &PathState,
        _rng: &mut PathRng,
        _rec: &mut Recorder,
    ) {
    }

    /// `s` has reflected at `hit` toward `out`, as `smp` drew it (its weight taken, its direction
    /// not yet turned).
    #[inline(always)]
    fn reflected(
        &mut self,
        _ctx: &WalkContext,
        _hit: &SurfaceHit,
        _s: &mut PathState,
        _smp: &crate::surface::Sampled,
        _out: DVec3,
    ) {
    }
}

/// Reflections at interfaces without a real collision in between after which a path is
/// truncated (counted in `truncated_paths`). Only total internal reflection repeats: a scattering
/// region in a clear layer of higher index than both neighbours sends some packets along the
/// layer at grazing angles, reflected between its faces for ever (issue 21: a run that never
/// ended). A partial reflection (R < 1) repeats 10⁴ times with probability `R^10⁴`.
pub const MAX_REFLECTIONS_WITHOUT_COLLISION: u32 = 10_000;

/// How a walk ended; the estimator's entry records it ([`super::forward::trace_path`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum End {
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

/// The random walk of `s` from the top surface (`start = 0`), or from inside layer `start` (a
/// layered twin parting from its path there), until it ends; the weight deposited by
/// absorption is added to `absorbed`. Every real collision is the estimator's ([`Estimator::collide`]).
///
/// The loop is nested: the outer one runs once per visit of a layer and reads what the event
/// loop needs from the layer and its filling medium (bounds, index, `1/σt`, the medium itself)
/// once, the inner one runs once per event. In a layer without regions the free flight is
/// sampled right here, so the collision's medium is the hoisted one (no index, no bounds
/// check, no [`Flight`] value in between); layers with regions go through [`free_flight`].
///
/// Every straight piece of the path inside the stack (to a collision, to an interface, to depth)
/// is handed to [`Estimator::track`] with the weight it is flown with (the volume tally's track
/// lengths), and with `E::VOLUME` every real collision's deposit and collision estimate before the
/// collision is handled ([`VolumeTally`]).
///
/// With `E::LATERAL` the layers end at the side faces of a box phantom (`Scene::lateral`): a
/// flight that would leave the box stops at the face ahead, where Fresnel's law against
/// `n_outside` reflects the path back in or lets it out (`End::Lateral`). Shadow rays and
/// camera paths are not run in a box (refused at resolve time).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn walk<E: Estimator>(
    est: &mut E,
    ctx: &WalkContext,
    start: usize,
    s: &mut PathState,
    rng: &mut PathRng,
    absorbed: &mut f64,
    null_collisions: &mut u64,
    rec: &mut Recorder,
) -> End {
    let WalkContext { scene, settings, .. } = *ctx;
    // The box's bounds (read only by the walk of a box phantom).
    let bounds = match scene.lateral {
        Some(b) if E::LATERAL => b,
        _ => crate::medium::Lateral { x: (0.0, 0.0), y: (0.0, 0.0), n_outside: 1.0 },
    };
    let mut li = start;
    let mut bounces = Bounces::new();
    // The next event count at which `end_of_event` looks at the event cap and renormalises.
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
                if E::LATERAL && !bounds.contains(s.pos.x + t * s.dir.x, s.pos.y + t * s.dir.y) {
                    break;
                }
                (t, fill, fill.albedo())
            } else {
                let (flight, t_opaque, opaque) = tracked_flight::<E>(est, ctx, li, s, &bounds, rng, null_collisions);
                match flight {
                    Flight::Collision { t, medium } => {
                        let m = &scene.media[medium];
                        (t, m, if albedo_grid { m.albedo_at(s.pos + t * s.dir) } else { m.albedo() })
                    }
                    // The flight ends at an opaque solid's boundary (before the plane and a side
                    // face): there the surface reflects it, outside the walk.
                    // (A flight to depth has t = ∞, and so has `t_opaque` without a solid ahead.)
                    Flight::Boundary { t } if t_opaque <= t && opaque != usize::MAX => {
                        return to_solid::<E>(est, ctx, s, (t, n, li), opaque, rng, rec);
                    }
                    Flight::Boundary { .. } => break,
                }
            };
            let mut before_gate = false;
            if E::GATE
                && let Some((l0, l1)) = settings.gate
            {
                // The collision happens at `l`: after the gate the path ends unrecorded (its
                // track scored up to `l1`); before it the deposit the collision will add is taken
                // back out of the absorbed weight (and the volume tally's).
                let l = s.l + n * t;
                if l > l1 {
                    est.track(ctx, rec, s, t, n);
                    return End::Gated;
                }
                if l < l0 {
                    *absorbed -= s.weight * (1.0 - albedo);
                    before_gate = true;
                }
            }
            if E::VOLUME
                && let Some(v) = ctx.volume
            {
                let p = s.pos + t * s.dir;
                est.track(ctx, rec, s, t, n);
                if !before_gate {
                    v.collision(rec.acc, p, s.l + n * t, s.weight, albedo, medium.sigma_t_at(p));
                }
            }
            if let Some(end) =
                est.collide(ctx, s, t, Vertex { medium, albedo, n, li }, rng, absorbed, &mut checkpoint, rec)
            {
                return end;
            }
        }

        // Reached the boundary plane ahead: the bottom one going down, else the top one. The
        // distance is the one `free_flight` reports, `|Δz| / |dir.z|` (signs cancel exactly);
        // a horizontal ray gets ±∞ or NaN and is truncated.
        let down = s.dir.z > 0.0;
        let (plane, next) = if down { (z_bottom, li + 1) } else { (z_top, li.wrapping_sub(1)) };
        let t_boundary = (plane - s.pos.z) / s.dir.z;
        if E::LATERAL {
            let (t_side, axis) = bounds.exit(s.pos, s.dir);
            // The side face comes first, or the ray is horizontal (`t_boundary` −∞ or NaN; +∞
            // is a way to depth, taken unless a face comes first).
            if t_side < t_boundary || t_boundary.is_nan() || t_boundary < 0.0 {
                if let Some(end) = side_face::<E>(est, ctx, s, t_side, axis, n, bounds, rng, rec) {
                    return end;
                }
                if bounces.trapped(s.order) {
                    return End::Truncated;
                }
                continue;
            }
        }
        // To depth (t = ∞) the track is clipped to the grid's box (and to the gate's end).
        est.track(ctx, rec, s, if t_boundary.is_finite() { t_boundary } else { f64::INFINITY }, n);
        if E::GATE && past_gate(settings, s.l + n * t_boundary) {
            return End::Gated;
        }
        if !t_boundary.is_finite() {
            // Only a semi-infinite last layer lets a path go to depth; an overflow towards a
            // finite plane (|dir.z| of order 1e-308) is a ray that never arrives.
            return if down && z_bottom == f64::INFINITY { End::ToDepth } else { End::Truncated };
        }
        if E::LENGTH {
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
            && (if down { beyond.is_some_and(|l| l.face.is_rough()) } else { layer.face.is_rough() })
        {
            return End::AtRough(if down { next } else { li });
        }
        let (r, cos_t) = fresnel::reflectance(n, n2, s.dir.z.abs());
        if r > 0.0 && (r >= 1.0 || rng.uniform() < r) {
            if bounces.trapped(s.order) {
                return End::Truncated;
            }
            s.dir.z = -s.dir.z;
            est.mirrored();
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
            let reflected_once = s.order == 0 && bounces.count == 1;
            return End::Escaped { side, n_ambient: n2, reflected_once };
        }
        est.refracted(s, n, n2, r);
        li = next;
    }
}

/// A flight of `s` through layer `li` that is not sampled inline (regions, density media, opaque
/// solids, a box phantom's side faces): to the first real collision, or to the nearest of the
/// plane ahead, a side face and the first opaque solid ahead, whose distance and index it also
/// returns (`∞` and `usize::MAX` without one). The estimator may fly it itself
/// ([`Estimator::own_flight`]: a path with its layered twin through density regions), and hears of
/// the walk's own flights through regions ([`Estimator::flew`]).
#[inline(always)]
fn tracked_flight<E: Estimator>(
    est: &mut E,
    ctx: &WalkContext,
    li: usize,
    s: &PathState,
    bounds: &crate::medium::Lateral,
    rng: &mut PathRng,
    null_collisions: &mut u64,
) -> (Flight, f64, usize) {
    let WalkContext { scene, settings, .. } = *ctx;
    let layer = &scene.layers[li];
    // Distance along z to the boundary plane ahead (either one for a horizontal ray).
    let dz = if s.dir.z >= 0.0 { layer.z_bottom - s.pos.z } else { s.pos.z - layer.z_top };
    let (t_opaque, opaque) =
        if layer.opaque.is_empty() { (f64::INFINITY, usize::MAX) } else { scene.first_opaque(layer, s.pos, s.dir) };
    let ray = LayerRay { scene, layer, pos: s.pos, dir: s.dir };
    let flight = if E::LATERAL {
        // The nearer of the plane ahead and the side face ahead (`min` takes the face for a
        // horizontal ray, whose distance to the plane is ∞ or NaN).
        let t_end = bounds.exit(s.pos, s.dir).0.min(dz / s.dir.z.abs()).min(t_opaque);
        free_flight_to(ray, t_end, settings.tracking, rng, null_collisions)
    } else if let Some(f) = est.own_flight(&ray, (dz / s.dir.z.abs()).min(t_opaque), li, s, rng, null_collisions) {
        return (f, t_opaque, opaque);
    } else if t_opaque < f64::INFINITY {
        free_flight_to(ray, (dz / s.dir.z.abs()).min(t_opaque), settings.tracking, rng, null_collisions)
    } else {
        free_flight(ray, dz, s.dir.z.abs(), settings.tracking, rng, null_collisions)
    };
    if !layer.regions.is_empty() {
        let (Flight::Collision { t, .. } | Flight::Boundary { t }) = flight;
        est.flew(scene, layer, s, t);
    }
    (flight, t_opaque, opaque)
}

/// A path's walk from layer `start` to its end, with its crossings of rough faces
/// ([`cross_rough_face`]) and its reflections at opaque surfaces (under the stack, or an opaque
/// solid's in a layer; [`reflect_at_surface`]) in between: the walk stops there and starts again
/// in the layer the path goes on in. `entering`: the path is at the stack's rough top face.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn walk_to_the_end<E: Estimator>(
    est: &mut E,
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
    let mut crossings = Bounces::new();
    // Entering through a rough top surface: the walk starts below its face. (One call of the
    // walk, which is inlined, and its end straight from it: a second call site doubled its code,
    // and an end that could also come from here was kept in memory and dispatched there, +12
    // instructions per path on the vdH slab.)
    if entering {
        let (deposit, next) = cross_rough_face::<E>(est, ctx, 0, s, rng, rec);
        *absorbed += deposit;
        match next {
            Ok(l) => li = l,
            Err(end) => return end,
        }
    }
    loop {
        let end = walk::<E>(est, ctx, li, s, rng, absorbed, null_collisions, rec);
        // (The deposits come back by value: `absorbed`'s address handed to a call kept it in
        // memory through every collision of the walk, +1 instruction each.)
        let (deposit, ended) = match end {
            End::AtRough(face) => {
                if crossings.trapped(s.order) {
                    return End::Truncated;
                }
                match cross_rough_face::<E>(est, ctx, face, s, rng, rec) {
                    (deposit, Ok(l)) => {
                        li = l;
                        (deposit, None)
                    }
                    (deposit, Err(end)) => (deposit, Some(end)),
                }
            }
            End::AtBottom => {
                let Some(bottom) = &scene.bottom else { return end };
                li = scene.layers.len() - 1;
                let frame = crate::medium::Surface::bottom_frame();
                reflect_at_surface::<E>(est, ctx, bottom, &frame, li, s, rng, rec)
            }
            End::AtOpaque(k) => {
                let o = &scene.opaque[k];
                li = o.layer;
                let frame = crate::surface::Frame::new(o.shape.outward_normal(s.pos, -s.dir));
                reflect_at_surface::<E>(est, ctx, &o.surface, &frame, li, s, rng, rec)
            }
            _ => return end,
        };
        *absorbed += deposit;
        if let Some(end) = ended {
            return end;
        }
    }
}

/// The path `s` reaches the rough top face of layer `face` at `s.pos`: the estimator's
/// connections from the face ([`Estimator::at_rough_face`]), then a reflection or refraction
/// drawn from the layer's face model ([`crate::surface::RoughDielectric`]: visible normals, each
/// with its Fresnel reflectance), whose weight `G1` multiplies the path's (the masked rest is
/// returned as absorbed; a path carrying radiance also takes `(n_i/n_t)²` through,
/// [`Estimator::crossing_weight`]). A face is no scattering event: the order stays. `Ok` the
/// layer the path goes on in, else how it ended (through the stack's top surface: an escape).
#[inline(never)]
fn cross_rough_face<E: Estimator>(
    est: &mut E,
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
    // The normal on the side the light comes from (up, the beam's side, as the bottom's frame).
    let frame = if down {
        crate::medium::Surface::bottom_frame()
    } else {
        crate::surface::Frame { n: DVec3::Z, t: DVec3::X, b: DVec3::Y }
    };
    let interface = scene.layers[face].face;
    let wi = frame.to_local(-s.dir);
    debug_assert!(wi.z > 0.0, "a rough face met from behind: wi = {wi}");
    let at = RoughFace { interface, frame, wi, n_i, n_t };
    est.at_rough_face(ctx, face, s, &at, rng, rec);
    let u = [rng.uniform(), rng.uniform(), rng.uniform()];
    let Some(c) = interface.sample(wi, n_i, n_t, u) else {
        return (s.weight, Err(End::Absorbed));
    };
    debug_assert!((0.0..=1.0).contains(&c.weight), "a rough face's weight G1 = {} outside 0…1", c.weight);
    let deposit = s.weight * (1.0 - c.weight);
    s.weight *= E::crossing_weight(c.weight, c.transmitted, n_i, n_t);
    if s.weight <= 0.0 {
        return (deposit, Err(End::Absorbed));
    }
    s.dir = frame.to_world(c.wo);
    est.crossed(s, &at, &c);
    if s.dir.z > 0.0 {
        (deposit, Ok(face))
    } else if face > 0 {
        (deposit, Ok(face - 1))
    } else {
        (deposit, Err(End::Escaped { side: Side::Top, n_ambient: scene.n_above, reflected_once: false }))
    }
}

/// A rough face as a path meets it: the face's model, its frame on the side the path comes from
/// (normal toward it), the path's reversed direction in that frame, and the indices on the path's
/// side (`n_i`) and beyond (`n_t`).
#[derive(Debug, Clone, Copy)]
pub(super) struct RoughFace {
    pub interface: crate::surface::Interface,
    pub frame: crate::surface::Frame,
    pub wi: DVec3,
    pub n_i: f64,
    pub n_t: f64,
}

/// An opaque surface as a path in layer `li` meets it: the surface, its local frame (its normal
/// pointing into the layer), the path's reversed direction in that frame, and, if it moves, its
/// velocity at the point (`moving` only where the walk tracks the Doppler term).
#[derive(Debug, Clone, Copy)]
pub(super) struct SurfaceHit<'a> {
    pub surface: &'a crate::medium::Surface,
    pub frame: &'a crate::surface::Frame,
    pub wi: DVec3,
    pub li: usize,
    pub moving: bool,
    pub v: DVec3,
}

/// The path `s` in layer `li` reaches an opaque surface of local frame `frame` (its normal
/// pointing into the layer) at `s.pos`: the estimator's connections from it
/// ([`Estimator::at_surface`]; a camera path's reflection carries radiance as it carries power,
/// the BSDFs being reciprocal), then a direction from the BSDF, whose weight multiplies the
/// path's (the rest is absorbed by the surface: returned, to be counted with the absorbed power,
/// as is a rough surface's masked share), and the surface's Doppler term. A reflection is a
/// scattering event: one more order, the event cap and Russian roulette. `Some` end if the path
/// ends here.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn reflect_at_surface<E: Estimator>(
    est: &mut E,
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
    let moving = E::DOPPLER && surface.is_moving();
    let v = if moving { surface.velocity_at(s.pos) } else { DVec3::ZERO };
    let hit = SurfaceHit { surface, frame, wi, li, moving, v };
    est.at_surface(ctx, &hit, s, rng, rec);
    let u = [rng.uniform(), rng.uniform(), rng.uniform()];
    let Some(smp) = surface.bsdf.sample(wi, u) else {
        return (s.weight, Some(End::Absorbed));
    };
    debug_assert!(smp.weight.is_finite() && smp.weight >= 0.0, "a BSDF's weight {}", smp.weight);
    let out = frame.to_world(smp.wo);
    let deposit = s.weight * (1.0 - smp.weight);
    s.weight *= smp.weight;
    if s.weight <= 0.0 {
        return (deposit, Some(End::Absorbed));
    }
    est.reflected(ctx, &hit, s, &smp, out);
    if moving {
        s.dldt += doppler_increment(n, v, s.dir - out);
        s.doppler_events += 1;
    }
    // The walk's next checkpoint is due at once (it renormalises and looks at the event cap).
    let mut checkpoint = s.order.min(ctx.settings.max_events);
    (deposit, turn(s, out, ctx.settings, rng, &mut checkpoint))
}

/// The path `s` in a layer of index `n` reaches the side face `axis` (0: x, 1: y) of the box
/// `b`, `t` away: the gate, the volume tally's track, then Fresnel against `b.n_outside` at
/// incidence `|dir·normal|` (unpolarised, as at the layer interfaces). `None`: reflected back in
/// (the normal component of `dir` reversed); else how the path ended.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn side_face<E: Estimator>(
    est: &mut E,
    ctx: &WalkContext,
    s: &mut PathState,
    t: f64,
    axis: usize,
    n: f64,
    b: crate::medium::Lateral,
    rng: &mut PathRng,
    rec: &mut Recorder,
) -> Option<End> {
    // Clipped to the gate's end if the path ends there.
    est.track(ctx, rec, s, t, n);
    if E::GATE && past_gate(ctx.settings, s.l + n * t) {
        return Some(End::Gated);
    }
    if !t.is_finite() {
        return Some(End::Truncated);
    }
    advance::<E>(s, t, n);
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

/// Reflections at faces since the path's last real collision (counted at the face, so that a
/// collision costs nothing): only total internal reflection keeps a path bouncing that long.
#[derive(Debug, Clone, Copy)]
struct Bounces {
    /// The scattering order they were counted at.
    order: u32,
    count: u32,
}

impl Bounces {
    #[inline(always)]
    fn new() -> Self {
        Bounces { order: u32::MAX, count: 0 }
    }

    /// One more at scattering order `order`: whether the path is trapped
    /// ([`MAX_REFLECTIONS_WITHOUT_COLLISION`]).
    #[inline(always)]
    fn trapped(&mut self, order: u32) -> bool {
        if order != self.order {
            (self.order, self.count) = (order, 0);
        }
        self.count += 1;
        self.count > MAX_REFLECTIONS_WITHOUT_COLLISION
    }
}

/// The path's flight of `t` in layer `li` of index `n` ends at the boundary of the opaque solid
/// `k` (before the plane and a side face): its track, the gate, and there the surface reflects
/// it, outside the walk. The layered twin, which has no solids, parts from the path here.
#[inline(always)]
fn to_solid<E: Estimator>(
    est: &mut E,
    ctx: &WalkContext,
    s: &mut PathState,
    (t, n, li): (f64, f64, usize),
    k: usize,
    rng: &PathRng,
    rec: &mut Recorder,
) -> End {
    est.track(ctx, rec, s, t, n);
    if E::GATE && past_gate(ctx.settings, s.l + n * t) {
        return End::Gated;
    }
    advance::<E>(s, t, n);
    est.at_solid(s, li, rng);
    End::AtOpaque(k)
}

/// The path flies `t` straight on in a layer of index `n`.
#[inline(always)]
pub(super) fn advance<E: Estimator>(s: &mut PathState, t: f64, n: f64) {
    s.pos += t * s.dir;
    if E::LENGTH {
        s.l += n * t;
    }
}

/// Whether optical path length `l` is past the end of the time gate.
#[inline(always)]
fn past_gate(settings: &WalkSettings, l: f64) -> bool {
    matches!(settings.gate, Some((_, l1)) if l > l1)
}

/// Whether a path recorded at optical path length `l` is inside the time gate (always in walks
/// compiled without one, `GATE = false`).
#[inline(always)]
pub(super) fn in_gate<const GATE: bool>(settings: &WalkSettings, l: f64) -> bool {
    match settings.gate {
        Some((l0, l1)) if GATE => l0 <= l && l <= l1,
        _ => true,
    }
}

/// Absorption weighting: deposit `(1 − albedo)` of the weight, carry on with the rest. `true` if
/// no weight is left.
#[inline(always)]
pub(super) fn absorb(s: &mut PathState, albedo: f64, absorbed: &mut f64) -> bool {
    *absorbed += s.weight * (1.0 - albedo);
    s.weight *= albedo;
    s.weight <= 0.0
}

/// The tail of every real scattering event on the particle `p` in a layer of index `n`, once the
/// estimator has drawn the new direction `out` (`delta` = `dir − out`): the event's Doppler and
/// Brownian terms if the particle moves ([`Particle::event`]), then the turn ([`turn`]). The
/// forward and adjoint estimators' collisions all end here.
#[inline(always)]
pub(super) fn scatter(
    s: &mut PathState,
    p: Particle,
    n: f64,
    (out, delta): (DVec3, DVec3),
    settings: &WalkSettings,
    rng: &mut PathRng,
    checkpoint: &mut u32,
) -> Option<End> {
    p.event(s, n, delta);
    turn(s, out, settings, rng, checkpoint)
}

/// The path turns to `out` at a real collision: one more scattering order, then the end of the
/// event ([`end_of_event`]).
#[inline(always)]
pub(super) fn turn(
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

/// The end of every real collision: event cap, periodic renormalisation, Russian roulette.
#[inline(always)]
pub(super) fn end_of_event(
    s: &mut PathState,
    settings: &WalkSettings,
    rng: &mut PathRng,
    checkpoint: &mut u32,
) -> Option<End> {
    debug_assert!(s.weight >= 0.0 && s.weight.is_finite(), "a path's weight {} after an event", s.weight);
    debug_assert!((s.dir.length_squared() - 1.0).abs() < 1e-9, "a path's direction {} is not unit", s.dir);
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
