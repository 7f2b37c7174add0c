//! Media presets: named media with cited optical properties, shipped as `media/presets/*.toml` and
//! compiled into the binary (so `preset = "whole_blood_785"` works from any directory).
//!
//! A preset file holds `description`, `references` and a `[medium]` table in the schema of
//! `[media.NAME]`. A config medium with `preset = "…"` is that table with the config's own keys
//! merged over it: a key given in another unit replaces the preset's (`sigma_s_per_m` replaces
//! `sigma_s_per_mm`), tables merge key by key, a table with a different `type` replaces the
//! preset's, and in an array of tables (`particles`) elements merge by index, so
//! `particles = [{ volume_fraction = 0.40 }]` or `--set media.blood.particles.0.volume_fraction=0.4`
//! changes one field of the first component.

use crate::error::ConfigError;

use super::units::insert_replacing;

/// Every shipped preset: `(name, file text)`. A test checks this list against `media/presets/`.
pub const PRESETS: &[(&str, &str)] = &[
    ("whole_blood_785", include_str!("../../media/presets/whole_blood_785.toml")),
    ("whole_blood_800", include_str!("../../media/presets/whole_blood_800.toml")),
    ("retina_inner_785", include_str!("../../media/presets/retina_inner_785.toml")),
    ("retina_outer_785", include_str!("../../media/presets/retina_outer_785.toml")),
    ("rpe_785", include_str!("../../media/presets/rpe_785.toml")),
    ("choroid_785", include_str!("../../media/presets/choroid_785.toml")),
    ("sclera_785", include_str!("../../media/presets/sclera_785.toml")),
    ("continental_aerosol_1550", include_str!("../../media/presets/continental_aerosol_1550.toml")),
    ("maritime_aerosol_1550", include_str!("../../media/presets/maritime_aerosol_1550.toml")),
    ("rain_mp_1550", include_str!("../../media/presets/rain_mp_1550.toml")),
    ("fog_1550", include_str!("../../media/presets/fog_1550.toml")),
    ("cloud_c1_1550", include_str!("../../media/presets/cloud_c1_1550.toml")),
];

/// The names of the shipped presets.
pub fn names() -> Vec<&'static str> {
    PRESETS.iter().map(|p| p.0).collect()
}

/// The `[medium]` table of a preset, with its `description` and `references` copied into it (so
/// the configuration as run records them).
pub fn medium_table(name: &str) -> Result<toml::Table, String> {
    let (_, text) = PRESETS
        .iter()
        .find(|p| p.0 == name)
        .ok_or_else(|| format!("= \"{name}\": no such preset; the shipped presets are {}", names().join(", ")))?;
    let mut doc: toml::Table =
        text.parse().map_err(|e: toml::de::Error| format!("preset \"{name}\" is not valid TOML: {}", e.message()))?;
    let mut medium = match doc.remove("medium") {
        Some(toml::Value::Table(t)) => t,
        _ => return Err(format!("preset \"{name}\" has no [medium] table")),
    };
    for key in ["description", "references"] {
        if let Some(v) = doc.remove(key) {
            medium.insert(key.to_string(), v);
        }
    }
    medium.insert("preset".into(), toml::Value::String(name.to_string()));
    Ok(medium)
}

/// Replace every `[media.NAME]` that names a `preset` by the preset merged with its own keys.
pub fn expand(doc: &mut toml::Table) -> Result<(), ConfigError> {
    let Some(toml::Value::Table(media)) = doc.get_mut("media") else { return Ok(()) };
    for (name, medium) in media.iter_mut() {
        let toml::Value::Table(own) = medium else { continue };
        let Some(preset) = own.get("preset") else { continue };
        let path = format!("media.{name}.preset");
        let preset = preset
            .as_str()
            .ok_or_else(|| ConfigError::new(&path, format!("= {preset}: expected a preset name (a string)")))?;
        let mut merged = medium_table(preset).map_err(|m| ConfigError::new(&path, m))?;
        let own = std::mem::take(own);
        merge(&mut merged, own);
        *medium = toml::Value::Table(merged);
    }
    Ok(())
}

/// Merge `over` into `base` (see the module docs for the rules).
pub fn merge(base: &mut toml::Table, over: toml::Table) {
    for (key, value) in over {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o))
                if b.get("type") == o.get("type") || !o.contains_key("type") =>
            {
                merge(b, o)
            }
            (Some(toml::Value::Array(b)), toml::Value::Table(o)) if o.keys().all(|k| k.parse::<usize>().is_ok()) => {
                merge_elements(b, o.into_iter().map(|(i, v)| (i.parse().expect("checked numeric"), v)))
            }
            (Some(toml::Value::Array(b)), toml::Value::Array(o)) if is_array_of_tables(b) && is_array_of_tables(&o) => {
                merge_elements(b, o.into_iter().enumerate())
            }
            (_, value) => insert_replacing(base, &key, value),
        }
    }
}

/// Merge `(index, value)` overrides into an array: tables merge, other values replace, indices past
/// the end append.
fn merge_elements(base: &mut Vec<toml::Value>, over: impl Iterator<Item = (usize, toml::Value)>) {
    for (i, v) in over {
        match (base.get_mut(i), v) {
            (Some(toml::Value::Table(bt)), toml::Value::Table(ot)) => merge(bt, ot),
            (Some(slot), v) => *slot = v,
            (None, v) => base.push(v),
        }
    }
}

fn is_array_of_tables(a: &[toml::Value]) -> bool {
    a.iter().all(|v| v.is_table())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(s: &str) -> toml::Table {
        s.parse().unwrap()
    }

    #[test]
    fn merge_rules() {
        let mut base = t(r#"
            sigma_s_per_mm = 75
            sigma_a_per_mm = 0.4
            phase = { type = "hg", g = 0.98 }
            particles = [{ n_particle = 1.4, volume_fraction = 0.45, size = { type = "monodisperse", diameter_um = 5 } }, { n_particle = 1.5 }]
        "#);
        merge(
            &mut base,
            t(r#"
            sigma_s_per_m = 2e4
            phase = { type = "mie" }
            particles = [{ number_density_per_cm3 = 5e6, size = { radius_um = 2 } }]
        "#),
        );
        assert_eq!(base.get("sigma_s_per_mm"), None);
        assert_eq!(base["sigma_s_per_m"].as_float(), Some(2e4));
        assert_eq!(base["sigma_a_per_mm"].as_float(), Some(0.4));
        assert_eq!(base["phase"], toml::Value::Table(t(r#"type = "mie""#)));
        let p = base["particles"].as_array().unwrap();
        assert_eq!(p.len(), 2);
        let p0 = p[0].as_table().unwrap();
        assert_eq!(p0.get("volume_fraction"), None);
        assert_eq!(p0["number_density_per_cm3"].as_float(), Some(5e6));
        assert_eq!(p0["size"].as_table().unwrap().get("diameter_um"), None);
        assert_eq!(p0["size"]["type"].as_str(), Some("monodisperse"));

        // `--set media.x.particles.1.n_particle=1.6` arrives as a table with numeric keys.
        merge(&mut base, t(r#"particles = { 1 = { n_particle = 1.6 } }"#));
        assert_eq!(base["particles"][1]["n_particle"].as_float(), Some(1.6));
    }

    #[test]
    fn every_preset_parses_and_unknown_names_are_listed() {
        for name in names() {
            let m = medium_table(name).unwrap_or_else(|e| panic!("{e}"));
            assert!(m.contains_key("description") && m.contains_key("references"), "{name}");
        }
        let e = medium_table("blood").unwrap_err();
        assert!(e.contains("no such preset") && e.contains("whole_blood_785"), "{e}");
    }
}
