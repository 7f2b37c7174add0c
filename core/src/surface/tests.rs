use super::*;
use crate::sampling::{PathRng, Purpose};

fn dir(theta_deg: f64, phi_deg: f64) -> DVec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// Copper at 1550 nm (Johnson & Christy 1972).
fn copper() -> Complex64 {
    metals::Metal::Copper.index(1.55e-6).unwrap()
}

/// `∫ g(ω) dω` over the sphere (`lower`: both hemispheres, else the upper one) by a midpoint
/// rule in (cos θ, φ) refined towards the poles (u² warps), where the lobes of smooth surfaces
/// peak.
fn integrate(lower: bool, mut g: impl FnMut(DVec3) -> f64) -> f64 {
    let (nt, np) = (3000, 360);
    let mut sum = 0.0;
    for hemi in if lower { vec![1.0, -1.0] } else { vec![1.0] } {
        for i in 0..nt {
            let u = (i as f64 + 0.5) / nt as f64;
            // cos θ = 1 − u² near the pole, with its Jacobian 2u.
            let c = 1.0 - u * u;
            let dc = 2.0 * u / nt as f64;
            let s = (1.0 - c * c).max(0.0).sqrt();
            for j in 0..np {
                let phi = std::f64::consts::TAU * (j as f64 + 0.5) / np as f64;
                let w = DVec3::new(s * phi.cos(), s * phi.sin(), hemi * c);
                sum += g(w) * dc * std::f64::consts::TAU / np as f64;
            }
        }
    }
    sum
}

/// The mean and standard error of the weights of `n` draws (0 for a draw that fails).
fn mean_weight(n: usize, rng: &mut PathRng, mut draw: impl FnMut([f64; 3]) -> f64) -> (f64, f64) {
    let (mut s, mut s2) = (0.0, 0.0);
    for _ in 0..n {
        let w = draw([rng.uniform(), rng.uniform(), rng.uniform()]);
        s += w;
        s2 += w * w;
    }
    let m = s / n as f64;
    (m, ((s2 / n as f64 - m * m).max(0.0) / n as f64).sqrt())
}

#[test]
fn conductor_fresnel_is_the_dielectric_one_without_absorption_and_the_textbook_one_at_normal_incidence() {
    for cos_i in [1.0, 0.9, 0.5, 0.1, 0.0] {
        let want = fresnel::reflectance(1.0, 1.5, cos_i).0;
        let got = conductor_reflectance(Complex64::new(1.5, 0.0), cos_i);
        assert!((got - want).abs() < 1e-14, "cos {cos_i}: {got} vs {want}");
    }
    // R(0) = ((n − 1)² + k²)/((n + 1)² + k²); grazing incidence reflects everything.
    let eta = copper();
    let want = ((eta.re - 1.0).powi(2) + eta.im.powi(2)) / ((eta.re + 1.0).powi(2) + eta.im.powi(2));
    assert!((conductor_reflectance(eta, 1.0) - want).abs() < 1e-14);
    assert!((conductor_reflectance(eta, 0.0) - 1.0).abs() < 1e-12);
    // A metal's reflectance dips towards the principal angle, then rises to 1.
    assert!(conductor_reflectance(eta, 0.2) < conductor_reflectance(eta, 1.0));
}

/// Each sampled direction's weight is `eval/pdf` (the walk's forward draws and the shadow rays'
/// densities are of one model), and every weight is finite and ≥ 0.
#[test]
fn sampled_weights_are_eval_over_pdf() {
    let mut rng = PathRng::new(3, Purpose::Test, 0, 0);
    let bsdfs = [
        Bsdf::Lambertian { albedo: 0.7 },
        Bsdf::Conductor { alpha: 0.05, eta: copper() },
        Bsdf::Conductor { alpha: 0.4, eta: copper() },
        Bsdf::Conductor { alpha: 1.0, eta: Complex64::new(1.5, 0.0) },
    ];
    for b in &bsdfs {
        for theta in [0.0, 40.0, 85.0] {
            let wi = dir(theta, 30.0);
            for _ in 0..2000 {
                let Some(s) = b.sample(wi, [rng.uniform(), rng.uniform(), rng.uniform()]) else { continue };
                assert!(s.weight.is_finite() && s.weight >= 0.0 && s.wo.z > 0.0 && !s.delta);
                let (f, p) = (b.eval(wi, s.wo), b.pdf(wi, s.wo));
                assert!(
                    (s.weight - f / p).abs() <= 1e-9 * s.weight.max(1e-300),
                    "{b:?} θ {theta}: {} vs {}",
                    s.weight,
                    f / p
                );
            }
        }
    }
    for (alpha, n_i, n_t) in [(0.1, 1.0, 1.5), (0.5, 1.5, 1.0), (0.9, 1.33, 1.0)] {
        let d = RoughDielectric { alpha };
        for theta in [0.0, 50.0, 80.0] {
            let wi = dir(theta, 0.0);
            for _ in 0..2000 {
                let Some(c) = d.sample(wi, n_i, n_t, [rng.uniform(), rng.uniform(), rng.uniform()]) else { continue };
                assert_eq!(c.transmitted, c.wo.z < 0.0);
                let (f, p) = (d.eval(wi, c.wo, n_i, n_t), d.pdf(wi, c.wo, n_i, n_t));
                assert!((c.weight - f / p).abs() <= 1e-9 * c.weight, "α {alpha} θ {theta}: {} vs {}", c.weight, f / p);
            }
        }
    }
}

/// The albedo `∫ f |cos θo| dωo` by quadrature of `eval` equals the mean sampled weight within
/// 4σ: `sample` and `eval` describe the same lobe. For a Lambertian surface it is the albedo; a
/// rough surface's falls short of its Fresnel reflectance by the masked share (single scattering).
#[test]
fn albedo_by_quadrature_is_the_mean_sampled_weight() {
    let mut rng = PathRng::new(5, Purpose::Test, 0, 0);
    let n = 400_000;
    let perfect = Complex64::new(1e-9, 1e9); // |r| = 1 at every incidence: the masking loss alone
    let cases = [
        (Bsdf::Lambertian { albedo: 0.7 }, 0.0),
        (Bsdf::Conductor { alpha: 0.1, eta: copper() }, 30.0),
        (Bsdf::Conductor { alpha: 0.5, eta: copper() }, 70.0),
        (Bsdf::Conductor { alpha: 0.5, eta: perfect }, 0.0),
        (Bsdf::Conductor { alpha: 1.0, eta: perfect }, 60.0),
        (
            Bsdf::Mixture(vec![
                (0.3, Bsdf::Lambertian { albedo: 0.5 }),
                (0.7, Bsdf::Conductor { alpha: 0.2, eta: copper() }),
            ]),
            45.0,
        ),
    ];
    for (b, theta) in &cases {
        let wi = dir(*theta, 0.0);
        let quad = integrate(false, |wo| b.eval(wi, wo));
        let (m, se) = mean_weight(n, &mut rng, |u| b.sample(wi, u).map_or(0.0, |s| s.weight));
        assert!((quad - m).abs() < 4.0 * se + 2e-3 * quad, "{b:?} at {theta}°: quadrature {quad}, sampled {m} ± {se}");
        if let Bsdf::Lambertian { albedo } = b {
            assert!((quad - albedo).abs() < 1e-3 && se < 1e-12, "Lambertian albedo {quad}, σ {se}");
        }
    }
    // A perfect reflector loses what its microfacets send below the horizon or mask, which grows
    // with the roughness (single scattering; Heitz et al. 2016). At normal incidence the normals
    // steeper than 45° alone reflect below the horizon: P(tan θm > 1) = α²/(1 + α²) of GGX's
    // projected normals, so the albedo is below 1/(1 + α²) (0.8 at α = 0.5, 0.5 at α = 1).
    let albedo = |alpha: f64| {
        let b = Bsdf::Conductor { alpha, eta: perfect };
        integrate(false, |wo| b.eval(DVec3::Z, wo))
    };
    let e = [albedo(0.02), albedo(0.2), albedo(0.5), albedo(1.0)];
    assert!(e[0] > 0.995 && e[0] < 1.0 + 2e-3, "α = 0.02: {}", e[0]);
    assert!(e.windows(2).all(|w| w[1] < w[0]), "albedos {e:?}");
    for (a, alpha) in e.iter().zip([0.02, 0.2, 0.5, 1.0]) {
        assert!(*a < 1.0 / (1.0 + alpha * alpha) + 2e-3, "α = {alpha}: albedo {a}");
    }
}

/// The rough dielectric's reflected and transmitted power, by quadrature of `eval` over both
/// hemispheres, is the mean sampled weight within 4σ; without absorption the two add up to 1
/// less the masked share, which vanishes as α → 0, where the reflected share is Fresnel's.
#[test]
fn rough_dielectric_conserves_energy_but_for_the_masked_share() {
    let mut rng = PathRng::new(9, Purpose::Test, 0, 0);
    for (alpha, n_i, n_t, theta) in [(0.3, 1.0, 1.5, 30.0), (0.6, 1.5, 1.0, 20.0), (0.1, 1.33, 1.0, 60.0)] {
        let d = RoughDielectric { alpha };
        let wi = dir(theta, 0.0);
        let refl = integrate(false, |wo| d.eval(wi, wo, n_i, n_t));
        let total = integrate(true, |wo| d.eval(wi, wo, n_i, n_t));
        let (m, se) = mean_weight(300_000, &mut rng, |u| d.sample(wi, n_i, n_t, u).map_or(0.0, |c| c.weight));
        let (mr, ser) = mean_weight(300_000, &mut rng, |u| {
            d.sample(wi, n_i, n_t, u).map_or(0.0, |c| if c.transmitted { 0.0 } else { c.weight })
        });
        assert!((total - m).abs() < 4.0 * se + 3e-3, "α {alpha}: R+T by quadrature {total}, sampled {m} ± {se}");
        assert!((refl - mr).abs() < 4.0 * ser + 3e-3, "α {alpha}: R by quadrature {refl}, sampled {mr} ± {ser}");
        assert!(m <= 1.0 + 4.0 * se, "α {alpha}: R + T = {m}");
    }
    // The masked share vanishes with the roughness (here from inside glass towards air, where the
    // refracted light leaves near grazing: 34 % lost at α = 0.6).
    let mut loss = |alpha: f64| {
        let d = RoughDielectric { alpha };
        1.0 - mean_weight(100_000, &mut rng, |u| d.sample(dir(20.0, 0.0), 1.5, 1.0, u).map_or(0.0, |c| c.weight)).0
    };
    let l = [loss(0.01), loss(0.1), loss(0.6)];
    assert!(l[0].abs() < 2e-3 && l[0] < l[1] && l[1] < l[2], "losses {l:?}");
    // α → 0: the smooth interface (reflectance and Snell's direction).
    let d = RoughDielectric { alpha: 1e-5 };
    let wi = dir(40.0, 0.0);
    let (r, cos_t) = fresnel::reflectance(1.0, 1.5, wi.z);
    let smooth_t = -fresnel::refract(-wi, 1.0, 1.5, cos_t);
    let (n, mut reflected, mut off) = (200_000, 0usize, Vec::new());
    for _ in 0..n {
        let c = d.sample(wi, 1.0, 1.5, [rng.uniform(), rng.uniform(), rng.uniform()]).expect("smooth: never masked");
        if c.transmitted {
            off.push((c.wo + smooth_t).length());
        } else {
            reflected += 1;
            off.push((c.wo - DVec3::new(-wi.x, -wi.y, wi.z)).length());
        }
    }
    off.sort_by(f64::total_cmp);
    let p = reflected as f64 / n as f64;
    let se = (r * (1.0 - r) / n as f64).sqrt();
    assert!((p - r).abs() < 4.0 * se, "reflected share {p}, Fresnel {r} (σ {se})");
    // GGX's normals tilt by tan θm ≈ α·√(u/(1 − u)): a median of α, a long tail.
    let (median, worst) = (off[n / 2], off[n - 1]);
    assert!(
        median < 3e-5 && worst < 0.05,
        "directions off the smooth interface's by {median} (median), {worst} (worst)"
    );
}

/// A conductor's BRDF is reciprocal: `f(wi, wo) = f(wo, wi)`.
#[test]
fn conductor_brdf_is_reciprocal() {
    let b = Bsdf::Conductor { alpha: 0.3, eta: copper() };
    for (a, c) in [(dir(10.0, 0.0), dir(60.0, 120.0)), (dir(75.0, 10.0), dir(30.0, 200.0))] {
        let f_ac = b.eval(a, c) / c.z;
        let f_ca = b.eval(c, a) / a.z;
        assert!((f_ac - f_ca).abs() < 1e-12 * f_ac, "{f_ac} vs {f_ca}");
    }
}

#[test]
fn a_smooth_mirror_is_a_dirac_lobe_with_fresnels_weight() {
    let b = Bsdf::Conductor { alpha: 0.0, eta: copper() };
    let wi = dir(35.0, 70.0);
    let s = b.sample(wi, [0.3, 0.6, 0.1]).unwrap();
    assert!(s.delta && (s.wo - DVec3::new(-wi.x, -wi.y, wi.z)).length() < 1e-15);
    assert_eq!(s.weight, conductor_reflectance(copper(), wi.z));
    assert_eq!((b.eval(wi, s.wo), b.pdf(wi, s.wo)), (0.0, 0.0));
    assert!(!b.has_continuous_part());
}

#[test]
fn frames_are_orthonormal_and_invert() {
    for n in [DVec3::Z, -DVec3::Z, DVec3::new(0.3, -0.4, 0.866).normalize()] {
        let f = Frame::new(n);
        let w = DVec3::new(0.2, 0.5, -0.7).normalize();
        assert!((f.to_world(f.to_local(w)) - w).length() < 1e-14);
        assert!((f.to_local(n) - DVec3::Z).length() < 1e-14);
    }
}

/// The conductor's Fresnel reflectance over the whole accepted range of `n` and `k` (1e-3 … 1e4,
/// 0 … 1e4, in media of index 1 … 10): finite, in [0, 1], and equal to the textbook's real form
/// (Born & Wolf §14.2: `a²`, `b²` from `n² − k² − sin²θ` and `4n²k²`) to 10⁻⁹.
#[test]
fn conductor_fresnel_is_exact_over_the_accepted_indices() {
    let reference = |n: f64, k: f64, c: f64| {
        let s2 = 1.0 - c * c;
        let d = n * n - k * k - s2;
        let root = (d * d + 4.0 * n * n * k * k).sqrt();
        // (root ± d)/2 without cancellation: their product is n²k².
        let nk2 = n * n * k * k;
        let (a2, b2) = if d >= 0.0 {
            (0.5 * (root + d), 2.0 * nk2 / (root + d))
        } else {
            (2.0 * nk2 / (root - d), 0.5 * (root - d))
        };
        let a = a2.sqrt();
        let rs = (a2 + b2 - 2.0 * a * c + c * c) / (a2 + b2 + 2.0 * a * c + c * c);
        let st = s2 / c; // sin θ tan θ
        let rp = rs * (a2 + b2 - 2.0 * a * st + st * st) / (a2 + b2 + 2.0 * a * st + st * st);
        0.5 * (rs + rp)
    };
    for n in [1e-3, 0.05, 1.0, 30.0, 1e4] {
        for k in [0.0, 1e-3, 1.0, 100.0, 1e4] {
            for n_medium in [1.0, 1.33, 10.0] {
                let eta = Complex64::new(n, k) / n_medium;
                for c in [1.0, 0.9, 0.5, 0.1, 1e-3, 1e-8] {
                    let r = conductor_reflectance(eta, c);
                    let want = reference(eta.re, eta.im, c);
                    assert!(
                        r.is_finite() && (0.0..=1.0).contains(&r),
                        "n = {n}, k = {k}, medium {n_medium}, cos {c}: R = {r}"
                    );
                    assert!(
                        (r - want).abs() < 1e-9,
                        "n = {n}, k = {k}, medium {n_medium}, cos {c}: R = {r}, textbook {want}"
                    );
                }
            }
        }
    }
}
