"""IK success rate on reachable pose targets: qpik, the lecture's pseudoinverse IGM, damped
least squares, mink and pink, side by side (protocol of issue 6; the logic is
:mod:`qpik.bench`).

Per robot, N reachable targets (FK of uniform random q within the limits, fixed seed) for
the robot's tool frame; every solve starts at mid-range. Success = position error <= 1e-4 m,
orientation error <= 1e-3 rad, all joints within limits, within the 50 ms budget per solve
(wall time). Every method restarts from random configurations within the budget, so the
comparison isolates the step rule.

Tool frames (qpik.bench.ROBOT_FRAMES): bundled ur5e and panda: site ``ee``; erd:panda: body
``panda_hand_tcp`` (9 DoF: its 2 finger joints do not move the frame, so every least-norm
step leaves them where they start); erd:ur3/ur5/ur10: ``tool0``; erd:xarm7: ``link_eef``;
erd:kinova: ``j2s6s200_end_effector``; erd:z1: ``gripperStator``.

pink (``pip install 'qpik[compare]'``: pin-pink and pin) runs where installed, on the same
robot files loaded by pinocchio, joints mapped by name; a robot pinocchio cannot load (or
whose frame it places differently) is skipped for pink, with the reason under the table.

Defaults: N = 1000; robots ur5e, panda, and erd:panda, erd:ur5, erd:ur10, erd:xarm7 when
example-robot-data is installed; every available method. About 95 s on a 2-core
machine (the baselines' failures each burn the full 50 ms; they are rare with restarts).

    python benchmarks/ik_success.py [--robots ur5e erd:ur5] [--n 1000]
        [--methods qpik pinv dls mink pink] [--budget 0.05] [--json OUT]
"""

from __future__ import annotations

import argparse
import json

from qpik import bench


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--robots",
        nargs="+",
        help="robots (default: ur5e panda, plus erd:panda erd:ur5 erd:ur10 erd:xarm7 when "
        "example-robot-data is installed)",
    )
    parser.add_argument("--n", type=int, default=bench.DEFAULT_N, help="targets per robot")
    parser.add_argument(
        "--methods",
        nargs="+",
        choices=list(bench.METHODS),
        help="methods (default: every available one)",
    )
    parser.add_argument(
        "--budget", type=float, default=bench.DEFAULT_BUDGET, help="time per solve [s]"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the targets")
    parser.add_argument("--json", metavar="OUT", help="write the results as JSON to OUT")
    args = parser.parse_args(argv)
    results = bench.run_ik_success(
        args.robots, n=args.n, methods=args.methods, seed=args.seed, budget=args.budget
    )
    bench.print_table(results)
    if args.json:
        with open(args.json, "w") as stream:
            json.dump(results, stream, indent=2)
    return results


if __name__ == "__main__":
    main()
