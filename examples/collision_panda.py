"""The Panda reaches around a sphere placed on its straight path (collision avoidance).

The site ``ee`` goes from the home pose to a goal 0.45 m to the side; a sphere of radius
6 cm sits on the middle of the straight segment. Level 0: the ee position; level 1: the
home posture; limits: the joints' position and velocity limits and a collision-avoidance
limit between the forearm, wrist and hand geoms and the sphere (``d_min`` = 10 mm).

It runs the same reach with qpik's :class:`qpik.limits.CollisionAvoidanceLimit` (rows in
displacement units) and with mink's (a velocity bound applied to the displacement) and
prints, for each, the closest distance over the run and the final goal error.

Run: ``python examples/collision_panda.py [--steps N]``.
"""

from __future__ import annotations

import argparse

import mink
import numpy as np

import qpik
from qpik.limits import CollisionAvoidanceLimit, geom_distance, joint_limits
from qpik.scene import add_obstacle
from qpik.tasks import PositionTask, PostureTask

ARM = ["link4", "link5", "link6", "link7", "hand"]
D_MIN = 0.01  # [m]


def reach(which: str, steps: int = 400, dt: float = 0.01) -> tuple[float, float]:
    """Closest arm-sphere distance [m] over the run and final goal error [m]."""
    base = qpik.load_robot("panda")
    start = qpik.Configuration(base, base.key_qpos[0]).frame_pose("ee")[0]
    goal = start + np.array([0.0, 0.45, 0.0])
    model = add_obstacle(base, "sphere", 0.06, 0.5 * (start + goal), name="ball")
    if which == "qpik":
        avoid = CollisionAvoidanceLimit(  # the Panda's collision capsules and the ball
            model,
            [(ARM, ["ball"])],
            minimum_distance_from_collisions=D_MIN,
            collision_detection_distance=0.1,
        )
    else:
        model.geom_contype[:] = model.geom_conaffinity[:] = 1
        avoid = mink.CollisionAvoidanceLimit(
            model,
            [(ARM, ["ball"])],
            minimum_distance_from_collisions=D_MIN,
            collision_detection_distance=0.1,
        )
    configuration = qpik.Configuration(model, model.key_qpos[0])
    tip = PositionTask("ee", gain=0.1)
    tip.set_target(goal)
    posture = PostureTask(model, cost=0.05)
    posture.set_target(model.key_qpos[0])
    solver = qpik.IKSolver(model, [[tip], [posture]], [avoid, *joint_limits(model)])
    closest = np.inf
    for _ in range(steps):
        configuration.integrate_inplace(solver.step(configuration, dt).velocity, dt)
        closest = min(closest, *(geom_distance(configuration, g, "ball") for g in ARM))
    error = float(np.linalg.norm(configuration.frame_pose("ee")[0] - goal))
    return float(closest), error


def main(argv: list[str] | None = None) -> int:
    """Command line: ``--steps N`` (default 400). Exit 0 when qpik's limit kept the arm
    at least 9 mm away and reached the goal within 2 cm."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=400, help="steps of 10 ms (default 400)")
    steps = parser.parse_args(argv).steps
    print(
        f"Panda around a sphere on its straight path, d_min = {D_MIN * 1e3:.0f} mm, {steps} steps"
    )
    results = {}
    for which in ("qpik", "mink"):
        closest, error = reach(which, steps)
        results[which] = (closest, error)
        print(
            f"  {which + ' rows:':<11} closest distance {closest * 1e3:+6.1f} mm, "
            f"goal error {error * 1e3:6.2f} mm"
        )
    closest, error = results["qpik"]
    return 0 if closest >= 0.009 and (steps < 300 or error <= 0.02) else 1


if __name__ == "__main__":
    raise SystemExit(main())
