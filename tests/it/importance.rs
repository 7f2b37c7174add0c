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
    let (up_top, down_top, up_bottom) = (t.at(0, top, up), t.at(0, top, down), t.at(0, bottom, up));
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
        for f in ["importance.npy", "importance_states.npy", "importance.png"] {
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

/// With weight windows (`run.importance = "windows"`) the camera's image and power equal the
/// plain walk's within their standard errors (χ² over the pixels, z of the power), the power is
/// more precise, and the run is the same bit for bit on 1 and 2 threads (the copies' streams come
/// from their paths').
#[test]
fn weight_windows_keep_the_estimate_and_the_determinism() {
    use crate::support::run::run;
    use crate::support::stats::chi2_difference;
    let sets = |w: &'static str| ["run.samples = 800000".to_string(), format!("run.importance = \"{w}\"")];
    let windowed = run(&slab(2), &sets("windows").iter().map(String::as_str).collect::<Vec<_>>());
    let plain = run(&slab(2), &sets("off").iter().map(String::as_str).collect::<Vec<_>>());
    let (a, b) = (image(&windowed, "camera.image"), image(&plain, "camera.image"));
    let (chi2, dof, p) = chi2_difference((&a.0, &a.1), (&b.0, &b.1));
    assert!(dof == 16 && p > 1e-4, "image: χ² = {chi2:.1} over {dof} pixels (p = {p:.2e})");
    let power = |r: &crate::support::run::Run| {
        let slot = r.out.layout.detectors[0].power;
        (r.out.estimates.mean()[slot], r.out.estimates.stderr()[slot])
    };
    let ((pw, sw), (pp, sp)) = (power(&windowed), power(&plain));
    let z = (pw - pp) / sw.hypot(sp);
    assert!(z.abs() < 4.0, "power {pw:.5e} ± {sw:.1e} with windows, {pp:.5e} ± {sp:.1e} plain (z = {z:.2})");
    assert!(sw < sp, "the windows' power σ {sw:.2e} against the plain walk's {sp:.2e}");
    let one = run(&slab(1), &sets("windows").iter().map(String::as_str).collect::<Vec<_>>());
    let bits = |r: &crate::support::run::Run| r.out.estimates.mean().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&windowed), bits(&one), "the windowed run depends on the threads");
}
