"""A 7-DoF reach with priorities: strict levels against one weighted level.

The Panda's site ``ee`` goes to a pose (6 equations, 7 joints) while a posture task asks
for the home configuration. With the posture in level 1 (strict priority), the pose is
met exactly and the posture uses only the one-dimensional null space. With both in one
weighted level (mink's default), the posture pulls the end effector off its target: the
weighted solve trades pose error for posture.

The weighted pose error does not go to zero, and its iterations approach the trade-off
slowly (Gauss-Newton on a residual that stays: about 100 iterations to 0.117 m here), so the
stall rule, which watches the pose error alone (``stall_window``, 5 by default), is given
every iteration: with the default, the solve stops "stalled" after 5 at 0.150 m, 28 % short
of the trade-off.

Run: python examples/reach_7dof_priorities.py [--max-iters N]
"""

from __future__ import annotations

import argparse

import numpy as np

import qpik
from qpik.tasks import OrientationTask, PositionTask, PostureTask

TARGET = (np.array([0.45, 0.25, 0.40]), None)


def stacks(model, home):
    def tasks():
        position, orientation = PositionTask("ee"), OrientationTask("ee")
        posture = PostureTask(model, cost=0.3)
        posture.set_target(home)
        return position, orientation, posture

    p, o, posture = tasks()
    strict = [[p, o], [posture]]
    p, o, posture = tasks()
    weighted = [[p, o, posture]]
    return {"strict (2 levels)": strict, "weighted (1 level)": weighted}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-iters", type=int, default=100, help="iterations (default 100)")
    args = parser.parse_args(argv)

    model = qpik.load_robot("panda")
    home = model.key_qpos[0].copy()
    rotation = np.array([[np.cos(0.5), np.sin(0.5), 0], [np.sin(0.5), -np.cos(0.5), 0], [0, 0, -1]])
    target = (TARGET[0], rotation)
    print(f"target: position {TARGET[0]} m, ee pointing down, yaw 0.5 rad; start: home")
    for name, stack in stacks(model, home).items():
        result = qpik.solve(
            model,
            {"ee": target},
            q0=home,
            stack=stack,
            max_iters=args.max_iters,
            restarts=0,
            stall_window=args.max_iters,
        )
        print(
            f"{name:>20}: {result.reason:>9}, {result.iterations:3d} iterations, position error "
            f"{result.position_error:.2e} m, orientation error {result.orientation_error:.2e} "
            f"rad, |q - home| = {np.linalg.norm(result.q - home):.3f} rad"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
