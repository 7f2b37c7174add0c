//! Direction and distance samplers against their densities: chi-square for Henyey–Greenstein,
//! Kolmogorov–Smirnov for free-flight distances (homogeneous and piecewise media, analytic and
//! delta tracking). Fixed seeds; a test fails below p = 1e-4.

use crate::support::stats::{chi_square, ks_test};
use ohd::numeric::simpson;

use glam::DVec3;
use ohd::flow::VelocityField;
use ohd::medium::{Layer, Medium, Region, Scene, Shape};
use ohd::phase::{HenyeyGreenstein, PhaseFunction};
use ohd::sampling::{PathRng, Purpose};
use ohd::transport::{Flight, LayerRay, Tracking, free_flight};

const P_MIN: f64 = 1e-4;

/// Probability mass of HG(h ≥ 0) on `m = 1 − cos θ ∈ [a, b]`, by integrating the *density*
/// (`eval`, not the sampler's inverse CDF) with Simpson's rule on a log grid.
fn hg_mass(h: f64, a: f64, b: f64) -> f64 {
    let p = HenyeyGreenstein::new(h).unwrap();
    let f = |m: f64| 2.0 * std::f64::consts::PI * p.eval(1.0 - m);
    let n = 400; // even
    if a <= 0.0 {
        // [0, b]: the density is smooth here (b is tiny); plain Simpson.
        return simpson(f, 0.0, b, n);
    }
    // Substitute m = e^u: ∫ f(m) dm = ∫ f(e^u) e^u du.
    let (ua, ub) = (a.ln(), b.ln());
    simpson(|u: f64| f(u.exp()) * u.exp(), ua, ub, n)
}

#[test]
fn henyey_greenstein_chi_square() {
    // Bins in log(1 − cos θ) about the peak (log(1 + cos θ) for g < 0), so that a forward peak of
    // width (1 − g)² is resolved: the first edge sits 1e-3 of the peak width from it.
    for (i, &g) in [-0.9f64, 0.0, 0.5, 0.9, 0.99, 0.999].iter().enumerate() {
        let h: f64 = g.abs();
        let width = (1.0 - h) * (1.0 - h);
        let lo: f64 = (1e-3 * width).max(1e-12);
        let nb = 60;
        let mut edges = vec![0.0];
        for k in 0..=nb {
            edges.push(lo * (2.0 / lo).powf(k as f64 / nb as f64));
        }
        let probs: Vec<f64> = edges.windows(2).map(|w| hg_mass(h, w[0], w[1])).collect();
        let total: f64 = probs.iter().sum();
        assert!((total - 1.0).abs() < 1e-6, "g={g}: density integrates to {total}");
        let phase = PhaseFunction::HenyeyGreenstein(HenyeyGreenstein::new(g).unwrap());
        let mut counts = vec![0.0; probs.len()];
        let n = 1_000_000;
        let mut rng = PathRng::new(20_251_122, Purpose::Test, i as u64, 0);
        for _ in 0..n {
            let d = phase.sample(rng.uniform());
            // Distance from the peak: 1 − cos θ forward, 1 + cos θ for backward g.
            let t = if g >= 0.0 { d.one_minus_cos } else { 2.0 - d.one_minus_cos };
            let k = edges.partition_point(|&e| e <= t).saturating_sub(1).min(counts.len() - 1);
            counts[k] += 1.0;
        }
        let (stat, dof, p) = chi_square(&counts, &probs);
        assert!(p > P_MIN, "g={g}: chi2 = {stat:.1} for {dof} dof, p = {p:.2e}");
    }
}

fn medium(name: &str, sigma_t: f64) -> Medium {
    Medium::new(name, 0.0, sigma_t, PhaseFunction::Isotropic, VelocityField::Static)
}

/// A semi-infinite layer of σt = 1000 /m with a sphere (σt = 4000 /m) and a box (σt = 0, a void)
/// on the ray's way.
fn piecewise_scene() -> Scene {
    let regions = vec![
        Region {
            name: "sphere".into(),
            shape: Shape::Sphere { center: DVec3::new(0.0, 0.0, 1.5e-3), radius: 0.5e-3 },
            medium: 1,
            layer: 0,
        },
        Region {
            name: "void".into(),
            shape: Shape::Box { min: DVec3::new(-1.0, -1.0, 2.5e-3), max: DVec3::new(1.0, 1.0, 3.0e-3) },
            medium: 2,
            layer: 0,
        },
    ];
    Scene {
        layers: vec![Layer {
            name: "l".into(),
            z_top: 0.0,
            z_bottom: f64::INFINITY,
            n: 1.0,
            medium: 0,
            regions: vec![0, 1],
            majorant: 4000.0,
            minorant: 0.0,
            heterogeneous: false,
            tau_above: 0.0,
            rough_faces: false,
            plain: true,
            obstructs_shadows: false,
            opaque: Vec::new(),
            face: ohd::surface::Interface::Smooth,
        }],
        regions,
        media: vec![medium("base", 1000.0), medium("dense", 4000.0), medium("void", 0.0)],
        n_above: 1.0,
        n_below: 1.0,
        lateral: None,
        bottom: None,
        opaque: Vec::new(),
        first_rough_face: 1,
        cycle: None,
    }
}

/// Optical depth along +z from the origin in [`piecewise_scene`].
fn piecewise_depth(t: f64) -> f64 {
    let seg = |a: f64, b: f64| (t.min(b) - a).max(0.0);
    1000.0 * t + 3000.0 * seg(1.0e-3, 2.0e-3) - 1000.0 * seg(2.5e-3, 3.0e-3)
}

fn sample_distances(scene: &Scene, tracking: Tracking, n: usize, stream: u64) -> (Vec<f64>, u64) {
    let mut rng = PathRng::new(7, Purpose::Test, stream, 0);
    let mut nulls = 0;
    let layer = &scene.layers[0];
    let d: Vec<f64> = (0..n)
        .map(|_| {
            match free_flight(
                LayerRay { scene, layer, pos: DVec3::ZERO, dir: DVec3::Z },
                f64::INFINITY,
                1.0,
                tracking,
                &mut rng,
                &mut nulls,
            ) {
                Flight::Collision { t, .. } => t,
                Flight::Boundary { t } => t,
            }
        })
        .collect();
    (d, nulls)
}

#[test]
fn free_flight_distances_ks() {
    // Homogeneous: CDF 1 − exp(−σt t).
    let mut homogeneous = piecewise_scene();
    homogeneous.layers[0].regions.clear();
    let (mut d, _) = sample_distances(&homogeneous, Tracking::Analytic, 200_000, 1);
    let (ks, p) = ks_test(&mut d, |t| 1.0 - (-1000.0 * t).exp());
    assert!(p > P_MIN, "homogeneous: D = {ks:.5}, p = {p:.2e}");

    // Piecewise: CDF 1 − exp(−τ(t)) for analytic segments, delta tracking with the exact and an
    // inflated majorant.
    let scene = piecewise_scene();
    for (k, tracking) in
        [Tracking::Analytic, Tracking::Delta { majorant_scale: 1.0 }, Tracking::Delta { majorant_scale: 3.0 }]
            .into_iter()
            .enumerate()
    {
        let (mut d, nulls) = sample_distances(&scene, tracking, 200_000, 10 + k as u64);
        let (ks, p) = ks_test(&mut d, |t| 1.0 - (-piecewise_depth(t)).exp());
        assert!(p > P_MIN, "{tracking:?}: D = {ks:.5}, p = {p:.2e}");
        match tracking {
            Tracking::Analytic => assert_eq!(nulls, 0, "analytic segments make no null collisions"),
            Tracking::Delta { .. } => assert!(nulls > 0),
        }
    }
}

#[test]
fn collisions_report_the_medium_they_happen_in() {
    let scene = piecewise_scene();
    let mut rng = PathRng::new(3, Purpose::Test, 0, 0);
    let mut nulls = 0;
    for tracking in [Tracking::Analytic, Tracking::Delta { majorant_scale: 2.0 }] {
        for _ in 0..20_000 {
            if let Flight::Collision { t, medium } = free_flight(
                LayerRay { scene: &scene, layer: &scene.layers[0], pos: DVec3::ZERO, dir: DVec3::Z },
                f64::INFINITY,
                1.0,
                tracking,
                &mut rng,
                &mut nulls,
            ) {
                let inside_sphere = (1.0e-3..=2.0e-3).contains(&t);
                assert_eq!(medium == 1, inside_sphere, "{tracking:?}: t = {t}, medium {medium}");
                assert_ne!(medium, 2, "no collision in a void");
            }
        }
    }
}
