"""Secondary objectives, meant for lower priority levels (the ``zeta`` of
``qdot = J^+ xi + N(q) zeta``).

Both are scalar tasks: the error is a scalar measure ``w(q)``, the Jacobian its gradient
``dw/dq`` (1, nv), so ``J dq = -gain * w`` moves ``q`` along the gradient. Placed below a
frame task, the QP restricts that motion to the null space of the frame task, as in the
general solution ``qdot = J^+ xi + N(q) zeta``.
"""

from __future__ import annotations

import mink
import mujoco
import numpy as np

from ..core import checks
from ..core.jacobian import (
    joint_limit_distance_terms,
    joint_limit_midranges,
    manipulability,
    row_indices,
)
from ..errors import mink_errors_as_qpik
from ..model.configuration import Configuration, FrameType
from ..model.gradients import manipulability_gradient, manipulability_terms

# These tasks read what only qpik.Configuration has (frame_pose, frame_jacobian, lower, upper), so
# their compute_* methods narrow mink's ``configuration: mink.Configuration`` (hence the
# ``type: ignore[override]``); qpik's entry points (qpik.diffik.mink_compat) turn a mink
# configuration into a qpik one before any task sees it.


def _scalar_joints(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """``(qpos indices, dof indices)`` of the hinge and slide joints, in joint order (a
    ball or free joint has several qpos entries and no scalar limit)."""
    scalar = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    joints = [j for j in range(model.njnt) if int(model.jnt_type[j]) in scalar]
    return (
        np.array([model.jnt_qposadr[j] for j in joints], dtype=np.int64),
        np.array([model.jnt_dofadr[j] for j in joints], dtype=np.int64),
    )


class JointLimitDistanceTask(mink.Task):
    """Keep joints away from their limits.

    Error ``w(q)``: :func:`qpik.analysis.joint_limit_distance` over the hinge and slide
    joints (``n`` of them), the mean squared distance of each joint from its mid-range,
    normalised by its range (0 at mid-range, 1/8 at the limits for every joint). Unlimited
    joints count in ``n`` and add 0; ball and free joints do not count. The Jacobian
    ``(1, nv)`` is its gradient, 0 on the dofs of ball and free joints.
    """

    k = 1

    def __init__(self, cost: float = 1.0, gain: float = 0.5, lm_damping: float = 0.0):
        numbers = {"cost": cost, "gain": gain, "lm_damping": lm_damping}
        with mink_errors_as_qpik(type(self).__name__, numbers):
            super().__init__(np.array([float(cost)]), gain, lm_damping)
        self._joints: tuple[mujoco.MjModel, np.ndarray, np.ndarray] | None = None
        #: (the limits' bytes, limited joints, their qpos and dofs, half, mid / half) of the
        #: last limits seen (see _terms)
        self._midranges: tuple | None = None

    def _indices(self, configuration: Configuration) -> tuple[np.ndarray, np.ndarray]:
        """The model's scalar joints (see :func:`_scalar_joints`), kept per model."""
        model = configuration.model
        if self._joints is None or self._joints[0] is not model:
            self._joints = (model, *_scalar_joints(model))
        return self._joints[1], self._joints[2]

    def _terms(self, configuration: Configuration) -> tuple[np.ndarray, np.ndarray]:
        """The error (1,) and Jacobian (1, nv) (see the class), from one pass: the values of
        :func:`qpik.analysis.joint_limit_distance` and its gradient, bit for bit, with the
        limits' mid-ranges kept while the limits are the same (checked once, when they
        change); :func:`joint_limit_distance_terms` itself where a value is not finite (it
        raises the typed error)."""
        qpos, dofs = self._indices(configuration)
        key = (configuration.lower.tobytes(), configuration.upper.tobytes())
        kept = self._midranges
        if kept is None or kept[0] != key:
            mid, half = joint_limit_midranges(configuration.lower[qpos], configuration.upper[qpos])
            where = np.flatnonzero(half > 0)  # the limited joints, in joint order
            with np.errstate(over="ignore", invalid="ignore"):
                kept = (key, where, qpos[where], dofs[where], half[where], mid[where] / half[where])
            self._midranges = kept
        _, where, limited_qpos, limited_dofs, half, mid_over_half = kept
        n = qpos.size
        ratio = np.zeros(n)  # (zeros kept at the unlimited joints: np.sum's grouping)
        with np.errstate(over="ignore", invalid="ignore"):
            limited = 0.5 * (configuration.q[limited_qpos] / half - mid_over_half)
            ratio[where] = limited
            w = np.sum(ratio**2) / (2 * n) if n else 0.0
            gradient = limited / (2 * n) / half
        if not (np.isfinite(w) and np.isfinite(gradient).all()):
            q = configuration.q[qpos]  # the checked computation: it raises the typed error
            joint_limit_distance_terms(q, configuration.lower[qpos], configuration.upper[qpos])
        jacobian = np.zeros((1, configuration.model.nv))
        jacobian[0, limited_dofs] = gradient
        return np.array([float(w)]), jacobian

    def compute_error(self, configuration: Configuration) -> np.ndarray:  # type: ignore[override]
        return self._terms(configuration)[0]

    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:  # type: ignore[override]
        return self._terms(configuration)[1]

    def compute_qp_residual(  # type: ignore[override]
        self, configuration: Configuration
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """mink's weighted residual of :meth:`_terms` (one pass, not two)."""
        return self._weighted_residual(*self._terms(configuration))


class ManipulabilityTask(mink.Task):
    """Raise the manipulability ``m(q) = sqrt(det J J^T)`` of a frame.

    Error ``e = -m(q)``; ``J dq = -gain * e`` asks each step for an increase of ``gain * m``
    along the gradient of ``m``. ``rows`` selects the rows of the frame's world-aligned
    Jacobian ``[v; omega]``: ``"pose"`` (6), ``"position"`` (3), ``"orientation"`` (3) or
    a sequence of row names / indices (see :mod:`qpik.analysis`); anything else raises
    :class:`qpik.InvalidInput` here, at construction. The error and its Jacobian use the
    same rows.
    """

    k = 1

    def __init__(
        self,
        frame_name: str,
        frame_type: FrameType | str = FrameType.SITE,
        rows: str = "pose",
        cost: float = 1.0,
        gain: float = 0.1,
        lm_damping: float = 0.0,
    ):
        numbers = {"cost": cost, "gain": gain, "lm_damping": lm_damping}
        with mink_errors_as_qpik(type(self).__name__, numbers):
            super().__init__(np.array([float(cost)]), gain, lm_damping)

        self.frame_name: str | int = checks.check_instance(
            "frame_name", frame_name, (str, int), "a frame name (or id)"
        )
        self.frame_type = FrameType.parse(frame_type)
        self._row_index = list(row_indices(rows))  # raises for an unknown choice
        self.rows = rows

    def compute_error(self, configuration: Configuration) -> np.ndarray:  # type: ignore[override]

        jacobian = configuration.frame_jacobian(self.frame_name, self.frame_type)
        return np.array([-manipulability(jacobian[self._row_index])])

    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:  # type: ignore[override]

        gradient = manipulability_gradient(
            configuration, self.frame_name, self.frame_type.value, rows=self.rows
        )
        return -np.asarray(gradient)[None, :]

    def compute_qp_residual(  # type: ignore[override]
        self, configuration: Configuration
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """mink's weighted residual of the error and Jacobian from one frame Jacobian
        (:func:`qpik.model.gradients.manipulability_terms`)."""
        value, gradient = manipulability_terms(
            configuration, self.frame_name, self.frame_type.value, rows=self.rows
        )
        return self._weighted_residual(np.array([-value]), -gradient[None, :])
