//! The forward estimator: packets from the laser, scored where they leave the stack (its escapes
//! into the detectors' cones and areas), by next-event estimation (shadow rays from every real
//! collision, rough face and opaque surface toward the cone detectors and lidar receivers,
//! [`super::nee`], balanced against the escapes), and by the deterministic unscattered
//! reflections at the interfaces below the surface; with `VOLUME` its track lengths and
//! collisions score the volume tally. It carries the layered twin of the control variate
//! ([`super::twin`]) where the run has one, and the weight windows and guide steer it
//! ([`super::steering`]).

use glam::DVec3;

use crate::detect::twin::TwinPath;
use crate::detect::{Exit, PathState, Recorder, Scalar, Side, Twin};
use crate::medium::{Medium, Scene};
use crate::sampling::PathRng;

use super::carried::{ForwardState, Split};
use super::event::{Particle, RENORMALISE_EVERY, doppler_increment, particle_velocity};
use super::fresnel;
use super::nee::{Crossing, NeeTarget, reflections_below};
use super::policy::WalkSettings;
use super::tracking::{Flight, LayerRay};
use super::walk::{
    End, Estimator, RoughFace, SurfaceHit, Vertex, WalkContext, absorb, in_gate, scatter, walk_to_the_end,
};
use super::windows::Windows;

/// The forward estimator, compiled per kind of scene: `DOPPLER = false` drops every velocity
/// lookup (nothing moves), `LENGTH = false` the optical-path-length bookkeeping (no chirp, no
/// gates), `NEE = false` the shadow rays and the layered twin (no next-event detector, no control
/// variate), `VOLUME = false` the volume tally's hooks (no `[volume]`), `GATE = false` the time
/// gate's checks (no `run.time_gate_ns`; a gated walk also tracks the length), `LATERAL = false`
/// the side faces of a box phantom (no `[lateral]`: the layers are infinite slabs). Its value is
/// the path's [`ForwardState`], one per batch, reused path after path.
pub(super) struct Forward<
    const DOPPLER: bool,
    const LENGTH: bool,
    const NEE: bool,
    const VOLUME: bool,
    const GATE: bool,
    const LATERAL: bool,
    const PULSE: bool,
>(ForwardState);

impl<
    const DOPPLER: bool,
    const LENGTH: bool,
    const NEE: bool,
    const VOLUME: bool,
    const GATE: bool,
    const LATERAL: bool,
    const PULSE: bool,
> Estimator for Forward<DOPPLER, LENGTH, NEE, VOLUME, GATE, LATERAL, PULSE>
{
    const DOPPLER: bool = DOPPLER;
    const LENGTH: bool = LENGTH;
    const GATE: bool = GATE;
    const LATERAL: bool = LATERAL;
    const VOLUME: bool = VOLUME;

    /// Absorption weighting, then (with `NEE`) the shadow rays ([`collide_nee`]) or the plain
    /// continuation ([`collide`]), the importance pilot's record of the state, and the weight
    /// window ([`super::steering::window`]).
    #[inline(always)]
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
    ) -> Option<End> {
        let li = v.li;
        if NEE {
            super::walk::advance::<Self>(s, t, v.n);
            if let Some(end) = collide_nee::<DOPPLER, LENGTH, PULSE>(
                ctx.scene,
                ctx.nee,
                ctx.windows,
                li,
                s,
                v.medium,
                v.albedo,
                v.n,
                ctx.settings,
                rng,
                absorbed,
                checkpoint,
                &mut self.0,
                rec,
            ) {
                return Some(end);
            }
        } else if let Some(end) = collide::<DOPPLER, LENGTH>(s, t, v, ctx, rng, absorbed, checkpoint) {
            // (A pulsatile scene's walk always has `NEE`: its collisions carry the harmonics.)
            return Some(end);
        }
        rec.scattered(li, s);
        super::steering::window(ctx, rec, &mut self.0, s, li, rng)
    }

    #[inline(always)]
    fn track(&self, ctx: &WalkContext, rec: &mut Recorder, s: &PathState, t: f64, n: f64) {
        if VOLUME && let Some(v) = ctx.volume {
            v.track::<GATE>(rec.acc, s.pos, s.dir, t, s.weight, s.l, n);
        }
    }

    /// Through density regions a path carrying its layered twin flies with it.
    #[inline(always)]
    fn own_flight(
        &mut self,
        ray: &LayerRay,
        t_end: f64,
        li: usize,
        s: &PathState,
        rng: &mut PathRng,
        null_collisions: &mut u64,
    ) -> Option<Flight> {
        let coupled = NEE && ray.layer.heterogeneous && self.0.twin.is_some_and(|t| !t.only);
        coupled.then(|| super::twin::coupled_flight::<LENGTH>(ray, t_end, li, s, rng, null_collisions, &mut self.0))
    }

    /// The twin's transmittance over the path's through the regions.
    #[inline(always)]
    fn flew(&mut self, scene: &Scene, layer: &crate::medium::Layer, s: &PathState, t: f64) {
        if NEE {
            super::twin::weigh_flight(scene, layer, s, t, &mut self.0);
        }
    }

    /// The layered twin, which has no solids, parts from the path here.
    #[inline(always)]
    fn at_solid(&mut self, s: &PathState, li: usize, rng: &PathRng) {
        if NEE && self.0.twin.is_some() {
            super::twin::part_at_solid(s, li, rng, &mut self.0);
        }
    }

    /// No shadow ray takes a smooth face's reflection: full weight for the escape after it.
    #[inline(always)]
    fn mirrored(&mut self) {
        if NEE {
            self.0.direct = None;
        }
    }

    /// Shadow rays from the face toward the next-event detectors above (the interface's
    /// reflection toward them when the path came down, its transmission when it came up;
    /// balanced against the direct escapes by the sampling density).
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
        if NEE {
            // Up from the face: into the layer above, or out of the stack.
            let density = |d: DVec3| {
                let wo = at.frame.to_local(d);
                (at.interface.eval(at.wi, wo, at.n_i, at.n_t), at.interface.pdf(at.wi, wo, at.n_i, at.n_t))
            };
            if PULSE {
                rec.pulse.copy_from_slice(&self.0.pulse);
            }
            let twin = self.0.twin.as_ref();
            surface_shadow_rays::<LENGTH>(ctx, face.checked_sub(1), s, twin, density, s.order, None, rng, rec);
        }
    }

    /// The density of the direction drawn over `n²|cos|` in the medium it goes on in.
    #[inline(always)]
    fn crossed(&mut self, _s: &mut PathState, at: &RoughFace, c: &crate::surface::Crossed) {
        if NEE {
            let n = if c.transmitted { at.n_t } else { at.n_i };
            self.0.direct = Some(at.interface.pdf(at.wi, c.wo, at.n_i, at.n_t) / (n * n * c.wo.z.abs()));
        }
    }

    /// Shadow rays toward the next-event detectors (the BSDF's value toward each, balanced
    /// against its own density where a direct escape can also reach the detector), with the
    /// surface's Doppler term.
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
        if NEE && surface.bsdf.has_continuous_part() {
            let n = ctx.scene.layers[li].n;
            let density = |d: DVec3| {
                let wo = frame.to_local(d);
                (surface.bsdf.eval(wi, wo), surface.bsdf.pdf(wi, wo))
            };
            let doppler = moving.then_some((n, v));
            if PULSE {
                rec.pulse.copy_from_slice(&self.0.pulse);
            }
            let twin = self.0.twin.as_ref();
            surface_shadow_rays::<LENGTH>(ctx, Some(li), s, twin, density, s.order + 1, doppler, rng, rec);
        }
    }

    /// The density of the direction drawn, in the layer's solid angle over `n²|cos|` (as a
    /// collision's phase-function density): a direct escape weighs itself against the shadow
    /// rays by it; a mirror's Dirac lobe is no shadow ray's (full weight).
    #[inline(always)]
    fn reflected(
        &mut self,
        ctx: &WalkContext,
        hit: &SurfaceHit,
        _s: &mut PathState,
        smp: &crate::surface::Sampled,
        out: DVec3,
    ) {
        if NEE {
            let n = ctx.scene.layers[hit.li].n;
            self.0.direct = (!smp.delta).then(|| hit.surface.bsdf.pdf(hit.wi, smp.wo) / (n * n * out.z.abs()));
        }
    }
}

impl<
    const DOPPLER: bool,
    const LENGTH: bool,
    const NEE: bool,
    const VOLUME: bool,
    const GATE: bool,
    const LATERAL: bool,
    const PULSE: bool,
> Forward<DOPPLER, LENGTH, NEE, VOLUME, GATE, LATERAL, PULSE>
{
    /// The estimator for a batch of paths.
    pub(super) fn new() -> Self {
        Forward(ForwardState::default())
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
    pub(super) fn trace_path(&mut self, ctx: &WalkContext, rec: &mut Recorder, rng: &mut PathRng) {
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
        if PULSE {
            // Nothing has moved the light yet: the specular reflection and the unscattered
            // reflections carry no harmonic.
            let k = scene.cycle.map_or(0, |c| c.harmonics);
            self.0.pulse.clear();
            self.0.pulse.resize(k, num_complex::Complex64::ZERO);
            rec.pulse.clone_from(&self.0.pulse);
        }
        if NEE {
            self.0.direct = None;
            if ctx.twin {
                self.0.twin = Some(TwinPath::new(pos.x, pos.y));
            }
        }
        // A rough top surface: the walk starts at its face, which reflects or refracts the beam.
        let n_top = scene.layers[0].n;
        let rough_entry = scene.layers[0].face.is_rough() && n_top != scene.n_above;
        // Specular reflection at entry, scored deterministically (as MCML).
        let (r_sp, cos_t) = fresnel::reflectance(scene.n_above, n_top, dir.z);
        if r_sp > 0.0 && !rough_entry {
            let reflected = PathState { dir: DVec3::new(dir.x, dir.y, -dir.z), weight: w0 * r_sp, ..s };
            if in_gate::<GATE>(ctx.settings, s.l) {
                rec.escape(Side::Top, reflected, Exit::Specular, scene.n_above, self.0.twin.as_ref(), None);
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
            unscattered_reflections::<NEE, LENGTH, GATE>(ctx, s, dir, self.0.twin.as_ref(), &mut local, rec);
            *rng = local;
        }

        // The walk draws from a copy local to this path, handed back at the end (a clone repeats its
        // original's numbers: the stream is unchanged). With `rng` itself (a local of the batch
        // loop, into which this function is inlined twice: with and without next-event targets)
        // the walk stored and reloaded the generator's state around its draws: callgrind, vdH slab
        // 2·10⁵ paths, 192.0M → 175.7M instructions (166.1M before next-event estimation, c3d5384).
        let mut local = rng.clone();
        // The path's walk, then those of the copies its weight windows split off, each walked on from
        // where it was made (layer, scattering order, own stream and twin). One call of the walk:
        // it is inlined, and a second call site for the copies doubled the code compiled per walk.
        let (mut li, mut entering, mut order) = (0, rough_entry, 0);
        loop {
            let (mut absorbed, mut null_collisions) = (0.0, 0);
            let end = walk_to_the_end::<Self>(
                self,
                ctx,
                li,
                &mut s,
                &mut local,
                &mut absorbed,
                &mut null_collisions,
                rec,
                entering,
            );
            finish_walk::<DOPPLER, LENGTH, NEE, GATE, PULSE>(
                ctx,
                rec,
                &mut self.0,
                &s,
                end,
                (absorbed, null_collisions, order),
            );
            let Some(c) = self.0.copies.pop() else { break };
            (self.0.twin, self.0.direct) = (c.twin, c.direct);
            (s, local, li, entering, order) = (c.s, c.rng, c.li, false, c.s.order);
        }
        *rng = local;
    }
}

/// Record how the walk of `s` ended (`end`), with its absorbed weight, its null collisions and
/// the scattering order it started its walk with (0 for a path from the source, a copy's order
/// at its split), and walk the layered twin that parted from it.
#[inline(always)]
fn finish_walk<const DOPPLER: bool, const LENGTH: bool, const NEE: bool, const GATE: bool, const PULSE: bool>(
    ctx: &WalkContext,
    rec: &mut Recorder,
    st: &mut ForwardState,
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
                if PULSE {
                    rec.pulse.copy_from_slice(&st.pulse);
                }
                rec.escape(side, s, exit, n_ambient, st.twin.as_ref(), st.direct);
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
    if NEE && let Some(split) = st.split.take() {
        twin_walk::<DOPPLER, LENGTH, GATE>(ctx, split, rec);
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
pub(super) fn unscattered_reflections<const NEE: bool, const LENGTH: bool, const GATE: bool>(
    ctx: &WalkContext,
    s: PathState,
    b: DVec3,
    twin: Option<&TwinPath>,
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
        let twin = match twin {
            Some(t) if NEE && (c.excess != 0.0 || c.twin_transmit != c.transmit) => Twin::Other(
                PathState::new(
                    c.pos,
                    DVec3::new(b.x, b.y, -b.z),
                    s.weight * c.twin_transmit * (c.excess - c.tau).exp(),
                    l,
                ),
                t.launch,
            ),
            Some(t) if NEE => Twin::Same(t.launch),
            _ => Twin::Off,
        };
        if (weight > 0.0 || twin != Twin::Off) && in_gate::<GATE>(ctx.settings, l) {
            let e = PathState::new(c.pos, DVec3::new(b.x, b.y, -b.z), weight, l);
            rec.reflection(&e, twin, n0);
        }
    });
    rec.stats.work.reflection_steps += steps;
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
    twin: Option<&TwinPath>,
    density: impl Fn(DVec3) -> (f64, f64),
    order: u32,
    doppler: Option<(f64, DVec3)>,
    rng: &mut PathRng,
    rec: &mut Recorder,
) {
    let boost = super::nee::connection_roulette(ctx.scene, from.unwrap_or(0), s, rng);
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
            ..*s
        };
        if let Some((n, v)) = doppler {
            e.dldt += doppler_increment(n, v, s.dir - h.dir_vertex);
            e.doppler_events += 1;
        }
        // The layered twin has the same planar surface (the bottom, a rough face): its shadow ray
        // is the path's without the regions' excess optical depth, weighted by `Λ`.
        let twin = super::twin::shadow_ray(
            twin,
            &e,
            || h.twin_is_path(),
            |tw| s.weight * tw.lambda * boost * h.twin_factor(density(h.dir_vertex).0),
            |_| {},
        );
        rec.next_event(target.detector, &e, twin, ctx.scene.n_above);
    }
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
    let (_, out, delta) = super::steering::continuation(ctx.windows, li, s, &pop.phase, rng);
    // (The velocity after the direction: this walk's streams as they always were.)
    let moving = DOPPLER && dynamic;
    let v = if moving { particle_velocity(pop, s.pos, rng) } else { DVec3::ZERO };
    let particle = Particle { pop, moving, v };
    scatter(s, particle, n, (out, delta), ctx.settings, rng, checkpoint)
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
pub(super) fn collide_nee<const DOPPLER: bool, const LENGTH: bool, const PULSE: bool>(
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
    st: &mut ForwardState,
    rec: &mut Recorder,
) -> Option<End> {
    // The layered twin at its path's collision: parted here, or sharing it in a region
    // ([`super::twin::at_collision`]).
    let fill = &scene.media[scene.layers[li].medium];
    let in_region = super::twin::at_collision(st, s, m, fill, li, rng);
    if absorb(s, albedo, absorbed) {
        return Some(End::Absorbed);
    }
    // One particle serves the shadow rays and the continuation (so that the balance heuristic
    // of `shadow_ray` weighs against the density the continuation is drawn from).
    // In a pulsatile scene the particle's cycle-mean flow and random velocity apart (drawn as
    // `Particle::pick` draws them): each pulses by its own waveform.
    let (path, flow, random) = if PULSE {
        Particle::pick_parts(m, s.pos, rng)
    } else {
        (Particle::pick::<DOPPLER>(m, s.pos, rng), DVec3::ZERO, DVec3::ZERO)
    };
    let pop = path.pop;
    // The coupled twin's own particle where it shares a collision in a region.
    let coupled = if in_region { super::twin::couple::<DOPPLER>(st, m, fill, s.pos, rng) } else { None };
    // (Without next-event targets this walk runs for the layered twin alone: no roulette draw, no
    // shadow ray, no density for the escapes' weights against them.)
    let boost = if nee.is_empty() { 0.0 } else { super::nee::connection_roulette(scene, li, s, rng) };
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
            ..*s
        };
        let in_out = s.dir - h.dir_vertex;
        // The twin's shadow ray: its phase function (its own particle's where it shares a
        // collision in a region), without the regions' excess optical depth, its Doppler state.
        let own = coupled.unwrap_or(path);
        let twin = super::twin::shadow_ray(
            st.twin.as_ref(),
            &e,
            || coupled.is_none() && h.twin_is_path(),
            |tw| s.weight * tw.lambda * boost * h.twin_factor(own.pop.phase.eval(s.dir.dot(h.dir_vertex))),
            |t| own.event(t, n, in_out),
        );
        path.event(&mut e, n, in_out);
        if PULSE {
            rec.pulse.copy_from_slice(&st.pulse);
            if path.moving {
                pop.pulse.event(&mut rec.pulse, s.pos, n, flow, random, in_out);
            }
        }
        rec.next_event(target.detector, &e, twin, scene.n_above);
    }
    // The continuation: guided where the weight windows have a guide that acts here, but not at
    // a collision the twin shares in a region (its likelihood ratio takes the phase function's own
    // draw).
    let steer = windows.filter(|_| coupled.is_none());
    let (cos, out, delta) = super::steering::continuation(steer, li, s, &pop.phase, rng);
    if !nee.is_empty() {
        st.direct = Some(pop.phase.eval(cos) / (n * n * out.z.abs()));
    }
    if let Some(own) = coupled {
        super::twin::turned(st, own, path, s, n, cos, delta);
    }
    if PULSE && path.moving {
        pop.pulse.event(&mut st.pulse, s.pos, n, flow, random, delta);
    }
    scatter(s, path, n, (out, delta), settings, rng, checkpoint)
}

/// The twin's own walk from where it parted from its path ([`Split`]), in the twin's scene
/// (`ctx.twin_scene`: the regions removed): its collision there (or, parted in flight, its
/// flight on from there), then its walk, every
/// contribution scored as the twin's alone ([`Twin::Only`]); nothing of it reaches the scalar
/// tallies or the volume tally.
#[cold]
#[inline(never)]
pub(super) fn twin_walk<const DOPPLER: bool, const LENGTH: bool, const GATE: bool>(
    ctx: &WalkContext,
    split: Split,
    rec: &mut Recorder,
) {
    let Some(scene) = ctx.twin_scene else { return };
    let ctx = WalkContext { scene, volume: None, reflections: false, windows: None, ..*ctx };
    let Split { mut s, li, twin, mut rng, flying, direct } = split;
    let mut own = Forward::<DOPPLER, LENGTH, true, false, GATE, false, false>(ForwardState {
        direct,
        twin: Some(TwinPath { only: true, ..twin }),
        ..ForwardState::default()
    });
    let layer = &scene.layers[li];
    let fill = &scene.media[layer.medium];
    let (mut absorbed, mut nulls) = (0.0, 0);
    let mut checkpoint = s.order.saturating_add(RENORMALISE_EVERY).min(ctx.settings.max_events);
    let first = if flying {
        None
    } else {
        collide_nee::<DOPPLER, LENGTH, false>(
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
            &mut own.0,
            rec,
        )
    };
    let end = match first {
        Some(end) => end,
        None => walk_to_the_end(&mut own, &ctx, li, &mut s, &mut rng, &mut absorbed, &mut nulls, rec, false),
    };
    if let End::Escaped { side, n_ambient, .. } = end
        && in_gate::<GATE>(ctx.settings, s.l)
    {
        rec.escape(side, s, Exit::Walked, n_ambient, own.0.twin.as_ref(), own.0.direct);
    }
}
