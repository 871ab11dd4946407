"""``qpik bench``: the IK success-rate benchmark, qpik against the pseudoinverse IGM, mink and
pink. Its harness and the adapters of the other libraries live in the repository's
``benchmarks/`` folder (``ik_bench.py``, ``ik_methods.py``), not in the installed package:
the command runs from a source checkout (``git clone``, then ``pip install -e .``), and
says so, exit status 2, where there is none.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import sys
from pathlib import Path
from types import ModuleType

from ._common import JSON_HELP, report_stream, write_json

#: The checkout's benchmarks folder (absent from an installed wheel).
BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


def harness() -> ModuleType:
    """The benchmark harness, ``benchmarks/ik_bench.py`` of the source checkout; raises
    :class:`FileNotFoundError` naming the folder when qpik is not run from one."""
    if not (BENCHMARKS / "ik_bench.py").is_file():
        raise FileNotFoundError(
            f"the benchmark harness is not installed with the package (no {BENCHMARKS}/"
            "ik_bench.py): run qpik bench from a source checkout of qpik "
            "(git clone, then pip install -e .)"
        )
    if str(BENCHMARKS) not in sys.path:
        sys.path.insert(0, str(BENCHMARKS))
    # by name: the harness is a file of the checkout, found through sys.path (no package)
    return importlib.import_module("ik_bench")


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "bench",
        help="IK success rate on reachable pose targets, qpik against baselines",
        description="Per robot, N reachable pose targets (FK of uniform random q within the "
        "limits, fixed seed) for its tool frame, each solved from mid-range by every method "
        "(qpik, the pseudoinverse IGM, damped least squares, mink, pink), "
        "interleaved. Protocol trac-ik (default): success = position <= 1e-5 m and "
        "rotation vector <= 1e-5 rad on each axis, joints within limits, within 5 ms, "
        "TRAC-IK's published figures beside; coarse: 1e-4 m and 1e-3 rad (norms) within "
        "50 ms. Prints a table; --json writes every number. Needs the editable install of "
        "a source checkout (pip install -e .: the harness is benchmarks/ik_bench.py).",
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
    parser.add_argument("--n", type=int, help="targets per robot (default: 1000)")
    parser.add_argument(
        "--methods",
        nargs="+",
        metavar="METHOD",
        help="from: qpik pinv dls mink pink (default: every available one)",
    )
    parser.add_argument(
        "--protocol",
        choices=["trac-ik", "coarse"],
        default="trac-ik",
        help="success criterion and budget (default: trac-ik)",
    )
    parser.add_argument(
        "--budget",
        type=float,
        default=None,
        help="time budget per solve [s] (default: the protocol's, 0.005 or 0.05)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the targets (0)")
    parser.add_argument("--json", metavar="OUT", help=JSON_HELP.format("results"))
    parser.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    try:
        bench = harness()
        protocol = {p.name: p for p in (bench.TRACIK, bench.COARSE)}[args.protocol]
        if args.budget is not None:
            protocol = dataclasses.replace(protocol, budget=args.budget)
        results = bench.run_ik_success(
            args.robots,
            n=bench.DEFAULT_N if args.n is None else args.n,
            methods=args.methods,
            seed=args.seed,
            protocol=protocol,
            progress=not args.quiet,
        )
    except (ValueError, FileNotFoundError) as exc:
        print(f"qpik bench: error: {exc}", file=sys.stderr)
        return 2
    with report_stream(args.json):
        bench.print_table(results)
    if args.json:
        write_json(args.json, json.dumps(results, indent=2))
    return 0
