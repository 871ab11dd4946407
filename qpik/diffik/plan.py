"""How a stack becomes a compiled step: :func:`make_plan` builds the
:class:`~qpik.diffik.compiled.CompiledPlan` of one :class:`qpik.IKSolver` (its arrays, laid
out by :mod:`.layout`, the views the plan writes through, and the compiled
:class:`~qpik.diffik.compiled.Kernel` over them), or None when a task or limit is not one
the kernel computes."""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from ..core import HierarchySolver
from ..model.gradients import dof_thresholds
from ..model.inertia import inertia_tree
from ..tasks.secondary import ManipulabilityTask
from .boxes import LimitBoxes
from .compiled import RANK_TOL, TOL, CompiledPlan, Kernel
from .layout import (
    DAMPING_TYPES,
    JACOBIANS,
    POSE_COST,
    POSE_KINDS,
    POSE_TARGETS,
    limit_layout,
    plan_arrays,
    task_layout,
)

__all__ = ["make_plan"]


def _views(row: np.ndarray, size: int, cost: int) -> tuple:
    """A task's data row with its target ``row[:size]`` and cost ``row[size:size + cost]``
    as views (writing into a held view is cheaper than slicing each step)."""
    return row, row[:size], row[size : size + cost]


def _frame_views(task, row: np.ndarray) -> tuple:
    """``(views, names)`` of a frame's data row: :func:`_views` of a frame task's (target
    wxyz_xyz, cost (6), gain and LM damping at 13 and 14) and None; a world-frame pose
    task's ``(row, its targets' views, its cost's at POSE_COST)`` and its targets'
    attribute names (:data:`POSE_TARGETS`; gain and LM damping at ``POSE_COST + 6``, ``+ 7``)."""
    pose = POSE_KINDS.get(type(task))
    if pose is None:
        return _views(row, 7, 6), None
    entries = POSE_TARGETS[type(task)]
    views = tuple(row[a:b] for _, a, b in entries)
    return (row, views, row[POSE_COST : POSE_COST + pose[1]]), tuple(n for n, _, _ in entries)


def make_plan(
    model: mujoco.MjModel, levels: Sequence[Sequence], limits: LimitBoxes, core: HierarchySolver
) -> CompiledPlan | None:
    """The :class:`CompiledPlan` of a stack under ``limits`` solved as ``core`` solves
    (its rank tolerance, tolerance and iteration cap), or None when a task or limit is not
    one the kernel computes (the QP path then serves every step). The trust region of
    ``limits`` (:attr:`qpik.StepOptions.max_joint_speed`) is appended to the velocity
    limits' entries: the kernel bounds each of its dofs by ``speed dt``, a hard bound as a
    velocity limit's."""
    layout = task_layout(model, levels)
    boxes = limit_layout(model, limits.limits)
    if layout is None or boxes is None:
        return None
    arrays = plan_arrays(model, layout, boxes, limits)
    settings = arrays["settings"]
    settings[RANK_TOL], settings[TOL] = core.rank_tolerance, core.tolerance
    jac, frame_data, posture_data = arrays["jac"], arrays["frame_data"], arrays["posture_data"]
    com_jac, com_data = arrays["com_jac"], arrays["com_data"]
    rel_jac, rel_data = arrays["rel_jac"], arrays["rel_data"]
    frames = [
        (task, JACOBIANS[kind], fid, jac[f, :3], jac[f, 3:], *_frame_views(task, frame_data[f]))
        for f, (task, kind, fid) in enumerate(layout.frames)
    ]
    postures = [
        (task, _views(posture_data[p], model.nq, model.nv), type(task) in DAMPING_TYPES)
        for p, task in enumerate(layout.postures)
    ]
    coms = [
        (task, body, given, com_jac[c], _views(com_data[c], 3, 3))
        for c, (task, body, given) in enumerate(layout.coms)
    ]
    relatives = [
        (
            task,
            (JACOBIANS[f[0]], f[1]),
            (JACOBIANS[r[0]], r[1]),
            rel_jac[i],
            _views(rel_data[i], 7, 6),
        )
        for i, (task, f, r) in enumerate(layout.relatives)
    ]
    used = tuple(any(kind == k for (kind, _), _rel in layout.frame_rows) for k in range(3))
    cold = np.zeros((len(levels), model.nv), dtype=np.int8)
    a = arrays
    kernel = Kernel(
        a["A"], a["b"], a["w"], a["starts"], a["tasks"], a["jac"], a["frames"], a["frame_data"],
        a["posture_data"], a["posture_map"], a["cfg_dof"], a["cfg_qadr"], a["cfg_data"],
        a["vel_dof"], a["vel_limit"], a["settings"], a["com_jac"], a["com_body"], a["com_data"],
        a["rel_jac"], a["rel_frames"], a["rel_data"], model.nq, a["user_mu"], a["lin_starts"],
        a["lin_const"], a["lin_data"], a["ke_data"], a["eq_map"], a["eq_data"],
    )  # fmt: skip
    if any(  # (a manipulability task whose frame a ball or free joint moves: plan_arrays' flag)
        type(task) is ManipulabilityTask and a["frame_data"][f, POSE_COST + 1]
        for f, (task, *_) in enumerate(layout.frames)
    ):
        kernel.set_dof_thresholds(dof_thresholds(model))
    if layout.kinetics:  # (the model's tree: the kernel makes M(q) at each step)
        tree = inertia_tree(model)
        assert tree is not None  # (task_layout placed them only where it is)
        kernel.set_inertia(*tree)
    lin_starts = a["lin_starts"].tolist()
    linears = [
        (task, lin_starts[i], a["lin_data"][0, lin_starts[i] : lin_starts[i + 1]])
        for i, (task, _, _) in enumerate(layout.linears)
    ]
    return CompiledPlan(
        model, frames, postures, coms, relatives, boxes.config_limits, boxes.general_limits,
        arrays, used, cold, core.max_iter or 0, kernel, limits, rows_tasks=layout.rows_tasks,
        linears=linears, vel_limits=boxes.vel_limits,
        kinetics=list(zip(layout.kinetics, a["ke_data"])),
        equalities=[(task, a["eq_data"][q]) for q, (task, _, _) in enumerate(layout.equalities)],
    )  # fmt: skip
