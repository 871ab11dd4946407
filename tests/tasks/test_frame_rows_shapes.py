"""frame_rows_into's shortcuts (a zero Jacobian column, jlog's zero lower-left block, the
identity jlog) give the bits of the full sums: A[i, j] = -cost[i] * (sum_k jlog[i, k]
col_j[k]), col_j = R^T J[:, j] blockwise, each sum from +0 in order of k."""

from __future__ import annotations

import numpy as np
import pytest

from qpik._engine.tasks import frame_error_jlog, frame_rows_into


def _reference(jac, xmat, jlog, cost):
    """The full sums, one IEEE operation at a time (Python floats are doubles)."""
    R = [float(x) for x in xmat]
    nv = jac.shape[1]
    A = np.empty((6, nv))
    for j in range(nv):
        col = [0.0] * 6
        for i in range(3):
            a = 0.0
            r = 0.0
            for k in range(3):
                a += R[3 * k + i] * float(jac[k, j])
                r += R[3 * k + i] * float(jac[3 + k, j])
            col[i] = a
            col[3 + i] = r
        for i in range(6):
            acc = 0.0
            for k in range(6):
                acc += float(jlog[i, k]) * col[k]
            A[i, j] = -float(cost[i]) * acc
    return A


def _same_bits(got, want):
    nan = np.isnan(want)
    assert np.array_equal(np.isnan(got), nan)
    assert np.array_equal(got[~nan].view(np.int64), want[~nan].view(np.int64))


def _rotation(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def _jac(rng, nv):
    jac = rng.normal(size=(6, nv))
    jac[:, 1] = 0.0  # a dof off the chain
    jac[:3, 2] = 0.0  # a column with zero translation rows
    jac[[0, 4], 3] = -0.0  # signed zeros among nonzeros
    jac[:, 4] = [-0.0, 0.0, -0.0, 0.0, -0.0, -0.0]  # a zero column of signed zeros
    return jac


def _jlogs(rng):
    R = _rotation(rng)
    xpos = rng.normal(size=3)
    target = np.concatenate([[0.9, 0.1, -0.3, 0.2], rng.normal(size=3)])
    target[:4] /= np.linalg.norm(target[:4])
    _, jl = frame_error_jlog(R.ravel(), xpos, target)  # lower-left block zero
    assert np.all(jl[3:, :3] == 0.0)
    full = rng.normal(size=(6, 6))  # general
    near = np.array(jl)
    near[4, 1] = 1e-300  # lower-left block not zero
    return R, {"jlog": jl, "eye": np.eye(6), "general": full, "near": near}


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("kind", ["jlog", "eye", "general", "near"])
@pytest.mark.parametrize("bad", [None, np.inf, -np.inf, np.nan, 1e308])
def test_frame_rows_into_matches_the_full_sums(seed, kind, bad):
    rng = np.random.default_rng(seed)
    nv = 8
    R, jlogs = _jlogs(rng)
    jlog = jlogs[kind]
    jac = _jac(rng, nv)
    if bad is not None:
        jac[1, 5] = bad  # a column whose local entries are not all finite
        jac[3, 6] = bad
    cost = np.array([1.0, 0.5, 0.0, 2.0, -0.0, 1e-3])
    error = rng.normal(size=6)
    A = np.full((6 + 2, nv), 7.0)
    b = np.zeros(6 + 2)
    frame_rows_into(A, b, 2, jac, R.ravel(), jlog, error, cost, 0.5, 0.1)
    _same_bits(A[2:], _reference(jac, R.ravel(), jlog, cost))
    assert np.all(A[:2] == 7.0)


def test_frame_rows_into_non_finite_jlog_and_xmat():
    rng = np.random.default_rng(7)
    nv = 5
    R, jlogs = _jlogs(rng)
    jac = _jac(rng, nv)
    cost = np.ones(6)
    for jlog, xmat in (
        (np.array(jlogs["jlog"]), R.ravel().copy()),
        (jlogs["eye"], R.ravel().copy()),
    ):
        jlog = np.array(jlog)
        jlog[0, 5] = np.inf
        A = np.zeros((6, nv))
        frame_rows_into(A, np.zeros(6), 0, jac, xmat, jlog, np.zeros(6), cost, 1.0, 0.0)
        _same_bits(A, _reference(jac, xmat, jlog, cost))
        xmat[4] = np.nan
        A = np.zeros((6, nv))
        frame_rows_into(A, np.zeros(6), 0, jac, xmat, jlogs["jlog"], np.zeros(6), cost, 1.0, 0.0)
        _same_bits(A, _reference(jac, xmat, jlogs["jlog"], cost))
