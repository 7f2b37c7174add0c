"""The Python package's writes against planted links (issue 52, item 1): `Result.save` of a scan
and of a plain run, and `ohd.run(out=…)`, with a symbolic link planted at every name the save
creates — each file, each pointing's directory and files, the lock, the marker — one at a time and
all at once, pointing to a canary file, to a directory elsewhere, to a FIFO, or to nothing.

What must hold whatever was planted (configs/README.md, "The output directory"): nothing outside
the output directory changes (the canary's bytes, the directory elsewhere's listing, the FIFO stays
a FIFO); a save either ends with the run's files in place, each a regular file with the bytes held,
or is refused with an OSError naming the path, having written nothing; no lock or temporary is left.

Needs the package installed (.ci/run installs it into its venv); skipped otherwise.
"""
import os
import stat
from pathlib import Path

import pytest

ohd = pytest.importorskip("ohd")

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = ROOT / "configs"


@pytest.fixture(scope="module")
def scan():
    """A small scan (4 pointings), in memory."""
    return ohd.run(CONFIGS / "wind_sunny.toml", samples=2000, seed=3, figures=False, progress=False)


@pytest.fixture(scope="module")
def plain():
    """A small run of the default experiment, in memory."""
    return ohd.run(samples=2000, seed=3, figures=False, progress=False)


def tree(d: Path):
    """Every entry below `d` with its kind and, for a regular file, its bytes (links not followed)."""
    out = {}
    for root, dirs, files in os.walk(d, followlinks=False):
        for name in dirs + files:
            p = Path(root) / name
            st = os.lstat(p)
            if stat.S_ISLNK(st.st_mode):
                out[str(p.relative_to(d))] = ("link", os.readlink(p))
            elif stat.S_ISREG(st.st_mode):
                out[str(p.relative_to(d))] = ("file", p.read_bytes())
            else:
                out[str(p.relative_to(d))] = ("dir" if stat.S_ISDIR(st.st_mode) else "other", None)
    return out


def names_written(result, scratch: Path):
    """The relative names a save of `result` creates (files and directories), from a scratch save."""
    result.save(scratch)
    return sorted(tree(scratch))


def expected_files(result):
    """{relative name: bytes} of what a save writes."""
    files = dict(result.files)
    for i, p in enumerate(result.pointings):
        files.update({f"pointing_{i:02}/{n}": b for n, b in p.files.items()})
    return files


class Outside:
    """A canary file, a directory elsewhere with a file in it, and a FIFO, beside the output
    directory; `unchanged()` says whether they are as they were."""

    def __init__(self, base: Path):
        self.canary = base / "canary"
        self.canary.write_bytes(b"keep me")
        self.elsewhere = base / "elsewhere"
        self.elsewhere.mkdir()
        (self.elsewhere / "theirs.npy").write_bytes(b"theirs")
        self.fifo = base / "fifo"
        os.mkfifo(self.fifo)
        self.before = tree(self.elsewhere)

    def targets(self):
        return {"canary": self.canary, "elsewhere": self.elsewhere, "fifo": self.fifo, "nothing": self.canary.parent / "none"}

    def unchanged(self):
        return (
            self.canary.read_bytes() == b"keep me"
            and tree(self.elsewhere) == self.before
            and stat.S_ISFIFO(os.lstat(self.fifo).st_mode)
        )


def plant(out: Path, names, target: Path):
    for n in names:
        p = out / n
        if p.parent != out and p.parent.is_symlink():
            continue  # inside a pointing directory planted as a link: that link is the case
        p.parent.mkdir(parents=True, exist_ok=True)
        if os.path.lexists(p):
            continue
        os.symlink(target, p)


def judge(result, out: Path, outside: Outside, planted):
    """Save `result` into `out` (with links `planted` there) and check the outcome."""
    before = tree(out)
    try:
        result.save(out)
    except OSError as e:
        assert outside.unchanged(), f"refused ({e}) but wrote outside"
        # The lock's name is ohd's: a link planted there may be replaced while the directory
        # is held, and the lock is removed when it is released.
        def kept(t):
            return {n: v for n, v in t.items() if Path(n).name != ".ohd-lock"}

        assert kept(tree(out)) == kept(before), f"refused ({e}) but changed the directory"
        assert str(out) in str(e) or any(n in str(e) for n in planted), f"the refusal names no path: {e}"
        return "refused"
    assert outside.unchanged(), "saved through a planted link"
    now = tree(out)
    for name, data in expected_files(result).items():
        assert now.get(name) == ("file", data), f"{name}: {now.get(name, ('missing', None))[0]} after the save"
    left = [n for n in now if Path(n).name.startswith(".")]
    assert not left, f"left behind: {left}"
    return "saved"


@pytest.mark.parametrize("which", ["scan", "plain"])
def test_links_planted_at_every_name_are_never_followed(which, scan, plain, tmp_path):
    result = scan if which == "scan" else plain
    names = names_written(result, tmp_path / "scratch")
    # The lock and the marker are written (and removed) by a save too.
    names += [".ohd-lock", "ohd_incomplete.txt"] + [f"pointing_{i:02}/.ohd-lock" for i in range(len(result.pointings))]
    outcomes = {"saved": 0, "refused": 0}
    k = 0
    for target_name in ["canary", "elsewhere", "fifo", "nothing"]:
        for group in [[n] for n in names] + [names]:
            k += 1
            base = tmp_path / f"case{k}"
            base.mkdir()
            outside = Outside(base)
            out = base / "out"
            out.mkdir()
            plant(out, group, outside.targets()[target_name])
            outcomes[judge(result, out, outside, group)] += 1
    # A link at a pointing's directory is refused; links at files are replaced.
    assert outcomes["saved"] > 0, outcomes
    if which == "scan":
        assert outcomes["refused"] > 0, outcomes
    print(which, len(names), "names:", outcomes)


def test_run_out_through_a_planted_pointing_link_is_refused(tmp_path):
    outside = Outside(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    os.symlink(outside.elsewhere, out / "pointing_00")
    with pytest.raises(OSError) as e:
        ohd.run(CONFIGS / "wind_sunny.toml", samples=2000, figures=False, progress=False, out=out)
    assert "pointing_00" in str(e.value)
    assert outside.unchanged()
