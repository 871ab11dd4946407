"""mink's limits whose rows the compiled step takes in parts (:func:`.layout.limit_layout`):
a view of each part (``VIEW``), named as the limit (:func:`.limit_inputs.limit_name` gives a
view its first base's name, so that the active limits are named as on the QP path). They read
mink 1.3's attributes of the limit; where one is missing, :func:`.layout.limit_layout`
leaves the limit to the QP path.

* :class:`BallJointRows`: a :class:`mink.ConfigurationLimit`'s ball-joint cone rows, general
  rows (its other dofs' bounds are the kernel's box entries).
* :class:`FreeJointAngular`: a :class:`mink.FreeJointVelocityLimit`'s angular bounds, one dof
  each: velocity-limit entries of the kernel's box (``|dq| <= dt angular_max``).
* :class:`FreeJointLinear`: its linear rows ``+-R^T v <= linear_max`` (``R`` the base's
  rotation), general rows, also where one bounds a single dof (an upright or yawed base's
  vertical row: the QP path folds it into the box; the same bound, the same optimum).
"""

from __future__ import annotations

import mink
import mujoco
import numpy as np

from .._engine import limits as _limits_engine
from ..model.configuration import dof_names

__all__ = ["BallJointRows", "FreeJointAngular", "FreeJointLinear", "angular_dofs"]


class BallJointRows(mink.ConfigurationLimit):
    """The rows of a :class:`mink.ConfigurationLimit` that bound its ball joints' rotation
    angles (``a^T dq <= gain (max_angle - angle)``, one a ball), for the compiled step's
    general rows; its other dofs' bounds are the kernel's box entries. mink's rows, bitwise
    (its arithmetic: ``mju_quat2Vel``, the angle its norm, the axis the vector over it, a zero
    row at the identity), with the gain read at each step; a row is named by its number in
    the limit's rows (after the ``2 len(indices)`` box rows), as the QP path names it.
    :meth:`compact_rows` gives the rows in play directly (:meth:`.boxes.LimitBoxes.general_rows`
    takes them); where the limit lacks mink 1.3's ball-joint attributes, the limit's own
    ``compute_qp_inequalities`` with its box rows emptied (``h = inf``) is read instead.
    Named as the limit (:func:`.limit_inputs.limit_name`: its first public base)."""

    VIEW = True

    def __init__(self, limit: mink.ConfigurationLimit):  # (not mink's: nothing to build)
        self.limit = limit
        self._phi = np.empty(3)
        boxed = 2 * len(limit.indices)  # (mink's upper then lower rows, ball rows after)
        self._boxed = boxed
        try:
            balls = zip(
                limit._ball_qposadr.tolist(),  # (mink 1.3's)
                limit._ball_dofadr.tolist(),
                limit._ball_max_angle.tolist(),
            )  # fmt: skip
            self._balls: list | None = list(balls)
        except AttributeError:
            self._balls = None
        self._names = [f"ConfigurationLimit row {boxed + i}" for i in range(len(self._balls or ()))]

    def compact_rows(self, configuration: mink.Configuration, dt: float):
        """``(G, h, names)`` of the ball rows in play (an empty row, at the identity, left
        out where it holds; a row on one dof kept), None where an empty row fails,
        NotImplemented without mink's attributes (the generic rows then)."""
        if self._balls is None:
            return NotImplemented
        q, phi, gain = configuration.q, self._phi, self.limit.gain
        rows, h, names = [], [], []
        for i, (padr, vadr, top) in enumerate(self._balls):
            mujoco.mju_quat2Vel(phi, q[padr : padr + 4], 1.0)
            angle = float(np.sqrt(phi.dot(phi)))  # (np.linalg.norm's arithmetic)
            if angle > 1e-9:
                # (a rotation about one coordinate axis gives a row on one dof: a general
                # row of the compiled step, as _multi_dof_rows keeps one; the QP path folds
                # it into the box, the same feasible set)
                axis = phi / angle
                rows.append((vadr, axis))
                h.append(gain * (top - angle))
                names.append(self._names[i])
            elif gain * (top - angle) < 0.0:  # (an empty row no displacement meets)
                return None
        G = np.zeros((len(rows), configuration.model.nv))
        for k, (vadr, axis) in enumerate(rows):
            G[k, vadr : vadr + 3] = axis
        return G, np.array(h, dtype=float), names

    def compute_qp_inequalities(self, configuration: mink.Configuration, dt: float):
        constraint = self.limit.compute_qp_inequalities(configuration, dt)
        G, h, boxed = constraint.G, constraint.h, self._boxed
        if boxed and G is not None and h is not None:
            G[:boxed] = 0.0
            h[:boxed] = np.inf
        return constraint


def angular_dofs(limit: mink.FreeJointVelocityLimit) -> np.ndarray:
    """The free joint's three angular dofs (after its three linear ones; mink 1.3's
    ``_lin_dofs``)."""
    return np.arange(3, 6) + int(limit._lin_dofs[0])


class FreeJointAngular(mink.FreeJointVelocityLimit, mink.VelocityLimit):
    """The angular part of a :class:`mink.FreeJointVelocityLimit` as a velocity limit of the
    kernel's box: ``indices`` the free joint's three angular dofs, ``limit`` its
    ``angular_max`` [rad/s] read at each step (mink's rows are ``+-dq_i <= dt max_i``, one
    dof each, which the QP path folds into the same box bounds). A velocity limit for
    :func:`.boxes.limit_values` (its speeds checked >= 0), named as the limit."""

    VIEW = True

    def __init__(self, limit: mink.FreeJointVelocityLimit):  # (not mink's: nothing to build)
        self.source = limit
        self.indices = angular_dofs(limit)

    @property
    def limit(self):
        return self.source.angular_max


#: The name the QP path gives the limit (its class's: .limit_inputs.limit_name).
_NAME = mink.FreeJointVelocityLimit.__name__


class FreeJointLinear(mink.FreeJointVelocityLimit):
    """The linear part of a :class:`mink.FreeJointVelocityLimit`: mink's rows ``R^T`` on the
    free joint's linear dofs, ``<= dt linear_max``, and their negation, bitwise (``R`` the
    base body's ``xmat``), numbered as in the limit's rows (the angular rows, where set, after
    each sign's linear ones); :meth:`compact_rows` for :meth:`.boxes.LimitBoxes.general_rows`."""

    VIEW = True

    def __init__(self, limit: mink.FreeJointVelocityLimit):  # (not mink's: nothing to build)
        self.source = limit
        #: the six rows' names where some bound one dof, by which and their signs
        self._one_dof: dict[tuple, list[str]] = {}
        per_side = 3 + (3 if limit.angular_max is not None else 0)
        self._names = [f"FreeJointVelocityLimit row {r}" for r in (0, 1, 2)] + [
            f"FreeJointVelocityLimit row {per_side + r}" for r in (0, 1, 2)
        ]

    def compact_rows(self, configuration: mink.Configuration, dt: float):
        """``(G, h, names)`` of the six linear rows, as general rows of the compiled step
        also where one bounds a single dof (a row of ``R^T`` with two zero entries: an
        upright or yawed base's vertical row, which the QP path folds into the box; the
        free joint's linear dofs have no box bound of their own, so the row is the only
        bound on that dof either way). Before, such a base sent every step to the QP path
        (a standing floating Talos: 3.5x mink's time a call)."""
        G, h = self._rows(configuration, dt)
        x = configuration.data.xmat[self.source.base_body_id].tolist()  # R, row-major
        # the rows of R^T on one dof (column i of R with one nonzero entry: an upright or
        # yawed base's vertical row), each with its entry's place and sign
        key = tuple(
            (i, k, x[3 * k + i] > 0.0)
            for i in range(3)
            for k in range(3)
            if x[3 * k + i] != 0.0 and (x[i] != 0.0) + (x[3 + i] != 0.0) + (x[6 + i] != 0.0) == 1
        )
        if not key:
            return G, h, self._names
        names = self._one_dof.get(key)
        if names is None:
            names = self._one_dof[key] = self._one_dof_names(configuration.model, G, key)
        return G, h, names

    def _one_dof_names(self, model: mujoco.MjModel, G: np.ndarray, key: tuple) -> list:
        """The six rows' names where the rows ``i`` of ``key`` (a row of ``R^T`` on one dof)
        and their negations ``i + 3`` are named as the QP path names the box bound it folds
        them into: ``"<joint> upper|lower (FreeJointVelocityLimit)"``."""
        names = list(self._names)
        for i, _k, _positive in key:
            for r in (i, i + 3):
                dof = int(np.flatnonzero(G[r])[0])
                joint = dof_names(model)[dof]  # (as .boxes names dofs)
                side = "upper" if G[r, dof] > 0.0 else "lower"
                names[r] = f"{joint} {side} ({_NAME})"
        return names

    def _rows(self, configuration: mink.Configuration, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """``(G, h)`` as mink computes them: ``R^T`` on the linear dofs, its negation below
        (every entry of the lower rows negated, zeros to -0), ``dt linear_max`` twice."""
        limit = self.source
        dofs = limit._lin_dofs
        if type(dofs) is np.ndarray and dofs.dtype.kind in "iu":
            try:  # (in the engine: the same operations, without NumPy's temporaries)
                return _limits_engine.free_joint_rows(
                    configuration.data.xmat[limit.base_body_id],
                    dofs.astype(np.int64, copy=False),
                    configuration.model.nv,
                    dt,
                    np.asarray(limit.linear_max, dtype=float),
                )
            except (TypeError, ValueError):  # (what it does not take: NumPy's way says why)
                pass
        G = np.zeros((6, configuration.model.nv))
        G[:3, limit._lin_dofs] = configuration.data.xmat[limit.base_body_id].reshape(3, 3).T
        np.negative(G[:3], out=G[3:])
        h = np.empty(6)
        np.multiply(dt, np.asarray(limit.linear_max, dtype=float), out=h[:3])
        h[3:] = h[:3]
        return G, h

    def compute_qp_inequalities(self, configuration: mink.Configuration, dt: float):
        """The six linear rows ``G dq <= h`` as mink computes them."""
        G, h = self._rows(configuration, dt)
        return mink.Constraint(G=G, h=h)
