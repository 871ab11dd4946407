"""Cholesky (cholesky_into) bit for bit against its definition: entry (i, j), j <= i, is
G[i, j] (less shift on the diagonal) minus L[i, k] L[j, k] for k < j, subtracted in k order,
then divided by L[j, j] off the diagonal or its square root taken on it; False at the first
pivot that is not positive. The column-by-column form (n < 24) and the form that keeps L's
columns as rows on the stack (24 <= n <= 64) must both give exactly these bits, with the
lower triangle alone written (the upper one left as it was)."""

from __future__ import annotations

import numpy as np
import pytest

from qpik.core import kernels as K


def _chol_reference(G, n, shift):
    L = np.zeros((n, n))
    for j in range(n):
        s = np.float64(G[j, j]) - np.float64(shift)
        for k in range(j):
            s = s - L[j, k] * L[j, k]
        if not s > 0.0:
            return False, L, j
        d = np.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, n):
            acc = np.float64(G[i, j])
            for k in range(j):
                acc = acc - L[i, k] * L[j, k]
            L[i, j] = acc / d
    return True, L, n


def _bits(x):
    return np.ascontiguousarray(x).view(np.int64)


@pytest.mark.parametrize("n", [1, 2, 5, 6, 7, 17, 23, 24, 25, 26, 31, 33, 38, 47, 64, 65])
@pytest.mark.parametrize("shift", [0.0, 0.25])
def test_cholesky_bits(n, shift):
    rng = np.random.default_rng(1000 + n)
    A = rng.normal(size=(n + 3, n))
    G = A.T @ A + (1.0 + shift) * np.eye(n)
    G[np.triu_indices(n, 1)] = rng.normal(size=n * (n - 1) // 2)  # the upper triangle: never read
    pad = n + 2  # L larger than n (its stride wider than n), the upper triangle marked
    L = np.full((pad, pad), 7.0)
    ok = K.cholesky_into(G, n, shift, L)
    ref_ok, R, _ = _chol_reference(G, n, shift)
    assert ok is True and ref_ok
    low = np.tril_indices(n)
    assert np.array_equal(_bits(L[:n, :n][low]), _bits(R[low]))
    assert np.all(L[:n, :n][np.triu_indices(n, 1)] == 7.0)
    assert np.all(L[n:, :] == 7.0) and np.all(L[:, n:] == 7.0)


@pytest.mark.parametrize("n", [6, 24, 29, 40])
def test_cholesky_fails_at_the_same_pivot(n):
    rng = np.random.default_rng(n)
    A = rng.normal(size=(n - 3, n))  # rank n - 3: a pivot at most round-off
    G = A.T @ A
    G[n - 2, n - 2] = -1.0
    ok = K.cholesky_into(G, n, 0.0, np.zeros((n, n)))
    ref_ok, _, _ = _chol_reference(G, n, 0.0)
    assert ok is ref_ok
    G = np.eye(n)
    G[n // 2, n // 2] = np.nan
    assert K.cholesky_into(G, n, 0.0, np.zeros((n, n))) is False


@pytest.mark.parametrize("n", [24, 30])
def test_cholesky_in_place(n):
    rng = np.random.default_rng(7 * n)
    A = rng.normal(size=(n + 1, n))
    G = A.T @ A + np.eye(n)
    ref_ok, R, _ = _chol_reference(G, n, 0.0)
    L = G.copy()
    assert K.cholesky_into(L, n, 0.0, L) is True and ref_ok
    low = np.tril_indices(n)
    assert np.array_equal(_bits(L[low]), _bits(R[low]))
