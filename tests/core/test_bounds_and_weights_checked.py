"""Bounds nothing can meet and rows' costs that are no costs are refused by
:meth:`HierarchySolver.solve` with :class:`qpik.InvalidInput` naming the field, in the
compiled one-call path as in the checks (``HierarchyProblem.validate``): before, ``lb =
+inf`` gave ``x = inf`` labelled solved, ``h = -inf`` was dropped (the row left unmet, the
level solved), and NaN or negative weights switched the damping law off (another answer,
solved). An infinite bound on its open side still means no bound."""

from __future__ import annotations

import numpy as np
import pytest

import qpik
from qpik.core import HierarchyProblem, HierarchySolver, Level

A = np.array([[1.0, 0.0, 0.0], [0.0, 1e-3, 0.0]])
b = np.array([1.0, 1.0])


def problem(lb=None, ub=None, G=None, h=None, **level):
    n = 3
    return HierarchyProblem(
        [Level(A, b, **level)],
        -10 * np.ones(n) if lb is None else np.asarray(lb),
        10 * np.ones(n) if ub is None else np.asarray(ub, float),
        np.zeros((0, n)) if G is None else np.asarray(G, float),
        np.zeros(0) if h is None else np.asarray(h, float),
    )


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        ({"lb": [np.inf, -1, -1]}, r"lb\[0\] is inf"),
        ({"ub": [1, -np.inf, 1]}, r"ub\[1\] is -inf"),
        ({"lb": [np.inf] * 3, "ub": [np.inf] * 3}, r"lb\[0\] is inf"),
        ({"lb": [0, 2, 0], "ub": [1, 1, 1]}, r"lb\[1\] = 2.0 > ub\[1\] = 1.0"),
        ({"G": [[1.0, 0.0, 0.0]], "h": [-np.inf]}, r"h\[0\] is -inf"),
        ({"G": [[np.inf, 0.0, 0.0]], "h": [1.0]}, "G has a NaN or infinite entry"),
        ({"weights": np.array([1.0, np.nan])}, "weights"),
        ({"weights": np.array([-1.0, -1.0])}, "weights"),
        ({"weights": np.array([np.inf, 1.0])}, "weights"),
        ({"regularization": "x"}, "regularization"),
        ({"regularization": np.ones(3)}, "regularization"),
    ],
)
@pytest.mark.parametrize("solver", ["auto", "quadprog"])
def test_a_bound_or_cost_that_cannot_be_meant_is_refused(kwargs, fragment, solver):
    if solver == "quadprog":
        pytest.importorskip("quadprog")
    with pytest.raises(qpik.errors.InvalidInput, match=fragment):
        HierarchySolver(solver=solver).solve(problem(**kwargs))


def test_an_infinite_bound_on_its_open_side_is_no_bound():
    free = HierarchySolver(damping_law=None).solve(
        problem(lb=[-np.inf] * 3, ub=[np.inf] * 3, G=[[1.0, 0, 0]], h=[np.inf])
    )
    assert all(s == "solved" for s in free.status)
    np.testing.assert_allclose(free.x, [1.0, 1000.0, 0.0], rtol=1e-12)
    weighted = HierarchySolver().solve(problem(weights=np.array([0.0, 2.0])))
    assert all(s == "solved" for s in weighted.status)


def test_max_iter_beyond_the_engines_range_is_refused_when_set():
    with pytest.raises(qpik.errors.InvalidOption, match="max_iter"):
        HierarchySolver(max_iter=2**70)
    assert HierarchySolver(max_iter=10**9).max_iter == 10**9


def test_complex_or_text_limits_are_refused_not_cast():
    """A complex bound (a float cast drops its imaginary part, with only numpy's warning)
    or a text one (a cast would parse it) is not numbers: InvalidArgumentType naming it."""
    for lb in (np.array([-1.0, -1.0 + 1.0j, -1.0]), np.array(["-1", "-1", "-1"])):
        with pytest.raises(qpik.errors.InvalidArgumentType, match="lb"):
            HierarchySolver().solve(problem(lb=lb))
