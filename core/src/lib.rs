//! # ohd-core — the physics of `ohd`
//!
//! The lower layers of `ohd` (its crate documentation states the conventions and draws the
//! layers): foundations (errors, numerics, random-number streams, statistics, spectra, phase
//! functions, surfaces, Mie scattering, the output registry, retrievals), the scene (media, flows,
//! the laser, input file formats), recording (detectors), transport (the walk and its estimators)
//! and runs (an experiment's batches, its pilots, post-processing, scans, convergence, and the
//! resolved experiment described in human units). The `ohd`
//! crate re-exports every module here under the same name and adds the configuration, the outputs
//! and the command line.
//!
//! Why a crate of its own: a release build optimises each crate as one codegen unit (more units
//! move the walk's inlining), and LLVM on one unit runs on one core. As two crates, this one and
//! `ohd`'s configuration (serde's deserialisers), outputs (plotters) and command line (clap) are
//! optimised at the same time on two cores, before and in the binary's thin LTO.

pub mod converge;
pub mod describe;
pub mod detect;
pub mod error;
pub mod experiment;
pub mod flow;
pub mod io;
pub mod medium;
pub mod mie;
pub mod numeric;
pub mod output;
pub mod phase;
pub mod pilot;
pub mod post;
pub mod retrieval;
pub mod sampling;
pub mod scan;
pub mod source;
pub mod spectrum;
pub mod stats;
pub mod surface;
pub mod sys;
pub mod transport;

/// Speed of light in vacuum, m/s (exact, SI).
pub const SPEED_OF_LIGHT: f64 = 299_792_458.0;
