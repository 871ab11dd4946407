"""One compiled call per differential IK step, for the stacks that allow it.

When every task of a stack is one of qpik's built-in :class:`~qpik.tasks.FrameTask` /
:class:`~qpik.tasks.PostureTask` and every limit is mink's ``ConfigurationLimit`` /
``VelocityLimit`` on a model of hinge and slide joints, :class:`qpik.IKSolver` does in
Python only what needs MuJoCo (one ``mj_jac*`` call per frame task) and copies the tasks'
targets and costs into preallocated arrays; :func:`fused_step` then computes every task's
rows (frame errors by the SE(3) routines of :mod:`qpik.tasks._lie`, mink's own arithmetic),
the box limits, and the whole cascade (:func:`qpik.core._kernels.solve_cascade`).

It computes exactly what the general path computes (same arithmetic in the same order:
tests compare the two bitwise); anything unusual (a non-finite row, conflicting limits, a
level whose active set did not settle) is handed back to the general path, which reports
or recovers it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mink
import mujoco
import numpy as np
from numba import njit

from .core import _kernels
from .core._cache import drop_stale_cache
from .core._kernels import merge_boxes, solve_cascade
from .errors import TargetNotSet
from .tasks import _lie
from .tasks.fast import FrameTask, PostureTask

# The kernels below call the core's and the Lie routines: numba's cache would not notice
# an edit there.
drop_stale_cache(__file__, [_kernels.__file__, _lie.__file__])

__all__ = ["FusedPlan", "fused_step", "make_plan"]

_KINDS = {"site": 0, "body": 1, "geom": 2}
_JACOBIAN = (mujoco.mj_jacSite, mujoco.mj_jacBody, mujoco.mj_jacGeom)
_POSE_FIELDS = (("site_xpos", "site_xmat"), ("xpos", "xmat"), ("geom_xpos", "geom_xmat"))
_FRAME, _POSTURE = 0, 1


@njit(cache=True)
def _frame_rows(A, b, row, jac, xpos, xmat, target, cost, gain, lm_damping):
    """Rows ``row:row+6`` of a frame task (see :func:`qpik.tasks.fast._frame_rows`);
    returns its LM term ``lm_damping |b|^2``."""
    nv = jac.shape[1]
    frame = np.empty(7)
    _lie.xmat_xpos_to_wxyz_xyz(frame, xmat, xpos)
    error = np.empty(6)
    _lie.se3_rminus(error, target, frame)
    relative = np.empty(7)
    _lie.se3_inverse_multiply(relative, target, frame)
    jlog = np.empty((6, 6))
    _lie.se3_jlog(jlog, relative)
    local = np.empty((6, nv))
    for i in range(3):
        for j in range(nv):
            a = 0.0
            r = 0.0
            for k in range(3):
                a += xmat[3 * k + i] * jac[k, j]
                r += xmat[3 * k + i] * jac[3 + k, j]
            local[i, j] = a
            local[3 + i, j] = r
    mu = 0.0
    for i in range(6):
        for j in range(nv):
            acc = 0.0
            for k in range(6):
                acc += jlog[i, k] * local[k, j]
            A[row + i, j] = -cost[i] * acc
        b[row + i] = cost[i] * (-gain * error[i])
        mu += b[row + i] * b[row + i]
    return lm_damping * mu


@njit(cache=True)
def _posture_rows(A, b, row, qpos, target, cost, gain, lm_damping):
    """Rows ``row:row+nv`` of a posture task on hinge/slide joints: ``A = diag(cost)``,
    ``b = cost (-gain (q - q*))``; returns ``lm_damping |b|^2``."""
    nv = qpos.shape[0]
    mu = 0.0
    for i in range(nv):
        for j in range(nv):
            A[row + i, j] = cost[i] * (1.0 if i == j else 0.0)
        b[row + i] = cost[i] * (-gain * (qpos[i] - target[i]))
        mu += b[row + i] * b[row + i]
    return lm_damping * mu


@njit(cache=True)
def _boxes(qpos, dt, cfg_dof, cfg_lower, cfg_upper, cfg_gain, vel_dof, vel_limit, n):
    """The limits' box, as :meth:`qpik.IKSolver._limit_rows` builds it: position bounds
    ``gain (upper - q)``, ``-gain (q - lower)`` (recoverable), velocity bounds
    ``|dq| <= v_max dt`` (hard), merged by :func:`merge_boxes`."""
    hard_lb = np.full(n, -np.inf)
    hard_ub = np.full(n, np.inf)
    pos_lb = np.full(n, -np.inf)
    pos_ub = np.full(n, np.inf)
    for e in range(cfg_dof.shape[0]):
        i = cfg_dof[e]
        q = qpos[i]
        upper = cfg_gain[e] * (cfg_upper[e] - q)
        lower = -cfg_gain[e] * (q - cfg_lower[e])
        if lower > pos_lb[i]:
            pos_lb[i] = lower
        if upper < pos_ub[i]:
            pos_ub[i] = upper
    for e in range(vel_dof.shape[0]):
        i = vel_dof[e]
        bound = vel_limit[e] * dt
        if -bound > hard_lb[i]:
            hard_lb[i] = -bound
        if bound < hard_ub[i]:
            hard_ub[i] = bound
    return merge_boxes(hard_lb, hard_ub, pos_lb, pos_ub)


@njit(cache=True)
def fused_step(
    A, b, w, starts, task_kind, task_index, task_level, task_row,
    jac, frame_kind, frame_id, site_xpos, site_xmat, xpos, xmat, geom_xpos, geom_xmat,
    frame_target, frame_cost, frame_scalars,
    qpos, posture_target, posture_cost, posture_scalars,
    cfg_dof, cfg_lower, cfg_upper, cfg_gain, vel_dof, vel_limit,
    dt, damping, threshold, max_damping, error_scale, rank_tol, max_iter, tol, warm, canonical,
):  # fmt: skip
    """Rows of every task, the limits' box and the cascade, in one call.

    ``A, b, w`` (M, nv), (M,), (M,) are filled (level ``k`` in rows
    ``starts[k]:starts[k+1]``); tasks are listed in stack order (``task_kind`` 0 frame,
    1 posture; ``task_index`` into the frame or posture arrays; ``task_level``,
    ``task_row`` their first row). Frame ``f``: ``jac[f]`` its world-aligned Jacobian
    (6, nv), ``frame_kind`` 0/1/2 site/body/geom and ``frame_id`` which pose row,
    ``frame_target[f]`` (7) ``wxyz_xyz``, ``frame_cost[f]`` (6), ``frame_scalars[f]``
    (gain, lm_damping). Posture ``p`` likewise on ``qpos``.

    Returns ``(ok, bad_dof, dq, status, sigma, lam2, iterations, active, residuals, reg,
    lb, ub)``: ``ok`` False when a row or regularisation is not finite, ``bad_dof >= 0``
    when the velocity-like limits of that dof conflict (both: nothing solved).
    """
    n = qpos.shape[0]
    L = starts.shape[0] - 1
    reg = np.zeros(L)
    for t in range(task_kind.shape[0]):
        i = task_index[t]
        row = task_row[t]
        if task_kind[t] == 0:
            kind = frame_kind[i]
            fid = frame_id[i]
            if kind == 0:
                pos, mat = site_xpos[fid], site_xmat[fid]
            elif kind == 1:
                pos, mat = xpos[fid], xmat[fid]
            else:
                pos, mat = geom_xpos[fid], geom_xmat[fid]
            cost = frame_cost[i]
            mu = _frame_rows(
                A, b, row, jac[i], pos, mat, frame_target[i], cost,
                frame_scalars[i, 0], frame_scalars[i, 1],
            )  # fmt: skip
            for r in range(6):
                w[row + r] = cost[r]
        else:
            cost = posture_cost[i]
            mu = _posture_rows(
                A, b, row, qpos, posture_target[i], cost,
                posture_scalars[i, 0], posture_scalars[i, 1],
            )  # fmt: skip
            for r in range(n):
                w[row + r] = cost[r]
        reg[task_level[t]] += mu
    for k in range(L):
        reg[k] = damping + reg[k]
    lb, ub, bad = _boxes(qpos, dt, cfg_dof, cfg_lower, cfg_upper, cfg_gain, vel_dof, vel_limit, n)
    total = 0.0
    square = 0.0
    for r in range(b.shape[0]):
        square += b[r] * b[r]
        for j in range(n):
            total += A[r, j]
    ok = np.isfinite(square) and np.isfinite(total) and np.isfinite(reg.sum())
    empty_G = np.zeros((0, n))
    empty_h = np.zeros(0)
    if not ok or bad >= 0:
        d = np.zeros(n)
        status = np.zeros(L, dtype=np.int64)
        return (ok, bad, d, status, np.zeros(L), np.zeros(L), np.zeros(L, dtype=np.int64),
                np.zeros((L, n), dtype=np.int8), np.zeros(L), reg, lb, ub)  # fmt: skip
    d, status, sigma, lam2, its, active, residuals = solve_cascade(
        A, b, w, starts, reg, lb, ub, empty_G, empty_h, threshold, max_damping, error_scale,
        rank_tol, max_iter, tol, warm, canonical,
    )  # fmt: skip
    return ok, bad, d, status, sigma, lam2, its, active, residuals, reg, lb, ub


@dataclass
class FusedPlan:
    """Preallocated arrays and the task/limit bookkeeping of :func:`fused_step` for one
    stack (built once per :class:`qpik.IKSolver`)."""

    model: mujoco.MjModel
    frames: list  # (task, jacobian function, frame id, position rows view, rotation rows view)
    postures: list
    config_limits: list  # (limit, first entry, last entry)
    arrays: dict

    def gather(self, configuration, dt: float) -> tuple:
        """Copy the tasks' current targets, costs and gains and the frames' Jacobians
        (MuJoCo) into the plan's arrays; the arguments of :func:`fused_step`."""
        a = self.arrays
        model, data = self.model, configuration.data
        target, cost, scalars = a["frame_target"], a["frame_cost"], a["frame_scalars"]
        for f, (task, jacobian, fid, jp, jr) in enumerate(self.frames):
            pose = task.transform_target_to_world
            if pose is None:
                raise TargetNotSet(type(task).__name__)
            target[f] = pose.wxyz_xyz
            cost[f] = task.cost
            scalars[f, 0] = task.gain
            scalars[f, 1] = task.lm_damping
            jacobian(model, data, jp, jr, fid)
        target, cost, scalars = a["posture_target"], a["posture_cost"], a["posture_scalars"]
        for p, task in enumerate(self.postures):
            if task.target_q is None:
                raise TargetNotSet(type(task).__name__)
            target[p] = task.target_q
            cost[p] = task.cost
            scalars[p, 0] = task.gain
            scalars[p, 1] = task.lm_damping
        gains = a["cfg_gain"]
        for limit, e0, e1 in self.config_limits:
            gains[e0:e1] = limit.gain
        poses = a["poses"]
        for kind, (position, rotation) in enumerate(_POSE_FIELDS):
            if a["kinds_used"][kind]:
                poses[2 * kind] = getattr(data, position)
                poses[2 * kind + 1] = getattr(data, rotation)
        return data.qpos, float(dt)


def make_plan(
    model: mujoco.MjModel, levels: Sequence[Sequence], limits: Sequence, scalar_joints: bool
) -> FusedPlan | None:
    """The :class:`FusedPlan` of a stack, or None when a task or limit is not one that
    :func:`fused_step` computes (the general path then serves every step)."""
    if not scalar_joints:
        return None
    nv = model.nv
    frames, postures = [], []
    kinds, index, level_of, rows = [], [], [], []
    starts = [0]
    frame_kind, frame_id = [], []
    for k, level in enumerate(levels):
        row = starts[-1]
        for task in level:
            if type(task) is FrameTask:
                kind = _KINDS.get(getattr(task.frame_type, "value", task.frame_type))
                if kind is None:
                    return None
                obj = (mujoco.mjtObj.mjOBJ_SITE, mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_GEOM)
                fid = mujoco.mj_name2id(model, obj[kind], task.frame_name)
                if fid < 0:
                    return None  # the general path reports the unknown frame
                kinds.append(_FRAME)
                index.append(len(frames))
                frames.append((task, _JACOBIAN[kind], fid))
                frame_kind.append(kind)
                frame_id.append(fid)
                size = 6
            elif type(task) is PostureTask and task._scalar:
                kinds.append(_POSTURE)
                index.append(len(postures))
                postures.append(task)
                size = nv
            else:
                return None
            level_of.append(k)
            rows.append(row)
            row += size
        starts.append(row)
    cfg_dof, cfg_lower, cfg_upper, config_limits = [], [], [], []
    vel_dof, vel_limit = [], []
    for limit in limits:
        if type(limit) is mink.ConfigurationLimit:
            indices = np.asarray(limit.indices, dtype=np.int64)
            e0 = len(cfg_dof)
            cfg_dof.extend(indices.tolist())
            cfg_lower.extend(np.asarray(limit.lower)[indices].tolist())
            cfg_upper.extend(np.asarray(limit.upper)[indices].tolist())
            config_limits.append((limit, e0, len(cfg_dof)))
        elif type(limit) is mink.VelocityLimit:
            vel_dof.extend(np.asarray(limit.indices, dtype=np.int64).tolist())
            vel_limit.extend(np.asarray(limit.limit, dtype=float).tolist())
        else:
            return None
    F, P, M = len(frames), len(postures), starts[-1]
    jac = np.zeros((F, 6, nv))
    frames = [(task, fn, fid, jac[f, :3], jac[f, 3:]) for f, (task, fn, fid) in enumerate(frames)]
    used = [kind in frame_kind for kind in range(3)]
    empty3, empty9 = np.zeros((0, 3)), np.zeros((0, 9))
    arrays = {
        "A": np.zeros((M, nv)),
        "b": np.zeros(M),
        "w": np.zeros(M),
        "starts": np.asarray(starts, dtype=np.int64),
        "task_kind": np.asarray(kinds, dtype=np.int64),
        "task_index": np.asarray(index, dtype=np.int64),
        "task_level": np.asarray(level_of, dtype=np.int64),
        "task_row": np.asarray(rows, dtype=np.int64),
        "jac": jac,
        "frame_kind": np.asarray(frame_kind, dtype=np.int64),
        "frame_id": np.asarray(frame_id, dtype=np.int64),
        "poses": [empty3, empty9, empty3, empty9, empty3, empty9],
        "kinds_used": used,
        "frame_target": np.zeros((F, 7)),
        "frame_cost": np.zeros((F, 6)),
        "frame_scalars": np.zeros((F, 2)),
        "posture_target": np.zeros((P, model.nq)),
        "posture_cost": np.zeros((P, nv)),
        "posture_scalars": np.zeros((P, 2)),
        "cfg_dof": np.asarray(cfg_dof, dtype=np.int64),
        "cfg_lower": np.asarray(cfg_lower, dtype=float),
        "cfg_upper": np.asarray(cfg_upper, dtype=float),
        "cfg_gain": np.zeros(len(cfg_dof)),
        "vel_dof": np.asarray(vel_dof, dtype=np.int64),
        "vel_limit": np.asarray(vel_limit, dtype=float),
    }
    return FusedPlan(model, frames, postures, config_limits, arrays)
