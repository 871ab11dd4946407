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


# The products with few zero entries in A (register blocks that add the zero products
# too, the same bits where the other factors are finite) and with non-finite ones (the
# zero entries' products skipped: 0 * inf is never added).
def _mm_reference(A, B):
    m, k = A.shape
    C = np.zeros((m, B.shape[1]))
    with np.errstate(all="ignore"):
        for i in range(m):
            for j in range(B.shape[1]):
                acc = np.float64(0.0)
                for t in range(k):
                    if A[i, t] != 0.0:
                        acc = acc + A[i, t] * B[t, j]
                C[i, j] = acc
    return C


def _sparse_case(rng, m, k, n, kind):
    A = rng.normal(size=(m, k))
    Z = rng.normal(size=(k, n))
    A[rng.random((m, k)) < 0.08] = 0.0
    A[rng.random((m, k)) < 0.04] = -0.0
    if kind == "nonfinite":
        Z[rng.random((k, n)) < 0.03] = np.inf
        Z[rng.random((k, n)) < 0.03] = np.nan
        A[rng.random((m, k)) < 0.02] = -np.inf
    elif kind == "cancel":  # sums that end at +0, and zero products of both signs
        A[:, 1::2] = A[:, 0::2][:, : A[:, 1::2].shape[1]]
        Z[1::2, :] = -Z[0::2, :][: Z[1::2, :].shape[0], :]
    elif kind == "huge":  # products that overflow to inf beside zero entries
        A *= 1e200
        Z *= 1e200
    elif kind == "zero_rows":  # whole rows of zeros of both signs (no products at all)
        A[::3, :] = 0.0
        A[1::5, :] = -0.0
        A[-1, :] = np.inf  # and a non-finite row among the kept ones
    return A, Z


@pytest.mark.parametrize("kind", ["sparse", "nonfinite", "cancel", "huge"])
@pytest.mark.parametrize("shape", [(4, 6, 5), (8, 38, 23), (12, 23, 17), (13, 9, 7)])
def test_product_blocks_with_zero_entries(shape, kind):
    from qpik._engine import core as E

    m, k, n = shape
    rng = np.random.default_rng(sum(shape) + len(kind))
    A, Z = _sparse_case(rng, m, k, n, kind)
    AZ = E.project_level(A, np.ones(m), Z, 1e-10)[0]
    assert np.array_equal(_bits(AZ), _bits(_mm_reference(A, Z)))


@pytest.mark.parametrize("kind", ["sparse", "nonfinite", "cancel", "huge", "zero_rows"])
@pytest.mark.parametrize("shape", [(6, 8), (12, 38), (38, 17), (9, 23), (4, 4), (70, 60)])
def test_gram_blocks_with_zero_entries(shape, kind):
    from qpik._engine import core as E

    m, n = shape
    rng = np.random.default_rng(3 * sum(shape) + len(kind))
    AZ, _ = _sparse_case(rng, m, n, 1, kind)
    AZ[:, n // 3] = 0.0  # a zero column: its rows of the Gram matrix all +0
    k = n
    H = E.reduced_qp(
        np.eye(m, k) if m <= k else np.eye(m, k),
        np.zeros(m),
        AZ,
        np.eye(k),
        np.zeros(k),
        0.0,
        -np.ones(k),
        np.ones(k),
        np.zeros((0, k)),
        np.zeros(0),
    )[0]
    ref = _mm_reference(AZ.T.copy(), AZ)
    ref = np.triu(ref) + np.triu(ref, 1).T  # the upper triangle's sums, mirrored
    off = ~np.eye(n, dtype=bool)
    assert np.array_equal(_bits(H[off]), _bits(ref[off]))
