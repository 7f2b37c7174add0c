//! Correlation outputs of a surface detector: the normalised field autocorrelation g1(τ), the
//! intensity autocorrelation g2(τ) = 1 + β|g1(τ)|² (diffuse correlation spectroscopy) and the
//! speckle contrast K(T) of exposure times T (laser speckle contrast imaging), for the detector's
//! total (its area: K over a spatial window is a detector over that window), optionally K for
//! every pixel of its image, and on an LDH camera all three per ROI.
//!
//! **Per path, exactly.** A detected path of weight `w`, Doppler beat frequency `f = (dl/dt)/λ0`
//! and Brownian sum `b = Σ D_k n_k² |Δ_k|²` ([`super::PathState::brownian`]) has the field
//! autocorrelation `exp(i2πfτ)·exp(−Γτ)` with `Γ = Σ D_k q_k² = (2π/λ0)² b` (the decay whose
//! Fourier transform is the Lorentzian of half-width [`super::BeatModel::brownian_hwhm`]); random
//! flow (a per-event velocity dispersion) is in `f`, drawn per path. The detector adds
//! `w·cos(2πfτ)e^{−Γτ}` and `w·sin(2πfτ)e^{−Γτ}` per delay τ (no spectrum binning), so that
//! `g1(τ) = Σ w e^{i2πfτ − Γτ} / Σ w`, the ensemble average over paths (Kim et al. 2025's path
//! integral; for Brownian media the correlation-transport form of Boas & Yodh 1997).
//!
//! **Normalised over the run.** The value of g1 is the ratio of the run's mean sums to its mean
//! detected power, and |g1|² (in g2 and K) is the ratio `(|S̄|² − σ²(S̄))/(P̄² − σ²(P̄))`, each square
//! less the estimated variance of its mean: the square of a mean is biased by that variance, which
//! for a detector seeing few paths is far above |g1|² itself (one path does not dephase: its
//! |g1| is e^{−Γτ}). `|S̄|² − σ²(S̄)` over B batches is exactly the mean of the cross-products
//! `S̄_i S̄_j*` of different batches (i ≠ j), so numerator and denominator are unbiased for |E S|²
//! and (E P)²; the ratio keeps a bias O(1/paths of the whole run), independent of the batch count
//! (test `correlation_does_not_depend_on_the_batch_count`). It is not clipped at 0 (clipping
//! biases K up where |g1|² ≈ 0). Normalising per batch, as a first version did, biased K over a
//! small window of `lsci_vessels` (artery, T = 10 ms) to 0.25, 0.29 and 0.38 with 16, 32 and 128
//! batches (σ 0.015), and per pixel toward √β.
//!
//! **Standard errors** by a delete-one-group jackknife: batch b is also tallied into group
//! `b mod GROUPS` (the sums and the power), and g1, g2 and K are recomputed from all groups but
//! one, each with the same unbiased squares taken over the groups (`Σ_{h≠h'} x_h x_h'`, the
//! groups being independent); `σ² = (G − 1)/G Σ (θ_(h) − θ̄)²` (Efron & Tibshirani 1993, An
//! Introduction to the Bootstrap, Eq. 11.5). It is the σ of the whole non-linear function (K of
//! the whole g1 curve) without its derivatives, and right with few paths per batch, where the
//! spread of per-batch ratios (the first σ) was 0.1–1.4 × the true one (test
//! `correlation_sigma_matches_closed_form_residuals_and_the_spread_of_seeds`). Where a replicate
//! has no positive P² estimate σ is NaN; with fewer than 3 batches, 0 as for any tally.
//!
//! **Per pixel** (`pixels`): each pixel keeps its own groups of sums and power (a batch records
//! into group 0's block, moved to its group's at the batch's end: no extra memory), and its K is
//! computed from its groups alone, with the same jackknife: unbiased whatever the paths per batch
//! (test `pixel_contrast_is_unbiased_and_does_not_depend_on_the_batch_count`). A pixel with too
//! few paths for a defined |g1|² (fewer than 3 groups, the unbiased P² or a replicate's not
//! positive) is NaN. Only K is written per pixel (g2 would cost delays × pixels more; LSCI reads K).
//! On an LDH camera every ROI is such a unit too (its paths those landing in its rectangle), with
//! g1, g2 and K written.
//!
//! **Speckle contrast** `K²(T) = (2β/T)∫₀ᵀ(1 − τ/T)|g1(τ)|²dτ` (Bandyopadhyay et al. 2005, Rev.
//! Sci. Instrum. 76, 093110, Eq. 5) is integrated over the tallied `|g1|²` on the τ grid, with
//! `|g1(0)|² = 1` as its first point (exact: g1 is normalised): between grid points `|g1|²` is
//! interpolated log-linearly (exponential in τ) and the weight `1 − τ/T` integrated exactly, so a
//! single-exponential `|g1|²` (a Brownian medium seen through one momentum transfer) is integrated
//! exactly, and a mixture of exponentials (diffuse light) with an error of 2·10⁻³ of K² at 8
//! points per decade (5·10⁻⁴ at 16) (test `contrast_quadrature_error_on_a_mixture`). Where `|g1|²` is not positive at
//! both ends of a piece (noise, or a zero of an oscillating Doppler g1) the piece is linear.

use super::{ImageSpec, Roi, detector_output, image_stack_output};
use crate::output::{Axis, Kind, Output, Registry, Slots};
use crate::stats::{BatchAccumulator, jackknife_variance};

pub use crate::stats::GROUPS;

/// What a detector correlates.
#[derive(Debug, Clone, PartialEq)]
pub struct CorrelationSpec {
    /// Delays τ (s), ascending and positive (log-spaced as configured).
    pub tau: Vec<f64>,
    /// Coherence factor β of g2 and K, in (0, 1].
    pub beta: f64,
    /// Exposure times T (s) of the speckle contrast, each within `(0, τ_max]`; may be empty.
    pub exposures: Vec<f64>,
    /// Also per pixel of the detector's image: the speckle contrast image (needs `exposures`).
    pub pixels: bool,
    /// Also g1, g2 and K per region of interest (an LDH camera's ROIs).
    pub rois: Vec<Roi>,
}

/// Where a detector's correlation tallies lie.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrelationLayout {
    /// Σ w cos, then Σ w sin, per τ (`2·taus`).
    pub sums: usize,
    /// The detector's sums and power per group of batches, `[group][re τ.., im τ.., power]`.
    pub groups: usize,
    /// g1: Re per τ, then Im per τ (set from the run's means by [`CorrelationSpec::finish_run`]).
    pub g1: usize,
    pub g2: usize,
    /// K per exposure time.
    pub contrast: usize,
    /// Per unit (the pixels if per pixel, then the ROIs), per group:
    /// `[group][unit][re τ.., im τ.., power]`; a batch records into group 0's block, moved to its
    /// own group's when it ends ([`CorrelationSpec::finish_batch`]).
    pub unit_groups: Option<usize>,
    /// The speckle contrast image, `[exposure][pixel]`.
    pub pixel_contrast: Option<usize>,
    /// Each ROI's g1 (re, im per τ), g2 and K, one after the other (`3·taus + exposures` each).
    pub roi_outputs: usize,
    pub taus: usize,
    /// Pixels with their own correlation (0 unless per pixel), and the units (pixels and ROIs).
    pub pixels: usize,
    pub units: usize,
}

impl CorrelationLayout {
    /// Numbers per unit (detector or pixel) and group: re and im per τ, then the power.
    fn unit(&self) -> usize {
        2 * self.taus + 1
    }
}

impl CorrelationSpec {
    /// Lay out detector `i`'s (`name`) correlation tallies from `reg`'s end and declare them
    /// (per pixel of `im` if asked for).
    pub fn declare(&self, i: usize, name: &str, im: Option<&ImageSpec>, reg: &mut Registry) -> CorrelationLayout {
        let (n, nt) = (self.tau.len(), self.exposures.len());
        let budget = Some((format!("detectors[{i}].correlation.points"), format!("= {n}")));
        let internal = |reg: &mut Registry, what: &str, len: usize, key: &Option<(String, String)>| {
            let start = reg.take(len);
            reg.declare(Output {
                budget_key: key.clone(),
                ..detector_output(i, format!("{name}.{what}"), Kind::Internal, Slots::contiguous(start, len), vec![len])
            });
            start
        };
        let tau = || Axis::file("tau_s", "s", format!("{name}_tau_s.npy"));
        let exposure = || Axis::file("exposure_s", "s", format!("{name}_exposure_s.npy"));
        let parts = || Axis::labels("part", vec!["real".into(), "imaginary".into()]);
        let sums = internal(reg, "correlation_sums", 2 * n, &budget);
        let groups = internal(reg, "correlation_groups", GROUPS * (2 * n + 1), &budget);
        let g1 = reg.take(2 * n);
        reg.declare(Output {
            file: format!("{name}_g1.npy"),
            undefined_nan: true,
            budget_key: budget.clone(),
            units: "1 (normalised field autocorrelation; row 0 real, row 1 imaginary part)",
            axes: vec![parts(), tau()],
            ..detector_output(
                i,
                format!("{name}.g1"),
                Kind::Curve,
                Slots { start: g1, rows: 2, stride: n, len: n },
                vec![2, n],
            )
        });
        let g2 = reg.take(n);
        reg.declare(Output {
            file: format!("{name}_g2.npy"),
            undefined_nan: true,
            primary: true,
            budget_key: budget.clone(),
            units: "1 (normalised intensity autocorrelation)",
            axes: vec![tau()],
            ..detector_output(i, format!("{name}.g2"), Kind::Curve, Slots::contiguous(g2, n), vec![n])
        });
        let contrast = reg.take(nt);
        if nt > 0 {
            reg.declare(Output {
                file: format!("{name}_speckle_contrast.npy"),
                undefined_nan: true,
                primary: true,
                units: "1 (speckle contrast K per exposure time)",
                axes: vec![exposure()],
                ..detector_output(
                    i,
                    format!("{name}.speckle_contrast"),
                    Kind::Curve,
                    Slots::contiguous(contrast, nt),
                    vec![nt],
                )
            });
        }
        let per_pixel = im.filter(|_| self.pixels && nt > 0);
        let pixels = per_pixel.map_or(0, |im| im.nx * im.ny);
        let units = pixels + self.rois.len();
        let pixel_key = Some((
            format!("detectors[{i}].correlation.pixels"),
            format!("= true ({pixels} pixels × {GROUPS} groups × ({n} delays × 2 + 1))"),
        ));
        let unit_groups = (units > 0).then(|| {
            let key = if pixels > 0 { &pixel_key } else { &budget };
            internal(reg, "unit_correlation_groups", GROUPS * units * (2 * n + 1), key)
        });
        let roi_outputs = reg.take(self.rois.len() * (3 * n + nt));
        for (r, roi) in self.rois.iter().enumerate() {
            let base = roi_outputs + r * (3 * n + nt);
            let what = [("g1", 0, 2, "1 (g1 of the ROI; row 0 real, row 1 imaginary part)"), ("g2", 2 * n, 1, "1")];
            for (w, off, rows, units) in what {
                reg.declare(Output {
                    file: format!("{name}_roi_{}_{w}.npy", roi.name),
                    undefined_nan: true,
                    budget_key: budget.clone(),
                    units,
                    axes: if rows == 2 { vec![parts(), tau()] } else { vec![tau()] },
                    ..detector_output(
                        i,
                        format!("{name}.roi_{}.{w}", roi.name),
                        Kind::Curve,
                        Slots { start: base + off, rows, stride: n, len: n },
                        if rows == 2 { vec![2, n] } else { vec![n] },
                    )
                });
            }
            if nt > 0 {
                reg.declare(Output {
                    file: format!("{name}_roi_{}_speckle_contrast.npy", roi.name),
                    undefined_nan: true,
                    units: "1 (speckle contrast K of the ROI per exposure time)",
                    axes: vec![exposure()],
                    ..detector_output(
                        i,
                        format!("{name}.roi_{}.speckle_contrast", roi.name),
                        Kind::Curve,
                        Slots::contiguous(base + 3 * n, nt),
                        vec![nt],
                    )
                });
            }
        }
        let mut pixel_contrast = None;
        if let Some(im) = per_pixel {
            let key = pixel_key;
            let c = reg.take(nt * pixels);
            reg.declare(Output {
                file: format!("{name}_speckle_contrast_image.npy"),
                undefined_nan: true,
                budget_key: key,
                units: "1 (speckle contrast K per exposure time and pixel; NaN: too few paths)",
                ..image_stack_output(i, format!("{name}.speckle_contrast_image"), im, nt, c).layered(exposure())
            });
            pixel_contrast = Some(c);
        }
        CorrelationLayout {
            sums,
            groups,
            g1,
            g2,
            contrast,
            unit_groups,
            pixel_contrast,
            roi_outputs,
            taus: n,
            pixels,
            units,
        }
    }

    /// Record a path of weight `w`, Doppler frequency `f` (Hz) and Brownian decay rate `rate`
    /// (`Γ`, s⁻¹), landed at `(x, y)` of the detector plane, in image pixel `pixel`.
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        lay: &CorrelationLayout,
        acc: &mut [f64],
        w: f64,
        f: f64,
        rate: f64,
        pixel: Option<usize>,
        (x, y): (f64, f64),
    ) {
        let n = lay.taus;
        if let Some(ug) = lay.unit_groups {
            for (r, roi) in self.rois.iter().enumerate() {
                if roi.contains(x, y) {
                    self.add(acc, ug + lay.unit() * (lay.pixels + r), w, f, rate);
                }
            }
        }
        let px = lay.unit_groups.zip(pixel.filter(|_| lay.pixels > 0)).map(|(s, p)| s + lay.unit() * p);
        if let Some(p) = px {
            acc[p + 2 * n] += w;
        }
        let omega = std::f64::consts::TAU * f;
        for (k, &tau) in self.tau.iter().enumerate() {
            let decay = if rate > 0.0 { w * (-rate * tau).exp() } else { w };
            let (re, im) = if omega != 0.0 {
                let (s, c) = (omega * tau).sin_cos();
                (decay * c, decay * s)
            } else {
                (decay, 0.0)
            };
            acc[lay.sums + k] += re;
            acc[lay.sums + n + k] += im;
            if let Some(p) = px {
                acc[p + k] += re;
                acc[p + n + k] += im;
            }
        }
    }

    /// Add a path to one unit's block at `o` (`[re τ.., im τ.., power]`).
    fn add(&self, acc: &mut [f64], o: usize, w: f64, f: f64, rate: f64) {
        let n = self.tau.len();
        acc[o + 2 * n] += w;
        let omega = std::f64::consts::TAU * f;
        for (k, &tau) in self.tau.iter().enumerate() {
            let decay = if rate > 0.0 { w * (-rate * tau).exp() } else { w };
            let (s, c) = (omega * tau).sin_cos();
            acc[o + k] += decay * c;
            acc[o + n + k] += decay * s;
        }
    }

    /// File a finished batch (number `batch` of the run) under its group: the detector's sums and
    /// power (slot `power`) copied into the group's block, the pixels' block moved there.
    pub fn finish_batch(&self, lay: &CorrelationLayout, acc: &mut [f64], power: usize, batch: u64) {
        let (n, u) = (lay.taus, lay.unit());
        let g = (batch % GROUPS as u64) as usize;
        let block = lay.groups + g * u;
        acc.copy_within(lay.sums..lay.sums + 2 * n, block);
        acc[block + 2 * n] = acc[power];
        if let Some(s) = lay.unit_groups.filter(|_| g > 0) {
            let len = lay.units * u;
            acc.copy_within(s..s + len, s + g * len);
            acc[s..s + len].fill(0.0);
        }
    }
}

/// Estimates from the sums of independent groups of paths (module docs, "Normalised over the
/// run"): each group's per-path means `x[h]`, `[re τ.., im τ.., power]`.
struct GroupSums {
    /// Σ over the groups and Σ of squares, per number.
    total: Vec<f64>,
    squares: Vec<f64>,
    count: usize,
}

impl GroupSums {
    fn new(x: &[Vec<f64>]) -> Self {
        let len = x.first().map_or(0, Vec::len);
        let (mut total, mut squares) = (vec![0.0; len], vec![0.0; len]);
        for xh in x {
            for (j, &v) in xh.iter().enumerate() {
                total[j] += v;
                squares[j] += v * v;
            }
        }
        GroupSums { total, squares, count: x.len() }
    }

    /// g1 (re, im per τ) and the unbiased `|g1|²` per τ of all the groups but `skip`; `None`
    /// where fewer than two groups remain or `P²`'s unbiased estimate is not positive.
    fn g1(&self, x: &[Vec<f64>], skip: Option<usize>, n: usize) -> Option<(Vec<f64>, Vec<f64>)> {
        let m = self.count - usize::from(skip.is_some());
        if m < 2 {
            return None;
        }
        let t = |j: usize| {
            let (mut t, mut q) = (self.total[j], self.squares[j]);
            if let Some(h) = skip {
                t -= x[h][j];
                q -= x[h][j] * x[h][j];
            }
            (t, q)
        };
        // Σ_{h≠h'} x_h x_h' / (m(m − 1)) = (T² − Q)/(m(m − 1)): unbiased for (E x)², the groups
        // being independent.
        let pairs = (m * (m - 1)) as f64;
        let (tp, qp) = t(2 * n);
        let den = (tp * tp - qp) / pairs;
        if den.is_nan() || den <= 0.0 {
            return None;
        }
        let mut g1 = vec![0.0; 2 * n];
        let mut g1sq = vec![0.0; n];
        for k in 0..n {
            let ((tr, qr), (ti, qi)) = (t(k), t(n + k));
            g1[k] = tr / tp;
            g1[n + k] = ti / tp;
            g1sq[k] = (tr * tr - qr + ti * ti - qi) / pairs / den;
        }
        Some((g1, g1sq))
    }
}

impl CorrelationSpec {
    /// g1, g2 and K (in that order, as one vector) of g1 and `|g1|²`.
    fn derived(&self, g1: &[f64], g1sq: &[f64]) -> Vec<f64> {
        let mut v = g1.to_vec();
        v.extend(g1sq.iter().map(|s| 1.0 + self.beta * s));
        v.extend(self.exposures.iter().map(|&t| contrast(&self.tau, g1sq, t, self.beta)));
        v
    }

    /// The delete-one-group jackknife variances of [`derived`](Self::derived) over the groups
    /// `x` (`None` with fewer than three groups or where a replicate is undefined).
    fn jackknife(&self, x: &[Vec<f64>], sums: &GroupSums) -> Option<Vec<f64>> {
        let n = self.tau.len();
        if x.len() < 3 {
            return None;
        }
        let reps: Vec<Vec<f64>> = (0..x.len())
            .map(|h| sums.g1(x, Some(h), n).map(|(g1, g1sq)| self.derived(&g1, &g1sq)))
            .collect::<Option<_>>()?;
        Some((0..reps[0].len()).map(|j| jackknife_variance(reps.iter().map(|r| r[j]))).collect())
    }

    /// Replace the run's g1, g2 and K (and the speckle contrast image) by their values from the
    /// run's means, with their jackknife variances over the groups of batches (module docs).
    pub fn finish_run(&self, lay: &CorrelationLayout, est: &mut BatchAccumulator, power: usize) {
        let (n, u) = (lay.taus, lay.unit());
        let b = est.batches();
        // The per-path means of group h's batches: its slots hold Σ over them / B.
        let sizes: Vec<usize> = (0..GROUPS).map(|h| b / GROUPS + usize::from(h < b % GROUPS)).collect();
        let group_means = |est: &BatchAccumulator, base: usize, stride: usize| -> Vec<Vec<f64>> {
            (0..GROUPS)
                .filter(|&h| sizes[h] > 0)
                .map(|h| {
                    let s = b as f64 / sizes[h] as f64;
                    est.mean()[base + h * stride..base + h * stride + u].iter().map(|v| v * s).collect()
                })
                .collect()
        };
        // The detector: the run's means, each square less its mean's variance over the B batches.
        let p = est.mean()[power];
        let den = p * p - est.variance(power);
        let mut g1 = vec![0.0; 2 * n];
        let mut g1sq = vec![0.0; n];
        let inv = if p > 0.0 { 1.0 / p } else { 0.0 };
        for k in 0..n {
            let (re, im) = (est.mean()[lay.sums + k], est.mean()[lay.sums + n + k]);
            let num = re * re + im * im - est.variance(lay.sums + k) - est.variance(lay.sums + n + k);
            // Nothing detected (or too little to tell P² from noise): 0, as without paths.
            g1sq[k] = if den > 0.0 { num / den } else { 0.0 };
            (g1[k], g1[n + k]) = (re * inv, im * inv);
        }
        let value = self.derived(&g1, &g1sq);
        let x = group_means(est, lay.groups, u);
        let var = self.jackknife(&x, &GroupSums::new(&x));
        let slots =
            (lay.g1..lay.g1 + 2 * n).chain(lay.g2..lay.g2 + n).chain(lay.contrast..lay.contrast + self.exposures.len());
        for (j, slot) in slots.enumerate() {
            est.set_mean(slot, value[j]);
            // Fewer than three batches: no spread, σ = 0 as for every tally.
            est.set_variance(slot, var.as_ref().map_or(if b < 3 { 0.0 } else { f64::NAN }, |v| v[j]));
        }
        // Each pixel and ROI: its groups alone (values and variances); NaN where undefined.
        let Some(ug) = lay.unit_groups else { return };
        let nt = self.exposures.len();
        let len = 3 * n + nt;
        for unit in 0..lay.units {
            let x = group_means(est, ug + unit * u, lay.units * u);
            let sums = GroupSums::new(&x);
            let point = sums.g1(&x, None, n).map(|(g1, g1sq)| self.derived(&g1, &g1sq));
            let var = point.as_ref().and_then(|_| self.jackknife(&x, &sums));
            let value = |j: usize| match (&point, &var) {
                (Some(v), Some(s2)) => (v[j], s2[j]),
                _ => (f64::NAN, f64::NAN),
            };
            let slots: Vec<(usize, usize)> = if unit < lay.pixels {
                let pc = lay.pixel_contrast.expect("per pixel");
                (0..nt).map(|j| (pc + j * lay.pixels + unit, 3 * n + j)).collect()
            } else {
                let base = lay.roi_outputs + (unit - lay.pixels) * len;
                (0..len).map(|j| (base + j, j)).collect()
            };
            for (slot, j) in slots {
                let (v, s2) = value(j);
                est.set_mean(slot, v);
                est.set_variance(slot, s2);
            }
        }
    }
}

/// The speckle contrast `K(T) = √[(2β/T)∫₀ᵀ(1 − τ/T)|g1(τ)|²dτ]` from `|g1|²` at the delays
/// `tau` (ascending, positive), with `|g1(0)|² = 1` prepended; `T ≤ tau`'s last (the module docs
/// give the quadrature).
pub fn contrast(tau: &[f64], g1sq: &[f64], t: f64, beta: f64) -> f64 {
    let mut integral = 0.0;
    let (mut a, mut ga) = (0.0, 1.0);
    for (&b, &gb) in tau.iter().zip(g1sq) {
        if a >= t {
            break;
        }
        let h = b.min(t) - a;
        // ∫₀ʰ [(1 − a/T) − u/T] g(a + u) du over this piece.
        let c0 = 1.0 - a / t;
        integral += if ga > 0.0 && gb > 0.0 {
            let s = (ga / gb).ln() / (b - a);
            let x = s * h;
            // E0 = ∫₀ʰ e^{−su} du, E1 = ∫₀ʰ u e^{−su} du, without cancellation for small |x|.
            // (1 − e^{−x}(1 + x))/x² = Σ_{n≥2} (−1)^n (n − 1)/n! x^{n−2}: its series below
            // |x| = 0.01 (truncation x⁵/840 < 10⁻¹³), where the closed form cancels.
            let (e0, e1) = if x.abs() < 1e-2 {
                let e1 = 0.5 - x * (1.0 / 3.0 - x * (1.0 / 8.0 - x * (1.0 / 30.0 - x / 144.0)));
                (-(-x).exp_m1() / s, h * h * e1)
            } else {
                let em = (-x).exp_m1();
                (-em / s, h * h * (1.0 - (-x).exp() * (1.0 + x)) / (x * x))
            };
            ga * (c0 * e0 - e1 / t)
        } else {
            let m = (gb - ga) / (b - a);
            c0 * (ga * h + m * h * h / 2.0) - (ga * h * h / 2.0 + m * h * h * h / 3.0) / t
        };
        (a, ga) = (b, gb);
    }
    (2.0 * beta / t * integral).max(0.0).sqrt()
}

/// `n` delays log-spaced from `tau_min` to `tau_max` (both included; `n ≥ 2`).
pub fn log_spaced(tau_min: f64, tau_max: f64, n: usize) -> Vec<f64> {
    let r = (tau_max / tau_min).ln() / (n - 1) as f64;
    (0..n).map(|k| if k == n - 1 { tau_max } else { tau_min * (r * k as f64).exp() }).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bandyopadhyay et al. 2005 Eq. 9: for `|g1|² = e^{−2x τ/T}` (x = ΓT),
    /// `K² = β(e^{−2x} − 1 + 2x)/(2x²)`.
    fn k_exponential(rate: f64, t: f64, beta: f64) -> f64 {
        let y = 2.0 * rate * t;
        // 2(e^{−y} − 1 + y)/y², by its series where the closed form cancels.
        let f = if y < 1e-2 {
            1.0 - y / 3.0 + y * y / 12.0 - y * y * y / 60.0 + y.powi(4) / 360.0
        } else {
            2.0 * ((-y).exp() - 1.0 + y) / (y * y)
        };
        (beta * f).sqrt()
    }

    #[test]
    fn contrast_is_exact_for_an_exponential_and_has_its_limits() {
        let tau = log_spaced(1e-7, 1e-1, 25);
        let rate = 1e3;
        let g1sq: Vec<f64> = tau.iter().map(|t| (-2.0 * rate * t).exp()).collect();
        for t in [1e-7, 3e-6, 1e-4, 1e-3, 2.5e-2, 1e-1] {
            let (k, want) = (contrast(&tau, &g1sq, t, 0.7), k_exponential(rate, t, 0.7));
            assert!((k / want - 1.0).abs() < 1e-9, "T = {t}: K = {k}, Bandyopadhyay {want}");
        }
        // K → √β as T → 0, and K² T → β/Γ for T ≫ 1/Γ.
        assert!((contrast(&tau, &g1sq, 1e-9, 0.7) - 0.7f64.sqrt()).abs() < 1e-5);
        let k = contrast(&tau, &g1sq, 1e-1, 0.7);
        assert!((k * k * 1e-1 * rate / 0.7 - 1.0).abs() < 0.011, "{}", k * k * 1e-1 * rate / 0.7);
    }

    /// The quadrature's error on a mixture of exponentials (diffuse light), measured against a
    /// fine grid: 2.1·10⁻³ of K² at 8 delays per decade, 5.3·10⁻⁴ at 16 (second order in the
    /// spacing of ln τ).
    #[test]
    fn contrast_quadrature_error_on_a_mixture() {
        let g = |t: f64| {
            let g1 = 0.5 * (-1e3 * t).exp() + 0.3 * (-1e4 * t).exp() + 0.2 * (-1e5 * t).exp();
            g1 * g1
        };
        let fine = log_spaced(1e-12, 1e-1, 20_001);
        let fine_sq: Vec<f64> = fine.iter().map(|&t| g(t)).collect();
        for (points, bound) in [(57, 2.2e-3), (113, 6e-4)] {
            let tau = log_spaced(1e-8, 1e-1, points);
            let g1sq: Vec<f64> = tau.iter().map(|&t| g(t)).collect();
            let mut worst: f64 = 0.0;
            for t in [1e-7, 1e-6, 1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 1e-2] {
                let (k, exact) = (contrast(&tau, &g1sq, t, 1.0), contrast(&fine, &fine_sq, t, 1.0));
                worst = worst.max((k * k / (exact * exact) - 1.0).abs());
            }
            println!("{points} delays over 7 decades: largest relative error of K² {worst:.2e}");
            assert!(worst < bound, "{points} delays: {worst}");
        }
    }

    #[test]
    fn a_single_path_gives_its_own_correlation() {
        let spec = CorrelationSpec {
            tau: log_spaced(1e-6, 1e-3, 4),
            beta: 0.5,
            exposures: vec![1e-3],
            pixels: false,
            rois: vec![],
        };
        let mut reg = Registry::default();
        let power = reg.take(1);
        let lay = spec.declare(0, "d", None, &mut reg);
        let mut est = BatchAccumulator::new(reg.len);
        let (w, f, rate) = (0.3, 1234.5, 800.0);
        // The same path in each of 4 batches: no spread, so every estimate is the path's own.
        for batch in 0..4 {
            let mut acc = vec![0.0; reg.len];
            acc[power] += w;
            spec.record(&lay, &mut acc, w, f, rate, None, (0.0, 0.0));
            spec.finish_batch(&lay, &mut acc, power, batch);
            est.push(&acc, 10);
        }
        spec.finish_run(&lay, &mut est, power);
        let (m, se) = (est.mean(), est.stderr());
        for (k, &t) in spec.tau.iter().enumerate() {
            let (re, im) = (m[lay.g1 + k], m[lay.g1 + 4 + k]);
            let d = (-rate * t).exp();
            let ph = std::f64::consts::TAU * f * t;
            assert!((re - d * ph.cos()).abs() < 1e-14 && (im - d * ph.sin()).abs() < 1e-14);
            assert!((m[lay.g2 + k] - (1.0 + 0.5 * d * d)).abs() < 1e-12, "{} vs {}", m[lay.g2 + k], 1.0 + 0.5 * d * d);
            assert!(se[lay.g1 + k] < 1e-12 && se[lay.g2 + k] < 1e-12);
        }
    }
}
