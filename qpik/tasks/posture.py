"""PostureTask and DampingTask: mink's joint-space tasks, with hinge/slide-only models
computed as ``q - q*`` and a cached identity Jacobian, and qpik's typed errors."""

from __future__ import annotations

import mink
import mujoco
import numpy as np
import numpy.typing as npt

from ..errors import TargetNotSet, mink_errors_as_qpik, qpik_errors
from .checked import CheckedTask

__all__ = ["DampingTask", "PostureTask"]


class PostureTask(mink.PostureTask, CheckedTask):
    """mink's :class:`~mink.PostureTask` (error ``q ⊖ q*``, Jacobian the identity, free
    joints' rows zeroed), with hinge/slide-only models computed as ``q - q*`` and a cached
    identity."""

    def __init__(
        self,
        model: mujoco.MjModel,
        cost: npt.ArrayLike,
        gain: float = 1.0,
        lm_damping: float = 0.0,
    ):
        """On ``model``'s configuration; ``cost`` [1/rad or 1/m]: one number or ``(nv,)``,
        >= 0; ``gain`` in [0, 1]; ``lm_damping`` >= 0 (mink's)."""
        arguments = {"model": model, "cost": cost, "gain": gain, "lm_damping": lm_damping}
        with mink_errors_as_qpik(type(self).__name__, arguments):
            super().__init__(model, cost, gain, lm_damping)
        self._scalar = model.nq == model.nv and self._v_ids is None
        self._jacobian = np.eye(model.nv)
        if self._v_ids is not None:
            self._jacobian[:, self._v_ids] = 0.0
        self._jacobian.setflags(write=False)

    def set_target(self, target_q: npt.ArrayLike) -> None:
        """The target configuration ``q*`` (nq,) [rad or m]; mink's checks, raised as
        qpik's errors (:class:`qpik.InvalidTarget` for a wrong shape)."""
        with qpik_errors():
            super().set_target(target_q)

    def compute_error(self, configuration: mink.Configuration) -> np.ndarray:
        """``q ⊖ q*`` ``(nv,)`` [rad or m] (``q - q*`` on hinge and slide joints);
        :class:`qpik.TargetNotSet` before a target is set."""
        if self.target_q is None:
            raise TargetNotSet(self.__class__.__name__)
        if self._scalar:
            return configuration.data.qpos - self.target_q
        return super().compute_error(configuration)

    def compute_jacobian(self, configuration: mink.Configuration) -> np.ndarray:
        """The identity ``(nv, nv)``, free joints' rows zeroed (a copy)."""
        return self._jacobian.copy()

    def compute_qp_residual(
        self, configuration: mink.Configuration
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """``(diag(cost) J, -gain diag(cost) e, lm_damping |b|^2)``: the task's rows."""
        error = self.compute_error(configuration)
        weighted_error = self.cost * (-self.gain * error)
        # |b|^2 summed in order, as the fused step's posture_rows sums it (a BLAS dot's
        # order differs in the last bit, and the level's answer may see it).
        acc = 0.0
        for v in weighted_error.tolist():
            acc += v * v
        mu = self.lm_damping * acc
        return self.cost[:, None] * self._jacobian, weighted_error, mu


class DampingTask(mink.DampingTask, CheckedTask):
    """mink's :class:`~mink.DampingTask` (a posture task toward the current
    configuration: it penalises the displacement), whose definition errors are qpik's
    typed errors (each also mink's)."""

    def __init__(self, model: mujoco.MjModel, cost: npt.ArrayLike):
        """On ``model``; ``cost`` [1/rad or 1/m]: one number or ``(nv,)``, >= 0."""
        with mink_errors_as_qpik(type(self).__name__, {"model": model, "cost": cost}):
            super().__init__(model, cost)
