"""Stacks users write that left the compiled step (h10's audit, each slower than mink
there): a dt that is np.float64 or an int, a limited ball joint turned about one axis, and
an objective-only task (mink's KineticEnergyRegularizationTask) whose rows took an
eigendecomposition each step. Each now takes the compiled step, with the same answer."""

from __future__ import annotations

import mink
import mujoco
import numpy as np

import qpik
from qpik.diffik.rows import _objective_rows

BALLS = """<mujoco><compiler angle="radian"/><worldbody><body><joint type="ball" range="0 1.0" limited="true"/>
<geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.03" mass="1"/>
<body pos="0 0 0.3"><joint type="hinge" axis="0 1 0" range="-2 2" limited="true"/>
<geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.03" mass="1"/>
<body pos="0 0 0.3"><joint type="ball" range="0 0.8" limited="true"/>
<geom type="capsule" fromto="0 0 0 0 0 0.2" size="0.03" mass="1"/>
<site name="tip" pos="0 0 0.2"/></body></body></body></worldbody></mujoco>"""


def _arm():
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    frame = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    frame.set_target(
        configuration.get_transform_frame_to_world("ee", "site")
        @ mink.SE3.from_translation(np.array([0.03, -0.03, 0.03]))
    )
    posture = mink.PostureTask(model, cost=1e-2)
    posture.set_target_from_configuration(configuration)
    return model, configuration, [frame, posture]


def test_a_dt_of_numpy_or_int_type_is_its_floats_step():
    model, configuration, tasks = _arm()
    limits = [mink.ConfigurationLimit(model)]
    reference = qpik.solve_ik(configuration, tasks, 0.01, "daqp", limits=limits)
    for dt in (np.float64(0.01), np.float32(0.25), 1):
        solver = qpik.IKSolver(model, [tasks], limits)
        assert solver.compiled_velocity(configuration, dt) is not None
        same = qpik.solve_ik(configuration, tasks, float(dt), "daqp", limits=limits)
        assert np.array_equal(qpik.solve_ik(configuration, tasks, dt, "daqp", limits=limits), same)
    assert np.array_equal(
        qpik.solve_ik(configuration, tasks, np.float64(0.01), "daqp", limits=limits), reference
    )


def test_a_ball_joint_turned_about_one_axis_takes_the_compiled_step():
    model = mujoco.MjModel.from_xml_string(BALLS)
    binding = 0
    for axis in ([1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [1.0, 0.7, 0.3]):
        axis = np.array(axis) / np.linalg.norm(axis)
        q = model.qpos0.copy()
        q[0:4] = [np.cos(0.495), *(np.sin(0.495) * axis)]  # 0.99 rad of the cone's 1.0
        q[4] = 0.5
        configuration = qpik.Configuration(model, q)
        frame = mink.FrameTask("tip", "site", position_cost=1.0, orientation_cost=0.1)
        frame.set_target(
            configuration.get_transform_frame_to_world("tip", "site")
            @ mink.SE3.from_translation(np.array([0.05, -0.05, 0.05]))
        )
        posture = mink.PostureTask(model, cost=1e-2)
        posture.set_target_from_configuration(configuration)
        limits = [mink.ConfigurationLimit(model)]
        solver = qpik.IKSolver(model, [[frame, posture]], limits)
        fast = solver.compiled_velocity(configuration, 0.01)
        assert fast is not None
        general = solver.qp_solution(configuration, 0.01)
        np.testing.assert_allclose(fast[0], general.velocity, atol=1e-9)
        # the cone's row (gain 0.95 of the 0.01 rad left) holds, and binds on some axes
        turn = axis @ fast[0][0:3] * 0.01
        assert turn <= 0.95 * 0.01 + 1e-12
        binding += abs(turn - 0.95 * 0.01) <= 1e-12
    assert binding >= 1


def test_objective_rows_reproduce_the_objective_by_either_factor(rng):
    """Cholesky where H is positive definite with room, the eigendecomposition where it is
    not (rank-deficient: a zero row per null direction); A^T A = H, A^T b = -c either way
    (on H's range)."""
    n = 7
    B = rng.normal(size=(n, n))
    for H in (B @ B.T + np.eye(n), B[:4].T @ B[:4]):
        c = H @ rng.normal(size=n)  # (in H's range)
        A, b, mu, weights = _objective_rows(H, c)
        assert A.shape == (n, n) and mu is None and weights.tolist() == [1.0] * n
        np.testing.assert_allclose(A.T @ A, H, atol=1e-10)
        np.testing.assert_allclose(A.T @ b, -c, atol=1e-9)


def test_the_kinetic_energy_task_takes_the_cholesky_rows():
    model, configuration, tasks = _arm()
    energy = qpik.tasks.KineticEnergyRegularizationTask(cost=1e-3)
    energy.set_dt(0.01)
    stack = [*tasks, energy]
    limits = [mink.ConfigurationLimit(model)]
    ours = qpik.solve_ik(configuration, stack, 0.01, "daqp", limits=limits)
    theirs = mink.solve_ik(configuration, stack, 0.01, "daqp", limits=limits)
    np.testing.assert_allclose(ours, theirs, atol=1e-8)


class ShoulderCap(mink.Limit):
    """A limit of one's own (docs/guides/mink.md's): joint 2 at most 0.5 rad/s, and a
    two-dof row."""

    def compute_qp_inequalities(self, configuration, dt):
        G = np.zeros((2, configuration.model.nv))
        G[0, 1] = 1.0
        G[1, 2:4] = [1.0, -1.0]
        return mink.Constraint(G=G, h=np.array([0.5 * dt, 0.3 * dt]))


def test_a_limit_of_ones_own_takes_the_compiled_step():
    """Its rows are hard general rows of the compiled step (h10's audit: the QP path, 2.5x
    mink's time): the same velocity as the QP path's to round-off, its rows met."""
    model, configuration, tasks = _arm()
    tasks[0].set_target(
        tasks[0].transform_target_to_world @ mink.SE3.from_translation(np.array([0.2, 0.1, 0.1]))
    )
    limits = [mink.ConfigurationLimit(model), ShoulderCap()]
    solver = qpik.IKSolver(model, [tasks], limits)
    fast = solver.compiled_velocity(configuration, 0.01)
    assert fast is not None
    general = solver.qp_solution(configuration, 0.01)
    np.testing.assert_allclose(fast[0], general.velocity, atol=1e-9)
    assert fast[0][1] <= 0.5 + 1e-12 and fast[0][2] - fast[0][3] <= 0.3 + 1e-12
    assert abs(fast[0][1] - 0.5) <= 1e-12 or abs(fast[0][2] - fast[0][3] - 0.3) <= 1e-12
    step = solver.step(configuration, 0.01)
    assert np.array_equal(step.velocity, fast[0]) and step.ok


class _OwnConfigurationLimit(mink.ConfigurationLimit):
    """A subclass of mink's box limit: its steps take the QP path."""


def test_the_qp_path_reads_a_mink_configuration_as_qpiks_tasks_do():
    """Pins h12's audit: on the QP path (here a subclass of mink's ConfigurationLimit; in the
    audit, support rows to relax), qpik's own tasks were handed the mink.Configuration and
    raised AttributeError ('lower') or InvalidArgumentType; the same step as a
    qpik.Configuration's."""
    from qpik.tasks import JointLimitDistanceTask, ManipulabilityTask

    model = qpik.load_robot("panda")
    q = model.key_qpos[0]
    for task in (JointLimitDistanceTask(cost=0.1), ManipulabilityTask("ee", "site", cost=0.1)):
        solver = qpik.IKSolver(model, [[task]], [_OwnConfigurationLimit(model)])
        assert solver.compiled_velocity(qpik.Configuration(model, q), 0.01) is None
        ours = solver.step(qpik.Configuration(model, q), 0.01)
        theirs = solver.step(mink.Configuration(model, q), 0.01)
        assert np.array_equal(ours.velocity, theirs.velocity) and theirs.ok


class _FarRow(mink.Limit):
    """dq_0 <= 1 rad: out of reach of the trust region's box (|dq_0| <= pi dt)."""

    def compute_qp_inequalities(self, configuration, dt):
        G = np.zeros((1, configuration.model.nv))
        G[0, 0] = 1.0
        return mink.Constraint(G=G, h=np.array([1.0]))


def test_a_row_out_of_reach_leaves_the_answer_bitwise_on_a_model_with_couplings():
    """Pins h13's audit: docs/concepts/levels.md says a general row no displacement in the
    box brings to its bound leaves the answer bitwise the one without it; on erd:panda (its
    finger mimic: a coupling level, solved by couple.hpp's exact fast path) the row sent the
    step to the general path, 1e-9 rad/s off."""
    from conftest import load_or_skip

    model = load_or_skip("erd:panda")
    q = model.qpos0.copy()
    q[:7] = [0.3, -0.4, 0.2, -2.0, 0.1, 1.6, 0.5]
    configuration = qpik.Configuration(model, q)
    task = mink.FrameTask("panda_link7", "body", position_cost=1.0, orientation_cost=1.0)
    task.set_target(
        mink.SE3.from_translation(np.array([0.05, -0.1, 0.08]))
        @ configuration.get_transform_frame_to_world("panda_link7", "body")
    )
    limits = [mink.ConfigurationLimit(model)]
    without = qpik.IKSolver(model, [[task]], limits).step(configuration, 0.01)
    with_row = qpik.IKSolver(model, [[task]], [*limits, _FarRow()]).step(configuration, 0.01)
    assert np.array_equal(without.velocity, with_row.velocity)
    assert with_row.status == without.status and with_row.ok
