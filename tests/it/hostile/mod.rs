//! Hostile inputs (issue 21): the built `ohd` fed mutated experiment files, corrupted VDB
//! files, phase tables, checkpoints and shards, and odd command-line flags, each case in a child
//! process with a wall-time bound. Every case must end with exit 0 and finite outputs, or with
//! exit 2, a message naming a key, flag or file, and nothing written; a panic, an abort, a hang
//! or an exit 2 that names nothing fails with the case's reproducer ([`oracle`]).
//!
//! The mutations are drawn from fixed seeds ([`mutate`]), one stream per case: the quick tests
//! (the default `cargo test`, seconds each) run the first cases of each category, and the deep
//! sweep (`cargo test --profile ci hostile:: -- --ignored`, minutes; counts in
//! validation/README.md, "Hostile inputs") runs many more, the same first ones among them, some
//! with a second or third mutation and a third of the checkpoints and shards with their CRC
//! forged. `OHD_HOSTILE_SEED=N` draws another set. A failing case's inputs are kept under
//! `target/tmp/hostile/` and its command is printed.

mod issue52;
mod mutate;
mod oracle;
mod safety;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use mutate::{Aim, Corruption, Draw, Mutation, Seg, absolute_files, apply, draw_mutation};
use oracle::{Case, Names, Tally};

/// Wall-time bound of an `ohd check` (they take milliseconds; the Mie of rain drops 2 s, of a
/// thousand aerosol populations 14 s on a loaded machine).
const CHECK_LIMIT: Duration = Duration::from_secs(60);
/// Wall-time bound of a tiny run (the slowest shipped experiment takes 4 s at this size).
const RUN_LIMIT: Duration = Duration::from_secs(60);
/// Paths of a tiny run.
const RUN_SAMPLES: &str = "512";

fn seed() -> u64 {
    std::env::var("OHD_HOSTILE_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(21)
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Depth {
    Quick,
    Deep,
}

impl Depth {
    fn name(self) -> &'static str {
        match self {
            Depth::Quick => "quick",
            Depth::Deep => "deep",
        }
    }

    /// Whether a case that has `done` mutations gets another: never in the quick tests; in the
    /// deep sweep a second in 30 % of the cases and a third in a third of those. Drawn after the
    /// mutations so far, so that a deep case begins with its quick twin's mutation.
    fn another(self, d: &mut Draw, done: usize) -> bool {
        self == Depth::Deep && done < 3 && d.chance(if done == 1 { 0.3 } else { 1.0 / 3.0 })
    }
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A stable stream number for a name (FNV-1a): a category's cases do not move when files are
/// added beside it.
fn stream(category: &str, name: &str) -> u64 {
    format!("{category}/{name}")
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325, |h, b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3))
}

/// The directory kept for a category's failing inputs (`target/tmp/hostile/<category>`), emptied.
fn inputs_root(category: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("hostile").join(category);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(v: &[&str]) -> Vec<String> {
    v.iter().map(|x| x.to_string()).collect()
}

fn path_str(p: &Path) -> String {
    p.to_str().expect("UTF-8 path").to_string()
}

/// Every shipped experiment: `configs/*.toml`, then `tests/configs/good/*.toml`.
fn shipped_configs() -> Vec<PathBuf> {
    let mut all = Vec::new();
    for dir in ["configs", "tests/configs/good"] {
        let mut files: Vec<PathBuf> = std::fs::read_dir(repo().join(dir))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        all.extend(files);
    }
    assert!(all.len() >= 8, "{all:?}");
    all
}

/// Experiments whose every load takes seconds (Mie of a rain-drop distribution): fewer cases.
fn costly(config: &Path) -> bool {
    config.file_name().is_some_and(|n| n == "wind_rainy.toml")
}

/// The `--set`s that make a shipped experiment a tiny run: a memory budget well inside the
/// child's address-space limit, and a lidar's gates and DFT cut down (its per-gate fits would
/// take most of the time).
fn tiny(doc: &toml::Table) -> Vec<String> {
    let mut sets = vec!["run.memory_budget_gib=0.5".to_string()];
    if let Some(dets) = doc.get("detectors").and_then(|d| d.as_array()) {
        for (i, det) in dets.iter().enumerate() {
            if det.get("lidar").is_some() {
                sets.push(format!("detectors.{i}.lidar.gates=6"));
                sets.push(format!("detectors.{i}.lidar.fft_points=256"));
            }
        }
    }
    sets
}

/// Whether a document holds a NaN anywhere: a value no key accepts.
fn has_nan(doc: &toml::Table) -> bool {
    mutate::nodes(doc).iter().any(|(_, v)| v.as_float().is_some_and(f64::is_nan))
}

/// The relative `file = "…"` strings of `doc` with their absolute paths against `dir`.
fn relative_files(doc: &toml::Table, dir: &Path) -> Vec<(String, String)> {
    mutate::nodes(doc)
        .into_iter()
        .filter(|(p, _)| matches!(p.last(), Some(Seg::Key(k)) if k == "file"))
        .filter_map(|(_, v)| v.as_str().map(String::from))
        .filter(|f| Path::new(f).is_relative())
        .map(|f| (f.clone(), path_str(&dir.join(&f))))
        .collect()
}

/// A mutant of one experiment file: the mutations, the `--set`s to give, the mutant file's
/// bytes if the mutations are not all `--set`s, and the document as mutated.
struct Mutant {
    what: Vec<Mutation>,
    sets: Vec<String>,
    file: Option<Vec<u8>>,
    /// The mutated document (`None` after a text edit).
    doc: Option<toml::Table>,
}

/// Draw a mutant of `config` (its `text`), on top of the `--set`s `base`.
fn mutant(d: &mut Draw, config: &Path, text: &str, base: &[String], aim: Aim, depth: Depth) -> Mutant {
    let mut doc: toml::Table = text.parse().expect("a shipped experiment parses");
    for b in base {
        ohd::config::apply_set(&mut doc, b).expect("the tiny-run --set applies");
    }
    let dir = config.parent().unwrap();
    let mut what = Vec::new();
    loop {
        let m = draw_mutation(d, &doc, text, aim, what.is_empty() && base.is_empty());
        if let Mutation::Text(e) = &m {
            let mut t = text.to_string();
            for (rel, abs) in relative_files(&doc, dir) {
                t = t.replace(&format!("\"{rel}\""), &format!("\"{abs}\""));
            }
            let bytes = e.apply(&t);
            return Mutant { what: vec![m], sets: Vec::new(), file: Some(bytes), doc: None };
        }
        apply(&mut doc, &m);
        what.push(m);
        if !depth.another(d, what.len()) || doc.values().map(mutate::size).sum::<usize>() > 2 * mutate::LONG_NODES {
            break;
        }
    }
    if what.iter().all(|m| matches!(m, Mutation::Set(_))) {
        let mut sets = base.to_vec();
        sets.extend(what.iter().map(|m| match m {
            Mutation::Set(s) => s.clone(),
            _ => unreachable!(),
        }));
        return Mutant { what, sets, file: None, doc: Some(doc) };
    }
    let mut written = doc.clone();
    absolute_files(&mut written, dir);
    let bytes = toml::to_string(&written).unwrap_or_else(|e| format!("# unserialisable: {e}\n")).into_bytes();
    Mutant { what, sets: Vec::new(), file: Some(bytes), doc: Some(doc) }
}

/// `ohd check` (or a tiny `ohd run`) of mutants of every shipped experiment.
fn config_mutants(depth: Depth, aim: Aim, per_config: usize, per_costly: usize) {
    let kind = if aim == Aim::Check { "config-check" } else { "config-run" };
    let category = format!("{kind}-{}", depth.name());
    let kept = inputs_root(&category);
    let scratch = tempfile::tempdir().unwrap();
    let cwd = scratch.path().join("cwd");
    std::fs::create_dir(&cwd).unwrap();
    let mut tally = Tally::default();
    for config in shipped_configs() {
        let name = config.file_name().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(&config).unwrap();
        let doc: toml::Table = text.parse().unwrap();
        let base = if aim == Aim::Run { tiny(&doc) } else { Vec::new() };
        let n = if costly(&config) { per_costly } else { per_config };
        for k in 0..n {
            let mut d = Draw::new(seed(), stream(kind, &name), k as u64);
            let m = mutant(&mut d, &config, &text, &base, aim, depth);
            let id = format!("{category} {name} #{k}");
            let inputs = kept.join(format!("{}-{k}", config.file_stem().unwrap().to_string_lossy()));
            let target = match &m.file {
                Some(bytes) => {
                    std::fs::create_dir_all(&inputs).unwrap();
                    let p = inputs.join(&name);
                    std::fs::write(&p, bytes).unwrap();
                    p
                }
                None => config.clone(),
            };
            let out = scratch.path().join("out");
            let mut args = match aim {
                Aim::Check => vec!["check".to_string(), path_str(&target)],
                Aim::Run => vec![
                    "run".to_string(),
                    path_str(&target),
                    "-q".into(),
                    "--threads".into(),
                    "1".into(),
                    "--samples".into(),
                    RUN_SAMPLES.into(),
                    "--out".into(),
                    path_str(&out),
                ],
            };
            for set in &m.sets {
                args.extend(["--set".to_string(), set.clone()]);
            }
            let what: Vec<String> = m.what.iter().map(|x| x.to_string()).collect();
            let mut case = Case::new(
                id,
                format!("{name}: {}", what.join("; ")),
                args,
                &cwd,
                if aim == Aim::Check { CHECK_LIMIT } else { RUN_LIMIT },
                Names::config(m.doc.as_ref(), &[&name]),
            );
            if aim == Aim::Run {
                case.out = Some(out.clone());
                case.watched.push(out.clone());
            }
            if let [Mutation::Set(s)] = &m.what[..] {
                case.key = s.split_once('=').map(|(k, _)| k.to_string());
            }
            // The experiment as ohd resolves it: a run's --samples and --threads come after the
            // --sets (and replace a NaN given to run.samples, say).
            let mut resolved = m.doc.clone();
            if let (Aim::Run, Some(doc)) = (aim, resolved.as_mut()) {
                for set in [format!("run.samples={RUN_SAMPLES}"), "run.threads=1".to_string()] {
                    let _ = ohd::config::apply_set(doc, &set);
                }
            }
            if resolved.as_ref().is_some_and(has_nan) {
                case.must_refuse = Some("the experiment holds a NaN".into());
            }
            case.inputs = m.file.is_some().then_some(inputs);
            tally.run(case);
            let _ = std::fs::remove_dir_all(&out);
        }
    }
    tally.finish(&category);
}

/// The experiment that reads a VDB file: a 1 mm slab whose density (and velocity, if the file
/// has a vector grid) comes from `file`, seen by a detector with a spectrum.
fn vdb_experiment(file: &Path, density: Option<&str>, velocity: Option<&str>) -> String {
    let file = path_str(file);
    let grid = |key: &str, g: Option<&str>| {
        g.map(|g| format!("{key} = {{ type = \"vdb\", file = \"{file}\", grid = \"{g}\", scale = 1e-3 }}\n"))
            .unwrap_or_default()
    };
    let (density, velocity) = (grid("density", density), grid("velocity", velocity));
    format!(
        r#"schema_version = 1
[source]
wavelength_nm = 633
[media.tissue]
sigma_a_per_mm = 0.1
sigma_s_per_mm = 10
{density}{velocity}
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
"#
    )
}

/// The committed VDB files with the first float grid and the first vector grid that load.
fn vdb_fixtures() -> Vec<(PathBuf, Option<String>, Option<String>)> {
    use ohd::io::formats::vdb::{self, ValueType};
    let mut out = Vec::new();
    for dir in ["tests/fixtures/vdb", "tests/fixtures/vdb_media", "media/vdb"] {
        let mut files: Vec<PathBuf> = std::fs::read_dir(repo().join(dir))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "vdb"))
            .collect();
        files.sort();
        for f in files {
            let grids = vdb::grids(&f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            let density = grids
                .iter()
                .find(|g| matches!(g.value_type, ValueType::Float) && vdb::read_float(&f, Some(&g.name)).is_ok())
                .map(|g| g.name.clone());
            let velocity = grids
                .iter()
                .find(|g| matches!(g.value_type, ValueType::Vec3s) && vdb::read_vec3(&f, Some(&g.name)).is_ok())
                .map(|g| g.name.clone());
            if density.is_some() || velocity.is_some() {
                out.push((f, density, velocity));
            }
        }
    }
    assert!(out.len() >= 10, "{out:?}");
    out
}

/// Truncated, flipped and overwritten copies of every committed VDB file, read through an
/// experiment and run.
fn corrupted_vdb_files(depth: Depth, per_file: usize) {
    let category = format!("vdb-{}", depth.name());
    let kept = inputs_root(&category);
    let scratch = tempfile::tempdir().unwrap();
    let cwd = scratch.path().join("cwd");
    std::fs::create_dir(&cwd).unwrap();
    let mut tally = Tally::default();
    for (fixture, density, velocity) in vdb_fixtures() {
        let name = fixture.file_name().unwrap().to_string_lossy().into_owned();
        let bytes = std::fs::read(&fixture).unwrap();
        for k in 0..per_file {
            let mut d = Draw::new(seed(), stream("vdb", &name), k as u64);
            let c = Corruption::draw(&mut d, bytes.len(), 4096);
            let inputs = kept.join(format!("{}-{k}", fixture.file_stem().unwrap().to_string_lossy()));
            std::fs::create_dir_all(&inputs).unwrap();
            let file = inputs.join(&name);
            std::fs::write(&file, c.apply(&bytes)).unwrap();
            let config = inputs.join("experiment.toml");
            std::fs::write(&config, vdb_experiment(&file, density.as_deref(), velocity.as_deref())).unwrap();
            let out = scratch.path().join("out");
            let mut case = Case::new(
                format!("{category} {name} #{k}"),
                format!("{name}: {c}"),
                tiny_run(&config, &out),
                &cwd,
                RUN_LIMIT,
                Names::only(&[&name, "media.tissue.density", "media.tissue.velocity"]),
            );
            case.out = Some(out.clone());
            case.watched.push(out.clone());
            case.inputs = Some(inputs);
            tally.run(case);
            let _ = std::fs::remove_dir_all(&out);
        }
    }
    tally.finish(&category);
}

/// `ohd run CONFIG -q --threads 1 --samples 512 --out OUT`.
fn tiny_run(config: &Path, out: &Path) -> Vec<String> {
    let mut a = s(&["run", "", "-q", "--threads", "1", "--samples", RUN_SAMPLES, "--out", ""]);
    a[1] = path_str(config);
    a[8] = path_str(out);
    a
}

/// The experiment that reads a phase table: a 1 mm slab at 633 nm.
fn table_experiment(file: &Path) -> String {
    format!(
        r#"schema_version = 1
[source]
wavelength_nm = 633
[media.m]
sigma_a_per_mm = 0.1
sigma_s_per_mm = 5
phase = {{ type = "table", file = "{}" }}
[[layers]]
thickness_mm = 1
n = 1.4
medium = "m"
"#,
        path_str(file)
    )
}

/// Mutated and corrupted copies of the phase tables of `tests/configs/tables/` (and the presets'
/// tables), read through an experiment and run.
fn corrupted_phase_tables(depth: Depth, per_table: usize) {
    let category = format!("table-{}", depth.name());
    let kept = inputs_root(&category);
    let scratch = tempfile::tempdir().unwrap();
    let cwd = scratch.path().join("cwd");
    std::fs::create_dir(&cwd).unwrap();
    let mut tally = Tally::default();
    let mut tables: Vec<PathBuf> = std::fs::read_dir(repo().join("tests/configs/tables"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().ends_with(".phase.toml"))
        .collect();
    tables.sort();
    assert!(tables.len() >= 3);
    for table in tables {
        let name = table.file_name().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(&table).unwrap();
        let doc: toml::Table = text.parse().unwrap();
        for k in 0..per_table {
            let mut d = Draw::new(seed(), stream("table", &name), k as u64);
            let (what, bytes, nan) = if d.chance(0.3) {
                let c = Corruption::draw(&mut d, text.len(), 200);
                (c.to_string(), c.apply(text.as_bytes()), false)
            } else {
                let mut m = doc.clone();
                let mut what = Vec::new();
                let mut bytes = None;
                loop {
                    let x = draw_mutation(&mut d, &m, &text, Aim::Check, what.is_empty());
                    what.push(x.to_string());
                    if let Mutation::Text(e) = &x {
                        bytes = Some(e.apply(&text));
                        break;
                    }
                    apply(&mut m, &x);
                    if !depth.another(&mut d, what.len())
                        || m.values().map(mutate::size).sum::<usize>() > 2 * mutate::LONG_NODES
                    {
                        break;
                    }
                }
                let nan = bytes.is_none() && has_nan(&m);
                let bytes = bytes.unwrap_or_else(|| toml::to_string(&m).unwrap_or_default().into_bytes());
                (what.join("; "), bytes, nan)
            };
            let inputs = kept.join(format!("{}-{k}", name.trim_end_matches(".phase.toml")));
            std::fs::create_dir_all(&inputs).unwrap();
            let file = inputs.join(&name);
            std::fs::write(&file, bytes).unwrap();
            let config = inputs.join("experiment.toml");
            std::fs::write(&config, table_experiment(&file)).unwrap();
            let out = scratch.path().join("out");
            let mut case = Case::new(
                format!("{category} {name} #{k}"),
                format!("{name}: {what}"),
                tiny_run(&config, &out),
                &cwd,
                RUN_LIMIT,
                Names::only(&[&name, "media.m.phase"]),
            );
            case.out = Some(out.clone());
            case.watched.push(out.clone());
            case.inputs = Some(inputs);
            if nan {
                case.must_refuse = Some("the table holds a NaN".into());
            }
            tally.run(case);
            let _ = std::fs::remove_dir_all(&out);
        }
    }
    tally.finish(&category);
}

/// The arguments of the small run whose checkpoints and shards are corrupted: the built-in
/// default experiment, 16 000 paths.
fn small_run(out: &Path) -> Vec<String> {
    let mut a = s(&["run", "-q", "--samples", "16000", "--seed", "3", "--threads", "1", "--out"]);
    a.push(path_str(out));
    a
}

/// Start `args`, kill the child (SIGKILL) once `file` exists or after `delay`; returns how it
/// ended if it ended before.
fn kill_when(cwd: &Path, args: &[String], file: Option<&Path>, delay: Duration) -> Option<std::process::ExitStatus> {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_ohd"))
        .args(args)
        .current_dir(cwd)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("ohd starts");
    let t0 = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return Some(status);
        }
        if file.is_some_and(Path::exists) || t0.elapsed() >= delay {
            child.kill().unwrap();
            child.wait().unwrap();
            return None;
        }
        std::thread::sleep(Duration::from_micros(500));
    }
}

/// A checkpoint of the small run, taken by killing it after its first save.
fn a_checkpoint(cwd: &Path, dir: &Path) -> Vec<u8> {
    let ckpt = dir.join("checkpoint.ohd");
    for _ in 0..5 {
        let _ = std::fs::remove_dir_all(dir);
        let mut a = small_run(dir);
        a.extend(s(&["--checkpoint-seconds", "0"]));
        kill_when(cwd, &a, Some(&ckpt), Duration::from_secs(60));
        if let Ok(b) = std::fs::read(&ckpt) {
            return b;
        }
    }
    panic!("no checkpoint.ohd in five tries");
}

/// Rewrite the CRC-32 that ends a checkpoint or shard file over what precedes it: a corruption
/// the checksum cannot see, for the parser behind it.
fn forge_crc(b: &mut [u8]) {
    if b.len() >= 4 {
        let n = b.len() - 4;
        let crc = crc32fast::hash(&b[..n]);
        b[n..].copy_from_slice(&crc.to_le_bytes());
    }
}

/// Corrupted checkpoints resumed and corrupted shards merged. A corruption under an intact
/// CRC-32 must be refused naming the file. In the deep sweep a third of the cases have the CRC
/// rewritten over the corruption (a forged file, as a writer's bug or a hand edit would make):
/// those may also be taken up, to finite outputs, within the time bound.
fn corrupted_checkpoints_and_shards(depth: Depth, per_kind: usize) {
    let category = format!("persist-{}", depth.name());
    let kept = inputs_root(&category);
    let scratch = tempfile::tempdir().unwrap();
    let cwd = scratch.path().join("cwd");
    std::fs::create_dir(&cwd).unwrap();
    let checkpoint = a_checkpoint(&cwd, &scratch.path().join("base"));
    let shard_dir = |i: usize| scratch.path().join(format!("shard{i}"));
    for i in 0..2 {
        let mut a = small_run(&shard_dir(i));
        a.extend(["--shard".to_string(), format!("{i}/2")]);
        let e = oracle::exec(&a, &cwd, RUN_LIMIT);
        assert_eq!(e.status, oracle::Status::Exit(0), "{}", e.stderr);
    }
    let shards: Vec<Vec<u8>> = (0..2).map(|i| std::fs::read(shard_dir(i).join("shard.ohd")).unwrap()).collect();
    // Plain and forged corruptions of checkpoints and of shards, counted apart.
    let mut tallies: Vec<(String, Tally)> = ["checkpoint", "checkpoint-forged", "shard", "shard-forged"]
        .iter()
        .map(|k| (format!("{category} {k}"), Tally::default()))
        .collect();
    for k in 0..per_kind {
        // A checkpoint, resumed.
        let mut d = Draw::new(seed(), stream("persist", "checkpoint"), k as u64);
        let c = Corruption::draw(&mut d, checkpoint.len(), 120);
        let forged = d.chance(1.0 / 3.0) && depth == Depth::Deep;
        let mut bytes = c.apply(&checkpoint);
        if forged {
            forge_crc(&mut bytes);
        }
        let dir = kept.join(format!("checkpoint-{k}"));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("checkpoint.ohd"), &bytes).unwrap();
        let mut args = small_run(&dir);
        args.push("--resume".into());
        let (tag, t) = &mut tallies[usize::from(forged)];
        let mut case = Case::new(
            format!("{tag} #{k}"),
            format!("checkpoint.ohd: {c}{}", if forged { ", CRC rewritten" } else { "" }),
            args,
            &cwd,
            RUN_LIMIT,
            Names::only(&["checkpoint.ohd"]),
        );
        case.out = Some(dir.clone());
        case.watched.push(dir.clone());
        case.inputs = Some(dir);
        t.run(case);

        // A shard, merged with the other.
        let mut d = Draw::new(seed(), stream("persist", "shard"), k as u64);
        let which = d.below(2);
        let c = Corruption::draw(&mut d, shards[which].len(), 200);
        let forged = d.chance(1.0 / 3.0) && depth == Depth::Deep;
        let mut bytes = c.apply(&shards[which]);
        if forged {
            forge_crc(&mut bytes);
        }
        let dir = kept.join(format!("shard-{k}"));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("shard.ohd"), &bytes).unwrap();
        let other = shard_dir(1 - which);
        let merged = scratch.path().join("merged");
        let args = vec!["merge".into(), path_str(&dir), path_str(&other), "--out".into(), path_str(&merged)];
        let (tag, t) = &mut tallies[2 + usize::from(forged)];
        let mut case = Case::new(
            format!("{tag} #{k}"),
            format!("shard {which}/2's shard.ohd: {c}{}", if forged { ", CRC rewritten" } else { "" }),
            args,
            &cwd,
            RUN_LIMIT,
            Names::only(&["shard.ohd"]),
        );
        case.out = Some(merged.clone());
        case.watched.extend([merged.clone(), dir.clone(), other]);
        case.inputs = Some(dir);
        t.run(case);
        let _ = std::fs::remove_dir_all(&merged);
    }
    oracle::finish_all(tallies);
}

/// Runs killed with SIGKILL at drawn moments (a checkpoint every batch), resumed (and killed
/// again) until one finishes: its outputs must be the uninterrupted run's, byte for byte.
fn kill_and_resume(depth: Depth, cycles: usize) {
    let category = format!("kill-resume-{}", depth.name());
    let scratch = tempfile::tempdir().unwrap();
    let cwd = scratch.path().join("cwd");
    std::fs::create_dir(&cwd).unwrap();
    let whole = scratch.path().join("whole");
    let t0 = Instant::now();
    let e = oracle::exec(&small_run(&whole), &cwd, RUN_LIMIT);
    assert_eq!(e.status, oracle::Status::Exit(0), "{}", e.stderr);
    let seconds = t0.elapsed().as_secs_f64();
    let mut failures = Vec::new();
    for k in 0..cycles {
        let mut d = Draw::new(seed(), stream("kill-resume", "cycle"), k as u64);
        let dir = scratch.path().join(format!("cycle{k}"));
        let finished = || dir.join("manifest.json").exists() && !dir.join("checkpoint.ohd").exists();
        let mut steps = Vec::new();
        let mut problems = Vec::new();
        let planned = 1 + d.below(3);
        for attempt in 0..=planned {
            if finished() {
                break;
            }
            let resume = dir.join("checkpoint.ohd").exists();
            let mut a = small_run(&dir);
            if resume {
                a.push("--resume".into());
            }
            if attempt < planned {
                a.extend(s(&["--checkpoint-seconds", "0"]));
                let delay = Duration::from_secs_f64(seconds * 1.2 * d.uniform());
                let step = format!(
                    "{}killed after {:.0} ms",
                    if resume { "resumed, " } else { "" },
                    delay.as_secs_f64() * 1e3
                );
                match kill_when(&cwd, &a, None, delay) {
                    None => steps.push(step),
                    Some(st) if st.success() => steps.push(format!("{step}: finished first")),
                    Some(st) => problems.push(format!("$ {} ended with {st} before it was killed", oracle::shell(&a))),
                }
                continue;
            }
            let e = oracle::exec(&a, &cwd, RUN_LIMIT);
            steps.push(if resume { "resumed to the end".into() } else { "run to the end".to_string() });
            if e.status != oracle::Status::Exit(0) {
                problems.push(format!("$ {} ended with {:?}\n    | {}", oracle::shell(&a), e.status, e.stderr.trim()));
            }
        }
        for e in std::fs::read_dir(&whole).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "npy") {
                let name = p.file_name().unwrap();
                if std::fs::read(&p).ok() != std::fs::read(dir.join(name)).ok() {
                    problems.push(format!("{} differs from the uninterrupted run's", name.to_string_lossy()));
                }
            }
        }
        if dir.join("checkpoint.ohd").exists() {
            problems.push("checkpoint.ohd outlives the finished run".into());
        }
        eprintln!(
            "{category} #{k}: {}; {}",
            steps.join(", "),
            if problems.is_empty() { "same outputs" } else { "FAILED" }
        );
        if !problems.is_empty() {
            failures.push(format!("[{category} #{k}] {}: {}", steps.join(", "), problems.join("; ")));
        }
    }
    eprintln!("{category}: {cycles} cycles, {} failed", failures.len());
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Odd command-line flags and special files: each with the words one of which its refusal
/// must name.
fn odd_flags() -> Vec<(Vec<String>, Vec<&'static str>)> {
    let run = |extra: &[&str]| -> Vec<String> {
        let mut a = s(&["run", "-q", "--threads", "1", "--samples", RUN_SAMPLES, "--out", "OUT"]);
        a.extend(s(extra));
        a
    };
    let vdh = path_str(&repo().join("validation/vdh_slab.toml"));
    // Special files of the tests' own (issue 33: never the machine's devices or system paths).
    let special = crate::support::special::special();
    let own = |p: &Path| -> &'static str { Box::leak(path_str(p).into_boxed_str()) };
    let (fifo, device, dir) = (own(&special.fifo), own(special.device_or_fifo()), own(&special.dir));
    let null = own(special.null.as_deref().unwrap_or(&special.fifo));
    let file_as_parent = own(&special.dir.join("file"));
    std::fs::write(file_as_parent, "a file where a directory is expected").unwrap();
    let under_file = own(&special.dir.join("file/x"));
    let mut cases: Vec<(Vec<String>, Vec<&'static str>)> = Vec::new();
    for v in ["0", "-1", "1e3", "18446744073709551615", "281474976710657", "nan", ""] {
        let mut a = run(&[]);
        a[5] = v.to_string();
        cases.push((a, vec!["--samples", "run.samples"]));
    }
    for v in ["18446744073709551615", "-1", "nan"] {
        cases.push((run(&["--seed", v]), vec!["--seed", "run.seed"]));
    }
    for v in ["100000", "-1", "1e9", "18446744073709551615"] {
        let mut a = run(&[]);
        a[3] = v.to_string();
        cases.push((a, vec!["--threads", "run.threads"]));
    }
    for v in ["nan", "-1", "inf", "1e300", "-0", "1e-300", "-inf", "x"] {
        cases.push((run(&["--checkpoint-seconds", v]), vec!["--checkpoint-seconds"]));
    }
    for v in ["nan", "0", "-1", "inf", "1e-300", "1", "2"] {
        cases.push((run(&["--target-error", v, "--max-samples", "4096"]), vec!["--target-error", "--max-samples"]));
    }
    for v in ["0", "1", "18446744073709551615"] {
        cases.push((run(&["--target-error", "0.5", "--max-samples", v]), vec!["--max-samples"]));
    }
    cases.push((run(&["--max-samples", "100"]), vec!["--max-samples", "--target-error"]));
    for v in [
        "0/0",
        "1/1",
        "0/1",
        "0/18446744073709551615",
        "18446744073709551614/18446744073709551615",
        "-1/2",
        "1/2/3",
        "/",
    ] {
        cases.push((run(&["--shard", v]), vec!["--shard"]));
    }
    cases.push((run(&["--shard", "0/2", "--resume"]), vec!["--shard", "--resume"]));
    cases.push((run(&["--resume"]), vec!["checkpoint.ohd"]));
    for set in [
        "",
        "=",
        "=1",
        "a..b=1",
        "layers.99.n=1",
        "layers.-1.n=1",
        "layers.0.n.x=1",
        "run.samples=1e999",
        "run=1",
        "media.blood.phase.g=0.999999999999",
        "detectors.0.image.pixels=[16384, 16384]",
    ] {
        cases.push((run(&["--set", set]), vec!["--set", "layers", "run", "media", "detectors", "a..b"]));
    }
    // (Endless files, /dev/zero, are issue_21_findings' cases.)
    for config in ["/nonexistent/x.toml", dir, null, "Cargo.toml", "README.md"] {
        let mut a = run(&[]);
        a.insert(1, config.to_string());
        cases.push((a, vec![config, "schema_version", "(top level)"]));
    }
    for config in ["Cargo.toml", "tests/fixtures/vdb/extra.vdb", "tests/configs/bad/toml_syntax.toml"] {
        let mut a = run(&[]);
        a.insert(1, path_str(&repo().join(config)));
        cases.push((a, vec![config, "schema_version", "(top level)", "unknown field"]));
    }
    for out in [null, under_file, device, fifo] {
        let mut a = run(&[]);
        a[7] = out.to_string();
        cases.push((a, vec![out]));
    }
    cases.push((s(&["check", "--set", "run.threads=-1"]), vec!["run.threads"]));
    cases.push((s(&["check", fifo]), vec![fifo, "schema_version"]));
    cases.push((s(&["merge", "--out", "OUT"]), vec!["DIR"]));
    cases.push((s(&["merge", "/nonexistent", "--out", "OUT"]), vec!["/nonexistent"]));
    cases.push((s(&["merge", dir, "--out", "OUT"]), vec![own(&special.dir.join("shard.ohd"))]));
    cases.push((s(&["merge", null, "--out", "OUT"]), vec![null]));
    for v in ["nan", "-1", "inf", "0", "1e-300"] {
        cases.push((
            s(&["converge", &vdh, "--samples", "4096", "--rungs", "2", "--budget-seconds", v, "--out", "OUT"]),
            vec!["--budget-seconds"],
        ));
    }
    for v in ["0", "1", "25", "-1"] {
        cases.push((s(&["converge", &vdh, "--samples", "4096", "--rungs", v, "--out", "OUT"]), vec!["--rungs"]));
    }
    cases.push((s(&["converge", &vdh, "--samples", "0", "--out", "OUT"]), vec!["--samples"]));
    cases.push((
        s(&["converge", &vdh, "--samples", "4096", "--rungs", "2", "--reference", null, "--out", "OUT"]),
        vec![null],
    ));
    for (k, v) in [
        ("--x", "nan"),
        ("--x", "inf"),
        ("--x", "-1"),
        ("--x", "1e300"),
        ("--m-real", "nan"),
        ("--m-real", "-1"),
        ("--m-imag", "inf"),
        ("--m-imag", "1e300"),
    ] {
        let mut a = s(&["mie", "--m-real", "1.5", "--x", "1"]);
        match a.iter().position(|x| x == k) {
            Some(i) => a[i + 1] = v.to_string(),
            None => a.extend([k.to_string(), v.to_string()]),
        }
        cases.push((a, vec![k, "size parameter", "refractive index"]));
    }
    for w in ["1e-300", "nan", "1e300"] {
        cases.push((
            s(&["mie", "--diameter-um", "1", "--n-particle", "1.4", "--n-medium", "1", "--wavelength-nm", w]),
            vec!["--wavelength-nm", "size parameter"],
        ));
    }
    cases.push((s(&["mie", "--m-real", "1.5", "--x", "1", "--angles", "100001", "--table", "OUT"]), vec!["--angles"]));
    cases.push((s(&["mie", "--m-real", "1.5", "--x", "1", "--angles", "16", "--table", device]), vec![device]));
    cases
}

fn odd_flag_cases(depth: Depth) {
    let category = format!("flags-{}", depth.name());
    let scratch = tempfile::tempdir().unwrap();
    let cwd = scratch.path().join("cwd");
    std::fs::create_dir(&cwd).unwrap();
    let mut tally = Tally::default();
    for (k, (args, words)) in odd_flags().into_iter().enumerate() {
        let out = scratch.path().join("out");
        let args: Vec<String> = args.into_iter().map(|a| if a == "OUT" { path_str(&out) } else { a }).collect();
        let mie = args[0] == "mie";
        let mut case =
            Case::new(format!("{category} #{k}"), "odd flags".into(), args, &cwd, RUN_LIMIT, Names::only(&words));
        case.out = (!mie).then(|| out.clone());
        case.watched.push(out.clone());
        case.stdout_json = mie && !case.args.iter().any(|a| a == "--table");
        tally.run(case);
        let _ = std::fs::remove_dir_all(&out);
    }
    tally.finish(&category);
}

/// The findings of issue 21's campaign, one case each, judged as every hostile case is: the
/// values that ran to NaN outputs, the ones accepted silently (now refused), the endless files
/// (refused for their size, not after filling memory), stale outputs, the total internal
/// reflection that never ended, and the checkpoint interval that panicked.
#[test]
fn issue_21_findings() {
    let category = "issue-21";
    let kept = inputs_root(category);
    let scratch = tempfile::tempdir().unwrap();
    let cwd = scratch.path().join("cwd");
    std::fs::create_dir(&cwd).unwrap();
    let config = |name: &str| repo().join("configs").join(name);
    let out = scratch.path().join("out");
    let tiny_sets = |name: &str, sets: &[&str]| -> Vec<String> {
        let doc: toml::Table = std::fs::read_to_string(config(name)).unwrap().parse().unwrap();
        let mut a = tiny_run(&config(name), &out);
        for s in tiny(&doc).iter().map(String::as_str).chain(sets.iter().copied()) {
            a.extend(["--set".to_string(), s.to_string()]);
        }
        a
    };
    let mut tally = Tally::default();
    let judge = |tally: &mut Tally, what: &str, args: Vec<String>, names: Names, must_refuse: Option<&str>| {
        let mut case = Case::new(format!("{category} {what}"), what.into(), args, &cwd, RUN_LIMIT, names);
        case.out = Some(out.clone());
        case.watched.push(out.clone());
        case.must_refuse = must_refuse.map(String::from);
        tally.run(case);
        let _ = std::fs::remove_dir_all(&out);
    };
    // Non-finite outputs with exit 0.
    for (name, set) in [
        ("wind_turbulence.toml", "detectors.0.lidar.sample_rate_mhz=1e-200"),
        ("wind_turbulence.toml", "detectors.0.lidar.first_gate_m=1e308"),
        ("wind_sunny.toml", "media.aerosol.motion.dispersion_m_per_s=1e308"),
    ] {
        judge(&mut tally, &format!("{name} --set {set}"), tiny_sets(name, &[set]), Names::config(None, &[name]), None);
    }
    // Values accepted silently.
    let refuse = [
        (
            "default.toml",
            &["media.unused.sigma_a_per_mm=nan", "media.unused.sigma_s_per_mm=1"][..],
            "NaN σa of a medium no layer uses",
        ),
        (
            "default.toml",
            &[
                "media.unused.sigma_a_per_mm=0",
                "media.unused.sigma_s_per_mm=1",
                "media.unused.phase.type=\"hg\"",
                "media.unused.phase.g=7",
            ],
            "HG g = 7 of a medium no layer uses",
        ),
        ("default.toml", &["media.blood.velocity.v_max_mm_per_s=1e12"], "blood flowing at 10⁹ m/s, faster than light"),
        ("fmcw_target.toml", &["media.target.velocity.velocity_m_per_s=[0, 0, 3e8]"], "a target receding at c"),
    ];
    for (name, sets, why) in refuse {
        judge(&mut tally, &format!("{name}: {why}"), tiny_sets(name, sets), Names::config(None, &[name]), Some(why));
    }
    // Endless files.
    let dir = kept.join("inputs");
    std::fs::create_dir_all(&dir).unwrap();
    // An endless file of the tests' own (issue 33: never the machine's /dev/zero).
    let zero = crate::support::special::special().endless();
    let zero_str = path_str(zero);
    let table = dir.join("table.toml");
    std::fs::write(&table, table_experiment(zero)).unwrap();
    let vdb = dir.join("vdb.toml");
    std::fs::write(&vdb, vdb_experiment(zero, Some("density"), None)).unwrap();
    for (what, config, names) in [
        ("the experiment file is endless", zero, &[zero_str.as_str()][..]),
        ("a phase table file is endless", table.as_path(), &[zero_str.as_str(), "media.m.phase"]),
        ("a VDB file is endless", vdb.as_path(), &[zero_str.as_str(), "media.tissue.density"]),
    ] {
        judge(&mut tally, what, tiny_run(config, &out), Names::only(names), None);
    }
    for (what, file, args) in [
        ("checkpoint.ohd is endless", "checkpoint.ohd", {
            let mut a = small_run(&out);
            a.push("--resume".into());
            a
        }),
        ("shard.ohd is endless", "shard.ohd", s(&["merge", "SHARD", "--out", "OUT"])),
    ] {
        let holder = scratch.path().join("holder");
        let _ = std::fs::remove_dir_all(&holder);
        let at = if file == "checkpoint.ohd" { out.clone() } else { holder.clone() };
        std::fs::create_dir_all(&at).unwrap();
        std::os::unix::fs::symlink(zero, at.join(file)).unwrap();
        let args = args
            .into_iter()
            .map(|a| match a.as_str() {
                "SHARD" => path_str(&holder),
                "OUT" => path_str(&out),
                _ => a,
            })
            .collect();
        let mut case =
            Case::new(format!("{category} {what}"), what.into(), args, &cwd, RUN_LIMIT, Names::only(&[file]));
        case.watched.push(at.clone());
        case.out = Some(out.clone());
        tally.run(case);
        let _ = std::fs::remove_dir_all(&out);
    }
    // Stale outputs: a lidar run into the directory of a camera run.
    let e = oracle::exec(&tiny_run(&config("default.toml"), &out), &cwd, RUN_LIMIT);
    assert_eq!(e.status, oracle::Status::Exit(0), "{}", e.stderr);
    let mut case = Case::new(
        format!("{category} stale outputs"),
        "configs/wind_turbulence.toml run into the output directory of configs/default.toml".into(),
        tiny_sets("wind_turbulence.toml", &[]),
        &cwd,
        RUN_LIMIT,
        Names::only(&[&path_str(&out)]),
    );
    case.out = Some(out.clone());
    case.watched.push(out.clone());
    case.listed_only = true;
    tally.run(case);
    let _ = std::fs::remove_dir_all(&out);
    // Light trapped between the faces of a clear layer by total internal reflection.
    let tir = dir.join("tir.toml");
    std::fs::write(
        &tir,
        r#"schema_version = 1
[source]
wavelength_nm = 800
[media.clear]
sigma_a_per_mm = 0
sigma_s_per_mm = 0
[media.cloud]
sigma_a_per_mm = 0
sigma_s_per_mm = 20
[[layers]]
name = "slab"
thickness_mm = 1
n = 1.33
medium = "clear"
[[regions]]
layer = "slab"
medium = "cloud"
shape = { type = "sphere", center_mm = [0, 0, 0.5], radius_mm = 0.3 }
"#,
    )
    .unwrap();
    judge(
        &mut tally,
        "total internal reflection in a clear layer",
        tiny_run(&tir, &out),
        Names::only(&["tir.toml"]),
        None,
    );
    judge(
        &mut tally,
        "--checkpoint-seconds 1e300",
        [tiny_run(&config("default.toml"), &out), s(&["--checkpoint-seconds", "1e300"])].concat(),
        Names::only(&["--checkpoint-seconds"]),
        None,
    );
    // Four layers of 10⁵ sublayers each, through `ohd check`, which builds them (a run of 512
    // paths through 4·10⁵ interfaces takes 20 s).
    let layers = "[[layers]]\nthickness_mm = 1\nn = 1.4\nmedium = \"m\"\nsublayers = 100000\n".repeat(4);
    let sub = dir.join("sublayers.toml");
    std::fs::write(
        &sub,
        format!("schema_version = 1\n[source]\nwavelength_nm = 633\n[media.m]\nsigma_a_per_mm = 0.1\nsigma_s_per_mm = 1\n{layers}"),
    )
    .unwrap();
    tally.run(Case::new(
        format!("{category} sublayers"),
        "4 layers × 100 000 sublayers, ohd check".into(),
        vec!["check".into(), path_str(&sub)],
        &cwd,
        CHECK_LIMIT,
        Names::config(None, &["sublayers.toml"]),
    ));
    tally.finish(category);
}

#[test]
fn config_mutants_through_check() {
    config_mutants(Depth::Quick, Aim::Check, 24, 3);
}

#[test]
fn config_mutants_through_tiny_runs() {
    config_mutants(Depth::Quick, Aim::Run, 3, 1);
}

#[test]
fn corrupted_vdb_files_are_refused_or_run() {
    corrupted_vdb_files(Depth::Quick, 3);
}

#[test]
fn corrupted_phase_tables_are_refused_or_run() {
    corrupted_phase_tables(Depth::Quick, 8);
}

#[test]
fn corrupted_checkpoints_and_shards_are_refused() {
    corrupted_checkpoints_and_shards(Depth::Quick, 24);
}

#[test]
fn killed_runs_resume_to_the_same_outputs() {
    kill_and_resume(Depth::Quick, 2);
}

#[test]
fn odd_flags_are_refused_or_run() {
    odd_flag_cases(Depth::Quick);
}

#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_config_mutants_through_check() {
    config_mutants(Depth::Deep, Aim::Check, 300, 30);
}

#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_config_mutants_through_tiny_runs() {
    config_mutants(Depth::Deep, Aim::Run, 120, 12);
}

#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_corrupted_vdb_files() {
    corrupted_vdb_files(Depth::Deep, 60);
}

#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_corrupted_phase_tables() {
    corrupted_phase_tables(Depth::Deep, 150);
}

#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_corrupted_checkpoints_and_shards() {
    corrupted_checkpoints_and_shards(Depth::Deep, 200);
}

#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_killed_runs_resume_to_the_same_outputs() {
    kill_and_resume(Depth::Deep, 16);
}
