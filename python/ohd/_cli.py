"""The `ohd` console script: the command line of the `ohd` binary, run from the package's own
extension (one build gives both; `pip install ./python` puts `ohd` on PATH)."""
import signal
import sys

from . import _ohd


def main() -> None:
    # Ctrl-C is the command's (a first one keeps the run's work, a second stops at once), not
    # Python's: the command sets its own handler over the default one.
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    sys.exit(_ohd.cli(["ohd", *sys.argv[1:]]))


if __name__ == "__main__":
    main()
