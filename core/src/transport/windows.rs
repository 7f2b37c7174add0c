//! Weight windows from an importance table (`run.importance = "windows"`; CADIS, Wagner &
//! Haghighat 1998 (recalled, unchecked)): after each scattering
//! event a forward path's weight is held within a window about `R/I*(z, θ)` — `I*` the table's
//! value of its state ([`crate::detect::importance`]), `R` the detector's response per path — so that
//! `weight × importance`, what the path goes on to contribute, stays near `R` for every path:
//! above the window the path is split into copies that share its weight, below it plays Russian
//! roulette up to the window's centre. Both keep every expectation (the path's and its layered
//! twin's, whose weight is the path's times `Λ`): unbiased. The copies walk on after the path, each
//! on a stream of its own drawn from the path's ([`crate::sampling::rng::PathRng::copy`]), and
//! belong to the path's history (its tail score, its batch).

use crate::detect::PathState;
use crate::detect::importance::ImportanceGrid;

use super::guide::Guide;

/// `run.importance`: what the importance table is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Importance {
    /// No table (default).
    #[default]
    Off,
    /// Computed and written: a diagnostic.
    Table,
    /// Computed, written, and the forward walk's weight windows.
    Windows,
    /// The weight windows, and the forward walk's directions guided by the table
    /// ([`super::guide`]).
    Guided,
    /// Computed and written; the windows, or the windows and guided directions, where a pilot
    /// measures that they pay ([`AutoWindows`]).
    Auto,
}

/// What the pilot of `run.importance = "auto"` measured (`crate::pilot`): the squared relative
/// error of the main output × the work (collision steps) of a run without the table's help, with
/// the weight windows, and with the windows and guided directions, on the same paths; the
/// cheapest is chosen, a change only where strictly cheaper.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct AutoWindows {
    pub off: f64,
    pub windows: f64,
    pub guided: f64,
}

impl AutoWindows {
    /// What these figures choose: [`Importance::Off`], [`Importance::Windows`] or
    /// [`Importance::Guided`] (the plainer on a tie; figures that are not numbers never win).
    pub fn choice(self) -> Importance {
        let mut best = (Importance::Off, self.off);
        for (i, f) in [(Importance::Windows, self.windows), (Importance::Guided, self.guided)] {
            if f < best.1 || (best.1.is_nan() && !f.is_nan()) {
                best = (i, f);
            }
        }
        best.0
    }

    /// Whether these figures choose the windows (alone or with guided directions).
    pub fn windows_chosen(self) -> bool {
        self.choice() != Importance::Off
    }
}

/// The ratio of a window's upper bound to its lower (MCNP's default 5 (recalled, unchecked)); its centre is
/// their geometric mean.
pub const WIDTH: f64 = 5.0;
/// Copies of one split, at most.
pub const MAX_SPLIT: u32 = 8;
/// Copies waiting to walk, at most per path (beyond it no more splits: a bound on the work and
/// memory of one path).
pub const MAX_PENDING: usize = 256;

/// The windows of a scene's states.
#[derive(Debug, Clone, PartialEq)]
pub struct Windows {
    pub grid: ImportanceGrid,
    /// Per bin: the window's centre (weight), 0 where the table has no value (no window).
    pub center: Vec<f64>,
    /// The guided directions of `run.importance = "guided"` ([`Guide`]), if any.
    pub guide: Option<Guide>,
}

/// What a window does to a path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Action {
    Keep,
    /// Into this many paths of equal weight (the path and `n − 1` copies).
    Split(u32),
    /// Survive with probability `p`, then with weight `w`.
    Roulette {
        p: f64,
        w: f64,
    },
}

impl Windows {
    /// The windows of a table of values `value` (per bin of `grid`) for a detector of response
    /// `response` (its detected weight per path).
    pub fn new(grid: ImportanceGrid, value: &[f64], response: f64) -> Self {
        let center = value
            .iter()
            .map(|&v| if v > 0.0 && v.is_finite() && response > 0.0 { response / v } else { 0.0 })
            .collect();
        Windows { grid, center, guide: None }
    }

    /// These windows with directions guided by the same table (`value`, of `scene`).
    pub fn guided(self, scene: &crate::medium::Scene, value: &[f64]) -> Self {
        Windows { guide: Some(Guide::new(scene, value)), ..self }
    }

    /// The guide's distribution of the continuation at a vertex where it acts there
    /// ([`Guide::at`]); `None` without a guide.
    #[inline]
    pub fn guide_at<'a>(
        &'a self,
        li: usize,
        pos: glam::DVec3,
        dir_in: glam::DVec3,
        phase: &'a crate::phase::PhaseFunction,
    ) -> Option<super::guide::Directions<'a>> {
        self.guide.as_ref()?.at(&self.grid, li, pos, dir_in, phase)
    }

    /// What the window of the state of `s` in layer `li` does to it.
    #[inline]
    pub fn check(&self, li: usize, s: &PathState) -> Action {
        let c = self.center[self.grid.bin(li, s.pos, s.dir.z)];
        let half = WIDTH.sqrt();
        debug_assert!(c >= 0.0 && c.is_finite(), "a window's centre {c}");
        if c <= 0.0 || s.weight <= 0.0 {
            Action::Keep
        } else if s.weight > c * half {
            let n = ((s.weight / c).round() as u32).clamp(2, MAX_SPLIT);
            // The copies weigh at least the window's bottom (above its top only past MAX_SPLIT).
            debug_assert!(s.weight / f64::from(n) >= c / half, "a split below the window: {} / {n}", s.weight);
            Action::Split(n)
        } else if s.weight < c / half {
            debug_assert!(s.weight / c < 1.0, "a roulette's survival {} ≥ 1", s.weight / c);
            Action::Roulette { p: s.weight / c, w: c }
        } else {
            Action::Keep
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// `auto` takes the cheapest of plain, windows and guided; the plainer on a tie; a figure
    /// that is not a number never wins.
    #[test]
    fn auto_takes_the_cheapest_and_the_plainer_on_a_tie() {
        let a = |off, windows, guided| AutoWindows { off, windows, guided }.choice();
        assert_eq!(a(3.0, 2.0, 1.0), Importance::Guided);
        assert_eq!(a(3.0, 1.0, 2.0), Importance::Windows);
        assert_eq!(a(1.0, 2.0, 3.0), Importance::Off);
        assert_eq!(a(1.0, 1.0, 1.0), Importance::Off);
        assert_eq!(a(2.0, 1.0, 1.0), Importance::Windows);
        assert_eq!(a(1.0, f64::NAN, f64::NAN), Importance::Off);
        assert_eq!(a(f64::NAN, 2.0, f64::NAN), Importance::Windows);
        assert_eq!(a(f64::INFINITY, f64::INFINITY, f64::INFINITY), Importance::Off);
        assert!(!AutoWindows { off: 1.0, windows: 2.0, guided: 3.0 }.windows_chosen());
    }

    /// The window about `R/I`: a path far above it splits (at most [`MAX_SPLIT`]), within it is
    /// kept, below it plays roulette to the centre with survival `w/c` (unbiased: `p·c = w`).
    #[test]
    fn a_window_splits_above_keeps_within_and_plays_roulette_below_and_bounds_the_weights() {
        let grid = ImportanceGrid { layers: vec![(0.0, 1e-5)], lateral: None };
        let n = grid.len();
        let w = Windows::new(grid, &vec![0.5; n], 0.05);
        let at = |weight: f64| PathState::new(DVec3::new(0.0, 0.0, 1e-6), DVec3::Z, weight, 0.0);
        assert_eq!(w.center[0], 0.1);
        assert_eq!(w.check(0, &at(0.1)), Action::Keep);
        assert_eq!(w.check(0, &at(0.3)), Action::Split(3));
        assert_eq!(w.check(0, &at(5.0)), Action::Split(MAX_SPLIT));
        let Action::Roulette { p, w: c } = w.check(0, &at(0.01)) else { panic!("roulette below") };
        assert!((p * c - 0.01).abs() < 1e-15 && c == 0.1);
        // Bounded: whatever the weight up to MAX_SPLIT·√WIDTH times the centre, the paths that
        // leave the window weigh within it (a split's copies share the weight; roulette's
        // survivors weigh the centre).
        for k in 0..=2000 {
            let weight = 0.1 * 10f64.powf(-2.0 + 3.25 * f64::from(k) / 2000.0);
            let out = match w.check(0, &at(weight)) {
                Action::Keep => weight,
                Action::Split(n) => weight / f64::from(n),
                Action::Roulette { w, .. } => w,
            };
            assert!(
                (0.1 / WIDTH.sqrt() - 1e-15..=0.1 * WIDTH.sqrt() + 1e-15).contains(&out),
                "weight {weight:.4e} leaves at {out:.4e}"
            );
        }
        let none = Windows::new(ImportanceGrid { layers: vec![(0.0, 1e-5)], lateral: None }, &vec![f64::NAN; n], 0.05);
        assert_eq!(none.check(0, &at(5.0)), Action::Keep);
    }
}
