//! Speckle statistics of single-window spectra (validation-values §4.8, §4.10): the mean of many
//! Algorithm 2 windows is Algorithm 1 convolved with |W|² (the exact expected periodogram), single
//! bins are exponential (contrast 1), sums of K independent bins have contrast 1/√K, and Algorithm
//! 1's Exp(1) draw has the same per-bin statistics. Fixed seeds; tolerances are tail
//! probabilities (p ≥ 1e-3) or standard errors, never re-rolled.

use crate::support::stats::{MeanChi2, contrast, ks_test, mean_vector_chi2};

use std::f64::consts::PI;

use num_complex::Complex;
use ohd::sampling::rng::{PathRng, Purpose};
use ohd::spectrum::{Line, Stft, Synthesizer, Window, speckle_draw};

const FS: f64 = 39_000.0;
const SEED: u64 = 20_250_731;

/// `count` lines of equal power (total 1): half uniform in each box `centre ± half_width`, like the
/// paper's speckle tutorial (two peaks, uniform within ±W).
fn two_box_lines(count: usize, boxes: [(f64, f64); 2], gammas: &[f64], element: u64) -> Vec<Line> {
    let mut rng = PathRng::new(SEED, Purpose::Test, element, 0);
    (0..count)
        .map(|j| {
            let (centre, half) = boxes[j % 2];
            Line {
                power: 1.0 / count as f64,
                frequency: centre + half * (2.0 * rng.uniform() - 1.0),
                gamma: gammas[j % gammas.len()],
            }
        })
        .collect()
}

/// `windows` Algorithm 2 periodograms, window `i` from stream `(SEED, Speckle, element, i)`.
fn windows(stft: &Stft, lines: &[Line], windows: usize, element: u64) -> Vec<Vec<f64>> {
    let mut synth = Synthesizer::new(stft);
    (0..windows)
        .map(|i| {
            let mut out = vec![0.0; stft.samples()];
            synth.periodogram(lines, &mut PathRng::new(SEED, Purpose::Speckle, element, i as u64), &mut out);
            out
        })
        .collect()
}

fn report(what: &str, r: &MeanChi2) {
    eprintln!(
        "{what}: χ² = {:.1} over {} bins (Satterthwaite a = {:.3}, dof = {:.1}), p = {:.3}; max |z| = {:.2} \
         (Bonferroni p = {:.3})",
        r.stat, r.components, r.scale, r.dof, r.p, r.max_abs_z, r.p_max_z
    );
}

/// The complex DFT amplitude of each line (unit phase) in each bin, normalised so that
/// `|b_jk|² = p_j K(ν_k − f_j, 0)`: `b_jk = √p_j Σ_n w[n] e^{2πi (f_j − ν_k) n/f_s}/√(N Σw²)`.
fn line_bin_amplitudes(stft: &Stft, lines: &[Line]) -> Vec<Vec<Complex<f64>>> {
    let n = stft.samples();
    lines
        .iter()
        .map(|l| {
            (0..n)
                .map(|k| {
                    let x = ((l.frequency - stft.bin_frequency(k)) % FS) / FS;
                    let s: Complex<f64> = stft
                        .coefficients()
                        .iter()
                        .enumerate()
                        .map(|(t, &w)| Complex::from_polar(w, 2.0 * PI * (x * t as f64).fract()))
                        .sum();
                    s * (l.power / stft.norm()).sqrt()
                })
                .collect()
        })
        .collect()
}

/// Exact covariance of the powers of bins `k` and `l` for fixed lines with independent uniform
/// phases: `|Σ_j b_jk b̄_jl|² − Σ_j |b_jk|²|b_jl|²` (the fourth moment of a random-phasor sum).
fn exact_covariance(b: &[Vec<Complex<f64>>], k: usize, l: usize) -> f64 {
    let cross: Complex<f64> = b.iter().map(|bj| bj[k] * bj[l].conj()).sum();
    let fourth: f64 = b.iter().map(|bj| bj[k].norm_sqr() * bj[l].norm_sqr()).sum();
    cross.norm_sqr() - fourth
}

#[test]
fn algorithm2_mean_is_expected_periodogram() {
    // 2000 windows of 200 lines in two 2 kHz wide boxes (−8 kHz and +11 kHz): the per-bin mean of
    // the fast Algorithm 2 equals Σ_j p_j K(ν_k − f_j) (Algorithm 1 convolved with |W|², Eq. 28).
    for (case, (n, window)) in [(64, Window::Hann), (64, Window::Rect), (512, Window::Hann)].into_iter().enumerate() {
        let stft = Stft::new(FS, n, window).unwrap();
        let lines = two_box_lines(200, [(-8_000.0, 1_000.0), (11_000.0, 1_000.0)], &[0.0], 1);
        let expected = stft.expected_periodogram(&lines);
        let samples = windows(&stft, &lines, 2_000, case as u64);
        let r = mean_vector_chi2(&samples, &expected);
        report(&format!("Algorithm 2 mean, N = {n}, {}", window.name()), &r);
        assert!(r.p >= 1e-3 && r.p_max_z >= 1e-3, "{r:?}");
        // The window's total power is speckled too, but its mean is the lines' power (Parseval).
        let totals: Vec<f64> = samples.iter().map(|s| s.iter().sum::<f64>()).collect();
        let (c, _) = contrast(&totals);
        let mean = totals.iter().sum::<f64>() / totals.len() as f64;
        let se = c * mean / (totals.len() as f64).sqrt();
        eprintln!("  mean total power {mean:.4} ± {se:.4} (expected 1)");
        assert!((mean - 1.0).abs() <= 4.0 * se);
    }
}

#[test]
fn brownian_algorithm2_mean_is_expected_periodogram() {
    // Lines broadened by Brownian motion (HWHM 0.3, 2 and 5 bins, and some pure tones): Cauchy
    // frequencies per window reproduce the Lorentzian-broadened kernel in the mean.
    //
    // (a) One broadened line, 50000 windows, all bins: each window's bin power is bounded by the
    // line's power, so the per-bin means are Gaussian and the test is sharp.
    let stft = Stft::new(FS, 64, Window::Hann).unwrap();
    for (case, gamma) in [0.3, 2.0, 5.0].into_iter().enumerate() {
        let lines = [Line { power: 1.0, frequency: 3_111.0, gamma: gamma * stft.bin_width() }];
        let expected = stft.expected_periodogram(&lines);
        let samples = windows(&stft, &lines, 50_000, 100 + case as u64);
        let r = mean_vector_chi2(&samples, &expected);
        report(&format!("one Brownian line, γ = {gamma} bins, N = 64, hann"), &r);
        assert!(r.p >= 1e-3 && r.p_max_z >= 1e-3, "{r:?}");
    }
    // (b) 2000 lines in the two boxes, 2000 windows, the bins whose expected power is at least 1%
    // of the peak (chosen from the expectation alone). Far outside, the expected power is the sum
    // of rare Cauchy excursions of single lines: per-window skewness up to 14 (measured), too
    // heavy a tail for a Gaussian test of a 2000-window mean.
    for (case, n) in [64usize, 512].into_iter().enumerate() {
        let stft = Stft::new(FS, n, Window::Hann).unwrap();
        let d = stft.bin_width();
        let lines =
            two_box_lines(2_000, [(-8_000.0, 1_000.0), (11_000.0, 1_000.0)], &[0.3 * d, 2.0 * d, 0.0, 5.0 * d], 2);
        let expected = stft.expected_periodogram(&lines);
        let peak = expected.iter().cloned().fold(0.0, f64::max);
        let body: Vec<usize> = (0..n).filter(|&k| expected[k] >= 1e-2 * peak).collect();
        let samples: Vec<Vec<f64>> = windows(&stft, &lines, 2_000, 10 + case as u64)
            .into_iter()
            .map(|s| body.iter().map(|&k| s[k]).collect())
            .collect();
        let e: Vec<f64> = body.iter().map(|&k| expected[k]).collect();
        let r = mean_vector_chi2(&samples, &e);
        report(&format!("Brownian Algorithm 2 mean, 2000 lines, N = {n}, hann"), &r);
        assert!(r.p >= 1e-3 && r.p_max_z >= 1e-3, "{r:?}");
    }
}

#[test]
fn algorithm2_bin_power_is_exponential() {
    // The bin of box B (10–12 kHz) with the most effective contributors: its power over 2000
    // windows, divided by its exact mean, is Exp(1) (KS), and its contrast is 1 within 4 standard
    // errors. "Contributing" lines lie within the Hann main lobe (±2 bins); the effective number
    // L_eff = (Σ|b_j|²)²/Σ|b_j|⁴ sets the exact contrast √(1 − 1/L_eff) of the random-phasor sum.
    let stft = Stft::new(FS, 64, Window::Hann).unwrap();
    let lines = two_box_lines(200, [(-8_000.0, 1_000.0), (11_000.0, 1_000.0)], &[0.0], 3);
    let b = line_bin_amplitudes(&stft, &lines);
    let expected = stft.expected_periodogram(&lines);
    let l_eff = |k: usize| {
        let s2: f64 = b.iter().map(|bj| bj[k].norm_sqr()).sum();
        let s4: f64 = b.iter().map(|bj| bj[k].norm_sqr().powi(2)).sum();
        s2 * s2 / s4
    };
    let k = (0..64)
        .filter(|&k| (10_000.0..=12_000.0).contains(&stft.bin_frequency(k)))
        .max_by(|&i, &j| l_eff(i).partial_cmp(&l_eff(j)).unwrap())
        .unwrap();
    let (leff, nu) = (l_eff(k), stft.bin_frequency(k));
    let contributing = lines.iter().filter(|l| (l.frequency - nu).abs() < 2.0 * stft.bin_width()).count();
    assert!(contributing >= 30 && leff >= 30.0, "bin {k}: {contributing} lines, L_eff = {leff}");
    let exact_contrast = (exact_covariance(&b, k, k)).sqrt() / expected[k];
    let samples = windows(&stft, &lines, 2_000, 20);
    let mut x: Vec<f64> = samples.iter().map(|s| s[k] / expected[k]).collect();
    let (c, se) = contrast(&x);
    let (d, p) = ks_test(&mut x, |v| 1.0 - (-v).exp());
    eprintln!(
        "bin {k} ({nu:.0} Hz), {contributing} lines in the main lobe, L_eff = {leff:.1}: KS D = {d:.4}, \
         p = {p:.3}; contrast {c:.4} ± {se:.4} (exact {exact_contrast:.4}, fully developed 1)"
    );
    assert!(p > 1e-3);
    assert!((c - 1.0).abs() <= 4.0 * se);
}

#[test]
fn sum_of_independent_bins_has_contrast_one_over_sqrt_k() {
    // 2000 lines uniform over 2–12 kHz (≈ 120 per bin), Hann: bins 3 apart are uncorrelated for a
    // flat spectrum (w² has Fourier components only up to ±2), so the sum of K = 4 such bins is
    // Gamma(4)-like with contrast 1/√K = 0.5. The exact contrast of the sum for these fixed lines
    // follows from the exact bin covariances.
    let stft = Stft::new(FS, 64, Window::Hann).unwrap();
    let lines = two_box_lines(2_000, [(7_000.0, 5_000.0), (7_000.0, 5_000.0)], &[0.0], 4);
    let bins = [37usize, 40, 43, 46]; // 3.0, 4.9, 6.7, 8.5 kHz
    let b = line_bin_amplitudes(&stft, &lines);
    let expected = stft.expected_periodogram(&lines);
    let mean_sum: f64 = bins.iter().map(|&k| expected[k]).sum();
    let var_sum: f64 =
        bins.iter().flat_map(|&k| bins.iter().map(move |&l| (k, l))).map(|(k, l)| exact_covariance(&b, k, l)).sum();
    let exact = var_sum.sqrt() / mean_sum;
    let samples = windows(&stft, &lines, 2_000, 30);
    let sums: Vec<f64> = samples.iter().map(|s| bins.iter().map(|&k| s[k]).sum()).collect();
    let (c, se) = contrast(&sums);
    let single: Vec<(f64, f64)> =
        bins.iter().map(|&k| contrast(&samples.iter().map(|s| s[k]).collect::<Vec<_>>())).collect();
    eprintln!(
        "sum of K = 4 bins: contrast {c:.4} ± {se:.4} (1/√K = 0.5, exact {exact:.4}); single bins {:?}",
        single.iter().map(|(c, s)| format!("{c:.3}±{s:.3}")).collect::<Vec<_>>()
    );
    assert!((c - 0.5).abs() <= 4.0 * se);
    assert!((c - exact).abs() <= 4.0 * se);
    for &(ci, si) in &single {
        assert!((ci - 1.0).abs() <= 4.0 * si);
    }
}

#[test]
fn speckle_draw_is_exponential_per_bin() {
    // Algorithm 1's single measurement: 20000 draws of a 64-bin expected spectrum. Per bin the mean
    // and the contrast (standard error 1/√n for Exp(1)) are within 4.5 standard errors (64 bins ×
    // 2 statistics at 4.5σ: family-wise false alarm < 1e-3), and the pooled P/E is Exp(1) (KS).
    let stft = Stft::new(FS, 64, Window::Hann).unwrap();
    let lines = two_box_lines(200, [(-8_000.0, 1_000.0), (11_000.0, 1_000.0)], &[0.0, 900.0], 5);
    let expected = stft.expected_periodogram(&lines);
    let n = 20_000;
    let mut draws = vec![vec![0.0; 64]; n];
    for (i, d) in draws.iter_mut().enumerate() {
        speckle_draw(&expected, &mut PathRng::new(SEED, Purpose::Speckle, 40, i as u64), d);
    }
    let (mut worst_mean, mut worst_contrast) = (0.0f64, 0.0f64);
    for k in 0..64 {
        let x: Vec<f64> = draws.iter().map(|d| d[k] / expected[k]).collect();
        let mean = x.iter().sum::<f64>() / n as f64;
        let z_mean = (mean - 1.0) * (n as f64).sqrt();
        let (c, _) = contrast(&x);
        let z_c = (c - 1.0) * (n as f64).sqrt();
        worst_mean = worst_mean.max(z_mean.abs());
        worst_contrast = worst_contrast.max(z_c.abs());
    }
    let mut pooled: Vec<f64> =
        draws.iter().step_by(16).flat_map(|d| d.iter().zip(&expected).map(|(p, e)| p / e)).collect();
    let (dks, p) = ks_test(&mut pooled, |v| 1.0 - (-v).exp());
    let r = mean_vector_chi2(&draws, &expected);
    report("speckle_draw mean", &r);
    eprintln!(
        "speckle_draw: max |z| of per-bin mean {worst_mean:.2}, of per-bin contrast {worst_contrast:.2}; \
         pooled KS D = {dks:.4} (n = {}), p = {p:.3}",
        pooled.len()
    );
    assert!(worst_mean <= 4.5 && worst_contrast <= 4.5);
    assert!(p > 1e-3 && r.p >= 1e-3 && r.p_max_z >= 1e-3);
    // The rows are independent and the draws bin-independent: Satterthwaite finds ≈ K dof.
    assert!((r.dof / 64.0 - 1.0).abs() < 0.1);
}
