"""FrameTask: mink's frame task with its rows computed straight from MuJoCo.

It is mink's class (``isinstance(task, mink.FrameTask)`` holds, targets are set the same
way) whose error and Jacobian are computed without building SE3 objects or re-allocating
per step: the frame pose and world-aligned Jacobian come from MuJoCo
(``data.site_xpos``/``site_xmat``, ``mj_jacSite``, and the body/geom equivalents), the SE3
log, its Jacobian and the local-frame rotation from mink's Lie-group arithmetic (its C
routines, ported to C++: :mod:`qpik.model.lie`).
They equal mink's own to round-off (tests check 1e-12).
"""

from __future__ import annotations

from typing import Any

import mink
import numpy as np
import numpy.typing as npt

from .._engine.tasks import frame_error_jlog, frame_rows_into
from ..core import checks
from ..errors import TargetNotSet, mink_errors_as_qpik, qpik_errors
from ..model.frames import (
    FRAME_JACOBIANS,
    FRAME_OBJECTS,
    FRAME_POSITIONS,
    FRAME_ROTATIONS,
    check_frame_type,
)
from .checked import CheckedTask, check_pose_target

__all__ = ["FrameTask", "frame_terms"]


def _frame_type_name(frame_type) -> str:
    return getattr(frame_type, "value", frame_type)


# The compiled kernels (qpik/_cpp/tasks/frame.hpp, bound in qpik._engine.tasks):
#
# frame_error_jlog(xmat, xpos, target) -> (error (6,), jlog (6, 6)): mink's frame-task error
#     log(T_fw^-1 T_tw) (the body twist from the frame at (xpos, xmat) to target,
#     wxyz_xyz) and jlog(T_tw^-1 T_fw), by mink's own SE(3) arithmetic (qpik.model.lie).
# frame_rows_into(A, b, row, jac, xmat, jlog, error, cost, gain, lm_damping) -> float:
#     rows row:row+6 of a frame task written into A/b (float64 C-contiguous, in place):
#     A = diag(cost) (-jlog) [R^T Jp; R^T Jr], b = -gain cost e (mink's
#     _weighted_residual); returns the LM term lm_damping |b|^2. jac is MuJoCo's
#     world-aligned Jacobian (6, nv), xmat the frame's rotation (row-major 9).


def frame_terms(task: mink.FrameTask, configuration) -> tuple | None:
    """``(jac, xmat, jlog, error)`` of a frame task (mink's or qpik's) at ``configuration``
    (qpik's), from MuJoCo and mink's SE3 arithmetic (:func:`frame_error_jlog`): the
    world-aligned Jacobian (6, nv), the frame's rotation (row-major 9), ``jlog(T_tb)`` and
    the body-twist error; ``None`` for a frame type only mink's generic path knows."""
    target = task.transform_target_to_world
    if target is None:
        raise TargetNotSet(task.__class__.__name__)
    check_pose_target(task, target, "transform_target_to_world")  # (mink's: set unchecked)
    kind: Any = _frame_type_name(task.frame_type)  # (a FrameType's value: its str keys)
    if kind not in FRAME_OBJECTS:
        return None
    model, data = configuration.model, configuration.data
    fid = configuration._resolve_frame_id(task.frame_name, kind)
    xpos = getattr(data, FRAME_POSITIONS[kind])[fid]
    xmat = getattr(data, FRAME_ROTATIONS[kind])[fid]
    jac = np.empty((6, model.nv))
    FRAME_JACOBIANS[kind](model, data, jac[:3], jac[3:], fid)
    error, jlog = frame_error_jlog(xmat, xpos, target.wxyz_xyz)
    return jac, xmat, jlog, error


class FrameTask(mink.FrameTask, CheckedTask):
    """mink's :class:`~mink.FrameTask` (error: the body twist ``log(T_bt)`` of the frame to
    its target, expressed in the frame's local axes [m, rad]; Jacobian ``-jlog(T_tb)
    {}_B J``), computed from MuJoCo directly."""

    def __init__(
        self,
        frame_name: str | int,
        frame_type: str,
        position_cost: npt.ArrayLike,
        orientation_cost: npt.ArrayLike,
        gain: float = 1.0,
        lm_damping: float = 0.0,
    ):
        """``frame_name`` (a name, or an id) of ``frame_type`` (``"site"``, ``"body"`` or
        ``"geom"``); ``position_cost`` [1/m] and ``orientation_cost`` [1/rad]: one number
        or ``(3,)`` each, >= 0; ``gain`` in [0, 1]; ``lm_damping`` >= 0 (mink's)."""
        arguments = {
            "frame_name": frame_name,
            "frame_type": frame_type,
            "position_cost": position_cost,
            "orientation_cost": orientation_cost,
            "gain": gain,
            "lm_damping": lm_damping,
        }
        with mink_errors_as_qpik(type(self).__name__, arguments):
            super().__init__(
                frame_name, frame_type, position_cost, orientation_cost, gain, lm_damping
            )
        checks.check_frame_name("frame_name", self.frame_name)
        check_frame_type(type(self).__name__, "frame_type", self.frame_type)

    def set_target(self, transform_target_to_world: mink.SE3) -> None:
        """The target pose of the frame in the world frame, a :class:`mink.SE3` (copied, as
        mink's); anything else, or an SE3 whose quaternion is zero, raises
        :class:`qpik.InvalidTarget` naming the task
        (:func:`qpik.tasks.checked.check_pose_target`)."""
        check_pose_target(self, transform_target_to_world, "set_target's target")
        # (checked: stored as mink's set_target stores it, without CheckedTask's check again)
        object.__setattr__(self, "transform_target_to_world", transform_target_to_world.copy())

    def compute_error(self, configuration: mink.Configuration) -> np.ndarray:
        """mink's error (see the class); before a target is set, :class:`qpik.TargetNotSet`
        (mink's error, translated: every error qpik raises is a :class:`qpik.QpikError`)."""
        with qpik_errors():
            return super().compute_error(configuration)

    def compute_jacobian(self, configuration: mink.Configuration) -> np.ndarray:
        """mink's Jacobian (see the class); before a target is set, :class:`qpik.TargetNotSet`."""
        with qpik_errors():
            return super().compute_jacobian(configuration)

    def _error_and_jacobian(
        self, configuration: mink.Configuration
    ) -> tuple[np.ndarray, np.ndarray]:
        terms = frame_terms(self, configuration)
        if terms is None:
            return super()._error_and_jacobian(configuration)
        jac, xmat, jlog, error = terms
        # Local (body) Jacobian: MuJoCo's rows are world-aligned, rotate them by R^T.
        rotation_t = xmat.reshape(3, 3).T
        local = np.empty_like(jac)
        np.matmul(rotation_t, jac[:3], out=local[:3])
        np.matmul(rotation_t, jac[3:], out=local[3:])
        return error, -(jlog @ local)

    def compute_qp_residual(
        self, configuration: mink.Configuration
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """``(diag(cost) J, -gain diag(cost) e, mu)`` in one compiled call after MuJoCo's."""
        terms = frame_terms(self, configuration)
        if terms is None:
            return super().compute_qp_residual(configuration)
        jac, xmat, jlog, error = terms
        A = np.empty((6, jac.shape[1]))
        b = np.empty(6)
        mu = frame_rows_into(
            A, b, 0, jac, xmat, jlog, error, self.cost, float(self.gain), float(self.lm_damping)
        )
        return A, b, mu
