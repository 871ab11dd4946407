"""``qpik robots``: the bundled models with their DoF and frames."""

from __future__ import annotations

import argparse

from ..configuration import FrameType, frame_names, joint_names
from ..robots import list_robots, load_robot, robot_path


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "robots",
        help="list the bundled robot models",
        description="List the bundled robot models with their DoF, joints and frames.",
        epilog="example: qpik robots",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    for name in list_robots():
        model = load_robot(name)
        print(f"{name}: {model.nv} DoF  ({robot_path(name).name})")
        print(f"  joints: {', '.join(joint_names(model))}")
        print(f"  sites:  {', '.join(frame_names(model, FrameType.SITE))}")
        bodies = [b for b in frame_names(model, FrameType.BODY) if b != "world"]
        print(f"  bodies: {', '.join(bodies)}")
    return 0
