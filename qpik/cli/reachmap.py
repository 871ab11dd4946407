"""``qpik reachmap``: a reachability map of a frame over a box (:mod:`qpik.reachability`)."""

from __future__ import annotations

import argparse
import math

import numpy as np

from ..batch.reachability_map import reachability
from ..limits import ConfigurationLimit, model_collision_limit
from ..model.configuration import resolve_robot
from ._common import add_solve_arguments, c_warnings_as_lines, solve_options_from_args


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
    parser.add_argument("--out", required=True, metavar="MAP.npz", help="where to save the map")
    parser.add_argument("--plot", metavar="MAP.png", help="save a figure (needs matplotlib)")
    parser.add_argument("--workers", type=int, metavar="N", help="processes (every core)")
    parser.add_argument(
        "--ray",
        metavar="ADDRESS",
        help="run on Ray: 'auto', 'ray://HOST:PORT' or 'local' (the cluster extra: "
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
        default=0.005,
        metavar="M",
        help="with --collision: the distance [m] every pair keeps, >= 0 (0.005)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    parser.set_defaults(func=run)


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
    if args.plot is not None:
        from ..plots import check_figure_path

        # fail before solving: the extra named if matplotlib is missing, or the extension
        check_figure_path("--plot", args.plot)
    options = solve_options_from_args(args)
    if args.collision is not None:
        with c_warnings_as_lines("reachmap"):
            model, _q0 = resolve_robot(args.robot)
        collision = model_collision_limit(
            model,
            scene=args.collision in ("scene", "all"),
            self_collision=args.collision in ("self", "all"),
            minimum_distance_from_collisions=args.min_distance,
            collision_detection_distance=args.min_distance + 0.05,
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
    rmap.save(args.out)
    if args.plot is not None:
        rmap.plot(args.plot)
    if not args.quiet:
        print(rmap.summary())
        print(f"saved {args.out}" + (f" and {args.plot}" if args.plot else ""))
    return 0
