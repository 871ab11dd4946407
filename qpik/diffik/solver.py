r"""The IK layer: a task stack and limits at a configuration become a hierarchy of QPs,
solved by :mod:`qpik.core`.

The variable of every level is the displacement ``dq = v dt`` (``nv``). Level ``k`` has the
weighted residual ``A_k dq - b_k`` of its tasks (``A = diag(cost) J``, ``b = -gain cost e``,
mink's convention) and the core solves

.. math::

    \min_{dq} \tfrac12 \|A_k dq - b_k\|^2 + \tfrac12 (\delta + \mu_k + \lambda_k^2) \|dq\|^2
    \quad \text{s.t.} \quad dq \in d_{k-1} + \mathcal{N}_{k-1}, \;
    lb \le dq \le ub, \; G dq \le h

where :math:`d_{k-1}` is the solution of the levels above and :math:`\mathcal{N}_{k-1}` the
null space of their rows: a lower level never changes a higher level's ``A_j dq``.
``delta`` (``damping``) is a constant Tikhonov term on every level, as in mink; ``mu_k`` the
tasks' own Levenberg-Marquardt terms; ``lambda_k`` the adaptive singularity damping of
:class:`~qpik.core.DampingLaw`, decided from the singular values of the level's unweighted
Jacobian in the null space above (see :mod:`qpik.core.cascade`).

Limits (mink's or qpik's) give box bounds on ``dq`` (joint position and velocity limits,
computed directly for mink's ConfigurationLimit/VelocityLimit) and general rows
``G dq <= h`` (collision avoidance, custom limits); they hold at every level.

:meth:`IKSolver.build` returns that hierarchy (:class:`qpik.core.HierarchyProblem`) for
inspection; :meth:`IKSolver.step` is ``build`` plus the core solve.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import mink
import mujoco
import numpy as np

from ..core import (
    DampingLaw,
    HierarchyProblem,
    HierarchySolver,
    Level,
    LevelStatus,
    checks,
)
from ..core.cascade import STATUS_OF_CODE, LevelCertificate, certificates
from ..core.kernels import merge_boxes, tighten
from ..errors import (
    InfeasibleLimits,
    InvalidArgumentType,
    InvalidInput,
    InvalidTarget,
    as_qpik_error,
)
from ..model.configuration import Configuration, joint_names
from ..options import UNSET, StepOptions, Unset
from ..tasks import BaseTask
from .compiled import FusedPlan, box_of, make_plan

#: Level statuses by the kernels' codes (as the floats of the one-call step's info array).
_STATUS_OF_CODE = {float(code): status for code, status in STATUS_OF_CODE.items()}
_SOLVED_CODE = next(c for c, s in _STATUS_OF_CODE.items() if s == LevelStatus.SOLVED)

__all__ = [
    "DampingLaw",
    "IKSolver",
    "LevelStatus",
    "Stack",
    "StepResult",
    "normalize_stack",
]


@dataclass
class StepResult:
    """What one differential IK step computed.

    Attributes:
        velocity: joint velocity ``(nv,)`` [rad/s or m/s] (``displacement / dt``).
        displacement: ``dq = velocity * dt`` ``(nv,)``.
        residuals: per level, the norm of its weighted residual ``|A_k dq - b_k|`` at the
            final ``dq``, over all its rows (zero Jacobian rows included).
        sigma_min: per level, the smallest singular value that drove its damping (inf
            when the level has none).
        damping: per level, ``lambda^2`` applied.
        status: per level, a :class:`~qpik.core.LevelStatus` (``"solved"``,
            ``"infeasible"``: level 0's limits admit no displacement, ``"kept_previous"``,
            ``"max_iter"``, ``"not_reached"``, ...).
        iterations: per level, active-set changes (or the forced backend's iterations).
        solve_time: wall time of the whole step [s].
        certificate: per level, its :class:`~qpik.core.LevelCertificate` (the largest
            scaled violation of primal feasibility, stationarity, dual signs and
            complementarity at the point it returned; ``solved`` only when each is at most
            :data:`~qpik.core.CERTIFICATE_TOLERANCE`, see :mod:`qpik.core.cascade`).
        coupling_residual: the residual ``|A dq - b|`` of the level of the model's
            couplings, solved above the stack (:attr:`qpik.StepOptions.couplings`);
            ``None`` when there is none. The lists above hold the stack's levels only.
    """

    velocity: np.ndarray
    displacement: np.ndarray
    residuals: list[float]
    sigma_min: list[float]
    damping: list[float]
    status: list[LevelStatus]
    iterations: list[int]
    solve_time: float
    certificate: list[LevelCertificate] = field(default_factory=list)
    coupling_residual: float | None = None
    _name_active_limits: Callable[[], list[str]] | None = field(default=None, repr=False)
    _active_limits: list[str] | None = field(default=None, repr=False)

    @property
    def active_limits(self) -> list[str]:
        """The limits that bind at the final ``dq``, e.g.
        ``"joint4 upper (ConfigurationLimit)"`` (named on first access)."""
        if self._active_limits is None:
            names = self._name_active_limits() if self._name_active_limits else []
            self._active_limits = names
        return self._active_limits

    @property
    def ok(self) -> bool:
        """True when every level was solved."""
        return all(s == LevelStatus.SOLVED for s in self.status)


#: A task stack: a task, a list of tasks (one weighted level), or a list of levels, each a
#: task or a list of tasks (level 0 first). See :func:`normalize_stack`.
Stack = BaseTask | Sequence[BaseTask | Sequence[BaseTask]]


def normalize_stack(stack: Stack) -> list[list[BaseTask]]:
    """Levels from a stack description.

    * a task: one level with that task;
    * a sequence of tasks only: **one** level (weighted, like ``mink.solve_ik``);
    * a sequence whose items are tasks or sequences of tasks, at least one a sequence: one
      level per item, item 0 the highest priority.
    """
    if isinstance(stack, BaseTask):
        return [[stack]]
    if isinstance(stack, (str, bytes)) or not isinstance(stack, Sequence):
        raise InvalidInput(f"the task stack must be a task or a list, got {type(stack).__name__}")
    items = list(stack)
    if not items:
        raise InvalidInput("the task stack is empty")
    if all(isinstance(item, BaseTask) for item in items):
        return [cast("list[BaseTask]", items)]  # all tasks: checked just above
    return [_level_of(index, item) for index, item in enumerate(items)]


def _level_of(index: int, item) -> list[BaseTask]:
    """Level ``index`` of a stack: a task or a non-empty sequence of tasks."""
    if isinstance(item, BaseTask):
        return [item]
    level = None
    if isinstance(item, Sequence) and not isinstance(item, (str, bytes)):
        level = list(item)
    if not level or not all(isinstance(t, BaseTask) for t in level):
        raise InvalidInput(
            f"level {index} of the stack must be a task or a non-empty list of tasks, got {item!r}"
        )
    return level


def _row_weights(task: BaseTask, rows: int) -> np.ndarray:
    """The rows' costs of a task (its ``cost`` broadcast), 1 where it has none."""
    cost = getattr(task, "cost", None)
    if type(cost) is np.ndarray and cost.shape == (rows,):
        return cost
    if cost is None:
        return np.ones(rows)
    try:
        return np.abs(np.broadcast_to(np.asarray(cost, dtype=float), (rows,)))
    except ValueError:
        return np.ones(rows)


def level_rows(
    tasks: Sequence[BaseTask], configuration: Configuration, nv: int
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Stacked weighted residual of a level ``(A, b, mu, weights)``: the objective is
    ``1/2 |A dq - b|^2 + 1/2 mu |dq|^2``; ``weights`` are the rows' costs.

    Tasks that only provide ``(H, c)`` are factored as ``H = A^T A``, ``A^T b = -c`` (unit
    weights). Every row is kept, zero rows included.
    """
    A_parts, b_parts, w_parts = [], [], []
    mu = 0.0
    for task in tasks:
        try:
            residual = task.compute_qp_residual(configuration)
            objective = task.compute_qp_objective(configuration) if residual is None else None
        except mink.MinkError as exc:  # mink's own task classes: qpik's counterpart
            raise as_qpik_error(exc) from exc
        if objective is not None:
            H, c = objective
            values, vectors = np.linalg.eigh(0.5 * (H + H.T))
            keep = values > 1e-12 * max(1.0, float(values.max(initial=0.0)))
            root = np.sqrt(values[keep])
            A_parts.append(root[:, None] * vectors[:, keep].T)
            b_parts.append(-(vectors[:, keep].T @ c) / root)
            w_parts.append(np.ones(int(keep.sum())))
        else:
            assert residual is not None  # objective is None only when a residual was given
            jacobian, error, task_mu = residual
            if jacobian.ndim != 2:
                jacobian, error = np.atleast_2d(jacobian), np.atleast_1d(error)
            A_parts.append(jacobian)
            b_parts.append(error)
            w_parts.append(_row_weights(task, jacobian.shape[0]))
            mu += float(task_mu)
    if len(A_parts) == 1:
        return A_parts[0], b_parts[0], mu, w_parts[0]
    A = np.vstack(A_parts) if A_parts else np.zeros((0, nv))
    b = np.concatenate(b_parts) if b_parts else np.zeros(0)
    w = np.concatenate(w_parts) if w_parts else np.zeros(0)
    return A, b, mu, w


@dataclass(frozen=True)
class _RowStructure:
    """Rows of a limit's ``G``: single-dof upper / lower bounds (row, dof, 1/coefficient),
    general rows, and empty rows; ``unique`` when no dof is bounded twice on one side."""

    upper_rows: np.ndarray
    upper_dofs: np.ndarray
    upper_scale: np.ndarray
    lower_rows: np.ndarray
    lower_dofs: np.ndarray
    lower_scale: np.ndarray
    general: np.ndarray
    empty: np.ndarray | None
    unique: bool


def _configuration_box(
    limit: mink.ConfigurationLimit, qpos: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """mink's ConfigurationLimit as box bounds on ``dq`` at ``qpos`` (nq,): its hinge and
    slide joints' rows (each dof's coordinate at its joint's qpos address)."""
    if len(limit.indices) == 0:  # no limited joint (mink keeps an empty float array)
        return np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0)
    adr = limit.indices
    if qpos.shape[0] != limit.model.nv:  # free or ball joints: dof index != qpos index
        model = limit.model
        adr = model.jnt_qposadr[model.dof_jntid[limit.indices]]
    q = qpos[adr]
    upper = limit.gain * (limit.upper[adr] - q)
    lower = -limit.gain * (q - limit.lower[adr])
    return limit.indices, lower, upper


def _velocity_box(
    limit: mink.VelocityLimit, qpos: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """mink's VelocityLimit as box bounds on ``dq``: ``|dq| <= v_max dt``."""
    bound = limit.limit * dt
    return limit.indices, -bound, bound


#: Limits whose rows are known to be single-dof bounds, computed directly as boxes (exact
#: type match: a subclass may change the rows). Used on models whose joints are all
#: hinges or slides; other limits go through ``compute_qp_inequalities``.
_BOX_LIMITS: dict[type, Callable[[Any, np.ndarray, float], tuple[np.ndarray, ...]]] = {
    mink.ConfigurationLimit: _configuration_box,
    mink.VelocityLimit: _velocity_box,
}


#: The name of the step's trust region in :attr:`StepResult.active_limits`.
TRUST_REGION = "trust region"


def _trust_region(nv: int, limits: Sequence, speed: float | None) -> tuple[np.ndarray, np.ndarray]:
    """``(dofs, speeds)`` of the trust region: the dofs that no velocity limit of
    ``limits`` bounds (mink's or qpik's ``VelocityLimit``), each at ``speed`` [rad/s or
    m/s]; empty when ``speed`` is None."""
    if speed is None:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    bounded = np.zeros(nv, dtype=bool)
    for limit in limits:
        if isinstance(limit, mink.VelocityLimit) and len(limit.indices):
            bounded[np.asarray(limit.indices, dtype=np.int64)] = True
    dofs = np.flatnonzero(~bounded).astype(np.int64)
    return dofs, np.full(dofs.size, float(speed))


def _trust_box(
    dofs: np.ndarray, speeds: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The trust region as box bounds on ``dq``: ``|dq| <= speed dt`` (as
    :func:`_velocity_box`, so both paths compute the same bits)."""
    bound = speeds * dt
    return dofs, -bound, bound


def _step_options(options: StepOptions | None, osqp_settings, **given) -> StepOptions:
    """``options`` (default :class:`StepOptions`) with the keywords that were given."""
    if options is not None and not isinstance(options, StepOptions):
        raise InvalidInput(f"options must be a qpik.StepOptions, got {options!r}")
    overrides = {name: value for name, value in given.items() if value is not UNSET}
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
        solver, damping, damping_law, rank_tolerance, warm_start, backend_options,
            max_joint_speed, couplings: the :class:`qpik.StepOptions` fields of the same
            names. ``couplings`` (default ``True``): the model's joint and fixed-tendon
            equalities (URDF ``<mimic>`` among them) hold as a level above the stack.
        osqp_settings: former name of ``backend_options`` for OSQP (an object with
            ``as_dict()``).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        stack: Stack,
        limits: Sequence[mink.Limit] = (),
        *,
        options: StepOptions | None = None,
        solver: str | Unset = UNSET,
        damping: float | Unset = UNSET,
        damping_law: DampingLaw | None | Unset = UNSET,
        rank_tolerance: float | Unset = UNSET,
        warm_start: bool | Unset = UNSET,
        backend_options: Mapping[str, Any] | None | Unset = UNSET,
        max_joint_speed: float | None | Unset = UNSET,
        couplings: bool | Unset = UNSET,
        osqp_settings=None,
    ):
        if not isinstance(model, mujoco.MjModel):
            raise InvalidInput(f"model must be a mujoco.MjModel, got {type(model).__name__}")
        self.options = _step_options(
            options,
            osqp_settings,
            solver=solver,
            damping=damping,
            damping_law=damping_law,
            rank_tolerance=rank_tolerance,
            warm_start=warm_start,
            backend_options=backend_options,
            max_joint_speed=max_joint_speed,
            couplings=couplings,
        )
        solver, damping = self.options.solver, self.options.damping
        damping_law, rank_tolerance = self.options.damping_law, self.options.rank_tolerance
        backend_options = self.options.backend_options
        self.model = model
        self.levels = normalize_stack(stack)
        if isinstance(limits, (str, bytes, Mapping)) or not isinstance(limits, Iterable):
            raise InvalidArgumentType("limits", "a list of limits", checks.type_name(limits))
        #: The levels the steps solve: the model's couplings first (StepOptions.couplings,
        #: on a model that states some), then ``levels``.
        self._levels = self.levels
        self._coupling_level = False
        if self.options.couplings and model.neq:
            from ..model.couplings import model_couplings

            if model_couplings(model) is not None:
                from ..tasks.coupling import CouplingTask

                self._levels = [[CouplingTask(model)], *self.levels]
                self._coupling_level = True
        self.limits = list(limits)
        for limit in self.limits:
            if not hasattr(limit, "compute_qp_inequalities"):
                raise InvalidInput(f"limits must be mink/qpik limits, got {limit!r}")
            if isinstance(limit, mink.ConfigurationLimit) and len(limit.indices):
                empty = limit.indices[limit.lower[limit.indices] > limit.upper[limit.indices]]
                if len(empty):
                    raise InfeasibleLimits(
                        f"{type(limit).__name__}: the limits of dof {int(empty[0])} are "
                        "empty (min_distance_from_limits exceeds half its range)"
                    )
        self.solver = solver
        self.damping = float(damping)
        self.damping_law = damping_law
        self.rank_tolerance = rank_tolerance
        self._core = HierarchySolver(
            solver,
            damping_law=damping_law,
            rank_tolerance=rank_tolerance,
            warm_start=self.options.warm_start,
            backend_options=None if backend_options is None else dict(backend_options),
        )
        self._nv = model.nv
        names = joint_names(model)
        self._dof_names = [names[model.dof_jntid[i]] for i in range(model.nv)]
        self._structure_cache: dict[int, tuple] = {}
        self._no_rows = np.zeros((0, self._nv))
        self._bounds = tuple(np.empty(self._nv) for _ in range(4))  # scratch for _limit_rows
        #: The trust region: dofs that no velocity limit bounds, and their speed bound
        #: [rad/s or m/s] (empty when StepOptions.max_joint_speed is None).
        self._trust_dofs, self._trust_speed = _trust_region(
            model.nv, self.limits, self.options.max_joint_speed
        )
        self._scalar_joints = model.nq == model.nv and bool(
            np.all(
                np.isin(model.jnt_type, [mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE])
            )
        )
        #: With a forced backend, answer by the one-call step (exact compiled solver) when
        #: it solves every level: the forced-backend path returns that same answer to
        #: round-off (the exact cold solve polishes the backend's), at a backend call per
        #: level where a limit binds. Off by default (``StepResult.iterations`` then count
        #: the exact solver's iterations, not the backend's); qpik.solve_ik turns it on.
        self._exact_forced = False
        # One compiled call per step when every task and limit allows it (see qpik.diffik.compiled).
        self._plan = make_plan(
            model,
            self._levels,
            self.limits,
            self._scalar_joints,
            self._core.rank_tolerance,
            self._core.tolerance,
            self._core.max_iter or 0,
            trust=(self._trust_dofs, self._trust_speed),
        )

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
        return sum(getattr(ws, "setups", 0) for ws in self._core._workspaces.values())

    def reset(self) -> None:
        """Forget warm starts and backend workspaces (they only ever change speed)."""
        self._core.reset()

    def _row_structure(self, limit, G: np.ndarray) -> _RowStructure:
        """How a limit's rows split into single-dof bounds and general rows. Cached while
        ``G`` is unchanged (mink's position and velocity limits return the same ``G``)."""
        key = id(limit)
        cached = self._structure_cache.get(key)
        if cached is not None and cached[0].shape == G.shape and np.array_equal(cached[0], G):
            return cached[1]
        nonzero = G != 0.0
        count = nonzero.sum(axis=1)
        unit = np.flatnonzero(count == 1)
        dofs = np.argmax(nonzero[unit], axis=1) if unit.size else np.zeros(0, dtype=int)
        coefficients = G[unit, dofs]
        up = coefficients > 0
        empty = np.flatnonzero(count == 0)
        structure = _RowStructure(
            upper_rows=unit[up],
            upper_dofs=dofs[up],
            upper_scale=1.0 / coefficients[up],
            lower_rows=unit[~up],
            lower_dofs=dofs[~up],
            lower_scale=1.0 / coefficients[~up],
            general=np.flatnonzero(count > 1),
            empty=empty if empty.size else None,
            unique=len(set(dofs[up].tolist())) == up.sum()
            and len(set(dofs[~up].tolist())) == (~up).sum(),
        )
        self._structure_cache[key] = (G.copy(), structure)
        return structure

    def _limit_rows(self, configuration: Configuration, dt: float):
        """Box bounds ``lb <= dq <= ub`` and general rows ``G dq <= h`` of all limits, and
        the per-limit box contributions (to name the active limits afterwards)."""
        hard_lb, hard_ub, pos_lb, pos_ub = self._bounds
        hard_lb.fill(-np.inf)
        hard_ub.fill(np.inf)
        pos_lb.fill(-np.inf)
        pos_ub.fill(np.inf)
        contributions = []  # (name, dofs, bounds) for each side of each limit
        general: tuple[list[np.ndarray], list[np.ndarray], list[str]] = ([], [], [])  # G, h, names
        for limit in self.limits:
            recoverable = isinstance(limit, mink.ConfigurationLimit) or getattr(
                limit, "recoverable", False
            )
            lb, ub = (pos_lb, pos_ub) if recoverable else (hard_lb, hard_ub)
            box = _BOX_LIMITS.get(type(limit)) if self._scalar_joints else None
            if box is not None:
                dofs, lower, upper = box(limit, configuration.data.qpos, dt)
                if len(dofs):
                    tighten(lb, ub, dofs, lower, upper)
                    name = type(limit).__name__
                    contributions.append((name, dofs, upper))
                    contributions.append((name, dofs, lower))
            else:
                self._limit_inequalities(limit, configuration, dt, lb, ub, contributions, general)
        if self._trust_dofs.size:  # the trust region: a hard bound, as a velocity limit's
            dofs, lower, upper = _trust_box(self._trust_dofs, self._trust_speed, dt)
            tighten(hard_lb, hard_ub, dofs, lower, upper)
            contributions.append((TRUST_REGION, dofs, upper))
            contributions.append((TRUST_REGION, dofs, lower))
        lb, ub, i = merge_boxes(hard_lb, hard_ub, pos_lb, pos_ub)
        if i >= 0:
            raise InfeasibleLimits(
                f"limits on {self._dof_names[i]} need {hard_lb[i]:.6g} <= dq <= "
                f"{hard_ub[i]:.6g}: no displacement satisfies them"
            )
        G = np.vstack(general[0]) if general[0] else self._no_rows
        h = np.concatenate(general[1]) if general[1] else np.zeros(0)
        return lb, ub, G, h, contributions, general[2]

    def _limit_inequalities(self, limit, configuration, dt, lb, ub, contributions, general):
        """A limit's ``compute_qp_inequalities`` split into single-dof bounds (tightening
        ``lb``/``ub`` in place) and general rows (appended to ``general``)."""
        constraint = limit.compute_qp_inequalities(configuration, dt)
        if constraint.inactive:
            return
        G = constraint.G if constraint.G.ndim == 2 else np.atleast_2d(constraint.G)
        h = np.atleast_1d(constraint.h)
        name = type(limit).__name__
        structure = self._row_structure(limit, G)
        if structure.empty is not None and np.any(h[structure.empty] < 0):
            raise InfeasibleLimits(f"{name} has a row 0 . dq <= {h[structure.empty].min():.3g}")
        for rows, dofs, scale, side, pick in (
            (structure.upper_rows, structure.upper_dofs, structure.upper_scale, ub, np.minimum),
            (structure.lower_rows, structure.lower_dofs, structure.lower_scale, lb, np.maximum),
        ):
            if rows.size:
                bounds = h[rows] * scale
                if structure.unique:
                    side[dofs] = pick(side[dofs], bounds)
                else:
                    pick.at(side, dofs, bounds)
                contributions.append((name, dofs, bounds))
        if structure.general.size:
            general[0].append(G[structure.general])
            general[1].append(h[structure.general])
            general[2].extend(f"{name} row {int(r)}" for r in structure.general)

    # ------------------------------------------------------------------- build
    def build(self, configuration: Configuration, dt: float) -> HierarchyProblem:
        """The hierarchy of QPs at ``configuration`` for a step of ``dt`` [s]: per level
        ``A, b`` (weighted rows, in the displacement ``dq``), ``regularization``
        (``damping`` plus the tasks' LM terms) and row ``weights`` (costs), and the limits
        as box bounds ``lb <= dq <= ub`` and general rows ``G dq <= h``. The adaptive
        damping is decided by the core when it solves. With the model's couplings
        (:attr:`qpik.StepOptions.couplings`) their level comes first, named
        ``"couplings"``; the stack's levels follow, named ``"level 0"``, ...."""
        return self._build(configuration, dt)[0]

    def _build(self, configuration: Configuration, dt: float):
        """``(problem, contributions)``; see :meth:`build`."""
        A, b, w, starts, reg, lb, ub, G, h, contributions, names = self._rows(configuration, dt)
        shift = int(self._coupling_level)
        levels = [
            Level(
                A[s0:s1],
                b[s0:s1],
                float(reg[k]),
                w[s0:s1],
                "couplings" if k < shift else f"level {k - shift}",
            )
            for k, (s0, s1) in enumerate(zip(starts[:-1].tolist(), starts[1:].tolist()))
        ]
        return HierarchyProblem(levels, lb, ub, G, h, names), contributions

    def _rows(self, configuration: Configuration, dt: float):
        """Every level's rows stacked as the core takes them, and the limits."""
        dt = checks.check_dt(dt)
        if configuration.model is not self.model and configuration.model.nv != self._nv:
            raise InvalidInput(
                f"configuration has nv={configuration.model.nv}, the solver's model {self._nv}"
            )
        lb, ub, G, h, contributions, general_names = self._limit_rows(configuration, dt)
        A_parts, b_parts, w_parts = [], [], []
        L = len(self._levels)
        starts = np.zeros(L + 1, dtype=np.int64)
        reg = np.empty(L)
        for k, tasks in enumerate(self._levels):
            A, b, mu, w = level_rows(tasks, configuration, self._nv)
            A_parts.append(A)
            b_parts.append(b)
            w_parts.append(w)
            starts[k + 1] = starts[k] + b.shape[0]
            reg[k] = self.damping + mu
        A = np.concatenate(A_parts) if L > 1 else np.ascontiguousarray(A_parts[0], dtype=float)
        b = np.concatenate(b_parts) if L > 1 else np.ascontiguousarray(b_parts[0], dtype=float)
        w = np.concatenate(w_parts) if L > 1 else np.ascontiguousarray(w_parts[0], dtype=float)
        if not (math.isfinite(float(b @ b)) and math.isfinite(float(A.sum()))) or not (
            math.isfinite(float(reg.sum()))
        ):
            self._raise_not_finite(A, b, starts, reg)
        return A, b, w, starts, reg, lb, ub, G, h, contributions, general_names

    def _raise_not_finite(self, A, b, starts, reg) -> None:
        """Name the first level whose rows or regularisation are not finite."""
        for k, tasks in enumerate(self._levels):
            s0, s1 = starts[k], starts[k + 1]
            finite = np.isfinite(A[s0:s1]).all() and np.isfinite(b[s0:s1]).all()
            if not (finite and math.isfinite(reg[k])):
                raise InvalidTarget(
                    f"priority level {k}: a task error or Jacobian is not finite (a NaN "
                    f"or inf target?) in {', '.join(type(t).__name__ for t in tasks)}"
                )

    # ------------------------------------------------------------------- step
    def step(self, configuration: Configuration, dt: float) -> StepResult:
        """Solve the stack at ``configuration`` for a step of ``dt`` [s]. With the
        model's couplings (:attr:`qpik.StepOptions.couplings`) their level is solved
        first; the result's per-level lists are the stack's levels, and
        ``coupling_residual`` the coupling level's."""
        result = self._step(configuration, dt)
        if self._coupling_level:
            result.coupling_residual = result.residuals[0]
            for name in ("residuals", "sigma_min", "damping", "status", "iterations"):
                setattr(result, name, list(getattr(result, name))[1:])
            if result.certificate:
                result.certificate = list(result.certificate)[1:]
        return result

    def _step(self, configuration: Configuration, dt: float) -> StepResult:
        start = time.perf_counter()
        checks.check_instance(
            "configuration", configuration, mink.Configuration, "a qpik.Configuration"
        )
        plan = self._plan
        if (
            plan is not None
            and configuration.model is self.model
            and type(dt) is float
            and checks.DT_MIN <= dt <= checks.DT_MAX
        ):
            if self._core.solver == "auto":
                result = self._fused_step(plan, configuration, dt, start)
            elif plan.general_limits:
                result = self._fused_general_step(plan, configuration, dt, start)
            else:
                result = None
                if self._exact_forced and not self._core.warm_start:
                    result = self._fused_step(plan, configuration, dt, start, forced=True)
                if result is None:
                    result = self._fused_rows_step(plan, configuration, dt, start)
            if result is not None:
                return result
        return self._general_step(configuration, dt, start)

    def _settings(self, plan: FusedPlan, dt: float) -> np.ndarray:
        """The one-call plan's ``settings`` array for a step of ``dt`` [s]."""
        core = self._core
        settings = plan.arrays["settings"]
        settings[0] = dt
        settings[1] = self.damping
        law = core.damping_law
        if law is not plan.law:  # the law is settable: refresh its entries
            settings[2:5] = core._law()
            plan.law = law
        return settings

    def _fused_general_step(
        self, plan: FusedPlan, configuration: Configuration, dt: float, start: float
    ):
        """:meth:`step` for a plan with general-row limits (collision avoidance) under a
        forced backend: the rows and the box in one compiled call (the plan's
        ``Kernel.rows``), the limits' rows ``G dq <= h`` from their own methods, then the
        core's solve (the exact one first with ``_exact_forced``, as in
        :meth:`_fused_step`; the default solver takes them in :meth:`_fused_step`).
        None where the general path must answer (a non-finite row, conflicting limits, a
        limit row on one dof only, which the general path folds into the box)."""
        args = plan.gather(configuration)
        if args is None:
            return None
        self._settings(plan, dt)
        code, reg, lb, ub = plan.kernel.rows(*args, plan.no_rows, plan.no_h)
        if code:
            return None
        qpos = args[0]
        a = plan.arrays
        general = self._general_rows(plan, configuration, dt)
        if general is None:
            return None
        G, h, names = general
        q = qpos.copy()
        args = (a["A"], a["b"], a["w"], a["starts"], reg, lb, ub, G, h, dt, start,
                lambda: self._box_contributions(q, dt), names)  # fmt: skip
        core = self._core
        if core.solver != "auto" and self._exact_forced and not core.warm_start:
            exact = self._exact_core()
            result = self._finish(*args, core=exact)
            if all(s == LevelStatus.SOLVED for s in result.status):
                return result
        return self._finish(*args)

    def _general_rows(self, plan: FusedPlan, configuration: Configuration, dt: float):
        """``(G, h, names)`` of the plan's general-row limits as the general path takes
        them (rows on two or more dofs; empty rows dropped), None when a row bounds one
        dof (the general path makes it a box bound) or an empty row is infeasible."""
        G_parts: list[np.ndarray] = []
        h_parts: list[np.ndarray] = []
        names: list[str] = []
        for limit in plan.general_limits:
            constraint = limit.compute_qp_inequalities(configuration, dt)
            if constraint.inactive:
                continue
            G = constraint.G if constraint.G.ndim == 2 else np.atleast_2d(constraint.G)
            h = np.atleast_1d(constraint.h)
            structure = self._row_structure(limit, G)
            if structure.upper_rows.size or structure.lower_rows.size:
                return None
            if structure.empty is not None and np.any(h[structure.empty] < 0):
                return None  # the general path names the infeasible row
            rows = structure.general
            if not rows.size:
                continue
            G_parts.append(G[rows])
            h_parts.append(h[rows])
            name = type(limit).__name__
            names.extend(f"{name} row {int(r)}" for r in rows)
        if not G_parts:
            return self._no_rows, np.zeros(0), names
        G = np.ascontiguousarray(np.vstack(G_parts) if len(G_parts) > 1 else G_parts[0], float)
        h = np.ascontiguousarray(np.concatenate(h_parts) if len(h_parts) > 1 else h_parts[0], float)
        return G, h, names

    def _exact_core(self) -> HierarchySolver:
        """An exact-solver core with this solver's settings (for ``_exact_forced``)."""
        core = self._core
        exact = getattr(self, "_exact", None)
        if exact is None:
            exact = HierarchySolver(
                "auto", damping_law=core.damping_law, rank_tolerance=core.rank_tolerance,
                max_iter=core.max_iter, tolerance=core.tolerance,
            )  # fmt: skip
            self._exact = exact
        exact.damping_law = core.damping_law
        return exact

    def _fused_rows_step(
        self, plan: FusedPlan, configuration: Configuration, dt: float, start: float
    ):
        """:meth:`step` for a forced backend: the rows and limits in one compiled call
        (:func:`qpik.diffik.compiled.fused_rows`), then the core's level-by-level solve. None where
        the general path must answer."""
        args = plan.gather(configuration)
        if args is None:
            return None
        self._settings(plan, dt)
        code, reg, lb, ub = plan.kernel.rows(*args, plan.no_rows, plan.no_h)
        if code:
            return None
        a = plan.arrays
        q = args[0].copy()
        G, h = self._no_rows, np.zeros(0)
        return self._finish(
            a["A"], a["b"], a["w"], a["starts"], reg, lb, ub, G, h, dt, start,
            lambda: self._box_contributions(q, dt), [],
        )  # fmt: skip

    def _fused_step(
        self,
        plan: FusedPlan,
        configuration: Configuration,
        dt: float,
        start: float,
        forced: bool = False,
    ):
        """:meth:`step` in one compiled call (:mod:`qpik.diffik.compiled`: the plan's
        ``Kernel.step``, collision limits' rows ``G dq <= h`` from their own methods passed
        in); None where the general path must answer (non-finite rows, conflicting limits,
        an unsettled active set, a collision row on one dof, a task changed beyond its plan).

        ``forced`` (a forced backend, see ``_exact_forced``): the answer is kept only when
        every level was solved by the exact cold solve, which is what the forced-backend
        path returns then (it polishes the backend's answer by that same solve; equal to
        round-off, tests/test_fastpath.py), and None otherwise; no backend is called."""
        args = plan.gather(configuration)
        if args is None:
            return None
        if plan.general_limits:  # collision avoidance: G dq <= h from the limits' methods
            general = self._general_rows(plan, configuration, dt)
            if general is None:
                return None
            G, h, names = general
        else:
            G, h, names = plan.no_rows, plan.no_h, []
        p = G.shape[0]
        core = self._core
        warm = core._warm
        if not core.warm_start or warm is None or warm.shape[1] != self._nv + p:
            warm = plan.cold_for(p)
        self._settings(plan, dt)
        code, d, v, info, active = plan.kernel.step(
            *args, G, h, warm, core.warm_start, plan.max_iter or 10 * (self._nv + p) + 50
        )
        if code:
            return None
        qpos = args[0]
        residuals, sigma, lam2, status, iterations = info[:5].tolist()
        if forced and any(s != _SOLVED_CODE for s in status):
            return None
        core._warm = active
        q = qpos.copy()
        return StepResult(
            velocity=v,
            displacement=d,
            residuals=residuals,
            sigma_min=sigma,
            damping=lam2,
            status=[_STATUS_OF_CODE[s] for s in status],
            iterations=list(map(int, iterations)),
            solve_time=time.perf_counter() - start,
            certificate=certificates(info[5:].T),
            _name_active_limits=lambda: self._active_limits(
                d,
                *box_of(plan, q, dt),
                G,
                h,
                self._box_contributions(q, dt),
                names,
            ),  # fmt: skip
        )

    def _box_contributions(self, qpos: np.ndarray, dt: float) -> list:
        """The limits' box contributions ``(name, dofs, bounds)`` at ``qpos`` (to name
        the active limits of a fused step, whose limits are all box limits; see
        :meth:`_limit_rows`)."""
        contributions = []
        for limit in self.limits:
            box = _BOX_LIMITS.get(type(limit))
            if box is None:  # a general-row limit (see _fused_general_step)
                continue
            dofs, lower, upper = box(limit, qpos, dt)
            name = type(limit).__name__
            contributions.append((name, dofs, upper))
            contributions.append((name, dofs, lower))
        if self._trust_dofs.size:
            dofs, lower, upper = _trust_box(self._trust_dofs, self._trust_speed, dt)
            contributions.append((TRUST_REGION, dofs, upper))
            contributions.append((TRUST_REGION, dofs, lower))
        return contributions

    def _general_step(self, configuration: Configuration, dt: float, start: float) -> StepResult:
        """:meth:`step` for any stack: :meth:`_rows` (tasks' and limits' own methods) and
        the core's solve."""
        A, b, w, starts, reg, lb, ub, G, h, contributions, names = self._rows(configuration, dt)
        return self._finish(
            A, b, w, starts, reg, lb, ub, G, h, dt, start, lambda: contributions, names
        )

    def _finish(
        self, A, b, w, starts, reg, lb, ub, G, h, dt, start, contributions, names, core=None
    ):
        """The core's solve of the stacked rows and its :class:`StepResult`;
        ``contributions()`` gives the limits' box contributions (for naming active
        limits, on first access); ``core`` another core than this solver's."""
        core = self._core if core is None else core
        result = core.solve_arrays(A, b, w, starts, reg, lb, ub, G, h)
        d = result.x
        if not (math.isfinite(float(d @ d)) and math.isfinite(sum(result.residuals))):
            raise InvalidTarget(
                "the step or a level's residual is not finite: a level's rows are too large "
                "to square in floating point (a cost or target near 1e150 or beyond?)"
            )
        return StepResult(
            velocity=d / dt,
            displacement=d,
            residuals=result.residuals,
            sigma_min=result.sigma,
            damping=result.damping,
            status=result.status,
            iterations=result.iterations,
            solve_time=time.perf_counter() - start,
            certificate=result.certificate,
            _name_active_limits=lambda: self._active_limits(
                d, lb, ub, G, h, contributions(), names
            ),
        )

    def _active_limits(self, d, lb, ub, G, h, contributions, general_names) -> list[str]:
        tol = 1e-9
        active = []
        for side, bound, at_bound in (
            ("upper", ub, np.isfinite(ub) & (d >= ub - tol)),
            ("lower", lb, np.isfinite(lb) & (d <= lb + tol)),
        ):
            for i in np.flatnonzero(at_bound):
                source = next(
                    (
                        name
                        for name, dofs, bounds in contributions
                        if np.any((dofs == i) & (np.abs(bounds - bound[i]) <= tol))
                    ),
                    "limit",
                )
                active.append(f"{self._dof_names[i]} {side} ({source})")
        if G.shape[0]:
            for j in np.flatnonzero(G @ d >= h - 1e-7):
                active.append(general_names[j])
        return active
