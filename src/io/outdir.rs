//! The directories ohd writes into ([`OutDir`]): held open, so that every file ohd creates,
//! replaces or removes there is named relative to the directory it was given, by one plain name,
//! and never reached through a symbolic link planted inside it (issue 33: temporary and probe
//! files opened by path followed planted links and truncated what they pointed to; a scan wrote
//! into, and removed from, a pointing directory that was a link to another directory).
//!
//! The contract (README "Output directory"):
//! - the directory given (`--out`) may be reached through links (it is the user's path); it is
//!   created with its parents if missing, and found unusable (a dangling link, a loop, a file, a
//!   name too long, read-only) before anything is traced;
//! - inside it, ohd writes only plain names (no `/`, no `..`): files through a temporary created
//!   exclusively (`O_CREAT | O_EXCL | O_NOFOLLOW`, a random name) and renamed over the name; a
//!   link at the name is replaced (the link, not what it points to); a directory, a device, a FIFO
//!   or a socket is refused, not replaced (for a lone file, `ohd mie --table`, a link to one too);
//! - its sub-directories (a scan's `pointing_NN/`) are made by ohd and opened without following
//!   a link: a link there is refused;
//! - a command that writes holds a lock on the directory for its whole life, and on each
//!   sub-directory it writes (a scan's pointing directories): an exclusive `flock` on the
//!   directory itself, held open, so that removing or replacing the file [`LOCK`] (which names
//!   the holder's process, for the message) releases nothing (issue 52: deleting the lock file
//!   mid-run let a second writer in; a run into `SCAN/pointing_00` went on beside the scan
//!   writing `SCAN`). A second writer into a held directory is refused naming it and the
//!   holder's process; so is a lone file written into it (`ohd mie --table`), and a lone file
//!   is never written at the lock's name.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{Read, Write};
use std::os::fd::OwnedFd;
use std::path::{Component, Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

use rustix::fs::{AtFlags, CWD, FileType, Mode, OFlags};

use crate::error::{Error, Result};

/// The lock file of a directory being written: holds the process ID of the ohd writing there.
pub const LOCK: &str = ".ohd-lock";

/// Tries at a fresh random temporary name before giving up (each try fails only if the name
/// exists: planted, or an astronomically unlikely collision).
const TEMPORARY_TRIES: usize = 16;

/// Whether `name` is one plain entry of a directory: not empty, no separator or NUL, not `.`
/// or `..`.
pub fn plain_name(name: &str) -> bool {
    !name.is_empty() && name != "." && name != ".." && !name.contains(['/', '\\', '\0'])
}

/// The refusal of `path` for `why` (an input error, exit status 2).
fn refused(path: &Path, why: impl Into<String>) -> Error {
    Error::Refused { path: path.to_path_buf(), why: why.into() }
}

/// What a file type is called in messages.
fn kind_name(t: FileType) -> &'static str {
    match t {
        FileType::RegularFile => "a regular file",
        FileType::Directory => "a directory",
        FileType::Symlink => "a symbolic link",
        FileType::Fifo => "a FIFO",
        FileType::Socket => "a socket",
        FileType::CharacterDevice => "a character device",
        FileType::BlockDevice => "a block device",
        _ => "not a file",
    }
}

fn io(e: rustix::io::Errno) -> std::io::Error {
    std::io::Error::from(e)
}

/// A random 64-bit number from the standard library's per-process random hash keys (seeded by
/// the OS), stirred by a counter: temporary names are not guessable.
fn random() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let mut h = std::hash::RandomState::new().build_hasher();
    h.write_u64(COUNTER.fetch_add(1, Ordering::Relaxed));
    h.finish()
}

/// The root of an [`OutDir`]: the directory held open, its lock if taken, the sub-directories
/// locked, and the directories made to reach it (released in this order: the sub-directories'
/// locks and the root's are gone before the directories made are removed).
#[derive(Debug)]
struct Root {
    fd: OwnedFd,
    lock: Option<Lock>,
    /// The sub-directories locked, by name, held as long as the root.
    subs: Mutex<BTreeMap<String, SubLock>>,
    /// Held for its drop.
    _made: Made,
}

/// A locked sub-directory, and whether ohd made it (then removed again if it is left empty).
#[derive(Debug)]
struct SubLock {
    lock: Lock,
    made: bool,
}

impl Root {
    fn new(fd: OwnedFd, lock: Option<Lock>, made: Made) -> Root {
        Root { fd, lock, subs: Mutex::default(), _made: made }
    }

    /// Whether this root locks the sub-directories it writes (an output directory does; the
    /// directory of a lone file has none).
    fn locks_subs(&self) -> bool {
        self.lock.as_ref().is_some_and(|l| l.named)
    }

    /// The open sub-directory `name`, if it is locked.
    fn locked_sub(&self, name: &str) -> Option<std::io::Result<OwnedFd>> {
        let subs = self.subs.lock().unwrap_or_else(PoisonError::into_inner);
        subs.get(name).map(|s| s.lock.dir.try_clone())
    }
}

impl Drop for Root {
    fn drop(&mut self) {
        let subs = std::mem::take(self.subs.get_mut().unwrap_or_else(PoisonError::into_inner));
        for (name, sub) in subs {
            drop(sub.lock);
            if sub.made {
                // Fails, and so keeps it, unless it is empty.
                let _ = rustix::fs::unlinkat(&self.fd, name.as_str(), AtFlags::REMOVEDIR);
            }
        }
        drop(self.lock.take());
    }
}

/// The directories made to reach an output directory (each as its parent, open, and its name),
/// outermost first: removed again, innermost first, if they are still empty when dropped (the
/// command was refused, or failed before writing: then it leaves nothing behind).
#[derive(Debug, Default)]
struct Made(Vec<(OwnedFd, std::ffi::OsString)>);

impl Drop for Made {
    fn drop(&mut self) {
        for (parent, name) in self.0.iter().rev() {
            // Fails, and so keeps it, unless it is empty.
            let _ = rustix::fs::unlinkat(parent, name.as_os_str(), AtFlags::REMOVEDIR);
        }
    }
}

/// A directory ohd writes into (see the module docs), or one of its sub-directories. Cheap to
/// clone: the root is shared (and its lock held until the last clone is dropped); a
/// sub-directory is made and opened (without following a link) at each use.
#[derive(Debug, Clone)]
pub struct OutDir {
    root: Arc<Root>,
    sub: Option<String>,
    path: PathBuf,
}

impl OutDir {
    /// The output directory `path` of a command that writes: created with its parents if missing,
    /// checked writable (a temporary file created exclusively and removed) and locked for as
    /// long as the value (or a clone) lives. Every failure is found here, before any work, and
    /// is an input error naming the directory.
    pub fn create(path: &Path) -> Result<OutDir> {
        let (fd, made) = open_path(path, true)?;
        let held = fd.try_clone().map_err(|e| refused(path, e.to_string()))?;
        // (Refused, the directories made are removed again: `made` is dropped.)
        let lock = Lock::take(held, path, true)?;
        let dir = OutDir { root: Arc::new(Root::new(fd, lock, made)), sub: None, path: path.to_path_buf() };
        // Writable: a probe, created as every temporary is and removed.
        let probe = dir.temporary("ohd-probe").map_err(|e| match e {
            Error::Write { source, .. } => refused(path, format!("cannot write into it: {source}")),
            e => e,
        })?;
        drop(probe);
        Ok(dir)
    }

    /// The existing directory `path`, for writing one file into a directory that is not an output
    /// directory (`ohd mie --table FILE`): refused if another ohd holds it (issue 52: a lone file
    /// was written into a directory being written), and locked shared while the value lives (lone
    /// files may be written side by side; no [`LOCK`] file).
    pub fn existing(path: &Path) -> Result<OutDir> {
        let shown = if path.as_os_str().is_empty() { Path::new(".") } else { path };
        let (fd, _) = open_path(shown, false)?;
        let held = fd.try_clone().map_err(|e| refused(shown, e.to_string()))?;
        let lock = Lock::take(held, shown, false)?;
        Ok(OutDir { root: Arc::new(Root::new(fd, lock, Made::default())), sub: None, path: path.to_path_buf() })
    }

    /// The sub-directory `name` (one plain name) of this output directory, made now if missing
    /// and locked as long as the output directory is (issue 52: another ohd writing into it is
    /// refused, and refuses another). A `name` that exists as anything but a directory (a link
    /// to one included) is refused, and so is a sub-directory another ohd holds.
    pub fn sub(&self, name: &str) -> Result<OutDir> {
        let path = self.path.join(name);
        if self.sub.is_some() || !plain_name(name) {
            return Err(refused(&path, "not one plain name inside the output directory"));
        }
        let sub = OutDir { root: self.root.clone(), sub: Some(name.to_string()), path };
        match self.kind(name)? {
            None | Some(FileType::Directory) => {}
            Some(t) => {
                return Err(refused(
                    &sub.path,
                    format!(
                        "{} where ohd keeps a sub-directory of its own: ohd does not follow or replace it",
                        kind_name(t)
                    ),
                ));
            }
        }
        if self.root.locks_subs() {
            self.lock_sub(name, &sub.path)?;
        }
        Ok(sub)
    }

    /// Lock the sub-directory `name` (at `path`) of the root, made if missing, unless it is locked
    /// already (by this root: a second lock of one process would conflict with its first).
    fn lock_sub(&self, name: &str, path: &Path) -> Result<()> {
        let mut subs = self.root.subs.lock().unwrap_or_else(PoisonError::into_inner);
        if subs.contains_key(name) {
            return Ok(());
        }
        let (fd, made) = open_sub(&self.root.fd, name, path)?;
        match Lock::take(fd, path, true) {
            Ok(Some(lock)) => {
                subs.insert(name.to_string(), SubLock { lock, made });
                Ok(())
            }
            Ok(None) => Ok(()),
            Err(e) => {
                if made {
                    let _ = rustix::fs::unlinkat(&self.root.fd, name, AtFlags::REMOVEDIR);
                }
                Err(e)
            }
        }
    }

    /// The directory's path as given (for messages and reading).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The directory, open: the root, or the sub-directory made if missing and opened without
    /// following a link.
    fn fd(&self) -> Result<OwnedFd> {
        let werr = |e: std::io::Error| Error::Write { path: self.path.clone(), source: e };
        let Some(name) = &self.sub else { return self.root.fd.try_clone().map_err(werr) };
        // A locked sub-directory is the one locked (what is named there meanwhile is not).
        if let Some(fd) = self.root.locked_sub(name) {
            return fd.map_err(werr);
        }
        open_sub(&self.root.fd, name, &self.path).map(|(fd, _)| fd)
    }

    /// The type of the entry `name` (not following a link), `None` if there is none.
    pub fn kind(&self, name: &str) -> Result<Option<FileType>> {
        let fd = match self.fd() {
            Ok(fd) => fd,
            Err(Error::Write { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(e),
        };
        match rustix::fs::statat(&fd, name, AtFlags::SYMLINK_NOFOLLOW) {
            Ok(st) => Ok(Some(FileType::from_raw_mode(st.st_mode))),
            Err(rustix::io::Errno::NOENT) => Ok(None),
            Err(e) => Err(Error::Write { path: self.path.join(name), source: io(e) }),
        }
    }

    /// Refuse `name` (one plain name) as a file to write unless it is missing, a regular file, or
    /// a link (to a regular file, or dangling): the link would be replaced, never followed. An
    /// input error: for a lone file (`ohd mie --table`), checked before it is made.
    pub fn check_target(&self, name: &str) -> Result<()> {
        if !plain_name(name) {
            return Err(refused(&self.path.join(name), "not one plain name inside the output directory"));
        }
        if name == LOCK {
            return Err(refused(&self.path.join(name), LOCK_NAME));
        }
        let problem = target_problem(&self.path, &self.fd()?, name, false)?;
        problem.map_or(Ok(()), |why| Err(refused(&self.path.join(name), why)))
    }

    /// A temporary file for `name` (one plain name), created exclusively under a random hidden
    /// name (`.NAME.tmp-PID-RANDOM`) beside it; [`Temporary::commit`] renames it over `name`, and
    /// dropped uncommitted it is removed. `name` itself is checked first: a link there is replaced
    /// (never followed), but a directory, a device, a FIFO or a socket is not (a write error,
    /// exit 1: files may have been written before it; [`OutDir::check_target`] refuses it as
    /// input before anything is).
    pub fn temporary(&self, name: &str) -> Result<Temporary> {
        let path = self.path.join(name);
        if !plain_name(name) {
            return Err(refused(&path, "not one plain name inside the output directory"));
        }
        if name == LOCK {
            return Err(refused(&path, LOCK_NAME));
        }
        temporary_in(self.fd()?, &self.path, name)
    }

    /// Write `bytes` to `name` atomically: readers see the old file or the complete new one.
    pub fn write_atomic(&self, name: &str, bytes: &[u8]) -> Result<()> {
        let mut t = self.temporary(name)?;
        t.write(bytes)?;
        t.commit().map(drop)
    }

    /// Remove the file `name` (one plain name; a link is removed, not what it points to); a
    /// missing file, or a directory, is left as it is.
    pub fn remove_file(&self, name: &str) -> Result<()> {
        let path = self.path.join(name);
        if !plain_name(name) {
            return Err(refused(&path, "not one plain name inside the output directory"));
        }
        let dir = match self.fd() {
            Ok(fd) => fd,
            Err(Error::Write { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => return Ok(()),
            Err(e) => return Err(e),
        };
        match rustix::fs::unlinkat(&dir, name, AtFlags::empty()) {
            Ok(()) | Err(rustix::io::Errno::NOENT | rustix::io::Errno::ISDIR | rustix::io::Errno::PERM) => Ok(()),
            Err(e) => Err(Error::Write { path, source: io(e) }),
        }
    }

    /// Remove this sub-directory if it is empty (what another program left there keeps it).
    /// Its lock is released first (ohd writes there no more; its lock file would keep it).
    pub fn remove_if_empty(&self) {
        if let Some(name) = &self.sub {
            let sub = self.root.subs.lock().unwrap_or_else(PoisonError::into_inner).remove(name);
            drop(sub);
            let _ = rustix::fs::unlinkat(&self.root.fd, name.as_str(), AtFlags::REMOVEDIR);
        }
    }

    /// The names of the regular files in the directory (none if it does not exist).
    pub fn files(&self) -> Result<Vec<String>> {
        let dir = match self.fd() {
            Ok(fd) => fd,
            Err(Error::Write { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => return Ok(vec![]),
            Err(e) => return Err(e),
        };
        let werr = |e| Error::Write { path: self.path.clone(), source: io(e) };
        let mut entries = rustix::fs::Dir::read_from(&dir).map_err(werr)?;
        let mut names = Vec::new();
        while let Some(entry) = entries.read() {
            let entry = entry.map_err(werr)?;
            let Ok(name) = entry.file_name().to_str() else { continue };
            let regular = match entry.file_type() {
                FileType::Unknown => rustix::fs::statat(&dir, name, AtFlags::SYMLINK_NOFOLLOW)
                    .is_ok_and(|st| FileType::from_raw_mode(st.st_mode) == FileType::RegularFile),
                t => t == FileType::RegularFile,
            };
            if regular {
                names.push(name.to_string());
            }
        }
        Ok(names)
    }
}

/// Why `name` in the directory `fd` (at `dir`) may not be written (see
/// [`OutDir::check_target`]), if it may not; with `links_replaced`, a link is no problem whatever
/// it points to (in an output directory the names are ohd's: a link planted there is replaced,
/// never followed).
fn target_problem(dir: &Path, fd: &OwnedFd, name: &str, links_replaced: bool) -> Result<Option<String>> {
    let path = dir.join(name);
    let kind = match rustix::fs::statat(fd, name, AtFlags::SYMLINK_NOFOLLOW) {
        Ok(st) => FileType::from_raw_mode(st.st_mode),
        Err(rustix::io::Errno::NOENT) => return Ok(None),
        Err(e) => return Err(Error::Write { path, source: io(e) }),
    };
    let target = match kind {
        FileType::RegularFile => return Ok(None),
        FileType::Symlink if links_replaced => return Ok(None),
        FileType::Symlink => match rustix::fs::statat(fd, name, AtFlags::empty()) {
            Ok(st) => FileType::from_raw_mode(st.st_mode),
            // Dangling, or a loop: the link is replaced.
            Err(_) => return Ok(None),
        },
        other => other,
    };
    Ok(match (kind, target) {
        (_, FileType::RegularFile) => None,
        (FileType::Symlink, t) => {
            Some(format!("a symbolic link to {}: not a regular file, ohd does not replace it", kind_name(t)))
        }
        (t, _) => Some(format!("{}: not a regular file, ohd does not replace it", kind_name(t))),
    })
}

/// A temporary file for `name` in the directory `dir` (at `dir_path`): see [`OutDir::temporary`].
fn temporary_in(dir: OwnedFd, dir_path: &Path, name: &str) -> Result<Temporary> {
    let path = dir_path.join(name);
    if let Some(why) = target_problem(dir_path, &dir, name, true)? {
        return Err(Error::Write { path, source: std::io::Error::other(why) });
    }
    let flags = OFlags::WRONLY | OFlags::CREATE | OFlags::EXCL | OFlags::NOFOLLOW | OFlags::CLOEXEC;
    let mut last = rustix::io::Errno::EXIST;
    for _ in 0..TEMPORARY_TRIES {
        let tmp = format!(".{name}.tmp-{}-{:016x}", std::process::id(), random());
        match rustix::fs::openat(&dir, tmp.as_str(), flags, Mode::from_raw_mode(0o666)) {
            Ok(fd) => {
                return Ok(Temporary { file: File::from(fd), dir, tmp, name: name.to_string(), path, done: false });
            }
            Err(e @ rustix::io::Errno::EXIST) => last = e,
            Err(e) => return Err(Error::Write { path, source: io(e) }),
        }
    }
    Err(Error::Write { path, source: io(last) })
}

/// The sub-directory `name` (at `path`) of the directory `root`, made if missing and opened
/// without following a link (a link or a file there is refused); and whether it was made now.
fn open_sub(root: &OwnedFd, name: &str, path: &Path) -> Result<(OwnedFd, bool)> {
    let werr = |e| Error::Write { path: path.to_path_buf(), source: io(e) };
    let made = match rustix::fs::mkdirat(root, name, Mode::from_raw_mode(0o777)) {
        Ok(()) => true,
        Err(rustix::io::Errno::EXIST) => false,
        Err(e) => return Err(werr(e)),
    };
    let flags = OFlags::RDONLY | OFlags::DIRECTORY | OFlags::NOFOLLOW | OFlags::CLOEXEC;
    let fd = rustix::fs::openat(root, name, flags, Mode::empty()).map_err(|e| match e {
        rustix::io::Errno::LOOP | rustix::io::Errno::NOTDIR => {
            refused(path, "not a directory (a symbolic link or a file): ohd does not follow or replace it")
        }
        e => werr(e),
    });
    match fd {
        Ok(fd) => Ok((fd, made)),
        Err(e) => {
            if made {
                let _ = rustix::fs::unlinkat(root, name, AtFlags::REMOVEDIR);
            }
            Err(e)
        }
    }
}

/// Open the directory at `path` (through links: it is the user's path), component by component,
/// creating what is missing when `create` (and returning what it made). A failure is an input
/// error naming `path`.
fn open_path(path: &Path, create: bool) -> Result<(OwnedFd, Made)> {
    let cannot = |what: &str, e: rustix::io::Errno| {
        let why = match e {
            rustix::io::Errno::LOOP => "a loop of symbolic links".to_string(),
            rustix::io::Errno::NOTDIR => "a part of the path is not a directory".to_string(),
            rustix::io::Errno::NOENT if what == "open" => {
                "missing (or a symbolic link to nothing: a dangling link)".to_string()
            }
            e => io(e).to_string(),
        };
        refused(path, format!("cannot {what} it as the output directory: {why}"))
    };
    if path.as_os_str().is_empty() {
        return Err(refused(path, "an empty path: expected a directory"));
    }
    let flags = OFlags::RDONLY | OFlags::DIRECTORY | OFlags::CLOEXEC;
    let mut fd = rustix::fs::openat(CWD, ".", flags, Mode::empty()).map_err(|e| cannot("open", e))?;
    let mut made = Made::default();
    for c in path.components() {
        let name = match c {
            Component::RootDir => {
                fd = rustix::fs::openat(CWD, "/", flags, Mode::empty()).map_err(|e| cannot("open", e))?;
                continue;
            }
            Component::CurDir | Component::Prefix(_) => continue,
            Component::ParentDir => std::ffi::OsStr::new(".."),
            Component::Normal(n) => n,
        };
        fd = match rustix::fs::openat(&fd, name, flags, Mode::empty()) {
            Ok(next) => next,
            Err(rustix::io::Errno::NOENT) if create && c != Component::ParentDir => {
                match rustix::fs::mkdirat(&fd, name, Mode::from_raw_mode(0o777)) {
                    Ok(()) => {
                        let parent = fd.try_clone().map_err(|e| refused(path, e.to_string()))?;
                        made.0.push((parent, name.to_os_string()));
                    }
                    // Exists: a link to nothing (then refused as dangling), or made meanwhile.
                    Err(rustix::io::Errno::EXIST) => {}
                    Err(e) => return Err(cannot("create", e)),
                }
                rustix::fs::openat(&fd, name, flags, Mode::empty()).map_err(|e| cannot("open", e))?
            }
            Err(e) => return Err(cannot("open", e)),
        };
    }
    Ok((fd, made))
}

/// A temporary file being written ([`OutDir::temporary`]).
#[derive(Debug)]
pub struct Temporary {
    file: File,
    dir: OwnedFd,
    tmp: String,
    name: String,
    path: PathBuf,
    done: bool,
}

impl Temporary {
    /// Append `bytes`.
    pub fn write(&mut self, bytes: &[u8]) -> Result<()> {
        self.file.write_all(bytes).map_err(|source| Error::Write { path: self.path.clone(), source })
    }

    /// The file being written, for a buffered writer.
    pub fn file(&mut self) -> &mut File {
        &mut self.file
    }

    /// The path written (for messages).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flush the file to disk and rename it over its name; returns the file, still open (to
    /// append to, as the marker is).
    pub fn commit(mut self) -> Result<File> {
        let werr = |source| Error::Write { path: self.path.clone(), source };
        self.file.sync_all().map_err(werr)?;
        rustix::fs::renameat(&self.dir, self.tmp.as_str(), &self.dir, self.name.as_str()).map_err(|e| werr(io(e)))?;
        self.done = true;
        self.file.try_clone().map_err(werr)
    }
}

impl Drop for Temporary {
    fn drop(&mut self) {
        if !self.done {
            let _ = rustix::fs::unlinkat(&self.dir, self.tmp.as_str(), AtFlags::empty());
        }
    }
}

/// Why a lone file is not written at the lock's name.
const LOCK_NAME: &str = "the name of the file that names the process writing into an output directory: ohd writes it only for the directory it writes into";

/// The lock of a directory: an exclusive `flock` on the directory itself (shared for a lone
/// file's directory), held open (released by the kernel if the process dies; removing or
/// replacing the [`LOCK`] file does not release it), and for an output directory the file
/// [`LOCK`] naming this process, removed (while still held) when dropped. On a file system
/// without locks on directories (NFS emulates `flock` by `fcntl`, which cannot lock a directory
/// opened for reading), the [`LOCK`] file is locked instead, as before issue 52.
#[derive(Debug)]
struct Lock {
    dir: OwnedFd,
    /// The [`LOCK`] file, when it is what is locked.
    file: Option<File>,
    /// Whether the [`LOCK`] file names this process (removed when dropped).
    named: bool,
}

impl Lock {
    /// Lock the directory `dir` (at `path`, for messages) and, if `named`, write this process's ID
    /// into its [`LOCK`]; or refuse naming the process that holds it. `None`: a lone file's
    /// directory (not `named`) on a file system without locks on directories, left unlocked.
    fn take(dir: OwnedFd, path: &Path, named: bool) -> Result<Option<Lock>> {
        // (A lone file's directory is locked shared: lone files may be written side by side.)
        use rustix::fs::FlockOperation::{NonBlockingLockExclusive, NonBlockingLockShared};
        match rustix::fs::flock(&dir, if named { NonBlockingLockExclusive } else { NonBlockingLockShared }) {
            Ok(()) => {}
            Err(rustix::io::Errno::WOULDBLOCK) => return Err(in_use(path, &dir)),
            Err(_) if named => return Lock::take_file(dir, path).map(Some),
            Err(_) => return Ok(None),
        }
        let lock = Lock { dir, file: None, named };
        if named {
            // Written as every file is (a link planted at the name is replaced, not followed).
            let held = lock.dir.try_clone().map_err(|e| refused(path, e.to_string()))?;
            let mut t = temporary_in(held, path, LOCK).map_err(|e| cannot_write(path, e))?;
            t.write(format!("{}\n", std::process::id()).as_bytes()).map_err(|e| cannot_write(path, e))?;
            t.commit().map_err(|e| cannot_write(path, e))?;
        }
        Ok(Some(lock))
    }

    /// Lock the file [`LOCK`] of `dir` (at `path`), or refuse naming the process that holds it.
    fn take_file(fd: OwnedFd, path: &Path) -> Result<Lock> {
        let lock_path = path.join(LOCK);
        let werr = |e: std::io::Error| Error::Write { path: lock_path.clone(), source: e };
        let flags = OFlags::RDWR | OFlags::CREATE | OFlags::NOFOLLOW | OFlags::NONBLOCK | OFlags::CLOEXEC;
        for _ in 0..TEMPORARY_TRIES {
            // What is planted at the lock's name — a link, a file with other names (a hard link
            // to a file elsewhere), anything but a regular file — is not opened or written: its
            // name is removed (the name is ohd's; what it points to is untouched), and tried again.
            let planted = rustix::fs::statat(&fd, LOCK, AtFlags::SYMLINK_NOFOLLOW)
                .is_ok_and(|st| FileType::from_raw_mode(st.st_mode) != FileType::RegularFile || st.st_nlink != 1);
            if planted {
                let _ = rustix::fs::unlinkat(&fd, LOCK, AtFlags::empty());
            }
            let file = match rustix::fs::openat(&fd, LOCK, flags, Mode::from_raw_mode(0o666)) {
                Ok(f) => File::from(f),
                Err(rustix::io::Errno::LOOP | rustix::io::Errno::NXIO | rustix::io::Errno::ISDIR) => {
                    let _ = rustix::fs::unlinkat(&fd, LOCK, AtFlags::empty());
                    continue;
                }
                Err(e) => return Err(werr(io(e))),
            };
            let st = rustix::fs::fstat(&file).map_err(|e| werr(io(e)))?;
            if FileType::from_raw_mode(st.st_mode) != FileType::RegularFile || st.st_nlink != 1 {
                let _ = rustix::fs::unlinkat(&fd, LOCK, AtFlags::empty());
                continue;
            }
            match rustix::fs::flock(&file, rustix::fs::FlockOperation::NonBlockingLockExclusive) {
                Ok(()) => {}
                Err(rustix::io::Errno::WOULDBLOCK) => return Err(in_use(path, &fd)),
                Err(e) => return Err(werr(io(e))),
            }
            // The file locked must still be the one named: a holder that ended removed it while
            // we opened it (then try again with the new one).
            let named = rustix::fs::statat(&fd, LOCK, AtFlags::SYMLINK_NOFOLLOW);
            if named.is_ok_and(|n| n.st_ino == st.st_ino && n.st_dev == st.st_dev) {
                file.set_len(0).map_err(werr)?;
                (&file).write_all(format!("{}\n", std::process::id()).as_bytes()).map_err(werr)?;
                return Ok(Lock { dir: fd, file: Some(file), named: true });
            }
        }
        Err(refused(&lock_path, "replaced again and again while ohd took it: another program is interfering"))
    }
}

/// A [`Lock::take`] failure to write the [`LOCK`] file of the directory `path` (read-only, or a
/// directory or a FIFO planted at the name), as a refusal naming the file.
fn cannot_write(path: &Path, e: Error) -> Error {
    match e {
        Error::Write { source, .. } => {
            refused(&path.join(LOCK), format!("cannot write ohd's lock file into the directory: {source}"))
        }
        e => e,
    }
}

/// The refusal of the directory `path` (open: `dir`) that another ohd holds, naming its process
/// as its [`LOCK`] file does (a regular file, not followed if a link, read without blocking).
fn in_use(path: &Path, dir: &OwnedFd) -> Error {
    let flags = OFlags::RDONLY | OFlags::NOFOLLOW | OFlags::NONBLOCK | OFlags::CLOEXEC;
    let pid = rustix::fs::openat(dir, LOCK, flags, Mode::empty()).ok().map(File::from).and_then(|f| {
        let regular = f.metadata().is_ok_and(|m| m.is_file());
        let mut text = String::new();
        (regular && f.take(64).read_to_string(&mut text).is_ok()).then_some(())?;
        text.trim().parse::<u32>().ok()
    });
    let holder = match pid {
        Some(pid) => format!("another ohd (process {pid})"),
        None => "another ohd".to_string(),
    };
    refused(
        path,
        format!(
            "in use: {holder} is writing into this directory (lock {LOCK}); wait for it to end, or give another output directory"
        ),
    )
}

impl Drop for Lock {
    fn drop(&mut self) {
        // Removed while still locked, then released: the next holder writes its own.
        if self.named {
            let _ = rustix::fs::unlinkat(&self.dir, LOCK, AtFlags::empty());
        }
        if let Some(file) = &self.file {
            let _ = rustix::fs::flock(file, rustix::fs::FlockOperation::Unlock);
        }
        let _ = rustix::fs::flock(&self.dir, rustix::fs::FlockOperation::Unlock);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listing(d: &Path) -> Vec<String> {
        let mut v: Vec<String> =
            std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
        v.sort();
        v
    }

    #[test]
    fn plain_names() {
        for ok in ["a.npy", ".hidden", "pointing_00", "..a"] {
            assert!(plain_name(ok), "{ok}");
        }
        for not in ["", ".", "..", "a/b", "/etc/passwd", "a\\b", "a\0b"] {
            assert!(!plain_name(not), "{not:?}");
        }
    }

    /// Files are written whole under their names, links planted at a name are replaced (their
    /// targets untouched), what is not a regular file is refused, and the lock is gone at the end.
    #[test]
    fn writes_stay_inside_and_replace_no_device() {
        let tmp = tempfile::tempdir().unwrap();
        let canary = tmp.path().join("canary");
        std::fs::write(&canary, "keep").unwrap();
        let out = tmp.path().join("a/b/out");
        {
            let d = OutDir::create(&out).unwrap();
            assert_eq!(listing(&out), [LOCK]);
            d.write_atomic("x.npy", b"1").unwrap();
            std::os::unix::fs::symlink(&canary, out.join("y.npy")).unwrap();
            d.write_atomic("y.npy", b"2").unwrap();
            assert_eq!(std::fs::read(out.join("y.npy")).unwrap(), b"2");
            assert!(!std::fs::symlink_metadata(out.join("y.npy")).unwrap().file_type().is_symlink());
            std::fs::create_dir(out.join("z.npy")).unwrap();
            // Found while writing (files may have been written before): a write error; checked
            // first, an input error.
            let e = d.write_atomic("z.npy", b"3").unwrap_err();
            assert!(!e.is_input_error() && e.to_string().contains("a directory"), "{e}");
            assert!(d.check_target("z.npy").unwrap_err().is_input_error());
            rustix::fs::mknodat(CWD, out.join("f"), FileType::Fifo, Mode::from_raw_mode(0o600), 0).unwrap();
            std::os::unix::fs::symlink(out.join("f"), out.join("l.npy")).unwrap();
            let e = d.write_atomic("f", b"4").unwrap_err().to_string();
            assert!(e.contains("a FIFO"), "{e}");
            // A link to a FIFO: refused as a lone file's target; replaced in an output directory.
            let e = d.check_target("l.npy").unwrap_err().to_string();
            assert!(e.contains("a symbolic link to a FIFO"), "{e}");
            d.write_atomic("l.npy", b"4").unwrap();
            assert!(std::os::unix::fs::FileTypeExt::is_fifo(
                &std::fs::symlink_metadata(out.join("f")).unwrap().file_type()
            ));
            assert!(d.write_atomic("../x.npy", b"5").unwrap_err().is_input_error());
            d.remove_file("x.npy").unwrap();
            std::os::unix::fs::symlink(&canary, out.join("w.npy")).unwrap();
            d.remove_file("w.npy").unwrap();
            assert_eq!(listing(&out), [LOCK, "f", "l.npy", "y.npy", "z.npy"]);
        }
        assert_eq!(std::fs::read_to_string(&canary).unwrap(), "keep");
        assert!(!out.join(LOCK).exists());
    }

    /// A second holder is refused naming the first's process; a sub-directory that is a link is
    /// refused; `newdir/.`, dangling links, loops and files as parents are found on creation.
    #[test]
    fn locks_and_refusals() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("out");
        let d = OutDir::create(&out).unwrap();
        let e = OutDir::create(&out).unwrap_err();
        assert!(e.is_input_error() && e.to_string().contains(&format!("process {}", std::process::id())), "{e}");
        let elsewhere = tmp.path().join("elsewhere");
        std::fs::create_dir(&elsewhere).unwrap();
        std::os::unix::fs::symlink(&elsewhere, out.join("pointing_01")).unwrap();
        assert!(d.sub("pointing_01").unwrap_err().is_input_error());
        let s = d.sub("pointing_00").unwrap();
        s.write_atomic("a.csv", b"a").unwrap();
        assert_eq!(std::fs::read(out.join("pointing_00/a.csv")).unwrap(), b"a");
        drop((d, s));
        OutDir::create(&out).unwrap();
        OutDir::create(&tmp.path().join("newdir/.")).unwrap();
        std::os::unix::fs::symlink(tmp.path().join("none"), tmp.path().join("dangling")).unwrap();
        std::os::unix::fs::symlink(tmp.path().join("loop"), tmp.path().join("loop")).unwrap();
        std::fs::write(tmp.path().join("file"), "").unwrap();
        for (p, why) in [
            ("dangling", "dangling"),
            ("loop", "loop"),
            ("file/out", "not a directory"),
            (&"n".repeat(300)[..], "too long"),
        ] {
            let e = OutDir::create(&tmp.path().join(p)).unwrap_err();
            assert!(e.is_input_error() && e.to_string().to_lowercase().contains(why), "{p}: {e}");
        }
        assert_eq!(std::fs::read_dir(&elsewhere).unwrap().count(), 0);
    }

    /// Issue 52: the lock is the directory's own: removing or replacing its lock file releases
    /// nothing (a8c4817 locked the file: a second writer took a new one).
    #[test]
    fn the_lock_outlives_its_file() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("out");
        std::fs::create_dir(&out).unwrap();
        let d = OutDir::create(&out).unwrap();
        assert_eq!(std::fs::read_to_string(out.join(LOCK)).unwrap(), format!("{}\n", std::process::id()));
        std::fs::remove_file(out.join(LOCK)).unwrap();
        let e = OutDir::create(&out).unwrap_err();
        assert!(e.is_input_error() && e.to_string().contains("in use"), "{e}");
        std::fs::write(out.join(LOCK), "1\n").unwrap();
        assert!(OutDir::create(&out).unwrap_err().is_input_error());
        drop(d);
        assert!(!out.join(LOCK).exists());
        drop(OutDir::create(&out).unwrap());
        // What is not a regular file at the lock's name is not replaced: refused, naming it.
        std::fs::create_dir(out.join(LOCK)).unwrap();
        let e = OutDir::create(&out).unwrap_err();
        assert!(e.is_input_error() && e.to_string().contains(LOCK) && e.to_string().contains("a directory"), "{e}");
        assert!(out.join(LOCK).is_dir());
    }

    /// Issue 52: an output directory locks each sub-directory it writes, so another writer into
    /// one is refused naming it and the holder, and the other way round; one root takes each
    /// sub-directory once; one made and left empty is removed again.
    #[test]
    fn sub_directories_are_locked_both_ways() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("out");
        let inner = out.join("pointing_00");
        let me = format!("process {}", std::process::id());
        let d = OutDir::create(&out).unwrap();
        let s = d.sub("pointing_00").unwrap();
        assert!(d.sub("pointing_00").is_ok() && d.clone().sub("pointing_00").is_ok());
        let e = OutDir::create(&inner).unwrap_err().to_string();
        assert!(e.contains(inner.to_str().unwrap()) && e.contains(&me), "{e}");
        s.write_atomic("a.csv", b"a").unwrap();
        drop((d, s));
        assert!(!inner.join(LOCK).exists() && inner.join("a.csv").exists());
        let held = OutDir::create(&inner).unwrap();
        let d = OutDir::create(&out).unwrap();
        let e = d.sub("pointing_00").unwrap_err();
        assert!(e.is_input_error() && e.to_string().contains(inner.to_str().unwrap()) && e.to_string().contains(&me));
        drop((d, held));
        let d = OutDir::create(&out).unwrap();
        d.sub("pointing_01").unwrap();
        drop(d);
        assert!(!out.join("pointing_01").exists() && !out.join(LOCK).exists());
    }

    /// Issue 52: a lone file's directory is refused while another ohd writes into it, and the
    /// lock's name is never a lone file's (a8c4817 replaced a held lock); lone files may be
    /// written side by side.
    #[test]
    fn lone_files_keep_out_of_held_directories_and_the_lock() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("out");
        std::fs::create_dir(&out).unwrap();
        let d = OutDir::create(&out).unwrap();
        let e = OutDir::existing(&out).unwrap_err();
        assert!(e.is_input_error() && e.to_string().contains("in use"), "{e}");
        let free = OutDir::existing(tmp.path()).unwrap();
        let beside = OutDir::existing(tmp.path()).unwrap();
        assert!(free.check_target(LOCK).unwrap_err().is_input_error());
        assert!(free.write_atomic(LOCK, b"1").unwrap_err().is_input_error());
        free.check_target("table.txt").unwrap();
        beside.write_atomic("table.txt", b"t").unwrap();
        drop((d, free, beside));
        assert!(!tmp.path().join(LOCK).exists());
        OutDir::existing(&out).unwrap();
    }
}
