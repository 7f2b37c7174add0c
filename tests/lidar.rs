//! Pulsed coherent Doppler lidar against closed forms (validation-values §4.9): the single-
//! scattering lidar equation per range gate, the Doppler peak at 2v_LOS/λ0, and the pulse-limited
//! spectral width 0.4413/τ_p.

mod common;

use common::{Run, chi2_sf, run};
use ohd::SPEED_OF_LIGHT;

/// Homogeneous haze (HG g = 0.7, σs = 5e-3 /m, σa = 5e-4 /m) from 0 to 1200 m, a pencil beam
/// straight up from 1 m below it, wind (3, 0, 1) m/s, 1550 nm; a monostatic receiver (40 mm
/// aperture radius, 1 mrad field of view): 20 gates of 10 samples at 50 MHz (30 m) from 90 m,
/// a 200 ns pulse.
const HAZE: &str = r#"
schema_version = 1
[run]
samples = 1_000_000
seed = 3
batches = 40
[source]
wavelength_nm = 1550
position_m = [0, 0, -1]
direction = [0, 0, 1]
[media.haze]
sigma_s_per_m = 5e-3
sigma_a_per_m = 5e-4
phase = { type = "hg", g = 0.7 }
velocity = { type = "uniform", velocity_m_per_s = [3, 0, 1] }
[[layers]]
thickness_m = 1200
n = 1.0
medium = "haze"
[[detectors]]
name = "lidar"
[detectors.lidar]
aperture_radius_mm = 40
field_of_view_mrad = 1
pulse_fwhm_ns = 200
sample_rate_mhz = 50
first_gate_m = 90
gate_points = 10
gates = 20
fft_points = 256
"#;

/// Vacuum wavelength, m.
const LAMBDA: f64 = 1550e-9;

fn lidar(r: &Run) -> (&ohd::detect::LidarSpec, &ohd::detect::LidarLayout) {
    (r.exp.detectors[0].lidar.as_ref().unwrap(), r.out.layout.detectors[0].lidar.as_ref().unwrap())
}

/// Gate energy of channel `c` (0 total, 1 single, 2 multiple): the lag sum D_0, with its error.
fn gate_energy(r: &Run, c: usize, g: usize) -> (f64, f64) {
    let (s, lay) = lidar(r);
    let o = lay.lags + ((c * s.gates + g) * s.gate_points) * 2;
    (r.out.estimates.mean()[o], r.out.estimates.stderr()[o])
}

/// The pulse energy that gate `g` collects from a return delayed by `t_d`: Σ_m a(t_m − t_d)²Δt
/// over its samples (a of unit energy, Gaussian with intensity FWHM τ_p).
fn gate_weight(s: &ohd::detect::LidarSpec, g: usize, t_d: f64) -> f64 {
    let sigma = s.pulse_sigma();
    (0..s.gate_points)
        .map(|m| {
            let t = s.first_sample_time + (g * s.gate_points + m) as f64 * s.dt();
            (-(t - t_d).powi(2) / (sigma * sigma)).exp() / (sigma * std::f64::consts::PI.sqrt()) * s.dt()
        })
        .sum()
}

#[test]
fn single_scattering_follows_the_lidar_equation_in_every_gate() {
    // E_g = ∫ σs·p(π)·A/R²·exp(−2σt·s)·W_g(2R/c) ds with R = s + 1 m the range from the
    // transceiver, s the depth into the haze (Simpson's rule, 0.02 m steps; the aperture's
    // offset from the axis, ≤ 4e-5 rad, changes p and R by < 1e-8 relative).
    let r = run(HAZE, &[]);
    let (spec, _) = lidar(&r);
    let (sigma_s, sigma_t, g): (f64, f64, f64) = (5e-3, 5.5e-3, 0.7);
    let p_back = (1.0 - g * g) / (4.0 * std::f64::consts::PI * (1.0 + g).powi(3));
    let area = spec.aperture_area();
    let (mut stat, mut dof) = (0.0, 0);
    for gate in 0..spec.gates {
        let f = |s: f64| {
            let range = s + 1.0;
            sigma_s * p_back * area / (range * range)
                * (-2.0 * sigma_t * s).exp()
                * gate_weight(spec, gate, 2.0 * range / SPEED_OF_LIGHT)
        };
        let h = 0.02;
        let n = (1200.0 / h) as usize;
        let mut sum = f(0.0) + f(1200.0);
        for i in 1..n {
            sum += f(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
        }
        let expected = sum * h / 3.0;
        let (v, e) = gate_energy(&r, 1, gate);
        let z = (v - expected) / e;
        eprintln!(
            "gate {gate} ({:.0} m): single {v:.4e} ± {e:.1e}, lidar equation {expected:.4e}, z = {z:+.2}",
            spec.gate_range(gate)
        );
        assert!(z.abs() < 4.5, "gate {gate}: z = {z}");
        stat += z * z;
        dof += 1;
    }
    let p = chi2_sf(stat, dof);
    assert!(p > 1e-3, "χ² = {stat:.1} for {dof} gates, p = {p:.2e}");
}

/// Spectrum of channel `c` in gate `g` (fftshift order) and its bin frequencies.
fn gate_spectrum(r: &Run, c: usize, g: usize) -> (Vec<f64>, Vec<f64>) {
    let (s, lay) = lidar(r);
    let o = lay.spectra + (c * s.gates + g) * s.fft_points;
    let f = (0..s.fft_points).map(|k| s.bin_frequency(k)).collect();
    (r.out.estimates.mean()[o..o + s.fft_points].to_vec(), f)
}

/// Index of the largest value.
fn argmax(p: &[f64]) -> usize {
    (0..p.len()).max_by(|&a, &b| p[a].total_cmp(&p[b])).unwrap()
}

#[test]
fn doppler_peak_sits_at_twice_the_line_of_sight_speed_over_lambda_in_every_gate() {
    // Wind (3, 0, 1) m/s seen straight up: v_LOS = +1 m/s (receding), f = 2v/λ0 = 1.2903 MHz.
    // Singly scattered light has exactly that frequency (the aperture offset changes it by
    // < 1e-8), so every gate's single-scattering periodogram is the windowed pulse's kernel
    // centred there: its peak, refined by a parabola through the three top bins, within 0.05
    // bin (195 kHz bins).
    let r = run(HAZE, &["run.samples=100000"]);
    let f0 = 2.0 * 1.0 / LAMBDA;
    let (spec, _) = lidar(&r);
    let width = spec.sample_rate / spec.fft_points as f64;
    for g in 0..spec.gates {
        let (p, f) = gate_spectrum(&r, 1, g);
        let k = argmax(&p);
        let (a, b, c) = (p[k - 1], p[k], p[k + 1]);
        let peak = f[k] + 0.5 * (a - c) / (a - 2.0 * b + c) * width;
        assert!((peak - f0).abs() < 0.05 * width, "gate {g}: peak {peak} Hz vs {f0} Hz");
    }
}

#[test]
fn a_gate_holding_the_whole_pulse_has_the_pulse_limited_width() {
    // A 2 m slab of haze at 299–301 m and one 2.56 µs gate (384 m) centred on it: every return
    // lies far inside the gate, so its periodogram is the pulse's power spectrum, a Gaussian of
    // FWHM 2 ln 2/(π τ_p) = 0.4413/τ_p = 2.2064 MHz for τ_p = 200 ns (validation-values §4.9), here on 12.2 kHz
    // bins (4096-point DFT). Half-maximum crossings by linear interpolation: within 0.5 %.
    let slab = r#"
schema_version = 1
[run]
samples = 20_000
seed = 5
batches = 16
[source]
wavelength_nm = 1550
position_m = [0, 0, -1]
direction = [0, 0, 1]
[media.clear]
sigma_s_per_m = 0
sigma_a_per_m = 0
[media.haze]
sigma_s_per_m = 5e-2
sigma_a_per_m = 0
phase = { type = "hg", g = 0.7 }
velocity = { type = "uniform", velocity_m_per_s = [0, 0, -2] }
[[layers]]
thickness_m = 299
n = 1.0
medium = "clear"
[[layers]]
thickness_m = 2
n = 1.0
medium = "haze"
[[detectors]]
name = "lidar"
[detectors.lidar]
aperture_radius_mm = 40
field_of_view_mrad = 1
pulse_fwhm_ns = 200
sample_rate_mhz = 50
first_gate_m = 109
gate_points = 128
gates = 1
fft_points = 4096
"#;
    let r = run(slab, &[]);
    let (p, f) = gate_spectrum(&r, 1, 0);
    let k = argmax(&p);
    let half = 0.5 * p[k];
    let cross = |range: &mut dyn Iterator<Item = usize>| -> f64 {
        let mut prev = k;
        for j in range {
            if p[j] < half {
                return f[prev] + (f[j] - f[prev]) * (p[prev] - half) / (p[prev] - p[j]);
            }
            prev = j;
        }
        panic!("no half-maximum crossing");
    };
    let fwhm = cross(&mut (k + 1..p.len())) - cross(&mut (0..k).rev());
    let want = 2.0 * std::f64::consts::LN_2 / (std::f64::consts::PI * 200e-9);
    assert!((want * 200e-9 - 0.4413).abs() < 1e-4);
    eprintln!("FWHM {fwhm:.1} Hz vs 2 ln 2/(π τ_p) = {want:.1} Hz");
    assert!((fwhm / want - 1.0).abs() < 0.005, "FWHM {fwhm} Hz vs {want} Hz");
    // Approaching at 2 m/s: the line at −2.5806 MHz.
    assert!((f[k] + 2.0 * 2.0 / LAMBDA).abs() <= 0.5 * (f[1] - f[0]), "peak at {} Hz", f[k]);
}
