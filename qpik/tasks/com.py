r"""Centre-of-mass task: move the robot's CoM to a target point (world frame).

The CoM of the subtree rooted at ``body`` (default body 1, the robot's root: the whole
robot when the world has one child body, as for every model :func:`qpik.load_robot`
builds) is MuJoCo's ``data.subtree_com[body]`` [m], world frame. Its Jacobian
``J_c = d c / d q`` ``(3, nv)`` is MuJoCo's ``mj_jacSubtreeCom`` (for a free joint the
columns follow MuJoCo's velocity convention: linear velocity in the world frame, angular
velocity in the body frame, the same as ``mj_integratePos``).

Error ``e = c(q) - c*`` ``(3,)`` [m]; the QP asks ``J_c dq = -gain e``. Error and Jacobian
equal mink's :class:`mink.ComTask` for body 1 (tests check both, and the Jacobian against
finite differences).
"""

from __future__ import annotations

import mink
import mujoco
import numpy as np
import numpy.typing as npt

from ..core import checks
from ..errors import (
    InvalidTarget,
    TargetNotSet,
    TaskDefinitionError,
    UnknownFrame,
    mink_errors_as_qpik,
)
from ..model.com import subtree_com_chain, subtree_com_jacobian
from ..model.configuration import frame_names
from .checked import CheckedTask

__all__ = ["ComTask"]


class ComTask(mink.Task, CheckedTask):
    """Drive the centre of mass of a subtree to a world-frame target [m].

    Args:
        cost: weight of the rows, a number or one per axis ``(3,)`` [1/m] (a zero weight
            drops that axis: ``cost=[1, 1, 0]`` leaves the height free).
        gain: fraction in [0, 1] of the error corrected per step.
        lm_damping: Levenberg-Marquardt damping (mink's).
        body: root of the subtree, by name or id (default 1: the robot's root body).
    """

    k: int = 3

    def __init__(
        self,
        cost: npt.ArrayLike = 1.0,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        body: str | int = 1,
    ):
        numbers = {"gain": gain, "lm_damping": lm_damping}
        with mink_errors_as_qpik(type(self).__name__, numbers):
            super().__init__(cost=np.zeros(self.k), gain=gain, lm_damping=lm_damping)
        if isinstance(body, (bool, np.bool_)) or not isinstance(body, (str, int, np.integer)):
            raise TaskDefinitionError(
                f"ComTask: body must be a body name or id (an int), got {checks.type_name(body)}"
                f" {body!r}"
            )
        self.body = body
        self.target_com: np.ndarray | None = None
        #: (model, body id, its subtree's per-dof chain) of the last compute_jacobian
        self._chain: tuple | None = None
        self.set_cost(cost)

    def __getstate__(self) -> dict:
        """The task's attributes for pickling and copies, without the cached chain (made
        again on first use: it holds the model)."""
        return {**self.__dict__, "_chain": None}

    def set_cost(self, cost: npt.ArrayLike) -> None:
        """Set the weights: one number for all three axes, or ``(3,)``, all >= 0."""
        with mink_errors_as_qpik("ComTask", {"cost": cost}):
            cost = np.atleast_1d(np.asarray(cost, dtype=float))
        if cost.ndim != 1 or cost.shape[0] not in (1, self.k) or not np.all(cost >= 0):
            raise TaskDefinitionError(
                f"ComTask cost must be one number or 3 numbers, all >= 0; got {cost.tolist()}"
            )
        self.cost[:] = cost

    def set_target(self, target_com: npt.ArrayLike) -> None:
        """Set the target CoM ``(3,)`` [m], world frame."""
        target = checks.check_vector("CoM target", target_com, self.k, error=InvalidTarget)
        self.target_com = target.copy()

    def set_target_from_configuration(self, configuration: mink.Configuration) -> None:
        """Target the CoM the configuration has now."""
        self.set_target(self.com(configuration))

    def _body_id(self, configuration: mink.Configuration) -> int:
        model = configuration.model
        if isinstance(self.body, str):
            body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, self.body)
        else:
            body = int(self.body) if 0 <= int(self.body) < model.nbody else -1
        if body < 0:
            raise UnknownFrame(self.body, "body", frame_names(model, "body"))
        return body

    def com(self, configuration: mink.Configuration) -> np.ndarray:
        """The subtree's CoM ``(3,)`` [m], world frame."""
        return configuration.data.subtree_com[self._body_id(configuration)].copy()

    def compute_error(self, configuration: mink.Configuration) -> np.ndarray:
        """``e = c(q) - c*`` ``(3,)`` [m], world frame."""
        if self.target_com is None:
            raise TargetNotSet(self.__class__.__name__)
        return self.com(configuration) - self.target_com

    def compute_jacobian(self, configuration: mink.Configuration) -> np.ndarray:
        """``J_c = d c / d q`` ``(3, nv)`` [m per unit of dq], world frame: the subtree's
        mass-weighted dof columns in O(nv) (:mod:`qpik.model.com`, as the compiled step
        computes them; ``mj_jacSubtreeCom``'s to round-off); for a massless subtree, whose
        CoM MuJoCo puts at the body's inertial frame origin, that point's Jacobian."""
        model = configuration.model
        body = self._body_id(configuration)
        jacobian = np.empty((self.k, model.nv))
        cached = self._chain
        if cached is None or cached[0] is not model or cached[1] != body:
            cached = self._chain = (model, body, subtree_com_chain(model, body))
        if cached[2] is None:
            # A massless subtree: MuJoCo's CoM is the body's inertial frame origin (its
            # subtree_com), and mj_jacSubtreeCom divides by the mass (NaN): the Jacobian of
            # that point on the body instead
            data = configuration.data
            mujoco.mj_jac(model, data, jacobian, None, data.subtree_com[body].copy(), body)
            return jacobian
        return subtree_com_jacobian(configuration.data, cached[2], jacobian)
