//! The layered twin of the control variate (`run.control_variate`, [`crate::detect::twin`]) as it
//! rides on forward paths: the likelihood ratio `Λ` of the path under the twin (each flight
//! through a region: the twin's transmittance over the path's; through density regions the path and
//! its twin fly together, [`coupled_flight`]), the parting where `Λ` leaves its band or the path
//! meets an opaque solid the twin has not ([`Split`]), and the twin's own walk from there once the
//! path has ended (`forward::twin_walk`). Its collisions are shared with the forward estimator's
//! ([`super::forward::collide_nee`]).

use crate::detect::PathState;
use crate::detect::twin::TwinPath;
use crate::medium::{Layer, Scene};
use crate::sampling::PathRng;

use super::forward::ForwardState;
use super::tracking::{Flight, LayerRay};

/// Where a forward path's layered twin parts from it: a collision of the path in a region with
/// `Λ` beyond [`TWIN_BAND`], which the twin makes in its layer's filling medium (with the weight
/// and Doppler state `s`: the path's arriving there times `Λ` and the collision densities' ratio)
/// and walks on from in the twin's scene with a copy of the path's generator (`forward::twin_walk`;
/// common random numbers, each walk a proper sample of its own). Until then the twin shares the
/// path; after, the path scores without a twin and the twin's walk scores only as the twin (its
/// share out of the pixels it meets, into the kernels).
#[derive(Clone)]
pub struct Split {
    pub s: PathState,
    pub li: usize,
    pub twin: TwinPath,
    pub rng: PathRng,
    /// Parted in a flight through a density region where the path collided and the twin did not
    /// ([`super::tracking::coupled_flight`]): the twin flies on from `s` (else it collides there).
    pub flying: bool,
    /// The path's [`ForwardState::direct`] there, which an escape of the twin flying on is
    /// balanced with.
    pub direct: Option<f64>,
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
