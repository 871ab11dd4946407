"""Figures of a solved problem (matplotlib: ``pip install 'qpik[plots]'``).

matplotlib is imported when a function here is first called, never by ``import qpik``;
without it, :class:`qpik.MissingExtra` names the ``plots`` extra. Functions draw on axes
you pass (or new ones) and return them; :func:`plot_result` lays out a whole figure and
can save it to a file (with the non-interactive Agg backend):

* :func:`plot_level_errors`: each level's residual against iteration (log scale);
* :func:`plot_joints`: joint trajectories inside their limit bands;
* :func:`plot_singular_values`: the goal frame's singular values and manipulability
  along the path;
* :func:`plot_planar_arm`: a planar arm at its start, intermediate and final
  configurations, with the targets.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from .analysis import manipulability, singular_values
from .configuration import Configuration, joint_names
from .errors import MissingExtra

if TYPE_CHECKING:  # matplotlib is optional and imported lazily
    import mujoco
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from .problem import ProblemResult

__all__ = [
    "is_planar",
    "joint_curves",
    "plot_joints",
    "plot_level_errors",
    "plot_planar_arm",
    "plot_result",
    "plot_singular_values",
]


def _matplotlib():
    try:
        import matplotlib
    except ImportError as exc:
        raise MissingExtra("plotting", "plots", "matplotlib") from exc
    return matplotlib


def _pyplot():
    _matplotlib()
    import matplotlib.pyplot as plt

    return plt


def _axes(ax):
    if ax is not None:
        return ax
    return _pyplot().subplots()[1]


def is_planar(model: mujoco.MjModel) -> bool:
    """Whether every joint is a hinge about the world z axis at ``qpos0`` (the bundled
    planar arms)."""
    import mujoco

    hinge = int(mujoco.mjtJoint.mjJNT_HINGE)
    axes = Configuration(model, model.qpos0).data.xaxis
    return model.njnt > 0 and all(
        int(model.jnt_type[j]) == hinge and np.allclose(np.abs(axes[j]), [0, 0, 1])
        for j in range(model.njnt)
    )


def plot_level_errors(
    residual_history: Sequence[Sequence[float]],
    ax: Axes | None = None,
    xlabel: str = "iteration",
    goal_error: np.ndarray | None = None,
) -> Axes:
    """Each priority level's weighted QP residual ``|A_k dq - b_k|`` per iteration (log
    scale), and the goal frame's position error [m] when given (``goal_error[i]`` after
    iteration ``i``, ``goal_error[0]`` at the start)."""
    ax = _axes(ax)
    if goal_error is not None:
        ax.semilogy(
            np.arange(len(goal_error)),
            np.maximum(goal_error, 1e-16),
            "k:",
            lw=1.5,
            label="goal position error [m]",
        )
    history = [list(row) for row in residual_history]
    levels = max((len(row) for row in history), default=0)
    for level in range(levels):
        values = np.array([row[level] if level < len(row) else np.nan for row in history])
        ax.semilogy(
            np.arange(1, len(values) + 1), np.maximum(values, 1e-16), label=f"level {level}"
        )
    ax.set_xlabel(xlabel)
    ax.set_ylabel("residual")
    ax.set_title("error per priority level")
    if levels or goal_error is not None:
        ax.legend(fontsize="small")
    ax.grid(True, which="both", alpha=0.3)
    return ax


def joint_curves(model: mujoco.MjModel, path: np.ndarray) -> list[tuple[str, np.ndarray, tuple]]:
    """What :func:`plot_joints` draws: per curve ``(label, values (k,), (lower, upper))``.

    A hinge or slide joint is its ``q`` [rad or m] with its range; a ball joint its
    rotation angle ``2 atan2(|xyz|, |w|)`` [rad] with ``[0, range]`` when limited; a free
    joint its position x, y, z [m] and rotation angle [rad] (no limits)."""
    import mujoco

    path = np.atleast_2d(path)
    names = joint_names(model)
    configuration = Configuration(model)
    curves = []

    def angle(quat: np.ndarray) -> np.ndarray:
        return 2.0 * np.arctan2(np.linalg.norm(quat[:, 1:], axis=1), np.abs(quat[:, 0]))

    unlimited = (-np.inf, np.inf)
    for j, name in enumerate(names):
        adr = model.jnt_qposadr[j]
        kind = int(model.jnt_type[j])
        if kind == int(mujoco.mjtJoint.mjJNT_FREE):
            for k, axis in enumerate("xyz"):
                curves.append((f"{name} {axis} [m]", path[:, adr + k], unlimited))
            curves.append((f"{name} angle", angle(path[:, adr + 3 : adr + 7]), unlimited))
        elif kind == int(mujoco.mjtJoint.mjJNT_BALL):
            bounds = (0.0, float(model.jnt_range[j, 1])) if model.jnt_limited[j] else unlimited
            curves.append((f"{name} angle", angle(path[:, adr : adr + 4]), bounds))
        else:
            bounds = (float(configuration.lower[adr]), float(configuration.upper[adr]))
            curves.append((name, path[:, adr], bounds))
    return curves


def plot_joints(
    model: mujoco.MjModel,
    path: np.ndarray,
    ax: Axes | None = None,
    time: np.ndarray | None = None,
) -> Axes:
    """Joint trajectories ``path (k, nq)`` with each joint's limits as a shaded band
    (ball joints: their rotation angle; free joints: position and rotation angle; see
    :func:`joint_curves`)."""
    ax = _axes(ax)
    path = np.atleast_2d(path)
    x = np.arange(len(path)) if time is None else time
    colors = _matplotlib().rcParams["axes.prop_cycle"].by_key()["color"]
    curves = joint_curves(model, path)
    for i, (label, values, (lower, upper)) in enumerate(curves):
        color = colors[i % len(colors)]
        ax.plot(x, values, color=color, marker="o" if len(path) < 8 else None, label=label)
        if np.isfinite(lower) and np.isfinite(upper):
            ax.axhspan(lower, upper, color=color, alpha=0.05)
            for bound in (lower, upper):
                ax.axhline(bound, color=color, lw=0.6, ls=":")
    ax.set_xlabel("time [s]" if time is not None else "configuration")
    ax.set_ylabel("q [rad or m]")
    ax.set_title("joints (limits dotted)")
    ax.legend(fontsize="x-small", ncol=2 if len(curves) <= 16 else 3)
    return ax


def _frame_jacobian_rows(model, frame, frame_type, rows: str):
    def jacobian(configuration: Configuration) -> np.ndarray:
        J = configuration.frame_jacobian(frame, frame_type)
        if rows == "planar":
            return J[:2]
        if rows == "position":
            return J[:3]
        return J

    return jacobian


def plot_singular_values(
    model: mujoco.MjModel,
    path: np.ndarray,
    frame: str,
    frame_type: str = "site",
    rows: str = "pose",
    ax: Axes | None = None,
    time: np.ndarray | None = None,
) -> Axes:
    """Singular values of the frame's Jacobian (``rows``: ``"pose"``, ``"position"`` or
    ``"planar"`` for vx, vy) and the manipulability ``sqrt(det J J^T)`` along ``path``."""
    ax = _axes(ax)
    configuration = Configuration(model)
    jacobian = _frame_jacobian_rows(model, frame, frame_type, rows)
    sigmas, measure = [], []
    for q in np.atleast_2d(path):
        configuration.update(q)
        J = jacobian(configuration)
        sigmas.append(singular_values(J))
        measure.append(manipulability(J))
    sigmas = np.array(sigmas)
    x = np.arange(len(sigmas)) if time is None else time
    marker = "o" if len(sigmas) < 8 else None
    for i in range(sigmas.shape[1]):
        ax.plot(x, sigmas[:, i], lw=1, marker=marker, label=f"sigma_{i + 1}")
    ax.plot(x, measure, "k--", lw=1.5, marker=marker, label="manipulability")
    ax.set_xlabel("time [s]" if time is not None else "configuration")
    ax.set_title(f"singular values of J ({frame}, {rows} rows)")
    ax.legend(fontsize="x-small", ncol=2)
    ax.grid(True, alpha=0.3)
    return ax


def plot_planar_arm(
    model: mujoco.MjModel,
    path: np.ndarray,
    targets: Sequence[np.ndarray] = (),
    frame: str = "ee",
    frame_type: str = "site",
    ax: Axes | None = None,
    intermediate: int = 3,
) -> Axes:
    """A planar arm drawn at the start (light), ``intermediate`` configurations along
    ``path`` and the final one (dark), with the tip's trace and the targets (crosses)."""
    ax = _axes(ax)
    path = np.atleast_2d(path)
    configuration = Configuration(model)
    picks = np.unique(np.linspace(0, len(path) - 1, intermediate + 2).round().astype(int))
    tip = []
    for q in path:
        configuration.update(q)
        tip.append(configuration.frame_pose(frame, frame_type)[0])
    tip = np.array(tip)
    ax.plot(tip[:, 0], tip[:, 1], color="tab:orange", lw=1, label="tip path")
    for rank, index in enumerate(picks):
        configuration.update(path[index])
        points = [np.zeros(3)] + [configuration.data.xpos[b].copy() for b in range(1, model.nbody)]
        points.append(configuration.frame_pose(frame, frame_type)[0])
        points = np.array(points)
        shade = 0.25 + 0.75 * rank / max(len(picks) - 1, 1)
        label = "start" if index == 0 else ("final" if index == len(path) - 1 else None)
        ax.plot(
            points[:, 0],
            points[:, 1],
            "-o",
            color=(0.1, 0.3, 0.7, shade),
            lw=3,
            ms=4,
            label=label,
        )
    for k, target in enumerate(targets):
        ax.plot(
            target[0],
            target[1],
            "x",
            color="tab:red",
            ms=10,
            mew=2,
            label="target" if k == 0 else None,
        )
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("arm: start, intermediate, final")
    ax.legend(fontsize="x-small")
    ax.grid(True, alpha=0.3)
    return ax


def plot_result(
    result: ProblemResult, path: str | os.PathLike | None = None, dpi: int = 80
) -> Figure:
    """A figure of a :class:`qpik.problem.ProblemResult`: level errors, joints, singular
    values and (planar robots) the arm. Saved to ``path`` when given (drawn on a bare
    :class:`matplotlib.figure.Figure`, Agg canvas: no GUI, pyplot's state untouched);
    returns the figure."""
    _matplotlib()
    problem = result.problem
    model = problem.model
    planar = is_planar(model)
    panels = 4 if planar else 3
    figsize = (4.2 * panels, 3.8)
    if path is not None:
        from matplotlib.figure import Figure

        fig = Figure(figsize=figsize)
        axes = fig.subplots(1, panels)
    else:
        fig, axes = _pyplot().subplots(1, panels, figsize=figsize)
    trace = result.trace
    time = None if trace is None else np.arange(len(trace.q)) * trace.dt
    plot_level_errors(
        result.residual_history,
        axes[0],
        xlabel="step" if trace is not None else "iteration",
        goal_error=None if trace is None else trace.position_error,
    )
    plot_joints(model, result.path, axes[1], time=time)
    goal = problem.goals[0]
    rows = "planar" if planar else ("pose" if goal.target.rotation is not None else "position")
    plot_singular_values(
        model, result.path, goal.frame, goal.frame_type, rows=rows, ax=axes[2], time=time
    )
    if planar:
        plot_planar_arm(
            model,
            result.path,
            [g.target.position for g in problem.goals],
            goal.frame,
            goal.frame_type,
            axes[3],
        )
    state = "converged" if result.converged else f"not converged: {result.reason}"
    fig.suptitle(f"{problem.name} ({state})", fontsize="medium")
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=dpi)
    return fig
