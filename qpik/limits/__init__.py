"""Limits: mink's, re-exported, qpik's own, and constructors from what a model declares.

* :func:`joint_limits`: position limits, plus velocity limits wherever the model declares
  them (the custom numeric ``velocity_limit``; URDF ``<limit velocity>`` through
  :func:`qpik.load_robot`);
* :class:`CollisionAvoidanceLimit` (:mod:`qpik.limits.collision`): mink's, with its rows in
  displacement units, pushing back inside the minimum distance, and a typed error when no
  geom pair is left to check;
* :class:`SupportPolygonLimit` (:mod:`qpik.limits.support`): the CoM's ground projection
  inside the contacts' convex hull.

A limit returns ``Constraint(G, h)``: ``G dq <= h`` on the displacement ``dq = v dt``.
qpik folds rows that bound a single joint into box bounds, and treats position limits
(:class:`ConfigurationLimit`) as *recoverable*: a start outside them moves back toward them
as fast as the other limits allow, instead of making the QP infeasible.
"""

from __future__ import annotations

import mujoco
import numpy as np
from mink import (
    ConfigurationLimit,
    Constraint,
    Limit,
    VelocityLimit,
)

from ..configuration import Configuration, joint_names
from .collision import CollisionAvoidanceLimit, geom_distance
from .support import SupportPolygonLimit

__all__ = [
    "CollisionAvoidanceLimit",
    "ConfigurationLimit",
    "Constraint",
    "Limit",
    "SupportPolygonLimit",
    "VelocityLimit",
    "geom_distance",
    "joint_limits",
    "velocity_limit_from_model",
]


def velocity_limit_from_model(model: mujoco.MjModel, scale: float = 1.0) -> VelocityLimit | None:
    """A :class:`VelocityLimit` from the model's custom numeric ``velocity_limit``
    (one value per dof, [rad/s] or [m/s]; 0 = none), times ``scale``, on the hinge and
    slide joints that have one; ``None`` if there is none."""
    limits = Configuration(model).velocity_limits()
    if limits is None:
        return None
    names = joint_names(model)
    scalar = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    velocities = {}
    for dof, value in enumerate(limits):
        joint = int(model.dof_jntid[dof])
        if int(model.jnt_type[joint]) in scalar and np.isfinite(value):
            velocities[names[joint]] = scale * float(value)
    if not velocities:
        return None
    return VelocityLimit(model, velocities)


def joint_limits(model: mujoco.MjModel, velocity_scale: float | None = 1.0) -> list[Limit]:
    """Position limits, plus a :class:`VelocityLimit` whenever the model declares velocity
    limits (``velocity_limit``: bundled models, and URDF ``<limit velocity>`` imported by
    :func:`qpik.load_robot`), scaled by ``velocity_scale`` (``None``: no velocity limit)."""
    limits: list[Limit] = [ConfigurationLimit(model)]
    if velocity_scale is not None:
        velocity = velocity_limit_from_model(model, velocity_scale)
        if velocity is not None:
            limits.append(velocity)
    return limits
