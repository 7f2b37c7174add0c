//! Media and the scene they fill: homogeneous media, region shapes, the layer stack.

mod scene;
mod shape;

pub use scene::{Layer, MAX_REGIONS_PER_LAYER, Region, Scene};
pub use shape::Shape;

use crate::flow::VelocityField;
use crate::phase::PhaseFunction;

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
            sigma_a,
            sigma_s,
            sigma_t,
            inv_sigma_t: if sigma_t > 0.0 { 1.0 / sigma_t } else { f64::INFINITY },
            albedo: if sigma_t > 0.0 { sigma_s / sigma_t } else { 0.0 },
        }
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
