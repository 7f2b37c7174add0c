//! Phase-table files (`*.phase.toml`, format documented in `media/README.md`): reading with
//! validation, and writing (`ohd mie --table`).
//!
//! A table is TOML: a header (`format`, `version`, `normalisation`, free-text `description`), an
//! optional `[optics]` record of what it describes (wavelength, indices, size distribution, Mie
//! efficiencies), a `[provenance]` table of strings, and two equally long columns: the angles
//! (`theta_deg` or `cos_theta`, strictly monotone, spanning 0°–180°) and `value`.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::phase::TabulatedPhase;

/// The `format` string that identifies a phase-table file.
pub const FORMAT: &str = "ohd-phase-table";
/// The table format version this build reads and writes.
pub const VERSION: i64 = 1;

/// How the values of a table are normalised as written (the loader renormalises to sr⁻¹ in any
/// case; a declared normalisation is checked, which catches a 4π or 2π mix-up).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Normalisation {
    /// `∫ p dΩ = 1` (sr⁻¹).
    PerSr,
    /// `∫ p dΩ = 4π` (the atmospheric-science convention).
    FourPi,
    /// Any positive scale (e.g. `(|S1|² + |S2|²)/2` as computed).
    Arbitrary,
}

impl Normalisation {
    /// `∫ p dΩ` a table in this normalisation should have.
    pub fn expected_integral(self) -> Option<f64> {
        match self {
            Normalisation::PerSr => Some(1.0),
            Normalisation::FourPi => Some(4.0 * std::f64::consts::PI),
            Normalisation::Arbitrary => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Normalisation::PerSr => "per_sr",
            Normalisation::FourPi => "four_pi",
            Normalisation::Arbitrary => "arbitrary",
        }
    }
}

/// How far a declared normalisation may be off (the piecewise-linear integral of a coarse table
/// differs from the true one) before the file is rejected as mislabelled.
pub const NORMALISATION_TOLERANCE: f64 = 0.1;

/// What a table describes; every field optional (a measured table has no Mie efficiencies).
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TableOptics {
    /// Vacuum wavelength the table is for; checked against the source when given.
    pub wavelength_nm: Option<f64>,
    pub n_medium: Option<f64>,
    pub n_particle: Option<f64>,
    pub k_particle: Option<f64>,
    /// Free text, e.g. "monodisperse, diameter 5.56 µm".
    pub size_distribution: Option<String>,
    pub size_parameter: Option<f64>,
    pub qext: Option<f64>,
    pub qsca: Option<f64>,
    pub qback: Option<f64>,
    /// Mean cosine of the exact (not tabulated) phase function.
    pub g: Option<f64>,
    pub sigma_s_per_m: Option<f64>,
    pub sigma_a_per_m: Option<f64>,
}

/// A phase-table file as written.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PhaseTableFile {
    pub format: String,
    pub version: i64,
    #[serde(default)]
    pub description: Option<String>,
    pub normalisation: Normalisation,
    #[serde(default)]
    pub optics: TableOptics,
    #[serde(default)]
    pub provenance: BTreeMap<String, String>,
    pub theta_deg: Option<Vec<f64>>,
    pub cos_theta: Option<Vec<f64>>,
    pub value: Vec<f64>,
}

/// A table read from a file: the phase function and the file's header.
#[derive(Debug, Clone)]
pub struct LoadedTable {
    pub phase: TabulatedPhase,
    pub file: PhaseTableFile,
}

/// Largest phase-table file read, bytes (`ohd mie --table` writes at most 100 000 angles, ~5 MiB).
pub const MAX_FILE_BYTES: u64 = 64 << 20;

/// Read and validate a phase table. The error is a message naming the file.
pub fn read_phase_table(path: &Path) -> Result<LoadedTable, String> {
    let shown = path.display();
    let text = crate::io::read_text_limited(path, MAX_FILE_BYTES, "a phase table").map_err(|e| match e {
        crate::error::Error::Read { source, .. } => format!("cannot read phase table `{shown}`: {source}"),
        e => e.to_string(),
    })?;
    parse_phase_table(&text, &shown.to_string())
}

/// Parse a phase table from text; `origin` names it in messages.
pub fn parse_phase_table(text: &str, origin: &str) -> Result<LoadedTable, String> {
    let bad = |m: String| format!("phase table `{origin}`: {m}");
    let doc: toml::Table = text.parse().map_err(|e: toml::de::Error| bad(format!("invalid TOML: {}", e.message())))?;
    match doc.get("format").and_then(|v| v.as_str()) {
        Some(FORMAT) => {}
        other => {
            return Err(bad(format!(
                "format = {}: expected format = \"{FORMAT}\" (see media/README.md)",
                other.map_or("(missing)".to_string(), |s| format!("\"{s}\""))
            )));
        }
    }
    match doc.get("version") {
        Some(toml::Value::Integer(VERSION)) => {}
        v => {
            let v = v.map_or("(missing)".to_string(), |v| v.to_string());
            return Err(bad(format!("version = {v}: this ohd reads version = {VERSION}")));
        }
    }
    let file: PhaseTableFile = serde_path_to_error::deserialize(toml::Value::Table(doc))
        .map_err(|e| bad(format!("{}: {}", e.path(), e.inner().message())))?;
    let phase = match (&file.theta_deg, &file.cos_theta) {
        (Some(t), None) => {
            let rad: Vec<f64> = t.iter().map(|d| d.to_radians()).collect();
            TabulatedPhase::from_angles(&rad, &file.value, origin)
        }
        (None, Some(c)) => TabulatedPhase::from_cosines(c, &file.value, origin),
        _ => return Err(bad("give exactly one angle column, theta_deg or cos_theta".into())),
    }
    .map_err(|e| bad(e.to_string()))?;
    if let Some(expected) = file.normalisation.expected_integral() {
        let ratio = phase.source_integral() / expected;
        if (ratio - 1.0).abs() > NORMALISATION_TOLERANCE {
            return Err(bad(format!(
                "normalisation = \"{}\" but the values integrate to {:.6} over the sphere ({:.4}× the expected {:.6}); \
                 fix the normalisation (per_sr, four_pi) or declare \"arbitrary\" to renormalise",
                file.normalisation.name(),
                phase.source_integral(),
                ratio,
                expected
            )));
        }
    }
    Ok(LoadedTable { phase, file })
}

/// The text of a phase-table file with angles in degrees (numbers written to round-trip exactly).
pub fn phase_table_text(
    description: &str,
    normalisation: Normalisation,
    optics: &TableOptics,
    provenance: &BTreeMap<String, String>,
    theta_deg: &[f64],
    values: &[f64],
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Phase table for ohd; format described in media/README.md.");
    let _ = writeln!(s, "format = \"{FORMAT}\"");
    let _ = writeln!(s, "version = {VERSION}");
    let _ = writeln!(s, "description = {}", toml::Value::String(description.to_string()));
    let _ = writeln!(s, "normalisation = \"{}\"", normalisation.name());
    let section = |s: &mut String, name: &str, table: String| {
        if !table.trim().is_empty() {
            let _ = write!(s, "\n[{name}]\n{table}");
        }
    };
    section(&mut s, "optics", toml::to_string(optics).unwrap_or_default());
    section(&mut s, "provenance", toml::to_string(provenance).unwrap_or_default());
    let column = |s: &mut String, name: &str, v: &[f64]| {
        let _ = writeln!(s, "\n{name} = [");
        for row in v.chunks(6) {
            let line: Vec<String> = row.iter().map(|x| format!("{x:e}")).collect();
            let _ = writeln!(s, "  {},", line.join(", "));
        }
        let _ = writeln!(s, "]");
    };
    // Top-level keys must precede the tables in TOML: put the columns before [optics].
    let mut head = String::new();
    let split = s.find("\n[").unwrap_or(s.len());
    head.push_str(&s[..split]);
    column(&mut head, "theta_deg", theta_deg);
    column(&mut head, "value", values);
    head.push_str(&s[split..]);
    head
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(norm: &str, values: &str) -> String {
        format!(
            "format = \"{FORMAT}\"\nversion = 1\nnormalisation = \"{norm}\"\ntheta_deg = [0, 90, 180]\nvalue = [{values}]\n"
        )
    }

    #[test]
    fn round_trips_through_text() {
        let theta: Vec<f64> = (0..=180).map(|d| d as f64).collect();
        let v: Vec<f64> =
            theta.iter().map(|t| (1.0 + t.to_radians().cos().powi(2)) * 3.0 / (16.0 * std::f64::consts::PI)).collect();
        let optics = TableOptics { wavelength_nm: Some(785.0), g: Some(0.0), ..Default::default() };
        let prov = BTreeMap::from([("generator".to_string(), "test".to_string())]);
        let text = phase_table_text("Rayleigh", Normalisation::PerSr, &optics, &prov, &theta, &v);
        let t = parse_phase_table(&text, "mem").unwrap();
        assert_eq!(t.file.value, v);
        assert_eq!(t.file.theta_deg.as_deref(), Some(theta.as_slice()));
        assert_eq!(t.file.optics, optics);
        assert_eq!(t.file.provenance, prov);
        assert!((t.phase.source_integral() - 1.0).abs() < 1e-3);
    }

    #[test]
    fn clear_errors() {
        let e = |text: &str| parse_phase_table(text, "t.phase.toml").unwrap_err();
        assert!(e("format = \"csv\"").contains("expected format = \"ohd-phase-table\""));
        assert!(e(&table("per_sr", "1, -1, 1")).contains("value 1 is negative"));
        assert!(e(&table("per_sr", "1, nan, 1")).contains("entry 1 is not a finite number"));
        assert!(e(&table("per_sr", "1, 1")).contains("3 angles but 2 values"));
        assert!(e(&table("per_sr", "0, 0, 0")).contains("all values are zero"));
        assert!(e(&table("per_cos", "1, 1, 1")).contains("normalisation"));
        // Uniform 1/(4π) would be per_sr; 1 everywhere integrates to 4π.
        assert!(e(&table("per_sr", "1, 1, 1")).contains("integrate to 12.566"));
        assert!(parse_phase_table(&table("four_pi", "1, 1, 1"), "t").is_ok());
        assert!(parse_phase_table(&table("arbitrary", "5, 5, 5"), "t").is_ok());
        let t = "format = \"ohd-phase-table\"\nversion = 1\nnormalisation = \"per_sr\"\ntheta_deg = [0, 100, 90, 180]\nvalue = [1, 1, 1, 1]\nextra = 1\n";
        assert!(e(t).contains("unknown field `extra`"), "{}", e(t));
        let t = t.replace("extra = 1\n", "");
        assert!(e(&t).contains("not strictly monotone at entry 2"), "{}", e(&t));
        assert!(e("format = \"ohd-phase-table\"\nversion = 2").contains("version = 2"));
    }
}
