//! Single-measurement speckle of the LDH camera's regions of interest (Kim et al. 2025
//! §5.2–5.3), synthesised after a run from the paths the run recorded in them
//! ([`RecordedLine`]s, kept when `[detectors.ldh.speckle]` is set): Algorithm 1 draws the run's
//! expected single-window periodogram times Exp(1) per bin, Algorithm 2 sums the recorded paths'
//! fields with random phases ([`Synthesizer`]).
//!
//! With `[detectors.ldh.speckle] pixels = true` every pixel gets a single-window speckled M0±
//! too ([`synthesize_pixel_speckle`]): Algorithm 1 from the pixel's spectrum, which the camera
//! records with `pixel_spectra = true`. The expected single-window periodogram of a pixel is
//! `S_k = Σ_j H_j K(ν_k − f_j)` over its histogram `H` ([`BinnedPeriodogram`]): the histogram
//! keeps no frequency finer than its bin, so a path counts at its bin's centre `f_j` (the binning
//! approximation; on the default axis, the STFT's own `f_s/N` bins, a line is moved by at most
//! half an STFT bin), and power outside the axis (the out-of-range tallies) is not in `S`.
//!
//! Streams: window `j` of ROI `r` and algorithm `a` draws from `(seed, Speckle, r, 2j + a)`;
//! window `j` of pixel `p` (the tally's image order, rows = y ascending) from
//! `(seed, Speckle, PIXEL_STREAM | p, j)`. An ROI index is a `Vec` index, below 2⁶³, so the
//! elements never coincide; each pixel's numbers depend on nothing but `(seed, p, j)`, so the
//! result is the same for any thread count.

use rayon::prelude::*;

use crate::detect::ldh::{LdhSpec, RecordedLine};
use crate::experiment::{Experiment, RunOutput};
use crate::output::Kind;
use crate::sampling::{PathRng, Purpose};
use crate::spectrum::{BandPowers, BinnedPeriodogram, Line, Stft, Synthesizer, speckle_draw};

/// The speckle spectra of a finished run of `exp` (its first LDH camera's ROIs; empty without
/// one or without `[detectors.ldh.speckle]`): [`synthesize_speckle`] of the lines `out` recorded
/// over its [`samples`](RunOutput::samples) paths, with the plan's seed.
pub fn speckle_of(exp: &Experiment, out: &RunOutput) -> Vec<RoiSpeckle> {
    match exp.detectors.iter().find_map(|d| d.ldh()) {
        Some(spec) => synthesize_speckle(spec, &out.lines, out.samples(), exp.plan.seed),
        None => Vec::new(),
    }
}

/// Band sums of a periodogram in fftshift order (as [`Stft::bin_frequency`]): M0± and M1 of a
/// single window, with the same bins as [`crate::spectrum::BandKernel`].
pub fn band_sums(stft: &Stft, band: (f64, f64), p: &[f64]) -> BandPowers {
    let mut out = BandPowers::default();
    for (k, &v) in p.iter().enumerate().skip(1) {
        // Bin 0 is the unpaired −f_s/2 bin, in neither half of the band.
        let nu = stft.bin_frequency(k);
        let a = nu.abs();
        if band.0 <= a && a <= band.1 {
            out.m0_plus += v;
            out.m0_minus += if nu > 0.0 { v } else { -v };
            out.m1 += a * v;
        }
    }
    out
}

/// Single-window speckle spectra of one ROI (Kim et al. 2025 §5.2–5.3), in fftshift order.
#[derive(Debug, Clone)]
pub struct RoiSpeckle {
    /// Paths recorded in the ROI.
    pub lines: usize,
    /// The expected single-window periodogram `S ∗ |W|²` of the recorded paths (N values).
    pub expected: Vec<f64>,
    /// Algorithm 1: `expected` times an Exp(1) draw per bin, one row per window (windows × N).
    pub algorithm1: Vec<f64>,
    /// Algorithm 2: the field of the recorded paths with random phases, `|FFT|²` (windows × N).
    pub algorithm2: Vec<f64>,
    /// Seconds spent in each algorithm (all windows), and on the expected periodogram.
    pub seconds_expected: f64,
    pub seconds_algorithm1: f64,
    pub seconds_algorithm2: f64,
}

/// Synthesise the speckle spectra of every ROI from the recorded lines of a run of `paths`
/// paths. A path's line carries power `w/paths` (the run's estimate is the mean over paths), so
/// the mean of Algorithm 2 over windows converges to `expected`, which is the run's Algorithm 1
/// estimate convolved with the window kernel. Window `j` of ROI `r` draws from the stream
/// `(seed, Speckle, r, 2j + algorithm)`.
pub fn synthesize_speckle(spec: &LdhSpec, recorded: &[RecordedLine], paths: u64, seed: u64) -> Vec<RoiSpeckle> {
    let Some(sp) = spec.speckle else { return Vec::new() };
    let n = spec.stft.samples();
    let windows = sp.windows as usize;
    let inv_paths = 1.0 / paths.max(1) as f64;
    let mut synth = Synthesizer::new(&spec.stft);
    (0..spec.rois.len())
        .map(|r| {
            let lines: Vec<Line> = recorded
                .iter()
                .filter(|l| l.roi as usize == r)
                .map(|l| Line { power: l.weight * inv_paths, frequency: l.frequency, gamma: l.gamma })
                .collect();
            let t = std::time::Instant::now();
            let expected = spec.stft.expected_periodogram(&lines);
            let seconds_expected = t.elapsed().as_secs_f64();
            let t = std::time::Instant::now();
            let mut algorithm1 = vec![0.0; windows * n];
            for (j, row) in algorithm1.chunks_exact_mut(n).enumerate() {
                let mut rng = PathRng::new(seed, Purpose::Speckle, r as u64, 2 * j as u64);
                speckle_draw(&expected, &mut rng, row);
            }
            let seconds_algorithm1 = t.elapsed().as_secs_f64();
            let t = std::time::Instant::now();
            let mut algorithm2 = vec![0.0; windows * n];
            for (j, row) in algorithm2.chunks_exact_mut(n).enumerate() {
                let mut rng = PathRng::new(seed, Purpose::Speckle, r as u64, 2 * j as u64 + 1);
                synth.periodogram(&lines, &mut rng, row);
            }
            let seconds_algorithm2 = t.elapsed().as_secs_f64();
            RoiSpeckle {
                lines: lines.len(),
                expected,
                algorithm1,
                algorithm2,
                seconds_expected,
                seconds_algorithm1,
                seconds_algorithm2,
            }
        })
        .collect()
}

/// The stream element bit of the per-pixel speckle: pixel `p` draws from element
/// `PIXEL_STREAM | p` (ROI `r` from element `r < 2⁶³`).
pub const PIXEL_STREAM: u64 = 1 << 63;

/// Single-window speckled M0± of every pixel (Algorithm 1 per pixel), with what they are drawn
/// from. Pixels in the tally's image order (`ny` rows of `nx`, rows = y ascending; the writer
/// turns them to row 0 = the largest y, as every written image), M0− with the library's sign (the
/// writer applies `flip_sign`).
#[derive(Debug, Clone)]
pub struct PixelSpeckle {
    pub nx: usize,
    pub ny: usize,
    pub windows: usize,
    /// `[window][pixel]`: window `j`'s band sums of `S_k · Exp(1)`.
    pub m0_plus: Vec<f64>,
    pub m0_minus: Vec<f64>,
    /// `[pixel]`: the band sums of `S` itself, the expectation of every window's M0±.
    pub expected_m0_plus: Vec<f64>,
    pub expected_m0_minus: Vec<f64>,
    /// `[pixel]`: the closed-form single-window contrast of M0+ (σ/mean over windows),
    /// `√(Σ_B S_k²)/Σ_B S_k` over the band's bins `B` (independent exponential bins); NaN where
    /// `S` is zero in the band.
    pub contrast: Vec<f64>,
    /// Power of the pixel spectra on their axis and outside it (the tallies `S` leaves out),
    /// summed over the pixels.
    pub in_range: f64,
    pub out_of_range: f64,
    /// Whether the spectra's axis is on the STFT grid (the O(N log N) path of `S`).
    pub on_stft_grid: bool,
    /// Wall seconds of the synthesis (`S`, draws and band sums of all pixels and windows).
    pub seconds: f64,
    /// Bytes of one copy of the per-pixel spectra tally (`pixels × (bins + 2) × 8`).
    pub spectra_bytes: usize,
}

/// The per-pixel speckle of a finished run of `exp` (its LDH camera with `speckle.pixels`;
/// `None` otherwise), from the run's estimate of the per-pixel spectra, on the plan's threads.
pub fn pixel_speckle_of(exp: &Experiment, out: &RunOutput) -> Option<PixelSpeckle> {
    let i = exp.detectors.iter().position(|d| d.ldh().is_some())?;
    let spec = exp.detectors[i].ldh()?;
    if !spec.speckle.is_some_and(|s| s.pixels) {
        return None;
    }
    let o = out.layout.registry.at(out.layout.detectors[i].ldh()?.pixel_spectra?);
    let Kind::PixelSpectra { nx, ny, .. } = o.kind else { unreachable!("{} is declared per-pixel spectra", o.name) };
    let (start, stride) = (o.slots.start, o.slots.stride);
    let spectra = &out.estimates.mean()[start..start + nx * ny * stride];
    Some(synthesize_pixel_speckle(spec, nx, ny, spectra, stride, exp.plan.seed, exp.plan.effective_threads()))
}

/// Algorithm 1 in every pixel: `spectra` holds pixel `p`'s histogram (fraction of the emitted
/// power per bin of `spec.spectrum_axis`, library sign) at `p·stride`, its below/above tallies
/// right after. For each pixel, `S` ([`BinnedPeriodogram`]), then per window `S_k · Exp(1)`
/// ([`speckle_draw`], stream `(seed, Speckle, PIXEL_STREAM | p, j)`) and its [`band_sums`].
/// `spec.speckle.windows` windows (1 if `spec.speckle` is `None`), on a pool of `threads`
/// threads; the result does not depend on `threads`.
pub fn synthesize_pixel_speckle(
    spec: &LdhSpec,
    nx: usize,
    ny: usize,
    spectra: &[f64],
    stride: usize,
    seed: u64,
    threads: usize,
) -> PixelSpeckle {
    let t = std::time::Instant::now();
    let pixels = nx * ny;
    let n = spec.stft.samples();
    let bins = spec.spectrum_axis.bins;
    assert!(stride >= bins + 2 && spectra.len() >= pixels * stride, "one histogram and two tallies per pixel");
    let windows = spec.speckle.map_or(1, |s| s.windows as usize);
    let band: Vec<usize> = (1..n)
        .filter(|&k| {
            let a = spec.stft.bin_frequency(k).abs();
            spec.band.0 <= a && a <= spec.band.1
        })
        .collect();
    // Per pixel: [M0+ of each window, M0− of each window, E M0+, E M0−, contrast, in, out].
    let record = 2 * windows + 5;
    let mut records = vec![0.0; pixels * record];
    let on_stft_grid = BinnedPeriodogram::new(&spec.stft, &spec.spectrum_axis).on_stft_grid();
    let work = |records: &mut [f64]| {
        records.par_chunks_mut(record).enumerate().with_min_len(64).for_each_init(
            || (BinnedPeriodogram::new(&spec.stft, &spec.spectrum_axis), vec![0.0; n], vec![0.0; n]),
            |(bp, s, row), (p, rec)| {
                let h = &spectra[p * stride..p * stride + bins + 2];
                rec[2 * windows + 3] = h[..bins].iter().sum();
                rec[2 * windows + 4] = h[bins] + h[bins + 1];
                if !bp.expected(&h[..bins], s) {
                    rec[2 * windows + 2] = f64::NAN;
                    return;
                }
                let e = band_sums(&spec.stft, spec.band, s);
                rec[2 * windows] = e.m0_plus;
                rec[2 * windows + 1] = e.m0_minus;
                let (sum, sq) = band.iter().fold((0.0, 0.0), |(a, b), &k| (a + s[k], b + s[k] * s[k]));
                rec[2 * windows + 2] = if sum > 0.0 { sq.sqrt() / sum } else { f64::NAN };
                for j in 0..windows {
                    let mut rng = PathRng::new(seed, Purpose::Speckle, PIXEL_STREAM | p as u64, j as u64);
                    speckle_draw(s, &mut rng, row);
                    let b = band_sums(&spec.stft, spec.band, row);
                    rec[j] = b.m0_plus;
                    rec[windows + j] = b.m0_minus;
                }
            },
        )
    };
    crate::experiment::on_threads(threads, || work(&mut records));
    let column = |c: usize| -> Vec<f64> { records.chunks_exact(record).map(|r| r[c]).collect() };
    let stack = |first: usize| -> Vec<f64> {
        (0..windows).flat_map(|j| records.chunks_exact(record).map(move |r| r[first + j])).collect()
    };
    PixelSpeckle {
        nx,
        ny,
        windows,
        m0_plus: stack(0),
        m0_minus: stack(windows),
        expected_m0_plus: column(2 * windows),
        expected_m0_minus: column(2 * windows + 1),
        contrast: column(2 * windows + 2),
        in_range: column(2 * windows + 3).iter().sum(),
        out_of_range: column(2 * windows + 4).iter().sum(),
        on_stft_grid,
        seconds: t.elapsed().as_secs_f64(),
        spectra_bytes: pixels * stride * std::mem::size_of::<f64>(),
    }
}
