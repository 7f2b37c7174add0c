//! Special files of the tests' own (issue 33: a hostile test pointed `ohd mie --table` at the
//! machine's `/dev/full` and, run as root, replaced it with a regular file). No test names a real
//! device or system path: a FIFO, and where the tests may make them (as root) character devices
//! with the numbers of `/dev/zero`, `/dev/null` and `/dev/full`, are made in a directory of the
//! test build's own (`target/tmp/special-PID`), and a canary file beside an output directory shows
//! that nothing outside it changed.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use rustix::fs::{CWD, FileType, Mode, makedev, mknodat};

/// The special files: always a FIFO; character devices where this process may make them.
#[derive(Debug)]
pub struct Special {
    /// A directory of the tests' own, holding the others.
    pub dir: PathBuf,
    pub fifo: PathBuf,
    /// Like `/dev/zero` (reads never end), `/dev/null`, `/dev/full` (writes fail, ENOSPC).
    pub zero: Option<PathBuf>,
    pub null: Option<PathBuf>,
    pub full: Option<PathBuf>,
}

impl Special {
    /// A file that never ends when read: the zero device where there is one, else the FIFO.
    pub fn endless(&self) -> &Path {
        self.zero.as_deref().unwrap_or(&self.fifo)
    }

    /// A file that is not regular and may not be replaced: the full device, else the FIFO.
    pub fn device_or_fifo(&self) -> &Path {
        self.full.as_deref().unwrap_or(&self.fifo)
    }
}

/// The special files of this test process, made once.
pub fn special() -> &'static Special {
    static SPECIAL: OnceLock<Special> = OnceLock::new();
    SPECIAL.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("special-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let fifo = dir.join("fifo");
        mknodat(CWD, &fifo, FileType::Fifo, Mode::from_raw_mode(0o600), 0).expect("a FIFO");
        let device = |name: &str, minor: u32| {
            let p = dir.join(name);
            match mknodat(CWD, &p, FileType::CharacterDevice, Mode::from_raw_mode(0o666), makedev(1, minor)) {
                Ok(()) => Some(p),
                Err(e) => {
                    eprintln!("no device node {name} of the tests' own ({e}): its cases use the FIFO or are skipped");
                    None
                }
            }
        };
        Special { zero: device("zero", 5), null: device("null", 3), full: device("full", 7), fifo, dir }
    })
}

/// A canary file beside `dir` (in its parent), for [`Canary::unchanged`].
pub struct Canary {
    path: PathBuf,
    bytes: Vec<u8>,
}

impl Canary {
    pub fn beside(dir: &Path) -> Canary {
        let parent = dir.parent().expect("a directory with a parent");
        std::fs::create_dir_all(parent).unwrap();
        let path = parent.join("canary.npy");
        let bytes = format!("canary {}\n", std::process::id()).into_bytes();
        std::fs::write(&path, &bytes).unwrap();
        Canary { path, bytes }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether the canary is as it was written (not truncated, replaced or removed).
    pub fn unchanged(&self) -> bool {
        let meta = std::fs::symlink_metadata(&self.path);
        meta.is_ok_and(|m| m.is_file()) && std::fs::read(&self.path).is_ok_and(|b| b == self.bytes)
    }
}
