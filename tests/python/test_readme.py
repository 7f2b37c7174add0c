"""The README's Python snippets, run against the outputs of the README's own commands.

The experiment files the README shows (```toml blocks whose first line is `# NAME.toml…`) are
written to a scratch directory, and the `ohd run` / `ohd check` lines of its ```sh blocks that use
the default experiment or those files are run there (`cargo run --release --` stands for the
binary), each run with few paths. Then every ```python block runs in that directory, on its own,
with matplotlib's Agg backend (one importing the `ohd` package only where it is installed): a
snippet that reads a file the commands do not write, or a name, shape or orientation the README
states wrongly, fails here.

The binary is $OHD_BINARY (.ci/run passes the one `cargo test --profile ci` built), else a release
build (validation/ohdpy.py).
"""
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()
SAMPLES = 100_000  # per run: enough for the walk-through's statements below, under a second each
COMMANDS = {"run", "check"}


def blocks(lang):
    return [m.group(1) for m in re.finditer(rf"^```{lang}\n(.*?)^```", README, re.M | re.S)]


def experiment_files():
    """{file name: text} of the README's experiment files."""
    files = {}
    for text in blocks("toml"):
        m = re.match(r"#\s*([\w.-]+\.toml)\b", text)
        if m:
            files[m.group(1)] = text
    return files


def commands(files):
    """The README's ohd commands that run here: argument lists after `ohd`."""
    out = []
    for text in blocks("sh"):
        for line in text.splitlines():
            words = shlex.split(line, comments=True)
            if words[:4] == ["cargo", "run", "--release", "--"]:
                words = ["ohd"] + words[4:]
            if len(words) < 2 or words[0] != "ohd" or words[1] not in COMMANDS:
                continue
            configs = [w for w in words[2:] if w.endswith(".toml")]
            if all(c in files for c in configs):
                out.append(words[1:])
    return out


def ohd_binary():
    if os.environ.get("OHD_BINARY"):
        return os.environ["OHD_BINARY"]
    sys.path.insert(0, str(ROOT / "validation"))
    import ohdpy

    return ohdpy.binary()


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    work = tmp_path_factory.mktemp("readme")
    files = experiment_files()
    for name, text in files.items():
        (work / name).write_text(text)
    binary = ohd_binary()
    for args in commands(files):
        if args[0] == "run":
            args = args + ["--samples", str(SAMPLES), "--quiet"]
        p = subprocess.run([binary] + args, cwd=work, capture_output=True, text=True)
        assert p.returncode == 0, f"ohd {' '.join(args)} failed:\n{p.stderr}"
    return work


def test_readme_has_what_this_test_runs():
    files = experiment_files()
    runs = [c for c in commands(files) if c[0] == "run"]
    assert "blood_slab.toml" in files
    assert ["run"] in runs, "the README's command that runs the default experiment"
    assert ["run", "blood_slab.toml"] in runs
    assert len(blocks("python")) >= 2


@pytest.mark.parametrize("index", range(len(blocks("python"))))
def test_python_snippet(workdir, index):
    code = blocks("python")[index]
    if re.search(r"^import ohd$", code, re.M):
        # The "From Python" snippet needs the package (`pip install ./python`; .ci/run installs it).
        pytest.importorskip("ohd")
    env = dict(os.environ, MPLBACKEND="Agg")
    p = subprocess.run([sys.executable, "-c", code], cwd=workdir, capture_output=True, text=True, env=env)
    assert p.returncode == 0, f"README python block {index} failed:\n{code}\n{p.stderr}"


def test_walkthrough_default_folder_and_doppler_line(workdir):
    """What the first-experiment walk-through says: outputs in out/blood_slab/, and a line at
    2nv/λ0 = 7.1 kHz (n = 1.4, v = 2 mm/s, λ0 = 785 nm) beside the band near 0 Hz."""
    import numpy as np

    d = workdir / "out" / "blood_slab"
    f = np.load(d / "camera_frequency_hz.npy")
    s = np.load(d / "camera_spectrum.npy")
    line = 2 * 1.4 * 2e-3 / 785e-9
    away = np.abs(f) > 2e3
    peak = f[away][np.argmax(s[away])]
    assert abs(peak - line) < 300, (peak, line)  # the bin (198 Hz wide) holding the line
    assert s[np.abs(f) < 1e3].sum() > 0


def test_image_orientation_matches_manifest(workdir):
    """The README's orientation statement, as the manifest records it."""
    import json

    m = json.loads((workdir / "out" / "vessel_in_tissue" / "manifest.json").read_text())

    def layouts(x):
        if isinstance(x, dict):
            for k, v in x.items():
                if k.endswith("layout") and isinstance(v, str):
                    yield v
                else:
                    yield from layouts(v)
        elif isinstance(x, list):
            for v in x:
                yield from layouts(v)

    found = list(layouts(m))
    assert found, "the manifest states no image layout"
    for layout in found:
        assert "descending" in layout and "top" in layout, layout


def test_configs_readme_key_reference_is_the_default_experiment(tmp_path):
    """configs/README.md's annotated key-by-key block is the default experiment: `ohd check`
    resolves it exactly as configs/default.toml (so its uncommented keys and values are real)."""
    text = (ROOT / "configs" / "README.md").read_text()
    block = re.search(r"^```toml\n(.*?)^```", text, re.M | re.S).group(1)
    (tmp_path / "block.toml").write_text(block)
    binary = ohd_binary()

    def resolved(path):
        p = subprocess.run([binary, "check", str(path)], capture_output=True, text=True)
        assert p.returncode == 0, p.stderr
        return p.stdout.split("\n", 1)[1]  # the first line names the file

    assert resolved(tmp_path / "block.toml") == resolved(ROOT / "configs" / "default.toml")
