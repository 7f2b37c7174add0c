//! Error against run time (issue 7): the σ a run reports for itself against its measured error,
//! the `1/√N` law, analytic references from the configuration, and runs to a target error.

use crate::support::run::experiment;
use crate::support::stats::assert_within_sigma;

use ohd::converge::{LadderOptions, Reference, Study, StudyLog, Target, study};
use ohd::experiment::{Decisions, Progress, Silent};

/// The van de Hulst slab with its published references (validation/vdh_slab.toml).
const VDH: &str = include_str!("../../validation/vdh_slab.toml");

struct Quiet;

impl StudyLog for Quiet {
    fn line(&mut self, _: &str) {}
    fn progress(&self) -> &dyn Progress {
        &Silent
    }
}

fn ladder(top: u64, rungs: usize) -> LadderOptions {
    LadderOptions { top_samples: Some(top), rungs, ..Default::default() }
}

/// Slope of `ln error` against `ln paths` over the ladder.
fn slope_in_paths(s: &Study, errors: &[f64]) -> f64 {
    let x: Vec<f64> = s.rungs.iter().map(|r| (r.samples as f64).ln()).collect();
    let y: Vec<f64> = errors.iter().map(|e| e.ln()).collect();
    ohd::converge::fit_line(&x, &y).expect("a fit").0
}

/// The van de Hulst slab set in uniform motion (1 mm/s into the slab) and seen from the top. In a
/// uniform translation `dl/dt` telescopes to `v·(dir_source − dir_exit)`, so a path leaving at
/// `μ = cos θ` beats at `v(1 + μ)/λ0` ∈ [1.58, 3.16] kHz: a spectrum spread over 40 bins.
fn moving_slab() -> ohd::experiment::Experiment {
    // The slab without its `[reference]` (the moving slab has no published values).
    let text = VDH.split("[reference]").next().unwrap().to_string()
        + r#"
[media.slab.velocity]
type = "uniform"
velocity_mm_per_s = [0, 0, 1]

[[detectors]]
name = "top"
[detectors.spectrum]
f_min_khz = 1.55
f_max_khz = 3.2
bins = 40
"#;
    experiment(&text, &["run.seed=3", "run.batches=64"])
}

/// 5 rungs up to 3.2·10⁶ paths and a reference run of 4× that made on the fly. The spectrum's
/// relative RMS error sums 40 bins, so each rung's ratio of measured to self-reported error is
/// tight (about √(χ²₄₀/40)): every rung must lie in [0.5, 2] and the error must fall as N^(−1/2).
/// Scalars are one draw per rung, so they are pooled over the ladder.
#[test]
fn self_reported_sigma_agrees_with_the_measured_error() {
    let exp = moving_slab();
    let s = study(&exp, &Decisions::default(), Vec::new(), &ladder(3_200_000, 5), &mut Quiet);
    assert_eq!(s.rungs.len(), 5);
    assert_eq!(s.main_output, "top.spectrum");
    let r = s.reference_run.as_ref().expect("a reference run made on the fly");
    assert_eq!(r.samples, 4 * s.rungs[4].samples);
    assert!(s.rungs.iter().all(|g| g.seed != r.seed), "rungs and reference share a seed");
    let spec = s.outputs.iter().find(|o| o.output.name == "top.spectrum").expect("the spectrum is measured");
    assert_eq!(spec.reference_kind, "run");
    for (k, q) in spec.sigma_ratio.iter().enumerate() {
        println!("rung {k}: error {:.4e}, σ {:.4e}, ratio {q:.3}", spec.error[k], spec.stderr[k]);
        assert!((0.5..=2.0).contains(q), "rung {k}: measured/σ = {q}");
    }
    let rms = spec.sigma_ratio_rms();
    assert!((0.75..=1.33).contains(&rms), "spectrum σ ratio over the ladder {rms}");
    // The rung's own error (the reference's variance removed) falls as N^(−1/2): the slope of a
    // 20-bin error is known to about ±0.05 here.
    let own: Vec<f64> =
        spec.error.iter().map(|e| (e * e - spec.reference_error * spec.reference_error).sqrt()).collect();
    let b = slope_in_paths(&s, &own);
    println!("slope of the spectrum's error in paths: {b:.3}");
    assert!((b + 0.5).abs() < 0.15, "slope {b}");
    let bs = spec.stderr_fit.expect("a σ fit").0;
    assert!((bs + 0.5).abs() < 0.05, "slope of σ {bs}");
    assert!((bs - slope_in_paths(&s, &spec.relative_stderr)).abs() < 1e-12);
    // Scalars with variance, pooled: mean of (e/σ_tot)² over rungs and scalars ~ χ²_n/n.
    let ratios: Vec<f64> =
        s.outputs.iter().filter(|o| o.output.is_scalar()).flat_map(|o| o.sigma_ratio.iter().copied()).collect();
    let pooled = (ratios.iter().map(|q| q * q).sum::<f64>() / ratios.len() as f64).sqrt();
    println!("{} scalar ratios, pooled rms {pooled:.3}", ratios.len());
    assert!(ratios.len() >= 10, "{} scalar ratios", ratios.len());
    assert!((0.5..=2.0).contains(&pooled), "pooled scalar σ ratio {pooled}");
    // The extrapolation: from the largest rung along 1/√N at the ladder's throughput.
    let t = spec.seconds_to(0.01).expect("an extrapolation");
    let n_top = s.rungs[4].samples as f64;
    let expected = n_top * (spec.error_scale() * spec.relative_stderr[4] / 0.01).powi(2) / spec.paths_per_second;
    assert!((t / expected - 1.0).abs() < 1e-12, "{t} vs {expected}");
}

/// Analytic references from `[reference]`: no reference run is made, the errors are measured
/// against van de Hulst's Rd and Tt and e^{−2}, and together their σ ratio is 1.
#[test]
fn analytic_references_from_the_configuration() {
    let exp = experiment(VDH, &["run.seed=5"]);
    assert_eq!(exp.references.len(), 5);
    let s = study(&exp, &Decisions::default(), Vec::new(), &ladder(2_000_000, 4), &mut Quiet);
    assert!(s.reference_run.is_none(), "all outputs with variance have analytic references");
    assert_eq!(s.main_output, "reflectance_diffuse");
    let mut ratios = Vec::new();
    for o in &s.outputs {
        assert_eq!(o.reference_kind, "analytic", "{}", o.output.name);
        assert_eq!(o.reference_error, 0.0);
        ratios.extend(o.sigma_ratio.iter().copied());
    }
    assert_eq!(s.outputs.len(), 4);
    assert_eq!(s.skipped.len(), 1);
    assert!(s.skipped.iter().any(|(n, _)| n == "reflectance_specular"), "n = 1: no specular reflection");
    let pooled = (ratios.iter().map(|q| q * q).sum::<f64>() / ratios.len() as f64).sqrt();
    println!("16 ratios: {ratios:.3?}, pooled {pooled:.3}");
    assert!((0.5..=2.0).contains(&pooled), "pooled σ ratio {pooled}");
}

/// A given reference (as read from a run directory) is used as is, and a wrong one shows:
/// scaling the reference spectrum by 1.2 makes the measured error ≫ σ.
#[test]
fn a_biased_reference_is_detected() {
    let exp = moving_slab();
    let mut r = exp.clone();
    r.plan.set_samples(3_200_000);
    r.plan.seed = 90;
    let out = r.run(&Silent);
    let se = out.estimates.stderr();
    let refs: Vec<Option<Reference>> = exp
        .outputs()
        .iter()
        .map(|o| {
            let (m, s) = o.slice(out.estimates.mean(), &se);
            let bias = if o.name == "top.spectrum" { 1.2 } else { 1.0 };
            Some(Reference { values: m.iter().map(|v| v * bias).collect(), stderr: s.to_vec(), kind: "directory" })
        })
        .collect();
    let s = study(&exp, &Decisions::default(), refs, &ladder(1_600_000, 3), &mut Quiet);
    assert!(s.reference_run.is_none());
    let spec = s.outputs.iter().find(|o| o.output.name == "top.spectrum").unwrap();
    assert_eq!(spec.reference_kind, "directory");
    // A 20 % scale error: relative error ≈ 0.2/1.2 whatever the paths (plus ≤ 3 % noise).
    for (k, e) in spec.relative.iter().enumerate() {
        assert!((e - 0.2 / 1.2).abs() < 0.02, "rung {k}: {e}");
    }
    assert!(spec.sigma_ratio_rms() > 4.0, "a 20 % bias must show: {}", spec.sigma_ratio_rms());
    let power = s.outputs.iter().find(|o| o.output.name == "top.detected_power").unwrap();
    println!("spectrum σ ratio {:.2}, power {:.2}", spec.sigma_ratio_rms(), power.sigma_ratio_rms());
    assert!(power.sigma_ratio_rms() < 3.0, "the unbiased power: {}", power.sigma_ratio_rms());
}

/// `--target-error`: whole rounds of the configured paths until the main output (Rd here) has
/// reached the target; the same numbers on 1 and 2 threads; the estimate is right.
#[test]
fn target_error_stops_at_the_target_on_any_thread_count() {
    let target_error = 0.002;
    let run = |threads: &str| {
        let exp = experiment(VDH, &["run.samples=32000", "run.seed=21", threads]);
        let t = Target { output: exp.main_output(), relative_error: target_error, max_samples: 100_000_000 };
        let out = exp.run_until(&Silent, Some(&t));
        (exp, out)
    };
    let (exp, one) = run("run.threads=1");
    let (_, two) = run("run.threads=2");
    assert_eq!(one.estimates.mean(), two.estimates.mean(), "thread count changed the result");
    assert_eq!(one.samples(), two.samples());
    let t = one.target.as_ref().expect("a target outcome");
    println!("{} rounds, {} paths, reached {:.5}", t.rounds, one.samples(), t.reached);
    assert!(t.met && t.reached <= target_error);
    // The rounds are extrapolated from 1/√N: it stops close to the target, not far below it.
    assert!(t.reached > 0.7 * target_error, "overshot: {}", t.reached);
    assert_eq!(one.samples(), t.rounds * exp.plan.samples());
    assert_eq!(one.batches, t.rounds * exp.plan.batches);
    assert_eq!(one.main_output.0, "reflectance_diffuse");
    let (rd, se) = (one.estimates.mean()[1], one.estimates.stderr()[1]);
    assert!((se / rd - t.reached).abs() < 1e-12);
    assert_within_sigma("Rd at the target error", rd, se, 0.09739, 4.0);
}

/// A target that cannot be met within `max_samples` stops there and says so.
#[test]
fn target_error_stops_at_max_samples() {
    let exp = experiment(VDH, &["run.samples=16000", "run.seed=22"]);
    let t = Target { output: exp.main_output(), relative_error: 1e-6, max_samples: 64_000 };
    let out = exp.run_until(&Silent, Some(&t));
    let o = out.target.clone().expect("an outcome");
    assert!(!o.met);
    assert_eq!(o.rounds, 4);
    assert_eq!(out.samples(), 64_000);
    assert!(o.reached > 1e-3);
}

/// An image is read pixel by pixel: the median over its pixels of the run's own σ/|value| falls as
/// N^(−1/2) over the ladder, over all pixels and over the regions' footprints (a drop of ink in a
/// slab under a camera of 8 × 8 pixels; the medians of 64 and 16 pixels, 5 rungs over 16× in
/// paths: each pixel's σ is known to about 13 % from its 32 batches, the slope to about ±0.03).
#[test]
fn per_pixel_errors_fall_as_monte_carlo_over_the_ladder() {
    let text = r#"schema_version = 1
[run]
seed = 2
batches = 32
[source]
wavelength_nm = 785
profile = "disk"
radius_mm = 1
position_mm = [0, 0, -1]
[media.tissue]
sigma_a_per_mm = 0.5
sigma_s_per_mm = 10
phase = { type = "hg", g = 0.8 }
[media.ink]
sigma_a_per_mm = 3
sigma_s_per_mm = 10
phase = { type = "hg", g = 0.8 }
[[layers]]
name = "slab"
thickness_mm = 2
n = 1.0
medium = "tissue"
[[regions]]
layer = "slab"
medium = "ink"
shape = { type = "sphere", center_mm = [0.25, 0.25, 0.6], radius_mm = 0.4 }
[[detectors]]
name = "camera"
area = { type = "rect", size_mm = [2, 2] }
image = { pixels = [8, 8] }
"#;
    let exp = experiment(text, &[]);
    let s = study(&exp, &Decisions::default(), Vec::new(), &ladder(320_000, 5), &mut Quiet);
    let image = s.outputs.iter().find(|o| o.output.name == "camera.image").expect("the image is measured");
    assert_eq!((image.pixel_median.len(), image.region_median.len()), (5, 5));
    for (what, fit) in [("all pixels", image.pixel_median_fit), ("the drop's footprint", image.region_median_fit)] {
        let (b, se, _) = fit.expect("a fit");
        println!("{what}: median per-pixel σ/value slope {b:.3} ± {se:.3}");
        assert!((b + 0.5).abs() < 0.1, "{what}: slope {b}");
    }
    // Scalars are not images.
    assert!(s.outputs.iter().filter(|o| o.output.is_scalar()).all(|o| o.pixel_median.is_empty()));
}

/// Issue 52: `ohd converge --reference DIR` took a directory whose values were NaN, ∞ or 1e308 (a
/// square past the largest number), ran its ladder, and skipped the output as "deterministic"
/// (`σ_r/‖r‖` came out 0). Such a reference is refused before any rung: exit 2 naming
/// `--reference` and the expected form, nothing studied.
#[test]
fn a_reference_of_nan_inf_or_1e308_is_refused() {
    use crate::support::files::ohd;
    let tmp = tempfile::tempdir().expect("a temporary directory");
    let cfg = tmp.path().join("moving_slab.toml");
    let text = VDH.split("[reference]").next().unwrap().to_string()
        + "\n[media.slab.velocity]\ntype = \"uniform\"\nvelocity_mm_per_s = [0, 0, 1]\n\n[[detectors]]\nname = \"top\"\n\
           [detectors.spectrum]\nf_min_khz = 1.55\nf_max_khz = 3.2\nbins = 40\n";
    std::fs::write(&cfg, text).expect("the config is written");
    let cfg = cfg.to_str().expect("UTF-8");
    let good = tmp.path().join("run");
    let o = ohd(tmp.path(), &["run", cfg, "--samples", "16000", "--quiet", "--out", good.to_str().expect("UTF-8")]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let spectrum = "top_spectrum.npy";
    assert!(good.join(spectrum).exists() && good.join("top_spectrum_stderr.npy").exists(), "the run's files");
    for (k, bad) in [f64::NAN, f64::INFINITY, 1e308].into_iter().enumerate() {
        let dir = tmp.path().join(format!("tampered_{k}"));
        std::fs::create_dir(&dir).expect("a directory");
        for e in std::fs::read_dir(&good).expect("the run") {
            let e = e.expect("an entry");
            std::fs::copy(e.path(), dir.join(e.file_name())).expect("copied");
        }
        // The first value of the spectrum (after the .npy header, version 1: its length at 8).
        let path = dir.join(spectrum);
        let mut bytes = std::fs::read(&path).expect("the spectrum");
        let start = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        bytes[start..start + 8].copy_from_slice(&bad.to_le_bytes());
        std::fs::write(&path, bytes).expect("tampered");
        let out = tmp.path().join(format!("study_{k}"));
        let args = ["converge", cfg, "--reference", dir.to_str().expect("UTF-8"), "--samples", "16000", "--rungs", "2"];
        let o = ohd(tmp.path(), &[&args[..], &["-q", "--out", out.to_str().expect("UTF-8")]].concat());
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{bad}: {err}");
        assert!(err.contains("--reference") && err.contains("top.spectrum") && err.contains("finite"), "{bad}: {err}");
        assert!(!out.join("converge.json").exists(), "{bad}: a study was written");
    }
}
