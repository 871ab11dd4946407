"""Statics: the joint torques that forces and torques on a robot at rest produce.

A wrench ``w = [f; t]`` (force ``f`` [N] and torque ``t`` [N m], world-aligned) acting at
the origin of a frame produces the joint torques

    tau = J(q)^T [f; t]                                                  (nv,) [N m or N]

where ``J`` is the frame's world-aligned Jacobian ``[v; omega] = J(q) qdot``
(:meth:`Configuration.frame_jacobian`). This is the kineto-static duality, read column
by column: for a revolute joint ``i`` with unit axis ``k_i`` and ``r_i`` the vector from
the joint to the frame origin, ``tau_i = k_i . (r_i x f) + k_i . t``. It is the dual of the
kinematic relation: the power ``(J qdot) . w`` that the wrench delivers equals the power
``qdot . tau`` at the joints.

Sign convention, used by every function here: a torque that something *produces* at the
joints is a generalized force acting on the robot, like MuJoCo's ``qfrc_applied``.
:func:`joint_torques` and :func:`gravity_torques` return produced torques. The motors hold
the robot still by cancelling the sum of what everything else produces, so
:func:`holding_torques` returns ``-(gravity_torques + sum of joint_torques)``: the motor
torques to command (``qfrc_actuator`` in MuJoCo).

All functions read the configuration's current ``q`` (run ``configuration.update(q)``
first) and leave the configuration's data untouched.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt

from .core import checks
from .errors import InvalidArgumentType, InvalidInput
from .model.configuration import Configuration, FrameType, joint_names

__all__ = [
    "ForceEllipsoid",
    "PayloadLimit",
    "ReferenceFrame",
    "WrenchEstimate",
    "force_ellipsoid",
    "gravity_torques",
    "holding_torques",
    "joint_torque_limits",
    "joint_torques",
    "max_payload",
    "wrench_from_torques",
]

#: Joint types with one dof (compared as ints: model arrays hold ints).
_SCALAR_JOINTS = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))

#: Relative tolerance on singular values below which a direction counts as lost.
DEFAULT_RCOND = 1e-8

#: A frame: its name (frame type ``site``), or ``(name, frame_type)``.
FrameSpec = str | int | tuple[str | int, FrameType | str]


class ReferenceFrame(str, enum.Enum):
    """Axes a force and torque are expressed in. The strings ``"world"`` and ``"local"``
    are accepted wherever a ``ReferenceFrame`` is."""

    #: World axes.
    WORLD = "world"
    #: The axes of the frame the wrench acts at (its rotation in ``frame_pose``).
    LOCAL = "local"

    @classmethod
    def parse(cls, value: ReferenceFrame | str) -> ReferenceFrame:
        """Convert a string or ReferenceFrame to a ReferenceFrame, with a clear error."""
        if isinstance(value, ReferenceFrame):
            return value
        try:
            return cls(str(value).lower())
        except ValueError:
            raise InvalidInput(f"expressed_in must be 'world' or 'local', got {value!r}") from None


# ------------------------------------------------------------------------- validation
#: What every function here takes as its first argument.
_CONFIGURATION = (
    "a qpik.Configuration (build one with qpik.Configuration(qpik.load_robot(name), q))"
)


def _check_configuration(configuration: Configuration) -> None:
    """A :class:`qpik.Configuration`, else :class:`qpik.errors.InvalidArgumentType` (a
    ``TypeError`` too)."""
    checks.check_instance("configuration", configuration, Configuration, _CONFIGURATION)


def _finite(what: str, tau: np.ndarray) -> np.ndarray:
    """``tau`` if finite, else :class:`InvalidInput` (the model's sizes overflow)."""
    return checks.check_finite_output(what, tau)


def _frame(frame: FrameSpec, frame_type: FrameType | str = FrameType.SITE):
    """Split a frame spec into ``(name, FrameType)``."""
    if isinstance(frame, tuple):
        if len(frame) != 2:
            raise InvalidInput(f"a frame is a name or (name, frame_type), got {frame!r}")
        frame, frame_type = frame
    return frame, FrameType.parse(frame_type)


# ---------------------------------------------------------------------- joint torques
def joint_torques(
    configuration: Configuration,
    frame: str | int,
    force: npt.ArrayLike,
    torque: npt.ArrayLike | None = None,
    frame_type: FrameType | str = FrameType.SITE,
    expressed_in: ReferenceFrame | str = ReferenceFrame.WORLD,
) -> np.ndarray:
    """Joint torques ``tau = J^T [f; t]`` ``(nv,)`` [N m, or N for slide joints] that a
    wrench acting at the frame origin produces.

    ``tau`` is the torque the external wrench exerts on the joints (a generalized force
    on the robot, as MuJoCo's ``mj_applyFT`` computes it). To hold the robot still
    against the wrench the motors must apply ``-tau``.

    Args:
        configuration: Robot at rest at its current ``q``.
        frame: Name (or id) of the frame whose origin the wrench acts at.
        force: Force ``f`` ``(3,)`` [N] acting on the robot.
        torque: Torque ``t`` ``(3,)`` [N m] acting on the robot; zero when omitted.
        frame_type: ``"site"`` (default), ``"body"`` (body frame origin, not the
            centre of mass) or ``"geom"``.
        expressed_in: ``"world"`` (default): ``f`` and ``t`` are in world axes;
            ``"local"``: in the frame's own axes (rotated to world here).
    """
    _check_configuration(configuration)
    kind = FrameType.parse(frame_type)
    axes = ReferenceFrame.parse(expressed_in)
    f = checks.check_vector("force", force, 3)
    t = np.zeros(3) if torque is None else checks.check_vector("torque", torque, 3)
    jacobian = configuration.frame_jacobian(frame, kind)
    if axes is ReferenceFrame.LOCAL:
        _, rotation = configuration.frame_pose(frame, kind)
        f, t = rotation @ f, rotation @ t
    return _finite("the joint torques", jacobian.T @ np.concatenate([f, t]))


def _zero_velocity_data(configuration: Configuration) -> mujoco.MjData:
    """A scratch MjData at the configuration's ``q`` with zero velocity, forward-computed."""
    model = configuration.model
    scratch = mujoco.MjData(model)
    scratch.qpos[:] = configuration.data.qpos
    scratch.qvel[:] = 0.0
    if model.nmocap:
        scratch.mocap_pos[:] = configuration.data.mocap_pos
        scratch.mocap_quat[:] = configuration.data.mocap_quat
    mujoco.mj_forward(model, scratch)
    return scratch


def gravity_torques(configuration: Configuration) -> np.ndarray:
    """Joint torques ``(nv,)`` [N m or N] that gravity *produces* at the current ``q``.

    Computed by MuJoCo as ``-qfrc_bias`` at zero velocity (where the bias force is
    gravity alone), on a scratch ``MjData``: the configuration's data is unchanged. Same
    sign convention as :func:`joint_torques`: the torque that compensates gravity (what
    the motors apply) is ``-gravity_torques(configuration)``.
    """
    _check_configuration(configuration)
    return _finite("the gravity torques", -_zero_velocity_data(configuration).qfrc_bias.copy())


def _wrench_items(
    wrenches: Iterable,
) -> list[tuple[str | int, FrameType, npt.ArrayLike, npt.ArrayLike | None]]:
    if isinstance(wrenches, (str, bytes, dict)) or not checks.is_iterable(wrenches):
        raise InvalidArgumentType(
            "wrenches", "a sequence of (frame, force[, torque]) tuples", checks.type_name(wrenches)
        )
    items = []
    for k, item in enumerate(wrenches):
        if not isinstance(item, (tuple, list)) or len(item) not in (2, 3):
            raise InvalidInput(
                f"wrenches[{k}] must be (frame, force) or (frame, force, torque), got {item!r}"
            )
        frame, force, torque = (*item, None) if len(item) == 2 else item
        name, kind = _frame(frame)
        items.append((name, kind, force, torque))
    return items


def holding_torques(
    configuration: Configuration,
    wrenches: Iterable[tuple] = (),
    gravity: bool = True,
) -> np.ndarray:
    """Motor torques ``(nv,)`` [N m or N] that hold the robot still at its current ``q``.

    ``holding = -(gravity_torques + sum_k J_k^T [f_k; t_k])``: the generalized force the
    actuators must apply (MuJoCo's ``qfrc_actuator``) so that, at zero velocity, the
    robot does not accelerate. Joint damping plays no part at zero velocity. When
    ``gravity`` is true the model's other passive forces at zero velocity (joint
    springs, gravity compensation) are cancelled too; the bundled robots have none.

    Args:
        configuration: Robot at rest at its current ``q``.
        wrenches: Contact wrenches acting on the robot, each ``(frame, force)`` or
            ``(frame, force, torque)``, with force [N] and torque [N m] in world axes at
            the frame origin; ``frame`` is a site name or ``(name, frame_type)``.
        gravity: Whether to hold the robot against gravity as well.
    """
    _check_configuration(configuration)
    gravity = checks.check_bool("gravity", gravity)
    tau = np.zeros(configuration.model.nv)
    for k, (name, kind, force, torque) in enumerate(_wrench_items(wrenches)):
        try:
            tau += joint_torques(configuration, name, force, torque, kind)
        except InvalidInput as exc:
            raise InvalidInput(f"wrenches[{k}]: {exc}") from None
    if gravity:
        scratch = _zero_velocity_data(configuration)
        tau += scratch.qfrc_passive - scratch.qfrc_bias
    return _finite("the holding torques", -tau)


# ------------------------------------------------------------------- wrench estimation
@dataclass(frozen=True)
class WrenchEstimate:
    """Least-squares wrench at a frame from joint torques (see :func:`wrench_from_torques`).

    Attributes:
        force: Estimated force ``(3,)`` [N], world axes.
        torque: Estimated torque ``(3,)`` [N m], world axes, about the frame origin.
        residual: ``tau - J^T [force; torque]`` ``(nv,)``: the part of ``tau`` that no
            wrench at this frame explains (model error, other contacts, noise).
        rank: Rank of ``J`` (6 when every wrench direction is observed).
        singular_values: Singular values of ``J``, largest first (``min(6, nv)``).
        unobservable: ``(6 - rank, 6)``: orthonormal wrench directions ``[f; t]`` that
            produce no joint torque (``J^T u = 0``). Their component is not estimated
            (the estimate has none of it).
    """

    force: np.ndarray
    torque: np.ndarray
    residual: np.ndarray
    rank: int
    singular_values: np.ndarray
    unobservable: np.ndarray

    @property
    def wrench(self) -> np.ndarray:
        """``[force; torque]`` ``(6,)``."""
        return np.concatenate([self.force, self.torque])

    @property
    def observable(self) -> bool:
        """Whether every wrench direction is observed (``rank == 6``)."""
        return self.rank == 6


def wrench_from_torques(
    configuration: Configuration,
    frame: str | int,
    tau: npt.ArrayLike,
    frame_type: FrameType | str = FrameType.SITE,
    rcond: float = DEFAULT_RCOND,
) -> WrenchEstimate:
    """Least-squares estimate of the wrench at the frame origin that produces ``tau``.

    Solves ``J^T w = tau`` for ``w = [f; t]`` by SVD, ``J = U S V^T``: the minimum-norm
    least-squares solution ``w = U_r S_r^-1 V_r^T tau`` over the singular values above
    ``rcond * s_max``. Columns of ``U`` beyond the rank are wrench directions the joints
    cannot sense: at a singular pose, or always when ``nv < 6``.

    ``tau`` follows :func:`joint_torques`' convention (the torque the wrench produces).
    From motor torques ``tau_m`` measured while the robot holds still, use
    ``tau = -(tau_m - holding_torques(configuration))`` (gravity removed). Note that the
    SVD mixes [N] and [N m]: which small direction is lost depends on the units.

    Args:
        configuration: Robot at rest at its current ``q``.
        frame: Frame whose origin the wrench acts at.
        tau: Joint torques ``(nv,)`` [N m or N].
        frame_type: ``"site"`` (default), ``"body"`` or ``"geom"``.
        rcond: Singular values below ``rcond`` times the largest count as zero.
    """
    _check_configuration(configuration)
    tau = checks.check_vector("tau", tau, configuration.model.nv)
    rcond = checks.check_real("rcond", rcond, 0.0, 1.0)
    jacobian = configuration.frame_jacobian(frame, frame_type)
    u, s, vt = np.linalg.svd(jacobian, full_matrices=True)
    rank = int(np.sum(s > rcond * s[0])) if s.size and s[0] > 0 else 0
    wrench = u[:, :rank] @ ((vt[:rank] @ tau) / s[:rank])
    return WrenchEstimate(
        force=wrench[:3],
        torque=wrench[3:],
        residual=tau - jacobian.T @ wrench,
        rank=rank,
        singular_values=s,
        unobservable=u[:, rank:].T.copy(),
    )


# -------------------------------------------------------------------- force ellipsoid
@dataclass(frozen=True)
class ForceEllipsoid:
    """The force manipulability ellipsoid ``{w : |J_r^T w| <= 1}`` (see
    :func:`force_ellipsoid`).

    Attributes:
        axes: ``(k, k)``: unit principal axes as columns, world axes, in the order of
            ``lengths``.
        lengths: ``(k,)``: semi-axis lengths [N per N m of joint torque norm for force
            rows], ``1 / sigma_i``; ``inf`` along directions the structure holds with
            no joint torque (``sigma_i = 0``). Shortest first.
        rows: Jacobian rows used (``0, 1, 2`` = force, ``3, 4, 5`` = torque).
    """

    axes: np.ndarray
    lengths: np.ndarray
    rows: tuple[int, ...]


def force_ellipsoid(
    configuration: Configuration,
    frame: str | int,
    frame_type: FrameType | str = FrameType.SITE,
    rows: Sequence[int] = (0, 1, 2),
    rcond: float = DEFAULT_RCOND,
) -> ForceEllipsoid:
    """Force manipulability ellipsoid of a frame: the wrenches that joint torques of unit
    norm can balance, ``{w : |J_r^T w| <= 1}``.

    ``J_r`` holds the chosen ``rows`` of the world-aligned Jacobian: by default the 3
    translational rows, so the ellipsoid is of forces [N] at the frame origin (no torque).
    With ``J_r = U S V^T`` its axes are the columns of ``U`` and its lengths ``1 / s``:
    the dual of the velocity ellipsoid ``{J_r qdot : |qdot| <= 1}`` (same axes, lengths
    ``s``). A direction with a long axis is one the arm resists well (and moves slowly).

    Args:
        configuration: Robot at its current ``q``.
        frame: Frame whose origin the force acts at.
        frame_type: ``"site"`` (default), ``"body"`` or ``"geom"``.
        rows: Rows of ``[v; omega]``: ``(0, 1, 2)`` forces (default), ``(3, 4, 5)``
            torques, ``range(6)`` full wrenches (mixed units).
        rcond: Singular values below ``rcond`` times the largest count as zero.
    """
    _check_configuration(configuration)
    rcond = checks.check_real("rcond", rcond, 0.0, 1.0)
    if (
        isinstance(rows, (str, bytes))
        or not checks.is_iterable(rows)
        or (isinstance(rows, np.ndarray) and rows.ndim != 1)
    ):
        raise InvalidArgumentType(
            "rows", "a sequence of Jacobian row indices in 0..5", checks.type_name(rows)
        )
    picked = tuple(checks.check_index(f"rows[{k}]", r, 6) for k, r in enumerate(rows))
    if not picked or len(set(picked)) != len(picked) or not all(0 <= r < 6 for r in picked):
        raise InvalidInput(f"rows must be distinct Jacobian row indices in 0..5, got {rows!r}")
    jacobian = configuration.frame_jacobian(frame, frame_type)[list(picked)]
    u, s, _ = np.linalg.svd(jacobian, full_matrices=True)
    sigma = np.zeros(len(picked))
    sigma[: s.size] = s
    scale = sigma[0] if sigma[0] > 0 else 1.0
    lengths = np.full(len(picked), np.inf)
    kept = sigma > rcond * scale
    lengths[kept] = 1.0 / sigma[kept]
    return ForceEllipsoid(axes=u, lengths=lengths, rows=picked)


# ------------------------------------------------------------------------ max payload
def joint_torque_limits(configuration: Configuration) -> np.ndarray:
    """Joint torque limits ``(nv, 2)`` [N m or N], lower and upper, from the actuators and
    the joints' effort ranges.

    Each joint-driven actuator contributes ``gear * force``: for a motor (fixed gain, no
    bias) with a ctrl range, ``force = gain * ctrlrange``, clipped to its ``forcerange``
    when it is force-limited too (MuJoCo clamps the force there, and no control makes
    more than ``gain * ctrl``); for another force-limited actuator, its ``forcerange``.
    Several actuators on one dof add up. A joint's own ``actuatorfrcrange`` (MuJoCo
    clamps the total actuator force on the joint to it; a URDF's ``<limit effort>``
    becomes it) caps that sum, and is
    the limit of a hinge or slide joint that no actuator drives (URDF models have no
    actuators). A dof with neither (a free base, a passive joint) gets ``[0, 0]``. Raises
    :class:`InvalidInput` for an actuator whose range cannot be read this way (pass
    ``torque_limits`` explicitly then).
    """
    _check_configuration(configuration)
    model = configuration.model
    limits = np.zeros((model.nv, 2))
    driven = np.zeros(model.nv, dtype=bool)
    names = joint_names(model)
    for a in range(model.nu):
        label = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a) or f"actuator{a}"
        if int(model.actuator_trntype[a]) != int(mujoco.mjtTrn.mjTRN_JOINT):
            raise InvalidInput(
                f"actuator {label!r} does not drive a joint directly; pass torque_limits"
            )
        joint = int(model.actuator_trnid[a, 0])
        if int(model.jnt_type[joint]) not in _SCALAR_JOINTS:
            raise InvalidInput(
                f"actuator {label!r} drives multi-dof joint {names[joint]!r}; pass torque_limits"
            )
        motor = (
            model.actuator_ctrllimited[a]
            and int(model.actuator_gaintype[a]) == int(mujoco.mjtGain.mjGAIN_FIXED)
            and int(model.actuator_biastype[a]) == int(mujoco.mjtBias.mjBIAS_NONE)
        )
        if motor:
            force = np.sort(model.actuator_gainprm[a, 0] * model.actuator_ctrlrange[a])
            if model.actuator_forcelimited[a]:
                low, high = model.actuator_forcerange[a]
                force = np.clip(force, low, high)
        elif model.actuator_forcelimited[a]:
            force = model.actuator_forcerange[a].copy()
        else:
            raise InvalidInput(
                f"actuator {label!r} has no force range and is not a ctrl-limited motor; "
                "pass torque_limits"
            )
        generalized = model.actuator_gear[a, 0] * force
        dof = model.jnt_dofadr[joint]
        limits[dof] += (generalized.min(), generalized.max())
        driven[dof] = True
    for j in range(model.njnt):
        if not model.jnt_actfrclimited[j] or int(model.jnt_type[j]) not in _SCALAR_JOINTS:
            continue
        dof = model.jnt_dofadr[j]
        low, high = model.jnt_actfrcrange[j]
        if driven[dof]:
            limits[dof] = np.clip(limits[dof], low, high)
        else:
            limits[dof] = (low, high)
    return limits


def _torque_limits(configuration: Configuration, torque_limits) -> np.ndarray:
    nv = configuration.model.nv
    if torque_limits is None:
        return joint_torque_limits(configuration)
    limits = checks.check_array(
        "torque_limits", torque_limits, f"({nv},) or ({nv}, 2) torque limits [N m]"
    )
    if limits.shape == (nv,):
        limits = np.stack([-limits, limits], axis=1)
    if limits.shape != (nv, 2):
        raise InvalidInput(
            f"torque_limits has shape {limits.shape}, expected ({nv},) symmetric limits "
            f"or ({nv}, 2) lower/upper"
        )
    if np.isnan(limits).any() or (limits[:, 0] > limits[:, 1]).any():
        raise InvalidInput("torque_limits must not be NaN and need lower <= upper")
    return limits


@dataclass(frozen=True)
class PayloadLimit:
    """The largest force along a direction that the joints can hold (see
    :func:`max_payload`).

    Attributes:
        force: Largest magnitude ``s`` [N] of the force ``s * direction`` the motors can
            hold; ``inf`` when no joint limit binds (the structure carries that
            direction); ``0.0`` when no ``s >= 0`` can be held (then :attr:`feasible` is
            false: the motors cannot hold even ``s = 0``, the robot's own weight).
        direction: Unit direction ``(3,)``, world axes.
        interval: ``(s_min, s_max)`` [N]: all magnitudes (negative ones too) that can be
            held; empty (``s_min > s_max``) when none can.
        limiting_joint: Name of the joint whose limit sets ``force`` (``None`` if none).
        holds_gravity: Whether the motors can hold the robot with no external force
            (against gravity when ``gravity`` is true; ``s = 0`` is feasible).
    """

    force: float
    direction: np.ndarray
    interval: tuple[float, float]
    limiting_joint: str | None
    holds_gravity: bool

    @property
    def feasible(self) -> bool:
        """Whether some magnitude ``s >= 0`` can be held (``interval`` meets ``s >= 0``)."""
        s_min, s_max = self.interval
        return bool(s_min <= s_max and s_max >= 0.0)


def max_payload(
    configuration: Configuration,
    frame: str | int,
    direction: npt.ArrayLike,
    torque_limits: npt.ArrayLike | None = None,
    frame_type: FrameType | str = FrameType.SITE,
    gravity: bool = True,
) -> PayloadLimit:
    """Largest force along ``direction`` at the frame origin that the motors can hold.

    The force ``s d`` (``d = direction / |direction|``, world axes; a hanging mass ``m``
    is ``d = (0, 0, -1)``, ``s = 9.81 m``) needs the motor torques
    ``h(s) = h0 - s a`` with ``h0 = holding_torques(configuration, gravity=gravity)`` and
    ``a = J_v^T d``. The 1-D linear program ``max s`` s.t. ``lo <= h0 - s a <= hi`` is
    solved in closed form, joint by joint: joint ``i`` allows
    ``s in [(h0_i - hi_i) / a_i, (h0_i - lo_i) / a_i]`` if ``a_i > 0``, the mirrored
    interval if ``a_i < 0``, and any ``s`` (if ``lo_i <= h0_i <= hi_i``) or none if
    ``a_i = 0``. The intersection is ``interval``; ``force`` is its upper end when it
    reaches ``s >= 0``, else ``0.0`` (and :attr:`PayloadLimit.feasible` is false).

    Args:
        configuration: Robot at rest at its current ``q``.
        frame: Frame whose origin the force acts at.
        direction: Direction ``(3,)`` of the force on the robot, world axes, nonzero.
        torque_limits: ``(nv,)`` symmetric limits ``|tau_i| <= l_i`` or ``(nv, 2)``
            lower/upper [N m]; default :func:`joint_torque_limits` (the actuators'
            ctrlrange * gear, or forcerange, and the joints' effort ranges).
        frame_type: ``"site"`` (default), ``"body"`` or ``"geom"``.
        gravity: Whether the motors also hold the robot against gravity.
    """
    _check_configuration(configuration)
    gravity = checks.check_bool("gravity", gravity)
    d = checks.check_vector("direction", direction, 3)
    largest = float(np.abs(d).max())
    if largest > 0.0:  # scaled first: the norm of a 1e300 vector overflows
        d = d / largest
    norm = float(np.linalg.norm(d))
    if largest * norm < 1e-12:
        raise InvalidInput(f"direction {d.tolist()} is zero; give a nonzero 3-vector")
    d = d / norm
    limits = _torque_limits(configuration, torque_limits)
    a = configuration.frame_jacobian(frame, frame_type)[:3].T @ d
    h0 = holding_torques(configuration, gravity=gravity)
    lo, hi = limits[:, 0], limits[:, 1]
    tol = 1e-12 * max(1.0, float(np.abs(a).max(initial=0.0)))  # a robot with no dof: a is empty
    lower = np.full(a.size, -np.inf)
    upper = np.full(a.size, np.inf)
    pos, neg, zero = a > tol, a < -tol, np.abs(a) <= tol
    lower[pos], upper[pos] = (h0[pos] - hi[pos]) / a[pos], (h0[pos] - lo[pos]) / a[pos]
    lower[neg], upper[neg] = (h0[neg] - lo[neg]) / a[neg], (h0[neg] - hi[neg]) / a[neg]
    blocked = zero & ((h0 < lo) | (h0 > hi))
    lower[blocked], upper[blocked] = np.inf, -np.inf
    s_min, s_max = float(lower.max(initial=-np.inf)), float(upper.min(initial=np.inf))
    holds_gravity = bool(np.all((lo <= h0) & (h0 <= hi)))
    feasible = s_min <= s_max and s_max >= 0
    limiting = None
    if feasible and np.isfinite(s_max):
        limiting = _dof_joint_names(configuration.model)[int(np.argmin(upper))]
    return PayloadLimit(
        force=s_max if feasible else 0.0,
        direction=d,
        interval=(s_min, s_max),
        limiting_joint=limiting,
        holds_gravity=holds_gravity,
    )


def _dof_joint_names(model: mujoco.MjModel) -> list[str]:
    """For every dof, the name of the joint it belongs to."""
    names = joint_names(model)
    return [names[int(model.dof_jntid[i])] for i in range(model.nv)]
