//! Small numerical tools shared by the library and its tests: `ln Γ` (for the F-test of
//! [`crate::retrieval::fit`] and the tests' chi-square tails) and composite Simpson quadrature.

use std::f64::consts::PI;

/// `ln Γ(x)` for `x > 0`: Stirling's series to the `y⁻⁹` term at `y = x + k ≥ 15`, brought back by
/// the recurrence `Γ(x + 1) = x·Γ(x)`. The first omitted term is `691/(360360·y¹¹) < 3·10⁻¹⁶`.
pub fn ln_gamma(x: f64) -> f64 {
    let (mut y, mut shift) = (x, 0.0);
    while y < 15.0 {
        shift += y.ln();
        y += 1.0;
    }
    let r = 1.0 / y;
    let r2 = r * r;
    // Bernoulli terms B_2k / (2k(2k − 1) y^(2k−1)).
    let series = r * (1.0 / 12.0 - r2 * (1.0 / 360.0 - r2 * (1.0 / 1260.0 - r2 * (1.0 / 1680.0 - r2 / 1188.0))));
    (y - 0.5) * y.ln() - y + 0.5 * (2.0 * PI).ln() + series - shift
}

/// `∫_a^b f` by composite Simpson's rule with `n` (even) intervals.
pub fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let h = (b - a) / n as f64;
    let mut sum = f(a) + f(b);
    for i in 1..n {
        sum += f(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    sum * h / 3.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ln_gamma_at_known_points() {
        let mut fact = 1.0f64;
        for n in 1..30 {
            // Γ(n) = (n − 1)!
            let got = ln_gamma(n as f64);
            assert!((got - fact.ln()).abs() < 1e-13 * fact.ln().max(1.0), "n={n}: {got} vs {}", fact.ln());
            fact *= n as f64;
        }
        assert!((ln_gamma(0.5) - PI.sqrt().ln()).abs() < 1e-14);
        assert!((ln_gamma(1.5) - (0.5 * PI.sqrt()).ln()).abs() < 1e-14);
    }

    #[test]
    fn simpson_is_exact_for_cubics() {
        let cubic = |x: f64| 2.0 * x * x * x - x * x + 3.0;
        // ∫_{−1}^{2} = [x⁴/2 − x³/3 + 3x] = (8 − 8/3 + 6) − (1/2 + 1/3 − 3).
        let exact = (8.0 - 8.0 / 3.0 + 6.0) - (0.5 + 1.0 / 3.0 - 3.0);
        assert!((simpson(cubic, -1.0, 2.0, 2) - exact).abs() < 1e-13);
        assert!((simpson(f64::sin, 0.0, PI, 100) - 2.0).abs() < 2e-8);
    }
}
