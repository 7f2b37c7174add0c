//! An output directory being written ([`DirWriter`]): the outputs of one ohd command in a
//! directory are always complete, or the directory is marked incomplete (issue 21: a run killed
//! while writing left new files beside an earlier run's and its `manifest.json`; a run with other
//! options left the files of the earlier one; killed writes left hidden temporary files).
//!
//! Writing begins with the marker [`MARKER`], which lists every file ohd wrote or is about to
//! write there; then what an earlier ohd output left in the directory is removed. Each file is
//! added to the marker before it is written (atomically, [`crate::io::write_atomic`]). The
//! record of the whole — a run's `manifest.json` (which lists exactly its files), a scan's
//! `scan.json`, a study's `converge.json` — is written last, and then the marker is removed. A
//! directory with the marker holds no complete output: its writing was interrupted (or is under
//! way); the next ohd command writing into it removes what the marker lists.
//!
//! A run or a scan replaces an earlier run or scan; a convergence study an earlier study (a study
//! written beside a run leaves the run, and the other way round). Only ohd's own files are ever
//! removed: the files an earlier record or marker lists (plain file names with an extension ohd
//! writes: `.npy`, `.exr`, `.png`, `.svg`, `.csv`, `.json`), the records themselves, ohd's temporary
//! files of those names (`.NAME.tmp-PID`, left by a killed process) and an earlier scan's
//! pointing directories, each cleaned the same way and then removed if empty. Files of other
//! programs stay, and so do checkpoints and shards (runs resume and merge from them).

use std::collections::BTreeSet;
use std::io::Write;
use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::error::{Error, Result};
use crate::io::{remove_stale_temporaries, write_atomic};

/// The marker of a directory being written, or whose writing was interrupted.
pub const MARKER: &str = "ohd_incomplete.txt";

/// A run's record: lists its files.
pub const MANIFEST: &str = "manifest.json";

/// A scan's record, and the VAD table written with it.
pub const SCAN: &str = "scan.json";
pub const VAD: &str = "vad.csv";
/// The scan's figure (PNG and SVG).
pub const VAD_FIGURES: [&str; 2] = ["vad_wind_profile.png", "vad_wind_profile.svg"];

/// A convergence study's record, and the files written with it.
pub const CONVERGE: &str = "converge.json";
pub const CONVERGE_FILES: [&str; 3] = ["converge.csv", "converge.png", "converge.svg"];

/// Largest record read back to find an earlier output's files, bytes.
const MAX_RECORD_BYTES: u64 = 256 << 20;

/// The extensions of the files ohd writes as outputs: a listed name without one is not removed.
const EXTENSIONS: [&str; 6] = ["npy", "exr", "png", "svg", "csv", "json"];

/// Files ohd writes under fixed names besides outputs, whose temporary files are its own.
const OWN_FILES: [&str; 3] = [MARKER, "checkpoint.ohd", "shard.ohd"];

/// What is written into a directory, and so what it replaces there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Output {
    /// A run (`manifest.json`) or a scan (`scan.json`, pointing directories): replaces either.
    Run,
    /// A convergence study (`converge.json`): replaces a study.
    Study,
}

/// Whether `name` can be one of ohd's output files in a directory: a plain file name (no path,
/// not hidden) with an extension ohd writes.
fn output_file(name: &str) -> bool {
    let plain = !name.is_empty() && !name.starts_with('.') && !name.contains(['/', '\\', '\0']);
    plain && name.rsplit_once('.').is_some_and(|(stem, ext)| !stem.is_empty() && EXTENSIONS.contains(&ext))
}

/// Whether `name` can be a scan's pointing directory: `pointing_NN`.
fn pointing_dir(name: &str) -> bool {
    name.strip_prefix("pointing_").is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()))
}

/// What an earlier ohd output left in a directory, as its records and marker list it.
#[derive(Debug, Default)]
struct Earlier {
    files: BTreeSet<String>,
    dirs: BTreeSet<String>,
}

impl Earlier {
    /// The files and pointing directories that `dir`'s records of an `output` and its marker list
    /// (a record that is not ohd's — no `ohd_version`, not a scan's — lists nothing).
    fn find(dir: &Path, output: Output) -> Earlier {
        let mut e = Earlier::default();
        let json = |name: &str| -> Option<Value> {
            let bytes = crate::io::read_limited(&dir.join(name), MAX_RECORD_BYTES, "an ohd record").ok()?;
            serde_json::from_slice(&bytes).ok()
        };
        let run = output == Output::Run;
        if let Some(m) = json(MANIFEST).filter(|m| run && m.get("ohd_version").is_some()) {
            let files = m.get("files").and_then(Value::as_array).into_iter().flatten();
            e.files.extend(files.filter_map(Value::as_str).map(str::to_string));
            e.files.insert(MANIFEST.into());
        }
        if let Some(s) = json(SCAN).filter(|s| run && s.get("gates").is_some()) {
            let pointings = s.get("pointings").and_then(Value::as_array).into_iter().flatten();
            e.dirs.extend(pointings.filter_map(|p| p.get("run").and_then(Value::as_str)).map(str::to_string));
            e.files.extend([SCAN, VAD].iter().chain(&VAD_FIGURES).map(|s| s.to_string()));
        }
        if !run && json(CONVERGE).is_some_and(|c| c.get("ohd_version").is_some()) {
            e.files.extend(CONVERGE_FILES.iter().chain([&CONVERGE]).map(|s| s.to_string()));
        }
        let marker = crate::io::read_text_limited(&dir.join(MARKER), MAX_RECORD_BYTES, "an ohd marker");
        for line in marker.iter().flat_map(|t| t.lines()).filter(|l| !l.starts_with('#')) {
            match line.strip_suffix('/') {
                Some(d) => e.dirs.insert(d.to_string()),
                None => e.files.insert(line.to_string()),
            };
        }
        e.files.retain(|f| output_file(f));
        e.dirs.retain(|d| pointing_dir(d));
        e
    }

    /// Remove the listed files of `dir` (the records first: from then on nothing claims the
    /// directory complete) and their temporary files and those of ohd's fixed names.
    fn remove_files(&self, dir: &Path) -> Result<()> {
        let records = [MANIFEST, SCAN, CONVERGE];
        let (first, rest): (Vec<&String>, Vec<&String>) =
            self.files.iter().partition(|f| records.contains(&f.as_str()));
        for name in first.into_iter().chain(rest) {
            remove_file(&dir.join(name))?;
        }
        remove_stale_temporaries(dir, |n| self.files.contains(n) || OWN_FILES.contains(&n))?;
        crate::io::remove_stale_probes(dir)
    }
}

/// Remove `path` if it is a file (not a directory); a missing file is no error.
fn remove_file(path: &Path) -> Result<()> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => std::fs::remove_file(path).map_err(|source| Error::Write { path: path.to_path_buf(), source }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(source) => Err(Error::Write { path: path.to_path_buf(), source }),
    }
}

/// Writes one command's outputs into a directory: see the module docs.
#[derive(Debug)]
pub struct DirWriter {
    dir: PathBuf,
    marker: std::fs::File,
    written: Vec<String>,
}

impl DirWriter {
    /// Begin writing an `output` into `dir` (created if needed): mark it incomplete, then remove
    /// what an earlier output of its kind and an interrupted one left there — except the pointing
    /// directories `keep`, which the caller writes (and cleans) itself.
    pub fn begin(dir: &Path, output: Output, keep: &[String]) -> Result<DirWriter> {
        let werr = |path: &Path| {
            let path = path.to_path_buf();
            move |source| Error::Write { path, source }
        };
        std::fs::create_dir_all(dir).map_err(werr(dir))?;
        let mut earlier = Earlier::find(dir, output);
        earlier.dirs.retain(|d| !keep.contains(d));
        let mut text = format!(
            "# ohd (process {}) is writing into this directory, or was interrupted while it wrote: until\n\
             # this file is gone, the files here are not one complete output. Running ohd into this\n\
             # directory again replaces them, first removing the files listed here (ohd's own).\n",
            std::process::id()
        );
        earlier.files.iter().for_each(|f| text.push_str(&format!("{f}\n")));
        earlier.dirs.iter().for_each(|d| text.push_str(&format!("{d}/\n")));
        let marker_path = dir.join(MARKER);
        write_atomic(&marker_path, text.as_bytes())?;
        earlier.remove_files(dir)?;
        for d in &earlier.dirs {
            let sub = dir.join(d);
            // A directory, not a link to one elsewhere.
            if std::fs::symlink_metadata(&sub).is_ok_and(|m| m.is_dir()) {
                Earlier { dirs: BTreeSet::new(), ..Earlier::find(&sub, Output::Run) }.remove_files(&sub)?;
                remove_file(&sub.join(MARKER))?;
                // Only once empty: a checkpoint, a shard or another program's file keeps it.
                let _ = std::fs::remove_dir(&sub);
            }
        }
        let marker = std::fs::OpenOptions::new().append(true).open(&marker_path).map_err(werr(&marker_path))?;
        Ok(DirWriter { dir: dir.to_path_buf(), marker, written: Vec::new() })
    }

    /// The directory written into.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Note `name` in the marker (`name/` for a directory) before it is written.
    fn note(&mut self, name: &str) -> Result<()> {
        writeln!(self.marker, "{name}").map_err(|source| Error::Write { path: self.dir.join(MARKER), source })
    }

    /// Write the file `name` (noted in the marker first), atomically.
    pub fn put(&mut self, name: &str, bytes: &[u8]) -> Result<()> {
        self.note(name)?;
        write_atomic(&self.dir.join(name), bytes)?;
        self.written.push(name.to_string());
        Ok(())
    }

    /// The figure `d` as the files `png` and `svg`.
    pub fn figure(&mut self, png: &str, svg: &str, d: &impl crate::io::figures::Draw) -> Result<()> {
        let f = super::figures::drawn(d, self.dir.join(png))?;
        self.put(png, &f.png)?;
        self.put(svg, f.svg.as_bytes())
    }

    /// The subdirectory `name` (a scan's pointing directory), noted in the marker: written and
    /// cleaned by its own writer.
    pub fn subdir(&mut self, name: &str) -> Result<PathBuf> {
        self.note(&format!("{name}/"))?;
        Ok(self.dir.join(name))
    }

    /// The files written so far, in order.
    pub fn written(&self) -> &[String] {
        &self.written
    }

    /// Write the record `(name, bytes)` if any, last, and remove the marker: the directory holds
    /// one complete output.
    pub fn finish(mut self, record: Option<(&str, &[u8])>) -> Result<()> {
        if let Some((name, bytes)) = record {
            self.put(name, bytes)?;
        }
        // Temporary files of these names that an earlier ohd left (before markers listed them).
        let written: BTreeSet<&str> = self.written.iter().map(String::as_str).collect();
        remove_stale_temporaries(&self.dir, |n| written.contains(n))?;
        drop(self.marker);
        remove_file(&self.dir.join(MARKER))
    }
}

/// Whether `dir` is marked incomplete (holds [`MARKER`]).
pub fn is_incomplete(dir: &Path) -> bool {
    dir.join(MARKER).exists()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_plain_output_names_are_ohds() {
        for ok in ["a.npy", "camera_image.exr", "lidar_gates.csv", "manifest.json", "camera_m0_directional.png"] {
            assert!(output_file(ok), "{ok}");
        }
        for not in ["", ".npy", ".hidden.npy", "../x.npy", "a/b.npy", "/etc/x.csv", "notes.txt", "thesis", "x.npy.bak"]
        {
            assert!(!output_file(not), "{not}");
        }
        assert!(pointing_dir("pointing_00") && pointing_dir("pointing_123"));
        assert!(!pointing_dir("pointing_") && !pointing_dir("pointing_0/..") && !pointing_dir("../pointing_00"));
    }

    /// Begin marks the directory and removes exactly what the earlier manifest and marker list
    /// (and their temporary files); finish writes the record last and removes the marker.
    #[test]
    fn an_earlier_output_is_replaced_and_other_files_stay() {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path();
        let manifest = r#"{"ohd_version": "0", "files": ["old.npy", "../outside.npy", "notes.txt"]}"#;
        for (name, text) in [
            ("manifest.json", manifest),
            ("old.npy", "old"),
            ("notes.txt", "the user's"),
            ("mine.npy", "the user's"),
            (".old.npy.tmp-12", "killed"),
            (".checkpoint.ohd.tmp-13", "killed"),
            (".mine.npy.tmp-14", "the user's"),
            ("killed.npy", "a killed run's"),
            (MARKER, "# …\nkilled.npy\n"),
        ] {
            std::fs::write(d.join(name), text).unwrap();
        }
        std::fs::write(d.join("converge.json"), r#"{"ohd_version": "0"}"#).unwrap();
        std::fs::write(d.join("converge.csv"), "a study's").unwrap();
        let mut w = DirWriter::begin(d, Output::Run, &[]).unwrap();
        let listing = || {
            let mut v: Vec<String> =
                std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
            v.sort();
            v
        };
        // A study beside the run stays.
        assert_eq!(listing(), [".mine.npy.tmp-14", "converge.csv", "converge.json", "mine.npy", "notes.txt", MARKER]);
        w.put("new.npy", b"new").unwrap();
        let marker = std::fs::read_to_string(d.join(MARKER)).unwrap();
        assert!(marker.contains("\nkilled.npy\n") && marker.contains("\nold.npy\n") && marker.ends_with("\nnew.npy\n"));
        assert_eq!(w.written(), ["new.npy"]);
        w.finish(Some(("manifest.json", br#"{"ohd_version": "0", "files": ["new.npy"]}"#))).unwrap();
        let run = [".mine.npy.tmp-14", "manifest.json", "mine.npy", "new.npy", "notes.txt"];
        assert_eq!(listing(), [&run[..1], &["converge.csv", "converge.json"], &run[1..]].concat());
        // A study replaces the study only.
        DirWriter::begin(d, Output::Study, &[]).unwrap().finish(None).unwrap();
        assert_eq!(listing(), run);
    }
}
