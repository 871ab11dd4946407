"""What the Jacobian reveals: rank, null space, singularities, redundancy, self-motion.

The analysis of the differential kinematics ``xi = J(q) qdot`` of a configuration. ``J``
is ``(m, n)``: ``m`` task rows (equations), ``n`` joint velocities (unknowns). Jacobians of a
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
from collections.abc import Sequence
from typing import TypedDict, Unpack

import numpy as np
import numpy.typing as npt

from .core import checks
from .core.jacobian import (
    ROW_NAMES,
    SINGULAR_TOL,
    Rows,
    SingularityReport,
    SolutionSet,
    as_tol,
    condition_number,
    damped_pseudoinverse,
    degree_of_redundancy,
    joint_limit_distance,
    joint_limit_distance_gradient,
    manipulability,
    null_space,
    nullspace_step,
    pseudoinverse,
    rank,
    row_indices,
    singular_values,
    singularity,
    solution_set,
)
from .errors import InvalidInput
from .model.configuration import Configuration, FrameType
from .model.gradients import check_configuration, manipulability_gradient
from .model.rotations import orientation_error

__all__ = [
    "Correction",
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


class Correction(TypedDict, total=False):
    """The drift correction of :func:`self_motion`: Gauss-Newton steps until the frame
    error is at most ``correction_tol`` [m, rad] (default 1e-10), at most
    ``max_corrections`` of them per step (default 20)."""

    correction_tol: float
    max_corrections: int


def self_motion(
    configuration: Configuration,
    frame: str | int,
    zeta: npt.ArrayLike,
    steps: int = 100,
    step_size: float = 0.01,
    rows: Rows = "position",
    frame_type: FrameType | str = "site",
    **correction: Unpack[Correction],
) -> np.ndarray:
    """Self-motion: move ``q`` along ``qdot = (I - J^+ J) zeta`` (the null space of the
    frame's Jacobian, chosen ``rows``) while the frame stays where it is.

    Each step moves ``q`` by ``step_size * (I - J^+ J) zeta`` [rad] (``zeta`` ``(nv,)``),
    then corrects the drift with Gauss-Newton steps ``J^+ e`` until the frame error
    ``e`` (position [m], and rotation vector [rad] for the orientation rows, world frame)
    is ``<= correction_tol`` or ``max_corrections`` steps are taken (``steps`` an int in
    [0, 100000], ``step_size`` finite, ``correction_tol`` >= 0, ``max_corrections`` in
    [0, 10000]; both keywords of :class:`Correction`). Joint limits are not enforced. The
    caller's configuration is not changed.

    Returns:
        The path of ``q``, ``(steps + 1, nq)``, starting at the current ``q``.
    """
    check_configuration(configuration)
    kind = FrameType.parse(frame_type)
    idx = list(row_indices(rows))
    work = configuration.copy()
    zeta = checks.check_vector("zeta", zeta, work.model.nv)
    steps = checks.check_integer("steps", steps, 0, 100_000)
    step_size = checks.check_real("step_size", step_size)
    checks.check_keywords("self_motion", dict(correction), Correction)
    correction_tol = checks.check_real(
        "correction_tol", correction.get("correction_tol", 1e-10), 0.0
    )
    max_corrections = checks.check_integer(
        "max_corrections", correction.get("max_corrections", 20), 0, 10_000
    )
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
        condition_number: ``sigma_max / sigma_min`` (``inf`` at a singularity, and with
            more rows than dofs: some task direction no joint moves).
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
    singular_tol: float | None = SINGULAR_TOL,
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
        singular_tol: Threshold of the singular flag (near-singularity); ``None``:
            numpy's default, as ``tol``'s.
    """
    check_configuration(configuration)
    if configuration.model.nv == 0:
        raise InvalidInput(
            "configuration: its model has no degree of freedom (nv = 0): no Jacobian to analyse"
        )
    kind = FrameType.parse(frame_type)
    idx = row_indices(rows)
    J = configuration.frame_jacobian(frame, kind)[list(idx)]
    s = singular_values(J)
    r = rank(J, tol)
    # (None: numpy's default relative to the largest singular value, as rank's)
    report = singularity(J, as_tol(singular_tol, s, J.shape, "singular_tol"))
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
        # (more rows than dofs: the task space's smallest singular value is 0, as the
        # report's manipulability and singular flag read it)
        condition_number=condition_number(J) if J.shape[0] <= J.shape[1] else float("inf"),
        singular=report.singular,
        singular_tol=report.tol,
        lost_directions=report.lost_directions,
    )
