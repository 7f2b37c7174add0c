//! What a scene's walk is compiled for: the features it uses, read once per batch and mapped to
//! the random walk monomorphised for them (as pbrt-v4's integrator owns its options).
//!
//! The walk ([`super::walk`]) is generic over seven features: the Doppler term (`DOPPLER`),
//! the optical path length (`LENGTH`), next-event estimation (`NEE`), the volume tally
//! (`VOLUME`), the time gate (`GATE`), the side faces of a box phantom (`LATERAL`); a camera
//! path is a walk of its own (`CAMERA`). [`Features::forward_paths`] and
//! [`Features::camera_paths`] are the only places that turn a run's flags into these type
//! parameters (48 forward walks and 4 camera walks are compiled).
//!
//! Measured (issue 34, `validation/README.md`): the Doppler term, the volume tally and the time
//! gate read at run time instead (6 forward walks, 2 camera walks) cost +12.7 % instructions on
//! the vdH slab and +3.3 % on `configs/default.toml` (callgrind, whole process): the unused
//! hooks in the event loop cost registers. They stay type parameters.

use crate::detect::Recorder;
use crate::sampling::StreamKey;

use super::camera::CameraTarget;
use super::walk::{WalkContext, trace_camera_path, trace_path};

/// Paths between two calls of the batch loop's `tick` ([`Features::forward_paths`]): progress
/// reports and checks for cancellation.
pub const PATHS_PER_TICK: u64 = 4096;

/// The features a run's walks use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Features {
    /// Something moves: the Doppler term and the Brownian line width at every scattering event.
    pub doppler: bool,
    /// The optical path length is tracked (a chirp, range gates, a time axis, a time gate).
    pub length: bool,
    /// Shadow rays toward next-event detectors at every real collision of a forward path, or the
    /// layered twin's bookkeeping (`WalkContext::twin`), which lives in the same collision
    /// (without targets it traces no shadow ray).
    pub nee: bool,
    /// The volume tally (`[volume]`) is scored along forward paths.
    pub volume: bool,
    /// The time gate (`run.time_gate_ns`) cuts forward paths (only with `length`).
    pub gate: bool,
    /// The layers end at the side faces of a box phantom (`[lateral]`; never with `nee`).
    pub lateral: bool,
}

impl Features {
    /// The features of walks through `ctx`, `length` telling whether the optical path length is
    /// needed (which only the experiment's detectors and source know).
    pub fn new(ctx: &WalkContext, length: bool) -> Self {
        Features {
            doppler: ctx.scene.is_moving(),
            length,
            nee: !ctx.nee.is_empty() || ctx.twin,
            volume: ctx.volume.is_some(),
            gate: length && ctx.settings.gate.is_some(),
            lateral: ctx.scene.lateral.is_some(),
        }
    }

    /// Trace the forward paths `0..paths` of `key` through `ctx` into `rec`, calling `tick` after
    /// every [`PATHS_PER_TICK`] of them; `tick` returning `true` stops the batch (cancelled), and
    /// so does this function's return value.
    ///
    /// Inlined into the batch loop with its walks, as they were before this dispatch moved here:
    /// with [`forward`](Self::forward) outlined, the walks read the context and the recorder
    /// through the caller's memory (measured: +1.5 % instructions on the vdH slab).
    #[inline(always)]
    pub fn forward_paths(
        self,
        ctx: &WalkContext,
        rec: &mut Recorder,
        key: &StreamKey,
        paths: u64,
        mut tick: impl FnMut() -> bool,
    ) -> bool {
        let t = &mut tick;
        match (self.doppler, self.length) {
            (false, false) => self.forward::<false, false>(ctx, rec, key, paths, t),
            (true, false) => self.forward::<true, false>(ctx, rec, key, paths, t),
            (false, true) => self.forward::<false, true>(ctx, rec, key, paths, t),
            (true, true) => self.forward::<true, true>(ctx, rec, key, paths, t),
        }
    }

    /// The camera paths of `pixel` of `cam`: `spp` of them, path `k` drawing from the stream
    /// `pixel·spp + k` of `key`, each weighing `batch_weight` in the batch.
    #[allow(clippy::too_many_arguments)]
    pub fn camera_paths(
        self,
        ctx: &WalkContext,
        cam: &CameraTarget,
        pixel: usize,
        spp: u64,
        batch_weight: f64,
        rec: &mut Recorder,
        key: &StreamKey,
    ) {
        let f = match (self.doppler, self.length) {
            (false, false) => camera_pixel::<false, false>,
            (true, false) => camera_pixel::<true, false>,
            (false, true) => camera_pixel::<false, true>,
            (true, true) => camera_pixel::<true, true>,
        };
        f(ctx, cam, pixel, spp, batch_weight, rec, key);
    }

    /// [`forward_paths`](Self::forward_paths) for one kind of scene: one branch per batch on the
    /// remaining features, so that a walk without them runs the loop it ran before there were
    /// any.
    #[inline(always)]
    fn forward<const DOPPLER: bool, const LENGTH: bool>(
        self,
        ctx: &WalkContext,
        rec: &mut Recorder,
        key: &StreamKey,
        paths: u64,
        tick: &mut impl FnMut() -> bool,
    ) -> bool {
        if self.lateral {
            return lateral_paths::<DOPPLER, LENGTH>(ctx, rec, key, paths, tick);
        }
        match (self.nee, self.volume, self.gate) {
            (false, false, false) => {
                paths_loop::<DOPPLER, LENGTH, false, false, false, false>(ctx, rec, key, paths, tick)
            }
            (false, true, false) => {
                paths_loop::<DOPPLER, LENGTH, false, true, false, false>(ctx, rec, key, paths, tick)
            }
            (false, false, true) => {
                paths_loop::<DOPPLER, LENGTH, false, false, true, false>(ctx, rec, key, paths, tick)
            }
            (false, true, true) => paths_loop::<DOPPLER, LENGTH, false, true, true, false>(ctx, rec, key, paths, tick),
            (true, false, false) => {
                paths_loop::<DOPPLER, LENGTH, true, false, false, false>(ctx, rec, key, paths, tick)
            }
            (true, true, false) => paths_loop::<DOPPLER, LENGTH, true, true, false, false>(ctx, rec, key, paths, tick),
            (true, false, true) => paths_loop::<DOPPLER, LENGTH, true, false, true, false>(ctx, rec, key, paths, tick),
            (true, true, true) => paths_loop::<DOPPLER, LENGTH, true, true, true, false>(ctx, rec, key, paths, tick),
        }
    }
}

/// The forward paths in a box phantom (`[lateral]`; resolve refuses next-event targets there).
/// Outlined: inlined beside the walks without it, its walks changed the register allocation of
/// theirs (measured: +0.23 % instructions on the vdH slab without `[lateral]`).
#[inline(never)]
fn lateral_paths<const DOPPLER: bool, const LENGTH: bool>(
    ctx: &WalkContext,
    rec: &mut Recorder,
    key: &StreamKey,
    paths: u64,
    tick: &mut impl FnMut() -> bool,
) -> bool {
    let volume = ctx.volume.is_some();
    let gate = LENGTH && ctx.settings.gate.is_some();
    match (volume, gate) {
        (false, false) => paths_loop::<DOPPLER, LENGTH, false, false, false, true>(ctx, rec, key, paths, tick),
        (true, false) => paths_loop::<DOPPLER, LENGTH, false, true, false, true>(ctx, rec, key, paths, tick),
        (false, true) => paths_loop::<DOPPLER, LENGTH, false, false, true, true>(ctx, rec, key, paths, tick),
        (true, true) => paths_loop::<DOPPLER, LENGTH, false, true, true, true>(ctx, rec, key, paths, tick),
    }
}

/// The batch loop of forward paths of one monomorphised walk.
#[inline(always)]
fn paths_loop<
    const DOPPLER: bool,
    const LENGTH: bool,
    const NEE: bool,
    const VOLUME: bool,
    const GATE: bool,
    const LATERAL: bool,
>(
    ctx: &WalkContext,
    rec: &mut Recorder,
    key: &StreamKey,
    paths: u64,
    tick: &mut impl FnMut() -> bool,
) -> bool {
    for i in 0..paths {
        let mut rng = key.path(i);
        trace_path::<DOPPLER, LENGTH, NEE, VOLUME, GATE, LATERAL>(ctx, rec, &mut rng);
        rec.end_path();
        if (i + 1) % PATHS_PER_TICK == 0 && tick() {
            return true;
        }
    }
    false
}

/// [`Features::camera_paths`] for one kind of scene.
#[allow(clippy::too_many_arguments)]
fn camera_pixel<const DOPPLER: bool, const LENGTH: bool>(
    ctx: &WalkContext,
    cam: &CameraTarget,
    pixel: usize,
    spp: u64,
    batch_weight: f64,
    rec: &mut Recorder,
    key: &StreamKey,
) {
    for k in 0..spp {
        let mut rng = key.path(pixel as u64 * spp + k);
        trace_camera_path::<DOPPLER, LENGTH>(ctx, cam, pixel, batch_weight, rec, &mut rng);
        rec.end_path();
    }
}
