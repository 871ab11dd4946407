"""``qpik fk``: forward kinematics of a frame, its pose and Jacobian."""

from __future__ import annotations

import argparse

import numpy as np

from ._common import add_robot_arguments, configuration_from_args, format_matrix


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "fk",
        help="print a frame's pose and Jacobian at a configuration",
        description="Forward kinematics: the world pose of a frame and its world-aligned "
        "Jacobian [v; omega] at configuration q.",
        epilog="example: qpik fk planar_2r --q 0.785398 0.001",
    )
    add_robot_arguments(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    configuration = configuration_from_args(args)
    position, rotation = configuration.frame_pose(args.frame, args.frame_type)
    jacobian = configuration.frame_jacobian(args.frame, args.frame_type)
    np.set_printoptions(precision=4, suppress=True)
    print(f"q = {np.array2string(configuration.q, precision=4)}")
    print(f"{args.frame_type} {args.frame!r} in the world frame:")
    print(f"  position [m] = {np.array2string(position, precision=6)}")
    print("  rotation =")
    print(format_matrix(rotation, indent="    "))
    print("  Jacobian [v; omega] (world-aligned, rows vx vy vz wx wy wz):")
    print(format_matrix(jacobian, indent="    "))
    return 0
