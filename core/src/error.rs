//! Typed errors. Configuration errors name the TOML key path, the offending value and what was
//! expected (range and unit); file errors name the file.
//!
//! Messages are shown bounded ([`bounded`]; issue 21: a 1 MB key was echoed as 2 MB of stderr, 1e300
//! as 301 digits): a number that `{}` prints in more than 24 characters is shown in exponent form
//! (the same value), a word (a key, a name, a path) longer than [`SHOWN_WORD`] characters and a
//! message longer than [`SHOWN_MESSAGE`] are cut in the middle with `…` and their length, and lists
//! show their first [`SHOWN_ITEMS`] items ([`list`]). The errors keep the whole text; only their
//! `Display` is bounded.

use std::borrow::Cow;
use std::fmt::Display;
use std::path::PathBuf;

/// An invalid experiment description: a TOML syntax error, an unknown key, a wrong type or an
/// out-of-range value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {}", bounded(.path), bounded(.message))]
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
#[error(
    "VDB file {}{}: {}",
    path.display(),
    grid.as_ref().map(|g| format!(", grid \"{}\"", shorten(g, SHOWN_WORD))).unwrap_or_default(),
    bounded(.message)
)]
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
    /// A path ohd will not write, replace or remove (exit status 2: it is input): outside the
    /// output directory, through a link planted there, not a regular file, or a directory
    /// unusable as the output directory or in use by another ohd ([`crate::io::outdir`]).
    #[error("{}: {why}", path.display())]
    Refused { path: PathBuf, why: String },
    /// An OpenVDB file that cannot be read (exit status 2: it is input).
    #[error(transparent)]
    Vdb(#[from] VdbError),
    /// Any other bad input (a command-line value out of range), with its message (exit status 2).
    #[error("{}", bounded(.0))]
    Input(String),
    /// A run whose output holds values that are not finite (exit status 1): validation should have
    /// refused what led to it, so the outputs are not written rather than written with NaN.
    #[error(
        "the run produced {count} non-finite value(s) (NaN or infinite) in {what}: its outputs are not written. A configuration value outside what validation checks is the likely cause; please report it with the configuration"
    )]
    NotFinite { what: String, count: usize },
    /// A run stopped before its end because its caller asked ([`crate::experiment::Progress::cancelled`]:
    /// a second Ctrl-C in the Python package; or stopping before any batch was done); nothing is
    /// written.
    #[error("the run was cancelled")]
    Cancelled,
    /// A run ended early because its caller asked ([`crate::experiment::Progress::stopping`]: the
    /// first Ctrl-C), after writing the result of the batches done and a checkpoint of them.
    #[error(
        "interrupted: the result of {batches} of {planned} batches is written into {} (its errors from those batches, the manifest's `interrupted` says so); `--resume` with the same command finishes the run",
        dir.display()
    )]
    Interrupted { dir: std::path::PathBuf, batches: u64, planned: u64 },
}

impl Error {
    /// Whether the error is the user's input (exit status 2) rather than a failure to run.
    pub fn is_input_error(&self) -> bool {
        matches!(self, Error::Config(_) | Error::Read { .. } | Error::Refused { .. } | Error::Vdb(_) | Error::Input(_))
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Characters of one word of a message (a key, a name, a path) shown whole.
pub const SHOWN_WORD: usize = 200;

/// Characters of a message shown whole.
pub const SHOWN_MESSAGE: usize = 4000;

/// Items of a list shown in a message ([`list`]).
pub const SHOWN_ITEMS: usize = 10;

/// A number printed by `{}` in more characters than this is shown in exponent form.
const LONG_NUMBER: usize = 24;

/// `s` if it has at most `max` characters, else its start and end around `…`, and its length:
/// `aaaaaaaa…aaaa (1000000 characters)`.
pub fn shorten(s: &str, max: usize) -> Cow<'_, str> {
    let n = s.chars().count();
    if n <= max {
        return Cow::Borrowed(s);
    }
    let head = max - max / 3;
    let tail = max / 3;
    let head_end = s.char_indices().nth(head).map_or(s.len(), |(i, _)| i);
    let tail_start = s.char_indices().nth(n - tail).map_or(s.len(), |(i, _)| i);
    Cow::Owned(format!("{}…{} ({n} characters)", &s[..head_end], &s[tail_start..]))
}

/// `items` joined by `, `, each [`shorten`]ed: the first [`SHOWN_ITEMS`], then `… and N more`.
pub fn list<T: Display>(items: impl IntoIterator<Item = T>) -> String {
    let mut shown = Vec::new();
    let mut more = 0usize;
    for item in items {
        if shown.len() < SHOWN_ITEMS {
            shown.push(shorten(&item.to_string(), SHOWN_WORD).into_owned());
        } else {
            more += 1;
        }
    }
    let mut s = shown.join(", ");
    if more > 0 {
        s.push_str(&format!(" … and {more} more"));
    }
    s
}

/// `message` as shown: numbers that `{}` printed in more than 24 characters in exponent form (only
/// where the digits are exactly what `{}` prints for that `f64`, so the value shown is the same),
/// words longer than [`SHOWN_WORD`] characters and then the whole beyond [`SHOWN_MESSAGE`]
/// [`shorten`]ed.
pub fn bounded(message: &str) -> Cow<'_, str> {
    let compact = compact_numbers(message);
    let words = shorten_words(&compact);
    match shorten(&words, SHOWN_MESSAGE) {
        Cow::Borrowed(_) if matches!((&compact, &words), (Cow::Borrowed(_), Cow::Borrowed(_))) => {
            Cow::Borrowed(message)
        }
        c => Cow::Owned(c.into_owned()),
    }
}

/// Numbers written out in full (`1e300` as 301 digits, `1e-320` as 320 zeros) in exponent form.
fn compact_numbers(s: &str) -> Cow<'_, str> {
    let b = s.as_bytes();
    let word = |c: u8| c.is_ascii_alphanumeric() || c == b'_' || c == b'.';
    let digits = |mut j: usize| {
        while j < b.len() && b[j].is_ascii_digit() {
            j += 1;
        }
        j
    };
    let mut out = String::new();
    let (mut copied, mut i) = (0, 0);
    while i < b.len() {
        if !(b[i].is_ascii_digit() && (i == 0 || !word(b[i - 1]))) {
            i += 1;
            continue;
        }
        let minus = i > 0 && b[i - 1] == b'-' && (i == 1 || !word(b[i - 2]));
        let start = if minus { i - 1 } else { i };
        let mut end = digits(i);
        if end + 1 < b.len() && b[end] == b'.' && b[end + 1].is_ascii_digit() {
            end = digits(end + 1);
        }
        let bounded_after = end == b.len() || !(word(b[end]) || b[end] == b'-');
        if end - start > LONG_NUMBER && bounded_after {
            let token = &s[start..end];
            // `{}` of an f64, or serde's form of it (a `.0` appended to an integral value).
            let plain = token.strip_suffix(".0").unwrap_or(token);
            if let Ok(v) = token.parse::<f64>()
                && format!("{v}") == plain
            {
                out.push_str(&s[copied..start]);
                out.push_str(&format!("{v:e}"));
                copied = end;
            }
        }
        i = end;
    }
    if copied == 0 {
        return Cow::Borrowed(s);
    }
    out.push_str(&s[copied..]);
    Cow::Owned(out)
}

/// Every run of non-space characters longer than [`SHOWN_WORD`] [`shorten`]ed.
fn shorten_words(s: &str) -> Cow<'_, str> {
    let long = |w: &str| w.len() > SHOWN_WORD && w.chars().count() > SHOWN_WORD;
    if !s.split(char::is_whitespace).any(long) {
        return Cow::Borrowed(s);
    }
    let mut out = String::with_capacity(s.len().min(2 * SHOWN_MESSAGE));
    let mut rest = s;
    while !rest.is_empty() {
        let end = rest.find(char::is_whitespace).unwrap_or(rest.len());
        out.push_str(&shorten(&rest[..end], SHOWN_WORD));
        let after = rest[end..].find(|c: char| !c.is_whitespace()).map_or(rest.len(), |k| end + k);
        out.push_str(&rest[end..after]);
        rest = &rest[after..];
    }
    Cow::Owned(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_written_out_in_full_are_shown_in_exponent_form() {
        let big = format!("{}", 1e300);
        assert_eq!(big.len(), 301);
        let m = format!("= {big}: expected 0 to {}, or -{big} or {} or {}", 1e3, 1e-320, 12.5);
        assert_eq!(bounded(&m), "= 1e300: expected 0 to 1000, or -1e300 or 1e-320 or 12.5");
        // serde's `Unexpected::Float` appends `.0`; a 17-digit float stays as printed.
        let serde = format!("invalid type: floating point `{big}.0`, expected u64");
        assert_eq!(bounded(&serde), "invalid type: floating point `1e300`, expected u64");
        for unchanged in [
            "= 12345678901234567: expected 1 to 2^64 − 1",
            "layers[0].thickness_mm = 0.000001: expected > 0 mm",
            // Digits that are not exactly what `{}` prints for an f64 (a name, a hash) stay.
            "= \"1234567890123456789012345678\": unknown medium",
            "pointing_000000000000000000000000000001",
        ] {
            assert!(matches!(bounded(unchanged), Cow::Borrowed(_)), "{unchanged}");
        }
    }

    #[test]
    fn long_words_messages_and_lists_are_cut() {
        let key = "k".repeat(1_000_000);
        let m = format!("unknown field `{key}`, expected one of `a`, `b`");
        let shown = bounded(&m);
        assert!(shown.chars().count() < 300, "{shown}");
        assert!(
            shown.starts_with("unknown field `kkk")
                && shown.ends_with("`, (1000003 characters) expected one of `a`, `b`")
        );
        let many = (0..10_000).map(|i| format!("layer{i} ")).collect::<String>();
        assert!(bounded(&many).chars().count() < SHOWN_MESSAGE + 40);
        assert_eq!(shorten("αβγδεζηθ", 6), "αβγδ…ηθ (8 characters)");
        assert_eq!(shorten("short", 6), "short");
        let names = (0..10_000).map(|i| format!("m{i}"));
        assert_eq!(list(names), "m0, m1, m2, m3, m4, m5, m6, m7, m8, m9 … and 9990 more");
        assert_eq!(list(["a", "b"]), "a, b");
        let e = ConfigError::new(format!("media.{key}.g"), format!("= {}: expected −1 < g < 1", 1e300));
        let shown = e.to_string();
        assert!(shown.len() < 400 && shown.contains("kk.g (1000008 characters): = 1e300: expected"), "{shown}");
        assert!(Error::Input(format!("--target-error {}", -1e300)).to_string().ends_with(" -1e300"));
    }
}
