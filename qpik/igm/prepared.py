"""What a full-IK solve reads from a robot model once: :class:`PreparedRobot` (joint limits,
the mid-range start, the bounds the compiled engine takes, the model's couplings and, per
target frame, its kinematic chain and reach bound, :class:`PreparedFrame`), and the cache
that keeps one per model for :func:`qpik.solve`, :data:`PREPARED` (a
:class:`PreparedRobots`, emptied by :func:`qpik.clear_caches`). An :class:`qpik.IKSession`
holds its own.
"""

from __future__ import annotations

import threading
import time
import weakref
from typing import Any

import mujoco
import numpy as np

from ..errors import InvalidConfiguration
from ..model import KinematicChain, ReachBound, chain_support, joint_limit_arrays, kernels
from ..model.configuration import Configuration, FrameType, quaternion_joints, unit_quaternions
from ..model.couplings import default_start, model_couplings, unheld_equalities
from ..model.frames import resolve_frame
from ..model.robots import check_kinematic_model
from . import kernels as igm_kernels
from .kernels import start_box
from .restarts import RAW_UINT64, rng_state
from .result import IKResult, LazyRows, Reason
from .targets import MAX_TARGET_DISTANCE, ORTHONORMAL_TOLERANCE, FrameKey

__all__ = [
    "FINGERPRINT_FIELDS",
    "PREPARED",
    "REASONS_BY_CODE",
    "PreparedFrame",
    "PreparedRobot",
    "PreparedRobots",
]

#: The :class:`Reason` of each of the compiled engine's reason codes.
REASONS_BY_CODE = tuple(Reason(name) for name in igm_kernels.REASON_NAMES)
#: What the compiled lane (:meth:`PreparedRobot.make_lane`) makes its answers with.
_LANE_CONSTS = (
    IKResult, LazyRows, REASONS_BY_CODE, np.random.Generator, tuple(RAW_UINT64), rng_state,
    time.perf_counter, list, tuple,
)  # fmt: skip


class PreparedFrame:
    """A target frame of a session: name, type and, when its chain has hinge and slide
    joints only, its chain and reach bound. ``packed``: the chain over its own joints
    (:meth:`KinematicChain.packed`), with ``index`` (their qpos addresses) and the packed
    joint bounds, when the chain's joints are not all of ``q`` (``None`` otherwise: the
    compiled engine then takes ``q`` as is). ``coupled``: a coupling of the model
    (:class:`qpik.model.Couplings`) moves a joint of the chain."""

    __slots__ = (
        "bounds", "chain", "coupled", "index", "kind", "name", "packed", "plan", "reach",
        "reach_free",
    )  # fmt: skip

    def __init__(
        self,
        name: str,
        kind: FrameType,
        chain: KinematicChain | None,
        reach: ReachBound | None,
        reach_free: ReachBound | None = None,
    ) -> None:
        self.name, self.kind, self.chain, self.reach = name, kind, chain, reach
        #: the reach bound with no joint limits (an unlimited slide: no bound), for solves
        #: whose limits are not the model's joint limits (``limits=None`` or a list)
        self.reach_free = reach if reach_free is None else reach_free
        self.packed: KinematicChain | None = None
        self.index: np.ndarray | None = None
        self.bounds: tuple[np.ndarray, np.ndarray] | None = None  # (joint, free), packed
        self.coupled = False
        #: (kernel options, joint limits?, time checked?, compiled plan) of the last compiled
        #: solve (:meth:`PreparedRobot.plan`), reused while the options are the same object
        self.plan: tuple | None = None

    def __getstate__(self) -> dict:
        # Pickled (and deep-copied) without the compiled plan, rebuilt at the next solve.
        return {name: getattr(self, name) for name in self.__slots__ if name != "plan"}

    def __setstate__(self, state: dict) -> None:
        for name, value in state.items():
            setattr(self, name, value)
        self.plan = None


class PreparedRobot:
    """What a session reads from a model once: joint limits, the mid-range start, the
    bounds the compiled engine takes and, per target frame, its chain and reach bound (on
    first use). It holds no reference to the model (the one-shot cache keys it by a weak
    reference to the model, :class:`PreparedRobots`). Raises as
    :func:`qpik.model.robots.check_kinematic_model` for a model no solve can use."""

    __slots__ = (
        "bounds_free",
        "bounds_joint",
        "coupling_memo",
        "couplings",
        "frames",
        "lane",
        "lower",
        "memo",
        "mid",
        "quaternions",
        "start_box",
        "support",
        "unheld",
        "upper",
    )

    def __init__(self, model: mujoco.MjModel) -> None:
        # a model edited in place into one no solve can use (a NaN body_pos, an empty joint
        # range) raises here, naming the field, rather than solving to a NaN or wrong answer
        check_kinematic_model(model)
        self.support = chain_support(model)
        #: (qpos address, joint name) of the free and ball joints' quaternions (start check)
        self.quaternions = quaternion_joints(model)
        if self.support is None:
            lower, upper = joint_limit_arrays(model)
        else:
            configuration = Configuration(model)
            lower, upper = configuration.lower.copy(), configuration.upper.copy()
        self.lower, self.upper = lower, upper
        #: the start check of IKSession (start_defect with the limits bound once)
        self.start_box = start_box(lower, upper, 1e-6)
        sample_lo = np.where(np.isfinite(lower), lower, -np.pi)
        sample_hi = np.where(np.isfinite(upper), upper, np.pi)
        free = np.full(model.nq, np.inf)
        self.bounds_joint = np.array([lower, upper, sample_lo, sample_hi])
        self.bounds_free = np.array([-free, free, sample_lo, sample_hi])
        self.couplings = model_couplings(model)
        #: (bytes of the last start, the couplings' error there), for IKSession
        self.coupling_memo: tuple[bytes, float] | None = None
        #: the active equalities no level holds (connect, weld, ...): checked at the end
        self.unheld = unheld_equalities(model)
        #: the default start: mid-range, the closed chains of unheld equalities at qpos0
        self.mid = default_start(model, lower, upper, self.unheld)
        self.frames: dict = {}  # frame key -> PreparedFrame
        self.memo: list = [None]  # the options memo of the sessions using this preparation
        #: the sessions' lean solve in one compiled call, for memo[0] (IKSession._solve)
        self.lane: Any = None

    def __getstate__(self) -> dict:
        # Pickled (and deep-copied) without the compiled start box, rebuilt from the limits,
        # and without the compiled lane, made again by the next solve.
        kept = (name for name in self.__slots__ if name not in ("start_box", "lane"))
        return {name: getattr(self, name) for name in kept}

    def __setstate__(self, state: dict) -> None:
        for name, value in state.items():
            setattr(self, name, value)
        self.start_box = start_box(self.lower, self.upper, 1e-6)
        self.lane = None

    def plan(self, frame: PreparedFrame, joint: bool, kernel_options: tuple) -> tuple:
        """The compiled engine's fixed arguments for ``frame`` (its chain, bounds, reach
        bound; the joint limits with ``joint``, else none) under ``kernel_options``
        (``qpik.igm.kernels.kernel_options``'s arrays), checked and copied once into a
        :func:`qpik.igm.kernels.igm_plan`, kept on the frame (``frame.plan``) while the
        solves' options are the same object."""
        options, int_options = kernel_options
        if frame.index is None:  # the chain's joints are all of q
            chain = frame.chain
            bounds = self.bounds_joint if joint else self.bounds_free
        else:  # the chain's joints only: the others stay where they are
            chain = frame.packed
            assert frame.bounds is not None
            bounds = frame.bounds[0] if joint else frame.bounds[1]
        reach = frame.reach if joint else frame.reach_free  # (limits None: no joint limits)
        assert chain is not None and reach is not None
        compiled = igm_kernels.igm_plan(
            chain.compiled, frame.index, self.mid.shape[0], bounds, reach.array, options,
            int_options,
        )  # fmt: skip
        plan = (kernel_options, joint, bool(int_options[3]), compiled)
        frame.plan = plan
        return plan

    def make_lane(self, memo: tuple) -> Any:
        """The sessions' lean solve in one compiled call (``qpik._engine.igm._SessionLane``)
        for the options memo ``memo`` (``IKSession._options``'s entry, its lane taken):
        ``IKSession._solve``'s memo test, ``_lean``'s tests and run and
        ``_compiled_result``'s result, bit for bit. Its ``solve`` returns ``None`` (nothing
        drawn, nothing run) wherever the general path must answer."""
        base, keywords, settings, kernel_options = memo[:4]
        budget = settings.time_budget
        return igm_kernels.session_lane(
            base, keywords, kernel_options, self.frames, self.start_box,
            None if budget is None else float(budget), self.mid, settings.seed, _LANE_CONSTS,
            ORTHONORMAL_TOLERANCE, MAX_TARGET_DISTANCE,
        )  # fmt: skip

    def checked_start(self, q: np.ndarray) -> np.ndarray:
        """The start ``q0`` (float64, ``(nq,)``) of a model with ball or free joints checked:
        :class:`qpik.InvalidConfiguration` naming ``q0`` for an entry that is not finite;
        ``q`` itself, or a copy with a quaternion MuJoCo would not normalise right
        (``[1e200, 1e200, 0, 0]``) normalised and a zero one the identity
        (:func:`qpik.model.configuration.unit_quaternions`)."""
        if not np.isfinite(q).all():
            i = int(np.flatnonzero(~np.isfinite(q))[0])
            raise InvalidConfiguration(f"q0[{i}] is {q[i]}; every entry must be finite", i)
        return unit_quaternions(q, self.quaternions, "q0") if self.quaternions else q

    def frame(self, model: mujoco.MjModel, key: FrameKey) -> PreparedFrame:
        """The :class:`PreparedFrame` of ``key`` on ``model`` (the model this was read from)."""
        try:
            cached = self.frames.get(key)
        except TypeError:  # unhashable key
            cached = None
        if cached is not None:
            return cached
        name, kind, _ = resolve_frame(model, key, argument="targets")
        chain = reach = reach_free = None
        try:
            chain = KinematicChain.from_model(model, name, kind)
        except ValueError:  # a ball or free joint (or a mocap body) on the chain
            pass
        if chain is not None:
            reach = chain.reach_bound(self.lower, self.upper)
            unlimited = np.full(self.lower.shape[0], np.inf)
            reach_free = chain.reach_bound(-unlimited, unlimited)
        entry = PreparedFrame(name, kind, chain, reach, reach_free)
        if chain is not None:
            if self.couplings is not None:
                entry.coupled = bool(np.isin(chain.dofs, self.couplings.dofs).any())
            if not chain.covers_q:
                index = chain.qpos_index
                entry.packed, entry.index = chain.packed(), index
                entry.bounds = (
                    np.ascontiguousarray(self.bounds_joint[:, index]),
                    np.ascontiguousarray(self.bounds_free[:, index]),
                )
        try:
            self.frames[key] = entry
        except TypeError:
            pass
        return entry


#: The arrays of an ``MjModel`` that a prepared robot (:class:`PreparedRobot`) is read from:
#: what the chains, joint limits, reach bounds and the mid-range start depend on. The
#: one-shot cache compares their bytes to those it prepared the robot from.
FINGERPRINT_FIELDS = (
    "qpos0",
    "jnt_type",
    "jnt_limited",
    "jnt_range",
    "jnt_axis",
    "jnt_pos",
    "jnt_qposadr",
    "jnt_dofadr",
    "body_parentid",
    "body_mocapid",
    "body_jntadr",
    "body_jntnum",
    "body_pos",
    "body_quat",
    "site_bodyid",
    "site_pos",
    "site_quat",
    "geom_bodyid",
    "geom_pos",
    "geom_quat",
    "eq_type",
    "eq_active0",
    "eq_obj1id",
    "eq_obj2id",
    "eq_data",
    "tendon_adr",
    "tendon_num",
    "tendon_length0",
    "wrap_type",
    "wrap_objid",
    "wrap_prm",
)


class PreparedRobots:
    """The one-shot cache of :func:`qpik.solve`: per ``MjModel``, what an :class:`qpik.IKSession`
    reads from it (joint limits, mid-range start, per frame its kinematic chain and reach
    bound), so that ``qpik.solve(model, targets)`` costs what a held session's ``solve``
    does. One instance, :data:`PREPARED`; :func:`qpik.clear_caches` empties
    it.

    * Keyed by the model object itself, through a weak reference: it never keeps a model
      alive (an entry goes with its model) and never serves another model.
    * Never stale: each lookup compares the model's arrays that the preparation read
      (:data:`FINGERPRINT_FIELDS`: joint types, axes, anchors, ranges, body and frame
      poses, ``qpos0``...) with a copy of them taken when it was prepared, one ``memcmp``
      in compiled code; a model changed in place is prepared anew.
    * Answers are bitwise those of a fresh :class:`qpik.IKSession`: the entry holds exactly what
      a session computes, from the same arrays.
    * At most ``max_models`` models (the first prepared goes first).
    """

    def __init__(self, max_models: int = 32) -> None:
        self.max_models = max_models
        self._entries: dict[int, tuple[weakref.ref, Any, PreparedRobot]] = {}
        # Reentrant: a weak reference callback (a collected model) may run inside get().
        self._lock = threading.RLock()

    def __len__(self) -> int:
        return len(self._entries)

    def clear(self) -> None:
        """Forget every prepared model."""
        with self._lock:
            self._entries.clear()

    def get(self, model: mujoco.MjModel) -> PreparedRobot:
        """The prepared robot of ``model``: the cached one when the model's arrays are
        unchanged since it was prepared, else a new one (cached)."""
        key = id(model)
        entry = self._entries.get(key)
        if entry is not None and entry[0]() is model and entry[1].unchanged():
            return entry[2]
        watch = model_watch(model)  # the bytes first, then what is read from them
        if watch is None:
            return PreparedRobot(model)  # not views of the model's memory: nothing to watch
        prepared = PreparedRobot(model)

        def forget(ref: weakref.ref, key: int = key) -> None:
            with self._lock:
                current = self._entries.get(key)
                if current is not None and current[0] is ref:
                    del self._entries[key]

        with self._lock:
            self._entries.pop(key, None)
            while len(self._entries) >= self.max_models:
                oldest = next(iter(self._entries), None)
                if oldest is None:
                    break
                self._entries.pop(oldest, None)
            self._entries[key] = (weakref.ref(model, forget), watch, prepared)
        return prepared


def model_watch(model: mujoco.MjModel) -> Any:
    """A copy of the bytes of ``model``'s :data:`FINGERPRINT_FIELDS`
    (``qpik.model.kernels.ArrayWatch``: ``unchanged()`` compares them again, one ``memcmp``
    in compiled code), or None where they are not views of the model's memory."""
    views = [getattr(model, name) for name in FINGERPRINT_FIELDS]
    if not all(_is_view_of(model, n, v) for n, v in zip(FINGERPRINT_FIELDS, views)):
        return None
    return kernels.ArrayWatch(views)


def _is_view_of(model: mujoco.MjModel, name: str, view: np.ndarray) -> bool:
    """Whether ``view`` (``getattr(model, name)``) is a C-contiguous view on memory the model
    holds: another read of the attribute gives a view on the same address (MuJoCo's arrays
    are fixed in the ``mjModel`` buffer for the model's life), or it is empty."""
    if not isinstance(view, np.ndarray) or not view.flags.c_contiguous:
        return False
    if view.size == 0:
        return True  # no entry to change (sizes are fixed)
    if view.flags.owndata:
        return False
    again = getattr(model, name)
    return bool(again.ctypes.data == view.ctypes.data and again.nbytes == view.nbytes)


#: The one-shot cache of :func:`qpik.solve` (see :class:`PreparedRobots`).
PREPARED = PreparedRobots()
