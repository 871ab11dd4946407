r"""Keep the centre of mass above the support polygon (static balance).

The support polygon is the convex hull of the contact
frames' footprints projected on the ground (the world x-y plane): each contact frame
carries footprint points fixed in its own axes, placed in the world at the current
configuration. By default they are the frame's own collision geometry
(:func:`qpik.limits.geometry.contact_footprint`: the corners of a foot's box, a mesh's
vertices, samples of capsules and spheres, on the frame's body and the bodies welded to
it); an explicit ``footprint``, points in each frame's x-y axes [m] (a sole's corners),
overrides it. The hull's edges are lines
``a_i^T p + o_i = 0`` with outward unit normals ``a_i``, so a
ground point ``p`` is inside with margin ``m`` when ``a_i^T p + o_i <= -m`` for every edge.
The hull is the compiled engine's monotone chain (``qpik._engine.limits.support_hull``;
about 1 us for a humanoid's two soles, where SciPy's Qhull takes about 90 us): its edges
run counter-clockwise from the lowest-x point, and a point that turns the chain by less
than 1e-10 (the sine of the angle: collinear, repeated, off the line by round-off) is no
vertex.

With ``c`` the CoM of the subtree of ``body`` (body 1 by default: the robot) and ``J_xy``
the first two rows of its Jacobian (``mj_jacSubtreeCom``), the limit's rows are, one per
edge, in displacement units [m]:

.. math::

    a_i^T J_{xy}\, dq \;\le\; \text{gain}\, (-m - o_i - a_i^T c_{xy})

so the CoM's ground projection approaches an edge by at most ``gain`` of the distance left
(it stays inside to first order, and a start outside moves back in). The hull is taken
as fixed during the step: hold the contact frames with a task of a higher (or the same)
priority, as a humanoid stack does with its feet.

The rows are general ``G dq <= h`` rows (they couple every joint that moves the CoM); they
hold at every priority level, like every limit of :class:`qpik.IKSolver`.
"""

from __future__ import annotations

from collections.abc import Sequence

import mink
import mujoco
import numpy as np
import numpy.typing as npt

from .._engine import limits as _engine
from ..core import checks
from ..errors import InvalidArgumentType, InvalidInput, LimitDefinitionError
from ..model.configuration import FrameType
from ..model.frames import check_model_type, resolve_frame

__all__ = ["SupportPolygonLimit"]


class SupportPolygonLimit(mink.Limit):
    """The CoM's ground projection stays inside the contacts' support polygon.

    Args:
        model: the MuJoCo model.
        contact_frames: the contact frames (feet, sole links): names, each a site, a body
            or a geom (looked up in that order), or ``(name, frame_type)``.
        margin: distance [m] kept between the CoM's projection and every hull edge.
        footprint: points ``(k, 2)`` [m] in each contact frame's own x-y axes (a sole's
            corners), the same for every frame; default (``None``): each frame's collision
            geometry (:func:`qpik.limits.geometry.contact_footprint`), or the frame's
            origin alone where its body carries no geometry or carries another contact
            frame too (point contacts, which need at least three frames that span an
            area).
        gain: fraction in (0, 1] of the distance to an edge that may be covered per step.
        body: subtree whose CoM is kept inside (name or id; default 1, the robot).
    """

    #: Its rows are recoverable: where they admit no step (the CoM farther outside the
    #: support than one step can bring back), IKSolver.step relaxes them by the least slack
    #: (qpik.diffik.recovery).
    relaxable_rows = True

    def __init__(
        self,
        model: mujoco.MjModel,
        contact_frames: Sequence[str | tuple[str, FrameType | str]],
        margin: float = 0.0,
        footprint: npt.ArrayLike | None = None,
        gain: float = 0.95,
        body: str | int = 1,
    ):
        check_model_type("model", model)
        for name, value in (("margin", margin), ("gain", gain)):
            if not checks.is_real(value):
                raise InvalidArgumentType(name, "a real number", checks.type_name(value))
        margin, gain = checks.check_real("margin", margin), checks.check_real("gain", gain)
        if footprint is not None:
            footprint = checks.check_array("footprint", footprint, "(k, 2) points [m]")
        if not isinstance(contact_frames, (list, tuple)) or not len(contact_frames):
            raise LimitDefinitionError(
                f"contact_frames must be a non-empty list of frame names, got {contact_frames!r}"
            )
        if not np.isfinite(margin) or margin < 0:
            raise LimitDefinitionError(f"margin must be a finite distance >= 0 [m], got {margin}")
        if not 0.0 < gain <= 1.0:
            raise LimitDefinitionError(f"gain must be in (0, 1], got {gain}")
        self.model = model
        self.margin = float(margin)
        self.gain = float(gain)
        self.frames = [
            tuple(resolve_frame(model, frame, argument="contact_frames"))
            for frame in contact_frames
        ]
        points = np.zeros((1, 2)) if footprint is None else np.asarray(footprint, dtype=float)
        if points.ndim != 2 or points.shape[1] != 2 or not np.all(np.isfinite(points)):
            raise LimitDefinitionError(
                f"footprint must be finite (k, 2) points [m], got {footprint!r}"
            )
        self.footprint = np.column_stack([points, np.zeros(len(points))])  # z = 0 in the frame
        #: Each frame's footprint points ``(k_i, 3)`` [m] in its own axes.
        self.footprints = (
            [self.footprint] * len(self.frames)
            if footprint is not None
            else _geometry_footprints(model, self.frames)
        )
        if isinstance(body, str):
            self.body = resolve_frame(model, body, FrameType.BODY, argument="body").id
        else:
            self.body = checks.check_index("body", body, model.nbody)
        self._jac = np.empty((3, model.nv))

    def support_points(self, configuration: mink.Configuration) -> np.ndarray:
        """The footprints' points on the ground ``(n, 2)`` [m], world x-y."""
        data = configuration.data
        points = []
        for (_, kind, fid), footprint in zip(self.frames, self.footprints, strict=True):
            if kind is FrameType.SITE:
                position, rotation = data.site_xpos[fid], data.site_xmat[fid]
            elif kind is FrameType.BODY:
                position, rotation = data.xpos[fid], data.xmat[fid]
            else:
                position, rotation = data.geom_xpos[fid], data.geom_xmat[fid]
            world = position + footprint @ rotation.reshape(3, 3).T
            points.append(world[:, :2])
        return np.vstack(points)

    def hull(self, configuration: mink.Configuration) -> tuple[np.ndarray, np.ndarray]:
        """Edges of the support polygon: outward unit normals ``(e, 2)`` and offsets
        ``(e,)`` (inside: ``normals @ p + offsets <= 0``)."""
        normals, offsets = _engine.support_hull(self.support_points(configuration))
        if not len(offsets):
            raise InvalidInput(
                "the contact frames' footprints span no area (collinear or too few points): "
                "give a footprint, e.g. a sole's corners, or more contact frames"
            )
        return normals, offsets

    def com(self, configuration: mink.Configuration) -> np.ndarray:
        """The CoM ``(3,)`` [m], world frame."""
        return configuration.data.subtree_com[self.body].copy()

    def com_margin(self, configuration: mink.Configuration) -> float:
        """Signed distance [m] from the CoM's ground projection to the polygon's boundary:
        positive inside (the smallest distance to an edge), negative outside."""
        normals, offsets = self.hull(configuration)
        return float(-(normals @ self.com(configuration)[:2] + offsets).max())

    def compute_qp_inequalities(
        self, configuration: mink.Configuration, dt: float
    ) -> mink.Constraint:
        """``G dq <= h`` [m], one row per edge of the support polygon (``dt`` unused:
        both sides are displacements)."""
        normals, offsets = self.hull(configuration)
        mujoco.mj_jacSubtreeCom(configuration.model, configuration.data, self._jac, self.body)
        com_xy = configuration.data.subtree_com[self.body, :2]
        G = normals @ self._jac[:2]
        h = self.gain * (-self.margin - offsets - normals @ com_xy)
        return mink.Constraint(G=G, h=h)


def _geometry_footprints(model: mujoco.MjModel, frames: list) -> list[np.ndarray]:
    """Each frame's footprint from its collision geometry, reduced to the vertices of its
    convex hull; the frame's origin alone where its body has no geometry, or where another
    contact frame is on the same rigid body (point feet marked by sites on one body)."""
    from .geometry import contact_footprint  # geometry imports collision, not support

    def weld(kind: FrameType, fid: int) -> int:
        if kind is FrameType.SITE:
            return int(model.body_weldid[model.site_bodyid[fid]])
        if kind is FrameType.GEOM:
            return int(model.body_weldid[model.geom_bodyid[fid]])
        return int(model.body_weldid[fid])

    welds = [weld(kind, fid) for _, kind, fid in frames]
    out = []
    for (_, kind, fid), body in zip(frames, welds, strict=True):
        if kind is not FrameType.GEOM and welds.count(body) > 1:
            out.append(np.zeros((1, 3)))
            continue
        try:
            points = contact_footprint(model, kind, fid)
        except LimitDefinitionError:
            points = np.zeros((1, 3))
        if len(points) > 8:
            from scipy.spatial import ConvexHull, QhullError  # noqa: PLC0415 (0.17 s; import qpik stays light)

            try:
                points = points[ConvexHull(points).vertices]
            except (QhullError, ValueError):  # flat: keep every point
                pass
        out.append(points)
    return out
