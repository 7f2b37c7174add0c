//! Errors of the Mie solver and the ensemble integrator. Every message states the offending value and
//! the accepted range.

use super::limits::{K_MAX, MX_MAX, N_MAX, N_MIN, X_MAX, X_MIN};

/// Invalid input to [`MieSolution::new`](super::MieSolution::new) or
/// [`ensemble_optics`](super::ensemble_optics).
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum MieError {
    /// Size parameter `x = 2π r n_medium / λ0` not finite or outside `[X_MIN, X_MAX]`.
    #[error("size parameter x = {x:e} is out of range: expected a finite value in [{X_MIN:e}, {X_MAX:e}]")]
    SizeParameter { x: f64 },
    /// Real part of the relative refractive index not finite or outside `[N_MIN, N_MAX]`.
    #[error(
        "real part of the relative refractive index n = {n:e} is out of range: expected finite, {N_MIN:e} ≤ n ≤ {N_MAX}"
    )]
    RealIndex { n: f64 },
    /// Imaginary part (absorption, `m = n − ik`) not finite or outside `[0, K_MAX]`.
    #[error(
        "imaginary part of the relative refractive index k = {k} is out of range: expected finite, \
         0 ≤ k ≤ {K_MAX} (m = n − ik, k ≥ 0 absorbs)"
    )]
    ImagIndex { k: f64 },
    /// `|m|·x` so large that the downward recurrence for the logarithmic derivative would take
    /// more than `MX_MAX` steps.
    #[error("|m|·x = {m_x:e} exceeds the limit {MX_MAX:e} (too many terms for the logarithmic-derivative recurrence)")]
    TooManyTerms { m_x: f64 },
    /// A scalar input of the ensemble out of its range (lengths in metres).
    #[error("{name} = {value:e} is out of range: expected {expected}")]
    Parameter { name: &'static str, value: f64, expected: &'static str },
    /// A size range whose lower bound is not below its upper bound.
    #[error("{name}: lower bound {min:e} m must be below upper bound {max:e} m")]
    Range { name: &'static str, min: f64, max: f64 },
    /// A concentration that is missing, superfluous or inconsistent.
    #[error("concentration: {0}")]
    Concentration(String),
    /// A size distribution with no particles inside its size range (its density underflows there).
    #[error("size distribution: {0}")]
    EmptyDistribution(String),
}
