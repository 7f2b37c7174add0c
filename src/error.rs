//! Typed errors. Configuration errors name the TOML key path, the offending value and what was
//! expected (range and unit); file errors name the file.

use std::path::PathBuf;

/// An invalid experiment description: a TOML syntax error, an unknown key, a wrong type or an
/// out-of-range value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{path}: {message}")]
pub struct ConfigError {
    /// Dotted key path, e.g. `layers[0].thickness_mm`; the file name for syntax errors.
    pub path: String,
    /// What is wrong, with the value and the expected range and unit.
    pub message: String,
}

impl Error {
    /// A file that was read but holds something invalid (exit status 2), with why.
    pub fn invalid_file(path: impl Into<PathBuf>, why: impl Into<String>) -> Self {
        Error::Read { path: path.into(), source: std::io::Error::new(std::io::ErrorKind::InvalidData, why.into()) }
    }
}

impl ConfigError {
    pub fn new(path: impl Into<String>, message: impl Into<String>) -> Self {
        Self { path: path.into(), message: message.into() }
    }
}

/// An OpenVDB file that cannot be read ([`crate::io::formats::vdb`]): names the file, the grid when there
/// is one, and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("VDB file {}{}: {message}", path.display(), grid.as_ref().map(|g| format!(", grid \"{g}\"")).unwrap_or_default())]
pub struct VdbError {
    pub path: PathBuf,
    pub grid: Option<String>,
    pub message: String,
}

/// Every error the library returns.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Bad input in the experiment description (exit status 2).
    #[error("config error: {0}")]
    Config(#[from] ConfigError),
    /// A file that could not be read (exit status 2: it is input).
    #[error("cannot read {path}: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    /// A file that could not be written (exit status 1).
    #[error("cannot write {path}: {source}")]
    Write { path: PathBuf, source: std::io::Error },
    /// An OpenVDB file that cannot be read (exit status 2: it is input).
    #[error(transparent)]
    Vdb(#[from] VdbError),
    /// Any other bad input (a command-line value out of range), with its message (exit status 2).
    #[error("{0}")]
    Input(String),
    /// A run whose output holds values that are not finite (exit status 1): validation should have
    /// refused what led to it, so the outputs are not written rather than written with NaN.
    #[error(
        "the run produced {count} non-finite value(s) (NaN or infinite) in {what}: its outputs are not written. A configuration value outside what validation checks is the likely cause; please report it with the configuration"
    )]
    NotFinite { what: String, count: usize },
}

impl Error {
    /// Whether the error is the user's input (exit status 2) rather than a failure to run.
    pub fn is_input_error(&self) -> bool {
        matches!(self, Error::Config(_) | Error::Read { .. } | Error::Vdb(_) | Error::Input(_))
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
