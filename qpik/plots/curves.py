"""Curves along a path: task, frame and level errors, joints, singular values."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Unpack

import numpy as np

from ..core import checks
from ..core.jacobian import manipulability, row_indices, singular_values
from ..errors import InvalidArgumentType, InvalidInput
from ..model.configuration import Configuration, FrameType, joint_names
from ..model.frames import check_model_type

if TYPE_CHECKING:  # matplotlib is optional and imported lazily
    import mujoco
    from matplotlib.axes import Axes

    from ..problem import ErrorCurve, ProblemResult
from .base import (
    FLOOR,
    MAX_NAMED,
    PathAxis,
    axes,
    check_along,
    check_ax,
    check_frame_type,
    check_frames,
    check_label,
    check_path,
    goal_starts,
    legend_below,
    lone_points,
    palette,
)


# ----------------------------------------------------------------------------- errors
def plot_error_curves(
    curves: Sequence[ErrorCurve],
    ax: Axes | None = None,
    x: np.ndarray | None = None,
    goal_index: np.ndarray | None = None,
    tolerances: dict[str, float] | None = None,
    title: str = "",
) -> Axes:
    """:class:`qpik.problem.ErrorCurve` s on a log scale, one colour per task or frame
    (``group``): position-like parts [m] solid, rotation parts [rad] dashed, joint-space
    errors [rad or m] dotted, unitless ones dash-dotted (named ``[-]``); ``tolerances``
    ``{unit: value}`` as grey lines of the same styles (for the units present)."""
    ax = axes(ax)
    colors = palette()
    groups = list(dict.fromkeys(curve.group or curve.label for curve in curves))
    for curve in curves:
        xs = np.arange(len(curve.values)) if x is None else x
        color = colors[groups.index(curve.group or curve.label) % len(colors)]
        unit = f" [{curve.unit or '-'}]"
        values = np.maximum(curve.values, FLOOR)
        ax.semilogy(
            xs,
            values,
            STYLE[curve.unit],
            color=color,
            lw=1.3,
            label=curve.label + unit,
            **lone_points(values),
        )
    units = {curve.unit for curve in curves}
    for unit, value in (tolerances or {}).items():
        if unit in units:
            ax.axhline(value, color="0.45", lw=0.9, ls=STYLE[unit], label=f"tolerance [{unit}]")
    if curves:
        goal_starts(ax, np.arange(len(curves[0].values)) if x is None else x, goal_index)
    ax.set_ylabel(_ylabel(units))
    ax.set_title(title)
    ax.grid(True, which="major", alpha=0.3)
    if any(np.any(np.asarray(curve.values) < FLOOR) for curve in curves):
        floor_note(ax)
    legend_below(ax, ncol=1 if len(curves) > 6 else 2)
    return ax


def floor_note(ax: Axes) -> None:
    """Say on ``ax`` that errors below :data:`FLOOR` are drawn at it (0 has no place on a
    log scale)."""
    ax.text(
        0.99, 0.01, f"below {FLOOR:g}: drawn at {FLOOR:g}", transform=ax.transAxes,
        ha="right", va="bottom", fontsize="x-small", color="0.4",
    )  # fmt: skip


STYLE = {"m": "-", "rad": "--", "rad or m": ":", "": "-."}
_STYLE_NAMES = {
    "m": "[m] solid",
    "rad": "[rad] dashed",
    "rad or m": "[rad or m] dotted",
    "": "[-] dash-dot",
}


def _ylabel(units: set) -> str:
    """The y label: each unit present and its line style (``[m] solid`` where none)."""
    present = [name for unit, name in _STYLE_NAMES.items() if unit in units] or ["[m] solid"]
    return "error: " + ", ".join(present)


def plot_task_errors(result: ProblemResult, ax: Axes | None = None) -> Axes:
    """Each task's error along the path, one colour per task, level in the label (see
    :meth:`qpik.problem.ProblemResult.task_errors`), with the tolerances."""
    check_result(result)
    check_ax(ax)
    return plot_path_errors(result, result.task_errors(), ax, "task error per priority level")


def plot_frame_errors(result: ProblemResult, ax: Axes | None = None) -> Axes:
    """Each goal frame's position [m] and rotation [rad] error along the path (blank
    while the goal being reached does not name the frame), with the tolerances."""
    check_result(result)
    check_ax(ax)
    return plot_path_errors(result, result.frame_errors(), ax, "error per goal frame")


def check_result(result) -> None:
    """``result``: a :class:`qpik.problem.ProblemResult`."""
    from ..problem import ProblemResult

    checks.check_instance("result", result, ProblemResult, "a qpik.problem.ProblemResult")


def plot_path_errors(
    result: ProblemResult, curves: Sequence[ErrorCurve], ax: Axes | None, title: str
) -> Axes:
    x, xlabel = path_axis(result)
    ax = plot_error_curves(curves, ax, x, result.goal_index, tolerances(result), title)
    ax.set_xlabel(xlabel)
    return ax


def tolerances(result: ProblemResult) -> dict[str, float]:
    options = result.problem.solve_options
    return {"m": options.tol_position, "rad": options.tol_orientation}


def path_axis(result: ProblemResult) -> tuple[np.ndarray, str]:
    """x values of :attr:`ProblemResult.path` and their label."""
    n = len(result.path)
    if result.trace is not None:
        return np.arange(n) * result.trace.dt, "time [s]"
    restarted = any(r.restarts_used for r in result.results)
    # (a solve's path is the attempt it returned: after restarts, not its iterations before)
    return np.arange(n), "iteration of the returned attempts (all goals)" if restarted else (
        "iteration (all goals)"
    )


def plot_level_errors(
    residual_history: Sequence[Sequence[float]],
    ax: Axes | None = None,
    xlabel: str = "iteration",
    goal_error: np.ndarray | None = None,
) -> Axes:
    """Each priority level's weighted QP residual ``|A_k dq - b_k|`` per step (log scale):
    what a step could not achieve (near zero once a level is feasible; it is not the task
    error, see :func:`plot_task_errors`); and the goal frames' largest position error [m]
    when given (``goal_error[i]`` after step ``i``, ``goal_error[0]`` at the start)."""
    expected = "a sequence of rows, each a sequence of numbers (one per level)"
    if (
        isinstance(residual_history, (str, bytes, dict, set))
        or not isinstance(residual_history, (Sequence, np.ndarray))
        or (isinstance(residual_history, np.ndarray) and residual_history.ndim == 0)
    ):
        raise InvalidArgumentType("residual_history", expected, checks.type_name(residual_history))
    history = [
        checks.check_vector(f"residual_history[{i}]", row, finite=False)
        for i, row in enumerate(residual_history)
    ]
    check_ax(ax)
    xlabel = checks.check_instance("xlabel", xlabel, str, "a str")
    if goal_error is not None:
        goal_error = checks.check_vector("goal_error", goal_error, finite=False)
    ax = axes(ax)
    if goal_error is not None:
        ax.semilogy(
            np.arange(len(goal_error)),
            np.maximum(goal_error, FLOOR),
            "k:",
            lw=1.5,
            label="goal position error [m]",
            **lone_points(goal_error),
        )
    levels = max((len(row) for row in history), default=0)
    for level in range(levels):
        values = np.array([row[level] if level < len(row) else np.nan for row in history])
        ax.semilogy(
            np.arange(1, len(values) + 1),
            np.maximum(values, FLOOR),
            label=f"level {level}",
            **lone_points(values),
        )
    ax.set_xlabel(xlabel)
    goal_starts(ax, np.arange(1, len(history) + 1), None)
    ax.set_ylabel("|A_k dq - b_k|")
    ax.set_title("QP residual per level, per step")
    ax.grid(True, which="major", alpha=0.3)
    legend_below(ax, ncol=3)
    return ax


# ----------------------------------------------------------------------------- joints
def joint_curves(model: mujoco.MjModel, path: np.ndarray) -> list[tuple[str, np.ndarray, tuple]]:
    """What :func:`plot_joints` draws: per curve ``(label, values (k,), (lower, upper))``.

    A hinge or slide joint is its ``q`` [rad or m] with its range; a ball joint its
    rotation angle ``2 atan2(|xyz|, |w|)`` [rad] with ``[0, range]`` when limited; a free
    joint its position x, y, z [m] and rotation angle [rad] (no limits)."""
    import mujoco

    check_model_type("model", model)
    path = check_path(model, path)
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
    goal_index: np.ndarray | None = None,
    xlabel: str | None = None,
) -> Axes:
    """Joint trajectories ``path (k, nq)`` along the path, each joint's limits dotted when
    they lie near the curves (the axis spans the motion, not the whole limit range; ball
    joints: their rotation angle; free joints: position and rotation angle; see
    :func:`joint_curves`). With more than :data:`MAX_NAMED` curves, the ones that move
    most are coloured and named, the others thin and grey (their limits not drawn)."""
    check_model_type("model", model)
    path = check_path(model, path)
    check_ax(ax)
    time = check_along("time", time, len(path))
    goal_index = check_along("goal_index", goal_index, len(path))
    xlabel = check_label("xlabel", xlabel)
    ax = axes(ax)
    x = np.arange(len(path)) if time is None else time
    colors = palette()
    curves = joint_curves(model, path)
    motion = [float(np.ptp(values)) for _, values, _ in curves]
    named = set(np.argsort(motion)[::-1][:MAX_NAMED]) if len(curves) > MAX_NAMED else None
    marker = "o" if len(path) < 8 else None
    low, high = near_range([values for _, values, _ in curves])
    for i, (label, values, (lower, upper)) in enumerate(curves):
        if named is not None and i not in named:
            ax.plot(x, values, color="0.75", lw=0.6, zorder=1)
            continue
        color = colors[i % len(colors)]
        ax.plot(x, values, color=color, marker=marker, ms=3, lw=1.3, label=label, zorder=2)
        for bound in (lower, upper):
            if low <= bound <= high:
                ax.axhline(bound, color=color, lw=0.8, ls=":")
    ax.set_ylim(low, high)
    if named is not None:
        ax.plot([], [], color="0.75", lw=0.6, label=f"{len(curves) - len(named)} others")
    goal_starts(ax, x, goal_index)
    ax.set_xlabel(xlabel or ("time [s]" if time is not None else "configuration"))
    ax.set_ylabel("q [rad or m]")
    ax.set_title("joints along the path (limits in view dotted)")
    ax.grid(True, alpha=0.3)
    legend_below(ax, ncol=3)
    return ax


def near_range(curves: Sequence[np.ndarray]) -> tuple[float, float]:
    """The y range of the curves, padded by 30 % of their span (at least 0.2): limits
    inside it are close enough to the motion to draw."""
    values = np.concatenate([np.ravel(c) for c in curves])
    values = values[np.isfinite(values)]
    low, high = (float(values.min()), float(values.max())) if values.size else (-1.0, 1.0)
    pad = max(0.3 * (high - low), 0.2)
    return low - pad, high + pad


# ----------------------------------------------------------------------------- sigma
def goal_jacobian(frames: Sequence[tuple[str, str | FrameType]], rows):
    """``configuration -> J``: the frames' Jacobians stacked, ``rows`` of each (what
    :func:`qpik.analysis.analyze` takes: ``"pose"``, ``"position"``, row names...; and
    ``"planar"`` for vx, vy)."""
    planar = isinstance(rows, str) and rows == "planar"
    take = list(row_indices(("vx", "vy") if planar else rows))

    def jacobian(configuration: Configuration) -> np.ndarray:
        return np.vstack([configuration.frame_jacobian(f, t)[take] for f, t in frames])

    return jacobian


def plot_singular_values(
    model: mujoco.MjModel,
    path: np.ndarray,
    frame: str | Sequence[tuple[str, str | FrameType]],
    frame_type: str | FrameType = "site",
    rows: str = "pose",
    ax: Axes | None = None,
    **along: Unpack[PathAxis],
) -> Axes:
    """Singular values of the frame's Jacobian (``rows``: ``"pose"``, ``"position"`` or
    ``"planar"`` for vx, vy; ``frame`` may be a list of ``(name, frame_type)``, whose
    Jacobians are stacked) and the manipulability ``sqrt(det J J^T)``, along ``path``; the
    x axis as :class:`PathAxis` says (``time``, ``goal_index``, ``xlabel``)."""
    check_model_type("model", model)
    path = check_path(model, path)
    if isinstance(frame, str):
        frames = [(frame, check_frame_type("frame_type", frame_type))]
    else:
        frames = check_frames("frame", frame)
        if not frames:
            raise InvalidInput("frame is an empty sequence; name at least one frame")
    if not (isinstance(rows, str) and rows == "planar"):
        row_indices(rows)
    check_ax(ax)
    checks.check_keywords("plot_singular_values", dict(along), PathAxis)
    time = check_along("time", along.get("time"), len(path))
    goal_index = check_along("goal_index", along.get("goal_index"), len(path))
    xlabel = check_label("xlabel", along.get("xlabel"))
    configuration = Configuration(model)
    for name, kind in frames:
        configuration.frame_id(name, kind)  # an unknown frame: UnknownFrame, before drawing
    ax = axes(ax)
    jacobian = goal_jacobian(frames, rows)
    sigma_rows, measure = [], []
    for q in path:
        configuration.update(q)
        J = jacobian(configuration)
        sigma_rows.append(singular_values(J))
        measure.append(manipulability(J))
    sigmas = np.array(sigma_rows)
    x = np.arange(len(sigmas)) if time is None else time
    marker = "o" if len(sigmas) < 8 else None
    for i in range(sigmas.shape[1]):
        ax.plot(x, sigmas[:, i], lw=1.2, marker=marker, ms=3, label=f"σ{i + 1}")
    ax.plot(x, measure, "k--", lw=1.5, marker=marker, ms=3, label="manipulability")
    goal_starts(ax, x, goal_index)
    names = ", ".join(name for name, _ in frames)
    ax.set_xlabel(xlabel or ("time [s]" if time is not None else "configuration"))
    ax.set_title(f"singular values of J ({rows} rows)\n{names}", fontsize="medium")
    # (J maps joint rates to the frame's: [m/rad] for position rows of hinge joints, [1]
    # for orientation rows, [m/m] for slides; the manipulability is their product)
    unit = {"position": "[m/rad]", "planar": "[m/rad]", "orientation": "[rad/rad]"}
    ax.set_ylabel(f"σ_i {unit.get(rows, '[m/rad or rad/rad]')}; manipulability: ∏ σ_i")
    ax.grid(True, alpha=0.3)
    legend_below(ax, ncol=4)
    return ax
