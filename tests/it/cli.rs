//! The command line, driven through the built binary: exit statuses, messages and outputs.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use crate::support::files::ohd;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
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
    // The changelog's newest entry and the Python package are this version (the manifest's
    // `ohd_version` is `CARGO_PKG_VERSION` itself).
    let changelog = std::fs::read_to_string(repo().join("CHANGELOG.md")).unwrap();
    let newest = changelog.lines().find_map(|l| l.strip_prefix("## [")).and_then(|l| l.split(']').next());
    assert_eq!(newest, Some(env!("CARGO_PKG_VERSION")), "CHANGELOG.md's newest entry");
    let pyproject = std::fs::read_to_string(repo().join("python/pyproject.toml")).unwrap();
    let line = format!("version = \"{}\"", env!("CARGO_PKG_VERSION"));
    assert!(pyproject.lines().any(|l| l.trim() == line), "python/pyproject.toml: no `{line}`");
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
    assert!(out.contains("slab: 0–200 µm"), "the 0.2 mm slab, in µm: {out}");
    assert!(out.contains("σs 9 mm⁻¹"), "the slab's σs = 9/mm: {out}");
    // Human units, no Debug dumps of internal structs.
    assert!(!out.contains('{') && !out.contains("DVec3"), "{out}");
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

/// Issue 33, item 8: delays, axes and chirps whose derived numbers are not finite passed `ohd
/// check`, then ended the run with non-finite outputs (exit 1), or wrote an axis of infinities or
/// a range of null without a warning (exit 0). Each is a configuration error (exit 2) naming the
/// key, before anything is written.
#[test]
fn derived_quantities_beyond_doubles_exit_2() {
    let tmp = tempfile::tempdir().unwrap();
    for (fixture, key) in [
        ("correlation_delay_ratio_overflows", "detectors[0].correlation.tau_max_s"),
        ("correlation_tau_min_subnormal", "detectors[0].correlation.tau_min_s"),
        ("spectrum_span_overflows", "detectors[0].spectrum.f_max_hz"),
        ("chirp_range_overflows", "source.chirp.duration_s"),
    ] {
        let bad = repo().join(format!("tests/configs/bad/{fixture}.toml"));
        let o = ohd(tmp.path(), &["check", path_str(&bad)]);
        assert_eq!(o.status.code(), Some(2), "{fixture}: {}", describe(&o));
        assert!(text(&o.stderr).contains(&format!("config error: {key}: ")), "{fixture}: {}", describe(&o));
        let out = tmp.path().join(fixture);
        let o = ohd(tmp.path(), &["run", path_str(&bad), "--out", path_str(&out), "--set", "run.samples=1000"]);
        assert_eq!(o.status.code(), Some(2), "{fixture}: {}", describe(&o));
        assert!(!out.exists(), "{fixture}: the output directory was created for a bad config");
    }
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
    // The summary is the command's result, on stdout (`ohd run x.toml > log` keeps it); nothing
    // but messages on stderr.
    let (out, err) = (text(&o.stdout), text(&o.stderr));
    assert!(out.contains("reflectance_diffuse") && out.contains("20000 paths in"), "{}", describe(&o));
    assert!(!err.contains("reflectance_diffuse"), "{err}");
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

/// A number of paths may be written as pmcx takes it, `2e4` (on the command line and in
/// `--set`): the same run as `20000`; a fraction or a negative count is refused with exit 2,
/// naming what is expected, and nothing is written.
#[test]
fn samples_take_a_whole_float_and_refuse_a_fraction() {
    let tmp = tempfile::tempdir().unwrap();
    let config = vdh_slab();
    let run = |name: &str, args: &[&str]| {
        let out = tmp.path().join(name);
        let mut all = vec!["run", path_str(&config), "--quiet", "--out", path_str(&out), "--set", "run.seed=5"];
        all.extend_from_slice(args);
        (ohd(tmp.path(), &all), out)
    };
    let estimate = |out: &Path| read_manifest(out)["estimates"]["absorbed_fraction"]["value"].as_f64().unwrap();
    let (whole, a) = run("whole", &["--samples", "20000"]);
    let (float, b) = run("float", &["--samples", "2e4"]);
    let (set, c) = run("set", &["--set", "run.samples=2.0e4"]);
    for o in [&whole, &float, &set] {
        assert_eq!(o.status.code(), Some(0), "{}", describe(o));
    }
    assert_eq!(estimate(&a).to_bits(), estimate(&b).to_bits());
    assert_eq!(estimate(&a).to_bits(), estimate(&c).to_bits());
    for (name, args) in [("half", ["--samples", "2.5"]), ("minus", ["--set", "run.samples=-3e4"])] {
        let (o, out) = run(name, &args);
        assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
        assert!(text(&o.stderr).contains("whole number of paths"), "{}", describe(&o));
        assert!(!out.exists());
    }
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
    // With no --out the default directory would be out/vessel_in_tissue (the experiment's name):
    // nothing else was written here.
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
    // Nothing on stderr (no warnings here); the summary on stdout: one line per estimate plus
    // the header.
    assert!(err.is_empty(), "{err}");
    let summary = text(&o.stdout);
    assert!(summary.lines().count() <= 8 && summary.contains("reflectance_diffuse"), "{summary}");
}

/// `ohd mie` prints exactly {"x", "qext", "qsca", "qback", "g"}.
fn mie_json(args: &[&str]) -> serde_json::Value {
    let mut all = vec!["mie"];
    all.extend_from_slice(args);
    let o = ohd(&repo(), &all);
    assert!(o.status.success(), "{}", describe(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{e}: {}", describe(&o)));
    let mut keys: Vec<&str> = v.as_object().expect("an object").keys().map(|k| k.as_str()).collect();
    keys.sort();
    assert_eq!(keys, ["g", "qback", "qext", "qsca", "x"]);
    v
}

#[test]
fn mie_prints_efficiencies_for_relative_and_physical_inputs() {
    // Wiscombe's MIEV0 case m = 0.75, x = 10 (validation-values §3).
    let v = mie_json(&["--m-real", "0.75", "--x", "10"]);
    for (k, want) in [("qext", 2.232265), ("qsca", 2.232265), ("g", 0.896473), ("qback", 0.046584)] {
        // The published values round to 6 decimals.
        let got = v[k].as_f64().unwrap();
        assert!((got - want).abs() <= 5e-7, "{k}: {got} vs {want}");
    }
    // Physical inputs: x = π D n_medium / λ, m = (N − iK)/n_medium; the B&H case m = 1.55, x = 5.21282
    // (r = 0.525 µm, λ0 = 0.6328 µm, in air).
    let v = mie_json(&["--diameter-um", "1.05", "--n-particle", "1.55", "--n-medium", "1", "--wavelength-nm", "632.8"]);
    assert!((v["x"].as_f64().unwrap() - 5.21282).abs() < 1e-5, "{v}");
    assert!((v["qext"].as_f64().unwrap() / 3.10543 - 1.0).abs() < 2e-6, "{v}");
    // The same sphere in water: the medium index enters both x and m.
    let w = mie_json(&[
        "--diameter-um",
        "1.05",
        "--n-particle",
        "1.55",
        "--k-particle",
        "0.01",
        "--n-medium",
        "1.33",
        "--wavelength-nm",
        "632.8",
    ]);
    let r = mie_json(&[
        "--m-real",
        &(1.55 / 1.33).to_string(),
        "--m-imag",
        &(0.01 / 1.33).to_string(),
        "--x",
        &(std::f64::consts::PI * 1.05 * 1.33 / 0.6328).to_string(),
    ]);
    for k in ["x", "qext", "qsca", "qback", "g"] {
        assert!((w[k].as_f64().unwrap() / r[k].as_f64().unwrap() - 1.0).abs() < 1e-12, "{k}: {w} vs {r}");
    }
}

#[test]
fn mie_writes_a_phase_table_that_loads() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("rbc.phase.toml");
    let v = mie_json(&[
        "--diameter-um",
        "5.56",
        "--n-particle",
        "1.40",
        "--n-medium",
        "1.345",
        "--wavelength-nm",
        "785",
        "--angles",
        "500",
        "--table",
        path_str(&table),
    ]);
    let loaded = ohd::io::formats::table::read_phase_table(&table).expect("the written table loads");
    assert_eq!(loaded.phase.len(), 500);
    assert_eq!(loaded.file.optics.wavelength_nm, Some(785.0));
    assert_eq!(loaded.file.optics.g, v["g"].as_f64());
    // Written per sr: integrates to 1 up to the linear interpolation of the forward peak.
    assert!((loaded.phase.source_integral() - 1.0).abs() < 0.01, "{}", loaded.phase.source_integral());
    assert!((loaded.phase.mean_cosine() - v["g"].as_f64().unwrap()).abs() < 1e-3);
}

#[test]
fn mie_bad_input_exits_2_with_a_message() {
    for (args, says) in [
        (vec!["mie", "--m-real", "1.5", "--m-imag", "-0.1", "--x", "1"], "--m-imag -0.1: expected k ≥ 0"),
        (vec!["mie", "--m-real", "1.5", "--x", "0"], "--x 0: expected a size parameter > 0"),
        (vec!["mie", "--m-real", "1.5", "--x", "1e9"], "size parameter"),
        (
            vec!["mie", "--diameter-um", "-1", "--n-particle", "1.4", "--n-medium", "1", "--wavelength-nm", "500"],
            "--diameter-um -1: expected a diameter > 0 µm",
        ),
        (vec!["mie", "--m-real", "1.5", "--x", "1", "--angles", "4", "--table", "t.toml"], "--angles 4"),
        (vec!["mie", "--m-real", "1.5"], "--x"),
        (vec!["mie", "--m-real", "1.5", "--x", "1", "--diameter-um", "1"], "cannot be used with"),
    ] {
        let o = ohd(&repo(), &args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", describe(&o));
        assert!(text(&o.stderr).contains(says), "{args:?}: expected `{says}` in\n{}", describe(&o));
        assert!(o.stdout.is_empty(), "{args:?}: printed {}", text(&o.stdout));
    }
    assert!(!repo().join("t.toml").exists());
}

#[test]
fn converge_writes_csv_json_and_png() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("conv");
    let o = ohd(
        tmp.path(),
        &["converge", path_str(&vdh_slab()), "--out", path_str(&out), "--samples", "256000", "--rungs", "3", "-q"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let csv = std::fs::read_to_string(out.join("converge.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("output,samples,seconds,error,stderr"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    // Rd, Tt, unscattered T and absorption against the config's analytic values, 3 rungs each.
    assert_eq!(rows.len(), 12, "{csv}");
    for r in &rows {
        let n: u64 = r[1].parse().unwrap();
        assert!([64_000, 128_000, 256_000].contains(&n), "{r:?}");
        for v in &r[2..] {
            let x: f64 = v.parse().unwrap();
            assert!(x.is_finite() && x >= 0.0, "{r:?}");
        }
    }
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("converge.json")).unwrap()).unwrap();
    assert_eq!(j["main_output"], "reflectance_diffuse");
    assert!(j["reference_run"].is_null(), "analytic references need no reference run: {j}");
    let rd = &j["outputs"]["reflectance_diffuse"];
    assert_eq!(rd["reference"], "analytic");
    assert_eq!(rd["metric"], "absolute");
    for key in ["slope", "seconds_to_1_percent", "seconds_to_0_1_percent", "sigma_ratio_rms", "stderr_slope"] {
        assert!(rd[key].as_f64().is_some_and(f64::is_finite), "{key}: {rd}");
    }
    // Tenfold accuracy costs a hundredfold in time (extrapolated along 1/√N).
    let (t1, t01) = (rd["seconds_to_1_percent"].as_f64().unwrap(), rd["seconds_to_0_1_percent"].as_f64().unwrap());
    assert!((t01 / t1 - 100.0).abs() < 1e-6, "{t1} s → {t01} s");
    assert!(j["skipped"]["reflectance_specular"].is_string(), "{j}");
    let png = std::fs::read(out.join("converge.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    // -q leaves out the log of each run (stderr); the summary table, the study's result, is on
    // stdout.
    let (out, err) = (text(&o.stdout), text(&o.stderr));
    assert!(
        !err.contains("rung 0") && out.contains("reflectance_diffuse") && out.contains("(main)"),
        "{}",
        describe(&o)
    );
}

#[test]
fn converge_reads_a_reference_run_directory() {
    let tmp = tempfile::tempdir().unwrap();
    let reference = tmp.path().join("ref");
    let o = ohd(tmp.path(), &["run", "--samples", "128000", "--seed", "40", "--out", path_str(&reference), "-q"]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let out = tmp.path().join("conv");
    let o = ohd(
        tmp.path(),
        &[
            "converge",
            "--reference",
            path_str(&reference),
            "--out",
            path_str(&out),
            "--samples",
            "64000",
            "--rungs",
            "2",
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("converge.json")).unwrap()).unwrap();
    assert!(j["reference_run"].is_null(), "{j}");
    assert_eq!(j["main_output"], "camera.m0_plus");
    for name in ["camera.spectrum", "camera.image", "camera.detected_power", "reflectance_diffuse"] {
        assert_eq!(j["outputs"][name]["reference"], "directory", "{name}: {j}");
        assert_eq!(j["outputs"][name]["sigma_ratio"].as_array().map(Vec::len), Some(2), "{name}");
    }
    let table = text(&o.stdout);
    assert!(table.contains("camera.spectrum") && table.contains("(main)"), "{}", describe(&o));
}

#[test]
fn converge_bad_input_exits_2_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("conv");
    let missing = tmp.path().join("no_such_run");
    // A reference directory that does not exist; then one of another experiment.
    let o = ohd(tmp.path(), &["converge", "--reference", path_str(&missing), "--out", path_str(&out)]);
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    assert!(text(&o.stderr).contains("no_such_run/manifest.json"), "{}", describe(&o));
    let vdh_run = tmp.path().join("vdh");
    let o = ohd(tmp.path(), &["run", path_str(&vdh_slab()), "--samples", "16000", "--out", path_str(&vdh_run), "-q"]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let o = ohd(tmp.path(), &["converge", "--reference", path_str(&vdh_run), "--out", path_str(&out)]);
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    assert!(text(&o.stderr).contains("is it a run of this experiment?"), "{}", describe(&o));
    for (args, named) in [
        (&["converge", "--budget-seconds", "0"][..], "--budget-seconds"),
        // Issue 21: a budget of 1e300 s without --samples ran without end.
        (&["converge", "--budget-seconds", "1e300"], "--budget-seconds"),
        (&["converge", "--rungs", "1"], "--rungs"),
        (&["converge", "--samples", "10"], "--samples"),
        (&["converge", "--set", "reference.nonsense=1"], "reference.nonsense"),
    ] {
        let mut a = args.to_vec();
        a.extend(["--out", path_str(&out)]);
        let o = ohd(tmp.path(), &a);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", describe(&o));
        assert!(text(&o.stderr).contains(named), "{args:?}: {}", describe(&o));
    }
    assert!(!out.exists(), "nothing is written on bad input");
}

#[test]
fn run_to_a_target_error() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("vdh");
    let o = ohd(
        tmp.path(),
        &["run", path_str(&vdh_slab()), "--samples", "16000", "--target-error", "0.01", "--out", path_str(&out)],
    );
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let m = read_manifest(&out);
    let t = &m["target_error"];
    assert_eq!(t["output"], "reflectance_diffuse");
    assert_eq!(t["met"], true, "{m}");
    let reached = t["reached"].as_f64().unwrap();
    assert!(reached <= 0.01 && reached > 0.005, "{reached}");
    let samples = m["samples"].as_u64().unwrap();
    assert_eq!(samples, 16000 * t["rounds"].as_u64().unwrap());
    assert_eq!(m["main_output"]["relative_error"].as_f64(), Some(reached));
    let rd = &m["estimates"]["reflectance_diffuse"];
    let rel = rd["stderr"].as_f64().unwrap() / rd["value"].as_f64().unwrap();
    assert!((rel - reached).abs() < 1e-12, "{rel} vs {reached}");
    assert!(text(&o.stdout).contains("target error 1.0000% met"), "{}", describe(&o));
    for bad in ["0", "1.5", "nan", "-0.1"] {
        let o = ohd(tmp.path(), &["run", path_str(&vdh_slab()), "--target-error", bad, "--out", path_str(&out)]);
        assert_eq!(o.status.code(), Some(2), "{bad}: {}", describe(&o));
        assert!(text(&o.stderr).contains("--target-error"), "{bad}: {}", describe(&o));
    }
    let o = ohd(
        tmp.path(),
        &["run", path_str(&vdh_slab()), "--samples", "16000", "--target-error", "0.01", "--max-samples", "100"],
    );
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    assert!(text(&o.stderr).contains("--max-samples"), "{}", describe(&o));
}

/// Start `ohd ARGS` in `cwd`, kill it with SIGKILL as soon as `file` exists (or after two
/// minutes), and return how it ended.
fn kill_once_written(cwd: &Path, args: &[String], file: &Path) -> std::process::ExitStatus {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ohd"))
        .args(args)
        .current_dir(cwd)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("ohd starts");
    let t0 = std::time::Instant::now();
    while !file.exists() && t0.elapsed().as_secs() < 120 {
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    child.kill().expect("SIGKILL"); // Child::kill sends SIGKILL on Unix
    child.wait().unwrap()
}

/// A run killed with SIGKILL after a checkpoint finishes with `--resume` (on another thread
/// count) exactly as an uninterrupted run: every `.npy` byte-identical, the same estimates.
#[test]
#[ignore = "deep tier (tens of seconds to minutes): bash .ci/deep"]
fn resume_after_sigkill_equals_an_uninterrupted_run() {
    let tmp = tempfile::tempdir().unwrap();
    let (whole, killed) = (tmp.path().join("whole"), tmp.path().join("killed"));
    let args = |dir: &Path| -> Vec<String> {
        ["run", "--samples", "3000000", "--seed", "12", "-q", "--out", path_str(dir)].map(String::from).to_vec()
    };
    let o = ohd(tmp.path(), &args(&whole).iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let mut a = args(&killed);
    a.extend(["--checkpoint-seconds".into(), "0".into()]);
    let ckpt = killed.join("checkpoint.ohd");
    let status = kill_once_written(tmp.path(), &a, &ckpt);
    assert!(ckpt.exists(), "no checkpoint was written");
    assert!(!killed.join("manifest.json").exists(), "the run finished before it was killed ({status:?})");
    let mut a = args(&killed);
    a.extend(["--resume".into(), "--threads".into(), "1".into()]);
    let o = ohd(tmp.path(), &a.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    assert!(text(&o.stderr).contains("resuming at batch"), "{}", describe(&o));
    assert!(!ckpt.exists(), "the checkpoint outlives the finished run");
    let mut npy = 0;
    for e in std::fs::read_dir(&whole).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "npy") {
            let name = p.file_name().unwrap();
            assert_eq!(std::fs::read(&p).unwrap(), std::fs::read(killed.join(name)).unwrap(), "{name:?} differs");
            npy += 1;
        }
    }
    assert!(npy >= 6, "{npy} .npy files");
    assert_eq!(read_manifest(&whole)["estimates"], read_manifest(&killed)["estimates"]);
    // Resuming again, with no checkpoint left, is refused naming the file.
    let o = ohd(tmp.path(), &a.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(2), "no checkpoint left: {}", describe(&o));
    assert!(text(&o.stderr).contains("checkpoint.ohd"), "{}", describe(&o));
}

/// Start `ohd ARGS` in `cwd`, send it `signal` `times` times (20 ms apart) as soon as `dir`
/// exists (the handler is set by then), and return how it ended.
fn interrupt_once_started(
    cwd: &Path,
    args: &[String],
    dir: &Path,
    signal: rustix::process::Signal,
    times: usize,
) -> Output {
    let child = Command::new(env!("CARGO_BIN_EXE_ohd"))
        .args(args)
        .current_dir(cwd)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ohd starts");
    let t0 = std::time::Instant::now();
    while !dir.exists() && t0.elapsed().as_secs() < 120 {
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    for _ in 0..times {
        rustix::process::kill_process(rustix::process::Pid::from_child(&child), signal).expect("signal sent");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// Ctrl-C keeps the work (issue 37), and so does SIGTERM, a batch system's way of ending a job
/// before its SIGKILL (issue 52: it killed the run and kept nothing): the first signal lets the
/// batches in flight finish, writes the result of the batches done (the manifest says how many of
/// how many; exit 128 + the signal's number) and a checkpoint, which `--resume` finishes into
/// exactly the uninterrupted run. A second signal stops at once and writes nothing.
fn a_stop_signal_writes_the_batches_done(signal: rustix::process::Signal, name: &str, status: i32) {
    let tmp = tempfile::tempdir().unwrap();
    let (whole, cut, stopped) = (tmp.path().join("whole"), tmp.path().join("cut"), tmp.path().join("stopped"));
    let args = |dir: &Path| -> Vec<String> {
        ["run", "--samples", "1000000", "--set", "run.batches=64", "--seed", "5", "-q", "--no-figures", "--out"]
            .iter()
            .map(|s| s.to_string())
            .chain([path_str(dir).to_string()])
            .collect()
    };
    let o = interrupt_once_started(tmp.path(), &args(&cut), &cut, signal, 1);
    assert_eq!(o.status.code(), Some(status), "{}", describe(&o));
    let err = text(&o.stderr);
    assert!(err.contains(&format!("{name}: finishing the batches in flight")) && err.contains("--resume"), "{err}");
    let m = read_manifest(&cut);
    let (done, planned) = (m["interrupted"]["batches"].as_u64().unwrap(), m["interrupted"]["planned_batches"].as_u64());
    assert!((1..64).contains(&done) && planned == Some(64), "{}", m["interrupted"]);
    assert_eq!((m["batches"].as_u64(), m["samples"].as_u64()), (Some(done), Some(done * 1_000_000 / 64)));
    assert!(err.contains(&format!("the result of {done} of 64 batches")), "{err}");
    assert!(m["estimates"]["reflectance_diffuse"]["stderr"].as_f64().unwrap() > 0.0, "σ from the batches done");
    assert!(cut.join("checkpoint.ohd").exists() && !cut.join("ohd_incomplete.txt").exists());

    let mut a = args(&cut);
    a.extend(["--resume".into(), "--threads".into(), "1".into()]);
    let o = ohd(tmp.path(), &a.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    assert!(text(&o.stderr).contains(&format!("resuming at batch {done} of 64")), "{}", describe(&o));
    let o = ohd(tmp.path(), &args(&whole).iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    assert!(assert_same_run(&whole, &cut) >= 6);
    assert!(read_manifest(&cut).get("interrupted").is_none() && !cut.join("checkpoint.ohd").exists());

    let o = interrupt_once_started(tmp.path(), &args(&stopped), &stopped, signal, 2);
    assert_eq!(o.status.code(), Some(status), "{}", describe(&o));
    assert!(!stopped.join("manifest.json").exists() && !stopped.join("checkpoint.ohd").exists());
}

#[test]
fn ctrl_c_writes_the_batches_done_and_resume_finishes_the_run() {
    a_stop_signal_writes_the_batches_done(rustix::process::Signal::INT, "Ctrl-C", 130);
}

#[test]
fn sigterm_writes_the_batches_done_and_resume_finishes_the_run() {
    a_stop_signal_writes_the_batches_done(rustix::process::Signal::TERM, "SIGTERM", 143);
}

/// Every data file of run directory `a` (all but the manifest) is byte-identical in `b`, and the
/// manifests hold the same estimates and statistics of the run; returns the number of files.
fn assert_same_run(a: &Path, b: &Path) -> usize {
    let mut files = 0;
    for e in std::fs::read_dir(a).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_name().unwrap().to_owned();
        if name != "manifest.json" {
            assert_eq!(std::fs::read(&p).unwrap(), std::fs::read(b.join(&name)).unwrap(), "{name:?} differs");
            files += 1;
        }
    }
    let (ma, mb) = (read_manifest(a), read_manifest(b));
    assert_eq!(ma["estimates"], mb["estimates"]);
    for k in ["paths", "scattering_events", "null_collisions", "roulette_terminations", "truncated_paths"] {
        assert_eq!(ma["statistics"][k], mb["statistics"][k], "statistics.{k}");
    }
    files
}

/// `ohd run --shard I/N` on every part (any thread counts) and `ohd merge` (shards in any
/// order) give a single run's outputs byte for byte: the vessel camera's spectra and image, the
/// retina LDH camera's M0± images and ROI speckle, which needs every recorded line in batch
/// order, a camera-estimated LDH camera (camera paths by batch and pixel) and one estimated by
/// camera paths on its footprints' pixels only. Mismatched,
/// missing, repeated and truncated shards are refused (exit 2, nothing written).
#[test]
#[ignore = "deep tier (tens of seconds to minutes): bash .ci/deep"]
fn shards_merge_into_a_single_run() {
    let tmp = tempfile::tempdir().unwrap();
    let retina = repo().join("configs/retina_ldh.toml");
    let camera = repo().join("tests/configs/good/camera_estimator.toml");
    let footprints = repo().join("tests/configs/good/footprints_estimator.toml");
    let light_field = repo().join("tests/configs/good/footprints_light_field.toml");
    let pulsatile = repo().join("tests/configs/good/pulsatile_vessel.toml");
    for (case, config, samples, count, set) in [
        ("vessel", None, "400000", 3u64, None),
        // With the LDH moments: their frequency images are ratios whose σ is a jackknife over
        // groups of batches, the same whatever the shards.
        ("retina", Some(&retina), "200000", 5, Some("detectors.0.ldh.moments=true")),
        ("camera", Some(&camera), "64000", 3, None),
        // Each shard and the merge decide `auto` by the same pilot.
        ("auto", Some(&camera), "64000", 2, Some("detectors.0.estimator=\"auto\"")),
        // Camera paths from the footprints' pixels beside the forward paths, speckle from these.
        ("footprints", Some(&footprints), "64000", 3, None),
        // Every shard makes the same light field's table.
        ("light_field", Some(&light_field), "64000", 3, None),
        // An acquisition over the cardiac cycle, its windows' line slots drawn per batch.
        ("pulsatile", Some(&pulsatile), "64000", 3, None),
    ] {
        let base = |dir: &Path| -> Vec<String> {
            let mut a: Vec<String> = vec!["run".into()];
            a.extend(config.map(|c| path_str(c).to_string()));
            a.extend(["--samples", samples, "--seed", "21", "-q", "--out", path_str(dir)].map(String::from));
            a.extend(set.into_iter().flat_map(|s| ["--set".to_string(), s.to_string()]));
            a
        };
        let run = |args: &[String]| ohd(tmp.path(), &args.iter().map(String::as_str).collect::<Vec<_>>());
        let whole = tmp.path().join(format!("{case}_whole"));
        let o = run(&base(&whole));
        assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
        let shard_dir = |i: u64| tmp.path().join(format!("{case}_shard{i}"));
        for i in 0..count {
            let mut a = base(&shard_dir(i));
            a.extend(["--shard".into(), format!("{i}/{count}"), "--threads".into(), (1 + i % 2).to_string()]);
            let o = run(&a);
            assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
            let files: Vec<_> = std::fs::read_dir(shard_dir(i)).unwrap().map(|e| e.unwrap().file_name()).collect();
            assert_eq!(files, ["shard.ohd"], "a shard writes its part only");
        }
        let merged = tmp.path().join(format!("{case}_merged"));
        let mut a = vec!["merge".to_string()];
        a.extend((0..count).rev().map(|i| path_str(&shard_dir(i)).to_string()));
        a.extend(["--out".into(), path_str(&merged).into()]);
        let o = run(&a);
        assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
        let files = assert_same_run(&whole, &merged);
        assert!(files >= if case == "retina" { 40 } else { 10 }, "{case}: {files} files compared");
        assert_eq!(read_manifest(&merged)["samples"], read_manifest(&whole)["samples"]);
    }
    // Refusals, naming what is wrong; none writes the merged directory.
    let (d0, d1, d2) =
        (tmp.path().join("vessel_shard0"), tmp.path().join("vessel_shard1"), tmp.path().join("vessel_shard2"));
    let other = tmp.path().join("other_seed");
    let o = ohd(
        tmp.path(),
        &["run", "--samples", "400000", "--seed", "22", "-q", "--shard", "1/3", "--out", path_str(&other)],
    );
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let bad = tmp.path().join("bad");
    let cut = tmp.path().join("cut");
    std::fs::create_dir(&cut).unwrap();
    let bytes = std::fs::read(d1.join("shard.ohd")).unwrap();
    std::fs::write(cut.join("shard.ohd"), &bytes[..bytes.len() / 2]).unwrap();
    // One flipped bit in the middle of the batch sums (issue 21: such a shard was merged).
    let flip = tmp.path().join("flip");
    std::fs::create_dir(&flip).unwrap();
    let mut flipped = bytes.clone();
    flipped[bytes.len() / 2] ^= 0x10;
    std::fs::write(flip.join("shard.ohd"), &flipped).unwrap();
    for (dirs, expect) in [
        (vec![&d0, &d1], "2 of 3 missing"),
        (vec![&d0, &d1, &d1, &d2], "given twice"),
        (vec![&d0, &other, &d2], "different run"),
        (vec![&d0, &cut, &d2], "truncated"),
        (vec![&d0, &flip, &d2], "checksum mismatch"),
        (vec![&d0, &bad, &d2], "bad/shard.ohd"),
    ] {
        let mut a = vec!["merge"];
        a.extend(dirs.iter().map(|d| path_str(d)));
        a.extend(["--out", path_str(&bad)]);
        let o = ohd(tmp.path(), &a);
        assert_eq!(o.status.code(), Some(2), "{expect}: {}", describe(&o));
        assert!(text(&o.stderr).contains(expect), "expected {expect:?}: {}", describe(&o));
        assert!(!bad.exists(), "{expect}: a refused merge wrote output");
    }
    for (shard, expect) in [("3/3", "0 ≤ I < N"), ("0/40", "run.batches = 32"), ("a/b", "I/N")] {
        let o = ohd(tmp.path(), &["run", "-q", "--shard", shard, "--out", path_str(&bad)]);
        assert_eq!(o.status.code(), Some(2), "--shard {shard}: {}", describe(&o));
        assert!(text(&o.stderr).contains(expect), "--shard {shard}: {}", describe(&o));
        assert!(!bad.exists());
    }
}

/// A scan (the four pointings of `configs/wind_sunny.toml`) in shards: each shard writes one
/// `pointing_NN/shard.ohd` per pointing, and the merge writes every pointing's run and the VAD
/// wind exactly as a single scan does. A scan killed with SIGKILL after a checkpoint resumes its
/// finished pointings from their kept checkpoints and the rest from theirs or from the start, to
/// the same files; the checkpoints go once the scan is written.
#[test]
fn scans_shard_merge_and_resume_like_a_single_scan() {
    let tmp = tempfile::tempdir().unwrap();
    let config = repo().join("configs/wind_sunny.toml");
    let base = |dir: &Path, samples: &str| -> Vec<String> {
        let mut a: Vec<String> = vec!["run".into(), path_str(&config).into()];
        a.extend(["--samples", samples, "--seed", "4", "-q", "--out", path_str(dir)].map(String::from));
        // Fewer gates and shorter spectra: the per-gate spectral fits would take most of the time.
        a.extend(["--set", "detectors.0.lidar.gates=6", "--set", "detectors.0.lidar.fft_points=256"].map(String::from));
        a
    };
    let run = |args: &[String]| ohd(tmp.path(), &args.iter().map(String::as_str).collect::<Vec<_>>());
    let compare = |a: &Path, b: &Path| {
        assert_eq!(std::fs::read(a.join("vad.csv")).unwrap(), std::fs::read(b.join("vad.csv")).unwrap(), "vad.csv");
        (0..4)
            .map(|i| assert_same_run(&a.join(format!("pointing_{i:02}")), &b.join(format!("pointing_{i:02}"))))
            .sum::<usize>()
    };
    let whole = tmp.path().join("whole");
    let o = run(&base(&whole, "40000"));
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    // Where the time went, per pointing in its manifest and in scan.json, summed there.
    let scan: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(whole.join("scan.json")).unwrap()).unwrap();
    let mut transport = 0.0;
    for (i, p) in scan["pointings"].as_array().unwrap().iter().enumerate() {
        let m = read_manifest(&whole.join(format!("pointing_{i:02}")));
        assert_eq!(p["timing"], m["timing"], "pointing {i}");
        let t = |k: &str| m["timing"][k].as_f64().unwrap();
        assert_eq!(t("transport_seconds"), m["wall_seconds"].as_f64().unwrap());
        assert!(t("gate_fit_seconds") > 0.0 && t("postprocess_seconds") >= t("gate_fit_seconds"), "{}", m["timing"]);
        assert!(t("writing_seconds") > 0.0);
        transport += t("transport_seconds");
    }
    let total = scan["timing"]["transport_seconds"].as_f64().unwrap();
    assert!((total - transport).abs() <= 1e-12 * transport, "{total} vs {transport}");
    let shard = |i: u32| tmp.path().join(format!("shard{i}"));
    for i in 0..2 {
        let mut a = base(&shard(i), "40000");
        a.extend(["--shard".into(), format!("{i}/2")]);
        let o = run(&a);
        assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
        assert!(shard(i).join("pointing_03/shard.ohd").exists());
    }
    let merged = tmp.path().join("merged");
    let o = ohd(tmp.path(), &["merge", path_str(&shard(1)), path_str(&shard(0)), "--out", path_str(&merged)]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    assert!(compare(&whole, &merged) >= 4 * 5);
    // Pointing 2's shards swapped with pointing 1's are refused: a shard knows its pointing.
    std::fs::copy(shard(0).join("pointing_01/shard.ohd"), shard(0).join("pointing_02/shard.ohd")).unwrap();
    let bad = tmp.path().join("bad");
    let o = ohd(tmp.path(), &["merge", path_str(&shard(0)), path_str(&shard(1)), "--out", path_str(&bad)]);
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));

    // Checkpoints: kill the scan once a later pointing has saved one.
    let whole = tmp.path().join("whole_long");
    let o = run(&base(&whole, "200000"));
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let killed = tmp.path().join("killed");
    let mut a = base(&killed, "200000");
    a.extend(["--checkpoint-seconds".into(), "0".into()]);
    let later = killed.join("pointing_01/checkpoint.ohd");
    let status = kill_once_written(tmp.path(), &a, &later);
    assert!(later.exists(), "no checkpoint of pointing 1 was written");
    assert!(!killed.join("vad.csv").exists(), "the scan finished before it was killed ({status:?})");
    let mut a = base(&killed, "200000");
    a.extend(["--resume".into(), "--threads".into(), "1".into()]);
    let o = run(&a);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    assert!(text(&o.stderr).contains("resuming at batch"), "{}", describe(&o));
    compare(&whole, &killed);
    for i in 0..4 {
        assert!(
            !killed.join(format!("pointing_{i:02}/checkpoint.ohd")).exists(),
            "pointing {i}'s checkpoint outlives the scan"
        );
    }

    // Ctrl-C: the pointing in progress is written with its batches done, the scan's directory
    // stays marked incomplete, and `--resume` finishes the scan to the same files.
    let cut = tmp.path().join("cut");
    let o = interrupt_once_started(tmp.path(), &base(&cut, "200000"), &cut, rustix::process::Signal::INT, 1);
    assert_eq!(o.status.code(), Some(130), "{}", describe(&o));
    assert!(cut.join("ohd_incomplete.txt").exists() && !cut.join("vad.csv").exists(), "{}", describe(&o));
    let mut a = base(&cut, "200000");
    a.push("--resume".into());
    let o = run(&a);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    assert!(text(&o.stderr).contains("resuming at batch"), "{}", describe(&o));
    compare(&whole, &cut);
    assert!((0..4).all(|i| !cut.join(format!("pointing_{i:02}/checkpoint.ohd")).exists()));
}

/// A checkpoint interval beyond `Duration`'s range (issue 21: `--checkpoint-seconds 1e300`
/// panicked converting it) means no checkpoint is ever due: the run finishes and writes its outputs.
#[test]
fn a_checkpoint_interval_too_long_to_represent_never_comes_due() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let o =
        ohd(tmp.path(), &["run", "--samples", "20000", "-q", "--checkpoint-seconds", "1e300", "--out", path_str(&out)]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    assert!(out.join("manifest.json").exists() && !out.join("checkpoint.ohd").exists());
}

/// Problems with where outputs go are found before a single path is traced (issue 21): a
/// detector name too long for its file names is a configuration error naming the key (`ohd
/// check` finds it too), and an `--out` that cannot be used ends the run at once (exit 2, issue
/// 33) instead of after the simulation (10¹² paths here: without the check this would not end).
#[test]
fn output_names_and_directories_are_checked_before_the_run() {
    let tmp = tempfile::tempdir().unwrap();
    let long = "d".repeat(300);
    let set = format!("detectors.0.name=\"{long}\"");
    let x = tmp.path().join("x");
    for args in [vec!["check", "--set", &set], vec!["run", "--set", &set, "--out", path_str(&x)]] {
        let cmd = args[0];
        let o = ohd(tmp.path(), &args);
        assert_eq!(o.status.code(), Some(2), "{cmd}: {}", describe(&o));
        let err = text(&o.stderr);
        assert!(err.contains("detectors[0].name") && err.contains("at most 64"), "{cmd}: {err}");
        assert!(err.len() < 400, "the message echoes the whole name: {err}");
    }
    let file = tmp.path().join("a_file");
    std::fs::write(&file, b"not a directory").unwrap();
    let out = file.join("run");
    let o = ohd(tmp.path(), &["run", "--samples", "1000000000000", "-q", "--out", path_str(&out)]);
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    assert!(text(&o.stderr).contains("not a directory"), "{}", describe(&o));
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 1, "nothing is written beside the file");
}

/// Every file ohd reads is read within a limit (issue 21: a path to `/dev/zero` read ~4 GB
/// before failing): a configuration, a phase table, a VDB file, a checkpoint, a shard and a
/// reference run's manifest that are devices, or regular files above their limits (sparse, so
/// nothing is written to disk), are refused at once, naming the file and the limit (exit 2,
/// nothing written).
#[test]
fn input_files_are_read_within_a_limit() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let sparse = |name: &str, size: u64| {
        let p = t.join(name);
        std::fs::File::create(&p).unwrap().set_len(size).unwrap();
        p
    };
    // An endless file of the test's own (never the machine's /dev/zero).
    let special = crate::support::special::special();
    let zero = special.endless();
    let zero_str = path_str(zero);
    let kind = if special.zero.is_some() { "a character device" } else { "a FIFO" };
    let big_config = sparse("big.toml", (64 << 20) + 1);
    let out = t.join("out");
    let refused = |args: &[&str], expect: &[&str]| {
        let start = std::time::Instant::now();
        let o = ohd(t, args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", describe(&o));
        let err = text(&o.stderr);
        for e in expect {
            assert!(err.contains(e), "{args:?}: expected {e:?} in {err}");
        }
        assert!(start.elapsed().as_secs() < 20, "{args:?} took {:?}", start.elapsed());
        assert!(!out.exists(), "{args:?} wrote output");
    };
    refused(&["check", zero_str], &[zero_str, &format!("not a regular file ({kind})"), "configuration file"]);
    refused(&["run", zero_str, "--out", path_str(&out)], &[zero_str, "not a regular file"]);
    refused(&["check", path_str(&big_config)], &["big.toml", "67108865 bytes, above the limit of 67108864 bytes"]);
    refused(&["check", path_str(t)], &["not a regular file (a directory)"]);

    // A phase table and a VDB file named by a configuration.
    let table = std::fs::read_to_string(repo().join("tests/configs/bad/table_missing_file.toml")).unwrap();
    let config = t.join("table.toml");
    std::fs::write(&config, table.replace("no_such_table.phase.toml", zero_str)).unwrap();
    refused(&["check", path_str(&config)], &["media.m.phase.file", zero_str, "not a regular file"]);
    std::fs::write(&config, table.replace("no_such_table.phase.toml", "big.phase.toml")).unwrap();
    sparse("big.phase.toml", (64 << 20) + 1);
    refused(
        &["check", path_str(&config)],
        &["media.m.phase.file", "above the limit of 67108864 bytes for a phase table"],
    );
    let vdb = std::fs::read_to_string(repo().join("tests/configs/bad/vdb_missing_file.toml")).unwrap();
    let config = t.join("vdb.toml");
    std::fs::write(&config, vdb.replace("../../fixtures/vdb_media/no_such.vdb", zero_str)).unwrap();
    refused(&["check", path_str(&config)], &["media.tissue.density.file", zero_str, "not a regular file"]);
    std::fs::write(&config, vdb.replace("../../fixtures/vdb_media/no_such.vdb", "big.vdb")).unwrap();
    sparse("big.vdb", (4 << 30) + 1);
    refused(
        &["check", path_str(&config)],
        &["big.vdb", "4294967297 bytes, above the limit of 4294967296 bytes for an OpenVDB file"],
    );

    // A checkpoint to resume from: a device, or above its limit (tied to the memory budget).
    let runs = t.join("runs");
    std::fs::create_dir(&runs).unwrap();
    let ckpt = runs.join("checkpoint.ohd");
    std::os::unix::fs::symlink(zero, &ckpt).unwrap();
    let o = ohd(t, &["run", "-q", "--resume", "--out", path_str(&runs)]);
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    assert!(text(&o.stderr).contains("checkpoint.ohd: not a regular file"), "{}", describe(&o));
    std::fs::remove_file(&ckpt).unwrap();
    std::fs::File::create(&ckpt).unwrap().set_len(64 << 20).unwrap();
    let o = ohd(t, &["run", "-q", "--resume", "--set", "run.memory_budget_gib=0.01", "--out", path_str(&runs)]);
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    assert!(text(&o.stderr).contains("above the limit of"), "{}", describe(&o));
    assert_eq!(std::fs::read_dir(&runs).unwrap().count(), 1, "only the checkpoint is there");

    // A shard to merge and a reference run's manifest.
    let shard = t.join("shard");
    std::fs::create_dir(&shard).unwrap();
    std::os::unix::fs::symlink(zero, shard.join("shard.ohd")).unwrap();
    refused(&["merge", path_str(&shard), "--out", path_str(&out)], &["shard.ohd", "not a regular file"]);
    std::os::unix::fs::symlink(zero, shard.join("manifest.json")).unwrap();
    refused(
        &["converge", "--reference", path_str(&shard), "--rungs", "2", "--out", path_str(&out)],
        &["manifest.json", "not a regular file"],
    );
}

/// Error messages stay short whatever the input (issue 21): a 1 MB key is shown cut with its
/// length, a 1 MB TOML line as a window around the error, 1e300 as `1e300` (not 301 digits, also
/// in serde's type errors), and a list of 10 000 names as its first few and how many more.
#[test]
fn error_messages_are_bounded() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let refused = |args: &[&str], expect: &[&str], max_len: usize| {
        let o = ohd(t, args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", describe(&o));
        let err = text(&o.stderr);
        assert!(err.len() <= max_len, "{} bytes of stderr: {}", err.len(), &err[..err.len().min(2000)]);
        for e in expect {
            assert!(err.contains(e), "expected {e:?} in {err}");
        }
    };
    let write = |name: &str, text: &str| {
        let p = t.join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let key = write("key.toml", &format!("schema_version = 1\n{} = 3\n", "k".repeat(1 << 20)));
    refused(&["check", path_str(&key)], &["kkk…kkk", "(1048576 characters)", "unknown field", "expected one of"], 1000);
    let line = write("line.toml", &format!("schema_version = 1\nx = {}\n", "v".repeat(1 << 20)));
    refused(&["check", path_str(&line)], &["line 2, column 5", "x = vvv", "vvv…\n", "    ^^^", "must be quoted"], 1000);
    let big = "1e300";
    for (set, expect) in [
        (format!("media.tissue.phase.g={big}"), "media.tissue.phase.g: = 1e300: expected"),
        (format!("layers.0.thickness_mm=-{big}"), "= -1e300: expected a thickness"),
        ("source.wavelength_nm=1e-320".into(), "= 1e-320: expected a vacuum wavelength"),
        (format!("run.samples={big}"), "floating point `1e300`, expected a whole number of paths"),
        ("run.seed=2.5".into(), "run.seed: invalid type: floating point `2.5`, expected a whole number ≥ 0"),
    ] {
        refused(&["check", "--set", &set], &[expect], 300);
    }
    refused(&["run", "--target-error", big], &["--target-error 1e300: expected"], 300);
    // A typo'd key: the nearest key suggested before the list of them all.
    refused(
        &["check", "--set", "run.sampels=3"],
        &["unknown field `sampels` (did you mean `samples`?), expected one of"],
        1000,
    );
    let mut many = String::from("schema_version = 1\n[source]\nwavelength_nm = 785\n");
    for i in 0..10_000 {
        many.push_str(&format!("[media.m{i}]\nsigma_a_per_mm = 0.1\nsigma_s_per_mm = 1\n"));
    }
    for i in 0..10_000 {
        many.push_str(&format!("[[layers]]\nname = \"l{i}\"\nthickness_mm = 1\nn = 1.4\nmedium = \"m{}\"\n", i % 3));
    }
    let region = "[[regions]]\nlayer = \"nope\"\nmedium = \"m1\"\nshape = { type = \"sphere\", center_mm = [0, 0, 0.5], radius_mm = 0.1 }\n";
    let path = write("many_layers.toml", &format!("{many}{region}"));
    refused(&["check", path_str(&path)], &["unknown layer; layers are l0, l1, l10, l100,", "… and 9990 more"], 300);
    let path = write("many_media.toml", &many.replacen("medium = \"m0\"", "medium = \"nope\"", 1));
    refused(&["check", path_str(&path)], &["unknown medium; defined media: m0, m1, m10,", "… and 9990 more"], 300);
}

/// The names in directory `d`, sorted.
fn listing(d: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    v.sort();
    v
}

/// An output directory holds one complete output or is marked incomplete (issue 21): a run
/// replaces the files of an earlier run (other options, other names) and of an interrupted one,
/// and ohd's stale temporary files, but never the files of others; a write that fails half-way
/// leaves `ohd_incomplete.txt` listing its files and no manifest, and a reference run in that state
/// is refused; a scan replaces an earlier scan's pointing directories, and a run a scan's.
#[test]
fn output_directories_hold_one_complete_output() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let out = t.join("out");
    std::fs::create_dir(&out).unwrap();
    let user = ["notes.txt", "mine.npy", ".mine.npy.tmp-7"];
    for f in user {
        std::fs::write(out.join(f), "the user's").unwrap();
    }
    // Temporary files a killed ohd left: of a checkpoint and of a file this run writes.
    for f in [".checkpoint.ohd.tmp-4194305", ".camera_spectrum.npy.tmp-4194305"] {
        std::fs::write(out.join(f), "killed").unwrap();
    }
    let run = |sets: &[&str]| {
        let mut a = vec!["run", "--samples", "20000", "-q", "--out", path_str(&out)];
        sets.iter().for_each(|s| a.extend(["--set", s]));
        ohd(t, &a)
    };
    // The directory holds the user's files, and exactly the manifest's.
    let complete = |what: &str| {
        let m = read_manifest(&out);
        let mut expect: Vec<String> =
            m["files"].as_array().unwrap().iter().map(|f| f.as_str().unwrap().into()).collect();
        expect.extend(user.iter().map(|f| f.to_string()));
        expect.push("manifest.json".into());
        expect.sort();
        assert_eq!(listing(&out), expect, "{what}");
    };
    let o = run(&[]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    complete("the first run");
    assert!(out.join("camera_spectrum_by_order.npy").exists());
    let o = run(&["detectors.0.name=cam", "detectors.0.spectrum.by_doppler_events=1"]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    complete("a run with other options");
    assert!(out.join("cam_spectrum.npy").exists() && !out.join("camera_spectrum.npy").exists());

    // A write that fails half-way (a directory where its image goes): marked incomplete.
    std::fs::create_dir(out.join("cam2_image.exr")).unwrap();
    let o = run(&["detectors.0.name=cam2"]);
    assert_eq!(o.status.code(), Some(1), "{}", describe(&o));
    assert!(text(&o.stderr).contains("cam2_image.exr"), "{}", describe(&o));
    let names = listing(&out);
    assert!(!names.contains(&"manifest.json".to_string()), "the earlier manifest outlives its run: {names:?}");
    assert!(names.iter().all(|n| !n.starts_with("cam_")), "files of the earlier run stay: {names:?}");
    assert!(names.contains(&"cam2_spectrum.npy".to_string()), "{names:?}");
    assert!(!names.iter().any(|n| n.contains(".tmp-") && !user.contains(&n.as_str())), "{names:?}");
    let marker = std::fs::read_to_string(out.join("ohd_incomplete.txt")).expect("marked incomplete");
    assert!(marker.contains("\ncam2_spectrum.npy\n") && marker.contains("\ncam2_image.exr\n"), "{marker}");
    let o = ohd(t, &["converge", "--reference", path_str(&out), "--rungs", "2", "--out", path_str(&t.join("c"))]);
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    assert!(text(&o.stderr).contains("incomplete"), "{}", describe(&o));
    // The next run replaces what the interrupted one wrote.
    std::fs::remove_dir(out.join("cam2_image.exr")).unwrap();
    let o = run(&[]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    complete("a run after an interrupted one");

    // A study beside the run leaves it; a shard removes a killed shard's temporary file.
    let o = ohd(t, &["converge", "--rungs", "2", "--samples", "64", "--budget-seconds", "5", "--out", path_str(&out)]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    assert!(out.join("converge.json").exists() && out.join("manifest.json").exists());
    let shard = t.join("shard");
    std::fs::create_dir(&shard).unwrap();
    std::fs::write(shard.join(".shard.ohd.tmp-4194305"), "killed").unwrap();
    let o = ohd(t, &["run", "--samples", "20000", "-q", "--shard", "0/2", "--out", path_str(&shard)]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    assert_eq!(listing(&shard), ["shard.ohd"]);

    // Scans: four pointings, then three, then a plain run.
    let scan = t.join("scan");
    let config = repo().join("configs/wind_sunny.toml");
    let scan_run = |sets: &[&str]| {
        let mut a = vec!["run", path_str(&config), "--samples", "8000", "-q", "--out", path_str(&scan)];
        let small = ["detectors.0.lidar.gates=6", "detectors.0.lidar.fft_points=256"];
        small.iter().chain(sets).for_each(|s| a.extend(["--set", s]));
        ohd(t, &a)
    };
    let o = scan_run(&[]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    std::fs::write(scan.join("pointing_03/mine.txt"), "the user's").unwrap();
    let o = scan_run(&["source.pointings_deg=[[0, 60], [120, 60], [240, 60]]"]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let pointings = ["pointing_00", "pointing_01", "pointing_02", "pointing_03"];
    assert_eq!(
        listing(&scan),
        [&pointings[..], &["scan.json", "vad.csv", "vad_wind_profile.png", "vad_wind_profile.svg"]].concat()
    );
    assert_eq!(listing(&scan.join("pointing_03")), ["mine.txt"], "the earlier 4th pointing's files stay");
    let o = ohd(t, &["run", "--samples", "20000", "-q", "--out", path_str(&scan)]);
    assert_eq!(o.status.code(), Some(0), "{}", describe(&o));
    let names = listing(&scan);
    assert!(names.contains(&"manifest.json".to_string()) && names.contains(&"pointing_03".to_string()), "{names:?}");
    assert!(
        !names
            .iter()
            .any(|n| ["pointing_00", "pointing_01", "pointing_02", "scan.json", "vad.csv"].contains(&n.as_str())),
        "{names:?}"
    );
}
