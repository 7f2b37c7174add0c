"""The Python package `ohd` (python/): results identical to the CLI's, errors, dict configs,
overrides, Ctrl-C, sweeps, stubs, and the example that redraws the README's figures.

Needs the package installed (.ci/run installs it into its venv); skipped otherwise. The CLI is
$OHD_BINARY (.ci/run passes the one `cargo test --profile ci` built), else a release build.
"""
import json
import os
import re
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

ohd = pytest.importorskip("ohd")

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = ROOT / "configs"


@pytest.fixture(scope="module")
def binary():
    if os.environ.get("OHD_BINARY"):
        return os.environ["OHD_BINARY"]
    sys.path.insert(0, str(ROOT / "validation"))
    import ohdpy

    return ohdpy.binary()


@pytest.fixture(scope="module")
def cli(binary):
    def run(*args, check=True, binary=binary):
        p = subprocess.run([binary, *map(str, args)], capture_output=True, text=True)
        if check:
            assert p.returncode == 0, p.stderr
        return p

    return run


def data_files(names):
    """The files whose bytes do not depend on timing (the manifest and figures of timings do)."""
    return sorted(n for n in names if n.endswith((".npy", ".exr", ".csv", ".png", ".svg")) and "converge" not in n)


def assert_same_as_dir(result, d):
    on_disk = sorted(p.name for p in d.iterdir())
    assert sorted(result.files) == on_disk
    names = data_files(on_disk)
    assert names, on_disk
    for name in names:
        assert result.files[name] == (d / name).read_bytes(), name
    m = json.loads((d / "manifest.json").read_text())
    assert result.manifest["estimates"] == m["estimates"]
    assert result.manifest["files"] == m["files"]


def test_default_run_is_the_cli_run_byte_for_byte(cli, tmp_path):
    cli("run", "--samples", 30000, "--seed", 7, "--out", tmp_path / "cli", "--quiet")
    r = ohd.run(samples=30000, seed=7, progress=False)
    assert_same_as_dir(r, tmp_path / "cli")
    # save() writes what `ohd run --out` writes.
    r.save(tmp_path / "py")
    assert_same_as_dir(r, tmp_path / "py")
    assert sorted(os.listdir(tmp_path / "py")) == sorted(os.listdir(tmp_path / "cli"))
    # The arrays are the files' arrays, with their axes and units.
    s = r["camera_spectrum"]
    np.testing.assert_array_equal(s.values, np.load(tmp_path / "cli" / "camera_spectrum.npy"))
    np.testing.assert_array_equal(s.stderr, np.load(tmp_path / "cli" / "camera_spectrum_stderr.npy"))
    np.testing.assert_array_equal(s.axes["frequency_hz"], np.load(tmp_path / "cli" / "camera_frequency_hz.npy"))
    assert s.units == "fraction of emitted power per bin"
    img = r["camera_image"]
    assert img.values.shape == (32, 32)
    assert img.axes["x_m"][0] < img.axes["x_m"][-1] and img.axes["y_m"][0] > img.axes["y_m"][-1]  # row 0 = top
    assert abs(img.axes["x_m"][0] - (-0.0004 + 0.0004 / 32)) < 1e-15
    e = r.estimates["reflectance_diffuse"]
    m = json.loads((tmp_path / "cli" / "manifest.json").read_text())
    assert (e.value, e.stderr) == (m["estimates"]["reflectance_diffuse"]["value"], m["estimates"]["reflectance_diffuse"]["stderr"])
    assert not s.values.flags.writeable  # a view of the result's bytes


def test_ldh_camera_run_is_the_cli_run(cli, tmp_path):
    cfg = CONFIGS / "retina_ldh.toml"
    moments = "detectors.0.ldh.moments=true"
    cli("run", cfg, "--samples", 20000, "--no-figures", "--set", moments, "--out", tmp_path / "cli", "--quiet")
    r = ohd.run(cfg, samples=20000, figures=False, progress=False, overrides=[moments])
    assert_same_as_dir(r, tmp_path / "cli")
    assert r["camera_m0_plus"].values.ndim == 2 and r["camera_m0_plus"].stderr is not None
    # Every scalar of the outputs table is where its JSON pointer says.
    for pointer, e in r.manifest["outputs"].items():
        if pointer.startswith("/"):
            node = r.manifest
            for part in pointer.strip("/").split("/"):
                node = node[part]
            assert (node is None or isinstance(node, float)) and e["kind"] == "scalar", pointer
    assert r["camera_mean_frequency_minus"].units == "Hz"
    # Every array comes with its units and one axis per dimension (the manifest's `outputs`
    # table), axis files are not outputs, and a relative-error map is not a power.
    for name, o in r.outputs.items():
        assert o.units and o.kind, name
        assert [len(c) for c in o.axes.values()] == list(o.values.shape), (name, list(o.axes), o.values.shape)
    assert "camera_roi_frequency_hz" not in r.outputs
    assert r["camera_m0_plus"].units.startswith("fraction of emitted power per pixel")
    assert r["camera_image_relative_error"].units.startswith("1 ") and r["camera_image_relative_error"].kind == "relative_error"
    np.testing.assert_array_equal(r["camera_m0_plus"].axes["x_m"], r["camera_image"].axes["x_m"])
    spectrum = next(o for n, o in r.outputs.items() if n.startswith("camera_roi_") and n.endswith("_spectrum"))
    np.testing.assert_array_equal(spectrum.axes["frequency_hz"], np.load(tmp_path / "cli" / "camera_roi_frequency_hz.npy"))
    assert list(spectrum.axes["channel"]) == ["total", "static", "single_doppler", "multiple_doppler"]
    # ohd.load reads back the Result that ohd.run returned.
    loaded = ohd.load(tmp_path / "cli")
    assert loaded.estimates == r.estimates and set(loaded.outputs) == set(r.outputs)
    for name, o in r.outputs.items():
        l = loaded[name]
        np.testing.assert_array_equal(l.values, o.values)
        assert (l.stderr is None) == (o.stderr is None) and (l.units, l.kind) == (o.units, o.kind)
        assert list(l.axes) == list(o.axes)
    with pytest.raises(FileNotFoundError):
        ohd.load(tmp_path / "nothing")


def test_pulsatile_run_has_the_cycles_time_axis(cli, tmp_path):
    """An acquisition over the cardiac cycle: the windows' outputs carry the time axis (the
    windows' centres over one 70 bpm cycle), and the run is the CLI's byte for byte."""
    cfg = CONFIGS / "retina_pulsatile.toml"
    sets = ["detectors.0.image.pixels=[16, 16]"]
    cli("run", cfg, "--samples", 20000, "--no-figures", "--set", sets[0], "--out", tmp_path / "cli", "--quiet")
    r = ohd.run(cfg, samples=20000, figures=False, progress=False, overrides=sets)
    assert_same_as_dir(r, tmp_path / "cli")
    series = r["camera_m0_plus_windows"]
    assert series.kind == "pixel_series" and series.values.shape == (16, 16, 65)
    t = series.axes["time_s"]
    np.testing.assert_allclose(np.diff(t), 512 / 39000, rtol=1e-12)
    assert 0 < t[0] < t[-1] < 60 / 70
    waveform = r["camera_roi_artery_m0_plus_waveform"]
    assert list(waveform.axes["value"]) == ["systolic", "diastolic", "resistivity_index"]
    roi = r["camera_roi_artery_m0_plus_windows"].values
    assert waveform.values[0] == roi.max() and waveform.values[1] == roi.min()
    assert waveform.values[2] == pytest.approx((roi.max() - roi.min()) / roi.max(), rel=1e-12)
    assert r["camera_roi_artery_spectrum_windows"].values.shape[0] == 65


def test_scan_run_is_the_cli_scan(cli, tmp_path):
    cfg = CONFIGS / "wind_sunny.toml"
    cli("run", cfg, "--samples", 4000, "--no-figures", "--out", tmp_path / "cli", "--quiet")
    r = ohd.run(cfg, samples=4000, figures=False, progress=False)
    assert len(r.pointings) == 4
    for i, p in enumerate(r.pointings):
        assert_same_as_dir(p, tmp_path / "cli" / f"pointing_{i:02}")
    assert r.files["vad.csv"] == (tmp_path / "cli" / "vad.csv").read_bytes()
    m = r.pointings[0]["lidar_range_doppler"]
    assert m.axes["range_m"].shape == (m.values.shape[0],) and m.axes["frequency_hz"].shape == (m.values.shape[1],)
    np.testing.assert_array_equal(m.axes["range_m"], np.load(tmp_path / "cli" / "pointing_00" / "lidar_range_m.npy"))
    assert m.units.startswith("fraction of the pulse energy")


# The README's first experiment, as a dict.
BLOOD_SLAB = {
    "schema_version": 1,
    "name": "blood_slab",
    "run": {"samples": 20000},
    "source": {"wavelength_nm": 785, "profile": "disk", "radius_mm": 0.2},
    "media": {
        "blood": {
            "sigma_a_per_mm": 0.4,
            "sigma_s_per_mm": 20,
            "phase": {"type": "hg", "g": 0.985},
            "velocity": {"type": "uniform", "velocity_mm_per_s": [0, 0, 2]},
        }
    },
    "layers": [{"name": "blood", "thickness_mm": 1, "n": 1.4, "medium": "blood"}],
    "detectors": [
        {
            "name": "camera",
            "area": {"type": "rect", "size_mm": [0.8, 0.8]},
            "acceptance_half_angle_deg": 30,
            "include_specular": False,
            "spectrum": {"f_min_khz": -10, "f_max_khz": 10, "bins": 101},
            "image": {"pixels": [32, 32]},
        }
    ],
}


def test_dict_config_runs_as_its_toml_text(cli, tmp_path):
    text = ohd.check(BLOOD_SLAB).toml
    (tmp_path / "slab.toml").write_text(text)
    a = ohd.run(BLOOD_SLAB, progress=False, figures=False)
    b = ohd.run(text, progress=False, figures=False)
    cli("run", tmp_path / "slab.toml", "--no-figures", "--out", tmp_path / "cli", "--quiet")
    for name in data_files(a.files):
        assert a.files[name] == b.files[name] == (tmp_path / "cli" / name).read_bytes(), name
    assert a.manifest["name"] == "blood_slab"


def test_overrides_as_dict_list_and_keywords_agree():
    a = ohd.run(overrides={"run.samples": 10000, "run.seed": 3, "source.wavelength_nm": 780}, progress=False, figures=False)
    b = ohd.run(overrides=["source.wavelength_nm=780"], samples=10000, seed=3, progress=False, figures=False)
    c = ohd.run(samples=10000, seed=3, progress=False, figures=False)
    assert a.files["camera_spectrum.npy"] == b.files["camera_spectrum.npy"]
    assert a.files["camera_spectrum.npy"] != c.files["camera_spectrum.npy"]
    assert a.manifest["overrides"] == ["run.samples=10000", "run.seed=3", "source.wavelength_nm=780"]
    assert a.manifest["config"]["source"]["wavelength_nm"] == 780
    # A number of paths written as pmcx takes it: 1e4 is 10000; a fraction is refused.
    d = ohd.run(overrides=["source.wavelength_nm=780"], samples=1e4, seed=3, progress=False, figures=False)
    assert d.files["camera_spectrum.npy"] == b.files["camera_spectrum.npy"]
    with pytest.raises(ValueError, match="whole number of paths"):
        ohd.run(samples=2.5, progress=False, figures=False)


def test_config_errors_are_value_errors_with_the_key_and_the_cli_message(cli, tmp_path):
    with pytest.raises(ohd.ConfigError) as e:
        ohd.check(overrides={"layers.0.thickness_mm": -1})
    assert isinstance(e.value, ValueError)
    assert e.value.key.startswith("layers[0].thickness_mm"), e.value.key
    p = cli("check", "--set", "layers.0.thickness_mm=-1", check=False)
    assert p.returncode == 2
    assert p.stderr.strip() == f"ohd: {e.value}"
    # An unknown key in a dict names its path.
    with pytest.raises(ohd.ConfigError) as e:
        ohd.check(dict(BLOOD_SLAB, run={"samples": 10, "sample": 3}))
    assert "run.sample" in e.value.key + str(e.value)
    # A value Python has and TOML has not.
    with pytest.raises(ohd.ConfigError) as e:
        ohd.check(dict(BLOOD_SLAB, run={"samples": object()}))
    assert e.value.key == "run.samples"
    # TOML syntax errors.
    with pytest.raises(ohd.ConfigError):
        ohd.check("schema_version = = 1\n")
    with pytest.raises(ValueError):
        ohd.run(samples=-1)


def test_cyclic_and_deeply_nested_values_raise_config_errors():
    """Issue 33, item 9: a dict or list that contains itself, or nesting thousands of levels deep,
    in a configuration or an override overflowed the conversion's stack and killed the
    interpreter. Each is a ConfigError naming the key path."""
    d = {}
    d["x"] = d
    a = []
    a.append(a)
    for config, overrides, key in [
        (dict(BLOOD_SLAB, extra=d), None, "extra.x"),
        (None, {"run.samples": d}, "run.samples.x"),
        (dict(BLOOD_SLAB, extra=a), None, "extra[0]"),
        (None, {"source.position_mm": a}, "source.position_mm[0]"),
    ]:
        with pytest.raises(ohd.ConfigError) as e:
            ohd.check(config, overrides=overrides)
        assert e.value.key.startswith(key), e.value.key
        assert "cycle" in str(e.value)
    deep_dict, deep_list = {}, []
    for _ in range(30000):
        deep_dict, deep_list = {"x": deep_dict}, [deep_list]
    for config, overrides, key in [
        (dict(BLOOD_SLAB, extra=deep_dict), None, "extra.x.x"),
        (dict(BLOOD_SLAB, extra=deep_list), None, "extra[0][0]"),
        (None, {"run.samples": deep_dict}, "run.samples.x.x"),
        (None, {"run.samples": deep_list}, "run.samples[0][0]"),
    ]:
        with pytest.raises(ohd.ConfigError) as e:
            ohd.check(config, overrides=overrides)
        assert e.value.key.startswith(key), e.value.key
        assert "levels deep" in str(e.value)
    # A list shared by two keys is no cycle.
    shared = [0.0, 0.0, -1.0]
    ohd.check(dict(BLOOD_SLAB, source=dict(BLOOD_SLAB["source"], position_mm=shared)))


def test_file_errors_are_os_errors(tmp_path):
    with pytest.raises(FileNotFoundError) as e:
        ohd.run(tmp_path / "missing.toml")
    assert "missing.toml" in str(e.value)
    with pytest.raises(OSError):
        ohd.check(tmp_path)  # a directory
    (tmp_path / "file").write_text("x")
    r = ohd.run(samples=1000, progress=False, figures=False)
    with pytest.raises(OSError):
        r.save(tmp_path / "file" / "out")
    with pytest.raises(OSError):
        ohd.run(samples=1000, progress=False, out=tmp_path / "file" / "out")


def test_hostile_configs_raise_python_errors_never_panics():
    """Inputs meant to break the parser and resolver (tests/configs/bad and a few more): every one
    either resolves or raises a ValueError/OSError, never a panic or a crash."""
    files = sorted((ROOT / "tests" / "configs").rglob("*.toml"))
    assert files
    texts = [f.read_text(errors="replace") for f in files]
    texts += ["schema_version = 1\n" + "[a]" * 5000, "x = " + "[" * 100000, "schema_version = 1e999\n", "\x00"]
    for text in texts:
        try:
            ohd.check(text if "\n" in text or "=" in text else text + "\n=")
        except (ValueError, OSError):
            pass


def test_second_ctrl_c_raises_keyboard_interrupt_within_a_batch(tmp_path):
    script = textwrap.dedent(
        """
        import os, signal, threading, time, ohd
        for t in (1.0, 1.3):
            threading.Timer(t, os.kill, (os.getpid(), signal.SIGINT)).start()
        t = time.monotonic()
        try:
            ohd.run(samples=10**9, progress=False, figures=False, out="out")
        except KeyboardInterrupt as e:
            print(time.monotonic() - t, hasattr(e, "result"))
        """
    )
    p = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    elapsed, kept = p.stdout.split()
    # The first Ctrl-C waits for the batches in flight (of 10⁹/32 paths: minutes); the second
    # cancels them within a few thousand paths, keeping nothing.
    assert 1.3 <= float(elapsed) < 2.3, elapsed
    assert kept == "False"
    assert not (tmp_path / "out").exists()  # nothing written


def test_ctrl_c_keeps_the_batches_done(tmp_path):
    script = textwrap.dedent(
        """
        import json, os, signal, threading, ohd
        threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT)).start()
        try:
            ohd.run(samples=4_000_000, overrides={"run.batches": 64}, progress=False, figures=False, out="out")
            print("finished")
        except KeyboardInterrupt as e:
            r = e.result
            print(json.dumps([r.manifest["interrupted"], r.manifest["samples"], r.manifest["batches"],
                              r.estimates["reflectance_diffuse"].value, r.estimates["reflectance_diffuse"].stderr,
                              str(e)]))
        """
    )
    p = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() != "finished", "the run ended before Ctrl-C (4·10⁶ paths take ≈ 20 s)"
    cut, samples, batches, rd, rd_err, message = json.loads(p.stdout)
    assert 1 <= cut["batches"] < cut["planned_batches"] == 64, cut
    assert batches == cut["batches"] and samples == batches * (4_000_000 // 64)
    assert "of 64 batches" in message
    # An estimate with the σ of the batches done (a few 10⁵ paths: a few 0.1 %).
    assert rd > 0 and 0 < rd_err < 0.02 * rd, (rd, rd_err)
    written = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert written["interrupted"] == cut
    # As the CLI's: a checkpoint that `ohd run --resume` finishes.
    assert (tmp_path / "out" / "checkpoint.ohd").is_file()


def test_progress_callback_sees_the_run():
    seen = []
    # About 2 s on 2 cores: the callback is polled every 50 ms, so it sees the run in between.
    ohd.run(samples=400_000, progress=lambda d, t: seen.append((d, t)), figures=False)
    assert seen[-1] == (400_000, 400_000)
    assert len({d for d, _ in seen}) > 2, seen
    assert all(t == 400_000 and 0 <= d <= t for d, t in seen)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)


def test_sweep_is_the_runs_one_by_one():
    runs = ohd.sweep(None, "source.wavelength_nm", [780, 790], samples=10000, progress=False, figures=False)
    assert [r.manifest["config"]["source"]["wavelength_nm"] for r in runs] == [780, 790]
    one = ohd.run(overrides={"source.wavelength_nm": 790}, samples=10000, progress=False, figures=False)
    assert runs[1].files["camera_spectrum.npy"] == one.files["camera_spectrum.npy"]
    pts = ohd.sweep(BLOOD_SLAB, points=[{"run.seed": 1}, ["run.seed=2"]], progress=False, figures=False)
    assert [r.manifest["seed"] for r in pts] == [1, 2]
    with pytest.raises(ohd.ConfigError):
        ohd.sweep(None, "run.samples", [10, -1], progress=False)


def test_mie_is_ohd_mie(cli):
    p = cli("mie", "--m-real", "1.33", "--x", "10")
    want = json.loads(p.stdout)
    got = ohd.mie(m_real=1.33, x=10, angles=64)
    assert {k: got[k] for k in want} == want
    assert got["theta_deg"].shape == got["phase_per_sr"].shape == (64,)
    t = np.radians(got["theta_deg"])
    y = got["phase_per_sr"] * np.sin(t)
    integral = 2 * np.pi * np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t))  # trapezoids
    assert abs(integral - 1) < 0.02
    with pytest.raises(ValueError, match="x="):
        ohd.mie(m_real=1.33, x=-1)


def test_check_prints_what_ohd_check_prints(cli):
    assert str(ohd.check(CONFIGS / "fmcw_target.toml")) == cli("check", CONFIGS / "fmcw_target.toml").stdout
    assert str(ohd.check()) == cli("check").stdout


def test_stubs_and_docs_are_installed():
    pkg = Path(ohd.__file__).parent
    for f in ("__init__.pyi", "_ohd.pyi", "py.typed"):
        assert (pkg / f).is_file(), f
    for f in (ohd.run, ohd.check, ohd.sweep, ohd.mie, ohd.converge, ohd.Result):
        assert f.__doc__ and len(f.__doc__) > 80, f
    assert "overrides" in ohd.run.__doc__ and "KeyboardInterrupt" in ohd.run.__doc__


def test_console_script_is_the_binary(cli, tmp_path):
    """`pip install ./python` also installs the `ohd` command (one build): it is the binary's code,
    so its run writes the binary's bytes, its report and exit statuses are the binary's."""
    script = Path(sys.executable).parent / "ohd"
    assert script.is_file(), f"no console script beside {sys.executable}"
    runs = {}
    for name, binary in (("script", {"binary": str(script)}), ("binary", {})):
        out = tmp_path / name
        p = cli("run", "--samples", "2e4", "--seed", "3", "--out", out, **binary)
        assert "reflectance_diffuse" in p.stdout, p.stdout
        runs[name] = {f.name: f.read_bytes() for f in out.iterdir() if f.suffix == ".npy"}
    assert len(runs["script"]) >= 6 and runs["script"] == runs["binary"]
    version = subprocess.run([str(script), "--version"], capture_output=True, text=True)
    assert version.returncode == 0 and ohd.__version__ in version.stdout
    bad = subprocess.run([str(script), "run", "--set", "run.samples=-1"], cwd=tmp_path, capture_output=True, text=True)
    assert bad.returncode == 2 and "run.samples" in bad.stderr, bad.stderr


def test_version_is_the_changelogs_and_the_manifests():
    changelog = (ROOT / "CHANGELOG.md").read_text()
    newest = next(line[4:].split("]")[0] for line in changelog.splitlines() if line.startswith("## ["))
    assert ohd.__version__ == newest
    assert ohd.run(samples=1000, progress=False, figures=False).manifest["ohd_version"] == newest


def test_example_redraws_the_readme_figures(tmp_path):
    """python/examples/default_figure.py runs the default experiment and writes the README's two
    figures: the same PNG bytes as media/readme/."""
    script = ROOT / "python" / "examples" / "default_figure.py"
    env = dict(os.environ, MPLBACKEND="Agg")
    p = subprocess.run([sys.executable, str(script), str(tmp_path)], capture_output=True, text=True, env=env, timeout=600)
    assert p.returncode == 0, p.stderr
    for name in ("default_m0_plus.png", "default_spectrum.png"):
        assert (tmp_path / name).read_bytes() == (ROOT / "media" / "readme" / name).read_bytes(), name
    assert (tmp_path / "default_spectrum_matplotlib.png").stat().st_size > 10_000


def test_converge_writes_the_study(tmp_path):
    study = ohd.converge(out=tmp_path / "c", samples=40_000, rungs=2, budget_seconds=60, figures=False)
    assert (tmp_path / "c" / "converge.csv").is_file()
    assert study["log"] and isinstance(study, dict)
    with pytest.raises(ohd.ConfigError):
        ohd.converge(out=tmp_path / "d", overrides={"run.samples": -1}, samples=1000, rungs=2)


def test_result_shows_itself_in_jupyter():
    r = ohd.run(samples=3200, seed=1, progress=False)
    page = r._repr_html_()
    assert page.startswith("<div><b>ohd.Result</b>") and f"{r.manifest['samples']} paths" in page
    # The main output's figure inline, and every scalar estimate in the table.
    assert r.main_figure() is not None and r.main_figure().startswith(b"\x89PNG")
    assert "data:image/png;base64," in page and "reflectance_diffuse" in page and "<table>" in page
    assert "data:image/png" not in ohd.run(samples=3200, seed=1, progress=False, figures=False)._repr_html_()


def test_api_reference_is_current_and_complete():
    """python/API.md is what python/apidoc.py generates from the installed package, and every
    public name (ohd.__all__, their public methods and properties) is documented."""
    p = subprocess.run([sys.executable, str(ROOT / "python" / "apidoc.py"), "--check"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr


@pytest.mark.parametrize(
    "script, args, figure",
    [
        ("ldh_image.py", ["--samples", "20000"], "ldh_image.png"),
        ("lidar_vad.py", ["--samples", "20000"], "lidar_vad.png"),
        ("dcs_fit.py", ["--samples", "20000"], "dcs_fit.png"),
        ("mie_table.py", [], "mie_table.png"),
        ("numpy_phantom.py", ["--samples", "20000"], "numpy_phantom.png"),
    ],
)
def test_gallery_examples_run(tmp_path, script, args, figure):
    """Every example of python/examples/ runs (at reduced samples) and writes its figure."""
    path = ROOT / "python" / "examples" / script
    env = dict(os.environ, MPLBACKEND="Agg")
    p = subprocess.run([sys.executable, str(path), *args, str(tmp_path)], capture_output=True, text=True, env=env, timeout=600)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / figure).read_bytes().startswith(b"\x89PNG")


def _phantom_config(density):
    """A blood-like slab over tissue whose top layer's density is `density` (a dict)."""
    return {
        "schema_version": 1,
        "name": "phantom",
        "run": {"samples": 20000, "seed": 3},
        "source": {"wavelength_nm": 785},
        "media": {
            "slab": {
                "sigma_a_per_mm": 0.2,
                "sigma_s_per_mm": 10,
                "phase": {"type": "hg", "g": 0.9},
                "velocity": {"type": "uniform", "velocity_mm_per_s": [0, 0, 2]},
                "density": density,
            }
        },
        "layers": [{"thickness_mm": 0.5, "n": 1.37, "medium": "slab"}],
        "detectors": [{"name": "probe", "area": {"type": "disk", "radius_mm": 1}, "spectrum": {"f_min_khz": -10, "f_max_khz": 10, "bins": 41}}],
    }


def test_numpy_volumes_run_as_npy_files(tmp_path):
    """`ohd.run(cfg, grids={name: array})` runs the array as the same volume a `.npy` file gives
    (`density = {type = "npy", file = …}`): the same bytes; an unknown or unused name is an error."""
    rng = np.random.default_rng(5)
    phantom = rng.uniform(0.2, 2.0, size=(12, 10, 8))  # float64: stored as float32, as a file would be
    np.save(tmp_path / "phantom.npy", phantom.astype(np.float32))
    place = {"type": "npy", "voxel_size_um": 100, "translate_mm": [-0.55, -0.45, 0.03]}
    from_array = ohd.run(_phantom_config({**place, "array": "phantom"}), grids={"phantom": phantom}, progress=False, figures=False)
    from_file = ohd.run(_phantom_config({**place, "file": str(tmp_path / "phantom.npy")}), progress=False, figures=False)
    npy = [n for n in from_file.files if n.endswith(".npy")]
    assert len(npy) >= 3 and all(from_array.files[n] == from_file.files[n] for n in npy)
    uniform = ohd.run(_phantom_config({"type": "ramp", "axis": "z", "from_mm": 0, "to_mm": 1, "density_from": 1, "density_to": 1}), progress=False, figures=False)
    assert any(uniform.files[n] != from_file.files[n] for n in npy), "the volume changed nothing"
    with pytest.raises(ohd.ConfigError, match="no such array"):
        ohd.run(_phantom_config({**place, "array": "other"}), grids={"phantom": phantom}, progress=False)
    with pytest.raises(ValueError, match="not named"):
        ohd.run(_phantom_config({**place, "file": str(tmp_path / "phantom.npy")}), grids={"phantom": phantom}, progress=False)


def _grids_config(density=None, velocity=None, budget_gib=None):
    cfg = _phantom_config(density or {"type": "ramp", "axis": "z", "from_mm": 0, "to_mm": 1, "density_from": 1, "density_to": 1})
    if velocity is not None:
        cfg["media"]["slab"]["velocity"] = velocity
    if budget_gib is not None:
        cfg["run"]["memory_budget_gib"] = budget_gib
    return cfg


def test_numpy_volumes_are_checked_before_anything_is_written(tmp_path, monkeypatch):
    """Issue 52, item 3: every array is checked — dtype, shape, finite float32 values, its size
    against the memory budget — before anything is written, and refused naming its `array` key;
    the temporary files are gone once the experiment is resolved, before the run. (They were
    written first, whatever they held: a broadcast view of one float became a 32 GB file.)"""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    place = {"type": "npy", "array": "v", "voxel_size_um": 100}
    writes = []
    real_open = open

    def spy(path, *a, **k):
        if str(path).startswith(str(tmp)):
            writes.append(str(path))
        return real_open(path, *a, **k)

    monkeypatch.setattr("builtins.open", spy)
    monkeypatch.setattr(np, "save", lambda *a, **k: writes.append("np.save"))
    # 128³ voxels, counted twice (8 bytes each) as the library counts a density: 16 MiB over 1 MiB.
    view = np.broadcast_to(np.float32(1), (128, 128, 128))
    with pytest.raises(ohd.ConfigError) as e:
        ohd.run(_grids_config(place, budget_gib=1 / 1024), grids={"v": view}, progress=False)
    assert e.value.key == "media.slab.density.array", e.value
    assert "16.0 MiB" in str(e.value) and "above the memory budget of 0.000977 GiB (run.memory_budget_gib)" in str(e.value), e.value
    # The budget from overrides, the same.
    with pytest.raises(ohd.ConfigError, match="above the memory budget") as e:
        ohd.run(_grids_config(place), grids={"v": view}, overrides={"run.memory_budget_gib": 1 / 1024}, progress=False)
    assert e.value.key == "media.slab.density.array"
    bad = np.ones((12, 10, 8))
    bad[3, 4, 5] = np.nan
    too_big = np.full((12, 10, 8), 1e39)  # finite as float64, inf as float32
    for a, words in [
        (bad, "element (3, 4, 5)"),
        (too_big, "not a finite float32"),
        (np.ones((12, 10, 8), dtype=complex), "dtype complex128"),
        (np.full((12, 10, 8), "1"), "dtype <U1"),
        (np.ones((12, 10)), "expected (nx, ny, nz)"),
        (np.ones((12, 10, 0)), "each size ≥ 1"),
    ]:
        with pytest.raises(ohd.ConfigError, match=re.escape(words)) as e:
            ohd.run(_grids_config(place), grids={"v": a}, progress=False)
        assert e.value.key == "media.slab.density.array", e.value
    flow = {"type": "npy", "array": "v", "voxel_size_um": 100}
    with pytest.raises(ohd.ConfigError, match=re.escape("expected (nx, ny, nz, 3)")) as e:
        ohd.run(_grids_config(velocity=flow), grids={"v": np.ones((4, 4, 4))}, progress=False)
    assert e.value.key == "media.slab.velocity.array"
    assert writes == [] and os.listdir(tmp) == []
    # A volume that runs: its file is gone while the run goes on.
    seen = []
    r = ohd.run(
        _grids_config({**place, "translate_mm": [-0.55, -0.45, 0.03]}),
        grids={"v": np.broadcast_to(np.float32(0.5), (12, 10, 8))},
        samples=2000,
        progress=lambda done, total: seen.append(os.listdir(tmp)),
        figures=False,
    )
    assert r.estimates and seen and all(s == [] for s in seen), seen


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    """A small run of the default experiment written by ohd.run(out=…), to copy and tamper with."""
    d = tmp_path_factory.mktemp("small") / "run"
    ohd.run(samples=2000, seed=1, threads=1, progress=False, out=d)
    return d


def _copy(src, dst):
    import shutil

    shutil.copytree(src, dst)
    return dst


def test_load_refuses_a_directory_whose_writing_did_not_finish(small_run, tmp_path):
    """Issue 52, item 7: a directory marked incomplete (ohd_incomplete.txt: its writing was
    killed) is not a finished run, whatever manifest it still holds; a run stopped by Ctrl-C is
    (its manifest's `interrupted`, no marker)."""
    d = _copy(small_run, tmp_path / "r")
    assert ohd.load(d).estimates
    (d / "ohd_incomplete.txt").write_text("# ohd (process 1) is writing into this directory\ncamera_image.npy\n")
    with pytest.raises(OSError, match="did not finish") as e:
        ohd.load(d)
    assert str(d) in str(e.value)
    (d / "ohd_incomplete.txt").unlink()
    m = json.loads((d / "manifest.json").read_text())
    m["interrupted"] = {"batches": 1, "planned_batches": 4}
    (d / "manifest.json").write_text(json.dumps(m))
    assert ohd.load(d).manifest["interrupted"]["batches"] == 1
    # A scan stays marked when Ctrl-C stops it, its last pointing `interrupted`: it loads with
    # the pointings written; marked with no pointing interrupted, it was killed.
    scan = tmp_path / "scan"
    scan.mkdir()
    (scan / "ohd_incomplete.txt").write_text("# ohd (process 1) is writing into this directory\npointing_00/\n")
    _copy(small_run, scan / "pointing_00")
    with pytest.raises(OSError, match="did not finish"):
        ohd.load(scan)
    (scan / "pointing_00" / "manifest.json").write_text(json.dumps(m))
    r = ohd.load(scan)
    assert len(r.pointings) == 1 and r.pointings[0].manifest["interrupted"]["batches"] == 1 and r.files == {}


def test_load_checks_the_manifest_against_the_files(small_run, tmp_path):
    """Issue 52, item 7: the manifest's shapes and axis counts are checked against the arrays'
    own headers before any axis is made (a one-line edit of a count made ohd.load allocate
    7.45 GiB), and an array whose header does not match its bytes is refused, naming the file."""

    def tampered(edit):
        d = _copy(small_run, tmp_path / f"r{len(list(tmp_path.iterdir()))}")
        m = json.loads((d / "manifest.json").read_text())
        edit(m, d)
        (d / "manifest.json").write_text(json.dumps(m))
        return d

    def count(m, d):
        m["outputs"]["camera_image.npy"]["axes"][0]["bins"]["count"] = 1_000_000

    def shape(m, d):
        m["outputs"]["camera_image.npy"]["shape"] = [32, 33]

    def header(m, d):
        b = (d / "camera_image.npy").read_bytes()
        (d / "camera_image.npy").write_bytes(b.replace(b"(32, 32)", b"(99999, 32)", 1))

    for edit, words in [(count, "bins.count = 1000000"), (shape, "shape [32, 33]"), (header, "bytes of data where its header")]:
        d = tampered(edit)
        with pytest.raises(ValueError, match=re.escape(words)) as e:
            ohd.load(d).outputs
        assert "camera_image.npy" in str(e.value), e.value


def test_load_reads_only_the_runs_own_files(small_run, tmp_path):
    """Issue 52, item 7: ohd.load reads what the manifest lists and nothing else, each a regular
    file of the directory itself within the size its manifest allows: a link (to a 40 GB file,
    read whole before), a FIFO, an oversized file, a name with a path and a pointing directory
    that is a link are refused naming them; a file the manifest does not list is not read."""
    outside = tmp_path / "outside"
    outside.mkdir()
    big = outside / "big.bin"
    with open(big, "wb") as f:
        f.truncate(40 << 30)  # sparse: no disk, and never read
    d = _copy(small_run, tmp_path / "link")
    (d / "camera_image.png").unlink()
    (d / "camera_image.png").symlink_to(big)
    with pytest.raises(OSError, match="symbolic link") as e:
        ohd.load(d)
    assert "camera_image.png" in str(e.value)
    d = _copy(small_run, tmp_path / "big")
    os.truncate(d / "camera_image.png", 40 << 30)
    with pytest.raises(ValueError, match="more than the") as e:
        ohd.load(d)
    assert "camera_image.png" in str(e.value)
    d = _copy(small_run, tmp_path / "fifo")
    (d / "camera_image.svg").unlink()
    os.mkfifo(d / "camera_image.svg")
    with pytest.raises(OSError, match="not a regular file"):
        ohd.load(d)
    d = _copy(small_run, tmp_path / "path")
    m = json.loads((d / "manifest.json").read_text())
    m["files"].append("../outside/big.bin")
    (d / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(ValueError, match="plain file names"):
        ohd.load(d)
    d = _copy(small_run, tmp_path / "extra")
    (d / "notes.txt").write_text("mine")
    assert "notes.txt" not in ohd.load(d).files
    # A scan whose pointing directory is a link to a run elsewhere.
    scan = tmp_path / "scan"
    scan.mkdir()
    (scan / "scan.json").write_text(json.dumps({"gates": [], "pointings": [{"run": "pointing_00"}]}))
    (scan / "pointing_00").symlink_to(small_run)
    with pytest.raises(OSError, match="not a directory") as e:
        ohd.load(scan)
    assert "pointing_00" in str(e.value)


# Issue 52, finding 1: a scan's `Result.save` is the CLI's writer (a8c4817 wrote it by path in
# Python: it followed planted links, wrote into and removed from a linked pointing directory, and
# took no lock).
@pytest.fixture(scope="module")
def scan_result():
    return ohd.run(CONFIGS / "wind_sunny.toml", samples=512, figures=False, progress=False)


def snapshot(d):
    return {p.relative_to(d): (p.is_symlink(), p.read_bytes() if p.is_file() else None) for p in d.rglob("*")}


def test_scan_save_replaces_planted_links_and_never_follows_them(scan_result, tmp_path):
    canary = tmp_path / "canary"
    canary.write_text("keep")
    d = tmp_path / "out"
    (d / "pointing_01").mkdir(parents=True)
    # At the outputs' names and at the temporary names a8c4817 wrote through (`.NAME.tmp`).
    names = ["vad.csv", "scan.json", ".vad.csv.tmp", ".scan.json.tmp"]
    for name in names + ["pointing_01/manifest.json", "pointing_01/lidar_range_m.npy"]:
        (d / name).symlink_to(canary)
    scan_result.save(d)
    assert canary.read_text() == "keep"
    for name in ["vad.csv", "scan.json"]:
        assert not (d / name).is_symlink() and (d / name).read_bytes() == scan_result.files[name]
    p = d / "pointing_01"
    for name in ["manifest.json", "lidar_range_m.npy"]:
        assert not (p / name).is_symlink() and (p / name).read_bytes() == scan_result.pointings[1].files[name]
    assert not list(d.rglob(".ohd-lock")) and not list(d.rglob("ohd_incomplete.txt"))
    assert ohd.load(d).pointings[1].files == scan_result.pointings[1].files


def test_scan_save_refuses_a_pointing_directory_that_links_elsewhere(scan_result, tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    # A manifest there lists a file of the user's: it must not be removed.
    (elsewhere / "manifest.json").write_text('{"ohd_version": "0", "files": ["keep.npy"]}')
    (elsewhere / "keep.npy").write_text("the user's")
    before = snapshot(elsewhere)
    d = tmp_path / "out"
    d.mkdir()
    (d / "pointing_00").symlink_to(elsewhere)
    with pytest.raises(OSError) as e:
        scan_result.save(d)
    assert "pointing_00" in str(e.value)
    assert snapshot(elsewhere) == before
    assert [p.name for p in d.iterdir()] == ["pointing_00"]


def test_a_save_into_a_directory_being_written_is_refused(binary, scan_result, tmp_path):
    for held in ["out", "out/pointing_01"]:
        d = tmp_path / held
        writer = subprocess.Popen(
            [binary, "run", "-q", "--threads", "1", "--samples", "100000000", "--out", d],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            t = time.time()
            while not (d / ".ohd-lock").exists() and time.time() - t < 60:
                time.sleep(0.005)
            with pytest.raises(OSError) as e:
                scan_result.save(tmp_path / "out")
            assert "in use" in str(e.value) and str(d) in str(e.value) and f"process {writer.pid}" in str(e.value)
        finally:
            writer.kill()
            writer.wait()
        assert not (tmp_path / "out" / "scan.json").exists()
        assert not (tmp_path / "out" / "pointing_00" / "manifest.json").exists()


def test_run_into_out_holds_the_directory_while_it_runs(cli, tmp_path):
    """Issue 52: `ohd.run(out=…)` is the CLI's run into the directory, locked for the whole run
    (it ran in memory, then saved: another writer could take the directory meanwhile)."""
    script = "import ohd; ohd.run(samples=10**9, progress=False, figures=False, out='out')"
    p = subprocess.Popen([sys.executable, "-c", script], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        t = time.monotonic()
        while not (tmp_path / "out" / ".ohd-lock").exists() and time.monotonic() - t < 60:
            time.sleep(0.01)
        other = cli("run", "--samples", 1000, "--out", tmp_path / "out", "-q", check=False)
    finally:
        p.kill()
        p.wait()
    assert other.returncode == 2, other.stderr
    assert "in use" in other.stderr and f"process {p.pid}" in other.stderr, other.stderr
    assert not (tmp_path / "out" / "manifest.json").exists()
