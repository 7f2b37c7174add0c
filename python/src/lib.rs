//! `ohd._ohd`: the extension module under the `ohd` Python package (python/ohd/__init__.py holds
//! the public API and its documentation). It is thin: configurations are loaded and runs made by
//! the library exactly as the CLI does (`ohd::run`), a run's files are collected in memory by
//! `ohd::io::write::manifest::write_run_memory` (the bytes `ohd run --out` writes) and written by
//! `ohd::io::write::memory::save` and `save_scan` (the CLI's atomic directory writer). No panic crosses into
//! Python: every entry point catches unwinding and raises RuntimeError.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Condvar, Mutex};
use std::time::Duration;

use ohd::error::Error;
use ohd::experiment::Progress;
use ohd::run::{Event, Finished, Loaded, Observer, RunRequest};
use pyo3::exceptions::{PyKeyboardInterrupt, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

pyo3::create_exception!(ohd, ConfigError, PyValueError, "An invalid experiment description (`.key`: the key path).");

/// How often the thread holding the GIL looks for Ctrl-C and reports progress while a run goes on.
const POLL: Duration = Duration::from_millis(50);

/// A library error as the Python exception the package documents.
fn to_py(e: Error) -> PyErr {
    let text = e.to_string();
    match e {
        Error::Config(c) => {
            let err = ConfigError::new_err(text);
            Python::attach(|py| {
                let _ = err.value(py).setattr("key", c.path);
            });
            err
        }
        Error::Read { path, source } | Error::Write { path, source } => os_error(text, Some(path), &source),
        Error::Refused { path, .. } => os_error(text, Some(path), &std::io::Error::other("refused")),
        Error::Vdb(v) => os_error(text, Some(v.path), &std::io::Error::from(std::io::ErrorKind::InvalidData)),
        Error::Input(_) => PyValueError::new_err(text),
        Error::Cancelled => PyKeyboardInterrupt::new_err(text),
        _ => PyRuntimeError::new_err(text),
    }
}

/// `OSError(errno, message, filename)`: Python picks the subclass from the errno
/// (FileNotFoundError, PermissionError, IsADirectoryError, …).
fn os_error(text: String, path: Option<PathBuf>, source: &std::io::Error) -> PyErr {
    use std::io::ErrorKind as K;
    // The errno where the OS gave none (ohd's own checks), from the kind: the values are POSIX's.
    let errno = source.raw_os_error().or(match source.kind() {
        K::NotFound => Some(2),
        K::PermissionDenied => Some(13),
        K::AlreadyExists => Some(17),
        K::IsADirectory => Some(21),
        K::NotADirectory => Some(20),
        K::InvalidData | K::InvalidInput => Some(22),
        _ => None,
    });
    let filename = path.map(|p| p.display().to_string());
    match errno {
        Some(n) => PyOSError::new_err((n, text, filename)),
        None => PyOSError::new_err(text),
    }
}

/// `f()` with a panic turned into RuntimeError.
fn guarded<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|p| Err(panic_error(p)))
}

fn panic_error(p: Box<dyn std::any::Any + Send>) -> PyErr {
    let what = p
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into());
    PyRuntimeError::new_err(format!("ohd: internal error (please report it with the configuration): {what}"))
}

/// The deepest nesting of dicts, lists (and NumPy values' `tolist()`) a configuration value may
/// have. A TOML experiment is a handful of levels deep (`detectors[0].ldh.roi[1].center_mm` is
/// five); the bound ends the conversion's recursion long before the native stack does (issue 33,
/// item 9: a dict nested 30 000 levels deep overflowed the stack and killed the interpreter).
const MAX_DEPTH: usize = 64;

/// A Python value of a configuration dict as TOML (key path for errors). A dict or list that
/// contains itself (a reference cycle) and nesting deeper than [`MAX_DEPTH`] are configuration
/// errors naming the key path where they were found.
fn to_toml(v: &Bound<'_, PyAny>, key: &str) -> PyResult<toml::Value> {
    to_toml_in(v, key, &mut Vec::new())
}

/// `ConfigError("config error: KEY: WHAT")` with `.key` = `key`.
fn key_error(key: &str, what: &str) -> PyErr {
    let err = ConfigError::new_err(format!("config error: {key}: {what}"));
    Python::attach(|py| {
        let _ = err.value(py).setattr("key", key);
    });
    err
}

/// [`to_toml`] inside the containers `open` (their ids, outermost first: the path from the root
/// to `v`).
fn to_toml_in(v: &Bound<'_, PyAny>, key: &str, open: &mut Vec<usize>) -> PyResult<toml::Value> {
    let bad = |what: String| key_error(key, &what);
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return v.extract::<i64>().map(toml::Value::Integer).map_err(|_| bad("an integer beyond 64 bits".into()));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    let is_dict = v.is_instance_of::<PyDict>();
    let is_list = v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>();
    // A container (or a NumPy value, whose `tolist()` is one): a level deeper.
    if !(is_dict || is_list || v.hasattr("tolist")?) {
        return Err(bad(format!(
            "a value of type {} (expected a number, string, bool, list or dict)",
            v.get_type().name()?
        )));
    }
    let id = v.as_ptr() as usize;
    if open.contains(&id) {
        return Err(bad("a dict or list that contains itself (a reference cycle): expected a tree of values".into()));
    }
    if open.len() >= MAX_DEPTH {
        return Err(bad(format!("nested more than {MAX_DEPTH} levels deep: expected a configuration of a few levels")));
    }
    open.push(id);
    let value = container_to_toml(v, key, open, is_dict);
    open.pop();
    value
}

/// The dict, list, tuple or NumPy value `v` of [`to_toml_in`], its id last in `open`.
fn container_to_toml(v: &Bound<'_, PyAny>, key: &str, open: &mut Vec<usize>, is_dict: bool) -> PyResult<toml::Value> {
    if is_dict {
        let d = v.cast::<PyDict>()?;
        let mut t = toml::Table::new();
        for (k, val) in d.iter() {
            let k: String = k.extract().map_err(|_| key_error(key, "a table with a key that is not a string"))?;
            let path = if key.is_empty() { k.clone() } else { format!("{key}.{k}") };
            if val.is_none() {
                continue; // None: the key left out (its default)
            }
            t.insert(k, to_toml_in(&val, &path, open)?);
        }
        return Ok(toml::Value::Table(t));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let mut a = Vec::new();
        for (i, item) in v.try_iter()?.enumerate() {
            a.push(to_toml_in(&item?, &format!("{key}[{i}]"), open)?);
        }
        return Ok(toml::Value::Array(a));
    }
    // NumPy scalars and arrays: their Python values.
    to_toml_in(&v.call_method0("tolist")?, key, open)
}

/// The memory budget of a run whose `run.memory_budget_gib` is `gib` (None: its default), in
/// bytes, lowered as the library lowers it under a process limit, and the key as its messages
/// name it: for checking NumPy volumes before they are handed over.
#[pyfunction]
#[pyo3(signature = (gib=None))]
fn memory_budget(gib: Option<f64>) -> PyResult<(u64, String)> {
    guarded(|| {
        use ohd::config::resolve::{DEFAULT_MEMORY_BUDGET_GIB, budget_key, lowered_budget};
        let (bytes, limited_by) = lowered_budget(gib.unwrap_or(DEFAULT_MEMORY_BUDGET_GIB));
        Ok((bytes, budget_key(limited_by)))
    })
}

/// An override value `v` as the text after `KEY=` of `--set` (TOML).
#[pyfunction]
fn toml_value(v: &Bound<'_, PyAny>, key: &str) -> PyResult<String> {
    guarded(|| {
        Ok(match to_toml(v, key)? {
            toml::Value::Table(t) => {
                // An inline table: `--set` parses `v = {…}`.
                let doc = toml::to_string(&toml::Table::from_iter([("v".to_string(), toml::Value::Table(t))]))
                    .map_err(|e| PyValueError::new_err(e.to_string()))?;
                let inline: toml::Table =
                    doc.parse().map_err(|e: toml::de::Error| PyValueError::new_err(e.to_string()))?;
                inline["v"].to_string()
            }
            other => other.to_string(),
        })
    })
}

/// A run's files `(name, bytes)`, the manifest last.
type Files = Vec<(String, Py<PyBytes>)>;

/// A configuration read and resolved (`ohd.check` prints it).
#[pyclass(frozen, module = "ohd._ohd")]
struct Experiment {
    loaded: Loaded,
}

#[pymethods]
impl Experiment {
    /// What `ohd check` prints.
    fn __str__(&self) -> String {
        format!("experiment \"{}\" from {}: valid\n{}", self.loaded.exp.name, self.loaded.origin, self.loaded.exp)
    }

    fn __repr__(&self) -> String {
        format!("<ohd.Experiment \"{}\" from {}>", self.loaded.exp.name, self.loaded.origin)
    }

    /// The experiment's name.
    #[getter]
    fn name(&self) -> String {
        self.loaded.exp.name.clone()
    }

    /// The configuration as run (overrides applied), as TOML text.
    #[getter]
    fn toml(&self) -> String {
        toml::to_string(&self.loaded.table).unwrap_or_default()
    }

    /// Paths per run.
    #[getter]
    fn samples(&self) -> u64 {
        self.loaded.exp.plan.samples()
    }

    /// The number of pointings: more than 1 for a scan (run into a directory, one per pointing).
    #[getter]
    fn pointings(&self) -> usize {
        self.loaded.exp.source.pointings.len().max(1)
    }

    /// Run it; returns `(manifest JSON text, [(file name, bytes)], stopped)`, the manifest last;
    /// `stopped`: Ctrl-C was pressed (the run then ended early, `manifest.interrupted`, unless it
    /// had traced its paths already).
    #[pyo3(signature = (figures, report=None))]
    fn run(&self, py: Python<'_>, figures: bool, report: Option<Py<PyAny>>) -> PyResult<(String, Files, bool)> {
        let loaded = &self.loaded;
        let exp = &loaded.exp;
        let ((manifest, files), stopped) = watched(py, exp.plan.samples(), report.as_ref(), Keep::Work, |progress| {
            let output = exp.run_resumable(&ohd::experiment::Decisions::default(), progress, None, None, None)?;
            let inv = ohd::io::write::manifest::Invocation { figures, ..loaded.invocation() };
            let (_, memory) = ohd::io::write::manifest::write_run_memory(
                exp,
                &output,
                &loaded.table,
                &inv,
                &ohd::experiment::Silent,
            )?;
            let files = memory.files;
            let manifest = files.last().map(|(_, b)| String::from_utf8_lossy(b).into_owned()).unwrap_or_default();
            Ok((manifest, files))
        })?;
        // Each file's bytes move into one Python bytes object (the arrays view them, uncopied).
        let files = files.into_iter().map(|(n, b)| (n, PyBytes::new(py, &b).unbind())).collect();
        Ok((manifest, files, stopped))
    }

    /// Run it as `ohd run --out dir` does (a scan: every pointing and the scan's own outputs); returns
    /// whether Ctrl-C was pressed (the run then ended early and wrote what it had, as the CLI's).
    #[pyo3(signature = (dir, figures, report=None))]
    fn run_to_dir(&self, py: Python<'_>, dir: PathBuf, figures: bool, report: Option<Py<PyAny>>) -> PyResult<bool> {
        let req = RunRequest { dir, no_figures: !figures, ..Default::default() };
        let total = self.loaded.exp.plan.samples() * self.pointings() as u64;
        let (_, stopped) = watched(py, total, report.as_ref(), Keep::Work, |progress| {
            let obs = Watching { progress };
            match ohd::run::run(&self.loaded, &req, &obs) {
                Ok(Finished::Run(_) | Finished::Scan { .. } | Finished::Shards(_)) => Ok(()),
                // Written, with its checkpoint: told as `stopped`.
                Err(Error::Interrupted { .. }) => Ok(()),
                Err(e) => Err(e),
            }
        })?;
        Ok(stopped)
    }
}

/// Progress shared between the run and the thread holding the GIL.
struct Shared {
    done: AtomicU64,
    total: AtomicU64,
    /// Set by the first Ctrl-C of a run ([`Keep::Work`]): it ends at its next batch boundary.
    stop: AtomicBool,
    cancel: AtomicBool,
}

/// What the first Ctrl-C does to the work [`watched`] runs.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Keep {
    /// A run ends at its next batch boundary and returns what it has (`Progress::stopping`);
    /// the second Ctrl-C cancels it.
    Work,
    /// The work is cancelled (a convergence study: a rung cut short is no rung).
    Nothing,
}

impl Progress for Shared {
    fn advance(&self, paths: u64) {
        self.done.fetch_add(paths, Ordering::Relaxed);
    }
    fn set_total(&self, paths: u64) {
        self.total.store(paths, Ordering::Relaxed);
    }
    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }
    fn stopping(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }
}

/// Progress of the runs of a scan: one counter over all pointings.
struct Forward<'a>(&'a Shared);

impl Progress for Forward<'_> {
    fn advance(&self, paths: u64) {
        self.0.advance(paths);
    }
    fn cancelled(&self) -> bool {
        self.0.cancelled()
    }
    fn stopping(&self) -> bool {
        self.0.stopping()
    }
}

struct Watching<'a> {
    progress: &'a Shared,
}

impl Observer for Watching<'_> {
    fn progress(&self, _paths: u64, _target: Option<f64>) -> Box<dyn Progress + '_> {
        Box::new(Forward(self.progress))
    }
    fn event(&self, _event: Event<'_>) {}
}

/// Run `work` on a thread of its own with the GIL released, while this thread looks for Ctrl-C
/// (`check_signals`) and calls `report(done, total)` every [`POLL`]. With [`Keep::Work`] the first
/// KeyboardInterrupt asks the run to stop at its next batch boundary and keep its work (returned
/// with `true`: Ctrl-C was pressed), the second cancels it; with [`Keep::Nothing`] the first
/// cancels. A cancelled run stops within a few thousand paths and raises the KeyboardInterrupt.
fn watched<T: Send>(
    py: Python<'_>,
    total: u64,
    report: Option<&Py<PyAny>>,
    keep: Keep,
    work: impl FnOnce(&Shared) -> ohd::error::Result<T> + Send,
) -> PyResult<(T, bool)> {
    let shared = Shared {
        done: AtomicU64::new(0),
        total: AtomicU64::new(total),
        stop: AtomicBool::new(false),
        cancel: AtomicBool::new(false),
    };
    let mut stopped = false;
    let finished = (Mutex::new(false), Condvar::new());
    let result = std::thread::scope(|s| -> PyResult<Option<std::thread::Result<ohd::error::Result<T>>>> {
        let handle = s.spawn(|| {
            let r = catch_unwind(AssertUnwindSafe(|| work(&shared)));
            *finished.0.lock().unwrap_or_else(|e| e.into_inner()) = true;
            finished.1.notify_all();
            r
        });
        let mut interrupted = None;
        loop {
            let over = py.detach(|| {
                let guard = finished.0.lock().unwrap_or_else(|e| e.into_inner());
                let (guard, _) = finished.1.wait_timeout_while(guard, POLL, |f| !*f).unwrap_or_else(|e| e.into_inner());
                *guard
            });
            if over {
                break;
            }
            if let Err(e) = py.check_signals() {
                if keep == Keep::Work && !stopped && e.is_instance_of::<PyKeyboardInterrupt>(py) {
                    shared.stop.store(true, Ordering::Relaxed);
                    stopped = true;
                    continue;
                }
                shared.cancel.store(true, Ordering::Relaxed);
                interrupted = Some(e);
                break;
            }
            if let Some(report) = report {
                let (d, t) = (shared.done.load(Ordering::Relaxed), shared.total.load(Ordering::Relaxed));
                if let Err(e) = report.call1(py, (d.min(t), t)) {
                    shared.cancel.store(true, Ordering::Relaxed);
                    interrupted = Some(e);
                    break;
                }
            }
        }
        // The work catches its own panics; a join error is one too.
        let joined = py.detach(|| handle.join()).unwrap_or_else(Err);
        match interrupted {
            Some(e) => Err(e),
            None => Ok(Some(joined)),
        }
    })?;
    if let Some(report) = report {
        let t = shared.total.load(Ordering::Relaxed);
        report.call1(py, (t, t))?;
    }
    match result {
        Some(Ok(r)) => r.map(|t| (t, stopped)).map_err(to_py),
        Some(Err(panic)) => Err(panic_error(panic)),
        None => Err(PyRuntimeError::new_err("the run ended without a result")),
    }
}

/// Load a configuration: `kind` is "default", "path", "text" or "dict"; `overrides` are `--set`
/// assignments, applied in order.
#[pyfunction]
#[pyo3(signature = (kind, config, overrides, origin=None))]
fn load(kind: &str, config: &Bound<'_, PyAny>, overrides: Vec<String>, origin: Option<String>) -> PyResult<Experiment> {
    guarded(|| load_one(kind, config, &overrides, origin))
}

fn load_one(
    kind: &str,
    config: &Bound<'_, PyAny>,
    overrides: &[String],
    origin: Option<String>,
) -> PyResult<Experiment> {
    let loaded = match kind {
        "default" => Loaded::read(None, overrides).map_err(to_py)?,
        "path" => {
            let p: PathBuf = config.extract()?;
            Loaded::read(Some(&p), overrides).map_err(to_py)?
        }
        "text" | "dict" => {
            let text: String = if kind == "text" {
                config.extract()?
            } else {
                let toml::Value::Table(t) = to_toml(config, "")? else { unreachable!("a dict is a table") };
                toml::to_string(&t).map_err(|e| PyValueError::new_err(format!("config error: {e}")))?
            };
            let origin = origin.unwrap_or_else(|| format!("<{kind}>"));
            let (table, exp) = ohd::config::load(&text, &origin, overrides).map_err(|e| to_py(e.into()))?;
            let stem = "experiment".to_string();
            Loaded {
                text,
                origin: origin.clone(),
                stem,
                source_path: origin,
                overrides: overrides.to_vec(),
                table,
                exp,
            }
        }
        other => return Err(PyValueError::new_err(format!("unknown configuration kind {other:?}"))),
    };
    Ok(Experiment { loaded })
}

/// Load one configuration with each list of overrides in `points`, the Mie ensembles computed
/// once for all of them (`ohd::mie::with_cache`).
#[pyfunction]
#[pyo3(signature = (kind, config, points, origin=None))]
fn load_many(
    kind: &str,
    config: &Bound<'_, PyAny>,
    points: Vec<Vec<String>>,
    origin: Option<String>,
) -> PyResult<Vec<Experiment>> {
    guarded(|| {
        ohd::mie::with_cache(|| {
            points.iter().map(|sets| load_one(kind, config, sets, origin.clone())).collect::<PyResult<Vec<_>>>()
        })
    })
}

/// Write a run's files (the manifest last) into `dir` as `ohd run --out` does.
#[pyfunction]
fn save(py: Python<'_>, dir: PathBuf, files: Vec<(String, Vec<u8>)>) -> PyResult<()> {
    guarded(|| py.detach(|| ohd::io::write::memory::save(&dir, &files)).map_err(to_py))
}

/// Write a scan's own files (`scan.json` last) and each pointing's run (the manifest last) into
/// `dir` and its `pointing_NN/` as `ohd run --out` writes a scan: the CLI's writer, locks and all.
#[pyfunction]
fn save_scan(
    py: Python<'_>,
    dir: PathBuf,
    files: Vec<(String, Vec<u8>)>,
    pointings: Vec<Vec<(String, Vec<u8>)>>,
) -> PyResult<()> {
    guarded(|| py.detach(|| ohd::io::write::memory::save_scan(&dir, &files, &pointings)).map_err(to_py))
}

/// Mie efficiencies of one sphere, as `ohd mie` (with `angles`: its phase function, per sr, at
/// the angles in radians).
#[pyfunction]
#[pyo3(signature = (n, k, x, angles=None))]
fn mie_sphere(py: Python<'_>, n: f64, k: f64, x: f64, angles: Option<usize>) -> PyResult<Py<PyDict>> {
    guarded(|| {
        let sol = ohd::mie::MieSolution::new(n, k, x).map_err(|e| PyValueError::new_err(e.to_string()))?;
        let q = sol.efficiencies();
        let d = PyDict::new(py);
        d.set_item("x", x)?;
        d.set_item("qext", q.qext)?;
        d.set_item("qsca", q.qsca)?;
        d.set_item("qback", q.qback)?;
        d.set_item("g", q.g)?;
        if let Some(angles) = angles {
            if !(16..=100_000).contains(&angles) {
                return Err(PyValueError::new_err(format!("angles={angles}: expected 16 to 100000")));
            }
            let theta = ohd::mie::angle_grid(angles, x);
            let mut p = vec![0.0; angles];
            sol.phase_function(&theta, &mut p);
            d.set_item("theta_rad", theta)?;
            d.set_item("phase_per_sr", p)?;
        }
        Ok(d.unbind())
    })
}

/// The relative index and size parameter of a sphere of diameter `d` (m) and index `n − ik` in a
/// medium of index `n_medium` at vacuum wavelength `wavelength` (m), as `ohd mie` computes them.
#[pyfunction]
fn relative_sphere(d: f64, n: f64, k: f64, n_medium: f64, wavelength: f64) -> (f64, f64, f64) {
    ohd::medium::relative_sphere(d, n, k, n_medium, wavelength)
}

/// The convergence study, written into `out` as `ohd converge` writes it; returns its log lines.
#[pyfunction]
#[pyo3(signature = (config, overrides, out, reference, budget_seconds, samples, rungs, figures))]
#[allow(clippy::too_many_arguments)]
fn converge(
    py: Python<'_>,
    config: Option<PathBuf>,
    overrides: Vec<String>,
    out: PathBuf,
    reference: Option<PathBuf>,
    budget_seconds: f64,
    samples: Option<u64>,
    rungs: usize,
    figures: bool,
) -> PyResult<Vec<String>> {
    struct Log<'a> {
        lines: Vec<String>,
        progress: &'a Shared,
    }
    impl ohd::converge::StudyLog for Log<'_> {
        fn line(&mut self, text: &str) {
            self.lines.push(text.to_string());
        }
        fn progress(&self) -> &dyn Progress {
            self.progress
        }
    }
    let req = ohd::run::converge::ConvergeRequest {
        config,
        overrides,
        out: Some(out),
        reference,
        budget_seconds,
        samples,
        rungs,
        no_figures: !figures,
    };
    guarded(|| {
        let (lines, _) = watched(py, 0, None, Keep::Nothing, |progress| {
            let mut log = Log { lines: Vec::new(), progress };
            ohd::run::converge::converge(&req, &ohd::run::Unobserved, &mut log)?;
            Ok(log.lines)
        })?;
        Ok(lines)
    })
}

/// The `ohd` command line (`ohd::cli`, the binary's own code) with `argv` (the command's name
/// first); returns its exit status. The package's `ohd` console script calls it: one build gives
/// the package and the command.
#[pyfunction]
fn cli(py: Python<'_>, argv: Vec<String>) -> u8 {
    py.detach(|| ohd::cli::status_from(argv))
}

#[pymodule]
fn _ohd(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("ConfigError", m.py().get_type::<ConfigError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("DEFAULT_CONFIG", ohd::DEFAULT_CONFIG)?;
    m.add_class::<Experiment>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(load_many, m)?)?;
    m.add_function(wrap_pyfunction!(save, m)?)?;
    m.add_function(wrap_pyfunction!(save_scan, m)?)?;
    m.add_function(wrap_pyfunction!(toml_value, m)?)?;
    m.add_function(wrap_pyfunction!(memory_budget, m)?)?;
    m.add_function(wrap_pyfunction!(mie_sphere, m)?)?;
    m.add_function(wrap_pyfunction!(relative_sphere, m)?)?;
    m.add_function(wrap_pyfunction!(converge, m)?)?;
    m.add_function(wrap_pyfunction!(cli, m)?)?;
    Ok(())
}
