"""The engine core alone (no robot): exactness against brute force and an independent QP
solver, strict priority, determinism, statuses, failures; then the IK layer against mink."""

from __future__ import annotations

import itertools
from pathlib import Path

import mink
import numpy as np
import pytest
import qpsolvers
from conftest import warm_solves_give_cold_bits

import qpik
from qpik.core import (
    DampingLaw,
    HierarchyProblem,
    HierarchySolver,
    Level,
    LevelStatus,
    solve_hierarchy,
)
from qpik.core import kernels as K

CORE = Path(qpik.__file__).parent / "core"


# ----------------------------------------------------------------- brute force reference
def _eq_qp(H, c, E, e):
    """min 1/2 x^T H x + c^T x s.t. E x = e (redundant rows allowed); None if E x = e has
    no solution."""
    n = H.shape[0]
    if E.shape[0] == 0:
        return np.linalg.solve(H, -c)
    kkt = np.block([[H, E.T], [E, np.zeros((E.shape[0], E.shape[0]))]])
    sol = np.linalg.lstsq(kkt, np.concatenate([-c, e]), rcond=None)[0]
    x = sol[:n]
    if np.abs(E @ x - e).max() > 1e-8:
        return None
    return x


def brute_force_level(H, c, E, e, C, lo, hi):
    """Enumerate every active set (each row: free, at its lower or at its upper bound) of
    ``min 1/2 x^T H x + c^T x s.t. E x = e, lo <= C x <= hi`` and keep the best feasible
    candidate (the QP is strictly convex, so that is the optimum)."""
    best, best_f = None, np.inf
    choices = []
    for i in range(C.shape[0]):
        options = [0]
        if np.isfinite(lo[i]):
            options.append(1)
        if np.isfinite(hi[i]):
            options.append(-1)
        choices.append(options)
    for pattern in itertools.product(*choices):
        rows = [C[i] for i, s in enumerate(pattern) if s]
        vals = [lo[i] if s > 0 else hi[i] for i, s in enumerate(pattern) if s]
        Eall = np.vstack([E] + ([np.array(rows)] if rows else []))
        eall = np.concatenate([e, np.array(vals)]) if rows else e
        x = _eq_qp(H, c, Eall, eall)
        if x is None:
            continue
        Cx = C @ x
        if np.any(Cx < lo - 1e-9) or np.any(Cx > hi + 1e-9):
            continue
        f = 0.5 * x @ H @ x + c @ x
        if f < best_f - 1e-12:
            best, best_f = x, f
    return best


def brute_force_hierarchy(levels, lb, ub, G, h):
    """The prioritised solution level by level in the full space: each level keeps every
    higher level's ``A_j x`` fixed by equality constraints."""
    n = lb.shape[0]
    C = np.vstack([np.eye(n), G])
    lo = np.concatenate([lb, np.full(G.shape[0], -np.inf)])
    hi = np.concatenate([ub, h])
    E, e = np.zeros((0, n)), np.zeros(0)
    x = None
    for level in levels:
        H = level.A.T @ level.A + level.regularization * np.eye(n)
        c = -level.A.T @ level.b
        x = brute_force_level(H, c, E, e, C, lo, hi)
        assert x is not None
        E = np.vstack([E, level.A])
        e = np.concatenate([e, level.A @ x])
    return x


def random_problem(rng, n, levels=2, general=1):
    lvls = []
    for _ in range(levels):
        m = int(rng.integers(1, n))
        lvls.append(Level(rng.standard_normal((m, n)), rng.standard_normal(m) * 2, 1e-3))
    lb = -rng.uniform(0.05, 0.8, n)
    ub = rng.uniform(0.05, 0.8, n)
    G = rng.standard_normal((general, n))
    h = rng.uniform(0.0, 0.5, general)
    return lvls, lb, ub, G, h


def test_cascade_equals_brute_force_active_sets(rng):
    checked = 0
    for trial in range(60):
        n = int(rng.integers(2, 5))
        levels, lb, ub, G, h = random_problem(rng, n, levels=int(rng.integers(1, 4)))
        result = solve_hierarchy(levels, lb, ub, G, h, damping_law=None)
        assert result.ok, (trial, result.status)
        reference = brute_force_hierarchy(levels, lb, ub, G, h)
        np.testing.assert_allclose(result.x, reference, atol=1e-8, err_msg=f"trial {trial}")
        checked += 1
    assert checked == 60


def test_one_level_equals_an_independent_qp_solver(rng):
    for _ in range(200):
        n = int(rng.integers(2, 12))
        (level,), lb, ub, G, h = random_problem(rng, n, levels=1, general=int(rng.integers(0, 5)))
        result = solve_hierarchy([level], lb, ub, G, h, damping_law=None)
        H = level.A.T @ level.A + level.regularization * np.eye(n)
        reference = qpsolvers.solve_qp(
            H, -level.A.T @ level.b, G, h, lb=lb, ub=ub, solver="quadprog"
        )
        np.testing.assert_allclose(result.x, reference, atol=1e-9)


def test_strict_priority_lower_levels_never_change_higher_rows(rng):
    for _ in range(100):
        n = int(rng.integers(3, 9))
        levels, lb, ub, G, h = random_problem(rng, n, levels=3)
        full = solve_hierarchy(levels, lb, ub, G, h)
        for k in range(1, 3):
            top = solve_hierarchy(levels[:k], lb, ub, G, h)
            for j in range(k):
                np.testing.assert_allclose(levels[j].A @ full.x, levels[j].A @ top.x, atol=1e-9)
        assert np.all(full.x >= lb - 1e-12) and np.all(full.x <= ub + 1e-12)
        assert np.all(G @ full.x <= h + 1e-9)


def test_answers_never_depend_on_history(rng):
    problems = []
    for _ in range(40):
        n = int(rng.integers(3, 9))
        levels, lb, ub, G, h = random_problem(rng, n, levels=2, general=2)
        problems.append(HierarchyProblem(levels, lb, ub, G, h))
    for solver_name, warm in (("auto", False), ("auto", True), ("osqp", False), ("osqp", True)):
        fresh = [HierarchySolver(solver_name, warm_start=warm).solve(p).x for p in problems]
        shared = HierarchySolver(solver_name, warm_start=warm)
        for _round in range(2):
            for p, x in zip(problems, fresh):
                shared.solve(p)  # warm starts from the previous problem's active sets
                if warm:  # the opt-in warm start: equal to round-off at degenerate vertices
                    np.testing.assert_allclose(shared.solve(p).x, x, rtol=0, atol=1e-12)
                else:  # the default: bitwise
                    np.testing.assert_array_equal(shared.solve(p).x, x)
        # Same answer from the exact kernel and the OSQP backend polished on its set.
    for p in problems:
        np.testing.assert_allclose(
            HierarchySolver("auto").solve(p).x, HierarchySolver("osqp").solve(p).x, atol=1e-9
        )


def test_warm_start_changes_speed_not_answer(rng):
    for _ in range(300):
        n = int(rng.integers(2, 10))
        m = int(rng.integers(0, 2 * n))
        M = rng.standard_normal((n + 2, n))
        H = M.T @ M + 1e-3 * np.eye(n)
        c = rng.standard_normal(n) * 3
        C = rng.standard_normal((m, n))
        x0 = rng.standard_normal(n) * 0.3
        lo, hi = C @ x0 - rng.uniform(0, 1, m), C @ x0 + rng.uniform(0, 1, m)
        cold = K.solve_qp(H, c, C, lo, hi, np.zeros(m, np.int8), 500, 1e-12, True)
        warm = K.solve_qp(H, c, C, lo, hi, cold[3], 500, 1e-12, True)
        assert cold[1] == warm[1] == K.SOLVED
        np.testing.assert_array_equal(cold[0], warm[0])
        assert warm[2] == 0 or not cold[3].any() or True  # accepted when strictly optimal
        wrong = rng.integers(-1, 2, m).astype(np.int8)  # an arbitrary warm start
        guess = K.solve_qp(H, c, C, lo, hi, wrong, 500, 1e-12, True)
        np.testing.assert_array_equal(guess[0], cold[0])


def test_infeasible_and_capped_levels_are_never_solved():
    n = 2
    infeasible = HierarchyProblem(
        [Level(np.eye(2), np.ones(2), 1e-6)],
        -np.ones(n),
        np.ones(n),
        np.array([[1.0, 0.0], [-1.0, 0.0]]),
        np.array([-1.0, -1.0]),
    )
    result = HierarchySolver().solve(infeasible)
    assert result.status == [LevelStatus.INFEASIBLE] and not result.ok
    # Capped at 1 iteration (OSQP and the exact kernel it falls back to): reported as
    # max_iter, never as solved.
    capped = HierarchyProblem(
        [Level(np.eye(2), 5 * np.ones(2), 1e-6)], -np.ones(n), np.ones(n), np.zeros((0, 2)),
        np.zeros(0),
    )  # fmt: skip
    result = HierarchySolver("osqp", max_iter=1, backend_options={"max_iter": 1}).solve(capped)
    assert result.status == [LevelStatus.MAX_ITER] and not result.ok
    assert result.status[0] == "max_iter"  # string-valued enum
    # OSQP capped alone: the exact kernel answers, exactly.
    rescued = HierarchySolver("osqp", backend_options={"max_iter": 1}).solve(capped)
    assert rescued.ok and rescued.backend == ["osqp failed: auto"]
    np.testing.assert_allclose(rescued.x, [1.0, 1.0])


def test_a_failing_backend_leaves_the_solver_usable(monkeypatch, rng):
    levels, lb, ub, G, h = random_problem(rng, 4, levels=2, general=1)
    levels[0].b = levels[0].b * 50  # far away: limits bind, the backend is called
    problem = HierarchyProblem(levels, lb, ub, G, h)
    solver = HierarchySolver("osqp")
    expected = HierarchySolver("osqp").solve(problem).x
    from qpik.core import backends

    original = backends.OSQPWorkspace.solve

    def explode(self, *args):
        raise RuntimeError("backend crashed")

    monkeypatch.setattr(backends.OSQPWorkspace, "solve", explode)
    rescued = solver.solve(problem)  # the exact kernel answers for the crashed backend
    np.testing.assert_array_equal(rescued.x, expected)
    monkeypatch.setattr(backends.OSQPWorkspace, "solve", original)
    np.testing.assert_array_equal(solver.solve(problem).x, expected)


def test_residuals_count_zero_rows():
    # A level whose second row has no Jacobian (a planar arm asked to move in z).
    A = np.array([[1.0, 0.0], [0.0, 0.0]])
    result = solve_hierarchy([Level(A, np.array([0.1, 0.5]), 1e-9)], -np.ones(2), np.ones(2))
    assert result.residuals[0] == pytest.approx(0.5, abs=1e-6)


def test_damping_ignores_structural_zeros_and_costs():
    rng = np.random.default_rng(3)
    J = rng.standard_normal((3, 7))
    J[2] = 0.5 * J[0] + 0.25 * J[1]  # rank 2 by construction (a LookAt-like level)
    level = Level(J, rng.standard_normal(3), 1e-6, np.ones(3))
    result = solve_hierarchy([level], -np.ones(7) * 10, np.ones(7) * 10)
    assert result.damping == [0.0] and 0.05 < result.sigma[0] < np.inf
    # A low-cost posture level is not singular.
    posture = Level(0.01 * np.eye(7), 0.01 * rng.standard_normal(7), 1e-6, np.full(7, 0.01))
    assert solve_hierarchy([posture], -np.ones(7), np.ones(7)).damping == [0.0]
    # A genuinely near-singular level is damped, smoothly.
    near = J.copy()
    near[2] += 1e-3 * rng.standard_normal(7)
    damped = solve_hierarchy([Level(near, np.ones(3), 1e-6, np.ones(3))], -np.ones(7), np.ones(7))
    assert damped.damping[0] > 0


def test_damping_law_and_problem_validation():
    with pytest.raises(qpik.InvalidInput, match="max_damping"):
        DampingLaw(max_damping=float("nan"))
    with pytest.raises(qpik.InvalidInput, match="1e6"):
        DampingLaw(1e300, 1e300)
    with pytest.raises(qpik.InvalidInput, match="level 0"):
        solve_hierarchy([Level(np.ones((2, 3)), np.ones(3))], -np.ones(3), np.ones(3))
    with pytest.raises(qpik.InvalidInput, match="not finite"):
        solve_hierarchy([Level(np.ones((1, 3)), np.array([np.nan]))], -np.ones(3), np.ones(3))
    with pytest.raises(qpik.InvalidInput, match="unknown QP solver"):
        HierarchySolver("nope")


def test_problem_limits_of_other_types_are_converted_or_named():
    """Lists are taken as arrays (the same answer); None, scalars, strings and wrong
    shapes raise InvalidInput naming the field, never an AttributeError or TypeError."""
    levels = [Level(np.eye(3), np.full(3, 2.0))]
    lb, ub, G0, h0 = -np.ones(3), np.ones(3), np.zeros((0, 3)), np.zeros(0)
    ref = HierarchySolver().solve(HierarchyProblem(levels, lb, ub, G0, h0)).x
    for kw in (
        dict(lb=[-1, -1, -1]),
        dict(ub=(1.0, 1.0, 1.0)),
        dict(G=[[0.0, 0.0, 0.0]], h=[5.0]),
    ):
        args = dict(lb=lb, ub=ub, G=G0, h=h0) | kw
        assert np.array_equal(HierarchySolver().solve(HierarchyProblem(levels, **args)).x, ref)
    for kw, field_name in (
        (dict(lb=None), "lb"),
        (dict(ub=None), "ub"),
        (dict(lb=-1.0), "lb"),
        (dict(G=None, h=None), "G"),
        (dict(G=[], h=[]), "G"),
        (dict(h=None), "h"),
        (dict(lb=np.array(["a", "b", "c"])), "lb"),
        (dict(ub=np.ones(4)), "ub"),
        (dict(G=np.ones((1, 2)), h=np.ones(1)), "G"),
    ):
        args = dict(lb=lb, ub=ub, G=G0, h=h0) | kw
        with pytest.raises(qpik.InvalidInput, match=field_name):
            HierarchySolver().solve(HierarchyProblem(levels, **args))
    with pytest.raises(qpik.InvalidInput, match="level 1 must be a Level"):
        HierarchySolver().solve(HierarchyProblem([levels[0], {"A": 1}], lb, ub, G0, h0))


# ------------------------------------------------------------- IK layer against mink
def _mink_cases():
    """(robot, tasks builder, limits builder) combinations of mink's tasks and limits."""

    def frame(position_cost=1.0, orientation_cost=1.0):
        def build(c, rng):
            task = mink.FrameTask("ee", "site", position_cost, orientation_cost)
            other = c.copy()
            other.update(np.clip(c.q + rng.uniform(-0.2, 0.2, c.nv), c.lower, c.upper))
            task.set_target(other.get_transform_frame_to_world("ee", "site"))
            return task

        return build

    def posture(cost):
        def build(c, rng):
            task = mink.PostureTask(c.model, cost=cost)
            task.set_target(np.clip(c.q + rng.uniform(-0.3, 0.3, c.nv), c.lower, c.upper))
            return task

        return build

    def look_at(c, rng):
        task = mink.LookAtTask("ee", "site", cost=1.0)
        task.set_target(c.frame_pose("ee")[0] + rng.uniform(-1, 1, 3) + np.array([0, 0, 1.5]))
        return task

    def axis_align(c, rng):
        task = mink.AxisAlignTask("ee", "site", cost=1.0)
        axis = rng.standard_normal(3)
        task.set_target(axis / np.linalg.norm(axis))
        return task

    def com(c, rng):
        task = mink.ComTask(cost=1.0)
        task.set_target(c.data.subtree_com[1] + rng.uniform(-0.02, 0.02, 3))
        return task

    def damping_task(c, rng):
        return mink.DampingTask(c.model, cost=0.1)

    def position_only(c, rng):
        return frame(1.0, 0.0)(c, rng)

    no_limits = lambda m: []  # noqa: E731
    position = lambda m: [mink.ConfigurationLimit(m)]  # noqa: E731
    both = lambda m: [mink.ConfigurationLimit(m), qpik.limits.velocity_limit_from_model(m)]  # noqa: E731
    cases = []
    for robot in ("panda", "ur5e"):
        for tasks in (
            [frame()],
            [frame(), posture(1e-2)],
            [frame(), posture(1.0)],
            [position_only, posture(1e-2)],
            [look_at, posture(1e-2)],
            [axis_align, posture(0.1)],
            [frame(1.0, 0.1), damping_task],
            [com, posture(0.1)],
        ):
            for limits in (no_limits, position, both):
                cases.append((robot, tasks, limits))
    return cases


def test_flat_mink_tasks_equal_mink_solve_ik_away_from_singularities():
    rng = np.random.default_rng(11)
    compared = 0
    for robot, builders, limits_of in _mink_cases():
        model = qpik.load_robot(robot)
        configuration = qpik.Configuration(model)
        for _attempt in range(5):
            configuration.update(configuration.random_q(rng))
            sigma = np.linalg.svd(configuration.frame_jacobian("ee"), compute_uv=False)
            if sigma[-1] < 0.1:  # near a kinematic singularity: not this test's business
                continue
            tasks = [build(configuration, rng) for build in builders]
            limits = limits_of(model)
            dt = 0.01
            expected = mink.solve_ik(configuration, tasks, dt, "daqp", damping=1e-6, limits=limits)
            solver = qpik.IKSolver(model, tasks, limits, damping=1e-6, max_joint_speed=None)
            result = solver.step(configuration, dt)
            assert result.damping == [0.0], (robot, builders, result.sigma_min)
            np.testing.assert_allclose(result.velocity * dt, expected * dt, atol=1e-9)
            compared += 1
            break
    assert compared >= 40


def test_ik_solver_answers_never_depend_on_history():
    rng = np.random.default_rng(5)
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model)
    limits = [mink.ConfigurationLimit(model), qpik.limits.velocity_limit_from_model(model)]
    frame = qpik.tasks.FrameTask("ee", "site", 1.0, 1.0)
    posture = qpik.tasks.PostureTask(model, cost=0.1)
    states = []
    for _ in range(20):
        configuration.update(configuration.random_q(rng))
        other = configuration.copy()
        other.update(other.random_q(rng))
        states.append((configuration.q.copy(), other.get_transform_frame_to_world("ee", "site")))
    for solver_name, warm in (("auto", False), ("auto", True), ("osqp", False)):
        shared = qpik.IKSolver(
            model, [[frame], [posture]], limits, solver=solver_name, warm_start=warm
        )
        answers = []
        for q, target in states:
            configuration.update(q)
            frame.set_target(target)
            posture.set_target(q)
            answers.append(shared.step(configuration, 0.01).velocity)
        for (q, target), answer in zip(reversed(states), reversed(answers)):
            configuration.update(q)
            frame.set_target(target)
            posture.set_target(q)
            fresh = qpik.IKSolver(
                model, [[frame], [posture]], limits, solver=solver_name, warm_start=warm
            )
            check = (
                np.testing.assert_array_equal
                if not warm
                else lambda a, b: np.testing.assert_allclose(a, b, rtol=0, atol=1e-10)
            )
            check(fresh.step(configuration, 0.01).velocity, answer)
            check(shared.step(configuration, 0.01).velocity, answer)


def test_build_returns_the_levels_qps():
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model)
    configuration.update(configuration.mid_q())
    frame = qpik.tasks.FrameTask("ee", "site", 1.0, 0.5)
    frame.set_target_from_configuration(configuration)
    posture = qpik.tasks.PostureTask(model, cost=0.1)
    posture.set_target(configuration.q)
    solver = qpik.IKSolver(
        model, [[frame], [posture]], [mink.ConfigurationLimit(model)], max_joint_speed=None
    )
    problem = solver.build(configuration, 0.01)
    assert [level.A.shape for level in problem.levels] == [(6, 7), (7, 7)]
    A, b, _ = frame.compute_qp_residual(configuration)
    np.testing.assert_array_equal(problem.levels[0].A, A)
    np.testing.assert_array_equal(problem.levels[0].weights, [1, 1, 1, 0.5, 0.5, 0.5])
    assert problem.levels[0].regularization == solver.damping
    np.testing.assert_allclose(
        problem.ub, 0.95 * (configuration.upper - configuration.q), atol=1e-15
    )
    # Solving the built problem gives the step.
    x = HierarchySolver().solve(problem).x
    np.testing.assert_array_equal(x, solver.step(configuration, 0.01).displacement)


def test_fast_tasks_equal_minks(rng):
    for robot in ("panda", "ur5e", "planar_2r"):
        model = qpik.load_robot(robot)
        configuration = qpik.Configuration(model)
        for frame_type, name in (
            ("site", "ee"),
            ("body", qpik.model.configuration.frame_names(model, "body")[-1]),
        ):
            for _ in range(10):
                configuration.update(configuration.random_q(rng))
                other = configuration.copy()
                other.update(other.random_q(rng))
                costs = rng.uniform(0, 2, 3), rng.uniform(0, 2, 3)
                ours = qpik.tasks.FrameTask(name, frame_type, *costs, gain=0.7, lm_damping=0.1)
                theirs = mink.FrameTask(name, frame_type, *costs, gain=0.7, lm_damping=0.1)
                target = other.get_transform_frame_to_world(name, frame_type)
                ours.set_target(target)
                theirs.set_target(target)
                for a, b in zip(
                    ours.compute_qp_residual(configuration),
                    theirs.compute_qp_residual(configuration),
                ):
                    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
                posture = qpik.tasks.PostureTask(model, cost=rng.uniform(0, 1, model.nv))
                reference = mink.PostureTask(model, cost=posture.cost)
                posture.set_target(other.q)
                reference.set_target(other.q)
                for a, b in zip(
                    posture.compute_qp_residual(configuration),
                    reference.compute_qp_residual(configuration),
                ):
                    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
                assert isinstance(ours, mink.FrameTask) and isinstance(posture, mink.PostureTask)


def test_bounds_of_dofs_fixed_by_a_level_above_do_not_wreck_the_level_below(rng):
    """Level 0 fixes dq0 and dq1 through rows that are not axis-aligned, so the null-space
    basis below has round-off (1e-17) in their rows; dq0 sits at its bound. The level below
    must still find its exact optimum in the free dofs (once a 1e-17 row entered the
    working set with a multiplier of 1e16, and a feasible but wrong point was 'solved')."""
    for trial in range(100):
        rotation = np.linalg.qr(rng.normal(size=(2, 2)))[0]
        Q = np.linalg.qr(rng.normal(size=(5, 5)))[0]
        A0 = rotation @ (Q.T @ Q)[:2]  # rows of dq0, dq1 with round-off in the others
        b0 = rotation @ np.array([0.4, 0.1])  # asks for dq0 = 0.4, beyond its bound 0.15
        A1 = rng.normal(size=(1, 5))  # rank 1 in 3 free dofs: H has eigenvalues 1e-6
        b1 = rng.normal(size=1)
        lb = np.array([-0.15, -0.15, -0.1, -0.1, -0.1])
        ub = -lb
        levels = [Level(A0, b0, 1e-9), Level(A1, b1, 1e-6)]
        result = solve_hierarchy(levels, lb, ub, np.zeros((0, 5)), np.zeros(0), damping_law=None)
        assert result.ok, trial
        # Reference: level 1 over the free dofs dq2..dq4 only (exact basis), by quadprog.
        fixed = result.x[:2]
        A, b = A1[:, 2:], b1 - A1[:, :2] @ fixed
        H = A.T @ A + 1e-6 * np.eye(3)
        c = -A.T @ b
        y = qpsolvers.solve_qp(H, c, lb=lb[2:], ub=ub[2:], solver="quadprog")
        np.testing.assert_allclose(result.x[2:], y, atol=1e-9, err_msg=f"trial {trial}")


@pytest.mark.parametrize("distance", [1e3, 1e4, 1e5])
def test_far_frame_targets_are_solved_at_the_velocity_limits(distance):
    """A frame target far out of reach makes mink's SE(3) rows ~distance, so H ~ 1e10 and
    more while the box keeps dq ~ 0.02: the products cancel far above 1e-8 of |H x + c|.
    The level must still be solved (its stationarity judged against the size of the terms,
    the KKT system re-solved where the iteration's multipliers drift), and equal an
    independent solver's answer to the same QP."""
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    limits = [mink.ConfigurationLimit(model), qpik.limits.velocity_limit_from_model(model)]
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    frame.set_target(mink.SE3.from_translation(np.array([distance, 0.0, 0.0])))
    solver = qpik.IKSolver(model, [[frame]], limits)
    result = solver.step(configuration, 0.01)
    assert result.status == [LevelStatus.SOLVED]
    problem = solver.build(configuration, 0.01)
    (level,) = problem.levels
    H = level.A.T @ level.A + level.regularization * np.eye(model.nv)
    reference = qpsolvers.solve_qp(
        H, -level.A.T @ level.b, lb=problem.lb, ub=problem.ub, solver="quadprog"
    )
    np.testing.assert_allclose(result.displacement, reference, atol=1e-4)
    assert np.abs(result.displacement).max() == pytest.approx(np.abs(problem.ub).max())


def test_warm_start_gives_the_cold_bits_on_damped_levels(rng):
    """Damped levels (rho > 0: the free level's Cholesky answer, free_answer's second
    candidate) solved cold and warm-started after a history of other problems: the same bits.
    Wide boxes (no row binds: the cold level stops at once, the warm one ends its dual method
    with an empty working set) and tight ones (rows bind on some levels), mixed."""
    problems = []
    for trial in range(120):
        n = int(rng.integers(2, 9))
        levels, lb, ub, G, h = random_problem(rng, n, levels=int(rng.integers(1, 4)), general=1)
        for level in levels:
            level.regularization = 10.0 ** rng.uniform(-8, 0)
            if trial % 3 == 0:
                level.b = level.b * 1e-3  # near the start: nothing binds
        if trial % 3 != 2:  # wide boxes and general rows: free levels
            lb, ub, h = lb * 1e3, ub * 1e3, h + 1e3
        problems.append(HierarchyProblem(levels, lb, ub, G, h))
    # each problem after the others (warm starts from their active sets) and again after itself
    free = warm_solves_give_cold_bits(problems, rounds=2)
    assert free > 40  # levels where nothing binds, cold and warm


@pytest.mark.parametrize(
    "options, name",
    [
        ({"eps_abs": -1.0}, "eps_abs"),
        ({"max_iter": "many"}, "max_iter"),
        ({"max_iter": 0}, "max_iter"),
        ({"rho": float("nan")}, "rho"),
        ({"scaling": -3}, "scaling"),
        ({"alpha": 2.0}, "alpha"),
        ({"polishing": "yes"}, "polishing"),
        ({"eps_abs": 0.0, "eps_rel": 0.0}, "eps_abs and eps_rel"),
        ({"bogus": 1}, "bogus"),
    ],
)
def test_osqp_settings_outside_what_osqp_takes_are_refused_when_set(options, name):
    """Pins h8's audit: a value OSQP's setup would refuse (it printed an error at every
    binding step and the dual method answered quietly) is an InvalidInput naming the
    setting, when the solver is made and when its options are set after."""
    with pytest.raises(qpik.InvalidInput, match=name):
        HierarchySolver("osqp", backend_options=options)
    solver = HierarchySolver("osqp")
    with pytest.raises(qpik.InvalidInput, match=name):
        solver.backend_options = options
    with pytest.raises(qpik.InvalidInput, match=name):
        qpik.IKSolver(
            qpik.load_robot("planar_2r"),
            [qpik.tasks.PostureTask(qpik.load_robot("planar_2r"), 1.0)],
            options=qpik.StepOptions(solver="osqp", backend_options=options),
        )
    with pytest.raises(qpik.InvalidInput, match=name):  # (full IK, either engine)
        qpik.solve("planar_2r", {"ee": [1.0, 1.0, 0.0]}, solver="osqp", backend_options=options)
    HierarchySolver("osqp", backend_options={"eps_abs": 1e-6, "polishing": 1, "rho": 0.5})
    # OSQP's earlier names, which it (and mink's callers) still use
    solver = HierarchySolver("osqp", backend_options={"polish": True, "warm_start": False})
    with pytest.raises(qpik.InvalidInput, match="polishing"):
        HierarchySolver("osqp", backend_options={"polish": "yes"})
    n = 2
    problem = HierarchyProblem(
        [Level(np.eye(n), 5 * np.ones(n))], -np.ones(n), np.ones(n), np.zeros((0, n)),
        np.zeros(0),
    )  # fmt: skip
    np.testing.assert_array_equal(solver.solve(problem).x, [1.0, 1.0])


def test_a_problem_of_no_variable_is_solved_by_every_path():
    """Pins h8's audit: n = 0 (A of shape (1, 0)) raised numpy's reshape error on the
    Python path (forced backends, non-float64 input)."""
    for A in (np.zeros((1, 0)), np.zeros((1, 0), dtype=np.float32)):
        problem = HierarchyProblem(
            [Level(A, np.ones(1))], np.zeros(0), np.zeros(0), np.zeros((0, 0)), np.zeros(0)
        )
        for solver in ("auto", "osqp", "quadprog"):
            result = HierarchySolver(solver).solve(problem)
            assert result.status == [LevelStatus.SOLVED] and result.x.shape == (0,)


def test_a_qpsolvers_backend_reports_its_iterations_where_it_gives_them():
    """quadprog's own count (was 0 for every qpsolvers backend)."""
    n = 3
    problem = HierarchyProblem(
        [Level(np.eye(n), 5 * np.ones(n))], -np.ones(n), np.ones(n), np.zeros((0, n)),
        np.zeros(0),
    )  # fmt: skip
    assert HierarchySolver("quadprog").solve(problem).iterations[0] > 0
