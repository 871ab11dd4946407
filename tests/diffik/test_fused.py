"""The one-call IK step (:mod:`qpik.diffik.compiled`) against the general path and against mink."""

from __future__ import annotations

import mink
import numpy as np
import pytest

import qpik
from qpik.limits import velocity_limit_from_model
from qpik.model import lie as _lie
from qpik.tasks import FrameTask, PostureTask

DT = 0.01


def _qp_step(solver: qpik.IKSolver, configuration) -> qpik.StepResult:
    """The step by the QP path (the tasks' and limits' own rows, then the core's cascade)."""
    return qpik.StepResult.of(solver._qp_step(configuration, DT), 0.0)


try:
    from mink.lie import _lie_ops_c as native
except ImportError:  # pragma: no cover - older mink
    native = None


@pytest.fixture(scope="module")
def panda():
    model = qpik.load_robot("panda")
    return model, qpik.Configuration(model)


def _same(a: qpik.StepResult, b: qpik.StepResult, iterations: bool = True) -> bool:
    """Bitwise the same step (``iterations=False``: a backend's warm-started workspace
    may count differently, which only ever changes speed)."""
    return (
        np.array_equal(a.displacement, b.displacement)
        and a.residuals == b.residuals
        and a.sigma_min == b.sigma_min
        and a.damping == b.damping
        and a.status == b.status
        and (a.iterations == b.iterations or not iterations)
        and a.active_limits == b.active_limits
    )


def _random_pose(rng, configuration, frame, kind, reach):
    position, rotation = configuration.frame_pose(frame, kind)
    turn = mink.SO3.exp(rng.normal(size=3) * reach)
    return mink.SE3.from_rotation_and_translation(
        turn @ mink.SO3.from_matrix(rotation), position + rng.uniform(-1, 1, 3) * reach
    )


@pytest.mark.skipif(native is None, reason="mink without compiled Lie routines")
def test_lie_port_equals_minks_compiled_routines():
    rng = np.random.default_rng(3)
    for k in range(2000):
        scale = (1e-9, 1e-5, 1e-2, 1.0, 3.0)[k % 5]
        target = mink.SE3.from_rotation_and_translation(
            mink.SO3.exp(rng.normal(size=3) * scale), rng.normal(size=3)
        ).wxyz_xyz
        xmat = mink.SO3.exp(rng.normal(size=3) * scale).as_matrix().ravel()
        xpos = rng.normal(size=3)
        frame = np.empty(7)
        _lie.xmat_xpos_to_wxyz_xyz(frame, xmat, xpos)
        np.testing.assert_allclose(frame, native.xmat_xpos_to_wxyz_xyz(xmat, xpos), 0, 1e-12)
        error = np.empty(6)
        _lie.se3_rminus(error, target, frame)
        np.testing.assert_allclose(error, native.se3_rminus(target, frame), 0, 1e-12)
        relative = np.empty(7)
        _lie.se3_inverse_multiply(relative, target, frame)
        jlog = np.empty((6, 6))
        _lie.se3_jlog(jlog, relative)
        expected = native.se3_jlog(native.se3_inverse_multiply(target, frame))
        np.testing.assert_allclose(jlog, expected, 0, 1e-12)


def test_fused_step_equals_the_general_path_bitwise(panda):
    """Frames with position and orientation costs, postures at two levels, a level of two
    tasks, gains and LM terms, costs changed between steps, limits binding or not."""
    model, configuration = panda
    rng = np.random.default_rng(7)
    frame = FrameTask("ee", "site", position_cost=1.0, orientation_cost=0.3, lm_damping=0.1)
    body = FrameTask("link5", "body", position_cost=0.5, orientation_cost=0.0, gain=0.5)
    posture = PostureTask(model, 0.1)
    soft = PostureTask(model, 1e-3, gain=0.3, lm_damping=1.0)
    limits = [mink.ConfigurationLimit(model, gain=0.9), velocity_limit_from_model(model)]
    solver = qpik.IKSolver(model, [[frame], [body, soft], [posture]], limits)
    assert solver._plan is not None
    home = model.key_qpos[0]
    for i in range(300):
        q = np.clip(
            home + rng.uniform(-0.8, 0.8, model.nv), configuration.lower, configuration.upper
        )
        configuration.update(q)
        reach = (0.002, 0.3)[i % 2]
        frame.set_target(_random_pose(rng, configuration, "ee", "site", reach))
        body.set_target(_random_pose(rng, configuration, "link5", "body", reach))
        posture.set_target(
            np.clip(q + rng.uniform(-1.5, 1.5, model.nv), configuration.lower, configuration.upper)
        )
        soft.set_target(configuration.mid_q())
        frame.set_orientation_cost(rng.uniform(0.0, 1.0))
        fused = solver.step(configuration, DT)
        general = _qp_step(solver, configuration)
        assert _same(fused, general), i


def test_fused_step_matches_mink_on_a_flat_level(panda):
    model, configuration = panda
    rng = np.random.default_rng(11)
    ours = [FrameTask("ee", "site", 1.0, 0.5), PostureTask(model, 0.05)]
    theirs = [mink.FrameTask("ee", "site", 1.0, 0.5), mink.PostureTask(model, 0.05)]
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    solver = qpik.IKSolver(model, ours, limits, damping_law=None)
    assert solver._plan is not None
    home = model.key_qpos[0]
    for _ in range(50):
        q = np.clip(
            home + rng.uniform(-0.5, 0.5, model.nv), configuration.lower, configuration.upper
        )
        configuration.update(q)
        target = _random_pose(rng, configuration, "ee", "site", 0.2)
        for task in (ours[0], theirs[0]):
            task.set_target(target)
        for task in (ours[1], theirs[1]):
            task.set_target(home)
        expected = mink.solve_ik(configuration, theirs, DT, "daqp", damping=1e-6, limits=limits)
        np.testing.assert_allclose(solver.step(configuration, DT).velocity, expected, 0, 1e-7)


def test_fused_answers_do_not_depend_on_history(panda):
    model, configuration = panda
    rng = np.random.default_rng(5)
    frame, posture = FrameTask("ee", "site", 1.0, 1.0), PostureTask(model, 0.1)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    solver = qpik.IKSolver(model, [[frame], [posture]], limits)
    home = model.key_qpos[0]
    configuration.update(home)
    frame.set_target(_random_pose(rng, configuration, "ee", "site", 0.3))
    posture.set_target(configuration.mid_q())
    first = solver.step(configuration, DT)
    saved = frame.transform_target_to_world
    for _ in range(20):  # other problems on the same solver
        configuration.update(
            np.clip(home + rng.uniform(-1, 1, model.nv), configuration.lower, configuration.upper)
        )
        frame.set_target(_random_pose(rng, configuration, "ee", "site", 0.5))
        solver.step(configuration, DT)
    configuration.update(home)
    frame.set_target(saved)
    again = solver.step(configuration, DT)
    fresh = qpik.IKSolver(model, [[frame], [posture]], limits).step(configuration, DT)
    assert _same(first, again) and _same(first, fresh)


def test_subclasses_supply_their_own_rows_to_the_fused_step(panda):
    model, _ = panda
    posture = PostureTask(model, 0.1)
    # mink's own FrameTask is computed in C++ too (tests/diffik/test_fastpath.py); a subclass
    # may change its rows, so it supplies them itself (its own methods, each step).
    assert qpik.IKSolver(model, [mink.FrameTask("ee", "site", 1.0, 1.0)])._plan is not None

    class MinkCustom(mink.FrameTask):
        pass

    plan = qpik.IKSolver(model, [MinkCustom("ee", "site", 1.0, 1.0)])._plan
    assert plan is not None and not plan.frames and len(plan.rows_tasks) == 1
    assert qpik.IKSolver(model, [posture], [mink.ConfigurationLimit(model)])._plan is not None

    class Custom(FrameTask):
        pass

    plan = qpik.IKSolver(model, [Custom("ee", "site", 1.0, 1.0)])._plan
    assert plan is not None and not plan.frames and len(plan.rows_tasks) == 1


def test_fused_step_reports_unset_and_non_finite_targets(panda):
    model, configuration = panda
    configuration.update(model.key_qpos[0])
    frame, posture = FrameTask("ee", "site", 1.0, 1.0), PostureTask(model, 0.1)
    solver = qpik.IKSolver(model, [[frame], [posture]], [mink.ConfigurationLimit(model)])
    posture.set_target(model.key_qpos[0])
    with pytest.raises(qpik.TargetNotSet):
        solver.step(configuration, DT)
    frame.set_target(mink.SE3.from_translation(np.array([np.nan, 0.0, 0.5])))
    with pytest.raises(qpik.InvalidTarget):
        solver.step(configuration, DT)
    frame.set_target(mink.SE3.from_translation(np.array([0.3, 0.0, 0.5])))
    assert solver.step(configuration, DT).ok  # still usable


def test_rows_whose_sum_overflows_go_to_the_qp_path(panda):
    """Every entry of A finite but their sum past the largest float (posture costs 1e308
    on a zero error): the kernel reports the rows not finite and the QP path answers, as
    when it summed them all; costs just below that bound stay in the kernel."""
    model, configuration = panda
    configuration.update(model.key_qpos[0])
    frame, posture = FrameTask("ee", "site", 1.0, 1.0), PostureTask(model, 1e308)
    solver = qpik.IKSolver(model, [[frame], [posture]], [mink.ConfigurationLimit(model)])
    frame.set_target(mink.SE3.from_translation(np.array([0.3, 0.0, 0.5])))
    posture.set_target(model.key_qpos[0])
    plan, core = solver._plan, solver._core
    assert plan is not None
    assert plan._solve(configuration, DT, solver.damping, core, False) is None
    posture.cost = np.full(model.nv, 1e10)
    assert plan._solve(configuration, DT, solver.damping, core, False) is not None


@pytest.mark.parametrize("backend", ["osqp", "daqp", "quadprog"])
def test_forced_backends_build_rows_in_one_call_with_the_same_answers(panda, backend):
    """With a forced backend the rows and limits come from one compiled call; the answer
    equals the general path's bitwise."""
    pytest.importorskip(backend)
    model, configuration = panda
    rng = np.random.default_rng(13)
    frame, posture = FrameTask("ee", "site", 1.0, 0.2), PostureTask(model, 0.1)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    solver = qpik.IKSolver(model, [[frame], [posture]], limits, solver=backend)
    home = model.key_qpos[0]
    for i in range(40):
        q = np.clip(
            home + rng.uniform(-0.6, 0.6, model.nv), configuration.lower, configuration.upper
        )
        configuration.update(q)
        frame.set_target(_random_pose(rng, configuration, "ee", "site", (0.001, 0.3)[i % 2]))
        posture.set_target(
            np.clip(q + rng.uniform(-1.5, 1.5, model.nv), configuration.lower, configuration.upper)
        )
        fused = solver.step(configuration, DT)
        general = _qp_step(solver, configuration)
        assert _same(fused, general, iterations=backend != "osqp"), i
