"""``qpik bench``: the IK success-rate benchmark (:mod:`qpik.bench`)."""

from __future__ import annotations

import argparse
import json
import sys

from .. import bench


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "bench",
        help="IK success rate on reachable pose targets, qpik against baselines",
        description="Per robot, N reachable pose targets (FK of uniform random q within the "
        "limits, fixed seed) for its tool frame, each solved from mid-range by every method "
        "(qpik, the lecture's pseudoinverse IGM, damped least squares, mink), interleaved. "
        "Success = position error <= 1e-4 m, orientation error <= 1e-3 rad, joints within "
        "limits, within the time budget. Prints a table; --json writes every number.",
        epilog="example: qpik bench --robots ur5e panda --n 200 --json bench.json",
    )
    parser.add_argument(
        "--robots",
        nargs="+",
        metavar="ROBOT",
        help="robots (default: ur5e panda, plus erd:panda erd:ur5 erd:ur10 erd:xarm7 when "
        "example-robot-data is installed)",
    )
    parser.add_argument(
        "--n", type=int, default=bench.DEFAULT_N, help=f"targets per robot ({bench.DEFAULT_N})"
    )
    parser.add_argument(
        "--methods",
        nargs="+",
        choices=list(bench.METHODS),
        metavar="METHOD",
        help=f"from: {' '.join(bench.METHODS)} (default: every available one)",
    )
    parser.add_argument(
        "--budget",
        type=float,
        default=bench.DEFAULT_BUDGET,
        help=f"time budget per solve [s] ({bench.DEFAULT_BUDGET})",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the targets (0)")
    parser.add_argument("--json", metavar="OUT", help="write the results as JSON to OUT")
    parser.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    try:
        results = bench.run_ik_success(
            args.robots,
            n=args.n,
            methods=args.methods,
            seed=args.seed,
            budget=args.budget,
            progress=not args.quiet,
        )
    except ValueError as exc:
        print(f"qpik bench: error: {exc}", file=sys.stderr)
        return 2
    bench.print_table(results)
    if args.json:
        with open(args.json, "w") as stream:
            json.dump(results, stream, indent=2)
    return 0
