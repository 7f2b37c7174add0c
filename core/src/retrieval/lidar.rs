//! Per-gate estimates of a pulsed lidar receiver's range–Doppler spectra: what
//! [`crate::detect::LidarSpec`] recorded, read by the estimators of this module's parent.
//!
//! [`retrieve_gate`] reads a gate's total spectrum plus the receiver's shot-noise floor with the
//! [`crate::retrieval`] estimators: moments (peak, centroid, width, FWHM, SNR) and one or two
//! components on the fixed floor, chosen by an F-test at [`FIT_SELECTION_LEVEL`]. Each component
//! is a Gaussian spread of velocities seen through the gate's spectral kernel
//! ([`crate::detect::LidarSpec::gate_kernel`], [`fit_one_or_two_with_kernel`]), not a Gaussian
//! in the spectrum: a short rectangular gate in a filled volume has a nearly Fejér (sinc²) kernel
//! with ~10 % of its power in sidelobes, which a plain Gaussian misses and the F-test then takes
//! for a second population (measured in `validation/README.md`). The fitted widths are the
//! scatterers' spreads, the kernel deconvolved. Plain Gaussians are fitted too and kept when
//! their one-component χ² is lower ([`LineShape`]): a gate that holds whole echoes shows the
//! pulse's Gaussian, not a filled gate's kernel.

use super::{
    FitOptions, Floor, GateEstimate, GateKernel, ModelChoice, OneFit, RetrievalError, fit_one_first, gate_estimates,
};
#[cfg(doc)]
use super::{fit_one_or_two, fit_one_or_two_with_kernel};
use crate::spectrum::FrequencyAxis;

/// Nominal level of the F-test that keeps a second Gaussian component in a gate fit. At the
/// retrieval module's default 0.01 the measured false-alarm rate on one-line spectra is 12 %
/// ([`fit_one_or_two`]); at 10⁻³ it is 1.6 %.
pub const FIT_SELECTION_LEVEL: f64 = 1e-3;

/// What is read off one gate's total spectrum: the spectral moments and the one- or
/// two-Gaussian fit, each with why it failed if it did ([`retrieve_gate`]).
#[derive(Debug, Clone, PartialEq)]
pub struct GateRetrieval {
    /// The shot-noise floor per bin added to the spectrum
    /// ([`crate::detect::LidarSpec::noise_floor_per_bin`]).
    pub noise_floor: f64,
    /// How many bins had a zero standard error and were given the gate's smallest positive one.
    pub stderr_substituted: usize,
    /// Peak, centroid, width, FWHM and SNR ([`gate_estimates`]).
    pub moments: Result<GateEstimate, RetrievalError>,
    /// One or two components on the fixed floor, chosen by the F-test at
    /// [`FIT_SELECTION_LEVEL`], of the line shape in [`line_shape`](Self::line_shape).
    pub fit: Result<ModelChoice, RetrievalError>,
    /// The line shape of [`fit`](Self::fit): the one whose one-component fit has the lower χ².
    pub line_shape: LineShape,
}

/// The line shape of a gate's components ([`retrieve_gate`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineShape {
    /// Gaussian velocity spreads seen through the gate's kernel (a filled gate).
    GateKernel,
    /// Gaussians in the spectrum (a gate holding whole echoes shows the pulse's Gaussian).
    Gaussian,
}

impl LineShape {
    /// `"gate_kernel"` or `"gaussian"`, as the outputs write it.
    pub fn name(self) -> &'static str {
        match self {
            LineShape::GateKernel => "gate_kernel",
            LineShape::Gaussian => "gaussian",
        }
    }
}

/// Estimates from one gate's expected periodogram `signal` (fftshift order, fraction of the
/// pulse energy per bin, as the receiver writes it), its batch standard errors `stderr` and its
/// spectral kernel `kernel` (`LidarSpec::gate_kernel_in` with the run's gate energies, as the
/// outputs use; or `LidarSpec::gate_kernel`). The receiver gives the rest: its bins `axis`
/// (`LidarSpec::frequency_axis`; `None` for a degenerate receiver, which is reported as an
/// error of both estimates), its shot-noise floor per bin `noise_floor`
/// (`LidarSpec::noise_floor_per_bin`) and its vacuum wavelength `wavelength`, m.
///
/// The spectrum a lidar would measure is the signal plus the shot-noise floor, so the moments
/// and fits are taken on `signal + floor` with that floor known: [`gate_estimates`] subtracts it
/// (its SNR is the gate's wideband CNR), and one or two components are fitted with
/// `Floor::Fixed(floor)` and the standard errors as weights, in two line shapes: Gaussian
/// velocity spreads seen through `kernel` ([`fit_one_or_two_with_kernel`]) and plain Gaussians
/// ([`fit_one_or_two`]). The shape whose one-component χ² is lower is kept (both have three
/// parameters per component: the likelihood decides), and only it is fitted with two components
/// ([`fit_one_first`]). The kernel is that of a filled gate; a
/// thin layer inside a long gate shows the pulse's own Gaussian spectrum instead, and there the
/// filled-gate kernel's sidelobes (the window's triangle) misfit by far. A shape whose fit fails
/// gives way to the other.
///
/// **Zero standard errors.** A bin whose batch standard error is 0 (every batch gave the
/// same value, usually a gate no path reached) would be an infinite weight. It is given the
/// smallest positive standard error of the same gate: zero spread over a finite number of
/// batches does not mean an exact value, and the best precision the run resolved anywhere in
/// that gate is the most that can be claimed for it; the bin then weighs no more than the
/// gate's best-measured bin. A gate with no positive standard error at all is fitted
/// unweighted (the fit then estimates the noise level from its residuals).
pub fn retrieve_gate(
    axis: Option<&FrequencyAxis>,
    noise_floor: f64,
    wavelength: f64,
    signal: &[f64],
    stderr: &[f64],
    kernel: &GateKernel,
) -> GateRetrieval {
    let floor = noise_floor;
    let values: Vec<f64> = signal.iter().map(|v| v + floor).collect();
    let smallest = stderr.iter().copied().filter(|&s| s > 0.0).fold(f64::INFINITY, f64::min);
    let mut substituted = 0;
    let se: Option<Vec<f64>> = smallest.is_finite().then(|| {
        stderr
            .iter()
            .map(|&s| {
                if s == 0.0 {
                    substituted += 1;
                    smallest
                } else {
                    s
                }
            })
            .collect()
    });
    let Some(axis) = axis else {
        let e = RetrievalError::InvalidParameter {
            name: "frequency_axis",
            value: f64::NAN,
            expected: "the receiver's bins (a positive digitiser rate)",
        };
        return GateRetrieval {
            noise_floor: floor,
            stderr_substituted: 0,
            moments: Err(e.clone()),
            fit: Err(e),
            line_shape: LineShape::GateKernel,
        };
    };
    let moments = gate_estimates(axis, &values, floor, wavelength);
    let options =
        FitOptions { floor: Floor::Fixed(floor), selection_level: FIT_SELECTION_LEVEL, ..FitOptions::default() };
    // The shapes are compared on their one-component fits; only the kept one goes on to two.
    let (through, plain) = rayon::join(
        || fit_one_first(axis, &values, se.as_deref(), wavelength, &options, Some(kernel)),
        || fit_one_first(axis, &values, se.as_deref(), wavelength, &options, None),
    );
    let (kept, line_shape) = match (through, plain) {
        (Ok(k), Ok(p)) if p.one().chi2 < k.one().chi2 => (Ok(p), LineShape::Gaussian),
        (Err(_), Ok(p)) => (Ok(p), LineShape::Gaussian),
        (k, _) => (k, LineShape::GateKernel),
    };
    let fit = kept.map(OneFit::choose);
    GateRetrieval { noise_floor: floor, stderr_substituted: substituted, moments, fit, line_shape }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gate_retrieval_substitutes_zero_errors_and_reports_empty_gates() {
        // The receiver of `detect::lidar`'s tests with 256 bins: 50 MHz, 10-point gates, a
        // 200 ns pulse, 1.55 µm, 100 µJ, η = 0.8·0.4.
        let (rate, m, k_len, wavelength) = (50e6, 10, 256, 1.55e-6);
        let floor = m as f64 * (6.626_070_15e-34 * crate::SPEED_OF_LIGHT / wavelength) / (0.32 * 100e-6) / k_len as f64;
        let (dt, sigma) = (1.0 / rate, 200e-9 / (2.0 * 2f64.ln().sqrt()));
        let lags = (0..m)
            .map(|d| {
                let tau = d as f64 * dt;
                (m - d) as f64 * (-tau * tau / (4.0 * sigma * sigma)).exp()
            })
            .collect();
        let kernel = GateKernel { lags, dt, fft_points: k_len };
        let bin = |k: usize| (k as f64 - (k_len / 2) as f64) * rate / k_len as f64;
        let axis =
            FrequencyAxis::new(bin(0) - 0.5 * rate / k_len as f64, bin(k_len - 1) + 0.5 * rate / k_len as f64, k_len)
                .unwrap();
        // A Gaussian spread of velocities at +2 MHz (1.55 m/s), σ 1 MHz, seen through the gate's
        // kernel, with 1 % errors, one of them 0: that bin gets the smallest positive error, and
        // one component at the line is found.
        let signal: Vec<f64> = (0..k_len).map(|k| kernel.periodogram(1e5 * floor, 2e6, 1e6, bin(k))).collect();
        let mut stderr: Vec<f64> = signal.iter().map(|v| 0.01 * v + 1e-3 * floor).collect();
        stderr[10] = 0.0;
        let r = retrieve_gate(Some(&axis), floor, wavelength, &signal, &stderr, &kernel);
        assert_eq!(r.stderr_substituted, 1);
        assert_eq!(r.noise_floor, floor);
        let mo = r.moments.unwrap();
        assert!((mo.peak_frequency_hz - 2e6).abs() < 1e3, "{}", mo.peak_frequency_hz);
        assert_eq!(r.line_shape, LineShape::GateKernel);
        let fit = r.fit.unwrap();
        assert_eq!(fit.components, 1);
        let c = &fit.one.components[0];
        assert!((c.mean_hz - 2e6).abs() < 1e3 && (c.sigma_hz / 1e6 - 1.0).abs() < 1e-3, "{c:?}");
        assert!((c.mean_velocity_m_per_s - 0.5 * wavelength * 2e6).abs() < 1e-3);
        // An empty gate: no signal for both, never a panic.
        let r = retrieve_gate(Some(&axis), floor, wavelength, &[0.0; 256], &[0.0; 256], &kernel);
        assert_eq!(r.moments, Err(RetrievalError::NoSignal));
        assert_eq!(r.fit, Err(RetrievalError::NoSignal));
        // No axis: both estimates say so.
        let r = retrieve_gate(None, floor, wavelength, &signal, &stderr, &kernel);
        let (Err(a), Err(b)) = (r.moments, r.fit) else { panic!("no axis, yet an estimate") };
        assert!(matches!(a, RetrievalError::InvalidParameter { name: "frequency_axis", .. }));
        assert_eq!(a.to_string(), b.to_string());
    }
}
