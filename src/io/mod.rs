//! Files, by role:
//!
//! * [`formats`]: what bytes look like — `.npy`, OpenEXR, PNG encoding, phase-function tables and
//!   the OpenVDB reader;
//! * [`write`](mod@write): a finished run's outputs, as its output registry declares them, and the manifest;
//! * [`figures`]: PNG previews and plots;
//! * [`persist`]: runs in progress, as shard and checkpoint files (one binary codec);
//! * [`outdir`]: the directories ohd writes into, held open and locked; every output file is
//!   written to a temporary name created exclusively and renamed into place ([`write_atomic`]
//!   for a lone file; [`remove_stale_temporaries`] removes those a killed ohd left);
//! * [`read_limited`]: every input file is read with a size limit (issue 21: a path to
//!   `/dev/zero` read gigabytes before failing).

pub mod figures;
pub mod outdir;
pub mod persist;
pub mod write;

// The input side lives in the physics crate (`ohd-core`), which reads scenes' files.
pub use ohd_core::io::{byte_size, formats, read_limited, read_text_limited};

use std::path::Path;

use crate::error::{Error, Result};

/// The name `.NAME.tmp-PID-RANDOM` of a temporary file ([`outdir::OutDir::temporary`]; before
/// issue 33 `.NAME.tmp-PID`) as `(NAME, PID)`.
fn temporary_of(file: &str) -> Option<(&str, u32)> {
    let (name, tail) = file.strip_prefix('.')?.rsplit_once(".tmp-")?;
    let pid = tail.split_once('-').map_or(tail, |(pid, random)| {
        if random.len() == 16 && random.bytes().all(|b| b.is_ascii_hexdigit()) { pid } else { "" }
    });
    let digits = !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit());
    Some((name, pid.parse().ok().filter(|_| digits)?))
}

/// The probe files of `ohd` before issue 33 (`.ohd-write-probe-PID`); today's probe is a
/// temporary file of the name [`PROBE`].
const OLD_PROBE: &str = ".ohd-write-probe-";

/// The name of the probe [`outdir::OutDir::create`] writes (as a temporary file) and removes.
pub(crate) const PROBE: &str = "ohd-probe";

/// Remove the temporary files `.NAME.tmp-…` in `dir` of the names `NAME` that `ours` accepts,
/// and the probes, which a killed ohd left (another process's: this one's are being written).
/// A missing `dir` is no error.
pub fn remove_stale_temporaries(dir: &outdir::OutDir, ours: impl Fn(&str) -> bool) -> Result<()> {
    let me = std::process::id();
    let old_probe =
        |f: &str| f.strip_prefix(OLD_PROBE).is_some_and(|p| !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit()));
    for file in dir.files()? {
        let stale = temporary_of(&file).is_some_and(|(name, pid)| pid != me && (name == PROBE || ours(name)));
        if stale || old_probe(&file) {
            dir.remove_file(&file)?;
        }
    }
    Ok(())
}

/// Write `bytes` to the file `path` atomically (readers see the old file or the complete new
/// one), in its existing directory: a temporary file created exclusively beside it, renamed over
/// it. An existing `path` that is not a regular file (a device, a FIFO, a directory, or a link to
/// one) is refused, not replaced (issue 33: `ohd mie --table /dev/full` replaced the device).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    // (`file_name` is none for `..` and `.`; a trailing `/` names a directory. The name itself is
    // checked plain by `check_target`.)
    let name = path.file_name().and_then(|n| n.to_str());
    let Some(name) = name.filter(|_| !path.as_os_str().to_string_lossy().ends_with('/')) else {
        return Err(Error::Refused {
            path: path.to_path_buf(),
            why: "not a file name: expected a path to a file".into(),
        });
    };
    // (The working directory for a bare file name: shown as the name alone.)
    let dir = outdir::OutDir::existing(path.parent().unwrap_or(Path::new("")))?;
    dir.check_target(name)?;
    dir.write_atomic(name, bytes)
}
