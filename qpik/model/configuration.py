"""The one state object: a robot model, its data, and the configuration ``q``
(``qpik.Configuration``; also importable from :mod:`qpik.model.configuration`).

:class:`Configuration` subclasses :class:`mink.Configuration`, so every mink task and
limit accepts it. It adds validated updates, world-aligned frame Jacobians
(``xi = [v; omega] = J(q) qdot``), joint-limit vectors and typed errors.
"""

from __future__ import annotations

import copy
import math
import os
from typing import Any, NoReturn

import mink
import mujoco
import numpy as np
import numpy.typing as npt

from ..core import checks
from ..core.checks import check_real, float_array, type_name
from ..errors import (
    InvalidArgumentType,
    InvalidConfiguration,
    InvalidInput,
    JointLimitViolation,
    LimitDefinitionError,
)
from .couplings import default_start
from .frames import (
    FRAME_JACOBIANS,
    FRAME_POSITIONS,
    FRAME_ROTATIONS,
    FrameType,
    check_model_type,
    frame_id,
    frame_names,
)
from .robots import load_robot, locate_robot

__all__ = [
    "Configuration",
    "FrameType",
    "check_within_limits",
    "frame_names",
    "joint_names",
    "limit_vectors",
]


#: Joint types with one qpos and one dof (compared as ints: model arrays hold ints).
_SCALAR_JOINTS = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
_FLOAT64 = np.dtype(np.float64)
#: Squared norms of a quaternion that MuJoCo normalises as it should (its ``mju_normalize4``
#: reads a norm below 1e-15 as the identity, and a squared norm that overflows as well).
_QUAT_SQUARED_NORMS = (1e-20, 1e20)


def quaternion_joints(model: mujoco.MjModel) -> tuple[tuple[int, str], ...]:
    """``(qpos address, joint name)`` of the quaternion ``(w, x, y, z)`` of every free and
    ball joint of ``model``, in joint order."""
    free, ball = int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_BALL)
    types = model.jnt_type
    return tuple(
        (
            int(model.jnt_qposadr[j]) + (3 if types[j] == free else 0),
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, int(j)) or f"joint{j}",
        )
        for j in np.flatnonzero((types == free) | (types == ball))
    )


def unit_quaternions(
    q: np.ndarray,
    quaternions: tuple[tuple[int, str], ...],
    where: str,
    values: list[float] | None = None,
) -> np.ndarray:
    """``q`` (finite, float64) with every quaternion of ``quaternions``
    (:func:`quaternion_joints`) readable as a rotation: ``q`` itself (not copied) when
    MuJoCo normalises each one right, else a copy with those it would not (a norm that
    underflows or overflows, ``[1e200, 1e200, 0, 0]``) normalised, scaled by their largest
    entry first, and a zero quaternion the identity ``(1, 0, 0, 0)``, as MuJoCo reads it
    (``mju_normalize4``) and mink's configurations take it: ``np.zeros(model.nq)`` is a
    configuration with every floating base and ball joint at the identity, in mink's own
    tests too. ``values``: ``q.tolist()`` when the caller has it. (``where`` names ``q``
    in the messages of the callers' other checks.)"""
    if values is None:
        values = q.tolist()
    low, high = _QUAT_SQUARED_NORMS
    out = q
    for adr, _joint in quaternions:
        w, x, y, z = values[adr : adr + 4]
        if low < w * w + x * x + y * y + z * z < high:  # (no ** : 1e200 ** 2 raises)
            continue
        quat = q[adr : adr + 4]
        scale = float(np.max(np.abs(quat)))
        if out is q:
            out = q.copy()
        if scale == 0.0:
            out[adr : adr + 4] = _IDENTITY_QUATERNION
            continue
        unit = quat / scale
        out[adr : adr + 4] = unit / np.linalg.norm(unit)
    return out


_IDENTITY_QUATERNION = (1.0, 0.0, 0.0, 0.0)


def joint_names(model: mujoco.MjModel) -> list[str]:
    """Joint names, with ``joint<i>`` standing in for unnamed joints."""
    check_model_type("model", model)
    return [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
        for j in range(model.njnt)
    ]


def dof_names(model: mujoco.MjModel) -> list[str]:
    """For every dof, a name: its joint's (:func:`joint_names`), with the dof's index in the
    joint, ``[k]``, where the joint has several (a free joint's six, a ball's three)."""
    names = joint_names(model)
    widths = {mujoco.mjtJoint.mjJNT_FREE: 6, mujoco.mjtJoint.mjJNT_BALL: 3}
    out = []
    for i in range(model.nv):
        joint = int(model.dof_jntid[i])
        width = widths.get(mujoco.mjtJoint(int(model.jnt_type[joint])), 1)
        k = i - int(model.jnt_dofadr[joint])
        out.append(names[joint] if width == 1 else f"{names[joint]}[{k}]")
    return out


def qpos_joint_names(model: mujoco.MjModel) -> list[str]:
    """For every qpos index, the name of the joint it belongs to."""
    names = [""] * model.nq
    widths = {
        mujoco.mjtJoint.mjJNT_FREE: 7,
        mujoco.mjtJoint.mjJNT_BALL: 4,
        mujoco.mjtJoint.mjJNT_SLIDE: 1,
        mujoco.mjtJoint.mjJNT_HINGE: 1,
    }
    for j, name in enumerate(joint_names(model)):
        adr = model.jnt_qposadr[j]
        for k in range(widths[mujoco.mjtJoint(model.jnt_type[j])]):
            names[adr + k] = name
    return names


def _limit_vectors(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Lower and upper joint limits ``(nq,)`` (read-only; +-inf where a scalar joint is
    unlimited, and on ball and free joints) and each qpos entry's joint name."""
    lower = np.full(model.nq, -np.inf)
    upper = np.full(model.nq, np.inf)
    for j in range(model.njnt):
        kind = model.jnt_type[j]
        if model.jnt_limited[j] and kind in _SCALAR_JOINTS:
            adr = model.jnt_qposadr[j]
            lower[adr], upper[adr] = model.jnt_range[j]
    lower.setflags(write=False)
    upper.setflags(write=False)
    return lower, upper, qpos_joint_names(model)


#: _limit_vectors of the last few models seen by Configuration.sharing, by id(model):
#: (model, fingerprint of its limits, vectors); the model is held so that its id stays its.
_SHARED_LIMITS: dict[int, tuple[mujoco.MjModel, bytes, tuple]] = {}


def _shared_limit_vectors(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """:func:`_limit_vectors`, kept per model (recomputed when the model's limits changed
    in place)."""
    stamp = model.jnt_range.tobytes() + model.jnt_limited.tobytes()
    entry = _SHARED_LIMITS.get(id(model))
    if entry is not None and entry[0] is model and entry[1] == stamp:
        return entry[2]
    if len(_SHARED_LIMITS) >= 8:
        _SHARED_LIMITS.pop(next(iter(_SHARED_LIMITS)))
    vectors = _limit_vectors(model)
    _SHARED_LIMITS[id(model)] = (model, stamp, vectors)
    return vectors


def limit_vectors(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """The joint limits ``(lower, upper)`` ``(nq,)`` [rad or m] that a
    :class:`Configuration` of ``model`` has (read-only; +-inf where a scalar joint is
    unlimited, and on ball and free joints), kept per model until its limits change."""
    lower, upper, _ = _shared_limit_vectors(model)
    return lower, upper


def _ball_violations_of(
    model: mujoco.MjModel, qpos: np.ndarray, tol: float
) -> list[tuple[int, int, float, float]]:
    """``(joint, qpos address, angle, limit)`` of ``qpos``'s limited ball joints rotated past
    their range (MuJoCo's ball-joint limit: ``range[1]``, the largest angle)."""
    out: list[tuple[int, int, float, float]] = []
    if not (model.jnt_type == mujoco.mjtJoint.mjJNT_BALL).any():  # (one test, no loop)
        return out
    for j, adr in _ball_joints(model):
        if not model.jnt_limited[j]:
            continue
        limit = float(model.jnt_range[j, 1])
        angle = _ball_angle(qpos, adr)
        if angle > limit + tol:
            out.append((j, int(adr), angle, limit))
    return out


def check_within_limits(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    tol: float = 1e-6,
) -> None:
    """Raise :class:`JointLimitViolation` (the first joint, in qpos order, then the ball
    joints) where ``qpos`` ``(nq,)`` is outside ``lower`` / ``upper`` ``(nq,)`` (a
    configuration's :attr:`Configuration.lower` / ``upper``) or a limited ball joint's range
    by more than ``tol``: :meth:`Configuration.check_limits` without an ``MjData`` (a
    configuration costs 0.4 ms on a humanoid)."""
    outside = np.flatnonzero((qpos < lower - tol) | (qpos > upper + tol))
    if outside.size:
        i = int(outside[0])
        raise JointLimitViolation(
            qpos_joint_names(model)[i], i, float(qpos[i]), float(lower[i]), float(upper[i])
        )
    for j, adr, angle, limit in _ball_violations_of(model, qpos, tol):
        raise JointLimitViolation(joint_names(model)[j], adr, angle, 0.0, limit)


class Configuration(mink.Configuration):
    """Model, data and configuration ``q`` of a robot, with forward kinematics up to date.

    Args:
        model: The MuJoCo model (see :func:`qpik.load_robot`), or a
            :class:`mink.Configuration`: its model is shared and its whole state (``q``,
            mocap poses, active equalities, ...) copied, so the two are independent
            afterwards (``qpik.Configuration(mink_configuration)``).
        q: Initial configuration ``(nq,)``; defaults to the model's ``qpos0`` (or to the
            mink configuration's ``q``).
    """

    def __init__(self, model: mujoco.MjModel | mink.Configuration, q: npt.ArrayLike | None = None):
        source = model if isinstance(model, mink.Configuration) else None
        if source is not None:
            model = source.model
        if not isinstance(model, mujoco.MjModel):
            raise InvalidInput(
                "Configuration needs a mujoco.MjModel (see qpik.load_robot) or a "
                f"mink.Configuration as `model`, got {type(model).__name__}"
            )
        self._lower, self._upper, self._qpos_joint = _limit_vectors(model)
        # mink types q as an ndarray, but only hands it to update(q), which validates any
        # array-like (see below)
        super().__init__(model, None if source is not None else q)  # type: ignore[arg-type]
        if source is not None:
            mujoco.mj_copyData(self.data, model, source.data)
            self.update(self.data.qpos.copy() if q is None else q)  # validated

    def __getstate__(self) -> dict:
        """The state a copy or a pickle takes: without :meth:`update`'s kept views of the
        model and data (a deep copy would copy ``data.qpos``'s view apart from the copied
        data, and ``update`` would then write where nothing reads)."""
        state = dict(self.__dict__)
        state.pop("_update_kept", None)
        return state

    @classmethod
    def sharing(cls, source: mink.Configuration) -> Configuration:
        """A :class:`Configuration` that reads and writes ``source``'s model and data in
        place (no copy, no forward kinematics: ``source`` is taken as up to date, as
        :func:`mink.solve_ik` takes it). ``source`` itself when it is already one."""
        if isinstance(source, Configuration):
            return source
        view = cls.__new__(cls)
        view.__dict__.update(source.__dict__)  # model, data and mink's cached vectors
        view._lower, view._upper, view._qpos_joint = _shared_limit_vectors(source.model)
        return view

    # ------------------------------------------------------------------ state
    def _validated(self, q: npt.ArrayLike) -> np.ndarray:
        try:
            q = float_array(q)  # (complex numbers and strings refused, not cast)
        except (TypeError, ValueError) as exc:  # ragged lists, objects
            raise InvalidConfiguration(
                f"configuration q is not a vector of {self.model.nq} numbers: {exc}"
            ) from None
        if q.ndim != 1 or q.shape[0] != self.model.nq:
            raise InvalidConfiguration(
                f"configuration q has shape {q.shape}, expected ({self.model.nq},) "
                f"for this model (joints: {', '.join(joint_names(self.model))})"
            )
        bad = np.flatnonzero(~np.isfinite(q))
        if bad.size:
            i = int(bad[0])
            raise InvalidConfiguration(
                f"configuration entry q[{i}] (joint {self._qpos_joint[i]!r}) is {q[i]}; "
                "every entry must be finite",
                index=i,
            )
        return q

    def update(self, q: npt.ArrayLike | None = None) -> None:
        """Set ``q`` (validated: length ``nq``, finite; a quaternion of a free or ball joint
        whose norm MuJoCo's normalisation would underflow or overflow is stored normalised,
        a zero one as the identity ``(1, 0, 0, 0)``, as MuJoCo reads it) and run forward
        kinematics (what
        :meth:`mink.Configuration.update` runs: ``mj_kinematics``, ``mj_comPos`` and, on a
        model with equalities, ``mj_makeConstraint``; before it, on a model with a tendon
        equality, ``mj_tendon``, without which MuJoCo makes no row of a tendon equality)."""
        model, data = self.model, self.data
        # (data, model, data.qpos, (nq,), neq > 0, quaternion_joints, tendon equalities),
        # kept while model and data are these (MuJoCo's arrays never move)
        kept = self.__dict__.get("_update_kept")
        if kept is None or kept[0] is not data or kept[1] is not model:
            kept = self._update_kept = (
                data,
                model,
                data.qpos,
                (model.nq,),
                model.neq > 0,
                quaternion_joints(model),
                bool(np.any(model.eq_type == mujoco.mjtEq.mjEQ_TENDON)),
            )
        if q is not None:
            # A float64 vector of nq finite entries (its sum finite: no NaN, no inf, with no
            # floating-point warning; one whose sum overflows is judged by _validated) is
            # taken as it is.
            values, checked = None, None
            if type(q) is np.ndarray and q.dtype is _FLOAT64 and q.shape == kept[3]:
                values = q.tolist()
                if math.isfinite(sum(values)):
                    checked = q
                else:
                    values = None
            if checked is None:
                checked = self._validated(q)
            if kept[5]:  # free and ball joints: a zero quaternion is the identity, tiny/huge scaled
                checked = unit_quaternions(checked, kept[5], "configuration q", values)
            kept[2][:] = checked
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        if kept[4]:
            if kept[6]:  # (a tendon equality's rows read the tendons' lengths and Jacobians)
                mujoco.mj_tendon(model, data)
            mujoco.mj_makeConstraint(model, data)

    @property
    def lower(self) -> np.ndarray:
        """Lower joint limits ``(nq,)`` [rad or m]; ``-inf`` where a joint is unlimited."""
        return self._lower

    @property
    def upper(self) -> np.ndarray:
        """Upper joint limits ``(nq,)`` [rad or m]; ``+inf`` where a joint is unlimited."""
        return self._upper

    def check_limits(self, tol: float = 1e-6, safety_break: bool = True) -> None:
        """Raise :class:`JointLimitViolation` if ``q`` is outside the limits by > ``tol``.

        With ``safety_break=False`` nothing is raised (mink's signature, kept for mink's
        ``solve_ik``).
        """
        if not checks.check_bool("safety_break", safety_break):
            return
        tol = check_real("tol", tol, 0.0)
        check_within_limits(self.model, self.data.qpos, self._lower, self._upper, tol)

    def within_limits(self, tol: float = 1e-6) -> bool:
        """Whether ``q`` lies within the joint limits (up to ``tol``); a limited ball joint
        is within when its rotation angle ``2 acos|w|`` [rad] is at most its range."""
        tol = check_real("tol", tol, 0.0)
        q = self.data.qpos
        if not np.all((q >= self._lower - tol) & (q <= self._upper + tol)):
            return False
        return not _ball_violations_of(self.model, q, tol)

    def ball_angles(self) -> dict[str, float]:
        """Rotation angle [rad] of every ball joint (``2 atan2(|xyz|, |w|)``, in [0, pi]),
        by joint name."""
        names = joint_names(self.model)
        return {names[j]: _ball_angle(self.data.qpos, adr) for j, adr in _ball_joints(self.model)}

    # ----------------------------------------------------------------- frames
    def frame_id(self, name: str | int, frame_type: FrameType | str = FrameType.SITE) -> int:
        """Id of a frame; raises :class:`UnknownFrame` listing the valid names."""
        kind = FrameType.parse(frame_type)
        key = (name, kind.value)
        try:
            cached = self._frame_id_cache.get(key)
        except TypeError:  # unhashable: a list, an array, a dict
            cached = None
        if cached is not None:
            return cached
        if isinstance(name, (bool, np.bool_)) or not isinstance(name, (str, int, np.integer)):
            # a list, a float, a Configuration, a function: no name (nor id) at all
            raise InvalidArgumentType(
                "frame name", "a frame name (str) or id (int)", type(name).__name__
            )
        fid = frame_id(self.model, name, kind)
        self._frame_id_cache[key] = fid
        return fid

    # mink resolves frames through this hook: route it to the typed error above.
    def _resolve_frame_id(self, frame_name: str | int, frame_type: str) -> int:
        return self.frame_id(frame_name, frame_type)

    def frame_pose(
        self, name: str | int, frame_type: FrameType | str = FrameType.SITE
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pose of a frame in the world frame: position ``(3,)`` [m], rotation ``(3, 3)``."""
        kind = FrameType.parse(frame_type)
        fid = self.frame_id(name, kind)
        position = getattr(self.data, FRAME_POSITIONS[kind])[fid].copy()
        rotation = getattr(self.data, FRAME_ROTATIONS[kind])[fid].reshape(3, 3).copy()
        return position, rotation

    def frame_jacobian(
        self, name: str | int, frame_type: FrameType | str = FrameType.SITE
    ) -> np.ndarray:
        """Jacobian ``(6, nv)`` of the frame's twist ``[v; omega]``, world-aligned.

        ``v`` [m/s] is the velocity of the frame origin and ``omega`` [rad/s] the angular
        velocity, both expressed in the world frame: ``xi = J(q) qdot``.
        (mink's ``get_frame_jacobian`` returns the same twist expressed in the local frame.)
        """
        kind = FrameType.parse(frame_type)
        fid = self.frame_id(name, kind)
        jac = np.empty((6, self.model.nv))
        FRAME_JACOBIANS[kind](self.model, self.data, jac[:3], jac[3:], fid)
        return jac

    def integrate(self, velocity: npt.ArrayLike, dt: float) -> np.ndarray:
        """Configuration reached from ``q`` moving at ``velocity`` ``(nv,)`` for ``dt`` [s].
        Raises :class:`InvalidConfiguration` naming the velocity when the result is not
        finite (a finite velocity too large to integrate: ``1e300`` rad/s of a free joint)."""
        v = self._validated_velocity(velocity)
        dt = check_real("dt", dt)
        q = super().integrate(v, dt)
        if not math.isfinite(sum(q.tolist())):  # (a sum that overflows: checked entrywise)
            bad = np.flatnonzero(~np.isfinite(q))
            if bad.size:
                self._integration_overflow(v, dt, q, int(bad[0]))
        return q

    def integrate_inplace(self, velocity: npt.ArrayLike, dt: float) -> None:
        """Move ``q`` at ``velocity`` ``(nv,)`` for ``dt`` [s] and rerun forward kinematics.
        Raises as :meth:`integrate` does, ``q`` then unchanged."""
        v = self._validated_velocity(velocity)
        dt = check_real("dt", dt)
        # |v| dt far below the float range (any real step): MuJoCo's integration in place,
        # q finite; else through integrate, which checks the result before it is stored.
        if max(map(abs, v.tolist()), default=0.0) * abs(dt) < 1e150:
            super().integrate_inplace(v, dt)
        else:
            self.data.qpos[:] = self.integrate(v, dt)
            self.update()

    def _integration_overflow(self, v: np.ndarray, dt: float, q: np.ndarray, i: int) -> NoReturn:
        """Raise :class:`InvalidConfiguration` for ``q`` = ``q + v dt`` whose entry ``i`` is
        not finite, naming the velocity entries of that entry's joint."""
        model = self.model
        j = int(np.searchsorted(model.jnt_qposadr, i, side="right")) - 1
        dof = int(model.jnt_dofadr[j])
        ndof = {int(mujoco.mjtJoint.mjJNT_FREE): 6, int(mujoco.mjtJoint.mjJNT_BALL): 3}
        width = ndof.get(int(model.jnt_type[j]), 1)
        entries = f"v[{dof}]" if width == 1 else f"v[{dof}:{dof + width}]"
        raise InvalidConfiguration(
            f"velocity entries {entries} = {v[dof : dof + width].tolist()} (joint "
            f"{self._qpos_joint[i]!r}) for dt = {dt:g} s give q[{i}] = {q[i]}: the velocity "
            "is too large to integrate (the result must be finite)",
            index=dof,
        )

    def _validated_velocity(self, velocity: npt.ArrayLike) -> np.ndarray:
        expected = f"{self.model.nv} numbers"
        kind = getattr(getattr(velocity, "dtype", None), "kind", "f")
        if velocity is None or isinstance(velocity, (str, bytes, dict)) or kind not in "biuf":
            raise InvalidArgumentType("velocity", expected, type_name(velocity))
        try:
            v = float_array(velocity)
        except (TypeError, ValueError):
            raise InvalidArgumentType("velocity", expected, type_name(velocity)) from None
        if v.shape != (self.model.nv,):
            raise InvalidConfiguration(f"velocity has shape {v.shape}, expected ({self.model.nv},)")
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise InvalidConfiguration(
                f"velocity entry v[{int(bad[0])}] is {v[bad[0]]}; every entry must be finite",
                index=int(bad[0]),
            )
        return v

    def copy(self) -> Configuration:
        """An independent configuration on the same model, at the same ``q``."""
        return Configuration(self.model, self.q)

    def random_q(self, rng: np.random.Generator | None = None) -> np.ndarray:
        """A configuration ``(nq,)``: each hinge and slide joint drawn uniformly within its
        limits [rad or m] (unlimited: [-pi, pi]), ball and free joints at ``qpos0``; ``rng``
        a numpy ``Generator`` (None: fresh entropy)."""
        if rng is not None:
            checks.check_instance("rng", rng, np.random.Generator, "a numpy Generator or None")
        rng = rng or np.random.default_rng()
        lo = np.where(np.isfinite(self._lower), self._lower, -np.pi)
        hi = np.where(np.isfinite(self._upper), self._upper, np.pi)
        q = self.model.qpos0.copy()
        scalar = _scalar_qpos_mask(self.model)
        q[scalar] = rng.uniform(lo[scalar], hi[scalar])
        return q

    def mid_q(self) -> np.ndarray:
        """The mid-range configuration (``qpos0`` for unlimited joints), with the joints of
        closed chains that the model's connect or weld constraints close (a gripper's
        linkage) at ``qpos0`` where that meets those constraints better
        (:func:`qpik.model.couplings.closed_chain_start`): the default start of full IK."""
        return default_start(self.model, self._lower, self._upper)

    def velocity_limits(self) -> np.ndarray | None:
        """Joint velocity limits ``(nv,)`` [rad/s or m/s] from the model's custom numeric
        ``velocity_limit`` (``inf`` where it holds 0 or less: no limit, as for a URDF joint
        without ``<limit velocity>``, or a free joint), or ``None`` when the model has
        none. Raises :class:`qpik.LimitDefinitionError` when it does not hold ``nv``
        values."""
        nid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_NUMERIC, "velocity_limit")
        if nid < 0:
            return None
        adr, size = self.model.numeric_adr[nid], self.model.numeric_size[nid]
        if size != self.model.nv:
            raise LimitDefinitionError(
                f"the model's custom numeric velocity_limit has {size} values; it needs "
                f"one per dof ({self.model.nv})"
            )
        values = np.array(self.model.numeric_data[adr : adr + size], dtype=float)
        values[~(values > 0)] = np.inf
        return values


def _ball_joints(model: mujoco.MjModel) -> list[tuple[int, int]]:
    """``(joint id, qpos address)`` of every ball joint."""
    ball = int(mujoco.mjtJoint.mjJNT_BALL)
    return [(j, int(model.jnt_qposadr[j])) for j in range(model.njnt) if model.jnt_type[j] == ball]


def _ball_angle(qpos: np.ndarray, adr: int) -> float:
    """Rotation angle [rad] of the (not necessarily unit) quaternion ``qpos[adr:adr+4]``."""
    w = abs(float(qpos[adr]))
    xyz = float(np.linalg.norm(qpos[adr + 1 : adr + 4]))
    return 2.0 * math.atan2(xyz, w)


def _scalar_qpos_mask(model: mujoco.MjModel) -> np.ndarray:
    """Mask of qpos entries that belong to hinge or slide joints."""
    mask = np.zeros(model.nq, dtype=bool)
    for j in range(model.njnt):
        if model.jnt_type[j] in _SCALAR_JOINTS:
            mask[model.jnt_qposadr[j]] = True
    return mask


def as_configuration(configuration: Any, name: str = "configuration") -> Configuration:
    """``configuration`` as a :class:`qpik.Configuration`: a mink one is read in place,
    through a view that shares its model and data (:meth:`qpik.Configuration.sharing`);
    :class:`qpik.InvalidInput` naming the argument otherwise."""
    if isinstance(configuration, Configuration):
        return configuration
    if isinstance(configuration, mink.Configuration):
        return Configuration.sharing(configuration)
    raise InvalidInput(
        f"{name} must be a qpik.Configuration or a mink.Configuration, "
        f"got {type(configuration).__name__}"
    )


def resolve_robot(
    robot: Any,
    *,
    relative_to: str | os.PathLike | None = None,
    floating_base: bool = False,
) -> tuple[mujoco.MjModel, np.ndarray | None]:
    """The one resolver of what qpik's entry points accept as a robot: ``(model, q)``.

    Args:
        robot: a :class:`qpik.Configuration` or a ``mink.Configuration`` (its model,
            and a copy of its ``q``: the caller's start), a ``mujoco.MjModel`` (as is,
            ``q`` ``None``), or anything :func:`locate_robot` resolves (a bundled name,
            ``"erd:NAME"``, a path), loaded with :func:`load_robot` (``q`` ``None``). A
            configuration whose mocap bodies are posed elsewhere than its model's defaults
            (``data.mocap_pos`` / ``mocap_quat`` set: an arm on a moved mocap base) gives a
            copy of its model with those poses as the defaults, so that a solve works
            where the configuration has the robot.
        relative_to: the folder a relative path is read from (default: the working
            directory).
        floating_base: passed to :func:`load_robot` for a file.

    Raises :class:`qpik.InvalidInput` naming ``robot`` for anything else, and
    :func:`load_robot`'s errors.
    """
    if isinstance(robot, mink.Configuration):  # (qpik's, or mink's read in place)
        robot = as_configuration(robot, "robot")
        return _with_mocap_poses(robot), robot.q
    if isinstance(robot, mujoco.MjModel):
        return robot, None
    if isinstance(robot, (str, os.PathLike)):
        path = locate_robot(robot, relative_to=relative_to)
        return load_robot(path, floating_base=floating_base), None
    raise InvalidInput(
        "robot must be a robot name, 'erd:NAME', a path, a mujoco.MjModel or a "
        f"qpik.Configuration (or mink's), got {type(robot).__name__}"
    )


def _with_mocap_poses(configuration: Configuration) -> mujoco.MjModel:
    """The configuration's model, or, where its mocap bodies are posed elsewhere than the
    model's defaults, a copy of it with the configuration's mocap poses as the defaults
    (``body_pos`` / ``body_quat`` of the mocap bodies, which MuJoCo copies into a new
    ``MjData``'s ``mocap_pos`` / ``mocap_quat``)."""
    model, data = configuration.model, configuration.data
    if model.nmocap == 0:
        return model
    bodies = np.flatnonzero(model.body_mocapid >= 0)
    order = model.body_mocapid[bodies]
    if np.array_equal(model.body_pos[bodies], data.mocap_pos[order]) and np.array_equal(
        model.body_quat[bodies], data.mocap_quat[order]
    ):
        return model
    posed = copy.copy(model)
    posed.body_pos[bodies] = data.mocap_pos[order]
    posed.body_quat[bodies] = data.mocap_quat[order]
    return posed
