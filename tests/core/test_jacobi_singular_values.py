"""project_level's singular values (one-sided Jacobi by rounds of disjoint pairs on the R of a
pivoted QR) against numpy.linalg.svd: sigma (the least singular value above the cutoff) and the
rank on random, graded, rank-deficient and near-cutoff levels of 1..24 rows, at extreme
scales; Zn an orthonormal basis of the level's null space within Z; the same inputs give the
same bits whatever ran before."""

from __future__ import annotations

import numpy as np
import pytest

from qpik._engine import core as E

RANK_TOL = 1e-10


def _orthonormal(rng, n, r):
    q, _ = np.linalg.qr(rng.standard_normal((n, r)))
    return q


def _reference(A, w, Z, rank_tol=RANK_TOL):
    """(singular values, cutoff) of diag(1/w) A Z over the rows of positive weight."""
    keep = w > 0
    M = (A[keep] / w[keep, None]) @ Z
    sv = np.linalg.svd(M, compute_uv=False)
    top = sv[0] if sv.size else 0.0
    return sv, rank_tol * max(1.0, top)


def _check(A, w, Z, rel, absolute=0.0):
    """sigma within rel of numpy's (plus absolute times the largest singular value)."""
    AZ, sigma, rank, Zn = E.project_level(A, w, Z, RANK_TOL)
    sv, cutoff = _reference(A, w, Z)
    expect = int(np.sum(sv > cutoff))
    assert rank == expect
    if expect:
        s_ref = sv[expect - 1]
        assert abs(sigma - s_ref) <= rel * s_ref + absolute * sv[0], (
            sigma,
            s_ref,
            abs(sigma - s_ref) / s_ref,
        )
    else:
        assert sigma == np.inf
    r = Z.shape[1]
    assert Zn.shape == (Z.shape[0], r - rank)
    if Zn.shape[1]:
        # orthonormal, within span(Z), and in the null space of the level (relative to its size)
        assert np.allclose(Zn.T @ Zn, np.eye(Zn.shape[1]), atol=1e-13)
        assert np.allclose(Z @ (Z.T @ Zn), Zn, atol=1e-13)
        keep = w > 0
        M = A[keep] / w[keep, None]
        dropped = np.linalg.norm(sv[expect:])  # the singular values at or below the cutoff
        assert np.linalg.norm(M @ Zn) <= dropped + 1e-12 * max(1.0, sv[0]) * np.sqrt(A.shape[0])
    return sigma, rank


@pytest.mark.parametrize("m", [1, 2, 3, 4, 5, 6, 7, 8, 9, 12, 17, 24])
def test_random_levels(m):
    rng = np.random.default_rng(100 + m)
    for trial in range(25):
        n = m + int(rng.integers(0, 6))
        A = rng.standard_normal((m, n))
        w = rng.uniform(0.5, 2.0, m)
        Z = np.eye(n) if trial % 2 == 0 else _orthonormal(rng, n, n - int(rng.integers(0, 2)))
        if Z.shape[1] < m:
            continue
        _check(A, w, Z, 1e-13)


@pytest.mark.parametrize("m", [3, 6, 8, 12])
def test_graded_and_clustered(m):
    rng = np.random.default_rng(200 + m)
    for trial in range(20):
        n = m + 2
        U = _orthonormal(rng, m, m)
        V = _orthonormal(rng, n, m)
        if trial % 2:
            s = 10.0 ** -rng.uniform(0, 3, m)  # graded: condition up to 1e3
        else:
            s = 1.0 + 1e-9 * rng.standard_normal(m)  # clustered
        A = (U * s) @ V.T
        w = np.ones(m)
        sigma, rank = _check(A, w, np.eye(n), 1e-12)
        assert rank == m


@pytest.mark.parametrize("m", [2, 3, 5, 6, 8, 10, 16])
def test_rank_deficient(m):
    rng = np.random.default_rng(300 + m)
    for trial in range(20):
        n = m + 3
        k = int(rng.integers(1, m))
        A = rng.standard_normal((m, k)) @ rng.standard_normal((k, n))
        w = rng.uniform(0.5, 2.0, m)
        Z = np.eye(n) if trial % 2 == 0 else _orthonormal(rng, n, n - 1)
        sigma, rank = _check(A, w, Z, 1e-12)
        assert rank == k


@pytest.mark.parametrize("m", [3, 6, 8])
def test_near_cutoff(m):
    """A singular value just above or below the cutoff is ranked as numpy's SVD ranks it."""
    rng = np.random.default_rng(400 + m)
    n = m + 1
    for trial in range(30):
        U = _orthonormal(rng, m, m)
        V = _orthonormal(rng, n, m)
        s = np.sort(rng.uniform(0.5, 3.0, m))[::-1]
        cutoff = RANK_TOL * max(1.0, s[0])
        s[-1] = cutoff * (1.0 + (1e-5 if trial % 2 else -1e-5))
        A = (U * s) @ V.T
        # (a singular value at the cutoff: within a few eps of the largest, absolutely)
        sigma, rank = _check(A, np.ones(m), np.eye(n), 1e-12, 1e-15)
        assert rank == (m if trial % 2 else m - 1)


@pytest.mark.parametrize("scale", [1e-150, 1e-100, 1e100, 1e140])
def test_extreme_scales(scale):
    """Rows far from 1 in size (the rotation's and the orthogonality test's overflow-safe
    branches: squared norms beyond 1e+-250) keep sigma and rank (rank_tol tiny, so that the
    cutoff stays below the small levels' singular values)."""
    rng = np.random.default_rng(7)
    for m in (3, 6, 10):
        A = rng.standard_normal((m, m + 2))
        w = np.ones(m)
        _, s1, r1, _ = E.project_level(A, w, np.eye(m + 2), 1e-300)
        _, s2, r2, _ = E.project_level(A * scale, w, np.eye(m + 2), 1e-300)
        assert np.isfinite(s2) and r2 == r1 == m
        assert abs(s2 / scale - s1) <= 1e-14 * s1


def test_same_bits_whatever_ran_before():
    rng = np.random.default_rng(11)
    cases = []
    for m in (3, 6, 7, 12):
        n = m + 2
        A = rng.standard_normal((m, n))
        A[-1] = A[0] + A[1]  # rank deficient: Zn from the logged rotations
        cases.append((A, rng.uniform(0.5, 2.0, m), _orthonormal(rng, n, n)))
        cases.append((rng.standard_normal((m, n)), np.ones(m), np.eye(n)))
    first = [E.project_level(A, w, Z, RANK_TOL) for A, w, Z in cases]
    for _k in range(3):
        order = rng.permutation(len(cases))
        for i in order:
            A, w, Z = cases[i]
            again = E.project_level(A, w, Z, RANK_TOL)
            f = first[i]
            assert again[1] == f[1] and again[2] == f[2]
            assert again[0].tobytes() == f[0].tobytes() and again[3].tobytes() == f[3].tobytes()


def test_rows_whose_squares_underflow_end_the_sweeps():
    """tests/data/dual_arm_weighted_level.npz: the one weighted level of mink's
    arm_dual_panda example (two identical arms, frame tasks and a posture, and a free object
    joint with zero rows and columns; A weighted, w its rows' costs). Ranked as a last level
    (its rows turned by the Gram matrix's eigenvectors), rows left with entries whose
    squares underflow (a squared norm of 0 with a nonzero product against another row) were
    rotated by angles whose sine underflowed, sweep after sweep to the bound of 60 (3 M
    instructions a solve); the null rows' noise (norms 1e-20 to 1e-36 of the largest) then
    kept 13 sweeps turning against the others, now left alone below 1e-9 of the rank cutoff
    (a few sweeps: benchmarks/mink_suite.py --examples, 0.90x -> 0.20x mink's time a call).
    The answer, sigma and rank against numpy's least squares and SVD."""
    from pathlib import Path

    from qpik.core import HierarchyProblem, HierarchySolver, Level

    z = np.load(Path(__file__).parents[1] / "data" / "dual_arm_weighted_level.npz")
    A, w = z["A"], z["w"]
    n = A.shape[1]
    b = np.random.default_rng(0).standard_normal(A.shape[0]) * 0.01
    sv = np.linalg.svd(A / w[:, None], compute_uv=False)
    for reg in (5e-3, 1e-3):
        problem = HierarchyProblem(
            [Level(A, b, reg, w)], -np.ones(n), np.ones(n), np.zeros((0, n)), np.zeros(0)
        )
        result = HierarchySolver(damping_law=None).solve(problem)
        stacked = np.vstack([A, np.sqrt(reg) * np.eye(n)])
        reference = np.linalg.lstsq(stacked, np.concatenate([b, np.zeros(n)]), rcond=None)[0]
        assert np.abs(reference).max() < 1.0  # (the box inactive)
        np.testing.assert_allclose(result.x, reference, rtol=0, atol=1e-14)
        kept = sv[sv > 1e-9 * sv[0]]
        assert result.sigma[0] == pytest.approx(kept.min(), rel=1e-13)
    _, sigma, rank, _ = E.project_level(A, w, np.eye(n), RANK_TOL)
    assert rank == 18 and sigma == pytest.approx(1.0, rel=1e-13)
