"""A mink user switches by changing one import (issue 14).

``qpik.solve_ik`` / ``qpik.build_ik`` take mink's arguments and defaults; their answers are
checked against mink itself (an independent QP: mink solves one weighted QP with DAQP),
against qpsolvers on the QP that ``build_ik`` returns, and against closed forms (the
classical null-space formula for priorities). These are qpik's own tests of the same
behaviours mink's suite checks; ``benchmarks/mink_suite.py`` runs mink's suite itself.
"""

from __future__ import annotations

import importlib.util
import inspect

import mink
import mujoco
import numpy as np
import pytest
import qpsolvers
from conftest import configuration_of

import qpik
from qpik.diffik import constraints as constraints_module

DT = 0.01
BACKENDS = [None, "daqp", "quadprog", "osqp"]


def _home(name: str = "ur5e") -> mink.Configuration:
    """A plain mink configuration of a bundled robot at its home keyframe."""
    configuration = mink.Configuration(qpik.load_robot(name))
    configuration.update_from_keyframe("home")
    return configuration


def _frame_task(configuration, offset=(0.02, -0.03, 0.04), cost=(1.0, 1.0)) -> mink.FrameTask:
    task = mink.FrameTask("ee", "site", position_cost=cost[0], orientation_cost=cost[1])
    start = configuration.get_transform_frame_to_world("ee", "site")
    task.set_target(mink.SE3.from_translation(np.asarray(offset, dtype=float)) @ start)
    return task


def _mink_answer(configuration, tasks, limits=None, constraints=None) -> np.ndarray:
    """mink's velocity: mink's own QP (``mink.build_ik``) solved exactly by quadprog
    (mink's DAQP default stops at a 1e-7 feasibility tolerance), checked against
    ``mink.solve_ik`` to that tolerance."""
    problem = mink.build_ik(configuration, tasks, DT, limits=limits, constraints=constraints)
    solution = qpsolvers.solve_problem(problem, solver="quadprog")
    assert solution.found
    velocity = solution.x / DT
    minks = mink.solve_ik(configuration, tasks, DT, "daqp", limits=limits, constraints=constraints)
    np.testing.assert_allclose(velocity, minks, atol=1e-5)
    return velocity


def _posture(configuration, cost=1e-2) -> mink.PostureTask:
    task = mink.PostureTask(configuration.model, cost=cost)
    task.set_target(configuration.model.qpos0)
    return task


# ----------------------------------------------------------------------------- signature
@pytest.mark.parametrize("name", ["solve_ik", "build_ik"])
def test_signature_is_minks(name):
    ours = inspect.signature(getattr(qpik, name)).parameters
    theirs = inspect.signature(getattr(mink, name)).parameters
    assert list(ours) == list(theirs)
    for parameter, mink_parameter in zip(ours.values(), theirs.values()):
        assert parameter.kind == mink_parameter.kind
        if mink_parameter.default is not inspect.Parameter.empty:
            assert parameter.default == mink_parameter.default, parameter.name
    assert qpik.solve_ik.__module__ == "qpik.diffik.mink_compat"


def test_solver_is_the_fourth_positional_argument():
    configuration = _home()
    task = _frame_task(configuration)
    by_position = qpik.solve_ik(configuration, [task], DT, "daqp", 1e-12)
    by_name = qpik.solve_ik(configuration, [task], dt=DT, solver="daqp", damping=1e-12)
    np.testing.assert_array_equal(by_position, by_name)


# ------------------------------------------------------------ the same answers as mink
def _random_configurations(model, rng, count):
    """Configurations well inside the limits (joints within 60% of their range)."""
    low, high = model.jnt_range[:, 0], model.jnt_range[:, 1]
    middle, half = 0.5 * (low + high), 0.5 * (high - low)
    home = model.key("home").qpos
    return [
        np.clip(home + rng.uniform(-0.3, 0.3, model.nq), middle - 0.6 * half, middle + 0.6 * half)
        for _ in range(count)
    ]


@pytest.mark.parametrize("robot", ["ur5e", "panda"])
@pytest.mark.parametrize("solver", BACKENDS)
def test_flat_list_matches_mink(robot, solver, rng):
    """Away from singularities a flat list is mink's weighted QP: same answer to 1e-9,
    with and without binding velocity limits."""
    model = qpik.load_robot(robot)
    tight = {model.joint(j).name: 0.3 for j in range(model.njnt)}
    checked = 0
    for q in _random_configurations(model, rng, 4):
        configuration = mink.Configuration(model, q)
        jacobian = qpik.Configuration(model, q).frame_jacobian("ee")
        assert np.linalg.svd(jacobian[:3], compute_uv=False).min() > 0.1  # not singular
        tasks = [
            _frame_task(configuration, offset=rng.uniform(-0.1, 0.1, 3)),
            _posture(configuration),
        ]
        for limits in (None, [mink.ConfigurationLimit(model), mink.VelocityLimit(model, tight)]):
            expected = _mink_answer(configuration, tasks, limits)
            if solver is None:
                ours = qpik.solve_ik(configuration, tasks, DT, limits=limits)
            else:
                ours = qpik.solve_ik(configuration, tasks, DT, solver, limits=limits)
            np.testing.assert_allclose(ours, expected, rtol=0, atol=1e-9)
            checked += 1
    assert checked == 8


def test_velocity_limits_bind_in_that_comparison(rng):
    """The comparison above is not vacuous: the tight velocity limits bind."""
    model = qpik.load_robot("ur5e")
    configuration = mink.Configuration(model, _random_configurations(model, rng, 1)[0])
    tight = {model.joint(j).name: 0.3 for j in range(model.njnt)}
    tasks = [_frame_task(configuration, offset=(0.08, -0.08, 0.08)), _posture(configuration)]
    free = qpik.solve_ik(configuration, tasks, DT, "daqp", limits=[])
    capped = qpik.solve_ik(
        configuration, tasks, DT, "daqp", limits=[mink.VelocityLimit(model, tight)]
    )
    assert np.abs(free).max() > 0.3
    assert np.abs(capped).max() == pytest.approx(0.3, abs=1e-12)


def test_answer_is_bitwise_repeatable():
    configuration = _home()
    tasks = [_frame_task(configuration), _posture(configuration)]
    first = qpik.solve_ik(configuration, tasks, DT, "daqp")
    other = _home("panda")  # something else solved in between
    qpik.solve_ik(other, [_frame_task(other, offset=(0.3, 0.3, 0.3))], DT, "osqp")
    assert first.tobytes() == qpik.solve_ik(configuration, tasks, DT, "daqp").tobytes()


# ---------------------------------------------------------------------------- limits
def test_default_limits_are_the_position_limits():
    """``limits=None`` enforces the joint limits, as mink does; ``[]`` enforces none."""
    model = qpik.load_robot("ur5e")
    configuration = _home()
    q = configuration.q
    q[2] = model.jnt_range[2, 1] - 0.01  # elbow 0.01 rad below its upper limit
    configuration.update(q)
    posture = mink.PostureTask(model, cost=1.0)
    target = q.copy()
    target[2] = model.jnt_range[2, 1] + 1.0  # asks for 1 rad beyond the limit
    posture.set_target(target)
    v_default = qpik.solve_ik(configuration, [posture], DT, "daqp")
    v_explicit = qpik.solve_ik(
        configuration, [posture], DT, "daqp", limits=[mink.ConfigurationLimit(model)]
    )
    v_none = qpik.solve_ik(configuration, [posture], DT, "daqp", limits=[])
    np.testing.assert_array_equal(v_default, v_explicit)
    gain = mink.ConfigurationLimit(model).gain
    assert v_default[2] * DT == pytest.approx(gain * 0.01, abs=1e-12)
    assert v_none[2] * DT == pytest.approx(1.01, abs=1e-9)
    np.testing.assert_allclose(v_default, _mink_answer(configuration, [posture]), atol=1e-9)


def test_limits_hold_over_a_closed_loop():
    """Integrating the velocities never leaves the limits (mink's examples crossed them
    by several radians when the default limit was missing)."""
    model = qpik.load_robot("ur5e")
    configuration = qpik.Configuration(model, model.key("home").qpos)
    posture = mink.PostureTask(model, cost=1.0)
    target = model.key("home").qpos.copy()
    target[2] = 20.0  # far beyond the elbow's pi limit
    posture.set_target(target)
    for _ in range(300):
        v = qpik.solve_ik(configuration, [posture], DT, "daqp")
        configuration.integrate_inplace(v, DT)
        assert configuration.within_limits(tol=1e-9)
    assert configuration.q[2] == pytest.approx(model.jnt_range[2, 1], abs=1e-3)


def test_safety_break_raises_minks_exception():
    model = qpik.load_robot("ur5e")
    configuration = _home()
    q = configuration.q
    q[0] = model.jnt_range[0, 1] + 0.1
    configuration.update(q)
    with pytest.raises(mink.NotWithinConfigurationLimits) as info:
        qpik.solve_ik(configuration, [], DT, "daqp", safety_break=True)
    error = info.value
    assert isinstance(error, qpik.JointLimitViolation)
    assert error.joint == "shoulder_pan_joint" and error.index == 0
    assert error.value == pytest.approx(q[0]) and error.upper == pytest.approx(
        model.jnt_range[0, 1]
    )


def test_safety_break_holds_on_the_kept_solver_way():
    """With a kept solver (the second call of the same objects) safety_break still checks
    the limits first, and inside them answers bitwise as without it."""
    model = qpik.load_robot("ur5e")
    configuration = _home()
    task = _frame_task(configuration)
    tasks = [task]
    plain = qpik.solve_ik(configuration, tasks, DT, "daqp")
    kept = qpik.solve_ik(configuration, tasks, DT, "daqp", safety_break=True)
    assert kept.tobytes() == plain.tobytes()
    q = configuration.q
    q[1] = model.jnt_range[1, 0] - 0.05
    configuration.update(q)
    qpik.solve_ik(configuration, tasks, DT, "daqp")  # (kept, and answered: no safety break)
    with pytest.raises(qpik.JointLimitViolation) as info:
        qpik.solve_ik(configuration, tasks, DT, "daqp", safety_break=True)
    assert info.value.joint == "shoulder_lift_joint"


def test_without_safety_break_a_start_outside_the_limits_moves_back():
    """Without ``safety_break`` there is no exception; the smallest velocity the limits
    allow is the one that heads back inside (mink's QP gives the same)."""
    model = qpik.load_robot("ur5e")
    configuration = _home()
    q = configuration.q
    q[0] = model.jnt_range[0, 1] + 0.1
    configuration.update(q)
    v = qpik.solve_ik(configuration, [], DT, "daqp")
    assert v[0] < 0 and np.all(v[1:] == 0)
    np.testing.assert_allclose(v, _mink_answer(configuration, []), atol=1e-9)


def test_empty_task_list_gives_zero_velocity():
    configuration = _home("panda")
    for limits in (None, []):
        v = qpik.solve_ik(configuration, [], DT, "daqp", limits=limits)
        assert v.shape == (configuration.model.nv,)
        assert np.all(v == 0)


# ------------------------------------------------------------------------ priorities
def test_list_of_levels_keeps_strict_priorities():
    """Two conflicting levels: the closed-form null-space solution
    ``dq = J1^+ b1 + (J2 N1)^+ (b2 - J2 J1^+ b1)`` (no limits, no damping)."""
    configuration = _home("panda")
    position = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=0.0)
    start = configuration.get_transform_frame_to_world("ee", "site")
    position.set_target(mink.SE3.from_translation(np.array([0.05, 0.0, -0.05])) @ start)
    posture = mink.PostureTask(configuration.model, cost=1.0)
    posture.set_target(configuration.model.qpos0)
    v = qpik.solve_ik(configuration, [[position], [posture]], DT, "daqp", damping=0.0, limits=[])
    A1, b1, _ = position.compute_qp_residual(configuration)
    A2, b2, _ = posture.compute_qp_residual(configuration)
    A1, b1 = A1[:3], b1[:3]  # the orientation rows have zero cost
    pinv1 = np.linalg.pinv(A1)
    N1 = np.eye(configuration.model.nv) - pinv1 @ A1
    expected = pinv1 @ b1 + np.linalg.pinv(A2 @ N1, rcond=1e-9) @ (b2 - A2 @ pinv1 @ b1)
    np.testing.assert_allclose(v * DT, expected, atol=1e-9)
    # The top level is met exactly; as one weighted level it would not be.
    np.testing.assert_allclose(A1 @ (v * DT), b1, atol=1e-10)
    flat = qpik.solve_ik(configuration, [position, posture], DT, "daqp", damping=0.0, limits=[])
    assert np.linalg.norm(A1 @ (flat * DT) - b1) > 1e-4


# ----------------------------------------------------------------------- constraints
def test_constraints_are_held_exactly_and_match_mink():
    model = qpik.load_robot("ur5e")
    configuration = qpik.Configuration(model, model.key("home").qpos)
    start = configuration.q
    task = _frame_task(configuration, offset=(0.0, 0.0, 0.05))
    freeze = mink.DofFreezingTask(model, dof_indices=[0, 1])
    v = qpik.solve_ik(configuration, [task], DT, "daqp", constraints=[freeze])
    np.testing.assert_allclose(v, _mink_answer(configuration, [task], None, [freeze]), atol=1e-9)
    for _ in range(20):
        v = qpik.solve_ik(configuration, [task], DT, "daqp", constraints=[freeze])
        configuration.integrate_inplace(v, DT)
    assert np.all(configuration.q[:2] == start[:2])
    assert np.abs(configuration.q[2:] - start[2:]).max() > 1e-3


def test_constraint_calls_kept_answer_bitwise_as_a_fresh_call(monkeypatch):
    """A call with constraints keeps its solver (SolverCache.keep_constrained): the next
    call with the same objects takes SolverCache.velocity's way, bitwise the answer of the
    full path after the caches are cleared; another constraint list (other objects) or a
    constraint whose target moved is answered afresh, not from the kept solver's rows."""
    model = qpik.load_robot("erd:panda")
    configuration = mink.Configuration(model)
    configuration.update(model.jnt_range.mean(1))
    frame = mink.FrameTask("panda_hand_tcp", "body", position_cost=1.0, orientation_cost=1.0)
    start = configuration.get_transform_frame_to_world("panda_hand_tcp", "body")
    frame.set_target(start @ mink.SE3.from_translation(np.array([0.03, -0.02, 0.01])))
    posture = mink.PostureTask(model, cost=0.1)
    posture.set_target(configuration.q)
    hold = mink.FrameTask("panda_hand_tcp", "body", position_cost=0.0, orientation_cost=1.0)
    hold.set_target_from_configuration(configuration)
    limits = [mink.ConfigurationLimit(model)]

    def call(constraints):
        return qpik.solve_ik(configuration, [frame, posture], DT, "daqp", 1e-6, limits=limits,
                             constraints=constraints)  # fmt: skip

    qpik.clear_caches()
    first = call([hold])
    built = []
    full = qpik.diffik.mink_compat._constrained_solver
    monkeypatch.setattr(
        "qpik.diffik.mink_compat._constrained_solver", lambda *a: built.append(1) or full(*a)
    )
    second = call([hold])  # (SolverCache.velocity: the full path not taken)
    assert second.tobytes() == first.tobytes() and not built
    theirs = mink.solve_ik(configuration, [frame, posture], DT, "daqp", 1e-6, limits=limits,
                           constraints=[hold])  # fmt: skip
    np.testing.assert_allclose(first, theirs, rtol=0, atol=1e-8)
    # the constraint held: the hand's rotation does not move (to first order)
    J = hold.compute_jacobian(configuration)
    np.testing.assert_allclose(J @ first, -hold.gain * hold.compute_error(configuration) / DT,
                               atol=1e-9)  # fmt: skip
    # a moved target is read at the call, through the kept solver
    hold.set_target(start @ mink.SE3.from_rotation(mink.SO3.from_z_radians(0.01)))
    moved = call([hold])
    qpik.clear_caches()
    assert call([hold]).tobytes() == moved.tobytes()
    assert np.abs(moved - first).max() > 1e-3
    # no constraint, as None or as an empty list: the same kept solver, the same bits
    assert call(None).tobytes() == call([]).tobytes() == call(()).tobytes()
    # another constraint object: a solver of its own
    freeze = mink.DofFreezingTask(model, dof_indices=[0])
    frozen = call([freeze])
    assert frozen[0] == 0.0 and call([freeze]).tobytes() == frozen.tobytes()


def test_unit_rows_scale_each_row_and_refuse_what_is_not_finite():
    from qpik._engine.tasks import unit_rows

    rng = np.random.default_rng(3)
    J = rng.standard_normal((5, 7))
    J[2] = 0.0  # a zero row stays as it is
    e = rng.standard_normal(5)
    A, b = np.empty_like(J), np.empty(5)
    assert unit_rows(A, b, J, e, 2.0)
    norms = np.linalg.norm(J, axis=1)
    scale = np.where(norms > 0, 1.0 / np.where(norms > 0, norms, 1.0), 1.0)
    np.testing.assert_allclose(A, J * scale[:, None], rtol=1e-15, atol=0)
    np.testing.assert_allclose(b, -2.0 * e * scale, rtol=1e-15, atol=0)
    assert np.all(A[2] == 0.0) and b[2] == -2.0 * e[2]
    np.testing.assert_allclose(np.linalg.norm(A[[0, 1, 3, 4]], axis=1), 1.0, rtol=1e-15)
    for bad in (np.nan, np.inf):
        Jb, A2, b2 = J.copy(), np.zeros_like(J), np.zeros(5)
        Jb[1, 3] = bad
        assert not unit_rows(A2, b2, Jb, e, 2.0)
        assert not np.any(A2) and not np.any(b2)  # nothing written
    assert not unit_rows(A, b, J, e, np.inf)  # -gain e not finite
    with pytest.raises(ValueError):
        unit_rows(A, b, J, e[:3], 1.0)


class _ScaledRow(mink.Task):
    """One equality row ``scale * dq_2 = -gain * 1e-3``: its units should not matter."""

    def __init__(self, scale: float):
        super().__init__(cost=np.ones(1), gain=1.0)
        self.scale = scale

    def compute_error(self, configuration):
        return np.array([1e-3])

    def compute_jacobian(self, configuration):
        jacobian = np.zeros((1, configuration.model.nv))
        jacobian[0, 2] = self.scale
        return jacobian


@pytest.mark.parametrize("scale", [1e-4, 1e-2, 1.0, 1e2])
def test_constraint_rows_of_any_scale_are_exact(scale):
    """A small row (below the damping law's singular threshold) is not damped away."""
    configuration = _home()
    task = _frame_task(configuration)
    v = qpik.solve_ik(configuration, [task], DT, "daqp", limits=[], constraints=[_ScaledRow(scale)])
    assert scale * v[2] * DT == pytest.approx(-1e-3, rel=1e-12)


def test_constraints_beyond_the_limits_are_met_as_closely_as_they_allow():
    configuration = _home()
    model = configuration.model
    row = _ScaledRow(1e-4)  # asks for dq_2 = -10 rad
    v = qpik.solve_ik(configuration, [], DT, "daqp", constraints=[row])
    gain = mink.ConfigurationLimit(model).gain
    lowest = -gain * (configuration.q[2] - model.jnt_range[2, 0])
    assert v[2] * DT == pytest.approx(lowest, abs=1e-12)


def test_constraints_sit_above_every_level():
    """With a list of levels, and with no task at all, the constraint rows still hold."""
    model = qpik.load_robot("panda")
    configuration = _home("panda")
    freeze = mink.DofFreezingTask(model, dof_indices=[3])
    levels = [[_frame_task(configuration, offset=(0.1, 0.1, 0.0))], [_posture(configuration, 1.0)]]
    v = qpik.solve_ik(configuration, levels, DT, "daqp", constraints=[freeze])
    assert v[3] == 0.0 and np.abs(v).max() > 0.1
    assert np.all(qpik.solve_ik(configuration, [], DT, "daqp", constraints=[freeze]) == 0)


# ---------------------------------------------------------------------------- kwargs
def test_kwargs_reach_the_qpsolvers_backend(monkeypatch):
    seen = []
    original = qpsolvers.solve_problem

    def spy(problem, solver, **kwargs):
        seen.append((solver, kwargs))
        return original(problem, solver, **kwargs)

    monkeypatch.setattr(qpsolvers, "solve_problem", spy)
    model = qpik.load_robot("ur5e")
    configuration = _home()
    tight = mink.VelocityLimit(model, {model.joint(j).name: 0.1 for j in range(model.njnt)})
    tasks = [_frame_task(configuration, offset=(0.1, 0.1, 0.1))]
    qpik.solve_ik(configuration, tasks, DT, "daqp", limits=[tight], primal_tol=1e-9)
    assert seen and all(kw.get("primal_tol") == 1e-9 for solver, kw in seen if solver == "daqp")


def test_osqp_kwargs_are_osqp_settings():
    configuration = _home()
    model = configuration.model
    tight = mink.VelocityLimit(model, {model.joint(j).name: 0.1 for j in range(model.njnt)})
    tasks = [_frame_task(configuration, offset=(0.1, 0.1, 0.1))]
    v = qpik.solve_ik(configuration, tasks, DT, "osqp", limits=[tight], eps_abs=1e-9, max_iter=8000)
    np.testing.assert_allclose(v, _mink_answer(configuration, tasks, [tight]), atol=1e-9)
    with pytest.raises(qpik.QpikError, match="not_a_setting"):
        qpik.solve_ik(configuration, tasks, DT, "osqp", limits=[tight], not_a_setting=1)


def test_kwargs_need_a_named_backend():
    configuration = _home()
    with pytest.raises(qpik.InvalidInput, match="primal_tol"):
        qpik.solve_ik(configuration, [_frame_task(configuration)], DT, primal_tol=1e-9)


# -------------------------------------------------------------------- bad input, errors
_BAD_ARGUMENTS = [
    ({"dt": 0.0}, qpik.InvalidInput, "dt"),
    ({"dt": float("nan")}, qpik.InvalidInput, "dt"),
    ({"damping": -1.0}, mink.InvalidDamping, "damping"),
    ({"damping": float("inf")}, qpik.InvalidDamping, "damping"),
    ({"tasks": "FrameTask"}, qpik.InvalidInput, "tasks"),
    ({"tasks": [[]]}, qpik.InvalidInput, r"tasks\[0\]"),
    ({"tasks": [[1.0]]}, qpik.InvalidInput, r"tasks\[0\]"),
    ({"limits": [object()]}, qpik.InvalidInput, r"limits\[0\]"),
    ({"limits": "ConfigurationLimit"}, qpik.InvalidInput, "limits"),
    ({"constraints": [object()]}, qpik.InvalidInput, r"constraints\[0\]"),
    ({"configuration": "ur5e"}, qpik.InvalidInput, "configuration"),
    ({"solver": "no_such_solver"}, qpik.InvalidInput, "no_such_solver"),
]
_BAD_CALLS = [("solve_ik", *bad) for bad in _BAD_ARGUMENTS] + [
    ("build_ik", *bad) for bad in _BAD_ARGUMENTS if "solver" not in bad[0]
]


@pytest.mark.parametrize("entry, arguments, error, fragment", _BAD_CALLS)
def test_bad_arguments_raise_typed_errors(entry, arguments, error, fragment):
    configuration = _home()
    call = {"configuration": configuration, "tasks": [_frame_task(configuration)], "dt": DT}
    if entry == "solve_ik":
        call["solver"] = "daqp"
    call.update(arguments)
    with pytest.raises(error, match=fragment):
        getattr(qpik, entry)(**call)


def test_infeasible_limits_raise_minks_no_solution_found():
    class Contradiction(mink.Limit):
        """dq_0 <= -1 and -dq_0 <= -1 together, over two joints (general rows)."""

        def compute_qp_inequalities(self, configuration, dt):
            G = np.zeros((2, configuration.model.nv))
            G[0, :2] = 1.0
            G[1, :2] = -1.0
            return mink.Constraint(G=G, h=np.array([-1.0, -1.0]))

    configuration = _home()
    with pytest.raises(mink.NoSolutionFound) as info:
        qpik.solve_ik(
            configuration, [_frame_task(configuration)], DT, "daqp", limits=[Contradiction()]
        )
    assert str(info.value) == "QP solver daqp failed to find a solution."
    assert isinstance(info.value, qpik.NoSolutionFound) and info.value.status == "infeasible"


def test_unknown_frames_are_minks_exceptions_too():
    configuration = configuration_of("ur5e")
    task = mink.FrameTask("gripper", "site", position_cost=1.0, orientation_cost=1.0)
    with pytest.raises(mink.InvalidFrame) as info:
        task.set_target_from_configuration(configuration)
    assert isinstance(info.value, qpik.UnknownFrame) and info.value.available == ["ee"]
    with pytest.raises(mink.UnsupportedFrame):
        configuration.get_transform_frame_to_world("ee", "joint")


# ------------------------------------------------------------------- configurations
def test_configuration_from_a_mink_configuration_copies_its_state():
    xml = """
    <mujoco>
      <worldbody>
        <body name="arm"><joint name="hinge" range="-1 1"/><geom size=".1"/>
          <site name="tip" pos="0.5 0 0"/></body>
        <body name="marker" mocap="true"><geom size=".05" contype="0" conaffinity="0"/></body>
      </worldbody>
    </mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    source = mink.Configuration(model, np.array([0.4]))
    source.data.mocap_pos[0] = [1.0, 2.0, 3.0]
    source.update()
    ours = qpik.Configuration(source)
    assert ours.model is model and ours.data is not source.data
    np.testing.assert_array_equal(ours.q, [0.4])
    np.testing.assert_array_equal(ours.data.mocap_pos[0], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(ours.frame_pose("marker", "body")[0], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(ours.frame_pose("tip")[0], source.data.site("tip").xpos)
    ours.update(np.array([-0.2]))
    np.testing.assert_array_equal(source.q, [0.4])  # independent afterwards
    np.testing.assert_array_equal(qpik.Configuration(source, np.array([0.1])).q, [0.1])
    with pytest.raises(qpik.InvalidConfiguration):
        qpik.Configuration(source, np.array([np.nan]))
    again = qpik.Configuration(ours)  # a qpik configuration is a mink one: copied the same way
    assert again.data is not ours.data and again.q.tobytes() == ours.q.tobytes()


def _qpik_task(name: str, configuration):
    """One of qpik's own tasks, with a target 2 cm / 0.05 rad away where it has one."""
    T = qpik.tasks
    pose = configuration.get_transform_frame_to_world("ee", "site")
    shifted = mink.SE3.from_translation(np.array([0.02, 0.0, 0.02])) @ pose
    turned = pose @ mink.SE3.from_rotation(mink.SO3.exp(np.array([0.05, 0.0, 0.0])))
    if name == "PositionTask":
        task = T.PositionTask("ee")
        task.set_target(shifted.translation())
    elif name == "OrientationTask":
        task = T.OrientationTask("ee")
        task.set_target(turned.rotation().as_matrix())
    elif name == "PoseTask":
        task = T.PoseTask("ee")
        task.set_target(shifted.translation(), turned.rotation().as_matrix())
    elif name == "FrameTask":
        task = T.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
        task.set_target(shifted)
    elif name == "PostureTask":
        task = T.PostureTask(configuration.model, cost=1.0)
        task.set_target(configuration.model.qpos0)
    elif name == "ComTask":
        task = T.ComTask(cost=1.0)
        task.set_target(np.array([0.05, 0.05, 0.3]))
    elif name == "JointLimitDistanceTask":
        task = T.JointLimitDistanceTask()
    else:
        task = T.ManipulabilityTask("ee")
    return task


@pytest.mark.parametrize(
    "name",
    [
        "PositionTask",
        "OrientationTask",
        "PoseTask",
        "FrameTask",
        "PostureTask",
        "ComTask",
        "JointLimitDistanceTask",
        "ManipulabilityTask",
    ],
)
def test_every_qpik_task_takes_a_mink_configuration(name):
    """Through solve_ik and build_ik, each of qpik's tasks takes mink's configuration and
    gives bitwise what it gives with qpik's."""
    source = _home()
    task = _qpik_task(name, qpik.Configuration(source))
    from_mink = qpik.solve_ik(source, [task], DT, "daqp")
    from_qpik = qpik.solve_ik(qpik.Configuration(source), [task], DT, "daqp")
    assert from_mink.tobytes() == from_qpik.tobytes()
    assert np.isfinite(from_mink).all() and np.abs(from_mink).max() > 0
    built = qpik.build_ik(source, [task], DT)
    np.testing.assert_array_equal(built.P, qpik.build_ik(qpik.Configuration(source), [task], DT).P)


def test_qpik_tasks_accept_a_mink_configuration():
    """qpik's own tasks (world-frame position task) through solve_ik with mink's state."""
    source = _home()
    task = qpik.tasks.PositionTask("ee")
    task.set_target(source.get_transform_frame_to_world("ee", "site").translation() + 0.02)
    from_mink = qpik.solve_ik(source, [task], DT, "daqp")
    from_qpik = qpik.solve_ik(qpik.Configuration(source), [task], DT, "daqp")
    np.testing.assert_array_equal(from_mink, from_qpik)
    assert np.abs(from_mink).max() > 0


# ---------------------------------------------------------------------------- build_ik
def test_build_ik_is_minks_problem_for_a_flat_list():
    model = qpik.load_robot("ur5e")
    configuration = _home()
    tasks = [_frame_task(configuration), _posture(configuration)]
    freeze = mink.DofFreezingTask(model, dof_indices=[0, 1])
    ours = qpik.build_ik(configuration, tasks, DT, constraints=[freeze])
    theirs = mink.build_ik(configuration, tasks, DT, constraints=[freeze])
    assert isinstance(ours, qpsolvers.Problem)
    for field in ("P", "q", "G", "h", "A", "b"):
        np.testing.assert_array_equal(getattr(ours, field), getattr(theirs, field))
    assert ours.A.shape == (2, model.nv)
    no_limits = qpik.build_ik(configuration, tasks, DT, limits=[])
    assert no_limits.G is None and no_limits.h is None and no_limits.A is None


def test_build_ik_problem_solved_independently_gives_solve_iks_answer():
    """quadprog on build_ik's QP gives solve_ik's dq (a flat list away from singularities)."""
    model = qpik.load_robot("ur5e")
    configuration = _home()
    tight = mink.VelocityLimit(model, {model.joint(j).name: 0.3 for j in range(model.njnt)})
    limits = [mink.ConfigurationLimit(model), tight]
    tasks = [_frame_task(configuration, offset=(0.1, -0.1, 0.1)), _posture(configuration)]
    problem = qpik.build_ik(configuration, tasks, DT, limits=limits)
    solution = qpsolvers.solve_problem(problem, solver="quadprog")
    assert solution.found
    np.testing.assert_allclose(
        qpik.solve_ik(configuration, tasks, DT, "daqp", limits=limits) * DT, solution.x, atol=1e-9
    )


def test_build_ik_gives_one_problem_per_level():
    configuration = _home()
    frame, posture = _frame_task(configuration), _posture(configuration)
    problems = qpik.build_ik(configuration, [[frame], [posture]], DT)
    assert isinstance(problems, list) and len(problems) == 2
    np.testing.assert_array_equal(problems[0].P, mink.build_ik(configuration, [frame], DT).P)
    np.testing.assert_array_equal(problems[1].q, mink.build_ik(configuration, [posture], DT).q)
    assert isinstance(qpik.build_ik(configuration, [], DT), qpsolvers.Problem)


# ------------------------------------------------------------------- one-import switch
def test_mink_loop_converges_with_qpik_patched_in(monkeypatch):
    """mink's own convergence pattern (a frame task reached in under 20 steps, error
    strictly decreasing) with ``mink.solve_ik`` and ``mink.Configuration`` replaced."""
    monkeypatch.setattr(mink, "solve_ik", qpik.solve_ik)
    monkeypatch.setattr(mink, "Configuration", qpik.Configuration)
    model = qpik.load_robot("ur5e")
    configuration = mink.Configuration(model)
    configuration.update_from_keyframe("home")
    assert isinstance(configuration, qpik.Configuration)
    task = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    start = configuration.get_transform_frame_to_world("ee", "site")
    task.set_target(start @ mink.SE3.from_translation(np.array([0.0, 0.0, 0.1])))  # local z
    limits = [
        mink.ConfigurationLimit(model),
        mink.VelocityLimit(model, {model.joint(j).name: np.pi for j in range(6)}),
    ]
    dt, last, steps = 5e-3, np.inf, 0
    velocity = mink.solve_ik(configuration, [task], dt, "daqp", limits=limits)
    while steps < 50:
        error = np.linalg.norm(task.compute_error(configuration))
        if error < 1e-6 and np.allclose(velocity, 0.0, atol=1e-4):
            break
        assert error < last
        last = error
        configuration.integrate_inplace(velocity, dt)
        velocity = mink.solve_ik(configuration, [task], dt, "daqp", limits=limits)
        steps += 1
    assert steps < 20
    assert np.linalg.norm(task.compute_error(configuration)) < 1e-6


def test_a_dt_so_small_that_the_velocity_overflows_is_named():
    configuration = _home()
    task = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    task.set_target(mink.SE3.from_translation(np.array([0.3, 0.1, 0.2])))
    with pytest.raises(qpik.InvalidInput, match="dt"):
        qpik.solve_ik(configuration, [task], 5e-324, "daqp", limits=[])


def test_build_ik_states_the_limits_qpik_enforces_outside_the_limits():
    """Started 0.1 rad beyond a limit with a velocity cap too slow to get back in one step,
    mink's QP is infeasible; build_ik's rows are the recovered ones, and solving them with
    quadprog gives solve_ik's step (back toward the limit at the cap)."""
    model = qpik.load_robot("ur5e")
    configuration = _home()
    q = configuration.q
    q[0] = model.jnt_range[0, 1] + 0.1
    configuration.update(q)
    cap = mink.VelocityLimit(model, {model.joint(j).name: 1.0 for j in range(model.njnt)})
    limits = [mink.ConfigurationLimit(model), cap]
    tasks = [_frame_task(configuration), _posture(configuration)]
    theirs = qpsolvers.solve_problem(
        mink.build_ik(configuration, tasks, DT, limits=limits), "quadprog"
    )
    assert not theirs.found
    problem = qpik.build_ik(configuration, tasks, DT, limits=limits)
    solution = qpsolvers.solve_problem(problem, solver="quadprog")
    assert solution.found
    v = qpik.solve_ik(configuration, tasks, DT, "daqp", limits=limits)
    np.testing.assert_allclose(v * DT, solution.x, atol=1e-9)
    assert v[0] == pytest.approx(-1.0, abs=1e-12)


def test_tasks_limits_and_constraints_may_be_any_iterables():
    """mink iterates over its arguments; tuples and generators give the list's answer."""
    model = qpik.load_robot("ur5e")
    configuration = _home()
    task = _frame_task(configuration)
    freeze = mink.DofFreezingTask(model, dof_indices=[0])
    as_lists = qpik.solve_ik(
        configuration,
        [task],
        DT,
        "daqp",
        limits=[mink.ConfigurationLimit(model)],
        constraints=[freeze],
    )
    as_generators = qpik.solve_ik(
        configuration,
        (t for t in [task]),
        DT,
        "daqp",
        limits=(limit for limit in [mink.ConfigurationLimit(model)]),
        constraints=(c for c in (freeze,)),
    )
    assert as_lists.tobytes() == as_generators.tobytes()
    assert isinstance(qpik.build_ik(configuration, (t for t in [task]), DT), qpsolvers.Problem)


# ------------------------------------------------------------ benchmarks/mink_suite.py
def _mink_suite_module():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "benchmarks" / "mink_suite.py"
    spec = importlib.util.spec_from_file_location("mink_suite", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module, path


def test_mink_suite_example_child_has_no_undefined_name(tmp_path):
    """The example scripts' child program is a string in benchmarks/mink_suite.py (no lint
    reaches it): ruff's undefined-name check on it as a file. A leftover of an earlier
    change (``xr, mult = z[:n], z[n:]`` in explain()) raised NameError on every state where
    the two answers differed, and mink's humanoid_g1 example could not run."""
    import shutil
    import subprocess

    ruff = shutil.which("ruff")
    if ruff is None:
        pytest.skip("ruff is not installed (the dev extra)")
    child = tmp_path / "_run_example.py"
    child.write_text(_mink_suite_module()[0]._EXAMPLE_CHILD)
    done = subprocess.run(
        [ruff, "check", "--no-cache", "--isolated", "--select", "F821,F841", str(child)],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stdout + done.stderr


def test_mink_suite_reads_junit_outcomes(tmp_path):
    module, _ = _mink_suite_module()
    report = tmp_path / "report.xml"
    report.write_text(
        '<testsuites><testsuite name="pytest">'
        '<testcase classname="test_a.TestA" name="test_ok"/>'
        '<testcase classname="test_a.TestA" name="test_bad"><failure message="AssertionError: 1 != 2">'
        "trace</failure></testcase>"
        '<testcase classname="test_a.TestA" name="test_model"><skipped message="needs a downloaded '
        'model: ur5e_mj_description"/></testcase>'
        "</testsuite></testsuites>"
    )
    assert module._outcomes(report) == {
        "test_a.TestA::test_ok": ("passed", ""),
        "test_a.TestA::test_bad": ("failed", "AssertionError: 1 != 2"),
        "test_a.TestA::test_model": ("skipped", "needs a downloaded model: ur5e_mj_description"),
    }


def test_mink_suite_serves_a_linked_model_from_its_own_folder(tmp_path, monkeypatch):
    """--models DIR holds links (``DIR/<name>.xml`` -> a Menagerie folder's model): the model
    is opened at the link's target, so that the files it names relative to itself (meshes in
    ``assets/``) are found; a name without a file is a skip, not an error."""
    import os
    import sys
    import unittest

    module, _ = _mink_suite_module()
    robot = tmp_path / "robot"
    (robot / "assets").mkdir(parents=True)
    (robot / "assets" / "tet.obj").write_text(module._TETRAHEDRON_OBJ)
    (robot / "robot.xml").write_text(
        '<mujoco><compiler meshdir="assets"/><asset><mesh file="tet.obj"/></asset>'
        '<worldbody><body><joint/><geom type="mesh" mesh="tet"/></body></worldbody></mujoco>'
    )
    models = tmp_path / "models"
    models.mkdir()
    os.symlink(robot / "robot.xml", models / "robot_mj_description.xml")
    monkeypatch.setenv("QPIK_MINK_PATCH", "0")
    monkeypatch.setenv("QPIK_MINK_MODELS", str(models))
    for name in ("robot_descriptions", "robot_descriptions.loaders",
                 "robot_descriptions.loaders.mujoco"):  # fmt: skip
        monkeypatch.setitem(sys.modules, name, None)  # restored after the test
    exec(module._PLUGIN, {"__name__": "qpik_mink_plugin"})
    load = sys.modules["robot_descriptions.loaders.mujoco"].load_robot_description
    model = load("robot_mj_description")
    assert (model.nmesh, model.njnt) == (1, 1)
    with pytest.raises(unittest.SkipTest, match="needs a downloaded model: absent_mj"):
        load("absent_mj_description")


@pytest.mark.slow
def test_mink_suite_runs_a_suite_stock_and_patched(tmp_path):
    """End to end on a three-test suite in mink's style: one test passes only with qpik
    patched in, one needs a downloaded model, one passes in both runs."""
    import subprocess
    import sys

    pytest.importorskip("absl")
    _, script = _mink_suite_module()
    (tmp_path / "test_style.py").write_text(
        "import unittest\n"
        "import mujoco\n"
        "import numpy as np\n"
        "import mink\n"
        "from robot_descriptions.loaders.mujoco import load_robot_description\n\n\n"
        "class TestStyle(unittest.TestCase):\n"
        "    def test_patched(self):\n"
        "        self.assertEqual(mink.solve_ik.__module__, 'qpik.diffik.mink_compat')\n\n"
        "    def test_model(self):\n"
        "        load_robot_description('ur5e_mj_description')\n\n"
        "    def test_both(self):\n"
        "        model = mujoco.MjModel.from_xml_string(\n"
        '            \'<mujoco><worldbody><body><joint range="-1 1"/><geom size=".1"/>\'\n'
        "            '</body></worldbody></mujoco>')\n"
        "        v = mink.solve_ik(mink.Configuration(model), [], 0.01, 'daqp')\n"
        "        np.testing.assert_array_equal(v, [0.0])\n"
    )
    run = subprocess.run(
        [sys.executable, str(script), "--tests", str(tmp_path)], capture_output=True, text=True
    )
    assert run.returncode == 0, run.stdout + run.stderr
    lines = run.stdout.splitlines()
    assert any(line.split()[:3] == ["stock", "mink", "1"] for line in lines), run.stdout
    assert any(line.split()[:4] == ["mink", "+", "qpik", "2"] for line in lines), run.stdout
    assert "needs a downloaded model (skipped in both runs): 1 tests" in run.stdout
    assert (
        "pass with qpik only: 1" in run.stdout
        and "test_style.TestStyle::test_patched" in run.stdout
    )


def test_free_joint_velocity_limit_composes_with_velocity_limit():
    """mink's own test_free_joint_velocity_limit scenario (its one failure under qpik
    before): a hand pulled 17 m away on a floating humanoid, the base twist capped in the
    base frame and every other joint at pi rad/s, daqp named; each step keeps both caps."""
    pytest.importorskip("daqp")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = qpik.load_robot("erd:talos", floating_base=True)
    configuration = mink.Configuration(model)
    configuration.update(model.key_qpos[0] if model.nkey else model.qpos0)
    task = mink.FrameTask("gripper_left_base_link", "body", 1.0, 1.0)
    task.set_target(mink.SE3.from_translation(np.array([10.0, 10.0, 10.0])))
    base = mink.FreeJointVelocityLimit(model, 1.0, 2.0)
    names = [model.joint(i).name for i in range(1, model.njnt)]
    joints = mink.VelocityLimit(model, dict.fromkeys(names, np.pi))
    for _ in range(8):
        v = qpik.solve_ik(configuration, [task], 1e-2, "daqp", limits=[base, joints])
        R = configuration.data.xmat[base.base_body_id].reshape(3, 3)
        assert np.abs(R.T @ v[:3]).max() <= 1.0 + 1e-6
        assert np.abs(v[3:6]).max() <= 2.0 + 1e-6
        assert np.abs(v[joints.indices]).max() <= np.pi + 1e-6
        configuration.integrate_inplace(v, 1e-2)


# ---------------------------------------------------- build_ik's QP is solve_ik's (issue 20)
def _single_level_cases():
    """Single-level stacks whose QP is well conditioned (cond(P) ~ 1e4..1e8): a frame task
    with a posture task on the Panda (limits binding or not), a frame task alone on the
    6-dof UR5e (square Jacobian)."""
    panda = _home("panda")
    ur5e = _home("ur5e")
    tight = mink.VelocityLimit(
        panda.model, {panda.model.joint(j).name: 0.2 for j in range(7)}
    )  # fmt: skip
    far = _frame_task(panda, offset=(0.1, -0.1, 0.1))
    return [
        (panda, [_frame_task(panda), _posture(panda)], []),
        (panda, [far, _posture(panda)], [mink.ConfigurationLimit(panda.model), tight]),
        (ur5e, [_frame_task(ur5e)], None),
    ]


@pytest.mark.parametrize("backend", ["daqp", "quadprog"])
@pytest.mark.parametrize("case", range(3))
def test_build_ik_qp_solved_by_a_backend_is_solve_iks_step(case, backend):
    """build_ik's QP, solved by daqp or quadprog, gives solve_ik's dq to 1e-9 relative on
    single-level stacks (the QP is mink's, bitwise, and solve_ik solves that QP)."""
    pytest.importorskip(backend)
    configuration, tasks, limits = _single_level_cases()[case]
    problem = qpik.build_ik(configuration, tasks, DT, limits=limits)
    solution = qpsolvers.solve_problem(problem, solver=backend)
    assert solution.found
    dq = qpik.solve_ik(configuration, tasks, DT, backend, limits=limits) * DT
    np.testing.assert_allclose(solution.x, dq, rtol=0, atol=1e-9 * np.abs(dq).max())
    assert np.linalg.cond(problem.P) < 1e9


def test_build_ik_ill_conditioned_qp_is_solve_iks_to_its_condition():
    """issue 20's 7.7e-5: a frame task alone on the 7-dof Panda with mink's damping 1e-12
    has cond(P) ~ 3e12. Its P is mink's bitwise and solve_ik's dq is that QP's minimiser
    (to 1e-12, from the same rows), but P itself, rounded to doubles, fixes the minimiser
    only to ~cond(P) eps in the redundant direction: backends on P agree with solve_ik in
    task space (what P determines well) and differ from it, and from each other, along
    the one null direction of the Jacobian, by up to cond(P) eps relative."""
    configuration = _home("panda")
    tasks = [_frame_task(configuration, offset=(0.05, -0.1, 0.08))]
    problem = qpik.build_ik(configuration, tasks, DT, limits=[])
    np.testing.assert_array_equal(problem.P, mink.build_ik(configuration, tasks, DT, limits=[]).P)
    condition = np.linalg.cond(problem.P)
    assert condition > 1e11
    dq = qpik.solve_ik(configuration, tasks, DT, "daqp", limits=[]) * DT
    # The minimiser of |A dq - b|^2 + damping |dq|^2 from the rows themselves (the stacked
    # least-squares system: condition sqrt(cond P), so accurate to ~1e-10).
    ik, _ = qpik.diffik.mink_compat._solver(
        qpik.diffik.mink_compat.as_configuration(configuration), tasks, None, 1e-12, [], None, {}
    )
    level = ik.build(qpik.diffik.mink_compat.as_configuration(configuration), DT).levels[0]
    nv = configuration.model.nv
    stacked = np.vstack([level.A, np.sqrt(level.regularization) * np.eye(nv)])
    exact = np.linalg.lstsq(stacked, np.concatenate([level.b, np.zeros(nv)]), rcond=None)[0]
    np.testing.assert_allclose(dq, exact, rtol=0, atol=1e-9 * np.abs(dq).max())
    J = level.A
    for backend in ("daqp", "quadprog"):
        if importlib.util.find_spec(backend) is None:
            continue
        x = qpsolvers.solve_problem(problem, solver=backend).x
        assert np.linalg.norm(x - dq) <= 10 * condition * np.finfo(float).eps * np.linalg.norm(dq)
        if backend == "quadprog":  # exact on P's range (daqp stops at its own tolerance)
            np.testing.assert_allclose(J @ x, J @ dq, rtol=0, atol=1e-9 * np.abs(J @ dq).max())


@pytest.mark.parametrize("rotated", [False, True])
def test_free_joint_velocity_limit_composes_with_velocity_limit_on_g1(rotated):
    """mink 1.3's test_composes_with_velocity_limit (and test_solve_respects_limit) on the
    bundled G1 at its "stand" keyframe, base yawed by 90 degrees or not: the base's
    linear rows are one-dof box rows while the base is unrotated and general rows once
    it turns; with daqp named, every step keeps the base and joint caps."""
    pytest.importorskip("daqp")
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "data" / "menagerie" / "g1.xml"
    model = mujoco.MjModel.from_xml_path(str(path))
    configuration = mink.Configuration(model)
    configuration.update_from_keyframe("stand")
    if rotated:
        q = configuration.q.copy()
        q[3:7] = [np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)]
        configuration.update(q)
    task = mink.FrameTask("left_six_link", "body", 1.0, 1.0)
    task.set_target(mink.SE3.from_translation(np.array([10.0, 10.0, 10.0])))
    base = mink.FreeJointVelocityLimit(model, 1.0, 2.0)
    names = [model.joint(i).name for i in range(1, model.njnt)]
    joints = mink.VelocityLimit(model, dict.fromkeys(names, np.pi))
    for _ in range(8):
        v = qpik.solve_ik(configuration, [task], 1e-2, "daqp", limits=[base, joints])
        R = configuration.data.xmat[base.base_body_id].reshape(3, 3)
        assert np.abs(R.T @ v[:3]).max() <= 1.0 + 1e-6
        assert np.abs(v[3:6]).max() <= 2.0 + 1e-6
        assert np.abs(v[joints.indices]).max() <= np.pi + 1e-6
        configuration.integrate_inplace(v, 1e-2)


def test_levels_in_new_lists_take_the_kept_solver(rng):
    """A call that writes its levels as new lists each time (``[[task], [posture]]``, the
    README's form) is served by the kept solver's fast path, keyed by the tasks level by
    level, and answers bitwise as the full path; a flat list of the same tasks (one level)
    is another solver."""
    from qpik.diffik.mink_compat import SOLVERS

    configuration = _home()
    task = _frame_task(configuration)
    posture = mink.PostureTask(configuration.model, cost=1e-2)
    posture.set_target_from_configuration(configuration)
    qpik.clear_caches()
    full = qpik.solve_ik(configuration, [[task], [posture]], DT)
    assert len(SOLVERS) == 1
    for levels in ([[task], [posture]], [task, [posture]], ((task,), [posture])):
        fast = SOLVERS.velocity(configuration, levels, DT, None, 1e-12, None)
        assert fast is not None and np.array_equal(fast, full)
        assert np.array_equal(qpik.solve_ik(configuration, levels, DT), full)
    assert SOLVERS.velocity(configuration, [task, posture], DT, None, 1e-12, None) is None
    assert SOLVERS.velocity(configuration, [[task, posture]], DT, None, 1e-12, None) is None
    assert len(SOLVERS) == 1


def test_constraints_take_the_compiled_step_and_answer_as_before():
    """``constraints``: their rows a level above the tasks' with no damping, mink's damping
    on each task level (mink_compat._constrained_solver), by the compiled step and kept
    between calls; the answer is the cascade's with the constraints' level inserted above
    the tasks' levels (the way solve_ik answered before, by a new core each call: 1.6x
    mink's time a call on mink's arm_panda_dof_freezing example), and mink's to round-off."""
    from qpik.core import HierarchySolver, Level
    from qpik.diffik import mink_compat

    model = qpik.load_robot("panda")
    configuration = mink.Configuration(model)
    frame = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0, lm_damping=1.0)
    posture = mink.PostureTask(model, cost=0.1)
    posture.set_target(model.key_qpos[0])
    freeze = mink.DofFreezingTask(model, dof_indices=[0, 1, 2])
    rng = np.random.default_rng(5)
    qpik.clear_caches()
    for turn in range(30):
        q = model.key_qpos[0] + rng.uniform(-0.8, 0.8, model.nq)
        configuration.update(np.clip(q, model.jnt_range[:, 0], model.jnt_range[:, 1]))
        pose = configuration.get_transform_frame_to_world("ee", "site")
        frame.set_target(pose.multiply(mink.SE3.exp(rng.normal(size=6) * 0.3)))
        damping = (1e-3, 1e-12)[turn % 2]
        constraints = [freeze] if turn % 3 else []  # (toggled, as the example does)
        velocity = qpik.solve_ik(configuration, [frame, posture], DT, "daqp", damping,
                                 constraints=constraints)  # fmt: skip
        theirs = mink.solve_ik(configuration, [frame, posture], DT, "daqp", damping,
                               constraints=constraints)  # fmt: skip
        np.testing.assert_allclose(velocity, theirs, rtol=0, atol=1e-9)
        if not constraints:
            continue
        assert np.all(velocity[:3] == 0.0)  # the frozen dofs, exactly
        own = mink_compat.as_configuration(configuration)
        ik = mink_compat._constrained_solver(
            own, [frame, posture], "daqp", damping, None, [freeze], {}
        )  # fmt: skip
        assert ik.compiled_velocity(own, DT) is not None  # (the compiled step applies)
        # the former answer: the tasks' problem with the constraints' unit rows above
        plain = mink_compat._new_solver(own, [[frame, posture]], "daqp", damping, None, {})
        problem = plain.build(own, DT)
        A, b = constraints_module.equality_rows(own, [freeze], model.nv)
        problem.levels.insert(0, Level(A, b, 0.0, None, "constraints"))
        reference = HierarchySolver("daqp", damping_law=plain.damping_law).solve(problem)
        np.testing.assert_allclose(velocity, reference.x / DT, rtol=0, atol=1e-10)
    assert mink_compat.SOLVERS.constraint_tasks
    qpik.clear_caches()
    assert not mink_compat.SOLVERS.constraint_tasks
    for _ in range(3):  # no task (the smallest displacement): one solver, kept
        velocity = qpik.solve_ik(configuration, [], DT, "daqp", constraints=[freeze])
        theirs = mink.solve_ik(configuration, [], DT, "daqp", constraints=[freeze])
        np.testing.assert_allclose(velocity, theirs, rtol=0, atol=1e-12)
    assert len(mink_compat.SOLVERS) == 1 and len(mink_compat.SOLVERS.constraint_tasks) == 1


@pytest.mark.parametrize("frame_type", ["site", "body", "geom"])
def test_frame_task_constraint_rows_by_the_engine_are_minks(rng, frame_type):
    """A mink FrameTask (or qpik's) held as a constraint has its equalities made by the
    engine (constraints._frame_rows: frame_terms and frame_rows_into with unit costs), the
    rows of mink's own compute_jacobian and compute_error to round-off, on random
    configurations and targets; a subclass of mink's keeps its own methods."""
    model = qpik.load_robot("panda")
    name = {"site": "ee", "body": "hand", "geom": model.geom(model.ngeom - 1).name}[frame_type]
    configuration = qpik.Configuration(model)
    lower, upper = configuration.lower, configuration.upper
    for cls in (mink.FrameTask, qpik.tasks.FrameTask):
        task = cls(name, frame_type, position_cost=1.0, orientation_cost=1.0, gain=0.7)
        task.set_target_from_configuration(configuration)
        rows = constraints_module.ConstraintRows([task], configuration)
        for _ in range(20):
            configuration.update(rng.uniform(lower, upper))
            pose = configuration.get_transform_frame_to_world(name, frame_type)
            task.set_target(pose @ mink.SE3.exp(rng.uniform(-0.3, 0.3, 6)))
            A, b, mu, weights = rows.rows_now(configuration)
            J = mink.FrameTask.compute_jacobian(task, configuration)
            e = mink.FrameTask.compute_error(task, configuration)
            norms = np.linalg.norm(J, axis=1)
            np.testing.assert_allclose(A, J / norms[:, None], rtol=0, atol=1e-12)
            np.testing.assert_allclose(b, -0.7 * e / norms, rtol=0, atol=1e-12 * (1 + abs(b).max()))
            # (weights UNDAMPED_WEIGHT: their rank judged as with 1, no adaptive damping)
            assert mu is None and np.array_equal(
                weights, np.full(6, constraints_module.UNDAMPED_WEIGHT)
            )

    class Shifted(mink.FrameTask):  # its own error: the engine's rows must not be taken
        def compute_error(self, configuration):
            return super().compute_error(configuration) + 1.0

    task = Shifted(name, frame_type, position_cost=1.0, orientation_cost=1.0)
    task.set_target(configuration.get_transform_frame_to_world(name, frame_type))
    A, b, _, _ = constraints_module.ConstraintRows([task], configuration).rows_now(configuration)
    J = mink.FrameTask.compute_jacobian(task, configuration)
    np.testing.assert_allclose(
        b, -1.0 * task.compute_error(configuration) / np.linalg.norm(J, axis=1)
    )


@pytest.mark.parametrize("solver", [None, "daqp"])
def test_constraints_near_a_singularity_are_held_exactly(solver):
    """Audit (mink at every level): constraints= are held exactly, with no damping, as the
    docs say; a mink FrameTask as the constraint at a Panda configuration where its unit
    rows' smallest singular value is 0.0165 (below the damping law's 0.05) got the adaptive
    damping (2.2e-3), and the constraint was missed by 1.27e-2 of |b| 3e-2 while mink's QP,
    solved exactly, meets it. qpik now meets it to round-off, as quadprog on mink's QP."""
    import qpsolvers

    model = qpik.load_robot("panda")
    q = [0.7142743740176092, -0.7304759657586889, -2.3938873363793935, -2.8770456343290203,
         1.6337481552629087, 3.2679796737033096, 0.5561204996344504]  # fmt: skip
    configuration = mink.Configuration(model)
    configuration.update(np.array(q))
    frame = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    offset = mink.SE3.exp(np.array([0.01, -0.02, 0.015, 0.02, 0.01, -0.03]))
    frame.set_target(configuration.get_transform_frame_to_world("ee", "site") @ offset)
    posture = mink.PostureTask(model, cost=0.1)
    posture.set_target(model.key_qpos[0])
    problem = mink.build_ik(
        configuration, [posture], 0.01, damping=1e-3, limits=[], constraints=[frame]
    )
    exact = qpsolvers.solve_problem(problem, solver="quadprog").x
    assert np.abs(problem.A @ exact - problem.b).max() < 1e-14
    qpik.clear_caches()
    velocity = qpik.solve_ik(
        configuration, [posture], 0.01, solver, damping=1e-3, limits=[], constraints=[frame]
    )
    assert np.abs(problem.A @ (velocity * 0.01) - problem.b).max() < 1e-14
    np.testing.assert_allclose(velocity * 0.01, exact, atol=1e-10)


def test_an_objective_whose_linear_term_leaves_h_range_is_refused():
    """Audit (mink at every level): a task of one's own that gives only mink's objective
    (H, c), with c partly outside H's range (H = diag(1, 0, ...), c = (-2e-3, -1e-3, 0, ...);
    or H = 0, a pure gradient step), lost that part of c silently: qpik answered v_1 = 0
    where mink's QP, solved exactly, gives 10. A level of least squares cannot hold such a
    term: TaskDefinitionError naming the task, on every path; an H that covers c still
    answers mink's exact optimum."""
    import qpsolvers

    class Bias(mink.tasks.BaseTask):
        def __init__(self, full: bool):
            self.full = full

        def compute_qp_objective(self, configuration):
            nv = configuration.model.nv
            H = np.eye(nv) if self.full else np.diag([1.0] + [0.0] * (nv - 1))
            c = np.zeros(nv)
            c[0], c[1] = -2e-3, -1e-3
            return mink.Objective(H, c)

    model = qpik.load_robot("panda")
    configuration = mink.Configuration(model)
    configuration.update(model.key_qpos[0])
    for solver in (None, "daqp"):
        qpik.clear_caches()
        with pytest.raises(qpik.errors.TaskDefinitionError, match="Bias.*outside H's range"):
            qpik.solve_ik(configuration, [Bias(False)], 0.01, solver, damping=1e-2)
    with pytest.raises(qpik.errors.TaskDefinitionError, match="Bias"):
        qpik.IKSolver(model, [[Bias(False)]]).step(qpik.Configuration(model), 0.01)
    problem = mink.build_ik(configuration, [Bias(True)], 0.01, damping=1e-2)
    exact = qpsolvers.solve_problem(problem, solver="quadprog").x / 0.01
    velocity = qpik.solve_ik(configuration, [Bias(True)], 0.01, damping=1e-2)
    np.testing.assert_allclose(velocity, exact, atol=1e-9)


def test_active_limits_name_each_dof_of_a_multi_dof_joint():
    """Audit (API): on the floating Talos with its six base dofs at the trust region,
    active_limits held 'root_joint upper (trust region)' three times and '... lower' three
    times, not saying which dof binds; a joint of several dofs is named per dof now,
    'root_joint[k]', on the compiled step and the QP path alike (the same names)."""
    import warnings

    from qpik.tasks import ComTask

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = qpik.load_robot("erd:talos", floating_base=True)
    configuration = qpik.Configuration(model, model.key("half_sitting").qpos)
    com = ComTask(cost=1.0, gain=1.0)
    com.set_target(configuration.data.subtree_com[1] + np.array([1.0, 1.0, 1.0]))
    names = []
    for solver in ("auto", "quadprog"):
        step = qpik.IKSolver(model, [[com]], solver=solver).step(configuration, 0.01)
        root = [name for name in step.active_limits if name.startswith("root_joint")]
        assert root and len(root) == len(set(root))
        assert all(name.startswith("root_joint[") for name in root)
        names.append(step.active_limits)
    assert names[0] == names[1]


def test_free_joint_linear_rows_are_minks_bitwise(rng):
    """The free joint's linear rows, made by the engine (_engine.limits.free_joint_rows), are
    mink's FreeJointVelocityLimit rows bit for bit (signs of zero included) at random base
    orientations, bounds and steps; an attribute the engine does not take (float dofs) is
    answered by NumPy's way, as before."""
    from qpik.diffik.mink_limits import FreeJointLinear

    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="base")
    body.add_freejoint()
    body.add_geom(size=[0.1, 0.1, 0.1], type=mujoco.mjtGeom.mjGEOM_BOX)
    arm = body.add_body(name="arm", pos=[0, 0, 0.2])
    arm.add_joint(name="hinge", axis=[0, 1, 0])
    arm.add_geom(size=[0.05, 0.2, 0], type=mujoco.mjtGeom.mjGEOM_CAPSULE)
    model = spec.compile()
    configuration = mink.Configuration(model)
    lin = np.r_[0:3, 6:9]  # (mink's rows: linear then angular, twice)
    for trial in range(200):
        q = configuration.q.copy()
        q[3:7] = rng.normal(size=4) * (trial % 7 != 0)  # (an identity base too)
        q[3:7] = q[3:7] / np.linalg.norm(q[3:7]) if q[3:7].any() else [1, 0, 0, 0]
        configuration.update(q)
        limit = mink.FreeJointVelocityLimit(
            model, max_linear_velocity=float(rng.uniform(0.01, 2.0)), max_angular_velocity=0.3
        )
        dt = float(rng.uniform(1e-3, 0.1))
        ref = limit.compute_qp_inequalities(configuration, dt)
        G, h = FreeJointLinear(limit)._rows(configuration, dt)
        for ours, theirs in ((G, ref.G[lin]), (h, ref.h[lin])):
            np.testing.assert_array_equal(ours, theirs)
            np.testing.assert_array_equal(np.signbit(ours), np.signbit(theirs))
    limit._lin_dofs = limit._lin_dofs.astype(float)  # (NumPy's way: its IndexError)
    with pytest.raises(IndexError):
        FreeJointLinear(limit)._rows(configuration, dt)
