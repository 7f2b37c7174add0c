//! Media made of particles: the bulk optics of a mixture of Mie ensembles (an external mixture, as
//! OPAC's aerosol types: each component scatters independently and the coefficients add).
//!
//! For components `i` with scattering σs,i, absorption σa,i, phase function p_i and backscatter
//! β_i = σs,i p_i(π): σs = Σ σs,i, σa = Σ σa,i, p = Σ σs,i p_i / σs, g = Σ σs,i g_i / σs,
//! β = Σ β_i and the lidar ratio S = (σs + σa)/β.

use serde::Serialize;

use crate::mie::{EnsembleSpec, MieError, SizeDistribution, angle_grid, ensemble_optics};

/// The Mie optics of one component.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ComponentOptics {
    pub name: String,
    /// m⁻¹.
    pub sigma_s: f64,
    /// m⁻¹.
    pub sigma_a: f64,
    pub g: f64,
    /// m⁻¹ sr⁻¹.
    pub backscatter: f64,
    /// m⁻³.
    pub number_density: f64,
    pub volume_fraction: f64,
    /// m (⟨r³⟩/⟨r²⟩).
    pub effective_radius: f64,
}

/// The bulk optics of a particle mixture, with its phase function on an angle grid.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParticleOptics {
    /// m⁻¹.
    pub sigma_s: f64,
    /// m⁻¹.
    pub sigma_a: f64,
    /// σs-weighted Mie asymmetry (exact, not from the table).
    pub g: f64,
    /// β = σs p(π), m⁻¹ sr⁻¹.
    pub backscatter: f64,
    /// (σs + σa)/β, sr.
    pub lidar_ratio: f64,
    pub components: Vec<ComponentOptics>,
    /// Scattering angles of the phase table (radians, 0 … π).
    #[serde(skip)]
    pub theta: Vec<f64>,
    /// The mixture's phase function at `theta`, sr⁻¹.
    #[serde(skip)]
    pub phase: Vec<f64>,
    /// Particle radii (m) with the σs each contributes (m⁻¹), over all components (see
    /// [`crate::mie::EnsembleOptics::sizes`]).
    #[serde(skip)]
    pub sizes: Vec<(f64, f64)>,
}

/// A sphere of diameter `d` (m) and index `n_p − i k_p` in a host of index `n_m`, lit at vacuum
/// wavelength `wavelength` (m), as the relative index `(n, k)` and size parameter `x` of Mie theory:
/// `m = (n_p − i k_p)/n_m`, `x = π d n_m / λ0` (the wavelength in the host is `λ0/n_m`).
pub fn relative_sphere(d: f64, n_p: f64, k_p: f64, n_m: f64, wavelength: f64) -> (f64, f64, f64) {
    (n_p / n_m, k_p / n_m, std::f64::consts::PI * d * n_m / wavelength)
}

/// Largest radius an ensemble contains (m).
fn largest_radius(d: &SizeDistribution) -> f64 {
    match *d {
        SizeDistribution::Monodisperse { radius } => radius,
        SizeDistribution::LogNormal { r_max, .. } | SizeDistribution::ModifiedGamma { r_max, .. } => r_max,
        SizeDistribution::MarshallPalmer { d_max, .. } => 0.5 * d_max,
    }
}

/// The optics of `components` (name, specification), with the phase function tabulated on an
/// `angles`-node grid dense near forward (finer for larger particles).
pub fn mixture_optics(components: &[(String, EnsembleSpec)], angles: usize) -> Result<ParticleOptics, MieError> {
    let x_max = components
        .iter()
        .map(|(_, s)| 2.0 * std::f64::consts::PI * largest_radius(&s.distribution) * s.n_medium / s.wavelength)
        .fold(0.0, f64::max);
    let theta = angle_grid(angles, x_max);
    let mut phase = vec![0.0; theta.len()];
    let (mut sigma_s, mut sigma_a, mut g_sum, mut backscatter) = (0.0, 0.0, 0.0, 0.0);
    let mut parts = Vec::with_capacity(components.len());
    let mut sizes = Vec::new();
    for (name, spec) in components {
        let e = ensemble_optics(spec, &theta)?;
        for (p, q) in phase.iter_mut().zip(&e.phase) {
            *p += e.sigma_s * q;
        }
        sigma_s += e.sigma_s;
        sizes.extend_from_slice(&e.sizes);
        sigma_a += e.sigma_a;
        g_sum += e.sigma_s * e.g;
        backscatter += e.backscatter;
        parts.push(ComponentOptics {
            name: name.clone(),
            sigma_s: e.sigma_s,
            sigma_a: e.sigma_a,
            g: e.g,
            backscatter: e.backscatter,
            number_density: e.number_density,
            volume_fraction: e.volume_fraction,
            effective_radius: e.effective_radius,
        });
    }
    if sigma_s > 0.0 {
        phase.iter_mut().for_each(|p| *p /= sigma_s);
    }
    let g = if sigma_s > 0.0 { g_sum / sigma_s } else { 0.0 };
    let lidar_ratio = if backscatter > 0.0 { (sigma_s + sigma_a) / backscatter } else { f64::INFINITY };
    Ok(ParticleOptics { sigma_s, sigma_a, g, backscatter, lidar_ratio, components: parts, theta, phase, sizes })
}
