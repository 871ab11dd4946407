"""A cold damped level whose unconstrained minimiser leaves a few rows tries, before the dual
method, the working set guessed from that minimiser (primal_guess in
qpik/_cpp/core/cascade.hpp): the rows it leaves, corrected by the most negative multiplier
or the most violated row, each candidate exact_level's own (eq_candidate) and certified as
exact_level certifies it. Where it holds, the level reports the candidates made as its
iterations (the dual method makes one per row that enters its working set).

Checked against closed forms and the independent lexicographic reference
(tests/exactness_oracle.py: quadprog level by level, no qpik code), and
cold against warm starts (the dual method from the previous set, then exact_level) bit for
bit."""

from __future__ import annotations

import numpy as np
from conftest import warm_solves_give_cold_bits
from exactness_oracle import reference_answer

from qpik.core import HierarchyProblem, HierarchySolver, Level


def _separable(n: int, outside: dict, rho: float) -> HierarchyProblem:
    """min 1/2 |x - b|^2 + rho/2 |x|^2 on the box [-1, 1]^n, b_i = outside[i] where given
    (past the box), else inside it."""
    b = np.linspace(-0.5, 0.5, n)
    for i, v in outside.items():
        b[i] = v
    return HierarchyProblem(
        [Level(np.eye(n), b, rho)], -np.ones(n), np.ones(n), np.zeros((0, n)), np.zeros(0)
    )


def test_the_rows_the_free_minimiser_leaves_are_the_answer_in_one_candidate():
    rho = 1e-3
    problem = _separable(16, {2: 3.0, 7: -2.5, 11: 1.5}, rho)
    result = HierarchySolver(damping_law=None).solve(problem)
    assert result.ok, result.status
    b = problem.levels[0].b
    # closed form: each coordinate its own 1-D problem, b_i / (1 + rho) clipped to the box
    np.testing.assert_allclose(result.x, np.clip(b / (1.0 + rho), -1.0, 1.0), atol=1e-14, rtol=0)
    expected = np.zeros(16, np.int8)
    expected[[2, 11]] = -1  # at the upper bound
    expected[7] = 1  # at the lower bound
    np.testing.assert_array_equal(result.active[0], expected)
    assert result.iterations[0] == 1  # one candidate, the guessed set (the dual method: 3)
    certificate = result.certificate[0]
    assert max(certificate.primal, certificate.stationarity, certificate.dual) < 1e-12


def _coupled(rng: np.random.Generator) -> tuple[HierarchyProblem, np.ndarray]:
    """Two damped levels on 14 to 30 variables (a task of a few rows, then a dense one below
    it); the lower one's free answer leaves 1 to 5 tight bounds."""
    n = int(rng.integers(14, 31))
    A0 = rng.standard_normal((int(rng.integers(1, 4)), n))
    m1 = int(rng.integers(n, 2 * n))
    A1 = rng.standard_normal((m1, n))
    x_free = rng.standard_normal(n)
    lb, ub = -10.0 * np.ones(n), 10.0 * np.ones(n)
    tight = rng.choice(n, size=int(rng.integers(1, 6)), replace=False)
    width = 0.3 * np.abs(x_free[tight])
    lb[tight] = np.where(x_free[tight] > 0, -1.0, -width)
    ub[tight] = np.where(x_free[tight] > 0, width, 1.0)
    rho = 10.0 ** rng.uniform(-4, -1)
    levels = [Level(A0, A0 @ (0.1 * x_free), rho), Level(A1, A1 @ x_free, rho)]
    return HierarchyProblem(levels, lb, ub, np.zeros((0, n)), np.zeros(0)), x_free


def test_guessed_levels_match_an_independent_lexicographic_reference():
    rng = np.random.default_rng(42)
    guessed = 0
    for _ in range(60):
        problem, _ = _coupled(rng)
        result = HierarchySolver(damping_law=None).solve(problem)
        assert result.ok, result.status
        x_ref = reference_answer(problem)
        scale = 1.0 + np.abs(x_ref).max()
        np.testing.assert_allclose(result.x, x_ref, atol=1e-7 * scale, rtol=0)
        for k in range(2):
            active = int(np.count_nonzero(result.active[k]))
            guessed += active >= 2 and result.iterations[k] < active
            certificate = result.certificate[k]
            assert max(certificate.primal, certificate.stationarity, certificate.dual) < 1e-9
    # the guess answered that many levels (the dual method makes one iteration or more per
    # active row)
    assert guessed >= 10, guessed


def test_guessed_levels_cold_and_warm_give_the_same_bits():
    rng = np.random.default_rng(7)
    problems = [_coupled(rng)[0] for _ in range(30)]
    problems += [_separable(16, {2: 3.0, 7: -2.5, 11: 1.5}, 1e-3), _separable(20, {0: -4.0}, 0.1)]
    warm_solves_give_cold_bits(problems)
