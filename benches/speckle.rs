//! Criterion benchmarks of single-window spectra: one Algorithm 2 window (random phases, Cauchy
//! frequencies for the broadened half of the lines, field, Hann window, FFT, |·|²) for N = 64 and
//! 512 samples at 39 kHz with 1e2, 1e4 and 1e5 lines, by the non-uniform FFT (`fast`) and by the
//! direct O(lines × N) sum (`direct`, up to 1e4 lines); and `BandKernel::eval` (M0+, M0−, M1 of one
//! line, 6–18.3 kHz band) per line for N = 64 and 512.
//!
//! `cargo bench -p ohd-benches --bench speckle -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use ohd::sampling::rng::{PathRng, Purpose};
use ohd::spectrum::{BandKernel, Line, Stft, Synthesizer, Window};

const FS: f64 = 39_000.0;

/// Two boxes (−8 ± 3 kHz, +11 ± 3 kHz, some lines aliased from ±50 kHz), every other line with a
/// 50 Hz Lorentzian half-width.
fn lines(count: usize) -> Vec<Line> {
    let mut rng = PathRng::new(1, Purpose::Test, 0, count as u64);
    (0..count)
        .map(|j| {
            let centre = [-8_000.0, 11_000.0, 50_000.0, -50_000.0][j % 4];
            Line {
                power: 1.0 / count as f64,
                frequency: centre + 3_000.0 * (2.0 * rng.uniform() - 1.0),
                gamma: if j % 2 == 0 { 0.0 } else { 50.0 },
            }
        })
        .collect()
}

fn algorithm2(c: &mut Criterion) {
    let mut g = c.benchmark_group("algorithm2_window");
    for n in [64usize, 512] {
        let stft = Stft::new(FS, n, Window::Hann).expect("valid STFT");
        for count in [100usize, 10_000, 100_000] {
            let ls = lines(count);
            let mut synth = Synthesizer::new(&stft);
            let mut out = vec![0.0; n];
            let mut window = 0u64;
            g.bench_function(format!("fast_N{n}_lines{count}"), |b| {
                b.iter(|| {
                    window += 1;
                    synth.periodogram(black_box(&ls), &mut PathRng::new(2, Purpose::Speckle, 0, window), &mut out);
                    black_box(out[n / 2])
                })
            });
            if count <= 10_000 {
                g.bench_function(format!("direct_N{n}_lines{count}"), |b| {
                    b.iter(|| {
                        window += 1;
                        synth.periodogram_direct(
                            black_box(&ls),
                            &mut PathRng::new(2, Purpose::Speckle, 0, window),
                            &mut out,
                        );
                        black_box(out[n / 2])
                    })
                });
            }
        }
    }
    g.finish();
}

fn band_eval(c: &mut Criterion) {
    let mut g = c.benchmark_group("band_kernel_eval");
    let ls = lines(1024);
    g.throughput(Throughput::Elements(ls.len() as u64));
    for n in [64usize, 512] {
        let stft = Stft::new(FS, n, Window::Hann).expect("valid STFT");
        let band = BandKernel::new(&stft, 6_000.0, 18_300.0).expect("non-empty band");
        g.bench_function(format!("N{n}_1024_lines"), |b| {
            b.iter(|| {
                let mut acc = 0.0;
                for l in black_box(&ls) {
                    let m = band.eval(l.frequency, l.gamma);
                    acc += m.m0_plus + m.m0_minus + m.m1;
                }
                black_box(acc)
            })
        });
    }
    g.finish();
}

criterion_group!(benches, algorithm2, band_eval);
criterion_main!(benches);
