"""The benchmarks' entry point (``bench_cli.run(main)`` under ``if __name__ == "__main__"``):
a bad argument (an unknown robot or frame, a robot file that does not load, a folder that
is not there) ends the run as the ``qpik`` command line does, with one line
``SCRIPT: error: ...`` and exit status 2, not a traceback."""

from __future__ import annotations

import argparse
import math
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


def at_least(minimum: int) -> Callable[[str], int]:
    """An argparse ``type`` for a count: an integer of at least ``minimum``, so that
    ``--n 0`` is refused as a bad argument (status 2) instead of failing later."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {value}")
        return value

    parse.__name__ = f"integer >= {minimum}"
    return parse


def positive_float(text: str) -> float:
    """An argparse ``type`` for a duration or a length: a finite number above 0."""
    return _finite(text, strict=True)


def nonnegative_float(text: str) -> float:
    """An argparse ``type`` for a limit where 0 means none: a finite number, 0 or above."""
    return _finite(text, strict=False)


def _finite(text: str, strict: bool) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value) or value < 0 or (strict and value == 0):
        sign = "above 0" if strict else "0 or above"
        raise argparse.ArgumentTypeError(f"must be a finite number {sign}, got {text}")
    return value
