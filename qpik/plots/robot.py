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
    legend_below,
)


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
) -> Axes:
    """The robot in 3D (matplotlib, from MuJoCo's body positions: a segment from each body
    to each child) at the start (grey), ``intermediate`` configurations along ``path``
    (light blue) and the final one (dark blue), with the traces of ``frames`` (orange)
    and the ``targets`` [m, world] (red crosses). ``view``: (elevation, azimuth) [deg].
    Needs no GL (no offscreen rendering): it works on machines without a display."""
    check_model_type("model", model)
    path = check_path(model, path)
    target_points = check_targets(targets)
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
        if rank == 0:
            color, width, label = (0.55, 0.55, 0.55, 0.9), 1.8, "start"
        elif last:
            color, width, label = (0.05, 0.2, 0.6, 1.0), 2.4, "final"
        else:
            color, width, label = (0.35, 0.6, 0.95, 0.6), 1.4, "intermediate" if rank == 1 else None
        lines = Line3DCollection(segments, colors=[color], lw=width, label=label)
        ax3d.add_collection3d(lines)
        points.append(segments.reshape(-1, 3))
    for k, trace in enumerate(frame_trace(configuration, path, frames)):
        ax3d.plot(*trace.T, color="tab:orange", lw=1, label="frame path" if k == 0 else None)
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
) -> Axes:
    """A planar arm seen from above at the start (light), ``intermediate`` configurations
    along ``path`` and the final one (dark), with the tip's trace and the targets."""
    check_model_type("model", model)
    path = check_path(model, path)
    target_points = check_targets(targets)
    frame = checks.check_frame_name("frame", frame)
    frame_type = check_frame_type("frame_type", frame_type)
    check_ax(ax)
    intermediate = checks.check_integer("intermediate", intermediate, 0, 10_000)
    configuration = Configuration(model)
    configuration.frame_id(frame, frame_type)  # an unknown frame: UnknownFrame, before drawing
    ax = axes(ax)
    (tip,) = frame_trace(configuration, path, [(frame, frame_type)])
    ax.plot(tip[:, 0], tip[:, 1], color="tab:orange", lw=1, label="tip path")
    picks = pick_indices(len(path), intermediate)
    for rank, index in enumerate(picks):
        configuration.update(path[index])
        joints = [np.zeros(3)] + [configuration.data.xpos[b].copy() for b in range(1, model.nbody)]
        joints.append(configuration.frame_pose(frame, frame_type)[0])
        points = np.array(joints)
        shade = min(1.0, 0.25 + 0.75 * rank / max(len(picks) - 1, 1))
        label = "start" if index == 0 else ("final" if index == len(path) - 1 else None)
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
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("arm (top view): start, intermediate, final")
    ax.grid(True, alpha=0.3)
    legend_below(ax, ncol=4)
    return ax
