"""``qpik view``: an interactive viewer in the browser (viser), or MuJoCo's own viewer."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from ..errors import InvalidInput

#: The default interface: this machine only (anyone who reaches the port moves the robot).
DEFAULT_HOST = "127.0.0.1"


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "view",
        help="interactive viewer in the browser: drag a goal frame, the IK re-solves",
        description="Serve an interactive 3-D view of a problem file (or a robot) in the "
        "browser (needs the viewer extra: pip install -e '.[viewer]'): the robot, a "
        "draggable handle on every goal frame with the IK re-solved live (strict levels, "
        "the problem's limits), a panel per level (status, residual, damping, active "
        "limits; red when the level cannot be met) and the solve time of each drag. The "
        "server listens on 127.0.0.1 unless --host says otherwise: whoever reaches the "
        "port can move the targets.",
        epilog="examples: qpik view tasks/panda_pose_reach.toml; "
        "qpik view panda --port 8081; "
        "qpik view tasks/talos_both_hands.toml --headless --seconds 2; "
        "qpik view tasks/panda_pose_reach.toml --mujoco (needs a display)",
    )
    parser.add_argument(
        "source",
        metavar="PROBLEM",
        help="problem file (.toml), or a robot: bundled name, .xml/.urdf path or erd:NAME",
    )
    parser.add_argument(
        "--host",
        default=DEFAULT_HOST,
        help="interface to listen on (default 127.0.0.1: this machine only; 0.0.0.0 "
        "exposes the viewer, and control of its targets, to the network)",
    )
    parser.add_argument(
        "--port", type=int, default=8080, help="TCP port (default 8080; 0: any free port)"
    )
    parser.add_argument(
        "--seconds",
        type=float,
        metavar="N",
        help="serve for N seconds, then exit (default: until Ctrl-C)",
    )
    parser.add_argument(
        "--headless",
        action="store_true",
        help="do not open a browser tab (for scripts and tests; pair with --seconds)",
    )
    parser.add_argument("--collision", action="store_true", help="draw the collision geoms too")
    parser.add_argument(
        "--floating-base",
        action="store_true",
        help="for a robot (not a problem file): add a free joint at the root",
    )
    parser.add_argument(
        "--mujoco",
        action="store_true",
        help="MuJoCo's own viewer (mujoco.viewer.launch_passive) instead of the browser; "
        "needs a display; shows the problem solved toward each goal in turn",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.seconds is not None and not args.seconds >= 0:
        raise InvalidInput(f"--seconds must be >= 0, got {args.seconds}")
    if not 0 <= args.port <= 65535:
        raise InvalidInput(f"--port must be in [0, 65535], got {args.port}")
    source = _source(args)
    if args.mujoco:
        return _run_mujoco(source, args.seconds)
    from ..viewer import Viewer

    start = time.perf_counter()
    viewer = Viewer(source, host=args.host, port=args.port, collision=args.collision)
    report = viewer.report
    print(f"qpik view: serving {viewer.url} (ready in {time.perf_counter() - start:.2f} s)")
    if report is not None:
        print(
            f"  goal frames: {', '.join(viewer.goals)}; start solve "
            f"{'converged' if report.converged else 'not converged'} in {report.steps} steps"
        )
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(
            f"  listening on {args.host}: anyone who reaches port {viewer.port} can move "
            "the targets",
            file=sys.stderr,
        )
    if not args.headless:
        viewer.open_browser()
    print("  " + ("Ctrl-C to stop" if args.seconds is None else f"for {args.seconds:g} s"))
    sys.stdout.flush()
    viewer.serve(args.seconds)
    if viewer.drag_times:
        times = sorted(viewer.drag_times)
        print(
            f"qpik view: {len(times)} drag solves, median "
            f"{1000 * times[len(times) // 2]:.2f} ms, worst {1000 * times[-1]:.2f} ms"
        )
    return 0


def _source(args: argparse.Namespace):
    """The problem (a .toml file) or the robot model to show."""
    from ..model.robots import load_robot
    from ..problem import load_problem

    if Path(args.source).suffix == ".toml":
        if args.floating_base:
            raise InvalidInput("--floating-base is for a robot; a problem file says floating_base")
        return load_problem(args.source)
    return load_robot(args.source, floating_base=args.floating_base)


def has_display() -> bool:
    """Whether a window can be opened (an X11 or Wayland display, or macOS / Windows)."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _run_mujoco(source, seconds: float | None) -> int:
    """MuJoCo's passive viewer: the start configuration, then the IK solved toward each
    goal of the problem in turn (one step per frame), until the window closes or
    ``seconds`` pass."""
    if not has_display():
        raise InvalidInput(
            "--mujoco needs a display (DISPLAY or WAYLAND_DISPLAY is not set); use the "
            "browser viewer (qpik view without --mujoco), which needs none"
        )
    import importlib

    from ..model.configuration import Configuration
    from ..problem import Problem
    from ..viewer.app import default_stack, live_of_problem
    from ..viewer.live import LiveSolve

    if isinstance(source, Problem):
        live = live_of_problem(source, None, None, None, 1)
        goals = [[(f.frame, f.target) for f in goal.frames] for goal in source.goals]
    else:
        configuration = Configuration(source, source.key_qpos[0] if source.nkey else None)
        live = LiveSolve(source, default_stack(configuration), q0=configuration.q, max_iterations=1)
        goals = []
    data = live.configuration.data
    deadline = None if seconds is None else time.monotonic() + seconds
    mujoco_viewer = importlib.import_module("mujoco.viewer")
    with mujoco_viewer.launch_passive(live.model, data) as handle:
        index, steps = 0, 0
        while handle.is_running() and (deadline is None or time.monotonic() < deadline):
            if goals and steps == 0:
                for frame, target in goals[index % len(goals)]:
                    live.set_target(frame, target.position, target.rotation)
            live.solve(max_iterations=1)
            steps = (steps + 1) % 300
            if steps == 0:
                index += 1
            handle.sync()
            time.sleep(1 / 60)
    return 0
