//! Lorenz–Mie scattering by homogeneous spheres ([`MieSolution`]) and by ensembles of them with a
//! size distribution ([`ensemble_optics`]).
mod ensemble;
mod error;
pub mod solver;

pub use ensemble::{
    Concentration, EnsembleOptics, EnsembleSpec, Packing, SizeDistribution, angle_grid, ensemble_optics,
};
pub use error::MieError;
pub use solver::{Complex64, Efficiencies, MieSolution};
