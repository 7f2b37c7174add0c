//! Criterion benchmarks: the per-event kernel (phase sampling, azimuth, rotation, Doppler term),
//! a homogeneous free flight, and whole runs of the van de Hulst slab and the default vessel
//! scene on one thread. Throughput is reported per event or per photon.
//!
//! `cargo bench -p ohd-benches --bench transport`; the whole-process comparison with a numba Monte Carlo is
//! `python3 validation/bench_numba.py`.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::DVec3;
use ohd::experiment::Silent;
use ohd::phase::{HenyeyGreenstein, PhaseFunction};
use ohd::sampling::{PathRng, Purpose, warp};
use ohd::transport::event::{doppler_increment, scatter_direction};

/// One real scattering event as the walk does it: deflection, azimuth, rotation, Doppler term.
fn scatter_event(
    g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    name: &str,
    phase: &PhaseFunction,
    rng: &mut PathRng,
) {
    let v = DVec3::new(0.0, 0.0, 1e-3);
    let mut dir = DVec3::Z;
    let mut dldt = 0.0;
    g.bench_function(name, |b| {
        b.iter(|| {
            let d = phase.sample(rng.uniform());
            let (cos_phi, sin_phi) = warp::azimuth_i32(|| rng.pair_i32());
            let (out, delta) = scatter_direction(dir, d, cos_phi, sin_phi);
            dldt += doppler_increment(1.4, v, delta);
            dir = out;
            black_box(dldt)
        })
    });
}

fn event_kernel(c: &mut Criterion) {
    let mut g = c.benchmark_group("event");
    g.throughput(Throughput::Elements(1));
    let phase = PhaseFunction::HenyeyGreenstein(HenyeyGreenstein::new(0.9).unwrap());
    let mut rng = PathRng::new(1, Purpose::Test, 0, 0);
    scatter_event(&mut g, "scatter_hg_with_doppler", &phase, &mut rng);
    g.bench_function("free_path_exponential", |b| b.iter(|| black_box(rng.exponential())));
    g.bench_function("path_stream_seeding", |b| {
        let key = ohd::sampling::StreamKey::new(1, Purpose::Path, 3);
        let mut i = 0u64;
        b.iter(|| {
            i += 1;
            black_box(key.path(i).uniform())
        })
    });
    g.finish();
}

/// Drawing one deflection: closed-form HG against tabulated phase functions (2000 angles, alias
/// table), alone and inside the whole event kernel. The issue-3 target: tabulated ≤ 1.5× HG.
fn phase_sampling(c: &mut Criterion) {
    use ohd::mie::{MieSolution, angle_grid};
    use ohd::phase::TabulatedPhase;
    let mut g = c.benchmark_group("phase");
    g.throughput(Throughput::Elements(1));
    let hg = HenyeyGreenstein::new(0.9).unwrap();
    let theta = angle_grid(2000, 1.0);
    let values: Vec<f64> = theta.iter().map(|t| hg.eval(t.cos())).collect();
    let hg_table = TabulatedPhase::from_angles(&theta, &values, "hg").unwrap();
    let (n, k, x) = ohd::medium::relative_sphere(5.56e-6, 1.40, 5.445e-5, 1.345, 785e-9);
    let sol = MieSolution::new(n, k, x).unwrap();
    let theta = angle_grid(2000, x);
    let mut values = vec![0.0; theta.len()];
    sol.phase_function(&theta, &mut values);
    let rbc = TabulatedPhase::from_angles(&theta, &values, "rbc").unwrap();
    let phases = [
        ("hg", PhaseFunction::HenyeyGreenstein(hg)),
        ("table_hg_2000", PhaseFunction::Tabulated(hg_table.into())),
        ("table_rbc_mie_2000", PhaseFunction::Tabulated(rbc.into())),
    ];
    let mut rng = PathRng::new(1, Purpose::Test, 1, 0);
    for (name, phase) in &phases {
        g.bench_function(format!("sample_{name}"), |b| b.iter(|| black_box(phase.sample(rng.uniform()))));
    }
    for (name, phase) in &phases {
        scatter_event(&mut g, &format!("event_{name}"), phase, &mut rng);
    }
    g.finish();
}

fn whole_runs(c: &mut Criterion) {
    let mut g = c.benchmark_group("run_1_thread");
    g.sample_size(10);
    let vdh = include_str!("../validation/vdh_slab.toml");
    // The vdH slab as shipped, then the same slab paying for features it does not need, to measure
    // what "a scene pays only for what it uses" saves: a (tiny) uniform velocity compiles the
    // Doppler term in, a chirp the path-length term.
    let moving = "media.slab.velocity={ type = \"uniform\", velocity_mm_per_s = [0, 0, 1e-9] }";
    let chirp = "source.chirp={ bandwidth_ghz = 1, duration_us = 10 }";
    for (name, text, photons, extra) in [
        ("vdh_slab", vdh, 200_000u64, vec![]),
        ("vdh_slab_with_doppler", vdh, 200_000, vec![moving]),
        ("vdh_slab_with_doppler_and_length", vdh, 200_000, vec![moving, chirp]),
        ("default_vessel", ohd::DEFAULT_CONFIG, 20_000, vec![]),
    ] {
        let mut sets = vec![format!("run.samples={photons}"), "run.threads=1".to_string()];
        sets.extend(extra.iter().map(|s| s.to_string()));
        let (_, exp) = ohd::config::load(text, name, &sets).expect("valid config");
        g.throughput(Throughput::Elements(exp.plan.samples()));
        g.bench_function(name, |b| b.iter(|| black_box(exp.run(&Silent).stats.scattering_events)));
    }
    g.finish();
}

criterion_group!(benches, event_kernel, phase_sampling, whole_runs);
criterion_main!(benches);
