//! Configuration fixtures: every file in `tests/configs/good` loads and runs, every file in
//! `tests/configs/bad` fails with the error its `# expect:` lines name, every shipped experiment
//! (`configs/`, `validation/`) runs and writes its outputs, and `--set` overrides behave.

use std::path::{Path, PathBuf};

use ohd::config::{apply_set, load};
use ohd::detect::Scalar;
use ohd::experiment::{Experiment, RunOutput, Silent};
use ohd::io::write::manifest::{Invocation, write_run};
use ohd::source::Profile;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The `.toml` files of a directory, sorted; panics if there are none.
fn toml_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no .toml files in {}", dir.display());
    files
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

fn load_file(path: &Path, sets: &[String]) -> (toml::Table, Experiment) {
    load(&read(path), &path.display().to_string(), sets).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn scalar(out: &RunOutput, s: Scalar) -> f64 {
    out.estimates.mean()[s as usize]
}

fn total(out: &RunOutput) -> f64 {
    scalar(out, Scalar::ReflectanceSpecular)
        + scalar(out, Scalar::ReflectanceDiffuse)
        + scalar(out, Scalar::TransmittanceTotal)
        + scalar(out, Scalar::AbsorbedFraction)
}

/// Run `exp` with `samples` paths and check that every estimate is finite and that no more power
/// leaves or is absorbed than was emitted.
///
/// Russian roulette is unbiased but does not conserve weight path by path: a survivor's weight is
/// divided by the survival probability `p`, so with the configured walk
/// `R_spec + R_diffuse + T + A` is 1 only in expectation and can come out above 1 by a few
/// `threshold · sqrt(roulette events / p) / N` (about 1e-6 at 2000 paths in a semi-infinite
/// medium). The exact bound `≤ 1` is therefore checked on a second run with roulette switched off
/// (threshold 0, paths capped at a number of events instead, which can only lose weight), and the
/// configured run is held to 1 plus six standard deviations of the roulette's net gain.
fn smoke_run(name: &str, exp: &mut Experiment, samples: u64) -> RunOutput {
    exp.plan.set_samples(samples);
    let out = exp.run(&Silent);
    assert_eq!(out.stats.paths, exp.plan.samples(), "{name}: paths traced");
    let mean = out.estimates.mean();
    let se = out.estimates.stderr();
    assert!(!mean.is_empty(), "{name}: no estimates");
    for (i, (m, s)) in mean.iter().zip(&se).enumerate() {
        assert!(m.is_finite() && s.is_finite(), "{name}: estimate {i} = {m} ± {s} is not finite");
    }
    assert_eq!(out.stats.non_finite, 0, "{name}: non-finite path contributions");
    for s in Scalar::ALL {
        let v = scalar(&out, s);
        assert!((0.0..=1.0 + 1e-9).contains(&v), "{name}: {} = {v} outside [0, 1]", s.name());
    }

    // With the configured roulette: 1 within the roulette's own noise.
    let walk = &exp.plan.walk;
    let n = out.stats.paths as f64;
    let roulette_events = out.stats.roulette_terminations as f64 / (1.0 - walk.roulette_survival).max(1e-12);
    let roulette_sd = walk.roulette_threshold * (roulette_events / walk.roulette_survival).sqrt() / n;
    let sum = total(&out);
    assert!(
        sum <= 1.0 + 1e-9 + 6.0 * roulette_sd,
        "{name}: R_spec + R_diffuse + T + A = {sum} > 1 + 6 × {roulette_sd:e} (roulette noise)"
    );
    assert!(sum > 0.5, "{name}: R_spec + R_diffuse + T + A = {sum}: most of the power went missing");

    // Without roulette: exactly at most 1.
    let mut exact = exp.clone();
    exact.plan.walk.roulette_threshold = 0.0;
    exact.plan.walk.max_events = exact.plan.walk.max_events.min(5000);
    let exact_out = exact.run(&Silent);
    assert_eq!(exact_out.stats.roulette_terminations, 0);
    let sum = total(&exact_out);
    assert!(sum <= 1.0 + 1e-9, "{name}: without roulette R_spec + R_diffuse + T + A = {sum} > 1");
    out
}

#[test]
fn good_fixtures_load_and_run() {
    let files = toml_files(&repo().join("tests/configs/good"));
    assert!(files.len() >= 4, "expected at least 4 good fixtures, found {}", files.len());
    for path in files {
        let (_, mut exp) = load_file(&path, &[]);
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        assert!(exp.plan.samples() <= 100_000, "{name}: keep run.samples small in fixtures");
        smoke_run(&name, &mut exp, 2000);
    }
}

/// The substrings a bad fixture's error must contain: one `# expect: ...` line first, optionally
/// followed by more.
fn expectations(path: &Path, text: &str) -> Vec<String> {
    let expects: Vec<String> =
        text.lines().map_while(|l| l.strip_prefix("# expect:")).map(|s| s.trim().to_string()).collect();
    assert!(!expects.is_empty(), "{}: the first line must be `# expect: <substring of the error>`", path.display());
    for e in &expects {
        assert!(!e.is_empty(), "{}: empty `# expect:` line", path.display());
    }
    expects
}

#[test]
fn bad_fixtures_fail_with_the_expected_message() {
    let files = toml_files(&repo().join("tests/configs/bad"));
    assert!(files.len() >= 14, "expected at least 14 bad fixtures, found {}", files.len());
    let mut failures = Vec::new();
    for path in &files {
        let text = read(path);
        let expects = expectations(path, &text);
        match load(&text, &path.display().to_string(), &[]) {
            Ok(_) => failures.push(format!("{}: loaded, but should fail with {expects:?}", path.display())),
            Err(e) => {
                let msg = e.to_string();
                assert!(!e.path.is_empty(), "{}: error without a key path: {msg}", path.display());
                for x in &expects {
                    if !msg.contains(x.as_str()) {
                        failures.push(format!("{}:\n  expected: {x}\n  got:      {msg}", path.display()));
                    }
                }
            }
        }
    }
    assert!(failures.is_empty(), "{} bad fixture(s) misbehaved:\n{}", failures.len(), failures.join("\n"));
}

#[test]
fn shipped_experiments_run_and_write_outputs() {
    let root = repo();
    let mut files = toml_files(&root.join("configs"));
    assert!(files.iter().any(|p| p.ends_with("configs/default.toml")), "configs/default.toml is missing");
    let validation = root.join("validation");
    if validation.is_dir() {
        files.extend(toml_files(&validation));
    }
    let tmp = tempfile::tempdir().expect("tempdir");
    for path in files {
        let (table, mut exp) = load_file(&path, &[]);
        let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
        let out = smoke_run(&stem, &mut exp, 4000);
        let dir = tmp.path().join(&stem);
        let inv = Invocation { config_source: path.display().to_string(), overrides: vec![], figures: true };
        let manifest = write_run(&dir, &exp, &out, &table, &inv).unwrap_or_else(|e| panic!("{stem}: {e}")).json();
        let text = std::fs::read_to_string(dir.join("manifest.json")).expect("manifest.json written");
        let parsed: serde_json::Value = serde_json::from_str(&text).expect("manifest.json parses");
        assert_eq!(parsed["name"], manifest["name"], "{stem}: manifest on disk differs from the one returned");
        assert_eq!(parsed["samples"].as_u64(), Some(exp.plan.samples()), "{stem}: samples");
        for s in Scalar::ALL {
            let v = parsed["estimates"][s.name()]["value"].as_f64().unwrap_or(f64::NAN);
            let want = scalar(&out, s);
            assert!((v - want).abs() <= 1e-12 * want.abs(), "{stem}: estimates.{} = {v}, ran {want}", s.name());
            assert!(
                parsed["estimates"][s.name()]["stderr"].as_f64().is_some(),
                "{stem}: estimates.{}.stderr",
                s.name()
            );
        }
        for f in parsed["files"].as_array().expect("files list") {
            let f = f.as_str().expect("file name");
            assert!(dir.join(f).is_file(), "{stem}: listed output {f} missing");
        }
    }
}

fn pencil_slab() -> (String, String) {
    let path = repo().join("tests/configs/good/pencil_slab.toml");
    (read(&path), path.display().to_string())
}

fn sets(s: &[&str]) -> Vec<String> {
    s.iter().map(|x| x.to_string()).collect()
}

#[test]
fn set_numeric_override_changes_the_layer() {
    let (text, origin) = pencil_slab();
    let (_, exp) = load(&text, &origin, &[]).unwrap();
    assert!((exp.scene.layers[0].z_bottom - 0.5e-3).abs() < 1e-15, "fixture slab is 0.5 mm");
    let (doc, exp) = load(&text, &origin, &sets(&["layers.0.thickness_mm=0.25"])).unwrap();
    assert!((exp.scene.layers[0].z_bottom - 0.25e-3).abs() < 1e-15, "z_bottom = {}", exp.scene.layers[0].z_bottom);
    assert_eq!(doc["layers"][0]["thickness_mm"].as_float(), Some(0.25), "the table as run carries the override");

    // The same through vdh_slab, as in the documentation: 0.2 mm → 0.5 mm.
    let path = repo().join("validation/vdh_slab.toml");
    if path.is_file() {
        let (_, exp) = load_file(&path, &sets(&["layers.0.thickness_mm=0.5"]));
        assert!((exp.scene.layers[0].z_bottom - 0.0005).abs() < 1e-15);
    }

    // An integer is accepted where a float is expected.
    let (_, exp) = load(&text, &origin, &sets(&["layers.0.thickness_mm=2"])).unwrap();
    assert!((exp.scene.layers[0].z_bottom - 2e-3).abs() < 1e-15);
    // Later overrides win.
    let (_, exp) = load(&text, &origin, &sets(&["run.seed=7", "run.seed=9"])).unwrap();
    assert_eq!(exp.plan.seed, 9);
}

#[test]
fn set_bare_word_is_a_string() {
    let (text, origin) = pencil_slab();
    let (doc, exp) = load(&text, &origin, &sets(&["source.profile=disk", "source.radius_mm=0.1"])).unwrap();
    assert_eq!(doc["source"]["profile"].as_str(), Some("disk"));
    match exp.source.profile {
        Profile::Disk { radius } => assert!((radius - 1e-4).abs() < 1e-18, "radius = {radius}"),
        p => panic!("expected a disk profile, got {p:?}"),
    }
    // A quoted string is the same.
    let (_, exp) = load(&text, &origin, &sets(&["source.profile=\"disk\"", "source.radius_mm=0.1"])).unwrap();
    assert!(matches!(exp.source.profile, Profile::Disk { .. }));
    // An unknown bare word is a string, then rejected by the schema naming the key.
    let e = load(&text, &origin, &sets(&["source.profile=ring"])).unwrap_err();
    assert!(e.to_string().contains("source.profile"), "{e}");
    assert!(e.to_string().contains("ring"), "{e}");
}

#[test]
fn set_array_value() {
    let (text, origin) = pencil_slab();
    let (doc, exp) = load(&text, &origin, &sets(&["source.direction=[0,0.1,1]"])).unwrap();
    assert_eq!(doc["source"]["direction"].as_array().map(|a| a.len()), Some(3));
    let d = exp.source.direction.to_array();
    let n = (0.01f64 + 1.0).sqrt();
    let want = [0.0, 0.1 / n, 1.0 / n];
    for k in 0..3 {
        assert!((d[k] - want[k]).abs() < 1e-12, "direction = {d:?}, want {want:?}");
    }
    // Spaces around `=` and inside the array are fine.
    let (_, exp) = load(&text, &origin, &sets(&["source.direction = [0, 0.1, 1]"])).unwrap();
    assert_eq!(exp.source.direction.to_array(), d);
}

#[test]
fn set_index_out_of_range_names_the_path() {
    let (text, origin) = pencil_slab();
    let e = load(&text, &origin, &sets(&["layers.3.thickness_mm=1"])).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("layers.3"), "{msg}");
    assert!(msg.contains("out of range"), "{msg}");
    assert!(msg.contains("array of 1"), "{msg}");
    // A non-numeric index into an array.
    let e = load(&text, &origin, &sets(&["layers.first.thickness_mm=1"])).unwrap_err();
    assert!(e.to_string().contains("layers.first"), "{e}");
    // Descending into a value.
    let e = load(&text, &origin, &sets(&["run.seed.x=1"])).unwrap_err();
    assert!(e.to_string().contains("run.seed"), "{e}");
    assert!(e.to_string().contains("not a table"), "{e}");
}

#[test]
fn set_unknown_key_is_an_unknown_field() {
    let (text, origin) = pencil_slab();
    let e = load(&text, &origin, &sets(&["source.colour=red"])).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("source.colour"), "{msg}");
    assert!(msg.contains("unknown field `colour`"), "{msg}");
    // A new table on the way is created, and then rejected as unknown too.
    let e = load(&text, &origin, &sets(&["optics.focus_mm=3"])).unwrap_err();
    assert!(e.to_string().contains("unknown field `optics`"), "{e}");
}

#[test]
fn set_malformed_assignment() {
    let mut doc = ohd::config::parse("schema_version = 1", "test").unwrap();
    let e = apply_set(&mut doc, "run.samples").unwrap_err();
    assert_eq!(e.path, "--set");
    assert!(e.message.contains("KEY=VALUE"), "{e}");
    for bad in ["=3", "run..samples=3", ".run=3"] {
        let e = apply_set(&mut doc, bad).unwrap_err();
        assert_eq!(e.path, "--set", "{bad}: {e}");
    }
    // A failed override leaves the table usable.
    assert_eq!(doc["schema_version"].as_integer(), Some(1));
    apply_set(&mut doc, "run.samples=10").unwrap();
    assert_eq!(doc["run"]["samples"].as_integer(), Some(10));
}
