//! Files, by role:
//!
//! * [`formats`]: what bytes look like — `.npy`, OpenEXR, PNG encoding, phase-function tables and
//!   the OpenVDB reader;
//! * [`write`](mod@write): a finished run's outputs, as its output registry declares them, and the manifest;
//! * [`figures`]: PNG previews and plots;
//! * [`persist`]: runs in progress, as shard and checkpoint files (one binary codec);
//! * [`write_atomic`]: every output file is written to a temporary name and renamed into place.

pub mod figures;
pub mod formats;
pub mod persist;
pub mod write;

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// The temporary name `path` is written under before it is renamed into place: hidden, in the
/// same directory (so the rename is atomic), and per process.
pub(crate) fn temporary_path(path: &Path) -> PathBuf {
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    dir.join(format!(".{name}.tmp-{}", std::process::id()))
}

/// Write `bytes` to `path` atomically: readers see the old file or the complete new one.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let tmp = temporary_path(path);
    let werr = |source| Error::Write { path: path.to_path_buf(), source };
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(werr)
}
