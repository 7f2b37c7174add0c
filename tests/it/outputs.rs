//! The files of a run as the output scheme states them (`src/lib.rs`, conventions), through the
//! built binary, for each kind of detector: every file the manifest lists exists, is the
//! detector's (`<detector>_<output>`) and is all the directory holds besides `manifest.json`,
//! and every file name the manifest mentions is one of them; every image-like array — `.npy`, and
//! the `.exr` channel of the same name — has row 0 = the largest `y` and columns `x` ascending,
//! checked on a scene whose light is many σ brighter at `+x`, `+y`; EXR channels say what they
//! hold; the default output folder is named after the experiment.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Output;

use ohd::io::formats::npy;

use crate::support::scenes;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Run `ohd args…` in `cwd`; panics unless it exits 0.
fn ohd(cwd: &Path, args: &[&str]) -> Output {
    let o = crate::support::files::ohd(cwd, args);
    assert_eq!(o.status.code(), Some(0), "ohd {args:?}: {}", String::from_utf8_lossy(&o.stderr));
    o
}

/// An absorbing, scattering slab moving away from the camera (+z, receding: a positive Doppler
/// line) lit by a narrow beam at (+0.5, +0.5) mm, and a 2 × 2 mm camera of 8 × 8 pixels over
/// it with a spectrum: light leaves the slab within ~0.2 mm (μ_eff ≈ 5.7/mm) of the beam, so
/// the top-right quadrant of every image is far brighter than the rest.
fn surface() -> String {
    let slab = r#"[source]
wavelength_nm = 785
profile = "disk"
radius_um = 100
position_mm = [0.5, 0.5, -1]
[ambient]
n_above = 1.0
[media.tissue]
sigma_a_per_mm = 1
sigma_s_per_mm = 10
phase = { type = "isotropic" }
velocity = { type = "uniform", velocity_mm_per_s = [0, 0, 3] }
[[layers]]
thickness_mm = 2
n = 1.4
medium = "tissue"
"#;
    let spectrum = r#"[detectors.spectrum]
f_min_khz = -30
f_max_khz = 30
bins = 30
by_order = 2
by_doppler_events = 2
"#;
    let header = scenes::header(40_000, 11, 16);
    format!("name = \"surface camera/1\"{header}{slab}{}{spectrum}", scenes::camera(2.0, 30.0, 8))
}

/// [`surface`]'s camera made an LDH camera with every output: M1, M0± by class, per-pixel
/// spectra and speckle, an ROI over the bright quadrant with its speckle.
const LDH: &str = r#"
[detectors.ldh]
frame_rate_khz = 78
window_samples = 64
band_khz = [2, 30]
m1 = true
by_class = true
pixel_spectra = true
[detectors.ldh.speckle]
windows = 3
pixels = true
[[detectors.ldh.roi]]
name = "spot"
center_um = [500, 500]
size_um = [500, 500]
"#;

/// The directory listing of `dir`, names only.
fn listing(dir: &Path) -> BTreeSet<String> {
    std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect()
}

fn read_json(path: &Path) -> serde_json::Value {
    let s = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&s).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Every string in `v` that looks like the name of a file of a run.
fn file_names(v: &serde_json::Value, out: &mut BTreeSet<String>) {
    match v {
        serde_json::Value::String(s) => {
            let plain = s.chars().all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c));
            if plain && [".npy", ".exr", ".png", ".svg", ".csv"].iter().any(|e| s.ends_with(e)) {
                out.insert(s.clone());
            }
        }
        serde_json::Value::Array(a) => a.iter().for_each(|x| file_names(x, out)),
        serde_json::Value::Object(m) => m.iter().filter(|(k, _)| *k != "config").for_each(|(_, x)| file_names(x, out)),
        _ => {}
    }
}

/// The run directory `dir` of a run with the one detector `detector`: the manifest's `files` are
/// exactly the directory's other entries, each named `<detector>_…`, and every file name the
/// manifest mentions (`frequency_file`, speckle files, plots, …) is among them. Returns the
/// manifest and the files.
fn check_run_dir(dir: &Path, detector: &str) -> (serde_json::Value, BTreeSet<String>) {
    let m = read_json(&dir.join("manifest.json"));
    let files: BTreeSet<String> =
        m["files"].as_array().expect("a file list").iter().map(|f| f.as_str().unwrap().to_string()).collect();
    let mut on_disk = listing(dir);
    assert!(on_disk.remove("manifest.json"));
    assert_eq!(files, on_disk, "{}: the manifest's files and the directory differ", dir.display());
    for f in &files {
        assert!(dir.join(f).is_file(), "{f} is not a file");
        assert!(f.starts_with(&format!("{detector}_")), "{f} is not named <detector>_<output> ({detector})");
    }
    let mut mentioned = BTreeSet::new();
    file_names(&m, &mut mentioned);
    let missing: Vec<&String> = mentioned.difference(&files).collect();
    assert!(missing.is_empty(), "{}: the manifest mentions files not written: {missing:?}", dir.display());
    (m, files)
}

fn load(path: &Path) -> (Vec<usize>, Vec<f64>) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    npy::from_bytes(&bytes).unwrap_or_else(|| panic!("{} is not an ohd .npy", path.display()))
}

/// Sums over the top and bottom halves of the rows and the left and right halves of the
/// columns of an `ny × nx` image: `[top, bottom, left, right]`.
fn halves(v: &[f64], ny: usize, nx: usize) -> [f64; 4] {
    let mut h = [0.0; 4];
    for (p, &x) in v.iter().enumerate() {
        let (iy, ix) = (p / nx, p % nx);
        h[if iy < ny / 2 { 0 } else { 1 }] += x;
        h[if ix < nx / 2 { 2 } else { 3 }] += x;
    }
    h
}

/// Image `v` (`ny × nx`) has its light in the top rows and the right columns: each bright half
/// holds more than 4× its opposite half, and, with standard errors `se`, exceeds it by more than
/// 10 σ (σ the quadrature sum over the image's pixels, an upper bound for either difference).
fn assert_top_right(what: &str, v: &[f64], se: Option<&[f64]>, ny: usize, nx: usize) {
    let [top, bottom, left, right] = halves(v, ny, nx);
    assert!(top > 4.0 * bottom.abs(), "{what}: top rows {top:e}, bottom rows {bottom:e}: not row 0 = largest y");
    assert!(right > 4.0 * left.abs(), "{what}: right columns {right:e}, left {left:e}: not x ascending");
    let z = se.map(|se| {
        let sigma = se.iter().map(|s| s * s).sum::<f64>().sqrt();
        ((top - bottom) / sigma).min((right - left) / sigma)
    });
    eprintln!("{what}: top/bottom {:.1}, right/left {:.1}, {z:?} σ", top / bottom, right / left);
    if let Some(z) = z {
        assert!(z > 10.0, "{what}: the bright halves exceed the others by only {z:.1} σ");
    }
}

/// The channels of an EXR file: `(name, width, height, values)`.
fn exr_channels(path: &Path) -> Vec<(String, usize, usize, Vec<f32>)> {
    use exr::prelude::*;
    let image = read_all_flat_layers_from_file(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let layer = &image.layer_data[0];
    let (w, h) = (layer.size.width(), layer.size.height());
    layer
        .channel_data
        .list
        .iter()
        .map(|c| {
            let values = match &c.sample_data {
                FlatSamples::F32(v) => v.clone(),
                other => panic!("{}: channel {} is not f32: {other:?}", path.display(), c.name),
            };
            (c.name.to_string(), w, h, values)
        })
        .collect()
}

/// Every image of a run of [`surface`] or [`surface`] + [`LDH`] in `dir` with its light in the
/// top-right quadrant, and each `.exr` holding its `.npy`'s values under the channel names of the
/// scheme. Returns the images checked.
fn check_images(dir: &Path, files: &BTreeSet<String>) -> BTreeSet<String> {
    let (ny, nx) = (8, 8);
    let mut checked = BTreeSet::new();
    for f in files.iter().filter(|f| f.ends_with(".npy") && !f.ends_with("_stderr.npy")) {
        let stem = f.trim_end_matches(".npy");
        let (shape, v) = load(&dir.join(f));
        let se_file = dir.join(format!("{stem}_stderr.npy"));
        let se = se_file.exists().then(|| load(&se_file).1);
        match shape[..] {
            [8, 8] if stem.ends_with("_relative_error") => {
                // σ/|value| is smallest where the light is: the top-right quadrant (no signal,
                // NaN, counts as the largest).
                let r: Vec<f64> = v.iter().map(|&x| if x.is_nan() { f64::INFINITY } else { x }).collect();
                let quadrant = |top: bool, right: bool| -> Vec<f64> {
                    let mut q: Vec<f64> = (0..ny * nx)
                        .filter(|p| (p / nx < ny / 2) == top && (p % nx >= nx / 2) == right)
                        .map(|p| r[p])
                        .collect();
                    q.sort_by(f64::total_cmp);
                    q
                };
                let (bright, dark) = (quadrant(true, true), quadrant(false, false));
                assert!(bright[bright.len() / 2] < dark[dark.len() / 2], "{f}: {bright:?} against {dark:?}");
                checked.insert(f.clone());
            }
            [8, 8] => {
                // Images resolved from zero (the static class's M0 is none: its paths are at DC).
                let total: f64 = v.iter().sum();
                let sigma = se.as_ref().map_or(0.0, |s| s.iter().map(|s| s * s).sum::<f64>().sqrt());
                if total != 0.0 && total.abs() > 20.0 * sigma {
                    assert_top_right(f, &v, se.as_deref(), ny, nx);
                    checked.insert(f.clone());
                }
            }
            [windows, 8, 8] => {
                for (j, w) in v.chunks_exact(ny * nx).enumerate() {
                    assert_top_right(&format!("{f} window {j}"), w, None, ny, nx);
                }
                assert_eq!(windows, 3);
                checked.insert(f.clone());
            }
            [8, 8, bins] => {
                let image: Vec<f64> = v.chunks_exact(bins).map(|s| s.iter().sum()).collect();
                assert_top_right(&format!("{f} summed over its bins"), &image, None, ny, nx);
                checked.insert(f.clone());
            }
            _ => {}
        }
        let exr = dir.join(format!("{stem}.exr"));
        if exr.exists() {
            // The channel is the output's name without the detector: `camera_image` holds the
            // intensity, `camera_m0_plus` M0+.
            let what = stem.strip_prefix("camera_").expect("a camera file");
            let what = if what == "image" { "intensity" } else { what };
            let channels = exr_channels(&exr);
            let names: Vec<&str> = channels.iter().map(|c| c.0.as_str()).collect();
            let stderr_name = format!("{what}_stderr");
            let mut want = vec![what, stderr_name.as_str()];
            want.sort();
            assert_eq!(names, want, "{stem}.exr");
            for (name, w, h, values) in &channels {
                assert_eq!((*w, *h), (nx, ny), "{stem}.exr");
                let npy = if name == what { &v } else { se.as_ref().expect("standard errors") };
                let same = values.iter().zip(npy).all(|(&a, &b)| a == b as f32);
                assert!(same && values.len() == npy.len(), "{stem}.exr channel {name} differs from the .npy");
            }
            if what == "intensity" || what == "m0_plus" {
                let as_f64: Vec<f64> =
                    channels.iter().find(|c| c.0 == what).unwrap().3.iter().map(|&x| x as f64).collect();
                assert_top_right(&format!("{stem}.exr"), &as_f64, None, ny, nx);
            }
        }
    }
    checked
}

#[test]
fn surface_camera_files_and_orientation_and_the_default_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let config = tmp.path().join("surface.toml");
    std::fs::write(&config, surface()).unwrap();
    // No --out: the folder is the experiment's name, its `/` and space made `_`.
    ohd(tmp.path(), &["run", config.to_str().unwrap(), "--quiet"]);
    assert_eq!(listing(&tmp.path().join("out")), BTreeSet::from(["surface_camera_1".to_string()]));
    let dir = tmp.path().join("out/surface_camera_1");
    let (_, files) = check_run_dir(&dir, "camera");
    for f in [
        "camera_frequency_hz.npy",
        "camera_spectrum.npy",
        "camera_spectrum_by_order.npy",
        "camera_spectrum_by_doppler_events.npy",
        "camera_image.npy",
        "camera_image.exr",
        "camera_image_relative_error.npy",
    ] {
        assert!(files.contains(f), "{f} not written: {files:?}");
    }
    let checked = check_images(&dir, &files);
    let want: BTreeSet<String> =
        ["camera_image.npy", "camera_image_relative_error.npy"].iter().map(|s| s.to_string()).collect();
    assert_eq!(checked, want);
}

#[test]
fn ldh_camera_files_and_orientation() {
    let tmp = tempfile::tempdir().unwrap();
    let config = tmp.path().join("ldh.toml");
    std::fs::write(&config, format!("{}{LDH}", surface())).unwrap();
    let dir = tmp.path().join("run");
    ohd(tmp.path(), &["run", config.to_str().unwrap(), "--quiet", "--out", dir.to_str().unwrap()]);
    let (m, files) = check_run_dir(&dir, "camera");
    let ldh = &m["detectors"]["camera"]["ldh"];
    assert_eq!(ldh["images"]["layout"], "rows = y descending (row 0 = top = largest y), columns = x ascending");
    assert_eq!(ldh["spectrum"]["frequency_file"], "camera_roi_frequency_hz.npy");
    for f in [
        "camera_roi_frequency_hz.npy",
        "camera_roi_spot_spectrum.npy",
        "camera_stft_frequency_hz.npy",
        "camera_roi_spot_periodogram.npy",
        "camera_roi_spot_speckle_algorithm1.npy",
        "camera_roi_spot_speckle_algorithm2.npy",
        "camera_m0_plus.exr",
        "camera_m0_minus_multiple_doppler.exr",
        "camera_m1.exr",
    ] {
        assert!(files.contains(f), "{f} not written: {files:?}");
    }
    // M0+'s errors on the scale of the camera's own speckle: one window's contrast over the band
    // (64 Hann frames at 78 kHz, 2–30 kHz) and the windows whose mean has the median's noise.
    let pe = &m["pixel_errors"]["camera.m0_plus"];
    let c = pe["speckle"]["single_window_contrast"].as_f64().unwrap();
    let stft = ohd::spectrum::stft::Stft::new(78e3, 64, ohd::spectrum::stft::Window::Hann).unwrap();
    assert_eq!(Some(c), stft.flat_band_contrast((2e3, 30e3)));
    assert_eq!(pe["speckle"]["window_frames"], 64);
    let k = pe["speckle"]["windows_at_median"].as_f64().unwrap();
    assert!((k - (c / pe["median"].as_f64().unwrap()).powi(2)).abs() <= 1e-12 * k, "{pe}");
    assert!(m["pixel_errors"]["camera.m0_minus"].get("speckle").is_none());
    let checked = check_images(&dir, &files);
    for f in [
        "camera_image.npy",
        "camera_m0_plus.npy",
        "camera_m0_minus.npy",
        "camera_m1.npy",
        "camera_m0_plus_single_doppler.npy",
        "camera_m0_plus_multiple_doppler.npy",
        "camera_m0_plus_relative_error.npy",
        "camera_pixel_spectra.npy",
        "camera_m0_plus_speckle.npy",
        "camera_m0_minus_speckle.npy",
        "camera_m0_plus_speckle_windows.npy",
        "camera_m0_plus_speckle_expected.npy",
    ] {
        assert!(checked.contains(f), "{f}: orientation not checked (checked: {checked:?})");
    }
}

#[test]
fn lidar_scan_and_fmcw_files() {
    let tmp = tempfile::tempdir().unwrap();
    // A VAD scan: scan.json and vad.csv beside one run directory per pointing.
    let wind = repo().join("configs/wind_sunny.toml");
    let scan = tmp.path().join("scan");
    let sets = ["--set", "detectors.0.lidar.gates=4", "--set", "detectors.0.lidar.fft_points=128"];
    let args =
        [&["run", wind.to_str().unwrap(), "--samples", "3000", "--quiet", "--out", scan.to_str().unwrap()][..], &sets]
            .concat();
    ohd(tmp.path(), &args);
    let scan_json = read_json(&scan.join("scan.json"));
    let pointings: Vec<String> =
        scan_json["pointings"].as_array().unwrap().iter().map(|p| p["run"].as_str().unwrap().to_string()).collect();
    assert_eq!(pointings, ["pointing_00", "pointing_01", "pointing_02", "pointing_03"]);
    let mut top: BTreeSet<String> = ["scan.json", "vad.csv", "vad_wind_profile.png", "vad_wind_profile.svg"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    top.extend(pointings.iter().cloned());
    assert_eq!(listing(&scan), top);
    for p in &pointings {
        let (m, files) = check_run_dir(&scan.join(p), "lidar");
        for f in ["lidar_range_m.npy", "lidar_frequency_hz.npy", "lidar_range_doppler.npy", "lidar_gates.csv"] {
            assert!(files.contains(f), "{p}: {f} not written: {files:?}");
        }
        assert_eq!(m["detectors"]["lidar"]["lidar"]["frequency_file"], "lidar_frequency_hz.npy");
        assert_eq!(m["detectors"]["lidar"]["lidar"]["gates_file"], "lidar_gates.csv");
    }

    // FMCW: a hard target seen by the receiver, its estimates in the receiver's CSV.
    let target = repo().join("configs/fmcw_target.toml");
    let dir = tmp.path().join("fmcw");
    ohd(tmp.path(), &["run", target.to_str().unwrap(), "--samples", "3000", "--quiet", "--out", dir.to_str().unwrap()]);
    let (m, files) = check_run_dir(&dir, "receiver");
    for f in
        ["receiver_frequency_hz.npy", "receiver_up_spectrum.npy", "receiver_down_spectrum.npy", "receiver_spectra.png"]
    {
        assert!(files.contains(f), "{f} not written: {files:?}");
    }
    assert_eq!(m["detectors"]["receiver"]["fmcw"]["file"], "receiver_fmcw_estimates.csv");
    let csv = std::fs::read_to_string(dir.join("receiver_fmcw_estimates.csv")).unwrap();
    assert!(csv.lines().nth(1).is_some_and(|l| l.starts_with("receiver,")), "{csv}");

    // An FMCW scan: fmcw_scan.csv (a row per pointing and chirped detector), its two figures and
    // scan.json beside the pointings' run directories; run again into the same directory with
    // fewer pointings, the scan's own files are rewritten and the pointing no longer run removed.
    let copper = repo().join("configs/fmcw_copper_treadmill.toml");
    let dir = tmp.path().join("copper");
    let scan_of = |elevations: &str| {
        let set = format!("source.pointings_deg={elevations}");
        ohd(
            tmp.path(),
            &[
                "run",
                copper.to_str().unwrap(),
                "--samples",
                "20000",
                "--quiet",
                "--out",
                dir.to_str().unwrap(),
                "--set",
                &set,
            ],
        );
    };
    for (elevations, n) in [("[[270, 85.5], [270, 86.2], [270, 86.3]]", 3), ("[[270, 85.5], [270, 86.2]]", 2)] {
        scan_of(elevations);
        let mut top: BTreeSet<String> = [
            "scan.json",
            "fmcw_scan.csv",
            "fmcw_scan_range.png",
            "fmcw_scan_range.svg",
            "fmcw_scan_velocity.png",
            "fmcw_scan_velocity.svg",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        top.extend((0..n).map(|i| format!("pointing_{i:02}")));
        assert_eq!(listing(&dir), top);
        let csv = std::fs::read_to_string(dir.join("fmcw_scan.csv")).unwrap();
        let rows: Vec<&str> = csv.lines().skip(1).collect();
        assert_eq!(rows.len(), n, "{csv}");
        assert!(rows[0].starts_with("0,270,85.5,receiver,"), "{csv}");
        let scan_json = read_json(&dir.join("scan.json"));
        assert_eq!(scan_json["fmcw"].as_array().unwrap().len(), n);
        assert_eq!(scan_json["fmcw"][1]["detector"], "receiver");
    }
}

/// What is read back as a reference — a run directory (`ohd converge --reference`) or values
/// given in `[reference]` as the file holds them — is in the tally's order and sign again: for
/// the intensity image and the M0− image with `flip_sign` (negated and flipped when written), the
/// tallies exactly.
#[test]
fn references_read_back_in_the_tally_order() {
    use ohd::io::write::manifest::{Invocation, write_run};
    let text = format!("{}{LDH}", surface());
    let sets = ["run.samples=4000", "detectors.0.ldh.flip_sign=true", "detectors.0.ldh.speckle.pixels=false"];
    let r = crate::support::run::run(&text, &sets);
    let tmp = tempfile::tempdir().unwrap();
    let table: toml::Table = toml::from_str(&text).unwrap();
    write_run(tmp.path(), &r.exp, &r.out, &table, &Invocation::default()).unwrap();
    let outputs = r.exp.outputs();
    let refs = ohd::io::write::converge::read_reference(tmp.path(), &outputs).unwrap();
    let (mean, stderr) = (r.out.estimates.mean(), r.out.estimates.stderr());
    for name in ["camera.image", "camera.m0_minus"] {
        let k = outputs.iter().position(|o| o.name == name).unwrap();
        let (o, reference) = (&outputs[k], refs[k].as_ref().unwrap());
        assert_eq!(reference.values, &mean[o.range()], "{name}");
        assert_eq!(reference.stderr, &stderr[o.range()], "{name}");
        // Not vacuous: the file is the tally's image upside down (and negated for M0−).
        let (_, file) = load(&tmp.path().join(&o.file));
        assert_ne!(file, reference.values, "{name}");

        // The file's values given in `[reference]`.
        let values: Vec<String> = file.iter().map(|v| format!("{v:e}")).collect();
        let with_reference = format!("{text}\n[reference]\n\"{name}\" = [{}]\n", values.join(", "));
        let exp = crate::support::run::experiment(&with_reference, &sets);
        let given = exp.references.iter().find(|(n, _)| n == name).expect("the reference");
        assert_eq!(given.1, &mean[o.range()], "{name} from [reference]");
    }
}
