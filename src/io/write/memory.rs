//! A run's files held in memory ([`Memory`]), as the Python package returns them, and written
//! into a directory later ([`save`]) exactly as `ohd run --out` writes them: the same bytes
//! through the same [`DirWriter`] (marker, atomic files, the manifest last).

use std::path::Path;

use super::Sink;
use super::dir::{DirWriter, MANIFEST, Output};
use crate::error::{Error, Result};

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

/// Write a run's files (as [`super::manifest::write_run_memory`] returns them: the manifest
/// last) into `dir`, replacing an earlier run there as `ohd run --out` does.
pub fn save(dir: &Path, files: &[(String, Vec<u8>)]) -> Result<()> {
    let Some(((record, manifest), rest)) = files.split_last().map(|((n, b), r)| ((n.as_str(), b), r)) else {
        return Err(Error::Input("no files to save: a run's files end with its manifest.json".into()));
    };
    if record != MANIFEST {
        return Err(Error::Input(format!("the last of a run's files is {MANIFEST}, not {record}")));
    }
    let mut w = DirWriter::begin(&crate::io::outdir::OutDir::create(dir)?, Output::Run, &[])?;
    for (name, bytes) in rest {
        w.put(name, bytes)?;
    }
    w.finish(Some((MANIFEST, manifest)))
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
}
