"""The per-step writers of a compiled plan (:mod:`.compiled`): each task's and limit's
current values (targets, costs, gains, LM damping; limits' bounds, gains and speeds)
written into its data row of the plan's arrays, checked as the QP path checks them (a
value that does not fit raises the typed error that names the task or limit), and the
guards on the task attributes a plan resolved when it was built (:func:`plan_guards`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import LimitDefinitionError, QpikError, TargetNotSet, TaskDefinitionError
from ..tasks.checked import check_gain, check_pose_target, pose_target_name
from ..tasks.secondary import ManipulabilityTask
from .boxes import limit_bounds, limit_values
from .constraints import FrameConstraint
from .layout import POSE_COST
from .rows import kinetic_scale

__all__ = [
    "guards_hold", "plan_guards", "user_task", "write_com_row", "write_equality_rows",
    "write_frame_row", "write_kinetic_rows", "write_limit_bounds", "write_limit_values",
    "write_linear_rows", "write_pose_row", "write_posture_row", "write_relative_row",
    "write_table_rows", "write_world_pose_row",
]  # fmt: skip


def _put(view: np.ndarray, value) -> None:
    """``value`` into ``view``, of ``view``'s shape exactly (no broadcasting: a scalar where
    a task keeps an array is refused as on the kernel's lean step and at the plan's build,
    with NumPy's ValueError, which the callers report as the task's)."""
    if type(value) is np.ndarray and value.shape == view.shape:  # (the usual case, fast)
        view[...] = value
        return
    array = np.asarray(value, dtype=float)
    if array.shape != view.shape:
        raise ValueError(f"a value of shape {array.shape} where its rows take {view.shape}")
    view[...] = array


def _gain(task):
    """A task's gain as written into its data row: :class:`qpik.InvalidGain` naming the
    task where it is a number outside [0, 1] (set after the task was built: mink's tasks
    take any; qpik's check it where it is set), as it is otherwise (what does not fit a
    row's entry is NumPy's error, reported by :func:`_unfit`)."""
    gain = task.gain
    check_gain(task, gain)
    return gain


def user_task(task):
    """The task an error names: a frame constraint's own task (the user's), else ``task``."""
    return task.task if type(task) is FrameConstraint else task


def write_pose_row(views: tuple, task, pose) -> None:
    """A frame-like task's target ``pose`` (wxyz_xyz), cost, gain and LM damping into its
    data row (15; the views of :func:`qpik.diffik.plan.make_plan`)."""
    # (a frame constraint's messages name the user's task; its gain is taken as it is, as
    # mink takes a constraint's: no row of a task of qpik's checks it)
    named = user_task(task)
    if pose is None:
        raise TargetNotSet(type(named).__name__)
    check_pose_target(named, pose, pose_target_name(named))
    row, target, cost = views
    _put(target, pose.wxyz_xyz)
    _put(cost, task.cost)
    row[13] = _gain(task) if named is task else task.gain
    row[14] = task.lm_damping


def write_world_pose_row(views: tuple, task, names: tuple) -> None:
    """A world-frame pose task's targets, cost, gain and LM damping into its data row
    (``POSE_DATA`` wide; the views of :func:`qpik.diffik.plan.make_plan`, its targets'
    views in the order of their attribute ``names``, :data:`POSE_TARGETS`)."""
    row, targets, cost = views
    for name, view in zip(names, targets, strict=True):
        value = getattr(task, name)
        if value is None:
            raise TargetNotSet(type(task).__name__)
        _put(view, np.reshape(value, -1))  # (no broadcasting: a number is not a vector)
    _put(cost, task.cost)
    row[POSE_COST + 6] = _gain(task)
    row[POSE_COST + 7] = task.lm_damping


def _unfit(task, exc: Exception) -> Exception:
    """What a task's values that do not fit its rows raise: ``exc`` itself where it is
    qpik's, else TaskDefinitionError naming the task (NumPy's ValueError or TypeError from
    an attribute set directly to the wrong shape or type)."""
    if isinstance(exc, QpikError):
        return exc
    task = user_task(task)
    name = getattr(task, "frame_name", None)
    label = type(task).__name__ + ("" if name is None else f" {name!r}")
    return TaskDefinitionError(
        f"{label}: its target, cost, gain or lm_damping does not fit its rows ({exc})"
    )


def write_frame_row(views: tuple, task, names: tuple | None) -> None:
    """A frame's data row: :func:`write_pose_row` of a frame task's target (``names``
    None), else :func:`write_world_pose_row`."""
    try:
        if names is None:
            write_pose_row(views, task, task.transform_target_to_world)
        else:
            write_world_pose_row(views, task, names)
    except (ValueError, TypeError) as exc:  # an attribute set to what does not fit its rows
        raise _unfit(task, exc) from exc


def write_relative_row(views: tuple, task) -> None:
    """A relative frame task's data row (:func:`write_pose_row` of its target in its root)."""
    try:
        write_pose_row(views, task, task.transform_target_to_root)
    except (ValueError, TypeError) as exc:
        raise _unfit(task, exc) from exc


def write_posture_row(views: tuple, task, damping: bool) -> None:
    """A posture or damping task's target (none for a damping task: its error is zero),
    costs, gain and LM damping into its data row ``views = (row, target, cost)``."""
    row, target_view, cost_view = views
    try:
        if not damping:
            target = task.target_q
            if target is None:
                raise TargetNotSet(type(task).__name__)
            _put(target_view, target)
        _put(cost_view, task.cost)
        row[-2] = _gain(task)
        row[-1] = task.lm_damping
    except (ValueError, TypeError) as exc:
        raise _unfit(task, exc) from exc


#: The attributes a plan resolves to frame ids when it is built, per kind of task.
_FRAME_ATTRIBUTES = ("frame_name", "frame_type")
_RELATIVE_ATTRIBUTES = (*_FRAME_ATTRIBUTES, "root_name", "root_type")


def plan_guards(frames: Sequence, relatives: Sequence, coms: Sequence) -> list[tuple]:
    """``(task, name, value)`` of every task attribute a plan resolved when it was built
    (the frame and root attributes it made frame ids of, a manipulability task's ``rows``,
    a CoM task's subtree ``body`` as given), from its ``frames``, ``relatives`` and ``coms``
    entries (the task first): a step where one changed is no longer the plan's
    (:func:`guards_hold`; the kernel checks the same, ``Kernel.set_guards``), and the QP
    path answers for the task as it is."""
    guards = [(f[0], n, getattr(f[0], n)) for f in frames for n in _FRAME_ATTRIBUTES]
    # (a manipulability task's rows: their indices are in its data row, written once)
    picks = [f[0] for f in frames if type(f[0]) is ManipulabilityTask]
    guards += [(task, "rows", task.rows) for task in picks]
    guards += [(r[0], n, getattr(r[0], n)) for r in relatives for n in _RELATIVE_ATTRIBUTES]
    return guards + [(c[0], "body", c[2]) for c in coms if c[2] is not None]


def guards_hold(guards: list[tuple]) -> bool:
    """Whether every guarded attribute is still its value (the same object, or equal)."""
    for task, name, value in guards:
        current = getattr(task, name, None)
        if current is value:
            continue
        try:
            if not bool(current == value):
                return False
        except (ValueError, TypeError):  # (an array, say: not the plan's name)
            return False
    return True


def write_limit_values(view: np.ndarray, limit, name: str) -> None:
    """A limit's ``name`` (a position limit's gain, one number for all its entries; a
    velocity limit's speeds [rad/s or m/s], one per entry) into ``view``, checked as the QP
    path checks them (:func:`qpik.diffik.boxes.limit_values`): LimitDefinitionError naming
    the limit where it does not fit or is out of range (nothing read for no entries, as the
    kernel and the QP path read nothing then)."""
    if view.size == 0:
        return
    value = limit_values(limit)
    try:
        if name == "gain":
            view[...] = float(value)
        else:
            _put(view, value)
    except (ValueError, TypeError) as exc:
        raise LimitDefinitionError(
            f"{type(limit).__name__}: its {name} does not fit its rows ({exc})"
        ) from exc


def write_limit_bounds(view: np.ndarray, limit, qadr: np.ndarray) -> None:
    """A position limit's bounds (``lower``, ``upper`` [rad or m]) at its dofs' qpos entries
    ``qadr`` into the columns of ``view`` ``(E, 2)``, checked as the QP path checks them
    (:func:`qpik.diffik.boxes.limit_bounds`: LimitDefinitionError or InfeasibleLimits)."""
    view[:, 0], view[:, 1] = limit_bounds(limit, qadr)


def write_com_row(views: tuple, task) -> None:
    """A CoM task's target, costs, gain and LM damping into its data row
    ``views = (row, target, cost)``."""
    row, target_view, cost_view = views
    try:
        target = task.target_com
        if target is None:
            raise TargetNotSet(type(task).__name__)
        _put(target_view, target)
        _put(cost_view, task.cost)
        row[6] = _gain(task)
        row[7] = task.lm_damping
    except (ValueError, TypeError) as exc:
        raise _unfit(task, exc) from exc


def write_linear_rows(linears: Sequence, lin: np.ndarray) -> bool:
    """The linear tasks' costs, gains and LM damping (``linears``: ``(task, first column,
    cost view)``) into ``lin`` (the plan's ``lin_data``); False where one does not fit (the
    QP path then answers, and reports it)."""
    for task, r0, cost_view in linears:
        cost = task.cost
        if type(cost) is not np.ndarray or cost.shape != cost_view.shape:
            return False
        cost_view[...] = cost
        try:
            lin[1:, r0] = task.gain, task.lm_damping
        except (TypeError, ValueError):
            return False
    return True


def write_kinetic_rows(kinetics: Sequence) -> bool:
    """The kinetic-energy tasks' cost and ``1 / dt^2`` (``kinetics``: ``(task, its ke_data
    row)``); False where one is not a number (no time step set: the QP path then answers,
    and the task's own methods report it)."""
    for task, row in kinetics:
        if kinetic_scale(task) is None:
            return False
        row[:] = task.cost, task.inv_dt_sq
    return True


def write_equality_rows(equalities: Sequence) -> bool:
    """The equality-constraint tasks' costs by position (mink's ``_cost``), gains and LM
    damping (``equalities``: ``(task, its eq_data row)``); a gain outside [0, 1] raises
    :class:`qpik.InvalidGain`; False where a value does not fit (the QP path then answers,
    and reports it)."""
    for task, row in equalities:
        cost = getattr(task, "_cost", None)
        if not (isinstance(cost, np.ndarray) and cost.ndim == 1 and cost.shape[0] <= row.size - 2):
            return False
        try:
            row[: cost.shape[0]] = cost
            row[-2], row[-1] = _gain(task), task.lm_damping
        except (TypeError, ValueError):
            return False
    return True


def write_table_rows(plan) -> bool:
    """A plan's linear, kinetic-energy and equality-constraint tasks' values
    (:func:`write_linear_rows`, :func:`write_kinetic_rows`, :func:`write_equality_rows`);
    False where one does not fit."""
    if plan.linears and not write_linear_rows(plan.linears, plan.arrays["lin_data"]):
        return False
    if plan.kinetics and not write_kinetic_rows(plan.kinetics):
        return False
    return not plan.equalities or write_equality_rows(plan.equalities)
