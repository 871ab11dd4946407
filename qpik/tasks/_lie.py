"""SE(3) routines of mink's compiled Lie-group module (``mink/lie/_lie_ops_c.c``), ported
operation for operation to numba so that a whole IK step can run in one compiled call.

Poses are ``wxyz_xyz`` (7,): a unit quaternion ``(w, x, y, z)`` then a translation [m].
Tangents are ``[v; omega]`` (6,) [m, rad]. 3x3 matrices are row-major (9,), as MuJoCo's
``xmat``. Every function writes into an ``out`` array: nothing is allocated, and the
arithmetic is done in the same order as mink's C code (tests compare them to 1e-12).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

EPS = 1e-10


@njit(cache=True, inline="always")
def _dot3(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, inline="always")
def _quat_mul(out, a, b) -> None:
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3]
    out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2]
    out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1]
    out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]


@njit(cache=True, inline="always")
def _quat_rotate(out, v, q) -> None:
    """``out = q v q^-1`` (``v`` (3,), ``q`` (w, x, y, z))."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    tx = 2.0 * (y * v[2] - z * v[1])
    ty = 2.0 * (z * v[0] - x * v[2])
    tz = 2.0 * (x * v[1] - y * v[0])
    out[0] = v[0] + w * tx + (y * tz - z * ty)
    out[1] = v[1] + w * ty + (z * tx - x * tz)
    out[2] = v[2] + w * tz + (x * ty - y * tx)


@njit(cache=True, inline="always")
def _skew(out, v) -> None:
    out[0] = 0.0
    out[1] = -v[2]
    out[2] = v[1]
    out[3] = v[2]
    out[4] = 0.0
    out[5] = -v[0]
    out[6] = -v[1]
    out[7] = v[0]
    out[8] = 0.0


@njit(cache=True, inline="always")
def _mat33_mul(C, A, B) -> None:
    for i in range(3):
        for j in range(3):
            C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j]


@njit(cache=True, inline="always")
def _mat33_transpose(out, m) -> None:
    for i in range(3):
        for j in range(3):
            out[3 * i + j] = m[3 * j + i]


@njit(cache=True)
def so3_log(omega, wxyz) -> None:
    """Rotation vector [rad] of a unit quaternion (the shorter way round)."""
    w, x, y, z = wxyz[0], wxyz[1], wxyz[2], wxyz[3]
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    norm = math.sqrt(x * x + y * y + z * z)
    if norm > 0.0:
        inv = 1.0 / norm
        x, y, z = x * inv, y * inv, z * inv
    if norm < EPS:
        omega[0] = 0.0
        omega[1] = 0.0
        omega[2] = 0.0
        return
    angle = 2.0 * math.atan2(norm, w)
    omega[0] = angle * x
    omega[1] = angle * y
    omega[2] = angle * z


@njit(cache=True)
def so3_ljacinv(out, omega) -> None:
    """SO(3) left Jacobian inverse at ``omega`` (row-major 3x3)."""
    theta = math.sqrt(_dot3(omega, omega))
    t2 = theta * theta
    if theta < EPS:
        beta = (1.0 / 12.0) * (1.0 + t2 / 60.0 * (1.0 + t2 / 42.0 * (1.0 + t2 / 40.0)))
    else:
        beta = (1.0 / t2) * (1.0 - (theta * math.sin(theta) / (2.0 * (1.0 - math.cos(theta)))))
    inner = _dot3(omega, omega)
    for i in range(3):
        for j in range(3):
            out[3 * i + j] = beta * (omega[i] * omega[j] - (inner if i == j else 0.0))
    a0, a1, a2 = -0.5 * omega[0], -0.5 * omega[1], -0.5 * omega[2]
    out[1] += -a2
    out[2] += a1
    out[3] += a2
    out[5] += -a0
    out[6] += -a1
    out[7] += a0
    out[0] += 1.0
    out[4] += 1.0
    out[8] += 1.0


@njit(cache=True)
def xmat_xpos_to_wxyz_xyz(out, xmat, xpos) -> None:
    """A MuJoCo frame (``xmat`` row-major 9, ``xpos`` 3) as ``wxyz_xyz`` (Shepperd)."""
    R = xmat
    tr = R[0] + R[4] + R[8]
    if tr > 0.0:
        s = math.sqrt(tr + 1.0) * 2.0
        out[0] = 0.25 * s
        out[1] = (R[7] - R[5]) / s
        out[2] = (R[2] - R[6]) / s
        out[3] = (R[3] - R[1]) / s
    elif R[0] > R[4] and R[0] > R[8]:
        s = math.sqrt(1.0 + R[0] - R[4] - R[8]) * 2.0
        out[0] = (R[7] - R[5]) / s
        out[1] = 0.25 * s
        out[2] = (R[1] + R[3]) / s
        out[3] = (R[2] + R[6]) / s
    elif R[4] > R[8]:
        s = math.sqrt(1.0 + R[4] - R[0] - R[8]) * 2.0
        out[0] = (R[2] - R[6]) / s
        out[1] = (R[1] + R[3]) / s
        out[2] = 0.25 * s
        out[3] = (R[5] + R[7]) / s
    else:
        s = math.sqrt(1.0 + R[8] - R[0] - R[4]) * 2.0
        out[0] = (R[3] - R[1]) / s
        out[1] = (R[2] + R[6]) / s
        out[2] = (R[5] + R[7]) / s
        out[3] = 0.25 * s
    n = math.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3])
    if n > 0.0:
        inv = 1.0 / n
        for i in range(4):
            out[i] *= inv
    out[4] = xpos[0]
    out[5] = xpos[1]
    out[6] = xpos[2]


@njit(cache=True)
def se3_log(tangent, T) -> None:
    """``log(T)`` as ``[v; omega]``."""
    omega = np.empty(3)
    so3_log(omega, T)
    theta = math.sqrt(_dot3(omega, omega))
    t2 = theta * theta
    skw = np.empty(9)
    skw2 = np.empty(9)
    vinv = np.empty(9)
    _skew(skw, omega)
    _mat33_mul(skw2, skw, skw)
    if t2 < EPS:
        for i in range(9):
            vinv[i] = -0.5 * skw[i] + skw2[i] / 12.0
    else:
        half = 0.5 * theta
        coeff = (1.0 - 0.5 * theta * math.cos(half) / math.sin(half)) / t2
        for i in range(9):
            vinv[i] = -0.5 * skw[i] + coeff * skw2[i]
    vinv[0] += 1.0
    vinv[4] += 1.0
    vinv[8] += 1.0
    t0, t1, t2_ = T[4], T[5], T[6]
    tangent[0] = vinv[0] * t0 + vinv[1] * t1 + vinv[2] * t2_
    tangent[1] = vinv[3] * t0 + vinv[4] * t1 + vinv[5] * t2_
    tangent[2] = vinv[6] * t0 + vinv[7] * t1 + vinv[8] * t2_
    tangent[3] = omega[0]
    tangent[4] = omega[1]
    tangent[5] = omega[2]


@njit(cache=True)
def se3_inverse_multiply(out, a, b) -> None:
    """``out = a^-1 b``."""
    inv_q = np.empty(4)
    inv_q[0] = a[0]
    inv_q[1] = -a[1]
    inv_q[2] = -a[2]
    inv_q[3] = -a[3]
    neg_t = np.empty(3)
    neg_t[0] = -a[4]
    neg_t[1] = -a[5]
    neg_t[2] = -a[6]
    inv_t = np.empty(3)
    _quat_rotate(inv_t, neg_t, inv_q)
    _quat_mul(out, inv_q, b)
    rotated = np.empty(3)
    _quat_rotate(rotated, b[4:7], inv_q)
    out[4] = rotated[0] + inv_t[0]
    out[5] = rotated[1] + inv_t[1]
    out[6] = rotated[2] + inv_t[2]


@njit(cache=True)
def se3_rminus(tangent, a, b) -> None:
    """``a ⊖ b = log(b^-1 a)``."""
    temp = np.empty(7)
    se3_inverse_multiply(temp, b, a)
    se3_log(tangent, temp)


@njit(cache=True)
def _get_q(Q, c) -> None:
    """The ``Q`` block of the SE(3) left Jacobian (Sola et al., eq. 180) at ``c``."""
    v = c[0:3]
    w = c[3:6]
    theta = math.sqrt(_dot3(w, w))
    t2 = theta * theta
    A = 0.5
    if t2 < EPS:
        B = (1.0 / 6.0) + (1.0 / 120.0) * t2
        C = -(1.0 / 24.0) + (1.0 / 720.0) * t2
        D = -(1.0 / 60.0)
    else:
        t4 = t2 * t2
        st = math.sin(theta)
        ct = math.cos(theta)
        B = (theta - st) / (t2 * theta)
        C = (1.0 - 0.5 * t2 - ct) / t4
        D = (2.0 * theta - 3.0 * st + theta * ct) / (2.0 * t4 * theta)
    V = np.empty(9)
    W = np.empty(9)
    _skew(V, v)
    _skew(W, w)
    VW = np.empty(9)
    WV = np.empty(9)
    WVW = np.empty(9)
    VWW = np.empty(9)
    VWW_T = np.empty(9)
    WVWW = np.empty(9)
    WWVW = np.empty(9)
    _mat33_mul(VW, V, W)
    _mat33_transpose(WV, VW)
    _mat33_mul(WVW, WV, W)
    _mat33_mul(VWW, VW, W)
    _mat33_transpose(VWW_T, VWW)
    _mat33_mul(WVWW, WVW, W)
    _mat33_mul(WWVW, W, WVW)
    for i in range(9):
        Q[i] = (
            A * V[i]
            + B * (WV[i] + VW[i] + WVW[i])
            - C * (VWW[i] - VWW_T[i] - 3.0 * WVW[i])
            + D * (WVWW[i] + WWVW[i])
        )


@njit(cache=True)
def se3_jlog(jlog, T) -> None:
    """``jlog(T)``: the right Jacobian inverse at ``log(T)`` (6x6)."""
    tangent = np.empty(6)
    se3_log(tangent, T)
    neg = -tangent
    for i in range(6):
        for j in range(6):
            jlog[i, j] = 0.0
    if _dot3(neg[3:6], neg[3:6]) < EPS:
        for i in range(6):
            jlog[i, i] = 1.0
        return
    Q = np.empty(9)
    _get_q(Q, neg)
    lji = np.empty(9)
    so3_ljacinv(lji, neg[3:6])
    for i in range(3):
        for j in range(3):
            jlog[i, j] = lji[3 * i + j]
            jlog[3 + i, 3 + j] = lji[3 * i + j]
    QJ = np.empty(9)
    JQJ = np.empty(9)
    _mat33_mul(QJ, Q, lji)
    _mat33_mul(JQJ, lji, QJ)
    for i in range(3):
        for j in range(3):
            jlog[i, 3 + j] = -JQJ[3 * i + j]
