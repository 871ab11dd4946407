"""The viewer's solver: a task stack re-solved from the current configuration each time a
goal frame moves (no viser here; :class:`LiveSolve` runs and is tested without it).

A *drag solve* (:meth:`LiveSolve.solve`) runs :class:`qpik.IKSolver` steps from the
current configuration, as :mod:`qpik.problem.modes`'s tracking does, until every goal
frame is within tolerance and the step has settled (``|dq|_inf`` below
:attr:`LiveSolve.settle`), or ``max_iterations`` steps. Strict priorities, limits and
damping are the stack's: a lower level never disturbs a higher one, and every limit
holds at every step. Starting from the current ``q`` (not from random restarts, as
:func:`qpik.solve` may) keeps the robot continuous while a handle is dragged.

A trust region (:attr:`LiveSolve.max_step`, as :attr:`qpik.SolveOptions.max_step`): no
step asks a goal frame to move by more than ``(metres, radians)``; a farther target is
approached along the straight line (position) and the shortest rotation, by that much
per step. The priorities stay exact (the step itself is never rescaled).

Level 0 held exactly: a step meets its levels to first order, so a large step (a target
far away, or out of reach) leaves a second-order drift (``|dq|^2``) on what level 0 holds
(the feet of a humanoid). When level 0 holds no goal frame, each step whose level-0 error
exceeds ``tol_position`` is followed by Newton steps of level 0 alone (up to
:data:`CORRECTIONS`), under the same limits (as ``examples/humanoid_talos.py`` does),
which removes that drift.

Each level's state after a solve (:class:`LevelReport`): ``"met"``, ``"compromise"``
(solved, but a residual remains because a higher level or a limit takes the freedom it
would need: the expected state of a posture level below a pose), ``"unmet"`` (the level
cannot be met: its QP was not solved, or it holds a goal frame, or it is level 0, and its
error stays above tolerance when the solve ends) or ``"pending"`` (a report of no step, as
after the robot is moved by hand: a goal not within tolerance, not yet solved for; status
``"not solved yet"``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, TypedDict, Unpack

import mujoco
import numpy as np
import numpy.typing as npt

from ..core import checks
from ..diffik.solver import IKSolver, StepResult, normalize_stack
from ..errors import InvalidArgumentType, InvalidInput, InvalidOption, InvalidTarget
from ..igm.qp_engine import set_frame_target
from ..igm.targets import Target, parse_target
from ..limits import joint_limits
from ..model.configuration import Configuration, FrameType
from ..model.frames import resolve_frame
from ..model.rotations import orientation_angle
from ..options import MAX_ITERS_LIMIT, StepOptions, check_integer, check_number
from ..tasks import OrientationTask, PoseTask, PositionTask

__all__ = ["GoalFrame", "LevelReport", "LiveSolve", "SolveReport", "describe_task"]

#: Newton steps of level 0 alone after a step, at most (module docstring).
CORRECTIONS = 3
#: Residual [task units] under which a solved level counts as met.
MET_RESIDUAL = 1e-6


@dataclass
class GoalFrame:
    """A frame with a draggable target.

    Attributes:
        name, frame_type: the frame (site, body or geom).
        levels: the levels whose tasks regulate it.
        rotation: whether a task regulates its orientation (else the handle only
            translates and the target has no rotation).
        target: the current target (position [m], rotation or ``None``; world frame).
    """

    name: str
    frame_type: FrameType
    levels: list[int]
    rotation: bool
    target: Target


@dataclass
class LevelReport:
    """One level after a drag solve.

    Attributes:
        index: 0 is the highest priority; ``tasks``: what it holds, in words.
        status: the last step's :class:`qpik.LevelStatus` value (``"solved"``, ...).
        residual: the last step's weighted residual ``|A dq - b|`` of the level (NaN when
            not solved since the robot moved).
        damping: the last step's ``lambda^2`` (adaptive singularity damping; NaN likewise).
        active_limits: the limits binding at the last step (``"joint4 upper ..."``).
        state: ``"met"``, ``"compromise"``, ``"unmet"`` or ``"pending"`` (module docstring).
        goal_error: the worst ``(position [m], orientation [rad])`` error of the level's
            goal frames (orientation NaN where none of them has its orientation
            regulated), or ``None`` when it holds none.
    """

    index: int
    tasks: list[str]
    status: str
    residual: float
    damping: float
    active_limits: list[str]
    state: str
    goal_error: tuple[float, float] | None = None

    @property
    def ok(self) -> bool:
        """Whether the level can be met (state not ``"unmet"``)."""
        return self.state != "unmet"


@dataclass
class SolveReport:
    """What one drag solve did.

    Attributes:
        q: the configuration after it ``(nq,)``.
        steps: IK steps taken; ``solve_time``: their wall time [s] (steps, integration
            and convergence checks).
        converged: every goal frame within tolerance and the step settled.
        levels: one :class:`LevelReport` per level.
        goal_errors: ``{frame: (position error [m], orientation error [rad])}``.
        last_step: the last :class:`qpik.StepResult` (``None`` when no step ran).
    """

    q: np.ndarray
    steps: int
    solve_time: float
    converged: bool
    levels: list[LevelReport]
    goal_errors: dict[str, tuple[float, float]]
    last_step: StepResult | None = field(default=None, repr=False)


def describe_task(task: Any) -> str:
    """A task in a few words: its class and frame (``PositionTask ee``)."""
    name = type(task).__name__
    frame = getattr(task, "frame_name", None)
    if frame is None and hasattr(task, "root_name"):  # mink's RelativeFrameTask
        frame = task.root_name
    return f"{name} {frame}" if frame else name


def _regulates_rotation(task: Any) -> bool:
    if isinstance(task, (OrientationTask, PoseTask)):
        return True
    if isinstance(task, PositionTask):
        return False
    cost = getattr(task, "cost", None)  # mink.FrameTask: 6 costs, the last 3 angular
    return cost is not None and np.size(cost) == 6 and bool(np.any(np.asarray(cost)[3:] > 0))


def goal_frames_of(levels: Sequence[Sequence[Any]]) -> list[tuple[str, FrameType]]:
    """The frames regulated by a frame, position, orientation or pose task, in stack
    order (each once)."""
    seen: dict[str, FrameType] = {}
    for level in levels:
        for task in level:
            name = getattr(task, "frame_name", None)
            if name is None or name in seen:
                continue
            seen[name] = FrameType.parse(getattr(task, "frame_type", FrameType.SITE))
    return list(seen.items())


class LiveSettings(TypedDict, total=False):
    """How :class:`LiveSolve` iterates: ``dt`` (the step's time [s], default 1),
    ``tol_position`` [m] (1e-4) and ``tol_orientation`` [rad] (1e-3), ``max_iterations``
    per drag solve (20), ``max_step`` (the trust region ``(metres, radians)``, default
    ``(0.2, 0.5)``; ``None``: none) and ``settle`` [rad or m] (1e-4)."""

    dt: float
    tol_position: float
    tol_orientation: float
    max_iterations: int
    max_step: tuple[float, float] | None
    settle: float


class LiveSolve:
    """A task stack on a configuration, re-solved after each move of a goal frame.

    Args:
        model: the MuJoCo model.
        levels: task stack (see :func:`qpik.diffik.solver.normalize_stack`), level 0 first;
            tasks on goal frames receive the targets.
        limits: limits holding at every step (default: the joint position limits).
        goals: the frames with a draggable target: names or ``(name, frame_type)`` (one
            name alone: that frame); default: every frame regulated by a frame, position,
            orientation or pose task.
        q0: start configuration ``(nq,)`` (default: the model's ``qpos0``).
        targets: start targets ``{goal frame: target}`` (a :class:`qpik.Target` or what
            :func:`qpik.igm.targets.parse_target` takes; default: each frame's pose at
            ``q0``); a frame that is not a goal: :class:`qpik.InvalidOption`.
        step_options: :class:`qpik.StepOptions` of the steps.
        level_names: the names of each level's tasks in the panel, one sequence of str
            per level (default: described from the tasks).

    Keyword Args:
        dt: the step's time [s] (velocity limits bound a step to ``v_max dt``).
        tol_position: [m]; ``tol_orientation``: [rad], when a goal frame is reached
            (finite, > 0).
        max_iterations: steps per drag solve at most (an int in [0, 100000]).
        max_step: trust region ``(metres, radians)``, both finite and > 0: what one step
            may ask of a goal frame at most; ``None``: no trust region.
        settle: a step with ``|dq|_inf`` below this [rad or m] has settled (finite, > 0).

    The settings take the ranges :class:`qpik.SolveOptions` gives the same names
    (``max_iterations`` is its ``max_iters``); out of range: :class:`qpik.InvalidOption`
    naming the setting.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        levels: Any,
        limits: Iterable[Any] | None = None,
        goals: Sequence[str | tuple[str, FrameType | str]] | None = None,
        q0: npt.ArrayLike | None = None,
        targets: dict[str, Target] | None = None,
        step_options: StepOptions | None = None,
        level_names: Sequence[Sequence[str]] | None = None,
        **settings: Unpack[LiveSettings],
    ):
        checks.check_keywords("LiveSolve", dict(settings), LiveSettings)
        checks.check_instance("model", model, mujoco.MjModel, "a mujoco.MjModel")
        self.dt = checks.check_dt(settings.get("dt", 1.0))
        self.tol_position = check_number("tol_position", settings.get("tol_position", 1e-4))
        self.tol_orientation = check_number(
            "tol_orientation", settings.get("tol_orientation", 1e-3)
        )
        self.max_iterations = check_max_iterations(settings.get("max_iterations", 20))
        self.max_step = check_max_step(settings.get("max_step", (0.2, 0.5)))
        self.settle = check_number("settle", settings.get("settle", 1e-4))
        self.model = model
        self.configuration = Configuration(model, q0)
        self.levels: list[list[Any]] = normalize_stack(levels)
        self.limits = list(joint_limits(model) if limits is None else limits)
        self.solver = IKSolver(model, self.levels, self.limits, options=step_options)
        self._correction: IKSolver | None = None
        self.level_names = (
            _check_level_names(level_names, len(self.levels))
            if level_names is not None
            else [[describe_task(t) for t in level] for level in self.levels]
        )
        keys = goal_frames_of(self.levels) if goals is None else goal_keys(model, goals)
        given = _check_targets(targets, [name for name, _ in keys])
        self.goals: dict[str, GoalFrame] = {}
        for name, kind in keys:
            in_levels = [
                k
                for k, level in enumerate(self.levels)
                if any(getattr(t, "frame_name", None) == name for t in level)
            ]
            rotation = any(
                _regulates_rotation(t)
                for level in self.levels
                for t in level
                if getattr(t, "frame_name", None) == name
            )
            position, matrix = self.configuration.frame_pose(name, kind)
            target = Target(position.copy(), matrix.copy() if rotation else None)
            if name in given:
                start = given[name]
                target = Target(
                    start.position.copy(),
                    None if start.rotation is None or not rotation else start.rotation.copy(),
                )
            self.goals[name] = GoalFrame(name, kind, in_levels, rotation, target)
            set_frame_target(self.levels, name, target)
        if self.levels and not any(0 in g.levels for g in self.goals.values()):
            self._correction = IKSolver(model, [self.levels[0]], self.limits, options=step_options)
        self.last: SolveReport | None = None

    # ------------------------------------------------------------------ state
    @property
    def q(self) -> np.ndarray:
        """The current configuration ``(nq,)`` (a copy)."""
        return self.configuration.q.copy()

    def set_q(self, q: npt.ArrayLike) -> None:
        """Move the robot to ``q`` ``(nq,)`` (targets unchanged; posture tasks keep
        theirs)."""
        self.configuration.update(np.asarray(q, dtype=float))

    def set_target(
        self,
        frame: str,
        position: npt.ArrayLike,
        rotation: npt.ArrayLike | None = None,
    ) -> Target:
        """Move the target of goal frame ``frame``: ``position`` ``(3,)`` [m] and, for a
        frame whose orientation is regulated, ``rotation`` (a 3x3 matrix, or a ``(4,)``
        quaternion ``w, x, y, z``), both in the world frame. A rotation left out keeps the
        current target's. Returns the new target (no solve: call :meth:`solve`).

        Raises :class:`qpik.InvalidOption` for a frame without a handle and
        :class:`qpik.InvalidTarget` for a position that is not 3 finite numbers or a
        rotation that is neither a rotation matrix nor a nonzero quaternion."""
        goal = self.goal(frame)
        matrix = goal.target.rotation
        if rotation is not None and goal.rotation:
            matrix = _rotation_matrix(rotation)
        point = checks.check_vector("position", position, 3, error=InvalidTarget)
        goal.target = parse_target(point if matrix is None else (point, matrix))
        set_frame_target(self.levels, frame, goal.target)
        return goal.target

    def goal(self, frame: str) -> GoalFrame:
        """The goal frame ``frame`` (:attr:`goals`); :class:`qpik.InvalidOption` naming
        ``frame`` when it has no handle (:class:`qpik.InvalidArgumentType` when it is not
        a str)."""
        if not isinstance(frame, str):
            raise InvalidArgumentType("frame", "a goal frame name (a str)", checks.type_name(frame))
        goal = self.goals.get(frame)
        if goal is None:
            names = ", ".join(self.goals) or "(none)"
            raise InvalidOption(
                "frame",
                frame,
                f"a goal frame ({names})",
                f"frame {frame!r} has no handle; goal frames: {names}",
            )
        return goal

    def goal_errors(self) -> dict[str, tuple[float, float]]:
        """``{frame: (position error [m], orientation error [rad])}`` at the current ``q``
        (orientation 0 for a position-only goal)."""
        out = {}
        for name, goal in self.goals.items():
            position, matrix = self.configuration.frame_pose(name, goal.frame_type)
            p = float(np.linalg.norm(position - goal.target.position))
            o = 0.0
            if goal.target.rotation is not None:
                o = float(orientation_angle(matrix, goal.target.rotation))
            out[name] = (p, o)
        return out

    def _within(self, errors: dict[str, tuple[float, float]]) -> bool:
        return all(p <= self.tol_position and o <= self.tol_orientation for p, o in errors.values())

    # ------------------------------------------------------------------ solving
    def step(self) -> StepResult:
        """One IK step from the current configuration, applied (goal targets farther than
        :attr:`max_step` approached by that much)."""
        clamped = self._clamp_targets()
        try:
            result = self.solver.step(self.configuration, self.dt)
        finally:
            for name in clamped:
                set_frame_target(self.levels, name, self.goals[name].target)
        self.configuration.integrate_inplace(result.velocity, self.dt)
        for _ in range(CORRECTIONS if self._correction is not None else 0):
            if self.level0_error() <= self.tol_position:
                break
            fix = self._correction.step(self.configuration, self.dt)  # type: ignore[union-attr]
            self.configuration.integrate_inplace(fix.velocity, self.dt)
        return result

    def level0_error(self) -> float:
        """The largest error norm of level 0's tasks at the current ``q`` (in each task's
        units: [m] for positions, [rad] for rotations, mixed for poses)."""
        worst = 0.0
        for task in self.levels[0] if self.levels else []:
            try:
                error = task.compute_error(self.configuration)
            except Exception:  # a task without a target: nothing to hold
                continue
            worst = max(worst, float(np.max(np.abs(error), initial=0.0)))
        return worst

    def _clamp_targets(self) -> list[str]:
        """Set the intermediate targets of the goal frames beyond the trust region; returns
        their names."""
        if self.max_step is None:
            return []
        max_position, max_rotation = self.max_step
        clamped = []
        for name, goal in self.goals.items():
            position, matrix = self.configuration.frame_pose(name, goal.frame_type)
            target = goal.target
            delta = target.position - position
            distance = float(np.linalg.norm(delta))
            far = distance > max_position
            p = position + delta * (max_position / distance) if far else target.position
            r = target.rotation
            if r is not None:
                angle = float(orientation_angle(matrix, r))
                if angle > max_rotation:
                    far = True
                    r = _toward(matrix, r, max_rotation / angle)
            if far:
                set_frame_target(self.levels, name, Target(p, r))
                clamped.append(name)
        return clamped

    def solve(self, max_iterations: int | None = None) -> SolveReport:
        """Steps until the goals are within tolerance and the step has settled, or
        ``max_iterations`` (default :attr:`max_iterations`) steps; returns the report."""
        limit = (
            self.max_iterations if max_iterations is None else check_max_iterations(max_iterations)
        )
        start = time.perf_counter()
        last: StepResult | None = None
        steps = 0
        converged = False
        for _ in range(limit):
            last = self.step()
            steps += 1
            settled = float(np.max(np.abs(last.displacement), initial=0.0)) <= self.settle
            if settled and self._within(self.goal_errors()):
                converged = True
                break
        errors = self.goal_errors()
        if last is None or not converged:
            converged = converged or (steps == 0 and self._within(errors))
        elapsed = time.perf_counter() - start
        self.last = SolveReport(
            q=self.q,
            steps=steps,
            solve_time=elapsed,
            converged=converged,
            levels=self._levels(last, errors),
            goal_errors=errors,
            last_step=last,
        )
        return self.last

    def _levels(
        self, step: StepResult | None, errors: dict[str, tuple[float, float]]
    ) -> list[LevelReport]:
        active = step.active_limits if step is not None else []
        reports = []
        for k in range(len(self.levels)):
            status = str(step.status[k]) if step is not None else "not solved yet"
            # (NaN before a solve since the robot moved: no residual to show)
            residual = float(step.residuals[k]) if step is not None else math.nan
            damping = float(step.damping[k]) if step is not None else math.nan
            frames = [g for g in self.goals.values() if k in g.levels]
            goal_error = None
            if frames:
                turned = [errors[g.name][1] for g in frames if g.rotation]
                goal_error = (  # (NaN: no frame of the level has its orientation regulated)
                    max(errors[g.name][0] for g in frames),
                    max(turned) if turned else math.nan,
                )
            reports.append(
                LevelReport(
                    index=k,
                    tasks=self.level_names[k],
                    status=status,
                    residual=residual,
                    damping=damping,
                    active_limits=list(active),
                    state=self._state(k, status, residual, goal_error),
                    goal_error=goal_error,
                )
            )
        return reports

    def _state(
        self, k: int, status: str, residual: float, goal_error: tuple[float, float] | None
    ) -> str:
        within = goal_error is None or (
            goal_error[0] <= self.tol_position and not goal_error[1] > self.tol_orientation
        )
        if status == "not solved yet":  # (no step taken: the robot moved by hand, say)
            # met only where a goal frame's error shows it: a level without one (a posture)
            # is not known met until a solve
            return "met" if within and goal_error is not None else "pending"
        if status != "solved":
            return "unmet"
        if goal_error is not None and (
            goal_error[0] > self.tol_position or goal_error[1] > self.tol_orientation
        ):
            return "unmet"
        if k == 0 and residual > self.tol_position:
            return "unmet"
        return "compromise" if residual > MET_RESIDUAL else "met"


def _toward(start: np.ndarray, end: np.ndarray, fraction: float) -> np.ndarray:
    """The rotation ``fraction`` of the way from ``start`` to ``end`` (both 3x3, world
    frame) along the shortest rotation."""
    from scipy.spatial.transform import Rotation

    relative = Rotation.from_matrix(end @ start.T).as_rotvec()
    return Rotation.from_rotvec(fraction * relative).as_matrix() @ start


def _key(model: mujoco.MjModel, goal: str | tuple[str, FrameType | str]) -> tuple[str, FrameType]:
    """``(name, frame_type)`` of a goal given as a name (site, body, geom: first found) or
    a pair."""
    name, kind, _ = resolve_frame(model, goal, argument="goals")
    return name, FrameType.parse(kind)


def goal_keys(model: mujoco.MjModel, goals: Any) -> list[tuple[str, FrameType]]:
    """The goal frames ``goals``: a sequence of names or ``(name, frame_type)`` pairs, or
    one name alone (a str is one frame, not a sequence of one-letter names)."""
    if isinstance(goals, str):
        return [_key(model, goals)]
    if isinstance(goals, (bytes, dict)) or not checks.is_iterable(goals):
        raise InvalidArgumentType(
            "goals", "a frame name or a sequence of frames", checks.type_name(goals)
        )
    return [_key(model, g) for g in goals]


def check_max_iterations(value: Any, name: str = "max_iterations") -> int:
    """IK steps per drag solve: an int in ``[0, MAX_ITERS_LIMIT]``, the range of
    :attr:`qpik.SolveOptions.max_iters`; else :class:`qpik.InvalidOption`."""
    return check_integer(name, value, 0, MAX_ITERS_LIMIT)


def check_max_step(value: Any) -> tuple[float, float] | None:
    """The trust region ``(metres, radians)``, both finite and > 0, or ``None``: what
    :class:`qpik.SolveOptions` accepts as ``max_step``; else :class:`qpik.InvalidOption`."""
    if value is None:
        return None
    if isinstance(value, np.ndarray) and value.shape == (2,):
        value = tuple(value.tolist())
    if not (isinstance(value, (tuple, list)) and len(value) == 2):
        raise InvalidOption("max_step", value, "(metres, radians) or None")
    return (
        check_number("max_step[0] (metres)", value[0]),
        check_number("max_step[1] (radians)", value[1]),
    )


def _check_level_names(level_names: Any, count: int) -> list[list[str]]:
    """``level_names``: one sequence of task names (str) per level."""
    expected = f"{count} sequences of task names (one per level)"
    if isinstance(level_names, (str, bytes, dict)) or not checks.is_iterable(level_names):
        raise InvalidArgumentType("level_names", expected, checks.type_name(level_names))
    names = list(level_names)
    if len(names) != count:
        raise InvalidInput(
            f"level_names has {len(names)} entries, expected {count} (one per level)"
        )
    out = []
    for k, level in enumerate(names):
        if isinstance(level, (str, bytes, dict)) or not checks.is_iterable(level):
            raise InvalidArgumentType(
                f"level_names[{k}]", "a sequence of task names (str)", checks.type_name(level)
            )
        level = list(level)
        for i, task in enumerate(level):
            if not isinstance(task, str):
                raise InvalidArgumentType(
                    f"level_names[{k}][{i}]", "a task name (str)", checks.type_name(task)
                )
        out.append(level)
    return out


def _check_targets(targets: Any, goals: list[str]) -> dict[str, Target]:
    """``targets``: ``{goal frame: target}`` (a :class:`qpik.Target`, or anything
    :func:`qpik.igm.targets.parse_target` takes), every key a goal frame."""
    if targets is None:
        return {}
    if not isinstance(targets, Mapping):
        raise InvalidArgumentType(
            "targets", "a dict {goal frame: Target}", checks.type_name(targets)
        )
    out = {}
    for name, value in targets.items():
        if name not in goals:
            raise InvalidOption(
                "targets",
                name,
                f"goal frames ({', '.join(goals) or 'none'})",
                f"targets has a target for {name!r}, which is not a goal frame; goal "
                f"frames: {', '.join(goals) or '(none)'}",
            )
        try:
            out[name] = parse_target(value)
        except InvalidTarget as exc:
            raise InvalidTarget(f"targets[{name!r}]: {exc}") from None
    return out


def _rotation_matrix(rotation: Any) -> np.ndarray:
    """A rotation given as a 3x3 matrix or a ``(4,)`` quaternion ``w, x, y, z`` (nonzero,
    normalised here), as a 3x3 matrix; anything else :class:`qpik.InvalidTarget`."""
    try:
        r = checks.float_array(rotation, booleans=False)  # (no complex, text or booleans)
    except (TypeError, ValueError):
        r = None
    if r is None or r.shape not in ((4,), (3, 3)):
        shape = getattr(r, "shape", None)
        raise InvalidTarget(
            "rotation must be a 3x3 rotation matrix or a (4,) quaternion w, x, y, z, got "
            + (f"shape {shape}" if shape is not None else checks.type_name(rotation))
        )
    if not np.isfinite(r).all():
        raise InvalidTarget(f"rotation must be finite, got {r.tolist()}")
    if r.shape == (4,):
        norm = float(np.linalg.norm(r))
        if not norm > 1e-9:
            raise InvalidTarget(f"rotation quaternion must be nonzero, got {r.tolist()}")
        m = np.empty(9)
        mujoco.mju_quat2Mat(m, r / norm)
        r = m.reshape(3, 3)
    return r.copy()
