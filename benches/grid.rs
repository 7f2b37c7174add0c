//! Sparse heterogeneous medium: null collisions and run time of delta/ratio tracking with the
//! majorant grid against one global majorant.
//!
//! The scene: a 128³ voxel grid (10 µm voxels, a 1.28 mm cube filling the top layer) holding
//! four vessels (cylinders of density 1, radius 50 µm, three along x at different depths and one
//! tilted), ≈ 2 % of the grid's volume, with blood-like optics (σs = 20 /mm, σa = 0.4 /mm,
//! g = 0.95) and nothing elsewhere; under it a homogeneous tissue layer that sends light back up;
//! a disk beam and a camera scored by next-event estimation (shadow rays cross the grid by ratio
//! tracking). One thread, 100 000 paths per configuration, the faster of two runs; an empty grid
//! gives the cost of the rest of the scene.
//!
//! `cargo bench -p ohd-benches --bench grid` (prints a table; not a criterion benchmark: one whole run per
//! configuration is what is compared).

use std::time::Instant;

use glam::DVec3;
use ohd::config::resolve::grid_heterogeneity;
use ohd::experiment::{Experiment, Silent};
use ohd::medium::density::{CellSize, Interpolation, MajorantKind, MajorantSpec, Placement};
use ohd::medium::grid::{IndexTransform, VoxelGrid};

const SCENE: &str = r#"
schema_version = 1
name = "sparse_vessels"
[run]
samples = 100_000
seed = 3
batches = 16
threads = 1
[source]
wavelength_nm = 785
profile = "disk"
radius_mm = 0.5
position_mm = [0, 0, -1]
direction = [0, 0, 1]
[media.vessels]
sigma_a_per_mm = 0.4
sigma_s_per_mm = 20
phase = { type = "hg", g = 0.95 }
[media.tissue]
sigma_a_per_mm = 0.05
sigma_s_per_mm = 10
phase = { type = "hg", g = 0.9 }
[[layers]]
name = "vessels"
thickness_mm = 1.28
n = 1.0
medium = "vessels"
[[layers]]
name = "tissue"
thickness_mm = 1
n = 1.0
medium = "tissue"
[[detectors]]
name = "camera"
next_event = true
area = { type = "rect", size_mm = [2, 2] }
acceptance_half_angle_deg = 10
"#;

/// Distance from `p` to the segment axis through `c` along unit `a`.
fn dist(p: DVec3, c: DVec3, a: DVec3) -> f64 {
    let d = p - c;
    (d - d.dot(a) * a).length()
}

fn vessels() -> (VoxelGrid<f32>, f64) {
    let h = 10e-6;
    let t = IndexTransform { voxel_size: DVec3::splat(h), translation: DVec3::new(-0.635e-3, -0.635e-3, 0.005e-3) };
    let mut g = VoxelGrid::new([0, 0, 0], [128, 128, 128], 0.0f32, t);
    let r = 50e-6;
    let axes = [
        (DVec3::new(0.0, -0.3e-3, 0.3e-3), DVec3::X),
        (DVec3::new(0.0, 0.1e-3, 0.6e-3), DVec3::X),
        (DVec3::new(0.0, 0.35e-3, 0.9e-3), DVec3::X),
        (DVec3::new(0.0, 0.0, 0.45e-3), DVec3::new(0.3, 1.0, 0.1).normalize()),
    ];
    let mut filled = 0usize;
    for k in 0..128 {
        for j in 0..128 {
            for i in 0..128 {
                let p = t.to_world(DVec3::new(i as f64, j as f64, k as f64));
                if axes.iter().any(|&(c, a)| dist(p, c, a) <= r) {
                    g.set([i, j, k], 1.0);
                    filled += 1;
                }
            }
        }
    }
    (g, filled as f64 / 128f64.powi(3))
}

fn experiment(grid: VoxelGrid<f32>, spec: MajorantSpec) -> (Experiment, f64) {
    let (_, mut exp) = ohd::config::load(SCENE, "bench", &[]).expect("scene");
    let t = Instant::now();
    let h =
        grid_heterogeneity("media.vessels.density", grid, None, Placement::default(), Interpolation::Trilinear, spec)
            .expect("grid");
    let build = t.elapsed().as_secs_f64();
    let m = exp.scene.layers[0].medium;
    exp.scene.media[m].set_heterogeneity(h);
    exp.scene.update_layers();
    (exp, build)
}

fn main() {
    let (grid, fill) = vessels();
    println!("128³ grid, vessels fill {:.2} % of it", 100.0 * fill);
    println!(
        "{:<16} {:>10} {:>14} {:>14} {:>10} {:>12} {:>14}",
        "majorant", "build s", "null coll.", "real coll.", "run s", "paths/s", "camera power"
    );
    let mut rows = Vec::new();
    let specs = [
        ("global", MajorantSpec { kind: MajorantKind::Global, cell: CellSize::Voxels(1) }),
        ("grid, 4 vox", MajorantSpec { kind: MajorantKind::Grid, cell: CellSize::Voxels(4) }),
        ("grid, 8 vox", MajorantSpec { kind: MajorantKind::Grid, cell: CellSize::Voxels(8) }),
        ("grid, 16 vox", MajorantSpec { kind: MajorantKind::Grid, cell: CellSize::Voxels(16) }),
        ("grid, 32 vox", MajorantSpec { kind: MajorantKind::Grid, cell: CellSize::Voxels(32) }),
    ];
    // What the rest of the scene costs: the same run with an empty grid (no collisions in the
    // top layer, every majorant cell 0, the DDA and shadow rays still walking it).
    let (empty, _) = experiment(VoxelGrid::new(grid.min, grid.dims, 0.0, grid.transform), MajorantSpec::default());
    let base = (0..2)
        .map(|_| {
            let t = Instant::now();
            empty.run(&Silent);
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min);
    println!("{:<16} {:>10} {:>14} {:>14} {base:>10.3}", "empty grid", "", "", "");
    for (label, spec) in specs {
        let (exp, build) = experiment(grid.clone(), spec);
        // The faster of two runs (the machine is shared).
        let mut secs = f64::INFINITY;
        let mut out = None;
        for _ in 0..2 {
            let t = Instant::now();
            out = Some(exp.run(&Silent));
            secs = secs.min(t.elapsed().as_secs_f64());
        }
        let out = out.unwrap();
        let i = out.layout.detectors[0].power;
        let (p, se) = (out.estimates.mean()[i], out.estimates.stderr()[i]);
        println!(
            "{label:<16} {build:>10.3} {:>14} {:>14} {secs:>10.3} {:>12.0} {:>9.4e} ± {:.1e}",
            out.stats.null_collisions,
            out.stats.scattering_events,
            exp.plan.samples() as f64 / secs,
            p,
            se
        );
        rows.push((label, out.stats.null_collisions, secs));
    }
    let (_, global_nulls, global_secs) = rows[0];
    for &(label, nulls, secs) in &rows[1..] {
        println!(
            "{label}: {:.1}× fewer null collisions, {:.2}× faster than global ({:.2}× on the time beyond the empty-grid run)",
            global_nulls as f64 / nulls.max(1) as f64,
            global_secs / secs,
            (global_secs - base) / (secs - base)
        );
    }
}
