r"""TRANSITIONAL: the numba reference of the core kernels (formerly qpik/core/_kernels.py).

The core's kernels are now compiled C++ (qpik/_cpp/core, exposed as
:mod:`qpik.core._kernels`). Modules not yet ported (qpik.model._kernels, qpik._fused) call
``cholesky_into``, ``merge_boxes`` and ``solve_cascade`` from inside their own numba
kernels, which cannot call a compiled extension function: :func:`register_overloads`
(called by :mod:`qpik.core._kernels` when numba is importable) tells numba to use the
functions below wherever such a kernel names the C++ ones. The two give the same bits
(tests/test_engine_core.py). Delete this module once no numba kernel calls the core.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# Status codes shared with qpik.core.hierarchy.LevelStatus (keep in sync).
SOLVED = 0
MAX_ITER = 1
INFEASIBLE = 2
KEPT_PREVIOUS = 3
NUMERICAL = 4
NOT_REACHED = 5

_BIG = 1e20  # bounds beyond this are treated as absent
_DEGENERATE = 1e-9  # multipliers / slacks this small make an active set degenerate
_ROUNDOFF = 1e-11  # violations this small at a degenerate vertex are round-off
_DEPENDENT = 1e-10  # a normal this close to the working set's span depends on it
_VERIFY = 1e-8  # a final violation above this (relative) is a numerical failure


@njit(cache=True)
def cholesky_into(G, n, shift, L):
    """Cholesky factor of ``G[:n, :n] - shift I`` written into the lower triangle of
    ``L[:n, :n]`` (``G`` unchanged); False as soon as a pivot is not positive (the matrix
    is not positive definite; ``L`` then holds a partial factor)."""
    for j in range(n):
        s = G[j, j] - shift
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return False
        d = np.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, n):
            t = G[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / d
    return True


@njit(cache=True)
def cholesky(H):
    """Lower Cholesky factor of a symmetric matrix and success flag (no exception)."""
    n = H.shape[0]
    L = np.zeros((n, n))
    return L, cholesky_into(H, n, 0.0, L)


@njit(cache=True)
def forward(L, B):
    """``L^-1 B`` for lower-triangular ``L`` and a matrix ``B``."""
    n, q = B.shape
    X = np.empty((n, q))
    for col in range(q):
        for i in range(n):
            s = B[i, col]
            for k in range(i):
                s -= L[i, k] * X[k, col]
            X[i, col] = s / L[i, i]
    return X


@njit(cache=True)
def forward_vec(L, b):
    """``L^-1 b`` for lower-triangular ``L``."""
    n = b.shape[0]
    x = np.empty(n)
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= L[i, k] * x[k]
        x[i] = s / L[i, i]
    return x


@njit(cache=True)
def backward_vec(L, b):
    """``L^-T b`` for lower-triangular ``L``."""
    n = b.shape[0]
    x = np.empty(n)
    for i in range(n - 1, -1, -1):
        s = b[i]
        for k in range(i + 1, n):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]
    return x


# Small dense products as loops: at IK sizes (n <= ~100) they beat a BLAS call's overhead,
# and their rounding is fixed by the code (no library or alignment dependence).
@njit(cache=True)
def mm(A, B):
    """``A @ B``."""
    m, k = A.shape
    n = B.shape[1]
    C = np.zeros((m, n))
    for i in range(m):
        for t in range(k):
            a = A[i, t]
            if a != 0.0:
                for j in range(n):
                    C[i, j] += a * B[t, j]
    return C


@njit(cache=True)
def mtm(A):
    """``A^T @ A`` (symmetric, computed once per pair)."""
    m, n = A.shape
    C = np.zeros((n, n))
    for t in range(m):
        for i in range(n):
            a = A[t, i]
            if a != 0.0:
                for j in range(i, n):
                    C[i, j] += a * A[t, j]
    for i in range(n):
        for j in range(i):
            C[i, j] = C[j, i]
    return C


@njit(cache=True)
def mv(A, x):
    """``A @ x``."""
    m, n = A.shape
    y = np.empty(m)
    for i in range(m):
        acc = 0.0
        for j in range(n):
            acc += A[i, j] * x[j]
        y[i] = acc
    return y


@njit(cache=True)
def mtv(A, x):
    """``A^T @ x``."""
    m, n = A.shape
    y = np.zeros(n)
    for i in range(m):
        a = x[i]
        if a != 0.0:
            for j in range(n):
                y[j] += A[i, j] * a
    return y


@njit(cache=True)
def dot(x, y):
    """``x @ y`` for vectors."""
    acc = 0.0
    for i in range(x.shape[0]):
        acc += x[i] * y[i]
    return acc


@njit(cache=True)
def min_singular(M):
    """Smallest singular value of ``M`` (p, m), p <= m, by one-sided Jacobi rotations of its
    rows (Hestenes): accurate to a few ulps relative to the value itself, and cheaper than
    LAPACK at these sizes."""
    U = M.copy()
    p, m = U.shape
    for _ in range(60):
        rotated = False
        for i in range(p - 1):
            for j in range(i + 1, p):
                alpha = 0.0
                beta = 0.0
                gamma = 0.0
                for k in range(m):
                    alpha += U[i, k] * U[i, k]
                    beta += U[j, k] * U[j, k]
                    gamma += U[i, k] * U[j, k]
                if gamma == 0.0 or abs(gamma) <= 1e-15 * np.sqrt(alpha * beta):
                    continue
                rotated = True
                zeta = (beta - alpha) / (2.0 * gamma)
                t = (1.0 if zeta >= 0.0 else -1.0) / (abs(zeta) + np.sqrt(1.0 + zeta * zeta))
                cs = 1.0 / np.sqrt(1.0 + t * t)
                sn = cs * t
                for k in range(m):
                    ui = U[i, k]
                    uj = U[j, k]
                    U[i, k] = cs * ui - sn * uj
                    U[j, k] = sn * ui + cs * uj
        if not rotated:
            break
    smallest = np.inf
    for i in range(p):
        norm = 0.0
        for k in range(m):
            norm += U[i, k] * U[i, k]
        smallest = min(smallest, np.sqrt(norm))
    return smallest


@njit(cache=True)
def _swap_pivot(R, norms, perm, i):
    """Column pivoting step: bring the column of largest remaining norm to position i."""
    best = i
    for j in range(i + 1, R.shape[1]):
        if norms[j] > norms[best]:
            best = j
    if best != i:
        for t in range(R.shape[0]):
            tmp = R[t, i]
            R[t, i] = R[t, best]
            R[t, best] = tmp
        tmp = norms[i]
        norms[i] = norms[best]
        norms[best] = tmp
        k = perm[i]
        perm[i] = perm[best]
        perm[best] = k


# Complexity 12: one Householder reflection, applied to R and accumulated into Q (two
# short loops over the same vector; split, the pair would pass the vector twice).
@njit(cache=True)
def _reflect(R, Q, x, i):
    """Apply the Householder reflection zeroing ``R[i+1:, i]`` to ``R`` (from the left)
    and accumulate it into ``Q`` (from the right); ``x`` is scratch (r,)."""
    r, m = R.shape
    size = r - i
    alpha = 0.0
    for t in range(size):
        x[t] = R[i + t, i]
        alpha += x[t] * x[t]
    alpha = np.sqrt(alpha)
    if alpha == 0.0:
        return
    if x[0] > 0.0:
        alpha = -alpha
    x[0] -= alpha
    vn = 0.0
    for t in range(size):
        vn += x[t] * x[t]
    if vn == 0.0:
        return
    for j in range(i, m):
        s = 0.0
        for t in range(size):
            s += x[t] * R[i + t, j]
        s = 2.0 * s / vn
        for t in range(size):
            R[i + t, j] -= s * x[t]
    for row in range(r):
        s = 0.0
        for t in range(size):
            s += Q[row, i + t] * x[t]
        s = 2.0 * s / vn
        for t in range(size):
            Q[row, i + t] -= s * x[t]


@njit(cache=True)
def _column_norms(R, start, norms):
    """``norms[j] = |R[start:, j]|^2`` for the columns after ``start - 1``."""
    for j in range(max(start, 0), R.shape[1]):
        norms[j] = 0.0
        for t in range(start, R.shape[0]):
            norms[j] += R[t, j] * R[t, j]


@njit(cache=True)
def householder_qr(M, pivot):
    """QR of ``M`` (r, m) by Householder reflections, optionally with column pivoting
    (rank revealing): ``M[:, perm] = Q R`` with ``Q`` (r, r) orthogonal and ``R`` (r, m)
    upper trapezoidal, ``|R_00| >= |R_11| >= ...`` when pivoting. Small matrices only: no
    LAPACK call overhead."""
    r, m = M.shape
    R = M.copy()
    Q = np.eye(r)
    perm = np.arange(m)
    norms = np.zeros(m)
    if pivot:
        _column_norms(R, 0, norms)
    x = np.empty(r)
    for i in range(min(r, m)):
        if pivot:
            _swap_pivot(R, norms, perm, i)
        _reflect(R, Q, x, i)
        if pivot:
            _column_norms(R, i + 1, norms)
    return Q, R, perm


@njit(cache=True)
def _normal(C, row, side):
    """Normal ``n`` of one-sided constraint ``n^T x >= rhs``: ``C_row`` (lower side, +1)
    or ``-C_row`` (upper side, -1)."""
    return C[row] * side


@njit(cache=True)
def _rhs(lo, hi, row, side):
    return lo[row] if side > 0 else -hi[row]


# Complexity 12: the null-space method's steps (QR of the normals, particular solution,
# reduced Hessian, multipliers) share their factors; each check returns early.
@njit(cache=True)
def _kkt_solve(H, L, c, C, lo, hi, act_row, act_side, q):
    """Minimiser of the QP with the working set held as equalities, and its multipliers
    (one per working constraint, >= 0 when dual feasible), by the null-space method:
    ``N = [Y W] [R1; 0]``, ``x = Y R1^-T rhs + W y`` with ``(W^T H W) y = -W^T (H x_p +
    c)``, ``R1 u = Y^T (H x + c)``. Stable however ill-conditioned ``H`` is (a vertex is
    found from the constraints alone). ``ok`` is False when the normals are dependent."""
    n = L.shape[0]
    if q == 0:
        return backward_vec(L, forward_vec(L, -c)), np.zeros(0), True
    N = np.empty((n, q))
    rhs = np.empty(q)
    for j in range(q):
        N[:, j] = C[act_row[j]] * act_side[j]
        rhs[j] = _rhs(lo, hi, act_row[j], act_side[j])
    Q, R, _ = householder_qr(N, False)
    scale = 0.0
    for i in range(q):
        scale = max(scale, abs(R[i, i]))
    for i in range(q):
        if abs(R[i, i]) <= 1e-13 * max(scale, 1e-300):
            return np.zeros(n), np.zeros(q), False
    t = np.empty(q)
    for i in range(q):  # R1^T t = rhs
        acc = rhs[i]
        for k in range(i):
            acc -= R[k, i] * t[k]
        t[i] = acc / R[i, i]
    Y = Q[:, :q].copy()
    x = mv(Y, t)
    if q < n:
        W = Q[:, q:].copy()
        Hr = mm(W.T.copy(), mm(H, W))
        Lr, ok = cholesky(Hr)
        if not ok:
            return x, np.zeros(q), False
        g = mtv(W, mv(H, x) + c)
        y = backward_vec(Lr, forward_vec(Lr, -g))
        x = x + mv(W, y)
    grad = mtv(Y, mv(H, x) + c)
    u = np.empty(q)
    for i in range(q - 1, -1, -1):  # R1 u = Y^T (H x + c)
        acc = grad[i]
        for k in range(i + 1, q):
            acc -= R[i, k] * u[k]
        u[i] = acc / R[i, i]
    return x, u, True


@njit(cache=True)
def _row_value(C, i, x):
    """``(C_i x, |C_i|)``."""
    cx = 0.0
    norm = 0.0
    for j in range(x.shape[0]):
        cx += C[i, j] * x[j]
        norm += C[i, j] * C[i, j]
    return cx, np.sqrt(norm)


@njit(cache=True)
def _max_abs(u, q):
    """``max |u[:q]|`` (0 when q is 0)."""
    big = 0.0
    for j in range(q):
        big = max(big, abs(u[j]))
    return big


@njit(cache=True)
def _row_norms(C):
    """``|C_i|`` of every row."""
    m, n = C.shape
    norms = np.empty(m)
    for i in range(m):
        norm = 0.0
        for j in range(n):
            norm += C[i, j] * C[i, j]
        norms[i] = np.sqrt(norm)
    return norms


@njit(cache=True)
def _unit_columns(C):
    """Per row, the column of its single entry when the row is +-e_j (a bound on one
    variable: level 0's box), else -1. Products with such a row skip the zeros (same
    bits: adding zeros does not change a sum)."""
    m, n = C.shape
    unit = np.full(m, -1, dtype=np.int64)
    for i in range(m):
        col = -1
        for j in range(n):
            if C[i, j] != 0.0:
                if col >= 0 or abs(C[i, j]) != 1.0:
                    col = -2
                    break
                col = j
        if col >= 0:
            unit[i] = col
    return unit


@njit(cache=True)
def _most_violated(x, C, lo, hi, skip, tol, norms, unit):
    """The most violated constraint (row, side) at x, by violation / |C_row| (``norms``);
    row -1 if every constraint holds within ``tol`` (relative to 1 + |bound|)."""
    m, n = C.shape
    best, best_row, best_side = 0.0, -1, 0
    for i in range(m):
        if skip[i]:
            continue
        norm = norms[i]
        if norm == 0.0:
            continue
        if unit[i] >= 0:
            cx = 0.0 + C[i, unit[i]] * x[unit[i]]
        else:
            cx = 0.0
            for j in range(n):
                cx += C[i, j] * x[j]
        if lo[i] > -_BIG:
            v = (lo[i] - cx) / norm
            if v > tol * (1.0 + abs(lo[i])) and v > best:
                best, best_row, best_side = v, i, 1
        if hi[i] < _BIG:
            v = (cx - hi[i]) / norm
            if v > tol * (1.0 + abs(hi[i])) and v > best:
                best, best_row, best_side = v, i, -1
    return best_row, best_side


@njit(cache=True)
def _dual_floor(u, q):
    """Multipliers at or below this are zero (weakly active constraints)."""
    return 1e-12 * (1.0 + _max_abs(u, q))


@njit(cache=True)
def _kkt_ok(x, u, C, lo, hi, q, tol):
    """Primal feasibility of x and dual feasibility of the multipliers u."""
    floor = _dual_floor(u, q)
    for j in range(q):
        if u[j] < -floor:
            return False
    skip = np.zeros(C.shape[0], dtype=np.bool_)
    row, _ = _most_violated(x, C, lo, hi, skip, tol, _row_norms(C), _unit_columns(C))
    return row < 0


@njit(cache=True)
def _strictly_optimal(x, u, C, lo, hi, act_row, q):
    """Whether a working set is the QP's *unique* optimal active set: every multiplier
    clearly positive and every other constraint clearly inactive (strict complementarity;
    the working set's normals are independent by construction). Only then is a warm
    start accepted, so that it finds exactly the set a cold start finds."""
    big = _max_abs(u, q)
    for j in range(q):
        if u[j] <= _DEGENERATE * (1.0 + big):
            return False
    m = C.shape[0]
    working = np.zeros(m, dtype=np.bool_)
    for j in range(q):
        working[act_row[j]] = True
    for i in range(m):
        if working[i]:
            continue
        cx, norm = _row_value(C, i, x)
        if norm == 0.0:
            continue
        margin = _DEGENERATE * norm
        if lo[i] > -_BIG and cx - lo[i] <= margin * (1.0 + abs(lo[i])):
            return False
        if hi[i] < _BIG and hi[i] - cx <= margin * (1.0 + abs(hi[i])):
            return False
    return True


@njit(cache=True)
def _inverse_transpose(L):
    """``L^-T`` of a lower-triangular ``L``: row i is ``L^-1 e_i`` (forward substitution)."""
    n = L.shape[0]
    J = np.zeros((n, n))
    for i in range(n):
        J[i, i] = 1.0 / L[i, i]
        for k in range(i + 1, n):
            acc = 0.0
            for j in range(i, k):
                acc -= L[k, j] * J[i, j]
            J[i, k] = acc / L[k, k]
    return J


# Steps of solve_qp's dual active-set iteration (Goldfarb-Idnani; J, R, u and the working
# set are updated in place).
@njit(cache=True)
def _directions(J, R, normal, unit, q, d, z, r):
    """``d = J^T n``; ``z = J2 d2`` (primal direction); ``r = R^-1 d1`` (dual direction).
    ``unit >= 0``: ``n`` is +-e_unit."""
    n = J.shape[0]
    if unit >= 0:
        for i in range(n):
            d[i] = 0.0 + J[unit, i] * normal[unit]
    else:
        for i in range(n):
            acc = 0.0
            for k in range(n):
                acc += J[k, i] * normal[k]
            d[i] = acc
    for k in range(n):
        acc = 0.0
        for i in range(q, n):
            acc += J[k, i] * d[i]
        z[k] = acc
    for i in range(q - 1, -1, -1):
        acc = d[i]
        for j in range(i + 1, q):
            acc -= R[i, j] * r[j]
        r[i] = acc / R[i, i]


@njit(cache=True)
def _dual_step(u, r, q):
    """Partial (dual) step: the largest ``t`` keeping the working multipliers >= 0, and the
    working constraint that blocks it (-1: none)."""
    t1 = np.inf
    drop = -1
    for j in range(q):
        if r[j] > 0.0:
            t = u[j] / r[j]
            if t < t1:
                t1, drop = t, j
    return t1, drop


@njit(cache=True)
def _primal_step(d, z, normal, slack, q):
    """Full (primal) step: the ``t`` that makes the candidate hold with equality; inf when
    the candidate's normal lies (numerically) in the span of the working set's (then
    ``d2 = d[q:]`` is round-off and ``z = J2 d2`` garbage)."""
    outside = 0.0
    total = 0.0
    for i in range(d.shape[0]):
        total += d[i] * d[i]
        if i >= q:
            outside += d[i] * d[i]
    zn = dot(z, normal)
    if outside > _DEPENDENT * _DEPENDENT * total and zn > 0.0:
        return max(-slack / zn, 0.0)
    return np.inf


@njit(cache=True)
def _rotate_in(J, d, q):
    """Add a constraint: Givens rotations of ``J``'s columns so that only ``d[:q+1]`` is
    non-zero (``d[q]`` becomes the new diagonal entry of ``R``)."""
    n = J.shape[0]
    for j in range(n - 1, q, -1):
        cc = d[j - 1]
        ss = d[j]
        h = np.hypot(cc, ss)
        if h == 0.0:
            continue
        d[j] = 0.0
        ss /= h
        cc /= h
        if cc < 0.0:
            cc = -cc
            ss = -ss
            d[j - 1] = -h
        else:
            d[j - 1] = h
        xny = ss / (1.0 + cc)
        for k in range(n):
            a = J[k, j - 1]
            b2 = J[k, j]
            J[k, j - 1] = a * cc + b2 * ss
            J[k, j] = xny * (a + J[k, j - 1]) - b2


@njit(cache=True)
def _drop(J, R, u, act_row, act_side, in_set, drop, q):
    """Remove working constraint ``drop`` of ``q``: shift the set, its multipliers and
    ``R``'s columns, then restore ``R``'s triangle (and ``J``) by Givens rotations."""
    n = J.shape[0]
    in_set[act_row[drop]] = False
    for j in range(drop, q - 1):
        act_row[j] = act_row[j + 1]
        act_side[j] = act_side[j + 1]
        u[j] = u[j + 1]
        for i in range(n):
            R[i, j] = R[i, j + 1]
    u[q - 1] = u[q]
    u[q] = 0.0
    for i in range(n):
        R[i, q - 1] = 0.0
    q -= 1
    for j in range(drop, q):
        cc = R[j, j]
        ss = R[j + 1, j]
        h = np.hypot(cc, ss)
        if h == 0.0:
            continue
        cc /= h
        ss /= h
        R[j + 1, j] = 0.0
        if cc < 0.0:
            R[j, j] = -h
            cc = -cc
            ss = -ss
        else:
            R[j, j] = h
        xny = ss / (1.0 + cc)
        for k in range(j + 1, q):
            a = R[j, k]
            b2 = R[j + 1, k]
            R[j, k] = a * cc + b2 * ss
            R[j + 1, k] = xny * (a + R[j, k]) - b2
        for k in range(n):
            a = J[k, j]
            b2 = J[k, j + 1]
            J[k, j] = a * cc + b2 * ss
            J[k, j + 1] = xny * (J[k, j] + a) - b2


@njit(cache=True)
def _mark(active, act_row, act_side, q):
    """Write the working set into ``active`` (the ``warm`` format)."""
    for j in range(q):
        active[act_row[j]] = act_side[j]


@njit(cache=True)
def _warm_answer(H, L, c, C, lo, hi, warm, tol, act_row, act_side):
    """``(True, answer)`` when the warm active set is still the QP's unique optimal one
    (then it is the answer, polished canonically), else ``(False, _)``."""
    m = C.shape[0]
    n = L.shape[0]
    q = 0
    for i in range(m):
        if warm[i] != 0:
            q += 1
    if q == 0 or q > n:
        return False, (np.zeros(n), NUMERICAL, 0, np.zeros(m, dtype=np.int8))
    q = 0
    for i in range(m):
        if warm[i] != 0:
            act_row[q] = i
            act_side[q] = warm[i]
            q += 1
    x, u, ok = _kkt_solve(H, L, c, C, lo, hi, act_row, act_side, q)
    if ok and _strictly_optimal(x, u, C, lo, hi, act_row, q):
        polished = _polish(H, L, c, C, lo, hi, x, u, act_row, act_side, q, 0, tol)
        if polished[1] == SOLVED:
            return True, polished
    return False, (np.zeros(n), NUMERICAL, 0, np.zeros(m, dtype=np.int8))


# Complexity 18: the Goldfarb-Idnani iteration (add a violated row, step, drop a blocking
# one) updates J, R, u and the working set in place; its steps are helpers above, and
# what remains are the method's exits (solved, cap, infeasible, dependent row).
@njit(cache=True)
def solve_qp(H, c, C, lo, hi, warm, max_iter, tol, canonical):
    """Solve ``min 1/2 x^T H x + c^T x s.t. lo <= C x <= hi`` exactly.

    Args:
        H: (n, n) symmetric positive definite.
        c: (n,).
        C: (m, n) constraint rows; ``lo``/``hi`` (m,), with +-1e20 or beyond for none
            (``lo == hi`` is an equality).
        warm: (m,) int8, the active set to try first: +1 lower side active, -1 upper
            side, 0 inactive (all zeros for a cold start).
        max_iter: cap on active-set changes.
        tol: feasibility tolerance, relative to ``1 + |bound|`` per unit row norm.
        canonical: end with the canonical KKT re-solve (needed when warm starts are used,
            so that both paths give the same bits); otherwise the cold answer is checked
            for stationarity and dual feasibility, which costs O(n q) instead of O(n^3).

    Returns:
        ``(x, status, iterations, active)``: ``active`` (m,) int8 in the ``warm`` format,
        the constraints with a positive multiplier at ``x``. ``status`` is SOLVED,
        MAX_ITER (x is the last iterate), INFEASIBLE or NUMERICAL (H not positive
        definite).
    """
    n = H.shape[0]
    m = C.shape[0]
    active = np.zeros(m, dtype=np.int8)
    L, ok = cholesky(H)
    if not ok:
        return np.zeros(n), NUMERICAL, 0, active
    act_row = np.empty(n + 1, dtype=np.int64)
    act_side = np.empty(n + 1, dtype=np.int64)
    q = 0
    found, polished = _warm_answer(H, L, c, C, lo, hi, warm, tol, act_row, act_side)
    if found:
        return polished
    # Cold: Goldfarb-Idnani from the unconstrained minimiser, with the factorisation
    # J = L^-T Q and the triangular R of the working set updated by Givens rotations as
    # constraints enter and leave (as in quadprog / eiquadprog): O(n^2) per change.
    x = backward_vec(L, forward_vec(L, -c))
    J = _inverse_transpose(L)
    R = np.zeros((n, n))
    r_norm = 1.0
    u = np.zeros(n + 1)
    d = np.empty(n)
    z = np.empty(n)
    r = np.empty(n + 1)
    in_set = np.zeros(m, dtype=np.bool_)
    norms = _row_norms(C)
    unit = _unit_columns(C)
    x_old = np.empty(n)
    u_old = np.empty(n + 1)
    iterations = 0
    while True:
        row, side = _most_violated(x, C, lo, hi, in_set, tol, norms, unit)
        if row < 0:
            if canonical:
                polished = _polish(H, L, c, C, lo, hi, x, u, act_row, act_side, q, iterations, tol)
                if polished[1] == SOLVED:
                    return polished
            verified = _verified(H, c, C, x, u, act_row, act_side, q, iterations)
            if verified[1] == SOLVED or canonical:
                return verified
            # The iteration's multipliers could not be verified (an ill-conditioned H):
            # the KKT system of the final active set, solved afresh, may still be.
            polished = _polish(H, L, c, C, lo, hi, x, u, act_row, act_side, q, iterations, tol)
            return polished if polished[1] == SOLVED else verified
        normal = _normal(C, row, side)
        rhs = _rhs(lo, hi, row, side)
        u[q] = 0.0
        while True:
            iterations += 1
            if iterations > max_iter:
                _mark(active, act_row, act_side, q)
                return x, MAX_ITER, iterations, active
            _directions(J, R, normal, unit[row], q, d, z, r)
            t1, drop = _dual_step(u, r, q)
            slack = dot(normal, x) - rhs
            t2 = _primal_step(d, z, normal, slack, q)
            t = min(t1, t2)
            if t == np.inf:
                # The candidate depends on the working set and no multiplier can give way.
                # At a degenerate vertex round-off leaves a violation of a few ulps: that
                # is not infeasibility, so the row is taken as met.
                nn = np.sqrt(dot(normal, normal))
                if -slack <= _ROUNDOFF * (nn * (1.0 + np.abs(x).max()) + abs(rhs)):
                    in_set[row] = True
                    break
                _mark(active, act_row, act_side, q)
                return x, INFEASIBLE, iterations, active
            full = t2 <= t1
            if full:
                x_old[:] = x
                u_old[:] = u
            if t2 < np.inf:
                for k in range(n):
                    x[k] += t * z[k]
            for j in range(q):
                u[j] -= t * r[j]
            u[q] += t
            if full:
                _rotate_in(J, d, q)
                for i in range(q + 1):
                    R[i, q] = d[i]
                if abs(d[q]) <= 1e-14 * r_norm:
                    # Numerically dependent on the working set after all: undo the step
                    # (J is unchanged where it matters) and leave the row out; the final
                    # verification catches it if it stays violated.
                    x[:] = x_old
                    u[:] = u_old
                    u[q] = 0.0
                    in_set[row] = True
                    break
                r_norm = max(r_norm, abs(d[q]))
                act_row[q] = row
                act_side[q] = side
                in_set[row] = True
                q += 1
                break
            # Drop the blocking constraint, restore R's triangle, and try again.
            _drop(J, R, u, act_row, act_side, in_set, drop, q)
            q -= 1


@njit(cache=True)
def _verified(H, c, C, x, u, act_row, act_side, q, iterations):
    """The cold answer with its KKT conditions checked: stationarity ``H x + c = N u`` and
    ``u >= 0`` (primal feasibility holds when the method ends). NUMERICAL otherwise.

    Stationarity is judged relative to the size of the terms summed (``|H| |x|``, ``|c|``,
    ``|N| |u|``, a backward error): on an ill-conditioned QP (a target 1e5 m away makes
    ``H`` 1e10 while the box keeps ``x`` at 0.02) the products cancel to a residual far
    above 1e-8 of ``|H x + c|`` while ``x`` is exact."""
    m = C.shape[0]
    n = x.shape[0]
    active = np.zeros(m, dtype=np.int8)
    floor = _dual_floor(u, q)
    g = mv(H, x) + c
    size = np.abs(c)
    for i in range(n):
        for j in range(n):
            size[i] += abs(H[i, j] * x[j])
    for j in range(q):
        if u[j] < -floor:
            return x, NUMERICAL, iterations, active
        if u[j] > floor:
            active[act_row[j]] = act_side[j]
        for i in range(n):
            term = u[j] * act_side[j] * C[act_row[j], i]
            g[i] -= term
            size[i] += abs(term)
    scale = 1.0
    for i in range(n):
        scale = max(scale, size[i])
    for i in range(n):
        if abs(g[i]) > _VERIFY * scale:
            return x, NUMERICAL, iterations, active
    return x, SOLVED, iterations, active


@njit(cache=True)
def _polish(H, L, c, C, lo, hi, x, u, act_row, act_side, q, iterations, tol):
    """Re-solve the KKT system on the canonical active set (positive multipliers, sorted
    by row) so that the answer does not depend on how that set was found."""
    m = C.shape[0]
    n = L.shape[0]
    active = np.zeros(m, dtype=np.int8)
    floor = _dual_floor(u, q)
    for j in range(q):
        if u[j] > floor:
            active[act_row[j]] = act_side[j]
    rows = np.empty(n + 1, dtype=np.int64)
    sides = np.empty(n + 1, dtype=np.int64)
    k = 0
    for i in range(m):
        if active[i] != 0:
            rows[k] = i
            sides[k] = active[i]
            k += 1
    xp, up, ok = _kkt_solve(H, L, c, C, lo, hi, rows, sides, k)
    # Accept the canonical solution unless it is clearly worse than the iterate (GI's own
    # answer is no more accurate): so both a warm and a cold start end here.
    if ok and _kkt_ok(xp, up, C, lo, hi, k, max(tol, 1e-9)):
        return xp, SOLVED, iterations, active
    # The KKT conditions could not be verified on the final active set (degeneracy and
    # round-off): never call that solved; the caller retries with widened rows.
    return x, NUMERICAL, iterations, active


@njit(cache=True)
def _widened(lo, hi, scale):
    """Bounds widened by ``scale (1 + |bound|) (1 + i / m)``: distinct per row, so that a
    degenerate vertex (more rows active than dimensions) becomes a regular one."""
    m = lo.shape[0]
    lo2 = np.empty(m)
    hi2 = np.empty(m)
    for i in range(m):
        eps = scale * (1.0 + i / max(m, 1))
        lo2[i] = lo[i] - eps * (1.0 + abs(lo[i])) if lo[i] > -_BIG else lo[i]
        hi2[i] = hi[i] + eps * (1.0 + abs(hi[i])) if hi[i] < _BIG else hi[i]
    return lo2, hi2


@njit(cache=True)
def active_guess(x, C, lo, hi):
    """Rows at a bound at an approximate solution ``x`` (a backend's): +1 lower, -1 upper
    (within ``1e-6 (1 + |C_i x|)``), in the ``warm`` format of :func:`solve_qp`."""
    m, n = C.shape
    guess = np.zeros(m, dtype=np.int8)
    for i in range(m):
        cx = 0.0
        for j in range(n):
            cx += C[i, j] * x[j]
        scale = 1e-6 * (1.0 + abs(cx))
        if np.isfinite(lo[i]) and cx <= lo[i] + scale:
            guess[i] = 1
        if np.isfinite(hi[i]) and cx >= hi[i] - scale:
            guess[i] = -1
    return guess


@njit(cache=True)
def solve_level(H, c, C, lo, hi, warm, max_iter, tol, lower, canonical):
    """:func:`solve_qp` for one level, robust to degenerate vertices: when the exact solve
    fails numerically (or, below the first level, whose QP is feasible by construction
    since ``z = 0`` meets every row, reports infeasibility), the rows are widened by
    1e-11, then 1e-9 (relative, distinct per row) and the QP solved again. The box is
    re-imposed exactly on ``dq`` afterwards."""
    z, st, its, act = solve_qp(H, c, C, lo, hi, warm, max_iter, tol, canonical)
    if st == SOLVED or st == MAX_ITER or (st == INFEASIBLE and not lower):
        return z, st, its, act
    m = lo.shape[0]
    for scale in (1e-11, 1e-9):
        lo2, hi2 = _widened(lo, hi, scale)
        cold = np.zeros(m, dtype=np.int8)
        z, st, more, act = solve_qp(H, c, C, lo2, hi2, cold, max_iter, tol, canonical)
        its += more
        if st == SOLVED:
            return z, st, its, act
    return z, st, its, act


@njit(cache=True)
def _unit_rows(A, w):
    """Whether ``diag(1/w) A`` is the identity (square, every weight positive)."""
    m, n = A.shape
    if m != n:
        return False
    for i in range(m):
        if not w[i] > 0.0:
            return False
        for j in range(n):
            if A[i, j] != (w[i] if i == j else 0.0):
                return False
    return True


# Complexity 12: the projection, the rank decision and the singular value share one QR;
# the posture-like and empty levels return early.
@njit(cache=True)
def project_level(A, w, Z, rank_tol):
    """Project a level into the null space ``Z`` of the levels above.

    Returns ``(AZ, sigma, rank, Zn)``: ``A Z``; the smallest singular value of the
    *unweighted* projected rows ``diag(1/w) A Z`` (rows with ``w == 0`` dropped: these are
    in the units of the tasks' Jacobians, whatever their costs) that is not a structural
    zero (``inf`` when there is none); that matrix's numerical rank (pivots above
    ``rank_tol * max(1, |R_00|)`` of a rank-revealing QR); and ``Zn``, an orthonormal basis
    of its null space within ``Z`` (the next level's ``Z``)."""
    AZ = mm(A, Z)
    m = A.shape[0]
    r = Z.shape[1]
    keep = 0
    for i in range(m):
        if w[i] > 0.0:
            keep += 1
    if keep == 0 or r == 0:
        return AZ, np.inf, 0, Z
    if _unit_rows(A, w):
        # diag(1/w) A is the identity (a posture-like level over every dof): its rows in
        # the null space are Z itself, whose singular values are all 1; nothing remains.
        return AZ, 1.0, r, np.zeros((Z.shape[0], 0))
    Mt = np.empty((r, keep))  # (diag(1/w) A Z)^T
    k = 0
    for i in range(m):
        if w[i] > 0.0:
            for j in range(r):
                Mt[j, k] = AZ[i, j] / w[i]
            k += 1
    Q, R, _ = householder_qr(Mt, True)
    top = abs(R[0, 0])
    cutoff = rank_tol * max(1.0, top)
    rank = 0
    for i in range(min(r, keep)):
        if abs(R[i, i]) > cutoff:
            rank += 1
    sigma = np.inf
    if rank > 0:
        # The singular values of the rank-p block R_p are those of the projected rows.
        Rp = R[:rank, :].copy()
        sigma = min_singular(Rp)
        if sigma <= cutoff:  # round-off below the rank decision: the last pivot bounds it
            sigma = abs(R[rank - 1, rank - 1])
    Zn = mm(Z, Q[:, rank:].copy())
    return AZ, sigma, rank, Zn


@njit(cache=True)
def level_damping(A, b, w, d, sigma, threshold, max_damping, error_scale):
    """The ``lambda^2`` a level gets: :func:`damping_of` its ``sigma``, scaled by its
    largest row cost squared and, with ``error_scale > 0``, by ``min(1, |A d - b| /
    error_scale)``. 0 when ``max_damping <= 0`` (no adaptive damping)."""
    if not max_damping > 0.0:
        return 0.0
    lam = damping_of(sigma, threshold, max_damping)
    if lam > 0.0:
        wmax = 0.0
        for i in range(w.shape[0]):
            wmax = max(wmax, w[i])
        lam *= wmax * wmax
        if error_scale > 0.0:
            e = mv(A, d) - b
            lam *= min(1.0, np.sqrt(dot(e, e)) / error_scale)
    return lam


@njit(cache=True)
def damping_of(sigma, threshold, max_damping):
    """``lambda^2`` driven by ``sigma``: ``max_damping^2 (1 - (sigma / threshold)^2)``
    below the threshold, else 0."""
    if not sigma < threshold:
        return 0.0
    ratio = sigma / threshold
    return max_damping * max_damping * (1.0 - ratio * ratio)


# Complexity 11: the box rows and the general rows each need their bounds shifted and
# their fixed rows dropped.
@njit(cache=True)
def reduced_qp(A, b, AZ, Z, d, reg, lb, ub, G, h):
    """The level's QP in null-space coordinates ``dq = d + Z z``: ``H = (AZ)^T AZ +
    reg I``, ``c = (AZ)^T (A d - b) + reg Z^T d``; rows ``lb - d <= Z z <= ub - d`` and
    ``G Z z <= h - G d``."""
    n, r = Z.shape
    p = G.shape[0]
    H = mtm(AZ)
    big = 0.0
    for i in range(r):
        big = max(big, H[i, i])
    # A floor far below any damping a user sets keeps H positive definite when the level
    # is rank deficient and reg is 0.
    reg = max(reg, 1e-14 * (1.0 + big))
    for i in range(r):
        H[i, i] += reg
    c = mtv(AZ, mv(A, d) - b) + reg * mtv(Z, d)
    C = np.empty((n + p, r))
    lo = np.empty(n + p)
    hi = np.empty(n + p)
    C[:n] = Z
    for i in range(n):
        lo[i] = lb[i] - d[i] if lb[i] > -_BIG else -np.inf
        hi[i] = ub[i] - d[i] if ub[i] < _BIG else np.inf
    if p:
        C[n:] = mm(G, Z)
        Gd = mv(G, d)
        for j in range(p):
            lo[n + j] = -np.inf
            hi[n + j] = h[j] - Gd[j]
    # A row that the levels above have fixed (its projection into the null space is
    # round-off, |C_i| <= 1e-10 |row|) constrains nothing that z can move: dropped. Kept,
    # its round-off direction would enter the working set with a multiplier ~ 1/|C_i|
    # and wreck the active set. (The box is re-imposed exactly on dq after the level.)
    for i in range(n + p):
        size = 1.0
        if i >= n:
            size = 0.0
            for t in range(n):
                size += G[i - n, t] * G[i - n, t]
        norm = 0.0
        for t in range(r):
            norm += C[i, t] * C[i, t]
        if norm <= 1e-20 * size:
            lo[i] = -np.inf
            hi[i] = np.inf
    return H, c, C, lo, hi


@njit(cache=True)
def tighten(lb, ub, dofs, lower, upper):
    """``lb[dofs] = max(lb[dofs], lower)``, ``ub[dofs] = min(ub[dofs], upper)`` in place
    (a dof may repeat)."""
    for k in range(dofs.shape[0]):
        i = dofs[k]
        if lower[k] > lb[i]:
            lb[i] = lower[k]
        if upper[k] < ub[i]:
            ub[i] = upper[k]


@njit(cache=True)
def merge_boxes(hard_lb, hard_ub, pos_lb, pos_ub):
    """The box of hard (velocity-like) and recoverable (position-like) bounds: their
    intersection, except where they conflict (a start outside the position limits that
    one step cannot leave), where dq moves toward the position limits at the hard limit's
    pace. Returns ``(lb, ub, i)`` with ``i >= 0`` the first dof whose *hard* bounds
    conflict (no displacement satisfies them), else -1."""
    n = hard_lb.shape[0]
    lb = np.empty(n)
    ub = np.empty(n)
    for i in range(n):
        if hard_lb[i] > hard_ub[i]:
            return lb, ub, i
        lo = max(hard_lb[i], pos_lb[i])
        hi = min(hard_ub[i], pos_ub[i])
        if lo > hi:
            if pos_ub[i] < hard_lb[i]:
                lo = hi = hard_lb[i]
            elif pos_lb[i] > hard_ub[i]:
                lo = hi = hard_ub[i]
        lb[i] = lo
        ub[i] = hi
    return lb, ub, -1


@njit(cache=True)
def _level_residuals(A, b, starts, x):
    """Per level, ``|A_k x - b_k|`` over all its rows."""
    r = mv(A, x) - b
    L = starts.shape[0] - 1
    out = np.empty(L)
    for k in range(L):
        s = 0.0
        for i in range(starts[k], starts[k + 1]):
            s += r[i] * r[i]
        out[k] = np.sqrt(s)
    return out


# Complexity 11: the cascade's loop over levels with its early exits (an empty level, a
# failed level 0, an unsettled active set).
@njit(cache=True)
def solve_cascade(
    A,
    b,
    w,
    starts,
    reg,
    lb,
    ub,
    G,
    h,
    threshold,
    max_damping,
    error_scale,
    rank_tol,
    max_iter,
    tol,
    warm,
    canonical,
):
    """All levels of a hierarchy in one compiled call (see the module docstring).

    Args:
        A, b, w: the levels' rows stacked ``(M, n)``, ``(M,)``, ``(M,)`` (row weights: the
            tasks' costs, for the damping and rank decisions), level ``k`` in rows
            ``starts[k]:starts[k+1]``.
        reg: (L,) each level's constant regularisation (damping + LM terms).
        lb, ub: (n,) box bounds on dq; G, h: (p, n), (p,) general rows ``G dq <= h``.
        threshold, max_damping, error_scale: the damping law (``error_scale <= 0``: none;
            ``max_damping <= 0``: no adaptive damping).
        rank_tol: singular values below ``rank_tol * max(1, sigma_max)`` are zero.
        max_iter, tol: the QP's iteration cap and feasibility tolerance.
        warm: (L, n + p) int8 active sets to try first (zeros: cold).
        canonical: see :func:`solve_qp` (True when warm starts are used).

    Returns:
        ``(dq, status, sigma, lam2, iterations, active, residuals)`` with per-level
        arrays, ``active`` (L, n + p) the final active sets and ``residuals`` each
        level's ``|A_k dq - b_k|``.
    """
    n = lb.shape[0]
    p = G.shape[0]
    L = starts.shape[0] - 1
    status = np.full(L, NOT_REACHED, dtype=np.int64)
    sigma = np.full(L, np.inf)
    lam2 = np.zeros(L)
    iterations = np.zeros(L, dtype=np.int64)
    active = np.zeros((L, n + p), dtype=np.int8)
    d = np.zeros(n)
    # Start from the box-feasible point nearest to 0 (a start outside the limits).
    for i in range(n):
        if d[i] < lb[i]:
            d[i] = lb[i]
        if d[i] > ub[i]:
            d[i] = ub[i]
    Z = np.eye(n)
    for k in range(L):
        s0, s1 = starts[k], starts[k + 1]
        r = Z.shape[1]
        if s1 == s0 or r == 0:
            status[k] = SOLVED
            continue
        Ak = A[s0:s1]
        bk = b[s0:s1]
        AZ, sig, rank, Zn = project_level(Ak, w[s0:s1], Z, rank_tol)
        lam = level_damping(Ak, bk, w[s0:s1], d, sig, threshold, max_damping, error_scale)
        sigma[k] = sig
        lam2[k] = lam
        H, c, C, lo, hi = reduced_qp(Ak, bk, AZ, Z, d, reg[k] + lam, lb, ub, G, h)
        z, st, its, act = solve_level(H, c, C, lo, hi, warm[k], max_iter, tol, k > 0, canonical)
        iterations[k] = its
        active[k] = act
        if st == SOLVED:
            d = d + mv(Z, z)
            for i in range(n):
                if d[i] < lb[i]:
                    d[i] = lb[i]
                if d[i] > ub[i]:
                    d[i] = ub[i]
            status[k] = SOLVED
        else:
            status[k] = st if k == 0 or st == MAX_ITER else KEPT_PREVIOUS
            if st == MAX_ITER or st == NUMERICAL or k == 0:
                return d, status, sigma, lam2, iterations, active, _level_residuals(A, b, starts, d)
            continue
        Z = Zn
    return d, status, sigma, lam2, iterations, active, _level_residuals(A, b, starts, d)


def register_overloads(engine) -> None:
    """Make numba compile calls to ``engine``'s functions (the C++ kernels) as calls to the
    numba functions of the same name above."""
    from numba.extending import overload

    for name in (
        "cholesky_into", "solve_qp", "solve_level", "active_guess", "project_level",
        "level_damping", "damping_of", "reduced_qp", "tighten", "merge_boxes", "solve_cascade",
    ):  # fmt: skip
        target = getattr(engine, name)
        py_func = globals()[name].py_func

        def typer(*args, _impl=py_func):
            return _impl

        overload(target, strict=False)(typer)
