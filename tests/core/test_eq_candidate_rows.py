"""A damped level whose final working set holds up to 16 rows (a humanoid's weighted level
with its joints at their limits: mink's humanoid_g1 keeps 12 bounds active each step) ends in
the normal equations' equality-constrained candidate (eq_candidate in
qpik/_cpp/core/cascade.hpp: N's factor and the q x q Schur complement) rather than the QR
re-solve, where its certificate holds.

Checked against an independent QP solver (quadprog, no qpik code) on levels where 9 to 16
rows bind, with every level solved and certified, and cold against warm starts bit for bit."""

from __future__ import annotations

import numpy as np
import qpsolvers
from conftest import warm_solves_give_cold_bits

from qpik.core import HierarchyProblem, HierarchySolver, Level


def _level_binding_many(rng: np.random.Generator) -> tuple[HierarchyProblem, np.ndarray, float]:
    """One damped level on n variables whose unconstrained answer leaves about 9 to 16 of
    them past a tight box (their bounds bind), the others inside a wide one."""
    n = int(rng.integers(24, 50))
    m = int(rng.integers(n // 2, 2 * n))
    A = rng.standard_normal((m, n)) * np.logspace(0, -1.5, n)  # graded columns
    rho = 10.0 ** rng.uniform(-3, -0.5)
    x_free = rng.standard_normal(n)
    b = A @ x_free
    tight = rng.choice(n, size=int(rng.integers(9, 17)), replace=False)
    lb, ub = -10.0 * np.ones(n), 10.0 * np.ones(n)
    width = 0.2 * np.abs(x_free[tight])
    lb[tight] = np.where(x_free[tight] > 0, -1.0, -width)
    ub[tight] = np.where(x_free[tight] > 0, width, 1.0)
    problem = HierarchyProblem([Level(A, b, rho)], lb, ub, np.zeros((0, n)), np.zeros(0))
    return problem, A.T @ A + rho * np.eye(n), float(rho)


def test_levels_with_many_active_rows_match_an_independent_qp_solver():
    rng = np.random.default_rng(2026)
    counts = []
    for _ in range(60):
        problem, H, _rho = _level_binding_many(rng)
        level = problem.levels[0]
        result = HierarchySolver(damping_law=None).solve(problem)
        assert result.ok, result.status
        reference = qpsolvers.solve_qp(
            H, -level.A.T @ level.b, lb=problem.lb, ub=problem.ub, solver="quadprog"
        )
        scale = 1.0 + np.abs(reference).max()
        np.testing.assert_allclose(result.x, reference, atol=1e-9 * scale, rtol=0)
        certificate = result.certificate[0]
        assert max(certificate.primal, certificate.stationarity, certificate.dual) < 1e-9
        counts.append(int(np.count_nonzero(result.active)))
    counts = np.array(counts)
    assert ((counts > 8) & (counts <= 16)).sum() >= 30, counts  # (the candidate's range)


def test_many_active_rows_cold_and_warm_give_the_same_bits():
    rng = np.random.default_rng(77)
    problems = [_level_binding_many(rng)[0] for _ in range(30)]
    warm_solves_give_cold_bits(problems)
