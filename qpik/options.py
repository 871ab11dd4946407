"""The options of qpik's entry points, in one place, with their defaults documented once.

* :class:`StepOptions`: one differential-IK step, what :class:`qpik.IKSolver` reads (the QP
  backend, constant and adaptive damping, rank tolerance, warm starts).
* :class:`SolveOptions`: the full-IK loop of :func:`qpik.solve`,
  :meth:`qpik.IKSession.solve`, :func:`qpik.solve_many` and the problem files' solve mode
  (tolerances, iterations, restarts, gains, trust region, limits, engine), with the
  :class:`StepOptions` of its steps.
* :data:`PRESETS`: named :class:`SolveOptions` (``"default"``, ``"precise"``, ``"fast"``,
  ``"tracking"``); ``SolveOptions.preset("fast", max_iters=50)``.
* :class:`SolveKeywords` (and its part :class:`LoopKeywords`): the option keywords of the
  entry points, one per field, typed once: ``qpik.solve(robot, targets, max_iters=50)`` is
  ``options.replace(max_iters=50)``.

Both are frozen dataclasses, validated on construction: a bad value raises
:class:`qpik.InvalidOption` (an :class:`qpik.InvalidInput`) naming the field, the value and
what was expected. Every entry point reads its defaults from here; no literal default is
re-typed elsewhere. Options are hashable (an entry point can remember the work it derived
from them) and compare by value.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import operator
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Final, TypedDict

from .errors import InvalidInput, InvalidOption

__all__ = [
    "DEFAULT_DAMPING",
    "SOLVERS",
    "DampingLaw",
    "DEFAULT_RESTARTS",
    "IGM_BACKEND_OPTIONS",
    "IGM_DAMPING",
    "DEFAULT_WORK_ATTEMPTS",
    "MAX_AUTO_RESTARTS",
    "MAX_ITERS_LIMIT",
    "PRESETS",
    "UNSET",
    "LoopKeywords",
    "SolveKeywords",
    "StepFieldKeywords",
    "SolveOptions",
    "StepOptions",
    "check_integer",
    "check_number",
]

#: Backends of the core's :class:`qpik.core.HierarchySolver`: "auto" is qpik's exact
#: compiled active set.
SOLVERS = ("auto", "osqp", "daqp", "quadprog", "proxqp", "clarabel")


def _real(value: Any) -> bool:
    """A number the damping law takes: a real (NumPy's too), not a bool (a flag set where a
    number was meant: ``True`` read as 1 would damp every level)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


@dataclass(frozen=True)
class DampingLaw:
    """Adaptive damping from the smallest singular value ``sigma`` of a level:
    ``lambda^2 = max_damping^2 (1 - (sigma / singular_threshold)^2)`` below the threshold,
    0 above it (:meth:`__call__`).

    Attributes:
        singular_threshold: ``sigma`` below which damping starts, in the units of the
            level's unweighted Jacobian (e.g. [m/rad] for a position task).
        max_damping: ``lambda`` reached at ``sigma = 0`` (same units), scaled by the
            level's largest cost.
        error_scale: if set, ``lambda^2`` is further scaled by ``min(1, |b - A d| /
            error_scale)``: damping fades as the level's error vanishes (Sugihara 2011);
            :func:`qpik.solve` uses this, velocity control does not.
        lower_trust: if above 0 (at most 1), the levels below a damped level move each dof
            with both bounds finite at most ``lower_trust * sigma / singular_threshold``
            times half its box's width from that level's answer (still within its box):
            near the singularity the damped level's null space turns between two steps, and
            lower levels taking their full step in it make a closed loop cycle (a posture
            below a task whose target is out of reach). 0 (the default) leaves their box as
            it is. The smaller box is no limit: ``StepResult.active_limits`` names only
            the limits the step meets.
    """

    singular_threshold: float = 0.05
    max_damping: float = 0.05
    error_scale: float | None = None
    lower_trust: float = 0.0

    def __post_init__(self) -> None:
        for name in ("singular_threshold", "max_damping"):
            value = getattr(self, name)
            if not (_real(value) and math.isfinite(value) and value >= 0):
                raise InvalidInput(f"DampingLaw.{name} must be finite and >= 0, got {value!r}")
        if self.singular_threshold > 1e6 or self.max_damping > 1e6:
            raise InvalidInput("DampingLaw values above 1e6 are not meaningful")
        if self.error_scale is not None and not (
            _real(self.error_scale)
            and math.isfinite(self.error_scale)
            and 0 < self.error_scale <= 1e6
        ):
            raise InvalidInput(
                f"DampingLaw.error_scale must be None or in (0, 1e6], got {self.error_scale!r}"
            )
        trust = self.lower_trust
        if not (_real(trust) and math.isfinite(trust) and 0 <= trust <= 1):
            raise InvalidInput(f"DampingLaw.lower_trust must be in [0, 1], got {trust!r}")

    def __call__(self, sigma: float, error_norm: float | None = None) -> float:
        """``lambda^2`` (for a level of unit cost) at smallest singular value ``sigma``."""
        if not sigma < self.singular_threshold:
            return 0.0
        ratio = sigma / self.singular_threshold
        lam2 = self.max_damping**2 * (1.0 - ratio * ratio)
        if self.error_scale is not None and error_norm is not None:
            lam2 *= min(1.0, error_norm / self.error_scale)
        return lam2


#: The default damping law of every entry point.
DEFAULT_DAMPING = DampingLaw()


#: The damping law of a full-IK solve: the velocity-control law (:data:`DEFAULT_DAMPING`,
#: ``sigma < 0.05``, ``lambda <= 0.05``) fading with the error (``error_scale = 0.3``).
IGM_DAMPING: Final = DampingLaw(error_scale=0.3)

#: Restarts when ``SolveOptions.restarts`` is ``None``: without a time budget (at most: see
#: :data:`DEFAULT_WORK_ATTEMPTS`), and the most with one. 100 is the Robotics Toolbox's
#: default number of searches (``ik_LM``'s ``slimit``).
DEFAULT_RESTARTS: Final = 100
MAX_AUTO_RESTARTS: Final = 1000
#: Without a time budget and with ``restarts=None``, a solve starts no new attempt once it
#: has run as many iterations as this many attempts of ``max_iters`` can (the work of the
#: first attempt and 20 restarts that each run to ``max_iters``): a deterministic work
#: budget. Attempts that stop early (stalled, blocked at a joint limit: the usual failure of
#: a 5- or 6-DoF arm, a few iterations each) leave room for more restarts, up to
#: :data:`DEFAULT_RESTARTS`; a target no attempt reaches costs no more iterations than 21
#: full attempts.
DEFAULT_WORK_ATTEMPTS: Final = 21
#: The largest ``max_iters`` (the returned attempt's path is kept in memory).
MAX_ITERS_LIMIT: Final = 100_000
#: The largest constant damping: beyond it the QP's regularisation swamps every task.
MAX_DAMPING: Final = 1e12
#: Backend options a full-IK solve uses when ``StepOptions.backend_options`` is ``None``,
#: per backend: the iterates need no more accuracy than it takes to find the active set
#: (the kernel's refinement then makes each step exact).
IGM_BACKEND_OPTIONS: Final = MappingProxyType(
    {"osqp": MappingProxyType({"eps_abs": 1e-5, "eps_rel": 1e-5})}
)
_ENGINES = ("auto", "compiled", "qp")


class Unset:
    """The default of an entry point's keyword: "not given, read it from the options"."""

    _instance = None

    def __new__(cls):
        if cls._instance is None:
            cls._instance = super().__new__(cls)
        return cls._instance

    def __repr__(self) -> str:
        return "<from options>"

    def __reduce__(self):
        return Unset, ()


#: The default of every option keyword of :func:`qpik.solve` and friends: the value then
#: comes from the ``options`` argument (or :data:`PRESETS` ``["default"]``).
UNSET: Final = Unset()


# ------------------------------------------------------------------------- checks
def _set(options: Any, name: str, value: Any) -> None:
    """Store a normalised value on a frozen options object (in ``__post_init__`` only)."""
    object.__setattr__(options, name, value)


def check_number(
    name: str,
    value: Any,
    *,
    allow_zero: bool = False,
    maximum: float | None = None,
    negative: bool = False,
) -> float:
    """``value`` as a finite float, ``> 0`` (``>= 0`` with ``allow_zero``; any sign with
    ``negative``) and at most ``maximum``; else :class:`qpik.InvalidOption` naming ``name``."""
    need = "" if negative else (" >= 0" if allow_zero else " > 0")
    if maximum is not None:
        need += f" and <= {maximum:g}"
    number = float(value) if _is_real(value) else math.nan
    low = -math.inf if negative else 0.0
    above_low = number > low or (allow_zero and number == low)
    below_high = maximum is None or number <= maximum
    if not (math.isfinite(number) and above_low and below_high):
        raise InvalidOption(name, value, f"a finite number{need}")
    return number


def _is_real(value: Any) -> bool:
    """A Python or NumPy int or float (not a bool)."""
    if isinstance(value, bool):
        return False
    return isinstance(value, (int, float)) or _is_numpy_number(value)


def _is_numpy_number(value: Any) -> bool:
    """A NumPy scalar or 0-d array of ints or floats (an array of several is not one)."""
    kind = type(value)
    return (
        kind.__module__ == "numpy"
        and getattr(value, "ndim", None) == 0
        and value.dtype.kind in "iuf"
    )


def check_integer(name: str, value: Any, minimum: int, maximum: int | None = None) -> int:
    """``value`` as an int in ``[minimum, maximum]`` (at most 2**62: the kernels' ints);
    else :class:`qpik.InvalidOption` naming ``name``."""
    maximum = 2**62 if maximum is None else min(maximum, 2**62)
    expected = f"an int in [{minimum}, {maximum}]"
    if isinstance(value, bool):
        raise InvalidOption(name, value, expected)
    try:
        number = operator.index(value)
    except TypeError:
        raise InvalidOption(name, value, expected) from None
    if number < minimum or number > maximum:
        raise InvalidOption(name, value, expected)
    return number


def _check_choice(name: str, value: Any, choices: Sequence[str]) -> str:
    if not isinstance(value, str) or value not in choices:
        expected = f"one of {', '.join(map(repr, choices))}"
        message = None
        if name == "solver":  # a message that lists the known solvers
            message = f"unknown QP solver {value!r}; known solvers: {', '.join(choices)}"
        raise InvalidOption(name, value, expected, message)
    return value


# -------------------------------------------------------------------------- step
#: Default trust region of a differential-IK step [rad/s or m/s]
#: (:attr:`StepOptions.max_joint_speed`): half a turn per second, 0.031 rad or m per 10 ms
#: step, on every dof that no velocity limit of the stack bounds.
DEFAULT_MAX_JOINT_SPEED: Final = math.pi


#: The most second-order correction passes of a step (:attr:`StepOptions.correction_passes`):
#: each pass shrinks the held levels' remainder by a factor of order ``|dq|``; two already
#: leave round-off.
MAX_CORRECTION_PASSES: Final = 10


@dataclass(frozen=True)
class StepOptions:
    """How one differential-IK step is solved (:class:`qpik.IKSolver`).

    Attributes:
        solver: the QP backend: ``"auto"`` (default: qpik's exact compiled active set),
            or one of :data:`qpik.core.SOLVERS` (``"osqp"``, ``"daqp"``, ``"quadprog"``,
            ``"proxqp"``, ``"clarabel"``; each needs its pip extra). A forced backend's
            answer is made exact by the kernel's canonical re-solve.
        damping: constant Tikhonov damping ``mu`` added to every level,
            ``1/2 mu |dq|^2`` in the units of the level's squared rows; finite, in
            ``[0, 1e12]``. Default ``1e-6``.
        damping_law: the adaptive singularity damping (:class:`qpik.DampingLaw`), or
            ``None`` for none. Default :data:`qpik.core.cascade.DEFAULT_DAMPING`
            (``sigma < 0.05``: ``lambda`` up to 0.05, units of the level's Jacobian).
        rank_tolerance: relative singular value below which a direction of a level is not
            a rank (its null space is kept for lower levels); in ``(0, 1)``. Default
            ``1e-9``.
        warm_start: try each level's active set of the previous step first (its KKT
            point, accepted only where strictly optimal), then the same canonical exact
            re-solve as a cold start, so answers agree with cold starts bit for bit where
            the optimal active set is unique. Default ``False``: that check costs more than
            the dual iterations it saves on today's stacks (measured slower: erd Panda
            tracking about 5-20 %, floating Talos about 20 %).
        backend_options: keyword options of the backend (e.g. OSQP's ``eps_abs``), or
            ``None`` (the backend's defaults). Kept as a read-only mapping; not part of
            the hash. OSQP's, DAQP's and quadprog's names and values are checked
            when a solver or solve takes them
            (:func:`qpik.core.backends.check_backend_options`: :class:`qpik.InvalidInput`
            naming the setting); proxqp's and clarabel's names at their first solve, their
            values by the backend. The solver ``"auto"`` runs no backend
            and reads none of them.
        max_joint_speed: the step's trust region [rad/s or m/s]: every dof that no
            velocity limit of the stack bounds (MJCF models, Menagerie's among them, state
            none) is held to ``|dq_i| <= max_joint_speed * dt``, a hard box bound merged
            into the limits' box at every level (met as every hard row is: to the
            certificate's tolerance, a violation of at most 1e-9 (1 + bound)), so that
            each step stays where the linearisation of the tasks and limits holds (without
            it a blocked or unreachable level takes steps of several radians). Dofs that a
            velocity limit bounds keep that limit only (their answers are unchanged). A
            free joint's three translations [m/s] and three rotations [rad/s] take the
            same number.
            ``StepResult.active_limits`` names it ``"trust region"``. Default
            :data:`DEFAULT_MAX_JOINT_SPEED` (``pi``: 0.031 rad per 10 ms step);
            ``None`` turns it off (mink's behaviour).
        couplings: keep the model's couplings (its joint and fixed-tendon equality
            constraints: MJCF ``<equality><joint>``, URDF ``<mimic>``;
            :func:`qpik.model.model_couplings`) as hard rows above every level: a level
            of their rows ``r(q) = 0`` (gain 1) is solved first, and the stack's levels
            act in its null space. ``StepResult`` reports the stack's levels only (the
            coupling level's residual as ``coupling_residual``). No effect on a model
            without couplings. Default ``True``; ``False``: the stack alone (mink's
            behaviour).
        correction_passes: second-order corrections of :meth:`qpik.IKSolver.step` (an
            int in ``[0, 10]``; default ``0``: none, the step as it always was, bit for
            bit). A step holds a task's linearisation ``J dq = -gain e`` exactly, but
            after ``q <- q (+) dq`` the task keeps the remainder ``r = e(q (+) dq) - e(q)
            - J dq``, of order ``|dq|^2`` (a held foot drifts by a fraction of a mm per
            step on a walking humanoid). Each pass evaluates the held levels' task errors
            once at ``q (+) dq`` (one forward kinematics, no new Jacobian), shifts those
            levels' targets by the remainder, ``b <- b - cost r``, and solves the step
            again with the same rows, damping and limits (so every limit still holds and
            the levels below stay optimal in the held levels' null space): the remainder
            left falls to order ``|dq|^3``. The held levels are decided once, from the
            uncorrected step: every level whose status is ``solved`` and whose weighted
            residual is met, ``|A_k dq - b_k| <= 1e-2 |b_k| + 1e-9 |A_k|_F |dq|`` (the
            step asks 99 % or more of the level's change and gets it; constant and
            adaptive damping alone leave less than that); a level the step can only
            approach (an unreachable target, a singular level) is left as it is. A
            task is corrected when it follows mink's :class:`mink.Task` contract (rows
            ``diag(cost) J``, ``-gain cost e``, its ``compute_error``); a task that only
            gives its own QP objective is not. The result's residuals and certificates
            are those of the corrected QP (targets shifted). Each pass costs one forward
            kinematics and one more solve of the cascade (on the floating Talos of
            ``benchmarks/step_time.py``, about as much as the step itself: one pass
            doubles its time and takes the feet's mean error after a step from 0.23 mm to
            0.02 mm). Read by :meth:`qpik.IKSolver.step` only (in the compiled step,
            collision and other general rows included, wherever the step takes it; else on
            the QP path); the compiled engine of :func:`qpik.solve` does not read it. With
            passes a forced backend agrees with ``"auto"`` to round-off (up to 4e-9 rad/s
            measured), not bit for bit. A pass that changes which limit binds can leave
            the held level further off (2 of 953 levels measured: 1.9e-4 against 6.2e-5).
    """

    solver: str = "auto"
    damping: float = 1e-6
    damping_law: DampingLaw | None = DEFAULT_DAMPING
    rank_tolerance: float = 1e-9
    warm_start: bool = False
    backend_options: Mapping[str, Any] | None = field(default=None, hash=False)
    max_joint_speed: float | None = DEFAULT_MAX_JOINT_SPEED
    couplings: bool = True
    correction_passes: int = 0

    def __post_init__(self) -> None:
        _check_choice("solver", self.solver, SOLVERS)
        _set(
            self,
            "correction_passes",
            check_integer("correction_passes", self.correction_passes, 0, MAX_CORRECTION_PASSES),
        )
        if not isinstance(self.couplings, bool):
            raise InvalidOption("couplings", self.couplings, "True or False")
        if self.max_joint_speed is not None:
            _set(
                self,
                "max_joint_speed",
                check_number("max_joint_speed", self.max_joint_speed, maximum=1e12),
            )
        _set(
            self,
            "damping",
            check_number("damping", self.damping, allow_zero=True, maximum=MAX_DAMPING),
        )
        if self.damping_law is not None and not isinstance(self.damping_law, DampingLaw):
            raise InvalidOption("damping_law", self.damping_law, "a qpik.DampingLaw or None")
        tolerance = check_number("rank_tolerance", self.rank_tolerance)
        if not tolerance < 1.0:
            raise InvalidOption("rank_tolerance", self.rank_tolerance, "a number in (0, 1)")
        _set(self, "rank_tolerance", tolerance)
        if not isinstance(self.warm_start, bool):
            raise InvalidOption("warm_start", self.warm_start, "True or False")
        if self.backend_options is not None:
            if not isinstance(self.backend_options, Mapping) or not all(
                isinstance(k, str) for k in self.backend_options
            ):
                raise InvalidOption(
                    "backend_options", self.backend_options, "a mapping {name: value} or None"
                )
            _set(self, "backend_options", MappingProxyType(dict(self.backend_options)))

    def replace(self, **overrides: Any) -> StepOptions:
        """A copy with ``overrides`` (field names), validated."""
        _check_fields(StepOptions, overrides)
        return dataclasses.replace(self, **overrides)


# ------------------------------------------------------------------------- solve
#: The fields of :class:`StepOptions`: in :meth:`SolveOptions.replace` and the entry
#: points' keywords they set the options of the solve's steps.
STEP_FIELDS: Final = (
    "solver",
    "damping",
    "damping_law",
    "rank_tolerance",
    "warm_start",
    "backend_options",
    "couplings",
)

#: The steps of a full-IK solve: :class:`StepOptions` with the error-faded damping law.
#: No step trust region (``max_joint_speed=None``): full IK sizes its own iterations.
SOLVE_STEP: Final = StepOptions(damping_law=IGM_DAMPING, max_joint_speed=None)


@dataclass(frozen=True)
class SolveOptions:
    r"""How a full-IK solve iterates (:func:`qpik.solve`; see :mod:`qpik.igm.session` for the
    loop ``q_{i+1} = q_i + beta dq``, ``J dq = -alpha e``).

    Attributes:
        tol_position: a frame (and every position-like level-0 task) has converged within
            this distance of its target [m]; finite, > 0. Default ``1e-4``.
        tol_orientation: likewise for angles [rad]; finite, > 0. Default ``1e-3``.
        max_iters: iterations per attempt, an int in ``[0, 100000]``. Default ``100``. A
            stack of several levels then steps level 0 alone while it is unmet, at most
            20 more (``qp_engine.LEVEL0_STEPS``): up to ``max_iters + 20`` an attempt.
        time_budget: wall time for the whole solve, restarts included [s]: ``None``
            (default, no limit) or finite and >= 0. A budget makes the result depend on
            the machine's speed.
        restarts: random restarts allowed after the first attempt (int >= 0); ``None``
            (default): without a time budget, up to 100 within a work budget of
            ``21 * max_iters`` iterations in all (:attr:`iteration_budget`: attempts that
            stop early leave room for more restarts), and with one, as many as
            ``time_budget`` allows (at most 1000) (:attr:`effective_restarts`).
        seed: seed of the restarts' random configurations, an int >= 0, or ``None``
            (default: fresh entropy, not reproducible). Same seed, bitwise the same result.
            (:func:`qpik.solve` also takes a numpy ``Generator`` or ``SeedSequence`` as its
            ``seed`` keyword; a batch's seed is :func:`qpik.solve_many`'s own argument.)
        alpha: gain of the target tasks, in ``(0, 1]`` (dimensionless: the fraction of the
            error a step asks for). Default ``1``.
        beta: scale of the step the QP returns, > 0 (``beta > 1`` iterates are clipped
            into the joint limits). Default ``1``.
        stall_window: iterations without progress after which an attempt stops (int >= 1):
            an iteration makes progress when its score (over the frames, the largest
            ``position / tol_position + orientation / tol_orientation``) falls below 95 % of
            the score at the window's start, a 5 % decrease
            (:data:`qpik.igm.kernels.PROGRESS`). Default ``5``.
        max_step: trust region ``(metres, radians)``: no iteration asks a target task for
            more than this; ``None`` for full steps ``J dq = -alpha e``. Default
            ``(0.2, 0.5)``.
        secondary: with the default stack on a redundant arm, add distance from the joint
            limits as a level-1 objective in the null space of the targets (``"qp"``
            engine). Default ``False``.
        limits: ``"joint"`` (default: the model's joint position limits), ``None`` (none)
            or a sequence of limits (kept as a tuple). With collision limits among them
            (:class:`qpik.limits.CollisionAvoidanceLimit`,
            :func:`qpik.limits.model_collision_limit`), a solve converges only where
            every pair they check is at least ``d_min - tol_position`` apart, and its
            steps never take a pair deeper inside ``d_min`` (``"qp"`` engine).
        engine: ``"auto"`` (default: the compiled engine when it applies), ``"compiled"``
            (raise :class:`qpik.InvalidInput` when it does not apply) or ``"qp"``.
        step: the :class:`StepOptions` of each step; default :data:`SOLVE_STEP` (the
            backend ``"auto"``, damping ``1e-6``, and the error-faded damping law
            :data:`IGM_DAMPING`). Its fields can be given flat to :meth:`replace`,
            :meth:`preset` and the entry points (``solver=``, ``damping=``,
            ``damping_law=``...); read them as :attr:`solver`, :attr:`damping`,
            :attr:`damping_law`.
    """

    tol_position: float = 1e-4
    tol_orientation: float = 1e-3
    max_iters: int = 100
    time_budget: float | None = None
    restarts: int | None = None
    seed: int | None = None
    alpha: float = 1.0
    beta: float = 1.0
    stall_window: int = 5
    max_step: tuple[float, float] | None = (0.2, 0.5)
    secondary: bool = False
    limits: str | tuple | None = "joint"
    engine: str = "auto"
    step: StepOptions = SOLVE_STEP

    def __post_init__(self) -> None:
        self._check_numbers()
        self._check_structure()

    def _check_numbers(self) -> None:
        """Tolerances, counts, gains and the time budget."""
        _set(self, "tol_position", check_number("tol_position", self.tol_position))
        _set(self, "tol_orientation", check_number("tol_orientation", self.tol_orientation))
        _set(self, "max_iters", check_integer("max_iters", self.max_iters, 0, MAX_ITERS_LIMIT))
        if self.time_budget is not None:
            _set(
                self, "time_budget", check_number("time_budget", self.time_budget, allow_zero=True)
            )
        if self.restarts is not None:
            _set(self, "restarts", check_integer("restarts", self.restarts, 0))
        if self.seed is not None:
            _set(self, "seed", _check_seed(self.seed))
        _set(self, "alpha", check_number("alpha", self.alpha, maximum=1.0))
        _set(self, "beta", check_number("beta", self.beta))
        _set(self, "stall_window", check_integer("stall_window", self.stall_window, 1))

    def _check_structure(self) -> None:
        """The trust region, the flags, the limits, the engine and the step options."""
        if self.max_step is not None:
            if not (isinstance(self.max_step, (tuple, list)) and len(self.max_step) == 2):
                raise InvalidOption("max_step", self.max_step, "(metres, radians) or None")
            metres = check_number("max_step[0] (metres)", self.max_step[0])
            radians = check_number("max_step[1] (radians)", self.max_step[1])
            _set(self, "max_step", (metres, radians))
        if not isinstance(self.secondary, bool):
            raise InvalidOption("secondary", self.secondary, "True or False")
        _set(self, "limits", _check_limits(self.limits))
        _check_choice("engine", self.engine, _ENGINES)
        if not isinstance(self.step, StepOptions):
            raise InvalidOption("step", self.step, "a qpik.StepOptions")

    # ------------------------------------------------------------------ derived
    @property
    def solver(self) -> str:
        """The QP backend of the steps (``step.solver``)."""
        return self.step.solver

    @property
    def damping(self) -> float:
        """The constant damping of the steps (``step.damping``)."""
        return self.step.damping

    @property
    def damping_law(self) -> DampingLaw | None:
        """The adaptive damping law of the steps (``step.damping_law``)."""
        return self.step.damping_law

    @property
    def couplings(self) -> bool:
        """Whether the model's couplings hold (``step.couplings``)."""
        return self.step.couplings

    @property
    def effective_restarts(self) -> int:
        """``restarts``, or for ``None`` 100 without a time budget (within
        :attr:`iteration_budget`) and 1000 with one."""
        if self.restarts is not None:
            return self.restarts
        return DEFAULT_RESTARTS if self.time_budget is None else MAX_AUTO_RESTARTS

    @property
    def iteration_budget(self) -> int | None:
        """The iterations (over all attempts) after which a solve starts no new attempt:
        ``DEFAULT_WORK_ATTEMPTS * max_iters`` when ``restarts`` and ``time_budget`` are both
        ``None`` (:data:`DEFAULT_WORK_ATTEMPTS`), else ``None`` (no such budget: the
        restarts given, or the time budget, bound the solve)."""
        if self.restarts is None and self.time_budget is None:
            return DEFAULT_WORK_ATTEMPTS * self.max_iters
        return None

    # ------------------------------------------------------------------ builders
    def replace(self, **overrides: Any) -> SolveOptions:
        """A copy with ``overrides``: field names, or :class:`StepOptions` field names
        (``solver``, ``damping``, ``damping_law``...), which replace those of ``step``.
        Validated; an unknown name raises :class:`qpik.InvalidOption`."""
        if not overrides:
            return self
        step = {k: overrides.pop(k) for k in STEP_FIELDS if k in overrides}
        _check_fields(SolveOptions, overrides)
        if step:
            overrides["step"] = overrides.get("step", self.step).replace(**step)
        return dataclasses.replace(self, **overrides)

    @classmethod
    def preset(cls, name: str, **overrides: Any) -> SolveOptions:
        """The preset ``name`` of :data:`PRESETS`, with ``overrides`` (see :meth:`replace`)."""
        return resolve(name).replace(**overrides)


def resolve(options: SolveOptions | str | None) -> SolveOptions:
    """``options`` as :class:`SolveOptions`: a preset name of :data:`PRESETS`, ``None``
    (``PRESETS["default"]``) or options themselves."""
    if options is None:
        return PRESETS["default"]
    if isinstance(options, SolveOptions):
        return options
    if isinstance(options, str) and options in PRESETS:
        return PRESETS[options]
    raise InvalidOption(
        "options", options, f"a qpik.SolveOptions, None or a preset name ({', '.join(PRESETS)})"
    )


def _check_seed(seed: Any) -> int:
    if isinstance(seed, bool):
        raise InvalidOption("seed", seed, "an int >= 0 or None")
    try:  # an array has __index__ but only a 0-d one of ints converts
        number = operator.index(seed)
    except TypeError:
        raise InvalidOption("seed", seed, "an int >= 0 or None") from None
    if number < 0:
        raise InvalidOption("seed", seed, "an int >= 0 or None")
    return number


def _check_limits(limits: Any) -> str | tuple | None:
    if limits is None or (isinstance(limits, str) and limits == "joint"):
        return limits
    if isinstance(limits, Sequence) and not isinstance(limits, str):
        for limit in limits:
            if not hasattr(limit, "compute_qp_inequalities"):
                raise InvalidOption("limits", limits, "'joint', None or a list of limits")
        return tuple(limits)
    raise InvalidOption("limits", limits, "'joint', None or a list of limits")


def _check_fields(cls: type, overrides: Mapping[str, Any]) -> None:
    names = {f.name for f in dataclasses.fields(cls)}
    extra = set(STEP_FIELDS) if cls is SolveOptions else set()
    for key in overrides:
        if key not in names:
            known = ", ".join(sorted(names | extra))
            raise InvalidOption(
                key, overrides[key], f"one of {known}", f"unknown option {key!r}; options: {known}"
            )


#: Named :class:`SolveOptions`:
#:
#: * ``"default"``: the defaults of :class:`SolveOptions` (0.1 mm, 1 mrad, 100 iterations,
#:   up to 100 restarts within the work of 21 full attempts).
#: * ``"precise"``: 1 um and 10 urad, 300 iterations per attempt, 50 restarts, and a
#:   trust region half the default.
#: * ``"fast"``: 1 mm and 10 mrad, 50 iterations per attempt, 5 restarts.
#: * ``"tracking"``: following a moving target from the last answer: no restarts (an
#:   answer never jumps to a random configuration), 20 iterations, the velocity-control
#:   damping law (:data:`qpik.core.cascade.DEFAULT_DAMPING`, no fading).
PRESETS: Final[Mapping[str, SolveOptions]] = MappingProxyType(
    {
        "default": SolveOptions(),
        "precise": SolveOptions(
            tol_position=1e-6,
            tol_orientation=1e-5,
            max_iters=300,
            restarts=50,
            max_step=(0.1, 0.25),
        ),
        "fast": SolveOptions(tol_position=1e-3, tol_orientation=1e-2, max_iters=50, restarts=5),
        "tracking": SolveOptions(restarts=0, max_iters=20, step=StepOptions()),
    }
)


# ---------------------------------------------------------------------- keywords
class LoopKeywords(TypedDict, total=False):
    """The option keywords of every full-IK loop, :func:`qpik.solve`'s and the baselines'
    (:func:`qpik.igm.baselines.igm`): the :class:`SolveOptions` fields of the same names, which
    document them."""

    tol_position: float
    tol_orientation: float
    max_iters: int
    time_budget: float | None
    restarts: int | None
    alpha: float
    beta: float
    stall_window: int


class StepFieldKeywords(TypedDict, total=False):
    """The keywords that set single fields of a :class:`StepOptions` (:data:`STEP_FIELDS`,
    documented there), in every entry point that takes them."""

    solver: str
    damping: float
    damping_law: DampingLaw | None
    rank_tolerance: float
    warm_start: bool
    backend_options: Mapping[str, Any] | None
    couplings: bool


class SolveKeywords(LoopKeywords, StepFieldKeywords, total=False):
    """The option keywords of :func:`qpik.solve`, :meth:`qpik.IKSession.solve`,
    :func:`qpik.solve_many`, :func:`qpik.reachability` and the batch files: one per field of
    :class:`SolveOptions` and per :data:`STEP_FIELDS` field of its :class:`StepOptions`
    (documented there), each overriding the ``options`` argument. ``seed`` is not among them:
    each entry point takes its own (a solve's also takes a numpy ``Generator``; a batch's
    seeds every target)."""

    max_step: tuple[float, float] | None
    secondary: bool
    limits: str | Sequence[Any] | None
    engine: str
    step: StepOptions
