"""The compiled step: one C++ call per differential IK step, for the stacks it covers.

:func:`qpik.diffik.plan.make_plan` builds a :class:`CompiledPlan` once per
:class:`qpik.IKSolver` when every limit is one the compiled :class:`Kernel` takes (mink's
``ConfigurationLimit`` without a limited ball joint and ``VelocityLimit``, exact types;
collision avoidance and the support polygon, :data:`.layout.GENERAL_LIMITS`); its layout
(which task goes where) is :mod:`.layout`'s. Tasks the kernel computes itself (exact types,
any joints): qpik's or mink's ``FrameTask``, ``PostureTask``, ``DampingTask``, ``ComTask``,
``RelativeFrameTask``; qpik's ``PositionTask``, ``OrientationTask``, ``PoseTask``,
``JointLimitDistanceTask``, and its ``CouplingTask`` when every coupling is linear
(``qpik/_cpp/tasks/linear.hpp``). Any other task (nonlinear couplings, the other secondary
tasks, mink's equality, DoF-freezing and kinetic-energy tasks, subclasses, user tasks)
supplies its own rows each step (:func:`qpik.diffik.rows.task_rows`, the QP path's very
arrays) into the plan's ``A, b, w``, its LM term into ``user_mu``, laid out by its declared
count (``task.k``, else its ``cost`` vector's length, else ``nv``; another shape sends the
step to the QP path). Python does only what needs MuJoCo or the task objects; the kernel
computes the other tasks' rows, the limits' box and the whole cascade
(``qpik/_cpp/diffik/fused.hpp``). A step is one kernel call (:meth:`CompiledPlan._lean`;
with general-row limits, a cold start and no passes, :meth:`CompiledPlan._rows_step`, the
limits' rows passed in): the kernel reads the tasks' values from the task objects (held,
``Kernel.set_sources``), computes the frame tasks' Jacobians (bitwise MuJoCo's ``mj_jac``)
and writes its answers into a row of output arrays allocated :data:`OUTPUT_ROWS` steps at
a time (views of that row, never written again): a :class:`~qpik.diffik.result.Solution`, or
:meth:`qpik.IKSolver.step`'s :class:`~qpik.diffik.result.StepResult` itself. It computes
what the QP path computes, bit for bit where that path's arithmetic is qpik's, to round-off
where it is mink's; anything unusual (a non-finite row, conflicting limits, an active set
that did not settle) returns None, and the QP path answers, reporting or recovering it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import mink
import mujoco
import numpy as np

from .._engine import diffik as _engine
from ..core import HierarchySolver, kernels
from ..core.cascade import STATUS_OF_CODE, LevelStatus, certificates
from ..model.configuration import Configuration
from ..model.frames import frame_chains
from .boxes import LimitBoxes, LimitRows, relaxable
from .correction import LeanCorrection
from .layout import (
    DAMPING,
    DT,
    ERROR_SCALE,
    LOWER_TRUST,
    RANK_TOL,
    THRESHOLD,
    TOL,
    com_chains,
    corrected_kinds,
    is_user_limit,
)
from .lean import lean_slots, lean_sources
from .result import Solution, StepResult, resolved_info, solve_rows
from .rows import TaskRows, efc_arrays, task_rows
from .writers import (
    guards_hold,
    plan_guards,
    write_com_row,
    write_frame_row,
    write_limit_bounds,
    write_limit_values,
    write_posture_row,
    write_relative_row,
    write_table_rows,
)

__all__ = ["CompiledPlan", "Kernel"]

# Result codes of the kernel: anything but OK sends the step to the QP path.
OK, NOT_FINITE, CONFLICT, UNSETTLED = 0, 1, 2, 3
assert (OK, NOT_FINITE, CONFLICT, UNSETTLED) == (
    _engine.OK, _engine.NOT_FINITE, _engine.CONFLICT, _engine.UNSETTLED
)  # fmt: skip
#: Level statuses by the kernel's codes (as the floats of its info array).
_STATUS_OF_CODE = {float(code): status for code, status in STATUS_OF_CODE.items()}
_SOLVED_CODE, _INFEASIBLE_CODE = float(kernels.SOLVED), float(kernels.INFEASIBLE)

_perf_counter = time.perf_counter
_NO_DATA = object()  # never an MjData: CompiledPlan._plain_data while no lane step may go

#: Rows of the output arrays a lean step writes into (:meth:`CompiledPlan._new_outputs`).
OUTPUT_ROWS = 64

#: :meth:`CompiledPlan._rows_step`'s "the gathered step answers".
_GATHER = object()

# The compiled kernel: its arguments are documented where it is bound
# (qpik/_cpp/bind_diffik.cpp, above the Kernel class).
Kernel = _engine.Kernel


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
    #: linear tasks (CouplingTask, DofConstraint): (task, first lin_data column, cost view)
    linears: list = field(default_factory=list)
    colds: dict = field(default_factory=dict)  # p -> (L, nv + p) int8 zeros
    vel_limits: list = field(default_factory=list)  # (limit, first, last vel_limit entry)
    #: kinetic-energy tasks: (task, its ``ke_data`` row: cost, inv_dt_sq)
    kinetics: list = field(default_factory=list)
    #: equality-constraint tasks: (task, its ``eq_data`` row: costs by position, gain, lm)
    equalities: list = field(default_factory=list)

    def __post_init__(self) -> None:
        self.nv, self.levels = self.model.nv, self.cold.shape[0]
        self._data: mujoco.MjData | None = None  # the MjData whose arrays _pose_args views
        self._pose_args: tuple = ()
        self.no_rows, self.no_h = np.zeros((0, self.nv)), np.zeros(0)
        self._deferred: np.ndarray | None = None  # (_kernel_step's deferred sigmas' records)
        self.colds[0] = self.cold
        self._out: tuple = ()  # the outputs _lean steps write into (_new_outputs)
        self._row = OUTPUT_ROWS
        self._chain_data: mujoco.MjData | None = None  # the MjData of attach_chains
        self._corrector: LeanCorrection | None = None  # _correct's passes (built on the first)
        self._cap = self.max_iter or 10 * self.nv + 50  # a lean step's cap on changes
        self._synced = self._version = -1  # the core's settings_version copied (sync)
        #: per CoM task, its per-dof chain ([]: mj_jacSubtreeCom gives every CoM Jacobian)
        self._com_chains = com_chains(self.model, [c[1] for c in self.coms])
        #: no row-supplying task or general rows, CoM tasks only with chains: once _lean
        #: attached a configuration, IKSolver.step's plain lane calls the kernel (no correction
        #: passes; it reads _plain_data, law, _row, kernel, _cap, _out...)
        chained = bool(self._com_chains) or not self.coms
        self._plain = chained and not (self.rows_tasks or self.general_limits or self.equalities)
        #: a plain plan's ``_data`` once its chains are that MjData's too (else _NO_DATA):
        #: the lane's one identity test for the three (kept by :meth:`_update_plain_data`)
        self._plain_data: object = _NO_DATA
        #: per row of ``_out`` (:meth:`_new_outputs`): the velocity view and the core's pending
        #: warm start ``(_out[3], row)``: a lane step indexes lists, creates neither
        self._velocity_rows: list = []
        self._active_rows: list = []
        #: where level 0 is infeasible, the QP path answers: it relaxes the general rows that
        #: qpik.diffik.recovery may, and names a user limit's rows that leave no displacement
        self._relaxable = any(
            relaxable(limit) or is_user_limit(limit) for limit in self.general_limits
        )
        self._config_limits = [c[0] for c in self.config_limits]
        #: the frames and subtrees the plan resolved, checked each step (plan_guards)
        self._guards = plan_guards(self.frames, self.relatives, self.coms)
        # (a task's gain outside [0, 1], set after the build on one of mink's own classes,
        # which take any: the kernel declines the step, Kernel::load_range, and gather's
        # writing of it raises InvalidGain)
        self.kernel.set_guards(self._guards)
        self.kernel.set_slots(*lean_slots(self))
        sources, self._limit_first = lean_sources(self)
        self.kernel.set_sources(sources)
        # The kernel makes the Jacobians, in the lean step and in the gathered one (gather)
        if self.frames:
            frames = frame_chains(self.model, self.arrays["frames"])
            self.kernel.set_chains(self.arrays["jac"], *frames)
        if self.relatives:  # and the relative frames' (each task's frame, then its root)
            rel = self.arrays["rel_frames"].reshape(-1, 2)
            self.kernel.set_rel_chains(self.arrays["rel_jac"], *frame_chains(self.model, rel))
        if self._com_chains:  # the kernel computes the CoM Jacobians too
            chains = (np.stack(a) for a in zip(*self._com_chains))
            self.kernel.set_com_chains(self.arrays["com_jac"], *chains)

    def __deepcopy__(self, memo: dict) -> CompiledPlan:
        """The plan itself: it is the solver's machinery, not data (a deep copy of a
        :class:`StepResult`, which reads its lazy fields through the plan, shares it)."""
        return self

    def cold_for(self, p: int) -> np.ndarray:
        """Zero active sets ``(L, nv + p)`` int8 (a cold start with ``p`` general rows)."""
        cold = self.colds.get(p)
        if cold is None:
            cold = self.colds[p] = np.zeros((self.cold.shape[0], self.model.nv + p), np.int8)
        return cold

    # ----------------------------------------------------------------- inputs
    def gather(self, configuration: mink.Configuration, loaded: bool = False) -> tuple | None:
        """Copy the tasks' current targets, costs and gains and MuJoCo's Jacobians into the
        plan's arrays; returns the kernel's MuJoCo arguments ``(qpos, site_xpos, site_xmat,
        xpos, xmat, geom_xpos, geom_xmat, subtree_com)``, or None when a task changed so
        that the plan no longer describes it (the QP path answers). ``loaded``: the kernel
        has read the tasks' and limits' values and checked the guards (``Kernel.load_sources``,
        as the lean step does): the Jacobians alone are made here."""
        data = configuration.data
        # The Jacobians by the kernel (Kernel.make_jacobians, as the lean step makes them:
        # bitwise MuJoCo's, at the attached MjData's frames); MuJoCo's CoM Jacobians where
        # the CoM tasks have no chains.
        poses = self._attach(data)
        self._jacobians(data)
        self.kernel.make_jacobians()
        if not loaded:
            for task, _jacobian, _fid, _jp, _jr, row, names in self.frames:
                write_frame_row(row, task, names)
            self._gather_postures()
            for task, _body, _given, _jac, views in self.coms:
                write_com_row(views, task)
            if not guards_hold(self._guards):  # a frame or subtree changed
                return None
            for task, _ff, _rf, _jac, row in self.relatives:
                write_relative_row(row, task)
            self._gather_gains()
            if not write_table_rows(self):
                return None
        if self.rows_tasks and not self._gather_rows(configuration):
            return None
        return poses

    def _attach(self, data: mujoco.MjData) -> tuple:
        """The kernel's MuJoCo arguments of ``data`` (:meth:`_poses`), attached to the
        kernel when ``data`` is not the MjData it holds (MjData's arrays never move: their
        views are kept)."""
        if data is not self._data:
            self._pose_args = self._poses(data)
            self.kernel.attach(data, *self._pose_args)
            self._data = data
            self._update_plain_data()
        return self._pose_args

    def _update_plain_data(self) -> None:  # after _data or _chain_data changed
        plain = self._plain and self._data is self._chain_data and self._data is not None
        self._plain_data = self._data if plain else _NO_DATA

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
        for task, views, damping in self.postures:
            write_posture_row(views, task, damping)

    def _gather_gains(self) -> None:
        """The limits' bounds, gains and speeds: loaded and checked by the kernel, else
        written here (write_limit_values / _bounds: the typed error of what does not fit)."""
        if self.kernel.load_limits(self._limit_first):
            return
        cfg, vel = self.arrays["cfg_data"], self.arrays["vel_limit"]
        for limit, e0, e1 in self.config_limits:
            write_limit_values(cfg[e0:e1, 2], limit, "gain")
            if e1 > e0:
                write_limit_bounds(cfg[e0:e1, :2], limit, self.arrays["cfg_qadr"][e0:e1])
        for limit, v0, v1 in self.vel_limits:
            write_limit_values(vel[v0:v1], limit, "limit")

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
        ``damping`` and ``core``'s settings (:meth:`sync`)."""
        settings = self.arrays["settings"]
        settings[DT] = dt
        settings[DAMPING] = damping
        if core.settings_version != self._synced:
            self.sync(core)

    def sync(self, core: HierarchySolver) -> None:
        """``core``'s settings copied again where they changed since the last copy (its
        ``settings_version``): damping law, rank tolerance, tolerance, cap on changes; the
        plain lane's ``_version`` is the core's where it may take steps (the default solver,
        cold starts), else -1 (IKSolver.step compares them)."""
        settings, law = self.arrays["settings"], core.damping_law
        settings[THRESHOLD : ERROR_SCALE + 1] = core.damping_settings
        settings[LOWER_TRUST] = core.lower_trust
        settings[RANK_TOL], settings[TOL] = core.rank_tolerance, core.tolerance
        if core.max_iter != self.max_iter:
            self.max_iter, self._corrector = core.max_iter, None
            self._cap = self.max_iter or 10 * self.nv + 50
        self.law, self._synced = law, core.settings_version
        lane = core.solver == "auto" and not core.warm_start
        self._version = self._synced if lane else -1

    def _general(self, configuration: mink.Configuration, dt: float):
        """``(G, h, names)`` of the plan's general-row limits (see
        :meth:`LimitBoxes.general_rows`; None: the QP path answers)."""
        if not self.general_limits:
            return self.no_rows, self.no_h, []
        return self.limits.general_rows(self.general_limits, configuration, dt)

    # ------------------------------------------------------------ lean step
    def _jacobians(self, data: mujoco.MjData) -> None:
        """Attach ``data``'s ``cdof`` and ``subtree_com``, whence the kernel makes the tasks'
        Jacobians; MuJoCo's CoM Jacobians where the CoM tasks have no chains."""
        if data is not self._chain_data:
            if self.frames or self._com_chains or self.relatives:
                self.kernel.attach_chains(data.cdof, data.subtree_com)
            if self.kinetics:  # (M(q) from its cdof and cinert)
                self.kernel.attach_inertia(data.cdof, data.cinert)
            self._chain_data = data
            self._update_plain_data()
        if self.equalities:  # (MuJoCo's constraint rows: their views change with nefc)
            self.kernel.attach_efc(*efc_arrays(self.model, data))
        if not self._com_chains:
            for _task, body, _given, jac, _row in self.coms:
                mujoco.mj_jacSubtreeCom(self.model, data, jac, body)

    def _correction(self) -> LeanCorrection:
        """The plan's corrector (:class:`qpik.diffik.correction.LeanCorrection`, on the plan's
        own configuration at ``q (+) dq``), made on first use."""
        corrector = self._corrector
        if corrector is None:
            aux = Configuration(self.model)
            self.kernel.attach_aux(aux.data, *self._poses(aux.data))
            corrector = self._corrector = LeanCorrection(
                self.kernel, aux, self.rows_tasks, bool(self.coms), self.arrays["b"].shape[0],
                self.max_iter or 10 * self.nv + 50,
            )  # fmt: skip
        return corrector

    def _correct(self, configuration: mink.Configuration, row: int, dt: float, passes: int) -> bool:
        """``passes`` second-order corrections of the lean step in row ``row`` of the
        outputs. False where the QP path must answer (and for kinds it does not correct)."""
        if not corrected_kinds(self.arrays["tasks"]):
            return False
        return self._correction().run(configuration, self._out[1][row], row, dt, passes)

    def _new_outputs(self) -> None:
        """Fresh rows for the next :data:`OUTPUT_ROWS` lean steps' answers (views of a
        step's own row, never written again, live on while a result holds one)."""
        nv, levels, rows = self.nv, self.levels, OUTPUT_ROWS
        self._out = (
            np.empty((rows, nv)),
            np.empty((rows, nv)),
            np.empty((rows, 9, levels)),
            np.empty((rows, levels, nv), np.int8),
            np.empty((rows, self.model.nq)),
            np.empty((rows, self.kernel.defer_width)),
        )
        self.kernel.attach_out(*self._out)
        self._velocity_rows = list(self._out[1])
        active = self._out[3]
        self._active_rows = [(active, row) for row in range(rows)]
        self._row = 0

    def _lean(self, configuration: mink.Configuration, dt: float, damping: float, core) -> int:
        """The step without general rows in one kernel call that also reads the tasks'
        values: the row of ``self._out`` holding its answers, ``-1`` where the QP path must
        answer, ``-2`` where :meth:`gather` must write the values (nothing solved)."""
        data = configuration.data
        if data is not self._chain_data or self.coms or self.equalities:
            self._jacobians(data)
        if self.rows_tasks and not self._gather_rows(configuration):
            return -1
        if data is not self._data:
            self._attach(data)
        if core.settings_version != self._synced:
            self.sync(core)
        row = self._row
        if row == OUTPUT_ROWS:
            self._new_outputs()
            row = 0
        nv = self.nv
        warm = core.warm_sets(self.levels, nv) if core.warm_start else None
        code = self.kernel.go(dt, damping, row, warm, core.warm_start, self._cap)
        if code == -1:
            return -2
        self._row = row + 1
        return row if code == OK else -1

    def _solve(
        self, configuration, dt: float, damping: float, core, forced: bool, resolve: bool = True
    ) -> tuple | None:
        """The kernel's step: ``(dq, v, info, general rows, qpos)`` (deferred sigma resolved;
        ``resolve=False``: left NaN), None where the QP path must answer (``forced``: also
        where a level was not solved); ``core``'s active sets updated."""
        if not self.general_limits:
            row = self._lean(configuration, dt, damping, core)
            if row >= 0:
                d, v, info, active, qpos, defer = self._out
                info = resolved_info(info[row], defer[row]) if resolve else info[row]
                if forced and any(s != _SOLVED_CODE for s in info[3].tolist()):
                    return None
                core.warm_start_from_row(active, row)
                return d[row], v[row], info, (self.no_rows, self.no_h, []), qpos[row]
            if row == -1:
                return None
        elif not core.warm_start:  # (the general rows' step in one kernel call)
            got = self._rows_step(configuration, dt, damping, core, forced)
            if got is None:
                return None
            if got is not _GATHER:
                row, general = got
                d, v, info, _active, qpos, defer = self._out
                info = resolved_info(info[row], defer[row]) if resolve else info[row]
                return d[row], v[row], info, general, qpos[row]
        return self._gathered_step(configuration, dt, damping, core, forced, resolve)

    def _gathered_step(
        self, configuration, dt: float, damping: float, core, forced: bool, resolve: bool = True
    ) -> tuple | None:
        """:meth:`_solve` by gathering the step's arrays in Python (:meth:`gather`; the
        values the kernel takes as they are read by it, ``Kernel.load_sources``).
        ``resolve=False``: the sigma of each level whose rank the cascade proves full left
        NaN in the info (as the lean step defers it; nothing else changes)."""
        poses = self.gather(configuration, self.kernel.load_sources(dt, damping))
        if poses is None:
            return None
        self.write_settings(dt, damping, core)
        out = self._kernel_step(poses, configuration, dt, core, forced, resolve)
        if out is None:
            return None
        return (*out, poses[0].copy())

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

    def lean_limits(self, qpos: np.ndarray, dt: float) -> LimitRows:
        """The :class:`LimitRows` of a lean step (no general rows) at ``qpos`` (a row of
        the outputs, never written again) for ``dt`` [s]."""
        return self._limit_rows(qpos, dt, (self.no_rows, self.no_h, []))

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
        """One step at ``configuration`` for ``dt`` [s] with the constant ``damping``, as
        ``core`` solves: the default solver in one kernel call; a forced backend on the
        kernel's rows and box. ``exact`` (an exact solver, for a forced backend that answers
        the displacement only): its answer is kept when it solves every level (the backend's,
        polished by that solve, is equal to round-off), no backend called. None where the QP
        path must answer (a non-finite row, conflicting limits, an unsettled active set, a
        task changed beyond its plan)."""
        if core.solver == "auto":
            return self._one_call(configuration, dt, damping, core)
        if exact is not None:
            solution = self._one_call(configuration, dt, damping, core, forced=True)
            if solution is not None:
                return solution
            exact = None
        poses = self.gather(configuration)
        if poses is None:
            return None
        self.write_settings(dt, damping, core)
        return self._rows_then_cascade(poses, configuration, dt, core, exact)

    def step_result(
        self,
        configuration: mink.Configuration,
        dt: float,
        damping: float,
        core: HierarchySolver,
        start: float,
        skip: int,
        passes: int = 0,
    ) -> StepResult | None:
        """:meth:`step` with the default solver as :meth:`qpik.IKSolver.step`'s
        :class:`StepResult` (the same numbers, no :class:`Solution` between): ``start`` the
        step's ``time.perf_counter()``, ``skip`` 1 when level 0 is the couplings' (reported
        apart), ``passes`` the correction passes (:attr:`qpik.StepOptions.correction_passes`,
        by the kernel). None where the QP path must answer."""
        if not self.general_limits:  # the lean step, its answers in row `row` of _out
            row = self._lean(configuration, dt, damping, core)
            if row >= 0:
                if passes and not self._correct(configuration, row, dt, passes):
                    return None
                core.warm_start_from_row(self._out[3], row)
                return StepResult.lean(
                    self._velocity_rows[row], _perf_counter() - start,
                    (self._out, row, skip, self, dt),
                )  # fmt: skip
            if row == -1:
                return None
        elif not passes and not core.warm_start:  # the general rows' step in one kernel call
            result = self._rows_result(configuration, dt, damping, core, start, skip)
            if result is not _GATHER:
                return result
        out = self._gathered_step(configuration, dt, damping, core, False, False)
        if out is None:
            return None
        d, v, info, general, qpos = out
        if passes:  # (the passes' sigmas resolved: no deferred records)
            corrected = self._correction().run_gathered(
                configuration, dt, passes, general, (d, v, info, None)
            )
            if corrected is None or (self._relaxable and _INFEASIBLE_CODE in corrected[2][3]):
                return None  # (the QP path corrects, or relaxes the general rows)
            d, v, info, active = corrected
            if active is not None:
                core.warm_start_from(active)
        return StepResult.lazy(
            v, d, info, skip, _perf_counter() - start,
            lambda: self._limit_rows(qpos, dt, general), deferred=self._deferred,
        )  # fmt: skip

    def _rows_step(self, configuration, dt: float, damping: float, core, forced: bool = False):
        """The gathered step from a cold start in one kernel call (``Kernel.rows_into``,
        answers in the lean step's output rows): ``(row, general rows)``; None where the QP
        path must answer (``forced``: also where a level was not solved); :data:`_GATHER`
        where a value does not load as it is (the gathered step writes it, or reports it)."""
        kernel = self.kernel
        if not kernel.load_sources(dt, damping):
            return _GATHER
        data = configuration.data
        self._attach(data)
        self._jacobians(data)
        if self.rows_tasks and not self._gather_rows(configuration):
            return None
        if core.settings_version != self._synced:
            self.sync(core)
        general = self._general(configuration, dt)
        if general is None:
            return None
        G, h, _ = general
        row = self._row
        if row == OUTPUT_ROWS:
            self._new_outputs()
            row = 0
        cap = self.max_iter or 10 * (self.nv + len(h)) + 50
        code, active = kernel.rows_into(row, G, h, cap)
        self._row = row + 1
        if code:
            return None
        status = self._out[2][row, 3].tolist()
        if (forced and any(s != _SOLVED_CODE for s in status)) or (
            self._relaxable and _INFEASIBLE_CODE in status  # (the QP path relaxes the rows)
        ):
            return None
        core.warm_start_from(active)
        return row, general

    def _rows_result(
        self, configuration, dt: float, damping: float, core, start: float, skip: int
    ) -> StepResult | None | object:
        """:meth:`step_result` with general rows, a cold start and no passes
        (:meth:`_rows_step`): its :class:`StepResult`, None or :data:`_GATHER`."""
        got = self._rows_step(configuration, dt, damping, core)
        if got is None or got is _GATHER:
            return got
        row, general = got
        out = self._out
        qpos = out[4][row]
        return StepResult.lazy(
            self._velocity_rows[row], out[0][row], out[2], skip, _perf_counter() - start,
            lambda: self._limit_rows(qpos, dt, general), row=row, deferred=out[5][row],
        )  # fmt: skip

    def _one_call(
        self, configuration, dt: float, damping: float, core, forced: bool = False
    ) -> Solution | None:
        """The whole step in one kernel call, warm started from ``core``'s active sets
        (which it then updates). ``forced``: kept only when every level was solved."""
        out = self._solve(configuration, dt, damping, core, forced)
        if out is None:
            return None
        d, v, info, general, qpos = out
        residuals, sigma, lam2, status, iterations = info[:5].tolist()
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
        self, poses: tuple, configuration, dt: float, core, forced: bool, resolve: bool = True
    ) -> tuple | None:
        """The kernel's step: ``(dq, v, info, general rows)``, None where the QP path must
        answer (``forced``: also where a level was not solved); ``core``'s active sets
        updated. ``resolve=False``: the levels' sigmas the cascade may defer left NaN
        (``Kernel.run_deferred``: half the instructions of a humanoid's weighted level)."""
        general = self._general(configuration, dt)
        if general is None:
            return None
        G, h, _ = general
        rows = self.nv + G.shape[0]  # box rows, then general rows
        warm = core.warm_sets(self.levels, rows)
        if warm is None:
            warm = self.cold_for(rows - self.nv)
        max_iter = self.max_iter or 10 * rows + 50
        if resolve:  # (on poses, attached by gather)
            code, d, v, info, active = self.kernel.run(G, h, warm, core.warm_start, max_iter)
            self._deferred = None
        else:  # the deferred sigmas' records kept for the step's result (step_result)
            code, d, v, info, active, self._deferred = self.kernel.run_deferred(
                G, h, warm, core.warm_start, max_iter
            )
        if code or (forced and any(s != _SOLVED_CODE for s in info[3].tolist())):
            return None
        if self._relaxable and _INFEASIBLE_CODE in info[3]:  # the QP path relaxes them
            return None
        core.warm_start_from(active)
        return d, v, info, general

    def velocity(
        self, configuration, dt: float, damping: float, core: HierarchySolver, exact: bool
    ) -> tuple[np.ndarray, list[LevelStatus]] | None:
        """The step's velocity ``dq / dt`` and its levels' statuses by one kernel call (as
        :meth:`step`, without the rest of its :class:`Solution`); None where :meth:`step` goes
        further (a forced backend without ``exact``, or a level it must answer)."""
        if core.solver != "auto" and not exact:
            return None
        out = self._solve(configuration, dt, damping, core, core.solver != "auto", False)
        return None if out is None else (out[1], [_STATUS_OF_CODE[s] for s in out[2][3].tolist()])

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
