"""What a solver's limits give it, checked where they enter: a limit built for another
robot's model (:func:`check_limit_model`, when the solver is built) and the rows a limit's
own ``compute_qp_inequalities`` returns (:func:`constraint_rows`, at the step):
:class:`qpik.LimitDefinitionError` naming the limit (:func:`limit_name`) where they do not
fit, never a limit applied to the wrong joints, NaN rows dropped, or an AttributeError."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from .._engine import limits as _limits_engine
from ..core.checks import float_array
from ..errors import LimitDefinitionError
from ..limits.collision import NEGLIGIBLE_ROW
from ..model.configuration import joint_names

__all__ = ["check_limit_model", "constraint_rows", "limit_name", "same_robot"]


def limit_name(limit: Any) -> str:
    """The name of ``limit``'s class in messages and active-limit names; for a private class
    of qpik's, its first public base's (``model_collision_limit`` gives a private subclass of
    ``CollisionAvoidanceLimit``: named so); for a view of part of a mink limit
    (:mod:`.mink_limits`), the limit's class."""
    cls = type(limit)
    if getattr(cls, "VIEW", False):  # (a view of part of a mink limit: .mink_limits)
        return cls.__mro__[1].__name__
    if cls.__name__.startswith("_") and cls.__module__.startswith("qpik."):
        return next((c.__name__ for c in cls.__mro__ if not c.__name__.startswith("_")), "")
    return cls.__name__


def constraint_rows(
    limit, constraint: Any
) -> tuple[np.ndarray, np.ndarray, None, int | None] | None:
    """The rows ``(G, h, None, fewest)`` of what a limit's own ``compute_qp_inequalities``
    returned (None where inactive: ``G`` and ``h`` None, as mink's ``Constraint`` says;
    ``fewest``: the fewest nonzero entries of a row where the engine counted them and found
    no negligible row (:data:`~qpik.limits.collision.NEGLIGIBLE_ROW`), ``G`` and ``h`` then
    copies where it is two or more; else None, and the limit's arrays as they are):
    LimitDefinitionError naming the limit where it is not a ``Constraint`` (None, say), its
    ``G`` and ``h`` are not arrays of numbers, or a row holds NaN or ``h = -inf`` (``G``
    must be finite; ``h`` may be ``+inf``, a row that never binds, as mink's collision rows
    out of range; ``-inf`` bounds nothing: no displacement meets it)."""
    try:
        G, h = constraint.G, constraint.h
    except AttributeError:
        raise LimitDefinitionError(
            f"{limit_name(limit)}: compute_qp_inequalities returned "
            f"{type(constraint).__name__}, not a mink.limits.Constraint(G, h)"
        ) from None
    if G is None and h is None:
        return None
    try:
        if type(G) is not np.ndarray or G.dtype.kind != "f":
            G = float_array(G)  # (complex or text rows refused, not cast)
        if type(h) is not np.ndarray or h.dtype.kind != "f":
            h = float_array(h)
    except (TypeError, ValueError) as exc:
        raise LimitDefinitionError(
            f"{limit_name(limit)}: its rows G and h must be arrays of numbers, got "
            f"{type(G).__name__} and {type(h).__name__} ({exc})"
        ) from None
    G = G if G.ndim == 2 else np.atleast_2d(G)
    h = h if h.ndim == 1 else np.atleast_1d(h)
    fewest = negligible = None
    if (
        G.dtype == np.float64
        and h.dtype == np.float64
        and G.flags.c_contiguous
        and h.flags.c_contiguous
    ):  # (counted by the engine, without NumPy's temporaries: the same counts)
        bad_g, bad_h, fewest, negligible = _limits_engine.row_stats(G, h, NEGLIGIBLE_ROW)
    else:
        bad_g, bad_h = np.count_nonzero(~np.isfinite(G)), np.count_nonzero(~(h > -np.inf))
    if bad_g or bad_h:
        raise LimitDefinitionError(
            f"{limit_name(limit)}: its rows are not finite (G must be finite and h neither "
            f"NaN nor -inf; {int(bad_g)} entries of G, {int(bad_h)} of h)"
        )
    if negligible != 0 or fewest is None:  # (not counted, or a row to flush: the caller's)
        return G, h, None, None
    if fewest >= 2:  # (every row on two dofs or more: new arrays, the limit's own kept)
        return G.copy(), h.copy(), None, fewest
    return G, h, None, fewest


def same_robot(a: mujoco.MjModel, b: mujoco.MjModel) -> bool:
    """Whether two models are the same robot as a limit reads it: the same object, or the
    same sizes, joints (types, qpos and dof addresses, which are limited) and joint names (two
    models loaded from one file are; a limit built for another robot is not). Ranges are not
    compared: a limit copies them when it is built, and may be built on a copy whose ranges
    were narrowed."""
    if a is b:
        return True
    if (a.nq, a.nv, a.njnt) != (b.nq, b.nv, b.njnt):
        return False
    for name in ("jnt_type", "jnt_qposadr", "jnt_dofadr", "jnt_limited"):
        if not np.array_equal(getattr(a, name), getattr(b, name)):
            return False
    return joint_names(a) == joint_names(b)


def _difference(own: mujoco.MjModel, model: mujoco.MjModel) -> str:
    """What first differs between a limit's model and the solver's, in words."""
    if (own.nq, own.nv, own.njnt) != (model.nq, model.nv, model.njnt):
        return (
            f"nq={own.nq}, nv={own.nv}, {own.njnt} joints against nq={model.nq}, "
            f"nv={model.nv}, {model.njnt} joints"
        )
    for name in ("jnt_type", "jnt_qposadr", "jnt_dofadr", "jnt_limited"):
        if not np.array_equal(getattr(own, name), getattr(model, name)):
            j = int(np.flatnonzero(getattr(own, name) != getattr(model, name))[0])
            return f"joint {j}'s {name} differs"
    names = [(a, b) for a, b in zip(joint_names(own), joint_names(model)) if a != b]
    return f"joint {names[0][0]!r} where the solver's model has {names[0][1]!r}" if names else "?"


def check_limit_model(limit, model: mujoco.MjModel) -> None:
    """LimitDefinitionError where ``limit`` holds a model (``limit.model``: mink's position
    and collision limits, qpik's) of another robot than ``model`` (:func:`same_robot`)."""
    own = getattr(limit, "model", None)
    if isinstance(own, mujoco.MjModel) and not same_robot(own, model):
        raise LimitDefinitionError(
            f"{limit_name(limit)} was built for another model than the solver's "
            f"({_difference(own, model)}): build it from the solver's model"
        )
    # mink's limits without a model (VelocityLimit): their projection's width is their
    # model's nv, and their dof indices must be the solver's
    projection = getattr(limit, "projection_matrix", None)
    if isinstance(projection, np.ndarray) and projection.ndim == 2:
        if projection.shape[1] != model.nv:
            raise LimitDefinitionError(
                f"{limit_name(limit)} was built for another model (nv={projection.shape[1]}) "
                f"than the solver's (nv={model.nv}): build it from the solver's model"
            )
    indices = getattr(limit, "indices", None)
    if isinstance(indices, np.ndarray) and indices.size and indices.dtype.kind in "iu":
        if int(indices.min()) < 0 or int(indices.max()) >= model.nv:
            raise LimitDefinitionError(
                f"{limit_name(limit)}: dof index {int(indices.max())} out of range for the "
                f"solver's model (nv={model.nv}): was it built for another model?"
            )
