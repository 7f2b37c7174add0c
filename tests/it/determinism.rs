//! Determinism: the same seed gives identical numbers and identical files for any thread count.

use ohd::io::write::manifest::{Invocation, write_run};

#[test]
#[ignore = "deep tier (tens of seconds to minutes): bash .ci/deep"]
fn one_and_two_threads_write_identical_outputs() {
    for (name, text) in [
        ("default", ohd::DEFAULT_CONFIG),
        ("vdh", include_str!("../../validation/vdh_slab.toml")),
        // Delta tracking over majorant segments and ratio-tracked shadow rays.
        ("density_ramp", include_str!("../configs/good/density_ramp.toml")),
        // Camera paths, pixel by pixel, besides the forward ones.
        ("camera", include_str!("../configs/good/camera_estimator.toml")),
        // Camera paths from the footprints' pixels, the forward paths elsewhere.
        ("footprints", include_str!("../configs/good/footprints_estimator.toml")),
        // ... connected to the layered twin's light field below the vessel (its table's pre-pass
        // in parallel groups summed in order).
        ("light_field", include_str!("../configs/good/footprints_light_field.toml")),
        // Pulsatile flows: the paths' harmonics, an acquisition's windows over the cycle and the
        // per-batch stream of its broadened lines' slots.
        ("pulsatile", include_str!("../configs/good/pulsatile_vessel.toml")),
    ] {
        let dirs: Vec<tempfile::TempDir> = (0..2).map(|_| tempfile::tempdir().unwrap()).collect();
        let mut manifests = Vec::new();
        for (threads, dir) in [1, 2].iter().zip(&dirs) {
            let sets = ["run.samples=120000".to_string(), format!("run.threads={threads}")];
            let (table, exp) = ohd::config::load(text, name, &sets).unwrap();
            let out = exp.run(&ohd::experiment::Silent);
            assert_eq!(out.threads, *threads);
            manifests.push(write_run(dir.path(), &exp, &out, &table, &Invocation::default()).unwrap().json());
        }
        assert_eq!(manifests[0]["estimates"], manifests[1]["estimates"], "{name}: estimates differ");
        assert_eq!(
            manifests[0]["run_statistics"]["scattering_events"],
            manifests[1]["run_statistics"]["scattering_events"]
        );
        assert_eq!(
            manifests[0]["run_statistics"]["null_collisions"],
            manifests[1]["run_statistics"]["null_collisions"]
        );
        let files = manifests[0]["files"].as_array().unwrap();
        for f in files {
            let f = f.as_str().unwrap();
            let a = std::fs::read(dirs[0].path().join(f)).unwrap();
            let b = std::fs::read(dirs[1].path().join(f)).unwrap();
            assert!(a == b, "{name}: {f} differs between 1 and 2 threads");
        }
        // A different seed really changes the numbers (the check above is not vacuous).
        let (_, exp) = ohd::config::load(text, name, &["run.samples=120000".into(), "run.seed=99".into()]).unwrap();
        let other = exp.run(&ohd::experiment::Silent);
        assert_ne!(
            other.estimates.mean()[1],
            manifests[0]["estimates"]["reflectance_diffuse"]["value"].as_f64().unwrap()
        );
    }
}

#[test]
fn a_path_replays_from_its_batch_and_index() {
    // Streams are a pure function of (seed, purpose, batch, sample): rebuilding one gives the
    // same numbers, independent of anything run before.
    use ohd::sampling::{PathRng, Purpose};
    let draw = |b, i| {
        let mut r = PathRng::new(42, Purpose::Path, b, i);
        [r.uniform(), r.uniform(), r.uniform()]
    };
    let first = draw(3, 17);
    for b in 0..5 {
        for i in 0..50 {
            let _ = draw(b, i);
        }
    }
    assert_eq!(first, draw(3, 17));
    assert_ne!(first, draw(17, 3));
}
