//! Lidar physics for the wind-lidar tests: the Henyey–Greenstein backscatter, the pulse product a
//! range gate collects, and the check of a run's single-scattering lag sums against a prediction.

use super::run::Run;
use super::stats::chi2_sf;

impl Run {
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
