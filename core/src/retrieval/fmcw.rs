//! FMCW range and radial velocity from one receiver's up- and down-chirp beat spectra.
//!
//! With the chirp slope `α = B/T`, a path of optical length `l` whose length changes at `dl/dt`
//! beats at `f_up = α·l/c + (dl/dt)/λ0` in the up-chirp and `f_down = α·l/c − (dl/dt)/λ0` in the
//! down-chirp (crate conventions). A target at range `R` (round trip `l = 2R`) with radial velocity
//! `v` (positive receding, `dl/dt = 2v`) gives `f_up = f_R + f_D`, `f_down = f_R − f_D` with
//! `f_R = 2RB/(cT)` and `f_D = 2v/λ0` (Kim et al. 2025, Eq. 9, there written with the approaching
//! sign), hence
//!
//! `R = c·T·(f_up + f_down)/(4B)`,  `v = λ0·(f_up − f_down)/4`.
//!
//! A receding target has `f_up > f_down`.
//!
//! **Two estimators of `f_up`, `f_down`** ([`fmcw_estimates`]), both from
//! [`gate_estimates`](super::gate_estimates) with a zero noise floor (Monte Carlo spectra are
//! noiseless expectations):
//! * the *peak*: the largest bin refined by the parabola through the logarithms of it and its
//!   two neighbours (exact for a Gaussian line; a line confined to one bin stays at the bin centre).
//!   This is the range of the strongest return — for a hard target, the target.
//! * the *centroid*: the power-weighted mean frequency over the contiguous run of bins around the
//!   peak holding more than 1 % of the peak bin. For a soft target (a cloud) it is the
//!   power-weighted mean range of the return, where the peak picks one noisy bin somewhere inside
//!   it. An empty bin inside a return ends the run: give the spectrum enough paths.
//!
//! **Resolution.** One frequency bin `Δf` spans the range `range_bin = c·T·Δf/(2B)` (the range
//! that moves `f_R`, and so both peaks, by one bin) and the velocity `velocity_bin = λ0·Δf/2` (the
//! velocity that moves `f_D`, and so both peaks, by one bin). Errors `δ_up`, `δ_down` of the two
//! peak frequencies give `δR = c·T·(δ_up + δ_down)/(4B)` and `δv = λ0·(δ_up − δ_down)/4`. The
//! refined peak always lies inside its peak bin (the offset is clamped to ±½ bin), so when each
//! peak bin holds its true line, `|δ| < Δf` and the recovered range and velocity are within one
//! `range_bin` and one `velocity_bin`. Peaks read at the bin centres (no refinement) would have
//! `|δ| ≤ Δf/2`, i.e. half of each: `c·T·Δf/(4B)` and `λ0·Δf/4`.
//!
//! **No standard errors.** The run keeps each bin's mean and standard error over batches, not the
//! batches themselves, so nothing here can be re-estimated per batch; and the up- and down-chirp
//! spectra are the same paths binned twice, so the error of `f_up + f_down` or `f_up − f_down`
//! needs their cross-covariance, which is not kept. The bins above are the resolution instead.

use super::{GateEstimate, RetrievalError, gate_estimates};
use crate::SPEED_OF_LIGHT;
use crate::spectrum::FrequencyAxis;

/// Range and radial velocity read off a pair of up- and down-chirp spectra. Frequencies in Hz,
/// ranges in m, velocities in m/s (positive receding).
#[derive(Debug, Clone, PartialEq)]
pub struct FmcwEstimate {
    /// Peak of the up-chirp spectrum (log-parabola refined).
    pub f_up_hz: f64,
    /// Peak of the down-chirp spectrum.
    pub f_down_hz: f64,
    /// `c·T·(f_up + f_down)/(4B)` from the peaks.
    pub range_m: f64,
    /// `λ0·(f_up − f_down)/4` from the peaks.
    pub radial_velocity_m_per_s: f64,
    /// Centroid of the up-chirp spectrum over its peak region.
    pub f_up_centroid_hz: f64,
    /// Centroid of the down-chirp spectrum over its peak region.
    pub f_down_centroid_hz: f64,
    /// The range from the centroids.
    pub range_centroid_m: f64,
    /// The radial velocity from the centroids.
    pub radial_velocity_centroid_m_per_s: f64,
    /// `c·T·Δf/(2B)`: the range one frequency bin spans.
    pub range_bin_m: f64,
    /// `λ0·Δf/2`: the radial velocity one frequency bin of Doppler shift spans.
    pub velocity_bin_m_per_s: f64,
    /// The up- or down-chirp peak region reaches the first or last bin of the axis: the return
    /// may extend beyond it and the estimates may be cut off.
    pub touches_axis_end: bool,
    /// The spectral moments of the up-chirp spectrum the estimates come from.
    pub up: GateEstimate,
    /// The same for the down-chirp spectrum.
    pub down: GateEstimate,
}

impl FmcwEstimate {
    /// Whether every estimate is a finite number. The configuration's checks keep the range
    /// conversions of a spectrum's axis finite (issue 33, item 8); an estimate that is not (the
    /// manifest writes it as null) is reported, never passed off as a result.
    pub fn is_finite(&self) -> bool {
        [
            self.f_up_hz,
            self.f_down_hz,
            self.range_m,
            self.radial_velocity_m_per_s,
            self.f_up_centroid_hz,
            self.f_down_centroid_hz,
            self.range_centroid_m,
            self.radial_velocity_centroid_m_per_s,
            self.range_bin_m,
            self.velocity_bin_m_per_s,
        ]
        .iter()
        .all(|x| x.is_finite())
    }
}

/// `f_R = 2RB/(cT)`: the beat frequency (Hz) of range `range_m` for a chirp of bandwidth
/// `bandwidth_hz` swept in `duration_s`.
pub fn range_frequency(range_m: f64, bandwidth_hz: f64, duration_s: f64) -> f64 {
    2.0 * range_m * bandwidth_hz / (SPEED_OF_LIGHT * duration_s)
}

/// `R = c·T·(f_up + f_down)/(4B)`.
pub fn range_from_beats(f_up_hz: f64, f_down_hz: f64, bandwidth_hz: f64, duration_s: f64) -> f64 {
    SPEED_OF_LIGHT * duration_s * (f_up_hz + f_down_hz) / (4.0 * bandwidth_hz)
}

/// `v = λ0·(f_up − f_down)/4` (positive receding).
pub fn velocity_from_beats(f_up_hz: f64, f_down_hz: f64, wavelength_m: f64) -> f64 {
    0.25 * wavelength_m * (f_up_hz - f_down_hz)
}

/// Range and radial velocity from the up-chirp spectrum `up` and the down-chirp spectrum `down`
/// (power per bin on `axis`, one value per bin) of a chirp of bandwidth `bandwidth_hz` swept in
/// `duration_s`, at vacuum wavelength `wavelength_m`. See the module docs for the estimators.
///
/// Errors: a bandwidth or duration that is not finite and positive
/// ([`RetrievalError::InvalidParameter`] naming it), spectra of the wrong length or with
/// non-finite values, a bad wavelength, or a spectrum with no positive bin
/// ([`RetrievalError::NoSignal`]).
pub fn fmcw_estimates(
    axis: &FrequencyAxis,
    up: &[f64],
    down: &[f64],
    wavelength_m: f64,
    bandwidth_hz: f64,
    duration_s: f64,
) -> Result<FmcwEstimate, RetrievalError> {
    for (name, value, expected) in [
        // B = 0 (a chirp of zero bandwidth, accepted by the configuration) is the CW limit: the
        // beats are ±(dl/dt)/λ0 and carry no range information, so there is no estimate.
        (
            "bandwidth_hz",
            bandwidth_hz,
            "a finite chirp bandwidth B > 0 Hz (with B = 0 the beat frequencies carry no range information)",
        ),
        ("duration_s", duration_s, "a finite chirp duration T > 0 s"),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return Err(RetrievalError::InvalidParameter { name, value, expected });
        }
    }
    let (u, d) = (gate_estimates(axis, up, 0.0, wavelength_m)?, gate_estimates(axis, down, 0.0, wavelength_m)?);
    let range = |a, b| range_from_beats(a, b, bandwidth_hz, duration_s);
    let velocity = |a, b| velocity_from_beats(a, b, wavelength_m);
    let dw = axis.bin_width();
    let touches = |g: &GateEstimate| g.window.start == 0 || g.window.end == axis.bins;
    Ok(FmcwEstimate {
        f_up_hz: u.peak_frequency_hz,
        f_down_hz: d.peak_frequency_hz,
        range_m: range(u.peak_frequency_hz, d.peak_frequency_hz),
        radial_velocity_m_per_s: velocity(u.peak_frequency_hz, d.peak_frequency_hz),
        f_up_centroid_hz: u.centroid_frequency_hz,
        f_down_centroid_hz: d.centroid_frequency_hz,
        range_centroid_m: range(u.centroid_frequency_hz, d.centroid_frequency_hz),
        radial_velocity_centroid_m_per_s: velocity(u.centroid_frequency_hz, d.centroid_frequency_hz),
        range_bin_m: SPEED_OF_LIGHT * duration_s * dw / (2.0 * bandwidth_hz),
        velocity_bin_m_per_s: 0.5 * wavelength_m * dw,
        touches_axis_end: touches(&u) || touches(&d),
        up: u,
        down: d,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const LAMBDA: f64 = 1.55e-6;
    const B: f64 = 1e9;
    const T: f64 = 10e-6;

    /// A Gaussian line (power 1, mean `mu`, standard deviation `sigma`) sampled at the bin centres.
    fn line(axis: &FrequencyAxis, mu: f64, sigma: f64) -> Vec<f64> {
        (0..axis.bins).map(|k| (-0.5 * ((axis.center(k) - mu) / sigma).powi(2)).exp()).collect()
    }

    #[test]
    fn closed_forms() {
        // 10 m at B = 1 GHz, T = 10 µs: 6.6713 MHz; 1 m/s at 1550 nm: 1.2903 MHz.
        let f_r = range_frequency(10.0, B, T);
        assert!((f_r - 6.671_281_9e6).abs() < 1.0, "{f_r}");
        let f_d = crate::retrieval::doppler_frequency(1.0, LAMBDA);
        assert!((range_from_beats(f_r + f_d, f_r - f_d, B, T) - 10.0).abs() < 1e-12);
        assert!((velocity_from_beats(f_r + f_d, f_r - f_d, LAMBDA) - 1.0).abs() < 1e-12);
        // Approaching: the down-chirp peak is the higher one.
        assert!((velocity_from_beats(f_r - f_d, f_r + f_d, LAMBDA) + 1.0).abs() < 1e-12);
    }

    #[test]
    fn gaussian_lines_are_recovered_exactly() {
        // Lines off the bin centres: the log-parabola peak and the centroid are exact.
        let axis = FrequencyAxis::new(0.0, 15e6, 1500).unwrap();
        let (r, v) = (10.123, -0.37);
        let (f_r, f_d) = (range_frequency(r, B, T), crate::retrieval::doppler_frequency(v, LAMBDA));
        let sigma = 3.3 * axis.bin_width();
        let (up, down) = (line(&axis, f_r + f_d, sigma), line(&axis, f_r - f_d, sigma));
        let e = fmcw_estimates(&axis, &up, &down, LAMBDA, B, T).unwrap();
        assert!((e.f_up_hz - (f_r + f_d)).abs() < 1e-6, "{}", e.f_up_hz);
        assert!((e.range_m - r).abs() < 1e-9 && (e.radial_velocity_m_per_s - v).abs() < 1e-9, "{e:?}");
        // The 1 % window truncates the line symmetrically only up to a bin: the centroid is within a
        // small fraction of one.
        assert!((e.range_centroid_m - r).abs() < 0.05 * e.range_bin_m, "{}", e.range_centroid_m);
        assert!((e.radial_velocity_centroid_m_per_s - v).abs() < 0.05 * e.velocity_bin_m_per_s);
        assert!((e.range_bin_m - SPEED_OF_LIGHT * T * 1e4 / (2.0 * B)).abs() < 1e-15);
        assert!((e.velocity_bin_m_per_s - LAMBDA * 1e4 / 2.0).abs() < 1e-18);
        assert!(!e.touches_axis_end);
    }

    #[test]
    fn one_bin_lines_stay_within_their_bin() {
        // Every path in one bin (a hard target): peak and centroid at the bin centres, so the
        // errors are at most half a bin in each frequency.
        let axis = FrequencyAxis::new(0.0, 15e6, 1500).unwrap();
        let (f_up, f_down) = (7.9616e6, 5.3810e6);
        let mut up = vec![0.0; 1500];
        let mut down = vec![0.0; 1500];
        up[(f_up / 1e4) as usize] = 2e-6;
        down[(f_down / 1e4) as usize] = 2e-6;
        let e = fmcw_estimates(&axis, &up, &down, LAMBDA, B, T).unwrap();
        assert_eq!((e.f_up_hz, e.f_down_hz), (7.965e6, 5.385e6));
        assert_eq!((e.f_up_centroid_hz, e.f_down_centroid_hz), (7.965e6, 5.385e6));
        assert!((e.range_m - range_from_beats(f_up, f_down, B, T)).abs() <= 0.5 * e.range_bin_m);
        assert!(
            (e.radial_velocity_m_per_s - velocity_from_beats(f_up, f_down, LAMBDA)).abs()
                <= 0.5 * e.velocity_bin_m_per_s
        );
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        let axis = FrequencyAxis::new(0.0, 4.0, 4).unwrap();
        let s = [0.0, 1.0, 2.0, 0.0];
        assert!(matches!(
            fmcw_estimates(&axis, &s, &s, LAMBDA, 0.0, T),
            Err(RetrievalError::InvalidParameter { name: "bandwidth_hz", .. })
        ));
        assert!(matches!(
            fmcw_estimates(&axis, &s, &s, LAMBDA, B, f64::NAN),
            Err(RetrievalError::InvalidParameter { name: "duration_s", .. })
        ));
        assert_eq!(fmcw_estimates(&axis, &s, &[0.0; 4], LAMBDA, B, T), Err(RetrievalError::NoSignal));
        assert!(matches!(fmcw_estimates(&axis, &s, &s[..3], LAMBDA, B, T), Err(RetrievalError::LengthMismatch { .. })));
        // A line at the axis end is flagged.
        let e = fmcw_estimates(&axis, &[3.0, 1.0, 0.0, 0.0], &s, LAMBDA, B, T).unwrap();
        assert!(e.touches_axis_end);
    }
}
