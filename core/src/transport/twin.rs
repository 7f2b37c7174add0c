//! The layered twin of the control variate (`run.control_variate`, [`crate::detect::twin`]) as it
//! rides on forward paths: the likelihood ratio `Λ` of the path under the twin (each flight
//! through a region: the twin's transmittance over the path's; through density regions the path and
//! its twin fly together, [`coupled_flight`]), the parting where `Λ` leaves its band or the path
//! meets an opaque solid the twin has not ([`Split`]), and the twin's own walk from there once the
//! path has ended (`forward::twin_walk`). Its collisions are shared with the forward estimator's
//! ([`super::forward::collide_nee`]).

use glam::DVec3;

use crate::detect::twin::TwinPath;
use crate::detect::{PathState, Twin};
use crate::medium::{Layer, Medium, Scene};
use crate::sampling::PathRng;

use super::carried::{ForwardState, Split};
use super::event::Particle;
use super::tracking::{Flight, LayerRay};

/// The layered twin at a real collision of its path `s` in the medium `m` of layer `li`, whose
/// filling medium is `fill` (the twin collides in `fill` where the path collides in a region).
/// While `Λ` stays within `[1/TWIN_BAND, TWIN_BAND]` it shares the path's collision
/// ([`couple`]); beyond, it parts from the path here and walks on by itself ([`Split`], traced
/// after the path) from the path's state arriving here, weighted by `Λ` and the collision
/// densities' ratio `σt,fill / σt,medium`; the path goes on without a twin. Returns whether the
/// collision is in a region with the twin riding on the path (before it parted).
#[inline(always)]
pub(super) fn at_collision(
    st: &mut ForwardState,
    s: &PathState,
    m: &Medium,
    fill: &Medium,
    li: usize,
    rng: &PathRng,
) -> bool {
    let in_region = st.twin.is_some_and(|t| !t.only) && !std::ptr::eq(m, fill);
    if in_region
        && let Some(tw) = st.twin
        && !(1.0 / TWIN_BAND..=TWIN_BAND).contains(&tw.lambda)
    {
        let weight = s.weight * fill.sigma_t() / m.sigma_t();
        st.split = Some(Split {
            s: tw.state(&PathState { weight, ..*s }),
            li,
            twin: tw,
            rng: rng.clone(),
            flying: false,
            direct: st.direct,
        });
        st.twin = None;
    }
    in_region
}

/// The twin's own particle where it shares its path's collision in a region (medium `m`, filling
/// medium `fill`) at `pos`: drawn by the fill's shares, on its own stream of the path's numbers
/// (no ratio), and its collision and weight after it over the path's, `σt,fill·a_fill / (σt·a) =
/// σs,fill/σs` (the flight's share is in from the flight). Not over the population's σs: the
/// path's draw of its particle is no part of the twin's density (measured: a vessel of two
/// populations, 14 and 6 /mm, gave an image 19 % low, χ² 57 over 16 pixels). `None` once the twin
/// has parted.
#[inline(always)]
pub(super) fn couple<'a, const DOPPLER: bool>(
    st: &mut ForwardState,
    m: &Medium,
    fill: &'a Medium,
    pos: DVec3,
    rng: &mut PathRng,
) -> Option<Particle<'a>> {
    let tw = st.twin.as_mut()?;
    let own = Particle::pick::<DOPPLER>(fill, pos, rng);
    tw.lambda *= fill.sigma_s() / m.sigma_s();
    tw.touched = true;
    Some(own)
}

/// What the path's layered twin `twin` scores of a shadow ray `e` of its path (before the
/// vertex's Doppler event): nothing without a twin; the twin's alone in its own walk; the path's
/// own share while the twin is the path (it has met no region, and `same()`: its ray's way and
/// density are the path's); else a state of its own, of weight `weight(twin)`, with the Doppler
/// event `event` of its own particle.
#[inline(always)]
pub(super) fn shadow_ray(
    twin: Option<&TwinPath>,
    e: &PathState,
    same: impl FnOnce() -> bool,
    weight: impl FnOnce(&TwinPath) -> f64,
    event: impl FnOnce(&mut PathState),
) -> Twin {
    match twin {
        None => Twin::Off,
        Some(tw) if tw.only => Twin::Only(tw.launch),
        Some(tw) if !tw.touched && same() => Twin::Same(tw.launch),
        Some(tw) => {
            let mut t = tw.state(e);
            t.weight = weight(tw);
            event(&mut t);
            Twin::Other(t, tw.launch)
        }
    }
}

/// The coupled twin (its particle `own`) after its path at `s` scattered on `path` toward the
/// direction of cosine `cos` (`delta` = `dir − out`), in a layer of index `n`: `Λ` times the
/// twin's phase-function density of that direction over the path's, and the twin's Doppler event
/// instead of the path's.
#[inline(always)]
pub(super) fn turned(
    st: &mut ForwardState,
    own: Particle,
    path: Particle,
    s: &PathState,
    n: f64,
    cos: f64,
    delta: DVec3,
) {
    let Some(tw) = st.twin.as_mut() else { return };
    tw.lambda *= own.pop.phase.eval(cos) / path.pop.phase.eval(cos);
    let mut shift = PathState::new(s.pos, s.dir, 0.0, 0.0);
    own.event(&mut shift, n, delta);
    let mut mine = PathState::new(s.pos, s.dir, 0.0, 0.0);
    path.event(&mut mine, n, delta);
    tw.dldt += shift.dldt - mine.dldt;
    tw.brownian += shift.brownian - mine.brownian;
    tw.doppler_events += i64::from(shift.doppler_events) - i64::from(mine.doppler_events);
}

/// A flight of the path `s` in layer `li` through density regions, flown with its layered twin
/// (`coupled_flight` of [`super::tracking`]) up to `t_end`: where they part, the twin is split off
/// ([`part_in_flight`]); where both collide in a region, the coupled collision of
/// `collide_nee`, whose `σs,fill/σs` holds the collision densities' ratio that this flight has not
/// weighted: `σt/σt,fill` takes it back out.
#[inline(always)]
pub(super) fn coupled_flight<const LENGTH: bool>(
    ray: &LayerRay,
    t_end: f64,
    li: usize,
    s: &PathState,
    rng: &mut PathRng,
    null_collisions: &mut u64,
    st: &mut ForwardState,
) -> Flight {
    let (scene, layer) = (ray.scene, ray.layer);
    let fill = &scene.media[layer.medium];
    let (flight, parting) = super::tracking::coupled_flight(ray, t_end, fill.sigma_t(), rng, null_collisions);
    match parting {
        Some(p) => part_in_flight::<LENGTH>(s, li, layer.n, p, st),
        None => {
            if let (Flight::Collision { medium, .. }, Some(tw)) = (flight, st.twin.as_mut())
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
pub(super) fn weigh_flight(scene: &Scene, layer: &Layer, s: &PathState, t: f64, st: &mut ForwardState) {
    if let Some(tw) = st.twin.as_mut() {
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
fn part_in_flight<const LENGTH: bool>(
    s: &PathState,
    li: usize,
    n: f64,
    p: super::tracking::Parting,
    st: &mut ForwardState,
) {
    let Some(tw) = st.twin.take() else { return };
    let at = PathState { pos: s.pos + p.t * s.dir, l: if LENGTH { s.l + n * p.t } else { 0.0 }, ..*s };
    st.split = Some(Split {
        s: tw.state(&at),
        li,
        twin: TwinPath { touched: true, ..tw },
        rng: p.rng,
        flying: !p.collides,
        direct: st.direct,
    });
}

/// The path `s` in layer `li` has flown to an opaque solid's boundary, which its layered twin
/// (without solids, `Scene::layered_twin`) does not have: the twin parts from it there and, once
/// the path has ended, flies on from that point (the path's flight ran that far without a
/// collision, and the rest of the twin's is a fresh exponential) on a copy of the generator
/// ([`Split`]); the path goes on without a twin.
#[cold]
#[inline(never)]
pub(super) fn part_at_solid(s: &PathState, li: usize, rng: &PathRng, st: &mut ForwardState) {
    let Some(tw) = st.twin.take() else { return };
    st.split = Some(Split {
        s: tw.state(s),
        li,
        twin: TwinPath { touched: true, ..tw },
        rng: rng.clone(),
        flying: true,
        direct: st.direct,
    });
}
