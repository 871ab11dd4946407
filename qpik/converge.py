r"""The inverse geometric model: iterate differential IK steps until the targets are met.

The lecture's recursion, for each frame with a target,

.. math::

    c = x_{des} - x(q_i), \qquad J(q_i)\, \dot q = \alpha\, c, \qquad
    q_{i+1} = q_i + \beta\, \dot q,

runs here with ``dt = 1``: ``alpha`` is the gain of the target tasks (the QP asks
``J dq = -alpha e``, ``e = x(q) - x_des``) and ``beta`` scales the displacement the QP
returns before it is applied. The QP adds what the lecture's pseudoinverse lacks: joint
limits hold at every iterate (``beta <= 1`` keeps them by convexity; a ``beta > 1`` iterate
is clipped into the limits), steps stay bounded near singularities (adaptive damping that
fades with the error), no iteration asks for more than a trust region (``max_step``), a
step that increases the error ``sum |e_p|^2 + |e_o|^2`` is halved (up to three times: near
singularities the damped step can otherwise overshoot into a limit cycle), and lower
levels (by default none; distance from the joint limits with ``secondary=True``) act only
in the null space of the targets.

Two engines run this rule (:attr:`IKResult.engine`):

* ``"compiled"``: one frame target, the default stack, joint limits (or none) and a model
  of hinge and slide joints. The whole solve (iterations, trust region, damping, stall
  detection, restarts) is one compiled call (:mod:`qpik.model._kernels`): forward
  kinematics and the frame Jacobian from arrays read once from the model, and each step's
  damped least-squares QP under the box of the joint limits solved exactly by an
  active-set method. It is the same QP as the general engine's, so both agree to round-off.
* ``"qp"``: everything else (several frames, custom stacks, other limits, ball or free
  joints, ``secondary=True``), on :class:`qpik.IKSolver` steps.

Errors: position error is the distance of the frame origin to its target [m]; orientation
error the angle of ``R R_des^T`` [rad]. A solve has **converged** when every frame with a
target is within ``tol_position`` and ``tol_orientation`` *and every task of level 0* is
within tolerance, targets or not (a custom stack's level 0 that holds the feet must still
hold them): position-like tasks (position, CoM) against ``tol_position``, orientation
tasks against ``tol_orientation``, frame/pose tasks both (the parts with a nonzero cost),
and any other task's error norm, in its own units, against ``tol_position``.

When an attempt stops making progress the reason is diagnosed (``at_limit``: a joint limit
binds; ``singular``: the target level's smallest singular value is below the damping
threshold; ``stalled`` otherwise) and the solve restarts from a random configuration
within the limits, while restarts and time remain. The best iterate over all attempts is
returned. A target position provably out of reach (farther from the base than the chain's
reach bound, :meth:`qpik.model.KinematicChain.reach_bound`) is answered at once with
``unreachable``.

Determinism: a solve keeps no state between calls. The same robot, targets, options and
``seed`` give bitwise the same ``q``, whatever was solved before, in this process or
another, through :func:`solve` or an :class:`IKSession`. The restarts draw from a
SplitMix64 stream seeded with ``seed``.
"""

from __future__ import annotations

import functools
import math
import operator
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mink
import mujoco
import numpy as np
import numpy.typing as npt

from .configuration import Configuration, FrameType, as_configuration, frame_names
from .core import SOLVERS
from .errors import (
    InvalidConfiguration,
    InvalidInput,
    InvalidTarget,
    JointLimitViolation,
    UnknownFrame,
)
from .hierarchy import DampingLaw, IKSolver, Stack, normalize_stack
from .limits import ConfigurationLimit
from .model import KinematicChain, ReachBound, _kernels, chain_support, joint_limits
from .robots import load_robot, robots_dir
from .tasks import (
    FrameTask,
    JointLimitDistanceTask,
    OrientationTask,
    PoseTask,
    PositionTask,
)

try:  # the QP layer is being rewritten (issue 10); the IGM only tunes OSQP when it can
    from .qp import OSQPSettings
except ImportError:  # pragma: no cover
    OSQPSettings = None

__all__ = [
    "IGM_DAMPING",
    "REASONS",
    "FrameKey",
    "IKResult",
    "IKSession",
    "RobotLike",
    "Target",
    "TargetLike",
    "clear_pool",
    "parse_target",
    "set_frame_target",
    "solve",
]

#: Why a solve ended. ``converged`` is the only success.
REASONS = {
    "converged": "every frame and every level-0 task is within tolerance",
    "max_iters": "the iteration limit of the last attempt was reached",
    "time_budget": "the time budget ran out",
    "stalled": "no progress, for no diagnosed reason (the target may be out of reach)",
    "at_limit": "no progress while a joint limit binds",
    "singular": "no progress at a singular configuration",
    "unreachable": "a target position is farther from the base than the arm reaches "
    "(provably: the chain's reach bound); answered without iterating",
}

#: The damping law of :func:`solve`: the velocity-control law, fading with the error.
IGM_DAMPING = DampingLaw(error_scale=0.3)

#: Restarts when ``restarts=None``: without a time budget, and the most with one.
DEFAULT_RESTARTS = 20
MAX_AUTO_RESTARTS = 1000
#: The largest ``max_iters`` (the returned attempt's path is kept in memory).
MAX_ITERS_LIMIT = 100_000
#: Gain of the joint-limit box (mink's ConfigurationLimit default): a step covers at most
#: this fraction of the distance to a limit.
LIMIT_GAIN = 0.95
#: Halvings of a step that increases the error ``sum |e_p|^2 + |e_o|^2`` [m^2, rad^2].
BACKTRACKS = _kernels.BACKTRACKS


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


def _array(value, shape: tuple[int, ...], what: str) -> np.ndarray:
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidTarget(
            f"{what} must be finite numbers of shape {shape}, got {value!r}"
        ) from exc
    if array.shape != shape:
        raise InvalidTarget(
            f"{what} must be finite numbers of shape {shape}, got an array of shape {array.shape}"
        )
    return array


_TARGET_DEFECTS = {
    1: "position target must be 3 finite numbers",
    2: "rotation target must be a finite 3x3 matrix",
    3: "rotation target is not a rotation matrix (R R^T != I or det <= 0)",
}


def parse_target(value: TargetLike) -> Target:
    """A :class:`Target` from a position ``(3,)``, a ``(position, rotation)`` pair, a 4x4
    homogeneous matrix, a ``mink.SE3`` or a ``Target``; NaN / malformed input raises
    :class:`qpik.InvalidTarget`. The rotation is checked once, in one compiled call
    (``|R R^T - I| <= 1e-6``, ``det R > 0``)."""
    if isinstance(value, tuple) and len(value) == 2:
        position, rotation = value
    elif isinstance(value, Target):
        position, rotation = value.position, value.rotation
    elif isinstance(value, mink.SE3):
        position, rotation = value.translation(), value.rotation().as_matrix()
    else:
        try:
            array = np.asarray(value, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InvalidTarget(
                f"a target is a position (3,), (position, rotation), a 4x4 matrix or an SE3; "
                f"got {value!r}"
            ) from exc
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
    position = _array(position, (3,), "position target")
    has_rot = rotation is not None
    rotation = _array(rotation, (3, 3), "rotation target") if has_rot else _EYE
    defect = _kernels.target_defect(position, rotation, has_rot)
    if defect:
        shown = position if defect == 1 else rotation
        raise InvalidTarget(f"{_TARGET_DEFECTS[defect]}, got {shown!r}")
    if not float(np.abs(position).max()) <= MAX_TARGET_DISTANCE:
        raise InvalidTarget(
            f"position target {position!r} is farther than {MAX_TARGET_DISTANCE:g} m from the "
            "world origin (its error would not be representable)"
        )
    return Target(position, rotation if has_rot else None)


_EYE = np.eye(3)

#: Targets beyond this distance from the origin [m] are rejected: no robot reaches them,
#: and their squared errors would overflow.
MAX_TARGET_DISTANCE = 1e9


_OBJ = {
    FrameType.SITE: mujoco.mjtObj.mjOBJ_SITE,
    FrameType.BODY: mujoco.mjtObj.mjOBJ_BODY,
    FrameType.GEOM: mujoco.mjtObj.mjOBJ_GEOM,
}


def _resolve_frame(model: mujoco.MjModel, key) -> tuple[str, FrameType]:
    """A target key: ``"name"`` (a site, else a body, else a geom) or ``(name, type)``."""
    if isinstance(key, tuple) and len(key) == 2 and isinstance(key[0], str):
        name, kind = key
        kind = FrameType.parse(kind)
        if mujoco.mj_name2id(model, _OBJ[kind], name) < 0:
            raise UnknownFrame(name, kind.value, frame_names(model, kind))
        return name, kind
    if not isinstance(key, str):
        raise InvalidInput(
            f"targets: a frame key is a name (str) or (name, frame type), got {key!r}"
        )
    for kind in (FrameType.SITE, FrameType.BODY, FrameType.GEOM):
        if mujoco.mj_name2id(model, _OBJ[kind], key) >= 0:
            return key, kind
    raise UnknownFrame(key, "site or body", frame_names(model, "site") + frame_names(model, "body"))


@dataclass
class IKResult:
    """The outcome of :func:`solve`.

    Attributes:
        q: the best configuration found ``(nq,)``, always within the joint limits.
        converged: whether every frame and every level-0 task is within tolerance at ``q``.
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
        engine: ``"compiled"`` or ``"qp"`` (see the module docstring).
    """

    q: np.ndarray
    converged: bool
    reason: str
    iterations: int
    restarts_used: int
    position_error: float
    orientation_error: float
    frame_errors: dict[str, tuple[float, float]] = field(default_factory=dict)
    residual_history: Sequence[list[float]] = field(default_factory=list, repr=False)
    error_history: Sequence[tuple[float, float]] = field(default_factory=list, repr=False)
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), repr=False)
    solve_time: float = 0.0
    engine: str = "qp"

    def __str__(self) -> str:
        state = "converged" if self.converged else f"not converged ({self.reason})"
        return (
            f"IK {state} in {self.iterations} iterations, {self.restarts_used} restarts, "
            f"{1e3 * self.solve_time:.2f} ms: position error {self.position_error:.3g} m, "
            f"orientation error {self.orientation_error:.3g} rad\n"
            f"q = {np.array2string(self.q, precision=4)}"
        )


# ----------------------------------------------------------------------- options
@dataclass(frozen=True)
class _Settings:
    """The validated loop options of :func:`solve` (documented there)."""

    tol_position: float
    tol_orientation: float
    max_iters: int
    time_budget: float | None
    restarts: int
    alpha: float
    beta: float
    stall_window: int
    damping_law: DampingLaw | None
    max_step: tuple[float, float] | None
    damping: float


def _number(name: str, value, *, positive: bool = True, allow_zero: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InvalidInput(f"{name} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value) or (positive and (value < 0 or (value == 0 and not allow_zero))):
        need = ">= 0" if allow_zero else "> 0"
        raise InvalidInput(f"{name} must be a finite number {need}, got {value!r}")
    return value


def _integer(name: str, value, minimum: int, maximum: int | None = None) -> int:
    """``value`` as an int in ``[minimum, maximum]`` (at most 2**62: the kernels' ints)."""
    maximum = 2**62 if maximum is None else min(maximum, 2**62)
    if isinstance(value, bool):
        raise InvalidInput(f"{name} must be an int >= {minimum}, got {value!r}")
    try:
        number = operator.index(value)
    except TypeError:
        raise InvalidInput(f"{name} must be an int >= {minimum}, got {value!r}") from None
    if number < minimum or number > maximum:
        bound = f"in [{minimum}, {maximum}]"
        raise InvalidInput(f"{name} must be an int {bound}, got {number}")
    return number


def _settings(
    tol_position,
    tol_orientation,
    max_iters,
    time_budget,
    restarts,
    alpha,
    beta,
    stall_window,
    damping_law,
    max_step,
    damping,
) -> _Settings:
    tol_position = _number("tol_position", tol_position)
    tol_orientation = _number("tol_orientation", tol_orientation)
    max_iters = _integer("max_iters", max_iters, 0, MAX_ITERS_LIMIT)
    if time_budget is not None:
        time_budget = _number("time_budget", time_budget, allow_zero=True)
    if restarts is None:
        restarts = DEFAULT_RESTARTS if time_budget is None else MAX_AUTO_RESTARTS
    else:
        restarts = _integer("restarts", restarts, 0)
    alpha = _number("alpha", alpha)
    if alpha > 1.0:
        raise InvalidInput(f"alpha must be in (0, 1] (a task gain), got {alpha}")
    beta = _number("beta", beta)
    stall_window = _integer("stall_window", stall_window, 1)
    if damping_law is not None and not isinstance(damping_law, DampingLaw):
        raise InvalidInput(f"damping_law must be a DampingLaw or None, got {damping_law!r}")
    if max_step is not None:
        if not (isinstance(max_step, (tuple, list)) and len(max_step) == 2):
            raise InvalidInput(f"max_step must be (metres, radians) or None, got {max_step!r}")
        max_step = (
            _number("max_step[0] (metres)", max_step[0]),
            _number("max_step[1] (radians)", max_step[1]),
        )
    damping = _number("damping", damping, allow_zero=True)
    return _Settings(
        tol_position,
        tol_orientation,
        max_iters,
        time_budget,
        restarts,
        alpha,
        beta,
        stall_window,
        damping_law,
        max_step,
        damping,
    )


def _rng_state(seed) -> np.ndarray:
    """The SplitMix64 state (uint64 (1,)) of ``seed``: an int >= 0, a Generator (one draw),
    a SeedSequence, or None (fresh entropy: not reproducible)."""
    if seed is None:
        return np.random.SeedSequence().generate_state(1, np.uint64)
    if isinstance(seed, np.random.Generator):
        return np.array([seed.integers(0, 2**64 - 1, dtype=np.uint64, endpoint=True)])
    if isinstance(seed, np.random.SeedSequence):
        return seed.generate_state(1, np.uint64)
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed >= 0:
        if seed < 2**64:
            return np.array([seed], dtype=np.uint64)
        return np.random.SeedSequence(int(seed)).generate_state(1, np.uint64)
    raise InvalidInput(
        f"seed must be an int >= 0, a numpy Generator or SeedSequence, or None; got {seed!r}"
    )


# ------------------------------------------------------------------------ session
class IKSession:
    """A robot prepared for repeated solves: hold one per robot and call :meth:`solve`.

    It reads the model once (joint limits, and per target frame its kinematic chain and
    reach bound, on first use) and keeps nothing else between solves: results never depend
    on what it solved before. After editing the model in place (its joint ranges, say),
    make a new session. :func:`solve` makes one per call (about 0.1 ms more per call).

    Args:
        robot: anything :func:`qpik.load_robot` accepts, or a :class:`qpik.Configuration`
            (its ``q`` is the default start).
    """

    def __init__(self, robot: RobotLike):
        model, robot_q = _model_of(robot)
        self.model: mujoco.MjModel = model
        self._robot_q = robot_q
        self._support = chain_support(model)
        if self._support is None:
            lower, upper = joint_limits(model)
        else:
            configuration = Configuration(model)
            lower, upper = configuration.lower.copy(), configuration.upper.copy()
        self._lower, self._upper = lower, upper
        self._sample_lo = np.where(np.isfinite(lower), lower, -np.pi)
        self._sample_hi = np.where(np.isfinite(upper), upper, np.pi)
        self._mid = model.qpos0.copy()
        limited = np.isfinite(lower) & np.isfinite(upper)
        self._mid[limited] = 0.5 * (lower[limited] + upper[limited])
        free = np.full(model.nq, np.inf)
        self._bounds_joint = np.array([lower, upper, self._sample_lo, self._sample_hi])
        self._bounds_free = np.array([-free, free, self._sample_lo, self._sample_hi])
        self._solver_checked = None
        self._memo = None  # the last options, validated (validation only: no results kept)
        self._frames: dict = {}  # frame key -> (name, kind, chain or None, reach or None)

    # ------------------------------------------------------------------ frames
    def _frame(self, key) -> tuple[str, FrameType, KinematicChain | None, ReachBound | None]:
        try:
            cached = self._frames.get(key)
        except TypeError:  # unhashable key
            cached = None
        if cached is not None:
            return cached
        name, kind = _resolve_frame(self.model, key)
        chain = reach = None
        if self._support is None:
            chain = KinematicChain.from_model(self.model, name, kind)
            reach = chain.reach_bound(self._lower, self._upper)
        entry = (name, kind, chain, reach)
        self._frames[key] = entry
        return entry

    def reach_bound(self, frame: FrameKey) -> ReachBound | None:
        """The :class:`qpik.model.ReachBound` of ``frame`` within the joint limits, or
        ``None`` for a model with ball or free joints."""
        return self._frame(frame)[3]

    def mid_q(self) -> np.ndarray:
        """The mid-range configuration (``qpos0`` for unlimited joints)."""
        return self._mid.copy()

    # ------------------------------------------------------------------- solve
    def solve(
        self,
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
        seed: int | np.random.Generator | np.random.SeedSequence | None = None,
        alpha: float = 1.0,
        beta: float = 1.0,
        solver: str = "auto",
        stall_window: int = 5,
        damping_law: DampingLaw | None = IGM_DAMPING,
        max_step: tuple[float, float] | None = (0.2, 0.5),
        secondary: bool = False,
        damping: float = 1e-6,
        engine: str = "auto",
    ) -> IKResult:
        """Solve inverse kinematics; the arguments are :func:`solve`'s."""
        start_time = time.perf_counter()
        key = (
            tol_position,
            tol_orientation,
            max_iters,
            time_budget,
            restarts,
            alpha,
            beta,
            stall_window,
            damping_law,
            max_step,
            damping,
        )
        memo = self._memo
        if memo is not None and memo[0] == key:
            settings, options, int_options = memo[1], memo[2], memo[3]
        else:  # validated once for a run of solves with the same options
            settings = _settings(*key)
            options, int_options = _kernel_options(settings)
            self._memo = (key, settings, options, int_options)
        rng_state = _rng_state(seed)
        if solver is not self._solver_checked:
            if not isinstance(solver, str) or solver not in SOLVERS:
                raise InvalidInput(
                    f"unknown QP solver {solver!r}; known solvers: {', '.join(SOLVERS)}"
                )
            self._solver_checked = solver
        if type(targets) is not dict and not isinstance(targets, Mapping):
            raise InvalidInput(
                f"targets must be a mapping {{frame: target}}, got {type(targets).__name__}"
            )
        if not targets:
            raise InvalidTarget("no targets given: pass {frame: target, ...}")
        frames = []
        for frame_key, value in targets.items():
            name, kind, chain, reach = self._frame(frame_key)
            frames.append((name, kind, parse_target(value), chain, reach))
        if limits is not None and not (
            (isinstance(limits, str) and limits == "joint")
            or (not isinstance(limits, str) and isinstance(limits, Sequence))
        ):
            raise InvalidInput(f"limits must be 'joint', None or a list of limits, got {limits!r}")
        if engine != "auto" and engine != "compiled" and engine != "qp":
            raise InvalidInput(f"engine must be 'auto', 'compiled' or 'qp', got {engine!r}")
        joint = isinstance(limits, str)
        compiled_ok = (
            stack is None
            and (limits is None or joint)
            and len(frames) == 1
            and frames[0][3] is not None
            and not secondary
        )
        if engine == "compiled" and not compiled_ok:
            raise InvalidInput(
                "engine='compiled' needs one frame target, the default stack, limits 'joint' "
                "or None, secondary=False and a model of hinge and slide joints"
                + (f" ({self._support})" if self._support else "")
            )
        limited = joint or (limits is not None and len(limits) > 0)
        q_start = self._start(q0, check=limited)
        if compiled_ok and engine != "qp":
            return self._solve_compiled(
                frames[0], q_start, joint, settings, options, int_options, rng_state, start_time
            )
        for _name, _kind, target, _chain, reach in frames:
            if reach is not None and reach.excludes(target.position, settings.tol_position):
                return self._answer_unreachable(frames, q_start, start_time)
        plain = [(name, kind, target) for name, kind, target, _, _ in frames]
        problem = _Problem(
            self.model,
            plain,
            stack,
            limits,
            settings.alpha,
            solver,
            settings.damping_law,
            secondary,
            settings.damping,
        )
        return _iterate(problem, q_start, start_time, rng_state, settings)

    # ---------------------------------------------------------------- helpers
    def _start(self, q0, check: bool) -> np.ndarray:
        """The validated start: ``q0``, else the robot's ``q``, else mid-range."""
        if q0 is None:
            if self._robot_q is None:
                return self._mid.copy()  # within the limits
            q0 = self._robot_q
        try:
            q = np.array(q0, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InvalidConfiguration(f"q0 must be {self.model.nq} numbers: {exc}") from exc
        if q.shape != (self.model.nq,):
            raise InvalidConfiguration(
                f"q0 has shape {q.shape}, expected ({self.model.nq},) for this model"
            )
        if not np.isfinite(q).all():
            i = int(np.flatnonzero(~np.isfinite(q))[0])
            raise InvalidConfiguration(f"q0[{i}] is {q[i]}; every entry must be finite", i)
        if check and self._support is None:
            outside = np.flatnonzero((q < self._lower - 1e-6) | (q > self._upper + 1e-6))
            if outside.size:
                i = int(outside[0])
                raise JointLimitViolation(
                    _qpos_name(self.model, i),
                    i,
                    float(q[i]),
                    float(self._lower[i]),
                    float(self._upper[i]),
                )
            np.clip(q, self._lower, self._upper, out=q)
        elif check:
            Configuration(self.model, q).check_limits()
        return q

    def _answer_unreachable(self, frames, q, start_time) -> IKResult:
        errors = {}
        for name, kind, target, chain, _ in frames:
            if chain is not None:
                position, rotation = chain.pose(q)
            else:  # pragma: no cover (reach bounds exist only with chains)
                position, rotation = Configuration(self.model, q).frame_pose(name, kind)
            errors[name] = _pose_errors(position, rotation, target)
        worst = _worst(errors)
        return IKResult(
            q=q,
            converged=False,
            reason="unreachable",
            iterations=0,
            restarts_used=0,
            position_error=worst[0],
            orientation_error=worst[1],
            frame_errors=errors,
            error_history=[worst],
            path=q[None, :].copy(),
            solve_time=time.perf_counter() - start_time,
            engine="qp",
        )

    def _solve_compiled(
        self, frame, q_start, joint, settings, options, int_options, rng_state, start_time
    ) -> IKResult:
        name, _kind, target, chain, reach = frame
        deadline = start_time + settings.time_budget if int_options[3] else np.inf
        n = settings.max_iters + 1
        path = np.empty((2, n, q_start.shape[0]))
        hist = np.empty((2, n, 3))
        info = np.empty(6, dtype=np.int64)
        rotation = target.rotation
        _kernels.igm_solve(
            chain.arrays,
            target.position,
            _EYE if rotation is None else rotation,
            rotation is not None,
            q_start,
            self._bounds_joint if joint else self._bounds_free,
            reach.array,
            options,
            int_options,
            rng_state,
            deadline,
            path,
            hist,
            info,
        )
        code, iterations, restarts_used, slot, length, _ = info.tolist()
        # Copies: the result must not keep the whole scratch buffers alive (batches).
        history = hist[slot, :length].copy()
        position_error, orientation_error, _ = history[-1].tolist()
        attempt = path[slot, :length].copy()
        return IKResult(
            q=attempt[-1].copy(),
            converged=code == 0,
            reason=_kernels.REASON_NAMES[code],
            iterations=iterations,
            restarts_used=restarts_used,
            position_error=position_error,
            orientation_error=orientation_error,
            frame_errors={name: (position_error, orientation_error)},
            residual_history=_Rows(history[1:, 2:]),
            error_history=_Rows(history[:, :2], tuple),
            path=attempt,
            solve_time=time.perf_counter() - start_time,
            engine="compiled",
        )


class _Rows(Sequence):
    """A read-only sequence of the rows of a 2-D array, each converted on access (to a
    list, or a tuple): the compiled engine's histories, built only when read."""

    __slots__ = ("_array", "_kind")

    def __init__(self, array: np.ndarray, kind: type = list):
        self._array = array
        self._kind = kind

    def __len__(self) -> int:
        return self._array.shape[0]

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self._kind(row) for row in self._array[index].tolist()]
        return self._kind(self._array[index].tolist())

    def __eq__(self, other) -> bool:
        return list(self) == list(other)

    def __repr__(self) -> str:
        return repr(list(self))


def _kernel_options(s: _Settings) -> tuple[np.ndarray, np.ndarray]:
    """The float and int option arrays of :func:`qpik.model._kernels.igm_solve`."""
    law = s.damping_law
    max_step = s.max_step if s.max_step is not None else (np.inf, np.inf)
    options = np.array(
        [
            s.tol_position,
            s.tol_orientation,
            s.alpha,
            s.beta,
            max_step[0],
            max_step[1],
            law.singular_threshold if law is not None else 0.0,
            law.max_damping if law is not None else 0.0,
            law.error_scale if law is not None and law.error_scale is not None else 0.0,
            s.damping,
            LIMIT_GAIN,
        ]
    )
    int_options = np.array(
        [s.max_iters, s.restarts, s.stall_window, int(s.time_budget is not None)],
        dtype=np.int64,
    )
    return options, int_options


def _qpos_name(model: mujoco.MjModel, index: int) -> str:
    for j in range(model.njnt):
        if (
            model.jnt_qposadr[j]
            <= index
            < model.jnt_qposadr[j]
            + (7 if model.jnt_type[j] == 0 else 4 if model.jnt_type[j] == 1 else 1)
        ):
            return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint #{j}"
    return f"q[{index}]"


def _pose_errors(position, rotation, target: Target) -> tuple[float, float]:
    d = position - target.position
    position_error = float(math.sqrt(d @ d))
    orientation_error = 0.0
    if target.rotation is not None:
        cosine = (np.trace(rotation @ target.rotation.T) - 1.0) / 2.0
        orientation_error = float(math.acos(min(1.0, max(-1.0, cosine))))
    return position_error, orientation_error


def _worst(errors: Mapping[str, tuple[float, float]]) -> tuple[float, float]:
    return max(p for p, _ in errors.values()), max(o for _, o in errors.values())


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
    seed: int | np.random.Generator | np.random.SeedSequence | None = None,
    alpha: float = 1.0,
    beta: float = 1.0,
    solver: str = "auto",
    stall_window: int = 5,
    damping_law: DampingLaw | None = IGM_DAMPING,
    max_step: tuple[float, float] | None = (0.2, 0.5),
    secondary: bool = False,
    damping: float = 1e-6,
    engine: str = "auto",
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
            matches. Every task of its level 0 must be within tolerance for ``converged``
            (see the module docstring).
        limits: ``"joint"`` (position limits of the model), ``None`` or a list of limits.
        tol_position: [m], finite and > 0; tol_orientation: [rad], finite and > 0.
        max_iters: iterations per attempt (int in [0, 100000]).
        time_budget: [s] for the whole solve, restarts included: ``None`` (no limit) or
            finite and >= 0.
        restarts: random restarts allowed after the first attempt (int >= 0); ``None``
            (default): 20 without a budget, and as many as ``time_budget`` allows (at most
            1000) with one.
        seed: seed of the restarts' random configurations: an int >= 0, a numpy
            ``Generator`` (one draw is taken from it) or ``SeedSequence``; same seed, same
            result. ``None``: fresh entropy.
        alpha: gain of the target tasks in (0, 1]; beta: step scale (> 0).
        solver: QP backend of the ``"qp"`` engine (see :class:`qpik.IKSolver`); the
            ``"compiled"`` engine always solves its QPs exactly by its own active set.
        stall_window: iterations without a 1 % improvement that count as no progress.
        damping_law: singularity damping; for a solve it also fades with the error.
        max_step: trust region ``(metres, radians)``: no iteration asks a target task for
            more than this (``None``: full steps, the lecture's recursion).
        secondary: with the default stack on a redundant arm, add distance from the joint
            limits as a level-1 objective in the null space of the targets (``"qp"``
            engine).
        damping: constant Tikhonov damping of every level (see :class:`qpik.IKSolver`).
        engine: ``"auto"`` (compiled when it applies), ``"compiled"`` (raise
            :class:`qpik.InvalidInput` when it does not apply) or ``"qp"``.

    Bad arguments raise a :class:`qpik.QpikError` subclass naming them. Each call prepares
    the robot anew (nothing is kept between calls); to solve many targets on one robot,
    hold an :class:`IKSession`.
    """
    return IKSession(robot).solve(
        targets,
        q0=q0,
        stack=stack,
        limits=limits,
        tol_position=tol_position,
        tol_orientation=tol_orientation,
        max_iters=max_iters,
        time_budget=time_budget,
        restarts=restarts,
        seed=seed,
        alpha=alpha,
        beta=beta,
        solver=solver,
        stall_window=stall_window,
        damping_law=damping_law,
        max_step=max_step,
        secondary=secondary,
        damping=damping,
        engine=engine,
    )


def clear_pool() -> None:
    """Forget the robots :func:`solve` loaded by name (it keeps nothing else between
    calls). Needed only after editing a robot file in place within the same second."""
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


# ------------------------------------------------------------------- general path
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


def _task_errors(task, configuration: Configuration) -> tuple[float, float] | None:
    """(position-like error, orientation error) of a level-0 task at ``configuration``, or
    ``None`` for a task without a target (see the module docstring for the rule)."""
    try:
        if isinstance(task, PositionTask):
            if task.target is None:
                return None
            position = configuration.frame_pose(task.frame_name, task.frame_type)[0]
            return float(np.linalg.norm(position - task.target)), 0.0
        if isinstance(task, OrientationTask):
            if task.target is None:
                return None
            rotation = configuration.frame_pose(task.frame_name, task.frame_type)[1]
            return 0.0, _pose_errors(np.zeros(3), rotation, Target(np.zeros(3), task.target))[1]
        if isinstance(task, PoseTask):
            if task.target_position is None:
                return None
            pose = configuration.frame_pose(task.frame_name, task.frame_type)
            p, o = _pose_errors(*pose, Target(task.target_position, task.target_rotation))
            return (p if np.any(task.cost[:3] > 0) else 0.0), (
                o if np.any(task.cost[3:] > 0) else 0.0
            )
        if isinstance(task, mink.FrameTask):
            target = task.transform_target_to_world
            if target is None:
                return None
            pose = configuration.frame_pose(task.frame_name, task.frame_type)
            p, o = _pose_errors(*pose, Target(target.translation(), target.rotation().as_matrix()))
            return (p if np.any(task.cost[:3] > 0) else 0.0), (
                o if np.any(task.cost[3:] > 0) else 0.0
            )
        error = np.asarray(task.compute_error(configuration), dtype=float)
    except mink.TargetNotSet:
        return None
    return float(np.linalg.norm(error)), 0.0


class _Problem:
    """What a general-path solve iterates: a scratch configuration, the stack and its
    solver, built afresh for every solve (nothing carries over between solves)."""

    def __init__(
        self, model, frames, stack, limits, alpha, solver, damping_law, secondary, damping
    ):
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
            limits = [ConfigurationLimit(model)]
        self.limits = list(limits or ())
        extra = {}
        if OSQPSettings is not None and solver == "osqp":
            # Iterates need no more accuracy than it takes to find the active set: the
            # refinement step then makes each step exact.
            extra["osqp_settings"] = OSQPSettings(eps_abs=1e-5, eps_rel=1e-5)
        self.solver = IKSolver(
            model,
            levels,
            self.limits,
            solver=solver,
            damping=damping,
            damping_law=damping_law,
            **extra,
        )
        self.levels = levels
        self.alpha = alpha
        self.primary = [
            t
            for t in levels[0]
            if isinstance(t, (PositionTask, OrientationTask, PoseTask, FrameTask))
        ]
        self.frames = frames
        if self.custom_stack:
            _set_stack_targets(self.levels, frames)
        else:
            for task, (_, _, target) in zip(self.target_tasks, frames):
                if isinstance(task, PoseTask):
                    task.set_target(target.position, target.rotation)
                else:
                    task.set_target(target.position)
        self.base_gains = [task.gain for task in self.primary]  # the user's gains
        target_frames = {name for name, _, _ in frames}
        # Level-0 tasks checked for convergence besides the target frames.
        self.level0 = [t for t in levels[0] if getattr(t, "frame_name", None) not in target_frames]

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
        return {
            name: _pose_errors(*configuration.frame_pose(name, kind), target)
            for name, kind, target in self.frames
        }

    def level0_errors(self, configuration: Configuration) -> list[tuple[float, float]]:
        """(position-like, orientation) errors of level 0's other tasks."""
        out = []
        for task in self.level0:
            errors = _task_errors(task, configuration)
            if errors is not None:
                out.append(errors)
        return out


def _iterate(problem: _Problem, q0, start_time: float, rng_state, settings: _Settings) -> IKResult:
    """The IGM loop of :func:`solve` on a prepared problem (the ``"qp"`` engine)."""
    try:
        return _loop(problem, q0, start_time, rng_state, settings)
    finally:
        problem.restore_gains()


def _loop(problem: _Problem, q0, start_time: float, rng_state, settings: _Settings) -> IKResult:
    tol_position, tol_orientation = settings.tol_position, settings.tol_orientation
    max_iters, time_budget, restarts = settings.max_iters, settings.time_budget, settings.restarts
    beta, stall_window, max_step = settings.beta, settings.stall_window, settings.max_step
    damping_law = settings.damping_law
    configuration = problem.configuration
    model = configuration.model
    configuration.update(q0)
    rng = np.random.default_rng(int(rng_state[0]))
    lower, upper = configuration.lower, configuration.upper
    threshold = damping_law.singular_threshold if damping_law is not None else 0.0

    def measure() -> tuple[dict[str, tuple[float, float]], float, bool, float]:
        errors = problem.errors(configuration)
        items = list(errors.values()) + problem.level0_errors(configuration)
        score = max(p / tol_position + o / tol_orientation for p, o in items)
        done = all(p <= tol_position and o <= tol_orientation for p, o in items)
        return errors, score, done, sum(p * p + o * o for p, o in items)

    def out_of_time() -> bool:
        return time_budget is not None and time.perf_counter() - start_time > time_budget

    best_q = configuration.q
    best_errors, best_score, best_done, _ = measure()
    best_history: list[list[float]] = []
    best_error_history = [_worst(best_errors)]
    best_path = [best_q]
    total_iterations = 0
    attempt = 0
    reason = "max_iters"
    first = True
    while True:
        history: list[list[float]] = []
        errors, current, done, energy = measure()
        error_history = [_worst(errors)]
        path = [configuration.q]
        window_start = current
        since_progress = 0
        attempt_reason = "max_iters"
        last_step = None
        for _ in range(max_iters):
            if done:
                attempt_reason = "converged"
                break
            if out_of_time():
                attempt_reason = "time_budget"
                break
            if max_step is not None:
                problem.clamp_gains(errors, *max_step)
            last_step = problem.solver.step(configuration, 1.0)
            total_iterations += 1
            history.append(list(last_step.residuals))
            # Backtracking, as the compiled engine: halve a step that increases the error.
            q_base = configuration.q
            scale = beta
            for halving in range(BACKTRACKS + 1):
                q = q_base.copy()
                mujoco.mj_integratePos(model, q, scale * last_step.displacement, 1.0)
                if beta > 1.0:
                    q = np.clip(q, lower, upper)
                configuration.update(q)
                errors, current, done, new_energy = measure()
                if new_energy < energy or halving == BACKTRACKS:
                    break
                scale *= 0.5
            energy = new_energy
            error_history.append(_worst(errors))
            path.append(q)
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
            if done:
                attempt_reason = "converged"
        if done:
            attempt_reason = "converged"
        if first or (done and not best_done) or (done == best_done and current < best_score):
            best_q, best_errors, best_score, best_done = configuration.q, errors, current, done
            best_history, best_error_history, best_path = history, error_history, path
        first = False
        reason = attempt_reason
        timed_out = out_of_time()
        if attempt_reason == "converged" or attempt >= restarts or timed_out:
            if timed_out and attempt_reason != "converged":
                reason = "time_budget"
            break
        attempt += 1
        configuration.update(configuration.random_q(rng))
    worst = _worst(best_errors)
    return IKResult(
        q=best_q,
        converged=best_done,
        reason="converged" if best_done else reason,
        iterations=total_iterations,
        restarts_used=attempt,
        position_error=worst[0],
        orientation_error=worst[1],
        frame_errors=best_errors,
        residual_history=best_history,
        error_history=best_error_history,
        path=np.array(best_path),
        solve_time=time.perf_counter() - start_time,
        engine="qp",
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
