//! Media and the scene they fill: homogeneous media, region shapes, the layer stack.

mod scene;
mod shape;

pub use scene::{Layer, MAX_REGIONS_PER_LAYER, Region, Scene};
pub use shape::Shape;

use crate::flow::VelocityField;
use crate::phase::PhaseFunction;

/// A homogeneous participating medium with the velocity field of its particles.
#[derive(Debug, Clone, PartialEq)]
pub struct Medium {
    /// Name in the configuration (for messages and the manifest).
    pub name: String,
    /// Absorption coefficient σa, m⁻¹.
    pub sigma_a: f64,
    /// Scattering coefficient σs, m⁻¹.
    pub sigma_s: f64,
    pub phase: PhaseFunction,
    pub velocity: VelocityField,
}

impl Medium {
    /// Extinction coefficient σt = σa + σs, m⁻¹.
    #[inline(always)]
    pub fn sigma_t(&self) -> f64 {
        self.sigma_a + self.sigma_s
    }

    /// Single-scattering albedo σs/σt (0 for a vacuum).
    #[inline(always)]
    pub fn albedo(&self) -> f64 {
        let t = self.sigma_t();
        if t > 0.0 { self.sigma_s / t } else { 0.0 }
    }
}
