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
from ..model.frames import FRAME_POSITIONS, FRAME_ROTATIONS, check_model_type, resolve_frame
from .collision import NEGLIGIBLE_ROW

__all__ = ["SupportPolygonLimit"]

_BAD_FOOTPRINTS = "footprints must hold one finite (k, 3) array of points [m] per contact frame"
_NO_AREA = (
    "the contact frames' footprints span no area (collinear or too few points): "
    "give a footprint, e.g. a sole's corners, or more contact frames"
)


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
        #: Each contact frame as ``(name, frame type, MuJoCo id)``.
        self.frames: list[tuple[str, FrameType, int]] = [
            resolve_frame(model, frame, argument="contact_frames") for frame in contact_frames
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
        kinds = {kind for _, kind, _ in self.frames}
        one = kinds.pop() if len(kinds) == 1 else None
        self._one_kind = None if one is None else (FRAME_POSITIONS[one], FRAME_ROTATIONS[one])
        self._ids = np.array([fid for _, _, fid in self.frames], dtype=np.intp)

    def _placements(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray, list]:
        """The contact frames' positions ``(F, 3)`` and rotations ``(F, 9)`` (local to
        world) in ``data``, and their footprints as the engine takes them."""
        frames = self.frames
        if self._one_kind is not None:  # (every frame a body, or every one a site, a geom)
            position, rotation = self._one_kind
            positions = getattr(data, position)[self._ids]
            rotations = getattr(data, rotation)[self._ids]
        else:
            positions, rotations = np.empty((len(frames), 3)), np.empty((len(frames), 9))
            for j, (_, kind, fid) in enumerate(frames):
                positions[j] = getattr(data, FRAME_POSITIONS[kind])[fid]
                rotations[j] = getattr(data, FRAME_ROTATIONS[kind])[fid]
        footprints = [
            f if type(f) is np.ndarray and f.dtype == np.float64 and f.flags.c_contiguous
            else np.ascontiguousarray(f, dtype=float)
            for f in self.footprints
        ]  # fmt: skip
        if len(footprints) != len(frames) or any(
            f.ndim != 2 or f.shape[1] != 3 for f in footprints
        ):
            raise LimitDefinitionError(_BAD_FOOTPRINTS)
        return positions, rotations, footprints

    def support_points(self, configuration: mink.Configuration) -> np.ndarray:
        """The footprints' points on the ground ``(n, 2)`` [m], world x-y: each frame's
        footprint point ``p`` at ``x + R p`` (the frame's position and rotation), frame by
        frame (by the engine: ``_engine.limits.support_points``)."""
        try:
            return _engine.support_points(*self._placements(configuration.data))
        except ValueError as exc:  # (a footprint's point not finite)
            raise LimitDefinitionError(f"{_BAD_FOOTPRINTS} ({exc})") from exc

    def hull(self, configuration: mink.Configuration) -> tuple[np.ndarray, np.ndarray]:
        """Edges of the support polygon, the hull of :meth:`support_points`: outward unit
        normals ``(e, 2)`` and offsets ``(e,)`` [m] (inside: ``normals @ p + offsets <= 0``),
        counter-clockwise from the lowest-x point. Raises :class:`~qpik.InvalidInput` where
        the points span no area."""
        normals, offsets = _engine.support_hull(self.support_points(configuration))
        if not len(offsets):
            raise InvalidInput(_NO_AREA)
        return normals, offsets

    def com(self, configuration: mink.Configuration) -> np.ndarray:
        """The CoM ``(3,)`` [m], world frame."""
        return configuration.data.subtree_com[self.body].copy()

    def com_margin(self, configuration: mink.Configuration) -> float:
        """Signed distance [m] from the CoM's ground projection to the polygon's boundary:
        positive inside (the smallest distance to an edge), negative outside."""
        normals, offsets = self.hull(configuration)
        return float(-(normals @ self.com(configuration)[:2] + offsets).max())

    def rows_in_play(
        self, configuration: mink.Configuration, dt: float
    ) -> tuple[np.ndarray, np.ndarray, int]:
        """``(G, h, fewest)``: :meth:`compute_qp_inequalities`' rows and the fewest nonzero
        entries of a row, in one engine call (``_engine.limits.support_rows``: the points,
        their hull and the rows ``a_e^T J_xy dq <= gain (-margin - o_e - a_e^T c_xy)``; a
        row of entries at most :data:`~qpik.limits.collision.NEGLIGIBLE_ROW` made zero)."""
        data = configuration.data
        mujoco.mj_jacSubtreeCom(configuration.model, data, self._jac, self.body)
        com = data.subtree_com[self.body]
        try:
            G, h, fewest = _engine.support_rows(
                *self._placements(data), self._jac, float(com[0]), float(com[1]),
                float(self.margin), float(self.gain), NEGLIGIBLE_ROW,
            )  # fmt: skip
        except ValueError as exc:  # (a footprint's point not finite)
            raise LimitDefinitionError(f"{_BAD_FOOTPRINTS} ({exc})") from exc
        if not len(h):
            raise InvalidInput(_NO_AREA)
        return G, h, fewest

    def compute_qp_inequalities(
        self, configuration: mink.Configuration, dt: float
    ) -> mink.Constraint:
        """``G dq <= h`` [m], one row per edge of the support polygon (``dt`` unused:
        both sides are displacements)."""
        G, h, _ = self.rows_in_play(configuration, dt)
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
