"""``qpik bench``: the IK success-rate benchmark (:mod:`qpik.bench`)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys

from .. import bench


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "bench",
        help="IK success rate on reachable pose targets, qpik against baselines",
        description="Per robot, N reachable pose targets (FK of uniform random q within the "
        "limits, fixed seed) for its tool frame, each solved from mid-range by every method "
        "(qpik, the lecture's pseudoinverse IGM, damped least squares, mink, pink), "
        "interleaved. Protocol trac-ik (default): success = position <= 1e-5 m and "
        "rotation vector <= 1e-5 rad on each axis, joints within limits, within 5 ms, "
        "TRAC-IK's published figures beside; coarse: 1e-4 m and 1e-3 rad (norms) within "
        "50 ms. Prints a table; --json writes every number.",
        epilog="example: qpik bench --robots ur5e panda --n 200 --methods qpik dls "
        "--json bench.json",
    )
    parser.add_argument(
        "--robots",
        nargs="+",
        metavar="ROBOT",
        help="robots (default: ur5e panda, plus every 6- and 7-DoF arm of example-robot-data "
        "when it is installed)",
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
        "--protocol",
        choices=[bench.TRACIK.name, bench.COARSE.name],
        default=bench.TRACIK.name,
        help="success criterion and budget (default: trac-ik)",
    )
    parser.add_argument(
        "--budget",
        type=float,
        default=None,
        help="time budget per solve [s] (default: the protocol's, 0.005 or 0.05)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the targets (0)")
    parser.add_argument("--json", metavar="OUT", help="write the results as JSON to OUT")
    parser.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    try:
        protocol = bench.TRACIK if args.protocol == bench.TRACIK.name else bench.COARSE
        if args.budget is not None:
            protocol = dataclasses.replace(protocol, budget=args.budget)
        results = bench.run_ik_success(
            args.robots,
            n=args.n,
            methods=args.methods,
            seed=args.seed,
            protocol=protocol,
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
