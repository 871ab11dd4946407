"""A forced backend (``solver="daqp"``, ``"quadprog"``, ``"osqp"``...) proposes each level's
active set; the exact cascade, started from them, answers. So its answer is the exact
solver's: no box row left past its bound, however small the bounds (``benchmarks/fuzz.py
--seed 7301``, case erd:182), and the same minimiser where a level has many (found by random
stacks on erd Go1, exact mode)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from qpik.core import HierarchySolver, LevelStatus
from qpik.core.backends import working_set_with_violated

DATA = Path(__file__).parents[1] / "data" / "exactness" / "backend_box_row_overshoot.npz"
TIE = Path(__file__).parents[1] / "data" / "exactness" / "backend_canonical_tie.npz"

#: The backends installed here (qpsolvers' names; daqp, quadprog and osqp are dependencies).
BACKENDS = [
    name
    for name, module in (("daqp", "daqp"), ("quadprog", "quadprog"), ("osqp", "osqp"))
    if importlib.util.find_spec(module) is not None
]


def _arrays(path: Path = DATA) -> tuple[np.ndarray, ...]:
    z = np.load(path)
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


@pytest.mark.parametrize("backend", BACKENDS)
def test_backend_answers_the_canonical_minimiser(backend):
    """erd Go1 on a floating base, exact mode (``damping=0``, ``damping_law=None``): four
    levels whose optima are not unique (every level's objective the same at both points, the
    base's yaw free of every task). The backends, level by level, returned a minimiser 0.031
    rad from the exact solver's in one dof; they now propose active sets and the exact cascade
    answers: the canonical minimiser (module doc of qpik.core.cascade), bit for bit, with the
    backend's iterations and name kept in the result."""
    arrays = _arrays(TIE)
    exact = HierarchySolver(damping_law=None).solve_arrays(*arrays)
    result = HierarchySolver(solver=backend, damping_law=None).solve_arrays(*arrays)
    assert all(s == LevelStatus.SOLVED for s in result.status), result.status
    np.testing.assert_array_equal(result.x, exact.x)
    # (OSQP may fail on a level: the exact kernel proposes there, "osqp failed: auto")
    assert all(name.startswith(backend) for name in result.backend), result.backend
    assert [c.primal for c in result.certificate] == [c.primal for c in exact.certificate]


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


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_backends_answer_does_not_depend_on_what_it_solved_before(backend):
    """One backend solver instance (OSQP keeps a warm workspace per level and size) solves
    both reproducers in turn, twice, with the default law and with none: every answer equals
    a fresh instance's and the exact solver's, bit for bit."""
    problems = [(_arrays(DATA), {}), (_arrays(TIE), {"damping_law": None})]
    busy = {
        "default": HierarchySolver(solver=backend),
        "none": HierarchySolver(solver=backend, damping_law=None),
    }
    for _round in range(2):
        for arrays, kwargs in [*problems, *problems[::-1]]:
            got = busy["none" if kwargs else "default"].solve_arrays(*arrays)
            fresh = HierarchySolver(solver=backend, **kwargs).solve_arrays(*arrays)
            exact = HierarchySolver(**kwargs).solve_arrays(*arrays)
            assert got.x.tobytes() == fresh.x.tobytes() == exact.x.tobytes()
            assert [s.value for s in got.status] == [s.value for s in exact.status]


def test_osqp_is_not_called_on_data_that_is_not_finite(capfd):
    """An infinite H (a weight of 1e300, squared): OSQP's setup would print its own error
    from C ("ERROR in LDL_factor ... non-convex") to the terminal. The workspace returns no
    answer without calling it, and prints nothing."""
    from qpik.core import backends

    workspace = backends.OSQPWorkspace(2, 2)
    H = np.array([[np.inf, 0.0], [0.0, 1.0]])
    solution = workspace.solve(H, np.zeros(2), np.eye(2), -np.ones(2), np.ones(2))
    assert solution.x is None and solution.status == "non_finite"
    assert workspace.setups == 0
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    finite = workspace.solve(np.eye(2), np.ones(2), np.eye(2), -np.ones(2), np.ones(2))
    np.testing.assert_allclose(finite.x, [-1.0, -1.0], atol=1e-3)
