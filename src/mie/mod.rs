//! Lorenz–Mie scattering by homogeneous spheres.
mod error;
pub mod solver;

pub use error::MieError;
pub use solver::{Complex64, Efficiencies, MieSolution};
