//! The special functions behind the F-test of [`super::fit::fit_one_or_two`]: the regularised
//! incomplete beta function and the upper tail of Fisher's F distribution (`ln Γ` is
//! [`crate::numeric::ln_gamma`]).

use crate::numeric::ln_gamma;

/// The regularised incomplete beta function `I_x(a, b)`, `a, b > 0`, `0 ≤ x ≤ 1`, from its
/// continued fraction (Abramowitz & Stegun 26.5.8)
/// `I_x(a,b) = x^a (1−x)^b / (a·B(a,b)) · 1/(1 + d₁/(1 + d₂/(1 + …)))` with
/// `d_{2k+1} = −(a+k)(a+b+k)x/((a+2k)(a+2k+1))`, `d_{2k} = k(b−k)x/((a+2k−1)(a+2k))`,
/// evaluated by the modified Lentz method; it converges fast for `x < (a+1)/(a+b+2)`, and the
/// symmetry `I_x(a,b) = 1 − I_{1−x}(b,a)` covers the rest.
pub(crate) fn beta_inc(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = a * x.ln() + b * (1.0 - x).ln() - (ln_gamma(a) + ln_gamma(b) - ln_gamma(a + b));
    if x < (a + 1.0) / (a + b + 2.0) {
        ln_front.exp() / a * beta_fraction(a, b, x)
    } else {
        1.0 - ln_front.exp() / b * beta_fraction(b, a, 1.0 - x)
    }
}

/// `1/(1 + d₁/(1 + d₂/(1 + …)))` of [`beta_inc`] by the modified Lentz method.
fn beta_fraction(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let (mut c, mut d, mut f) = (1.0, 0.0, 1.0);
    for m in 1..1000 {
        let k = (m / 2) as f64;
        let dm = if m % 2 == 1 {
            -(a + k) * (a + b + k) * x / ((a + 2.0 * k) * (a + 2.0 * k + 1.0))
        } else {
            k * (b - k) * x / ((a + 2.0 * k - 1.0) * (a + 2.0 * k))
        };
        d = 1.0 + dm * d;
        if d.abs() < TINY {
            d = TINY;
        }
        c = 1.0 + dm / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let delta = c * d;
        f *= delta;
        if (delta - 1.0).abs() < 1e-15 {
            break;
        }
    }
    1.0 / f
}

/// `P(F > f)` for Fisher's F distribution with `(d1, d2)` degrees of freedom:
/// `I_{d2/(d2 + d1·f)}(d2/2, d1/2)`.
pub(crate) fn f_distribution_sf(f: f64, d1: f64, d2: f64) -> f64 {
    if f <= 0.0 {
        return 1.0;
    }
    if f == f64::INFINITY {
        return 0.0;
    }
    beta_inc(0.5 * d2, 0.5 * d1, d2 / (d2 + d1 * f))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn incomplete_beta_closed_forms() {
        for &x in &[1e-6, 0.01, 0.2, 0.5, 0.77, 0.999] {
            assert!((beta_inc(1.0, 1.0, x) - x).abs() < 1e-14);
            assert!((beta_inc(3.5, 1.0, x) - x.powf(3.5)).abs() < 1e-14);
            assert!((beta_inc(1.0, 2.5, x) - (1.0 - (1.0 - x).powf(2.5))).abs() < 1e-14, "x={x}");
            // I_x(½, ½) = (2/π)·asin √x: the arcsine distribution.
            assert!((beta_inc(0.5, 0.5, x) - 2.0 / PI * x.sqrt().asin()).abs() < 1e-13, "x={x}");
            let (a, b) = (7.5, 1.5);
            assert!((beta_inc(a, b, x) + beta_inc(b, a, 1.0 - x) - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn f_tail_matches_tables() {
        // d1 = 2: P(F > f) = (1 + 2f/d2)^(−d2/2) exactly.
        for &(f, d2) in &[(0.5f64, 7.0f64), (3.0, 40.0), (10.0, 250.0)] {
            let exact = (1.0 + 2.0 * f / d2).powf(-0.5 * d2);
            assert!((f_distribution_sf(f, 2.0, d2) / exact - 1.0).abs() < 1e-13);
        }
        // Upper percentage points (Abramowitz & Stegun Table 26.9): F(3, 10) at 5 % = 3.71,
        // F(3, 120) at 1 % = 3.95, F(3, 60) at 1 % = 4.13.
        assert!((f_distribution_sf(3.7083, 3.0, 10.0) - 0.05).abs() < 1e-4);
        assert!((f_distribution_sf(3.9491, 3.0, 120.0) - 0.01).abs() < 1e-4);
        assert!((f_distribution_sf(4.1259, 3.0, 60.0) - 0.01).abs() < 1e-4);
        assert_eq!(f_distribution_sf(0.0, 3.0, 10.0), 1.0);
        assert_eq!(f_distribution_sf(f64::INFINITY, 3.0, 10.0), 0.0);
    }
}
