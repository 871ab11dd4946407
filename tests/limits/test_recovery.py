"""Recoverable collision rows (qpik.diffik.recovery): a start deeper inside a collision
distance than one step can leave, under the trust region. Before, level 0 was infeasible
at every step (the robot stayed where it was, velocity zero), or, where a one-dof row
emptied the box, IKSolver.step raised InfeasibleLimits. References: the closed form of
the least slack of one row over a box, MuJoCo's own distance (mj_geomDistance) after the
step, and the hard rows of other limits, which stay hard."""

from __future__ import annotations

import mink
import mujoco
import numpy as np
import pytest
import scipy.optimize

import qpik
from qpik.diffik.recovery import least_slack
from qpik.tasks import PostureTask

DT = 0.01
BOUND = qpik.options.DEFAULT_MAX_JOINT_SPEED * DT  # the trust region per step

#: A sphere on slides pressed into a fixed sphere (penetration 5 cm): a carriage on x (or x
#: and y) carries the puck on a z slide, across the contact normal (so that mink's
#: collision filter, which skips a body and its weld's parent, keeps the pair).
XML = """<mujoco><worldbody>
  <body name="carriage">{joints}<geom type="box" size="0.01 0.01 0.01" contype="0" conaffinity="0"/>
    <body name="puck"><joint name="z" type="slide" axis="0 0 1" range="-1 1"/>
      <geom name="puck" type="sphere" size="0.1"/></body></body>
  <body name="post" pos="{post}"><geom name="post" type="sphere" size="0.1"/></body>
</worldbody></mujoco>"""
SLIDE = '<joint name="{0}" type="slide" axis="{1}" range="-1 1"/>'


def _model(planar: bool) -> mujoco.MjModel:
    joints = SLIDE.format("x", "1 0 0") + (SLIDE.format("y", "0 1 0") if planar else "")
    post = "0.106 0.106 0" if planar else "0.15 0 0"
    return mujoco.MjModel.from_xml_string(XML.format(joints=joints, post=post))


def _distance(model: mujoco.MjModel, q: np.ndarray) -> float:
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    return mujoco.mj_geomDistance(model, data, 1, 2, 1.0, None)


def _solver(model, extra=()):
    collision = qpik.limits.CollisionAvoidanceLimit(
        model, [(["puck"], ["post"])], minimum_distance_from_collisions=0.01,
        collision_detection_distance=0.2,
    )  # fmt: skip
    posture = PostureTask(model, cost=1.0)
    posture.set_target(np.full(model.nq, 0.5))  # toward the post
    limits = [mink.ConfigurationLimit(model), collision, *extra]
    return qpik.IKSolver(model, [[posture]], limits), posture


@pytest.mark.parametrize("planar", [False, True])
def test_a_start_in_deep_contact_separates_as_fast_as_the_trust_region_allows(planar):
    """One dof (its row folds into the box and emptied it: InfeasibleLimits) and two (a
    general row: level 0 infeasible, a zero step): now the step leaves the contact at the
    trust region's speed along the normal, level 0 still says infeasible, and the
    relaxation is the row's least slack (closed form for one row over a box)."""
    model = _model(planar)
    solver, _ = _solver(model)
    configuration = qpik.Configuration(model, np.zeros(model.nq))
    start = _distance(model, configuration.q)
    assert start == pytest.approx(-0.05, abs=1e-3)
    result = solver.step(configuration, DT)
    assert result.status[0] == "infeasible" and not result.ok
    normal = result.displacement[:-1]  # the carriage's dofs; the z slide is free
    # away, at the bound (less the relaxed row's margin, RELAXATION_MARGINS[0] (|g| + |h|))
    np.testing.assert_allclose(normal, -BOUND, rtol=0, atol=2e-9)
    limits = solver._rows(configuration, DT, fold=False)[1]
    (g,), (h,) = limits.G, limits.h  # the z slide's entry: zero (across the normal)
    lowest = np.minimum(g * limits.lb, g * limits.ub).sum()  # the row's least value
    np.testing.assert_allclose(result.relaxation, [lowest - h], rtol=1e-9)
    assert result.relaxation[0] > 0.0
    assert _distance(model, configuration.q + result.displacement) > start + 0.03
    # a closed loop leaves the contact, step after step, then the posture task moves on
    for _ in range(20):
        step = solver.step(configuration, DT)
        assert np.abs(step.displacement).max() <= BOUND * (1 + 1e-12)
        configuration.integrate_inplace(step.velocity, DT)
    assert _distance(model, configuration.q) >= 0.01 - 1e-6
    assert step.ok and step.relaxation is None


def test_the_slack_problem_matches_the_one_row_closed_form_on_random_rows():
    """least_slack on one relaxable row over random boxes: the row's own least slack."""
    rng = np.random.default_rng(0)
    model = _model(True)
    solver, _ = _solver(model)
    limits = solver._rows(qpik.Configuration(model, np.zeros(model.nq)), DT, fold=False)[1]
    for _ in range(50):
        g = rng.normal(size=2)
        lb = -rng.uniform(0.01, 0.1, 2)
        ub = rng.uniform(0.01, 0.1, 2)
        h = np.minimum(g * lb, g * ub).sum() - rng.uniform(0.0, 0.05)
        rows = type(limits)(lb, ub, g[None], np.array([h]), ["r"], lambda: [], ["x", "y"],
                            np.array([True]))  # fmt: skip
        expected = np.minimum(g * lb, g * ub).sum() - h
        np.testing.assert_allclose(least_slack(rows), [expected], rtol=1e-9, atol=1e-15)


class _HardRow(mink.Limit):
    """A user limit x <= -0.1 (hard: not relaxed)."""

    def compute_qp_inequalities(self, configuration, dt):
        G = np.zeros((1, configuration.nv))
        G[0, 0] = 1.0
        return mink.Constraint(G=G, h=np.array([-0.1]))


def test_rows_of_other_limits_stay_hard():
    """A user limit's one-dof row that empties the box still raises InfeasibleLimits; the
    collision row alone relaxes, and only the collision row takes slack."""
    model = _model(False)
    solver, _ = _solver(model, [_HardRow()])
    configuration = qpik.Configuration(model, np.zeros(model.nq))
    with pytest.raises(qpik.InfeasibleLimits):
        solver.step(configuration, DT)
    plain, _ = _solver(model)
    assert plain.step(configuration, DT).relaxation is not None


def test_a_step_that_needs_no_relaxation_reports_none():
    model = _model(True)
    solver, _ = _solver(model)
    result = solver.step(qpik.Configuration(model, np.array([-0.3, -0.3, 0.0])), DT)
    assert result.ok and result.relaxation is None


def test_without_a_trust_region_the_rows_need_no_relaxation():
    """max_joint_speed=None (mink's behaviour): the box no longer stops the separation; the
    step leaves the contact at once and nothing is relaxed. An unbounded dof's entry is
    kept in the slack problem (least_slack on the same rows with the box opened)."""
    model = _model(True)
    collision = qpik.limits.CollisionAvoidanceLimit(
        model, [(["puck"], ["post"])], minimum_distance_from_collisions=0.01,
        collision_detection_distance=0.2,
    )  # fmt: skip
    posture = PostureTask(model, cost=1.0)
    posture.set_target(np.full(model.nq, 0.5))
    solver = qpik.IKSolver(model, [[posture]], [collision], max_joint_speed=None)
    configuration = qpik.Configuration(model, np.zeros(model.nq))
    result = solver.step(configuration, DT)
    assert result.ok and result.relaxation is None
    limits = solver._rows(configuration, DT, fold=False)[1]
    assert not np.isfinite(limits.lb).any()
    np.testing.assert_array_equal(least_slack(limits), 0.0)


def test_the_corrected_step_recovers_too():
    """correction_passes=1 (the QP path's corrected step): the same recovery, the same
    relaxation as the plain step at the same state."""
    model = _model(True)
    plain, posture = _solver(model)
    corrected = qpik.IKSolver(model, [[posture]], plain.limits, correction_passes=1)
    configuration = qpik.Configuration(model, np.zeros(model.nq))
    a, b = plain.step(configuration, DT), corrected.step(configuration, DT)
    assert b.status[0] == "infeasible" and b.relaxation is not None
    np.testing.assert_allclose(b.relaxation, a.relaxation, rtol=1e-12)
    np.testing.assert_allclose(b.displacement[:-1], -BOUND, rtol=0, atol=2e-9)


def test_a_degenerate_relaxed_set_is_widened_until_level_0_is_solved():
    """Where the relaxed rows meet at a degenerate vertex, level 0 may not be certified at
    the first margin: the next margin of RELAXATION_MARGINS is tried (here a stand-in
    solve, certified from the second margin on), and the last is kept where none is."""
    from qpik.core import LevelStatus
    from qpik.diffik.recovery import RELAXATION_MARGINS
    from qpik.diffik.result import Solution

    model = _model(True)
    solver, _ = _solver(model)
    limits = solver._rows(qpik.Configuration(model, np.zeros(model.nq)), DT, fold=False)[1]
    slack = least_slack(limits)
    seen = []

    def solve(rows, certified_from=1):
        seen.append(rows.h.copy())
        ok = len(seen) > certified_from
        status = [LevelStatus.SOLVED if ok else LevelStatus.NUMERICAL]
        d = np.full(model.nv, float(len(seen)))
        return Solution(d, d / DT, [0.0], [1.0], [0.0], status, [0], [], lambda: rows)

    result = solver._relaxed(solve, limits, slack)
    assert len(seen) == 2 and result.displacement[0] == 2.0
    assert result.status == [LevelStatus.INFEASIBLE] and result.relaxation is slack
    widened = (seen[1] - seen[0])[slack > 0]
    scale = (np.linalg.norm(limits.G, axis=1) + np.abs(limits.h))[slack > 0]
    np.testing.assert_allclose(widened, (RELAXATION_MARGINS[1] - RELAXATION_MARGINS[0]) * scale)
    seen.clear()
    result = solver._relaxed(lambda rows: solve(rows, 99), limits, slack)
    assert len(seen) == len(RELAXATION_MARGINS) and result.displacement[0] == len(seen)


def test_an_uncertified_slack_problem_still_gives_a_slack_that_admits_a_step(monkeypatch):
    """Where the core does not certify the slack problem, the slack that lets the rows
    admit its step x (inside the box), else the box's point nearest 0: the relaxed rows
    then admit that step (here a stand-in core returning numerical_failure)."""
    import qpik.diffik.recovery as recovery
    from qpik.core import LevelStatus

    model = _model(True)
    solver, _ = _solver(model)
    limits = solver._rows(qpik.Configuration(model, np.zeros(model.nq)), DT, fold=False)[1]
    n, p = model.nv, limits.G.shape[0]

    class Stub:
        x = np.zeros(n + p)

        def __init__(self, *args, **kwargs):
            pass

        def solve(self, problem):
            return type("R", (), {"status": [LevelStatus.NUMERICAL], "x": Stub.x})()

    monkeypatch.setattr(recovery, "HierarchySolver", Stub)
    for step in (np.array([-0.02, -0.01, 0.0]), np.array([1.0, 0.0, 0.0])):  # in / out of box
        Stub.x = np.concatenate([step, np.zeros(p)])
        slack = least_slack(limits)
        x = step if np.all((limits.lb <= step) & (step <= limits.ub)) else np.zeros(n)
        np.testing.assert_array_equal(slack, np.maximum(limits.G @ x - limits.h, 0.0))
        assert np.all(limits.G @ x <= limits.h + slack)


def test_the_recovered_step_is_the_same_bits_whatever_ran_before():
    """The deep-contact step of a fresh solver, of the same solver after other steps
    (free and recovered ones), and of another solver instance: bitwise the same velocity,
    relaxation and statuses."""
    model = _model(True)
    deep = np.zeros(model.nq)

    def step(solver):
        result = solver.step(qpik.Configuration(model, deep), DT)
        return result.velocity.tobytes(), result.relaxation.tobytes(), list(result.status)

    fresh, _ = _solver(model)
    reference = step(fresh)
    used, _ = _solver(model)
    for q in ([-0.3, -0.3, 0.0], [0.05, 0.0, 0.1], [-0.01, 0.02, 0.0]):
        used.step(qpik.Configuration(model, np.array(q)), DT)
    assert step(used) == reference
    assert step(used) == reference  # again, right after itself
    other, _ = _solver(model)
    assert step(other) == reference


#: The planar model with a second carriage, its x slide coupled to the first's by an
#: equality: the model's couplings (a level of their own, solved before the stack's).
COUPLED = """<mujoco><worldbody>
  <body name="carriage"><joint name="x" type="slide" axis="1 0 0" range="-1 1"/>
    <joint name="y" type="slide" axis="0 1 0" range="-1 1"/>
    <geom type="box" size="0.01 0.01 0.01" contype="0" conaffinity="0"/>
    <body name="puck"><joint name="z" type="slide" axis="0 0 1" range="-1 1"/>
      <geom name="puck" type="sphere" size="0.1"/></body></body>
  <body name="post" pos="0.106 0.106 0"><geom name="post" type="sphere" size="0.1"/></body>
  <body name="follower" pos="0 0 2"><joint name="w" type="slide" axis="1 0 0" range="-1 1"/>
    <geom type="box" size="0.01 0.01 0.01" contype="0" conaffinity="0"/></body>
</worldbody><equality><joint joint1="w" joint2="x"/></equality></mujoco>"""


def test_a_model_with_couplings_recovers_too():
    """With the model's couplings, their level comes first and is the one the collision
    row makes infeasible; the stack's levels were then not reached and the step was zero
    (example-robot-data's Baxter, whose grippers are coupled, with model_collision_limit,
    never moved: its start overlaps by 4.8 cm). Now the same recovery as without couplings:
    the relaxed step leaves the contact, the couplings held."""
    model = mujoco.MjModel.from_xml_string(COUPLED)
    solver, _ = _solver(model)
    configuration = qpik.Configuration(model, np.zeros(model.nq))
    start = _distance(model, configuration.q)
    result = solver.step(configuration, DT)
    assert result.status[0] == "infeasible" and result.relaxation is not None
    d = result.displacement
    # w follows x to the couplings level's damping (1e-6 relative): the relaxed row moves x
    # at that level already, where w follows by least squares (w = x / (1 + 1e-6))
    assert result.coupling_residual < 1e-6
    assert abs(d[3] - d[0]) <= 2e-6 * abs(d[0])
    assert _distance(model, configuration.q + d) > start + 0.03


#: A ball on a hinge about its own centre's vertical axis, inside a fixed box: the turn
#: does not move the ball, so the pair's distance row is 0 . dq <= h with h < 0 (5 cm deep).
UNMOVED = """<mujoco><worldbody>
  <body name="spinner" pos="0 0 0"><joint name="spin" type="hinge" axis="0 0 1" range="-1 1"/>
    <geom name="ball" type="sphere" size="0.1"/></body>
  <body name="other"><joint name="x" type="slide" axis="1 0 0" range="-1 1"/>
    <geom type="box" size="0.01 0.01 0.01" contype="0" conaffinity="0"/></body>
  <geom name="wall" type="box" pos="0.15 0 0" size="0.1 0.1 0.1"/>
</worldbody></mujoco>"""


def test_build_returns_the_problem_the_step_solves_where_no_joint_moves_a_pair():
    """A collision row that no dof moves, violated at the start (0 . dq <= -0.047). The core
    called level 0 numerical_failure (the dual method skips a row of norm 0), so the step did
    not recover and stood still; and build raised InfeasibleLimits ("a row 0 . dq <= ...")
    where the step went on (erd Tiago with model_collision_limit at its middle
    configuration). Now level 0 is infeasible (the row is its own proof), the step relaxes
    the row and moves, and build returns the step's problem, the collision rows general."""
    from qpik.core import HierarchySolver

    model = mujoco.MjModel.from_xml_string(UNMOVED)
    limit = qpik.limits.model_collision_limit(model, collision_detection_distance=0.2)
    posture = PostureTask(model, cost=1.0)
    posture.set_target(np.array([0.5, 0.5]))
    solver = qpik.IKSolver(model, [[posture]], [mink.ConfigurationLimit(model), limit])
    configuration = qpik.Configuration(model, np.zeros(model.nq))
    result = solver.step(configuration, DT)
    assert result.status[0] == "infeasible" and result.relaxation is not None
    problem = solver.build(configuration, DT)
    assert problem.G.shape[0] >= 1 and np.all(problem.G[np.argmin(problem.h)] == 0.0)
    assert problem.h.min() < 0.0
    core = HierarchySolver().solve(problem)
    assert core.status[0] == "infeasible"  # (was numerical_failure: no recovery then)
    # the row relaxed by its violation, and the posture pursued within the box
    assert result.relaxation[0] == pytest.approx(-problem.h.min(), rel=1e-12)
    np.testing.assert_allclose(result.displacement, problem.ub, rtol=1e-12)


@pytest.mark.parametrize("scale", [0.0, 1e-20, -1e-20])
def test_a_row_no_displacement_in_the_box_meets_makes_level_0_infeasible(scale):
    """A general row whose entries are 0 or round-off (1e-20: erd Panda's collision pair
    between bodies no joint separates, 3.3 cm deep) against a box of 0.03: no displacement in
    the box meets it, and the dual method, which skips a row of norm (nearly) 0, ended
    numerical_failure there, so the step's recovery never ran and every level was
    not_reached. Now level 0 is infeasible (the row and the box are the proof)."""
    from qpik.core import HierarchyProblem, HierarchySolver, Level

    n = 3
    problem = HierarchyProblem(
        [Level(np.eye(n), np.ones(n), 0.0)],
        np.full(n, -0.03), np.full(n, 0.03),
        np.array([[scale, 0.0, 0.0], [1.0, 1.0, 0.0]]), np.array([-0.033, 0.05]),
    )  # fmt: skip
    for solver in (HierarchySolver(), HierarchySolver(damping_law=None)):
        result = solver.solve(problem)
        assert result.status[0] == "infeasible", result.status
        assert result.certificate[0].primal > 1e-3
    # a row that the box can meet is left to the dual method as before
    feasible = HierarchyProblem(
        [Level(np.eye(n), np.ones(n), 0.0)],
        np.full(n, -0.03), np.full(n, 0.03),
        np.array([[1.0, 0.0, 0.0]]), np.array([-0.02]),
    )  # fmt: skip
    assert HierarchySolver().solve(feasible).status[0] == "solved"


def test_the_slack_problem_leaves_out_rows_the_box_meets():
    """Many rows (a many-pair robot's collision rows within the detection distance), a few of
    which a step in the box can break: least_slack gives the rows the box meets everywhere no
    slack, and the others the least-squares slack an independent solver finds (scipy's
    L-BFGS-B on 1/2 |max(0, G x - h)|^2 + 1/2 eps^2 |x|^2 over the box)."""
    from qpik.diffik.boxes import LimitRows
    from qpik.diffik.recovery import SLACK_STEP_WEIGHT

    rng = np.random.default_rng(3)
    n, far, near = 7, 300, 6
    lb, ub = -np.full(n, 0.03), np.full(n, 0.03)
    G = rng.normal(size=(far + near, n))
    reach = np.abs(G) @ ub  # the largest g_i x over the box
    h = reach + rng.uniform(0.001, 0.1, far + near)  # met everywhere in the box
    h[:near] = -reach[:near] * rng.uniform(0.1, 0.8, near)  # not met at x = 0, nor together
    rows = LimitRows(lb, ub, G, h, [f"r{i}" for i in range(len(h))], lambda: [],
                     [f"q{j}" for j in range(n)], np.ones(len(h), bool))  # fmt: skip
    slack = least_slack(rows)
    assert slack is not None and np.all(slack[near:] == 0.0) and np.all(slack[:near] >= 0.0)

    def objective(x):
        excess = np.maximum(0.0, G @ x - h)
        eps2 = SLACK_STEP_WEIGHT**2  # (the level's rows: SLACK_STEP_WEIGHT I on x)
        return 0.5 * excess @ excess + 0.5 * eps2 * x @ x, G.T @ excess + eps2 * x

    best = scipy.optimize.minimize(objective, np.zeros(n), jac=True, method="L-BFGS-B",
                                   bounds=list(zip(lb, ub)), options={"ftol": 1e-15, "gtol": 1e-13})  # fmt: skip
    expected = np.maximum(0.0, G @ best.x - h)
    assert 0.5 * slack @ slack <= 0.5 * expected @ expected * (1 + 1e-6) + 1e-15
    np.testing.assert_allclose(slack, expected, rtol=1e-4, atol=1e-7)


@pytest.mark.filterwarnings("ignore")
def test_a_start_outside_the_support_polygon_comes_back_with_the_feet_held():
    """h18's audit: a CoM outside the polygon (the sole footprint shifted forward) sent the
    step to the recovery, whose least slack moved the floating base and the legs: the feet
    held at level 0 slid (0.14 m in one step, 14 m in 300) and the polygon moved with them,
    the CoM never back. The slack problem now holds the polygon's contact frames: the CoM
    comes back within a few steps, the feet stay."""
    from conftest import load_or_skip

    from qpik.limits import SupportPolygonLimit, joint_limits
    from qpik.tasks import FrameTask, PostureTask

    model = load_or_skip("erd:talos", floating_base=True)
    q0 = model.key("half_sitting").qpos.copy()
    configuration = qpik.Configuration(model, q0)
    feet = ("left_sole_link", "right_sole_link")
    sole = np.array([[0.1, 0.05], [0.1, -0.05], [-0.1, 0.05], [-0.1, -0.05]])
    support = SupportPolygonLimit(model, feet, margin=0.02, footprint=sole + [0.15, 0.0])
    tasks = [FrameTask(n, "body", position_cost=1.0, orientation_cost=1.0) for n in feet]
    for task in tasks:
        task.set_target_from_configuration(configuration)
    posture = PostureTask(model, cost=1e-2)
    posture.set_target(q0)
    solver = qpik.IKSolver(model, [tasks, [posture]], [*joint_limits(model, 0.9), support])
    assert support.com_margin(configuration) < -0.04
    relaxed = 0
    for _ in range(10):
        step = solver.step(configuration, 0.01)
        relaxed += step.relaxation is not None
        configuration.integrate_inplace(step.velocity, 0.01)
        slide = max(np.linalg.norm(t.compute_error(configuration)[:3]) for t in tasks)
        assert slide < 2e-3  # (the feet's second-order error, not a slide)
    assert relaxed >= 1
    assert support.com_margin(configuration) >= 0.02 - 1e-4


def test_the_slack_relaxes_only_the_limit_kind_that_needs_it():
    """h18's audit: where only the support polygon's rows could not be met, the joint least
    squares slack relaxed collision rows too (by up to 2 mm a step: pairs then
    penetrated). The rows of one limit kind are relaxed alone where that suffices."""
    from qpik.diffik.boxes import LimitRows

    rows = LimitRows(
        lb=np.array([-1.0]),
        ub=np.array([1.0]),
        G=np.array([[1.0], [-1.0]]),
        h=np.array([-2.0, 0.5]),  # x <= -2 (out of the box), x >= -0.5
        row_names=["SupportPolygonLimit row 0", "CollisionAvoidanceLimit row 0"],
        sources=list,
        dof_names=["x"],
        relaxable=np.array([True, True]),
    )
    slack = least_slack(rows)
    np.testing.assert_allclose(slack, [1.5, 0.0], atol=1e-9)


def test_a_joint_whose_name_has_row_in_it_keeps_its_limit_kind():
    """A general row on one dof is named as that bound, ``"<joint> upper (<limit class>)"``,
    and MuJoCo takes any joint name: a joint named ``"front row hip"`` once made its row of
    kind ``"front"`` (the name was split at its ``" row "``), so that its limit's rows were
    relaxed apart from the rest of their kind. The bound's form is read first."""
    from qpik.diffik.boxes import LimitRows

    rows = LimitRows(
        lb=np.array([-1.0, -1.0]),
        ub=np.array([1.0, 1.0]),
        # x0 <= -2 and x1 <= -1.8 (support rows, out of the box), x0 + x1 >= -1.9 (collision)
        G=np.array([[1.0, 0.0], [-1.0, -1.0], [0.0, 1.0]]),
        h=np.array([-2.0, 1.9, -1.8]),
        row_names=[
            "SupportPolygonLimit row 0",
            "CollisionAvoidanceLimit row 0",
            "front row hip upper (SupportPolygonLimit)",
        ],
        sources=list,
        dof_names=["x", "front row hip"],
        relaxable=np.array([True, True, True]),
    )
    slack = least_slack(rows)
    # the support rows alone relaxed (both: one kind), the collision row kept hard (relaxing
    # every row together would give [1, 0.1, 0.8]: the pair 0.1 into its minimum distance)
    np.testing.assert_allclose(slack, [1.0, 0.0, 0.9], atol=1e-9)
