//! Doppler physics against closed forms (validation-values §4): sign, rigid translation at every
//! order, isotropic random directions, Poiseuille flow, mirror symmetry, Parseval, FMCW.

use crate::support::run::run;
use crate::support::scenes::tube_scene;
use crate::support::stats::chi_square;

use ohd::transport::event::doppler_increment;

/// A slab of isotropic scatterers, index-matched to its surroundings, watched from the top.
/// λ0 = 1 µm, so f = dl/dt · 1e6 Hz per m/s.
const SLAB: &str = r#"
schema_version = 1
[run]
samples = 400000
seed = 5
batches = 16
[source]
wavelength_nm = 1000
[ambient]
n_above = 1.4
n_below = 1.4
[media.scatterers]
sigma_a_per_mm = 0
sigma_s_per_mm = 1
velocity = { type = "uniform", velocity_mm_per_s = [0, 0, 1] }
[[layers]]
thickness_mm = 1
n = 1.4
medium = "scatterers"
[[detectors]]
name = "top"
acceptance_half_angle_deg = 10
[detectors.spectrum]
f_min_hz = -4000
f_max_hz = 4000
bins = 800
by_order = 6
by_doppler_events = 3
"#;

#[test]
fn coaxial_backscatter_sign_unit() {
    // A particle receding along the beam (+z is away from a top-side observer) at v, backscatter:
    // dir_in = +z, dir_out = −z, so dl/dt = n v (dir_in − dir_out)·ẑ = +2nv: positive frequency.
    let (n, v) = (1.33, 0.7);
    let dldt = doppler_increment(n, glam::DVec3::new(0.0, 0.0, v), glam::DVec3::new(0.0, 0.0, 2.0));
    assert!((dldt - 2.0 * n * v).abs() < 1e-15 && dldt > 0.0);
    // 785 nm in tissue n = 1.4: 3566.9 Hz per mm/s (validation-values §4.1).
    let f = doppler_increment(1.4, glam::DVec3::new(0.0, 0.0, 1e-3), glam::DVec3::new(0.0, 0.0, 2.0)) / 785e-9;
    assert!((f - 3566.9).abs() < 0.05, "{f}");
}

#[test]
fn rigid_translation_gives_the_same_shift_at_every_order() {
    // Internal segments cancel; only the entry (+z) and exit (within 10° of −z) directions count:
    // f ∈ [n v (1 + cos 10°)/λ0, 2nv/λ0] = [2778.7, 2800] Hz for every order ≥ 1. The walk runs
    // under delta tracking with an inflated majorant and a denser region of the same velocity, so
    // null collisions happen and must not add anything.
    let sets = [
        "run.tracking=\"delta\"",
        "run.majorant_scale=2.5",
        "media.dense={ sigma_a_per_mm = 0, sigma_s_per_mm = 3, velocity = { type = \"uniform\", velocity_mm_per_s = [0, 0, 1] } }",
        "regions=[{ layer = \"layer0\", medium = \"dense\", shape = { type = \"sphere\", center_mm = [0, 0, 0.5], radius_mm = 0.3 } }]",
    ];
    let r = run(SLAB, &sets);
    assert!(r.out.stats.null_collisions > 0);
    let (n, v, lambda) = (1.4, 1e-3, 1e-6);
    let (lo, hi) = (n * v * (1.0 + 10f64.to_radians().cos()) / lambda, 2.0 * n * v / lambda);
    let axis = r.exp.detectors[0].surface().unwrap().spectrum().unwrap().axis;
    for order in 1..=6 {
        let ch = r.channel(0, 0, 1 + order); // channel 1 + k is order k
        let mut inside = 0.0;
        for (k, &w) in ch.values.iter().enumerate() {
            let (f0, f1) = (axis.center(k) - 5.0, axis.center(k) + 5.0);
            if f1 > lo && f0 < hi {
                inside += w;
            } else {
                assert_eq!(w, 0.0, "order {order}: weight {w} at {:.1} Hz outside [{lo:.1}, {hi:.1}]", axis.center(k));
            }
        }
        assert!(inside > 0.0, "order {order} detected nothing");
        assert_eq!(ch.below + ch.above, 0.0);
    }
    // Order 0 (light that never scattered) is not Doppler shifted, and here none comes back up.
    assert!(r.channel(0, 0, 1).values.iter().all(|&w| w == 0.0));
}

#[test]
fn isotropic_random_directions_give_a_uniform_spectrum() {
    // Single backscatter on particles moving in uniformly random directions at speed V:
    // f uniform on [−2nV/λ0, +2nV/λ0] = [−2800, 2800] Hz (validation-values §4.3). Order-1
    // detections within 5° of backscatter; 10 bins; all weights are 1 (no absorption, matched
    // indices), so the tallies are counts.
    let r = run(
        SLAB,
        &[
            "media.scatterers.velocity={ type = \"random_direction\", speed_mm_per_s = 1 }",
            "detectors.0.acceptance_half_angle_deg=5",
            "detectors.0.spectrum.f_min_hz=-2800",
            "detectors.0.spectrum.f_max_hz=2800",
            "detectors.0.spectrum.bins=10",
            "run.samples=10000000",
        ],
    );
    let ch = r.channel(0, 0, 2); // order 1
    let counts: Vec<f64> = ch.values.iter().map(|v| (v * r.paths()).round()).collect();
    let total: f64 = counts.iter().sum();
    assert!(total > 5000.0, "only {total} single-scattering detections");
    // Out of range only through the 5° cone blur (|q| < 2k): none beyond the edges.
    assert_eq!(ch.below + ch.above, 0.0);
    let (stat, dof, p) = chi_square(&counts, &[0.1; 10]);
    assert!(p > 1e-4, "chi2 {stat:.1} / {dof} dof, p = {p:.2e}: {counts:?}");
}

#[test]
fn uniformly_illuminated_poiseuille_tube_gives_a_flat_spectrum() {
    // An optically thin tube (τ ≈ 0.03 across) at 45° in a transparent layer, lit by a flat-top
    // beam wider than its projection, observed in near-backscatter (HG g = −0.99 scatterers,
    // 3° acceptance). Every tube element is lit and weighted alike, and the slab planes cut every
    // axis-parallel line over the same length, so v = v_max(1 − r²/R²) is uniform on [0, v_max]:
    // the spectrum is flat on [0, f_max], f_max = n v_max ê·(dir_in − dir_out)/λ0 = √2 v_max/λ0
    // (validation-values §4.4, "whole cross-section uniformly illuminated and weighted").
    let text = tube_scene(r#"{ type = "poiseuille", v_max_mm_per_s = 1 }"#);
    let r = run(&text, &["run.seed=9"]);
    let ch = r.channel(0, 0, 2); // order 1
    let counts: Vec<f64> = ch.values.iter().map(|v| (v * r.paths()).round()).collect();
    // Bins 0–18 lie inside [0, 0.95 f_max]: flat. Bin 19 ends at f_max and bin 20 holds only the
    // blur of the 3° cone (≤ 2.6 % of f_max); beyond 1.05 f_max there is nothing.
    let inner = &counts[..19];
    let n_inner: f64 = inner.iter().sum();
    assert!(n_inner > 5000.0, "only {n_inner} detections");
    let (stat, dof, p) = chi_square(inner, &[1.0 / 19.0; 19]);
    assert!(p > 1e-4, "chi2 {stat:.1} / {dof} dof, p = {p:.2e}: {inner:?}");
    assert_eq!(counts[21], 0.0);
    assert_eq!(ch.above, 0.0);
    assert!(counts[20] < 0.2 * n_inner / 19.0, "blur bin {}", counts[20]);
    // A plug-flow control: a uniform velocity gives a single line at f_max instead.
}

#[test]
fn reversing_velocities_mirrors_the_spectrum_exactly() {
    // Same seed, every velocity reversed: bin k ↔ bin B−1−k exactly (odd bin count, symmetric axis),
    // below ↔ above, in every channel. Poiseuille (default scene) and uniform.
    let cases: [(&str, Vec<&str>, Vec<&str>); 2] = [
        (
            ohd::DEFAULT_CONFIG,
            vec!["run.samples=100000"],
            vec!["run.samples=100000", "media.blood.velocity.v_max_mm_per_s=-34"],
        ),
        (
            SLAB,
            vec!["run.samples=100000", "detectors.0.spectrum.bins=801"],
            vec![
                "run.samples=100000",
                "detectors.0.spectrum.bins=801",
                "media.scatterers.velocity.velocity_mm_per_s=[0, 0, -1]",
            ],
        ),
    ];
    for (text, fwd, rev) in cases {
        let (a, b) = (run(text, &fwd), run(text, &rev));
        let channels = a.out.layout.detectors[0].spectrum().unwrap().channels;
        let mut shifted = 0.0;
        for c in 0..channels {
            let (x, y) = (a.channel(0, 0, c), b.channel(0, 0, c));
            let n = x.values.len();
            for k in 0..n {
                assert_eq!(x.values[k], y.values[n - 1 - k], "channel {c}, bin {k}");
                assert_eq!(x.stderr[k], y.stderr[n - 1 - k]);
                if 2 * k + 1 != n {
                    shifted += x.values[k];
                }
            }
            assert_eq!((x.below, x.above), (y.above, y.below));
        }
        assert!(shifted > 0.0, "the check must see shifted light");
    }
}

#[test]
fn parseval_spectrum_sums_to_detected_power() {
    // Sum over bins plus the out-of-range tallies equals the detected power of the same paths, for
    // the total and for every split (orders, Doppler events), to rounding.
    for (text, sets) in [
        (ohd::DEFAULT_CONFIG, vec!["run.samples=100000"]),
        (SLAB, vec!["run.samples=100000", "detectors.0.spectrum.f_max_hz=2790"]),
    ] {
        let r = run(text, &sets);
        let (power, _) = r.power(0);
        let spec = r.exp.detectors[0].surface().unwrap().spectrum().unwrap();
        let groups = [
            (0usize, 1usize),
            (1, spec.by_order.unwrap() as usize + 1),
            (2 + spec.by_order.unwrap() as usize, spec.by_doppler_events.unwrap() as usize + 1),
        ];
        let mut out_of_range = 0.0;
        for (first, count) in groups {
            let mut sum = 0.0;
            for c in first..first + count {
                let ch = r.channel(0, 0, c);
                sum += ch.values.iter().sum::<f64>() + ch.below + ch.above;
                if c == 0 {
                    out_of_range = ch.below + ch.above;
                }
            }
            assert!((sum - power).abs() <= 1e-12 * power, "channels {first}..: {sum} vs {power}");
        }
        assert!(power > 0.0);
        if sets.len() > 1 {
            assert!(out_of_range > 0.0, "the narrowed axis must push weight out of range");
        }
    }
}

#[test]
fn fmcw_beat_of_a_receding_diffuse_target() {
    // A thin, dense (τ = 20) scattering sheet 10 m below the laser, receding at 1 m/s, watched
    // from the laser's plane: f_R = 2RB/(cT) = 6.6713 MHz for B = 1 GHz, T = 10 µs, and the
    // Doppler shift of 2v/λ0 = 1.2903 MHz at 1550 nm splits the chirps:
    // f_up = f_R + f_D, f_down = f_R − f_D (validation-values §4.6). R and v are recovered.
    let text = r#"
schema_version = 1
[run]
samples = 200000
seed = 2
batches = 16
[source]
wavelength_nm = 1550
position_m = [0, 0, -10]
chirp = { bandwidth_ghz = 1, duration_us = 10 }
[media.target]
sigma_a_per_mm = 0
sigma_s_per_mm = 20000
velocity = { type = "uniform", velocity_m_per_s = [0, 0, 1] }
[[layers]]
thickness_mm = 0.001
n = 1.0
medium = "target"
[[detectors]]
name = "rx"
distance_m = 10
area = { type = "disk", radius_m = 0.5 }
acceptance_half_angle_deg = 2
[detectors.spectrum]
f_min_mhz = 0
f_max_mhz = 15
bins = 3000
"#;
    let r = run(text, &[]);
    let axis = r.exp.detectors[0].surface().unwrap().spectrum().unwrap().axis;
    let peak = |chirp: usize| {
        let ch = r.channel(0, chirp, 0);
        let (k, _) = ch.values.iter().enumerate().max_by(|a, b| a.1.partial_cmp(b.1).unwrap()).unwrap();
        // Weighted mean over the peak's neighbourhood (±3 bins).
        let (mut s, mut w) = (0.0, 0.0);
        for j in k.saturating_sub(3)..=(k + 3).min(axis.bins - 1) {
            s += ch.values[j] * axis.center(j);
            w += ch.values[j];
        }
        s / w
    };
    let (up, down) = (peak(0), peak(1));
    let c = ohd::SPEED_OF_LIGHT;
    let (b, t, lambda) = (1e9, 10e-6, 1550e-9);
    let f_r = 2.0 * 10.0 * b / (c * t);
    let f_d = 2.0 * 1.0 / lambda;
    let bin = axis.bin_width();
    assert!((up - (f_r + f_d)).abs() < bin, "f_up {up} vs {}", f_r + f_d);
    assert!((down - (f_r - f_d)).abs() < bin, "f_down {down} vs {}", f_r - f_d);
    let range = c * t * (up + down) / (4.0 * b);
    let v = lambda * (up - down) / 4.0;
    assert!((range - 10.0).abs() < 0.01, "R = {range}");
    assert!((v - 1.0).abs() < 0.005, "v = {v}");
}
