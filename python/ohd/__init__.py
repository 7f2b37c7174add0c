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

import errno
import io
import json
import os
import stat
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, List, Mapping, NamedTuple, Optional, Sequence, Tuple, Union

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


def _npy(data: bytes, name: str = ".npy file") -> np.ndarray:
    """The array of a `.npy` file's bytes, viewing them (read-only, not copied); a ValueError
    naming `name` unless the header is a plain array's whose data are exactly the bytes after it."""
    f = io.BytesIO(data)
    try:
        version = np.lib.format.read_magic(f)
        header = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, fortran, dtype = header(f)
    except (ValueError, EOFError, SyntaxError, TypeError) as e:
        raise ValueError(f"{name}: not a .npy file ohd wrote: {e}") from None
    if dtype.hasobject or dtype.itemsize == 0:
        raise ValueError(f"{name}: dtype {dtype}: expected numbers")
    count = 1
    for d in shape:
        count *= int(d)
    if count * dtype.itemsize != len(data) - f.tell():
        raise ValueError(
            f"{name}: {len(data) - f.tell()} bytes of data where its header (shape {tuple(shape)}, {dtype}) declares {count * dtype.itemsize}"
        )
    a = np.frombuffer(data, dtype=dtype, count=count, offset=f.tell())
    return a.reshape(shape, order="F" if fortran else "C")


def _estimates(tree: Any) -> Any:
    if isinstance(tree, dict):
        if set(tree) == {"value", "stderr"}:
            return Estimate(tree["value"], tree["stderr"])
        return {k: _estimates(v) for k, v in tree.items()}
    return tree


# What `ohd.load` reads (issue 52, item 7): only the files a directory's record lists, each a
# regular file of this directory (no link followed, nothing else opened), no larger than its
# record allows, and only a directory whose writing finished.
_MARKER = "ohd_incomplete.txt"  # src/io/write/dir.rs: a directory being written or whose writing stopped
_RECORD_BYTES = 256 << 20  # the most a manifest.json or scan.json may hold (as the CLI reads them)
_NPY_HEADER_BYTES = 1 << 16  # the most a .npy header may take
_OTHER_BYTES = 256 << 20  # a figure, table or EXR beyond what the declared arrays allow
_SCAN_FILES = (
    "scan.json",
    "vad.csv",
    "vad_wind_profile.png",
    "vad_wind_profile.svg",
    "fmcw_scan.csv",
    "fmcw_scan_range.png",
    "fmcw_scan_range.svg",
    "fmcw_scan_velocity.png",
    "fmcw_scan_velocity.svg",
)


def _plain(name: Any) -> bool:
    """A plain file name of the directory itself (no path, not hidden)."""
    return isinstance(name, str) and name not in ("", ".", "..") and not name.startswith(".") and not any(c in name for c in "/\\\0")


def _pointing(name: Any) -> bool:
    return isinstance(name, str) and name.startswith("pointing_") and name[9:].isdigit() and name[9:].isascii()


def _open_dir(name: str, where: Path, dir_fd: Optional[int] = None) -> int:
    """A descriptor of the directory `name` (in `dir_fd`, then a real directory, not a link)."""
    flags = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | getattr(os, "O_CLOEXEC", 0)
    if dir_fd is None:
        return os.open(name, flags)
    try:
        return os.open(name, flags | os.O_NOFOLLOW, dir_fd=dir_fd)
    except OSError as e:
        if e.errno in (errno.ELOOP, errno.ENOTDIR):
            raise OSError(f"{where / name}: not a directory (a symbolic link or a file): ohd.load reads a scan's own pointing directories only") from None
        raise


def _read_in(dir_fd: int, name: str, where: Path, limit: int) -> Optional[bytes]:
    """The bytes of the regular file `name` of the directory `dir_fd` (`where`), at most `limit`
    of them, or None if there is none; a link, a FIFO, a device or a larger file is refused
    before anything is read."""
    path = where / name
    try:
        st = os.stat(name, dir_fd=dir_fd, follow_symlinks=False)
    except FileNotFoundError:
        return None
    if stat.S_ISLNK(st.st_mode):
        raise OSError(f"{path}: a symbolic link: ohd.load reads only the run's own files, not what a link points to")
    if not stat.S_ISREG(st.st_mode):
        raise OSError(f"{path}: not a regular file: ohd.load reads only the run's own files")
    if st.st_size > limit:
        raise ValueError(f"{path}: {st.st_size} bytes, more than the {limit} its record allows: not the file the run wrote")
    flags = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)
    fd = os.open(name, flags, dir_fd=dir_fd)
    with open(fd, "rb", buffering=0, closefd=True) as f:
        if not stat.S_ISREG(os.fstat(fd).st_mode):  # (replaced since it was looked at)
            raise OSError(f"{path}: not a regular file: ohd.load reads only the run's own files")
        chunks, size = [], 0
        while size <= limit:
            chunk = f.read(min(limit + 1 - size, 1 << 24))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    if size > limit:
        raise ValueError(f"{path}: more than the {limit} bytes its record allows: not the file the run wrote")
    return b"".join(chunks)


def _record(dir_fd: int, name: str, where: Path) -> Optional[Dict[str, Any]]:
    data = _read_in(dir_fd, name, where, _RECORD_BYTES)
    if data is None:
        return None
    try:
        record = json.loads(data)
    except ValueError as e:
        raise ValueError(f"{where / name}: not JSON ohd wrote: {e}") from None
    if not isinstance(record, dict):
        raise ValueError(f"{where / name}: expected a JSON object")
    return record


def _file_bounds(manifest: Dict[str, Any]) -> Tuple[Dict[str, int], int]:
    """The most bytes each file of a run may hold, as its manifest's `outputs` table declares
    them (an array's shape × 16 bytes and a header; its EXR the same), and the bound of any other
    file (a figure, a table): a fixed 256 MiB beyond four times the largest array."""
    bounds: Dict[str, int] = {}
    table = manifest.get("outputs")
    for file, e in (table.items() if isinstance(table, dict) else []):
        shape = e.get("shape") if isinstance(e, dict) else None
        if not isinstance(shape, list) or not all(isinstance(d, int) and not isinstance(d, bool) and d >= 0 for d in shape):
            continue
        n = 1
        for d in shape:
            n *= d
        data = 16 * n + _NPY_HEADER_BYTES
        for name in (file, e.get("stderr_file"), e.get("relative_error_file"), e.get("exr_file")):
            if isinstance(name, str):
                bounds[name] = max(bounds.get(name, 0), data)
    return bounds, _OTHER_BYTES + 4 * max(bounds.values(), default=0)


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

    def _axis(self, a: Dict[str, Any], n: int, file: str) -> np.ndarray:
        """The coordinates of one axis of the manifest's `outputs` table, of the `n` points the
        data of `file` have along it (a count the manifest states otherwise is refused before
        anything is made of it)."""

        def count(c: Any, key: str) -> int:
            if isinstance(c, bool) or not isinstance(c, int) or c != n:
                raise ValueError(f"manifest.json: outputs.{file}: axis {a.get('name')!r}: {key}.count = {c!r}, where {file} has {n}")
            return c

        if "bins" in a:
            b = a["bins"]
            return b["start"] + (np.arange(count(b.get("count"), "bins")) + 0.5) * b["width"]
        if "linear" in a:
            lin = a["linear"]
            return lin["first"] + lin["step"] * np.arange(count(lin.get("count"), "linear"))
        if "file" in a:
            name = a["file"]
            if name not in self.files:
                raise ValueError(f"manifest.json: outputs.{file}: axis {a.get('name')!r}: {name!r} is not among the run's files")
            values = _npy(self.files[name], name)
            if values.ndim != 1 or len(values) != n:
                raise ValueError(f"{name}: an axis of shape {values.shape}, where {file} has {n} points along it")
            return values
        labels = np.array(a.get("labels", []))
        if labels.ndim != 1 or len(labels) != n:
            raise ValueError(f"manifest.json: outputs.{file}: axis {a.get('name')!r}: {len(labels)} labels, where {file} has {n}")
        return labels

    def _read_outputs(self) -> Dict[str, Output]:
        table = self.manifest.get("outputs")
        if table is None:
            return self._guess_outputs()
        if not isinstance(table, dict):
            raise ValueError("manifest.json: outputs: expected a table")
        out = {}
        for file, e in table.items():
            if not isinstance(e, dict):
                raise ValueError(f"manifest.json: outputs.{file}: expected a table")
            if not file.endswith(".npy") or e.get("kind") == "axis" or file not in self.files:
                continue
            values = _npy(self.files[file], file)
            shape = e.get("shape")
            if shape is not None and list(values.shape) != shape:
                raise ValueError(f"manifest.json: outputs.{file}: shape {shape}, where the file holds {list(values.shape)}")
            err = e.get("stderr_file")
            if err in self.files:
                err_name = err
                err = _npy(self.files[err_name], err_name)
                if err.shape != values.shape:
                    raise ValueError(f"{err_name}: shape {list(err.shape)}, where {file} has {list(values.shape)}")
            else:
                err = None
            axes_table = e.get("axes", [])
            if not isinstance(axes_table, list) or not all(isinstance(a, dict) and "name" in a for a in axes_table):
                raise ValueError(f"manifest.json: outputs.{file}: axes: expected a list of tables with a name")
            if len(axes_table) not in (0, values.ndim):
                raise ValueError(f"manifest.json: outputs.{file}: {len(axes_table)} axes, where the file has {values.ndim} dimensions")
            axes = {a["name"]: self._axis(a, values.shape[i], file) for i, a in enumerate(axes_table)}
            stem = file[: -len(".npy")]
            out[stem] = Output(stem, values, err, axes, e.get("units"), e.get("kind"))
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
            values = _npy(data, name)
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
                        axes[v[len(prefix):-len(".npy")]] = _npy(self.files[v], v)
                if "x_range_m" in group and "pixels" in group:
                    (x0, x1), (y0, y1), (nx, ny) = group["x_range_m"], group["y_range_m"], group["pixels"]
                    if values.shape[-2:] != (ny, nx):  # (made only as large as the data are)
                        raise ValueError(f"manifest.json: pixels {[nx, ny]}, where {name} has shape {list(values.shape)}")
                    axes["x_m"] = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
                    axes["y_m"] = y1 - (np.arange(ny) + 0.5) * (y1 - y0) / ny  # rows: y descending
            out[stem] = Output(stem, values, _npy(err, stem + "_stderr.npy") if err is not None else None, axes, units)
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
        """The run (or scan) written into `dir`, read as its record lists it (see `load`)."""
        fd = _open_dir(os.fspath(dir), Path(dir))
        try:
            return cls._from_fd(fd, Path(dir))
        finally:
            os.close(fd)

    @classmethod
    def _from_fd(cls, fd: int, where: Path) -> "Result":
        try:
            os.stat(_MARKER, dir_fd=fd, follow_symlinks=False)
            marked = True
        except FileNotFoundError:
            marked = False
        manifest = None if marked else _record(fd, "manifest.json", where)
        if manifest is not None:
            names = manifest.get("files", [])
            if not isinstance(names, list) or not all(_plain(n) for n in names):
                bad = [n for n in names if not _plain(n)] if isinstance(names, list) else names
                raise ValueError(f"{where / 'manifest.json'}: files: {bad!r}: expected plain file names of this directory")
            bounds, other = _file_bounds(manifest)
            files: Dict[str, bytes] = {}
            for name in names:
                data = _read_in(fd, name, where, bounds.get(name, other))
                if data is not None:
                    files[name] = data
            # The manifest last, as written (read again: the bytes it has, not its parse).
            files["manifest.json"] = _read_in(fd, "manifest.json", where, _RECORD_BYTES) or b""
            return cls(files, [])
        scan = None if marked else _record(fd, "scan.json", where)
        if scan is not None:
            runs = [p.get("run") if isinstance(p, dict) else p for p in (scan.get("pointings") or [])]
        elif marked:
            # A scan stopped by Ctrl-C stays marked until `--resume` finishes it; its marker lists
            # the pointings written so far, the last one's manifest `interrupted`. Anything else
            # marked was killed (or is being written): not a run to load.
            text = _read_in(fd, _MARKER, where, _RECORD_BYTES) or b""
            lines = [l for l in text.decode("utf-8", "replace").splitlines() if not l.startswith("#")]
            # (The marker also lists an earlier output's pointing directories, first: in the
            # pointings' order, and those without a run of their own are passed over below.)
            runs = sorted({l[:-1] for l in lines if l.endswith("/") and _pointing(l[:-1])}, key=lambda n: int(n[9:]))
        else:
            raise FileNotFoundError(f"{where}: no finished run here (no manifest.json)")
        bad = [r for r in runs if not _pointing(r)]
        if bad:
            raise ValueError(f"{where / 'scan.json'}: pointings: {bad!r}: expected pointing directories of this directory")
        pointings = []
        for name in runs:
            try:
                sub = _open_dir(name, where, fd)
            except FileNotFoundError:
                if marked:
                    continue
                raise
            try:
                pointings.append(cls._from_fd(sub, where / name))
            except FileNotFoundError:
                if not marked:
                    raise
            finally:
                os.close(sub)
        if marked and not any("interrupted" in p.manifest for p in pointings):
            raise OSError(
                f"{where}: the output written here did not finish ({_MARKER} marks it: its writing was killed, or is under way); run it again"
            )
        files = {}
        if not marked:
            for name in _SCAN_FILES:
                data = _read_in(fd, name, where, _RECORD_BYTES if name.endswith(".json") else _OTHER_BYTES)
                if data is not None:
                    files[name] = data
        return cls(files, pointings)


def load(dir: Union[str, "os.PathLike[str]"]) -> Result:
    """The `Result` of a run written into `dir` (by `ohd run --out dir`, `ohd merge` or
    `Result.save`): the same estimates, outputs, manifest and files that `ohd.run` returned for it.
    A scan's directory gives its pointings in `.pointings`; a run or scan stopped by Ctrl-C loads
    with what it kept (its manifest's `interrupted`).

    Only what the run's record lists is read (manifest.json's `files`, scan.json's pointing
    directories), each a regular file of the directory itself (not a link) no larger than the
    manifest's shapes allow, and each array is checked against its manifest entry before any of
    its axes is made. Raises FileNotFoundError if `dir` holds no run (no manifest.json), an
    OSError if its writing did not finish (it is marked `ohd_incomplete.txt`: killed, or under
    way) or it holds a link or a special file where the run's files are, and a ValueError if a
    file does not match what its manifest says of it."""
    path = Path(dir)
    if not path.is_dir():
        raise FileNotFoundError(f"{os.fspath(dir)}: no finished run here (not a directory)")
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
    out        also write the outputs into this directory, as `ohd run --out` does (refused
               before any work if it cannot be used; locked while the run goes on).
    progress   True: a progress line on a terminal or in Jupyter; False: none; or a callable
               `progress(done_paths, total_paths)` called about every 50 ms.
    figures    write the PNG/SVG figures (as the CLI; False as `--no-figures`).
    grids      NumPy volumes by name, for a dict `config` whose `density` or `velocity` tables
               say `{"type": "npy", "array": NAME, "voxel_size_um": …}`: `array[i, j, k]` is voxel
               (i, j, k) along x, y, z (a density of shape (nx, ny, nz); a velocity in m/s of
               shape (nx, ny, nz, 3)). They run as `.npy` files given by `file` would, the same
               grids an OpenVDB file gives (configs/README.md, "NumPy volumes"). Each array is
               checked before anything is written — a real dtype that converts to float32, that
               shape, finite float32 values, within `run.memory_budget_gib` — else ConfigError
               naming its `array` key; the temporary files they are handed over in are removed
               before the run begins.

    Returns a `Result` (`estimates`, `outputs`/`result[name]`, `manifest`, `files`, `save()`).
    For the same configuration and seed the arrays are the bytes `ohd run --out` writes.
    A scan (several pointings) returns one `Result` per pointing in `.pointings`.
    Raises ConfigError (a ValueError) on an invalid configuration, an OSError on a file that
    cannot be read or written. Ctrl-C ends the run at its next batch boundary and raises
    KeyboardInterrupt with the result of the batches done as `.result` (its manifest's
    `interrupted` gives the batches done and planned; with `out`, that result is written there,
    with a checkpoint that `ohd run --resume` finishes);
    a second Ctrl-C stops at once, with nothing kept.
    """
    if grids is not None:
        if not isinstance(config, Mapping):
            raise TypeError("run(…, grids=…): give the configuration as a dict whose volumes name the arrays")
        sets = _sets(overrides, samples, seed, threads)
        # The arrays are checked before anything is written, and the files are gone before the
        # run begins: the resolved experiment holds its grids (a run stopped by Ctrl-C, or by an
        # error while resolving, leaves nothing behind; only a SIGKILL during `check` could).
        arrays = _checked_grids(config, grids, sets)
        with tempfile.TemporaryDirectory(prefix="ohd-grids-") as tmp:
            exp = check(_with_grid_files(config, arrays, Path(tmp)), overrides=sets)
        return _run(exp, out, _reporter(progress), figures)
    if isinstance(config, Experiment):
        if overrides is not None or samples is not None or seed is not None or threads is not None:
            raise TypeError("run(Experiment, …): give overrides, samples, seed, threads to check() instead")
        exp = config
    else:
        exp = check(config, overrides=_sets(overrides, samples, seed, threads))
    return _run(exp, out, _reporter(progress), figures)


def _budget(config: Mapping[str, Any], sets: List[str]) -> Tuple[int, str]:
    """The memory budget, bytes, of `config` with the `--set` assignments `sets` (the last
    assignment of run.memory_budget_gib, else the dict's, else the default; lowered under a
    process limit as the library lowers it), and the key its messages name."""
    gib: Any = None
    run_table = config.get("run")
    if isinstance(run_table, Mapping):
        gib = run_table.get("memory_budget_gib")
    for a in sets:
        key, _, value = a.partition("=")
        if key.strip() == "run.memory_budget_gib":
            gib = value.strip()
    try:
        gib = float(gib) if gib is not None else None
    except (TypeError, ValueError):
        gib = None
    if gib is not None and not (0 < gib <= 1e6):
        gib = None  # refused by the library, naming the key, once the configuration is read
    return _ohd.memory_budget(gib)


def _gib(n: int) -> str:
    return f"{n / (1 << 30):.1f} GiB" if n >= 1 << 30 else f"{n / (1 << 20):.1f} MiB"


def _grid_tables(config: Any, key: str = ""):
    """(key, table) of every `{"type": "npy", "array": NAME}` table of a configuration dict."""
    if isinstance(config, Mapping):
        if config.get("type") == "npy" and "array" in config:
            yield key, config
        for k, v in config.items():
            yield from _grid_tables(v, f"{key}.{k}" if key else str(k))
    elif isinstance(config, list):
        for i, v in enumerate(config):
            yield from _grid_tables(v, f"{key}.{i}")


def _config_error(key: str, message: str) -> ConfigError:
    err = ConfigError(f"config error: {key}: {message}")
    err.key = key  # type: ignore[attr-defined]
    return err


def _checked_grids(config: Mapping[str, Any], grids: Mapping[str, Any], sets: List[str]) -> Dict[str, np.ndarray]:
    """The arrays of `grids` that `config` names, each checked before anything is written or
    copied (issue 52, item 3: a broadcast view of one float became a 32 GB file): a real dtype
    (float32 or one that converts to it), the shape its table needs — (nx, ny, nz) for a density,
    (nx, ny, nz, 3) for a velocity — and float32 values that are finite, all of them within the
    memory budget. A ConfigError names the table's `array` key."""
    budget, budget_key = _budget(config, sets)
    arrays: Dict[str, np.ndarray] = {}
    keys: Dict[str, str] = {}
    total = 0
    for key, table in _grid_tables(config):
        name, akey = table["array"], f"{key}.array"
        if not isinstance(name, str) or name not in grids:
            given = ", ".join(map(str, grids)) or "none"
            raise _config_error(akey, f"= {name!r}: no such array in grids (given: {given})")
        velocity = key.rsplit(".", 1)[-1] == "velocity"
        expected = "(nx, ny, nz, 3)" if velocity else "(nx, ny, nz)"
        if name in keys:
            if velocity != keys[name].endswith("velocity"):
                raise _config_error(akey, f"= {name!r}: the array of {keys[name]} too, a {'density' if velocity else 'velocity'}")
            continue
        try:
            a = np.asanyarray(grids[name])
        except Exception as e:  # whatever the object's __array__ raises
            raise _config_error(akey, f"= {name!r}: not an array: {e}") from None
        if a.dtype.kind not in "biuf" or not np.can_cast(a.dtype, np.float32, casting="same_kind"):
            raise _config_error(akey, f"= {name!r}: dtype {a.dtype}: expected real numbers (float32, or a dtype that converts to it)")
        if a.ndim != (4 if velocity else 3) or (velocity and a.shape[3] != 3) or 0 in a.shape:
            raise _config_error(akey, f"= {name!r}: an array of shape {a.shape}: expected {expected}, each size ≥ 1")
        # As the library counts it: float32 voxels, a density twice while it is resolved.
        voxels = a.size // (3 if velocity else 1)
        nbytes = 4 * a.size * (1 if velocity else 2)
        if total + nbytes > budget:
            how = f"{voxels} voxels × {12 if velocity else 4} bytes{'' if velocity else ', 2 copies while resolving'}"
            before = f"; with the {_gib(total)} of the arrays before it that is" if total else ""
            raise _config_error(
                akey,
                f"= {name!r}: the array of shape {a.shape} would take {_gib(nbytes)} ({how}){before} above the memory budget of {budget / (1 << 30):.3g} GiB ({budget_key})",
            )
        total += nbytes
        keys[name] = key
        arrays[name] = a
    for name, a in arrays.items():
        # Finite as float32 (a float64 of 1e39 is not), a slab at a time: no copy of the whole.
        for i in range(a.shape[0]):
            with np.errstate(over="ignore"):
                slab = np.asarray(a[i], dtype=np.float32)
            if not np.isfinite(slab).all():
                where = tuple(int(j) for j in np.argwhere(~np.isfinite(slab))[0])
                raise _config_error(
                    f"{keys[name]}.array",
                    f"= {name!r}: element {(i, *where)} is {a[(i, *where)]!r}, not a finite float32: expected finite values",
                )
    unused = set(grids) - set(arrays)
    if unused:
        raise ValueError(f"grids: {', '.join(sorted(map(str, unused)))} not named by any `array` of the configuration")
    return arrays


def _with_grid_files(config: Mapping[str, Any], grids: Mapping[str, np.ndarray], tmp: Path) -> Dict[str, Any]:
    """A copy of `config` whose `{"type": "npy", "array": NAME}` tables name `.npy` files in `tmp`
    holding `grids[NAME]` (checked by `_checked_grids`) as float32, each written once, a slab at
    a time (a broadcast view is never made whole)."""
    written: Dict[str, str] = {}

    def walk(v: Any) -> Any:
        if isinstance(v, Mapping):
            out = {k: walk(x) for k, x in v.items()}
            if out.get("type") == "npy" and "array" in out:
                name = out.pop("array")
                if name not in written:
                    a = grids[name]
                    path = tmp / f"grid_{len(written)}.npy"
                    with open(path, "wb") as f:
                        header = {"descr": "<f4", "fortran_order": False, "shape": tuple(int(d) for d in a.shape)}
                        np.lib.format.write_array_header_2_0(f, header)
                        for i in range(a.shape[0]):
                            f.write(np.ascontiguousarray(a[i], dtype="<f4").tobytes())
                    written[name] = str(path)
                out["file"] = written[name]
            return out
        if isinstance(v, list):
            return [walk(x) for x in v]
        return v

    return walk(config)


def _run(exp: Experiment, out, report, figures: bool) -> Result:
    if out is not None:
        # The CLI's run into `out` (issue 52: one writer for both): the directory refused before
        # any work if it cannot be used, locked for the whole run, and after Ctrl-C the batches
        # done written with a checkpoint for `ohd run --resume`; the result is what it wrote.
        stopped = exp.run_to_dir(os.fspath(out), figures, report)
        return _stopped(Result._from_dir(Path(out)), stopped)
    if exp.pointings > 1:
        with tempfile.TemporaryDirectory(prefix="ohd-scan-") as tmp:
            stopped = exp.run_to_dir(tmp, figures, report)
            return _stopped(Result._from_dir(Path(tmp)), stopped)
    _, files, stopped = exp.run(figures, report)
    return _stopped(Result(dict(files)), stopped)


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
