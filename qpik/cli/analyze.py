"""``qpik analyze``: what a frame's Jacobian says at a configuration (rank, redundancy,
singular values, manipulability, condition number, singularity)."""

from __future__ import annotations

import argparse

import numpy as np

from ..analysis import ROW_NAMES, analyze
from ._common import (
    OUTSIDE_LIMITS_NOTE,
    add_robot_arguments,
    configuration_from_args,
    warn_outside_limits,
)


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "analyze",
        help="analyse a frame's Jacobian: rank, redundancy, singularities",
        description="Kinematic analysis of a frame's world-aligned Jacobian [v; omega] at "
        "configuration q: rank, degree of redundancy (dim N(J)), singular values, "
        "manipulability sqrt(det J J^T), condition number, and the task directions lost "
        "at (or near) a singularity." + OUTSIDE_LIMITS_NOTE,
        epilog="examples: qpik analyze panda --q 0 0 0 -1.5 0 1.5 0.8; "
        "qpik analyze planar_4r --q 0.76 0.90 0.69 1.19 --position-only; "
        "qpik analyze planar_2r --q 0.785398 0.001 --rows vx vy",
    )
    add_robot_arguments(parser)
    rows = parser.add_mutually_exclusive_group()
    rows.add_argument(
        "--position-only",
        action="store_true",
        help="analyse the position rows vx vy vz only (default: all six rows)",
    )
    rows.add_argument(
        "--rows",
        nargs="+",
        choices=ROW_NAMES,
        metavar="ROW",
        help=f"analyse these rows only, from: {' '.join(ROW_NAMES)} "
        "(e.g. --rows vx vy for a planar arm)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    configuration = configuration_from_args(args)
    rows = args.rows or ("position" if args.position_only else "pose")
    report = analyze(configuration, args.frame, args.frame_type, rows)
    warn_outside_limits(configuration, "analyze")
    print(f"q = {np.array2string(configuration.q, precision=4)}")
    print(report)
    return 0
