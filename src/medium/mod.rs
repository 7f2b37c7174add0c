//! Media and the scene they fill: homogeneous media, region shapes, the layer stack.

mod particles;
mod scene;
mod shape;

pub use particles::{ComponentOptics, ParticleOptics, mixture_optics, relative_sphere};
pub use scene::{Layer, MAX_REGIONS_PER_LAYER, Region, Scene};
pub use shape::Shape;

use serde::Serialize;

use crate::flow::VelocityField;
use crate::phase::PhaseFunction;

/// Where a medium's optics came from, for the manifest (nothing here is read by the walk).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct MediumInfo {
    /// The preset it was expanded from.
    pub preset: Option<String>,
    /// The phase function in words ("hg", "table", "mie", "isotropic").
    pub phase: String,
    /// Mean cosine of the phase function as sampled.
    pub g: f64,
    /// A phase table's origin and how its values were normalised as given.
    pub table: Option<TableInfo>,
    /// Mie optics of the particles, before explicit σ values and `sigma_s_scale` were applied.
    pub particles: Option<ParticleOptics>,
    pub sigma_s_scale: f64,
}

/// A phase table as loaded.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TableInfo {
    pub origin: String,
    pub angles: usize,
    /// Declared normalisation of a table file (`per_sr`, `four_pi`, `arbitrary`).
    pub source_normalisation: Option<String>,
    /// `∫ p dΩ` of the values as given (renormalised to 1 on load).
    pub source_integral: f64,
    pub provenance: std::collections::BTreeMap<String, String>,
}

/// Random motion of a medium's particles beyond the mean flow of its [`VelocityField`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Motion {
    /// Standard deviation of each Cartesian component of a random velocity drawn afresh at every
    /// scattering event and added to the flow (shear-induced dispersion, tumbling), m/s.
    pub dispersion: f64,
    /// Translational diffusion coefficient `D` of the particles (Brownian motion), m²/s. Not drawn
    /// per event: a path collects `D·q²` per event, and its line is broadened into a Lorentzian of
    /// half-width `Σ D_k q_k² / 2π` Hz (see `detect`).
    pub diffusion: f64,
}

impl Motion {
    /// Whether the particles move at random at all.
    pub fn is_random(&self) -> bool {
        self.dispersion > 0.0 || self.diffusion > 0.0
    }
}

/// Stokes–Einstein diffusion coefficient `D = k_B T / (6π η r)` (m²/s) of a sphere of radius `r`
/// (m) in a fluid of viscosity `η` (Pa·s) at temperature `T` (K).
pub fn stokes_einstein(radius: f64, temperature: f64, viscosity: f64) -> f64 {
    const BOLTZMANN: f64 = 1.380_649e-23; // J/K, exact (SI 2019)
    BOLTZMANN * temperature / (6.0 * std::f64::consts::PI * viscosity * radius)
}

/// A homogeneous participating medium with the velocity field of its particles.
///
/// The coefficients are fixed at construction so that the derived constants the random walk
/// uses at every collision (σt, 1/σt, albedo) are computed once.
#[derive(Debug, Clone, PartialEq)]
pub struct Medium {
    /// Name in the configuration (for messages and the manifest).
    pub name: String,
    pub phase: PhaseFunction,
    pub velocity: VelocityField,
    /// Random motion beyond the flow (none by default).
    pub motion: Motion,
    /// Provenance of the optics, for the manifest.
    pub info: MediumInfo,
    sigma_a: f64,
    sigma_s: f64,
    sigma_t: f64,
    inv_sigma_t: f64,
    albedo: f64,
}

impl Medium {
    /// A medium with absorption σa and scattering σs (m⁻¹, finite and ≥ 0).
    pub fn new(
        name: impl Into<String>,
        sigma_a: f64,
        sigma_s: f64,
        phase: PhaseFunction,
        velocity: VelocityField,
    ) -> Self {
        let sigma_t = sigma_a + sigma_s;
        Medium {
            name: name.into(),
            phase,
            velocity,
            motion: Motion::default(),
            info: MediumInfo::default(),
            sigma_a,
            sigma_s,
            sigma_t,
            inv_sigma_t: if sigma_t > 0.0 { 1.0 / sigma_t } else { f64::INFINITY },
            albedo: if sigma_t > 0.0 { sigma_s / sigma_t } else { 0.0 },
        }
    }

    /// Whether scattering on this medium's particles changes `dl/dt` or broadens the line (a
    /// "Doppler event").
    #[inline(always)]
    pub fn is_dynamic(&self) -> bool {
        self.velocity.is_moving() || self.motion.is_random()
    }

    /// Absorption coefficient σa, m⁻¹.
    pub fn sigma_a(&self) -> f64 {
        self.sigma_a
    }

    /// Scattering coefficient σs, m⁻¹.
    pub fn sigma_s(&self) -> f64 {
        self.sigma_s
    }

    /// Extinction coefficient σt = σa + σs, m⁻¹.
    #[inline(always)]
    pub fn sigma_t(&self) -> f64 {
        self.sigma_t
    }

    /// Mean free path 1/σt, m (∞ in a vacuum).
    #[inline(always)]
    pub fn inv_sigma_t(&self) -> f64 {
        self.inv_sigma_t
    }

    /// Single-scattering albedo σs/σt (0 for a vacuum).
    #[inline(always)]
    pub fn albedo(&self) -> f64 {
        self.albedo
    }
}
