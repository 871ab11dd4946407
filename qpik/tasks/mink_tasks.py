"""mink's tasks that qpik re-exports, with qpik's errors.

Each class here subclasses mink's (``isinstance(task, mink.RelativeFrameTask)`` holds,
and mink's code paths apply) and changes only its errors: an error mink raises while the
task is built, given a target or evaluated (``TargetNotSet`` before ``set_target``,
``IntegrationTimestepNotSet`` before ``set_dt``, ...) is raised as qpik's counterpart
(:func:`qpik.errors.as_qpik_error`), which also subclasses mink's, so ``except
mink.TargetNotSet`` and ``except qpik.QpikError`` both catch it. Numbers are checked
where they enter: a cost must be finite and >= 0, ``set_dt`` takes ``dt`` in
[:data:`qpik.core.checks.DT_MIN`, :data:`qpik.core.checks.DT_MAX`] [s].
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import mink
import mujoco
import numpy as np
import numpy.typing as npt

from ..core import checks
from ..errors import (
    InvalidTarget,
    QpikError,
    TaskDefinitionError,
    arguments_of,
    check_task_numbers,
    mink_errors_as_qpik,
    qpik_errors,
)
from ..model.frames import check_frame_type
from .checked import CheckedTask

__all__ = [
    "AxisAlignTask",
    "DofFreezingTask",
    "EqualityConstraintTask",
    "KineticEnergyRegularizationTask",
    "LookAtTask",
    "RelativeFrameTask",
]

#: The methods whose mink errors become qpik's (those a task class defines).
_RUN_METHODS = (
    "set_target",
    "set_target_from_configuration",
    "compute_error",
    "compute_jacobian",
    "compute_qp_objective",
    "compute_qp_residual",
)

_C = TypeVar("_C", bound=type)

#: The constructor arguments that name a frame (a str, or an int id as mink takes).
_FRAME_ARGUMENTS = ("frame_name", "root_name")
#: The constructor arguments that name a frame type (body, site or geom).
_FRAME_TYPE_ARGUMENTS = ("frame_type", "root_type")


def _run_with_qpik_errors(method: Callable[..., Any]) -> Callable[..., Any]:
    @functools.wraps(method)
    def wrapped(self, *args: Any, **kwargs: Any) -> Any:
        with qpik_errors():
            return method(self, *args, **kwargs)

    return wrapped


def _set_target_with_qpik_errors(method: Callable[..., Any]) -> Callable[..., Any]:
    """``set_target``: also a target of a wrong type (mink's would raise an
    ``AttributeError`` or ``TypeError``) raises :class:`qpik.InvalidTarget`."""
    run = _run_with_qpik_errors(method)

    @functools.wraps(method)
    def wrapped(self, *args: Any, **kwargs: Any) -> Any:
        try:
            return run(self, *args, **kwargs)
        except (AttributeError, TypeError, ValueError) as error:
            if isinstance(error, QpikError):
                raise
            raise InvalidTarget(f"{type(self).__name__}.set_target: {error}") from error

    return wrapped


def _init_with_qpik_errors(method: Callable[..., Any]) -> Callable[..., Any]:
    @functools.wraps(method)
    def wrapped(self, *args: Any, **kwargs: Any) -> None:
        arguments = arguments_of(method, self, *args, **kwargs)
        for name in _FRAME_ARGUMENTS:  # mink checks none of them until the first step
            if name in arguments:
                checks.check_frame_name(name, arguments[name])
        for name in _FRAME_TYPE_ARGUMENTS:
            if name in arguments:
                check_frame_type(type(self).__name__, name, arguments[name])
        check_task_numbers(type(self).__name__, arguments)
        with mink_errors_as_qpik(type(self).__name__, arguments):
            method(self, *args, **kwargs)
        cost = getattr(self, "cost", None)
        if cost is not None:
            try:
                finite = all(math.isfinite(float(c)) for c in getattr(cost, "flat", [cost]))
            except (TypeError, ValueError):
                finite = False
            if not finite:
                raise TaskDefinitionError(
                    f"{type(self).__name__}: cost must be finite and >= 0, got {cost!r}"
                )

    return wrapped


def _with_qpik_errors(cls: _C) -> _C:
    """Wrap ``cls``'s constructor and run methods (inherited from mink) as described in
    the module docstring."""
    init = cls.__dict__.get("__init__", cls.__mro__[1].__init__)  # type: ignore[misc]
    cls.__init__ = _init_with_qpik_errors(init)  # type: ignore[misc]
    for name in _RUN_METHODS:
        method = getattr(cls, name, None)
        if method is not None and not getattr(method, "__isabstractmethod__", False):
            wrap = _set_target_with_qpik_errors if name == "set_target" else _run_with_qpik_errors
            setattr(cls, name, wrap(method))
    return cls


@_with_qpik_errors
class AxisAlignTask(mink.AxisAlignTask, CheckedTask):
    """mink's :class:`mink.AxisAlignTask`, with qpik's errors."""


@_with_qpik_errors
class DofFreezingTask(mink.DofFreezingTask, CheckedTask):
    """mink's :class:`mink.DofFreezingTask`, with qpik's errors: ``model`` must be an
    ``MjModel`` and ``dof_indices`` distinct ints in ``[0, nv)``
    (:func:`qpik.core.checks.check_indices`)."""

    def __init__(self, model: mujoco.MjModel, dof_indices: list[int], gain: float = 1.0):
        checks.check_instance("model", model, mujoco.MjModel, "a mujoco.MjModel")
        if isinstance(dof_indices, (list, tuple)) and not dof_indices:
            raise TaskDefinitionError("DofFreezingTask requires at least one DOF index")
        indices = checks.check_indices("dof_indices", dof_indices, model.nv)
        super().__init__(model, indices, gain)


@_with_qpik_errors
class EqualityConstraintTask(mink.EqualityConstraintTask, CheckedTask):
    """mink's :class:`mink.EqualityConstraintTask`, with qpik's errors (``equalities``
    other than ``None`` or a sequence of equality ids and names is named)."""

    def __init__(
        self,
        model: mujoco.MjModel,
        cost: npt.ArrayLike,
        equalities: Sequence[int | str] | None = None,
        gain: float = 1.0,
        lm_damping: float = 0.0,
    ) -> None:
        entries = equalities if equalities is not None else []
        if isinstance(entries, (str, bytes)) or not isinstance(entries, Sequence):
            raise TaskDefinitionError(
                "EqualityConstraintTask: argument equalities must be None or a sequence of "
                f"equality ids or names, got {type(equalities).__name__}"
            )
        for entry in entries:
            if isinstance(entry, bool) or not isinstance(entry, (int, np.integer, str)):
                raise TaskDefinitionError(
                    "EqualityConstraintTask: argument equalities holds "
                    f"{type(entry).__name__} {entry!r}; expected equality ids or names"
                )
        super().__init__(model, cost, equalities, gain, lm_damping)


@_with_qpik_errors
class LookAtTask(mink.LookAtTask, CheckedTask):
    """mink's :class:`mink.LookAtTask`, with qpik's errors."""


@_with_qpik_errors
class RelativeFrameTask(mink.RelativeFrameTask, CheckedTask):
    """mink's :class:`mink.RelativeFrameTask`, with qpik's errors (a frame or root type
    that is not ``"body"``, ``"site"`` or ``"geom"`` raises :class:`qpik.UnknownFrameType`
    at once; a step before ``set_target`` raises :class:`qpik.TargetNotSet`; a target that
    is not a :class:`mink.SE3` raises :class:`qpik.InvalidTarget`)."""

    def __init__(
        self,
        frame_name: str | int,
        frame_type: str,
        root_name: str | int,
        root_type: str,
        position_cost: npt.ArrayLike,
        orientation_cost: npt.ArrayLike,
        gain: float = 1.0,
        lm_damping: float = 0.0,
    ) -> None:
        super().__init__(
            frame_name, frame_type, root_name, root_type, position_cost, orientation_cost,
            gain, lm_damping,
        )  # fmt: skip

    def set_target(self, transform_target_to_root: mink.SE3) -> None:
        """Target pose of the frame in the root frame, a :class:`mink.SE3`."""
        if not isinstance(transform_target_to_root, mink.SE3):
            raise InvalidTarget(
                f"{type(self).__name__}.set_target takes a mink.SE3, got "
                f"{type(transform_target_to_root).__name__}"
            )
        super().set_target(transform_target_to_root)


@_with_qpik_errors
class KineticEnergyRegularizationTask(mink.KineticEnergyRegularizationTask, CheckedTask):
    """mink's :class:`mink.KineticEnergyRegularizationTask`, with qpik's errors (a step
    before :meth:`set_dt` raises :class:`qpik.IntegrationTimestepNotSet`), a finite cost
    >= 0 and a checked ``dt``."""

    def set_dt(self, dt: float) -> None:
        """Set the integration time step ``dt`` [s], in [:data:`qpik.core.checks.DT_MIN`,
        :data:`qpik.core.checks.DT_MAX`]."""
        super().set_dt(checks.check_dt(dt))
