//! Output files: written atomically (a temporary file in the same directory, then a rename).
//! Input: OpenVDB grids ([`vdb`]).

mod binary;
pub mod checkpoint;
pub mod converge;
pub mod fmcw;
pub mod ldh;
pub mod lidar;
pub mod manifest;
pub mod npy;
pub mod plot;
pub mod png;
pub mod scan;
pub mod shard;
pub mod table;
pub mod vdb;

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

/// An EXR image of named `f32` channels (`ny` rows of `nx`), as bytes.
pub fn exr_bytes(nx: usize, ny: usize, channels: &[(&str, &[f64])]) -> std::result::Result<Vec<u8>, String> {
    use exr::prelude::*;
    let list: Vec<AnyChannel<FlatSamples>> = channels
        .iter()
        .map(|(name, data)| AnyChannel::new(*name, FlatSamples::F32(data.iter().map(|&v| v as f32).collect())))
        .collect();
    let layer = Layer::new(
        (nx, ny),
        LayerAttributes::named("ohd"),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(list)),
    );
    let mut cursor = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer).write().to_buffered(&mut cursor).map_err(|e| e.to_string())?;
    Ok(cursor.into_inner())
}
