"""One compiled call per differential IK step, for the stacks that allow it.

When every task of a stack is a frame, posture or damping task (qpik's
:class:`~qpik.tasks.FrameTask` / :class:`~qpik.tasks.PostureTask` /
:class:`~qpik.tasks.DampingTask`, or mink's classes of the same names) and every limit
is mink's ``ConfigurationLimit`` / ``VelocityLimit`` (or ``CollisionAvoidanceLimit``,
whose general rows come from its own methods and go to the core's cascade: two compiled
calls then, see ``IKSolver._fused_general_step``) on a model of hinge and slide joints,
:class:`qpik.IKSolver` does in Python only what needs MuJoCo (one ``mj_jac*`` call per
frame task) and copies the tasks' targets and costs into preallocated arrays;
:func:`fused_step` then computes every task's rows (frame errors by the SE(3) routines of
:mod:`qpik.tasks._lie`, mink's own arithmetic; mink's own FrameTask gets the same rows as
qpik's, equal to mink's to round-off), the box limits, and the whole cascade
(:func:`qpik.core._kernels.solve_cascade`), in C++ (``qpik/_cpp/diffik/fused.hpp``).

It computes exactly what the general path computes (same arithmetic in the same order:
tests compare the two bitwise); anything unusual (a non-finite row, conflicting limits, a
level whose active set did not settle) is handed back to the general path, which reports
or recovers it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import mink
import mujoco
import numpy as np

from ._engine import diffik as _engine
from .errors import TargetNotSet
from .tasks.fast import DampingTask, FrameTask, PostureTask

__all__ = ["FusedPlan", "box_of", "fused_rows", "fused_step", "make_plan"]

_KINDS = {"site": 0, "body": 1, "geom": 2}
_OBJECTS = (mujoco.mjtObj.mjOBJ_SITE, mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_GEOM)
_JACOBIAN = (mujoco.mj_jacSite, mujoco.mj_jacBody, mujoco.mj_jacGeom)
_FRAME, _POSTURE = 0, 1
#: Frame tasks computed in C++: qpik's, and mink's own class (same rows, mink's SE(3)
#: arithmetic; equal to mink's to round-off). Exact types: a subclass may change the rows.
_FRAME_TYPES = (FrameTask, mink.FrameTask)
#: Posture-like tasks: mink's/qpik's PostureTask (rows ``diag(cost)``, error ``q - q*`` on
#: hinge/slide joints) and DampingTask (the same toward the current ``q``: error zero).
_POSTURE_TYPES = (PostureTask, mink.PostureTask)
_DAMPING_TYPES = (DampingTask, mink.DampingTask)

# Result codes of fused_step: anything but OK sends the step to the general path.
OK, NOT_FINITE, CONFLICT, UNSETTLED = 0, 1, 2, 3
assert (OK, NOT_FINITE, CONFLICT, UNSETTLED) == (
    _engine.OK, _engine.NOT_FINITE, _engine.CONFLICT, _engine.UNSETTLED
)  # fmt: skip
#: ``settings`` entries of :func:`fused_step`.
DT, DAMPING, THRESHOLD, MAX_DAMPING, ERROR_SCALE, RANK_TOL, TOL = range(7)

# The compiled kernels (qpik/_cpp/diffik/fused.hpp, bound in qpik._engine.diffik). Arrays
# written into (A, b, w) must be float64 C-contiguous of the plan's shapes (never copied);
# the other arrays are used in place when they are float64 / int64 / int8 C-contiguous.
#
# fused_step(A, b, w, starts, tasks, jac, frames, site_xpos, site_xmat, xpos, xmat,
#            geom_xpos, geom_xmat, frame_data, qpos, posture_data, cfg_dof, cfg_data,
#            vel_dof, vel_limit, settings, max_iter, warm, canonical)
#       -> (code, dq, v, info, active)
#   Rows of every task, the limits' box and the cascade, in one call (one function on
#   purpose: each check that sends the step to the general path sits where its data is).
#   ``A, b, w`` (M, nv), (M,), (M,) are filled (level ``k`` in rows ``starts[k]:starts[k+1]``).
#   ``tasks`` (T, 4) lists the tasks in stack order: kind (0 frame, 1 posture), index into
#   the frame or posture arrays, level, first row. Frame ``f``: ``jac[f]`` its world-aligned
#   Jacobian (6, nv); ``frames[f]`` (kind 0/1/2 site/body/geom, id) picks its pose;
#   ``frame_data[f]`` = target ``wxyz_xyz`` (7), cost (6), gain, lm_damping. Posture ``p``:
#   ``posture_data[p]`` = target (nq), cost (nv), gain, lm_damping. Position limits:
#   ``cfg_dof`` and ``cfg_data`` rows (lower, upper, gain); velocity limits ``vel_dof``,
#   ``vel_limit`` [per s]. ``settings``: see ``DT, DAMPING, ...``. ``warm`` (L, nv) int8:
#   the previous active sets; ``canonical``: warm starting on.
#   ``code`` OK or why the general path must answer; ``info`` (5, L) rows: residual,
#   sigma, lambda^2, status, iterations; ``active`` (L, nv) int8.
# fused_rows(<fused_step's first 21 arguments>) -> (code, reg, lb, ub)
#   The hierarchy's rows and limits without solving it: fills ``A, b, w``; ``code`` OK,
#   NOT_FINITE (a row or regularisation) or CONFLICT (velocity-like limits of a dof).
# _boxes(qpos, dt, cfg_dof, cfg_lower, cfg_upper, cfg_gain, vel_dof, vel_limit, n)
#       -> (lb, ub, i)
#   The limits' box, as :meth:`qpik.IKSolver._limit_rows` builds it: position bounds
#   ``gain (upper - q)``, ``-gain (q - lower)`` (recoverable), velocity bounds
#   ``|dq| <= v_max dt`` (hard), merged by :func:`qpik.core._kernels.merge_boxes`.
fused_step = _engine.fused_step
fused_rows = _engine.fused_rows
_boxes = _engine.boxes


def box_of(plan: FusedPlan, qpos: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The limits' merged box ``(lb, ub)`` of a plan at ``qpos`` for a step of ``dt``."""
    a = plan.arrays
    cfg = a["cfg_data"]
    lb, ub, _ = _boxes(
        qpos, dt, a["cfg_dof"], cfg[:, 0], cfg[:, 1], cfg[:, 2], a["vel_dof"], a["vel_limit"],
        qpos.shape[0],
    )  # fmt: skip
    return lb, ub


@dataclass
class FusedPlan:
    """Preallocated arrays and the task/limit bookkeeping of :func:`fused_step` for one
    stack (built once per :class:`qpik.IKSolver`)."""

    model: mujoco.MjModel
    frames: list  # (task, jacobian function, id, position rows, rotation rows, data row)
    postures: list  # (task, data row, damping: target is the current q)
    config_limits: list  # (limit, first entry, last entry)
    general_limits: list  # limits whose rows G dq <= h are computed by their own methods
    arrays: dict
    kinds_used: tuple
    cold: np.ndarray  # (L, nv) int8 zeros: a cold start's active sets (never written)
    max_iter: int  # the core's cap on active-set changes per level
    law: object = field(default_factory=object)  # the law ``arrays["settings"]`` holds

    def __post_init__(self) -> None:
        a = self.arrays
        #: fused_step's / fused_rows' arguments before the poses and after ``qpos``.
        self.head = (a["A"], a["b"], a["w"], a["starts"], a["tasks"], a["jac"], a["frames"])
        self.frame_data = a["frame_data"]
        self.tail = (
            a["posture_data"], a["cfg_dof"], a["cfg_data"], a["vel_dof"], a["vel_limit"]
        )  # fmt: skip

    def _gather_frames(self, data: mujoco.MjData) -> None:
        """Frame tasks' targets, costs, gains and MuJoCo Jacobians into the plan."""
        model = self.model
        for task, jacobian, fid, jp, jr, row in self.frames:
            pose = task.transform_target_to_world
            if pose is None:
                raise TargetNotSet(type(task).__name__)
            row[0:7] = pose.wxyz_xyz
            row[7:13] = task.cost
            row[13] = task.gain
            row[14] = task.lm_damping
            jacobian(model, data, jp, jr, fid)

    def gather(self, configuration) -> tuple:
        """Copy the tasks' current targets, costs and gains and the frames' Jacobians
        (MuJoCo) into the plan's arrays; returns ``(qpos, poses)`` for
        :func:`fused_step`."""
        model, data = self.model, configuration.data
        self._gather_frames(data)
        nq, nv = model.nq, model.nv
        for task, row, damping in self.postures:
            if damping:
                row[0:nq] = data.qpos
            elif task.target_q is None:
                raise TargetNotSet(type(task).__name__)
            else:
                row[0:nq] = task.target_q
            row[nq : nq + nv] = task.cost
            row[nq + nv] = task.gain
            row[nq + nv + 1] = task.lm_damping
        if self.config_limits:
            cfg = self.arrays["cfg_data"]
            for limit, e0, e1 in self.config_limits:
                cfg[e0:e1, 2] = limit.gain
        empty3, empty9 = self.arrays["empty3"], self.arrays["empty9"]
        site, body, geom = self.kinds_used
        poses = (
            data.site_xpos if site else empty3,
            data.site_xmat if site else empty9,
            data.xpos if body else empty3,
            data.xmat if body else empty9,
            data.geom_xpos if geom else empty3,
            data.geom_xmat if geom else empty9,
        )
        return data.qpos, poses


def make_plan(
    model: mujoco.MjModel,
    levels: Sequence[Sequence],
    limits: Sequence,
    scalar_joints: bool,
    rank_tolerance: float,
    tolerance: float,
    max_iter: int,
) -> FusedPlan | None:
    """The :class:`FusedPlan` of a stack, or None when a task or limit is not one that
    :func:`fused_step` computes (the general path then serves every step)."""
    if not scalar_joints:
        return None
    layout = _task_layout(model, levels)
    boxes = _limit_boxes(limits)
    if layout is None or boxes is None:
        return None
    nv = model.nv
    frames, postures, tasks, frame_rows, starts = layout
    cfg_dof, cfg_data, config_limits, vel_dof, vel_limit, general_limits = boxes
    F, P, M = len(frames), len(postures), starts[-1]
    jac = np.zeros((F, 6, nv))
    frame_data = np.zeros((F, 15))
    posture_data = np.zeros((P, model.nq + nv + 2))
    arrays = {
        "A": np.zeros((M, nv)),
        "b": np.zeros(M),
        "w": np.zeros(M),
        "starts": np.asarray(starts, dtype=np.int64),
        "tasks": np.asarray(tasks, dtype=np.int64).reshape(-1, 4),
        "jac": jac,
        "frames": np.asarray(frame_rows, dtype=np.int64).reshape(-1, 2),
        "frame_data": frame_data,
        "posture_data": posture_data,
        "cfg_dof": np.asarray(cfg_dof, dtype=np.int64),
        "cfg_data": np.asarray(cfg_data, dtype=float).reshape(-1, 3),
        "vel_dof": np.asarray(vel_dof, dtype=np.int64),
        "vel_limit": np.asarray(vel_limit, dtype=float),
        "settings": np.zeros(7),
        "empty3": np.zeros((0, 3)),
        "empty9": np.zeros((0, 9)),
    }
    frames = [
        (task, fn, fid, jac[f, :3], jac[f, 3:], frame_data[f])
        for f, (task, fn, fid) in enumerate(frames)
    ]
    postures = [
        (task, posture_data[p], type(task) in _DAMPING_TYPES) for p, task in enumerate(postures)
    ]
    used = tuple(any(kind == k for kind, _ in frame_rows) for k in range(3))
    settings = arrays["settings"]
    settings[RANK_TOL], settings[TOL] = rank_tolerance, tolerance
    cold = np.zeros((len(levels), nv), dtype=np.int8)
    return FusedPlan(
        model, frames, postures, config_limits, general_limits, arrays, used, cold, max_iter
    )  # fmt: skip


def _frame_entry(model: mujoco.MjModel, task) -> tuple[int, int] | None:
    """``(kind, id)`` of a FrameTask's frame, None when the general path must serve it
    (an unknown frame type or name: it reports them)."""
    kind = _KINDS.get(getattr(task.frame_type, "value", task.frame_type))
    if kind is None:
        return None
    fid = mujoco.mj_name2id(model, _OBJECTS[kind], task.frame_name)
    return None if fid < 0 else (kind, fid)


def _task_layout(model: mujoco.MjModel, levels: Sequence[Sequence]):
    """``(frames, postures, tasks, frame_rows, starts)`` of a stack whose tasks are all
    FrameTask / PostureTask / DampingTask (qpik's or mink's, exact types; postures on
    hinge/slide joints only), None otherwise: rows are laid out level by level, task by
    task."""
    frames, postures, tasks, frame_rows = [], [], [], []
    starts = [0]
    for k, level in enumerate(levels):
        row = starts[-1]
        for task in level:
            if type(task) in _FRAME_TYPES:
                entry = _frame_entry(model, task)
                if entry is None:
                    return None
                tasks.append((_FRAME, len(frames), k, row))
                frames.append((task, _JACOBIAN[entry[0]], entry[1]))
                frame_rows.append(entry)
                row += 6
            elif _scalar_posture(model, task):
                tasks.append((_POSTURE, len(postures), k, row))
                postures.append(task)
                row += model.nv
            else:
                return None
        starts.append(row)
    return frames, postures, tasks, frame_rows, starts


def _scalar_posture(model: mujoco.MjModel, task) -> bool:
    """Whether a task is a posture or damping task (qpik's or mink's, exact type) on a
    model of hinge/slide joints, whose rows :func:`fused_step` computes."""
    kind = type(task)
    if kind not in _POSTURE_TYPES and kind not in _DAMPING_TYPES:
        return False
    return (
        model.nq == model.nv
        and getattr(task, "_v_ids", None) is None
        and (getattr(task, "cost", None) is not None and np.shape(task.cost) == (model.nv,))
    )


#: Limits of general rows ``G dq <= h`` that a plan takes (their rows from their own
#: methods each step, the cascade in one compiled call; exact types).
_GENERAL_LIMITS = (mink.CollisionAvoidanceLimit,)


def _limit_boxes(limits: Sequence):
    """``(cfg_dof, cfg_data, config_limits, vel_dof, vel_limit, general_limits)`` of mink's
    position and velocity limits and its collision avoidance limits (None when another
    limit is present)."""
    cfg_dof, cfg_data, config_limits, vel_dof, vel_limit = [], [], [], [], []
    general_limits = []
    for limit in limits:
        if type(limit) is mink.ConfigurationLimit:
            indices = np.asarray(limit.indices, dtype=np.int64)
            e0 = len(cfg_dof)
            cfg_dof.extend(indices.tolist())
            lower, upper = np.asarray(limit.lower)[indices], np.asarray(limit.upper)[indices]
            cfg_data.extend(zip(lower.tolist(), upper.tolist(), [0.0] * len(indices)))
            config_limits.append((limit, e0, len(cfg_dof)))
        elif type(limit) is mink.VelocityLimit:
            vel_dof.extend(np.asarray(limit.indices, dtype=np.int64).tolist())
            vel_limit.extend(np.asarray(limit.limit, dtype=float).tolist())
        elif type(limit) in _GENERAL_LIMITS:
            general_limits.append(limit)
        else:
            return None
    return cfg_dof, cfg_data, config_limits, vel_dof, vel_limit, general_limits
