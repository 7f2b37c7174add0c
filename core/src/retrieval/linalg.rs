//! Dense linear algebra for the small symmetric systems of the retrievals (n ≤ 7): Cholesky
//! factorisation, solve and inverse, and the eigenvalues of a symmetric matrix (cyclic Jacobi) for
//! condition numbers. Matrices are row-major `n × n` slices.

/// The lower Cholesky factor `L` (`A = L·Lᵀ`) of a symmetric matrix, or `None` unless `A` is
/// numerically positive definite (a pivot ≤ 0 or non-finite).
pub(crate) fn cholesky(a: &[f64], n: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let dot: f64 = (0..j).map(|k| l[i * n + k] * l[j * n + k]).sum();
            let v = a[i * n + j] - dot;
            if i == j {
                if !(v > 0.0 && v.is_finite()) {
                    return None;
                }
                l[i * n + i] = v.sqrt();
            } else {
                l[i * n + j] = v / l[j * n + j];
            }
        }
    }
    Some(l)
}

/// Solve `L·Lᵀ·x = b` by forward and back substitution.
pub(crate) fn cholesky_solve(l: &[f64], n: usize, b: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; n];
    for i in 0..n {
        let dot: f64 = (0..i).map(|k| l[i * n + k] * y[k]).sum();
        y[i] = (b[i] - dot) / l[i * n + i];
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let dot: f64 = (i + 1..n).map(|k| l[k * n + i] * x[k]).sum();
        x[i] = (y[i] - dot) / l[i * n + i];
    }
    x
}

/// The inverse of a symmetric positive-definite matrix (column by column from its Cholesky
/// factor), or `None` when it is not positive definite.
pub(crate) fn spd_inverse(a: &[f64], n: usize) -> Option<Vec<f64>> {
    let l = cholesky(a, n)?;
    let mut inv = vec![0.0; n * n];
    let mut e = vec![0.0; n];
    for j in 0..n {
        e.iter_mut().enumerate().for_each(|(i, v)| *v = if i == j { 1.0 } else { 0.0 });
        for (i, v) in cholesky_solve(&l, n, &e).into_iter().enumerate() {
            inv[i * n + j] = v;
        }
    }
    // Symmetrise the round-off.
    for i in 0..n {
        for j in 0..i {
            let m = 0.5 * (inv[i * n + j] + inv[j * n + i]);
            inv[i * n + j] = m;
            inv[j * n + i] = m;
        }
    }
    Some(inv)
}

/// The eigenvalues of a symmetric matrix in ascending order, by cyclic Jacobi rotations (Golub &
/// Van Loan, *Matrix Computations*, §8.5): each rotation in the `(p, q)` plane with
/// `t = tan φ` the smaller root of `t² + 2θt − 1 = 0`, `θ = (a_qq − a_pp)/(2a_pq)`, zeroes `a_pq`;
/// sweeps repeat until the off-diagonal part is below round-off of the whole matrix.
pub(crate) fn symmetric_eigenvalues(a: &[f64], n: usize) -> Vec<f64> {
    let mut m = a.to_vec();
    let total: f64 = m.iter().map(|v| v * v).sum();
    for _sweep in 0..64 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| m[i * n + j].powi(2))
            .sum();
        if off <= 1e-32 * total || off == 0.0 {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = m[p * n + q];
                if apq == 0.0 {
                    continue;
                }
                let theta = (m[q * n + q] - m[p * n + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for r in 0..n {
                    if r != p && r != q {
                        let (arp, arq) = (m[r * n + p], m[r * n + q]);
                        let (nrp, nrq) = (c * arp - s * arq, s * arp + c * arq);
                        m[r * n + p] = nrp;
                        m[p * n + r] = nrp;
                        m[r * n + q] = nrq;
                        m[q * n + r] = nrq;
                    }
                }
                m[p * n + p] -= t * apq;
                m[q * n + q] += t * apq;
                m[p * n + q] = 0.0;
                m[q * n + p] = 0.0;
            }
        }
    }
    let mut ev: Vec<f64> = (0..n).map(|i| m[i * n + i]).collect();
    ev.sort_by(f64::total_cmp);
    ev
}

/// The 2-norm condition number `λ_max/λ_min` of a symmetric positive semi-definite matrix; `∞`
/// when the smallest eigenvalue is not positive (singular to round-off).
pub(crate) fn condition_number(a: &[f64], n: usize) -> f64 {
    let ev = symmetric_eigenvalues(a, n);
    let (lo, hi) = (ev[0], ev[n - 1]);
    if lo > 0.0 { hi / lo } else { f64::INFINITY }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `Q·diag(λ)·Qᵀ` with `Q` a product of plane rotations: a symmetric matrix of known spectrum.
    fn with_spectrum(lambda: &[f64]) -> Vec<f64> {
        let n = lambda.len();
        let mut q: Vec<f64> = (0..n * n).map(|k| if k / n == k % n { 1.0 } else { 0.0 }).collect();
        for p in 0..n {
            for r in p + 1..n {
                let phi = 0.3 + 0.7 * (p * n + r) as f64;
                let (c, s) = (phi.cos(), phi.sin());
                for i in 0..n {
                    let (a, b) = (q[i * n + p], q[i * n + r]);
                    q[i * n + p] = c * a - s * b;
                    q[i * n + r] = s * a + c * b;
                }
            }
        }
        let mut a = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                a[i * n + j] = (0..n).map(|k| q[i * n + k] * lambda[k] * q[j * n + k]).sum();
            }
        }
        a
    }

    #[test]
    fn jacobi_recovers_a_known_spectrum() {
        let lambda = [0.001, 0.5, 2.0, 3.0, 7.5, 40.0, 1000.0];
        let ev = symmetric_eigenvalues(&with_spectrum(&lambda), 7);
        for (e, l) in ev.iter().zip(lambda) {
            assert!((e - l).abs() < 1e-11 * 1000.0, "{e} vs {l}");
        }
        let cond = condition_number(&with_spectrum(&[1.0, 2.0, 4.0]), 3);
        assert!((cond - 4.0).abs() < 1e-12, "{cond}");
        // Rank 2: singular to round-off.
        assert!(condition_number(&with_spectrum(&[0.0, 1.0, 2.0]), 3) > 1e14);
    }

    #[test]
    fn cholesky_inverse_is_an_inverse() {
        let lambda = [0.2, 1.0, 3.0, 9.0, 27.0];
        let a = with_spectrum(&lambda);
        let inv = spd_inverse(&a, 5).unwrap();
        for i in 0..5 {
            for j in 0..5 {
                let p: f64 = (0..5).map(|k| a[i * 5 + k] * inv[k * 5 + j]).sum();
                assert!((p - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12, "({i},{j}) = {p}");
            }
        }
        let l = cholesky(&a, 5).unwrap();
        let b = [1.0, -2.0, 0.5, 3.0, 0.0];
        let x = cholesky_solve(&l, 5, &b);
        for i in 0..5 {
            let r: f64 = (0..5).map(|k| a[i * 5 + k] * x[k]).sum::<f64>() - b[i];
            assert!(r.abs() < 1e-12);
        }
        assert!(cholesky(&with_spectrum(&[-1.0, 1.0, 2.0]), 3).is_none());
    }
}
