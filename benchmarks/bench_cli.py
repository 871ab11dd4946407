"""The benchmarks' entry point (``bench_cli.run(main)`` under ``if __name__ == "__main__"``):
a bad argument (an unknown robot or frame, a robot file that does not load, a folder that
is not there) ends the run as the ``qpik`` command line does, with one line
``SCRIPT: error: ...`` and exit status 2, not a traceback."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

from qpik import QpikError


def run(main: Callable[[], object]) -> None:
    """Run ``main()`` and exit with its status where it returns an int; a
    :class:`qpik.QpikError` or an operating-system error exits with its message and
    status 2."""
    try:
        code = main()
    except (QpikError, OSError) as exc:
        message = " ".join(str(exc).split())
        print(f"{Path(sys.argv[0]).name}: error: {message}", file=sys.stderr)
        raise SystemExit(2) from None
    if isinstance(code, int) and not isinstance(code, bool):
        raise SystemExit(code)
