"""``DampingLaw.lower_trust``: below a damped level, the levels' box shrinks around the
answer so far, by ``lower_trust * sigma / singular_threshold`` of its half-width.

The reference is closed form: level 0 is two unit rows on dofs 0 and 1, the second scaled
by 0.01 (its smallest singular value, below the default threshold 0.05: damped), level 1
asks dofs 2 and 3 for 5 in a box of half-width 1. Level 0's answer is the same whatever is
below it; level 1 gets its box (1) without the trust, and 0.2 = 1 * 0.01 / 0.05 with it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import qpik
from qpik.core import HierarchyProblem, HierarchySolver, Level
from qpik.core import kernels as K


def _problem(scale: float = 0.01) -> HierarchyProblem:
    A0 = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, scale, 0.0, 0.0]])
    A1 = np.eye(4)
    levels = [Level(A0, np.array([1.0, 1.0])), Level(A1, np.array([0.0, 0.0, 5.0, 5.0]))]
    return HierarchyProblem(levels, -np.ones(4), np.ones(4), np.zeros((0, 4)), np.zeros(0))


def _solve(problem: HierarchyProblem, trust: float):
    return HierarchySolver(damping_law=qpik.DampingLaw(lower_trust=trust)).solve(problem)


def test_lower_levels_move_within_the_shrunk_box():
    problem = _problem()
    off, on = _solve(problem, 0.0), _solve(problem, 1.0)
    assert off.sigma[0] == pytest.approx(0.01) and off.damping[0] > 0.0
    assert np.array_equal(off.x[2:], [1.0, 1.0])
    assert on.x[2:] == pytest.approx([0.2, 0.2], abs=1e-12)
    # level 0's answer is its own, not moved by the box below it
    A0 = problem.levels[0].A
    assert np.array_equal(A0 @ on.x, A0 @ off.x)
    assert all(str(s) == "solved" for s in on.status)
    for cert in on.certificate:
        assert max(cert.primal, cert.stationarity, cert.dual, cert.complementarity) < 1e-12


def test_half_the_trust_half_the_box():
    on = _solve(_problem(), 0.5)
    assert on.x[2:] == pytest.approx([0.1, 0.1], abs=1e-12)


def test_an_undamped_level_leaves_the_box_as_it_is():
    problem = _problem(scale=0.5)  # sigma 0.5: above the threshold, no damping
    off, on = _solve(problem, 0.0), _solve(problem, 1.0)
    assert off.damping[0] == 0.0
    assert np.array_equal(on.x, off.x)


def test_off_is_the_default_bit_for_bit():
    problem = _problem()
    default = HierarchySolver().solve(problem)
    assert np.array_equal(default.x, _solve(problem, 0.0).x)


def test_the_level_by_level_path_matches_the_kernel():
    problem = _problem()
    solver = HierarchySolver(damping_law=qpik.DampingLaw(lower_trust=1.0))
    A, b, w, starts, reg = problem.stacked()
    kernel = solver.solve_arrays(A, b, w, starts, reg, problem.lb, problem.ub, problem.G, problem.h)
    warm = np.zeros((2, 4), np.int8)
    python = solver._solve_levels(
        A, b, w, starts, reg, problem.lb, problem.ub, problem.G, problem.h, warm, fallback=True
    )
    assert np.array_equal(python.x, kernel.x)


def test_trust_box_keeps_an_unbounded_dof_and_the_point():
    d = np.array([0.5, 0.0, 2.0])
    lb = np.array([-1.0, -math.inf, 1.0])
    ub = np.array([1.0, 3.0, 3.0])
    tlb, tub = K.trust_box(d, 0.5, lb, ub)
    assert np.array_equal(tlb, [0.0, -math.inf, 1.5])
    assert np.array_equal(tub, [1.0, 3.0, 2.5])
    assert np.all(tlb <= d) and np.all(d <= tub)


@pytest.mark.parametrize("value", [-0.1, 1.5, math.nan, math.inf, True, "1"])
def test_lower_trust_out_of_range_is_refused(value):
    with pytest.raises(qpik.InvalidInput, match="lower_trust"):
        qpik.DampingLaw(lower_trust=value)


def test_trust_box_stays_inside_the_box_for_a_point_just_outside():
    lb, ub = np.array([-1.0, -1.0]), np.array([1.0, 1.0])
    d = np.array([1.0 + 1e-15, -1.0 - 1e-15])  # round-off outside
    tlb, tub = K.trust_box(d, 0.5, lb, ub)
    assert np.all(lb <= tlb) and np.all(tub <= ub) and np.all(tlb <= tub)
    assert np.array_equal(tlb, [0.5, -1.0]) and np.array_equal(tub, [1.0, -0.5])


def _random_hierarchies(count: int = 48):
    from exactness_oracle import problems

    for problem in problems(2026, count):
        if not problem.feasible:
            continue
        levels = [Level(A, b, rho) for A, b, rho in problem.levels]
        yield problem.kind, HierarchyProblem(levels, problem.lb, problem.ub, problem.G, problem.h)


def test_random_hierarchies_keep_the_levels_down_to_the_first_damped_one():
    """On the oracle's random hierarchies (feasible kinds): with the trust, every level is
    still solved and certified and the limits met; the task values of the levels down to
    the first damped one are those without it (the trust acts only below it); a hierarchy
    with no damped level gets the same answer bit for bit."""
    from exactness_oracle import scaled_violation

    damped = 0
    for kind, problem in _random_hierarchies():
        off, on = _solve(problem, 0.0), _solve(problem, 1.0)
        assert all(str(s) == "solved" for s in on.status) == all(
            str(s) == "solved" for s in off.status
        ), kind
        if not all(str(s) == "solved" for s in on.status):
            continue
        assert all(c.holds for c in on.certificate), (kind, on.certificate)
        assert scaled_violation(on.x, problem.lb, problem.ub, problem.G, problem.h) <= 1e-9
        first = next((k for k, lam in enumerate(off.damping) if lam > 0.0), None)
        if first is None or first == len(problem.levels) - 1:
            assert np.array_equal(on.x, off.x), kind
            continue
        damped += 1
        for level in problem.levels[: first + 1]:
            a, b = level.A @ on.x, level.A @ off.x
            assert np.abs(a - b).max() <= 1e-8 * (1.0 + np.abs(b).max()), kind
    assert damped >= 3  # the trust was in play on some of them
