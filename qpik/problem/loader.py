"""The :class:`Problem` of a file and :func:`load_problem`, which reads and validates it.

The top-level fields (``robot``, ``q0``, ``mode``, ``[limits]``, ``[solver]``,
``[track]``, ``[statics]``) are read here; levels and tasks by :mod:`.specs`, goals by
:mod:`.goals`; the values themselves by :class:`.reader.Reader`. The schema is documented
in :mod:`qpik.problem` and the repository's ``tasks/README.md``.
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

from ..configuration import Configuration, FrameType, joint_names
from ..core.hierarchy import DampingLaw
from ..errors import InvalidOption, QpikError
from ..limits import ConfigurationLimit, SupportPolygonLimit, VelocityLimit
from ..options import PRESETS, SolveOptions
from ..qp_engine import set_frame_target
from ..robots import list_robots, resolve_robot
from .goals import Goal, read_goals
from .modes import MODES
from .reader import MAX_LENGTH, MAX_WRENCH, RANGES, Reader, describe, read_toml
from .report import ProblemResult, StaticsReport, jsonable
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
}
#: The ``[solver]`` fields and their TOML types (ranges: :data:`.reader.RANGES`): a
#: preset of :data:`qpik.options.PRESETS` and overrides of its :class:`qpik.SolveOptions`.
_SOLVER_KEYS: dict[str, type] = {
    "preset": str,
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
#: ``[solver]`` fields of the solve mode only.
_SOLVE_ONLY = (
    "max_iters",
    "restarts",
    "time_budget",
    "alpha",
    "beta",
    "max_step",
    "seed",
    "stall_window",
)
#: ``[solver]`` fields passed to :class:`qpik.SolveOptions` as they are.
_OPTION_FIELDS = (
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
#: The preset of each mode when ``[solver]`` names none.
DEFAULT_PRESETS = {"solve": "default", "track": "tracking"}
#: The seed of a problem file's restarts when ``[solver]`` gives none (reproducible runs).
DEFAULT_SEED = 0
_SUPPORT_KEYS = {"frames", "frame_type", "margin", "footprint"}


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
            set_frame_target(levels, frame.frame, frame.target)
        return levels

    def build_limits(self) -> list:
        """The limits of the problem: position, velocity, then support-polygon limits."""
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
            },
            "solver": jsonable(self.options),
            "solve_options": _options_dict(self.solve_options),
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
def load_problem(path: str | os.PathLike) -> Problem:
    """Read and validate a problem file (see :mod:`qpik.problem` for the schema).

    Raises :class:`qpik.ProblemFileError` naming the file, the field and what was
    expected, for an unreadable or malformed file, a missing field, a wrong type, an
    unknown task type, frame or robot.
    """
    path = Path(path)
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
    position_limits, velocity_limits = _read_limits(reader, data, model)
    dt, steps, stop_at_goal = _read_track(reader, data, mode)
    options, solve_options = _read_solver(reader, data, mode)
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
        support=_read_support(reader, data, model),
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
        raise reader.fail("robot", f"{expected} ({exc})") from exc
    return model, robot


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


def _read_limits(reader: Reader, data: dict, model) -> tuple[bool, np.ndarray | None]:
    """``[limits]``: joint position limits on or off, and the velocity limits (nv,)."""
    table = reader.table(
        data, "limits", "", {"position", "velocity", "support"}, "a [limits] table", {}
    )
    position = reader.get(table, "position", "limits", bool, "true or false", True)
    value = table.get("velocity", False)
    if value is False:
        return position, None
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        velocity = _velocity_scale(reader, value, model)
    elif isinstance(value, list):
        velocity = reader.vector(value, "limits.velocity", model.nv, _velocity_expected(model))
        for i, v in enumerate(velocity):
            reader.number(float(v), f"limits.velocity[{i}]", "velocity", "a velocity")
    elif isinstance(value, dict):
        velocity = _velocity_table(reader, value, model)
    else:
        raise reader.fail(
            "limits.velocity", f"expected {_velocity_expected(model)}, got {describe(value)}"
        )
    if np.any(velocity <= 0):
        raise reader.fail("limits.velocity", f"expected {_velocity_expected(model)} (all > 0)")
    return position, velocity


def _velocity_expected(model: mujoco.MjModel) -> str:
    return (
        "false, a scale of the model's velocity_limit (> 0), a list of "
        f"{model.nv} velocities [rad/s] or a table {{joint = velocity}}"
    )


def _velocity_scale(reader: Reader, value: float, model: mujoco.MjModel) -> np.ndarray:
    """``value`` times the model's velocity_limit (dofs it leaves unlimited stay inf)."""
    base = Configuration(model).velocity_limits()
    if base is None:
        raise reader.fail(
            "limits.velocity",
            "a list or table of velocities: the model declares no velocity_limit to scale",
        )
    reader.number(value, "limits.velocity", "velocity", "a scale")
    velocity = float(value) * np.asarray(base, dtype=float)
    for i in np.flatnonzero(np.isfinite(base)):
        reader.number(
            float(velocity[i]),
            f"limits.velocity (x the velocity_limit of dof {i})",
            "velocity",
            "a velocity",
        )
    return velocity


def _velocity_table(reader: Reader, value: dict, model: mujoco.MjModel) -> np.ndarray:
    """A velocity [rad/s or m/s] per joint name; every joint needs one."""
    names = joint_names(model)
    velocity = np.full(model.nv, np.inf)
    for joint, v in value.items():
        if joint not in names:
            raise reader.fail(
                f"limits.velocity.{joint}", f"a joint name, one of: {', '.join(names)}"
            )
        reader.number(v, f"limits.velocity.{joint}", "velocity", "a velocity")
        velocity[np.flatnonzero(model.dof_jntid == names.index(joint))] = float(v)
    if np.any(np.isinf(velocity)):
        missing = [names[model.dof_jntid[i]] for i in np.flatnonzero(np.isinf(velocity))]
        raise reader.fail("limits.velocity", f"a velocity for every joint; missing: {missing}")
    return velocity


def _read_support(reader: Reader, data: dict, model: mujoco.MjModel) -> dict[str, Any] | None:
    """``[limits.support]``: the centre of mass's ground projection stays within the
    support polygon of ``frames`` (their ``footprint`` corners [m] in each frame's x-y
    axes, default its origin), ``margin`` [m] inside."""
    limits = data.get("limits", {})
    if "support" not in limits:
        return None
    table = reader.table(limits, "support", "limits", _SUPPORT_KEYS, "a [limits.support] table")
    where = "limits.support"
    frames = reader.get(table, "frames", where, list, "a list of contact frame names")
    if not frames or not all(isinstance(f, str) for f in frames):
        raise reader.fail(f"{where}.frames", f"expected frame names, got {describe(frames)}")
    frame_type = table.get("frame_type", "site")
    kinds = [
        reader.frame({"frame": name, "frame_type": frame_type}, f"{where}.frames[{i}]", model)[1]
        for i, name in enumerate(frames)
    ]
    kind = kinds[0]
    out: dict[str, Any] = {"frames": list(frames), "frame_type": kind.value, "margin": 0.0}
    if "margin" in table:
        out["margin"] = float(reader.number(table["margin"], f"{where}.margin", "margin"))
    if "footprint" in table:
        points = reader.get(table, "footprint", where, list, "a list of [x, y] points [m]")
        if not points:
            raise reader.fail(f"{where}.footprint", "expected at least one [x, y] point")
        out["footprint"] = np.array(
            [
                reader.bounded_vector(
                    p, f"{where}.footprint[{i}]", 2, "[x, y] in metres", MAX_LENGTH
                )
                for i, p in enumerate(points)
            ]
        )
    return out


def _read_solver(reader: Reader, data: dict, mode: str) -> tuple[dict[str, Any], SolveOptions]:
    """``[solver]``: each field typed and range-checked (solve-only fields in track mode
    are errors), and the :class:`qpik.SolveOptions` they make."""
    table = reader.table(data, "solver", "", _SOLVER_KEYS, "a [solver] table", {})
    options: dict[str, Any] = {}
    for key, kind in _SOLVER_KEYS.items():
        if key not in table:
            continue
        name = f"solver.{key}"
        if mode != "solve" and key in _SOLVE_ONLY:
            raise reader.fail(name, 'only with mode = "solve" (not used in tracking)')
        if key == "max_step":
            options[key] = _read_max_step(reader, table[key])
            continue
        options[key] = reader.get(table, key, "solver", kind)
        if name in RANGES:
            reader.number(options[key], name, name, reader._EXPECTED[kind])
    return options, _solve_options(reader, options, mode)


def _solve_options(reader: Reader, options: dict[str, Any], mode: str) -> SolveOptions:
    """The preset of ``options`` (default: the mode's) with the other fields over it."""
    preset = options.get("preset", DEFAULT_PRESETS[mode])
    if preset not in PRESETS:
        raise reader.fail(
            "solver.preset", f"one of {', '.join(map(repr, PRESETS))}, got {preset!r}"
        )
    base = PRESETS[preset]
    overrides: dict[str, Any] = {k: options[k] for k in _OPTION_FIELDS if k in options}
    overrides.setdefault("seed", DEFAULT_SEED)
    if "max_step" in options:
        step = options["max_step"]
        overrides["max_step"] = None if step is False else tuple(step)
    law = base.damping_law or DampingLaw()
    if not options.get("adaptive_damping", True):
        overrides["damping_law"] = None
    elif "singular_threshold" in options or "max_damping" in options:
        overrides["damping_law"] = DampingLaw(
            singular_threshold=options.get("singular_threshold", law.singular_threshold),
            max_damping=options.get("max_damping", law.max_damping),
            error_scale=law.error_scale,
        )
    try:
        return base.replace(**overrides)
    except InvalidOption as exc:  # the reader's ranges are tighter; kept as a safety net
        raise reader.fail(f"solver.{exc.field}", exc.expected) from exc


def _options_dict(options: SolveOptions) -> dict[str, Any]:
    """The run's options as plain data (the damping law as its fields)."""
    law = options.damping_law
    return {
        "tol_position": options.tol_position,
        "tol_orientation": options.tol_orientation,
        "max_iters": options.max_iters,
        "restarts": options.restarts,
        "seed": options.seed,
        "time_budget": options.time_budget,
        "alpha": options.alpha,
        "beta": options.beta,
        "max_step": jsonable(options.max_step),
        "stall_window": options.stall_window,
        "solver": options.solver,
        "damping": options.damping,
        "damping_law": None if law is None else jsonable(vars(law)),
    }


def _read_max_step(reader: Reader, value) -> list[float] | bool:
    """``max_step = [metres, radians]`` or ``false``."""
    if value is False:
        return False
    vector = reader.vector(value, "solver.max_step", 2, "[metres, radians] or false")
    for i, v in enumerate(vector):
        reader.number(float(v), f"solver.max_step[{i}]", "solver.max_step")
    return vector.tolist()


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
