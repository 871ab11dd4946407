"""Limits: mink's, re-exported, qpik's own, and constructors from what a model declares.

* :func:`joint_limits`: position limits, plus velocity limits wherever the model declares
  them (the custom numeric ``velocity_limit``; URDF ``<limit velocity>`` through
  :func:`qpik.load_robot`);
* :class:`BallJointLimit` (:mod:`qpik.limits.ball`): limited ball joints within their
  range for a step of any size (a polytope inscribed in the rotation-angle bound), which
  :func:`joint_limits` adds whenever the model has one;
* :class:`CollisionAvoidanceLimit` (:mod:`qpik.limits.collision`): mink's, with its rows in
  displacement units, pushing back inside the minimum distance, and a typed error when no
  geom pair is left to check;
* :class:`SupportPolygonLimit` (:mod:`qpik.limits.support`): the CoM's ground projection
  inside the contacts' convex hull (by default, of the contact bodies' collision geometry);
* :func:`model_collision_limit`, :func:`collision_pairs`, :func:`collision_geoms`
  (:mod:`qpik.limits.geometry`): collision avoidance over the pairs the model's own
  geometry lets collide (robot--scene and self-collision, adjacent bodies excluded), less
  the self-collision pairs :func:`always_in_contact` finds overlapping in every pose.

:class:`ConfigurationLimit` and :class:`VelocityLimit` build mink's own objects, after
checking their arguments (typed :class:`qpik.LimitDefinitionError`).

A limit returns ``Constraint(G, h)``: ``G dq <= h`` on the displacement ``dq = v dt``.
qpik folds rows that bound a single joint into box bounds, and treats position limits
(:class:`ConfigurationLimit`) as *recoverable*: a start outside them moves back toward them
as fast as the other limits allow, instead of making the QP infeasible.
"""

from __future__ import annotations

import abc
from collections.abc import Mapping

import mink
import mujoco
import numpy as np
import numpy.typing as npt
from mink import Constraint, Limit

from ..core import checks
from ..errors import LimitDefinitionError
from ..model.configuration import Configuration, joint_names
from .ball import BallJointLimit, limited_ball_joints
from .collision import CollisionAvoidanceLimit, geom_distance
from .geometry import (
    always_in_contact,
    checked_pairs,
    closest_pair,
    collision_clearance,
    collision_geoms,
    collision_limits,
    collision_pairs,
    model_collision_limit,
)
from .support import SupportPolygonLimit

__all__ = [
    "PLACEHOLDER_SPEED",
    "BallJointLimit",
    "CollisionAvoidanceLimit",
    "ConfigurationLimit",
    "Constraint",
    "Limit",
    "SupportPolygonLimit",
    "VelocityLimit",
    "always_in_contact",
    "checked_pairs",
    "closest_pair",
    "collision_clearance",
    "collision_geoms",
    "collision_limits",
    "collision_pairs",
    "geom_distance",
    "joint_limits",
    "limited_ball_joints",
    "model_collision_limit",
    "velocity_limit_from_model",
]


class _MinkClass(abc.ABCMeta):
    """Metaclass of qpik's names for mink's limits: ``isinstance`` and ``issubclass``
    answer for mink's class, since the constructor returns mink's own object."""

    def __instancecheck__(cls, instance) -> bool:
        return cls.__mro__[1] in type(instance).__mro__

    def __subclasscheck__(cls, subclass) -> bool:
        # A plain MRO test: ABCMeta's own check walks mink's subclasses, this one included.
        return isinstance(subclass, type) and cls.__mro__[1] in subclass.__mro__


class ConfigurationLimit(mink.ConfigurationLimit, metaclass=_MinkClass):
    """mink's :class:`mink.ConfigurationLimit` (joint position limits, rows
    ``gain * (q_max - q)`` [rad or m] on ``dq``), with qpik's typed errors: a bad ``gain``
    or ``min_distance_from_limits`` raises :class:`qpik.LimitDefinitionError`: ``gain`` in
    (0, 1]; ``min_distance_from_limits`` [rad or m] finite, at most half of every limited
    joint's range (negative values widen the limits, as in mink).

    The object built *is* mink's (``type(limit) is mink.ConfigurationLimit``), so every
    code path that knows mink's limit (qpik's box bounds among them) applies to it."""

    # returns mink's own object, which _MinkClass makes an instance of this class too
    def __new__(  # type: ignore[misc]
        cls,
        model: mujoco.MjModel,
        gain: float = 0.95,
        min_distance_from_limits: float = 0.0,
    ) -> mink.ConfigurationLimit:
        if not isinstance(model, mujoco.MjModel):
            raise LimitDefinitionError(
                f"ConfigurationLimit needs a mujoco.MjModel, got {type(model).__name__}"
            )
        try:
            gain = float(gain)
            distance = float(min_distance_from_limits)
        except (TypeError, ValueError):
            raise LimitDefinitionError(
                f"ConfigurationLimit gain and min_distance_from_limits must be numbers, got "
                f"{gain!r}, {min_distance_from_limits!r}"
            ) from None
        if not np.isfinite(distance):
            raise LimitDefinitionError(
                f"ConfigurationLimit min_distance_from_limits must be finite, got {distance}"
            )
        try:
            limit = mink.ConfigurationLimit(model, gain, distance)
        except mink.LimitDefinitionError as exc:
            raise LimitDefinitionError(f"{exc} (got gain={gain})") from None
        indices = np.asarray(limit.indices, dtype=np.int64)
        empty = indices[limit.lower[indices] > limit.upper[indices]]
        if empty.size:
            dof = int(empty[0])
            joint = joint_names(model)[int(model.dof_jntid[dof])]
            raise LimitDefinitionError(
                f"ConfigurationLimit min_distance_from_limits={distance:g} leaves joint "
                f"{joint!r} no range: its limits {model.jnt_range[model.dof_jntid[dof]].tolist()} "
                f"are less than 2 * {distance:g} apart"
            )
        return limit


class VelocityLimit(mink.VelocityLimit, metaclass=_MinkClass):
    """mink's :class:`mink.VelocityLimit` (``|v_i| <= v_max,i`` [rad/s or m/s], rows
    ``v_max dt`` on ``dq``), with qpik's typed errors: an unknown joint, a free joint or a
    velocity that is not a positive number raises :class:`qpik.LimitDefinitionError`.
    The object built is mink's (see :class:`ConfigurationLimit`)."""

    # returns mink's own object (see ConfigurationLimit.__new__)
    def __new__(  # type: ignore[misc]
        cls, model: mujoco.MjModel, velocities: Mapping[str, npt.ArrayLike] | None = None
    ) -> mink.VelocityLimit:
        if not isinstance(model, mujoco.MjModel):
            raise LimitDefinitionError(
                f"VelocityLimit needs a mujoco.MjModel, got {type(model).__name__}"
            )
        velocities = {} if velocities is None else velocities
        if not isinstance(velocities, Mapping):
            raise LimitDefinitionError(
                f"velocities must map joint names to speeds, got {type(velocities).__name__}"
            )
        names = joint_names(model)
        for name, value in velocities.items():
            if name not in names:
                raise LimitDefinitionError(
                    f"VelocityLimit: no joint {name!r}; joints: {', '.join(names)}"
                )
            try:
                speeds = np.atleast_1d(np.asarray(value, dtype=float))
            except (TypeError, ValueError):
                raise LimitDefinitionError(
                    f"VelocityLimit: joint {name!r}: a speed [rad/s or m/s], got {value!r}"
                ) from None
            if speeds.ndim != 1 or not np.all(speeds > 0) or np.isnan(speeds).any():
                raise LimitDefinitionError(
                    f"VelocityLimit: joint {name!r}: speeds must be > 0, got {value!r}"
                )
        try:
            return mink.VelocityLimit(model, velocities)
        except mink.LimitDefinitionError as exc:
            raise LimitDefinitionError(str(exc)) from None


#: A model's velocity limit [rad/s or m/s] at or above this is a placeholder for "none"
#: (:func:`velocity_limit_from_model`): the fastest real joints of example-robot-data's 66
#: robots turn at 60 rad/s (Romeo), and URDFs write 100, 1000 or 10000 for unlimited.
PLACEHOLDER_SPEED = 100.0


def velocity_limit_from_model(
    model: mujoco.MjModel, scale: float = 1.0
) -> mink.VelocityLimit | None:
    """A :class:`VelocityLimit` from the model's custom numeric ``velocity_limit``
    (one value per dof, [rad/s] or [m/s]; 0 = none), times ``scale`` (a finite number
    > 0), on the hinge and slide joints that have one; ``None`` if there is none. A value
    of :data:`PLACEHOLDER_SPEED` or more is a URDF's way to write "no limit" (1000 and 10000
    rad/s on erd solo12, bolt, baxter; no actuated joint turns that fast) and bounds
    nothing: the step's trust region (:attr:`qpik.StepOptions.max_joint_speed`) holds that
    dof, as it holds a dof with no velocity limit, instead of letting one 10 ms step turn
    it 7.5 rad."""
    scale = checks.check_real("scale", scale, 0.0, open_minimum=True)
    limits = Configuration(model).velocity_limits()
    if limits is None:
        return None
    names = joint_names(model)
    scalar = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    velocities = {}
    for dof, value in enumerate(limits):
        joint = int(model.dof_jntid[dof])
        if int(model.jnt_type[joint]) in scalar and np.isfinite(value):
            if value >= PLACEHOLDER_SPEED:
                continue  # (a placeholder: the trust region holds the dof)
            velocities[names[joint]] = scale * float(value)
    if not velocities:
        return None
    return VelocityLimit(model, velocities)


def _without_ball_rows(limit: mink.ConfigurationLimit) -> None:
    """Leave out mink's own ball-joint rows of ``limit`` (mink 1.3: a first-order row along
    the rotation axis, ``a^T dq <= gain (range - angle)``), where :class:`BallJointLimit`
    holds the ranges: a start past a range made that row ask for the whole way back in one
    step, more than the velocity limits or the trust region allow, and, on two or more
    dofs, it is a general row no recovery relaxes - every step infeasible, the joint stuck.
    A mink without those attributes is left as it is."""
    if hasattr(limit, "_ball_qposadr") and hasattr(limit, "_ball_max_angle"):
        empty = np.zeros(0, dtype=np.int64)
        limit._ball_qposadr = empty
        limit._ball_dofadr = empty.copy()
        limit._ball_max_angle = np.zeros(0)


def joint_limits(model: mujoco.MjModel, velocity_scale: float | None = 1.0) -> list[Limit]:
    """Position limits, plus a :class:`VelocityLimit` whenever the model declares velocity
    limits (``velocity_limit``: bundled models, and URDF ``<limit velocity>`` imported by
    :func:`qpik.load_robot`), scaled by ``velocity_scale`` (a finite number > 0; ``None``:
    no velocity limit), plus a :class:`BallJointLimit` whenever the model has a limited
    ball joint (its range then holds for a step of any size, trust region off too)."""
    if velocity_scale is not None:
        velocity_scale = checks.check_real("velocity_scale", velocity_scale, 0.0, open_minimum=True)
    configuration_limit = ConfigurationLimit(model)
    limits: list[Limit] = [configuration_limit]
    if limited_ball_joints(model):
        _without_ball_rows(configuration_limit)
        limits.append(BallJointLimit(model))
    if velocity_scale is not None:
        velocity = velocity_limit_from_model(model, velocity_scale)
        if velocity is not None:
            limits.append(velocity)
    return limits
