"""A cold damped level of few rows (a humanoid's CoM or feet: m rows against r >= 12 free
directions, 2 m <= r) whose row-space answer leaves a few bounds guesses its working set in
the row-space form before H is made (row_space_guess and row_space_set_candidate in
qpik/_cpp/core/cascade.hpp), and every path that ends on such a set takes the same candidate
(set_candidate: exact_level after the dual method, primal_guess, warm starts).

Checked against closed forms and the independent lexicographic reference
(tests/exactness_oracle.py: quadprog level by level, no qpik code), and cold against warm
starts (the dual method from the previous set, then exact_level) bit for bit."""

from __future__ import annotations

import numpy as np
from conftest import warm_solves_give_cold_bits
from exactness_oracle import reference_answer

from qpik.core import HierarchyProblem, HierarchySolver, Level


def _few_rows_binding(rng: np.random.Generator, general: bool = False) -> HierarchyProblem:
    """Two damped levels on 24 to 40 variables: a task of 2 to 8 rows whose free answer leaves
    1 to 6 tight bounds, then a dense task below it; with ``general``, two general rows that
    the answer meets with slack."""
    n = int(rng.integers(24, 41))
    m0 = int(rng.integers(2, 9))
    A0 = rng.standard_normal((m0, n)) * np.logspace(0, -1, n)
    x_free = rng.standard_normal(n)
    rho = 10.0 ** rng.uniform(-5, -1)
    # the level's own free answer, and bounds tight on a few of its largest entries
    x0 = np.linalg.solve(A0.T @ A0 + rho * np.eye(n), A0.T @ (A0 @ x_free))
    tight = np.argsort(-np.abs(x0))[: int(rng.integers(1, 7))]
    lb, ub = -10.0 * np.ones(n), 10.0 * np.ones(n)
    width = 0.3 * np.abs(x0[tight])
    lb[tight] = np.where(x0[tight] > 0, -1.0, -width)
    ub[tight] = np.where(x0[tight] > 0, width, 1.0)
    m1 = int(rng.integers(n // 2, n))
    A1 = rng.standard_normal((m1, n))
    levels = [Level(A0, A0 @ x_free, rho), Level(A1, A1 @ rng.standard_normal(n), rho)]
    if general:
        G = rng.standard_normal((2, n))
        h = np.abs(G).sum(axis=1) * 10.0 + 1.0  # never binding inside the box
        return HierarchyProblem(levels, lb, ub, G, h)
    return HierarchyProblem(levels, lb, ub, np.zeros((0, n)), np.zeros(0))


def test_the_bounds_a_few_rows_level_leaves_are_the_answer_of_a_few_candidates():
    """One level of 3 rows on 20 variables, decoupled enough for a closed form: each row
    moves its own variable, and the free answer of the first two leaves their bounds."""
    n, rho = 20, 1e-3
    A = np.zeros((3, n))
    A[0, 0] = A[1, 5] = A[2, 9] = 1.0
    b = np.array([3.0, -2.0, 0.5])
    lb, ub = -np.ones(n), np.ones(n)
    problem = HierarchyProblem([Level(A, b, rho)], lb, ub, np.zeros((0, n)), np.zeros(0))
    result = HierarchySolver(damping_law=None).solve(problem)
    assert result.ok, result.status
    expected = np.zeros(n)
    expected[[0, 5, 9]] = np.clip(b / (1.0 + rho), -1.0, 1.0)
    np.testing.assert_allclose(result.x, expected, atol=1e-14, rtol=0)
    active = np.zeros(n, np.int8)
    active[0], active[5] = -1, 1  # upper, lower
    np.testing.assert_array_equal(result.active[0], active)
    assert result.iterations[0] == 1  # one candidate, the guessed set
    certificate = result.certificate[0]
    assert max(certificate.primal, certificate.stationarity, certificate.dual) < 1e-12


def test_few_rows_levels_match_an_independent_lexicographic_reference():
    rng = np.random.default_rng(2612)
    guessed = 0
    for trial in range(60):
        problem = _few_rows_binding(rng, general=trial % 3 == 0)
        result = HierarchySolver(damping_law=None).solve(problem)
        assert result.ok, (trial, result.status)
        x_ref = reference_answer(problem)
        scale = 1.0 + np.abs(x_ref).max()
        np.testing.assert_allclose(result.x, x_ref, atol=1e-7 * scale, rtol=0, err_msg=str(trial))
        active = int(np.count_nonzero(result.active[0]))
        guessed += active >= 2 and result.iterations[0] < active
        for k in range(2):
            certificate = result.certificate[k]
            assert max(certificate.primal, certificate.stationarity, certificate.dual) < 1e-9
    # the guess answered most first levels (the dual method makes one iteration or more per
    # active row)
    assert guessed >= 20, guessed


def test_few_rows_levels_cold_and_warm_give_the_same_bits():
    rng = np.random.default_rng(11)
    problems = [_few_rows_binding(rng, general=i % 2 == 1) for i in range(24)]
    warm_solves_give_cold_bits(problems)
