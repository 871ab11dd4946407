"""mink's LookAtTask's rows by the compiled ``look_at_residual`` (qpik.diffik.rows): equal
to mink's own ``compute_qp_residual`` to round-off for every frame type, axis, cost, gain and
LM damping, the same errors where a target, frame or attribute does not fit, and the
compiled step with a look-at task answers as the QP path does (mink's method computed the
frame's transform and Jacobian twice, about 95 us a task: the look-at examples of mink ran
at 0.6x to 1x mink's time per call)."""

from __future__ import annotations

import mink
import numpy as np
import pytest

import qpik
from qpik.diffik.rows import _look_at_residual, task_rows
from qpik.model.configuration import Configuration

DT = 0.01


@pytest.fixture
def panda():
    model = qpik.load_robot("panda")
    return model, qpik.Configuration(model, model.key_qpos[0])


@pytest.mark.parametrize("cls", [mink.LookAtTask, qpik.tasks.LookAtTask])
@pytest.mark.parametrize("frame", [("ee", "site"), ("link6", "body"), (3, "body")])
def test_rows_equal_minks(panda, cls, frame):
    model, configuration = panda
    rng = np.random.default_rng(7)
    for _ in range(20):
        configuration.update(model.key_qpos[0] + rng.uniform(-0.5, 0.5, model.nq))
        task = cls(
            *frame, axis=rng.normal(size=3), cost=rng.uniform(0.1, 3.0),
            gain=rng.uniform(0.1, 1.0), lm_damping=rng.uniform(0.0, 2.0),
        )  # fmt: skip
        task.set_target(rng.normal(size=3))
        fast = _look_at_residual(task, Configuration.sharing(configuration))
        assert fast is not None
        reference = task.compute_qp_residual(configuration)
        for ours, theirs in zip(fast[:2], reference[:2], strict=True):
            np.testing.assert_allclose(
                ours, theirs, rtol=0, atol=1e-14 * (1 + np.abs(theirs).max())
            )
        assert fast[2] == pytest.approx(reference[2], rel=1e-13, abs=1e-300)
        rows, error, mu, weights = task_rows(task, Configuration.sharing(configuration))
        assert rows is fast[0] or np.array_equal(rows, fast[0])


def test_what_does_not_fit_raises_as_minks_method(panda):
    model, configuration = panda
    own = Configuration.sharing(configuration)
    unset = mink.LookAtTask("ee", "site")
    with pytest.raises(qpik.TargetNotSet):
        task_rows(unset, own)
    unknown = mink.LookAtTask("nowhere", "site")
    unknown.set_target(np.zeros(3))
    with pytest.raises(qpik.UnknownFrame):
        task_rows(unknown, own)
    odd = mink.LookAtTask("ee", "site")
    odd.set_target(np.zeros(3))
    odd.cost = np.ones(2)  # (set directly, past set_cost's check): mink's own method answers
    assert _look_at_residual(odd, own) is None
    with pytest.raises(qpik.QpikError):
        task_rows(odd, own)
    # the target at the frame's origin: mink's clamp of the distance, the same rows
    origin = mink.LookAtTask("ee", "site")
    origin.set_target(configuration.frame_pose("ee")[0])
    fast = _look_at_residual(origin, own)
    reference = origin.compute_qp_residual(configuration)
    assert fast is not None and np.array_equal(np.isfinite(fast[0]), np.isfinite(reference[0]))


def test_the_compiled_step_with_a_look_at_task_answers_as_the_qp_path(panda):
    model, configuration = panda
    rng = np.random.default_rng(3)
    look = mink.LookAtTask("ee", "site", axis=(0.0, 0.0, 1.0), cost=1.0, lm_damping=1.0)
    posture = mink.PostureTask(model, cost=1e-2)
    posture.set_target(model.key_qpos[0])
    limits = [mink.ConfigurationLimit(model), mink.VelocityLimit(model, {"joint1": 1.0})]
    solver = qpik.IKSolver(model, [[look], [posture]], limits)
    assert solver._plan is not None and [t for t, *_ in solver._plan.rows_tasks] == [look]
    for _ in range(10):
        look.set_target(rng.normal(size=3))
        configuration.update(model.key_qpos[0] + rng.uniform(-0.4, 0.4, model.nq))
        result = solver.step(configuration, DT)
        reference = solver.qp_solution(configuration, DT)
        np.testing.assert_allclose(result.velocity, reference.velocity, rtol=0, atol=1e-10)
        mink_answer = mink.solve_ik(configuration, [look, posture], DT, "daqp", 1e-3)
        ours = qpik.solve_ik(configuration, [look, posture], DT, "daqp", 1e-3)
        np.testing.assert_allclose(ours, mink_answer, rtol=0, atol=1e-7)
