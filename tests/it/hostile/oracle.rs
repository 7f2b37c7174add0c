//! Running `ohd` on one hostile input and judging how it ended.
//!
//! The binary runs as a child process under a wall-time bound (killed and failed beyond it) and
//! an address-space limit ([`MEMORY_LIMIT_KIB`], set by `ulimit -v` in the `sh` that `exec`s it,
//! so that a runaway allocation aborts the child instead of taking the machine). The verdict:
//!
//! - exit 0: every `.npy` written is finite (but the `*_relative_error.npy` maps, NaN where a
//!   pixel has no signal by design, README "Outputs") and every manifest parses, with finite
//!   scalar estimates;
//! - exit 2: stderr names a configuration key, a command-line flag or a file (see
//!   [`names_key_or_file`]), not for running out of memory (an endless or huge input is
//!   refused for its size, before it fills the address space), and no watched file or
//!   directory changed;
//! - anything else (a panic's 101, an abort or other signal, a timeout, exit 1) fails.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::{Read, Seek};
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The child's address-space limit: 4 GiB, eight times what any run of the harness is allowed
/// for its tallies (`run.memory_budget_gib = 0.5` in runs).
pub const MEMORY_LIMIT_KIB: u64 = 4 << 20;

/// How a child ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Status {
    Exit(i32),
    Signal(i32),
    TimedOut,
}

pub struct Ended {
    pub status: Status,
    pub stdout: String,
    pub stderr: String,
    pub seconds: f64,
}

/// Run `ohd args…` in `cwd` with stdin closed, within `limit`.
pub fn exec(args: &[String], cwd: &Path, limit: Duration) -> Ended {
    let mut out = tempfile::tempfile().expect("a temporary file");
    let mut err = tempfile::tempfile().expect("a temporary file");
    let t0 = Instant::now();
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {MEMORY_LIMIT_KIB} 2>/dev/null; exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_ohd"))
        .args(args)
        .current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(out.try_clone().unwrap())
        .stderr(err.try_clone().unwrap())
        .spawn()
        .expect("sh starts");
    let mut pause = Duration::from_millis(1);
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait") {
            break match (s.code(), s.signal()) {
                (Some(c), _) => Status::Exit(c),
                (None, Some(sig)) => Status::Signal(sig),
                (None, None) => Status::Signal(-1),
            };
        }
        if t0.elapsed() > limit {
            child.kill().expect("SIGKILL");
            child.wait().expect("wait");
            break Status::TimedOut;
        }
        std::thread::sleep(pause);
        pause = (pause * 2).min(Duration::from_millis(20));
    };
    let seconds = t0.elapsed().as_secs_f64();
    let text = |f: &mut std::fs::File| {
        let mut b = Vec::new();
        f.rewind().unwrap();
        f.read_to_end(&mut b).unwrap();
        String::from_utf8_lossy(&b).into_owned()
    };
    Ended { status, stdout: text(&mut out), stderr: text(&mut err), seconds }
}

/// The command line, quoted for a shell.
pub fn shell(args: &[String]) -> String {
    let quote = |a: &str| {
        if !a.is_empty() && a.chars().all(|c| c.is_ascii_alphanumeric() || "-_./=:,+".contains(c)) {
            a.to_string()
        } else {
            format!("'{}'", a.replace('\'', r"'\''"))
        }
    };
    let shown: Vec<String> = args.iter().map(|a| quote(a)).collect();
    let line = format!("ohd {}", shown.join(" "));
    if line.chars().count() > 600 {
        format!("{}… ({} chars)", line.chars().take(560).collect::<String>(), line.len())
    } else {
        line
    }
}

/// Every file below `dir` (or `dir` itself if a file) with its size and a hash of its bytes; an
/// empty map if it does not exist.
pub fn snapshot(dir: &Path) -> BTreeMap<PathBuf, (u64, u64)> {
    use std::hash::{Hash, Hasher};
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(p) = stack.pop() {
        let Ok(meta) = std::fs::symlink_metadata(&p) else { continue };
        if meta.is_dir() {
            out.insert(p.clone(), (0, 0));
            for e in std::fs::read_dir(&p).into_iter().flatten().flatten() {
                stack.push(e.path());
            }
        } else {
            let mut h = std::collections::hash_map::DefaultHasher::new();
            if meta.is_file() {
                std::fs::read(&p).unwrap_or_default().hash(&mut h);
            }
            out.insert(p, (meta.len(), h.finish()));
        }
    }
    out
}

/// What an input must be refused with: the names any of which the message may give.
pub struct Names {
    /// Top-level configuration sections and keys a config error may start with.
    pub keys: Vec<String>,
    /// Files (or parts of their paths) and flags (`--samples`) the message may name.
    pub words: Vec<String>,
    /// Whether only `words` count (a corrupted file must be named itself).
    pub words_only: bool,
}

/// The sections of an experiment file (`ExperimentFile`); a config error's key path starts with
/// one of them.
pub const SECTIONS: &[&str] = &[
    "schema_version",
    "name",
    "description",
    "run",
    "source",
    "ambient",
    "media",
    "layers",
    "regions",
    "detectors",
    "wind",
    "reference",
    "volume",
    "lateral",
    "bottom",
    "opaque",
];

impl Names {
    /// A mutant configuration: any key path into it, a `--set`, or the file.
    pub fn config(doc: Option<&toml::Table>, files: &[&str]) -> Names {
        let mut keys: Vec<String> = SECTIONS.iter().map(|s| s.to_string()).collect();
        keys.extend(doc.into_iter().flat_map(|d| d.keys().cloned()));
        Names { keys, words: files.iter().map(|s| s.to_string()).collect(), words_only: false }
    }

    /// Only these words (a corrupted file's name, a flag).
    pub fn only(words: &[&str]) -> Names {
        Names { keys: Vec::new(), words: words.iter().map(|s| s.to_string()).collect(), words_only: true }
    }
}

/// Whether the first error line of `stderr` names a key, flag or file of `names`:
///
/// - `ohd: config error: PATH: …` with PATH a key path whose first segment is one of
///   `names.keys`, an unknown key the message names as such, `(top level)`, a `--set …`, or one
///   of `names.words` (the file, for syntax errors);
/// - `ohd: cannot read PATH: …` and `ohd: VDB file PATH…` with a path;
/// - any other `ohd: …` line that contains one of `names.words`;
/// - a command-line parser's (clap's) `error: …`, which quotes the argument it could not take
///   (`unexpected argument '-1' found`, `invalid value 'x' for '--seed <SEED>'`) or names the
///   missing one (`<DIR>`), on that line or the next.
///
/// With `names.words_only`, only the last two rules count.
pub fn names_key_or_file(stderr: &str, names: &Names) -> bool {
    let Some(line) = stderr.lines().find(|l| l.starts_with("ohd: ") || l.starts_with("error: ")) else {
        return false;
    };
    if names.words.iter().any(|w| !w.is_empty() && line.contains(w.as_str())) {
        return true;
    }
    if line.starts_with("error: ") {
        let next = stderr.lines().skip_while(|l| *l != line).nth(1).unwrap_or("");
        return line.contains('\'') || line.contains('<') || next.contains('<') || next.contains("--");
    }
    if names.words_only {
        return false;
    }
    if let Some(rest) = line.strip_prefix("ohd: config error: ") {
        let path = rest.split(": ").next().unwrap_or("");
        let first = path.split(['.', '[']).next().unwrap_or("");
        let last = path.rsplit(['.', ']']).next().unwrap_or("");
        return path == "(top level)"
            || path.starts_with("--set ")
            || (!first.is_empty() && names.keys.iter().any(|k| k == first))
            || (!last.is_empty() && rest.contains(&format!("unknown field `{last}`")));
    }
    for prefix in ["ohd: cannot read ", "ohd: VDB file "] {
        if let Some(rest) = line.strip_prefix(prefix) {
            return rest.contains('/') || rest.split(':').next().is_some_and(|p| p.contains('.'));
        }
    }
    false
}

/// Whether a config error names `key` (a dotted `--set` path) or a key above or below it.
pub fn names_the_key(stderr: &str, key: &str) -> bool {
    let Some(rest) = stderr.lines().find_map(|l| l.strip_prefix("ohd: config error: ")) else { return false };
    let path = rest.split(": ").next().unwrap_or("").replace('[', ".").replace(']', "");
    let (a, b): (Vec<&str>, Vec<&str>) = (path.split('.').collect(), key.split('.').collect());
    let n = a.len().min(b.len());
    n > 0 && a[..n] == b[..n]
}

/// Problems with the outputs of a run that exited 0 in `dir` (all of it, scans' pointings too).
pub fn output_problems(dir: &Path) -> Vec<String> {
    let mut problems = Vec::new();
    let mut manifests = 0;
    for (p, _) in snapshot(dir) {
        let name = p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let shown = p.strip_prefix(dir).unwrap_or(&p).display().to_string();
        if name.ends_with(".npy") {
            let Some((_, data)) = std::fs::read(&p).ok().and_then(|b| ohd::io::formats::npy::from_bytes(&b)) else {
                problems.push(format!("{shown} is not a readable .npy"));
                continue;
            };
            // NaN is documented where a value is undefined: a relative error of a zero value, a
            // correlation estimate from too few paths (`Output::undefined_nan`); never infinity.
            let stem = name.trim_end_matches(".npy").trim_end_matches("_stderr");
            let nan_documented = name.ends_with("_relative_error.npy")
                || ["_g1", "_g2", "_speckle_contrast", "_speckle_contrast_image"].iter().any(|s| stem.ends_with(s));
            let bad = data.iter().filter(|v| if nan_documented { v.is_infinite() } else { !v.is_finite() }).count();
            if bad > 0 {
                problems.push(format!("{shown}: {bad} of {} values not finite", data.len()));
            }
        } else if name == "manifest.json" {
            manifests += 1;
            let m: Option<serde_json::Value> = std::fs::read(&p).ok().and_then(|b| serde_json::from_slice(&b).ok());
            let Some(m) = m else {
                problems.push(format!("{shown} does not parse"));
                continue;
            };
            for k in ["reflectance_specular", "reflectance_diffuse", "transmittance_total", "absorbed_fraction"] {
                for f in ["value", "stderr"] {
                    if !m["estimates"][k][f].as_f64().is_some_and(f64::is_finite) {
                        problems.push(format!("{shown}: estimates.{k}.{f} = {}", m["estimates"][k][f]));
                    }
                }
            }
        } else if name.contains(".tmp") || name.starts_with('.') {
            problems.push(format!("{shown}: a temporary file left behind"));
        }
    }
    if dir.join("converge.json").exists() {
        if std::fs::read(dir.join("converge.json"))
            .ok()
            .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
            .is_none()
        {
            problems.push("converge.json does not parse".into());
        }
    } else if manifests == 0 && !dir.join("shard.ohd").exists() {
        problems.push("no manifest.json written".into());
    }
    problems
}

/// Files in run directory `dir` that its manifest does not list: left over from another run.
fn unlisted_files(dir: &Path) -> Vec<String> {
    let m: serde_json::Value =
        std::fs::read(dir.join("manifest.json")).ok().and_then(|b| serde_json::from_slice(&b).ok()).unwrap_or_default();
    let listed: Vec<&str> =
        m["files"].as_array().map(|a| a.iter().filter_map(|v| v.as_str()).collect()).unwrap_or_default();
    std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n != "manifest.json" && !listed.contains(&n.as_str()))
        .map(|n| format!("{n} is not the run's (a stale output)"))
        .collect()
}

/// Problems with `ohd mie`'s JSON on stdout.
fn json_problems(stdout: &str) -> Vec<String> {
    match serde_json::from_str::<serde_json::Value>(stdout.trim()) {
        Ok(serde_json::Value::Object(m)) => m
            .iter()
            .filter(|(_, v)| !v.as_f64().is_some_and(f64::is_finite))
            .map(|(k, v)| format!("stdout: {k} = {v}"))
            .collect(),
        _ => vec![format!("stdout is not a JSON object: {stdout:?}")],
    }
}

/// The non-finite detections a run that exited 0 counted (`run_statistics.non_finite` of its
/// manifests).
pub fn non_finite_detections(dir: &Path) -> u64 {
    snapshot(dir)
        .keys()
        .filter(|p| p.file_name().is_some_and(|n| n == "manifest.json"))
        .filter_map(|p| serde_json::from_slice::<serde_json::Value>(&std::fs::read(p).ok()?).ok())
        .filter_map(|m| m["run_statistics"]["non_finite"].as_u64())
        .sum()
}

/// One hostile case: what was done, the command, and what to expect.
pub struct Case<'a> {
    /// The category and case number, e.g. `config-check #17`.
    pub id: String,
    /// What was mutated or corrupted, for the reproducer.
    pub what: String,
    pub args: Vec<String>,
    pub cwd: &'a Path,
    pub limit: Duration,
    /// The run's output directory, checked on exit 0 (none for `ohd check`).
    pub out: Option<PathBuf>,
    /// Files and directories that must be as they were after an exit 2.
    pub watched: Vec<PathBuf>,
    pub names: Names,
    /// A `--set` key whose naming is counted (not required).
    pub key: Option<String>,
    /// Why the input must be refused (exit 2), if it must: a NaN in the experiment, say.
    pub must_refuse: Option<String>,
    /// An exit 1 naming one of `names.words` is right (an `--out` that cannot be written).
    pub exit1_ok: bool,
    /// On exit 0, stdout is one JSON object of finite numbers (`ohd mie`).
    pub stdout_json: bool,
    /// On exit 0, every file in `out` is one the manifest lists (no stale outputs of an
    /// earlier run).
    pub listed_only: bool,
    /// The case's input files: removed if it passes, kept for the reproducer if it fails.
    pub inputs: Option<PathBuf>,
    /// On exit 0, the run counted no non-finite detection (issue 52: surfaces at their extremes
    /// dropped every detection of a run that then exited 0 with a warning).
    pub finite_detections: bool,
}

impl<'a> Case<'a> {
    /// A case with no expectations beyond the oracle's.
    pub fn new(id: String, what: String, args: Vec<String>, cwd: &'a Path, limit: Duration, names: Names) -> Self {
        Case {
            id,
            what,
            args,
            cwd,
            limit,
            out: None,
            watched: vec![cwd.to_path_buf()],
            names,
            key: None,
            must_refuse: None,
            exit1_ok: false,
            stdout_json: false,
            listed_only: false,
            inputs: None,
            finite_detections: false,
        }
    }
}

/// Counts of one category and the failures' reproducers.
#[derive(Default)]
pub struct Tally {
    pub cases: usize,
    pub accepted: usize,
    pub refused: usize,
    /// Refusals whose config error named the mutated key (or one above or below it).
    pub refused_naming_key: usize,
    /// Refusals of a `--set` mutation (the denominator of `refused_naming_key`).
    pub refused_of_set: usize,
    /// Accepted runs that counted non-finite detections (finite outputs: not a failure).
    pub accepted_with_non_finite: usize,
    pub failures: BTreeMap<&'static str, usize>,
    pub reproducers: Vec<String>,
    /// The accepted runs that counted non-finite detections.
    pub notes: Vec<String>,
    pub seconds: f64,
    pub slowest: f64,
    pub slowest_case: String,
}

impl Tally {
    /// Run `case`, judge it, count it.
    pub fn run(&mut self, case: Case<'_>) {
        let before: Vec<_> = case.watched.iter().map(|p| snapshot(p)).collect();
        let e = exec(&case.args, case.cwd, case.limit);
        self.cases += 1;
        self.seconds += e.seconds;
        if e.seconds > self.slowest {
            self.slowest = e.seconds;
            self.slowest_case = case.id.clone();
        }
        let fail = |kind: &'static str, why: String, t: &mut Tally| {
            *t.failures.entry(kind).or_default() += 1;
            let mut r = String::new();
            let _ = writeln!(r, "[{}] {kind}: {why}", case.id);
            let _ = writeln!(r, "    input: {}", case.what);
            let _ = writeln!(r, "    $ {}", shell(&case.args));
            if let Some(d) = &case.inputs {
                let _ = writeln!(r, "    (inputs kept in {})", d.display());
            }
            let tail: Vec<&str> = e.stderr.lines().rev().take(4).collect();
            for l in tail.into_iter().rev() {
                let _ = writeln!(r, "    | {}", l.chars().take(300).collect::<String>());
            }
            t.reproducers.push(r);
        };
        let failures_before = self.reproducers.len();
        match e.status {
            Status::Exit(0) => {
                let mut problems = case.out.as_deref().map(output_problems).unwrap_or_default();
                if case.stdout_json {
                    problems.extend(json_problems(&e.stdout));
                }
                if case.listed_only {
                    problems.extend(case.out.as_deref().map(unlisted_files).unwrap_or_default());
                }
                if let Some(why) = &case.must_refuse {
                    fail("accepted, must be refused", why.clone(), self);
                } else if problems.is_empty() {
                    let n = case.out.as_deref().map_or(0, non_finite_detections);
                    if n > 0 && case.finite_detections {
                        fail("exit 0 with dropped detections", format!("{n} non-finite detections"), self);
                    } else if n > 0 {
                        self.accepted += 1;
                        self.accepted_with_non_finite += 1;
                        self.notes.push(format!("[{}] {n} non-finite detections: {}", case.id, case.what));
                    } else {
                        self.accepted += 1;
                    }
                } else {
                    fail("exit 0 with bad outputs", problems.join("; "), self);
                }
            }
            Status::Exit(2) => {
                let changed: Vec<String> = case
                    .watched
                    .iter()
                    .zip(&before)
                    .filter(|(p, b)| snapshot(p) != **b)
                    .map(|(p, _)| p.display().to_string())
                    .collect();
                if !names_key_or_file(&e.stderr, &case.names) {
                    fail("exit 2 naming no key or file", format!("expected one of {:?}", case.names.words), self);
                } else if e.stderr.contains("out of memory") {
                    // An endless or huge input filled the address space before it was refused.
                    fail("exit 2 out of memory", format!("after {:.1} s", e.seconds), self);
                } else if !changed.is_empty() {
                    fail("exit 2 but wrote", format!("changed: {}", changed.join(", ")), self);
                } else {
                    self.refused += 1;
                    if let Some(k) = &case.key {
                        self.refused_of_set += 1;
                        self.refused_naming_key += usize::from(names_the_key(&e.stderr, k));
                    }
                }
            }
            Status::Exit(1) if case.exit1_ok && names_key_or_file(&e.stderr, &case.names) => self.refused += 1,
            Status::Exit(101) => fail("panic", String::new(), self),
            Status::Exit(c) => fail("unexpected exit status", format!("exit {c}"), self),
            Status::Signal(s) => fail("killed by a signal", format!("signal {s} (6 = abort)"), self),
            Status::TimedOut => fail("timeout", format!("still running after {:?}", case.limit), self),
        }
        if self.reproducers.len() == failures_before {
            if let Some(d) = &case.inputs {
                let _ = std::fs::remove_dir_all(d);
            }
        }
    }

    /// One line of counts.
    pub fn summary(&self, category: &str) -> String {
        let failed: usize = self.failures.values().sum();
        let mut s = format!(
            "{category}: {} cases in {:.1} s (slowest {:.2} s, {}): {} exit 0, {} exit 2, {failed} failed",
            self.cases, self.seconds, self.slowest, self.slowest_case, self.accepted, self.refused
        );
        if self.refused_of_set > 0 {
            let _ = write!(
                s,
                "; {} of {} refused --set mutants named their key",
                self.refused_naming_key, self.refused_of_set
            );
        }
        if self.accepted_with_non_finite > 0 {
            let _ = write!(s, "; {} accepted runs counted non-finite detections", self.accepted_with_non_finite);
        }
        for (k, n) in &self.failures {
            let _ = write!(s, "; {k}: {n}");
        }
        s
    }

    /// Print the summary and fail with the reproducers if any case failed.
    pub fn finish(self, category: &str) {
        finish_all(vec![(category.to_string(), self)]);
    }
}

/// Print the summaries (and notes) of several tallies, then fail with the reproducers of all
/// their failing cases, if any.
pub fn finish_all(tallies: Vec<(String, Tally)>) {
    let mut summaries = Vec::new();
    let mut reproducers = Vec::new();
    for (category, t) in tallies {
        let summary = t.summary(&category);
        eprintln!("{summary}");
        for n in &t.notes {
            eprintln!("    note: {n}");
        }
        summaries.push(summary);
        reproducers.extend(t.reproducers);
    }
    if !reproducers.is_empty() {
        let shown = reproducers.len().min(40);
        panic!(
            "{}\n{} failing cases{}:\n{}",
            summaries.join("\n"),
            reproducers.len(),
            if shown < reproducers.len() { format!(" (the first {shown})") } else { String::new() },
            reproducers[..shown].join("")
        );
    }
}
