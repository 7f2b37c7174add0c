//! Checkpoints of a running part (`ohd run --checkpoint-seconds`, `--resume`): saved into
//! `DIR/checkpoint.ohd` every so many seconds (the file format: [`crate::io::persist::checkpoint`]),
//! fingerprinted with the configuration as run, so that a checkpoint or shard is only ever taken
//! up by the experiment (and pointing) that wrote it.

use std::sync::Mutex;
use std::time::{Duration, Instant};

use super::Part;
use crate::error::{Error, Result};
use crate::experiment::{Checkpoint, RunOutput, RunState};

/// FNV-1a (64 bit) of `text`: the fingerprint of a configuration.
pub fn fingerprint(text: &str) -> u64 {
    text.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// The fingerprint of the configuration as run, without `run.threads` (results do not depend
/// on it, so a run may resume, or a shard run, on another thread count).
pub fn config_fingerprint(table: &toml::Table) -> u64 {
    let mut t = table.clone();
    if let Some(toml::Value::Table(run)) = t.get_mut("run") {
        run.remove("threads");
    }
    fingerprint(&toml::to_string(&t).unwrap_or_default())
}

/// Saves a part's state into its checkpoint file every `every`.
#[derive(Debug)]
pub struct FileCheckpoint {
    path: std::path::PathBuf,
    fingerprint: u64,
    every: Duration,
    last: Mutex<Instant>,
}

impl FileCheckpoint {
    /// Checkpoints of `part` every `seconds` (≥ 0), its directory created.
    pub fn new(part: &Part, seconds: f64) -> Result<Self> {
        create_dir(part)?;
        Ok(FileCheckpoint {
            path: part.checkpoint(),
            fingerprint: part.fingerprint,
            every: Duration::from_secs_f64(seconds),
            last: Mutex::new(Instant::now()),
        })
    }
}

impl Checkpoint for FileCheckpoint {
    fn due(&self) -> bool {
        self.last.lock().is_ok_and(|t| t.elapsed() >= self.every)
    }

    fn save(&self, state: &RunState) -> Result<()> {
        crate::io::persist::checkpoint::write(&self.path, self.fingerprint, state)?;
        if let Ok(mut t) = self.last.lock() {
            *t = Instant::now();
        }
        Ok(())
    }
}

fn create_dir(part: &Part) -> Result<()> {
    std::fs::create_dir_all(&part.dir).map_err(|source| Error::Write { path: part.dir.clone(), source })
}

/// Save the finished `output` of `part` as its checkpoint: resumed, it finishes at once.
pub fn save_final(part: &Part, output: &RunOutput) -> Result<()> {
    create_dir(part)?;
    crate::io::persist::checkpoint::write(&part.checkpoint(), part.fingerprint, &output.final_state())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fingerprints_differ_and_ignore_threads() {
        assert_ne!(fingerprint("a = 1"), fingerprint("a = 2"));
        let t = |s: &str| -> toml::Table { s.parse().unwrap() };
        let a = config_fingerprint(&t("[run]\nseed = 1\nthreads = 1\n"));
        assert_eq!(a, config_fingerprint(&t("[run]\nseed = 1\nthreads = 4\n")));
        assert_ne!(a, config_fingerprint(&t("[run]\nseed = 2\nthreads = 1\n")));
    }
}
