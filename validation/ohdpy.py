"""What the validation scripts share: the ohd binary they run and the virtual environment their
Python packages live in.

    import ohdpy                                   # validation/ on sys.path (see the scripts)
    ap = argparse.ArgumentParser(); ohdpy.add_binary_argument(ap); args = ap.parse_args()
    ohdpy.use_venv("numpy", "numba")               # re-runs the script inside validation/.venv
    binary = ohdpy.binary(args.binary)             # --binary, else cargo build --release

Packages go into `validation/.venv` (created on first use with `python3 -m venv`), never into the
interpreter that started the script: that may be a system Python or someone's project
environment. Standard library only, so that it runs before the venv exists.
"""
import json
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / "validation" / ".venv"
# Set in the re-executed process: a second re-exec would mean the venv's Python is not the venv's.
_REEXEC = "OHD_VALIDATION_VENV"


def add_binary_argument(ap, flag="--binary"):
    ap.add_argument(flag, metavar="PATH",
                    help="the ohd binary to run (default: build with cargo build --release and use "
                         "target/release/ohd, or $CARGO_TARGET_DIR/release/ohd)")


def target_dir():
    """Cargo's target directory for this workspace (CARGO_TARGET_DIR and .cargo/config respected)."""
    out = subprocess.run(["cargo", "metadata", "--format-version", "1", "--no-deps"], cwd=ROOT,
                         check=True, capture_output=True, text=True).stdout
    return Path(json.loads(out)["target_directory"])


def build(*extra):
    """`cargo build --release --bin ohd EXTRA…` in the repository; returns target/release."""
    subprocess.run(["cargo", "build", "--release", "--bin", "ohd", *extra], cwd=ROOT, check=True)
    return target_dir() / "release"


def binary(path=None, *build_extra):
    """The ohd binary to run: `path` (checked) if given, else a fresh release build's."""
    if path is None:
        return str(build(*build_extra) / "ohd")
    p = Path(path).expanduser().resolve()
    if not (p.is_file() and os.access(p, os.X_OK)):
        sys.exit(f"--binary {path}: not an executable file")
    return str(p)


def _name_and_version(requirement):
    m = re.fullmatch(r"\s*([A-Za-z0-9_.\-]+)\s*(?:==\s*([^\s]+))?\s*", requirement)
    if not m:
        raise ValueError(f"unsupported requirement {requirement!r}: use NAME or NAME==VERSION")
    return m.group(1), m.group(2)


def _missing(python, requirements):
    """The requirements not installed in `python`'s environment (NAME, or NAME==VERSION exactly)."""
    probe = ("import importlib.metadata as m, json, sys\n"
             "out = {}\n"
             "for n in json.loads(sys.argv[1]):\n"
             "    try: out[n] = m.version(n)\n"
             "    except m.PackageNotFoundError: out[n] = None\n"
             "print(json.dumps(out))\n")
    names = [_name_and_version(r)[0] for r in requirements]
    found = json.loads(subprocess.run([str(python), "-c", probe, json.dumps(names)], check=True,
                                      capture_output=True, text=True).stdout)
    missing = []
    for r in requirements:
        name, version = _name_and_version(r)
        have = found[name]
        if have is None or (version is not None and have != version):
            missing.append(r)
    return missing


def in_venv():
    return Path(sys.prefix).resolve() == VENV.resolve()


def use_venv(*requirements):
    """Make sure `requirements` (pip specifiers: NAME or NAME==VERSION) are installed in
    validation/.venv, then continue inside it: returns at once when this process already runs
    there, else re-executes the script with the venv's Python and the same arguments."""
    python = VENV / "bin" / "python"
    if not python.exists():
        print(f"ohdpy: creating {VENV} (python3 -m venv)", file=sys.stderr)
        if subprocess.run([sys.executable, "-m", "venv", str(VENV)]).returncode != 0:
            sys.exit("ohdpy: python3 -m venv failed; on Debian and Ubuntu install python3-venv")
    missing = _missing(python, requirements)
    if missing:
        print(f"ohdpy: installing {' '.join(missing)} into {VENV}", file=sys.stderr)
        subprocess.run([str(python), "-m", "pip", "install", "--quiet", "--disable-pip-version-check",
                        *missing], check=True)
    if in_venv():
        return
    if os.environ.get(_REEXEC):
        sys.exit(f"ohdpy: re-executed with {python} but still outside {VENV}")
    env = dict(os.environ, **{_REEXEC: "1"})
    script = os.path.abspath(sys.argv[0])
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(str(python), [str(python), script, *sys.argv[1:]], env)
