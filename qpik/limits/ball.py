r"""Ball-joint ranges that hold for a step of any size.

MuJoCo bounds a limited ball joint's rotation angle ``theta = |phi|`` (``phi`` the
rotation vector of its quaternion) by ``rho = range[1]``. mink's row on that angle is its
linearisation along the current axis: motion across the axis grows the angle at second
order, so without a velocity limit or trust region a large step leaves the range
(issue 22: 2.5 rad against a 1.047 rad range).

The rows here are exact for any step. A step ``dq`` of the ball's three dofs rotates the
joint to ``R exp(dq)`` (MuJoCo's integration, ``mj_integratePos``), whose angle is the
geodesic distance from ``exp(-phi)`` to ``exp(dq)``. SO(3) has non-negative curvature, so
(Toponogov's hinge comparison, both sides at most pi long)

.. math::

    \theta(R \exp(dq)) \;\le\; |\phi + dq| \qquad (|dq| \le \pi):

the range holds wherever ``z = phi + dq`` lies in the Euclidean ball of radius ``rho``.
The rows are a cube inscribed in that ball, centred on the identity, with a body diagonal
along the current axis ``a = phi / theta``: its faces ``|f_j^T z| <= rho / sqrt(3)``, with
``(f_1, f_2, f_3)`` the orthonormal frame whose diagonal ``(f_1 + f_2 + f_3) / sqrt(3)`` is
``a``. Its vertex ``rho a`` lies on the sphere, so

* the current rotation is inside (``dq = 0`` is always feasible);
* along the axis the joint may turn out to its range's edge in one step (the angle grows
  exactly as ``a^T dq`` there);
* at the edge, a step across the axis needs an inward component (the cube's corner
  cone), so the joint slides along its range by moving inward;
* the rows do not bind where ``|phi + dq| <= rho / sqrt(3)`` (the step ends within 58 %
  of the range).

Where ``2 rho > pi``, a box ``|dq_j| <= pi / sqrt(3)`` on the ball's dofs keeps the
comparison's condition ``|dq| <= pi``. A joint rotated past its range (a start outside)
takes its current angle as the bound: the angle does not grow.
"""

from __future__ import annotations

import math

import mink
import mujoco
import numpy as np
from mink import Constraint

from ..errors import LimitDefinitionError
from ..model.frames import check_model_type

__all__ = ["BallJointLimit", "limited_ball_joints"]


def limited_ball_joints(model: mujoco.MjModel) -> list[int]:
    """The ids of the ball joints whose range bounds their rotation (``range[1] < pi``)."""
    check_model_type("model", model)
    ball = int(mujoco.mjtJoint.mjJNT_BALL)
    return [
        j
        for j in range(model.njnt)
        if int(model.jnt_type[j]) == ball
        and model.jnt_limited[j]
        and 0.0 < float(model.jnt_range[j, 1]) < math.pi
    ]


def _frame(phi: np.ndarray) -> tuple[float, np.ndarray]:
    """The angle ``|phi|`` and an orthonormal frame ``(a, e1, e2)`` (rows) with ``a`` along
    ``phi`` (any axis at the identity)."""
    theta = float(np.linalg.norm(phi))
    a = phi / theta if theta > 1e-12 else np.array([0.0, 0.0, 1.0])
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    e1 = np.cross(a, helper)
    e1 /= np.linalg.norm(e1)
    return theta, np.vstack([a, e1, np.cross(a, e1)])


def ball_rows(phi: np.ndarray, rho: float) -> tuple[np.ndarray, np.ndarray]:
    """The rows ``(G, h)`` (``G`` is ``(6, 3)``, or ``(12, 3)`` where ``2 rho > pi``) on
    one ball's step ``dq`` [rad] that keep its angle within ``rho`` [rad] after
    ``R exp(dq)``, from its rotation vector ``phi`` (see the module's text)."""
    theta, (a, e1, e2) = _frame(np.asarray(phi, dtype=float))
    rho = max(rho, theta)  # a start past the range: the angle does not grow
    turns = 2.0 * math.pi / 3.0 * np.arange(3)
    faces = a / math.sqrt(3.0) + math.sqrt(2.0 / 3.0) * (
        np.cos(turns)[:, None] * e1 + np.sin(turns)[:, None] * e2
    )
    half = rho / math.sqrt(3.0)
    along = theta / math.sqrt(3.0)  # f_j^T phi, the same for the three faces
    rows = [faces, -faces]
    bounds = [np.full(3, half - along), np.full(3, half + along)]
    if 2.0 * rho > math.pi:
        rows += [np.eye(3), -np.eye(3)]
        bounds += [np.full(6, math.pi / math.sqrt(3.0))]
    return np.vstack(rows), np.concatenate(bounds)


class BallJointLimit(mink.Limit):
    """The model's limited ball joints stay within their range (MuJoCo's: the rotation
    angle at most ``range[1]``) for a step of any size, with the trust region off too.

    Rows ``G dq <= h`` [rad] on each ball's three dofs (see :mod:`qpik.limits.ball`);
    :func:`qpik.limits.joint_limits` adds this limit whenever the model has a limited ball
    joint. Raises :class:`qpik.LimitDefinitionError` for a model without one."""

    def __init__(self, model: mujoco.MjModel) -> None:
        if not isinstance(model, mujoco.MjModel):
            raise LimitDefinitionError(
                f"BallJointLimit needs a mujoco.MjModel, got {type(model).__name__}"
            )
        joints = limited_ball_joints(model)
        if not joints:
            raise LimitDefinitionError(
                "BallJointLimit: the model has no ball joint with a range below pi"
            )
        self.model = model
        self.joints = joints
        self._qposadr = [int(model.jnt_qposadr[j]) for j in joints]
        self._dofadr = [int(model.jnt_dofadr[j]) for j in joints]
        self._range = [float(model.jnt_range[j, 1]) for j in joints]

    def compute_qp_inequalities(self, configuration: mink.Configuration, dt: float) -> Constraint:
        """The rows on the displacement ``dq = v dt`` [rad] (``dt`` unused)."""
        del dt
        q = configuration.q
        blocks_g, blocks_h = [], []
        phi = np.empty(3)
        for qadr, dadr, rho in zip(self._qposadr, self._dofadr, self._range):
            quat = np.array(q[qadr : qadr + 4], dtype=float)
            quat /= np.linalg.norm(quat)
            mujoco.mju_quat2Vel(phi, quat, 1.0)
            rows, bounds = ball_rows(phi, rho)
            g = np.zeros((rows.shape[0], self.model.nv))
            g[:, dadr : dadr + 3] = rows
            blocks_g.append(g)
            blocks_h.append(bounds)
        return Constraint(G=np.vstack(blocks_g), h=np.concatenate(blocks_h))
