//! Lorenz–Mie solution for a homogeneous sphere (Bohren & Huffman 1983, ch. 4; numerics after
//! Wiscombe 1980, NCAR/TN-140+STR "Mie scattering calculations: advances in technique and fast,
//! vector-speed computer codes").
//!
//! ## Conventions
//!
//! The caller gives the relative index as `m = n − ik` with `k ≥ 0` absorbing (Wiscombe's
//! convention, validation-values §3). Internally, and in every complex number this module returns,
//! the Bohren & Huffman convention is used: time factor `e^{−iωt}`, `m = n + ik`, outgoing waves
//! `ξ_n(ρ) = ρ h_n⁽¹⁾(ρ) = ψ_n(ρ) + i η_n(ρ)` with `ψ_n = ρ j_n`, `η_n = ρ y_n`. The two
//! conventions differ by complex conjugation of the coefficients and amplitudes; efficiencies and
//! intensities are the same. For a small non-absorbing sphere with `m > 1`,
//! `S(0) ≈ −i x³ (m² − 1)/(m² + 2)` (imaginary part negative), and always `Re S(0) = x² Qext / 4`.
//!
//! ## Coefficients
//!
//! With `D_n(z) = ψ_n'(z)/ψ_n(z)` (B&H §4.8; their ψ/ψ' form of a_n, b_n divided through by `ψ_n(mx)`):
//!
//! ```text
//! a_n = [(D_n(mx)/m + n/x) ψ_n(x) − ψ_{n−1}(x)] / [(D_n(mx)/m + n/x) ξ_n(x) − ξ_{n−1}(x)]
//! b_n = [(m D_n(mx) + n/x) ψ_n(x) − ψ_{n−1}(x)] / [(m D_n(mx) + n/x) ξ_n(x) − ξ_{n−1}(x)]
//! ```
//!
//! Two rearrangements keep every digit for small `x`, where the numerators are differences of
//! numbers of size `n/x` that agree to `O(x²)`:
//!
//! * `ψ_{n−1} = (D_n(x) + n/x) ψ_n` (a Riccati–Bessel identity), so the numerators become
//!   `(D_n(mx)/m − D_n(x)) ψ_n` and `(m D_n(mx) − D_n(x)) ψ_n`, and the real (ψ) part of each
//!   denominator equals its numerator: `a_n = A/(A + iP)`. For real `m`, `A` and `P` are real, so
//!   `Re a_n = |a_n|²` and Qext = Qsca to rounding.
//! * The logarithmic derivative is carried as `G_n(z) = D_n(z) − (n+1)/z`, the part left after the
//!   small-argument pole. Its downward recurrence follows from `D_{n−1} = n/z − 1/(D_n + n/z)`:
//!
//!   ```text
//!   G_{n−1}(z) = −z / (z G_n(z) + 2n + 1),          G_n(z) ≈ −z/(2n + 3) for |z| ≪ n,
//!   ```
//!
//!   and the pole terms cancel analytically: `m D_n(mx) − D_n(x) = m G_n(mx) − G_n(x)`,
//!   `D_n(mx)/m − D_n(x) = G_n(mx)/m − G_n(x) + (n+1)(1 − m²)/(m² x)`.
//!
//! ## Recurrences and their stability
//!
//! * `G_n(mx)` (complex) and `G_n(x)` (real) by downward recurrence (Wiscombe 1980: stable for any
//!   `m`, including strong absorption and large `|m|x`, where upward recurrence fails), started with
//!   `G = 0`, i.e. `D = (n+1)/z` (the value for `n ≫ |z|`), at `n_start = max(N, |z|) + 16 +
//!   10|z|^{1/3}`: Wiscombe's `+16` alone leaves errors of 1e-6 near `N ≈ |z|` (see
//!   `start_order`). A unit test checks that starting much higher changes nothing.
//! * `η_n(x)` by upward recurrence (always stable: it is the dominant solution).
//! * `ψ_n(x)` by upward recurrence while `n < x` (oscillatory region), and for `n ≥ x` by
//!   `ψ_n = ψ_{n−1} / (G_n(x) + (2n+1)/x)`, which is stable where upward recurrence loses `ψ`
//!   (it decays there; always the case for small `x`). `ψ_n(x)` has no zeros for `n ≥ x`.
//! * Number of terms `N` from Wiscombe's criterion, at least 3 so that the `O(x²)`
//!   asymmetry of small spheres (from `a_1 a_2*`, `a_1 b_1*`) is kept.
//! * Angular functions by upward recurrence in `μ = cos θ` (B&H ch. 4):
//!   `π_n = ((2n−1) μ π_{n−1} − n π_{n−2})/(n−1)`, `τ_n = n μ π_n − (n+1) π_{n−1}`.

use std::f64::consts::PI;

pub use super::error::MieError;
pub use super::limits::{K_MAX, MX_MAX, N_MAX, N_MIN, X_MAX, X_MIN};
pub use num_complex::Complex64;

/// Order at which the downward recurrences for `G_n(z)` start: `max(N, |z|) + 16 + 10|z|^{1/3}`.
///
/// Wiscombe's `max(N, |z|) + 16` suffices for single precision only. Just above the turning point
/// `n ≈ |z|` (real z) a start error shrinks by `(ψ_n/ψ_{n−1})² ≈ exp(−2√(2j/|z|))` per order `j`
/// above `|z|`; reaching `e^{−36}` takes `j ≈ 7 |z|^{1/3}` orders. With `+16` alone the error in
/// `G_1` was 3e-6 at m = 1.33, x = 100, and Qext missed Wiscombe's 2.101321 by 1e-6 relative.
fn start_order(n_terms: usize, z_abs: f64) -> usize {
    n_terms.max(z_abs.ceil() as usize) + 16 + (10.0 * z_abs.cbrt()).ceil() as usize
}

/// Efficiencies (cross-section / geometric cross-section π r²) and the asymmetry parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Efficiencies {
    /// Extinction efficiency, `(2/x²) Σ (2n+1) Re(a_n + b_n)` (B&H ch. 4).
    pub qext: f64,
    /// Scattering efficiency, `(2/x²) Σ (2n+1)(|a_n|² + |b_n|²)` (B&H ch. 4).
    pub qsca: f64,
    /// Backscatter efficiency in the radar convention, `4|S1(π)|²/x² = |Σ (2n+1)(−1)ⁿ(a_n − b_n)|²/x²`
    /// (m = 0.75, x = 10 → 0.046584). The phase function at π is `qback / (4π qsca)`.
    pub qback: f64,
    /// Asymmetry parameter ⟨cos θ⟩ (B&H ch. 4); 0 when nothing scatters:
    /// `g Qsca x²/4 = Σ n(n+2)/(n+1) Re(a_n a*_{n+1} + b_n b*_{n+1}) + Σ (2n+1)/(n(n+1)) Re(a_n b*_n)`.
    pub g: f64,
}

/// Mie coefficients `a_n`, `b_n` (n = 1..=N, Bohren & Huffman convention) of one sphere.
#[derive(Debug, Clone, PartialEq)]
pub struct MieSolution {
    x: f64,
    /// Relative index in the B&H convention, `n + ik`.
    m: Complex64,
    /// `a[i]` is `a_{i+1}`.
    a: Vec<Complex64>,
    b: Vec<Complex64>,
}

/// Number of terms: Wiscombe's (1980) criterion, at least 3.
fn wiscombe_terms(x: f64) -> usize {
    let c = x.cbrt();
    let n = if x <= 8.0 {
        x + 4.0 * c + 1.0
    } else if x < 4200.0 {
        x + 4.05 * c + 2.0
    } else {
        x + 4.0 * c + 2.0
    };
    (n as usize).max(3)
}

/// `G_n(z) = D_n(z) − (n+1)/z` for `n = 0..=n_max` (index n) by downward recurrence from `n_start`.
fn g_complex(z: Complex64, n_max: usize, n_start: usize) -> Vec<Complex64> {
    let mut out = vec![Complex64::new(0.0, 0.0); n_max + 1];
    let mut g = Complex64::new(0.0, 0.0);
    for n in (1..=n_start).rev() {
        // g holds G_n; compute G_{n−1}.
        let mut den = z * g + (2 * n + 1) as f64;
        if den.re == 0.0 && den.im == 0.0 {
            // Exact zero (measure-zero event): step over the pole.
            den = Complex64::new(f64::MIN_POSITIVE, 0.0);
        }
        if n <= n_max {
            out[n] = g;
        }
        g = -z / den;
    }
    out[0] = g;
    out
}

/// Real version of [`g_complex`] for the real argument `x`.
fn g_real(x: f64, n_max: usize, n_start: usize) -> Vec<f64> {
    let mut out = vec![0.0; n_max + 1];
    let mut g = 0.0;
    for n in (1..=n_start).rev() {
        let mut den = x * g + (2 * n + 1) as f64;
        if den == 0.0 {
            den = f64::MIN_POSITIVE;
        }
        if n <= n_max {
            out[n] = g;
        }
        g = -x / den;
    }
    out[0] = g;
    out
}

impl MieSolution {
    /// Solve for a sphere of relative index `m = n − ik` and size parameter `x = 2π r n_medium/λ0`.
    /// `k ≥ 0` is absorbing (m = n − ik).
    ///
    /// Accepted: `x ∈ [X_MIN, X_MAX]`, `N_MIN ≤ n ≤ N_MAX`, `0 ≤ k ≤ K_MAX`, `|m|·x ≤ MX_MAX`, all finite.
    /// `m = 1` exactly gives zero coefficients (no scattering).
    pub fn new(n: f64, k: f64, x: f64) -> Result<Self, MieError> {
        if !(x.is_finite() && (X_MIN..=X_MAX).contains(&x)) {
            return Err(MieError::SizeParameter { x });
        }
        if !(n.is_finite() && (N_MIN..=N_MAX).contains(&n)) {
            return Err(MieError::RealIndex { n });
        }
        if !(k.is_finite() && (0.0..=K_MAX).contains(&k)) {
            return Err(MieError::ImagIndex { k });
        }
        let m = Complex64::new(n, k);
        let m_x = m.norm() * x;
        if m_x > MX_MAX {
            return Err(MieError::TooManyTerms { m_x });
        }
        let terms = wiscombe_terms(x);
        if n == 1.0 && k == 0.0 {
            let zero = vec![Complex64::new(0.0, 0.0); terms];
            return Ok(MieSolution { x, m, a: zero.clone(), b: zero });
        }

        let z = m * x;
        let g_mx = g_complex(z, terms, start_order(terms, m_x));
        let g_x = g_real(x, terms, start_order(terms, x));

        let (sin_x, cos_x) = x.sin_cos();
        // ψ_{n−2}, ψ_{n−1} and η_{n−2}, η_{n−1}, starting from n = 1: ψ_{−1} = cos x, ψ_0 = sin x,
        // η_{−1} = sin x, η_0 = −cos x.
        let (mut psi_2, mut psi_1) = (cos_x, sin_x);
        let (mut eta_2, mut eta_1) = (sin_x, -cos_x);
        let inv_x = 1.0 / x;
        let inv_m = m.inv();
        let inv_m2 = inv_m * inv_m;
        // (1 − m²)/m², accurate for m → 1.
        let one_minus_m2_over_m2 = (1.0 - m) * (1.0 + m) * inv_m2;

        let mut a = Vec::with_capacity(terms);
        let mut b = Vec::with_capacity(terms);
        for nn in 1..=terms {
            let nf = nn as f64;
            let two_n_plus_1 = 2.0 * nf + 1.0;
            let psi = if nf < x {
                (2.0 * nf - 1.0) * inv_x * psi_1 - psi_2
            } else {
                psi_1 / (g_x[nn] + two_n_plus_1 * inv_x)
            };
            let eta = (2.0 * nf - 1.0) * inv_x * eta_1 - eta_2;

            let gz = g_mx[nn];
            let gx = g_x[nn];
            // a_n = A / (A + iP)
            let num_a = (gz * inv_m - gx + (nf + 1.0) * inv_x * one_minus_m2_over_m2) * psi;
            let p = (gz * inv_m + (nf + 1.0) * inv_x * inv_m2 + nf * inv_x) * eta - eta_1;
            // b_n = B / (B + iQ)
            let num_b = (m * gz - gx) * psi;
            let q = (m * gz + two_n_plus_1 * inv_x) * eta - eta_1;
            let i = Complex64::i();
            a.push(num_a / (num_a + i * p));
            b.push(num_b / (num_b + i * q));

            psi_2 = psi_1;
            psi_1 = psi;
            eta_2 = eta_1;
            eta_1 = eta;
        }
        Ok(MieSolution { x, m, a, b })
    }

    pub fn size_parameter(&self) -> f64 {
        self.x
    }

    /// Number of terms N of the series.
    pub fn terms(&self) -> usize {
        self.a.len()
    }

    /// The coefficients `(a_n, b_n)` for n = 1..=N (index n − 1), Bohren & Huffman convention.
    pub fn coefficients(&self) -> (&[Complex64], &[Complex64]) {
        (&self.a, &self.b)
    }

    /// Qext, Qsca, Qback and g from the series (B&H ch. 4; Qback radar convention).
    pub fn efficiencies(&self) -> Efficiencies {
        let (mut ext, mut sca, mut asym) = (0.0, 0.0, 0.0);
        let mut back = Complex64::new(0.0, 0.0);
        let terms = self.a.len();
        for i in 0..terms {
            let nf = (i + 1) as f64;
            let c = 2.0 * nf + 1.0;
            let (an, bn) = (self.a[i], self.b[i]);
            ext += c * (an.re + bn.re);
            sca += c * (an.norm_sqr() + bn.norm_sqr());
            let sign = if (i + 1) % 2 == 0 { 1.0 } else { -1.0 };
            back += c * sign * (an - bn);
            asym += c / (nf * (nf + 1.0)) * (an * bn.conj()).re;
            if i + 1 < terms {
                let (an1, bn1) = (self.a[i + 1], self.b[i + 1]);
                asym += nf * (nf + 2.0) / (nf + 1.0) * (an * an1.conj() + bn * bn1.conj()).re;
            }
        }
        let x = self.x;
        let qsca = 2.0 * sca / (x * x);
        // Divide before squaring: |S1(π)|² would underflow for tiny x long before Qback does.
        let back_over_x = back / x;
        Efficiencies {
            qext: 2.0 * ext / (x * x),
            qsca,
            qback: back_over_x.norm_sqr(),
            // g = (4/(x² Qsca)) Σ… = 2 Σ… / Σ(2n+1)(|a|²+|b|²)
            g: if sca > 0.0 { 2.0 * asym / sca } else { 0.0 },
        }
    }

    /// S1(θ), S2(θ) (Bohren & Huffman convention) at scattering angles θ (radians, 0 = forward).
    ///
    /// `S1 = Σ (2n+1)/(n(n+1)) (a_n π_n + b_n τ_n)`, `S2 = Σ (2n+1)/(n(n+1)) (a_n τ_n + b_n π_n)`
    /// (B&H ch. 4). The scattered intensity for unpolarised light is `(|S1|² + |S2|²)/2`.
    pub fn amplitudes(&self, theta: &[f64]) -> Vec<(Complex64, Complex64)> {
        theta
            .iter()
            .map(|&t| {
                let mu = t.cos();
                let (mut pi_prev, mut pi) = (0.0, 1.0);
                let mut s1 = Complex64::new(0.0, 0.0);
                let mut s2 = Complex64::new(0.0, 0.0);
                for (i, (an, bn)) in self.a.iter().zip(&self.b).enumerate() {
                    let nf = (i + 1) as f64;
                    if i > 0 {
                        let next = ((2.0 * nf - 1.0) * mu * pi - nf * pi_prev) / (nf - 1.0);
                        pi_prev = pi;
                        pi = next;
                    }
                    let tau = nf * mu * pi - (nf + 1.0) * pi_prev;
                    let c = (2.0 * nf + 1.0) / (nf * (nf + 1.0));
                    s1 += c * (an * pi + bn * tau);
                    s2 += c * (an * tau + bn * pi);
                }
                (s1, s2)
            })
            .collect()
    }

    /// (|S1|² + |S2|²)/2 at each θ, written into `out` (same length as `theta`).
    ///
    /// The loop runs over n outside and the angles inside, on flat arrays, so that the inner loop
    /// vectorises; nothing is allocated per n. It accumulates `S± = S1 ± S2 = Σ c_n (a_n ± b_n)(π_n ± τ_n)`
    /// (`c_n = (2n+1)/(n(n+1))`), which needs half the multiplications of S1 and S2, and returns
    /// `(|S+|² + |S−|²)/4`. Near θ = 0 (S− → 0) and θ = π (S+ → 0) this loses nothing: the large
    /// sum is formed directly, the small one from `π_n − τ_n` or `π_n + τ_n`, exact at μ = ±1.
    ///
    /// # Panics
    /// If `out.len() != theta.len()` (a programming error, not an input error).
    pub fn unpolarised_intensity(&self, theta: &[f64], out: &mut [f64]) {
        assert_eq!(theta.len(), out.len(), "unpolarised_intensity: theta and out differ in length");
        let len = theta.len();
        let mu: Vec<f64> = theta.iter().map(|t| t.cos()).collect();
        // π_{n−1} and π_{n−2}. Before n = 1 these are π_0 = 0 and a stand-in 1 that, with the
        // coefficients chosen for n = 1 below, yields π_1 = 1.
        let mut p1 = vec![0.0; len];
        let mut p2 = vec![1.0; len];
        let mut spr = vec![0.0; len];
        let mut spi = vec![0.0; len];
        let mut smr = vec![0.0; len];
        let mut smi = vec![0.0; len];
        for (i, (an, bn)) in self.a.iter().zip(&self.b).enumerate() {
            let nf = (i + 1) as f64;
            let c = (2.0 * nf + 1.0) / (nf * (nf + 1.0));
            let (plus, minus) = (c * (an + bn), c * (an - bn));
            // π_n = α μ π_{n−1} − β π_{n−2}; for n = 1, α = 0, β = −1 with the stand-in π_{−1} = 1.
            let (alpha, beta) = if i == 0 { (0.0, -1.0) } else { ((2.0 * nf - 1.0) / (nf - 1.0), nf / (nf - 1.0)) };
            let np1 = nf + 1.0;
            let (mu, p1, p2) = (&mu[..len], &mut p1[..len], &mut p2[..len]);
            let (spr, spi, smr, smi) = (&mut spr[..len], &mut spi[..len], &mut smr[..len], &mut smi[..len]);
            for j in 0..len {
                let u = mu[j];
                let pm1 = p1[j];
                let p = alpha * u * pm1 - beta * p2[j];
                let t = nf * u * p - np1 * pm1;
                p2[j] = pm1;
                p1[j] = p;
                let (sum, diff) = (p + t, p - t);
                spr[j] += plus.re * sum;
                spi[j] += plus.im * sum;
                smr[j] += minus.re * diff;
                smi[j] += minus.im * diff;
            }
        }
        for j in 0..len {
            out[j] = 0.25 * (spr[j] * spr[j] + spi[j] * spi[j] + smr[j] * smr[j] + smi[j] * smi[j]);
        }
    }

    /// Phase function normalised to 1 over the sphere (sr⁻¹): `(|S1|² + |S2|²)/(2π x² Qsca)`.
    /// All zeros if Qsca = 0.
    ///
    /// # Panics
    /// If `out.len() != theta.len()`.
    pub fn phase_function(&self, theta: &[f64], out: &mut [f64]) {
        self.unpolarised_intensity(theta, out);
        let qsca = self.efficiencies().qsca;
        let norm = PI * self.x * self.x * qsca;
        if norm > 0.0 {
            out.iter_mut().for_each(|v| *v /= norm);
        } else {
            out.iter_mut().for_each(|v| *v = 0.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downward_recurrence_start_is_converged() {
        // Starting the G recurrences far higher must not change G_n for n ≤ N.
        for &(mr, mi, x) in &[
            (1.33, 1e-5, 100.0),
            (10.0, 10.0, 50.0),
            (1.5, 0.0, 1e4),
            (0.75, 0.0, 2e4),
            (1.0001, 0.0, 3.0),
            (1.33, 0.0, 7.0),
        ] {
            let z = Complex64::new(mr, mi) * x;
            let n = wiscombe_terms(x);
            let g1 = g_complex(z, n, start_order(n, z.norm()));
            let g2 = g_complex(z, n, start_order(n, z.norm()) + 5000);
            let r1 = g_real(x, n, start_order(n, x));
            let r2 = g_real(x, n, start_order(n, x) + 5000);
            for k in 1..=n {
                let d = (g1[k] - g2[k]).norm() / (g2[k] + (k as f64 + 1.0) / z).norm();
                assert!(d < 1e-13, "complex G_{k}, m={mr}+{mi}i x={x}: rel diff {d:e}");
                let dr = (r1[k] - r2[k]).abs() / (r2[k] + (k as f64 + 1.0) / x).abs().max(1e-300);
                assert!(dr < 1e-13, "real G_{k}, x={x}: rel diff {dr:e}");
            }
        }
    }

    #[test]
    fn riccati_bessel_small_argument() {
        // G_n(z) ≈ −z/(2n+3) for |z| ≪ 1 (from ψ_n ∝ z^{n+1}(1 − z²/(2(2n+3)) + …)).
        let x = 1e-4;
        let g = g_real(x, 5, 30);
        for (n, gn) in g.iter().enumerate().take(6).skip(1) {
            let expect = -x / (2.0 * n as f64 + 3.0);
            assert!((gn / expect - 1.0).abs() < 1e-7, "G_{n}({x}) = {gn:e}, expected ≈ {expect:e}");
        }
    }

    #[test]
    fn coefficients_match_high_precision_values() {
        // a_n, b_n evaluated directly from the B&H ψ/ψ' form,
        // a_n = [m ψ_n(mx) ψ_n'(x) − ψ_n(x) ψ_n'(mx)] / [m ψ_n(mx) ξ_n'(x) − ξ_n(x) ψ_n'(mx)] and likewise
        // b_n, with ψ_n = √(πz/2) J_{n+½}, η_n = √(πz/2) Y_{n+½}, ξ_n = ψ_n + iη_n, in mpmath 1.3.0 at
        // 40 significant digits, printed to 16 digits.
        // m is in the B&H convention (n + ik). The tiny-x rows test the cancellation-free numerators.
        // (n, k, x, order, a_n, b_n)
        type Row = (f64, f64, f64, usize, (f64, f64), (f64, f64));
        #[rustfmt::skip]
        let cases: [Row; 13] = [
            (1.33, 1e-5, 1e4, 1, (0.8467371339486803, -0.1634247445382292), (0.8732732750144168, -0.21378258543399356)),
            (1.33, 1e-5, 1e4, 2, (0.8732354893410799, -0.21384739846820208), (0.8467388567978329, -0.1634248707805196)),
            (10.0, 10.0, 1e4, 1, (0.10758705897487597, 0.22530693404381863), (0.8924129413597945, -0.22530693527847806)),
            (10.0, 10.0, 1e4, 2, (0.8923227865260971, -0.2254638799577414), (0.10767721247137316, 0.22546388366212106)),
            (1.33, 1e-5, 2e4, 1, (0.31350267392098446, 0.3194423153017686), (0.3110148745185396, 0.22575061414598985)),
            (1.33, 1e-5, 2e4, 3, (0.3135742008257531, 0.3194812326816808), (0.31100913209030645, 0.2257541513239342)),
            (1.5, 0.0, 1e-4, 1, (3.84467512766583e-26, -1.9607843144175317e-13), (7.71604937904174e-44, -2.777777777116402e-22)),
            (1.5, 0.0, 1e-4, 2, (1.23456789888301e-44, -1.1111111100529101e-22), (6.298815815626663e-63, -7.936507932098766e-32)),
            (0.75, 0.0, 10.0, 1, (0.4421697430471844, -0.49664440133839355), (0.32091552114661925, -0.4668283939884259)),
            (0.75, 0.0, 10.0, 5, (0.9089485977047358, -0.2876821934623869), (0.8375373408301418, -0.36887469897692454)),
            (0.75, 0.0, 10.0, 12, (0.00032243942673557504, 0.01795370322667893), (2.902829738125591e-05, 0.005387713312640814)),
            (1.33, 1e-5, 100.0, 50, (0.9801316126321202, -0.1367990844012415), (0.9241308344703817, -0.26243325500660847)),
            (1.33, 1e-5, 100.0, 110, (1.0817202293552513e-06, 0.000566834309163106), (9.240265675209586e-07, 0.0006624429304928845)),
        ];
        for &(n, k, x, order, a_ref, b_ref) in &cases {
            let s = MieSolution::new(n, k, x).unwrap();
            let (a, b) = s.coefficients();
            let (a, b) = (a[order - 1], b[order - 1]);
            // Upward recurrences over ~x orders accumulate ~x·ε.
            let tol = 1e-15 * x.max(1000.0);
            let (a_ref, b_ref) = (Complex64::new(a_ref.0, a_ref.1), Complex64::new(b_ref.0, b_ref.1));
            // Real and imaginary parts separately: tiny-x Re a_1 ~ x⁶ sits 13 decades below Im a_1.
            for (got, want, what) in [(a, a_ref, "a"), (b, b_ref, "b")] {
                for (g, w, part) in [(got.re, want.re, "re"), (got.im, want.im, "im")] {
                    let rel = (g - w).abs() / w.abs();
                    assert!(rel < tol, "m={n}+{k}i x={x} {what}_{order}.{part}: {g:e} vs {w:e} (rel {rel:e})");
                }
            }
        }
    }

    #[test]
    fn terms_follow_wiscombe() {
        assert_eq!(wiscombe_terms(1e-6), 3);
        assert_eq!(wiscombe_terms(1.0), 6);
        assert_eq!(wiscombe_terms(10.0), (10.0 + 4.05 * 10f64.cbrt() + 2.0) as usize);
        assert_eq!(wiscombe_terms(1e4), (1e4 + 4.0 * 1e4f64.cbrt() + 2.0) as usize);
    }

    #[test]
    fn rejects_bad_input_without_panicking() {
        for &(n, k, x) in &[
            (1.5, 0.0, f64::NAN),
            (1.5, 0.0, 0.0),
            (1.5, 0.0, -1.0),
            (1.5, 0.0, f64::INFINITY),
            (1.5, 0.0, 2e5),
            (0.0, 0.0, 1.0),
            (-1.0, 0.0, 1.0),
            (1e-300, 0.0, 1.0),
            (f64::NAN, 0.0, 1.0),
            (1.5, -1e-3, 1.0),
            (1.5, f64::INFINITY, 1.0),
            (100.0, 100.0, 1e5),
        ] {
            assert!(MieSolution::new(n, k, x).is_err(), "accepted n={n} k={k} x={x}");
        }
        let e = MieSolution::new(1.5, 0.0, -1.0).unwrap_err();
        assert!(e.to_string().contains("-1e0") && e.to_string().contains("1e5"), "{e}");
    }

    #[test]
    fn index_one_scatters_nothing() {
        let s = MieSolution::new(1.0, 0.0, 5.0).unwrap();
        let e = s.efficiencies();
        assert_eq!((e.qext, e.qsca, e.qback, e.g), (0.0, 0.0, 0.0, 0.0));
        let mut p = [1.0; 3];
        s.phase_function(&[0.0, 1.0, PI], &mut p);
        assert_eq!(p, [0.0; 3]);
    }

    #[test]
    fn amplitudes_match_intensity_loop_and_optical_theorem() {
        let s = MieSolution::new(1.5, 0.01, 7.3).unwrap();
        let theta: Vec<f64> = (0..=50).map(|i| PI * i as f64 / 50.0).collect();
        let amp = s.amplitudes(&theta);
        let mut inten = vec![0.0; theta.len()];
        s.unpolarised_intensity(&theta, &mut inten);
        for ((s1, s2), i) in amp.iter().zip(&inten) {
            let direct = 0.5 * (s1.norm_sqr() + s2.norm_sqr());
            assert!((direct - i).abs() <= 1e-12 * direct, "{direct} vs {i}");
        }
        let e = s.efficiencies();
        let x = s.size_parameter();
        // Optical theorem: Qext = 4 Re S(0) / x²; S1(0) = S2(0); S1(π) = −S2(π).
        assert!((4.0 * amp[0].0.re / (x * x) / e.qext - 1.0).abs() < 1e-12);
        assert!((amp[0].0 - amp[0].1).norm() < 1e-12 * amp[0].0.norm());
        let (b1, b2) = amp[50];
        assert!((b1 + b2).norm() < 1e-10 * b1.norm());
        assert!((4.0 * b1.norm_sqr() / (x * x) / e.qback - 1.0).abs() < 1e-10);
    }
}
