"""``qpik robots``: the bundled models with their DoF and frames, and example-robot-data's."""

from __future__ import annotations

import argparse
import warnings

from ..errors import InvalidOption
from ..model.configuration import FrameType, frame_names, joint_names
from ..model.robots import (
    erd_robots,
    erd_robots_folder,
    list_robots,
    load_robot,
    robot_path,
    tool_frame,
)
from ._common import c_warnings_as_lines


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "robots",
        help="list the bundled robot models (--erd: example-robot-data's)",
        description="List the bundled robot models with their DoF, joints, frames and tool "
        "frame; with --erd, every robot of example-robot-data (the robots extra: "
        "pip install -e '.[robots]') "
        "as the erd:NAME that loads it.",
        epilog="examples: qpik robots; qpik robots --erd; qpik robots --erd --details",
    )
    parser.add_argument(
        "--erd", action="store_true", help="list example-robot-data's robots (erd:NAME)"
    )
    parser.add_argument(
        "--details",
        action="store_true",
        help="with --erd: load each robot and print its DoF, tool frame and named poses "
        "(slower: about 0.2 s per robot)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.erd:
        return _run_erd(args.details)
    if args.details:
        raise InvalidOption(
            "--details",
            True,
            "used with --erd",
            "--details applies with --erd only (the bundled robots are always listed in full)",
        )
    for name in list_robots():
        model = load_robot(name)
        print(f"{name}: {model.nv} DoF  ({robot_path(name).name})")
        print(f"  joints: {', '.join(joint_names(model))}")
        print(f"  sites:  {', '.join(frame_names(model, FrameType.SITE))}")
        bodies = [b for b in frame_names(model, FrameType.BODY) if b != "world"]
        print(f"  bodies: {', '.join(bodies)}")
        print(f"  tool frame: {tool_frame(model).frame_type} {tool_frame(model).name}")
    print("example-robot-data's robots: qpik robots --erd (erd:NAME, e.g. erd:talos)")
    return 0


def _run_erd(details: bool) -> int:
    robots = erd_robots()  # MissingExtra names the extra when the package is missing
    base = erd_robots_folder()
    width = max(len(name) for name in robots) + 4
    print(f"{len(robots)} robots of example-robot-data ({base}):")
    for name, path in robots.items():
        line = f"  erd:{name:<{width}} {path.relative_to(base)}"
        if details:
            with warnings.catch_warnings(), c_warnings_as_lines("robots"):
                warnings.simplefilter("ignore")
                model = load_robot(f"erd:{name}")
            tool = tool_frame(model)
            keys = [model.key(k).name for k in range(model.nkey)]
            line += f"  {model.nv} DoF, tool {tool.frame_type} {tool.name}"
            if keys:
                line += f", poses: {', '.join(keys)}"
        print(line)
    print("load one with qpik.load_robot('erd:NAME', floating_base=True) for a free base")
    return 0
