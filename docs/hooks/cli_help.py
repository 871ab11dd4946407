"""Write docs/cli-help/*.txt: what ``qpik --help`` and each ``qpik COMMAND --help`` print
(80 columns), included in docs/guides/cli.md. Run it after changing the command line:

    python docs/hooks/cli_help.py

tests/package/test_docs.py checks that the files match the command line."""

from __future__ import annotations

import contextlib
import io
import os
import sys
from pathlib import Path

FOLDER = Path(__file__).resolve().parent.parent / "cli-help"
COMMANDS = [
    "robots",
    "fk",
    "demo",
    "analyze",
    "statics",
    "reach",
    "batch",
    "reachmap",
    "view",
    "bench",
]


def help_text(command: str | None) -> str:
    """What ``qpik [COMMAND] --help`` prints, 80 columns wide."""
    from qpik.cli import main

    os.environ["COLUMNS"] = "80"
    argv = ([command] if command else []) + ["--help"]
    out, saved = io.StringIO(), sys.argv
    sys.argv = ["qpik", *argv]
    try:
        with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
            main(argv)
    finally:
        sys.argv = saved
    return out.getvalue()


def main() -> None:
    FOLDER.mkdir(exist_ok=True)
    for command in [None, *COMMANDS]:
        (FOLDER / f"{command or 'qpik'}.txt").write_text(help_text(command))


if __name__ == "__main__":
    main()
