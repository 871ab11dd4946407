"""The :class:`Problem` of a file and :func:`load_problem`, which reads and validates it.

The top-level fields (``robot``, ``floating_base``, ``q0``, ``mode``, ``[track]``,
``[statics]``) are read here; levels and tasks by :mod:`.specs`, goals by :mod:`.goals`,
``[limits]`` by :mod:`.limits`, ``[solver]`` by :mod:`.solver`; the values themselves by
:class:`.reader.Reader`. The schema is documented in :mod:`qpik.problem` and the
repository's ``tasks/README.md``.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..core import checks
from ..core.cascade import DampingLaw
from ..errors import QpikError
from ..igm.qp_engine import set_frame_target
from ..limits import ConfigurationLimit, SupportPolygonLimit, VelocityLimit
from ..model.configuration import Configuration, FrameType, joint_names, resolve_robot
from ..model.robots import list_robots
from ..options import SolveOptions
from .goals import Goal, read_goals
from .limits import read_limits, read_support
from .modes import MODES
from .reader import MAX_WRENCH, Reader, read_toml
from .report import ProblemResult, StaticsReport, jsonable
from .scene import build_collision, read_collision, read_obstacles
from .solver import options_dict, read_solver
from .specs import TaskSpec, read_levels

_TOP_KEYS = {
    "name",
    "description",
    "robot",
    "floating_base",
    "q0",
    "mode",
    "levels",
    "target",
    "waypoints",
    "limits",
    "solver",
    "track",
    "statics",
    "obstacles",
}


@dataclass
class Problem:
    """A validated IK problem (see :mod:`qpik.problem` for the file schema).

    Attributes:
        path: the file it was read from.
        name, description: from the file.
        robot: the ``robot`` field as written; ``model``: the loaded model.
        q0: start configuration ``(nq,)``.
        levels: task specs, level 0 first.
        position_limits: whether joint position limits hold.
        velocity_limits: per-dof velocity limits ``(nv,)`` [rad/s or m/s], or None.
        options: the ``[solver]`` table as written, validated.
        mode: a key of :data:`qpik.problem.modes.MODES` (``"solve"`` or ``"track"``).
        goals: the target, or the waypoints in order.
        dt, steps, stop_at_goal: tracking settings (track mode).
        statics: the ``[statics]`` table, validated, or None.
        support: the ``[limits.support]`` table, validated (frames, margin [m],
            footprint), or None.
        collision: the ``[limits.collision]`` table, validated (:mod:`.scene`), or None;
            the file's ``[[obstacles]]`` are in ``model``.
        solve_options: the :class:`qpik.SolveOptions` of the run: the ``[solver]`` preset
            (default ``"default"`` in solve mode, ``"tracking"`` in track mode) with the
            table's fields; track mode reads its tolerances and ``step`` options.
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
    support: dict[str, Any] | None = None
    collision: dict[str, Any] | None = None
    solve_options: SolveOptions = field(default_factory=SolveOptions)

    # ------------------------------------------------------------------ building
    def start_configuration(self) -> Configuration:
        """A new configuration at ``q0``."""
        return Configuration(self.model, self.q0)

    def build_stack(self, start: Configuration | None = None) -> list[list]:
        """Fresh task objects, level 0 first (targets set; the goal frames' tasks get the
        first goal)."""
        start = start if start is not None else self.start_configuration()
        levels = [[spec.build(self.model, start) for spec in level] for level in self.levels]
        for frame in self.goals[0].frames:
            set_frame_target(levels, frame.frame, frame.target, frame.frame_type)
        return levels

    def build_limits(self) -> list:
        """The limits of the problem: position, velocity, support-polygon, then collision
        limits."""
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
        if self.support is not None:
            s = self.support
            frames = [(name, s["frame_type"]) for name in s["frames"]]
            limits.append(SupportPolygonLimit(self.model, frames, s["margin"], s.get("footprint")))
        if self.collision is not None:
            limits.append(build_collision(self.model, self.collision))
        return limits

    def damping_law(self) -> DampingLaw | None:
        """The adaptive damping of the run (``solve_options.damping_law``)."""
        return self.solve_options.damping_law

    # ------------------------------------------------------------------ solving
    def solve(self) -> ProblemResult:
        """Run the file's mode (:data:`qpik.problem.modes.MODES`) and the statics."""
        start_time = time.perf_counter()
        results, trace, converged, reason = MODES[self.mode](self)
        final_q = trace.q[-1] if trace is not None else results[-1].q
        return ProblemResult(
            problem=self,
            converged=converged,
            reason=reason,
            results=results,
            trace=trace,
            statics=self.statics_at(final_q) if self.statics is not None else None,
            solve_time=time.perf_counter() - start_time,
        )

    def statics_at(self, q: np.ndarray) -> StaticsReport:
        """The ``[statics]`` report at ``q`` (the wrench at its frame, default the first
        goal frame)."""
        spec = self.statics or {}
        goal = self.goals[0]
        return StaticsReport.compute(
            Configuration(self.model, q),
            spec.get("frame", goal.frame),
            FrameType.parse(spec.get("frame_type", goal.frame_type)),
            np.asarray(spec.get("force", np.zeros(3)), dtype=float),
            np.asarray(spec.get("torque", np.zeros(3)), dtype=float),
            spec.get("payload_direction"),
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
                "velocity": jsonable(self.velocity_limits),
                "support": jsonable(self.support),
                "collision": jsonable(self.collision),
            },
            "solver": jsonable(self.options),
            "solve_options": options_dict(self.solve_options),
            "goals": [goal.to_dict() for goal in self.goals],
        }
        if self.mode == "track":
            out["track"] = {"dt": self.dt, "steps": self.steps, "stop_at_goal": self.stop_at_goal}
        if self.statics is not None:
            out["statics"] = jsonable(self.statics)
        return out

    def to_json(self, indent: int | None = 2) -> str:
        """:meth:`to_dict` as JSON."""
        return json.dumps(self.to_dict(), indent=indent)


# ----------------------------------------------------------------------------- loading
def problem_files() -> list[Path]:
    """The shipped problem files (the repository's ``tasks/*.toml``, or the installed
    copy), sorted."""
    from importlib import resources

    packaged = Path(str(resources.files("qpik"))) / "_tasks"
    if packaged.is_dir():
        return sorted(packaged.glob("*.toml"))
    return sorted((Path(__file__).resolve().parents[2] / "tasks").glob("*.toml"))


def _shipped_if_missing(path: Path) -> Path:
    """``path``, or the shipped problem file it names when ``path`` is relative, does
    not exist and is ``NAME.toml`` or ``tasks/NAME.toml``."""
    if path.is_absolute() or path.exists() or path.suffix != ".toml":
        return path
    if len(path.parts) > 2 or (len(path.parts) == 2 and path.parts[0] != "tasks"):
        return path
    for shipped in problem_files():
        if shipped.name == path.name:
            return shipped
    return path


def load_problem(path: str | os.PathLike) -> Problem:
    """Read and validate a problem file (see :mod:`qpik.problem` for the schema).

    Raises :class:`qpik.ProblemFileError` naming the file, the field and what was
    expected, for an unreadable or malformed file, a missing field, a wrong type, an
    unknown task type, frame or robot; :class:`qpik.errors.InvalidArgumentType` (also a
    ``TypeError``) when ``path`` is not a ``str`` or ``os.PathLike`` of one (``bytes``).

    A relative path that does not exist but names a shipped problem file
    (``tasks/NAME.toml`` or ``NAME.toml``, see :func:`qpik.problem.problem_files`) reads
    that file, so the README's ``qpik reach tasks/panda_pose_reach.toml`` works from any
    folder once qpik is installed.
    """
    path = _shipped_if_missing(Path(checks.check_path("path", path)))
    reader = Reader(str(path))
    data = read_toml(path)
    reader.unknown_keys(data, _TOP_KEYS, "")
    model, robot = _read_model(reader, data, path)
    start = _read_start(reader, data, model)
    modes = " or ".join(f'"{m}"' for m in MODES)
    mode = reader.get(data, "mode", "", str, modes, "solve")
    if mode not in MODES:
        raise reader.fail("mode", f"expected {modes}, got {mode!r}")
    levels = read_levels(reader, data, model, start)
    position_limits, velocity_limits = read_limits(reader, data, model)
    dt, steps, stop_at_goal = _read_track(reader, data, mode)
    options, solve_options = read_solver(reader, data, mode)
    return Problem(
        path=str(path),
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
        goals=read_goals(reader, data, model, levels),
        dt=dt,
        steps=steps,
        stop_at_goal=stop_at_goal,
        statics=_read_statics(reader, data, model) if "statics" in data else None,
        support=read_support(reader, data, model, start),
        collision=read_collision(reader, data, model),
        solve_options=solve_options,
    )


def _read_model(reader: Reader, data: dict, path: Path) -> tuple[mujoco.MjModel, str]:
    """The model of ``robot`` (and ``floating_base``); a path is relative to the file."""
    expected = (
        f"a bundled robot ({', '.join(list_robots())}), 'erd:NAME', or a path to an "
        ".xml/.urdf file relative to the problem file"
    )
    robot = reader.get(data, "robot", "", str, expected)
    floating = reader.get(data, "floating_base", "", bool, "true or false", False)
    try:
        model, _ = resolve_robot(robot, relative_to=path.parent, floating_base=floating)
    except (QpikError, OSError, ValueError) as exc:  # ValueError: a name the OS rejects
        if floating and _loads_fixed(robot, path):  # the free joint is what fails
            raise reader.fail(
                "floating_base", f"false for this robot: it cannot have a free base ({exc})"
            ) from exc
        raise reader.fail("robot", f"{expected} ({exc})") from exc
    return read_obstacles(reader, data, model), robot


def _loads_fixed(robot: str, path: Path) -> bool:
    """Whether ``robot`` loads without ``floating_base``."""
    try:
        resolve_robot(robot, relative_to=path.parent)
    except (QpikError, OSError, ValueError):
        return False
    return True


def _read_start(reader: Reader, data: dict, model: mujoco.MjModel) -> Configuration:
    """The start configuration ``q0`` (default ``"mid"``), within the joint limits."""
    start = Configuration(model)
    q0 = reader.configuration(data.get("q0", "mid"), "q0", model, start, allow_start=False)
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
    return start


def _read_track(reader: Reader, data: dict, mode: str) -> tuple[float, int, bool]:
    """``[track]``: ``dt`` [s], ``steps`` and ``stop_at_goal`` (track mode only)."""
    if mode != "track":
        if "track" in data:
            raise reader.fail("track", 'a [track] table only with mode = "track"')
        return 0.01, 0, False
    track = reader.table(
        data, "track", "", {"dt", "steps", "stop_at_goal"}, "a [track] table with dt and steps"
    )
    dt = reader.get(track, "dt", "track", float, "a step in seconds (> 0)")
    steps = reader.get(track, "steps", "track", int, "a number of steps (>= 1)")
    stop_at_goal = reader.get(track, "stop_at_goal", "track", bool, "true or false", False)
    reader.number(dt, "track.dt", "track.dt", "a step in seconds")
    reader.number(steps, "track.steps", "track.steps", "a number of steps")
    return dt, steps, stop_at_goal


def _read_statics(reader: Reader, data: dict, model: mujoco.MjModel) -> dict[str, Any]:
    """``[statics]``: ``frame``, ``force`` [N], ``torque`` [N m], ``payload_direction``."""
    table = reader.table(
        data,
        "statics",
        "",
        {"frame", "frame_type", "force", "torque", "payload_direction"},
        "a [statics] table",
    )
    out: dict[str, Any] = {}
    if "frame_type" in table and "frame" not in table:  # it would be ignored
        raise reader.fail("statics.frame_type", "only with statics.frame (the frame it types)")
    if "frame" in table:
        out["frame"], out["frame_type"] = reader.frame(table, "statics", model)
    for key, what in (("force", "[fx, fy, fz] in newtons"), ("torque", "[tx, ty, tz] in N m")):
        if key in table:
            out[key] = reader.bounded_vector(table[key], f"statics.{key}", 3, what, MAX_WRENCH)
    if "payload_direction" in table:
        out["payload_direction"] = reader.direction(
            table["payload_direction"], "statics.payload_direction"
        )
    return out
