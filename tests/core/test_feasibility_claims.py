"""The dual method's infeasibility claim at level 0 is checked before it is reported.

Rows with an empty interior (an equality written as two inequalities, ``E x <= e`` and
``-E x <= -e``) at a tight box, under a level that leaves most dofs out (``H`` singular, no
regularisation): the dual method, on the floor that makes ``H`` definite, stopped on a row it
could meet and reported ``infeasible`` on 81 of 300 such feasible problems. The claim is now
checked by the same dual method on the identity Hessian (the nearest point meeting the rows)
and, where that finds one, the level is solved from it (``detail::feasible_after_all``).
Reference: quadprog with the equalities as equalities (no pair), the level's objective plus
``1e-10 |x|^2`` for strict convexity."""

from __future__ import annotations

import numpy as np
import pytest
import quadprog

from qpik.core import HierarchyProblem, HierarchySolver, Level, LevelStatus


def _equality_pairs(seed: int, rho: float):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 20))
    me = int(rng.integers(1, max(2, n // 2)))
    x_star = rng.uniform(-1, 1, n)  # feasible by construction, strictly inside the box
    E = rng.normal(size=(me, n))
    e = E @ x_star
    lb, ub = x_star - rng.uniform(0.1, 1, n), x_star + rng.uniform(0.1, 1, n)
    A = rng.normal(size=(int(rng.integers(1, 8)), n))
    b = rng.normal(size=A.shape[0])
    G, h = np.vstack([E, -E]), np.concatenate([e, -e])
    return HierarchyProblem([Level(A, b, rho)], lb, ub, G, h), (A, b, E, e)


def _reference(problem, A, b, E, e, rho):
    n = problem.n
    P = A.T @ A + (rho + 1e-10) * np.eye(n)
    C = np.vstack([E, np.eye(n), -np.eye(n)]).T
    rhs = np.concatenate([e, problem.lb, -problem.ub])
    x = quadprog.solve_qp(P, A.T @ b, C, rhs, meq=E.shape[0])[0]
    return 0.5 * np.sum((A @ x - b) ** 2) + 0.5 * rho * x @ x


@pytest.mark.parametrize("rho", [0.0, 1e-12])
def test_equalities_as_inequality_pairs_are_feasible(rho):
    for seed in range(80):
        problem, (A, b, E, e) = _equality_pairs(seed, rho)
        result = HierarchySolver(damping_law=None).solve(problem)
        assert result.status == [LevelStatus.SOLVED], (seed, result.certificate)
        x = result.x
        assert np.abs(E @ x - e).max() <= 1e-9 * (1 + np.abs(e).max()), seed
        assert np.all(x >= problem.lb - 1e-12) and np.all(x <= problem.ub + 1e-12)
        ours = 0.5 * np.sum((A @ x - b) ** 2) + 0.5 * rho * x @ x
        ref = _reference(problem, A, b, E, e, rho)
        assert ours <= ref + 1e-7 * max(1.0, abs(ref)), (seed, ours, ref)


def test_a_true_infeasibility_is_still_reported():
    """The same rows made inconsistent (e and e + 0.1): infeasible, certified primal."""
    problem, (A, b, E, e) = _equality_pairs(3, 0.0)
    G = np.vstack([E, -E])
    h = np.concatenate([e, -(e + 0.1)])
    bad = HierarchyProblem(problem.levels, problem.lb, problem.ub, G, h)
    result = HierarchySolver(damping_law=None).solve(bad)
    assert result.status[0] == LevelStatus.INFEASIBLE
