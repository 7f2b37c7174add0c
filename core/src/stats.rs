//! Batch statistics: every estimate is the mean over `B` independent, equally sized batches of the
//! per-batch mean, and its standard error is `s/√B` with `s` the sample standard deviation of the
//! batch means. Batches are folded in batch order (Welford's update), so the result does not
//! depend on which thread ran which batch.

use serde::Serialize;

/// Counters of what happened during a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct RunStats {
    pub paths: u64,
    /// Real scattering (and absorption-weighting) events.
    pub scattering_events: u64,
    /// Rejected tentative collisions of delta tracking.
    pub null_collisions: u64,
    /// Paths ended by Russian roulette.
    pub roulette_terminations: u64,
    /// Paths stopped at the event cap or travelling parallel to the layers in a void.
    pub truncated_paths: u64,
    /// Detections with a non-finite weight, path length or frequency (never binned).
    pub non_finite: u64,
    /// The work of the paths, in counted steps (transient: neither persisted nor written; the
    /// pilot of `estimator = "auto"` weighs estimators by it, [`crate::pilot`]).
    #[serde(skip)]
    pub work: Work,
}

/// Counted steps of the paths traced, deterministic (unlike their time): the cost measure of the
/// pilot of `estimator = "auto"` ([`crate::pilot`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Work {
    /// Real and null collisions of camera paths (those of forward paths are
    /// [`RunStats::scattering_events`] and [`RunStats::null_collisions`]).
    pub camera_events: u64,
    /// Shadow rays traced by forward paths (to next-event detectors).
    pub shadow_rays: u64,
    /// Connections traced by camera paths (to the laser, and the beam-lobe flights).
    pub camera_connections: u64,
    /// Scattering vertices whose continuation the importance table guided
    /// ([`crate::transport::guide`]).
    pub guided: u64,
    /// Steps of the ways down and up of forward paths' deterministic unscattered reflections
    /// ([`crate::transport::forward`]'s `unscattered_reflections`): a layer crossed, or a run of
    /// homogeneous layers crossed at once on a way up. Linear in the number of interfaces (`2N`
    /// per path through `N` plain layers); not in the pilots' cost, which was measured without it.
    pub reflection_steps: u64,
}

/// Work of one connection in collision steps (the pilots' measure of cost, [`crate::pilot`]). A
/// connection crosses the layers above its vertex (Fresnel, phase function, optical depth of
/// each) — measured on the shipped LDH scenes (validation/README.md).
pub const CONNECTION_STEPS: f64 = 3.0;
/// The cost of consulting the guide at a vertex ([`crate::transport::guide`]: its cell, and where
/// it acts the candidates), in collision steps: measured on dcs_forearm, where the guide's
/// consults added half the walk's time of the weight windows alone.
pub const GUIDE_STEPS: f64 = 0.5;

impl RunStats {
    /// Work of the forward paths, in collision steps.
    pub fn forward_work(&self) -> f64 {
        (self.scattering_events + self.null_collisions) as f64
            + CONNECTION_STEPS * self.work.shadow_rays as f64
            + GUIDE_STEPS * self.work.guided as f64
    }

    /// Work of the camera paths, in collision steps.
    pub fn camera_work(&self) -> f64 {
        self.work.camera_events as f64 + CONNECTION_STEPS * self.work.camera_connections as f64
    }

    pub fn merge(&mut self, o: &RunStats) {
        self.paths += o.paths;
        self.scattering_events += o.scattering_events;
        self.null_collisions += o.null_collisions;
        self.roulette_terminations += o.roulette_terminations;
        self.truncated_paths += o.truncated_paths;
        self.non_finite += o.non_finite;
        self.work.camera_events += o.work.camera_events;
        self.work.shadow_rays += o.work.shadow_rays;
        self.work.camera_connections += o.work.camera_connections;
        self.work.guided += o.work.guided;
        self.work.reflection_steps += o.work.reflection_steps;
    }
}

/// Groups of batches of the delete-one-group jackknife of the outputs that are not linear in the
/// tallies (ratios, g1, g2, K): batch `b` is also tallied into group `b mod GROUPS`. 16 groups
/// give σ to ±18 % (a χ² of 15 degrees of freedom).
pub const GROUPS: usize = 16;

/// The delete-one-group jackknife variance of an estimate from its replicates `θ_(h)`, each
/// computed without group `h`: `(G − 1)/G Σ_h (θ_(h) − θ̄)²` (Efron & Tibshirani 1993, An
/// Introduction to the Bootstrap, §11.2). NaN with fewer than three replicates.
pub fn jackknife_variance(replicates: impl ExactSizeIterator<Item = f64> + Clone) -> f64 {
    let g = replicates.len() as f64;
    if replicates.len() < 3 {
        return f64::NAN;
    }
    let mean = replicates.clone().sum::<f64>() / g;
    (g - 1.0) / g * replicates.map(|r| (r - mean) * (r - mean)).sum::<f64>()
}

/// Running mean and sum of squared deviations of per-batch means, element by element.
#[derive(Debug, Clone)]
pub struct BatchAccumulator {
    batches: usize,
    mean: Vec<f64>,
    m2: Vec<f64>,
}

impl BatchAccumulator {
    pub fn new(len: usize) -> Self {
        BatchAccumulator { batches: 0, mean: vec![0.0; len], m2: vec![0.0; len] }
    }

    /// Add one batch: `sums` are the batch's totals over its `paths` paths.
    pub fn push(&mut self, sums: &[f64], paths: u64) {
        self.batches += 1;
        let k = self.batches as f64;
        let inv_n = 1.0 / paths as f64;
        for ((m, q), &s) in self.mean.iter_mut().zip(self.m2.iter_mut()).zip(sums) {
            let x = s * inv_n;
            let d = x - *m;
            *m += d / k;
            *q += d * (x - *m);
        }
    }

    /// The state as `(batches, mean, m2)`, for a checkpoint.
    pub fn parts(&self) -> (usize, &[f64], &[f64]) {
        (self.batches, &self.mean, &self.m2)
    }

    /// Rebuild from [`parts`](Self::parts); `None` if `mean` and `m2` differ in length.
    pub fn from_parts(batches: usize, mean: Vec<f64>, m2: Vec<f64>) -> Option<Self> {
        (mean.len() == m2.len()).then_some(BatchAccumulator { batches, mean, m2 })
    }

    pub fn batches(&self) -> usize {
        self.batches
    }

    /// The estimates (mean over batches of the per-path means).
    pub fn mean(&self) -> &[f64] {
        &self.mean
    }

    /// The relative error of the estimates in `range` as one vector: `√(Σ σ_k²)/‖mean‖₂`
    /// (infinite where the mean is zero, and with fewer than two batches).
    pub fn relative_error(&self, range: std::ops::Range<usize>) -> f64 {
        if self.batches < 2 {
            return f64::INFINITY;
        }
        let var: f64 = self.m2[range.clone()].iter().map(|&q| self.variance_of_mean(q)).sum();
        let x2: f64 = self.mean[range].iter().map(|v| v * v).sum();
        if x2 > 0.0 { (var / x2).sqrt() } else { f64::INFINITY }
    }

    /// Variance of the mean of one estimate from its sum of squared deviations `q` (two or more
    /// batches): `q/((B − 1)B)`; NaN stays NaN (an undefined variance set by
    /// [`set_variance`](Self::set_variance)).
    fn variance_of_mean(&self, q: f64) -> f64 {
        let b = self.batches as f64;
        if q.is_nan() { q } else { q.max(0.0) / (b - 1.0) / b }
    }

    /// The estimated variance of the mean of estimate `i` (0 with fewer than two batches).
    pub fn variance(&self, i: usize) -> f64 {
        if self.batches < 2 { 0.0 } else { self.variance_of_mean(self.m2[i]) }
    }

    /// Replace the value of estimate `i` by `value`, keeping its spread over the batches (a
    /// derived output whose run-level value is not the mean of its per-batch values; see
    /// `detect::TallyLayout::finish_run`).
    pub fn set_mean(&mut self, i: usize, value: f64) {
        self.mean[i] = value;
    }

    /// Give estimate `i` the variance of its mean `var` (a derived output whose standard error is
    /// not its per-batch spread, e.g. a jackknife's; with two or more batches).
    pub fn set_variance(&mut self, i: usize, var: f64) {
        let b = self.batches as f64;
        if self.batches >= 2 {
            self.m2[i] = var * (b - 1.0) * b;
        }
    }

    /// Standard error of each estimate (0 with fewer than two batches).
    pub fn stderr(&self) -> Vec<f64> {
        if self.batches < 2 {
            return vec![0.0; self.mean.len()];
        }
        self.m2.iter().map(|&q| self.variance_of_mean(q).sqrt()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn welford_matches_two_pass() {
        let batches = [[1.0, 10.0], [3.0, 10.0], [2.0, 10.0], [6.0, 10.0]];
        let mut acc = BatchAccumulator::new(2);
        for b in &batches {
            acc.push(b, 2);
        }
        // Per-batch means: 0.5, 1.5, 1.0, 3.0 → mean 1.5, sample var 7/6 → se √(7/24).
        assert!((acc.mean()[0] - 1.5).abs() < 1e-15);
        assert!((acc.stderr()[0] - (7.0f64 / 24.0).sqrt()).abs() < 1e-15);
        // A constant estimate has zero error.
        assert_eq!(acc.stderr()[1], 0.0);
    }
}

/// MCNP's check of a tally's largest history scores (the slope of the score density's tail,
/// X-5 Monte Carlo Team 2003, MCNP5 manual vol. I §2.VI (recalled, unchecked)): the density `f(x)` of the
/// paths' scores falls as `x^−s` at its high end; the variance of the tally exists for `s > 3`,
/// and MCNP asks for `s ≥ 3` (it prints 10 for a tail that falls faster than any power). Here
/// `s = 1 + α` with `α` Hill's estimator of the tail index from the largest `k` scores
/// (Hill 1975, Ann. Statist. 3(5)): `α = k / Σ_{i≤k} ln(x_i/x_(k+1))`, `k` = min(200, 5 % of
/// the scores) (MCNP's 201 largest, recalled), at least 20.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TailCheck {
    /// Paths with a non-zero score.
    pub scores: u64,
    /// How many of the largest the slope is fitted to (0: too few scores).
    pub largest: u64,
    /// `s`, capped at 10 (`None` with too few scores).
    pub slope: Option<f64>,
}

/// The largest number of scores the tail slope is fitted to.
pub const TAIL_LARGEST: f64 = 200.0;
/// The smallest.
const TAIL_FEWEST: f64 = 20.0;
/// MCNP's cap of the slope.
pub const TAIL_SLOPE_CAP: f64 = 10.0;

impl TailCheck {
    /// The check of scores binned by size: `counts[b]` scores in bin `b` with `Σ ln x =
    /// logs[b]`, bin `b` spanning `[ln_edge(b), ln_edge(b + 1))` of `ln x`, bins in increasing
    /// size. Within the bin the `k` largest end in, `ln x` is taken as uniform.
    pub fn of(counts: &[f64], logs: &[f64], ln_edge: impl Fn(usize) -> f64) -> Self {
        let n: f64 = counts.iter().sum();
        let k = TAIL_LARGEST.min((0.05 * n).floor());
        if k < TAIL_FEWEST {
            return TailCheck { scores: n as u64, largest: 0, slope: None };
        }
        // Σ ln x over the k largest and ln x_(k+1), from the top bin down.
        let (mut taken, mut sum_ln, mut threshold) = (0.0, 0.0, f64::NAN);
        for b in (0..counts.len()).rev() {
            let c = counts[b];
            if c <= 0.0 {
                continue;
            }
            if taken + c < k {
                taken += c;
                sum_ln += logs[b];
                continue;
            }
            // Part of this bin: its top fraction f, uniform in ln x over [lo, hi).
            let (lo, hi) = (ln_edge(b), ln_edge(b + 1));
            let f = (k - taken) / c;
            threshold = hi - f * (hi - lo);
            sum_ln += (k - taken) * (hi - 0.5 * f * (hi - lo));
            break;
        }
        let excess = sum_ln - k * threshold;
        let slope = if excess > 0.0 { (1.0 + k / excess).min(TAIL_SLOPE_CAP) } else { TAIL_SLOPE_CAP };
        TailCheck { scores: n as u64, largest: k as u64, slope: Some(slope) }
    }
}
