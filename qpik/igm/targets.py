"""Frame targets of a full-IK solve: what a target may be, its parsing and its errors.

A target is a position [m] in the world frame and, optionally, a rotation matrix (frame to
world). :func:`parse_target` accepts a position ``(3,)``, a ``(position, rotation)`` pair,
a 4x4 homogeneous matrix, a ``mink.SE3`` or a :class:`Target`, and raises
:class:`qpik.InvalidTarget` for anything else. :func:`pose_errors` measures a frame pose
against a target: the distance of the origins [m] and the angle of ``R_target R^T`` [rad]
(:func:`qpik.model.rotations.orientation_angle`, the formula the compiled engine uses).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypeAlias

import mink
import mujoco
import numpy as np
import numpy.typing as npt

from ..core.checks import float_array
from ..errors import InvalidTarget, UnknownFrameType
from ..model import kernels
from ..model.configuration import Configuration, FrameType
from ..model.rotations import ORTHONORMAL_TOLERANCE, nearest_rotation, orientation_angle
from ..tasks import OrientationTask, PoseTask, PositionTask
from .kernels import target_ok

__all__ = [
    "MAX_TARGET_DISTANCE",
    "FrameKey",
    "RobotLike",
    "Target",
    "TargetLike",
    "STEERS_POSITION",
    "STEERS_ROTATION",
    "TARGET_TASKS",
    "check_distinct_frames",
    "parse_target",
    "pose_errors",
    "regulating_tasks",
    "set_frame_target",
    "set_task_target",
    "worst_errors",
]

#: Targets beyond this distance from the origin [m] are rejected: no robot reaches them,
#: and their squared errors would overflow.
MAX_TARGET_DISTANCE = 1e9


@dataclass(frozen=True)
class Target:
    """A target for one frame: a position [m] in the world frame and, optionally, a
    rotation matrix (frame to world)."""

    position: np.ndarray
    rotation: np.ndarray | None = None


#: What :func:`qpik.solve` accepts as a robot: anything :func:`qpik.load_robot` takes, or a
#: :class:`qpik.Configuration`.
RobotLike: TypeAlias = str | os.PathLike | mujoco.MjModel | Configuration
#: A target frame: a name (site, then body, then geom) or ``(name, frame_type)``.
FrameKey = str | tuple[str, FrameType | str]
#: A target: a position (3,), ``(position, rotation)``, a 4x4 matrix, an SE3 or a Target.
TargetLike = Target | mink.SE3 | npt.ArrayLike | tuple[npt.ArrayLike, npt.ArrayLike]


_TARGET_DEFECTS = {
    1: "position target must be 3 finite numbers",
    2: "rotation target must be a finite 3x3 matrix",
    3: "rotation target is not a rotation matrix (R R^T != I or det <= 0)",
}
_FORMS = "a target is a position (3,), (position, rotation), a 4x4 matrix or an SE3"


#: The native float64 dtype (a singleton: ``is`` tests it without ``==``'s conversion of
#: ``np.float64``, about 0.4 us a call).
_FLOAT64 = np.dtype(np.float64)


def _real(value) -> np.ndarray:
    """``value`` as a new float64 array of real numbers (:func:`qpik.core.checks.float_array`,
    booleans refused too: no position is a truth value)."""
    return np.array(float_array(value, booleans=False), dtype=float)


def _array(value, shape: tuple[int, ...], what: str) -> np.ndarray:
    if type(value) is np.ndarray and value.dtype is _FLOAT64 and value.shape == shape:
        return value.copy()  # the common case, at the cost of a copy
    try:
        array = _real(value)
    except (TypeError, ValueError) as exc:
        raise InvalidTarget(
            f"{what} must be finite numbers of shape {shape}, got {value!r} ({exc})"
        ) from exc
    if array.shape != shape:
        raise InvalidTarget(
            f"{what} must be finite numbers of shape {shape}, got an array of shape {array.shape}"
        )
    return array


def _parts(value: TargetLike) -> tuple:
    """``(position, rotation or None)`` of any accepted form, unchecked."""
    if isinstance(value, tuple) and len(value) == 2:
        return value
    if isinstance(value, Target):
        return value.position, value.rotation
    if isinstance(value, mink.SE3):
        return value.translation(), value.rotation().as_matrix()
    try:
        array = _real(value)
    except (TypeError, ValueError) as exc:
        raise InvalidTarget(f"{_FORMS}; got {value!r} ({exc})") from exc
    if array.shape == (4, 4):
        if not np.isfinite(array).all():
            raise InvalidTarget(f"a 4x4 target must be finite numbers, got {array!r}")
        if not np.allclose(array[3], [0, 0, 0, 1]):
            raise InvalidTarget("a 4x4 target's last row must be (0, 0, 0, 1)")
        return array[:3, 3], array[:3, :3]
    if array.shape == (3,):
        return array, None
    raise InvalidTarget(f"{_FORMS}; got an array of shape {array.shape}")


def parse_target(value: TargetLike, frame: FrameKey | None = None) -> Target:
    """A :class:`Target` from a position ``(3,)``, a ``(position, rotation)`` pair, a 4x4
    homogeneous matrix, a ``mink.SE3`` or a ``Target``; NaN / malformed input raises
    :class:`qpik.InvalidTarget` (its message beginning with ``frame`` where given: the
    frame of several whose target it is). The rotation is checked once, in one compiled call
    (``|R R^T - I| <= 1e-6``, ``det R > 0``), and the target is the rotation nearest to
    it (:func:`qpik.model.rotations.nearest_rotation`, which keeps a matrix orthonormal
    within :data:`qpik.model.rotations.ORTHONORMAL_TOLERANCE`); positions farther than
    :data:`MAX_TARGET_DISTANCE` from the world origin are rejected."""
    try:
        return _parse_target(value)
    except InvalidTarget as exc:
        if frame is None:
            raise
        raise InvalidTarget(f"target of {frame!r}: {exc}") from None


def _parse_target(value: TargetLike) -> Target:
    """:func:`parse_target` of one target."""
    if type(value) is tuple and len(value) == 2:
        # The common (position, rotation) pair of float64 arrays, valid and orthonormal:
        # checked in one compiled call; anything else takes the general path.
        position, rotation = value
        if (
            type(position) is np.ndarray
            and type(rotation) is np.ndarray
            and target_ok(position, rotation, ORTHONORMAL_TOLERANCE, MAX_TARGET_DISTANCE)
        ):
            return Target(position.copy(), rotation.copy())
    position, rotation = _parts(value)
    position = _array(position, (3,), "position target")
    x, y, z = position.tolist()
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise InvalidTarget(f"{_TARGET_DEFECTS[1]}, got {position!r}")
    if rotation is not None:
        rotation = _array(rotation, (3, 3), "rotation target")
        # One compiled pass: max |R R^T - I|, inf where R is not finite or det R <= 0.
        defect = kernels.rotation_defect(rotation)
        if not defect <= 1e-6:
            code = 3 if np.isfinite(rotation).all() else 2
            raise InvalidTarget(f"{_TARGET_DEFECTS[code]}, got {rotation!r}")
        if defect > ORTHONORMAL_TOLERANCE:
            rotation = nearest_rotation(rotation)
    if not max(abs(x), abs(y), abs(z)) <= MAX_TARGET_DISTANCE:
        raise InvalidTarget(
            f"position target {position!r} is farther than {MAX_TARGET_DISTANCE:g} m from the "
            "world origin (its error would not be representable)"
        )
    return Target(position, rotation)


def pose_errors(position: np.ndarray, rotation: np.ndarray, target: Target) -> tuple[float, float]:
    """``(|p - p_target| [m], angle of R_target R^T [rad])`` of a frame pose (world frame)
    against ``target``; the angle is 0 for a position-only target."""
    d = position - target.position
    position_error = float(math.sqrt(d @ d))
    if target.rotation is None:
        return position_error, 0.0
    return position_error, orientation_angle(rotation, target.rotation)


def worst_errors(errors: Mapping[str, tuple[float, float]]) -> tuple[float, float]:
    """The largest position error [m] and the largest orientation error [rad] over frames."""
    return max(p for p, _ in errors.values()), max(o for _, o in errors.values())


def check_distinct_frames(frames: list, keys: list) -> None:
    """:class:`qpik.InvalidTarget` where two of ``keys`` name one frame (``'ee'`` and
    ``('ee', 'site')``: two targets for it, which a solve would treat as a conflict);
    ``frames``: their resolved frames (``name`` and ``kind``), in the same order."""
    seen: dict = {}
    for frame, key in zip(frames, keys):
        first = seen.setdefault((frame.name, frame.kind), key)
        if first is not key:
            raise InvalidTarget(
                f"targets name the frame {frame.kind.value} {frame.name!r} twice ({first!r} "
                f"and {key!r}): give it one target"
            )


#: The tasks that take a frame's target (:func:`set_frame_target`), and what each steers.
TARGET_TASKS = (PositionTask, OrientationTask, PoseTask, mink.FrameTask)
STEERS_POSITION = (PositionTask, PoseTask, mink.FrameTask)
STEERS_ROTATION = (OrientationTask, PoseTask, mink.FrameTask)


def regulating_tasks(
    levels: Sequence[Sequence], frame: str, kind: FrameType | str | None = None
) -> list:
    """The tasks of ``levels`` that take ``frame``'s target (position, orientation, pose
    and mink frame tasks of that frame name, and of that frame type where ``kind`` is
    given: a body and a geom of the same name are two frames)."""
    out = []
    for task in (t for level in levels for t in level):
        if getattr(task, "frame_name", None) != frame:
            continue
        if not isinstance(task, TARGET_TASKS):
            continue  # (a frame-named task that takes no target: a look-at task, say)
        if kind is not None:
            try:
                same = FrameType.parse(task.frame_type) is FrameType.parse(kind)
            except (AttributeError, UnknownFrameType):
                same = False
            if not same:
                continue
        out.append(task)
    return out


def set_frame_target(
    levels: Sequence[Sequence], frame: str, target: Target, kind: FrameType | str | None = None
) -> bool:
    """Set ``target`` on every task of ``levels`` that regulates ``frame`` (of type
    ``kind`` where given: :func:`regulating_tasks`); returns whether any task does."""
    tasks = regulating_tasks(levels, frame, kind)
    for task in tasks:
        set_task_target(task, frame, target)
    return bool(tasks)


def set_task_target(task: Any, frame: str, target: Target) -> None:
    """Set ``target`` on one task that takes it (:func:`regulating_tasks`' kinds); a pose
    task given a position-only target raises :class:`qpik.InvalidTarget`."""
    if isinstance(task, PositionTask):
        task.set_target(target.position)
    elif isinstance(task, OrientationTask):
        if target.rotation is not None:
            task.set_target(target.rotation)
    elif isinstance(task, (PoseTask, mink.FrameTask)):
        if target.rotation is None:
            raise InvalidTarget(
                f"frame {frame!r} has a pose task in the stack but a position-only target"
            )
        if isinstance(task, PoseTask):
            task.set_target(target.position, target.rotation)
        else:
            task.set_target(
                mink.SE3.from_rotation_and_translation(
                    mink.SO3.from_matrix(target.rotation), target.position
                )
            )
