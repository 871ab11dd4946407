"""IKSolver.step's plain lane (the lean compiled step of a plain plan, its kernel called
and its StepResult made in step's own frame): the same result as CompiledPlan.step_result's
lean step, field by field and bitwise; results kept after more steps than an output array
has rows; every change the lane does not cover (a damping law, another MjData, warm
starts, correction passes, a non-finite target, a bad argument) routed as before."""

from __future__ import annotations

import mink
import mujoco
import numpy as np
import pytest

import qpik
from qpik.diffik import compiled
from qpik.limits import velocity_limit_from_model

DT = 0.01
FIELDS = (
    "velocity", "displacement", "residuals", "sigma_min", "damping", "status", "iterations",
    "certificate", "coupling_residual", "active_limits",
)  # fmt: skip


@pytest.fixture(scope="module")
def panda():
    model = qpik.load_robot("erd:panda")  # a finger mimic: a coupling level, linear
    return model, qpik.Configuration(model)


def _solver(model, **keywords):
    frame = qpik.tasks.FrameTask("panda_hand_tcp", "body", position_cost=1.0, orientation_cost=1.0)
    posture = qpik.tasks.PostureTask(model, 0.1)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    return qpik.IKSolver(model, [[frame], [posture]], limits, **keywords), frame, posture


def _move(rng, configuration, frame, posture):
    q = configuration.mid_q() + rng.uniform(-0.6, 0.6, configuration.model.nq)
    configuration.update(np.clip(q, configuration.lower, configuration.upper))
    p, R = configuration.frame_pose("panda_hand_tcp", "body")
    frame.set_target(
        mink.SE3.from_rotation_and_translation(
            mink.SO3.from_matrix(R), p + rng.uniform(-1, 1, 3) * 0.3
        )
    )
    posture.set_target(np.clip(q + 0.2, configuration.lower, configuration.upper))


def _same(a, b):
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and np.array_equal(x, y), name
        else:
            assert x == y, name
    assert type(a.solve_time) is float and a.solve_time >= 0.0


def test_the_lane_gives_step_results_answer_and_keeps_earlier_results(panda):
    """Steps through the lane equal the same steps by CompiledPlan.step_result (the lane
    off), every field bitwise, over more steps than an output array has rows; the lane's
    result holds only its velocity, time and source until a field is read; the core's
    active sets are the step's; no result changes after later steps."""
    model, configuration = panda
    lane_solver, frame, posture = _solver(model)
    plain_solver = qpik.IKSolver(model, lane_solver.levels, lane_solver.limits)
    plain_solver._plan._update_plain_data = lambda: None  # no lane: every step by step_result
    plan = lane_solver._plan
    assert plan._plain and plain_solver._plan._plain
    rng = np.random.default_rng(5)
    _move(rng, configuration, frame, posture)
    lane_solver.step(configuration, DT)  # the first step attaches (step_result's way)
    assert plan._plain_data is configuration.data
    calls = []
    step_result = plan.step_result
    plan.step_result = lambda *args: calls.append(args) or step_result(*args)
    kept = []
    for _ in range(compiled.OUTPUT_ROWS + 8):
        _move(rng, configuration, frame, posture)
        a = lane_solver.step(configuration, DT)
        b = plain_solver.step(configuration, DT)
        assert type(a) is qpik.StepResult
        assert set(vars(a)) == {"velocity", "solve_time", "_src"}  # the rest read lazily
        row = a._src[1]
        assert np.array_equal(lane_solver._core.active_sets, plan._out[3][row])
        assert np.array_equal(a.velocity, plan._out[1][row]) and a.velocity.base is plan._out[1]
        _same(a, b)
        kept.append((a, {name: np.copy(getattr(a, name)) for name in ("velocity", "displacement")}))
    # only the step whose output rows were full went by step_result (_lean makes new ones)
    assert len(calls) == 1
    for result, arrays in kept:
        for name, value in arrays.items():
            assert np.array_equal(getattr(result, name), value)


def test_what_the_lane_does_not_cover_goes_the_way_it_went(panda):
    """A new damping law, another MjData, warm starts: the lane steps aside and the answer
    is a fresh solver's; a non-finite target raises InvalidTarget and the solver stays
    usable; bad arguments raise the same typed errors; correction passes have no lane."""
    model, configuration = panda
    rng = np.random.default_rng(9)
    solver, frame, posture = _solver(model)
    _move(rng, configuration, frame, posture)
    solver.step(configuration, DT)
    solver.step(configuration, DT)

    def fresh(configuration, **keywords):
        other = qpik.IKSolver(model, solver.levels, solver.limits, **keywords)
        return other.step(configuration, DT)

    solver.damping_law = qpik.DampingLaw(singular_threshold=0.3, max_damping=0.05)
    _same(solver.step(configuration, DT), fresh(configuration, damping_law=solver.damping_law))
    solver.damping_law = None
    _same(solver.step(configuration, DT), fresh(configuration, damping_law=None))
    other = qpik.Configuration(model)
    other.update(np.clip(configuration.q + 0.1, configuration.lower, configuration.upper))
    _same(solver.step(other, DT), fresh(other, damping_law=None))
    _same(solver.step(configuration, DT), fresh(configuration, damping_law=None))
    core, asked = solver._core, []
    core.warm_start = True
    warm_sets = core.warm_sets
    core.warm_sets = lambda *args: asked.append(args) or warm_sets(*args)
    row = solver._plan._row
    warm, cold = solver.step(configuration, DT), fresh(configuration, damping_law=None)
    assert solver._plan._row == row + 1 and len(asked) == 1  # by _lean, warm started
    assert np.array_equal(warm.velocity, cold.velocity) and warm.status == cold.status
    core.warm_start = False
    del core.warm_sets

    target = frame.transform_target_to_world
    frame.set_target(mink.SE3.from_translation(np.array([np.nan, 0.0, 0.5])))
    with pytest.raises(qpik.InvalidTarget):
        solver.step(configuration, DT)
    frame.set_target(target)
    _same(solver.step(configuration, DT), fresh(configuration, damping_law=None))

    with pytest.raises(qpik.QpikError):
        solver.step(configuration.q, DT)  # not a configuration
    for dt in (0.0, -0.01, float("nan"), 1e9, "0.01"):
        with pytest.raises(qpik.QpikError):
            solver.step(configuration, dt)
    # an int or np.float64 dt is its float's: the lane taken, the same bits (was the QP
    # path's, 2.6x mink's time where a dt came from np.diff of time stamps: h10's audit)
    for dt in (1, np.float64(DT)):
        row = solver._plan._row
        by_other = solver.step(configuration, dt)
        assert solver._plan._row == row + 1
        assert np.array_equal(by_other.velocity, solver.step(configuration, float(dt)).velocity)

    # a forced backend: its own path (CompiledPlan.step), never the lane
    forced, frame, posture = _solver(model, solver="daqp")
    _move(rng, configuration, frame, posture)
    forced._core.solver = "auto"  # one default step: the configuration attached
    forced.step(configuration, DT)
    forced._core.solver = "daqp"
    assert forced._plan._plain_data is configuration.data  # the lane's key would hold
    calls = []
    plan_step = forced._plan.step
    forced._plan.step = lambda *args: calls.append(args) or plan_step(*args)
    forced.step(configuration, DT)
    assert len(calls) == 1

    # correction passes: never the lane (it would answer the step uncorrected)
    corrected, frame, posture = _solver(model, correction_passes=1)
    uncorrected = qpik.IKSolver(model, corrected.levels, corrected.limits)
    _move(rng, configuration, frame, posture)
    p, R = configuration.frame_pose("panda_hand_tcp", "body")  # a near target: held, corrected
    frame.set_target(mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(R), p + 0.002))
    first = corrected.step(configuration, DT)
    assert corrected._plan._plain_data is configuration.data  # the lane's key would hold
    _same(corrected.step(configuration, DT), first)
    assert not np.array_equal(uncorrected.step(configuration, DT).velocity, first.velocity)


def _humanoid_solver(model, body):
    """A floating humanoid's feet / CoM (qpik's ComTask of subtree ``body``) / posture."""
    feet = [
        qpik.tasks.FrameTask(f, "body", 1.0, 1.0) for f in ("left_sole_link", "right_sole_link")
    ]
    com = qpik.tasks.ComTask(1.0, body=body)
    posture = qpik.tasks.PostureTask(model, 0.1)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    return qpik.IKSolver(model, [feet, [com], [posture]], limits), feet, com, posture


def test_com_plans_take_the_lane_and_a_changed_subtree_leaves_it():
    """A plan with a CoM task whose Jacobian the kernel makes takes the lane (the same
    results as step_result's lean step, bitwise); setting the task's subtree (ComTask.body)
    again: the kernel declines the step (the plan's guards, qpik.diffik.layout.plan_guards)
    and the QP path answers, for the new subtree (a fresh solver's answer); set back, the
    lane answers again, with the plan's bits."""
    model = qpik.load_robot("erd:talos", floating_base=True)
    configuration = qpik.Configuration(model, model.key_qpos[0])
    solver, feet, com, posture = _humanoid_solver(model, 1)
    plain_solver = qpik.IKSolver(model, solver.levels, solver.limits)
    plain_solver._plan._update_plain_data = lambda: None  # no lane: every step by step_result
    plan = solver._plan
    assert plan._plain and plan.coms
    for foot in feet:
        foot.set_target_from_configuration(configuration)
    posture.set_target(configuration.q)
    rng = np.random.default_rng(3)
    for _ in range(5):
        com.set_target(com.com(configuration) + rng.uniform(-0.03, 0.03, 3))
        _same(solver.step(configuration, DT), plain_solver.step(configuration, DT))
    assert plan._plain_data is configuration.data
    pelvis = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, 2)
    com.body = pelvis  # another subtree: the plan's CoM row no longer applies
    fresh, *_ = _humanoid_solver(model, pelvis)
    fresh_com = fresh.levels[1][0]
    fresh_com.set_target(com.target_com)
    for foot, other in zip(feet, fresh.levels[0]):
        other.set_target(foot.transform_target_to_world)
    fresh.levels[2][0].set_target(posture.target_q)
    changed = solver.step(configuration, DT)
    reference = fresh.step(configuration, DT)
    np.testing.assert_allclose(changed.velocity, reference.velocity, rtol=0, atol=1e-12)
    # (the subtrees ask for different motions: body 1's answer is another)
    whole, *_ = _humanoid_solver(model, 1)
    whole.levels[1][0].set_target(com.target_com)
    for foot, other in zip(feet, whole.levels[0]):
        other.set_target(foot.transform_target_to_world)
    whole.levels[2][0].set_target(posture.target_q)
    assert np.abs(whole.step(configuration, DT).velocity - changed.velocity).max() > 1e-6
    np.testing.assert_array_equal(
        changed.velocity, solver.qp_solution(configuration, DT).velocity
    )  # (the QP path's answer)
    com.body = 1  # the plan's subtree again
    solver.step(configuration, DT)
    assert plan._plain_data is configuration.data
    _same(solver.step(configuration, DT), plain_solver.step(configuration, DT))
