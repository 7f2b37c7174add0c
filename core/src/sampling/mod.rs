//! Random-number streams and warps: pure maps from uniform numbers to samples.

pub mod discrete;
pub mod rng;
pub mod tabulated;
pub mod warp;

pub use discrete::Discrete;
pub use rng::{PathRng, Purpose, StreamKey};
