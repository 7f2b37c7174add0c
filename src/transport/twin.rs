//! The layered twin of the control variate (`run.control_variate`, [`crate::detect::twin`]) as it
//! rides on forward paths: the likelihood ratio `Λ` of the path under the twin (each flight
//! through a region: the twin's transmittance over the path's; through density regions the path and
//! its twin fly together, [`coupled_flight`]), the parting where `Λ` leaves its band or the path
//! meets an opaque solid the twin has not ([`Split`]), and the twin's own walk from there once the
//! path has ended ([`twin_walk`]). Its collisions are shared with the forward estimator's
//! ([`super::forward::collide_nee`]).

use crate::detect::twin::{Split, TwinPath};
use crate::detect::{Exit, PathState, Recorder};
use crate::medium::{Layer, Scene};
use crate::sampling::PathRng;

use super::event::RENORMALISE_EVERY;
use super::forward::Forward;
use super::tracking::{Flight, LayerRay};
use super::walk::{End, Estimator, WalkContext, in_gate, walk_to_the_end};

/// A flight of the path `s` in layer `li` through density regions, flown with its layered twin
/// (`coupled_flight` of [`super::tracking`]) up to `t_end`: where they part, the twin is split off
/// ([`part_in_flight`]); where both collide in a region, the coupled collision of
/// `collide_nee`, whose `σs,fill/σs` holds the collision densities' ratio that this flight has not
/// weighted: `σt/σt,fill` takes it back out.
#[inline(always)]
pub(super) fn coupled_flight<E: Estimator>(
    ray: &LayerRay,
    t_end: f64,
    li: usize,
    s: &PathState,
    rng: &mut PathRng,
    null_collisions: &mut u64,
    rec: &mut Recorder,
) -> Flight {
    let (scene, layer) = (ray.scene, ray.layer);
    let fill = &scene.media[layer.medium];
    let (flight, parting) = super::tracking::coupled_flight(ray, t_end, fill.sigma_t(), rng, null_collisions);
    match parting {
        Some(p) => part_in_flight::<E>(s, li, layer.n, p, rec),
        None => {
            if let (Flight::Collision { medium, .. }, Some(tw)) = (flight, rec.twin.as_mut())
                && medium != layer.medium
            {
                tw.lambda *= scene.media[medium].sigma_t() / fill.sigma_t();
            }
        }
    }
    flight
}

/// A flight of `t` of the path `s` through layer `layer`, which holds regions: the twin (if the
/// path carries one) is weighted by its transmittance over the path's (the regions' excess optical
/// depth along it).
#[inline(always)]
pub(super) fn weigh_flight(scene: &Scene, layer: &Layer, s: &PathState, t: f64, rec: &mut Recorder) {
    if let Some(tw) = rec.twin.as_mut() {
        tw.flight(super::nee::region_excess(scene, layer, s.pos, s.dir, t));
    }
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
fn part_in_flight<E: Estimator>(s: &PathState, li: usize, n: f64, p: super::tracking::Parting, rec: &mut Recorder) {
    let Some(tw) = rec.twin.take() else { return };
    let at = PathState { pos: s.pos + p.t * s.dir, l: if E::LENGTH { s.l + n * p.t } else { 0.0 }, ..*s };
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
pub(super) fn part_at_solid(s: &PathState, li: usize, rng: &PathRng, rec: &mut Recorder) {
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
pub(super) fn twin_walk<const DOPPLER: bool, const LENGTH: bool, const GATE: bool>(
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
        super::forward::collide_nee::<DOPPLER, LENGTH>(
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
        None => walk_to_the_end::<Forward<DOPPLER, LENGTH, true, false, GATE, false>>(
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
