"""qpik's world-frame pose tasks (PositionTask, OrientationTask, PoseTask) in the compiled
step: their rows come from one compiled routine (qpik/_cpp/tasks/pose.hpp), which the
kernel calls for them (no rows supplied from Python) and their own ``compute_qp_residual``
calls too. Checked against an independent NumPy/SciPy reference (the rotation vector by
SciPy, the inverse left Jacobian in closed form), finite differences of the error by
MuJoCo's own ``mj_integratePos``, and the QP path's answer, bit for bit."""

from __future__ import annotations

import mink
import mujoco
import numpy as np
import pytest
from conftest import central_difference
from scipy.spatial.transform import Rotation

import qpik
from qpik.errors import TargetNotSet, TaskDefinitionError
from qpik.limits import velocity_limit_from_model
from qpik.tasks import FrameTask, OrientationTask, PoseTask, PositionTask, PostureTask

DT = 0.01


@pytest.fixture(scope="module")
def panda():
    model = qpik.load_robot("panda")
    return model, qpik.Configuration(model, model.key_qpos[0])


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _ljacinv(phi):
    """The inverse left Jacobian of SO(3) in closed form (Barfoot's), phi away from 0 and pi."""
    theta = np.linalg.norm(phi)
    K = _skew(phi)
    coef = 1.0 / theta**2 - (1.0 + np.cos(theta)) / (2.0 * theta * np.sin(theta))
    return np.eye(3) - 0.5 * K + coef * K @ K


def _reference(task, configuration):
    """``(diag(cost) J, -gain cost e, mu)`` from MuJoCo's pose and Jacobian, SciPy's
    rotation vector and the closed form of the inverse left Jacobian."""
    model, data = configuration.model, configuration.data
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, task.frame_name)
    p, R = data.site_xpos[site].copy(), data.site_xmat[site].reshape(3, 3)
    jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    mujoco.mj_jacSite(model, data, jp, jr, site)
    parts = []
    if isinstance(task, (PositionTask, PoseTask)):
        target = task.target if isinstance(task, PositionTask) else task.target_position
        parts.append((p - target, jp))
    if isinstance(task, (OrientationTask, PoseTask)):
        target = task.target if isinstance(task, OrientationTask) else task.target_rotation
        phi = Rotation.from_matrix(R @ target.T).as_rotvec()
        parts.append((phi, _ljacinv(phi) @ jr))
    e = np.concatenate([a for a, _ in parts])
    J = np.vstack([b for _, b in parts])
    b = task.cost * (-task.gain * e)
    return task.cost[:, None] * J, b, task.lm_damping * float(b @ b)


def _tasks():
    return [
        PositionTask("ee", "site", cost=[1.0, 0.5, 2.0], gain=0.8, lm_damping=0.3),
        OrientationTask("ee", "site", cost=[0.7, 1.0, 0.2], gain=0.9),
        PoseTask("ee", "site", position_cost=1.0, orientation_cost=[0.4, 0.5, 0.6], lm_damping=0.2),
    ]


def _random_targets(rng, configuration, tasks):
    position, rotation = configuration.frame_pose("ee", "site")
    turn = Rotation.from_rotvec(rng.uniform(-1.0, 1.0, 3)).as_matrix()
    for task in tasks:
        target = position + rng.normal(size=3) * 0.1
        if isinstance(task, PositionTask):
            task.set_target(target)
        elif isinstance(task, OrientationTask):
            task.set_target(turn @ rotation)
        else:
            task.set_target(target, turn @ rotation)


def test_rows_equal_an_independent_reference(panda):
    model, configuration = panda
    rng = np.random.default_rng(5)
    tasks = _tasks()
    for _ in range(20):
        configuration.update(model.key_qpos[0] + rng.uniform(-0.5, 0.5, model.nq))
        _random_targets(rng, configuration, tasks)
        for task in tasks:
            A, b, mu = task.compute_qp_residual(configuration)
            ref_A, ref_b, ref_mu = _reference(task, configuration)
            np.testing.assert_allclose(A, ref_A, rtol=0, atol=1e-12)
            np.testing.assert_allclose(b, ref_b, rtol=0, atol=1e-12)
            assert mu == pytest.approx(ref_mu, rel=1e-12, abs=1e-15)
            # the unweighted error and Jacobian are the rows at unit cost and gain -1
            k = b.shape[0]
            np.testing.assert_array_equal(
                A, task.cost[:, None] * task.compute_jacobian(configuration)
            )
            np.testing.assert_array_equal(
                b, task.cost * (-task.gain * task.compute_error(configuration))
            )
            assert k == (6 if isinstance(task, PoseTask) else 3)


def test_jacobian_is_the_errors_derivative(panda):
    """Central differences of the error along each dof by mj_integratePos (conftest's)."""
    model, configuration = panda
    rng = np.random.default_rng(6)
    tasks = _tasks()
    configuration.update(model.key_qpos[0] + rng.uniform(-0.5, 0.5, model.nq))
    _random_targets(rng, configuration, tasks)
    for task in tasks:
        J = task.compute_jacobian(configuration)
        fd = central_difference(configuration, task.compute_error)
        np.testing.assert_allclose(J, fd, rtol=0, atol=1e-7)


def test_the_kernel_computes_them_with_the_qp_paths_bits(panda):
    """The three tasks on two levels above a posture, position and velocity limits: the
    plan computes them itself (no task supplies its rows), its lean step reads their targets
    (no gather after the first step), and each velocity equals the QP path's bit for bit."""
    model, configuration = panda
    rng = np.random.default_rng(7)
    position, orientation, pose = _tasks()
    posture = PostureTask(model, cost=0.05)
    posture.set_target(model.key_qpos[0])
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    solver = qpik.IKSolver(model, [[pose], [position, orientation], [posture]], limits)
    plan = solver._plan
    assert plan is not None and not plan.rows_tasks and len(plan.frames) == 3
    gathered: list = []
    gather = plan.gather
    plan.gather = lambda *args: gathered.append(1) or gather(*args)  # type: ignore[method-assign]
    for k in range(12):
        configuration.update(model.key_qpos[0] + rng.uniform(-0.4, 0.4, model.nq))
        _random_targets(rng, configuration, [position, orientation, pose])
        result = solver.step(configuration, DT)
        reference = solver.qp_solution(configuration, DT)
        np.testing.assert_array_equal(result.velocity, reference.velocity)
        assert result.status == reference.status
        if k > 0:
            assert not gathered[1:], "the lean step gathered the targets in Python"


def test_a_target_not_set_is_reported(panda):
    model, configuration = panda
    solver = qpik.IKSolver(model, [[OrientationTask("ee", "site")]], [])
    with pytest.raises(TargetNotSet):
        solver.step(configuration, DT)


def _attribute_cases():
    frame = (mink.FrameTask, FrameTask)
    return [
        (PositionTask, "cost", np.ones(6)),
        (OrientationTask, "target", np.eye(4)),
        (PoseTask, "gain", "x"),
        (PoseTask, "cost", np.ones(3)),
        *((cls, "cost", np.ones(3)) for cls in frame),
        *((cls, "gain", "x") for cls in frame),
    ]


@pytest.mark.parametrize(("cls", "name", "value"), _attribute_cases())
def test_an_attribute_set_to_what_does_not_fit_is_a_typed_error(panda, cls, name, value):
    """A task's cost, gain or target set directly (not by its setters) to what does not fit
    its rows: TaskDefinitionError naming the task, on the compiled step and on the QP path
    (not NumPy's ValueError from inside the plan)."""
    model, configuration = panda
    configuration.update(model.key_qpos[0])
    if cls in (mink.FrameTask, FrameTask):
        task = cls("ee", "site", position_cost=1.0, orientation_cost=1.0)
        task.set_target(mink.SE3.from_translation(np.array([0.3, 0.0, 0.5])))
    else:
        task = cls("ee", "site")
        _random_targets(np.random.default_rng(0), configuration, [task])
    posture = PostureTask(model, cost=0.1)
    posture.set_target(model.key_qpos[0])
    solver = qpik.IKSolver(model, [[task], [posture]], [mink.ConfigurationLimit(model)])
    solver.step(configuration, DT)
    setattr(task, name, value)
    with pytest.raises(TaskDefinitionError, match=type(task).__name__):
        solver.step(configuration, DT)
    with pytest.raises(TaskDefinitionError, match=type(task).__name__):
        solver.qp_solution(configuration, DT)
