//! The f64 FFTs ohd runs (spectra, STFTs, the layered twin's kernels), planned here.
//!
//! rustfft's planner and algorithms are generic over the float type, so every crate that plans an
//! `f64` FFT compiles all of them for `f64`: in `ohd` they were 17 % of the unoptimised IR of its
//! one codegen unit, which LLVM optimises on one core before the binary's thin LTO does it again.
//! Planned behind these non-generic functions, they are compiled once, in this crate, beside
//! `ohd`'s own compilation (cargo's pipelining), and are a module of their own in the binary's LTO.
//! A plan is rustfft's (`Arc<dyn Fft<f64>>`): running it is a call through its vtable, as before,
//! and the same algorithms compute the same bits.

use std::sync::Arc;

pub use rustfft::Fft;
pub use rustfft::num_complex::Complex;

/// A planner of `f64` FFTs (rustfft's `FftPlanner<f64>`: it reuses the plans and twiddle tables
/// of the sizes it has planned).
pub struct Planner(rustfft::FftPlanner<f64>);

impl Default for Planner {
    fn default() -> Self {
        Self::new()
    }
}

impl Planner {
    /// A planner choosing the fastest algorithms this CPU runs (AVX or SSE where present).
    pub fn new() -> Self {
        Planner(rustfft::FftPlanner::new())
    }

    /// The forward transform of length `n` (unnormalised, `exp(−2πi jk/n)`).
    pub fn forward(&mut self, n: usize) -> Arc<dyn Fft<f64>> {
        self.0.plan_fft_forward(n)
    }

    /// The inverse transform of length `n` (unnormalised, `exp(+2πi jk/n)`).
    pub fn inverse(&mut self, n: usize) -> Arc<dyn Fft<f64>> {
        self.0.plan_fft_inverse(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forward_then_inverse_is_n_times_the_input() {
        let mut p = Planner::new();
        for n in [1, 7, 64, 360, 1000] {
            let x: Vec<Complex<f64>> = (0..n).map(|j| Complex::new((j as f64).sin(), (0.3 * j as f64).cos())).collect();
            let mut y = x.clone();
            p.forward(n).process(&mut y);
            p.inverse(n).process(&mut y);
            for (a, b) in x.iter().zip(&y) {
                assert!((a * n as f64 - b).norm() <= 1e-9 * n as f64, "n = {n}");
            }
        }
    }
}
