"""The viewer's two times: start to first drawn frame, and the solve behind a drag.

1. **Start to first drawn frame** [s]: from ``Viewer(...)`` (the problem loaded, the
   start solved, the server up) until a headless Chromium, already running and pointed at
   the page, shows the robot (a screenshot with the scene drawn), on the Panda problem
   ``tasks/panda_pose_reach.toml``. Parts: viewer ready, page text (panels) shown, first
   frame with the robot. SwiftShader renders in software: a real GPU draws faster.
2. **Solve behind a drag** [ms], 7-DoF Panda: the handle's target moved in steps of
   about 5 mm along a circle of 8 cm (what a drag at 30 updates a second sends), each
   move re-solved to tolerance (1e-4 m, 1e-3 rad) from the current configuration. Two
   stacks: the viewer's default (``mink``-style frame task, posture in the null space) and
   the problem file's (position + orientation tasks, posture). Goal: median <= 2 ms.

Run: ``python benchmarks/viewer.py [--moves N] [--no-browser]`` (needs the viewer extra
and, for 1., ``chromium`` on the PATH).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from bench_cli import at_least  # benchmarks/bench_cli.py (this folder is on sys.path)

import qpik
from qpik.problem import load_problem
from qpik.viewer import LiveSolve, default_stack
from qpik.viewer.app import live_of_problem

ROOT = Path(__file__).resolve().parent.parent


def drag_times(live: LiveSolve, frame: str, moves: int = 400) -> np.ndarray:
    """Solve time [s] of each of ``moves`` target moves (5 mm apart, on a circle)."""
    centre, rotation = live.configuration.frame_pose(frame)
    live.solve(max_iterations=200)
    times = []
    for i in range(moves):
        angle = 2 * np.pi * i / 100  # 100 moves a turn: 5 mm apart on an 8 cm circle
        offset = 0.08 * np.array([0.0, np.sin(angle), 1.0 - np.cos(angle)])
        live.set_target(frame, centre + offset, rotation)
        report = live.solve()
        if not report.converged:
            raise RuntimeError(f"move {i}: not converged ({report.goal_errors})")
        times.append(report.solve_time)
    return np.array(times)


def first_frame() -> dict[str, float]:
    """Seconds from ``Viewer(...)`` to: ready, panels shown, first frame with the robot."""
    from qpik.viewer import Viewer
    from qpik.viewer.browser import Browser

    with Browser() as browser:
        start = time.perf_counter()
        viewer = Viewer(ROOT / "tasks" / "panda_pose_reach.toml", port=0)
        try:
            ready = time.perf_counter() - start
            browser.open(viewer.url)
            browser.wait_for_text("Level 0", "solve time:")
            panels = time.perf_counter() - start
            drawn = _wait_for_robot(browser) - start
        finally:
            viewer.close()
    return {"ready": ready, "panels": panels, "first_frame": drawn}


def _wait_for_robot(browser, timeout: float = 120.0) -> float:
    """The time at which a screenshot first shows the robot drawn (dark-enough pixels in
    the 3-D view beside the grid)."""
    import io

    from PIL import Image

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        image = np.asarray(Image.open(io.BytesIO(browser.screenshot())).convert("L"), float)
        h, w = image.shape
        scene = image[int(0.22 * h) : int(0.95 * h), int(0.05 * w) : int(0.70 * w)]
        # the robot's shaded surfaces: mid greys, rarer than the grid's thin lines
        if np.mean((scene > 120) & (scene < 235)) > 0.01:
            return time.perf_counter()
        time.sleep(0.05)
    raise RuntimeError("the robot was never drawn")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--moves", type=at_least(1), default=400, help="target moves per stack")
    parser.add_argument("--no-browser", action="store_true", help="skip the first-frame time")
    args = parser.parse_args(argv)

    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key("home").qpos)
    stacks = {
        "viewer default (frame task; posture)": LiveSolve(
            model, default_stack(configuration), q0=configuration.q
        ),
        "tasks/panda_pose_reach.toml (position + orientation; posture)": live_of_problem(
            load_problem(ROOT / "tasks" / "panda_pose_reach.toml"), None, None, None, 20
        ),
    }
    print(f"solve behind a drag, 7-DoF Panda, {args.moves} moves of ~5 mm (goal: <= 2 ms)")
    for name, live in stacks.items():
        times = drag_times(live, "ee", args.moves) * 1e3
        print(
            f"  {name:62s} median {np.median(times):.3f} ms  p95 "
            f"{np.percentile(times, 95):.3f} ms  max {times.max():.3f} ms"
        )
    if not args.no_browser:
        figures = first_frame()
        print("start to first drawn frame (Panda problem, headless Chromium, SwiftShader)")
        for key, what in (
            ("ready", "viewer ready (problem loaded, start solved, server up)"),
            ("panels", "page panels shown"),
            ("first_frame", "first frame with the robot drawn"),
        ):
            print(f"  {what:56s} {figures[key]:.2f} s")
    return 0


if __name__ == "__main__":
    import bench_cli  # benchmarks/bench_cli.py (this folder is on sys.path)

    bench_cli.run(main)
