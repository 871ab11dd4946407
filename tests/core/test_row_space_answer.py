"""A damped level of few rows (m < r free directions, 2 m <= r or m <= 8: a humanoid's feet or
CoM level, an arm's frame task) takes
its free answer through the space of its rows (row_space_candidate in
qpik/_cpp/core/cascade.hpp, an m x m factor rather than the r x r normal equations).

Checked against a long-double solve of the same least squares (no qpik code in it), against
the QP path of an independent solver where rows bind, and cold against warm starts bit for
bit (the cold cascade tries the row-space answer before it makes H; a warm level reaches the
same candidate through exact_level's empty working set)."""

from __future__ import annotations

import numpy as np
import pytest
import qpsolvers
from conftest import warm_solves_give_cold_bits

from qpik.core import HierarchyProblem, HierarchySolver, Level


def _solve_long_double(K: np.ndarray, b: np.ndarray) -> np.ndarray:
    """K x = b by Gaussian elimination in np.longdouble (K symmetric positive definite)."""
    K = K.copy()
    b = b.copy()
    n = len(b)
    for i in range(n):
        for j in range(i + 1, n):
            f = K[j, i] / K[i, i]
            K[j, i:] -= f * K[i, i:]
            b[j] -= f * b[i]
    x = np.zeros(n, dtype=np.longdouble)
    for i in reversed(range(n)):
        x[i] = (b[i] - K[i, i + 1 :] @ x[i + 1 :]) / K[i, i]
    return x


def _damped_least_squares(A: np.ndarray, b: np.ndarray, rho: float) -> np.ndarray:
    """argmin |A x - b|^2 + rho |x|^2 = A^T (A A^T + rho I)^-1 b, in long double."""
    Al = A.astype(np.longdouble)
    K = Al @ Al.T + np.longdouble(rho) * np.eye(A.shape[0], dtype=np.longdouble)
    return (Al.T @ _solve_long_double(K, b.astype(np.longdouble))).astype(float)


def _empty_rows(n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros((0, n)), np.zeros(0)


@pytest.mark.parametrize("seed", range(4))
def test_free_level_of_few_rows_matches_a_long_double_solve(seed):
    """One level, m rows (2 m <= n or m <= 8, m < n), n variables, rho > 0, a box no answer reaches: the answer is
    the damped least-squares minimiser to a few ulps (the row-space candidate, refined)."""
    rng = np.random.default_rng(1000 + seed)
    worst = 0.0
    for _ in range(40):
        n = int(rng.integers(6, 40))
        m = int(rng.integers(1, max(n // 2, min(n - 1, 8)) + 1))  # (row_space_level's levels)
        # rows of graded sizes (a Jacobian's: singular values over about three decades)
        U, _, Vt = np.linalg.svd(rng.standard_normal((m, n)), full_matrices=False)
        A = (U * np.logspace(0, -rng.uniform(0, 3), m)) @ Vt
        b = rng.standard_normal(m)
        rho = 10.0 ** rng.uniform(-7, -2)
        result = HierarchySolver(damping_law=None).solve(
            HierarchyProblem(
                [Level(A, b, rho)], -1e6 * np.ones(n), 1e6 * np.ones(n), *_empty_rows(n)
            )
        )
        assert result.ok, result.status
        reference = _damped_least_squares(A, b, rho)
        worst = max(worst, np.abs(result.x - reference).max() / np.abs(reference).max())
    assert worst < 1e-13, worst


def test_few_rows_binding_box_matches_an_independent_qp_solver():
    """Where the box binds, the row-space try fails its rows and the level takes the dual
    method (the general path): the answer is still the QP's optimum."""
    rng = np.random.default_rng(7)
    binding = 0
    for _ in range(80):
        n = int(rng.integers(8, 30))
        m = int(rng.integers(1, n // 2 + 1))
        A = rng.standard_normal((m, n))
        b = rng.standard_normal(m) * 3.0
        rho = 10.0 ** rng.uniform(-5, -2)
        lb = -rng.uniform(0.05, 0.4, n)
        ub = rng.uniform(0.05, 0.4, n)
        result = HierarchySolver(damping_law=None).solve(
            HierarchyProblem([Level(A, b, rho)], lb, ub, *_empty_rows(n))
        )
        assert result.ok, result.status
        H = A.T @ A + rho * np.eye(n)
        reference = qpsolvers.solve_qp(H, -A.T @ b, lb=lb, ub=ub, solver="quadprog")
        np.testing.assert_allclose(result.x, reference, atol=1e-9)
        binding += bool(result.active.any())
    assert binding > 40


def test_few_rows_levels_cold_and_warm_give_the_same_bits():
    """Damped levels of few rows over several levels, cold and warm-started after the other
    problems (with and without the damping law): bit for bit, answers and active sets."""
    rng = np.random.default_rng(11)
    problems = []
    for trial in range(60):
        n = int(rng.integers(10, 32))
        levels = []
        for _ in range(int(rng.integers(1, 4))):
            m = int(rng.integers(1, max(2, n // 4)))
            levels.append(
                Level(
                    rng.standard_normal((m, n)), rng.standard_normal(m), 10.0 ** rng.uniform(-7, -2)
                )
            )
        width = 1e3 if trial % 2 else rng.uniform(0.1, 0.6)
        lb = -width * np.ones(n)
        ub = width * np.ones(n)
        problems.append(HierarchyProblem(levels, lb, ub, *_empty_rows(n)))
    assert warm_solves_give_cold_bits(problems) > 30
