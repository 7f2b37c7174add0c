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
    let inv = Invocation { config_source: path.display().to_string(), overrides: vec![] };
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
