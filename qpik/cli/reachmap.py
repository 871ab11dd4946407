"""``qpik reachmap``: a reachability map of a frame over a box (:mod:`qpik.reachability`)."""

from __future__ import annotations

import argparse
import math

import numpy as np

from ..batch.reachability_map import map_path, reachability
from ..errors import InvalidInput
from ..limits import ConfigurationLimit, model_collision_limit
from ..model.configuration import resolve_robot
from ._common import (
    add_solve_arguments,
    c_warnings_as_lines,
    check_writable,
    solve_options_from_args,
)


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "reachmap",
        help="reachability map: per voxel of a box, the fraction of K orientations IK reaches",
        description="Grid the box REGION (world frame) into voxels of RESOLUTION metres and, "
        "for each voxel centre and each of K orientations spread evenly over SO(3), solve IK "
        "for FRAME (qpik.solve, seeded per pose) on every core or on Ray. Voxels farther "
        "than the chain's reach bound are skipped without IK. Saves the map (npz: centers "
        "(V, 3), fraction (V,), reached (V, K), skipped, orientations (K, 3, 3), meta) and "
        "optionally a figure (slices and a 3D scatter; needs matplotlib).",
        epilog="example: qpik reachmap ur5e --frame ee --region -1 -1 -0.2 1 1 1.2 "
        "--resolution 0.1 --orientations 16 --out ur5e_map.npz --plot ur5e_map.png",
    )
    parser.add_argument(
        "robot", metavar="ROBOT", help="bundled name (qpik robots), .xml/.urdf path or erd:NAME"
    )
    parser.add_argument("--frame", required=True, help="frame name (site, body or geom)")
    parser.add_argument(
        "--region",
        nargs=6,
        type=float,
        required=True,
        metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"),
        help="opposite corners of the box [m], world frame",
    )
    parser.add_argument("--resolution", type=float, required=True, help="voxel edge [m]")
    parser.add_argument(
        "--orientations",
        type=int,
        default=16,
        metavar="K",
        help="orientations per voxel, spread over SO(3) (16); 0: positions only",
    )
    parser.add_argument(
        "--out",
        required=True,
        metavar="MAP.npz",
        help="where to save the map (.npz appended when missing, as numpy does)",
    )
    parser.add_argument("--plot", metavar="MAP.png", help="save a figure (needs matplotlib)")
    parser.add_argument("--workers", type=int, metavar="N", help="processes (every core)")
    parser.add_argument(
        "--ray",
        metavar="ADDRESS",
        help="run on Ray: 'auto', 'ray://HOST:PORT' (Ray Client: pip install "
        "'ray[client]'), 'HOST:PORT' or 'local', as qpik batch --ray (the cluster extra: "
        "pip install -e '.[cluster]')",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the IK restarts (0)")
    add_solve_arguments(parser, "pose", iterations=False)
    parser.add_argument(
        "--collision",
        choices=("scene", "self", "all"),
        help="exclude poses reached only in collision: the robot's collision geoms against "
        "the world's (scene), against each other (self) or both (all); pairs from the "
        "model's own geometry (qpik.limits.model_collision_limit). Default: not checked",
    )
    parser.add_argument(
        "--min-distance",
        type=non_negative_distance,
        metavar="M",
        help=f"with --collision (an error without it): the distance [m] every pair keeps, "
        f">= 0 ({DEFAULT_MIN_DISTANCE:g})",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    parser.set_defaults(func=run)


#: ``--min-distance``'s default [m].
DEFAULT_MIN_DISTANCE = 0.005


def non_negative_distance(text: str) -> float:
    """An argparse type: a finite distance [m] >= 0 (a negative minimum distance would let
    the robot's geoms penetrate by that much and still count as clear)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a distance [m] >= 0, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0.0):
        raise argparse.ArgumentTypeError(f"expected a finite distance [m] >= 0, got {text}")
    return value


def run(args: argparse.Namespace) -> int:
    # Fail before solving: the map's file (saved as numpy does: .npz appended), the figure's
    # (the extra named if matplotlib is missing, the extension, a program it needs), each
    # folder writable; an option that would be ignored.
    out = map_path(args.out)
    check_writable("--out", out)
    if args.plot is not None:
        from ..plots import check_figure_path

        check_figure_path("--plot", args.plot)
        check_writable("--plot", args.plot)
    if args.min_distance is not None and args.collision is None:
        raise InvalidInput(
            "--min-distance is the distance the collision pairs keep: it needs --collision "
            "(scene, self or all)"
        )
    options = solve_options_from_args(args)
    if args.collision is not None:
        with c_warnings_as_lines("reachmap"):
            model, _q0 = resolve_robot(args.robot)
        distance = DEFAULT_MIN_DISTANCE if args.min_distance is None else args.min_distance
        collision = model_collision_limit(
            model,
            scene=args.collision in ("scene", "all"),
            self_collision=args.collision in ("self", "all"),
            minimum_distance_from_collisions=distance,
            collision_detection_distance=distance + 0.05,
        )
        options["limits"] = [ConfigurationLimit(model), collision]
    rmap = reachability(
        args.robot,
        args.frame,
        region=np.array(args.region).reshape(2, 3),
        resolution=args.resolution,
        orientations=args.orientations,
        workers=args.workers,
        backend="ray" if args.ray else "process",
        address=None if args.ray in (None, "local") else args.ray,
        seed=args.seed,
        progress=not args.quiet,
        **options,
    )
    written = rmap.save(out)
    if args.plot is not None:
        rmap.plot(args.plot)
    if not args.quiet:
        print(rmap.summary())
        print(f"saved {written}" + (f" and {args.plot}" if args.plot else ""))
    return 0
