//! The short-time Fourier transform of a camera pixel: window, bins, and the exact expected
//! periodogram of detected paths ("lines").
//!
//! ## Normalisation
//!
//! A window of `N` samples at rate `f_s` is multiplied by `w[n]`, transformed, and the power in bin
//! `k` is `P_k = |Σ_n w[n] x[n] e^{−2πi k′n/N}|² / (N Σ_n w[n]²)`, with bins in fftshift order
//! (`ν_k = (k − N/2)·f_s/N`, DC at `k = N/2`). With this normalisation a unit-power field `x` has
//! `Σ_k P_k = Σ_n w²|x|² / Σ_n w² = 1`: bin values are *power per bin as a fraction of the emitted
//! power*, as everywhere in [`crate::spectrum`], and a line of power `p` spreads exactly `p` over
//! the `N` bins (`Σ_k K = 1`, tested).
//!
//! ## Physics
//!
//! * Finite window, Kim et al. 2025 Eq. 28: the expected measured spectrum is the path spectrum
//!   convolved with `|W(ν)|²`. For one line at `f` the DFT is a sampled Dirichlet-type kernel, and
//!   `E P_k = p · K(ν_k − f, γ)` with
//!   `K(δ, γ) = (1/(N Σw²)) Σ_{|d|<N} R_w(|d|) ρ^{|d|} cos(2π δ d/f_s)`,
//!   `R_w(d) = Σ_n w[n] w[n+d]`, `ρ = e^{−2πγ/f_s}` (the Wiener–Khinchin form of `|W|²`, exact).
//! * Brownian broadening (Lorentzian of half-width `γ`, validation-values §4.10): a line whose
//!   instantaneous frequency is Cauchy distributed with HWHM `γ` has the per-sample phase step
//!   `θ = 2π f/f_s` wrapped-Cauchy, with characteristic function `E e^{iθd} = e^{iθ₀d} ρ^{|d|}`; a
//!   phase-diffusing field `e^{iφ(t)}` (Wiener `φ`) has the same autocorrelation
//!   `e^{2πi f₀τ − 2πγ|τ|}`. Both give the kernel above exactly (second moments only; their higher
//!   statistics differ, which the periodogram mean does not see).
//! * Aliasing: `K` is periodic in `δ` with period `f_s`, as a real camera's sampled spectrum is;
//!   `|f| > f_s/2` folds back.
//! * LDH moments (Kim et al. Eq. 56, HoloDoppler's `moment0`/`directional`): [`BandKernel`] gives
//!   the band integrals `M0±` and `M1` of one line exactly, without storing a spectrum.

use std::f64::consts::PI;

use super::FrequencyAxis;
use num_complex::Complex;
use ohd_fft::Planner;

/// The analysis window of the STFT.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Window {
    /// `w[n] = 1`.
    Rect,
    /// Periodic ("DFT-even") Hann: `w[n] = 0.5 − 0.5 cos(2πn/N)`, `n = 0..N−1`.
    Hann,
}

impl Window {
    pub fn name(self) -> &'static str {
        match self {
            Window::Rect => "rect",
            Window::Hann => "hann",
        }
    }

    /// The `n` window coefficients.
    pub fn coefficients(self, n: usize) -> Vec<f64> {
        match self {
            Window::Rect => vec![1.0; n],
            Window::Hann => (0..n).map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / n as f64).cos()).collect(),
        }
    }
}

/// One detected path as a spectral line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line {
    /// Fraction of the emitted power.
    pub power: f64,
    /// Beat frequency, Hz (signed; may exceed Nyquist, then it aliases).
    pub frequency: f64,
    /// Lorentzian half width at half maximum, Hz (0 = pure tone).
    pub gamma: f64,
}

/// A short-time Fourier transform set-up: `N` samples at `f_s` with a window.
#[derive(Debug, Clone)]
pub struct Stft {
    sample_rate: f64,
    samples: usize,
    window: Window,
    coefficients: Vec<f64>,
    /// `R_w(d) = Σ_n w[n] w[n+d]`, `d = 0..N−1`.
    autocorrelation: Vec<f64>,
    /// `N Σ w²`.
    norm: f64,
}

/// `e^{2πi·frac}` for the phase `2π·f/f_s` of a frequency, reduced modulo `f_s` first (the
/// remainder is exact in floating point, so `|f| ≫ f_s` keeps full precision).
#[inline]
pub(crate) fn cycles(f: f64, sample_rate: f64) -> f64 {
    (f % sample_rate) / sample_rate
}

impl Stft {
    /// `None` unless `f_s` is finite and positive and `samples` is even and at least 2.
    pub fn new(sample_rate: f64, samples: usize, window: Window) -> Option<Self> {
        if !(sample_rate.is_finite() && sample_rate > 0.0 && samples >= 2 && samples % 2 == 0) {
            return None;
        }
        let coefficients = window.coefficients(samples);
        let autocorrelation: Vec<f64> = (0..samples)
            .map(|d| coefficients[..samples - d].iter().zip(&coefficients[d..]).map(|(a, b)| a * b).sum())
            .collect();
        let norm = samples as f64 * autocorrelation[0];
        Some(Stft { sample_rate, samples, window, coefficients, autocorrelation, norm })
    }

    pub fn sample_rate(&self) -> f64 {
        self.sample_rate
    }

    pub fn samples(&self) -> usize {
        self.samples
    }

    pub fn window(&self) -> Window {
        self.window
    }

    /// The window coefficients `w[n]`.
    pub fn coefficients(&self) -> &[f64] {
        &self.coefficients
    }

    /// `R_w(d) = Σ_n w[n] w[n+d]` for `d = 0..N−1`.
    pub fn autocorrelation(&self) -> &[f64] {
        &self.autocorrelation
    }

    /// The periodogram normalisation `N Σ w²`.
    pub fn norm(&self) -> f64 {
        self.norm
    }

    /// `f_s / N`, Hz.
    pub fn bin_width(&self) -> f64 {
        self.sample_rate / self.samples as f64
    }

    /// Frequency of bin `k` in fftshift order: `ν_k = (k − N/2)·f_s/N`, `k = 0..N` (ascending, DC at
    /// `k = N/2`).
    pub fn bin_frequency(&self, k: usize) -> f64 {
        (k as f64 - (self.samples / 2) as f64) * self.bin_width()
    }

    /// The bins `k = 1..N` whose `|ν_k|` lies in `band` (both signs), as the LDH band sums take
    /// them (bin 0, the unpaired `−f_s/2`, in neither half).
    pub fn band_bins(&self, band: (f64, f64)) -> impl Iterator<Item = usize> + '_ {
        (1..self.samples).filter(move |&k| {
            let a = self.bin_frequency(k).abs();
            band.0 <= a && a <= band.1
        })
    }

    /// The instrument's own noise on a band sum: the speckle contrast `σ/M0` of one window's M0
    /// over `band` for a field whose spectrum is flat about the band, in fully developed speckle
    /// (circular Gaussian bin amplitudes). The amplitudes of bins `m` apart have the covariance
    /// `C(m) = Σ_n w[n]² e^{−2πi mn/N}`, their powers `|C(m)|²`, so
    /// `σ/M0 = √(Σ_{k,l∈B} |C(k−l)|²) / (|B|·C(0))`: `1/√|B|` for a rectangular window, about
    /// `1.39/√|B|` for a Hann window (neighbours correlate, `|C(±1)/C(0)|² = 4/9`,
    /// `|C(±2)/C(0)|² = 1/36`). Both sums by FFT: `|C|²` from the transform of `w²`, the count of
    /// pairs `m` apart from the band's indicator. `None` for a band without bins.
    pub fn flat_band_contrast(&self, band: (f64, f64)) -> Option<f64> {
        let n = self.samples;
        let mut indicator = vec![Complex::new(0.0, 0.0); n];
        let mut count = 0usize;
        for k in self.band_bins(band) {
            indicator[k] = Complex::new(1.0, 0.0);
            count += 1;
        }
        if count == 0 {
            return None;
        }
        let mut planner = Planner::new();
        let fft = planner.forward(n);
        let mut c: Vec<Complex<f64>> = self.coefficients.iter().map(|w| Complex::new(w * w, 0.0)).collect();
        fft.process(&mut c);
        // Pairs m apart: the cyclic autocorrelation of the indicator, |FFT|² transformed back.
        fft.process(&mut indicator);
        let mut pairs: Vec<Complex<f64>> = indicator.iter().map(|x| Complex::new(x.norm_sqr(), 0.0)).collect();
        planner.inverse(n).process(&mut pairs);
        let sum: f64 = c.iter().zip(&pairs).map(|(c, p)| c.norm_sqr() * p.re / n as f64).sum();
        Some(sum.max(0.0).sqrt() / (count as f64 * c[0].re))
    }

    /// `ρ = e^{−2πγ/f_s}`, the per-sample coherence of a line of HWHM `γ`.
    pub fn coherence(&self, gamma: f64) -> f64 {
        (-2.0 * PI * gamma / self.sample_rate).exp()
    }

    /// Expected normalised periodogram power in a bin centred `offset` Hz away from a line with
    /// Lorentzian HWHM `gamma`:
    /// `K(offset, γ) = (1/(N Σw²)) Σ_{d=−(N−1)}^{N−1} R_w(|d|) ρ^{|d|} cos(2π·offset·d/f_s)`,
    /// `ρ = exp(−2πγ/f_s)`. Exact: `E|DFT|²` of a windowed tone whose frequency is Cauchy distributed
    /// with HWHM `γ` (equivalently a phase-diffusing line). Periodic in `offset` with period `f_s`
    /// (aliasing); `Σ_k K(ν_k − f, γ) = 1` for every `f` and `γ`. O(N).
    pub fn kernel(&self, offset: f64, gamma: f64) -> f64 {
        let x = cycles(offset, self.sample_rate);
        let rho = self.coherence(gamma);
        let mut sum = 0.0;
        let mut rho_d = 1.0;
        for (d, &r) in self.autocorrelation.iter().enumerate().skip(1) {
            rho_d *= rho;
            // Reduce x·d to a fraction of a cycle before the cosine (|x·d| < N).
            sum += r * rho_d * (2.0 * PI * (x * d as f64).fract()).cos();
        }
        (self.autocorrelation[0] + 2.0 * sum) / self.norm
    }

    /// Expected periodogram of a set of lines (fftshift order, `N` values):
    /// `P_k = Σ_j p_j K(ν_k − f_j, γ_j)`.
    ///
    /// Cost O(lines × N + N log N): the lines are summed into the `N` lag coefficients
    /// `C_d = Σ_j p_j ρ_j^d e^{−2πi f_j d/f_s}` (powers by repeated multiplication, error ≲ N·ε), and
    /// one N-point DFT of `R_w(d) C_d` gives all bins. A reference, not a hot path (it builds an FFT
    /// plan per call).
    pub fn expected_periodogram(&self, lines: &[Line]) -> Vec<f64> {
        let n = self.samples;
        let mut lag = vec![Complex::new(0.0, 0.0); n];
        for line in lines {
            let rho = self.coherence(line.gamma);
            let step = Complex::from_polar(rho, -2.0 * PI * cycles(line.frequency, self.sample_rate));
            let mut z = Complex::new(line.power, 0.0);
            for c in lag.iter_mut() {
                *c += z;
                z *= step;
            }
        }
        // P_k = (1/norm) Re Σ_d c_d R(d) C_d e^{2πi ν_k d/f_s}, c_0 = 1, c_d = 2; with
        // e^{2πi ν_k d/f_s} = (−1)^d e^{2πi k d/N} this is an inverse DFT over d.
        for (d, c) in lag.iter_mut().enumerate() {
            let sign = if d % 2 == 0 { 1.0 } else { -1.0 };
            let weight = if d == 0 { 1.0 } else { 2.0 };
            *c *= sign * weight * self.autocorrelation[d] / self.norm;
        }
        Planner::new().inverse(n).process(&mut lag);
        lag.iter().map(|c| c.re).collect()
    }
}

/// Band integrals of the expected periodogram, evaluated exactly per line in O(N) without storing
/// spectra.
///
/// Band `B+` = bins with `f1 ≤ ν_k ≤ f2`, `B−` = bins with `f1 ≤ −ν_k ≤ f2` (`0 < f1 < f2`; the unpaired
/// `−f_s/2` bin is in neither, so the band stays mirror symmetric).
/// `M0+ = Σ_{B+} P_k + Σ_{B−} P_k`, `M0− = Σ_{B+} P_k − Σ_{B−} P_k`, `M1 = Σ_{B+ ∪ B−} |ν_k| P_k`
/// (Hz × power).
///
/// Each band function of a line at `f` with HWHM `γ` is `Re Σ_{d=0}^{N−1} a_d z^d` with
/// `z = ρ e^{2πi f/f_s}`: with `A_d = Σ_{k∈B+} e^{−2πi ν_k d/f_s}` and `g_d = c_d R_w(d)/(N Σw²)`
/// (`c_0 = 1`, `c_d = 2`), the coefficients are `g_d·2 Re A_d` (M0+), `g_d·2i Im A_d` (M0−) and
/// `g_d·2 Σ_{B+} ν_k cos(2π ν_k d/f_s)` (M1). By the band's mirror symmetry they are real, purely
/// imaginary and real, so only their real magnitudes are stored (`M0− = −Im Σ b_d z^d`).
///
/// The higher moments ([`BandKernel::with_moments`]) weight the same bins by the signed frequency
/// and its square: `M1− = Σ_{B+} ν_k P_k − Σ_{B−} |ν_k| P_k` (coefficients `g_d·2i Σ_{B+} ν_k Im e^{−2πi ν_k d/f_s}`),
/// `M2± = Σ_{B+} ν_k² P_k ± Σ_{B−} ν_k² P_k` (`g_d·2 Σ_{B+} ν_k² cos(…)` and
/// `g_d·2i Σ_{B+} ν_k² Im e^{…}`); `M1+` is `M1`. Kim et al. Eq. 56 with `f`, `f²` under the
/// integral: `M_n± = ∫_{f1}^{f2} f^n [S(f) ± S(−f)] df`.
///
/// Evaluation splits each polynomial into even and odd powers, `p(z) = E(z²) + z O(z²)`, and runs
/// the six Horner chains in `z²` side by side over eight lanes (three functions × even/odd, one
/// pad each: measured 5–8% faster than six lanes), which the compiler vectorises: half the steps
/// and no serial dependency between the chains (measured 1.45× faster than three chains in `z`).
#[derive(Debug, Clone)]
pub struct BandKernel {
    sample_rate: f64,
    bins: usize,
    /// For `j = 0..N/2`: `[M0+, M0− (imaginary part), M1, 0]` coefficients of `d = 2j`, then
    /// the same of `d = 2j + 1`.
    coefficients: Vec<[f64; 8]>,
    /// With the higher moments: `[M1− (imaginary part), M2+, M2− (imaginary part), 0]`, likewise.
    moments: Option<Vec<[f64; 8]>>,
    /// Per function (`M0+`, `M0−`, `M1`, then `M1−`, `M2+`, `M2−`): the bound on the rounding of
    /// its evaluation, [`rounding_floor`]. A value within it is zero as far as the evaluation can
    /// tell, and is given as 0: a static line's `M0+` (zero for a Hann or rectangular window
    /// whose band starts past the leakage) was rounding residue of either sign, ±10⁻²⁰.
    floor: [f64; 6],
}

/// Horner's rule for `p(z) = Σ_d c_d z^d` of degree `N` at `|z| ≤ 1` errs by at most about
/// `2N·ε·Σ|c_d|` (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., §5.1):
/// that bound over the `N` coefficients of each function (lanes `l` and `l + 4`). Measured
/// against a brute-force periodogram sum (`band_kernel_matches_brute_force`), the errors are
/// below it (worst 6.6·10⁻¹³ of the functions' scale at N = 512); at 4× the bound that test
/// fails, as real leakage (1.3·10⁻¹² of a Hann tone's power far outside the band) is given as 0.
fn rounding_floor(coefficients: &[[f64; 8]], lane: usize) -> f64 {
    let n = 2 * coefficients.len();
    let sum: f64 = coefficients.iter().map(|c| c[lane].abs() + c[lane + 4].abs()).sum();
    2.0 * n as f64 * f64::EPSILON * sum
}

/// `x`, or 0 where `|x|` is within the rounding `floor` of its evaluation.
#[inline(always)]
fn beyond(x: f64, floor: f64) -> f64 {
    if x.abs() <= floor { 0.0 } else { x }
}

/// `x` of a function that is a sum of non-negative periodogram bins (`M0+`, `M2+`): 0 where it is
/// below the rounding `floor` of its evaluation, so never negative.
#[inline(always)]
fn nonnegative(x: f64, floor: f64) -> f64 {
    if x <= floor { 0.0 } else { x }
}

/// The higher band moments of a line ([`BandKernel::eval_moments`]): `M1−` (Hz × fraction of
/// power) and `M2±` (Hz² × fraction of power).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BandMoments {
    pub m1_minus: f64,
    pub m2_plus: f64,
    pub m2_minus: f64,
}

/// `M0+`, `M0−` (fraction of power) and `M1` (Hz × fraction of power) of a band.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BandPowers {
    pub m0_plus: f64,
    pub m0_minus: f64,
    pub m1: f64,
}

impl BandKernel {
    /// `None` if the band is empty or invalid (`f1 ≥ f2`, `f1 ≤ 0`, non-finite).
    pub fn new(stft: &Stft, f1: f64, f2: f64) -> Option<Self> {
        Self::build(stft, f1, f2, false)
    }

    /// [`new`](Self::new), also evaluating the higher moments `M1−`, `M2±`
    /// ([`eval_moments`](Self::eval_moments)).
    pub fn with_moments(stft: &Stft, f1: f64, f2: f64) -> Option<Self> {
        Self::build(stft, f1, f2, true)
    }

    fn build(stft: &Stft, f1: f64, f2: f64, moments: bool) -> Option<Self> {
        if !(f1.is_finite() && f2.is_finite() && f1 > 0.0 && f1 < f2) {
            return None;
        }
        let n = stft.samples;
        let half = n / 2;
        // Positive bins k = N/2+1 .. N−1 (ν < f_s/2, so the unpaired bin never enters).
        let band: Vec<usize> = (half + 1..n)
            .filter(|&k| {
                let nu = stft.bin_frequency(k);
                f1 <= nu && nu <= f2
            })
            .collect();
        if band.is_empty() {
            return None;
        }
        // e^{−2πi m/N} for exact integer phases m = (k − N/2)·d mod N.
        let table: Vec<(f64, f64)> = (0..n).map(|m| (2.0 * PI * m as f64 / n as f64).sin_cos()).collect();
        // The coefficients of lag `d` of the band sums weighted by `ν_k^p`: `[g·2 Σ ν^p cos, g·2 Σ ν^p Im]`.
        let weighted = |d: usize, p: i32| -> [f64; 2] {
            let g = if d == 0 { 1.0 } else { 2.0 } * stft.autocorrelation[d] / stft.norm;
            let (mut re, mut im) = (0.0, 0.0);
            for &k in &band {
                let (s, c) = table[((k - half) * d) % n];
                let w = if p == 0 { 1.0 } else { stft.bin_frequency(k).powi(p) };
                re += w * c; // Re Σ ν^p e^{−iθd}
                im -= w * s; // Im Σ ν^p e^{−iθd}
            }
            [g * 2.0 * re, g * 2.0 * im]
        };
        // Even and odd lags side by side, four functions each.
        let lanes = |f: &dyn Fn(usize) -> [f64; 3]| -> Vec<[f64; 8]> {
            (0..n / 2)
                .map(|j| {
                    let (e, o) = (f(2 * j), f(2 * j + 1));
                    [e[0], e[1], e[2], 0.0, o[0], o[1], o[2], 0.0]
                })
                .collect()
        };
        let coefficients = lanes(&|d| {
            let ([p, m], [first, _]) = (weighted(d, 0), weighted(d, 1));
            [p, m, first]
        });
        let moments = moments.then(|| {
            lanes(&|d| {
                let ([_, first], [p2, m2]) = (weighted(d, 1), weighted(d, 2));
                [first, p2, m2]
            })
        });
        let mut floor = [0.0; 6];
        for l in 0..3 {
            floor[l] = rounding_floor(&coefficients, l);
            floor[3 + l] = moments.as_ref().map_or(0.0, |m| rounding_floor(m, l));
        }
        Some(BandKernel { sample_rate: stft.sample_rate, bins: band.len(), coefficients, moments, floor })
    }

    /// Number of bins in `B+` (= in `B−`).
    pub fn bins(&self) -> usize {
        self.bins
    }

    /// Exact `M0+`, `M0−`, `M1` of one line of unit power at frequency `f` with HWHM `gamma`, by
    /// Horner's rule in `z = ρ e^{2πi f/f_s}` (`f` reduced modulo `f_s` first): `N/2` steps in
    /// `z²` of six complex multiply-adds (even and odd powers of the three band functions), all in
    /// one pass; O(N). A value within the rounding of its evaluation is 0; `M0+` is never
    /// negative.
    pub fn eval(&self, f: f64, gamma: f64) -> BandPowers {
        let z = self.z(f, gamma);
        let p = horner(&self.coefficients, z);
        let f = &self.floor;
        BandPowers { m0_plus: nonnegative(p(0).re, f[0]), m0_minus: beyond(-p(1).im, f[1]), m1: beyond(p(2).re, f[2]) }
    }

    /// Exact `M1−`, `M2+`, `M2−` of one line of unit power at `f` with HWHM `gamma`, as
    /// [`eval`](Self::eval) evaluates `M0±`, `M1`; zero if the kernel was built without them
    /// ([`with_moments`](Self::with_moments)).
    pub fn eval_moments(&self, f: f64, gamma: f64) -> BandMoments {
        let Some(co) = &self.moments else { return BandMoments::default() };
        let p = horner(co, self.z(f, gamma));
        let f = &self.floor;
        BandMoments {
            m1_minus: beyond(-p(0).im, f[3]),
            m2_plus: nonnegative(p(1).re, f[4]),
            m2_minus: beyond(-p(2).im, f[5]),
        }
    }

    /// `z = ρ e^{2πi f/f_s}` of a line at `f` (reduced modulo `f_s`) with HWHM `gamma`.
    fn z(&self, f: f64, gamma: f64) -> Complex<f64> {
        let rho = (-2.0 * PI * gamma / self.sample_rate).exp();
        Complex::from_polar(rho, 2.0 * PI * cycles(f, self.sample_rate))
    }
}

/// The three polynomials of `coefficients` (even and odd powers side by side, eight lanes) at
/// `z`, by Horner's rule in `z²`: `p(i)` is function `i`'s value.
#[inline(always)]
fn horner(coefficients: &[[f64; 8]], z: Complex<f64>) -> impl Fn(usize) -> Complex<f64> {
    let w = z * z;
    let (mut re, mut im) = ([0.0; 8], [0.0; 8]);
    for co in coefficients.iter().rev() {
        for l in 0..8 {
            let r = re[l] * w.re - im[l] * w.im + co[l];
            im[l] = re[l] * w.im + im[l] * w.re;
            re[l] = r;
        }
    }
    // p(z) = E(z²) + z·O(z²) per function.
    move |i: usize| Complex::new(re[i], im[i]) + z * Complex::new(re[i + 4], im[i + 4])
}

/// Points of a [`BandTable`] over one period `f_s` of the line's frequency: 64 per lag of an
/// `N = 512` window, so that cubic interpolation of the kernel's highest harmonic errs by
/// `(2π/64)⁴·3/128 ≈ 2·10⁻⁶` of its (window-tapered, far smaller) amplitude.
pub const BAND_TABLE_POINTS_PER_LAG: usize = 64;

/// The most `ε·N` (`ε = 2πγ/f_s`, the line's damping per lag) a [`BandTable`] serves: its
/// Taylor series in `ε` stops at `ε³`, which errs by `(εN)⁴/24 ≤ 2.6·10⁻⁷` of the functions'
/// scale here; broader lines are evaluated exactly.
pub const BAND_TABLE_MAX_DAMPING: f64 = 0.05;

/// `M0±` of a line as functions of its frequency, tabulated for the many evaluations of an
/// acquisition's windows ([`crate::detect::ldh::Acquisition`]: one line per window per detected
/// path). `M0±(f, γ) = Re/−Im Σ_d c_d e^{−εd} e^{idθ}` with `θ = 2πf/f_s`, `ε = 2πγ/f_s`
/// ([`BandKernel::eval`]); the table holds `T_k(θ) = Σ_d c_d d^k e^{idθ}` for `k ≤ 3` on a grid
/// of `θ` (one inverse FFT each), read by cubic Lagrange interpolation and summed as the Taylor
/// series `Σ_k (−ε)^k/k! T_k`. Within 10⁻⁸ (Hann) and 2·10⁻⁷ (rectangular window) of the unit
/// line's power of the exact evaluation (test `band_table_matches_the_kernel`).
#[derive(Debug, Clone)]
pub struct BandTable {
    sample_rate: f64,
    /// Lags of the window (`N`).
    lags: usize,
    /// `[k][t]`: `(M0+, M0−)` of `T_k` at `θ_t = 2πt/T`.
    tables: [Vec<[f64; 2]>; 4],
    floor: [f64; 2],
}

impl BandTable {
    /// The table of `kernel`'s `M0±`.
    pub fn new(kernel: &BandKernel) -> Self {
        let lags = 2 * kernel.coefficients.len();
        let size = lags * BAND_TABLE_POINTS_PER_LAG;
        let inverse = Planner::new().inverse(size);
        let table = |k: i32| -> Vec<[f64; 2]> {
            // Lane 0 is M0+'s coefficient (the real part), lane 1 M0−'s (minus the imaginary
            // part), each complex: c_d = [re, im] over the two functions at once would mix them,
            // so each is transformed on its own.
            let lane = |l: usize| -> Vec<Complex<f64>> {
                let mut v = vec![Complex::new(0.0, 0.0); size];
                for (j, co) in kernel.coefficients.iter().enumerate() {
                    for (d, c) in [(2 * j, co[l]), (2 * j + 1, co[l + 4])] {
                        v[d] = Complex::new(c, 0.0) * (d as f64).powi(k);
                    }
                }
                inverse.process(&mut v);
                v
            };
            let (plus, minus) = (lane(0), lane(1));
            plus.iter().zip(&minus).map(|(p, m)| [p.re, -m.im]).collect()
        };
        BandTable {
            sample_rate: kernel.sample_rate,
            lags,
            tables: [table(0), table(1), table(2), table(3)],
            floor: [kernel.floor[0], kernel.floor[1]],
        }
    }

    /// `(M0+, M0−)` of a unit line at `f` with HWHM `gamma`, or `None` for a line broader than
    /// the table serves ([`BAND_TABLE_MAX_DAMPING`]).
    #[inline]
    pub fn eval(&self, f: f64, gamma: f64) -> Option<(f64, f64)> {
        let eps = 2.0 * PI * gamma / self.sample_rate;
        // (A NaN width is refused too.)
        if eps * self.lags as f64 > BAND_TABLE_MAX_DAMPING || eps.is_nan() {
            return None;
        }
        let size = self.tables[0].len();
        let x = (cycles(f, self.sample_rate) * size as f64).rem_euclid(size as f64);
        let i = (x as usize).min(size - 1);
        let u = x - i as f64;
        // Cubic Lagrange weights on the points i − 1, i, i + 1, i + 2.
        let w = [
            -u * (u - 1.0) * (u - 2.0) / 6.0,
            (u + 1.0) * (u - 1.0) * (u - 2.0) / 2.0,
            -(u + 1.0) * u * (u - 2.0) / 2.0,
            (u + 1.0) * u * (u - 1.0) / 6.0,
        ];
        let at = |t: &[[f64; 2]], c: usize| -> f64 { (0..4).map(|j| w[j] * t[(i + size + j - 1) % size][c]).sum() };
        let series = |c: usize| -> f64 {
            let t = &self.tables;
            if eps == 0.0 {
                return at(&t[0], c);
            }
            at(&t[0], c) - eps * (at(&t[1], c) - eps / 2.0 * (at(&t[2], c) - eps / 3.0 * at(&t[3], c)))
        };
        Some((nonnegative(series(0), self.floor[0]), beyond(series(1), self.floor[1])))
    }
}

/// The expected single-window periodogram of a power histogram on a [`FrequencyAxis`] (fftshift
/// order, `N` values): `S_k = Σ_j H_j K(ν_k − f_j, 0)` with `f_j` the centre of axis bin `j`,
/// i.e. [`Stft::expected_periodogram`] of one pure tone per bin. This is the per-pixel speckle's
/// expectation ([`crate::post::speckle`]): the histogram does not keep where in its bin a path
/// fell, so every path counts at its bin's centre (a Brownian path's Lorentzian, already spread
/// over the bins by [`FrequencyAxis::add_line`], likewise). The out-of-range tallies are not used.
///
/// Cost per histogram: on the STFT's own grid (bins `f_s/N` wide, centres at integer multiples of
/// `f_s/N`, as the default LDH axis) the bins fold modulo `f_s` onto the `N` STFT frequencies
/// (aliasing, as `K` is `f_s`-periodic) and the lag sums are one `N`-point FFT: two FFTs in all,
/// O(N log N). On any other axis the lag sums are accumulated per non-empty bin:
/// O(non-empty bins × N). Plans and buffers are built once; reuse one per thread.
pub struct BinnedPeriodogram {
    n: usize,
    /// The STFT bin (`0..N`, unshifted: `m` is the frequency `m f_s/N` modulo `f_s`) each axis bin
    /// folds onto, when the axis is on the STFT grid.
    folded: Option<Vec<usize>>,
    /// `e^{−2πi f_j/f_s}` per axis bin (the general path).
    steps: Vec<Complex<f64>>,
    /// `(−1)^d c_d R_w(d)/(N Σw²)`, `c_0 = 1`, `c_d = 2`.
    weights: Vec<f64>,
    forward: std::sync::Arc<dyn ohd_fft::Fft<f64>>,
    inverse: std::sync::Arc<dyn ohd_fft::Fft<f64>>,
    lag: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
}

impl BinnedPeriodogram {
    pub fn new(stft: &Stft, axis: &FrequencyAxis) -> Self {
        let n = stft.samples;
        let delta = stft.bin_width();
        let first = axis.center(0) / delta;
        let on_grid = ((axis.bin_width() - delta).abs() <= 1e-9 * delta) && (first - first.round()).abs() <= 1e-6;
        let folded = on_grid.then(|| {
            let i0 = first.round() as i64;
            (0..axis.bins).map(|j| (i0 + j as i64).rem_euclid(n as i64) as usize).collect()
        });
        let steps = (0..axis.bins)
            .map(|j| Complex::from_polar(1.0, -2.0 * PI * cycles(axis.center(j), stft.sample_rate)))
            .collect();
        let weights = (0..n)
            .map(|d| {
                let sign = if d % 2 == 0 { 1.0 } else { -1.0 };
                let c = if d == 0 { 1.0 } else { 2.0 };
                sign * c * stft.autocorrelation[d] / stft.norm
            })
            .collect();
        let mut planner = Planner::new();
        let forward = planner.forward(n);
        let inverse = planner.inverse(n);
        let scratch_len = forward.get_inplace_scratch_len().max(inverse.get_inplace_scratch_len());
        let zero = Complex::new(0.0, 0.0);
        BinnedPeriodogram {
            n,
            folded,
            steps,
            weights,
            forward,
            inverse,
            lag: vec![zero; n],
            scratch: vec![zero; scratch_len],
        }
    }

    /// Whether the axis is on the STFT grid (the O(N log N) path).
    pub fn on_stft_grid(&self) -> bool {
        self.folded.is_some()
    }

    /// `S_k` of the histogram `hist` (the axis's bins, without the out-of-range tallies) into
    /// `out` (`N` values, fftshift order as [`Stft::bin_frequency`]). `S_k ≥ 0` exactly; the
    /// rounding of the FFTs (≲ 1e-16 of `Σ H`) is clamped at 0. Returns `false` (and zeros) if the
    /// histogram is empty.
    pub fn expected(&mut self, hist: &[f64], out: &mut [f64]) -> bool {
        assert_eq!(hist.len(), self.steps.len(), "one value per axis bin");
        assert_eq!(out.len(), self.n, "output length must be N");
        if hist.iter().all(|&h| h == 0.0) {
            out.fill(0.0);
            return false;
        }
        let zero = Complex::new(0.0, 0.0);
        self.lag.fill(zero);
        match &self.folded {
            Some(folded) => {
                // C_d = Σ_m h_m e^{−2πi m d/N}: the forward DFT of the folded histogram.
                for (&m, &h) in folded.iter().zip(hist) {
                    self.lag[m].re += h;
                }
                self.forward.process_with_scratch(&mut self.lag, &mut self.scratch);
            }
            None => {
                for (&step, &h) in self.steps.iter().zip(hist) {
                    if h == 0.0 {
                        continue;
                    }
                    let mut z = Complex::new(h, 0.0);
                    for c in self.lag.iter_mut() {
                        *c += z;
                        z *= step;
                    }
                }
            }
        }
        // As in Stft::expected_periodogram: an inverse DFT over the lags gives the bins.
        for (c, &w) in self.lag.iter_mut().zip(&self.weights) {
            *c *= w;
        }
        self.inverse.process_with_scratch(&mut self.lag, &mut self.scratch);
        for (o, c) in out.iter_mut().zip(&self.lag) {
            *o = c.re.max(0.0);
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FS: f64 = 39_000.0;

    /// |Σ_n w[n] e^{2πi (f − ν) n/f_s}|²/(N Σw²), summed directly with exact phases.
    fn direct_tone_power(stft: &Stft, offset: f64) -> f64 {
        let x = cycles(offset, stft.sample_rate());
        let mut s = Complex::new(0.0, 0.0);
        for (n, &w) in stft.coefficients().iter().enumerate() {
            s += Complex::from_polar(w, 2.0 * PI * (x * n as f64).fract());
        }
        s.norm_sqr() / stft.norm()
    }

    #[test]
    fn constructor_and_bins() {
        assert!(Stft::new(FS, 63, Window::Rect).is_none());
        assert!(Stft::new(FS, 0, Window::Rect).is_none());
        assert!(Stft::new(f64::NAN, 64, Window::Rect).is_none());
        assert!(Stft::new(-1.0, 64, Window::Rect).is_none());
        let s = Stft::new(FS, 64, Window::Hann).unwrap();
        assert_eq!(s.bin_frequency(32), 0.0);
        assert_eq!(s.bin_frequency(0), -FS / 2.0);
        assert!((s.bin_width() - 609.375).abs() < 1e-12);
        let w = Window::Hann.coefficients(8);
        assert_eq!(w[0], 0.0);
        assert!((w[4] - 1.0).abs() < 1e-15); // periodic: peak at N/2, no trailing zero
        assert!((w[1] - w[7]).abs() < 1e-15);
        assert_eq!(Window::Hann.name(), "hann");
        // Hann: Σw² = 3N/8.
        assert!((s.norm() - 64.0 * 24.0).abs() < 1e-9);
    }

    /// The speckle of one window's band sum over a flat spectrum: `1/√|B|` for a rectangular
    /// window; the Hann window's by its correlated neighbours, as a direct double sum gives it;
    /// the figures HoloDoppler's set-ups give (512 frames at
    /// 39 kHz over 6–18.3 kHz: 324 bins, 5.6 % / 7.7 %; 64 frames: 42 bins, 15 % / 21 %).
    #[test]
    fn flat_band_contrast_is_the_speckle_of_the_band_sum() {
        for (n, bins, rect, hann) in [(512, 324, 0.056, 0.077), (64, 42, 0.15, 0.21)] {
            let r = Stft::new(FS, n, Window::Rect).unwrap();
            assert_eq!(r.band_bins((6e3, 18.3e3)).count(), bins);
            let c = r.flat_band_contrast((6e3, 18.3e3)).unwrap();
            assert!((c - 1.0 / (bins as f64).sqrt()).abs() < 1e-12 && (c - rect).abs() < 0.005, "{n}: {c}");
            let h = Stft::new(FS, n, Window::Hann).unwrap();
            let c = h.flat_band_contrast((6e3, 18.3e3)).unwrap();
            // Direct: C(m) = Σ_n w² e^{−2πi mn/N}, pairs over the band's bins.
            let w2: Vec<f64> = h.coefficients().iter().map(|w| w * w).collect();
            let cov = |m: i64| -> f64 {
                let z: Complex<f64> = w2
                    .iter()
                    .enumerate()
                    .map(|(j, &x)| Complex::from_polar(x, -2.0 * PI * (m * j as i64) as f64 / n as f64))
                    .sum();
                z.norm_sqr()
            };
            let b: Vec<i64> = h.band_bins((6e3, 18.3e3)).map(|k| k as i64).collect();
            let direct = b.iter().flat_map(|&k| b.iter().map(move |&l| k - l)).map(cov).sum::<f64>().sqrt()
                / (b.len() as f64 * w2.iter().sum::<f64>());
            assert!((c - direct).abs() < 1e-9 * direct && (c - hann).abs() < 0.005, "{n}: {c} against {direct}");
        }
        let s = Stft::new(FS, 64, Window::Hann).unwrap();
        assert_eq!(s.flat_band_contrast((30e3, 40e3)), None);
    }

    #[test]
    fn kernel_sums_to_one() {
        for window in [Window::Rect, Window::Hann] {
            for n in [64, 512] {
                let s = Stft::new(FS, n, window).unwrap();
                let delta = s.bin_width();
                for &f in &[0.0, 123.4, -5_000.7, 19_499.0, 47_311.1, -3.0e5 - 17.3, 2.5e7 + 0.3] {
                    for &g in &[0.0, 0.3 * delta, 5.0 * delta] {
                        let sum: f64 = (0..n).map(|k| s.kernel(s.bin_frequency(k) - f, g)).sum();
                        assert!((sum - 1.0).abs() < 1e-12, "{window:?} N={n} f={f} γ={g}: Σ K = {sum}");
                    }
                }
            }
        }
    }

    #[test]
    fn kernel_rect_is_dirichlet() {
        let n = 64;
        let s = Stft::new(FS, n, Window::Rect).unwrap();
        for &offset in &[1.0, 37.3, 304.7, 609.375 * 2.5, -7_777.7, 19_000.0, 60_123.4] {
            let x: f64 = offset / FS;
            let nn = n as f64;
            let dirichlet = (PI * nn * x).sin().powi(2) / (nn * nn * (PI * x).sin().powi(2));
            let k = s.kernel(offset, 0.0);
            assert!((k - dirichlet).abs() < 1e-12, "offset {offset}: {k} vs {dirichlet}");
        }
        assert!((s.kernel(0.0, 0.0) - 1.0).abs() < 1e-14);
        assert!(s.kernel(s.bin_width(), 0.0).abs() < 1e-14); // zeros at multiples of 1/T
    }

    #[test]
    fn kernel_is_the_windowed_tone_power() {
        for window in [Window::Rect, Window::Hann] {
            for n in [64, 512] {
                let s = Stft::new(FS, n, window).unwrap();
                for &offset in &[0.0, 11.1, 333.3, -1234.5, 9_876.5, 38_999.9, -123_456.7] {
                    let (k, d) = (s.kernel(offset, 0.0), direct_tone_power(&s, offset));
                    assert!((k - d).abs() < 1e-12, "{window:?} N={n} offset {offset}: {k} vs {d}");
                }
            }
        }
    }

    #[test]
    fn kernel_is_periodic_and_lorentzian_for_wide_lines() {
        let s = Stft::new(FS, 64, Window::Hann).unwrap();
        for &o in &[10.0, 700.0, -2_000.0] {
            assert!((s.kernel(o, 50.0) - s.kernel(o + 3.0 * FS, 50.0)).abs() < 1e-13);
            assert!((s.kernel(o, 50.0) - s.kernel(-o, 50.0)).abs() < 1e-15);
        }
        // γ ≫ bin width and ≪ f_s: the kernel approaches the Lorentzian mass of one bin,
        // Δ·γ/(π(δ² + γ²)), up to aliasing and the window's smoothing (a few percent).
        let gamma = 3_000.0;
        for &o in &[0.0, 1_000.0, 4_000.0] {
            let lorentz = s.bin_width() * gamma / (PI * (o * o + gamma * gamma));
            let k = s.kernel(o, gamma);
            assert!((k / lorentz - 1.0).abs() < 0.1, "offset {o}: {k} vs {lorentz}");
        }
    }

    #[test]
    fn expected_periodogram_is_the_kernel_sum() {
        for window in [Window::Rect, Window::Hann] {
            let s = Stft::new(FS, 64, window).unwrap();
            let lines = [
                Line { power: 0.5, frequency: 1_234.5, gamma: 0.0 },
                Line { power: 0.25, frequency: -9_876.0, gamma: 80.0 },
                Line { power: 0.125, frequency: 3.0 * FS + 17.0, gamma: 2_000.0 },
                Line { power: 0.125, frequency: 19_500.0, gamma: 0.0 },
            ];
            let p = s.expected_periodogram(&lines);
            assert_eq!(p.len(), 64);
            for (k, &pk) in p.iter().enumerate() {
                let reference: f64 =
                    lines.iter().map(|l| l.power * s.kernel(s.bin_frequency(k) - l.frequency, l.gamma)).sum();
                assert!((pk - reference).abs() < 1e-13, "bin {k}: {pk} vs {reference}");
            }
            assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
    }

    fn brute_band(s: &Stft, f1: f64, f2: f64, f: f64, gamma: f64) -> (BandPowers, BandMoments) {
        let (mut out, mut m) = (BandPowers::default(), BandMoments::default());
        let n = s.samples();
        for k in 1..n {
            let nu = s.bin_frequency(k);
            let p = s.kernel(nu - f, gamma);
            // Both bands by the definition: M_n± = Σ_{B+} |ν|^n P ± Σ_{B−} |ν|^n P.
            for (inside, sign) in [(f1 <= nu && nu <= f2, 1.0), (f1 <= -nu && -nu <= f2, -1.0)] {
                if inside {
                    out.m0_plus += p;
                    out.m0_minus += sign * p;
                    out.m1 += nu.abs() * p;
                    m.m1_minus += sign * nu.abs() * p;
                    m.m2_plus += nu * nu * p;
                    m.m2_minus += sign * nu * nu * p;
                }
            }
        }
        (out, m)
    }

    #[test]
    fn band_table_matches_the_kernel() {
        // The table against the exact evaluation over the frequencies (negative, past f_s, on
        // and between grid points) and line widths up to its limit; beyond it, `None`.
        for window in [Window::Rect, Window::Hann] {
            for n in [64, 512] {
                let s = Stft::new(FS, n, window).unwrap();
                for &(f1, f2) in &[(6_000.0, 18_300.0), (500.0, 1_500.0)] {
                    let band = BandKernel::new(&s, f1, f2).unwrap();
                    let table = BandTable::new(&band);
                    let top = 2.0 * PI * (n as f64) / FS;
                    let mut worst: f64 = 0.0;
                    for i in 0..4000 {
                        let f = -70_000.0 + 37.913 * i as f64;
                        for g in [0.0, 0.3 * BAND_TABLE_MAX_DAMPING / top, BAND_TABLE_MAX_DAMPING / top] {
                            let e = band.eval(f, g);
                            let (p, m) = table.eval(f, g).expect("within the table's damping");
                            worst = worst.max((p - e.m0_plus).abs()).max((m - e.m0_minus).abs());
                        }
                    }
                    // Measured: 1e-8 (Hann), 2e-7 (rectangular).
                    assert!(worst < 1e-6, "{window:?} N {n} band {f1}..{f2}: {worst:e}");
                    assert!(table.eval(1e3, 1.01 * BAND_TABLE_MAX_DAMPING / top).is_none());
                }
            }
        }
    }

    #[test]
    fn band_kernel_matches_brute_force() {
        // Scale of the error: 1e-12 of the band functions' natural size (1 for M0±, f2 for M1±, f2² for M2±;
        // both are attained for a line inside the band), or of the value if larger.
        let mut worst: f64 = 0.0;
        for window in [Window::Rect, Window::Hann] {
            for n in [64, 512] {
                let s = Stft::new(FS, n, window).unwrap();
                for &(f1, f2) in &[(6_000.0, 18_300.0), (500.0, 1_500.0), (10_000.0, 19_500.0), (100.0, 30_000.0)] {
                    let Some(band) = BandKernel::with_moments(&s, f1, f2) else { panic!("band {f1}..{f2} empty") };
                    for i in 0..40 {
                        let f = -60_000.0 + 3_001.37 * i as f64;
                        for &g in &[0.0, 0.3 * s.bin_width(), 5.0 * s.bin_width(), 3_000.0] {
                            let (e, em) = (band.eval(f, g), band.eval_moments(f, g));
                            let (b, bm) = brute_band(&s, f1, f2, f, g);
                            // The higher moments at the scale f2 (M1−) and f2² (M2±).
                            let err_m1 = (em.m1_minus - bm.m1_minus).abs() / bm.m1_minus.abs().max(f2);
                            let err_2p = (em.m2_plus - bm.m2_plus).abs() / bm.m2_plus.abs().max(f2 * f2);
                            let err_2m = (em.m2_minus - bm.m2_minus).abs() / bm.m2_minus.abs().max(f2 * f2);
                            worst = worst.max(err_m1).max(err_2p).max(err_2m);
                            assert!(
                                err_m1 < 1e-12 && err_2p < 1e-12 && err_2m < 1e-12,
                                "{window:?} N={n} band {f1}..{f2} f={f} γ={g}: {em:?} vs {bm:?}"
                            );
                            let err_p = (e.m0_plus - b.m0_plus).abs() / b.m0_plus.abs().max(1.0);
                            let err_m = (e.m0_minus - b.m0_minus).abs() / b.m0_minus.abs().max(1.0);
                            let err_1 = (e.m1 - b.m1).abs() / b.m1.abs().max(f2);
                            worst = worst.max(err_p).max(err_m).max(err_1);
                            assert!(
                                err_p < 1e-12 && err_m < 1e-12 && err_1 < 1e-12,
                                "{window:?} N={n} band {f1}..{f2} f={f} γ={g}: {e:?} vs {b:?}"
                            );
                        }
                    }
                }
            }
        }
        eprintln!("band kernel vs brute force: worst scaled error {worst:.2e}");
    }

    #[test]
    fn band_kernel_symmetry_and_leakage() {
        let s = Stft::new(FS, 64, Window::Hann).unwrap();
        let band = BandKernel::with_moments(&s, 6_000.0, 18_300.0).unwrap();
        // Bins 6094 … 18281 Hz: k − N/2 = 10 … 30.
        assert_eq!(band.bins(), 21);
        // The moments' kernel leaves M0± and M1 as they are, bit for bit.
        let plain = BandKernel::new(&s, 6_000.0, 18_300.0).unwrap();
        assert_eq!(plain.eval(12_345.6, 321.0), band.eval(12_345.6, 321.0));
        assert_eq!(plain.eval_moments(12_345.6, 321.0), BandMoments::default());
        for i in 0..50 {
            let f = -45_000.0 + 1_837.9 * i as f64;
            for &g in &[0.0, 200.0, 4_000.0] {
                let (p, m) = (band.eval(f, g), band.eval(-f, g));
                assert!((p.m0_plus - m.m0_plus).abs() < 1e-14, "M0+ even");
                assert!((p.m0_minus + m.m0_minus).abs() < 1e-14, "M0− odd");
                assert!((p.m1 - m.m1).abs() < 1e-14 * 18_300.0, "M1 even");
                let (pm, mm) = (band.eval_moments(f, g), band.eval_moments(-f, g));
                assert!((pm.m1_minus + mm.m1_minus).abs() < 1e-14 * 18_300.0, "M1− odd");
                assert!((pm.m2_plus - mm.m2_plus).abs() < 1e-14 * 18_300.0_f64.powi(2), "M2+ even");
                assert!((pm.m2_minus + mm.m2_minus).abs() < 1e-14 * 18_300.0_f64.powi(2), "M2− odd");
            }
        }
        // A pure tone in the middle of the band (12.4 kHz = 20.37 bins, ≥ 9.6 bins from either edge):
        // with Hann the leakage out of the band is 1 − M0+ = 1.48e-7 and into the mirror band B−
        // (M0+ − M0−)/2 = 2.6e-8 (both also from numpy's FFT of the windowed tone); checked as
        // < 1e-6 and < 1e-7. A rect window's sinc² tails leak 1 − M0+ = 8.8e-3 (checked in
        // 0.005..0.05).
        let f = 20.37 * s.bin_width();
        let hann = band.eval(f, 0.0);
        let rect = BandKernel::new(&Stft::new(FS, 64, Window::Rect).unwrap(), 6_000.0, 18_300.0).unwrap().eval(f, 0.0);
        let mirror = (hann.m0_plus - hann.m0_minus) / 2.0;
        eprintln!(
            "tone at {f:.1} Hz: Hann 1 − M0+ = {:.3e}, B− power {mirror:.3e}; rect 1 − M0+ = {:.3e}",
            1.0 - hann.m0_plus,
            1.0 - rect.m0_plus
        );
        assert!(1.0 - hann.m0_plus < 1e-6 && 1.0 - hann.m0_plus > 0.0);
        assert!(mirror > 0.0 && mirror < 1e-7);
        assert!((0.005..0.05).contains(&(1.0 - rect.m0_plus)));
        // M1/M0+ is the mean |frequency| of the band power: close to the tone for Hann; so are the
        // signed mean M1−/M0+ (of −f: −f) and the RMS √(M2+/M0+) (the tone's spread, ±2 bins, adds
        // < 0.3 % of f).
        assert!((hann.m1 / hann.m0_plus - f).abs() < 0.01 * s.bin_width());
        let (hm, hm_neg) = (band.eval_moments(f, 0.0), band.eval_moments(-f, 0.0));
        assert!((hm.m1_minus / hann.m0_plus - f).abs() < 0.01 * s.bin_width());
        assert!((hm_neg.m1_minus / hann.m0_plus + f).abs() < 0.01 * s.bin_width());
        let rms = (hm.m2_plus / hann.m0_plus).sqrt();
        assert!(rms >= f && rms - f < 0.003 * f, "RMS {rms} of a tone at {f}");
    }

    /// A static line (f = 0, γ = 0) puts no power into a band past the window's leakage (Hann:
    /// bins 0 and ±1; rect: bin 0): its `M0±` and `M1` are exactly 0, not rounding residue of
    /// either sign (issue 37: the static class's M0+ image was ±10⁻²⁰); and `M0+`, `M2+`, sums of
    /// non-negative bins, are never negative.
    #[test]
    fn band_kernel_static_line_is_zero_and_m0_plus_never_negative() {
        for window in [Window::Rect, Window::Hann] {
            for n in [64, 512] {
                let s = Stft::new(FS, n, window).unwrap();
                let band = BandKernel::with_moments(&s, 6_000.0, 18_300.0).unwrap();
                eprintln!("{window:?} N={n}: rounding floors {:?}", band.floor);
                assert!(band.floor.iter().all(|f| *f > 0.0 && *f < 1e-10 * 18_300.0_f64.powi(2)));
                assert_eq!(band.eval(0.0, 0.0), BandPowers::default(), "{window:?} N={n}");
                assert_eq!(band.eval_moments(0.0, 0.0), BandMoments::default(), "{window:?} N={n}");
                for i in 0..400 {
                    let f = -60_000.0 + 301.37 * i as f64;
                    for &g in &[0.0, 0.3 * s.bin_width(), 3_000.0] {
                        let (e, m) = (band.eval(f, g), band.eval_moments(f, g));
                        assert!(e.m0_plus >= 0.0 && m.m2_plus >= 0.0, "{window:?} N={n} f={f} γ={g}: {e:?} {m:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn band_kernel_rejects_bad_bands() {
        let s = Stft::new(FS, 64, Window::Hann).unwrap();
        assert!(BandKernel::new(&s, 0.0, 1_000.0).is_none());
        assert!(BandKernel::new(&s, 2_000.0, 1_000.0).is_none());
        assert!(BandKernel::new(&s, 100.0, 200.0).is_none()); // between bins 0 and 609 Hz
        assert!(BandKernel::new(&s, 100.0, f64::INFINITY).is_none());
        // A band reaching past Nyquist stops at the last paired bin.
        assert_eq!(BandKernel::new(&s, 18_000.0, 50_000.0).unwrap().bins(), 2);
    }
    #[test]
    fn binned_periodogram_is_the_expected_periodogram_of_bin_centres() {
        // On the STFT grid (the default LDH axis: N + 1 bins odd-centred on DC) and off it (a
        // finer, shifted axis wider than f_s: aliasing), S equals the expected periodogram of one
        // tone per bin at its centre.
        for window in [Window::Rect, Window::Hann] {
            let stft = Stft::new(FS, 64, window).unwrap();
            let d = stft.bin_width();
            let axes = [
                crate::spectrum::FrequencyAxis::new(-32.5 * d, 32.5 * d, 65).unwrap(),
                crate::spectrum::FrequencyAxis::new(-1.3 * FS, 0.9 * FS, 301).unwrap(),
                crate::spectrum::FrequencyAxis::new(-64.5 * d, 95.5 * d, 160).unwrap(),
            ];
            for (a, axis) in axes.iter().enumerate() {
                let mut bp = BinnedPeriodogram::new(&stft, axis);
                assert_eq!(bp.on_stft_grid(), a != 1, "axis {a}");
                let hist: Vec<f64> =
                    (0..axis.bins).map(|j| if j % 7 == 3 { 0.0 } else { 1.0 + ((j * 37) % 11) as f64 }).collect();
                let lines: Vec<Line> = hist
                    .iter()
                    .enumerate()
                    .map(|(j, &h)| Line { power: h, frequency: axis.center(j), gamma: 0.0 })
                    .collect();
                let reference = stft.expected_periodogram(&lines);
                let mut s = vec![0.0; 64];
                assert!(bp.expected(&hist, &mut s));
                let total: f64 = hist.iter().sum();
                for (k, (x, r)) in s.iter().zip(&reference).enumerate() {
                    assert!((x - r).abs() < 1e-12 * total, "axis {a}, bin {k}: {x} vs {r}");
                }
                assert!((s.iter().sum::<f64>() / total - 1.0).abs() < 1e-12);
                assert!(!bp.expected(&vec![0.0; axis.bins], &mut s) && s.iter().all(|&v| v == 0.0));
            }
        }
    }
}
