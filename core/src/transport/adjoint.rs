//! The adjoint estimator: camera paths from a pixel's point and cone, walked as forward paths run
//! backwards and carrying radiance, connected to the laser's beam at every vertex (the beam, beam-
//! lobe and face-lobe connections of [`super::camera`], which holds their geometry). Its hooks: a
//! real collision connects ([`collide_camera`]), a refraction scales the radiance by `(n/n₂)²`, the
//! stack's first rough face connects to the beam arriving through it, and an opaque surface's
//! reflection connects as a collision does ([`camera_surface_connection`]).

use glam::DVec3;

use crate::detect::{PathState, Recorder, Shot};
use crate::medium::Medium;
use crate::sampling::{PathRng, warp};

use super::camera::CameraTarget;
use super::event::{Particle, deflect, doppler_increment, scatter_direction};
use super::walk::{End, Estimator, RoughFace, SurfaceHit, Vertex, WalkContext, scatter, walk_to_the_end};

/// Camera paths through a scene where something moves (`DOPPLER`) and whose optical path length
/// is needed (`LENGTH`); its value is the path's [`Balance`] against its connections.
pub(super) struct Adjoint<const DOPPLER: bool, const LENGTH: bool, const FIELD: bool> {
    balance: Balance,
    /// With `FIELD`, where the path stands with the light field ([`super::field`]).
    field: FieldWalk,
}

/// A camera path's part in the light field's estimate ([`super::field`]).
#[derive(Clone)]
enum FieldWalk {
    /// Before it has met a region or gone below every region: a plain camera path (its light
    /// has not yet seen what the regions change).
    Before,
    /// From that collision (`j*`) on, its walk shared with the layered twin's: the connections
    /// score the scene's light minus the twin's. Holds where the next flight starts from.
    Shared(Option<Start>),
    /// Its flight from `Start` met a region: the path scores alone, and once it has ended the twin
    /// walks on from there by itself.
    Parted(Start),
    /// It has met a region (and its twin, if it had one, has parted and walked): the path scores
    /// alone, until its next collision in a layer's filling medium shares its walk with a new
    /// twin.
    Plain,
    /// The layered twin's own walk after it parted: its flight to its first collision, the
    /// connection there to the beam, and the light field's table for the rest (in the twin's
    /// scene the table is all the scattered light there is).
    Twin,
}

/// Where a flight starts: the path after its collision there, its generator, its layer and its
/// balance against the connections.
#[derive(Clone)]
struct Start {
    s: PathState,
    rng: PathRng,
    li: usize,
    balance: Balance,
}

/// What a camera path's next vertex is weighed against: the connection from an earlier vertex
/// that also reaches it, with the ratio of the walk's density of its way there (times the
/// Fresnel transmittances of the smooth faces crossed since, which that connection crosses
/// deterministically) to the connection's density. The balance heuristic then gives the vertex's
/// own connection the weight `ratio/(ratio + 1)`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Balance {
    /// No connection takes the path's way to its next vertex (its start, a smooth face's
    /// reflection, a rough face's crossing, a mirror): full weight.
    Full,
    /// Above the stack's first rough face: the beam-lobe connection of the vertex before
    /// (`super::camera`, "Two ways to the last vertex"), against the guide lobe's density.
    BeamLobe(f64),
    /// At or below the first rough face: the face-lobe connection of the vertex before
    /// ([`face_connection`]), which the face's own connection from below weighs against
    /// ([`face_mis`]).
    FaceLobe(f64),
}

impl Balance {
    /// The balance heuristic's weight of a vertex's connection when `ratio` is the one it is
    /// weighed against (else full).
    #[inline(always)]
    fn weight(ratio: Option<f64>) -> f64 {
        ratio.map_or(1.0, |q| q / (q + 1.0))
    }
}

impl<const DOPPLER: bool, const LENGTH: bool, const FIELD: bool> Estimator for Adjoint<DOPPLER, LENGTH, FIELD> {
    const DOPPLER: bool = DOPPLER;
    const LENGTH: bool = LENGTH;
    const GATE: bool = false;
    const LATERAL: bool = false;
    const VOLUME: bool = false;

    #[inline(always)]
    fn collide(
        &mut self,
        ctx: &WalkContext,
        s: &mut PathState,
        t: f64,
        v: Vertex,
        rng: &mut PathRng,
        _absorbed: &mut f64,
        checkpoint: &mut u32,
        rec: &mut Recorder,
    ) -> Option<End> {
        super::walk::advance::<Self>(s, t, v.n);
        // The twin that parted on the way here walks first; this collision may share the walk
        // with a new one.
        if FIELD && matches!(self.field, FieldWalk::Parted(_)) {
            if let FieldWalk::Parted(start) = std::mem::replace(&mut self.field, FieldWalk::Plain) {
                twin_walk::<DOPPLER, LENGTH>(ctx, start, rec);
            }
        }
        let end = collide_camera::<DOPPLER, LENGTH, FIELD>(
            ctx,
            v.li,
            s,
            &mut self.balance,
            &mut self.field,
            v.medium,
            v.albedo,
            v.n,
            rng,
            checkpoint,
            rec,
        );
        if FIELD
            && end.is_none()
            && let FieldWalk::Shared(start) = &mut self.field
        {
            *start = Some(Start { s: *s, rng: rng.clone(), li: v.li, balance: self.balance });
        }
        end
    }

    /// A flight shared with the layered twin that meets a region parts the two; a plain path's
    /// first such flight makes its next collision outside the regions share its walk.
    #[inline(always)]
    fn flew(&mut self, scene: &crate::medium::Scene, layer: &crate::medium::Layer, s: &PathState, t: f64) {
        if FIELD
            && let FieldWalk::Shared(start) = &mut self.field
            && super::nee::touches_region(scene, layer, s.pos, s.dir, t)
        {
            self.field = start.take().map_or(FieldWalk::Plain, FieldWalk::Parted);
        } else if FIELD
            && matches!(self.field, FieldWalk::Before)
            && super::nee::touches_region(scene, layer, s.pos, s.dir, t)
        {
            self.field = FieldWalk::Plain;
        }
    }

    /// Radiance across the interface: `L/n²` is invariant. The beam-lobe connection crosses it
    /// deterministically: its density ratio takes the transmittance.
    #[inline(always)]
    fn refracted(&mut self, s: &mut PathState, n: f64, n2: f64, r: f64) {
        s.weight *= (n / n2) * (n / n2);
        match &mut self.balance {
            Balance::BeamLobe(q) | Balance::FaceLobe(q) => *q *= 1.0 - r,
            Balance::Full => {}
        }
    }

    /// No connection takes a smooth face's reflection.
    #[inline(always)]
    fn mirrored(&mut self) {
        self.balance = Balance::Full;
    }

    /// The stack's first rough face is where the laser's beam stops being a Dirac direction, so
    /// there the path connects to it: the beam of irradiance `E` arriving from above along `b`
    /// leaves the face toward the camera path with the radiance `E·cos θ_b·F(−b → −dir)/|cos
    /// θ_out|`, `F` the face's power per steradian ([`crate::surface::Interface::eval`]: its
    /// reflection when the path came down, its transmission when it came up). Coming down, no
    /// other way reaches that light (the beam-lobe connection crosses no rough face): full
    /// weight; coming up, the vertex before also connected through the face's lobe
    /// ([`face_connection`]), and the two are balanced ([`Balance::FaceLobe`]).
    #[inline(always)]
    fn at_rough_face(
        &mut self,
        ctx: &WalkContext,
        face: usize,
        s: &PathState,
        at: &RoughFace,
        rng: &mut PathRng,
        rec: &mut Recorder,
    ) {
        let scene = ctx.scene;
        let Some(shot) = ctx.shot else { return };
        if face != scene.first_rough_face {
            return;
        }
        let (n_above, n_below) = (scene.n_above_layer(face), scene.layers[face].n);
        // The face's frame with its normal up, on the beam's side.
        let up = crate::medium::Surface::bottom_frame();
        let boost = super::nee::connection_roulette(scene, face, s, rng);
        rec.stats.work.camera_connections += 1;
        if boost > 0.0
            && let Some(b) = super::camera::beam_at_face(scene, ctx.source, face, s.pos, rng)
        {
            let (to_light, to_camera) = (up.to_local(-b.dir), up.to_local(-s.dir));
            let f = at.interface.eval(to_light, to_camera, n_above, n_below);
            if f > 0.0 {
                let radiance = b.irradiance * to_light.z * f / to_camera.z.abs();
                // From below, weighted against the face-lobe connection of the vertex before
                // ([`face_mis`]); from above no other way reaches it.
                let down = s.dir.z > 0.0;
                let against = match self.balance {
                    Balance::FaceLobe(q) if !down => Some(q),
                    _ => None,
                };
                let e = PathState {
                    dir: -s.dir,
                    weight: s.weight * Balance::weight(against) * boost * radiance * shot.scale,
                    l: if LENGTH { s.l + b.length } else { 0.0 },
                    ..*s
                };
                rec.camera(&shot, &e);
            }
        }
    }

    /// Carrying radiance: a refraction from `n_i` into `n_t` multiplies the weight by
    /// `(n_i/n_t)²` (`L/n²` is invariant, as across a smooth face).
    #[inline(always)]
    fn crossing_weight(w: f64, transmitted: bool, n_i: f64, n_t: f64) -> f64 {
        if transmitted { w * (n_i / n_t) * (n_i / n_t) } else { w }
    }

    /// The next vertex is no beam-lobe connection's (none crosses a rough face): full weight.
    #[inline(always)]
    fn crossed(&mut self, _s: &mut PathState, _at: &RoughFace, _c: &crate::surface::Crossed) {
        self.balance = Balance::Full;
    }

    #[inline(always)]
    fn at_surface(
        &mut self,
        ctx: &WalkContext,
        hit: &SurfaceHit,
        s: &PathState,
        rng: &mut PathRng,
        rec: &mut Recorder,
    ) {
        let SurfaceHit { surface, frame, wi, li, moving, v } = *hit;
        camera_surface_connection::<LENGTH>(ctx, surface, frame, wi, li, s, (moving, v), rng, rec);
    }

    /// Below the first rough face, against the face-lobe connection ([`face_mis`]).
    #[inline(always)]
    fn reflected(
        &mut self,
        ctx: &WalkContext,
        hit: &SurfaceHit,
        _s: &mut PathState,
        smp: &crate::surface::Sampled,
        out: DVec3,
    ) {
        let beyond = hit.li >= ctx.scene.first_rough_face && !smp.delta;
        self.balance =
            if beyond { face_mis(ctx, hit.li, out, hit.surface.bsdf.pdf(hit.wi, smp.wo)) } else { Balance::Full };
    }
}

/// Trace one camera path of pixel `pixel` of `cam` ([`super::camera`]), recording its
/// connections to the laser into `rec` with the tally weight `batch_weight` per path.
pub(super) fn trace_camera_path<const DOPPLER: bool, const LENGTH: bool, const FIELD: bool>(
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
    let mut est = Adjoint::<DOPPLER, LENGTH, FIELD> { balance: Balance::Full, field: FieldWalk::Before };
    let end = walk_to_the_end(
        &mut est,
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
    if FIELD && let FieldWalk::Parted(start) = est.field {
        twin_walk::<DOPPLER, LENGTH>(&ctx, start, rec);
    }
}

/// The layered twin's own walk from where it parted from its camera path ([`FieldWalk::Parted`]),
/// in the twin's scene with the path's generator as it was there, every connection scored with
/// the opposite sign.
#[cold]
#[inline(never)]
fn twin_walk<const DOPPLER: bool, const LENGTH: bool>(ctx: &WalkContext, start: Start, rec: &mut Recorder) {
    let (Some(scene), Some(shot)) = (ctx.twin_scene, ctx.shot) else { return };
    let ctx = WalkContext { scene, shot: Some(Shot { scale: -shot.scale, ..shot }), ..*ctx };
    let Start { mut s, mut rng, li, balance } = start;
    let mut est = Adjoint::<DOPPLER, LENGTH, true> { balance, field: FieldWalk::Twin };
    let (mut absorbed, mut null_collisions) = (0.0, 0);
    let before = s.order;
    let end = walk_to_the_end(&mut est, &ctx, li, &mut s, &mut rng, &mut absorbed, &mut null_collisions, rec, false);
    rec.stats.work.camera_events += u64::from(s.order - before) + u64::from(end == End::Absorbed) + null_collisions;
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
        ..*s
    };
    mark(&mut e, -h.dir);
    rec.camera(shot, &e);
}

/// A camera path's [`Balance`] after a vertex in layer `li` (at or below the stack's first rough
/// face) sent it along `out` with the density `q`: `q/q_lobe`, the ratio of its density to the
/// face-lobe connection's ([`super::camera::face_lobe_density`]), which the crossings of smooth
/// faces on the way multiply by their transmittances and the rough face's connection from below
/// turns into its weight; full where no face-lobe connection takes that way. (The
/// density is evaluated in here: a phase function's evaluation added to `collide_camera` made
/// the compiler outline it from there, +1 % of the camera walk's instructions.)
#[cold]
#[inline(never)]
fn face_mis(ctx: &WalkContext, li: usize, out: DVec3, q: f64) -> Balance {
    let lobe = super::camera::face_lobe_density(ctx.scene, ctx.source, li, out);
    if lobe > 0.0 { Balance::FaceLobe(q / lobe) } else { Balance::Full }
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
pub(super) fn camera_surface_connection<const LENGTH: bool>(
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
    let boost = super::nee::connection_roulette(scene, li, s, rng);
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
                ..*s
            };
            mark(&mut e, b.dir);
            rec.camera(&shot, &e);
        }
    }
}

/// A real collision of a camera path at `s.pos`: the absorption weighting, the connection to the
/// laser scored into the path's pixel, the beam-lobe connection through a vertex further up, then
/// a new direction as [`collide`] (see [`super::camera`], "Two ways to the last vertex"). One
/// particle velocity serves the connections and the continuation. With the light field
/// (`FIELD`, [`super::field`]) the first collision below every region in a layer's filling medium
/// also connects to the field's table, and from there on the connections score the scene's light
/// minus its layered twin's.
//
// Outlined, as `collide_nee`: the connections are traces through every layer above.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn collide_camera<const DOPPLER: bool, const LENGTH: bool, const FIELD: bool>(
    ctx: &WalkContext,
    li: usize,
    s: &mut PathState,
    balance: &mut Balance,
    field: &mut FieldWalk,
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
        return collide_camera_beyond::<DOPPLER, LENGTH>(ctx, li, s, balance, m, n, rng, checkpoint, rec);
    }
    let particle = Particle::pick::<DOPPLER>(m, s.pos, rng);
    let pop = particle.pop;
    // The beam reaches the vertex through at least the same optical depth as a shadow ray.
    let boost = super::nee::connection_roulette(scene, li, s, rng);
    // The guide lobe about the beam's reversed direction in this layer.
    let guide = super::camera::guide();
    let up = super::camera::refracted_down(ctx.source.direction, scene.n_above, n).map(|b| -b);
    // With the light field: shared with the twin from before, or from here (`j*`).
    let shared = FIELD && matches!(field, FieldWalk::Shared(_));
    let switch = FIELD
        && match field {
            FieldWalk::Before => switches_here(ctx, li, s.pos, m),
            FieldWalk::Plain => ctx.field.is_some() && in_fill(ctx, li, m),
            _ => false,
        };
    if FIELD && matches!(field, FieldWalk::Twin) {
        return twin_collision::<DOPPLER, LENGTH>(ctx, li, s, *balance, particle, boost, n, rng, rec);
    }
    if let (Some(shot), true) = (ctx.shot, boost > 0.0) {
        // This vertex as the walk's last: weighted against the lobe connection from the vertex
        // before, [`Balance::BeamLobe`] = (walk density · Fresnel transmittances)/(guide density)
        // of the way here (full when the lobe connection cannot make it).
        let w = Balance::weight(match *balance {
            Balance::BeamLobe(q) => Some(q),
            _ => None,
        });
        let here = Link { pos: s.pos, dir_in: s.dir, particle, n };
        let tail = *s;
        rec.stats.work.camera_connections += 1;
        if shared {
            connect::<LENGTH, true>(ctx, li, &shot, here, tail, s.weight * w * boost, rng, rec);
        } else {
            connect::<LENGTH, false>(ctx, li, &shot, here, tail, s.weight * w * boost, rng, rec);
        }
        // The beam-lobe connection: a direction from the guide lobe, the straight refracted way
        // through the layers to a real collision there, and its connection.
        if let Some(up) = up {
            let dd = guide.sample(rng.uniform());
            let (cos_phi, sin_phi) = warp::azimuth_i32(|| rng.pair_i32());
            let (dir, _) = scatter_direction(up, dd, cos_phi, sin_phi);
            let lobe = Lobe {
                li,
                pos: s.pos,
                dir,
                tail,
                delta: s.dir - dir,
                particle,
                n,
                p_walk: pop.phase.eval(s.dir.dot(dir)),
                p_guide: guide.eval(dd.cos),
                w: s.weight * boost,
            };
            if shared || switch {
                lobe_pair::<DOPPLER, LENGTH>(ctx, &shot, lobe, rng, rec);
            } else {
                lobe_connection::<DOPPLER, LENGTH>(ctx, &shot, lobe, rng, rec);
            }
        }
    }
    if switch {
        if let (Some(shot), Some(table)) = (ctx.shot, ctx.field) {
            table_connection(ctx, table, li, &shot, s, particle, n, rng, rec);
        }
        *field = FieldWalk::Shared(None);
    }
    let (d, out, delta) = deflect(s.dir, &pop.phase, rng);
    *balance = match up {
        Some(up) => Balance::BeamLobe(pop.phase.eval(d.cos) / guide.eval(up.dot(out))),
        None => Balance::Full,
    };
    scatter(s, particle, n, (out, delta), ctx.settings, rng, checkpoint)
}

/// The parted twin's collision ([`FieldWalk::Twin`]): its connection to the beam, weighted
/// against the beam-lobe connection of the vertex it parted at, and the light field's table for
/// the light that scattered before reaching it. Its walk ends here.
#[allow(clippy::too_many_arguments)]
#[cold]
#[inline(never)]
fn twin_collision<const DOPPLER: bool, const LENGTH: bool>(
    ctx: &WalkContext,
    li: usize,
    s: &mut PathState,
    balance: Balance,
    particle: Particle,
    boost: f64,
    n: f64,
    rng: &mut PathRng,
    rec: &mut Recorder,
) -> Option<End> {
    let (Some(shot), Some(table)) = (ctx.shot, ctx.field) else { return Some(End::Absorbed) };
    if boost > 0.0 {
        let w = Balance::weight(match balance {
            Balance::BeamLobe(q) => Some(q),
            _ => None,
        });
        let here = Link { pos: s.pos, dir_in: s.dir, particle, n };
        rec.stats.work.camera_connections += 1;
        connect::<LENGTH, false>(ctx, li, &shot, here, *s, s.weight * w * boost, rng, rec);
    }
    table_connection(ctx, table, li, &shot, s, particle, n, rng, rec);
    Some(End::Absorbed)
}

/// Whether a camera path's collision at `pos` in layer `li` (in medium `m`), before it has met a
/// region, is its `j*` ([`super::field`]): below every region, in the layer's filling medium.
#[inline(always)]
fn switches_here(ctx: &WalkContext, li: usize, pos: DVec3, m: &Medium) -> bool {
    ctx.field.is_some_and(|t| pos.z > t.z_switch) && in_fill(ctx, li, m)
}

/// Whether `m` is layer `li`'s filling medium (not a region's).
#[inline(always)]
fn in_fill(ctx: &WalkContext, li: usize, m: &Medium) -> bool {
    std::ptr::eq(m, &ctx.scene.media[ctx.scene.layers[li].medium])
}

/// A beam-lobe connection from a camera path's vertex: the vertex's layer and position, the
/// direction drawn from the guide lobe, the path there (`tail`) and the vertex's `dir_in −
/// dir_out` toward it, its particle and index, the walk's and the guide's densities of the
/// direction, and the path's weight with the connection roulette's boost.
#[derive(Clone, Copy)]
struct Lobe<'a> {
    li: usize,
    pos: DVec3,
    dir: DVec3,
    tail: PathState,
    delta: DVec3,
    particle: Particle<'a>,
    n: f64,
    p_walk: f64,
    p_guide: f64,
    w: f64,
}

/// The beam-lobe connection `lobe` in `ctx`'s scene: the straight way to a real collision further
/// up ([`super::camera::lobe_flight`]) and its connection there, weighted against the walk's way
/// there by the balance heuristic (with the light field, [`lobe_pair`]).
#[inline(always)]
fn lobe_connection<const DOPPLER: bool, const LENGTH: bool>(
    ctx: &WalkContext,
    shot: &Shot,
    lobe: Lobe,
    rng: &mut PathRng,
    rec: &mut Recorder,
) {
    rec.stats.work.camera_connections += 1;
    let h = super::camera::lobe_flight(ctx.scene, lobe.li, lobe.pos, lobe.dir, ctx.settings.tracking, rng);
    if let Some(h) = h {
        lobe_vertex::<DOPPLER, LENGTH, false>(ctx, shot, &lobe, h, rng, rec);
    }
}

/// The connection at `h`, where `lobe`'s flight collided; with `PAIR` the scene's light minus
/// the layered twin's (the way up met no region, [`lobe_pair`]).
#[inline(always)]
fn lobe_vertex<const DOPPLER: bool, const LENGTH: bool, const PAIR: bool>(
    ctx: &WalkContext,
    shot: &Shot,
    lobe: &Lobe,
    h: super::camera::LobeHit,
    rng: &mut PathRng,
    rec: &mut Recorder,
) {
    let scene = ctx.scene;
    let m2 = &scene.media[h.medium];
    let albedo2 = if scene.layers[h.layer].heterogeneous { m2.albedo_at(h.pos) } else { m2.albedo() };
    let there_particle = Particle::pick::<DOPPLER>(m2, h.pos, rng);
    let mut tail = lobe.tail;
    lobe.particle.event(&mut tail, lobe.n, lobe.delta);
    tail.order += 1;
    tail.l += if LENGTH { h.length } else { 0.0 };
    let n2 = scene.layers[h.layer].n;
    let there = Link { pos: h.pos, dir_in: h.dir, particle: there_particle, n: n2 };
    let pt = lobe.p_walk * h.transmit;
    let w = lobe.w * pt / (pt + lobe.p_guide) * h.radiance * albedo2;
    rec.stats.work.camera_connections += 1;
    connect::<LENGTH, PAIR>(ctx, h.layer, shot, there, tail, w, rng, rec);
}

/// The beam-lobe connection `lobe` of a camera path sharing its walk with the layered twin
/// ([`FieldWalk::Shared`]): the scene's light minus the twin's. A way up that meets no region is
/// the twin's too (the same numbers draw the same flight): one flight, its connection's
/// difference; one that meets a region is flown again in the twin's scene from the same numbers
/// and each scored on its own, the twin's with the opposite sign.
#[cold]
#[inline(never)]
fn lobe_pair<const DOPPLER: bool, const LENGTH: bool>(
    ctx: &WalkContext,
    shot: &Shot,
    lobe: Lobe,
    rng: &mut PathRng,
    rec: &mut Recorder,
) {
    rec.stats.work.camera_connections += 1;
    let mut twin_rng = rng.clone();
    let tracking = ctx.settings.tracking;
    let (h, touched) =
        super::camera::lobe_flight_touching::<true>(ctx.scene, lobe.li, lobe.pos, lobe.dir, tracking, rng);
    if !touched {
        if let Some(h) = h {
            lobe_vertex::<DOPPLER, LENGTH, true>(ctx, shot, &lobe, h, rng, rec);
        }
        return;
    }
    if let Some(h) = h {
        lobe_vertex::<DOPPLER, LENGTH, false>(ctx, shot, &lobe, h, rng, rec);
    }
    let Some(scene) = ctx.twin_scene else { return };
    let twin_ctx = WalkContext { scene, field: None, ..*ctx };
    let twin_shot = Shot { scale: -shot.scale, ..*shot };
    if let Some(h) = super::camera::lobe_flight(scene, lobe.li, lobe.pos, lobe.dir, tracking, &mut twin_rng) {
        lobe_vertex::<DOPPLER, LENGTH, false>(&twin_ctx, &twin_shot, &lobe, h, &mut twin_rng, rec);
    }
}

/// The light field's connection at `j*` ([`super::field`]): the twin's scattered light arriving
/// along directions `ω′` drawn from the phase function about the way to the camera, read from the
/// table, each with a Doppler state drawn from its bin.
#[allow(clippy::too_many_arguments)]
#[cold]
#[inline(never)]
fn table_connection(
    _ctx: &WalkContext,
    table: &super::field::FieldTable,
    li: usize,
    shot: &Shot,
    s: &PathState,
    particle: Particle,
    n: f64,
    rng: &mut PathRng,
    rec: &mut Recorder,
) {
    let to_camera = -s.dir;
    let w = s.weight * shot.scale / super::field::TABLE_SAMPLES as f64;
    for _ in 0..super::field::TABLE_SAMPLES {
        let (_, arrive, _) = deflect(to_camera, &particle.pop.phase, rng);
        let (radiance, bin) = table.radiance(li, s.pos, arrive);
        let u = rng.uniform();
        if radiance <= 0.0 {
            continue;
        }
        let (events, dldt) = table.draw(bin, u);
        let mut e = PathState { dir: to_camera, weight: w * radiance, order: s.order + 2, ..*s };
        particle.event(&mut e, n, arrive + s.dir);
        e.dldt += dldt;
        e.doppler_events += events;
        rec.camera(shot, &e);
    }
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
    balance: &mut Balance,
    m: &Medium,
    n: f64,
    rng: &mut PathRng,
    checkpoint: &mut u32,
    rec: &mut Recorder,
) -> Option<End> {
    let particle = Particle::pick::<DOPPLER>(m, s.pos, rng);
    let pop = particle.pop;
    let boost = super::nee::connection_roulette(ctx.scene, li, s, rng);
    if boost > 0.0
        && let Some(shot) = ctx.shot
    {
        let dir_in = s.dir;
        let density = |u: DVec3| {
            let p = pop.phase.eval(dir_in.dot(u));
            (p, p)
        };
        let mark = |e: &mut PathState, arrive: DVec3| {
            particle.event(e, n, arrive + dir_in);
        };
        face_connection::<LENGTH>(ctx, li, &shot, s, density, boost, mark, rng, rec);
    }
    let (d, out, delta) = deflect(s.dir, &pop.phase, rng);
    *balance = face_mis(ctx, li, out, pop.phase.eval(d.cos));
    scatter(s, particle, n, (out, delta), ctx.settings, rng, checkpoint)
}

/// A vertex a camera path connects to the laser from: where, the walk's direction into it, the
/// particle scattering there (and its velocity), and the layer's index.
#[derive(Clone, Copy)]
struct Link<'a> {
    pos: DVec3,
    dir_in: DVec3,
    particle: Particle<'a>,
    n: f64,
}

/// Connect `at` (in layer `li`) to the laser and score the path into `shot`'s pixel with the
/// weight `w` (the walk's weight, with every factor but the phase function and the irradiance).
/// With `PAIR`, the scene's irradiance minus the layered twin's (nothing where the way up meets
/// no region).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn connect<const LENGTH: bool, const PAIR: bool>(
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
    let irradiance = if PAIR { b.irradiance - b.twin_irradiance() } else { b.irradiance };
    if PAIR && irradiance == 0.0 {
        return;
    }
    // The light arrives along `b.dir` and leaves towards the camera along `−dir_in`.
    let p = at.particle.pop.phase.eval(-b.dir.dot(at.dir_in));
    let mut e = PathState {
        pos: at.pos,
        dir: -at.dir_in,
        weight: w * p * irradiance * shot.scale,
        l: if LENGTH { tail.l + b.length } else { 0.0 },
        order: tail.order + 1,
        ..tail
    };
    at.particle.event(&mut e, at.n, b.dir + at.dir_in);
    rec.camera(shot, &e);
}
