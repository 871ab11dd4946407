r"""Reachability maps: per voxel of a box, the fraction of a set of orientations that IK
reaches, as robot base-placement and capability-map tools compute them (reuleaux, ...).

For a grid of voxel centres :math:`c_v` (world frame, [m]) and rotations :math:`R_k`, each
pose :math:`(c_v, R_k)` is a :func:`qpik.solve` target for one frame; the map stores which
converged and, per voxel, the fraction :math:`\frac{1}{K}\sum_k \text{reached}(v, k)`
(reuleaux's reachability index divided by 100). The solves run through
:func:`qpik.solve_many`'s machinery: a process pool on every core or a Ray cluster, seeded
per pose (the map does not depend on workers or backend).

Voxels that no configuration can reach are skipped without IK: every joint of the chain
from the world to the frame is a hinge, a ball or a bounded slide, so the frame stays
within :func:`reach_bound` of the chain's first joint anchor (the sum of the fixed
distances between consecutive joint anchors, plus the slides' travel); a voxel centre
farther than that is out of reach for every orientation.

With collision limits among the solve options' ``limits`` (say
``limits=[ConfigurationLimit(model), model_collision_limit(model)]``), a pose counts as
reached only when its answer keeps every checked pair at least ``d_min - tol_position``
apart (:func:`qpik.solve`'s rule), so poses that only a configuration in collision reaches
are left out; the map records it (:attr:`ReachabilityMap.collision_pairs`,
:attr:`ReachabilityMap.collisions_checked`) and its summary says so.
"""

from __future__ import annotations

import json
import math
import os
import textwrap
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
import numpy.typing as npt

from ..core import checks
from ..errors import InvalidArgumentType, InvalidInput, InvalidOption
from ..igm.prepared import PREPARED
from ..igm.qp_engine import check_limits_model
from ..igm.targets import FrameKey, RobotLike, parse_target
from ..limits import checked_pairs, collision_limits
from ..model.configuration import FrameType
from ..model.frames import resolve_frame
from ..options import SolveOptions
from .map_file import MAP_ARRAYS, read_map_file
from .pool import Batch, BatchKeywords, prepare_robot, stream_chunks

if TYPE_CHECKING:
    from matplotlib.figure import Figure
    from typing_extensions import Unpack

__all__ = [
    "ReachabilityMap",
    "map_path",
    "plot_reachability",
    "reach_bound",
    "reachability",
    "so3_grid",
]

#: The most orientations per voxel a map takes (a count beyond is a typo, and its memory
#: would run out).
MAX_ORIENTATIONS = 100_000
#: The most IK solves a map takes, voxels times orientations (a flag each: 1 GB; hours of
#: solves on a few cores); each within its own cap, their product can still be 8e11.
MAX_SOLVES = 1_000_000_000


def so3_grid(count: int) -> np.ndarray:
    """``count`` rotation matrices ``(count, 3, 3)`` spread evenly over SO(3): the
    Super-Fibonacci spiral (Alexa, CVPR 2022), deterministic, with low discrepancy for
    every ``count`` (not only the sizes of a regular grid)."""
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise InvalidInput(f"orientations must be a positive count or (K, 3, 3), got {count!r}")
    if count > MAX_ORIENTATIONS:
        raise InvalidInput(
            f"orientations must be at most {MAX_ORIENTATIONS} per voxel, got {count}"
        )
    from scipy.spatial.transform import Rotation

    phi = math.sqrt(2.0)
    psi = 1.533751168755204288118041
    s = np.arange(count) + 0.5
    r = np.sqrt(s / count)
    big_r = np.sqrt(1.0 - s / count)
    alpha = 2.0 * np.pi * s / phi
    beta = 2.0 * np.pi * s / psi
    quaternions = np.stack(
        [r * np.sin(alpha), r * np.cos(alpha), big_r * np.sin(beta), big_r * np.cos(beta)],
        axis=1,
    )
    return Rotation.from_quat(quaternions).as_matrix()


def _frame_of(model: mujoco.MjModel, frame: FrameKey) -> tuple[FrameType, int, int]:
    """``(kind, frame id, body id)`` of a frame key (a name: site, body then geom)."""
    _name, kind, index = resolve_frame(model, frame, argument="frame")
    body = {
        FrameType.SITE: lambda: model.site_bodyid[index],
        FrameType.BODY: lambda: index,
        FrameType.GEOM: lambda: model.geom_bodyid[index],
    }[kind]()
    return kind, index, int(body)


def reach_bound(robot: RobotLike, frame: FrameKey) -> tuple[np.ndarray, float]:
    """``(center, radius)``: for every configuration, the frame's origin lies within
    ``radius`` [m] of ``center`` (world frame).

    ``center`` is the anchor of the first joint on the chain from the world to the frame
    (fixed, as no joint moves it); ``radius`` sums the distances between consecutive joint
    anchors and from the last one to the frame, which hinge and ball joints leave
    unchanged, plus each slide joint's largest travel from ``qpos0``. A chain with a free
    joint or an unbounded slide has no bound (``inf``). Computed at ``qpos0``.
    """
    _spec, model, _q0 = prepare_robot(robot)
    kind, index, body = _frame_of(model, frame)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    point = {
        FrameType.SITE: data.site_xpos,
        FrameType.BODY: data.xpos,
        FrameType.GEOM: data.geom_xpos,
    }[kind][index].copy()
    chain: list[int] = []
    while body > 0:
        start, count = model.body_jntadr[body], model.body_jntnum[body]
        chain[:0] = range(start, start + count)
        body = model.body_parentid[body]
    if not chain:
        return point, 0.0
    radius = 0.0
    for joint in chain:
        kind_j = model.jnt_type[joint]
        if kind_j == mujoco.mjtJoint.mjJNT_FREE:
            return data.xanchor[chain[0]].copy(), math.inf
        if kind_j == mujoco.mjtJoint.mjJNT_SLIDE:
            if not model.jnt_limited[joint]:
                return data.xanchor[chain[0]].copy(), math.inf
            lower, upper = model.jnt_range[joint]
            q0 = model.qpos0[model.jnt_qposadr[joint]]
            radius += max(abs(upper - q0), abs(q0 - lower))
    points = np.vstack([data.xanchor[chain], point])
    radius += float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
    return data.xanchor[chain[0]].copy(), radius


def _reach_bounds(model: mujoco.MjModel, frame: FrameKey) -> list[tuple[np.ndarray, float]]:
    """Balls that each hold every position of the frame: :func:`reach_bound`, and the
    IK engine's (:meth:`qpik.model.KinematicChain.reach_bound`, through the common
    perpendiculars of consecutive axes) where the frame's own chain is supported, the
    per-frame check :func:`qpik.solve` makes (joints off the chain, a free object among
    them, do not count). Each is a proof on its own, so a voxel outside either is out of
    reach; neither is always the tighter."""
    bounds = [reach_bound(model, frame)]
    engine = PREPARED.get(model).frame(model, frame).reach
    if engine is not None:
        bounds.append((np.asarray(engine.center, dtype=float), float(engine.radius)))
    return bounds


def _real_array(name: str, value: Any, expected: str) -> np.ndarray:
    """:func:`qpik.core.checks.check_array`, real numbers only: complex numbers (whose
    imaginary part a float cast drops), strings or booleans raise
    :class:`qpik.InvalidArgumentType` naming ``name``."""
    try:
        dtype = np.asarray(value).dtype
    except (TypeError, ValueError):  # ragged: check_array says so
        dtype = np.dtype(object)
    if dtype.kind in "cbUSV":
        raise InvalidArgumentType(name, f"{expected} of real numbers", f"{dtype.name} values")
    return checks.check_array(name, value, expected)


def _grid(region: npt.ArrayLike, resolution: float) -> tuple[np.ndarray, tuple[int, int, int]]:
    """Voxel centres ``(V, 3)`` (C order over the (x, y, z) indices) and the grid shape:
    voxels of edge ``resolution`` [m], as many as fit in the region along each axis (at
    least one), the grid centred in the region."""
    region = _real_array("region", region, "a (2, 3) array of opposite corners [m]")
    if region.shape != (2, 3) or not np.isfinite(region).all():
        got = f"shape {region.shape}" if region.shape != (2, 3) else f"{region.tolist()}"
        raise InvalidInput(
            f"region must be a finite (2, 3) array of opposite corners [m], got {got}"
        )
    if (
        isinstance(resolution, bool)
        or not isinstance(resolution, (int, float, np.floating, np.integer))
        or not math.isfinite(resolution)
        or resolution <= 0
    ):
        raise InvalidInput(f"resolution must be a positive voxel size [m], got {resolution!r}")
    lower, upper = region.min(axis=0), region.max(axis=0)
    extent = upper - lower
    per_axis = np.maximum(1.0, np.floor(extent / resolution + 1e-9))
    voxels = float(np.prod(per_axis))  # in floats: an int product overflows for tiny voxels
    if not voxels <= 10_000_000:
        raise InvalidInput(
            f"region / resolution gives {voxels:.3g} voxels (more than 10 million): "
            "use a coarser resolution"
        )
    counts = per_axis.astype(int)
    middle = (lower + upper) / 2.0
    axes = [
        middle[i] + (np.arange(counts[i]) - (counts[i] - 1) / 2.0) * resolution for i in range(3)
    ]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return grid, (int(counts[0]), int(counts[1]), int(counts[2]))


#: The fields of a :class:`ReachabilityMap` saved in the JSON ``meta`` entry of its
#: ``.npz`` (besides ``solve_options``, saved as the ``repr`` of each value); its arrays
#: are :data:`qpik.batch.map_file.MAP_ARRAYS`, and :mod:`qpik.batch.map_file` reads both.
_MAP_META = (
    "shape",
    "resolution",
    "frame",
    "robot",
    "reach",
    "seed",
    "elapsed",
    "engines",
    "collision_pairs",
    "collision_distance",
)


@dataclass
class ReachabilityMap:
    """A reachability map (see :func:`reachability`).

    Attributes:
        centers: voxel centres ``(V, 3)`` [m], world frame, in C order over the grid's
            ``(x, y, z)`` indices (``fraction.reshape(shape)`` is the grid).
        fraction: per voxel, the fraction of the orientations reached, in [0, 1].
        reached: ``(V, K)``: whether IK reached voxel ``v`` with orientation ``k``
            (``(V, 1)`` for a position-only map).
        skipped: ``(V,)``: voxels beyond :func:`reach_bound`, given 0 without IK.
        orientations: the rotations ``(K, 3, 3)`` (world frame; none for a position-only
            map).
        shape: the grid's ``(nx, ny, nz)``.
        resolution: voxel edge [m].
        region: the box asked for, ``(2, 3)`` [m].
        frame: the frame; robot: what the robot was given as (name or path).
        base, reach: the :func:`reach_bound` sphere (centre [m], radius [m]).
        seed: the batch seed; elapsed: wall time [s]; solve_options: the IK options
            given: the solve keywords, and ``options`` (a preset's name or a
            :class:`qpik.SolveOptions`) when given.
        engines: the IK solves per engine (``{"compiled": 480}``: :attr:`qpik.IKResult.engine`).
        collision_pairs: the geom pairs (names) that the solves' collision limits checked:
            a pose reached only in collision (a pair closer than ``d_min -
            tol_position``) counts as not reached; empty when the solves had no collision
            limit (collisions not checked).
        collision_distance: the smallest ``d_min`` [m] of those limits (None without).
    """

    centers: np.ndarray
    fraction: np.ndarray
    reached: np.ndarray
    skipped: np.ndarray
    orientations: np.ndarray
    shape: tuple[int, int, int]
    resolution: float
    region: np.ndarray
    frame: str
    robot: str
    base: np.ndarray
    reach: float
    seed: int = 0
    elapsed: float = 0.0
    engines: dict[str, int] = field(default_factory=dict)
    solve_options: dict[str, Any] = field(default_factory=dict)
    collision_pairs: list[tuple[str, str]] = field(default_factory=list)
    collision_distance: float | None = None

    @property
    def collisions_checked(self) -> bool:
        """Whether the solves checked collisions (poses reached only in collision
        excluded)."""
        return bool(self.collision_pairs)

    @property
    def grid(self) -> np.ndarray:
        """``fraction`` as an ``(nx, ny, nz)`` array."""
        return self.fraction.reshape(self.shape)

    @property
    def solves(self) -> int:
        """IK solves run (voxels not skipped times orientations)."""
        return int((~self.skipped).sum()) * self.reached.shape[1]

    def summary(self) -> str:
        """A few lines: grid, reached voxels, time."""
        reachable = int((self.fraction > 0).sum())
        return (
            f"reachability of {self.frame!r} on {self.robot}: {len(self.fraction)} voxels "
            f"{self.shape} of {self.resolution:g} m, {_orientation_text(self)}\n"
            f"{reachable} voxels reached with at least one orientation, "
            f"{int((self.fraction == 1).sum())} with all; mean fraction "
            f"{self.fraction.mean():.3f}\n"
            f"{int(self.skipped.sum())} voxels beyond the reach bound "
            f"({self.reach:.3f} m from {np.round(self.base, 3).tolist()}) skipped; "
            f"{self.solves} IK solves in {self.elapsed:.1f} s\n{_collision_text(self)}"
        )

    def save(self, path: str | os.PathLike) -> str:
        """Save as ``.npz`` (arrays, plus a JSON ``meta`` entry for the rest) at
        :func:`map_path` of ``path``: ``.npz`` is appended to a path without it, as
        :func:`numpy.savez` does (``save("m")`` writes ``m.npz``, which ``load("m")``
        reads). Returns the path written."""
        path = map_path(path)
        meta: dict[str, Any] = {name: getattr(self, name) for name in _MAP_META}
        meta["shape"] = list(self.shape)
        meta["solve_options"] = {k: repr(v) for k, v in self.solve_options.items()}
        arrays = {name: getattr(self, name) for name in MAP_ARRAYS}
        np.savez(path, **arrays, meta=np.array(json.dumps(meta)))
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> ReachabilityMap:
        """Read a map written by :meth:`save`: the file ``path``, or where there is none,
        ``path + ".npz"`` (what ``save(path)`` wrote, :func:`map_path`). The file is
        checked: a missing or unreadable file, a file that is not such a map, a field
        missing or of the wrong type, shape or range (``fraction`` in [0, 1] and equal to
        ``reached``'s mean, finite ``centers`` ``(V, 3)`` on the grid of ``shape`` and
        ``resolution``, ...) raise :class:`qpik.ProblemFileError` naming the file and the
        field."""
        path = checks.check_path("path", path)
        if not os.path.exists(path) and os.path.exists(map_path(path)):
            path = map_path(path)
        return cls(**read_map_file(path))

    def plot(self, path: str | os.PathLike | None = None, slices: int = 4) -> Figure:
        """See :func:`plot_reachability`."""
        return plot_reachability(self, path, slices=slices)


def map_path(path: str | os.PathLike) -> str:
    """The file :meth:`ReachabilityMap.save` writes for ``path``: ``path`` when it ends
    in ``.npz``, else ``path + ".npz"`` (:func:`numpy.savez`'s rule)."""
    path = checks.check_path("path", path)
    return path if path.endswith(".npz") else path + ".npz"


def _collision_text(rmap: ReachabilityMap) -> str:
    if not rmap.collisions_checked:
        return "collisions not checked (no collision limit): poses in collision may count"
    pairs = rmap.collision_pairs
    shown = ", ".join(f"{a}-{b}" for a, b in pairs[:4]) + (", ..." if len(pairs) > 4 else "")
    return (
        f"collisions checked: {len(pairs)} geom pair(s) kept {rmap.collision_distance:g} m "
        f"apart ({shown}); poses reached only in collision excluded"
    )


def _orientation_text(rmap: ReachabilityMap) -> str:
    count = len(rmap.orientations)
    return f"{count} orientations" if count else "positions only"


def _rotations(orientations: int | npt.ArrayLike) -> np.ndarray:
    """The map's target rotations ``(K, 3, 3)``: none for ``0``, :func:`so3_grid` for a
    count, or the given matrices, checked."""
    if isinstance(orientations, (int, np.integer)) and orientations == 0:
        return np.zeros((0, 3, 3))  # position only
    if isinstance(orientations, (int, np.integer)) and not isinstance(orientations, bool):
        return so3_grid(int(orientations))
    rotations = _real_array("orientations", orientations, "a count or a (K, 3, 3) array")
    if rotations.ndim != 3 or rotations.shape[1:] != (3, 3) or len(rotations) == 0:
        raise InvalidInput(
            f"orientations must be a count or a (K, 3, 3) array, got shape {rotations.shape}"
        )
    for k, rotation in enumerate(rotations):
        try:
            parse_target((np.zeros(3), rotation))
        except Exception as exc:
            raise InvalidInput(f"orientations[{k}]: {exc}") from None
    return rotations


def reachability(
    robot: RobotLike,
    frame: FrameKey,
    *,
    region: npt.ArrayLike,
    resolution: float,
    orientations: int | npt.ArrayLike,
    options: SolveOptions | str | None = None,
    **keywords: Unpack[BatchKeywords],
) -> ReachabilityMap:
    """Compute a reachability map of ``frame``.

    Args:
        robot: a name, a path, an ``MjModel`` or a :class:`qpik.Configuration` (its ``q``
            is the IK start).
        frame: a site, body or geom name (or ``(name, frame_type)``).
        region: ``(2, 3)`` opposite corners of the box to map [m], world frame.
        resolution: voxel edge [m]; the grid is centred in the region (at most 10
            million voxels).
        orientations: a count ``K`` (spread evenly over SO(3), :func:`so3_grid`) or
            ``(K, 3, 3)`` rotation matrices (world frame); ``0``: positions only (one
            target per voxel, no orientation: ``fraction`` is 0 or 1). At most
            :data:`MAX_ORIENTATIONS`, and voxels times orientations at most
            :data:`MAX_SOLVES` (else :class:`qpik.InvalidInput`, before any solve).
        options: the :class:`qpik.SolveOptions` (or a preset name) of every solve.
        **keywords: as for :func:`qpik.solve_many`: how the batch runs (``workers``,
            ``backend``, ``address``, ``seed``, ``progress``, ...), and the keywords of
            every :func:`qpik.solve` (tolerances, ``restarts``, ``time_budget``, ...: they
            trade the map's accuracy for its time).

    Returns:
        a :class:`ReachabilityMap`; ``.fraction`` has one value per voxel, ``.centers``
        the voxel centres.
    """
    start_time = time.perf_counter()
    batch = Batch.prepare(robot, options, keywords, ("histories",))
    check_limits_model(batch.model, batch.options.limits)
    centers, shape = _grid(region, resolution)
    rotations = _rotations(orientations)
    solves = float(len(centers)) * max(1, len(rotations))
    if not solves <= MAX_SOLVES:
        raise InvalidInput(
            f"region / resolution gives {len(centers)} voxels and orientations "
            f"{max(1, len(rotations))} per voxel: {solves:.3g} IK solves (more than "
            f"{MAX_SOLVES:.0e}); use a coarser resolution or fewer orientations"
        )
    margin = batch.options.tol_position  # [m]: a voxel this close to the bound may converge
    skipped = np.zeros(len(centers), dtype=bool)
    bounds = _reach_bounds(batch.model, frame)
    for center, radius in bounds:
        skipped |= np.linalg.norm(centers - center, axis=1) > radius + margin
    base, reach = min(bounds, key=lambda bound: bound[1])
    candidates = np.flatnonzero(~skipped)
    k = max(1, len(rotations))

    def targets_at(start: int, stop: int) -> list[dict]:
        if len(rotations) == 0:
            return [{frame: centers[candidates[i]]} for i in range(start, stop)]
        return [
            {frame: (centers[candidates[i // k]], rotations[i % k])} for i in range(start, stop)
        ]

    flags = np.zeros(len(candidates) * k, dtype=bool)
    engines: dict[str, int] = {}
    for start, results in stream_chunks(batch, len(flags), targets_at):
        flags[start : start + len(results)] = [r.converged for r in results]
        for result in results:
            engine = str(getattr(result, "engine", None))
            engines[engine] = engines.get(engine, 0) + 1
    reached = np.zeros((len(centers), k), dtype=bool)
    reached[candidates] = flags.reshape(len(candidates), k)
    spec = batch.setup.spec
    collisions = collision_limits(batch.options.limits)
    return ReachabilityMap(
        centers=centers,
        fraction=reached.mean(axis=1),
        reached=reached,
        skipped=skipped,
        orientations=rotations,
        shape=shape,
        resolution=float(resolution),
        region=np.asarray(region, dtype=float),
        frame=frame if isinstance(frame, str) else str(frame[0]),
        robot=spec if isinstance(spec, str) else f"MjModel(nq={batch.model.nq})",
        base=base,
        reach=reach,
        seed=batch.setup.entropy,
        elapsed=time.perf_counter() - start_time,
        engines=engines,
        solve_options=_recorded_options(options, batch.keywords),
        collision_pairs=checked_pairs(collisions),
        collision_distance=min(
            (float(c.minimum_distance_from_collisions) for c in collisions), default=None
        ),
    )


def _recorded_options(
    options: SolveOptions | str | None, keywords: Mapping[str, Any]
) -> dict[str, Any]:
    """The solve options a map records: the keywords given and, when given, ``options``
    (a preset's name, or the :class:`qpik.SolveOptions`: its ``repr`` names every
    field)."""
    recorded = dict(keywords)
    if options is not None:
        recorded["options"] = options
    return recorded


def _check_slices(slices: Any) -> int:
    """``slices`` as an int >= 0 (0: the 3D scatter alone); else
    :class:`qpik.InvalidArgumentType` or :class:`qpik.InvalidOption`."""
    expected = "an int >= 0 (the number of z slices; 0: none)"
    if isinstance(slices, (bool, np.bool_)) or not isinstance(slices, (int, np.integer)):
        raise InvalidArgumentType("slices", expected, checks.type_name(slices))
    if slices < 0:
        raise InvalidOption("slices", slices, expected)
    return int(slices)


def plot_reachability(
    rmap: ReachabilityMap, path: str | os.PathLike | None = None, *, slices: int = 4, dpi: int = 90
) -> Figure:
    """A figure of a map: ``slices`` horizontal slices (constant z, x right, y up, colour
    = fraction reached) and a 3D scatter of the voxels reached at least once, coloured
    the same way, cut at the reach-bound centre's y to show the inside. Saved to ``path``
    when given (bare ``Figure``, Agg canvas: pyplot's state untouched, ``dpi`` in
    [1, 2400]); needs matplotlib (``qpik[plots]``). ``slices`` is an int >= 0 (0: the 3D
    scatter alone; at most one slice per voxel layer is drawn)."""
    from ..plots import check_figure_path, pyplot, require_matplotlib

    require_matplotlib()
    slices = _check_slices(slices)
    checks.check_real("dpi", dpi, 1.0, 2400.0)
    if path is not None:
        path = check_figure_path("path", path)
    grid = rmap.grid
    nx, ny, nz = rmap.shape
    # Slices spread over the heights where something is reached (else over the whole box).
    occupied = np.flatnonzero(grid.max(axis=(0, 1)) > 0)
    low, high = (occupied[0], occupied[-1]) if occupied.size else (0, nz - 1)
    count = min(slices, high - low + 1)
    # (one slice: the middle layer, not the lowest: linspace(low, high, 1) is [low])
    spread = [(low + high) / 2] if count == 1 else np.linspace(low, high, count)
    levels = np.unique(np.round(spread).astype(int))
    panels = len(levels)
    figsize = (3.2 * panels + 5.0, 4.4)
    if path is not None:
        from matplotlib.figure import Figure

        fig = Figure(figsize=figsize)
    else:
        fig = pyplot().figure(figsize=figsize)
    # (no slice: the colourbar right of the 3D view, whose x ticks it would cover on its left)
    ratios = [1.0] * panels + [0.08, 1.9] if panels else [1.9, 0.08]
    spec = fig.add_gridspec(1, panels + 2, width_ratios=ratios, wspace=0.2 if panels else 0.35)
    bar_column, view_column = (panels, panels + 1) if panels else (1, 0)
    centers = rmap.centers.reshape(nx, ny, nz, 3)
    half = rmap.resolution / 2.0
    extent = (
        centers[0, 0, 0, 0] - half,
        centers[-1, 0, 0, 0] + half,
        centers[0, 0, 0, 1] - half,
        centers[0, -1, 0, 1] + half,
    )
    image = None
    for column, level in enumerate(levels):
        ax = fig.add_subplot(spec[0, column])
        image = ax.imshow(
            grid[:, :, level].T,
            origin="lower",
            extent=extent,
            vmin=0.0,
            vmax=1.0,
            cmap="viridis",
            interpolation="nearest",
        )
        ax.plot(rmap.base[0], rmap.base[1], "r+", markersize=8)
        ax.set_title(f"z = {centers[0, 0, level, 2]:.3f} m", fontsize="small")
        ax.set_xlabel("x [m]")
        if column == 0:
            ax.set_ylabel("y [m]")
        else:  # (the same y extent as the first slice: its labels would run into that one)
            ax.tick_params(labelleft=False)
        ax.set_aspect("equal")
    colorbar_ax = fig.add_subplot(spec[0, bar_column])
    # image is None only for slices=0 (no panel): matplotlib then draws a plain colorbar
    fig.colorbar(image, cax=colorbar_ax, label="fraction of orientations reached")  # type: ignore[arg-type]
    ax3 = fig.add_subplot(spec[0, view_column], projection="3d")
    # The far half only (the voxels that reach y >= the base's y: centres at y >= base - half
    # a voxel), so the cut shows the inside of the workspace.
    cut = rmap.centers[:, 1] >= rmap.base[1] - half
    if not cut.any():
        cut[:] = True
    shown = (rmap.fraction > 0) & cut
    points = rmap.centers[shown]
    ax3.scatter(
        points[:, 0],
        points[:, 1],
        points[:, 2],
        c=rmap.fraction[shown],
        cmap="viridis",
        vmin=0.0,
        vmax=1.0,
        s=float(np.clip(4000.0 / max(1, len(rmap.fraction)) ** (2.0 / 3.0), 2.0, 40.0)),
        alpha=0.85,
        depthshade=False,
    )
    ax3.scatter(*rmap.base, color="red", marker="+", s=60)
    half_voxel = rmap.resolution / 2.0
    lower = np.minimum(rmap.region.min(axis=0), rmap.centers.min(axis=0) - half_voxel)
    upper = np.maximum(rmap.region.max(axis=0), rmap.centers.max(axis=0) + half_voxel)
    ax3.set_xlim(lower[0], upper[0])
    ax3.set_ylim(lower[1], upper[1])
    ax3.set_zlim(lower[2], upper[2])
    ax3.set_box_aspect(np.maximum(upper - lower, 0.2 * (upper - lower).max()))
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax3.set_zlabel("z [m]")
    ax3.set_title(
        f"voxels reached, centres at y >= {rmap.base[1] - half:.3g} m "
        f"({int(shown.sum())}/{int(cut.sum())})",
        fontsize="small",
    )
    title = (
        f"reachability of {rmap.frame!r} on {rmap.robot}: {_orientation_text(rmap)}, "
        f"{rmap.resolution:g} m voxels (+: reach-bound centre)"
    )
    # Wrapped to the figure's width (about 11 characters an inch at this size): a narrow
    # figure (few slices) would clip one long line at both edges.
    lines = textwrap.wrap(title, width=int(figsize[0] * 11))
    fig.suptitle("\n".join(lines), fontsize="medium")
    top = 0.86 - 0.05 * (len(lines) - 1)
    # Margins of the labels outside the panels (the first one's y label, the 3D z label).
    left, right = max(0.07, 0.85 / figsize[0]), 1.0 - 0.6 / figsize[0]
    fig.subplots_adjust(left=left, right=right, bottom=0.12, top=top, wspace=0.35)
    if path is not None:
        fig.savefig(path, dpi=dpi)
    return fig
