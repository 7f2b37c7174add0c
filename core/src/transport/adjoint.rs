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
pub(super) struct Adjoint<const DOPPLER: bool, const LENGTH: bool> {
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

impl<const DOPPLER: bool, const LENGTH: bool> Estimator for Adjoint<DOPPLER, LENGTH> {
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
        collide_camera::<DOPPLER, LENGTH>(
            ctx,
            v.li,
            s,
            &mut self.balance,
            v.medium,
            v.albedo,
            v.n,
            rng,
            checkpoint,
            rec,
        )
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
pub(super) fn trace_camera_path<const DOPPLER: bool, const LENGTH: bool>(
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
    let end = walk_to_the_end(
        &mut Adjoint::<DOPPLER, LENGTH> { balance: Balance::Full },
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
/// particle velocity serves the connections and the continuation.
//
// Outlined, as `collide_nee`: the connections are traces through every layer above.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn collide_camera<const DOPPLER: bool, const LENGTH: bool>(
    ctx: &WalkContext,
    li: usize,
    s: &mut PathState,
    balance: &mut Balance,
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
                let there_particle = Particle::pick::<DOPPLER>(m2, h.pos, rng);
                let mut tail = tail;
                particle.event(&mut tail, n, s.dir - dir);
                tail.order += 1;
                tail.l += if LENGTH { h.length } else { 0.0 };
                let n2 = scene.layers[h.layer].n;
                let there = Link { pos: h.pos, dir_in: h.dir, particle: there_particle, n: n2 };
                let pt = p_walk * h.transmit;
                let w = s.weight * boost * pt / (pt + p_guide) * h.radiance * albedo2;
                rec.stats.work.camera_connections += 1;
                connect::<LENGTH>(ctx, h.layer, &shot, there, tail, w, rng, rec);
            }
        }
    }
    let (d, out, delta) = deflect(s.dir, &pop.phase, rng);
    *balance = match up {
        Some(up) => Balance::BeamLobe(pop.phase.eval(d.cos) / guide.eval(up.dot(out))),
        None => Balance::Full,
    };
    scatter(s, particle, n, (out, delta), ctx.settings, rng, checkpoint)
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
    let p = at.particle.pop.phase.eval(-b.dir.dot(at.dir_in));
    let mut e = PathState {
        pos: at.pos,
        dir: -at.dir_in,
        weight: w * p * b.irradiance * shot.scale,
        l: if LENGTH { tail.l + b.length } else { 0.0 },
        order: tail.order + 1,
        ..tail
    };
    at.particle.event(&mut e, at.n, b.dir + at.dir_in);
    rec.camera(shot, &e);
}
