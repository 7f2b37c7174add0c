//! Phase functions: the angular distribution of scattered light, normalised to 1 over the sphere
//! (sr⁻¹). A closed set, dispatched by `match` on the per-collision path.

mod hg;
mod tabulated;

use std::sync::Arc;

pub use hg::HenyeyGreenstein;
pub use tabulated::TabulatedPhase;

/// A sampled deflection: the polar angle of `dir_out` about `dir_in`.
///
/// `one_minus_cos` is carried separately because forward-peaked media (blood, g ≈ 0.99) deflect by
/// milliradians, where `1 − cos θ` computed from `cos θ` would lose most of its digits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Deflection {
    /// `cos θ = dir_in · dir_out`.
    pub cos: f64,
    /// `1 − cos θ`, accurate for small angles.
    pub one_minus_cos: f64,
    /// `sin θ ≥ 0`.
    pub sin: f64,
}

impl Deflection {
    /// The deflection with the given `1 − cos θ` (in `[0, 2]`).
    #[inline(always)]
    pub fn from_one_minus_cos(m: f64) -> Self {
        let m = m.clamp(0.0, 2.0);
        Deflection { cos: 1.0 - m, one_minus_cos: m, sin: (m * (2.0 - m)).sqrt() }
    }
}

/// The phase functions a medium can have.
#[derive(Debug, Clone, PartialEq)]
pub enum PhaseFunction {
    /// `p = 1/(4π)`.
    Isotropic,
    /// Henyey–Greenstein with asymmetry `g ∈ (−1, 1)`.
    HenyeyGreenstein(HenyeyGreenstein),
    /// A table (Mie, measured), shared by every medium and thread that uses it.
    Tabulated(Arc<TabulatedPhase>),
}

impl PhaseFunction {
    /// Draw a deflection from one uniform number `u ∈ [0, 1)`.
    #[inline(always)]
    pub fn sample(&self, u: f64) -> Deflection {
        match self {
            PhaseFunction::Isotropic => Deflection::from_one_minus_cos(2.0 * (1.0 - u)),
            PhaseFunction::HenyeyGreenstein(hg) => hg.sample(u),
            PhaseFunction::Tabulated(t) => t.sample(u),
        }
    }

    /// The density (sr⁻¹) of the distribution [`sample`](Self::sample) draws from, at `cos θ`.
    #[inline]
    pub fn eval(&self, cos_theta: f64) -> f64 {
        match self {
            PhaseFunction::Isotropic => 1.0 / (4.0 * std::f64::consts::PI),
            PhaseFunction::HenyeyGreenstein(hg) => hg.eval(cos_theta),
            PhaseFunction::Tabulated(t) => t.eval(cos_theta),
        }
    }

    /// Mean cosine of the deflection.
    pub fn mean_cosine(&self) -> f64 {
        match self {
            PhaseFunction::Isotropic => 0.0,
            PhaseFunction::HenyeyGreenstein(hg) => hg.g(),
            PhaseFunction::Tabulated(t) => t.mean_cosine(),
        }
    }
}
