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
//!
//! Everything is written, replaced and removed through the directory held open
//! ([`OutDir`]: plain names only, no link followed). A record or marker that lists a name with a
//! path in it (`/`, `..`, an absolute path) is refused, and nothing is removed (issue 33).

use std::collections::BTreeSet;
use std::io::Write;
use std::path::Path;

use serde_json::Value;

use crate::error::{Error, Result};
use crate::io::outdir::{LOCK, OutDir, plain_name};
use crate::io::remove_stale_temporaries;

/// The name of pointing `i`'s directory inside a scan's: `pointing_NN`.
pub fn pointing_name(i: usize) -> String {
    format!("pointing_{i:02}")
}

/// The marker of a directory being written, or whose writing was interrupted.
pub const MARKER: &str = "ohd_incomplete.txt";

/// A run's record: lists its files.
pub const MANIFEST: &str = "manifest.json";

/// A scan's record, and the VAD table written with it.
pub const SCAN: &str = "scan.json";
pub const VAD: &str = "vad.csv";
/// The scan's figure (PNG and SVG).
pub const VAD_FIGURES: [&str; 2] = ["vad_wind_profile.png", "vad_wind_profile.svg"];
/// An FMCW scan's table of range and velocity per pointing, and its figures (PNG and SVG each).
pub const FMCW_SCAN: &str = "fmcw_scan.csv";
pub const FMCW_SCAN_FIGURES: [&str; 4] =
    ["fmcw_scan_range.png", "fmcw_scan_range.svg", "fmcw_scan_velocity.png", "fmcw_scan_velocity.svg"];

/// A convergence study's record, and the files written with it.
pub const CONVERGE: &str = "converge.json";
pub const CONVERGE_FILES: [&str; 3] = ["converge.csv", "converge.png", "converge.svg"];

/// Largest record read back to find an earlier output's files, bytes.
const MAX_RECORD_BYTES: u64 = 256 << 20;

/// The extensions of the files ohd writes as outputs: a listed name without one is not removed.
const EXTENSIONS: [&str; 6] = ["npy", "exr", "png", "svg", "csv", "json"];

/// Files ohd writes under fixed names besides outputs, whose temporary files are its own.
const OWN_FILES: [&str; 4] = [MARKER, "checkpoint.ohd", "shard.ohd", LOCK];

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
    /// (a record that is not ohd's — no `ohd_version`, not a scan's — lists nothing). A listed
    /// name with a path in it (`a/b`, `..`, `/etc/x`) is refused, naming the record.
    fn find(dir: &Path, output: Output) -> Result<Earlier> {
        let mut e = Earlier::default();
        let json = |name: &str| -> Option<Value> {
            let bytes = crate::io::read_limited(&dir.join(name), MAX_RECORD_BYTES, "an ohd record").ok()?;
            serde_json::from_slice(&bytes).ok()
        };
        let listed = |record: &str, names: &mut dyn Iterator<Item = &str>| -> Result<Vec<String>> {
            names
                .map(|n| match plain_name(n.strip_suffix('/').unwrap_or(n)) {
                    true => Ok(n.to_string()),
                    false => Err(Error::Refused {
                        path: dir.join(record),
                        why: format!(
                            "lists {:?}, not a plain name in this directory: ohd removes only its own files here (edit or remove the file)",
                            crate::error::shorten(n, crate::error::SHOWN_WORD)
                        ),
                    }),
                })
                .collect()
        };
        let run = output == Output::Run;
        if let Some(m) = json(MANIFEST).filter(|m| run && m.get("ohd_version").is_some()) {
            let files = m.get("files").and_then(Value::as_array).into_iter().flatten();
            e.files.extend(listed(MANIFEST, &mut files.filter_map(Value::as_str))?);
            e.files.insert(MANIFEST.into());
        }
        if let Some(s) = json(SCAN).filter(|s| run && (s.get("gates").is_some() || s.get("fmcw").is_some())) {
            let pointings = s.get("pointings").and_then(Value::as_array).into_iter().flatten();
            e.dirs.extend(listed(SCAN, &mut pointings.filter_map(|p| p.get("run").and_then(Value::as_str)))?);
            let own = [SCAN, VAD, FMCW_SCAN].into_iter().chain(VAD_FIGURES).chain(FMCW_SCAN_FIGURES);
            e.files.extend(own.map(|s| s.to_string()));
        }
        if !run && json(CONVERGE).is_some_and(|c| c.get("ohd_version").is_some()) {
            e.files.extend(CONVERGE_FILES.iter().chain([&CONVERGE]).map(|s| s.to_string()));
        }
        let marker = crate::io::read_text_limited(&dir.join(MARKER), MAX_RECORD_BYTES, "an ohd marker");
        let mut lines = marker.iter().flat_map(|t| t.lines()).filter(|l| !l.starts_with('#'));
        for line in listed(MARKER, &mut lines)? {
            match line.strip_suffix('/') {
                Some(d) => e.dirs.insert(d.to_string()),
                None => e.files.insert(line),
            };
        }
        e.files.retain(|f| output_file(f));
        e.dirs.retain(|d| pointing_dir(d));
        Ok(e)
    }

    /// Remove the listed files of `dir` (the records first: from then on nothing claims the
    /// directory complete) and their temporary files and those of ohd's fixed names.
    fn remove_files(&self, dir: &OutDir) -> Result<()> {
        let records = [MANIFEST, SCAN, CONVERGE];
        let (first, rest): (Vec<&String>, Vec<&String>) =
            self.files.iter().partition(|f| records.contains(&f.as_str()));
        for name in first.into_iter().chain(rest) {
            dir.remove_file(name)?;
        }
        remove_stale_temporaries(dir, |n| self.files.contains(n) || OWN_FILES.contains(&n))
    }
}

/// Writes one command's outputs into a directory: see the module docs.
#[derive(Debug)]
pub struct DirWriter {
    dir: OutDir,
    marker: std::fs::File,
    written: Vec<String>,
}

impl DirWriter {
    /// Begin writing an `output` into `dir`: mark it incomplete, then remove what an earlier
    /// output of its kind and an interrupted one left there — except the pointing directories
    /// `keep`, which the caller writes (and cleans) itself. What the earlier records list is
    /// checked before anything is removed (a listed name with a path in it, or a pointing
    /// directory that is a link, is refused).
    pub fn begin(dir: &OutDir, output: Output, keep: &[String]) -> Result<DirWriter> {
        let mut earlier = Earlier::find(dir.path(), output)?;
        earlier.dirs.retain(|d| !keep.contains(d));
        let subs = earlier.dirs.iter().map(|d| dir.sub(d)).collect::<Result<Vec<_>>>()?;
        let mut text = format!(
            "# ohd (process {}) is writing into this directory, or was interrupted while it wrote: until\n\
             # this file is gone, the files here are not one complete output. Running ohd into this\n\
             # directory again replaces them, first removing the files listed here (ohd's own).\n",
            std::process::id()
        );
        earlier.files.iter().for_each(|f| text.push_str(&format!("{f}\n")));
        earlier.dirs.iter().for_each(|d| text.push_str(&format!("{d}/\n")));
        let mut marker = dir.temporary(MARKER)?;
        marker.write(text.as_bytes())?;
        let marker = marker.commit()?;
        earlier.remove_files(dir)?;
        for (name, sub) in earlier.dirs.iter().zip(subs) {
            // Only a directory ohd made (a link was refused above; one planted since is not
            // followed: `sub`'s operations open it without following links).
            if dir.kind(name)? == Some(rustix::fs::FileType::Directory) {
                Earlier { dirs: BTreeSet::new(), ..Earlier::find(sub.path(), Output::Run)? }.remove_files(&sub)?;
                sub.remove_file(MARKER)?;
                // Only once empty: a checkpoint, a shard or another program's file keeps it.
                sub.remove_if_empty();
            }
        }
        Ok(DirWriter { dir: dir.clone(), marker, written: Vec::new() })
    }

    /// Check, before any work, what [`DirWriter::begin`] will find in `dir` for an `output`: the
    /// earlier records and marker list no path, and their pointing directories are directories
    /// (so that a run is not refused for them after its simulation).
    pub fn check(dir: &OutDir, output: Output) -> Result<()> {
        let earlier = Earlier::find(dir.path(), output)?;
        earlier.dirs.iter().try_for_each(|d| dir.sub(d).map(drop))
    }

    /// The directory written into.
    pub fn dir(&self) -> &Path {
        self.dir.path()
    }

    /// Note `name` in the marker (`name/` for a directory) before it is written.
    fn note(&mut self, name: &str) -> Result<()> {
        writeln!(self.marker, "{name}").map_err(|source| Error::Write { path: self.dir.path().join(MARKER), source })
    }

    /// Write the file `name` (noted in the marker first), atomically.
    pub fn put(&mut self, name: &str, bytes: &[u8]) -> Result<()> {
        self.note(name)?;
        self.dir.write_atomic(name, bytes)?;
        self.written.push(name.to_string());
        Ok(())
    }

    /// The figure `d` as the files `png` and `svg`.
    pub fn figure(&mut self, png: &str, svg: &str, d: &impl crate::io::figures::Draw) -> Result<()> {
        let f = super::figures::drawn(d, self.dir.path().join(png))?;
        self.put(png, &f.png)?;
        self.put(svg, f.svg.as_bytes())
    }

    /// The subdirectory `name` (a scan's pointing directory), noted in the marker: written and
    /// cleaned by its own writer.
    pub fn subdir(&mut self, name: &str) -> Result<OutDir> {
        let sub = self.dir.sub(name)?;
        self.note(&format!("{name}/"))?;
        Ok(sub)
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
        self.dir.remove_file(MARKER)
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
        let manifest = r#"{"ohd_version": "0", "files": ["old.npy", "notes.txt"]}"#;
        for (name, text) in [
            ("manifest.json", manifest),
            ("old.npy", "old"),
            ("notes.txt", "the user's"),
            ("mine.npy", "the user's"),
            (".old.npy.tmp-12", "killed"),
            (".old.npy.tmp-12-0123456789abcdef", "killed"),
            (".checkpoint.ohd.tmp-13", "killed"),
            (".mine.npy.tmp-14", "the user's"),
            ("killed.npy", "a killed run's"),
            (MARKER, "# …\nkilled.npy\n"),
        ] {
            std::fs::write(d.join(name), text).unwrap();
        }
        std::fs::write(d.join("converge.json"), r#"{"ohd_version": "0"}"#).unwrap();
        std::fs::write(d.join("converge.csv"), "a study's").unwrap();
        let out = OutDir::create(d).unwrap();
        let mut w = DirWriter::begin(&out, Output::Run, &[]).unwrap();
        let listing = || {
            let mut v: Vec<String> =
                std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
            v.sort();
            v
        };
        // A study beside the run stays.
        let left = [".mine.npy.tmp-14", LOCK, "converge.csv", "converge.json", "mine.npy", "notes.txt", MARKER];
        assert_eq!(listing(), left);
        w.put("new.npy", b"new").unwrap();
        let marker = std::fs::read_to_string(d.join(MARKER)).unwrap();
        assert!(marker.contains("\nkilled.npy\n") && marker.contains("\nold.npy\n") && marker.ends_with("\nnew.npy\n"));
        assert_eq!(w.written(), ["new.npy"]);
        w.finish(Some(("manifest.json", br#"{"ohd_version": "0", "files": ["new.npy"]}"#))).unwrap();
        let run = [".mine.npy.tmp-14", "manifest.json", "mine.npy", "new.npy", "notes.txt"];
        assert_eq!(listing(), [&run[..1], &[LOCK, "converge.csv", "converge.json"], &run[1..]].concat());
        // A study replaces the study only.
        DirWriter::begin(&out, Output::Study, &[]).unwrap().finish(None).unwrap();
        drop(out);
        assert_eq!(listing(), run);
    }

    /// A record or marker listing a name with a path in it is refused, naming the record, and
    /// nothing is removed; so is an earlier scan's pointing directory that is a link.
    #[test]
    fn records_that_list_paths_are_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path().join("out");
        let out = OutDir::create(&d).unwrap();
        std::fs::write(tmp.path().join("outside.npy"), "the user's").unwrap();
        for (record, text) in [
            (MANIFEST, r#"{"ohd_version": "0", "files": ["../outside.npy"]}"#),
            (MANIFEST, r#"{"ohd_version": "0", "files": ["/etc/x.npy"]}"#),
            (MARKER, "# …\na/../x.npy\n"),
            (MARKER, "# …\n../\n"),
            (SCAN, r#"{"gates": [], "pointings": [{"run": "../pointing_00"}]}"#),
        ] {
            std::fs::write(d.join(record), text).unwrap();
            let e = DirWriter::begin(&out, Output::Run, &[]).unwrap_err();
            assert!(e.is_input_error() && e.to_string().contains(record), "{e}");
            assert!(DirWriter::check(&out, Output::Run).is_err());
            assert!(d.join(record).exists() && tmp.path().join("outside.npy").exists());
            std::fs::remove_file(d.join(record)).unwrap();
        }
        std::os::unix::fs::symlink(tmp.path(), d.join("pointing_00")).unwrap();
        std::fs::write(d.join(SCAN), r#"{"gates": [], "pointings": [{"run": "pointing_00"}]}"#).unwrap();
        let e = DirWriter::begin(&out, Output::Run, &[]).unwrap_err();
        assert!(e.is_input_error() && e.to_string().contains("pointing_00"), "{e}");
        assert!(d.join(SCAN).exists() && tmp.path().join("outside.npy").exists());
    }
}
