"""Secondary objectives, meant for lower priority levels (the ``zeta`` of
``qdot = J^+ xi + N(q) zeta``).

Both are scalar tasks: the error is a scalar measure ``w(q)`` that the task lowers (the
joint-limit distance; the inverse manipulability ``1 / m``, so that ``m`` rises), the
Jacobian its gradient ``dw/dq`` (1, nv), so ``J dq = -gain * w`` moves ``q`` down the
gradient of ``w``. Placed below a
frame task, the QP restricts that motion to the null space of the frame task, as in the
general solution ``qdot = J^+ xi + N(q) zeta``.
"""

from __future__ import annotations

import mink
import mujoco
import numpy as np

from .._engine.tasks import inverse_manipulability, joint_limit_distance_row
from ..core import checks
from ..core.jacobian import (
    joint_limit_distance_terms,
    joint_limit_midranges,
    row_indices,
)
from ..errors import TaskDefinitionError, mink_errors_as_qpik
from ..model.configuration import Configuration, FrameType, as_configuration
from ..model.gradients import frame_body, motion_chain
from .checked import CheckedTask

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


def _check_cost(what: str, cost: np.ndarray) -> None:
    """:class:`TaskDefinitionError` naming the cost unless it is finite and >= 0 (mink's
    Task takes any)."""
    if not (np.all(np.isfinite(cost)) and np.all(cost >= 0.0)):
        raise TaskDefinitionError(f"{what}: cost must be finite and >= 0, got {cost[0]!r}")


class JointLimitDistanceTask(mink.Task, CheckedTask):
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
        _check_cost(type(self).__name__, self.cost)
        self._joints: tuple[mujoco.MjModel, np.ndarray, np.ndarray] | None = None
        #: (the limits' bytes, limited_joints()) of the last limits seen (see _rows)
        self._midranges: tuple | None = None

    def _indices(self, configuration: Configuration) -> tuple[np.ndarray, np.ndarray]:
        """The model's scalar joints (see :func:`_scalar_joints`), kept per model."""
        _, qpos, dofs = self._indices_of(configuration.model)
        return qpos, dofs

    def limited_joints(
        self, model: mujoco.MjModel, lower: np.ndarray, upper: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
        """``(qpos addresses, dofs, half ranges, mid / half, n)`` of ``model``'s limited
        hinge and slide joints in joint order under the limits ``lower``, ``upper`` (nq,),
        and ``n`` the hinge and slide joints counted (limited or not): what its row is made
        of (``qpik._engine.tasks.joint_limit_distance_row``, which the compiled step calls
        too). The limits are checked here (:func:`qpik.analysis.joint_limit_distance`'s
        errors)."""
        _, qpos, dofs = self._indices_of(model)
        mid, half = joint_limit_midranges(lower[qpos], upper[qpos])
        where = np.flatnonzero(half > 0)
        with np.errstate(over="ignore", invalid="ignore"):
            moh = mid[where] / half[where]
        return qpos[where], dofs[where], half[where], moh, int(qpos.size)

    def _indices_of(self, model: mujoco.MjModel) -> tuple[mujoco.MjModel, np.ndarray, np.ndarray]:
        if self._joints is None or self._joints[0] is not model:
            self._joints = (model, *_scalar_joints(model))
        return self._joints

    def _rows(
        self, configuration: Configuration, cost: float, gain: float, lm_damping: float
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """``(A (1, nv), b (1,), mu)`` in one compiled call, the limited joints kept while the
        limits are the same (by their bytes); where a value is not finite,
        :func:`joint_limit_distance_terms` raises the typed error. A mink configuration is
        read through qpik's view of it."""
        configuration = as_configuration(configuration)
        key = (configuration.lower.tobytes(), configuration.upper.tobytes())
        kept = self._midranges
        if kept is None or kept[0] != key:
            joints = self.limited_joints(
                configuration.model, configuration.lower, configuration.upper
            )
            kept = self._midranges = (key, joints)
        qadr, dofs, half, moh, n = kept[1]
        A, b = np.empty((1, configuration.model.nv)), np.empty(1)
        mu, w = joint_limit_distance_row(
            A, b, 0, configuration.q, qadr, dofs, half, moh, float(n), cost, gain, lm_damping
        )
        if not (np.isfinite(w) and np.isfinite(A).all()):
            qpos, _ = self._indices(configuration)  # the checked computation: it raises
            joint_limit_distance_terms(
                configuration.q[qpos], configuration.lower[qpos], configuration.upper[qpos]
            )
        return A, b, mu

    def compute_error(self, configuration: Configuration) -> np.ndarray:  # type: ignore[override]
        """``w(q)`` (1,) (see the class)."""
        return self._rows(configuration, 1.0, -1.0, 0.0)[1]

    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:  # type: ignore[override]
        """``dw/dq`` (1, nv) (see the class)."""
        return self._rows(configuration, 1.0, -1.0, 0.0)[0]

    def compute_qp_residual(  # type: ignore[override]
        self, configuration: Configuration
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """``(cost dw/dq, -gain cost w, mu)`` in one compiled call."""
        cost = np.asarray(self.cost, dtype=float)
        if cost.size != 1:
            raise TaskDefinitionError(
                f"JointLimitDistanceTask: cost must be one number, got shape {cost.shape}"
            )
        return self._rows(
            configuration, float(cost.reshape(-1)[0]), float(self.gain), float(self.lm_damping)
        )


class ManipulabilityTask(mink.Task, CheckedTask):
    """Raise the manipulability ``m(q) = sqrt(det J J^T)`` of a frame.

    Error ``e = 1 / m(q)`` (the inverse manipulability: it falls as ``m`` rises, toward 0),
    Jacobian its gradient ``de/dq = -(dm/dq) / m^2`` (1, nv); ``J dq = -gain * e`` asks each
    step for ``dm/dq dq = gain * m``: an increase of ``gain * m`` along the gradient of
    ``m``. Where ``m`` is 0 (more rows than dofs, where ``m`` is 0 for every ``q``; an
    exact singularity; a smallest singular value at most :data:`RANK_FLOOR` = 1e-9 of the
    largest, where ``m`` is round-off and ``1 / m`` noise) or ``1 / m^2`` overflows, no
    step raises it to first order: ``e = 0`` and a zero row (the task is idle there). Near
    a maximum of ``m`` (its gradient vanishing) no step meets the increase asked, and the
    level's damping law and the step's trust region
    (:attr:`qpik.StepOptions.max_joint_speed`) bound the steps there (with neither, they
    grow as ``m / |dm/dq|``): with ``lm_damping = 0`` the steps then go back and forth across
    the maximum at the trust region's size. To settle there, give ``lm_damping``: its term
    ``lm_damping |gain e|^2`` outweighs ``|de/dq|^2`` where ``|d log m / dq|^2 <
    lm_damping gain^2``, and each step there is a gradient step ``d log m / dq /
    (lm_damping gain)`` [rad], which shrinks with the gradient (measured: ``lm_damping = 30``
    settles the bundled Panda, UR5e and planar arms at their maxima, their last steps below
    1e-15 rad, where ``0`` keeps steps of 0.031 rad; under it a posture level whose target
    is far from the maximum still pulls the arm along it at the trust region's size).
    ``rows`` selects the
    rows of the frame's world-aligned Jacobian ``[v; omega]``: ``"pose"`` (6),
    ``"position"`` (3), ``"orientation"`` (3) or a sequence of row names / indices (see
    :mod:`qpik.analysis`); anything else raises :class:`qpik.InvalidInput` here, at
    construction. The error and its Jacobian use the same rows.
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
        _check_cost(type(self).__name__, self.cost)

        self.frame_name: str | int = checks.check_instance(
            "frame_name", frame_name, (str, int), "a frame name (or id)"
        )
        self.frame_type = frame_type
        self.rows = rows

    @property
    def frame_type(self) -> FrameType:
        """The frame's type (settable: a :class:`qpik.model.frames.FrameType` or its name;
        an unknown one raises :class:`qpik.UnknownFrameType`)."""
        return self._frame_type

    @frame_type.setter
    def frame_type(self, value: FrameType | str) -> None:
        self._frame_type = FrameType.parse(value)

    @property
    def rows(self) -> str:
        """Which rows of the frame Jacobian the manipulability is of (settable, as the
        constructor's ``rows``: ``"pose"``, ``"position"``, ``"orientation"`` or a sequence
        of row names or indices, :func:`qpik.core.jacobian.row_indices`; another raises
        :class:`qpik.InvalidInput`)."""
        return self._rows

    @rows.setter
    def rows(self, value: str) -> None:
        self._row_index = list(row_indices(value))  # raises for an unknown choice
        self._rows = value

    @property
    def row_indices(self) -> tuple[int, ...]:
        """The indices of :attr:`rows` into the frame Jacobian's rows ``[v; omega]``."""
        return tuple(self._row_index)

    def chain(self, configuration: Configuration) -> tuple[np.ndarray, np.ndarray | None]:
        """``(dofs, thresholds)``: the dofs that move the task's frame (root first) and, where
        a ball or free joint is among them, each dof's threshold of the kinematic Hessian
        (:func:`qpik.model.gradients.motion_chain`; None on a chain of hinges and slides).
        The compiled engine computes the task's error and Jacobian from them
        (``qpik/_cpp/tasks/manipulability.hpp``, in the compiled step and in these methods
        alike). An unknown frame raises :class:`qpik.UnknownFrame`."""
        kind = self.frame_type
        fid = configuration.frame_id(self.frame_name, kind)
        return motion_chain(configuration.model, frame_body(configuration.model, fid, kind))

    def _value(self, configuration: Configuration) -> float:
        """``m(q)``, or 0 where the rows are of deficient rank to round-off (more rows than
        dofs, or a singular value at most :data:`RANK_FLOOR` of the largest: ``m`` is then
        round-off, and ``1 / m`` would be noise of any size). A mink configuration is read
        through qpik's view of it."""
        return self._engine_terms(as_configuration(configuration))[2]

    def compute_error(self, configuration: Configuration) -> np.ndarray:  # type: ignore[override]
        """``1 / m(q)`` (1,), 0 where ``m`` is 0 (see the class)."""
        return np.array([self._engine_terms(as_configuration(configuration))[0]])

    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:  # type: ignore[override]
        """``-(dm/dq) / m^2`` (1, nv), zero where ``m`` is 0 (see the class)."""
        return self._terms(configuration)[1]

    def compute_qp_residual(  # type: ignore[override]
        self, configuration: Configuration
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """mink's weighted residual of the error and Jacobian (:meth:`_terms`)."""
        return self._weighted_residual(*self._terms(configuration))

    def _terms(self, configuration: Configuration) -> tuple[np.ndarray, np.ndarray]:
        """``(e (1,), de/dq (1, nv))`` from one Jacobian and its decomposition, by the
        engine (:meth:`_engine_terms`)."""
        e, gradient, _ = self._engine_terms(as_configuration(configuration))
        return np.array([e]), gradient[None, :]

    def _engine_terms(self, configuration: Configuration) -> tuple[float, np.ndarray, float]:
        """``(e, de/dq (nv,), m)`` by the engine (``inverse_manipulability``): from the
        frame's Jacobian at the configuration's MjData (MuJoCo's ``mj_jacSite`` /
        ``mj_jacBody`` / ``mj_jacGeom``, as the compiled step reads it) and its chain
        (:meth:`chain`). Equal to NumPy's SVD with ``mj_jacDot``'s gradient
        (:func:`qpik.model.gradients.manipulability_parts`) to round-off."""
        model = configuration.model
        dofs, thresholds = self.chain(configuration)
        jac = configuration.frame_jacobian(self.frame_name, self.frame_type)
        if len(self._row_index) > model.nv:
            return 0.0, np.zeros(model.nv), 0.0  # (m is 0 for every q: more rows than dofs)
        rows = np.asarray(self._row_index, dtype=np.int64)
        e, gradient, value, _ = inverse_manipulability(jac, rows, dofs, thresholds)
        return e, gradient, value


#: :class:`ManipulabilityTask` is idle where its rows' smallest singular value is at most
#: this much of the largest (their rank deficient to round-off; the engine's kRankFloor,
#: ``qpik/_cpp/tasks/manipulability.hpp``).
RANK_FLOOR = 1e-9
