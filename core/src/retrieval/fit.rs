//! One- and two-Gaussian fits of a gate spectrum, as Wei et al. 2019 (Opt. Express 27:31235)
//! separate the aerosol and rain peaks of a coherent Doppler lidar.
//!
//! **Model.** With `f_k` the bin centres,
//! `S(f_k) = b + Σ_{j=1..m} A_j·exp(−(f_k − μ_j)²/(2 s_j²))`, `m ∈ {1, 2}`, where `A_j` is the
//! component's peak value *per bin* (the units of the spectrum), `μ_j` its mean and `s_j` its
//! standard deviation (Hz), and `b` the white floor per bin, fixed or fitted ([`Floor`]). The
//! component's power (its sum over bins, for `s_j ≳ Δ` and a component inside the axis) is
//! `A_j·s_j·√(2π)/Δ`. The model samples the line at the bin centres; for a histogram of a
//! density the fitted `s_j²` exceeds the density's by `Δ²/12` (see
//! [`MomentOptions::bin_integrated`](super::MomentOptions::bin_integrated)).
//!
//! **Components seen through a gate's kernel.** A range gate of a pulsed lidar does not show a
//! line as a Gaussian: its expected periodogram is the scatterers' velocity distribution seen
//! through the gate's own spectral kernel (for a short rectangular gate nearly a Fejér, sinc²,
//! kernel). Given a [`GateKernel`] ([`fit_one_or_two_with_kernel`], [`fit_gaussians_with_kernel`])
//! each component is instead the expected `K`-point periodogram of a Gaussian spread of beat
//! frequencies (mean `μ_j`, standard deviation `s_j`) through the gate's lag window `L_d`:
//! `S_j(ν) = (P_j/K)·[L_0 + 2 Re Σ_{d=1}^{M−1} L_d·e^{−2π² s_j² d² Δt²}·e^{2πi(μ_j − ν)dΔt}]/L_0`
//! (derivation at [`GateKernel`]), where `P_j` is the component's power (its sum over the `K`
//! bins of the DFT). `s_j` is then the scatterers' own spread (the kernel's width deconvolved,
//! 0 for one velocity) and `μ_j` the line's centre. The parameters are `(ln P_j, μ_j, s_j²)`
//! (`s²` in bins², bounded below by `min_sigma_hz²`, default 0, and above by the axis width²:
//! the model is smooth in `s²` down to and at 0, where `ln s` would not be), with the analytic
//! Jacobian of the lag sum. Everything else (floor, weights, Levenberg–Marquardt, bounds on the
//! means, F-test, uncertainties) is as for plain Gaussians.
//!
//! **Estimator.** Weighted least squares, `χ² = Σ_k ((y_k − S(f_k))/σ_k)²` with the per-bin
//! standard errors `σ_k` if given (else `σ_k = 1`), minimised by Levenberg–Marquardt (Marquardt
//! 1963: `(JᵀJ + λ·diag JᵀJ)·δ = Jᵀr`, λ divided by 10 after a step that lowers χ², multiplied
//! by 10 after one that does not) with the analytic Jacobian. The parameters are
//! `(ln A_j, μ_j, ln s_j)` (and `b`), so amplitudes and widths stay positive; internally
//! frequencies are in bins, so every parameter has a natural unit of order 1. Trial points are
//! projected onto bounds that keep each component's mean on the axis and its width within
//! `[max(0.1 bin, FitOptions::min_sigma_hz), axis width]` (a narrower line is one bin or noise, a
//! wider one is indistinguishable from the floor). Stopping: an accepted step that lowers χ² by
//! less than 10⁻¹⁰ relative and is shorter than 10⁻³ standard errors; or no step lowering χ² at
//! any damping (round-off); else [`RetrievalError::DidNotConverge`] after
//! [`FitOptions::max_iterations`].
//!
//! **Uncertainties.** The covariance of the parameters is `(JᵀWJ)⁻¹` at the minimum, scaled by the
//! reduced `χ²/dof` when no standard errors are given (the noise level is then estimated from the
//! residuals); standard errors of derived quantities follow to first order.
//!
//! **Labels.** Components are returned sorted by increasing `s_j`: `components[0]` is the
//! narrow one. In a wind-lidar gate that is the aerosol, which moves with the air and is only
//! broadened by turbulence and the pulse; rain is the broad one, because drops of different sizes
//! fall at different terminal speeds (Wei et al. 2019). The rule is the caller's to trust: this
//! module only sorts by width.

use super::linalg::{cholesky, cholesky_solve, condition_number, spd_inverse};
use super::special::f_distribution_sf;
use super::{
    MomentOptions, RetrievalError, check_finite, check_len, check_stderr, check_wavelength, gate_estimates_with,
    radial_velocity,
};
use crate::spectrum::FrequencyAxis;
use std::f64::consts::PI;

/// `FWHM = 2√(2 ln 2)·σ` for a Gaussian.
const FWHM_PER_SIGMA: f64 = 2.354_820_045_030_949;

/// The noise floor of the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Floor {
    /// Known white floor per bin (0 for a floor already subtracted).
    Fixed(f64),
    /// Fitted as one more (linear) parameter.
    Fitted,
}

/// Fit settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// Default `Floor::Fixed(0.0)`.
    pub floor: Floor,
    /// Levenberg–Marquardt iterations (Jacobian evaluations) before
    /// [`RetrievalError::DidNotConverge`]; default 200.
    pub max_iterations: usize,
    /// The narrowest component standard deviation (Hz) a fit may reach; at least 0.1 bin is
    /// always enforced. Default 0. Set it to the spectral resolution (the standard deviation of the
    /// window's or pulse's spectral response): a narrower component can only be a noise bump.
    /// On the tested one-line spectra a 2-bin bound halves [`fit_one_or_two`]'s false alarms.
    pub min_sigma_hz: f64,
    /// [`fit_one_or_two`] keeps two components when the F-test's `p` is below this nominal level.
    /// Default 0.01 (see [`fit_one_or_two`] for the false-alarm rate it really gives).
    pub selection_level: f64,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions { floor: Floor::Fixed(0.0), max_iterations: 200, min_sigma_hz: 0.0, selection_level: 0.01 }
    }
}

/// The spectral kernel of a range gate: its lag window `L_d` (`d = 0 … M − 1`), sample interval
/// `Δt` and DFT length `K`, for fits of components seen through the gate
/// ([`fit_one_or_two_with_kernel`]).
///
/// **Derivation.** A gate's expected periodogram (`K`-point zero-padded DFT of its `M` samples,
/// `P = |X|²/K`, bins `ν`) is `P(ν) = (1/K)·[D_0 + 2 Re Σ_{d=1}^{M−1} D_d e^{−2πiνdΔt}]` with the
/// lag sums `D_d = Σ_paths w·e^{2πi f dΔt}·Σ_m x_{m+d} x_m` (the receiver's own accumulation,
/// [`LidarSpec::finish_batch`](crate::detect::LidarSpec::finish_batch)). When the beat frequencies
/// `f` of the scatterers are independent of their echo delays, the expectation over `f`
/// factorises: `D_d = W·L_d·φ(dΔt)` with `L_d` the delay-averaged `Σ_m x_{m+d} x_m` (the lag
/// window, up to a constant) and `φ(τ) = E e^{2πifτ}` the characteristic function of the
/// frequencies; for a Gaussian of mean `μ` and standard deviation `s`,
/// `φ(τ) = e^{2πiμτ − 2π²s²τ²}`. Hence
/// `P(ν) = (W/K)·[L_0 + 2 Re Σ_{d≥1} L_d·e^{−2π²s²d²Δt²}·e^{2πi(μ − ν)dΔt}]`. Over the `K` bins
/// `ν_k = (k − K/2)/(KΔt)` of the DFT, `Σ_k e^{−2πiν_k dΔt} = 0` for `0 < d < K`, so
/// `Σ_k P(ν_k) = W·L_0` (Parseval): dividing by `L_0` makes the amplitude the component's power.
/// `s = 0` gives the kernel itself. Only the shape of `L_d` matters (its scale cancels).
#[derive(Debug, Clone, PartialEq)]
pub struct GateKernel {
    /// The lag window `L_d`, `d = 0 … M − 1`; `L_0 > 0`.
    pub lags: Vec<f64>,
    /// Sample interval `Δt`, s.
    pub dt: f64,
    /// DFT length `K ≥ M`.
    pub fft_points: usize,
}

impl GateKernel {
    /// Errors unless the lags are finite with `L_0 > 0`, `Δt` is finite and positive, and
    /// `K ≥ M ≥ 1`.
    pub fn validate(&self) -> Result<(), RetrievalError> {
        check_finite("kernel lags", &self.lags)?;
        let l0 = self.lags.first().copied().unwrap_or(0.0);
        if l0 <= 0.0 {
            return Err(RetrievalError::InvalidParameter {
                name: "kernel lag 0",
                value: l0,
                expected: "a positive zero-lag window L_0 (at least one lag)",
            });
        }
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return Err(RetrievalError::InvalidParameter {
                name: "kernel dt",
                value: self.dt,
                expected: "a finite positive sample interval",
            });
        }
        if self.fft_points < self.lags.len() {
            return Err(RetrievalError::InvalidParameter {
                name: "kernel fft_points",
                value: self.fft_points as f64,
                expected: "a DFT at least as long as the lag window",
            });
        }
        Ok(())
    }

    /// The expected periodogram at `nu_hz` of a Gaussian spread of beat frequencies of total power
    /// `power` (summed over the `K` bins), mean `mean_hz` and standard deviation `sigma_hz`, seen
    /// through this kernel (the model of [`GateKernel`]'s derivation).
    pub fn periodogram(&self, power: f64, mean_hz: f64, sigma_hz: f64, nu_hz: f64) -> f64 {
        let dt = self.dt;
        let sum: f64 = self
            .lags
            .iter()
            .enumerate()
            .skip(1)
            .map(|(d, l)| {
                let t = d as f64 * dt;
                l * (-2.0 * PI * PI * sigma_hz * sigma_hz * t * t).exp() * (2.0 * PI * (mean_hz - nu_hz) * t).cos()
            })
            .sum();
        power * (1.0 + 2.0 * sum / self.lags[0]) / self.fft_points as f64
    }
}

/// A [`GateKernel`] in the fit's internal units (frequencies in bins of the axis).
#[derive(Debug, Clone)]
struct KernelModel {
    /// `L_d/(K·L_0)`: the lag window of a component of unit power.
    c: Vec<f64>,
    /// `2π·Δ·Δt`: the phase per bin of frequency offset and per lag.
    omega: f64,
    /// `2π²·Δ²·Δt²`: `s²d²` (`s` in bins) to the exponent of the spread's damping.
    gamma: f64,
    /// The squared width (bins²) of a Gaussian with the kernel's curvature at its peak,
    /// `(c_0 + 2Σc_d)/(2Σc_d ω² d²)`: what the kernel adds to a line's apparent width², for
    /// starting points only.
    s2: f64,
    /// `cos(dωk)` and `sin(dωk)` for lags `d = 1 … M − 1` (row `d − 1`) at every bin `k`: the
    /// parameter-free half of `cos d(θ_μ − ωk)`, so that a profile is a few multiply–adds per
    /// lag and bin instead of a `sin_cos` and a rotation chain per bin (the profile is where the
    /// fits spend their time).
    cos: Vec<f64>,
    sin: Vec<f64>,
    bins: usize,
}

impl KernelModel {
    /// The kernel on an axis of `bins` bins of `bin_width` Hz.
    fn new(kernel: &GateKernel, bin_width: f64, bins: usize) -> Self {
        let norm = kernel.fft_points as f64 * kernel.lags[0];
        let c: Vec<f64> = kernel.lags.iter().map(|l| l / norm).collect();
        let omega = 2.0 * PI * bin_width * kernel.dt;
        let gamma = 0.5 * omega * omega;
        let peak = c[0] + 2.0 * c.iter().skip(1).sum::<f64>();
        let curvature: f64 = 2.0 * c.iter().enumerate().map(|(d, c)| c * (omega * d as f64).powi(2)).sum::<f64>();
        // A flat kernel (one sample) has no peak: the widest start, the axis.
        let s2 = if curvature > 0.0 && peak > 0.0 { peak / curvature } else { (bins * bins) as f64 };
        let lags = c.len().saturating_sub(1);
        let (mut cos, mut sin) = (vec![0.0; lags * bins], vec![0.0; lags * bins]);
        for d in 1..=lags {
            let row = (d - 1) * bins;
            for k in 0..bins {
                let (sn, cs) = (omega * (d * k) as f64).sin_cos();
                cos[row + k] = cs;
                sin[row + k] = sn;
            }
        }
        KernelModel { c, omega, gamma, s2, cos, sin, bins }
    }

    /// A component `(ln P, μ, s²)` as coefficients of the basis `1, cos dωk, sin dωk`
    /// (`d = 1 … M − 1`, [`LagSpace`]): per basis function, the coefficient of the component's
    /// value and of its derivatives, `[g, ∂g/∂μ, ∂g/∂s²]` (`∂g/∂ln P = g`).
    fn component(&self, ln_p: f64, mu: f64, v: f64) -> Vec<[f64; 3]> {
        let lags = self.c.len();
        let amp = ln_p.exp();
        let mut out = vec![[0.0; 3]; 2 * lags - 1];
        out[0] = [amp * self.c[0], 0.0, 0.0];
        for (d, c) in self.c.iter().enumerate().skip(1) {
            let a = 2.0 * amp * c * (-self.gamma * v * (d * d) as f64).exp();
            let (s_mu, c_mu) = (self.omega * d as f64 * mu).sin_cos();
            let (alpha, beta) = (a * c_mu, a * s_mu);
            let (wd, gd2) = (self.omega * d as f64, self.gamma * (d * d) as f64);
            out[d] = [alpha, -wd * beta, -gd2 * alpha];
            out[lags - 1 + d] = [beta, wd * alpha, -gd2 * beta];
        }
        out
    }

    /// A unit-power component's value at its centre, and its derivative in `s²`.
    fn peak(&self, v: f64) -> (f64, f64) {
        let (mut value, mut dv) = (self.c[0], 0.0);
        for (d, c) in self.c.iter().enumerate().skip(1) {
            let d2 = (d * d) as f64;
            let a = 2.0 * c * (-self.gamma * v * d2).exp();
            value += a;
            dv -= a * self.gamma * d2;
        }
        (value, dv)
    }
}

/// One fitted Gaussian component with first-order standard errors.
#[derive(Debug, Clone, PartialEq)]
pub struct GaussComponent {
    /// Peak value per bin, `A` (with a [`GateKernel`]: the component's model at its centre).
    pub amplitude: f64,
    /// Standard error of `A`.
    pub amplitude_stderr: f64,
    /// Mean `μ` (Hz).
    pub mean_hz: f64,
    /// Standard error of `μ` (Hz); in m/s multiply by `λ0/2`.
    pub mean_hz_stderr: f64,
    /// Standard deviation `s` (Hz); with a [`GateKernel`], the scatterers' spread with the
    /// kernel deconvolved.
    pub sigma_hz: f64,
    /// Standard error of `s` (Hz). With a [`GateKernel`] the fit determines `s²` (standard error
    /// `e`), and this is `min(e/(2s), √e)`: the first-order error where `s ≫ √e`, and `√e` (the
    /// spread at which `s²` is one standard error above 0) where `s` is not resolved from 0.
    pub sigma_hz_stderr: f64,
    /// `A·s·√(2π)/Δ`, in the units of the spectrum summed over bins; with a [`GateKernel`], the
    /// fitted power itself (the component's sum over the `K` bins of the DFT).
    pub power: f64,
    /// Standard error of the power (through the covariance of `ln A` and `ln s`; with a kernel,
    /// of `ln P`).
    pub power_stderr: f64,
    /// `λ0·μ/2`, positive receding.
    pub mean_velocity_m_per_s: f64,
    /// `λ0·s/2`.
    pub sigma_velocity_m_per_s: f64,
}

/// A converged fit.
#[derive(Debug, Clone, PartialEq)]
pub struct GaussianFit {
    /// Sorted by increasing `sigma_hz` (narrow first: aerosol before rain).
    pub components: Vec<GaussComponent>,
    /// The floor per bin (the fixed value, or the fitted one).
    pub floor: f64,
    /// Its standard error; 0 when the floor was fixed.
    pub floor_stderr: f64,
    /// `Σ ((y − S)/σ)²` at the minimum (with `σ = 1` when no standard errors were given).
    pub chi2: f64,
    /// Bins minus fitted parameters.
    pub dof: usize,
    /// Jacobian evaluations used.
    pub iterations: usize,
    /// Whether the covariance was scaled by `χ²/dof` (no standard errors given).
    pub covariance_scaled: bool,
}

/// The outcome of [`fit_one_or_two`].
#[derive(Debug, Clone, PartialEq)]
pub struct ModelChoice {
    /// 1 or 2: the number of components the F-test keeps.
    pub components: usize,
    /// The one-component fit.
    pub one: GaussianFit,
    /// The two-component fit, or why it failed (then one component is chosen).
    pub two: Result<GaussianFit, RetrievalError>,
    /// `F = ((χ²₁ − χ²₂)/3) / (χ²₂/dof₂)`; 0 when the two-component fit failed.
    pub f_statistic: f64,
    /// `P(F(3, dof₂) > F)`; 1 when the two-component fit failed.
    pub p_value: f64,
}

impl ModelChoice {
    /// The fit with the chosen number of components.
    pub fn chosen(&self) -> &GaussianFit {
        match (&self.two, self.components) {
            (Ok(two), 2) => two,
            _ => &self.one,
        }
    }
}

/// Fit one and two Gaussian components and keep two only if the nested-model F-test prefers them
/// at `p <` [`FitOptions::selection_level`] (default 0.01): `F = ((χ²₁ − χ²₂)/3)/(χ²₂/dof₂)`
/// referred to `F(3, dof₂)`. The F form is used with or without standard errors because it does not depend on
/// their absolute scale (Monte Carlo standard errors are themselves estimates). A decrease of χ²
/// below `10⁻²⁰·Σ(y/σ)²` (round-off, as on noiseless data) counts as none: one component is kept.
///
/// **The level is nominal.** The second component's mean and width are not identified when its
/// amplitude is 0, so under the one-line hypothesis `F` is not `F(3, dof₂)`-distributed (Davies
/// 1987, Biometrika 74:33): the second component settles on the largest noise bump anywhere on
/// the axis, a look-elsewhere effect. Measured (integration test
/// `model_selection_finds_rain_and_rarely_invents_it`: 256 bins, one line of peak SNR 20 per bin,
/// white Gaussian noise, 1000 spectra): two components are chosen in 12.4 % of one-line spectra
/// at `p < 0.01`, 1.6 % at `p < 10⁻³`, 0.2 % at `p < 10⁻⁴`; with
/// [`FitOptions::min_sigma_hz`] = 2 bins, 6.4 % at `p < 0.01` and 0.3 % at `p < 10⁻³`. Choose
/// the level for the false-alarm rate you need on your own axis and line widths (the
/// [`ModelChoice::p_value`] is returned for that).
pub fn fit_one_or_two(
    axis: &FrequencyAxis,
    values: &[f64],
    stderr: Option<&[f64]>,
    wavelength_m: f64,
    options: &FitOptions,
) -> Result<ModelChoice, RetrievalError> {
    fit_one_first(axis, values, stderr, wavelength_m, options, None).map(OneFit::choose)
}

/// [`fit_one_or_two`] with components seen through a gate's spectral kernel (module docs): each
/// component's `sigma_hz` is the scatterers' spread, its `power` the fitted power. The kernel's
/// `K` need not equal the axis' bins (the model is evaluated at the bin centres), but `Δt` must be
/// the sampling interval of the spectrum's DFT. Errors as [`fit_one_or_two`], and for an invalid
/// kernel ([`GateKernel::validate`]).
pub fn fit_one_or_two_with_kernel(
    axis: &FrequencyAxis,
    values: &[f64],
    stderr: Option<&[f64]>,
    wavelength_m: f64,
    options: &FitOptions,
    kernel: &GateKernel,
) -> Result<ModelChoice, RetrievalError> {
    fit_one_first(axis, values, stderr, wavelength_m, options, Some(kernel)).map(OneFit::choose)
}

/// [`fit_one_or_two`] (`kernel` `None`) or [`fit_one_or_two_with_kernel`] stopped after the
/// one-component fit, so that a caller comparing line shapes on their one-component fits
/// ([`super::retrieve_gate`]) fits two components only in the shape it keeps: the other shape's
/// two-component fit, the larger part of the work, would be thrown away. [`OneFit::choose`]
/// finishes exactly as the whole function does (the same arithmetic, the same bits).
pub fn fit_one_first<'a>(
    axis: &'a FrequencyAxis,
    values: &'a [f64],
    stderr: Option<&[f64]>,
    wavelength_m: f64,
    options: &FitOptions,
    kernel: Option<&GateKernel>,
) -> Result<OneFit<'a>, RetrievalError> {
    let problem = Problem::validated(axis, values, stderr, wavelength_m, options, kernel)?;
    problem.check_points(1)?;
    let solution = problem.fit_one(axis)?;
    let one = problem.report(axis, &solution, wavelength_m)?;
    Ok(OneFit { problem, axis, wavelength_m, selection_level: options.selection_level, solution, one })
}

/// A one-component fit that can go on to the choice between one and two components
/// ([`fit_one_first`]).
pub struct OneFit<'a> {
    problem: Problem<'a>,
    axis: &'a FrequencyAxis,
    wavelength_m: f64,
    selection_level: f64,
    solution: Solution,
    one: GaussianFit,
}

impl OneFit<'_> {
    /// The one-component fit.
    pub fn one(&self) -> &GaussianFit {
        &self.one
    }

    /// The two-component fit and the F-test between the two ([`fit_one_or_two`]).
    pub fn choose(self) -> ModelChoice {
        let OneFit { problem, axis, wavelength_m, selection_level, solution, one } = self;
        let two = problem
            .check_points(2)
            .and_then(|()| problem.fit_two(axis, &solution))
            .and_then(|s| problem.report(axis, &s, wavelength_m));
        choice(&problem, one, two, selection_level)
    }
}

/// The F-test between the one- and two-component fits of `problem`.
fn choice(
    problem: &Problem<'_>,
    one: GaussianFit,
    two: Result<GaussianFit, RetrievalError>,
    selection_level: f64,
) -> ModelChoice {
    // A χ² decrease at the round-off level of χ² itself is no evidence (noiseless data).
    let resolution = 1e-20 * problem.y.iter().zip(&problem.w).map(|(y, w)| (y * w).powi(2)).sum::<f64>();
    let (f_statistic, p_value) = match &two {
        Ok(two) if one.chi2 - two.chi2 > resolution => {
            let extra = (one.dof - two.dof) as f64;
            let f = if two.chi2 > 0.0 {
                ((one.chi2 - two.chi2) / extra) / (two.chi2 / two.dof as f64)
            } else {
                f64::INFINITY
            };
            (f, f_distribution_sf(f, extra, two.dof as f64))
        }
        _ => (0.0, 1.0),
    };
    let components = if p_value < selection_level { 2 } else { 1 };
    ModelChoice { components, one, two, f_statistic, p_value }
}

/// Fit `components` (1 or 2) Gaussians on a floor to `values` (one per bin of `axis`), weighted by
/// `stderr` when given.
///
/// Starting points: one component from the gate moments of the floor-subtracted spectrum (peak
/// position and interpolated height; `s` from the FWHM, or from the window width when the FWHM is
/// undefined; with a fitted floor, the floor starts at the median bin). Two components: the lower
/// χ² of two starts, (a) the one-component fit plus a second Gaussian at the highest peak of its
/// residual smoothed by a Gaussian kernel as wide as the first component (height and width from
/// the smoothed residual's gate moments, deconvolved), made for separated peaks, and
/// (b) two Gaussians at the one-component mean with half its amplitude each and widths `s/2` and
/// `2s`, made for a narrow line on a broad one at nearly the same velocity, where the residual of
/// (a) need not have a clear peak. (On the noiseless concentric case of the unit tests both starts
/// reach the same minimum; on separated peaks (b) is the slower and sometimes stalls in a local
/// minimum, which the χ² comparison discards.)
///
/// A fit that ends on a bound (see the module docs) is reported as converged there, with the
/// covariance at that point.
///
/// Errors: mismatched lengths, non-finite input, non-positive standard errors, `components` not 1
/// or 2, fewer bins than parameters + 1, no signal above the floor, a singular fit (a component
/// collapsed or two coincide: [`RetrievalError::Degenerate`]), or no convergence.
pub fn fit_gaussians(
    axis: &FrequencyAxis,
    values: &[f64],
    stderr: Option<&[f64]>,
    components: usize,
    wavelength_m: f64,
    options: &FitOptions,
) -> Result<GaussianFit, RetrievalError> {
    fit_n(Problem::validated(axis, values, stderr, wavelength_m, options, None)?, axis, components, wavelength_m)
}

/// [`fit_gaussians`] with components seen through a gate's spectral kernel (module docs; starting
/// points as [`fit_gaussians`]'s with the kernel's width taken off the widths and its peak off the
/// heights).
pub fn fit_gaussians_with_kernel(
    axis: &FrequencyAxis,
    values: &[f64],
    stderr: Option<&[f64]>,
    components: usize,
    wavelength_m: f64,
    options: &FitOptions,
    kernel: &GateKernel,
) -> Result<GaussianFit, RetrievalError> {
    let problem = Problem::validated(axis, values, stderr, wavelength_m, options, Some(kernel))?;
    fit_n(problem, axis, components, wavelength_m)
}

fn fit_n(
    problem: Problem<'_>,
    axis: &FrequencyAxis,
    components: usize,
    wavelength_m: f64,
) -> Result<GaussianFit, RetrievalError> {
    if !(components == 1 || components == 2) {
        return Err(RetrievalError::InvalidParameter {
            name: "components",
            value: components as f64,
            expected: "1 or 2 Gaussian components",
        });
    }
    problem.check_points(components)?;
    let one = problem.fit_one(axis)?;
    let solution = if components == 1 { one } else { problem.fit_two(axis, &one)? };
    problem.report(axis, &solution, wavelength_m)
}

/// Height, mean (bins) and standard deviation (bins, ≥ ½) of the main peak of a floor-subtracted
/// spectrum, from its gate moments.
fn moment_start(axis: &FrequencyAxis, signal: &[f64]) -> Result<(f64, f64, f64), RetrievalError> {
    // Only frequencies are used: any wavelength will do.
    let g = gate_estimates_with(axis, signal, 0.0, 1.0, &MomentOptions::default())?;
    let dw = axis.bin_width();
    let mu = (g.peak_frequency_hz - axis.f_min) / dw - 0.5;
    let s = g.fwhm_hz.map_or(g.width_hz, |w| w / FWHM_PER_SIGMA) / dw;
    Ok((g.peak_signal, mu, s.max(0.5)))
}

/// `y` convolved with a unit-sum Gaussian kernel of standard deviation `sigma` bins (cut at 4σ,
/// renormalised over the bins inside the axis near its ends).
fn gaussian_smooth(y: &[f64], sigma: f64) -> Vec<f64> {
    let reach = (4.0 * sigma).ceil() as usize;
    // The kernel over offsets −reach…reach; bin j weighs full[j + reach − k] at bin k.
    let full: Vec<f64> = (0..=2 * reach).map(|i| (-0.5 * ((i as f64 - reach as f64) / sigma).powi(2)).exp()).collect();
    // The whole kernel's sum, for every bin whose window lies inside the axis (the same slice
    // summed in the same order: the same bits as summing it there, without a serial sum per bin).
    let full_sum: f64 = full.iter().sum();
    (0..y.len())
        .map(|k| {
            let (lo, hi) = (k.saturating_sub(reach), (k + reach).min(y.len() - 1));
            let w = &full[lo + reach - k..=hi + reach - k];
            let norm = if w.len() == full.len() { full_sum } else { w.iter().sum::<f64>() };
            dot(&y[lo..=hi], w) / norm
        })
        .collect()
}

fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
}

/// The least-squares problem in internal units: bin index `x = k` as the abscissa, parameters
/// `[ln A, μ, ln s]` per component (μ, s in bins), or `[ln P, μ, s²]` with a gate kernel, then
/// the floor if fitted.
struct Problem<'a> {
    y: &'a [f64],
    /// `1/σ_k`.
    w: Vec<f64>,
    /// Whether standard errors were given (else `w = 1` and the covariance is scaled).
    weighted: bool,
    fixed_floor: f64,
    fit_floor: bool,
    /// `ln` of the narrowest component width allowed (bins).
    ln_s_min: f64,
    /// The gate kernel the components are seen through, if any.
    kernel: Option<KernelModel>,
    /// With a kernel: χ² and the normal equations in the space of the kernel's basis functions
    /// ([`LagSpace`]), built at first use (`None` inside when its Gram matrix is singular).
    lag_space: std::cell::OnceCell<Option<LagSpace>>,
    /// With a kernel, the smallest `s²` allowed (bins²): `min_sigma_hz²`.
    v_min: f64,
    /// [`FitOptions::max_iterations`].
    max_iterations: usize,
}

/// One component at every bin ([`Problem::profile`]): its value and (if asked) its derivatives in
/// its mean and width parameter.
struct Profile {
    g: Vec<f64>,
    d_mu: Vec<f64>,
    d_width: Vec<f64>,
    /// The bins outside which all three are 0.
    support: std::ops::Range<usize>,
}

/// The kernel model in the space of its `2M − 1` basis functions `T = [1, cos dωk, sin dωk]`
/// (`d = 1 … M − 1`): every model is `S = T·c` (a component's coefficients are the lag terms
/// `P c_0`, `a_d cos dωμ`, `a_d sin dωμ`, the floor adds to the first), and so is every column of
/// its Jacobian. With the Gram matrix `G = TᵀW²T = LLᵀ` and `c_y` the weighted projection of the
/// data `y` on `T`, `χ²(c) = ‖y − Tc_y‖²_W + ‖Lᵀ(c_y − c)‖²` exactly (the residual of the
/// projection is W-orthogonal to `T`): χ² and the normal equations cost `O(M²)` instead of
/// `O(M·bins)`, and the only sum over bins, the projection's residual, is taken once per problem.
/// Both terms are sums of squares (no cancellation between large numbers).
struct LagSpace {
    dim: usize,
    /// `L`, row-major lower triangle.
    l: Vec<f64>,
    /// `c_y`.
    cy: Vec<f64>,
    /// `‖y − T·c_y‖²_W`.
    perp: f64,
}

impl LagSpace {
    /// `None` when `G` is not numerically positive definite (fewer bins than basis functions,
    /// or weights that do not separate them): the fit then sums over bins.
    fn new(km: &KernelModel, y: &[f64], w: &[f64]) -> Option<LagSpace> {
        let (bins, lags) = (y.len(), km.c.len());
        let dim = 2 * lags - 1;
        let basis = |i: usize| -> &[f64] {
            if i < lags { &km.cos[(i - 1) * bins..i * bins] } else { &km.sin[(i - lags) * bins..(i - lags + 1) * bins] }
        };
        let u: Vec<Vec<f64>> = (0..dim)
            .map(|i| if i == 0 { w.to_vec() } else { basis(i).iter().zip(w).map(|(t, w)| t * w).collect() })
            .collect();
        let wy: Vec<f64> = y.iter().zip(w).map(|(y, w)| y * w).collect();
        let mut g = vec![0.0; dim * dim];
        for a in 0..dim {
            for b in 0..=a {
                let v = dot(&u[a], &u[b]);
                g[a * dim + b] = v;
                g[b * dim + a] = v;
            }
        }
        let b: Vec<f64> = u.iter().map(|ui| dot(ui, &wy)).collect();
        let l = cholesky(&g, dim)?;
        let cy = cholesky_solve(&l, dim, &b);
        let mut resid = wy;
        for (i, ui) in u.iter().enumerate() {
            resid.iter_mut().zip(ui).for_each(|(r, t)| *r -= cy[i] * t);
        }
        let perp = resid.iter().map(|r| r * r).sum::<f64>();
        (perp.is_finite() && cy.iter().all(|c| c.is_finite())).then_some(LagSpace { dim, l, cy, perp })
    }

    /// `Lᵀx`.
    fn whiten(&self, x: &[f64]) -> Vec<f64> {
        let n = self.dim;
        (0..n).map(|i| (i..n).map(|m| self.l[m * n + i] * x[m]).sum()).collect()
    }

    /// `Lᵀ(c_y − c)`.
    fn whitened_residual(&self, c: &[f64]) -> Vec<f64> {
        let d: Vec<f64> = self.cy.iter().zip(c).map(|(a, b)| a - b).collect();
        self.whiten(&d)
    }
}

/// A plain Gaussian component is taken as 0 where it is below `e^{−GAUSS_TAIL}` of its peak.
const GAUSS_TAIL: f64 = 80.0;
/// Bins between exact evaluations of a plain Gaussian component (products in between).
const GAUSS_RESTART: usize = 32;

/// `Σ a_k b_k` in four interleaved partial sums, which the compiler turns into vector
/// instructions (a single running sum is a serial chain it may not reorder).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ca.remainder().iter().zip(cb.remainder()).map(|(x, y)| x * y).sum();
    for (x, y) in ca.zip(cb) {
        for i in 0..4 {
            acc[i] += x[i] * y[i];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Where Levenberg–Marquardt stopped.
struct Solution {
    params: Vec<f64>,
    chi2: f64,
    iterations: usize,
}

/// Relative χ² decrease below which an accepted step counts as converged (with a small step).
const CHI2_RTOL: f64 = 1e-10;
/// Step length, in standard errors of the parameters, below which a step is small.
const STEP_TOL_SE: f64 = 1e-3;
/// The narrowest component (standard deviation in bins) a fit may reach whatever
/// [`FitOptions::min_sigma_hz`] says.
const S_MIN_BINS: f64 = 0.1;
/// Damping beyond which no step lowering χ² exists at the working precision.
const LAMBDA_MAX: f64 = 1e10;

impl<'a> Problem<'a> {
    /// The problem after every input check that does not depend on the number of components.
    fn validated(
        axis: &FrequencyAxis,
        values: &'a [f64],
        stderr: Option<&[f64]>,
        wavelength_m: f64,
        options: &FitOptions,
        kernel: Option<&GateKernel>,
    ) -> Result<Self, RetrievalError> {
        check_len("values", values, axis.bins)?;
        if let Some(k) = kernel {
            k.validate()?;
        }
        check_finite("values", values)?;
        if let Some(se) = stderr {
            check_len("stderr", se, axis.bins)?;
            check_stderr(se)?;
        }
        check_wavelength(wavelength_m)?;
        if let Floor::Fixed(b) = options.floor
            && !b.is_finite()
        {
            return Err(RetrievalError::InvalidParameter {
                name: "floor",
                value: b,
                expected: "a finite floor per bin",
            });
        }
        let min_sigma = options.min_sigma_hz;
        if !(min_sigma.is_finite() && min_sigma >= 0.0) {
            return Err(RetrievalError::InvalidParameter {
                name: "min_sigma_hz",
                value: min_sigma,
                expected: "a finite width ≥ 0 Hz",
            });
        }
        let level = options.selection_level;
        if !(level > 0.0 && level < 1.0) {
            return Err(RetrievalError::InvalidParameter {
                name: "selection_level",
                value: level,
                expected: "a significance level in (0, 1)",
            });
        }
        let dw = axis.bin_width();
        let mut problem = Problem::new(values, stderr, options.floor, (min_sigma / dw).max(S_MIN_BINS));
        problem.max_iterations = options.max_iterations;
        problem.kernel = kernel.map(|k| KernelModel::new(k, dw, axis.bins));
        problem.v_min = (min_sigma / dw).powi(2);
        Ok(problem)
    }

    /// At least one degree of freedom for `components`.
    fn check_points(&self, components: usize) -> Result<(), RetrievalError> {
        let needed = 3 * components + self.fit_floor as usize + 1;
        if self.y.len() < needed { Err(RetrievalError::TooFewPoints { needed, found: self.y.len() }) } else { Ok(()) }
    }

    /// One component from the gate moments of the floor-subtracted spectrum.
    fn fit_one(&self, axis: &FrequencyAxis) -> Result<Solution, RetrievalError> {
        let floor0 = if self.fit_floor { median(self.y) } else { self.fixed_floor };
        let signal: Vec<f64> = self.y.iter().map(|v| v - floor0).collect();
        let (a, mu, s) = moment_start(axis, &signal)?;
        let p = match &self.kernel {
            None => vec![a.ln(), mu, s.ln()],
            // The kernel's own width off the apparent one, its peak off the height.
            Some(km) => {
                let v = self.clamp_v(s * s - km.s2);
                vec![(a / km.peak(v).0).ln(), mu, v]
            }
        };
        self.levenberg_marquardt(self.with_floor(p, floor0))
    }

    /// `s²` (bins²) within its bounds.
    fn clamp_v(&self, v: f64) -> f64 {
        let bins = self.y.len() as f64;
        v.clamp(self.v_min, (bins * bins).max(self.v_min))
    }

    /// Two components from the better of starts (a) and (b) of [`fit_gaussians`].
    fn fit_two(&self, axis: &FrequencyAxis, one: &Solution) -> Result<Solution, RetrievalError> {
        let p1 = &one.params;
        let floor1 = self.floor(p1);
        let ln2 = 2f64.ln();
        let mut starts = Vec::new();
        // (a) a second Gaussian on the highest peak of the residual smoothed by a Gaussian kernel
        // as wide as the first component (a matched filter: a single noisy bin must not set the
        // start), its moments deconvolved: a line (A, s) smoothed by a unit-sum kernel of width
        // k has width √(s² + k²) and height A·s/√(s² + k²).
        // With a gate kernel the widths are apparent ones, √(s² + kernel's s²), and heights
        // are converted to powers through the kernel's peak.
        let residual: Vec<f64> = self.y.iter().zip(self.values(p1)).map(|(y, m)| y - m).collect();
        let apparent1 = match &self.kernel {
            None => p1[2].exp(),
            Some(km) => (p1[2] + km.s2).sqrt(),
        };
        let smoothing = apparent1.max(1.0);
        if let Ok((h, mu2, w)) = moment_start(axis, &gaussian_smooth(&residual, smoothing)) {
            let s2 = (w * w - smoothing * smoothing).max(0.25).sqrt();
            let a2 = h * (s2 * s2 + smoothing * smoothing).sqrt() / s2;
            let second = match &self.kernel {
                None => [a2.ln(), mu2, s2.ln()],
                Some(km) => {
                    let v2 = self.clamp_v(s2 * s2 - km.s2);
                    [(a2 / km.peak(v2).0).ln(), mu2, v2]
                }
            };
            starts.push(self.with_floor(vec![p1[0], p1[1], p1[2], second[0], second[1], second[2]], floor1));
        }
        // (b) a narrow and a broad Gaussian at the one-component mean.
        match &self.kernel {
            None => starts
                .push(self.with_floor(vec![p1[0] - ln2, p1[1], p1[2] - ln2, p1[0] - ln2, p1[1], p1[2] + ln2], floor1)),
            // s²/4 and 4s² + the kernel's: a broad component at least as wide as the kernel.
            Some(km) => {
                let (narrow, broad) = (self.clamp_v(0.25 * p1[2]), self.clamp_v(4.0 * p1[2] + km.s2));
                starts.push(self.with_floor(vec![p1[0] - ln2, p1[1], narrow, p1[0] - ln2, p1[1], broad], floor1));
            }
        }
        // (b) is always there, so the initial error is always replaced.
        let mut best: Result<Solution, _> = Err(RetrievalError::DidNotConverge { iterations: 0 });
        for p0 in starts {
            let r = self.levenberg_marquardt(p0).and_then(|s| self.covariance(&s).map(|_| s));
            best = match (best, r) {
                (Ok(b), Ok(s)) => Ok(if s.chi2 < b.chi2 { s } else { b }),
                (Ok(b), Err(_)) => Ok(b),
                (Err(_), r) => r,
            };
        }
        best
    }

    fn new(y: &'a [f64], stderr: Option<&[f64]>, floor: Floor, s_min_bins: f64) -> Self {
        let w = match stderr {
            Some(se) => se.iter().map(|s| 1.0 / s).collect(),
            None => vec![1.0; y.len()],
        };
        let (fixed_floor, fit_floor) = match floor {
            Floor::Fixed(b) => (b, false),
            Floor::Fitted => (0.0, true),
        };
        Problem {
            y,
            w,
            weighted: stderr.is_some(),
            fixed_floor,
            fit_floor,
            ln_s_min: s_min_bins.ln(),
            kernel: None,
            lag_space: std::cell::OnceCell::new(),
            v_min: 0.0,
            max_iterations: FitOptions::default().max_iterations,
        }
    }

    /// `3m` parameters, or `3m + 1` with the floor.
    fn components(&self, p: &[f64]) -> usize {
        p.len() / 3
    }

    /// `p` with the floor appended when it is fitted.
    fn with_floor(&self, mut p: Vec<f64>, floor: f64) -> Vec<f64> {
        if self.fit_floor {
            p.push(floor);
        }
        p
    }

    fn floor(&self, p: &[f64]) -> f64 {
        if self.fit_floor { p[p.len() - 1] } else { self.fixed_floor }
    }

    /// Component `j` at every bin: its value `g` and, with `derivatives`, its derivatives in its
    /// mean and in its width parameter (`∂g/∂ln A = g` for both models).
    /// Gaussian: `∂g/∂μ = g·(x − μ)/s²`, `∂g/∂ln s = g·(x − μ)²/s²`.
    /// Kernel, with `a_d = P·c_d·e^{−γ s² d²}` and `θ = ω(μ − x)`:
    /// `g = P c_0 + 2Σ a_d cos dθ`, `∂g/∂μ = −2Σ a_d ω d sin dθ`, `∂g/∂s² = −2Σ a_d γ d² cos dθ`,
    /// with `cos dθ = cos dωμ·cos dωx + sin dωμ·sin dωx` and
    /// `sin dθ = sin dωμ·cos dωx − cos dωμ·sin dωx` on the kernel's tables.
    fn profile(&self, p: &[f64], j: usize, derivatives: bool) -> Profile {
        let (ln_a, mu, width) = (p[3 * j], p[3 * j + 1], p[3 * j + 2]);
        let bins = self.y.len();
        let derivative = |len: usize| if derivatives { vec![0.0; len] } else { Vec::new() };
        match &self.kernel {
            None => {
                let inv_s = (-width).exp();
                // Beyond |u|² = 2·GAUSS_TAIL the line is below e^{−GAUSS_TAIL} ≈ 2e-35 of its peak:
                // zero to far below the round-off of any bin it shares with the peak, and skipped.
                let reach = (2.0 * GAUSS_TAIL).sqrt() / inv_s;
                let (lo, hi) = if reach.is_finite() && mu.is_finite() {
                    (
                        (mu - reach).ceil().clamp(0.0, bins as f64) as usize,
                        ((mu + reach).floor() + 1.0).clamp(0.0, bins as f64) as usize,
                    )
                } else {
                    (0, bins)
                };
                let len = hi.max(lo) - lo;
                let mut out = Profile {
                    g: vec![0.0; len],
                    d_mu: derivative(len),
                    d_width: derivative(len),
                    support: lo..lo + len,
                };
                // g(k + 1) = g(k)·r(k) with r(k) = e^{−u h − h²/2} and r(k + 1) = r(k)·e^{−h²}
                // (h = 1/s): two products per bin instead of an exp, restarted from exact values
                // every GAUSS_RESTART bins so that the products' round-off stays ≲ 1e-13.
                let q = (-inv_s * inv_s).exp();
                let (mut g, mut r) = (0.0, 0.0);
                for i in 0..len {
                    let u = ((lo + i) as f64 - mu) * inv_s;
                    if i % GAUSS_RESTART == 0 {
                        g = (ln_a - 0.5 * u * u).exp();
                        r = (-u * inv_s - 0.5 * inv_s * inv_s).exp();
                    } else {
                        g *= r;
                        r *= q;
                    }
                    out.g[i] = g;
                    if derivatives {
                        out.d_mu[i] = g * u * inv_s;
                        out.d_width[i] = g * u * u;
                    }
                }
                out
            }
            Some(km) => {
                debug_assert_eq!(km.bins, bins);
                let amp = ln_a.exp();
                // Every bin starts at the lag-0 term `P·c_0`.
                let mut out = Profile {
                    g: vec![amp * km.c[0]; bins],
                    d_mu: derivative(bins),
                    d_width: derivative(bins),
                    support: 0..bins,
                };
                for (d, c) in km.c.iter().enumerate().skip(1) {
                    let a = 2.0 * amp * c * (-km.gamma * width * (d * d) as f64).exp();
                    let (s_mu, c_mu) = (km.omega * d as f64 * mu).sin_cos();
                    let (alpha, beta) = (a * c_mu, a * s_mu);
                    let row = (d - 1) * bins..d * bins;
                    let (cos, sin) = (&km.cos[row.clone()], &km.sin[row]);
                    if derivatives {
                        let (wd, gd2) = (km.omega * d as f64, km.gamma * (d * d) as f64);
                        let (mc, ms) = (-wd * beta, wd * alpha);
                        let (vc, vs) = (-gd2 * alpha, -gd2 * beta);
                        // One pass over the tables for the value and both derivatives.
                        for ((((g, dm), dv), cs), sn) in
                            out.g.iter_mut().zip(out.d_mu.iter_mut()).zip(out.d_width.iter_mut()).zip(cos).zip(sin)
                        {
                            *g += alpha * cs + beta * sn;
                            *dm += mc * cs + ms * sn;
                            *dv += vc * cs + vs * sn;
                        }
                    } else {
                        for ((g, cs), sn) in out.g.iter_mut().zip(cos).zip(sin) {
                            *g += alpha * cs + beta * sn;
                        }
                    }
                }
                out
            }
        }
    }

    /// `S` at every bin.
    fn values(&self, p: &[f64]) -> Vec<f64> {
        let mut s = vec![self.floor(p); self.y.len()];
        for j in 0..self.components(p) {
            let prof = self.profile(p, j, false);
            for (v, g) in s[prof.support].iter_mut().zip(prof.g) {
                *v += g;
            }
        }
        s
    }

    fn chi2(&self, p: &[f64]) -> f64 {
        if let Some((km, ls)) = self.lag() {
            let e = ls.whitened_residual(&self.coefficients(km, p));
            let c = ls.perp + e.iter().map(|v| v * v).sum::<f64>();
            return if c.is_finite() { c } else { f64::INFINITY };
        }
        let c: f64 = self.y.iter().zip(&self.w).zip(self.values(p)).map(|((y, w), m)| (w * (y - m)).powi(2)).sum();
        if c.is_finite() { c } else { f64::INFINITY }
    }

    /// The normal matrix `JᵀWJ` and gradient `JᵀW·r` (`r = y − S`) at `p`, row-major, from the
    /// components' [`profile`](Self::profile)s and `∂S/∂b = 1`: the weighted Jacobian by columns,
    /// then each entry one dot product ([`dot`], which vectorises).
    fn normal_equations(&self, p: &[f64]) -> (Vec<f64>, Vec<f64>) {
        if let Some((km, ls)) = self.lag() {
            return self.lag_normal_equations(km, ls, p);
        }
        let n = p.len();
        let bins = self.y.len();
        let mut model = vec![self.floor(p); bins];
        let mut columns: Vec<Vec<f64>> = Vec::with_capacity(n);
        // Outside every component's support the Jacobian's rows are 0 unless the floor is fitted:
        // those bins add nothing to JᵀWJ or JᵀWr.
        let (mut lo, mut hi) = if self.fit_floor { (0, bins) } else { (bins, 0) };
        let profiles: Vec<Profile> = (0..self.components(p)).map(|j| self.profile(p, j, true)).collect();
        for prof in &profiles {
            (lo, hi) = (lo.min(prof.support.start), hi.max(prof.support.end));
            for (m, g) in model[prof.support.clone()].iter_mut().zip(&prof.g) {
                *m += g;
            }
        }
        let span = lo..hi.max(lo);
        let w = &self.w[span.clone()];
        for prof in &profiles {
            let (at, end) = (prof.support.start - span.start, prof.support.end - span.start);
            for col in [&prof.g, &prof.d_mu, &prof.d_width] {
                let inside = col.iter().zip(&w[at..end]).map(|(v, w)| v * w);
                let zeros = |n: usize| std::iter::repeat_n(0.0, n);
                columns.push(zeros(at).chain(inside).chain(zeros(span.len() - end)).collect());
            }
        }
        if self.fit_floor {
            columns.push(w.to_vec());
        }
        let r: Vec<f64> =
            self.y[span.clone()].iter().zip(w).zip(&model[span.clone()]).map(|((y, w), m)| w * (y - m)).collect();
        let cols: Vec<&[f64]> = columns.iter().map(|c| c.as_slice()).collect();
        let mut ata = vec![0.0; n * n];
        let mut atr = vec![0.0; n];
        for a in 0..n {
            atr[a] = dot(cols[a], &r);
            for b in 0..=a {
                let v = dot(cols[a], cols[b]);
                ata[a * n + b] = v;
                ata[b * n + a] = v;
            }
        }
        (ata, atr)
    }

    /// The kernel and its [`LagSpace`] for this problem's data, if there is a kernel and the
    /// space's Gram matrix is positive definite.
    fn lag(&self) -> Option<(&KernelModel, &LagSpace)> {
        let km = self.kernel.as_ref()?;
        let ls = self.lag_space.get_or_init(|| LagSpace::new(km, self.y, &self.w)).as_ref()?;
        Some((km, ls))
    }

    /// The model `S` at `p` as coefficients of the kernel's basis ([`LagSpace`]).
    fn coefficients(&self, km: &KernelModel, p: &[f64]) -> Vec<f64> {
        let lags = km.c.len();
        let mut c = vec![0.0; 2 * lags - 1];
        c[0] = self.floor(p);
        for j in 0..self.components(p) {
            for (i, v) in km.component(p[3 * j], p[3 * j + 1], p[3 * j + 2]).into_iter().enumerate() {
                c[i] += v[0];
            }
        }
        c
    }

    /// [`Problem::normal_equations`] in the kernel's basis: with `C` the basis coefficients of
    /// each column of the Jacobian and `G = LLᵀ`, `JᵀWJ = (LᵀC)ᵀ(LᵀC)` and
    /// `JᵀWr = (LᵀC)ᵀ·Lᵀ(c_y − c)`.
    fn lag_normal_equations(&self, km: &KernelModel, ls: &LagSpace, p: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let n = p.len();
        let dim = ls.dim;
        let mut columns: Vec<Vec<f64>> = vec![vec![0.0; dim]; n];
        for j in 0..self.components(p) {
            for (i, v) in km.component(p[3 * j], p[3 * j + 1], p[3 * j + 2]).into_iter().enumerate() {
                for (t, x) in v.into_iter().enumerate() {
                    columns[3 * j + t][i] = x;
                }
            }
        }
        if self.fit_floor {
            columns[n - 1][0] = 1.0;
        }
        let e: Vec<Vec<f64>> = columns.iter().map(|c| ls.whiten(c)).collect();
        let r = ls.whitened_residual(&self.coefficients(km, p));
        let mut ata = vec![0.0; n * n];
        let mut atr = vec![0.0; n];
        for a in 0..n {
            atr[a] = dot(&e[a], &r);
            for b in 0..=a {
                let v = dot(&e[a], &e[b]);
                ata[a * n + b] = v;
                ata[b * n + a] = v;
            }
        }
        (ata, atr)
    }

    /// `p` projected onto the bounds: each mean on the axis (`−½ ≤ μ ≤ bins − ½`, bin units),
    /// each width in `[s_min, bins]` (a narrower "line" is one bin or noise, a wider one is a floor);
    /// with a kernel, `s²` in `[min_sigma², bins²]` (the kernel already has the resolution's width).
    fn clamp_to_box(&self, mut p: Vec<f64>) -> Vec<f64> {
        let bins = self.y.len() as f64;
        for j in 0..self.components(&p) {
            p[3 * j + 1] = p[3 * j + 1].clamp(-0.5, bins - 0.5);
            p[3 * j + 2] = match self.kernel {
                None => p[3 * j + 2].clamp(self.ln_s_min, bins.ln().max(self.ln_s_min)),
                Some(_) => self.clamp_v(p[3 * j + 2]),
            };
        }
        p
    }

    /// The step-size stopping rule: the step is shorter than [`STEP_TOL_SE`] standard errors,
    /// `δᵀ(JᵀWJ)δ ≤ STEP_TOL_SE²·χ²/dof` — the standard errors being those the residuals imply
    /// (for correct weights `χ²/dof ≈ 1`; on noiseless data it is round-off, so the rule waits
    /// for the round-off rule of [`Problem::levenberg_marquardt`]).
    fn step_is_small(&self, delta: &[f64], ata: &[f64], chi2: f64) -> bool {
        let n = delta.len();
        let quad: f64 = (0..n).map(|a| (0..n).map(|b| delta[a] * ata[a * n + b] * delta[b]).sum::<f64>()).sum();
        quad <= STEP_TOL_SE * STEP_TOL_SE * chi2 / (self.y.len() - n) as f64
    }

    /// Levenberg–Marquardt from `p`, kept within bounds by projecting every trial point (and the
    /// start) with [`Problem::clamp_to_box`]. Converged when an accepted step both lowers χ² by less than
    /// [`CHI2_RTOL`] relative and is small ([`Problem::step_is_small`]), or when no step lowers χ²
    /// even at damping [`LAMBDA_MAX`] (the minimum is resolved to round-off: the steps tried there
    /// are gradient steps shorter than round-off of χ²).
    fn levenberg_marquardt(&self, p: Vec<f64>) -> Result<Solution, RetrievalError> {
        let mut p = self.clamp_to_box(p);
        let n = p.len();
        let mut chi2 = self.chi2(&p);
        if !chi2.is_finite() {
            return Err(RetrievalError::NonFinite { what: "initial model", index: 0 });
        }
        let mut lambda = 1e-3;
        for iteration in 1..=self.max_iterations {
            let (ata, atr) = self.normal_equations(&p);
            let max_diag = (0..n).map(|i| ata[i * n + i]).fold(0.0f64, f64::max);
            let frozen = self.held_at_bounds(&p, &atr);
            loop {
                let mut damped = ata.clone();
                let mut rhs = atr.clone();
                for i in 0..n {
                    damped[i * n + i] += lambda * ata[i * n + i].max(1e-15 * max_diag);
                }
                for i in (0..n).filter(|&i| frozen[i]) {
                    for j in 0..n {
                        damped[i * n + j] = 0.0;
                        damped[j * n + i] = 0.0;
                    }
                    damped[i * n + i] = 1.0;
                    rhs[i] = 0.0;
                }
                let step = cholesky(&damped, n).map(|l| cholesky_solve(&l, n, &rhs));
                if let Some(delta) = step {
                    let trial = self.clamp_to_box(p.iter().zip(&delta).map(|(a, d)| a + d).collect());
                    let trial_chi2 = self.chi2(&trial);
                    if trial_chi2 <= chi2 {
                        let decrease = chi2 - trial_chi2;
                        let taken: Vec<f64> = trial.iter().zip(&p).map(|(a, b)| a - b).collect();
                        p = trial;
                        chi2 = trial_chi2;
                        lambda = (lambda * 0.1).max(1e-12);
                        if decrease <= CHI2_RTOL * chi2 && self.step_is_small(&taken, &ata, chi2) {
                            return Ok(Solution { params: p, chi2, iterations: iteration });
                        }
                        break;
                    }
                }
                lambda *= 10.0;
                if lambda > LAMBDA_MAX {
                    return Ok(Solution { params: p, chi2, iterations: iteration });
                }
            }
        }
        Err(RetrievalError::DidNotConverge { iterations: self.max_iterations })
    }

    /// With a gate kernel, the parameters that sit on a bound of [`Problem::clamp_to_box`] with the
    /// gradient pushing them out (`JᵀWr`, the descent direction, pointing outside): they are held
    /// for the step, which then solves for the others only. A one-velocity line has `s² = 0` on
    /// its bound; a projected full step there would move the other parameters as if `s²` had
    /// gone negative, and the fit would crawl. (Plain Gaussians are fitted as before: nothing is
    /// held.)
    fn held_at_bounds(&self, p: &[f64], atr: &[f64]) -> Vec<bool> {
        let mut held = vec![false; p.len()];
        if self.kernel.is_none() {
            return held;
        }
        let bins = self.y.len() as f64;
        for j in 0..self.components(p) {
            for (i, lo, hi) in [
                (3 * j + 1, -0.5, bins - 0.5),
                (3 * j + 2, self.clamp_v(f64::NEG_INFINITY), self.clamp_v(f64::INFINITY)),
            ] {
                held[i] = (p[i] <= lo && atr[i] < 0.0) || (p[i] >= hi && atr[i] > 0.0);
            }
        }
        held
    }

    /// `(JᵀWJ)⁻¹` at the solution, or [`RetrievalError::Degenerate`] with its condition number.
    fn covariance(&self, s: &Solution) -> Result<Vec<f64>, RetrievalError> {
        let n = s.params.len();
        let (ata, _) = self.normal_equations(&s.params);
        spd_inverse(&ata, n).ok_or_else(|| RetrievalError::Degenerate {
            what: "the fit does not determine every parameter (a component collapsed, left the axis, or two coincide)",
            condition: condition_number(&ata, n),
        })
    }

    /// Convert a solution to physical units with first-order standard errors, components sorted
    /// by width.
    fn report(&self, axis: &FrequencyAxis, s: &Solution, wavelength_m: f64) -> Result<GaussianFit, RetrievalError> {
        let n = s.params.len();
        let dof = self.y.len() - n;
        let scaled = !self.weighted;
        let mut cov = self.covariance(s)?;
        if scaled {
            let r = s.chi2 / dof as f64;
            cov.iter_mut().for_each(|c| *c *= r);
        }
        let dw = axis.bin_width();
        let p = &s.params;
        let mut components: Vec<GaussComponent> = (0..self.components(p))
            .map(|j| {
                let (i_a, i_mu, i_s) = (3 * j, 3 * j + 1, 3 * j + 2);
                let c = |a: usize, b: usize| cov[a * n + b];
                let mean_hz = axis.f_min + (p[i_mu] + 0.5) * dw;
                let (amplitude, amplitude_stderr, sigma_hz, sigma_hz_stderr, power, power_stderr) = match &self.kernel {
                    None => {
                        let amplitude = p[i_a].exp();
                        let sigma_bins = p[i_s].exp();
                        let sigma_hz = sigma_bins * dw;
                        // Σ_k A·exp(−(k − μ)²/(2s²)) ≈ A·s·√(2π) (s in bins) = A·s_Hz·√(2π)/Δ.
                        let power = amplitude * sigma_bins * (2.0 * PI).sqrt();
                        (
                            amplitude,
                            amplitude * c(i_a, i_a).sqrt(),
                            sigma_hz,
                            sigma_hz * c(i_s, i_s).sqrt(),
                            power,
                            power * (c(i_a, i_a) + c(i_s, i_s) + 2.0 * c(i_a, i_s)).max(0.0).sqrt(),
                        )
                    }
                    Some(km) => {
                        let power = p[i_a].exp();
                        let v = p[i_s];
                        // The peak P·h(s²): ln peak = ln P + ln h, ∂ln h/∂s² = h'/h.
                        let (h, dh) = km.peak(v);
                        let q = dh / h;
                        let amplitude = power * h;
                        let ln_amp_var = c(i_a, i_a) + q * q * c(i_s, i_s) + 2.0 * q * c(i_a, i_s);
                        let sigma_bins = v.max(0.0).sqrt();
                        let v_se = c(i_s, i_s).max(0.0).sqrt();
                        let sigma_se =
                            if sigma_bins > 0.0 { (0.5 * v_se / sigma_bins).min(v_se.sqrt()) } else { v_se.sqrt() };
                        (
                            amplitude,
                            amplitude * ln_amp_var.max(0.0).sqrt(),
                            sigma_bins * dw,
                            sigma_se * dw,
                            power,
                            power * c(i_a, i_a).max(0.0).sqrt(),
                        )
                    }
                };
                GaussComponent {
                    amplitude,
                    amplitude_stderr,
                    mean_hz,
                    mean_hz_stderr: dw * c(i_mu, i_mu).sqrt(),
                    sigma_hz,
                    sigma_hz_stderr,
                    power,
                    power_stderr,
                    mean_velocity_m_per_s: radial_velocity(mean_hz, wavelength_m),
                    sigma_velocity_m_per_s: radial_velocity(sigma_hz, wavelength_m),
                }
            })
            .collect();
        components.sort_by(|a, b| a.sigma_hz.total_cmp(&b.sigma_hz));
        let (floor, floor_stderr) =
            if self.fit_floor { (p[n - 1], cov[n * n - 1].sqrt()) } else { (self.fixed_floor, 0.0) };
        Ok(GaussianFit {
            components,
            floor,
            floor_stderr,
            chi2: s.chi2,
            dof,
            iterations: s.iterations,
            covariance_scaled: scaled,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::doppler_frequency;
    use super::*;

    const LAMBDA: f64 = 1.55e-6;

    /// ±12.9 MHz (±10 m/s at 1.55 µm) in 256 bins of 100.8 kHz (0.078 m/s).
    fn axis() -> FrequencyAxis {
        let f = doppler_frequency(10.0, LAMBDA);
        FrequencyAxis::new(-f, f, 256).unwrap()
    }

    /// `b + Σ A·exp(−(f − μ)²/(2s²))` at the bin centres; components as (A, μ_Hz, s_Hz).
    fn model(axis: &FrequencyAxis, floor: f64, comps: &[(f64, f64, f64)]) -> Vec<f64> {
        (0..axis.bins)
            .map(|k| {
                let f = axis.center(k);
                floor + comps.iter().map(|&(a, mu, s)| a * (-0.5 * ((f - mu) / s).powi(2)).exp()).sum::<f64>()
            })
            .collect()
    }

    /// Aerosol at +2 m/s (σ 0.3 m/s) and rain at −4 m/s (σ 1.5 m/s), as (A, μ, s) in Hz.
    fn aerosol_and_rain() -> [(f64, f64, f64); 2] {
        let hz = |v| doppler_frequency(v, LAMBDA);
        [(3.0, hz(2.0), hz(0.3)), (1.2, hz(-4.0), hz(1.5))]
    }

    #[test]
    fn analytic_gradient_matches_finite_differences() {
        let y = model(&axis(), 0.1, &aerosol_and_rain());
        let stderr: Vec<f64> = (0..y.len()).map(|k| 0.05 + 0.001 * k as f64).collect();
        let problem = Problem::new(&y, Some(&stderr), Floor::Fitted, S_MIN_BINS);
        // Away from the minimum: Jᵀ W r = −½ ∂χ²/∂p.
        let p = vec![1.2, 170.0, 1.1, 0.1, 80.0, 2.4, 0.13];
        let (_, atr) = problem.normal_equations(&p);
        for i in 0..p.len() {
            let h = 1e-6;
            let (mut hi, mut lo) = (p.clone(), p.clone());
            hi[i] += h;
            lo[i] -= h;
            let numeric = -0.5 * (problem.chi2(&hi) - problem.chi2(&lo)) / (2.0 * h);
            assert!((atr[i] - numeric).abs() < 1e-6 * numeric.abs().max(1.0), "p{i}: {} vs {numeric}", atr[i]);
        }
    }

    #[test]
    fn noiseless_two_gaussians_to_machine_precision() {
        let axis = axis();
        let truth = aerosol_and_rain();
        for floor in [Floor::Fixed(0.25), Floor::Fitted] {
            let y = model(&axis, 0.25, &truth);
            let fit = fit_gaussians(&axis, &y, None, 2, LAMBDA, &FitOptions { floor, ..Default::default() }).unwrap();
            assert_eq!(fit.components.len(), 2);
            // Narrow (aerosol) first.
            for (c, &(a, mu, s)) in fit.components.iter().zip(&truth) {
                assert!((c.amplitude / a - 1.0).abs() < 1e-9, "{floor:?}: A {} vs {a}", c.amplitude);
                assert!((c.mean_hz - mu).abs() < 1e-9 * axis.bin_width(), "{floor:?}: μ {} vs {mu}", c.mean_hz);
                assert!((c.sigma_hz / s - 1.0).abs() < 1e-9, "{floor:?}: s {} vs {s}", c.sigma_hz);
                assert!((c.mean_velocity_m_per_s - LAMBDA * mu / 2.0).abs() < 1e-9);
                assert!((c.sigma_velocity_m_per_s - LAMBDA * s / 2.0).abs() < 1e-9);
                // The component's power is its sum over bins (on an axis 4× as wide with the
                // same bins: the rain line reaches the edge of the fitted one).
                let dw = axis.bin_width();
                let wide = FrequencyAxis::new(axis.f_min - 384.0 * dw, axis.f_max + 384.0 * dw, 1024).unwrap();
                let sum: f64 = model(&wide, 0.0, &[(a, mu, s)]).iter().sum();
                assert!((c.power / sum - 1.0).abs() < 1e-9, "power {} vs {sum}", c.power);
            }
            assert!((fit.floor - 0.25).abs() < 1e-12);
            assert!(fit.chi2 < 1e-20, "χ² {}", fit.chi2);
            assert_eq!(fit.dof, 256 - 6 - matches!(floor, Floor::Fitted) as usize);
            assert!(fit.covariance_scaled);
        }
    }

    #[test]
    fn components_are_sorted_by_width_whatever_their_heights() {
        // The broad line is the taller one here: it must still come second.
        let axis = axis();
        let hz = |v| doppler_frequency(v, LAMBDA);
        let truth = [(0.5, hz(1.0), hz(0.2)), (4.0, hz(-2.0), hz(1.0))];
        let fit = fit_gaussians(&axis, &model(&axis, 0.0, &truth), None, 2, LAMBDA, &FitOptions::default()).unwrap();
        assert!((fit.components[0].sigma_hz / hz(0.2) - 1.0).abs() < 1e-9);
        assert!((fit.components[1].sigma_hz / hz(1.0) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn concentric_narrow_on_broad_is_separated() {
        // Same mean: the residual of one Gaussian has no single clear peak; start (b) handles it.
        let axis = axis();
        let hz = |v| doppler_frequency(v, LAMBDA);
        let truth = [(2.0, hz(0.5), hz(0.25)), (1.0, hz(0.5), hz(2.0))];
        let fit = fit_gaussians(&axis, &model(&axis, 0.0, &truth), None, 2, LAMBDA, &FitOptions::default()).unwrap();
        for (c, &(a, mu, s)) in fit.components.iter().zip(&truth) {
            assert!((c.amplitude / a - 1.0).abs() < 1e-8, "A {} vs {a}", c.amplitude);
            assert!((c.mean_hz - mu).abs() < 1e-8 * axis.bin_width());
            assert!((c.sigma_hz / s - 1.0).abs() < 1e-8);
        }
    }

    #[test]
    fn one_component_fit_and_choice_on_noiseless_data() {
        let axis = axis();
        let hz = |v| doppler_frequency(v, LAMBDA);
        let y = model(&axis, 0.0, &[(1.0, hz(-3.3), hz(0.7))]);
        let fit = fit_gaussians(&axis, &y, None, 1, LAMBDA, &FitOptions::default()).unwrap();
        assert!((fit.components[0].mean_velocity_m_per_s + 3.3).abs() < 1e-9);
        assert!((fit.components[0].sigma_velocity_m_per_s - 0.7).abs() < 1e-9);
        // One line: a second component cannot lower χ² (or is degenerate), so one is kept.
        let choice = fit_one_or_two(&axis, &y, None, LAMBDA, &FitOptions::default()).unwrap();
        assert_eq!(choice.components, 1);
        assert_eq!(choice.chosen(), &choice.one);
        // Two lines: χ²₂ ≈ 0 against a large χ²₁.
        let choice =
            fit_one_or_two(&axis, &model(&axis, 0.0, &aerosol_and_rain()), None, LAMBDA, &FitOptions::default())
                .unwrap();
        assert_eq!(choice.components, 2);
        assert!(choice.p_value < 1e-12);
        assert_eq!(choice.chosen().components.len(), 2);
    }

    #[test]
    fn the_level_decides_the_choice() {
        // Rain 10× weaker than the aerosol in white noise (fixed seed): whatever p the F-test
        // gives, a level just above it keeps two components and one just below keeps one.
        let axis = axis();
        let hz = |v| doppler_frequency(v, LAMBDA);
        let clean = model(&axis, 0.0, &[(1.0, hz(2.0), hz(0.3)), (0.1, hz(-4.0), hz(1.5))]);
        let mut rng = crate::sampling::PathRng::new(7, crate::sampling::Purpose::Test, 0, 0);
        let y: Vec<f64> = clean.iter().map(|v| v + 0.05 * rng.normal()).collect();
        let se = vec![0.05; y.len()];
        let base = fit_one_or_two(&axis, &y, Some(&se), LAMBDA, &FitOptions::default()).unwrap();
        let p = base.p_value;
        assert!(p > 0.0 && p < 1e-6, "{p}");
        for (level, expect) in [(p * 1.01, 2), (p * 0.99, 1)] {
            let opts = FitOptions { selection_level: level, ..Default::default() };
            let c = fit_one_or_two(&axis, &y, Some(&se), LAMBDA, &opts).unwrap();
            assert_eq!((c.components, c.p_value), (expect, p));
        }
        let bad = FitOptions { selection_level: 1.0, ..Default::default() };
        assert!(fit_one_or_two(&axis, &y, Some(&se), LAMBDA, &bad).is_err());
    }

    #[test]
    fn weighted_covariance_is_not_rescaled() {
        // Noiseless data with stderrs s: χ² ≈ 0 but the standard errors are (JᵀWJ)⁻¹ as given —
        // doubling every stderr doubles every reported standard error.
        let axis = axis();
        let y = model(&axis, 0.0, &aerosol_and_rain());
        let one = vec![0.01; y.len()];
        let two = vec![0.02; y.len()];
        let a = fit_gaussians(&axis, &y, Some(&one), 2, LAMBDA, &FitOptions::default()).unwrap();
        let b = fit_gaussians(&axis, &y, Some(&two), 2, LAMBDA, &FitOptions::default()).unwrap();
        assert!(!a.covariance_scaled);
        for (ca, cb) in a.components.iter().zip(&b.components) {
            assert!((cb.mean_hz_stderr / ca.mean_hz_stderr - 2.0).abs() < 1e-6);
            assert!((cb.power_stderr / ca.power_stderr - 2.0).abs() < 1e-6);
            assert!(ca.mean_hz_stderr > 0.0 && ca.sigma_hz_stderr > 0.0);
        }
    }

    /// A 10-sample gate at 50 MHz on a 200 ns pulse (σ_p = 6.0 samples), 256-point DFT: the lag
    /// window `(M − d)·e^{−d²Δt²/(4σ_p²)}`.
    fn gate_kernel() -> GateKernel {
        let dt = 20e-9;
        let sigma_p = 200e-9 / (2.0 * std::f64::consts::LN_2.sqrt());
        let lags = (0..10).map(|d| (10 - d) as f64 * (-((d as f64 * dt) / sigma_p).powi(2) / 4.0).exp()).collect();
        GateKernel { lags, dt, fft_points: 256 }
    }

    /// The DFT axis of [`gate_kernel`]: bins `ν_k = (k − 128)·f_s/256` (195.3 kHz, 0.151 m/s).
    fn gate_axis() -> FrequencyAxis {
        let w = 50e6 / 256.0;
        FrequencyAxis::new(-128.5 * w, 127.5 * w, 256).unwrap()
    }

    /// The expected periodogram of lines `(P, μ, s)` (Gaussian spreads of frequency) through
    /// `kernel`, built independently of the fit's model: the lag sums
    /// `D_d = Σ P·(L_d/L_0)·e^{2πiμdΔt − 2π²s²d²Δt²}` (the characteristic function of a
    /// Gaussian), `D_{−d} = conj D_d`, and `P_k = (1/K)·Σ_{|d|<M} D_d e^{−2πiν_k dΔt}` summed in
    /// complex arithmetic.
    fn lag_sum_spectrum(kernel: &GateKernel, axis: &FrequencyAxis, floor: f64, lines: &[(f64, f64, f64)]) -> Vec<f64> {
        use num_complex::Complex64;
        let m = kernel.lags.len() as i64;
        let lag = |d: i64| -> Complex64 {
            let t = d.abs() as f64 * kernel.dt;
            let z: Complex64 = lines
                .iter()
                .map(|&(p, mu, s)| {
                    p * kernel.lags[d.unsigned_abs() as usize] / kernel.lags[0]
                        * Complex64::from_polar((-2.0 * PI * PI * s * s * t * t).exp(), 2.0 * PI * mu * t)
                })
                .sum();
            if d < 0 { z.conj() } else { z }
        };
        (0..axis.bins)
            .map(|k| {
                let nu = axis.center(k);
                let z: Complex64 = (1 - m..m)
                    .map(|d| lag(d) * Complex64::from_polar(1.0, -2.0 * PI * nu * d as f64 * kernel.dt))
                    .sum();
                floor + z.re / kernel.fft_points as f64
            })
            .collect()
    }

    #[test]
    fn kernel_gradient_matches_finite_differences() {
        let (kernel, axis) = (gate_kernel(), gate_axis());
        let hz = |v| doppler_frequency(v, LAMBDA);
        let y = lag_sum_spectrum(&kernel, &axis, 0.01, &[(3.0, hz(1.0), hz(0.3)), (1.0, hz(-2.0), hz(1.5))]);
        let stderr: Vec<f64> = (0..y.len()).map(|k| 0.005 + 1e-5 * k as f64).collect();
        let mut problem = Problem::new(&y, Some(&stderr), Floor::Fitted, S_MIN_BINS);
        problem.kernel = Some(KernelModel::new(&kernel, axis.bin_width(), axis.bins));
        // Away from the minimum, s² (bins²) of 3 and 150, and at s² = 0.
        for p in [vec![1.2, 135.0, 3.0, 0.1, 112.0, 150.0, 0.013], vec![0.9, 140.3, 0.0, -0.5, 100.0, 80.0, 0.0]] {
            let (_, atr) = problem.normal_equations(&p);
            for i in 0..p.len() {
                let h = 1e-5;
                let (mut hi, mut lo) = (p.clone(), p.clone());
                hi[i] += h;
                lo[i] -= h;
                let numeric = -0.5 * (problem.chi2(&hi) - problem.chi2(&lo)) / (2.0 * h);
                assert!((atr[i] - numeric).abs() < 1e-6 * numeric.abs().max(1.0), "p{i}: {} vs {numeric}", atr[i]);
            }
        }
    }

    #[test]
    fn kernel_basis_chi2_and_normal_equations_are_the_sums_over_bins() {
        // The fit's χ² and normal equations through the kernel's basis (LagSpace) against the
        // same sums taken bin by bin (the basis disabled), away from the minimum, at s² = 0 and
        // with a fitted floor: equal to round-off.
        let (kernel, axis) = (gate_kernel(), gate_axis());
        let hz = |v| doppler_frequency(v, LAMBDA);
        let y = lag_sum_spectrum(&kernel, &axis, 0.01, &[(3.0, hz(1.0), hz(0.3)), (1.0, hz(-2.0), hz(1.5))]);
        let stderr: Vec<f64> = (0..y.len()).map(|k| 0.005 + 1e-4 * (k as f64 - 100.0).abs()).collect();
        for floor in [Floor::Fitted, Floor::Fixed(0.01)] {
            let problem = |basis: bool| {
                let mut p = Problem::new(&y, Some(&stderr), floor, S_MIN_BINS);
                p.kernel = Some(KernelModel::new(&kernel, axis.bin_width(), axis.bins));
                if !basis {
                    assert!(p.lag_space.set(None).is_ok());
                }
                p
            };
            let (fast, slow) = (problem(true), problem(false));
            assert!(fast.lag().is_some() && slow.lag().is_none());
            for mut p in
                [vec![1.2, 135.0, 3.0, 0.1, 112.0, 150.0, 0.013], vec![0.9, 140.3, 0.0, -0.5, 100.0, 80.0, 0.0]]
            {
                if floor != Floor::Fitted {
                    p.pop();
                }
                let (a, b) = (fast.chi2(&p), slow.chi2(&p));
                assert!((a / b - 1.0).abs() < 1e-10, "χ² {a} vs {b}");
                let ((ata_f, atr_f), (ata_s, atr_s)) = (fast.normal_equations(&p), slow.normal_equations(&p));
                let scale = ata_s.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                for (x, y) in ata_f.iter().zip(&ata_s) {
                    assert!((x - y).abs() < 1e-10 * scale, "JᵀWJ {x} vs {y}");
                }
                let scale = atr_s.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                for (x, y) in atr_f.iter().zip(&atr_s) {
                    assert!((x - y).abs() < 1e-9 * scale, "JᵀWr {x} vs {y}");
                }
            }
        }
    }

    #[test]
    fn kernel_periodogram_is_the_lag_sum_spectrum_and_sums_to_its_power() {
        let (kernel, axis) = (gate_kernel(), gate_axis());
        let (p, mu, s) = (2.5, 1.7e6, 0.4e6);
        let want = lag_sum_spectrum(&kernel, &axis, 0.0, &[(p, mu, s)]);
        let got: Vec<f64> = (0..axis.bins).map(|k| kernel.periodogram(p, mu, s, axis.center(k))).collect();
        for (k, (a, b)) in got.iter().zip(&want).enumerate() {
            assert!((a - b).abs() < 1e-13 * p, "bin {k}: {a} vs {b}");
        }
        assert!((got.iter().sum::<f64>() / p - 1.0).abs() < 1e-12);
        // s = 0 is the kernel itself: a ~sinc² with zeros near every f_s/M = 5 MHz.
        let zero: Vec<f64> = (0..axis.bins).map(|k| kernel.periodogram(1.0, 0.0, 0.0, axis.center(k))).collect();
        let first_min = (129..160).find(|&k| zero[k + 1] > zero[k]).unwrap();
        assert!((25..=32).contains(&(first_min - 128)), "first minimum {} bins out", first_min - 128);
        let sidelobes: f64 =
            zero.iter().enumerate().filter(|(k, _)| k.abs_diff(128) >= first_min - 128).map(|(_, v)| v).sum();
        eprintln!("first minimum {} bins out, sidelobe power {sidelobes:.4}", first_min - 128);
        assert!((0.05..0.15).contains(&sidelobes), "sidelobe power {sidelobes}");
    }

    #[test]
    fn noiseless_kernel_lines_are_recovered() {
        // One and two Gaussian velocity spreads through a 10-sample gate's kernel (no plain
        // Gaussian fits these: the kernel is ~sinc²), on a floor: every parameter to 1e-6
        // relative (means to 1e-6 bin), the one-line data choose one component, and a single
        // velocity (s = 0) comes back with s = 0.
        let (kernel, axis) = (gate_kernel(), gate_axis());
        let hz = |v| doppler_frequency(v, LAMBDA);
        let dw = axis.bin_width();
        let check = |c: &GaussComponent, (p, mu, s): (f64, f64, f64)| {
            assert!((c.power / p - 1.0).abs() < 1e-6, "P {} vs {p}", c.power);
            assert!((c.mean_hz - mu).abs() < 1e-6 * dw, "μ {} vs {mu}", c.mean_hz);
            assert!((c.sigma_hz - s).abs() < 1e-6 * s.max(dw), "s {} vs {s}", c.sigma_hz);
            assert!((c.amplitude / kernel.periodogram(p, mu, s, mu) - 1.0).abs() < 1e-6);
        };
        for floor in [Floor::Fixed(0.02), Floor::Fitted] {
            let opts = FitOptions { floor, ..Default::default() };
            for line in [(2.0, hz(1.0), hz(0.3)), (0.7, hz(-3.1), hz(1.2)), (1.0, hz(0.37), 0.0)] {
                let y = lag_sum_spectrum(&kernel, &axis, 0.02, &[line]);
                let fit = fit_gaussians_with_kernel(&axis, &y, None, 1, LAMBDA, &opts, &kernel).unwrap();
                check(&fit.components[0], line);
                let choice = fit_one_or_two_with_kernel(&axis, &y, None, LAMBDA, &opts, &kernel).unwrap();
                assert_eq!(choice.components, 1, "{line:?}: p = {}", choice.p_value);
                // Plain Gaussians miss the kernel's sidelobes.
                if line.2 == 0.0 {
                    let plain = fit_gaussians(&axis, &y, None, 1, LAMBDA, &opts).unwrap();
                    assert!(plain.chi2 > 1e6 * fit.chi2.max(1e-30), "{} vs {}", plain.chi2, fit.chi2);
                }
            }
            // Aerosol and rain in one gate, 3 m/s apart: narrow first.
            let truth = [(2.0, hz(0.0), hz(0.3)), (1.0, hz(-3.0), hz(1.2))];
            let y = lag_sum_spectrum(&kernel, &axis, 0.02, &truth);
            let fit = fit_gaussians_with_kernel(&axis, &y, None, 2, LAMBDA, &opts, &kernel).unwrap();
            for (c, &t) in fit.components.iter().zip(&truth) {
                check(c, t);
            }
            let choice = fit_one_or_two_with_kernel(&axis, &y, None, LAMBDA, &opts, &kernel).unwrap();
            assert_eq!(choice.components, 2);
        }
        // An invalid kernel is an error, not a panic.
        let y = lag_sum_spectrum(&kernel, &axis, 0.0, &[(1.0, 0.0, 1e5)]);
        for bad in [
            GateKernel { lags: vec![], ..kernel.clone() },
            GateKernel { lags: vec![0.0, 1.0], ..kernel.clone() },
            GateKernel { dt: 0.0, ..kernel.clone() },
            GateKernel { fft_points: 5, ..kernel.clone() },
        ] {
            let r = fit_one_or_two_with_kernel(&axis, &y, None, LAMBDA, &FitOptions::default(), &bad);
            assert!(matches!(r, Err(RetrievalError::InvalidParameter { .. })), "{bad:?}: {r:?}");
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let axis = FrequencyAxis::new(0.0, 10.0, 10).unwrap();
        let y = [0.0, 0.1, 1.0, 3.0, 1.0, 0.1, 0.0, 0.0, 0.0, 0.0];
        let opts = FitOptions::default();
        assert!(matches!(
            fit_gaussians(&axis, &y[..9], None, 1, LAMBDA, &opts),
            Err(RetrievalError::LengthMismatch { .. })
        ));
        assert!(matches!(
            fit_gaussians(&axis, &y, None, 3, LAMBDA, &opts),
            Err(RetrievalError::InvalidParameter { name: "components", .. })
        ));
        assert!(matches!(
            fit_gaussians(&axis, &y, Some(&[1.0; 10].map(|s: f64| s - 1.0)), 1, LAMBDA, &opts),
            Err(RetrievalError::InvalidParameter { name: "stderr", .. })
        ));
        assert_eq!(fit_gaussians(&axis, &[0.0; 10], None, 1, LAMBDA, &opts), Err(RetrievalError::NoSignal));
        let small = FrequencyAxis::new(0.0, 6.0, 6).unwrap();
        assert_eq!(
            fit_gaussians(&small, &y[..6], None, 2, LAMBDA, &opts),
            Err(RetrievalError::TooFewPoints { needed: 7, found: 6 })
        );
        let capped = FitOptions { max_iterations: 1, ..opts };
        assert_eq!(
            fit_gaussians(&axis, &model(&axis, 0.0, &[(1.0, 4.3, 1.7)]), None, 1, LAMBDA, &capped),
            Err(RetrievalError::DidNotConverge { iterations: 1 })
        );
    }
}
