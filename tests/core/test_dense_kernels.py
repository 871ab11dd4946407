"""The dense products of the core, bit for bit against their definition: entry (i, j) of
A @ Z is +0 plus the products A[i, t] Z[t, j] of the nonzero A[i, t], added in t order (the
register-blocked kernels must give exactly these bits: the sign of a zero, NaN and inf
included), and H = (A Z)^T (A Z) + reg I likewise off its diagonal."""

from __future__ import annotations

import zlib

import numpy as np
import pytest

from qpik._engine import core as E


def _mm_reference(A, B):
    m, k = A.shape
    n = B.shape[1]
    C = np.zeros((m, n))
    with np.errstate(all="ignore"):
        for i in range(m):
            for j in range(n):
                acc = np.float64(0.0)
                for t in range(k):
                    a = A[i, t]
                    if a != 0.0:
                        acc = acc + a * B[t, j]
                C[i, j] = acc
    return C


def _mtm_reference(A):
    m, n = A.shape
    C = np.zeros((n, n))
    with np.errstate(all="ignore"):
        for i in range(n):
            for j in range(i, n):
                acc = np.float64(0.0)
                for t in range(m):
                    a = A[t, i]
                    if a != 0.0:
                        acc = acc + a * A[t, j]
                C[i, j] = C[j, i] = acc
    return C


def _same_bits(x, y):
    return x.shape == y.shape and np.array_equal(x.view(np.int64), y.view(np.int64))


def _case(rng, m, k, n, kind):
    A = rng.normal(size=(m, k))
    Z = rng.normal(size=(k, n))
    if kind == "zeros":  # scattered zeros of both signs, a zero column, a zero row
        A[rng.random((m, k)) < 0.3] = 0.0
        A[rng.random((m, k)) < 0.1] = -0.0
        A[:, k // 2] = 0.0
        A[m // 2, :] = -0.0
    elif kind == "nonfinite":  # inf and NaN in Z against zeros of A (0 * inf is skipped)
        A[rng.random((m, k)) < 0.2] = 0.0
        Z[rng.random((k, n)) < 0.05] = np.inf
        Z[rng.random((k, n)) < 0.05] = np.nan
    elif kind == "cancel":  # exact cancellations: sums that end at +0
        A[:, 1::2] = A[:, 0::2][:, : A[:, 1::2].shape[1]]
        Z[1::2, :] = -Z[0::2, :][: Z[1::2, :].shape[0], :]
    return A, Z


SHAPES = [
    (1, 3, 2),
    (4, 4, 4),
    (5, 7, 3),
    (8, 9, 8),
    (9, 13, 10),
    (12, 35, 20),
    (6, 5, 1),
    (7, 3, 11),
]


@pytest.mark.parametrize("kind", ["dense", "zeros", "nonfinite", "cancel"])
@pytest.mark.parametrize("shape", SHAPES)
def test_product_with_z_is_the_ordered_skip_zero_sum(shape, kind):
    m, k, n = shape
    rng = np.random.default_rng(zlib.crc32(repr((shape, kind)).encode()))
    A, Z = _case(rng, m, k, n, kind)
    AZ = E.project_level(A, np.ones(m), Z, 1e-10)[0]
    assert _same_bits(AZ, _mm_reference(A, Z))


@pytest.mark.parametrize("kind", ["dense", "zeros", "cancel"])
@pytest.mark.parametrize("shape", SHAPES)
def test_objective_hessian_is_the_ordered_skip_zero_sum(shape, kind):
    m, k, n = shape
    rng = np.random.default_rng(zlib.crc32(repr((shape, kind, "H")).encode()))
    A, Z = _case(rng, m, k, n, kind)
    AZ = _mm_reference(A, Z)
    # d, lb, ub of length k; no general rows
    d = np.zeros(k)
    H = E.reduced_qp(
        A, np.zeros(m), AZ, Z, d, 0.0, -np.ones(k), np.ones(k), np.zeros((0, k)), np.zeros(0)
    )[0]
    ref = _mtm_reference(AZ)
    off = ~np.eye(n, dtype=bool)
    assert _same_bits(H[off], ref[off])
