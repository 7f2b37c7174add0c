//! What a forward path carries besides its [`PathState`] ([`ForwardState`]): the state the
//! forward estimator (`forward.rs`), the layered twin (`twin.rs`) and the weight windows
//! (`steering.rs`) share, in a file of its own so that each imports it and none imports another
//! for it.

use crate::detect::PathState;
use crate::detect::twin::TwinPath;
use crate::sampling::PathRng;

/// What a forward path carries besides its [`PathState`]: what its escape is balanced against the
/// shadow rays with, its layered twin and where the twin parted from it, and the copies its weight
/// windows split off. (Not generic: the outlined collision `forward::collide_nee` and the twin's and
/// windows' functions take it as it is, compiled once per kind of walk.)
#[derive(Default)]
pub(super) struct ForwardState {
    /// The density of the path's last direction at its last vertex (a particle's phase function,
    /// a rough face's or a surface's sampling density), over `n_k² |cos θ_k|` there: a direct
    /// escape weighs itself against the shadow rays with it ([`crate::detect::Recorder::escape`]). `None` before
    /// the first vertex, after a reflection at a smooth face and after a mirror's (no shadow ray
    /// takes those ways), and in a walk without next-event estimation.
    pub direct: Option<f64>,
    /// The path's layered twin for the control variate (`None`: no control variate, or the twin
    /// has parted, [`super::twin`]).
    pub twin: Option<TwinPath>,
    /// Where the twin parted from the path, to walk on once the path has ended.
    pub split: Option<Split>,
    /// Copies of the path split off by its weight windows, waiting to walk on after it
    /// ([`super::steering::split`]).
    pub copies: Vec<Pending>,
    /// The path's harmonic Doppler components `F_k` in a scene whose flows pulse (empty
    /// otherwise, [`crate::flow::pulse`]).
    pub pulse: Vec<num_complex::Complex64>,
}

/// Where a forward path's layered twin parts from it: a collision of the path in a region with
/// `Λ` beyond [`super::twin::TWIN_BAND`], which the twin makes in its layer's filling medium
/// (with the weight and Doppler state `s`: the path's arriving there times `Λ` and the collision
/// densities' ratio) and walks on from in the twin's scene with a copy of the path's generator
/// (`forward::twin_walk`; common random numbers, each walk a proper sample of its own). Until then the twin shares the
/// path; after, the path scores without a twin and the twin's walk scores only as the twin (its
/// share out of the pixels it meets, into the kernels).
#[derive(Clone)]
pub(super) struct Split {
    pub s: PathState,
    pub li: usize,
    pub twin: TwinPath,
    pub rng: PathRng,
    /// Parted in a flight through a density region where the path collided and the twin did not
    /// ([`super::tracking::coupled_flight`]): the twin flies on from `s` (else it collides there).
    pub flying: bool,
    /// The path's [`ForwardState::direct`] there, which an escape of the twin flying on is
    /// balanced with.
    pub direct: Option<f64>,
}

/// A copy of a forward path made by a weight window's split ([`super::steering::split`]): its
/// state, layer, own stream and what it carries (its layered twin, [`ForwardState::direct`]), to walk on from
/// after the path.
#[derive(Clone)]
pub(super) struct Pending {
    pub s: PathState,
    pub li: usize,
    pub rng: PathRng,
    pub twin: Option<TwinPath>,
    pub direct: Option<f64>,
}
