//! The finished run: what the simulation returned and what the post-processing computed from it,
//! typed, between the transport and the files. The writers ([`crate::io::write`]) only write it.
//!
//! Post-processing here: the non-finite check of every declared output (a bug if it fails: the
//! run ends before anything is written), the LDH ROIs' and pixels' single-window speckle from the
//! recorded paths ([`super::speckle`]), the lidar receivers' gate retrievals (moments and fits of
//! every gate's spectrum, [`crate::retrieval::retrieve_gate`]) and the run's warnings
//! ([`super::warnings`]).

use std::time::Instant;

use rayon::prelude::*;

use super::{PixelSpeckle, RoiSpeckle, Warning, pixel_speckle_of, speckle_of, warnings};
use crate::detect::{DetectorKind, LidarLayout, LidarSpec};
use crate::error::Result;
use crate::experiment::{Experiment, Progress, RunOutput};
use crate::retrieval::{GateRetrieval, retrieve_gate};

/// A run ready to be written.
pub struct Finished<'a> {
    pub exp: &'a Experiment,
    pub out: &'a RunOutput,
    /// The standard errors of the tallies (the values are `out.estimates.mean()`).
    pub stderr: Vec<f64>,
    /// Single-window speckle of each LDH ROI (empty without).
    pub speckle: Vec<RoiSpeckle>,
    /// Single-window speckle in every pixel of the LDH camera (`speckle.pixels`).
    pub pixel_speckle: Option<PixelSpeckle>,
    /// Per detector, a lidar receiver's gate retrievals in gate order (empty for the others).
    pub retrievals: Vec<Vec<GateRetrieval>>,
    /// What the run could not get right.
    pub warnings: Vec<Warning>,
    /// Time spent on the speckle and on the gate fits, s (0 without lidar receivers).
    pub speckle_seconds: f64,
    pub gate_fit_seconds: f64,
}

impl<'a> Finished<'a> {
    /// Check and post-process the run `out` of `exp`, telling `progress` how far the gate fits
    /// are (its total set to the gates of every lidar receiver, advanced by one per gate).
    pub fn new(exp: &'a Experiment, out: &'a RunOutput, progress: &dyn Progress) -> Result<Self> {
        let stderr = out.estimates.stderr();
        let (registry, mean) = (&out.layout.registry, out.estimates.mean());
        // Non-finite estimates are a bug: refused before anything is written (issue 21, item 4).
        registry.check_finite(mean, &stderr)?;
        let t = Instant::now();
        let speckle = speckle_of(exp, out);
        let pixel_speckle = pixel_speckle_of(exp, out);
        let speckle_seconds = t.elapsed().as_secs_f64();
        // The lidar gate fits, every receiver's gates in parallel.
        let t = Instant::now();
        progress.set_total(exp.detectors.iter().filter_map(|d| d.lidar()).map(|l| l.gates as u64).sum());
        let threads = exp.plan.effective_threads();
        let retrievals: Vec<Vec<GateRetrieval>> = exp
            .detectors
            .iter()
            .enumerate()
            .map(|(i, d)| match &d.kind {
                DetectorKind::Lidar(spec) => {
                    let lay = out.layout.detectors[i].lidar.as_ref().expect("a lidar receiver's layout");
                    retrieve_gates(lay, mean, &stderr, spec, threads, progress)
                }
                DetectorKind::Surface(_) => Vec::new(),
            })
            .collect();
        // 0 without a lidar receiver (nothing was fitted).
        let gate_fit_seconds = if retrievals.iter().any(|r| !r.is_empty()) { t.elapsed().as_secs_f64() } else { 0.0 };
        let warnings = warnings(exp, out);
        Ok(Finished {
            exp,
            out,
            stderr,
            speckle,
            pixel_speckle,
            retrievals,
            warnings,
            speckle_seconds,
            gate_fit_seconds,
        })
    }

    /// The run's means of the tallies.
    pub fn mean(&self) -> &'a [f64] {
        self.out.estimates.mean()
    }
}

/// What is read off every gate of a lidar receiver (laid out as `lay`; [`retrieve_gate`] on its total
/// spectrum plus the shot-noise floor, through the gate's kernel for the run's gate energies), in
/// gate order. The gates are independent, so they are retrieved in parallel on `threads` threads
/// (results do not depend on the count) and `progress` advances by one per gate.
pub fn retrieve_gates(
    lay: &LidarLayout,
    mean: &[f64],
    stderr: &[f64],
    spec: &LidarSpec,
    threads: usize,
    progress: &dyn Progress,
) -> Vec<GateRetrieval> {
    let bins = spec.fft_points;
    // The total channel's gate energies (lag 0): the echo density that shapes each gate's kernel.
    let energies: Vec<f64> = (0..spec.gates).map(|g| mean[lay.lags + spec.lag_slot(0, g, 0)]).collect();
    let (axis, floor) = (spec.frequency_axis(), spec.noise_floor_per_bin());
    let one = |g: usize| {
        let o = lay.spectra + g * bins;
        let kernel = spec.gate_kernel_in(g, &energies);
        let r = retrieve_gate(axis.as_ref(), floor, spec.wavelength, &mean[o..o + bins], &stderr[o..o + bins], &kernel);
        progress.advance(1);
        r
    };
    crate::experiment::on_threads(threads, || (0..spec.gates).into_par_iter().map(one).collect())
}
