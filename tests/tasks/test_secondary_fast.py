"""The secondary tasks' rows each step: JointLimitDistanceTask keeps its limits' mid-ranges
while the limits stay the same (the values of qpik.analysis' public functions, bit for bit,
and the new limits once a model's ranges change in place); the manipulability gradient
uses a scratch MjData kept per model, so its answer does not depend on what ran before and
the caller's data is not touched."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import load_or_skip

import qpik
from qpik.analysis import joint_limit_distance, joint_limit_distance_gradient
from qpik.model.gradients import manipulability_gradient
from qpik.tasks import JointLimitDistanceTask


def _reference(task, configuration):
    qpos, dofs = task._indices(configuration)
    args = (configuration.q[qpos], configuration.lower[qpos], configuration.upper[qpos])
    jacobian = np.zeros((1, configuration.model.nv))
    jacobian[0, dofs] = joint_limit_distance_gradient(*args)
    return np.array([joint_limit_distance(*args)]), jacobian


@pytest.mark.parametrize("name", ["panda", "erd:talos"])
def test_joint_limit_distance_rows_are_the_public_functions_bits(name):
    """The Panda's 7 joints and Talos' 32 (np.sum groups 8 terms and more in pairs: the
    zeros of unlimited joints kept in place)."""
    model = load_or_skip(name)
    rng = np.random.default_rng(3)
    task = JointLimitDistanceTask(cost=2.0, gain=0.4)
    bounds = qpik.Configuration(model)
    for _ in range(30):
        q = np.clip(model.qpos0 + rng.uniform(-1.0, 1.0, model.nq), bounds.lower, bounds.upper)
        configuration = qpik.Configuration(model, q)
        error, jacobian = _reference(task, configuration)
        np.testing.assert_array_equal(task.compute_error(configuration), error)
        np.testing.assert_array_equal(task.compute_jacobian(configuration), jacobian)
        A, b, _ = task.compute_qp_residual(configuration)
        np.testing.assert_array_equal(A, 2.0 * jacobian)
        np.testing.assert_array_equal(b, 2.0 * (-0.4 * error))


def test_joint_limit_distance_follows_limits_changed_in_place():
    model = qpik.load_robot("panda")
    task = JointLimitDistanceTask()
    configuration = qpik.Configuration(model, model.qpos0)
    before = task.compute_error(configuration).copy()
    model.jnt_range[0] = [-0.5, 0.1]  # joint 1's range, halved and shifted
    configuration = qpik.Configuration(model, model.qpos0)
    error, jacobian = _reference(task, configuration)
    np.testing.assert_array_equal(task.compute_error(configuration), error)
    np.testing.assert_array_equal(task.compute_jacobian(configuration), jacobian)
    assert error[0] != before[0]


def test_manipulability_gradient_does_not_depend_on_what_ran_before():
    model = qpik.load_robot("panda")
    rng = np.random.default_rng(4)
    a = qpik.Configuration(model, model.qpos0 + rng.uniform(-1.0, 1.0, model.nq))
    b = qpik.Configuration(model, model.qpos0 + rng.uniform(-1.0, 1.0, model.nq))
    qvel_before = a.data.qvel.copy()
    first = manipulability_gradient(a, "ee", "site")
    manipulability_gradient(b, "ee", "site", rows="position")
    np.testing.assert_array_equal(manipulability_gradient(a, "ee", "site"), first)
    np.testing.assert_array_equal(a.data.qvel, qvel_before)
    # central differences of the manipulability along each joint
    from qpik.analysis import manipulability

    h, numeric = 1e-6, np.zeros(model.nv)
    for k in range(model.nv):
        values = []
        for sign in (1.0, -1.0):
            q = a.q.copy()
            q[k] += sign * h
            probe = qpik.Configuration(model, q)
            values.append(manipulability(probe.frame_jacobian("ee", "site")))
        numeric[k] = (values[0] - values[1]) / (2 * h)
    np.testing.assert_allclose(first, numeric, rtol=1e-6, atol=1e-8)


def test_manipulability_task_rows_are_its_error_and_jacobian():
    """compute_qp_residual (one frame Jacobian) against compute_error / compute_jacobian
    (each its own), bit for bit, for each row choice."""
    from qpik.tasks import ManipulabilityTask

    model = qpik.load_robot("panda")
    rng = np.random.default_rng(9)
    for rows in ("pose", "position", "orientation"):
        task = ManipulabilityTask("ee", "site", rows=rows, cost=0.5, gain=0.3)
        for _ in range(5):
            configuration = qpik.Configuration(model, model.qpos0 + rng.uniform(-1, 1, model.nq))
            A, b, _ = task.compute_qp_residual(configuration)
            np.testing.assert_array_equal(A, 0.5 * task.compute_jacobian(configuration))
            np.testing.assert_array_equal(b, 0.5 * (-0.3 * task.compute_error(configuration)))
