//! The importance table of `run.importance = "table"` (`ohd::importance`): what a unit of weight
//! leaving a scattering event at depth `z` along polar angle θ brings a small-pupil camera over
//! forward-peaked tissue — high for states heading up near the surface, and falling with depth
//! and away from the pupil's direction — the same on any number of threads, written with its
//! figure and manifest entry.

use crate::support::run::experiment;
use crate::support::scenes;
use ohd::detect::importance::{ANGLE_BINS, DEPTH_BINS};

/// A 400 µm layer (σs 15 /mm, σa 0.1 /mm, g 0.9, n 1.37) over a semi-infinite absorbing one, under
/// water, lit by a pencil beam at normal incidence, seen by a 2 mm camera of 8° half-angle.
fn slab(threads: u32) -> String {
    let header = scenes::header(40_000, 3, 16);
    format!(
        r#"{header}threads = {threads}
importance = "table"
[source]
wavelength_nm = 785
[ambient]
n_above = 1.336
[media.tissue]
sigma_a_per_mm = 0.1
sigma_s_per_mm = 15
phase = {{ type = "hg", g = 0.9 }}
[media.deep]
sigma_a_per_mm = 2
sigma_s_per_mm = 30
phase = {{ type = "hg", g = 0.9 }}
[[layers]]
name = "tissue"
thickness_um = 400
n = 1.37
medium = "tissue"
[[layers]]
name = "deep"
thickness_mm = inf
n = 1.38
medium = "deep"
{camera}"#,
        camera = scenes::camera(2.0, 8.0, 4)
    )
}

/// States heading up near the surface (θ within 3.75° of straight up, the top depth bin) are worth
/// many times those heading down there, and more than those heading up at the layer's bottom;
/// every bin of the first layer has states; the table is bit for bit the same on 1 and 2 threads.
#[test]
fn the_importance_table_is_high_for_states_heading_up_near_the_surface() {
    let exp = experiment(&slab(2), &[]);
    assert_eq!(exp.importance_obstacle(), None);
    let t = exp.importance_table().expect("a forward-estimated camera");
    let (top, bottom, up, down) = (0, DEPTH_BINS - 1, ANGLE_BINS - 1, 0);
    let (up_top, down_top, up_bottom) = (t.at(0, 0, top, up), t.at(0, 0, top, down), t.at(0, 0, bottom, up));
    assert!(up_top > 20.0 * down_top, "up {up_top:.3e} against down {down_top:.3e} at the top");
    assert!(up_top > 2.0 * up_bottom, "up at the top {up_top:.3e} against at the bottom {up_bottom:.3e}");
    assert!(t.states[..DEPTH_BINS * ANGLE_BINS].iter().all(|&n| n > 0), "a bin of the first layer without states");
    assert_eq!(t.paths, ohd::detect::importance::PILOT_PATHS);
    let one = experiment(&slab(1), &[]).importance_table().expect("the same");
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&t.value), bits(&one.value), "the table depends on the threads");
}

/// `ohd run` writes the table, its states and figure, and the manifest's `importance` entry;
/// without the key, nothing of it.
#[test]
fn a_run_writes_the_table_with_its_figure() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let cfg = dir.path().join("slab.toml");
    std::fs::write(&cfg, slab(2)).expect("the config is written");
    for (set, written) in [("run.importance=\"table\"", true), ("run.importance=\"off\"", false)] {
        let out = dir.path().join(if written { "on" } else { "off" });
        let st = std::process::Command::new(env!("CARGO_BIN_EXE_ohd"))
            .args(["run", "--quiet", "--set", set, "--out"])
            .arg(&out)
            .arg(&cfg)
            .status()
            .expect("ohd runs");
        assert!(st.success());
        for f in ["importance.npy", "importance_states.npy", "importance_relative_error.npy", "importance.png"] {
            assert_eq!(out.join(f).exists(), written, "{f} with {set}");
        }
        let m: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("manifest.json")).expect("a manifest")).expect("JSON");
        assert_eq!(m.get("importance").is_some(), written);
        if written {
            assert_eq!(m["importance"]["pilot_paths"], ohd::detect::importance::PILOT_PATHS);
            assert_eq!(m["importance"]["detector"], "camera");
        }
    }
}

/// An image output's values and standard errors.
fn image(r: &crate::support::run::Run, name: &str) -> (Vec<f64>, Vec<f64>) {
    let o = r.out.layout.registry.outputs.iter().find(|o| o.name == name).unwrap_or_else(|| panic!("no {name}"));
    o.values(r.out.estimates.mean(), &r.out.estimates.stderr())
}

/// The slab's camera with `run.importance = importance` against the plain walk, 8·10⁵ paths
/// each: its image and power equal the plain walk's within their standard errors (χ² over the
/// pixels, z of the power), and the run is the same bit for bit on 1 and 2 threads (the copies'
/// streams come from their paths'). Returns the power's σ with it and plain.
fn against_the_plain_walk(importance: &str) -> (f64, f64) {
    use crate::support::run::{Run, run};
    use crate::support::stats::chi2_difference;
    let sets = |w: &str| ["run.samples = 800000".to_string(), format!("run.importance = \"{w}\"")];
    let with = |threads: u32, w: &str| run(&slab(threads), &sets(w).iter().map(String::as_str).collect::<Vec<_>>());
    let (steered, plain) = (with(2, importance), with(2, "off"));
    let (a, b) = (image(&steered, "camera.image"), image(&plain, "camera.image"));
    let (chi2, dof, p) = chi2_difference((&a.0, &a.1), (&b.0, &b.1));
    assert!(dof == 16 && p > 1e-4, "{importance}: image χ² = {chi2:.1} over {dof} pixels (p = {p:.2e})");
    let ((pw, sw), (pp, sp)) = (steered.power(0), plain.power(0));
    let z = (pw - pp) / sw.hypot(sp);
    assert!(z.abs() < 4.0, "power {pw:.5e} ± {sw:.1e} {importance}, {pp:.5e} ± {sp:.1e} plain (z = {z:.2})");
    let bits = |r: &Run| r.out.estimates.mean().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&steered), bits(&with(1, importance)), "the {importance} run depends on the threads");
    (sw, sp)
}

/// With weight windows (`run.importance = "windows"`) the camera's estimate is the plain walk's
/// ([`against_the_plain_walk`]), and its power is more precise.
#[test]
fn weight_windows_keep_the_estimate_and_the_determinism() {
    let (sw, sp) = against_the_plain_walk("windows");
    assert!(sw < sp, "the windows' power σ {sw:.2e} against the plain walk's {sp:.2e}");
}

/// Guided directions (`run.importance = "guided"`: the windows, and continuations resampled on
/// the importance): the camera's estimate is the plain walk's ([`against_the_plain_walk`]), and
/// its power's σ is below 0.75 of the plain walk's at the same paths (measured 0.69 / 0.51 / 0.33
/// with seeds 1 / 2 / 3; this is seed 3).
#[test]
fn guided_directions_keep_the_camera_estimate_and_gain_under_a_small_pupil() {
    let (sg, sp) = against_the_plain_walk("guided");
    assert!(sg < 0.75 * sp, "the guided power σ {sg:.2e} against the plain walk's {sp:.2e}");
}

/// A semi-infinite Brownian medium (n = 1, isotropic, μs = 1 /mm, μa = 0.01 /mm) under a pencil
/// beam, and a DCS fibre ring 14.5–15.5 mm from it with a time axis and g1: light that must go
/// ~15 transport lengths sideways, most of it deep.
fn dcs_ring(threads: u32, importance: &str) -> String {
    let ring = scenes::dcs_ring(14.5, 15.5, 40, 21);
    let (pencil, tissue) = (scenes::PENCIL_785, scenes::brownian_half_space(0.01, 1.0));
    format!(
        "{}threads = {threads}\nimportance = \"{importance}\"\n{pencil}{tissue}{ring}",
        scenes::header(300_000, 7, 16)
    )
}

/// An output's values and standard errors, by name.
fn named(r: &crate::support::run::Run, name: &str) -> (Vec<f64>, Vec<f64>) {
    let o = r.out.layout.registry.expect(name);
    o.values(r.out.estimates.mean(), &r.out.estimates.stderr())
}

/// For a fibre away from the beam the table has lateral bins (the distance to the ring): a state
/// over the ring heading up is worth more than one at the beam heading up, at the same depth.
/// With its weight windows (`"windows"`) the ring's power, TPSF and g1 equal the plain walk's
/// within their standard errors (z; χ² over the time bins and the delays), the power's σ is
/// at most half the plain walk's at the same paths, and the run is bit-identical on 1 and 2
/// threads. With `"guided"` the guide does not act here (`transport::guide::MIN_SPREAD`: the
/// importance hardly varies over an isotropic scattering's directions): bit for bit the windows'
/// run. `"auto"` measures that
/// the windows pay here and takes them (with or without guided directions): the same numbers as
/// the run it chose (the pilot's paths are its own).
#[test]
fn weight_windows_keep_a_distant_dcs_fibre_estimate_and_auto_takes_them() {
    use crate::support::run::run;
    use crate::support::stats::chi2_difference;
    use ohd::detect::importance::LATERAL_BINS;
    let exp = experiment(&dcs_ring(2, "table"), &[]);
    let t = exp.importance_table().expect("a forward-estimated fibre");
    assert_eq!(t.shape(), vec![1, LATERAL_BINS, DEPTH_BINS, ANGLE_BINS]);
    let (over, at_beam) = (t.at(0, 0, 2, ANGLE_BINS - 1), t.at(0, LATERAL_BINS - 1, 2, ANGLE_BINS - 1));
    assert!(over > 10.0 * at_beam, "up over the ring {over:.3e} against up at the beam {at_beam:.3e}");

    let windowed = run(&dcs_ring(2, "windows"), &[]);
    let plain = run(&dcs_ring(2, "off"), &[]);
    let guided = run(&dcs_ring(2, "guided"), &[]);
    for (what, r) in [("windows", &windowed), ("guided", &guided)] {
        let ((pw, sw), (pp, sp)) = (r.power(0), plain.power(0));
        let z = (pw - pp) / sw.hypot(sp);
        assert!(z.abs() < 4.0, "power {pw:.5e} ± {sw:.1e} {what}, {pp:.5e} ± {sp:.1e} plain (z = {z:.2})");
        assert!(sw < 0.5 * sp, "the {what} power σ {sw:.2e} against the plain walk's {sp:.2e}");
        for name in ["ring.tpsf", "ring.g1"] {
            let (a, b) = (named(r, name), named(&plain, name));
            let (chi2, dof, p) = chi2_difference((&a.0, &a.1), (&b.0, &b.1));
            assert!(dof >= 10 && p > 1e-4, "{what}: {name}: χ² = {chi2:.1} over {dof} values (p = {p:.2e})");
        }
    }
    let bits = |r: &crate::support::run::Run| r.out.estimates.mean().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let one = run(&dcs_ring(1, "windows"), &[]);
    assert_eq!(bits(&windowed), bits(&one), "the windowed run depends on the threads");
    // Isotropic scattering in a diffusive medium: the importance hardly varies over the
    // directions a scattering reaches, so the guide never acts and the run is the windows'.
    assert_eq!(bits(&windowed), bits(&guided), "the guide acted where the importance is nearly isotropic");

    let auto = ohd::pilot::decide(&experiment(&dcs_ring(2, "auto"), &[]));
    let a = auto.plan.importance_auto.expect("the pilot decided");
    assert!(
        a.windows_chosen(),
        "auto: figures {:.3e} without, {:.3e} with the windows, {:.3e} guided",
        a.off,
        a.windows,
        a.guided
    );
    let chosen = if a.choice() == ohd::transport::windows::Importance::Guided { &guided } else { &windowed };
    assert_eq!(
        bits(chosen),
        auto.run(&ohd::experiment::Silent).estimates.mean().iter().map(|x| x.to_bits()).collect::<Vec<_>>()
    );
}

/// A lidar receiver gets no table and no windows (`ohd check` says why): the plain walk's own
/// errors of its multiply scattered gates are not reliable enough to validate windows against
/// (measured, validation/README.md).
#[test]
fn a_lidar_receiver_gets_no_importance_table() {
    use crate::support::scenes::{Gates, UPWARD_1550};
    let fog = "[media.fog]\nsigma_s_per_m = 2e-2\nsigma_a_per_m = 1e-4\nphase = { type = \"hg\", g = 0.8 }\n\
               [[layers]]\nthickness_m = 150\nn = 1.0\nmedium = \"fog\"\n";
    let receiver = scenes::lidar_receiver(10, Gates { first_gate_m: 30, gate_points: 10, gates: 8, fft_points: 64 });
    let text = format!("{}{UPWARD_1550}{fog}{receiver}", scenes::header(20_000, 11, 16));
    let exp = experiment(&text, &["run.importance = \"windows\""]);
    let why = exp.importance_obstacle().expect("an obstacle");
    assert!(why.contains("lidar") && why.contains("not validated"), "{why}");
    assert!(exp.importance_table().is_none());
    assert!(exp.to_string().contains("importance table: none (detector `lidar` is a lidar receiver"), "{exp}");
    let auto = ohd::pilot::decide(&experiment(&text, &["run.importance = \"auto\""]));
    assert_eq!(auto.plan.importance_auto, None);
    assert!(!auto.plan.windows());
}
