//! Post-processing of a finished run: what is computed from its outputs (tallies, recorded
//! paths) after the transport, never inside it.
//!
//! * [`speckle`]: single-window speckle spectra of the LDH camera's regions of interest
//!   synthesised from the recorded paths ([`speckle_of`]).
//!
//! The lidar's per-gate moments and fits, which read a finished run's spectra too, are
//! estimators of [`crate::retrieval`] ([`crate::retrieval::retrieve_gate`]).

pub mod speckle;

pub use speckle::{RoiSpeckle, band_sums, speckle_of, synthesize_speckle};
