"""Limits by value: what :class:`qpik.diffik.mink_compat.SolverCache` finds a kept solver
by besides identity (mink's ``ConfigurationLimit`` and ``VelocityLimit``: a control loop
that builds ``[mink.ConfigurationLimit(model)]`` at each call)."""

from __future__ import annotations

from typing import Any

import mink
import numpy as np

__all__ = ["limit_value", "value_key"]


def limit_value(limit: Any) -> tuple | None:
    """A limit's value, by which the solver cache of ``solve_ik``
    (:class:`~qpik.diffik.mink_compat.SolverCache`) also finds a kept solver (mink's
    ``ConfigurationLimit`` and ``VelocityLimit`` exactly: a control loop that builds
    ``[mink.ConfigurationLimit(model)]`` at each call): its class and the arrays and
    numbers its rows are computed from; None for any other limit (found by identity only)."""
    kind = type(limit)
    arrays = LIMIT_VALUES.get(kind)
    if arrays is None:
        return None
    try:  # (an attribute edited into what no solver takes: found by identity, then named)
        values = [getattr(limit, name) for name in arrays]
        if not all(type(v) is np.ndarray for v in values):
            return None
        gain = getattr(limit, "gain", None)
        if gain is not None and type(gain) is not float:
            return None
        return (kind, id(getattr(limit, "model", None)), gain, *(
            (v.dtype.str, v.shape, v.tobytes()) for v in values
        ))  # fmt: skip
    except AttributeError:
        return None


#: The arrays a limit's rows are computed from, per class of :func:`limit_value`.
LIMIT_VALUES: dict[type, tuple[str, ...]] = {
    mink.ConfigurationLimit: ("lower", "upper", "indices", "_ball_max_angle"),
    mink.VelocityLimit: ("indices", "limit", "projection_matrix"),
}


def value_key(key: tuple, limits: Any) -> tuple | None:
    """``key`` (a key of :class:`~qpik.diffik.mink_compat.SolverCache`) with its limits by
    value (:func:`limit_value`), None where a limit has none."""
    if type(limits) not in (list, tuple) or not limits:
        return None
    values = tuple(map(limit_value, limits))
    if None in values:
        return None
    return (*key[:2], values, *key[3:])
