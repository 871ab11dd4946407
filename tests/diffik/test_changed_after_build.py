"""Tasks and limits changed after the solver was built (found by the fuzz campaign's
``mutate`` category, benchmarks/fuzz.py): the solver that stepped before answers as a new
solver built from the changed objects does (bit for bit where its plan is made again), and
what does not fit is the same typed error on every path and at the build."""

from __future__ import annotations

import mink
import mujoco
import numpy as np
import pytest
from conftest import FLOATING

import qpik
from qpik.errors import (
    InfeasibleLimits,
    InvalidInput,
    LimitDefinitionError,
    TaskDefinitionError,
    UnknownFrameType,
)

DT = 0.01


def _refused_on_every_path(error, match: str, solver, configuration, fresh) -> None:
    """``error`` (its message naming ``match``) from ``solver``'s step, from its QP path and
    from the step of ``fresh()``, a solver built after the change."""
    calls = (
        lambda: solver.step(configuration, DT),
        lambda: solver.qp_solution(configuration, DT),
        lambda: fresh().step(configuration, DT),
    )
    for call in calls:
        with pytest.raises(error, match=match):
            call()


def _panda(limits_of=None):
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    p = configuration.frame_pose("ee", "site")[0]
    frame.set_target(mink.SE3.from_translation(p + 0.05))
    posture = qpik.tasks.PostureTask(model, cost=0.1)
    posture.set_target(model.key_qpos[0])
    position = mink.ConfigurationLimit(model)
    velocity = mink.VelocityLimit(model, {model.joint(j).name: 2.0 for j in range(model.njnt)})
    return model, configuration, [[frame], [posture]], [position, velocity]


def _floating():
    model = mujoco.MjModel.from_xml_string(FLOATING)
    configuration = qpik.Configuration(model, model.qpos0)
    task = qpik.tasks.PositionTask("ee", "site")
    task.set_target(configuration.frame_pose("ee", "site")[0] + 0.05)
    return model, configuration, [[task]], [mink.ConfigurationLimit(model)]


@pytest.mark.parametrize("robot", [_panda, _floating])
@pytest.mark.parametrize(
    ("which", "name", "value"),
    [
        ("position", "gain", -1.0),
        ("position", "gain", 1.5),
        ("position", "gain", float("nan")),
        ("position", "gain", np.ones(2)),
        ("position", "lower", "flip"),
        ("velocity", "limit", "negative"),
        ("velocity", "limit", "nan"),
    ],
)
def test_limit_values_out_of_range_are_refused_everywhere(robot, which, name, value):
    """A position limit's gain outside (0, 1] (mink's own range, checked when the limit is
    built), a velocity limit's speed below 0 or NaN, set after the build:
    LimitDefinitionError from the solver that stepped, from its QP path and from a new
    solver; bounds that leave a joint no range: InfeasibleLimits from each (before: taken as they were, a step past the limits, or NumPy's
    TypeError at the build); on a floating robot too, where mink's rows (not boxes) carry
    the position limit."""
    model, configuration, levels, limits = robot()
    if which == "velocity" and len(limits) < 2:
        pytest.skip("no velocity limit on this robot")
    solver = qpik.IKSolver(model, levels, limits)
    solver.step(configuration, DT)
    limit = limits[0] if which == "position" else limits[1]
    if isinstance(value, str):
        current = np.array(getattr(limit, name), dtype=float)
        if value == "flip":
            adr = model.jnt_qposadr[model.dof_jntid[limit.indices[0]]]
            current[adr] = limit.upper[adr] + 1.0
        else:
            current[0] = -1.0 if value == "negative" else np.nan
        value = current
    error = InfeasibleLimits if name == "lower" else LimitDefinitionError  # (an empty range)
    setattr(limit, name, value)
    _refused_on_every_path(
        error,
        type(limit).__name__,
        solver,
        configuration,
        lambda: qpik.IKSolver(model, levels, limits),
    )


def test_a_cost_of_the_wrong_shape_is_refused_on_every_path():
    """A task cost assigned as one number where the task keeps an array (mink's cost is
    per row): TaskDefinitionError on the solver that stepped (its gathered step broadcast
    it before) and on a new solver, as on the kernel's lane."""
    model, configuration, levels, limits = _panda()
    posture = levels[1][0]
    solver = qpik.IKSolver(model, levels, limits)
    solver.step(configuration, DT)
    posture.cost = 0.5
    with pytest.raises(TaskDefinitionError, match="PostureTask"):
        solver.step(configuration, DT)
    with pytest.raises(TaskDefinitionError, match="PostureTask"):
        qpik.IKSolver(model, levels, limits).step(configuration, DT)


def test_rows_and_error_of_different_lengths_are_a_typed_error():
    """A task whose gain was set to an array of the wrong length (mink's DofFreezingTask:
    its error is -gain times its rows' residual) gives rows and an error of different
    lengths: TaskDefinitionError naming it, not NumPy's broadcast error from the core."""
    model, configuration, levels, limits = _panda()
    freeze = mink.DofFreezingTask(model, dof_indices=[model.nv - 1])
    freeze.gain = np.ones(5)
    solver = qpik.IKSolver(model, [[*levels[0], freeze], levels[1]], limits, solver="osqp")
    with pytest.raises(TaskDefinitionError, match="DofFreezingTask"):
        solver.step(configuration, DT)


def test_manipulability_task_frame_type_and_rows_are_checked_when_set():
    """ManipulabilityTask.frame_type and .rows set after the build: parsed and checked as
    the constructor's (before: an AttributeError at the step, and rows that kept the old
    row index); a valid new value is the one the step uses."""
    task = qpik.tasks.ManipulabilityTask("ee", "site", rows="pose")
    with pytest.raises(UnknownFrameType):
        task.frame_type = "nope"
    with pytest.raises(InvalidInput):
        task.rows = "bogus"
    task.frame_type = "site"
    task.rows = "position"
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    fresh = qpik.tasks.ManipulabilityTask("ee", "site", rows="position")
    np.testing.assert_array_equal(
        task.compute_error(configuration), fresh.compute_error(configuration)
    )
    np.testing.assert_array_equal(
        task.compute_jacobian(configuration), fresh.compute_jacobian(configuration)
    )


@pytest.mark.parametrize(
    ("make", "name", "value"),
    [
        (lambda: qpik.tasks.PositionTask("ee", "site"), "target", 0.5),
        (lambda: qpik.tasks.OrientationTask("ee", "site"), "target", 1.0),
        (lambda: qpik.tasks.OrientationTask("ee", "site"), "target", np.ones(9)),
        (lambda: qpik.tasks.PoseTask("ee", "site"), "target_rotation", 1.0),
        (lambda: qpik.tasks.PoseTask("ee", "site"), "target_position", np.zeros(2)),
    ],
)
def test_a_target_of_the_wrong_shape_is_refused_on_every_path(make, name, value):
    """A world-frame target assigned directly as a number (or of the wrong shape) where the
    task keeps a vector or matrix: TaskDefinitionError naming the task on the lane, the QP
    path and a new solver (before: an AttributeError from the QP path, and a number
    broadcast into every entry on the gathered step)."""
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    task = make()
    task.set_target_from_configuration(configuration)
    limits = [mink.ConfigurationLimit(model)]
    solver = qpik.IKSolver(model, [[task]], limits)
    solver.step(configuration, DT)
    setattr(task, name, value)
    _refused_on_every_path(
        TaskDefinitionError, type(task).__name__, solver, configuration,
        lambda: qpik.IKSolver(model, [[task]], limits),
    )  # fmt: skip
