//! The integration tests, one binary (one link of the library instead of one per file). Each
//! module is one subject; [`support`] holds the statistics harness and the run and lidar helpers
//! they share. Configurations and fixtures stay in `tests/configs`, `tests/data` and
//! `tests/fixtures`. Run one subject with `cargo test --test it slab::` (a name filter).

mod support;

mod atmosphere;
mod bsdf_chi2;
mod camera;
mod cli;
mod config_fixtures;
mod control_variate;
mod converge;
mod determinism;
mod doppler;
mod estimators;
mod figures;
mod fmcw;
mod grid;
mod hostile;
mod importance;
mod lateral;
mod ldh;
mod lidar;
mod mie;
mod npy_volume;
mod outputs;
mod peers;
mod phase_table;
mod pixel_speckle;
mod precision;
mod presets;
mod pulsatile;
mod reflections;
mod reliability;
mod retrieval;
mod sampling;
mod slab;
mod speckle;
mod stiff;
mod surface;
mod tcorr;
mod time_gate;
mod vdb;
mod vdb_media;
mod volume;

/// Every `.rs` file here is a module of this binary: a file not named above would compile into
/// nothing and its tests would silently not run.
#[test]
fn every_test_file_is_a_module() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/it");
    let main = std::fs::read_to_string(dir.join("main.rs")).unwrap();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_stem().unwrap().to_str().unwrap().to_owned();
        if path.extension().is_some_and(|e| e == "rs") && name != "main" {
            assert!(
                main.contains(&format!("\nmod {name};\n")),
                "tests/it/{name}.rs is not declared in tests/it/main.rs"
            );
        }
    }
}
