"""Functions of a Jacobian matrix: singular values, rank, null space, redundancy,
pseudoinverses, manipulability, conditioning, the solution set of ``J x = xi``, the
nearest singularity, and the joint-limit distance (a secondary criterion for null-space
motion). Matrices only (no robot): :mod:`qpik.analysis` is the front door, with the
functions of a configuration.

Tolerances: ``tol`` is an *absolute* threshold on singular values; a singular value
counts (toward the rank, and is inverted by the pseudoinverse) when it is ``> tol``. The
default ``tol=None`` is numpy's, ``max(m, n) * eps * sigma_max`` (exact rank up to
rounding), floored at the smallest normal float so that no inverse overflows.
:func:`singularity` instead flags configurations *near* a singularity, with the absolute
threshold :data:`SINGULAR_TOL`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from typing import Literal

import numpy as np
import numpy.typing as npt
import scipy.linalg

from ..errors import InfeasibleLimits, InvalidArgumentType, InvalidInput
from . import checks

__all__ = [
    "ROW_NAMES",
    "SINGULAR_TOL",
    "Rows",
    "SingularityReport",
    "SolutionSet",
    "condition_number",
    "damped_pseudoinverse",
    "degree_of_redundancy",
    "entry_scale",
    "joint_limit_distance",
    "joint_limit_distance_gradient",
    "joint_limit_distance_terms",
    "joint_limit_midranges",
    "manipulability",
    "null_space",
    "nullspace_step",
    "pseudoinverse",
    "rank",
    "as_tol",
    "row_indices",
    "singular_value_product",
    "singular_values",
    "singularity",
    "solution_set",
]

#: Names of the six rows of a frame Jacobian ``[v; omega]`` (world-aligned).
ROW_NAMES: tuple[str, ...] = ("vx", "vy", "vz", "wx", "wy", "wz")

#: Default threshold of :func:`singularity` on the smallest singular value [Jacobian
#: units]: at or below it a configuration is reported as (near) singular. The planar 2R
#: arm with unit links at ``q2 = 0.001`` (``sigma_min ~ 4.5e-4``) is flagged.
SINGULAR_TOL = 1e-3

#: Relative residual below which ``J x = xi`` counts as solved (see :func:`solution_set`).
_RESIDUAL_RTOL = 1e-9

_ROW_SETS = {"pose": (0, 1, 2, 3, 4, 5), "position": (0, 1, 2), "orientation": (3, 4, 5)}

Rows = Literal["pose", "position", "orientation"] | Sequence[int | str]


# ---------------------------------------------------------------------- validation
def _as_matrix(J: npt.ArrayLike, name: str = "J") -> np.ndarray:
    """``J`` as a finite 2-D float array with at least one row and one column."""
    try:
        if np.iscomplexobj(np.asarray(J)):  # (a ragged list fails here: named below)
            raise InvalidInput(f"{name} is complex; a real matrix is expected")
        J = np.asarray(J, dtype=float)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, InvalidInput):
            raise
        raise InvalidInput(f"{name} is not a numeric matrix: {exc}") from None
    if J.ndim != 2 or J.shape[0] == 0 or J.shape[1] == 0:
        raise InvalidInput(f"{name} has shape {J.shape}, expected a 2-D (m, n) array, m, n >= 1")
    bad = np.argwhere(~np.isfinite(J))
    if bad.size:
        i, j = (int(k) for k in bad[0])
        raise InvalidInput(f"{name}[{i}, {j}] is {J[i, j]}; every entry must be finite")
    return J


def as_tol(tol: float | None, s: np.ndarray, shape: tuple[int, int], name: str = "tol") -> float:
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


def entry_scale(J: np.ndarray) -> float:
    """The largest ``|J_ij|`` (1 for a zero matrix): SVDs run on ``J / scale``, whose
    entries are at most 1, so that neither huge (1e300) nor tiny (1e-300) entries
    overflow or underflow inside LAPACK."""
    scale = float(np.max(np.abs(J))) if J.size else 0.0
    return scale if scale > 0.0 else 1.0


def _svdvals(J: np.ndarray) -> np.ndarray:
    """Singular values of ``J``, decreasing, computed on the scaled matrix (they are
    ``inf`` only where the true value exceeds the largest float)."""
    scale = entry_scale(J)
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


def row_indices(rows: Rows) -> tuple[int, ...]:
    """Row indices into a ``(6, nv)`` frame Jacobian for a ``rows`` argument."""
    if isinstance(rows, str):
        if rows not in _ROW_SETS:
            raise InvalidInput(
                f"unknown rows {rows!r}; expected one of: {', '.join(_ROW_SETS)}, "
                f"or a sequence of row names ({' '.join(ROW_NAMES)}) or indices 0-5"
            )
        return _ROW_SETS[rows]
    zero_d = isinstance(rows, np.ndarray) and rows.ndim == 0  # iterable by type, not by value
    if isinstance(rows, bytes) or not isinstance(rows, Iterable) or zero_d:
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
    return int(np.count_nonzero(s > as_tol(tol, s, J.shape)))


def _ranked_svd(
    J: np.ndarray, tol: float | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, float]:
    """``(U, s, Vt, r, tol)``: the full SVD of ``J`` (its vectors; ``s`` the singular
    values of :func:`singular_values`, which every function here decides the rank on, so
    that :func:`rank`, :func:`null_space`, :func:`pseudoinverse` and :func:`singularity`
    agree even where ``tol`` equals a singular value to the last bit) and the rank ``r``:
    the number of values ``> tol``."""
    s = _svdvals(J)
    tol = as_tol(tol, s, J.shape)
    U, _, Vt = scipy.linalg.svd(J / entry_scale(J))
    return U, s, Vt, int(np.count_nonzero(s > tol)), tol


def null_space(J: npt.ArrayLike, tol: float | None = None) -> np.ndarray:
    """Orthonormal basis ``(n, n - r)`` of the null space N(J): joint velocities that
    produce no task velocity. Its columns are the right singular vectors of the singular
    values ``<= tol`` (and of the ``n - m`` missing ones when ``m < n``)."""
    J = _as_matrix(J)
    _, _, Vt, r, _ = _ranked_svd(J, tol)
    return np.ascontiguousarray(Vt[r:].T)


def degree_of_redundancy(J: npt.ArrayLike, tol: float | None = None) -> int:
    """The degree of redundancy: ``dim N(J) = n - rank(J)``."""
    J = _as_matrix(J)
    return J.shape[1] - rank(J, tol)


def pseudoinverse(J: npt.ArrayLike, tol: float | None = None) -> np.ndarray:
    """Moore-Penrose pseudoinverse ``J^+`` ``(n, m)``; singular values ``<= tol`` are
    treated as zero. ``J^+ xi`` is the least-norm (least-squares) solution of
    ``J qdot = xi``."""
    J = _as_matrix(J)
    U, s, Vt, r, _ = _ranked_svd(J, tol)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        pinv = (Vt[:r].T / s[:r]) @ U[:, :r].T
    return _finite_result(pinv, "the pseudoinverse")


def damped_pseudoinverse(J: npt.ArrayLike, damping: float) -> np.ndarray:
    """Damped least-squares inverse ``J^T (J J^T + damping I)^-1`` ``(n, m)``.

    ``damping`` (> 0) is added to the diagonal, as in mink (it is ``lambda^2`` in the
    notation ``J^T (J J^T + lambda^2 I)^-1``). Each singular value ``s`` of ``J`` maps to
    ``s / (s^2 + damping) <= 1 / (2 sqrt(damping))``, so the result stays bounded at and
    near singularities: ``||J_damped^+||_2 <= 1 / (2 sqrt(damping))`` for every ``J``.
    (:func:`qpik.igm.baselines.damped_least_squares_step` takes the textbook's ``lambda``
    instead: its ``damping`` is the square root of this one.)
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
    scale = entry_scale(J)
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
    return singular_value_product(_svdvals(J))


def singular_value_product(s: np.ndarray) -> float:
    """The product of singular values ``s`` (0 where one is 0; ``inf`` past the float
    range), summed in logs: the product of 1e200s would overflow early."""
    if np.any(s == 0.0):
        return 0.0
    log = float(np.sum(np.log(s)))
    return math.exp(log) if log < 709.78 else float("inf")


def condition_number(J: npt.ArrayLike) -> float:
    """``sigma_max / sigma_min`` over the ``min(m, n)`` singular values; ``inf`` when
    ``sigma_min`` is 0 (or the ratio exceeds the float range). Large near a singularity."""
    J = _as_matrix(J)
    s = scipy.linalg.svdvals(J / entry_scale(J))  # the ratio does not depend on the scale
    with np.errstate(over="ignore"):
        return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")


# --------------------------------------------------------------- J qdot = xi, cases
@dataclasses.dataclass(frozen=True)
class SolutionSet:
    """The set of solutions of ``J qdot = xi``, by cases (rank of ``J`` and of ``[J xi]``).

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
        zeta = checks.check_vector("zeta", zeta, self.null_basis.shape[1])
        return self.particular + self.null_basis @ zeta


def solution_set(J: npt.ArrayLike, xi: npt.ArrayLike, tol: float | None = None) -> SolutionSet:
    """Solve ``J qdot = xi`` (``J`` ``(m, n)``, ``xi`` ``(m,)``) and classify the solutions.

    ``xi`` counts as reachable when the least-squares residual is at rounding level
    (relative to ``||xi|| + sigma_max ||J^+ xi||``); singular values ``<= tol`` count as 0.
    """
    J = _as_matrix(J)
    xi = checks.check_vector("xi", xi, J.shape[0])
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
    """The general solution ``qdot = J^+ xi + (I - J^+ J) zeta`` ``(n,)``.

    ``zeta`` ``(n,)`` is any joint velocity (for example ``-grad`` of a secondary
    criterion); its projection onto N(J) changes nothing in the task.
    """
    J = _as_matrix(J)
    xi = checks.check_vector("xi", xi, J.shape[0])
    zeta = checks.check_vector("zeta", zeta, J.shape[1])
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


def singularity(J: npt.ArrayLike, tol: float | None = SINGULAR_TOL) -> SingularityReport:
    """Singularity analysis of ``J`` with an absolute threshold ``tol`` on singular values
    (``None``: numpy's default, relative to the largest, as :func:`rank` takes it)."""
    J = _as_matrix(J)
    m = J.shape[0]
    U, s, Vt, r, tol = _ranked_svd(J, tol)  # (None: numpy's default, as rank's)
    s = _finite_result(s, "a singular value of J")
    task_s = np.zeros(m)
    task_s[: s.size] = s  # m > n: the m - n missing singular values are 0
    lost = U[:, task_s <= tol]
    return SingularityReport(
        sigma_min=float(task_s[-1]),
        singular=bool(task_s[-1] <= tol),
        tol=tol,
        rank=r,
        lost_directions=lost,
        null_motions=np.ascontiguousarray(Vt[r:].T),
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
    return _gradient(q, half, _ratio(q, mid, half))


def joint_limit_distance_terms(
    q: npt.ArrayLike, lower: npt.ArrayLike, upper: npt.ArrayLike
) -> tuple[float, np.ndarray]:
    """:func:`joint_limit_distance` and :func:`joint_limit_distance_gradient` together (the
    same values), the inputs checked once: what a task needs each step."""
    q, mid, half = _limits(q, lower, upper)
    if q.size == 0:
        return 0.0, np.zeros(0)
    ratio = _ratio(q, mid, half)
    with np.errstate(over="ignore"):
        w = np.sum(ratio**2) / (2 * q.size)
    value = float(_finite_result(np.asarray(w), "the joint-limit distance"))
    return value, _gradient(q, half, ratio)


def joint_limit_midranges(
    lower: npt.ArrayLike, upper: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """``(mid, half)`` (n,) of the limits that :func:`joint_limit_distance` uses: the
    mid-range and half-range of each joint with two finite, distinct limits, 0 and 0 for
    the others (checked as there: :class:`InvalidInput`, :class:`InfeasibleLimits`)."""
    _, mid, half = _limits(np.zeros(np.shape(lower)), lower, upper)
    return mid, half


def _gradient(q: np.ndarray, half: np.ndarray, ratio: np.ndarray) -> np.ndarray:
    """The gradient of :func:`joint_limit_distance_gradient` from its ratio terms."""
    gradient = np.zeros_like(q)
    limited = half > 0
    with np.errstate(over="ignore"):  # ratio / (n span) = ratio / (2 n half)
        gradient[limited] = ratio[limited] / (2 * q.size) / half[limited]
    return _finite_result(gradient, "the joint-limit distance gradient")
