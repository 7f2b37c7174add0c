//! Guided directions from an importance table (`run.importance = "guided"`; issue 36 item 2;
//! after the product of the phase function and the
//! incident importance that Herholz et al. 2019 sample): at a scattering event the forward path
//! draws [`CANDIDATES`] directions from the phase function, keeps one with probability
//! `w_j / Σw`, `w_j = I*(z, θ_j) + c` (the table's value in the candidate's polar band plus a
//! floor `c` = [`FLOOR`] × the candidates' mean value), and multiplies its weight by
//! `(Σw / K) / w_j` — resampled importance sampling (Talbot et al. 2005), whose estimate
//! `E[(Σw/K)/w_j · f(ω_j)] = E[(1/K) Σ f(ω_k)] = ∫ p f` is unbiased for any positive `w`: the
//! continuation leans toward the important directions the phase function offers, the weight
//! factor is at most `(1 + FLOOR)/FLOOR`, and a wrong table only costs variance.
//!
//! **Why not a mixture of the phase function with a band guide.** Built first: the continuation
//! drawn half from the phase function, half from a guide picking a polar band `b` with
//! probability ∝ `R̄(μ_in, b)·I*(z, b)` (`R̄` the phase function's azimuth-averaged
//! redistribution) and a direction uniform in the band, weighted by the mixture's density. In
//! g 0.9–0.95 media the band's uniform azimuth misses the phase function's lobe, so the factors
//! were bimodal (≈ 2 for phase draws, ≈ 0.1 for guide draws): on the control-variate retina
//! fixture the ROI spectra's wings came out with rare large scores (χ² 118 over 65 bins), and
//! on dcs_forearm guided everywhere the fibre's power read 1.0·10⁻⁴ in four seeds against
//! 3.3·10⁻⁴ (a tail the run's σ did not see). Candidates drawn from the phase function cannot
//! miss its lobe.
//!
//! The guide acts only where the table's importance varies over the directions the phase
//! function reaches ([`MIN_SPREAD`], from `R̄`, computed once per phase function of the scene and
//! table cell, [`Guide::new`]); elsewhere the continuation is the phase function's, unweighted.
//! Multiple importance weights of next-event estimation keep the phase function's density (any
//! partition of unity keeps both estimators unbiased).

use glam::DVec3;

use crate::detect::importance::{ANGLE_BINS, ImportanceGrid};
use crate::medium::Scene;
use crate::phase::PhaseFunction;
use crate::sampling::PathRng;

/// Directions drawn from the phase function per guided continuation.
pub const CANDIDATES: usize = 4;

/// The floor of the candidates' resampling weights, as a share of their mean value: bounds the
/// weight factor by `(1 + FLOOR)/FLOOR`.
pub const FLOOR: f64 = 0.25;

/// The guide acts at a vertex only where the table's importance, over the directions the phase
/// function reaches, has a relative variance `Σ R̄_b I_b² / (Σ R̄_b I_b)² − 1` of at least this:
/// where the importance hardly varies over them the guide cannot gain, and its candidates cost.
/// Measured (whole-process, 2 cores): guided everywhere (0), dcs_forearm at 2.5·10⁵ paths took
/// 28.9 s against 15.0 s from 2 for the same σ of the fibre's power (±3.6·10⁻⁶ and ±2.9·10⁻⁶),
/// and retina_ldh 54.1 s against 46.0 s with a worse pooled vessel M0+ (6.6 % against 4.7 %).
pub const MIN_SPREAD: f64 = 2.0;

/// Deflection-angle steps of the quadrature of the redistribution (uniform in θ over [0, π]:
/// 0.09°, fine enough for the forward peak of blood's Mie phase function).
const QUADRATURE_STEPS: usize = 2048;

/// Which phase function a redistribution belongs to.
#[derive(Debug, Clone, PartialEq)]
enum PhaseKey {
    Isotropic,
    HenyeyGreenstein(u64),
    Tabulated(usize),
}

impl PhaseKey {
    fn of(p: &PhaseFunction) -> Self {
        match p {
            PhaseFunction::Isotropic => PhaseKey::Isotropic,
            PhaseFunction::HenyeyGreenstein(hg) => PhaseKey::HenyeyGreenstein(hg.g().to_bits()),
            PhaseFunction::Tabulated(t) => PhaseKey::Tabulated(std::sync::Arc::as_ptr(t) as usize),
        }
    }
}

/// The guide of a scene's forward walk: the table's values, and per phase function of the scene
/// where the guide acts.
#[derive(Debug, Clone, PartialEq)]
pub struct Guide {
    /// Per bin of the table's grid: its value, 0 where it has none.
    value: Vec<f64>,
    /// Per phase function: per cell of the table (its bins but the angle) and incoming band,
    /// whether the guide acts there ([`MIN_SPREAD`]).
    acts: Vec<(PhaseKey, Vec<bool>)>,
}

impl Guide {
    /// The guide of `scene` from the table values `value` (per bin of its grid).
    pub fn new(scene: &Scene, value: &[f64]) -> Self {
        let value: Vec<f64> = value.iter().map(|&v| if v > 0.0 && v.is_finite() { v } else { 0.0 }).collect();
        let mut acts: Vec<(PhaseKey, Vec<bool>)> = Vec::new();
        for m in &scene.media {
            for pop in m.populations() {
                let key = PhaseKey::of(&pop.phase);
                if !acts.iter().any(|(k, _)| *k == key) {
                    let r = redistribution_matrix(&pop.phase);
                    let flags = value
                        .chunks_exact(ANGLE_BINS)
                        .flat_map(|cell| r.chunks_exact(ANGLE_BINS).map(move |row| spread(row, cell) >= MIN_SPREAD))
                        .collect();
                    acts.push((key, flags));
                }
            }
        }
        Guide { value, acts }
    }

    /// The guide's distribution of the continuation at a vertex in layer `li` at `pos`, reached
    /// along `dir_in`, of a scatterer of phase function `phase`, where the guide acts there
    /// (Open PGL's `VolumeSamplingDistribution::Init` for a vertex); `None` where it does not
    /// (the continuation is then the phase function's own draw, unweighted).
    #[inline]
    pub fn at<'a>(
        &'a self,
        grid: &ImportanceGrid,
        li: usize,
        pos: DVec3,
        dir_in: DVec3,
        phase: &'a PhaseFunction,
    ) -> Option<Directions<'a>> {
        let key = PhaseKey::of(phase);
        let (_, acts) = self.acts.iter().find(|(k, _)| *k == key)?;
        // The table's bins at this depth (and lateral bin) start at the bin of θ = 0.
        let base = grid.bin(li, pos, 1.0);
        acts[base + ImportanceGrid::angle_bin(dir_in.z)].then(|| Directions {
            values: &self.value[base..base + ANGLE_BINS],
            phase,
            dir_in,
        })
    }
}

/// The guide's distribution of a path's continuation at one vertex, in the shape of Open PGL's
/// `VolumeSamplingDistribution`: made for the vertex ([`Guide::at`]: the table's values per polar
/// band there, the particle's phase function, the direction the path arrived along), then sampled
/// ([`sample`](Self::sample)).
///
/// Unlike Open PGL's mixtures it offers no `pdf`: a direction kept by resampling [`CANDIDATES`]
/// phase-function draws has no closed-form density (the expectation over the other candidates of
/// `K·w/Σw` times the phase function's). The draw carries its weight factor instead, which keeps
/// the estimate unbiased whatever the values; an estimator balancing its own techniques against
/// this one weighs the continuation by the phase function's density (any partition of unity keeps
/// the estimators unbiased, as next-event estimation's escapes do here).
#[derive(Debug, Clone, Copy)]
pub struct Directions<'a> {
    values: &'a [f64],
    phase: &'a PhaseFunction,
    dir_in: DVec3,
}

impl Directions<'_> {
    /// A continuation `(cos θ, out, dir_in − out)` and the factor on the path's weight
    /// ([`resample`]), drawing its candidates with `draw` (the phase function's own sampling,
    /// [`super::event::deflect`]).
    #[inline]
    pub fn sample(&self, rng: &mut PathRng) -> (Candidate, f64) {
        let (dir, phase) = (self.dir_in, self.phase);
        resample(self.values, rng, |rng| {
            let (d, out, delta) = super::event::deflect(dir, phase, rng);
            (d.cos, out, delta)
        })
    }
}

/// One of [`CANDIDATES`] directions from the phase function: `(cos θ, out, dir − out)`.
pub type Candidate = (f64, DVec3, DVec3);

/// The guided continuation at a cell of values `values` (per polar band, [`Guide::at`]):
/// [`CANDIDATES`] directions drawn by `draw` from the phase function, one kept by resampling on
/// their bands' values (with the [`FLOOR`]); returns it and the path's weight factor.
#[inline]
pub fn resample(
    values: &[f64],
    rng: &mut PathRng,
    mut draw: impl FnMut(&mut PathRng) -> Candidate,
) -> (Candidate, f64) {
    let candidates: [Candidate; CANDIDATES] = std::array::from_fn(|_| draw(rng));
    let mut w = candidates.map(|(_, out, _)| values[ImportanceGrid::angle_bin(out.z)]);
    let mean = w.iter().sum::<f64>() / CANDIDATES as f64;
    if !(mean > 0.0 && mean.is_finite()) {
        // No value among them: the first, as the phase function drew it.
        return (candidates[0], 1.0);
    }
    w.iter_mut().for_each(|w| *w += FLOOR * mean);
    let total: f64 = w.iter().sum();
    let mut u = rng.uniform() * total;
    let mut k = CANDIDATES - 1;
    for (j, &wj) in w.iter().enumerate() {
        if u < wj {
            k = j;
            break;
        }
        u -= wj;
    }
    let factor = total / CANDIDATES as f64 / w[k];
    // Every candidate's value is at least `FLOOR·mean`, and their mean is `(1 + FLOOR)·mean`.
    debug_assert!(
        factor > 0.0 && factor <= (1.0 + FLOOR) / FLOOR * (1.0 + 1e-12),
        "the guide's factor {factor} outside (0, (1 + FLOOR)/FLOOR]"
    );
    (candidates[k], factor)
}

/// The relative variance of the importance `values` (one cell's, per band) over the
/// redistribution `r` (one incoming band's row): `Σ r I² / (Σ r I)² − 1`; −1 where the cell has
/// no value the phase function reaches.
fn spread(r: &[f64], values: &[f64]) -> f64 {
    let (mut first, mut second) = (0.0, 0.0);
    for (&r, &v) in r.iter().zip(values) {
        first += r * v;
        second += r * v * v;
    }
    if first > 0.0 && first.is_finite() { second / (first * first) - 1.0 } else { -1.0 }
}

/// `(cos θ_{b+1}, cos θ_b)`: the z-components bounding band `b`.
#[inline]
fn band_cos(b: usize) -> (f64, f64) {
    let w = std::f64::consts::PI / ANGLE_BINS as f64;
    ((w * (b + 1) as f64).cos(), (w * b as f64).cos())
}

/// `R̄[a · ANGLE_BINS + b]`: for a direction at the centre of band `a`, the probability that a
/// deflection drawn from `phase` (and a uniform azimuth) leaves it in band `b`. A midpoint
/// quadrature over the deflection angle γ (weights `2π p(cos γ) sin γ dγ`); at each γ the
/// outgoing `μ = μ_in cos γ + sin θ_in sin γ cos φ` over a uniform azimuth φ has the arcsine
/// distribution on `[c − r, c + r]`, whose share of each band is in closed form. Each row is
/// normalised to 1.
fn redistribution_matrix(phase: &PhaseFunction) -> Vec<f64> {
    let mut m = vec![0.0; ANGLE_BINS * ANGLE_BINS];
    let dg = std::f64::consts::PI / QUADRATURE_STEPS as f64;
    let weights: Vec<(f64, f64, f64)> = (0..QUADRATURE_STEPS)
        .map(|i| {
            let g = (i as f64 + 0.5) * dg;
            let (sin, cos) = g.sin_cos();
            (cos, sin, 2.0 * std::f64::consts::PI * phase.eval(cos) * sin * dg)
        })
        .collect();
    // Below μ = x: the share of the arcsine distribution about `c` of half-width `r`.
    let below = |x: f64, c: f64, r: f64| {
        if r <= 0.0 {
            if x > c { 1.0 } else { 0.0 }
        } else {
            1.0 - ((x - c) / r).clamp(-1.0, 1.0).acos() / std::f64::consts::PI
        }
    };
    for (a, row) in m.chunks_exact_mut(ANGLE_BINS).enumerate() {
        let theta = ImportanceGrid::angle(a);
        let (s_in, mu_in) = theta.sin_cos();
        for &(cos, sin, w) in &weights {
            let (c, r) = (mu_in * cos, s_in * sin);
            // Only the bands that [c − r, c + r] overlaps.
            let (first, last) =
                (ImportanceGrid::angle_bin((c + r).min(1.0)), ImportanceGrid::angle_bin((c - r).max(-1.0)));
            for (b, cell) in row.iter_mut().enumerate().take(last + 1).skip(first) {
                let (lo, hi) = band_cos(b);
                *cell += w * (below(hi, c, r) - below(lo, c, r));
            }
        }
        let total: f64 = row.iter().sum();
        if total > 0.0 {
            row.iter_mut().for_each(|v| *v /= total);
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::HenyeyGreenstein;

    /// The solid angle of band `b`, sr.
    fn band_solid_angle(b: usize) -> f64 {
        let (lo, hi) = band_cos(b);
        2.0 * std::f64::consts::PI * (hi - lo)
    }

    /// The redistribution of an isotropic phase function is each band's share of the sphere,
    /// whatever the incoming band; a forward-peaked one has the mean cosine `g·μ_in` (the
    /// azimuth-averaged HG's first moment).
    #[test]
    fn the_redistribution_has_the_bands_share_and_the_mean_cosine() {
        let iso = redistribution_matrix(&PhaseFunction::Isotropic);
        for a in [0, 17, 47] {
            for b in 0..ANGLE_BINS {
                let want = band_solid_angle(b) / (4.0 * std::f64::consts::PI);
                assert!((iso[a * ANGLE_BINS + b] - want).abs() < 1e-3 * want, "{a}→{b}");
            }
        }
        let g = 0.9;
        let hg = redistribution_matrix(&PhaseFunction::HenyeyGreenstein(HenyeyGreenstein::new(g).unwrap()));
        for a in [0, 10, 24, 40] {
            let mu_in = ImportanceGrid::angle(a).cos();
            let mean: f64 = (0..ANGLE_BINS)
                .map(|b| {
                    let (lo, hi) = band_cos(b);
                    hg[a * ANGLE_BINS + b] * 0.5 * (lo + hi)
                })
                .sum();
            // The bands' midpoints stand for their directions: within their half-width.
            assert!((mean - g * mu_in).abs() < 0.02, "band {a}: mean {mean:.4} against {:.4}", g * mu_in);
            let row_sum: f64 = hg[a * ANGLE_BINS..(a + 1) * ANGLE_BINS].iter().sum();
            assert!((row_sum - 1.0).abs() < 1e-12);
        }
    }

    /// Resampling keeps every expectation over the phase function (`E[factor · f(ω)] = ∫ p f`,
    /// here for `f` = 1 and `f = 1 + 3·max(−ω_z, 0)⁴`, sharply up) from several incoming
    /// directions, moves the draws toward the important band, and bounds the factor by
    /// `(1 + FLOOR)/FLOOR`.
    #[test]
    fn resampling_keeps_the_expectations_and_bounds_the_factor() {
        let phase = PhaseFunction::HenyeyGreenstein(HenyeyGreenstein::new(0.8).unwrap());
        // Importance rising steeply toward straight up (θ = π), none straight down.
        let values: Vec<f64> = (0..ANGLE_BINS).map(|b| if b == 0 { 0.0 } else { (0.2 * b as f64).exp() }).collect();
        let f = |out: DVec3| 1.0 + 3.0 * (-out.z).max(0.0).powi(4);
        let mut rng = PathRng::new(11, crate::sampling::Purpose::Test, 0, 0);
        let n = 100_000;
        for dir in [DVec3::Z, DVec3::new(0.6, 0.0, 0.8), DVec3::new(0.0, 0.8, -0.6), -DVec3::Z] {
            let draw = |rng: &mut PathRng| {
                let d = phase.sample(rng.uniform());
                let (c, s) = crate::sampling::warp::azimuth_i32(|| rng.pair_i32());
                let (out, delta) = crate::transport::event::scatter_direction(dir, d, c, s);
                (d.cos, out, delta)
            };
            // Sums of f, f² plain; of factor·f, its square, the factor, its square, guided.
            let (mut sums, mut up_plain, mut up_guided) = ([0.0; 6], 0, 0);
            for _ in 0..n {
                let (_, out, _) = draw(&mut rng);
                sums[0] += f(out);
                sums[1] += f(out).powi(2);
                up_plain += usize::from(out.z < 0.0);
                let ((_, out, _), factor) = resample(&values, &mut rng, draw);
                assert!(factor > 0.0 && factor <= (1.0 + FLOOR) / FLOOR + 1e-12, "factor {factor}");
                sums[2] += factor * f(out);
                sums[3] += (factor * f(out)).powi(2);
                sums[4] += factor;
                sums[5] += factor * factor;
                up_guided += usize::from(out.z < 0.0);
            }
            let nf = n as f64;
            let mean_sd = |s: f64, s2: f64| (s / nf, ((s2 / nf - (s / nf).powi(2)) / nf).sqrt());
            let ((plain, sp), (guided, sg), (one, so)) =
                (mean_sd(sums[0], sums[1]), mean_sd(sums[2], sums[3]), mean_sd(sums[4], sums[5]));
            let z = (guided - plain) / sp.hypot(sg);
            assert!(z.abs() < 4.0, "from {dir}: {guided:.4} ± {sg:.4} guided against {plain:.4} ± {sp:.4}");
            assert!((one - 1.0).abs() < 4.0 * so, "from {dir}: mean factor {one:.4} ± {so:.4}");
            assert!(up_guided >= up_plain, "from {dir}: {up_guided} draws up guided, {up_plain} plain");
        }
    }
}
