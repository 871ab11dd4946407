"""One compiled call per differential IK step, for the stacks that allow it.

When every task of a stack is one the kernel knows (qpik's or mink's ``FrameTask``,
``PostureTask``, ``DampingTask``, ``ComTask``, and mink's ``RelativeFrameTask``; exact
types: a subclass may change the rows) and every limit is mink's ``ConfigurationLimit``
(without a limited ball joint) / ``VelocityLimit`` / ``CollisionAvoidanceLimit``, on any
model (hinge, slide, ball and free joints), :class:`qpik.IKSolver` does in Python only
what needs MuJoCo (one ``mj_jac*`` call per frame, ``mj_jacSubtreeCom`` per CoM task, the
collision limits' own rows ``G dq <= h``) and copies the tasks' targets and costs into
preallocated arrays; the plan's compiled :class:`Kernel` then computes every task's rows
(frame errors by mink's SE(3) arithmetic, ``qpik/_cpp/model/se3.hpp``; posture errors
``q (-) q*`` on the tangent space as ``mj_differentiatePos``: free joints' rows zero, ball
joints' rotation vectors), the box limits (each dof's coordinate at its joint's qpos
address), and the whole cascade with the general rows (the core's ``solve_cascade``), in
one C++ call (``qpik/_cpp/diffik/fused.hpp``).

It computes what the general path computes: the same arithmetic in the same order where
the general path's is qpik's (tests compare the two bitwise: frame tasks, CoM, postures on
hinge/slide/free joints, limits, collision rows), mink's own arithmetic to round-off
elsewhere (mink's FrameTask and RelativeFrameTask, ball joints: 1e-12). Anything unusual
(a non-finite row, conflicting limits, a level whose active set did not settle) is handed
back to the general path, which reports or recovers it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import mink
import mujoco
import numpy as np

from .._engine import diffik as _engine
from ..errors import TargetNotSet
from ..model.frames import FRAME_JACOBIANS, FRAME_OBJECTS
from ..tasks import DampingTask, FrameTask, PostureTask
from ..tasks.com import ComTask

__all__ = ["FusedPlan", "Kernel", "box_of", "fused_rows", "fused_step", "make_plan"]

_KINDS = {"site": 0, "body": 1, "geom": 2}
_OBJECTS = tuple(FRAME_OBJECTS[kind] for kind in _KINDS)  # in the order of the codes
_JACOBIAN = tuple(FRAME_JACOBIANS[kind] for kind in _KINDS)
#: Frame tasks computed in C++: qpik's, and mink's own class (same rows, mink's SE(3)
#: arithmetic; equal to mink's to round-off). Exact types: a subclass may change the rows.
_FRAME_TYPES = (FrameTask, mink.FrameTask)
#: Posture-like tasks: mink's/qpik's PostureTask (rows ``diag(cost) J``, J the identity with
#: the free joints' columns zeroed, error ``q (-) q*``) and DampingTask (error zero).
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
#   ``code`` OK or why the general path must answer; ``info`` (9, L) rows: residual,
#   sigma, lambda^2, status, iterations, then the certificate (primal, stationarity,
#   dual, complementarity); ``active`` (L, nv) int8.
# fused_rows(<fused_step's first 21 arguments>) -> (code, reg, lb, ub)
#   The hierarchy's rows and limits without solving it: fills ``A, b, w``; ``code`` OK,
#   NOT_FINITE (a row or regularisation) or CONFLICT (velocity-like limits of a dof).
# _boxes(qpos, dt, cfg_dof, cfg_lower, cfg_upper, cfg_gain, vel_dof, vel_limit, n)
#       -> (lb, ub, i)
#   The limits' box, as :meth:`qpik.IKSolver._limit_rows` builds it: position bounds
#   ``gain (upper - q)``, ``-gain (q - lower)`` (recoverable), velocity bounds
#   ``|dq| <= v_max dt`` (hard), merged by :func:`qpik.core.kernels.merge_boxes`.
#
# Kernel(A, b, w, starts, tasks, jac, frames, frame_data, posture_data, posture_map,
#        cfg_dof, cfg_qadr, cfg_data, vel_dof, vel_limit, settings, com_jac, com_body,
#        com_data, rel_jac, rel_frames, rel_data, nq)
#   One stack's compiled step (built by make_plan). The index arrays are copied and checked
#   once; the float arrays are held by reference (float64 C-contiguous, never copied: the
#   plan writes into them before each call). ``tasks`` (T, 4) rows: kind (0 frame,
#   1 posture, 2 CoM, 3 relative frame, 4 damping), index into that kind's arrays, level,
#   first row. ``posture_map`` (nv, 2): per dof, kind (0 hinge/slide, 1 free joint, 2 first
#   dof of a ball joint, 3 its others) and qpos address; ``cfg_qadr`` the qpos address of
#   each position-limited dof. CoM ``c``: ``com_jac[c]`` (3, nv) from mj_jacSubtreeCom,
#   ``com_body[c]`` its subtree's body, ``com_data[c]`` = target [m, world] (3), cost (3),
#   gain, lm_damping. Relative frame ``r``: ``rel_jac[r]`` (12, nv) the frame's then the
#   root's world-aligned Jacobians, ``rel_frames[r]`` = frame kind, id, root kind, id,
#   ``rel_data[r]`` as ``frame_data`` with the target in the root frame.
# Kernel.step(qpos, site_xpos, site_xmat, xpos, xmat, geom_xpos, geom_xmat, subtree_com,
#             G, h, warm, canonical, max_iter) -> (code, dq, v, info, active)
#   As fused_step, with MuJoCo's arrays only, general rows ``G dq <= h`` (p, nv) held at
#   every level, ``warm`` (L, nv + p); ``active`` (L, nv + p).
# Kernel.rows(<step's first 10 arguments>) -> (code, reg, lb, ub): as fused_rows.
fused_step = _engine.fused_step
fused_rows = _engine.fused_rows
_boxes = _engine.boxes
Kernel = _engine.Kernel


def box_of(plan: FusedPlan, qpos: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The limits' merged box ``(lb, ub)`` of a plan at ``qpos`` (nq,) for a step of ``dt``
    [s] (bounds on ``dq``, indexed by dof)."""
    a = plan.arrays
    cfg = a["cfg_data"]
    nv = plan.model.nv
    q = np.zeros(nv)
    q[a["cfg_dof"]] = qpos[a["cfg_qadr"]]  # each position-limited dof's coordinate
    lb, ub, _ = _boxes(
        q, dt, a["cfg_dof"], cfg[:, 0], cfg[:, 1], cfg[:, 2], a["vel_dof"], a["vel_limit"], nv
    )  # fmt: skip
    return lb, ub


#: Task kinds of the plan's ``tasks`` table (qpik/_cpp/diffik/fused.hpp: TaskKind).
_FRAME, _POSTURE, _COM, _RELATIVE, _DAMPING = 0, 1, 2, 3, 4
#: Per-dof kinds of ``posture_map`` (fused.hpp: PostureDof).
_SCALAR_DOF, _FREE_DOF, _BALL_FIRST, _BALL_OTHER = 0, 1, 2, 3


@dataclass
class FusedPlan:
    """Preallocated arrays, the compiled :class:`Kernel` and the task/limit bookkeeping of
    the one-call step for one stack (built once per :class:`qpik.IKSolver`).

    Before each call :meth:`gather` copies what the tasks hold (targets, costs, gains) and
    MuJoCo's Jacobians into the arrays the kernel reads (it holds them by reference)."""

    model: mujoco.MjModel
    frames: list  # (task, jacobian function, id, position rows, rotation rows, data row)
    postures: list  # (task, data row, damping: the error is zero, no target)
    coms: list  # (task, body id, body as given, Jacobian (3, nv), data row)
    relatives: list  # (task, (jacobian fn, id) frame, (fn, id) root, jac (12, nv), data row)
    config_limits: list  # (limit, first entry, last entry)
    general_limits: list  # limits whose rows G dq <= h are computed by their own methods
    arrays: dict
    kinds_used: tuple
    cold: np.ndarray  # (L, nv) int8 zeros: a cold start's active sets (never written)
    max_iter: int  # the core's cap on active-set changes per level (0: 10 (nv + p) + 50)
    kernel: Any = None  # qpik._engine.diffik.Kernel over ``arrays``
    law: object = field(default_factory=object)  # the law ``arrays["settings"]`` holds
    colds: dict = field(default_factory=dict)  # p -> (L, nv + p) int8 zeros

    def __post_init__(self) -> None:
        a = self.arrays
        #: fused_step's / fused_rows' arguments before the poses and after ``qpos``
        #: (the legacy functions, on scalar-joint plans; tests).
        self.head = (a["A"], a["b"], a["w"], a["starts"], a["tasks"], a["jac"], a["frames"])
        self.frame_data = a["frame_data"]
        self.tail = (
            a["posture_data"], a["cfg_dof"], a["cfg_data"], a["vel_dof"], a["vel_limit"]
        )  # fmt: skip
        self.no_rows = np.zeros((0, self.model.nv))
        self.no_h = np.zeros(0)
        self.colds[0] = self.cold
        #: the gains last written into ``cfg_data`` (NaN: not yet)
        self.gains = [float("nan")] * len(self.config_limits)

    def cold_for(self, p: int) -> np.ndarray:
        """Zero active sets ``(L, nv + p)`` int8 (a cold start with ``p`` general rows)."""
        cold = self.colds.get(p)
        if cold is None:
            cold = self.colds[p] = np.zeros((self.cold.shape[0], self.model.nv + p), np.int8)
        return cold

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
        """Copy the tasks' current targets, costs and gains and MuJoCo's Jacobians into the
        plan's arrays; returns the kernel's MuJoCo arguments ``(qpos, site_xpos, site_xmat,
        xpos, xmat, geom_xpos, geom_xmat, subtree_com)``, or None when a task changed so
        that the plan no longer describes it (the general path answers)."""
        model, data = self.model, configuration.data
        if self.frames:
            self._gather_frames(data)
        nv = model.nv
        nq = model.nq
        for task, row, damping in self.postures:
            if not damping:  # a damping task's error is zero: no target
                target = task.target_q
                if target is None:
                    raise TargetNotSet(type(task).__name__)
                row[0:nq] = target
            row[nq : nq + nv] = task.cost
            row[nq + nv] = task.gain
            row[nq + nv + 1] = task.lm_damping
        for task, body, given, jac, row in self.coms:
            if given is not None and task.body is not given:
                return None  # the subtree changed: resolved by the general path
            target = task.target_com
            if target is None:
                raise TargetNotSet(type(task).__name__)
            row[0:3] = target
            row[3:6] = task.cost
            row[6] = task.gain
            row[7] = task.lm_damping
            mujoco.mj_jacSubtreeCom(model, data, jac, body)
        for task, (ff, fid), (rf, rid), jac, row in self.relatives:
            pose = task.transform_target_to_root
            if pose is None:
                raise TargetNotSet(type(task).__name__)
            row[0:7] = pose.wxyz_xyz
            row[7:13] = task.cost
            row[13] = task.gain
            row[14] = task.lm_damping
            ff(model, data, jac[0:3], jac[3:6], fid)
            rf(model, data, jac[6:9], jac[9:12], rid)
        if self.config_limits:
            gains = self.gains
            for i, (limit, e0, e1) in enumerate(self.config_limits):
                gain = limit.gain
                if gain != gains[i]:  # written when it changes (NaN: every call)
                    self.arrays["cfg_data"][e0:e1, 2] = gain
                    gains[i] = gain
        empty3, empty9 = self.arrays["empty3"], self.arrays["empty9"]
        site, body, geom = self.kinds_used
        return (
            data.qpos,
            data.site_xpos if site else empty3,
            data.site_xmat if site else empty9,
            data.xpos if body else empty3,
            data.xmat if body else empty9,
            data.geom_xpos if geom else empty3,
            data.geom_xmat if geom else empty9,
            data.subtree_com if self.coms else empty3,
        )


def make_plan(
    model: mujoco.MjModel,
    levels: Sequence[Sequence],
    limits: Sequence,
    scalar_joints: bool,
    rank_tolerance: float,
    tolerance: float,
    max_iter: int,
    trust: tuple[np.ndarray, np.ndarray] | None = None,
) -> FusedPlan | None:
    """The :class:`FusedPlan` of a stack, or None when a task or limit is not one that the
    one-call step computes (the general path then serves every step).

    ``scalar_joints`` (the model has hinge/slide joints only) is no longer needed (kept for
    callers); ``max_iter``: the core's cap (0 for its default ``10 (nv + p) + 50``);
    ``trust``: the step's trust region ``(dofs, speeds [rad/s or m/s])``
    (:attr:`qpik.StepOptions.max_joint_speed`), appended to the velocity limits' entries:
    the kernel's box bounds each of these dofs by ``speed dt``, a hard bound as a
    velocity limit's."""
    layout = _task_layout(model, levels)
    boxes = _limit_boxes(model, limits)
    if layout is None or boxes is None:
        return None
    nv, nq = model.nv, model.nq
    frames, postures, coms, relatives, tasks, frame_rows, starts = layout
    cfg_dof, cfg_qadr, cfg_data, config_limits, vel_dof, vel_limit, general_limits = boxes
    if trust is not None and len(trust[0]):
        vel_dof = [*vel_dof, *np.asarray(trust[0], dtype=np.int64).tolist()]
        vel_limit = [*vel_limit, *np.asarray(trust[1], dtype=float).tolist()]
    F, P, C, R, M = len(frames), len(postures), len(coms), len(relatives), starts[-1]
    jac = np.zeros((F, 6, nv))
    frame_data = np.zeros((F, 15))
    posture_data = np.zeros((P, nq + nv + 2))
    com_jac = np.zeros((C, 3, nv))
    com_data = np.zeros((C, 8))
    rel_jac = np.zeros((R, 12, nv))
    rel_data = np.zeros((R, 15))
    i64 = np.int64
    arrays = {
        "A": np.zeros((M, nv)),
        "b": np.zeros(M),
        "w": np.zeros(M),
        "starts": np.asarray(starts, dtype=i64),
        "tasks": np.asarray(tasks, dtype=i64).reshape(-1, 4),
        "jac": jac,
        "frames": np.asarray([row for row, rel in frame_rows if not rel], dtype=i64).reshape(-1, 2),
        "frame_data": frame_data,
        "posture_data": posture_data,
        "posture_map": _posture_map(model),
        "cfg_dof": np.asarray(cfg_dof, dtype=i64),
        "cfg_qadr": np.asarray(cfg_qadr, dtype=i64),
        "cfg_data": np.asarray(cfg_data, dtype=float).reshape(-1, 3),
        "vel_dof": np.asarray(vel_dof, dtype=i64),
        "vel_limit": np.asarray(vel_limit, dtype=float),
        "settings": np.zeros(7),
        "com_jac": com_jac,
        "com_body": np.asarray([body for _, body, _ in coms], dtype=i64),
        "com_data": com_data,
        "rel_jac": rel_jac,
        "rel_frames": np.asarray([(*f, *r) for _, f, r in relatives], dtype=i64).reshape(-1, 4),
        "rel_data": rel_data,
        "empty3": np.zeros((0, 3)),
        "empty9": np.zeros((0, 9)),
    }
    frames = [
        (task, _JACOBIAN[kind], fid, jac[f, :3], jac[f, 3:], frame_data[f])
        for f, (task, kind, fid) in enumerate(frames)
    ]
    postures = [
        (task, posture_data[p], type(task) in _DAMPING_TYPES) for p, task in enumerate(postures)
    ]
    coms = [
        (task, body, given, com_jac[c], com_data[c]) for c, (task, body, given) in enumerate(coms)
    ]
    relatives = [
        (task, (_JACOBIAN[f[0]], f[1]), (_JACOBIAN[r[0]], r[1]), rel_jac[i], rel_data[i])
        for i, (task, f, r) in enumerate(relatives)
    ]
    used = tuple(any(kind == k for (kind, _), _rel in frame_rows) for k in range(3))
    settings = arrays["settings"]
    settings[RANK_TOL], settings[TOL] = rank_tolerance, tolerance
    cold = np.zeros((len(levels), nv), dtype=np.int8)
    a = arrays
    kernel = Kernel(
        a["A"], a["b"], a["w"], a["starts"], a["tasks"], a["jac"], a["frames"], a["frame_data"],
        a["posture_data"], a["posture_map"], a["cfg_dof"], a["cfg_qadr"], a["cfg_data"],
        a["vel_dof"], a["vel_limit"], a["settings"], a["com_jac"], a["com_body"], a["com_data"],
        a["rel_jac"], a["rel_frames"], a["rel_data"], nq,
    )  # fmt: skip
    return FusedPlan(
        model, frames, postures, coms, relatives, config_limits, general_limits, arrays, used,
        cold, max_iter, kernel,
    )  # fmt: skip


def _posture_map(model: mujoco.MjModel) -> np.ndarray:
    """Per dof ``(kind, qpos address)`` (see ``_SCALAR_DOF``...): how a posture task's
    error ``q (-) q*`` (``mj_differentiatePos``) reads ``qpos``."""
    out = np.zeros((model.nv, 2), dtype=np.int64)
    for j in range(model.njnt):
        kind, q0, v0 = int(model.jnt_type[j]), int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            out[v0 : v0 + 6] = (_FREE_DOF, q0)
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            out[v0] = (_BALL_FIRST, q0)
            out[v0 + 1 : v0 + 3] = (_BALL_OTHER, q0)
        else:
            out[v0] = (_SCALAR_DOF, q0)
    return out


def _frame_entry(model: mujoco.MjModel, frame_type, frame_name) -> tuple[int, int] | None:
    """``(kind, id)`` of a frame, None when the general path must serve it (an unknown
    frame type or name: it reports them)."""
    kind = _KINDS.get(getattr(frame_type, "value", frame_type))
    if kind is None:
        return None
    if isinstance(frame_name, (int, np.integer)) and not isinstance(frame_name, bool):
        count = (model.nsite, model.nbody, model.ngeom)[kind]
        return (kind, int(frame_name)) if 0 <= frame_name < count else None
    if not isinstance(frame_name, str):
        return None
    fid = mujoco.mj_name2id(model, _OBJECTS[kind], frame_name)
    return None if fid < 0 else (kind, fid)


#: CoM tasks: qpik's (any subtree) and mink's (the subtree of body 1). Exact types.
_COM_TYPES = (ComTask, mink.ComTask)


def _com_body(model: mujoco.MjModel, task) -> tuple[int, object] | None:
    """``(body id, task.body as given)`` of a CoM task (mink's: body 1, None), None when the
    general path must serve it (an unknown body: it reports it)."""
    if type(task) is mink.ComTask:
        return (1, None) if model.nbody > 1 else None
    given = task.body
    if isinstance(given, str):
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, given)
    elif isinstance(given, (int, np.integer)) and not isinstance(given, bool):
        body = int(given) if 0 <= int(given) < model.nbody else -1
    else:
        return None
    return None if body < 0 else (body, given)


def _task_layout(model: mujoco.MjModel, levels: Sequence[Sequence]):
    """``(frames, postures, coms, relatives, tasks, frame_rows, starts)`` of a stack whose
    tasks the kernel computes (qpik's or mink's FrameTask / PostureTask / DampingTask /
    ComTask, mink's RelativeFrameTask; exact types), None otherwise: rows are laid out
    level by level, task by task."""
    frames, postures, coms, relatives, tasks, frame_rows = [], [], [], [], [], []
    starts = [0]
    nv = model.nv
    for k, level in enumerate(levels):
        row = starts[-1]
        for task in level:
            kind = type(task)
            if kind in _FRAME_TYPES:
                entry = _frame_entry(model, task.frame_type, task.frame_name)
                if entry is None:
                    return None
                tasks.append((_FRAME, len(frames), k, row))
                frames.append((task, *entry))
                frame_rows.append((entry, False))
                row += 6
            elif kind in _POSTURE_TYPES or kind in _DAMPING_TYPES:
                if np.shape(getattr(task, "cost", None)) != (nv,):
                    return None
                if kind in _DAMPING_TYPES:
                    tasks.append((_DAMPING, len(postures), k, row))
                else:
                    tasks.append((_POSTURE, len(postures), k, row))
                postures.append(task)
                row += nv
            elif kind in _COM_TYPES:
                entry = _com_body(model, task)
                if entry is None or np.shape(task.cost) != (3,):
                    return None
                tasks.append((_COM, len(coms), k, row))
                coms.append((task, *entry))
                row += 3
            elif kind is mink.RelativeFrameTask:
                frame = _frame_entry(model, task.frame_type, task.frame_name)
                root = _frame_entry(model, task.root_type, task.root_name)
                if frame is None or root is None:
                    return None
                tasks.append((_RELATIVE, len(relatives), k, row))
                relatives.append((task, frame, root))
                frame_rows.extend(((frame, True), (root, True)))
                row += 6
            else:
                return None
        starts.append(row)
    return frames, postures, coms, relatives, tasks, frame_rows, starts


#: Limits of general rows ``G dq <= h`` that a plan takes (their rows from their own
#: methods each step, in the same compiled call; exact types).
_GENERAL_LIMITS = (mink.CollisionAvoidanceLimit,)


def _limit_boxes(model: mujoco.MjModel, limits: Sequence):
    """``(cfg_dof, cfg_qadr, cfg_data, config_limits, vel_dof, vel_limit, general_limits)``
    of mink's position and velocity limits and its collision avoidance limits (None when
    another limit is present, or a position limit bounds a ball joint)."""
    cfg_dof, cfg_qadr, cfg_data, config_limits, vel_dof, vel_limit = [], [], [], [], [], []
    general_limits = []
    for limit in limits:
        if type(limit) is mink.ConfigurationLimit:
            if len(getattr(limit, "_ball_qposadr", ())):
                return None  # a ball joint's cone row: the general path
            indices = np.asarray(limit.indices, dtype=np.int64)
            qadr = model.jnt_qposadr[model.dof_jntid[indices]].astype(np.int64)
            e0 = len(cfg_dof)
            cfg_dof.extend(indices.tolist())
            cfg_qadr.extend(qadr.tolist())
            lower, upper = np.asarray(limit.lower)[qadr], np.asarray(limit.upper)[qadr]
            cfg_data.extend(zip(lower.tolist(), upper.tolist(), [0.0] * len(indices)))
            config_limits.append((limit, e0, len(cfg_dof)))
        elif type(limit) is mink.VelocityLimit:
            vel_dof.extend(np.asarray(limit.indices, dtype=np.int64).tolist())
            vel_limit.extend(np.asarray(limit.limit, dtype=float).tolist())
        elif type(limit) in _GENERAL_LIMITS:
            general_limits.append(limit)
        else:
            return None
    return cfg_dof, cfg_qadr, cfg_data, config_limits, vel_dof, vel_limit, general_limits
