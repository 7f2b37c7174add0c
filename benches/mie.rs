//! Criterion benchmarks of the Mie code: building a 2000-angle phase table (solve + phase function
//! on `angle_grid(2000, 1e4)`) for one sphere at x = 1e4 and x = 100 (m = 1.33 − 1e-5i), the solve
//! alone, and the Marshall–Palmer rain ensemble at 1.55 µm (R = 5 mm/h, D = 0.05–6 mm, 1000 angles,
//! default 256 sizes, rayon's global pool).
//!
//! `cargo bench -p ohd-benches --bench mie`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use ohd::mie::{DEFAULT_SIZE_POINTS, EnsembleSpec, MieSolution, SizeDistribution, angle_grid, ensemble_optics};

fn phase_tables(c: &mut Criterion) {
    let mut g = c.benchmark_group("mie_phase_table_2000");
    let theta = angle_grid(2000, 1e4);
    for x in [1e4, 100.0] {
        g.bench_function(format!("x={x}"), |b| {
            let mut out = vec![0.0; theta.len()];
            b.iter(|| {
                let s = MieSolution::new(1.33, 1e-5, black_box(x)).expect("valid sphere");
                s.phase_function(&theta, &mut out);
                black_box(out[0])
            })
        });
        g.bench_function(format!("solve_only_x={x}"), |b| {
            b.iter(|| black_box(MieSolution::new(1.33, 1e-5, black_box(x)).expect("valid sphere").terms()))
        });
    }
    g.finish();
}

fn rain_ensemble(c: &mut Criterion) {
    let mut g = c.benchmark_group("mie_ensemble");
    g.sample_size(10);
    let spec = EnsembleSpec {
        n_particle: 1.3109,
        k_particle: 1.35e-4,
        n_medium: 1.0,
        wavelength: 1.55e-6,
        distribution: SizeDistribution::MarshallPalmer { rain_rate_mm_per_h: 5.0, d_min: 0.05e-3, d_max: 6e-3 },
        concentration: None,
        packing: None,
        size_points: DEFAULT_SIZE_POINTS,
    };
    let theta = angle_grid(1000, std::f64::consts::PI * 6e-3 / 1.55e-6);
    g.bench_function("marshall_palmer_R5_1550nm_1000_angles", |b| {
        b.iter(|| black_box(ensemble_optics(&spec, &theta).expect("valid ensemble").sigma_ext))
    });
    g.finish();
}

criterion_group!(benches, phase_tables, rain_ensemble);
criterion_main!(benches);
