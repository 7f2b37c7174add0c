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
//! Both sample the same distance distribution (`tests/it/sampling.rs`). The analytic segments and
//! the heterogeneous tracker cut the ray into spans of one medium the same way ([`for_each_span`]).
//!
//! A layer whose medium or regions have a density field (`Layer::heterogeneous`) is tracked by
//! [`heterogeneous`]: the ray is cut into spans of one medium; a homogeneous span is one segment
//! with majorant σt (so it never makes a null collision, unless `Tracking::Delta` inflates it),
//! a span of a density medium is cut further into its majorant segments (DDA through the
//! majorant grid, or the ramp's pieces), and delta tracking runs segment by segment: one
//! exponential optical depth per tentative collision, consumed across segments at their own
//! majorants (pbrt-v4's `SampleT_maj`, §14.2; Woodcock et al. 1965). The loop over a density
//! span is generic over the field type ([`Field`]), so each is compiled on its own after one
//! `match` per span; homogeneous layers never reach it.
//!
//! Transmittance along a shadow ray through such a layer is estimated by residual ratio tracking
//! ([`ratio_transmittance`]; Novák, Selle & Jarosz 2014) with the segment's lower bound as the
//! control: `T = Π_segments exp(−σc·ℓ) · Π_tentative (1 − (σt(x) − σc)/(σ̄ − σc))`.

use std::ops::ControlFlow;

use glam::DVec3;

use crate::medium::density::{Density, Field};
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

/// The ray `pos + t·dir` through `layer` of `scene`: what every tracker of this module follows
/// (small and `Copy`; the trackers are inlined or outlined per call frequency, see
/// `DESIGN.md`).
#[derive(Debug, Clone, Copy)]
pub struct LayerRay<'a> {
    pub scene: &'a Scene,
    pub layer: &'a Layer,
    pub pos: DVec3,
    pub dir: DVec3,
}

/// What delta tracking carries from one majorant segment to the next: the optical depth `tau`
/// left to the next tentative collision, the generator (by value, see `PathRng`) and the count of
/// null collisions.
struct DeltaState {
    tau: f64,
    rng: PathRng,
    nulls: u64,
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

/// Sample the next real collision along `ray` (`pos + t·dir` in `layer`), before the boundary plane that
/// lies `dz ≥ 0` away along z (in the direction of travel), with `abs_dir_z = |dir.z|`.
/// `null_collisions` counts the rejected tentative collisions of delta tracking.
///
/// The homogeneous case compares `t·|dir.z| < dz`, so the division giving the distance to the
/// boundary is only done when the boundary is reached.
#[inline(always)]
pub fn free_flight(
    ray: LayerRay,
    dz: f64,
    abs_dir_z: f64,
    tracking: Tracking,
    rng: &mut PathRng,
    null_collisions: &mut u64,
) -> Flight {
    let LayerRay { scene, layer, .. } = ray;
    if !layer.heterogeneous && layer.regions.is_empty() {
        let t = rng.exponential() * scene.media[layer.medium].inv_sigma_t();
        return if t * abs_dir_z < dz {
            Flight::Collision { t, medium: layer.medium }
        } else {
            Flight::Boundary { t: dz / abs_dir_z }
        };
    }
    free_flight_to(ray, dz / abs_dir_z, tracking, rng, null_collisions)
}

/// [`free_flight`] to a boundary `t_boundary` away along the ray (the nearer of the plane ahead
/// and a side face of a box phantom, [`crate::medium::Lateral`]).
#[inline(always)]
pub fn free_flight_to(
    ray: LayerRay,
    t_boundary: f64,
    tracking: Tracking,
    rng: &mut PathRng,
    null_collisions: &mut u64,
) -> Flight {
    let LayerRay { scene, layer, .. } = ray;
    if layer.heterogeneous {
        let scale = match tracking {
            Tracking::Analytic => 1.0,
            Tracking::Delta { majorant_scale } => majorant_scale,
        };
        let (flight, advanced) = heterogeneous(&ray, t_boundary, scale, rng.clone(), null_collisions);
        *rng = advanced;
        return flight;
    }
    if layer.regions.is_empty() {
        let t = rng.exponential() * scene.media[layer.medium].inv_sigma_t();
        return if t < t_boundary {
            Flight::Collision { t, medium: layer.medium }
        } else {
            Flight::Boundary { t: t_boundary }
        };
    }
    // The outlined trackers never see `rng` itself (see `PathRng`): the analytic one needs one
    // optical depth, drawn here, and delta tracking works on the generator passed by value.
    match tracking {
        Tracking::Analytic => analytic_segments(&ray, t_boundary, rng.exponential()),
        Tracking::Delta { majorant_scale } => {
            let (flight, advanced) =
                delta(&ray, t_boundary, layer.majorant * majorant_scale, rng.clone(), null_collisions);
            *rng = advanced;
            flight
        }
    }
}

#[inline(never)]
fn analytic_segments(ray: &LayerRay, t_boundary: f64, mut tau: f64) -> Flight {
    // Invert the optical depth across the spans of constant σt.
    let LayerRay { scene, layer, pos, dir } = *ray;
    let hit = for_each_span(scene, layer, pos, dir, t_boundary, |t0, t1, medium| {
        let m = &scene.media[medium];
        let depth = m.sigma_t() * (t1 - t0);
        if tau < depth {
            return ControlFlow::Break(Flight::Collision { t: t0 + tau * m.inv_sigma_t(), medium });
        }
        tau -= depth;
        ControlFlow::Continue(())
    });
    hit.unwrap_or(Flight::Boundary { t: t_boundary })
}

#[inline(never)]
fn delta(
    ray: &LayerRay,
    t_boundary: f64,
    majorant: f64,
    mut rng: PathRng,
    null_collisions: &mut u64,
) -> (Flight, PathRng) {
    if majorant <= 0.0 {
        return (Flight::Boundary { t: t_boundary }, rng);
    }
    let LayerRay { scene, layer, pos, dir } = *ray;
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

/// Most spans of one medium a ray can cross in a layer.
const MAX_SPANS: usize = 2 * MAX_REGIONS_PER_LAYER + 1;

/// Call `f(t0, t1, medium)` for the spans of [`spans`] in order, until it breaks. A layer without
/// regions is one span; a layer with one region (the usual heterogeneous scene: a grid in a box)
/// needs no span buffer either: at most three spans, computed from the one intersection. (The
/// buffer of [`spans`], 33 entries, was 6 % of the profile of `validation/vdb/vessels_bench.toml`
/// in copies and fills alone.)
#[inline(always)]
fn for_each_span<B>(
    scene: &Scene,
    layer: &Layer,
    pos: DVec3,
    dir: DVec3,
    t_end: f64,
    mut f: impl FnMut(f64, f64, usize) -> ControlFlow<B>,
) -> Option<B> {
    // A layer without regions (a density medium filling a layer) is one span: no intersections
    // and no buffer (`spans` filled and copied its 33 entries on every free flight: `memset` and
    // `memcpy` alone were 19 % of the instructions of a constant-density van de Hulst slab).
    if layer.regions.is_empty() {
        return match f(0.0, t_end, layer.medium) {
            ControlFlow::Break(x) => Some(x),
            ControlFlow::Continue(()) => None,
        };
    }
    if let [r] = layer.regions[..] {
        let region = &scene.regions[r];
        let (a, b) = region.shape.intersect(pos, dir).map_or((t_end, t_end), |(a, b)| (a.max(0.0), b.min(t_end)));
        if b > a && region.medium != layer.medium {
            for (t0, t1, m) in [(0.0, a, layer.medium), (a, b, region.medium), (b, t_end, layer.medium)] {
                if t1 > t0
                    && let ControlFlow::Break(x) = f(t0, t1, m)
                {
                    return Some(x);
                }
            }
            return None;
        }
        return match f(0.0, t_end, layer.medium) {
            ControlFlow::Break(x) => Some(x),
            ControlFlow::Continue(()) => None,
        };
    }
    let (spans, n) = spans(scene, layer, pos, dir, t_end);
    for &(t0, t1, m) in &spans[..n] {
        if let ControlFlow::Break(x) = f(t0, t1, m) {
            return Some(x);
        }
    }
    None
}

/// The ray `pos + t·dir`, `0 ≤ t ≤ t_end`, in `layer` cut into consecutive spans of one medium
/// (`(t0, t1, medium)`, in order; regions listed first win where they overlap).
fn spans(scene: &Scene, layer: &Layer, pos: DVec3, dir: DVec3, t_end: f64) -> ([(f64, f64, usize); MAX_SPANS], usize) {
    let mut out = [(0.0, 0.0, 0usize); MAX_SPANS];
    let mut hits = [(0.0f64, 0.0f64, 0usize); MAX_REGIONS_PER_LAYER];
    let mut n_hits = 0;
    for &r in &layer.regions {
        let region = &scene.regions[r];
        if let Some((a, b)) = region.shape.intersect(pos, dir) {
            let (a, b) = (a.max(0.0), b.min(t_end));
            if b > a {
                hits[n_hits] = (a, b, region.medium);
                n_hits += 1;
            }
        }
    }
    if n_hits == 0 {
        out[0] = (0.0, t_end, layer.medium);
        return (out, 1);
    }
    let mut cuts = [0.0f64; 2 * MAX_REGIONS_PER_LAYER + 2];
    let mut n_cuts = 0;
    for &(a, b, _) in &hits[..n_hits] {
        cuts[n_cuts] = a;
        cuts[n_cuts + 1] = b;
        n_cuts += 2;
    }
    cuts[n_cuts] = 0.0;
    cuts[n_cuts + 1] = t_end;
    n_cuts += 2;
    let cuts = &mut cuts[..n_cuts];
    cuts.sort_unstable_by(f64::total_cmp);
    let mut n = 0;
    for w in cuts.windows(2) {
        let (t0, t1) = (w[0], w[1]);
        if t1 <= t0 {
            continue;
        }
        // The midpoint of an infinite piece is infinite: its medium is the one just past t0.
        let mid = if t1.is_finite() { 0.5 * (t0 + t1) } else { t0 + 1.0 };
        let medium = hits[..n_hits].iter().find(|&&(a, b, _)| a <= mid && mid < b).map_or(layer.medium, |h| h.2);
        if n > 0 && out[n - 1].2 == medium {
            out[n - 1].1 = t1;
        } else {
            out[n] = (t0, t1, medium);
            n += 1;
        }
    }
    (out, n)
}

/// Delta tracking over majorant segments through a layer with density media (see the module
/// docs); `scale ≥ 1` inflates every majorant. Gets the generator by value (see `PathRng`).
#[inline(never)]
fn heterogeneous(
    ray: &LayerRay,
    t_boundary: f64,
    scale: f64,
    mut rng: PathRng,
    null_collisions: &mut u64,
) -> (Flight, PathRng) {
    let mut st = DeltaState { tau: rng.exponential(), rng, nulls: 0 };
    let hit = for_each_span(ray.scene, ray.layer, ray.pos, ray.dir, t_boundary, |a, b, medium| {
        let m = &ray.scene.media[medium];
        let sigma_t = m.sigma_t();
        let hit = match m.density() {
            None => constant_segment(sigma_t, sigma_t * scale, a, b, &mut st),
            Some(Density::Ramp(f)) => delta_field(f, sigma_t, scale, ray, (a, b), &mut st),
            Some(Density::Grid(f)) => delta_field(f, sigma_t, scale, ray, (a, b), &mut st),
        };
        match hit {
            Some(t) => ControlFlow::Break(Flight::Collision { t, medium }),
            None => ControlFlow::Continue(()),
        }
    });
    *null_collisions += st.nulls;
    (hit.unwrap_or(Flight::Boundary { t: t_boundary }), st.rng)
}

/// Delta tracking on `[t0, t1)` where σt is the constant `sigma_t` and the majorant `majorant`
/// (≥ σt), with the optical depth `st.tau` left from earlier segments (at their majorants).
/// `Some` distance of a real collision, else `st.tau` is what is left past `t1`.
#[inline(always)]
fn constant_segment(sigma_t: f64, majorant: f64, mut t0: f64, t1: f64, st: &mut DeltaState) -> Option<f64> {
    if majorant <= 0.0 {
        return None;
    }
    let DeltaState { tau, rng, nulls } = st;
    loop {
        let depth = majorant * (t1 - t0);
        if *tau >= depth {
            *tau -= depth;
            return None;
        }
        let t = t0 + *tau / majorant;
        // A majorant equal to σt accepts every tentative collision: no draw.
        if majorant <= sigma_t || rng.uniform() * majorant < sigma_t {
            return Some(t);
        }
        *nulls += 1;
        t0 = t;
        *tau = rng.exponential();
    }
}

/// Delta tracking through a density field `f` scaling σt, over its majorant segments of
/// the span `[a, b)` of `ray`, majorants inflated by `scale`. Compiled per field type.
#[inline(always)]
fn delta_field<F: Field>(
    f: &F,
    sigma_t: f64,
    scale: f64,
    ray: &LayerRay,
    (a, b): (f64, f64),
    st: &mut DeltaState,
) -> Option<f64> {
    let (pos, dir) = (ray.pos, ray.dir);
    let DeltaState { tau, rng, nulls } = st;
    for seg in f.segments(pos, dir, a, b) {
        let majorant = seg.max * sigma_t * scale;
        if majorant <= 0.0 {
            continue;
        }
        // Where the segment's lower bound reaches its majorant every tentative collision is
        // real: no lookup, no draw.
        let certain = seg.min * sigma_t >= majorant;
        let mut t0 = seg.t0;
        loop {
            let depth = majorant * (seg.t1 - t0);
            if *tau >= depth {
                *tau -= depth;
                break;
            }
            let t = t0 + *tau / majorant;
            if certain || rng.uniform() * majorant < sigma_t * f.density(pos + t * dir) {
                return Some(t);
            }
            *nulls += 1;
            t0 = t;
            *tau = rng.exponential();
        }
    }
    None
}

/// Where a forward path's layered twin parted from it along a [`coupled_flight`]: at distance
/// `t`, colliding there (`collides`, the path flew on) or flying on (the path collided), with the
/// generator as it was there (the twin walks on with it: common random numbers).
#[derive(Clone)]
pub struct Parting {
    pub t: f64,
    pub collides: bool,
    pub rng: PathRng,
}

/// The free flight of a forward path and of its layered twin together through a layer whose
/// regions may hold density fields (the twin's scene has the layer's filling medium, of σt
/// `fill`, in their place; a filling medium of its own density is refused with the control
/// variate). Both are delta-tracked on one Poisson process of tentative collisions, at each
/// region segment's majorant raised to at least `fill`, and one uniform `u` decides each
/// tentative collision for both: real for the path if `u·σ̄ < σt(x)`, for the twin if
/// `u·σ̄ < fill`. Each is thus its own scene's exact flight, with no likelihood ratio; they
/// share the flight while they agree (a collision of both is the coupled collision of
/// `collide_nee`), and part at the first tentative collision where they do not ([`Parting`]):
/// from there the path flies on alone. Outside the regions they agree by construction.
/// (A likelihood ratio over the null collisions, `(1 − fill/σ̄)/(1 − σt(x)/σ̄)`, instead has no
/// bound where the grid's majorant is tight, and none at all for a clear filling medium, whose
/// twin never collides: `vessels_ldh`.)
#[inline(never)]
pub fn coupled_flight(
    ray: &LayerRay,
    t_boundary: f64,
    fill: f64,
    rng: &mut PathRng,
    null_collisions: &mut u64,
) -> (Flight, Option<Parting>) {
    let mut st = CoupledState { tau: rng.exponential(), rng: rng.clone(), nulls: 0, fill, parting: None };
    let hit = for_each_span(ray.scene, ray.layer, ray.pos, ray.dir, t_boundary, |a, b, medium| {
        let m = &ray.scene.media[medium];
        let region = medium != ray.layer.medium;
        let sigma_t = m.sigma_t();
        let hit = match m.density() {
            None => st.segment(sigma_t, a, b, region, |_| sigma_t),
            Some(Density::Ramp(f)) => coupled_field(f, sigma_t, ray, (a, b), region, &mut st),
            Some(Density::Grid(f)) => coupled_field(f, sigma_t, ray, (a, b), region, &mut st),
        };
        match hit {
            Some(t) => ControlFlow::Break(Flight::Collision { t, medium }),
            None => ControlFlow::Continue(()),
        }
    });
    *null_collisions += st.nulls;
    *rng = st.rng;
    (hit.unwrap_or(Flight::Boundary { t: t_boundary }), st.parting)
}

/// [`DeltaState`] of a [`coupled_flight`]: the twin's σt and where it parted.
struct CoupledState {
    tau: f64,
    rng: PathRng,
    nulls: u64,
    fill: f64,
    parting: Option<Parting>,
}

impl CoupledState {
    /// Delta tracking on `[t0, t1)` at the majorant `majorant` (raised to the twin's σt in a
    /// region while the twin is coupled), σt at distance `t` being `sigma(t)`. `Some` distance of
    /// the path's real collision, else the optical depth left is in `self.tau`.
    #[inline(always)]
    fn segment(
        &mut self,
        majorant: f64,
        mut t0: f64,
        t1: f64,
        region: bool,
        sigma: impl Fn(f64) -> f64,
    ) -> Option<f64> {
        let coupled = region && self.parting.is_none();
        let majorant = if coupled { majorant.max(self.fill) } else { majorant };
        if majorant <= 0.0 {
            return None;
        }
        loop {
            let depth = majorant * (t1 - t0);
            if self.tau >= depth {
                self.tau -= depth;
                return None;
            }
            let t = t0 + self.tau / majorant;
            let u = self.rng.uniform() * majorant;
            let real = u < sigma(t);
            if coupled && self.parting.is_none() && real != (u < self.fill) {
                self.parting = Some(Parting { t, collides: !real, rng: self.rng.clone() });
            }
            if real {
                return Some(t);
            }
            self.nulls += 1;
            t0 = t;
            self.tau = self.rng.exponential();
        }
    }
}

/// [`CoupledState::segment`] over the majorant segments of a density field `f` scaling σt on the
/// span `[a, b)` of `ray`.
#[inline(always)]
fn coupled_field<F: Field>(
    f: &F,
    sigma_t: f64,
    ray: &LayerRay,
    (a, b): (f64, f64),
    region: bool,
    st: &mut CoupledState,
) -> Option<f64> {
    let (pos, dir) = (ray.pos, ray.dir);
    for seg in f.segments(pos, dir, a, b) {
        if let Some(t) = st.segment(seg.max * sigma_t, seg.t0, seg.t1, region, |t| sigma_t * f.density(pos + t * dir)) {
            return Some(t);
        }
    }
    None
}

/// Transmittance of the straight segment `pos + s·dir`, `0 ≤ s ≤ t`, through `layer`: exact
/// `exp(−σt·ℓ)` over homogeneous spans, residual ratio tracking (Novák et al. 2014) over density
/// spans, with the segment bounds `[σc, σ̄]` of the majorant segments: `exp(−σc·ℓ)` analytically
/// and a factor `1 − (σt(x) − σc)/(σ̄ − σc) ∈ [0, 1]` per tentative collision at rate `σ̄ − σc`.
/// Unbiased; where a segment's bounds meet (constant cells) it is exact and draws nothing.
pub fn ratio_transmittance(scene: &Scene, layer: &Layer, pos: DVec3, dir: DVec3, t: f64, rng: &mut PathRng) -> f64 {
    let mut tau = 0.0;
    let mut tr = 1.0;
    let blocked = for_each_span(scene, layer, pos, dir, t, |a, b, medium| {
        let m = &scene.media[medium];
        let sigma_t = m.sigma_t();
        match m.density() {
            None => tau += sigma_t * (b - a),
            Some(Density::Ramp(f)) => tr *= ratio_field(f, sigma_t, pos, dir, (a, b), &mut tau, rng),
            Some(Density::Grid(f)) => tr *= ratio_field(f, sigma_t, pos, dir, (a, b), &mut tau, rng),
        }
        if tr <= 0.0 { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
    });
    if blocked.is_some() {
        return 0.0;
    }
    tr * (-tau).exp()
}

/// The ratio-tracking factor of a density span (the control's optical depth is added to `tau`).
#[inline(always)]
fn ratio_field<F: Field>(
    f: &F,
    sigma_t: f64,
    pos: DVec3,
    dir: DVec3,
    (a, b): (f64, f64),
    tau: &mut f64,
    rng: &mut PathRng,
) -> f64 {
    let mut tr = 1.0;
    for seg in f.segments(pos, dir, a, b) {
        let control = seg.min * sigma_t;
        *tau += control * (seg.t1 - seg.t0);
        let residual = (seg.max - seg.min) * sigma_t;
        if residual <= 0.0 {
            continue;
        }
        let inv = 1.0 / residual;
        let mut s = seg.t0;
        loop {
            s += rng.exponential() * inv;
            if s >= seg.t1 {
                break;
            }
            tr *= 1.0 - (sigma_t * f.density(pos + s * dir) - control) * inv;
            if tr <= 0.0 {
                return 0.0;
            }
        }
    }
    tr
}
