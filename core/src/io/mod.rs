//! Input files: their formats ([`formats`]: `.npy`, OpenEXR, PNG encoding, phase-function
//! tables, the OpenVDB reader) and [`read_limited`]: every input file is read with a size limit
//! (issue 21: a path to `/dev/zero` read gigabytes before failing). The files a run writes, and
//! the directories it writes them into, are the `ohd` crate's (`ohd::io`).

pub mod formats;

use std::io::Read;
use std::path::Path;

use crate::error::{Error, Result};

/// A byte count for messages: `64 MiB`, `4 GiB`, `1.5 KiB`, `12 bytes`.
pub fn byte_size(n: u64) -> String {
    const UNITS: [(&str, u64); 3] = [("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)];
    match UNITS.iter().find(|(_, u)| n >= *u) {
        Some((name, u)) if n % u == 0 => format!("{} {name}", n / u),
        Some((name, u)) => format!("{:.1} {name}", n as f64 / *u as f64),
        None => format!("{n} bytes"),
    }
}

/// Why `path` (of type `kind`) cannot be read as a file: not a regular file, named.
fn not_regular(path: &Path, kind: std::fs::FileType, what: &str) -> Error {
    #[cfg(unix)]
    let name = {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_char_device() {
            "a character device"
        } else if kind.is_block_device() {
            "a block device"
        } else if kind.is_fifo() {
            "a FIFO"
        } else if kind.is_socket() {
            "a socket"
        } else if kind.is_dir() {
            "a directory"
        } else {
            "not a file"
        }
    };
    #[cfg(not(unix))]
    let name = if kind.is_dir() { "a directory" } else { "not a file" };
    Error::invalid_file(path, format!("not a regular file ({name}): expected {what}"))
}

fn too_large(path: &Path, size: Option<u64>, limit: u64, what: &str) -> Error {
    let (mut shown, mut max) = (size.map(byte_size), byte_size(limit));
    if size.is_some_and(|n| n - limit <= limit / 1000) {
        // Just above the limit: in bytes, or both would read the same.
        (shown, max) = (size.map(|n| format!("{n} bytes")), format!("{limit} bytes"));
    }
    let shown = shown.map_or_else(|| "larger than".to_string(), |s| format!("{s}, above"));
    Error::invalid_file(path, format!("{shown} the limit of {max} for {what}"))
}

/// Read the whole file at `path`, at most `limit` bytes; `what` names the kind of file in errors
/// ("a configuration file"). A path that is not a regular file (a device such as `/dev/zero`, a
/// FIFO, a directory) or a file above `limit` is refused before anything is read, naming the file
/// and the limit (an input error, exit status 2); a file that grows while read is cut at
/// `limit + 1` bytes and refused too.
pub fn read_limited(path: &Path, limit: u64, what: &str) -> Result<Vec<u8>> {
    let rerr = |source| Error::Read { path: path.to_path_buf(), source };
    let meta = std::fs::metadata(path).map_err(rerr)?;
    if !meta.is_file() {
        return Err(not_regular(path, meta.file_type(), what));
    }
    if meta.len() > limit {
        return Err(too_large(path, Some(meta.len()), limit, what));
    }
    let file = std::fs::File::open(path).map_err(rerr)?;
    // The file opened is the one checked (not swapped for a device since).
    let meta = file.metadata().map_err(rerr)?;
    if !meta.is_file() {
        return Err(not_regular(path, meta.file_type(), what));
    }
    let mut bytes = Vec::with_capacity(meta.len().min(limit) as usize);
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes).map_err(rerr)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(path, None, limit, what));
    }
    Ok(bytes)
}

/// [`read_limited`] as UTF-8 text.
pub fn read_text_limited(path: &Path, limit: u64, what: &str) -> Result<String> {
    String::from_utf8(read_limited(path, limit, what)?).map_err(|e| {
        Error::invalid_file(
            path,
            format!("not UTF-8 text (invalid byte at {}): expected {what}", e.utf8_error().valid_up_to()),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_sizes_read_short() {
        assert_eq!(byte_size(64 << 20), "64 MiB");
        assert_eq!(byte_size(4 << 30), "4 GiB");
        assert_eq!(byte_size(1536), "1.5 KiB");
        assert_eq!(byte_size(12), "12 bytes");
    }

    /// Reads are bounded: a file above the limit, a device and a directory are refused naming
    /// the file and the limit; a file at the limit is read whole.
    #[test]
    fn reads_are_bounded_and_refuse_what_is_not_a_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.toml");
        std::fs::write(&path, b"0123456789").unwrap();
        assert_eq!(read_limited(&path, 10, "a test file").unwrap(), b"0123456789");
        let e = read_limited(&path, 9, "a test file").unwrap_err();
        assert!(e.is_input_error(), "{e}");
        let msg = e.to_string();
        assert!(
            msg.contains("f.toml") && msg.contains("10 bytes, above the limit of 9 bytes for a test file"),
            "{msg}"
        );
        let e = read_limited(dir.path(), 100, "a test file").unwrap_err().to_string();
        assert!(e.contains("not a regular file (a directory)"), "{e}");
        #[cfg(unix)]
        {
            let t = std::time::Instant::now();
            let e = read_limited(Path::new("/dev/zero"), 1 << 20, "a test file").unwrap_err().to_string();
            assert!(e.contains("/dev/zero") && e.contains("a character device"), "{e}");
            assert!(t.elapsed().as_secs_f64() < 1.0);
        }
        std::fs::write(&path, [0xff, 0xfe]).unwrap();
        let e = read_text_limited(&path, 10, "a test file").unwrap_err().to_string();
        assert!(e.contains("not UTF-8"), "{e}");
    }
}
