"""The ``qpik`` command line. One module per command; each exposes ``register(subparsers)``.

Add a command by writing ``qpik/cli/<name>.py`` with a ``register`` function and listing
it in ``COMMANDS``.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import TextIO

from .. import __version__
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


_VERBOSE_HELP = "show warnings in full, with the source line that raised them"


def build_parser(commands: Sequence[str] = COMMANDS) -> argparse.ArgumentParser:
    """The argument parser with ``commands`` registered (default: every command; :func:`main`
    registers only the one its arguments name, so that ``qpik reach`` imports no other
    command's modules)."""
    parser = argparse.ArgumentParser(
        prog="qpik",
        description="Inverse kinematics as prioritized QPs on MuJoCo models, each level solved "
        "exactly by qpik's compiled active-set solver (the default; OSQP and the qpsolvers "
        "backends on request).",
    )
    parser.add_argument("--version", action="version", version=f"qpik {__version__}")
    parser.add_argument("--verbose", "-v", action="store_true", help=_VERBOSE_HELP)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in commands:
        importlib.import_module(f"{__name__}.{name}").register(sub)
    for command in sub.choices.values():
        # also after the command (qpik reach FILE --verbose); SUPPRESS keeps the top-level
        # value when the command's own flag is not given
        command.add_argument(
            "--verbose", "-v", action="store_true", default=argparse.SUPPRESS, help=_VERBOSE_HELP
        )
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
    environment variable ``QPIK_DEBUG=1`` to see the traceback). Python warnings print one
    line each, ``qpik COMMAND: warning: ...`` (``--verbose``: Python's own format).
    """
    words = list(sys.argv[1:] if argv is None else argv)
    # The command is the first word that is not an option (the top level's options take no
    # value); any other first word (a typo, none, --help) gets every command, for the usage.
    named = next((word for word in words if not word.startswith("-")), None)
    parser = build_parser([named] if named in COMMANDS else COMMANDS)
    args = parser.parse_args(words)
    with _warnings_shown(args.command, verbose=args.verbose):
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    """Run the command; errors become a message and an exit code (see :func:`main`)."""
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
    except Exception as exc:  # the last resort of a command line
        if os.environ.get("QPIK_DEBUG"):
            raise
        print(
            f"qpik {args.command}: internal error: {type(exc).__name__}: {_one_line(exc)} "
            "(a bug in qpik: please report it; QPIK_DEBUG=1 shows the traceback)",
            file=sys.stderr,
        )
        return EXIT_INTERNAL_ERROR


@contextmanager
def _warnings_shown(command: str, verbose: bool) -> Iterator[None]:
    """Python warnings raised while a command runs, each printed on one line of stderr as
    ``qpik COMMAND: warning: MESSAGE (Category)``, without the source line Python adds
    (``verbose``: Python's own format, file, line and source included). The previous
    ``warnings.showwarning`` is restored afterwards."""
    with warnings.catch_warnings():
        if not verbose:

            def show(message, category, filename, lineno, file=None, line=None) -> None:
                stream: TextIO | None = file if file is not None else sys.stderr
                if stream is None:  # no stderr (pythonw): nowhere to say it
                    return
                text = _one_line(message) if str(message).strip() else category.__name__
                try:
                    stream.write(f"qpik {command}: warning: {text} ({category.__name__})\n")
                except OSError:  # a closed stream: the warning is lost, not the command
                    pass

            warnings.showwarning = show
        yield


def _one_line(exc: BaseException | str, limit: int = 2000) -> str:
    """The message of an exception (or a warning) on one line, at most ``limit`` characters."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
