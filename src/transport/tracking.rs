//! Free-flight sampling inside one layer.
//!
//! A layer without regions is homogeneous: its free path is sampled analytically (exact). A layer
//! with regions has piecewise-constant σt along a ray. Two exact estimators are offered:
//!
//! * [`Tracking::Analytic`] (default): intersect the ray with the layer's regions, cut it into
//!   segments of constant σt and invert the optical depth `τ = −ln(1 − ξ)` across them —
//!   equivalent to delta tracking with a per-segment majorant equal to σt, so no null collisions.
//! * [`Tracking::Delta`]: Woodcock/delta tracking with one majorant per layer (the largest σt of
//!   the layer and its regions, optionally inflated for tests); tentative collisions are accepted
//!   with probability σt(x)/σ̄ after a point lookup, the rest are null collisions (not vertices).
//!
//! Both sample the same distance distribution; the test `analytic_and_delta_agree` checks it.

use glam::DVec3;

use crate::medium::{Layer, MAX_REGIONS_PER_LAYER, Scene};
use crate::sampling::PathRng;

/// How free paths are sampled in layers that hold regions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Tracking {
    Analytic,
    /// Delta tracking with the layer majorant multiplied by `majorant_scale ≥ 1`.
    Delta {
        majorant_scale: f64,
    },
}

/// The outcome of a free flight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Flight {
    /// A real collision at distance `t` in medium `medium` (index into `Scene::media`).
    Collision { t: f64, medium: usize },
    /// No collision before the layer boundary, reached at distance `t` (∞ for a ray parallel to
    /// the layers or into a semi-infinite layer).
    Boundary { t: f64 },
}

/// Sample the next real collision along `pos + t·dir` in `layer`, before the boundary plane that
/// lies `dz ≥ 0` away along z (in the direction of travel), with `abs_dir_z = |dir.z|`.
/// `null_collisions` counts the rejected tentative collisions of delta tracking.
///
/// The homogeneous case compares `t·|dir.z| < dz`, so the division giving the distance to the
/// boundary is only done when the boundary is reached.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn free_flight(
    scene: &Scene,
    layer: &Layer,
    pos: DVec3,
    dir: DVec3,
    dz: f64,
    abs_dir_z: f64,
    tracking: Tracking,
    rng: &mut PathRng,
    null_collisions: &mut u64,
) -> Flight {
    if layer.regions.is_empty() {
        let t = rng.exponential() * scene.media[layer.medium].inv_sigma_t();
        return if t * abs_dir_z < dz {
            Flight::Collision { t, medium: layer.medium }
        } else {
            Flight::Boundary { t: dz / abs_dir_z }
        };
    }
    let t_boundary = dz / abs_dir_z;
    // The outlined trackers never see `rng` itself (see `PathRng`): the analytic one needs one
    // optical depth, drawn here, and delta tracking works on the generator passed by value.
    match tracking {
        Tracking::Analytic => analytic_segments(scene, layer, pos, dir, t_boundary, rng.exponential()),
        Tracking::Delta { majorant_scale } => {
            let (flight, advanced) = delta(
                scene,
                layer,
                pos,
                dir,
                t_boundary,
                layer.majorant * majorant_scale,
                rng.clone(),
                null_collisions,
            );
            *rng = advanced;
            flight
        }
    }
}

#[inline(never)]
fn analytic_segments(scene: &Scene, layer: &Layer, pos: DVec3, dir: DVec3, t_boundary: f64, mut tau: f64) -> Flight {
    // Region intervals along the ray, clipped to [0, t_boundary], in priority order.
    let mut spans = [(0.0f64, 0.0f64, 0usize); MAX_REGIONS_PER_LAYER];
    let mut n_spans = 0;
    for &r in &layer.regions {
        let region = &scene.regions[r];
        if let Some((a, b)) = region.shape.intersect(pos, dir) {
            let (a, b) = (a.max(0.0), b.min(t_boundary));
            if b > a {
                spans[n_spans] = (a, b, region.medium);
                n_spans += 1;
            }
        }
    }
    if n_spans == 0 {
        let t = tau * scene.media[layer.medium].inv_sigma_t();
        return if t < t_boundary {
            Flight::Collision { t, medium: layer.medium }
        } else {
            Flight::Boundary { t: t_boundary }
        };
    }
    // Breakpoints: 0, every span end, t_boundary; sorted (insertion sort: a handful of entries).
    let mut cuts = [0.0f64; 2 * MAX_REGIONS_PER_LAYER + 2];
    let mut n_cuts = 0;
    for &(a, b, _) in &spans[..n_spans] {
        cuts[n_cuts] = a;
        cuts[n_cuts + 1] = b;
        n_cuts += 2;
    }
    cuts[n_cuts] = 0.0;
    cuts[n_cuts + 1] = t_boundary;
    n_cuts += 2;
    let cuts = &mut cuts[..n_cuts];
    for i in 1..cuts.len() {
        let mut j = i;
        while j > 0 && cuts[j - 1] > cuts[j] {
            cuts.swap(j - 1, j);
            j -= 1;
        }
    }
    for w in cuts.windows(2) {
        let (t0, t1) = (w[0], w[1]);
        if t1 <= t0 {
            continue;
        }
        let mid = 0.5 * (t0 + t1);
        let medium =
            spans[..n_spans].iter().find(|&&(a, b, _)| a <= mid && mid < b).map_or(layer.medium, |&(_, _, m)| m);
        let m = &scene.media[medium];
        let depth = m.sigma_t() * (t1 - t0);
        if tau < depth {
            return Flight::Collision { t: t0 + tau * m.inv_sigma_t(), medium };
        }
        tau -= depth;
    }
    Flight::Boundary { t: t_boundary }
}

#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn delta(
    scene: &Scene,
    layer: &Layer,
    pos: DVec3,
    dir: DVec3,
    t_boundary: f64,
    majorant: f64,
    mut rng: PathRng,
    null_collisions: &mut u64,
) -> (Flight, PathRng) {
    if majorant <= 0.0 {
        return (Flight::Boundary { t: t_boundary }, rng);
    }
    let inv = 1.0 / majorant;
    let mut t = 0.0;
    loop {
        t += rng.exponential() * inv;
        if t >= t_boundary {
            return (Flight::Boundary { t: t_boundary }, rng);
        }
        let medium = scene.medium_at(layer, pos + t * dir);
        if rng.uniform() * majorant < scene.media[medium].sigma_t() {
            return (Flight::Collision { t, medium }, rng);
        }
        *null_collisions += 1;
    }
}
