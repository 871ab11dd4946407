"""Drag the Panda's hand in the browser; the posture holds in the null space.

Level 0: the pose (position and orientation) of the site ``ee``; level 1: the ``home``
posture, which acts only in the null space of level 0 (one degree of redundancy: the
elbow swings while the hand stays). Joint position limits hold at every step.

The page (printed address; 127.0.0.1 only) shows a handle on the hand: drag it and the IK
re-solves from the current configuration, with each level's status, residual, damping
and active limits, and the solve time of the last drag. With ``--headless`` the hand's
target also moves by itself along a circle (as a drag would), and the example prints the
solve times behind those moves (goal: at most 2 ms per solve on this 7-DoF arm).

Run: ``python examples/viewer_panda.py [--headless] [--seconds N] [--port P]`` (needs
``pip install -e '.[viewer]'``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import qpik
from qpik.tasks import FrameTask, PostureTask


def make_viewer(port: int = 8080, host: str = "127.0.0.1"):
    """The viewer: the Panda at ``home``, the hand's pose in level 0, the posture in 1."""
    from qpik.viewer import Viewer

    model = qpik.load_robot("panda")
    home = model.key("home").qpos
    configuration = qpik.Configuration(model, home)
    hand = FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    hand.set_target_from_configuration(configuration)
    posture = PostureTask(model, cost=0.1)
    posture.set_target(home)
    return Viewer(model, levels=[[hand], [posture]], goals=["ee"], q0=home, host=host, port=port)


def circle(viewer, seconds: float, radius: float = 0.08, period: float = 2.0) -> list[float]:
    """Move the hand's target along a circle [m] (world y-z plane) for ``seconds``, about
    30 moves a second, as a drag would; returns the solve time [s] behind each move."""
    centre, rotation = viewer.frame_pose("ee")
    times = []
    start = time.monotonic()
    while (elapsed := time.monotonic() - start) < seconds:
        angle = 2 * np.pi * elapsed / period
        offset = radius * np.array([0.0, np.sin(angle), 1.0 - np.cos(angle)])
        times.append(viewer.set_target("ee", centre + offset, rotation).solve_time)
        time.sleep(1 / 30)
    return times


def main(argv: list[str] | None = None) -> int:
    """Command line; exit 0 (1 when a scripted move left the hand off its target)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--headless", action="store_true", help="move the target by itself")
    parser.add_argument("--seconds", type=float, help="serve N seconds (default: until Ctrl-C)")
    parser.add_argument("--port", type=int, default=8080, help="TCP port (0: any free one)")
    args = parser.parse_args(argv)
    viewer = make_viewer(args.port)
    print(f"viewer_panda: open {viewer.url} and drag the hand (posture: null space)")
    if not args.headless:
        viewer.serve(args.seconds)
        return 0
    try:
        times = circle(viewer, 2.0 if args.seconds is None else args.seconds)
        error = viewer.report.goal_errors["ee"] if viewer.report else (np.inf, np.inf)
    finally:
        viewer.close()
    print(
        f"  {len(times)} moves of the target: solve time median {1e3 * np.median(times):.2f} ms, "
        f"worst {1e3 * np.max(times):.2f} ms (goal <= 2 ms); last error "
        f"{1e3 * error[0]:.3f} mm, {np.degrees(error[1]):.3f} deg"
    )
    return 0 if error[0] <= 1e-3 else 1


if __name__ == "__main__":
    raise SystemExit(main())
