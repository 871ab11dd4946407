"""Task specs of a problem file and the registry of task builders.

A task type is one :class:`TaskKind` entry of :data:`TASK_KINDS`: the fields it takes
(frame, costs, gain and damping, extra options, target keys) and a builder that makes the
task object from a validated :class:`TaskSpec`. Adding a task type is adding one entry.

Targets a file leaves out hold the start value (the frame's start pose, the start
posture, the start centre of mass). Positions [m] and rotations are in the world frame.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import mink
import mujoco
import numpy as np

from ..model.configuration import Configuration, FrameType
from ..tasks import (
    BaseTask,
    ComTask,
    DampingTask,
    FrameTask,
    JointLimitDistanceTask,
    ManipulabilityTask,
    OrientationTask,
    PositionTask,
    PostureTask,
)
from .reader import ROTATION_KEYS, Reader, describe, dotted


@dataclass
class TaskSpec:
    """One task of a problem file, validated; :meth:`build` makes a fresh task object.

    Attributes:
        type: a key of :data:`TASK_KINDS`.
        field: where it sits in the file (``levels[0].tasks[1]``), for messages.
        options: constructor arguments (costs, gain, ...).
        frame, frame_type: the regulated frame (tasks with a frame only).
        position: target position ``(3,)`` [m, world], or None (frame, position, com).
        rotation: target rotation ``(3, 3)`` (world), or None (frame, orientation).
        posture: posture target ``(nq,)`` (posture tasks), or None.
    """

    type: str
    field: str
    options: dict[str, Any]
    frame: str | None = None
    frame_type: FrameType = FrameType.SITE
    position: np.ndarray | None = None
    rotation: np.ndarray | None = None
    posture: np.ndarray | None = None

    @property
    def kind(self) -> TaskKind:
        """The registry entry of :attr:`type`."""
        return TASK_KINDS[self.type]

    def build(self, model: mujoco.MjModel, start: Configuration) -> BaseTask:
        """A new task object with its target set (start values where none was given)."""
        return self.kind.build(self, model, start)

    def label(self) -> str:
        """A short name for figures and reports: ``position gripper_left_base_link``."""
        return self.type if self.frame is None else f"{self.type} {self.frame}"

    def to_dict(self) -> dict:
        """Plain data (rotations as matrices)."""
        out: dict[str, Any] = {"type": self.type}
        if self.frame is not None:
            out["frame"], out["frame_type"] = self.frame, self.frame_type.value
        out.update(
            {k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in self.options.items()}
        )
        target = {
            key: value.tolist()
            for key, value in (
                ("position", self.position),
                ("matrix", self.rotation),
                ("q", self.posture),
            )
            if value is not None
        }
        if target:
            out["target"] = target
        return out


# ----------------------------------------------------------------------- builders
def _build_frame(spec: TaskSpec, model: mujoco.MjModel, start: Configuration) -> BaseTask:
    assert spec.frame is not None  # a kind with a frame: the reader set it
    task = FrameTask(spec.frame, spec.frame_type.value, **spec.options)
    position, rotation = start.frame_pose(spec.frame, spec.frame_type)
    position = position if spec.position is None else spec.position
    rotation = rotation if spec.rotation is None else spec.rotation
    task.set_target(
        mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), position)
    )
    return task


def _build_position(spec: TaskSpec, model: mujoco.MjModel, start: Configuration) -> BaseTask:
    assert spec.frame is not None  # a kind with a frame: the reader set it
    task = PositionTask(spec.frame, spec.frame_type, **spec.options)
    _target_or_start(task, spec.position, start)
    return task


def _build_orientation(spec: TaskSpec, model: mujoco.MjModel, start: Configuration) -> BaseTask:
    assert spec.frame is not None  # a kind with a frame: the reader set it
    task = OrientationTask(spec.frame, spec.frame_type, **spec.options)
    _target_or_start(task, spec.rotation, start)
    return task


def _build_com(spec: TaskSpec, model: mujoco.MjModel, start: Configuration) -> BaseTask:
    task = ComTask(**spec.options)
    _target_or_start(task, spec.position, start)
    return task


def _build_posture(spec: TaskSpec, model: mujoco.MjModel, start: Configuration) -> BaseTask:
    task = PostureTask(model, **spec.options)
    task.set_target(start.q if spec.posture is None else spec.posture)
    return task


def _target_or_start(task, target: np.ndarray | None, start: Configuration) -> None:
    if target is None:
        task.set_target_from_configuration(start)
    else:
        task.set_target(target)


# ----------------------------------------------------------------------- registry
#: Size of a cost vector: 3 (x, y, z), ``"nv"`` (one per dof) or None (a number only).
CostSize = int | Literal["nv"] | None


@dataclass(frozen=True)
class TaskKind:
    """How a task type is read from a file and built.

    Attributes:
        cls: the task class (for docs and :data:`TASK_TYPES`).
        build: ``(spec, model, start) -> task``, the target set.
        frame: whether the task regulates a frame (``frame``, ``frame_type``).
        goal: whether a goal may name that frame (the task then receives the goal).
        costs: ``(field, size, default)`` per cost field.
        options: the numeric options it takes (keys of :data:`qpik.problem.reader.RANGES`).
        target: keys of its ``target`` table: ``position``, ``rotation`` (one of ``rpy``,
            ``quaternion``, ``matrix``), ``q``; each required when the table is given.
        choices: string options ``{field: (allowed values, default)}``.
    """

    cls: type
    build: Callable[[TaskSpec, mujoco.MjModel, Configuration], BaseTask]
    frame: bool = False
    goal: bool = False
    costs: tuple[tuple[str, CostSize, float], ...] = (("cost", None, 1.0),)
    options: tuple[str, ...] = ("gain", "lm_damping")
    target: tuple[str, ...] = ()
    choices: dict[str, tuple[tuple[str, ...], str]] = field(default_factory=dict)

    def fields(self) -> set[str]:
        """Every field a task table of this kind may hold."""
        names = {"type", *self.options, *self.choices, *(c[0] for c in self.costs)}
        if self.frame:
            names |= {"frame", "frame_type"}
        if self.target:
            names.add("target")
        return names

    def target_fields(self) -> set[str]:
        """The keys its ``target`` table may hold."""
        keys = set(self.target) - {"rotation"}
        return keys | set(ROTATION_KEYS) if "rotation" in self.target else keys


def _simple(cls: type) -> Callable[[TaskSpec, mujoco.MjModel, Configuration], BaseTask]:
    """A builder for a task class taking only its options (no frame, model, target)."""
    return lambda spec, model, start: cls(**spec.options)


def _with_model(cls: type) -> Callable[[TaskSpec, mujoco.MjModel, Configuration], BaseTask]:
    """A builder for a task class taking the model and its options."""
    return lambda spec, model, start: cls(model, **spec.options)


def _with_frame(cls: type) -> Callable[[TaskSpec, mujoco.MjModel, Configuration], BaseTask]:
    """A builder for a task class taking its frame and its options, no target."""
    return lambda spec, model, start: cls(spec.frame, spec.frame_type, **spec.options)


_XYZ = (("cost", 3, 1.0),)

#: The task types a problem file may use, by name.
TASK_KINDS: dict[str, TaskKind] = {
    "frame": TaskKind(
        FrameTask,
        _build_frame,
        frame=True,
        goal=True,
        costs=(("position_cost", 3, 1.0), ("orientation_cost", 3, 1.0)),
        target=("position", "rotation"),
    ),
    "position": TaskKind(
        PositionTask, _build_position, frame=True, goal=True, costs=_XYZ, target=("position",)
    ),
    "orientation": TaskKind(
        OrientationTask,
        _build_orientation,
        frame=True,
        goal=True,
        costs=_XYZ,
        target=("rotation",),
    ),
    "posture": TaskKind(PostureTask, _build_posture, costs=(("cost", "nv", 1.0),), target=("q",)),
    "joint_limit_distance": TaskKind(JointLimitDistanceTask, _simple(JointLimitDistanceTask)),
    "manipulability": TaskKind(
        ManipulabilityTask,
        _with_frame(ManipulabilityTask),
        frame=True,
        options=("gain",),
        choices={"rows": (("pose", "position"), "pose")},
    ),
    "damping": TaskKind(
        DampingTask, _with_model(DampingTask), costs=(("cost", "nv", 1e-3),), options=()
    ),
    "com": TaskKind(ComTask, _build_com, costs=_XYZ, target=("position",)),
}

#: Task types a problem file may use, with the class each maps to.
TASK_TYPES: dict[str, type] = {name: kind.cls for name, kind in TASK_KINDS.items()}


# ----------------------------------------------------------------------- reading
def read_levels(
    reader: Reader, data: dict, model: mujoco.MjModel, start: Configuration
) -> list[list[TaskSpec]]:
    """The ``levels`` of a file, level 0 first: ``[[levels]]`` tables with ``tasks``, or
    the inline form ``levels = [[{...}], [{...}]]``."""
    raw = reader.get(data, "levels", "", list, "a list of levels ([[levels]] tables with tasks)")
    if not raw:
        raise reader.fail("levels", "expected at least one level")
    levels = []
    for i, level in enumerate(raw):
        where = f"levels[{i}]"
        if isinstance(level, dict):
            reader.unknown_keys(level, {"name", "tasks"}, where)
            reader.get(level, "name", where, str, "a level name (a string)", "")
            tasks = reader.get(level, "tasks", where, list, "a list of tasks ([[levels.tasks]])")
            where = f"{where}.tasks"
        elif isinstance(level, list):
            tasks = level
        else:
            raise reader.fail(where, f"expected a table with tasks, got {describe(level)}")
        if not tasks:
            raise reader.fail(where, "expected at least one task")
        levels.append(
            [read_task(reader, t, dotted(where, j), model, start) for j, t in enumerate(tasks)]
        )
    return levels


def read_task(
    reader: Reader, table, where: str, model: mujoco.MjModel, start: Configuration
) -> TaskSpec:
    """One task table, checked against its :class:`TaskKind`."""
    if not isinstance(table, dict):
        raise reader.fail(where, f"expected a task table, got {describe(table)}")
    known = ", ".join(TASK_KINDS)
    name = reader.get(table, "type", where, str, f"a task type, one of: {known}")
    if name not in TASK_KINDS:
        raise reader.fail(f"{where}.type", f"unknown task type {name!r}; known types: {known}")
    kind = TASK_KINDS[name]
    reader.unknown_keys(table, kind.fields(), where)
    spec = TaskSpec(type=name, field=where, options={})
    if kind.frame:
        spec.frame, spec.frame_type = reader.frame(table, where, model)
    for option in kind.options:
        if option in table:
            value = reader.number(table[option], f"{where}.{option}", option)
            spec.options[option] = float(value)
    for cost, size, default in kind.costs:
        length = model.nv if size == "nv" else size
        spec.options[cost] = reader.cost(table, cost, where, length, default)
    for option, (allowed, choice_default) in kind.choices.items():
        value = reader.get(
            table, option, where, str, " or ".join(map(repr, allowed)), choice_default
        )
        if value not in allowed:
            raise reader.fail(
                f"{where}.{option}", f"expected {' or '.join(map(repr, allowed))}, got {value!r}"
            )
        spec.options[option] = value
    if "target" in table:
        _read_task_target(reader, table, where, kind, spec, model, start)
    return spec


def _read_task_target(
    reader: Reader,
    table: dict,
    where: str,
    kind: TaskKind,
    spec: TaskSpec,
    model: mujoco.MjModel,
    start: Configuration,
) -> None:
    """Fill ``spec``'s target from ``table["target"]``; each key of the kind is required."""
    target = reader.table(table, "target", where, kind.target_fields(), "a target table")
    twhere = f"{where}.target"
    if "q" in kind.target:
        value = reader.get(target, "q", twhere, (list, str), "a configuration")
        spec.posture = reader.configuration(value, f"{twhere}.q", model, start, allow_start=True)
    if "position" in kind.target:
        spec.position = reader.position(target, "position", twhere)
    if "rotation" in kind.target:
        spec.rotation = reader.rotation(target, twhere)
        if spec.rotation is None:
            raise reader.fail(
                f"{twhere}.rpy", f"missing; expected one of {', '.join(ROTATION_KEYS)}"
            )
