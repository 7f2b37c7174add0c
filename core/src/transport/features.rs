//! What a scene's walk is compiled for: the features it uses, read once per batch and mapped to
//! the random walk monomorphised for them (as pbrt-v4's integrator owns its options).
//!
//! The walk ([`super::walk`]) is generic over its estimator, a type whose consts say what the
//! path tracks: the forward estimator ([`super::forward::Forward`]) over six features, the Doppler
//! term (`DOPPLER`), the optical path length (`LENGTH`), next-event estimation and the layered twin
//! (`NEE`), the volume tally (`VOLUME`), the time gate (`GATE`, only with `LENGTH`), the side faces
//! of a box phantom (`LATERAL`, never with `NEE`); camera paths ([`super::adjoint::Adjoint`]) over
//! the first two. [`Features::forward_paths`] and [`Features::camera_paths`] are the only places
//! that turn a run's flags into these types: 36 forward walks (and 2 carrying a pulsatile scene's
//! harmonics, `PULSE`), 4 camera walks and 6 walks of a
//! parted twin are compiled (issue 53: 48 forward walks, each inlined twice, before; a gate without
//! the length was compiled though never run).
//!
//! Measured (issue 34, `validation/README.md`): the Doppler term, the volume tally and the time
//! gate read at run time instead (6 forward walks, 2 camera walks) cost +12.7 % instructions on
//! the vdH slab and +3.3 % on `configs/default.toml` (callgrind, whole process): the unused
//! hooks in the event loop cost registers. They stay type parameters.

use crate::detect::Recorder;
use crate::sampling::StreamKey;

use super::adjoint::trace_camera_path;
use super::camera::CameraTarget;
use super::forward::Forward;
use super::walk::WalkContext;

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
    /// The scene's flows pulse (`Scene::cycle`): forward paths carry their harmonic Doppler
    /// components ([`crate::flow::pulse`]); resolve refuses the volume tally, the time gate, a
    /// box phantom, the control variate and the weight windows with it, and its walk always has
    /// `NEE`.
    pub pulse: bool,
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
            pulse: ctx.scene.cycle.is_some(),
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
        if self.pulse {
            return pulse_paths(self.length, ctx, rec, key, paths, t);
        }
        // A time gate comes only with the optical path length (`Features::new`): no walk is
        // compiled for a gate without it.
        match (self.doppler, self.length, self.gate) {
            (false, false, _) => self.forward::<false, false, false>(ctx, rec, key, paths, t),
            (true, false, _) => self.forward::<true, false, false>(ctx, rec, key, paths, t),
            (false, true, false) => self.forward::<false, true, false>(ctx, rec, key, paths, t),
            (true, true, false) => self.forward::<true, true, false>(ctx, rec, key, paths, t),
            (false, true, true) => self.forward::<false, true, true>(ctx, rec, key, paths, t),
            (true, true, true) => self.forward::<true, true, true>(ctx, rec, key, paths, t),
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
        // The light field ([`super::field`]) is refused where the path length is tracked.
        let f = match (self.doppler, self.length, ctx.field.is_some()) {
            (false, false, false) => camera_pixel::<false, false, false>,
            (true, false, false) => camera_pixel::<true, false, false>,
            (false, true, _) => camera_pixel::<false, true, false>,
            (true, true, _) => camera_pixel::<true, true, false>,
            (false, false, true) => camera_pixel::<false, false, true>,
            (true, false, true) => camera_pixel::<true, false, true>,
        };
        f(ctx, cam, pixel, spp, batch_weight, rec, key);
    }

    /// [`forward_paths`](Self::forward_paths) for one kind of scene: one branch per batch on the
    /// remaining features, so that a walk without them runs the loop it ran before there were
    /// any.
    #[inline(always)]
    fn forward<const DOPPLER: bool, const LENGTH: bool, const GATE: bool>(
        self,
        ctx: &WalkContext,
        rec: &mut Recorder,
        key: &StreamKey,
        paths: u64,
        tick: &mut impl FnMut() -> bool,
    ) -> bool {
        if self.lateral {
            return lateral_paths::<DOPPLER, LENGTH, GATE>(ctx, rec, key, paths, tick);
        }
        match (self.nee, self.volume) {
            (false, false) => {
                paths_loop::<DOPPLER, LENGTH, false, false, GATE, false, false>(ctx, rec, key, paths, tick)
            }
            (false, true) => paths_loop::<DOPPLER, LENGTH, false, true, GATE, false, false>(ctx, rec, key, paths, tick),
            (true, false) => paths_loop::<DOPPLER, LENGTH, true, false, GATE, false, false>(ctx, rec, key, paths, tick),
            (true, true) => paths_loop::<DOPPLER, LENGTH, true, true, GATE, false, false>(ctx, rec, key, paths, tick),
        }
    }
}

/// The forward paths in a box phantom (`[lateral]`; resolve refuses next-event targets there).
/// Outlined: inlined beside the walks without it, its walks changed the register allocation of
/// theirs (measured: +0.23 % instructions on the vdH slab without `[lateral]`).
#[inline(never)]
fn lateral_paths<const DOPPLER: bool, const LENGTH: bool, const GATE: bool>(
    ctx: &WalkContext,
    rec: &mut Recorder,
    key: &StreamKey,
    paths: u64,
    tick: &mut impl FnMut() -> bool,
) -> bool {
    if ctx.volume.is_some() {
        paths_loop::<DOPPLER, LENGTH, false, true, GATE, true, false>(ctx, rec, key, paths, tick)
    } else {
        paths_loop::<DOPPLER, LENGTH, false, false, GATE, true, false>(ctx, rec, key, paths, tick)
    }
}

/// The forward paths of a scene whose flows pulse, carrying their harmonics (outlined: the walks
/// of the other scenes are compiled as before).
#[inline(never)]
fn pulse_paths(
    length: bool,
    ctx: &WalkContext,
    rec: &mut Recorder,
    key: &StreamKey,
    paths: u64,
    tick: &mut impl FnMut() -> bool,
) -> bool {
    if length {
        pulse_loop::<true>(ctx, rec, key, paths, tick)
    } else {
        pulse_loop::<false>(ctx, rec, key, paths, tick)
    }
}

#[inline(always)]
fn pulse_loop<const LENGTH: bool>(
    ctx: &WalkContext,
    rec: &mut Recorder,
    key: &StreamKey,
    paths: u64,
    tick: &mut impl FnMut() -> bool,
) -> bool {
    rec.pulse = vec![num_complex::Complex64::ZERO; ctx.scene.cycle.map_or(0, |c| c.harmonics)];
    paths_loop::<true, LENGTH, true, false, false, false, true>(ctx, rec, key, paths, tick)
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
    const PULSE: bool,
>(
    ctx: &WalkContext,
    rec: &mut Recorder,
    key: &StreamKey,
    paths: u64,
    tick: &mut impl FnMut() -> bool,
) -> bool {
    let mut estimator = Forward::<DOPPLER, LENGTH, NEE, VOLUME, GATE, LATERAL, PULSE>::new();
    for i in 0..paths {
        let mut rng = key.path(i);
        estimator.trace_path(ctx, rec, &mut rng);
        rec.end_path();
        if (i + 1) % PATHS_PER_TICK == 0 && tick() {
            return true;
        }
    }
    false
}

/// [`Features::camera_paths`] for one kind of scene.
#[allow(clippy::too_many_arguments)]
fn camera_pixel<const DOPPLER: bool, const LENGTH: bool, const FIELD: bool>(
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
        trace_camera_path::<DOPPLER, LENGTH, FIELD>(ctx, cam, pixel, batch_weight, rec, &mut rng);
        rec.end_path();
    }
}
