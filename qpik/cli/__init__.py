"""The ``qpik`` command line. One module per command; each exposes ``register(subparsers)``.

Add a command by writing ``qpik/cli/<name>.py`` with a ``register`` function and listing
it in ``COMMANDS``.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from ..errors import QpikError

#: Command modules, in the order ``qpik --help`` lists them.
COMMANDS = [
    "robots",
    "fk",
    "demo",
    "analyze",
    "statics",
    "bench",
    "reach",
    "batch",
    "reachmap",
    "view",
]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every command registered."""
    parser = argparse.ArgumentParser(
        prog="qpik",
        description="Inverse kinematics as prioritized QPs (MuJoCo models, OSQP solver).",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        importlib.import_module(f"{__name__}.{name}").register(sub)
    return parser


#: Exit codes: 0 success, 1 a command's negative answer (e.g. ``reach``: not converged),
#: 2 invalid input (argparse's usage errors too), 70 an internal error (``EX_SOFTWARE``: a
#: bug; please report it; ``QPIK_DEBUG=1`` prints its traceback). Commands may add their
#: own (``batch``: 3 stopped early).
EXIT_INVALID_INPUT = 2
EXIT_INTERNAL_ERROR = 70


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``qpik`` console script. Returns the exit code.

    Errors never print a traceback: a :class:`qpik.QpikError` or an operating-system
    error (a file that cannot be read or written) prints ``qpik COMMAND: error: ...`` and
    returns 2; anything else is a bug, reported in one line with exit code 70 (set the
    environment variable ``QPIK_DEBUG=1`` to see the traceback).
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except BrokenPipeError:  # output piped into `head` and the like: stop quietly
        sys.stderr.close()
        return 0
    except (QpikError, OSError) as exc:
        print(f"qpik {args.command}: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_INVALID_INPUT
    except KeyboardInterrupt:
        print(f"qpik {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - the last resort of a command line
        if os.environ.get("QPIK_DEBUG"):
            raise
        print(
            f"qpik {args.command}: internal error: {type(exc).__name__}: {_one_line(exc)} "
            "(a bug in qpik: please report it; QPIK_DEBUG=1 shows the traceback)",
            file=sys.stderr,
        )
        return EXIT_INTERNAL_ERROR


def _one_line(exc: BaseException, limit: int = 2000) -> str:
    """The message of an exception on one line, at most ``limit`` characters."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
