//! Units, in one place. A quantity whose natural unit is not SI carries its unit in its key
//! (`thickness_um`, `sigma_s_per_cm`, `f_max_khz`): [`UNITS`] declares every such suffix once, with
//! its family, its factor to SI and its unit as printed in messages.
//!
//! In the schema a quantity is one typed field, [`Quantity<S>`], whose unit set `S` names the
//! suffixes that key accepts (the serde attributes of the field name the same keys, for
//! `deny_unknown_fields`). [`mark`], one pre-pass over a copy of the table before it is
//! deserialised, wraps each value of a suffixed key together with the key as written, so that the
//! quantity knows its unit and messages name the key as the user wrote it; it also notes a
//! quantity given in two units, which serde refuses as a duplicate field and
//! [`Marked::duplicate`] words as "give only one of …". The table as written (recorded in the
//! manifest) is not changed. A key's accepted units are declared twice, necessarily: in its
//! field's serde names (what serde accepts and lists for a typo) and in its unit set (what
//! [`Quantity`] checks and what "missing …: give one of …" lists); a unit of the wrong set fails
//! at deserialisation.
//!
//! The same table serves overrides, which replace a quantity given in another unit
//! ([`insert_replacing`]).

use std::fmt;
use std::marker::PhantomData;

use serde::de::{DeserializeOwned, Error as _};
use serde::{Deserialize, Deserializer};

use crate::error::ConfigError;

/// What a unit measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    Length,
    Angle,
    Time,
    Frequency,
    Speed,
    Diffusivity,
    Viscosity,
    Temperature,
    Energy,
    /// Per length: attenuation coefficients.
    Attenuation,
    NumberDensity,
    AngularSpeed,
}

/// One unit suffix: `value × factor` is the value in SI units.
#[derive(Debug, PartialEq)]
pub struct Unit {
    pub suffix: &'static str,
    pub family: Family,
    pub factor: f64,
    /// As printed in messages.
    pub printed: &'static str,
}

const fn unit(suffix: &'static str, family: Family, factor: f64, printed: &'static str) -> Unit {
    Unit { suffix, family, factor, printed }
}

/// Every unit suffix a key may carry, by family. A key's suffix is the longest that matches, so
/// that `_mm_per_s` is not read as `_s`. (Degrees convert to radians; keys that are used in degrees
/// read the number as written.)
pub const UNITS: [Unit; 33] = {
    use Family::*;
    [
        unit("_nm", Length, 1e-9, "nm"),
        unit("_um", Length, 1e-6, "µm"),
        unit("_mm", Length, 1e-3, "mm"),
        unit("_cm", Length, 1e-2, "cm"),
        unit("_m", Length, 1.0, "m"),
        unit("_urad", Angle, 1e-6, "µrad"),
        unit("_mrad", Angle, 1e-3, "mrad"),
        unit("_deg", Angle, std::f64::consts::PI / 180.0, "°"),
        unit("_ns", Time, 1e-9, "ns"),
        unit("_us", Time, 1e-6, "µs"),
        unit("_ms", Time, 1e-3, "ms"),
        unit("_s", Time, 1.0, "s"),
        unit("_hz", Frequency, 1.0, "Hz"),
        unit("_khz", Frequency, 1e3, "kHz"),
        unit("_mhz", Frequency, 1e6, "MHz"),
        unit("_ghz", Frequency, 1e9, "GHz"),
        unit("_mm_per_s", Speed, 1e-3, "mm/s"),
        unit("_m_per_s", Speed, 1.0, "m/s"),
        unit("_mm_per_h", Speed, 1e-3 / 3600.0, "mm/h"),
        unit("_um2_per_s", Diffusivity, 1e-12, "µm²/s"),
        unit("_m2_per_s", Diffusivity, 1.0, "m²/s"),
        unit("_mpa_s", Viscosity, 1e-3, "mPa·s"),
        unit("_pa_s", Viscosity, 1.0, "Pa·s"),
        unit("_k", Temperature, 1.0, "K"),
        unit("_uj", Energy, 1e-6, "µJ"),
        unit("_mj", Energy, 1e-3, "mJ"),
        unit("_per_m", Attenuation, 1.0, "m⁻¹"),
        unit("_per_cm", Attenuation, 100.0, "cm⁻¹"),
        unit("_per_mm", Attenuation, 1000.0, "mm⁻¹"),
        unit("_per_m3", NumberDensity, 1.0, "m⁻³"),
        unit("_per_cm3", NumberDensity, 1e6, "cm⁻³"),
        unit("_rad_per_s", AngularSpeed, 1.0, "rad/s"),
        unit("_rpm", AngularSpeed, std::f64::consts::TAU / 60.0, "rpm"),
    ]
};

/// The quantity and unit of a key with a unit suffix (`thickness_mm` → `("thickness", mm)`).
pub fn split_key(key: &str) -> Option<(&str, &'static Unit)> {
    UNITS
        .iter()
        .filter_map(|u| key.strip_suffix(u.suffix).filter(|q| !q.is_empty()).map(|q| (q, u)))
        .max_by_key(|(_, u)| u.suffix.len())
}

/// Quantities that are alternatives to each other: giving one replaces the others on override.
const ALTERNATIVES: [&[&str]; 3] =
    [&["number_density", "volume_fraction"], &["diameter", "radius"], &["v_max", "mean"]];

/// The unit a key (or a dotted path ending in one) carries, for messages (`thickness_um` → "µm").
pub fn unit_of(path: &str) -> &'static str {
    split_key(path).map_or("", |(_, u)| u.printed)
}

/// The quantity a key names, without its unit (`sigma_s_per_mm` → `sigma_s`).
fn quantity_of(key: &str) -> &str {
    split_key(key).map_or(key, |(q, _)| q)
}

/// Whether two keys give the same quantity (in any unit, or as an alternative form).
pub fn same_quantity(a: &str, b: &str) -> bool {
    let (qa, qb) = (quantity_of(a), quantity_of(b));
    qa == qb || ALTERNATIVES.iter().any(|g| g.contains(&qa) && g.contains(&qb))
}

/// Insert `key = value` into `table`, removing any key that gives the same quantity in another
/// unit (an override of `sigma_s_per_mm` by `sigma_s_per_m` replaces it, rather than conflicting).
pub fn insert_replacing(table: &mut toml::Table, key: &str, value: toml::Value) {
    table.retain(|k, _| k == key || !same_quantity(k, key));
    table.insert(key.to_string(), value);
}

/// The suffixes one key accepts: a subset of one family of [`UNITS`], in the order messages list
/// them.
pub trait UnitSet {
    const FAMILY: Family;
    const SUFFIXES: &'static [&'static str];

    /// The keys of quantity `name` in these units (`thickness` → `thickness_um`, …).
    fn keys(name: &str) -> Vec<String> {
        Self::SUFFIXES.iter().map(|s| format!("{name}{s}")).collect()
    }
}

macro_rules! unit_sets {
    ($($(#[$doc:meta])* $name:ident: $family:ident = [$($suffix:literal),+];)*) => {$(
        $(#[$doc])*
        #[derive(Debug, Clone, Copy)]
        pub enum $name {}
        impl UnitSet for $name {
            const FAMILY: Family = Family::$family;
            const SUFFIXES: &'static [&'static str] = &[$($suffix),+];
        }
    )*};
}

unit_sets! {
    /// Most lengths: µm, mm or m.
    Length: Length = ["_um", "_mm", "_m"];
    /// Metres only (heights and ranges of an atmosphere).
    Metres: Length = ["_m"];
    /// A molecule's or small particle's radius.
    SmallRadius: Length = ["_um", "_nm"];
    Wavelength: Length = ["_nm", "_um"];
    /// A receiver's aperture.
    Aperture: Length = ["_mm", "_m"];
    /// A beam divergence.
    SmallAngle: Angle = ["_urad", "_mrad"];
    FieldOfView: Angle = ["_urad", "_mrad", "_deg"];
    /// Degrees only (pointing, wind direction, acceptance).
    Degrees: Angle = ["_deg"];
    ChirpDuration: Time = ["_s", "_ms", "_us"];
    PulseWidth: Time = ["_ns", "_us"];
    /// A detector's time axis (times of flight).
    TimeOfFlight: Time = ["_ns"];
    /// Correlation delays and exposure times.
    Delay: Time = ["_s", "_ms", "_us"];
    /// Frequencies of a detector's spectrum.
    Frequency: Frequency = ["_hz", "_khz", "_mhz", "_ghz"];
    /// Frequencies of a camera (frame rate, band, spectrum).
    CameraFrequency: Frequency = ["_hz", "_khz"];
    ChirpBandwidth: Frequency = ["_hz", "_mhz", "_ghz"];
    SampleRate: Frequency = ["_hz", "_mhz"];
    /// Flow speeds and velocities.
    Speed: Speed = ["_mm_per_s", "_m_per_s"];
    /// Wind speeds and velocities.
    MetresPerSecond: Speed = ["_m_per_s"];
    RainRate: Speed = ["_mm_per_h"];
    Diffusivity: Diffusivity = ["_m2_per_s", "_um2_per_s"];
    Viscosity: Viscosity = ["_mpa_s", "_pa_s"];
    Temperature: Temperature = ["_k"];
    PulseEnergy: Energy = ["_uj", "_mj"];
    Coefficient: Attenuation = ["_per_m", "_per_cm", "_per_mm"];
    NumberDensity: NumberDensity = ["_per_m3", "_per_cm3"];
    /// A surface's rotation.
    AngularSpeed: AngularSpeed = ["_rad_per_s", "_rpm"];
}

/// A quantity as given: the number(s) as written under `key` (as written, e.g. `thickness_mm`),
/// in `unit`, one of the units of `S`.
pub struct Quantity<S, V = f64> {
    pub value: V,
    pub key: String,
    pub unit: &'static Unit,
    set: PhantomData<S>,
}

impl<S, V: Clone> Clone for Quantity<S, V> {
    fn clone(&self) -> Self {
        Self { value: self.value.clone(), key: self.key.clone(), unit: self.unit, set: PhantomData }
    }
}

impl<S, V: fmt::Debug> fmt::Debug for Quantity<S, V> {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "{} = {:?}", self.key, self.value)
    }
}

impl<S> Quantity<S> {
    /// The value in SI units.
    pub fn si(&self) -> f64 {
        self.value * self.unit.factor
    }
}

impl<S, const N: usize> Quantity<S, [f64; N]> {
    /// The values in SI units.
    pub fn si(&self) -> [f64; N] {
        self.value.map(|x| x * self.unit.factor)
    }
}

/// The keys [`mark`] wraps a value and its key in.
const KEY: &str = "\u{0}key";
const VALUE: &str = "\u{0}value";

impl<'de, S: UnitSet, V: DeserializeOwned> Deserialize<'de> for Quantity<S, V> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let marked = toml::Table::deserialize(d)?;
        let (Some(toml::Value::String(key)), Some(value)) = (marked.get(KEY), marked.get(VALUE)) else {
            return Err(D::Error::custom("a quantity not marked by config::units::mark"));
        };
        let unit = split_key(key)
            .map(|(_, u)| u)
            .filter(|u| u.family == S::FAMILY && S::SUFFIXES.contains(&u.suffix))
            .ok_or_else(|| D::Error::custom(format!("`{key}`: expected a unit of {}", S::SUFFIXES.join(", "))))?;
        let value = V::deserialize(value.clone()).map_err(|e| D::Error::custom(e.message()))?;
        Ok(Self { value, key: key.clone(), unit, set: PhantomData })
    }
}

/// A table ready to deserialise, from [`mark`].
pub struct Marked {
    pub table: toml::Table,
    /// Quantities given under more than one key of a table: (the table's path, the keys in the
    /// order of [`UNITS`]).
    pub twice: Vec<(String, Vec<String>)>,
}

impl Marked {
    /// The message for serde's "duplicate field" error at `path` (a quantity given in two of the
    /// units its field accepts): "give only one of …" at the table's path.
    pub fn duplicate(&self, path: &str, message: &str) -> Option<ConfigError> {
        let field = message.strip_prefix("duplicate field `")?.strip_suffix('`')?;
        let (quantity, _) = split_key(field)?;
        let (at, keys) = self
            .twice
            .iter()
            .filter(|(at, keys)| {
                let within = path == at || path.strip_prefix(at.as_str()).is_some_and(|r| r.starts_with(['.', '[']));
                within && keys.iter().any(|k| split_key(k).is_some_and(|(q, _)| q == quantity))
            })
            .max_by_key(|(at, _)| at.len())?;
        let at = if at.is_empty() { "(top level)" } else { at };
        Some(ConfigError::new(at, format!("give only one of {}", keys.join(", "))))
    }
}

/// A copy of `doc` ready to deserialise: in every table of the schema, the value of each key
/// with a unit suffix is wrapped with the key as written, for [`Quantity`]. The names of media
/// and the keys of `[reference]` are names, not fields, and are left alone. Quantities given in
/// two units are noted (serde refuses them as duplicates if the field accepts both keys, and as
/// unknown keys otherwise).
pub fn mark(doc: &toml::Table) -> Marked {
    let mut table = doc.clone();
    let mut twice = Vec::new();
    for (key, value) in table.iter_mut() {
        match (key.as_str(), value) {
            ("reference", _) => {}
            ("media", toml::Value::Table(media)) => {
                for (name, medium) in media.iter_mut() {
                    mark_value(&format!("media.{name}"), medium, &mut twice);
                }
            }
            (_, value) => mark_value(key, value, &mut twice),
        }
    }
    mark_table("", &mut table, &mut twice);
    Marked { table, twice }
}

fn mark_value(path: &str, value: &mut toml::Value, twice: &mut Vec<(String, Vec<String>)>) {
    match value {
        toml::Value::Table(t) => {
            for (key, v) in t.iter_mut() {
                mark_value(&format!("{path}.{key}"), v, twice);
            }
            mark_table(path, t, twice);
        }
        toml::Value::Array(a) => {
            for (i, v) in a.iter_mut().enumerate() {
                mark_value(&format!("{path}[{i}]"), v, twice);
            }
        }
        _ => {}
    }
}

/// Wrap the suffixed keys of one table (its sub-tables are done), noting quantities given twice.
fn mark_table(path: &str, table: &mut toml::Table, twice: &mut Vec<(String, Vec<String>)>) {
    let suffixed: Vec<(String, String)> =
        table.keys().filter_map(|k| split_key(k).map(|(q, _)| (k.clone(), q.to_string()))).collect();
    for (i, (key, quantity)) in suffixed.iter().enumerate() {
        let same: Vec<&str> = suffixed.iter().filter(|(_, q)| q == quantity).map(|(k, _)| k.as_str()).collect();
        if same.len() > 1 && !suffixed[..i].iter().any(|(_, q)| q == quantity) {
            let mut keys: Vec<String> = same.iter().map(|k| k.to_string()).collect();
            keys.sort_by_key(|k| split_key(k).map(|(_, u)| UNITS.iter().position(|x| x == u)));
            twice.push((path.to_string(), keys));
        }
        let slot = table.get_mut(key).expect("a key of the table");
        let value = std::mem::replace(slot, toml::Value::Boolean(false));
        let mut wrapped = toml::Table::new();
        wrapped.insert(KEY.into(), toml::Value::String(key.clone()));
        wrapped.insert(VALUE.into(), value);
        *slot = toml::Value::Table(wrapped);
    }
}

/// A serde message listing the expected keys ("unknown field `x`, expected one of `a_um`, …") with
/// the keys of each quantity in the order of [`UNITS`] (serde lists a field's keys sorted by name).
pub fn order_expected_keys(message: &str) -> String {
    const AT: &str = "expected one of ";
    let Some(i) = message.find(AT).map(|i| i + AT.len()) else { return message.to_string() };
    let mut keys: Vec<&str> = message[i..].split(", ").collect();
    let quantity = |k: &str| split_key(k.trim_matches('`')).map(|(q, _)| q.to_string());
    let rank = |k: &str| split_key(k.trim_matches('`')).and_then(|(_, u)| UNITS.iter().position(|x| x == u));
    let mut start = 0;
    while start < keys.len() {
        let q = quantity(keys[start]);
        let end = start + keys[start..].iter().take_while(|k| q.is_some() && quantity(k) == q).count().max(1);
        keys[start..end].sort_by_key(|k| rank(k));
        start = end;
    }
    format!("{}{}", &message[..i], keys.join(", "))
}

/// A serde message in the words of the experiment file rather than of Rust: the integer and float
/// types named as what they mean (`expected u64` → `expected a whole number ≥ 0`), and for an
/// unknown key the nearest expected one suggested (`unknown field `sampels` (did you mean
/// `samples`?), expected one of …`) when it is within a third of its length in edits.
pub fn readable(message: &str) -> String {
    let mut m = message.to_string();
    for (rust, words) in [
        ("expected u64", "expected a whole number ≥ 0"),
        ("expected u32", "expected a whole number ≥ 0"),
        ("expected usize", "expected a whole number ≥ 0"),
        ("expected i64", "expected a whole number"),
        ("expected f64", "expected a number"),
    ] {
        if m.ends_with(rust) {
            m.replace_range(m.len() - rust.len().., words);
        }
    }
    const UNKNOWN: &str = "unknown field `";
    const AT: &str = "expected one of ";
    let given = m.strip_prefix(UNKNOWN).and_then(|u| u.split('`').next()).unwrap_or("").to_string();
    // (A key of hundreds of characters is no typo of a key.)
    if let Some(e) = m.find(AT)
        && !given.is_empty()
        && given.len() <= 64
    {
        let nearest = m[e + AT.len()..]
            .split(", ")
            .map(|k| k.trim_matches('`'))
            .map(|k| (edit_distance(&given, k), k))
            .min_by_key(|&(d, _)| d);
        if let Some((d, k)) = nearest
            && d > 0
            && 3 * d <= given.chars().count().max(3)
        {
            let suggestion = format!(" (did you mean `{k}`?)");
            m.insert_str(UNKNOWN.len() + given.len() + 1, &suggestion);
        }
    }
    m
}

/// The Levenshtein distance of two keys (insertions, deletions and substitutions of characters).
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let next = (row[j + 1] + 1).min(row[j] + 1).min(diagonal + usize::from(ca != cb));
            diagonal = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_speak_the_files_words_and_suggest_the_nearest_key() {
        assert_eq!(
            readable("invalid type: floating point `2.5`, expected u64"),
            "invalid type: floating point `2.5`, expected a whole number ≥ 0"
        );
        assert_eq!(
            readable("invalid type: string \"a\", expected f64"),
            "invalid type: string \"a\", expected a number"
        );
        assert_eq!(
            readable("unknown field `sampels`, expected one of `samples`, `seed`, `batches`"),
            "unknown field `sampels` (did you mean `samples`?), expected one of `samples`, `seed`, `batches`"
        );
        assert_eq!(
            readable("unknown field `thickness_nm`, expected one of `name`, `thickness_um`, `thickness_mm`"),
            "unknown field `thickness_nm` (did you mean `thickness_um`?), expected one of `name`, `thickness_um`, `thickness_mm`"
        );
        // Nothing near: no suggestion.
        assert_eq!(
            readable("unknown field `zz`, expected one of `samples`"),
            "unknown field `zz`, expected one of `samples`"
        );
        assert_eq!(edit_distance("kitten", "sitting"), 3);
    }

    #[test]
    fn units_and_quantities() {
        assert_eq!(unit_of("media.blood.v_max_mm_per_s"), "mm/s");
        assert_eq!(unit_of("thickness_m"), "m");
        assert_eq!(unit_of("duration_s"), "s");
        assert_eq!(unit_of("n"), "");
        assert!(same_quantity("sigma_s_per_mm", "sigma_s_per_m"));
        assert!(!same_quantity("sigma_s_per_mm", "sigma_a_per_mm"));
        assert!(same_quantity("volume_fraction", "number_density_per_cm3"));
        assert!(same_quantity("radius_um", "diameter_mm"));
        assert!(!same_quantity("min_radius_um", "radius_um"));
        assert!(same_quantity("wavelength_nm", "wavelength_um"));
    }

    fn unit_named(suffix: &str) -> &'static Unit {
        UNITS.iter().find(|u| u.suffix == suffix).expect("a unit set names a suffix of UNITS")
    }

    #[test]
    fn unit_sets_name_units_of_their_family() {
        fn check<S: UnitSet>() {
            for s in S::SUFFIXES {
                assert_eq!(unit_named(s).family, S::FAMILY, "{s}");
            }
        }
        check::<Length>();
        check::<Metres>();
        check::<SmallRadius>();
        check::<Wavelength>();
        check::<Aperture>();
        check::<SmallAngle>();
        check::<FieldOfView>();
        check::<Degrees>();
        check::<ChirpDuration>();
        check::<PulseWidth>();
        check::<TimeOfFlight>();
        check::<Delay>();
        check::<Frequency>();
        check::<CameraFrequency>();
        check::<ChirpBandwidth>();
        check::<SampleRate>();
        check::<Speed>();
        check::<MetresPerSecond>();
        check::<RainRate>();
        check::<Diffusivity>();
        check::<Viscosity>();
        check::<Temperature>();
        check::<PulseEnergy>();
        check::<Coefficient>();
        check::<NumberDensity>();
    }

    #[test]
    fn expected_keys_in_unit_order() {
        let m = "unknown field `x`, expected one of `axis`, `from_m`, `from_mm`, `from_um`, `sigma_a_per_cm`, \
                 `sigma_a_per_m`, `sigma_a_per_mm`, `majorant`";
        assert_eq!(
            order_expected_keys(m),
            "unknown field `x`, expected one of `axis`, `from_um`, `from_mm`, `from_m`, `sigma_a_per_m`, \
             `sigma_a_per_cm`, `sigma_a_per_mm`, `majorant`"
        );
        assert_eq!(order_expected_keys("missing field `n`"), "missing field `n`");
    }

    #[test]
    fn marking_wraps_suffixed_keys_and_notes_two_units() {
        let doc: toml::Table = r#"
            [source]
            wavelength_nm = 633
            [media.tissue_mm]
            sigma_s_per_mm = 10
            [reference]
            "a_m" = 1
        "#
        .parse()
        .unwrap();
        let m = mark(&doc);
        assert!(m.twice.is_empty());
        let m = m.table;
        assert_eq!(m["source"]["wavelength_nm"][KEY].as_str(), Some("wavelength_nm"));
        assert_eq!(m["source"]["wavelength_nm"][VALUE].as_integer(), Some(633));
        assert!(m["media"]["tissue_mm"]["sigma_s_per_mm"].is_table());
        assert_eq!(m["reference"]["a_m"].as_integer(), Some(1));
        let q: Quantity<Wavelength> = m["source"]["wavelength_nm"].clone().try_into().unwrap();
        assert_eq!((q.si(), q.key.as_str()), (633.0 * 1e-9, "wavelength_nm"));

        let two: toml::Table = "[[layers]]\nthickness_mm = 1\nthickness_um = 2\n".parse().unwrap();
        let m = mark(&two);
        assert_eq!(m.twice, [("layers[0]".to_string(), vec!["thickness_um".to_string(), "thickness_mm".to_string()])]);
        let e = m.duplicate("layers[0]", "duplicate field `thickness_um`").unwrap();
        assert_eq!(e.to_string(), "layers[0]: give only one of thickness_um, thickness_mm");
        assert!(m.duplicate("layers[0]", "duplicate field `n`").is_none());
    }
}
