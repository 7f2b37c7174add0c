//! Frequency axes, the histogram slots a beat frequency falls into, Lorentzian bin fractions, and
//! the camera's short-time spectra.
//!
//! * [`FrequencyAxis`] / [`Slot`]: the histogram (Algorithm 1 of Kim et al. 2025) over an explicit
//!   signed axis; [`lorentzian_bin_fraction`] / [`lorentzian_tail_fractions`] spread a
//!   Brownian-broadened path (validation-values §4.10) over it instead of one bin.
//! * [`stft`]: a camera window of `N` samples at `f_s` — bins, the exact expected periodogram of a
//!   set of lines (Kim et al. Eq. 28, `|W|²` convolution with aliasing and Lorentzian broadening),
//!   and exact per-line LDH band moments `M0±`, `M1` ([`BandKernel`]).
//! * [`synth`]: single-window speckled spectra — Algorithm 2 (random-phase field and FFT, Kim et
//!   al. Eqs. 39–42) by a non-uniform FFT, and Algorithm 1's `S_k · Exp(1)` draw.
//!
//! Normalisation throughout: power per bin as a fraction of the emitted power (not per Hz); a line
//! of power `p` puts exactly `p` into the `N` bins of a window (`Σ_k K = 1`).

pub mod stft;
pub mod synth;

pub use stft::{BandKernel, BandMoments, BandPowers, BandTable, BinnedPeriodogram, Line, Stft, Window};
pub use synth::{Synthesizer, speckle_draw};

use std::f64::consts::PI;

/// An explicit signed frequency axis: `bins` equal bins over `[f_min, f_max)` (Hz), ascending.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrequencyAxis {
    pub f_min: f64,
    pub f_max: f64,
    pub bins: usize,
    inv_width: f64,
}

/// Where a frequency lands on an axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    Bin(usize),
    Below,
    Above,
    /// NaN or infinite: counted as non-finite, never binned.
    NonFinite,
}

impl FrequencyAxis {
    /// `None` unless `f_min < f_max` (both finite), `bins ≥ 1`, and the span `f_max − f_min` and
    /// its inverse `bins/(f_max − f_min)` are finite (edges of ±1.7e308 overflow the span, and with
    /// it the bin width and the bin centres).
    pub fn new(f_min: f64, f_max: f64, bins: usize) -> Option<Self> {
        let inv_width = bins as f64 / (f_max - f_min);
        (f_min.is_finite()
            && f_max.is_finite()
            && f_min < f_max
            && bins >= 1
            && (f_max - f_min).is_finite()
            && inv_width.is_finite())
        .then_some(FrequencyAxis { f_min, f_max, bins, inv_width })
    }

    /// Width of one bin, Hz.
    pub fn bin_width(&self) -> f64 {
        (self.f_max - self.f_min) / self.bins as f64
    }

    /// Centre frequency of bin `k`, Hz.
    pub fn center(&self, k: usize) -> f64 {
        self.f_min + (k as f64 + 0.5) * self.bin_width()
    }

    /// The slot of frequency `f`: bin `k` covers `[f_min + kΔ, f_min + (k+1)Δ)`.
    #[inline(always)]
    pub fn locate(&self, f: f64) -> Slot {
        if !f.is_finite() {
            return Slot::NonFinite;
        }
        if f < self.f_min {
            return Slot::Below;
        }
        let k = ((f - self.f_min) * self.inv_width) as usize;
        if f >= self.f_max {
            Slot::Above
        } else {
            // Rounding can put f just below f_max into bin `bins`; keep it in range.
            Slot::Bin(k.min(self.bins - 1))
        }
    }
}

/// Fraction of a unit-area Lorentzian centred at `f` with half width at half maximum `gamma` that
/// lies in `[lo, hi)`: `(atan((hi − f)/γ) − atan((lo − f)/γ))/π`, evaluated without cancellation
/// as `atan2((hi − lo)γ, γ² + (hi − f)(lo − f))/π` (the difference formula
/// `atan a − atan b = atan2(a − b, 1 + ab)` for `a > b`, scaled by `γ²`; the branch is `atan2`'s), so
/// far tails keep full relative precision and are never negative. For `γ = 0` it is exactly the
/// indicator of `[lo, hi)`. Returns 0 for an empty or reversed interval.
pub fn lorentzian_bin_fraction(lo: f64, hi: f64, f: f64, gamma: f64) -> f64 {
    if hi.is_nan() || lo.is_nan() || hi <= lo {
        return 0.0;
    }
    if gamma == 0.0 {
        return if lo <= f && f < hi { 1.0 } else { 0.0 };
    }
    if hi == f64::INFINITY || lo == f64::NEG_INFINITY {
        let (below, above) = lorentzian_tail_fractions(lo, hi, f, gamma);
        return (1.0 - below - above).max(0.0);
    }
    (((hi - lo) * gamma).atan2(gamma * gamma + (hi - f) * (lo - f)) / PI).clamp(0.0, 1.0)
}

/// The fractions of a unit-area Lorentzian (centre `f`, HWHM `gamma`) below `f_min` and at or
/// above `f_max`: `atan2(γ, f − f_min)/π` and `atan2(γ, f_max − f)/π`, precise in the far tails.
/// For `γ = 0`: `(1, 0)` if `f < f_min`, `(0, 1)` if `f ≥ f_max`, else `(0, 0)` — the
/// [`FrequencyAxis::locate`] convention.
pub fn lorentzian_tail_fractions(f_min: f64, f_max: f64, f: f64, gamma: f64) -> (f64, f64) {
    if gamma == 0.0 {
        return (if f < f_min { 1.0 } else { 0.0 }, if f >= f_max { 1.0 } else { 0.0 });
    }
    (gamma.atan2(f - f_min) / PI, gamma.atan2(f_max - f) / PI)
}

impl FrequencyAxis {
    /// The slot (a bin, or `bins`/`bins + 1` below/above the axis) that a line at `f` with
    /// Lorentzian half-width `gamma` puts its whole weight into for the uniform `u` in `[0, 1)`:
    /// that of the frequency `f + γ·tan(π(u − ½))` drawn from the Lorentzian (a pure tone's own
    /// slot). Each slot's probability is the line's fraction in it, so a weight added there has
    /// [`add_line`](Self::add_line)'s expectation at the cost of one slot instead of every bin
    /// (camera paths, whose connections add tens of lines each, [`crate::detect::ldh`]). `None`
    /// for a non-finite `f`.
    #[inline]
    pub fn drawn_slot(&self, f: f64, gamma: f64, u: f64) -> Option<usize> {
        let nu = if gamma > 0.0 { f + gamma * (PI * (u - 0.5)).tan() } else { f };
        match self.locate(nu) {
            Slot::Bin(k) => Some(k),
            Slot::Below => Some(self.bins),
            Slot::Above => Some(self.bins + 1),
            // (u = 0 draws −∞: below.)
            Slot::NonFinite => f.is_finite().then_some(self.bins),
        }
    }

    /// Add a line of weight `w` at frequency `f` with Lorentzian half-width `gamma` (Hz, 0 for a
    /// pure tone) to `hist`, laid out as this axis's `bins` followed by the below/above tallies.
    /// A broadened line is integrated exactly over every bin and both out-of-range tails, so the
    /// slots still sum to `w` (Parseval). `false` (nothing added) for a non-finite `f` or `w`.
    pub fn add_line(&self, hist: &mut [f64], w: f64, f: f64, gamma: f64) -> bool {
        if !(f.is_finite() && w.is_finite() && gamma.is_finite()) {
            return false;
        }
        if gamma <= 0.0 {
            let slot = match self.locate(f) {
                Slot::Bin(k) => k,
                Slot::Below => self.bins,
                Slot::Above => self.bins + 1,
                Slot::NonFinite => return false,
            };
            hist[slot] += w;
            return true;
        }
        let dw = self.bin_width();
        for (k, h) in hist[..self.bins].iter_mut().enumerate() {
            let lo = self.f_min + k as f64 * dw;
            *h += w * lorentzian_bin_fraction(lo, lo + dw, f, gamma);
        }
        let (below, above) = lorentzian_tail_fractions(self.f_min, self.f_max, f, gamma);
        hist[self.bins] += w * below;
        hist[self.bins + 1] += w * above;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫_lo^hi of the Lorentzian density by composite Gauss–Legendre (5 points) on `parts` pieces.
    fn lorentz_integral(lo: f64, hi: f64, f: f64, gamma: f64, parts: usize) -> f64 {
        const X: [f64; 5] =
            [0.0, -0.538_469_310_105_683, 0.538_469_310_105_683, -0.906_179_845_938_664, 0.906_179_845_938_664];
        const W: [f64; 5] = [
            0.568_888_888_888_889,
            0.478_628_670_499_366,
            0.478_628_670_499_366,
            0.236_926_885_056_189,
            0.236_926_885_056_189,
        ];
        let h = (hi - lo) / parts as f64;
        let mut sum = 0.0;
        for p in 0..parts {
            let c = lo + (p as f64 + 0.5) * h;
            for (x, w) in X.iter().zip(W) {
                let d = c + 0.5 * h * x - f;
                sum += w * 0.5 * h * gamma / (PI * (d * d + gamma * gamma));
            }
        }
        sum
    }

    /// Issue 33, item 8: an axis whose span or bin width is not a finite number is refused (edges
    /// of ±1.7e308 made an all-infinite axis of bin centres).
    #[test]
    fn axes_with_a_span_beyond_doubles_are_refused() {
        assert!(FrequencyAxis::new(-1.7e308, 1.7e308, 256).is_none());
        assert!(FrequencyAxis::new(0.0, 1e-310, 1).is_none());
        assert!(FrequencyAxis::new(0.0, f64::INFINITY, 1).is_none());
        let a = FrequencyAxis::new(-0.8e308, 0.8e308, 256).unwrap();
        assert!((0..a.bins).all(|k| a.center(k).is_finite()));
    }

    #[test]
    fn lorentzian_fractions_sum_to_one() {
        let axis = FrequencyAxis::new(-20_000.0, 20_000.0, 65).unwrap();
        for &f in &[0.0, 123.4, -19_999.0, 25_000.0, -1.0e6, 7_000.0] {
            for &g in &[0.0, 1.0, 300.0, 5_000.0, 1.0e5] {
                let bins: f64 = (0..axis.bins)
                    .map(|k| {
                        let lo = axis.f_min + k as f64 * axis.bin_width();
                        lorentzian_bin_fraction(lo, lo + axis.bin_width(), f, g)
                    })
                    .sum();
                let (below, above) = lorentzian_tail_fractions(axis.f_min, axis.f_max, f, g);
                assert!((bins + below + above - 1.0).abs() < 1e-13, "f={f} γ={g}: {bins} + {below} + {above}");
                assert!(below >= 0.0 && above >= 0.0);
            }
        }
        // γ = 0 is the histogram slot.
        assert_eq!(lorentzian_bin_fraction(0.0, 1.0, 0.0, 0.0), 1.0);
        assert_eq!(lorentzian_bin_fraction(0.0, 1.0, 1.0, 0.0), 0.0);
        assert_eq!(lorentzian_tail_fractions(-1.0, 1.0, 1.0, 0.0), (0.0, 1.0));
        assert_eq!(lorentzian_tail_fractions(-1.0, 1.0, -1.5, 0.0), (1.0, 0.0));
        assert_eq!(lorentzian_bin_fraction(1.0, 0.0, 0.5, 1.0), 0.0);
        assert!((lorentzian_bin_fraction(f64::NEG_INFINITY, f64::INFINITY, 3.0, 2.0) - 1.0).abs() < 1e-15);
        assert!((lorentzian_bin_fraction(3.0, f64::INFINITY, 3.0, 2.0) - 0.5).abs() < 1e-15);
    }

    #[test]
    fn lorentzian_fraction_matches_numeric_integral() {
        for &(lo, hi, f, g) in &[
            (0.0, 1.0, 0.5, 0.1),
            (-3.0, 2.0, 0.0, 1.0),
            (10.0, 12.0, 0.0, 1.0),
            (-12.0, -10.0, 0.0, 1.0),
            (100.0, 100.5, 99.0, 3.0),
            (0.0, 609.375, 100.0, 31.0),
        ] {
            let exact = lorentzian_bin_fraction(lo, hi, f, g);
            let numeric = lorentz_integral(lo, hi, f, g, 4_000);
            assert!(
                (exact - numeric).abs() < 1e-12 * numeric.max(1e-3),
                "[{lo},{hi}) f={f} γ={g}: {exact} vs {numeric}"
            );
        }
    }

    #[test]
    fn lorentzian_far_tails_are_precise() {
        // A bin one half-width wide, 1e6 half-widths away on either side, and far tails of the
        // axis: the relative error against a (cancellation-free) numeric integral is below 1e-10.
        for &(g, sign) in &[(1.0, 1.0), (31.0, -1.0), (1e-3, 1.0)] {
            let lo = 5.0 + sign * 1e6 * g;
            let (lo, hi) = if sign > 0.0 { (lo, lo + g) } else { (lo - g, lo) };
            let exact = lorentzian_bin_fraction(lo, hi, 5.0, g);
            let numeric = lorentz_integral(lo, hi, 5.0, g, 4);
            assert!(exact > 0.0);
            assert!((exact / numeric - 1.0).abs() < 1e-10, "γ={g}: {exact:e} vs {numeric:e}");
        }
        let (below, above) = lorentzian_tail_fractions(-1e6, 1e6, 0.0, 1.0);
        // ∫_{1e6}^∞ = atan(1e-6)/π = (1e-6 − 1e-18/3)/π.
        let reference = (1e-6 - 1e-18 / 3.0) / PI;
        assert!((below / reference - 1.0).abs() < 1e-12 && (above / reference - 1.0).abs() < 1e-12);
    }

    #[test]
    fn slots_and_mirror_symmetry() {
        let a = FrequencyAxis::new(-10.0, 10.0, 5).unwrap();
        assert_eq!(a.locate(0.0), Slot::Bin(2)); // odd bin count: DC is the centre bin
        assert_eq!(a.locate(-10.0), Slot::Bin(0));
        assert_eq!(a.locate(10.0), Slot::Above);
        assert_eq!(a.locate(-10.000001), Slot::Below);
        assert_eq!(a.locate(f64::NAN), Slot::NonFinite);
        assert_eq!(a.locate(9.999999999), Slot::Bin(4));
        for &f in &[0.3, 1.9, 2.1, 5.5, 7.77] {
            match (a.locate(f), a.locate(-f)) {
                (Slot::Bin(i), Slot::Bin(j)) => assert_eq!(i + j, 4),
                other => panic!("{other:?}"),
            }
        }
        assert!((a.center(2)).abs() < 1e-15);
        assert!(FrequencyAxis::new(1.0, 1.0, 3).is_none());
        assert!(FrequencyAxis::new(0.0, 1.0, 0).is_none());
    }
}
