"""eqp_ls's folded least-squares step (qpik/_cpp/core/certify.hpp, reg_lstsq_into): a damped
level (rho > 0) of 12 or more free directions (r) with rows held active is re-solved from
A Z W and sqrt(rho) I instead of the pivoted QR of B W. The answer must be the damped
problem's minimiser: checked against quadprog on min 1/2 |A x - b|^2 + rho/2 |x|^2 within a
box, with rows of A few (m <= r - q: the by-rows layout) and many (the by-columns layout)."""

from __future__ import annotations

import numpy as np
import pytest
import quadprog

from qpik.core import HierarchyProblem, HierarchySolver, Level, LevelStatus


def _reference(A, b, rho, lb, ub):
    n = A.shape[1]
    H = A.T @ A + rho * np.eye(n)
    a = A.T @ b
    C = np.hstack([np.eye(n), -np.eye(n)])
    return quadprog.solve_qp(H, a, C, np.concatenate([lb, -ub]))[0]


@pytest.mark.parametrize("m", [3, 12, 40])
@pytest.mark.parametrize("rho", [1e-2, 1e-5])
def test_damped_level_with_active_boxes_is_the_minimiser(m, rho):
    rng = np.random.default_rng(1000 + m)
    solver = HierarchySolver(damping_law=None)
    held = 0
    for _ in range(20):
        n = int(rng.integers(14, 30))
        A = rng.normal(size=(m, n)) * rng.uniform(0.1, 3.0, size=(m, 1))
        b = rng.normal(size=m) * 3.0
        lb = -rng.uniform(0.05, 0.5, size=n)
        ub = rng.uniform(0.05, 0.5, size=n)
        res = solver.solve(
            HierarchyProblem([Level(A, b, rho)], lb, ub, np.zeros((0, n)), np.zeros(0))
        )
        assert res.status[0] is LevelStatus.SOLVED
        x = np.asarray(res.x)
        ref = _reference(A, b, rho, lb, ub)
        on = np.sum(np.isclose(x, lb) | np.isclose(x, ub))
        held += on > 0
        scale = 1.0 + np.abs(ref).max()
        assert np.abs(x - ref).max() <= 1e-8 * scale, (n, on, np.abs(x - ref).max())
    assert held  # some answers hold rows (eqp_ls then folds: n >= 14)
