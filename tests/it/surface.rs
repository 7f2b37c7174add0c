//! Opaque surfaces under the stack (`[bottom]`, issue 38) against closed forms: a Lambertian floor
//! under a clear dielectric layer, a smooth metal mirror, and the Doppler lines of a translating
//! and of a rotating Lambertian plate.

use ohd::detect::Scalar;
use ohd::surface::fresnel;

use crate::support::run::{Run, experiment, run};
use crate::support::stats::assert_within_sigma;

/// A clear layer (no scattering, no absorption) over an opaque floor, watched from the top through
/// a 10° cone with shadow rays; a pencil beam at normal incidence. λ0 = 1 µm, so f = dl/dt · 10⁶
/// Hz per m/s.
const FLOOR: &str = r#"
schema_version = 1
[run]
samples = 200000
seed = 3
batches = 16
[source]
wavelength_nm = 1000
profile = "pencil"
[media.clear]
sigma_a_per_mm = 0
sigma_s_per_mm = 0
[[layers]]
thickness_mm = 1
n = 1.0
medium = "clear"
[bottom]
surface = { type = "lambertian", albedo = 0.6 }
[[detectors]]
name = "top"
acceptance_half_angle_deg = 10
next_event = true
[detectors.spectrum]
f_min_hz = -4000
f_max_hz = 4000
bins = 800
by_order = 2
"#;

/// The share of a Lambertian radiance inside a medium of index `n` that leaves through its plane
/// surface into index 1: `∫ (1 − R(θ)) 2 cos θ sin θ dθ` up to the critical angle (midpoint rule).
fn lambertian_escape(n: f64) -> f64 {
    let steps = 200_000;
    let mut sum = 0.0;
    for i in 0..steps {
        let c = (i as f64 + 0.5) / steps as f64; // cos θ, uniform: 2 cos θ sin θ dθ = d(cos² θ) = 2c dc
        let (r, _) = fresnel::reflectance(n, 1.0, c);
        sum += (1.0 - r) * 2.0 * c / steps as f64;
    }
    sum
}

#[test]
fn lambertian_floor_under_a_clear_layer_has_its_closed_form() {
    // Entering at normal incidence (specular R0), then the floor's albedo a, then either out
    // (the escape share T of a Lambertian radiance) or back to the floor by internal
    // reflection: Rd = (1 − R0) a T / (1 − a (1 − T)).
    let (n, a) = (1.4f64, 0.6);
    let r = run(FLOOR, &["layers.0.n=1.4", "detectors.0.next_event=false"]);
    let r0 = ((n - 1.0) / (n + 1.0)).powi(2);
    let t = lambertian_escape(n);
    let want = (1.0 - r0) * a * t / (1.0 - a * (1.0 - t));
    let (rd, se) = r.scalar(Scalar::ReflectanceDiffuse);
    assert_within_sigma("Rd", rd, se, want, 4.0);
    assert!((r.scalar(Scalar::ReflectanceSpecular).0 - r0).abs() < 1e-12);
    // Nothing passes the floor; what does not come out is absorbed by it.
    assert_eq!(r.scalar(Scalar::TransmittanceTotal).0, 0.0);
    let (ab, se_ab) = r.scalar(Scalar::AbsorbedFraction);
    assert_within_sigma("A", ab, se_ab, 1.0 - r0 - rd, 4.0);
}

#[test]
fn a_smooth_metal_floor_returns_its_fresnel_reflectance() {
    // A matched clear layer over a mirror of copper's index at 1 µm: every path comes back with
    // weight R(0) = ((n − 1)² + k²)/((n + 1)² + k²), exactly.
    let r = run(FLOOR, &["bottom.surface={ type = \"conductor\", n = 0.3, k = 6.4 }", "detectors.0.next_event=false"]);
    let want = ((0.3f64 - 1.0).powi(2) + 6.4f64.powi(2)) / ((1.3f64).powi(2) + 6.4f64.powi(2));
    let (rd, se) = r.scalar(Scalar::ReflectanceDiffuse);
    assert!((rd - want).abs() < 1e-12 && se < 1e-12, "Rd = {rd} ± {se}, R(0) = {want}");
}

/// The power-weighted mean and RMS width of detector 0's order-1 spectrum (Hz), and its bins'
/// total.
fn moments(r: &Run) -> (f64, f64, f64, Vec<(f64, f64)>) {
    let axis = r.exp.detectors[0].surface().unwrap().spectrum().unwrap().axis;
    let ch = r.channel(0, 0, 2); // channel 1 + k is order k
    let bins: Vec<(f64, f64)> = ch.values.iter().enumerate().map(|(k, &w)| (axis.center(k), w)).collect();
    let total: f64 = bins.iter().map(|b| b.1).sum();
    let mean = bins.iter().map(|(f, w)| f * w).sum::<f64>() / total;
    let var = bins.iter().map(|(f, w)| (f - mean).powi(2) * w).sum::<f64>() / total;
    (mean, var.sqrt(), total, bins)
}

#[test]
fn a_translating_lambertian_plate_gives_the_closed_form_line() {
    // v = (vx, 0, vz); light arrives along +z and leaves within θa of −z, at (θ, φ): f = [vz (1 +
    // cos θ) − vx sin θ cos φ]/λ0. Over the cone's Lambertian radiance the mean is vz (1 + ⟨cos θ⟩)
    // /λ0 with ⟨cos θ⟩ = (2/3)(1 − cos³θa)/(1 − cos²θa), and every frequency lies within
    // [vz (1 + cos θa) − |vx| sin θa, 2 vz + |vx| sin θa]/λ0.
    let (vx, vz, lambda) = (2e-3f64, 1e-3, 1e-6);
    let r = run(FLOOR, &["bottom.velocity_m_per_s=[0.002, 0, 0.001]"]);
    let ca = 10f64.to_radians().cos();
    let sa = 10f64.to_radians().sin();
    let mean_cos = 2.0 / 3.0 * (1.0 - ca.powi(3)) / (1.0 - ca * ca);
    let want = vz * (1.0 + mean_cos) / lambda;
    let (lo, hi) = ((vz * (1.0 + ca) - vx.abs() * sa) / lambda, (2.0 * vz + vx.abs() * sa) / lambda);
    let (mean, rms, total, bins) = moments(&r);
    assert!(total > 0.0);
    for (f, w) in &bins {
        if *w > 0.0 {
            assert!(*f > lo - 5.0 && *f < hi + 5.0, "weight {w} at {f:.1} Hz outside [{lo:.1}, {hi:.1}]");
        }
    }
    // The mean of N shadow rays drawn uniformly in the cone: σ ≈ rms/√N; the 10 Hz bins shift a
    // mean by at most their half width, and average to well under.
    let n = r.paths();
    assert!((mean - want).abs() < 4.0 * rms / n.sqrt() + 1.0, "mean {mean:.2} Hz, closed form {want:.2} Hz");
    // Only the floor scatters: nothing at order 2.
    assert!(r.channel(0, 0, 3).values.iter().all(|&w| w == 0.0));
}

#[test]
fn a_rotating_disk_broadens_the_line_symmetrically() {
    // A disk spinning about the z axis at ω, lit at radius r0: its surface moves at ω r0 along y
    // there, in its own plane, so f = −ω r0 sin θ sin φ/λ0: a line centred on 0 whose RMS width
    // over the cone's Lambertian radiance is ω r0 sin θa/(2 λ0) (⟨sin²θ sin²φ⟩ = sin²θa/4).
    let (omega, r0, lambda) = (10.0, 2e-3, 1e-6);
    let r = run(
        FLOOR,
        &["bottom.angular_velocity_rad_per_s=[0, 0, 10]", "source.position_mm=[2, 0, -1]", "run.samples=400000"],
    );
    let want = omega * r0 * 10f64.to_radians().sin() / (2.0 * lambda);
    let (mean, rms, _, bins) = moments(&r);
    let bound = omega * r0 * 10f64.to_radians().sin() / lambda;
    assert!(bins.iter().all(|(f, w)| *w == 0.0 || f.abs() < bound + 5.0), "a frequency beyond ±{bound:.1} Hz");
    let n = r.paths();
    assert!(mean.abs() < 4.0 * rms / n.sqrt() + 1.0, "mean {mean:.2} Hz");
    // The bins (10 Hz) widen a width of σ by √(σ² + 10²/12): 0.6 % here.
    let binned = (want * want + 100.0 / 12.0).sqrt();
    assert!((rms / binned - 1.0).abs() < 0.02, "RMS {rms:.2} Hz, closed form {binned:.2} Hz");
}

#[test]
fn bad_surfaces_are_refused_with_their_key() {
    for (set, key, words) in [
        ("bottom.surface={ type = \"lambertian\", albedo = 1.5 }", "bottom.surface.albedo", "0 … 1"),
        ("bottom.surface={ type = \"conductor\", material = \"tin\" }", "bottom.surface.material", "copper"),
        (
            "bottom.surface={ type = \"conductor\", material = \"copper\", roughness = 2 }",
            "bottom.surface.roughness",
            "α",
        ),
        ("bottom.surface={ type = \"conductor\", material = \"gold\" }", "bottom.surface.material", "nm"),
        (
            "bottom.surface={ type = \"mixture\", parts = [{ weight = 0.5, surface = { type = \"lambertian\", albedo = 0.5 } }, { weight = 0.4, surface = { type = \"lambertian\", albedo = 0.2 } }] }",
            "bottom.surface.parts",
            "sum",
        ),
        ("layers.0.thickness_mm=inf", "layers[0].thickness_mm", "finite"),
        ("layers.0.roughness=1.5", "layers[0].roughness", "α"),
        ("layers.0.roughness=-0.1", "layers[0].roughness", "0 (smooth) … 1"),
    ] {
        let sets: Vec<&str> = if key == "bottom.surface.material" && words == "nm" {
            vec![set, "source.wavelength_nm=3000"]
        } else {
            vec![set]
        };
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        let e = ohd::config::load(FLOOR, "test", &sets).map(|_| ()).expect_err(set);
        let text = e.to_string();
        assert!(text.contains(key) && text.contains(words), "{set}: {text}");
    }
}

// Opaque solids inside a layer (`[[opaque]]`).

/// `FLOOR` without its `[bottom]`: its layer made 2 mm deep with an opaque slab whose top face is
/// at 1 mm, wider than any path goes (`SLAB`): the same floor, met by the walk inside its layer
/// instead of under it.
fn slab_floor() -> String {
    let floor = "[bottom]\nsurface = { type = \"lambertian\", albedo = 0.6 }\n";
    assert!(FLOOR.contains(floor));
    FLOOR.replace(floor, "")
}

const SLAB: [&str; 2] = [
    "layers.0.thickness_mm=2",
    "opaque=[{ name = \"slab\", layer = \"layer0\", shape = { type = \"box\", center_mm = [0, 0, 1.25], size_mm = [4000, 4000, 0.5] }, surface = { type = \"lambertian\", albedo = 0.6 } }]",
];

#[test]
fn an_opaque_slab_is_the_floor_it_stands_for() {
    let (n, a) = (1.4f64, 0.6);
    let mut sets = SLAB.to_vec();
    sets.extend(["layers.0.n=1.4", "detectors.0.next_event=false"]);
    let r = run(&slab_floor(), &sets);
    let r0 = ((n - 1.0) / (n + 1.0)).powi(2);
    let t = lambertian_escape(n);
    let want = (1.0 - r0) * a * t / (1.0 - a * (1.0 - t));
    let (rd, se) = r.scalar(Scalar::ReflectanceDiffuse);
    assert_within_sigma("Rd", rd, se, want, 4.0);
    assert_eq!(r.scalar(Scalar::TransmittanceTotal).0, 0.0);
    let (ab, se_ab) = r.scalar(Scalar::AbsorbedFraction);
    assert_within_sigma("A", ab, se_ab, 1.0 - r0 - rd, 4.0);
}

#[test]
fn a_translating_opaque_slab_gives_the_plates_line() {
    // As `a_translating_lambertian_plate_gives_the_closed_form_line`, the plate an opaque solid.
    let (vz, lambda) = (1e-3f64, 1e-6);
    let mut sets = SLAB.to_vec();
    let moving = SLAB[1].replace("} }]", "}, velocity_m_per_s = [0, 0, 0.001] }]");
    sets[1] = &moving;
    let r = run(&slab_floor(), &sets);
    let ca = 10f64.to_radians().cos();
    let mean_cos = 2.0 / 3.0 * (1.0 - ca.powi(3)) / (1.0 - ca * ca);
    let want = vz * (1.0 + mean_cos) / lambda;
    let (mean, rms, total, bins) = moments(&r);
    assert!(total > 0.0);
    let (lo, hi) = (vz * (1.0 + ca) / lambda, 2.0 * vz / lambda);
    assert!(
        bins.iter().all(|(f, w)| *w == 0.0 || (*f > lo - 5.0 && *f < hi + 5.0)),
        "a frequency outside [{lo}, {hi}]"
    );
    assert!((mean - want).abs() < 4.0 * rms / r.paths().sqrt() + 1.0, "mean {mean:.2} Hz, closed form {want:.2} Hz");
}

/// A hazy layer with an opaque sphere and a box in it, between the beam's scattering and a
/// detector beside the beam: shadow rays must stop at them.
const SHADED: &str = r#"
schema_version = 1
[run]
samples = 1600000
seed = 5
batches = 16
[source]
wavelength_nm = 1000
profile = "disk"
radius_mm = 0.3
[media.haze]
sigma_a_per_mm = 0.1
sigma_s_per_mm = 2
phase = { type = "hg", g = 0.7 }
[[layers]]
name = "haze"
thickness_mm = 3
n = 1.0
medium = "haze"
[[opaque]]
name = "ball"
layer = "haze"
shape = { type = "sphere", center_mm = [0.6, 0, 0.7], radius_mm = 0.4 }
surface = { type = "conductor", material = "gold", roughness = 0.4 }
[[opaque]]
name = "brick"
layer = "haze"
shape = { type = "box", center_mm = [-0.3, 0.5, 1.2], size_mm = [0.6, 0.4, 0.8] }
surface = { type = "lambertian", albedo = 0.8 }
[[detectors]]
name = "beside"
area = { type = "disk", center_mm = [1.2, 0], radius_mm = 0.8 }
axis = [0.5, 0, -0.866]
acceptance_half_angle_deg = 20
next_event = true
"#;

#[test]
fn shadow_rays_stop_at_opaque_solids() {
    // The same power by shadow rays (balanced against escapes) and by escapes alone: a shadow ray
    // through a solid would add light the escapes never bring (measured: shadow rays that pass
    // through the ball put the two 6.5σ apart).
    let nee = run(SHADED, &[]);
    let escapes = run(SHADED, &["detectors.0.next_event=false"]);
    let (a, sa) = nee.power(0);
    let (b, sb) = escapes.power(0);
    assert!(a > 0.0 && b > 0.0);
    let z = (a - b) / sa.hypot(sb);
    assert!(z.abs() < 4.0, "shadow rays {a:.5e} ± {sa:.1e}, escapes {b:.5e} ± {sb:.1e}: {z:.1}σ apart");
    // And the solids matter here: without them the detector sees more (the test could fail).
    let open = run(SHADED, &["opaque=[]"]);
    let (c, sc) = open.power(0);
    assert!((c - a) / sa.hypot(sc) > 8.0, "without the solids {c:.4e} ± {sc:.1e}, with {a:.4e} ± {sa:.1e}");
}

#[test]
fn bad_opaque_solids_are_refused_with_their_key() {
    let solid = |s: &str| format!("opaque=[{{ layer = \"haze\", {s} }}]");
    for (set, key, words) in [
        (solid("surface = { type = \"lambertian\", albedo = 0.5 }"), "opaque[0]", "missing shape"),
        (
            solid("shape = { type = \"sphere\", center_mm = [0, 0, 2.8], radius_mm = 0.4 }, surface = { type = \"lambertian\", albedo = 0.5 }"),
            "opaque[0].shape",
            "inside",
        ),
        (solid("shape = { type = \"sphere\", center_mm = [0, 0, 1], radius_mm = 0.4 }"), "opaque[0]", "missing surface"),
        (
            solid("shape = { type = \"cylinder\", center_mm = [0, 0, 1], axis = [1, 0, 0], radius_mm = 0.4 }, surface = { type = \"lambertian\", albedo = 0.5 }"),
            "opaque[0].shape",
            "length",
        ),
        (
            "opaque=[{ layer = \"glass\", shape = { type = \"sphere\", center_mm = [0, 0, 1], radius_mm = 0.4 }, surface = { type = \"lambertian\", albedo = 0.5 } }]".to_string(),
            "opaque[0].layer",
            "haze",
        ),
        (solid("shape = { type = \"sphere\", center_mm = [0, 0, 1], radius_mm = 0.4 }, surface = { type = \"lambertian\", albedo = 0.5 }, velocity_m_per_s = [0, inf, 0]"), "opaque[0].velocity_m_per_s", "finite"),
    ] {
        let e = ohd::config::load(SHADED, "test", std::slice::from_ref(&set)).map(|_| ()).expect_err(&set);
        let text = e.to_string();
        assert!(text.contains(key) && text.contains(words), "{set}: {text}");
    }
    // Camera paths meet the solids (tests/it/camera.rs), but not a mirror in the beam: it would
    // reflect a second beam, which no camera path connects to.
    let camera = ["detectors.0.estimator=\"camera\"", "detectors.0.image={pixels=[4,4]}"];
    let mirror = "opaque.0.surface={type=\"conductor\",material=\"gold\",roughness=0}";
    assert!(ohd::config::load(SHADED, "test", &camera.map(String::from)).is_ok());
    let sets = [camera[0], camera[1], mirror].map(String::from);
    let e = ohd::config::load(SHADED, "test", &sets).expect_err("mirror");
    assert!(
        e.to_string().contains("detectors[0].estimator")
            && e.to_string().contains("opaque[0].surface is a smooth mirror"),
        "{e}"
    );
    // Under a rough face the beam reaches it scattered: allowed.
    let sets = [camera[0], camera[1], mirror, "layers.0.roughness=0.2", "layers.0.n=1.33"].map(String::from);
    assert!(ohd::config::load(SHADED, "test", &sets).is_ok());
}

// Rough faces between layers (`layers[i].roughness`).

/// A clear, semi-infinite medium of index 1.5 under a rough top face (GGX α = 0.3), lit by a
/// pencil beam at 30° from the normal.
const ROUGH_ENTRY: &str = r#"
schema_version = 1
[run]
samples = 400000
seed = 7
batches = 16
[source]
wavelength_nm = 1000
profile = "pencil"
direction = [0.5, 0, 0.8660254037844386]
[media.clear]
sigma_a_per_mm = 0
sigma_s_per_mm = 0
[[layers]]
thickness_mm = inf
n = 1.5
roughness = 0.3
medium = "clear"
"#;

/// `∫ f(wi, wo)|cos θo| dωo` of a rough interface over the hemisphere above (`up`) or below it,
/// by the midpoint rule in (cos θo, φo).
fn rough_albedo(alpha: f64, wi: glam::DVec3, n_i: f64, n_t: f64, up: bool) -> f64 {
    let interface = ohd::surface::RoughDielectric { alpha };
    let (nu, nphi) = (2000, 720);
    let mut sum = 0.0;
    for i in 0..nu {
        let c = (i as f64 + 0.5) / nu as f64;
        let c = if up { c } else { -c };
        let s = (1.0 - c * c).sqrt();
        for j in 0..nphi {
            let phi = std::f64::consts::TAU * (j as f64 + 0.5) / nphi as f64;
            let wo = glam::DVec3::new(s * phi.cos(), s * phi.sin(), c);
            sum += interface.eval(wi, wo, n_i, n_t);
        }
    }
    sum * std::f64::consts::TAU / (nu * nphi) as f64
}

#[test]
fn a_rough_entry_face_reflects_and_transmits_its_microfacet_shares() {
    // Reflected (escaping), transmitted (to depth) and masked (absorbed) shares of the beam at a
    // rough face over a clear medium: the first two the quadratures of the interface's BSDF, the
    // third what is left, a non-absorbing interface's single-scattering loss.
    let r = run(ROUGH_ENTRY, &[]);
    let wi = glam::DVec3::new(0.5, 0.0, 0.8660254037844386);
    let (want_r, want_t) = (rough_albedo(0.3, wi, 1.0, 1.5, true), rough_albedo(0.3, wi, 1.0, 1.5, false));
    let (rd, se_r) = r.scalar(Scalar::ReflectanceDiffuse);
    assert_eq!(r.scalar(Scalar::ReflectanceSpecular).0, 0.0, "a rough face has no specular reflection");
    let (t, se_t) = r.scalar(Scalar::TransmittanceTotal);
    let (a, se_a) = r.scalar(Scalar::AbsorbedFraction);
    assert_within_sigma("R", rd, se_r, want_r, 4.0);
    assert_within_sigma("T", t, se_t, want_t, 4.0);
    assert!(a > 0.0, "a rough face masks some of the light");
    assert_within_sigma("A", a, se_a, 1.0 - want_r - want_t, 4.0);
    assert!((rd + t + a - 1.0).abs() < 1e-9, "R + T + A = {}", rd + t + a);
}

/// Two scattering layers (n = 1.4 over 1.33, clear air below), each with a rough top face, seen
/// through a 15° cone with shadow rays.
const ROUGH_SLAB: &str = r#"
schema_version = 1
[run]
samples = 300000
seed = 11
batches = 16
[source]
wavelength_nm = 1000
profile = "disk"
radius_mm = 0.2
[media.haze]
sigma_a_per_mm = 0.2
sigma_s_per_mm = 3
phase = { type = "hg", g = 0.8 }
[[layers]]
thickness_mm = 0.5
n = 1.4
roughness = 0.3
medium = "haze"
[[layers]]
thickness_mm = 0.5
n = 1.33
roughness = 0.2
medium = "haze"
[[detectors]]
name = "top"
acceptance_half_angle_deg = 15
next_event = true
"#;

#[test]
fn shadow_rays_from_rough_faces_agree_with_the_escapes() {
    // A rough face is a vertex of shadow rays (balanced against the escapes by its sampling
    // density); the shadow rays of the particles stop at it. Power by both = by escapes alone.
    let nee = run(ROUGH_SLAB, &[]);
    let escapes = run(ROUGH_SLAB, &["detectors.0.next_event=false", "run.samples=1200000"]);
    let ((a, sa), (b, sb)) = (nee.power(0), escapes.power(0));
    let z = (a - b) / sa.hypot(sb);
    assert!(a > 0.0 && z.abs() < 4.0, "shadow rays {a:.5e} ± {sa:.1e}, escapes {b:.5e} ± {sb:.1e}: {z:.1}σ apart");
}

#[test]
fn a_rough_face_tends_to_the_smooth_one() {
    // α = 10⁻⁴ against the smooth Fresnel faces (α = 0, another code path): reflectance,
    // transmittance, absorption and the detector's power within 4σ.
    let smooth = run(ROUGH_SLAB, &["layers.0.roughness=0", "layers.1.roughness=0"]);
    let rough = run(ROUGH_SLAB, &["layers.0.roughness=1e-4", "layers.1.roughness=1e-4"]);
    let total_r = |r: &Run| {
        let ((s, ss), (d, sd)) = (r.scalar(Scalar::ReflectanceSpecular), r.scalar(Scalar::ReflectanceDiffuse));
        (s + d, ss.hypot(sd))
    };
    let pairs = [
        ("R", total_r(&smooth), total_r(&rough)),
        ("T", smooth.scalar(Scalar::TransmittanceTotal), rough.scalar(Scalar::TransmittanceTotal)),
        ("A", smooth.scalar(Scalar::AbsorbedFraction), rough.scalar(Scalar::AbsorbedFraction)),
        ("P", smooth.power(0), rough.power(0)),
    ];
    for (what, (a, sa), (b, sb)) in pairs {
        let z = (a - b) / sa.hypot(sb);
        assert!(z.abs() < 4.0, "{what}: smooth {a:.6} ± {sa:.1e}, α = 1e-4 {b:.6} ± {sb:.1e}: {z:.1}σ apart");
    }
}

#[test]
fn a_flight_to_depth_meets_no_solid() {
    // A semi-infinite clear layer holding a scattering region: flights that miss the region go
    // to depth (a boundary at t = ∞), where no opaque solid lies ahead either (t = ∞ too): they
    // are transmitted, not taken for a solid's boundary (a regression: `numpy_phantom.py`).
    let text = r#"
schema_version = 1
[run]
samples = 20000
[source]
wavelength_nm = 1000
profile = "disk"
radius_mm = 0.5
[media.clear]
sigma_a_per_mm = 0
sigma_s_per_mm = 0
[media.haze]
sigma_a_per_mm = 0.1
sigma_s_per_mm = 5
[[layers]]
name = "deep"
thickness_mm = inf
n = 1.0
medium = "clear"
[[regions]]
layer = "deep"
medium = "haze"
shape = { type = "sphere", center_mm = [0, 0, 1], radius_mm = 0.2 }
"#;
    let r = run(text, &[]);
    let (t, _) = r.scalar(Scalar::TransmittanceTotal);
    assert!(t > 0.5 && t < 1.0, "transmitted to depth {t}");
    assert_eq!(r.out.stats.truncated_paths, 0);
}

// Extremes (issue 52): faces smoother than f64 resolves, metals' indices, surface speeds.

/// Roughnesses inside the documented 0 … 1 but below `ROUGHNESS_MIN` (10⁻⁸): they ended in NaN
/// ("non-finite … please report it") with shadow rays and in every camera detection dropped.
const TINY: [&str; 4] = ["1e-9", "1e-20", "1e-160", "5e-324"];

#[test]
fn faces_smoother_than_the_minimum_are_the_smooth_faces() {
    // Resolved to α = 0: the layers' faces, a conductor and a mixture's conductor.
    for a in TINY {
        let e = experiment(
            FLOOR,
            &[
                &format!("layers.0.roughness={a}"),
                "layers.0.n=1.4",
                &format!(
                    "bottom.surface={{ type = \"mixture\", parts = [{{ weight = 0.5, surface = {{ type = \"conductor\", material = \"gold\", roughness = {a} }} }}, {{ weight = 0.5, surface = {{ type = \"lambertian\", albedo = 0.5 }} }}] }}"
                ),
            ],
        );
        assert_eq!(e.scene.layers[0].face.roughness(), 0.0, "α = {a}");
        let Some(ohd::surface::Bsdf::Mixture(parts)) = e.scene.bottom.as_ref().map(|b| &b.bsdf) else {
            panic!("mixture")
        };
        assert!(matches!(parts[0].1, ohd::surface::Bsdf::Conductor { alpha: 0.0, .. }), "α = {a}: {:?}", parts[0].1);
    }
    // Shadow rays through the faces: the smooth faces' run, number for number, all detections kept.
    let smooth = run(ROUGH_SLAB, &["layers.0.roughness=0", "layers.1.roughness=0", "run.samples=40000"]);
    for a in TINY {
        let r = run(
            ROUGH_SLAB,
            &[&format!("layers.0.roughness={a}"), &format!("layers.1.roughness={a}"), "run.samples=40000"],
        );
        assert!(r.power(0).0.is_finite() && r.out.stats.non_finite == 0, "α = {a}: {:?}", r.power(0));
        assert_eq!(r.power(0), smooth.power(0), "α = {a}");
        assert_eq!(r.scalar(Scalar::AbsorbedFraction), smooth.scalar(Scalar::AbsorbedFraction), "α = {a}");
    }
}

#[test]
fn the_smoothest_rough_face_agrees_with_the_smooth_one() {
    // Just above the threshold (α = 10⁻⁸, the stable form of D) and at 10⁻⁵: finite, no detection
    // dropped, the smooth faces' reflectance, transmittance, absorption and power within 4σ.
    let smooth = run(ROUGH_SLAB, &["layers.0.roughness=0", "layers.1.roughness=0"]);
    for a in ["1e-8", "1e-5"] {
        let rough = run(ROUGH_SLAB, &[&format!("layers.0.roughness={a}"), &format!("layers.1.roughness={a}")]);
        assert_eq!(rough.exp.scene.layers[0].face.roughness(), a.parse::<f64>().unwrap());
        assert_eq!(rough.out.stats.non_finite, 0, "α = {a}");
        let total_r = |r: &Run| {
            let ((s, ss), (d, sd)) = (r.scalar(Scalar::ReflectanceSpecular), r.scalar(Scalar::ReflectanceDiffuse));
            (s + d, ss.hypot(sd))
        };
        let pairs = [
            ("R", total_r(&smooth), total_r(&rough)),
            ("T", smooth.scalar(Scalar::TransmittanceTotal), rough.scalar(Scalar::TransmittanceTotal)),
            ("A", smooth.scalar(Scalar::AbsorbedFraction), rough.scalar(Scalar::AbsorbedFraction)),
            ("P", smooth.power(0), rough.power(0)),
        ];
        for (what, (x, sx), (y, sy)) in pairs {
            let z = (x - y) / sx.hypot(sy);
            assert!(
                y.is_finite() && z.abs() < 4.0,
                "{what}: smooth {x:.6} ± {sx:.1e}, α = {a} {y:.6} ± {sy:.1e}: {z:.1}σ apart"
            );
        }
    }
}

#[test]
fn camera_paths_take_tiny_roughness_as_smooth_and_refuse_narrow_lobes_in_the_beam() {
    // The camera estimator: below the threshold the smooth faces' run, every detection kept
    // (before: power 10⁻¹⁶ of 0.006, every detection dropped with a warning).
    let text = include_str!("../configs/good/camera_surfaces.toml");
    let base = ["run.samples=4000"];
    let smooth = run(text, &[base[0], "layers.0.roughness=0", "layers.1.roughness=0"]);
    assert!(smooth.power(0).0 > 0.0);
    for a in TINY {
        let r = run(text, &[base[0], &format!("layers.0.roughness={a}"), &format!("layers.1.roughness={a}")]);
        assert!(r.out.stats.non_finite == 0, "α = {a}: {} detections dropped", r.out.stats.non_finite);
        assert_eq!(r.power(0), smooth.power(0), "α = {a}");
    }
    // Between the threshold and 0.01 the first rough face's lobe is too narrow for camera paths
    // (a 20,000-path run at α = 10⁻⁵ came out at 0.38 of the forward estimate, 170σ off): refused,
    // as a rough conductor that narrow in the beam; the forward estimator takes both.
    for (sets, words) in [
        (vec!["layers.0.roughness=1e-5".to_string()], "the top face of layer \"top\" (roughness = 1e-5)"),
        (vec!["layers.0.roughness=0.005".to_string(), "layers.1.roughness=0.3".to_string()], "roughness ≥ 0.01"),
    ] {
        let e = ohd::config::load(text, "test", &sets).map(|_| ()).expect_err(words);
        assert!(e.to_string().contains("detectors[0].estimator") && e.to_string().contains(words), "{e}");
        let forward: Vec<String> =
            sets.iter().cloned().chain(["detectors.0.estimator=\"forward\"".to_string()]).collect();
        assert!(ohd::config::load(text, "test", &forward).is_ok());
    }
    let camera = ["detectors.0.estimator=\"camera\"", "detectors.0.image={pixels=[4,4]}"];
    for (alpha, words) in [
        ("1e-5", "opaque[0].surface is a rough conductor of roughness 1e-5"),
        ("1e-9", "opaque[0].surface is a smooth mirror"),
    ] {
        let set = format!("opaque.0.surface={{type=\"conductor\",material=\"gold\",roughness={alpha}}}");
        let sets = [camera[0], camera[1], &set].map(String::from);
        let e = ohd::config::load(SHADED, "test", &sets).map(|_| ()).expect_err(alpha);
        assert!(e.to_string().contains("detectors[0].estimator") && e.to_string().contains(words), "{e}");
    }
}

#[test]
fn surface_parameters_beyond_their_physical_range_are_refused_with_their_key() {
    let c = 299_792_458.0f64;
    // The sphere "ball" of SHADED spins about its centre: its fastest point moves at ω R.
    let r = 0.4e-3;
    let spin = |w: f64| format!("opaque.0.angular_velocity_rad_per_s=[0, {w:e}, 0]");
    for (sets, key, words) in [
        (
            vec!["bottom.surface={ type = \"conductor\", n = 1e-100, k = 1 }".to_string()],
            "bottom.surface.n",
            "= 1e-100: expected a metal's refractive index in [0.001, 10000]",
        ),
        (
            vec!["bottom.surface={ type = \"conductor\", n = 1e155, k = 1 }".to_string()],
            "bottom.surface.n",
            "[0.001, 10000]",
        ),
        (
            vec!["bottom.surface={ type = \"conductor\", n = 1, k = 1e155 }".to_string()],
            "bottom.surface.k",
            "= 1e155: expected an extinction coefficient in [0, 10000]",
        ),
        (vec!["bottom.surface={ type = \"conductor\", n = 1, k = -1 }".to_string()], "bottom.surface.k", "[0, 10000]"),
        (
            vec!["bottom.velocity_m_per_s=[1.7e308, 0, 0]".to_string()],
            "bottom.velocity_m_per_s",
            "= [1.7e308, 0, 0] m/s: expected a finite speed below the speed of light, |v| < c = 299792458 m/s",
        ),
        (
            vec!["bottom.velocity_m_per_s=[0, 299792458, 0]".to_string()],
            "bottom.velocity_m_per_s",
            "below the speed of light",
        ),
        (
            vec!["bottom.angular_velocity_rad_per_s=[0, 0, 1e308]".to_string()],
            "bottom.angular_velocity_rad_per_s",
            "below the speed of light",
        ),
        (
            vec!["bottom.angular_velocity_rpm=[0, 0, 600]".to_string(), "bottom.center_m=[1e308, 0, 0]".to_string()],
            "bottom.center_m",
            "= [1e308, 0, 0] m: the surface's fastest point",
        ),
        // A plane rotating at 3·10⁵ rad/s moves at c 1 km from its axis.
        (
            vec!["bottom.angular_velocity_rad_per_s=[0, 0, 3e5]".to_string()],
            "bottom.angular_velocity_rad_per_s",
            "within 1000 m of the z axis",
        ),
    ] {
        let sets: Vec<&str> = sets.iter().map(String::as_str).collect();
        let e = ohd::config::load(FLOOR, "test", &sets.iter().map(|s| s.to_string()).collect::<Vec<_>>())
            .map(|_| ())
            .expect_err(key);
        let text = e.to_string();
        assert!(text.contains(key) && text.contains(words), "{sets:?}: {text}");
    }
    // The edges: a metal at the ends of the range, a floor at 2.9·10⁵ rad/s, a ball whose surface
    // moves just below c, and just above.
    for set in [
        "bottom.surface={ type = \"conductor\", n = 1e-3, k = 1e4 }",
        "bottom.surface={ type = \"conductor\", n = 1e4, k = 0 }",
        "bottom.angular_velocity_rad_per_s=[0, 0, 2.9e5]",
    ] {
        assert!(ohd::config::load(FLOOR, "test", &[set.to_string()]).is_ok(), "{set}");
    }
    assert!(ohd::config::load(SHADED, "test", &[spin(c / r * (1.0 - 1e-6))]).is_ok());
    let e = ohd::config::load(SHADED, "test", &[spin(c / r * (1.0 + 1e-6))]).map(|_| ()).expect_err("spin");
    assert!(
        e.to_string().contains("opaque[0].angular_velocity_rad_per_s") && e.to_string().contains("of the solid"),
        "{e}"
    );
    let e = ohd::config::load(SHADED, "test", &["opaque.0.velocity_m_per_s=[3e8, 0, 0]".to_string()])
        .map(|_| ())
        .expect_err("v");
    assert!(
        e.to_string().contains("opaque[0].velocity_m_per_s: = [300000000, 0, 0] m/s: expected a finite speed below"),
        "{e}"
    );
}

#[test]
fn metal_tables_take_their_end_points_and_say_so() {
    // Copper and gold at 413.3 and 1937 nm, aluminium at 413.28 and 4132.8 nm: their table's ends
    // (1937 nm and 4132.8 nm were refused, by a message stating a range that held them).
    let metal = |m: &str| format!("bottom.surface={{ type = \"conductor\", material = \"{m}\" }}");
    for (m, inside, outside, range) in [
        ("copper", ["413.3", "1937"], ["413.29", "1937.01"], "413.3 … 1937 nm"),
        ("gold", ["413.3", "1937"], ["413.29", "1937.01"], "413.3 … 1937 nm"),
        ("aluminium", ["413.28", "4132.8"], ["413.27", "4132.81"], "413.28 … 4132.8 nm"),
    ] {
        for w in inside {
            let sets = [metal(m), format!("source.wavelength_nm={w}")];
            assert!(ohd::config::load(FLOOR, "test", &sets).is_ok(), "{m} at {w} nm");
        }
        for w in outside {
            let sets = [metal(m), format!("source.wavelength_nm={w}")];
            let e = ohd::config::load(FLOOR, "test", &sets).map(|_| ()).expect_err(w);
            let want = format!("covers {range} (both included), not the source's {w} nm");
            assert!(
                e.to_string().contains("bottom.surface.material") && e.to_string().contains(&want),
                "{e}\nwanted: {want}"
            );
        }
    }
}
