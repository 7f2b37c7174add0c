//! Configuration: TOML text → (`--set` overrides) → [`schema::ExperimentFile`] →
//! [`resolve::resolve`] → a validated [`crate::experiment::Experiment`] in SI units.
//!
//! Every error on that way is a [`ConfigError`] naming the key path, the value and what was
//! expected.

pub mod preset;
pub mod resolve;
pub mod schema;
pub mod units;

use std::path::Path;

use crate::error::ConfigError;
use crate::experiment::Experiment;

pub use resolve::resolve;

/// Largest configuration file read, bytes: far above any experiment (a `[reference]` array of a
/// million values is ~20 MiB of TOML), far below what would exhaust memory.
pub const MAX_FILE_BYTES: u64 = 64 << 20;

/// Parse TOML text into a table; `origin` (a file name) prefixes syntax errors.
pub fn parse(text: &str, origin: &str) -> Result<toml::Table, ConfigError> {
    text.parse::<toml::Table>()
        .map_err(|e| ConfigError::new(origin, format!("invalid TOML: {}", syntax_error(text, &e))))
}

/// Characters of a TOML line shown around a syntax error.
const EXCERPT: usize = 100;

/// The TOML parser's report of a syntax error in `text` (where, the line, a caret under the
/// spot, what), with a line longer than [`EXCERPT`] characters shown as a window around the spot
/// (issue 21: a 1 MB line was echoed whole, twice with the carets).
fn syntax_error(text: &str, e: &toml::de::Error) -> String {
    let report = e.to_string();
    let report = report.trim_end();
    let Some(span) = e.span().filter(|_| report.lines().any(|l| l.chars().count() > EXCERPT + 10)) else {
        return report.to_string();
    };
    let mut at = span.start.min(text.len());
    while !text.is_char_boundary(at) {
        at -= 1;
    }
    let line_start = text[..at].rfind('\n').map_or(0, |i| i + 1);
    let line_end = text[at..].find('\n').map_or(text.len(), |i| at + i);
    let line = text[line_start..line_end].trim_end_matches('\r');
    let number = text[..line_start].matches('\n').count() + 1;
    let column = text[line_start..at].chars().count();
    let from = column.saturating_sub(EXCERPT / 2);
    let chars = line.chars().count();
    let (before, after) = (if from > 0 { "…" } else { "" }, if from + EXCERPT < chars { "…" } else { "" });
    let shown: String = line.chars().skip(from).take(EXCERPT).collect();
    let carets = span.len().clamp(1, (EXCERPT - (column - from)).max(1));
    let pad = " ".repeat(number.to_string().len());
    let indent = " ".repeat(column - from + before.chars().count());
    format!(
        "TOML parse error at line {number}, column {}\n{pad} |\n{number} | {before}{shown}{after}\n{pad} | {indent}{}\n{}",
        column + 1,
        "^".repeat(carets),
        e.message()
    )
}

/// Apply one `KEY=VALUE` override: `KEY` is a dotted path (array elements by index, e.g.
/// `layers.0.thickness_mm`), `VALUE` a TOML value (`2.5`, `[0, 0, 1]`, `"disk"`); a bare word that
/// is not valid TOML is taken as a string. Missing tables on the path are created.
pub fn apply_set(doc: &mut toml::Table, assignment: &str) -> Result<(), ConfigError> {
    let (key, raw) = assignment
        .split_once('=')
        .ok_or_else(|| ConfigError::new("--set", format!("`{assignment}`: expected KEY=VALUE")))?;
    let key = key.trim();
    let raw = raw.trim();
    let value = match format!("v = {raw}").parse::<toml::Table>() {
        Ok(mut t) => t.remove("v").expect("parsed key"),
        Err(_) => toml::Value::String(raw.to_string()),
    };
    let parts: Vec<&str> = key.split('.').collect();
    if key.is_empty() || parts.iter().any(|p| p.is_empty()) {
        return Err(ConfigError::new("--set", format!("`{key}`: expected a dotted key path such as run.samples")));
    }
    let mut root = toml::Value::Table(std::mem::take(doc));
    let result = set_path(&mut root, &parts, value);
    if let toml::Value::Table(t) = root {
        *doc = t;
    }
    result
}

fn set_path(root: &mut toml::Value, parts: &[&str], value: toml::Value) -> Result<(), ConfigError> {
    let mut node = root;
    for (i, part) in parts.iter().enumerate() {
        let last = i + 1 == parts.len();
        let here = parts[..=i].join(".");
        node = match node {
            toml::Value::Table(t) => {
                if last {
                    units::insert_replacing(t, part, value);
                    return Ok(());
                }
                t.entry(part.to_string()).or_insert_with(|| toml::Value::Table(toml::Table::new()))
            }
            toml::Value::Array(a) => {
                let len = a.len();
                let idx: usize = part.parse().map_err(|_| {
                    ConfigError::new(
                        format!("--set {here}"),
                        format!("`{part}` is not an index into an array of {len}"),
                    )
                })?;
                let slot = a.get_mut(idx).ok_or_else(|| {
                    ConfigError::new(format!("--set {here}"), format!("index {idx} is out of range (array of {len})"))
                })?;
                if last {
                    *slot = value;
                    return Ok(());
                }
                slot
            }
            _ => {
                return Err(ConfigError::new(
                    format!("--set {}", parts.join(".")),
                    format!("`{}` is a value, not a table", parts[..i].join(".")),
                ));
            }
        };
    }
    Ok(())
}

/// Parse `text`, apply the overrides in order, expand media presets, deserialise and resolve.
/// Returns the table as run (after overrides, presets expanded) with the resolved experiment.
///
/// Files the configuration names (phase tables) are found relative to the directory of `origin`
/// when it is a file, else relative to the working directory.
pub fn load(text: &str, origin: &str, sets: &[String]) -> Result<(toml::Table, Experiment), ConfigError> {
    let mut doc = parse(text, origin)?;
    for s in sets {
        apply_set(&mut doc, s)?;
    }
    preset::expand(&mut doc)?;
    let file = deserialize(&doc)?;
    let origin = Path::new(origin);
    let base = if origin.is_file() { origin.parent().unwrap_or(Path::new(".")) } else { Path::new(".") };
    let experiment = resolve::resolve_in(&file, base)?;
    Ok((doc, experiment))
}

/// Deserialise a table into the schema, with errors naming the key path.
pub fn deserialize(doc: &toml::Table) -> Result<schema::ExperimentFile, ConfigError> {
    match doc.get("schema_version") {
        None => {
            return Err(ConfigError::new(
                "schema_version",
                format!("missing; this ohd reads schema_version = {}", schema::SCHEMA_VERSION),
            ));
        }
        Some(toml::Value::Integer(v)) if *v == schema::SCHEMA_VERSION => {}
        Some(v) => {
            return Err(ConfigError::new(
                "schema_version",
                format!("= {v}: this ohd reads schema_version = {}", schema::SCHEMA_VERSION),
            ));
        }
    }
    // Quantities learn the key they were given under (and so their unit) from one pre-pass.
    let mut marked = units::mark(doc);
    serde_path_to_error::deserialize(toml::Value::Table(std::mem::take(&mut marked.table))).map_err(|e| {
        let path = e.path().to_string();
        let path = if path == "." { "(top level)".to_string() } else { path };
        let message = e.into_inner().message().to_string();
        marked
            .duplicate(&path, &message)
            .unwrap_or_else(|| ConfigError::new(path, units::readable(&units::order_expected_keys(&message))))
    })
}
