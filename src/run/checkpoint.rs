//! Checkpoints of a running part (`ohd run --checkpoint-seconds`, `--resume`): saved into
//! `DIR/checkpoint.ohd` every so many seconds (the file format: [`crate::io::persist::checkpoint`]),
//! fingerprinted with the configuration as run, so that a checkpoint or shard is only ever taken
//! up by the experiment (and pointing) that wrote it.

use std::sync::Mutex;
use std::time::{Duration, Instant};

use super::{CHECKPOINT, Part};
use crate::error::Result;
use crate::experiment::{Checkpoint, RunOutput, RunState};
use crate::io::outdir::OutDir;

/// Saves a part's state into its checkpoint file every `every`.
#[derive(Debug)]
pub struct FileCheckpoint {
    dir: OutDir,
    fingerprint: u64,
    every: Duration,
    last: Mutex<Instant>,
}

impl FileCheckpoint {
    /// Checkpoints of `part` every `seconds` (≥ 0) (the temporary checkpoint files a killed ohd
    /// left in its directory removed).
    pub fn new(part: &Part, seconds: f64) -> Result<Self> {
        crate::io::remove_stale_temporaries(&part.dir, |n| n == CHECKPOINT)?;
        Ok(FileCheckpoint {
            dir: part.dir.clone(),
            fingerprint: part.fingerprint,
            // An interval beyond `Duration`'s range (≈ 5.8·10¹¹ years) never comes due.
            every: Duration::try_from_secs_f64(seconds).unwrap_or(Duration::MAX),
            last: Mutex::new(Instant::now()),
        })
    }
}

impl Checkpoint for FileCheckpoint {
    fn due(&self) -> bool {
        self.last.lock().is_ok_and(|t| t.elapsed() >= self.every)
    }

    fn save(&self, state: &RunState) -> Result<()> {
        crate::io::persist::checkpoint::write(&self.dir, CHECKPOINT, self.fingerprint, state)?;
        if let Ok(mut t) = self.last.lock() {
            *t = Instant::now();
        }
        Ok(())
    }
}

/// Save the finished `output` of `part` as its checkpoint: resumed, it finishes at once.
pub fn save_final(part: &Part, output: &RunOutput) -> Result<()> {
    crate::io::persist::checkpoint::write(&part.dir, CHECKPOINT, part.fingerprint, &output.final_state())
}
