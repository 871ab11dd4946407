"""Goals of a problem file: ``[target]`` or ``[[waypoints]]``, each one or several frames.

A goal table is either one frame::

    [target]
    frame = "ee"                 # default: the frame of level 0's first goal task
    position = [0.5, 0.2, 0.4]   # [m], world frame
    rpy = [3.14159, 0, 0]        # optional rotation (rpy, quaternion or matrix)

or several frames reached together (both hands of a humanoid)::

    [target]
    [[target.frames]]
    frame = "gripper_left_base_link"
    frame_type = "body"
    position = [0.3, 0.4, 1.0]
    [[target.frames]]
    frame = "gripper_right_base_link"
    frame_type = "body"
    position = [0.3, -0.4, 1.0]

Each frame of a goal (its name and type) must be regulated by a ``frame``, ``position`` or
``orientation`` task of the stack (those tasks receive the goal); a frame regulated by a
``frame`` task needs a rotation, and every part of a goal must be steered by some task (a
position by a frame or position task, a rotation by a frame or orientation task).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ..igm.targets import FrameKey, Target
from ..model.configuration import Configuration, FrameType
from ..model.rotations import orientation_angle
from .reader import ROTATION_KEYS, Reader, describe, dotted
from .specs import TaskSpec

_FRAME_FIELDS = {"frame", "frame_type", "position", *ROTATION_KEYS}


@dataclass(frozen=True)
class FrameGoal:
    """One frame of a goal: its name, type and target (position [m], optional rotation,
    world frame); ``field``: where it sits in the file."""

    frame: str
    frame_type: FrameType
    target: Target
    field: str

    def error(self, configuration: Configuration) -> tuple[float, float]:
        """Position error [m] and orientation error [rad] (0 without a rotation target)
        of the frame at ``configuration``."""
        position, rotation = configuration.frame_pose(self.frame, self.frame_type)
        position_error = float(np.linalg.norm(position - self.target.position))
        if self.target.rotation is None:
            return position_error, 0.0
        return position_error, orientation_angle(rotation, self.target.rotation)

    def to_dict(self) -> dict:
        """Plain data (the rotation as a matrix)."""
        out = {
            "frame": self.frame,
            "frame_type": self.frame_type.value,
            "position": self.target.position.tolist(),
        }
        if self.target.rotation is not None:
            out["matrix"] = self.target.rotation.tolist()
        return out


@dataclass(frozen=True)
class Goal:
    """A goal of the problem: one or several frames reached together.

    Attributes:
        frames: the frames and their targets, in file order.
        field: where it sits in the file (``target``, ``waypoints[2]``).
    """

    frames: tuple[FrameGoal, ...]
    field: str

    @property
    def frame(self) -> str:
        """The first frame's name (the goal frame of a one-frame goal)."""
        return self.frames[0].frame

    @property
    def frame_type(self) -> FrameType:
        """The first frame's type."""
        return self.frames[0].frame_type

    @property
    def target(self) -> Target:
        """The first frame's target."""
        return self.frames[0].target

    def targets(self) -> dict[FrameKey, Target]:
        """``{(frame, frame_type): target}``, what :func:`qpik.solve` takes."""
        return {(f.frame, f.frame_type.value): f.target for f in self.frames}

    def errors(self, configuration: Configuration) -> list[tuple[float, float]]:
        """Per frame, ``(position error [m], orientation error [rad])``."""
        return [f.error(configuration) for f in self.frames]

    def worst_error(self, configuration: Configuration) -> tuple[float, float]:
        """The largest position error [m] and orientation error [rad] over the frames."""
        errors = self.errors(configuration)
        return max(p for p, _ in errors), max(o for _, o in errors)

    def to_dict(self) -> dict:
        """Plain data: ``{"frames": [...]}``, plus the first frame's fields at the top."""
        return {**self.frames[0].to_dict(), "frames": [f.to_dict() for f in self.frames]}


def read_goals(
    reader: Reader, data: dict, model: mujoco.MjModel, levels: list[list[TaskSpec]]
) -> list[Goal]:
    """The ``[target]`` (one goal) or the ``[[waypoints]]`` (goals in order)."""
    if ("target" in data) == ("waypoints" in data):
        raise reader.fail(
            "target",
            "exactly one of a [target] table or a list of [[waypoints]]"
            + (" (both given)" if "target" in data else ""),
        )
    if "target" in data:
        return [read_goal(reader, data["target"], "target", model, levels)]
    waypoints = reader.get(data, "waypoints", "", list, "a list of [[waypoints]] tables")
    if not waypoints:
        raise reader.fail("waypoints", "expected at least one waypoint")
    return [read_goal(reader, w, f"waypoints[{i}]", model, levels) for i, w in enumerate(waypoints)]


def read_goal(
    reader: Reader, table, where: str, model: mujoco.MjModel, levels: list[list[TaskSpec]]
) -> Goal:
    """One goal table: a frame (its fields at the top) or ``frames = [...]``."""
    if not isinstance(table, dict):
        raise reader.fail(where, f"expected a table, got {describe(table)}")
    if "frames" not in table:
        return Goal((_read_frame_goal(reader, table, where, model, levels),), where)
    reader.unknown_keys(table, {"frames"}, where)
    raw = reader.get(table, "frames", where, list, "a list of frame tables ([[...frames]])")
    if not raw:
        raise reader.fail(f"{where}.frames", "expected at least one frame")
    frames = []
    for i, item in enumerate(raw):
        fwhere = dotted(f"{where}.frames", i)
        if not isinstance(item, dict):
            raise reader.fail(fwhere, f"expected a table, got {describe(item)}")
        frames.append(_read_frame_goal(reader, item, fwhere, model, levels))
        if any(f.frame == frames[-1].frame for f in frames[:-1]):
            raise reader.fail(f"{fwhere}.frame", f"a frame not already in {where}.frames")
    return Goal(tuple(frames), where)


def _read_frame_goal(
    reader: Reader, table: dict, where: str, model: mujoco.MjModel, levels: list[list[TaskSpec]]
) -> FrameGoal:
    reader.unknown_keys(table, _FRAME_FIELDS, where)
    if "frame" in table:
        frame, kind = reader.frame(table, where, model)
    else:
        first = next((s for s in levels[0] if s.kind.goal), None)
        if first is None:
            raise reader.fail(
                f"{where}.frame",
                "missing; expected a frame name (level 0 has no frame, position or "
                "orientation task to take it from)",
            )
        assert first.frame is not None  # a goal kind has a frame
        frame, kind = first.frame, first.frame_type
    position = reader.position(table, "position", where)
    rotation = reader.rotation(table, where)
    regulating = [
        s
        for level in levels
        for s in level
        if s.kind.goal and s.frame == frame and s.frame_type == kind
    ]
    if not regulating:
        raise reader.fail(
            f"{where}.frame",
            f"a frame regulated by a frame, position or orientation task; no task regulates "
            f"the {kind.value} {frame!r}",
        )
    types = {s.type for s in regulating}
    if not types & {"frame", "position"}:
        raise reader.fail(
            f"{where}.position",
            f"a position no task steers: only an orientation task regulates {frame!r} (its "
            "position would be measured, never reached); regulate it with a frame task",
        )
    if rotation is not None and not types & {"frame", "orientation"}:
        raise reader.fail(
            f"{where}.rpy",
            f"a rotation no task steers: only a position task regulates {frame!r} (it would "
            "be measured, never reached); drop it, or regulate the frame with a frame task",
        )
    if rotation is None and any(s.type == "frame" for s in regulating):
        raise reader.fail(
            f"{where}.rpy",
            f"missing; a frame task regulates {frame!r}, so the goal needs a rotation "
            f"({', '.join(ROTATION_KEYS)}), or use a position task",
        )
    return FrameGoal(frame, kind, Target(position, rotation), where)
