"""The compiled step: one C++ call per differential IK step, for the stacks it covers.

:func:`make_plan` builds a :class:`CompiledPlan` once per :class:`qpik.IKSolver` when every
limit is one the compiled :class:`Kernel` takes (mink's ``ConfigurationLimit`` without a
limited ball joint, ``VelocityLimit`` and ``CollisionAvoidanceLimit``; exact types). Tasks
the kernel computes itself: qpik's or mink's ``FrameTask``, ``PostureTask``,
``DampingTask``, ``ComTask``, mink's ``RelativeFrameTask`` (exact types, any joints). Any
other task (qpik's pose, coupling and secondary tasks, mink's equality, DoF-freezing and
kinetic-energy tasks, subclasses, user tasks) supplies its own rows: each step Python asks
it for them (:func:`qpik.diffik.rows.task_rows`, the QP path's very arrays) and writes them
into the plan's ``A, b, w``, its LM term into ``user_mu``; the kernel adds that term to its
level. Such a task's rows are laid out by its declared count (``task.k``, else its ``cost``
vector's length, else ``nv``); a step where it returns another shape goes to the QP path.
Each step, Python does only what needs MuJoCo or the task objects (their targets and costs,
one Jacobian call per frame, the rows of the tasks that supply them, the collision limits'
rows ``G dq <= h``) and the kernel computes the other tasks' rows, the limits' box and the
whole cascade
(``qpik/_cpp/diffik/fused.hpp``), returning a :class:`~qpik.diffik.result.Solution`. It
computes what the QP path computes, in the same arithmetic where that path's is qpik's
(tests compare the two bitwise) and in mink's to round-off elsewhere; anything unusual (a
non-finite row, conflicting limits, an active set that did not settle) returns None, and
the QP path answers, reporting or recovering it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import mink
import mujoco
import numpy as np

from .._engine import diffik as _engine
from ..core import HierarchySolver
from ..core.cascade import STATUS_OF_CODE, LevelStatus, certificates
from ..errors import TargetNotSet
from ..model.configuration import Configuration
from ..model.frames import FRAME_JACOBIANS, FRAME_OBJECTS
from ..tasks import DampingTask, FrameTask, PostureTask
from ..tasks.com import ComTask
from .boxes import LimitBoxes, LimitRows
from .result import Solution, solve_rows
from .rows import TaskRows, task_rows

__all__ = ["CompiledPlan", "Kernel", "make_plan"]

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
#: CoM tasks: qpik's (any subtree) and mink's (the subtree of body 1). Exact types.
_COM_TYPES = (ComTask, mink.ComTask)
#: Limits of general rows ``G dq <= h`` that a plan takes (their rows from their own
#: methods each step, in the same compiled call; exact types).
_GENERAL_LIMITS = (mink.CollisionAvoidanceLimit,)

# Result codes of the kernel: anything but OK sends the step to the QP path.
OK, NOT_FINITE, CONFLICT, UNSETTLED = 0, 1, 2, 3
assert (OK, NOT_FINITE, CONFLICT, UNSETTLED) == (
    _engine.OK, _engine.NOT_FINITE, _engine.CONFLICT, _engine.UNSETTLED
)  # fmt: skip
#: ``settings`` entries of the kernel.
DT, DAMPING, THRESHOLD, MAX_DAMPING, ERROR_SCALE, RANK_TOL, TOL = range(7)
#: Level statuses by the kernel's codes (as the floats of its info array).
_STATUS_OF_CODE = {float(code): status for code, status in STATUS_OF_CODE.items()}
_SOLVED_CODE = next(c for c, s in _STATUS_OF_CODE.items() if s == LevelStatus.SOLVED)
#: Task kinds of the plan's ``tasks`` table (qpik/_cpp/diffik/fused.hpp: TaskKind).
_FRAME, _POSTURE, _COM, _RELATIVE, _DAMPING, _ROWS = 0, 1, 2, 3, 4, 5
#: Per-dof kinds of ``posture_map`` (fused.hpp: PostureDof).
_SCALAR_DOF, _FREE_DOF, _BALL_FIRST, _BALL_OTHER = 0, 1, 2, 3

# The compiled kernel: its arguments are documented where it is bound
# (qpik/_cpp/bind_diffik.cpp, above the Kernel class).
Kernel = _engine.Kernel


def _write_pose_row(row: np.ndarray, task, pose) -> None:
    """A frame-like task's target ``pose`` (wxyz_xyz), cost, gain and LM damping into its
    data row (15)."""
    if pose is None:
        raise TargetNotSet(type(task).__name__)
    row[0:7] = pose.wxyz_xyz
    row[7:13] = task.cost
    row[13] = task.gain
    row[14] = task.lm_damping


@dataclass
class CompiledPlan:
    """Preallocated arrays, the compiled :class:`Kernel` and the task/limit bookkeeping of
    the compiled step of one stack (built once per :class:`qpik.IKSolver`).

    :meth:`step` is one step: :meth:`gather` copies what the tasks hold (targets, costs,
    gains) and MuJoCo's Jacobians into the arrays the kernel reads (it holds them by
    reference), then the kernel answers."""

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
    kernel: Any  # qpik._engine.diffik.Kernel over ``arrays``
    limits: LimitBoxes  # the solver's limits: active-limit names and general rows
    law: object = field(default_factory=object)  # the law ``arrays["settings"]`` holds
    #: tasks that supply their own rows: (task, first row, last row), ``user_mu`` in order
    rows_tasks: list = field(default_factory=list)
    colds: dict = field(default_factory=dict)  # p -> (L, nv + p) int8 zeros

    def __post_init__(self) -> None:
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

    # ----------------------------------------------------------------- inputs
    def gather(self, configuration: mink.Configuration) -> tuple | None:
        """Copy the tasks' current targets, costs and gains and MuJoCo's Jacobians into the
        plan's arrays; returns the kernel's MuJoCo arguments ``(qpos, site_xpos, site_xmat,
        xpos, xmat, geom_xpos, geom_xmat, subtree_com)``, or None when a task changed so
        that the plan no longer describes it (the QP path answers)."""
        data = configuration.data
        model = self.model
        for task, jacobian, fid, jp, jr, row in self.frames:
            _write_pose_row(row, task, task.transform_target_to_world)
            jacobian(model, data, jp, jr, fid)
        self._gather_postures()
        if not self._gather_coms(data):
            return None
        for task, (ff, fid), (rf, rid), jac, row in self.relatives:
            _write_pose_row(row, task, task.transform_target_to_root)
            ff(model, data, jac[0:3], jac[3:6], fid)
            rf(model, data, jac[6:9], jac[9:12], rid)
        self._gather_gains()
        if self.rows_tasks and not self._gather_rows(configuration):
            return None
        return self._poses(data)

    def _gather_rows(self, configuration: mink.Configuration) -> bool:
        """The rows of the tasks that supply them (:func:`task_rows`, the QP path's arrays)
        into ``A, b, w``, their LM terms into ``user_mu``; False when a task's rows do not
        have its planned shape (the QP path answers)."""
        configuration = Configuration.sharing(configuration)  # the QP path's view
        a = self.arrays
        A, b, w, user_mu = a["A"], a["b"], a["w"], a["user_mu"]
        nv = self.model.nv
        for u, (task, r0, r1) in enumerate(self.rows_tasks):
            rows, error, mu, weights = task_rows(task, configuration)
            if (
                rows.shape != (r1 - r0, nv)
                or np.shape(error) != (r1 - r0,)
                or np.shape(weights) != (r1 - r0,)
            ):
                return False
            A[r0:r1] = rows
            b[r0:r1] = error
            w[r0:r1] = weights
            user_mu[u] = 0.0 if mu is None else float(mu)
        return True

    def _gather_postures(self) -> None:
        """Posture and damping tasks' targets, costs, gains and LM damping."""
        nv, nq = self.model.nv, self.model.nq
        for task, row, damping in self.postures:
            if not damping:  # a damping task's error is zero: no target
                target = task.target_q
                if target is None:
                    raise TargetNotSet(type(task).__name__)
                row[0:nq] = target
            row[nq : nq + nv] = task.cost
            row[nq + nv] = task.gain
            row[nq + nv + 1] = task.lm_damping

    def _gather_coms(self, data: mujoco.MjData) -> bool:
        """CoM tasks' targets, costs and Jacobians; False when a task's subtree changed
        (the QP path resolves it)."""
        for task, body, given, jac, row in self.coms:
            if given is not None and task.body is not given:
                return False
            target = task.target_com
            if target is None:
                raise TargetNotSet(type(task).__name__)
            row[0:3] = target
            row[3:6] = task.cost
            row[6] = task.gain
            row[7] = task.lm_damping
            mujoco.mj_jacSubtreeCom(self.model, data, jac, body)
        return True

    def _gather_gains(self) -> None:
        """The position limits' gains, written when they change (NaN: every call)."""
        gains = self.gains
        for i, (limit, e0, e1) in enumerate(self.config_limits):
            gain = limit.gain
            if gain != gains[i]:
                self.arrays["cfg_data"][e0:e1, 2] = gain
                gains[i] = gain

    def _poses(self, data: mujoco.MjData) -> tuple:
        """The kernel's MuJoCo arguments (empty arrays for the kinds no frame uses)."""
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

    def write_settings(self, dt: float, damping: float, core: HierarchySolver) -> None:
        """The kernel's ``settings`` for a step of ``dt`` [s] with the constant
        ``damping`` and ``core``'s damping law (its entries rewritten when the law
        object changes: the law is settable)."""
        settings = self.arrays["settings"]
        settings[DT] = dt
        settings[DAMPING] = damping
        law = core.damping_law
        if law is not self.law:
            settings[THRESHOLD : ERROR_SCALE + 1] = core.damping_settings
            self.law = law

    def _general(self, configuration: mink.Configuration, dt: float):
        """``(G, h, names)`` of the plan's general-row limits (see
        :meth:`LimitBoxes.general_rows`; None: the QP path answers)."""
        if not self.general_limits:
            return self.no_rows, self.no_h, []
        return self.limits.general_rows(self.general_limits, configuration, dt)

    # ----------------------------------------------------------------- limits
    def box(self, qpos: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """The limits' merged box ``(lb, ub)`` at ``qpos`` (nq,) for a step of ``dt`` [s]
        (bounds on ``dq``, indexed by dof), as the kernel computes it."""
        a = self.arrays
        cfg = a["cfg_data"]
        nv = self.model.nv
        q = np.zeros(nv)
        q[a["cfg_dof"]] = qpos[a["cfg_qadr"]]  # each position-limited dof's coordinate
        lb, ub, _ = _engine.boxes(
            q, dt, a["cfg_dof"], cfg[:, 0], cfg[:, 1], cfg[:, 2], a["vel_dof"], a["vel_limit"], nv
        )  # fmt: skip
        return lb, ub

    def _limit_rows(self, qpos: np.ndarray, dt: float, general: tuple, box=None) -> LimitRows:
        """The step's :class:`LimitRows` at ``qpos`` (a copy), with the general rows
        ``(G, h, names)``; ``box`` ``(lb, ub)`` when known (else computed here)."""
        lb, ub = self.box(qpos, dt) if box is None else box
        G, h, names = general
        limits = self.limits
        return LimitRows(
            lb, ub, G, h, names, lambda: limits.contributions(qpos, dt), limits.dof_names
        )

    # ------------------------------------------------------------------- step
    def step(
        self,
        configuration: mink.Configuration,
        dt: float,
        damping: float,
        core: HierarchySolver,
        exact: HierarchySolver | None = None,
    ) -> Solution | None:
        """One step at ``configuration`` for ``dt`` [s] with the constant ``damping``,
        solved as ``core`` solves: with the default solver in one kernel call; with a forced
        backend, the kernel's rows and box, then ``core``'s cascade. ``exact`` (an exact
        solver, for a forced backend whose answer is only the displacement): its answer is
        kept when it solves every level (the forced backend's answer, polished by that same
        exact solve, is equal to round-off), and no backend is called. None where the QP
        path must answer (a non-finite row, conflicting limits, an unsettled active set, a
        collision row on one dof, a task changed beyond its plan)."""
        poses = self.gather(configuration)
        if poses is None:
            return None
        self.write_settings(dt, damping, core)
        if core.solver == "auto":
            return self._one_call(poses, configuration, dt, core)
        if exact is not None:
            solution = self._one_call(poses, configuration, dt, core, forced=True)
            if solution is not None:
                return solution
            exact = None
        return self._rows_then_cascade(poses, configuration, dt, core, exact)

    def _one_call(
        self, poses: tuple, configuration: mink.Configuration, dt: float, core, forced: bool = False
    ) -> Solution | None:
        """The whole step in one kernel call, warm started from ``core``'s active sets
        (which it then updates). ``forced``: kept only when every level was solved."""
        out = self._kernel_step(poses, configuration, dt, core, forced)
        if out is None:
            return None
        d, v, info, status, general = out
        residuals, sigma, lam2, _, iterations = info[:5].tolist()
        qpos = poses[0].copy()
        return Solution(
            displacement=d,
            velocity=v,
            residuals=residuals,
            sigma_min=sigma,
            damping=lam2,
            status=[_STATUS_OF_CODE[s] for s in status],
            iterations=list(map(int, iterations)),
            certificate=certificates(info[5:].T),
            limits=lambda: self._limit_rows(qpos, dt, general),
        )

    def _kernel_step(
        self, poses: tuple, configuration: mink.Configuration, dt: float, core, forced: bool
    ) -> tuple | None:
        """The kernel's step: ``(dq, v, info, status codes, general rows)``, None where the
        QP path must answer (``forced``: also where a level was not solved); ``core``'s
        active sets updated."""
        general = self._general(configuration, dt)
        if general is None:
            return None
        G, h, _ = general
        nv, p = self.model.nv, G.shape[0]
        warm = core.warm_sets(self.cold.shape[0], nv + p)
        if warm is None:
            warm = self.cold_for(p)
        code, d, v, info, active = self.kernel.step(
            *poses, G, h, warm, core.warm_start, self.max_iter or 10 * (nv + p) + 50
        )
        if code:
            return None
        status = info[3].tolist()
        if forced and any(s != _SOLVED_CODE for s in status):
            return None
        core.warm_start_from(active)
        return d, v, info, status, general

    def velocity(
        self,
        configuration: mink.Configuration,
        dt: float,
        damping: float,
        core: HierarchySolver,
        exact: bool,
    ) -> tuple[np.ndarray, list[LevelStatus]] | None:
        """The step's velocity ``dq / dt`` and its levels' statuses by one kernel call (what
        :meth:`step` computes, without the rest of its :class:`Solution`); None where
        :meth:`step` would go further (a forced backend without ``exact``, or a level the
        forced backend must answer) or the QP path must answer."""
        if core.solver != "auto" and not exact:
            return None
        poses = self.gather(configuration)
        if poses is None:
            return None
        self.write_settings(dt, damping, core)
        out = self._kernel_step(poses, configuration, dt, core, core.solver != "auto")
        if out is None:
            return None
        return out[1], [_STATUS_OF_CODE[s] for s in out[3]]

    def _rows_then_cascade(
        self, poses: tuple, configuration: mink.Configuration, dt: float, core, exact
    ) -> Solution | None:
        """The rows and box in one kernel call, the general rows from their limits, then
        the cascade: ``exact``'s first when given (kept when it solves every level), else
        ``core``'s."""
        code, reg, lb, ub = self.kernel.rows(*poses, self.no_rows, self.no_h)
        if code:
            return None
        general = self._general(configuration, dt)
        if general is None:
            return None
        a = self.arrays
        tasks = TaskRows(a["A"], a["b"], a["w"], a["starts"], reg)
        limits = self._limit_rows(poses[0].copy(), dt, general, (lb, ub))
        if exact is not None:
            solution = solve_rows(exact, tasks, limits, dt)
            if solution.ok:
                return solution
        return solve_rows(core, tasks, limits, dt)


@dataclass(frozen=True)
class _TaskLayout:
    """Where each task of a stack goes in the plan: the frame, posture, CoM and relative
    frame tasks with their frames or bodies, the tasks that supply their rows, the ``tasks``
    table rows, the frames used ``((kind, id), relative)`` and each level's first row
    (``starts``)."""

    frames: list
    postures: list
    coms: list
    relatives: list
    tasks: list
    frame_rows: list
    starts: list
    rows_tasks: list  # (task, first row, last row) of the tasks that supply their rows


@dataclass(frozen=True)
class _LimitLayout:
    """The entries of a plan's limits: position limits (``cfg_dof``, ``cfg_qadr``,
    ``cfg_data`` rows (lower, upper, gain), and ``(limit, first, last entry)``), velocity
    limits (``vel_dof``, ``vel_limit``) and the general-row limits."""

    cfg_dof: list
    cfg_qadr: list
    cfg_data: list
    config_limits: list
    vel_dof: list
    vel_limit: list
    general_limits: list


def make_plan(
    model: mujoco.MjModel, levels: Sequence[Sequence], limits: LimitBoxes, core: HierarchySolver
) -> CompiledPlan | None:
    """The :class:`CompiledPlan` of a stack under ``limits`` solved as ``core`` solves
    (its rank tolerance, tolerance and iteration cap), or None when a task or limit is not
    one the kernel computes (the QP path then serves every step). The trust region of
    ``limits`` (:attr:`qpik.StepOptions.max_joint_speed`) is appended to the velocity
    limits' entries: the kernel bounds each of its dofs by ``speed dt``, a hard bound as a
    velocity limit's."""
    layout = _task_layout(model, levels)
    boxes = _limit_layout(model, limits.limits)
    if layout is None or boxes is None:
        return None
    arrays = _plan_arrays(model, layout, boxes, limits)
    settings = arrays["settings"]
    settings[RANK_TOL], settings[TOL] = core.rank_tolerance, core.tolerance
    jac, frame_data, posture_data = arrays["jac"], arrays["frame_data"], arrays["posture_data"]
    com_jac, com_data = arrays["com_jac"], arrays["com_data"]
    rel_jac, rel_data = arrays["rel_jac"], arrays["rel_data"]
    frames = [
        (task, _JACOBIAN[kind], fid, jac[f, :3], jac[f, 3:], frame_data[f])
        for f, (task, kind, fid) in enumerate(layout.frames)
    ]
    postures = [
        (task, posture_data[p], type(task) in _DAMPING_TYPES)
        for p, task in enumerate(layout.postures)
    ]
    coms = [
        (task, body, given, com_jac[c], com_data[c])
        for c, (task, body, given) in enumerate(layout.coms)
    ]
    relatives = [
        (task, (_JACOBIAN[f[0]], f[1]), (_JACOBIAN[r[0]], r[1]), rel_jac[i], rel_data[i])
        for i, (task, f, r) in enumerate(layout.relatives)
    ]
    used = tuple(any(kind == k for (kind, _), _rel in layout.frame_rows) for k in range(3))
    cold = np.zeros((len(levels), model.nv), dtype=np.int8)
    a = arrays
    kernel = Kernel(
        a["A"], a["b"], a["w"], a["starts"], a["tasks"], a["jac"], a["frames"], a["frame_data"],
        a["posture_data"], a["posture_map"], a["cfg_dof"], a["cfg_qadr"], a["cfg_data"],
        a["vel_dof"], a["vel_limit"], a["settings"], a["com_jac"], a["com_body"], a["com_data"],
        a["rel_jac"], a["rel_frames"], a["rel_data"], model.nq, a["user_mu"],
    )  # fmt: skip
    return CompiledPlan(
        model, frames, postures, coms, relatives, boxes.config_limits, boxes.general_limits,
        arrays, used, cold, core.max_iter or 0, kernel, limits, rows_tasks=layout.rows_tasks,
    )  # fmt: skip


def _plan_arrays(
    model: mujoco.MjModel, layout: _TaskLayout, boxes: _LimitLayout, limits: LimitBoxes
) -> dict:
    """The arrays the kernel holds, preallocated (the float ones written before each
    call)."""
    nv, nq = model.nv, model.nq
    vel_dof = [*boxes.vel_dof, *limits.trust_dofs.tolist()]
    vel_limit = [*boxes.vel_limit, *limits.trust_speeds.tolist()]
    F, P, C, R = len(layout.frames), len(layout.postures), len(layout.coms), len(layout.relatives)
    M = layout.starts[-1]
    i64 = np.int64
    frames = [row for row, rel in layout.frame_rows if not rel]
    rel_frames = [(*f, *r) for _, f, r in layout.relatives]
    return {
        "A": np.zeros((M, nv)),
        "b": np.zeros(M),
        "w": np.zeros(M),
        "starts": np.asarray(layout.starts, dtype=i64),
        "tasks": np.asarray(layout.tasks, dtype=i64).reshape(-1, 4),
        "jac": np.zeros((F, 6, nv)),
        "frames": np.asarray(frames, dtype=i64).reshape(-1, 2),
        "frame_data": np.zeros((F, 15)),
        "posture_data": np.zeros((P, nq + nv + 2)),
        "posture_map": _posture_map(model),
        "cfg_dof": np.asarray(boxes.cfg_dof, dtype=i64),
        "cfg_qadr": np.asarray(boxes.cfg_qadr, dtype=i64),
        "cfg_data": np.asarray(boxes.cfg_data, dtype=float).reshape(-1, 3),
        "vel_dof": np.asarray(vel_dof, dtype=i64),
        "vel_limit": np.asarray(vel_limit, dtype=float),
        "settings": np.zeros(7),
        "com_jac": np.zeros((C, 3, nv)),
        "com_body": np.asarray([body for _, body, _ in layout.coms], dtype=i64),
        "com_data": np.zeros((C, 8)),
        "rel_jac": np.zeros((R, 12, nv)),
        "rel_frames": np.asarray(rel_frames, dtype=i64).reshape(-1, 4),
        "rel_data": np.zeros((R, 15)),
        "user_mu": np.zeros(len(layout.rows_tasks)),
        "empty3": np.zeros((0, 3)),
        "empty9": np.zeros((0, 9)),
    }


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
    """``(kind, id)`` of a frame, None when the QP path must serve it (an unknown
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


def _com_body(model: mujoco.MjModel, task) -> tuple[int, object] | None:
    """``(body id, task.body as given)`` of a CoM task (mink's: body 1, None), None when the
    QP path must serve it (an unknown body: it reports it)."""
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


def _declared_rows(task, nv: int) -> int:
    """The rows a task that supplies its own declares: ``task.k`` (mink's row count), else
    the length of its ``cost`` vector, else ``nv`` (a task of ``(H, c)`` only: its factor has
    ``nv`` rows where ``H`` has full rank)."""
    k = getattr(task, "k", None)
    if isinstance(k, (int, np.integer)) and not isinstance(k, bool) and k >= 0:
        return int(k)
    cost = getattr(task, "cost", None)
    if isinstance(cost, np.ndarray) and cost.ndim == 1:
        return cost.shape[0]
    return nv


def _task_layout(model: mujoco.MjModel, levels: Sequence[Sequence]) -> _TaskLayout | None:
    """The layout of a stack: the tasks the kernel computes (qpik's or mink's FrameTask /
    PostureTask / DampingTask / ComTask, mink's RelativeFrameTask; exact types) and those
    that supply their rows (any other); None where a task the kernel computes names what the
    model lacks (the QP path reports it). Rows are laid out level by level, task by task."""
    frames, postures, coms, relatives, tasks, frame_rows = [], [], [], [], [], []
    rows_tasks: list = []
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
            else:  # rows supplied by the task itself, each step
                size = _declared_rows(task, nv)
                tasks.append((_ROWS, len(rows_tasks), k, row))
                rows_tasks.append((task, row, row + size))
                row += size
        starts.append(row)
    return _TaskLayout(frames, postures, coms, relatives, tasks, frame_rows, starts, rows_tasks)


def _limit_layout(model: mujoco.MjModel, limits: Sequence) -> _LimitLayout | None:
    """The entries of mink's position and velocity limits and its collision avoidance
    limits (None when another limit is present, or a position limit bounds a ball
    joint)."""
    cfg_dof, cfg_qadr, cfg_data, config_limits, vel_dof, vel_limit = [], [], [], [], [], []
    general_limits = []
    for limit in limits:
        if type(limit) is mink.ConfigurationLimit:
            if _limits_a_ball_joint(limit.model):
                return None  # a ball joint's cone row: the QP path
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
    return _LimitLayout(
        cfg_dof, cfg_qadr, cfg_data, config_limits, vel_dof, vel_limit, general_limits
    )


def _limits_a_ball_joint(model: mujoco.MjModel) -> bool:
    """A ball joint of ``model`` has a range (mink's ConfigurationLimit bounds its rotation
    angle by a general row, which the kernel does not compute)."""
    ball = model.jnt_type == mujoco.mjtJoint.mjJNT_BALL
    return bool(np.any(ball & (model.jnt_limited != 0)))
