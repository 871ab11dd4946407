"""What the Jacobian reveals: rank, null space, singularities, redundancy, self-motion.

The lecture's analysis of ``xi = J(q) qdot`` made executable. ``J`` is ``(m, n)``: ``m``
task rows (equations), ``n`` joint velocities (unknowns). Jacobians of a
:class:`~qpik.Configuration` are world-aligned twists ``[v; omega]``: rows
``vx vy vz`` [m/s per joint unit] then ``wx wy wz`` [rad/s per joint unit].

* Pure functions of a matrix: :func:`singular_values`, :func:`rank`, :func:`null_space`,
  :func:`degree_of_redundancy`, :func:`pseudoinverse`, :func:`damped_pseudoinverse`,
  :func:`manipulability`, :func:`condition_number`, :func:`solution_set`,
  :func:`singularity`, :func:`nullspace_step`.
* Functions of a configuration and a frame: :func:`analyze`, :func:`self_motion`,
  :func:`manipulability_gradient`.
* Secondary criteria for null-space motion: :func:`joint_limit_distance` and its gradient.

Tolerances: ``tol`` is an *absolute* threshold on singular values; a singular value
counts (toward the rank, and is inverted by the pseudoinverse) when it is ``> tol``. The
default ``tol=None`` is numpy's, ``max(m, n) * eps * sigma_max`` (exact rank up to
rounding), floored at the smallest normal float so that no inverse overflows.
:func:`singularity` instead flags configurations *near* a singularity, with the absolute
threshold :data:`SINGULAR_TOL`.

Task rows: wherever ``rows`` is accepted it is ``"pose"`` (all six rows), ``"position"``
(``vx vy vz``), ``"orientation"`` (``wx wy wz``), or a sequence of row names or indices
(``("vx", "vy")`` or ``(0, 1)``), for example to drop the rows a planar robot cannot move.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from typing import Literal

import mujoco
import numpy as np
import numpy.typing as npt
import scipy.linalg

from . import checks
from .configuration import Configuration, FrameType
from .errors import InfeasibleLimits, InvalidArgumentType, InvalidInput
from .model.rotations import orientation_error

__all__ = [
    "ROW_NAMES",
    "SINGULAR_TOL",
    "KinematicReport",
    "SingularityReport",
    "SolutionSet",
    "analyze",
    "condition_number",
    "damped_pseudoinverse",
    "degree_of_redundancy",
    "joint_limit_distance",
    "joint_limit_distance_gradient",
    "manipulability",
    "manipulability_gradient",
    "null_space",
    "nullspace_step",
    "pseudoinverse",
    "rank",
    "self_motion",
    "singular_values",
    "singularity",
    "solution_set",
]

#: Names of the six rows of a frame Jacobian ``[v; omega]`` (world-aligned).
ROW_NAMES: tuple[str, ...] = ("vx", "vy", "vz", "wx", "wy", "wz")

#: Default threshold of :func:`singularity` on the smallest singular value [Jacobian
#: units]: at or below it a configuration is reported as (near) singular. With unit
#: links, the lecture's 2R arm at ``q2 = 0.001`` (``sigma_min ~ 4.5e-4``) is flagged.
SINGULAR_TOL = 1e-3

#: Relative residual below which ``J x = xi`` counts as solved (see :func:`solution_set`).
_RESIDUAL_RTOL = 1e-9

_ROW_SETS = {"pose": (0, 1, 2, 3, 4, 5), "position": (0, 1, 2), "orientation": (3, 4, 5)}

Rows = Literal["pose", "position", "orientation"] | Sequence[int | str]


# ---------------------------------------------------------------------- validation
def _as_matrix(J: npt.ArrayLike, name: str = "J") -> np.ndarray:
    """``J`` as a finite 2-D float array with at least one row and one column."""
    try:
        J = np.asarray(J, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidInput(f"{name} is not a numeric matrix: {exc}") from None
    if J.ndim != 2 or J.shape[0] == 0 or J.shape[1] == 0:
        raise InvalidInput(f"{name} has shape {J.shape}, expected a 2-D (m, n) array, m, n >= 1")
    bad = np.argwhere(~np.isfinite(J))
    if bad.size:
        i, j = (int(k) for k in bad[0])
        raise InvalidInput(f"{name}[{i}, {j}] is {J[i, j]}; every entry must be finite")
    return J


def _as_vector(x: npt.ArrayLike, size: int, name: str) -> np.ndarray:
    """``x`` as a finite float vector of length ``size``."""
    try:
        x = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidInput(f"{name} is not a numeric vector: {exc}") from None
    if x.shape != (size,):
        raise InvalidInput(f"{name} has shape {x.shape}, expected ({size},)")
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        i = int(bad[0])
        raise InvalidInput(f"{name}[{i}] is {x[i]}; every entry must be finite")
    return x


def _as_tol(tol: float | None, s: np.ndarray, shape: tuple[int, int], name: str = "tol") -> float:
    """The absolute singular-value threshold: ``tol``, or numpy's default when None;
    ``name``: the argument, for messages."""
    if tol is None:  # floored at the smallest normal float: 1 / s must not overflow
        s_max = float(s[0]) if s.size else 0.0
        return max(max(shape) * np.finfo(float).eps * s_max, np.finfo(float).tiny)
    if isinstance(tol, (bool, str, bytes)):
        raise InvalidInput(f"{name} is {tol!r}; it must be a finite number >= 0")
    try:
        tol = float(tol)
    except (TypeError, ValueError):
        raise InvalidInput(f"{name} is {tol!r}; it must be a finite number >= 0") from None
    if not np.isfinite(tol) or tol < 0:
        raise InvalidInput(f"{name} is {tol}; it must be a finite number >= 0")
    return tol


def _scale(J: np.ndarray) -> float:
    """The largest ``|J_ij|`` (1 for a zero matrix): SVDs run on ``J / scale``, whose
    entries are at most 1, so that neither huge (1e300) nor tiny (1e-300) entries
    overflow or underflow inside LAPACK."""
    scale = float(np.max(np.abs(J))) if J.size else 0.0
    return scale if scale > 0.0 else 1.0


def _svdvals(J: np.ndarray) -> np.ndarray:
    """Singular values of ``J``, decreasing, computed on the scaled matrix (they are
    ``inf`` only where the true value exceeds the largest float)."""
    scale = _scale(J)
    with np.errstate(over="ignore"):
        return scipy.linalg.svdvals(J / scale) * scale


def _finite_result(value: np.ndarray, what: str) -> np.ndarray:
    """``value`` if finite; else the exact result exceeds the float range: InvalidInput."""
    if not np.all(np.isfinite(value)):
        raise InvalidInput(
            f"{what} overflows the float range (its exact value exceeds 1.8e308): rescale "
            "the inputs (e.g. use other units)"
        )
    return value


def _row_indices(rows: Rows) -> tuple[int, ...]:
    """Row indices into a ``(6, nv)`` frame Jacobian for a ``rows`` argument."""
    if isinstance(rows, str):
        if rows not in _ROW_SETS:
            raise InvalidInput(
                f"unknown rows {rows!r}; expected one of: {', '.join(_ROW_SETS)}, "
                f"or a sequence of row names ({' '.join(ROW_NAMES)}) or indices 0-5"
            )
        return _ROW_SETS[rows]
    if isinstance(rows, bytes) or not isinstance(rows, Iterable):
        raise InvalidArgumentType(
            "rows",
            "'pose', 'position', 'orientation' or a sequence of row names or indices",
            checks.type_name(rows),
        )
    indices = []
    for row in rows:
        if isinstance(row, str) and row in ROW_NAMES:
            indices.append(ROW_NAMES.index(row))
        elif isinstance(row, (int, np.integer)) and not isinstance(row, bool) and 0 <= row < 6:
            indices.append(int(row))
        else:
            raise InvalidInput(
                f"unknown row {row!r}; rows are named {' '.join(ROW_NAMES)} or indexed 0-5"
            )
    if not indices or len(set(indices)) != len(indices):
        raise InvalidInput(f"rows {list(rows)!r} must be non-empty and without repeats")
    return tuple(indices)


# ------------------------------------------------------------ functions of a matrix
def singular_values(J: npt.ArrayLike) -> np.ndarray:
    """The ``min(m, n)`` singular values of ``J``, in decreasing order."""
    return _finite_result(_svdvals(_as_matrix(J)), "a singular value of J")


def rank(J: npt.ArrayLike, tol: float | None = None) -> int:
    """Numerical rank of ``J``: the number of singular values ``> tol``."""
    J = _as_matrix(J)
    s = _svdvals(J)
    return int(np.count_nonzero(s > _as_tol(tol, s, J.shape)))


def null_space(J: npt.ArrayLike, tol: float | None = None) -> np.ndarray:
    """Orthonormal basis ``(n, n - r)`` of the null space N(J): joint velocities that
    produce no task velocity. Its columns are the right singular vectors of the singular
    values ``<= tol`` (and of the ``n - m`` missing ones when ``m < n``)."""
    J = _as_matrix(J)
    s = _svdvals(J)
    tol = _as_tol(tol, s, J.shape)
    if s[0] <= tol:  # every direction is lost (J = 0 up to tol)
        return np.eye(J.shape[1])
    scale = _scale(J)  # the basis is that of J / scale; rcond is relative to s[0]
    return scipy.linalg.null_space(J / scale, rcond=min(1.0, tol / s[0]))


def degree_of_redundancy(J: npt.ArrayLike, tol: float | None = None) -> int:
    """The lecture's degree of redundancy: ``dim N(J) = n - rank(J)``."""
    J = _as_matrix(J)
    return J.shape[1] - rank(J, tol)


def pseudoinverse(J: npt.ArrayLike, tol: float | None = None) -> np.ndarray:
    """Moore-Penrose pseudoinverse ``J^+`` ``(n, m)``; singular values ``<= tol`` are
    treated as zero. ``J^+ xi`` is the least-norm (least-squares) solution of
    ``J qdot = xi``."""
    J = _as_matrix(J)
    tol = _as_tol(tol, _svdvals(J), J.shape)
    scale = _scale(J)  # (J / scale)^+ = scale J^+
    with np.errstate(over="ignore"):
        pinv = scipy.linalg.pinv(J / scale, atol=tol / scale, rtol=0.0) / scale
    return _finite_result(pinv, "the pseudoinverse")


def damped_pseudoinverse(J: npt.ArrayLike, damping: float) -> np.ndarray:
    """Damped least-squares inverse ``J^T (J J^T + damping I)^-1`` ``(n, m)``.

    ``damping`` (> 0) is added to the diagonal, as in mink (it is ``lambda^2`` in the
    notation ``J^T (J J^T + lambda^2 I)^-1``). Each singular value ``s`` of ``J`` maps to
    ``s / (s^2 + damping) <= 1 / (2 sqrt(damping))``, so the result stays bounded at and
    near singularities: ``||J_damped^+||_2 <= 1 / (2 sqrt(damping))`` for every ``J``.
    """
    J = _as_matrix(J)
    damping = checks.check_real("damping", damping)
    if damping <= 0:
        raise InvalidInput(
            f"damping is {damping}; it must be > 0 (use pseudoinverse() for no damping)"
        )
    # V diag(s / (s^2 + damping)) U^T from the SVD of the scaled J: the same matrix as
    # J^T (J J^T + damping I)^-1, without forming J J^T (which overflows for |J| ~ 1e160
    # and loses the small singular values to rounding)
    scale = _scale(J)
    U, s, Vt = scipy.linalg.svd(J / scale, full_matrices=False)
    with np.errstate(over="ignore", divide="ignore"):
        s = s * scale
        gain = np.zeros_like(s)
        positive = s > 0
        gain[positive] = 1.0 / (s[positive] + damping / s[positive])
    return _finite_result((Vt.T * gain) @ U.T, "the damped pseudoinverse")


def manipulability(J: npt.ArrayLike) -> float:
    """Yoshikawa's manipulability ``sqrt(det(J J^T))``: the product of the singular
    values (0 at a singularity, and always 0 when ``m > n``)."""
    J = _as_matrix(J)
    if J.shape[0] > J.shape[1]:
        return 0.0
    s = _svdvals(J)
    if np.any(s == 0.0):
        return 0.0
    log = float(np.sum(np.log(s)))  # in logs: the product of 1e200s would overflow early
    return math.exp(log) if log < 709.78 else float("inf")


def condition_number(J: npt.ArrayLike) -> float:
    """``sigma_max / sigma_min`` over the ``min(m, n)`` singular values; ``inf`` when
    ``sigma_min`` is 0 (or the ratio exceeds the float range). Large near a singularity."""
    J = _as_matrix(J)
    s = scipy.linalg.svdvals(J / _scale(J))  # the ratio does not depend on the scale
    with np.errstate(over="ignore"):
        return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")


# --------------------------------------------------------------- J qdot = xi, cases
@dataclasses.dataclass(frozen=True)
class SolutionSet:
    """The set of solutions of ``J qdot = xi``, as the lecture's case analysis.

    Attributes:
        kind: ``"unique"`` (consistent, ``N(J) = {0}``), ``"infinite"`` (consistent,
            ``dim N(J) > 0``) or ``"none"`` (``xi`` is not in the range of ``J``).
        particular: ``J^+ xi`` ``(n,)``: the least-norm solution; when ``kind`` is
            ``"none"``, the least-norm least-squares solution instead.
        null_basis: Orthonormal basis ``(n, n - rank)`` of N(J): every solution is
            ``particular + null_basis @ zeta``.
        residual: ``||J particular - xi||`` (0 up to rounding unless ``kind == "none"``).
        rank: Numerical rank of ``J``.
    """

    kind: Literal["unique", "infinite", "none"]
    particular: np.ndarray
    null_basis: np.ndarray
    residual: float
    rank: int

    def general(self, zeta: npt.ArrayLike) -> np.ndarray:
        """The general solution ``particular + null_basis @ zeta``, ``zeta`` ``(n - rank,)``."""
        zeta = _as_vector(zeta, self.null_basis.shape[1], "zeta")
        return self.particular + self.null_basis @ zeta


def solution_set(J: npt.ArrayLike, xi: npt.ArrayLike, tol: float | None = None) -> SolutionSet:
    """Solve ``J qdot = xi`` (``J`` ``(m, n)``, ``xi`` ``(m,)``) and classify the solutions.

    ``xi`` counts as reachable when the least-squares residual is at rounding level
    (relative to ``||xi|| + sigma_max ||J^+ xi||``); singular values ``<= tol`` count as 0.
    """
    J = _as_matrix(J)
    xi = _as_vector(xi, J.shape[0], "xi")
    with np.errstate(over="ignore", invalid="ignore"):
        particular = _finite_result(pseudoinverse(J, tol) @ xi, "the solution J^+ xi")
        mismatch = _finite_result(J @ particular - xi, "the residual J J^+ xi - xi")
    residual = float(scipy.linalg.norm(mismatch))  # BLAS nrm2: no overflow in the squares
    basis = null_space(J, tol)
    with np.errstate(over="ignore"):
        scale = scipy.linalg.norm(xi) + singular_values(J)[0] * scipy.linalg.norm(particular)
    kind: Literal["unique", "infinite", "none"]
    if residual > _RESIDUAL_RTOL * scale:
        kind = "none"
    else:
        kind = "infinite" if basis.shape[1] else "unique"
    return SolutionSet(kind, particular, basis, residual, J.shape[1] - basis.shape[1])


def nullspace_step(
    J: npt.ArrayLike, xi: npt.ArrayLike, zeta: npt.ArrayLike, *, tol: float | None = None
) -> np.ndarray:
    """The lecture's general solution ``qdot = J^+ xi + (I - J^+ J) zeta`` ``(n,)``.

    ``zeta`` ``(n,)`` is any joint velocity (for example ``-grad`` of a secondary
    criterion); its projection onto N(J) changes nothing in the task.
    """
    J = _as_matrix(J)
    xi = _as_vector(xi, J.shape[0], "xi")
    zeta = _as_vector(zeta, J.shape[1], "zeta")
    pinv = pseudoinverse(J, tol)
    with np.errstate(over="ignore", invalid="ignore"):
        step = pinv @ xi + zeta - pinv @ (J @ zeta)
    return _finite_result(step, "the null-space step")


@dataclasses.dataclass(frozen=True)
class SingularityReport:
    """How close ``J`` is to a singularity, and what is lost there.

    Attributes:
        sigma_min: Smallest of the ``m`` task-space singular values (0 when ``m > n``).
        singular: ``sigma_min <= tol``: at or near a singular configuration.
        tol: The threshold used.
        rank: Number of singular values ``> tol``.
        lost_directions: ``(m, k)`` orthonormal task-space directions (left singular
            vectors of the singular values ``<= tol``): twists the robot cannot produce.
        null_motions: ``(n, n - rank)`` orthonormal joint motions that produce no task
            velocity (up to ``tol``).
    """

    sigma_min: float
    singular: bool
    tol: float
    rank: int
    lost_directions: np.ndarray
    null_motions: np.ndarray


def singularity(J: npt.ArrayLike, tol: float = SINGULAR_TOL) -> SingularityReport:
    """Singularity analysis of ``J`` with an absolute threshold ``tol`` on singular values."""
    J = _as_matrix(J)
    tol = _as_tol(tol, np.zeros(0), J.shape)
    m = J.shape[0]
    scale = _scale(J)
    U, s, _ = scipy.linalg.svd(J / scale)
    with np.errstate(over="ignore"):
        s = _finite_result(s * scale, "a singular value of J")
    task_s = np.zeros(m)
    task_s[: s.size] = s  # m > n: the m - n missing singular values are 0
    lost = U[:, task_s <= tol]
    return SingularityReport(
        sigma_min=float(task_s[-1]),
        singular=bool(task_s[-1] <= tol),
        tol=tol,
        rank=int(np.count_nonzero(s > tol)),
        lost_directions=lost,
        null_motions=null_space(J, tol),
    )


# ------------------------------------------------------------ secondary criteria
def _limits(
    q: npt.ArrayLike, lower: npt.ArrayLike, upper: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(q - mid) / range`` terms' ingredients: ``q``, mid-range, range (0 = unlimited)."""
    q = checks.check_vector("q", q)
    lower = checks.check_vector("lower", lower, finite=False)
    upper = checks.check_vector("upper", upper, finite=False)
    for name, bound in (("lower", lower), ("upper", upper)):
        if bound.shape != q.shape:
            raise InvalidInput(f"{name} has shape {bound.shape}, expected {q.shape} like q")
        if np.isnan(bound).any():
            raise InvalidInput(f"{name}[{int(np.flatnonzero(np.isnan(bound))[0])}] is nan")
    bad = np.flatnonzero(lower > upper)
    if bad.size:
        i = int(bad[0])
        raise InfeasibleLimits(f"lower[{i}] = {lower[i]} > upper[{i}] = {upper[i]}")
    limited = np.isfinite(lower) & np.isfinite(upper) & (upper > lower)
    lo = np.where(limited, lower, 0.0)
    hi = np.where(limited, upper, 0.0)
    # halves first: (hi - lo) and (lo + hi) overflow for limits near +-1.8e308
    return q, 0.5 * lo + 0.5 * hi, 0.5 * hi - 0.5 * lo


def _ratio(q: np.ndarray, mid: np.ndarray, half: np.ndarray) -> np.ndarray:
    """``(q - mid) / (2 half)`` (0 for unlimited joints), without intermediate overflow."""
    ratio = np.zeros_like(q)
    limited = half > 0
    with np.errstate(over="ignore", invalid="ignore"):
        ratio[limited] = 0.5 * (q[limited] / half[limited] - mid[limited] / half[limited])
    return _finite_result(ratio, "(q - mid-range) / range")


def joint_limit_distance(q: npt.ArrayLike, lower: npt.ArrayLike, upper: npt.ArrayLike) -> float:
    """Normalised distance from the joint mid-ranges (Liegeois 1977; Siciliano et al.,
    *Robotics*, eq. 3.57):

        w(q) = 1 / (2 n) * sum_i ((q_i - qbar_i) / (q_max_i - q_min_i))^2,

    with ``qbar_i`` the mid-range and ``n = len(q)``. It is 0 with every joint at its
    mid-range and ``1/8`` with every joint at a limit: *minimise* it (null-space velocity
    ``zeta = -k grad w``) to stay away from the limits (Siciliano maximises ``-w``).
    Joints without two finite, distinct limits contribute 0. ``q``, ``lower``, ``upper``
    are ``(n,)`` [rad or m]; ``w`` is dimensionless.
    """
    q, mid, half = _limits(q, lower, upper)
    if q.size == 0:
        return 0.0
    ratio = _ratio(q, mid, half)
    with np.errstate(over="ignore"):
        w = np.sum(ratio**2) / (2 * q.size)
    return float(_finite_result(np.asarray(w), "the joint-limit distance"))


def joint_limit_distance_gradient(
    q: npt.ArrayLike, lower: npt.ArrayLike, upper: npt.ArrayLike
) -> np.ndarray:
    """Gradient ``(n,)`` [1/rad or 1/m] of :func:`joint_limit_distance` w.r.t. ``q``:
    ``(q_i - qbar_i) / (n (q_max_i - q_min_i)^2)``, 0 for unlimited joints."""
    q, mid, half = _limits(q, lower, upper)
    ratio = _ratio(q, mid, half)
    gradient = np.zeros_like(q)
    limited = half > 0
    with np.errstate(over="ignore"):  # ratio / (n span) = ratio / (2 n half)
        gradient[limited] = ratio[limited] / (2 * q.size) / half[limited]
    return _finite_result(gradient, "the joint-limit distance gradient")


# ------------------------------------------------------- functions of a configuration
def _frame_point(
    configuration: Configuration, data: mujoco.MjData, frame: str | int, frame_type: FrameType
) -> tuple[np.ndarray, int]:
    """World position of the frame origin in ``data`` and the body it moves with."""
    fid = configuration.frame_id(frame, frame_type)
    model = configuration.model
    if frame_type is FrameType.SITE:
        return data.site_xpos[fid].copy(), int(model.site_bodyid[fid])
    if frame_type is FrameType.GEOM:
        return data.geom_xpos[fid].copy(), int(model.geom_bodyid[fid])
    return data.xpos[fid].copy(), fid


def _check_configuration(configuration: Configuration) -> None:
    """A :class:`qpik.Configuration`, else :class:`InvalidArgumentType` (a TypeError)."""
    checks.check_instance(
        "configuration",
        configuration,
        Configuration,
        "a qpik.Configuration (build one with qpik.Configuration(qpik.load_robot(name), q))",
    )


def manipulability_gradient(
    configuration: Configuration,
    frame: str | int,
    frame_type: FrameType | str = "site",
    rows: Rows = "pose",
) -> np.ndarray:
    """Gradient ``(nv,)`` of the manipulability ``sqrt(det J J^T)`` of a frame's Jacobian
    (the chosen ``rows``) w.r.t. the configuration (tangent space: ``q`` for hinges and
    slides).

    Analytic: with ``J = U S V^T``, ``dw/dq_k = sum_i (prod_{j != i} s_j) u_i^T (dJ/dq_k)
    v_i``, where ``dJ/dq_k`` is MuJoCo's ``mj_jacDot`` at joint velocity ``e_k``. This
    equals ``w tr(J^+ dJ/dq_k)`` away from singularities and stays finite at a
    singularity of rank ``m - 1`` (where ``w`` has a kink; one one-sided derivative is
    returned). Zero when ``m > n`` (``w`` is then identically 0). The caller's
    configuration is not changed.
    """
    _check_configuration(configuration)
    kind = FrameType.parse(frame_type)
    idx = list(_row_indices(rows))
    model = configuration.model
    nv = model.nv
    if len(idx) > nv:
        return np.zeros(nv)
    data = mujoco.MjData(model)
    data.qpos[:] = configuration.q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    point, body = _frame_point(configuration, data, frame, kind)
    jac = np.empty((6, nv))
    mujoco.mj_jac(model, data, jac[:3], jac[3:], point, body)
    U, s, Vt = scipy.linalg.svd(jac[idx], full_matrices=False)
    coefficients = np.array([np.prod(np.delete(s, i)) for i in range(s.size)])
    gradient = np.empty(nv)
    jac_dot = np.empty((6, nv))
    for k in range(nv):
        data.qvel[:] = 0.0
        data.qvel[k] = 1.0
        mujoco.mj_comVel(model, data)
        mujoco.mj_jacDot(model, data, jac_dot[:3], jac_dot[3:], point, body)
        dJ = jac_dot[idx]
        gradient[k] = np.sum(coefficients * np.einsum("ji,jk,ik->i", U, dJ, Vt))
    return gradient


def _frame_error(
    configuration: Configuration,
    frame: str | int,
    kind: FrameType,
    target: tuple[np.ndarray, np.ndarray],
    idx: list[int],
) -> np.ndarray:
    """Twist-like error ``[p* - p; log(R* R^T)]`` (world-aligned) on the chosen rows."""
    position, rotation = configuration.frame_pose(frame, kind)
    rotvec = orientation_error(rotation, target[1])
    return np.concatenate([target[0] - position, rotvec])[idx]


def self_motion(
    configuration: Configuration,
    frame: str | int,
    zeta: npt.ArrayLike,
    steps: int = 100,
    step_size: float = 0.01,
    rows: Rows = "position",
    frame_type: FrameType | str = "site",
    *,
    correction_tol: float = 1e-10,
    max_corrections: int = 20,
) -> np.ndarray:
    """Self-motion: move ``q`` along ``qdot = (I - J^+ J) zeta`` (the null space of the
    frame's Jacobian, chosen ``rows``) while the frame stays where it is.

    Each step moves ``q`` by ``step_size * (I - J^+ J) zeta`` [rad] (``zeta`` ``(nv,)``),
    then corrects the drift with Gauss-Newton steps ``J^+ e`` until the frame error
    ``e`` (position [m], and rotation vector [rad] for the orientation rows, world frame)
    is ``<= correction_tol`` or ``max_corrections`` steps are taken (``steps`` an int in
    [0, 100000], ``step_size`` finite, ``correction_tol`` >= 0, ``max_corrections`` in
    [0, 10000]). Joint limits are not
    enforced. The caller's configuration is not changed.

    Returns:
        The path of ``q``, ``(steps + 1, nq)``, starting at the current ``q``.
    """
    _check_configuration(configuration)
    kind = FrameType.parse(frame_type)
    idx = list(_row_indices(rows))
    work = configuration.copy()
    zeta = _as_vector(zeta, work.model.nv, "zeta")
    steps = checks.check_integer("steps", steps, 0, 100_000)
    step_size = checks.check_real("step_size", step_size)
    correction_tol = checks.check_real("correction_tol", correction_tol, 0.0)
    max_corrections = checks.check_integer("max_corrections", max_corrections, 0, 10_000)
    target = work.frame_pose(frame, kind)
    path = np.empty((steps + 1, work.model.nq))
    path[0] = work.q
    for step in range(1, steps + 1):
        J = work.frame_jacobian(frame, kind)[idx]
        pinv = pseudoinverse(J)
        move = step_size * (zeta - pinv @ (J @ zeta))
        error = _frame_error(work, frame, kind, target, idx)
        work.integrate_inplace(move + pinv @ error, 1.0)
        for _ in range(max_corrections):
            error = _frame_error(work, frame, kind, target, idx)
            if np.linalg.norm(error) <= correction_tol:
                break
            J = work.frame_jacobian(frame, kind)[idx]
            work.integrate_inplace(pseudoinverse(J) @ error, 1.0)
        path[step] = work.q
    return path


@dataclasses.dataclass(frozen=True)
class KinematicReport:
    """What the Jacobian of one frame says at one configuration (see :func:`analyze`).

    Attributes:
        frame, frame_type: The frame analysed.
        rows: Names of the task rows used (``ROW_NAMES`` subset).
        q: The configuration ``(nq,)``.
        jacobian: The Jacobian rows ``(m, nv)``, world-aligned ``[v; omega]``.
        singular_values: The ``min(m, nv)`` singular values, decreasing.
        rank: Numerical rank (``tol``).
        redundancy: Degree of redundancy ``dim N(J) = nv - rank``.
        manipulability: ``sqrt(det J J^T)``.
        condition_number: ``sigma_max / sigma_min`` (``inf`` at a singularity).
        singular: Smallest task-space singular value ``<= singular_tol``.
        singular_tol: The threshold used for ``singular``.
        lost_directions: ``(m, k)`` task directions that cannot be produced (when singular).
    """

    frame: str | int
    frame_type: str
    rows: tuple[str, ...]
    q: np.ndarray
    jacobian: np.ndarray
    singular_values: np.ndarray
    rank: int
    redundancy: int
    manipulability: float
    condition_number: float
    singular: bool
    singular_tol: float
    lost_directions: np.ndarray

    def __str__(self) -> str:
        m, n = self.jacobian.shape
        values = " ".join(f"{s:.4g}" for s in self.singular_values)
        lines = [
            f"{self.frame_type} {self.frame!r}, rows {' '.join(self.rows)} (m = {m} tasks, "
            f"n = {n} DoF)",
            f"  rank                  {self.rank}",
            f"  degree of redundancy  {self.redundancy}   (dim N(J) = n - rank)",
            f"  singular values       {values}",
            f"  manipulability        {self.manipulability:.6g}   (sqrt det J J^T)",
            f"  condition number      {self.condition_number:.6g}",
        ]
        if not self.singular:
            sigma_min = self.singular_values[-1] if m <= n else 0.0
            lines.append(
                f"  singular              no   (smallest singular value {sigma_min:.4g} "
                f"> {self.singular_tol:g})"
            )
        else:
            if self.rank < m:
                why = f"at a singularity, rank {self.rank} < {m} rows; cannot produce"
            else:
                sigma_min = self.singular_values[-1]
                why = (
                    f"near a singularity, smallest singular value {sigma_min:.4g} "
                    f"<= {self.singular_tol:g}; nearly lost"
                )
            lines.append(f"  singular              yes  ({why}:)")
            for direction in self.lost_directions.T:
                lines.append(f"    {_combination(direction, self.rows)}")
        return "\n".join(lines)


def _combination(vector: np.ndarray, names: Sequence[str]) -> str:
    """``0.707 vx - 0.707 vy`` for a unit vector over named rows (sign normalised)."""
    k = int(np.argmax(np.abs(vector)))
    vector = vector if vector[k] > 0 else -vector
    terms = [(c, name) for c, name in zip(vector, names) if abs(c) > 5e-4]
    text = ""
    for c, name in terms:
        sign = "-" if c < 0 else ("+" if text else "")
        text += f"{' ' if text else ''}{sign}{' ' if text else ''}{abs(c):.3g} {name}"
    return text


def analyze(
    configuration: Configuration,
    frame: str | int,
    frame_type: FrameType | str = "site",
    rows: Rows = "pose",
    *,
    tol: float | None = None,
    singular_tol: float = SINGULAR_TOL,
) -> KinematicReport:
    """Analyse the Jacobian of ``frame`` at the configuration's current ``q``.

    Args:
        configuration: The robot and its configuration (not changed).
        frame: Frame name (or id).
        frame_type: ``"site"``, ``"body"`` or ``"geom"``.
        rows: Task rows: ``"pose"`` (6), ``"position"`` (3), ``"orientation"`` (3), or a
            sequence of row names/indices. A planar robot has zero rows (``vz``, ``wx``,
            ``wy``): they lower the rank and show up as lost directions; pick the rows
            the robot can move (``("vx", "vy")``) to analyse the planar task.
        tol: Singular-value threshold of the rank (default: numpy's, exact rank).
        singular_tol: Threshold of the singular flag (near-singularity).
    """
    _check_configuration(configuration)
    kind = FrameType.parse(frame_type)
    idx = _row_indices(rows)
    J = configuration.frame_jacobian(frame, kind)[list(idx)]
    s = singular_values(J)
    r = rank(J, tol)
    report = singularity(J, _as_tol(singular_tol, np.zeros(0), J.shape, "singular_tol"))
    return KinematicReport(
        frame=frame,
        frame_type=kind.value,
        rows=tuple(ROW_NAMES[i] for i in idx),
        q=configuration.q,
        jacobian=J,
        singular_values=s,
        rank=r,
        redundancy=J.shape[1] - r,
        manipulability=manipulability(J),
        condition_number=condition_number(J),
        singular=report.singular,
        singular_tol=report.tol,
        lost_directions=report.lost_directions,
    )
