"""A level the certified cascade does not solve reports the certificate of the point it
keeps: finite figures, naming the condition that fails (never NaN)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import quadprog
import scipy.linalg
import scipy.optimize

from qpik.core import HierarchyProblem, HierarchySolver, Level, LevelStatus
from qpik.core import kernels as K

DATA = Path(__file__).parents[1] / "data" / "exactness" / "trust_region_pinned_level.npz"


def test_kept_level_has_a_finite_certificate_naming_what_fails():
    z = np.load(DATA)
    levels = [Level(z[f"A{k}"], z[f"b{k}"], float(z[f"reg{k}"])) for k in range(int(z["L"]))]
    problem = HierarchyProblem(levels, z["lb"], z["ub"], z["G"], z["h"])
    result = HierarchySolver(damping_law=None).solve(problem)
    for status, certificate in zip(result.status, result.certificate):
        figures = (
            certificate.primal,
            certificate.stationarity,
            certificate.dual,
            certificate.complementarity,
        )
        assert all(math.isfinite(f) for f in figures), (status, certificate)
        if status == LevelStatus.SOLVED:
            assert certificate.holds
        else:
            assert certificate.failed  # says which condition fails


def _pinned_problem():
    z = np.load(DATA)
    levels = [Level(z[f"A{k}"], z[f"b{k}"], float(z[f"reg{k}"])) for k in range(int(z["L"]))]
    return z, levels, HierarchyProblem(levels, z["lb"], z["ub"], z["G"], z["h"])


def test_pinned_level_is_solved():
    """After levels 0-1 every dof but the last sits on its box bound, and the bound rows of
    dofs 0 and 2 pin a direction of the null space (both on their upper bound, opposite
    normals there): they are eliminated as equalities (drop_pinned), so that a 4e-18
    entry of another bound row's normal no longer closes the last dof's direction. Level
    2 is solved, the levels above keep their rows, and the answer equals an independent
    one: scipy's bounded least squares of level 2 along the numerical null space of the
    levels above."""
    z, levels, problem = _pinned_problem()
    result = HierarchySolver(damping_law=None).solve(problem)
    assert all(s == LevelStatus.SOLVED for s in result.status)
    assert all(c.holds for c in result.certificate)
    x = result.x
    lb, ub, G, h = z["lb"], z["ub"], z["G"], z["h"]
    assert np.all(x >= lb) and np.all(x <= ub) and np.all(G @ x <= h + 1e-15)
    # The levels above are not degraded: their rows as with levels 0-1 alone.
    above = HierarchySolver(damping_law=None).solve(HierarchyProblem(levels[:2], lb, ub, G, h))
    for A in (z["A0"], z["A1"]):
        np.testing.assert_allclose(A @ x, A @ above.x, rtol=0, atol=1e-15)
    # Reference: the levels above leave the null space of [A0; A1] (numerical rank, the
    # cascade's rank tolerance 1e-9), two directions; the one that keeps dofs 0-5 on their
    # bounds is the last dof (to round-off). Level 2 along it, with its bound, by
    # scipy.optimize.lsq_linear (+ the regularisation row).
    N = scipy.linalg.null_space(np.vstack([z["A0"], z["A1"]]), rcond=1e-9)
    assert np.all(np.minimum(x[:6] - lb[:6], ub[:6] - x[:6]) <= 1e-15)
    D = N @ scipy.linalg.null_space(N[:6], rcond=1e-9)
    assert D.shape[1] == 1 and abs(abs(D[6, 0]) - 1.0) < 1e-12
    e6 = np.eye(7)[:, 6]
    A2, b2, reg = z["A2"], z["b2"], float(z["reg2"])
    base = above.x * (1 - e6)
    M = np.vstack([A2 @ e6[:, None], np.sqrt(reg) * np.ones((1, 1))])
    f = np.concatenate([b2 - A2 @ base, [0.0]])
    ref = scipy.optimize.lsq_linear(M, f, bounds=(lb[6], ub[6]), tol=1e-15)
    assert ref.success
    assert abs(x[6] - ref.x[0]) <= 1e-12
    np.testing.assert_allclose(x[:6], above.x[:6], rtol=0, atol=1e-15)


def test_task_on_pinned_dofs_only_is_solved():
    """Level 0 pulls x0 + x1 to 5 against the box (both at 1: in its null space their bound
    rows pin the direction x0 - x1); level 1 is a task on x0 alone, which can no longer
    move (its gradient in null-space coordinates is round-off of Z, measured against the
    full-space gradient), level 2 a task on x2. Every level is solved, x0 and x1 stay on
    their bounds exactly, and x2 equals scipy's bounded least-squares answer."""
    n = 3
    A0, b0 = np.array([[1.0, 1.0, 0.0]]), np.array([5.0])
    A1, b1 = np.array([[1.0, 0.0, 0.0]]), np.array([0.0])
    A2, b2 = np.array([[0.0, 0.0, 1.0]]), np.array([0.5])
    lb, ub = -np.ones(n), np.ones(n)
    reg = 1e-6
    levels = [Level(A0, b0, reg), Level(A1, b1, reg), Level(A2, b2, reg)]
    G, h = np.zeros((0, n)), np.zeros(0)
    for solver in ("auto", "osqp"):
        result = HierarchySolver(solver=solver, damping_law=None).solve(
            HierarchyProblem(levels, lb, ub, G, h)
        )
        assert all(s == LevelStatus.SOLVED for s in result.status), (solver, result.status)
        assert result.x[0] == 1.0 and result.x[1] == 1.0
        ref = scipy.optimize.lsq_linear(
            np.array([[1.0], [np.sqrt(reg)]]), np.array([0.5, 0.0]), bounds=(-1.0, 1.0), tol=1e-15
        )
        assert abs(result.x[2] - ref.x[0]) <= 1e-12


def test_zero_width_box_row_is_an_equality():
    """A dof whose box has width 0 (lb = ub, e.g. a position bound beyond the velocity
    limit) keeps that value exactly and the level is solved: the other dofs equal scipy's
    bounded least squares with the dof substituted."""
    rng = np.random.default_rng(3)
    n = 6
    A, b = rng.normal(size=(4, n)), rng.normal(size=4)
    lb, ub = -0.3 * np.ones(n), 0.3 * np.ones(n)
    lb[2] = ub[2] = 0.1
    reg = 1e-6
    result = HierarchySolver(damping_law=None).solve(
        HierarchyProblem([Level(A, b, reg)], lb, ub, np.zeros((0, n)), np.zeros(0))
    )
    assert result.status == [LevelStatus.SOLVED] and result.certificate[0].holds
    assert result.x[2] == 0.1
    free = [i for i in range(n) if i != 2]
    M = np.vstack([A[:, free], np.sqrt(reg) * np.eye(n - 1)])
    f = np.concatenate([b - A[:, 2] * 0.1, np.zeros(n - 1)])
    ref = scipy.optimize.lsq_linear(M, f, bounds=(lb[free], ub[free]), tol=1e-15)
    np.testing.assert_allclose(result.x[free], ref.x, rtol=0, atol=1e-10)


TALOS = Path(__file__).parents[1] / "data" / "exactness" / "talos_pinned_arms.npz"


def test_talos_arms_pinned_by_the_levels_above_posture_is_solved():
    """A state of benchmarks/step_time.py's fixed-base Talos (hands / torso / head /
    posture, the left hand's target out of reach): after the hands, torso and head, each
    arm has five joints on velocity bounds whose normals are positively dependent in the
    null space (four dimensions), a vertex the levels above chose. The posture level was
    kept_previous (its candidates' multipliers cancelling on those rows); with the rows
    pinned it is solved, and equals daqp's answer to the same level stated independently
    (full space: the levels above's rows held by an orthonormal basis of their numerical
    row space, the box as bounds)."""
    qpsolvers = pytest.importorskip("qpsolvers")
    if "daqp" not in qpsolvers.available_solvers:
        pytest.skip("daqp not installed")
    z = np.load(TALOS)
    A, b, w, starts, reg = z["A"], z["b"], z["w"], z["starts"], z["reg"]
    lb, ub, G, h = z["lb"], z["ub"], z["G"], z["h"]
    L, n = starts.shape[0] - 1, lb.shape[0]
    out = K.solve_cascade(
        A, b, w, starts, reg, lb, ub, G, h, float(z["threshold"]), float(z["max_damping"]),
        float(z["error_scale"]), float(z["rank_tol"]), int(z["max_iter"]), float(z["tol"]),
        np.zeros((L, n), np.int8), True,
    )  # fmt: skip
    x, status, lam2 = out[0], out[1], out[3]
    assert status.tolist() == [K.SOLVED] * L
    _, S, Vt = np.linalg.svd(A[: starts[L - 1]], full_matrices=False)
    R = Vt[S > 1e-9 * max(1.0, S[0])]
    Ak, bk = A[starts[L - 1] :], b[starts[L - 1] :]
    P = Ak.T @ Ak + (reg[L - 1] + lam2[L - 1]) * np.eye(n)
    q = -Ak.T @ bk
    ref = qpsolvers.solve_qp(P, q, A=R, b=R @ x, lb=lb, ub=ub, solver="daqp")
    assert ref is not None
    np.testing.assert_allclose(x, ref, rtol=0, atol=1e-10)
    # the measure: worse only beyond 1e-9 of the larger objective (quadprog's own
    # round-off, and the SVD basis R of this machine's LAPACK, move ref by ~1e-15)
    f_x, f_ref = 0.5 * x @ P @ x + q @ x, 0.5 * ref @ P @ ref + q @ ref
    assert f_x <= f_ref + 1e-9 * max(abs(f_x), abs(f_ref))


@pytest.mark.parametrize("solver", ["auto", "daqp", "quadprog", "osqp"])
def test_levels_below_a_failed_level_have_finite_certificates(solver):
    """Level 0's rows cannot all hold (x0 <= -1 and x0 >= 1): it is infeasible and the
    levels below are not reached. Each of them still reports the certificate of the
    returned point (finite; their primal feasibility there, as every level's), in the
    compiled cascade and in the level-by-level path of a forced backend alike."""
    G = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    h = np.array([-1.0, -1.0])
    levels = [
        Level(np.eye(3), np.array([0.5, 0.0, 0.0])),
        Level(np.array([[1.0, 1.0, 0.0]]), np.array([1.0])),
        Level(np.zeros((0, 3)), np.zeros(0)),
    ]
    problem = HierarchyProblem(levels, -np.ones(3), np.ones(3), G, h)
    result = HierarchySolver(solver=solver, damping_law=None).solve(problem)
    assert result.status[0] is LevelStatus.INFEASIBLE
    assert result.status[1:] == [LevelStatus.NOT_REACHED] * 2
    x = np.asarray(result.x)
    violation = max(float(np.max(G @ x - h)), 0.0)
    for certificate in result.certificate:
        figures = [
            certificate.primal,
            certificate.stationarity,
            certificate.dual,
            certificate.complementarity,
        ]
        assert all(math.isfinite(f) for f in figures), figures
        # the same point, the same rows: every level's primal figure is the same
        assert certificate.primal == result.certificate[0].primal
    assert (result.certificate[0].primal > 0) == (violation > 0)


FLOATING = Path(__file__).parents[1] / "data" / "exactness" / "talos_floating_posture.npz"


@pytest.mark.parametrize("state", range(4))
def test_talos_floating_posture_level_is_solved(state):
    """Four states (steps 115, 145, 163, 310) of benchmarks/step_time.py's floating Talos
    (hands / torso / head / posture). The posture level was kept_previous: its candidate
    failed stationarity alone (3.5e-9 to 4e-8) on a dof no level above touches (the
    component of a unit column of Z, posture near its target there), whose own terms are
    ~1e-16 while the solve leaves eps-relative round-off of |x| in it. Measured against
    the round-off a solve in Z leaves there (|Z|^T |H| dx), the level is solved, and its answer equals
    quadprog's optimum of the same level stated independently (full space: the levels
    above's rows held through an orthonormal basis of their numerical row space, the box
    as rows), objective included."""
    z = np.load(FLOATING)
    A, b, lb, ub = z["A"][state], z["b"][state], z["lb"][state], z["ub"][state]
    w, starts, reg, G, h = z["w"], z["starts"], z["reg"], z["G"], z["h"]
    L, n = starts.shape[0] - 1, lb.shape[0]
    out = K.solve_cascade(
        A, b, w, starts, reg, lb, ub, G, h, float(z["threshold"]), float(z["max_damping"]),
        float(z["error_scale"]), float(z["rank_tol"]), int(z["max_iter"]), float(z["tol"]),
        np.zeros((L, n + G.shape[0]), np.int8), True,
    )  # fmt: skip
    x, status, lam2, cert = out[0], out[1], out[3], np.asarray(out[7])
    assert status.tolist() == [K.SOLVED] * L
    assert np.all(cert <= 1e-9), cert
    above = slice(0, starts[L - 1])
    keep = w[above] > 0
    _, S, Vt = np.linalg.svd(A[above][keep] / w[above][keep, None], full_matrices=False)
    R = Vt[S > 1e-9 * max(1.0, S[0])]
    Ak, bk = A[starts[L - 1] :], b[starts[L - 1] :]
    P = Ak.T @ Ak + (reg[L - 1] + lam2[L - 1]) * np.eye(n)
    q = -Ak.T @ bk
    rows = np.vstack([R, np.eye(n), -np.eye(n)])
    rhs = np.concatenate([R @ x, lb, -ub])
    ref = quadprog.solve_qp(P, -q, rows.T, rhs, R.shape[0])[0]
    np.testing.assert_allclose(x, ref, rtol=0, atol=1e-10)
    # the measure: worse only beyond 1e-9 of the larger objective (quadprog's own
    # round-off, and the SVD basis R of this machine's LAPACK, move ref by ~1e-15)
    f_x, f_ref = 0.5 * x @ P @ x + q @ x, 0.5 * ref @ P @ ref + q @ ref
    assert f_x <= f_ref + 1e-9 * max(abs(f_x), abs(f_ref))


@pytest.mark.parametrize(
    ("offset", "holds"), [(1e-14, True), (1e-10, True), (1e-8, False), (1e-6, False)]
)
def test_stationarity_scale_is_the_round_off_of_the_largest_entry(offset, holds):
    """One level, no limits, optimum x* with one entry 0 and the others 1e-2 (the level's
    own terms on that entry vanish at x*). Moved off x* along that entry by ``offset``
    times max|x|, the stationarity figure is ``offset`` (the gradient there against the
    round-off scale |H| 1 max|x|): a solve's round-off (1e-14) is certified, a move of 1e-8
    relative is caught (the scale of the entry's own terms alone failed both)."""
    n, j = 6, 2
    A = 0.1 * np.eye(n)
    xstar = np.full(n, 1e-2)
    xstar[j] = 0.0
    rho = 1e-6
    b = (A.T @ A + rho * np.eye(n)) @ xstar / 0.1  # A^T (A x* - b) + rho x* = 0
    x = xstar.copy()
    x[j] += offset * np.abs(xstar).max()
    inf = np.full(n, np.inf)
    none = (np.zeros((0, n)), np.zeros(0))
    cert = K.certify_point(A, b, rho, np.eye(n), x, -inf, inf, *none)
    assert bool(cert[1] <= 1e-9) is holds, cert
    assert cert[1] == pytest.approx(offset, rel=1e-6)
    assert K.certify_point(A, b, rho, np.eye(n), xstar, -inf, inf, *none)[1] <= 1e-15


SINGULAR = Path(__file__).parents[1] / "data" / "exactness" / "hqp_singular_objective_slack.npz"


def _singular_problem(extra: float):
    z = np.load(SINGULAR)
    level = Level(z["A0"], z["b0"], float(z["reg0"]) + extra)
    return HierarchyProblem([level], z["lb"], z["ub"], z["G"], z["h"]), z["A0"].shape[0]


def _singular_optimum(problem, k: int) -> float:
    """quadprog's optimum 1/2 |s|^2 of the problem (1e-8 |x|^2 added for strict convexity;
    its effect on the optimum is far below the tolerance used)."""
    A, lb, ub, G, h = problem.levels[0].A, problem.lb, problem.ub, problem.G, problem.h
    n = A.shape[1]
    P = A.T @ A + 1e-8 * np.eye(n)
    fin_l, fin_u = np.isfinite(lb), np.isfinite(ub)
    C = np.vstack([-G, np.eye(n)[fin_l], -np.eye(n)[fin_u]]).T
    b0 = np.concatenate([-h, lb[fin_l], -ub[fin_u]])
    x = quadprog.solve_qp(P, np.zeros(n), C, b0)[0]
    return 0.5 * x[-k:] @ x[-k:]


def test_a_singular_objective_is_solved_with_a_floor():
    """The level solved with 1e-14 of Tikhonov: quadprog's optimum, every row met (the
    case: tests/data/exactness/README.md)."""
    problem, k = _singular_problem(1e-14)
    result = HierarchySolver(damping_law=None).solve(problem)
    assert result.status == [LevelStatus.SOLVED]
    s = result.x[-k:]
    assert 0.5 * s @ s == pytest.approx(_singular_optimum(problem, k), rel=1e-6)
    assert (problem.G @ result.x - problem.h).max() <= 1e-12


def test_a_singular_objective_is_solved_exactly():
    """The same level in the exact mode (no floor): solved at quadprog's optimum, every row
    met. The dofs x are held by the active rows alone (the objective leaves them out): their
    stationarity components are the cancellation of the multipliers' terms, measured against
    those terms (up to the level's largest objective size), not only against 1e-6 of it (it
    was numerical_failure with x = 0, stationarity 1.84e-9; README)."""
    problem, k = _singular_problem(0.0)
    result = HierarchySolver(damping_law=None).solve(problem)
    assert result.status == [LevelStatus.SOLVED]
    assert result.certificate[0].holds
    assert result.certificate[0].stationarity <= 1e-12  # round-off, far below the tolerance
    s = result.x[-k:]
    assert 0.5 * s @ s == pytest.approx(_singular_optimum(problem, k), rel=1e-9)
    assert (problem.G @ result.x - problem.h).max() <= 1e-12
    assert np.all(result.x >= problem.lb) and np.all(result.x <= problem.ub)
    # The same slacks as with the 1e-14 floor (unique: the objective is strictly convex in
    # s; the dofs x, which it leaves out, are not).
    floored = HierarchySolver(damping_law=None).solve(_singular_problem(1e-14)[0])
    np.testing.assert_allclose(result.x[-k:], floored.x[-k:], rtol=0, atol=1e-12)


def _slack_level(seed: int):
    """A slack level (the recovery's shape, qpik.diffik.recovery): objective 1/2 |s|^2 on k
    slacks only, nx dofs x in a box that the objective leaves out, rows G x - s <= h."""
    rng = np.random.default_rng(seed)
    nx, k = int(rng.integers(3, 30)), int(rng.integers(2, 15))
    A = np.hstack([np.zeros((k, nx)), np.eye(k)])
    G = np.hstack([rng.normal(size=(k, nx)), -np.eye(k)])
    h = rng.normal(size=k) - 0.5
    box = rng.uniform(0.01, 0.1)
    lb = np.concatenate([np.full(nx, -box), np.full(k, -np.inf)])
    ub = np.concatenate([np.full(nx, box), np.full(k, np.inf)])
    return HierarchyProblem([Level(A, np.zeros(k), 0.0)], lb, ub, G, h), nx


# seeds 195, 306, 395, ...: the optimum puts s on 0 with a row active at a degenerate vertex
# (the objective's gradient vanishes there): numerical_failure before the zero-multiplier
# certificate (certify.hpp)
@pytest.mark.parametrize(
    "seeds", [range(0, 60), [195, 306, 395, 431, 547, 550, 662, 682, 683, 741, 766, 778]]
)
def test_slack_levels_are_solved_exactly(seeds):
    """Slack levels in the exact mode: every one solved, at quadprog's optimum (1e-10 |x|^2
    added for strict convexity), every row met. Where the optimum has s = 0 with a row
    active, the certificate holds with zero multipliers (the candidate's are round-off)."""
    for seed in seeds:
        problem, nx = _slack_level(seed)
        result = HierarchySolver(damping_law=None).solve(problem)
        assert result.status == [LevelStatus.SOLVED], (seed, result.certificate)
        assert result.certificate[0].holds
        s = result.x[nx:]
        G, h, lb, ub = problem.G, problem.h, problem.lb, problem.ub
        assert (G @ result.x - h).max() <= 1e-9 * (1 + np.abs(h).max())
        assert np.all(result.x >= lb - 1e-12) and np.all(result.x <= ub + 1e-12)
        n = problem.n
        P = problem.levels[0].A.T @ problem.levels[0].A + 1e-10 * np.eye(n)
        fin_l, fin_u = np.isfinite(lb), np.isfinite(ub)
        C = np.vstack([-G, np.eye(n)[fin_l], -np.eye(n)[fin_u]]).T
        b0 = np.concatenate([-h, lb[fin_l], -ub[fin_u]])
        ref = quadprog.solve_qp(P, np.zeros(n), C, b0)[0][nx:]
        assert 0.5 * s @ s <= 0.5 * ref @ ref * (1 + 1e-6) + 1e-12, seed


VERTEX = Path(__file__).parents[1] / "data" / "exactness" / "degenerate_vertex_kept_point.npz"


def test_degenerate_vertex_kept_point_is_certified():
    """erd Romeo LAAS small, exact mode (tests/data/exactness/README.md): level 1 leaves every
    dof of level 2's free directions on a bound, and that point is level 2's optimum; the dual
    method's candidates all fail there, and the level is solved at the point it keeps, by
    multipliers found again in extended precision. Checked here without qpik: the point is a
    KKT point of level 2 (scipy's NNLS on the null space of the levels above, the bounds on
    which it sits), with the objective of the level above unchanged."""
    z = np.load(VERTEX)
    levels = [
        Level(
            z[f"A{k}"], z[f"b{k}"], float(z[f"reg{k}"]), z[f"w{k}"] if f"w{k}" in z.files else None
        )
        for k in range(int(z["L"]))
    ]
    lb, ub = z["lb"], z["ub"]
    solver = HierarchySolver(damping_law=None)
    above = solver.solve(HierarchyProblem(levels[:2], lb, ub, z["G"], z["h"]))
    result = solver.solve(HierarchyProblem(levels[:3], lb, ub, z["G"], z["h"]))
    assert result.status[2] == LevelStatus.SOLVED, result.certificate[2]
    assert result.certificate[2].holds
    x = result.x
    np.testing.assert_allclose(x, above.x, rtol=0, atol=1e-15)  # the kept point (snapped)
    # independent KKT check of level 2 at x
    A0, A1, A2 = (np.asarray(z[f"A{k}"]) for k in range(3))
    N = scipy.linalg.null_space(np.vstack([A0, A1]))
    g = N.T @ (A2.T @ (A2 @ x - z["b2"]))
    low = np.flatnonzero(x - lb <= 1e-12 * (1 + np.abs(lb)))
    high = np.flatnonzero(ub - x <= 1e-12 * (1 + np.abs(ub)))
    normals = np.array([N[i] for i in low] + [-N[i] for i in high]).T
    u, residual = scipy.optimize.nnls(normals, g, maxiter=100_000)
    assert residual <= 1e-9 * np.linalg.norm(g), residual
    # The same bits from a solver whose workspace solved other problems first (the kept
    # point's fallback borrows the last candidate's storage and gives it back).
    busy = HierarchySolver(damping_law=None)
    busy.solve(HierarchyProblem(levels, lb, ub, z["G"], z["h"]))
    busy.solve(_pinned_problem()[2])
    again = busy.solve(HierarchyProblem(levels[:3], lb, ub, z["G"], z["h"]))
    assert np.array_equal(again.x, result.x)
    assert [s.value for s in again.status] == [s.value for s in result.status]
