//! Media read from OpenVDB files written by OpenVDB itself (`tests/fixtures/vdb_media/`, made by
//! `validation/vdb/make_media_fixtures.py`): a constant density equals the homogeneous medium,
//! and a Poiseuille velocity grid gives the analytic tube's spectrum. Tolerances are in standard
//! errors; seeds are fixed.

mod common;

use common::{chi_square, run};
use ohd::detect::Scalar;

/// Largest |z| two estimates of the same quantity may differ by.
const Z_MAX: f64 = 4.0;

/// A 1 mm slab (σa 0.07 /mm, σs 7 /mm, g 0.8, n 1.4 in air) lit by a pencil beam; `medium` is
/// the slab's medium table.
fn slab(medium: &str) -> String {
    format!(
        r#"
schema_version = 1
[run]
samples = 400_000
batches = 20
[source]
wavelength_nm = 633
profile = "pencil"
position_mm = [0, 0, 0]
direction = [0, 0, 1]
[media.tissue]
phase = {{ type = "hg", g = 0.8 }}
{medium}
[[layers]]
thickness_mm = 1
n = 1.4
medium = "tissue"
"#
    )
}

#[test]
fn a_constant_vdb_density_equals_the_homogeneous_medium() {
    // constant.vdb holds 0.7 everywhere: a box of 80 × 80 × 20 voxels of 0.05 mm filled by
    // OpenVDB's fill (active tiles and leaves) and the same value as its background. Scaled onto
    // σa 0.1 /mm and σs 10 /mm it is the homogeneous slab of 0.07 and 7 /mm. Every cell of the
    // majorant grid is then exact (no null collisions); with the majorant doubled (delta
    // tracking, scale 2) half the tentative collisions are null. Both agree with the
    // homogeneous slab within Z_MAX standard errors in reflectance, transmittance and absorption
    // (independent seeds).
    let vdb = r#"sigma_a_per_mm = 0.1
sigma_s_per_mm = 10
density = { type = "vdb", file = "tests/fixtures/vdb_media/constant.vdb", grid = "density", scale = 1e-3 }"#;
    let homogeneous = run(&slab("sigma_a_per_mm = 0.07\nsigma_s_per_mm = 7"), &["run.seed=1"]);
    let grid = run(&slab(vdb), &["run.seed=2"]);
    let inflated = run(&slab(vdb), &["run.seed=3", "run.tracking=\"delta\"", "run.majorant_scale=2"]);
    assert_eq!(grid.out.stats.null_collisions, 0, "an exact majorant makes no null collisions");
    let events = inflated.out.stats.scattering_events as f64;
    let nulls = inflated.out.stats.null_collisions as f64;
    eprintln!("doubled majorant: {nulls} null collisions for {events} scattering events");
    assert!(nulls > 0.5 * events, "doubled majorant: {nulls} null collisions for {events} events");
    for s in [Scalar::ReflectanceDiffuse, Scalar::TransmittanceTotal, Scalar::AbsorbedFraction] {
        let (h, h_se) = homogeneous.scalar(s);
        for (name, r) in [("grid", &grid), ("doubled", &inflated)] {
            let (v, v_se) = r.scalar(s);
            let z = (v - h) / h_se.hypot(v_se);
            eprintln!("{}: homogeneous {h:.6} ± {h_se:.6}, {name} {v:.6} ± {v_se:.6}, z = {z:+.2}", s.name());
            assert!(z.abs() < Z_MAX, "{}: {name} z = {z}", s.name());
        }
    }
}

/// The thin tube of `tests/doppler.rs`'s flat-spectrum test (HG g = −0.99 scatterers, 3°
/// acceptance, a tube at 45° lit uniformly), its velocity given by `velocity`.
fn tube(velocity: &str) -> String {
    format!(
        r#"
schema_version = 1
[run]
samples = 3000000
batches = 16
[source]
wavelength_nm = 1000
profile = "disk"
radius_mm = 0.35
position_mm = [0, 0, -0.1]
[media.clear]
sigma_a_per_mm = 0
sigma_s_per_mm = 0
[media.blood]
sigma_a_per_mm = 0
sigma_s_per_mm = 0.2
phase = {{ type = "hg", g = -0.99 }}
[[layers]]
name = "clear"
thickness_mm = 0.4
n = 1.0
medium = "clear"
[[regions]]
layer = "clear"
medium = "blood"
shape = {{ type = "cylinder", center_mm = [0, 0, 0.2], axis = [1, 0, 1], radius_mm = 0.05 }}
velocity = {velocity}
[[detectors]]
name = "top"
acceptance_half_angle_deg = 3
[detectors.spectrum]
f_min_hz = 0
f_max_hz = 1555.634918610405   # 1.1 f_max
bins = 22
by_order = 2
"#
    )
}

#[test]
fn a_vdb_poiseuille_velocity_gives_the_analytic_tube_spectrum() {
    // tube.vdb samples v_max(1 − r²/R²) along the tube's axis on voxels of R/8, as half floats,
    // the parabola continued past the wall so that trilinear interpolation inside the tube only
    // sees the quadratic: velocity error ≤ 0.5 v_max (h/R)² = 0.008 v_max (linear interpolation
    // of a concave parabola lies below it), a sixth of a bin here. The single-scattering
    // spectrum is then the analytic tube's: flat on [0, f_max] (bins 0–18, χ² against uniform as
    // in tests/doppler.rs), and bin by bin the same as the analytic Poiseuille field's run
    // (independent seeds; two-sample χ² over bins 0–18). At the top edge (bin 19 ends at f_max,
    // bin 20 holds the 3° cone's blur beyond it) the grid's lower peak speed moves at most
    // 0.008/0.05 = 16 % of a bin's content below 0.95 f_max: asserted with 4σ of counting noise.
    // (Measured at 4× the paths: bins 0–18 χ² = 20.9 for 19, p = 0.34; bins 19–20 hold 977
    // against 1117, −12.5 %, within the 16 %.)
    let vdb = r#"{ type = "vdb", file = "tests/fixtures/vdb_media/tube.vdb", grid = "velocity", scale = 1e-3 }"#;
    let grid = run(&tube(vdb), &["run.seed=11"]);
    let analytic = run(&tube(r#"{ type = "poiseuille", v_max_mm_per_s = 1 }"#), &["run.seed=12"]);
    let counts = |r: &common::Run| -> Vec<f64> {
        let ch = r.channel(0, 0, 2); // order 1
        ch.values.iter().map(|v| (v * r.paths()).round()).collect()
    };
    let (g, a) = (counts(&grid), counts(&analytic));
    eprintln!("grid {g:?}\nanalytic {a:?}");
    let inner = &g[..19];
    let n_inner: f64 = inner.iter().sum();
    assert!(n_inner > 5000.0, "only {n_inner} detections");
    let (stat, dof, p) = chi_square(inner, &[1.0 / 19.0; 19]);
    eprintln!("grid tube, bins 0–18 against flat: χ² = {stat:.1} for {dof} (p = {p:.3})");
    assert!(p > 1e-4, "chi2 {stat:.1} / {dof} dof, p = {p:.2e}: {inner:?}");
    assert_eq!(g[21], 0.0, "nothing beyond 1.05 f_max");
    // Two Poisson samples of the same spectrum (equal paths): (g − a)²/(g + a) is χ²₁ per bin.
    let chi2: f64 = g[..19].iter().zip(&a[..19]).map(|(x, y)| (x - y).powi(2) / (x + y)).sum();
    let p = common::chi2_sf(chi2, 19);
    eprintln!("grid vs analytic tube, bins 0–18: χ² = {chi2:.1} for 19 (p = {p:.3})");
    assert!(p > 1e-4, "grid vs analytic: χ² = {chi2:.1} for 19: {g:?} vs {a:?}");
    let (top_g, top_a) = (g[19] + g[20], a[19] + a[20]);
    let bound = 0.16 * n_inner / 19.0 + 4.0 * (top_g + top_a).sqrt();
    eprintln!("bins 19–20: grid {top_g}, analytic {top_a}; allowed difference {bound:.0}");
    assert!((top_g - top_a).abs() < bound, "top edge: grid {top_g} vs analytic {top_a} (bound {bound:.0})");
}
