"""The 4R self-motion: the tip holds still while the joints move in the null space.

A textbook self-motion: from q1 = (0.76, 0.90, 0.69, 1.19) the tip of the 4-link planar arm
is at p_e = (-1, 2) (to 2 decimals; the problem's target is where q1 puts it exactly). Level
0 holds it there (v_e = 0); level 1 lowers the joint-limit distance w(q) (0 with every joint
at mid-range, 1/8 at the limits: :func:`qpik.analysis.joint_limit_distance`), so that ``qdot
= J^+ xi + N(q) zeta`` lowers w without moving the tip (w, not each joint: q2 and q3 move
away from 0, their mid-range, on the way to w's least value where the tip is held,
0.0086 from 0.0104). The problem
is tasks/planar_4r_self_motion.toml, run here with a chosen number of steps; ``--plot``
saves the figure of the run.

Run: python examples/self_motion_4r.py [--steps N] [--plot OUT.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import qpik
from qpik.analysis import joint_limit_distance

TASK = Path(__file__).resolve().parent.parent / "tasks" / "planar_4r_self_motion.toml"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200, help="steps of 10 ms (default 200)")
    parser.add_argument("--plot", metavar="OUT.png", help="save a figure of the run")
    args = parser.parse_args(argv)

    problem = qpik.load_problem(TASK)
    problem.steps = args.steps
    result = problem.solve()
    trace = result.trace
    configuration = problem.start_configuration()
    lower, upper = configuration.lower, configuration.upper
    print(f"{'t [s]':>6} {'q':>34} {'tip error [m]':>14} {'w(q)':>15}")
    for i in range(0, len(trace.q), max(1, len(trace.q) // 8)):
        q = trace.q[i]
        print(
            f"{i * trace.dt:6.2f} {str(q.round(3)):>34} {trace.position_error[i]:14.2e} "
            f"{joint_limit_distance(q, lower, upper):15.5f}"
        )
    print(result.summary())
    if args.plot:
        from qpik.plots import plot_result

        plot_result(result, args.plot)
        print(f"figure: {args.plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
