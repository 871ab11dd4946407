"""solve_qp's row scan (qpik/_cpp/core/qp.hpp, RowScan): the working set's rows are swapped out
of the scanned columns and back, the rows' norms are taken as the columns are laid out, and
the most violated row is the first largest in the order of rows. Zero rows change nothing
(the same bits with or without them), and of two equal rows the first is taken."""

from __future__ import annotations

import numpy as np
import pytest

from qpik.core import kernels as K

SOLVED = 0


def _qp(rng, n, p):
    M = rng.standard_normal((n + 2, n))
    H = M.T @ M + 1e-3 * np.eye(n)
    c = 3.0 * rng.standard_normal(n)
    C = np.vstack([np.eye(n), rng.standard_normal((p, n))])
    lo = np.concatenate([-0.1 * np.ones(n), -np.inf * np.ones(p)])
    hi = np.concatenate([0.1 * np.ones(n), rng.uniform(0.0, 0.2, p)])
    return H, c, C, lo, hi


def _solve(H, c, C, lo, hi, canonical=True):
    warm = np.zeros(C.shape[0], np.int8)
    n = H.shape[0]
    return K.solve_qp(H, c, C, lo, hi, warm, 20 * n + 50, 1e-12, canonical)


@pytest.mark.parametrize("canonical", [True, False])
@pytest.mark.parametrize("seed", range(6))
def test_zero_rows_change_no_bits(seed, canonical):
    rng = np.random.default_rng(300 + seed)
    n, p = 9 + seed, 8 + 3 * seed
    H, c, C, lo, hi = _qp(rng, n, p)
    ref = _solve(H, c, C, lo, hi, canonical)
    # zero rows (satisfied bounds) spread among the others
    m = C.shape[0]
    where = sorted(rng.choice(m + 1, size=3, replace=True))
    C2, lo2, hi2, keep = C, lo, hi, np.arange(m)
    for k, at in enumerate(where):
        at = at + k
        C2 = np.insert(C2, at, 0.0, axis=0)
        lo2 = np.insert(lo2, at, -1.0)
        hi2 = np.insert(hi2, at, 1.0)
        keep = np.where(keep >= at, keep + 1, keep)
    out = _solve(H, c, C2, lo2, hi2, canonical)
    assert ref[1] == SOLVED and out[1] == SOLVED
    assert ref[0].tobytes() == out[0].tobytes()
    assert ref[2] == out[2]
    assert np.array_equal(np.asarray(out[3])[keep], np.asarray(ref[3]))


@pytest.mark.parametrize("seed", range(6))
def test_equal_rows_take_the_first(seed):
    rng = np.random.default_rng(400 + seed)
    n, p = 8 + seed, 6 + 2 * seed
    H, c, C, lo, hi = _qp(rng, n, p)
    ref = _solve(H, c, C, lo, hi)
    active = np.asarray(ref[3])
    rows = np.flatnonzero(active[n:]) + n  # general rows at a bound
    if rows.size == 0:
        pytest.skip("no general row active")
    r = int(rows[0])
    # the same row again after it: the copy never enters (it depends on the first)
    C2 = np.insert(C, r + 1, C[r], axis=0)
    lo2 = np.insert(lo, r + 1, lo[r])
    hi2 = np.insert(hi, r + 1, hi[r])
    out = _solve(H, c, C2, lo2, hi2)
    assert out[1] == SOLVED
    a2 = np.asarray(out[3])
    assert a2[r] == active[r] and a2[r + 1] == 0
    np.testing.assert_allclose(out[0], ref[0], rtol=0, atol=1e-9)
