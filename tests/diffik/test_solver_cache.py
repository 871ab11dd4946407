"""qpik.solve_ik keeps its IKSolver between calls (qpik.diffik.mink_compat.SolverCache) and reads a
mink.Configuration in place: same answers, bit for bit, as a fresh solver's."""

from __future__ import annotations

import mink
import numpy as np
import pytest

import qpik
from qpik.diffik.mink_compat import SOLVERS


def _setup(robot: str = "ur5e"):
    model = qpik.load_robot(robot)
    configuration = mink.Configuration(model)
    configuration.update(model.qpos0 + 0.1)
    site = "ee" if robot == "ur5e" else qpik.robots.tool_frame(model)[0]
    task = mink.FrameTask(site, "site", position_cost=1.0, orientation_cost=1.0)
    task.set_target(
        configuration.get_transform_frame_to_world(site, "site")
        @ mink.SE3.from_translation(np.array([0.05, -0.02, 0.08]))
    )
    posture = mink.PostureTask(model, cost=1e-2)
    posture.set_target_from_configuration(configuration)
    return model, configuration, task, posture


@pytest.mark.parametrize("solver", [None, "daqp", "osqp"])
@pytest.mark.parametrize("levels", [False, True])
def test_kept_solver_answers_bitwise_as_a_fresh_one(solver, levels):
    model, configuration, task, posture = _setup()
    tasks = [[task], [posture]] if levels else [task, posture]
    limits = [
        mink.ConfigurationLimit(model),
        mink.VelocityLimit(model, {"shoulder_pan_joint": 0.5}),
    ]
    kept, fresh = [], []
    q = configuration.q.copy()
    for loop, out in ((True, kept), (False, fresh)):
        configuration.update(q)
        qpik.clear_caches()
        for _ in range(15):
            if not loop:
                qpik.clear_caches()
            v = qpik.solve_ik(configuration, tasks, 0.01, solver, limits=limits)
            out.append(v)
            configuration.integrate_inplace(v, 0.01)
    for a, b in zip(kept, fresh):
        assert np.array_equal(a, b)


def test_solver_is_kept_per_identity_and_rebuilt_when_it_changes():
    model, configuration, task, posture = _setup()
    qpik.clear_caches()
    qpik.solve_ik(configuration, [task, posture], 0.01)
    qpik.solve_ik(configuration, [task, posture], 0.01)
    assert len(SOLVERS) == 1
    other = mink.PostureTask(model, cost=1e-2)
    other.set_target_from_configuration(configuration)
    qpik.solve_ik(configuration, [task, other], 0.01)
    qpik.solve_ik(configuration, [[task], [posture]], 0.01)
    qpik.solve_ik(configuration, [task, posture], 0.01, damping=1e-6)
    assert len(SOLVERS) == 4
    qpik.clear_caches()
    assert len(SOLVERS) == 0


@pytest.mark.parametrize("solver", [None, "daqp"])
def test_limits_built_anew_at_each_call_find_the_kept_solver(solver):
    """A loop that builds [ConfigurationLimit(model), VelocityLimit(...)] at each call (new
    objects, equal values) is answered by the kept solver (h10's audit: a new solver each
    call, 2.6x mink's time), bit for bit a fresh solver's; a limit of other values (a gain,
    a range edited in place, a speed) gets a solver of its own."""
    model, configuration, task, posture = _setup()

    def limits(gain=0.95, speed=0.5):
        return [
            mink.ConfigurationLimit(model, gain=gain),
            mink.VelocityLimit(model, {"shoulder_pan_joint": speed}),
        ]

    qpik.clear_caches()
    answers = [qpik.solve_ik(configuration, [task, posture], 0.01, solver, limits=limits())]
    for _ in range(3):
        answers.append(qpik.solve_ik(configuration, [task, posture], 0.01, solver, limits=limits()))
    assert len(SOLVERS) == 1
    assert all(np.array_equal(a, answers[0]) for a in answers)
    qpik.solve_ik(configuration, [task, posture], 0.01, solver, limits=limits(gain=0.5))
    qpik.solve_ik(configuration, [task, posture], 0.01, solver, limits=limits(speed=0.25))
    assert len(SOLVERS) == 3
    saved = model.jnt_range.copy()
    try:
        model.jnt_range[:, 0] = configuration.q[: model.njnt] - 1e-4  # nearly pinned
        model.jnt_range[:, 1] = configuration.q[: model.njnt] + 1e-4
        pinned = qpik.solve_ik(configuration, [task, posture], 0.01, solver, limits=limits())
        assert len(SOLVERS) == 4 and np.abs(pinned).max() <= 1e-4 / 0.01 + 1e-9
    finally:
        model.jnt_range[:] = saved


def test_a_kept_limit_changed_since_is_not_taken_for_an_equal_new_one():
    """A caller holding two equal limit lists A and B: the solver kept for A reads A's
    objects; where A's velocity limit is then changed, a call with B (its values the old
    ones) must not get A's solver, which would use the changed values."""
    model, configuration, task, posture = _setup()

    def limits():
        return [mink.VelocityLimit(model, {"shoulder_pan_joint": 0.5})]

    qpik.clear_caches()
    first, second = limits(), limits()
    qpik.solve_ik(configuration, [task, posture], 0.01, "daqp", limits=first)
    first[0].limit = np.full_like(first[0].limit, 0.01)  # (the kept solver reads it)
    answer = qpik.solve_ik(configuration, [task, posture], 0.01, "daqp", limits=second)
    qpik.clear_caches()
    fresh = qpik.solve_ik(configuration, [task, posture], 0.01, "daqp", limits=limits())
    assert np.array_equal(answer, fresh)


def test_default_limits_follow_a_model_changed_in_place():
    model, configuration, task, posture = _setup()
    qpik.clear_caches()
    before = qpik.solve_ik(configuration, [task, posture], 0.01)
    saved = model.jnt_range.copy()
    try:
        model.jnt_range[:, 0] = configuration.q[: model.njnt] - 1e-4  # nearly pinned
        model.jnt_range[:, 1] = configuration.q[: model.njnt] + 1e-4
        pinned = qpik.solve_ik(configuration, [task, posture], 0.01)
        assert np.abs(pinned).max() <= 1e-4 / 0.01 + 1e-9
        assert not np.array_equal(pinned, before)
    finally:
        model.jnt_range[:] = saved


def test_mink_configuration_is_read_in_place_not_copied():
    """A state set on the mink configuration (q, mocap, data) is what the step sees, and
    the configuration itself is not modified."""
    model, configuration, task, posture = _setup()
    v1 = qpik.solve_ik(configuration, [task, posture], 0.01)
    configuration.update(configuration.q + 0.05)
    q = configuration.q.copy()
    v2 = qpik.solve_ik(configuration, [task, posture], 0.01)
    assert not np.array_equal(v1, v2)
    assert np.array_equal(configuration.q, q)
    fresh = qpik.Configuration(model, q)
    assert np.array_equal(v2, qpik.solve_ik(fresh, [task, posture], 0.01))


def test_sharing_view_shares_model_and_data():
    model, configuration, _, _ = _setup()
    view = qpik.Configuration.sharing(configuration)
    assert view.model is configuration.model and view.data is configuration.data
    assert isinstance(view, qpik.Configuration)
    assert qpik.Configuration.sharing(view) is view
    assert np.array_equal(view.lower, qpik.Configuration(model).lower)


def test_a_constrained_call_does_not_keep_a_solver_of_other_limits():
    """h19's audit: a call with constraints= found the solver kept for equal limits (A) and
    kept it under its own limits' identity (B); A changed afterwards changed B's answer."""
    model, configuration, task, posture = _setup()
    freeze = mink.DofFreezingTask(model, dof_indices=[0])

    def limits():
        return [mink.VelocityLimit(model, {model.joint(i).name: 0.5 for i in range(model.njnt)})]

    qpik.clear_caches()
    first, second = limits(), limits()
    qpik.solve_ik(configuration, [task, posture], 0.01, "daqp", limits=first, constraints=[freeze])
    qpik.solve_ik(configuration, [task, posture], 0.01, "daqp", limits=second, constraints=[freeze])
    first[0].limit = np.full_like(first[0].limit, 0.01)
    after = qpik.solve_ik(
        configuration, [task, posture], 0.01, "daqp", limits=second, constraints=[freeze]
    )
    qpik.clear_caches()
    fresh = qpik.solve_ik(
        configuration, [task, posture], 0.01, "daqp", limits=second, constraints=[freeze]
    )
    assert np.array_equal(after, fresh) and np.abs(fresh).max() > 0.1


def test_solve_ik_from_threads_answers_as_one_thread_does():
    """h19's audit: threads on their own tasks raised KeyError where the cache evicted, and
    threads sharing task objects (as mink allows) stepped one kept solver at once: wrong
    velocities. A kept solver is stepped by one thread at a time; the cache is locked."""
    import threading

    model, configuration, task, posture = _setup()

    def run(out: list, configuration: mink.Configuration) -> None:
        for k in range(12):
            levels = [[task], [posture]] if k % 2 else [task, posture]  # (two entries)
            out.append(qpik.solve_ik(configuration, levels, 0.01, None, limits=None))
            configuration.integrate_inplace(out[-1], 0.01)  # (each thread its own states)
            extra = [mink.PostureTask(model, cost=1e-2) for _ in range(3)]  # (evictions)
            for t in extra:
                t.set_target_from_configuration(configuration)
            qpik.solve_ik(configuration, [task, *extra], 0.01)

    alone: list = []
    qpik.clear_caches()
    run(alone, mink.Configuration(model, configuration.q))
    results: list[list] = [[] for _ in range(4)]
    threads = [
        threading.Thread(target=run, args=(results[i], mink.Configuration(model, configuration.q)))
        for i in range(4)
    ]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for out in results:
        assert len(out) == len(alone)
        assert all(np.array_equal(a, b) for a, b in zip(out, alone))
