//! A real scattering event's kinematics: the new direction about the old (rotated by the
//! deflection, keeping `dir_in − dir_out` to full relative precision), the periodic
//! renormalisation of the direction, the particle's velocity and the event's Doppler and Brownian
//! terms.

use glam::DVec3;

use crate::detect::PathState;
use crate::medium::Population;
use crate::phase::Deflection;
use crate::sampling::{PathRng, warp};

/// Rotate `dir` by the deflection `d` at azimuth `(cos φ, sin φ)`.
///
/// Returns the new direction and `dir_in − dir_out`, computed directly as
/// `(1 − cos θ)·dir_in − sin θ·(cos φ t + sin φ b)` so that it keeps its relative precision for
/// the milliradian deflections of forward-peaked media (a difference of two nearly equal unit
/// vectors would not).
///
/// The new direction is as unit as `dir` up to rounding, not renormalised: rounding makes
/// `|dir|² − 1` drift by a few 1e-16 per event, which the walk removes every
/// [`RENORMALISE_EVERY`] events with [`renormalise`].
///
/// `(t, b)` is the basis of [`warp::orthonormal_basis`] (Duff et al. 2017), but not built: with
/// `s = sign(dir.z)`, `a = −1/(s + dir.z)`, `c = sin θ cos φ`, `c′ = sin θ sin φ` and
/// `w = s·c·x + c′·y`, its terms collect into
/// `sin θ·(cos φ t + sin φ b) = (c + a·x·w, s·c′ + a·y·w, −w)`, about half the arithmetic of
/// forming `t` and `b` (measured: 131 → 118 instructions per collision).
#[inline(always)]
pub fn scatter_direction(dir: DVec3, d: Deflection, cos_phi: f64, sin_phi: f64) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(dir.z);
    let a = -1.0 / (sign + dir.z);
    let (c, c_prime) = (d.sin * cos_phi, d.sin * sin_phi);
    let w = sign * c * dir.x + c_prime * dir.y;
    let aw = a * w;
    let perp_sin = DVec3::new(c + aw * dir.x, sign * c_prime + aw * dir.y, -w);
    (dir * d.cos + perp_sin, dir * d.one_minus_cos - perp_sin)
}

/// How many scattering events the walk lets pass between renormalisations of the direction.
///
/// Renormalising after every event cost 14 instructions per collision (callgrind, 4% of a van
/// de Hulst path). Without it, `||dir|² − 1|` measured over 2·10⁷ events stays below 1e-14 for
/// |g| ≤ 0.99 and reaches 1e-12 for g = 0.999999 (tiny deflections let the rounding errors
/// accumulate); renormalising every 32 events bounds it by the drift of 32 events (test
/// `direction_stays_unit_over_many_events`).
pub const RENORMALISE_EVERY: u32 = 32;

/// One Newton step towards `|dir| = 1`, for a `dir` whose length is already 1 up to rounding.
#[inline(always)]
pub fn renormalise(dir: DVec3) -> DVec3 {
    dir * (1.5 - 0.5 * dir.length_squared())
}

/// Change of `dl/dt` at a real scattering event on a particle of velocity `v` in a medium of index
/// `n`, given `dir_in − dir_out`: `n · v · (dir_in − dir_out)` (positive = path lengthening).
#[inline(always)]
pub fn doppler_increment(n: f64, v: DVec3, dir_in_minus_out: DVec3) -> f64 {
    n * v.dot(dir_in_minus_out)
}

/// A scattering event on a particle of velocity `v` with `dir_in − dir_out = delta`: the Doppler
/// term, the Brownian `q²D` term and the event count. The scattering vector is
/// `q = (2πn/λ0)·delta`, so `D·q² = (2π/λ0)²·D n²|delta|²` and only the wavelength-free part is
/// carried.
#[inline(always)]
pub(super) fn doppler_event(s: &mut PathState, m: &Population, n: f64, v: DVec3, delta: DVec3) {
    s.dldt += doppler_increment(n, v, delta);
    if m.motion.diffusion > 0.0 {
        s.brownian += m.motion.diffusion * n * n * delta.length_squared();
    }
    s.doppler_events += 1;
}

/// A new direction about `dir` drawn from `phase` (its deflection, then the azimuth): the
/// deflection, the direction and `dir − out` ([`scatter_direction`]).
#[inline(always)]
pub(super) fn deflect(
    dir: DVec3,
    phase: &crate::phase::PhaseFunction,
    rng: &mut PathRng,
) -> (Deflection, DVec3, DVec3) {
    let d = phase.sample(rng.uniform());
    let (cos_phi, sin_phi) = warp::azimuth_i32(|| rng.pair_i32());
    let (out, delta) = scatter_direction(dir, d, cos_phi, sin_phi);
    (d, out, delta)
}

/// The particle a path scatters on at a real collision: its population, whether it moves (never
/// where the walk does not track the Doppler term) and its velocity then. (A flag and a vector, not
/// an `Option`: held as an `Option<DVec3>` through the shadow rays' loop it cost fmcw_target's
/// collisions 28 instructions each, callgrind.)
#[derive(Clone, Copy)]
pub(super) struct Particle<'a> {
    pub pop: &'a Population,
    pub moving: bool,
    pub v: DVec3,
}

impl<'a> Particle<'a> {
    /// A particle of the medium `m` at `pos`: a population by the medium's shares, then its
    /// velocity if it moves (and `DOPPLER`).
    #[inline(always)]
    pub fn pick<const DOPPLER: bool>(m: &'a crate::medium::Medium, pos: DVec3, rng: &mut PathRng) -> Self {
        let (pop, dynamic) = m.pick_dynamic(rng);
        let moving = DOPPLER && dynamic;
        let v = if moving { particle_velocity(pop, pos, rng) } else { DVec3::ZERO };
        Particle { pop, moving, v }
    }

    /// [`Particle::pick`] with the particle's velocity apart: its flow (the field's cycle-mean
    /// velocity) and its random velocity (the dispersion's draw), whose sum is the particle's
    /// `v` as [`Particle::pick`] draws it (the same numbers in the same order), for the harmonics
    /// of a pulsatile scene ([`crate::flow::pulse::Pulse::event`]).
    #[inline(always)]
    pub fn pick_parts(m: &'a crate::medium::Medium, pos: DVec3, rng: &mut PathRng) -> (Self, DVec3, DVec3) {
        let (pop, moving) = m.pick_dynamic(rng);
        if !moving {
            return (Particle { pop, moving, v: DVec3::ZERO }, DVec3::ZERO, DVec3::ZERO);
        }
        let flow = pop.velocity.velocity(pos, rng);
        let sd = pop.motion.dispersion;
        let random = if sd > 0.0 { sd * DVec3::new(rng.normal(), rng.normal(), rng.normal()) } else { DVec3::ZERO };
        let v = if sd > 0.0 { flow + random } else { flow };
        (Particle { pop, moving, v }, flow, random)
    }

    /// The event's Doppler and Brownian terms on `s`, in a layer of index `n`, for
    /// `dir_in − dir_out = delta` ([`doppler_event`]); nothing if the particle does not move.
    #[inline(always)]
    pub fn event(&self, s: &mut PathState, n: f64, delta: DVec3) {
        if self.moving {
            doppler_event(s, self.pop, n, self.v, delta);
        }
    }
}

/// The velocity of the particle a path scatters on at `p`: the flow plus, for a medium with a
/// velocity dispersion, a Gaussian random velocity drawn for this event.
#[inline(always)]
pub(super) fn particle_velocity(m: &Population, p: DVec3, rng: &mut PathRng) -> DVec3 {
    let mut v = m.velocity.velocity(p, rng);
    let sd = m.motion.dispersion;
    if sd > 0.0 {
        v += sd * DVec3::new(rng.normal(), rng.normal(), rng.normal());
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::{HenyeyGreenstein, PhaseFunction};
    use crate::sampling::Purpose;

    #[test]
    fn scattering_matches_the_explicit_basis() {
        // The collected form equals sin θ·(cos φ t + sin φ b) with the basis built, to rounding,
        // for directions in every octant and at the poles, and deflections down to 1e-9 rad,
        // where `dir_in − dir_out` must keep its relative precision.
        let mut rng = PathRng::new(6, Purpose::Test, 0, 0);
        let mut dirs = vec![DVec3::Z, -DVec3::Z, DVec3::X, DVec3::new(1e-9, 0.0, -1.0).normalize()];
        for _ in 0..2000 {
            dirs.push(warp::uniform_sphere(rng.uniform(), rng.uniform()));
        }
        for dir in dirs {
            for theta in [1e-9, 1e-4, 0.3, 2.0, 3.1] {
                let d = Deflection {
                    cos: f64::cos(theta),
                    one_minus_cos: 2.0 * (0.5 * theta).sin().powi(2),
                    sin: theta.sin(),
                };
                let (cos_phi, sin_phi) = warp::azimuth_i32(|| rng.pair_i32());
                let (out, delta) = scatter_direction(dir, d, cos_phi, sin_phi);
                let (t, b) = warp::orthonormal_basis(dir);
                let perp = t * cos_phi + b * sin_phi;
                let (out_ref, delta_ref) = (dir * d.cos + perp * d.sin, dir * d.one_minus_cos - perp * d.sin);
                assert!((out - out_ref).length() < 1e-15, "{dir} θ={theta}: {out} vs {out_ref}");
                assert!((delta - delta_ref).length() <= 1e-15 * delta_ref.length(), "{dir} θ={theta}");
                assert!((out.length() - 1.0).abs() < 1e-15 && (out.dot(dir) - d.cos).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn direction_stays_unit_over_many_events() {
        // The walk's sequence of rotations and periodic renormalisations, 10⁶ events per g.
        for &g in &[0.0, 0.75, -0.9, 0.99, 0.999999] {
            let phase = PhaseFunction::HenyeyGreenstein(HenyeyGreenstein::new(g).unwrap());
            let mut rng = PathRng::new(5, Purpose::Test, 0, 0);
            let mut dir = DVec3::new(0.3, -0.5, 0.7).normalize();
            let mut worst = 0.0f64;
            for order in 1..=1_000_000u32 {
                let d = phase.sample(rng.uniform());
                let (cos_phi, sin_phi) = warp::azimuth_i32(|| rng.pair_i32());
                dir = scatter_direction(dir, d, cos_phi, sin_phi).0;
                if order % RENORMALISE_EVERY == 0 {
                    dir = renormalise(dir);
                }
                worst = worst.max((dir.length_squared() - 1.0).abs());
            }
            assert!(worst < 1e-14, "g = {g}: ||dir|² − 1| reached {worst:e}");
        }
    }
}
