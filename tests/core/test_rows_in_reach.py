"""General rows out of reach of the box (``core::rows_in_reach``): a row ``g x <= h`` whose
largest value over the box is below ``h`` by more than round-off never binds, so the cascade
leaves it out. The answer is then bitwise the answer without the row, its ``active`` entries
are 0 in the (n + p) layout, and the final primal measure still covers it; a row whose bound
the box reaches (however barely) or that an unbounded dof moves is kept."""

from __future__ import annotations

import numpy as np
import pytest

from qpik.core import HierarchyProblem, HierarchySolver, Level


def _levels(rng, n):
    return [
        Level(rng.standard_normal((3, n)), rng.standard_normal(3)),
        Level(rng.standard_normal((4, n)), rng.standard_normal(4), 1e-6),
        Level(np.eye(n), 0.5 * rng.standard_normal(n), 1e-3),
    ]


def _far_rows(rng, n, p, lb, ub):
    """p rows whose largest value over the box is below h by 0.3 or more."""
    G = rng.standard_normal((p, n))
    reach = np.where(G > 0, G * ub, G * lb).sum(axis=1)
    return G, reach + 0.3 + rng.uniform(0.0, 2.0, p)


@pytest.mark.parametrize("seed", range(40))
def test_rows_out_of_reach_leave_the_answer_bitwise(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 12))
    lb, ub = -0.1 * rng.uniform(0.2, 1.0, n), 0.1 * rng.uniform(0.2, 1.0, n)
    G_in = rng.standard_normal((2, n))
    h_in = 0.02 * rng.standard_normal(2)  # in reach: may bind
    G_out, h_out = _far_rows(rng, n, 3, lb, ub)
    order = rng.permutation(5)  # the two kinds interleaved
    G = np.vstack([G_in, G_out])[order]
    h = np.concatenate([h_in, h_out])[order]
    kept = np.argsort(order)[:2]  # where the rows in reach went
    for damping_law in (None, "default"):
        solver = HierarchySolver() if damping_law else HierarchySolver(damping_law=None)
        levels = _levels(np.random.default_rng(seed + 100), n)
        every = solver.solve(HierarchyProblem(levels, lb, ub, G, h))
        alone = solver.solve(HierarchyProblem(levels, lb, ub, G[np.sort(kept)], h[np.sort(kept)]))
        assert every.x.tobytes() == alone.x.tobytes()
        assert [str(s) for s in every.status] == [str(s) for s in alone.status]
        assert every.certificate == alone.certificate
        assert every.iterations == alone.iterations
        assert every.primal == alone.primal
        for a_every, a_alone in zip(every.active, alone.active, strict=True):
            a_every, a_alone = np.asarray(a_every), np.asarray(a_alone)
            assert a_every.shape == (n + 5,) and a_alone.shape == (n + 2,)
            np.testing.assert_array_equal(a_every[:n], a_alone[:n])
            np.testing.assert_array_equal(a_every[n:][np.sort(kept)], a_alone[n:])
            assert not a_every[n:][np.setdiff1d(np.arange(5), kept)].any()
        assert (G @ every.x - h).max() <= 1e-12  # every row met, the far ones with slack


def test_a_row_the_box_reaches_binds():
    # x_0 + x_1 <= 0.2 - 1e-12 on the box [-0.1, 0.1]^2: reached only at a corner, by 1e-12;
    # kept (the margin is relative, 1e-6), and it binds where the level pulls to that corner.
    lb, ub = -0.1 * np.ones(2), 0.1 * np.ones(2)
    G, h = np.array([[1.0, 1.0]]), np.array([0.2 - 1e-12])
    level = Level(np.eye(2), np.array([1.0, 1.0]))
    result = HierarchySolver(damping_law=None).solve(HierarchyProblem([level], lb, ub, G, h))
    assert result.x.sum() <= h[0] + 1e-15
    assert np.asarray(result.active[0])[2] != 0


def test_a_row_on_an_unbounded_dof_is_kept():
    # No bound on x_1: the row's reach is unbounded, so it is kept and binds.
    lb, ub = np.array([-0.1, -np.inf]), np.array([0.1, np.inf])
    G, h = np.array([[0.0, 1.0]]), np.array([5.0])
    level = Level(np.eye(2), np.array([0.0, 10.0]))
    result = HierarchySolver(damping_law=None).solve(HierarchyProblem([level], lb, ub, G, h))
    assert result.x[1] == pytest.approx(5.0, abs=1e-12)
    assert np.asarray(result.active[0])[2] != 0


def test_the_dual_method_no_longer_passes_through_a_far_row():
    # The level pulls to (100, 100), far outside the box [-0.1, 0.1]^2; the row
    # x_0 + x_1 <= 0.25 is out of reach (0.2 at most) but the most violated row there, so the
    # dual method would add it first and drop it later. Left out, the level takes the
    # iterations it takes without the row, and the same bits.
    lb, ub = -0.1 * np.ones(2), 0.1 * np.ones(2)
    G, h = np.array([[1.0, 1.0]]), np.array([0.25])
    level = Level(np.eye(2), np.array([100.0, 100.0]))
    solver = HierarchySolver(damping_law=None)
    every = solver.solve(HierarchyProblem([level], lb, ub, G, h))
    alone = solver.solve(HierarchyProblem([level], lb, ub, np.zeros((0, 2)), np.zeros(0)))
    assert every.x.tobytes() == alone.x.tobytes()
    assert every.iterations == alone.iterations == [2]
    np.testing.assert_array_equal(np.asarray(every.active[0]), [-1, -1, 0])


def test_the_same_problem_gives_the_same_bits_after_other_solves():
    # The cascade keeps storage between solves (the rows in reach, H's product before its
    # regularisation for the exact re-solve): a problem solved fresh, after other problems of
    # other sizes and row counts, and by another solver instance, gives the same bits.
    rng = np.random.default_rng(7)

    def problem(n, far):
        lb, ub = -0.05 * np.ones(n), 0.05 * np.ones(n)
        G_far, h_far = _far_rows(rng, n, far, lb, ub)
        G = np.vstack([rng.standard_normal((2, n)), G_far])
        h = np.concatenate([0.01 * rng.standard_normal(2), h_far])
        return HierarchyProblem(_levels(rng, n), lb, ub, G, h)

    target = problem(9, 3)
    others = [problem(int(n), int(far)) for n, far in ((12, 0), (6, 5), (9, 1), (15, 2))]
    fresh = HierarchySolver().solve(target)
    used = HierarchySolver()
    for other in others:
        used.solve(other)
    again = used.solve(target)
    for other in others[::-1]:
        used.solve(other)
    for result in (again, used.solve(target), HierarchySolver().solve(target)):
        assert result.x.tobytes() == fresh.x.tobytes()
        assert result.certificate == fresh.certificate
        assert [np.asarray(a).tobytes() for a in result.active] == [
            np.asarray(a).tobytes() for a in fresh.active
        ]
    assert max(fresh.iterations) > 0  # (the bounds bind: the exact re-solve has rows)
