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
pub mod ldh;
pub mod lidar;
pub mod manifest;
pub mod memory;
pub mod scan;
pub mod tcorr;
pub mod volume;

use std::collections::{BTreeMap, BTreeSet};

use serde::Serialize;

use super::formats::{exr::exr_bytes, npy};
use crate::error::{Error, Result};
use crate::output::{Kind, Output, PixelErrors, Registry};

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

/// The last line of defence against non-finite outputs (issue 21, item 4): validation refuses
/// what cannot give finite output, so a NaN or an infinity in a run's estimates or standard errors
/// is a bug, and the run fails (exit status 1) naming the first output that holds one, before any
/// file is written, rather than write it silently (NaN is let through where an output documents it
/// as undefined: [`crate::output::Output::undefined_nan`]). Every written output is checked, its
/// out-of-range tallies included; internal ones (a lidar's lag sums) are not written, and show in
/// the outputs made from them.
pub fn check_finite(registry: &Registry, mean: &[f64], stderr: &[f64]) -> Result<()> {
    for o in registry.outputs.iter().filter(|o| o.kind != Kind::Internal) {
        let slots = o.slots.start..o.slots.start + o.slots.footprint();
        let bad = |x: &f64| if o.undefined_nan { x.is_infinite() } else { !x.is_finite() };
        let count = |v: &[f64]| v[slots.clone()].iter().filter(|x| bad(x)).count();
        let (values, errors) = (count(mean), count(stderr));
        if values + errors > 0 {
            let what = format!(
                "output {} ({values} of its {} values and {errors} of their standard errors; file {})",
                o.name,
                slots.len(),
                o.file.trim_start_matches('/')
            );
            return Err(Error::NotFinite { what, count: values + errors });
        }
    }
    Ok(())
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
}

impl<'a, 'p> Writer<'a, 'p> {
    pub fn new(put: &'a mut Put<'p>, registry: &'a Registry, mean: &'a [f64], stderr: &'a [f64]) -> Self {
        Writer { put, registry, mean, stderr, written: BTreeSet::new(), pixel_errors: BTreeMap::new(), figures: true }
    }

    /// Write a file.
    pub fn put(&mut self, name: String, bytes: Vec<u8>) -> Result<()> {
        (self.put)(name, bytes)
    }

    /// Write `values` (of `shape`) as the `.npy` file `name`, refusing non-finite values
    /// ([`check_finite`] for arrays made at write time: axes, speckle).
    pub fn npy(&mut self, name: String, shape: &[usize], values: &[f64]) -> Result<()> {
        let count = values.iter().filter(|x| !x.is_finite()).count();
        if count > 0 {
            return Err(Error::NotFinite { what: format!("{name} (of {} values)", values.len()), count });
        }
        self.put(name, npy::to_bytes(shape, values))
    }

    /// The output `name` (declared by the detector being written).
    pub fn output(&self, name: &str) -> &'a Output {
        self.registry.expect(name)
    }

    /// A scalar output as an estimate (`sign ×` its tally, and its standard error).
    pub fn estimate(&mut self, o: &Output) -> Estimate {
        self.written.insert(o.name.clone());
        let s = o.slots.start;
        estimate(o.sign * self.mean[s], self.stderr[s])
    }

    /// An array output's values (`sign ×` the tallies) and standard errors as `.npy` files (the
    /// latter unless the output has none); returns them.
    pub fn array(&mut self, o: &Output) -> Result<(Vec<f64>, Vec<f64>)> {
        self.written.insert(o.name.clone());
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
        self.put(name, exr)?;
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
        let finite = |v: f64| v.is_finite().then_some(v);
        let entry = PixelErrorEntry {
            file,
            median: finite(pe.median),
            p90: finite(pe.p90),
            pixels_without_signal: pe.without_signal,
        };
        self.pixel_errors.insert(o.name.clone(), entry);
        Ok(())
    }

    /// Detector `i`'s declared outputs that no writer of its kind has written: arrays as `.npy`
    /// (with their standard errors), scalars into `estimates` under their name after the
    /// detector's. An output declared in the registry and recorded into is thus written even
    /// before its detector's writer knows of it.
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
            undefined_nan: false,
        };
        let start = reg.take(4);
        let image = Kind::Image { nx: 2, ny: 1, min: [0.0; 2], max: [1.0; 2] };
        reg.declare(Output {
            file: "new.npy".into(),
            ..base("cam.new", image, Slots::contiguous(start, 2), vec![1, 2])
        });
        reg.declare(base("cam.flux", Kind::Scalar, Slots::contiguous(start + 2, 1), vec![]));
        reg.declare(base("cam.work", Kind::Internal, Slots::contiguous(start + 3, 1), vec![1]));
        let (mean, se) = ([1.0, 2.0, 3.0, 4.0], [0.1, 0.2, 0.3, 0.4]);
        let mut files: Vec<(String, Vec<u8>)> = Vec::new();
        let mut put = |name: String, bytes: Vec<u8>| -> Result<()> {
            files.push((name, bytes));
            Ok(())
        };
        let mut w = Writer::new(&mut put, &reg, &mean, &se);
        let mut estimates = BTreeMap::new();
        w.rest(0, &mut estimates).unwrap();
        assert_eq!(estimates.get("flux"), Some(&Entry::Estimate(estimate(-3.0, 0.3))));
        assert_eq!(estimates.len(), 1);
        let names: Vec<&str> = files.iter().map(|f| f.0.as_str()).collect();
        assert_eq!(names, ["new.npy", "new_stderr.npy"]);
        assert_eq!(npy::from_bytes(&files[0].1), Some((vec![1, 2], vec![-1.0, -2.0])));
        assert_eq!(npy::from_bytes(&files[1].1), Some((vec![1, 2], vec![0.1, 0.2])));
    }
}
