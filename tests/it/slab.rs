//! Radiative transfer in slabs against published and closed-form values (validation-values §1),
//! energy conservation, Fresnel interfaces, honesty of the error bars, and agreement of the
//! tracking estimators.

use crate::support::run::run;
use crate::support::stats::assert_within_sigma;

use ohd::detect::Scalar;

const VDH: &str = include_str!("../../validation/vdh_slab.toml");

#[test]
fn van_de_hulst_slab() {
    // 1e6 photons; Rd, Tt, unscattered T within 3σ of van de Hulst (1980) / MCML.
    let r = run(VDH, &["run.samples=1000000", "run.seed=11"]);
    let (rd, se_rd) = r.scalar(Scalar::ReflectanceDiffuse);
    let (tt, se_tt) = r.scalar(Scalar::TransmittanceTotal);
    let (tu, se_tu) = r.scalar(Scalar::TransmittanceUnscattered);
    assert_within_sigma("Rd", rd, se_rd, 0.09739, 3.0);
    assert_within_sigma("Tt", tt, se_tt, 0.66096, 3.0);
    assert_within_sigma("T unscattered", tu, se_tu, (-2.0f64).exp(), 3.0);
    // Matched boundaries: no specular reflection at all.
    assert_eq!(r.scalar(Scalar::ReflectanceSpecular).0, 0.0);
    // Absorption closes the balance exactly in expectation: A = 1 − Rd − Tt within 3σ of the sum.
    let (a, se_a) = r.scalar(Scalar::AbsorbedFraction);
    assert_within_sigma("A", a, se_a, 1.0 - rd - tt, 4.0);
}

#[test]
fn albedo_one_conserves_energy_with_fresnel_interfaces() {
    // No absorption, mismatched indices on both sides (partial reflection and total internal
    // reflection at every exit): every packet leaves with weight 1, so R + T = 1.
    let r = run(VDH, &["media.slab.sigma_a_per_cm=0", "layers.0.n=1.4", "ambient.n_below=1.33", "run.samples=200000"]);
    let total = r.scalar(Scalar::ReflectanceSpecular).0
        + r.scalar(Scalar::ReflectanceDiffuse).0
        + r.scalar(Scalar::TransmittanceTotal).0;
    assert!((1.0 - total).abs() < 1e-3, "R + T = {total}");
    assert_eq!(r.scalar(Scalar::AbsorbedFraction).0, 0.0);
    assert_eq!(r.out.stats.roulette_terminations, 0);
}

#[test]
fn fresnel_slab_closed_form() {
    // A purely absorbing slab of index n in air, normal incidence: specular R0 = ((n−1)/(n+1))²
    // exactly, and unscattered transmission through the multiple internal reflections
    // T = (1 − R0)² e^{−τ} / (1 − R0² e^{−2τ}) (the packets reflected back inside cross again).
    let n: f64 = 1.5;
    let tau: f64 = 0.5;
    let r = run(
        VDH,
        &[
            "media.slab.sigma_s_per_cm=0",
            "media.slab.sigma_a_per_cm=25", // τ = 25 /cm × 0.02 cm
            "layers.0.n=1.5",
            "run.samples=1000000",
            "run.roulette_threshold=0",
        ],
    );
    let r0 = ((n - 1.0) / (n + 1.0)).powi(2);
    let (rsp, se_sp) = r.scalar(Scalar::ReflectanceSpecular);
    assert!((rsp - r0).abs() < 1e-12 && se_sp < 1e-12, "specular {rsp} vs {r0}");
    let e = (-tau).exp();
    let t = (1.0 - r0).powi(2) * e / (1.0 - r0 * r0 * e * e);
    let (tt, se) = r.scalar(Scalar::TransmittanceTotal);
    assert_within_sigma("T through a Fresnel slab", tt, se, t, 3.0);
    // What leaves through the top besides the specular part: the internally reflected packets,
    // R = R0 + (1 − R0)² R0 e^{−2τ} / (1 − R0² e^{−2τ}) in total.
    let rd_expected = (1.0 - r0).powi(2) * r0 * e * e / (1.0 - r0 * r0 * e * e);
    let (rd, se_rd) = r.scalar(Scalar::ReflectanceDiffuse);
    assert_within_sigma("internally reflected R", rd, se_rd, rd_expected, 3.0);
}

#[test]
fn oblique_specular_reflection_is_fresnel() {
    // A beam at 45° onto glass (n = 1.5): the specular reflectance is the unpolarised Fresnel
    // value 0.05024 exactly, and the light refracted in travels at sin θt = sin 45°/1.5; with an
    // absorbing slab of τ = 0.5 along the normal, the unscattered transmission through the
    // oblique path is e^{−τ/cos θt} times the two interface transmissions (up to the multiple
    // internal reflections, which add (1 − R)² R² e^{−3τ/cos θt}/(1 − R² e^{−2τ/cos θt})).
    let r = run(
        VDH,
        &[
            "media.slab.sigma_s_per_cm=0",
            "media.slab.sigma_a_per_cm=25",
            "layers.0.n=1.5",
            "source.direction=[1, 0, 1]",
            "run.samples=400000",
            "run.roulette_threshold=0",
        ],
    );
    let (rsp, _) = r.scalar(Scalar::ReflectanceSpecular);
    assert!((rsp - 0.050_240).abs() < 5e-6, "specular at 45° = {rsp}");
    let cos_t = (1.0f64 - 0.5 / 2.25).sqrt();
    // Fresnel reflectance inside the slab at θt (the same for both crossings, by reciprocity).
    let cos45 = std::f64::consts::FRAC_1_SQRT_2;
    let (r0, _) = ohd::transport::fresnel::reflectance(1.0, 1.5, cos45);
    let e = (-0.5 / cos_t).exp();
    let t = (1.0 - r0).powi(2) * e / (1.0 - r0 * r0 * e * e);
    let (tt, se) = r.scalar(Scalar::TransmittanceTotal);
    assert_within_sigma("T through an oblique Fresnel slab", tt, se, t, 3.0);
}

#[test]
fn error_bars_are_honest() {
    // Over 40 independent runs of the van de Hulst slab, z = (estimate − reference)/stderr must
    // look like a unit normal: mean within 3.5/√40, sample variance within the 99.9% chi-square
    // band for 39 degrees of freedom ([0.45, 1.85]).
    let mut z = Vec::new();
    for seed in 0..40 {
        let r = run(VDH, &["run.samples=50000", "run.batches=16", &format!("run.seed={}", 1000 + seed)]);
        let (rd, se) = r.scalar(Scalar::ReflectanceDiffuse);
        z.push((rd - 0.09739) / se);
        let (tt, se) = r.scalar(Scalar::TransmittanceTotal);
        z.push((tt - 0.66096) / se);
    }
    for (name, zs) in [
        ("Rd", z.iter().step_by(2).copied().collect::<Vec<_>>()),
        ("Tt", z.iter().skip(1).step_by(2).copied().collect()),
    ] {
        let k = zs.len() as f64;
        let mean = zs.iter().sum::<f64>() / k;
        let var = zs.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (k - 1.0);
        assert!(mean.abs() < 3.5 / k.sqrt(), "{name}: mean z = {mean:.3}");
        assert!((0.45..1.85).contains(&var), "{name}: var z = {var:.3}");
    }
}

#[test]
fn analytic_and_delta_tracking_agree() {
    // The default scene (a vessel in tissue): analytic segments versus delta tracking with the
    // exact and a 3× inflated majorant give the same reflectance and detected power within 4σ.
    let base = ["run.samples=400000", "run.seed=3"];
    let a = run(ohd::DEFAULT_CONFIG, &base);
    for scale in ["1", "3"] {
        let mut sets = base.to_vec();
        let s = format!("run.majorant_scale={scale}");
        sets.extend(["run.tracking=\"delta\"", s.as_str()]);
        let d = run(ohd::DEFAULT_CONFIG, &sets);
        assert!(d.out.stats.null_collisions > 0);
        for (what, (x, sx), (y, sy)) in [
            ("Rd", a.scalar(Scalar::ReflectanceDiffuse), d.scalar(Scalar::ReflectanceDiffuse)),
            ("camera power", a.power(0), d.power(0)),
        ] {
            let z = (x - y) / (sx * sx + sy * sy).sqrt();
            assert!(z.abs() < 4.0, "{what} (majorant ×{scale}): {x:.6} ± {sx:.6} vs {y:.6} ± {sy:.6}");
        }
        // The Doppler-shifted share (paths that met the moving blood) agrees too.
        let (ca, cd) = (a.channel(0, 0, 0), d.channel(0, 0, 0));
        let dc = 100; // DC bin of the default 201-bin axis
        let (sa, sd): (f64, f64) = (
            ca.values.iter().enumerate().filter(|(k, _)| *k != dc).map(|(_, v)| v).sum(),
            cd.values.iter().enumerate().filter(|(k, _)| *k != dc).map(|(_, v)| v).sum(),
        );
        let (ea, ed) = (
            ca.stderr.iter().enumerate().filter(|(k, _)| *k != dc).map(|(_, v)| v * v).sum::<f64>(),
            cd.stderr.iter().enumerate().filter(|(k, _)| *k != dc).map(|(_, v)| v * v).sum::<f64>(),
        );
        // Summing per-bin variances overstates the error of the sum only through bin correlations,
        // which are positive here; the test stays conservative.
        assert!(((sa - sd) / (ea + ed).sqrt()).abs() < 4.0, "shifted power {sa} vs {sd}");
    }
}
