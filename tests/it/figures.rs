//! Figures (issue 22): every output of the shipped camera, LDH and FMCW configurations gets a
//! PNG with an SVG beside it, each listed in the manifest and valid; `--no-figures` writes none.

use std::path::Path;

use ohd::run::{Loaded, RunRequest, Unobserved, run};

use crate::support::files::png_size;

fn repo(p: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// Run `config` (a few paths) into `dir`; the manifest's file list.
fn run_into(config: &str, dir: &Path, no_figures: bool, sets: &[&str]) -> Vec<String> {
    let mut sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    sets.push("run.samples=4000".into());
    let loaded = Loaded::read(Some(&repo(config)), &sets).expect("config loads");
    let req = RunRequest { dir: dir.to_path_buf(), no_figures, ..Default::default() };
    run(&loaded, &req, &Unobserved).expect("run written");
    let m: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap();
    m["files"].as_array().unwrap().iter().map(|f| f.as_str().unwrap().to_string()).collect()
}

#[test]
fn every_figure_is_listed_valid_and_has_its_svg() {
    let cases: [(&str, &[&str], &[&str]); 3] = [
        (
            "configs/default.toml",
            &[],
            &["camera_image", "camera_spectrum", "camera_spectrum_by_order", "camera_spectrum_by_doppler_events"],
        ),
        (
            "configs/retina_ldh.toml",
            &["detectors.0.image.pixels=[32, 32]"],
            &[
                "camera_m0_plus",
                "camera_m0_minus",
                "camera_m0_directional",
                "camera_m0_plus_static",
                "camera_m0_minus_multiple_doppler",
                "camera_roi_artery_spectrum",
                "camera_roi_vein_spectrum",
            ],
        ),
        ("configs/fmcw_target.toml", &[], &["receiver_spectra"]),
    ];
    for (config, sets, expected) in cases {
        let tmp = tempfile::tempdir().unwrap();
        let files = run_into(config, tmp.path(), false, sets);
        for stem in expected {
            for ext in ["png", "svg"] {
                let f = format!("{stem}.{ext}");
                assert!(files.contains(&f), "{config}: {f} not in the manifest: {files:?}");
            }
        }
        let pngs: Vec<&String> = files.iter().filter(|f| f.ends_with(".png")).collect();
        assert!(pngs.len() >= expected.len());
        for f in pngs {
            let (w, h) = png_size(&tmp.path().join(f));
            assert!((600..=2000).contains(&w) && (500..=700).contains(&h), "{config}: {f} is {w}×{h}");
            let svg = f.replace(".png", ".svg");
            assert!(files.contains(&svg), "{config}: {svg} missing");
            let text = std::fs::read_to_string(tmp.path().join(&svg)).unwrap();
            assert!(text.starts_with("<svg") && text.trim_end().ends_with("</svg>"), "{config}: {svg}");
            assert!(text.contains(&format!("width=\"{w}\"")), "{config}: {svg} has another size than its PNG");
        }
        // Every listed file exists, and only listed files and the manifest are there.
        let mut present: Vec<String> =
            std::fs::read_dir(tmp.path()).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
        present.retain(|f| f != "manifest.json");
        present.sort();
        let mut listed = files.clone();
        listed.sort();
        // (A file written twice, e.g. the STFT axis once per ROI, is listed twice.)
        listed.dedup();
        assert_eq!(present, listed, "{config}");
    }
}

#[test]
fn no_figures_writes_no_png_or_svg() {
    for (config, sets) in
        [("configs/default.toml", &[][..]), ("configs/retina_ldh.toml", &["detectors.0.image.pixels=[16, 16]"][..])]
    {
        let tmp = tempfile::tempdir().unwrap();
        let files = run_into(config, tmp.path(), true, sets);
        let drawn: Vec<String> = std::fs::read_dir(tmp.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .filter(|f| f.ends_with(".png") || f.ends_with(".svg"))
            .collect();
        assert!(drawn.is_empty(), "{config}: {drawn:?}");
        assert!(files.iter().any(|f| f.ends_with(".npy")) && !files.iter().any(|f| f.ends_with(".png")));
    }
}

/// A lidar's figures name the detector and where it points (issue 37: a scan's four pointings
/// drew four figures that could not be told apart), in the title; the vertical stare names its
/// elevation only.
#[test]
fn lidar_figures_name_the_detector_and_the_pointing() {
    for (sets, says) in [
        (vec!["source.pointings_deg=[[90, 60]]"], "lidar, azimuth 90°, elevation 60°"),
        (vec!["source.pointings_deg=[[0, 90]]"], "lidar, elevation 90°"),
    ] {
        let tmp = tempfile::tempdir().unwrap();
        let mut sets = sets.clone();
        sets.extend(["detectors.0.lidar.gates=6", "detectors.0.lidar.fft_points=256"]);
        run_into("configs/wind_sunny.toml", tmp.path(), false, &sets);
        for fig in ["lidar_range_doppler.svg", "lidar_gate_spectra.svg"] {
            let svg = std::fs::read_to_string(tmp.path().join(fig)).unwrap();
            assert!(svg.contains(says), "{fig}: no `{says}` in its text");
        }
        let spectra = std::fs::read_to_string(tmp.path().join("lidar_gate_spectra.svg")).unwrap();
        // In its unit (`100 µJ`), not programmer notation (`1.000e-4 J`).
        let energy = spectra
            .split("pulse energy ")
            .find(|t| t.starts_with(|c: char| c.is_ascii_digit()))
            .and_then(|t| t.split(',').next())
            .unwrap_or("?");
        assert!(energy.ends_with('J') && !energy.contains('e'), "pulse energy `{energy}`");
    }
}
