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

use std::f64::consts::PI;

use glam::DVec3;
use num_complex::Complex;

use crate::SPEED_OF_LIGHT;

/// Path classes of the range–Doppler outputs: every path, single scattering, multiple.
pub const LIDAR_CHANNELS: [&str; 3] = ["total", "single", "multiple"];

/// Amplitude support of the pulse, in units of `σ` (the amplitude there is `e^{−18}` ≈ 1.5e-8).
const PULSE_SUPPORT_SIGMAS: f64 = 6.0;

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
}

/// Offsets of a lidar receiver's tallies.
#[derive(Debug, Clone, PartialEq)]
pub struct LidarLayout {
    /// `[channel][gate][lag d][re, im]`: the lag sums `D_d`.
    pub lags: usize,
    /// `[channel][gate][bin]`: the expected periodograms (filled per batch from the lag sums).
    pub spectra: usize,
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

    /// Area of the receiving aperture, m².
    pub fn aperture_area(&self) -> f64 {
        PI * self.aperture_radius * self.aperture_radius
    }

    /// Lay out the tallies from `start`.
    pub fn layout(&self, start: &mut usize) -> LidarLayout {
        let channels = LIDAR_CHANNELS.len();
        let lags = *start;
        *start += channels * self.gates * self.gate_points * 2;
        let spectra = *start;
        *start += channels * self.gates * self.fft_points;
        LidarLayout { lags, spectra }
    }

    /// Record a detected path of weight `w`, optical path length `l` (emission to aperture, m) and
    /// beat frequency `f` (Hz) into channel 0 and the channel of its scattering order. `x` is
    /// scratch space for the pulse samples, reused across calls (no allocation per path).
    #[allow(clippy::too_many_arguments)]
    pub fn record(&self, lay: &LidarLayout, acc: &mut [f64], x: &mut Vec<f64>, w: f64, l: f64, f: f64, order: u32) {
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
                    let o = lay.lags + ((c * self.gates + g) * m_len + d) * 2;
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
        }
    }

    fn run(s: &LidarSpec, lines: &[(f64, f64, f64, u32)]) -> (LidarLayout, Vec<f64>) {
        let mut len = 0;
        let lay = s.layout(&mut len);
        let mut acc = vec![0.0; len];
        let mut x = Vec::new();
        for &(w, l, f, o) in lines {
            s.record(&lay, &mut acc, &mut x, w, l, f, o);
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
}
