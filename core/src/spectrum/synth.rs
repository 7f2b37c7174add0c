//! Single-window speckled spectra: Algorithm 2 by a non-uniform FFT, and Algorithm 1's draw.
//!
//! **Algorithm 2** (Kim et al. 2025 §5.3, Eqs. 39–42): every detected path is a line of amplitude
//! `a_j = √p_j` and an independent uniform phase `ψ_j`; the camera samples the field
//! `x[n] = Σ_j a_j e^{i(2π f_j n/f_s + ψ_j)}`, `n = 0..N−1`, and the periodogram of the windowed
//! samples is one speckled measurement. The cross terms vanish in expectation, so
//! `E P_k = Σ_j p_j K(ν_k − f_j, γ_j)` ([`Stft::expected_periodogram`], Eq. 28). A line with
//! Lorentzian HWHM `γ_j > 0` (Brownian motion) gets a Cauchy-distributed frequency `f_j + γ_j C`
//! per window (`C` standard Cauchy, the law of `tan(π(U − ½))`): its per-sample phase step is then
//! wrapped-Cauchy, whose characteristic function `ρ^{|d|}` is exactly the Lorentzian kernel's
//! (phase-diffusion identity).
//!
//! The direct sum costs O(lines × N) (the paper's 75 s against Algorithm 1's 6 s, Kim et al.
//! §7.1.1). Here `x[n]` is a type-1 non-uniform FFT (Dutt & Rokhlin 1993; Barnett, Magland & af
//! Klinteberg 2019): each line's complex amplitude is spread onto a periodic grid of `M = 2N`
//! phase points with the "exponential of semicircle" kernel `φ(z) = e^{β(√(1−z²) − 1)}` of width
//! `W = 8` points, `β = 2.30 W`; one inverse FFT of size `M` gives the grid's Fourier series, and
//! dividing by the kernel's Fourier transform recovers the `N` samples. Cost O(lines·W + M log M);
//! error below 4e-7 of `max |x|` (tested: worst single line over a grid cell 3.9e-7, random sums
//! 1e-7 to 3e-7). The periodic grid aliases frequencies modulo `f_s` for free, as the camera does.
//! The kernel is evaluated per line as a polynomial in the line's fractional grid offset
//! (Chebyshev interpolation at set-up, Horner over all `W` points at once) instead of `W`
//! exponentials, and the random phase and the Cauchy variate come from disc points instead of
//! `sin_cos` and `tan` (together: 14.4 → 7.8 ms per window of 1e5 lines at N = 64).
//!
//! **Algorithm 1, single measurement** (Kim et al. §5.2): each bin's expected power times an
//! independent `Exp(1)` draw ([`speckle_draw`]) — fully developed speckle, contrast 1, bins
//! uncorrelated.

use std::f64::consts::PI;
use std::sync::Arc;

use num_complex::Complex;
use ohd_fft::{Fft, Planner};

use super::stft::{Line, Stft, cycles};
use crate::sampling::rng::PathRng;

/// Spreading width in grid points.
const WIDTH: usize = 8;
const HALF: usize = WIDTH / 2;
/// ES kernel shape, Barnett et al. 2019's choice for oversampling 2.
const BETA: f64 = 2.30 * WIDTH as f64;
/// Degree of the polynomial of each kernel point in the fractional offset (max error 2e-9 of the
/// kernel's peak; the ES kernel's `√` cusp of height `β e^{−β}` at `|z| = 1` limits it).
const DEGREE: usize = 12;

/// The ES kernel on `[−1, 1]`.
fn es_kernel(z: f64) -> f64 {
    if z.abs() >= 1.0 { 0.0 } else { (BETA * ((1.0 - z * z).sqrt() - 1.0)).exp() }
}

/// Gauss–Legendre nodes and weights on `[−1, 1]` (Newton iteration on `P_q`).
fn gauss_legendre(q: usize) -> Vec<(f64, f64)> {
    (0..q)
        .map(|i| {
            let mut x = (PI * (i as f64 + 0.75) / (q as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=q {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                dp = q as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// Synthesises single-window speckled periodograms: the field of the detected lines with random
/// phases, sampled at `f_s` over `N` samples, windowed, transformed with rustfft,
/// `|·|² / (N Σw²)`. Plans and buffers are built once; a `Synthesizer` is reused across windows.
pub struct Synthesizer {
    stft: Stft,
    /// Oversampled grid size `M`.
    grid: usize,
    /// Monomial coefficients (`x^j`, `j = 0..=DEGREE`) of kernel point `i` as a function of
    /// `x = 2s − 1`, `s` the fractional offset: `[j][i]` (from Chebyshev interpolation).
    polynomial: Vec<[f64; WIDTH]>,
    /// Per time sample: `h / Ĝ(n − N/2)` (deconvolution), and that times `w[n]/√(N Σw²)`.
    deconvolution: Vec<f64>,
    post: Vec<f64>,
    inverse: Arc<dyn Fft<f64>>,
    forward: Arc<dyn Fft<f64>>,
    /// The spreading grid with `W/2` guard points each side (`M + W`).
    padded: Vec<Complex<f64>>,
    time: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
}

impl Synthesizer {
    pub fn new(stft: &Stft) -> Self {
        let n = stft.samples();
        let grid = (2 * n).max(2 * WIDTH);
        // Chebyshev interpolation of g_i(s) = φ(2(s + i)/W − 1), s ∈ [0, 1], at DEGREE + 1 nodes,
        // then converted to monomials in x = 2s − 1 for Horner's rule (|x| ≤ 1, the coefficients
        // stay below ~10², so conversion costs ~1e-14).
        let nodes = DEGREE + 1;
        let mut chebyshev = vec![[0.0; WIDTH]; nodes];
        for i in 0..WIDTH {
            let values: Vec<f64> = (0..nodes)
                .map(|k| {
                    let x = (PI * (k as f64 + 0.5) / nodes as f64).cos();
                    let s = 0.5 * (x + 1.0);
                    es_kernel(2.0 * (s + i as f64) / WIDTH as f64 - 1.0)
                })
                .collect();
            for (j, row) in chebyshev.iter_mut().enumerate() {
                let c: f64 = values
                    .iter()
                    .enumerate()
                    .map(|(k, v)| v * (PI * j as f64 * (k as f64 + 0.5) / nodes as f64).cos())
                    .sum();
                row[i] = if j == 0 { 1.0 } else { 2.0 } * c / nodes as f64;
            }
        }
        // T_j as monomial coefficient rows (T_{j+1} = 2x T_j − T_{j−1}).
        let mut t_prev = vec![0.0; nodes];
        let mut t_cur = vec![0.0; nodes];
        t_prev[0] = 1.0; // T_0
        t_cur[1] = 1.0; // T_1
        let mut polynomial = vec![[0.0; WIDTH]; nodes];
        for (j, cheb) in chebyshev.iter().enumerate() {
            let t = match j {
                0 => t_prev.clone(),
                1 => t_cur.clone(),
                _ => {
                    let next: Vec<f64> =
                        (0..nodes).map(|p| if p > 0 { 2.0 * t_cur[p - 1] } else { 0.0 } - t_prev[p]).collect();
                    t_prev = std::mem::replace(&mut t_cur, next);
                    t_cur.clone()
                }
            };
            for (p, &tp) in t.iter().enumerate() {
                for i in 0..WIDTH {
                    polynomial[p][i] += cheb[i] * tp;
                }
            }
        }
        // Ĝ(m) = α ∫_{−1}^{1} φ(z) cos(mαz) dz, α = πW/M (the kernel's half width in radians);
        // h/Ĝ(m) = 2/(W I(m)). With z = sin θ the integrand is analytic: Gauss–Legendre in θ.
        let alpha = PI * WIDTH as f64 / grid as f64;
        let quadrature = gauss_legendre(48);
        let deconvolution: Vec<f64> = (0..n)
            .map(|idx| {
                let m = idx as f64 - (n / 2) as f64;
                let integral: f64 = quadrature
                    .iter()
                    .map(|&(t, w)| {
                        let (s, c) = (0.5 * PI * t).sin_cos();
                        w * 0.5 * PI * (BETA * (c - 1.0)).exp() * (m * alpha * s).cos() * c
                    })
                    .sum();
                2.0 / (WIDTH as f64 * integral)
            })
            .collect();
        let scale = 1.0 / stft.norm().sqrt();
        let post = deconvolution.iter().zip(stft.coefficients()).map(|(d, w)| d * w * scale).collect();
        let mut planner = Planner::new();
        let inverse = planner.inverse(grid);
        let forward = planner.forward(n);
        let scratch_len = inverse.get_inplace_scratch_len().max(forward.get_inplace_scratch_len());
        let zero = Complex::new(0.0, 0.0);
        Synthesizer {
            stft: stft.clone(),
            grid,
            polynomial,
            deconvolution,
            post,
            inverse,
            forward,
            padded: vec![zero; grid + WIDTH],
            time: vec![zero; n],
            scratch: vec![zero; scratch_len],
        }
    }

    /// The STFT set-up.
    pub fn stft(&self) -> &Stft {
        &self.stft
    }

    /// Oversampled grid size `M`.
    pub fn grid(&self) -> usize {
        self.grid
    }

    /// One window: lines get independent uniform phases `ψ_j` and (if `γ_j > 0`) a Cauchy
    /// frequency `f_j + γ_j·C`, `C` standard Cauchy, drawn from `rng` (in that order per line).
    /// Amplitude `a_j = √p_j`. Output `out` (`N` values, fftshift order as
    /// [`Stft::bin_frequency`]): `P_k = |Σ_n w[n] x[n] e^{−2πi k′n/N}|²/(N Σ w²)`, so that
    /// `E[P_k] = Stft::expected_periodogram(lines)[k]`. Cost O(lines·W + M log M).
    ///
    /// Draws (no trigonometric functions per line): the phase is taken at the window centre
    /// `n = N/2` (any fixed reference gives independent uniform phases) and drawn as a unit phasor
    /// `(u² − v², 2uv)/(u² + v²)` of a uniform point `(u, v)` of the unit disc (rejection from the
    /// square, 4/π tries); `C = u/v` of another such point is standard Cauchy — the same law as
    /// `tan(π(U − ½))`, since the point's polar angle is uniform.
    pub fn periodogram(&mut self, lines: &[Line], rng: &mut PathRng, out: &mut [f64]) {
        self.clear_grid();
        let sample_rate = self.stft.sample_rate();
        for line in lines {
            let (c, phasor) = draw(line, sample_rate, rng);
            self.spread(phasor * line.power.sqrt(), c);
        }
        self.grid_to_time();
        self.finish(true, out);
    }

    /// The same window as [`Synthesizer::periodogram`] (same random numbers, same lines) with the
    /// field summed directly: O(lines × N). The benchmark's reference.
    pub fn periodogram_direct(&mut self, lines: &[Line], rng: &mut PathRng, out: &mut [f64]) {
        self.time.fill(Complex::new(0.0, 0.0));
        let sample_rate = self.stft.sample_rate();
        let n_half = (self.stft.samples() / 2) as f64;
        for line in lines {
            let (c, phasor) = draw(line, sample_rate, rng);
            // The drawn phase is at n = N/2; the recursion starts at n = 0.
            let start = Complex::from_polar(line.power.sqrt(), -2.0 * PI * (c * n_half).fract());
            accumulate_direct(&mut self.time, phasor * start, c);
        }
        self.finish(false, out);
    }

    /// The direct O(lines × N) field `x[n] = Σ_j √p_j e^{i(2π f_j n/f_s + ψ_j)}` for given phases
    /// `ψ_j` (radians), at the lines' own frequencies; for tests and the benchmark's reference.
    pub fn field_direct(&self, lines: &[Line], phases: &[f64]) -> Vec<Complex<f64>> {
        assert_eq!(lines.len(), phases.len());
        let mut x = vec![Complex::new(0.0, 0.0); self.stft.samples()];
        for (line, &psi) in lines.iter().zip(phases) {
            let c = unit_cycles(line.frequency, self.stft.sample_rate());
            accumulate_direct(&mut x, Complex::from_polar(line.power.sqrt(), psi), c);
        }
        x
    }

    /// The fast (non-uniform FFT) field for given phases and the lines' own frequencies: what
    /// [`Synthesizer::periodogram`] computes before the window, for the accuracy test.
    pub fn field_fast(&mut self, lines: &[Line], phases: &[f64]) -> Vec<Complex<f64>> {
        assert_eq!(lines.len(), phases.len());
        self.clear_grid();
        let n_half = (self.stft.samples() / 2) as f64;
        for (line, &psi) in lines.iter().zip(phases) {
            let c = unit_cycles(line.frequency, self.stft.sample_rate());
            // Phase ψ at n = 0, so e^{i(ψ + 2π c N/2)} at the centre n = N/2.
            let centre = Complex::from_polar(line.power.sqrt(), psi + 2.0 * PI * (c * n_half).fract());
            self.spread(centre, c);
        }
        self.grid_to_time();
        self.time.iter().zip(&self.deconvolution).map(|(x, d)| x * d).collect()
    }

    fn clear_grid(&mut self) {
        self.padded.fill(Complex::new(0.0, 0.0));
    }

    /// Spread the line `A e^{2πi c (n − N/2)}` (`A` its complex amplitude at the window centre)
    /// onto the grid: with the output index centred (`m = n − N/2`) it is the point `u = c M`.
    #[inline(always)]
    fn spread(&mut self, amp: Complex<f64>, c: f64) {
        let u = c * self.grid as f64 - HALF as f64;
        // ceil(u) for u ≥ −W/2 without a libm call: truncation of a positive shift is the floor.
        let floor = (u + WIDTH as f64) as i64 - WIDTH as i64;
        let left = if (floor as f64) < u { floor + 1 } else { floor };
        let x = 2.0 * (left as f64 - u) - 1.0;
        // Horner over the W kernel points at once. The row count is read from the Vec (not the
        // constant) on purpose: a fully unrolled constant-length loop was compiled lane by lane
        // in scalar code; this form is vectorised (measured −13% per line).
        let (last, rows) = self.polynomial.split_last().expect("DEGREE + 1 rows");
        let mut v = *last;
        for row in rows.iter().rev() {
            for (vi, ri) in v.iter_mut().zip(row) {
                *vi = *vi * x + ri;
            }
        }
        // left ≥ −W/2, so the padded index of the first point is ≥ 0; u ≤ M − W/2 keeps the last
        // below M + W.
        let start = (left + HALF as i64) as usize;
        let cells = &mut self.padded[start..start + WIDTH];
        for (cell, vi) in cells.iter_mut().zip(v) {
            *cell += amp * vi;
        }
    }

    /// Fold the guard points onto the periodic grid, inverse FFT, and gather the `N` centred
    /// samples `B[n − N/2]` into `time` (not yet deconvolved).
    fn grid_to_time(&mut self) {
        let (m, n) = (self.grid, self.stft.samples());
        for p in 0..HALF {
            let v = self.padded[p];
            self.padded[p + m] += v;
        }
        for p in m + HALF..m + WIDTH {
            let v = self.padded[p];
            self.padded[p - m] += v;
        }
        let main = &mut self.padded[HALF..HALF + m];
        self.inverse.process_with_scratch(main, &mut self.scratch);
        for (idx, t) in self.time.iter_mut().enumerate() {
            // m = idx − N/2 modulo M.
            *t = main[(idx + m - n / 2) % m];
        }
    }

    /// Window (with the deconvolution if `fast`), forward FFT, `|·|²`, fftshift into `out`.
    fn finish(&mut self, fast: bool, out: &mut [f64]) {
        let n = self.stft.samples();
        assert_eq!(out.len(), n, "output length must be N");
        if fast {
            for (t, p) in self.time.iter_mut().zip(&self.post) {
                *t *= p;
            }
        } else {
            let scale = 1.0 / self.stft.norm().sqrt();
            for (t, w) in self.time.iter_mut().zip(self.stft.coefficients()) {
                *t *= w * scale;
            }
        }
        self.forward.process_with_scratch(&mut self.time, &mut self.scratch);
        for (q, y) in self.time.iter().enumerate() {
            out[(q + n / 2) % n] = y.norm_sqr();
        }
    }
}

/// `f/f_s` modulo 1, in `[0, 1)` (`f` reduced modulo `f_s` first, exactly).
#[inline(always)]
fn unit_cycles(f: f64, sample_rate: f64) -> f64 {
    let c = cycles(f, sample_rate);
    let c = if c < 0.0 { c + 1.0 } else { c };
    if c >= 1.0 { 0.0 } else { c }
}

/// A uniform point of the unit disc, by rejection from the square `[−1, 1)²` (probability π/4
/// per try); the origin is rejected too, so both the phasor and the ratio below are finite.
#[inline(always)]
fn disc_point(rng: &mut PathRng) -> (f64, f64, f64) {
    loop {
        let u = 2.0 * rng.uniform() - 1.0;
        let v = 2.0 * rng.uniform() - 1.0;
        let r2 = u * u + v * v;
        if r2 <= 1.0 && v != 0.0 {
            return (u, v, r2);
        }
    }
}

/// One line's random draws: the phase first (a uniform unit phasor, `(u² − v², 2uv)/r²` of a disc
/// point: its angle is twice the point's uniform angle), then, if `γ > 0`, the Cauchy frequency
/// (`u/v` of another disc point: the cotangent of a uniform angle). Returns (frequency in cycles
/// per sample in `[0, 1)`, phasor).
#[inline(always)]
fn draw(line: &Line, sample_rate: f64, rng: &mut PathRng) -> (f64, Complex<f64>) {
    let (u, v, r2) = disc_point(rng);
    let phasor = Complex::new((u * u - v * v) / r2, 2.0 * u * v / r2);
    let f = if line.gamma > 0.0 {
        let (u, v, _) = disc_point(rng);
        line.frequency + line.gamma * (u / v)
    } else {
        line.frequency
    };
    (unit_cycles(f, sample_rate), phasor)
}

/// `x[n] += A e^{2πi c n}` by rotation, re-anchored on the exact phase every 32 samples (rounding
/// stays ≲ 32 ε).
fn accumulate_direct(x: &mut [Complex<f64>], amp: Complex<f64>, c: f64) {
    let step = Complex::from_polar(1.0, 2.0 * PI * c);
    let mut z = Complex::new(0.0, 0.0);
    for (n, xn) in x.iter_mut().enumerate() {
        if n % 32 == 0 {
            z = amp * Complex::from_polar(1.0, 2.0 * PI * (c * n as f64).fract());
        }
        *xn += z;
        z *= step;
    }
}

/// Algorithm 1 single measurement: each bin's expected power times an independent `Exp(1)` draw
/// (fully developed speckle, Kim et al. §5.2).
pub fn speckle_draw(expected: &[f64], rng: &mut PathRng, out: &mut [f64]) {
    assert_eq!(expected.len(), out.len());
    for (o, &e) in out.iter_mut().zip(expected) {
        *o = e * rng.exponential();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Purpose;
    use crate::spectrum::stft::Window;

    #[test]
    fn kernel_polynomial_is_accurate() {
        let stft = Stft::new(39_000.0, 64, Window::Rect).unwrap();
        let synth = Synthesizer::new(&stft);
        let mut worst: f64 = 0.0;
        for t in 0..1000 {
            let s = t as f64 / 1000.0 + 0.000_37;
            let x = 2.0 * s - 1.0;
            for i in 0..WIDTH {
                let v = synth.polynomial.iter().rev().fold(0.0, |acc, row| acc * x + row[i]);
                worst = worst.max((v - es_kernel(2.0 * (s + i as f64) / WIDTH as f64 - 1.0)).abs());
            }
        }
        eprintln!("polynomial ES kernel: max error {worst:.2e}");
        assert!(worst < 1e-8, "{worst}");
    }

    #[test]
    fn disc_draws_are_uniform_phases_and_cauchy() {
        // Phasor angles uniform (KS over 1e5 draws: D√n < 1.95 is p > 1e-3),
        // and the Cauchy draws' quartiles at ±1.
        let n = 100_000;
        let mut rng = PathRng::new(9, Purpose::Test, 0, 0);
        let line = Line { power: 1.0, frequency: 0.0, gamma: 1.0 };
        let mut angles = Vec::with_capacity(n);
        let mut cauchy = Vec::with_capacity(n);
        for _ in 0..n {
            let (u, v, r2) = disc_point(&mut rng);
            angles.push(Complex::new((u * u - v * v) / r2, 2.0 * u * v / r2).arg());
            let (u, v, _) = disc_point(&mut rng);
            cauchy.push(line.gamma * u / v);
        }
        angles.sort_by(f64::total_cmp);
        let d = angles
            .iter()
            .enumerate()
            .map(|(i, a)| ((a + PI) / (2.0 * PI) - i as f64 / n as f64).abs())
            .fold(0.0, f64::max);
        eprintln!("disc phasor angles: KS D√n = {:.3}", d * (n as f64).sqrt());
        assert!(d * (n as f64).sqrt() < 1.95, "{d}");
        let inside = cauchy.iter().filter(|c| c.abs() < 1.0).count() as f64 / n as f64;
        assert!((inside - 0.5).abs() < 4.0 * 0.5 / (n as f64).sqrt(), "{inside}");
    }

    #[test]
    fn gauss_legendre_integrates_polynomials() {
        let q = gauss_legendre(10);
        let sum: f64 = q.iter().map(|(_, w)| w).sum();
        assert!((sum - 2.0).abs() < 1e-14);
        let x18: f64 = q.iter().map(|(x, w)| w * x.powi(18)).sum();
        assert!((x18 - 2.0 / 19.0).abs() < 1e-14);
    }

    /// max |fast − direct| / max |direct| for random lines over several multiples of f_s.
    fn fast_field_error(n: usize, lines: usize, seed: u64) -> f64 {
        let fs = 39_000.0;
        let stft = Stft::new(fs, n, Window::Hann).unwrap();
        let mut synth = Synthesizer::new(&stft);
        let mut rng = PathRng::new(seed, Purpose::Test, n as u64, lines as u64);
        let ls: Vec<Line> = (0..lines)
            .map(|_| Line { power: rng.uniform() + 0.01, frequency: (rng.uniform() - 0.5) * 8.0 * fs, gamma: 0.0 })
            .collect();
        let phases: Vec<f64> = (0..lines).map(|_| 2.0 * PI * rng.uniform()).collect();
        let direct = synth.field_direct(&ls, &phases);
        let fast = synth.field_fast(&ls, &phases);
        let scale = direct.iter().map(|z| z.norm()).fold(0.0, f64::max);
        direct.iter().zip(&fast).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max) / scale
    }

    #[test]
    fn fast_field_matches_direct_sum() {
        for &n in &[2, 8, 64, 512] {
            for &lines in &[1, 7, 300, 5_000] {
                let err = fast_field_error(n, lines, 3);
                eprintln!("N = {n:3}, {lines:4} lines: max |fast − direct| / max |direct| = {err:.2e}");
                assert!(err < 1e-6, "N={n} lines={lines}: {err:e}");
            }
        }
        // Worst case over a line's grid offset: one unit line at 2000 frequencies across a grid
        // cell (the error of any sum is at most Σ_j √p_j times this).
        for &n in &[64, 512] {
            let stft = Stft::new(39_000.0, n, Window::Hann).unwrap();
            let mut synth = Synthesizer::new(&stft);
            let cell = 39_000.0 / synth.grid() as f64;
            let worst = (0..2000)
                .map(|i| {
                    let l = [Line { power: 1.0, frequency: 5_000.0 + cell * i as f64 / 2000.0, gamma: 0.0 }];
                    let (d, f) = (synth.field_direct(&l, &[0.3]), synth.field_fast(&l, &[0.3]));
                    d.iter().zip(&f).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max)
                })
                .fold(0.0, f64::max);
            eprintln!("N = {n:3}: worst single-line error over a grid cell {worst:.2e}");
            assert!(worst < 1e-6);
        }
    }

    #[test]
    fn single_on_grid_tone_lands_in_one_bin() {
        // Rect window, a tone exactly on bin 5 (above DC): all power in that bin.
        let stft = Stft::new(1_000.0, 64, Window::Rect).unwrap();
        let mut synth = Synthesizer::new(&stft);
        let mut out = vec![0.0; 64];
        let lines = [Line { power: 0.7, frequency: stft.bin_frequency(37) + 3_000.0, gamma: 0.0 }];
        synth.periodogram(&lines, &mut PathRng::new(1, Purpose::Test, 0, 0), &mut out);
        assert!((out[37] - 0.7).abs() < 1e-6, "{}", out[37]);
        assert!(out.iter().enumerate().filter(|&(k, _)| k != 37).all(|(_, &p)| p < 1e-12));
        let mut direct = vec![0.0; 64];
        synth.periodogram_direct(&lines, &mut PathRng::new(1, Purpose::Test, 0, 0), &mut direct);
        assert!((direct[37] - 0.7).abs() < 1e-12);
    }

    #[test]
    fn fast_and_direct_periodograms_agree_with_same_draws() {
        let stft = Stft::new(39_000.0, 64, Window::Hann).unwrap();
        let mut synth = Synthesizer::new(&stft);
        let lines: Vec<Line> = (0..200)
            .map(|j| Line { power: 0.005, frequency: -30_000.0 + 311.7 * j as f64, gamma: (j % 3) as f64 * 150.0 })
            .collect();
        let (mut a, mut b) = (vec![0.0; 64], vec![0.0; 64]);
        synth.periodogram(&lines, &mut PathRng::new(5, Purpose::Speckle, 0, 1), &mut a);
        synth.periodogram_direct(&lines, &mut PathRng::new(5, Purpose::Speckle, 0, 1), &mut b);
        let scale = b.iter().cloned().fold(0.0, f64::max);
        let err = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / scale;
        assert!(err < 2e-6, "{err:e}");
    }
}
