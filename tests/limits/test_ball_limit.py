"""Ball-joint ranges hold for a step of any size (issue 22): the rows of
:class:`qpik.limits.BallJointLimit`, which :func:`qpik.limits.joint_limits` adds, keep the
rotation angle after MuJoCo's own integration (``mj_integratePos``) within the range with
the trust region off, and leave a step alone where the range does not bind."""

from __future__ import annotations

import itertools

import mink
import mujoco
import numpy as np
import pytest

import qpik
from qpik.limits import BallJointLimit, ConfigurationLimit, joint_limits
from qpik.limits.ball import ball_rows
from qpik.tasks import FrameTask, PostureTask

BALL = """
<mujoco>
  <worldbody>
    <body name="base">
      <joint name="yaw" type="hinge" axis="0 0 1" range="-2 2"/>
      <geom type="box" size="0.05 0.05 0.05" mass="1"/>
      <body name="head" pos="0 0 0.35">
        <joint name="neck" type="ball" range="0 60" limited="true"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.05" mass="1"/>
        <site name="eye" pos="0 0 0.3"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _angle(quat: np.ndarray) -> float:
    return float(2.0 * np.arctan2(np.linalg.norm(quat[1:]), abs(quat[0])))


def _quat(axis: np.ndarray, angle: float) -> np.ndarray:
    quat = np.zeros(4)
    mujoco.mju_axisAngle2Quat(quat, axis / np.linalg.norm(axis), angle)
    return quat


def test_joint_limits_adds_the_ball_limit():
    model = mujoco.MjModel.from_xml_string(BALL)
    limits = joint_limits(model)
    assert any(isinstance(limit, BallJointLimit) for limit in limits)
    free = mujoco.MjModel.from_xml_string(BALL.replace('limited="true"', 'limited="false"'))
    assert not any(isinstance(limit, BallJointLimit) for limit in joint_limits(free))
    with pytest.raises(qpik.LimitDefinitionError):
        BallJointLimit(free)


def test_rows_hold_the_range_on_their_polytope():
    """The rows' cube (a vertex on the range's sphere, along the current axis): at its
    vertices and at random points inside it, the angle after ``R exp(dq)`` stays within the
    range, and ``dq = 0`` is always feasible."""
    rng = np.random.default_rng(3)
    for _ in range(300):
        rho = rng.uniform(0.05, 3.0)
        phi = rng.normal(size=3)
        phi *= rng.uniform(0.0, rho) / np.linalg.norm(phi)
        theta = float(np.linalg.norm(phi))
        rows, bounds = ball_rows(phi, rho)
        assert np.all(bounds >= 0.0)
        faces = rows[:3]
        half = rho / np.sqrt(3.0)
        corners = np.array(list(itertools.product([-half, half], repeat=3))) @ faces
        inside = rng.uniform(-half, half, size=(20, 3)) @ faces
        if theta > 1e-12:  # the vertex on the sphere is the one along the axis
            assert np.isclose(np.max(corners @ phi) / theta, rho)
        for z in np.vstack([corners, inside]):
            dq = z - phi
            if np.any(rows @ dq > bounds + 1e-9):
                continue  # cut by the |dq| <= pi box
            quat = _quat(phi if theta > 1e-12 else np.array([0.0, 0.0, 1.0]), theta)
            mujoco.mju_quatIntegrate(quat, dq, 1.0)
            assert _angle(quat) <= rho + 1e-9


@pytest.mark.parametrize("task", ["posture", "frame"])
def test_ball_range_holds_for_any_step_with_the_trust_region_off(task):
    """Random steps of 0.01-0.2 s toward targets up to 2.5 rad away: the angle after
    ``mj_integratePos`` never passes the range (60 degrees) by more than 1e-9, and it
    reaches the range's edge."""
    model = mujoco.MjModel.from_xml_string(BALL)
    bound = float(model.jnt_range[1, 1])
    rng = np.random.default_rng(11)
    configuration = qpik.Configuration(model)
    if task == "posture":
        objective = PostureTask(model, cost=1.0)
    else:
        objective = FrameTask("eye", "site", position_cost=1.0, orientation_cost=0.1)
    solver = qpik.IKSolver(model, [objective], joint_limits(model), max_joint_speed=None)
    worst = 0.0
    for trial in range(20):
        if task == "posture":
            target = np.zeros(model.nq)
            target[1:5] = _quat(rng.normal(size=3), rng.uniform(1.2, 2.5))
            objective.set_target(target)
        else:
            goal = rng.normal(size=3)
            goal = np.array([0.0, 0.0, 0.35]) + 0.3 * goal / np.linalg.norm(goal)
            objective.set_target(mink.SE3.from_translation(goal))
        for _ in range(10):
            dt = rng.uniform(0.01, 0.2)
            velocity = solver.step(configuration, dt).velocity
            qpos = configuration.q.copy()
            mujoco.mj_integratePos(model, qpos, velocity, dt)
            worst = max(worst, _angle(qpos[1:5]))
            assert _angle(qpos[1:5]) <= bound + 1e-9, (trial, _angle(qpos[1:5]) - bound)
            configuration.update(qpos)
    assert worst > bound - 0.05  # it went to the range's edge


def test_the_step_is_unchanged_where_the_range_does_not_bind():
    """Starts and targets within 0.25 rad of the identity under a 60 degree range (the
    rows bind only past ``range / sqrt(3)``, 0.6 rad): the step equals the one without
    them."""
    model = mujoco.MjModel.from_xml_string(BALL)
    rng = np.random.default_rng(5)
    posture = PostureTask(model, cost=1.0)
    with_rows = qpik.IKSolver(model, [posture], joint_limits(model), max_joint_speed=None)
    without = qpik.IKSolver(model, [posture], [ConfigurationLimit(model)], max_joint_speed=None)
    for _ in range(20):
        q = np.zeros(model.nq)
        q[0] = rng.uniform(-1.0, 1.0)
        q[1:5] = _quat(rng.normal(size=3), rng.uniform(0.0, 0.25))
        target = np.zeros(model.nq)
        target[0] = rng.uniform(-1.0, 1.0)
        target[1:5] = _quat(rng.normal(size=3), rng.uniform(0.0, 0.25))
        posture.set_target(target)
        configuration = qpik.Configuration(model, q)
        dt = rng.uniform(0.01, 0.2)
        ours = with_rows.step(configuration, dt).velocity
        theirs = without.step(configuration, dt).velocity
        np.testing.assert_allclose(ours, theirs, atol=1e-9)
