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

/// A command that runs until killed (far more paths than a test waits for), started in `cwd`.
fn endless(cwd: &Path, args: &[&str]) -> std::process::Child {
    Command::new(bin())
        .args(args)
        .current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

/// Wait (at most `seconds`) until `path` exists; whether it does.
fn wait_for(path: &Path, seconds: u64) -> bool {
    let t = Instant::now();
    while !path.exists() && t.elapsed() < Duration::from_secs(seconds) {
        std::thread::sleep(Duration::from_millis(5));
    }
    path.exists()
}

/// Issue 52, finding 2a: a scan holds the lock of each of its pointing directories, so a run into
/// `SCAN/pointing_00` while the scan writes `SCAN` is refused (a8c4817: both ended in exit 0, and
/// `scan.json` claimed a complete scan whose `pointing_00/` held the other experiment); and a scan
/// into `SCAN` while a run writes `SCAN/pointing_00` is refused. Both exit 2 naming the pointing
/// directory and the holder's process.
#[test]
fn a_scan_and_a_run_into_its_pointing_directory_exclude_each_other() {
    let tmp = tempfile::tempdir().unwrap();
    let scan = tmp.path().join("scan");
    let canary = Canary::beside(&scan);
    let wind = config("wind_sunny.toml");
    let long_scan = ["run", "-q", "--threads", "1", &wind, "--samples", "100000000", "--out", scan.to_str().unwrap()];
    let mut first = endless(tmp.path(), &long_scan);
    assert!(wait_for(&scan.join(".ohd-lock"), 60), "the scan did not start");
    // (The pointing directories are locked right after the scan's own; a8c4817 never locked them.)
    wait_for(&scan.join("pointing_00").join(".ohd-lock"), 10);
    let inner = scan.join("pointing_00");
    let nested = sh_ohd(tmp.path(), "", &strs(&small(&inner)));
    first.kill().unwrap();
    first.wait().unwrap();
    assert_eq!(nested.status.code(), Some(2), "{}", describe(&nested));
    let e = text(&nested.stderr);
    assert!(e.contains(inner.to_str().unwrap()) && e.contains(&format!("process {}", first.id())), "{e}");
    assert!(!inner.join("manifest.json").exists());

    let scan = tmp.path().join("scan2");
    let inner = scan.join("pointing_00");
    let long_run = ["run", "-q", "--threads", "1", "--samples", "100000000", "--out", inner.to_str().unwrap()];
    let mut first = endless(tmp.path(), &long_run);
    assert!(wait_for(&inner.join(".ohd-lock"), 60), "the run did not start");
    let outer = sh_ohd(tmp.path(), "", &["run", "-q", &wind, "--samples", "512", "--out", scan.to_str().unwrap()]);
    first.kill().unwrap();
    first.wait().unwrap();
    assert_eq!(outer.status.code(), Some(2), "{}", describe(&outer));
    let e = text(&outer.stderr);
    assert!(e.contains(inner.to_str().unwrap()) && e.contains(&format!("process {}", first.id())), "{e}");
    assert!(!scan.join("scan.json").exists() && !scan.join("pointing_01").exists());
    assert!(canary.unchanged());
}

/// Issue 52, finding 2b: the lock is the directory's own (`flock` on the directory held open), so
/// removing or replacing the `.ohd-lock` file mid-run releases nothing: a second run is still
/// refused naming the directory (a8c4817: it took a new lock file, both ended in exit 0 and the
/// first run's output was lost).
#[test]
fn a_removed_or_replaced_lock_file_still_locks() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let canary = Canary::beside(&out);
    let long_run = ["run", "-q", "--threads", "1", "--samples", "100000000", "--out", out.to_str().unwrap()];
    let mut first = endless(tmp.path(), &long_run);
    assert!(wait_for(&out.join(".ohd-lock"), 60), "the run did not start");
    std::fs::remove_file(out.join(".ohd-lock")).unwrap();
    let removed = sh_ohd(tmp.path(), "", &strs(&small(&out)));
    std::fs::write(out.join(".ohd-lock"), "1\n").unwrap();
    let replaced = sh_ohd(tmp.path(), "", &strs(&small(&out)));
    first.kill().unwrap();
    first.wait().unwrap();
    for o in [removed, replaced] {
        assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
        let e = text(&o.stderr);
        assert!(e.contains(out.to_str().unwrap()) && e.contains("in use"), "{e}");
    }
    assert!(!out.join("manifest.json").exists());
    assert!(canary.unchanged());
}

/// Issue 52, finding 2c: `ohd mie --table` (a lone file) never writes the lock's name, and never
/// into a directory another ohd holds: exit 2 naming it (a8c4817 replaced the held lock, and wrote
/// into the directory being written).
#[test]
fn a_lone_file_is_never_the_lock_nor_in_a_held_directory() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let canary = Canary::beside(&out);
    let mie = |table: &Path| {
        sh_ohd(
            tmp.path(),
            "",
            &["mie", "--m-real", "1.5", "--x", "1", "--angles", "32", "--table", table.to_str().unwrap()],
        )
    };
    let long_run = ["run", "-q", "--threads", "1", "--samples", "100000000", "--out", out.to_str().unwrap()];
    let mut first = endless(tmp.path(), &long_run);
    assert!(wait_for(&out.join(".ohd-lock"), 60), "the run did not start");
    let lock = std::fs::read_to_string(out.join(".ohd-lock")).unwrap();
    let on_lock = mie(&out.join(".ohd-lock"));
    let beside = mie(&out.join("table.txt"));
    let lock_after = std::fs::read_to_string(out.join(".ohd-lock")).unwrap_or_default();
    first.kill().unwrap();
    first.wait().unwrap();
    assert_eq!(lock_after, lock, "the lock was replaced");
    for o in [on_lock, beside] {
        assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
        let e = text(&o.stderr);
        assert!(e.contains(out.to_str().unwrap()) && e.contains(&format!("process {}", first.id())), "{e}");
    }
    assert!(!out.join("table.txt").exists());
    // With no holder, the lock's name is still not a lone file's; another name is.
    let free = tmp.path().join("free");
    std::fs::create_dir(&free).unwrap();
    let o = mie(&free.join(".ohd-lock"));
    assert_eq!(o.status.code(), Some(2), "{}", describe(&o));
    assert!(text(&o.stderr).contains(free.join(".ohd-lock").to_str().unwrap()), "{}", describe(&o));
    assert!(!free.join(".ohd-lock").exists());
    assert!(mie(&free.join("table.txt")).status.success());
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
        // The run's report is its result, on stdout; a study logs its runs on stderr and its
        // table on stdout.
        (vec!["run", "--samples", "2000", "--out", "run"], 1, Some("run/manifest.json")),
        (vec!["converge", &vdh, "--samples", "4096", "--rungs", "2", "--out", "study"], 1, Some("study/converge.json")),
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

// ---------------------------------------------------------------------------------------------
// The deep sweep of these classes (`cargo test --profile ci hostile:: -- --ignored`; counts in
// validation/README.md, "Hostile inputs"). Each case's verdict: an allowed exit status (never a
// panic's 101, a signal or a timeout), the canary beside the output directory and a directory of
// the user's elsewhere unchanged, the tests' own special files still special, no lock left.

/// The commands the sweeps run, each writing into `OUT` (replaced by the case's directory):
/// (what, arguments, the file that says the output is complete).
fn commands(shards: &Path) -> Vec<(&'static str, Vec<String>, &'static str)> {
    let own = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let sunny = config("wind_sunny.toml");
    let doc: toml::Table = std::fs::read_to_string(&sunny).unwrap().parse().unwrap();
    let mut scan = own(&["run", "-q", "--threads", "1", &sunny, "--samples", "512"]);
    for s in super::tiny(&doc) {
        scan.extend(["--set".into(), s]);
    }
    let vdh = repo().join("validation/vdh_slab.toml").display().to_string();
    vec![
        ("run", own(&["run", "-q", "--threads", "1", "--samples", "2000", "--out", "OUT"]), "manifest.json"),
        (
            "run with checkpoints",
            own(&["run", "-q", "--threads", "1", "--samples", "2000", "--checkpoint-seconds", "0", "--out", "OUT"]),
            "manifest.json",
        ),
        ("scan", [scan, own(&["--out", "OUT"])].concat(), "scan.json"),
        (
            "shard",
            own(&["run", "-q", "--threads", "1", "--samples", "2000", "--shard", "0/2", "--out", "OUT"]),
            "shard.ohd",
        ),
        (
            "merge",
            own(&[
                "merge",
                &shards.join("0").display().to_string(),
                &shards.join("1").display().to_string(),
                "--out",
                "OUT",
            ]),
            "manifest.json",
        ),
        (
            "converge",
            own(&["converge", "-q", &vdh, "--samples", "4096", "--rungs", "2", "--out", "OUT"]),
            "converge.json",
        ),
    ]
}

/// A sweep's temporary directory, holding two shards of the default experiment's small run (for
/// `merge`) in `shards/0` and `shards/1`.
fn with_shards() -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let shards = tmp.path().join("shards");
    make_shards(&shards);
    (tmp, shards)
}

/// Two shards of the default experiment's small run, in `dir/0` and `dir/1`.
fn make_shards(dir: &Path) {
    std::fs::create_dir_all(dir).unwrap();
    for i in 0..2 {
        let out = dir.join(i.to_string());
        let shard = format!("{i}/2");
        let o = sh_ohd(
            dir,
            "",
            &["run", "-q", "--threads", "1", "--samples", "2000", "--shard", &shard, "--out", out.to_str().unwrap()],
        );
        assert!(o.status.success(), "{}", describe(&o));
    }
}

fn with_out(args: &[String], out: &Path) -> Vec<String> {
    args.iter().map(|a| if a == "OUT" { out.display().to_string() } else { a.clone() }).collect()
}

/// A sweep's cases: counted by outcome, failures kept with their reproducers.
#[derive(Default)]
struct Sweep {
    cases: usize,
    by_status: std::collections::BTreeMap<String, usize>,
    failures: Vec<String>,
}

impl Sweep {
    /// Judge one ended case: `allowed` exit statuses, and `problems` found by the caller.
    fn judge(&mut self, what: &str, o: &Output, allowed: &[i32], mut problems: Vec<String>) {
        self.cases += 1;
        let status = match (o.status.code(), std::os::unix::process::ExitStatusExt::signal(&o.status)) {
            (Some(c), _) => format!("exit {c}"),
            (None, Some(s)) => format!("signal {s}"),
            _ => "unknown".into(),
        };
        *self.by_status.entry(status.clone()).or_default() += 1;
        if !o.status.code().is_some_and(|c| allowed.contains(&c)) {
            problems.push(format!("{status}, expected one of {allowed:?}"));
        }
        if text(&o.stderr).contains("panicked") {
            problems.push("panicked".into());
        }
        if !problems.is_empty() {
            self.failures.push(format!("{what}: {}\n{}", problems.join("; "), describe(o)));
        }
    }

    fn finish(self, class: &str) {
        eprintln!("{class}: {} cases, {:?}, {} failed", self.cases, self.by_status, self.failures.len());
        assert!(self.failures.is_empty(), "{}", self.failures.join("\n\n"));
    }
}

/// The user's things around an output directory, which no case may change: a canary file beside
/// it, a directory elsewhere (with its own manifest and files), and the tests' special files.
struct Around {
    canary: Canary,
    elsewhere: PathBuf,
    before: std::collections::BTreeMap<PathBuf, (u64, u64)>,
}

impl Around {
    fn new(root: &Path, out: &Path) -> Around {
        let canary = Canary::beside(out);
        let elsewhere = root.join("elsewhere");
        std::fs::create_dir_all(&elsewhere).unwrap();
        std::fs::write(elsewhere.join("manifest.json"), r#"{"ohd_version": "0", "files": ["keep.npy"]}"#).unwrap();
        std::fs::write(elsewhere.join("keep.npy"), "the user's").unwrap();
        let before = super::oracle::snapshot(&elsewhere);
        Around { canary, elsewhere, before }
    }

    fn problems(&self, out: &Path) -> Vec<String> {
        let mut p = vec![];
        if !self.canary.unchanged() {
            p.push("the canary beside the output directory changed".into());
        }
        if super::oracle::snapshot(&self.elsewhere) != self.before {
            p.push("a directory elsewhere changed".into());
        }
        let s = special();
        for f in [Some(&s.fifo), s.full.as_ref(), s.null.as_ref()].into_iter().flatten() {
            let m = std::fs::symlink_metadata(f).map(|m| m.file_type());
            if !m.is_ok_and(|t| {
                std::os::unix::fs::FileTypeExt::is_fifo(&t) || std::os::unix::fs::FileTypeExt::is_char_device(&t)
            }) {
                p.push(format!("{} is no longer special", f.display()));
            }
        }
        if out.join(".ohd-lock").exists() {
            p.push("the lock was left".into());
        }
        p
    }
}

/// Links at every name each command creates or removes (its outputs as a scratch run lists them,
/// the records, the marker, the checkpoint, the shard, the lock, their temporary names of the
/// process, the old probe, the scan's pointing directories), each pointing to the canary, the
/// directory elsewhere, the tests' FIFO or device, or nothing: exit 0 or 2, nothing outside
/// changed.
#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_planted_links() {
    let (tmp, shards) = with_shards();
    let mut sweep = Sweep::default();
    for (what, args, _) in commands(&shards) {
        let out = tmp.path().join("case").join("out");
        let scratch = tmp.path().join("scratch");
        let o = sh_ohd(tmp.path(), "", &strs(&with_out(&args, &scratch)));
        assert!(o.status.success(), "{what}: {}", describe(&o));
        let mut names: Vec<String> = walk_names(&scratch);
        std::fs::remove_dir_all(&scratch).unwrap();
        names.extend(
            ["ohd_incomplete.txt", "checkpoint.ohd", "shard.ohd", ".ohd-lock", "manifest.json"].map(String::from),
        );
        names.extend(["pointing_00", "pointing_01"].map(String::from));
        names.sort();
        names.dedup();
        let s = special();
        let targets: Vec<(&str, PathBuf)> = [
            ("the canary", None),
            ("a directory elsewhere", None),
            ("the FIFO", Some(s.fifo.clone())),
            ("the device", s.full.clone()),
            ("nothing", Some(tmp.path().join("nothing"))),
        ]
        .into_iter()
        .filter_map(|(k, p)| match k {
            "the canary" | "a directory elsewhere" => Some((k, PathBuf::new())),
            _ => p.map(|p| (k, p)),
        })
        .collect();
        for (kind, target) in &targets {
            // One case with every name planted at once, and one per name (its temporary too).
            // (The pointing directories are links in cases of their own: with them links, the
            // script would plant the names inside them into the directory they point to.)
            let every = names.iter().filter(|n| !n.starts_with("pointing_") || n.contains('/')).collect();
            let plans: Vec<Vec<&String>> = std::iter::once(every).chain(names.iter().map(|n| vec![n])).collect();
            for plan in plans {
                let _ = std::fs::remove_dir_all(tmp.path().join("case"));
                let around = Around::new(&tmp.path().join("case"), &out);
                let target = match *kind {
                    "the canary" => around.canary.path().to_path_buf(),
                    "a directory elsewhere" => around.elsewhere.clone(),
                    _ => target.clone(),
                };
                let mut script = format!("mkdir -p \"{}\"\n", out.display());
                for n in &plan {
                    let (dir, name) = match n.rsplit_once('/') {
                        Some((d, n)) => (out.join(d), n.to_string()),
                        None => (out.clone(), n.to_string()),
                    };
                    script.push_str(&format!("mkdir -p \"{}\"\n", dir.display()));
                    for at in [name.clone(), format!(".{name}.tmp-$$")] {
                        script.push_str(&format!("ln -sfn \"{}\" \"{}/{at}\"\n", target.display(), dir.display()));
                    }
                }
                script.push_str(&format!(
                    "ln -sfn \"{}\" \"{}/.ohd-write-probe-$$\"\n",
                    target.display(),
                    out.display()
                ));
                let o = sh_ohd(tmp.path(), &script, &strs(&with_out(&args, &out)));
                let label = format!(
                    "{what}, links to {kind} at {}",
                    if plan.len() > 1 { "every name".into() } else { plan[0].clone() }
                );
                sweep.judge(&label, &o, &[0, 2], around.problems(&out));
            }
        }
    }
    sweep.finish("planted links");
}

/// Files below a directory, relative to it, with their sizes and hashes.
type Files = std::collections::BTreeMap<PathBuf, (u64, u64)>;

/// The files below `dir` (not `dir` itself), by their paths relative to it.
fn relative(dir: &Path) -> Files {
    super::oracle::snapshot(dir)
        .into_iter()
        .map(|(p, h)| (p.strip_prefix(dir).unwrap().to_path_buf(), h))
        .filter(|(p, _)| !p.as_os_str().is_empty())
        .collect()
}

/// The names of the files below `dir`, relative to it (`pointing_00/manifest.json`).
fn walk_names(dir: &Path) -> Vec<String> {
    let mut names = vec![];
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let name = e.file_name().into_string().unwrap();
        if e.file_type().unwrap().is_dir() {
            names.extend(walk_names(&e.path()).into_iter().map(|n| format!("{name}/{n}")));
        } else {
            names.push(name);
        }
    }
    names
}

/// Two commands at once into one directory, the second started after a drawn delay (0 to 1.5 s),
/// over pairs of runs with different seeds, a run and a study, a run and a merge: each ends with
/// 0, or 2 naming the lock's holder; afterwards no lock is left, and a directory without the
/// marker holds exactly what its record lists, byte for byte one command's (its solo run's bytes).
#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_concurrent_commands() {
    let (tmp, shards) = with_shards();
    let cmds = commands(&shards);
    let find = |w: &str| cmds.iter().find(|c| c.0 == w).unwrap().1.clone();
    let run = |seed: &str| {
        // Long enough (about a second) that the second command starts while it runs.
        let args = ["run", "-q", "--threads", "1", "--samples", "100000", "--seed", seed, "--out", "OUT"];
        let set = ["--set", "detectors.0.image.pixels=[512, 512]"];
        args.iter().chain(&set).map(|s| s.to_string()).collect::<Vec<_>>()
    };
    let pairs: Vec<(&str, Vec<String>, Vec<String>)> = vec![
        ("run seed 1 / run seed 2", run("1"), run("2")),
        ("run / converge", run("1"), find("converge")),
        ("run / merge", run("1"), find("merge")),
        ("merge / merge", find("merge"), find("merge")),
    ];
    // What each command writes alone: its files' bytes.
    let solo = |args: &[String]| {
        let d = tmp.path().join("solo");
        let _ = std::fs::remove_dir_all(&d);
        let o = sh_ohd(tmp.path(), "", &strs(&with_out(args, &d)));
        assert!(o.status.success(), "{}", describe(&o));
        relative(&d)
    };
    let mut sweep = Sweep::default();
    for (what, a, b) in &pairs {
        let (sa, sb) = (solo(a), solo(b));
        for k in 0..8u64 {
            let out = tmp.path().join("case/out");
            let _ = std::fs::remove_dir_all(tmp.path().join("case"));
            let around = Around::new(&tmp.path().join("case"), &out);
            let spawn = |args: &[String]| {
                Command::new(bin())
                    .args(with_out(args, &out))
                    .stdout(Stdio::piped())
                    .stderr(Stdio::piped())
                    .spawn()
                    .unwrap()
            };
            let first = spawn(a);
            std::thread::sleep(Duration::from_millis(k * 200));
            let second = spawn(b);
            let (oa, ob) = (first.wait_with_output().unwrap(), second.wait_with_output().unwrap());
            let mut problems = around.problems(&out);
            if !out.join("ohd_incomplete.txt").exists() {
                let now = relative(&out);
                // Timings differ from run to run: records and figures are compared by name only.
                let timed =
                    |p: &Path| p.extension().is_some_and(|e| ["json", "png", "svg", "csv"].iter().any(|x| e == *x));
                let holds = |solo: &Files| solo.iter().all(|(p, h)| now.get(p).is_some_and(|n| timed(p) || n == h));
                let known = now.keys().all(|p| sa.contains_key(p) || sb.contains_key(p));
                if !(known && (holds(&sa) || holds(&sb))) {
                    problems.push("complete, but not one command's output (or a run and a study beside it)".into());
                }
            }
            for (o, who) in [(&oa, "first"), (&ob, "second")] {
                if o.status.code() == Some(2) && !text(&o.stderr).contains("in use") {
                    problems.push(format!("the {who} was refused, not for the lock"));
                }
            }
            sweep.judge(&format!("{what}, {} ms apart: first", k * 200), &oa, &[0, 2], problems);
            sweep.judge(&format!("{what}, {} ms apart: second", k * 200), &ob, &[0, 2], vec![]);
        }
    }
    sweep.finish("concurrent commands");
}

/// Each command into a small tmpfs (16 KiB to 4 MiB) mounted in the test's directory, where the
/// test may mount one (as root), else skipped with a message: exit 0, or 1 naming the full device's
/// error (2 if found before any work: nothing written); no temporary file left; a failed run's
/// directory marked incomplete or holding no record.
#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_full_disk() {
    let (tmp, shards) = with_shards();
    let mnt = tmp.path().join("mnt");
    std::fs::create_dir(&mnt).unwrap();
    let mut sweep = Sweep::default();
    for size in ["16k", "64k", "256k", "1m", "4m"] {
        let mount =
            Command::new("mount").args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"]).arg(&mnt).output();
        if !mount.as_ref().is_ok_and(|o| o.status.success()) {
            eprintln!("full disk: cannot mount a tmpfs here (not root, or no permission): class skipped");
            return;
        }
        for (what, args, record) in commands(&shards) {
            let out = mnt.join("out");
            let around = Around::new(&tmp.path().join("case"), &tmp.path().join("case/out"));
            let o = sh_ohd(tmp.path(), "", &strs(&with_out(&args, &out)));
            let mut problems = around.problems(&out);
            let left = walk_names(&mnt);
            if left.iter().any(|n| n.contains(".tmp-")) {
                problems.push(format!("temporary files left: {left:?}"));
            }
            if o.status.code() == Some(1) {
                if !text(&o.stderr).contains("No space left") {
                    problems.push("exit 1 without the device's error".into());
                }
                if out.join(record).exists() && !out.join("ohd_incomplete.txt").exists() {
                    problems.push("a failed write left a record without the marker".into());
                }
            }
            // Found before any work (a scan's pointing directories and their locks are made
            // first): refused as an unusable output directory, nothing written.
            if o.status.code() == Some(2) {
                if !text(&o.stderr).contains("No space left") {
                    problems.push("exit 2 without the device's error".into());
                }
                if out.join(record).exists() || out.join("ohd_incomplete.txt").exists() {
                    problems.push("refused after writing".into());
                }
            }
            sweep.judge(&format!("{what} into a {size} tmpfs"), &o, &[0, 1, 2], problems);
            let _ = std::fs::remove_dir_all(&out);
        }
        let umount = Command::new("umount").arg(&mnt).status().unwrap();
        assert!(umount.success(), "umount {}", mnt.display());
    }
    sweep.finish("full disk");
}

/// Every command with its standard output, error or both a closed pipe or (where the tests have
/// one) their own full device: exit 0 (nothing was said there) or 1, never a panic; a command's
/// outputs complete all the same.
#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_broken_streams() {
    let (tmp, shards) = with_shards();
    let mut cmds: Vec<(&str, Vec<String>, &str)> =
        commands(&shards).into_iter().map(|(w, a, r)| (w, a.into_iter().filter(|x| x != "-q").collect(), r)).collect();
    let own = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    cmds.push(("check", own(&["check"]), ""));
    cmds.push(("check scan", own(&["check", &config("wind_sunny.toml")]), ""));
    cmds.push(("mie", own(&["mie", "--m-real", "1.33", "--x", "20"]), ""));
    cmds.push((
        "mie --table",
        own(&["mie", "--m-real", "1.33", "--x", "20", "--angles", "64", "--table", "OUT.table"]),
        "",
    ));
    let full = special().full.clone();
    let mut sweep = Sweep::default();
    for (what, args, record) in &cmds {
        for streams in ["stdout", "stderr", "both"] {
            for sink in ["a closed pipe", "a full device"] {
                let make = || match sink {
                    "a closed pipe" => Some(closed_pipe()),
                    _ => full.as_ref().map(|f| Stdio::from(std::fs::OpenOptions::new().write(true).open(f).unwrap())),
                };
                let (Some(a), Some(b)) = (make(), make()) else { continue };
                let out = tmp.path().join("case/out");
                let _ = std::fs::remove_dir_all(tmp.path().join("case"));
                let around = Around::new(&tmp.path().join("case"), &out);
                let args: Vec<String> = args
                    .iter()
                    .map(|x| {
                        if x == "OUT.table" {
                            tmp.path().join("case/table.toml").display().to_string()
                        } else {
                            x.clone()
                        }
                    })
                    .collect();
                let mut c = Command::new(bin());
                c.args(with_out(&args, &out)).current_dir(tmp.path()).stdin(Stdio::null());
                match streams {
                    "stdout" => c.stdout(a).stderr(Stdio::piped()),
                    "stderr" => c.stderr(a).stdout(Stdio::piped()),
                    _ => c.stdout(a).stderr(b),
                };
                let o = c.output().unwrap();
                let mut problems = around.problems(&out);
                if !record.is_empty() && (!out.join(record).exists() || out.join("ohd_incomplete.txt").exists()) {
                    problems.push("the output is not complete".into());
                }
                sweep.judge(&format!("{what}, {streams} to {sink}"), &o, &[0, 1], problems);
            }
        }
    }
    sweep.finish("broken streams");
}

/// Resource limits: file sizes (`ulimit -f`, 512-byte blocks) from one block up, on every command;
/// address space (`ulimit -v`) from 200 MB up against images from 64² to 8192² pixels: exit 0, 1
/// ("File too large", the directory marked incomplete) or 2 (refused up front for the memory
/// budget), never a signal.
#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_resource_limits() {
    let (tmp, shards) = with_shards();
    let mut sweep = Sweep::default();
    for blocks in [1, 8, 64, 512, 4096, 32768] {
        for (what, args, record) in commands(&shards) {
            let out = tmp.path().join("case/out");
            let _ = std::fs::remove_dir_all(tmp.path().join("case"));
            let around = Around::new(&tmp.path().join("case"), &out);
            let o = sh_ohd(tmp.path(), &format!("ulimit -f {blocks}"), &strs(&with_out(&args, &out)));
            let mut problems = around.problems(&out);
            if o.status.code() == Some(1) && out.join(record).exists() && !out.join("ohd_incomplete.txt").exists() {
                problems.push("a failed write left a record without the marker".into());
            }
            sweep.judge(&format!("{what} under ulimit -f {blocks}"), &o, &[0, 1], problems);
        }
    }
    for kib in [200_000, 400_000, 800_000, 1_600_000, 3_200_000] {
        for pixels in [64, 1024, 2048, 4096, 8192] {
            let out = tmp.path().join("case/out");
            let _ = std::fs::remove_dir_all(tmp.path().join("case"));
            let around = Around::new(&tmp.path().join("case"), &out);
            let set = format!("detectors.0.image.pixels=[{pixels}, {pixels}]");
            let args =
                ["run", "-q", "--threads", "1", "--samples", "2000", "--set", &set, "--out", out.to_str().unwrap()];
            let o = sh_ohd(tmp.path(), &format!("ulimit -v {kib}"), &args);
            let problems = around.problems(&out);
            sweep.judge(&format!("{pixels}² image under ulimit -v {kib}"), &o, &[0, 2], problems);
        }
    }
    sweep.finish("resource limits");
}

/// The keys of `doc` (dotted, array elements by index) whose values set an axis, a range or a
/// step: where an extreme value can overflow a derived quantity (issue 33, item 8).
fn range_keys(doc: &toml::Table) -> Vec<String> {
    const RANGE: [&str; 14] = [
        "f_min",
        "f_max",
        "tau_min",
        "tau_max",
        "t_min",
        "t_max",
        "bandwidth",
        "duration",
        "frame_rate",
        "time_gate",
        "size",
        "bins",
        "points",
        "exposures",
    ];
    fn walk(v: &toml::Value, key: String, out: &mut Vec<String>) {
        match v {
            toml::Value::Table(t) => {
                t.iter().for_each(|(k, v)| walk(v, if key.is_empty() { k.clone() } else { format!("{key}.{k}") }, out))
            }
            toml::Value::Array(a) if a.iter().all(|x| x.is_table()) => {
                a.iter().enumerate().for_each(|(i, v)| walk(v, format!("{key}.{i}"), out))
            }
            _ => {
                let last = key.rsplit('.').next().unwrap_or_default();
                if RANGE.iter().any(|r| last.starts_with(r)) {
                    out.push(key);
                }
            }
        }
    }
    let mut out = vec![];
    walk(&toml::Value::Table(doc.clone()), String::new(), &mut out);
    out
}

/// Extreme values for a range key holding `v`: the issue's overflowing ends and their kin.
fn extremes(v: &toml::Value) -> Vec<String> {
    let scalars = ["1.7e308", "-1.7e308", "5e-324", "1e-160", "1e160", "1e300", "-1e300", "0"];
    match v {
        toml::Value::Integer(_) => ["0", "1", "4294967296", "9223372036854775807"].map(String::from).to_vec(),
        toml::Value::Array(a) => {
            let n = a.len().max(1);
            scalars
                .iter()
                .map(|s| format!("[{}]", vec![*s; n].join(", ")))
                .chain([format!("[{}]", ["5e-324", "1.7e308"][..n.min(2)].join(", "))])
                .collect()
        }
        _ => scalars.map(String::from).to_vec(),
    }
}

/// Overflowing ranges over every range key of the shipped experiments (`quick`: the issue's
/// keys of the configs that have them; else every key, each extreme): `ohd check` exits 2
/// naming the key, or 0 — and then a tiny run exits 0 with finite outputs or 2 naming it.
fn overflowing_ranges(quick: bool) {
    let category = if quick { "ranges-quick" } else { "ranges-deep" };
    let scratch = tempfile::tempdir().unwrap();
    let cwd = scratch.path().join("cwd");
    std::fs::create_dir(&cwd).unwrap();
    let mut tally = super::oracle::Tally::default();
    for config in super::shipped_configs() {
        let name = config.file_name().unwrap().to_string_lossy().into_owned();
        if super::costly(&config) {
            continue;
        }
        let doc: toml::Table = std::fs::read_to_string(&config).unwrap().parse().unwrap();
        for key in range_keys(&doc) {
            let quick_key = ["tau_min", "f_min", "f_max", "bandwidth"]
                .iter()
                .any(|k| key.rsplit('.').next().unwrap_or_default().starts_with(k));
            if quick && !quick_key {
                continue;
            }
            let mut value = toml::Value::Table(doc.clone());
            for part in key.split('.') {
                value = match value {
                    toml::Value::Table(t) => t[part].clone(),
                    toml::Value::Array(a) => a[part.parse::<usize>().unwrap()].clone(),
                    v => v,
                };
            }
            let values = extremes(&value);
            let values = if quick { values[..3].to_vec() } else { values };
            for v in values {
                let out = scratch.path().join("out");
                let set = format!("{key}={v}");
                let mut args =
                    vec!["run".to_string(), super::path_str(&config), "-q".into(), "--threads".into(), "1".into()];
                args.extend(["--samples".into(), super::RUN_SAMPLES.into(), "--out".into(), super::path_str(&out)]);
                for s in super::tiny(&doc).into_iter().chain([set.clone()]) {
                    args.extend(["--set".into(), s]);
                }
                let mut case = super::oracle::Case::new(
                    format!("{category} {name} {set}"),
                    format!("{name} --set {set}"),
                    args,
                    &cwd,
                    super::RUN_LIMIT,
                    super::oracle::Names::config(Some(&doc), &[&name]),
                );
                case.out = Some(out.clone());
                case.watched.push(out.clone());
                case.key = Some(key.clone());
                tally.run(case);
                let _ = std::fs::remove_dir_all(&out);
            }
        }
    }
    tally.finish(category);
}

/// Finding 8, quick: the issue's overflowing keys (delays, spectrum edges, chirp bandwidth) at
/// three extremes each, on every shipped experiment that has them.
#[test]
fn overflowing_ranges_are_refused_or_run_finite() {
    overflowing_ranges(true);
}

#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_overflowing_ranges() {
    overflowing_ranges(false);
}

/// What a case of [`deep_nested_and_unlocked_outputs`] does to the holder's locks before the
/// second command starts.
#[derive(Debug, Clone, Copy)]
enum Tamper {
    Nothing,
    /// `.ohd-lock` of the directory removed.
    RemoveLock,
    /// `.ohd-lock` of the pointing directory removed.
    RemovePointingLock,
    /// `.ohd-lock` replaced by a regular file naming another process.
    ReplaceLock,
    /// `.ohd-lock` replaced by a link to the canary.
    LinkLock,
}

/// A snapshot without the locks' own entries.
fn but_locks(s: &std::collections::BTreeMap<PathBuf, (u64, u64)>) -> Vec<(PathBuf, (u64, u64))> {
    s.iter().filter(|(p, _)| !p.ends_with(".ohd-lock")).map(|(p, v)| (p.clone(), *v)).collect()
}

/// Nested and unlocked outputs (issue 52, finding 2): while a scan writes `SCAN` (a long one, held
/// until the second command has ended), each lock tampered with as [`Tamper`] says, a second
/// command aims at `SCAN` or inside it — a run into `SCAN` and into each `pointing_NN`, a study
/// and a merge into a pointing, `ohd mie --table` onto the locks and into a pointing — and the
/// other way round, a scan into `X` while a run writes `X/pointing_0K`. The second must be refused
/// (exit 2, "in use"), having written nothing into the holder's directories; the canary beside
/// and a directory elsewhere stay as they were.
#[test]
#[ignore = "deep sweep, minutes: cargo test --profile ci hostile:: -- --ignored"]
fn deep_nested_and_unlocked_outputs() {
    let (tmp, shards) = with_shards();
    let cmds = commands(&shards);
    let find = |w: &str| cmds.iter().find(|c| c.0 == w).unwrap().1.clone();
    let wind = config("wind_sunny.toml");
    let endless_scan = |out: &Path| {
        ["run", "-q", "--threads", "1", wind.as_str(), "--samples", "100000000", "--out", out.to_str().unwrap()]
            .iter()
            .map(|s| s.to_string())
            .collect::<Vec<_>>()
    };
    let mie = |table: &str| -> Vec<String> {
        ["mie", "--m-real", "1.5", "--x", "1", "--angles", "32", "--table", table]
            .iter()
            .map(|s| s.to_string())
            .collect()
    };
    // (what, the second command with OUT for its target, the target relative to SCAN)
    let mut seconds: Vec<(String, Vec<String>, String)> = vec![("run".into(), find("run"), String::new())];
    for p in 0..4 {
        seconds.push((format!("run into pointing_0{p}"), find("run"), format!("pointing_0{p}")));
    }
    seconds.push(("converge into pointing_00".into(), find("converge"), "pointing_00".into()));
    seconds.push(("merge into pointing_01".into(), find("merge"), "pointing_01".into()));
    seconds.push(("mie --table onto the lock".into(), mie("OUT"), ".ohd-lock".into()));
    seconds.push(("mie --table onto pointing_02's lock".into(), mie("OUT"), "pointing_02/.ohd-lock".into()));
    seconds.push(("mie --table into pointing_03".into(), mie("OUT"), "pointing_03/table.txt".into()));
    let tampers =
        [Tamper::Nothing, Tamper::RemoveLock, Tamper::RemovePointingLock, Tamper::ReplaceLock, Tamper::LinkLock];
    let tamper = |dir: &Path, inner: &Path, t: Tamper, canary: &Path| match t {
        Tamper::Nothing => {}
        Tamper::RemoveLock => drop(std::fs::remove_file(dir.join(".ohd-lock"))),
        Tamper::RemovePointingLock => drop(std::fs::remove_file(inner.join(".ohd-lock"))),
        Tamper::ReplaceLock => {
            let _ = std::fs::remove_file(dir.join(".ohd-lock"));
            std::fs::write(dir.join(".ohd-lock"), "1\n").unwrap();
        }
        Tamper::LinkLock => {
            let _ = std::fs::remove_file(dir.join(".ohd-lock"));
            std::os::unix::fs::symlink(canary, dir.join(".ohd-lock")).unwrap();
        }
    };
    let mut sweep = Sweep::default();
    let mut k = 0;
    for (what, args, target) in &seconds {
        for &t in &tampers {
            k += 1;
            let root = tmp.path().join(format!("case{k}"));
            let scan = root.join("scan");
            let around = Around::new(&root, &scan);
            let mut first = endless(tmp.path(), &strs(&endless_scan(&scan)));
            let started = wait_for(&scan.join("pointing_03").join(".ohd-lock"), 60);
            let inner =
                scan.join(target.split('/').next().filter(|p| p.starts_with("pointing_")).unwrap_or("pointing_00"));
            tamper(&scan, &inner, t, around.canary.path());
            let before = super::oracle::snapshot(&scan);
            let aim = if target.is_empty() { scan.clone() } else { scan.join(target) };
            let o = sh_ohd(tmp.path(), "", &strs(&with_out(args, &aim)));
            let after = super::oracle::snapshot(&scan);
            first.kill().unwrap();
            first.wait().unwrap();
            let mut problems = Vec::new();
            if !started {
                problems.push("the scan did not start within 60 s".into());
            }
            let e = text(&o.stderr);
            if o.status.code() == Some(2) && !(e.contains("in use") || e.contains(".ohd-lock")) {
                problems.push("refused, but not for the lock".into());
            }
            // Only the locks' own names may have changed (a link planted there is replaced).
            if but_locks(&before) != but_locks(&after) {
                problems.push("wrote into the scan's directories".into());
            }
            if !around.canary.unchanged() {
                problems.push("the canary changed".into());
            }
            if super::oracle::snapshot(&around.elsewhere) != around.before {
                problems.push("a directory elsewhere changed".into());
            }
            sweep.judge(&format!("scan holds SCAN, {t:?}, then {what}"), &o, &[2], problems);
            let _ = std::fs::remove_dir_all(&root);
        }
    }
    // The other way round: a run holds X/pointing_0K, then a scan into X.
    for p in 0..4 {
        for t in [Tamper::Nothing, Tamper::RemovePointingLock, Tamper::LinkLock] {
            k += 1;
            let root = tmp.path().join(format!("case{k}"));
            let scan = root.join("x");
            let inner = scan.join(format!("pointing_0{p}"));
            let around = Around::new(&root, &scan);
            let long_run = ["run", "-q", "--threads", "1", "--samples", "100000000", "--out", inner.to_str().unwrap()];
            let mut first = endless(tmp.path(), &long_run);
            let started = wait_for(&inner.join(".ohd-lock"), 60);
            // The run's lock is its directory's: tamper with it there.
            tamper(
                &inner,
                &inner,
                if matches!(t, Tamper::RemovePointingLock) { Tamper::RemoveLock } else { t },
                around.canary.path(),
            );
            let before = super::oracle::snapshot(&inner);
            let o = sh_ohd(tmp.path(), "", &strs(&with_out(&find("scan"), &scan)));
            let after = super::oracle::snapshot(&inner);
            first.kill().unwrap();
            first.wait().unwrap();
            let mut problems = Vec::new();
            if !started {
                problems.push("the run did not start within 60 s".into());
            }
            if o.status.code() == Some(2) && !text(&o.stderr).contains("in use") {
                problems.push("refused, but not for the lock".into());
            }
            if but_locks(&before) != but_locks(&after) {
                problems.push("wrote into the run's directory".into());
            }
            if scan.join("scan.json").exists() {
                problems.push("scan.json written".into());
            }
            if !around.canary.unchanged() {
                problems.push("the canary changed".into());
            }
            sweep.judge(&format!("a run holds pointing_0{p}, {t:?}, then a scan"), &o, &[2], problems);
            let _ = std::fs::remove_dir_all(&root);
        }
    }
    sweep.finish("nested and unlocked outputs");
}
