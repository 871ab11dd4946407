"""The tasks :func:`qpik.solve_ik` builds around mink's ``constraints``: their equality rows
``J dq = -gain e`` as one level above the tasks (:class:`ConstraintRows`), and mink's
``damping`` as each task level's constant Tikhonov term (:class:`Tikhonov`).

Both supply their rows themselves (:class:`qpik.diffik.rows.SuppliedRows`): made, checked
and, for the constraints, scaled to unit norm in one call at each step, by the compiled
step's gathered rows and the QP path alike (:func:`qpik.diffik.rows.task_rows`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import mink
import numpy as np

from .._engine.tasks import frame_rows_into, unit_rows
from ..errors import InvalidInput, TaskDefinitionError
from ..model.configuration import Configuration
from ..tasks.frame import FrameTask, frame_terms
from ..tasks.mink_tasks import DofFreezingTask
from .rows import SuppliedRows

__all__ = [
    "ConstraintRows", "DofConstraint", "FrameConstraint", "Tikhonov", "constraint_level",
    "dof_freezing_form", "equality_rows",
]  # fmt: skip


def _stacked(
    configuration: mink.Configuration, constraints: Sequence[mink.Task], nv: int
) -> tuple[np.ndarray, np.ndarray, float]:
    """The constraints' Jacobian rows ``J`` and the vector ``e`` with the number ``gain``
    whose rows ``J dq = -gain e`` they are: one task's own arrays and gain, or every task's
    stacked in order with ``e`` its ``-gain e`` already (and ``gain`` -1)."""
    if len(constraints) == 1:
        task = constraints[0]
        J = np.atleast_2d(task.compute_jacobian(configuration))
        return J, np.atleast_1d(task.compute_error(configuration)), float(task.gain)
    A = [np.atleast_2d(task.compute_jacobian(configuration)) for task in constraints]
    with np.errstate(over="ignore", invalid="ignore"):  # (checked where they are used)
        b = [-task.gain * np.atleast_1d(task.compute_error(configuration)) for task in constraints]
    A_eq = np.vstack(A) if A else np.zeros((0, nv))
    b_eq = np.concatenate(b) if b else np.zeros(0)
    return A_eq, b_eq, -1.0


#: The frame tasks whose rows :func:`_frame_rows` makes (mink's class and qpik's, not a
#: subclass that may compute its own), and their unit costs (read-only).
_FRAME_TASKS = (mink.FrameTask, FrameTask)
_UNIT_COST = np.ones(6)
_UNIT_COST.flags.writeable = False


def _frame_rows(
    task: mink.FrameTask, configuration: Configuration
) -> tuple[np.ndarray, np.ndarray, float] | None:
    """A frame task's equalities ``J dq = -gain e`` as :func:`_stacked` returns them
    (``J``, ``-gain e``, ``-1``), by the engine (:func:`qpik.tasks.frame.frame_terms`, then
    ``frame_rows_into`` with unit costs: mink's ``compute_jacobian`` and ``compute_error``
    to round-off) rather than mink's Python; None for a frame type only mink knows."""
    terms = frame_terms(task, configuration)
    if terms is None:
        return None
    jac, xmat, jlog, error = terms
    J, b = np.empty((6, jac.shape[1])), np.empty(6)
    frame_rows_into(J, b, 0, jac, xmat, jlog, error, _UNIT_COST, float(task.gain), 0.0)
    return J, b, -1.0


def _not_finite() -> InvalidInput:
    return InvalidInput("constraints: a constraint's Jacobian or error is not finite")


def equality_rows(
    configuration: mink.Configuration, constraints: Sequence[mink.Task], nv: int
) -> tuple[np.ndarray, np.ndarray]:
    """mink's equality rows ``J dq = -gain e`` of the constraint tasks (costs not applied),
    stacked in order: ``A`` (k, nv) in the tasks' units, ``b`` (k,); raises
    :class:`qpik.InvalidInput` where they are not finite."""
    J, e, gain = _stacked(configuration, constraints, nv)
    with np.errstate(over="ignore", invalid="ignore"):
        b = -gain * e
    if not (np.isfinite(J).all() and np.isfinite(b).all()):
        raise _not_finite()
    return J, b


#: The weight of every constraint row (:meth:`ConstraintRows.rows_now`): the core judges a
#: level's rank and singular values on ``diag(1 / w) A`` (:class:`qpik.core.Level`), so the
#: constraints' singular values read 2^40 times theirs - far above any damping law's
#: threshold for every direction the rank keeps (at least ``rank_tolerance`` times the
#: largest, which unit rows make at least 1) - and the adaptive damping never applies to
#: them, as mink's equality constraints get none; a power of two, so the rank is decided
#: on exactly scaled numbers, as with weight 1.
UNDAMPED_WEIGHT = 2.0**-40


class ConstraintRows(SuppliedRows):
    """mink's constraint tasks (``solve_ik(constraints=...)``) as one task whose rows are
    their equalities ``J dq = -gain e`` (:func:`equality_rows`, costs not applied), each
    row scaled to unit norm (the same equalities: a row's units then do not meet the
    core's round-off floor), with no LM term and no adaptive damping (their weights
    :data:`UNDAMPED_WEIGHT`, even where the rows are nearly dependent: a frame constraint
    near a singularity): the level above the tasks' in :func:`qpik.solve_ik`'s solver,
    which holds them exactly where they can be met. ``k``: their number of rows at the
    configuration it was made at."""

    label = "constraints: their rows"

    def __init__(self, constraints: list, configuration: Configuration):
        self.constraints = constraints
        self.k = int(self.compute_qp_residual(configuration)[0].shape[0])

    def _unit_rows(self, configuration: mink.Configuration) -> tuple[np.ndarray, np.ndarray]:
        """The equalities with each row scaled to unit norm (a zero row as it is;
        ``qpik._engine.tasks.unit_rows``)."""
        nv = configuration.model.nv
        constraints = self.constraints
        stacked = None
        if (
            len(constraints) == 1
            and type(constraints[0]) in _FRAME_TASKS
            and isinstance(configuration, Configuration)
        ):
            stacked = _frame_rows(constraints[0], configuration)
        J, e, gain = stacked or _stacked(configuration, constraints, nv)
        if J.ndim != 2 or J.shape[1] != nv or e.shape != (J.shape[0],):
            raise TaskDefinitionError(
                f"constraints: their rows are of shape {J.shape} and their errors {e.shape}; "
                f"(k, {nv}) and (k,) expected"
            )
        A, b = np.empty(J.shape), np.empty(J.shape[0])
        if not unit_rows(A, b, J, e, gain):
            raise _not_finite()
        return A, b

    def compute_qp_residual(self, configuration: mink.Configuration):
        A, b = self._unit_rows(configuration)
        return A, b, None

    def compute_qp_objective(self, configuration: mink.Configuration) -> mink.Objective:
        A, b = self._unit_rows(configuration)
        return mink.Objective(A.T @ A, -(A.T @ b))

    def rows_now(self, configuration: mink.Configuration) -> tuple:
        A, b = self._unit_rows(configuration)
        return A, b, None, np.full(A.shape[0], UNDAMPED_WEIGHT)


class _OneConstraint(ConstraintRows):
    """:class:`ConstraintRows` of one task (``task``), whose gain the plan reads through it."""

    lm_damping = 0.0

    def __init__(self, task: mink.Task, configuration: Configuration):
        super().__init__([task], configuration)

    @property
    def task(self) -> Any:
        """The constraint task (a ``mink.Task``)."""
        return self.constraints[0]

    @property
    def gain(self) -> float:
        """The task's gain (its rows ``J dq = -gain e``)."""
        return self.task.gain


class FrameConstraint(_OneConstraint):
    """One frame task's constraint (mink's or qpik's ``FrameTask``, exact types) that the
    compiled step computes itself (kind ``FRAME`` with ``UNIT_ROWS``,
    qpik/_cpp/diffik/fused.hpp): the task's frame rows with unit costs and no LM term, each
    scaled to unit norm, weight :data:`UNDAMPED_WEIGHT` - the rows
    :meth:`ConstraintRows.rows_now` makes, which the QP path takes. The plan reads the
    task's target, gain and frame through it (its ``cost`` ones, ``lm_damping`` 0)."""

    cost = _UNIT_COST

    @property
    def transform_target_to_world(self) -> mink.SE3 | None:
        """The task's target pose in the world frame."""
        return self.task.transform_target_to_world

    @property
    def frame_name(self) -> str | int:
        """The task's frame name (or id)."""
        return self.task.frame_name

    @property
    def frame_type(self) -> str:
        """The task's frame type."""
        return self.task.frame_type


def dof_freezing_form(task: Any, nq: int) -> tuple[np.ndarray, np.ndarray]:
    """A DoF-freezing task as a linear task of the plan: ``(form (k, nq + 1), jacobian (k,
    nv))``, its Jacobian as mink computes it (once, at the task's construction: it does not
    depend on the configuration) and a zero residual (its error is zero)."""
    jacobian = np.array(task.compute_jacobian(None), dtype=np.float64)
    return np.zeros((jacobian.shape[0], nq + 1)), jacobian


class DofConstraint(_OneConstraint):
    """A ``DofFreezingTask`` (mink's or qpik's) as a constraint that the compiled step
    computes itself (kind ``LINEAR`` with ``UNIT_ROWS``): its constant rows, one unit row
    per frozen dof (``linear_form``, :func:`dof_freezing_form`), weight
    :data:`UNDAMPED_WEIGHT`, its costs ones."""

    def __init__(self, task: mink.DofFreezingTask, configuration: Configuration):
        super().__init__(task, configuration)
        #: the linear task's form and Jacobian (:func:`dof_freezing_form`)
        self.linear_form = dof_freezing_form(task, configuration.model.nq)
        self.cost = np.ones(self.linear_form[1].shape[0])
        self.cost.flags.writeable = False


#: The constraint tasks the compiled step computes itself, by exact type: their wrappers.
_NATIVE: dict[type, Callable[[Any, Configuration], ConstraintRows]] = {
    mink.FrameTask: FrameConstraint,
    FrameTask: FrameConstraint,
    mink.DofFreezingTask: DofConstraint,
    DofFreezingTask: DofConstraint,
}


def constraint_level(constraints: list, configuration: Configuration) -> list[ConstraintRows]:
    """The constraints' level of :func:`qpik.solve_ik`: one :class:`ConstraintRows` of them
    all where none is a task the compiled step computes, else one task each in order (a
    :class:`FrameConstraint` for a frame task, a :class:`DofConstraint` for a
    ``DofFreezingTask``, mink's or qpik's). Each row is the same either way but for a frame task in
    a stack of several: its rows are then qpik's frame rows rather than mink's
    ``compute_jacobian`` (equal to round-off)."""
    if not any(type(task) in _NATIVE for task in constraints):
        return [ConstraintRows(constraints, configuration)]
    return [_NATIVE.get(type(task), _one_task)(task, configuration) for task in constraints]


def _one_task(task: mink.Task, configuration: Configuration) -> ConstraintRows:
    return ConstraintRows([task], configuration)


class Tikhonov(SuppliedRows):
    """mink's ``damping`` of a task level as a task with no rows: its LM term, ``damping``,
    the level's constant regularisation (:func:`qpik.solve_ik` with constraints: the
    solver's own damping is 0 there, so that the constraints' level gets none). A compiled
    plan reads ``damping`` once, when it is built (:func:`qpik.diffik.layout.task_layout`)."""

    k = 0

    def __init__(self, damping: float):
        self.damping = float(damping)
        self._empty: tuple | None = None

    def compute_qp_residual(self, configuration: mink.Configuration):
        nv = configuration.model.nv
        return np.zeros((0, nv)), np.zeros(0), self.damping

    def compute_qp_objective(self, configuration: mink.Configuration) -> mink.Objective:
        nv = configuration.model.nv
        return mink.Objective(self.damping * np.eye(nv), np.zeros(nv))

    def rows_now(self, configuration: mink.Configuration) -> tuple:
        nv = configuration.model.nv
        empty = self._empty
        if empty is None or empty[0].shape[1] != nv:
            empty = self._empty = (np.zeros((0, nv)), np.zeros(0), np.zeros(0))
        return empty[0], empty[1], self.damping, empty[2]
