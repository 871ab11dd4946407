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

Options: every keyword of :func:`solve` and :meth:`IKSession.solve` is a field of
:class:`qpik.SolveOptions` (or of its :class:`qpik.StepOptions`), whose docstrings hold the
defaults; ``options=`` takes a whole set (or a preset name: ``"precise"``, ``"fast"``,
...), and explicit keywords override it.

Layout: targets are parsed in :mod:`qpik.targets`, results and reasons live in
:mod:`qpik.result`, the ``"qp"`` engine in :mod:`qpik.qp_engine` and the restart loop (shared
with :mod:`qpik.baselines`) in :mod:`qpik.restarts`; this module holds the session and the
entry point. Its former names (``Target``, ``parse_target``, ``REASONS``, ...) are
re-exported here.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any

import mink
import mujoco
import numpy as np
import numpy.typing as npt

from .configuration import Configuration, FrameType, _qpos_joint_names
from .errors import InvalidConfiguration, InvalidInput, InvalidTarget, JointLimitViolation
from .hierarchy import DampingLaw, Stack
from .model import KinematicChain, ReachBound, _kernels, chain_support, joint_limits
from .model.frames import resolve_frame
from .options import (  # noqa: F401 (the limits re-exported for the former single module)
    DEFAULT_RESTARTS,
    IGM_DAMPING,
    MAX_AUTO_RESTARTS,
    MAX_ITERS_LIMIT,
    UNSET,
    SolveOptions,
    _Unset,
    resolve,
)
from .qp_engine import QPProblem, iterate, set_frame_target
from .restarts import Clock
from .result import IGM_REASONS, REASONS, IKResult, LazyRows, Reason
from .robots import resolve_robot
from .targets import (  # noqa: F401 (MAX_TARGET_DISTANCE re-exported)
    MAX_TARGET_DISTANCE,
    FrameKey,
    RobotLike,
    Target,
    TargetLike,
    parse_target,
    pose_errors,
    worst_errors,
)

__all__ = [
    "IGM_DAMPING",
    "IGM_REASONS",
    "REASONS",
    "FrameKey",
    "IKResult",
    "IKSession",
    "Reason",
    "RobotLike",
    "SolveOptions",
    "Target",
    "TargetLike",
    "clear_pool",
    "parse_target",
    "set_frame_target",
    "solve",
]

#: Gain of the joint-limit box (mink's ConfigurationLimit default): a step covers at most
#: this fraction of the distance to a limit.
LIMIT_GAIN = 0.95
#: Halvings of a step that increases the error ``sum |e_p|^2 + |e_o|^2`` [m^2, rad^2].
BACKTRACKS = _kernels.BACKTRACKS
_EYE = np.eye(3)
#: The option keywords of :func:`solve` besides ``seed`` (fields of SolveOptions and of its
#: StepOptions).
_OPTION_KEYWORDS = (
    "limits",
    "tol_position",
    "tol_orientation",
    "max_iters",
    "time_budget",
    "restarts",
    "alpha",
    "beta",
    "solver",
    "stall_window",
    "damping_law",
    "max_step",
    "secondary",
    "damping",
    "engine",
)
Seed = int | np.random.Generator | np.random.SeedSequence | None


def clear_pool() -> None:
    """Kept for compatibility; does nothing. :func:`solve` keeps no pool of robots: each
    call loads its robot, and an :class:`IKSession` holds one robot for many solves."""


def _rng_state(seed: Seed) -> np.ndarray:
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


def _kernel_options(s: SolveOptions) -> tuple[np.ndarray, np.ndarray]:
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
        [s.max_iters, s.effective_restarts, s.stall_window, int(s.time_budget is not None)],
        dtype=np.int64,
    )
    return options, int_options


class _Frame:
    """A target frame of a session: name, type and, for hinge/slide models, its chain and
    reach bound."""

    __slots__ = ("chain", "kind", "name", "reach")

    def __init__(
        self,
        name: str,
        kind: FrameType,
        chain: KinematicChain | None,
        reach: ReachBound | None,
    ) -> None:
        self.name, self.kind, self.chain, self.reach = name, kind, chain, reach


# ------------------------------------------------------------------------ session
class IKSession:
    """A robot prepared for repeated solves: hold one per robot and call :meth:`solve`.

    It loads the robot once and reads the model once (joint limits, and per target frame
    its kinematic chain and reach bound, on first use). These caches belong to the session:
    after editing the model in place (its joint ranges, say), make a new session. Results
    never depend on what it solved before. :func:`solve` makes one per call.

    Args:
        robot: anything :func:`qpik.robots.resolve_robot` accepts (a name, ``"erd:NAME"``,
            a path, an ``MjModel``), or a :class:`qpik.Configuration` (its ``q`` is the
            default start).
        options: the session's default :class:`qpik.SolveOptions` (or a preset name);
            ``None``: ``PRESETS["default"]``.
    """

    def __init__(self, robot: RobotLike, options: SolveOptions | str | None = None):
        model, robot_q = resolve_robot(robot)
        self.model: mujoco.MjModel = model
        self.options: SolveOptions = resolve(options)
        self._robot_q = robot_q
        self._support = chain_support(model)
        if self._support is None:
            lower, upper = joint_limits(model)
        else:
            configuration = Configuration(model)
            lower, upper = configuration.lower.copy(), configuration.upper.copy()
        self._lower, self._upper = lower, upper
        sample_lo = np.where(np.isfinite(lower), lower, -np.pi)
        sample_hi = np.where(np.isfinite(upper), upper, np.pi)
        self._mid = model.qpos0.copy()
        limited = np.isfinite(lower) & np.isfinite(upper)
        self._mid[limited] = 0.5 * (lower[limited] + upper[limited])
        free = np.full(model.nq, np.inf)
        self._bounds_joint = np.array([lower, upper, sample_lo, sample_hi])
        self._bounds_free = np.array([-free, free, sample_lo, sample_hi])
        self._memo: tuple | None = None  # the last (options, overrides) -> derived arrays
        self._frames: dict = {}  # frame key -> _Frame

    # ------------------------------------------------------------------ frames
    def _frame(self, key: FrameKey) -> _Frame:
        try:
            cached = self._frames.get(key)
        except TypeError:  # unhashable key
            cached = None
        if cached is not None:
            return cached
        name, kind, _ = resolve_frame(self.model, key, argument="targets")
        chain = reach = None
        if self._support is None:
            chain = KinematicChain.from_model(self.model, name, kind)
            reach = chain.reach_bound(self._lower, self._upper)
        entry = _Frame(name, kind, chain, reach)
        self._frames[key] = entry
        return entry

    def reach_bound(self, frame: FrameKey) -> ReachBound | None:
        """The :class:`qpik.model.ReachBound` of ``frame`` within the joint limits, or
        ``None`` for a model with ball or free joints."""
        return self._frame(frame).reach

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
        options: SolveOptions | str | None = None,
        seed: Seed | _Unset = UNSET,
        limits: str | Sequence[mink.Limit] | None | _Unset = UNSET,
        tol_position: float | _Unset = UNSET,
        tol_orientation: float | _Unset = UNSET,
        max_iters: int | _Unset = UNSET,
        time_budget: float | None | _Unset = UNSET,
        restarts: int | None | _Unset = UNSET,
        alpha: float | _Unset = UNSET,
        beta: float | _Unset = UNSET,
        solver: str | _Unset = UNSET,
        stall_window: int | _Unset = UNSET,
        damping_law: DampingLaw | None | _Unset = UNSET,
        max_step: tuple[float, float] | None | _Unset = UNSET,
        secondary: bool | _Unset = UNSET,
        damping: float | _Unset = UNSET,
        engine: str | _Unset = UNSET,
    ) -> IKResult:
        """Solve inverse kinematics; the arguments are :func:`solve`'s (``options``
        defaults to the session's)."""
        start_time = time.perf_counter()
        given = locals()
        overrides = {k: given[k] for k in _OPTION_KEYWORDS if given[k] is not UNSET}
        settings, kernel_options = self._options(options, overrides)
        rng_state = _rng_state(settings.seed if isinstance(seed, _Unset) else seed)
        frames = self._targets(targets)
        compiled_ok = self._compiled_applies(settings, stack, frames)
        joint = settings.limits == "joint"
        limited = joint or bool(settings.limits)
        q_start = self._start(q0, check=limited)
        if compiled_ok and settings.engine != "qp":
            return self._solve_compiled(
                frames[0], q_start, joint, settings, kernel_options, rng_state, start_time
            )
        for _frame, target in frames:
            if _frame.reach is not None and _frame.reach.excludes(
                target.position, settings.tol_position
            ):
                return self._answer_unreachable(frames, q_start, start_time)
        plain = [(f.name, f.kind, target) for f, target in frames]
        problem = QPProblem(self.model, plain, stack, settings)
        clock = Clock(start_time, settings.time_budget)
        return iterate(problem, q_start, clock, int(rng_state[0]), settings)

    # ---------------------------------------------------------------- helpers
    def _options(
        self, options: SolveOptions | str | None, overrides: dict[str, Any]
    ) -> tuple[SolveOptions, tuple[np.ndarray, np.ndarray]]:
        """The options of a solve, validated once for a run of solves with the same ones,
        with the compiled engine's option arrays."""
        try:
            key = (options, tuple(overrides.items()))
            hash(key)
        except TypeError:  # a list of limits, say: not remembered
            key = None
        memo = self._memo
        if key is not None and memo is not None and memo[0] == key:
            return memo[1], memo[2]
        base = self.options if options is None else resolve(options)
        settings = base.replace(**overrides)
        derived = (settings, _kernel_options(settings))
        if key is not None:
            self._memo = (key, *derived)
        return derived

    def _targets(self, targets: Mapping[FrameKey, TargetLike]) -> list[tuple[_Frame, Target]]:
        if type(targets) is not dict and not isinstance(targets, Mapping):
            raise InvalidInput(
                f"targets must be a mapping {{frame: target}}, got {type(targets).__name__}"
            )
        if not targets:
            raise InvalidTarget("no targets given: pass {frame: target, ...}")
        return [(self._frame(key), parse_target(value)) for key, value in targets.items()]

    def _compiled_applies(
        self, settings: SolveOptions, stack: Stack | None, frames: list[tuple[_Frame, Target]]
    ) -> bool:
        """Whether the compiled engine takes this solve; raises when ``engine='compiled'``
        was asked for and it does not."""
        applies = (
            stack is None
            and (settings.limits is None or settings.limits == "joint")
            and len(frames) == 1
            and frames[0][0].reach is not None
            and not settings.secondary
        )
        if settings.engine == "compiled" and not applies:
            raise InvalidInput(
                "engine='compiled' needs one frame target, the default stack, limits 'joint' "
                "or None, secondary=False and a model of hinge and slide joints"
                + (f" ({self._support})" if self._support else "")
            )
        return applies

    def _start(self, q0: npt.ArrayLike | None, check: bool) -> np.ndarray:
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
                    _qpos_joint_names(self.model)[i],
                    i,
                    float(q[i]),
                    float(self._lower[i]),
                    float(self._upper[i]),
                )
            np.clip(q, self._lower, self._upper, out=q)
        elif check:
            Configuration(self.model, q).check_limits()
        return q

    def _answer_unreachable(
        self, frames: list[tuple[_Frame, Target]], q: np.ndarray, start_time: float
    ) -> IKResult:
        errors = {}
        for frame, target in frames:
            assert frame.chain is not None  # reach bounds exist only with chains
            errors[frame.name] = pose_errors(*frame.chain.pose(q), target)
        worst = worst_errors(errors)
        return IKResult(
            q=q,
            converged=False,
            reason=Reason.UNREACHABLE,
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
        self, frame_target, q_start, joint, settings, kernel_options, rng_state, start_time
    ) -> IKResult:
        frame, target = frame_target
        options, int_options = kernel_options
        deadline = start_time + settings.time_budget if int_options[3] else np.inf
        n = settings.max_iters + 1
        path = np.empty((2, n, q_start.shape[0]))
        hist = np.empty((2, n, 3))
        info = np.empty(6, dtype=np.int64)
        rotation = target.rotation
        _kernels.igm_solve(
            frame.chain.arrays,
            target.position,
            _EYE if rotation is None else rotation,
            rotation is not None,
            q_start,
            self._bounds_joint if joint else self._bounds_free,
            frame.reach.array,
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
            reason=Reason(_kernels.REASON_NAMES[code]),
            iterations=iterations,
            restarts_used=restarts_used,
            position_error=position_error,
            orientation_error=orientation_error,
            frame_errors={frame.name: (position_error, orientation_error)},
            residual_history=LazyRows(history[1:, 2:]),
            error_history=LazyRows(history[:, :2], tuple),
            path=attempt,
            solve_time=time.perf_counter() - start_time,
            engine="compiled",
        )


def solve(
    robot: RobotLike,
    targets: Mapping[FrameKey, TargetLike],
    *,
    q0: npt.ArrayLike | None = None,
    stack: Stack | None = None,
    options: SolveOptions | str | None = None,
    limits: str | Sequence[mink.Limit] | None | _Unset = UNSET,
    tol_position: float | _Unset = UNSET,
    tol_orientation: float | _Unset = UNSET,
    max_iters: int | _Unset = UNSET,
    time_budget: float | None | _Unset = UNSET,
    restarts: int | None | _Unset = UNSET,
    seed: Seed | _Unset = UNSET,
    alpha: float | _Unset = UNSET,
    beta: float | _Unset = UNSET,
    solver: str | _Unset = UNSET,
    stall_window: int | _Unset = UNSET,
    damping_law: DampingLaw | None | _Unset = UNSET,
    max_step: tuple[float, float] | None | _Unset = UNSET,
    secondary: bool | _Unset = UNSET,
    damping: float | _Unset = UNSET,
    engine: str | _Unset = UNSET,
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
            matches, for the solve only (the tasks are given back unchanged). Every task of
            its level 0 must be within tolerance for ``converged`` (see the module
            docstring).
        options: a :class:`qpik.SolveOptions`, a preset name of :data:`qpik.PRESETS`
            (``"default"``, ``"precise"``, ``"fast"``, ``"tracking"``) or ``None`` (the
            default preset). The keywords below override it.
        seed: seed of the restarts' random configurations: an int >= 0, a numpy
            ``Generator`` (one draw is taken from it) or ``SeedSequence``; same seed, same
            result. ``None``: fresh entropy. Default: ``options.seed`` (``None``).
        limits, tol_position, tol_orientation, max_iters, time_budget, restarts, alpha,
            beta, stall_window, max_step, secondary, engine: the fields of
            :class:`qpik.SolveOptions` (units, ranges and defaults documented there).
        solver, damping, damping_law: the fields of :class:`qpik.StepOptions` of each step
            (for a solve, ``damping_law`` defaults to the error-faded
            :data:`qpik.options.IGM_DAMPING`); the ``"compiled"`` engine always solves its
            QPs exactly by its own active set.

    Bad arguments raise a :class:`qpik.QpikError` subclass naming them
    (:class:`qpik.InvalidOption` for an option). Each call loads and prepares the robot
    anew (nothing is kept between calls); to solve many targets on one robot, hold an
    :class:`IKSession`.
    """
    given = locals()
    keywords = {k: given[k] for k in _OPTION_KEYWORDS if given[k] is not UNSET}
    return IKSession(robot).solve(
        targets, q0=q0, stack=stack, options=options, seed=seed, **keywords
    )
