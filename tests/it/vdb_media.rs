//! Media read from OpenVDB files written by OpenVDB itself (`tests/fixtures/vdb_media/`, made by
//! `validation/vdb/make_media_fixtures.py`): a constant density equals the homogeneous medium,
//! and a Poiseuille velocity grid gives the analytic tube's spectrum. Tolerances are in standard
//! errors; seeds are fixed.

use crate::support::lidar::{check_single_scattering_lags, gate_lag_weight, hg_backscatter};
use crate::support::run::{Run, run};
use crate::support::scenes::{self, Gates, tube_scene};
use crate::support::stats::{chi_square, chi2_sf};
use ohd::numeric::simpson;

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

#[test]
fn a_vdb_poiseuille_velocity_gives_the_analytic_tube_spectrum() {
    // tube.vdb samples v_max(1 − r²/R²) along the tube's axis on voxels of R/8, as half floats,
    // the parabola continued past the wall so that trilinear interpolation inside the tube only
    // sees the quadratic: velocity error ≤ 0.5 v_max (h/R)² = 0.008 v_max (linear interpolation
    // of a concave parabola lies below it), a sixth of a bin here. The single-scattering
    // spectrum is then the analytic tube's: flat on [0, f_max] (bins 0–18, χ² against uniform as
    // in tests/it/doppler.rs), and bin by bin the same as the analytic Poiseuille field's run
    // (independent seeds; two-sample χ² over bins 0–18). At the top edge (bin 19 ends at f_max,
    // bin 20 holds the 3° cone's blur beyond it) the grid's lower peak speed moves at most
    // 0.008/0.05 = 16 % of a bin's content below 0.95 f_max: asserted with 4σ of counting noise.
    // (Measured at 4× the paths: bins 0–18 χ² = 20.9 for 19, p = 0.34; bins 19–20 hold 977
    // against 1117, −12.5 %, within the 16 %.)
    let vdb = r#"{ type = "vdb", file = "tests/fixtures/vdb_media/tube.vdb", grid = "velocity", scale = 1e-3 }"#;
    let grid = run(&tube_scene(vdb), &["run.seed=11"]);
    let analytic = run(&tube_scene(r#"{ type = "poiseuille", v_max_mm_per_s = 1 }"#), &["run.seed=12"]);
    let counts = |r: &Run| -> Vec<f64> {
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
    let p = chi2_sf(chi2, 19);
    eprintln!("grid vs analytic tube, bins 0–18: χ² = {chi2:.1} for 19 (p = {p:.3})");
    assert!(p > 1e-4, "grid vs analytic: χ² = {chi2:.1} for 19: {g:?} vs {a:?}");
    let (top_g, top_a) = (g[19] + g[20], a[19] + a[20]);
    let bound = 0.16 * n_inner / 19.0 + 4.0 * (top_g + top_a).sqrt();
    eprintln!("bins 19–20: grid {top_g}, analytic {top_a}; allowed difference {bound:.0}");
    assert!((top_g - top_a).abs() < bound, "top edge: grid {top_g} vs analytic {top_a} (bound {bound:.0})");
}

/// A pulsed lidar staring up from 1 m below a 400 m haze whose velocity is the turbulent wind box
/// of `media/vdb/wind_box.vdb` (32³ voxels of 10 m over x, y ∈ [−160, 150] m, z ∈ [0, 310] m;
/// outside it the background, 8 m/s east).
fn wind_box() -> String {
    let haze = r#"[source]
wavelength_nm = 1550
position_m = [30, -40, -1]
direction = [0, 0, 1]
[media.haze]
sigma_s_per_m = 3e-3
sigma_a_per_m = 3e-4
phase = { type = "hg", g = 0.7 }
velocity = { type = "vdb", file = "media/vdb/wind_box.vdb", grid = "velocity" }
[[layers]]
name = "air"
thickness_m = 400
n = 1.0
medium = "haze"
"#;
    // The first gate at 90 m: full overlap (see the test).
    let receiver = scenes::lidar_receiver(1, Gates { first_gate_m: 90, gate_points: 10, gates: 11, fft_points: 64 });
    format!("{}{haze}{receiver}", scenes::header(1_000_000, 21, 40))
}

#[test]
fn lidar_gates_through_a_vdb_wind_box_follow_the_grid_along_the_beam() {
    // Single scattering from the beam's axis: each gate's lag sums are the lidar equation with
    // the Doppler phase of the grid's vertical wind at every height,
    // E[D_d] = β ∫ A/R²·e^{−2σt s}·W_{g,d}(2R/c)·e^{2πi (2w(s)/λ0) dΔt} ds, β = σs p_HG(π),
    // R = s + 1 m, w(s) the trilinear grid value at (30, −40, s). D_0 (real) and D_1 (real and
    // imaginary) of all 11 gates (90–420 m: in the box, across its top at 310 m and above it,
    // where the background's w = 0 holds) are z-tested, |z| < 4.5, with a χ² over all 33.
    // (A first gate at 60 m comes out 2 % low, with any velocity field, and right with a 5 mrad
    // field of view: the pulse's tail brings echoes from below 40 m into it, where the 40 mm
    // aperture is seen wider than the 1 mrad half-angle: incomplete overlap, which the formula
    // leaves out.)
    use num_complex::Complex64;
    let r = run(&wind_box(), &[]);
    let (spec, _) = r.lidar();
    let medium = &r.exp.scene.media[r.exp.scene.layers[0].medium];
    let ohd::flow::VelocityField::Grid(field) = &medium.population().velocity else {
        panic!("the haze's velocity is not a grid")
    };
    let beta = 3e-3 * hg_backscatter(0.7);
    let (sigma_t, lambda, dt) = (3.3e-3, 1550e-9, spec.dt());
    let w = |s: f64| field.value(glam::DVec3::new(30.0, -40.0, s)).z;
    check_single_scattering_lags(&r, |g, d| {
        let at = |s: f64| {
            let range = s + 1.0;
            let phase = 2.0 * std::f64::consts::PI * 2.0 * w(s) / lambda * d as f64 * dt;
            let geometry = spec.aperture_area() / (range * range)
                * (-2.0 * sigma_t * s).exp()
                * gate_lag_weight(spec, g, 2.0 * range / ohd::SPEED_OF_LIGHT, d);
            Complex64::from_polar(beta * geometry, phase)
        };
        Complex64::new(simpson(|s| at(s).re, 0.0, 400.0, 20_000), simpson(|s| at(s).im, 0.0, 400.0, 20_000))
    });
}
