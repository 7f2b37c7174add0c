//! Issue 21 ("Reliability"): what an experiment may allocate is counted against the memory budget
//! before it is allocated, no output is written with NaN or infinite values, and what a run
//! cannot get right (power off a spectrum's axis, aliased lidar echoes, truncated paths) is
//! reported as a warning on stderr and in the manifest.

use std::path::{Path, PathBuf};

use ohd::config::load;
use ohd::error::Error;
use ohd::experiment::Silent;
use ohd::io::write::manifest::{Invocation, write_run};
use ohd::stats::BatchAccumulator;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

/// A run whose estimates hold a NaN (what validation failed to refuse) fails with
/// [`Error::NotFinite`] naming the output, and writes nothing: not even its directory.
#[test]
fn a_non_finite_estimate_fails_the_run_and_writes_nothing() {
    let path = repo().join("tests/configs/good/moving_media.toml");
    let (table, mut exp) = load(&read(&path), &path.display().to_string(), &[]).unwrap();
    exp.plan.set_samples(2000);
    let mut out = exp.run(&Silent);
    let spectrum = exp.outputs().into_iter().find(|o| o.name == "probe.spectrum").expect("the probe's spectrum");
    let (batches, mean, m2) = out.estimates.parts();
    let mut mean = mean.to_vec();
    mean[spectrum.slots.start + 3] = f64::NAN;
    out.estimates = BatchAccumulator::from_parts(batches, mean, m2.to_vec()).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run");
    let inv = Invocation { config_source: path.display().to_string(), overrides: vec![], figures: true };
    match write_run(&dir, &exp, &out, &table, &inv) {
        Err(e @ Error::NotFinite { .. }) => {
            let msg = e.to_string();
            assert!(msg.contains("probe.spectrum") && msg.contains("probe_spectrum.npy"), "{msg}");
            assert!(!e.is_input_error(), "a failure of the run (exit status 1), not bad input");
        }
        other => panic!("expected a non-finite error, got {other:?}"),
    }
    assert!(!dir.exists(), "the run's directory was created");
}

/// What the memory budget counts for the media of a split layer is what they take: resolving a
/// layer of rain (17 particle populations, each with its fall-speed table) into 2000 more
/// sublayers, and copying the experiment as a run does, keeps as many more bytes as the
/// estimate says, within 15 % (measured: 25 153 bytes held per sublayer, 25 970 counted; the estimate adds the allocator's 16 bytes per block, which the
/// count leaves out). Before issue 21 the budget counted the tallies only, and 4 × 10⁵ such
/// sublayers grew to 5.8 GB in `ohd check` and aborted.
#[test]
fn the_budget_counts_what_sublayers_take() {
    let path = repo().join("configs/wind_rainy.toml");
    let text = read(&path);
    let held_by = |sublayers: u64| -> (i64, u64) {
        let before = crate::support::alloc::held();
        let (_, exp) = load(&text, "wind_rainy", &[format!("layers.0.sublayers={sublayers}")]).unwrap();
        let copy = exp.clone();
        let held = crate::support::alloc::held() - before;
        let block = exp.plan.memory.iter().find(|b| b.what.starts_with("the media of layers[0]")).expect("counted");
        assert_eq!(copy.scene.layers.len() as u64, sublayers);
        (held, block.bytes)
    };
    // The Mie optics (the same for both) and everything else that does not grow cancel.
    let (held_a, counted_a) = held_by(1000);
    let (held_b, counted_b) = held_by(3000);
    let (held, counted) = ((held_b - held_a) as f64, (counted_b - counted_a) as f64);
    let per_layer = |b: f64| b / 2000.0;
    assert!(
        (counted / held - 1.0).abs() < 0.15,
        "2000 sublayers held {:.0} bytes each as resolved and copied, the budget counted {:.0}",
        per_layer(held),
        per_layer(counted)
    );

    // Past the budget, refused before the sublayers are made: a configuration error naming the
    // key and the budget.
    let e = load(&text, "wind_rainy", &["layers.0.sublayers=100000".into(), "run.memory_budget_gib=1".into()])
        .expect_err("2.4 GiB of sublayers refused under a 1 GiB budget");
    let msg = e.to_string();
    assert!(msg.starts_with("layers[0].sublayers: = 100000: the media of layers[0]"), "{msg}");
    assert!(msg.contains("above the memory budget of 1.0 GiB (run.memory_budget_gib)"), "{msg}");
}

/// The codes of a run's warnings.
fn codes(r: &crate::support::run::Run) -> Vec<&'static str> {
    ohd::post::warnings(&r.exp, &r.out).iter().map(|w| w.code).collect()
}

/// A belt moving at 10⁵ m/s shifts most of the probe's power beyond its ±20 kHz axis: warned of.
/// The fixture as written loses 1.2 % into the tails, below the threshold of 5 %.
#[test]
fn power_off_the_spectrum_axis_is_warned_of() {
    let text = read(&repo().join("tests/configs/good/moving_media.toml"));
    let fast = crate::support::run::run(&text, &["run.samples=2000", "media.belt.velocity.velocity_m_per_s=[1e5,0,0]"]);
    assert_eq!(codes(&fast), ["off_axis_power"]);
    let w = &ohd::post::warnings(&fast.exp, &fast.out)[0];
    assert!(
        w.message.starts_with("detector \"probe\": ") && w.message.contains("detectors[0].spectrum"),
        "{}",
        w.message
    );
    let slow = crate::support::run::run(&text, &["run.samples=2000"]);
    assert!(codes(&slow).is_empty(), "{:?}", codes(&slow));
}

/// A fog receding at 35.75 m/s from a 1.55 µm lidar sampling at 50 MHz (band ±19.375 m/s) is
/// seen at −3 m/s, every gate's retrieval "ok": all of its power is counted as aliased and warned
/// of. At 10 m/s nothing is aliased.
#[test]
fn lidar_aliasing_is_warned_of() {
    let text = r#"
schema_version = 1
[run]
samples = 4000
[source]
wavelength_nm = 1550
position_m = [0, 0, -1]
[media.fog]
sigma_s_per_m = 1e-2
sigma_a_per_m = 0
velocity = { type = "uniform", velocity_m_per_s = [0, 0, 35.75] }
[[layers]]
thickness_m = 300
n = 1.0
medium = "fog"
[[detectors]]
name = "lidar"
[detectors.lidar]
aperture_radius_mm = 40
field_of_view_urad = 100
pulse_fwhm_ns = 200
sample_rate_mhz = 50
first_gate_m = 30
gates = 8
"#;
    let power = |r: &crate::support::run::Run, name: &str| {
        let o = r.out.layout.registry.expect(name);
        r.out.estimates.mean()[o.slots.start]
    };
    let fast = crate::support::run::run(text, &[]);
    assert_eq!(codes(&fast), ["lidar_aliasing"]);
    let detected = power(&fast, "lidar.detected_power");
    assert!(detected > 0.0 && power(&fast, "lidar.aliased_power") == detected);
    let slow = crate::support::run::run(text, &["media.fog.velocity.velocity_m_per_s=[0,0,10]"]);
    assert!(codes(&slow).is_empty(), "{:?}", codes(&slow));
    assert_eq!(power(&slow, "lidar.aliased_power"), 0.0);
}

/// An albedo-1 half-space with the event cap at 10⁴ truncates about 6 % of its paths (their
/// weight lost: R falls short of 1 by as much): warned of. With the default cap (10⁶) a 0.2 mm
/// slab truncates none.
#[test]
fn truncated_paths_are_warned_of() {
    let text = read(&repo().join("validation/energy_albedo1.toml"));
    let capped = crate::support::run::run(
        &text,
        &["run.samples=2000", "layers.0.thickness_mm=inf", "run.max_scattering_events=10000"],
    );
    assert!(capped.out.stats.truncated_paths > 0);
    assert_eq!(codes(&capped), ["truncated_paths"]);
    let slab = crate::support::run::run(&text, &["run.samples=2000"]);
    assert_eq!(slab.out.stats.truncated_paths, 0);
    assert!(codes(&slab).is_empty(), "{:?}", codes(&slab));
}

/// The warnings go into the manifest (`warnings`, `[]` when there are none) and onto stderr at
/// the end of the run's report.
#[test]
fn warnings_are_in_the_manifest_and_on_stderr() {
    let config = repo().join("validation/energy_albedo1.toml");
    let tmp = tempfile::tempdir().unwrap();
    let run = |dir: &Path, sets: &[&str]| {
        let mut args = vec!["run".to_string(), config.display().to_string(), "--samples".into(), "2000".into()];
        args.extend(["--quiet".into(), "--out".into(), dir.display().to_string()]);
        for s in sets {
            args.extend(["--set".to_string(), s.to_string()]);
        }
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_ohd")).args(&args).output().expect("ohd runs");
        assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
        let manifest: serde_json::Value = serde_json::from_str(&read(&dir.join("manifest.json"))).unwrap();
        (String::from_utf8_lossy(&o.stderr).into_owned(), manifest)
    };
    let (stderr, manifest) =
        run(&tmp.path().join("capped"), &["layers.0.thickness_mm=inf", "run.max_scattering_events=10000"]);
    let warnings = manifest["warnings"].as_array().expect("a warnings array");
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert_eq!(warnings[0]["code"], "truncated_paths");
    let message = warnings[0]["message"].as_str().unwrap();
    let last = stderr.lines().last().unwrap_or_default();
    assert_eq!(last, format!("ohd: warning: {message}"), "the warning ends the report:\n{stderr}");
    let (stderr, manifest) = run(&tmp.path().join("slab"), &[]);
    assert_eq!(manifest["warnings"], serde_json::json!([]));
    assert!(!stderr.contains("warning"), "{stderr}");
}
