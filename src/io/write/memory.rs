//! A run's files held in memory ([`Memory`]), as the Python package returns them, and written
//! into a directory later ([`save`], a scan's with its pointings [`save_scan`]) exactly as
//! `ohd run --out` writes them: the same bytes through the same [`OutDir`] and [`DirWriter`]
//! (locks, marker, atomic files, the record last).

use std::path::Path;

use super::Sink;
use super::dir::{DirWriter, MANIFEST, MARKER, Output, SCAN};
use crate::error::{Error, Result};
use crate::io::outdir::{OutDir, plain_name};

/// Files `(name, bytes)` in the order written.
#[derive(Debug, Default, Clone)]
pub struct Memory {
    pub files: Vec<(String, Vec<u8>)>,
}

impl Sink for Memory {
    fn put_file(&mut self, name: String, bytes: Vec<u8>) -> Result<()> {
        self.files.push((name, bytes));
        Ok(())
    }

    fn written(&self) -> Vec<String> {
        self.files.iter().map(|(n, _)| n.clone()).collect()
    }
}

/// A file to save: its name and bytes.
pub type Named = (String, Vec<u8>);

/// Refuse, before anything is written, file names that are not ohd's to write into an output
/// directory: not one plain name, hidden (ohd's temporary and lock files), or the marker.
fn check_names(dir: &Path, files: &[Named]) -> Result<()> {
    match files.iter().find(|(n, _)| !plain_name(n) || n.starts_with('.') || n == MARKER) {
        Some((name, _)) => Err(Error::Refused {
            path: dir.join(&*crate::error::shorten(name, crate::error::SHOWN_WORD)),
            why: "not a name of ohd's outputs: expected one plain file name, not hidden, not the marker".into(),
        }),
        None => Ok(()),
    }
}

/// A run's files split into the others and the manifest (last), or why they are not a run's.
fn run_files(files: &[Named]) -> Result<(&[Named], &[u8])> {
    let Some(((record, manifest), rest)) = files.split_last().map(|((n, b), r)| ((n.as_str(), b), r)) else {
        return Err(Error::Input("no files to save: a run's files end with its manifest.json".into()));
    };
    if record != MANIFEST {
        return Err(Error::Input(format!("the last of a run's files is {MANIFEST}, not {record}")));
    }
    Ok((rest, manifest))
}

/// Write a run's files into `dir` (held, locked): the manifest last.
fn write_run(dir: &OutDir, files: &[Named]) -> Result<()> {
    let (rest, manifest) = run_files(files)?;
    let mut w = DirWriter::begin(dir, Output::Run, &[])?;
    for (name, bytes) in rest {
        w.put(name, bytes)?;
    }
    w.finish(Some((MANIFEST, manifest)))
}

/// Write a run's files (as [`super::manifest::write_run_memory`] returns them: the manifest
/// last) into `dir`, replacing an earlier run there as `ohd run --out` does.
pub fn save(dir: &Path, files: &[Named]) -> Result<()> {
    check_names(dir, files)?;
    run_files(files)?;
    write_run(&OutDir::create(dir)?, files)
}

/// Write a scan into `dir` as `ohd run --out` writes one (issue 52: the Python package wrote a
/// scan's files by path, following links planted at their names and at `pointing_NN`, and took
/// no lock): its own `files` (`scan.json` last, if any) and each of `pointings` (a run's files,
/// the manifest last) into `pointing_NN/`. One writer, as the CLI's: the directory and every
/// pointing directory locked for the whole save (another ohd writing into either refuses it), a
/// pointing directory that is a link refused, the scan's directory marked incomplete before a
/// pointing is written and its record written last; what an earlier output there left is
/// replaced. Every name is checked before anything is written.
pub fn save_scan(dir: &Path, files: &[Named], pointings: &[Vec<Named>]) -> Result<()> {
    if pointings.is_empty() {
        return Err(Error::Input("no pointings to save: a scan's pointings are runs of their own".into()));
    }
    check_names(dir, files)?;
    for (i, p) in pointings.iter().enumerate() {
        let sub = dir.join(super::dir::pointing_name(i));
        check_names(&sub, p)?;
        run_files(p).map_err(|e| Error::Input(format!("{}: {e}", sub.display())))?;
    }
    let out = OutDir::create(dir)?;
    DirWriter::check(&out, Output::Run)?;
    let names: Vec<String> = (0..pointings.len()).map(super::dir::pointing_name).collect();
    // Each pointing directory locked, and what an earlier output there records checked, before
    // anything is written.
    let subs = names
        .iter()
        .map(|n| out.sub(n).and_then(|sub| DirWriter::check(&sub, Output::Run).map(|()| sub)))
        .collect::<Result<Vec<_>>>()?;
    let mut w = DirWriter::begin(&out, Output::Run, &names)?;
    for ((name, sub), files) in names.iter().zip(&subs).zip(pointings) {
        w.subdir(name)?;
        write_run(sub, files)?;
    }
    let record = files.iter().find(|(n, _)| n == SCAN);
    for (name, bytes) in files.iter().filter(|(n, _)| n != SCAN) {
        w.put(name, bytes)?;
    }
    match record {
        Some((name, bytes)) => w.finish(Some((name.as_str(), bytes.as_slice()))),
        // A scan stopped before its end (Ctrl-C) has no record: its directory stays marked
        // incomplete, as the CLI leaves it, for `--resume`.
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Saved files are the bytes held, the manifest written last (the marker gone).
    #[test]
    fn saved_files_are_the_bytes_held() {
        let tmp = tempfile::tempdir().unwrap();
        let files =
            vec![("a.npy".to_string(), b"abc".to_vec()), (MANIFEST.to_string(), br#"{"files":["a.npy"]}"#.to_vec())];
        save(tmp.path(), &files).unwrap();
        assert_eq!(std::fs::read(tmp.path().join("a.npy")).unwrap(), b"abc");
        assert_eq!(std::fs::read(tmp.path().join(MANIFEST)).unwrap(), files[1].1);
        assert!(!super::super::dir::is_incomplete(tmp.path()));
        assert!(save(tmp.path(), &files[..1]).is_err());
        assert!(save(tmp.path(), &[]).is_err());
    }

    fn run(tag: &str) -> Vec<(String, Vec<u8>)> {
        vec![("a.npy".to_string(), tag.as_bytes().to_vec()), (MANIFEST.to_string(), br#"{"files":["a.npy"]}"#.to_vec())]
    }

    /// Issue 52: a scan is saved as `ohd run --out` writes one: each pointing a run of its own in
    /// `pointing_NN/`, the scan's record last, links at its names replaced (their targets
    /// untouched), no marker or lock left.
    #[test]
    fn a_scan_is_saved_as_the_cli_writes_it() {
        let tmp = tempfile::tempdir().unwrap();
        let (d, canary) = (tmp.path().join("out"), tmp.path().join("canary"));
        std::fs::write(&canary, "keep").unwrap();
        std::fs::create_dir_all(d.join("pointing_01")).unwrap();
        std::os::unix::fs::symlink(&canary, d.join("vad.csv")).unwrap();
        std::os::unix::fs::symlink(&canary, d.join("pointing_01/a.npy")).unwrap();
        let own = vec![(SCAN.to_string(), b"{}".to_vec()), ("vad.csv".to_string(), b"v".to_vec())];
        save_scan(&d, &own, &[run("0"), run("1")]).unwrap();
        assert_eq!(std::fs::read_to_string(&canary).unwrap(), "keep");
        assert_eq!(std::fs::read(d.join("vad.csv")).unwrap(), b"v");
        assert_eq!(std::fs::read(d.join("pointing_01/a.npy")).unwrap(), b"1");
        assert!(d.join("pointing_00/manifest.json").is_file() && d.join(SCAN).is_file());
        for dir in [d.clone(), d.join("pointing_00"), d.join("pointing_01")] {
            assert!(!super::super::dir::is_incomplete(&dir) && !dir.join(crate::io::outdir::LOCK).exists());
        }
    }

    /// Issue 52: a pointing directory that is a link, a directory another ohd holds (the scan's
    /// or a pointing's), a name that is not an output's: refused, nothing written or removed.
    #[test]
    fn a_scan_save_is_refused_where_the_cli_is() {
        let tmp = tempfile::tempdir().unwrap();
        let (d, elsewhere) = (tmp.path().join("out"), tmp.path().join("elsewhere"));
        std::fs::create_dir_all(&elsewhere).unwrap();
        std::fs::write(elsewhere.join(MANIFEST), r#"{"ohd_version": "0", "files": ["keep.npy"]}"#).unwrap();
        std::fs::write(elsewhere.join("keep.npy"), "the user's").unwrap();
        std::fs::create_dir_all(&d).unwrap();
        std::os::unix::fs::symlink(&elsewhere, d.join("pointing_00")).unwrap();
        let own = vec![(SCAN.to_string(), b"{}".to_vec())];
        let e = save_scan(&d, &own, &[run("0"), run("1")]).unwrap_err();
        assert!(e.is_input_error() && e.to_string().contains("pointing_00"), "{e}");
        assert_eq!(std::fs::read_dir(&elsewhere).unwrap().count(), 2);
        assert!(elsewhere.join("keep.npy").exists());
        std::fs::remove_file(d.join("pointing_00")).unwrap();
        for held in [d.clone(), d.join("pointing_01")] {
            let lock = OutDir::create(&held).unwrap();
            let e = save_scan(&d, &own, &[run("0"), run("1")]).unwrap_err();
            assert!(e.is_input_error() && e.to_string().contains("in use"), "{e}");
            assert!(e.to_string().contains(held.to_str().unwrap()), "{e}");
            drop(lock);
        }
        for bad in ["../x.npy", ".ohd-lock", "ohd_incomplete.txt", "a/b.npy"] {
            let files = vec![(bad.to_string(), b"x".to_vec()), (SCAN.to_string(), b"{}".to_vec())];
            assert!(save_scan(&d, &files, &[run("0"), run("1")]).unwrap_err().is_input_error(), "{bad}");
            let pointing = vec![(bad.to_string(), b"x".to_vec()), (MANIFEST.to_string(), b"{}".to_vec())];
            assert!(save_scan(&d, &own, &[run("0"), pointing]).unwrap_err().is_input_error(), "{bad}");
        }
        assert!(save_scan(&d, &own, &[run("0"), run("1")[..1].to_vec()]).unwrap_err().is_input_error());
        assert!(save_scan(&d, &own, &[]).unwrap_err().is_input_error());
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0, "written or left");
    }
}
