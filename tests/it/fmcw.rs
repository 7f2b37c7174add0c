//! FMCW range and radial velocity against closed forms (validation-values §4 item 6): a hard target
//! (`configs/fmcw_target.toml`, a diffuse sheet at 10 m) gives up- and down-chirp peaks at
//! `f_R ± f_D` with `f_R = 2RB/(cT)` and `f_D = 2v/λ0`, hence `R = cT(f_up + f_down)/(4B)` and
//! `v = λ0(f_up − f_down)/4`; a soft target (`configs/fmcw_cloud.toml`, a 1 m cloud slab from 10 m)
//! gives a return spread over the slab's ranges whose power and mean range follow the
//! single-scattering lidar equation.

use crate::support::run::{Run, run};
use crate::support::stats::assert_within_sigma;
use ohd::numeric::simpson;

use ohd::SPEED_OF_LIGHT;
use ohd::io::write::manifest::{Invocation, write_run};
use ohd::retrieval::FmcwEstimate;
use ohd::retrieval::fmcw::range_frequency;

const TARGET: &str = include_str!("../../configs/fmcw_target.toml");
const CLOUD: &str = include_str!("../../configs/fmcw_cloud.toml");

/// The transceiver of both configs: 1550 nm, B = 1 GHz, T = 10 µs.
const LAMBDA: f64 = 1550e-9;
const B: f64 = 1e9;
const T: f64 = 10e-6;

fn estimates(r: &Run) -> FmcwEstimate {
    match r.exp.fmcw_estimates(&r.out, 0) {
        Some(Ok(e)) => e,
        other => panic!("no FMCW estimates: {other:?}"),
    }
}

/// Doppler shift of radial velocity `v`, Hz.
fn doppler(v: f64) -> f64 {
    2.0 * v / LAMBDA
}

#[test]
fn closed_form_beat_frequencies() {
    // validation-values §4.6: f_R = 2RB/(cT) = 6.6713 MHz at 10 m; f_D = 2v/λ0 = 1.2903 MHz at 1 m/s.
    assert!((range_frequency(10.0, B, T) - 6.6713e6).abs() < 50.0);
    assert!((doppler(1.0) - 1.2903e6).abs() < 50.0);
}

/// The hard target at range 10 m moving at `v`: the peaks, range and velocity, each within one
/// bin — and within half a bin, as every detected path falls into one bin per chirp (the sheet is
/// 1 µm thick and the receiver's 0.35° cone adds < 0.2 mm of path), so the estimates are bin
/// centres and each peak errs by at most Δf/2.
fn check_hard_target(r: &Run, v: f64) -> FmcwEstimate {
    let e = estimates(r);
    let axis = r.exp.detectors[0].surface().unwrap().spectrum().unwrap().axis;
    let df = axis.bin_width();
    for chirp in 0..2 {
        let s = r.out.spectrum(0, chirp, 0).unwrap();
        assert_eq!(s.iter().filter(|&&x| x > 0.0).count(), 1, "chirp {chirp}: the line fills one bin");
    }
    let (f_r, f_d) = (range_frequency(10.0, B, T), doppler(v));
    assert!((e.range_bin_m - SPEED_OF_LIGHT * T * df / (2.0 * B)).abs() < 1e-15);
    assert!((e.velocity_bin_m_per_s - LAMBDA * df / 2.0).abs() < 1e-18);
    for (what, f, want) in [("f_up", e.f_up_hz, f_r + f_d), ("f_down", e.f_down_hz, f_r - f_d)] {
        assert!((f - want).abs() <= 0.5 * df, "{what} = {f} Hz, expected {want} ± {} Hz", 0.5 * df);
    }
    assert!((e.range_m - 10.0).abs() <= 0.5 * e.range_bin_m, "range {} m (bin {} m)", e.range_m, e.range_bin_m);
    assert!(
        (e.radial_velocity_m_per_s - v).abs() <= 0.5 * e.velocity_bin_m_per_s,
        "velocity {} m/s vs {v} (bin {} m/s)",
        e.radial_velocity_m_per_s,
        e.velocity_bin_m_per_s
    );
    // One bin: the centroid is the peak.
    assert_eq!((e.f_up_centroid_hz, e.f_down_centroid_hz), (e.f_up_hz, e.f_down_hz));
    assert!(!e.touches_axis_end);
    e
}

#[test]
fn hard_target_range_and_velocity_within_one_bin() {
    let r = run(TARGET, &["run.samples=100000"]);
    let e = check_hard_target(&r, 1.0);
    // Receding: the optical path lengthens, so the up-chirp peak is the higher one.
    assert!(e.f_up_hz > e.f_down_hz);

    // The manifest and the CSV carry the same numbers.
    let tmp = tempfile::tempdir().unwrap();
    let table: toml::Table = toml::from_str(TARGET).unwrap();
    let m = write_run(tmp.path(), &r.exp, &r.out, &table, &Invocation::default()).unwrap().json();
    let est = &m["estimates"]["detectors"]["receiver"];
    assert_eq!(est["range_m"].as_f64(), Some(e.range_m));
    assert_eq!(est["radial_velocity_m_per_s"].as_f64(), Some(e.radial_velocity_m_per_s));
    assert_eq!(est["velocity_bin_m_per_s"].as_f64(), Some(e.velocity_bin_m_per_s));
    assert!(m["detectors"]["receiver"]["fmcw"]["note"].is_null());
    let csv = std::fs::read_to_string(tmp.path().join("receiver_fmcw_estimates.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 2, "{csv}");
    assert!(lines[0].starts_with("detector,range_m,radial_velocity_m_per_s,f_up_hz,f_down_hz,"), "{csv}");
    let row: Vec<f64> = lines[1].split(',').skip(1).map(|x| x.parse().unwrap()).collect();
    assert_eq!(row[0], e.range_m);
    assert_eq!(row[1], e.radial_velocity_m_per_s);
}

#[test]
fn approaching_target_mirrors_the_peaks() {
    let r = run(TARGET, &["run.samples=100000", "media.target.velocity.velocity_m_per_s=[0, 0, -1]"]);
    let e = check_hard_target(&r, -1.0);
    assert!(e.f_down_hz > e.f_up_hz);
}

#[test]
fn cloud_slab_range_inside_and_velocity_within_one_bin() {
    // Default samples (4·10⁶, about half a second on 2 cores).
    let r = run(CLOUD, &[]);
    let e = estimates(&r);
    let (near, far) = (10.0, 11.0);

    // Single scattering (the slab's optical depth is 0.018): a vertex at range R scores
    // β·A/R²·exp(−2σt(R − 10 m)) per unit range into the 50 mm receiver (the local estimate of its
    // shadow rays), with β = σs·p(π) of the cloud's (tabulated Mie) phase function.
    let m = &r.exp.scene.media[0];
    let beta = m.sigma_s() * m.population().phase.eval(-1.0);
    let area = std::f64::consts::PI * 0.05f64.powi(2);
    let density = |range: f64| beta * area / (range * range) * (-2.0 * m.sigma_t() * (range - near)).exp();
    let power = simpson(density, near, far, 1000);
    let mean_range = simpson(|x| x * density(x), near, far, 1000) / power;
    let (p, se) = r.power(0);
    eprintln!(
        "cloud: power {p:.5e} ± {se:.1e} (lidar equation {power:.5e}); range peak {:.4} m, centroid {:.4} m \
         (mean {mean_range:.4} m); velocity peak {:.5} m/s, centroid {:.5} m/s",
        e.range_m, e.range_centroid_m, e.radial_velocity_m_per_s, e.radial_velocity_centroid_m_per_s
    );
    assert_within_sigma("detected power", p, se, power, 4.0);

    // The peak is the strongest bin somewhere in the flat return: inside the slab (± one bin).
    let bin = e.range_bin_m;
    assert!(e.range_m > near - bin && e.range_m < far + bin, "peak range {} m", e.range_m);
    // The centroid is the power-weighted mean range: the lidar equation's, to a fraction of a bin
    // (a Monte Carlo error of ≈ 0.29 m/√(paths detected), a few mm; binning adds nothing to a
    // mean over bins that cover the whole return).
    assert!(e.range_centroid_m > near && e.range_centroid_m < far, "centroid range {} m", e.range_centroid_m);
    assert!(
        (e.range_centroid_m - mean_range).abs() < 0.5 * bin,
        "centroid range {} m vs the lidar equation's mean {mean_range} m (bin {bin} m)",
        e.range_centroid_m
    );
    // The up- and down-chirp returns are the same paths shifted by ±f_D, so their centroids give
    // the velocity; their peaks are independent noisy maxima of a flat return and do not.
    assert!(
        (e.radial_velocity_centroid_m_per_s - 1.0).abs() < e.velocity_bin_m_per_s,
        "centroid velocity {} m/s (bin {} m/s)",
        e.radial_velocity_centroid_m_per_s,
        e.velocity_bin_m_per_s
    );
    // The whole return lies inside the axis and inside the centroid windows.
    assert!(!e.touches_axis_end);
    let (lo, hi) = (range_frequency(near, B, T), range_frequency(far, B, T));
    let f_d = doppler(1.0);
    let df = r.exp.detectors[0].surface().unwrap().spectrum().unwrap().axis.bin_width();
    for (g, shift) in [(&e.up, f_d), (&e.down, -f_d)] {
        let axis = r.exp.detectors[0].surface().unwrap().spectrum().unwrap().axis;
        let (a, b) = (axis.center(g.window.start) - 0.5 * df, axis.center(g.window.end - 1) + 0.5 * df);
        assert!(
            a <= lo + shift + df && b >= hi + shift - df,
            "window {a}..{b} Hz vs return {}..{} Hz",
            lo + shift,
            hi + shift
        );
    }
}

#[test]
fn no_signal_gives_a_note_and_no_estimates() {
    // An axis (20–30 MHz) far above the target's beats: every path is out of range.
    let sets = ["run.samples=20000", "detectors.0.spectrum.f_min_mhz=20", "detectors.0.spectrum.f_max_mhz=30"];
    let r = run(TARGET, &sets);
    assert!(matches!(r.exp.fmcw_estimates(&r.out, 0), Some(Err(ohd::retrieval::RetrievalError::NoSignal))));
    let tmp = tempfile::tempdir().unwrap();
    let table: toml::Table = toml::from_str(TARGET).unwrap();
    let m = write_run(tmp.path(), &r.exp, &r.out, &table, &Invocation::default()).unwrap().json();
    let note = m["detectors"]["receiver"]["fmcw"]["note"].as_str().unwrap_or_default();
    assert!(note.starts_with("no estimates: no signal"), "{note}");
    assert!(m["estimates"]["detectors"]["receiver"].get("range_m").is_none());
    let csv = std::fs::read_to_string(tmp.path().join("receiver_fmcw_estimates.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1, "header only: {csv}");
    // Without a chirp there are no FMCW outputs at all.
    let single = TARGET.replace("chirp = { bandwidth_ghz = 1, duration_us = 10 }", "");
    assert_ne!(single, TARGET);
    let r = run(&single, &["run.samples=2000"]);
    assert!(r.exp.fmcw_estimates(&r.out, 0).is_none());
}

/// Issue 33, item 8: a retrieval that gives no estimates says so in the run's warnings, not only in
/// its note (a range of null was written without a warning). The shipped target has estimates and
/// no such warning.
#[test]
fn missing_estimates_are_warned_of() {
    let codes = |r: &Run| ohd::post::warnings(&r.exp, &r.out).into_iter().collect::<Vec<_>>();
    let r = run(TARGET, &["run.samples=2000", "source.chirp={ bandwidth_hz = 0, duration_us = 10 }"]);
    assert!(matches!(r.exp.fmcw_estimates(&r.out, 0), Some(Err(_))));
    let w = codes(&r);
    let missing: Vec<_> = w.iter().filter(|w| w.code == "fmcw_no_estimates").collect();
    assert_eq!(missing.len(), 1, "{w:?}");
    assert!(missing[0].message.starts_with("detector \"receiver\": no FMCW range"), "{}", missing[0].message);
    assert!(missing[0].message.contains("bandwidth_hz = 0"), "{}", missing[0].message);
    let r = run(TARGET, &["run.samples=20000"]);
    assert!(estimates(&r).is_finite());
    assert!(!codes(&r).iter().any(|w| w.code == "fmcw_no_estimates"));
}

/// Issue 38: the hard target as an opaque surface (`[bottom]`: a Lambertian plate receding at
/// 1 m/s under a 1 µm clear layer) instead of a dense scattering sheet gives the same peaks,
/// range and velocity, each within half a bin; approaching, the mirrored peaks.
#[test]
fn a_moving_lambertian_plate_is_the_hard_target() {
    for v in [1.0, -1.0] {
        let velocity = format!("bottom.velocity_m_per_s=[0, 0, {v}]");
        let sets = [
            "run.samples=20000",
            "media.target={ sigma_a_per_mm = 0, sigma_s_per_mm = 0 }",
            "bottom.surface={ type = \"lambertian\", albedo = 0.5 }",
            velocity.as_str(),
        ];
        let r = run(TARGET, &sets);
        let e = check_hard_target(&r, v);
        assert_eq!(e.f_up_hz > e.f_down_hz, v > 0.0);
    }
}

const COPPER: &str = include_str!("../../configs/fmcw_copper_treadmill.toml");

/// The closed form of `configs/fmcw_copper_treadmill.toml` at elevation `el` (degrees), from its
/// resolved geometry: the beam descends at β = 90° − el from the transceiver `s` onto the floor
/// (the copper plate's top face, `x = x_f`). On the plate it is reflected toward the belt: seen
/// from the mirror image `s′ = (2 x_f − s_x, s_y, s_z)` along `d′ = (sin β, 0, cos β)`, the
/// belt's plane (centre `c`, normal `n`) lies at `R = (c − s′)·n/(d′·n)`, and the belt's velocity
/// `v` gives the radial velocity `v·d′`. Beyond the plate, the fabric floor at range
/// `(s_x − x_f)/sin β`, static. Returns (range, velocity, on the plate).
fn copper_closed_form(exp: &ohd::experiment::Experiment, el: f64) -> (f64, f64, bool) {
    use ohd::medium::Shape;
    let s = exp.source.position;
    let by = |name: &str| exp.scene.opaque.iter().find(|o| o.name == name).unwrap();
    let Shape::Box { min, max } = by("copper").shape else { panic!("the plate is a box") };
    let Shape::Cylinder { center, axis, .. } = by("belt").shape else { panic!("the belt is a disk") };
    let beta = (90.0 - el).to_radians();
    let (x_f, h) = (max.x, s.x - max.x);
    let spot = s.z + h / beta.tan();
    if (min.z..=max.z).contains(&spot) {
        let mirror = glam::DVec3::new(2.0 * x_f - s.x, s.y, s.z);
        let d = glam::DVec3::new(beta.sin(), 0.0, beta.cos());
        let range = (center - mirror).dot(axis) / d.dot(axis);
        (range, by("belt").surface.velocity.dot(d), true)
    } else {
        (h / beta.sin(), 0.0, false)
    }
}

#[test]
fn the_copper_scan_sees_the_belt_in_the_plate_and_the_fabric_beyond_it() {
    // Two pointings onto the plate and two beyond its edge, each ≥ 0.5 m from it along the floor
    // (the receiver's 0.1° field of view spans ±0.34 m of floor there): range and velocity within
    // a range bin and a velocity bin of the closed form.
    let mut seen = [0, 0];
    for el in [85.4, 85.7, 86.1, 86.35] {
        let r = run(COPPER, &[&format!("source.pointings_deg=[[270, {el}]]"), "run.samples=1000000"]);
        let e = estimates(&r);
        let (range, v, plate) = copper_closed_form(&r.exp, el);
        seen[usize::from(plate)] += 1;
        assert!(
            (e.range_m - range).abs() <= e.range_bin_m,
            "elevation {el}°: range {} m, closed form {range} m (bin {} m)",
            e.range_m,
            e.range_bin_m
        );
        assert!(
            (e.radial_velocity_m_per_s - v).abs() <= e.velocity_bin_m_per_s,
            "elevation {el}°: velocity {} m/s, closed form {v} m/s (bin {} m/s)",
            e.radial_velocity_m_per_s,
            e.velocity_bin_m_per_s
        );
    }
    assert_eq!(seen, [2, 2], "two pointings beyond the plate and two onto it");
}
