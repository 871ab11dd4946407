"""The task side of a step: a stack of tasks becomes priority levels, and each level the
weighted rows ``A_k dq - b_k`` of its tasks, stacked as the core's cascade takes them.

:func:`normalize_stack` reads the stack forms users write (a task, a list of tasks, a list
of levels); :func:`level_rows` asks each task of a level for its rows (mink's convention:
``A = diag(cost) J``, ``b = -gain cost e``); :func:`stack_rows` stacks every level into one
:class:`TaskRows` and names the first level whose rows are not finite.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NoReturn, cast

import mink
import mujoco
import numpy as np
import scipy.linalg

from .._engine.tasks import axis_align_residual, equality_rows, kinetic_rows, look_at_residual
from ..errors import InvalidInput, InvalidTarget, QpikError, TaskDefinitionError, as_qpik_error
from ..model.configuration import Configuration
from ..model.frames import FRAME_POSITIONS, FRAME_ROTATIONS, FrameType
from ..model.inertia import inertia_matrix, inertia_tree
from ..tasks import (
    AxisAlignTask,
    BaseTask,
    EqualityConstraintTask,
    KineticEnergyRegularizationTask,
    LookAtTask,
)
from ..tasks.checked import POSE_TARGETS, CheckedTask, check_gain, check_pose_target

__all__ = ["Stack", "TaskRows", "level_rows", "normalize_stack", "stack_rows", "task_rows"]

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


#: mink's ``get_epsilon(float64)``: the smallest distance to the point looked at [m]
_EPS = 1e-10


def _residual_inputs(task, configuration: Configuration, target_name: str) -> tuple | None:
    """``(kind, fid, target, axis, cost, gain, lm)`` of a look-at or axis-align task (its
    target the attribute ``target_name``), None where anything is not as mink's defaults
    make it (no target, a frame name or type, axis, cost, gain or LM damping of another
    kind): the task's own method then answers, or raises its error."""
    try:
        target, axis, cost = getattr(task, target_name), task.axis, task.cost
        gain, lm = float(task.gain), float(task.lm_damping)
        if not (
            type(target) is np.ndarray and target.shape == (3,)
            and type(axis) is np.ndarray and axis.shape == (3,)
            and type(cost) is np.ndarray and cost.shape == (3,)
        ):  # fmt: skip
            return None
        kind = FrameType.parse(task.frame_type)
        fid = configuration.frame_id(task.frame_name, kind)
    except (QpikError, TypeError, ValueError, AttributeError, KeyError):
        return None
    return kind, fid, target, axis, cost, gain, lm


def _look_at_residual(
    task: mink.LookAtTask, configuration: Configuration
) -> tuple[np.ndarray, np.ndarray, float] | None:
    """A :class:`mink.LookAtTask`'s weighted residual ``(cost J, -cost gain e, lm |.|^2)``
    as its ``compute_qp_residual`` defines it (``e = a - d``, ``d = r / |r|``, ``r = R^T
    (p* - p)``; ``J = (I - d d^T) (J_v - [r]x J_w) / |r|``, the Jacobian blocks in the
    frame), from MuJoCo's pose and Jacobian of the frame at once, by the compiled
    ``look_at_residual`` (``qpik/_cpp/tasks/look_at.hpp``): mink's computes the frame's
    transform and Jacobian twice over (its error and its Jacobian apart), about 70-95 us a
    task. Equal to mink's to round-off. None where an input does not fit
    (:func:`_residual_inputs`)."""
    inputs = _residual_inputs(task, configuration, "target_pos")
    if inputs is None:
        return None
    kind, fid, target, axis, cost, gain, lm = inputs
    data = configuration.data
    jacobian = configuration.frame_jacobian(fid, kind)
    weighted, weighted_error = np.empty((3, jacobian.shape[1])), np.empty(3)
    mu = look_at_residual(
        weighted, weighted_error, jacobian, getattr(data, FRAME_ROTATIONS[kind])[fid],
        getattr(data, FRAME_POSITIONS[kind])[fid], target, axis, cost, gain, lm, _EPS,
    )  # fmt: skip
    return weighted, weighted_error, mu


def _axis_align_residual(
    task: mink.AxisAlignTask, configuration: Configuration
) -> tuple[np.ndarray, np.ndarray, float] | None:
    """A :class:`mink.AxisAlignTask`'s weighted residual ``(cost J, -cost gain e, lm |.|^2)``
    as its ``compute_qp_residual`` defines it (``e = a - d``, ``d = R^T t``, ``J = -[d]x
    J_w``, ``J_w`` the frame's angular block), from MuJoCo's rotation and Jacobian of the
    frame, by the compiled ``axis_align_residual`` (``qpik/_cpp/tasks/axis_align.hpp``):
    mink's builds the frame's transform, its body Jacobian and the products in Python.
    Equal to mink's to round-off. None where an input does not fit
    (:func:`_residual_inputs`)."""
    inputs = _residual_inputs(task, configuration, "target_dir")
    if inputs is None:
        return None
    kind, fid, target, axis, cost, gain, lm = inputs
    jacobian = configuration.frame_jacobian(fid, kind)
    weighted, weighted_error = np.empty((3, jacobian.shape[1])), np.empty(3)
    mu = axis_align_residual(
        weighted, weighted_error, jacobian[3:],
        getattr(configuration.data, FRAME_ROTATIONS[kind])[fid], target, axis, cost, gain, lm,
    )  # fmt: skip
    return weighted, weighted_error, mu


#: The tasks whose weighted residual the engine computes (mink's classes and qpik's, the
#: same methods with qpik's errors; not a subclass, which may compute its own): their
#: residual functions.
_COMPILED_RESIDUALS: dict[type, Callable] = {
    mink.LookAtTask: _look_at_residual,
    LookAtTask: _look_at_residual,
    mink.AxisAlignTask: _axis_align_residual,
    AxisAlignTask: _axis_align_residual,
}


def kinetic_scale(task: mink.KineticEnergyRegularizationTask) -> float | None:
    """A kinetic-energy task's ``cost / dt^2`` as mink scales ``M`` by it (``cost *
    inv_dt_sq``), None where its cost or ``inv_dt_sq`` is not a float (or an int): no time
    step set, a value of another type (its own methods then report it)."""
    cost, inv_dt_sq = task.cost, task.inv_dt_sq
    if not isinstance(cost, (float, int)) or not isinstance(inv_dt_sq, (float, int)):
        return None
    if type(cost) is bool or type(inv_dt_sq) is bool:
        return None
    return float(cost) * float(inv_dt_sq)


def _kinetic_rows(
    task: mink.KineticEnergyRegularizationTask, configuration: Configuration
) -> tuple[np.ndarray, np.ndarray, None, np.ndarray] | None:
    """A kinetic-energy task's rows ``(A, b = 0, None, ones)``, ``A^T A = (cost / dt^2)
    M(q)``, by the compiled engine (:func:`qpik.model.inertia.inertia_matrix`, then the
    Cholesky factor of ``qpik/_cpp/tasks/kinetic.hpp``): the compiled step's rows, bit for
    bit; a cost / dt^2 below 0 or not finite raises :class:`qpik.TaskDefinitionError`. None
    where its objective is left to its own methods: a value :func:`kinetic_scale` does not
    take, a model whose actuators or tendons add armature, or ``H`` not positive
    definite to the engine's test (the eigendecomposition then factors it)."""
    scale = kinetic_scale(task)
    if scale is not None and not (math.isfinite(scale) and scale >= 0.0):
        raise TaskDefinitionError(
            f"{type(task).__name__}: its cost / dt^2 (cost * inv_dt_sq) must be a finite "
            f"number >= 0, got {scale!r} (a cost or time step set out of range?)"
        )
    tree = inertia_tree(configuration.model) if scale is not None else None
    if tree is None:
        return None
    A = kinetic_rows(inertia_matrix(configuration.data, tree), scale)
    if A is None:
        return None
    n = A.shape[0]
    return A, np.zeros(n), None, np.ones(n)


def efc_arrays(model: mujoco.MjModel, data: mujoco.MjData) -> tuple:
    """The MjData's constraint rows as the engine reads them (``qpik/_cpp/tasks/
    equality.hpp``): ``(efc_J, efc_pos, efc_type, efc_id, efc_J_rownnz, efc_J_rowadr,
    efc_J_colind, sparse)``, as ``mj_makeConstraint`` left them (which
    :meth:`mink.Configuration.update` runs on a model with equalities)."""
    return (
        data.efc_J, data.efc_pos, data.efc_type, data.efc_id, data.efc_J_rownnz,
        data.efc_J_rowadr, data.efc_J_colind, bool(mujoco.mj_isSparse(model)),
    )  # fmt: skip


def equality_constants(task: mink.EqualityConstraintTask, neq: int) -> np.ndarray | None:
    """Each equality's position in an equality-constraint task (``(neq,)`` int64, -1 where
    not its: mink 1.3's ``_eq_id_to_pos``), None where the task does not hold it so."""
    position = getattr(task, "_eq_id_to_pos", None)
    if not (isinstance(position, np.ndarray) and position.shape == (neq,)):
        return None
    return position.astype(np.int64)


def _equality_rows(
    task: mink.EqualityConstraintTask, configuration: Configuration
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray] | None:
    """An equality-constraint task's weighted rows ``(cost J, -cost gain e, lm |.|^2,
    costs)`` from MuJoCo's constraint rows of its equalities (``efc_J``, ``efc_pos``), as
    mink's ``compute_qp_residual`` makes them, by the compiled engine (``qpik/_cpp/tasks/
    equality.hpp``: the compiled step's rows, bit for bit; mink's squares summed by BLAS,
    to round-off). None where the task does not hold its values as mink 1.3 does (its own
    methods then serve)."""
    model = configuration.model
    position = equality_constants(task, model.neq)
    cost = getattr(task, "_cost", None)
    gain, lm = task.gain, task.lm_damping
    if position is None or not (isinstance(cost, np.ndarray) and cost.dtype == float):
        return None
    if cost.ndim != 1 or type(gain) not in (float, int) or type(lm) not in (float, int):
        return None
    efc = efc_arrays(model, configuration.data)
    try:
        A, b, mu, w = equality_rows(*efc, model.nv, position, cost, float(gain), float(lm))
    except ValueError:  # (MuJoCo's arrays not as they should be: mink's methods report it)
        return None
    return A, b, mu, w


#: The tasks whose rows the engine makes (mink's class and qpik's; not a subclass, which
#: may compute its own): the factor of an objective ``(H, c)``, MuJoCo's constraint rows.
_ENGINE_ROWS: dict[type, Callable] = {
    mink.KineticEnergyRegularizationTask: _kinetic_rows,
    KineticEnergyRegularizationTask: _kinetic_rows,
    mink.EqualityConstraintTask: _equality_rows,
    EqualityConstraintTask: _equality_rows,
}


class SuppliedRows(BaseTask):
    """A task of qpik's own that makes its rows as :func:`task_rows` returns them, already
    checked (shapes, finiteness): :meth:`rows_now` (its errors typed by :func:`task_rows`,
    naming :attr:`label`). The tasks that :func:`qpik.solve_ik` builds around mink's
    constraints (:mod:`.constraints`)."""

    #: What an error in its rows names (``"<label> failed (...)"``).
    label = "rows"

    def rows_now(self, configuration: Configuration) -> tuple:
        """``(A, b, mu, weights)`` at ``configuration``, as :func:`task_rows` returns them."""
        raise NotImplementedError


def _raise_rows_failure(exc: Exception, label: str) -> NoReturn:
    """Raise qpik's counterpart of ``exc``, raised while a task made the rows ``label``
    names: a :class:`mink.MinkError` (mink's own task classes) as qpik's
    (:func:`qpik.errors.as_qpik_error`), a :class:`qpik.QpikError` as it is, another
    ``ValueError`` or ``TypeError`` (a cost or gain set to what does not fit) as a
    :class:`qpik.TaskDefinitionError`."""
    if isinstance(exc, mink.MinkError):
        raise as_qpik_error(exc) from exc
    if isinstance(exc, QpikError):
        raise exc
    raise TaskDefinitionError(f"{label} failed ({exc})") from exc


def _check_read_values(task: BaseTask) -> None:
    """The values of ``task`` that mink's own classes take unchecked where they are set
    (qpik's check them there: :class:`qpik.tasks.checked.CheckedTask`): a gain outside
    [0, 1] (:class:`qpik.InvalidGain`), a frame target that is not an SE3 or whose
    quaternion is zero (:class:`qpik.InvalidTarget`), named with the task."""
    if isinstance(task, CheckedTask):
        return
    check_gain(task, getattr(task, "gain", 1.0))
    for cls, name in POSE_TARGETS:
        if isinstance(task, cls):
            target = getattr(task, name, None)
            if target is not None:  # (None: the task's own TargetNotSet)
                check_pose_target(task, target, name)


#: The part of an objective's ``c`` outside its ``H``'s range (relative to ``|c|``) beyond
#: which :func:`_objective_rows` refuses it: a least-squares task's ``c = -J^T W e`` has one
#: of its round-off only (at most about 1e-6 of it along a direction the eigenvalue cutoff
#: drops).
_OUTSIDE_RANGE = 1e-5


def _objective_rows(
    H: np.ndarray, c: np.ndarray, name: str = "a task"
) -> tuple[np.ndarray, np.ndarray, None, np.ndarray]:
    """Rows ``(A, b)`` of an objective ``(H, c)`` (``H`` symmetric, finite): ``A^T A = H``,
    ``A^T b = -c``, one row per dof (unit weights, no LM term). A ``c`` with a part outside
    ``H``'s range (a linear term where ``H`` is 0, as a gradient step ``c = -grad``) has no
    such rows - a level of least squares cannot hold it, and mink's QP answers it only
    through its damping - so it raises :class:`qpik.TaskDefinitionError` naming the task
    (``name``) rather than being dropped."""
    # H positive definite with room (every Cholesky pivot^2 above the cutoff below): its
    # factor's rows, H = L L^T, A = L^T, L b = -c (a mass matrix: 43 dofs in about 8 us,
    # where the eigendecomposition below takes 100 us).
    factor = _cholesky_rows(H, c)
    if factor is not None:
        return factor
    # Else one row per eigenvector, whatever H's rank: an eigenvalue at or below the cutoff
    # gives a zero row (b 0), so that the task's rows keep their shape from step to step
    # (the compiled step plans them; a cost of 0, say, made the row count change and sent
    # every step to the QP path). A zero row adds nothing to the level's objective.
    values, vectors = np.linalg.eigh(H)
    keep = values > 1e-12 * max(1.0, float(values.max(initial=0.0)))
    outside = float(np.linalg.norm(vectors[:, ~keep].T @ c))
    if outside > _OUTSIDE_RANGE * float(np.linalg.norm(c)):
        raise TaskDefinitionError(
            f"{name}: its objective's linear term c has a part outside H's range ({outside:.3g}"
            f" of |c| = {float(np.linalg.norm(c)):.3g}: a linear term where H is 0), which a "
            "level of least squares cannot hold; give the task rows (compute_qp_residual) or "
            "an H whose range covers c"
        )
    root = np.sqrt(np.where(keep, values, 0.0))
    A = root[:, None] * vectors.T
    b = np.zeros(len(values))
    b[keep] = -(vectors[:, keep].T @ c) / root[keep]
    return A, b, None, np.ones(len(values))


def _cholesky_rows(
    H: np.ndarray, c: np.ndarray
) -> tuple[np.ndarray, np.ndarray, None, np.ndarray] | None:
    """:func:`task_rows`' rows of an objective ``(H, c)`` by the Cholesky factor of ``H``
    (``A = L^T``, ``L b = -c``: ``A^T A = H``, ``A^T b = -c``), None where ``H`` is not
    positive definite with every pivot^2 above ``1e-12 max(1, max diag H)`` (the
    eigendecomposition's cutoff then decides the rank)."""
    if H.shape[0] == 0:
        return None
    try:
        L = np.linalg.cholesky(H)
    except np.linalg.LinAlgError:
        return None
    pivots = np.diagonal(L)
    if not (pivots * pivots).min() > 1e-12 * max(1.0, float(np.diagonal(H).max())):
        return None
    b = -scipy.linalg.solve_triangular(L, c, lower=True, check_finite=False)
    return np.ascontiguousarray(L.T), b, None, np.ones(H.shape[0])


def _engine_rows(task: BaseTask, configuration: Configuration) -> tuple | None:
    """:func:`task_rows`' answer where the compiled engine makes the task's rows (the
    compiled step's, bit for bit: :data:`_ENGINE_ROWS`, :data:`_COMPILED_RESIDUALS`),
    else None (the task's own methods)."""
    objective_rows = _ENGINE_ROWS.get(type(task))
    if objective_rows is not None:
        return objective_rows(task, configuration)
    compiled = _COMPILED_RESIDUALS.get(type(task))
    residual = None if compiled is None else compiled(task, configuration)
    if residual is None:
        return None
    # (the engine's residual: (3, nv) rows, (3,) error and a float mu, checked inputs; the
    # cost its (3,) array: the general checks of task_rows would pass)
    if residual[2] < 0.0:  # (an lm_damping set below 0 directly)
        raise TaskDefinitionError(
            f"{type(task).__name__}: its LM damping term must be one number >= 0, got "
            f"{residual[2]!r} (an lm_damping set to what does not fit?)"
        )
    return residual[0], residual[1], residual[2], task.cost  # type: ignore[attr-defined]


def task_rows(
    task: BaseTask, configuration: Configuration
) -> tuple[np.ndarray, np.ndarray, float | None, np.ndarray]:
    """One task's weighted rows ``(A, b, mu, weights)`` as :func:`level_rows` stacks them:
    its ``compute_qp_residual`` (``mu`` its LM term), or, for a task that only provides
    ``(H, c)``, the factor ``H = A^T A``, ``A^T b = -c`` (unit weights, ``mu`` None: no
    term); a :class:`SuppliedRows` task's :meth:`~SuppliedRows.rows_now`. The compiled
    step's rows supplied by a task (:mod:`.compiled`) are these arrays."""
    if isinstance(task, SuppliedRows):
        try:
            return task.rows_now(configuration)
        except (mink.MinkError, ValueError, TypeError) as exc:
            _raise_rows_failure(exc, task.label)
    _check_read_values(task)
    rows = _engine_rows(task, configuration)
    if rows is not None:
        return rows
    residual = objective = None
    try:  # an overflow (a target near 1e150 or beyond): the finiteness checks report it
        with np.errstate(over="ignore"):
            residual = task.compute_qp_residual(configuration)
            objective = None if residual is not None else task.compute_qp_objective(configuration)
    except (mink.MinkError, ValueError, TypeError) as exc:
        _raise_rows_failure(exc, f"{type(task).__name__}: its rows")
    if objective is not None:
        H, c = objective
        with np.errstate(over="ignore", invalid="ignore"):
            symmetric = 0.5 * (H + H.T)
        if not (np.isfinite(symmetric).all() and np.isfinite(c).all()):
            raise TaskDefinitionError(
                f"{type(task).__name__}: its objective (H, c) is not finite (a cost, gain or "
                "time step out of range?)"
            )
        return _objective_rows(symmetric, c, type(task).__name__)
    assert residual is not None  # objective is None only when a residual was given
    jacobian, error, task_mu = residual
    # (a NaN: its error is, which the finiteness checks report as the target's)
    if task_mu is not None and (np.ndim(task_mu) != 0 or float(task_mu) < 0.0):
        raise TaskDefinitionError(
            f"{type(task).__name__}: its LM damping term must be one number >= 0, got "
            f"{task_mu!r} (an lm_damping set to what does not fit?)"
        )
    if jacobian.ndim != 2:
        jacobian, error = np.atleast_2d(jacobian), np.atleast_1d(error)
    nv = configuration.model.nv
    if jacobian.ndim != 2 or jacobian.shape[1] != nv or np.shape(error) != (jacobian.shape[0],):
        raise TaskDefinitionError(
            f"{type(task).__name__}: its rows are of shape {jacobian.shape} and its error "
            f"{np.shape(error)}; ({jacobian.shape[0]}, {nv}) and ({jacobian.shape[0]},) "
            "expected (a cost or gain set to what does not fit?)"
        )
    return jacobian, error, task_mu, _row_weights(task, jacobian.shape[0])


def level_rows(
    tasks: Sequence[BaseTask], configuration: Configuration, nv: int
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Stacked weighted residual of a level ``(A, b, mu, weights)``: the objective is
    ``1/2 |A dq - b|^2 + 1/2 mu |dq|^2``; ``weights`` are the rows' costs.

    Each task's rows are :func:`task_rows`'s (tasks that only provide ``(H, c)`` factored as
    ``H = A^T A``, ``A^T b = -c``, unit weights). Every row is kept, zero rows included.
    """
    A_parts, b_parts, w_parts = [], [], []
    mu = 0.0
    for task in tasks:
        A, b, task_mu, w = task_rows(task, configuration)
        A_parts.append(A)
        b_parts.append(b)
        w_parts.append(w)
        if task_mu is not None:
            mu += float(task_mu)
    if len(A_parts) == 1:
        return A_parts[0], b_parts[0], mu, w_parts[0]
    A = np.vstack(A_parts) if A_parts else np.zeros((0, nv))
    b = np.concatenate(b_parts) if b_parts else np.zeros(0)
    w = np.concatenate(w_parts) if w_parts else np.zeros(0)
    return A, b, mu, w


@dataclass(frozen=True)
class TaskRows:
    """Every level's rows stacked as the core's cascade takes them (float64, C-contiguous):
    level ``k`` is rows ``starts[k]:starts[k + 1]`` of ``A`` (M, nv), ``b`` and ``w`` (the
    rows' costs) (M,), with the constant Tikhonov term ``reg[k]`` (``damping`` plus its
    tasks' LM terms)."""

    A: np.ndarray
    b: np.ndarray
    w: np.ndarray
    starts: np.ndarray
    reg: np.ndarray


def stack_rows(
    levels: Sequence[Sequence[BaseTask]], configuration: Configuration, nv: int, damping: float
) -> TaskRows:
    """The :class:`TaskRows` of ``levels`` at ``configuration``; raises
    :class:`qpik.InvalidConfiguration` where its ``q`` is not finite, else
    :class:`qpik.InvalidTarget` naming the first level whose rows are not finite."""
    A_parts, b_parts, w_parts = [], [], []
    L = len(levels)
    starts = np.zeros(L + 1, dtype=np.int64)
    reg = np.empty(L)
    for k, tasks in enumerate(levels):
        A, b, mu, w = level_rows(tasks, configuration, nv)
        A_parts.append(A)
        b_parts.append(b)
        w_parts.append(w)
        starts[k + 1] = starts[k] + b.shape[0]
        reg[k] = damping + mu
    A = np.concatenate(A_parts) if L > 1 else np.ascontiguousarray(A_parts[0], dtype=float)
    b = np.concatenate(b_parts) if L > 1 else np.ascontiguousarray(b_parts[0], dtype=float)
    w = np.concatenate(w_parts) if L > 1 else np.ascontiguousarray(w_parts[0], dtype=float)
    rows = TaskRows(A, b, w, starts, reg)
    with np.errstate(over="ignore"):  # the squares overflow only on rows near 1e150
        square = float(b @ b)
    if not (math.isfinite(square) and math.isfinite(float(A.sum()))) or not (
        math.isfinite(float(reg.sum()))
    ):
        _raise_not_finite(levels, rows, configuration)
    return rows


def _raise_not_finite(
    levels: Sequence[Sequence[BaseTask]], rows: TaskRows, configuration: Configuration
) -> None:
    """Name the configuration where its ``q`` is not finite (a mink one filled with NaN:
    :class:`qpik.InvalidConfiguration`), else the first level whose rows or regularisation
    are not finite."""
    configuration._validated(configuration.q)
    for k, tasks in enumerate(levels):
        s0, s1 = rows.starts[k], rows.starts[k + 1]
        finite = np.isfinite(rows.A[s0:s1]).all() and np.isfinite(rows.b[s0:s1]).all()
        if not (finite and math.isfinite(rows.reg[k])):
            raise InvalidTarget(
                f"priority level {k}: a task error or Jacobian is not finite (a NaN "
                f"or inf target?) in {', '.join(type(t).__name__ for t in tasks)}"
            )
