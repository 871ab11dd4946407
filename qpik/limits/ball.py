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
The rows are the faces of a polytope inscribed in that ball (all its vertices on the
sphere, so it lies inside the ball: the rows are exact for any step), with a vertex along
the current axis ``a = phi / theta``: by default the regular icosahedron (20 faces, 5 of
them at each vertex), or its geodesic subdivisions (``subdivisions=1``: 80 faces, ``2``:
320), scaled by ``rho`` and turned so that one vertex is ``rho a``. So

* the current rotation is inside (``dq = 0`` is always feasible);
* along the axis the joint may turn out to its range's edge in one step (the angle grows
  exactly as ``a^T dq`` there);
* at the edge, a step across the axis needs an inward component (the vertex's cone: a
  tangential move ``t`` needs ``t tan(alpha)`` inward, ``alpha`` = 37.4 degrees for the
  icosahedron, 54.7 for the cube of earlier versions), so the joint slides along its
  range by moving inward;
* the rows do not bind where ``|phi + dq|`` is below the polytope's inradius: 79 % of the
  range for the icosahedron (the cube: 58 %), 93 % with one subdivision; the polytope
  holds 61 % of the ball's volume (the cube 37 %), 87 % with one subdivision, 97 % with
  two.

Where ``2 rho > pi``, a box ``|dq_j| <= pi / sqrt(3)`` on the ball's dofs keeps the
comparison's condition ``|dq| <= pi``. A joint rotated past its range (a start outside)
takes its current angle as the bound: the angle does not grow.
"""

from __future__ import annotations

import functools
import math

import mink
import mujoco
import numpy as np
from mink import Constraint

from ..core.checks import type_name
from ..errors import InvalidArgumentType, LimitDefinitionError
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


def _cross(a: list[float], b: list[float]) -> list[float]:
    """``a x b`` of two 3-vectors, as ``np.cross`` computes it (the same products and
    differences: the same bits), without its cost on arrays of three."""
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _frame(phi: np.ndarray) -> tuple[float, np.ndarray]:
    """The angle ``|phi|`` and an orthonormal frame ``(a, e1, e2)`` (rows) with ``a`` along
    ``phi`` (any axis at the identity)."""
    theta = float(np.linalg.norm(phi))
    a = (phi / theta if theta > 1e-12 else np.array([0.0, 0.0, 1.0])).tolist()
    size = [abs(v) for v in a]
    helper = [0.0, 0.0, 0.0]
    helper[size.index(min(size))] = 1.0  # (np.argmin's: the first smallest)
    e1 = np.array(_cross(a, helper))
    e1 /= np.linalg.norm(e1)
    e1l = e1.tolist()
    return theta, np.array([a, e1l, _cross(a, e1l)])


@functools.lru_cache(maxsize=4)
def unit_polytope(subdivisions: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``(normals, offsets)`` of the faces ``normals @ x <= offsets`` of a polytope
    inscribed in the unit sphere with a vertex at ``(1, 0, 0)``: the regular icosahedron,
    each subdivision splitting every triangle into four (edge midpoints pushed out onto
    the sphere). Unit normals ``(k, 3)``, offsets ``(k,)`` (each face's distance from the
    centre), sorted (deterministic)."""
    from scipy.spatial import ConvexHull  # on first use

    ring = 2.0 * math.pi / 5.0 * np.arange(5)
    r, x = 2.0 / math.sqrt(5.0), 1.0 / math.sqrt(5.0)
    points = np.vstack(
        [
            [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]],
            np.column_stack([np.full(5, x), r * np.cos(ring), r * np.sin(ring)]),
            np.column_stack(
                [np.full(5, -x), r * np.cos(ring + math.pi / 5), r * np.sin(ring + math.pi / 5)]
            ),
        ]
    )
    for _ in range(subdivisions):
        hull = ConvexHull(points)
        midpoints = {}
        for simplex in hull.simplices:
            for i, j in ((0, 1), (1, 2), (0, 2)):
                edge = (min(simplex[i], simplex[j]), max(simplex[i], simplex[j]))
                mid = points[edge[0]] + points[edge[1]]
                midpoints[edge] = mid / np.linalg.norm(mid)
        points = np.vstack([points, *[midpoints[e] for e in sorted(midpoints)]])
    equations = ConvexHull(points).equations  # n . x + d <= 0, |n| = 1
    order = np.lexsort(np.round(equations.T[::-1], 12))
    equations = equations[order]
    return equations[:, :3].copy(), -equations[:, 3].copy()


def ball_rows(phi: np.ndarray, rho: float, subdivisions: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The rows ``(G, h)`` (``G`` is ``(k, 3)``: the polytope's faces, 6 more where
    ``2 rho > pi``) on one ball's step ``dq`` [rad] that keep its angle within ``rho``
    [rad] after ``R exp(dq)``, from its rotation vector ``phi`` (see the module's text)."""
    theta, frame = _frame(np.asarray(phi, dtype=float))
    rho = max(rho, theta)  # a start past the range: the angle does not grow
    normals, offsets = unit_polytope(subdivisions)
    faces = normals @ frame  # the polytope's vertex (1, 0, 0) turned onto a
    rows = [faces]
    along = faces @ phi
    bound = rho * offsets - along
    # A start on the range sits on a vertex of the polytope: the faces meeting there have
    # bound 0, its round-off (1e-16 rad) left below 0 made the start infeasible by that
    # much, which no level's answer then proved (numerical_failure, a zero step). Within
    # round-off of 0 they are 0.
    tight = (bound < 0.0) & (bound >= -1e-12 * (rho * np.abs(offsets) + np.abs(along)))
    bounds = [np.where(tight, 0.0, bound)]
    if 2.0 * rho > math.pi:
        rows += [np.eye(3), -np.eye(3)]
        bounds += [np.full(6, math.pi / math.sqrt(3.0))]
    return np.vstack(rows), np.concatenate(bounds)


class BallJointLimit(mink.Limit):
    """The model's limited ball joints stay within their range (MuJoCo's: the rotation
    angle at most ``range[1]``) for a step of any size, with the trust region off too.

    Rows ``G dq <= h`` [rad] on each ball's three dofs: the faces of a polytope inscribed
    in the ball ``|phi + dq| <= range`` (see :mod:`qpik.limits.ball`), the icosahedron (20
    rows per joint) or, with ``subdivisions`` 1 or 2, a geodesic one (80 or 320 rows,
    closer to the ball); :func:`qpik.limits.joint_limits` adds this limit whenever the
    model has a limited ball joint. Raises :class:`qpik.LimitDefinitionError` for a model
    without one, or a ``subdivisions`` other than 0, 1 or 2."""

    def __init__(self, model: mujoco.MjModel, subdivisions: int = 0) -> None:
        if not isinstance(model, mujoco.MjModel):
            raise LimitDefinitionError(
                f"BallJointLimit needs a mujoco.MjModel, got {type(model).__name__}"
            )
        if isinstance(subdivisions, (bool, np.bool_)) or not isinstance(
            subdivisions, (int, np.integer)
        ):
            raise InvalidArgumentType("subdivisions", "an int (0, 1 or 2)", type_name(subdivisions))
        if int(subdivisions) not in (0, 1, 2):
            raise LimitDefinitionError(
                f"BallJointLimit: subdivisions must be 0, 1 or 2, got {subdivisions!r}"
            )
        joints = limited_ball_joints(model)
        if not joints:
            raise LimitDefinitionError(
                "BallJointLimit: the model has no ball joint with a range below pi"
            )
        self.model = model
        self.subdivisions = int(subdivisions)
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
            rows, bounds = ball_rows(phi, rho, self.subdivisions)
            g = np.zeros((rows.shape[0], self.model.nv))
            g[:, dadr : dadr + 3] = rows
            blocks_g.append(g)
            blocks_h.append(bounds)
        return Constraint(G=np.vstack(blocks_g), h=np.concatenate(blocks_h))
