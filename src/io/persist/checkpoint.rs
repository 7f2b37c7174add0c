//! Checkpoint files of a running experiment (`ohd run --checkpoint-seconds`, `--resume`;
//! [`crate::run::checkpoint`]): the [`RunState`] at a batch boundary in a small binary file
//! (little-endian), written atomically (temporary file, then rename), with the fingerprint of the
//! configuration so that a checkpoint is only ever resumed by the experiment that wrote it.
//!
//! Layout: `OHDCKPT` and a format byte; the fingerprint (u64); `next`, `end` (u64); `err`,
//! `elapsed` (f64); the six run counters (u64); the accumulator's batch count and length (u64)
//! and its `mean` and `m2` (f64 each); the number of recorded lines (u64) and each line's `roi`
//! (u32), `class` (u8), `weight`, `frequency`, `gamma` (f64); the CRC-32 of everything before it
//! (u32), so that a flipped byte is refused rather than resumed from.

use std::path::Path;

use super::binary::{Reader, Writer};
use crate::error::{Error, Result};
use crate::experiment::RunState;
use crate::stats::BatchAccumulator;

const MAGIC: &[u8; 8] = b"OHDCKPT\x02";

/// The bytes of a checkpoint of `s` for the configuration with fingerprint `fp`.
pub fn to_bytes(fp: u64, s: &RunState) -> Vec<u8> {
    let (batches, mean, m2) = s.estimates.parts();
    let mut w = Writer(Vec::with_capacity(128 + 16 * mean.len() + 29 * s.lines.len()));
    w.0.extend_from_slice(MAGIC);
    w.u64s(&[fp, s.next, s.end]);
    w.f64s(&[s.err, s.elapsed]);
    w.stats(&s.stats);
    w.u64s(&[batches as u64, mean.len() as u64]);
    w.f64s(mean);
    w.f64s(m2);
    w.lines(&s.lines);
    let crc = crc32fast::hash(&w.0);
    w.0.extend_from_slice(&crc.to_le_bytes());
    w.0
}

/// Parse a checkpoint: `(fingerprint, state)`, `None` if it is not a whole checkpoint.
pub fn from_bytes(bytes: &[u8]) -> Option<(u64, RunState)> {
    let (body, crc) = bytes.split_at_checked(bytes.len().checked_sub(4)?)?;
    if crc32fast::hash(body).to_le_bytes() != crc {
        return None;
    }
    let mut r = Reader(body.strip_prefix(MAGIC.as_slice())?);
    let (fp, next, end) = (r.u64()?, r.u64()?, r.u64()?);
    let (err, elapsed) = (r.f64()?, r.f64()?);
    let stats = r.stats()?;
    let (batches, len) = (r.u64()?, r.u64()?);
    let mean = r.f64s(len)?;
    let m2 = r.f64s(len)?;
    let estimates = BatchAccumulator::from_parts(usize::try_from(batches).ok()?, mean, m2)?;
    let lines = r.lines()?;
    if !r.is_empty() || next > end {
        return None;
    }
    Some((fp, RunState { estimates, stats, lines, next, end, err, elapsed }))
}

/// Write the checkpoint of `s` to the file `name` of `dir`, atomically.
pub fn write(dir: &crate::io::outdir::OutDir, name: &str, fp: u64, s: &RunState) -> Result<()> {
    dir.write_atomic(name, &to_bytes(fp, s))
}

/// Largest checkpoint of an experiment with `tallies` tallies and the memory budget `budget`
/// (bytes): its fixed part, the accumulator's mean and m² (16 bytes per tally) and the recorded
/// lines, which a run holds in memory too, up to the budget.
pub fn max_bytes(tallies: usize, budget: u64) -> u64 {
    4096 + 16 * tallies as u64 + budget
}

/// Read the checkpoint at `path` for the configuration with fingerprint `fp`, checking that it
/// is whole, of this experiment (`tallies` long) and not past its end; a file above `limit`
/// bytes ([`max_bytes`]) or not a regular file is refused unread.
pub fn read(path: &Path, fp: u64, tallies: usize, limit: u64) -> Result<RunState> {
    let bytes = crate::io::read_limited(path, limit, "an ohd checkpoint")?;
    let bad = |why: &str| Error::invalid_file(path, why);
    let (got, state) = from_bytes(&bytes).ok_or_else(|| bad("not a whole ohd checkpoint (truncated or corrupt)"))?;
    if got != fp || state.estimates.mean().len() != tallies {
        return Err(bad("written by a different experiment (configuration or --set differ); rerun without --resume"));
    }
    let (_, mean, m2) = state.estimates.parts();
    if !mean.iter().chain(m2).all(|v| super::plausible(*v)) {
        return Err(bad("holds a tally no run can produce (not finite, or beyond 1e100): corrupt"));
    }
    Ok(state)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::RecordedLine;
    use crate::stats::RunStats;

    #[test]
    fn round_trip_and_corruption() {
        let mut acc = BatchAccumulator::new(3);
        acc.push(&[1.0, 2.0, 3.0], 10);
        acc.push(&[2.0, 0.5, 3.0], 10);
        let s = RunState {
            estimates: acc,
            stats: RunStats { paths: 20, scattering_events: 7, ..Default::default() },
            lines: vec![RecordedLine { roi: 2, class: 1, weight: 0.5, frequency: -3.0, gamma: 1e-3 }],
            next: 2,
            end: 16,
            err: 0.25,
            elapsed: 1.5,
        };
        let b = to_bytes(42, &s);
        let (fp, t) = from_bytes(&b).expect("parses");
        assert_eq!(fp, 42);
        assert_eq!(t.estimates.parts(), s.estimates.parts());
        assert_eq!((t.stats, t.lines.clone(), t.next, t.end, t.err, t.elapsed), (s.stats, s.lines, 2, 16, 0.25, 1.5));
        for cut in 0..b.len() {
            assert!(from_bytes(&b[..cut]).is_none(), "a checkpoint cut at {cut} parsed");
        }
        let mut longer = b.clone();
        longer.push(0);
        assert!(from_bytes(&longer).is_none());
        // Any one flipped bit is caught (issue 21: a flipped data byte was resumed from).
        for i in 0..b.len() {
            let mut flipped = b.clone();
            flipped[i] ^= 1 << (i % 8);
            assert!(from_bytes(&flipped).is_none(), "a checkpoint with byte {i} flipped parsed");
        }
    }
}
