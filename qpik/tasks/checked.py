"""Checks of the task values that a solver reads at every step (a gain, a frame target),
made where they are set on qpik's tasks (:class:`CheckedTask`) and where qpik reads them
from mink's own task classes (:mod:`qpik.diffik`: the gathered step and the QP path).

A gain must be a number in ``[0, 1]``, as mink's constructors check it: one set later to
``2.0``, ``-1.0`` or NaN raises :class:`qpik.InvalidGain` naming the task (what is not one
number is reported by the step where it does not fit the task's rows). A
frame target must be a :class:`mink.SE3` whose quaternion is not zero (a zero quaternion
is no rotation: its orientation error would read 0 whatever the frame's orientation);
:class:`qpik.InvalidTarget` naming the task otherwise. A NaN target is reported at the step
(its rows are not finite), as before.
"""

from __future__ import annotations

from typing import Any

import mink
import numpy as np

from ..errors import InvalidGain, InvalidTarget

__all__ = [
    "POSE_TARGETS",
    "CheckedTask",
    "check_gain",
    "check_pose_target",
    "gain_is_valid",
    "pose_target_name",
    "task_label",
]


def task_label(task: Any) -> str:
    """A task's class and, where it has one, its frame's name (``FrameTask 'ee'``)."""
    name = getattr(task, "frame_name", None)
    return type(task).__name__ + ("" if name is None else f" {name!r}")


def _gain_number(gain: Any) -> float | None:
    """``gain`` as a float where it is one number (a float, an int, a bool, a NumPy scalar or
    a 0-d array), else None (an array, a string: not a number the gain check judges)."""
    if type(gain) is float:
        return gain
    if isinstance(gain, (str, bytes)) or np.ndim(gain) != 0:
        return None
    try:
        return float(gain)
    except (TypeError, ValueError):
        return None


def gain_is_valid(gain: Any) -> bool:
    """Whether ``gain`` is one number in ``[0, 1]``."""
    value = _gain_number(gain)
    return value is not None and 0.0 <= value <= 1.0


def check_gain(task: Any, gain: Any) -> None:
    """Raise :class:`qpik.InvalidGain` naming ``task`` where ``gain`` is a number outside
    ``[0, 1]`` or NaN. What is not one number (an array, a string) is left to the step,
    which reports it where it does not fit the task's rows (TaskDefinitionError)."""
    if type(gain) is float and 0.0 <= gain <= 1.0:  # (the usual case)
        return
    value = _gain_number(gain)
    if value is not None and not 0.0 <= value <= 1.0:
        raise InvalidGain(f"{task_label(task)}: gain must be in [0, 1], got {gain!r}")


def check_pose_target(task: Any, target: Any, name: str) -> None:
    """Raise :class:`qpik.InvalidTarget` naming ``task`` and ``name`` (its attribute, or
    the argument) where ``target`` is not a :class:`mink.SE3` of 7 entries (``wxyz_xyz``)
    or its quaternion is zero. NaN entries pass (the step reports the rows they make)."""
    if not isinstance(target, mink.SE3):
        raise InvalidTarget(
            f"{task_label(task)}: {name} must be a mink.SE3, got {type(target).__name__}"
        )
    entries = target.wxyz_xyz
    if type(entries) is not np.ndarray or entries.shape != (7,):
        raise InvalidTarget(
            f"{task_label(task)}: {name} must hold 7 entries (wxyz_xyz), got {np.shape(entries)}"
        )
    w, x, y, z, *_ = entries.tolist()
    if w == 0.0 and x == 0.0 and y == 0.0 and z == 0.0:
        raise InvalidTarget(
            f"{task_label(task)}: {name} has a zero quaternion (wxyz = 0): it is no rotation"
        )


#: The target attribute of each frame-like task class (mink's, and so qpik's subclasses).
POSE_TARGETS: tuple[tuple[type, str], ...] = (
    (mink.FrameTask, "transform_target_to_world"),
    (mink.RelativeFrameTask, "transform_target_to_root"),
)
_POSE_TARGET_NAMES = frozenset(name for _, name in POSE_TARGETS)


def pose_target_name(task: Any) -> str:
    """The attribute holding ``task``'s target pose (:data:`POSE_TARGETS`; ``"target"`` for
    another class), for messages."""
    for cls, name in POSE_TARGETS:
        if isinstance(task, cls):
            return name
    return "target"


class CheckedTask:
    """Mixin of qpik's tasks: the values a solver reads again at every step are checked
    where they are set (the solver's compiled step reads them as they are): ``gain``
    (:func:`check_gain`) and a frame task's target (:func:`check_pose_target`; ``None``
    allowed: no target). Reading an attribute costs what it did (only assignments pass
    here)."""

    __slots__ = ()

    def __setattr__(self, name: str, value: Any) -> None:
        if name == "gain":
            check_gain(self, value)
        elif name in _POSE_TARGET_NAMES and value is not None:
            check_pose_target(self, value, name)
        super().__setattr__(name, value)
