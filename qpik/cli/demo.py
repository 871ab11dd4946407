"""``qpik demo``: solve a reaching problem on a bundled arm and print the result."""

from __future__ import annotations

import argparse

import numpy as np

from ..igm.session import solve
from ..model.configuration import Configuration
from ..model.couplings import closed_chain_start
from ..model.robots import load_robot, tool_frame
from ..options import PRESETS
from ._common import c_warnings_as_lines, non_negative_int

#: The default preset's orientation tolerance per unit of position tolerance [rad/m].
_ORIENTATION_PER_METRE = PRESETS["default"].tol_orientation / PRESETS["default"].tol_position


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "demo",
        help="solve a reaching problem on a bundled arm and print the result",
        description="Solve inverse kinematics for the pose of the robot's tool frame "
        "(qpik.robots.tool_frame: the site `ee` on the bundled arms) reached by a random "
        "configuration (seeded), starting from mid-range, under joint limits.",
        epilog="example: qpik demo --robot panda --seed 3 --tol 1e-5",
    )
    parser.add_argument(
        "--robot",
        default="panda",
        help="a bundled robot, 'erd:NAME' or a path to an MJCF/URDF file (default: panda)",
    )
    parser.add_argument(
        "--seed", type=non_negative_int, default=0, help="seed of the target (default: 0)"
    )
    parser.add_argument(
        "--tol",
        type=float,
        default=PRESETS["default"].tol_position,
        help="position tolerance [m]; the orientation's scales with it as in qpik.PRESETS "
        f"(default: {PRESETS['default'].tol_position:g})",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    with c_warnings_as_lines("demo"):
        model = load_robot(args.robot)
    configuration = Configuration(model)
    goal_q = configuration.random_q(np.random.default_rng(args.seed))
    # a closed linkage's joints (connect or weld constraints, which random_q does not meet)
    # back at qpos0, where that meets them: a target the robot can take
    goal_q = closed_chain_start(model, goal_q, configuration.lower, configuration.upper)
    configuration.update(goal_q)
    tool = tool_frame(model)
    frame = (tool.name, tool.frame_type)
    position, rotation = configuration.frame_pose(*frame)
    print(f"robot {args.robot} ({model.nv} DoF): reach {tool.frame_type} {tool.name!r} to")
    print(f"  (the tool frame: {tool.reason})")
    print(f"  position [m] = {np.array2string(position, precision=4)}")
    print(f"  rotation = {np.array2string(rotation, precision=3).replace(chr(10), '')}")
    result = solve(
        model,
        {frame: (position, rotation)},
        seed=args.seed,
        tol_position=args.tol,
        tol_orientation=args.tol * _ORIENTATION_PER_METRE,
    )
    print(result)
    print(f"engine: {result.engine} (see qpik.solve)")
    return 0 if result.converged else 1
