//! Post-processing of a finished run: what is computed from its outputs (tallies, recorded
//! paths) after the transport, never inside it.
//!
//! * [`speckle`]: single-window speckle spectra of the LDH camera's regions of interest
//!   synthesised from the recorded paths ([`speckle_of`]), and single-window speckled M0± in
//!   every pixel from the per-pixel spectra ([`pixel_speckle_of`]).
//!
//! * [`finished`]: the typed finished run ([`Finished`]) the writers write: the checks and all of
//!   the post-processing below, run once, before any file is opened.
//!
//! * [`warnings`]: what the run could not get right (power off a spectrum's axis, aliased lidar
//!   echoes, truncated paths, non-finite detections), for the manifest and the command line.
//!
//! The lidar's per-gate moments and fits, which read a finished run's spectra too, are
//! estimators of [`crate::retrieval`] ([`crate::retrieval::retrieve_gate`]), run over the gates by
//! [`retrieve_gates`].

pub mod finished;
pub mod speckle;
pub mod warnings;

pub use finished::{Finished, retrieve_gates};

pub use speckle::{
    PIXEL_STREAM, PixelSpeckle, RoiSpeckle, band_sums, pixel_speckle_of, speckle_of, synthesize_pixel_speckle,
    synthesize_speckle,
};
pub use warnings::{Warning, warnings};
