"""Regression tests of what the fuzz campaigns of issue 25 found after seed 99 (seeds 31337,
2027, 5150 and the two leftovers of seed 99): one test per class, each checking the class's
property (a typed error naming the argument the bad value came in, every returned figure
finite or documented), cheap enough for the default run.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import qpik
from qpik import statics


# --------------------------------------------------------------------------------------
# Class (seed 99, signature:774): solve_many(robot=Configuration outside its limits) named
# q0, an argument the caller never passed; the error names the robot, as qpik.solve does.
@pytest.mark.parametrize("workers", [1, 2])
def test_solve_many_names_the_robot_whose_q_is_outside(workers: int) -> None:
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, np.zeros(model.nq))  # joint4 range < 0
    targets = [{"ee": np.array([0.4, 0.0, 0.5])}] * 2
    with pytest.raises(qpik.JointLimitViolation, match="^robot") as caught:
        qpik.solve_many(configuration, targets, workers=workers)
    assert caught.value.where.startswith("robot")
    with pytest.raises(qpik.JointLimitViolation, match="^robot"):
        qpik.solve(configuration, targets[0])
    with pytest.raises(qpik.JointLimitViolation, match="^q0"):  # an explicit q0 is q0
        qpik.solve_many(model, targets, q0=np.zeros(model.nq), workers=1)


def test_solve_many_starts_from_the_robot_q_as_solve_does() -> None:
    model = qpik.load_robot("panda")
    mid = model.jnt_range.mean(axis=1)
    configuration = qpik.Configuration(model, mid + 0.1)
    target = {"ee": np.array([0.4, 0.1, 0.5])}
    batch = qpik.solve_many(configuration, [target], workers=1, seed=3)
    seed = qpik.batch.worker.target_seed(3, 0)
    single = qpik.solve(configuration, target, seed=seed)
    assert np.array_equal(batch[0].q, single.q)


# --------------------------------------------------------------------------------------
# Class (seed 99, reading): PayloadLimit.force was NaN when no magnitude s >= 0 can be
# held. It is 0.0 then (feasible false); +inf only where no limit binds (documented).
def test_infeasible_payload_is_zero_not_nan() -> None:
    model = qpik.load_robot("ur5e")  # the motors hold its weight: nothing holds it with 0
    configuration = qpik.Configuration(model, np.array([0.0, -1.0, 1.0, 0.0, 0.5, 0.0]))
    weak = statics.max_payload(configuration, "ee", [0.0, 0.0, -1.0], np.zeros((model.nv, 2)))
    assert weak.force == 0.0 and not weak.feasible and not weak.holds_gravity
    assert not any(math.isnan(x) for x in weak.interval)
    strong = statics.max_payload(configuration, "ee", [0.0, 0.0, -1.0])
    assert strong.feasible and 0.0 < strong.force < math.inf


# --------------------------------------------------------------------------------------
# Class (erd category, seed 1): a task on a frame no dof moves (a fixed robot's base
# body: a zero Jacobian) with a damped level was reported numerical_failure and solve_ik
# raised NoSolutionFound: x = 0 is optimal, but the least-squares round-off of b through
# the regularisation rows (eps sqrt(rho) |b|) was measured against a zero scale.
def test_zero_jacobian_level_is_solved() -> None:
    n = 4
    for rho in (0.0, 1e-12, 1e-6, 1.0):
        level = qpik.core.Level(np.zeros((3, n)), np.array([1.0, -2.0, 0.5]), rho)
        inf = np.full(n, np.inf)
        problem = qpik.core.HierarchyProblem([level], -inf, inf, np.zeros((0, n)), np.zeros(0))
        result = qpik.core.HierarchySolver().solve(problem)
        assert [str(s) for s in result.status] == ["solved"], (rho, result.certificate)
        assert np.abs(result.x).max() <= 1e-9
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.jnt_range.mean(axis=1))
    base = qpik.tasks.PositionTask("link0", "body")
    base.set_target(np.array([0.5, 0.0, 0.0]))
    posture = qpik.tasks.PostureTask(model, cost=0.01)
    posture.set_target_from_configuration(configuration)
    limits = [qpik.limits.ConfigurationLimit(model, gain=0.95)]
    step = qpik.IKSolver(model, [[base], [posture]], limits).step(configuration, 0.01)
    assert [str(s) for s in step.status] == ["solved", "solved"]
    v = qpik.solve_ik(configuration, [[base], [posture]], 0.01, limits=limits)
    assert np.isfinite(v).all() and np.abs(v).max() <= 1e-9


# --------------------------------------------------------------------------------------
# Class (seed 31337, signature:429/826/621): a task constructor's number of a wrong type
# (an MjModel or a function as cost, bytes as axis) was blamed on the costs in general
# ("float() argument" read as a signature mismatch) or on another argument whose value
# the message quoted ('ee' inside b'ee'); the argument is named.
@pytest.mark.parametrize(
    ("make", "name"),
    [
        (lambda m: qpik.tasks.JointLimitDistanceTask(cost=m), "cost"),
        (lambda m: qpik.tasks.PositionTask("ee", cost=lambda: 1.0), "cost"),
        (lambda m: qpik.tasks.ManipulabilityTask("ee", gain=m), "gain"),
        (lambda m: qpik.tasks.ComTask(lm_damping=m), "lm_damping"),
        (lambda m: qpik.tasks.ComTask(cost=m), "cost"),
        (lambda m: qpik.tasks.LookAtTask("ee", "site", axis=b"ee"), "axis"),
        (lambda m: qpik.tasks.OrientationTask("ee", cost=[1.0, 2.0]), "cost"),
        (lambda m: qpik.tasks.PoseTask("ee", position_cost=[1.0, 2.0]), "position_cost"),
        (lambda m: qpik.tasks.DampingTask(m, cost="x"), "cost"),
    ],
)
def test_task_number_of_a_wrong_type_is_named(make, name: str) -> None:
    model = qpik.load_robot("panda")
    with pytest.raises(qpik.QpikError, match=f"argument {name} ") as caught:
        make(model)
    assert isinstance(caught.value, (TypeError, ValueError))


# --------------------------------------------------------------------------------------
# Class (erd category, seed 1): on a floating base a start outside the limits was refused
# without saying it was q0 (the fixed-base path names it).
def test_floating_base_start_outside_names_q0(tmp_path) -> None:
    xml = tmp_path / "arm.xml"
    xml.write_text(
        '<mujoco><worldbody><body name="base"><geom size="0.1"/><body name="b">'
        '<joint name="j" range="0.5 1"/><geom size="0.1"/><site name="ee" pos="0.3 0 0"/>'
        "</body></body></worldbody></mujoco>"
    )
    model = qpik.load_robot(str(xml), floating_base=True)
    q0 = model.qpos0.copy()  # j = 0, below its range
    assert model.nq == 8
    with pytest.raises(qpik.JointLimitViolation, match="^q0: joint 'j'"):
        qpik.solve(model, {"ee": [0.3, 0.0, 0.0]}, q0=q0)


# --------------------------------------------------------------------------------------
# Class (signature, new targets): public functions the campaign had not called with wrong
# types let Python's errors out (AttributeError 'njnt' / 'neq' / 'model', ValueError on
# an array's truth value, matmul on a string): each argument is checked where it enters,
# by qpik.core.checks, and named.
def _wrong_calls():
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model)
    return [
        (lambda: qpik.limits.BallJointLimit(np.zeros(3)), "MjModel"),
        (lambda: qpik.limits.limited_ball_joints("panda"), "model"),
        (lambda: qpik.limits.collision_geoms(model, robot_only=np.ones(2)), "robot_only"),
        (lambda: qpik.limits.geom_distance(np.zeros(3), 0, 1), "configuration"),
        (lambda: qpik.limits.geom_distance(configuration, b"ee", 1), "geom1"),
        (lambda: qpik.limits.geom_distance(configuration, 0, np.nan), "geom2"),
        (lambda: qpik.limits.geom_distance(configuration, 0, 1, cap="x"), "cap"),
        (lambda: qpik.analysis.orientation_error("x", np.eye(3)), "R_current"),
        (lambda: qpik.analysis.orientation_error(np.eye(3), np.eye(2)), "R_target"),
        (lambda: configuration.check_limits(safety_break=np.ones(2)), "safety_break"),
        (lambda: configuration.within_limits(tol=np.ones(3)), "tol"),
        (lambda: qpik.tasks.CouplingTask(model, cost=None), "cost"),
        (lambda: qpik.tasks.CouplingTask(np.zeros(3)), "model"),
        (lambda: qpik.tasks.EqualityConstraintTask(model, 1.0, gain={1}), "gain"),
        (lambda: qpik.tasks.EqualityConstraintTask(model, 1.0, equalities=b"x"), "equalities"),
        # seed 2027, signature:638 and :605: a ragged nesting, a 0-d array of row indices
        (lambda: qpik.limits.model_collision_limit(model, geoms=[[0, [1]], 2]), "geoms"),
        (lambda: qpik.statics.force_ellipsoid(configuration, "ee", rows=np.array(1)), "rows"),
    ]


@pytest.mark.parametrize("index", range(17))
def test_public_function_names_a_wrong_argument(index: int) -> None:
    call, name = _wrong_calls()[index]
    with pytest.raises(qpik.QpikError, match=name) as caught:
        call()
    assert isinstance(caught.value, (TypeError, ValueError))


# --------------------------------------------------------------------------------------
# Class (seed 2027, solve_many:174): solve_many with workers > 1 inside a daemonic process
# (a pool's worker) raised multiprocessing's AssertionError; it solves in that process.
def _solve_many_in(queue) -> None:
    try:
        results = qpik.solve_many(
            "planar_2r", [{"ee": [1.0, 0.5, 0.0]}] * 3, workers=2, pool_threshold=1, max_iters=5
        )
        queue.put(("ok", len(results)))
    except Exception as error:  # noqa: BLE001 - reported to the test
        queue.put((type(error).__name__, str(error)))


def test_solve_many_in_a_daemonic_process() -> None:
    import multiprocessing

    context = multiprocessing.get_context("spawn")
    queue = context.Queue()
    process = context.Process(target=_solve_many_in, args=(queue,), daemon=True)
    process.start()
    assert queue.get(timeout=120) == ("ok", 3)
    process.join(30)


# --------------------------------------------------------------------------------------
# Hypothesis properties of the classes above (derandomized, a few dozen examples each).
from hypothesis import given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from properties_common import not_a_number, props  # noqa: E402


@props(25)
@given(
    zero_columns=st.lists(st.booleans(), min_size=4, max_size=4),
    rho=st.sampled_from([0.0, 1e-12, 1e-9, 1e-6, 1e-3, 1.0]),
    seed=st.integers(0, 2**16),
)
def test_level_with_dofs_it_does_not_move_is_solved(zero_columns, rho, seed) -> None:
    """A level whose Jacobian has zero columns (dofs its task does not move), damped or
    not, is certified solved, its answer zero on those dofs."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((3, 4))
    A[:, np.array(zero_columns)] = 0.0
    inf = np.full(4, np.inf)
    level = qpik.core.Level(A, rng.standard_normal(3), rho)
    problem = qpik.core.HierarchyProblem([level], -inf, inf, np.zeros((0, 4)), np.zeros(0))
    result = qpik.core.HierarchySolver().solve(problem)
    assert [str(s) for s in result.status] == ["solved"], result.certificate
    if rho > 0:
        assert np.abs(result.x[np.array(zero_columns)]).max(initial=0.0) <= 1e-9


@props(25)
@given(
    kind=st.sampled_from(["JointLimitDistanceTask", "ComTask", "PositionTask", "DampingTask"]),
    name=st.sampled_from(["cost", "gain", "lm_damping"]),
    value=not_a_number,
)
def test_task_number_of_a_wrong_kind_is_typed(kind: str, name: str, value) -> None:
    """A task weight, gain or damping that is not a number raises a QpikError that is
    also a ValueError or TypeError, or is accepted (a list of numbers as a cost)."""
    model = qpik.load_robot("planar_2r")
    make = {
        "JointLimitDistanceTask": lambda **k: qpik.tasks.JointLimitDistanceTask(**k),
        "ComTask": lambda **k: qpik.tasks.ComTask(**k),
        "PositionTask": lambda **k: qpik.tasks.PositionTask("ee", **k),
        "DampingTask": lambda **k: qpik.tasks.DampingTask(model, **k),
    }[kind]
    if kind == "DampingTask" and name != "cost":
        return  # DampingTask takes a cost only
    try:
        make(**{name: value})
    except qpik.QpikError as error:
        assert isinstance(error, (TypeError, ValueError))


# --------------------------------------------------------------------------------------
# Open (seeds 5150 and 2027, erd:738 and 3 more): at dt = 1e-9 (DT_MIN) a forced backend
# (osqp, daqp, quadprog: the level-by-level path) returns a step whose velocity is 2 %
# over a VelocityLimit on a floating anymal (the compiled "auto" path holds it): the
# bounds v_max dt ~ 1e-9 are below the certificate's absolute primal scale (1 + |bound|).
def _erd_has(name: str) -> bool:
    try:
        return name in qpik.robots.erd_robots()
    except qpik.QpikError:
        return False


def _fuzz():
    import importlib.util
    import sys
    from pathlib import Path

    path = Path(__file__).parents[2] / "benchmarks" / "fuzz.py"
    spec = importlib.util.spec_from_file_location("qpik_fuzz", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["qpik_fuzz"] = module
    spec.loader.exec_module(module)
    return module


@pytest.mark.skipif(not _erd_has("anymal"), reason="example-robot-data not installed")
def test_forced_backend_holds_velocity_limits_at_the_smallest_dt() -> None:
    fuzz = _fuzz()
    spec = fuzz.make_spec(5150, "erd", 738)  # anymal, floating, quadprog, dt = 1e-9
    outcome, detail, _ = fuzz._outcome(fuzz.RUNNERS["erd"], spec)
    assert outcome not in fuzz.BAD, detail


def test_a_0d_array_where_a_sequence_is_expected_is_a_typed_error() -> None:
    """Fuzz seed 8080 signature:204: a 0-d array claims ``__iter__`` but raises a bare
    TypeError when iterated; every sequence argument is checked with
    ``checks.is_iterable``, which refuses it."""
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model)
    zero_d = np.array(1.0)
    with pytest.raises(qpik.QpikError, match="wrenches") as info:
        statics.holding_torques(configuration, zero_d)
    assert isinstance(info.value, TypeError)
    with pytest.raises(qpik.QpikError):
        qpik.IKSolver(model, [[qpik.tasks.PostureTask(model, cost=1.0)]], zero_d)
    with pytest.raises(qpik.QpikError):
        qpik.solve_many("panda", zero_d)


@pytest.mark.parametrize("subdivisions", [b"1", 1.0, None, True, np.array([1, 2])])
def test_ball_joint_limit_names_a_wrong_subdivisions_first(subdivisions) -> None:
    """Fuzz seed 6006 signature:257/311: ``BallJointLimit(model, subdivisions=<wrong
    type>)`` on a model without a ball joint blamed the model; the argument is checked
    first and named (a TypeError too)."""
    model = qpik.load_robot("panda")
    with pytest.raises(qpik.QpikError, match="subdivisions") as info:
        qpik.limits.BallJointLimit(model, subdivisions=subdivisions)
    assert isinstance(info.value, TypeError)
    with pytest.raises(qpik.LimitDefinitionError, match="subdivisions"):
        qpik.limits.BallJointLimit(model, subdivisions=3)


# --------------------------------------------------------------------------------------
# An audit of the public API's docstrings and bad input (2026-12-05): each value below was
# taken silently or raised an untyped error from deep inside; each is now a typed QpikError
# naming the argument.
def _bad_public_calls():
    from qpik.analysis import singular_values
    from qpik.robots import gripper_joints, locate_robot, tool_frame
    from qpik.tasks import ComTask, JointLimitDistanceTask, ManipulabilityTask, PositionTask

    configuration = qpik.Configuration(qpik.load_robot("planar_2r"))
    return [
        (lambda: ManipulabilityTask("ee", cost=float("nan")), qpik.TaskDefinitionError, "cost"),
        (lambda: ManipulabilityTask("ee", cost=-1.0), qpik.TaskDefinitionError, "cost"),
        (lambda: JointLimitDistanceTask(cost=float("nan")), qpik.TaskDefinitionError, "cost"),
        (lambda: PositionTask("ee", cost=-1.0), qpik.TaskDefinitionError, "position cost"),
        (lambda: configuration.random_q("x"), qpik.InvalidArgumentType, "rng"),
        (lambda: configuration.random_q(5), qpik.InvalidArgumentType, "rng"),
        (lambda: tool_frame("x"), qpik.InvalidArgumentType, "model"),
        (lambda: gripper_joints(None), qpik.InvalidArgumentType, "model"),
        (lambda: locate_robot(5), qpik.InvalidArgumentType, "robot"),
        (lambda: ComTask(body=[1]), qpik.TaskDefinitionError, "body"),
        (lambda: ComTask(body=1.7), qpik.TaskDefinitionError, "body"),
        (lambda: singular_values(np.ones((2, 2)) * 1j), qpik.InvalidInput, "complex"),
        (lambda: singular_values([[1.0, 2.0], [3.0]]), qpik.InvalidInput, "numeric matrix"),
        (lambda: qpik.solve("planar_2r", {"ee": [np.nan, 0, 0]}), qpik.InvalidTarget, "'ee'"),
        (
            lambda: qpik.solve("planar_2r", {"ee": np.full((4, 4), np.nan)}),
            qpik.InvalidTarget,
            "'ee'.*finite",
        ),
    ]


@pytest.mark.parametrize("index", range(15))
def test_public_calls_name_their_bad_argument(index: int) -> None:
    call, error, words = _bad_public_calls()[index]
    with pytest.raises(error, match=words):
        call()


def test_random_q_leaves_ball_joints_at_qpos0_as_documented() -> None:
    import mujoco

    model = mujoco.MjModel.from_xml_string(
        '<mujoco><compiler angle="radian"/><worldbody><body><joint type="ball" range="0 1"'
        ' limited="true"/><geom size=".1"/><body><joint type="hinge" range="-0.5 0.25"/>'
        '<geom size=".1"/></body></body></worldbody></mujoco>'
    )
    for seed in range(20):
        q = qpik.Configuration(model).random_q(np.random.default_rng(seed))
        assert q[:4].tolist() == [1.0, 0.0, 0.0, 0.0]  # the ball joint at qpos0
        assert -0.5 <= q[4] <= 0.25  # the hinge within its range


@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
@pytest.mark.parametrize("with_task", [True, False])
def test_a_mink_configuration_of_nan_is_named_by_solve_ik(bad: float, with_task: bool) -> None:
    """docs/guides/mink.md: a configuration with NaN or inf entries raises
    InvalidConfiguration; through qpik.solve_ik on a mink.Configuration it raised
    InvalidTarget (a task) or returned a velocity (no task), and a kept solver's call after a
    valid one must name it too."""
    import mink

    model = qpik.load_robot("panda")
    configuration = mink.Configuration(model)
    configuration.update(model.key_qpos[0])
    task = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    task.set_target(mink.SE3.identity())
    tasks = [task] if with_task else []
    limits = [mink.ConfigurationLimit(model)]
    qpik.solve_ik(configuration, tasks, 0.01, "daqp", limits=limits)  # (a kept solver)
    q = configuration.q.copy()
    q[2] = bad
    configuration.update(q)
    for _ in range(2):
        with pytest.raises(qpik.InvalidConfiguration, match=r"q\[2\]"):
            qpik.solve_ik(configuration, tasks, 0.01, "daqp", limits=limits)


def test_a_scaled_user_row_gets_the_same_answer_from_every_backend_and_a_dropped_row_is_not_named():
    """An audit of the docs: a user limit's one-dof row scaled by 1e10 (h = 1e7) was solved
    by solver="auto" and ended numerical_failure with a forced backend (the compiled step
    gave the backend the row unfolded); and a row of h = 1e22, dropped as documented, was
    still named in active_limits while the step went past it."""
    import mink

    class Scaled(mink.Limit):
        def __init__(self, model, scale, h):
            self.scale, self.h, self.nv = scale, h, model.nv

        def compute_qp_inequalities(self, configuration, dt):
            G = np.zeros((1, self.nv))
            G[0, 0] = self.scale
            return mink.Constraint(G=G, h=np.array([self.h]))

    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    posture = qpik.tasks.PostureTask(model, cost=1.0)
    target = model.key_qpos[0].copy()
    target[:2] += 1.0
    posture.set_target(target)
    answers = []
    for solver in ("auto", "daqp", "quadprog", "osqp"):
        limits = [mink.ConfigurationLimit(model), Scaled(model, 1e10, 1e7)]
        step = qpik.IKSolver(model, [[posture]], limits, solver=solver).step(configuration, 0.01)
        assert step.ok, (solver, step.status)
        answers.append(step.displacement)
    for other in answers[1:]:
        np.testing.assert_allclose(other, answers[0], atol=1e-9)
    assert answers[0][0] == pytest.approx(1e-3)

    # The same row over two dofs (a general row, not folded): norm 1.4e10, solved.
    class Pair(Scaled):
        def compute_qp_inequalities(self, configuration, dt):
            G = np.zeros((1, self.nv))
            G[0, :2] = self.scale
            return mink.Constraint(G=G, h=np.array([self.h]))

    limits = [mink.ConfigurationLimit(model), Pair(model, 1e10, 1e7)]
    step = qpik.IKSolver(model, [[posture]], limits).step(configuration, 0.01)
    assert step.ok and step.displacement[:2].sum() == pytest.approx(1e-3)
    limits = [mink.ConfigurationLimit(model), Scaled(model, 1e25, 1e22)]
    step = qpik.IKSolver(model, [[posture]], limits).step(configuration, 0.01)
    assert step.displacement[0] > 1e-3  # (the row bounds nothing: h >= 1e20)
    assert not any("Scaled" in name for name in step.active_limits), step.active_limits


def test_a_com_task_on_a_massless_subtree_and_secondary_tasks_on_mink_configurations():
    """An audit of every task's error and Jacobian: ComTask(body=...) on a subtree of no
    mass (the UR5e's tool0) had a NaN Jacobian (mj_jacSubtreeCom divides by the mass), and
    the step blamed the target; JointLimitDistanceTask and ManipulabilityTask called with a
    mink.Configuration raised AttributeError."""
    import mink
    import mujoco

    from qpik.tasks import ComTask, JointLimitDistanceTask, ManipulabilityTask

    model = qpik.load_robot("ur5e")
    q = np.array([0.3, -1.2, 1.1, -0.4, 0.7, 0.2])
    configuration = qpik.Configuration(model, q)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "tool0")
    assert model.body_subtreemass[body] == 0.0
    task = ComTask(body="tool0")
    task.set_target(configuration.data.subtree_com[body] + [0.01, 0.0, 0.0])
    jacobian = task.compute_jacobian(configuration)
    finite_difference = np.zeros((3, model.nv))
    for i in range(model.nv):
        step = np.zeros(model.nv)
        step[i] = 1e-6
        configuration.update(q + step)
        plus = task.compute_error(configuration)
        configuration.update(q - step)
        minus = task.compute_error(configuration)
        finite_difference[:, i] = (plus - minus) / 2e-6
    configuration.update(q)
    np.testing.assert_allclose(jacobian, finite_difference, atol=1e-8)
    assert qpik.IKSolver(model, [[task]], []).step(configuration, 0.01).ok
    theirs = mink.Configuration(model, q)
    ours = qpik.Configuration(model, q)
    for secondary in (JointLimitDistanceTask(), ManipulabilityTask("ee")):
        np.testing.assert_array_equal(
            secondary.compute_error(theirs), secondary.compute_error(ours)
        )
        np.testing.assert_array_equal(
            secondary.compute_jacobian(theirs), secondary.compute_jacobian(ours)
        )
