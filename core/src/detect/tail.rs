//! The tail check of a camera's regions (MCNP's check of the largest history scores): every
//! path's score into the pixels of the regions' footprints ([`super::image::region_mask`]),
//! pooled, for the intensity image and the M0+ image, binned by size on a log scale, so that the
//! run can fit the slope of the largest scores ([`crate::stats::TailCheck`]).
//!
//! A path's score is what it adds to the pooled footprint pixels over its whole history (all its
//! detections and next-event contributions); with the layered control variate it is the path's
//! difference `f − Λ·f_twin` there (the twin's kernels are a separate, laterally smooth estimate,
//! not a path's score). Paths that add nothing are not binned. The histogram is an internal
//! tally of the run (`NAME.tail_scores`): batch statistics, shards, merges and resumes keep it
//! like any other, so the check is the same whatever the threads.

use crate::output::{Kind, Registry, Slots};
use crate::stats::TailCheck;

/// Bins per decade of a score's absolute value.
pub const PER_DECADE: usize = 10;
/// `log10` of the lower edge of the first bin (smaller scores go into it, larger than the last
/// bin's upper edge into the last).
const LOG10_FIRST: f64 = -40.0;
/// Decades covered: scores from 1e-40 to 1e5 (a path's weight is of order 1 at launch).
const DECADES: usize = 45;
/// Bins per channel.
pub const BINS: usize = PER_DECADE * DECADES;
/// The channels: the intensity image, the M0+ image.
pub const CHANNELS: usize = 2;
/// Channel of the intensity image.
pub const INTENSITY: usize = 0;
/// Channel of the M0+ image.
pub const M0_PLUS: usize = 1;

/// Values per bin: the count, `Σ ln |score|` and `Σ |score|`.
pub const PER_BIN: usize = 3;

/// Where a camera's tail histograms lie: per channel, [`BINS`] triples ([`PER_BIN`]), from slot
/// `start`; the mask of the footprints' pixels (tally order) and the first slots of the
/// images whose pixels the channels pool.
#[derive(Debug, Clone, PartialEq)]
pub struct TailLayout {
    pub start: usize,
    pub mask: Vec<bool>,
    /// The first slot of the intensity image and of the M0+ image (`None`: not recorded).
    pub images: [Option<usize>; CHANNELS],
}

impl TailLayout {
    /// Lay out detector `i`'s (named `name`) histograms from `reg`'s end, for the images at
    /// `images` pooled over the pixels of `mask`.
    pub fn declare(
        i: usize,
        name: &str,
        mask: Vec<bool>,
        images: [Option<usize>; CHANNELS],
        reg: &mut Registry,
    ) -> Self {
        let len = CHANNELS * BINS * PER_BIN;
        let start = reg.take(len);
        reg.declare(super::detector_output(
            i,
            format!("{name}.tail_scores"),
            Kind::Internal,
            Slots::contiguous(start, len),
            vec![CHANNELS, BINS, PER_BIN],
        ));
        TailLayout { start, mask, images }
    }

    /// Whether `pixel` of the image is in the footprints.
    #[inline]
    pub fn covers(&self, pixel: Option<usize>) -> bool {
        pixel.is_some_and(|p| self.mask.get(p).copied().unwrap_or(false))
    }

    /// Bin one path's scores (the non-zero ones) into the batch's tally `acc`.
    pub fn record(&self, acc: &mut [f64], scores: [f64; CHANNELS]) {
        for (c, &s) in scores.iter().enumerate() {
            let a = s.abs();
            if a == 0.0 || !a.is_finite() {
                continue;
            }
            let slot = self.start + PER_BIN * (c * BINS + bin_of(a));
            acc[slot] += 1.0;
            acc[slot + 1] += a.ln();
            acc[slot + 2] += a;
        }
    }

    /// The channel whose histogram pools the image output starting at slot `image`, if any.
    pub fn channel_of(&self, image: usize) -> Option<usize> {
        self.images.iter().position(|&s| s == Some(image))
    }

    /// Channel `c`'s histogram from a run's means `mean` over `paths` paths (per batch times
    /// batches: the means are per path): per bin the count, `Σ ln |score|` and `Σ |score|`.
    pub fn histogram(&self, c: usize, mean: &[f64], paths: f64) -> [Vec<f64>; PER_BIN] {
        let h = &mean[self.start + PER_BIN * c * BINS..self.start + PER_BIN * (c + 1) * BINS];
        // Back from means per path to counts (integers up to rounding: rounded) and sums.
        let column = |k: usize| h.iter().skip(k).step_by(PER_BIN).map(|m| m * paths);
        [column(0).map(f64::round).collect(), column(1).collect(), column(2).collect()]
    }

    /// The tail check of channel `c` from a run's means `mean` over `paths` paths.
    pub fn check(&self, c: usize, mean: &[f64], paths: f64) -> TailCheck {
        let [counts, logs, _] = self.histogram(c, mean, paths);
        TailCheck::of(&counts, &logs, ln_edge)
    }
}

/// The bin of a score of absolute value `a > 0`.
pub fn bin_of(a: f64) -> usize {
    ((a.log10() - LOG10_FIRST) * PER_DECADE as f64).floor().clamp(0.0, (BINS - 1) as f64) as usize
}

/// `ln` of the lower edge of bin `b`.
pub fn ln_edge(b: usize) -> f64 {
    (LOG10_FIRST + b as f64 / PER_DECADE as f64) * std::f64::consts::LN_10
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::{PathRng, Purpose};

    /// The check of `n` scores drawn by `draw` from uniforms, binned as a run bins them.
    fn check_of(n: usize, seed: u64, draw: impl Fn(f64) -> f64) -> TailCheck {
        let mut rng = PathRng::new(seed, Purpose::Test, 0, 0);
        let (mut counts, mut logs) = (vec![0.0; BINS], vec![0.0; BINS]);
        for _ in 0..n {
            let x = draw(rng.uniform());
            let b = bin_of(x);
            counts[b] += 1.0;
            logs[b] += x.ln();
        }
        TailCheck::of(&counts, &logs, ln_edge)
    }

    /// Pareto scores of tail index α (density slope 1 + α) at any scale: the slope fitted to the
    /// largest 200 of 10⁵ is 1 + α within 4σ (Hill's σ ≈ α/√k); with no power tail (exponential
    /// scores) it is far steeper than any of them.
    #[test]
    fn the_slope_of_pareto_scores_is_their_tail_index_plus_one() {
        for (seed, alpha, scale) in [(1, 1.5, 1e-9), (2, 2.0, 1e-3), (3, 4.0, 0.5)] {
            let t = check_of(100_000, seed, |u: f64| scale * (1.0 - u).powf(-1.0 / alpha));
            let s = t.slope.expect("enough scores");
            let sigma = alpha / (t.largest as f64).sqrt();
            assert_eq!((t.scores, t.largest), (100_000, 200));
            assert!(
                (s - (1.0 + alpha)).abs() < 4.0 * sigma,
                "α = {alpha}: slope {s:.3}, expected {} ± {sigma:.3}",
                1.0 + alpha
            );
        }
        let t = check_of(100_000, 4, |u: f64| 1e-6 * -(1.0 - u).ln());
        assert!(t.slope.unwrap() > 5.5, "exponential scores: slope {:?}", t.slope);
    }

    /// Fewer than 400 scores (20 in their top 5 %) give no slope.
    #[test]
    fn too_few_scores_give_no_slope() {
        let t = check_of(399, 5, |u: f64| 1.0 / (1.0 - u));
        assert_eq!((t.scores, t.largest, t.slope), (399, 0, None));
        assert!(check_of(400, 5, |u: f64| 1.0 / (1.0 - u)).slope.is_some());
    }
}
