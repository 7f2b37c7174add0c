//! Heterogeneous media: density grids and ramps, majorant grids, delta tracking over majorant
//! segments and ratio tracking. Tolerances are in standard errors of the estimates; seeds are
//! fixed.

use crate::support::run::experiment;
use crate::support::stats::ks_test;

use glam::DVec3;
use ohd::config::resolve::grid_heterogeneity;
use ohd::detect::Scalar;
use ohd::experiment::{Experiment, RunOutput, Silent};
use ohd::flow::VelocityField;
use ohd::medium::density::{CellSize, Interpolation, MajorantKind, MajorantSpec, Placement, Ramp};
use ohd::medium::grid::{IndexTransform, VoxelGrid};
use ohd::medium::{Density, Heterogeneity, Layer, Medium, Scene};
use ohd::phase::PhaseFunction;
use ohd::sampling::{PathRng, Purpose};
use ohd::transport::tracking::{Flight, LayerRay, Tracking, free_flight, ratio_transmittance};

/// p-value below which a KS test fails (fixed seeds: never re-rolled).
const P_MIN: f64 = 1e-3;
/// Largest |z| two estimates of the same quantity may differ by.
const Z_MAX: f64 = 4.0;

/// A slab of 0.5 mm with μa = 1 /mm, μs = 9 /mm, g = 0.75, n = 1 in and out (as van de Hulst's
/// slab, thicker); a camera scored by next-event estimation when `camera` is set.
fn slab(camera: bool) -> String {
    let mut s = String::from(
        r#"
schema_version = 1
name = "grid_slab"
[run]
samples = 100_000
seed = 5
batches = 20
[source]
wavelength_nm = 633
profile = "pencil"
position_mm = [0, 0, 0]
direction = [0, 0, 1]
[ambient]
n_above = 1.0
n_below = 1.0
[media.slab]
sigma_a_per_mm = 1
sigma_s_per_mm = 9
phase = { type = "hg", g = 0.75 }
[[layers]]
name = "slab"
thickness_mm = 0.5
n = 1.0
medium = "slab"
"#,
    );
    if camera {
        s.push_str(
            r#"
[[detectors]]
name = "camera"
next_event = true
area = { type = "rect", size_mm = [4, 4] }
acceptance_half_angle_deg = 10
"#,
        );
    }
    s
}

fn run(exp: &Experiment) -> RunOutput {
    exp.run(&Silent)
}

fn scalar(out: &RunOutput, s: Scalar) -> (f64, f64) {
    (out.estimates.mean()[s as usize], out.estimates.stderr()[s as usize])
}

fn power(exp: &Experiment, out: &RunOutput, d: usize) -> (f64, f64) {
    let i = out.layout.detectors[d].power;
    let _ = exp;
    (out.estimates.mean()[i], out.estimates.stderr()[i])
}

fn z(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0) / (a.1 * a.1 + b.1 * b.1).sqrt()
}

/// A 0.05 mm lattice over ±`half` mm laterally and the slab's depth, filled by `f(world point)`,
/// with background `bg`.
fn lattice(half_mm: f64, depth_mm: f64, bg: f32, f: impl Fn(DVec3) -> f32) -> VoxelGrid<f32> {
    let h = 0.05e-3;
    let n = (half_mm * 1e-3 / h).round() as i32;
    let nz = (depth_mm * 1e-3 / h).round() as usize + 1;
    let t = IndexTransform { voxel_size: DVec3::splat(h), translation: DVec3::ZERO };
    let mut g = VoxelGrid::new([-n, -n, 0], [2 * n as usize + 1, 2 * n as usize + 1, nz], bg, t);
    for k in 0..nz as i32 {
        for j in -n..=n {
            for i in -n..=n {
                g.set([i, j, k], f(t.to_world(DVec3::new(i as f64, j as f64, k as f64))));
            }
        }
    }
    g
}

/// Give the slab's medium the density `grid`.
fn with_grid(mut exp: Experiment, grid: VoxelGrid<f32>, spec: MajorantSpec) -> Experiment {
    let h = grid_heterogeneity("media.slab.density", grid, None, Placement::default(), Interpolation::Trilinear, spec)
        .expect("grid density");
    let m = exp.scene.layers[0].medium;
    exp.scene.media[m].set_heterogeneity(h);
    exp.scene.update_layers();
    assert!(exp.scene.layers[0].heterogeneous);
    exp
}

#[test]
fn a_constant_density_grid_equals_the_homogeneous_medium() {
    let text = slab(true);
    let homogeneous = experiment(&text, &[]);
    let reference = run(&homogeneous);
    // Density 1 on the lattice and outside it: every majorant cell is exact (no null collision,
    // no lookup) — and with the majorants doubled every tentative collision looks the density up.
    for (label, sets) in [("exact", vec![]), ("inflated", vec!["run.tracking = \"delta\"", "run.majorant_scale = 2"])] {
        let grid = lattice(1.0, 0.5, 1.0, |_| 1.0);
        let exp = with_grid(experiment(&text, &sets), grid, MajorantSpec::default());
        let out = run(&exp);
        for s in [Scalar::ReflectanceDiffuse, Scalar::TransmittanceTotal, Scalar::AbsorbedFraction] {
            let (a, b) = (scalar(&out, s), scalar(&reference, s));
            let zz = z(a, b);
            println!("{label} {s:?}: grid {:.5} ± {:.5}, homogeneous {:.5} ± {:.5}, z = {zz:.2}", a.0, a.1, b.0, b.1);
            assert!(zz.abs() < Z_MAX, "{label} {s:?}: z = {zz:.2}");
        }
        let (a, b) = (power(&exp, &out, 0), power(&homogeneous, &reference, 0));
        let zz = z(a, b);
        println!("{label} camera: grid {:.5e} ± {:.1e}, homogeneous {:.5e} ± {:.1e}, z = {zz:.2}", a.0, a.1, b.0, b.1);
        assert!(zz.abs() < Z_MAX, "{label} camera: z = {zz:.2}");
        if label == "exact" {
            assert_eq!(out.stats.null_collisions, 0);
        } else {
            assert!(out.stats.null_collisions > 0);
        }
    }
}

/// Sparse blobs: three spheres of density 3 (trilinear edges) in a density-0.05 haze, inside the
/// slab.
fn blobs(p: DVec3) -> f32 {
    let centres =
        [DVec3::new(0.0, 0.0, 0.15e-3), DVec3::new(0.2e-3, -0.1e-3, 0.3e-3), DVec3::new(-0.25e-3, 0.2e-3, 0.35e-3)];
    if centres.iter().any(|c| (p - *c).length() < 0.1e-3) { 3.0 } else { 0.05 }
}

#[test]
fn global_grid_and_inflated_majorants_agree() {
    let text = slab(true);
    let grid = || lattice(0.6, 0.5, 0.05, blobs);
    let cell = MajorantSpec { kind: MajorantKind::Grid, cell: CellSize::Voxels(2) };
    let global = MajorantSpec { kind: MajorantKind::Global, cell: CellSize::Voxels(2) };
    let runs = [
        ("grid", with_grid(experiment(&text, &[]), grid(), cell)),
        ("global", with_grid(experiment(&text, &[]), grid(), global)),
        (
            "grid x2",
            with_grid(experiment(&text, &["run.tracking = \"delta\"", "run.majorant_scale = 2"]), grid(), cell),
        ),
    ];
    let outs: Vec<(&str, RunOutput)> = runs.iter().map(|(l, e)| (*l, run(e))).collect();
    for (label, out) in &outs {
        println!("{label}: null collisions {}, real {}", out.stats.null_collisions, out.stats.scattering_events);
    }
    for i in 1..outs.len() {
        for s in [Scalar::ReflectanceDiffuse, Scalar::TransmittanceTotal, Scalar::AbsorbedFraction] {
            let (a, b) = (scalar(&outs[i].1, s), scalar(&outs[0].1, s));
            let zz = z(a, b);
            println!("{} vs grid {s:?}: {:.5} ± {:.5} vs {:.5} ± {:.5}, z = {zz:.2}", outs[i].0, a.0, a.1, b.0, b.1);
            assert!(zz.abs() < Z_MAX, "{} {s:?}: z = {zz:.2}", outs[i].0);
        }
        let (a, b) = (power(&runs[i].1, &outs[i].1, 0), power(&runs[0].1, &outs[0].1, 0));
        let zz = z(a, b);
        println!("{} vs grid camera: {:.5e} ± {:.1e} vs {:.5e} ± {:.1e}, z = {zz:.2}", outs[i].0, a.0, a.1, b.0, b.1);
        assert!(zz.abs() < Z_MAX, "{} camera: z = {zz:.2}", outs[i].0);
    }
    // The grid majorant wastes far fewer tentative collisions than the global one.
    let (grid_nulls, global_nulls) = (outs[0].1.stats.null_collisions, outs[1].1.stats.null_collisions);
    assert!(grid_nulls * 5 < global_nulls, "grid {grid_nulls} vs global {global_nulls}");
}

fn ramp_scene(kind: MajorantKind) -> (Scene, Ramp) {
    let mut m = Medium::new("ramp", 200.0, 800.0, PhaseFunction::Isotropic, VelocityField::Static);
    // From density 0.2 at z = 0.5 mm up to 3 at z = 2 mm (σt from 200 to 3000 /m), clamped.
    let ramp = Ramp::new(2, 0.5e-3, 2e-3, 0.2, 3.0, kind).unwrap();
    m.set_heterogeneity(Heterogeneity { density: Density::Ramp(ramp), albedo: None, info: Default::default() });
    let mut scene = Scene {
        layers: vec![Layer {
            name: "l".into(),
            z_top: 0.0,
            z_bottom: f64::INFINITY,
            n: 1.0,
            medium: 0,
            regions: vec![],
            majorant: 0.0,
            minorant: 0.0,
            heterogeneous: false,
            tau_above: 0.0,
            rough_faces: false,
            plain: true,
            obstructs_shadows: false,
            opaque: Vec::new(),
            face: ohd::surface::Interface::Smooth,
        }],
        regions: vec![],
        media: vec![m],
        n_above: 1.0,
        n_below: 1.0,
        lateral: None,
        bottom: None,
        opaque: Vec::new(),
        first_rough_face: 1,
        cycle: None,
    };
    scene.update_layers();
    (scene, ramp)
}

#[test]
fn ramp_collision_distances_follow_the_closed_form_optical_depth() {
    let dir = DVec3::new(0.3, -0.2, 1.0).normalize();
    let pos = DVec3::new(0.1e-3, 0.0, 0.1e-3);
    for (k, (kind, tracking)) in [
        (MajorantKind::Grid, Tracking::Analytic),
        (MajorantKind::Global, Tracking::Analytic),
        (MajorantKind::Grid, Tracking::Delta { majorant_scale: 2.0 }),
    ]
    .into_iter()
    .enumerate()
    {
        let (scene, ramp) = ramp_scene(kind);
        let mut rng = PathRng::new(17, Purpose::Test, k as u64, 0);
        let mut nulls = 0;
        let n = 200_000;
        let mut d: Vec<f64> = (0..n)
            .map(|_| {
                let dz = f64::INFINITY;
                match free_flight(
                    LayerRay { scene: &scene, layer: &scene.layers[0], pos, dir },
                    dz,
                    dir.z,
                    tracking,
                    &mut rng,
                    &mut nulls,
                ) {
                    Flight::Collision { t, medium } => {
                        assert_eq!(medium, 0);
                        t
                    }
                    Flight::Boundary { t } => t,
                }
            })
            .collect();
        let (ks, p) = ks_test(&mut d, |t| 1.0 - (-1000.0 * ramp.integral(pos, dir, 0.0, t)).exp());
        println!("ramp {kind:?} {tracking:?}: D = {ks:.5}, p = {p:.3}, null collisions {nulls} for {n} flights");
        assert!(p > P_MIN, "{kind:?} {tracking:?}: D = {ks:.5}, p = {p:.2e}");
    }
}

/// Mean and standard error of `n` ratio-tracking estimates.
fn mean_transmittance(scene: &Scene, pos: DVec3, dir: DVec3, t: f64, stream: u64, n: usize) -> (f64, f64) {
    let mut rng = PathRng::new(23, Purpose::Test, stream, 0);
    let (mut s1, mut s2) = (0.0, 0.0);
    for _ in 0..n {
        let tr = ratio_transmittance(scene, &scene.layers[0], pos, dir, t, &mut rng);
        assert!((0.0..=1.0).contains(&tr), "{tr}");
        s1 += tr;
        s2 += tr * tr;
    }
    let mean = s1 / n as f64;
    (mean, ((s2 / n as f64 - mean * mean) / (n as f64 - 1.0)).sqrt())
}

#[test]
fn ratio_tracking_through_a_ramp_gives_exp_minus_tau() {
    let pos = DVec3::new(0.0, 0.0, 2.5e-3);
    let dir = DVec3::new(0.2, 0.1, -1.0).normalize();
    let t = 2.4e-3 / -dir.z;
    for (k, kind) in [MajorantKind::Grid, MajorantKind::Global].into_iter().enumerate() {
        let (scene, ramp) = ramp_scene(kind);
        let want = (-1000.0 * ramp.integral(pos, dir, 0.0, t)).exp();
        let (mean, se) = mean_transmittance(&scene, pos, dir, t, k as u64, 200_000);
        let zz = (mean - want) / se;
        println!("ramp {kind:?}: T = {mean:.6} ± {se:.1e}, exp(−τ) = {want:.6}, z = {zz:.2}");
        assert!(zz.abs() < Z_MAX, "{kind:?}: z = {zz:.2}");
    }
}

#[test]
fn ratio_tracking_through_a_grid_gives_its_integral() {
    // Random voxel values; along a lattice line trilinear lookup is linear between voxels, so the
    // integral is the trapezoid sum. A tilted ray's integral by fine quadrature.
    let mut r = PathRng::new(29, Purpose::Test, 0, 0);
    let h = 0.1e-3;
    let t = IndexTransform { voxel_size: DVec3::splat(h), translation: DVec3::new(-1e-3, -1e-3, 0.0) };
    let mut g = VoxelGrid::new([0, 0, 0], [21, 21, 21], 0.0f32, t);
    for v in g.data.iter_mut() {
        *v = if r.uniform() < 0.5 { 0.0 } else { (r.uniform() * 4.0) as f32 };
    }
    let sigma_t = 1000.0;
    let values = g.clone();
    let mut m = Medium::new("g", 0.0, sigma_t, PhaseFunction::Isotropic, VelocityField::Static);
    let spec = MajorantSpec { kind: MajorantKind::Grid, cell: CellSize::Voxels(4) };
    m.set_heterogeneity(
        grid_heterogeneity("d", g, None, Placement::default(), Interpolation::Trilinear, spec).unwrap(),
    );
    let (mut scene, _) = ramp_scene(MajorantKind::Grid);
    scene.media = vec![m];
    scene.update_layers();
    // Along −z on the lattice line i = 7, j = 12, from z = 2.05 mm (outside) to the surface.
    let (i, j) = (7, 12);
    let pos = t.to_world(DVec3::new(i as f64, j as f64, 20.5));
    // Index z from 0 to 20 is linear between voxels; from 20 to 20.5 the value falls from v20
    // towards the zero background, v20·(1 − s), whose integral over s ∈ [0, 0.5] is 0.375·v20.
    let v = |k: i32| f64::from(values.get([i, j, k]));
    let integral = h * ((0..20).map(|k| 0.5 * (v(k) + v(k + 1))).sum::<f64>() + 0.375 * v(20));
    let want = (-sigma_t * integral).exp();
    let (mean, se) = mean_transmittance(&scene, pos, -DVec3::Z, pos.z, 10, 100_000);
    let zz = (mean - want) / se;
    println!("grid, lattice line: T = {mean:.6} ± {se:.1e}, exp(−τ) = {want:.6}, z = {zz:.2}");
    assert!(zz.abs() < Z_MAX, "z = {zz:.2}");
    // A tilted ray by midpoint quadrature of the density itself.
    let dir = DVec3::new(0.3, -0.25, -1.0).normalize();
    let pos = DVec3::new(-0.4e-3, 0.3e-3, 2.2e-3);
    let len = pos.z / -dir.z;
    let density = scene.media[0].density().unwrap();
    let steps = 200_000;
    let dt = len / steps as f64;
    let tau: f64 = (0..steps).map(|k| sigma_t * density.at(pos + (k as f64 + 0.5) * dt * dir) * dt).sum();
    let want = (-tau).exp();
    let (mean, se) = mean_transmittance(&scene, pos, dir, len, 11, 100_000);
    let zz = (mean - want) / se;
    println!("grid, tilted: T = {mean:.6} ± {se:.1e}, exp(−τ) = {want:.6} (τ = {tau:.4}), z = {zz:.2}");
    assert!(zz.abs() < Z_MAX, "z = {zz:.2}");
}

#[test]
fn an_albedo_grid_equals_layers_of_those_albedos() {
    // The slab (σt = 10 /mm) with density 1 and an albedo grid read by nearest lookup: 0.9 above
    // z = 0.225 mm (voxel 4.5 of 0.05 mm, so nearest lookup switches exactly there) and 0.3
    // below, against two homogeneous layers of σt 10 /mm with those albedos (index-matched, n = 1
    // throughout). Reflectance, transmittance, absorption and the NEE camera agree within Z_MAX.
    let text = slab(true);
    let two_layers = text.replace(
        "[[layers]]\nname = \"slab\"\nthickness_mm = 0.5\nn = 1.0\nmedium = \"slab\"\n",
        "[media.dark]\nsigma_a_per_mm = 7\nsigma_s_per_mm = 3\nphase = { type = \"hg\", g = 0.75 }\n\
         [[layers]]\nname = \"slab\"\nthickness_mm = 0.225\nn = 1.0\nmedium = \"slab\"\n\
         [[layers]]\nname = \"dark\"\nthickness_mm = 0.275\nn = 1.0\nmedium = \"dark\"\n",
    );
    assert_ne!(two_layers, text, "the slab's layer table was not found");
    let layered = experiment(&two_layers, &["run.samples = 200000"]);
    let reference = run(&layered);
    let density = lattice(1.0, 0.5, 1.0, |_| 1.0);
    let albedo = lattice(1.0, 0.5, 0.3, |p| if p.z < 0.225e-3 { 0.9 } else { 0.3 });
    let h = grid_heterogeneity(
        "media.slab.density",
        density,
        Some(albedo),
        Placement::default(),
        Interpolation::Nearest,
        MajorantSpec::default(),
    )
    .expect("grid density with albedo");
    let mut exp = experiment(&text, &["run.samples = 200000", "run.seed = 6"]);
    let m = exp.scene.layers[0].medium;
    exp.scene.media[m].set_heterogeneity(h);
    exp.scene.update_layers();
    let out = run(&exp);
    for s in [Scalar::ReflectanceDiffuse, Scalar::TransmittanceTotal, Scalar::AbsorbedFraction] {
        let (a, b) = (scalar(&out, s), scalar(&reference, s));
        let zz = z(a, b);
        println!("albedo grid {s:?}: {:.5} ± {:.5}, two layers {:.5} ± {:.5}, z = {zz:.2}", a.0, a.1, b.0, b.1);
        assert!(zz.abs() < Z_MAX, "{s:?}: z = {zz:.2}");
    }
    let (a, b) = (power(&exp, &out, 0), power(&layered, &reference, 0));
    let zz = z(a, b);
    println!("albedo grid camera: {:.5e} ± {:.1e}, two layers {:.5e} ± {:.1e}, z = {zz:.2}", a.0, a.1, b.0, b.1);
    assert!(zz.abs() < Z_MAX, "camera: z = {zz:.2}");
}
