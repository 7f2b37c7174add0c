//! The command line, driven through the built binary: exit statuses, messages and outputs.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Run `ohd args…` in `cwd` with every standard stream piped (not a terminal).
fn ohd(cwd: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ohd"))
        .args(args)
        .current_dir(cwd)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .output()
        .expect("ohd starts")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn describe(o: &Output) -> String {
    format!("status {:?}\n--- stdout\n{}\n--- stderr\n{}", o.status.code(), text(&o.stdout), text(&o.stderr))
}

fn path_str(p: &Path) -> &str {
    p.to_str().expect("UTF-8 path")
}

fn vdh_slab() -> PathBuf {
    repo().join("validation/vdh_slab.toml")
}

fn read_manifest(dir: &Path) -> serde_json::Value {
    let p = dir.join("manifest.json");
    let s = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("cannot read {}: {e}", p.display()));
    serde_json::from_str(&s).expect("manifest.json parses")
}

#[test]
fn version() {
    let tmp = tempfile::tempdir().unwrap();
    let o = ohd(tmp.path(), &["--version"]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let out = text(&o.stdout);
    assert!(out.contains("ohd"), "{out}");
    assert!(out.contains(env!("CARGO_PKG_VERSION")), "{out}");
}

#[test]
fn check_prints_the_resolved_experiment() {
    let tmp = tempfile::tempdir().unwrap();
    let o = ohd(tmp.path(), &["check", path_str(&vdh_slab())]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let out = text(&o.stdout);
    assert!(out.contains("valid"), "{out}");
    assert!(out.contains("layers:"), "{out}");
    assert!(out.contains("slab"), "{out}");
    assert!(out.contains("0.2000 mm"), "the 0.2 mm slab: {out}");
    assert!(out.contains("paths"), "{out}");
    // `check` writes nothing.
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0, "check wrote files");
}

#[test]
fn bad_config_exits_2_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let bad = repo().join("tests/configs/bad/zero_thickness.toml");
    let out = tmp.path().join("x");
    let o = ohd(tmp.path(), &["run", path_str(&bad), "--out", path_str(&out)]);
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    let err = text(&o.stderr);
    assert!(err.contains("layers[0].thickness_mm"), "{err}");
    assert!(err.contains("> 0"), "{err}");
    assert!(!out.exists(), "the output directory was created for a bad config");
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0, "something was written");

    // The same through `check`.
    let o = ohd(tmp.path(), &["check", path_str(&bad)]);
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    assert!(text(&o.stderr).contains("layers[0].thickness_mm"), "{}", describe(&o));
}

#[test]
fn bad_set_value_exits_2() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("x");
    let o =
        ohd(tmp.path(), &["run", path_str(&vdh_slab()), "--out", path_str(&out), "--set", "media.slab.phase.g=1.5"]);
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    assert!(text(&o.stderr).contains("media.slab.phase.g"), "{}", describe(&o));
    assert!(!out.exists());
}

#[test]
fn missing_config_file_exits_2_and_names_it() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("no_such_experiment.toml");
    for cmd in ["run", "check"] {
        let o = ohd(tmp.path(), &[cmd, path_str(&missing)]);
        assert_eq!(o.status.code(), Some(2), "{cmd}: {}", describe(&o));
        assert!(text(&o.stderr).contains("no_such_experiment.toml"), "{cmd}: {}", describe(&o));
    }
    assert!(!tmp.path().join("out").exists());
}

#[test]
fn run_writes_the_manifest() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("vdh");
    let o = ohd(
        tmp.path(),
        &["run", path_str(&vdh_slab()), "--samples", "20000", "--out", path_str(&out), "--set", "run.seed=5"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let m = read_manifest(&out);
    for key in ["reflectance_diffuse", "transmittance_total", "reflectance_specular", "absorbed_fraction"] {
        let e = &m["estimates"][key];
        let v = e["value"].as_f64().unwrap_or_else(|| panic!("estimates.{key}.value missing: {m}"));
        let s = e["stderr"].as_f64().unwrap_or_else(|| panic!("estimates.{key}.stderr missing: {m}"));
        assert!(v.is_finite() && (0.0..=1.0).contains(&v), "estimates.{key}.value = {v}");
        assert!(s.is_finite() && s >= 0.0, "estimates.{key}.stderr = {s}");
    }
    // van de Hulst slab: Rd = 0.09739, Tt = 0.66096; 20000 paths are good to well under 0.02.
    let rd = m["estimates"]["reflectance_diffuse"]["value"].as_f64().unwrap();
    let tt = m["estimates"]["transmittance_total"]["value"].as_f64().unwrap();
    assert!((rd - 0.09739).abs() < 0.02, "Rd = {rd}");
    assert!((tt - 0.66096).abs() < 0.02, "Tt = {tt}");
    assert_eq!(m["seed"].as_u64(), Some(5), "{m}");
    assert!(m["samples"].as_u64().unwrap() >= 20000, "{m}");
    let overrides: Vec<&str> =
        m["overrides"].as_array().expect("overrides").iter().filter_map(|v| v.as_str()).collect();
    assert!(overrides.contains(&"run.seed=5"), "{overrides:?}");
    assert!(overrides.contains(&"run.samples=20000"), "{overrides:?}");
    assert_eq!(m["config"]["run"]["seed"].as_u64(), Some(5), "the config as run carries the override");
    assert!(m["config_source"].as_str().unwrap().contains("vdh_slab.toml"), "{m}");
    // The summary goes to stderr; stdout stays clean.
    let err = text(&o.stderr);
    assert!(err.contains("reflectance_diffuse"), "{err}");
    // Nothing is written outside --out.
    let entries: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(entries, vec![std::ffi::OsString::from("vdh")]);
}

#[test]
fn malformed_set_exits_2() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("x");
    let o = ohd(tmp.path(), &["run", path_str(&vdh_slab()), "--out", path_str(&out), "--set", "run.seed"]);
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    let err = text(&o.stderr);
    assert!(err.contains("--set"), "{err}");
    assert!(err.contains("KEY=VALUE"), "{err}");
    assert!(!out.exists());
}

#[test]
fn default_experiment_without_config() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("default");
    let o = ohd(tmp.path(), &["run", "--samples", "3000", "--out", path_str(&out)]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let m = read_manifest(&out);
    assert_eq!(m["name"].as_str(), Some("vessel_in_tissue"), "{m}");
    assert!(m["config_source"].as_str().unwrap().contains("default"), "{m}");
    for f in [
        "camera_frequency_hz.npy",
        "camera_spectrum.npy",
        "camera_spectrum_stderr.npy",
        "camera_spectrum_by_order.npy",
        "camera_spectrum_by_order_stderr.npy",
        "camera_spectrum_by_doppler_events.npy",
        "camera_spectrum_by_doppler_events_stderr.npy",
        "camera_image.npy",
        "camera_image_stderr.npy",
        "camera_image.exr",
    ] {
        assert!(out.join(f).is_file(), "{f} missing; files: {}", m["files"]);
    }
    // The frequency axis: 201 bins as configured.
    let npy = std::fs::read(out.join("camera_frequency_hz.npy")).unwrap();
    assert_eq!(&npy[..6], b"\x93NUMPY");
    assert!(text(&npy[..128.min(npy.len())]).contains("(201,)"), "{}", text(&npy[..128.min(npy.len())]));
    assert_eq!(m["detectors"]["camera"]["spectrum"]["bins"].as_u64(), Some(201), "{m}");
    // With no --out the default directory would be out/default: nothing else was written here.
    assert!(!tmp.path().join("out").exists());
}

#[test]
fn no_progress_bar_when_not_a_terminal() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("quiet");
    let o = ohd(tmp.path(), &["run", path_str(&vdh_slab()), "--samples", "50000", "--out", path_str(&out)]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let err = text(&o.stderr);
    assert!(!err.contains('\r'), "carriage returns (a progress bar?) in piped stderr: {err:?}");
    assert!(!err.contains('\u{1b}'), "escape sequences (a progress bar?) in piped stderr: {err:?}");
    assert!(!err.contains("ETA"), "{err:?}");
    assert!(out.join("manifest.json").is_file());
    // Only the summary: one line per estimate plus the header.
    assert!(err.lines().count() <= 8, "{err}");
}
