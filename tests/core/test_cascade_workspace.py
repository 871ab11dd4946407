"""The compiled cascade's workspace (kept by HierarchySolver between solves) holds no state
but capacity: a solver that solved problems of other sizes before gives bitwise the answer
of a fresh solver."""

from __future__ import annotations

import numpy as np

from qpik.core import HierarchyProblem, HierarchySolver, Level


def _problem(rng: np.random.Generator, n: int, p: int) -> HierarchyProblem:
    levels = [
        Level(rng.standard_normal((3, n)), rng.standard_normal(3)),
        Level(rng.standard_normal((n - 2, n)), rng.standard_normal(n - 2), 1e-6),
        Level(np.eye(n), np.zeros(n), 1e-4),
    ]
    lb, ub = -0.3 * np.ones(n), 0.3 * np.ones(n)
    G = rng.standard_normal((p, n))
    return HierarchyProblem(levels, lb, ub, G, 0.2 * np.ones(p))


def _bits(result) -> tuple:
    cert = [(c.primal, c.stationarity, c.dual, c.complementarity) for c in result.certificate]
    return (result.x.tobytes(), result.active.tobytes(), result.status, result.sigma, cert)


def test_a_reused_solver_gives_the_bits_of_a_fresh_one():
    rng = np.random.default_rng(7)
    problems = [_problem(rng, n, p) for n, p in [(9, 2), (5, 0), (14, 4), (7, 1), (9, 2)]]
    reused = HierarchySolver(damping_law=None)
    for problem in problems + problems[::-1]:
        fresh = HierarchySolver(damping_law=None).solve(problem)
        assert _bits(reused.solve(problem)) == _bits(fresh)
        A, b, w, starts, reg = problem.stacked()
        arrays = (A, b, w, starts, reg, problem.lb, problem.ub, problem.G, problem.h)
        assert _bits(reused.solve_arrays(*arrays)) == _bits(fresh)
