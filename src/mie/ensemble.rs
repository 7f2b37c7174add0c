//! Particle ensembles: the bulk optics of spheres with a size distribution and a concentration.
//!
//! For a number density `N` of spheres whose radii follow the normalised distribution `s(r)`:
//!
//! ```text
//! σs = N ∫ s(r) π r² Qsca(r) dr,   σa = N ∫ s(r) π r² (Qext − Qsca)(r) dr,
//! p(θ) = ∫ s π r² Qsca p_r(θ) dr / ∫ s π r² Qsca dr,   g = ∫ s π r² Qsca g_r dr / ∫ s π r² Qsca dr,
//! β = σs p(π) = N ∫ s(r) r² Qback(r)/4 dr   (Qback = 4|S1(π)|²/x², so p_r(π) = Qback/(4π Qsca)).
//! ```
//!
//! The integrals over r are Gauss–Legendre quadratures in `ln r` over the truncation range, whose
//! nodes are solved in parallel and summed in a fixed order (deterministic). Nodes whose geometric
//! cross-section weight is below 1e-12 of the largest are skipped: a distribution's tails cost nothing.
//!
//! Dependent scattering: `Packing::Twersky` multiplies σs (and β) by `W = (1 − f)(1.4 − f)` for
//! volume fraction `f` — Twersky 1970 (J. Opt. Soc. Am. 60:1084) as applied to red blood cells by
//! Steinke & Shepherd 1988 (Appl. Opt. 27:4027), valid for RBC-like particles up to a hematocrit of
//! ≈ 0.6 (the constant 1.4 is their fit for RBC shape; not a hard-sphere result).

use std::f64::consts::PI;

use rayon::prelude::*;

use super::{MieError, MieSolution};

/// How particle radii are distributed (lengths in metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SizeDistribution {
    Monodisperse {
        radius: f64,
    },
    /// `dN/d ln r ∝ exp(−(ln r − ln r_med)²/(2 ln² σ_g))` on `[r_min, r_max]` (OPAC).
    LogNormal {
        median_radius: f64,
        sigma_g: f64,
        r_min: f64,
        r_max: f64,
    },
    /// Deirmendjian's modified gamma, `n(r) ∝ r^α exp(−(α/γ)(r/r_c)^γ)` on `[r_min, r_max]`.
    ModifiedGamma {
        alpha: f64,
        gamma: f64,
        mode_radius: f64,
        r_min: f64,
        r_max: f64,
    },
    /// Marshall & Palmer 1948 raindrops, `N(D) = N0 exp(−Λ D)`, `N0 = 8000 m⁻³ mm⁻¹`,
    /// `Λ = 4.1 R^−0.21 mm⁻¹` (R in mm/h), diameters on `[d_min, d_max]`. Absolute concentration.
    MarshallPalmer {
        rain_rate_mm_per_h: f64,
        d_min: f64,
        d_max: f64,
    },
}

/// How many particles there are (not used by Marshall–Palmer, which fixes it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Concentration {
    /// Particles per m³ (within the truncation range).
    NumberDensity(f64),
    /// Fraction of the volume the particles fill, in (0, 1).
    VolumeFraction(f64),
}

/// Dependent-scattering correction for dense suspensions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Packing {
    /// σs × (1 − f)(1.4 − f) (Twersky 1970; Steinke & Shepherd 1988).
    Twersky,
}

/// What [`ensemble_optics`] computes from.
#[derive(Debug, Clone, PartialEq)]
pub struct EnsembleSpec {
    pub n_particle: f64,
    /// `k ≥ 0` absorbing (index `n − ik`).
    pub k_particle: f64,
    pub n_medium: f64,
    /// Vacuum wavelength, m.
    pub wavelength: f64,
    pub distribution: SizeDistribution,
    pub concentration: Option<Concentration>,
    pub packing: Option<Packing>,
    /// Gauss–Legendre nodes in `ln r` (ignored for monodisperse).
    pub size_points: usize,
}

/// Bulk optics of an ensemble (per unit volume of the suspension).
#[derive(Debug, Clone, PartialEq)]
pub struct EnsembleOptics {
    /// m⁻¹.
    pub sigma_s: f64,
    /// Absorption by the particles, m⁻¹.
    pub sigma_a: f64,
    /// m⁻¹.
    pub sigma_ext: f64,
    /// Exact σs-weighted Mie asymmetry.
    pub g: f64,
    /// β = σs p(π), m⁻¹ sr⁻¹.
    pub backscatter: f64,
    /// σext/β, sr.
    pub lidar_ratio: f64,
    /// m⁻³.
    pub number_density: f64,
    pub volume_fraction: f64,
    /// ⟨r³⟩/⟨r²⟩, m.
    pub effective_radius: f64,
    /// Phase function at the caller's angles, sr⁻¹.
    pub phase: Vec<f64>,
    /// Quadrature nodes actually solved.
    pub size_points: usize,
}

/// Marshall–Palmer intercept, m⁻⁴ (8000 m⁻³ mm⁻¹).
const MP_N0: f64 = 8.0e6;

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton on P_n from Chebyshev guesses).
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                let p = if n == 0 { 1.0 } else { p1 };
                let pm1 = p0;
                dp = n as f64 * (x * p - pm1) / (x * x - 1.0);
                let dx = p / dp;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// Radii and number weights (dN per node, unnormalised; absolute for Marshall–Palmer).
fn nodes(d: &SizeDistribution, size_points: usize) -> Result<Vec<(f64, f64)>, MieError> {
    let positive = |name: &'static str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(MieError::Parameter { name, value: v, expected: "a finite value > 0" })
        }
    };
    let range = |name: &'static str, lo: f64, hi: f64| {
        positive(name, lo)?;
        positive(name, hi)?;
        if lo < hi { Ok((lo, hi)) } else { Err(MieError::Range { name, min: lo, max: hi }) }
    };
    let quadrature = |lo: f64, hi: f64, density: &dyn Fn(f64) -> f64| -> Vec<(f64, f64)> {
        // ∫ f(r) dr = ∫ r f(r) d ln r; density is dN/d ln r.
        let (a, b) = (lo.ln(), hi.ln());
        gauss_legendre(size_points.max(2))
            .into_iter()
            .map(|(t, w)| {
                let u = 0.5 * (a + b) + 0.5 * (b - a) * t;
                let r = u.exp();
                (r, 0.5 * (b - a) * w * density(r))
            })
            .collect()
    };
    Ok(match *d {
        SizeDistribution::Monodisperse { radius } => vec![(positive("radius", radius)?, 1.0)],
        SizeDistribution::LogNormal { median_radius, sigma_g, r_min, r_max } => {
            let rm = positive("median_radius", median_radius)?;
            if !(sigma_g.is_finite() && sigma_g > 1.0) {
                return Err(MieError::Parameter { name: "sigma_g", value: sigma_g, expected: "a finite value > 1" });
            }
            let (lo, hi) = range("radius range", r_min, r_max)?;
            let s = sigma_g.ln();
            quadrature(lo, hi, &|r: f64| (-(r / rm).ln().powi(2) / (2.0 * s * s)).exp())
        }
        SizeDistribution::ModifiedGamma { alpha, gamma, mode_radius, r_min, r_max } => {
            let rc = positive("mode_radius", mode_radius)?;
            positive("alpha", alpha)?;
            positive("gamma", gamma)?;
            let (lo, hi) = range("radius range", r_min, r_max)?;
            // r·n(r) relative to its value at r_c, in logs so that large α cannot overflow.
            quadrature(lo, hi, &|r: f64| {
                let q = r / rc;
                ((alpha + 1.0) * q.ln() - (alpha / gamma) * (q.powf(gamma) - 1.0)).exp()
            })
        }
        SizeDistribution::MarshallPalmer { rain_rate_mm_per_h, d_min, d_max } => {
            let rate = positive("rain_rate_mm_per_h", rain_rate_mm_per_h)?;
            let (lo, hi) = range("diameter range", d_min, d_max)?;
            let lambda = 4.1e3 * rate.powf(-0.21); // m⁻¹
            // dN/d ln r = r · N(r), N(r) dr = N0 exp(−Λ 2r) 2 dr.
            quadrature(0.5 * lo, 0.5 * hi, &|r: f64| r * 2.0 * MP_N0 * (-lambda * 2.0 * r).exp())
        }
    })
}

/// The bulk optics of `spec`, with the phase function at scattering angles `theta` (radians).
pub fn ensemble_optics(spec: &EnsembleSpec, theta: &[f64]) -> Result<EnsembleOptics, MieError> {
    for (name, v, ok) in
        [("n_medium", spec.n_medium, spec.n_medium > 0.0), ("wavelength", spec.wavelength, spec.wavelength > 0.0)]
    {
        if !(v.is_finite() && ok) {
            return Err(MieError::Parameter { name, value: v, expected: "a finite value > 0" });
        }
    }
    let nodes = nodes(&spec.distribution, spec.size_points)?;
    let shape_total: f64 = nodes.iter().map(|n| n.1).sum();
    if !(shape_total.is_finite() && shape_total > 0.0) {
        return Err(MieError::EmptyDistribution(format!(
            "no particles within the size range ({:?})",
            spec.distribution
        )));
    }
    let volume = |r: f64| 4.0 / 3.0 * PI * r * r * r;
    let mean_volume: f64 = nodes.iter().map(|&(r, w)| w * volume(r)).sum::<f64>() / shape_total;
    let is_rain = matches!(spec.distribution, SizeDistribution::MarshallPalmer { .. });
    let number_density = match (is_rain, spec.concentration) {
        (true, None) => shape_total,
        (true, Some(_)) => {
            return Err(MieError::Concentration("Marshall–Palmer fixes the concentration; give none".into()));
        }
        (false, Some(Concentration::NumberDensity(n))) if n.is_finite() && n > 0.0 => n,
        (false, Some(Concentration::VolumeFraction(f))) if f > 0.0 && f < 1.0 => f / mean_volume,
        (false, Some(c)) => return Err(MieError::Concentration(format!("{c:?} is out of range"))),
        (false, None) => {
            return Err(MieError::Concentration("missing: give a number density or volume fraction".into()));
        }
    };
    let volume_fraction = number_density * mean_volume;
    // Number fractions; drop nodes whose geometric cross-section weight is negligible.
    let fractions: Vec<(f64, f64)> = nodes.iter().map(|&(r, w)| (r, w / shape_total)).collect();
    let biggest = fractions.iter().map(|&(r, s)| s * r * r).fold(0.0, f64::max);
    let kept: Vec<(f64, f64)> = fractions.into_iter().filter(|&(r, s)| s * r * r >= 1e-12 * biggest).collect();
    let (m_re, m_im) = (spec.n_particle / spec.n_medium, spec.k_particle / spec.n_medium);
    let k = 2.0 * PI * spec.n_medium / spec.wavelength;
    let solved: Vec<Result<(f64, f64, super::Efficiencies, Vec<f64>), MieError>> = kept
        .par_iter()
        .map(|&(r, s)| {
            let sol = MieSolution::new(m_re, m_im, k * r)?;
            let mut p = vec![0.0; theta.len()];
            sol.phase_function(theta, &mut p);
            Ok((r, s, sol.efficiencies(), p))
        })
        .collect();
    let (mut csca, mut cabs, mut gsum, mut back, mut r2, mut r3) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let mut phase = vec![0.0; theta.len()];
    for item in solved {
        let (r, s, q, p) = item?;
        let area = PI * r * r;
        let c = s * area * q.qsca;
        csca += c;
        cabs += s * area * (q.qext - q.qsca);
        gsum += c * q.g;
        back += s * r * r * q.qback / 4.0;
        r2 += s * r * r;
        r3 += s * r * r * r;
        for (acc, v) in phase.iter_mut().zip(&p) {
            *acc += c * v;
        }
    }
    if csca > 0.0 {
        phase.iter_mut().for_each(|v| *v /= csca);
    }
    let packing = match spec.packing {
        Some(Packing::Twersky) => (1.0 - volume_fraction) * (1.4 - volume_fraction),
        None => 1.0,
    };
    let sigma_s = number_density * csca * packing;
    let sigma_a = number_density * cabs;
    let backscatter = number_density * back * packing;
    Ok(EnsembleOptics {
        sigma_s,
        sigma_a,
        sigma_ext: sigma_s + sigma_a,
        g: if csca > 0.0 { gsum / csca } else { 0.0 },
        backscatter,
        lidar_ratio: if backscatter > 0.0 { (sigma_s + sigma_a) / backscatter } else { f64::INFINITY },
        number_density,
        volume_fraction,
        effective_radius: if r2 > 0.0 { r3 / r2 } else { 0.0 },
        phase,
        size_points: kept.len(),
    })
}

/// `n ≥ 16` scattering angles from 0 to π (radians, strictly increasing) for particles up to size
/// parameter `x_max`: θ = 0, then half the nodes geometric from `min(0.01, 0.05/x_max)` (well inside
/// a diffraction peak of width ≈ 1/x) to π/6, the rest uniform to π.
pub fn angle_grid(n: usize, x_max: f64) -> Vec<f64> {
    let n = n.max(16);
    let first = (0.05 / x_max.max(1e-12)).min(0.01);
    let knee = PI / 6.0;
    let n_log = n / 2; // nodes in [first, knee]
    let n_lin = n - 1 - n_log; // nodes in (knee, π]
    let mut t = Vec::with_capacity(n);
    t.push(0.0);
    let ratio = (knee / first).ln();
    t.extend((0..n_log).map(|i| first * (ratio * i as f64 / (n_log - 1) as f64).exp()));
    t.extend((1..=n_lin).map(|i| knee + (PI - knee) * i as f64 / n_lin as f64));
    *t.last_mut().expect("n ≥ 16") = PI;
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        for n in [2, 5, 16, 96] {
            let q = gauss_legendre(n);
            let w: f64 = q.iter().map(|p| p.1).sum();
            assert!((w - 2.0).abs() < 1e-13, "n = {n}: weights sum to {w}");
            // ∫ x^(2n−2) over [−1, 1] = 2/(2n − 1).
            let e = 2 * n - 2;
            let s: f64 = q.iter().map(|p| p.1 * p.0.powi(e as i32)).sum();
            assert!((s - 2.0 / (e + 1) as f64).abs() < 1e-12, "n = {n}: {s}");
        }
    }

    #[test]
    fn angle_grid_is_increasing_and_spans_the_sphere() {
        for (n, x) in [(16, 1e-3), (1000, 30.0), (2000, 1e4)] {
            let t = angle_grid(n, x);
            assert_eq!(t.len(), n);
            assert_eq!((t[0], t[n - 1]), (0.0, PI));
            assert!(t.windows(2).all(|w| w[1] > w[0]), "n = {n}, x = {x}");
            assert!(t[1] <= 0.05 / x + 1e-15);
        }
    }
}
