//! Precision (issue 7): Doppler shifts are computed as shifts (`f = (dl/dt)/λ0`), never as
//! differences of optical frequencies, so 1 Hz on a 200 THz carrier is exact; and optical path
//! lengths summed over kilometres keep sub-millimetre accuracy.

use crate::support::run::run;

use ohd::SPEED_OF_LIGHT;
use ohd::detect::BeatModel;

/// The vacuum wavelength of a 200 THz carrier, m.
const LAMBDA_200_THZ: f64 = SPEED_OF_LIGHT / 2e14;

/// The beat model itself: `dl/dt = λ0 · 1 Hz` gives 1 Hz to the last bit, where the difference
/// of the two optical frequencies in `f64` (ulp of 2·10¹⁴ Hz = 1/32 Hz) could not be trusted to
/// better than 3 %.
#[test]
fn beat_frequency_is_a_shift_not_a_difference() {
    let beat = BeatModel::new(LAMBDA_200_THZ, None);
    for f in [1.0, 1e-3, 0.37, 12.5] {
        let got = beat.frequency(0, 0.0, f * LAMBDA_200_THZ);
        assert!((got - f).abs() <= 2.0 * f64::EPSILON * f, "{f} Hz → {got}");
    }
    // What a difference of optical frequencies would give for 0.37 Hz.
    let nu0 = SPEED_OF_LIGHT / LAMBDA_200_THZ;
    let diff = (nu0 + 0.37) - nu0;
    assert!((diff - 0.37).abs() > 1e-3, "f64 differences at 200 THz lose the shift: {diff}");
    // With a chirp the Doppler part is still a shift on top of the range beat.
    let chirped = BeatModel::new(LAMBDA_200_THZ, Some(1e14));
    let l = 2000.0;
    let (up, down) = (chirped.frequency(0, l, LAMBDA_200_THZ), chirped.frequency(1, l, LAMBDA_200_THZ));
    assert!(((up - down) / 2.0 - 1.0).abs() < 1e-6, "f_D from a 667 MHz range beat: {}", (up - down) / 2.0);
}

/// A multiply scattering slab (albedo 1, g = 0.9, optical thickness 10) in uniform motion at
/// `v = λ0/2` per second away from a 200 THz source. In a uniform translation `dl/dt` telescopes
/// to `v·(dir_source − dir_exit)`, so every path leaving within 0.05° of the normal beats at
/// `(1 + cos θ)/2` Hz ∈ [1 − 1.9·10⁻⁷, 1] Hz, whatever its scattering order. On bins of 1 µHz,
/// all of the detected power must land in the one bin around 1 Hz: the sum of hundreds of
/// increments of ~10⁻⁶ m/s keeps 10⁻⁷ relative accuracy.
#[test]
fn one_hertz_doppler_on_a_200_thz_carrier() {
    let text = format!(
        r#"
schema_version = 1
[run]
samples = 200000
batches = 16
seed = 7
[source]
wavelength_nm = {wl_nm}
profile = "pencil"
position_mm = [0, 0, 0]
[media.slab]
sigma_a_per_mm = 0
sigma_s_per_mm = 10
phase = {{ type = "hg", g = 0.9 }}
velocity = {{ type = "uniform", velocity_mm_per_s = [0, 0, {v_mm}] }}
[[layers]]
name = "slab"
thickness_mm = 1
n = 1.0
medium = "slab"
[[detectors]]
name = "top"
area = {{ type = "all" }}
acceptance_half_angle_deg = 0.05
next_event = true
[detectors.spectrum]
f_min_hz = 0.9999955
f_max_hz = 1.0000055
bins = 11
by_order = 3
"#,
        wl_nm = LAMBDA_200_THZ * 1e9,
        v_mm = 0.5 * LAMBDA_200_THZ * 1e3
    );
    let r = run(&text, &[]);
    let (power, _) = r.power(0);
    assert!(power > 0.0);
    let total = r.channel(0, 0, 0);
    println!("power {power:.4e}, spectrum {:?}", total.values);
    assert_eq!((total.below, total.above), (0.0, 0.0), "weight outside ±5 µHz of 1 Hz");
    for (k, v) in total.values.iter().enumerate() {
        if k != 4 {
            assert_eq!(*v, 0.0, "bin {k} ({} Hz) holds {v}", 0.9999955 + k as f64 * 1e-6);
        }
    }
    assert!((total.values[4] / power - 1.0).abs() < 1e-12, "{} of {power}", total.values[4]);
    // Most of it multiply scattered: the shift survives the telescoping sum.
    let high = r.channel(0, 0, 4);
    let share = high.values[4] / power;
    println!("order ≥ 3 share {share:.3}");
    assert!(share > 0.3, "order ≥ 3 carries {share} of the power");
    assert_eq!(r.out.stats.non_finite, 0);
}

/// FMCW over a kilometre: a clear 1 km layer cut into 1000 sublayers of 1 m, then a 10 µm
/// scattering sheet (τ = 0.01), seen in backscatter within 0.01° (shadow rays). A single
/// scattering at depth `z` has `l = z + z/cos θ` ∈ [2000, 2000.000035] m (sheet depth and cone);
/// with a chirp of 10¹⁴ Hz/s one 10 µm bin is 3.3 Hz of a 667 MHz beat. All single-scattering
/// power must land in the four bins from 2000 m to 2000.00004 m, none below 2000 m: the sum over
/// more than 2000 segments is good to well under a millimetre (10 µm here).
#[test]
fn kilometre_paths_keep_sub_millimetre_length() {
    let k = 1e14 / SPEED_OF_LIGHT; // Hz per metre of optical path
    let bin = 1e-5; // m
    let (l_min, bins) = (2000.0 - 5.0 * bin, 20);
    let text = format!(
        r#"
schema_version = 1
[run]
samples = 100000
batches = 16
seed = 8
[source]
wavelength_nm = 1550
profile = "pencil"
position_m = [0, 0, 0]
chirp = {{ bandwidth_ghz = 1, duration_us = 10 }}
[media.air]
sigma_a_per_m = 0
sigma_s_per_m = 0
[media.sheet]
sigma_a_per_m = 0
sigma_s_per_m = 1000
phase = {{ type = "hg", g = 0.0 }}
[[layers]]
name = "air"
thickness_m = 1000
sublayers = 1000
n = 1.0
medium = "air"
[[layers]]
name = "sheet"
thickness_m = 1e-5
n = 1.0
medium = "sheet"
[[detectors]]
name = "top"
area = {{ type = "all" }}
acceptance_half_angle_deg = 0.01
next_event = true
[detectors.spectrum]
f_min_hz = {f_min}
f_max_hz = {f_max}
bins = {bins}
by_order = 2
"#,
        f_min = k * l_min,
        f_max = k * (l_min + bins as f64 * bin),
    );
    let r = run(&text, &[]);
    let (power, _) = r.power(0);
    let single = r.channel(0, 0, 2);
    let single_total: f64 = single.values.iter().sum::<f64>() + single.below + single.above;
    println!("power {power:.4e}, single {single_total:.4e}, bins {:?}", single.values);
    assert!(single_total > 0.9 * power, "single scattering dominates a τ = 0.01 sheet");
    assert_eq!((single.below, single.above), (0.0, 0.0));
    let inside: f64 = single.values[5..9].iter().sum();
    assert!((inside / single_total - 1.0).abs() < 1e-12, "{inside} of {single_total}");
    assert!(single.values[..5].iter().all(|&v| v == 0.0), "a single-scattering path shorter than 2 km");
    // Up and down chirps agree (nothing moves).
    assert_eq!(r.channel(0, 0, 0).values, r.channel(0, 1, 0).values);
    assert_eq!(r.out.stats.non_finite, 0);
}
