//! Box phantoms (`[lateral]`, `ohd::medium::Lateral`): the energy balance with the side faces'
//! term, a wide box against the infinite slab, Fresnel's split at a side face against its closed
//! form, a matched box, the volume tally and the time gate inside a box, and MCX's cube60 and
//! cube60b benchmarks against MCX's own acceptance ranges.

use ohd::detect::Scalar;

use crate::support::run::{Run, run};
use crate::support::stats::assert_within_sigma;

const VDH: &str = include_str!("../../validation/vdh_slab.toml");
const CUBE60: &str = include_str!("../../validation/cube60/cube60.toml");
const CUBE60B: &str = include_str!("../../validation/cube60/cube60b.toml");

/// `transmittance_lateral` (value, standard error).
fn lateral(r: &Run) -> (f64, f64) {
    let i = r.out.layout.lateral.expect("a box declares transmittance_lateral");
    (r.out.estimates.mean()[i], r.out.estimates.stderr()[i])
}

/// R_sp + R_d + T + A + lateral.
fn balance(r: &Run) -> f64 {
    [Scalar::ReflectanceSpecular, Scalar::ReflectanceDiffuse, Scalar::TransmittanceTotal, Scalar::AbsorbedFraction]
        .iter()
        .map(|&s| r.scalar(s).0)
        .sum::<f64>()
        + lateral(r).0
}

/// Unpolarised Fresnel reflectance from `n1` into `n2` at incidence `cos_i` (Born & Wolf §1.5):
/// `R = (r_s² + r_p²)/2`, `r_s = (n1 cos i − n2 cos t)/(n1 cos i + n2 cos t)`,
/// `r_p = (n2 cos i − n1 cos t)/(n2 cos i + n1 cos t)`; 1 beyond the critical angle.
fn fresnel(n1: f64, n2: f64, cos_i: f64) -> f64 {
    let sin_t = n1 / n2 * (1.0 - cos_i * cos_i).sqrt();
    if sin_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    let rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t);
    0.5 * (rs * rs + rp * rp)
}

#[test]
fn energy_balance_is_exact_per_path_in_a_mismatched_box() {
    // A 3 × 4 × 2 mm box of index 1.4 (μs' = 1/mm, μa = 0.05/mm) with air above, water below
    // and n = 1.2 beside, no roulette and no gate: absorption weighting leaves every path's
    // weight in A or at one face, so R_sp + R_d + T + A + lateral = 1 path by path (up to
    // rounding), and the side faces take a good share.
    let r = run(
        VDH,
        &[
            "media.slab.sigma_a_per_cm=0.5",
            "media.slab.sigma_s_per_cm=40",
            "layers.0.thickness_mm=2",
            "layers.0.n=1.4",
            "ambient.n_below=1.33",
            "lateral.x_mm=[-1, 2]",
            "lateral.y_mm=[-2.5, 1.5]",
            "lateral.n_outside=1.2",
            "run.roulette_threshold=0",
            "run.samples=20000",
        ],
    );
    let total = balance(&r);
    let (lat, _) = lateral(&r);
    eprintln!(
        "lateral {lat:.5}, R_d {:.5}, T {:.5}",
        r.scalar(Scalar::ReflectanceDiffuse).0,
        r.scalar(Scalar::TransmittanceTotal).0
    );
    assert!(lat > 0.05, "lateral {lat}");
    assert!((total - 1.0).abs() < 1e-12, "R + T + A + lateral = {total}");
    assert_eq!(r.out.stats.truncated_paths, 0);
}

#[test]
fn a_wide_box_is_the_infinite_slab() {
    // The van de Hulst slab (transport length 1/(μa + μs(1 − g)) = 0.31 mm) cut to a box 6 mm
    // wide (±10 transport lengths): Rd, Tt and A within 3σ of van de Hulst (1980) / MCML as for
    // the infinite slab (`slab::van_de_hulst_slab`), and next to nothing leaves at the sides.
    let r = run(VDH, &["lateral.x_mm=[-3, 3]", "lateral.y_mm=[-3, 3]", "run.samples=1000000", "run.seed=11"]);
    let (rd, se_rd) = r.scalar(Scalar::ReflectanceDiffuse);
    let (tt, se_tt) = r.scalar(Scalar::TransmittanceTotal);
    let (a, se_a) = r.scalar(Scalar::AbsorbedFraction);
    assert_within_sigma("Rd", rd, se_rd, 0.09739, 3.0);
    assert_within_sigma("Tt", tt, se_tt, 0.66096, 3.0);
    assert_within_sigma("A", a, se_a, 1.0 - 0.09739 - 0.66096, 3.0);
    let (lat, se_lat) = lateral(&r);
    assert!(lat < 0.1 * se_rd.min(se_tt), "lateral {lat} ± {se_lat}");
    // A box 0.6 mm wide (±1 transport length) loses a good part at the sides: the term is live.
    let narrow = run(VDH, &["lateral.x_mm=[-0.3, 0.3]", "lateral.y_mm=[-0.3, 0.3]", "run.samples=20000"]);
    assert!(lateral(&narrow).0 > 0.05, "narrow box: lateral {}", lateral(&narrow).0);
    assert!((balance(&narrow) - 1.0).abs() < 1e-3, "narrow box: balance {}", balance(&narrow));
}

/// A clear layer 2 mm thick, index 1.5, water-matched below, cut at x = 1 mm (and far away on
/// the other sides), a pencil beam from air at 60° towards +x entering at the origin.
fn clear_box(n_outside: f64) -> Run {
    let theta = 60f64.to_radians();
    let dir = format!("source.direction=[{}, 0, {}]", theta.sin(), theta.cos());
    let n_out = format!("lateral.n_outside={n_outside}");
    run(
        VDH,
        &[
            "media.slab.sigma_a_per_cm=0",
            "media.slab.sigma_s_per_cm=0",
            "layers.0.thickness_mm=2",
            "layers.0.n=1.5",
            "ambient.n_below=1.5",
            &dir,
            "lateral.x_mm=[-10, 1]",
            "lateral.y_mm=[-10, 10]",
            &n_out,
            "run.samples=200000",
            "run.seed=5",
        ],
    )
}

#[test]
fn a_beam_splits_at_a_side_face_as_fresnel_says() {
    // Refracted at the top (sin θ = sin 60°/1.5), the beam meets the x = 1 mm face at depth
    // 1.41 mm with incidence cos i = sin θ; what the face reflects crosses back to the matched
    // bottom (at x = 0.59 mm) and is transmitted. So, with R_sp the specular reflectance at 60°
    // and R the face's: lateral = (1 − R_sp)(1 − R), T = (1 − R_sp) R (binomial, each path one
    // draw), against water (n = 1.33) outside.
    let r = clear_box(1.33);
    let cos60 = 0.5f64;
    let r_sp = fresnel(1.0, 1.5, cos60);
    let sin_in = 60f64.to_radians().sin() / 1.5;
    let r_face = fresnel(1.5, 1.33, sin_in);
    eprintln!("R_sp {r_sp:.6}, face R {r_face:.6}");
    assert!((r.scalar(Scalar::ReflectanceSpecular).0 - r_sp).abs() < 1e-12);
    assert!(r_face > 0.02 && r_face < 0.5, "a split worth testing: R = {r_face}");
    let (lat, se_lat) = lateral(&r);
    let (t, se_t) = r.scalar(Scalar::TransmittanceTotal);
    assert_within_sigma("lateral", lat, se_lat, (1.0 - r_sp) * (1.0 - r_face), 3.0);
    assert_within_sigma("T", t, se_t, (1.0 - r_sp) * r_face, 3.0);
    assert!((r_sp + lat + t - 1.0).abs() < 1e-12, "balance {}", r_sp + lat + t);
    // Air outside: incidence beyond the critical angle (sin i = cos θ = 0.82 > 1/1.5), all of
    // it is reflected back in and leaves at the bottom.
    let tir = clear_box(1.0);
    assert_eq!(lateral(&tir).0, 0.0);
    assert!((tir.scalar(Scalar::TransmittanceTotal).0 - (1.0 - r_sp)).abs() < 1e-12);
}

#[test]
fn a_matched_box_loses_exactly_what_crosses_its_faces() {
    // n outside = n inside: no face reflects, so everything that reaches the x face leaves
    // there, deterministically: lateral = 1 − R_sp, nothing reaches the bottom.
    let r = clear_box(1.5);
    let r_sp = fresnel(1.0, 1.5, 0.5);
    let (lat, se_lat) = lateral(&r);
    assert!((lat - (1.0 - r_sp)).abs() < 1e-12 && se_lat < 1e-12, "lateral {lat} ± {se_lat}");
    assert_eq!(r.scalar(Scalar::TransmittanceTotal).0, 0.0);
}

#[test]
fn volume_tally_and_time_gate_work_in_a_box() {
    // A volume grid over a 2 × 2 × 1 mm box (and beyond it): every deposit lands in a voxel, so
    // the voxels add up to absorbed_fraction, with the time gate on too; the gate only removes
    // weight (the balance falls short by what is still travelling at t1).
    let sets = [
        "media.slab.sigma_a_per_cm=5",
        "media.slab.sigma_s_per_cm=50",
        "layers.0.thickness_mm=1",
        "layers.0.n=1.4",
        "lateral.x_mm=[-1, 1]",
        "lateral.y_mm=[-1, 1]",
        "lateral.n_outside=1.0",
        "volume.center_mm=[0, 0, 0.5]",
        "volume.size_mm=[4, 4, 1.2]",
        "volume.voxels=[4, 4, 3]",
        "run.samples=20000",
    ];
    for gate in [None, Some("run.time_gate_ns=[0, 0.01]")] {
        let mut s: Vec<&str> = sets.to_vec();
        s.extend(gate);
        let r = run(VDH, &s);
        let (a, _) = r.scalar(Scalar::AbsorbedFraction);
        let o = r.out.layout.registry.expect("volume.absorbed");
        let (v, _) = o.values(r.out.estimates.mean(), &r.out.estimates.stderr());
        let sum: f64 = v.iter().sum();
        assert!(a > 0.05 && (sum - a).abs() <= 1e-12 * a, "{gate:?}: Σ voxels {sum} vs absorbed_fraction {a}");
        let total = balance(&r);
        eprintln!("{gate:?}: balance {total:.6}, lateral {:.5}", lateral(&r).0);
        match gate {
            None => assert!((total - 1.0).abs() < 2e-3, "balance {total}"),
            Some(_) => assert!(total < 0.99 && total > 0.3, "gated balance {total}"),
        }
    }
}

#[test]
fn cube60_and_cube60b_meet_mcx_acceptance_ranges() {
    // MCX's own regression test (test/testmcx.sh) accepts "absorbed: 17.x%" for cube60 (no
    // boundary reflection) and "27.x%" for cube60b (Fresnel on all six faces, n = 1 outside);
    // MCX launches without the specular loss at entry, so cube60b's absorbed fraction is
    // divided by 1 − R_sp (see validation/cube60/). 2·10⁵ paths: σ ≈ 0.08 % (absolute), the
    // values (17.7 %, 27.3 % at 10⁷ paths) sit ≥ 3σ inside the ranges.
    let r = run(CUBE60, &["run.samples=200000", "run.seed=3"]);
    let (a, se) = r.scalar(Scalar::AbsorbedFraction);
    eprintln!("cube60: {a:.5} ± {se:.5}");
    assert!((0.17..0.18).contains(&a) && se < 1e-3, "cube60 absorbed {a} ± {se}");
    let r = run(CUBE60B, &["run.samples=200000", "run.seed=3"]);
    let (a, se) = r.scalar(Scalar::AbsorbedFraction);
    let r_sp = r.scalar(Scalar::ReflectanceSpecular).0;
    assert!((r_sp - fresnel(1.0, 1.37, 1.0)).abs() < 1e-12);
    let (a, se) = (a / (1.0 - r_sp), se / (1.0 - r_sp));
    eprintln!("cube60b: {a:.5} ± {se:.5}");
    assert!((0.27..0.28).contains(&a) && se < 1e-3, "cube60b absorbed {a} ± {se}");
}
