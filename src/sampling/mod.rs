//! Random-number streams and warps: pure maps from uniform numbers to samples.

pub mod rng;
pub mod tabulated;
pub mod warp;

pub use rng::{PathRng, Purpose, StreamKey};
