"""The ``"qp"`` engine of :func:`qpik.solve`: the IGM loop on :class:`qpik.IKSolver` steps,
for whatever the compiled engine does not take (several frames, custom stacks, other
limits, ball or free joints, a level-1 objective). See :mod:`qpik.igm.session` for the rule.

A solve borrows the tasks of a caller's stack: it sets their targets and scales their
gains (the trust region) while it runs, and gives every task back as it found it
(:func:`borrowed_tasks`), even when the solve raises.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

import mink
import mujoco
import numpy as np

from ..diffik.solver import MODEL_CHECKED, IKSolver, normalize_stack
from ..errors import InvalidOption, InvalidTarget
from ..limits import BallJointLimit, collision_clearance, collision_limits
from ..model.chain import bodies_chain_joints, body_chain_joints, chain_qpos_mask
from ..model.configuration import Configuration, FrameType
from ..model.couplings import model_couplings
from ..options import IGM_BACKEND_OPTIONS, SolveOptions
from ..tasks import JointLimitDistanceTask, OrientationTask, PoseTask, PositionTask
from .kernels import BACKTRACKS
from .restarts import Attempt, Clock, StallWindow, run_attempts
from .result import IKResult, Reason
from .targets import (
    STEERS_POSITION,
    STEERS_ROTATION,
    TARGET_TASKS,
    Target,
    pose_errors,
    regulating_tasks,
    set_frame_target,
    set_task_target,
    worst_errors,
)

__all__ = [
    "QPProblem",
    "borrowed_tasks",
    "check_limits_model",
    "idle_qpos",
    "iterate",
    "joint_position_limits",
    "lent_scratch",
    "set_frame_target",
]

#: At most this many steps of level 0 alone finish an attempt of a stack of several
#: levels that ended with level 0 (or a coupling) not within tolerance.
LEVEL0_STEPS = 20

#: With collision limits, a step that takes a pair deeper inside its ``d_min`` (by more
#: than half ``tol_position``) is halved up to this many times, then not taken: a full
#: step may cross an obstacle thinner than itself before the pair's row is active (its
#: ``collision_detection_distance``).
COLLISION_BACKTRACKS = 10

#: A frame target as the engine holds it: ``(name, frame type, target)``.
FrameTarget = tuple[str, FrameType, Target]
#: The attributes a solve may change on a caller's task (targets, and the gain that the
#: trust region scales).
_BORROWED = ("target", "target_position", "target_rotation", "transform_target_to_world", "gain")


@contextlib.contextmanager
def lent_scratch(owner: dict, model: mujoco.MjModel) -> Iterator[tuple[Configuration, list]]:
    """A "qp"-engine solve's scratch configuration and joint limits, lent by ``owner`` (an
    :class:`qpik.IKSession`'s ``__dict__``, key ``_lent``; made there on first use: 0.7 ms
    of each solve on a humanoid) for the block and given back after it. Taken out while
    lent (one ``dict.pop``, atomic): a concurrent solve of the same session makes its own,
    so neither writes the other's (the answers are the same bits either way: nothing of a
    solve is kept in it for the next)."""
    lent, prepared = owner.pop("_lent", None), owner.get("_prepared")
    if lent is None:
        lent = (Configuration(model), joint_position_limits(model))
    try:
        yield lent
    finally:
        if owner.get("_prepared") is prepared:  # (not made again meanwhile: an edited model)
            owner["_lent"] = lent


@contextlib.contextmanager
def borrowed_tasks(levels: Sequence[Sequence]) -> Iterator[None]:
    """Within the block, the tasks of ``levels`` may have their targets and gains changed;
    on leaving it (normally or by an exception) each gets back the values it had."""
    saved = []
    for level in levels:
        for task in level:
            attributes = getattr(task, "__dict__", {})
            saved.append((task, {k: attributes[k] for k in _BORROWED if k in attributes}))
    try:
        yield
    finally:
        for task, values in saved:
            for name, value in values.items():
                setattr(task, name, value)


def task_errors(task: Any, configuration: Configuration) -> tuple[float, float] | None:
    """(position-like error, orientation error) of a level-0 task at ``configuration``, or
    ``None`` for a task without a target (see :mod:`qpik.igm.session` for the rule)."""
    try:
        target = _task_target(task)
        if target is None:
            return None
        if target is _NOT_A_FRAME_TASK:
            error = np.asarray(task.compute_error(configuration), dtype=float)
            return float(np.linalg.norm(error)), 0.0
        position, orientation = pose_errors(
            *configuration.frame_pose(task.frame_name, task.frame_type), target
        )
    except mink.TargetNotSet:
        return None
    if isinstance(task, PositionTask):
        return position, 0.0
    if isinstance(task, OrientationTask):
        return 0.0, orientation
    # a pose: the parts with a nonzero cost
    return (
        position if np.any(task.cost[:3] > 0) else 0.0,
        orientation if np.any(task.cost[3:] > 0) else 0.0,
    )


_NOT_A_FRAME_TASK = Target(np.zeros(3))
_ORIGIN = np.zeros(3)


def _task_target(task: Any) -> Target | None:
    """The frame target of a frame task (``None`` when unset), or ``_NOT_A_FRAME_TASK``."""
    if isinstance(task, PositionTask):
        return None if task.target is None else Target(task.target)
    if isinstance(task, OrientationTask):
        # only the angle is read
        return None if task.target is None else Target(_ORIGIN, task.target)
    if isinstance(task, PoseTask):
        if task.target_position is None:
            return None
        return Target(task.target_position, task.target_rotation)
    if isinstance(task, mink.FrameTask):
        world = task.transform_target_to_world
        if world is None:
            return None
        return Target(world.translation(), world.rotation().as_matrix())
    return _NOT_A_FRAME_TASK


def _frame_body(model: mujoco.MjModel, frame: Any, frame_type: Any) -> int:
    """The body of a frame given as a task holds it (name or id, frame type)."""
    kind = FrameType.parse(frame_type)
    obj = {
        FrameType.BODY: mujoco.mjtObj.mjOBJ_BODY,
        FrameType.SITE: mujoco.mjtObj.mjOBJ_SITE,
        FrameType.GEOM: mujoco.mjtObj.mjOBJ_GEOM,
    }[kind]
    fid = int(frame) if not isinstance(frame, str) else mujoco.mj_name2id(model, obj, frame)
    if kind is FrameType.BODY:
        return fid
    return int(model.site_bodyid[fid] if kind is FrameType.SITE else model.geom_bodyid[fid])


def _task_joints(model: mujoco.MjModel, task: Any) -> set[int] | None:
    """The joints a task's rows can move (``None``: any joint): a frame task's chain (a
    relative frame task's two chains), the limited hinge and slide joints of
    :class:`JointLimitDistanceTask`; any other task may move any joint."""
    if isinstance(task, TARGET_TASKS):
        return body_chain_joints(model, _frame_body(model, task.frame_name, task.frame_type))
    if isinstance(task, mink.RelativeFrameTask):
        joints = body_chain_joints(model, _frame_body(model, task.frame_name, task.frame_type))
        return joints | body_chain_joints(model, _frame_body(model, task.root_name, task.root_type))
    if isinstance(task, JointLimitDistanceTask):
        scalar = (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)
        return {
            j for j in range(model.njnt) if model.jnt_type[j] in scalar and model.jnt_limited[j]
        }
    return None


def _limit_joints(model: mujoco.MjModel, limit: Any) -> set[int] | None:
    """The joints a limit's rows can move from a start within the joint limits: none for
    box limits (position, velocity, ball-joint ranges), the chains of every geom of a
    collision limit's pairs; any joint for another limit."""
    if isinstance(limit, mink.CollisionAvoidanceLimit):
        # each body's chain once (Talos: 883 pairs over 60 bodies; a chain per geom of
        # every pair took 14 ms of each solve)
        geoms = np.asarray(limit.geom_id_pairs, dtype=np.int64).reshape(-1)
        return bodies_chain_joints(model, np.unique(model.geom_bodyid[geoms]).tolist())
    if isinstance(limit, (mink.ConfigurationLimit, mink.VelocityLimit, BallJointLimit)):
        return set()
    return None


def idle_qpos(
    model: mujoco.MjModel, levels: Sequence[Sequence], limits: Sequence, couplings
) -> np.ndarray:
    """The qpos entries ``(nq,)`` (bool) of the joints that nothing in a solve moves: on no
    task's chain (:func:`_task_joints`), in no coupling, moved by no limit (a free object,
    another arm, fingers off the chains). The engine keeps them bitwise where they start
    (the steps' rounding would move them by ~1e-16). All False when a task or limit may
    move any joint (a posture or CoM task, a support polygon)."""
    moved: set[int] = set()
    for item in [*(t for level in levels for t in level), *limits]:
        found = (
            _task_joints(model, item)
            if not isinstance(item, mink.Limit)
            else _limit_joints(model, item)
        )
        if found is None:
            return np.zeros(model.nq, dtype=bool)
        moved |= found
    if couplings is not None:
        moved |= {int(model.dof_jntid[d]) for d in couplings.dofs}
    idle = np.zeros(model.nq, dtype=bool)
    widths = {0: 7, 1: 4, 2: 1, 3: 1}  # free, ball, slide, hinge
    for j in set(range(model.njnt)) - moved:
        adr = int(model.jnt_qposadr[j])
        idle[adr : adr + widths[int(model.jnt_type[j])]] = True
    return idle


def check_limits_model(model: mujoco.MjModel, limits: Sequence | str | None) -> None:
    """Raise :class:`qpik.InvalidOption` (``limits``) when a limit was built on a model of
    another shape than the solved one (dofs; a collision limit's geoms): a collision limit
    built on a scene (:func:`qpik.scene.add_obstacle`) but a solve of the bare robot."""
    if limits is None or isinstance(limits, str):
        return
    for limit in limits:
        own = getattr(limit, "model", None)
        if not isinstance(own, mujoco.MjModel) or own is model:
            continue
        geoms = isinstance(limit, mink.CollisionAvoidanceLimit) and own.ngeom != model.ngeom
        if own.nv != model.nv or own.nq != model.nq or geoms:
            raise InvalidOption(
                "limits",
                type(limit).__name__,
                f"limits built on the solved robot's model (this one's model has nq {own.nq}, "
                f"nv {own.nv}, {own.ngeom} geoms; the robot nq {model.nq}, nv {model.nv}, "
                f"{model.ngeom} geoms: build a scene's collision limit on the scene, and "
                "solve the scene)",
            )


def joint_position_limits(model: mujoco.MjModel) -> list:
    """The limits of ``limits="joint"``: the model's joint position limits, a limited ball
    joint's range included (:class:`qpik.limits.BallJointLimit`; ``ConfigurationLimit``
    bounds hinge and slide joints only)."""
    from ..limits import (  # on first use (it imports scipy.spatial)
        BallJointLimit,
        ConfigurationLimit,
        limited_ball_joints,
    )

    limits: list = [ConfigurationLimit(model)]
    if limited_ball_joints(model):
        limits.append(BallJointLimit(model))
    return limits


def _limits(model: mujoco.MjModel, options: SolveOptions) -> list:
    if options.limits == "joint":
        return joint_position_limits(model)
    check_limits_model(model, options.limits)
    return list(options.limits or ())


class QPProblem:
    """What a ``"qp"``-engine solve iterates: a scratch configuration, the stack and its
    :class:`qpik.IKSolver`, built afresh for every solve (nothing carries over), but for
    what a caller that solves often lends it (:class:`qpik.IKSession`): ``scratch``, a
    configuration of ``model`` that every solve sets from its start (:func:`iterate`), and
    ``joint_limits``, the ``ConfigurationLimit`` of ``limits="joint"`` (no state: its rows
    are read from the configuration). An ``MjData`` and that limit cost 0.7 ms on a
    humanoid."""

    def __init__(
        self,
        model: mujoco.MjModel,
        frames: Sequence[FrameTarget],
        stack: Any,
        options: SolveOptions,
        scratch: Configuration | None = None,
        joint_limits: list | None = None,
    ):
        self.configuration = Configuration(model) if scratch is None else scratch
        self.frames = list(frames)
        self.custom_stack = stack is not None
        levels = self._default_levels(model, options) if stack is None else normalize_stack(stack)
        self.levels = levels
        if joint_limits is not None and options.limits == "joint":
            self.limits: list = list(joint_limits)
        else:
            self.limits = _limits(model, options)
        #: The collision limits among the limits: an iterate counts as converged only
        #: when every pair they check is at least ``d_min - tol_position`` apart.
        self.collisions = collision_limits(self.limits)
        step = options.step
        if step.backend_options is None and step.solver in IGM_BACKEND_OPTIONS:
            step = step.replace(backend_options=IGM_BACKEND_OPTIONS[step.solver])
        checked = MODEL_CHECKED.set(True)  # (its session's preparation checked the model)
        try:
            self.solver = IKSolver(model, levels, self.limits, options=step)
        finally:
            MODEL_CHECKED.reset(checked)
        target_frames = {name for name, _, _ in self.frames}
        # The tasks that move toward the targets, at whatever level (the trust region
        # scales their gains): the default stack's level 0, one per frame in frame order;
        # in a given stack, every frame task on a target frame.
        self.primary = [
            t
            for level in (levels[:1] if stack is None else levels)
            for t in level
            if isinstance(t, TARGET_TASKS)
            and (stack is None or getattr(t, "frame_name", None) in target_frames)
        ]
        # Level-0 tasks checked for convergence besides the target frames.
        self.level0 = [t for t in levels[0] if getattr(t, "frame_name", None) not in target_frames]
        self.base_gains: list[float] = []
        #: The model's couplings, held by the steps (their level comes first) and counted
        #: in convergence; None without any or with ``couplings=False``.
        self.couplings = model_couplings(model) if options.step.couplings else None
        #: The qpos entries nothing in the solve moves (:func:`idle_qpos`): every iterate
        #: keeps them bitwise as they start.
        self.idle = idle_qpos(model, levels, self.limits, self.couplings)
        #: Several levels: iterates are ranked lexicographically by level
        #: (:meth:`level_key`), and an attempt that ends with level 0 not met is finished
        #: by steps of level 0 alone (:attr:`level0_solver`, built on first use).
        self.multilevel = len(levels) > 1
        self._level0_solver: IKSolver | None = None
        self._step_options = step

    @property
    def level0_solver(self) -> IKSolver:
        """An :class:`IKSolver` of level 0 alone (and the couplings), same limits."""
        if self._level0_solver is None:
            checked = MODEL_CHECKED.set(True)
            try:
                self._level0_solver = IKSolver(
                    self.configuration.model, self.levels[:1], self.limits,
                    options=self._step_options,
                )  # fmt: skip
            finally:
                MODEL_CHECKED.reset(checked)
        return self._level0_solver

    def level_measures(
        self, configuration: Configuration, options: SolveOptions
    ) -> tuple[float, list[float]]:
        """``(coupling measure, per level measure)`` at ``configuration``: the largest
        ratio of a task's error to its tolerance (``max(p / tol_p, o / tol_o)``, 0 for a
        level without a task with a target); a level has met its tolerance when its
        measure is <= 1. The couplings' residual is measured against ``tol_position``."""
        tol_p, tol_o = options.tol_position, options.tol_orientation
        coupling = 0.0
        if self.couplings is not None:
            coupling = self.couplings.error(configuration.q) / tol_p
        measures = []
        for level in self.levels:
            worst = 0.0
            for task in level:
                errors = task_errors(task, configuration)
                if errors is not None:
                    worst = max(worst, errors[0] / tol_p, errors[1] / tol_o)
            measures.append(worst)
        return coupling, measures

    def collision_violation(self, configuration: Configuration, tol: float) -> float:
        """How far [m] the closest pair of the collision limits is inside its ``d_min``
        (``max(0, d_min - d)``; 0 without collision limits). Distances are computed up to
        ``d_min + tol`` only (nothing farther matters)."""
        clearance = collision_clearance(
            configuration.model, configuration.data, self.collisions, cap=tol
        )
        return 0.0 if clearance is None else max(0.0, -clearance)

    def _default_levels(self, model: mujoco.MjModel, options: SolveOptions) -> list[list]:
        """Level 0: a position or pose task per frame (gain ``alpha``); level 1, with
        ``secondary`` on a redundant arm: distance from the joint limits."""
        primary = [
            PositionTask(name, kind, gain=options.alpha)
            if target.rotation is None
            else PoseTask(name, kind, gain=options.alpha)
            for name, kind, target in self.frames
        ]
        rows = sum(3 if target.rotation is None else 6 for _, _, target in self.frames)
        levels: list[list] = [primary]
        if model.nv > rows and options.secondary:
            levels.append([JointLimitDistanceTask(cost=1.0, gain=0.5)])
        return levels

    def set_targets(self) -> None:
        """Set each frame's target on the stack's tasks; every frame must have a task.
        Called inside :func:`borrowed_tasks`; remembers the gains the trust region scales."""
        if not self.custom_stack:  # one task per frame
            for task, (name, _kind, target) in zip(self.primary, self.frames):
                set_task_target(task, name, target)
        for name, kind, target in self.frames if self.custom_stack else ():
            tasks = regulating_tasks(self.levels, name, kind)
            label = f"the {FrameType.parse(kind).value} {name!r}"
            if not tasks:
                raise InvalidTarget(f"no task in the given stack regulates {label}")
            # (as problem files: a part of the target no task steers would be measured,
            # never reached, and the solve would run its every restart)
            if not any(isinstance(t, STEERS_POSITION) for t in tasks):
                raise InvalidTarget(
                    f"a position no task steers: only an orientation task regulates {label} "
                    "(its position would be measured, never reached); regulate it with a "
                    "position, pose or frame task"
                )
            if target.rotation is not None and not any(
                isinstance(t, STEERS_ROTATION) for t in tasks
            ):
                raise InvalidTarget(
                    f"a rotation no task steers: only a position task regulates {label}; give "
                    "it a position-only target, or regulate it with a pose or frame task"
                )
            set_frame_target(self.levels, name, target, kind)
        self.base_gains = [task.gain for task in self.primary]

    def clamp_gains(
        self,
        errors: Mapping[str, tuple[float, float]],
        max_position_step: float,
        max_orientation_step: float,
    ) -> None:
        """Trust region: scale the target tasks' gains so that no iteration asks for more
        than ``max_position_step`` [m] or ``max_orientation_step`` [rad]."""
        for task, base_gain in zip(self.primary, self.base_gains):
            name = task.frame_name  # mink's FrameTask allows an id; the errors are by name
            if not isinstance(name, str) or name not in errors:
                continue
            position_error, orientation_error = errors[name]
            position_limit = max_position_step / max(position_error, 1e-12)
            orientation_limit = max_orientation_step / max(orientation_error, 1e-12)
            if isinstance(task, PositionTask):
                limit = position_limit
            elif isinstance(task, OrientationTask):
                limit = orientation_limit
            else:  # a pose: one gain for both parts, the tighter one
                limit = min(position_limit, orientation_limit)
            task.gain = min(base_gain, limit)

    def errors(self, configuration: Configuration) -> dict[str, tuple[float, float]]:
        """Per frame, (position error [m], orientation error [rad]) at ``configuration``."""
        return {
            name: pose_errors(*configuration.frame_pose(name, kind), target)
            for name, kind, target in self.frames
        }

    def level0_errors(self, configuration: Configuration) -> list[tuple[float, float]]:
        """(position-like, orientation) errors of level 0's other tasks."""
        out = []
        for task in self.level0:
            errors = task_errors(task, configuration)
            if errors is not None:
                out.append(errors)
        return out


class _Measure:
    """The errors of the current iterate: per frame, the score ``max(p / tol_p + o /
    tol_o)`` over frames and level-0 tasks, whether all are within tolerance, and the
    energy ``sum |e_p|^2 + |e_o|^2`` that backtracking decreases. With collision limits,
    the closest pair's depth inside its ``d_min`` [m] counts as one more position-like
    error (0 when every pair keeps ``d_min``), and ranks first in :attr:`key`."""

    __slots__ = ("done", "energy", "errors", "key", "score", "violation")

    def __init__(self, problem: QPProblem, options: SolveOptions):
        configuration = problem.configuration
        tol_p, tol_o = options.tol_position, options.tol_orientation
        self.errors = problem.errors(configuration)
        items = list(self.errors.values()) + problem.level0_errors(configuration)
        if problem.couplings is not None:
            items.append((problem.couplings.error(configuration.q), 0.0))
        self.violation = 0.0
        if problem.collisions:
            self.violation = problem.collision_violation(configuration, tol_p)
            items.append((self.violation, 0.0))
        self.score = max(p / tol_p + o / tol_o for p, o in items)
        self.done = all(p <= tol_p and o <= tol_o for p, o in items)
        self.energy = sum(p * p + o * o for p, o in items)
        #: Several levels: the lexicographic rank of the iterate, the couplings first,
        #: then level 0, 1, ... (each measure of ``QPProblem.level_measures`` floored at
        #: 1: within tolerance counts as met), then the score. Lower is better.
        self.key: tuple[float, ...] = (self.score,)
        if problem.multilevel:
            coupling, levels = problem.level_measures(configuration, options)
            self.key = (max(1.0, coupling), *(max(1.0, m) for m in levels), self.score)
        if problem.collisions:  # a configuration in collision ranks after any clear one
            self.key = (max(1.0, self.violation / tol_p), *self.key)


class _Path:
    """The iterates of one attempt: residuals, worst errors, configurations and measures."""

    def __init__(self, measure: _Measure, q: np.ndarray):
        self.residuals: list[list[float]] = []
        self.errors = [worst_errors(measure.errors)]
        self.q = [q]
        self.measures = [measure]
        self.last = measure

    def keep_best(self) -> None:
        """Cut the path at its best iterate by :attr:`_Measure.key` (the first among
        equals), which becomes the last."""
        keys = [m.key for m in self.measures]
        best = min(range(len(keys)), key=keys.__getitem__)
        del self.q[best + 1 :], self.errors[best + 1 :], self.measures[best + 1 :]
        del self.residuals[best:]
        self.last = self.measures[-1]


def _diagnose(step: Any, singular_threshold: float) -> Reason:
    """Why an attempt stopped making progress."""
    if step is None:
        return Reason.STALLED
    if step.active_limits:
        return Reason.AT_LIMIT
    if step.sigma_min and step.sigma_min[0] < singular_threshold:
        return Reason.SINGULAR
    return Reason.STALLED


class _Engine:
    """One solve's attempts on a prepared problem."""

    def __init__(self, problem: QPProblem, options: SolveOptions, clock: Clock):
        self.problem = problem
        self.options = options
        self.clock = clock
        self.iterations = 0
        configuration = problem.configuration
        self.bounds = (configuration.lower, configuration.upper)
        law = options.damping_law
        self.threshold = law.singular_threshold if law is not None else 0.0

    def _backtrack(self, step: Any, path: _Path) -> _Measure:
        """Apply ``beta`` times the step, halved (up to ``BACKTRACKS`` times) while it
        increases the energy, as the compiled engine does; with collision limits, also
        halved (up to ``COLLISION_BACKTRACKS`` times) while it takes a pair deeper inside
        its ``d_min``, and not taken if it still does."""
        configuration = self.problem.configuration
        q_base = configuration.q
        scale = self.options.beta
        collisions = bool(self.problem.collisions)
        allowed = max(path.last.violation, 0.5 * self.options.tol_position)
        halvings = COLLISION_BACKTRACKS if collisions else BACKTRACKS
        for halving in range(halvings + 1):
            q = q_base.copy()
            mujoco.mj_integratePos(configuration.model, q, scale * step.displacement, 1.0)
            if self.options.beta > 1.0:
                q = np.clip(q, *self.bounds)
            q[self.problem.idle] = q_base[self.problem.idle]
            configuration.update(q)
            measure = _Measure(self.problem, self.options)
            deeper = collisions and measure.violation > allowed
            if not deeper and (measure.energy < path.last.energy or halving >= BACKTRACKS):
                break
            if deeper and halving == halvings:  # still deeper at the last halving
                q = q_base
                configuration.update(q)
                measure = _Measure(self.problem, self.options)
                break
            scale *= 0.5
        path.errors.append(worst_errors(measure.errors))
        path.q.append(q)
        path.measures.append(measure)
        path.last = measure
        return measure

    def attempt(self) -> Attempt[_Path]:
        """Iterate from the configuration's current ``q``."""
        options, problem = self.options, self.problem
        measure = _Measure(problem, options)
        path = _Path(measure, problem.configuration.q)
        stall = StallWindow(measure.score, options.stall_window)
        reason = Reason.MAX_ITERS
        for _ in range(options.max_iters):
            if measure.done or self.clock.out_of_time():
                reason = Reason.TIME_BUDGET if not measure.done else reason
                break
            if options.max_step is not None:
                problem.clamp_gains(measure.errors, *options.max_step)
            step = problem.solver.step(problem.configuration, 1.0)
            self.iterations += 1
            path.residuals.append(list(step.residuals))
            measure = self._backtrack(step, path)
            # A vanishing step that leaves the error: nothing more comes of this start.
            vanished = float(np.sqrt(step.displacement @ step.displacement)) < 1e-9
            if stall.update(measure.score) or vanished:
                reason = _diagnose(step, self.threshold)
                break
        if measure.done:
            reason = Reason.CONVERGED
        elif problem.multilevel:
            self._finish_level0(path)
            path.keep_best()
            measure = path.last
        return Attempt(measure.done, measure.score, reason, path, measure.key)

    def _finish_level0(self, path: _Path) -> None:
        """Steps of level 0 alone (and the couplings) from the attempt's last iterate,
        while level 0 or a coupling is not met (at most ``LEVEL0_STEPS``, no further once
        a step vanishes): the lower levels' last steps may have left level 0 off by
        their linearisation error, which these Gauss-Newton steps remove. With collision
        limits, a step that would take a pair deeper inside ``d_min`` ends them untaken."""
        problem, options = self.problem, self.options
        solver = problem.level0_solver
        first = 1 if problem.collisions else 0  # the key's coupling entry
        for _ in range(LEVEL0_STEPS):
            key = path.last.key
            if key[first] <= 1.0 and key[first + 1] <= 1.0 or self.clock.out_of_time():
                break
            step = solver.step(problem.configuration, 1.0)
            q_base = problem.configuration.q
            q = q_base.copy()
            mujoco.mj_integratePos(problem.configuration.model, q, step.displacement, 1.0)
            q[problem.idle] = q_base[problem.idle]
            problem.configuration.update(q)
            measure = _Measure(problem, options)
            allowed = max(path.last.violation, 0.5 * options.tol_position)
            if problem.collisions and measure.violation > allowed:  # deeper in collision
                problem.configuration.update(q_base)
                break
            self.iterations += 1
            path.residuals.append(list(step.residuals))
            path.errors.append(worst_errors(measure.errors))
            path.q.append(q)
            path.measures.append(measure)
            path.last = measure
            if float(np.sqrt(step.displacement @ step.displacement)) < 1e-12:
                break


def iterate(problem: QPProblem, q0: np.ndarray, clock: Clock, seed: int, options: SolveOptions):
    """The IGM loop of :func:`qpik.solve` on a prepared problem (the ``"qp"`` engine), from
    ``q0``; restarts draw from ``numpy.random.default_rng(seed)``. The caller's tasks are
    given back unchanged. Restarts draw only the joints that move the target frames."""
    configuration = problem.configuration
    rng = np.random.default_rng(seed)
    engine = _Engine(problem, options, clock)
    # Restarts draw the joints that move the target frames (the union of their chains),
    # as the compiled engine does; the others (a free object, another arm) keep the start.
    # (No target frame, or none moved by a joint: every joint is drawn, as before.)
    moved = chain_qpos_mask(configuration.model, [(name, kind) for name, kind, _ in problem.frames])
    kept = ~moved if moved.any() else moved
    fixed = np.asarray(q0, dtype=float)[kept]

    def restart() -> None:
        q = configuration.random_q(rng)
        q[kept] = fixed
        configuration.update(q)

    with borrowed_tasks(problem.levels):
        problem.set_targets()
        configuration.update(q0)
        best, reason, used = run_attempts(
            engine.attempt,
            restart,
            options.effective_restarts,
            clock,
            budget=options.iteration_budget,
            spent=lambda: engine.iterations,
        )
    path = best.payload
    worst = worst_errors(path.last.errors)
    with borrowed_tasks(problem.levels):  # the targets, to measure the levels at q
        problem.set_targets()
        configuration.update(path.q[-1])
        coupling, measures = problem.level_measures(configuration, options)
    return IKResult(
        q=path.q[-1],
        converged=best.converged,
        reason=reason,
        iterations=engine.iterations,
        restarts_used=used,
        position_error=worst[0],
        orientation_error=worst[1],
        frame_errors=path.last.errors,
        residual_history=path.residuals,
        error_history=path.errors,
        path=np.array(path.q),
        solve_time=clock.elapsed(),
        engine="qp",
        levels_met=tuple(m <= 1.0 for m in measures),
        coupling_error=coupling * options.tol_position,
    )
