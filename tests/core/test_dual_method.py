"""The dual active-set method (solve_qp, qpik/_cpp/core/qp.hpp) on QPs that make it add and
drop many rows: its answers meet the KKT conditions, an iteration limit ends in the typed
MAX_ITER status, and a cascade that kept its workspace after larger solves (many dual
iterations, factors and rotations of other sizes left in its storage) gives the bits of a
fresh one."""

from __future__ import annotations

import numpy as np
import pytest

from qpik.core import HierarchyProblem, HierarchySolver, Level
from qpik.core import kernels as K

SOLVED, MAX_ITER = 0, 1


def _qp(rng: np.random.Generator, n: int, p: int, box: float, diagonal: bool = False):
    M = rng.standard_normal((n + 2, n))
    # a diagonal H: J = L^-T diagonal, so a unit row's d has one nonzero and most of the
    # rotations that add it are skipped (h = 0)
    H = np.diag(rng.uniform(0.5, 2.0, n)) if diagonal else M.T @ M + 1e-3 * np.eye(n)
    c = 3.0 * rng.standard_normal(n)
    # unit rows (box) first, then general rows: the first adds meet J = L^-T's zeros
    # (rotations skipped), the general rows make the method drop rows again
    C = np.vstack([np.eye(n), rng.standard_normal((p, n))])
    lo = np.concatenate([-box * np.ones(n), -np.inf * np.ones(p)])
    hi = np.concatenate([box * np.ones(n), rng.uniform(0.0, 0.2, p)])
    return H, c, C, lo, hi


def _kkt_residuals(H, c, C, lo, hi, x):
    """Primal violation and the best stationarity residual over u >= 0 on the active rows."""
    cx = C @ x
    primal = max(0.0, float(np.max(np.maximum(lo - cx, cx - hi))))
    tol = 1e-7 * (1.0 + np.abs(cx))
    at_lo, at_hi = np.abs(cx - lo) <= tol, np.abs(cx - hi) <= tol
    N = np.vstack([C[at_lo], -C[at_hi]]).T  # H x + c = N u, u >= 0
    g = H @ x + c
    if N.shape[1] == 0:
        return primal, float(np.linalg.norm(g)), 0.0
    u, *_ = np.linalg.lstsq(N, g, rcond=None)
    return (
        primal,
        float(np.linalg.norm(N @ u - g) / (1.0 + np.linalg.norm(g))),
        float(-min(0.0, u.min())),
    )


@pytest.mark.parametrize("diagonal", [False, True])
@pytest.mark.parametrize("seed", range(8))
def test_many_adds_and_drops_end_at_a_kkt_point(seed, diagonal):
    rng = np.random.default_rng(100 + seed)
    n, p = 12 + seed, 10 + 2 * seed
    H, c, C, lo, hi = _qp(rng, n, p, 0.05 + 0.02 * seed, diagonal)
    warm = np.zeros(C.shape[0], np.int8)
    x, status, iterations, active = K.solve_qp(H, c, C, lo, hi, warm, 10 * n + 50, 1e-12, True)[:4]
    assert status == SOLVED
    assert iterations > 3  # the method worked through a set, not one step
    primal, stationarity, dual = _kkt_residuals(H, c, C, lo, hi, x)
    assert primal <= 1e-9 and stationarity <= 1e-7 and dual <= 1e-9
    # the same inputs, the same bits
    again = K.solve_qp(H, c, C, lo, hi, warm, 10 * n + 50, 1e-12, True)
    assert np.array_equal(again[0], x) and again[1:3] == (status, iterations)


def test_an_iteration_limit_ends_in_max_iter():
    rng = np.random.default_rng(3)
    H, c, C, lo, hi = _qp(rng, 16, 20, 0.05)
    warm = np.zeros(C.shape[0], np.int8)
    full = K.solve_qp(H, c, C, lo, hi, warm, 500, 1e-12, True)
    assert full[1] == SOLVED and full[2] > 4
    for limit in (0, 1, 3, full[2] - 1):
        cut = K.solve_qp(H, c, C, lo, hi, warm, limit, 1e-12, True)
        assert cut[1] == MAX_ITER and cut[2] == limit + 1


def _humanoid_like(rng: np.random.Generator, n: int) -> HierarchyProblem:
    rng.standard_normal(n)  # (a draw the recorded cases were made after)
    levels = [
        Level(0.3 * rng.standard_normal((6, n)), np.zeros(6)),
        Level(0.4 * rng.standard_normal((8, n)), 0.01 * rng.standard_normal(8)),
        Level(np.eye(n), 0.05 * rng.standard_normal(n)),
    ]
    lb, ub = -rng.uniform(0.005, 0.03, n), rng.uniform(0.005, 0.03, n)
    G = 0.2 * rng.standard_normal((5, n))
    return HierarchyProblem(levels, lb, ub, G, rng.uniform(0.0, 0.002, 5))


def _bits(result) -> tuple:
    cert = [(c.primal, c.stationarity, c.dual, c.complementarity) for c in result.certificate]
    return (result.x.tobytes(), result.active.tobytes(), result.status, result.iterations, cert)


def test_a_kept_workspace_after_larger_dual_solves_gives_fresh_bits():
    rng = np.random.default_rng(11)
    problems = [_humanoid_like(rng, n) for n in (30, 12, 24, 9, 30, 17)]
    assert any(sum(HierarchySolver(damping_law=None).solve(p).iterations) > 10 for p in problems)
    reused = HierarchySolver(damping_law=None)
    for problem in problems + problems[::-1]:
        assert _bits(reused.solve(problem)) == _bits(
            HierarchySolver(damping_law=None).solve(problem)
        )
