//! The speed-of-light reference of issue 7: a minimal hand-written random walk on the van de Hulst
//! slab of `validation/vdh_slab.toml` (μa = 10 /cm, μs = 90 /cm, HG g = 0.75, 0.2 mm thick, n = 1
//! everywhere, normal pencil beam), with no configuration and no tallies but the event count and
//! the reflected, transmitted and absorbed weights; and `ohd` on the same scene, one thread, run
//! alternately in one process so that both see the same machine load.
//!
//! ```sh
//! cargo run --release --example bare_walk -- --photons 2000000 --rounds 7     # interleaved A B A B …
//! cargo run --release --example bare_walk -- --mode bare --photons 50000      # one side only (callgrind)
//! ```
//!
//! What the bare walk is, written as a competent engineer would write it for speed (and not
//! sharing code with the simulator):
//!
//! * one xoshiro256++ generator for the whole run (the same kind of generator ohd uses,
//!   `rand::rngs::Xoshiro256PlusPlus`, but seeded once: ohd seeds a fresh stream per path so that
//!   every path can be replayed independently of threads);
//! * exponential free paths from `rand_distr::Exp1` (the ziggurat ohd uses too; `−ln u` would make
//!   the reference slower);
//! * the textbook HG inverse `cos θ = (1 + g² − ((1 − g²)/(1 − g + 2gξ))²)/(2g)`;
//! * the azimuth's cosine and sine by rejection from the square (von Neumann 1951: a point in the
//!   unit disk, its doubled angle), both coordinates from one 64-bit draw, no `sin_cos`;
//! * MCML's direction update (Wang, Jacques & Zheng 1995), full 3-D position;
//! * implicit capture (absorption weighting) and Russian roulette below weight 10⁻⁴ with survival
//!   0.1, and the cap of 10⁶ events per photon: ohd's defaults, so that the event counts compare.
//!   An event is a real collision (ohd's `scattering_events`).
//!
//! It prints Rd and Tt with their standard errors (they must match ohd's within σ, and van de
//! Hulst's 0.09739 and 0.66096) and events per second for both.

use std::time::Instant;

use ohd::experiment::Silent;
use rand::rngs::Xoshiro256PlusPlus;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Exp1};

const MU_A: f64 = 1_000.0; // 10 /cm in /m
const MU_S: f64 = 9_000.0; // 90 /cm
const G: f64 = 0.75;
const THICKNESS: f64 = 2e-4; // 0.2 mm
const ROULETTE_THRESHOLD: f64 = 1e-4;
const ROULETTE_SURVIVAL: f64 = 0.1;
const MAX_EVENTS: u64 = 1_000_000;

/// What a run produced.
#[derive(Debug, Default, Clone, Copy)]
struct Tally {
    photons: u64,
    events: u64,
    /// Rd, Tt and the absorbed fraction, each (mean, standard error).
    rd: (f64, f64),
    tt: (f64, f64),
    absorbed: (f64, f64),
    seconds: f64,
}

/// Mean and standard error of a per-photon score from its sum and sum of squares.
fn mean_se(n: u64, s: f64, s2: f64) -> (f64, f64) {
    let n = n as f64;
    let m = s / n;
    (m, ((s2 / n - m * m) / (n - 1.0)).max(0.0).sqrt())
}

#[inline(always)]
fn uniform(rng: &mut Xoshiro256PlusPlus) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / 9_007_199_254_740_992.0)
}

/// The bare walk: `photons` photons from one generator seeded with `seed`.
fn bare_walk(photons: u64, seed: u64) -> Tally {
    let start = Instant::now();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mu_t = MU_A + MU_S;
    let inv_mu_t = 1.0 / mu_t;
    let albedo = MU_S / mu_t;
    let (g2, inv_2g) = (G * G, 0.5 / G);
    let (mut reflected, mut reflected2, mut transmitted, mut transmitted2) = (0.0, 0.0, 0.0, 0.0);
    let (mut absorbed, mut absorbed2, mut all_events) = (0.0, 0.0, 0u64);
    for _ in 0..photons {
        let (mut x, mut y, mut z) = (0.0f64, 0.0f64, 0.0f64);
        let (mut ux, mut uy, mut uz) = (0.0f64, 0.0f64, 1.0f64);
        let mut w = 1.0f64;
        let mut events = 0u64;
        let mut deposit = 0.0;
        loop {
            let s: f64 = Exp1.sample(&mut rng);
            let s = s * inv_mu_t;
            let z_new = z + s * uz;
            if z_new < 0.0 {
                reflected += w;
                reflected2 += w * w;
                break;
            }
            if z_new >= THICKNESS {
                transmitted += w;
                transmitted2 += w * w;
                break;
            }
            x += s * ux;
            y += s * uy;
            z = z_new;
            events += 1;
            deposit += w * (1.0 - albedo);
            w *= albedo;
            // Henyey–Greenstein deflection.
            let tmp = (1.0 - g2) / (1.0 - G + 2.0 * G * uniform(&mut rng));
            let cos_t = ((1.0 + g2 - tmp * tmp) * inv_2g).clamp(-1.0, 1.0);
            let sin_t = (1.0 - cos_t * cos_t).sqrt();
            // Azimuth: a point in the unit disk by rejection, its doubled angle.
            // Both coordinates from the two 32-bit halves of one draw, as signed integers
            // (uniform on [−2³¹, 2³¹)): one generator call per trial.
            let (cos_p, sin_p) = loop {
                let r = rng.next_u64();
                let (a, b) = (f64::from((r >> 32) as i32), f64::from(r as i32));
                let r2 = a * a + b * b;
                if r2 <= 4_611_686_018_427_387_904.0 && r2 > 0.0 {
                    let inv = 1.0 / r2;
                    break ((a * a - b * b) * inv, 2.0 * a * b * inv);
                }
            };
            // MCML's rotation.
            if uz.abs() > 0.99999 {
                ux = sin_t * cos_p;
                uy = sin_t * sin_p;
                uz = if uz > 0.0 { cos_t } else { -cos_t };
            } else {
                let temp = (1.0 - uz * uz).sqrt();
                let inv = 1.0 / temp;
                let nx = sin_t * (ux * uz * cos_p - uy * sin_p) * inv + ux * cos_t;
                let ny = sin_t * (uy * uz * cos_p + ux * sin_p) * inv + uy * cos_t;
                uz = -sin_t * cos_p * temp + uz * cos_t;
                ux = nx;
                uy = ny;
            }
            if events >= MAX_EVENTS {
                break;
            }
            if w < ROULETTE_THRESHOLD {
                if uniform(&mut rng) < ROULETTE_SURVIVAL {
                    w /= ROULETTE_SURVIVAL;
                } else {
                    break;
                }
            }
        }
        all_events += events;
        absorbed += deposit;
        absorbed2 += deposit * deposit;
        std::hint::black_box((x, y));
    }
    Tally {
        photons,
        events: all_events,
        rd: mean_se(photons, reflected, reflected2),
        tt: mean_se(photons, transmitted, transmitted2),
        absorbed: mean_se(photons, absorbed, absorbed2),
        seconds: start.elapsed().as_secs_f64(),
    }
}

/// ohd on `validation/vdh_slab.toml`, one thread, `photons` paths, seed `seed`.
fn ohd_run(photons: u64, seed: u64) -> Tally {
    let sets = [format!("run.samples={photons}"), format!("run.seed={seed}"), "run.threads=1".to_string()];
    let (_, exp) = ohd::config::load(include_str!("../validation/vdh_slab.toml"), "vdh_slab", &sets).expect("valid");
    let out = exp.run(&Silent);
    let (mean, se) = (out.estimates.mean(), out.estimates.stderr());
    let at = |s: ohd::detect::Scalar| (mean[s as usize], se[s as usize]);
    Tally {
        photons: exp.plan.samples(),
        events: out.stats.scattering_events,
        rd: at(ohd::detect::Scalar::ReflectanceDiffuse),
        tt: at(ohd::detect::Scalar::TransmittanceTotal),
        absorbed: at(ohd::detect::Scalar::AbsorbedFraction),
        seconds: out.wall_seconds,
    }
}

/// One side of the comparison: `(photons, seed)` to its tally.
type Side = fn(u64, u64) -> Tally;

fn stats(v: &mut [f64]) -> (f64, f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[0], v[v.len() / 2], v[v.len() - 1])
}

fn main() {
    let mut photons = 2_000_000u64;
    let mut rounds = 5usize;
    let mut mode = "both".to_string();
    let mut seed = 1u64;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().unwrap_or_else(|| panic!("{a} needs a value"));
        match a.as_str() {
            "--photons" => photons = value().parse().expect("--photons N"),
            "--rounds" => rounds = value().parse().expect("--rounds N"),
            "--mode" => mode = value(),
            "--seed" => seed = value().parse().expect("--seed N"),
            _ => panic!("unknown argument {a} (--photons N, --rounds N, --mode bare|ohd|both, --seed N)"),
        }
    }
    let sides: Vec<(&str, Side)> = match mode.as_str() {
        "bare" => vec![("bare", bare_walk)],
        "ohd" => vec![("ohd", ohd_run)],
        "both" => vec![("bare", bare_walk), ("ohd", ohd_run)],
        _ => panic!("--mode bare|ohd|both"),
    };
    let mut rates: Vec<Vec<f64>> = vec![Vec::new(); sides.len()];
    let mut secs: Vec<Vec<f64>> = vec![Vec::new(); sides.len()];
    let mut last = vec![Tally::default(); sides.len()];
    for round in 0..rounds {
        for (k, (_, f)) in sides.iter().enumerate() {
            let t = f(photons, seed + round as u64);
            rates[k].push(t.events as f64 / t.seconds);
            secs[k].push(t.seconds);
            last[k] = t;
        }
    }
    println!("{photons} photons per run, {rounds} rounds, alternating; one thread");
    println!(
        "| code | events/photon | M events/s min / median / max | s min / median / max | Rd ± σ | Tt ± σ | absorbed ± σ |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut medians = Vec::new();
    for (k, (name, _)) in sides.iter().enumerate() {
        let t = last[k];
        let ((r, rse), (tt, tse), (ab, abse)) = (t.rd, t.tt, t.absorbed);
        let (a, b, c) = stats(&mut rates[k]);
        let (sa, sb, sc) = stats(&mut secs[k]);
        medians.push(b);
        println!(
            "| {name} | {:.4} | {:.2} / {:.2} / {:.2} | {sa:.3} / {sb:.3} / {sc:.3} | {r:.5} ± {rse:.5} | {tt:.5} ± {tse:.5} | {ab:.5} ± {abse:.5} |",
            t.events as f64 / t.photons as f64,
            a / 1e6,
            b / 1e6,
            c / 1e6,
        );
    }
    if medians.len() == 2 {
        println!("ohd / bare events/s (medians): {:.3}", medians[1] / medians[0]);
    }
}
