//! Stiff and extreme cases (issue 7): each test drives one parameter to an extreme and checks the
//! physical limit it must reach, the finiteness of every output and that the run ends. The
//! derivations are in the comments here and in `validation/stiff/README.md`. Seeds are fixed;
//! tolerances are in standard errors of the estimate (4σ), or exact where the limit is
//! deterministic path by path.

use crate::support::run::{Channel, Run, roi_channel, roi_m0, run};
use crate::support::stats::assert_within_sigma;
use ohd::numeric::simpson;

use std::time::Instant;

use ohd::detect::Scalar;
use ohd::phase::HenyeyGreenstein;
use ohd::sampling::{PathRng, Purpose};

/// Speed of light, m/s.
const C: f64 = 299_792_458.0;

/// A pencil beam at normal incidence from z = 0 into the stack, λ0 = 1 µm, index 1 above and
/// below, 2·10⁵ paths in 16 batches; the media, layers and detectors follow.
const HEAD: &str = r#"
schema_version = 1
[run]
samples = 200000
seed = 7
batches = 16
[source]
wavelength_nm = 1000
profile = "pencil"
position_mm = [0, 0, 0]
direction = [0, 0, 1]
[ambient]
n_above = 1.0
n_below = 1.0
"#;

fn scene(rest: &str) -> String {
    format!("{HEAD}{rest}")
}

/// Every estimate and standard error is finite and no detection was non-finite.
fn assert_finite(r: &Run, what: &str) {
    let m = r.out.estimates.mean();
    let se = r.out.estimates.stderr();
    assert!(m.iter().all(|v| v.is_finite()), "{what}: a non-finite estimate");
    assert!(se.iter().all(|v| v.is_finite() && *v >= 0.0), "{what}: a non-finite standard error");
    assert_eq!(r.out.stats.non_finite, 0, "{what}: non-finite detections");
    eprintln!("{what}: {:?}, {:.2} s", r.out.stats, r.out.wall_seconds);
}

/// z of the difference of two independent estimates.
fn z_diff(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0) / (a.1 * a.1 + b.1 * b.1).sqrt()
}

fn report(what: &str, (v, se): (f64, f64), reference: f64) {
    eprintln!("{what}: {v:.6} ± {se:.2e} vs {reference:.6} (z = {:+.2})", (v - reference) / se);
}

// ---------------------------------------------------------------------------------------------
// g = ±0.999999

#[test]
fn hg_sampling_g_pm_0_999999() {
    // Sampling: ⟨cos θ⟩ = g. (1) Monte Carlo over 4·10⁶ draws, within 4 sample standard errors
    // (σ(cos θ)² = (1 − g²)/3 − … ≈ 6.7e-7, so the error is 4e-7: it separates g = 0.999999 from
    // 1). (2) The inverse CDF integrated over u ∈ [0, 1] (substitution u = eᵗ, 4·10⁵ trapezoids
    // in t, Simpson, which resolves the step of width (1 − |g|)/2|g| ≈ 5e-7 at u = 0) gives ⟨cos θ⟩ = g to
    // 1e-12, and ⟨1 − cos θ⟩ = 1 − g = 1e-6 to 1e-6 relative for g > 0: no cancellation.
    for g in [0.999_999, -0.999_999] {
        let p = HenyeyGreenstein::new(g).unwrap();
        let mut rng = PathRng::new(5, Purpose::Test, 0, 0);
        let n = 4_000_000;
        let (mut s1, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let d = p.sample(rng.uniform());
            assert!(d.cos.is_finite() && d.sin.is_finite() && (-1.0..=1.0).contains(&d.cos));
            s1 += d.cos;
            s2 += d.cos * d.cos;
        }
        let nf = n as f64;
        let mean = s1 / nf;
        let se = ((s2 / nf - mean * mean) / (nf - 1.0)).sqrt();
        report(&format!("HG g = {g}: ⟨cos θ⟩ (MC)"), (mean, se), g);
        assert_within_sigma("⟨cos θ⟩", mean, se, g, 4.0);

        // Simpson's rule in t = ln u on [−80, 0] (the rest of [0, 1] weighs < e^{−80}).
        let sample = |t: f64| p.sample(t.exp().min(1.0 - f64::EPSILON));
        let cos_int = simpson(|t| sample(t).cos * t.exp(), -80.0, 0.0, 400_000);
        let m_int = simpson(|t| sample(t).one_minus_cos * t.exp(), -80.0, 0.0, 400_000);
        eprintln!("HG g = {g}: ∫cos = {cos_int:.12}, ∫(1 − cos) = {m_int:.6e}");
        assert!((cos_int - g).abs() < 1e-12, "∫ cos θ du = {cos_int} vs g = {g}");
        if g > 0.0 {
            assert!(((m_int - (1.0 - g)) / (1.0 - g)).abs() < 1e-6, "∫ (1 − cos θ) du = {m_int:e}");
        }
    }
}

#[test]
fn hg_g_plus_0_999999() {
    // A 1 cm slab, σs = 1000 /m (τs = 10), σa = 20 /m (τa = 0.2), g = +0.999999, matched. As
    // g → 1 scattering does not change the direction (σs(1 − g)L = 1e-5 ≪ 1): the slab is a pure
    // absorber, T → e^{−σa L} and R → 0. Absorption weighting gives each path e^{−σa ℓ}
    // with ℓ ≈ L (the excess path is of order τs(1 − g)L). Measured: total transmittance and the
    // power into a 5° cone below (the multiple-scattering halo beyond 5° holds ~1e-4 of it);
    // reflectance R ≈ τs·P(deflection > 90°)·e^{−τa} ≈ 2e-6 (about 0.4 of the 2·10⁵ paths), asserted
    // below 1e-4 (25 paths: the Poisson tail is ~1e-40; with the wrong sign of g R would be ~1/2,
    // with g = 0.99 ~1e-3); and R + T + A = 1 path by path (no roulette above the 1e-4 threshold).
    let r = run(
        &scene(
            r#"
[media.m]
sigma_s_per_m = 1000
sigma_a_per_m = 20
phase = { type = "hg", g = 0.999999 }
[[layers]]
thickness_mm = 10
n = 1.0
medium = "m"
[[detectors]]
name = "cone"
side = "bottom"
acceptance_half_angle_deg = 5
"#,
        ),
        &[],
    );
    assert_finite(&r, "g = +0.999999");
    let want = (-0.2f64).exp();
    report("T total", r.scalar(Scalar::TransmittanceTotal), want);
    report("T into 5°", r.power(0), want);
    let (t, se) = r.scalar(Scalar::TransmittanceTotal);
    assert_within_sigma("T total", t, se, want, 4.0);
    let (tc, se) = r.power(0);
    assert_within_sigma("T into a 5° cone", tc, se, want, 4.0);
    let hg = HenyeyGreenstein::new(0.999_999).unwrap();
    let p_back = 1.0 - hg.cdf_one_minus_cos(1.0);
    let (rd, _) = r.scalar(Scalar::ReflectanceDiffuse);
    eprintln!("R diffuse = {rd:.3e}, P(back) = {p_back:.3e}");
    assert!(rd < 1e-4, "R diffuse {rd:e} (τs·P(back) = {:e})", 10.0 * p_back);
    let total = rd + t + r.scalar(Scalar::AbsorbedFraction).0;
    assert!((total - 1.0).abs() < 1e-9, "R + T + A = {total}");
    assert_eq!(r.out.stats.truncated_paths, 0);
}

#[test]
fn hg_g_minus_0_999999() {
    // g = −0.999999, σa = 0, τs = σs L = 1, matched: every scattering reverses the direction
    // (up to (1 + cos θ) ~ 1e-6). This is the rod model with certain reversal: the fluxes obey
    // dI₊/dz = −σ(I₊ − I₋) = −σT (the net flux T = I₊ − I₋ is constant), so with I₊(0) = 1 and
    // I₋(L) = 0: T = 1/(1 + τ) = 1/2, R = τ/(1 + τ) = 1/2.
    let r = run(
        &scene(
            r#"
[media.m]
sigma_s_per_m = 1000
sigma_a_per_m = 0
phase = { type = "hg", g = -0.999999 }
[[layers]]
thickness_mm = 1
n = 1.0
medium = "m"
"#,
        ),
        &[],
    );
    assert_finite(&r, "g = −0.999999");
    report("T", r.scalar(Scalar::TransmittanceTotal), 0.5);
    report("R", r.scalar(Scalar::ReflectanceDiffuse), 0.5);
    let (t, se) = r.scalar(Scalar::TransmittanceTotal);
    assert_within_sigma("T = 1/(1 + τ)", t, se, 0.5, 4.0);
    let (rd, se) = r.scalar(Scalar::ReflectanceDiffuse);
    assert_within_sigma("R = τ/(1 + τ)", rd, se, 0.5, 4.0);
    assert!((rd + t - 1.0).abs() < 1e-12 && r.scalar(Scalar::AbsorbedFraction).0 == 0.0);
}

// ---------------------------------------------------------------------------------------------
// σt = 1e-9 and 1e9 per metre

#[test]
fn sigma_t_1e_minus_9_per_m() {
    // A 1 m slab of σs = 1e-9 /m (τ = 1e-9) and n = 1.5 in air: only Fresnel. Specular
    // R0 = ((n − 1)/(n + 1))² = 0.04 exactly; the incoherent sum of internal reflections gives
    // T = (1 − R0)² e^{−τ}/(1 − R0² e^{−2τ}) → (1 − R0)/(1 + R0) = 0.923077 and the rest leaves
    // by the top. Expected scattering events over all paths: 2·10⁵ × ~1e-9 ≈ 2e-4.
    let r = run(
        &scene(
            r#"
[media.m]
sigma_s_per_m = 1e-9
sigma_a_per_m = 0
[[layers]]
thickness_m = 1
n = 1.5
medium = "m"
"#,
        ),
        &[],
    );
    assert_finite(&r, "σt = 1e-9 /m");
    let r0: f64 = 0.04;
    let (rsp, _) = r.scalar(Scalar::ReflectanceSpecular);
    assert!((rsp - r0).abs() < 1e-12, "specular {rsp}");
    let tau = 1e-9f64;
    let t = (1.0 - r0).powi(2) * (-tau).exp() / (1.0 - r0 * r0 * (-2.0 * tau).exp());
    let (tt, se) = r.scalar(Scalar::TransmittanceTotal);
    report("T", (tt, se), t);
    assert_within_sigma("T", tt, se, t, 4.0);
    assert_eq!(tt, r.scalar(Scalar::TransmittanceUnscattered).0, "every transmitted path is unscattered");
    assert!(r.out.stats.scattering_events <= 3, "{} events", r.out.stats.scattering_events);
}

#[test]
fn sigma_t_1e9_per_m() {
    // Similarity: the transport equation depends on σt and L only through τ = σt L (with the
    // albedo and phase function fixed), so a 1 mm slab at σt = 1e9 /m (τ = 1e6) must give the
    // diffuse reflectance of a 1000 m slab at σt = 1e3 /m, and both that of the semi-infinite
    // medium (nothing crosses τ = 1e6: T = 0 exactly). Albedo 0.9, g = 0.8. Independent seeds.
    // The work per path is invariant too: the mean number of events per path agrees.
    let medium = |scale: &str, thick: &str, seed: u64| {
        scene(&format!(
            r#"
[media.m]
sigma_s_per_m = {}
sigma_a_per_m = {}
phase = {{ type = "hg", g = 0.8 }}
[[layers]]
{thick}
n = 1.0
medium = "m"
"#,
            format_args!("0.9e{scale}"),
            format_args!("0.1e{scale}")
        ))
        .replace("seed = 7", &format!("seed = {seed}"))
    };
    let t = Instant::now();
    let stiff = run(&medium("9", "thickness_mm = 1", 1), &["run.samples=100000"]);
    let stiff_s = t.elapsed().as_secs_f64();
    let soft = run(&medium("3", "thickness_m = 1000", 2), &["run.samples=100000"]);
    let semi = run(&medium("3", "thickness_mm = inf", 3), &["run.samples=100000"]);
    for (what, r) in [("σt = 1e9 /m", &stiff), ("σt = 1e3 /m", &soft), ("semi-infinite", &semi)] {
        assert_finite(r, what);
        assert_eq!(r.scalar(Scalar::TransmittanceTotal).0, 0.0, "{what}: T");
        assert_eq!(r.out.stats.truncated_paths, 0);
    }
    let (a, b, c) = (
        stiff.scalar(Scalar::ReflectanceDiffuse),
        soft.scalar(Scalar::ReflectanceDiffuse),
        semi.scalar(Scalar::ReflectanceDiffuse),
    );
    eprintln!("Rd: σt = 1e9 {a:?}, 1e3 {b:?}, semi-infinite {c:?}; {stiff_s:.2} s");
    assert!(z_diff(a, b).abs() < 4.0, "Rd 1e9 vs 1e3: z = {:.2}", z_diff(a, b));
    assert!(z_diff(a, c).abs() < 4.0, "Rd 1e9 vs semi-infinite: z = {:.2}", z_diff(a, c));
    let per_path = |r: &Run| r.out.stats.scattering_events as f64 / r.paths();
    let (ea, eb) = (per_path(&stiff), per_path(&soft));
    eprintln!("events per path: {ea:.2} vs {eb:.2}");
    assert!((ea / eb - 1.0).abs() < 0.05, "events per path {ea} vs {eb}");
}

// ---------------------------------------------------------------------------------------------
// Albedo exactly 1, semi-infinite

#[test]
fn albedo_one_semi_infinite() {
    // σa = 0, σs = 1000 /m, isotropic, semi-infinite, n = 1.33 under air. Physically all light
    // comes back (the depth of a random walk in a half-space is recurrent): R_sp + R_d = 1,
    // A = 0, T = 0. The return time has an infinite mean (first passage ~ n^{−1/2}), so the
    // event cap (here 10⁵) truncates a fraction f_t ~ 1/√(π·10⁵) of the walks; that is the only
    // loss, and it is counted. Roulette: the threshold 0.99 makes every path play once, at its
    // first event, with the entry weight 1 − R0 = 0.97994 < 0.99 (survival 1/2, survivors carry
    // 1.96): unbiased, so R_sp + R_d = 1 − (1 − R0)·f_t/q within the roulette's standard error,
    // with f_t/q the truncated fraction among the survivors. The roulette kills half the paths
    // (binomial, within 4σ).
    let r = run(
        &scene(
            r#"
[media.m]
sigma_s_per_m = 1000
sigma_a_per_m = 0
[[layers]]
thickness_mm = inf
n = 1.33
medium = "m"
"#,
        ),
        &[
            "run.samples=50000",
            "run.max_scattering_events=100000",
            "run.roulette_threshold=0.99",
            "run.roulette_survival=0.5",
        ],
    );
    assert_finite(&r, "albedo 1");
    let n = r.paths();
    let r0 = (0.33f64 / 2.33).powi(2);
    let (rsp, _) = r.scalar(Scalar::ReflectanceSpecular);
    assert!((rsp - r0).abs() < 1e-12);
    assert_eq!(r.scalar(Scalar::AbsorbedFraction).0, 0.0);
    assert_eq!(r.scalar(Scalar::TransmittanceTotal).0, 0.0);
    let killed = r.out.stats.roulette_terminations as f64;
    let sd = (n * 0.25).sqrt();
    eprintln!("roulette: {killed} of {n} (expected {} ± {sd:.0})", n / 2.0);
    assert!((killed - n / 2.0).abs() < 4.0 * sd, "roulette terminations {killed}");
    let f_t = r.out.stats.truncated_paths as f64 / (n - killed);
    eprintln!(
        "truncated fraction of the surviving walks: {f_t:.2e} (1/√(π·10⁵) = {:.2e})",
        1.0 / (std::f64::consts::PI * 1e5).sqrt()
    );
    assert!(f_t < 0.01, "truncated fraction {f_t}");
    let (rd, se) = r.scalar(Scalar::ReflectanceDiffuse);
    let want = 1.0 - (1.0 - r0) * f_t;
    report("R_sp + R_d", (rsp + rd, se), want);
    assert_within_sigma("R_sp + R_d", rsp + rd, se, want, 4.0);
}

// ---------------------------------------------------------------------------------------------
// Zero-density regions

const TURBID: &str = r#"
[media.turbid]
sigma_s_per_mm = 2
sigma_a_per_mm = 0.1
phase = { type = "hg", g = 0.8 }
[media.void]
sigma_s_per_mm = 0
sigma_a_per_mm = 0
"#;

#[test]
fn zero_density_region() {
    // A 2 mm turbid layer holding a box region of σs = σa = 0 over its top millimetre (10 m
    // wide: no path leaves it sideways) is the stack "1 mm void over 1 mm turbid". Compared:
    // R_d and T of the region scene, with analytic segments and with delta tracking (majorant
    // ×2), against the stack, independent seeds, |z| < 4.
    let region = scene(&format!(
        r#"{TURBID}
[[layers]]
name = "slab"
thickness_mm = 2
n = 1.0
medium = "turbid"
[[regions]]
layer = "slab"
medium = "void"
shape = {{ type = "box", center_mm = [0, 0, 0.5], size_mm = [10000, 10000, 1] }}
"#
    ));
    let stack = scene(&format!(
        r#"{TURBID}
[[layers]]
thickness_mm = 1
n = 1.0
medium = "void"
[[layers]]
thickness_mm = 1
n = 1.0
medium = "turbid"
"#
    ));
    let reference = run(&stack, &["run.seed=1"]);
    assert_finite(&reference, "void layer");
    for (what, sets) in [
        ("analytic", vec!["run.seed=2"]),
        ("delta ×2", vec!["run.seed=3", "run.tracking=\"delta\"", "run.majorant_scale=2"]),
    ] {
        let r = run(&region, &sets);
        assert_finite(&r, what);
        for s in [Scalar::ReflectanceDiffuse, Scalar::TransmittanceTotal, Scalar::TransmittanceUnscattered] {
            let z = z_diff(r.scalar(s), reference.scalar(s));
            eprintln!("{what} {}: {:?} vs {:?}, z = {z:+.2}", s.name(), r.scalar(s), reference.scalar(s));
            assert!(z.abs() < 4.0, "{what} {}: z = {z:.2}", s.name());
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Layer thickness 1e-9 m and 1e6 m

const VDH_MEDIUM: &str = r#"
[media.slab]
sigma_a_per_cm = 10
sigma_s_per_cm = 90
phase = { type = "hg", g = 0.75 }
[media.film]
sigma_s_per_m = 10000
sigma_a_per_m = 0
"#;

#[test]
fn layer_thickness_1e_minus_9_m() {
    // (a) van de Hulst's slab (validation-values §1: Rd = 0.09739, Tt = 0.66096, unscattered
    // e^{−2}) between two 1e-9 m films of σs = 1e4 /m (τ = 1e-5 each), all matched: the films
    // are invisible (their effect, ≲ 1e-5, is far below σ).
    let sandwich = scene(&format!(
        r#"{VDH_MEDIUM}
[[layers]]
thickness_m = 1e-9
n = 1.0
medium = "film"
[[layers]]
thickness_mm = 0.2
n = 1.0
medium = "slab"
[[layers]]
thickness_m = 1e-9
n = 1.0
medium = "film"
"#
    ));
    let r = run(&sandwich, &[]);
    assert_finite(&r, "films around the vdH slab");
    for (s, want) in [
        (Scalar::ReflectanceDiffuse, 0.09739),
        (Scalar::TransmittanceTotal, 0.66096),
        (Scalar::TransmittanceUnscattered, (-2.0f64 - 2e-5).exp()),
    ] {
        report(s.name(), r.scalar(s), want);
        let (v, se) = r.scalar(s);
        assert_within_sigma(s.name(), v, se, want, 4.0);
    }
    // (b) A lone 1e-9 m film of n = 1.5 in air: only Fresnel, T = (1 − R0)/(1 + R0) with
    // R0 = 0.04, and the top gets R0 + the rest.
    let film = scene(&format!(
        r#"{VDH_MEDIUM}
[[layers]]
thickness_m = 1e-9
n = 1.5
medium = "film"
"#
    ));
    let r = run(&film, &[]);
    assert_finite(&r, "film alone");
    let r0: f64 = 0.04;
    let (t, se) = r.scalar(Scalar::TransmittanceTotal);
    report("film T", (t, se), (1.0 - r0) / (1.0 + r0));
    assert_within_sigma("film T", t, se, (1.0 - r0) / (1.0 + r0), 4.0);
    let rt = r.scalar(Scalar::ReflectanceSpecular).0 + r.scalar(Scalar::ReflectanceDiffuse).0;
    assert!((rt + t - 1.0).abs() < 1e-12, "R + T = {}", rt + t);
    assert!(r.out.stats.scattering_events <= 3, "{} events in the film", r.out.stats.scattering_events);
}

#[test]
fn layer_thickness_1e6_m() {
    // van de Hulst's medium 1e6 m thick (τ = 1e8) against the same medium with thickness inf:
    // the same diffuse reflectance within 4σ (independent seeds), nothing transmitted.
    let layer = |thick: &str| {
        scene(&format!(
            r#"{VDH_MEDIUM}
[[layers]]
{thick}
n = 1.0
medium = "slab"
"#
        ))
    };
    let deep = run(&layer("thickness_m = 1e6"), &["run.seed=1"]);
    let semi = run(&layer("thickness_mm = inf"), &["run.seed=2"]);
    assert_finite(&deep, "1e6 m");
    assert_finite(&semi, "inf");
    assert_eq!(deep.scalar(Scalar::TransmittanceTotal).0, 0.0);
    let (a, b) = (deep.scalar(Scalar::ReflectanceDiffuse), semi.scalar(Scalar::ReflectanceDiffuse));
    eprintln!("Rd 1e6 m {a:?} vs inf {b:?}: z = {:+.2}", z_diff(a, b));
    assert!(z_diff(a, b).abs() < 4.0);
}

// ---------------------------------------------------------------------------------------------
// Index contrast 1.0 → 3.5

#[test]
fn index_contrast_1_to_3_5() {
    // n = 3.5 in air: R0 = ((3.5 − 1)/4.5)² = 0.308642 at normal incidence, exactly.
    // (a) A pure absorber, τ = 0.1: T = (1 − R0)² e^{−τ}/(1 − R0² e^{−2τ}) and the internally
    // reflected part leaving by the top R0(1 − R0)² e^{−2τ}/(1 − R0² e^{−2τ}) (closed forms,
    // incoherent multiple reflections).
    let r0 = (2.5f64 / 4.5).powi(2);
    let absorber = scene(
        r#"
[media.m]
sigma_s_per_m = 0
sigma_a_per_m = 100
[[layers]]
thickness_mm = 1
n = 3.5
medium = "m"
"#,
    );
    let r = run(&absorber, &["run.roulette_threshold=0"]);
    assert_finite(&r, "n = 3.5 absorber");
    let (rsp, _) = r.scalar(Scalar::ReflectanceSpecular);
    assert!((rsp - 0.308_642).abs() < 1e-6 && (rsp - r0).abs() < 1e-12, "specular {rsp}");
    let e = (-0.1f64).exp();
    let den = 1.0 - r0 * r0 * e * e;
    let (t, se) = r.scalar(Scalar::TransmittanceTotal);
    report("T", (t, se), (1.0 - r0).powi(2) * e / den);
    assert_within_sigma("T", t, se, (1.0 - r0).powi(2) * e / den, 4.0);
    let (rd, se) = r.scalar(Scalar::ReflectanceDiffuse);
    report("R internal", (rd, se), r0 * (1.0 - r0).powi(2) * e * e / den);
    assert_within_sigma("R internal", rd, se, r0 * (1.0 - r0).powi(2) * e * e / den, 4.0);
    // (b) Conservative scattering (σs = 1000 /m, isotropic): light is trapped by total internal
    // reflection outside the 16.6° critical cone and leaves only through it, after many events;
    // every path still ends (no truncation) and R_sp + R_d + T = 1 to rounding, A = 0.
    let r = run(&absorber, &["media.m.sigma_s_per_m=1000", "media.m.sigma_a_per_m=0"]);
    assert_finite(&r, "n = 3.5 conservative");
    assert_eq!(r.out.stats.truncated_paths, 0);
    let total = r.scalar(Scalar::ReflectanceSpecular).0
        + r.scalar(Scalar::ReflectanceDiffuse).0
        + r.scalar(Scalar::TransmittanceTotal).0;
    eprintln!("events per path {:.1}", r.out.stats.scattering_events as f64 / r.paths());
    assert!((total - 1.0).abs() < 1e-12, "R + T = {total}");
    assert_eq!(r.scalar(Scalar::AbsorbedFraction).0, 0.0);
}

// ---------------------------------------------------------------------------------------------
// Velocities and frequency axes. For a uniform translation v of every scatterer in one matched
// medium of index n, the Doppler terms telescope: Σ_k n v·(d_in,k − d_out,k) = n v·(d_0 − d_out),
// so every detected path beats at f = n v·(ẑ − d_out)/λ0 (first order in v/c, the model's
// formula), whatever its order. With v = v ẑ and reflection (d_out·ẑ = −cos θ_exit):
// f = n v (1 + cos θ_exit)/λ0 ∈ [n v/λ0, 2 n v/λ0].

/// A matched 1 mm slab (σs = 1000 /m, σa = 100 /m, g = 0.5) moving at `v` m/s along +z.
fn moving_slab(v: f64, detectors: &str) -> String {
    scene(&format!(
        r#"
[media.m]
sigma_s_per_m = 1000
sigma_a_per_m = 100
phase = {{ type = "hg", g = 0.5 }}
velocity = {{ type = "uniform", velocity_m_per_s = [0, 0, {v:e}] }}
[[layers]]
thickness_mm = 1
n = 1.0
medium = "m"
{detectors}
"#
    ))
}

/// The detector's total spectrum: bins + below + above = detected power (to rounding).
fn assert_conserved(r: &Run, det: usize) -> Channel {
    let ch = r.channel(det, 0, 0);
    let (p, _) = r.power(det);
    let sum: f64 = ch.values.iter().sum::<f64>() + ch.below + ch.above;
    assert!(p > 0.0 && (sum - p).abs() <= 1e-12 * p, "detector {det}: bins + out of range {sum} vs power {p}");
    ch
}

#[test]
fn velocity_zero() {
    // v = 0: every path beats at f = 0, so the DC bin of a symmetric odd axis holds the whole
    // detected power and every other bin and both out-of-range tallies are exactly 0.
    let r = run(
        &moving_slab(
            0.0,
            r#"
[[detectors]]
name = "top"
[detectors.spectrum]
f_min_hz = -1000
f_max_hz = 1000
bins = 21
"#,
        ),
        &["run.samples=50000"],
    );
    assert_finite(&r, "v = 0");
    eprintln!("Doppler term compiled in: {}", r.exp.needs_doppler());
    let ch = assert_conserved(&r, 0);
    let (p, _) = r.power(0);
    assert!((ch.values[10] - p).abs() <= 1e-12 * p);
    assert!(ch.values.iter().enumerate().all(|(k, &v)| k == 10 || v == 0.0));
    assert_eq!((ch.below, ch.above), (0.0, 0.0));
}

#[test]
fn velocity_1e_minus_3_c() {
    // v = 1e-3 c ≈ 3.0e5 m/s along +z, λ0 = 1 µm. A 1° cone about −z sees
    // f ∈ [v(1 + cos 1°)/λ0, 2v/λ0] = [5.99539e11, 5.99585e11] Hz, inside the bin
    // [5.99e11, 6.00e11) of a 1 GHz axis: that bin holds the whole power. A kHz axis on a second
    // detector cannot hold it: its `above` tally does, exactly.
    let v = 1e-3 * C;
    let r = run(
        &moving_slab(
            v,
            r#"
[[detectors]]
name = "narrow"
acceptance_half_angle_deg = 1
[detectors.spectrum]
f_min_ghz = 590
f_max_ghz = 610
bins = 20
[[detectors]]
name = "khz"
[detectors.spectrum]
f_min_khz = -1
f_max_khz = 1
bins = 21
"#,
        ),
        &["run.samples=100000"],
    );
    assert_finite(&r, "v = 1e-3 c");
    let (lo, hi) = (v * (1.0 + 1f64.to_radians().cos()) / 1e-6, 2.0 * v / 1e-6);
    assert!(lo >= 5.99e11 && hi < 6.0e11, "[{lo:e}, {hi:e}]");
    let ch = assert_conserved(&r, 0);
    let (p, _) = r.power(0);
    eprintln!("1° cone power {p:.4e}, bin [599, 600) GHz {:.4e}", ch.values[9]);
    assert!((ch.values[9] - p).abs() <= 1e-12 * p, "peak bin {} vs power {p}", ch.values[9]);
    let ch = assert_conserved(&r, 1);
    let (p, _) = r.power(1);
    assert!((ch.above - p).abs() <= 1e-12 * p && ch.below == 0.0 && ch.values.iter().all(|&v| v == 0.0));
}

#[test]
fn frequency_axis_narrower_than_one_doppler_shift() {
    // v = 1 mm/s, λ0 = 1 µm: every reflected path beats in [1, 2] kHz. An axis [−100, 100) Hz
    // (5 bins) is narrower than that: all of the power is in its `above` tally; an axis
    // [3, 4) kHz puts all of it in `below`. Bins + below + above = detected power.
    let r = run(
        &moving_slab(
            1e-3,
            r#"
[[detectors]]
name = "dc"
[detectors.spectrum]
f_min_hz = -100
f_max_hz = 100
bins = 5
[[detectors]]
name = "high"
[detectors.spectrum]
f_min_khz = 3
f_max_khz = 4
bins = 5
"#,
        ),
        &["run.samples=50000"],
    );
    assert_finite(&r, "narrow axes");
    let (p, _) = r.power(0);
    let a = assert_conserved(&r, 0);
    let b = assert_conserved(&r, 1);
    assert!(a.values.iter().all(|&v| v == 0.0) && a.below == 0.0 && (a.above - p).abs() <= 1e-12 * p);
    assert!(b.values.iter().all(|&v| v == 0.0) && b.above == 0.0 && (b.below - p).abs() <= 1e-12 * p);
}

/// An LDH camera (f_s = 39 kHz, N_w = 512, band 6–18.3 kHz) looking back through a 2° cone at
/// the moving slab, with an ROI spectrum axis of ±100 kHz (wider than f_s).
fn ldh_scene(v: f64) -> String {
    moving_slab(
        v,
        r#"
[[detectors]]
name = "camera"
area = { type = "rect", size_mm = [0.4, 0.4] }
acceptance_half_angle_deg = 2
[detectors.image]
pixels = [1, 1]
[detectors.ldh]
frame_rate_khz = 39
band_khz = [6, 18.3]
spectrum = { f_min_khz = -100, f_max_khz = 100, bins = 200 }
[[detectors.ldh.roi]]
name = "all"
size_mm = [0.4, 0.4]
"#,
    )
}

#[test]
fn frequency_axis_wider_than_nyquist() {
    // A plain spectrum axis is a histogram of the continuous beat frequency: it has no Nyquist
    // limit. The LDH camera samples at f_s: (a) an M0 band beyond f_s/2 is refused, naming the
    // key and the limit; (b) an ROI spectrum axis wider than f_s is allowed and holds the true
    // (unaliased) beat frequencies, while M0± alias as the camera does: a line at 50 kHz is seen
    // at 50 − 39 = 11 kHz, inside the band, so M0+ = M0− = its power (minus the Hann kernel's
    // leakage, < 1e-3) — exactly as a line at 11 kHz (same paths, same seed).
    let bad = ldh_scene(0.0).replace("band_khz = [6, 18.3]", "band_khz = [6, 25]");
    let e = ohd::config::load(&bad, "test", &[]).expect_err("a band beyond f_s/2 is refused");
    let msg = e.to_string();
    eprintln!("{msg}");
    assert!(msg.contains("detectors[0].ldh.band_khz") && msg.contains("f_s/2 = 19500 Hz"), "{msg}");

    // 2v/λ0 = 50 kHz and 11 kHz (the 2° cone spreads it by 3e-4).
    let (v50, v11) = (50e3 * 1e-6 / 2.0, 11e3 * 1e-6 / 2.0);
    let a = run(&ldh_scene(v50), &["run.samples=50000"]);
    let b = run(&ldh_scene(v11), &["run.samples=50000"]);
    assert_finite(&a, "LDH 50 kHz");
    assert_finite(&b, "LDH 11 kHz");
    let ch = roi_channel(&a, 0, 0, 0);
    let total: f64 = ch.values.iter().sum::<f64>();
    assert!(total > 0.0 && ch.below == 0.0 && ch.above == 0.0);
    // Bin k covers [−100 + k, −99 + k) kHz: 50 kHz·(1 − 3e-4) … 50 kHz is bin 149 (and 150 for
    // the exact 50 kHz edge of a path straight back).
    let in_peak = ch.values[149] + ch.values[150];
    assert!((in_peak - total).abs() <= 1e-12 * total, "ROI spectrum off its 50 kHz bins");
    let ((p50, s50), (m50, _)) = roi_m0(&a, 0, 0);
    let ((p11, _), (m11, _)) = roi_m0(&b, 0, 0);
    eprintln!("M0+ at 50 kHz {p50:.6e} ± {s50:.1e}, at 11 kHz {p11:.6e}; ROI power {total:.6e}; M0− {m50:.6e}");
    assert!(p50 > (1.0 - 1e-3) * total && p50 <= total * (1.0 + 1e-12), "M0+ {p50} vs power {total}");
    assert!((m50 - p50).abs() <= 1e-3 * p50, "M0− {m50} vs M0+ {p50}");
    assert!((p50 - p11).abs() <= 1e-9 * p11 && (m50 - m11).abs() <= 1e-9 * p11, "aliasing is not periodic");
}

// ---------------------------------------------------------------------------------------------
// One bin, one sample, one pixel

#[test]
fn one_bin() {
    // v = 1 mm/s: f = v(1 + cos θ_exit)/λ0 (above). A one-bin axis [0, 1.5) kHz holds the paths
    // leaving more than 60° from the normal, its `above` tally those within 60°: exactly the
    // power of a second detector with a 60° cone (same paths).
    let r = run(
        &moving_slab(
            1e-3,
            r#"
[[detectors]]
name = "one"
[detectors.spectrum]
f_min_khz = 0
f_max_khz = 1.5
bins = 1
[[detectors]]
name = "cone60"
acceptance_half_angle_deg = 60
"#,
        ),
        &["run.samples=50000"],
    );
    assert_finite(&r, "one bin");
    let ch = assert_conserved(&r, 0);
    let (p60, _) = r.power(1);
    eprintln!("one bin {:.6e}, above {:.6e}, 60° cone {p60:.6e}", ch.values[0], ch.above);
    assert!(ch.below == 0.0 && ch.values[0] > 0.0);
    assert!((ch.above - p60).abs() <= 1e-9 * p60, "above {} vs 60° cone {p60}", ch.above);
}

#[test]
fn one_sample() {
    // run.samples = 1 is rounded up to one path per batch (16 paths): it must run, give finite
    // estimates and standard errors, the exact specular reflectance, and (no roulette) the
    // energy balance R_sp + R_d + T + A = 1 path by path.
    let r = run(
        &scene(&format!(
            r#"{VDH_MEDIUM}
[[layers]]
thickness_mm = 0.2
n = 1.4
medium = "slab"
"#
        )),
        &["run.samples=1", "run.roulette_threshold=0"],
    );
    assert_finite(&r, "one sample");
    assert_eq!(r.paths(), 16.0);
    assert_eq!(r.out.stats.paths, 16);
    let r0 = (0.4f64 / 2.4).powi(2);
    assert!((r.scalar(Scalar::ReflectanceSpecular).0 - r0).abs() < 1e-12);
    let total: f64 =
        [Scalar::ReflectanceSpecular, Scalar::ReflectanceDiffuse, Scalar::TransmittanceTotal, Scalar::AbsorbedFraction]
            .iter()
            .map(|&s| r.scalar(s).0)
            .sum();
    assert!((total - 1.0).abs() < 1e-12, "energy {total}");
}

#[test]
fn one_pixel() {
    // A 1×1 image over the detector's area: the pixel is the area, so it holds exactly the
    // detected power (same paths, same additions) with the same standard error; an LDH camera on
    // that pixel has the M0± of an ROI covering the image.
    let r = run(&ldh_scene(50e3 * 1e-6 / 2.0), &["run.samples=50000"]);
    assert_finite(&r, "one pixel");
    let lay = &r.out.layout.detectors[0];
    let i = lay.image().unwrap();
    let (m, se) = (r.out.estimates.mean(), r.out.estimates.stderr());
    let (p, sp) = r.power(0);
    eprintln!("pixel {:.6e} ± {:.1e}, power {p:.6e} ± {sp:.1e}", m[i], se[i]);
    assert!(p > 0.0 && (m[i] - p).abs() <= 1e-12 * p && (se[i] - sp).abs() <= 1e-9 * sp);
    let ll = lay.ldh().unwrap();
    let ((roi_plus, _), (roi_minus, _)) = roi_m0(&r, 0, 0);
    assert!((m[ll.m0_plus] - roi_plus).abs() <= 1e-9 * roi_plus);
    assert!((m[ll.m0_minus] - roi_minus).abs() <= 1e-9 * roi_plus);
}

// ---------------------------------------------------------------------------------------------
// A pixel count beyond the memory budget

#[test]
fn pixel_count_beyond_memory_budget() {
    // 16384² pixels with per-pixel LDH spectra of 513 bins: ~2.7e8 × 515 tallies, over 1 TiB per
    // copy: `ohd check` and `ohd run` refuse it (exit 2) naming the key and the estimate, and
    // write nothing. The budget is a key: 1e-6 GiB refuses even a 64×64 image.
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("huge.toml");
    let text = moving_slab(
        0.0,
        r#"
[[detectors]]
name = "camera"
area = { type = "rect", size_mm = [0.4, 0.4] }
[detectors.image]
pixels = [16384, 16384]
[detectors.ldh]
pixel_spectra = true
"#,
    );
    std::fs::write(&cfg, &text).unwrap();
    let out = dir.path().join("out");
    for args in
        [vec!["check", cfg.to_str().unwrap()], vec!["run", cfg.to_str().unwrap(), "--out", out.to_str().unwrap()]]
    {
        let t = Instant::now();
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_ohd")).args(&args).output().expect("ohd starts");
        let err = String::from_utf8_lossy(&o.stderr);
        eprintln!("ohd {}: {:?} in {:.2} s: {err}", args[0], o.status.code(), t.elapsed().as_secs_f64());
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains("detectors[0].ldh.pixel_spectra"), "{err}");
        assert!(
            err.contains("GiB") && err.contains("memory budget of 8.0 GiB") && err.contains("run.memory_budget_gib"),
            "{err}"
        );
        assert!(!out.exists(), "an output directory was created");
    }
    // Without per-pixel spectra the same image needs 2 GiB per copy of the tallies, so
    // (2 + batches in flight ≥ 1) copies exceed a 4 GiB budget: the image's key is named.
    let plain = text.replace("[detectors.ldh]\npixel_spectra = true\n", "");
    let e = ohd::config::load(&plain, "test", &["run.memory_budget_gib=4".into()]).expect_err("refused");
    let msg = e.to_string();
    eprintln!("{msg}");
    assert!(msg.contains("detectors[0].image.pixels") && msg.contains("[16384, 16384]") && msg.contains("4.0 GiB"));
    let small = plain.replace("[16384, 16384]", "[64, 64]");
    assert!(ohd::config::load(&small, "test", &[]).is_ok());
    // (1e-4 GiB = 107 kB: the layer's medium, counted first, fits; the 64 × 64 image's tallies,
    // about 200 kB with the copies, do not.)
    let e = ohd::config::load(&small, "test", &["run.memory_budget_gib=1e-4".into()]).expect_err("refused");
    assert!(e.to_string().contains("detectors[0].image.pixels"), "{e}");
    assert!(ohd::config::load(&small, "test", &["run.memory_budget_gib=0".into()]).is_err());
}

// ---------------------------------------------------------------------------------------------
// Mie x = 1e4

#[test]
fn mie_x_1e4() {
    // A water-like sphere (m = 1.33) and an absorbing one (m = 1.33 − 0.01i) at x = 1e4
    // (~10⁴ terms): finite efficiencies; Q_ext → 2 (the extinction paradox; the correction is
    // O(x^{−2/3}) ≈ 0.5 %, so within 2 %); Q_sca = Q_ext without absorption; with absorption
    // (κx = 100: opaque) Q_sca → 1 + (reflection) ∈ (1, 1.2); g in (0, 1), 0.80–0.95 for the
    // transparent sphere (geometric optics with diffraction: ≈ 0.87); the phase function finite,
    // positive and normalised (∫ p dΩ = 1 on a grid dense in the 1e-4 rad diffraction peak).
    for (k, transparent) in [(0.0, true), (0.01, false)] {
        let t = Instant::now();
        let mie = ohd::mie::MieSolution::new(1.33, k, 1e4).expect("x = 1e4 is accepted");
        let q = mie.efficiencies();
        let secs = t.elapsed().as_secs_f64();
        eprintln!("m = 1.33 − {k}i, x = 1e4: {q:?}, {} terms, {secs:.3} s", mie.terms());
        assert!(q.qext.is_finite() && q.qsca.is_finite() && q.qback.is_finite() && q.g.is_finite());
        assert!((q.qext - 2.0).abs() < 0.04, "Qext = {}", q.qext);
        assert!(q.g > 0.0 && q.g < 1.0);
        if transparent {
            assert!((q.qsca - q.qext).abs() < 1e-9, "Qsca {} vs Qext {}", q.qsca, q.qext);
            assert!((0.80..0.95).contains(&q.g), "g = {}", q.g);
        } else {
            assert!(q.qsca > 1.0 && q.qsca < 1.2, "Qsca = {}", q.qsca);
        }
        let theta = ohd::mie::angle_grid(20_000, 1e4);
        let mut p = vec![0.0; theta.len()];
        mie.phase_function(&theta, &mut p);
        assert!(p.iter().all(|v| v.is_finite() && *v > 0.0), "phase function not finite and positive");
        let norm: f64 = theta
            .windows(2)
            .zip(p.windows(2))
            .map(|(t, v)| 0.5 * (v[0] * t[0].sin() + v[1] * t[1].sin()) * (t[1] - t[0]) * 2.0 * std::f64::consts::PI)
            .sum();
        eprintln!("∫ p dΩ = {norm:.5}");
        assert!((norm - 1.0).abs() < 0.02, "∫ p dΩ = {norm}");
        assert!(t.elapsed().as_secs_f64() < 30.0);
    }
}

// ---------------------------------------------------------------------------------------------
// FMCW with B = 0

#[test]
fn fmcw_zero_bandwidth() {
    // A chirp of zero bandwidth is a single-frequency laser: f_up = (dl/dt)/λ0 and
    // f_down = −(dl/dt)/λ0. So the up-chirp spectrum equals the CW Doppler spectrum (here of a
    // slab moving at 1 mm/s: 1–2 kHz), bin for bin (same seed, same paths), and the down-chirp
    // spectrum is its mirror on a symmetric axis (bin k ↔ bins − 1 − k, below ↔ above). Range
    // retrieval has no information: a clear note, no NaN.
    let det = r#"
[[detectors]]
name = "top"
[detectors.spectrum]
f_min_khz = -3
f_max_khz = 3
bins = 61
"#;
    let cw = run(&moving_slab(1e-3, det), &["run.samples=50000"]);
    let fm =
        run(&moving_slab(1e-3, det), &["run.samples=50000", "source.chirp={ bandwidth_hz = 0, duration_us = 10 }"]);
    assert_finite(&cw, "CW");
    assert_finite(&fm, "B = 0");
    let (c, up, down) = (cw.channel(0, 0, 0), fm.channel(0, 0, 0), fm.channel(0, 1, 0));
    let p = cw.power(0).0;
    assert!(c.values.iter().sum::<f64>() > 0.99 * p);
    for k in 0..61 {
        assert!((up.values[k] - c.values[k]).abs() <= 1e-12 * p, "up-chirp bin {k}");
        assert!((down.values[60 - k] - up.values[k]).abs() <= 1e-12 * p, "down-chirp mirror of bin {k}");
    }
    assert!((down.below - up.above).abs() <= 1e-12 * p && (down.above - up.below).abs() <= 1e-12 * p);
    let est = fm.exp.fmcw_estimates(&fm.out, 0).expect("a chirp and a spectrum");
    let msg = est.expect_err("no range from B = 0").to_string();
    eprintln!("{msg}");
    assert!(msg.contains("bandwidth_hz") && msg.contains("no range information"), "{msg}");
}

// ---------------------------------------------------------------------------------------------
// A ramp density with a loose and a tight majorant

#[test]
fn ramp_density_loose_and_tight_majorant() {
    // A 2 mm layer whose density is 0 above z = 0.5 mm, rises linearly to 2 at z = 1.5 mm and
    // stays 2 below: ∫ d dz = 1 mm·1 + 0.5 mm·2 = 2 mm. (a) A pure absorber (σa = 1000 /m at
    // density 1): T = e^{−σa ∫d dz} = e^{−2}, for the tight majorant (per piece, analytic
    // tracking) and a loose one (one global bound inflated ×100: 400 null collisions per
    // path) alike; the zero-density top costs no null collision with the tight one (about one per
    // crossing of the linear piece, whose bound is its larger end). (b) With
    // scattering (σs = 900, σa = 100 /m, g = 0.8) the two agree in R_d and T (independent seeds).
    let ramp = |majorant: &str, sa: f64, ss: f64| {
        scene(&format!(
            r#"
[media.m]
sigma_s_per_m = {ss}
sigma_a_per_m = {sa}
phase = {{ type = "hg", g = 0.8 }}
density = {{ type = "ramp", axis = "z", from_mm = 0.5, to_mm = 1.5, density_from = 0, density_to = 2, majorant = "{majorant}" }}
[[layers]]
thickness_mm = 2
n = 1.0
medium = "m"
"#
        ))
    };
    let loose_sets = ["run.samples=100000", "run.seed=2", "run.tracking=\"delta\"", "run.majorant_scale=100"];
    let want = (-2.0f64).exp();
    let tight = run(&ramp("grid", 1000.0, 0.0), &["run.samples=100000", "run.seed=1"]);
    let t = Instant::now();
    let loose = run(&ramp("global", 1000.0, 0.0), &loose_sets);
    let loose_s = t.elapsed().as_secs_f64();
    for (what, r) in [("tight", &tight), ("loose", &loose)] {
        assert_finite(r, what);
        let (v, se) = r.scalar(Scalar::TransmittanceTotal);
        report(&format!("{what} T"), (v, se), want);
        assert_within_sigma(what, v, se, want, 4.0);
    }
    let nulls = loose.out.stats.null_collisions as f64 / loose.paths();
    eprintln!(
        "null collisions per path: tight {:.2}, loose {nulls:.0} ({loose_s:.2} s)",
        tight.out.stats.null_collisions as f64 / tight.paths()
    );
    // Tight: the ramp piece's bound is its larger end, 2σ, against a mean of σ over 1 mm: about
    // one null collision per crossing, none in the constant pieces.
    let tight_nulls = tight.out.stats.null_collisions as f64 / tight.paths();
    assert!(tight_nulls < 1.5 && nulls > 100.0, "null collisions per path: tight {tight_nulls}, loose {nulls}");

    let tight = run(&ramp("grid", 100.0, 900.0), &["run.samples=100000", "run.seed=3"]);
    let loose = run(
        &ramp("global", 100.0, 900.0),
        &["run.samples=100000", "run.seed=4", "run.tracking=\"delta\"", "run.majorant_scale=100"],
    );
    assert_finite(&tight, "tight, scattering");
    assert_finite(&loose, "loose, scattering");
    for s in [Scalar::ReflectanceDiffuse, Scalar::TransmittanceTotal] {
        let z = z_diff(tight.scalar(s), loose.scalar(s));
        eprintln!("{}: tight {:?} loose {:?}, z = {z:+.2}", s.name(), tight.scalar(s), loose.scalar(s));
        assert!(z.abs() < 4.0, "{}: z = {z:.2}", s.name());
    }
}

/// A scattering sphere inside a clear layer of index 1.33 between air: packets leaving the sphere
/// at grazing angles are totally internally reflected between the layer's faces for ever (issue
/// 21: a 1 000-path run did not end). The walk truncates a path after
/// `MAX_REFLECTIONS_WITHOUT_COLLISION` reflections without a collision and counts it; the run ends,
/// the trapped share is counted, and what is not trapped still balances (R + T + A + trapped
/// ≤ 1 with the trapped paths' weight the only loss).
#[test]
fn light_trapped_by_total_internal_reflection_is_truncated_and_counted() {
    let text = r#"
schema_version = 1
[run]
samples = 20000
batches = 16
[source]
wavelength_nm = 800
[media.clear]
sigma_a_per_mm = 0
sigma_s_per_mm = 0
[media.cloud]
sigma_a_per_mm = 0
sigma_s_per_mm = 20
phase = { type = "hg", g = 0.0 }
[[layers]]
name = "slab"
thickness_mm = 1
n = 1.33
medium = "clear"
[[regions]]
layer = "slab"
medium = "cloud"
shape = { type = "sphere", center_mm = [0, 0, 0.5], radius_mm = 0.3 }
"#;
    let r = crate::support::run::run(text, &[]);
    let st = &r.out.stats;
    // Isotropic scattering in a sphere: a fair share of the directions lie beyond the critical
    // angle (48.8°) of both faces, and half of those never meet the sphere again.
    assert!(st.truncated_paths > 100, "only {} paths truncated", st.truncated_paths);
    use ohd::detect::Scalar;
    let total = [Scalar::ReflectanceSpecular, Scalar::ReflectanceDiffuse, Scalar::TransmittanceTotal]
        .iter()
        .map(|&s| r.scalar(s).0)
        .sum::<f64>();
    let trapped = st.truncated_paths as f64 / st.paths as f64;
    // No absorption: the weight of a packet is 1 − R_specular until it leaves or is truncated.
    assert!(
        (total + trapped * (1.0 - r.scalar(Scalar::ReflectanceSpecular).0) - 1.0).abs() < 0.01,
        "R + T = {total}, trapped {trapped}"
    );
}
