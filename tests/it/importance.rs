//! The importance table of `run.importance = "table"` (`ohd::importance`): what a unit of weight
//! leaving a scattering event at depth `z` along polar angle θ brings a small-pupil camera over
//! forward-peaked tissue — high for states heading up near the surface, and falling with depth
//! and away from the pupil's direction — the same on any number of threads, written with its
//! figure and manifest entry.

use crate::support::run::experiment;
use crate::support::scenes;
use ohd::detect::importance::{ANGLE_BINS, DEPTH_BINS};
use std::sync::Arc;

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
    // A run of 8·10⁵ paths, whose pilot has the most paths (the run itself is not made).
    let exp = experiment(&slab(2), &["run.samples = 800000"]);
    assert_eq!(exp.importance_obstacle(), None);
    let t = exp.importance_table().expect("a forward-estimated camera");
    let (top, bottom, up, down) = (0, DEPTH_BINS - 1, ANGLE_BINS - 1, 0);
    let (up_top, down_top, up_bottom) = (t.at(0, 0, top, up), t.at(0, 0, top, down), t.at(0, 0, bottom, up));
    assert!(up_top > 20.0 * down_top, "up {up_top:.3e} against down {down_top:.3e} at the top");
    assert!(up_top > 2.0 * up_bottom, "up at the top {up_top:.3e} against at the bottom {up_bottom:.3e}");
    assert!(t.states[..DEPTH_BINS * ANGLE_BINS].iter().all(|&n| n > 0), "a bin of the first layer without states");
    assert_eq!(t.paths, ohd::detect::importance::PILOT_PATHS);
    let one = experiment(&slab(1), &["run.samples = 800000"]).importance_table().expect("the same");
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
            // Half the run's 40,000 paths.
            assert_eq!(m["importance"]["pilot_paths"], 20_000);
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
///
/// The table is that of a run of 8·10⁵ paths or more (a pilot of 2·10⁵ paths, as every run's was
/// when this was measured, issue 36), handed to the runs of 3·10⁵ paths: their own would be half
/// their paths (issue 52), which resolves too few states under the beam heading up for the
/// lateral contrast (measured: 4.8 instead of > 10).
#[test]
fn weight_windows_keep_a_distant_dcs_fibre_estimate_and_auto_takes_them() {
    use crate::support::run::Run;
    use crate::support::stats::chi2_difference;
    use ohd::detect::importance::{LATERAL_BINS, PILOT_PATHS};
    let large = ["run.samples = 800000"];
    let exp = experiment(&dcs_ring(2, "table"), &large);
    let t = Arc::new(exp.importance_table().expect("a forward-estimated fibre"));
    assert_eq!(t.shape(), vec![1, LATERAL_BINS, DEPTH_BINS, ANGLE_BINS]);
    assert_eq!(t.paths, PILOT_PATHS);
    let (over, at_beam) = (t.at(0, 0, 2, ANGLE_BINS - 1), t.at(0, LATERAL_BINS - 1, 2, ANGLE_BINS - 1));
    assert!(over > 10.0 * at_beam, "up over the ring {over:.3e} against up at the beam {at_beam:.3e}");

    let run = |threads: u32, importance: &str| {
        use ohd::experiment::{Decisions, ImportanceDecision};
        let exp = experiment(&dcs_ring(threads, importance), &[]);
        let table = ImportanceDecision { steering: exp.plan.importance, figures: None, table: Arc::clone(&t) };
        let decisions = Decisions { importance: Some(table), ..Decisions::default() };
        Run { out: exp.run_decided(&decisions, &ohd::experiment::Silent), exp }
    };
    let windowed = run(2, "windows");
    let plain = run(2, "off");
    let guided = run(2, "guided");
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
    let bits = |r: &Run| r.out.estimates.mean().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let one = run(1, "windows");
    assert_eq!(bits(&windowed), bits(&one), "the windowed run depends on the threads");
    // Isotropic scattering in a diffusive medium: the importance hardly varies over the
    // directions a scattering reaches, so the guide never acts and the run is the windows'.
    assert_eq!(bits(&windowed), bits(&guided), "the guide acted where the importance is nearly isotropic");

    // Decided for a run of 8·10⁵ paths (its table the one above), then run with 3·10⁵.
    let mut auto = experiment(&dcs_ring(2, "auto"), &large);
    let decided = ohd::pilot::decide(&auto);
    let d = decided.importance.as_ref().expect("the pilot decided");
    let a = d.figures.expect("the pilot's figures are kept");
    assert_eq!(d.steering, a.choice());
    assert!(
        a.windows_chosen(),
        "auto: figures {:.3e} without, {:.3e} with the windows, {:.3e} guided",
        a.off,
        a.windows,
        a.guided
    );
    let table = &d.table;
    let value_bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!((table.paths, value_bits(&table.value)), (t.paths, value_bits(&t.value)), "auto's table");
    auto.plan.set_samples(windowed.exp.plan.samples());
    let chosen = if a.choice() == ohd::transport::windows::Importance::Guided { &guided } else { &windowed };
    assert_eq!(
        bits(chosen),
        auto.run_decided(&decided, &ohd::experiment::Silent)
            .estimates
            .mean()
            .iter()
            .map(|x| x.to_bits())
            .collect::<Vec<_>>()
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
    let exp = experiment(&text, &["run.importance = \"auto\""]);
    let why = exp.importance_obstacle().expect("an obstacle");
    assert!(why.contains("lidar") && why.contains("not validated"), "{why}");
    assert!(exp.importance_table().is_none());
    assert!(exp.to_string().contains("importance table: none (detector `lidar` is a lidar receiver"), "{exp}");
    // Asked for by name, the windows are refused (issue 52): they would do nothing.
    let sets = ["run.importance = \"windows\"".to_string()];
    let Err(e) = ohd::config::load(&text, "test", &sets) else { panic!("windows for a lidar receiver were accepted") };
    let e = e.to_string();
    assert!(e.contains("run.importance") && e.contains("lidar receiver") && e.contains("\"auto\" or \"off\""), "{e}");
    let auto = ohd::pilot::decide(&exp);
    assert_eq!(auto.importance, None);
    assert_eq!(auto.steering(&exp.plan), ohd::transport::windows::Importance::Off);
}

/// Issue 52: the pilot was 2·10⁵ paths whatever the run's size, ten times a run of 20,000 paths of
/// an albedo-1 scene (past 300 s). It is now half the run's paths, within 4,000 … 2·10⁵
/// ([`pilot_paths`]): on the slab without absorption (albedo 1 in both layers: long paths) a
/// run of 20,000 paths has a pilot of 10,000, whose work (collision steps) is at most 0.6 of the
/// run's (half its paths, through the same stack), and `auto` charges the windows' and guided
/// figures with it.
#[test]
fn the_pilot_follows_the_run_and_auto_counts_its_cost() {
    use ohd::detect::importance::{PILOT_MIN_PATHS, PILOT_PATHS, pilot_paths};
    assert_eq!((pilot_paths(1_000), pilot_paths(20_000), pilot_paths(400_000)), (PILOT_MIN_PATHS, 10_000, PILOT_PATHS));
    let sets = ["media.tissue.sigma_a_per_mm = 0", "media.deep.sigma_a_per_mm = 0", "run.samples = 20000"];
    let exp = experiment(&slab(2), &sets);
    let t = exp.importance_table().expect("a forward-estimated camera");
    assert_eq!(t.paths, 10_000);
    let run = experiment(&slab(2), &[&sets[..], &["run.importance = \"off\""]].concat()).run(&ohd::experiment::Silent);
    let run_work = (run.stats.scattering_events + run.stats.null_collisions) as f64;
    assert!(
        t.work > 0.0 && t.work < 0.6 * run_work,
        "the pilot's work {:.3e} against the run's {run_work:.3e}",
        t.work
    );
    // `auto`: the same pilot, its table's work charged to the windows and guided figures only
    // (the same paths: the figures differ by that charge alone).
    let auto = experiment(&slab(2), &[&sets[..], &["run.importance = \"auto\""]].concat());
    let free = ohd::detect::importance::ImportanceTable { work: 0.0, ..t.clone() };
    let none = ohd::experiment::Decisions::default();
    let (a, b) = (
        ohd::pilot::importance_pilot(&auto, &none, &Arc::new(t)),
        ohd::pilot::importance_pilot(&auto, &none, &Arc::new(free)),
    );
    assert!(a.off.is_finite() && a.windows.is_finite() && a.guided.is_finite(), "{a:?}");
    assert_eq!(a.off, b.off, "the plain walk needs no table");
    assert!(a.windows > b.windows && a.guided > b.guided, "charged {a:?}, free {b:?}");
}

/// Issue 52: `run.importance` asked for by name with no detector (the main output a scalar) did
/// nothing, silently; it is refused naming the key, as `run.control_variate = "layered"` is where
/// it does not apply. `"auto"` is accepted (it applies where it can; `ohd check` says why not).
#[test]
fn an_importance_table_without_a_detector_is_refused() {
    let text =
        format!("{}{}{}", scenes::header(20_000, 3, 16), scenes::PENCIL_785, scenes::brownian_half_space(0.01, 1.0));
    for asked in ["table", "windows", "guided"] {
        let sets = [format!("run.importance = \"{asked}\"")];
        let Err(e) = ohd::config::load(&text, "test", &sets) else {
            panic!("windows for a lidar receiver were accepted")
        };
        let e = e.to_string();
        assert!(e.contains("run.importance") && e.contains(asked) && e.contains("is not a detector's"), "{asked}: {e}");
    }
    let exp = experiment(&text, &["run.importance = \"auto\""]);
    assert!(exp.to_string().contains("importance table: none (the main output"), "{exp}");
}
