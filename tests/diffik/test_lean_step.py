"""The lean compiled step (qpik.diffik.compiled.CompiledPlan._lean): the tasks' values
written by the kernel, answers in rows of output arrays. Its answers are bitwise those of
the general compiled step (values written by gather), and the QP path's to round-off;
values it does not take as they are (a list, a float32 gain) go the general way with
NumPy's conversions; a result is never overwritten by later steps."""

from __future__ import annotations

import mink
import numpy as np
import pytest

import qpik
from qpik.diffik import compiled
from qpik.limits import velocity_limit_from_model

DT = 0.01


@pytest.fixture(scope="module")
def panda():
    model = qpik.load_robot("erd:panda")  # a finger mimic: a coupling level, linear
    return model, qpik.Configuration(model)


def _stack(model):
    frame = qpik.tasks.FrameTask("panda_hand_tcp", "body", position_cost=1.0, orientation_cost=0.5)
    posture = qpik.tasks.PostureTask(model, 0.1)
    damping = mink.DampingTask(model, cost=0.05)
    return frame, posture, [[frame], [posture, damping]]


def _targets(rng, configuration, frame, posture):
    q = configuration.mid_q() + rng.uniform(-0.5, 0.5, configuration.model.nq)
    configuration.update(np.clip(q, configuration.lower, configuration.upper))
    p, R = configuration.frame_pose("panda_hand_tcp", "body")
    frame.set_target(
        mink.SE3.from_rotation_and_translation(
            mink.SO3.from_matrix(R), p + rng.normal(size=3) * 0.2
        )
    )
    posture.set_target(np.clip(q + 0.3, configuration.lower, configuration.upper))


def test_lean_step_equals_general_and_qp_paths_and_keeps_its_results(panda):
    """Bitwise: the lean step and the general compiled step (its values written by gather);
    the QP path to round-off (the kernel's coupling fast path); every result keeps its
    numbers after more steps than an output array has rows."""
    model, configuration = panda
    frame, posture, levels = _stack(model)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    lean = qpik.IKSolver(model, levels, limits)
    general = qpik.IKSolver(model, levels, limits)
    assert lean._plan is not None and not lean._plan.general_limits
    general._plan._lean = lambda *args: -2  # the values not loaded: the general way
    rng = np.random.default_rng(3)
    kept = []
    deferred = 0
    for _ in range(compiled.OUTPUT_ROWS + 6):
        _targets(rng, configuration, frame, posture)
        a = lean.step(configuration, DT)
        b = general.step(configuration, DT)
        qp = qpik.StepResult.of(lean._qp_step(configuration, DT), 0.0, True)
        assert np.array_equal(a.velocity, b.velocity)
        assert np.array_equal(a.displacement, b.displacement)
        assert a.residuals == b.residuals and a.status == b.status
        assert a.coupling_residual == b.coupling_residual
        # The lean step leaves the sigma of a level proved full rank without damping to the
        # result (NaN in its row, its rows kept); the general step computes every one: the
        # same bits once resolved.
        plan = lean._plan
        deferred += int(np.isnan(plan._out[2][plan._row - 1][1]).sum())
        assert np.array(a.sigma_min).tobytes() == np.array(b.sigma_min).tobytes()
        assert np.array(a.damping).tobytes() == np.array(b.damping).tobytes()
        # The QP path solves the finger mimic's level with the others; the kernel by its
        # fast path (tests/diffik/test_couple_fastpath.py): equal to round-off. (Seed 3's
        # steps 35, 38 and 46, a finger on its limit with the arm on a vertex, found the
        # core's pinned-row defect: tests/data/exactness/hqp_pinned_finger.npz.)
        assert a.status == qp.status
        assert np.abs(a.displacement - qp.displacement).max() <= 1e-14
        np.testing.assert_allclose(a.residuals, qp.residuals, rtol=0, atol=1e-12)
        assert abs(a.coupling_residual - qp.coupling_residual) <= 1e-14
        assert a.active_limits == qp.active_limits
        kept.append((a, a.velocity.copy(), a.displacement.copy(), list(a.residuals)))
    for result, v, d, residuals in kept:
        assert np.array_equal(result.velocity, v) and np.array_equal(result.displacement, d)
        assert result.residuals == residuals
    assert deferred > 0


def test_values_the_kernel_does_not_take_go_the_general_way(panda):
    """A cost given as a list, a float32 gain or lm_damping, a boolean gain: written by
    NumPy's conversions (gather), the answer that of the same values as float64."""
    model, configuration = panda
    rng = np.random.default_rng(11)
    frame, posture, levels = _stack(model)
    solver = qpik.IKSolver(model, levels, [mink.ConfigurationLimit(model)])
    _targets(rng, configuration, frame, posture)
    reference = solver.step(configuration, DT)
    for change, undo in [
        (lambda: setattr(frame, "cost", list(frame.cost)), lambda c: setattr(frame, "cost", c)),
        (lambda: setattr(frame, "gain", np.float32(1.0)), lambda c: setattr(frame, "gain", c)),
        (lambda: setattr(posture, "lm_damping", np.float32(0.0)),
         lambda c: setattr(posture, "lm_damping", c)),
        (lambda: setattr(posture, "gain", True), lambda c: setattr(posture, "gain", c)),
    ]:  # fmt: skip
        saved = (frame.cost, frame.gain, posture.lm_damping, posture.gain)
        change()
        result = solver.step(configuration, DT)
        assert np.array_equal(result.velocity, reference.velocity)
        frame.cost, frame.gain, posture.lm_damping, posture.gain = saved
        del undo
    # a value of the wrong length is NumPy's to judge (it raises, as the general path does)
    frame.cost = np.ones(5)
    with pytest.raises(ValueError):
        solver.step(configuration, DT)
    frame.cost = np.ones(6)


def test_a_gain_changed_between_paths_is_written(panda):
    """A position limit's gain changed while steps alternate between the lean and the
    general way is the one used: the answer equals a fresh solver's."""
    model, configuration = panda
    rng = np.random.default_rng(2)
    frame, posture, levels = _stack(model)
    limit = mink.ConfigurationLimit(model, gain=0.95)
    solver = qpik.IKSolver(model, levels, [limit])
    _targets(rng, configuration, frame, posture)
    for gain, cost in [(0.5, np.ones(6)), (0.95, [1.0] * 6), (0.95, np.ones(6)), (0.3, [1.0] * 6)]:
        limit.gain = gain
        frame.cost = cost
        ours = solver.step(configuration, DT)
        fresh = qpik.IKSolver(model, levels, [limit]).step(configuration, DT)
        assert np.array_equal(ours.velocity, fresh.velocity)
    frame.cost = np.ones(6)


@pytest.mark.parametrize("robot", ["erd:talos", "ur5e", "panda"])
def test_kernel_frame_jacobians_are_mujocos(robot):
    """The frame Jacobians the lean step computes (Kernel.set_chains) are bitwise MuJoCo's
    mj_jacSite / mj_jacBody / mj_jacGeom, on sites, bodies and geoms of every depth (a
    floating base, a body welded to its parent, the world body)."""
    model = qpik.load_robot(robot)
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(7)
    kinds = [("body", model.nbody), ("site", model.nsite), ("geom", model.ngeom)]
    frames = [
        (kind, int(i))
        for kind, count in kinds
        for i in np.unique(np.linspace(0, count - 1, 6).astype(int))
        if count
    ]
    tasks = [qpik.tasks.FrameTask(fid, kind, 1.0, 1.0) for kind, fid in frames]
    solver = qpik.IKSolver(model, [tasks], [mink.ConfigurationLimit(model)])
    plan = solver._plan
    assert plan is not None and not plan.general_limits
    plan.gather = lambda *args: pytest.fail("the lean step only")
    for _ in range(5):
        q = configuration.random_q(rng)
        configuration.update(q)
        for task in tasks:
            task.set_target_from_configuration(configuration)
        solver.step(configuration, DT)
        for f, (kind, fid) in enumerate(frames):
            expected = configuration.frame_jacobian(fid, kind)
            assert np.array_equal(plan.arrays["jac"][f], expected), (kind, fid)


@pytest.mark.parametrize("robot", ["erd:talos", "panda"])
def test_kernel_relative_frame_jacobians_are_mujocos(robot):
    """The relative-frame tasks' Jacobians the lean step computes (Kernel.set_rel_chains)
    are bitwise MuJoCo's, for the task's frame and its root frame alike; the step takes the
    plain lane (no Python Jacobian calls) and equals a fresh solver's."""
    model = qpik.load_robot(robot)
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(8)
    last, mid = model.body(model.nbody - 1).name, model.body(model.nbody // 2).name
    pairs = [((last, "body"), (mid, "body")), ((mid, "body"), (model.body(0).name, "body"))]
    if model.nsite:
        pairs.append(((model.site(model.nsite - 1).name, "site"), (mid, "body")))
    tasks = [
        qpik.tasks.RelativeFrameTask(f, fk, r, rk, position_cost=1.0, orientation_cost=0.5)
        for (f, fk), (r, rk) in pairs
    ]
    levels = [tasks, [qpik.tasks.PostureTask(model, 0.1)]]
    solver = qpik.IKSolver(model, levels, [mink.ConfigurationLimit(model)])
    plan = solver._plan
    assert plan is not None and plan._plain and not plan.general_limits
    plan.gather = lambda *args: pytest.fail("the lean step only")
    for _ in range(4):
        configuration.update(configuration.random_q(rng))
        for task in tasks:
            task.set_target_from_configuration(configuration)
        levels[1][0].set_target(configuration.random_q(rng))
        step = solver.step(configuration, DT)
        assert configuration.data is plan._plain_data  # the plain lane
        for r, task in enumerate(tasks):
            frame = configuration.frame_jacobian(task.frame_name, task.frame_type)
            root = configuration.frame_jacobian(task.root_name, task.root_type)
            assert np.array_equal(plan.arrays["rel_jac"][r, :6], frame)
            assert np.array_equal(plan.arrays["rel_jac"][r, 6:], root)
        fresh = qpik.IKSolver(model, levels, [mink.ConfigurationLimit(model)])
        fresh._plan.gather = plan.gather
        assert np.array_equal(fresh.step(configuration, DT).velocity, step.velocity)
