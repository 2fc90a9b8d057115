"""``tiltsim`` as a command of the Python package: the same command line as the Rust
executable (``tiltsim run``, ``sweep``, ``compare``, ...). Participant processes of an IPC run
are served by this same command."""

from __future__ import annotations

import os
import sys


def main() -> None:
    from . import _tiltsim

    exe = os.path.abspath(sys.argv[0]) if sys.argv and sys.argv[0] else ""
    if exe and os.path.basename(exe) == "tiltsim" and os.access(exe, os.X_OK):
        os.environ.setdefault("TILTSIM_PARTICIPANT_EXE", exe)
    sys.exit(_tiltsim.cli(["tiltsim", *sys.argv[1:]]))


if __name__ == "__main__":
    main()
