//! The unit suffixes config keys may carry (`thickness_um`, `sigma_s_per_cm`), in one place: for
//! messages ("µm") and for overrides, which replace a quantity given in another unit.

/// `(suffix, unit as printed)`, longest suffix first so that `_mm_per_s` is not read as `_s`.
const UNITS: [(&str, &str); 31] = [
    ("_um2_per_s", "µm²/s"),
    ("_m2_per_s", "m²/s"),
    ("_mpa_s", "mPa·s"),
    ("_pa_s", "Pa·s"),
    ("_mm_per_s", "mm/s"),
    ("_mm_per_h", "mm/h"),
    ("_m_per_s", "m/s"),
    ("_per_cm3", "cm⁻³"),
    ("_per_m3", "m⁻³"),
    ("_per_mm", "mm⁻¹"),
    ("_per_cm", "cm⁻¹"),
    ("_per_m", "m⁻¹"),
    ("_ghz", "GHz"),
    ("_mhz", "MHz"),
    ("_khz", "kHz"),
    ("_deg", "°"),
    ("_urad", "µrad"),
    ("_mrad", "mrad"),
    ("_k", "K"),
    ("_hz", "Hz"),
    ("_um", "µm"),
    ("_nm", "nm"),
    ("_mm", "mm"),
    ("_cm", "cm"),
    ("_us", "µs"),
    ("_ns", "ns"),
    ("_ms", "ms"),
    ("_uj", "µJ"),
    ("_mj", "mJ"),
    ("_m", "m"),
    ("_s", "s"),
];

/// Quantities that are alternatives to each other: giving one replaces the others on override.
const ALTERNATIVES: [&[&str]; 3] =
    [&["number_density", "volume_fraction"], &["diameter", "radius"], &["v_max", "mean"]];

/// The unit a key (or a dotted path ending in one) carries, for messages (`thickness_um` → "µm").
pub fn unit_of(path: &str) -> &'static str {
    UNITS.iter().find(|(s, _)| path.ends_with(s)).map_or("", |(_, u)| u)
}

/// The quantity a key names, without its unit (`sigma_s_per_mm` → `sigma_s`).
fn quantity_of(key: &str) -> &str {
    UNITS.iter().find_map(|(s, _)| key.strip_suffix(s).filter(|q| !q.is_empty())).unwrap_or(key)
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
