//! The output directory and the machine (issue 33), tried as a hostile user would: links planted
//! at every name ohd writes or removes, a scan's pointing directory that is a link elsewhere,
//! records that list paths, config stems that are `..`, two runs into one directory, unusable
//! `--out` paths, closed and full standard streams, resource limits and special files as outputs.
//! Every case runs the built binary in a temporary directory of its own, with a canary file beside
//! the output directory that must come through unchanged; the devices and FIFOs are the tests'
//! own ([`crate::support::special`]).
//!
//! The quick tests here are one case per finding of the issue; [`super::deep_safety`] sweeps each
//! class wider (`--ignored`, counts in validation/README.md, "Hostile inputs").

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use crate::support::special::{Canary, special};

pub fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_ohd")
}

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn config(name: &str) -> String {
    repo().join("configs").join(name).display().to_string()
}

pub fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

pub fn describe(o: &Output) -> String {
    format!("status {:?}\n--- stdout\n{}\n--- stderr\n{}", o.status, text(&o.stdout), text(&o.stderr))
}

/// `ohd args…` in `cwd` through `sh -c 'PREFIX; exec ohd "$@"'`: the shell's `$$` is ohd's
/// process ID (for names that carry it), and `prefix` may set limits (`ulimit -f 64`).
pub fn sh_ohd(cwd: &Path, prefix: &str, args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!("{prefix}\nexec \"$0\" \"$@\""))
        .arg(bin())
        .args(args)
        .current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .output()
        .expect("sh starts")
}

/// A small run of the default experiment (a camera with images and spectra).
pub fn small(out: &Path) -> Vec<String> {
    ["run", "-q", "--threads", "1", "--samples", "2000", "--out"]
        .iter()
        .map(|s| s.to_string())
        .chain([out.display().to_string()])
        .collect()
}

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

/// The names a run of `args` writes into `out` (its manifest's files, the manifest), from a run
/// into a scratch directory.
pub fn names_written(cwd: &Path, args: &[String], out: &Path) -> Vec<String> {
    let scratch = cwd.join("names-scratch");
    let a: Vec<String> =
        args.iter().map(|a| if Path::new(a) == out { scratch.display().to_string() } else { a.clone() }).collect();
    let o = sh_ohd(cwd, "", &strs(&a));
    assert!(o.status.success(), "{}", describe(&o));
    let m: serde_json::Value = serde_json::from_slice(&std::fs::read(scratch.join("manifest.json")).unwrap()).unwrap();
    let mut names: Vec<String> =
        m["files"].as_array().unwrap().iter().map(|f| f.as_str().unwrap().to_string()).collect();
    names.push("manifest.json".into());
    std::fs::remove_dir_all(&scratch).unwrap();
    names
}

/// Finding 1: a link planted at any name ohd creates or removes — the outputs, the marker, the
/// manifest, the checkpoint, the lock, and the temporary and probe names of the process (known to
/// a planter as the shell's `$$` before it `exec`s ohd) — is never followed: the canary it
/// points to is unchanged, and the run succeeds.
#[test]
fn planted_links_are_never_followed() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let canary = Canary::beside(&out);
    let args: Vec<String> = [small(&out), vec!["--checkpoint-seconds".into(), "0".into()]].concat();
    let names = names_written(tmp.path(), &args, &out);
    let fixed = ["ohd_incomplete.txt", "checkpoint.ohd", ".ohd-lock", "shard.ohd"];
    let mut plant = String::from("set -e\n");
    for n in names.iter().map(String::as_str).chain(fixed) {
        for at in [n.to_string(), format!(".{n}.tmp-$$")] {
            plant.push_str(&format!("ln -s \"{}\" \"{}/{at}\"\n", canary.path().display(), out.display()));
        }
    }
    plant.push_str(&format!("ln -s \"{}\" \"{}/.ohd-write-probe-$$\"\n", canary.path().display(), out.display()));
    std::fs::create_dir(&out).unwrap();
    let o = sh_ohd(tmp.path(), &plant, &strs(&args));
    assert!(o.status.success(), "{}", describe(&o));
    assert!(canary.unchanged(), "a planted link was followed: the canary changed\n{}", describe(&o));
    for n in &names {
        let m = std::fs::symlink_metadata(out.join(n)).unwrap();
        assert!(m.is_file(), "{n}: {:?}", m.file_type());
    }
}

/// Finding 2: a scan whose pointing directory is a link to another directory is refused naming
/// it (exit 2) — nothing is written there, nothing listed by that directory's own manifest is
/// removed; and a record that lists a path (`../x.npy`, `/abs/x.npy`, `a/b.npy`) is refused
/// naming the record, before anything is removed.
#[test]
fn a_scan_and_its_records_stay_inside_the_directory() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let canary = Canary::beside(&out);
    let elsewhere = tmp.path().join("elsewhere");
    std::fs::create_dir_all(&elsewhere).unwrap();
    std::fs::write(elsewhere.join("manifest.json"), r#"{"ohd_version": "0", "files": ["keep.npy"]}"#).unwrap();
    std::fs::write(elsewhere.join("keep.npy"), "the user's").unwrap();
    std::fs::create_dir_all(&out).unwrap();
    std::os::unix::fs::symlink(&elsewhere, out.join("pointing_01")).unwrap();
    let before = super::oracle::snapshot(&elsewhere);
    let o = sh_ohd(
        tmp.path(),
        "",
        &["run", "-q", &config("wind_sunny.toml"), "--samples", "512", "--out", out.to_str().unwrap()],
    );
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    assert!(text(&o.stderr).contains("pointing_01"), "{}", describe(&o));
    assert_eq!(super::oracle::snapshot(&elsewhere), before, "the linked directory changed");
    // Records listing paths, as a run's manifest and as the marker.
    for (record, text_) in [
        ("manifest.json", r#"{"ohd_version": "0", "files": ["../canary.npy"]}"#.to_string()),
        ("manifest.json", format!(r#"{{"ohd_version": "0", "files": ["{}"]}}"#, canary.path().display())),
        ("manifest.json", r#"{"ohd_version": "0", "files": ["a/../../canary.npy"]}"#.to_string()),
        ("ohd_incomplete.txt", "# interrupted\n../canary.npy\n".to_string()),
        ("ohd_incomplete.txt", "# interrupted\n../out/\n".to_string()),
    ] {
        let _ = std::fs::remove_dir_all(&out);
        std::fs::create_dir_all(&out).unwrap();
        std::fs::write(out.join(record), &text_).unwrap();
        let o = sh_ohd(tmp.path(), "", &strs(&small(&out)));
        assert_eq!(o.status.code(), Some(2), "{record} {text_}: {}", describe(&o));
        assert!(text(&o.stderr).contains(record), "{}", describe(&o));
        assert_eq!(std::fs::read_dir(&out).unwrap().count(), 1, "{record}: written or removed: {}", describe(&o));
        assert!(canary.unchanged());
    }
}

/// Finding 3: the default output directory of a file named `..toml` or `...toml` (without a
/// `name`) is one folder inside `out/`, not `out/..`.
#[test]
fn config_stems_are_folder_names() {
    let tmp = tempfile::tempdir().unwrap();
    let text_ = std::fs::read_to_string(repo().join("validation/vdh_slab.toml")).unwrap();
    let unnamed: String = text_.lines().filter(|l| !l.starts_with("name =")).map(|l| format!("{l}\n")).collect();
    for (file, folder) in [("..toml", "_"), ("...toml", "__"), ("-.toml", "-")] {
        std::fs::write(tmp.path().join(file), &unnamed).unwrap();
        let o = sh_ohd(tmp.path(), "", &["run", "-q", "--samples", "1000", "--", file]);
        assert!(o.status.success(), "{file}: {}", describe(&o));
        assert!(tmp.path().join("out").join(folder).join("manifest.json").is_file(), "{file}: {}", describe(&o));
        assert!(!tmp.path().join("manifest.json").exists() && !tmp.path().join("out/manifest.json").exists());
    }
}

/// Finding 4: a second command into a directory being written is refused naming the directory
/// and the first one's process; the first finishes; the lock is gone after it.
#[test]
fn one_command_at_a_time_per_directory() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let canary = Canary::beside(&out);
    let mut first = Command::new(bin())
        .args(["run", "-q", "--threads", "1", "--samples", "600000", "--out", out.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t = Instant::now();
    while !out.join(".ohd-lock").exists() && t.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(5));
    }
    let second = sh_ohd(tmp.path(), "", &strs(&small(&out)));
    let merge = sh_ohd(tmp.path(), "", &["merge", tmp.path().to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let converge = sh_ohd(
        tmp.path(),
        "",
        &[
            "converge",
            &repo().join("validation/vdh_slab.toml").display().to_string(),
            "--samples",
            "4096",
            "--rungs",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
    );
    let status = first.wait().unwrap();
    assert!(status.success(), "the first run failed");
    for o in [second, merge, converge] {
        assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
        let e = text(&o.stderr);
        assert!(e.contains(out.to_str().unwrap()) && e.contains(&format!("process {}", first.id())), "{e}");
    }
    assert!(!out.join(".ohd-lock").exists() && !out.join("ohd_incomplete.txt").exists());
    assert!(canary.unchanged());
}

/// Finding 5: an output directory that cannot be used — a dangling link, a loop of links, a name
/// over the file-system's limit, a file where a directory must be — is refused before anything is
/// traced (exit 2 naming it, although the run asked would take minutes), for `run`, `converge`
/// and `merge`; `newdir/.` is a directory like any other.
#[test]
fn unusable_output_directories_are_refused_before_tracing() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    std::os::unix::fs::symlink(t.join("nothing"), t.join("dangling")).unwrap();
    std::os::unix::fs::symlink(t.join("loop"), t.join("loop")).unwrap();
    std::fs::write(t.join("file"), "").unwrap();
    let long = "n".repeat(300);
    for out in ["dangling", "loop", long.as_str(), "file/out", "file"] {
        for args in [
            vec!["run", "-q", "--samples", "100000000000", "--out", out],
            vec!["converge", "--samples", "100000000000", "--budget-seconds", "3e7", "--out", out],
            vec!["merge", "nowhere", "--out", out],
        ] {
            // (Bounded in CPU time: without the early check these would trace for hours.)
            let o = sh_ohd(t, "ulimit -t 30", &args);
            assert_eq!(o.status.code(), Some(2), "{args:?}: {}", describe(&o));
            assert!(text(&o.stderr).contains(&out[..out.len().min(40)]), "{args:?}: {}", describe(&o));
        }
    }
    let o = sh_ohd(t, "", &["run", "-q", "--samples", "1000", "--out", "newdir/."]);
    assert!(o.status.success() && t.join("newdir/manifest.json").is_file(), "{}", describe(&o));
    // A read-only parent stops only a user without the right to override it.
    if !rustix::process::geteuid().is_root() {
        let ro = t.join("ro");
        std::fs::create_dir(&ro).unwrap();
        std::fs::set_permissions(&ro, std::os::unix::fs::PermissionsExt::from_mode(0o555)).unwrap();
        let args = ["converge", "--samples", "100000000000", "--budget-seconds", "3e7", "--out", "ro/out"];
        let o = sh_ohd(t, "ulimit -t 30", &args);
        assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    } else {
        eprintln!("as root, a read-only parent does not stop writing: that case is left out");
    }
}

/// Run `args` with its standard output or error (`stream` 1 or 2) going to `sink`.
pub fn with_stream(cwd: &Path, args: &[&str], stream: u8, sink: Stdio) -> Output {
    let mut c = Command::new(bin());
    c.args(args).current_dir(cwd).stdin(Stdio::null());
    if stream == 1 {
        c.stdout(sink).stderr(Stdio::piped());
    } else {
        c.stderr(sink).stdout(Stdio::piped());
    }
    c.output().expect("ohd starts")
}

/// A pipe whose reading end is closed: writing to it fails (EPIPE).
pub fn closed_pipe() -> Stdio {
    let (reader, writer) = rustix::pipe::pipe().unwrap();
    drop(reader);
    Stdio::from(writer)
}

/// Finding 6: a closed or full standard stream never panics (exit 101) nor loses the results:
/// the outputs are written and the exit status is 1.
#[test]
fn closed_and_full_streams_end_cleanly() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let full = special().full.clone();
    if full.is_none() {
        eprintln!("no full device of the tests' own: only closed pipes are tried");
    }
    let vdh = repo().join("validation/vdh_slab.toml").display().to_string();
    let cases: Vec<(Vec<&str>, u8, Option<&str>)> = vec![
        (vec!["check"], 1, None),
        (vec!["mie", "--m-real", "1.5", "--x", "1"], 1, None),
        (vec!["run", "--samples", "2000", "--out", "run"], 2, Some("run/manifest.json")),
        (vec!["converge", &vdh, "--samples", "4096", "--rungs", "2", "--out", "study"], 2, Some("study/converge.json")),
    ];
    for (args, stream, written) in cases {
        let sinks: Vec<(&str, Stdio)> = [
            Some(("a closed pipe", closed_pipe())),
            full.as_ref()
                .map(|f| ("a full device", Stdio::from(std::fs::OpenOptions::new().write(true).open(f).unwrap()))),
        ]
        .into_iter()
        .flatten()
        .collect();
        for (what, sink) in sinks {
            if let Some(w) = written {
                let _ = std::fs::remove_dir_all(t.join(w).parent().unwrap());
            }
            let o = with_stream(t, &args, stream, sink);
            assert_eq!(o.status.code(), Some(1), "{args:?}, stream {stream} to {what}: {}", describe(&o));
            assert!(!text(&o.stderr).contains("panicked"), "{}", describe(&o));
            if let Some(w) = written {
                assert!(t.join(w).is_file(), "{args:?}, stream {stream} to {what}: {w} not written");
            }
        }
    }
}

/// Finding 7: under a file-size limit a write fails as a write error (exit 1, the directory marked
/// incomplete), not SIGXFSZ; under an address-space limit too small for an image's tallies the
/// run is refused before it starts (exit 2 naming the budget and the limit), not aborted in the
/// allocator.
#[test]
fn resource_limits_end_in_errors_not_signals() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let canary = Canary::beside(&out);
    let mut args = small(&out);
    args.extend(["--set".into(), "detectors.0.image.pixels=[256, 256]".into()]);
    let o = sh_ohd(tmp.path(), "ulimit -f 64", &strs(&args));
    assert_eq!(o.status.code(), Some(1), "{}", describe(&o));
    assert!(text(&o.stderr).contains("File too large"), "{}", describe(&o));
    assert!(out.join("ohd_incomplete.txt").is_file());
    let mut args = small(&out);
    args.extend(["--set".into(), "detectors.0.image.pixels=[8192, 8192]".into()]);
    let o = sh_ohd(tmp.path(), "ulimit -v 1000000", &strs(&args));
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    let e = text(&o.stderr);
    assert!(e.contains("detectors") && e.contains("ulimit -v"), "{e}");
    assert!(canary.unchanged());
}

/// Finding 10: `ohd mie --table` never replaces what is not a regular file — a FIFO, a device
/// node, a link to either — (exit 2 naming it), and writes a regular file or a dangling link's
/// name as asked.
#[test]
fn devices_and_fifos_are_never_replaced() {
    let tmp = tempfile::tempdir().unwrap();
    let s = special();
    let mie = |table: &Path| {
        sh_ohd(
            tmp.path(),
            "",
            &["mie", "--m-real", "1.5", "--x", "1", "--angles", "16", "--table", table.to_str().unwrap()],
        )
    };
    let link = tmp.path().join("link");
    std::os::unix::fs::symlink(s.device_or_fifo(), &link).unwrap();
    for target in [s.fifo.as_path(), s.device_or_fifo(), &link] {
        let kind = std::fs::symlink_metadata(target).unwrap().file_type();
        let o = mie(target);
        assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
        assert!(text(&o.stderr).contains(target.to_str().unwrap()), "{}", describe(&o));
        assert_eq!(std::fs::symlink_metadata(target).unwrap().file_type(), kind, "{} replaced", target.display());
    }
    let o = mie(&tmp.path().join("table.toml"));
    assert!(o.status.success() && tmp.path().join("table.toml").is_file(), "{}", describe(&o));
}
