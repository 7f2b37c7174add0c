//! `ohd converge`: the convergence study of an experiment ([`crate::converge::study`]) against a
//! reference read from a run directory or made on the fly, written as `converge.csv`,
//! `converge.json` and `converge.png` ([`crate::io::write::converge`]).

use std::path::PathBuf;

use super::{Event, Loaded, Observer};
use crate::converge::{LadderOptions, Study, StudyLog};
use crate::error::{Error, Result};

/// What to study and how.
#[derive(Debug, Clone)]
pub struct ConvergeRequest {
    /// The experiment file (the built-in default without one) and the `--set` overrides.
    pub config: Option<PathBuf>,
    pub overrides: Vec<String>,
    /// Output directory (default: `out/<experiment name>_converge`).
    pub out: Option<PathBuf>,
    /// A run directory of the same experiment as the reference.
    pub reference: Option<PathBuf>,
    /// Wall-time budget of the whole study, seconds.
    pub budget_seconds: f64,
    /// Paths of the largest rung (instead of sizing the ladder from the budget).
    pub samples: Option<u64>,
    /// Rungs, each twice the paths of the one before (2 to 24).
    pub rungs: usize,
    /// Write no figure (`--no-figures`).
    pub no_figures: bool,
}

/// A study written into `dir`.
#[derive(Debug, Clone)]
pub struct StudyWritten {
    pub study: Study,
    pub dir: PathBuf,
}

/// Check `req`, load its experiment (of a scan: the first pointing, told as
/// [`Event::StudyingFirstPointing`]), run the study with `log` and write it.
pub fn converge(req: &ConvergeRequest, obs: &dyn Observer, log: &mut dyn StudyLog) -> Result<StudyWritten> {
    // At most a year: a study is a run to be waited for (issue 21: 1e300 s ran without end).
    if !(req.budget_seconds > 0.0 && req.budget_seconds <= 3.2e7) {
        return Err(Error::Input(format!(
            "--budget-seconds {}: expected a time in (0, 3.2e7] s (at most a year)",
            req.budget_seconds
        )));
    }
    if !(2..=24).contains(&req.rungs) {
        return Err(Error::Input(format!("--rungs {}: expected 2 to 24 rungs", req.rungs)));
    }
    let loaded = Loaded::read(req.config.as_deref(), &req.overrides)?;
    let dir = req.out.clone().unwrap_or_else(|| loaded.default_dir("_converge"));
    // The directory, locked for the whole study: found unusable now, not after it.
    let out = crate::io::outdir::OutDir::create(&dir)?;
    crate::io::write::dir::DirWriter::check(&out, crate::io::write::dir::Output::Study)?;
    let Loaded { mut exp, origin, .. } = loaded;
    let smallest = exp.plan.batches << (req.rungs - 1);
    if let Some(n) = req.samples
        && n < smallest
    {
        return Err(Error::Input(format!(
            "--samples {n}: expected at least run.batches × 2^(rungs − 1) = {smallest} paths (one path per batch on the smallest rung)"
        )));
    }
    if exp.source.pointings.len() > 1 {
        let p = exp.source.pointings[0];
        obs.event(Event::StudyingFirstPointing(&p));
        exp = exp.pointed(&p);
    }
    let refs = match &req.reference {
        Some(dir) => {
            let outputs = exp.outputs();
            let refs = crate::io::write::converge::read_reference(dir, &outputs)?;
            // Before any rung: a study against a NaN would measure nothing (issue 52).
            for (o, r) in outputs.iter().zip(&refs) {
                if let Some(why) = r.as_ref().and_then(|r| r.defect(o)) {
                    return Err(Error::Input(format!(
                        "--reference {}: {why}: expected a run directory of this experiment, its values and standard \
                         errors finite numbers (magnitudes below about 1e154: their squares must sum to a finite number)",
                        dir.display()
                    )));
                }
            }
            refs
        }
        None => Vec::new(),
    };
    let opts = LadderOptions {
        top_samples: req.samples,
        budget_seconds: req.budget_seconds,
        rungs: req.rungs,
        ..Default::default()
    };
    let decisions = crate::pilot::decide(&exp);
    let study = crate::converge::study(&exp, &decisions, refs, &opts, log);
    crate::io::write::converge::write_study(&out, &study, &origin, !req.no_figures)?;
    Ok(StudyWritten { study, dir })
}
