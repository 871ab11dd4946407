r"""mink's entry points, with qpik underneath: switch by changing one import.

:func:`solve_ik` and :func:`build_ik` take mink's arguments, in mink's order, with mink's
defaults (``damping=1e-12``; ``limits=None`` means a :class:`mink.ConfigurationLimit`), and
accept a :class:`mink.Configuration` as well as a :class:`qpik.Configuration`::

    from qpik import solve_ik                     # was: from mink import solve_ik
    v = solve_ik(configuration, tasks, dt, "daqp", limits=limits)

What qpik adds, without changing a flat list's answer away from singularities:

* ``tasks`` may be a list of levels (a list of lists): strict priorities, each level solved
  in the null space of the ones above (a flat list is one weighted level, as in mink);
* ``constraints`` (mink's equality tasks, ``J dq = -gain e``) are held exactly: they form a
  level above every task level, with no Tikhonov term (rows a QP must satisfy exactly,
  whenever the limits allow it);
* near a singularity the adaptive damping of :class:`qpik.DampingLaw` bounds the step;
* a start outside the position limits moves back toward them instead of making the QP
  infeasible (``safety_break=True`` raises :class:`qpik.JointLimitViolation`, which is a
  :class:`mink.NotWithinConfigurationLimits`, as mink does).

The variable is the displacement ``dq = v dt`` [rad or m per step] in the tangent space
(``nv``); the velocity returned is ``dq / dt`` [rad/s or m/s]. Frames are mink's (tasks
define theirs).
"""

from __future__ import annotations

import math
import threading
import weakref
from collections.abc import Sequence
from typing import Any

import mink
import numpy as np
import qpsolvers

from ..core import LevelStatus, checks
from ..core.checks import type_name
from ..errors import InvalidArgumentType, InvalidDamping, InvalidInput, NoSolutionFound
from ..model.configuration import Configuration, as_configuration
from ..tasks import BaseTask
from .constraints import Tikhonov, constraint_level, equality_rows
from .limit_values import limit_value as _limit_value
from .limit_values import value_key as _value_key
from .result import SQUARABLE
from .solver import IKSolver

__all__ = ["SOLVERS", "SolverCache", "build_ik", "solve_ik"]

#: A flat list of tasks (one weighted level, as in mink) or a list of levels.
Tasks = Sequence[BaseTask] | Sequence[BaseTask | Sequence[BaseTask]]


class _MinimumNorm(BaseTask):
    """``dq = 0`` as a least-squares task: the smallest displacement the limits allow
    (what an empty task list asks for)."""

    def compute_qp_residual(self, configuration: mink.Configuration):
        nv = configuration.model.nv
        return np.eye(nv), np.zeros(nv), 0.0

    def compute_qp_objective(self, configuration: mink.Configuration) -> mink.Objective:
        nv = configuration.model.nv
        return mink.Objective(np.eye(nv), np.zeros(nv))


def _is_list_like(value: Any) -> bool:
    """A list, tuple or other iterable of items (mink iterates; a string is not one)."""
    if isinstance(value, np.ndarray) and value.ndim == 0:  # Iterable by type, not by value
        return False
    return checks.is_iterable(value) and not isinstance(value, (str, bytes, BaseTask))


def _levels(tasks: Any) -> list[list[BaseTask]]:
    """Levels from mink's ``tasks``: ``[]`` none; a flat list, one level; a list whose
    items include lists, one level per item (item 0 the highest priority)."""
    if isinstance(tasks, BaseTask):
        return [[tasks]]
    if not _is_list_like(tasks):
        raise InvalidInput(
            f"tasks must be a list of tasks or a list of levels, got {type(tasks).__name__}"
        )
    items = list(tasks)
    if all(isinstance(item, BaseTask) for item in items):
        return [items] if items else []
    levels = []
    for index, item in enumerate(items):
        level = [item] if isinstance(item, BaseTask) else item
        level = list(level) if _is_list_like(level) else None
        if not level:
            raise InvalidInput(
                f"tasks[{index}] must be a task or a non-empty list of tasks, got {item!r}"
            )
        for j, task in enumerate(level):
            if not isinstance(task, BaseTask):
                raise InvalidInput(f"tasks[{index}][{j}] is not a task: {task!r}")
        levels.append(list(level))
    return levels


def _limits(configuration: Configuration, limits: Any) -> list[mink.Limit]:
    """mink's default (``None``: the model's position limits) or the given limits."""
    if limits is None:
        return [mink.ConfigurationLimit(configuration.model)]
    if not _is_list_like(limits):
        raise InvalidInput(f"limits must be None or a list of limits, got {limits!r}")
    limits = list(limits)
    for index, limit in enumerate(limits):
        if not hasattr(limit, "compute_qp_inequalities"):
            raise InvalidInput(f"limits[{index}] is not a mink/qpik limit: {limit!r}")
    return limits


def _constraints(constraints: Any) -> list[mink.Task]:
    if constraints is None:
        return []
    if not _is_list_like(constraints):
        raise InvalidInput(f"constraints must be None or a list of tasks, got {constraints!r}")
    constraints = list(constraints)
    for index, task in enumerate(constraints):
        if not (hasattr(task, "compute_jacobian") and hasattr(task, "compute_error")):
            raise InvalidInput(
                f"constraints[{index}] must be a task with compute_jacobian and "
                f"compute_error (a mink.Task), got {task!r}"
            )
    return constraints


def _check_step(dt: Any, damping: Any) -> None:
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise InvalidInput(f"dt must be a positive number of seconds, got {dt!r}")
    if not (isinstance(damping, (int, float)) and math.isfinite(damping) and damping >= 0):
        raise InvalidDamping(f"damping must be finite and >= 0, got {damping!r}")


def solve_ik(
    configuration: mink.Configuration,
    tasks: Tasks,
    dt: float,
    solver: str | None = None,
    damping: float = 1e-12,
    safety_break: bool = False,
    limits: Sequence[mink.Limit] | None = None,
    constraints: Sequence[mink.Task] | None = None,
    **kwargs: Any,
) -> np.ndarray:
    """One differential IK step, with :func:`mink.solve_ik`'s signature.

    Args:
        configuration: the robot's configuration (qpik's or mink's; not modified).
        tasks: a list of tasks (one weighted level, as in mink), or a list of levels
            (lists of tasks; level 0 the highest priority). ``[]`` asks for the smallest
            velocity the limits allow: zero when the start is within them.
        dt: integration timestep [s].
        solver: QP backend. ``None``: qpik's exact compiled active-set solver. A name
            (``"daqp"``, ``"osqp"``, ``"quadprog"``, ``"proxqp"``, ``"clarabel"``; mink
            passes it fourth, positionally) forces that backend wherever a limit binds;
            its answer is polished by qpik's exact solve, so where that solve alone
            settles every level (stacks of the compiled step, :mod:`qpik.diffik.compiled`) the
            backend is not called: the same velocity, to round-off. With backend
            ``kwargs`` the backend is always called.
        damping: Tikhonov (Levenberg-Marquardt) term on every task level [unitless], as
            mink's; the constraints get none.
        safety_break: raise :class:`qpik.JointLimitViolation` (a
            :class:`mink.NotWithinConfigurationLimits`) if the configuration is outside its
            position limits; without it qpik steers back toward them.
        limits: limits enforced at every level; ``None`` (mink's default) means the model's
            position limits (:class:`mink.ConfigurationLimit`), ``[]`` none.
        constraints: equality tasks held exactly, above every task level.
        kwargs: settings of the forced backend (OSQP settings, or qpsolvers keyword
            arguments of that solver).

    Returns:
        The velocity ``v = dq / dt`` ``(nv,)`` [rad/s or m/s], in the tangent space.

    Threads: ``solve_ik`` may be called from several threads at once (a solver it keeps is
    stepped by one thread at a time); one :class:`qpik.IKSolver` must not be stepped by
    several threads at once (hold one per thread, or a :class:`qpik.IKSession`).

    Raises:
        qpik.NoSolutionFound: (a :class:`mink.NoSolutionFound`, with mink's message) when
            the highest level cannot be solved; ``status`` and ``level`` say why.
        qpik.InvalidInput: a malformed argument, named.
    """
    safety_break = checks.check_bool("safety_break", safety_break)
    if not kwargs:
        velocity = SOLVERS.velocity(
            configuration, tasks, dt, solver, damping, limits, constraints, safety_break
        )
        if velocity is not None:
            return velocity
    configuration = as_configuration(configuration)
    configuration._validated(configuration.q)  # (a mink one filled with NaN: named)
    _check_step(dt, damping)
    configuration.check_limits(safety_break=safety_break)
    constraint_tasks = _constraints(constraints)  # (an iterable, read once)
    if constraint_tasks:  # held exactly, in a level above the tasks'
        ik = _constrained_solver(
            configuration, tasks, solver, damping, limits, constraint_tasks, kwargs
        )
        if not kwargs:  # the next such call: SOLVERS.velocity's
            SOLVERS.keep_constrained(configuration, tasks, limits, solver, damping, constraints, ik)
    else:
        ik, _ = _solver(configuration, tasks, solver, damping, limits, None, kwargs)
    with SOLVERS.step_lock(ik):
        result = ik.step(configuration, dt)
        status, displacement = result.status, result.displacement.copy()
    _raise_unsolved(ik, status)
    with np.errstate(over="ignore"):
        velocity = displacement / dt
    if not np.isfinite(velocity).all():
        raise InvalidInput(f"dt = {dt!r} s is too small: the velocity dq / dt overflows")
    return velocity


def _raise_unsolved(ik: IKSolver, status: Sequence[LevelStatus]) -> None:
    """mink's :class:`NoSolutionFound` when the highest level was not solved."""
    if status and status[0] != LevelStatus.SOLVED:
        error = NoSolutionFound(ik.solver)  # mink's message, word for word
        error.status, error.level = str(status[0]), 0
        raise error


def _level_ids(tasks: list | tuple) -> tuple:
    """The ids of ``tasks`` level by level, as :meth:`SolverCache.get` keys them: a flat list
    is one level; a list with a list or tuple among its items has a level per item (a task
    alone, a level of one). An item of another kind counts as a task: a key that matches
    a kept entry names only objects that entry was built with (and holds)."""
    for item in tasks:
        if type(item) in (list, tuple):
            return tuple(
                tuple(map(id, item)) if type(item) in (list, tuple) else (id(item),)
                for item in tasks
            )
    return (tuple(map(id, tasks)),)


class SolverCache:
    """The :class:`IKSolver` objects that :func:`solve_ik` and :func:`build_ik` keep
    between calls, so that a control loop calling ``solve_ik`` with the same model, task
    and limit objects builds its solver once (as it would hold an :class:`IKSolver`).

    An entry is found by the identity of the model, of every task (level by level) and of
    every limit, and by the solver name, damping and backend settings; any change in their
    number, order or identity builds a new solver. With ``limits=None`` (mink's default
    :class:`mink.ConfigurationLimit`) the entry also records the model's joint ranges, so
    a model whose limits were changed in place gets a new one. Entries hold their objects,
    so an identity is never reused while its entry lives. The answers are bitwise those
    of a fresh solver (warm starts are off in these solvers: nothing carries over from
    one call to the next). ``qpik.clear_caches()`` empties it.
    """

    #: Entries kept (the least recently used goes first).
    size = 8

    def __init__(self) -> None:
        #: guards every dict of the cache (solve_ik may be called from several threads);
        #: a kept solver in use is taken out while its step runs (velocity; the full path
        #: steps a solver of its own making or one taken so), so no two threads step it
        self._lock = threading.Lock()
        #: one lock per kept solver, held while a call steps it (:meth:`stepping`)
        self._step_locks: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        self._entries: dict[tuple, tuple[tuple, IKSolver, Any]] = {}
        #: the key of a kept entry by its limits' values (_value_key): where a call's limit
        #: objects are new but equal to a kept entry's, that entry's solver answers
        self._values: dict[tuple | None, tuple] = {}
        #: the solvers of calls with constraints, by the call's objects (keep_constrained)
        self._constrained: dict[tuple, tuple[tuple, IKSolver, Any]] = {}
        #: the constraint and damping tasks of :func:`_constrained_solver` (its entries: by
        #: the identity of the constraint tasks, the damping and the number of levels; an
        #: entry holds its tasks), kept as the solvers are
        self.constraint_tasks: dict[tuple, tuple] = {}

    def clear(self) -> None:
        """Forget every kept solver (and the constraint tasks kept for them)."""
        with self._lock:
            self._entries.clear()
            self._values.clear()
            self._constrained.clear()
            self.constraint_tasks.clear()

    def __len__(self) -> int:
        return len(self._entries)

    def _fast_key(
        self,
        configuration: Any,
        tasks: Any,
        limits: Any,
        solver: Any,
        damping: Any,
        constraints: Any,
    ) -> tuple | None:
        """The key of :meth:`velocity`'s kept solvers for these arguments (None where the
        call is not one it answers: not a list or tuple of tasks, of limits or of
        constraints; ``limits=None`` keyed by the model's joint ranges)."""
        if type(tasks) not in (list, tuple) or not isinstance(configuration, mink.Configuration):
            return None
        if solver is not None and type(solver) is not str:  # the full path names it
            return None
        model = configuration.model
        if limits is None:
            limit_key: tuple = (None, model.jnt_range.tobytes(), model.jnt_limited.tobytes())
        elif type(limits) in (list, tuple):
            limit_key = tuple(map(id, limits))
        else:
            return None
        if constraints is None or (type(constraints) in (list, tuple) and not constraints):
            # (no constraint: an empty list is none, as the full path takes it)
            return (id(model), _level_ids(tasks), limit_key, solver, damping, "")
        if type(constraints) not in (list, tuple):
            return None
        # (a call with constraints: a key of its own kind, in _constrained)
        return (
            id(model),
            _level_ids(tasks),
            limit_key,
            solver,
            damping,
            tuple(map(id, constraints)),
        )

    def step_lock(self, ik: IKSolver) -> Any:
        """``ik``'s own lock: a kept solver is stepped by one thread at a time (its compiled
        plan's buffers are its own), whichever calls find it; hold it around the step."""
        lock = self._step_locks.get(ik)
        if lock is None:
            with self._lock:
                lock = self._step_locks.get(ik)
                if lock is None:
                    lock = self._step_locks[ik] = threading.Lock()
        return lock

    def keep_constrained(
        self,
        configuration: Any,
        tasks: Any,
        limits: Any,
        solver: str | None,
        damping: Any,
        constraints: Any,
        ik: IKSolver,
    ) -> None:
        """Keep ``ik``, the solver of a checked call with ``constraints``
        (:func:`_constrained_solver`'s), for :meth:`velocity`: by the identity of the model,
        of every task, limit and constraint, and the solver name and damping (the call's
        objects held while it is kept)."""
        if type(damping) is not float:
            return
        key = self._fast_key(configuration, tasks, limits, solver, damping, constraints)
        if key is None:
            return
        if limits is not None and list(map(id, ik.limits)) != list(map(id, limits)):
            return  # (a solver kept for equal limits: it reads those, not this call's)
        held = (configuration.model, list(tasks), limits, list(constraints))
        lock = self.step_lock(ik)  # (before the cache's lock: it takes it to make one)
        with self._lock:
            self._constrained.pop(key, None)
            if len(self._constrained) >= self.size:
                self._constrained.pop(next(iter(self._constrained)), None)
            self._constrained[key] = (held, ik, lock)  # most recently used last

    def velocity(
        self,
        configuration: Any,
        tasks: Any,
        dt: Any,
        solver: str | None,
        damping: Any,
        limits: Any,
        constraints: Any = None,
        safety_break: bool = False,
    ) -> np.ndarray | None:
        """:func:`solve_ik`'s answer for a call with a kept solver (a list or tuple of tasks
        or of levels, ``dt`` and ``damping`` floats, constraints None or a list or tuple of
        the constraint tasks of a kept solver; no backend settings), None otherwise:
        :func:`solve_ik` then checks every argument and answers. With ``safety_break`` the
        configuration's position limits are checked first, as there
        (:class:`qpik.JointLimitViolation`).

        A kept entry holds its task and limit objects, so ids equal to its key's are those
        objects, checked when the entry was built. The step is the kept solver's (the
        compiled step on ``configuration`` read in place, or the QP path), and the velocity
        the step's ``dq / dt``: bitwise :func:`solve_ik`'s full path."""
        if type(dt) is not float:  # (np.float64, an int: the same step as its float's)
            dt = checks.as_float_dt(dt)
        if type(damping) is not float:
            damping = checks.as_float_dt(damping)
        if type(dt) is not float or type(damping) is not float or not 0.0 <= damping < math.inf:
            return None
        key = self._fast_key(configuration, tasks, limits, solver, damping, constraints)
        if key is None:
            return None
        entries = self._entries if key[-1] == "" else self._constrained
        with self._lock:
            entry = entries.pop(key, None)
            if entry is None:
                key, entry = self._by_value(entries, key, limits)
                if entry is None:
                    return None
            entries[key] = entry  # most recently used last
        ik, lock = entry[1], entry[2]
        model = configuration.model
        if not 0.0 < dt < math.inf or model is not ik.model:
            return None
        if safety_break:
            as_configuration(configuration).check_limits(safety_break=True)
        with lock:
            fast = ik.compiled_velocity(configuration, dt)
            if fast is not None:
                velocity, status = fast
                velocity = velocity.copy()  # (its buffer is the solver's: a thread's next call)
            else:
                solution = ik.compiled_solution(configuration, dt)
                if solution is None:
                    solution = ik.qp_solution(as_configuration(configuration), dt)
                velocity, status = solution.velocity, solution.status
        _raise_unsolved(ik, status)
        # finite (its sum finite, else every entry checked: a finite v may overflow it)
        if not (math.isfinite(sum(velocity.tolist())) or np.isfinite(velocity).all()):
            return None  # the full path reports it
        return velocity

    def _by_value(
        self, entries: dict, key: tuple, limits: Any, value_key: tuple | None = None
    ) -> tuple[tuple, tuple | None]:
        """``(key, entry)`` of the kept entry whose limits equal ``limits`` by value (taken
        out of ``entries``), or ``(key, None)``. The entry's own limit objects are compared
        as they are now (the kept solver reads them: one edited in place since is not the
        call's)."""
        if value_key is None:
            value_key = _value_key(key, limits)
        kept_key = None if value_key is None else self._values.get(value_key)
        entry = None if kept_key is None else entries.pop(kept_key, None)
        if entry is None or value_key is None or kept_key is None:
            return key, None
        held = entry[0][2]
        if type(held) not in (list, tuple) or tuple(map(_limit_value, held)) != value_key[2]:
            entries[kept_key] = entry  # (its limits changed since: not this call's)
            return key, None
        return kept_key, entry

    def get(
        self,
        configuration: Configuration,
        levels: list[list[BaseTask]],
        limits: Any,
        solver: str | None,
        damping: float,
        backend_options: dict,
    ) -> IKSolver:
        """The kept solver for these arguments, or a new one (then kept)."""
        model = configuration.model
        if limits is None:
            limit_key: tuple = (None, model.jnt_range.tobytes(), model.jnt_limited.tobytes())
        else:
            limit_key = tuple(map(id, limits))
        key = (
            id(model),
            tuple(tuple(map(id, level)) for level in levels),
            limit_key,
            solver,
            float(damping),
            repr(sorted(backend_options.items())) if backend_options else "",
        )
        with self._lock:
            entry = self._entries.pop(key, None)
            value_key = None
            if entry is None:
                value_key = _value_key(key, limits)
                key, entry = self._by_value(self._entries, key, limits, value_key)
        if entry is None:  # (made outside the lock: another thread may make one too)
            ik = _new_solver(configuration, levels, solver, damping, limits, backend_options)
            # held: their ids stay theirs; the solver's step lock (step_lock)
            entry = ((model, levels, limits), ik, self.step_lock(ik))
        with self._lock:
            if len(self._entries) >= self.size:
                self._entries.pop(next(iter(self._entries)), None)
            if value_key is not None:
                if len(self._values) >= 4 * self.size:
                    self._values.clear()  # (keys of entries gone: a miss, then made again)
                self._values[value_key] = key
            self._entries[key] = entry  # most recently used last
        return entry[1]


#: The one cache of mink-style calls (see :class:`SolverCache`).
SOLVERS = SolverCache()


def _solver(
    configuration: Configuration,
    tasks: Any,
    solver: str | None,
    damping: float,
    limits: Any,
    constraints: Any,
    backend_options: dict,
) -> tuple[IKSolver, tuple[np.ndarray, np.ndarray] | None]:
    """The :class:`IKSolver` of the task levels (kept between calls, see
    :class:`SolverCache`), and the constraints' equality rows."""
    levels = _levels(tasks)
    if limits is not None:
        limits = _limits(configuration, limits)
    constraint_tasks = _constraints(constraints)
    if solver is not None and not isinstance(solver, str):  # a key of the solver cache
        raise InvalidArgumentType("solver", "a QP solver name (str) or None", type_name(solver))
    if backend_options and solver in (None, "auto"):
        raise InvalidInput(
            f"solver keyword arguments {sorted(backend_options)} are settings of a "
            "named backend: pass solver='osqp', 'daqp', ... with them"
        )
    ik = SOLVERS.get(configuration, levels, limits, solver, damping, backend_options)
    rows = None
    if constraint_tasks:
        rows = equality_rows(configuration, constraint_tasks, configuration.model.nv)
    return ik, rows


def _constrained_solver(
    configuration: Configuration,
    tasks: Any,
    solver: str | None,
    damping: float,
    limits: Any,
    constraint_tasks: list,
    backend_options: dict,
) -> IKSolver:
    """The solver of a call with constraints (``constraint_tasks``, checked by
    :func:`_constraints`): their rows (:func:`~qpik.diffik.constraints.constraint_level`,
    no damping) a level above the task levels, each task level with mink's ``damping`` as
    an LM term (:class:`~qpik.diffik.constraints.Tikhonov`; the solver's own damping 0),
    kept between calls as :class:`SolverCache` keeps solvers (the constraint and damping
    tasks are kept too, so that the same call finds the same solver). Each step is then the
    compiled step's where it applies, as without constraints; before, each call solved an
    ``IKSolver.build`` problem with the constraints' level inserted, by a new core (1.6x
    mink's time a call on mink's arm_panda_dof_freezing example)."""
    levels = _levels(tasks)
    model = configuration.model
    key = (id(model), tuple(map(id, constraint_tasks)), float(damping), len(levels))
    kept = SOLVERS.constraint_tasks
    entry = kept.pop(key, None)
    if entry is None:
        rows = constraint_level(constraint_tasks, configuration)
        tikhonov = [Tikhonov(damping) for _ in range(max(len(levels), 1))]
        # (no task: the smallest displacement, one kept task, as _new_solver's)
        entry = (model, constraint_tasks, rows, tikhonov, [_MinimumNorm()] if not levels else [])
        if len(kept) >= SolverCache.size:
            kept.pop(next(iter(kept)))
    kept[key] = entry  # most recently used last
    _, _, rows, tikhonov, minimum = entry
    levels = levels or [minimum]
    stack = [rows, *([*level, extra] for level, extra in zip(levels, tikhonov, strict=True))]
    return _solver(configuration, stack, solver, 0.0, limits, None, backend_options)[0]


def _new_solver(
    configuration: Configuration,
    levels: list[list[BaseTask]],
    solver: str | None,
    damping: float,
    limits: Any,
    backend_options: dict,
) -> IKSolver:
    """A new :class:`IKSolver` of ``levels`` (``[]``: the minimum-norm task) under
    ``limits`` (``None``: the model's position limits, as mink's default)."""
    limit_list = _limits(configuration, limits)
    if not levels:
        levels = [[_MinimumNorm()]]
    # mink's behaviour: no trust region beyond the limits given (StepOptions.max_joint_speed),
    # and the tasks and constraints given only (no coupling level: StepOptions.couplings;
    # mink's EqualityConstraintTask in ``constraints`` holds a model's couplings).
    options: dict[str, Any] = {"damping": damping, "max_joint_speed": None, "couplings": False}
    if solver is not None:
        options["solver"] = solver
    if backend_options:
        options["backend_options"] = backend_options
    ik = IKSolver(configuration.model, levels, limit_list, **options)
    # Only the velocity is returned: a named backend's answer, polished by the exact solve,
    # is that solve's (see IKSolver.exact_shortcut), so it is skipped where the exact
    # compiled step solves every level; not when the caller gave the backend settings.
    ik.exact_shortcut = not backend_options
    return ik


def build_ik(
    configuration: mink.Configuration,
    tasks: Tasks,
    dt: float,
    damping: float = 1e-12,
    limits: Sequence[mink.Limit] | None = None,
    constraints: Sequence[mink.Task] | None = None,
) -> qpsolvers.Problem | list[qpsolvers.Problem]:
    r"""The QP of each level as :func:`solve_ik` poses it, in :func:`mink.build_ik`'s shape.

    Built from :meth:`qpik.IKSolver.build`. Each level's problem is
    :math:`\min \tfrac12 dq^T P dq + q^T dq` subject to :math:`G dq \le h` and
    :math:`A dq = b`, over the displacement ``dq = v dt``:

    * ``P = A_k^T A_k + (damping + sum_i mu_i) I`` and ``q = -A_k^T b_k`` from the level's
      weighted rows (``A_k = diag(cost) J``, ``b_k = -gain cost e``): mink's objective;
    * ``G, h``: the limits as qpik enforces them, box bounds first (a row ``dq_i <= ub_i``
      for each finite upper bound, then ``-dq_i <= -lb_i`` for each finite lower bound:
      position limits already steer a start outside them back, velocity limits folded in)
      then the general rows (collision avoidance, ...); ``None`` when there are none;
    * ``A, b``: the constraints' rows ``J dq = -gain e`` (mink's), ``None`` without any.

    A flat list of tasks gives one :class:`qpsolvers.Problem` (mink's shape; ``[]`` gives
    mink's ``P = damping I``); its solution is :func:`solve_ik`'s ``dq`` whenever qpik's
    adaptive damping is zero (away from singularities): solve_ik solves the same objective
    from the level's rows, exactly. A backend solving ``P`` agrees with it to
    ``cond(P) eps`` relative: 1e-12 on a well-conditioned level, but with mink's damping
    1e-12 a task with fewer rows than dofs (a frame task on a 7-dof arm) has
    ``cond(P) ~ 1e12``, and ``P`` rounded to doubles then fixes the minimiser only to
    ~1e-5 along the Jacobian's null direction (backends differ from each other there as
    much; the task-space step ``J dq`` stays exact). A list of levels gives one problem
    per level; :func:`solve_ik` solves them in cascade, each level restricted to the optimal
    set of the levels above, which is why they are returned separately.

    Args: as :func:`solve_ik` (``dt`` in [s]).
    """
    configuration = as_configuration(configuration)
    _check_step(dt, damping)
    tasks = list(tasks) if _is_list_like(tasks) else tasks  # iterated more than once here
    flat = not _is_list_like(tasks) or all(isinstance(task, BaseTask) for task in tasks)
    ik, constraint_rows = _solver(configuration, tasks, None, damping, limits, constraints, {})
    hierarchy = ik.build(configuration, dt)
    nv = configuration.model.nv
    G, h = _inequality_rows(hierarchy.lb, hierarchy.ub, hierarchy.G, hierarchy.h)
    A_eq, b_eq = constraint_rows if constraint_rows is not None else (None, None)
    levels = _levels(tasks)
    problems = []
    for level in hierarchy.levels if levels else []:
        A, b, regularization = _squarable(level.A, level.b, level.regularization)
        P = A.T @ A
        P.flat[:: nv + 1] += regularization
        problems.append(qpsolvers.Problem(P, -(A.T @ b), G, h, A_eq, b_eq))
    if not levels:  # mink's problem for no task: the smallest displacement
        problems.append(qpsolvers.Problem(damping * np.eye(nv), np.zeros(nv), G, h, A_eq, b_eq))
    return problems[0] if flat else problems


def _squarable(A: np.ndarray, b: np.ndarray, regularization: float) -> tuple[Any, Any, float]:
    """A level's rows and regularisation, scaled down by ``s`` (the objective by ``s^2``,
    which leaves its minimiser unchanged) when an entry is too large to square into a
    finite ``P`` (a cost near 1e150 or beyond); unchanged otherwise."""
    largest = max(float(np.abs(A).max(initial=0.0)), float(np.abs(b).max(initial=0.0)))
    if not largest > SQUARABLE or not math.isfinite(largest):
        return A, b, regularization
    return A / largest, b / largest, regularization / largest / largest


def _inequality_rows(
    lb: np.ndarray, ub: np.ndarray, G: np.ndarray, h: np.ndarray
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Box bounds and general rows as ``G dq <= h`` (``None, None`` when there are none)."""
    nv = lb.shape[0]
    upper = np.flatnonzero(np.isfinite(ub))
    lower = np.flatnonzero(np.isfinite(lb))
    eye = np.eye(nv)
    rows = np.vstack([eye[upper], -eye[lower], G]) if nv else np.zeros((0, nv))
    bounds = np.concatenate([ub[upper], -lb[lower], h])
    if bounds.size == 0:
        return None, None
    return rows, bounds
