"""What a problem run returns: :class:`ProblemResult` (with a :class:`TrackTrace` in track
mode and a :class:`StaticsReport` when the file asks for statics), their JSON output, and
the task and frame errors along the path (what :mod:`qpik.plots` draws).

Units: metres, radians, seconds, newtons; positions, forces and torques in world axes.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, Protocol

import mujoco
import numpy as np

from .. import statics as _statics
from ..errors import QpikError
from ..igm.qp_engine import set_frame_target
from ..igm.result import IKResult
from ..limits import checked_pairs, closest_pair, collision_limits
from ..model.configuration import Configuration, FrameType
from ..options import SolveOptions
from .goals import Goal
from .specs import TaskSpec


class Problem(Protocol):
    """What a run mode and a report read of a :class:`qpik.problem.Problem` (its fields
    and builders; the class itself is in :mod:`.loader`, which runs the modes)."""

    name: str
    robot: str
    mode: str
    model: mujoco.MjModel
    levels: list[list[TaskSpec]]
    velocity_limits: np.ndarray | None
    goals: list[Goal]
    dt: float
    steps: int
    stop_at_goal: bool
    solve_options: SolveOptions
    q0: np.ndarray

    def start_configuration(self) -> Configuration: ...
    def build_stack(self, start: Configuration | None = None) -> list[list]: ...
    def build_limits(self) -> list: ...
    def to_dict(self) -> dict[str, Any]: ...


def jsonable(value):
    """``value`` as JSON-ready data: arrays as lists, inf as ``"inf"``, NaN as None."""
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (np.floating, np.integer)):
        return jsonable(value.item())
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    return value


# ----------------------------------------------------------------------------- track
@dataclass
class TrackTrace:
    """What a ``mode = "track"`` run did, step by step.

    Attributes:
        dt: step [s].
        q: configurations ``(steps + 1, nq)``, the start first.
        velocity: joint velocities ``(steps, nv)`` [rad/s].
        residuals: per step, each level's weighted QP residual ``|A_k dq - b_k|``.
        sigma_min: per step, each level's smallest singular value.
        step_time: wall time of each :meth:`IKSolver.step` [s].
        goal_index: per step, the goal being tracked.
        active_limits: per step, how many limits bind.
        position_error, orientation_error: ``(steps + 1,)`` [m], [rad], the largest over
            the frames of the goal tracked.
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
        """Steps taken, all goals together."""
        return len(self.velocity)

    def to_dict(self) -> dict:
        """Plain data (step times as mean and max)."""
        times = self.step_time
        return {
            "dt": self.dt,
            "steps": self.steps,
            "converged": self.converged,
            "reason": self.reason,
            "q": self.q.tolist(),
            "velocity": self.velocity.tolist(),
            "residuals": jsonable(self.residuals),
            "position_error": self.position_error.tolist(),
            "orientation_error": self.orientation_error.tolist(),
            "max_velocity_ratio": jsonable(self.max_velocity_ratio),
            "step_time_mean": float(times.mean()) if len(times) else None,
            "step_time_max": float(times.max()) if len(times) else None,
        }


# ----------------------------------------------------------------------------- statics
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

    @classmethod
    def compute(
        cls,
        configuration: Configuration,
        frame: str,
        frame_type: FrameType,
        force: np.ndarray,
        torque: np.ndarray,
        payload_direction: np.ndarray | None,
    ) -> StaticsReport:
        """The report at ``configuration`` for a wrench at ``frame`` (world axes)."""
        tau = _statics.joint_torques(configuration, frame, force, torque, frame_type)
        gravity = _statics.gravity_torques(configuration)
        holding = _statics.holding_torques(configuration, [((frame, frame_type), force, torque)])
        try:
            limits = _statics.joint_torque_limits(configuration)
        except QpikError:
            limits = None
        within = None
        payload = None
        if limits is not None:
            within = bool(np.all((limits[:, 0] <= holding) & (holding <= limits[:, 1])))
            if payload_direction is not None:
                payload = _statics.max_payload(
                    configuration, frame, payload_direction, None, frame_type
                )
        return cls(frame, force, torque, tau, gravity, holding, limits, within, payload)

    def to_dict(self) -> dict:
        """Plain data (the payload with its mass in kg at g = 9.81 m/s^2)."""
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
                "force": jsonable(self.payload.force),
                "mass_kg": jsonable(self.payload.force / 9.81),
                "direction": self.payload.direction.tolist(),
                "limiting_joint": self.payload.limiting_joint,
                "holds_gravity": self.payload.holds_gravity,
            }
        return out

    def summary_lines(self) -> list[str]:
        """The lines :meth:`ProblemResult.summary` prints for it."""
        lines = [
            f"  statics at {self.frame!r}: force {np.array2string(self.force, precision=3)} N; "
            f"holding torques [N m] {np.array2string(self.holding, precision=2)}"
        ]
        if self.within_limits is not None:
            lines.append(f"  holding torques within actuator limits: {self.within_limits}")
        pay = self.payload
        if pay is not None and pay.feasible:
            lines.append(
                f"  max payload along {np.array2string(pay.direction, precision=2)}: "
                f"{pay.force:.1f} N ({pay.force / 9.81:.2f} kg), "
                + (
                    f"limited by {pay.limiting_joint}"
                    if pay.limiting_joint is not None
                    else "unbounded: no joint's torque grows with a load along it"
                )
            )
        elif pay is not None:
            lines.append("  max payload: none (the pose cannot be held)")
        return lines


# ----------------------------------------------------------------------------- errors
@dataclass
class ErrorCurve:
    """One curve of errors along a path: ``label``, ``level`` (task level, or -1 for a
    goal frame), ``unit`` (``"m"``, ``"rad"``, ``"rad or m"`` for a joint-space error
    such as a posture's, or ``""`` for a unitless one such as the joint-limit distance),
    ``values (k,)`` (NaN where it does not apply, e.g. a frame not in the goal being
    reached) and ``group`` (the task or frame it belongs to: its position and rotation parts
    share it)."""

    label: str
    level: int
    unit: str
    values: np.ndarray
    group: str = ""


def _task_error_parts(task, configuration: Configuration) -> list[tuple[str, float]]:
    """``(unit, norm)`` per part of a task's error ``e(q)``: a 6-row frame error as its
    position [m] and rotation [rad] halves, 3 rows of a frame task in their unit, a
    posture's joint-space error [rad or m], else ``|e|`` unitless (costs are not applied)."""
    error = np.asarray(task.compute_error(configuration), dtype=float)
    frame = getattr(task, "frame_name", None)
    if frame is not None and error.shape == (6,):
        return [("m", float(np.linalg.norm(error[:3]))), ("rad", float(np.linalg.norm(error[3:])))]
    unit = {
        "PositionTask": "m",
        "OrientationTask": "rad",
        "ComTask": "m",
        "PostureTask": "rad or m",
    }.get(type(task).__name__, "")
    return [(unit, float(np.linalg.norm(error)))]


# ----------------------------------------------------------------------------- result
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

    def _goal_paths(self) -> list[np.ndarray]:
        """Per goal (solve mode), the configurations of its returned attempt, without its
        first one when that is where the previous goal ended (the same configuration)."""
        previous, parts = self.problem.q0, []
        for r in self.results:
            part = r.path if len(r.path) else r.q[None]
            if np.array_equal(part[0], previous):
                part = part[1:]
            parts.append(part)
            previous = r.q
        return parts

    @property
    def path(self) -> np.ndarray:
        """Configurations along the way ``(k, nq)``: the start, then every step (track
        mode) or every iterate of each goal's returned attempt, goal after goal (solve
        mode; an attempt that began from a random restart begins with that restart)."""
        if self.trace is not None:
            return self.trace.q
        return np.concatenate([self.problem.q0[None], *self._goal_paths()])

    @property
    def goal_index(self) -> np.ndarray:
        """Per configuration of :attr:`path`, the goal it works toward ``(k,)``."""
        if self.trace is not None:
            return np.concatenate([[0], self.trace.goal_index]).astype(int)
        parts = [np.full(len(p), i) for i, p in enumerate(self._goal_paths())]
        return np.concatenate([[0], *parts]).astype(int)

    @property
    def iterations(self) -> int:
        """IK iterations (solve mode) or steps (track mode), all goals together."""
        if self.trace is not None:
            return self.trace.steps
        return sum(r.iterations for r in self.results)

    @property
    def residual_history(self) -> list[list[float]]:
        """Per iteration (all goals, in order) or per step, each level's QP residual."""
        if self.trace is not None:
            return self.trace.residuals
        return [row for r in self.results for row in r.residual_history]

    def frame_errors(self) -> list[ErrorCurve]:
        """Along :attr:`path`, per goal frame, its position error [m] and orientation error
        [rad] (the latter only for frames with a rotation target)."""
        problem = self.problem
        configuration = Configuration(problem.model)
        path, index = self.path, self.goal_index
        names = list(dict.fromkeys(f.frame for g in problem.goals for f in g.frames))
        values = {name: np.full((len(path), 2), np.nan) for name in names}
        for k, q in enumerate(path):
            configuration.update(q)
            for frame in problem.goals[index[k]].frames:
                values[frame.frame][k] = frame.error(configuration)
                if frame.target.rotation is None:
                    values[frame.frame][k, 1] = np.nan
        curves = []
        for name in names:
            curves.append(ErrorCurve(f"{name} position", -1, "m", values[name][:, 0], name))
            if not np.all(np.isnan(values[name][:, 1])):
                curves.append(ErrorCurve(f"{name} rotation", -1, "rad", values[name][:, 1], name))
        return curves

    def task_errors(self) -> list[ErrorCurve]:
        """Along :attr:`path`, each task's error ``|e(q)|`` (unweighted; a frame task's as
        position [m] and rotation [rad]), with the targets of the goal being reached: what
        each priority level asks, not the QP residual of a step."""
        problem = self.problem
        configuration = problem.start_configuration()
        levels = problem.build_stack(configuration)
        path, index = self.path, self.goal_index
        columns: dict[tuple[int, int, str], list[float]] = {}
        current = 0
        for k, q in enumerate(path):
            if index[k] != current:
                current = int(index[k])
                for frame in problem.goals[current].frames:
                    set_frame_target(levels, frame.frame, frame.target, frame.frame_type)
            configuration.update(q)
            for level, tasks in enumerate(levels):
                for j, task in enumerate(tasks):
                    for unit, value in _task_error_parts(task, configuration):
                        columns.setdefault((level, j, unit), []).append(value)
        return [
            ErrorCurve(
                f"L{level} {problem.levels[level][j].label()}",
                level,
                unit,
                np.array(values),
                f"{level}.{j}",
            )
            for (level, j, unit), values in columns.items()
        ]

    def collisions(self) -> dict[str, Any] | None:
        """What the file's collision limits checked: ``pairs`` (geom names),
        ``min_distance`` (their smallest ``d_min`` [m]); at the final :attr:`q`, the
        ``closest`` pair (the smallest ``d - d_min``) and its ``distance`` [m]
        (``mj_geomDistance``, capped at ``d_min`` + 1 m; negative when they penetrate);
        ``path_closest`` and ``path_distance``: the same over every configuration of
        :attr:`path`. None when the file has no collision limit (collisions not
        checked)."""
        limits = collision_limits(self.problem.build_limits())
        if not limits:
            return None
        configuration = Configuration(self.problem.model)
        along = []
        for q in self.path:
            configuration.update(q)
            found = closest_pair(configuration.model, configuration.data, limits)
            assert found is not None  # limits holds a collision limit
            along.append(found)
        worst = min(along, key=lambda found: found[2])  # the first among equals
        return {
            "pairs": checked_pairs(limits),
            "min_distance": min(float(c.minimum_distance_from_collisions) for c in limits),
            "closest": list(along[-1][0]),
            "distance": along[-1][1],
            "path_closest": list(worst[0]),
            "path_distance": worst[1],
        }

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
            lines += _trace_lines(self.trace)
        for i, r in enumerate(self.results):
            label = "target" if len(self.results) == 1 else f"waypoint {i}"
            lines.append(
                f"  {label}: {r.reason}, {r.iterations} iterations, {r.restarts_used} restarts, "
                f"position error {r.position_error:.3g} m, orientation error "
                f"{r.orientation_error:.3g} rad"
            )
            if len(r.frame_errors) > 1:  # a goal of several frames: each one's errors
                lines += [
                    f"    {frame}: {p:.3g} m, {o:.3g} rad"
                    for frame, (p, o) in r.frame_errors.items()
                ]
        lines.append(f"  q = {np.array2string(self.q, precision=4)}")
        collisions = self.collisions()
        if collisions is not None:
            lines.append(_collision_line(collisions))
        if self.statics is not None:
            lines += self.statics.summary_lines()
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """Plain data: the problem, the outcome, per goal results or the trace, statics."""
        return {
            "problem": self.problem.to_dict(),
            "converged": self.converged,
            "reason": self.reason,
            "q": self.q.tolist(),
            "iterations": self.iterations,
            "solve_time": self.solve_time,
            "results": [_ik_result_dict(r) for r in self.results],
            "trace": None if self.trace is None else self.trace.to_dict(),
            "statics": None if self.statics is None else self.statics.to_dict(),
            "collisions": jsonable(self.collisions()),
        }

    def to_json(self, indent: int | None = 2) -> str:
        """:meth:`to_dict` as JSON."""
        return json.dumps(self.to_dict(), indent=indent)


def _collision_line(c: dict[str, Any]) -> str:
    a, b = c["closest"]
    pa, pb = c["path_closest"]
    return (
        f"  collisions checked: {len(c['pairs'])} geom pair(s) kept {c['min_distance']:g} m "
        f"apart; closest at q: {a}-{b} {c['distance']:.4g} m, along the path: {pa}-{pb} "
        f"{c['path_distance']:.4g} m"
    )


def _trace_lines(t: TrackTrace) -> list[str]:
    lines = [
        f"  final error: position {t.position_error[-1]:.3g} m, orientation "
        f"{t.orientation_error[-1]:.3g} rad; step time mean "
        f"{1e6 * t.step_time.mean():.0f} us, max {1e6 * t.step_time.max():.0f} us"
    ]
    if not math.isnan(t.max_velocity_ratio):
        lines.append(f"  max |v| / v_max = {t.max_velocity_ratio:.3f}")
    if t.residuals:
        levels = ", ".join(f"{r:.3g}" for r in t.residuals[-1])
        lines.append(f"  final level residuals: {levels}")
    return lines


def _ik_result_dict(r: IKResult) -> dict[str, Any]:
    return {
        "converged": r.converged,
        "reason": r.reason,
        "q": r.q.tolist(),
        "iterations": r.iterations,
        "restarts_used": r.restarts_used,
        "position_error": r.position_error,
        "orientation_error": r.orientation_error,
        "frame_errors": jsonable(r.frame_errors),
        "residual_history": jsonable(r.residual_history),
        "solve_time": r.solve_time,
    }
