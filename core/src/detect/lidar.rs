//! The receiver of a pulsed coherent Doppler lidar: range gates as windows of the sampled
//! heterodyne signal, and their expected periodograms split into single and multiple scattering.
//!
//! ## Signal model
//!
//! The transmitted pulse has a Gaussian intensity envelope of full width at half maximum `τ_p`:
//! amplitude `a(t) = exp(−t²/2σ²)/(σ√π)^{1/2}` with `σ = τ_p/(2√ln 2)`, normalised to unit energy
//! (`∫a² dt = 1`). A detected path of weight `w` (fraction of the pulse energy reaching the
//! receiver), optical path length `l` and beat frequency `f` adds the heterodyne signal
//! `√w·a(t − l/c)·e^{2πi f t + iφ}` with a random phase `φ` (paths are mutually incoherent,
//! Kim et al. 2025 Eq. 19). The digitiser samples it at `f_s`; gate `g` is the `M` samples
//! `t_j = t_0 + j/f_s`, `j = gM … gM + M − 1` (contiguous gates, rectangular window), and its
//! spectrum is the `K`-point DFT (zero-padded, `K ≥ M`) in fftshift order,
//! `ν_k = (k − K/2)·f_s/K`, normalised as `P_k = |X_k|²/K` so that `Σ_k P_k` is the energy of the
//! samples, `Σ_j |x_j|²`, with `x_j = a(t_j − l/c)·√Δt` (a fraction of the pulse energy).
//!
//! ## What is accumulated
//!
//! The expected periodogram of a gate is linear in the paths and depends on them only through the
//! lag sums `D_d = Σ_paths w·e^{2πi f d/f_s}·Σ_m x_{m+d} x_m` (`0 ≤ d < M`, `D_{−d} = conj D_d`):
//! `E P(ν) = (1/K)·[D_0 + 2 Re Σ_{d≥1} D_d e^{−2πi ν d/f_s}]` exactly. A path therefore costs
//! `O(P²)` for the `P ≤ M` samples its pulse touches in each gate (a ±6σ support), never `O(K)`:
//! per gate and path class only `M` complex lag sums are kept, and each batch's spectra are made
//! from its lag sums ([`LidarSpec::finish_batch`]) so that every bin has its batch standard
//! error. `D_0` is the gate's energy: the overlap of the pulse with the gate window, summed over
//! the paths (the "gate weighting" of the lidar equation).
//!
//! With no other broadening, a gate that holds the whole pulse shows the pulse's power spectrum,
//! a Gaussian of FWHM `2 ln 2/(π τ_p) = 0.4413/τ_p` (validation-values §4.9), centred on `f`.
//!
//! ## Shot-noise floor
//!
//! The spectra above are noiseless expectations of the signal. A shot-noise-limited heterodyne
//! receiver (local oscillator strong enough that its shot noise dominates every other noise) adds
//! to each complex (I/Q) sample, which is one temporal mode of duration `Δt = 1/f_s`, a zero-mean
//! circular white noise of one photon energy `hν` per mode referred to the signal:
//! `E|n_j|²·E_p = hν/η` with `ν = c/λ0` and `η = η_q·η_h` the detector's quantum efficiency times
//! the heterodyne (mixing, mode-matching) efficiency. The wideband carrier-to-noise ratio of a
//! signal of power `P_s` is then `η P_s/(hν B)` with the noise bandwidth `B = f_s` of the complex
//! samples (Frehlich & Kavaya 1991, Appl. Opt. 30:5325, Eq. 1 with the antenna efficiency as
//! `η_h`; Rye & Hardesty 1993, IEEE TGRS 31:16, the wideband CNR). In this module's units
//! (fraction of the pulse energy `E_p`, so `|x_j|²` is the signal's share of the pulse in sample
//! `j`) the noise variance per sample is
//!
//! `σ² = hν/(η E_p)`  ([`LidarSpec::noise_variance_per_sample`]),
//!
//! so the per-sample SNR `|x_j|²/σ²` equals `η E_p|x_j|²/hν`, the number of signal photoelectrons
//! in the sample: the CNR above with `P_s = E_p|x_j|²/Δt` and `B = 1/Δt`.
//!
//! The noise's expected periodogram follows from the same lag-sum formula as the signal's: for
//! white noise `E D_0 = Σ_m E|n_m|² = Mσ²` and `E D_d = Σ_m E n_{m+d} n̄_m = 0` for `d ≥ 1`, so
//! `E P_k = (1/K)·[Mσ² + 0] = Mσ²/K` in every bin ([`LidarSpec::noise_floor_per_bin`]),
//! independent of the zero padding's `K` only through the `1/K` that spreads the gate's noise
//! energy `Mσ²` over `K` bins (Parseval: `Σ_k P_k = Σ_m |x_m|²`). Signal and noise are independent,
//! so a measured gate's expected periodogram is the signal's plus this floor; averaging `N`
//! pulses leaves both unchanged and divides the fluctuations (each bin exponentially distributed
//! for one pulse) by `√N`. A gate's SNR as [`crate::retrieval::gate_estimates`] reports it,
//! `Σ_k (P_k − floor)/(K·floor) = D_0/(Mσ²)`, is therefore the wideband CNR averaged over the
//! gate's samples.
//!
//! ## Per-gate estimates
//!
//! What is read off a gate's total spectrum plus that floor (moments and one- or two-component
//! fits through the gate's kernel) is post-processing of a finished run's spectra:
//! [`crate::retrieval::lidar::retrieve_gate`].
//!
//! ## The gate's kernel
//!
//! For echoes whose beat frequencies are independent of their delays, the lag sums factorise
//! (see [`GateKernel`]): `E D_d = W·L_d·φ(dΔt)`, with `φ` the characteristic function of the
//! frequencies and `L_d` the lag window, `Σ_m x_{m+d}x_m` averaged over the echo delays `t_e`
//! with their density `ρ(t_e)`. With `x_m = a(t_m − t_e)√Δt` and the unit-energy pulse's
//! autocorrelation `∫a(u + τ)a(u)du = e^{−τ²/(4σ_p²)}`, a density uniform over the gate and
//! the pulse's reach around it gives
//!
//! `L_d = (M − d)·e^{−d²Δt²/(4σ_p²)}`  ([`LidarSpec::gate_kernel`], up to the constant `ρΔt`):
//!
//! the triangle of the rectangular window times the pulse's autocorrelation. A density linear in
//! delay across the gate (the `1/R²` and extinction trends of a filled volume, to first order)
//! leaves it unchanged: the product `a(t_{m+d} − t_e)·a(t_m − t_e)` is centred on the midpoint of
//! the two samples, and over `m = 0 … M − 1 − d` those midpoints average to the gate's centre
//! for every `d`.
//!
//! The curvature does not cancel, and it matters: a convex density (`1/R²`) weighs the gate's
//! ends, where only short lags have sample pairs, so the long lags fall below the triangle (in
//! the haze of `tests/it/lidar.rs`, `L_9` is 4.5 % low at 100 m and 0.8 % at 670 m: measured from
//! the receiver's own lag sums, and reproduced to the Monte Carlo noise by integrating the lidar
//! equation's density), and a one-velocity gate then looks like a spread of 0.1–0.2 m/s that the
//! Monte Carlo errors resolve. [`LidarSpec::gate_kernel_in`] therefore integrates the lag window
//! over the single-scattering echo density of a filled volume seen with full overlap,
//!
//! `ρ(t_e) ∝ e^{q u}/R(t_e)²`,  `R = c t_e/2`, `u = t_e − t_g` (`t_g` the gate's centre),
//!
//! the `1/R²` known and `e^{q u}` the local two-way transmission and backscatter profile, log-linear
//! with its slope `q` fitted to the energies `D_0` of the gate's neighbours (a slope only: a
//! log-curvature fitted from three noisy gate energies was tried, and its Monte Carlo noise left
//! 0.1–0.3 % errors in `L_9` that the F-test still resolved in 9 of 20 haze gates). It is not
//! the kernel of a thin layer inside a long gate (there `L_d ∝ e^{−d²Δt²/(4σ_p²)}`, without the
//! triangle: the pulse's Gaussian spectrum).

use std::f64::consts::PI;

use glam::DVec3;
use num_complex::Complex;

use super::detector_output;
use crate::SPEED_OF_LIGHT;
use crate::output::{Axis, Kind, Output, Registry, Slots};
use crate::retrieval::GateKernel;
use crate::spectrum::FrequencyAxis;

/// Path classes of the range–Doppler outputs: every path, single scattering, multiple.
pub const LIDAR_CHANNELS: [&str; 3] = ["total", "single", "multiple"];

/// Amplitude support of the pulse, in units of `σ` (the amplitude there is `e^{−18}` ≈ 1.5e-8).
const PULSE_SUPPORT_SIGMAS: f64 = 6.0;

/// Planck constant, J·s (exact in the 2019 SI).
pub const PLANCK: f64 = 6.626_070_15e-34;

/// Default transmitted pulse energy, J: 100 µJ, the USTC/NUIST coherent Doppler wind lidar
/// (Wu et al. 2024, Acta Opt. Sin. 44:1636001, Table 1; media/references.md §B1), also the Halo
/// StreamLine XR's ≈100 µJ.
pub const DEFAULT_PULSE_ENERGY: f64 = 100e-6;
/// Default detector quantum efficiency (InGaAs photodiodes at 1.55 µm: 0.7–0.9).
pub const DEFAULT_QUANTUM_EFFICIENCY: f64 = 0.8;
/// Default heterodyne (mixing and mode-matching) efficiency: about 0.4 for a monostatic system
/// with a truncated Gaussian beam matched to the aperture (Frehlich & Kavaya 1991 give at most
/// 0.42 for the optimal truncation in the far field).
pub const DEFAULT_HETERODYNE_EFFICIENCY: f64 = 0.4;

/// A monostatic pulsed lidar receiver at the transceiver.
#[derive(Debug, Clone, PartialEq)]
pub struct LidarSpec {
    /// Centre of the receiving aperture (the transceiver), m.
    pub position: DVec3,
    /// Unit pointing direction (the receiver accepts light travelling along `−axis`).
    pub axis: DVec3,
    /// Radius of the receiving aperture (a disk perpendicular to `axis`), m.
    pub aperture_radius: f64,
    /// Cosine of the field-of-view half-angle.
    pub cos_fov: f64,
    /// Intensity FWHM of the pulse, s.
    pub pulse_fwhm: f64,
    /// Digitiser rate `f_s`, Hz.
    pub sample_rate: f64,
    /// Time of the first sample of gate 0 after emission, s.
    pub first_sample_time: f64,
    /// Samples per gate `M`.
    pub gate_points: usize,
    pub gates: usize,
    /// DFT length `K ≥ M` (zero padding).
    pub fft_points: usize,
    /// Vacuum wavelength `λ0` of the source, m (photon energy, radial velocities).
    pub wavelength: f64,
    /// Transmitted pulse energy `E_p`, J.
    pub pulse_energy: f64,
    /// Detector quantum efficiency `η_q` in (0, 1].
    pub quantum_efficiency: f64,
    /// Heterodyne (mixing, mode-matching) efficiency `η_h` in (0, 1].
    pub heterodyne_efficiency: f64,
}

/// Offsets of a lidar receiver's tallies.
#[derive(Debug, Clone, PartialEq)]
pub struct LidarLayout {
    /// `[channel][gate][lag d][re, im]`: the lag sums `D_d`.
    pub lags: usize,
    /// `[channel][gate][bin]`: the expected periodograms (filled per batch from the lag sums).
    pub spectra: usize,
    /// The power of the echoes whose beat frequency lies outside the spectra's band
    /// `[−f_s/2, f_s/2)`: sampled at `f_s`, they fold into it at a wrong velocity (aliasing).
    pub aliased: usize,
}

impl LidarSpec {
    /// Amplitude standard deviation `σ = τ_p/(2√ln 2)` of the pulse envelope, s.
    pub fn pulse_sigma(&self) -> f64 {
        self.pulse_fwhm / (2.0 * std::f64::consts::LN_2.sqrt())
    }

    /// Sample interval `1/f_s`, s.
    pub fn dt(&self) -> f64 {
        1.0 / self.sample_rate
    }

    /// Range (m) of the centre of gate `g`: `c·t/2` at the mean time of its samples.
    pub fn gate_range(&self, g: usize) -> f64 {
        let t = self.first_sample_time
            + ((g * self.gate_points) as f64 + 0.5 * (self.gate_points as f64 - 1.0)) * self.dt();
        0.5 * SPEED_OF_LIGHT * t
    }

    /// Frequency of DFT bin `k` (fftshift order), Hz.
    pub fn bin_frequency(&self, k: usize) -> f64 {
        (k as f64 - (self.fft_points / 2) as f64) * self.sample_rate / self.fft_points as f64
    }

    /// The bins as an ascending [`FrequencyAxis`]: `K` bins of `f_s/K` centred on
    /// [`bin_frequency`](Self::bin_frequency)`(k)` (fftshift order is ascending order), from
    /// `ν_0 − Δ/2` to `ν_{K−1} + Δ/2`. `None` only for a degenerate spec (`f_s` not positive).
    pub fn frequency_axis(&self) -> Option<FrequencyAxis> {
        let half = 0.5 * self.sample_rate / self.fft_points as f64;
        FrequencyAxis::new(
            self.bin_frequency(0) - half,
            self.bin_frequency(self.fft_points - 1) + half,
            self.fft_points,
        )
    }

    /// The spectral kernel of a gate filled uniformly with echoes (module docs, "The gate's
    /// kernel"): the lag window `L_d = (M − d)·exp(−d²Δt²/(4σ_p²))`, `d = 0 … M − 1`, with
    /// `σ_p` = [`pulse_sigma`](Self::pulse_sigma), on this receiver's `Δt` and `K`.
    pub fn gate_kernel(&self) -> GateKernel {
        let (dt, sigma, m) = (self.dt(), self.pulse_sigma(), self.gate_points);
        let lags = (0..m)
            .map(|d| {
                let tau = d as f64 * dt;
                (m - d) as f64 * (-tau * tau / (4.0 * sigma * sigma)).exp()
            })
            .collect();
        GateKernel { lags, dt, fft_points: self.fft_points }
    }

    /// The spectral kernel of gate `g` for the echo density `e^{q u}/R²` of a filled volume
    /// (module docs, "The gate's kernel"), with the slope `q` fitted to the gate energies
    /// `energies` (`D_0` of every gate, the total channel): the model's energies of the two gates
    /// around `g` (the first or last three gates' outer two at the ends) have the observed ratio.
    /// The integral over the echo delays is a Riemann sum on a grid of `σ_p/4` over the gate's
    /// samples and `4.5σ_p` around them (the sum is exact to far below 10⁻⁹ for a Gaussian
    /// pulse, by Poisson summation; beyond the cut a pair of samples weighs `e^{−20}` = 2·10⁻⁹
    /// of its peak, so even a `1/R²` 100 times larger there leaves 2·10⁻⁷). Falls back to the uniform [`gate_kernel`](Self::gate_kernel) when there are
    /// fewer than three gates, `energies` is not one per gate, one of the two is not positive and
    /// finite (an empty neighbour: a layer's edge, where no smooth density holds anyway), the
    /// delays reach back to the transceiver (`R ≤ 1 m`), or the slope does not converge.
    pub fn gate_kernel_in(&self, g: usize, energies: &[f64]) -> GateKernel {
        self.filled_volume_lags(g, energies)
            .map(|lags| GateKernel { lags, dt: self.dt(), fft_points: self.fft_points })
            .unwrap_or_else(|| self.gate_kernel())
    }

    /// `Σ_{t_e} ρ(t_e)·Σ_m x_{m+d}(t_e) x_m(t_e)` for gate `j`, `d = 0 … lags − 1`, with
    /// `ρ = e^{q(t_e − t_c)}·(R_c/R)²` about the centre `t_c` of gate `c` (`x` unnormalised).
    fn density_lag_window(&self, j: usize, c: usize, q: f64, lags: usize) -> Option<Vec<f64>> {
        let (dt, sigma, m) = (self.dt(), self.pulse_sigma(), self.gate_points);
        let t0 = self.first_sample_time + (j * m) as f64 * dt;
        let t1 = t0 + (m - 1) as f64 * dt;
        let t_c = 2.0 * self.gate_range(c) / SPEED_OF_LIGHT;
        let (reach, h) = (4.5 * sigma, 0.25 * sigma);
        let start = t0 - reach;
        if 0.5 * SPEED_OF_LIGHT * start <= 1.0 {
            return None;
        }
        let mut out = vec![0.0; lags];
        let mut x = vec![0.0; m];
        let steps = ((t1 + reach - start) / h).ceil() as usize;
        for i in 0..=steps {
            let t_e = start + i as f64 * h;
            let rho = (q * (t_e - t_c)).exp() * (t_c / t_e).powi(2);
            for (k, v) in x.iter_mut().enumerate() {
                let u = t0 + k as f64 * dt - t_e;
                *v = (-u * u / (2.0 * sigma * sigma)).exp();
            }
            for (d, o) in out.iter_mut().enumerate() {
                *o += rho * x[d..].iter().zip(&x).map(|(a, b)| a * b).sum::<f64>();
            }
        }
        out.iter().all(|v| v.is_finite()).then_some(out)
    }

    /// `L_d` of gate `g` for the filled-volume density, or `None` (see
    /// [`gate_kernel_in`](Self::gate_kernel_in)).
    fn filled_volume_lags(&self, g: usize, energies: &[f64]) -> Option<Vec<f64>> {
        let (gates, m) = (self.gates, self.gate_points);
        if gates < 3 || energies.len() != gates || g >= gates {
            return None;
        }
        let j0 = g.saturating_sub(1).min(gates - 3);
        let (e0, e2) = (energies[j0], energies[j0 + 2]);
        if !(e0.is_finite() && e2.is_finite() && e0 > 0.0 && e2 > 0.0) {
            return None;
        }
        let observed = (e2 / e0).ln();
        let span = 2.0 * (m as f64) * self.dt();
        let model = |q: f64| -> Option<f64> {
            let a = self.density_lag_window(j0, g, q, 1)?[0];
            let b = self.density_lag_window(j0 + 2, g, q, 1)?[0];
            let r = (b / a).ln();
            r.is_finite().then_some(r)
        };
        // d ln(E_2/E_0)/dq ≈ the two gates' separation: a fixed-point iteration on it.
        let mut q = 0.0;
        let mut converged = false;
        for _ in 0..50 {
            let residual = observed - model(q)?;
            q += residual / span;
            if residual.abs() < 1e-12 {
                converged = true;
                break;
            }
        }
        if !converged {
            return None;
        }
        let w = self.density_lag_window(g, g, q, m)?;
        // Scaled so that a uniform density gives (M − d)·e^{−d²Δt²/(4σ_p²)}.
        (w[0] > 0.0).then(|| w.iter().map(|v| v / w[0] * m as f64).collect())
    }

    /// Photon energy `hν = hc/λ0`, J.
    pub fn photon_energy(&self) -> f64 {
        PLANCK * SPEED_OF_LIGHT / self.wavelength
    }

    /// Overall detection efficiency `η = η_q·η_h`.
    pub fn efficiency(&self) -> f64 {
        self.quantum_efficiency * self.heterodyne_efficiency
    }

    /// Shot-noise variance of one complex sample in units of the pulse energy,
    /// `σ² = hν/(η E_p)` (module docs, "Shot-noise floor").
    pub fn noise_variance_per_sample(&self) -> f64 {
        self.photon_energy() / (self.efficiency() * self.pulse_energy)
    }

    /// Expected shot-noise periodogram of a gate, per bin: `M·σ²/K` (fraction of the pulse energy
    /// per bin, the units of the spectra).
    pub fn noise_floor_per_bin(&self) -> f64 {
        self.gate_points as f64 * self.noise_variance_per_sample() / self.fft_points as f64
    }

    /// Area of the receiving aperture, m².
    pub fn aperture_area(&self) -> f64 {
        PI * self.aperture_radius * self.aperture_radius
    }

    /// Lay out the receiver's tallies (detector `i`, called `name`) from the end of `reg` and
    /// declare its outputs: the range–Doppler spectra of each channel, from the lag sums, and the
    /// power of aliased echoes (a scalar, `aliased_power`).
    pub fn declare(&self, i: usize, name: &str, reg: &mut Registry) -> LidarLayout {
        let channels = LIDAR_CHANNELS.len();
        let budget = Some((format!("detectors[{i}].lidar.gates"), format!("= {}", self.gates)));
        let n = channels * self.gates * self.gate_points * 2;
        let lags = reg.take(n);
        reg.declare(Output {
            budget_key: budget.clone(),
            ..detector_output(i, format!("{name}.lag_sums"), Kind::Internal, Slots::contiguous(lags, n), vec![n])
        });
        let (gates, bins) = (self.gates, self.fft_points);
        let spectra = reg.take(channels * gates * bins);
        for (c, channel) in LIDAR_CHANNELS.iter().enumerate() {
            let stem = if c == 0 { "range_doppler".to_string() } else { format!("range_doppler_{channel}") };
            reg.declare(Output {
                units: "fraction of the pulse energy per bin",
                file: format!("{name}_{stem}.npy"),
                primary: c == 0,
                budget_key: budget.clone(),
                axes: vec![
                    Axis::file("range_m", "m", format!("{name}_range_m.npy")),
                    Axis::file("frequency_hz", "Hz", format!("{name}_frequency_hz.npy")),
                ],
                ..detector_output(
                    i,
                    format!("{name}.{stem}"),
                    Kind::RangeDoppler { gates, bins },
                    Slots::contiguous(spectra + c * gates * bins, gates * bins),
                    vec![gates, bins],
                )
            });
        }
        // After the spectra, so that the slots before it stay where they were.
        let aliased = reg.take(1);
        reg.declare(Output {
            units: "fraction of the pulse energy",
            file: format!("/estimates/detectors/{name}/aliased_power/value"),
            ..detector_output(i, format!("{name}.aliased_power"), Kind::Scalar, Slots::contiguous(aliased, 1), vec![])
        });
        LidarLayout { lags, spectra, aliased }
    }

    /// Whether an echo of beat frequency `f` (Hz) lies outside the band `[−f_s/2, f_s/2)` the
    /// sampled signal represents, so that its spectrum folds in at `f` minus a multiple of `f_s`.
    #[inline]
    pub fn aliases(&self, f: f64) -> bool {
        let half = 0.5 * self.sample_rate;
        !(-half..half).contains(&f)
    }

    /// Offset of the lag sum `D_d` of channel `c` in gate `g` (real part; the imaginary part
    /// follows) from the start of the lag sums: `[channel][gate][lag d][re, im]`.
    #[inline(always)]
    pub fn lag_slot(&self, c: usize, g: usize, d: usize) -> usize {
        ((c * self.gates + g) * self.gate_points + d) * 2
    }

    /// Record a detected path `echo` into channel 0 and the channel of its scattering order (and,
    /// beyond the sampled band, into the aliased power). `x` is scratch space for the pulse
    /// samples, reused across calls (no allocation per path).
    pub fn record(&self, lay: &LidarLayout, acc: &mut [f64], x: &mut Vec<f64>, echo: Echo) {
        let Echo { weight: w, length: l, frequency: f, order } = echo;
        if self.aliases(f) {
            acc[lay.aliased] += w;
        }
        let class = if order <= 1 { 1 } else { 2 };
        let dt = self.dt();
        let sigma = self.pulse_sigma();
        let t_d = l / SPEED_OF_LIGHT;
        let samples = (self.gates * self.gate_points) as f64;
        // The samples the pulse touches: |t_j − t_d| ≤ 6σ.
        let lo = ((t_d - PULSE_SUPPORT_SIGMAS * sigma - self.first_sample_time) / dt).ceil().max(0.0);
        let hi = ((t_d + PULSE_SUPPORT_SIGMAS * sigma - self.first_sample_time) / dt).floor().min(samples - 1.0);
        if lo.is_nan() || hi.is_nan() || lo > hi {
            return;
        }
        let (lo, hi) = (lo as usize, hi as usize);
        // x_j = a(t_j − t_d)·√Δt with a of unit energy.
        let scale = (dt / (sigma * PI.sqrt())).sqrt();
        let inv_2s2 = 1.0 / (2.0 * sigma * sigma);
        x.clear();
        x.extend((lo..=hi).map(|j| {
            let u = self.first_sample_time + j as f64 * dt - t_d;
            scale * (-u * u * inv_2s2).exp()
        }));
        let step = Complex::from_polar(1.0, 2.0 * PI * (f * dt).rem_euclid(1.0));
        let m_len = self.gate_points;
        for g in lo / m_len..=hi / m_len {
            // The gate's samples that the pulse touches, as indices into `x`.
            let a = (g * m_len).max(lo) - lo;
            let b = ((g + 1) * m_len - 1).min(hi) - lo;
            let xs = &x[a..=b];
            let mut z = Complex::new(w, 0.0);
            for d in 0..xs.len() {
                let r: f64 = xs[d..].iter().zip(xs).map(|(p, q)| p * q).sum();
                let v = z * r;
                for c in [0, class] {
                    let o = lay.lags + self.lag_slot(c, g, d);
                    acc[o] += v.re;
                    acc[o + 1] += v.im;
                }
                z *= step;
            }
        }
    }

    /// Fill a batch's spectra from its lag sums: `P_k = (1/K)[D_0 + 2 Re Σ_{d≥1} D_d e^{−2πiν_k d/f_s}]`.
    pub fn finish_batch(&self, lay: &LidarLayout, acc: &mut [f64]) {
        let (m, k_len) = (self.gate_points, self.fft_points);
        // e^{−2πi ν_k d/f_s} = e^{−2πi (k − K/2) d/K}; the phase (k − K/2)·d mod K is exact.
        let table: Vec<(f64, f64)> = (0..k_len).map(|p| (2.0 * PI * p as f64 / k_len as f64).sin_cos()).collect();
        let half = k_len / 2;
        for cg in 0..LIDAR_CHANNELS.len() * self.gates {
            let lags = lay.lags + cg * m * 2;
            let d: Vec<(f64, f64)> = (0..m).map(|i| (acc[lags + 2 * i], acc[lags + 2 * i + 1])).collect();
            if d[0].0 == 0.0 {
                continue;
            }
            let out = lay.spectra + cg * k_len;
            for k in 0..k_len {
                let shift = (k + k_len - half) % k_len;
                let mut s = 0.0;
                for (i, &(re, im)) in d.iter().enumerate().skip(1) {
                    let (sin, cos) = table[(shift * i) % k_len];
                    // Re[(re + i·im)(cos − i·sin)] = re·cos + im·sin.
                    s += re * cos + im * sin;
                }
                acc[out + k] = (d[0].0 + 2.0 * s) / k_len as f64;
            }
        }
    }
}

/// A detected path as a lidar records it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Echo {
    pub weight: f64,
    /// Optical path length from emission to the aperture, m.
    pub length: f64,
    /// Beat frequency, Hz.
    pub frequency: f64,
    /// Scattering order.
    pub order: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> LidarSpec {
        LidarSpec {
            position: DVec3::ZERO,
            axis: DVec3::Z,
            aperture_radius: 0.04,
            cos_fov: 0.0,
            pulse_fwhm: 200e-9,
            sample_rate: 50e6,
            first_sample_time: 0.0,
            gate_points: 10,
            gates: 40,
            fft_points: 64,
            wavelength: 1.55e-6,
            pulse_energy: DEFAULT_PULSE_ENERGY,
            quantum_efficiency: DEFAULT_QUANTUM_EFFICIENCY,
            heterodyne_efficiency: DEFAULT_HETERODYNE_EFFICIENCY,
        }
    }

    fn run(s: &LidarSpec, lines: &[(f64, f64, f64, u32)]) -> (LidarLayout, Vec<f64>) {
        let mut reg = crate::output::Registry::default();
        let lay = s.declare(0, "lidar", &mut reg);
        let mut acc = vec![0.0; reg.len];
        let mut x = Vec::new();
        for &(w, l, f, o) in lines {
            s.record(&lay, &mut acc, &mut x, Echo { weight: w, length: l, frequency: f, order: o });
        }
        s.finish_batch(&lay, &mut acc);
        (lay, acc)
    }

    /// `|Σ_j x_j e^{2πi(f − ν_k)t_j}|²/K` for one gate, summed directly.
    fn direct(s: &LidarSpec, l: f64, f: f64, g: usize) -> Vec<f64> {
        let sigma = s.pulse_sigma();
        let t_d = l / SPEED_OF_LIGHT;
        (0..s.fft_points)
            .map(|k| {
                let nu = s.bin_frequency(k);
                let mut z = Complex::new(0.0, 0.0);
                for m in 0..s.gate_points {
                    let j = g * s.gate_points + m;
                    let t = s.first_sample_time + j as f64 * s.dt();
                    let a = (-(t - t_d).powi(2) / (2.0 * sigma * sigma)).exp() / (sigma * PI.sqrt()).sqrt();
                    z += Complex::from_polar(a * s.dt().sqrt(), 2.0 * PI * (f - nu) * (m as f64) * s.dt());
                }
                z.norm_sqr() / s.fft_points as f64
            })
            .collect()
    }

    #[test]
    fn lag_sums_give_the_direct_periodogram() {
        let s = spec();
        let (l, f) = (2.0 * 600.0, 3.3e6); // a path from 600 m
        let (lay, acc) = run(&s, &[(0.7, l, f, 3)]);
        for g in 0..s.gates {
            let want = direct(&s, l, f, g);
            for c in [0, 2] {
                let o = lay.spectra + (c * s.gates + g) * s.fft_points;
                for k in 0..s.fft_points {
                    let got = acc[o + k];
                    assert!((got - 0.7 * want[k]).abs() < 1e-12 * 0.7, "gate {g} bin {k}: {got} vs {}", want[k]);
                }
            }
            let single = lay.spectra + (s.gates + g) * s.fft_points;
            assert!(acc[single..single + s.fft_points].iter().all(|&v| v == 0.0));
        }
    }

    #[test]
    fn gate_energies_add_up_to_the_pulse_energy() {
        // Σ_k P_k = D_0 = the energy in the gate; over all gates, the whole pulse (its ±6σ
        // support lies inside the gated window), to the accuracy of sampling a Gaussian 10
        // times per FWHM (Poisson summation: error ~e^{−π²σ²f_s²}, negligible).
        let s = spec();
        let (lay, acc) = run(&s, &[(1.0, 2.0 * 700.0, -1.0e6, 1)]);
        let mut total = 0.0;
        for g in 0..s.gates {
            let o = lay.spectra + g * s.fft_points;
            let e: f64 = acc[o..o + s.fft_points].iter().sum();
            let d0 = acc[lay.lags + g * s.gate_points * 2];
            assert!((e - d0).abs() < 1e-12, "gate {g}: {e} vs {d0}");
            total += e;
        }
        assert!((total - 1.0).abs() < 1e-9, "{total}");
    }

    #[test]
    fn long_gate_shows_the_pulse_spectrum() {
        // One 2.56 µs gate around a 200 ns pulse: the periodogram is the pulse's power spectrum,
        // Gaussian of FWHM 0.4413/τ_p = 2.2066 MHz, at f (sampled on a fine zero-padded grid).
        let s = LidarSpec { gate_points: 128, gates: 1, fft_points: 4096, ..spec() };
        let f = 2.0e6;
        let (lay, acc) = run(&s, &[(1.0, SPEED_OF_LIGHT * 1.28e-6, f, 1)]);
        let p = &acc[lay.spectra..lay.spectra + s.fft_points];
        let (kmax, &pmax) = p.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).unwrap();
        assert!((s.bin_frequency(kmax) - f).abs() <= s.sample_rate / s.fft_points as f64);
        let width = p.iter().filter(|&&v| v >= 0.5 * pmax).count() as f64 * s.sample_rate / s.fft_points as f64;
        let want = 2.0 * std::f64::consts::LN_2 / (PI * s.pulse_fwhm);
        assert!((width / want - 1.0).abs() < 0.01, "FWHM {width} vs {want}");
    }

    #[test]
    fn frequency_axis_centres_are_the_fftshift_bins() {
        for k_len in [64, 65, 256] {
            let s = LidarSpec { fft_points: k_len, ..spec() };
            let axis = s.frequency_axis().unwrap();
            assert_eq!(axis.bins, k_len);
            for k in 0..k_len {
                assert!((axis.center(k) - s.bin_frequency(k)).abs() < 1e-6, "K = {k_len}, bin {k}");
            }
            assert!((axis.bin_width() - s.sample_rate / k_len as f64).abs() < 1e-6);
        }
    }

    #[test]
    fn noise_floor_numbers() {
        // hν at 1.55 µm = 1.2816e-19 J; η = 0.32, E_p = 100 µJ: σ² = 4.005e-15; M = 10, K = 64.
        let s = spec();
        assert!((s.photon_energy() / 1.281_6e-19 - 1.0).abs() < 1e-4, "{}", s.photon_energy());
        let sigma2 = s.photon_energy() / (0.8 * 0.4 * 100e-6);
        assert!((s.noise_variance_per_sample() / sigma2 - 1.0).abs() < 1e-14);
        assert!((s.noise_floor_per_bin() - 10.0 * sigma2 / 64.0).abs() < 1e-14 * sigma2);
        // Twice the energy, half the noise.
        let s2 = LidarSpec { pulse_energy: 2.0 * s.pulse_energy, ..s.clone() };
        assert!((s2.noise_floor_per_bin() * 2.0 / s.noise_floor_per_bin() - 1.0).abs() < 1e-14);
    }

    #[test]
    fn white_noise_through_the_lag_sums_gives_the_floor() {
        // White circular complex Gaussian samples of variance σ² (re, im each σ²/2), put through
        // the receiver's own periodogram (lag sums D_d = Σ_m n_{m+d}·conj(n_m), then
        // finish_batch): the mean over R realisations is Mσ²/K in every bin. Each bin of one
        // realisation is exponential with mean Mσ²/K, so the mean over R has a relative standard
        // error 1/√R = 0.0125 at R = 6400: every bin within 5 of those. The average over the K
        // bins is the samples' energy over K (Parseval), a sum of M exponentials: within
        // 5/√(R·M).
        let s = LidarSpec { gates: 1, ..spec() };
        let (m, k_len) = (s.gate_points, s.fft_points);
        let sigma2 = s.noise_variance_per_sample();
        let floor = s.noise_floor_per_bin();
        let mut reg = crate::output::Registry::default();
        let lay = s.declare(0, "lidar", &mut reg);
        let len = reg.len;
        let reps = 6400;
        let mut mean = vec![0.0; k_len];
        let mut rng = crate::sampling::PathRng::new(11, crate::sampling::Purpose::Test, 0, 0);
        let sd = (0.5 * sigma2).sqrt();
        for _ in 0..reps {
            let n: Vec<Complex<f64>> = (0..m).map(|_| Complex::new(sd * rng.normal(), sd * rng.normal())).collect();
            let mut acc = vec![0.0; len];
            for d in 0..m {
                let v: Complex<f64> = (0..m - d).map(|j| n[j + d] * n[j].conj()).sum();
                acc[lay.lags + 2 * d] = v.re;
                acc[lay.lags + 2 * d + 1] = v.im;
            }
            s.finish_batch(&lay, &mut acc);
            // Parseval: the bins sum to the samples' energy.
            let energy: f64 = n.iter().map(|z| z.norm_sqr()).sum();
            let total: f64 = acc[lay.spectra..lay.spectra + k_len].iter().sum();
            assert!((total - energy).abs() < 1e-12 * energy);
            for (a, v) in mean.iter_mut().zip(&acc[lay.spectra..lay.spectra + k_len]) {
                *a += v / reps as f64;
            }
        }
        let rel = 1.0 / (reps as f64).sqrt();
        for (k, v) in mean.iter().enumerate() {
            assert!((v / floor - 1.0).abs() < 5.0 * rel, "bin {k}: {v:.4e} vs Mσ²/K = {floor:.4e}");
        }
        let avg = mean.iter().sum::<f64>() / k_len as f64;
        assert!((avg / floor - 1.0).abs() < 5.0 / ((reps * m) as f64).sqrt(), "{avg:.4e} vs {floor:.4e}");
    }

    #[test]
    fn gate_kernel_model_matches_echoes_spread_uniformly_in_delay() {
        // Echoes on a fine grid of delays (σ_p/4 apart, uniform weight) covering gate 20 and 8σ_p
        // of pulse around it, each with beat frequencies on a fine grid (σ/10 apart, ±8σ) weighted
        // by a Gaussian of mean μ and standard deviation σ: the receiver's own lag sums and
        // periodogram of gate 20. Both grids are Riemann sums of Gaussians, exact far below
        // 1e-9 (Poisson summation), and the pulse's ±6σ_p support truncates at 1.5e-8 of the
        // amplitude. The one-component fit through gate_kernel() returns μ and σ to 1e-6 and
        // the gate's energy D_0 as the power; σ = 0 (one velocity) comes back as 0.
        let s = LidarSpec { fft_points: 256, ..spec() };
        let (g, sp) = (20, s.pulse_sigma());
        let t0 = s.first_sample_time + (g * s.gate_points) as f64 * s.dt();
        let t1 = t0 + (s.gate_points - 1) as f64 * s.dt();
        let delays: Vec<f64> = {
            let (a, h) = (t0 - 8.0 * sp, 0.25 * sp);
            (0..).map(|i| a + i as f64 * h).take_while(|&t| t <= t1 + 8.0 * sp).collect()
        };
        let axis = s.frequency_axis().unwrap();
        let kernel = s.gate_kernel();
        let dw = axis.bin_width();
        for (mu, sigma) in [(1.3e6, 0.4e6), (-2.1e6, 1.5e6), (0.77e6, 0.0)] {
            let lines: Vec<(f64, f64)> = if sigma == 0.0 {
                vec![(mu, 1.0)]
            } else {
                let raw: Vec<(f64, f64)> = (-80..=80)
                    .map(|i| {
                        let z = i as f64 / 10.0;
                        (mu + z * sigma, (-0.5 * z * z).exp())
                    })
                    .collect();
                let total: f64 = raw.iter().map(|l| l.1).sum();
                raw.into_iter().map(|(f, w)| (f, w / total)).collect()
            };
            let mut paths = Vec::new();
            for &t in &delays {
                for &(f, w) in &lines {
                    paths.push((w, t * SPEED_OF_LIGHT, f, 1));
                }
            }
            let (lay, acc) = run(&s, &paths);
            let o = lay.spectra + g * s.fft_points;
            let p = &acc[o..o + s.fft_points];
            let d0 = acc[lay.lags + g * s.gate_points * 2];
            let fit = crate::retrieval::fit_gaussians_with_kernel(
                &axis,
                p,
                None,
                1,
                s.wavelength,
                &crate::retrieval::FitOptions::default(),
                &kernel,
            )
            .unwrap();
            let c = &fit.components[0];
            eprintln!(
                "μ {mu:e}, σ {sigma:e}: fitted {:.9e} ± {:.1e}, σ {:.9e}, P/D_0 − 1 = {:.1e}",
                c.mean_hz,
                c.mean_hz_stderr,
                c.sigma_hz,
                c.power / d0 - 1.0
            );
            assert!((c.mean_hz - mu).abs() < 1e-6 * dw, "μ {} vs {mu}", c.mean_hz);
            assert!((c.sigma_hz - sigma).abs() < 1e-6 * sigma.max(dw), "σ {} vs {sigma}", c.sigma_hz);
            assert!((c.power / d0 - 1.0).abs() < 1e-6, "P {} vs D_0 {d0}", c.power);
        }
    }

    #[test]
    fn gate_kernel_in_follows_a_filled_volume_echo_density() {
        // Gates 1–3 around 100 m; echoes on a fine grid of delays (σ_p/4 apart) covering them and
        // 8σ_p around, weighted by e^{−σ_t c t}/R² (two-way extinction 5.5e-3 /m, 1/R²), one
        // frequency each. The receiver's lag sums of gate 2 are W·L_d·e^{2πifdΔt}: |D_d|/D_0 is
        // its true lag window, and gate_kernel_in, given only the gate energies D_0, reproduces
        // it to 1e-6 (the Riemann sums are exact far below; the pulse's ±6σ_p cut in the
        // receiver is 1.5e-8, the kernel's 4.5σ_p cut ≤ 2e-7), where the uniform kernel is 2.5 %
        // off at the longest lag.
        let s = LidarSpec { first_sample_time: 2.0 * 73.0 / SPEED_OF_LIGHT, gates: 5, ..spec() };
        let (g, sp, m) = (2, s.pulse_sigma(), s.gate_points);
        let t_c = 2.0 * s.gate_range(g) / SPEED_OF_LIGHT;
        let reach = 1.5 * m as f64 * s.dt() + 8.0 * sp;
        let paths: Vec<(f64, f64, f64, u32)> = (0..)
            .map(|i| t_c - reach + i as f64 * 0.25 * sp)
            .take_while(|&t| t <= t_c + reach)
            .map(|t| ((-5.5e-3 * SPEED_OF_LIGHT * t).exp() / (t * t), t * SPEED_OF_LIGHT, 1.7e6, 1))
            .collect();
        let (lay, acc) = run(&s, &paths);
        let energies: Vec<f64> = (0..s.gates).map(|j| acc[lay.lags + j * m * 2]).collect();
        let lag = |d: usize| {
            let o = lay.lags + (g * m + d) * 2;
            acc[o].hypot(acc[o + 1])
        };
        let fitted = s.gate_kernel_in(g, &energies);
        let uniform = s.gate_kernel();
        for d in 1..m {
            let truth = lag(d) / lag(0);
            let got = fitted.lags[d] / fitted.lags[0];
            assert!((got / truth - 1.0).abs() < 1e-6, "d = {d}: {got} vs {truth}");
        }
        let off = uniform.lags[m - 1] / uniform.lags[0] / (lag(m - 1) / lag(0)) - 1.0;
        assert!(off > 0.02, "uniform kernel off by {off}");
        // An empty neighbour, too few gates, delays back to the transceiver (gate 0 here, from
        // 73 m: 4.5σ_p is 81 m): the uniform kernel.
        let mut holed = energies.clone();
        holed[3] = 0.0;
        assert_eq!(s.gate_kernel_in(g, &holed), uniform);
        assert_eq!(s.gate_kernel_in(g, &energies[..4]), uniform);
        let two = LidarSpec { gates: 2, ..s.clone() };
        assert_eq!(two.gate_kernel_in(0, &energies[..2]), two.gate_kernel());
        let near = LidarSpec { first_sample_time: 0.0, ..s.clone() };
        assert_eq!(near.gate_kernel_in(0, &energies), near.gate_kernel());
        assert_eq!(s.gate_kernel_in(0, &energies), uniform);
        assert_ne!(s.gate_kernel_in(4, &energies), uniform);
    }
}
