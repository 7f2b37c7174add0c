//! The parts of a run: the run itself, or for a scan one run per pointing in its own directory
//! `pointing_NN/`; and a scan's per-pointing results gathered into the VAD wind per range gate
//! ([`crate::scan`]), written as `vad.csv` and `scan.json` ([`crate::io::write::scan`]).

use std::path::{Path, PathBuf};

use super::{Event, Observer};
use crate::error::Result;
use crate::experiment::{Decisions, Experiment, RunOutput};
use crate::io::outdir::OutDir;
use crate::io::persist::{config_fingerprint, fingerprint};
use crate::io::write::dir::{DirWriter, Output, VAD};
use crate::io::write::manifest::Timing;
use crate::scan::GateWind;

/// A run, or one pointing of a scan: its experiment, its pilots' decisions, output directory and
/// fingerprint.
#[derive(Debug, Clone)]
pub struct Part {
    /// As configured (pointed, for a pointing of a scan).
    pub exp: Experiment,
    /// What its pilots decided ([`crate::pilot::decide`]), which its runs apply.
    pub decisions: Decisions,
    /// The output directory (locked), or a scan's pointing directory inside it.
    pub dir: OutDir,
    /// Of the configuration as run and the pointing: a checkpoint or shard of one pointing is
    /// never taken for another's.
    pub fingerprint: u64,
    /// The pointing's index in a scan (`None` for a plain run).
    pub pointing: Option<usize>,
}

impl Part {
    /// Where the part's checkpoint is saved.
    pub fn checkpoint(&self) -> PathBuf {
        self.dir.path().join(CHECKPOINT)
    }
}

/// The name of a part's checkpoint file in its directory.
pub const CHECKPOINT: &str = "checkpoint.ohd";

pub use crate::io::write::dir::pointing_name;

/// The directory of pointing `i` of a scan, inside the scan's.
pub fn pointing_dir(dir: &Path, i: usize) -> PathBuf {
    dir.join(pointing_name(i))
}

/// The parts of a run of `exp` (configured as `table`) into `dir`: itself, or for a scan one per
/// pointing into `dir/pointing_NN` (a pointing directory that exists as anything but a directory,
/// a link included, or that another ohd holds, is refused now, before any work; each is locked as
/// long as `dir` is); each with its `estimator = "auto"` decided by a pilot ([`crate::pilot`],
/// deterministic: every shard and every resume decides the same).
pub fn parts(exp: &Experiment, table: &toml::Table, dir: &OutDir) -> Result<Vec<Part>> {
    let fp = config_fingerprint(table);
    if exp.source.pointings.len() <= 1 {
        let decisions = crate::pilot::decide(exp);
        return Ok(vec![Part { exp: exp.clone(), decisions, dir: dir.clone(), fingerprint: fp, pointing: None }]);
    }
    // Every pointing directory, locked before any pilot runs (issue 52: a run into one of them
    // while the scan wrote was not refused).
    // What an earlier output in each records is checked now too, before anything is written.
    let dirs = (0..exp.source.pointings.len())
        .map(|i| {
            let sub = dir.sub(&pointing_name(i))?;
            DirWriter::check(&sub, Output::Run)?;
            Ok(sub)
        })
        .collect::<Result<Vec<_>>>()?;
    let pointing = |(i, (p, dir)): (usize, (&crate::source::Pointing, OutDir))| {
        let exp = exp.pointed(p);
        Part {
            decisions: crate::pilot::decide(&exp),
            exp,
            dir,
            fingerprint: fingerprint(&format!("{fp:016x} pointing {i}")),
            pointing: Some(i),
        }
    };
    Ok(exp.source.pointings.iter().zip(dirs).enumerate().map(pointing).collect())
}

/// A scan's per-pointing results, gathered for the VAD wind per range gate, and its directory
/// being written.
#[derive(Debug, Default)]
pub(super) struct Scan {
    runs: Vec<String>,
    velocities: Vec<Vec<Option<f64>>>,
    ranges: Vec<f64>,
    /// Each pointing's FMCW read-offs, one per detector with a chirped spectrum.
    fmcw: Vec<Vec<crate::io::write::scan::FmcwRow>>,
    /// Each pointing's timing, in the order written.
    timings: Vec<Timing>,
    /// The scan's directory, written from its first pointing's outputs on (marked incomplete
    /// until [`Scan::finish`]).
    out: Option<DirWriter>,
}

impl Scan {
    /// Before `part`'s outputs are written, if it is a pointing of the scan of `parts` into `dir`:
    /// at the first, begin writing the scan's directory (marked incomplete; what an earlier output
    /// left there removed, but this scan's pointing directories, which each pointing's writer
    /// cleans), and note the pointing's directory in it. Nothing for a plain run.
    pub(super) fn writing(&mut self, dir: &OutDir, parts: &[Part], part: &Part) -> Result<()> {
        let Some(i) = part.pointing else { return Ok(()) };
        if self.out.is_none() {
            let keep: Vec<String> = parts.iter().filter_map(|p| p.pointing).map(pointing_name).collect();
            self.out = Some(DirWriter::begin(dir, Output::Run, &keep)?);
        }
        if let Some(out) = self.out.as_mut() {
            out.subdir(&pointing_name(i))?;
        }
        Ok(())
    }

    /// Gather what the VAD needs of `part`'s output and its `timing` (nothing of a plain run).
    pub(super) fn add(&mut self, part: &Part, output: &RunOutput, timing: Timing) {
        let Some(i) = part.pointing else { return };
        self.timings.push(timing);
        if let Some(v) = crate::scan::gate_peak_velocities(&part.exp, output) {
            self.velocities.push(v);
        }
        if let Some(l) = part.exp.detectors.iter().find_map(|d| d.lidar()) {
            self.ranges = (0..l.gates).map(|g| l.gate_range(g)).collect();
        }
        let fmcw: Vec<_> = (part.exp.detectors.iter().enumerate())
            .filter_map(|(d, det)| {
                let e = part.exp.fmcw_estimates(output, d)?;
                Some((det.name.clone(), e.map_err(|e| e.to_string())))
            })
            .collect();
        if !fmcw.is_empty() {
            self.fmcw.push(fmcw);
        }
        self.runs.push(pointing_name(i));
    }

    /// Once every pointing is written: the VAD wind of a scan of `exp` into the scan's directory
    /// when every pointing has gate velocities, returned; then the directory is complete.
    pub(super) fn finish(
        &mut self,
        exp: &Experiment,
        figures: bool,
        obs: &dyn Observer,
    ) -> Result<Option<Vec<GateWind>>> {
        let pointings = &exp.source.pointings;
        let Some(out) = self.out.take() else { return Ok(None) };
        if pointings.len() > 1 && self.velocities.len() == pointings.len() {
            let gates = crate::scan::vad_per_gate(pointings, exp.source.position.z, &self.ranges, &self.velocities);
            let path = out.dir().join(VAD);
            crate::io::write::scan::write_scan(
                out,
                pointings,
                &self.runs,
                &gates,
                exp.scene.wind(),
                figures,
                &self.timings,
            )?;
            obs.event(Event::ScanWritten {
                what: "VAD wind per gate",
                path: &path,
                timing: &Timing::sum(&self.timings),
            });
            return Ok(Some(gates));
        }
        if pointings.len() > 1 && self.fmcw.len() == pointings.len() {
            let path = out.dir().join(crate::io::write::dir::FMCW_SCAN);
            crate::io::write::scan::write_fmcw_scan(out, pointings, &self.runs, &self.fmcw, figures, &self.timings)?;
            let timing = Timing::sum(&self.timings);
            obs.event(Event::ScanWritten {
                what: "FMCW range and velocity per pointing",
                path: &path,
                timing: &timing,
            });
            return Ok(None);
        }
        out.finish(None)?;
        Ok(None)
    }
}
