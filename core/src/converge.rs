//! Error against run time: a run's named outputs, the error of each, and the convergence study of
//! `ohd converge`.
//!
//! Every estimate carries the standard error of its mean over the run's batches
//! ([`crate::stats`]). Here those per-slot errors become one error per *output*:
//!
//! * a **scalar** (a reflectance, a detector's power): the absolute error `|x − r|` against a
//!   reference `r`, and the run's own estimate of it, `σ`;
//! * a **spectrum or image**: the relative RMS error over its bins or pixels, `‖x − r‖₂ / ‖r‖₂`,
//!   and the run's own estimate `√(Σ σ_k²) / ‖r‖₂` (the expected value of the former when the
//!   reference is exact, since `E‖x − r‖² = Σ σ_k²` for an unbiased `x`).
//!
//! Without a reference a run estimates its relative error from itself: `σ/|x|` or
//! `√(Σ σ_k²)/‖x‖₂` ([`NamedOutput::relative_error`]); `ohd run --target-error` stops on it.
//!
//! [`study`] runs a ladder of sample counts with independent seeds, measures each output's error
//! against an analytic reference the configuration declares (`[reference]`), a reference run read
//! from disk, or a reference run made on the fly with more paths (and its own seed), then fits
//! `log error = a + b log seconds` per output and extrapolates the time to 1 % and 0.1 %.
//! With a noisy reference, the expected squared error is the sum of both runs' variances, so the
//! agreement check compares the measured error with `√(σ² + σ_ref²)`.

use crate::experiment::{Decisions, Experiment, Progress, RunOutput};
pub use crate::experiment::{Target, TargetOutcome};
use crate::stats::BatchAccumulator;

/// One named output of a run (declared in the [`crate::output::Registry`]).
pub use crate::output::Output as NamedOutput;

fn norm(x: impl Iterator<Item = f64>) -> f64 {
    x.map(|v| v * v).sum::<f64>().sqrt()
}

/// The error metrics of an output.
impl NamedOutput {
    /// The run's estimate of its own relative error: `σ/|x|` for a scalar, `√(Σσ²)/‖x‖₂`
    /// otherwise. Infinite when the output is zero.
    pub fn relative_error(&self, acc: &BatchAccumulator) -> f64 {
        acc.relative_error(self.range())
    }

    /// The measured error of `mean` against `reference` (absolute for a scalar, relative RMS
    /// otherwise) and the run's own estimate of it from `stderr`, in the same metric.
    /// `None` when the reference is zero everywhere (no relative error is defined).
    pub fn error_against(&self, mean: &[f64], stderr: &[f64], reference: &[f64]) -> Option<(f64, f64)> {
        let x = &mean[self.range()];
        let s = norm(stderr[self.range()].iter().copied());
        let d = norm(x.iter().zip(reference).map(|(a, b)| a - b));
        if self.is_scalar() {
            return Some((d, s));
        }
        let r = norm(reference.iter().copied());
        (r > 0.0).then(|| (d / r, s / r))
    }

    /// The error in `error_against`'s metric turned relative (a scalar's divided by `|r|`).
    pub fn to_relative(&self, error: f64, reference: &[f64]) -> f64 {
        if self.is_scalar() { error / reference[0].abs() } else { error }
    }

    /// The output's values and standard errors, sliced from the accumulator of a run.
    pub fn slice<'a>(&self, mean: &'a [f64], stderr: &'a [f64]) -> (&'a [f64], &'a [f64]) {
        (&mean[self.range()], &stderr[self.range()])
    }
}

/// An output's reference for the convergence study: values in the tally's convention and their
/// standard errors (zero for an analytic reference).
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    pub values: Vec<f64>,
    pub stderr: Vec<f64>,
    /// `analytic`, `run` (made on the fly) or `directory`.
    pub kind: &'static str,
}

impl Reference {
    /// What makes this reference of `output` unusable, if anything: a value or standard error
    /// that is not a finite number, or values or standard errors whose squares sum past the
    /// largest `f64` (the study's norms `‖r‖`, `‖σ_r‖` would be infinite: magnitudes from about
    /// 1.3·10¹⁵⁴ up). A run of ohd never writes one (issue 52: a tampered directory's NaN, ∞ or
    /// 1e308 was taken, and its output skipped as "deterministic").
    pub fn defect(&self, output: &NamedOutput) -> Option<String> {
        for (what, v) in [("value", &self.values), ("standard error", &self.stderr)] {
            if let Some((k, x)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                return Some(format!("{} holds the {what} {x} at index {k}", output.name));
            }
            if !norm(v.iter().copied()).is_finite() {
                return Some(format!(
                    "{}'s {what}s are too large: their squares sum past the largest number",
                    output.name
                ));
            }
        }
        None
    }

    /// The reference's own error in `output`'s metric: `σ_r` for a scalar, `‖σ_r‖/‖r‖` otherwise.
    pub fn error(&self, output: &NamedOutput) -> f64 {
        let s = norm(self.stderr.iter().copied());
        if output.is_scalar() {
            return s;
        }
        let r = norm(self.values.iter().copied());
        if r > 0.0 { s / r } else { 0.0 }
    }
}

/// How `ohd converge` chooses its ladder.
#[derive(Debug, Clone, PartialEq)]
pub struct LadderOptions {
    /// Paths of the largest rung; `None` = from the time budget.
    pub top_samples: Option<u64>,
    /// Wall-time budget of the whole study (the ladder and a reference run made on the fly), s.
    pub budget_seconds: f64,
    /// Number of rungs, each twice the paths of the one before.
    pub rungs: usize,
    /// Paths of a reference run made on the fly, as a multiple of the largest rung.
    pub reference_factor: u64,
}

impl Default for LadderOptions {
    fn default() -> Self {
        LadderOptions { top_samples: None, budget_seconds: 120.0, rungs: 6, reference_factor: 4 }
    }
}

/// One rung of the ladder.
#[derive(Debug, Clone, PartialEq)]
pub struct Rung {
    pub samples: u64,
    pub seconds: f64,
    pub seed: u64,
}

/// One output's measured convergence.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputConvergence {
    pub output: NamedOutput,
    pub reference_kind: &'static str,
    /// Per rung: its paths.
    pub samples: Vec<u64>,
    /// Per rung: measured error and the run's own estimate (in the output's metric).
    pub error: Vec<f64>,
    pub stderr: Vec<f64>,
    /// Per rung: the measured error relative to the reference (a scalar's divided by `|r|`).
    pub relative: Vec<f64>,
    /// Per rung: the run's own σ, relative in the same way.
    pub relative_stderr: Vec<f64>,
    /// The reference's own error in the output's metric (0 for an analytic reference).
    pub reference_error: f64,
    /// Per rung: measured error / `√(σ² + σ_ref²)`.
    pub sigma_ratio: Vec<f64>,
    /// Least-squares fit of `ln(relative error) = a + b ln(seconds)`: `(b, its standard error, a)`.
    /// With a reference run, the error fitted is the rung's own, `√(e² − e_ref²)`: the measured
    /// `e² = ‖x − r‖²/‖r‖²` has expectation `σ_x² + σ_ref²` and the reference's part is known.
    pub fit: Option<(f64, f64, f64)>,
    /// The fit of the run's own relative σ against the rung's *paths* (smooth: no reference
    /// noise and no timing noise in it; slope −1/2 for Monte Carlo).
    pub stderr_fit: Option<(f64, f64, f64)>,
    /// The ladder's throughput, all rungs' paths over all their seconds.
    pub paths_per_second: f64,
    /// An image's per-pixel errors, read pixel by pixel: per rung the median of its own
    /// `σ/|value|` over the pixels, and over the regions' footprints (with a mask of them,
    /// [`crate::output::RegionErrors`]); empty otherwise.
    pub pixel_median: Vec<f64>,
    pub region_median: Vec<f64>,
    /// Their fits against the rung's paths, as [`stderr_fit`](Self::stderr_fit).
    pub pixel_median_fit: Option<(f64, f64, f64)>,
    pub region_median_fit: Option<(f64, f64, f64)>,
}

impl OutputConvergence {
    /// Root mean square of the per-rung ratios of measured to expected error (1 when the run's
    /// σ is right).
    pub fn sigma_ratio_rms(&self) -> f64 {
        let r: Vec<f64> = self.sigma_ratio.iter().copied().filter(|v| v.is_finite()).collect();
        if r.is_empty() { f64::NAN } else { (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt() }
    }

    /// How much larger the measured error is than the run's own σ, over the whole ladder:
    /// `√(mean_k (e_k² − e_ref²)/σ_k²)` (1 when σ is right).
    pub fn error_scale(&self) -> f64 {
        let terms: Vec<f64> = self
            .error
            .iter()
            .zip(&self.stderr)
            .filter(|(_, s)| **s > 0.0)
            .map(|(e, s)| (e * e - self.reference_error * self.reference_error) / (s * s))
            .collect();
        if terms.is_empty() { f64::NAN } else { (terms.iter().sum::<f64>() / terms.len() as f64).max(0.0).sqrt() }
    }

    /// Seconds until the error reaches relative error `e`, extrapolated along the `1/√N` law of
    /// Monte Carlo from the largest rung (the run's own σ there, scaled by
    /// [`error_scale`](Self::error_scale)), at the ladder's throughput. One rung's measured error
    /// is a single draw (for a scalar, `|z|σ`), and one rung's wall time is noisy on a shared
    /// machine, so neither is extrapolated through; the fitted slopes check the law instead.
    /// `None` without a σ.
    pub fn seconds_to(&self, e: f64) -> Option<f64> {
        let (&s, &n) = (self.relative_stderr.last()?, self.samples.last()?);
        let c = self.error_scale();
        (s > 0.0 && c > 0.0 && c.is_finite() && self.paths_per_second > 0.0)
            .then(|| n as f64 * (c * s / e).powi(2) / self.paths_per_second)
    }
}

/// Fit `ln y = a + b ln x(rung)` over the rungs with positive, finite `x` and `y`.
fn loglog_fit(rungs: &[Rung], x: impl Fn(&Rung) -> f64, y: impl Iterator<Item = f64>) -> Option<(f64, f64, f64)> {
    let (x, y): (Vec<f64>, Vec<f64>) = rungs
        .iter()
        .zip(y)
        .filter(|(r, e)| x(r) > 0.0 && *e > 0.0 && e.is_finite())
        .map(|(r, e)| (x(r).ln(), e.ln()))
        .unzip();
    fit_line(&x, &y)
}

/// The result of a convergence study.
#[derive(Debug, Clone, PartialEq)]
pub struct Study {
    pub rungs: Vec<Rung>,
    pub outputs: Vec<OutputConvergence>,
    /// Outputs left out, with the reason.
    pub skipped: Vec<(String, String)>,
    /// The reference run made on the fly, if any.
    pub reference_run: Option<Rung>,
    /// The run's main output ([`Experiment::main_output`]): its name, and its first tally slot.
    pub main_output: String,
    pub main_slot: usize,
}

impl Study {
    /// Whether `o` is the run's main output.
    pub fn is_main(&self, o: &NamedOutput) -> bool {
        o.slots.start == self.main_slot
    }
}

/// Least-squares line through `(x, y)`: `(slope, its standard error, intercept)`; the slope's
/// error is NaN with two points.
pub fn fit_line(x: &[f64], y: &[f64]) -> Option<(f64, f64, f64)> {
    let n = x.len().min(y.len());
    if n < 2 {
        return None;
    }
    let (mx, my) = (x.iter().sum::<f64>() / n as f64, y.iter().sum::<f64>() / n as f64);
    let sxx: f64 = x.iter().map(|v| (v - mx).powi(2)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let b = sxy / sxx;
    let a = my - b * mx;
    let rss: f64 = x.iter().zip(y).map(|(u, v)| (v - a - b * u).powi(2)).sum();
    let se = if n > 2 { (rss / (n - 2) as f64 / sxx).sqrt() } else { f64::NAN };
    Some((b, se, a))
}

/// Paths of each rung: `rungs` counts doubling up to `top`, each a whole number per batch.
pub fn ladder_samples(top: u64, rungs: usize, batches: u64) -> Vec<u64> {
    (0..rungs)
        .map(|k| {
            let n = top >> (rungs - 1 - k).min(63);
            n.div_ceil(batches).max(1) * batches
        })
        .collect()
}

/// Paths of the largest rung that fit the study into `opts.budget_seconds`: a pilot run measures
/// the speed (growing until it takes a quarter second, so that start-up costs do not dominate its
/// rate); the ladder (≈ 2× its top rung) and a reference run (`reference_factor` × the top rung)
/// share the budget. At least 16 paths per batch on the smallest rung.
fn top_rung_for_budget(
    exp: &Experiment,
    decisions: &Decisions,
    opts: &LadderOptions,
    need_run: bool,
    log: &mut dyn StudyLog,
) -> u64 {
    let batches = exp.plan.batches;
    let mut pilot = exp.clone();
    let mut n = batches * 256;
    let rate = loop {
        pilot.plan.set_samples(n);
        let t = pilot.run_decided(decisions, log.progress()).wall_seconds.max(1e-6);
        if t >= 0.25 || n >= batches << 16 {
            break pilot.plan.samples() as f64 / t;
        }
        n *= 4;
    };
    let share = 2.0 + if need_run { opts.reference_factor as f64 } else { 0.0 };
    let top = (rate * opts.budget_seconds / share) as u64;
    log.line(&format!("pilot: {rate:.0} paths/s; top rung {top} paths"));
    top.max((batches * 16) << (opts.rungs.max(2) - 1))
}

/// What [`study`] reports while it works (a line per run).
pub trait StudyLog {
    fn line(&mut self, text: &str);
    fn progress(&self) -> &dyn Progress;
}

/// Run the convergence study of `exp` over its [`outputs`](Experiment::outputs), with
/// `references[i]` the reference of output `i` when known (read from disk); the configuration's
/// analytic references take precedence, and a reference run of the rest is made on the fly with
/// the configured seed. Rung `k` runs with seed `seed + 1 + k`, independent of the others
/// and of the reference. Every run applies `decisions` (the pilots', made once for the study).
pub fn study(
    exp: &Experiment,
    decisions: &Decisions,
    mut references: Vec<Option<Reference>>,
    opts: &LadderOptions,
    log: &mut dyn StudyLog,
) -> Study {
    let outputs = exp.outputs();
    references.resize(outputs.len(), None);
    for (name, values) in &exp.references {
        if let Some(i) = outputs.iter().position(|o| &o.name == name) {
            references[i] =
                Some(Reference { values: values.clone(), stderr: vec![0.0; values.len()], kind: "analytic" });
        }
    }
    let need_run = references.iter().any(Option::is_none);
    let batches = exp.plan.batches;
    let rungs = opts.rungs.max(2);
    let top = match opts.top_samples {
        Some(n) => n,
        None => top_rung_for_budget(exp, decisions, opts, need_run, log),
    };
    let samples = ladder_samples(top, rungs, batches);
    let mut reference_run = None;
    if need_run {
        let mut r = exp.clone();
        r.plan.set_samples(opts.reference_factor.max(1) * samples[rungs - 1]);
        log.line(&format!("reference run: {} paths, seed {}", r.plan.samples(), r.plan.seed));
        let out = r.run_decided(decisions, log.progress());
        let se = out.estimates.stderr();
        for (o, slot) in outputs.iter().zip(references.iter_mut()) {
            if slot.is_none() {
                let (m, s) = o.slice(out.estimates.mean(), &se);
                *slot = Some(Reference { values: m.to_vec(), stderr: s.to_vec(), kind: "run" });
            }
        }
        reference_run = Some(Rung { samples: r.plan.samples(), seconds: out.wall_seconds, seed: r.plan.seed });
    }
    let mut ladder = Vec::with_capacity(rungs);
    let mut results: Vec<OutputConvergence> = outputs
        .iter()
        .zip(&references)
        .map(|(o, r)| OutputConvergence {
            output: o.clone(),
            reference_kind: r.as_ref().map_or("none", |r| r.kind),
            samples: Vec::new(),
            error: Vec::new(),
            stderr: Vec::new(),
            relative: Vec::new(),
            relative_stderr: Vec::new(),
            reference_error: r.as_ref().map_or(0.0, |r| r.error(o)),
            sigma_ratio: Vec::new(),
            fit: None,
            stderr_fit: None,
            paths_per_second: f64::NAN,
            pixel_median: Vec::new(),
            region_median: Vec::new(),
            pixel_median_fit: None,
            region_median_fit: None,
        })
        .collect();
    // Each image's mask of the regions' footprints, in the tally's order.
    let masks: Vec<Option<Vec<bool>>> = outputs.iter().map(|o| exp.region_mask_of(o)).collect();
    for (k, &n) in samples.iter().enumerate() {
        let mut e = exp.clone();
        e.plan.seed = exp.plan.seed.wrapping_add(1 + k as u64);
        e.plan.set_samples(n);
        let out: RunOutput = e.run_decided(decisions, log.progress());
        let se = out.estimates.stderr();
        for (res, r) in results.iter_mut().zip(&references) {
            let Some(r) = r else { continue };
            let Some((err, s)) = res.output.error_against(out.estimates.mean(), &se, &r.values) else { continue };
            let ref_se = res.reference_error;
            res.samples.push(e.plan.samples());
            res.error.push(err);
            res.stderr.push(s);
            res.relative.push(res.output.to_relative(err, &r.values));
            res.relative_stderr.push(res.output.to_relative(s, &r.values));
            res.sigma_ratio.push(err / (s * s + ref_se * ref_se).sqrt());
        }
        for (res, mask) in results.iter_mut().zip(&masks) {
            let Some(pe) = res.output.pixel_errors(out.estimates.mean(), &se) else { continue };
            res.pixel_median.push(pe.median);
            if let Some(mask) = mask {
                let (v, e) = res.output.slice(out.estimates.mean(), &se);
                let r = crate::output::RegionErrors::of(v, e, mask);
                res.region_median.push(r.median_region.unwrap_or(f64::NAN));
            }
        }
        log.line(&format!("rung {k}: {} paths in {:.3} s (seed {})", e.plan.samples(), out.wall_seconds, e.plan.seed));
        ladder.push(Rung { samples: e.plan.samples(), seconds: out.wall_seconds, seed: e.plan.seed });
    }
    let mut skipped = Vec::new();
    let mut kept = Vec::new();
    let rate = ladder.iter().map(|r| r.samples as f64).sum::<f64>() / ladder.iter().map(|r| r.seconds).sum::<f64>();
    for (mut res, r) in results.into_iter().zip(&references) {
        let Some(r) = r else { continue };
        if r.values.iter().all(|&v| v == 0.0) {
            skipped.push((res.output.name.clone(), "the reference is zero (no relative error is defined)".into()));
            continue;
        }
        if res.stderr.iter().all(|&s| s == 0.0) && res.reference_error == 0.0 {
            skipped.push((res.output.name.clone(), "deterministic: no Monte Carlo variance in any rung".into()));
            continue;
        }
        let rel_ref = res.output.to_relative(res.reference_error, &r.values);
        let own = res.relative.iter().map(|e| (e * e - rel_ref * rel_ref).max(0.0).sqrt());
        res.fit = loglog_fit(&ladder, |r| r.seconds, own);
        res.stderr_fit = loglog_fit(&ladder, |r| r.samples as f64, res.relative_stderr.iter().copied());
        res.pixel_median_fit = loglog_fit(&ladder, |r| r.samples as f64, res.pixel_median.iter().copied());
        res.region_median_fit = loglog_fit(&ladder, |r| r.samples as f64, res.region_median.iter().copied());
        res.paths_per_second = rate;
        kept.push(res);
    }
    let main = exp.main_output();
    Study { rungs: ladder, outputs: kept, skipped, reference_run, main_output: main.name, main_slot: main.slots.start }
}
