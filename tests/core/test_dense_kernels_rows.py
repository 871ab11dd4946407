"""The dense products' last two or three rows (register blocks of two or three rows where
those rows hold no zero entry) and project_level's M^T (kept rows two at a time, a product
by 1 / w where w is a power of two, else a quotient), bit for bit against their definitions."""

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


def _rng(*key):
    return np.random.default_rng(zlib.crc32(repr(key).encode()))


@pytest.mark.parametrize("m", [2, 3, 5, 6, 7, 11])
@pytest.mark.parametrize("k", [1, 2, 5, 35])
@pytest.mark.parametrize("n", [1, 2, 3, 8, 9, 23])
@pytest.mark.parametrize("kind", ["dense", "zero_last", "nonfinite_last"])
def test_product_last_rows(m, k, n, kind):
    rng = _rng(m, k, n, kind)
    A = rng.normal(size=(m, k))
    Z = rng.normal(size=(k, n))
    if kind == "zero_last":  # a zero (of either sign) in the last rows: the scalar rows
        A[m - 1, rng.integers(k)] = -0.0 if rng.random() < 0.5 else 0.0
    elif kind == "nonfinite_last":  # inf and NaN in A's last rows (nonzero: in the blocks)
        A[m - 1, rng.integers(k)] = np.inf
        A[m - 2, rng.integers(k)] = np.nan
        Z[rng.integers(k), rng.integers(n)] = -np.inf
    AZ = E.project_level(A, np.ones(m), Z, 1e-10)[0]
    assert _same_bits(AZ, _mm_reference(A, Z))


@pytest.mark.parametrize("shape", [(3, 5), (12, 35), (7, 23), (35, 6), (4, 7), (5, 4)])
def test_objective_hessian_lower_triangle(shape):
    m, n = shape
    rng = _rng(shape, "H")
    AZ = rng.normal(size=(m, n))
    k = n  # Z = I (n, n)
    Z = np.eye(n)
    H = E.reduced_qp(
        AZ,
        np.zeros(m),
        AZ,
        Z,
        np.zeros(k),
        0.0,
        -np.ones(k),
        np.ones(k),
        np.zeros((0, k)),
        np.zeros(0),
    )[0]
    ref = _mtm_reference(AZ)
    off = ~np.eye(n, dtype=bool)
    assert _same_bits(H[off], ref[off])
    assert _same_bits(H, H.T.copy())


@pytest.mark.parametrize("m", [1, 2, 3, 6, 7])
@pytest.mark.parametrize("n", [3, 6, 9])
@pytest.mark.parametrize("weights", ["pow2", "other", "mixed"])
def test_scaled_rows_match_prescaled(m, n, weights):
    # project_level(A, w, I) factors M = diag(1/w) A over the kept rows (w > 0); the same
    # bits as A[kept] / w[kept] (numpy's quotient: x * (1 / w) = x / w for w a power of two)
    # with unit weights.
    rng = _rng(m, n, weights)
    A = rng.normal(size=(m, n))
    if weights == "pow2":
        w = 2.0 ** rng.integers(-3, 4, size=m)
    elif weights == "other":
        w = rng.uniform(0.3, 3.0, size=m)
    else:
        w = np.where(
            rng.random(m) < 0.5, 2.0 ** rng.integers(-3, 4, size=m), rng.uniform(0.3, 3.0, size=m)
        )
    if m > 2:
        w[1] = 0.0  # a dropped row between kept ones
    kept = w > 0.0
    Z = np.eye(n)
    got = E.project_level(A, w, Z, 1e-10)
    ref = E.project_level(A[kept] / w[kept][:, None], np.ones(int(kept.sum())), Z, 1e-10)
    assert got[1] == ref[1] and got[2] == ref[2]
    assert _same_bits(got[3], ref[3])


@pytest.mark.parametrize("n", [5, 8, 9, 35])
@pytest.mark.parametrize("r", [3, 7, 8, 23])
@pytest.mark.parametrize("m", [1, 2, 3, 5])
def test_null_basis_through_a_basis(n, r, m):
    # Zn (n, c) from a Z (n, r) with orthonormal columns: orthonormal, A Zn ~ 0, Z Z^T Zn = Zn.
    if r > n:
        pytest.skip("Z has at most n columns")
    rng = _rng(n, r, m, "Zn")
    Z = np.linalg.qr(rng.normal(size=(n, r)))[0]
    A = rng.normal(size=(m, n))
    AZ, sigma, rank, Zn = E.project_level(A, np.ones(m), Z, 1e-10)
    assert rank == min(m, r)
    assert Zn.shape == (n, r - rank)
    if Zn.shape[1]:
        assert np.allclose(Zn.T @ Zn, np.eye(Zn.shape[1]), atol=1e-12)
        assert np.allclose(A @ Zn, 0.0, atol=1e-12)
        assert np.allclose(Z @ (Z.T @ Zn), Zn, atol=1e-12)
