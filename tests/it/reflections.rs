//! Deterministic unscattered reflections (`run.reflections`, `transport::forward`'s
//! `unscattered_reflections`): the laser's reflections at the interfaces below the surface are
//! scored into the forward detectors from each path, and the walk's own unscattered
//! once-reflected escapes are left out of them. The detectors' expectations are unchanged (the
//! sampled reflections agree within σ), the closed form of a clear stack is met with no variance
//! of its own, and the scalar tallies stay the walk's.

use ohd::detect::Scalar;

use ohd::transport::policy::reflection_second_moment;

use crate::support::run::{Run, experiment, run};
use crate::support::scenes;
use crate::support::stats::chi2_difference;

/// Normal-incidence Fresnel reflectance between indices `a` and `b`.
fn fresnel(a: f64, b: f64) -> f64 {
    ((a - b) / (a + b)).powi(2)
}

/// Under air, a 300 µm layer of n = 1.37 over a 500 µm layer of n = 1.45 over water (n = 1.33),
/// both of medium "tissue" (σa 0.1 /mm, σs `sigma_s` /mm, HG g = 0.9), lit by a pencil (or the
/// source keys that follow) and seen by an 8 × 8 camera of 1 mm at 20° with a spectrum, without
/// the specular reflection at the surface.
fn stack(sigma_s: f64, samples: u64, reflections: &str) -> String {
    let body = format!(
        r#"[source]
wavelength_nm = 785
position_mm = [0, 0, -1]
[ambient]
n_above = 1.0
n_below = 1.33
[media.tissue]
sigma_a_per_mm = 0.1
sigma_s_per_mm = {sigma_s}
phase = {{ type = "hg", g = 0.9 }}
[[layers]]
thickness_um = 300
n = 1.37
medium = "tissue"
[[layers]]
thickness_um = 500
n = 1.45
medium = "tissue"
"#
    );
    let spectrum = "[detectors.spectrum]\nf_min_khz = -30\nf_max_khz = 30\nbins = 8\n";
    let header = scenes::header(samples, 11, 32);
    format!("{header}reflections = \"{reflections}\"\n{body}{}{spectrum}", scenes::camera(1.0, 20.0, 8))
}

/// The camera's image: values and standard errors.
fn image(r: &Run) -> (Vec<f64>, Vec<f64>) {
    let o = r.exp.outputs().into_iter().find(|o| o.name == "camera.image").expect("an image");
    o.values(r.out.estimates.mean(), &r.out.estimates.stderr())
}

/// A clear stack: every path's detected light is its two single reflections (and, rarely, light
/// reflected three times or more, `R²·R_top ≲ 10⁻⁸`), so the deterministic estimate is the closed
/// form `T0²·(R12·A1 + T12²·A1·A2·R2w)` with no spread between batches, and the sampled one
/// meets it within its σ. The scalar tallies are the walk's in both.
#[test]
fn a_clear_stack_reflects_the_closed_form() {
    let (t0, r12, r2w) = (1.0 - fresnel(1.0, 1.37), fresnel(1.37, 1.45), fresnel(1.45, 1.33));
    let (a1, a2) = ((-2.0 * 0.1 * 0.3f64).exp(), (-2.0 * 0.1 * 0.5f64).exp());
    let expected = t0 * t0 * (r12 * a1 + (1.0 - r12).powi(2) * a1 * a2 * r2w);
    let det = run(&stack(0.0, 200_000, "deterministic"), &[]);
    let (p, se) = det.power(0);
    assert!(
        (p - expected).abs() < 1e-7 * expected + 4.0 * se && se < 1e-6 * expected,
        "deterministic: {p:.9e} ± {se:.1e} against {expected:.9e}"
    );
    let sampled = run(&stack(0.0, 200_000, "sampled"), &[]);
    let (q, sq) = sampled.power(0);
    let z = (q - expected) / sq;
    assert!(z.abs() < 4.0, "sampled: {q:.6e} ± {sq:.1e} against {expected:.6e} (z = {z:.2})");
    assert!(sq > 0.02 * expected, "the sampled reflections should scatter between batches: σ = {sq:.2e}");
    for s in Scalar::ALL {
        assert_eq!(det.scalar(s), sampled.scalar(s), "{} differs", s.name());
    }
    // What `auto` weighs: the sampled reflections' second moment per path, the probability
    // `T0·Σ T²·R·e^{−2τ}` times the squared weight `T0²` (here ~10⁻³: deterministic), and under a
    // scattering top layer (σs 15 /mm, 0.3 mm: e^{−9} less) far below the threshold (sampled).
    let moment = t0 * expected;
    let exp = &det.exp;
    let m = reflection_second_moment(&exp.scene, &exp.source);
    assert!((m - moment).abs() < 1e-12 * moment, "second moment {m:e}, closed form {moment:e}");
    let auto = |sigma_s: f64| {
        let e = experiment(&stack(sigma_s, 1000, "auto"), &[]);
        ohd::transport::policy::deterministic_reflections(&e.scene, &e.source, &e.plan.walk, &e.detectors)
    };
    assert!(auto(0.0) && !auto(15.0), "auto: clear {}, scattering {}", auto(0.0), auto(15.0));
}

/// A scattering stack under a flat-top beam, its scatterers moving at random (5 mm/s per
/// component, so that the diffuse light spreads over the spectrum's bins and the reflections stay
/// in the bin of 0 Hz): deterministic and sampled reflections give the same detected power, image
/// and spectrum within their standard errors. The two runs draw on different seeds, so their
/// errors are independent: 64 pixels and 8 bins of differences (on one seed the diffuse light was
/// the same paths in both and the image gave χ² 1.5 over 64; the static spectrum filled one bin).
/// Measured: image χ² 23.9 over 64, spectrum 5.7 over 8. The pixels' errors are correlated (two
/// seeds of the same mode gave 23 and 26 over 64, the pixels' differences mostly of one sign), so
/// the image's χ² is conservative here. The reflections are `T0²(R12·A1 + T12²·A1·A2·R2w) ≈
/// 2.8·10⁻⁴` of the beam, 3.9 times the power's combined σ (7.2·10⁻⁵: the diffuse light carries
/// most of the variance).
#[test]
fn deterministic_reflections_agree_with_sampled_ones() {
    let go = |mode: &str, seed: &str| {
        let text = stack(2.0, 400_000, mode);
        run(
            &text,
            &["source.profile=\"disk\"", "source.radius_mm=0.3", "media.tissue.motion={dispersion_mm_per_s=5}", seed],
        )
    };
    let (det, sampled) = (go("deterministic", "run.seed=11"), go("sampled", "run.seed=12"));
    let (a, b) = (det.power(0), sampled.power(0));
    let z = (a.0 - b.0) / a.1.hypot(b.1);
    assert!(z.abs() < 4.0, "power: deterministic {a:?}, sampled {b:?} (z = {z:.2})");
    let (a_image, b_image) = (image(&det), image(&sampled));
    let (stat, dof, p) = chi2_difference((&a_image.0, &a_image.1), (&b_image.0, &b_image.1));
    assert!(dof == 64 && p > 1e-4, "image: χ² = {stat:.1} over {dof} pixels (p = {p:.2e})");
    let (ca, cb) = (det.channel(0, 0, 0), sampled.channel(0, 0, 0));
    let (stat, dof, p) = chi2_difference((&ca.values, &ca.stderr), (&cb.values, &cb.stderr));
    assert!(dof == 8 && p > 1e-4, "spectrum: χ² = {stat:.1} over {dof} bins (p = {p:.2e})");
}

/// `N` clear layers of 1 µm (σa 0.1 /mm) alternating n = 1.40 and 1.41 over water under the
/// camera of [`stack`]: `N` interfaces of `R ≈ 1.3·10⁻⁵` and a last one of `8.5·10⁻⁴`, few enough
/// reflected light that light reflected three times or more is ≲ 10⁻⁶ of the detected power.
fn many_interfaces(n: usize, samples: u64, reflections: &str) -> String {
    let mut body = String::from(
        "[source]\nwavelength_nm = 785\nposition_mm = [0, 0, -1]\n[ambient]\nn_above = 1.0\nn_below = 1.33\n\
         [media.clear]\nsigma_a_per_mm = 0.1\nsigma_s_per_mm = 0\nphase = { type = \"hg\", g = 0.9 }\n",
    );
    for j in 0..n {
        body += &format!(
            "[[layers]]\nthickness_um = 1\nn = {}\nmedium = \"clear\"\n",
            if j % 2 == 0 { 1.40 } else { 1.41 }
        );
    }
    let header = scenes::header(samples, 11, 16);
    format!("{header}reflections = \"{reflections}\"\n{body}{}", scenes::camera(1.0, 20.0, 8))
}

/// Issue 52: the way up from each of `N` interfaces was traced layer by layer, `N²/2` crossings
/// per path (1,000 interfaces: 17–37 s a run). Through a stack of homogeneous layers the
/// deterministic reflections now take `2N` steps per path (counted: `N` layers down, one summed
/// run up per interface), and at 1,000 interfaces they still meet the closed form
/// `T0²·Σ_j Π_{k<j}(1 − R_k)²·R_j·e^{−2τ_j}` (normal incidence).
#[test]
fn a_thousand_interfaces_cost_linear_steps_and_meet_the_closed_form() {
    let n = 1000;
    let paths = 256;
    let r = run(&many_interfaces(n, paths, "deterministic"), &[]);
    let steps = r.out.stats.work.reflection_steps;
    assert_eq!(steps, 2 * n as u64 * paths, "steps of the reflections' ways ({} per path)", steps / paths);
    let index = |j: usize| {
        if j == n {
            1.33
        } else if j % 2 == 0 {
            1.40
        } else {
            1.41
        }
    };
    let t0 = 1.0 - fresnel(1.0, 1.40);
    let (mut expected, mut through) = (0.0, 1.0);
    for j in 0..n {
        let rj = fresnel(index(j), index(j + 1));
        let tau = 0.1 * 1e-3 * (j + 1) as f64;
        expected += t0 * t0 * through * through * rj * (-2.0 * tau).exp();
        through *= 1.0 - rj;
    }
    let (p, se) = r.power(0);
    assert!(
        (p - expected).abs() < 1e-6 * expected + 4.0 * se,
        "deterministic: {p:.9e} ± {se:.1e} against {expected:.9e}"
    );
}
