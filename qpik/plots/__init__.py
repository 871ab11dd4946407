"""Figures of a solved problem (matplotlib, the ``plots`` extra: ``pip install -e ".[plots]"``).

matplotlib is imported when a function here is first called, never by ``import qpik``;
without it, :class:`qpik.MissingExtra` names the ``plots`` extra. Functions draw on axes
you pass (or new ones) and return them; :func:`plot_result` lays out a whole figure and
can save it to a file (with the non-interactive Agg backend, no display needed).

Every panel of a path is drawn along the whole path: in track mode every step (x: time
[s]), in solve mode every iterate of each goal's solve (x: iteration), with dotted
vertical lines where the next goal (waypoint) begins.

* :func:`plot_task_errors`: each task's error ``|e(q)|`` per priority level (what each
  level asks, log scale: position parts [m], rotation parts [rad]);
* :func:`plot_frame_errors`: each goal frame's position [m] and rotation [rad] error;
* :func:`plot_level_errors`: each level's QP residual ``|A_k dq - b_k|`` per step (what
  the solver could not do in that step: near zero once a level is feasible);
* :func:`plot_joints`: joint trajectories inside their limit bands;
* :func:`plot_singular_values`: the goal frames' singular values and manipulability;
* :func:`plot_robot`: the robot in 3D (segments from each body to its children, from
  MuJoCo's body positions) at its start, intermediate and final configurations, with the
  targets; :func:`plot_planar_arm`: the same seen from above for planar arms.

Legends sit outside the axes (below them), never on the data; with many joints only the
ones that move most are named.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np

from ..core import checks
from . import curves as _curves
from .base import FLOOR as FLOOR  # the constants, readable as qpik.plots.X
from .base import MAX_NAMED as MAX_NAMED
from .base import PathAxis, check_figure_path, is_planar, pyplot, require_matplotlib
from .curves import (
    joint_curves,
    plot_error_curves,
    plot_frame_errors,
    plot_joints,
    plot_level_errors,
    plot_singular_values,
    plot_task_errors,
)
from .robot import plot_planar_arm, plot_robot, robot_segments

if TYPE_CHECKING:  # matplotlib is optional and imported lazily
    from matplotlib.figure import Figure

    from ..problem import ProblemResult
    from ..problem.report import Problem


# ----------------------------------------------------------------------------- figure
def level_targets(problem: Problem) -> list[tuple[str, np.ndarray]]:
    """The position targets [m, world] of the levels' frame tasks on frames that no goal
    names (a lower level's own target, the feet a humanoid holds where they start), as
    ``(label, position)`` with the label ``"L<level> <frame> target"``; what
    :func:`plot_result` marks beside the goals' targets."""
    goal_frames = {f.frame for g in problem.goals for f in g.frames}
    out = []
    for level, tasks in enumerate(problem.build_stack(problem.start_configuration())):
        for task in tasks:
            frame = getattr(task, "frame_name", None)
            if frame is None or frame in goal_frames:
                continue
            target = getattr(task, "target", None)
            if isinstance(target, np.ndarray) and target.shape == (3,):
                position = target
            elif getattr(task, "transform_target_to_world", None) is not None:
                position = task.transform_target_to_world.translation()
            else:  # an orientation's target, or none set
                continue
            out.append((f"L{level} {frame} target", np.array(position, dtype=float)))
    return out


def plot_result(
    result: ProblemResult, path: str | os.PathLike | None = None, dpi: int = 80
) -> Figure:
    """A figure of a :class:`qpik.problem.ProblemResult`: task error per level and error
    per goal frame (top), joints and singular values of the goal frames' Jacobian
    (bottom), all along the path, and the robot on the right (3D, or from above for
    planar arms). The QP residual per step is :func:`plot_level_errors`'s. Saved to
    ``path`` when given (drawn on a bare :class:`matplotlib.figure.Figure`, Agg canvas: no
    GUI, pyplot's state untouched); returns the figure."""
    _curves.check_result(result)
    if path is not None:
        path = check_figure_path("path", path)
    checks.check_real("dpi", dpi, 0.0, 10_000.0, open_minimum=True)
    require_matplotlib()
    problem = result.problem
    model = problem.model
    planar = is_planar(model)
    figsize = (16.5, 10.5)
    if path is not None:
        from matplotlib.figure import Figure

        fig = Figure(figsize=figsize, layout="constrained")
    else:
        fig = pyplot().figure(figsize=figsize, layout="constrained")
    grid = fig.add_gridspec(2, 3, width_ratios=(1.0, 1.0, 1.1))
    x, xlabel = _curves.path_axis(result)
    time = x if result.trace is not None else None
    plot_task_errors(result, fig.add_subplot(grid[0, 0]))
    plot_frame_errors(result, fig.add_subplot(grid[0, 1]))
    frames = list(dict.fromkeys((f.frame, f.frame_type) for g in problem.goals for f in g.frames))
    targets = [f.target.position for g in problem.goals for f in g.frames]
    others = level_targets(problem)
    if planar:
        plot_planar_arm(
            model, result.path, targets, *frames[0], fig.add_subplot(grid[:, 2]),
            task_targets=others,
        )  # fmt: skip
    else:
        plot_robot(
            model, result.path, targets, frames, fig.add_subplot(grid[:, 2], projection="3d"),
            task_targets=others,
        )  # fmt: skip
    index = result.goal_index
    plot_joints(model, result.path, fig.add_subplot(grid[1, 0]), time, index, xlabel)
    with_rotation = all(f.target.rotation is not None for g in problem.goals for f in g.frames)
    rows = "planar" if planar else ("pose" if with_rotation else "position")
    plot_singular_values(
        model,
        result.path,
        frames,
        rows=rows,
        ax=fig.add_subplot(grid[1, 1]),
        time=time,
        goal_index=index,
        xlabel=xlabel,
    )
    state = "converged" if result.converged else f"not converged: {result.reason}"
    fig.suptitle(f"{problem.name} ({state})", fontsize="large")
    if path is not None:
        fig.savefig(path, dpi=dpi)
    return fig


__all__ = [
    "PathAxis",
    "check_figure_path",
    "is_planar",
    "joint_curves",
    "plot_error_curves",
    "plot_frame_errors",
    "plot_joints",
    "plot_level_errors",
    "plot_planar_arm",
    "plot_result",
    "plot_robot",
    "level_targets",
    "plot_singular_values",
    "plot_task_errors",
    "pyplot",
    "require_matplotlib",
    "robot_segments",
]
