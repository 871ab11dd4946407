"""``qpik reach``: solve a problem file (tasks/*.toml), print, save JSON and a figure."""

from __future__ import annotations

import argparse
import sys

from ..model.configuration import FrameType
from ..model.robots import tool_frame
from ..problem import load_problem
from ._common import (
    JSON_HELP,
    c_warnings_as_lines,
    check_writable,
    report_stream,
    write_json,
)


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "reach",
        help="solve an IK problem file (TOML) and report, optionally as JSON and a figure",
        description="Load an IK problem file (schema: tasks/README.md), solve it (qpik.solve "
        "per target or waypoint, or differential tracking with mode = 'track'), and print "
        "the outcome. Exit status: 0 converged, 1 not converged (with the reason), 2 "
        "invalid input (the file, the field and what was expected).",
        epilog="examples: qpik reach tasks/panda_pose_reach.toml; "
        "qpik reach tasks/planar_4r_self_motion.toml --plot self_motion.png; "
        "qpik reach tasks/ur5e_velocity_limits.toml --json out.json --quiet; "
        "qpik reach tasks/panda_pose_reach.toml --json - | jq .converged",
    )
    parser.add_argument("file", metavar="FILE", help="problem file (.toml)")
    parser.add_argument("--json", metavar="OUT", help=JSON_HELP.format("result"))
    parser.add_argument(
        "--plot", metavar="OUT.png", help="save a figure (needs the plots extra: matplotlib)"
    )
    parser.add_argument(
        "--quiet", action="store_true", help="print nothing on success (errors still go to stderr)"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    with c_warnings_as_lines("reach"):
        problem = load_problem(args.file)
    if args.plot is not None:
        from ..plots import check_figure_path

        # fail before solving: the extra named if matplotlib is missing, the extension, a
        # program the format needs, a folder that cannot be written
        check_figure_path("--plot", args.plot)
        check_writable("--plot", args.plot)
    if args.json is not None and args.json != "-":  # (as --plot: before the solve)
        check_writable("--json", args.json)
    result = problem.solve()
    with report_stream(args.json):
        _report(args, problem, result)
    if args.json is not None:
        write_json(args.json, result.to_json())
    if args.plot is not None:
        from ..plots import plot_result

        plot_result(result, args.plot)
    if not result.converged:
        print(f"qpik reach: not converged: {result.reason}", file=sys.stderr)
        return 1
    return 0


def _report(args: argparse.Namespace, problem, result) -> None:
    """The goal frames and the result's summary (nothing with ``--quiet``)."""
    if not args.quiet:
        tool = tool_frame(problem.model)
        frames = [f for goal in problem.goals[:1] for f in goal.frames]
        names = []
        for frame in frames:
            note = f" (the robot's tool frame: {tool.reason})" if frame.frame == tool.name else ""
            names.append(f"{FrameType(frame.frame_type).value} {frame.frame!r}{note}")
        print(f"goal frame{'s' if len(names) > 1 else ''}: {', '.join(names)}")
        print(result.summary())
