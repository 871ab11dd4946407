"""Limits: mink's, re-exported, and constructors from what a model file declares.

A limit returns ``Constraint(G, h)``: ``G dq <= h`` on the displacement ``dq = v dt``.
qpik folds rows that bound a single joint into box bounds, and treats position limits
(:class:`ConfigurationLimit`) as *recoverable*: a start outside them moves back toward them
as fast as the other limits allow, instead of making the QP infeasible.
"""

from __future__ import annotations

import mujoco
from mink import (
    CollisionAvoidanceLimit,
    ConfigurationLimit,
    Constraint,
    Limit,
    VelocityLimit,
)

from ..configuration import Configuration, joint_names

__all__ = [
    "CollisionAvoidanceLimit",
    "ConfigurationLimit",
    "Constraint",
    "Limit",
    "VelocityLimit",
    "joint_limits",
    "velocity_limit_from_model",
]


def velocity_limit_from_model(model: mujoco.MjModel, scale: float = 1.0) -> VelocityLimit | None:
    """A :class:`VelocityLimit` from the model's custom numeric ``velocity_limit``
    (one value per hinge/slide dof, [rad/s] or [m/s]), times ``scale``; ``None`` if absent."""
    limits = Configuration(model).velocity_limits()
    if limits is None:
        return None
    names = joint_names(model)
    velocities = {}
    for dof, value in enumerate(limits):
        velocities[names[model.dof_jntid[dof]]] = scale * float(value)
    return VelocityLimit(model, velocities)


def joint_limits(model: mujoco.MjModel, velocity_scale: float | None = 1.0) -> list[Limit]:
    """Position limits, plus the model's velocity limits when it declares them and
    ``velocity_scale`` is not None."""
    limits: list[Limit] = [ConfigurationLimit(model)]
    if velocity_scale is not None:
        velocity = velocity_limit_from_model(model, velocity_scale)
        if velocity is not None:
            limits.append(velocity)
    return limits
