//! Shared test harness: chi-square and Kolmogorov–Smirnov tests, and helpers to run experiments
//! from inline TOML. Tolerances are stated as tail probabilities or in standard errors; seeds are
//! fixed.
#![allow(dead_code)]

use ohd::detect::Scalar;
use ohd::experiment::{Experiment, RunOutput, Silent};

/// ln Γ(x) for x > 0 (Lanczos, g = 7, n = 9).
pub fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        return (std::f64::consts::PI / (std::f64::consts::PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised upper incomplete gamma Q(a, x) (series below a + 1, continued fraction above).
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let front = (-x + a * x.ln() - ln_gamma(a)).exp();
    if x < a + 1.0 {
        let (mut sum, mut term, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..10_000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - front * sum
    } else {
        // Lentz's continued fraction.
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        front * h
    }
}

/// Upper-tail probability of a chi-square statistic with `dof` degrees of freedom.
pub fn chi2_sf(stat: f64, dof: usize) -> f64 {
    gamma_q(0.5 * dof as f64, 0.5 * stat)
}

/// Pearson chi-square of observed counts against expected probabilities (bins with an expected
/// count below 5 are merged into their neighbour). Returns (statistic, dof, p-value).
pub fn chi_square(observed: &[f64], probabilities: &[f64]) -> (f64, usize, f64) {
    assert_eq!(observed.len(), probabilities.len());
    let n: f64 = observed.iter().sum();
    let mut merged: Vec<(f64, f64)> = Vec::new();
    let (mut o_acc, mut e_acc) = (0.0, 0.0);
    for (&o, &p) in observed.iter().zip(probabilities) {
        o_acc += o;
        e_acc += p * n;
        if e_acc >= 5.0 {
            merged.push((o_acc, e_acc));
            o_acc = 0.0;
            e_acc = 0.0;
        }
    }
    if e_acc > 0.0 || o_acc > 0.0 {
        match merged.last_mut() {
            Some(last) => {
                last.0 += o_acc;
                last.1 += e_acc;
            }
            None => merged.push((o_acc, e_acc)),
        }
    }
    let stat: f64 = merged.iter().map(|&(o, e)| (o - e) * (o - e) / e).sum();
    let dof = merged.len().saturating_sub(1).max(1);
    (stat, dof, chi2_sf(stat, dof))
}

/// Kolmogorov–Smirnov: largest CDF distance of `samples` against `cdf`, and its p-value from the
/// asymptotic Kolmogorov distribution (with Stephens' small-sample correction).
pub fn ks_test(samples: &mut [f64], cdf: impl Fn(f64) -> f64) -> (f64, f64) {
    samples.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let n = samples.len() as f64;
    let mut d: f64 = 0.0;
    for (i, &x) in samples.iter().enumerate() {
        let f = cdf(x);
        d = d.max(f - i as f64 / n).max((i + 1) as f64 / n - f);
    }
    let lambda = (n.sqrt() + 0.12 + 0.11 / n.sqrt()) * d;
    let mut p = 0.0;
    for k in 1..200 {
        let k = k as f64;
        p += 2.0 * (-1f64).powf(k - 1.0) * (-2.0 * k * k * lambda * lambda).exp();
    }
    (d, p.clamp(0.0, 1.0))
}

/// Load an experiment from inline TOML with `--set`-style overrides; panics with the message.
pub fn experiment(text: &str, sets: &[&str]) -> Experiment {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    match ohd::config::load(text, "test", &sets) {
        Ok((_, e)) => e,
        Err(e) => panic!("config: {e}"),
    }
}

/// A finished run with accessors.
pub struct Run {
    pub exp: Experiment,
    pub out: RunOutput,
}

pub fn run(text: &str, sets: &[&str]) -> Run {
    let exp = experiment(text, sets);
    let out = exp.run(&Silent);
    Run { exp, out }
}

/// One spectrum channel of one detector and chirp: (values, stderrs, below, above).
pub struct Channel {
    pub values: Vec<f64>,
    pub stderr: Vec<f64>,
    pub below: f64,
    pub above: f64,
}

impl Run {
    pub fn scalar(&self, s: Scalar) -> (f64, f64) {
        (self.out.estimates.mean()[s as usize], self.out.estimates.stderr()[s as usize])
    }

    pub fn power(&self, detector: usize) -> (f64, f64) {
        let i = self.out.layout.detectors[detector].power;
        (self.out.estimates.mean()[i], self.out.estimates.stderr()[i])
    }

    /// Channel 0 is the total; then orders 0…K (if split), then Doppler-event counts.
    pub fn channel(&self, detector: usize, chirp: usize, channel: usize) -> Channel {
        let lay = &self.out.layout.detectors[detector];
        let (start, stride) = lay.spectra.expect("detector has a spectrum");
        let bins = stride - 2;
        self.slots(start + (chirp * lay.channels + channel) * stride, bins)
    }

    /// The `bins` values at `o` of the tally vector and the two out-of-range slots after them.
    pub fn slots(&self, o: usize, bins: usize) -> Channel {
        let m = self.out.estimates.mean();
        let se = self.out.estimates.stderr();
        Channel {
            values: m[o..o + bins].to_vec(),
            stderr: se[o..o + bins].to_vec(),
            below: m[o + bins],
            above: m[o + bins + 1],
        }
    }

    /// Paths traced.
    pub fn paths(&self) -> f64 {
        self.exp.plan.samples() as f64
    }

    /// The lidar receiver (the first detector) and its tally layout.
    pub fn lidar(&self) -> (&ohd::detect::LidarSpec, &ohd::detect::LidarLayout) {
        (self.exp.detectors[0].lidar().unwrap(), self.out.layout.detectors[0].lidar.as_ref().unwrap())
    }

    /// Lag sum `D_d` of the lidar's channel `c` (0 total, 1 single, 2 multiple) in gate `g`, with
    /// the standard errors of its real and imaginary parts. `D_0` is the gate energy.
    pub fn lag(&self, c: usize, g: usize, d: usize) -> (num_complex::Complex64, (f64, f64)) {
        let (s, lay) = self.lidar();
        let o = lay.lags + ((c * s.gates + g) * s.gate_points + d) * 2;
        let (m, e) = (self.out.estimates.mean(), self.out.estimates.stderr());
        (num_complex::Complex64::new(m[o], m[o + 1]), (e[o], e[o + 1]))
    }
}

/// Henyey–Greenstein backscatter `p(π) = (1 − g²)/(4π(1 + g)³)`, sr⁻¹.
pub fn hg_backscatter(g: f64) -> f64 {
    (1.0 - g * g) / (4.0 * std::f64::consts::PI * (1.0 + g).powi(3))
}

/// Assert |measured − reference| ≤ k·σ, with a message.
pub fn assert_within_sigma(what: &str, measured: f64, sigma: f64, reference: f64, k: f64) {
    let z = (measured - reference) / sigma;
    assert!(
        sigma > 0.0 && z.abs() <= k,
        "{what}: {measured:.6} ± {sigma:.6} vs {reference:.6} (z = {z:.2}, allowed {k})"
    );
}

/// A chi-square of a mean vector against its expectation, with the per-component sample variance,
/// for correlated components.
#[derive(Debug, Clone, Copy)]
pub struct MeanChi2 {
    /// `Σ_k z_k²`, `z_k = (mean_k − expected_k)/(s_k/√n)`.
    pub stat: f64,
    /// Satterthwaite scale `a = tr(C²)/tr(C)` and effective dof `b = tr(C)²/tr(C²)` (`C` the
    /// sample correlation matrix of the components), so that `stat ≈ a·χ²_b`.
    pub scale: f64,
    pub dof: f64,
    pub p: f64,
    pub max_abs_z: f64,
    /// Family-wise (Bonferroni) p-value of the largest `|z|`: `components · P(|Z| > max |z|)`,
    /// valid under any correlation.
    pub p_max_z: f64,
    pub components: usize,
}

/// `samples[i]` is the i-th independent draw of a vector whose expectation is `expected`. Each
/// component's mean is standardised by its own sample standard error; the sum of squares is
/// referred to `a·χ²_b` with the Satterthwaite moments of the estimated correlation matrix (each
/// off-diagonal `r²` reduced by its sampling bias `(1 − r²)²/(n − 1)`), which is exact in mean and
/// variance for Gaussian means whatever the correlation (`a = 1`, `b = K` for independent ones).
/// Components with zero sample variance are skipped.
pub fn mean_vector_chi2(samples: &[Vec<f64>], expected: &[f64]) -> MeanChi2 {
    let n = samples.len();
    let len = expected.len();
    assert!(n > 2 && samples.iter().all(|s| s.len() == len));
    let nf = n as f64;
    let mean: Vec<f64> = (0..len).map(|k| samples.iter().map(|s| s[k]).sum::<f64>() / nf).collect();
    let var: Vec<f64> =
        (0..len).map(|k| samples.iter().map(|s| (s[k] - mean[k]).powi(2)).sum::<f64>() / (nf - 1.0)).collect();
    let used: Vec<usize> = (0..len).filter(|&k| var[k] > 0.0).collect();
    let z: Vec<f64> = used.iter().map(|&k| (mean[k] - expected[k]) / (var[k] / nf).sqrt()).collect();
    let stat: f64 = z.iter().map(|z| z * z).sum();
    let max_abs_z = z.iter().fold(0.0f64, |m, z| m.max(z.abs()));
    // Standardised samples, then the correlation matrix's tr(C²).
    let std: Vec<Vec<f64>> =
        samples.iter().map(|s| used.iter().map(|&k| (s[k] - mean[k]) / var[k].sqrt()).collect()).collect();
    let dim = used.len();
    let mut tr_c2 = dim as f64;
    for a in 0..dim {
        for b in a + 1..dim {
            let r = std.iter().map(|v| v[a] * v[b]).sum::<f64>() / (nf - 1.0);
            let r2 = (r * r - (1.0 - r * r).powi(2) / (nf - 1.0)).max(0.0);
            tr_c2 += 2.0 * r2;
        }
    }
    let tr_c = dim as f64;
    let scale = tr_c2 / tr_c;
    let dof = tr_c * tr_c / tr_c2;
    let p = gamma_q(0.5 * dof, 0.5 * stat / scale);
    let p_max_z = (dim as f64 * gamma_q(0.5, 0.5 * max_abs_z * max_abs_z)).min(1.0);
    MeanChi2 { stat, scale, dof, p, max_abs_z, p_max_z, components: dim }
}

/// Sample mean, standard deviation and contrast `σ/μ` of `x`, with the contrast's standard error
/// by the delta method from the sample central moments:
/// `Var(C) ≈ [(m4 − m2²)/(4 m2 μ²) − m3/μ³ + m2²/μ⁴]/n`.
pub fn contrast(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let mu = x.iter().sum::<f64>() / n;
    let m = |p: i32| x.iter().map(|v| (v - mu).powi(p)).sum::<f64>() / n;
    let (m2, m3, m4) = (m(2), m(3), m(4));
    let c = m2.sqrt() / mu;
    let var = ((m4 - m2 * m2) / (4.0 * m2 * mu * mu) - m3 / mu.powi(3) + m2 * m2 / mu.powi(4)) / n;
    (c, var.max(0.0).sqrt())
}

#[test]
fn harness_self_check() {
    // Q(1, x) = e^{-x}; chi-square with 2 dof: sf(x) = e^{-x/2}.
    assert!((gamma_q(1.0, 2.0) - (-2.0f64).exp()).abs() < 1e-12);
    assert!((chi2_sf(3.0, 2) - (-1.5f64).exp()).abs() < 1e-12);
    // Median of chi-square(10) ≈ 9.3418.
    assert!((chi2_sf(9.341_818, 10) - 0.5).abs() < 1e-5);
    assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-12);
    // Contrast of an exact two-point sample {1, 3}: μ = 2, σ = 1.
    assert!((contrast(&[1.0, 3.0, 1.0, 3.0]).0 - 0.5).abs() < 1e-15);
}

/// One channel of an LDH ROI spectrum (0 = total, then static, single Doppler, multiple Doppler).
pub fn roi_channel(r: &Run, detector: usize, roi: usize, channel: usize) -> Channel {
    let ll = r.out.layout.detectors[detector].ldh.as_ref().expect("an LDH camera");
    r.slots(ll.rois[roi].spectrum + channel * ll.stride, ll.stride - 2)
}

/// An LDH ROI's M0+ and M0− with their standard errors: ((m0+, σ), (m0−, σ)).
pub fn roi_m0(r: &Run, detector: usize, roi: usize) -> ((f64, f64), (f64, f64)) {
    let ll = r.out.layout.detectors[detector].ldh.as_ref().expect("an LDH camera");
    let (m, se) = (r.out.estimates.mean(), r.out.estimates.stderr());
    let rl = &ll.rois[roi];
    ((m[rl.m0_plus], se[rl.m0_plus]), (m[rl.m0_minus], se[rl.m0_minus]))
}

/// Chi-square of binned estimates against expected values, using their standard errors; a bin
/// with a zero standard error must be within 1e-3 of the total of its expected value. Returns
/// (chi², dof, p).
pub fn chi_square_estimates(values: &[f64], stderr: &[f64], expected: &[f64]) -> (f64, usize, f64) {
    let mut stat = 0.0;
    let mut dof = 0;
    for ((&v, &s), &e) in values.iter().zip(stderr).zip(expected) {
        if s > 0.0 {
            stat += ((v - e) / s).powi(2);
            dof += 1;
        } else {
            let scale: f64 = expected.iter().map(|x| x.abs()).sum();
            // No contribution at all (or a constant one): only a bin expected to be nearly empty.
            assert!((v - e).abs() <= 1e-3 * scale, "bin with zero error: {v} vs {e}");
        }
    }
    (stat, dof, chi2_sf(stat, dof.max(1)))
}

/// The lag-`d` pulse product a lidar gate `g` collects from a return delayed by `t_d`:
/// `Σ_m a(t_{m+d} − t_d)·a(t_m − t_d)·Δt` over the gate's sample pairs, `a` the unit-energy
/// Gaussian pulse amplitude (intensity FWHM τ_p). Lag 0 is the pulse energy in the gate.
pub fn gate_lag_weight(s: &ohd::detect::LidarSpec, g: usize, t_d: f64, d: usize) -> f64 {
    let sigma = s.pulse_sigma();
    let a = |m: usize| {
        let t = s.first_sample_time + (g * s.gate_points + m) as f64 * s.dt();
        (-(t - t_d).powi(2) / (2.0 * sigma * sigma)).exp() / (sigma * std::f64::consts::PI.sqrt()).sqrt()
    };
    (0..s.gate_points.saturating_sub(d)).map(|m| a(m + d) * a(m) * s.dt()).sum()
}

/// Simpson's rule for `f` over `[a, b]` with an even number `n` of intervals.
pub fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let h = (b - a) / n as f64;
    let mut sum = f(a) + f(b);
    for i in 1..n {
        sum += f(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    sum * h / 3.0
}

/// z-scores of a lidar run's single-scattering lag sums D_0 (real) and D_1 (real and imaginary) of
/// every gate against `expected(g, d)`; asserts each |z| < 4.5 and the χ² over all of them
/// p > 1e-3.
pub fn check_single_scattering_lags(r: &Run, expected: impl Fn(usize, usize) -> num_complex::Complex64) {
    let (spec, _) = r.lidar();
    let (mut stat, mut dof) = (0.0, 0);
    for g in 0..spec.gates {
        for d in 0..2 {
            let want = expected(g, d);
            let (v, (se_re, se_im)) = r.lag(1, g, d);
            let mut parts = vec![("re", v.re, se_re, want.re)];
            if d == 1 {
                parts.push(("im", v.im, se_im, want.im));
            }
            for (what, v, se, want) in parts {
                let z = (v - want) / se;
                eprintln!("gate {g} D_{d} {what}: {v:.5e} ± {se:.1e} vs {want:.5e}, z = {z:+.2}");
                assert!(z.abs() < 4.5, "gate {g}, D_{d} {what}: z = {z}");
                stat += z * z;
                dof += 1;
            }
        }
    }
    let p = chi2_sf(stat, dof);
    eprintln!("χ² = {stat:.1} for {dof}, p = {p:.3}");
    assert!(p > 1e-3, "χ² = {stat:.1} for {dof} values, p = {p:.2e}");
}

/// A thin tube at 45° in a transparent layer, lit uniformly and seen in near-backscatter (HG
/// g = −0.99 scatterers, 3° acceptance; the flat-spectrum scene of validation-values §4.4), its
/// velocity given by `velocity` (a TOML inline table), 3·10⁶ paths in 16 batches.
pub fn tube_scene(velocity: &str) -> String {
    format!(
        r#"
schema_version = 1
[run]
samples = 3000000
batches = 16
[source]
wavelength_nm = 1000
profile = "disk"
radius_mm = 0.35
position_mm = [0, 0, -0.1]
[media.clear]
sigma_a_per_mm = 0
sigma_s_per_mm = 0
[media.blood]
sigma_a_per_mm = 0
sigma_s_per_mm = 0.2
phase = {{ type = "hg", g = -0.99 }}
[[layers]]
name = "clear"
thickness_mm = 0.4
n = 1.0
medium = "clear"
[[regions]]
layer = "clear"
medium = "blood"
shape = {{ type = "cylinder", center_mm = [0, 0, 0.2], axis = [1, 0, 1], radius_mm = 0.05 }}
velocity = {velocity}
[[detectors]]
name = "top"
acceptance_half_angle_deg = 3
[detectors.spectrum]
f_min_hz = 0
f_max_hz = 1555.634918610405   # 1.1 f_max
bins = 22
by_order = 2
"#
    )
}
