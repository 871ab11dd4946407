"""Issue 22: steps stay where the linearisation holds on models without velocity limits
(the trust region of :attr:`qpik.StepOptions.max_joint_speed`), in the general path and
the one-call step alike."""

from __future__ import annotations

import pathlib

import mink
import mujoco
import numpy as np
import pytest
from conftest import BALL

import qpik
from qpik.limits import CollisionAvoidanceLimit, geom_distance, joint_limits
from qpik.scene import add_obstacle
from qpik.tasks import ComTask, FrameTask, PositionTask, PostureTask

DATA = pathlib.Path(__file__).parents[1] / "data" / "menagerie"
DT = 0.01
BOUND = qpik.options.DEFAULT_MAX_JOINT_SPEED * DT  # [rad or m per step]


def test_collision_example_without_velocity_limits_keeps_its_clearance():
    """The README collision example (examples/collision_panda.py) with position limits
    only, as on Menagerie's panda.xml: the arm stays at least d_min - 1 mm from the ball
    and no step exceeds the trust region."""
    arm, d_min = ["link4", "link5", "link6", "link7", "hand"], 0.01
    base = qpik.load_robot("panda")
    start = qpik.Configuration(base, base.key_qpos[0]).frame_pose("ee")[0]
    goal = start + np.array([0.0, 0.45, 0.0])
    model = add_obstacle(base, "sphere", 0.06, 0.5 * (start + goal), name="ball")
    avoid = CollisionAvoidanceLimit(
        model, [(arm, ["ball"])], minimum_distance_from_collisions=d_min,
        collision_detection_distance=0.1,
    )  # fmt: skip
    configuration = qpik.Configuration(model, model.key_qpos[0])
    tip = PositionTask("ee", gain=0.1)
    tip.set_target(goal)
    posture = PostureTask(model, cost=0.05)
    posture.set_target(model.key_qpos[0])
    limits = [avoid, *joint_limits(model, velocity_scale=None)]
    assert not any(isinstance(limit, mink.VelocityLimit) for limit in limits)
    solver = qpik.IKSolver(model, [[tip], [posture]], limits)
    closest, largest = np.inf, 0.0
    for _ in range(300):
        result = solver.step(configuration, DT)
        largest = max(largest, float(np.abs(result.displacement).max()))
        configuration.integrate_inplace(result.velocity, DT)
        closest = min(closest, *(geom_distance(configuration, g, "ball") for g in arm))
    assert closest >= d_min - 1e-3
    assert largest <= BOUND + 1e-12


def _g1_stack(model):
    """mink's humanoid task set as levels: feet + CoM / hands / posture."""
    feet = [
        FrameTask(f, "site", position_cost=1.0, orientation_cost=1.0)
        for f in ("left_foot", "right_foot")
    ]  # noqa: E501
    com = ComTask(cost=1.0)
    hands = [PositionTask(h, "site") for h in ("left_palm", "right_palm")]
    posture = PostureTask(model, cost=0.1)
    return feet, com, hands, posture


@pytest.mark.parametrize("speed", ["default", "none"])
def test_humanoid_feet_hold_with_a_hand_out_of_reach(speed):
    model = qpik.load_robot(str(DATA / "g1.xml"))
    configuration = qpik.Configuration(model, model.key_qpos[0])
    feet, com, hands, posture = _g1_stack(model)
    for task in feet:
        task.set_target_from_configuration(configuration)
    com.set_target_from_configuration(configuration)
    posture.set_target_from_configuration(configuration)
    left = configuration.frame_pose("left_palm", "site")[0]
    hands[0].set_target(left + np.array([2.0, 0.5, 0.5]))  # 2 m ahead: out of reach
    hands[1].set_target(configuration.frame_pose("right_palm", "site")[0])
    start = [configuration.frame_pose(f, "site")[0].copy() for f in ("left_foot", "right_foot")]
    options = qpik.StepOptions(max_joint_speed=None) if speed == "none" else None
    solver = qpik.IKSolver(
        model, [[*feet, com], hands, [posture]], joint_limits(model), options=options
    )
    drift = 0.0
    for _ in range(50):
        result = solver.step(configuration, DT)
        configuration.integrate_inplace(result.velocity, DT)
        drift = max(
            drift,
            *(
                float(np.linalg.norm(configuration.frame_pose(f, "site")[0] - p))
                for f, p in zip(("left_foot", "right_foot"), start)
            ),
        )
    if speed == "default":
        assert drift <= 1e-3
    else:  # without it, the feet drift (what issue 22 measured)
        assert drift > 1e-3


def test_ball_joint_range_holds_in_differential_ik():
    """A ball joint's range (60 degrees) holds while a posture task pulls it 2.5 rad away."""
    model = mujoco.MjModel.from_xml_string(BALL)
    bound = float(model.jnt_range[0, 1])  # [rad] (MJCF ranges are in degrees)
    configuration = qpik.Configuration(model)
    posture = PostureTask(model, cost=1.0)
    target = np.zeros(4)
    mujoco.mju_axisAngle2Quat(target, np.array([1.0, 0.0, 0.0]), 2.5)
    posture.set_target(target)
    solver = qpik.IKSolver(model, [posture], joint_limits(model))
    worst = 0.0
    for _ in range(200):
        result = solver.step(configuration, DT)
        configuration.integrate_inplace(result.velocity, DT)
        quat = configuration.q[:4]
        angle = 2 * np.arctan2(np.linalg.norm(quat[1:]), abs(quat[0]))
        worst = max(worst, float(angle))
    assert worst <= bound + 1e-3
    assert worst > bound - 0.05  # it went to the range's edge
