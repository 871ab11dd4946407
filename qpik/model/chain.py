"""The kinematic chain of one frame, read from a MuJoCo model into arrays once.

:class:`KinematicChain` holds what the compiled kernels (:mod:`qpik.model.kernels`) need
to compute the frame's pose and Jacobian without calling MuJoCo: per body from the world to
the frame's body, its pose in its parent (``body_pos``, ``body_quat``); per joint on those
bodies, its type, axis and anchor in the body (``jnt_axis``, ``jnt_pos``), its reference
``qpos0`` and its qpos/dof addresses; and the frame's pose in its body (a site's or geom's
``pos``/``quat``, identity for a body). The chain's joints must be hinges and slides; joints
off the chain may be of any type (a free object elsewhere in the scene, a ball-jointed
head): the chain reads only its own joints' coordinates. A ball or free joint, or a mocap
body, on the chain leaves the frame to the general path (:func:`chain_support` says why).

Units: positions [m], angles [rad]; poses and Jacobians are in the world frame.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import mujoco
import numpy as np
import numpy.typing as npt

from ..core.checks import check_vector
from ..errors import InvalidConfiguration, InvalidInput
from . import kernels as _kernels
from .frames import FrameType, frame_id, frame_name

__all__ = [
    "QPOS_WIDTH",
    "KinematicChain",
    "ReachBound",
    "bodies_chain_joints",
    "body_chain_joints",
    "chain_qpos_mask",
    "chain_support",
    "joint_limit_arrays",
]

_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
#: The Jacobian argument of a pose-only fk_jac (never written: want_jac is False).
_NO_JAC = np.empty((6, 0))
_SLIDE = int(mujoco.mjtJoint.mjJNT_SLIDE)


def chain_support(model: mujoco.MjModel, joints: npt.ArrayLike | None = None) -> str | None:
    """Why the compiled kernels cannot handle ``model`` (a ball or free joint), or
    ``None`` when every joint is a hinge or a slide. ``joints``: check only these joint
    ids (a chain's; joints off a chain may be of any type)."""
    types = model.jnt_type
    ids = np.arange(model.njnt) if joints is None else np.asarray(joints, dtype=np.int64)
    for j in ids[(types[ids] != _HINGE) & (types[ids] != _SLIDE)]:
        kind = int(types[j])
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, int(j)) or f"#{j}"
        what = mujoco.mjtJoint(kind).name[6:].lower()
        return f"joint {name!r} is a {what} joint (the compiled kernels take hinge and slide)"
    return None


def chain_qpos_mask(
    model: mujoco.MjModel, frames: list[tuple[str | int, FrameType | str]]
) -> np.ndarray:
    """The qpos entries ``(nq,)`` (bool) of the joints that move any of ``frames`` (each
    ``(name or id, frame type)``): the union of their chains, every joint type. The other
    entries (a free object, another arm, fingers off the chains) do not move the frames."""
    mask = np.zeros(model.nq, dtype=bool)
    for frame, frame_type in frames:
        kind = FrameType.parse(frame_type)
        fid = frame_id(model, frame, kind)
        if kind is FrameType.BODY:
            body = fid
        elif kind is FrameType.SITE:
            body = int(model.site_bodyid[fid])
        else:
            body = int(model.geom_bodyid[fid])
        while body > 0:
            for joint in range(
                model.body_jntadr[body], model.body_jntadr[body] + model.body_jntnum[body]
            ):
                adr = int(model.jnt_qposadr[joint])
                mask[adr : adr + QPOS_WIDTH[int(model.jnt_type[joint])]] = True
            body = int(model.body_parentid[body])
    return mask


def body_chain_joints(model: mujoco.MjModel, body: int) -> set[int]:
    """The joints (ids, every type) from the world to ``body``."""
    return bodies_chain_joints(model, (body,))


def bodies_chain_joints(model: mujoco.MjModel, bodies: Iterable[int]) -> set[int]:
    """The joints (ids, every type) from the world to any of ``bodies``: the union of their
    chains, each body above them walked once (a collision limit's hundreds of pairs share a
    few dozen bodies and their ancestors)."""
    joints: set[int] = set()
    seen: set[int] = set()
    for start_body in bodies:
        body = int(start_body)
        while body > 0 and body not in seen:
            seen.add(body)
            start = int(model.body_jntadr[body])
            joints.update(range(start, start + int(model.body_jntnum[body])))
            body = int(model.body_parentid[body])
    return joints


#: qpos entries per joint type (free, ball, slide, hinge).
QPOS_WIDTH = {
    int(mujoco.mjtJoint.mjJNT_FREE): 7,
    int(mujoco.mjtJoint.mjJNT_BALL): 4,
    int(mujoco.mjtJoint.mjJNT_SLIDE): 1,
    int(mujoco.mjtJoint.mjJNT_HINGE): 1,
}


def joint_limit_arrays(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper position limits ``(nq,)`` [rad or m] of a hinge/slide model;
    -/+inf for unlimited joints."""
    lower = np.full(model.nq, -np.inf)
    upper = np.full(model.nq, np.inf)
    for j in range(model.njnt):
        if model.jnt_limited[j]:
            adr = model.jnt_qposadr[j]
            lower[adr], upper[adr] = model.jnt_range[j]
    return lower, upper


@dataclass(frozen=True)
class ReachBound:
    """A ball that holds every position the frame can reach: ``|p(q) - center| <= radius``
    for every ``q`` within the limits (``radius = inf`` when a slide joint is unlimited).

    ``center`` [m] is a world point that no joint moves (a point on the first hinge axis);
    ``radius`` [m] the length of a path through one or two points of each hinge axis to the
    frame, every segment of which no joint changes, plus the travel of the slides."""

    center: np.ndarray
    radius: float

    @property
    def array(self) -> np.ndarray:
        """``(cx, cy, cz, radius)`` as the compiled IGM takes it."""
        cached = self.__dict__.get("_array")
        if cached is None:
            cached = np.array([*self.center, self.radius], dtype=float)
            object.__setattr__(self, "_array", cached)
        return cached

    def excludes(self, position: np.ndarray, tolerance: float) -> bool:
        """Whether no configuration brings the frame within ``tolerance`` [m] of
        ``position`` (world frame [m])."""
        d = position - self.center
        distance = float(np.sqrt(d @ d))
        return distance > self.radius + tolerance + 1e-9 * (1.0 + self.radius)


@dataclass(frozen=True, eq=False)
class KinematicChain:
    """Arrays describing the chain from the world to one frame (see the module docstring).

    Build with :meth:`from_model`. ``arrays`` is the tuple the kernels take; ``compiled``
    the same arrays checked and copied once into the compiled engine's chain object
    (:class:`qpik.model.kernels.Chain`), which the kernels take without unpacking the
    tuple at each call (what :meth:`pose`, :meth:`jacobian` and the solves pass).
    """

    frame: str
    frame_type: FrameType
    nq: int
    nv: int
    arrays: tuple = field(repr=False)
    #: dof addresses of the joints on the chain (the others never move the frame).
    dofs: np.ndarray = field(repr=False)
    #: ``arrays`` as the compiled engine's chain object (built from them when not given).
    compiled: _kernels.Chain = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.compiled is None:
            object.__setattr__(self, "compiled", _kernels.Chain(self.arrays, self.nq, self.nv))

    def __reduce__(self) -> tuple:
        # Pickled (and deep-copied) without the compiled object, rebuilt from the arrays.
        fields = (self.frame, self.frame_type, self.nq, self.nv, self.arrays, self.dofs)
        return (type(self), fields)

    @classmethod
    def from_model(
        cls, model: mujoco.MjModel, frame: str | int, frame_type: FrameType | str = FrameType.SITE
    ) -> KinematicChain:
        """The chain of ``frame`` (a name or id of the given type). Raises
        :class:`qpik.UnknownFrame` for a missing frame and :class:`ValueError` when
        :func:`chain_support` rejects a joint of the chain (a ball or free joint on it) or
        a mocap body is on the chain. Joints off the chain may be of any type."""
        kind = FrameType.parse(frame_type)
        fid = frame_id(model, frame, kind)
        if kind is FrameType.BODY:
            body = fid
            frame_pos, frame_quat = np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0])
        elif kind is FrameType.SITE:
            body = int(model.site_bodyid[fid])
            frame_pos, frame_quat = model.site_pos[fid], model.site_quat[fid]
        else:
            body = int(model.geom_bodyid[fid])
            frame_pos, frame_quat = model.geom_pos[fid], model.geom_quat[fid]
        parent, mocap = model.body_parentid, model.body_mocapid
        path = []
        while body > 0:
            if mocap[body] >= 0:
                raise ValueError(f"mocap body #{body} is on the chain of {frame!r}")
            path.append(body)
            body = int(parent[body])
        bodies = np.array(path[::-1], dtype=np.int64)
        jntadr, jntnum = model.body_jntadr[bodies], model.body_jntnum[bodies]
        jnt_start = np.zeros(len(bodies) + 1, dtype=np.int64)
        np.cumsum(jntnum, out=jnt_start[1:])
        joints = np.concatenate(
            [np.arange(a, a + n, dtype=np.int64) for a, n in zip(jntadr, jntnum)]
            or [np.zeros(0, dtype=np.int64)]
        )
        reason = chain_support(model, joints)
        if reason is not None:
            raise ValueError(reason)
        axes = np.linalg.norm(model.jnt_axis[joints].reshape(-1, 3), axis=1)
        if not np.all(np.abs(axes - 1.0) <= 1e-6):  # a zero axis: MuJoCo's FK differs
            raise ValueError(f"a joint axis on the chain of {frame!r} is not a unit vector")
        jnt_type = np.where(model.jnt_type[joints] == _HINGE, _kernels.HINGE, _kernels.SLIDE)
        qadr = model.jnt_qposadr[joints].astype(np.int64)
        arrays = (
            np.ascontiguousarray(model.body_pos[bodies], dtype=float).reshape(-1, 3),
            _quat2mat(model.body_quat[bodies].reshape(-1, 4)),
            jnt_start,
            jnt_type.astype(np.int64),
            np.ascontiguousarray(model.jnt_axis[joints], dtype=float).reshape(-1, 3),
            np.ascontiguousarray(model.jnt_pos[joints], dtype=float).reshape(-1, 3),
            qadr,
            model.jnt_dofadr[joints].astype(np.int64),
            np.ascontiguousarray(model.qpos0[qadr], dtype=float),
            np.array(frame_pos, dtype=float),
            _quat2mat(np.asarray(frame_quat, dtype=float).reshape(1, 4))[0],
        )
        name = frame if isinstance(frame, str) else frame_name(model, kind, fid)
        return cls(name, kind, model.nq, model.nv, arrays, arrays[7].copy())

    @property
    def qpos_index(self) -> np.ndarray:
        """qpos addresses ``(k,)`` of the chain's joints, in chain order."""
        return self.arrays[6]

    @property
    def covers_q(self) -> bool:
        """Whether the chain's joints are every coordinate of ``q``, in order (``q`` is
        then its own packed form, see :meth:`packed`)."""
        index = self.arrays[6]
        return (
            self.nq == self.nv == index.shape[0]
            and bool(np.array_equal(index, np.arange(self.nq)))
            and bool(np.array_equal(self.arrays[7], np.arange(self.nv)))
        )

    def packed(self) -> KinematicChain:
        """The same chain over its own joints only: ``q`` of the packed chain is
        ``q_full[self.qpos_index]`` (its ``nq == nv ==`` the chain's joint count), so the
        solves that move and sample every coordinate of ``q`` move only the chain's joints;
        the others stay where they are when the packed answer is written back."""
        k = self.arrays[6].shape[0]
        order = np.arange(k, dtype=np.int64)
        arrays = (*self.arrays[:6], order, order.copy(), *self.arrays[8:])
        return type(self)(self.frame, self.frame_type, k, k, arrays, order.copy())

    # ------------------------------------------------------------------ kinematics
    def _q(self, q: npt.ArrayLike) -> np.ndarray:
        return check_vector("q", q, self.nq, error=InvalidConfiguration)

    def pose(self, q: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Pose of the frame at ``q`` in the world frame: position (3,) [m], rotation (3, 3)."""
        position, rotation = np.empty(3), np.empty((3, 3))
        _kernels.fk_jac(self.compiled, self._q(q), position, rotation, _NO_JAC, False)
        return position, rotation

    def jacobian(self, q: npt.ArrayLike) -> np.ndarray:
        """World-aligned Jacobian ``(6, nv)`` ``[v; omega]`` of the frame at ``q`` (as
        :meth:`qpik.Configuration.frame_jacobian`: ``v`` [m/s] of the frame origin and
        ``omega`` [rad/s], both in the world frame)."""
        jac = np.empty((6, self.nv))
        _kernels.fk_jac(self.compiled, self._q(q), np.empty(3), np.empty((3, 3)), jac, True)
        return jac

    # ----------------------------------------------------------------------- reach
    def reach_bound(self, lower: np.ndarray, upper: np.ndarray) -> ReachBound:
        """A :class:`ReachBound` of the frame for joints within ``[lower, upper]`` (nq,).

        Each hinge axis is a line fixed in the two bodies it joins, so the distance between
        a point of axis ``k`` and a point of axis ``k + 1`` never changes, nor does the
        distance of the frame to a point of the last axis. The path ``s_1 -> r_2 -> s_2 ->
        ... -> s_m -> frame`` through the feet of the common perpendiculars of consecutive
        axes (``r_k``, ``s_k`` on axis ``k``) therefore bounds ``|p(q) - s_1|``: its length is
        the sum of the DH lengths ``|a_k|`` and offsets ``|d_k|`` plus the tool offset. A
        slide adds its largest travel from the reference configuration.
        """
        lower = check_vector("lower", lower, self.nq, finite=False)
        upper = check_vector("upper", upper, self.nq, finite=False)
        if np.isnan(lower).any() or np.isnan(upper).any():
            raise InvalidInput("lower and upper joint limits must not be NaN (inf: unlimited)")
        jnt_type, qadr = self.arrays[3], self.arrays[6]
        nj = jnt_type.shape[0]
        limited = np.isfinite(lower) & np.isfinite(upper)
        q_ref = np.zeros(self.nq)
        q_ref[limited] = 0.5 * (lower[limited] + upper[limited])
        travel = 0.0
        for j in range(nj):
            if jnt_type[j] == _kernels.SLIDE:
                lo, hi = lower[qadr[j]], upper[qadr[j]]
                if not (np.isfinite(lo) and np.isfinite(hi)):
                    return ReachBound(np.zeros(3), float("inf"))
                travel += 0.5 * (hi - lo)
        center = np.empty(3)
        radius = _kernels.reach_radius(self.compiled, q_ref, center)
        return ReachBound(center, float(radius + travel))


def _quat2mat(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices (k, 3, 3) of unit quaternions (k, 4) ``(w, x, y, z)``, as MuJoCo's
    ``mju_quat2Mat``."""
    return _kernels.quat2mat(np.ascontiguousarray(quat, dtype=float))
