"""A task's target, cost, gain or LM damping assigned directly (not by its setters) to what
does not fit its rows: TaskDefinitionError naming the task, on the compiled step (the lean
step declines such a value and the gathered step reports it) and on the QP path, never
NumPy's ValueError from inside the plan. Frame and pose tasks are checked in
tests/tasks/test_pose_compiled.py; these are the CoM, posture, damping and relative-frame
tasks (qpik's and mink's)."""

from __future__ import annotations

import mink
import numpy as np
import pytest

import qpik
from qpik.errors import TaskDefinitionError
from qpik.tasks import ComTask, DampingTask, PostureTask, RelativeFrameTask

DT = 0.01


def _com(model, configuration, cls):
    task = cls(cost=1.0)
    task.set_target(configuration.data.subtree_com[1] + 0.01)
    return task


def _posture(model, configuration, cls):
    task = cls(model, cost=0.1)
    task.set_target(configuration.q)
    return task


def _relative(model, configuration, cls):
    task = cls("ee", "site", "link0", "body", position_cost=1.0, orientation_cost=1.0)
    task.set_target(mink.SE3.from_translation(np.array([0.3, 0.0, 0.5])))
    return task


CASES = [
    (_com, ComTask, "target_com", np.zeros(5)),
    (_com, ComTask, "target_com", "abc"),
    (_com, ComTask, "cost", np.ones(5)),
    (_com, ComTask, "gain", "x"),
    (_com, mink.ComTask, "target_com", np.zeros(5)),
    (_com, mink.ComTask, "lm_damping", [1.0, 2.0]),
    (_posture, PostureTask, "target_q", np.zeros(5)),
    (_posture, PostureTask, "cost", np.ones(5)),
    (_posture, PostureTask, "gain", [1.0, 2.0]),
    (_posture, mink.PostureTask, "target_q", np.zeros(5)),
    (_posture, DampingTask, "cost", np.ones(5)),
    (_posture, DampingTask, "lm_damping", "x"),
    (_relative, RelativeFrameTask, "cost", np.ones(3)),
    (_relative, mink.RelativeFrameTask, "gain", "x"),
]


@pytest.mark.parametrize(("make", "cls", "name", "value"), CASES)
def test_an_attribute_that_does_not_fit_is_a_typed_error(make, cls, name, value):
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    task = make(model, configuration, cls)
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    frame.set_target_from_configuration(configuration)
    solver = qpik.IKSolver(model, [[frame], [task]], [mink.ConfigurationLimit(model)])
    solver.step(configuration, DT)
    solver.step(configuration, DT)  # (the lean step's lane, where it applies)
    setattr(task, name, value)
    with pytest.raises(TaskDefinitionError, match=cls.__name__):
        solver.step(configuration, DT)
    with pytest.raises(TaskDefinitionError, match=cls.__name__):
        solver.qp_solution(configuration, DT)
