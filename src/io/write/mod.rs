//! Writing a finished run's outputs, as the run's [`crate::output::Registry`]
//! declares them: `manifest.json` and every detector's files ([`manifest::write_run`]), an LDH
//! camera's ([`ldh`]) and a lidar receiver's ([`lidar`]) outputs, FMCW read-offs ([`fmcw`]), a
//! scan's VAD wind ([`scan`]) and the convergence study ([`converge`]); each into its directory
//! through a [`dir::DirWriter`], so that a directory holds one complete output or is marked
//! incomplete.

pub mod converge;
pub mod dir;
pub mod figures;
pub mod fmcw;
pub mod importance;
pub mod ldh;
pub mod lidar;
pub mod manifest;
pub mod memory;
pub mod parts;
pub mod scan;
pub mod tcorr;
pub mod volume;

use std::collections::{BTreeMap, BTreeSet};

use serde::Serialize;

use super::formats::{exr::exr_bytes, npy};
use crate::error::{Error, Result};
use crate::output::{Axis, Kind, Output, PixelErrors, Registry};

/// A value and its standard error (`null` in JSON when not finite).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    pub value: f64,
    pub stderr: f64,
}

/// `{"value": v, "stderr": s}`.
pub fn estimate(value: f64, stderr: f64) -> Estimate {
    Estimate { value, stderr }
}

/// An entry of the manifest's `estimates`: an estimate, a number without an error (a derived
/// total, an FMCW read-off) or a group of entries (a detector's, the out-of-range tallies).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Entry {
    Estimate(Estimate),
    Number(f64),
    Group(BTreeMap<String, Entry>),
}

/// The layout of every image file (`.npy`, `.exr`, `.png`): as an image viewer and
/// `plt.imshow` show it ([`Output::values`] makes it).
pub const IMAGE_LAYOUT: &str = "rows = y descending (row 0 = top = largest y), columns = x ascending";

/// Where a file goes: `put(name, bytes)` writes it atomically and lists it in the manifest.
pub type Put<'a> = dyn FnMut(String, Vec<u8>) -> Result<()> + 'a;

/// Where a run's files go, in the order written: a directory ([`dir::DirWriter`], atomically)
/// or memory ([`memory::Memory`], the Python package's results).
pub trait Sink {
    /// Write the file `name`.
    fn put_file(&mut self, name: String, bytes: Vec<u8>) -> Result<()>;
    /// The files written so far, in order (the manifest's `files`).
    fn written(&self) -> Vec<String>;
}

impl Sink for dir::DirWriter {
    fn put_file(&mut self, name: String, bytes: Vec<u8>) -> Result<()> {
        self.put(&name, &bytes)
    }

    fn written(&self) -> Vec<String> {
        dir::DirWriter::written(self).to_vec()
    }
}

/// `file.npy` → `file_stderr.npy`.
pub fn stderr_file(file: &str) -> String {
    format!("{}_stderr.npy", file.trim_end_matches(".npy"))
}

/// The manifest's description of one written output (`outputs`, keyed by its file: a `.npy` name,
/// or a JSON pointer into the manifest for a scalar): what a reader needs to interpret the file
/// without knowing ohd's file names.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutputEntry {
    /// The declared output (`camera.m0_plus`); absent for what is made at write time (axis
    /// files, speckle draws, relative-error maps).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub output: Option<String>,
    /// `image`, `spectrum`, `curve`, `scalar`, …; `axis` for the coordinates of other outputs'
    /// axes.
    pub kind: &'static str,
    /// For an axis file: the name of the axis whose coordinates it holds (`frequency_hz`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub axis: Option<&'static str>,
    pub shape: Vec<usize>,
    pub units: &'static str,
    /// One per dimension of `shape`.
    pub axes: Vec<Axis>,
    /// The file of the standard errors (same shape).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stderr_file: Option<String>,
    /// The file holds `sign ×` the output's tally (an LDH camera's M0− with `flip_sign`).
    #[serde(skip_serializing_if = "is_one")]
    pub sign: f64,
    /// NaN marks a value left undefined (too few paths).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub undefined_nan: bool,
    /// Its OpenEXR copy (images).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exr_file: Option<String>,
    /// The map of its per-pixel relative errors (main images).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub relative_error_file: Option<String>,
    /// Its figure (`.png`, with an `.svg` beside it), if drawn.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub figure: Option<String>,
}

fn is_one(x: &f64) -> bool {
    *x == 1.0
}

impl OutputEntry {
    /// The entry of a declared output.
    pub fn of(o: &Output) -> Self {
        OutputEntry {
            output: Some(o.name.clone()),
            kind: o.kind.name(),
            axis: None,
            shape: o.shape.clone(),
            units: o.units,
            axes: o.axes.clone(),
            stderr_file: (o.stderr && !o.is_scalar()).then(|| stderr_file(&o.file)),
            sign: o.sign,
            undefined_nan: o.undefined_nan,
            exr_file: None,
            relative_error_file: None,
            figure: None,
        }
    }

    /// The entry of an array made at write time.
    pub fn made(kind: &'static str, shape: &[usize], units: &'static str, axes: Vec<Axis>) -> Self {
        OutputEntry {
            output: None,
            kind,
            axis: None,
            shape: shape.to_vec(),
            units,
            axes,
            stderr_file: None,
            sign: 1.0,
            undefined_nan: false,
            exr_file: None,
            relative_error_file: None,
            figure: None,
        }
    }
}

/// The manifest's `outputs`: the `table` of every output written, each given the figure drawn of
/// it (`<stem>.png` beside `<stem>.npy`) if that is among `files`.
pub fn with_figures(mut table: BTreeMap<String, OutputEntry>, files: &[String]) -> BTreeMap<String, OutputEntry> {
    let drawn: BTreeSet<&str> = files.iter().map(String::as_str).collect();
    for (file, entry) in table.iter_mut() {
        let png = format!("{}.png", file.trim_end_matches(".npy"));
        if file.ends_with(".npy") && drawn.contains(png.as_str()) {
            entry.figure = Some(png);
        }
    }
    table
}

/// A finished run's outputs being written: where files go, the registry that declares the
/// outputs, and the run's means and standard errors laid out as the tallies.
pub struct Writer<'a, 'p> {
    pub put: &'a mut Put<'p>,
    pub registry: &'a Registry,
    pub mean: &'a [f64],
    pub stderr: &'a [f64],
    /// The outputs written so far, by name ([`Writer::rest`] writes the others).
    pub written: BTreeSet<String>,
    /// The per-pixel relative errors of the images written, by output name (for the manifest).
    pub pixel_errors: BTreeMap<String, PixelErrorEntry>,
    /// Whether figures are drawn ([`Writer::figure`]; `--no-figures` turns them off).
    pub figures: bool,
    /// Every output written so far, by file (the manifest's `outputs`).
    pub table: BTreeMap<String, OutputEntry>,
    /// Each camera's mask of the regions' footprints, as written (row 0 = the largest `y`), and
    /// its file, by detector: its main images' errors are also given split by it.
    pub masks: BTreeMap<usize, (String, Vec<bool>)>,
    /// The single-window speckle contrast and frames of the LDH cameras' M0+ images, by their first
    /// tally slot ([`crate::experiment::Experiment::m0_speckle`]).
    pub speckle: BTreeMap<usize, (f64, usize)>,
    /// The tail checks of the cameras' regions, by the first tally slot of the image they pool
    /// ([`crate::experiment::RunOutput::tail_checks`]).
    pub tails: BTreeMap<usize, crate::stats::TailCheck>,
    /// The run's paths (the regions' variance per path).
    pub paths: f64,
}

/// The manifest's summary of an image's per-pixel relative errors ([`PixelErrors`]).
#[derive(Debug, Clone, serde::Serialize)]
pub struct PixelErrorEntry {
    /// The map's file: `σ/|value|` per pixel, NaN where the value is 0.
    pub file: String,
    pub median: Option<f64>,
    pub p90: Option<f64>,
    /// Pixels with a zero value (no relative error).
    pub pixels_without_signal: usize,
    /// Split by the detector's mask of the regions' footprints (`NAME_region_mask.npy`), if it
    /// has one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub regions: Option<RegionEntry>,
    /// An M0+ image's errors on the scale of the LDH camera's own speckle noise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub speckle: Option<crate::output::SpeckleScale>,
}

/// [`PixelErrorEntry::regions`]: the mask's file and the split.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RegionEntry {
    pub mask_file: String,
    #[serde(flatten)]
    pub errors: crate::output::RegionErrors,
}

impl<'a, 'p> Writer<'a, 'p> {
    pub fn new(put: &'a mut Put<'p>, registry: &'a Registry, mean: &'a [f64], stderr: &'a [f64]) -> Self {
        Writer {
            put,
            registry,
            mean,
            stderr,
            written: BTreeSet::new(),
            pixel_errors: BTreeMap::new(),
            masks: BTreeMap::new(),
            speckle: BTreeMap::new(),
            tails: BTreeMap::new(),
            paths: 0.0,
            figures: true,
            table: BTreeMap::new(),
        }
    }

    /// Write a file.
    pub fn put(&mut self, name: String, bytes: Vec<u8>) -> Result<()> {
        (self.put)(name, bytes)
    }

    /// Write `values` (of `shape`) as the `.npy` file `name`, made at write time (speckle draws):
    /// listed in the manifest's `outputs` as `entry` says, refusing non-finite values
    /// ([`check_finite`] for arrays made at write time).
    pub fn npy(&mut self, name: String, values: &[f64], entry: OutputEntry) -> Result<()> {
        let count = values.iter().filter(|x| !x.is_finite()).count();
        if count > 0 {
            return Err(Error::NotFinite { what: format!("{name} (of {} values)", values.len()), count });
        }
        let bytes = npy::to_bytes(&entry.shape, values);
        self.table.insert(name.clone(), entry);
        self.put(name, bytes)
    }

    /// Write the coordinates along an axis (`axis`: its name, as the outputs' [`Axis`] names it)
    /// as the `.npy` file `name`.
    pub fn axis_file(&mut self, name: String, axis: &'static str, units: &'static str, values: &[f64]) -> Result<()> {
        let entry = OutputEntry { axis: Some(axis), ..OutputEntry::made("axis", &[values.len()], units, Vec::new()) };
        self.npy(name, values, entry)
    }

    /// A scalar output as an estimate (`sign ×` its tally, and its standard error).
    pub fn estimate(&mut self, o: &Output) -> Estimate {
        self.written.insert(o.name.clone());
        self.table.insert(o.file.clone(), OutputEntry::of(o));
        let s = o.slots.start;
        estimate(o.sign * self.mean[s], self.stderr[s])
    }

    /// An array output's values (`sign ×` the tallies) and standard errors as `.npy` files (the
    /// latter unless the output has none); returns them.
    pub fn array(&mut self, o: &Output) -> Result<(Vec<f64>, Vec<f64>)> {
        self.written.insert(o.name.clone());
        self.table.insert(o.file.clone(), OutputEntry::of(o));
        let (v, e) = o.values(self.mean, self.stderr);
        self.put(o.file.clone(), npy::to_bytes(&o.shape, &v))?;
        if o.stderr {
            self.put(stderr_file(&o.file), npy::to_bytes(&o.shape, &e))?;
        }
        Ok((v, e))
    }

    /// An image output as `.npy` files and an `.exr` whose channels are `channel` (what it
    /// holds: `intensity`, `m0_plus`, …) and `channel_stderr`; returns its values and standard
    /// errors (row 0 = the largest `y`, as written).
    pub fn image(&mut self, o: &Output, channel: &str) -> Result<(Vec<f64>, Vec<f64>)> {
        let Kind::Image { nx, ny, .. } = o.kind else { unreachable!("{} is declared an image", o.name) };
        let (v, e) = self.array(o)?;
        let name = format!("{}.exr", o.file.trim_end_matches(".npy"));
        let exr = exr_bytes(nx, ny, &[(channel, &v), (&format!("{channel}_stderr"), &e)])
            .map_err(|m| Error::Write { path: name.clone().into(), source: std::io::Error::other(m) })?;
        self.put(name.clone(), exr)?;
        if let Some(entry) = self.table.get_mut(&o.file) {
            entry.exr_file = Some(name);
        }
        if o.primary {
            self.pixel_error_map(o, nx, ny, &v, &e)?;
        }
        Ok((v, e))
    }

    /// A main image's per-pixel relative errors: a map (`.npy`, NaN where the value is 0; drawn
    /// beside the image in its figure) and its summary for the manifest.
    fn pixel_error_map(&mut self, o: &Output, nx: usize, ny: usize, v: &[f64], e: &[f64]) -> Result<()> {
        let pe = PixelErrors::of(v, e);
        let stem = o.file.trim_end_matches(".npy");
        let file = format!("{stem}_relative_error.npy");
        self.put(file.clone(), npy::to_bytes(&[ny, nx], &pe.map))?;
        let axes = o.axes.clone();
        let mut entry = OutputEntry::made("relative_error", &[ny, nx], "1 (σ/|value|; NaN where the value is 0)", axes);
        entry.undefined_nan = true;
        self.table.insert(file.clone(), entry);
        if let Some(entry) = self.table.get_mut(&o.file) {
            entry.relative_error_file = Some(file.clone());
        }
        let finite = |v: f64| v.is_finite().then_some(v);
        let regions = o.detector.and_then(|d| self.masks.get(&d)).map(|(mask_file, mask)| RegionEntry {
            mask_file: mask_file.clone(),
            errors: crate::output::RegionErrors::of(v, e, mask)
                .with_run(self.tails.get(&o.slots.start).copied(), self.paths),
        });
        let speckle = self.speckle.get(&o.slots.start).map(|&(c, frames)| {
            crate::output::SpeckleScale::new(c, frames, pe.median, regions.as_ref().map(|r| &r.errors))
        });
        let entry = PixelErrorEntry {
            file,
            median: finite(pe.median),
            p90: finite(pe.p90),
            pixels_without_signal: pe.without_signal,
            regions,
            speckle,
        };
        self.pixel_errors.insert(o.name.clone(), entry);
        Ok(())
    }

    /// Detector `i`'s declared outputs that no writer of its kind has written: images as `.npy`,
    /// `.exr` and their figure (titled and drawn as declared), other arrays as `.npy` (with their
    /// standard errors), scalars into `estimates` under their name after the detector's. An
    /// output declared in the registry and recorded into is thus written, completely, without a
    /// writer of its own.
    pub fn rest(&mut self, i: usize, estimates: &mut BTreeMap<String, Entry>) -> Result<()> {
        let registry = self.registry;
        for o in registry.of_detector(i) {
            if self.written.contains(&o.name) {
                continue;
            }
            match o.kind {
                Kind::Internal => {}
                Kind::Scalar => {
                    let key = o.name.split_once('.').map_or(o.name.as_str(), |(_, k)| k).to_string();
                    let e = self.estimate(o);
                    estimates.insert(key, Entry::Estimate(e));
                }
                Kind::Image { .. } => {
                    let (detector, what) = o.name.split_once('.').unwrap_or(("", &o.name));
                    let (v, e) = self.image(o, what)?;
                    let title = format!("{detector}: {}", if o.title.is_empty() { what } else { &o.title });
                    self.image_figure(o, &v, &e, &title, o.units)?;
                }
                _ => {
                    self.array(o)?;
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::Slots;

    /// An output declared and recorded into, but unknown to its detector's writer, is still
    /// written: an array as `.npy` with its standard errors, a scalar into the estimates.
    #[test]
    fn outputs_no_writer_knows_are_written_by_rest() {
        let mut reg = Registry::default();
        let base = |name: &str, kind, slots, shape| Output {
            name: name.into(),
            detector: Some(0),
            kind,
            slots,
            shape,
            units: "",
            file: String::new(),
            stderr: true,
            sign: -1.0,
            primary: false,
            budget_key: None,
            axes: Vec::new(),
            style: crate::output::Style::Sequential,
            title: String::new(),
            derivation: crate::output::Derivation::Tally,
            undefined_nan: false,
        };
        let start = reg.take(4);
        let image = Kind::Image { nx: 2, ny: 1, min: [0.0; 2], max: [1.0; 2] };
        reg.declare(Output {
            file: "new.npy".into(),
            ..base("cam.new", image, Slots::contiguous(start, 2), vec![1, 2])
        });
        reg.declare(Output {
            file: "/estimates/detectors/cam/flux/value".into(),
            ..base("cam.flux", Kind::Scalar, Slots::contiguous(start + 2, 1), vec![])
        });
        reg.declare(base("cam.work", Kind::Internal, Slots::contiguous(start + 3, 1), vec![1]));
        let (mean, se) = ([1.0, 2.0, 3.0, 4.0], [0.1, 0.2, 0.3, 0.4]);
        let mut files: Vec<(String, Vec<u8>)> = Vec::new();
        let mut put = |name: String, bytes: Vec<u8>| -> Result<()> {
            files.push((name, bytes));
            Ok(())
        };
        let mut w = Writer::new(&mut put, &reg, &mean, &se);
        w.figures = false;
        let mut estimates = BTreeMap::new();
        w.rest(0, &mut estimates).unwrap();
        // Each is listed in the outputs table with its kind and units.
        assert_eq!(w.table["new.npy"].kind, "image");
        assert_eq!(w.table["new.npy"].exr_file.as_deref(), Some("new.exr"));
        assert!(w.table.keys().any(|k| k.starts_with('/')), "the scalar");
        drop(w);
        assert_eq!(estimates.get("flux"), Some(&Entry::Estimate(estimate(-3.0, 0.3))));
        assert_eq!(estimates.len(), 1);
        let names: Vec<&str> = files.iter().map(|f| f.0.as_str()).collect();
        assert_eq!(names, ["new.npy", "new_stderr.npy", "new.exr"]);
        assert_eq!(npy::from_bytes(&files[0].1), Some((vec![1, 2], vec![-1.0, -2.0])));
        assert_eq!(npy::from_bytes(&files[1].1), Some((vec![1, 2], vec![0.1, 0.2])));
    }
}
