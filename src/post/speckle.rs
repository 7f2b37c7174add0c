//! Single-measurement speckle of the LDH camera's regions of interest (Kim et al. 2025
//! §5.2–5.3), synthesised after a run from the paths the run recorded in them
//! ([`RecordedLine`]s, kept when `[detectors.ldh.speckle]` is set): Algorithm 1 draws the run's
//! expected single-window periodogram times Exp(1) per bin, Algorithm 2 sums the recorded paths'
//! fields with random phases ([`Synthesizer`]).

use crate::detect::ldh::{LdhSpec, RecordedLine};
use crate::experiment::{Experiment, RunOutput};
use crate::sampling::{PathRng, Purpose};
use crate::spectrum::{BandPowers, Line, Stft, Synthesizer, speckle_draw};

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
