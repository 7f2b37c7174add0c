//! Gauss–Legendre quadrature (Abramowitz & Stegun 25.4.29; Golub & Welsch 1969 for the theory).

use std::f64::consts::PI;

/// Nodes (ascending) and weights of the `n`-point Gauss–Legendre rule on `[−1, 1]`: exact for
/// polynomials of degree `2n − 1`. Nodes are the roots of `P_n`, found by Newton's method from
/// Tricomi's estimate `cos(π(i + 3/4)/(n + 1/2))`; weights `2/((1 − x²) P_n'(x)²)`.
/// `n = 0` gives empty vectors.
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut nodes = vec![0.0; n];
    let mut weights = vec![0.0; n];
    let nf = n as f64;
    for i in 0..n.div_ceil(2) {
        let mut x = (PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            // P_n(x) and P_n'(x) by the three-term recurrence.
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let kf = k as f64;
                let p2 = ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf;
                p0 = p1;
                p1 = p2;
            }
            let p = if n == 1 { x } else { p1 };
            let p_prev = if n == 1 { 1.0 } else { p0 };
            dp = nf * (x * p - p_prev) / (x * x - 1.0);
            let dx = p / dp;
            x -= dx;
            if dx.abs() <= 1e-16 * x.abs().max(1e-300) {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        // Root i counts down from +1; store ascending and mirror.
        nodes[n - 1 - i] = x;
        nodes[i] = -x;
        weights[n - 1 - i] = w;
        weights[i] = w;
    }
    if n % 2 == 1 {
        nodes[n / 2] = 0.0;
    }
    (nodes, weights)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integrates_polynomials_exactly() {
        for n in [1usize, 2, 3, 8, 33, 128, 1000] {
            let (x, w) = gauss_legendre(n);
            assert!(x.windows(2).all(|p| p[0] < p[1]), "n={n}: nodes not ascending");
            let total: f64 = w.iter().sum();
            assert!((total - 2.0).abs() < 1e-13, "n={n}: Σw = {total}");
            // ∫ x^k dx over [−1, 1] = 2/(k+1) for even k, 0 for odd k; exact up to k = 2n − 1.
            for k in 0..(2 * n).min(40) {
                let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(k as i32)).sum();
                let exact = if k % 2 == 0 { 2.0 / (k as f64 + 1.0) } else { 0.0 };
                assert!((q - exact).abs() < 1e-13, "n={n} k={k}: {q} vs {exact}");
            }
        }
        // A smooth non-polynomial: ∫ e^x = e − 1/e.
        let (x, w) = gauss_legendre(20);
        let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.exp()).sum();
        assert!((q - (1f64.exp() - (-1f64).exp())).abs() < 1e-14);
    }
}
