"""ohd from Python: run optical heterodyne detection experiments and get NumPy arrays back.

    >>> import ohd
    >>> r = ohd.run(samples=200_000, seed=1)          # the built-in default experiment
    >>> r.estimates["reflectance_diffuse"].value
    >>> r["camera_spectrum"].values, r["camera_spectrum"].axes["frequency_hz"]
    >>> r.save("out/default")                          # exactly what `ohd run --out` writes
    >>> ohd.load("out/default")                        # the same Result, read back

A configuration is a path, a TOML string or a nested dict, in the schema of configs/README.md,
checked with the CLI's error messages (`ohd.ConfigError`, a ValueError with `.key`). A run is the
CLI's run, from the same library: for the same configuration and seed its arrays are the bytes
`ohd run --out` writes. Runs release the GIL; Ctrl-C ends a run early and keeps its work
(KeyboardInterrupt with `.result`).
"""
from __future__ import annotations

import io
import json
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, List, Mapping, NamedTuple, Optional, Sequence, Union

import numpy as np

from . import _ohd
from ._ohd import ConfigError, Experiment

__version__ = _ohd.__version__
__all__ = [
    "run",
    "load",
    "check",
    "sweep",
    "mie",
    "converge",
    "Result",
    "Output",
    "Estimate",
    "Experiment",
    "ConfigError",
    "DEFAULT_CONFIG",
]

#: The built-in default experiment (configs/default.toml), as TOML text.
DEFAULT_CONFIG: str = _ohd.DEFAULT_CONFIG

Config = Union[None, str, "os.PathLike[str]", Mapping[str, Any], Experiment]
Overrides = Union[None, Mapping[str, Any], Sequence[str]]
Report = Callable[[int, int], Any]


class Estimate(NamedTuple):
    """A scalar estimate: its value and standard error."""

    value: float
    stderr: float


class Output:
    """One output array of a run (a `.npy` file of `ohd run --out`).

    `values` and `stderr` (None where the run writes no standard errors) are read-only views of
    the file's bytes; `axes` maps each dimension's axis name, in order, to its coordinates
    (`frequency_hz`: bin centres in Hz; `x_m`, `y_m`: pixel centres in m, `y_m` descending as the
    image rows; `channel`: names; `range_m`, `time_s`, `tau_s`, …), as the manifest's `outputs`
    table declares them; `units` is the unit of the values; `kind` what it is (`image`,
    `spectrum`, `curve`, `relative_error`, …).
    """

    def __init__(
        self,
        name: str,
        values: np.ndarray,
        stderr: Optional[np.ndarray],
        axes: Dict[str, np.ndarray],
        units: Optional[str],
        kind: Optional[str] = None,
    ):
        self.name = name
        self.values = values
        self.stderr = stderr
        self.axes = axes
        self.units = units
        self.kind = kind

    def __array__(self, dtype=None, copy=None):
        return self.values if dtype is None else self.values.astype(dtype)

    def __repr__(self) -> str:
        axes = ", ".join(f"{k}[{len(v)}]" for k, v in self.axes.items())
        return f"<ohd.Output {self.name} {self.values.dtype}{list(self.values.shape)} axes({axes}) units={self.units!r}>"


def _npy(data: bytes) -> np.ndarray:
    """The array of a `.npy` file's bytes, viewing them (read-only, not copied)."""
    f = io.BytesIO(data)
    version = np.lib.format.read_magic(f)
    header = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
    shape, fortran, dtype = header(f)
    count = int(np.prod(shape, dtype=np.int64))
    a = np.frombuffer(data, dtype=dtype, count=count, offset=f.tell())
    return a.reshape(shape, order="F" if fortran else "C")


def _estimates(tree: Any) -> Any:
    if isinstance(tree, dict):
        if set(tree) == {"value", "stderr"}:
            return Estimate(tree["value"], tree["stderr"])
        return {k: _estimates(v) for k, v in tree.items()}
    return tree


class Result:
    """What a run returns: its files in memory, as `ohd run --out` writes them.

    * `estimates`: the manifest's scalar estimates, nested as there, each an `Estimate(value, stderr)`.
    * `outputs` / `result[name]`: every array output by file stem (`camera_spectrum`, …), an `Output`.
    * `manifest`: manifest.json as a dict; `files`: {file name: bytes}, in the order written.
    * `save(dir)`: write the files into `dir` as `ohd run --out dir` does.
    * `pointings`: for a scan, one `Result` per pointing (this one holds the scan's own files).
    * `main_figure()`: the main output's PNG; in Jupyter a `Result` shows it with its estimates.
    """

    def __init__(self, files: Dict[str, bytes], pointings: Optional[List["Result"]] = None):
        self.files = files
        self.pointings = pointings or []
        text = files.get("manifest.json")
        self.manifest: Dict[str, Any] = json.loads(text) if text else {}
        self.estimates: Dict[str, Any] = _estimates(self.manifest.get("estimates", {}))
        self._outputs: Optional[Dict[str, Output]] = None

    @property
    def outputs(self) -> Dict[str, Output]:
        """Every array output of the run, by file stem (`camera_m0_plus`, …), as an `Output`
        with its values, standard errors, axes and units; read from the files when first asked."""
        if self._outputs is None:
            self._outputs = self._read_outputs()
        return self._outputs

    def _axis(self, a: Dict[str, Any]) -> np.ndarray:
        """The coordinates of one axis of the manifest's `outputs` table."""
        if "bins" in a:
            b = a["bins"]
            return b["start"] + (np.arange(b["count"]) + 0.5) * b["width"]
        if "linear" in a:
            lin = a["linear"]
            return lin["first"] + lin["step"] * np.arange(lin["count"])
        if "file" in a:
            return _npy(self.files[a["file"]])
        return np.array(a.get("labels", []))

    def _read_outputs(self) -> Dict[str, Output]:
        table = self.manifest.get("outputs")
        if table is None:
            return self._guess_outputs()
        out = {}
        for file, e in table.items():
            if not file.endswith(".npy") or e.get("kind") == "axis" or file not in self.files:
                continue
            err = e.get("stderr_file")
            err = _npy(self.files[err]) if err in self.files else None
            axes = {a["name"]: self._axis(a) for a in e.get("axes", [])}
            stem = file[: -len(".npy")]
            out[stem] = Output(stem, _npy(self.files[file]), err, axes, e.get("units"), e.get("kind"))
        return out

    def _guess_outputs(self) -> Dict[str, Output]:
        """Outputs of a manifest written before ohd 0.1's `outputs` table, by file name."""
        axes_files = set()
        groups = []  # (name prefix, group key, group dict) of the manifest's detectors
        for det, info in (self.manifest.get("detectors") or {}).items():
            for key, group in (info.items() if isinstance(info, dict) else []):
                if isinstance(group, dict):
                    groups.append((det + "_", key, group))
                    axes_files.update(v for k, v in group.items() if k.endswith("_file") and str(v).endswith(".npy"))
        out = {}
        for name, data in self.files.items():
            if not name.endswith(".npy") or name.endswith("_stderr.npy") or name in axes_files:
                continue
            stem = name[: -len(".npy")]
            err = self.files.get(stem + "_stderr.npy")
            axes: Dict[str, np.ndarray] = {}
            units = None
            for prefix, key, group in groups:
                # A detector's group ("spectrum", "image", "lidar", …) describes the outputs
                # named after it or whose file it names.
                if not stem.startswith(prefix) or (key not in stem[len(prefix):] and f'"{name}"' not in json.dumps(group)):
                    continue
                units = group.get("units", units)
                for k, v in group.items():
                    if k.endswith("_file") and v in self.files and str(v).endswith(".npy"):
                        axes[v[len(prefix):-len(".npy")]] = _npy(self.files[v])
                if "x_range_m" in group and "pixels" in group:
                    (x0, x1), (y0, y1), (nx, ny) = group["x_range_m"], group["y_range_m"], group["pixels"]
                    axes["x_m"] = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
                    axes["y_m"] = y1 - (np.arange(ny) + 0.5) * (y1 - y0) / ny  # rows: y descending
            out[stem] = Output(stem, _npy(data), _npy(err) if err is not None else None, axes, units)
        return out

    def __getitem__(self, name: str) -> Output:
        """`result["camera_m0_plus"]`: the output of that file stem; a KeyError lists them all."""
        try:
            return self.outputs[name]
        except KeyError:
            raise KeyError(f"{name!r}: no such output; outputs: {', '.join(self.outputs)}") from None

    def __contains__(self, name: str) -> bool:
        """Whether the run has an output of that file stem."""
        return name in self.outputs

    def save(self, dir: Union[str, "os.PathLike[str]"]) -> None:
        """Write the run's files into `dir` exactly as `ohd run --out dir` writes them, by the same
        writer (atomically, the manifest last, replacing an earlier run there; a scan's pointings
        into `pointing_NN/`, its `scan.json` last). Locked while it writes: OSError if another ohd
        writes into `dir` or one of its pointing directories; a link at a pointing directory is
        refused, a link at a file's name replaced, never followed."""
        dir = os.fspath(dir)
        if self.pointings:
            _ohd.save_scan(dir, list(self.files.items()), [list(p.files.items()) for p in self.pointings])
            return
        _ohd.save(dir, list(self.files.items()))

    def main_figure(self) -> Optional[bytes]:
        """The PNG of the run's main output (the one `--target-error` controls), if figures were
        drawn; else None."""
        main = (self.manifest.get("main_output") or {}).get("name")
        for entry in (self.manifest.get("outputs") or {}).values():
            if entry.get("output") == main and entry.get("figure") in self.files:
                return self.files[entry["figure"]]
        return None

    def _repr_html_(self) -> str:
        """Jupyter's view of a run: its name and size, the main output's figure, and the table of
        its scalar estimates with standard errors."""
        import base64
        import html

        m = self.manifest
        head = html.escape(f"{m.get('name', '?')}: {m.get('samples')} paths, seed {m.get('seed')}")
        main = m.get("main_output") or {}
        err = main.get("relative_error")
        lines = [f"<b>ohd.Result</b> {head}"]
        if err is not None:
            lines.append(html.escape(f"main output {main.get('name')}: relative error {100 * err:.3g} %"))
        if "interrupted" in m:
            cut = m["interrupted"]
            lines.append(html.escape(f"interrupted: {cut['batches']} of {cut['planned_batches']} batches"))
        if self.pointings:
            lines.append(f"{len(self.pointings)} pointings (<code>.pointings</code>)")
        parts = ["<div>" + "<br>".join(lines) + "</div>"]
        png = self.main_figure()
        if png is not None:
            data = base64.b64encode(png).decode("ascii")
            parts.append(f'<img src="data:image/png;base64,{data}" style="max-width:100%">')
        rows = []

        def walk(prefix: str, tree: Any) -> None:
            for k, v in tree.items():
                if isinstance(v, Estimate):
                    rows.append((prefix + k, v))
                elif isinstance(v, dict):
                    walk(prefix + k + ".", v)

        walk("", self.estimates)
        if rows:
            cells = "".join(
                f"<tr><td>{html.escape(k)}</td><td>{v.value:.6g}</td><td>{v.stderr:.2g}</td></tr>" for k, v in rows
            )
            parts.append(f"<table><tr><th>estimate</th><th>value</th><th>standard error</th></tr>{cells}</table>")
        return "\n".join(parts)

    def __repr__(self) -> str:
        name = self.manifest.get("name", "?")
        n = self.manifest.get("samples")
        extra = f", {len(self.pointings)} pointings" if self.pointings else ""
        return f"<ohd.Result {name!r}: {n} paths, {len(self.outputs)} outputs, {len(self.files)} files{extra}>"

    @classmethod
    def _from_dir(cls, dir: Path) -> "Result":
        files = {}
        pointings = []
        for p in sorted(dir.iterdir()):
            if p.is_dir() and p.name.startswith("pointing_"):
                pointings.append(cls._from_dir(p))
            elif p.is_file() and not p.name.startswith("."):
                files[p.name] = p.read_bytes()
        if "manifest.json" in files:  # the manifest last, as written
            files["manifest.json"] = files.pop("manifest.json")
        return cls(files, pointings)


def load(dir: Union[str, "os.PathLike[str]"]) -> Result:
    """The `Result` of a run written into `dir` (by `ohd run --out dir`, `ohd merge` or
    `Result.save`): the same estimates, outputs, manifest and files that `ohd.run` returned for it.
    A scan's directory gives its pointings in `.pointings`. Raises FileNotFoundError if `dir` holds
    no finished run (no manifest.json)."""
    path = Path(dir)
    if not (path / "manifest.json").is_file() and not (path / "pointing_00").is_dir():
        raise FileNotFoundError(f"{os.fspath(dir)}: no finished run here (no manifest.json)")
    return Result._from_dir(path)


def _sets(overrides: Overrides, samples=None, seed=None, threads=None) -> List[str]:
    """`--set` assignments: the overrides, then samples, seed and threads (as the CLI orders them)."""
    if overrides is None:
        sets: List[str] = []
    elif isinstance(overrides, Mapping):
        sets = [f"{k}={_ohd.toml_value(v, k)}" for k, v in overrides.items()]
    elif isinstance(overrides, str):
        sets = [overrides]
    else:
        sets = [str(s) for s in overrides]
    if samples is not None:
        sets.append(f"run.samples={_count(samples)}")
    for key, v in (("run.seed", seed), ("run.threads", threads)):
        if v is not None:
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
                raise ValueError(f"{key.split('.')[1]}={v!r}: expected an integer ≥ 0")
            sets.append(f"{key}={int(v)}")
    return sets


def _count(samples) -> int:
    """A number of paths: an integer ≥ 0, or a float of a whole value (`1e6`, as pmcx takes it)."""
    if not isinstance(samples, bool):
        if isinstance(samples, (int, np.integer)) and samples >= 0:
            return int(samples)
        if isinstance(samples, (float, np.floating)) and float(samples).is_integer() and 0 <= samples <= 2.0**53:
            return int(samples)
    raise ValueError(f"samples={samples!r}: expected a whole number of paths ≥ 0, such as 1000000 or 1e6")


def _source(config: Config):
    """(kind, value) of a configuration for the extension's `load`."""
    if config is None:
        return "default", None
    if isinstance(config, Mapping):
        return "dict", dict(config)
    if isinstance(config, os.PathLike):
        return "path", os.fspath(config)
    if isinstance(config, str):
        # TOML text has a newline or an assignment; a file name has neither.
        return ("text", config) if ("\n" in config or "=" in config) else ("path", config)
    raise TypeError(f"config: expected a path, TOML text, a dict or None, not {type(config).__name__}")


def check(config: Config = None, *, overrides: Overrides = None) -> Experiment:
    """Read and resolve a configuration as `ohd check` does; `print()` the result for what
    `ohd check` prints. Raises ConfigError (a ValueError with `.key`) or an OSError."""
    if isinstance(config, Experiment):
        return config
    kind, value = _source(config)
    return _ohd.load(kind, value, _sets(overrides))


def _reporter(progress: Union[bool, Report]) -> Optional[Report]:
    if callable(progress):
        return progress
    if not progress:
        return None
    jupyter = "ipykernel" in sys.modules
    if not (jupyter or (hasattr(sys.stderr, "isatty") and sys.stderr.isatty())):
        return None
    stream = sys.stdout if jupyter else sys.stderr
    state = {"last": 0.0, "start": time.monotonic()}

    def report(done: int, total: int) -> None:
        now = time.monotonic()
        finished = total > 0 and done >= total
        if not finished and now - state["last"] < 0.2:
            return
        state["last"] = now
        frac = done / total if total else 0.0
        bar = "#" * int(30 * frac)
        stream.write(f"\rohd [{bar:<30}] {100 * frac:5.1f}% {done}/{total} paths {now - state['start']:.1f} s")
        if finished:
            stream.write("\n")
        stream.flush()

    return report


def run(
    config: Config = None,
    *,
    samples: Union[None, int, float] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    overrides: Overrides = None,
    out: Union[None, str, "os.PathLike[str]"] = None,
    progress: Union[bool, Report] = True,
    figures: bool = True,
    grids: Optional[Mapping[str, Any]] = None,
) -> Result:
    """Run an experiment, as `ohd run` does, and return its outputs in memory.

    config     a path to a TOML file, TOML text, a nested dict (the schema of configs/README.md),
               an `Experiment` from `check`, or None for the built-in default experiment.
    samples, seed, threads
               as `--samples`, `--seed`, `--threads` (the same as overrides of run.samples, …).
    overrides  {"key.path": value} or ["key.path=value", …], as `--set` (applied in order).
    out        also write the outputs into this directory (as `ohd run --out`).
    progress   True: a progress line on a terminal or in Jupyter; False: none; or a callable
               `progress(done_paths, total_paths)` called about every 50 ms.
    figures    write the PNG/SVG figures (as the CLI; False as `--no-figures`).
    grids      NumPy volumes by name, for a dict `config` whose `density` or `velocity` tables
               say `{"type": "npy", "array": NAME, "voxel_size_um": …}`: `array[i, j, k]` is voxel
               (i, j, k) along x, y, z (a density of shape (nx, ny, nz); a velocity in m/s of
               shape (nx, ny, nz, 3)). They run as `.npy` files given by `file` would, the same
               grids an OpenVDB file gives (configs/README.md, "NumPy volumes").

    Returns a `Result` (`estimates`, `outputs`/`result[name]`, `manifest`, `files`, `save()`).
    For the same configuration and seed the arrays are the bytes `ohd run --out` writes.
    A scan (several pointings) returns one `Result` per pointing in `.pointings`.
    Raises ConfigError (a ValueError) on an invalid configuration, an OSError on a file that
    cannot be read or written. Ctrl-C ends the run at its next batch boundary and raises
    KeyboardInterrupt with the result of the batches done as `.result` (its manifest's
    `interrupted` gives the batches done and planned; with `out`, that result is written there);
    a second Ctrl-C stops at once, with nothing kept.
    """
    if grids is not None:
        if not isinstance(config, Mapping):
            raise TypeError("run(…, grids=…): give the configuration as a dict whose volumes name the arrays")
        with tempfile.TemporaryDirectory(prefix="ohd-grids-") as tmp:
            config = _with_grid_files(config, grids, Path(tmp))
            exp = check(config, overrides=_sets(overrides, samples, seed, threads))
            return _run(exp, out, _reporter(progress), figures)
    if isinstance(config, Experiment):
        if overrides is not None or samples is not None or seed is not None or threads is not None:
            raise TypeError("run(Experiment, …): give overrides, samples, seed, threads to check() instead")
        exp = config
    else:
        exp = check(config, overrides=_sets(overrides, samples, seed, threads))
    return _run(exp, out, _reporter(progress), figures)


def _with_grid_files(config: Mapping[str, Any], grids: Mapping[str, Any], tmp: Path) -> Dict[str, Any]:
    """A copy of `config` whose `{"type": "npy", "array": NAME}` tables name `.npy` files in `tmp`
    holding `grids[NAME]` (float32), each written once."""
    written: Dict[str, str] = {}
    used = set()

    def walk(v: Any, key: str) -> Any:
        if isinstance(v, Mapping):
            out = {k: walk(x, f"{key}.{k}" if key else str(k)) for k, x in v.items()}
            if out.get("type") == "npy" and "array" in out:
                name = out.pop("array")
                if name not in grids:
                    given = ", ".join(map(str, grids)) or "none"
                    err = ConfigError(f"config error: {key}.array: = {name!r}: no such array in grids (given: {given})")
                    err.key = f"{key}.array"  # type: ignore[attr-defined]
                    raise err
                if name not in written:
                    path = tmp / f"grid_{len(written)}.npy"
                    np.save(path, np.asarray(grids[name], dtype=np.float32))
                    written[name] = str(path)
                used.add(name)
                out["file"] = written[name]
            return out
        if isinstance(v, list):
            return [walk(x, f"{key}.{i}") for i, x in enumerate(v)]
        return v

    result = walk(config, "")
    unused = set(grids) - used
    if unused:
        raise ValueError(f"grids: {', '.join(sorted(map(str, unused)))} not named by any `array` of the configuration")
    return result


def _run(exp: Experiment, out, report, figures: bool) -> Result:
    if out is not None:
        _ohd.check_writable(os.fspath(out))
    if exp.pointings > 1:
        if out is not None:
            stopped = exp.run_to_dir(os.fspath(out), figures, report)
            return _stopped(Result._from_dir(Path(out)), stopped)
        with tempfile.TemporaryDirectory(prefix="ohd-scan-") as tmp:
            stopped = exp.run_to_dir(tmp, figures, report)
            return _stopped(Result._from_dir(Path(tmp)), stopped)
    _, files, stopped = exp.run(figures, report)
    result = Result(dict(files))
    if out is not None:
        result.save(out)
    return _stopped(result, stopped)


def _stopped(result: Result, stopped: bool) -> Result:
    """`result`, or after Ctrl-C a KeyboardInterrupt carrying it as `.result`."""
    if not stopped:
        return result
    runs = result.pointings or [result]
    cut = [r.manifest["interrupted"] for r in runs if "interrupted" in r.manifest]
    if cut:
        what = f"the result of {cut[0]['batches']} of {cut[0]['planned_batches']} batches (errors from those)"
    else:
        what = "the complete result (Ctrl-C came after the paths were traced)"
    e = KeyboardInterrupt(f"ohd: interrupted: {what} is in .result")
    e.result = result  # type: ignore[attr-defined]
    raise e


def sweep(
    config: Config,
    key: Optional[str] = None,
    values: Optional[Iterable[Any]] = None,
    *,
    points: Optional[Iterable[Overrides]] = None,
    samples: Union[None, int, float] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    overrides: Overrides = None,
    progress: Union[bool, Report] = True,
    figures: bool = True,
) -> List[Result]:
    """Run `config` once per value of `key` (`sweep(cfg, "source.wavelength_nm", [780, 785])`),
    or once per overrides in `points` (a list of dicts or `--set` lists), after `overrides`.

    Every point is resolved first, with Mie ensembles computed once for all points that share
    them (a rain ensemble costs ≈ 1.7 s per resolution), so configuration errors surface before
    any run. Returns one `Result` per point, in order.
    """
    if (key is None) == (points is None):
        raise TypeError("sweep: give either key and values, or points")
    if key is not None:
        if values is None:
            raise TypeError("sweep: values are required with key")
        points = [{key: v} for v in values]
    base = _sets(overrides)
    tail = _sets(None, samples, seed, threads)
    lists = [base + _sets(p) + tail for p in points]
    if isinstance(config, Experiment):
        raise TypeError("sweep: give the configuration itself (a path, TOML text or dict), not an Experiment")
    kind, value = _source(config)
    exps = _ohd.load_many(kind, value, lists)
    report = _reporter(progress)
    return [_run(e, None, report, figures) for e in exps]


def mie(
    *,
    m_real: Optional[float] = None,
    m_imag: float = 0.0,
    x: Optional[float] = None,
    diameter_um: Optional[float] = None,
    n_particle: Optional[float] = None,
    k_particle: float = 0.0,
    n_medium: Optional[float] = None,
    wavelength_nm: Optional[float] = None,
    angles: Optional[int] = None,
) -> Dict[str, Any]:
    """Mie efficiencies of one sphere, as `ohd mie`: give `m_real` and `x` (with `m_imag`), or
    `diameter_um`, `n_particle` (`k_particle`), `n_medium` and `wavelength_nm`.

    Returns {"x", "qext", "qsca", "qback", "g"}; with `angles` (16 to 100000) also the phase
    function (per sr, normalised over the sphere) as arrays "theta_deg" and "phase_per_sr".
    """

    def finite(name, v, ok, expected):
        if v is None or not np.isfinite(v) or not ok(v):
            raise ValueError(f"{name}={v!r}: expected {expected}")
        return float(v)

    if m_real is not None and diameter_um is None:
        n = finite("m_real", m_real, lambda v: v > 0, "a real part > 0")
        k = finite("m_imag", m_imag, lambda v: v >= 0, "k ≥ 0 (m = n − ik; k > 0 absorbs)")
        x = finite("x", x, lambda v: v > 0, "a size parameter > 0")
    elif diameter_um is not None and m_real is None:
        d = finite("diameter_um", diameter_um, lambda v: v > 0, "a diameter > 0 µm")
        np_ = finite("n_particle", n_particle, lambda v: v > 0, "a refractive index > 0")
        kp = finite("k_particle", k_particle, lambda v: v >= 0, "k ≥ 0 (index n − ik; k > 0 absorbs)")
        nm = finite("n_medium", n_medium, lambda v: v > 0, "a refractive index > 0")
        wl = finite("wavelength_nm", wavelength_nm, lambda v: v > 0, "a vacuum wavelength > 0 nm")
        n, k, x = _ohd.relative_sphere(d * 1e-6, np_, kp, nm, wl * 1e-9)
    else:
        raise ValueError(
            "give either m_real and x (with m_imag), or diameter_um, n_particle, n_medium and wavelength_nm"
        )
    d = _ohd.mie_sphere(n, k, x, angles)
    if angles is not None:
        d["theta_deg"] = np.degrees(np.asarray(d.pop("theta_rad")))
        d["phase_per_sr"] = np.asarray(d["phase_per_sr"])
    return d


def converge(
    config: Union[None, str, "os.PathLike[str]"] = None,
    *,
    out: Union[str, "os.PathLike[str]"],
    reference: Union[None, str, "os.PathLike[str]"] = None,
    budget_seconds: float = 120.0,
    samples: Union[None, int, float] = None,
    rungs: int = 6,
    overrides: Overrides = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    figures: bool = True,
) -> Dict[str, Any]:
    """The convergence study of `ohd converge` (error against run time over a ladder of sample
    counts), written into `out`; returns converge.json as a dict, with its log as "log".
    `config` is a file path (or None for the default experiment)."""
    if config is not None and not isinstance(config, (str, os.PathLike)):
        raise TypeError("converge: config is a file path (or None for the default experiment)")
    lines = _ohd.converge(
        None if config is None else os.fspath(config),
        _sets(overrides, None, seed, threads),
        os.fspath(out),
        None if reference is None else os.fspath(reference),
        float(budget_seconds),
        None if samples is None else _count(samples),
        int(rungs),
        figures,
    )
    study = json.loads((Path(out) / "converge.json").read_text())
    study["log"] = lines
    return study
