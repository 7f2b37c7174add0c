//! The statistics harness: chi-square and Kolmogorov–Smirnov tests, the incomplete gamma
//! function behind them, and assertions in standard errors. Tolerances are stated as tail
//! probabilities or in standard errors; seeds are fixed by the tests.

use ohd::numeric::ln_gamma;

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
/// count below 5 are merged into their neighbour). Returns (statistic, dof, p-value); panics when
/// the bins merge into one (0 degrees of freedom: nothing was tested).
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
    let dof = merged.len().saturating_sub(1);
    assert!(dof > 0, "χ² over 0 degrees of freedom: {} bins merged into {}", observed.len(), merged.len());
    (stat, dof, chi2_sf(stat, dof))
}

/// Pearson chi-square of observed counts against expected counts over the same cells, pooled as
/// pbrt-v4's and Mitsuba's χ² tests pool them: the cells expected below 5 become one, which joins
/// the smallest other cell if it is still below 5. A draw in a cell expected empty gives χ² = ∞
/// (p = 0). Returns (statistic, dof, p-value); panics below 1 degree of freedom (nothing tested).
pub fn chi_square_counts(observed: &[f64], expected: &[f64]) -> (f64, usize, f64) {
    assert_eq!(observed.len(), expected.len());
    let impossible = observed.iter().zip(expected).any(|(&o, &e)| e <= 0.0 && o > 0.0);
    let mut cells: Vec<(f64, f64)> = Vec::new();
    let (mut o_pool, mut e_pool) = (0.0, 0.0);
    for (&o, &e) in observed.iter().zip(expected) {
        if e < 5.0 {
            o_pool += o;
            e_pool += e;
        } else {
            cells.push((o, e));
        }
    }
    if o_pool > 0.0 || e_pool > 0.0 {
        let smallest = (0..cells.len()).min_by(|&a, &b| cells[a].1.total_cmp(&cells[b].1));
        match smallest {
            Some(k) if e_pool < 5.0 => {
                cells[k].0 += o_pool;
                cells[k].1 += e_pool;
            }
            _ => cells.push((o_pool, e_pool)),
        }
    }
    let dof = cells.len().saturating_sub(1);
    assert!(dof > 0, "χ² over 0 degrees of freedom: {} cells pooled into {}", observed.len(), cells.len());
    if impossible {
        return (f64::INFINITY, dof, 0.0);
    }
    let stat: f64 = cells.iter().filter(|c| c.1 > 0.0).map(|&(o, e)| (o - e) * (o - e) / e).sum();
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

/// A comparison with nothing to compare fails, and so does a slot without an error that differs.
#[test]
#[should_panic(expected = "0 degrees of freedom")]
fn a_difference_over_no_degree_of_freedom_fails() {
    chi2_difference((&[1.0, 2.0], &[0.0, 0.0]), (&[1.0, 2.0], &[0.0, 0.0]));
}

#[test]
#[should_panic(expected = "no error on either side")]
fn a_slot_without_errors_must_be_equal() {
    chi2_difference((&[1.0, 2.0], &[0.0, 0.1]), (&[1.5, 2.0], &[0.0, 0.1]));
}

/// Cells expected below 5 are pooled, the pool joins the smallest cell while below 5, and a draw
/// where none is expected fails.
#[test]
fn counts_pool_their_small_cells() {
    let (stat, dof, p) = chi_square_counts(&[10.0, 0.0, 0.0, 90.0], &[10.0, 1.0, 1.0, 88.0]);
    assert_eq!(dof, 1);
    assert!((stat - (4.0 / 12.0 + 4.0 / 88.0)).abs() < 1e-12 && p > 0.5);
    assert_eq!(chi_square_counts(&[10.0, 1.0, 89.0], &[10.0, 0.0, 90.0]).2, 0.0);
}

/// Chi-square of binned estimates against expected values, using their standard errors; a bin
/// with a zero standard error must be within 1e-3 of the total of its expected value. Returns
/// (chi², dof, p); panics when no bin has an error (0 degrees of freedom).
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
    assert!(dof > 0, "χ² over 0 degrees of freedom: no bin of {} has an error", values.len());
    (stat, dof, chi2_sf(stat, dof))
}

/// χ² of the differences of two estimates over their combined standard errors: (χ², dof, p).
/// A slot where neither has an error is no degree of freedom; there the two must be equal to
/// rounding (10⁻⁹ of the larger), else it panics naming the slot. A comparison with no degree of
/// freedom at all (every slot without an error: nothing was compared) panics too: it is a failed
/// test, not a pass with p = 1.
pub fn chi2_difference(a: (&[f64], &[f64]), b: (&[f64], &[f64])) -> (f64, usize, f64) {
    assert!(
        a.0.len() == b.0.len() && a.1.len() == a.0.len() && b.1.len() == b.0.len(),
        "χ² of differences: {} and {} slots",
        a.0.len(),
        b.0.len()
    );
    let (mut stat, mut dof) = (0.0, 0);
    for i in 0..a.0.len() {
        let var = a.1[i].powi(2) + b.1[i].powi(2);
        if var > 0.0 {
            stat += (a.0[i] - b.0[i]).powi(2) / var;
            dof += 1;
        } else {
            let (x, y) = (a.0[i], b.0[i]);
            assert!(
                (x - y).abs() <= 1e-9 * x.abs().max(y.abs()),
                "χ² of differences: slot {i} has no error on either side but {x:e} against {y:e}"
            );
        }
    }
    assert!(dof > 0, "χ² of differences over 0 degrees of freedom: no slot of {} has an error", a.0.len());
    (stat, dof, chi2_sf(stat, dof))
}
