//! Media presets: every shipped file is registered and resolves at its wavelength; the Mie-based
//! presets reproduce the bulk optics of `media/references.md` (values derived
//! there with miepython, so the tolerances allow for quadrature and truncation choices we cannot
//! see); hematocrit overrides scale blood as the model says.

use ohd::medium::Medium;

fn resolve(preset: &str, wavelength_nm: f64, extra: &str) -> Medium {
    let text = format!(
        "schema_version = 1\n[source]\nwavelength_nm = {wavelength_nm}\n[media.m]\npreset = \"{preset}\"\n{extra}\n\
         [[layers]]\nthickness_m = 1\nn = 1.0\nmedium = \"m\"\n"
    );
    let (_, exp) = ohd::config::load(&text, preset, &[]).unwrap_or_else(|e| panic!("{preset}: {e}"));
    exp.scene.media[0].clone()
}

fn within(what: &str, got: f64, want: f64, rel: f64) {
    assert!((got / want - 1.0).abs() <= rel, "{what}: {got} vs {want} (±{:.0} %)", rel * 100.0);
}

#[test]
fn every_preset_file_is_registered_and_resolves() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("media/presets");
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    files.sort();
    let mut names: Vec<String> = ohd::config::preset::names().iter().map(|s| s.to_string()).collect();
    names.sort();
    assert_eq!(files, names, "media/presets/*.toml and config::preset::PRESETS differ");
    for name in names {
        let wl = name.rsplit('_').next().unwrap().parse::<f64>().unwrap();
        let m = resolve(&name, wl, "");
        assert!(m.sigma_s() > 0.0 && m.sigma_a() > 0.0, "{name}");
        assert!(m.info.preset.as_deref() == Some(name.as_str()));
    }
}

#[test]
fn aerosol_and_rain_presets_match_the_derived_bulk_optics() {
    // (preset, extinction /km, albedo, g, lidar ratio sr) from media/references.md §B2, §B4.
    for (name, ext, albedo, g, s, tol) in [
        ("continental_aerosol_1550", 0.0151, 0.82, 0.63, 52.0, 0.05),
        ("maritime_aerosol_1550", 0.075, 0.99, 0.79, 66.0, 0.10),
        ("rain_mp_1550", 1.01, 0.73, 0.93, 510.0, 0.05),
    ] {
        let m = resolve(name, 1550.0, "");
        let p = m.info.particles.as_ref().expect("Mie optics");
        within(&format!("{name} extinction"), m.sigma_t() * 1e3, ext, tol);
        assert!((m.albedo() - albedo).abs() <= 0.015, "{name} albedo {} vs {albedo}", m.albedo());
        assert!((p.g - g).abs() <= 0.015, "{name} g {} vs {g}", p.g);
        within(&format!("{name} lidar ratio"), p.lidar_ratio, s, 0.15);
        // The tabulated phase function samples with the exact Mie g up to the table's resolution.
        assert!((m.info.g - p.g).abs() < 5e-3, "{name}: table g {} vs Mie g {}", m.info.g, p.g);
    }
}

#[test]
fn whole_blood_scales_with_hematocrit() {
    let h45 = resolve("whole_blood_785", 785.0, "");
    // Calibrated to the measured ≈ 75 mm⁻¹ (Friebel); absorption close to 0.45 × the Hb value.
    within("blood σs", h45.sigma_s() * 1e-3, 75.0, 0.02);
    within("blood σa", h45.sigma_a() * 1e-3, 0.40, 0.10);
    assert!(h45.info.g > 0.99 && h45.info.g < 0.995, "blood g {}", h45.info.g);
    let h40 = resolve("whole_blood_785", 785.0, "particles = { volume_fraction = 0.40 }");
    // Same cells: σs ∝ H (1 − H)(1.4 − H) (number of cells × Twersky), σa ∝ H.
    let twersky = |h: f64| h * (1.0 - h) * (1.4 - h);
    within("σs(0.40)/σs(0.45)", h40.sigma_s() / h45.sigma_s(), twersky(0.40) / twersky(0.45), 1e-12);
    within("σa(0.40)/σa(0.45)", h40.sigma_a() / h45.sigma_a(), 0.40 / 0.45, 1e-12);
    // An explicit coefficient in another unit replaces the preset's.
    let thin = resolve("whole_blood_785", 785.0, "sigma_s_per_cm = 200\nsigma_s_scale = 1");
    within("explicit σs", thin.sigma_s(), 2e4, 1e-12);
}
