"""The model's couplings as a task: the rows ``r(q) = 0`` of
:class:`qpik.model.Couplings` (joint and fixed-tendon equalities, URDF ``<mimic>``).

:class:`qpik.IKSolver` puts it, alone, in a level above the stack's (option
``StepOptions.couplings``, on by default), so the stack acts in its null space; it can
also be placed in a stack by hand (with ``couplings=False``)."""

from __future__ import annotations

import mink
import mujoco
import numpy as np

from .._engine.tasks import linear_residual
from ..errors import TaskDefinitionError, check_task_numbers, mink_errors_as_qpik
from ..model.couplings import Couplings, model_couplings
from .checked import CheckedTask


class CouplingTask(mink.Task, CheckedTask):
    """Hold the model's couplings: error ``r(q)`` (one row per coupling,
    :meth:`qpik.model.Couplings.residual`), Jacobian ``dr/dq`` (exact).

    Args:
        model: the MuJoCo model; it must state at least one coupling
            (:class:`qpik.TaskDefinitionError` otherwise).
        cost: weight of every row. Default 1.
        gain: fraction of the residual a step removes, in [0, 1]. Default 1 (a linear
            coupling holds after one step).
    """

    def __init__(self, model: mujoco.MjModel, cost: float = 1.0, gain: float = 1.0):
        check_task_numbers(type(self).__name__, {"cost": cost, "gain": gain})
        couplings = model_couplings(model)
        if couplings is None:
            raise TaskDefinitionError(
                "CouplingTask: the model states no joint or fixed-tendon equality"
            )
        self.couplings: Couplings = couplings
        self.k = len(couplings)
        with mink_errors_as_qpik(type(self).__name__, {"cost": cost, "gain": gain}):
            super().__init__(np.full(self.k, float(cost)), gain, 0.0)
        # Linear couplings (a URDF mimic, a joint equality of degree 1): the residual is one
        # compiled product over qpos (the compiled step's own arithmetic, so both paths give
        # the same bits), and the Jacobian is constant, computed once.
        linear = couplings.linear_form()
        self._constant = couplings.jacobian(model.qpos0) if linear else None
        self._form: np.ndarray | None = None
        if linear is not None:
            rows, offset = linear
            form = np.zeros((self.k, model.nq + 1))
            for t, adr in enumerate(couplings.qadr.tolist()):
                form[:, adr] += rows[:, t]
            form[:, model.nq] = offset
            self._form = form

    @property
    def linear_form(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(form, jacobian)`` when every coupling is linear, else None: the residual is
        ``form[:, :nq] @ q - form[:, nq]`` (``form`` ``(k, nq + 1)``, over qpos) and the
        Jacobian ``(k, nv)`` is constant (copies)."""
        if self._form is None or self._constant is None:
            return None
        return self._form.copy(), self._constant.copy()

    def compute_error(self, configuration: mink.Configuration) -> np.ndarray:
        """The couplings' residual ``(k,)`` at the configuration's ``q`` (0 where met)."""
        if self._form is not None:  # the configuration's q is already checked
            return linear_residual(self._form, configuration.q)
        return self.couplings.residual(configuration.q)

    def compute_jacobian(self, configuration: mink.Configuration) -> np.ndarray:
        """The residual's Jacobian ``(k, nv)`` (a copy; constant for linear couplings)."""
        if self._constant is not None:
            return self._constant.copy()
        return self.couplings.jacobian(configuration.q)
