"""Position-only and orientation-only frame tasks, in the world frame.

mink's :class:`~mink.FrameTask` with a zero orientation cost also regulates position only,
but keeps six rows (three of them zero) and expresses its error in the local frame. These
tasks have exactly the rows they regulate, world-aligned, so that a level's rank and
smallest singular value (which drive qpik's damping) mean what they say.
"""

from __future__ import annotations

import mink
import numpy as np
import numpy.typing as npt

from .._engine.tasks import POSE_FULL, POSE_ORIENTATION, POSE_POSITION, pose_rows_into
from ..core import checks
from ..errors import InvalidTarget, TargetNotSet, TaskDefinitionError, mink_errors_as_qpik
from ..model.configuration import Configuration, FrameType, as_configuration
from ..model.frames import FRAME_JACOBIANS, FRAME_POSITIONS, FRAME_ROTATIONS
from .checked import CheckedTask

# Their rows come from one compiled routine (qpik/_cpp/tasks/pose.hpp, pose_rows_into), the
# one the compiled step calls for them too (kinds 7 to 9 of qpik.diffik.layout.POSE_KINDS):
# the same bits on both paths. Its error and Jacobian are its rows with unit cost and gain
# -1 (b = 1 (1 e) = e, A = 1 J = J: exact).
#
# These tasks read what only qpik.Configuration has (frame_id and its MjData), so their
# compute_* methods narrow mink's ``configuration: mink.Configuration`` (hence the
# ``type: ignore`` on the classes that take them); qpik's entry points
# (qpik.diffik.mink_compat) turn a mink configuration into a qpik one before any task sees it.


_UNITS = {3: np.ones(3), 6: np.ones(6)}  # unit costs by row count


def _pose_rows(
    task,
    configuration: Configuration,
    target: np.ndarray,
    part: int,
    cost: np.ndarray,
    gain: float,
    lm_damping: float,
) -> tuple[np.ndarray, np.ndarray, float]:
    """``(A, b, mu)`` of ``part`` (``POSE_POSITION``, ``POSE_ORIENTATION`` or ``POSE_FULL``)
    of ``task``'s frame at ``configuration``: ``A = diag(cost) J``, ``b = -gain cost e``,
    ``mu = lm_damping |b|^2`` (world frame; ``target``: position (3) [m] then rotation
    (row-major 9))."""
    kind = task.frame_type
    configuration = as_configuration(configuration)
    fid = configuration.frame_id(task.frame_name, kind)
    model, data = configuration.model, configuration.data
    xpos = getattr(data, FRAME_POSITIONS[kind])[fid]
    xmat = getattr(data, FRAME_ROTATIONS[kind])[fid]
    jac = np.empty((6, model.nv))
    FRAME_JACOBIANS[kind](model, data, jac[:3], jac[3:], fid)
    k = 6 if part == POSE_FULL else 3
    A, b = np.empty((k, model.nv)), np.empty(k)
    mu = pose_rows_into(A, b, 0, jac, xpos, xmat, target, part, cost, gain, lm_damping)
    return A, b, mu


def _numbers(value: npt.ArrayLike, what: str) -> np.ndarray:
    """A float copy of ``value``; :class:`InvalidTarget` when it is not numbers."""
    if isinstance(value, (str, bytes)):
        raise InvalidTarget(f"{what} must be numbers, got {type(value).__name__}")
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidTarget(f"{what} must be numbers, got {type(value).__name__}") from None


def checked_position(value: npt.ArrayLike, what: str = "position target") -> np.ndarray:
    """A copy of ``value`` as a finite position (3,) [m]; :class:`InvalidTarget` otherwise."""
    return checks.check_vector(what, value, 3, error=InvalidTarget).copy()


def checked_rotation(value: npt.ArrayLike | mink.SO3, what: str = "rotation target") -> np.ndarray:
    """A copy of ``value`` (a rotation matrix (3, 3), or mink's :class:`~mink.SO3`) as a
    rotation matrix (3, 3); :class:`InvalidTarget` otherwise."""
    if isinstance(value, mink.SO3):
        value = value.as_matrix()
    rotation = _numbers(value, what)
    if rotation.shape != (3, 3) or not np.all(np.isfinite(rotation)):
        raise InvalidTarget(f"{what} must be a finite 3x3 matrix, got {rotation!r}")
    if not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6) or np.linalg.det(rotation) < 0:
        raise InvalidTarget(f"{what} is not a rotation matrix (R R^T != I or det < 0)")
    return rotation


def _entries(value, shape: tuple[int, ...], what: str) -> np.ndarray:
    """A target attribute (set by the setters, or assigned directly) as float entries of
    ``shape``, flattened: ValueError naming it where it is not (a number where a vector or
    matrix is expected: no broadcasting), which the steps report as the task's
    TaskDefinitionError."""
    if type(value) is np.ndarray and value.shape == shape and value.dtype == np.float64:
        return value.reshape(-1)  # (the setters' arrays: the usual case, no copy)
    entries = np.asarray(value, dtype=float)
    if entries.shape != shape:
        raise ValueError(f"a {what} of shape {entries.shape}, not {shape}")
    return entries.reshape(-1)


def _cost_vector(cost: npt.ArrayLike, name: str) -> np.ndarray:
    vector = np.broadcast_to(np.asarray(cost, dtype=float), (3,)).copy()
    if not np.all(np.isfinite(vector)) or np.any(vector < 0):
        raise TaskDefinitionError(f"{name} must be finite and >= 0, got {vector}")
    return vector


class _CompiledRows:
    """The error, Jacobian and weighted rows of a world-frame pose task from its ``_rows``
    (one compiled call: :func:`_pose_rows`): the error and Jacobian are the rows at unit
    cost and gain -1."""

    k: int
    cost: np.ndarray
    gain: float
    lm_damping: float

    def _rows(
        self, configuration: Configuration, cost: np.ndarray, gain: float, lm: float
    ) -> tuple[np.ndarray, np.ndarray, float]:
        raise NotImplementedError

    def compute_error(self, configuration: Configuration) -> np.ndarray:
        """The error ``e`` (k,) in the world frame [m, rad] (see the class)."""
        return self._rows(configuration, _UNITS[self.k], -1.0, 0.0)[1]

    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:
        """The Jacobian ``de/dq`` (k, nv) (see the class)."""
        return self._rows(configuration, _UNITS[self.k], -1.0, 0.0)[0]

    def compute_qp_residual(
        self, configuration: Configuration
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """``(diag(cost) J, -gain diag(cost) e, mu)`` in one compiled call."""
        return self._rows(configuration, self.cost, float(self.gain), float(self.lm_damping))


class _FrameRowsTask(_CompiledRows, mink.Task, CheckedTask):  # type: ignore[misc]  # (see the note above)
    """A task on three rows of one frame's pose (see the subclasses)."""

    k = 3
    _cost_name = "cost"

    def __init__(
        self,
        frame_name: str,
        frame_type: FrameType | str = FrameType.SITE,
        cost: npt.ArrayLike = 1.0,
        gain: float = 1.0,
        lm_damping: float = 0.0,
    ):
        numbers = {"cost": cost, "gain": gain, "lm_damping": lm_damping}
        with mink_errors_as_qpik(type(self).__name__, numbers):
            super().__init__(_cost_vector(cost, self._cost_name), gain, lm_damping)
        self.frame_name = checks.check_frame_name("frame_name", frame_name)
        self.frame_type = FrameType.parse(frame_type)
        self.target: np.ndarray | None = None

    _part = POSE_POSITION

    def _target12(self) -> np.ndarray:
        raise NotImplementedError

    def _rows(self, configuration: Configuration, cost: np.ndarray, gain: float, lm: float):
        return _pose_rows(self, configuration, self._target12(), self._part, cost, gain, lm)


class PositionTask(_FrameRowsTask):
    """Bring a frame's origin to a target position (world frame, [m]).

    Error ``e = p(q) - p_target`` (3,), Jacobian the linear rows of the world-aligned frame
    Jacobian.
    """

    k = 3
    _cost_name = "position cost"

    def set_target(self, position: npt.ArrayLike) -> None:
        """Target position of the frame origin in the world frame [m]."""
        self.target = checked_position(position)

    def set_target_from_configuration(self, configuration: Configuration) -> None:
        """Target = the frame's current position."""
        self.set_target(
            as_configuration(configuration).frame_pose(self.frame_name, self.frame_type)[0]
        )

    def _target12(self) -> np.ndarray:
        if self.target is None:
            raise TargetNotSet(type(self).__name__)
        target = np.zeros(12)
        target[:3] = _entries(self.target, (3,), "position target")
        return target


class OrientationTask(_FrameRowsTask):
    """Bring a frame's orientation to a target rotation (world frame).

    Error ``e = log(R(q) R_target^T)`` (3,) [rad], the rotation vector from the target to the
    current orientation in world coordinates; Jacobian ``Jl^-1(e) J_omega`` (exact).
    """

    k = 3
    _cost_name = "orientation cost"

    def set_target(self, rotation: npt.ArrayLike | mink.SO3) -> None:
        """Target rotation of the frame in the world frame: a rotation matrix (3, 3) or
        mink's :class:`~mink.SO3`."""
        self.target = checked_rotation(rotation)

    def set_target_from_configuration(self, configuration: Configuration) -> None:
        """Target = the frame's current orientation."""
        self.set_target(
            as_configuration(configuration).frame_pose(self.frame_name, self.frame_type)[1]
        )

    _part = POSE_ORIENTATION

    @property
    def _rotation_entries(self) -> np.ndarray | None:
        """The target rotation's 9 entries, row-major (None while no target is set): what
        the compiled step reads each step (a 1-D view of the matrix)."""
        return None if self.target is None else _entries(self.target, (3, 3), "rotation target")

    def _target12(self) -> np.ndarray:
        if self.target is None:
            raise TargetNotSet(type(self).__name__)
        target = np.zeros(12)
        target[3:] = _entries(self.target, (3, 3), "rotation target")
        return target


class PoseTask(_CompiledRows, mink.Task, CheckedTask):  # type: ignore[misc]  # (see the note above)
    """Bring a frame to a target pose, errors in the world frame.

    Error ``e = [p(q) - p_target; log(R(q) R_target^T)]`` (6,) [m, rad]; Jacobian
    ``[J_v; Jl^-1(e_rot) J_omega]`` (exact). The same rows as :class:`PositionTask` and
    :class:`OrientationTask` together, computed from one frame pose and one Jacobian.
    (mink's :class:`~mink.FrameTask` regulates the same pose with a local-frame error.)
    """

    k = 6

    def __init__(
        self,
        frame_name: str,
        frame_type: FrameType | str = FrameType.SITE,
        position_cost: npt.ArrayLike = 1.0,
        orientation_cost: npt.ArrayLike = 1.0,
        gain: float = 1.0,
        lm_damping: float = 0.0,
    ):
        arguments = {"position_cost": position_cost, "orientation_cost": orientation_cost}
        with mink_errors_as_qpik(type(self).__name__, arguments):
            cost = np.concatenate(
                [
                    _cost_vector(position_cost, "position cost"),
                    _cost_vector(orientation_cost, "orientation cost"),
                ]
            )
            super().__init__(cost, gain, lm_damping)
        self.frame_name = checks.check_frame_name("frame_name", frame_name)
        self.frame_type = FrameType.parse(frame_type)
        self.target_position: np.ndarray | None = None
        self.target_rotation: np.ndarray | None = None

    def set_target(
        self, position: npt.ArrayLike | mink.SE3, rotation: npt.ArrayLike | mink.SO3 | None = None
    ) -> None:
        """Target pose in the world frame: a position (3,) [m] and a rotation (a matrix (3, 3)
        or mink's :class:`~mink.SO3`), or one mink :class:`~mink.SE3` (``rotation`` left
        out)."""
        if isinstance(position, mink.SE3):
            if rotation is not None:
                raise InvalidTarget(
                    "PoseTask.set_target: give one mink.SE3, or a position and a rotation"
                )
            rotation = position.rotation()
            position = position.translation()
        elif rotation is None:
            raise InvalidTarget("PoseTask.set_target: rotation is missing (or give one mink.SE3)")
        self.target_position = checked_position(position)
        self.target_rotation = checked_rotation(rotation)

    def set_target_from_configuration(self, configuration: Configuration) -> None:
        """Target = the frame's current pose."""
        self.set_target(
            *as_configuration(configuration).frame_pose(self.frame_name, self.frame_type)
        )

    @property
    def _rotation_entries(self) -> np.ndarray | None:
        """The target rotation's 9 entries, row-major (None while no target is set): what
        the compiled step reads each step (a 1-D view of the matrix)."""
        rotation = self.target_rotation
        return None if rotation is None else _entries(rotation, (3, 3), "rotation target")

    def _rows(self, configuration: Configuration, cost: np.ndarray, gain: float, lm: float):
        if self.target_position is None or self.target_rotation is None:
            raise TargetNotSet(type(self).__name__)
        target = np.empty(12)
        target[:3] = _entries(self.target_position, (3,), "position target")
        target[3:] = _entries(self.target_rotation, (3, 3), "rotation target")
        return _pose_rows(self, configuration, target, POSE_FULL, cost, gain, lm)
