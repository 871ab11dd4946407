"""The layout of a compiled plan (:mod:`.compiled`): which of a stack's tasks and limits
the kernel computes, where each one's rows and data go in the plan's arrays, and those
arrays, preallocated once per :class:`qpik.IKSolver`.

Tasks the kernel computes itself (exact types; a subclass may change the rows): qpik's or
mink's ``FrameTask``, ``PostureTask``, ``DampingTask``, ``ComTask``,
``RelativeFrameTask``, qpik's world-frame ``PositionTask``, ``OrientationTask`` and
``PoseTask`` (kinds ``POSE_KINDS``), qpik's ``JointLimitDistanceTask`` (kind
``JOINT_LIMITS_KIND``), and qpik's ``CouplingTask`` when every coupling is linear (kind
``LINEAR_KIND``: constant Jacobian, residual ``C q - offset``), a DoF-freezing task (kind
``LINEAR_KIND``, its residual zero), a kinetic-energy task (kind ``KINETIC_KIND``: the
factor of ``(cost / dt^2) M(q)``, ``M`` by the kernel); :func:`qpik.solve_ik`'s frame and
DoF-freezing
constraints (``FRAME_KIND`` / ``LINEAR_KIND`` with ``UNIT_ROWS``) and its levels' damping
terms (constants in ``user_mu``). Any other task supplies its rows each step (kind
``ROWS_KIND``, laid out by its declared count).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import mink
import mujoco
import numpy as np

from ..errors import QpikError
from ..limits.ball import BallJointLimit
from ..limits.support import SupportPolygonLimit
from ..model.com import subtree_com_chain
from ..model.configuration import limit_vectors
from ..model.frames import FRAME_JACOBIANS, FRAME_OBJECTS, FrameType
from ..model.gradients import motion_chain
from ..model.inertia import inertia_tree
from ..tasks import (
    AxisAlignTask,
    DampingTask,
    DofFreezingTask,
    EqualityConstraintTask,
    FrameTask,
    KineticEnergyRegularizationTask,
    LookAtTask,
    PostureTask,
    RelativeFrameTask,
)
from ..tasks.com import ComTask
from ..tasks.coupling import CouplingTask
from ..tasks.pose import OrientationTask, PoseTask, PositionTask
from ..tasks.secondary import JointLimitDistanceTask, ManipulabilityTask
from .boxes import LimitBoxes
from .constraints import DofConstraint, FrameConstraint, Tikhonov, dof_freezing_form
from .mink_limits import BallJointRows, FreeJointAngular, FreeJointLinear
from .rows import equality_constants

__all__ = [
    "COM_TYPES", "DAMPING_TYPES", "FRAME_TYPES", "GENERAL_LIMITS", "JACOBIANS", "KINDS",
    "KINETIC_KIND", "POSE_COST", "POSE_DATA", "POSE_KINDS", "POSE_TARGETS", "POSTURE_TYPES",
    "LimitLayout",
    "TaskLayout", "UNIT_ROWS", "com_chains", "corrected_kinds", "limit_layout", "plan_arrays",
    "task_layout",
    "joint_limit_constants",
]  # fmt: skip

KINDS = {"site": 0, "body": 1, "geom": 2}
OBJECTS = tuple(FRAME_OBJECTS[FrameType(kind)] for kind in KINDS)  # in the codes' order
JACOBIANS = tuple(FRAME_JACOBIANS[FrameType(kind)] for kind in KINDS)
#: Frame tasks computed in C++: qpik's, and mink's own class (same rows, mink's SE(3)
#: arithmetic; equal to mink's to round-off). Exact types: a subclass may change the rows.
FRAME_TYPES = (FrameTask, mink.FrameTask)
#: Relative frame tasks: qpik's (mink's with qpik's errors) and mink's. Exact types.
RELATIVE_TYPES = (RelativeFrameTask, mink.RelativeFrameTask)
#: Posture-like tasks: mink's/qpik's PostureTask (rows ``diag(cost) J``, J the identity with
#: the free joints' columns zeroed, error ``q (-) q*``) and DampingTask (error zero).
POSTURE_TYPES = (PostureTask, mink.PostureTask)
DAMPING_TYPES = (DampingTask, mink.DampingTask)
#: DoF-freezing tasks (mink's and qpik's; rows e_j for the frozen dofs, their error zero:
#: linear tasks of a zero residual, their Jacobian taken once as mink computes it once).
DOF_FREEZING_TYPES = (DofFreezingTask, mink.DofFreezingTask)
#: CoM tasks: qpik's (any subtree) and mink's (the subtree of body 1). Exact types.
COM_TYPES = (ComTask, mink.ComTask)
#: Limits of general rows ``G dq <= h`` that a plan takes, their rows from their own
#: methods each step, in the same compiled call: mink's collision avoidance (and its
#: subclasses: qpik's, over the model's pairs too), qpik's support polygon and its
#: ball-joint ranges (the rows :func:`qpik.limits.joint_limits` adds for a limited ball
#: joint; and their subclasses), but for one that says it is ``recoverable`` (its rows then
#: steer back into its region, as the QP path computes them). A row on a single dof stays a
#: general row, named as the box bound the QP path folds it into (LimitBoxes.general_rows).
GENERAL_LIMITS = (mink.CollisionAvoidanceLimit, SupportPolygonLimit, BallJointLimit)

#: Task kinds of the plan's ``tasks`` table (qpik/_cpp/diffik/fused.hpp: TaskKind).
FRAME_KIND, POSTURE_KIND, COM_KIND, RELATIVE_KIND = 0, 1, 2, 3
DAMPING_KIND, ROWS_KIND, LINEAR_KIND = 4, 5, 6
#: Added to ``FRAME_KIND`` or ``LINEAR_KIND``: a constraint's rows (:class:`.constraints.
#: FrameConstraint`, ``DofConstraint``: unit costs, each row scaled to unit norm, weight
#: ``UNDAMPED_WEIGHT``, no LM term; fused.hpp UNIT_ROWS).
UNIT_ROWS = 32
#: qpik's JointLimitDistanceTask (qpik/_cpp/tasks/joint_limits.hpp): one row, its constants
#: in the linear tasks' table (:func:`joint_limit_constants`), its cost, gain and LM
#: damping loaded as theirs.
JOINT_LIMITS_KIND = 10
#: qpik's world-frame pose tasks (qpik/_cpp/tasks/pose.hpp), and mink's and qpik's look-at
#: and axis-align tasks (tasks/look_at.hpp, axis_align.hpp), a frame of the ``frames``
#: table each, by exact type: their kind (7 position, 8 orientation, 9 both, 11 look-at,
#: 12 axis-align) and rows.
LOOK_AT_KIND, AXIS_ALIGN_KIND = 11, 12
#: mink's and qpik's KineticEnergyRegularizationTask (qpik/_cpp/tasks/kinetic.hpp; exact
#: types): nv rows, ``L^T`` of ``(cost / dt^2) M(q) = L L^T`` (``M`` made by the kernel,
#: :mod:`qpik.model.inertia`), its cost and ``inv_dt_sq`` in a row of ``ke_data``.
KINETIC_KIND = 13
KINETIC_TYPES = (KineticEnergyRegularizationTask, mink.KineticEnergyRegularizationTask)
#: qpik's ManipulabilityTask (qpik/_cpp/tasks/manipulability.hpp): one row, a frame of the
#: ``frames`` table, the indices of its rows in its data row (their number at 0, then at
#: most ``MANIPULABILITY_ROWS`` of them), at ``POSE_COST + 1`` 1 where a ball or free joint
#: moves the frame (the kernel's dof thresholds, :meth:`ManipulabilityTask.chain`).
MANIPULABILITY_KIND, MANIPULABILITY_ROWS = 14, 11
#: mink's and qpik's EqualityConstraintTask (qpik/_cpp/tasks/equality.hpp; exact types):
#: MuJoCo's constraint rows of its equalities (connect 3, weld 6, joint and tendon 1 each),
#: its planned rows and each equality's position in ``eq_map``, its costs by position, gain
#: and LM damping in ``eq_data``.
EQUALITY_KIND = 15
EQUALITY_TYPES = (EqualityConstraintTask, mink.EqualityConstraintTask)
#: The rows of each kind of equality (mjtEq: connect, weld, joint, tendon).
EQUALITY_WIDTHS = {0: 3, 1: 6, 2: 1, 3: 1}
POSE_KINDS: dict[type, tuple[int, int]] = {
    PositionTask: (7, 3),
    OrientationTask: (8, 3),
    PoseTask: (9, 6),
    LookAtTask: (LOOK_AT_KIND, 3),
    mink.LookAtTask: (LOOK_AT_KIND, 3),
    AxisAlignTask: (AXIS_ALIGN_KIND, 3),
    mink.AxisAlignTask: (AXIS_ALIGN_KIND, 3),
    ManipulabilityTask: (MANIPULABILITY_KIND, 1),
}
#: A pose task's data row (``frame_data`` then has ``POSE_DATA`` columns): its targets'
#: entries by attribute (position 0:3 [m], rotation 3:12 row-major; a look-at task's point
#: [m] or an axis-align task's direction 0:3 and the frame's axis 3:6), then its cost at
#: ``POSE_COST`` (3 or 6 entries), gain and LM damping at ``POSE_COST + 6`` and ``+ 7``.
POSE_TARGETS: dict[type, tuple[tuple[str, int, int], ...]] = {
    PositionTask: (("target", 0, 3),),
    OrientationTask: (("_rotation_entries", 3, 12),),  # (the target's 9 entries, 1-D)
    PoseTask: (("target_position", 0, 3), ("_rotation_entries", 3, 12)),
    LookAtTask: (("target_pos", 0, 3), ("axis", 3, 6)),
    mink.LookAtTask: (("target_pos", 0, 3), ("axis", 3, 6)),
    AxisAlignTask: (("target_dir", 0, 3), ("axis", 3, 6)),
    mink.AxisAlignTask: (("target_dir", 0, 3), ("axis", 3, 6)),
    ManipulabilityTask: (),  # (no target: its rows' indices written once, plan_arrays)
}
POSE_COST, POSE_DATA = 12, 20
#: Per-dof kinds of ``posture_map`` (fused.hpp: PostureDof).
SCALAR_DOF, FREE_DOF, BALL_FIRST, BALL_OTHER = 0, 1, 2, 3


def corrected_kinds(tasks: np.ndarray) -> bool:
    """Whether the kernel's correction passes cover every task of a plan's ``tasks`` table
    (fused.hpp corrected_kind): not a constraint's unit rows, nor a look-at, axis-align or
    kinetic-energy task's (``CompiledPlan`` leaves their correction to the QP path)."""
    kinds = tasks[:, 0]
    others = (LOOK_AT_KIND, AXIS_ALIGN_KIND, KINETIC_KIND, MANIPULABILITY_KIND, EQUALITY_KIND)
    return not ((kinds & UNIT_ROWS).any() or np.isin(kinds, others).any())


@dataclass(frozen=True)
class TaskLayout:
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
    linears: list  # (task, form (k, nq + 1), jacobian (k, nv)) of the linear tasks
    #: the levels' constant LM terms (qpik.solve_ik's Tikhonov tasks, no rows): (entry of
    #: ``tasks``, damping), their ``user_mu`` entries after the row-supplying tasks'
    mus: list = field(default_factory=list)
    #: the kinetic-energy tasks, in ``ke_data``'s order
    kinetics: list = field(default_factory=list)
    #: the equality-constraint tasks: (task, planned rows, positions (neq,)), in ``eq_map``'s
    equalities: list = field(default_factory=list)

    @property
    def has_pose(self) -> bool:
        """Whether a frame of the plan is a world-frame pose task's (``frame_data`` is then
        ``POSE_DATA`` wide)."""
        return any(type(task) in POSE_KINDS for task, *_ in self.frames)


@dataclass(frozen=True)
class LimitLayout:
    """The entries of a plan's limits: position limits (``cfg_dof``, ``cfg_qadr``,
    ``cfg_data`` rows (lower, upper, gain), and ``(limit, first, last entry)``), velocity
    limits (``vel_dof``, ``vel_limit``, and ``(limit, first, last entry)``) and the
    general-row limits."""

    cfg_dof: list
    cfg_qadr: list
    cfg_data: list
    config_limits: list
    vel_dof: list
    vel_limit: list
    general_limits: list
    vel_limits: list


def plan_arrays(
    model: mujoco.MjModel, layout: TaskLayout, boxes: LimitLayout, limits: LimitBoxes
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
    lin_sizes = [form.shape[0] for _, form, _ in layout.linears]
    lin_starts = np.concatenate([[0], np.cumsum(lin_sizes, dtype=i64)]).astype(i64)
    frame_data = np.zeros((F, POSE_DATA if layout.has_pose else 15))
    for f, (task, *frame) in enumerate(layout.frames):
        if type(task) is ManipulabilityTask:  # (constants: its rows' number and indices)
            picked = task.row_indices
            frame_data[f, 0], frame_data[f, 1 : 1 + len(picked)] = len(picked), picked
            # (1: a ball or free joint moves it, the kernel's dof thresholds)
            frame_data[f, POSE_COST + 1] = free_or_ball_chain(model, frame)
    lin_const = np.zeros((int(lin_starts[-1]), nv + nq + 1))
    for (_, form, jacobian), r0, r1 in zip(layout.linears, lin_starts[:-1], lin_starts[1:]):
        lin_const[r0:r1, :nv] = jacobian
        lin_const[r0:r1, nv:] = form
    return {
        "A": np.zeros((M, nv)),
        "b": np.zeros(M),
        "w": np.zeros(M),
        "starts": np.asarray(layout.starts, dtype=i64),
        "tasks": np.asarray(layout.tasks, dtype=i64).reshape(-1, 4),
        "jac": np.zeros((F, 6, nv)),
        "frames": np.asarray(frames, dtype=i64).reshape(-1, 2),
        "frame_data": frame_data,
        "posture_data": np.zeros((P, nq + nv + 2)),
        "posture_map": posture_map(model),
        "cfg_dof": np.asarray(boxes.cfg_dof, dtype=i64),
        "cfg_qadr": np.asarray(boxes.cfg_qadr, dtype=i64),
        "cfg_data": np.asarray(boxes.cfg_data, dtype=float).reshape(-1, 3),
        "vel_dof": np.asarray(vel_dof, dtype=i64),
        "vel_limit": np.asarray(vel_limit, dtype=float),
        "settings": np.zeros(8),
        "com_jac": np.zeros((C, 3, nv)),
        "com_body": np.asarray([body for _, body, _ in layout.coms], dtype=i64),
        "com_data": np.zeros((C, 8)),
        "rel_jac": np.zeros((R, 12, nv)),
        "rel_frames": np.asarray(rel_frames, dtype=i64).reshape(-1, 4),
        "rel_data": np.zeros((R, 15)),
        "user_mu": np.array([0.0] * len(layout.rows_tasks) + [mu for _, mu in layout.mus]),
        "lin_starts": lin_starts,
        "lin_const": lin_const,
        "lin_data": np.zeros((3, int(lin_starts[-1]))),
        "ke_data": np.zeros((len(layout.kinetics), 2)),
        "eq_map": np.array(
            [[rows, *position] for _, rows, position in layout.equalities], dtype=np.int64
        ).reshape(-1, model.neq + 1),
        "eq_data": np.zeros((len(layout.equalities), model.neq + 2)),
        "empty3": np.zeros((0, 3)),
        "empty9": np.zeros((0, 9)),
    }


def posture_map(model: mujoco.MjModel) -> np.ndarray:
    """Per dof ``(kind, qpos address)`` (see ``SCALAR_DOF``...): how a posture task's
    error ``q (-) q*`` (``mj_differentiatePos``) reads ``qpos``."""
    out = np.zeros((model.nv, 2), dtype=np.int64)
    for j in range(model.njnt):
        kind, q0, v0 = int(model.jnt_type[j]), int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            out[v0 : v0 + 6] = (FREE_DOF, q0)
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            out[v0] = (BALL_FIRST, q0)
            out[v0 + 1 : v0 + 3] = (BALL_OTHER, q0)
        else:
            out[v0] = (SCALAR_DOF, q0)
    return out


def frame_entry(model: mujoco.MjModel, frame_type, frame_name) -> tuple[int, int] | None:
    """``(kind, id)`` of a frame, None when the QP path must serve it (an unknown
    frame type or name: it reports them)."""
    kind = KINDS.get(getattr(frame_type, "value", frame_type))
    if kind is None:
        return None
    if isinstance(frame_name, (int, np.integer)) and not isinstance(frame_name, bool):
        count = (model.nsite, model.nbody, model.ngeom)[kind]
        return (kind, int(frame_name)) if 0 <= frame_name < count else None
    if not isinstance(frame_name, str):
        return None
    fid = mujoco.mj_name2id(model, OBJECTS[kind], frame_name)
    return None if fid < 0 else (kind, fid)


def com_body(model: mujoco.MjModel, task) -> tuple[int, object] | None:
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


def declared_rows(task, nv: int) -> int:
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


def task_layout(model: mujoco.MjModel, levels: Sequence[Sequence]) -> TaskLayout | None:
    """The layout of a stack: the tasks the kernel computes (qpik's or mink's FrameTask /
    PostureTask / DampingTask / ComTask / RelativeFrameTask, qpik's linear
    CouplingTask; exact types) and those that supply their rows (any other); None where a
    task the kernel computes names what the model lacks (the QP path reports it). Rows are
    laid out level by level, task by task."""
    layout = TaskLayout([], [], [], [], [], [], [0], [], [])
    for k, level in enumerate(levels):
        row = layout.starts[-1]
        for task in level:
            size = _place(layout, model, task, k, row)
            if size is None:
                return None
            row += size
        layout.starts.append(row)
    first = len(layout.rows_tasks)
    for j, (entry, _damping) in enumerate(layout.mus):
        code, _, k, row = layout.tasks[entry]
        layout.tasks[entry] = (code, first + j, k, row)
    return layout


def _place(layout: TaskLayout, model: mujoco.MjModel, task, k: int, row: int) -> int | None:
    """Enter ``task`` (level ``k``, first row ``row``) in ``layout``; its row count, None
    where it names what the model lacks."""
    kind, nv = type(task), model.nv
    if kind is ManipulabilityTask and not _manipulability_fits(model, task):
        pass  # (its rows supplied, below)
    elif kind in FRAME_TYPES or kind in RELATIVE_TYPES or kind in POSE_KINDS:
        return _place_frame(layout, model, task, k, row)
    if kind is FrameConstraint:  # its frame rows, unit costs, each row then of unit norm
        size = _place_frame(layout, model, task, k, row)
        if size is not None:
            code, index, level, first = layout.tasks[-1]
            layout.tasks[-1] = (code | UNIT_ROWS, index, level, first)
        return size
    if kind is Tikhonov:  # no rows: its damping, the level's LM term (user_mu, constant)
        layout.tasks.append((ROWS_KIND, -1, k, row))
        layout.mus.append((len(layout.tasks) - 1, float(task.damping)))
        return 0
    if kind in _MODEL_TYPES or (kind in KINETIC_TYPES and inertia_tree(model) is not None):
        return _place_model_task(layout, model, task, k, row)
    if kind in EQUALITY_TYPES and (planned := equality_layout(model, task)) is not None:
        layout.tasks.append((EQUALITY_KIND, len(layout.equalities), k, row))
        layout.equalities.append((task, *planned))
        return planned[0]
    linear = _linear_form(model, task)
    if kind is JointLimitDistanceTask:
        linear = joint_limit_constants(model, task)
        if linear is None:
            return None
        layout.tasks.append((JOINT_LIMITS_KIND, len(layout.linears), k, row))
        layout.linears.append((task, *linear))
        return 1
    if linear is not None:
        form, jacobian = linear
        code = LINEAR_KIND | (UNIT_ROWS if kind is DofConstraint else 0)
        layout.tasks.append((code, len(layout.linears), k, row))
        layout.linears.append((task, form, jacobian))
        return form.shape[0]
    size = declared_rows(task, nv)  # rows supplied by the task itself, each step
    layout.tasks.append((ROWS_KIND, len(layout.rows_tasks), k, row))
    layout.rows_tasks.append((task, row, row + size))
    return size


#: The tasks :func:`_place_model_task` places (their rows over the whole model).
_MODEL_TYPES = (*POSTURE_TYPES, *DAMPING_TYPES, *COM_TYPES)


def _place_model_task(
    layout: TaskLayout, model: mujoco.MjModel, task, k: int, row: int
) -> int | None:
    """:func:`_place` for a posture, damping, kinetic-energy or CoM task; None where its
    cost does not have its rows' shape or a CoM task's body is not the model's."""
    kind, nv = type(task), model.nv
    if kind in POSTURE_TYPES or kind in DAMPING_TYPES:
        if np.shape(getattr(task, "cost", 0.0)) != (nv,):
            return None
        code = DAMPING_KIND if kind in DAMPING_TYPES else POSTURE_KIND
        layout.tasks.append((code, len(layout.postures), k, row))
        layout.postures.append(task)
        return nv
    if kind in KINETIC_TYPES:  # (on a model whose M the kernel makes: inertia_tree)
        layout.tasks.append((KINETIC_KIND, len(layout.kinetics), k, row))
        layout.kinetics.append(task)
        return nv
    entry = com_body(model, task)  # (a CoM task)
    if entry is None or np.shape(task.cost) != (3,):
        return None
    layout.tasks.append((COM_KIND, len(layout.coms), k, row))
    layout.coms.append((task, *entry))
    return 3


def equality_layout(model: mujoco.MjModel, task) -> tuple[int, np.ndarray] | None:
    """An equality-constraint task's planned rows (its equalities' widths summed: each one
    active) and each equality's position in it (:func:`.rows.equality_constants`), None
    where the kernel does not compute it (the task does not hold them as mink 1.3 does, or
    an equality of another kind, a flex's)."""
    position = equality_constants(task, model.neq)
    ids = getattr(task, "_eq_ids", None)
    if position is None or not isinstance(ids, np.ndarray):
        return None
    widths = [EQUALITY_WIDTHS.get(int(model.eq_type[e])) for e in ids.tolist()]
    if None in widths:
        return None
    return sum(widths), position  # type: ignore[arg-type]


def _manipulability_fits(model: mujoco.MjModel, task: ManipulabilityTask) -> bool:
    """Whether the kernel computes a manipulability task: its frame the model's, at most
    ``MANIPULABILITY_ROWS`` rows picked, its cost one number."""
    frame = frame_entry(model, task.frame_type, task.frame_name)
    return not (
        frame is None or len(task.row_indices) > MANIPULABILITY_ROWS or np.shape(task.cost) != (1,)
    )


def free_or_ball_chain(model: mujoco.MjModel, frame: tuple[int, int]) -> bool:
    """Whether a ball or free joint moves a manipulability task's frame ``(kind, id)`` (the
    kernel then takes the dofs' Hessian thresholds: :func:`qpik.model.gradients.motion_chain`)."""
    kind, fid = frame
    body = fid if kind == 1 else int((model.site_bodyid, model.geom_bodyid)[kind // 2][fid])
    return motion_chain(model, body)[1] is not None


def _linear_form(model: mujoco.MjModel, task) -> tuple | None:
    """``(form (k, nq + 1), jacobian (k, nv))`` of a task the plan takes as linear (qpik's
    CouplingTask where its couplings are, a DofConstraint, a DoF-freezing task: its rows
    constant, its error zero, as mink computes them once), else None."""
    kind = type(task)
    if kind is CouplingTask or kind is DofConstraint:
        return task.linear_form
    if kind in DOF_FREEZING_TYPES:
        return dof_freezing_form(task, model.nq)
    return None


def joint_limit_constants(model: mujoco.MjModel, task) -> tuple | None:
    """A joint-limit distance task's constants in the linear tasks' table (its one row of
    ``lin_const``, kind ``JOINT_LIMITS_KIND``): ``(form (1, nq + 1), jacobian (1, nv))``,
    the half range by dof (0 where the dof is not a limited joint's) as its Jacobian row,
    mid / half by qpos address and ``n`` (the scalar joints counted) as its form; None where
    its cost is not one number or the limits do not check (the QP path reports them)."""
    if np.shape(getattr(task, "cost", 0.0)) != (1,):
        return None
    lower, upper = limit_vectors(model)
    try:
        qadr, dofs, half, mid_over_half, n = task.limited_joints(model, lower, upper)
    except QpikError:
        return None
    jacobian = np.zeros((1, model.nv))
    jacobian[0, dofs] = half
    form = np.zeros((1, model.nq + 1))
    form[0, qadr] = mid_over_half
    form[0, -1] = n
    return form, jacobian


def _place_frame(layout: TaskLayout, model: mujoco.MjModel, task, k: int, row: int) -> int | None:
    """:func:`_place` for a frame, relative frame or world-frame pose task (6 rows; a
    position or orientation task 3)."""
    frame = frame_entry(model, task.frame_type, task.frame_name)
    if frame is None:
        return None
    pose = POSE_KINDS.get(type(task))
    if pose is not None:
        code, size = pose
        if np.shape(getattr(task, "cost", 0.0)) != (size,):
            return None  # a cost not of its rows' shape: the QP path reports it
        layout.tasks.append((code, len(layout.frames), k, row))
        layout.frames.append((task, *frame))
        layout.frame_rows.append((frame, False))
        return size
    if type(task) in RELATIVE_TYPES:
        root = frame_entry(model, task.root_type, task.root_name)
        if root is None:
            return None
        layout.tasks.append((RELATIVE_KIND, len(layout.relatives), k, row))
        layout.relatives.append((task, frame, root))
        layout.frame_rows.extend(((frame, True), (root, True)))
        return 6
    layout.tasks.append((FRAME_KIND, len(layout.frames), k, row))
    layout.frames.append((task, *frame))
    layout.frame_rows.append((frame, False))
    return 6


def limit_layout(model: mujoco.MjModel, limits: Sequence) -> LimitLayout | None:
    """The entries of mink's position and velocity limits and its collision avoidance
    limits, a position limit's ball-joint rows as general rows and a free-joint velocity
    limit's angular bounds as box entries and its linear rows as general rows (views of
    them: :mod:`.mink_limits`); None when another limit is present."""
    cfg_dof: list[int] = []
    cfg_qadr: list[int] = []
    cfg_data: list[tuple[float, float, float]] = []
    config_limits: list[tuple] = []
    vel_dof: list[int] = []
    vel_limit: list[float] = []
    vel_limits: list[tuple] = []
    general_limits: list = []
    for limit in limits:
        if type(limit) is mink.ConfigurationLimit:
            if limits_a_ball_joint(limit.model):  # its cones' rows: general rows
                general_limits.append(BallJointRows(limit))
            indices = np.asarray(limit.indices, dtype=np.int64)
            qadr = model.jnt_qposadr[model.dof_jntid[indices]].astype(np.int64)
            e0 = len(cfg_dof)
            cfg_dof.extend(indices.tolist())
            cfg_qadr.extend(qadr.tolist())
            lower, upper = np.asarray(limit.lower)[qadr], np.asarray(limit.upper)[qadr]
            cfg_data.extend(zip(lower.tolist(), upper.tolist(), [0.0] * len(indices)))
            config_limits.append((limit, e0, len(cfg_dof)))
        elif type(limit) is mink.VelocityLimit:
            v0 = len(vel_dof)
            vel_dof.extend(np.asarray(limit.indices, dtype=np.int64).tolist())
            vel_limit.extend(np.asarray(limit.limit, dtype=float).tolist())
            vel_limits.append((limit, v0, len(vel_dof)))
        elif type(limit) is mink.FreeJointVelocityLimit:  # (mink 1.3's attributes read)
            try:
                linear = FreeJointLinear(limit) if limit.linear_max is not None else None
                angular = FreeJointAngular(limit) if limit.angular_max is not None else None
            except (AttributeError, IndexError, TypeError):
                return None
            if angular is not None:  # its angular bounds: velocity-limit box entries
                v0 = len(vel_dof)
                vel_dof.extend(angular.indices.tolist())
                vel_limit.extend(np.asarray(angular.limit, dtype=float).tolist())
                vel_limits.append((angular, v0, len(vel_dof)))
            if linear is not None:  # its linear rows: general rows
                general_limits.append(linear)
        elif isinstance(limit, GENERAL_LIMITS) and not getattr(limit, "recoverable", False):
            general_limits.append(limit)
        elif is_user_limit(limit):
            general_limits.append(limit)  # (its rows from its own method, each step)
        else:
            return None
    return LimitLayout(
        cfg_dof, cfg_qadr, cfg_data, config_limits, vel_dof, vel_limit, general_limits, vel_limits
    )


#: Limits whose rows the QP path reads as bounds of boxes (a subclass of one of them, too):
#: not a user limit of general rows (:func:`is_user_limit`).
_BOX_KINDS = (mink.ConfigurationLimit, mink.VelocityLimit, mink.FreeJointVelocityLimit)


def is_user_limit(limit: object) -> bool:
    """A limit of the user's own class (a ``mink.Limit`` subclass qpik does not know, or
    any object with ``compute_qp_inequalities``) whose rows are hard general rows: not one
    of mink's box limits or a subclass of one, not ``recoverable`` (rows that steer back
    into a region, which the QP path computes) and not ``relaxable_rows``. The compiled step
    takes its rows as it takes the collision rows (:meth:`LimitBoxes.general_rows`: its
    ``compute_qp_inequalities`` each step, a row on one dof kept as a general row, an empty
    row no displacement meets sending the step to the QP path, which names it)."""
    return (
        callable(getattr(limit, "compute_qp_inequalities", None))
        and not isinstance(limit, _BOX_KINDS)
        and not getattr(limit, "recoverable", False)
        and not getattr(limit, "relaxable_rows", False)
    )


def limits_a_ball_joint(model: mujoco.MjModel) -> bool:
    """A ball joint of ``model`` has a range (mink's ConfigurationLimit bounds its rotation
    angle by a general row: the compiled step takes it from
    :class:`.mink_limits.BallJointRows`)."""
    ball = model.jnt_type == mujoco.mjtJoint.mjJNT_BALL
    return bool(np.any(ball & (model.jnt_limited != 0)))


#: ``settings`` entries of the kernel.
DT, DAMPING, THRESHOLD, MAX_DAMPING, ERROR_SCALE, RANK_TOL, TOL, LOWER_TRUST = range(8)


def com_chains(model: mujoco.MjModel, bodies: list[int]) -> list:
    """Per CoM task (its subtree's root body), the per-dof chain of its Jacobian
    (:func:`qpik.model.com.subtree_com_chain`); [] when any subtree has no mass (then
    MuJoCo's ``mj_jacSubtreeCom`` gives every one)."""
    chains = [subtree_com_chain(model, body) for body in bodies]
    return chains if all(c is not None for c in chains) else []
