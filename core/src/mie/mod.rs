//! Lorenz–Mie scattering by homogeneous spheres, and the bulk optics of particle ensembles.
//!
//! * [`MieSolution`] — the series coefficients of one sphere, its efficiencies, amplitudes and
//!   phase function ([`solver`] documents the conventions and the numerics).
//! * [`ensemble_optics`] — σs, σa, g, backscatter and the tabulated phase function of a size
//!   distribution (log-normal, modified gamma, Marshall–Palmer rain, monodisperse), optionally
//!   with Twersky's packing correction ([`ensemble`]).
//! * [`angle_grid`] — a θ grid dense near forward for tabulating phase functions.
//!
//! Units are SI (lengths in metres, coefficients in m⁻¹, phase functions in sr⁻¹ normalised over
//! the sphere). The relative index is written `m = n − ik` with `k ≥ 0` absorbing; complex
//! coefficients and amplitudes are returned in the Bohren & Huffman convention (`e^{−iωt}`).

pub mod ensemble;
mod error;
mod limits;
mod quadrature;
pub mod solver;

pub use ensemble::{
    Concentration, DEFAULT_SIZE_POINTS, EnsembleOptics, EnsembleSpec, Packing, SizeDistribution, angle_grid,
    ensemble_optics, with_cache,
};
pub use error::MieError;
pub use quadrature::gauss_legendre;
pub use solver::{Complex64, Efficiencies, MieSolution};
