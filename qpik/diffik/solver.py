r"""The IK layer's entry point: :class:`IKSolver` turns a task stack and limits at a
configuration into a hierarchy of QPs over the displacement ``dq = v dt`` (``nv``) and
solves it with :mod:`qpik.core`.

Level ``k`` has the weighted residual ``A_k dq - b_k`` of its tasks (:mod:`.rows`) and the
core solves

.. math::

    \min_{dq} \tfrac12 \|A_k dq - b_k\|^2 + \tfrac12 (\delta + \mu_k + \lambda_k^2) \|dq\|^2
    \quad \text{s.t.} \quad dq \in d_{k-1} + \mathcal{N}_{k-1}, \;
    lb \le dq \le ub, \; G dq \le h

where :math:`d_{k-1}` is the solution of the levels above and :math:`\mathcal{N}_{k-1}` the
null space of their rows: a lower level never changes a higher level's ``A_j dq``.
``delta`` (``damping``) is a constant Tikhonov term on every level, as in mink; ``mu_k`` the
tasks' own Levenberg-Marquardt terms; ``lambda_k`` the adaptive singularity damping of
:class:`~qpik.core.DampingLaw` (see :mod:`qpik.core.cascade`). The limits give the box and
general rows (:mod:`.boxes`), which hold at every level.

A step goes down once and comes back with its :class:`~qpik.diffik.result.Solution`: by the
compiled step (:mod:`.compiled`) where the stack allows it, else by the QP path (the tasks'
and limits' own rows, then the core's cascade). :meth:`IKSolver.build` returns the
hierarchy (:class:`qpik.core.HierarchyProblem`) for inspection.
"""

from __future__ import annotations

import contextvars
import copy
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import mink
import mujoco
import numpy as np

from ..core import DampingLaw, HierarchyProblem, HierarchySolver, Level, LevelStatus, checks
from ..errors import (
    InfeasibleLimits,
    InvalidArgumentType,
    InvalidInput,
    QpikError,
    ReadOnlyAttribute,
)
from ..model.configuration import Configuration
from ..model.robots import check_kinematic_model
from ..options import MAX_DAMPING, UNSET, StepFieldKeywords, StepOptions, check_number
from .boxes import LimitBoxes, LimitRows, relaxable
from .compiled import OK as _OK
from .compiled import OUTPUT_ROWS as _OUTPUT_ROWS
from .correction import qp_corrected
from .plan import make_plan
from .recovery import RELAXATION_MARGINS, contact_rows, least_slack, relaxed_rows
from .result import Solution, StepResult, solve_rows
from .rows import Stack, TaskRows, normalize_stack, stack_rows
from .writers import guards_hold

if TYPE_CHECKING:
    from typing_extensions import Unpack

    from ..tasks import BaseTask

_perf_counter = time.perf_counter
_new = object.__new__
_MinkConfiguration = mink.Configuration
_DT_MIN, _DT_MAX = checks.DT_MIN, checks.DT_MAX

__all__ = [
    "DampingLaw",
    "IKSolver",
    "LevelStatus",
    "Stack",
    "StepKeywords",
    "StepResult",
    "normalize_stack",
]


class StepKeywords(StepFieldKeywords, total=False):
    """The keywords of :class:`IKSolver` that override single fields of its
    :class:`qpik.StepOptions` (the fields of the same names, :data:`qpik.options.STEP_FIELDS`,
    ``max_joint_speed`` and ``correction_passes``), and ``osqp_settings``."""

    max_joint_speed: float | None
    correction_passes: int
    osqp_settings: Any


def _step_options(options: StepOptions | None, keywords: dict[str, Any]) -> StepOptions:
    """``options`` (default :class:`StepOptions`) with the keywords that were given."""
    if options is not None and not isinstance(options, StepOptions):
        raise InvalidInput(f"options must be a qpik.StepOptions, got {options!r}")
    osqp_settings = keywords.pop("osqp_settings", None)
    overrides = {name: value for name, value in keywords.items() if value is not UNSET}
    if osqp_settings is not None and "backend_options" not in overrides:
        if not callable(getattr(osqp_settings, "as_dict", None)):
            raise InvalidArgumentType(
                "osqp_settings",
                "None or OSQP settings (an object with as_dict())",
                checks.type_name(osqp_settings),
            )
        overrides["backend_options"] = osqp_settings.as_dict()
    options = options if options is not None else StepOptions()
    return options.replace(**overrides) if overrides else options


#: The attributes of an :class:`IKSolver` fixed at construction, with what to do instead of
#: assigning one (:class:`qpik.ReadOnlyAttribute`).
_FIXED = {
    "model": "build an IKSolver for the other model",
    "options": "build a new IKSolver with options=...",
    "levels": "build a new IKSolver with the new stack (tasks are kept by reference: "
    "task.set_target(...) moves a target)",
    "limits": "build a new IKSolver with the new limits (a limit's gain, bounds and speeds "
    "may be changed in place)",
    "solver": "build a new IKSolver with solver=...",
    "rank_tolerance": "build a new IKSolver with rank_tolerance=...",
}


#: True while a caller that has checked its model itself builds solvers (the "qp" engine,
#: whose :class:`qpik.igm.prepared.PreparedRobot` checked the model and watches it for
#: edits): :class:`IKSolver` then skips :func:`qpik.model.robots.check_kinematic_model`
#: (40-100 us, per solve on that engine).
MODEL_CHECKED: contextvars.ContextVar[bool] = contextvars.ContextVar(
    "qpik_model_checked", default=False
)


class IKSolver:
    """Differential IK with strict priorities.

    Args:
        model: the MuJoCo model (its ``nv`` fixes the QP size).
        stack: the task stack (see :func:`normalize_stack`); tasks are kept by reference,
            so ``task.set_target(...)`` between steps is how targets move.
        limits: mink or qpik limits, enforced at every level.
        options: how each step is solved (:class:`qpik.StepOptions`: backend, constant
            and adaptive damping, rank tolerance, warm starts; its docstring holds the
            defaults). The keywords below override single fields of it.
        keywords: ``solver``, ``damping``, ``damping_law``, ``rank_tolerance``,
            ``warm_start``, ``backend_options``, ``max_joint_speed``, ``couplings``,
            ``correction_passes`` (second-order corrections of each step): the
            :class:`qpik.StepOptions` fields of the same names (an unknown name raises
            :class:`qpik.InvalidOption`). ``couplings`` (default ``True``): the model's
            joint and fixed-tendon equalities (URDF ``<mimic>`` among them) hold as a level
            above the stack. ``osqp_settings``: OSQP's settings as an object with
            ``as_dict()``, used as ``backend_options`` when those are not given.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        stack: Stack,
        limits: Sequence[mink.Limit] = (),
        *,
        options: StepOptions | None = None,
        **keywords: Unpack[StepKeywords],
    ):
        if not isinstance(model, mujoco.MjModel):
            raise InvalidInput(f"model must be a mujoco.MjModel, got {type(model).__name__}")
        if not MODEL_CHECKED.get():  # (NaN geometry, an empty range: named here)
            check_kinematic_model(model, "model")
        options = _step_options(options, dict(keywords))
        self._options = options
        backend_options = options.backend_options
        self._model = model
        stack_levels = normalize_stack(stack)
        self._stack = tuple(tuple(level) for level in stack_levels)
        #: The levels the steps solve: the model's couplings first (StepOptions.couplings,
        #: on a model that states some), then ``levels``.
        self._levels = stack_levels
        self._coupling_level = False
        if options.couplings and model.neq:
            from ..model.couplings import model_couplings

            if model_couplings(model) is not None:
                from ..tasks.coupling import CouplingTask

                self._levels = [[CouplingTask(model)], *stack_levels]
                self._coupling_level = True
        self._limits = LimitBoxes(model, limits, options.max_joint_speed)
        self._damping = float(options.damping)
        self.damping_law = options.damping_law
        self._core = HierarchySolver(
            options.solver,
            damping_law=self.damping_law,
            rank_tolerance=options.rank_tolerance,
            warm_start=options.warm_start,
            backend_options=None if backend_options is None else dict(backend_options),
        )
        self._exact: HierarchySolver | None = None
        self._aux: Configuration | None = None  # kinematics at q (+) dq (correction passes)
        self._passes = options.correction_passes
        self._nv = model.nv
        #: With a forced backend, answer by the exact compiled solve when it solves every
        #: level: the forced-backend path returns that same answer (the exact cascade,
        #: started from the backend's active sets, answers), at a backend call per level
        #: where a limit binds. Off by default (``StepResult.iterations`` then count the
        #: exact solver's iterations, not the backend's); :func:`qpik.solve_ik` turns it on.
        self.exact_shortcut = False
        # One compiled call per step when every task and limit allows it.
        self._plan = make_plan(model, self._levels, self._limits, self._core)

    # Copies (copy.copy, copy.deepcopy) and pickles: the compiled plan is the solver's
    # machinery, bound to the tasks and limits it was built from (and its kernel does not
    # pickle). A copy makes its plan again from its own tasks and limits, as a new solver
    # does, so that its steps take the compiled path on them (a deep copy that shared the
    # original's plan answered every step on the QP path, 20 times slower). The core drops
    # its warm start and backend workspaces (HierarchySolver.__getstate__): a copy starts
    # cold, which changes no answer.
    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_plan"] = self._plan is not None  # (made again by __setstate__)
        return state

    def __setstate__(self, state: dict) -> None:
        planned = state.pop("_plan")
        self.__dict__.update(state)
        plan = None
        if planned:
            try:
                plan = make_plan(self._model, self._levels, self._limits, self._core)
            except (QpikError, ValueError, TypeError, IndexError):
                plan = None  # (a task changed so that no plan applies: the QP path names it)
        self.__dict__["_plan"] = plan

    def __deepcopy__(self, memo: dict) -> IKSolver:
        """A copy with its own tasks, limits and core, on the same model: the model is the
        robot's description, shared as the configurations built on it are (the compiled step
        takes a configuration of the solver's own model; a copied model would send every
        step of the copy to the QP path)."""
        memo.setdefault(id(self._model), self._model)
        new = IKSolver.__new__(IKSolver)
        memo[id(self)] = new
        new.__setstate__(copy.deepcopy(self.__getstate__(), memo))
        return new

    # The attributes fixed at construction: read-only (an assignment would leave the built
    # plan, core and boxes answering for the old value: ReadOnlyAttribute says so).
    def __setattr__(self, name: str, value: Any) -> None:
        hint = _FIXED.get(name)
        if hint is not None:
            raise ReadOnlyAttribute("IKSolver", name, hint)
        object.__setattr__(self, name, value)

    @property
    def model(self) -> mujoco.MjModel:
        """The MuJoCo model the solver was built for (read-only)."""
        return self._model

    @property
    def options(self) -> StepOptions:
        """The :class:`qpik.StepOptions` the solver was built with, the keywords applied
        (read-only; :attr:`damping` and :attr:`damping_law` are the settable ones)."""
        return self._options

    @property
    def levels(self) -> tuple[tuple[BaseTask, ...], ...]:
        """The task stack, level by level, highest priority first, as given (read-only
        tuples: the tasks themselves are kept by reference, so ``task.set_target(...)``
        between steps moves them; the model's couplings, solved above them, not included)."""
        return self._stack

    @property
    def limits(self) -> tuple[Any, ...]:
        """The limits enforced at every level, as given (read-only; each limit kept by
        reference: its gain, bounds or speeds may change between steps)."""
        return tuple(self._limits.limits)

    @property
    def solver(self) -> str:
        """The QP backend (:attr:`qpik.StepOptions.solver`; read-only)."""
        return self._core.solver

    @property
    def rank_tolerance(self) -> float:
        """The relative rank tolerance of each level (:attr:`qpik.StepOptions.rank_tolerance`;
        read-only)."""
        return self._core.rank_tolerance

    @property
    def damping(self) -> float:
        """The constant Tikhonov damping ``mu`` added to every level (settable: a number in
        ``[0, 1e12]``, as :attr:`qpik.StepOptions.damping`; else :class:`qpik.InvalidOption`)."""
        return self._damping

    @damping.setter
    def damping(self, value: float) -> None:
        self._damping = float(check_number("damping", value, allow_zero=True, maximum=MAX_DAMPING))

    @property
    def damping_law(self) -> DampingLaw | None:
        """The adaptive damping law (settable)."""
        return self._damping_law

    @damping_law.setter
    def damping_law(self, law: DampingLaw | None) -> None:
        if law is not None and not isinstance(law, DampingLaw):
            raise InvalidInput(f"damping_law must be a DampingLaw or None, got {law!r}")
        self._damping_law = law
        if hasattr(self, "_core"):
            self._core.damping_law = law

    @property
    def workspace_setups(self) -> int:
        """How many backend workspaces were built so far (OSQP: at most one per level and
        reduced size; 0 with the default exact solver)."""
        return self._core.workspace_setups

    def reset(self) -> None:
        """Forget warm starts and backend workspaces (they only ever change speed)."""
        self._core.reset()

    # ------------------------------------------------------------------- build
    def build(self, configuration: Configuration, dt: float) -> HierarchyProblem:
        """The hierarchy of QPs at ``configuration`` for a step of ``dt`` [s]: per level
        ``A, b`` (weighted rows, in the displacement ``dq``), ``regularization``
        (``damping`` plus the tasks' LM terms) and row ``weights`` (costs), and the limits
        as box bounds ``lb <= dq <= ub`` and general rows ``G dq <= h``. The adaptive
        damping is decided by the core when it solves. With the model's couplings
        (:attr:`qpik.StepOptions.couplings`) their level comes first, named
        ``"couplings"``; the stack's levels follow, named ``"level 0"``, ....

        The limits are the ones :meth:`step` solves with: where a relaxable limit's row
        admits no displacement at all (a collision pair deeper inside its minimum distance
        than one step can leave, or one no joint moves), that limit's rows stay general
        rows, and the core reports level 0 ``infeasible`` on this problem as the step does
        before it relaxes them (:mod:`qpik.diffik.recovery`); :class:`qpik.InfeasibleLimits`
        only where the box is empty without them."""
        tasks, limits = self._recoverable_rows(configuration, dt)
        shift = int(self._coupling_level)
        starts = tasks.starts.tolist()
        levels = [
            Level(
                tasks.A[s0:s1],
                tasks.b[s0:s1],
                float(tasks.reg[k]),
                tasks.w[s0:s1],
                "couplings" if k < shift else f"level {k - shift}",
            )
            for k, (s0, s1) in enumerate(zip(starts[:-1], starts[1:]))
        ]
        return HierarchyProblem(levels, limits.lb, limits.ub, limits.G, limits.h, limits.row_names)

    def _rows(
        self, configuration: Configuration, dt: float, fold: bool = True
    ) -> tuple[TaskRows, LimitRows]:
        """Every level's rows stacked as the core takes them, and the limits
        (``fold``: :meth:`LimitBoxes.rows`')."""
        dt = checks.check_dt(dt)
        if configuration.model is not self._model and configuration.model.nv != self._nv:
            raise InvalidInput(
                f"configuration has nv={configuration.model.nv}, the solver's model {self._nv}"
            )
        limits = self._limits.rows(configuration, dt, fold)
        return stack_rows(self._levels, configuration, self._nv, self._damping), limits

    # ------------------------------------------------------------------- step
    def step(self, configuration: Configuration, dt: float) -> StepResult:
        """Solve the stack at ``configuration`` for a step of ``dt`` [s]. With the
        model's couplings (:attr:`qpik.StepOptions.couplings`) their level is solved
        first; the result's per-level lists are the stack's levels, and
        ``coupling_residual`` the coupling level's. With
        :attr:`qpik.StepOptions.correction_passes`, the held levels' second-order remainder
        at ``configuration.integrate(velocity, dt)`` is shifted out of their targets and the
        step solved again, that many times (the compiled step does it in
        its kernel)."""
        start = _perf_counter()
        if type(dt) is not float:  # (np.float64, an int: the same step as its float's)
            dt = checks.as_float_dt(dt)
        plan, core = self._plan, self._core
        # The plain lane: the default solver's step by a plain plan (no CoM
        # or row-supplying task, no general rows), without correction passes, when each
        # check of CompiledPlan._lean holds (the configuration's MjData attached with its
        # chains, the core's settings copied and lane-fit: CompiledPlan.sync, a free output
        # row):
        # the kernel called from this frame and StepResult.lean's result made here. It is
        # inlined because a Python call costs about 1.7k instructions of a 72k-instruction
        # step. Its conditions are one `or` chain whose jumps stay short (CPython 3.11
        # specializes a comparison only when the jump after it needs no EXTENDED_ARG).
        if (
            plan is None
            or self._passes
            or type(dt) is not float
            or core.settings_version != plan._version  # (the default solver, cold: sync)
            or not isinstance(configuration, _MinkConfiguration)
            or configuration.model is not self._model
            or not _DT_MIN <= dt <= _DT_MAX
            or configuration.data is not plan._plain_data  # (never, for a plan not plain)
            or (row := plan._row) == _OUTPUT_ROWS
        ):
            code = -1  # not taken: CompiledPlan.step_result decides, as for any plan
        else:
            code = plan.kernel.go_cold(dt, self._damping, row, plan._cap)
            if code == _OK:  # its answers are in row `row` of the outputs
                plan._row = row + 1
                # core.warm_start_from_row(plan._out[3], row): its one attribute store
                core._warm_row = plan._active_rows[row]
                # StepResult.lean(velocity, solve_time, source), as its attributes
                lean = _new(StepResult)
                lean.velocity = plan._velocity_rows[row]
                lean.solve_time = _perf_counter() - start
                source = (plan._out, row, self._coupling_level, plan, dt)
                lean._src = source  # type: ignore[attr-defined]  # (not a field)
                return lean
            if code != -1:  # not solved: the QP path reports or recovers it
                plan._row = row + 1
            # (code -1: a value the kernel does not take as it is: _lean's way)
        if (  # the default solver: one kernel call, straight to the result
            code == -1
            and plan is not None
            and type(dt) is float
            and core.solver == "auto"
            and isinstance(configuration, _MinkConfiguration)
            and configuration.model is self._model
            and _DT_MIN <= dt <= _DT_MAX
        ):
            result = plan.step_result(
                configuration, dt, self._damping, core, start, self._coupling_level, self._passes
            )
            if result is None and self._replanned():  # (the plan of the tasks as they are)
                result = self._plan.step_result(  # type: ignore[union-attr]
                    configuration, dt, self._damping, core, start, self._coupling_level,
                    self._passes,
                )  # fmt: skip
            if result is not None:
                return result
        return self._general_step(configuration, dt, start)

    def _general_step(self, configuration: Configuration, dt: float, start: float) -> StepResult:
        """:meth:`step` where its lane and plan do not answer: the corrected step, a forced
        backend's compiled step, or the QP path (a mink configuration read in place through
        qpik's view, as qpik's tasks read it)."""
        checks.check_instance(
            "configuration", configuration, mink.Configuration, "a qpik.Configuration"
        )
        if not isinstance(configuration, Configuration):
            configuration = Configuration.sharing(configuration)
        solution = None
        passes = self._passes
        if passes:  # the corrected step: the QP path's (see _corrected)
            solution = self._corrected(configuration, dt, passes)
        elif self._core.solver != "auto" and self._compiled_step_applies(configuration, dt):
            solution = self._compiled_step(configuration, dt)
            if solution is not None and (
                self._recoverable(solution) or LevelStatus.NUMERICAL in solution.status
            ):
                # the QP path relaxes the general rows (qpik.diffik.recovery); and a backend
                # that failed on the kernel's rows answers on the QP path's, a one-dof row
                # folded into the box (a user row scaled by 1e10: what "auto" answers)
                solution = None
        if solution is None:
            solution = self._qp_step(configuration, dt)
        return StepResult.of(solution, time.perf_counter() - start, self._coupling_level)

    def compiled_solution(self, configuration: mink.Configuration, dt: float) -> Solution | None:
        """The step by the compiled plan as a :class:`Solution` (every level, the
        couplings' first), None where the plan does not apply or the QP path must answer.
        ``configuration`` (qpik's or mink's) is read in place. With
        :attr:`qpik.StepOptions.correction_passes`: None (:meth:`qp_solution` corrects)."""
        if type(dt) is not float:  # (np.float64, an int: the same step as its float's)
            dt = checks.as_float_dt(dt)
        if self._passes or not self._compiled_step_applies(configuration, dt):
            return None
        return self._compiled_step(configuration, dt)

    def compiled_velocity(
        self, configuration: mink.Configuration, dt: float
    ) -> tuple[np.ndarray, list[LevelStatus]] | None:
        """The step's velocity ``dq / dt`` and every level's status (the couplings' first)
        by the compiled plan in one call, bitwise :meth:`step`'s; None where :meth:`step`
        would take another way (the caller then asks :meth:`compiled_solution`), and with
        :attr:`qpik.StepOptions.correction_passes`."""
        if type(dt) is not float:  # (np.float64, an int: the same step as its float's)
            dt = checks.as_float_dt(dt)
        if self._plan is None or self._passes or not self._compiled_step_applies(configuration, dt):
            return None
        core = self._core
        exact = self.exact_shortcut and core.solver != "auto" and not core.warm_start
        return self._plan.velocity(configuration, dt, self._damping, core, exact)

    def qp_solution(self, configuration: Configuration, dt: float) -> Solution:
        """The step by the QP path as a :class:`Solution` (every level, the couplings'
        first), corrected as :meth:`step` corrects
        (:attr:`qpik.StepOptions.correction_passes`)."""
        if self._passes:
            return self._corrected(configuration, dt, self._passes)
        return self._qp_step(configuration, dt)

    def _compiled_step_applies(self, configuration: mink.Configuration, dt: float) -> bool:
        """The solver has a compiled plan, for this model, and ``dt`` is a valid float."""
        return (
            self._plan is not None
            and configuration.model is self._model
            and type(dt) is float
            and checks.DT_MIN <= dt <= checks.DT_MAX
        )

    def _compiled_step(self, configuration: mink.Configuration, dt: float) -> Solution | None:
        """The step by the compiled plan (:meth:`CompiledPlan.step`), None where the QP
        path must answer."""
        assert self._plan is not None
        core = self._core
        exact = None
        if self.exact_shortcut and core.solver != "auto" and not core.warm_start:
            exact = self._exact_core()
        solution = self._plan.step(configuration, dt, self._damping, core, exact)
        if solution is None and self._replanned():
            solution = self._plan.step(configuration, dt, self._damping, core, exact)
        return solution

    def _replanned(self) -> bool:
        """Where a task attribute the compiled plan resolved when it was built (a frame's
        name or type, a relative task's root, a CoM task's body: its guards) changed since,
        the plan of the tasks as they are now replaces it, so that the steps from here are
        a new solver's, bit for bit (not the QP path's answer, equal only to round-off);
        True when it did. Where no plan applies to them now (an unknown frame, say), the old
        plan stays: its guards send the steps to the QP path, which answers or raises, and
        it serves again once the attributes are back."""
        plan = self._plan
        if plan is None or guards_hold(plan._guards):
            return False
        try:
            new = make_plan(self._model, self._levels, self._limits, self._core)
        except (QpikError, ValueError, TypeError, IndexError):
            return False  # (an attribute that does not fit: the QP path names it)
        if new is None or not guards_hold(new._guards):
            return False
        self._plan = new
        return True

    def _qp_step(self, configuration: Configuration, dt: float) -> Solution:
        """The step for any stack: the tasks' and limits' own rows, then the core's
        cascade; where level 0 is infeasible, again on the relaxable rows relaxed by their
        least slack (:mod:`qpik.diffik.recovery`)."""
        return self._recovered(
            configuration, dt, lambda tasks, limits: solve_rows(self._core, tasks, limits, dt)
        )

    def _recovered(
        self,
        configuration: Configuration,
        dt: float,
        solve: Callable[[TaskRows, LimitRows], Solution],
    ) -> Solution:
        """``solve`` on the step's rows (:meth:`_recoverable_rows`); where its first stack
        level is infeasible and a limit may relax, ``solve`` again on the relaxable rows
        relaxed by their least slack (:meth:`_relaxed`)."""
        tasks, limits = self._recoverable_rows(configuration, dt)
        solution = solve(tasks, limits)
        slack = self._slack(solution, limits, configuration)
        if slack is None:
            return solution
        return self._relaxed(lambda rows: solve(tasks, rows), limits, slack)

    def _recoverable_rows(
        self, configuration: Configuration, dt: float
    ) -> tuple[TaskRows, LimitRows]:
        """:meth:`_rows`, or, where a relaxable limit's one-dof row emptied the box
        (:class:`qpik.InfeasibleLimits`), the rows with those limits' rows all general (the
        same error where the box is empty without them)."""
        try:
            return self._rows(configuration, dt)
        except InfeasibleLimits:
            return self._rows(configuration, dt, fold=False)

    def _relaxed(
        self, solve: Callable[[LimitRows], Solution], limits: LimitRows, slack: np.ndarray
    ) -> Solution:
        """``solve`` on ``limits`` relaxed by ``slack``, each margin of
        :data:`qpik.diffik.recovery.RELAXATION_MARGINS` in turn until the first stack level
        is solved; that solution with its first stack level still reported ``infeasible``
        (the limits as given admit no displacement) and ``relaxation`` set."""
        level = int(self._coupling_level)
        for margin in RELAXATION_MARGINS:
            solution = solve(relaxed_rows(limits, slack, margin))
            if solution.status[level] == LevelStatus.SOLVED:
                break
        solution.status = [*solution.status]
        solution.status[level] = LevelStatus.INFEASIBLE
        solution.relaxation = slack
        return solution

    def _recoverable(self, solution: Solution) -> bool:
        """Whether ``solution``'s first level is infeasible (the couplings' where the model
        has couplings: no level below is then reached) and a limit's rows may be relaxed
        (:func:`qpik.diffik.boxes.relaxable`): the recovery's case."""
        return solution.status[0] == LevelStatus.INFEASIBLE and any(
            relaxable(limit) for limit in self._limits.limits
        )

    def _slack(
        self, solution: Solution, limits: LimitRows, configuration: Configuration
    ) -> np.ndarray | None:
        """The relaxable general rows' least slack (:func:`qpik.diffik.recovery.least_slack`)
        where :meth:`_recoverable` holds, with the support polygons' contact frames held
        (:func:`qpik.diffik.recovery.contact_rows`); else None."""
        if limits.G.shape[0] == 0 or not self._recoverable(solution):
            return None
        slack = least_slack(limits, contact_rows(self._limits.limits, configuration))
        return slack if slack is not None and slack.any() else None

    def _corrected(self, configuration: Configuration, dt: float, passes: int) -> Solution:
        """The step with ``passes`` second-order corrections on the QP path
        (:attr:`qpik.StepOptions.correction_passes`; :func:`qpik.diffik.correction.qp_corrected`;
        the compiled lean step does the same in its kernel): the step at ``configuration``;
        then, on the levels it holds (:func:`qpik.diffik.correction.held_levels`), each pass
        reads the tasks' errors at ``q (+) dq`` (one forward kinematics, no Jacobian), shifts
        those levels' targets by the remainder ``cost (e(q (+) dq) - e(q)) - A dq`` and solves
        again with the same rows, damping and limits."""
        if self._aux is None:
            self._aux = Configuration(self._model)
        levels, aux = self._levels, self._aux
        return self._recovered(
            configuration,
            dt,
            lambda tasks, limits: qp_corrected(
                self._core, levels, configuration, dt, passes, (tasks, limits), aux
            ),
        )

    def _exact_core(self) -> HierarchySolver:
        """An exact-solver core with this solver's settings (for :attr:`exact_shortcut`)."""
        core = self._core
        if self._exact is None:
            self._exact = HierarchySolver(
                "auto", damping_law=core.damping_law, rank_tolerance=core.rank_tolerance,
                max_iter=core.max_iter, tolerance=core.tolerance,
            )  # fmt: skip
        self._exact.damping_law = core.damping_law
        return self._exact
