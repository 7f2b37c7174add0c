//! ohd's BSDFs against Mitsuba 3's (issue 38): the reflection lobes of a rough conductor
//! (copper at 1550 nm), the reflection and transmission lobes of a rough dielectric (air to glass,
//! n = 1.5) at α = 0.05, 0.3, 0.7, and a Lambertian reflector, each at incidences 0°, 40°, 75°.
//! The reference is `validation/peers/mitsuba_bsdf_lobes.json`, written by
//! `validation/peers/bsdf_lobes.py` with Mitsuba 3.9.1 (`roughconductor`, `roughdielectric`,
//! `diffuse`; power weights, `TransportMode.Importance`): per bin of outgoing direction (20 in
//! cos θo over [−1, 1] × 18 in φo) the mean sampled weight and its variance. ohd's BSDFs are
//! sampled here into the same bins; the lobes agree by χ² over the bins, the albedos within 4σ.

use glam::DVec3;
use num_complex::Complex64;
use ohd::sampling::{PathRng, Purpose};
use ohd::surface::{Bsdf, RoughDielectric};
use serde_json::Value;

use crate::support::stats::chi2_sf;

const REFERENCE: &str = include_str!("../../validation/peers/mitsuba_bsdf_lobes.json");
const DRAWS: usize = 1_000_000;

/// ohd's histogram of one case: per bin the mean weight and its variance of the mean; the albedo
/// and its standard error.
fn ohd_lobe(case: &Value, mu_bins: usize, phi_bins: usize, seed: u64) -> (Vec<(f64, f64)>, f64, f64) {
    let num = |k: &str| case[k].as_f64().unwrap();
    let theta = num("theta_deg").to_radians();
    let wi = DVec3::new(theta.sin(), 0.0, theta.cos());
    let kind = case["bsdf"].as_str().unwrap();
    let bsdf = match kind {
        "roughconductor" => Some(Bsdf::Conductor { alpha: num("alpha"), eta: Complex64::new(num("eta"), num("k")) }),
        "diffuse" => Some(Bsdf::Lambertian { albedo: num("reflectance") }),
        _ => None,
    };
    let mut rng = PathRng::new(seed, Purpose::Test, 0, 0);
    let (mut s1, mut s2) = (vec![0.0; mu_bins * phi_bins], vec![0.0; mu_bins * phi_bins]);
    let (mut total, mut total2) = (0.0, 0.0);
    for _ in 0..DRAWS {
        let u = [rng.uniform(), rng.uniform(), rng.uniform()];
        let drawn = match &bsdf {
            Some(b) => b.sample(wi, u).map(|s| (s.wo, s.weight)),
            None => RoughDielectric { alpha: num("alpha") }
                .sample(wi, num("ext_ior"), num("int_ior"), u)
                .map(|c| (c.wo, c.weight)),
        };
        let Some((wo, w)) = drawn else { continue };
        let i = (((wo.z.clamp(-1.0, 1.0) + 1.0) / 2.0 * mu_bins as f64) as usize).min(mu_bins - 1);
        let phi = wo.y.atan2(wo.x).rem_euclid(std::f64::consts::TAU);
        let j = ((phi / std::f64::consts::TAU * phi_bins as f64) as usize).min(phi_bins - 1);
        s1[i * phi_bins + j] += w;
        s2[i * phi_bins + j] += w * w;
        total += w;
        total2 += w * w;
    }
    let n = DRAWS as f64;
    let bins = s1.iter().zip(&s2).map(|(a, b)| (a / n, ((b / n) - (a / n).powi(2)).max(0.0) / n)).collect();
    let albedo = total / n;
    (bins, albedo, ((total2 / n - albedo * albedo).max(0.0) / n).sqrt())
}

#[test]
fn bsdf_lobes_match_mitsuba() {
    let reference: Value = serde_json::from_str(REFERENCE).unwrap();
    let mu_bins = reference["bins"]["mu"][2].as_u64().unwrap() as usize;
    let phi_bins = reference["bins"]["phi"][2].as_u64().unwrap() as usize;
    let cases = reference["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 21, "3 α × 3 angles of two rough BSDFs, 3 angles of the diffuse one");
    let mut failures = Vec::new();
    for (c, case) in cases.iter().enumerate() {
        let (ours, albedo, se) = ohd_lobe(case, mu_bins, phi_bins, 100 + c as u64);
        let mut theirs = vec![(0.0, 0.0); mu_bins * phi_bins];
        for b in case["bins"].as_array().unwrap() {
            theirs[b[0].as_u64().unwrap() as usize] = (b[1].as_f64().unwrap(), b[2].as_f64().unwrap());
        }
        // Bins where either side saw enough weight for a variance to mean something.
        let (mut chi2, mut dof) = (0.0, 0usize);
        for ((a, va), (b, vb)) in ours.iter().zip(&theirs) {
            let v = va + vb;
            if v > 0.0 && (a.max(*b) > 1e-5) {
                chi2 += (a - b).powi(2) / v;
                dof += 1;
            }
        }
        let p = chi2_sf(chi2, dof);
        let (ma, ms) = (case["albedo"].as_f64().unwrap(), case["albedo_stderr"].as_f64().unwrap());
        // (A Lambertian's weight is its albedo on every draw: no spread on either side.)
        let sigma = se.hypot(ms);
        let z =
            if sigma > 0.0 { (albedo - ma) / sigma } else { f64::from(u8::from((albedo - ma).abs() > 1e-12)) * 1e9 };
        let name = format!(
            "{} α {} θi {}°",
            case["bsdf"].as_str().unwrap(),
            case["alpha"].as_f64().map_or("-".into(), |a| a.to_string()),
            case["theta_deg"]
        );
        eprintln!(
            "{name}: χ² {chi2:.1} over {dof} bins (p = {p:.3}); albedo {albedo:.5} ± {se:.5}, Mitsuba {ma:.5} ± {ms:.5} ({z:+.1}σ)"
        );
        // 21 cases: p < 10⁻⁴ anywhere has a 0.2 % chance when the lobes agree.
        if p < 1e-4 || z.abs() > 4.0 {
            failures.push(name);
        }
    }
    assert!(failures.is_empty(), "lobes or albedos differ from Mitsuba's: {failures:?}");
}
