"""HierarchySolver's settings are checked where they are set (the constructor's keywords
and assignments afterwards alike: qpik.core.settings), and a setting changed after a solve
is the one the next solve uses, on the core and on the compiled step that copied it."""

from __future__ import annotations

import mink
import numpy as np
import pytest

import qpik
from qpik.core import DampingLaw, HierarchyProblem, HierarchySolver, Level
from qpik.errors import InvalidInput, InvalidOption

BAD = [
    ("solver", "nope"),
    ("solver", 3),
    ("rank_tolerance", "x"),
    ("rank_tolerance", -1.0),
    ("rank_tolerance", np.nan),
    ("rank_tolerance", True),
    ("warm_start", "yes"),
    ("warm_start", 1),
    ("damping_law", "x"),
    ("tolerance", np.inf),
    ("tolerance", "x"),
    ("max_iter", -5),
    ("max_iter", 2.5),
    ("max_iter", "x"),
    ("backend_options", "x"),
]


def _problem() -> HierarchyProblem:
    rng = np.random.default_rng(0)
    levels = [Level(rng.normal(size=(3, 5)), rng.normal(size=3)), Level(np.eye(5), np.zeros(5))]
    return HierarchyProblem(
        levels, lb=-0.3 * np.ones(5), ub=0.3 * np.ones(5), G=np.zeros((0, 5)), h=np.zeros(0)
    )


@pytest.mark.parametrize(("name", "value"), BAD)
def test_a_setting_out_of_its_range_is_refused_where_it_is_set(name, value):
    """Assigned after construction or given to the constructor: qpik's InvalidOption naming
    the setting (an unknown backend: InvalidInput), never a solve that runs with it (before,
    an assignment was taken as it was: 'nope' solved as 'auto', -1 as a rank tolerance, and
    'x' raised TypeError from the compiled call)."""
    solver = HierarchySolver()
    before = solver.solve(_problem()).x.copy()
    error = InvalidInput if name == "solver" else InvalidOption
    with pytest.raises(error, match=name if name != "solver" else "solver"):
        setattr(solver, name, value)
    np.testing.assert_array_equal(solver.solve(_problem()).x, before)
    with pytest.raises(error):
        HierarchySolver(**{name: value})  # type: ignore[arg-type]


def test_a_setting_changed_after_a_solve_is_the_next_solves():
    problem = _problem()
    solver = HierarchySolver(damping_law=None)
    solver.solve(problem)
    solver.max_iter, solver.tolerance = 3, 1e-10
    fresh = HierarchySolver(damping_law=None, max_iter=3, tolerance=1e-10)
    np.testing.assert_array_equal(solver.solve(problem).x, fresh.solve(problem).x)
    assert solver.settings_version > 0


def _near_singular_problem() -> HierarchyProblem:
    """Level 0 two nearly parallel rows (smallest singular value ~7e-5: damped by the
    default law, exact without one), level 1 a posture; a box that binds."""
    rng = np.random.default_rng(1)
    A0 = np.zeros((2, 5))
    A0[0, 0], A0[1, 0], A0[1, 1] = 1.0, 1.0, 1e-4
    levels = [Level(A0, np.array([0.2, 0.21])), Level(np.eye(5), rng.normal(size=5))]
    return HierarchyProblem(
        levels, lb=-0.3 * np.ones(5), ub=0.3 * np.ones(5), G=np.zeros((0, 5)), h=np.zeros(0)
    )


def test_the_solves_arguments_follow_every_setting_and_copy():
    """HierarchySolver.solve keeps the compiled call's arguments made from its settings
    between solves (SolverSettings._call_args); every assignment makes them again: after
    each change the answer is, bit for bit, that of a fresh solver built with the settings
    so far, and a copy solves with its own (its own workspace, its own later changes)."""
    import copy

    problem = _near_singular_problem()
    solver = HierarchySolver()
    damped = solver.solve(problem).x.copy()
    changes = [
        ("damping_law", None),
        ("damping_law", DampingLaw(singular_threshold=0.3, max_damping=0.2, lower_trust=1.0)),
        ("rank_tolerance", 1e-3),
        ("tolerance", 1e-10),
        ("max_iter", 40),
        ("warm_start", True),
        ("warm_start", False),
    ]
    settings: dict = {}
    answers = []
    for name, value in changes:
        setattr(solver, name, value)
        settings[name] = value
        got = solver.solve(problem)
        expected = HierarchySolver(**settings).solve(problem)
        np.testing.assert_array_equal(got.x, expected.x)
        assert got.status == expected.status
        answers.append(got.x.copy())
    assert np.abs(answers[0] - damped).max() > 1e-3  # (the law's change took effect)
    assert np.abs(answers[1] - answers[0]).max() > 1e-3
    twin = copy.deepcopy(solver)
    np.testing.assert_array_equal(twin.solve(problem).x, answers[-1])
    assert twin._call_args is not None and twin._call_args[10] is twin._cascade_workspace
    assert twin._cascade_workspace is not solver._cascade_workspace
    twin.damping_law = None
    np.testing.assert_array_equal(solver.solve(problem).x, answers[-1])  # (unchanged)


def _panda_far():
    """The bundled Panda at its home pose, a frame target 0.3 m away over a posture 0.5 rad
    away (both levels bind), its position and velocity limits."""
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    p = configuration.frame_pose("ee", "site")[0]
    frame.set_target(mink.SE3.from_translation(p + 0.3))
    posture = qpik.tasks.PostureTask(model, cost=0.1)
    posture.set_target(model.key_qpos[0] + 0.5)
    limits = [mink.ConfigurationLimit(model), qpik.limits.velocity_limit_from_model(model)]
    return model, configuration, frame, posture, limits


def test_the_compiled_step_copies_the_core_settings_again_where_they_changed():
    """An IKSolver's core settings changed after its plan copied them (its damping law
    through IKSolver.damping_law, its rank tolerance and cap through the core): the next
    step is that of a solver built with them, bit for bit, on the plain lane (before, the
    lane kept the copied rank tolerance and cap)."""
    model, configuration, frame, posture, limits = _panda_far()
    law = DampingLaw(singular_threshold=0.3, max_damping=0.2, error_scale=None)
    solver = qpik.IKSolver(model, [[frame], [posture]], limits)
    solver.step(configuration, 0.01)
    solver.step(configuration, 0.01)
    solver.damping_law = law
    solver._core.rank_tolerance = 0.1  # (drops a direction here)
    solver._core.max_iter = 2
    changed = solver.step(configuration, 0.01)
    again = solver.step(configuration, 0.01)  # (the lane)
    assert solver._plan._plain_data is configuration.data
    fresh = qpik.IKSolver(model, [[frame], [posture]], limits, damping_law=law, rank_tolerance=0.1)
    fresh._core.max_iter = 2
    expected = fresh.step(configuration, 0.01)
    np.testing.assert_array_equal(changed.velocity, expected.velocity)
    np.testing.assert_array_equal(again.velocity, expected.velocity)
    assert [str(s) for s in again.status] == [str(s) for s in expected.status]
    # the cap and tolerance the plan's kernel reads (before: the build's, 0 and 1e-9)
    from qpik.diffik.layout import RANK_TOL

    assert solver._plan._cap == 2 and solver._plan.arrays["settings"][RANK_TOL] == 0.1
    default = qpik.IKSolver(model, [[frame], [posture]], limits, damping_law=law)
    assert np.abs(default.step(configuration, 0.01).velocity - again.velocity).max() > 1e-3


def test_a_level_past_its_cap_reports_the_same_whatever_ran_before():
    """A cap the dual method hits (max_iter=2): the level falls back to OSQP, from a fresh
    workspace, so that its iteration count, like every other field, is the same on a first
    solve, a second one and one after another problem (before: 55, 5 and 115, from a kept,
    warm OSQP workspace; x the same)."""
    pytest.importorskip("osqp")
    model, configuration, frame, posture, limits = _panda_far()
    ik = qpik.IKSolver(model, [[frame], [posture]], limits)
    problem = ik.build(configuration, 0.01)
    other = ik.build(qpik.Configuration(model, model.key_qpos[0] + 0.1), 0.01)
    first = HierarchySolver(max_iter=2)
    a = first.solve(problem)
    again = first.solve(problem)
    after = HierarchySolver(max_iter=2)
    after.solve(other)
    b = after.solve(problem)
    assert a.backend[0] == "osqp"  # (the fallback this is about)
    for result in (again, b):
        np.testing.assert_array_equal(result.x, a.x)
        assert result.iterations == a.iterations and result.status == a.status


def test_settings_versions_are_never_shared_between_solvers():
    """Two solvers built alike have different settings versions, and every assignment gives
    a new one (a plan that copied one solver's settings never takes another's for them)."""
    a, b = HierarchySolver(), HierarchySolver()
    assert a.settings_version != b.settings_version
    before = a.settings_version
    a.warm_start = False  # (the same value: still a new version)
    assert a.settings_version not in (before, b.settings_version)


def test_backend_options_of_a_wrong_type_or_name_are_typed_errors():
    """Audit (options): OSQP values of a wrong type ("1e-3", None) raised a bare TypeError
    from the range comparison; an option a qpsolvers backend does not take made it fail on
    every level without a word. Both are InvalidInput naming the option now."""
    import qpik
    from qpik.tasks import PositionTask

    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    tip = PositionTask("ee")
    tip.set_target(configuration.frame_pose("ee")[0] + [0.3, 0.0, 0.0])
    for value in ("1e-3", None, [1e-3]):
        with pytest.raises(qpik.InvalidInput, match="eps_abs"):
            qpik.IKSolver(model, [[tip]], solver="osqp", backend_options={"eps_abs": value})
    pytest.importorskip("daqp")
    with pytest.raises(qpik.InvalidInput, match="daqp takes no option 'bogus_key'"):
        qpik.IKSolver(model, [[tip]], solver="daqp", backend_options={"bogus_key": 1})


@pytest.mark.parametrize(
    ("solver", "options", "match"),
    [
        ("daqp", {"eps_prox": "abc"}, "daqp setting 'eps_prox' must be a number"),
        ("daqp", {"iter_limit": True}, "daqp setting 'iter_limit' must be an integer"),
        ("daqp", {"iter_limit": 0}, "daqp setting 'iter_limit' must be an integer"),
        ("daqp", {"primal_tol": -1e-6}, "daqp setting 'primal_tol' must be a number in \\(0"),
        ("daqp", {"primal_tol": float("nan")}, "daqp setting 'primal_tol'"),
        ("daqp", {"sense": [0]}, "daqp takes no option 'sense'"),
        ("quadprog", {"factorized": "x"}, "quadprog setting 'factorized' must be False, got 'x'"),
        ("quadprog", {"factorized": True}, "quadprog setting 'factorized' must be False, got True"),
    ],
)
def test_daqp_and_quadprog_values_are_checked_when_the_solver_is_made(solver, options, match):
    """Audit (options, left open before): DAQP's and quadprog's option values went to the
    backend unchecked (DAQP read ``iter_limit=True`` as 1; quadprog's ``factorized=True``
    would read qpik's Hessian as the inverse of its factor). Each is an InvalidInput naming
    the setting when the solver is made, by IKSolver, by HierarchySolver's setting and by a
    full-IK solve alike; the values the backend takes still solve."""
    import qpik
    from qpik.core import HierarchySolver
    from qpik.tasks import PositionTask

    pytest.importorskip(solver)
    model = qpik.load_robot("panda")
    tip = PositionTask("ee")
    with pytest.raises(qpik.InvalidInput, match=match):
        qpik.IKSolver(model, [[tip]], solver=solver, backend_options=options)
    core = HierarchySolver(solver=solver)
    with pytest.raises(qpik.InvalidInput, match=match):
        core.backend_options = options
    assert core.backend_options == {}
    step = qpik.StepOptions(solver=solver, backend_options=options)
    target = qpik.Configuration(model, model.key_qpos[0]).frame_pose("ee")[0]
    with pytest.raises(qpik.InvalidInput, match=match):
        qpik.solve(model, {"ee": target}, options=qpik.SolveOptions(step=step))


def test_daqp_and_quadprog_values_they_take_still_solve():
    import qpik
    from qpik.tasks import PositionTask

    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    tip = PositionTask("ee")
    tip.set_target(configuration.frame_pose("ee")[0] + [0.3, 0.0, 0.0])
    reference = qpik.IKSolver(model, [[tip]]).step(configuration, 0.01).velocity
    for solver, options in (
        ("daqp", {"primal_tol": 1e-9, "iter_limit": 500, "presolve": 0}),
        ("quadprog", {"factorized": False}),
    ):
        pytest.importorskip(solver)
        result = qpik.IKSolver(model, [[tip]], solver=solver, backend_options=options).step(
            configuration, 0.01
        )
        assert result.ok
        np.testing.assert_allclose(result.velocity, reference, atol=1e-9)
