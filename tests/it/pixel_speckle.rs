//! Per-pixel speckle of the LDH camera (`[detectors.ldh.speckle] pixels = true`): Algorithm 1
//! drawn in every pixel from its spectrum. Its expectation is the band sum of the pixel's binned
//! expected periodogram `S` (checked against the exact per-line band kernel of tones at the bin
//! centres), the mean over windows converges to it, the single-window contrast is
//! `√(Σ_B S_k²)/Σ_B S_k`, and the files do not depend on the thread count. Fixed seeds;
//! tolerances in standard errors, never re-rolled.

use crate::support::scenes::{self, BEAM_785, WATER_AROUND};
use crate::support::stats::contrast;

use ohd::detect::{LdhOptions, LdhSpec, SpeckleSpec};
use ohd::io::write::manifest::{Invocation, write_run};
use ohd::post::synthesize_pixel_speckle;
use ohd::sampling::rng::{PathRng, Purpose};
use ohd::spectrum::{FrequencyAxis, Line, Stft, Window};

const FS: f64 = 39_000.0;
const SEED: u64 = 20_251_124;

/// A 64-sample Hann camera, band 3–15 kHz, `windows` per-pixel windows, on `axis`.
fn camera(axis: FrequencyAxis, windows: u32) -> LdhSpec {
    let stft = Stft::new(FS, 64, Window::Hann).unwrap();
    let options = LdhOptions {
        flip_sign: false,
        m1: false,
        moments: false,
        by_class: false,
        rois: Vec::new(),
        spectrum_axis: axis,
        pixel_spectra: true,
        speckle: Some(SpeckleSpec { windows, pixels: true }),
        acquisition: None,
    };
    LdhSpec::new(stft, (3_000.0, 15_000.0), options).unwrap()
}

/// The default LDH axis: N + 1 bins of f_s/N centred on the STFT frequencies.
fn stft_axis() -> FrequencyAxis {
    let d = FS / 64.0;
    FrequencyAxis::new(-32.5 * d, 32.5 * d, 65).unwrap()
}

/// `pixels` random histograms (bins, then two out-of-range tallies): a DC peak (static tissue),
/// a few Doppler bins of random power, one pixel left empty.
fn histograms(axis: &FrequencyAxis, pixels: usize) -> Vec<f64> {
    let stride = axis.bins + 2;
    let mut rng = PathRng::new(SEED, Purpose::Test, 7, 0);
    let mut h = vec![0.0; pixels * stride];
    for p in 1..pixels {
        let row = &mut h[p * stride..(p + 1) * stride];
        row[axis.bins / 2] = 1e-3 * rng.uniform();
        for _ in 0..(1 + p % 5) {
            let j = (rng.uniform() * axis.bins as f64) as usize;
            row[j] += 1e-5 * rng.uniform();
        }
        row[axis.bins] = 1e-6; // out of range: not in S
    }
    h
}

#[test]
fn expectation_is_the_band_kernel_of_bin_centres_and_the_window_mean_converges_to_it() {
    // Two axes: the STFT grid (fast path) and a finer, off-grid one wider than f_s (the general
    // path, with aliasing).
    for axis in [stft_axis(), FrequencyAxis::new(-25_000.0, 31_000.0, 173).unwrap()] {
        let windows = 3000;
        let spec = camera(axis, windows);
        let (nx, ny) = (3, 2);
        let h = histograms(&axis, nx * ny);
        let stride = axis.bins + 2;
        let s = synthesize_pixel_speckle(&spec, nx, ny, &h, stride, SEED, 2);
        let pixels = nx * ny;
        for p in 0..pixels {
            let row = &h[p * stride..p * stride + axis.bins];
            // Exact band powers of one pure tone per bin, at the bin's centre.
            let (mut plus, mut minus) = (0.0, 0.0);
            for (j, &v) in row.iter().enumerate() {
                let b = spec.kernel.eval(axis.center(j), 0.0);
                plus += v * b.m0_plus;
                minus += v * b.m0_minus;
            }
            let scale = row.iter().sum::<f64>().max(1e-300);
            assert!(
                (s.expected_m0_plus[p] - plus).abs() < 1e-11 * scale,
                "pixel {p}: {} vs {plus}",
                s.expected_m0_plus[p]
            );
            assert!((s.expected_m0_minus[p] - minus).abs() < 1e-11 * scale, "pixel {p}: M0−");
            if p == 0 {
                // The empty pixel: nothing drawn.
                assert!(s.expected_m0_plus[0] == 0.0 && (0..windows as usize).all(|j| s.m0_plus[j * pixels] == 0.0));
                continue;
            }
            // Mean over windows within 4 standard errors of the expectation.
            for (stack, e, what) in [(&s.m0_plus, plus, "M0+"), (&s.m0_minus, minus, "M0−")] {
                let v: Vec<f64> = (0..windows as usize).map(|j| stack[j * pixels + p]).collect();
                let w = v.len() as f64;
                let mean = v.iter().sum::<f64>() / w;
                let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (w - 1.0)).sqrt();
                let z = (mean - e) / (sd / w.sqrt());
                assert!(
                    z.abs() < 4.0,
                    "axis {} bins, pixel {p}, {what}: mean {mean:e} vs {e:e} (z = {z:.2})",
                    axis.bins
                );
            }
        }
    }
}

#[test]
fn single_window_contrast_is_the_closed_form() {
    // Pixel 1 of a spectrum spread over many band bins: σ/mean of its M0+ over 4000 windows
    // against √(Σ_B S_k²)/Σ_B S_k, within 4 standard errors of the measured contrast.
    let axis = stft_axis();
    let windows = 4000;
    let spec = camera(axis, windows);
    let stride = axis.bins + 2;
    let mut h = vec![0.0; 2 * stride];
    for j in 0..axis.bins {
        let f = axis.center(j).abs();
        h[stride + j] = if (2_000.0..16_000.0).contains(&f) { 1.0 + (j % 3) as f64 } else { 0.0 };
    }
    h[stride + axis.bins / 2] = 50.0;
    let s = synthesize_pixel_speckle(&spec, 2, 1, &h, stride, SEED, 1);
    // The closed form from S computed independently (tones at the bin centres).
    let lines: Vec<Line> =
        (0..axis.bins).map(|j| Line { power: h[stride + j], frequency: axis.center(j), gamma: 0.0 }).collect();
    let p = spec.stft.expected_periodogram(&lines);
    let band: Vec<f64> =
        (1..64).filter(|&k| (3_000.0..=15_000.0).contains(&spec.stft.bin_frequency(k).abs())).map(|k| p[k]).collect();
    let exact = band.iter().map(|x| x * x).sum::<f64>().sqrt() / band.iter().sum::<f64>();
    assert!((s.contrast[1] / exact - 1.0).abs() < 1e-10, "{} vs {exact}", s.contrast[1]);
    let v: Vec<f64> = (0..windows as usize).map(|j| s.m0_plus[2 * j + 1]).collect();
    let (c, se) = contrast(&v);
    eprintln!("per-pixel single-window contrast {c:.4} ± {se:.4}, closed form {exact:.4}");
    assert!(((c - exact) / se).abs() < 4.0, "contrast {c:.4} ± {se:.4} vs {exact:.4}");
}

/// A thin vessel in a faintly scattering water layer under a flat-top beam of radius 150 µm, seen
/// by an 8 × 8 camera (20° acceptance) with per-pixel spectra and per-pixel speckle, no ROI.
fn vessel() -> String {
    let beam = format!("{BEAM_785}profile = \"disk\"\nradius_um = 150\n");
    let camera = r#"[[detectors]]
name = "camera"
area = { type = "rect", size_mm = [0.4, 0.4] }
acceptance_half_angle_deg = 20
[detectors.image]
pixels = [8, 8]
[detectors.ldh]
window_samples = 64
band_khz = [1, 10]
pixel_spectra = true
[detectors.ldh.speckle]
pixels = true
windows = 3
"#;
    let vessel = scenes::vessel_in_water(0.2, 5.0);
    format!("{}{beam}{WATER_AROUND}{vessel}{camera}", scenes::header(60_000, 5, 16))
}

#[test]
fn files_are_identical_for_one_and_two_threads() {
    let dirs: Vec<tempfile::TempDir> = (0..3).map(|_| tempfile::tempdir().unwrap()).collect();
    let mut manifests = Vec::new();
    for (sets, dir) in
        [["run.threads=1", "run.seed=5"], ["run.threads=2", "run.seed=5"], ["run.threads=2", "run.seed=6"]]
            .iter()
            .zip(&dirs)
    {
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        let (table, exp) = ohd::config::load(&vessel(), "vessel", &sets).unwrap();
        let out = exp.run(&ohd::experiment::Silent);
        manifests.push(write_run(dir.path(), &exp, &out, &table, &Invocation::default()).unwrap().json());
    }
    let info = &manifests[0]["detectors"]["camera"]["ldh"]["pixel_speckle"];
    assert_eq!(info["windows"], 3);
    let files = manifests[0]["files"].as_array().unwrap();
    let speckle: Vec<&str> = files.iter().filter_map(|f| f.as_str()).filter(|f| f.contains("speckle")).collect();
    for f in [
        "camera_m0_plus_speckle.npy",
        "camera_m0_minus_speckle.npy",
        "camera_m0_plus_speckle.png",
        "camera_m0_minus_speckle.png",
    ] {
        assert!(speckle.contains(&f), "{f} not in the manifest's files");
    }
    for f in files {
        let f = f.as_str().unwrap();
        let a = std::fs::read(dirs[0].path().join(f)).unwrap();
        let b = std::fs::read(dirs[1].path().join(f)).unwrap();
        assert!(a == b, "{f} differs between 1 and 2 threads");
    }
    // Not vacuous: the frame has signal, and another seed changes it.
    let frame = std::fs::read(dirs[0].path().join("camera_m0_plus_speckle.npy")).unwrap();
    let (shape, values) = ohd::io::formats::npy::from_bytes(&frame).unwrap();
    assert_eq!(shape, vec![8, 8]);
    assert!(values.iter().filter(|&&v| v > 0.0).count() > 32, "{values:?}");
    assert_ne!(frame, std::fs::read(dirs[2].path().join("camera_m0_plus_speckle.npy")).unwrap());
}

fn config_error(sets: &[String]) -> String {
    match ohd::config::load(&vessel(), "vessel", sets) {
        Ok(_) => panic!("{sets:?}: expected a config error"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn pixels_without_pixel_spectra_is_a_config_error_naming_the_key() {
    let sets = vec!["detectors.0.ldh.pixel_spectra=false".to_string()];
    let e = config_error(&sets);
    assert!(
        e.contains("detectors[0].ldh.speckle.pixels") && e.contains("detectors[0].ldh.pixel_spectra = true"),
        "{e}"
    );
    // Without ROIs, speckle needs pixels = true.
    let sets = vec!["detectors.0.ldh.speckle.pixels=false".to_string()];
    let e = config_error(&sets);
    assert!(e.contains("speckle.pixels = true"), "{e}");
}
