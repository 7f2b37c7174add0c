//! Writing a finished run's outputs, as the run's [`crate::output::Registry`]
//! declares them: `manifest.json` and every detector's files ([`manifest::write_run`]), an LDH
//! camera's ([`ldh`]) and a lidar receiver's ([`lidar`]) outputs, FMCW read-offs ([`fmcw`]), a
//! scan's VAD wind ([`scan`]) and the convergence study ([`converge`]).

pub mod converge;
pub mod fmcw;
pub mod ldh;
pub mod lidar;
pub mod manifest;
pub mod scan;

use std::collections::BTreeMap;

use serde::Serialize;

use super::formats::{exr::exr_bytes, npy};
use crate::error::{Error, Result};
use crate::output::{Kind, Output, Registry};

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

/// The layout of every image file.
pub const IMAGE_LAYOUT: &str = "rows = y (ascending), columns = x (ascending)";

/// Where a file goes: `put(name, bytes)` writes it atomically and lists it in the manifest.
pub type Put<'a> = dyn FnMut(String, Vec<u8>) -> Result<()> + 'a;

/// `file.npy` → `file_stderr.npy`.
pub fn stderr_file(file: &str) -> String {
    format!("{}_stderr.npy", file.trim_end_matches(".npy"))
}

/// A finished run's outputs being written: where files go, the registry that declares the
/// outputs, and the run's means and standard errors laid out as the tallies.
pub struct Writer<'a, 'p> {
    pub put: &'a mut Put<'p>,
    pub registry: &'a Registry,
    pub mean: &'a [f64],
    pub stderr: &'a [f64],
}

impl<'a> Writer<'a, '_> {
    /// Write a file.
    pub fn put(&mut self, name: String, bytes: Vec<u8>) -> Result<()> {
        (self.put)(name, bytes)
    }

    /// The output `name` (declared by the detector being written).
    pub fn output(&self, name: &str) -> &'a Output {
        self.registry.get(name).unwrap_or_else(|| panic!("the output {name} is declared"))
    }

    /// A scalar output as an estimate (`sign ×` its tally, and its standard error).
    pub fn estimate(&self, o: &Output) -> Estimate {
        let s = o.slots.start;
        estimate(o.sign * self.mean[s], self.stderr[s])
    }

    /// An array output's values (`sign ×` the tallies) and standard errors as `.npy` files (the
    /// latter unless the output has none); returns them.
    pub fn array(&mut self, o: &Output) -> Result<(Vec<f64>, Vec<f64>)> {
        let (v, e) = o.values(self.mean, self.stderr);
        self.put(o.file.clone(), npy::to_bytes(&o.shape, &v))?;
        if o.stderr {
            self.put(stderr_file(&o.file), npy::to_bytes(&o.shape, &e))?;
        }
        Ok((v, e))
    }

    /// An image output as `.npy` files and an `.exr` whose channels are `channel` and
    /// `stderr`; returns its values and standard errors.
    pub fn image(&mut self, o: &Output, channel: &str) -> Result<(Vec<f64>, Vec<f64>)> {
        let Kind::Image { nx, ny, .. } = o.kind else { unreachable!("{} is declared an image", o.name) };
        let (v, e) = self.array(o)?;
        let name = format!("{}.exr", o.file.trim_end_matches(".npy"));
        let exr = exr_bytes(nx, ny, &[(channel, &v), ("stderr", &e)])
            .map_err(|m| Error::Write { path: name.clone().into(), source: std::io::Error::other(m) })?;
        self.put(name, exr)?;
        Ok((v, e))
    }
}
