"""mink's LookAtTask's and AxisAlignTask's rows by the compiled ``look_at_residual`` and
``axis_align_residual`` (qpik.diffik.rows): equal to mink's own ``compute_qp_residual`` to
round-off for every frame type, axis, cost, gain and LM damping, the same errors where a
target, frame or attribute does not fit, a subclass's own rows kept, and the compiled step
with such a task answers as the QP path and mink do (mink's methods built the frame's
transform and Jacobian in Python, the look-at one twice: about 95 us a task; mink's look-at
examples ran at 0.6x to 1x mink's time per call, its arm_panda_engrave at 0.51x)."""

from __future__ import annotations

import mink
import numpy as np
import pytest

import qpik
from qpik.diffik.rows import _axis_align_residual, _look_at_residual, task_rows
from qpik.model.configuration import Configuration

DT = 0.01

#: per kind: its residual function and task classes (mink's and qpik's)
KINDS = {
    "look_at": (_look_at_residual, (mink.LookAtTask, qpik.tasks.LookAtTask)),
    "axis_align": (_axis_align_residual, (mink.AxisAlignTask, qpik.tasks.AxisAlignTask)),
}
CASES = [(kind, cls) for kind, (_, classes) in KINDS.items() for cls in classes]


@pytest.fixture
def panda():
    model = qpik.load_robot("panda")
    return model, qpik.Configuration(model, model.key_qpos[0])


@pytest.mark.parametrize(("kind", "cls"), CASES)
@pytest.mark.parametrize("frame", [("ee", "site"), ("link6", "body"), (3, "body")])
def test_rows_equal_minks(panda, kind, cls, frame):
    model, configuration = panda
    residual = KINDS[kind][0]
    rng = np.random.default_rng(7)
    for _ in range(20):
        configuration.update(model.key_qpos[0] + rng.uniform(-0.5, 0.5, model.nq))
        task = cls(
            *frame, axis=rng.normal(size=3), cost=rng.uniform(0.1, 3.0),
            gain=rng.uniform(0.1, 1.0), lm_damping=rng.uniform(0.0, 2.0),
        )  # fmt: skip
        task.set_target(rng.normal(size=3))
        fast = residual(task, Configuration.sharing(configuration))
        assert fast is not None
        reference = task.compute_qp_residual(configuration)
        for ours, theirs in zip(fast[:2], reference[:2], strict=True):
            np.testing.assert_allclose(
                ours, theirs, rtol=0, atol=1e-14 * (1 + np.abs(theirs).max())
            )
        assert fast[2] == pytest.approx(reference[2], rel=1e-13, abs=1e-300)
        rows, error, mu, weights = task_rows(task, Configuration.sharing(configuration))
        assert rows is fast[0] or np.array_equal(rows, fast[0])


@pytest.mark.parametrize("kind", KINDS)
def test_what_does_not_fit_raises_as_minks_method(panda, kind):
    model, configuration = panda
    residual, (cls, _) = KINDS[kind]
    own = Configuration.sharing(configuration)
    unset = cls("ee", "site")
    with pytest.raises(qpik.TargetNotSet):
        task_rows(unset, own)
    unknown = cls("nowhere", "site")
    unknown.set_target(np.array([0.0, 0.0, 1.0]))
    with pytest.raises(qpik.UnknownFrame):
        task_rows(unknown, own)
    odd = cls("ee", "site")
    odd.set_target(np.array([0.0, 0.0, 1.0]))
    odd.cost = np.ones(2)  # (set directly, past set_cost's check): mink's own method answers
    assert residual(odd, own) is None
    with pytest.raises(qpik.QpikError):
        task_rows(odd, own)

    negative = cls("ee", "site")
    negative.set_target(np.array([0.3, -0.2, 1.0]))
    negative.lm_damping = -1.0  # (set directly, past mink's check)
    with pytest.raises(qpik.TaskDefinitionError, match="LM damping"):
        task_rows(negative, own)

    class Shifted(cls):  # a subclass computes its own rows
        def compute_qp_residual(self, configuration):
            A, b, mu = super().compute_qp_residual(configuration)
            return A, b + 1.0, mu

    shifted = Shifted("ee", "site")
    shifted.set_target(np.array([0.3, 0.1, 1.0]))
    _, error, _, _ = task_rows(shifted, own)
    np.testing.assert_array_equal(error, shifted.compute_qp_residual(configuration)[1])


def test_a_look_at_target_at_the_frame_is_clamped_as_minks(panda):
    model, configuration = panda
    own = Configuration.sharing(configuration)
    origin = mink.LookAtTask("ee", "site")
    origin.set_target(configuration.frame_pose("ee")[0])
    fast = _look_at_residual(origin, own)
    reference = origin.compute_qp_residual(configuration)
    assert fast is not None and np.array_equal(np.isfinite(fast[0]), np.isfinite(reference[0]))


@pytest.mark.parametrize("kind", KINDS)
def test_the_compiled_step_answers_as_the_qp_path_and_mink(panda, kind):
    model, configuration = panda
    rng = np.random.default_rng(3)
    cls = KINDS[kind][1][0]
    frame = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=0.0, lm_damping=1e-2)
    pointing = cls("ee", "site", axis=(0.0, 0.0, 1.0), cost=1.0, lm_damping=1.0)
    posture = mink.PostureTask(model, cost=1e-2)
    posture.set_target(model.key_qpos[0])
    limits = [mink.ConfigurationLimit(model), mink.VelocityLimit(model, {"joint1": 1.0})]
    solver = qpik.IKSolver(model, [[frame, pointing], [posture]], limits)
    # (the kernel computes the pointing task's rows itself: a frame of the plan, kind 11 or 12)
    assert solver._plan is not None and not solver._plan.rows_tasks
    assert [t for t, *_ in solver._plan.frames] == [frame, pointing]
    for _ in range(10):
        configuration.update(model.key_qpos[0] + rng.uniform(-0.4, 0.4, model.nq))
        pose = configuration.get_transform_frame_to_world("ee", "site")
        frame.set_target(pose @ mink.SE3.from_translation(rng.uniform(-0.02, 0.02, 3)))
        pointing.set_target(rng.normal(size=3))
        result = solver.step(configuration, DT)
        reference = solver.qp_solution(configuration, DT)
        np.testing.assert_allclose(result.velocity, reference.velocity, rtol=0, atol=1e-10)
        tasks = [frame, pointing, posture]
        mink_answer = mink.solve_ik(configuration, tasks, DT, "daqp", 1e-3)
        ours = qpik.solve_ik(configuration, tasks, DT, "daqp", 1e-3)
        np.testing.assert_allclose(ours, mink_answer, rtol=0, atol=1e-7)
