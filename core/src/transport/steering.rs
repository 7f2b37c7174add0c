//! Steering of forward paths: the weight windows of `run.importance = "windows"`
//! ([`super::windows`]: split a path whose weight is above its window, play roulette below) and the
//! guide ([`super::guide`]: a continuation resampled from several phase-function draws on the
//! importance table's values). Called at the end of a forward path's collision.

use glam::DVec3;

use crate::detect::{PathState, Recorder};
use crate::sampling::PathRng;

use super::carried::{ForwardState, Pending};
use super::event::deflect;
use super::walk::{End, WalkContext};
use super::windows::{Action, MAX_PENDING, Windows};

/// The weight window of `s` after a scattering event in layer `li` (`run.importance =
/// "windows"`, [`super::windows`]): split it, play roulette (`Some`: it has ended) or keep it.
/// Nothing without windows: the test is inlined into every collision, the windows' work is not
/// (measured: an outlined call at every collision that returned at once cost the vdH slab 7–12
/// instructions per collision).
#[inline(always)]
pub(super) fn window(
    ctx: &WalkContext,
    rec: &mut Recorder,
    st: &mut ForwardState,
    s: &mut PathState,
    li: usize,
    rng: &mut PathRng,
) -> Option<End> {
    match ctx.windows {
        None => None,
        Some(w) => apply_window(w, rec, st, s, li, rng),
    }
}

/// [`window`] with the run's windows `w`.
#[inline(never)]
fn apply_window(
    w: &Windows,
    rec: &mut Recorder,
    st: &mut ForwardState,
    s: &mut PathState,
    li: usize,
    rng: &mut PathRng,
) -> Option<End> {
    if w.guide.is_some() {
        rec.stats.work.guided += 1;
    }
    match w.check(li, s) {
        Action::Keep => {}
        Action::Split(n) => split(st, s, li, n, rng.split_key()),
        Action::Roulette { p, w } => {
            if rng.uniform() >= p {
                return Some(End::Roulette);
            }
            s.weight = w;
        }
    }
    None
}

/// Split `s` (in layer `li`) into `n` paths of equal weight ([`super::windows`]): `s` goes on
/// with its share, `n − 1` copies wait in `st` to walk on after it, copy `k` on the stream
/// `PathRng::copy(key, k)`, each with what the path carries as it is now (its layered twin, its
/// escape's balance). No split once [`MAX_PENDING`] copies wait.
#[cold]
#[inline(never)]
pub(super) fn split(st: &mut ForwardState, s: &mut PathState, li: usize, n: u32, key: u64) {
    if st.copies.len() + n as usize > MAX_PENDING {
        return;
    }
    s.weight /= f64::from(n);
    for k in 1..n {
        let rng = PathRng::copy(key, u64::from(k));
        st.copies.push(Pending { s: *s, li, rng, twin: st.twin, direct: st.direct });
    }
}

/// The continuation of a forward path `s` from a scatterer of phase function `phase` in layer
/// `li`: from the guide's distribution at the vertex where the weight windows have a guide
/// ([`continue_guided`]), else the phase function's draw. Returns `(cos θ, out, dir − out)` of
/// the deflection.
#[inline(always)]
pub(super) fn continuation(
    windows: Option<&Windows>,
    li: usize,
    s: &mut PathState,
    phase: &crate::phase::PhaseFunction,
    rng: &mut PathRng,
) -> (f64, DVec3, DVec3) {
    match windows {
        Some(w) if w.guide.is_some() => {
            let guided = w.guide_at(li, s.pos, s.dir, phase);
            continue_guided(s, phase, guided, rng)
        }
        _ => {
            let (d, out, delta) = deflect(s.dir, phase, rng);
            (d.cos, out, delta)
        }
    }
}

/// The continuation of `s` from a scatterer of phase function `phase` where the guide acts
/// (`guided`, [`super::guide::Directions`]): one of several directions drawn from the phase
/// function, resampled on their importance, and the weight times the resampling's factor; the
/// phase function's draw alone (weight unchanged) where it does not (`None`).
#[inline(never)]
fn continue_guided(
    s: &mut PathState,
    phase: &crate::phase::PhaseFunction,
    guided: Option<super::guide::Directions>,
    rng: &mut PathRng,
) -> (f64, DVec3, DVec3) {
    let Some(guided) = guided else {
        let (d, out, delta) = deflect(s.dir, phase, rng);
        return (d.cos, out, delta);
    };
    let (chosen, factor) = guided.sample(rng);
    s.weight *= factor;
    chosen
}
