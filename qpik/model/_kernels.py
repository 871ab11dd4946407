r"""Compiled kernels (numba, cached) of the kinematic chain and of the IGM solve.

Every kernel takes plain arrays: no MuJoCo call happens inside (a ctypes call cannot be
cached by numba), so they compile once per machine and load from numba's cache afterwards.
numba's cache of a kernel does not notice edits to the kernels it calls in *other*
modules: this module calls the core's Cholesky, and drops its cached code when
``qpik/core/_kernels.py`` changes (:func:`qpik.core._cache.drop_stale_cache`).
``NUMBA_DISABLE_JIT=1`` runs everything as Python while debugging.

Kinematics follow MuJoCo's ``mj_kinematics`` (``engine_core_smooth.c``): per body on the
chain, ``p <- p + R body_pos``, ``R <- R body_rot``; then per joint of the body, the axis
``R axis`` and anchor ``p + R jnt_pos`` in the world frame; a hinge rotates ``R`` about its
local axis by ``q - qpos0`` and keeps the anchor fixed, a slide moves ``p`` along the axis
by ``q - qpos0``. The frame Jacobian (``mj_jac``) has, per dof, ``[u x (p_f - a); u]`` for a
hinge and ``[u; 0]`` for a slide (world-aligned, ``[v; omega]``).

The IGM (:func:`igm_solve`): per iteration, the damped least-squares step of the pose error
under box bounds (joint limits), solved exactly by an active-set method
(:func:`box_qp`), with the trust region, the damping law fading with the error, backtracking
(a step that increases the error is halved, up to ``BACKTRACKS`` times), stall detection
(``stall_window`` iterations without the score falling below ``PROGRESS`` times its value at
the window's start) and restarts from a deterministic random stream (SplitMix64): odd
restarts draw from the central ``RESTART_SPREAD`` of the restart box, even ones from all of
it (starts near mid-range converge more often; the full box keeps the draws diverse). Over
2,000 TRAC-IK targets per arm on six arms of example-robot-data, these two choices (with a
5 % decrease as progress instead of 1 %) cut the mean iterations per solve by 1-13 % and the
most for one target by up to 2.7x (ur5: 602 -> 220).
"""

from __future__ import annotations

import time

import numba
import numpy as np
from numba import njit

from ..core import _kernels as _core_kernels
from ..core._cache import drop_stale_cache
from ..core._kernels import cholesky_into

drop_stale_cache(__file__, [_core_kernels.__file__])

HINGE = 0
SLIDE = 1

# Reasons (codes) returned by igm_solve; names in qpik.converge.REASONS.
CONVERGED = 0
MAX_ITERS = 1
TIME_BUDGET = 2
STALLED = 3
AT_LIMIT = 4
SINGULAR = 5
UNREACHABLE = 6
#: Halvings of a step that increases the error (see igm_solve).
BACKTRACKS = 3
#: An attempt progresses when its score falls below this fraction of the score at the
#: start of its stall window.
PROGRESS = 0.95
#: Iterations between two reads of the clock (a read costs about 1.2 us, a quarter of an
#: iteration: it leaves the compiled code for Python's time.perf_counter).
CLOCK_EVERY = 8
#: Every other restart draws from this fraction of the restart box, around its center.
RESTART_SPREAD = 0.6
REASON_NAMES = (
    "converged",
    "max_iters",
    "time_budget",
    "stalled",
    "at_limit",
    "singular",
    "unreachable",
)

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)


# ------------------------------------------------------------------ kinematics
@njit(cache=True)
def _axis_rotation(axis, angle, out):
    """Rotation matrix of ``angle`` [rad] about unit ``axis`` (Rodrigues), into ``out``."""
    x, y, z = axis[0], axis[1], axis[2]
    c = np.cos(angle)
    s = np.sin(angle)
    t = 1.0 - c
    out[0, 0] = t * x * x + c
    out[0, 1] = t * x * y - s * z
    out[0, 2] = t * x * z + s * y
    out[1, 0] = t * x * y + s * z
    out[1, 1] = t * y * y + c
    out[1, 2] = t * y * z - s * x
    out[2, 0] = t * x * z - s * y
    out[2, 1] = t * y * z + s * x
    out[2, 2] = t * z * z + c


@njit(cache=True)
def quat2mat(quat):
    """Rotation matrices (k, 3, 3) of unit quaternions (k, 4) ``(w, x, y, z)``."""
    out = np.empty((quat.shape[0], 3, 3))
    for k in range(quat.shape[0]):
        w, x, y, z = quat[k, 0], quat[k, 1], quat[k, 2], quat[k, 3]
        out[k, 0, 0] = w * w + x * x - y * y - z * z
        out[k, 1, 1] = w * w - x * x + y * y - z * z
        out[k, 2, 2] = w * w - x * x - y * y + z * z
        out[k, 0, 1] = 2 * (x * y - w * z)
        out[k, 0, 2] = 2 * (x * z + w * y)
        out[k, 1, 0] = 2 * (x * y + w * z)
        out[k, 1, 2] = 2 * (y * z - w * x)
        out[k, 2, 0] = 2 * (x * z - w * y)
        out[k, 2, 1] = 2 * (y * z + w * x)
    return out


@njit(cache=True)
def _matmul3(A, B, out):
    for i in range(3):
        a0, a1, a2 = A[i, 0], A[i, 1], A[i, 2]
        for j in range(3):
            out[i, j] = a0 * B[0, j] + a1 * B[1, j] + a2 * B[2, j]


@njit(cache=True)
def _copy3(src, dst):
    for i in range(3):
        for j in range(3):
            dst[i, j] = src[i, j]


# Complexity 11: MuJoCo's kinematics per body and per joint type (hinge, slide), as in
# mj_kinematics; splitting it would pass the running pose around by value.
@njit(cache=True)
def _walk(chain, q, axes, anchors, position, rotation, scratch):
    """Walk the chain (the tuple of :class:`qpik.model.KinematicChain`) at ``q``: world
    axes and anchors of its joints (nj, 3) and the frame's pose (``position`` (3,) [m],
    ``rotation`` (3, 3)). ``scratch``: (4, 3, 3), overwritten."""
    body_pos, body_rot, jnt_start, jnt_type, jnt_axis, jnt_pos = chain[:6]
    jnt_qadr, jnt_qpos0, frame_pos, frame_rot = chain[6], chain[8], chain[9], chain[10]
    R, tmp, rot, p = scratch[0], scratch[1], scratch[2], scratch[3, 0]
    for i in range(3):
        p[i] = 0.0
        for j in range(3):
            R[i, j] = 1.0 if i == j else 0.0
    for b in range(body_pos.shape[0]):
        for i in range(3):
            p[i] += R[i, 0] * body_pos[b, 0] + R[i, 1] * body_pos[b, 1] + R[i, 2] * body_pos[b, 2]
        _matmul3(R, body_rot[b], tmp)
        _copy3(tmp, R)
        for j in range(jnt_start[b], jnt_start[b + 1]):
            for i in range(3):
                axes[j, i] = (
                    R[i, 0] * jnt_axis[j, 0] + R[i, 1] * jnt_axis[j, 1] + R[i, 2] * jnt_axis[j, 2]
                )
                anchors[j, i] = (
                    p[i]
                    + R[i, 0] * jnt_pos[j, 0]
                    + R[i, 1] * jnt_pos[j, 1]
                    + R[i, 2] * jnt_pos[j, 2]
                )
            value = q[jnt_qadr[j]] - jnt_qpos0[j]
            if jnt_type[j] == HINGE:
                _axis_rotation(jnt_axis[j], value, rot)
                _matmul3(R, rot, tmp)
                _copy3(tmp, R)
                for i in range(3):
                    p[i] = anchors[j, i] - (
                        R[i, 0] * jnt_pos[j, 0] + R[i, 1] * jnt_pos[j, 1] + R[i, 2] * jnt_pos[j, 2]
                    )
            else:
                for i in range(3):
                    p[i] += axes[j, i] * value
    for i in range(3):
        position[i] = (
            p[i] + R[i, 0] * frame_pos[0] + R[i, 1] * frame_pos[1] + R[i, 2] * frame_pos[2]
        )
    _matmul3(R, frame_rot, rotation)


@njit(cache=True, inline="always")
def _fk_jac(chain, q, axes, anchors, position, rotation, jac, want_jac, scratch):
    """:func:`fk_jac` with the scratch ``axes``, ``anchors`` (nj, 3) and ``scratch``
    (4, 3, 3) given."""
    _walk(chain, q, axes, anchors, position, rotation, scratch)
    if not want_jac:
        return
    jnt_type, jnt_dadr = chain[3], chain[7]
    for i in range(6):
        for j in range(jac.shape[1]):
            jac[i, j] = 0.0
    for j in range(jnt_type.shape[0]):
        d = jnt_dadr[j]
        u0, u1, u2 = axes[j, 0], axes[j, 1], axes[j, 2]
        if jnt_type[j] == HINGE:
            r0 = position[0] - anchors[j, 0]
            r1 = position[1] - anchors[j, 1]
            r2 = position[2] - anchors[j, 2]
            jac[0, d] += u1 * r2 - u2 * r1
            jac[1, d] += u2 * r0 - u0 * r2
            jac[2, d] += u0 * r1 - u1 * r0
            jac[3, d] += u0
            jac[4, d] += u1
            jac[5, d] += u2
        else:
            jac[0, d] += u0
            jac[1, d] += u1
            jac[2, d] += u2


@njit(cache=True)
def fk_jac(chain, q, position, rotation, jac, want_jac):
    """Pose of the chain's frame at ``q`` (world frame: ``position`` (3,) [m], ``rotation``
    (3, 3)) and, if ``want_jac``, its world-aligned Jacobian ``jac`` (6, nv) ``[v; omega]``
    (columns of dofs off the chain are zero). ``chain``: the tuple of
    :class:`qpik.model.KinematicChain`."""
    nj = chain[3].shape[0]
    axes, anchors, scratch = np.empty((nj, 3)), np.empty((nj, 3)), np.empty((4, 3, 3))
    _fk_jac(chain, q, axes, anchors, position, rotation, jac, want_jac, scratch)


@njit(cache=True)
def _dot3(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True)
def _dist3(a, b):
    return np.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)


@njit(cache=True)
def _feet(a1, u1, a2, u2, s, r):
    """Closest points ``s`` on ``a1 + t u1`` and ``r`` on ``a2 + t u2`` (unit directions);
    for parallel lines, ``a1`` and its projection on the second line."""
    w = np.empty(3)
    for i in range(3):
        w[i] = a1[i] - a2[i]
    b = _dot3(u1, u2)
    d = _dot3(u1, w)
    e = _dot3(u2, w)
    den = 1.0 - b * b
    if den < 1e-12:
        t1, t2 = 0.0, e
    else:
        t1, t2 = (b * e - d) / den, (e - b * d) / den
    for i in range(3):
        s[i] = a1[i] + t1 * u1[i]
        r[i] = a2[i] + t2 * u2[i]


# Complexity 13: one pass over the hinges, each either paired with the next hinge (the
# common perpendicular's feet) or, the last one, with the frame; the first sets the centre.
@njit(cache=True)
def reach_radius(chain, q, center):
    """Length of the path ``s_1 -> r_2 -> s_2 -> ... -> s_m -> frame`` through the feet of
    the common perpendiculars of consecutive hinge axes at ``q`` (each segment is fixed in
    one body, so the length holds at every ``q``); ``center`` receives ``s_1``. Without a
    hinge, the frame position at ``q`` and 0."""
    jnt_type = chain[3]
    nj = jnt_type.shape[0]
    axes = np.empty((nj, 3))
    anchors = np.empty((nj, 3))
    p = np.empty(3)
    _walk(chain, q, axes, anchors, p, np.empty((3, 3)), np.empty((4, 3, 3)))
    s = np.empty(3)
    r = np.empty(3)
    previous = np.empty(3)
    first = True
    length = 0.0
    for i in range(3):
        center[i] = p[i]
    for j in range(nj):
        if jnt_type[j] != HINGE:
            continue
        nxt = -1
        for k in range(j + 1, nj):
            if jnt_type[k] == HINGE:
                nxt = k
                break
        if nxt >= 0:
            _feet(anchors[j], axes[j], anchors[nxt], axes[nxt], s, r)
        else:
            w = np.empty(3)
            for i in range(3):
                w[i] = p[i] - anchors[j, i]
            t = _dot3(axes[j], w)
            for i in range(3):
                s[i] = anchors[j, i] + axes[j, i] * t
        if first:
            for i in range(3):
                center[i] = s[i]
            first = False
        else:
            length += _dist3(s, previous)
        if nxt >= 0:
            length += _dist3(r, s)
            for i in range(3):
                previous[i] = r[i]
        else:
            length += _dist3(p, s)
    return length


# ------------------------------------------------------------------- rotations
@njit(cache=True)
def rotation_log(R, out):
    """Rotation vector (axis * angle [rad]) of rotation matrix ``R`` into ``out``; returns
    the angle. Accurate near 0 (``atan2`` of the skew part) and near pi (axis from the
    symmetric part)."""
    v0 = 0.5 * (R[2, 1] - R[1, 2])
    v1 = 0.5 * (R[0, 2] - R[2, 0])
    v2 = 0.5 * (R[1, 0] - R[0, 1])
    s = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    c = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    theta = np.arctan2(s, c)
    if c > -0.9:
        if s < 1e-300:
            out[0] = 0.0
            out[1] = 0.0
            out[2] = 0.0
            return 0.0
        k = theta / s
        out[0] = k * v0
        out[1] = k * v1
        out[2] = k * v2
        return theta
    # Near pi: R + R^T = 2 c I + 2 (1 - c) u u^T.
    best = 0
    for i in range(1, 3):
        if R[i, i] > R[best, best]:
            best = i
    u = np.empty(3)
    for i in range(3):
        u[i] = 0.5 * (R[i, best] + R[best, i])
    u[best] -= c
    norm = np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
    for i in range(3):
        u[i] /= norm
    if u[0] * v0 + u[1] * v1 + u[2] * v2 < 0.0:
        for i in range(3):
            u[i] = -u[i]
    for i in range(3):
        out[i] = theta * u[i]
    return theta


@njit(cache=True)
def rotation_defect(R):
    """``max |R R^T - I|`` of a 3x3 matrix, or inf when an entry is not finite or
    ``det R <= 0`` (one cheap check of a rotation target)."""
    for i in range(3):
        for j in range(3):
            if not np.isfinite(R[i, j]):
                return np.inf
    det = (
        R[0, 0] * (R[1, 1] * R[2, 2] - R[1, 2] * R[2, 1])
        - R[0, 1] * (R[1, 0] * R[2, 2] - R[1, 2] * R[2, 0])
        + R[0, 2] * (R[1, 0] * R[2, 1] - R[1, 1] * R[2, 0])
    )
    if not det > 0.0:
        return np.inf
    worst = 0.0
    for i in range(3):
        for j in range(3):
            s = R[i, 0] * R[j, 0] + R[i, 1] * R[j, 1] + R[i, 2] * R[j, 2]
            if i == j:
                s -= 1.0
            worst = max(worst, abs(s))
    return worst


@njit(cache=True)
def target_defect(position, rotation, has_rot):
    """0 for a valid target; 1: the position is not finite; 2: the rotation is not finite;
    3: the rotation is not a rotation (``|R R^T - I| > 1e-6`` or ``det R <= 0``)."""
    for i in range(3):
        if not np.isfinite(position[i]):
            return 1
    if has_rot:
        defect = rotation_defect(rotation)
        if not defect <= 1e-6:
            for i in range(3):
                for j in range(3):
                    if not np.isfinite(rotation[i, j]):
                        return 2
            return 3
    return 0


@njit(cache=True)
def left_jacobian_inverse(phi, out):
    """Inverse left Jacobian of SO(3) at rotation vector ``phi``: ``d log(R) = Jl^-1 omega``
    for a world perturbation ``dR = [omega] R``."""
    theta = np.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    S = np.zeros((3, 3))
    S[0, 1] = -phi[2]
    S[0, 2] = phi[1]
    S[1, 0] = phi[2]
    S[1, 2] = -phi[0]
    S[2, 0] = -phi[1]
    S[2, 1] = phi[0]
    if theta < 1e-6:
        k = 1.0 / 12.0
    else:
        k = 1.0 / (theta * theta) - (1.0 + np.cos(theta)) / (2.0 * theta * np.sin(theta))
    for i in range(3):
        for j in range(3):
            s2 = S[i, 0] * S[0, j] + S[i, 1] * S[1, j] + S[i, 2] * S[2, j]
            out[i, j] = -0.5 * S[i, j] + k * s2
        out[i, i] += 1.0


# --------------------------------------------------------------------- box QP
@njit(cache=True)
def _cholesky_solve_subset(H, rhs, free, nfree, L, x, y):
    """Solve ``H[F, F] x_F = rhs_F`` by Cholesky (F: the first ``nfree`` of ``free``;
    scratch ``L`` (n, n), ``y`` (n,)); returns False if ``H[F, F]`` is not positive
    definite."""
    for a in range(nfree):
        i = free[a]
        for b in range(a + 1):
            j = free[b]
            s = H[i, j]
            for k in range(b):
                s -= L[a, k] * L[b, k]
            if a == b:
                if not s > 0.0:
                    return False
                L[a, a] = np.sqrt(s)
            else:
                L[a, b] = s / L[b, b]
    for a in range(nfree):
        s = rhs[free[a]]
        for k in range(a):
            s -= L[a, k] * y[k]
        y[a] = s / L[a, a]
    for a in range(nfree - 1, -1, -1):
        s = y[a]
        for k in range(a + 1, nfree):
            s -= L[k, a] * x[free[k]]
        x[free[a]] = s / L[a, a]
    return True


@njit(cache=True)
def box_qp(H, g, lb, ub, x, max_iter):
    """``min 1/2 x^T H x + g^T x  s.t.  lb <= x <= ub`` (H positive definite), exactly, by
    a primal active-set method from the feasible point ``clip(0, lb, ub)``.

    The working set grows by the blocking bound of each ratio test and shrinks by the bound
    with the most negative multiplier (lowest index on ties: Bland's rule against cycling),
    up to ``max_iter`` changes. Writes the minimiser into ``x``; returns ``(status,
    iterations)``: status 0 solved, 1 iteration cap (``x`` feasible, not optimal), 2 ``H``
    not positive definite. One function, so that another exact QP kernel can replace it.
    """
    n = H.shape[0]
    return _box_qp(H, g, lb, ub, x, max_iter, _box_qp_workspace(n))


@njit(cache=True)
def _box_qp_workspace(n):
    """Scratch of :func:`_box_qp` for ``n`` variables."""
    return (
        np.empty(n, dtype=np.int8),
        np.empty(n, dtype=np.int64),
        np.empty((n, n)),
        np.empty(n),
        np.empty(n),
        np.empty(n),
    )


@njit(cache=True)
def _free_rhs(H, g, x, state, free, target, rhs):
    """The free variables (indices into ``free``, their count returned) and the right-hand
    side ``-g - H_fb x_b`` of their minimiser with the others held at their bounds (whose
    ``target`` is their current value)."""
    n = H.shape[0]
    nfree = 0
    for i in range(n):
        if state[i] == 0:
            free[nfree] = i
            nfree += 1
        else:
            target[i] = x[i]
    for a in range(nfree):
        i = free[a]
        s = -g[i]
        for j in range(n):
            if state[j] != 0:
                s -= H[i, j] * x[j]
        rhs[i] = s
    return nfree


@njit(cache=True)
def _ratio_test(x, target, lb, ub, free, nfree):
    """The longest step in ``[0, 1]`` from ``x`` toward ``target`` that keeps the free
    variables in their bounds, and the variable that blocks it (``-1``: none) with its
    side (-1 lower, +1 upper)."""
    step = 1.0
    block = -1
    block_side = 0
    for a in range(nfree):
        i = free[a]
        d = target[i] - x[i]
        if d < 0.0 and target[i] < lb[i]:
            t = (lb[i] - x[i]) / d
            if t < step:
                step, block, block_side = t, i, -1
        elif d > 0.0 and target[i] > ub[i]:
            t = (ub[i] - x[i]) / d
            if t < step:
                step, block, block_side = t, i, 1
    return max(step, 0.0), block, block_side


@njit(cache=True)
def _most_negative_multiplier(H, g, x, state):
    """The held bound whose multiplier is the most negative (it should be released), or
    -1 when every multiplier is >= 0 (the working set is optimal)."""
    n = H.shape[0]
    worst = 0.0
    release = -1
    for i in range(n):
        if state[i] == 0:
            continue
        grad = g[i]
        for j in range(n):
            grad += H[i, j] * x[j]
        multiplier = grad if state[i] < 0 else -grad  # >= 0 at the optimum
        if multiplier < worst - 1e-14 * (1.0 + abs(grad)):
            worst = multiplier
            release = i
    return release


@njit(cache=True)
def _box_qp(H, g, lb, ub, x, max_iter, workspace):
    """:func:`box_qp` with its scratch (:func:`_box_qp_workspace`) given: a primal
    active-set method over the bounds. Returns ``(code, iterations)``: 0 solved, 1 the
    cap, 2 a singular free block."""
    n = H.shape[0]
    state, free, L, target, rhs, y = workspace
    for i in range(n):
        state[i] = 0  # 0 free, -1 at lower, +1 at upper
        x[i] = min(max(0.0, lb[i]), ub[i])
    for iteration in range(max_iter):
        nfree = _free_rhs(H, g, x, state, free, target, rhs)
        if nfree > 0 and not _cholesky_solve_subset(H, rhs, free, nfree, L, target, y):
            return 2, iteration
        step, block, block_side = _ratio_test(x, target, lb, ub, free, nfree)
        for a in range(nfree):
            i = free[a]
            x[i] += step * (target[i] - x[i])
        if block >= 0:  # a bound blocks the step: hold it and solve again
            x[block] = lb[block] if block_side < 0 else ub[block]
            state[block] = block_side
            continue
        release = _most_negative_multiplier(H, g, x, state)
        if release < 0:
            return 0, iteration + 1
        state[release] = 0
    return 1, max_iter


# ----------------------------------------------------------------------- RNG
@njit(cache=True)
def uniform(state):
    """A uniform draw in [0, 1) from the SplitMix64 stream ``state`` (uint64 (1,),
    advanced in place)."""
    state[0] += _GOLDEN
    z = state[0]
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    z = z ^ (z >> np.uint64(31))
    return float(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def _now():
    with numba.objmode(t="float64"):
        t = time.perf_counter()
    return t


# ------------------------------------------------------------------------ IGM
@njit(cache=True, inline="always")
def _pose_error(position, rotation, target_p, target_R, has_rot, error, rot_err, M):
    """Error ``[p - p_t; log(R R_t^T)]`` into ``error`` (``M`` (3, 3): scratch); returns
    (position error [m], orientation error [rad])."""
    for i in range(3):
        error[i] = position[i] - target_p[i]
    ep = np.sqrt(error[0] ** 2 + error[1] ** 2 + error[2] ** 2)
    if not has_rot:
        return ep, 0.0
    for i in range(3):
        for j in range(3):
            M[i, j] = (
                rotation[i, 0] * target_R[j, 0]
                + rotation[i, 1] * target_R[j, 1]
                + rotation[i, 2] * target_R[j, 2]
            )
    eo = rotation_log(M, rot_err)
    for i in range(3):
        error[3 + i] = rot_err[i]
    return ep, eo


# Complexity 12: cyclic Jacobi sweeps with their convergence test, on a small symmetric
# matrix (no LAPACK call from compiled code).
@njit(cache=True)
def _smallest_eigenvalue(G, n):
    """Smallest eigenvalue of the symmetric ``G[:n, :n]`` (cyclic Jacobi; ``G`` is
    overwritten)."""
    for _sweep in range(50):
        off = 0.0
        diag = 0.0
        for i in range(n):
            diag += G[i, i] * G[i, i]
            for j in range(i + 1, n):
                off += G[i, j] * G[i, j]
        if off <= 1e-30 * diag or off == 0.0:
            break
        for p in range(n - 1):
            for q in range(p + 1, n):
                if G[p, q] == 0.0:
                    continue
                theta = (G[q, q] - G[p, p]) / (2.0 * G[p, q])
                t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + np.sqrt(theta * theta + 1.0))
                c = 1.0 / np.sqrt(t * t + 1.0)
                s = t * c
                for k in range(n):
                    gkp = G[k, p]
                    gkq = G[k, q]
                    G[k, p] = c * gkp - s * gkq
                    G[k, q] = s * gkp + c * gkq
                for k in range(n):
                    gpk = G[p, k]
                    gqk = G[q, k]
                    G[p, k] = c * gpk - s * gqk
                    G[q, k] = s * gpk + c * gqk
    smallest = G[0, 0]
    for i in range(1, n):
        if G[i, i] < smallest:
            smallest = G[i, i]
    return smallest


@njit(cache=True)
def _smallest_singular_value(A, m, nv, G, threshold=0.0):
    """:func:`_smallest_singular_value_in` with its scratch allocated."""
    n = max(6, nv)
    return _smallest_singular_value_in(
        A, m, nv, G, threshold, np.empty(m, dtype=np.int64), np.empty((n, n))
    )


@njit(cache=True)
def _smallest_singular_value_in(A, m, nv, G, threshold, rows, L):
    """The ``min(r, nv)``-th singular value of ``A[:m]``, ``r`` its rows that are not
    identically zero (a planar arm's out-of-plane row is a structural zero, not a
    singularity), from the smaller Gram matrix built in the scratch ``G``. With
    ``threshold > 0`` it returns inf when that value is at least ``threshold``: one Cholesky
    factorisation of ``G - threshold^2 I`` decides, so that away from singularities no
    eigenvalue is computed. Scratch: ``rows`` (m,) int64, ``L`` like ``G``."""
    r = 0
    for i in range(m):
        for k in range(nv):
            if A[i, k] != 0.0:
                rows[r] = i
                r += 1
                break
    if r == 0:
        return np.inf
    # The smaller Gram matrix: B B^T (r x r) or B^T B (nv x nv), B = A[rows].
    by_rows = r <= nv
    n, inner = (r, nv) if by_rows else (nv, r)
    for a in range(n):
        for c in range(a, n):
            s = 0.0
            for k in range(inner):
                if by_rows:
                    s += A[rows[a], k] * A[rows[c], k]
                else:
                    s += A[rows[k], a] * A[rows[k], c]
            G[a, c] = s
            G[c, a] = s
    if threshold > 0.0 and _positive_definite_shifted(G, n, threshold * threshold, L):
        return np.inf
    return np.sqrt(max(_smallest_eigenvalue(G, n), 0.0))


@njit(cache=True)
def _positive_definite_shifted(G, n, shift, L):
    """Whether ``G[:n, :n] - shift I`` is positive definite (Cholesky into the scratch
    ``L``; ``G`` unchanged)."""
    return cholesky_into(G, n, shift, L)


@njit(cache=True, inline="always")
def _evaluate(chain, q, target_p, target_R, has_rot, work):
    """Forward kinematics, Jacobian and pose error at ``q`` into ``work``
    (:func:`_workspaces`); returns (position error [m], orientation error [rad])."""
    axes, anchors, position, rotation, jac, error, rot_err, M, scratch = work
    _fk_jac(chain, q, axes, anchors, position, rotation, jac, True, scratch)
    return _pose_error(position, rotation, target_p, target_R, has_rot, error, rot_err, M)


@njit(cache=True)
def _record(path, hist, slot, index, q, ep, eo):
    """Iterate ``index`` of attempt slot ``slot``: ``q`` and its errors."""
    path[slot, index] = q
    hist[slot, index, 0] = ep
    hist[slot, index, 1] = eo


@njit(cache=True)
def _stall_reason(active, sigma, threshold):
    """Why an attempt stopped progressing: a binding joint limit, else a singularity
    (the level's smallest singular value below the damping threshold), else stalled."""
    if active:
        return AT_LIMIT
    return SINGULAR if sigma < threshold else STALLED


@njit(cache=True)
def _target_level(jac, cols, error, rot_err, has_rot, gain, A, b, Jinv):
    """The target level ``A dx = b`` over the chain's dofs ``cols``: ``A = [J_v; Jl^-1
    J_w]`` (columns ``cols`` of the Jacobian), ``b = -gain e``."""
    nc = cols.shape[0]
    for i in range(3):
        for c in range(nc):
            A[i, c] = jac[i, cols[c]]
        b[i] = -gain * error[i]
    if has_rot:
        left_jacobian_inverse(rot_err, Jinv)
        for i in range(3):
            for c in range(nc):
                j = cols[c]
                A[3 + i, c] = (
                    Jinv[i, 0] * jac[3, j] + Jinv[i, 1] * jac[4, j] + Jinv[i, 2] * jac[5, j]
                )
            b[3 + i] = -gain * error[3 + i]


@njit(cache=True)
def _regularisation(A, b, m, gram, options, rows, L):
    """``(damping + lambda^2, sigma)``: the adaptive damping of the level (the damping law:
    ``lambda^2 = max_damping^2 (1 - (sigma / threshold)^2)`` below the threshold, faded by
    ``|b| / error_scale``) and its smallest singular value (inf when not computed)."""
    threshold, max_damping, error_scale, reg = options[6], options[7], options[8], options[9]
    if not threshold > 0.0:
        return reg, np.inf
    sigma = _smallest_singular_value_in(A, m, A.shape[1], gram, threshold, rows, L)
    if sigma < threshold:
        ratio = sigma / threshold
        lam2 = max_damping * max_damping * (1.0 - ratio * ratio)
        if error_scale > 0.0:
            bnorm = 0.0
            for i in range(m):
                bnorm += b[i] * b[i]
            bnorm = np.sqrt(bnorm)
            lam2 *= min(1.0, bnorm / error_scale)
        reg += lam2
    return reg, sigma


@njit(cache=True)
def _box_problem(A, b, m, reg, q, cols, lower, upper, limit_gain, H, g, lb, ub):
    """The damped least-squares QP of the level, ``H = A^T A + reg I``, ``g = -A^T b``,
    under the box ``limit_gain (limits - q)`` of the dofs ``cols`` (it always holds 0)."""
    nc = A.shape[1]
    for i in range(nc):
        s = 0.0
        for k in range(m):
            s += A[k, i] * b[k]
        g[i] = -s
        for j in range(i, nc):
            s = 0.0
            for k in range(m):
                s += A[k, i] * A[k, j]
            H[i, j] = s
            H[j, i] = s
        H[i, i] += reg
        d = cols[i]
        lb[i] = limit_gain * (lower[d] - q[d])
        ub[i] = limit_gain * (upper[d] - q[d])
        if lb[i] > 0.0:
            lb[i] = 0.0
        if ub[i] < 0.0:
            ub[i] = 0.0


@njit(cache=True)
def _step_facts(A, b, m, dx, cols, lb, ub, lower, upper):
    """``(|A dx - b|, |dx|, whether a limited joint's bound is active)`` of a step."""
    nc = dx.shape[0]
    residual = 0.0
    for k in range(m):
        s = -b[k]
        for j in range(nc):
            s += A[k, j] * dx[j]
        residual += s * s
    step_norm = 0.0
    active = False
    for j in range(nc):
        step_norm += dx[j] * dx[j]
        d = cols[j]
        at_lower = dx[j] <= lb[j] and lower[d] > -np.inf
        if at_lower or (dx[j] >= ub[j] and upper[d] < np.inf):
            active = True
    return np.sqrt(residual), np.sqrt(step_norm), active


@njit(cache=True, inline="always")
def _line_search(chain, target, q, q_base, dx, cols, t, lower, upper, ep, eo, work):
    """``q = clip(q_base + t dx)`` on the dofs ``cols``, halving ``t`` while the error
    ``|e_p|^2 + |e_o|^2`` ([m^2], [rad^2]) does not decrease, up to ``BACKTRACKS`` times
    (near singularities the damped step can overshoot into a limit cycle); returns the
    errors at ``q``."""
    target_p, target_R, has_rot = target
    previous = ep * ep + eo * eo
    for attempt_step in range(BACKTRACKS + 1):
        for c in range(cols.shape[0]):
            j = cols[c]
            q[j] = q_base[j] + t * dx[c]
            if q[j] < lower[j]:
                q[j] = lower[j]
            if q[j] > upper[j]:
                q[j] = upper[j]
        ep, eo = _evaluate(chain, q, target_p, target_R, has_rot, work)
        if ep * ep + eo * eo < previous or attempt_step == BACKTRACKS:
            break
        t *= 0.5
    return ep, eo


@njit(cache=True, inline="always")
def _trust_gain(alpha, ep, eo, has_rot, max_step_p, max_step_o):
    """The target task's gain under the trust region: at most ``alpha``, and small enough
    that one step asks for at most ``max_step_p`` [m] and ``max_step_o`` [rad]."""
    gain = alpha
    if ep > 0.0 and max_step_p / ep < gain:
        gain = max_step_p / ep
    if has_rot and eo > 0.0 and max_step_o / eo < gain:
        gain = max_step_o / eo
    return gain


@njit(cache=True, inline="always")
def _progress(current, window_start, since_progress):
    """The stall window after a score: it restarts on a decrease below ``PROGRESS`` times
    its first score, else counts one more iteration without progress."""
    if current < PROGRESS * window_start:
        return current, 0
    return window_start, since_progress + 1


@njit(cache=True)
def _attempt(chain, target, q, settings, record, work, qp_work, counts):
    """One attempt of the IGM from ``q`` (advanced in place). ``target``: (position,
    rotation, has_rot); ``settings``: (bounds, options, int_options, deadline); ``record``:
    (path, hist, slot), the attempt slot its iterates go to. ``counts`` (int64 (2,)): QP
    solves and capped QP solves, added to. Returns (reason, iterates, score ``e_p / tol_p
    + e_o / tol_o``, out of time)."""
    target_p, target_R, has_rot = target
    bounds, options, int_options, deadline = settings
    path, hist, slot = record
    A, b, Jinv, H, g, lb, ub, dx, q_base, gram, rows, L_sigma, box_work = qp_work
    jac, error, rot_err = work[4], work[5], work[6]
    cols = chain[7]
    lower, upper = bounds[0], bounds[1]
    tol_p, tol_o, alpha, beta = options[0], options[1], options[2], options[3]
    max_step_p, max_step_o, threshold, limit_gain = options[4], options[5], options[6], options[10]
    max_iters, stall_window, check_time = int_options[0], int_options[2], int_options[3]
    m = 6 if has_rot else 3
    ep, eo = _evaluate(chain, q, target_p, target_R, has_rot, work)
    length = np.int64(0)  # not a literal: one compiled _record serves every call
    _record(path, hist, slot, length, q, ep, eo)
    hist[slot, 0, 2] = 0.0
    length += 1
    current = ep / tol_p + eo / tol_o
    window_start = current
    since_progress = 0
    for it in range(max_iters):
        if ep <= tol_p and eo <= tol_o:
            return CONVERGED, length, current, False
        if check_time != 0 and (it % CLOCK_EVERY == 0) and _now() > deadline:
            return TIME_BUDGET, length, current, True
        gain = _trust_gain(alpha, ep, eo, has_rot, max_step_p, max_step_o)
        _target_level(jac, cols, error, rot_err, has_rot, gain, A, b, Jinv)
        reg, sigma = _regularisation(A, b, m, gram, options, rows, L_sigma)
        _box_problem(A, b, m, reg, q, cols, lower, upper, limit_gain, H, g, lb, ub)
        status, _ = _box_qp(H, g, lb, ub, dx, 4 * dx.shape[0] + 20, box_work)
        counts[0] += 1
        if status != 0:
            counts[1] += 1
        residual, step_norm, active = _step_facts(A, b, m, dx, cols, lb, ub, lower, upper)
        hist[slot, it + 1, 2] = residual
        q_base[:] = q
        ep, eo = _line_search(chain, target, q, q_base, dx, cols, beta, lower, upper, ep, eo, work)
        _record(path, hist, slot, length, q, ep, eo)
        length += 1
        current = ep / tol_p + eo / tol_o
        if step_norm < 1e-9:
            return _stall_reason(active, sigma, threshold), length, current, False
        window_start, since_progress = _progress(current, window_start, since_progress)
        if since_progress >= stall_window:
            return _stall_reason(active, sigma, threshold), length, current, False
    if ep <= tol_p and eo <= tol_o:
        return CONVERGED, length, current, False
    return MAX_ITERS, length, current, False


@njit(cache=True)
def _workspaces(nj, nc, nq):
    """Scratch arrays of the IGM for ``nj`` joints on the chain, ``nc`` chain dofs and
    ``nq`` coordinates: the kinematics' (axes, anchors, position, rotation, jac, error,
    rot_err, M, scratch) and the step's (A, b, Jinv, H, g, lb, ub, dx, q_base, gram, rows,
    L, box QP workspace)."""
    work = (
        np.empty((nj, 3)),
        np.empty((nj, 3)),
        np.empty(3),
        np.empty((3, 3)),
        np.empty((6, nq)),
        np.zeros(6),
        np.zeros(3),
        np.empty((3, 3)),
        np.empty((4, 3, 3)),
    )
    size = max(6, nc)
    qp_work = (
        np.empty((6, nc)),
        np.empty(6),
        np.empty((3, 3)),
        np.empty((nc, nc)),
        np.empty(nc),
        np.empty(nc),
        np.empty(nc),
        np.empty(nc),
        np.empty(nq),
        np.empty((size, size)),
        np.empty(6, dtype=np.int64),
        np.empty((size, size)),
        _box_qp_workspace(nc),
    )
    return work, qp_work


@njit(cache=True)
def _beyond_reach(target_p, reach, tol_p):
    """Whether ``target_p`` is farther from the reach ball's center than its radius plus
    ``tol_p`` (with a relative margin for round-off)."""
    d0 = target_p[0] - reach[0]
    d1 = target_p[1] - reach[1]
    d2 = target_p[2] - reach[2]
    return np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) > reach[3] + tol_p + 1e-9 * (1.0 + reach[3])


@njit(cache=True, inline="always")
def _better(done, score, best_done, best_score):
    """Whether an attempt beats the best so far: converged beats not, then the score."""
    return (done and not best_done) or (done == best_done and score < best_score)


@njit(cache=True, inline="always")
def _restart_start(q, sample_lo, sample_hi, attempt, rng_state):
    """The start of restart ``attempt`` (1, 2, ...), drawn into ``q``: odd restarts from
    the central ``RESTART_SPREAD`` of the restart box, even ones from all of it."""
    spread = 1.0 if attempt % 2 == 0 else RESTART_SPREAD
    for j in range(q.shape[0]):
        u = 0.5 + spread * (uniform(rng_state) - 0.5)
        q[j] = sample_lo[j] + (sample_hi[j] - sample_lo[j]) * u


@njit(cache=True)
def igm_solve(
    chain,
    target_p,
    target_R,
    has_rot,
    q0,
    bounds,
    reach,
    options,
    int_options,
    rng_state,
    deadline,
    path,
    hist,
    info,
):
    """The whole IGM solve of one frame target (see :func:`qpik.solve` for the rule).

    Args:
        chain: the tuple of chain arrays (:class:`qpik.model.KinematicChain`).
        target_p (3,), target_R (3, 3): the target in the world frame; ``has_rot``: False
            for a position-only target.
        q0 (nq,): start, within the limits.
        bounds (4, nq): lower and upper joint limits (+-inf where none), then the box that
            random restarts draw from.
        reach (4,): center (3,) [m] and radius [m] of the frame's reach bound; a target
            farther than ``radius + tol_position`` from the center ends the solve at once
            (UNREACHABLE).
        options (float64): tol_position, tol_orientation, alpha, beta, max_step_position,
            max_step_orientation (inf: none), singular_threshold, max_damping,
            error_scale (<= 0: none), damping, limit_gain.
        int_options (int64): max_iters, restarts, stall_window, check_time (0/1).
        rng_state: uint64 (1,) SplitMix64 state, advanced in place.
        deadline: ``time.perf_counter()`` value at which the budget ends (if checked).
        path (2, max_iters + 1, nq), hist (2, max_iters + 1, 3): per attempt slot, the
            iterates and, per iterate, (position error [m], orientation error [rad], QP
            residual of the step that left it).
        info (int64, 6): reason code, total iterations, restarts used, slot of the returned
            attempt (its last iterate is the answer), its number of iterates, QP solves that
            hit the iteration cap.
    """
    restarts, check_time = int_options[1], int_options[3]
    sample_lo, sample_hi = bounds[2], bounds[3]
    nq = q0.shape[0]
    work, qp_work = _workspaces(chain[3].shape[0], chain[7].shape[0], nq)
    target = (target_p, target_R, has_rot)
    settings = (bounds, options, int_options, deadline)
    q = q0.copy()
    counts = np.zeros(2, dtype=np.int64)
    if _beyond_reach(target_p, reach, options[0]):
        ep, eo = _evaluate(chain, q, target_p, target_R, has_rot, work)
        first = np.int64(0)
        _record(path, hist, first, first, q, ep, eo)
        hist[0, 0, 2] = 0.0
        info[:] = 0
        info[0] = UNREACHABLE
        info[4] = 1
        return
    best_score = np.inf
    best_slot = 0
    best_len = 1
    best_reason = MAX_ITERS
    reason = MAX_ITERS
    slot = np.int64(0)
    attempt = 0
    out_of_time = False
    while True:
        reason, length, current, out_of_time = _attempt(
            chain, target, q, settings, (path, hist, slot), work, qp_work, counts
        )
        done = reason == CONVERGED
        if attempt == 0 or _better(done, current, best_reason == CONVERGED, best_score):
            best_score = current
            best_slot = slot
            best_len = length
            best_reason = reason
            slot = 1 - slot
        if done or attempt >= restarts:
            break
        if check_time != 0 and (out_of_time or _now() > deadline):
            out_of_time = True
            break
        attempt += 1
        _restart_start(q, sample_lo, sample_hi, attempt, rng_state)
    final = reason
    if best_reason == CONVERGED:
        final = CONVERGED
    elif out_of_time:
        final = TIME_BUDGET
    info[0] = final
    info[1] = counts[0]
    info[2] = attempt
    info[3] = best_slot
    info[4] = best_len
    info[5] = counts[1]
