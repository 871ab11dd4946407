"""A forced backend's answer (``solver="daqp"``, ``"quadprog"``, ``"osqp"``...) is made exact
on the rows it leaves outside their bounds too: no box row is left past its bound, however
small the bounds (found by ``benchmarks/fuzz.py --seed 7301``, case erd:182)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from qpik.core import HierarchySolver, LevelStatus
from qpik.core.backends import working_set_with_violated

DATA = Path(__file__).parents[1] / "data" / "exactness" / "backend_box_row_overshoot.npz"

#: The backends installed here (qpsolvers' names; daqp, quadprog and osqp are dependencies).
BACKENDS = [
    name
    for name, module in (("daqp", "daqp"), ("quadprog", "quadprog"), ("osqp", "osqp"))
    if importlib.util.find_spec(module) is not None
]


def _arrays() -> tuple[np.ndarray, ...]:
    z = np.load(DATA)
    return tuple(z[k] for k in ("A", "b", "w", "starts", "reg", "lb", "ub", "G", "h"))


@pytest.mark.parametrize("backend", BACKENDS)
def test_backend_meets_tiny_velocity_bounds_exactly(backend):
    """erd Baxter, floating base, one IKSolver step at ``dt = 1e-9`` (the fuzz's boundary):
    velocity bounds of 1.5 rad/s are displacement bounds of 1.5e-9, while the unbounded free
    joint moves O(1). The posture level's minimiser passes dof 7's upper bound by 5.5e-12,
    which the dual method's tolerance and the certificate's primal measure (scaled by
    ``1 + |bound|``) both accepted: a 0.37 % overshoot of the velocity limit, every level
    ``solved``. Held on the bound, the row is met exactly, and the answer is the exact
    solver's (``"auto"``) bit for bit."""
    arrays = _arrays()
    lb, ub = arrays[5], arrays[6]
    exact = HierarchySolver().solve_arrays(*arrays)
    result = HierarchySolver(solver=backend).solve_arrays(*arrays)
    assert all(s == LevelStatus.SOLVED for s in result.status), result.status
    assert np.all(result.x <= ub) and np.all(result.x >= lb)
    assert exact.x[7] == ub[7]
    np.testing.assert_array_equal(result.x, exact.x)


def test_violated_rows_join_the_working_set():
    """Rows strictly outside their bounds at ``z`` are added (+1 on a lower bound, -1 on an
    upper), the solver's own entries kept, rows met (even on a bound) left as they were."""
    C = np.eye(4)
    lo = np.array([0.0, 0.0, 0.0, 0.0])
    hi = np.array([1.0, 1.0, 1.0, 1.0])
    z = np.array([-1e-300, 1.0 + 2e-16, 1.0, 0.5])
    act = np.array([0, 0, 0, -1], np.int8)
    np.testing.assert_array_equal(working_set_with_violated(z, act, C, lo, hi, 4), [1, -1, 0, -1])
    np.testing.assert_array_equal(working_set_with_violated(z, None, C, lo, hi, 4), [1, -1, 0, 0])
    np.testing.assert_array_equal(working_set_with_violated(None, act, C, lo, hi, 4), act)
