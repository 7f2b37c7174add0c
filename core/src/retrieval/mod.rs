//! Per-range-gate estimators for a coherent Doppler wind lidar: what is read off one gate's
//! spectrum, and the wind vector read off several gates' radial velocities; and the range and
//! velocity of an FMCW target.
//!
//! * [`gate`]: spectral moments of one gate — total and signal power, peak (sub-bin interpolated),
//!   centroid, width, FWHM and the narrowband SNR ([`gate_estimates`]).
//! * [`fit`]: one- or two-Gaussian fits of a gate spectrum on a floor by weighted
//!   Levenberg–Marquardt, and the F-test that chooses between them ([`fit_one_or_two`]), as Wei et
//!   al. 2019 (Opt. Express 27:31235) separate aerosol and rain.
//! * [`fmcw`]: range and radial velocity of an FMCW target from its up- and down-chirp spectra
//!   (peaks and centroids), with the range and velocity one frequency bin spans
//!   ([`fmcw_estimates`]).
//! * [`lidar`]: what is read off one gate of a pulsed lidar receiver's range–Doppler spectra —
//!   the moments and the one- or two-component fit on the shot-noise floor, through the gate's
//!   spectral kernel or as plain Gaussians ([`retrieve_gate`]).
//! * [`vad`]: velocity–azimuth display — the least-squares wind vector from radial velocities
//!   along several pointings, with its covariance and the horizontal speed and direction
//!   ([`vad_fit`]).
//!
//! Conventions are the crate's: SI units, `f64`, spectra as power per bin on an ascending
//! [`FrequencyAxis`](crate::spectrum::FrequencyAxis), and the Doppler sign *positive = receding*:
//! a beat frequency `f` is the radial velocity `v_r = λ0·f/2` along the pointing unit vector `d̂`
//! (away from the lidar), so a wind `V` gives `v_r = d̂·V` ([`radial_velocity`]).
//!
//! Nothing here panics on bad input: every entry point returns [`RetrievalError`].

pub mod fit;
pub mod fmcw;
pub mod gate;
pub mod lidar;
mod linalg;
mod special;
pub mod vad;

pub use fit::{
    FitOptions, Floor, GateKernel, GaussComponent, GaussianFit, ModelChoice, OneFit, fit_gaussians,
    fit_gaussians_with_kernel, fit_one_first, fit_one_or_two, fit_one_or_two_with_kernel,
};
pub use fmcw::{FmcwEstimate, fmcw_estimates};
pub use gate::{GateEstimate, MomentOptions, gate_estimates, gate_estimates_with};
pub use lidar::{FIT_SELECTION_LEVEL, GateRetrieval, LineShape, retrieve_gate};
pub use vad::{VadFit, pointing, vad_fit};

/// Why a retrieval could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RetrievalError {
    /// Two inputs that must have the same length do not.
    #[error("{what}: expected {expected} values, got {found}")]
    LengthMismatch { what: &'static str, expected: usize, found: usize },
    /// A NaN or infinite input.
    #[error("{what}: non-finite value at index {index}")]
    NonFinite { what: &'static str, index: usize },
    /// A parameter outside its valid range.
    #[error("{name} = {value}: expected {expected}")]
    InvalidParameter { name: &'static str, value: f64, expected: &'static str },
    /// Fewer data points than the estimate needs.
    #[error("too few points: {needed} needed, {found} given")]
    TooFewPoints { needed: usize, found: usize },
    /// The data do not determine every parameter: the normal matrix is singular or too badly
    /// conditioned (its condition number is reported; `∞` when exactly singular).
    #[error("degenerate problem: {what} (condition number of the normal matrix {condition:.3e})")]
    Degenerate { what: &'static str, condition: f64 },
    /// No bin rises above the noise floor.
    #[error("no signal: no bin exceeds the noise floor")]
    NoSignal,
    /// An iterative fit hit its iteration cap before its stopping rules were met.
    #[error("the fit did not converge in {iterations} iterations")]
    DidNotConverge { iterations: usize },
}

/// Radial velocity (m/s, positive receding) of a beat frequency `f_hz` at vacuum wavelength
/// `wavelength_m`: `v_r = λ0·f/2` (the round trip doubles the Doppler shift).
pub fn radial_velocity(f_hz: f64, wavelength_m: f64) -> f64 {
    0.5 * wavelength_m * f_hz
}

/// Beat frequency (Hz) of a radial velocity (m/s, positive receding): `f = 2·v_r/λ0`.
pub fn doppler_frequency(v_m_per_s: f64, wavelength_m: f64) -> f64 {
    2.0 * v_m_per_s / wavelength_m
}

/// `Ok` when every value is finite, else [`RetrievalError::NonFinite`] at the first bad index.
fn check_finite(what: &'static str, values: &[f64]) -> Result<(), RetrievalError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(RetrievalError::NonFinite { what, index }),
        None => Ok(()),
    }
}

/// `Ok` when `values` has `expected` entries.
fn check_len(what: &'static str, values: &[f64], expected: usize) -> Result<(), RetrievalError> {
    if values.len() == expected {
        Ok(())
    } else {
        Err(RetrievalError::LengthMismatch { what, expected, found: values.len() })
    }
}

/// A wavelength must be finite and positive.
fn check_wavelength(wavelength_m: f64) -> Result<(), RetrievalError> {
    if wavelength_m.is_finite() && wavelength_m > 0.0 {
        Ok(())
    } else {
        Err(RetrievalError::InvalidParameter {
            name: "wavelength_m",
            value: wavelength_m,
            expected: "a finite wavelength > 0 m",
        })
    }
}

/// Per-point standard errors must be finite and positive (a zero would be an infinite weight).
fn check_stderr(stderr: &[f64]) -> Result<(), RetrievalError> {
    check_finite("stderr", stderr)?;
    match stderr.iter().find(|&&s| s <= 0.0) {
        Some(&value) => Err(RetrievalError::InvalidParameter {
            name: "stderr",
            value,
            expected: "standard errors > 0 (a zero is an infinite weight: merge empty bins or give a floor)",
        }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn doppler_sign_and_scale() {
        // 1.55 µm: 1 m/s receding is +1.290 MHz; the two maps are inverse.
        let lambda = 1.55e-6;
        let f = doppler_frequency(1.0, lambda);
        assert!((f - 2.0 / 1.55e-6).abs() < 1e-6 * f);
        assert!(f > 0.0);
        assert!((radial_velocity(f, lambda) - 1.0).abs() < 1e-15);
        assert!((radial_velocity(-f, lambda) + 1.0).abs() < 1e-15);
    }

    #[test]
    fn input_checks_name_the_problem() {
        assert_eq!(
            check_len("values", &[1.0, 2.0], 3),
            Err(RetrievalError::LengthMismatch { what: "values", expected: 3, found: 2 })
        );
        assert_eq!(
            check_finite("values", &[1.0, f64::NAN]),
            Err(RetrievalError::NonFinite { what: "values", index: 1 })
        );
        assert!(check_wavelength(0.0).is_err() && check_wavelength(f64::INFINITY).is_err());
        assert!(check_stderr(&[1.0, 0.0]).is_err() && check_stderr(&[1.0, 2.0]).is_ok());
    }
}
