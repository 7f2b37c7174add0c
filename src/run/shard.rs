//! Shards: `ohd run --shard I/N` runs the `I`-th of `N` contiguous parts of a run's batches
//! ([`Experiment::shard_batches`]) and writes every batch's tally sums to `DIR/shard.ohd` (the
//! file format: [`crate::io::persist::shard`]); `ohd merge` folds the shards' batches in batch order,
//! exactly as one process would have, so the merged outputs equal a single run's bit for bit.
//! (Merging per-shard summaries instead would not: Welford's fold of batch means is sequential.)
//! A scan shards and merges per pointing (`DIR/pointing_NN/shard.ohd`), then writes the VAD wind.

use std::ops::Range;
use std::path::{Path, PathBuf};

use super::scan::Scan;
use super::{Event, Finished, Loaded, Observer, Part, parts, pointing_dir};
use crate::detect::RecordedLine;
use crate::error::{Error, Result};
use crate::experiment::{Decisions, Experiment, RunOutput};
use crate::io::outdir::OutDir;
use crate::io::persist::shard::{FILE_NAME, ShardHeader, ShardReader, ShardTrailer, ShardWriter};
use crate::io::write::dir::{DirWriter, Output};
use crate::io::write::manifest::{Invocation, write_run_with};
use crate::stats::{BatchAccumulator, RunStats};

/// A shard written: part `index` of `count`, its batches of the run's `batches`, its paths and
/// seconds, and its file.
#[derive(Debug, Clone, PartialEq)]
pub struct ShardSummary {
    pub index: u64,
    pub count: u64,
    pub range: Range<u64>,
    pub batches: u64,
    pub paths: u64,
    pub seconds: f64,
    pub path: PathBuf,
}

/// Run part `index` of `count` of the batches of `part` (of `loaded`) into `part.dir/shard.ohd`.
pub fn run_shard(loaded: &Loaded, part: &Part, index: u64, count: u64, obs: &dyn Observer) -> Result<ShardSummary> {
    let (exp, dir) = (&part.exp, &part.dir);
    if count > exp.plan.batches {
        return Err(Error::Input(format!(
            "--shard {index}/{count}: expected at most run.batches = {} parts (raise run.batches, 16 to 65536, for more)",
            exp.plan.batches
        )));
    }
    let range = exp.shard_batches(index, count);
    let header = ShardHeader {
        fingerprint: part.fingerprint,
        index,
        count,
        first: range.start,
        last: range.end,
        batches: exp.plan.batches,
        paths_per_batch: exp.plan.paths_per_batch,
        tallies: exp.output_layout().tallies() as u64,
        config_text: loaded.text.clone(),
        config_source: loaded.source_path.clone(),
        // Results do not depend on the thread count: the merged run does not record one shard's.
        overrides: loaded.overrides.iter().filter(|s| !s.starts_with("run.threads=")).cloned().collect(),
    };
    // The temporary shard file of a killed `ohd run --shard` is its own.
    crate::io::remove_stale_temporaries(dir, |n| n == FILE_NAME)?;
    let path = dir.path().join(FILE_NAME);
    let start = std::time::Instant::now();
    let mut writer = ShardWriter::create(dir, FILE_NAME, &header)?;
    let mut trailer = ShardTrailer { threads: exp.plan.effective_threads() as u64, ..Default::default() };
    let mut sink = |sums: &[f64], stats: RunStats, lines: Vec<RecordedLine>| {
        trailer.stats.merge(&stats);
        trailer.lines.extend(lines);
        writer.batch(sums)
    };
    let paths = (range.end - range.start) * exp.plan.paths_per_batch;
    {
        let progress = obs.progress(paths, None);
        exp.run_batches(&part.decisions, range.clone(), &*progress, &mut sink)?;
    }
    trailer.seconds = start.elapsed().as_secs_f64();
    let seconds = trailer.seconds;
    writer.finish(&trailer)?;
    let summary = ShardSummary { index, count, range, batches: exp.plan.batches, paths, seconds, path };
    obs.event(Event::ShardWritten(&summary));
    Ok(summary)
}

/// Merge the shards in `dirs` (every part of one run, any order) into the run's outputs in
/// `out`, identical to a single run's (the manifest's timings aside): of a scan per pointing,
/// then the VAD wind. The configuration is the one the shards recorded.
pub fn merge(dirs: &[PathBuf], out: &Path, figures: bool, obs: &dyn Observer) -> Result<Finished> {
    let Some(first) = dirs.first() else {
        return Err(Error::Input("no shard directories given".into()));
    };
    // The directory, locked for the whole merge: found unusable now, before the shards are read.
    let out = OutDir::create(out)?;
    DirWriter::check(&out, Output::Run)?;
    // A scan's shards are per pointing: DIR/pointing_NN/shard.ohd.
    let head = [first.join(FILE_NAME), pointing_dir(first, 0).join(FILE_NAME)]
        .into_iter()
        .find(|p| p.exists())
        .unwrap_or_else(|| first.join(FILE_NAME));
    let h = ShardReader::open(&head)?.header;
    // The configuration recorded in the shard: if it no longer loads, the shard is what is wrong.
    let (table, exp) = crate::config::load(&h.config_text, &h.config_source, &h.overrides)
        .map_err(|e| Error::invalid_file(&head, format!("the configuration it records does not load: {e}")))?;
    let inv = Invocation { config_source: h.config_source, overrides: h.overrides, figures };
    let mut scan = Scan::default();
    let parts = parts(&exp, &table, &out)?;
    let mut last = None;
    for part in &parts {
        let sub = |d: &PathBuf| part.pointing.map_or_else(|| d.clone(), |i| pointing_dir(d, i));
        let shards = dirs.iter().map(|d| ShardReader::open(&sub(d).join(FILE_NAME))).collect::<Result<Vec<_>>>()?;
        let shards = check_set(shards)?;
        if shards[0].header.fingerprint != part.fingerprint {
            return Err(Error::invalid_file(
                &shards[0].path,
                "its configuration no longer resolves to the run it records (was ohd or a file it reads changed?)",
            ));
        }
        let count = shards.len();
        let output = fold(&part.exp, &part.decisions, shards)?;
        scan.writing(&out, &parts, part)?;
        let timing = write_run_with(&part.dir, &part.exp, &output, &table, &inv, &*obs.postprocess())?.timing;
        let dir = part.dir.path();
        obs.event(Event::Merged { exp: &part.exp, output: &output, dir, shards: count, timing: &timing });
        scan.add(part, &output, timing);
        if parts.len() == 1 {
            last = Some(output);
        }
    }
    let vad = scan.finish(&exp, figures, obs)?;
    match (parts.len(), last) {
        (1, Some(output)) => Ok(Finished::Run(Box::new(output))),
        (n, _) => Ok(Finished::Scan { pointings: n, vad }),
    }
}

/// Check that `shards` are all the parts of one run, each once: same fingerprint and count,
/// every index from 0 to count − 1. Returns them in index order.
pub fn check_set(mut shards: Vec<ShardReader>) -> Result<Vec<ShardReader>> {
    let Some(first) = shards.first() else {
        return Err(Error::Input("no shard directories given".into()));
    };
    let (fp, count, path0) = (first.header.fingerprint, first.header.count, first.path.clone());
    for s in &shards {
        if s.header.fingerprint != fp || s.header.count != count {
            return Err(Error::invalid_file(
                &s.path,
                format!(
                    "a shard of a different run than {} (configuration, --set, seed, samples or shard count differ)",
                    path0.display()
                ),
            ));
        }
    }
    shards.sort_by_key(|s| s.header.index);
    for w in shards.windows(2) {
        if w[0].header.index == w[1].header.index {
            return Err(Error::Input(format!(
                "shard {}/{count} given twice: {} and {}",
                w[0].header.index,
                w[0].path.display(),
                w[1].path.display()
            )));
        }
    }
    let have: Vec<u64> = shards.iter().map(|s| s.header.index).collect();
    let missing: Vec<u64> = (0..count).filter(|i| !have.contains(i)).collect();
    if !missing.is_empty() {
        return Err(Error::Input(format!(
            "shard(s) {} of {count} missing (give the directory of every part of the run)",
            crate::error::list(missing)
        )));
    }
    Ok(shards)
}

/// Fold the batches of `shards` (from [`check_set`]: every part of one run of `exp` with
/// `decisions`, in order) into the run's output, exactly as a single process folds them. The
/// output's wall time is the shards' total and its thread count their largest.
pub fn fold(exp: &Experiment, decisions: &Decisions, shards: Vec<ShardReader>) -> Result<RunOutput> {
    let len = exp.output_layout().tallies();
    let mut estimates = BatchAccumulator::new(len);
    let (mut stats, mut lines, mut seconds, mut threads) = (RunStats::default(), Vec::new(), 0.0, 0);
    let mut sums = vec![0.0; len];
    for mut s in shards {
        let h = &s.header;
        let expected = exp.shard_batches(h.index, h.count);
        if h.batches != exp.plan.batches
            || h.paths_per_batch != exp.plan.paths_per_batch
            || h.tallies != len as u64
            || (h.first..h.last) != expected
        {
            return Err(Error::invalid_file(&s.path, "does not match the experiment it names (batches or tallies)"));
        }
        for _ in expected {
            s.batch(&mut sums)?;
            estimates.push(&sums, exp.plan.paths_per_batch);
        }
        let t = s.trailer()?;
        stats.merge(&t.stats);
        lines.extend(t.lines);
        seconds += t.seconds;
        threads = threads.max(t.threads as usize);
    }
    let mut out = exp.finish(decisions, estimates, stats, lines, seconds);
    out.threads = threads;
    Ok(out)
}
