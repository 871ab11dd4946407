"""The ``qpik`` command line. One module per command; each exposes ``register(subparsers)``.

Add a command by writing ``qpik/cli/<name>.py`` with a ``register`` function and listing
it in ``COMMANDS``.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from ..errors import QpikError

#: Command modules, in the order ``qpik --help`` lists them.
COMMANDS = ["robots", "fk", "demo", "analyze", "statics", "bench", "reach"]


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


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``qpik`` console script. Returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except BrokenPipeError:  # output piped into `head` and the like: stop quietly
        sys.stderr.close()
        return 0
    except QpikError as exc:
        print(f"qpik {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
