//! The classes of hostile input that issue 52's campaign found failing in what was added after
//! the output-directory work: surfaces at their extremes (tiny roughness, conductor indices,
//! speeds at and beyond c, the metal tables' ends), NumPy volumes (over the memory budget,
//! corrupted, lying headers), the cost of pilots and of deterministic reflections through many
//! interfaces, and `ohd converge --reference` with a non-finite value. Each case is judged by the
//! oracle as every hostile case is, and an accepted run of these classes must also have counted
//! no non-finite detection (the campaign's runs dropped thousands with exit 0 and a warning).
//!
//! The quick test (`issue_52_findings`, the default suite) is the campaign's findings, one case
//! each; the deep sweep (`--ignored`) runs every surface key of the shipped surface experiments at
//! every extreme value, corrupted and lying `.npy` volumes, and the pilots' and interfaces' cost
//! ladders. The output-directory findings (nested and unlocked outputs, the lock's name) are
//! tests of `safety.rs`; the Python package's are in `tests/python/test_api.py`.

use std::path::Path;

use super::mutate::{Corruption, Draw, Seg, dotted, nodes};
use super::oracle::{Case, Names, Tally};
use super::{Depth, RUN_LIMIT, inputs_root, path_str, repo, seed, stream, tiny, tiny_run};

/// The shipped experiments with surfaces: rough faces, `[bottom]`, `[[opaque]]`.
const SURFACE_CONFIGS: &[&str] = &[
    "configs/fmcw_copper_treadmill.toml",
    "tests/configs/good/bottom_surface.toml",
    "tests/configs/good/camera_surfaces.toml",
    "tests/configs/good/opaque_rough.toml",
];

/// Extreme numbers for a surface's keys: tiny roughness down to the smallest double, indices
/// and speeds up to the largest, and the non-finite ones (which must be refused).
const EXTREMES: &[&str] = &[
    "0", "5e-324", "1e-300", "1e-160", "1e-100", "1e-20", "1e-9", "1e-5", "1", "2", "1e155", "1e300", "1.7e308", "-1",
    "-1e308", "nan", "inf", "-inf",
];

/// Whether a key path is a surface's parameter: a layer's roughness, anything of `[bottom]` or
/// of an `[[opaque]]` solid.
fn surface_key(path: &[Seg]) -> bool {
    match path {
        [Seg::Key(k), ..] if k == "bottom" || k == "opaque" => true,
        [Seg::Key(l), Seg::Index(_), Seg::Key(r)] => l == "layers" && r == "roughness",
        _ => false,
    }
}

/// The numeric leaves (numbers, and each number of a short array) of `doc` that are surface
/// parameters, as `--set` paths.
fn surface_numbers(doc: &toml::Table) -> Vec<String> {
    nodes(doc)
        .into_iter()
        .filter(|(p, v)| surface_key(p) && (v.is_float() || v.is_integer()))
        .map(|(p, _)| dotted(&p))
        .collect()
}

/// A tiny run of the shipped experiment `config` with `sets`, judged; an accepted run must have
/// counted no non-finite detection.
#[allow(clippy::too_many_arguments)]
fn judge_run(
    tally: &mut Tally,
    id: String,
    config: &Path,
    sets: &[String],
    cwd: &Path,
    out: &Path,
    must_refuse: Option<&str>,
    key: Option<String>,
) {
    let doc: toml::Table = std::fs::read_to_string(config).unwrap().parse().unwrap();
    let mut args = tiny_run(config, out);
    // A scan of many pointings (the FMCW treadmill's 56) is cut to its first and last: the
    // surfaces are the same at every pointing.
    let mut base = tiny(&doc);
    let pointings = doc.get("source").and_then(|s| s.get("pointings_deg")).and_then(|p| p.as_array());
    if let Some(p) = pointings.filter(|p| p.len() > 2) {
        base.push(format!("source.pointings_deg=[{}, {}]", p[0], p[p.len() - 1]));
    }
    for set in base.iter().chain(sets) {
        args.extend(["--set".to_string(), set.clone()]);
    }
    let name = config.file_name().unwrap().to_string_lossy().into_owned();
    let mut case =
        Case::new(id, format!("{name}: {}", sets.join("; ")), args, cwd, RUN_LIMIT, Names::config(None, &[&name]));
    case.out = Some(out.to_path_buf());
    case.watched.push(out.to_path_buf());
    case.must_refuse = must_refuse.map(String::from);
    case.key = key;
    case.finite_detections = true;
    tally.run(case);
    let _ = std::fs::remove_dir_all(out);
}

/// Every surface number of every shipped surface experiment at every extreme value (deep), or
/// every `stride`-th of those cases (quick), through a tiny run; the camera experiment also with
/// the forward estimator and the forward ones with the camera's where they allow it.
fn surface_extremes(depth: Depth, stride: usize) {
    let category = format!("surfaces-{}", depth.name());
    let scratch = tempfile::tempdir().unwrap();
    let cwd = scratch.path().join("cwd");
    std::fs::create_dir(&cwd).unwrap();
    let out = scratch.path().join("out");
    let mut tally = Tally::default();
    let mut k = 0usize;
    for rel in SURFACE_CONFIGS {
        let config = repo().join(rel);
        let doc: toml::Table = std::fs::read_to_string(&config).unwrap().parse().unwrap();
        let name = config.file_name().unwrap().to_string_lossy().into_owned();
        for key in surface_numbers(&doc) {
            for v in EXTREMES {
                k += 1;
                if k % stride != 0 {
                    continue;
                }
                let set = format!("{key}={v}");
                let nan = (*v == "nan").then_some("a NaN surface parameter");
                judge_run(
                    &mut tally,
                    format!("{category} {name} {set}"),
                    &config,
                    &[set],
                    &cwd,
                    &out,
                    nan,
                    Some(key.clone()),
                );
            }
        }
    }
    // Conductor indices given as n and k, at their extremes, on each conductor.
    let copper = repo().join(SURFACE_CONFIGS[0]);
    let doc: toml::Table = std::fs::read_to_string(&copper).unwrap().parse().unwrap();
    let conductors: Vec<String> = nodes(&doc)
        .into_iter()
        .filter(|(p, v)| surface_key(p) && v.get("type").and_then(|t| t.as_str()) == Some("conductor"))
        .map(|(p, _)| dotted(&p))
        .collect();
    assert!(!conductors.is_empty(), "{} has a conductor", SURFACE_CONFIGS[0]);
    for surface in &conductors {
        for n in ["1e-300", "1e-101", "1e-3", "0.2", "1e3", "1e156", "1.7e308"] {
            for kk in ["0", "1e-300", "3", "1e156", "1.7e308"] {
                k += 1;
                if k % stride != 0 {
                    continue;
                }
                let set = format!("{surface}={{ type = \"conductor\", n = {n}, k = {kk}, roughness = 0.1 }}");
                judge_run(
                    &mut tally,
                    format!("{category} {set}"),
                    &copper,
                    &[set],
                    &cwd,
                    &out,
                    None,
                    Some(surface.clone()),
                );
            }
        }
    }
    // The metals' tables at and beyond their ends.
    for metal in ["copper", "gold", "aluminium"] {
        for nm in ["412", "413", "1937", "1938", "4132.8", "4133"] {
            k += 1;
            if k % stride != 0 {
                continue;
            }
            let sets = vec![format!("{}.material=\"{metal}\"", conductors[0]), format!("source.wavelength_nm={nm}")];
            judge_run(&mut tally, format!("{category} {metal} at {nm} nm"), &copper, &sets, &cwd, &out, None, None);
        }
    }
    tally.finish(&category);
}

/// A 1 mm slab whose density is the NumPy volume `file` (voxels of 50 µm), seen by a detector
/// with a spectrum; `velocity`, if given, is a `.npy` velocity field of the same voxels.
fn npy_experiment(file: &Path, velocity: Option<&Path>, budget_gib: f64) -> String {
    let velocity = velocity
        .map(|v| format!("velocity = {{ type = \"npy\", file = \"{}\", voxel_size_um = 50 }}\n", path_str(v)))
        .unwrap_or_default();
    format!(
        r#"schema_version = 1
[run]
memory_budget_gib = {budget_gib}
[source]
wavelength_nm = 633
[media.tissue]
sigma_a_per_mm = 0.1
sigma_s_per_mm = 10
density = {{ type = "npy", file = "{}", voxel_size_um = 50 }}
{velocity}
[[layers]]
thickness_mm = 1
n = 1.4
medium = "tissue"
[[detectors]]
name = "top"
acceptance_half_angle_deg = 30
[detectors.spectrum]
f_min_hz = -1e6
f_max_hz = 1e6
bins = 64
"#,
        path_str(file)
    )
}

/// A `.npy` file's bytes: version 1.0, the header `dict` padded to a multiple of 64, then `data`.
fn npy_bytes(dict: &str, data: &[u8]) -> Vec<u8> {
    let mut header = dict.to_string();
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    b.extend((header.len() as u16).to_le_bytes());
    b.extend(header.as_bytes());
    b.extend(data);
    b
}

/// Little-endian float32 bytes of `n` values from `f(i)`.
fn floats(n: usize, f: impl Fn(usize) -> f32) -> Vec<u8> {
    (0..n).flat_map(|i| f(i).to_le_bytes()).collect()
}

/// The NumPy volumes of the campaign: headers that lie (shapes whose product overflows, or far
/// beyond the bytes or the budget), dtypes no volume is, values no density is, and a volume
/// over the run's memory budget. Each with what its refusal must name.
fn crafted_volumes() -> Vec<(&'static str, Vec<u8>, f64)> {
    let ok = floats(512, |i| (i % 7) as f32 * 0.2);
    let dict = |descr: &str, shape: &str| format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    vec![
        ("a valid 8³ volume", npy_bytes(&dict("<f4", "(8, 8, 8)"), &ok), 0.5),
        ("a shape of 2000³ with 512 values", npy_bytes(&dict("<f4", "(2000, 2000, 2000)"), &ok), 0.5),
        ("a shape whose product overflows 64 bits", npy_bytes(&dict("<f4", "(4294967296, 4294967296, 8)"), &ok), 0.5),
        ("a shape of (2⁶³, 1, 1)", npy_bytes(&dict("<f4", "(9223372036854775807, 1, 1)"), &ok), 0.5),
        ("a negative shape", npy_bytes(&dict("<f4", "(-8, 8, 8)"), &ok), 0.5),
        ("a 2-D shape", npy_bytes(&dict("<f4", "(64, 8)"), &ok), 0.5),
        ("a shape with a 0", npy_bytes(&dict("<f4", "(0, 8, 8)"), &[]), 0.5),
        ("complex values", npy_bytes(&dict("<c8", "(8, 8, 4)"), &ok), 0.5),
        ("Python objects", npy_bytes(&dict("|O", "(8, 8, 8)"), &ok), 0.5),
        ("big-endian float32", npy_bytes(&dict(">f4", "(8, 8, 8)"), &ok), 0.5),
        ("float16", npy_bytes(&dict("<f2", "(8, 8, 16)"), &ok), 0.5),
        (
            "NaN densities",
            npy_bytes(&dict("<f4", "(8, 8, 8)"), &floats(512, |i| if i == 77 { f32::NAN } else { 1.0 })),
            0.5,
        ),
        (
            "infinite densities",
            npy_bytes(&dict("<f4", "(8, 8, 8)"), &floats(512, |i| if i == 5 { f32::INFINITY } else { 1.0 })),
            0.5,
        ),
        ("negative densities", npy_bytes(&dict("<f4", "(8, 8, 8)"), &floats(512, |i| -((i % 3) as f32))), 0.5),
        ("densities of 3e38", npy_bytes(&dict("<f4", "(8, 8, 8)"), &floats(512, |_| 3e38)), 0.5),
        ("the data cut short", npy_bytes(&dict("<f4", "(8, 8, 8)"), &ok[..1000]), 0.5),
        (
            "a header that never ends",
            {
                let mut b = npy_bytes(&dict("<f4", "(8, 8, 8)"), &ok);
                b[8] = 0xff;
                b[9] = 0xff;
                b
            },
            0.5,
        ),
        // 64³ float32 is 1 MiB as stored, several times that as a grid with its majorants: over a
        // budget of 1 MiB.
        (
            "a 64³ volume over a 1 MiB budget",
            npy_bytes(&dict("<f4", "(64, 64, 64)"), &floats(64 * 64 * 64, |_| 1.0)),
            1.0 / 1024.0,
        ),
    ]
}

/// The crafted volumes (every one), and in the deep sweep `per_file` corruptions of the valid
/// one, as densities (and velocities) through a tiny run.
fn npy_volumes(depth: Depth, per_file: usize) {
    let category = format!("npy-{}", depth.name());
    let kept = inputs_root(&category);
    let scratch = tempfile::tempdir().unwrap();
    let cwd = scratch.path().join("cwd");
    std::fs::create_dir(&cwd).unwrap();
    let out = scratch.path().join("out");
    let mut tally = Tally::default();
    let crafted = crafted_volumes();
    let valid = crafted[0].1.clone();
    let mut inputs: Vec<(String, Vec<u8>, f64)> =
        crafted.into_iter().map(|(what, bytes, budget)| (what.to_string(), bytes, budget)).collect();
    for k in 0..per_file {
        let mut d = Draw::new(seed(), stream("npy", "valid"), k as u64);
        let c = Corruption::draw(&mut d, valid.len(), 128);
        inputs.push((format!("the valid volume: {c}"), c.apply(&valid), 0.5));
    }
    for (k, (what, bytes, budget)) in inputs.into_iter().enumerate() {
        let dir = kept.join(format!("volume-{k}"));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("density.npy");
        std::fs::write(&file, &bytes).unwrap();
        let config = dir.join("experiment.toml");
        std::fs::write(&config, npy_experiment(&file, None, budget)).unwrap();
        let mut case = Case::new(
            format!("{category} #{k}"),
            what.clone(),
            tiny_run(&config, &out),
            &cwd,
            RUN_LIMIT,
            Names::only(&["density.npy", "media.tissue.density", "memory_budget_gib"]),
        );
        case.out = Some(out.clone());
        case.watched.push(out.clone());
        case.inputs = Some(dir);
        case.finite_detections = true;
        tally.run(case);
        let _ = std::fs::remove_dir_all(&out);
    }
    tally.finish(&category);
}

/// An experiment with `layers` clear layers of alternating index between two scattering ones
/// (each interface a step of index), with `run.reflections` as given, seen by a top detector
/// (1000 interfaces took 23 s at 2000 paths deterministically, 0.15 s sampled; 3000 over 120 s:
/// a8c4817).
fn interfaces_experiment(layers: usize, reflections: &str) -> String {
    let mut t = format!(
        "schema_version = 1\n[run]\nreflections = \"{reflections}\"\n[source]\nwavelength_nm = 633\n\
         [media.m]\nsigma_a_per_mm = 0.1\nsigma_s_per_mm = 2\n[media.clear]\nsigma_a_per_mm = 0\nsigma_s_per_mm = 0\n\
         [[layers]]\nthickness_um = 100\nn = 1.4\nmedium = \"m\"\n"
    );
    for i in 0..layers {
        let n = if i % 2 == 0 { 1.5 } else { 1.35 };
        t.push_str(&format!("[[layers]]\nthickness_um = 1\nn = {n}\nmedium = \"clear\"\n"));
    }
    t.push_str("[[layers]]\nthickness_um = 100\nn = 1.4\nmedium = \"m\"\n");
    t.push_str("[[detectors]]\nname = \"top\"\nacceptance_half_angle_deg = 30\n");
    t
}

/// A thick slab of albedo 1 (its paths scatter thousands of times) seen by a top detector: a
/// 2000-path run takes 0.3 s, and a pilot of a fixed 2·10⁵ paths took 67 s (a8c4817).
const ALBEDO_1: &str = r#"schema_version = 1
name = "albedo1_thick"
[source]
wavelength_nm = 633
[media.slab]
sigma_a_per_mm = 0
sigma_s_per_mm = 50
phase = { type = "hg", g = 0.5 }
[[layers]]
thickness_mm = 20
n = 1.4
medium = "slab"
[[detectors]]
name = "top"
acceptance_half_angle_deg = 30
"#;

/// `ohd run CONFIG -q --threads 1 --samples SAMPLES --out OUT --set …`.
fn sized_run(config: &Path, out: &Path, samples: &str, sets: &[String]) -> Vec<String> {
    let mut a = tiny_run(config, out);
    let at = a.iter().position(|x| x == "--samples").expect("tiny_run gives --samples");
    a[at + 1] = samples.to_string();
    for set in sets {
        a.extend(["--set".to_string(), set.clone()]);
    }
    a
}

/// The pilots and deterministic reflections whose cost ignored the run's size: a run of a few
/// thousand paths must end within the hostile cases' time bound however many interfaces its
/// paths cross and whatever pilot its options ask for.
fn costly_options(depth: Depth) {
    let category = format!("cost-{}", depth.name());
    let kept = inputs_root(&category);
    let scratch = tempfile::tempdir().unwrap();
    let cwd = scratch.path().join("cwd");
    std::fs::create_dir(&cwd).unwrap();
    let out = scratch.path().join("out");
    let mut tally = Tally::default();
    let judge = |tally: &mut Tally, id: String, what: String, args: Vec<String>, file: &str| {
        let mut case = Case::new(id, what, args, &cwd, RUN_LIMIT, Names::config(None, &[file]));
        case.out = Some(out.clone());
        case.watched.push(out.clone());
        tally.run(case);
        let _ = std::fs::remove_dir_all(&out);
    };
    let (counts, modes): (&[usize], &[&str]) = match depth {
        Depth::Quick => (&[3000], &["auto"]),
        Depth::Deep => (&[10, 100, 1000, 3000], &["auto", "deterministic", "sampled"]),
    };
    for &n in counts {
        for mode in modes {
            let config = kept.join(format!("interfaces_{n}_{mode}.toml"));
            std::fs::write(&config, interfaces_experiment(n, mode)).unwrap();
            judge(
                &mut tally,
                format!("{category} {n} interfaces, reflections {mode}"),
                format!("{n} clear layers of alternating index, run.reflections = \"{mode}\""),
                sized_run(&config, &out, "2000", &[]),
                "interfaces",
            );
        }
    }
    // The importance pilot on a scene of albedo 1 (every path lives long), at a run's size.
    let albedo1 = kept.join("albedo1_thick.toml");
    std::fs::write(&albedo1, ALBEDO_1).unwrap();
    let (samples, options): (&[&str], &[&str]) = match depth {
        Depth::Quick => (&["2000"], &["table"]),
        Depth::Deep => (&["512", "2000", "20000"], &["table", "windows", "guided", "auto"]),
    };
    for n in samples {
        for opt in options {
            let args = sized_run(&albedo1, &out, n, &[format!("run.importance=\"{opt}\"")]);
            judge(
                &mut tally,
                format!("{category} importance {opt} at {n} paths"),
                format!("a thick slab of albedo 1, run.importance = \"{opt}\", {n} paths"),
                args,
                "albedo1_thick.toml",
            );
        }
    }
    tally.finish(&category);
}

/// A case of each surface finding of the campaign (the quick share of the classes follows: the
/// pilots' and interfaces' cost, the crafted volumes, every 37th surface extreme).
#[test]
fn issue_52_findings() {
    let category = "issue-52";
    let scratch = tempfile::tempdir().unwrap();
    let cwd = scratch.path().join("cwd");
    std::fs::create_dir(&cwd).unwrap();
    let out = scratch.path().join("out");
    let mut tally = Tally::default();
    let camera = repo().join("tests/configs/good/camera_surfaces.toml");
    let rough = repo().join("tests/configs/good/opaque_rough.toml");
    let sets = |v: &[&str]| -> Vec<String> { v.iter().map(|x| x.to_string()).collect() };
    // Tiny roughness, next-event and camera-side (exit 1 "non-finite", and every camera
    // detection dropped with exit 0).
    for a in ["1e-9", "1e-40", "1e-160", "5e-324"] {
        for (config, key) in
            [(&rough, "layers.0.roughness"), (&camera, "layers.0.roughness"), (&camera, "layers.1.roughness")]
        {
            let name = config.file_name().unwrap().to_string_lossy().into_owned();
            let set = format!("{key}={a}");
            judge_run(&mut tally, format!("{category} {name} {set}"), config, &sets(&[&set]), &cwd, &out, None, None);
        }
    }
    // Conductor indices at the extremes (NaN absorbed_fraction, exit 1), surface motions at and
    // beyond c (detections dropped, exit 0).
    for set in [
        "opaque.0.surface={ type = \"conductor\", n = 1e-101, k = 3, roughness = 0.2 }",
        "opaque.0.surface={ type = \"conductor\", n = 1e156, k = 1e156, roughness = 0.2 }",
        "opaque.0.velocity_mm_per_s=[0, 0, 1.7e308]",
        "opaque.0.velocity_mm_per_s=[0, 0, 3e11]",
        "opaque.0.angular_velocity_rpm=[0, 1e308, 0]",
        "opaque.0.center_mm=[1e308, 0, 0]",
    ] {
        let key = set.split_once('=').map(|(k, _)| k.to_string());
        judge_run(
            &mut tally,
            format!("{category} opaque_rough.toml {set}"),
            &rough,
            &sets(&[set]),
            &cwd,
            &out,
            None,
            key,
        );
    }
    // The metals' tables at their documented ends.
    for (metal, nm) in [("copper", "413"), ("gold", "1937"), ("aluminium", "4132.8")] {
        let s = sets(&[&format!("opaque.0.surface.material=\"{metal}\""), &format!("source.wavelength_nm={nm}")]);
        judge_run(&mut tally, format!("{category} {metal} at {nm} nm"), &rough, &s, &cwd, &out, None, None);
    }
    tally.finish(category);
}

#[test]
fn pilots_and_many_interfaces_cost_what_the_run_does() {
    costly_options(Depth::Quick);
}

#[test]
fn lying_and_oversized_npy_volumes_are_refused_or_run() {
    npy_volumes(Depth::Quick, 0);
}

#[test]
fn surfaces_at_their_extremes_are_refused_or_run_finite() {
    surface_extremes(Depth::Quick, 37);
}

#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_surface_extremes() {
    surface_extremes(Depth::Deep, 1);
}

#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_npy_volumes() {
    npy_volumes(Depth::Deep, 120);
}

#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_costly_options() {
    costly_options(Depth::Deep);
}
