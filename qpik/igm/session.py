r"""Full IK (the inverse geometric model): :func:`solve` and :class:`IKSession` iterate
differential-IK steps until the targets are met.

The damped least-squares IGM, for each frame with a target,

.. math::

    c = x_{des} - x(q_i), \qquad J(q_i)\, \dot q = \alpha\, c, \qquad
    q_{i+1} = q_i + \beta\, \dot q,

runs here with ``dt = 1``: ``alpha`` is the gain of the target tasks (the QP asks
``J dq = -alpha e``, ``e = x(q) - x_des``) and ``beta`` scales the displacement the QP
returns before it is applied. Each step is a QP: joint limits hold at every iterate
(``beta <= 1`` keeps them by convexity; a ``beta > 1`` iterate is clipped into the limits),
steps stay bounded near singularities (adaptive damping that fades with the error), no
iteration asks for more than a trust region (``max_step``), a step that increases the error
``sum |e_p|^2 + |e_o|^2`` is halved (up to three times: near singularities the damped step
can otherwise overshoot into a limit cycle), and lower levels (by default none; distance
from the joint limits with ``secondary=True``) act only in the null space of the targets.

Two engines run this rule (:attr:`IKResult.engine`):

* ``"compiled"``: one frame target, the default stack, joint limits (or none) and hinge
  and slide joints on the target's chain (joints off the chain may be of any type: a free
  object elsewhere in the scene, another arm; they stay where they are, restarts
  included, and the packed chain coordinates are written back into the full ``q``). The
  whole solve (iterations, trust region, damping, stall detection, restarts) is one
  compiled call (:mod:`qpik.igm.kernels`): forward kinematics and the frame Jacobian
  from arrays read once from the model (:mod:`qpik.igm.prepared`), and each step's damped
  least-squares QP under the box of the joint limits solved exactly by an active-set
  method. It is the same QP as the general engine's, so both agree to round-off.
* ``"qp"``: everything else (several frames, custom stacks, other limits, ball or free
  joints on the chain, ``secondary=True``, a coupling of the model that moves a joint of
  the chain or that the start breaks), on :class:`qpik.IKSolver` steps
  (:mod:`qpik.igm.qp_engine`).

Couplings (``couplings=True``, the default): the model's joint and fixed-tendon equality
constraints (``<equality><joint>``, URDF ``<mimic>``; :mod:`qpik.model.couplings`) are a
level above the stack in every ``"qp"`` step, and count in ``converged`` (their residual
against ``tol_position``); ``IKResult.coupling_error`` reports them at ``q``. The compiled
engine moves only the target's chain: it takes a model with couplings when none of them
moves a joint of the chain and they hold at the start (to 1e-9); otherwise the solve runs on
the ``"qp"`` engine (``engine="compiled"`` then raises :class:`qpik.InvalidInput`). The equalities
qpik does not hold (connect and weld loop closures: ``Couplings.skipped``) are measured at
the returned ``q`` (``IKResult.constraint_error``, MuJoCo's residuals): a ``q`` that breaks
one beyond the tolerances is not converged (reason ``constraint``), whatever the targets.

Stacks of several levels (a custom ``stack``): the iterates are ranked lexicographically,
the couplings first, then level 0, 1, ... (each level's largest error-to-tolerance ratio,
``<= 1`` counting as met), then the score; an attempt that ends without converging is
finished by steps of level 0 alone (at most :data:`qpik.igm.qp_engine.LEVEL0_STEPS`) and
returns its best iterate in that order, and attempts compare by it. So a solve with the
feet in level 0 and a hand out of reach in level 1 returns the feet within tolerance
(``converged=False``; ``IKResult.levels_met`` is ``(True, False, ...)``).

Errors: position error is the distance of the frame origin to its target [m]; orientation
error the angle of ``R R_des^T`` [rad]. A solve has **converged** when every frame with a
target is within ``tol_position`` and ``tol_orientation`` *and every task of level 0* is
within tolerance, targets or not (a custom stack's level 0 that holds the feet must still
hold them): position-like tasks (position, CoM) against ``tol_position``, orientation
tasks against ``tol_orientation``, frame/pose tasks both (the parts with a nonzero cost),
and any other task's error norm, in its own units, against ``tol_position``.

When an attempt stops making progress (:mod:`qpik.igm.restarts`; the compiled engine also
stops one at a step the limits or the damping block) the reason is diagnosed
(``at_limit``: a joint limit binds; ``singular``: the target level's smallest singular
value is below the damping threshold; ``stalled`` otherwise) and the solve restarts from a
random configuration within the limits, while restarts and time remain. The best iterate
over all attempts is returned. A target position provably out of reach (farther from the
base than the chain's reach bound, :meth:`qpik.model.KinematicChain.reach_bound`) is
answered at once with ``unreachable``.

Determinism: a solve keeps no state between calls. The same robot, targets, options and
``seed`` give bitwise the same ``q``, whatever was solved before, in this process or
another, through :func:`solve` or an :class:`IKSession`. The restarts draw from a
SplitMix64 stream seeded with ``seed``.

Options: every option keyword of :func:`solve` and :meth:`IKSession.solve`
(:class:`qpik.options.SolveKeywords`) is a field of :class:`qpik.SolveOptions` (or of its
:class:`qpik.StepOptions`), whose docstrings document it; ``options=`` takes a whole set
(or a preset name: ``"precise"``, ``"fast"``, ...), and the keywords override it.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
import numpy.typing as npt

from ..diffik.solver import Stack, normalize_stack
from ..errors import (
    InvalidConfiguration,
    InvalidInput,
    InvalidTarget,
    JointLimitViolation,
    ReadOnlyAttribute,
)
from ..model import ReachBound
from ..model.configuration import (
    Configuration,
    check_within_limits,
    qpos_joint_names,
    resolve_robot,
)
from ..model.couplings import unheld_equality_errors
from ..model.rotations import ORTHONORMAL_TOLERANCE
from ..options import PRESETS, UNSET, SolveKeywords, SolveOptions, Unset, resolve
from . import kernels
from .kernels import kernel_options as _kernel_options
from .prepared import PREPARED, REASONS_BY_CODE, PreparedFrame, PreparedRobot, model_watch
from .qp_engine import QPProblem, borrowed_tasks, iterate, lent_scratch
from .restarts import RAW_UINT64, Clock, Seed
from .restarts import rng_state as _rng_state
from .result import IKResult, LazyRows, Reason
from .targets import (
    MAX_TARGET_DISTANCE,
    FrameKey,
    RobotLike,
    Target,
    TargetLike,
    check_distinct_frames,
    parse_target,
    pose_errors,
    worst_errors,
)

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = ["IKSession", "Seed", "SolveArguments", "SolveCall", "solve"]

LIMIT_GAIN = kernels.LIMIT_GAIN
_Generator = np.random.Generator


class SolveArguments(SolveKeywords, total=False):
    """The keywords of :func:`solve` that every solve of a batch shares
    (:func:`qpik.solve_many`, :func:`qpik.reachability`, the batch files): the start ``q0``,
    the ``stack`` and the option keywords (:class:`qpik.options.SolveKeywords`)."""

    q0: npt.ArrayLike | None
    stack: Stack | None


class SolveCall(SolveArguments, total=False):
    """The keywords of :func:`solve` and :meth:`IKSession.solve`: those of
    :class:`SolveArguments` and the ``seed`` of the solve (documented by :func:`solve`)."""

    seed: Seed | Unset


class IKSession:
    """A robot prepared for repeated solves: hold one per robot and call :meth:`solve`.

    It loads the robot once and reads the model once (joint limits, and per target frame
    its kinematic chain and reach bound, on first use). These caches belong to the session,
    and each solve checks them against the model's arrays they were read from (one
    ``memcmp``): a model edited in place (its joint ranges narrowed, say) is read again, and
    the solve is a new session's, bit for bit. Results never depend on what it solved
    before. :func:`solve` uses the same preparation, kept per model in :data:`PREPARED`
    (checked the same way at each call).

    Args:
        robot: anything :func:`qpik.robots.resolve_robot` accepts (a name, ``"erd:NAME"``,
            a path, an ``MjModel``), or a :class:`qpik.Configuration` (its ``q`` is the
            default start).
        options: the session's default :class:`qpik.SolveOptions` (or a preset name);
            ``None``: ``PRESETS["default"]``.
    """

    def __init__(self, robot: RobotLike, options: SolveOptions | str | None = None):
        model, robot_q = resolve_robot(robot)
        self._watch = model_watch(model)  # (the arrays read; compared at each solve)
        self._setup(model, robot_q, resolve(options), PreparedRobot(model))

    def _setup(
        self,
        model: mujoco.MjModel,
        robot_q: np.ndarray | None,
        options: SolveOptions,
        prepared: PreparedRobot,
    ) -> None:
        self._model = model
        self._defaults = options
        self._robot_q = robot_q
        self._prepared = prepared
        self._support = prepared.support
        self._lower, self._upper, self._mid = prepared.lower, prepared.upper, prepared.mid
        self._bounds_joint, self._bounds_free = prepared.bounds_joint, prepared.bounds_free
        self._memo: list = prepared.memo  # [the last (options, values, settings, arrays)]
        # the "qp" engine's scratch configuration and joint limits (made on first use)
        self._lent: tuple[Configuration, list] | None = None

    def __getstate__(self) -> dict:  # (the watch is compiled: made again from the model;
        return {**self.__dict__, "_watch": None, "_lent": None}  # the scratch, on first use)

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state, _watch=model_watch(state["_model"]))

    @property
    def model(self) -> mujoco.MjModel:
        """The robot's model (read-only: the session's preparation is of it; assigning one
        raises :class:`qpik.ReadOnlyAttribute`: build a new session for another robot)."""
        return self._model

    @model.setter
    def model(self, value: Any) -> None:
        raise ReadOnlyAttribute("IKSession", "model", "build an IKSession for the other robot")

    @property
    def options(self) -> SolveOptions:
        """The session's default :class:`qpik.SolveOptions` (settable: options, a preset name
        or ``None``, checked as the constructor's; another value raises
        :class:`qpik.InvalidOption`)."""
        return self._defaults

    @options.setter
    def options(self, value: SolveOptions | str | None) -> None:
        self._defaults = resolve(value)

    @classmethod
    def _from_prepared(
        cls, model: mujoco.MjModel, robot_q: np.ndarray | None, prepared: PreparedRobot
    ) -> IKSession:
        """A session on ``model`` with the default options over an existing preparation."""
        session = cls.__new__(cls)
        session._watch = None  # (the one-shot cache watches the model: PreparedRobots.get)
        session._setup(model, robot_q, PRESETS["default"], prepared)
        return session

    # ------------------------------------------------------------------ frames
    def _frame(self, key: FrameKey) -> PreparedFrame:
        return self._prepared.frame(self.model, key)

    def reach_bound(self, frame: FrameKey) -> ReachBound | None:
        """The :class:`qpik.model.ReachBound` of ``frame`` within the joint limits, or
        ``None`` for a model with ball or free joints."""
        return self._frame(frame).reach

    def mid_q(self) -> np.ndarray:
        """The default start: the mid-range configuration (``qpos0`` for unlimited joints),
        as :meth:`qpik.Configuration.mid_q` (closed chains of connect or weld constraints
        at ``qpos0``)."""
        return self._mid.copy()

    # ------------------------------------------------------------------- solve
    def solve(
        self,
        targets: Mapping[FrameKey, TargetLike],
        *,
        options: SolveOptions | str | None = None,
        **keywords: Unpack[SolveCall],
    ) -> IKResult:
        """Solve inverse kinematics; the arguments are :func:`solve`'s (``options``
        defaults to the session's)."""
        start_time = time.perf_counter()
        watch = self._watch
        if watch is not None and not watch.unchanged():  # edited in place (refused: watch kept)
            self._watch, prepared = model_watch(self._model), PreparedRobot(self._model)
            self._setup(self._model, self._robot_q, self._defaults, prepared)
        return self._solve(targets, options, keywords, start_time)

    def _solve(
        self,
        targets: Mapping[FrameKey, TargetLike],
        options: SolveOptions | str | None,
        keywords: SolveCall,
        start_time: float,
    ) -> IKResult:
        """:meth:`solve` from the start of its clock (``keywords``: its own, changed): the
        compiled lane of the options memo where it answers (``PreparedRobot.make_lane``),
        else :meth:`_general`."""
        lane = self._prepared.lane
        if lane is not None and options is None:
            result = lane.solve(self._defaults, self._robot_q, targets, keywords, start_time)
            if result is not None:
                return result
        return self._general(targets, options, keywords, start_time)

    def _general(
        self,
        targets: Mapping[FrameKey, TargetLike],
        options: SolveOptions | str | None,
        keywords: SolveCall,
        start_time: float,
    ) -> IKResult:
        """:meth:`_solve` where the compiled lane does not answer."""
        q0 = keywords.pop("q0", None)
        stack = keywords.pop("stack", None)
        seed = keywords.pop("seed", UNSET)
        settings, kernel_options, lean = self._options(options, keywords)
        if type(seed) is _Generator and type(seed.bit_generator) in RAW_UINT64:
            rng_state = seed.bit_generator.random_raw()  # (rng_state's draw)
        else:
            rng_state = _rng_state(settings.seed if isinstance(seed, Unset) else seed)
        # (Few calls and checks on this path: a solve between a planner's other work runs with
        # cold caches, where each costs several times what it costs in a loop of solves.)
        if lean and stack is None:
            result = self._lean(targets, q0, settings, kernel_options, rng_state, start_time)
            if result is not None:
                return result
        frames = self._targets(targets)
        compiled_ok = self._compiled_applies(settings, stack, frames)
        joint = settings.limits == "joint"
        limited = joint or bool(settings.limits)
        q_start = self._start(q0, check=limited)
        start_coupling = None  # the couplings' error at q_start, where it was measured
        if compiled_ok and settings.step.couplings and self._prepared.couplings is not None:
            start_coupling = self._start_coupling_error(q_start)
        if compiled_ok and start_coupling is not None and not start_coupling <= 1e-9:
            # A coupling of joints the compiled engine keeps still is broken at the start:
            # the "qp" engine restores it (its coupling level).
            if settings.engine == "compiled":
                raise InvalidInput(
                    "engine='compiled' keeps the joints off the target's chain where they "
                    "are, and q0 breaks a coupling among them (the model's equality "
                    f"constraints, by {start_coupling:.3g}); use "
                    "engine='auto' or couplings=False"
                )
            compiled_ok = False
        if compiled_ok and settings.engine != "qp":
            result = self._solve_compiled(
                frames[0],
                q_start,
                joint,
                settings,
                (kernel_options, rng_state),
                start_time,
                start_coupling,
            )
            if self._prepared.unheld.size == 0:  # nothing to check (_check_unheld)
                return result
            return self._check_unheld(result, settings)
        # A target provably out of reach ends the solve at once, unless the stack has
        # several levels (the others are still solved: level 0 may hold other frames).
        single = stack is None or len(normalize_stack(stack)) == 1
        for _frame, target in frames if single else ():
            # (the joint limits' bound only where they hold: else the one without them)
            reach = _frame.reach if settings.limits == "joint" else _frame.reach_free
            if reach is not None and reach.excludes(target.position, settings.tol_position):
                result = self._answer_unreachable(frames, q_start, start_time)
                result.levels_met = self._levels_met(frames, stack, settings, q_start)
                return self._check_unheld(result, settings)
        plain = [(f.name, f.kind, target) for f, target in frames]
        with lent_scratch(self.__dict__, self.model) as (scratch, limits):
            problem = QPProblem(self.model, plain, stack, settings, scratch, limits)
            result = iterate(
                problem, q_start, Clock(start_time, settings.time_budget), rng_state, settings
            )
        return self._check_unheld(result, settings)

    def _check_unheld(self, result: IKResult, settings: SolveOptions) -> IKResult:
        """``result`` with :attr:`IKResult.constraint_error` filled in, and not converged
        (reason ``constraint``) where ``q`` breaks an active equality constraint of the
        model that no level holds (connect, weld: :func:`unheld_equalities`) by more than
        ``tol_position`` [m] or, a weld's rotation, ``tol_orientation`` [rad]."""
        unheld = self._prepared.unheld
        if unheld.size == 0:
            return result
        position, rotation = unheld_equality_errors(self.model, result.q, unheld)
        result.constraint_error = max(position, rotation)
        broken = position > settings.tol_position or rotation > settings.tol_orientation
        if result.converged and broken:
            result.converged = False
            result.reason = Reason.CONSTRAINT
        return result

    # ---------------------------------------------------------------- helpers
    def _options(
        self, options: SolveOptions | str | None, keywords: Mapping[str, Any]
    ) -> tuple[SolveOptions, tuple[np.ndarray, np.ndarray], bool]:
        """The options of a solve (``keywords``: the option keywords given), validated once
        for a run of solves with the same ones, with the compiled engine's option arrays and
        whether the lean lane (:meth:`_lean`) may take the solve."""
        base = self._defaults if options is None else resolve(options)
        memo = self._memo[0]
        try:
            # The last options' keywords: the same values, and of the same types (True == 1
            # and 50.0 == 50, where only the int is valid), compared in compiled code.
            if (
                memo is not None
                and memo[0] is base
                and keywords == memo[1]
                and tuple(map(type, map(keywords.__getitem__, memo[4]))) == memo[5]
            ):
                return memo[2], memo[3], memo[6]
        except (TypeError, ValueError):  # values that do not compare plainly (arrays)
            pass
        settings = base.replace(**keywords)
        kernel_options = _kernel_options(settings)
        try:
            hash(tuple(keywords.items()))
        except TypeError:  # a list of limits, say: not remembered
            return settings, kernel_options, False
        prepared = self._prepared
        lean = (  # the options and robot of the lean lane (_lean)
            settings.limits == "joint"
            and not settings.secondary
            and settings.engine != "qp"
            and self._support is None
            and prepared.couplings is None
            and prepared.unheld.size == 0
        )
        keys, types = tuple(keywords), tuple(map(type, keywords.values()))
        self._memo[0] = (base, dict(keywords), settings, kernel_options, keys, types, lean)
        self._prepared.lane = None  # (made for this memo by the next lean solve: make_lane)
        return settings, kernel_options, lean

    def _targets(
        self, targets: Mapping[FrameKey, TargetLike]
    ) -> list[tuple[PreparedFrame, Target]]:
        if type(targets) is not dict and not isinstance(targets, Mapping):
            raise InvalidInput(
                f"targets must be a mapping {{frame: target}}, got {type(targets).__name__}"
            )
        if not targets:
            raise InvalidTarget("no targets given: pass {frame: target, ...}")
        prepared = self._prepared.frames
        frames = []
        for key, value in targets.items():
            try:
                frame = prepared[key]  # the frame's preparation, once read (self._frame)
            except (KeyError, TypeError):
                frame = self._frame(key)
            frames.append((frame, parse_target(value, key)))
        if len(frames) > 1:  # (one frame named twice: 'ee' and ('ee', 'site'))
            check_distinct_frames([f for f, _ in frames], list(targets))
        return frames

    def _compiled_applies(
        self,
        settings: SolveOptions,
        stack: Stack | None,
        frames: list[tuple[PreparedFrame, Target]],
    ) -> bool:
        """Whether the compiled engine takes this solve; raises when ``engine='compiled'``
        was asked for and it does not."""
        applies = (
            stack is None
            and (settings.limits is None or settings.limits == "joint")
            and len(frames) == 1
            and frames[0][0].reach is not None
            and not settings.secondary
            and not (settings.step.couplings and frames[0][0].coupled)
        )
        if settings.engine == "compiled" and not applies:
            coupled = settings.step.couplings and frames[0][0].coupled
            raise InvalidInput(
                "engine='compiled' needs one frame target, the default stack, limits 'joint' "
                "or None, secondary=False, hinge and slide joints on the target's chain and "
                "no coupling of the model on it (couplings=False turns them off)"
                + (" (a coupling moves a joint of the chain)" if coupled else "")
                + (f" ({self._support})" if self._support and frames[0][0].reach is None else "")
            )
        return applies

    def _start_coupling_error(self, q_start: np.ndarray) -> float:
        """The couplings' error at ``q_start`` (the model has couplings), remembered for the
        last start measured (a run of solves from the same start measures it once)."""
        key = q_start.tobytes()
        memo = self._prepared.coupling_memo
        if memo is not None and memo[0] == key:
            return memo[1]
        assert self._prepared.couplings is not None
        error = self._prepared.couplings.error(q_start)
        self._prepared.coupling_memo = (key, error)
        return error

    def _start(self, q0: npt.ArrayLike | None, check: bool) -> np.ndarray:
        """The validated start: ``q0``, else the robot's ``q``, else mid-range."""
        where = "q0"
        if q0 is None:
            if self._robot_q is None:
                return self._mid.copy()  # within the limits
            q0, where = self._robot_q, "robot (its configuration's q, the default start)"
        try:
            q = np.array(q0, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InvalidConfiguration(f"q0 must be {self.model.nq} numbers: {exc}") from exc
        if q.shape != (self._mid.shape[0],):
            raise InvalidConfiguration(
                f"q0 has shape {q.shape}, expected ({self.model.nq},) for this model"
            )
        if check and self._support is None:
            # One compiled pass: finite, within the limits (1e-6), then clipped in place.
            code, i = self._prepared.start_box.check(q)  # start_defect(q, lower, upper, 1e-6)
            if code == 1:
                raise InvalidConfiguration(f"q0[{i}] is {q[i]}; every entry must be finite", i)
            if code == 2:
                raise JointLimitViolation(
                    qpos_joint_names(self.model)[i],
                    i,
                    float(q[i]),
                    float(self._lower[i]),
                    float(self._upper[i]),
                    where=where,
                )
            return q
        q = self._prepared.checked_start(q)  # finite; quaternions nonzero, normalised if need be
        if check:
            try:
                check_within_limits(self.model, q, self._lower, self._upper)
            except JointLimitViolation as exc:  # named after the argument q came in
                raise JointLimitViolation(
                    exc.joint, exc.index, exc.value, exc.lower, exc.upper, where=where
                ) from None
        return q

    def _levels_met(
        self, frames: list[tuple[PreparedFrame, Target]], stack, settings, q: np.ndarray
    ) -> tuple[bool, ...]:
        """Per level of the stack the "qp" engine would solve (the default one with its
        ``secondary`` level, or ``stack``), whether ``q`` meets it: one entry per level, as
        an answer the engine iterated gives."""
        plain = [(f.name, f.kind, target) for f, target in frames]
        with lent_scratch(self.__dict__, self.model) as (scratch, limits):
            problem = QPProblem(self.model, plain, stack, settings, scratch, limits)
            with borrowed_tasks(problem.levels):
                problem.set_targets()
                problem.configuration.update(q)
                _coupling, measures = problem.level_measures(problem.configuration, settings)
        return tuple(bool(m <= 1.0) for m in measures)

    def _answer_unreachable(
        self, frames: list[tuple[PreparedFrame, Target]], q: np.ndarray, start_time: float
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
            levels_met=(False,),
            coupling_error=self._coupling_error(q),
        )

    def _lean(
        self,
        targets: Mapping[FrameKey, TargetLike],
        q0: npt.ArrayLike | None,
        settings: SolveOptions,
        kernel_options: tuple,
        rng_state: int,
        start_time: float,
    ) -> IKResult | None:
        """:meth:`_solve`'s lean lane: one (position, rotation) target of a frame the compiled
        engine solved with these options, a robot with no coupling, no unheld equality,
        hinge/slide chains, limits "joint": checks and engine in one compiled call, bit for
        bit the general path, which answers (or raises) wherever this returns None."""
        if type(targets) is not dict or len(targets) != 1:
            return None
        ((key, value),) = targets.items()
        try:
            frame = self._prepared.frames.get(key)
        except TypeError:  # an unhashable key
            return None
        if frame is None or type(value) is not tuple or len(value) != 2:
            return None
        plan = frame.plan
        if plan is None or plan[0] is not kernel_options or plan[1] is not True:
            return None
        if q0 is None:
            q0 = self._mid if self._robot_q is None else self._robot_q
        budget = settings.time_budget
        deadline = start_time + budget if plan[2] and budget is not None else np.inf
        run = kernels.igm_lean_run(
            plan[3], value[0], value[1], q0, self._prepared.start_box, rng_state, deadline,
            ORTHONORMAL_TOLERANCE, MAX_TARGET_DISTANCE,
        )  # fmt: skip
        if run is None:
            return None
        if self._prepared.lane is None:  # (the lane of these options: the next solves')
            self._prepared.lane = self._prepared.make_lane(self._memo[0])
        return self._compiled_result(run, frame.name, start_time, 0.0)  # (no coupling)

    def _solve_compiled(
        self, frame_target, q_start, joint, settings, kernel_inputs, start_time, start_coupling
    ) -> IKResult:
        """The compiled engine's solve. ``start_coupling``: the couplings' error at
        ``q_start`` when they were measured there (they then involve no joint of the
        chain, which alone moves, so it is their error at the answer too), else None."""
        frame, target = frame_target
        kernel_options, rng_state = kernel_inputs
        plan = frame.plan
        if plan is None or plan[0] is not kernel_options or plan[1] is not joint:
            plan = self._prepared.plan(frame, joint, kernel_options)
        deadline = start_time + settings.time_budget if plan[2] else np.inf
        run = kernels.igm_plan_run(
            plan[3], target.position, target.rotation, q_start, rng_state, deadline
        )
        return self._compiled_result(run, frame.name, start_time, start_coupling)

    def _compiled_result(
        self, run: tuple, name: str, start_time: float, coupling: float | None
    ) -> IKResult:
        """The :class:`IKResult` of a compiled run (:func:`qpik.igm.kernels.igm_plan_run`'s
        tuple) for frame ``name``; ``coupling``: the couplings' error at the answer where it
        is known, else None (measured here)."""
        code, iterations, restarts_used, q, path, history, position_error, orientation_error = run
        converged = code == 0
        return IKResult(
            q, converged, REASONS_BY_CODE[code], iterations, restarts_used, position_error,
            orientation_error, time.perf_counter() - start_time,
            {name: (position_error, orientation_error)}, LazyRows(history, list, 1, 2),
            LazyRows(history, tuple, 0, 0, 2), path, "compiled", (converged,),
            coupling if coupling is not None else self._coupling_error(q),
        )  # fmt: skip

    def _coupling_error(self, q: np.ndarray) -> float:
        couplings = self._prepared.couplings
        return 0.0 if couplings is None else couplings.error(q)


def solve(
    robot: RobotLike,
    targets: Mapping[FrameKey, TargetLike],
    *,
    options: SolveOptions | str | None = None,
    **keywords: Unpack[SolveCall],
) -> IKResult:
    """Solve inverse kinematics for one or several frame targets.

    Args:
        robot: anything :func:`qpik.load_robot` accepts, or a :class:`qpik.Configuration`
            (left unchanged; its ``q`` is the default start).
        targets: ``{frame: target}``; a frame is a site, body or geom name (sites first) or
            ``(name, frame_type)``; a target is a position (3,) [m], ``(position,
            rotation)``, a 4x4 matrix or a ``mink.SE3``, all in the world frame.
        options: a :class:`qpik.SolveOptions`, a preset name of :data:`qpik.PRESETS`
            (``"default"``, ``"precise"``, ``"fast"``, ``"tracking"``) or ``None`` (the
            default preset). The keywords override it.

    Keyword Args:
        q0: start configuration (default: the configuration's ``q``, or the mid-range).
            Must lie within the joint limits.
        stack: a task stack to use instead of the default (position/orientation tasks in
            level 0; see ``secondary``); targets are set on its tasks whose ``frame_name``
            matches, for the solve only (the tasks are given back unchanged). Every task of
            its level 0 must be within tolerance for ``converged`` (see the module
            docstring).
        seed: seed of the restarts' random configurations: an int >= 0, a numpy
            ``Generator`` (one draw is taken from it) or ``SeedSequence``; same seed, same
            result. ``None``: fresh entropy. Default: ``options.seed`` (``None``).
        **keywords: options overriding ``options``, each a field of
            :class:`qpik.SolveOptions` (``tol_position``, ``max_iters``, ``restarts``,
            ``time_budget``, ``engine``, ...) or of its :class:`qpik.StepOptions`
            (``solver``, ``damping``, ``damping_law``, ``couplings``, ...), documented
            there; :class:`qpik.options.SolveKeywords` lists them.

    Bad arguments raise a :class:`qpik.QpikError` subclass naming them
    (:class:`qpik.InvalidOption` for an option, an unknown keyword included).

    Cost of a one-shot call: given an ``MjModel`` (or a :class:`qpik.Configuration`), the
    robot's preparation (joint limits, mid-range start, the frame's chain, reach bound) is
    kept per model in one cache, :data:`qpik.igm.prepared.PREPARED`, so a call on the
    compiled engine costs what a held :class:`IKSession`'s ``solve`` does (the "qp"
    engine's solver, and a configuration's moved mocap bodies, are made anew at each call).
    The cache holds the model weakly, checks at each call that the arrays it was prepared
    from (:data:`qpik.igm.prepared.FINGERPRINT_FIELDS`) are unchanged (a model edited in
    place is prepared anew), and gives bitwise a fresh :class:`IKSession`'s answers;
    :func:`qpik.clear_caches` empties it. A robot given by name or path is loaded and
    prepared at each call: to solve many targets on one robot, hold an :class:`IKSession`.
    """
    if isinstance(robot, mujoco.MjModel):
        session = IKSession._from_prepared(robot, None, PREPARED.get(robot))
    elif isinstance(robot, Configuration):  # (its mocap poses kept: resolve_robot)
        model, q = resolve_robot(robot)
        session = IKSession._from_prepared(model, q, PREPARED.get(model))
    else:
        session = IKSession(robot)
    # The clock (solve_time, time_budget) starts once the robot is loaded, as a session's.
    return session._solve(targets, options, keywords, time.perf_counter())
