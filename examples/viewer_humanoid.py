"""Drag Talos's left hand in the browser while its feet and centre of mass hold.

Floating Talos (example-robot-data, 38 dofs), from ``half_sitting``. Priorities (level 0
first), under the joint position limits and the support-polygon limit (the CoM's ground
projection 2 cm inside the feet's convex hull), which hold at every level:

* level 0: both feet where they start (6-D pose of the sole links);
* level 1: the centre of mass over its start (horizontal position only);
* level 2: the left hand to its target (position), the one frame with a handle;
* level 3: torso upright and the ``half_sitting`` posture.

The page (printed address; 127.0.0.1 only) draws the robot from its meshes, the support
polygon (blue) and the CoM's ground projection (red). Drag the hand: the arm and the
trunk follow as far as the feet and the CoM allow; a target out of reach turns level 2
red in the panel. With ``--headless`` the target moves by itself (forward, then far out
of reach) and the example prints what each level did.

Run: ``python examples/viewer_humanoid.py [--headless] [--seconds N] [--port P]`` (needs
``pip install -e '.[viewer,robots]'``).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import qpik
from qpik.limits import ConfigurationLimit, SupportPolygonLimit
from qpik.tasks import ComTask, FrameTask, OrientationTask, PositionTask, PostureTask

FEET = ("left_sole_link", "right_sole_link")
HAND = "gripper_left_base_link"
#: Talos's sole: 0.20 m x 0.10 m, centred on the sole link (x forward).
SOLE = [[0.1, 0.05], [0.1, -0.05], [-0.1, 0.05], [-0.1, -0.05]]


def make_viewer(port: int = 8080, host: str = "127.0.0.1"):
    """The viewer of the stack in the module docstring."""
    from qpik.viewer import Viewer

    with warnings.catch_warnings():  # the URDF's .dae meshes are dropped, with a warning
        warnings.simplefilter("ignore")
        model = qpik.load_robot("erd:talos", floating_base=True)
    start = model.key("half_sitting").qpos
    configuration = qpik.Configuration(model, start)
    feet = [FrameTask(name, "body", position_cost=1.0, orientation_cost=1.0) for name in FEET]
    for task in feet:
        task.set_target_from_configuration(configuration)
    com = ComTask(cost=[1.0, 1.0, 0.0])  # x-y only: the height is free
    com.set_target_from_configuration(configuration)
    hand = PositionTask(HAND, "body")
    hand.set_target_from_configuration(configuration)
    torso = OrientationTask("torso_2_link", "body", gain=0.5)
    torso.set_target(np.eye(3))
    posture = PostureTask(model, cost=1e-2)
    posture.set_target(start)
    limits = [ConfigurationLimit(model), SupportPolygonLimit(model, FEET, 0.02, SOLE)]
    return Viewer(
        model,
        levels=[feet, [com], [hand], [torso, posture]],
        limits=limits,
        goals=[(HAND, "body")],
        q0=start,
        host=host,
        port=port,
        max_iterations=30,
    )


def main(argv: list[str] | None = None) -> int:
    """Command line; exit 0 (1 when the feet moved or a reachable target was missed)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--headless", action="store_true", help="move the target by itself")
    parser.add_argument("--seconds", type=float, help="serve N seconds (default: until Ctrl-C)")
    parser.add_argument("--port", type=int, default=8080, help="TCP port (0: any free one)")
    args = parser.parse_args(argv)
    viewer = make_viewer(args.port)
    print(f"viewer_humanoid: open {viewer.url} and drag the left hand (feet and CoM hold)")
    if not args.headless:
        viewer.serve(args.seconds)
        return 0
    seconds = 2.0 if args.seconds is None else args.seconds
    try:
        hand, _ = viewer.frame_pose(HAND)
        feet = [viewer.live.configuration.frame_pose(f, "body")[0] for f in FEET]
        reach = viewer.set_target(HAND, hand + [0.15, 0.05, 0.10], max_iterations=100)
        far = viewer.set_target(HAND, hand + [0.0, 1.5, 0.0], max_iterations=100)
        time.sleep(max(0.0, seconds - 0.5))
        moved = max(
            float(np.linalg.norm(viewer.live.configuration.frame_pose(f, "body")[0] - p))
            for f, p in zip(FEET, feet)
        )
    finally:
        viewer.close()
    for what, report in (("reachable", reach), ("out of reach", far)):
        states = ", ".join(f"{lv.index}: {lv.state} ({lv.status})" for lv in report.levels)
        error = report.goal_errors[HAND][0]
        print(
            f"  target {what}: hand error {1e3 * error:.2f} mm after {report.steps} steps "
            f"({1e3 * report.solve_time:.1f} ms); levels {states}"
        )
    print(f"  feet moved at most {moved:.2e} m")
    ok = reach.goal_errors[HAND][0] <= 1e-3 and moved <= 1e-4 and not far.levels[2].ok
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
