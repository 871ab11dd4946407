"""Ball-joint ranges hold for a step of any size (issue 22): the rows of
:class:`qpik.limits.BallJointLimit`, which :func:`qpik.limits.joint_limits` adds, keep the
rotation angle after MuJoCo's own integration (``mj_integratePos``) within the range with
the trust region off, and leave a step alone where the range does not bind."""

from __future__ import annotations

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


def _vertices(rows: np.ndarray, bounds: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """The vertices of ``{dq : rows dq <= bounds}`` (``inside`` strictly feasible)."""
    from scipy.spatial import HalfspaceIntersection

    return HalfspaceIntersection(np.column_stack([rows, -bounds]), inside).intersections


def _mujoco_limit_distance(model: mujoco.MjModel, data: mujoco.MjData, quat: np.ndarray) -> float:
    """MuJoCo's own distance to the ball joint's limit (``efc_pos`` of its limit row:
    ``range - angle``, negative past the range), with a margin that makes the row exist
    at every rotation."""
    data.qpos[:] = 0.0
    data.qpos[1:5] = quat
    mujoco.mj_fwdPosition(model, data)
    rows = np.flatnonzero(
        (data.efc_type[: data.nefc] == int(mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT))
        & (data.efc_id[: data.nefc] == 1)
    )
    assert len(rows) == 1
    return float(data.efc_pos[rows[0]])


@pytest.mark.parametrize("subdivisions", [0, 1, 2])
def test_rows_hold_the_range_against_mujocos_limit(subdivisions):
    """The rows' polytope is inscribed in the ball ``|phi + dq| <= range`` with a vertex
    at ``range * phi / |phi|``; at every vertex and at random points inside, MuJoCo's own
    ball-joint limit (``efc_pos`` after ``mj_integratePos``) is not passed; ``dq = 0`` is
    always feasible."""
    model = mujoco.MjModel.from_xml_string(BALL)
    model.jnt_margin[1] = 10.0  # the limit row exists at every rotation
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    for _ in range(60 if subdivisions < 2 else 15):
        rho = rng.uniform(0.05, 3.0)
        model.jnt_range[1] = [0.0, rho]
        phi = rng.normal(size=3)
        phi *= rng.uniform(0.0, rho) / np.linalg.norm(phi)
        theta = float(np.linalg.norm(phi))
        rows, bounds = ball_rows(phi, rho, subdivisions)
        assert np.all(bounds >= -1e-12)  # dq = 0 is feasible
        corners = _vertices(rows, bounds, -0.5 * phi)
        radii = np.linalg.norm(corners + phi, axis=1)
        assert np.all(radii <= rho + 1e-9)
        if theta > 1e-9 and 2 * rho <= np.pi:  # the vertex along the axis (no |dq| box)
            assert np.min(np.linalg.norm(corners + phi - rho * phi / theta, axis=1)) < 1e-9
        weights = rng.dirichlet(np.ones(len(corners)), size=20)
        start = _quat(phi if theta > 1e-12 else np.array([0.0, 0.0, 1.0]), theta)
        for dq in np.vstack([corners, weights @ corners]):
            qpos = np.zeros(model.nq)
            qpos[1:5] = start
            velocity = np.zeros(model.nv)
            velocity[1:4] = dq
            mujoco.mj_integratePos(model, qpos, velocity, 1.0)
            assert _mujoco_limit_distance(model, data, qpos[1:5]) >= -1e-9
            assert _angle(qpos[1:5]) <= rho + 1e-9


def test_the_icosahedron_is_tighter_than_the_cube():
    """Against the cube of earlier versions (6 faces, a vertex along the axis): at the
    range's edge a tangential move needs less inward motion (tan 37.4 deg against tan 54.7
    deg), and the rows leave alone every step that ends within 79 % of the range (58 %)."""
    from qpik.limits.ball import unit_polytope

    normals, offsets = unit_polytope(0)
    assert normals.shape == (20, 3) and np.allclose(offsets, offsets[0])
    assert offsets[0] == pytest.approx(0.7947, abs=1e-4) and offsets[0] > 1 / np.sqrt(3)
    at_vertex = np.isclose(normals[:, 0], offsets)  # faces through (1, 0, 0)
    tilt = np.degrees(np.arccos(normals[at_vertex, 0]))
    assert at_vertex.sum() == 5 and np.allclose(tilt, 37.377, atol=1e-3)
    assert len(unit_polytope(1)[0]) == 80 and unit_polytope(1)[1].min() > 0.93
    model = mujoco.MjModel.from_xml_string(BALL)
    assert (
        len(BallJointLimit(model).compute_qp_inequalities(qpik.Configuration(model), 0.01).h) == 20
    )
    with pytest.raises(qpik.LimitDefinitionError):
        BallJointLimit(model, subdivisions=3)


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
    rows bind only past 79 % of the range, 0.83 rad): the step equals the one without
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


def test_the_ball_rows_take_the_compiled_step():
    """With :func:`joint_limits`' BallJointLimit the step is one compiled call (its rows the
    limit's own, general rows of the step; before, every step went to the QP path): in a
    closed loop whose targets turn the head past its range, each step is the QP path's to
    round-off, with the same statuses and the same limits named active, the ball's rows
    among them."""
    model = mujoco.MjModel.from_xml_string(BALL)
    configuration = qpik.Configuration(model)
    frame = FrameTask("eye", "site", position_cost=1.0, orientation_cost=0.1)
    posture = PostureTask(model, cost=1e-2)
    posture.set_target(configuration.q)
    solver = qpik.IKSolver(model, [[frame], [posture]], joint_limits(model))
    rng = np.random.default_rng(3)
    named = 0
    for _ in range(6):
        goal = rng.normal(size=3)
        frame.set_target(
            mink.SE3.from_translation([0.0, 0.0, 0.35] + 0.3 * goal / np.linalg.norm(goal))
        )
        for _ in range(8):
            fast = solver.compiled_velocity(configuration, 0.05)
            assert fast is not None
            result = solver.step(configuration, 0.05)
            reference = solver.qp_solution(configuration, 0.05)
            np.testing.assert_array_equal(fast[0], result.velocity)
            np.testing.assert_allclose(result.velocity, reference.velocity, rtol=0, atol=1e-10)
            assert [str(s) for s in result.status] == [str(s) for s in reference.status]
            expected = qpik.StepResult.of(reference, 0.0).active_limits
            assert sorted(result.active_limits) == sorted(expected)
            named += any("BallJointLimit" in name for name in result.active_limits)
            configuration.update(configuration.integrate(result.velocity, 0.05))
    assert named >= 10


def test_joint_limits_bring_a_ball_started_past_its_range_back():
    """Audit (limits): a limited ball joint (range 60 deg) started at 80 deg about the axis
    (1, 1, 0) never came back under joint_limits(model): mink's ConfigurationLimit row along
    the rotation axis asked for the whole way back in one step, more than the trust region
    allows, and on two dofs it is a general row no recovery relaxes - 200 of 200 steps
    infeasible, the angle at 80. joint_limits leaves mink's ball rows out where
    BallJointLimit holds the range: the joint comes back, every step solved."""
    import collections

    from qpik.limits import joint_limits
    from qpik.tasks import PositionTask

    xml = """<mujoco><worldbody><body name="base">
      <joint name="ball" type="ball" range="0 60" limited="true"/>
      <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.02" mass="1"/>
      <body name="tip" pos="0 0 0.3"><site name="tip"/>
      <geom type="sphere" size="0.02" mass="0.1"/></body></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    axis = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    a = np.radians(80.0)
    configuration = qpik.Configuration(model, np.r_[np.cos(a / 2), np.sin(a / 2) * axis])
    tip = PositionTask("tip", "site", gain=1.0)
    tip.set_target([0.0, 0.0, 0.3])
    solver = qpik.IKSolver(model, [[tip]], joint_limits(model))
    statuses: collections.Counter = collections.Counter()
    for _ in range(200):
        result = solver.step(configuration, 0.01)
        configuration.integrate_inplace(result.velocity, 0.01)
        statuses[result.status[0].value] += 1
    phi = np.zeros(3)
    mujoco.mju_quat2Vel(phi, configuration.q[:4] / np.linalg.norm(configuration.q[:4]), 1.0)
    assert statuses == {"solved": 200} and np.degrees(np.linalg.norm(phi)) < 1.0
