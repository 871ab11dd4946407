r"""The inverse geometric model: iterate differential IK steps until the targets are met.

The lecture's recursion, for each frame with a target,

.. math::

    c = x_{des} - x(q_i), \qquad J(q_i)\, \dot q = \alpha\, c, \qquad
    q_{i+1} = q_i + \beta\, \dot q,

runs here on :class:`qpik.IKSolver` steps with ``dt = 1``: ``alpha`` is the gain of the
target tasks (the QP asks ``J dq = -alpha e``, ``e = x(q) - x_des``) and ``beta`` scales the
displacement the QP returns before it is applied. The QP adds what the lecture's
pseudoinverse lacks: joint limits hold at every iterate (``beta <= 1`` keeps them by
convexity; a ``beta > 1`` iterate is clipped into the limits), steps stay bounded near
singularities (adaptive damping), and lower levels (by default, distance from the joint
limits, on redundant arms) act only in the null space of the targets.

Errors: position error is the distance of the frame origin to its target [m]; orientation
error the angle of ``R R_des^T`` [rad]. A solve has converged when every frame is within
``tol_position`` and ``tol_orientation``.

When an attempt stops making progress the reason is diagnosed (``at_limit``: a joint limit
binds; ``singular``: the target level's smallest singular value is below the damping
threshold; ``stalled`` otherwise) and the solve restarts from a random configuration
within the limits, while restarts and time remain. The best iterate over all attempts is
returned.
"""

from __future__ import annotations

import functools
import math
import os
import sys
import time
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mink
import mujoco
import numpy as np
import numpy.typing as npt

from .configuration import Configuration, FrameType, as_configuration, frame_names
from .errors import InvalidInput, InvalidTarget, UnknownFrame
from .hierarchy import DampingLaw, IKSolver, Stack, normalize_stack
from .limits import ConfigurationLimit
from .qp import OSQPSettings
from .robots import load_robot, robots_dir
from .tasks import (
    FrameTask,
    JointLimitDistanceTask,
    OrientationTask,
    PoseTask,
    PositionTask,
)
from .tasks.frame import checked_position, checked_rotation

__all__ = [
    "REASONS",
    "FrameKey",
    "RobotLike",
    "TargetLike",
    "clear_pool",
    "IKResult",
    "Target",
    "parse_target",
    "set_frame_target",
    "solve",
]

#: Why a solve ended. ``converged`` is the only success.
REASONS = {
    "converged": "every frame is within tolerance of its target",
    "max_iters": "the iteration limit of the last attempt was reached",
    "time_budget": "the time budget ran out",
    "stalled": "no progress, for no diagnosed reason (the target may be out of reach)",
    "at_limit": "no progress while a joint limit binds",
    "singular": "no progress at a singular configuration",
}


#: The damping law of :func:`solve`: the velocity-control law, fading with the error.
IGM_DAMPING = DampingLaw(error_scale=0.3)


@dataclass(frozen=True)
class Target:
    """A target for one frame: a position [m] in the world frame and, optionally, a
    rotation matrix (world frame)."""

    position: np.ndarray
    rotation: np.ndarray | None = None


#: What :func:`solve` accepts as a robot: anything :func:`qpik.load_robot` takes, or a
#: :class:`qpik.Configuration`.
RobotLike = str | os.PathLike | mujoco.MjModel | Configuration
#: A target frame: a name (site, then body, then geom) or ``(name, frame_type)``.
FrameKey = str | tuple[str, FrameType | str]
#: A target: a position (3,), ``(position, rotation)``, a 4x4 matrix, an SE3 or a Target.
TargetLike = Target | mink.SE3 | npt.ArrayLike | tuple[npt.ArrayLike, npt.ArrayLike]


def parse_target(value: TargetLike) -> Target:
    """A :class:`Target` from a position ``(3,)``, a ``(position, rotation)`` pair, a 4x4
    homogeneous matrix, a ``mink.SE3`` or a ``Target``; NaN / malformed input raises
    :class:`qpik.InvalidTarget`."""
    if isinstance(value, Target):
        position, rotation = value.position, value.rotation
    elif isinstance(value, mink.SE3):
        position, rotation = value.translation(), value.rotation().as_matrix()
    elif isinstance(value, tuple) and len(value) == 2:
        position, rotation = value
    else:
        array = np.asarray(value, dtype=float)
        if array.shape == (4, 4):
            if not np.allclose(array[3], [0, 0, 0, 1]):
                raise InvalidTarget("a 4x4 target's last row must be (0, 0, 0, 1)")
            position, rotation = array[:3, 3], array[:3, :3]
        elif array.shape == (3,):
            position, rotation = array, None
        else:
            raise InvalidTarget(
                f"a target is a position (3,), (position, rotation), a 4x4 matrix or an SE3; "
                f"got an array of shape {array.shape}"
            )
    position = checked_position(position)
    if rotation is not None:
        rotation = checked_rotation(rotation)
    return Target(position, rotation)


_OBJ = {
    FrameType.SITE: mujoco.mjtObj.mjOBJ_SITE,
    FrameType.BODY: mujoco.mjtObj.mjOBJ_BODY,
    FrameType.GEOM: mujoco.mjtObj.mjOBJ_GEOM,
}


def _resolve_frame(model: mujoco.MjModel, key) -> tuple[str, FrameType]:
    """A target key: ``"name"`` (a site, else a body, else a geom) or ``(name, type)``."""
    if isinstance(key, tuple):
        name, kind = key
        kind = FrameType.parse(kind)
        if mujoco.mj_name2id(model, _OBJ[kind], name) < 0:
            raise UnknownFrame(name, kind.value, frame_names(model, kind))
        return name, kind
    for kind in (FrameType.SITE, FrameType.BODY, FrameType.GEOM):
        if mujoco.mj_name2id(model, _OBJ[kind], key) >= 0:
            return key, kind
    raise UnknownFrame(key, "site or body", frame_names(model, "site") + frame_names(model, "body"))


def _parse_targets(model: mujoco.MjModel, targets: Mapping) -> list[tuple[str, FrameType, Target]]:
    if not targets:
        raise InvalidTarget("no targets given: pass {frame: target, ...}")
    frames = []
    for key, value in targets.items():
        name, kind = _resolve_frame(model, key)
        frames.append((name, kind, parse_target(value)))
    return frames


@dataclass
class IKResult:
    """The outcome of :func:`solve`.

    Attributes:
        q: the best configuration found ``(nq,)``, always within the joint limits.
        converged: whether every frame is within tolerance at ``q``.
        reason: one of :data:`REASONS`.
        iterations: IK steps taken, all attempts together.
        restarts_used: random restarts made after the first attempt.
        position_error: largest frame position error at ``q`` [m].
        orientation_error: largest frame orientation error at ``q`` [rad] (0 without
            orientation targets).
        frame_errors: per frame, ``(position_error, orientation_error)``.
        residual_history: per iteration of the returned attempt, each level's QP residual
            ``|A_k dq - b_k|`` (what the solver minimised at that step).
        error_history: per iteration of the returned attempt (its start first), the largest
            frame ``(position_error [m], orientation_error [rad])``.
        path: the configurations of the returned attempt, its start first ``(k, nq)``.
        solve_time: wall time [s].
    """

    q: np.ndarray
    converged: bool
    reason: str
    iterations: int
    restarts_used: int
    position_error: float
    orientation_error: float
    frame_errors: dict[str, tuple[float, float]] = field(default_factory=dict)
    residual_history: list[list[float]] = field(default_factory=list, repr=False)
    error_history: list[tuple[float, float]] = field(default_factory=list, repr=False)
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), repr=False)
    solve_time: float = 0.0

    def __str__(self) -> str:
        state = "converged" if self.converged else f"not converged ({self.reason})"
        return (
            f"IK {state} in {self.iterations} iterations, {self.restarts_used} restarts, "
            f"{1e3 * self.solve_time:.2f} ms: position error {self.position_error:.3g} m, "
            f"orientation error {self.orientation_error:.3g} rad\n"
            f"q = {np.array2string(self.q, precision=4)}"
        )


class _Problem:
    """What a solve iterates: a scratch configuration, the stack and its solver.

    Problems built from the default stack are pooled per model and target structure (see
    :func:`_acquire`), so that repeated solves skip allocating MuJoCo data, tasks and QP
    workspaces; the targets are set anew for every solve.
    """

    def __init__(
        self, model, frames, stack, limits, alpha, solver, damping_law, secondary, damping
    ):
        if not 0.0 < alpha <= 1.0:
            raise InvalidInput(f"alpha must be in (0, 1] (a task gain), got {alpha}")
        self.configuration = Configuration(model)
        self.custom_stack = stack is not None
        self.target_tasks: list[PositionTask | PoseTask] = []
        if stack is None:
            primary = []
            rows = 0
            for name, kind, target in frames:
                if target.rotation is None:
                    task = PositionTask(name, kind, gain=alpha)
                    rows += 3
                else:
                    task = PoseTask(name, kind, gain=alpha)
                    rows += 6
                primary.append(task)
                self.target_tasks.append(task)
            levels = [primary]
            if model.nv > rows and secondary:
                levels.append([JointLimitDistanceTask(cost=1.0, gain=0.5)])
        else:
            levels = normalize_stack(stack)
        if isinstance(limits, str):
            if limits != "joint":
                raise InvalidInput(
                    f"limits must be 'joint', None or a list of limits, got {limits!r}"
                )
            limits = [ConfigurationLimit(model)]
        self.limits = list(limits or ())
        # Iterates need no more accuracy than it takes to find the active set: the
        # refinement step then makes each step exact.
        self.solver = IKSolver(
            model,
            levels,
            self.limits,
            solver=solver,
            damping=damping,
            damping_law=damping_law,
            osqp_settings=OSQPSettings(eps_abs=1e-5, eps_rel=1e-5),
        )
        self.levels = levels
        self.alpha = alpha
        self.primary = [
            t
            for t in levels[0]
            if isinstance(t, (PositionTask, OrientationTask, PoseTask, FrameTask))
        ]
        self.base_gains = [alpha] * len(self.primary)
        self.frames = frames

    def set_targets(self, frames: list[tuple[str, FrameType, Target]]) -> None:
        """Set the targets of this solve on the stack's tasks."""
        self.frames = frames
        if self.custom_stack:
            _set_stack_targets(self.levels, frames)
            self.base_gains = [task.gain for task in self.primary]  # the user's gains
            return
        for task, (_, _, target) in zip(self.target_tasks, frames):
            if isinstance(task, PoseTask):
                task.set_target(target.position, target.rotation)
            else:
                task.set_target(target.position)
            task.gain = self.alpha

    def clamp_gains(
        self,
        errors: Mapping[str, tuple[float, float]],
        max_position_step: float,
        max_orientation_step: float,
    ) -> None:
        """Trust region: scale the target tasks' gains so that no iteration asks for more
        than ``max_position_step`` [m] or ``max_orientation_step`` [rad]."""
        for task, base_gain in zip(self.primary, self.base_gains):
            if task.frame_name not in errors:
                continue
            position_error, orientation_error = errors[task.frame_name]
            position_limit = max_position_step / max(position_error, 1e-12)
            orientation_limit = max_orientation_step / max(orientation_error, 1e-12)
            if isinstance(task, PositionTask):
                limit = position_limit
            elif isinstance(task, OrientationTask):
                limit = orientation_limit
            else:  # a pose: one gain for both parts, the tighter one
                limit = min(position_limit, orientation_limit)
            task.gain = min(base_gain, limit)

    def restore_gains(self) -> None:
        """Give the target tasks back the gains they had before the solve."""
        for task, base_gain in zip(self.primary, self.base_gains):
            task.gain = base_gain

    def errors(self, configuration: Configuration) -> dict[str, tuple[float, float]]:
        """Per frame, (position error [m], orientation error [rad]) at ``configuration``."""
        result = {}
        for name, kind, target in self.frames:
            position, rotation = configuration.frame_pose(name, kind)
            position_error = float(np.linalg.norm(position - target.position))
            orientation_error = 0.0
            if target.rotation is not None:
                cosine = (np.trace(rotation @ target.rotation.T) - 1.0) / 2.0
                orientation_error = float(math.acos(min(1.0, max(-1.0, cosine))))
            result[name] = (position_error, orientation_error)
        return result


_POOL: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _acquire(
    model, frames, stack, limits, alpha, solver, damping_law, secondary, damping
) -> _Problem:
    """A problem for this model and target structure: from the pool when the stack is the
    default and the limits are ``"joint"`` or none, else a new one."""
    poolable = stack is None and (limits is None or isinstance(limits, str))
    if poolable:
        structure = tuple((name, kind, t.rotation is not None) for name, kind, t in frames)
        key = (structure, limits, alpha, solver, damping_law, secondary, damping)
        free = _POOL.setdefault(model, {}).setdefault(key, [])
        if free:
            problem = free.pop()
            problem.set_targets(frames)
            return problem
    problem = _Problem(model, frames, stack, limits, alpha, solver, damping_law, secondary, damping)
    problem.set_targets(frames)
    problem.pool_key = key if poolable else None
    return problem


def _release(problem: _Problem) -> None:
    """Give a pooled problem back (at most a few per key are kept)."""
    problem.restore_gains()
    if problem.pool_key is None:
        return
    free = _POOL.setdefault(problem.configuration.model, {}).setdefault(problem.pool_key, [])
    if len(free) < 4:
        free.append(problem)


def clear_pool() -> None:
    """Forget the scratch problems :func:`solve` keeps per model (and the robots it loaded
    by name): needed only after editing a model in place (its joint ranges, say)."""
    _POOL.clear()
    _load_cached.cache_clear()


@functools.lru_cache(maxsize=16)
def _load_cached(source: str, mtime: float) -> mujoco.MjModel:
    return load_robot(source)


def _model_of(robot) -> tuple[mujoco.MjModel, np.ndarray | None]:
    """The model of ``robot`` and, for a Configuration, its ``q``. Names and paths are
    loaded once (and again when the file changes)."""
    if isinstance(robot, Configuration):
        return robot.model, robot.q
    if isinstance(robot, mujoco.MjModel):
        return robot, None
    if isinstance(robot, (str, os.PathLike)):
        text = os.fspath(robot)
        path = Path(text)
        if not path.exists() and not text.startswith("erd:"):
            path = robots_dir() / f"{text}.xml"
        mtime = path.stat().st_mtime if path.exists() else 0.0
        return _load_cached(text, mtime), None
    return as_configuration(robot).model, None


def set_frame_target(levels: Sequence[Sequence], frame: str, target: Target) -> bool:
    """Set ``target`` on every task of ``levels`` that regulates ``frame`` (position,
    orientation, pose and mink frame tasks); returns whether any task does."""
    matched = False
    for task in (t for level in levels for t in level):
        if getattr(task, "frame_name", None) != frame:
            continue
        matched = True
        if isinstance(task, PositionTask):
            task.set_target(target.position)
        elif isinstance(task, OrientationTask):
            if target.rotation is not None:
                task.set_target(target.rotation)
        elif isinstance(task, (PoseTask, FrameTask)):
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
    return matched


def _set_stack_targets(levels, frames) -> None:
    """Set each frame's target on the stack's tasks; every frame must have a task."""
    for name, _kind, target in frames:
        if not set_frame_target(levels, name, target):
            raise InvalidTarget(f"no task in the given stack regulates frame {name!r}")


def solve(
    robot: RobotLike,
    targets: Mapping[FrameKey, TargetLike],
    *,
    q0: npt.ArrayLike | None = None,
    stack: Stack | None = None,
    limits: str | Sequence[mink.Limit] | None = "joint",
    tol_position: float = 1e-4,
    tol_orientation: float = 1e-3,
    max_iters: int = 100,
    time_budget: float | None = None,
    restarts: int | None = None,
    seed: int | np.random.Generator | None = None,
    alpha: float = 1.0,
    beta: float = 1.0,
    solver: str = "osqp",
    stall_window: int = 5,
    damping_law: DampingLaw | None = IGM_DAMPING,
    max_step: tuple[float, float] | None = (0.2, 0.5),
    secondary: bool = False,
    damping: float = 1e-6,
) -> IKResult:
    """Solve inverse kinematics for one or several frame targets.

    Args:
        robot: anything :func:`qpik.load_robot` accepts, or a :class:`qpik.Configuration`
            (left unchanged; its ``q`` is the default start).
        targets: ``{frame: target}``; a frame is a site, body or geom name (sites first) or
            ``(name, frame_type)``; a target is a position (3,) [m], ``(position,
            rotation)``, a 4x4 matrix or a ``mink.SE3``, all in the world frame.
        q0: start configuration (default: the configuration's ``q``, or the mid-range).
            Must lie within the joint limits.
        stack: a task stack to use instead of the default (position/orientation tasks in
            level 0; see ``secondary``); targets are set on its tasks whose ``frame_name``
            matches.
        limits: ``"joint"`` (position limits of the model), ``None`` or a list of limits.
        tol_position: [m]; tol_orientation: [rad].
        max_iters: iterations per attempt.
        time_budget: [s] for the whole solve, restarts included (``None``: no limit).
        restarts: random restarts allowed after the first attempt; ``None`` (default):
            as many as ``time_budget`` allows, or 20 without a budget.
        seed: seed of the restarts' random configurations (same seed, same result).
        alpha: gain of the target tasks in (0, 1]; beta: step scale (> 0).
        solver: QP backend (see :class:`qpik.IKSolver`).
        stall_window: iterations without a 1 % improvement that count as no progress.
        damping_law: singularity damping; for a solve it also fades with the error.
        max_step: trust region ``(metres, radians)``: no iteration asks a target task for
            more than this (``None``: full steps, the lecture's recursion).
        damping: constant Tikhonov damping of every level (see :class:`qpik.IKSolver`).
        secondary: with the default stack on a redundant arm, add distance from the joint
            limits as a level-1 objective in the null space of the targets (about 1.5x the
            time per iteration).

    Scratch data, tasks and QP workspaces are reused between calls on the same model, and
    robots given by name are loaded once: after editing a model in place, call
    :func:`clear_pool`.
    """
    start_time = time.perf_counter()
    if not beta > 0 or not math.isfinite(beta):
        raise InvalidInput(f"beta must be a positive number, got {beta}")
    if restarts is None:
        restarts = 20 if time_budget is None else sys.maxsize
    model, robot_q = _model_of(robot)
    frames = _parse_targets(model, targets)
    problem = _acquire(model, frames, stack, limits, alpha, solver, damping_law, secondary, damping)
    settings = _Settings(
        tol_position,
        tol_orientation,
        max_iters,
        time_budget,
        restarts,
        beta,
        stall_window,
        damping_law,
        max_step,
    )
    try:
        return _iterate(problem, q0 if q0 is not None else robot_q, start_time, seed, settings)
    finally:
        _release(problem)


@dataclass(frozen=True)
class _Settings:
    """The loop options of :func:`solve` (documented there)."""

    tol_position: float
    tol_orientation: float
    max_iters: int
    time_budget: float | None
    restarts: int
    beta: float
    stall_window: int
    damping_law: DampingLaw | None
    max_step: tuple[float, float] | None


def _iterate(problem: _Problem, q0, start_time: float, seed, settings: _Settings) -> IKResult:
    """The IGM loop of :func:`solve` on a prepared problem."""
    tol_position, tol_orientation = settings.tol_position, settings.tol_orientation
    max_iters, time_budget, restarts = settings.max_iters, settings.time_budget, settings.restarts
    beta, stall_window, max_step = settings.beta, settings.stall_window, settings.max_step
    damping_law = settings.damping_law
    configuration = problem.configuration
    configuration.update(q0 if q0 is not None else configuration.mid_q())
    configuration.check_limits()
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    lower, upper = configuration.lower, configuration.upper
    threshold = damping_law.singular_threshold if damping_law is not None else 0.0

    def score(errors) -> float:
        return max(p / tol_position + o / tol_orientation for p, o in errors.values())

    def worst(errors) -> tuple[float, float]:
        return max(p for p, _ in errors.values()), max(o for _, o in errors.values())

    best_q, best_errors = configuration.q, problem.errors(configuration)
    best_history: list[list[float]] = []
    best_error_history = [worst(best_errors)]
    best_path = [best_q]
    best_score = score(best_errors)
    total_iterations = 0
    attempt = 0
    reason = "max_iters"
    while True:
        history: list[list[float]] = []
        errors = problem.errors(configuration)
        error_history = [worst(errors)]
        path = [configuration.q]
        current = score(errors)
        window_start = current
        since_progress = 0
        attempt_reason = "max_iters"
        last_step = None
        for _ in range(max_iters):
            if current <= 1.0:
                attempt_reason = "converged"
                break
            if time_budget is not None and time.perf_counter() - start_time > time_budget:
                attempt_reason = "time_budget"
                break
            if max_step is not None:
                problem.clamp_gains(errors, *max_step)
            last_step = problem.solver.step(configuration, 1.0)
            total_iterations += 1
            history.append(last_step.residuals)
            q = configuration.integrate(beta * last_step.displacement, 1.0)
            if beta > 1.0:
                q = np.clip(q, lower, upper)
            configuration.update(q)
            errors = problem.errors(configuration)
            error_history.append(worst(errors))
            path.append(q)
            current = score(errors)
            if _norm(last_step.displacement) < 1e-9:
                # A vanishing step that leaves the error: nothing more comes of this start.
                attempt_reason = _diagnose(last_step, threshold)
                break
            if current < 0.99 * window_start:
                window_start = current
                since_progress = 0
            else:
                since_progress += 1
                if since_progress >= stall_window:
                    attempt_reason = _diagnose(last_step, threshold)
                    break
        else:
            if current <= 1.0:
                attempt_reason = "converged"
        if current < best_score:
            best_q, best_errors, best_score = configuration.q, errors, current
            best_history, best_error_history, best_path = history, error_history, path
        reason = attempt_reason
        out_of_time = time_budget is not None and time.perf_counter() - start_time > time_budget
        if attempt_reason == "converged" or attempt >= restarts or out_of_time:
            if out_of_time and attempt_reason != "converged":
                reason = "time_budget"
            break
        attempt += 1
        configuration.update(configuration.random_q(rng))
    converged = best_score <= 1.0
    return IKResult(
        q=best_q,
        converged=converged,
        reason="converged" if converged else reason,
        iterations=total_iterations,
        restarts_used=attempt,
        position_error=worst(best_errors)[0],
        orientation_error=worst(best_errors)[1],
        frame_errors=best_errors,
        residual_history=best_history,
        error_history=best_error_history,
        path=np.array(best_path),
        solve_time=time.perf_counter() - start_time,
    )


def _norm(vector: np.ndarray) -> float:
    return float(np.sqrt(vector @ vector))


def _diagnose(step, singular_threshold: float) -> str:
    """Why an attempt stopped making progress."""
    if step is None:
        return "stalled"
    if step.active_limits:
        return "at_limit"
    if step.sigma_min and step.sigma_min[0] < singular_threshold:
        return "singular"
    return "stalled"
