"""The robot drawn at its start, intermediate and final configurations: 3D segments from
MuJoCo's body positions, or a top view of a planar arm."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..core import checks
from ..errors import InvalidInput
from ..model.configuration import Configuration, FrameType
from ..model.frames import check_model_type

if TYPE_CHECKING:  # matplotlib is optional and imported lazily
    import mujoco
    from matplotlib.axes import Axes
    from mpl_toolkits.mplot3d import Axes3D

from .base import (
    axes,
    check_ax,
    check_frame_type,
    check_frames,
    check_path,
    check_targets,
    check_task_targets,
    legend_below,
    lone_points,
)

#: Markers of the levels' own targets (task_targets), in turn.
_TASK_MARKERS = ("o", "s", "D", "^", "v", "P")


# ----------------------------------------------------------------------------- robot
def robot_segments(
    model: mujoco.MjModel,
    configuration: Configuration,
    frames: Sequence[tuple[str, str | FrameType]] = (),
) -> np.ndarray:
    """Segments ``(n, 2, 3)`` [m, world] from each body's origin to its children's (a
    body on a free joint is not tied to the world), then from the body of each of
    ``frames`` (a site or geom) to the frame, at the configuration."""
    import mujoco

    check_model_type("model", model)
    checks.check_instance("configuration", configuration, Configuration, "a qpik.Configuration")
    theirs = configuration.model
    if (theirs.nbody, theirs.nq, theirs.nsite, theirs.ngeom) != (
        model.nbody,
        model.nq,
        model.nsite,
        model.ngeom,
    ):
        raise InvalidInput("configuration is of another model than model (other sizes)")
    frames = check_frames("frames", frames)
    free = int(mujoco.mjtJoint.mjJNT_FREE)
    xpos = configuration.data.xpos
    segments = []
    for body in range(1, model.nbody):
        parent = int(model.body_parentid[body])
        first, count = model.body_jntadr[body], model.body_jntnum[body]
        if parent == 0 and any(int(model.jnt_type[j]) == free for j in range(first, first + count)):
            continue
        segments.append((xpos[parent], xpos[body]))
    owner = {FrameType.SITE: model.site_bodyid, FrameType.GEOM: model.geom_bodyid}
    for name, kind in frames:
        kind = FrameType.parse(kind)
        if kind in owner:
            body = owner[kind][configuration.frame_id(name, kind)]
            segments.append((xpos[body], configuration.frame_pose(name, kind)[0]))
    return np.array(segments).reshape(-1, 2, 3)


def world_geoms(model: mujoco.MjModel) -> list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
    """The scene's solid geoms fixed in the world (body 0: a problem file's
    ``[[obstacles]]``, :func:`qpik.scene.add_obstacle`'s): ``(type, size (3,), position (3,)
    [m, world], rotation (3, 3))`` of each visible sphere, capsule, cylinder, ellipsoid or
    box (planes, meshes and height fields left out)."""
    import mujoco

    kinds = {
        int(mujoco.mjtGeom.mjGEOM_SPHERE),
        int(mujoco.mjtGeom.mjGEOM_CAPSULE),
        int(mujoco.mjtGeom.mjGEOM_CYLINDER),
        int(mujoco.mjtGeom.mjGEOM_ELLIPSOID),
        int(mujoco.mjtGeom.mjGEOM_BOX),
    }
    out = []
    for g in range(model.ngeom):
        kind = int(model.geom_type[g])
        if int(model.geom_bodyid[g]) != 0 or kind not in kinds or model.geom_rgba[g, 3] <= 0:
            continue
        rotation = np.empty(9)
        mujoco.mju_quat2Mat(rotation, model.geom_quat[g])
        out.append(
            (kind, model.geom_size[g].copy(), model.geom_pos[g].copy(), rotation.reshape(3, 3))
        )
    return out


def geom_surface(kind: int, size: np.ndarray, position, rotation, n: int = 14) -> np.ndarray:
    """Points ``(3, n, 2 n)`` [m, world] of a geom's surface (sphere, ellipsoid, capsule,
    cylinder: their axes along the geom's z) or, for a box, its 8 corners ``(3, 2, 4)``."""
    import mujoco

    if kind == int(mujoco.mjtGeom.mjGEOM_BOX):
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        local = (signs * size).T.reshape(3, 2, 4)
    else:
        u = np.linspace(0.0, 2.0 * np.pi, 2 * n)
        v = np.linspace(0.0, np.pi, n)
        cos_u, sin_u = np.cos(u)[None, :], np.sin(u)[None, :]
        if kind == int(mujoco.mjtGeom.mjGEOM_CYLINDER):  # radius size[0], half-length size[1]
            shape = (n, 2 * n)
            t = np.broadcast_to(np.linspace(-1.0, 1.0, n)[:, None], shape)
            x, y = (np.broadcast_to(size[0] * c, shape) for c in (cos_u, sin_u))
            local = np.array([x, y, size[1] * t])
        else:
            ring, height = np.sin(v)[:, None], np.cos(v)[:, None] * np.ones_like(u)[None, :]
            x, y = ring * cos_u, ring * sin_u
            if kind == int(mujoco.mjtGeom.mjGEOM_ELLIPSOID):
                local = np.array([size[0] * x, size[1] * y, size[2] * height])
            elif kind == int(mujoco.mjtGeom.mjGEOM_CAPSULE):  # half-spheres on a cylinder
                local = np.array(
                    [size[0] * x, size[0] * y, size[0] * height + np.sign(height) * size[1]]
                )
            else:  # sphere
                local = size[0] * np.array([x, y, height])
    points = np.tensordot(rotation, local, axes=1)
    return points + np.reshape(position, (3,) + (1,) * (points.ndim - 1))


def pick_indices(n: int, intermediate: int) -> np.ndarray:
    return np.unique(np.linspace(0, n - 1, intermediate + 2).round().astype(int))


def frame_trace(configuration, path, frames) -> list[np.ndarray]:
    traces: list[list[np.ndarray]] = [[] for _ in frames]
    for q in path:
        configuration.update(q)
        for trace, (name, kind) in zip(traces, frames):
            trace.append(configuration.frame_pose(name, kind)[0])
    return [np.array(t) for t in traces]


def plot_robot(
    model: mujoco.MjModel,
    path: np.ndarray,
    targets: Sequence[np.ndarray] = (),
    frames: Sequence[tuple[str, str | FrameType]] = (),
    ax: Axes | None = None,
    intermediate: int = 2,
    view: tuple[float, float] = (12.0, -70.0),
    task_targets: Sequence[tuple[str, np.ndarray]] = (),
) -> Axes:
    """The robot in 3D (matplotlib, from MuJoCo's body positions: a segment from each body
    to each child) at the start (grey), ``intermediate`` configurations along ``path``
    (light blue) and the final one (dark blue), with the traces of ``frames`` (orange)
    and the ``targets`` [m, world] (red crosses). ``task_targets``: other targets to mark,
    ``(label, position [m, world])`` (a lower level's frame target, say), each its own
    marker. The scene's solid geoms fixed in the world are drawn too
    (:func:`world_geoms`: a problem file's ``[[obstacles]]``). ``view``: (elevation,
    azimuth) [deg]. Needs no GL (no offscreen rendering): it works on machines without a
    display."""
    check_model_type("model", model)
    path = check_path(model, path)
    target_points = check_targets(targets)
    others = check_task_targets(task_targets)
    frames = check_frames("frames", frames)
    check_ax(ax, three_d=True)
    intermediate = checks.check_integer("intermediate", intermediate, 0, 10_000)
    elevation, azimuth = checks.check_vector("view", view, 2)
    configuration = Configuration(model)
    for name, kind in frames:
        configuration.frame_id(name, kind)  # an unknown frame: UnknownFrame, before drawing
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    ax3d: Axes3D = axes(ax, projection="3d")
    picks = pick_indices(len(path), intermediate)
    points = [np.zeros((0, 3))]
    for rank, index in enumerate(picks):
        configuration.update(path[index])
        segments = robot_segments(model, configuration, frames)
        last = rank == len(picks) - 1
        label: str | None
        if len(picks) == 1:  # a path of one configuration: the start is the answer
            color, width, label = (0.05, 0.2, 0.6, 1.0), 2.4, "start = final"
        elif rank == 0:
            color, width, label = (0.55, 0.55, 0.55, 0.9), 1.8, "start"
        elif last:
            color, width, label = (0.05, 0.2, 0.6, 1.0), 2.4, "final"
        else:
            color, width, label = (0.35, 0.6, 0.95, 0.6), 1.4, "intermediate" if rank == 1 else None
        lines = Line3DCollection(segments, colors=[color], lw=width, label=label)
        ax3d.add_collection3d(lines)
        points.append(segments.reshape(-1, 3))
    for k, trace in enumerate(frame_trace(configuration, path, frames)):
        label = "frame path" if k == 0 else None
        ax3d.plot(*trace.T, color="tab:orange", lw=1, label=label, **lone_points(trace))
        points.append(trace)
    for k, target in enumerate(target_points):
        ax3d.plot(
            *np.reshape(target, (3, 1)),
            "x",
            color="tab:red",
            ms=8,
            mew=2,
            label="target" if k == 0 else None,
        )
        points.append(np.reshape(target, (1, 3)))
    for k, (label, target) in enumerate(others):
        marker = _TASK_MARKERS[k % len(_TASK_MARKERS)]
        ax3d.plot(*np.reshape(target, (3, 1)), marker, color="tab:purple", ms=7, mfc="none",
                  mew=2, label=label)  # fmt: skip
        points.append(np.reshape(target, (1, 3)))
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    for k, (geom_type, size, position, rotation) in enumerate(world_geoms(model)):
        surface = geom_surface(geom_type, size, position, rotation)
        label = "obstacle" if k == 0 else None
        if surface.shape[1:] == (2, 4):  # a box: its six faces
            c = surface.reshape(3, 8).T
            faces = [c[[0, 1, 3, 2]], c[[4, 5, 7, 6]], c[[0, 1, 5, 4]], c[[2, 3, 7, 6]],
                     c[[0, 2, 6, 4]], c[[1, 3, 7, 5]]]  # fmt: skip
            ax3d.add_collection3d(
                Poly3DCollection(
                    faces, facecolor=(0.8, 0.2, 0.2, 0.25), edgecolor="0.4", lw=0.5, label=label
                )  # fmt: skip
            )
        else:
            ax3d.plot_surface(*surface, color="tab:red", alpha=0.25, lw=0, label=label)
        points.append(surface.reshape(3, -1).T)
    equal_3d(ax3d, np.vstack(points))
    ax3d.view_init(float(elevation), float(azimuth))
    ax3d.set_xlabel("x [m]", fontsize="small")
    ax3d.set_ylabel("y [m]", fontsize="small")
    ax3d.set_zlabel("z [m]", fontsize="small")
    ax3d.tick_params(labelsize="x-small")
    from matplotlib.ticker import MaxNLocator

    for axis in (ax3d.xaxis, ax3d.yaxis, ax3d.zaxis):
        axis.set_major_locator(MaxNLocator(4))
    ax3d.set_title("robot: start, intermediate, final")
    legend_below(ax3d, ncol=2)
    return ax3d


def equal_3d(ax, points: np.ndarray) -> None:
    """One scale on the three axes [m], each axis spanning its own range of ``points``
    (padded, and at least 40 % of the largest: a tall robot makes a tall box, a flat
    motion no sliver)."""
    low, high = points.min(axis=0), points.max(axis=0)
    largest = max(float(np.max(high - low)), 0.2)
    half = np.maximum((high - low) / 2, 0.2 * largest) + 0.05 * largest
    centre = (low + high) / 2
    for setter, c, h in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, half):
        setter(c - h, c + h)
    ax.set_box_aspect(tuple(2 * half), zoom=0.95)


def plot_planar_arm(
    model: mujoco.MjModel,
    path: np.ndarray,
    targets: Sequence[np.ndarray] = (),
    frame: str = "ee",
    frame_type: str | FrameType = "site",
    ax: Axes | None = None,
    intermediate: int = 3,
    task_targets: Sequence[tuple[str, np.ndarray]] = (),
) -> Axes:
    """A planar arm seen from above at the start (light), ``intermediate`` configurations
    along ``path`` and the final one (dark), with the tip's trace and the targets (red
    crosses); ``task_targets``: other targets to mark, ``(label, position [m, world])`` (a
    lower level's frame target, say), each its own marker."""
    check_model_type("model", model)
    path = check_path(model, path)
    target_points = check_targets(targets)
    others = check_task_targets(task_targets)
    frame = checks.check_frame_name("frame", frame)
    frame_type = check_frame_type("frame_type", frame_type)
    check_ax(ax)
    intermediate = checks.check_integer("intermediate", intermediate, 0, 10_000)
    configuration = Configuration(model)
    configuration.frame_id(frame, frame_type)  # an unknown frame: UnknownFrame, before drawing
    ax = axes(ax)
    (tip,) = frame_trace(configuration, path, [(frame, frame_type)])
    ax.plot(tip[:, 0], tip[:, 1], color="tab:orange", lw=1, label="tip path", **lone_points(tip))
    picks = pick_indices(len(path), intermediate)
    for rank, index in enumerate(picks):
        configuration.update(path[index])
        joints = [np.zeros(3)] + [configuration.data.xpos[b].copy() for b in range(1, model.nbody)]
        joints.append(configuration.frame_pose(frame, frame_type)[0])
        points = np.array(joints)
        label: str | None
        if len(picks) == 1:  # a path of one configuration: the start is the answer
            shade, label = 1.0, "start = final"
        else:
            shade = min(1.0, 0.25 + 0.75 * rank / (len(picks) - 1))
            label = "start" if index == 0 else ("final" if index == len(path) - 1 else None)
            if label is None and rank == 1:  # (the first intermediate one names them all)
                label = "intermediate"
        ax.plot(
            points[:, 0], points[:, 1], "-o", color=(0.1, 0.3, 0.7, shade), lw=3, ms=4, label=label
        )
    for k, target in enumerate(target_points):
        ax.plot(
            target[0],
            target[1],
            "x",
            color="tab:red",
            ms=10,
            mew=2,
            label="target" if k == 0 else None,
        )
    for k, (label, target) in enumerate(others):
        marker = _TASK_MARKERS[k % len(_TASK_MARKERS)]
        ax.plot(target[0], target[1], marker, color="tab:purple", ms=9, mfc="none", mew=2,
                label=label)  # fmt: skip
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("arm (top view): start, intermediate, final")
    ax.grid(True, alpha=0.3)
    legend_below(ax, ncol=4)
    return ax
