"""``qpik statics``: joint torques of a wrench at a frame, gravity and holding torques."""

from __future__ import annotations

import argparse

import numpy as np

from ..errors import InvalidInput
from ..model.configuration import joint_names
from ..statics import gravity_torques, holding_torques, joint_torque_limits, joint_torques
from ._common import (
    OUTSIDE_LIMITS_NOTE,
    add_robot_arguments,
    configuration_from_args,
    warn_outside_limits,
)


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "statics",
        help="print the joint torques a force/torque at a frame produces, and holding torques",
        description="Statics at rest: tau = J^T [f; t] for a wrench at the frame origin (the "
        "torque it produces at the joints), the torque gravity produces, and the motor "
        "torques that hold the robot still against both (-(gravity + tau); a model's joint "
        "springs at rest are cancelled too, and printed)." + OUTSIDE_LIMITS_NOTE,
        epilog="example: qpik statics ur5e --q 0 -1.57 1.57 0 0 0 --force 0 0 -20",
    )
    add_robot_arguments(parser)
    parser.add_argument(
        "--force",
        nargs=3,
        type=float,
        required=True,
        metavar=("FX", "FY", "FZ"),
        help="force on the robot at the frame origin [N]",
    )
    parser.add_argument(
        "--torque",
        nargs=3,
        type=float,
        default=None,
        metavar=("TX", "TY", "TZ"),
        help="torque on the robot at the frame origin [N m] (default: zero)",
    )
    parser.add_argument(
        "--local",
        action="store_true",
        help="force and torque are in the frame's axes (default: world axes)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    configuration = configuration_from_args(args)
    expressed_in = "local" if args.local else "world"
    tau = joint_torques(
        configuration, args.frame, args.force, args.torque, args.frame_type, expressed_in
    )
    gravity = gravity_torques(configuration)
    holding = holding_torques(configuration) - tau  # -(gravity + springs + tau)
    passive = -(holding + gravity + tau)  # the model's passive forces at rest (springs, gravcomp)
    try:
        limits = joint_torque_limits(configuration)
    except InvalidInput:
        limits = None
    tau, gravity, holding = (np.where(np.abs(x) < 5e-9, 0.0, x) for x in (tau, gravity, holding))
    warn_outside_limits(configuration, "statics")
    print(f"q = {np.array2string(configuration.q, precision=4)}")
    print(
        f"wrench at {args.frame_type} {args.frame!r} ({expressed_in} axes): "
        f"force [N] = {_fmt(args.force)}, torque [N m] = {_fmt(args.torque or [0, 0, 0])}"
    )
    print("joint torques [N m]: tau = J^T [f; t] (produced by the wrench), gravity (produced")
    print("by gravity), holding = -(gravity + tau) (what the motors apply to stay still)")
    dofs = [joint_names(configuration.model)[j] for j in configuration.model.dof_jntid]
    acting = [(dof, value) for dof, value in zip(dofs, passive.tolist()) if abs(value) > 5e-9]
    if acting:  # (holding cancels them too)
        listed = ", ".join(f"{dof} {value:.4f}" for dof, value in acting)
        print(
            "  passive: the model's passive forces at rest (joint springs, gravity "
            f"compensation), which holding cancels too: {listed}"
        )
    _print_table(dofs, tau, gravity, holding, limits)
    return 0


def _print_table(dofs, tau, gravity, holding, limits) -> None:
    """One row per dof: tau, gravity and holding torques [N m], and the actuator limits
    (marked where the holding torque exceeds them) when the model has them."""
    width = max(len(n) for n in dofs + ["joint"])
    header = f"  {'joint':<{width}} {'tau':>10} {'gravity':>10} {'holding':>10}"
    print(header + ("     limits" if limits is not None else ""))
    for i, name in enumerate(dofs):
        row = f"  {name:<{width}} {tau[i]:10.4f} {gravity[i]:10.4f} {holding[i]:10.4f}"
        if limits is not None:
            lo, hi = limits[i]
            mark = "" if lo <= holding[i] <= hi else "  EXCEEDED"
            row += f"  [{lo:g}, {hi:g}]{mark}"
        print(row)
    if limits is not None:
        inside = bool(np.all((limits[:, 0] <= holding) & (holding <= limits[:, 1])))
        print(f"holding torques within the actuator limits: {'yes' if inside else 'no'}")


def _fmt(values) -> str:
    return np.array2string(np.asarray(values, dtype=float), precision=4)
