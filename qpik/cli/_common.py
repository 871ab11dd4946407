"""Arguments and formatting shared by the CLI commands."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np

from ..errors import InvalidInput, JointLimitViolation, UnknownFrame
from ..model.configuration import Configuration
from ..model.frames import resolve_frame
from ..model.robots import load_robot, tool_frame
from ..options import PRESETS


def add_robot_arguments(parser: argparse.ArgumentParser, *, frame: bool = True) -> None:
    """Add ``ROBOT``, ``--q`` and (optionally) ``--frame``/``--frame-type``."""
    parser.add_argument(
        "robot", metavar="ROBOT", help="bundled name (qpik robots), .xml/.urdf path or erd:NAME"
    )
    parser.add_argument(
        "--q",
        nargs="+",
        type=float,
        metavar="Q",
        help="joint configuration [rad or m], nq values (default: the model's qpos0)",
    )
    parser.add_argument(
        "--floating-base",
        action="store_true",
        help="add a free joint at the root (q starts with x y z qw qx qy qz)",
    )
    parser.add_argument(
        "--key",
        metavar="NAME",
        help="start from the model's keyframe NAME (an SRDF state such as half_sitting), or "
        "#K for its K-th keyframe (0 first: an unnamed one)",
    )
    if frame:
        parser.add_argument(
            "--frame",
            default=None,
            help="frame name (default: the robot's tool frame: site ee, else a known tool "
            "link, else the last link of the longest chain)",
        )
        parser.add_argument(
            "--frame-type",
            default=None,
            choices=["site", "body", "geom"],
            help="frame type (default: the type of the frame that has that name, site first)",
        )


def non_negative_int(text: str) -> int:
    """An argparse type: an integer >= 0 (seeds, counts); bad input is a usage error."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {value}")
    return value


def configuration_from_args(args: argparse.Namespace) -> Configuration:
    """Load ``args.robot`` and set ``args.q`` (or the keyframe ``args.key``); pick the
    frame (``args.frame``, ``args.frame_type``) when the command has one."""
    with c_warnings_as_lines(getattr(args, "command", None) or "qpik"):
        model = load_robot(args.robot, floating_base=getattr(args, "floating_base", False))
    q = args.q
    key = getattr(args, "key", None)
    if key is not None:
        kid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, key)
        if kid < 0 and key.startswith("#") and key[1:].isdigit() and int(key[1:]) < model.nkey:
            kid = int(key[1:])  # (by its index: an unnamed keyframe has no name to give)
        if kid < 0:
            keys = [model.key(k).name or f"#{k} (unnamed)" for k in range(model.nkey)]
            raise InvalidInput(f"--key {key!r}: keyframes are: {', '.join(keys) or '(none)'}")
        if q is not None:
            raise InvalidInput("give --q or --key, not both")
        q = model.key_qpos[kid]
    configuration = Configuration(model, q)
    if hasattr(args, "frame"):
        _pick_frame(args, model)
    return configuration


def _pick_frame(args: argparse.Namespace, model: mujoco.MjModel) -> None:
    """Fill ``args.frame``/``args.frame_type``: the tool frame when no frame is given
    (printed, with the rule that chose it); the type of the named frame otherwise."""
    if args.frame is None:
        tool = tool_frame(model)
        args.frame, chosen = tool.name, tool.frame_type
        if args.frame_type is not None and args.frame_type != chosen:
            raise InvalidInput(f"--frame-type {args.frame_type} needs --frame NAME")
        args.frame_type = chosen
        print(f"frame: {tool.frame_type} {tool.name!r} ({tool.reason}; --frame to choose)")
        return
    if args.frame_type is None:
        try:
            args.frame_type = resolve_frame(model, args.frame).type.value
        except UnknownFrame:
            args.frame_type = "site"  # the command's typed error then lists the sites


def format_matrix(matrix: np.ndarray, indent: str = "  ", digits: int = 4) -> str:
    """Rows of a matrix, aligned, one per line."""
    width = digits + 4
    return "\n".join(
        indent + " ".join(f"{x:{width}.{digits}f}" for x in np.atleast_1d(row))
        for row in np.atleast_2d(matrix)
    )


#: The solve options the batch commands take as flags (``--tol-position`` ...).
_SOLVE_FLAGS = ("tol_position", "tol_orientation", "max_iters", "restarts", "time_budget")


def add_solve_arguments(parser: argparse.ArgumentParser, per: str, iterations: bool = True) -> None:
    """``--preset`` and the solve options a batch command overrides (``per``: what one
    solve is, "target" or "pose"); defaults are :data:`qpik.PRESETS`'s."""
    parser.add_argument(
        "--preset",
        choices=list(PRESETS),
        help="named solve options (qpik.PRESETS; default: default)",
    )
    parser.add_argument("--tol-position", type=float, help="[m] (the preset's)")
    parser.add_argument("--tol-orientation", type=float, help="[rad] (the preset's)")
    if iterations:
        parser.add_argument("--max-iters", type=int, help="iterations per attempt")
    parser.add_argument("--restarts", type=int, help=f"random restarts per {per}")
    parser.add_argument("--time-budget", type=float, help=f"[s] per {per}")


def solve_options_from_args(args: argparse.Namespace) -> dict:
    """The keywords of the solves: ``options`` (the preset) and the flags given."""
    options: dict = {"options": args.preset}
    for name in _SOLVE_FLAGS:
        value = getattr(args, name, None)
        if value is not None:
            options[name] = value
    return options


#: Said in the description of the commands that take a configuration and answer outside
#: the limits too (statics, analyze).
OUTSIDE_LIMITS_NOTE = (
    " A q outside the joint limits is answered too, with a one-line warning on stderr "
    "(qpik.solve refuses such a start)."
)

#: The file name that means standard output (``--json -``).
STDOUT = "-"

JSON_HELP = "write the {} as JSON to OUT ('-': standard output, the report then on stderr)"


def write_json(path: str, text: str, option: str = "--json") -> None:
    """Write JSON ``text`` (and a newline) to ``path``, or to standard output when ``path``
    is ``-``; a file that cannot be written raises an ``OSError`` whose message names
    ``option`` and the path (the command's exit 2)."""
    if path == STDOUT:
        sys.stdout.write(text + "\n")
        sys.stdout.flush()
    else:
        try:
            Path(path).write_text(text + "\n")
        except OSError as exc:
            raise OSError(
                f"{option} {path!r}: cannot write the JSON: {exc.strerror or exc}"
            ) from exc


def check_writable(option: str, path: str) -> None:
    """:class:`qpik.InvalidInput` naming ``option`` when the file ``path`` cannot be
    written: a folder, in a folder that does not exist or that this user may not write
    in, or an existing file it may not write. Checked before a long computation (its
    result would be lost)."""
    folder = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path):
        problem = "is a folder, not a file"
    elif not os.path.isdir(folder):
        problem = f"its folder {folder!r} does not exist"
    elif not os.access(folder, os.W_OK | os.X_OK):
        problem = f"its folder {folder!r} is not writable"
    elif os.path.exists(path) and not os.access(path, os.W_OK):
        problem = "the file exists and is not writable"
    else:
        return
    raise InvalidInput(f"{option} {path!r}: cannot write there: {problem}")


@contextlib.contextmanager
def c_warnings_as_lines(command: str) -> Iterator[None]:
    """What C code (MuJoCo's compiler: ``WARNING: <mimic> on joint ... ignored``) writes
    to the process's stderr while the block runs, caught and printed after it as the
    command's one-line warnings, ``qpik COMMAND: warning: TEXT`` (blank lines dropped).
    Python's own writes to ``sys.stderr`` inside the block are caught too, and printed
    after it as they are where they are already the command's lines (``qpik ...``)."""
    sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:  # no stderr descriptor (pythonw): nothing to catch
        yield
        return
    with tempfile.TemporaryFile(mode="w+b") as caught:
        os.dup2(caught.fileno(), 2)
        try:
            yield
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            caught.seek(0)
            text = caught.read().decode(errors="replace")
    for line in text.splitlines():
        line = line.strip()
        if line.startswith("qpik "):  # a line of the command's own (a Python warning shown)
            print(line, file=sys.stderr)
        elif line:
            line = line.removeprefix("WARNING: ").removeprefix("Warning: ")
            print(f"qpik {command}: warning: {line}", file=sys.stderr)


@contextlib.contextmanager
def report_stream(json_path: str | None) -> Iterator[None]:
    """The human-readable report of a command goes to stdout, or to stderr while the JSON
    goes to stdout (``--json -``), so that stdout holds JSON only (``| jq``)."""
    if json_path == STDOUT:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    else:
        yield


def warn_outside_limits(configuration: Configuration, command: str) -> None:
    """One line on stderr when ``q`` is outside the joint limits (by more than 1e-6): the
    first joint outside and how many more. The command still answers (statics and the
    Jacobian are defined there); :func:`qpik.solve` refuses such a start instead."""
    try:
        configuration.check_limits()
    except JointLimitViolation as exc:
        q, tol = configuration.q, 1e-6
        outside = int(
            np.count_nonzero((q < configuration.lower - tol) | (q > configuration.upper + tol))
        )
        more = f" (and {outside - 1} more)" if outside > 1 else ""
        print(
            f"qpik {command}: warning: q is outside the joint limits: {exc}{more}; "
            "answering for it anyway",
            file=sys.stderr,
        )
