"""The 2R arm near its singularity: pseudoinverse step norms against qpik's.

The textbook planar 2R example: l1 = l2 = 1, q1 = pi/4, and q2 shrinking toward 0, where
det J = l1 l2 sin q2 vanishes. Asked for the same small tip velocity xi (1 cm/s along the
lost direction) the inverse ``J^-1 xi`` grows like 1 / sin q2 (|J^-1 xi| / |xi| is
sqrt(5) / (2 sin(q2 / 2)), 2236 at q2 = 0.001), while qpik's step (a PositionTask solved by
IKSolver, with its adaptive damping) stays bounded: asked only along the lost direction,
the tip then nearly stops (about 1e-6 m/s of the 1e-2 m/s asked at q2 = 0.001) instead of
the joints spinning.

Run: python examples/singularity_2r.py [--steps N]
"""

from __future__ import annotations

import argparse

import numpy as np

import qpik
from qpik.analysis import pseudoinverse


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=8, help="number of q2 values (default 8)")
    args = parser.parse_args(argv)

    configuration = qpik.Configuration(qpik.load_robot("planar_2r"))
    task = qpik.tasks.PositionTask("ee", gain=1.0)
    solver = qpik.IKSolver(
        configuration.model, [task], [qpik.limits.ConfigurationLimit(configuration.model)]
    )
    dt = 0.01
    print(f"{'q2 [rad]':>10} {'sin q2':>10} {'|J^-1 xi| [rad/s]':>18} {'|qpik v| [rad/s]':>17}")
    for q2 in np.geomspace(0.5, 1e-3, args.steps):
        configuration.update([np.pi / 4, q2])
        J = configuration.frame_jacobian("ee")[:2]
        position = configuration.frame_pose("ee")[0]
        # the direction lost at q2 = 0: along the arm (radial), 1 cm/s
        radial = position[:2] / np.linalg.norm(position[:2])
        xi = 0.01 * radial
        pinv_velocity = pseudoinverse(J) @ xi
        task.set_target(position + np.append(xi, 0.0) * dt)
        step = solver.step(configuration, dt)
        print(
            f"{q2:10.4g} {np.sin(q2):10.4g} {np.linalg.norm(pinv_velocity):18.4g} "
            f"{np.linalg.norm(step.velocity):17.4g}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
