"""Priority QP engine: strict priorities, limits, damping, backends, failures."""

from __future__ import annotations

import mink
import mujoco
import numpy as np
import pytest
from conftest import configuration_of

import qpik
from qpik import solve_ik
from qpik.diffik.solver import DampingLaw, IKSolver, normalize_stack
from qpik.igm.baselines import nullspace_projection_step, pseudoinverse_step
from qpik.tasks import FrameTask, JointLimitDistanceTask, PositionTask, PostureTask

DT = 0.01


def panda(q=None, rng=None):
    configuration = configuration_of("panda")
    if q is None:
        q = configuration.random_q(rng) if rng is not None else configuration.mid_q()
    configuration.update(q)
    return configuration


def pose_task(configuration, rng, cost=1.0):
    """A FrameTask whose target is the pose of a nearby random configuration."""
    task = FrameTask("ee", "site", position_cost=cost, orientation_cost=cost)
    other = configuration.copy()
    q = configuration.q + rng.uniform(-0.3, 0.3, configuration.nv)
    other.update(np.clip(q, configuration.lower, configuration.upper))
    task.set_target_from_configuration(other)
    return task


def residual_norm(task, configuration, velocity, dt=DT):
    A, b, _ = task.compute_qp_residual(configuration)
    return float(np.linalg.norm(A @ (velocity * dt) - b))


def conflicting_tasks(configuration):
    """End effector and elbow pulled to positions no configuration reaches together."""
    ee = PositionTask("ee")
    ee.set_target(configuration.frame_pose("ee")[0] + np.array([0.3, 0.1, -0.2]))
    elbow = PositionTask("link4", "body")
    elbow.set_target(configuration.frame_pose("link4", "body")[0] + np.array([-0.3, 0.2, 0.3]))
    return ee, elbow


def test_normalize_stack():
    configuration = panda()
    a, b = conflicting_tasks(configuration)
    assert normalize_stack(a) == [[a]]
    assert normalize_stack([a, b]) == [[a, b]]  # a flat list is one weighted level
    assert normalize_stack([[a], b]) == [[a], [b]]
    with pytest.raises(qpik.InvalidInput, match="level 1"):
        normalize_stack([[a], []])
    with pytest.raises(qpik.InvalidInput, match="empty"):
        normalize_stack([])


def test_priority_keeps_higher_level_and_swaps():
    configuration = panda()
    limits = [mink.ConfigurationLimit(configuration.model)]
    ee, elbow = conflicting_tasks(configuration)
    alone_ee = IKSolver(configuration.model, [ee], limits).step(configuration, DT)
    alone_elbow = IKSolver(configuration.model, [elbow], limits).step(configuration, DT)
    first = IKSolver(configuration.model, [[ee], [elbow]], limits).step(configuration, DT)
    swapped = IKSolver(configuration.model, [[elbow], [ee]], limits).step(configuration, DT)
    assert first.ok and swapped.ok
    assert abs(first.residuals[0] - alone_ee.residuals[0]) <= 1e-6
    assert abs(swapped.residuals[0] - alone_elbow.residuals[0]) <= 1e-6
    # The conflict is real: whichever task is second is worse off than when it is first.
    assert first.residuals[1] > swapped.residuals[0] + 1e-3
    assert swapped.residuals[1] > first.residuals[0] + 1e-3
    # Three levels keep their order: adding a posture level changes nothing above it.
    posture = PostureTask(configuration.model, cost=1.0)
    posture.set_target(configuration.mid_q() + 0.3)
    three = IKSolver(configuration.model, [[ee], [elbow], [posture]], limits).step(
        configuration, DT
    )
    np.testing.assert_allclose(three.residuals[:2], first.residuals, atol=1e-6)


def test_two_levels_equal_classical_nullspace_projection(rng):
    checked = 0
    while checked < 20:
        configuration = panda(rng=rng)
        frame = pose_task(configuration, rng)
        posture = PostureTask(configuration.model, cost=0.5)
        posture.set_target(configuration.mid_q())
        A1, b1, _ = frame.compute_qp_residual(configuration)
        A2, b2, _ = posture.compute_qp_residual(configuration)
        if np.linalg.svd(A1, compute_uv=False)[-1] < 0.05:
            continue  # near a singularity the undamped formula is itself ill-posed
        solver = IKSolver(configuration.model, [[frame], [posture]], damping=1e-9, damping_law=None)
        dq = solver.step(configuration, 1.0).displacement
        np.testing.assert_allclose(dq, nullspace_projection_step(A1, b1, A2, b2), atol=1e-5)
        checked += 1


def test_default_damping_matches_classical_away_from_singularities(rng):
    checked = 0
    while checked < 10:
        configuration = panda(rng=rng)
        frame = pose_task(configuration, rng)
        posture = PostureTask(configuration.model, cost=0.5)
        posture.set_target(configuration.mid_q())
        # The classical formula is undamped: only the adaptive law's damping is left on.
        result = IKSolver(configuration.model, [[frame], [posture]], damping=1e-9).step(
            configuration, 1.0
        )
        if result.damping != [0.0, 0.0]:
            continue
        A1, b1, _ = frame.compute_qp_residual(configuration)
        A2, b2, _ = posture.compute_qp_residual(configuration)
        np.testing.assert_allclose(
            result.displacement, nullspace_projection_step(A1, b1, A2, b2), atol=1e-5
        )
        checked += 1


@pytest.mark.parametrize("backend", ["daqp", "quadprog"])
def test_osqp_equals_other_backends(backend, rng):
    for _ in range(10):
        configuration = panda(rng=rng)
        model = configuration.model
        limits = [mink.ConfigurationLimit(model), qpik.limits.velocity_limit_from_model(model)]
        frame = pose_task(configuration, rng)
        posture = PostureTask(model, cost=0.1)
        posture.set_target(configuration.mid_q())
        stack = [[frame], [posture]]
        osqp_step = IKSolver(model, stack, limits).step(configuration, DT)
        other = IKSolver(model, stack, limits, solver=backend).step(configuration, DT)
        assert osqp_step.ok and other.ok
        np.testing.assert_allclose(osqp_step.velocity, other.velocity, atol=1e-5)


def test_flat_level_matches_mink_solve_ik(rng):
    for _ in range(10):
        configuration = panda(rng=rng)
        model = configuration.model
        limits = [mink.ConfigurationLimit(model), qpik.limits.velocity_limit_from_model(model)]
        frame = pose_task(configuration, rng)
        posture = PostureTask(model, cost=0.1)
        posture.set_target(configuration.mid_q())
        ours = IKSolver(model, [frame, posture], limits, damping=1e-3).step(configuration, DT)
        theirs = mink.solve_ik(
            configuration, [frame, posture], DT, "daqp", damping=1e-3, limits=limits
        )
        if ours.damping[0] == 0.0:
            np.testing.assert_allclose(ours.velocity, theirs, atol=1e-5)


def test_mink_tasks_and_limits_at_every_level(rng):
    configuration = panda(rng=rng)
    model = configuration.model
    com = mink.ComTask(cost=1.0)
    com.set_target(configuration.data.subtree_com[1] + 0.01)
    damping_task = mink.DampingTask(model, cost=0.1)
    frame = pose_task(configuration, rng)
    limits = [mink.ConfigurationLimit(model), mink.VelocityLimit(model, {"joint1": 0.5})]
    for stack in ([[frame], [com], [damping_task]], [[com], [frame, damping_task]]):
        result = IKSolver(model, stack, limits).step(configuration, DT)
        assert result.ok and np.all(np.isfinite(result.velocity))
        assert abs(result.velocity[0]) <= 0.5 + 1e-9


@pytest.mark.parametrize("solver_name", ["auto", "osqp"])
def test_limits_hold_over_1000_random_steps(rng, solver_name):
    configuration = panda()
    model = configuration.model
    vmax = configuration.velocity_limits()
    limits = [mink.ConfigurationLimit(model), qpik.limits.velocity_limit_from_model(model)]
    frame = FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    posture = PostureTask(model, cost=0.01)
    solver = IKSolver(model, [[frame], [posture]], limits, solver=solver_name)
    for _episode in range(10):
        configuration.update(configuration.random_q(rng))
        goal = configuration.copy()
        goal.update(goal.random_q(rng))
        frame.set_target_from_configuration(goal)
        posture.set_target(goal.q)
        for _ in range(100):
            result = solver.step(configuration, DT)
            assert np.all(np.abs(result.velocity) <= vmax + 1e-9)
            q_next = configuration.integrate(result.velocity, DT)
            assert np.all(q_next >= configuration.lower - 1e-12)
            assert np.all(q_next <= configuration.upper + 1e-12)
            configuration.update(q_next)
    if solver_name == "osqp":  # at most one OSQP workspace per level, never rebuilt
        assert 1 <= solver.workspace_setups <= 2
    else:
        assert solver.workspace_setups == 0


def test_start_outside_limits_recovers_under_velocity_limits():
    """pink issue #206: outside the position limits with tight velocity limits, the QP must
    stay feasible and move back at the velocity limit."""
    configuration = panda()
    model = configuration.model
    q = configuration.mid_q()
    q[3] = configuration.upper[3] + 0.5  # joint4 half a radian above its upper limit
    configuration.update(q)
    limits = [mink.ConfigurationLimit(model), mink.VelocityLimit(model, {"joint4": 0.1})]
    posture = PostureTask(model, cost=1.0)
    posture.set_target(q)  # the posture task even pulls the wrong way
    solver = IKSolver(model, [posture], limits)
    for _ in range(600):
        result = solver.step(configuration, DT)
        assert result.ok
        configuration.integrate_inplace(result.velocity, DT)
        if configuration.q[3] <= configuration.upper[3]:
            break
    assert result.velocity[3] == pytest.approx(-0.1) or configuration.within_limits()
    assert configuration.within_limits(tol=1e-9)


def test_2r_singularity_step_stays_bounded():
    configuration = configuration_of("planar_2r", [np.pi / 4, 0.001])
    task = PositionTask("ee")
    position = configuration.frame_pose("ee")[0]
    # Ask for motion along the arm (the direction the singular arm cannot produce).
    target = position - 0.05 * position / np.linalg.norm(position)
    task.set_target(target)
    law = DampingLaw()
    result = IKSolver(configuration.model, [task], damping_law=law).step(configuration, 1.0)
    J = configuration.frame_jacobian("ee")[:2]
    xi = (target - position)[:2]
    plain = pseudoinverse_step(J, xi)
    assert np.linalg.norm(plain) > 1000 * np.linalg.norm(xi) * 0.5
    assert result.sigma_min[0] < 1e-3 and result.damping[0] > 0
    bound = np.linalg.norm(xi) / (2 * law.max_damping)
    assert np.linalg.norm(result.displacement) <= bound
    assert np.linalg.norm(result.displacement) < np.linalg.norm(plain) / 100


def test_2r_converges_away_from_singularity():
    configuration = configuration_of("planar_2r", [np.pi / 4, 0.001])
    task = PositionTask("ee")
    task.set_target([1.2, 0.3, 0.0])
    solver = IKSolver(configuration.model, [task], [mink.ConfigurationLimit(configuration.model)])
    for _ in range(200):
        configuration.integrate_inplace(solver.step(configuration, 1.0).velocity, 1.0)
    np.testing.assert_allclose(configuration.frame_pose("ee")[0], [1.2, 0.3, 0.0], atol=1e-8)


def test_joint_limit_distance_in_the_null_space(rng):
    from qpik.analysis import joint_limit_distance

    configuration = panda()
    q = configuration.mid_q() + np.array([1.5, 0.8, -1.5, 0.6, 1.5, -1.0, 1.2]) * 0.9
    configuration.update(np.clip(q, configuration.lower, configuration.upper))
    model = configuration.model
    frame = FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    frame.set_target_from_configuration(configuration)
    distance = JointLimitDistanceTask(cost=1.0, gain=0.5)
    limits = [mink.ConfigurationLimit(model)]
    both = IKSolver(model, [[frame], [distance]], limits)
    alone = IKSolver(model, [[frame]], limits)
    start = joint_limit_distance(configuration.q, configuration.lower, configuration.upper)
    for _ in range(50):
        result = both.step(configuration, DT)
        reference = alone.step(configuration, DT)
        assert abs(result.residuals[0] - reference.residuals[0]) <= 1e-6
        configuration.integrate_inplace(result.velocity, DT)
    end = joint_limit_distance(configuration.q, configuration.lower, configuration.upper)
    assert end < 0.8 * start
    # Null-space motion drifts the pose at second order; level 0 corrects it every step.
    np.testing.assert_allclose(frame.compute_error(configuration), 0.0, atol=1e-4)


def test_missing_backend_names_the_extra(monkeypatch):
    import qpsolvers

    monkeypatch.setattr(qpsolvers, "available_solvers", ["osqp"])
    configuration = panda()
    with pytest.raises(qpik.MissingExtra, match=r"qpik\[solvers\]"):
        IKSolver(configuration.model, [PostureTask(configuration.model, 1.0)], solver="daqp")
    with pytest.raises(qpik.InvalidInput, match="unknown QP solver 'gurobix'"):
        IKSolver(configuration.model, [PostureTask(configuration.model, 1.0)], solver="gurobix")


class ContradictoryRows(mink.Limit):
    """x0 + x1 <= -1 and -(x0 + x1) <= -1: no dq satisfies both."""

    def compute_qp_inequalities(self, configuration, dt):
        G = np.zeros((2, configuration.nv))
        G[0, :2], G[1, :2] = 1.0, -1.0
        return mink.Constraint(G=G, h=np.array([-1.0, -1.0]))


class ContradictoryBox(mink.Limit):
    def compute_qp_inequalities(self, configuration, dt):
        G = np.zeros((2, configuration.nv))
        G[0, 0], G[1, 0] = 1.0, -1.0
        return mink.Constraint(G=G, h=np.array([-1.0, -1.0]))


def test_infeasible_general_rows_are_never_dropped():
    configuration = panda()
    posture = PostureTask(configuration.model, cost=1.0)
    posture.set_target(configuration.mid_q() + 0.1)
    result = IKSolver(configuration.model, [posture], [ContradictoryRows()]).step(configuration, DT)
    assert result.status == ["infeasible"] and not result.ok
    np.testing.assert_array_equal(result.displacement, 0.0)  # no motion rather than no limit
    with pytest.raises(qpik.NoSolutionFound):
        solve_ik(configuration, [posture], DT, limits=[ContradictoryRows()])


def test_infeasible_box_limits_raise():
    configuration = panda()
    posture = PostureTask(configuration.model, cost=1.0)
    posture.set_target(configuration.mid_q())
    with pytest.raises(qpik.InfeasibleLimits, match="joint1"):
        solve_ik(configuration, [posture], DT, limits=[ContradictoryBox()])


def test_solve_ik_returns_velocity_and_validates_dt():
    configuration = panda()
    posture = PostureTask(configuration.model, cost=1.0)
    posture.set_target(configuration.mid_q() + 0.01)
    v = solve_ik(configuration, [posture], 0.1)
    np.testing.assert_allclose(v, 0.1, atol=1e-5)
    with pytest.raises(qpik.InvalidInput, match="dt"):
        solve_ik(configuration, [posture], 0.0)


def test_active_limits_are_named():
    configuration = panda()
    model = configuration.model
    posture = PostureTask(model, cost=1.0)
    posture.set_target(configuration.mid_q() + 1.0)
    limits = [mink.VelocityLimit(model, {"joint2": 0.2})]
    result = IKSolver(model, [posture], limits, options=qpik.StepOptions(max_joint_speed=None))
    assert result.step(configuration, DT).active_limits == ["joint2 upper (VelocityLimit)"]
    # With the default trust region, the other joints' 1 rad steps are bounded and named.
    result = IKSolver(model, [posture], limits).step(configuration, DT)
    assert "joint2 upper (VelocityLimit)" in result.active_limits
    assert "joint1 upper (trust region)" in result.active_limits
    assert np.abs(result.displacement).max() <= np.pi * DT + 1e-12


class SumLimit(mink.Limit):
    """A general row: dq0 + dq1 <= 0.001 (no single-dof bound)."""

    def compute_qp_inequalities(self, configuration, dt):
        G = np.zeros((1, configuration.nv))
        G[0, :2] = 1.0
        return mink.Constraint(G=G, h=np.array([0.001]))


def test_general_rows_hold_at_every_level():
    configuration = panda()
    model = configuration.model
    ee, elbow = conflicting_tasks(configuration)
    posture = PostureTask(model, cost=1.0)
    posture.set_target(configuration.mid_q() + 1.0)  # pulls dq0 + dq1 up
    limits = [SumLimit(), mink.ConfigurationLimit(model)]
    for stack in ([posture], [[ee], [posture]], [[elbow], [ee], [posture]]):
        result = IKSolver(model, stack, limits).step(configuration, DT)
        assert result.ok
        dq = result.displacement
        assert dq[0] + dq[1] <= 0.001 + 1e-9
        if stack == [posture]:  # alone, the posture pushes against the row
            assert "SumLimit row 0" in result.active_limits


OBSTACLE_2R = """
<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <geom name="obstacle" type="sphere" size="0.25" pos="1.2 0.9 0"/>
    <body name="link1">
      <joint name="q1" type="hinge" axis="0 0 1" range="-3.1 3.1"/>
      <geom name="link1" type="capsule" size="0.04" fromto="0 0 0 1 0 0"/>
      <body name="link2" pos="1 0 0">
        <joint name="q2" type="hinge" axis="0 0 1" range="-3.1 3.1"/>
        <geom name="link2" type="capsule" size="0.04" fromto="0 0 0 1 0 0"/>
        <site name="ee" pos="1 0 0"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _closest_approach(model, limits, steps=300):
    """Track a tip target behind an obstacle (posture below it); the closest approach of
    the links to the obstacle [m] and how many steps a collision row was active."""
    configuration = qpik.Configuration(model, [0.0, 0.3])
    tip = PositionTask("ee", gain=0.05)
    tip.set_target([0.6, 1.7, 0.0])  # behind the obstacle: the straight way goes through it
    posture = PostureTask(model, cost=0.1)
    posture.set_target([0.0, 0.3])
    # No trust region: the rows alone must keep the links out (tests/diffik/test_physical_steps.py
    # holds the default's).
    solver = IKSolver(
        model, [[tip], [posture]], limits, options=qpik.StepOptions(max_joint_speed=None)
    )
    fromto = np.zeros(6)
    closest, active = np.inf, 0
    for _ in range(steps):
        result = solver.step(configuration, DT)
        assert result.ok
        active += any(n.startswith("CollisionAvoidanceLimit") for n in result.active_limits)
        configuration.integrate_inplace(result.velocity, DT)
        for link in ("link1", "link2"):
            closest = min(
                closest,
                mujoco.mj_geomDistance(
                    model,
                    configuration.data,
                    model.geom(link).id,
                    model.geom("obstacle").id,
                    1.0,
                    fromto,
                ),
            )
    return closest, active


def test_collision_avoidance_rows_hold_at_every_level():
    model = mujoco.MjModel.from_xml_string(OBSTACLE_2R)
    avoid = mink.CollisionAvoidanceLimit(
        model,
        [(["link1", "link2"], ["obstacle"])],
        minimum_distance_from_collisions=0.02,
        collision_detection_distance=0.2,
    )
    free, _ = _closest_approach(model, [mink.ConfigurationLimit(model)])
    guarded, active = _closest_approach(model, [avoid, mink.ConfigurationLimit(model)])
    assert free < -0.1  # without the limit, link 2 passes through the obstacle
    assert active > 0 and guarded > 0.0  # with it, the row binds and nothing penetrates


def test_nan_target_of_a_mink_task_names_the_level():
    configuration = panda()
    frame = FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    frame.set_target(mink.SE3.from_translation(np.array([0.3, np.nan, 0.5])))
    posture = PostureTask(configuration.model, cost=1.0)
    posture.set_target(configuration.q)
    with pytest.raises(qpik.InvalidTarget, match="priority level 1.*FrameTask"):
        IKSolver(configuration.model, [[posture], [frame]]).step(configuration, DT)


class GenericConfigurationLimit(mink.ConfigurationLimit):
    """Same rows; a subclass, so the solver takes the generic compute_qp_inequalities path."""


class GenericVelocityLimit(mink.VelocityLimit):
    """Same rows; a subclass, so the solver takes the generic path."""


def test_direct_box_limits_equal_the_generic_path(rng):
    configuration = panda()
    model = configuration.model
    velocities = {f"joint{i + 1}": 0.5 for i in range(7)}
    direct = [mink.ConfigurationLimit(model), mink.VelocityLimit(model, velocities)]
    generic = [GenericConfigurationLimit(model), GenericVelocityLimit(model, velocities)]
    for _ in range(10):
        configuration.update(configuration.random_q(rng))
        frame = pose_task(configuration, rng)
        a = IKSolver(model, [frame], direct).step(configuration, DT)
        b = IKSolver(model, [frame], generic).step(configuration, DT)
        np.testing.assert_allclose(a.velocity, b.velocity, atol=1e-9)
        assert sorted(a.active_limits) == sorted(n.replace("Generic", "") for n in b.active_limits)
