//! Correlation outputs of a surface detector: the normalised field autocorrelation g1(τ), the
//! intensity autocorrelation g2(τ) = 1 + β|g1(τ)|² (diffuse correlation spectroscopy) and the
//! speckle contrast K(T) of exposure times T (laser speckle contrast imaging), for the detector's
//! total (its area: K over a spatial window is a detector over that window).
//!
//! **Per path, exactly.** A detected path of weight `w`, Doppler beat frequency `f = (dl/dt)/λ0`
//! and Brownian sum `b = Σ D_k n_k² |Δ_k|²` ([`super::Escape::brownian`]) has the field
//! autocorrelation `exp(i2πfτ)·exp(−Γτ)` with `Γ = Σ D_k q_k² = (2π/λ0)² b` (the decay whose
//! Fourier transform is the Lorentzian of half-width [`super::BeatModel::brownian_hwhm`]); random
//! flow (a per-event velocity dispersion) is in `f`, drawn per path. The detector adds
//! `w·cos(2πfτ)e^{−Γτ}` and `w·sin(2πfτ)e^{−Γτ}` per delay τ (no spectrum binning), so that
//! `g1(τ) = Σ w e^{i2πfτ − Γτ} / Σ w`, the ensemble average over paths (Kim et al. 2025's path
//! integral; for Brownian media the correlation-transport form of Boas & Yodh 1997).
//!
//! **Normalised over the run.** The value of g1 is the ratio of the run's mean sums to its mean
//! detected power, and |g1|² (in g2 and K) is the ratio `(|S̄|² − σ²(S̄))/(P̄² − σ²(P̄))`, each square
//! less the estimated variance of its mean: the square of a mean is biased by that variance, which
//! for a detector seeing few paths is far above |g1|² itself (one path does not dephase: its
//! |g1| is e^{−Γτ}). This removes the bias to O(1/paths) of the whole run
//! ([`CorrelationSpec::finish_run`]). Each batch also gets its own g1, g2 and K (its sums over
//! its power), and the standard errors are the spread of those per-batch values over the batches
//! (batch means): exact for large batches, approximate where a batch holds only a few detected
//! paths. Normalising per batch only, as a first version did, biased K over a small window of
//! `lsci_vessels` (artery, T = 10 ms) to 0.25, 0.29 and 0.38 with 16, 32 and 128 batches
//! (σ 0.015); the run-level value does not depend on the batch count
//! (test `correlation_does_not_depend_on_the_batch_count`). No K per pixel: the bias-corrected
//! |g1|² of a pixel with a handful of paths is too noisy to be of use, and per-pixel tallies
//! cost pixels × delays × 2 numbers; LSCI computes K over a spatial window, which a detector
//! over that window does here.
//!
//! **Speckle contrast** `K²(T) = (2β/T)∫₀ᵀ(1 − τ/T)|g1(τ)|²dτ` (Bandyopadhyay et al. 2005, Rev.
//! Sci. Instrum. 76, 093110, Eq. 5) is integrated over the tallied `|g1|²` on the τ grid, with
//! `|g1(0)|² = 1` as its first point (exact: g1 is normalised): between grid points `|g1|²` is
//! interpolated log-linearly (exponential in τ) and the weight `1 − τ/T` integrated exactly, so a
//! single-exponential `|g1|²` (a Brownian medium seen through one momentum transfer) is integrated
//! exactly, and a mixture of exponentials (diffuse light) with an error of 2·10⁻³ of K² at 8
//! points per decade (5·10⁻⁴ at 16) (test `contrast_quadrature_error_on_a_mixture`). Where `|g1|²` is not positive at
//! both ends of a piece (noise, or a zero of an oscillating Doppler g1) the piece is linear.

use super::detector_output;
use crate::output::{Kind, Output, Registry, Slots};

/// What a detector correlates.
#[derive(Debug, Clone, PartialEq)]
pub struct CorrelationSpec {
    /// Delays τ (s), ascending and positive (log-spaced as configured).
    pub tau: Vec<f64>,
    /// Coherence factor β of g2 and K, in (0, 1].
    pub beta: f64,
    /// Exposure times T (s) of the speckle contrast, each within `(0, τ_max]`; may be empty.
    pub exposures: Vec<f64>,
}

/// Where a detector's correlation tallies lie.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrelationLayout {
    /// Σ w cos, then Σ w sin, per τ (`2·taus`).
    pub sums: usize,
    /// g1: Re per τ, then Im per τ (per batch: the sums over the detected power).
    pub g1: usize,
    pub g2: usize,
    /// K per exposure time.
    pub contrast: usize,
    pub taus: usize,
}

impl CorrelationSpec {
    /// Lay out detector `i`'s (`name`) correlation tallies from `reg`'s end and declare them.
    pub fn declare(&self, i: usize, name: &str, reg: &mut Registry) -> CorrelationLayout {
        let (n, nt) = (self.tau.len(), self.exposures.len());
        let budget = Some((format!("detectors[{i}].correlation.points"), format!("= {n}")));
        let sums = reg.take(2 * n);
        reg.declare(Output {
            budget_key: budget.clone(),
            ..detector_output(
                i,
                format!("{name}.correlation_sums"),
                Kind::Internal,
                Slots::contiguous(sums, 2 * n),
                vec![2 * n],
            )
        });
        let g1 = reg.take(2 * n);
        reg.declare(Output {
            file: format!("{name}_g1.npy"),
            budget_key: budget.clone(),
            units: "1 (normalised field autocorrelation; row 0 real, row 1 imaginary part)",
            ..detector_output(
                i,
                format!("{name}.g1"),
                Kind::Curve,
                Slots { start: g1, rows: 2, stride: n, len: n },
                vec![2, n],
            )
        });
        let g2 = reg.take(n);
        reg.declare(Output {
            file: format!("{name}_g2.npy"),
            primary: true,
            budget_key: budget.clone(),
            units: "1 (normalised intensity autocorrelation)",
            ..detector_output(i, format!("{name}.g2"), Kind::Curve, Slots::contiguous(g2, n), vec![n])
        });
        let contrast = reg.take(nt);
        if nt > 0 {
            reg.declare(Output {
                file: format!("{name}_speckle_contrast.npy"),
                primary: true,
                units: "1 (speckle contrast K per exposure time)",
                ..detector_output(
                    i,
                    format!("{name}.speckle_contrast"),
                    Kind::Curve,
                    Slots::contiguous(contrast, nt),
                    vec![nt],
                )
            });
        }
        CorrelationLayout { sums, g1, g2, contrast, taus: n }
    }

    /// Record a path of weight `w`, Doppler frequency `f` (Hz) and Brownian decay rate `rate`
    /// (`Γ`, s⁻¹).
    #[inline(never)]
    pub fn record(&self, lay: &CorrelationLayout, acc: &mut [f64], w: f64, f: f64, rate: f64) {
        let n = lay.taus;
        let omega = std::f64::consts::TAU * f;
        for (k, &tau) in self.tau.iter().enumerate() {
            let decay = if rate > 0.0 { w * (-rate * tau).exp() } else { w };
            let (re, im) = if omega != 0.0 {
                let (s, c) = (omega * tau).sin_cos();
                (decay * c, decay * s)
            } else {
                (decay, 0.0)
            };
            acc[lay.sums + k] += re;
            acc[lay.sums + n + k] += im;
        }
    }

    /// Turn a finished batch's sums into g1, g2 and K: `power` is the slot of the detector's
    /// power; `paths` the batch's paths (the batch statistics divide every tally by it).
    pub fn finish_batch(&self, lay: &CorrelationLayout, acc: &mut [f64], power: usize, paths: f64) {
        let n = lay.taus;
        let mut g1sq = vec![0.0; n];
        let inv = if acc[power] > 0.0 { 1.0 / acc[power] } else { 0.0 };
        for k in 0..n {
            let (re, im) = (acc[lay.sums + k] * inv, acc[lay.sums + n + k] * inv);
            g1sq[k] = re * re + im * im;
            acc[lay.g1 + k] = paths * re;
            acc[lay.g1 + n + k] = paths * im;
            acc[lay.g2 + k] = paths * (1.0 + self.beta * g1sq[k]);
        }
        for (j, &t) in self.exposures.iter().enumerate() {
            acc[lay.contrast + j] = paths * contrast(&self.tau, &g1sq, t, self.beta);
        }
    }
}

impl CorrelationSpec {
    /// Replace the run's g1, g2 and K by their values from the run's means (module docs:
    /// "Normalised over the run"), keeping the per-batch spread as their standard errors.
    pub fn finish_run(&self, lay: &CorrelationLayout, est: &mut crate::stats::BatchAccumulator, power: usize) {
        let n = lay.taus;
        let p = est.mean()[power];
        let den = p * p - est.variance(power);
        let mut g1sq = vec![0.0; n];
        for (k, sq) in g1sq.iter_mut().enumerate() {
            let (re, im) = (est.mean()[lay.sums + k], est.mean()[lay.sums + n + k]);
            let num = re * re + im * im - est.variance(lay.sums + k) - est.variance(lay.sums + n + k);
            // Nothing detected (or too little to tell |g1|² from noise): 0, as a batch without
            // paths gives.
            *sq = if den > 0.0 { (num / den).max(0.0) } else { 0.0 };
            let inv = if p > 0.0 { 1.0 / p } else { 0.0 };
            est.set_mean(lay.g1 + k, re * inv);
            est.set_mean(lay.g1 + n + k, im * inv);
            est.set_mean(lay.g2 + k, 1.0 + self.beta * *sq);
        }
        for (j, &t) in self.exposures.iter().enumerate() {
            est.set_mean(lay.contrast + j, contrast(&self.tau, &g1sq, t, self.beta));
        }
    }
}

/// The speckle contrast `K(T) = √[(2β/T)∫₀ᵀ(1 − τ/T)|g1(τ)|²dτ]` from `|g1|²` at the delays
/// `tau` (ascending, positive), with `|g1(0)|² = 1` prepended; `T ≤ tau`'s last (the module docs
/// give the quadrature).
pub fn contrast(tau: &[f64], g1sq: &[f64], t: f64, beta: f64) -> f64 {
    let mut integral = 0.0;
    let (mut a, mut ga) = (0.0, 1.0);
    for (&b, &gb) in tau.iter().zip(g1sq) {
        if a >= t {
            break;
        }
        let h = b.min(t) - a;
        // ∫₀ʰ [(1 − a/T) − u/T] g(a + u) du over this piece.
        let c0 = 1.0 - a / t;
        integral += if ga > 0.0 && gb > 0.0 {
            let s = (ga / gb).ln() / (b - a);
            let x = s * h;
            // E0 = ∫₀ʰ e^{−su} du, E1 = ∫₀ʰ u e^{−su} du, without cancellation for small |x|.
            // (1 − e^{−x}(1 + x))/x² = Σ_{n≥2} (−1)^n (n − 1)/n! x^{n−2}: its series below
            // |x| = 0.01 (truncation x⁵/840 < 10⁻¹³), where the closed form cancels.
            let (e0, e1) = if x.abs() < 1e-2 {
                let e1 = 0.5 - x * (1.0 / 3.0 - x * (1.0 / 8.0 - x * (1.0 / 30.0 - x / 144.0)));
                (-(-x).exp_m1() / s, h * h * e1)
            } else {
                let em = (-x).exp_m1();
                (-em / s, h * h * (1.0 - (-x).exp() * (1.0 + x)) / (x * x))
            };
            ga * (c0 * e0 - e1 / t)
        } else {
            let m = (gb - ga) / (b - a);
            c0 * (ga * h + m * h * h / 2.0) - (ga * h * h / 2.0 + m * h * h * h / 3.0) / t
        };
        (a, ga) = (b, gb);
    }
    (2.0 * beta / t * integral).max(0.0).sqrt()
}

/// `n` delays log-spaced from `tau_min` to `tau_max` (both included; `n ≥ 2`).
pub fn log_spaced(tau_min: f64, tau_max: f64, n: usize) -> Vec<f64> {
    let r = (tau_max / tau_min).ln() / (n - 1) as f64;
    (0..n).map(|k| if k == n - 1 { tau_max } else { tau_min * (r * k as f64).exp() }).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bandyopadhyay et al. 2005 Eq. 9: for `|g1|² = e^{−2x τ/T}` (x = ΓT),
    /// `K² = β(e^{−2x} − 1 + 2x)/(2x²)`.
    fn k_exponential(rate: f64, t: f64, beta: f64) -> f64 {
        let y = 2.0 * rate * t;
        // 2(e^{−y} − 1 + y)/y², by its series where the closed form cancels.
        let f = if y < 1e-2 {
            1.0 - y / 3.0 + y * y / 12.0 - y * y * y / 60.0 + y.powi(4) / 360.0
        } else {
            2.0 * ((-y).exp() - 1.0 + y) / (y * y)
        };
        (beta * f).sqrt()
    }

    #[test]
    fn contrast_is_exact_for_an_exponential_and_has_its_limits() {
        let tau = log_spaced(1e-7, 1e-1, 25);
        let rate = 1e3;
        let g1sq: Vec<f64> = tau.iter().map(|t| (-2.0 * rate * t).exp()).collect();
        for t in [1e-7, 3e-6, 1e-4, 1e-3, 2.5e-2, 1e-1] {
            let (k, want) = (contrast(&tau, &g1sq, t, 0.7), k_exponential(rate, t, 0.7));
            assert!((k / want - 1.0).abs() < 1e-9, "T = {t}: K = {k}, Bandyopadhyay {want}");
        }
        // K → √β as T → 0, and K² T → β/Γ for T ≫ 1/Γ.
        assert!((contrast(&tau, &g1sq, 1e-9, 0.7) - 0.7f64.sqrt()).abs() < 1e-5);
        let k = contrast(&tau, &g1sq, 1e-1, 0.7);
        assert!((k * k * 1e-1 * rate / 0.7 - 1.0).abs() < 0.011, "{}", k * k * 1e-1 * rate / 0.7);
    }

    /// The quadrature's error on a mixture of exponentials (diffuse light), measured against a
    /// fine grid: 2.1·10⁻³ of K² at 8 delays per decade, 5.3·10⁻⁴ at 16 (second order in the
    /// spacing of ln τ).
    #[test]
    fn contrast_quadrature_error_on_a_mixture() {
        let g = |t: f64| {
            let g1 = 0.5 * (-1e3 * t).exp() + 0.3 * (-1e4 * t).exp() + 0.2 * (-1e5 * t).exp();
            g1 * g1
        };
        let fine = log_spaced(1e-12, 1e-1, 20_001);
        let fine_sq: Vec<f64> = fine.iter().map(|&t| g(t)).collect();
        for (points, bound) in [(57, 2.2e-3), (113, 6e-4)] {
            let tau = log_spaced(1e-8, 1e-1, points);
            let g1sq: Vec<f64> = tau.iter().map(|&t| g(t)).collect();
            let mut worst: f64 = 0.0;
            for t in [1e-7, 1e-6, 1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 1e-2] {
                let (k, exact) = (contrast(&tau, &g1sq, t, 1.0), contrast(&fine, &fine_sq, t, 1.0));
                worst = worst.max((k * k / (exact * exact) - 1.0).abs());
            }
            println!("{points} delays over 7 decades: largest relative error of K² {worst:.2e}");
            assert!(worst < bound, "{points} delays: {worst}");
        }
    }

    #[test]
    fn a_single_path_gives_its_own_correlation() {
        let spec = CorrelationSpec { tau: log_spaced(1e-6, 1e-3, 4), beta: 0.5, exposures: vec![1e-3] };
        let mut reg = Registry::default();
        let power = reg.take(1);
        let lay = spec.declare(0, "d", &mut reg);
        let mut acc = vec![0.0; reg.len];
        let (w, f, rate) = (0.3, 1234.5, 800.0);
        acc[power] += w;
        spec.record(&lay, &mut acc, w, f, rate);
        spec.finish_batch(&lay, &mut acc, power, 10.0);
        for (k, &t) in spec.tau.iter().enumerate() {
            let (re, im) = (acc[lay.g1 + k] / 10.0, acc[lay.g1 + 4 + k] / 10.0);
            let d = (-rate * t).exp();
            let ph = std::f64::consts::TAU * f * t;
            assert!((re - d * ph.cos()).abs() < 1e-14 && (im - d * ph.sin()).abs() < 1e-14);
            assert!((acc[lay.g2 + k] / 10.0 - (1.0 + 0.5 * d * d)).abs() < 1e-14);
        }
    }
}
