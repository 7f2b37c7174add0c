//! Scans: one run per pointing of the beam, and the velocity–azimuth display (VAD) retrieval of
//! the wind in every range gate from the radial velocities the pointings measure.
//!
//! Each pointing is an independent run of the same experiment with the source (and the lidar
//! receiver, which looks along it) turned to that pointing; the seed is the same for all, so a
//! scan is reproducible pointing by pointing. In gate `g` every pointing `d̂_i` measures the
//! radial velocity `v_i = d̂_i·V` (positive receding) at the peak of its gate spectrum; the wind
//! `V` is the least-squares solution of those equations ([`crate::retrieval::vad_fit`]). Gates
//! at the same range lie at the same height only when all pointings share one elevation (a
//! conical scan, the usual VAD); the height reported is the mean over the pointings.

use crate::experiment::{Experiment, RunOutput};
use crate::retrieval::{RetrievalError, VadFit, gate_estimates, vad_fit};
use crate::source::Pointing;

/// The peak radial velocity (m/s, positive receding) of every gate of the run's lidar receiver,
/// from the expected spectrum of all scattering orders (the `peak_velocity_m_per_s` of
/// `NAME_gates.csv`: the shot-noise floor, a constant, does not move the peak); `None` for a gate
/// without signal. `None` altogether without a lidar receiver.
pub fn gate_peak_velocities(exp: &Experiment, out: &RunOutput) -> Option<Vec<Option<f64>>> {
    let (i, spec) = exp.detectors.iter().enumerate().find_map(|(i, d)| d.lidar().map(|l| (i, l)))?;
    let start = out.layout.detectors[i].lidar.as_ref()?.spectra;
    let k = spec.fft_points;
    let axis = spec.frequency_axis()?;
    let mean = out.estimates.mean();
    Some(
        (0..spec.gates)
            .map(|g| {
                let o = start + g * k;
                gate_estimates(&axis, &mean[o..o + k], 0.0, exp.source.wavelength).ok().map(|e| e.peak_velocity_m_per_s)
            })
            .collect(),
    )
}

/// The VAD retrieval of one range gate.
#[derive(Debug, Clone)]
pub struct GateWind {
    pub range_m: f64,
    /// Mean height of the gate centre over the pointings, m.
    pub height_m: f64,
    /// The radial velocity each pointing measured (`None`: no signal).
    pub radial_velocities: Vec<Option<f64>>,
    pub fit: Result<VadFit, RetrievalError>,
}

/// VAD per gate from `velocities[pointing][gate]` at gate ranges `ranges` (m).
/// `z0` is the height of the lidar (the source's `z`).
pub fn vad_per_gate(pointings: &[Pointing], z0: f64, ranges: &[f64], velocities: &[Vec<Option<f64>>]) -> Vec<GateWind> {
    ranges
        .iter()
        .enumerate()
        .map(|(g, &range_m)| {
            let radial: Vec<Option<f64>> = velocities.iter().map(|v| v.get(g).copied().flatten()).collect();
            let (dirs, vr): (Vec<_>, Vec<_>) =
                pointings.iter().zip(&radial).filter_map(|(p, v)| v.map(|v| (p.direction, v))).unzip();
            let height_m =
                z0 + pointings.iter().map(|p| range_m * p.direction.z).sum::<f64>() / pointings.len().max(1) as f64;
            GateWind { range_m, height_m, fit: vad_fit(&dirs, &vr, None), radial_velocities: radial }
        })
        .collect()
}
