r"""IK problem files: a robot, a task stack, limits, solver options and goals, in TOML.

:func:`load_problem` reads and validates a file; :meth:`Problem.solve` runs it and returns
a :class:`ProblemResult`. Every error in a file raises :class:`qpik.ProblemFileError`,
which names the file, the field (dotted, e.g. ``levels[0].tasks[1].type``) and what was
expected. The shipped examples live in the repository's ``tasks/`` folder.

Schema (units: metres, radians, seconds; positions and rotations in the world frame)::

    name = "panda_pose_reach"          # optional, default: the file's stem
    description = "..."                # optional
    robot = "panda"                    # bundled name (qpik robots), "erd:NAME", or a path
                                       # to an .xml/.urdf file relative to this file
    q0 = "home"                        # start: a list of nq numbers, "mid" (default),
                                       # "qpos0", or a keyframe name of the model ("home")
    mode = "solve"                     # "solve" (default): qpik.solve per goal (the IGM);
                                       # "track": differential IK steps with IKSolver

    [[levels]]                         # level 0: the highest priority
    [[levels.tasks]]
    type = "frame"                     # one of TASK_TYPES (below)
    frame = "ee"                       # frame name (frame, position, orientation,
    frame_type = "site"                #   manipulability); site (default), body or geom;
                                       #   both left out: the robot's tool frame
                                       #   (qpik.robots.tool_frame)
    position_cost = 1.0                # frame tasks: position_cost, orientation_cost;
    orientation_cost = 1.0             #   other tasks: cost (a number or a list)
    gain = 1.0                         # in (0, 1]; optional
    target = { position = [0.5, 0.2, 0.4], rpy = [3.14159, 0, 0] }   # optional

    [[levels]]                         # level 1: acts in the null space of level 0
    [[levels.tasks]]
    type = "posture"
    cost = 0.01
    target = { q = "home" }            # posture target: q list, "start" (default), "mid",
                                       # "qpos0" or a keyframe name

    [target]                           # the goal: exactly one of [target] / [[waypoints]]
    frame = "ee"                       # default: the frame of the first task of level 0
    position = [0.5, 0.2, 0.4]         # required
    rpy = [3.14159, 0.0, 0.785398]     # optional rotation (see below)

    [limits]
    position = true                    # joint position limits (default true)
    velocity = 0.5                     # false / absent: none; a number: that fraction of
                                       # the model's velocity_limit; a list of nv values
                                       # [rad/s]; or a table {joint = value}

    [solver]                           # all optional; defaults are qpik.solve's
    solver = "osqp"                    # QP backend
    tol_position = 1e-4                # [m]
    tol_orientation = 1e-3             # [rad]
    max_iters = 100                    # per attempt (solve mode)
    restarts = 20                      # random restarts (solve mode)
    seed = 0
    time_budget = 1.0                  # [s] per goal (solve mode)
    alpha = 1.0                        # gain of the goal tasks (solve mode)
    beta = 1.0                         # step scale (solve mode)
    max_step = [0.2, 0.5]              # trust region [m, rad], or false (solve mode)
    singular_threshold = 0.05          # adaptive damping (DampingLaw), both modes
    max_damping = 0.05                 #   (adaptive_damping = false switches it off)
    damping = 1e-6                     # constant Tikhonov term, both modes

    [track]                            # mode = "track" only
    dt = 0.01                          # [s] per step
    steps = 300                        # steps per goal
    stop_at_goal = false               # stop a goal's steps once within tolerance

    [statics]                          # optional: statics at the final configuration
    frame = "ee"                       # default: the goal frame
    force = [0, 0, -20]                # [N], world axes, on the robot at the frame origin
    torque = [0, 0, 0]                 # [N m], optional
    payload_direction = [0, 0, -1]     # optional: max_payload along this direction

Task types (:data:`TASK_TYPES`) and their classes: ``frame`` (:class:`mink.FrameTask`,
6 rows, error in the frame's local axes), ``position`` / ``orientation``
(:class:`qpik.tasks.PositionTask` / :class:`~qpik.tasks.OrientationTask`, 3 world-aligned
rows), ``posture`` (:class:`mink.PostureTask`), ``joint_limit_distance``
(:class:`~qpik.tasks.JointLimitDistanceTask`), ``manipulability``
(:class:`~qpik.tasks.ManipulabilityTask`, with ``rows = "pose" | "position"``),
``damping`` (:class:`mink.DampingTask`) and ``com`` (:class:`mink.ComTask`, target
``position``). A task target left out holds the start value (the frame's start pose, the
start posture, the start centre of mass); a task on the goal frame gets the goal.

Rotations: ``rpy = [roll, pitch, yaw]`` [rad], extrinsic x-y-z, ``R = Rz(yaw) Ry(pitch)
Rx(roll)``; or ``quaternion = [w, x, y, z]`` (MuJoCo's order, normalised on load); or
``matrix = [[r00, r01, r02], [r10, r11, r12], [r20, r21, r22]]`` (rows). At most one.

Numbers are range-checked on load (:data:`RANGES`): every number must be finite;
positions, centre-of-mass targets and joint values within +-:data:`MAX_LENGTH`, ``rpy``
angles within +-:data:`MAX_ANGLE` rad, costs in [0, :data:`MAX_COST`], forces and torques
within +-:data:`MAX_WRENCH`, and each ``[solver]`` / ``[track]`` / task option within its
interval (e.g. ``gain`` in (0, 1], ``lm_damping`` in [0, 1e6], ``time_budget`` in
(0, 86400] s, ``seed`` in [0, 2^63 - 1], ``track.steps`` in [1, 1e6]). A ``q0`` outside a
joint limit by at most 1e-6 (the tolerance of :meth:`qpik.Configuration.check_limits`) is
clamped onto it. The file must be UTF-8 (a byte-order mark is allowed).

Modes. ``solve``: each goal (the target, or each waypoint in turn, from the previous
result) is one :func:`qpik.solve` with ``stack`` = the levels; in a solve the gain of the
level-0 position and orientation tasks on the goal frame is the solver's ``alpha``.
``track``: :class:`qpik.IKSolver` steps of ``dt`` from ``q0`` toward each goal in turn,
``steps`` steps each, under the limits (a velocity limit bounds each step to
``v_max dt``); the result is a :class:`TrackTrace`. Either way the problem has converged
when the final configuration of every goal is within ``tol_position`` and
``tol_orientation`` of it.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mink
import mujoco
import numpy as np

from . import statics as _statics
from .configuration import Configuration, FrameType, frame_names, joint_names
from .converge import IGM_DAMPING, IKResult, Target, set_frame_target, solve
from .errors import ProblemFileError, QpikError, UnknownFrame, UnknownRobot
from .hierarchy import DampingLaw, IKSolver
from .limits import ConfigurationLimit, VelocityLimit
from .robots import list_robots, load_robot, tool_frame
from .tasks import (
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

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "TASK_TYPES",
    "Goal",
    "Problem",
    "ProblemResult",
    "StaticsReport",
    "TaskSpec",
    "TrackTrace",
    "load_problem",
    "problem_files",
]

#: Task types a problem file may use, with the class each maps to.
TASK_TYPES = {
    "frame": FrameTask,
    "position": PositionTask,
    "orientation": OrientationTask,
    "posture": PostureTask,
    "joint_limit_distance": JointLimitDistanceTask,
    "manipulability": ManipulabilityTask,
    "damping": DampingTask,
    "com": ComTask,
}
_FRAME_TASKS = ("frame", "position", "orientation", "manipulability")
_GOAL_TASKS = ("frame", "position", "orientation")
_TOP_KEYS = {
    "name",
    "description",
    "robot",
    "q0",
    "mode",
    "levels",
    "target",
    "waypoints",
    "limits",
    "solver",
    "track",
    "statics",
}
_SOLVER_KEYS = {
    "solver": str,
    "tol_position": float,
    "tol_orientation": float,
    "max_iters": int,
    "restarts": int,
    "seed": int,
    "time_budget": float,
    "alpha": float,
    "beta": float,
    "max_step": list,
    "singular_threshold": float,
    "max_damping": float,
    "adaptive_damping": bool,
    "damping": float,
    "stall_window": int,
}
_ROTATION_KEYS = ("rpy", "quaternion", "matrix")

#: Largest magnitude of a length [m] (target positions, centre of mass, joint values in a
#: posture or q0 [rad or m]) a file may give: beyond it a squared error overflows.
MAX_LENGTH = 1e6
#: Largest magnitude of an angle [rad] in ``rpy``.
MAX_ANGLE = 100.0
#: Largest task cost or weight: the QP holds its square next to unit-scale terms.
MAX_COST = 1e6
#: Largest force [N] or torque [N m] of a ``[statics]`` table.
MAX_WRENCH = 1e9

#: Allowed range ``(low, high)`` of every number of ``[solver]``, ``[track]`` and the task
#: options, inclusive (``low_open``: ``low`` itself excluded).
RANGES: dict[str, tuple[float, float, bool]] = {
    "solver.tol_position": (1e-12, 1e3, False),  # [m]
    "solver.tol_orientation": (1e-12, math.pi, False),  # [rad]
    "solver.max_iters": (1, 100_000, False),
    "solver.restarts": (0, 100_000, False),
    "solver.seed": (0, 2**63 - 1, False),
    "solver.time_budget": (0.0, 86_400.0, True),  # [s]
    "solver.alpha": (0.0, 1.0, True),
    "solver.beta": (0.0, 100.0, True),
    "solver.max_step": (0.0, MAX_LENGTH, True),  # [m, rad]
    "solver.singular_threshold": (0.0, 1e3, False),
    "solver.max_damping": (0.0, 1e6, False),
    "solver.damping": (0.0, 1e6, False),
    "solver.stall_window": (1, 100_000, False),
    "track.dt": (1e-9, 1e3, False),  # [s]
    "track.steps": (1, 1_000_000, False),
    "gain": (0.0, 1.0, True),
    "lm_damping": (0.0, 1e6, False),
    "velocity": (1e-9, 1e6, False),  # [rad/s or m/s]
}


def problem_files() -> list[Path]:
    """The shipped problem files (the repository's ``tasks/*.toml``, or the installed
    copy), sorted."""
    from importlib import resources

    packaged = Path(str(resources.files("qpik"))) / "_tasks"
    folder = packaged if packaged.is_dir() else Path(__file__).resolve().parent.parent / "tasks"
    return sorted(folder.glob("*.toml"))


# ----------------------------------------------------------------------------- reading
class _Reader:
    """Typed access to a parsed TOML table; every failure is a ProblemFileError naming
    the field."""

    def __init__(self, path: str):
        self.path = path

    def fail(self, field_name: str, expected: str) -> ProblemFileError:
        return ProblemFileError(self.path, field_name, expected)

    def get(self, table: dict, key: str, where: str, kind, expected: str, default=...):
        name = f"{where}.{key}" if where else key
        if key not in table:
            if default is ...:
                raise self.fail(name, f"missing; expected {expected}")
            return default
        value = table[key]
        if kind is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if kind in (int, float) and isinstance(value, bool):
            raise self.fail(name, f"expected {expected}, got {value!r}")
        if not isinstance(value, kind):
            raise self.fail(name, f"expected {expected}, got {_describe(value)}")
        return value

    def vector(self, value, name: str, size: int | None, expected: str) -> np.ndarray:
        if not isinstance(value, list) or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) for x in value
        ):
            raise self.fail(name, f"expected {expected}, got {_describe(value)}")
        array = np.asarray(value, dtype=float)
        if size is not None and array.shape != (size,):
            raise self.fail(name, f"expected {expected}, got {len(value)} numbers")
        if not np.all(np.isfinite(array)):
            raise self.fail(name, f"expected {expected} (finite), got {value!r}")
        return array

    def number(self, value, name: str, rule: str, expected: str | None = None) -> float:
        """Check a number against :data:`RANGES` ``[rule]``: finite, within the range."""
        low, high, low_open = RANGES[rule]
        interval = f"{'(' if low_open else '['}{low:g}, {high:g}]"
        expected = f"{expected or 'a number'} in {interval}"
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(name, f"expected {expected}, got {_describe(value)}")
        finite = isinstance(value, int) or math.isfinite(value)  # ints: no float overflow
        ok = finite and (value > low if low_open else value >= low) and value <= high
        if not ok:
            raise self.fail(name, f"expected {expected}, got {value!r}")
        return value

    def bounded_vector(
        self, value, name: str, size: int | None, expected: str, bound: float
    ) -> np.ndarray:
        """:meth:`vector` whose entries are at most ``bound`` in magnitude."""
        array = self.vector(value, name, size, expected)
        big = np.flatnonzero(np.abs(array) > bound)
        if big.size:
            i = int(big[0])
            raise self.fail(
                name, f"expected {expected}, each within [-{bound:g}, {bound:g}]; "
                f"entry {i} is {array[i]!r}"
            )
        return array

    def unknown_keys(self, table: dict, allowed, where: str) -> None:
        for key in table:
            if key not in allowed:
                name = f"{where}.{key}" if where else key
                raise self.fail(
                    name, f"unknown field; expected one of: {', '.join(sorted(allowed))}"
                )


def _describe(value) -> str:
    kind = {
        bool: "a boolean",
        int: "an integer",
        float: "a number",
        str: "a string",
        list: "a list",
        dict: "a table",
    }.get(type(value), type(value).__name__)
    text = repr(value)
    return f"{kind} ({text if len(text) <= 40 else text[:37] + '...'})"


def _rotation_from(reader: _Reader, table: dict, where: str) -> np.ndarray | None:
    """The rotation matrix of ``rpy`` / ``quaternion`` / ``matrix`` in ``table``, if any."""
    given = [k for k in _ROTATION_KEYS if k in table]
    if len(given) > 1:
        raise reader.fail(f"{where}.{given[1]}", f"give at most one of {', '.join(_ROTATION_KEYS)}")
    if not given:
        return None
    key = given[0]
    name = f"{where}.{key}"
    if key == "rpy":
        roll, pitch, yaw = reader.bounded_vector(
            table[key], name, 3, "[roll, pitch, yaw] in radians", MAX_ANGLE
        )
        return _rz(yaw) @ _ry(pitch) @ _rx(roll)
    if key == "quaternion":
        quat = reader.vector(table[key], name, 4, "[w, x, y, z] (nonzero)")
        scale = float(np.max(np.abs(quat)))
        if scale > 0.0:  # scaled first: the norm of [1e300, ...] would overflow
            quat = quat / scale
        norm = float(np.linalg.norm(quat))
        if scale == 0.0 or norm * scale < 1e-9:
            raise reader.fail(name, "expected a nonzero quaternion [w, x, y, z]")
        rotation = np.zeros(9)
        mujoco.mju_quat2Mat(rotation, quat / norm)
        return rotation.reshape(3, 3)
    rows = table[key]
    if not isinstance(rows, list) or len(rows) != 3:
        raise reader.fail(name, f"expected 3 rows of 3 numbers, got {_describe(rows)}")
    matrix = np.array(
        [reader.vector(r, f"{name}[{i}]", 3, "3 numbers") for i, r in enumerate(rows)]
    )
    if not np.allclose(matrix @ matrix.T, np.eye(3), atol=1e-6) or np.linalg.det(matrix) < 0:
        raise reader.fail(name, "expected a rotation matrix (R R^T = I, det R = +1)")
    return matrix


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# ----------------------------------------------------------------------------- spec
@dataclass
class TaskSpec:
    """One task of a problem file, validated; :meth:`build` makes a fresh task object.

    Attributes:
        type: one of :data:`TASK_TYPES`.
        field: where it sits in the file (``levels[0].tasks[1]``), for messages.
        options: constructor arguments (costs, gain, ...).
        frame, frame_type: the regulated frame (frame tasks only).
        position, rotation: target (frame, position, orientation, com tasks), or None.
        posture: posture target ``(nq,)`` (posture tasks).
    """

    type: str
    field: str
    options: dict[str, Any]
    frame: str | None = None
    frame_type: FrameType = FrameType.SITE
    position: np.ndarray | None = None
    rotation: np.ndarray | None = None
    posture: np.ndarray | None = None

    def build(self, model: mujoco.MjModel, start: Configuration) -> BaseTask:
        """A new task object with its target set (start values where none was given)."""
        kind = self.type
        o = self.options
        if kind == "frame":
            task = FrameTask(self.frame, self.frame_type.value, **o)
            position, rotation = start.frame_pose(self.frame, self.frame_type)
            position = position if self.position is None else self.position
            rotation = rotation if self.rotation is None else self.rotation
            task.set_target(
                mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), position)
            )
        elif kind == "position":
            task = PositionTask(self.frame, self.frame_type, **o)
            if self.position is None:
                task.set_target_from_configuration(start)
            else:
                task.set_target(self.position)
        elif kind == "orientation":
            task = OrientationTask(self.frame, self.frame_type, **o)
            if self.rotation is None:
                task.set_target_from_configuration(start)
            else:
                task.set_target(self.rotation)
        elif kind == "manipulability":
            task = ManipulabilityTask(self.frame, self.frame_type, **o)
        elif kind == "posture":
            task = PostureTask(model, **o)
            task.set_target(start.q if self.posture is None else self.posture)
        elif kind == "joint_limit_distance":
            task = JointLimitDistanceTask(**o)
        elif kind == "damping":
            task = DampingTask(model, **o)
        else:  # com
            task = ComTask(**o)
            if self.position is None:
                task.set_target_from_configuration(start)
            else:
                task.set_target(self.position)
        return task

    def to_dict(self) -> dict:
        out: dict[str, Any] = {"type": self.type}
        if self.frame is not None:
            out["frame"], out["frame_type"] = self.frame, self.frame_type.value
        out.update({k: _jsonable(v) for k, v in self.options.items()})
        target = {}
        if self.position is not None:
            target["position"] = self.position.tolist()
        if self.rotation is not None:
            target["matrix"] = self.rotation.tolist()
        if self.posture is not None:
            target["q"] = self.posture.tolist()
        if target:
            out["target"] = target
        return out


@dataclass
class Goal:
    """A goal of the problem: a frame and its target (position [m], optional rotation)."""

    frame: str
    frame_type: FrameType
    target: Target
    field: str

    def to_dict(self) -> dict:
        out = {
            "frame": self.frame,
            "frame_type": self.frame_type.value,
            "position": self.target.position.tolist(),
        }
        if self.target.rotation is not None:
            out["matrix"] = self.target.rotation.tolist()
        return out


@dataclass
class Problem:
    """A validated IK problem (see the module docstring for the file schema).

    Attributes:
        path: the file it was read from.
        name, description: from the file.
        robot: the ``robot`` field as written; ``model``: the loaded model.
        q0: start configuration ``(nq,)``.
        levels: task specs, level 0 first.
        position_limits: whether joint position limits hold.
        velocity_limits: per-dof velocity limits ``(nv,)`` [rad/s or m/s], or None.
        options: the ``[solver]`` table, validated.
        mode: ``"solve"`` or ``"track"``.
        goals: the target, or the waypoints in order.
        dt, steps, stop_at_goal: tracking settings (track mode).
        statics: the ``[statics]`` table, validated, or None.
    """

    path: str
    name: str
    description: str
    robot: str
    model: mujoco.MjModel = field(repr=False)
    q0: np.ndarray
    levels: list[list[TaskSpec]]
    position_limits: bool
    velocity_limits: np.ndarray | None
    options: dict[str, Any]
    mode: str
    goals: list[Goal]
    dt: float = 0.01
    steps: int = 0
    stop_at_goal: bool = False
    statics: dict[str, Any] | None = None

    # ------------------------------------------------------------------ building
    def start_configuration(self) -> Configuration:
        """A new configuration at ``q0``."""
        return Configuration(self.model, self.q0)

    def build_stack(self, start: Configuration | None = None) -> list[list]:
        """Fresh task objects, level 0 first (targets set; the goal frame's tasks get the
        first goal)."""
        start = start if start is not None else self.start_configuration()
        levels = [[spec.build(self.model, start) for spec in level] for level in self.levels]
        set_frame_target(levels, self.goals[0].frame, self.goals[0].target)
        return levels

    def build_limits(self) -> list:
        """The limits of the problem: position limits, then velocity limits."""
        limits: list = []
        if self.position_limits:
            limits.append(ConfigurationLimit(self.model))
        if self.velocity_limits is not None:
            names = joint_names(self.model)
            velocities = {
                names[self.model.dof_jntid[i]]: float(v)
                for i, v in enumerate(self.velocity_limits)
                if np.isfinite(v)
            }
            limits.append(VelocityLimit(self.model, velocities))
        return limits

    def damping_law(self) -> DampingLaw | None:
        """The adaptive damping of the file (the IGM's error-faded law in solve mode)."""
        o = self.options
        if not o.get("adaptive_damping", True):
            return None
        base = IGM_DAMPING if self.mode == "solve" else DampingLaw()
        return DampingLaw(
            singular_threshold=o.get("singular_threshold", base.singular_threshold),
            max_damping=o.get("max_damping", base.max_damping),
            error_scale=base.error_scale,
        )

    # ------------------------------------------------------------------ solving
    def solve(self) -> ProblemResult:
        """Solve every goal in turn (see the module docstring for the two modes)."""
        start_time = time.perf_counter()
        if self.mode == "track":
            trace = self._track()
            results: list[IKResult] = []
            final_q = trace.q[-1]
            converged, reason = trace.converged, trace.reason
        else:
            trace = None
            results = self._solve_goals()
            final_q = results[-1].q
            converged = all(r.converged for r in results)
            failed = [i for i, r in enumerate(results) if not r.converged]
            reason = "converged"
            if failed:
                first = results[failed[0]]
                where = "target" if len(self.goals) == 1 else f"waypoint {failed[0]}"
                reason = f"{where}: {first.reason}"
        report = self._statics(final_q) if self.statics is not None else None
        return ProblemResult(
            problem=self,
            converged=converged,
            reason=reason,
            results=results,
            trace=trace,
            statics=report,
            solve_time=time.perf_counter() - start_time,
        )

    def _solve_goals(self) -> list[IKResult]:
        o = self.options
        kwargs: dict[str, Any] = {
            k: o[k]
            for k in (
                "solver",
                "tol_position",
                "tol_orientation",
                "max_iters",
                "restarts",
                "seed",
                "time_budget",
                "alpha",
                "beta",
                "stall_window",
                "damping",
            )
            if k in o
        }
        if "max_step" in o:
            kwargs["max_step"] = None if o["max_step"] is False else tuple(o["max_step"])
        kwargs["damping_law"] = self.damping_law()
        q = self.q0
        results = []
        for goal in self.goals:
            start = Configuration(self.model, q)
            stack = [[spec.build(self.model, start) for spec in level] for level in self.levels]
            result = solve(
                self.model,
                {(goal.frame, goal.frame_type.value): goal.target},
                q0=q,
                stack=stack,
                limits=self.build_limits(),
                **kwargs,
            )
            results.append(result)
            q = result.q
        return results

    def _track(self) -> TrackTrace:
        o = self.options
        configuration = self.start_configuration()
        levels = self.build_stack(configuration)
        solver = IKSolver(
            self.model,
            levels,
            self.build_limits(),
            solver=o.get("solver", "osqp"),
            damping=o.get("damping", 1e-6),
            damping_law=self.damping_law(),
        )
        tol_p = o.get("tol_position", 1e-4)
        tol_o = o.get("tol_orientation", 1e-3)
        qs = [configuration.q]
        velocities, residuals, sigmas, step_times, goal_index, n_active = [], [], [], [], [], []
        errors = [_goal_error(configuration, self.goals[0])]
        reached: list[bool] = []
        for index, goal in enumerate(self.goals):
            if index > 0:
                set_frame_target(levels, goal.frame, goal.target)
                errors[-1] = _goal_error(configuration, goal)
            for _ in range(self.steps):
                if self.stop_at_goal and errors[-1][0] <= tol_p and errors[-1][1] <= tol_o:
                    break
                step = solver.step(configuration, self.dt)
                configuration.integrate_inplace(step.velocity, self.dt)
                qs.append(configuration.q)
                velocities.append(step.velocity.copy())
                residuals.append(list(step.residuals))
                sigmas.append(list(step.sigma_min))
                step_times.append(step.solve_time)
                goal_index.append(index)
                n_active.append(len(step.active_limits))
                errors.append(_goal_error(configuration, goal))
            reached.append(errors[-1][0] <= tol_p and errors[-1][1] <= tol_o)
        nv = self.model.nv
        velocity = np.array(velocities).reshape(-1, nv)
        ratio = float("nan")
        if self.velocity_limits is not None and len(velocity):
            ratio = float(np.max(np.abs(velocity) / self.velocity_limits))
        error = np.array(errors)
        converged = all(reached)
        failed = [i for i, ok in enumerate(reached) if not ok]
        if converged:
            reason = "converged"
        else:
            where = "target" if len(self.goals) == 1 else f"waypoint {failed[0]}"
            reason = f"{where}: not within tolerance after {self.steps} steps of {self.dt} s"
        return TrackTrace(
            dt=self.dt,
            q=np.array(qs),
            velocity=velocity,
            residuals=residuals,
            sigma_min=sigmas,
            step_time=np.array(step_times),
            goal_index=np.array(goal_index, dtype=int),
            active_limits=np.array(n_active, dtype=int),
            position_error=error[:, 0],
            orientation_error=error[:, 1],
            max_velocity_ratio=ratio,
            converged=converged,
            reason=reason,
        )

    def _statics(self, q: np.ndarray) -> StaticsReport:
        spec = self.statics or {}
        configuration = Configuration(self.model, q)
        frame = spec.get("frame", self.goals[0].frame)
        kind = FrameType.parse(spec.get("frame_type", self.goals[0].frame_type))
        force = np.asarray(spec.get("force", [0.0, 0.0, 0.0]), dtype=float)
        torque = np.asarray(spec.get("torque", [0.0, 0.0, 0.0]), dtype=float)
        tau = _statics.joint_torques(configuration, frame, force, torque, kind)
        gravity = _statics.gravity_torques(configuration)
        holding = _statics.holding_torques(configuration, [((frame, kind), force, torque)])
        try:
            limits = _statics.joint_torque_limits(configuration)
        except QpikError:
            limits = None
        within = None
        if limits is not None:
            within = bool(np.all((limits[:, 0] <= holding) & (holding <= limits[:, 1])))
        payload = None
        if "payload_direction" in spec and limits is not None:
            payload = _statics.max_payload(
                configuration, frame, spec["payload_direction"], None, kind
            )
        return StaticsReport(
            frame=frame,
            force=force,
            torque=torque,
            tau=tau,
            gravity=gravity,
            holding=holding,
            torque_limits=limits,
            within_limits=within,
            payload=payload,
        )

    # ------------------------------------------------------------------ output
    def to_dict(self) -> dict:
        """The validated problem as plain data (rotations as matrices)."""
        out: dict[str, Any] = {
            "path": self.path,
            "name": self.name,
            "description": self.description,
            "robot": self.robot,
            "q0": self.q0.tolist(),
            "mode": self.mode,
            "levels": [[spec.to_dict() for spec in level] for level in self.levels],
            "limits": {
                "position": self.position_limits,
                "velocity": None if self.velocity_limits is None else self.velocity_limits.tolist(),
            },
            "solver": {k: _jsonable(v) for k, v in self.options.items()},
            "goals": [goal.to_dict() for goal in self.goals],
        }
        if self.mode == "track":
            out["track"] = {"dt": self.dt, "steps": self.steps, "stop_at_goal": self.stop_at_goal}
        if self.statics is not None:
            out["statics"] = {k: _jsonable(v) for k, v in self.statics.items()}
        return out

    def to_json(self, indent: int | None = 2) -> str:
        """:meth:`to_dict` as JSON."""
        return json.dumps(self.to_dict(), indent=indent)


def _goal_error(configuration: Configuration, goal: Goal) -> tuple[float, float]:
    """Position error [m] and orientation error [rad] of a goal's frame."""
    position, rotation = configuration.frame_pose(goal.frame, goal.frame_type)
    position_error = float(np.linalg.norm(position - goal.target.position))
    orientation_error = 0.0
    if goal.target.rotation is not None:
        cosine = (np.trace(rotation @ goal.target.rotation.T) - 1.0) / 2.0
        orientation_error = float(math.acos(min(1.0, max(-1.0, cosine))))
    return position_error, orientation_error


def _jsonable(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    return value


# ----------------------------------------------------------------------------- results
@dataclass
class TrackTrace:
    """What a ``mode = "track"`` run did, step by step.

    Attributes:
        dt: step [s].
        q: configurations ``(steps + 1, nq)``, the start first.
        velocity: joint velocities ``(steps, nv)`` [rad/s].
        residuals: per step, each level's weighted residual.
        sigma_min: per step, each level's smallest singular value.
        step_time: wall time of each :meth:`IKSolver.step` [s].
        goal_index: per step, the goal being tracked.
        active_limits: per step, how many limits bind.
        position_error, orientation_error: ``(steps + 1,)`` [m], [rad] to the goal tracked.
        max_velocity_ratio: largest ``|v_i| / v_max_i`` over the run (nan without velocity
            limits); at most 1 when the velocity limits hold.
        converged, reason: whether every goal was within tolerance at the end of its steps.
    """

    dt: float
    q: np.ndarray
    velocity: np.ndarray
    residuals: list[list[float]]
    sigma_min: list[list[float]]
    step_time: np.ndarray
    goal_index: np.ndarray
    active_limits: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray
    max_velocity_ratio: float
    converged: bool
    reason: str

    @property
    def steps(self) -> int:
        return len(self.velocity)

    def to_dict(self) -> dict:
        times = self.step_time
        return {
            "dt": self.dt,
            "steps": self.steps,
            "converged": self.converged,
            "reason": self.reason,
            "q": self.q.tolist(),
            "velocity": self.velocity.tolist(),
            "residuals": _jsonable(self.residuals),
            "position_error": self.position_error.tolist(),
            "orientation_error": self.orientation_error.tolist(),
            "max_velocity_ratio": _jsonable(self.max_velocity_ratio),
            "step_time_mean": float(times.mean()) if len(times) else None,
            "step_time_max": float(times.max()) if len(times) else None,
        }


@dataclass
class StaticsReport:
    """Statics at the final configuration (see :mod:`qpik.statics`).

    Attributes:
        frame: where the wrench acts; force [N], torque [N m] (world axes).
        tau: ``J^T [f; t]`` (nv,) [N m], produced by the wrench.
        gravity: produced by gravity; holding: ``-(gravity + tau)``, the motor torques.
        torque_limits: ``(nv, 2)`` actuator limits or None; within_limits: whether the
            holding torques respect them.
        payload: :func:`qpik.statics.max_payload` along ``payload_direction``, or None.
    """

    frame: str
    force: np.ndarray
    torque: np.ndarray
    tau: np.ndarray
    gravity: np.ndarray
    holding: np.ndarray
    torque_limits: np.ndarray | None
    within_limits: bool | None
    payload: _statics.PayloadLimit | None

    def to_dict(self) -> dict:
        out = {
            "frame": self.frame,
            "force": self.force.tolist(),
            "torque": self.torque.tolist(),
            "tau": self.tau.tolist(),
            "gravity": self.gravity.tolist(),
            "holding": self.holding.tolist(),
            "torque_limits": None if self.torque_limits is None else self.torque_limits.tolist(),
            "within_limits": self.within_limits,
        }
        if self.payload is not None:
            out["payload"] = {
                "force": _jsonable(self.payload.force),
                "mass_kg": _jsonable(self.payload.force / 9.81),
                "direction": self.payload.direction.tolist(),
                "limiting_joint": self.payload.limiting_joint,
                "holds_gravity": self.payload.holds_gravity,
            }
        return out


@dataclass
class ProblemResult:
    """The outcome of :meth:`Problem.solve`.

    Attributes:
        problem: the problem solved.
        converged: whether every goal was reached within tolerance.
        reason: ``"converged"``, else which goal failed and why.
        results: solve mode: one :class:`qpik.IKResult` per goal (empty in track mode).
        trace: track mode: the :class:`TrackTrace` (None in solve mode).
        statics: the :class:`StaticsReport` when the file has a ``[statics]`` table.
        solve_time: wall time of the whole problem [s].
    """

    problem: Problem
    converged: bool
    reason: str
    results: list[IKResult]
    trace: TrackTrace | None
    statics: StaticsReport | None
    solve_time: float

    @property
    def q(self) -> np.ndarray:
        """The final configuration ``(nq,)``."""
        return self.trace.q[-1] if self.trace is not None else self.results[-1].q

    @property
    def path(self) -> np.ndarray:
        """Configurations along the way ``(k, nq)``: the start, then every step (track
        mode) or every goal's solution (solve mode; :class:`qpik.IKResult` keeps no
        intermediate iterates)."""
        if self.trace is not None:
            return self.trace.q
        return np.array([self.problem.q0] + [r.q for r in self.results])

    @property
    def iterations(self) -> int:
        """IK iterations (solve mode) or steps (track mode), all goals together."""
        if self.trace is not None:
            return self.trace.steps
        return sum(r.iterations for r in self.results)

    @property
    def residual_history(self) -> list[list[float]]:
        """Per iteration (all goals, in order) or per step, each level's residual."""
        if self.trace is not None:
            return self.trace.residuals
        return [row for r in self.results for row in r.residual_history]

    def summary(self) -> str:
        """A few lines for people."""
        p = self.problem
        state = "converged" if self.converged else f"NOT converged ({self.reason})"
        lines = [
            f"{p.name}: {p.robot} ({p.model.nv} DoF), {len(p.levels)} level(s), "
            f"{len(p.goals)} goal(s), mode {p.mode}",
            f"{state}: {self.iterations} {'steps' if p.mode == 'track' else 'iterations'}, "
            f"{1e3 * self.solve_time:.1f} ms",
        ]
        if self.trace is not None:
            t = self.trace
            lines.append(
                f"  final error: position {t.position_error[-1]:.3g} m, orientation "
                f"{t.orientation_error[-1]:.3g} rad; step time mean "
                f"{1e6 * t.step_time.mean():.0f} us, max {1e6 * t.step_time.max():.0f} us"
            )
            if not math.isnan(t.max_velocity_ratio):
                lines.append(f"  max |v| / v_max = {t.max_velocity_ratio:.3f}")
            if t.residuals:
                levels = ", ".join(f"{r:.3g}" for r in t.residuals[-1])
                lines.append(f"  final level residuals: {levels}")
        for i, r in enumerate(self.results):
            label = "target" if len(self.results) == 1 else f"waypoint {i}"
            lines.append(
                f"  {label}: {r.reason}, {r.iterations} iterations, {r.restarts_used} restarts, "
                f"position error {r.position_error:.3g} m, orientation error "
                f"{r.orientation_error:.3g} rad"
            )
        lines.append(f"  q = {np.array2string(self.q, precision=4)}")
        if self.statics is not None:
            s = self.statics
            lines.append(
                f"  statics at {s.frame!r}: force {np.array2string(s.force, precision=3)} N; "
                f"holding torques [N m] {np.array2string(s.holding, precision=2)}"
            )
            if s.within_limits is not None:
                lines.append(f"  holding torques within actuator limits: {s.within_limits}")
            if s.payload is not None:
                pay = s.payload
                if pay.feasible:
                    lines.append(
                        f"  max payload along {np.array2string(pay.direction, precision=2)}: "
                        f"{pay.force:.1f} N ({pay.force / 9.81:.2f} kg), limited by "
                        f"{pay.limiting_joint}"
                    )
                else:
                    lines.append("  max payload: none (the pose cannot be held)")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """Plain data: the problem, the outcome, per goal results or the trace, statics."""
        out: dict[str, Any] = {
            "problem": self.problem.to_dict(),
            "converged": self.converged,
            "reason": self.reason,
            "q": self.q.tolist(),
            "iterations": self.iterations,
            "solve_time": self.solve_time,
            "results": [
                {
                    "converged": r.converged,
                    "reason": r.reason,
                    "q": r.q.tolist(),
                    "iterations": r.iterations,
                    "restarts_used": r.restarts_used,
                    "position_error": r.position_error,
                    "orientation_error": r.orientation_error,
                    "residual_history": _jsonable(r.residual_history),
                    "solve_time": r.solve_time,
                }
                for r in self.results
            ],
            "trace": None if self.trace is None else self.trace.to_dict(),
            "statics": None if self.statics is None else self.statics.to_dict(),
        }
        return out

    def to_json(self, indent: int | None = 2) -> str:
        """:meth:`to_dict` as JSON."""
        return json.dumps(self.to_dict(), indent=indent)


# ----------------------------------------------------------------------------- loading
def load_problem(path: str | os.PathLike) -> Problem:
    """Read and validate a problem file (see the module docstring for the schema).

    Raises :class:`qpik.ProblemFileError` naming the file, the field and what was
    expected, for an unreadable or malformed file, a missing field, a wrong type, an
    unknown task type, frame or robot.
    """
    path = Path(path)
    name = str(path)
    reader = _Reader(name)
    try:
        raw = path.read_bytes()
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the path
        reason = getattr(exc, "strerror", None) or exc
        raise reader.fail("(file)", f"a readable TOML file ({reason})") from exc
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise reader.fail(
            "(file)", f"UTF-8 text (TOML); byte {exc.start} (line {line}) is not valid UTF-8"
        ) from None
    text = text.removeprefix("\ufeff")  # a byte-order mark is harmless
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise reader.fail("(file)", f"valid TOML ({exc})") from exc
    except RecursionError:
        raise reader.fail(
            "(file)", "TOML nested at most a few hundred levels deep (arrays or tables)"
        ) from None
    reader.unknown_keys(data, _TOP_KEYS, "")

    model, robot = _load_model(reader, data, path)
    start = Configuration(model)
    q0 = _configuration_value(
        reader, data.get("q0", "mid"), "q0", model, start, allow_start=False, default=None
    )
    try:
        start.update(q0)
        start.check_limits()
    except QpikError as exc:
        raise reader.fail("q0", f"a configuration within the joint limits ({exc})") from exc
    # within check_limits' tolerance but outside a limit: clamp, so that no iterate
    # starts (and stays) outside
    clamped = np.clip(start.q, start.lower, start.upper)
    if not np.array_equal(clamped, start.q):
        start.update(clamped)

    mode = reader.get(data, "mode", "", str, '"solve" or "track"', "solve")
    if mode not in ("solve", "track"):
        raise reader.fail("mode", f'expected "solve" or "track", got {mode!r}')

    levels = _read_levels(reader, data, model, start)
    goals = _read_goals(reader, data, model, levels)
    position_limits, velocity_limits = _read_limits(reader, data, model)
    options = _read_solver(reader, data, mode)

    dt, steps, stop_at_goal = 0.01, 0, False
    if mode == "track":
        track = reader.get(data, "track", "", dict, "a [track] table with dt and steps")
        reader.unknown_keys(track, {"dt", "steps", "stop_at_goal"}, "track")
        dt = reader.get(track, "dt", "track", float, "a step in seconds (> 0)")
        steps = reader.get(track, "steps", "track", int, "a number of steps (>= 1)")
        stop_at_goal = reader.get(track, "stop_at_goal", "track", bool, "true or false", False)
        reader.number(dt, "track.dt", "track.dt", "a step in seconds")
        reader.number(steps, "track.steps", "track.steps", "a number of steps")
    elif "track" in data:
        raise reader.fail("track", 'a [track] table only with mode = "track"')

    statics = None
    if "statics" in data:
        statics = _read_statics(reader, data, model)

    return Problem(
        path=name,
        name=reader.get(data, "name", "", str, "a string", path.stem),
        description=reader.get(data, "description", "", str, "a string", ""),
        robot=robot,
        model=model,
        q0=start.q,
        levels=levels,
        position_limits=position_limits,
        velocity_limits=velocity_limits,
        options=options,
        mode=mode,
        goals=goals,
        dt=dt,
        steps=steps,
        stop_at_goal=stop_at_goal,
        statics=statics,
    )


def _load_model(reader: _Reader, data: dict, path: Path) -> tuple[mujoco.MjModel, str]:
    expected = (
        f"a bundled robot ({', '.join(list_robots())}), 'erd:NAME', or a path to an "
        ".xml/.urdf file relative to the problem file"
    )
    robot = reader.get(data, "robot", "", str, expected)
    if robot in list_robots() or robot.startswith("erd:"):
        source: str | Path = robot
    elif robot.lower().endswith((".xml", ".urdf")) or "/" in robot or os.sep in robot:
        try:
            source = (path.parent / robot).resolve()
            found = source.is_file()
        except (OSError, ValueError) as exc:  # a name too long, a NUL byte
            raise reader.fail("robot", f"{expected}; cannot read {robot!r} ({exc})") from None
        if not found:
            raise reader.fail("robot", f"{expected}; no such file: {source}")
    else:
        raise reader.fail("robot", str(UnknownRobot(robot, list_robots())))
    try:
        return load_robot(source), robot
    except (QpikError, OSError) as exc:
        raise reader.fail("robot", f"{expected} ({exc})") from exc


def _configuration_value(
    reader: _Reader, value, name: str, model, start, *, allow_start: bool, default
) -> np.ndarray:
    """A configuration from a list of nq numbers or a name (mid, qpos0, start, keyframe)."""
    # keyframes by name, with their own index (unnamed keyframes cannot be chosen)
    named = {}
    for k in range(model.nkey):
        key_name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, k)
        if key_name and key_name not in named:
            named[key_name] = k
    keys = list(named)
    names = ["mid", "qpos0"] + (["start"] if allow_start else []) + keys
    expected = f"a list of {model.nq} numbers or one of: {', '.join(names)}"
    if isinstance(value, str):
        if value == "mid":
            return start.mid_q()
        if value == "qpos0":
            return model.qpos0.copy()
        if value == "start" and allow_start:
            return start.q
        if value in named:
            q = model.key_qpos[named[value]].copy()
            if not np.all(np.isfinite(q)):
                raise reader.fail(name, f"keyframe {value!r} of the model has non-finite qpos")
            return q
        raise reader.fail(name, f"expected {expected}, got {value!r}")
    return reader.bounded_vector(value, name, model.nq, expected, MAX_LENGTH)


def _frame(reader: _Reader, table: dict, where: str, model) -> tuple[str, FrameType]:
    if "frame" not in table and "frame_type" not in table:  # the robot's tool frame
        tool = tool_frame(model)
        return tool.name, FrameType(tool.frame_type)
    frame = reader.get(table, "frame", where, str, "a frame name (e.g. 'ee')")
    kind_text = reader.get(table, "frame_type", where, str, "site, body or geom", "site")
    try:
        kind = FrameType.parse(kind_text)
    except QpikError as exc:
        raise reader.fail(f"{where}.frame_type", str(exc)) from exc
    obj = {
        FrameType.SITE: mujoco.mjtObj.mjOBJ_SITE,
        FrameType.BODY: mujoco.mjtObj.mjOBJ_BODY,
        FrameType.GEOM: mujoco.mjtObj.mjOBJ_GEOM,
    }[kind]
    if mujoco.mj_name2id(model, obj, frame) < 0:
        raise reader.fail(
            f"{where}.frame", str(UnknownFrame(frame, kind.value, frame_names(model, kind)))
        )
    return frame, kind


def _cost(reader: _Reader, table: dict, key: str, where: str, size: int | None, default):
    if key not in table:
        return default
    value = table[key]
    name = f"{where}.{key}"
    interval = f"in [0, {MAX_COST:g}]"
    expected = f"a number {interval}" + (f" or a list of {size} numbers {interval}" if size else "")
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        cost = float(value)
        if not (math.isfinite(cost) and 0 <= cost <= MAX_COST):
            raise reader.fail(name, f"expected {expected}, got {value!r}")
        return cost
    if size is None:
        raise reader.fail(name, f"expected {expected}, got {_describe(value)}")
    vector = reader.bounded_vector(value, name, size, expected, MAX_COST)
    if np.any(vector < 0):
        raise reader.fail(name, f"expected {expected}, got {value!r}")
    return vector


def _read_levels(reader: _Reader, data: dict, model, start: Configuration) -> list[list[TaskSpec]]:
    raw = reader.get(data, "levels", "", list, "a list of levels ([[levels]] tables with tasks)")
    if not raw:
        raise reader.fail("levels", "expected at least one level")
    levels = []
    for i, level in enumerate(raw):
        where = f"levels[{i}]"
        if isinstance(level, dict):
            reader.unknown_keys(level, {"name", "tasks"}, where)
            tasks = reader.get(level, "tasks", where, list, "a list of tasks ([[levels.tasks]])")
            task_where = f"{where}.tasks"
        elif isinstance(level, list):
            tasks, task_where = level, where
        else:
            raise reader.fail(where, f"expected a table with tasks, got {_describe(level)}")
        if not tasks:
            raise reader.fail(task_where, "expected at least one task")
        levels.append(
            [_read_task(reader, t, f"{task_where}[{j}]", model, start) for j, t in enumerate(tasks)]
        )
    return levels


def _read_task(reader: _Reader, table, where: str, model, start: Configuration) -> TaskSpec:
    if not isinstance(table, dict):
        raise reader.fail(where, f"expected a task table, got {_describe(table)}")
    kind = reader.get(table, "type", where, str, f"a task type, one of: {', '.join(TASK_TYPES)}")
    if kind not in TASK_TYPES:
        raise reader.fail(
            f"{where}.type", f"unknown task type {kind!r}; known types: {', '.join(TASK_TYPES)}"
        )
    allowed = {"type", "gain", "lm_damping", "cost", "target"}
    if kind in _FRAME_TASKS:
        allowed |= {"frame", "frame_type"}
    if kind == "frame":
        allowed = (allowed - {"cost"}) | {"position_cost", "orientation_cost"}
    if kind == "manipulability":
        allowed = (allowed - {"target", "lm_damping"}) | {"rows"}
    if kind == "damping":
        allowed = {"type", "cost"}
    if kind == "joint_limit_distance":
        allowed -= {"target"}
    reader.unknown_keys(table, allowed, where)
    spec = TaskSpec(type=kind, field=where, options={})
    if kind in _FRAME_TASKS:
        spec.frame, spec.frame_type = _frame(reader, table, where, model)
    o = spec.options
    if "gain" in table:
        o["gain"] = float(reader.number(table["gain"], f"{where}.gain", "gain", "a gain"))
    if "lm_damping" in table:
        o["lm_damping"] = float(
            reader.number(table["lm_damping"], f"{where}.lm_damping", "lm_damping")
        )
    if kind == "frame":
        o["position_cost"] = _cost(reader, table, "position_cost", where, 3, 1.0)
        o["orientation_cost"] = _cost(reader, table, "orientation_cost", where, 3, 1.0)
    elif kind in ("position", "orientation", "com"):
        o["cost"] = _cost(reader, table, "cost", where, 3, 1.0)
    elif kind in ("posture", "damping"):
        o["cost"] = _cost(
            reader, table, "cost", where, model.nv, 1.0 if kind == "posture" else 1e-3
        )
    else:
        o["cost"] = _cost(reader, table, "cost", where, None, 1.0)
    if kind == "manipulability":
        rows = reader.get(table, "rows", where, str, '"pose" or "position"', "pose")
        if rows not in ("pose", "position"):
            raise reader.fail(f"{where}.rows", f'expected "pose" or "position", got {rows!r}')
        o["rows"] = rows
    if "target" in table:
        target = reader.get(table, "target", where, dict, "a target table")
        twhere = f"{where}.target"
        if kind == "posture":
            reader.unknown_keys(target, {"q"}, twhere)
            value = reader.get(target, "q", twhere, (list, str), "a configuration")
            spec.posture = _configuration_value(
                reader, value, f"{twhere}.q", model, start, allow_start=True, default=None
            )
        else:
            keys = {"position"} if kind in ("position", "com") else set()
            if kind in ("orientation", "frame"):
                keys |= set(_ROTATION_KEYS)
            if kind == "frame":
                keys.add("position")
            reader.unknown_keys(target, keys, twhere)
            if "position" in keys:
                spec.position = reader.bounded_vector(
                    reader.get(target, "position", twhere, list, "[x, y, z] in metres"),
                    f"{twhere}.position",
                    3,
                    "[x, y, z] in metres",
                    MAX_LENGTH,
                )
            if kind in ("orientation", "frame"):
                spec.rotation = _rotation_from(reader, target, twhere)
                if spec.rotation is None:
                    raise reader.fail(
                        f"{twhere}.rpy", f"missing; expected one of {', '.join(_ROTATION_KEYS)}"
                    )
    return spec


def _read_goal(reader: _Reader, table, where: str, model, levels) -> Goal:
    if not isinstance(table, dict):
        raise reader.fail(where, f"expected a table, got {_describe(table)}")
    reader.unknown_keys(table, {"frame", "frame_type", "position", *_ROTATION_KEYS}, where)
    if "frame" in table:
        frame, kind = _frame(reader, table, where, model)
    else:
        first = next((s for s in levels[0] if s.type in _GOAL_TASKS), None)
        if first is None:
            raise reader.fail(
                f"{where}.frame",
                "missing; expected a frame name (level 0 has no frame, position or "
                "orientation task to take it from)",
            )
        frame, kind = first.frame, first.frame_type
    position = reader.bounded_vector(
        reader.get(table, "position", where, list, "[x, y, z] in metres"),
        f"{where}.position",
        3,
        "[x, y, z] in metres",
        MAX_LENGTH,
    )
    rotation = _rotation_from(reader, table, where)
    regulating = [
        s for level in levels for s in level if s.type in _GOAL_TASKS and s.frame == frame
    ]
    if not regulating:
        raise reader.fail(
            f"{where}.frame",
            f"a frame regulated by a frame, position or orientation task; no task regulates "
            f"{frame!r}",
        )
    if rotation is None and any(s.type == "frame" for s in regulating):
        raise reader.fail(
            f"{where}.rpy",
            f"missing; a frame task regulates {frame!r}, so the goal needs a rotation "
            f"({', '.join(_ROTATION_KEYS)}), or use a position task",
        )
    return Goal(frame, kind, Target(position, rotation), where)


def _read_goals(reader: _Reader, data: dict, model, levels) -> list[Goal]:
    if ("target" in data) == ("waypoints" in data):
        raise reader.fail(
            "target",
            "exactly one of a [target] table or a list of [[waypoints]]"
            + (" (both given)" if "target" in data else ""),
        )
    if "target" in data:
        return [_read_goal(reader, data["target"], "target", model, levels)]
    waypoints = reader.get(data, "waypoints", "", list, "a list of [[waypoints]] tables")
    if not waypoints:
        raise reader.fail("waypoints", "expected at least one waypoint")
    return [
        _read_goal(reader, w, f"waypoints[{i}]", model, levels) for i, w in enumerate(waypoints)
    ]


def _read_limits(reader: _Reader, data: dict, model) -> tuple[bool, np.ndarray | None]:
    table = reader.get(data, "limits", "", dict, "a [limits] table", {})
    reader.unknown_keys(table, {"position", "velocity"}, "limits")
    position = reader.get(table, "position", "limits", bool, "true or false", True)
    value = table.get("velocity", False)
    expected = (
        "false, a scale of the model's velocity_limit (> 0), a list of "
        f"{model.nv} velocities [rad/s] or a table {{joint = velocity}}"
    )
    if value is False:
        return position, None
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        base = Configuration(model).velocity_limits()
        if base is None:
            raise reader.fail(
                "limits.velocity",
                "a list or table of velocities: the model declares no velocity_limit to scale",
            )
        reader.number(value, "limits.velocity", "velocity", "a scale")
        velocity = float(value) * np.asarray(base, dtype=float)
        for i in range(model.nv):
            if not np.isfinite(base[i]):
                continue  # a dof the model leaves unlimited (0 in its velocity_limit)
            reader.number(
                float(velocity[i]), f"limits.velocity (x the velocity_limit of dof {i})",
                "velocity", "a velocity",
            )
        return position, velocity
    if isinstance(value, list):
        velocity = reader.vector(value, "limits.velocity", model.nv, expected)
        for i, v in enumerate(velocity):
            reader.number(float(v), f"limits.velocity[{i}]", "velocity", "a velocity")
    elif isinstance(value, dict):
        names = joint_names(model)
        velocity = np.full(model.nv, np.inf)
        for joint, v in value.items():
            if joint not in names:
                raise reader.fail(
                    f"limits.velocity.{joint}", f"a joint name, one of: {', '.join(names)}"
                )
            reader.number(v, f"limits.velocity.{joint}", "velocity", "a velocity")
            dofs = np.flatnonzero(model.dof_jntid == names.index(joint))
            velocity[dofs] = float(v)
        if np.any(np.isinf(velocity)):
            missing = [names[model.dof_jntid[i]] for i in np.flatnonzero(np.isinf(velocity))]
            raise reader.fail("limits.velocity", f"a velocity for every joint; missing: {missing}")
    else:
        raise reader.fail("limits.velocity", f"expected {expected}, got {_describe(value)}")
    if np.any(velocity <= 0):
        raise reader.fail("limits.velocity", f"expected {expected} (all > 0)")
    return position, velocity


def _read_solver(reader: _Reader, data: dict, mode: str) -> dict[str, Any]:
    table = reader.get(data, "solver", "", dict, "a [solver] table", {})
    reader.unknown_keys(table, set(_SOLVER_KEYS), "solver")
    options: dict[str, Any] = {}
    for key, kind in _SOLVER_KEYS.items():
        if key not in table:
            continue
        if key == "max_step":
            value = table[key]
            if value is False:
                options[key] = False
                continue
            vector = reader.vector(value, "solver.max_step", 2, "[metres, radians] or false")
            for i, v in enumerate(vector):
                reader.number(float(v), f"solver.max_step[{i}]", "solver.max_step")
            options[key] = vector.tolist()
            continue
        expected = {
            str: "a string",
            float: "a number",
            int: "an integer",
            bool: "true or false",
        }[kind]
        options[key] = reader.get(table, key, "solver", kind, expected)
        if f"solver.{key}" in RANGES:
            reader.number(options[key], f"solver.{key}", f"solver.{key}", expected)
    if mode == "track":
        for key in ("max_iters", "restarts", "time_budget", "alpha", "beta", "max_step", "seed"):
            if key in options:
                raise reader.fail(
                    f"solver.{key}", 'only with mode = "solve" (not used in tracking)'
                )
    return options


def _read_statics(reader: _Reader, data: dict, model) -> dict[str, Any]:
    table = reader.get(data, "statics", "", dict, "a [statics] table")
    reader.unknown_keys(
        table, {"frame", "frame_type", "force", "torque", "payload_direction"}, "statics"
    )
    out: dict[str, Any] = {}
    if "frame" in table:
        out["frame"], out["frame_type"] = _frame(reader, table, "statics", model)
    for key, what in (
        ("force", "[fx, fy, fz] in newtons"),
        ("torque", "[tx, ty, tz] in newton metres"),
        ("payload_direction", "a nonzero direction [x, y, z]"),
    ):
        if key in table:
            out[key] = reader.bounded_vector(table[key], f"statics.{key}", 3, what, MAX_WRENCH)
    if "payload_direction" in out:
        direction = out["payload_direction"]
        scale = float(np.max(np.abs(direction)))
        if scale == 0.0:
            raise reader.fail("statics.payload_direction", "expected a nonzero direction [x, y, z]")
        direction = direction / scale  # scaled first: no underflow / overflow in the norm
        out["payload_direction"] = direction / np.linalg.norm(direction)
    return out
