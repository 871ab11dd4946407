"""Arguments and formatting shared by the CLI commands."""

from __future__ import annotations

import argparse

import numpy as np

from ..configuration import Configuration
from ..robots import load_robot


def add_robot_arguments(parser: argparse.ArgumentParser, *, frame: bool = True) -> None:
    """Add ``ROBOT``, ``--q`` and (optionally) ``--frame``/``--frame-type``."""
    parser.add_argument(
        "robot", metavar="ROBOT", help="bundled name (qpik robots), .xml/.urdf path or erd:NAME"
    )
    parser.add_argument(
        "--q",
        nargs="+",
        type=float,
        metavar="Q",
        help="joint configuration [rad or m], nq values (default: the model's qpos0)",
    )
    if frame:
        parser.add_argument("--frame", default="ee", help="frame name (default: ee)")
        parser.add_argument(
            "--frame-type",
            default="site",
            choices=["site", "body", "geom"],
            help="frame type (default: site)",
        )


def configuration_from_args(args: argparse.Namespace) -> Configuration:
    """Load ``args.robot`` and set ``args.q``."""
    return Configuration(load_robot(args.robot), args.q)


def format_matrix(matrix: np.ndarray, indent: str = "  ", digits: int = 4) -> str:
    """Rows of a matrix, aligned, one per line."""
    width = digits + 4
    return "\n".join(
        indent + " ".join(f"{x:{width}.{digits}f}" for x in np.atleast_1d(row))
        for row in np.atleast_2d(matrix)
    )
