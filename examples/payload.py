"""The payload a pose can hold: statics at solved poses of the Panda.

For poses with the end effector pointing down at a growing horizontal reach, qpik.solve
finds the configuration, then the static relation tau = J^T f (virtual work) gives the
joint torques a downward force produces; :func:`qpik.statics.max_payload` finds the largest
force the motors (87 / 12 N m) can hold on top of gravity, and which joint limits it.
The further out, the longer the lever arms and the smaller the payload.

Run: python examples/payload.py [--n N]
"""

from __future__ import annotations

import argparse

import numpy as np

import qpik
from qpik.statics import holding_torques, max_payload

DOWN = np.diag([1.0, -1.0, -1.0])  # ee z axis pointing down


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=6, help="number of reaches (default 6)")
    args = parser.parse_args(argv)

    model = qpik.load_robot("panda")
    home = model.key_qpos[0].copy()
    print(
        f"{'reach x [m]':>11} {'IK':>10} {'max payload':>16} {'limited by':>10} "
        f"{'|holding| max':>14}"
    )
    for x in np.linspace(0.3, 0.75, args.n):
        result = qpik.solve(model, {"ee": ([x, 0.0, 0.3], DOWN)}, q0=home, seed=0, restarts=10)
        configuration = qpik.Configuration(model, result.q)
        payload = max_payload(configuration, "ee", [0.0, 0.0, -1.0])
        holding = holding_torques(configuration)
        load = (
            f"{payload.force:6.1f} N {payload.force / 9.81:5.2f} kg"
            if payload.feasible
            else "cannot hold"
        )
        print(
            f"{x:11.3f} {result.reason:>10} {load:>16} {str(payload.limiting_joint):>10} "
            f"{np.abs(holding).max():11.2f} Nm"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
