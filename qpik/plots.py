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
from collections.abc import Sequence
from typing import TYPE_CHECKING, TypedDict, Unpack

import numpy as np

from .core import checks
from .core.jacobian import manipulability, row_indices, singular_values
from .errors import InvalidArgumentType, InvalidInput, MissingExtra
from .model.configuration import Configuration, FrameType, joint_names
from .model.frames import check_model_type

if TYPE_CHECKING:  # matplotlib is optional and imported lazily
    import mujoco
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d import Axes3D

    from .problem import ErrorCurve, ProblemResult

__all__ = [
    "PathAxis",
    "is_planar",
    "joint_curves",
    "plot_error_curves",
    "plot_frame_errors",
    "plot_joints",
    "plot_level_errors",
    "plot_planar_arm",
    "plot_result",
    "plot_robot",
    "plot_singular_values",
    "plot_task_errors",
    "pyplot",
    "require_matplotlib",
    "robot_segments",
]

#: Errors below this are drawn at it (log scales cannot show 0).
FLOOR = 1e-12
#: At most this many curves are named in a legend; the rest are drawn thin and grey.
MAX_NAMED = 10


def require_matplotlib():
    """The ``matplotlib`` module, or :class:`qpik.errors.MissingExtra` naming the ``plots``
    extra."""
    try:
        import matplotlib
    except ImportError as exc:
        raise MissingExtra("plotting", "plots", "matplotlib") from exc
    return matplotlib


def pyplot():
    """``matplotlib.pyplot`` (:class:`qpik.errors.MissingExtra` without matplotlib)."""
    require_matplotlib()
    import matplotlib.pyplot as plt

    return plt


# ----------------------------------------------------------------------------- checks
# Each public function checks its arguments here, once, before it draws anything: a value
# of a wrong type raises InvalidArgumentType (a TypeError), a wrong shape or a NaN
# InvalidInput (a ValueError), each naming the argument.
def _check_ax(ax, three_d: bool = False):
    """``ax``: ``None`` (new axes) or matplotlib axes (3D ones for a 3D plot)."""
    if ax is None:
        return None
    require_matplotlib()
    if three_d:
        from mpl_toolkits.mplot3d import Axes3D

        return checks.check_instance("ax", ax, Axes3D, "None or 3D matplotlib axes")
    from matplotlib.axes import Axes

    return checks.check_instance("ax", ax, Axes, "None or matplotlib axes")


def _check_path(model: mujoco.MjModel, path) -> np.ndarray:
    """``path``: configurations ``(k, nq)`` (k >= 1; one ``(nq,)`` is a path of one),
    finite, as a float array."""
    expected = f"configurations: an array (k, {model.nq}) of numbers"
    array = checks.check_array("path", path, expected)
    if array.ndim not in (1, 2):
        raise InvalidInput(f"path has shape {array.shape}; expected {expected}")
    array = np.atleast_2d(array)
    if array.shape[0] == 0 or array.shape[1] != model.nq:
        raise InvalidInput(f"path has shape {np.shape(path)}; expected {expected}")
    if not np.all(np.isfinite(array)):
        raise InvalidInput("path has NaN or infinite entries")
    return array


def _check_frame_type(name: str, value) -> FrameType:
    """A frame type: a ``FrameType`` or one of the strings body, site, geom."""
    if not isinstance(value, (str, FrameType)):
        raise InvalidArgumentType(
            name, "a frame type ('body', 'site' or 'geom')", checks.type_name(value)
        )
    return FrameType.parse(value)


def _check_frames(name: str, frames) -> list[tuple[str, FrameType]]:
    """A sequence of ``(frame name, frame type)`` pairs."""
    expected = "a sequence of (frame name, frame type) pairs"
    if isinstance(frames, (str, bytes, dict, set)) or not isinstance(frames, Sequence):
        if not (isinstance(frames, np.ndarray) and frames.ndim == 2):
            raise InvalidArgumentType(name, expected, checks.type_name(frames))
    pairs = []
    for i, pair in enumerate(frames):
        if isinstance(pair, (str, bytes)) or not isinstance(pair, (Sequence, np.ndarray)):
            raise InvalidArgumentType(f"{name}[{i}]", expected, checks.type_name(pair))
        if len(pair) != 2:
            raise InvalidInput(f"{name}[{i}] has {len(pair)} entries; expected {expected}")
        frame = checks.check_frame_name(f"{name}[{i}][0]", pair[0])
        pairs.append((frame, _check_frame_type(f"{name}[{i}][1]", pair[1])))
    return pairs


def _check_targets(targets) -> np.ndarray:
    """``targets``: positions ``(k, 3)`` [m] (a sequence of 3-vectors, maybe empty)."""
    expected = "a sequence of positions [x, y, z] (m)"
    if isinstance(targets, (set, frozenset)):
        raise InvalidArgumentType("targets", expected, checks.type_name(targets))
    array = checks.check_array("targets", targets, expected)
    if array.size == 0:
        return np.zeros((0, 3))
    if array.ndim != 2 or array.shape[1] != 3:
        raise InvalidInput(f"targets has shape {array.shape}; expected {expected}")
    if not np.all(np.isfinite(array)):
        raise InvalidInput("targets has NaN or infinite entries")
    return array


def _check_along(name: str, value, n: int) -> np.ndarray | None:
    """``time`` or ``goal_index``: ``None`` or one finite number per configuration."""
    if value is None:
        return None
    array = checks.check_vector(name, value, n)
    if name == "goal_index":
        if not np.all(array == np.round(array)):
            raise InvalidInput(f"goal_index must hold whole numbers (goal indices), got {value}")
        return array.astype(int)
    return array


def _check_label(name: str, value) -> str | None:
    """An axis label: ``None`` or a ``str``."""
    if value is None:
        return None
    return checks.check_instance(name, value, str, "a str or None")


def _axes(ax, projection: str | None = None):
    if ax is not None:
        return ax
    if projection is None:
        return pyplot().subplots()[1]
    return pyplot().figure().add_subplot(projection=projection)


def _colors() -> list[str]:
    return require_matplotlib().rcParams["axes.prop_cycle"].by_key()["color"]


def _legend_below(ax: Axes, ncol: int = 2) -> None:
    """The legend under the axes (off the data), if anything is labelled."""
    handles, labels = ax.get_legend_handles_labels()
    if not handles:
        return
    ax.legend(
        handles,
        labels,
        loc="upper center",
        bbox_to_anchor=(0.5, -0.16),
        fontsize="x-small",
        ncol=ncol,
        frameon=False,
    )


def _goal_starts(ax: Axes, x: np.ndarray, goal_index: np.ndarray | None) -> None:
    """Dotted vertical lines where a new goal (waypoint) begins, named at the top; and
    whole-number ticks when ``x`` counts iterations."""
    if np.issubdtype(np.asarray(x).dtype, np.integer):
        from matplotlib.ticker import MaxNLocator

        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    if goal_index is None:
        return
    transform = ax.get_xaxis_transform()  # x in data, y in axes fraction
    for k in np.flatnonzero(np.diff(goal_index)) + 1:
        ax.axvline(x[k], color="0.5", lw=0.8, ls=":")
        ax.text(
            x[k],
            0.99,
            f" goal {goal_index[k]}",
            transform=transform,
            fontsize="x-small",
            color="0.4",
            va="top",
        )


def is_planar(model: mujoco.MjModel) -> bool:
    """Whether every joint is a hinge about the world z axis at ``qpos0`` (the bundled
    planar arms)."""
    import mujoco

    check_model_type("model", model)
    hinge = int(mujoco.mjtJoint.mjJNT_HINGE)
    axes = Configuration(model, model.qpos0).data.xaxis
    return model.njnt > 0 and all(
        int(model.jnt_type[j]) == hinge and np.allclose(np.abs(axes[j]), [0, 0, 1])
        for j in range(model.njnt)
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
    (``group``): position-like parts [m] solid, rotation parts [rad] dashed, unitless
    errors dash-dotted; ``tolerances`` ``{unit: value}`` as grey lines of the same styles
    (for the units present)."""
    ax = _axes(ax)
    colors = _colors()
    groups = list(dict.fromkeys(curve.group or curve.label for curve in curves))
    for curve in curves:
        xs = np.arange(len(curve.values)) if x is None else x
        color = colors[groups.index(curve.group or curve.label) % len(colors)]
        unit = f" [{curve.unit}]" if curve.unit else ""
        ax.semilogy(
            xs,
            np.maximum(curve.values, FLOOR),
            _STYLE[curve.unit],
            color=color,
            lw=1.3,
            label=curve.label + unit,
        )
    units = {curve.unit for curve in curves}
    for unit, value in (tolerances or {}).items():
        if unit in units:
            ax.axhline(value, color="0.45", lw=0.9, ls=_STYLE[unit], label=f"tolerance [{unit}]")
    if curves:
        _goal_starts(ax, np.arange(len(curves[0].values)) if x is None else x, goal_index)
    ax.set_ylabel("error: [m] solid, [rad] dashed")
    ax.set_title(title)
    ax.grid(True, which="major", alpha=0.3)
    _legend_below(ax, ncol=1 if len(curves) > 6 else 2)
    return ax


_STYLE = {"m": "-", "rad": "--", "": "-."}


def plot_task_errors(result: ProblemResult, ax: Axes | None = None) -> Axes:
    """Each task's error along the path, one colour per task, level in the label (see
    :meth:`qpik.problem.ProblemResult.task_errors`), with the tolerances."""
    _check_result(result)
    _check_ax(ax)
    return _plot_path_errors(result, result.task_errors(), ax, "task error per priority level")


def plot_frame_errors(result: ProblemResult, ax: Axes | None = None) -> Axes:
    """Each goal frame's position [m] and rotation [rad] error along the path (blank
    while the goal being reached does not name the frame), with the tolerances."""
    _check_result(result)
    _check_ax(ax)
    return _plot_path_errors(result, result.frame_errors(), ax, "error per goal frame")


def _check_result(result) -> None:
    """``result``: a :class:`qpik.problem.ProblemResult`."""
    from .problem import ProblemResult

    checks.check_instance("result", result, ProblemResult, "a qpik.problem.ProblemResult")


def _plot_path_errors(
    result: ProblemResult, curves: Sequence[ErrorCurve], ax: Axes | None, title: str
) -> Axes:
    x, xlabel = _path_axis(result)
    ax = plot_error_curves(curves, ax, x, result.goal_index, _tolerances(result), title)
    ax.set_xlabel(xlabel)
    return ax


def _tolerances(result: ProblemResult) -> dict[str, float]:
    options = result.problem.solve_options
    return {"m": options.tol_position, "rad": options.tol_orientation}


def _path_axis(result: ProblemResult) -> tuple[np.ndarray, str]:
    """x values of :attr:`ProblemResult.path` and their label."""
    n = len(result.path)
    if result.trace is not None:
        return np.arange(n) * result.trace.dt, "time [s]"
    return np.arange(n), "iteration (all goals)"


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
        or np.ndim(residual_history) == 0
    ):
        raise InvalidArgumentType("residual_history", expected, checks.type_name(residual_history))
    history = [
        checks.check_vector(f"residual_history[{i}]", row, finite=False)
        for i, row in enumerate(residual_history)
    ]
    _check_ax(ax)
    xlabel = checks.check_instance("xlabel", xlabel, str, "a str")
    if goal_error is not None:
        goal_error = checks.check_vector("goal_error", goal_error, finite=False)
    ax = _axes(ax)
    if goal_error is not None:
        ax.semilogy(
            np.arange(len(goal_error)),
            np.maximum(goal_error, FLOOR),
            "k:",
            lw=1.5,
            label="goal position error [m]",
        )
    levels = max((len(row) for row in history), default=0)
    for level in range(levels):
        values = np.array([row[level] if level < len(row) else np.nan for row in history])
        ax.semilogy(
            np.arange(1, len(values) + 1), np.maximum(values, FLOOR), label=f"level {level}"
        )
    ax.set_xlabel(xlabel)
    _goal_starts(ax, np.arange(1, len(history) + 1), None)
    ax.set_ylabel("|A_k dq - b_k|")
    ax.set_title("QP residual per level, per step")
    ax.grid(True, which="major", alpha=0.3)
    _legend_below(ax, ncol=3)
    return ax


# ----------------------------------------------------------------------------- joints
def joint_curves(model: mujoco.MjModel, path: np.ndarray) -> list[tuple[str, np.ndarray, tuple]]:
    """What :func:`plot_joints` draws: per curve ``(label, values (k,), (lower, upper))``.

    A hinge or slide joint is its ``q`` [rad or m] with its range; a ball joint its
    rotation angle ``2 atan2(|xyz|, |w|)`` [rad] with ``[0, range]`` when limited; a free
    joint its position x, y, z [m] and rotation angle [rad] (no limits)."""
    import mujoco

    check_model_type("model", model)
    path = _check_path(model, path)
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


class PathAxis(TypedDict, total=False):
    """The x axis of a plot along a path: ``time`` ``(k,)`` [s] (default: the index),
    ``goal_index`` ``(k,)`` (the goal each point belongs to; its starts are marked) and
    ``xlabel``."""

    time: np.ndarray | None
    goal_index: np.ndarray | None
    xlabel: str | None


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
    path = _check_path(model, path)
    _check_ax(ax)
    time = _check_along("time", time, len(path))
    goal_index = _check_along("goal_index", goal_index, len(path))
    xlabel = _check_label("xlabel", xlabel)
    ax = _axes(ax)
    x = np.arange(len(path)) if time is None else time
    colors = _colors()
    curves = joint_curves(model, path)
    motion = [float(np.ptp(values)) for _, values, _ in curves]
    named = set(np.argsort(motion)[::-1][:MAX_NAMED]) if len(curves) > MAX_NAMED else None
    marker = "o" if len(path) < 8 else None
    low, high = _near_range([values for _, values, _ in curves])
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
    _goal_starts(ax, x, goal_index)
    ax.set_xlabel(xlabel or ("time [s]" if time is not None else "configuration"))
    ax.set_ylabel("q [rad or m]")
    ax.set_title("joints along the path (limits in view dotted)")
    ax.grid(True, alpha=0.3)
    _legend_below(ax, ncol=3)
    return ax


def _near_range(curves: Sequence[np.ndarray]) -> tuple[float, float]:
    """The y range of the curves, padded by 30 % of their span (at least 0.2): limits
    inside it are close enough to the motion to draw."""
    values = np.concatenate([np.ravel(c) for c in curves])
    values = values[np.isfinite(values)]
    low, high = (float(values.min()), float(values.max())) if values.size else (-1.0, 1.0)
    pad = max(0.3 * (high - low), 0.2)
    return low - pad, high + pad


# ----------------------------------------------------------------------------- sigma
def _goal_jacobian(frames: Sequence[tuple[str, str | FrameType]], rows):
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
    path = _check_path(model, path)
    if isinstance(frame, str):
        frames = [(frame, _check_frame_type("frame_type", frame_type))]
    else:
        frames = _check_frames("frame", frame)
        if not frames:
            raise InvalidInput("frame is an empty sequence; name at least one frame")
    if not (isinstance(rows, str) and rows == "planar"):
        row_indices(rows)
    _check_ax(ax)
    checks.check_keywords("plot_singular_values", dict(along), PathAxis)
    time = _check_along("time", along.get("time"), len(path))
    goal_index = _check_along("goal_index", along.get("goal_index"), len(path))
    xlabel = _check_label("xlabel", along.get("xlabel"))
    configuration = Configuration(model)
    for name, kind in frames:
        configuration.frame_id(name, kind)  # an unknown frame: UnknownFrame, before drawing
    ax = _axes(ax)
    jacobian = _goal_jacobian(frames, rows)
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
    _goal_starts(ax, x, goal_index)
    names = ", ".join(name for name, _ in frames)
    ax.set_xlabel(xlabel or ("time [s]" if time is not None else "configuration"))
    ax.set_title(f"singular values of J ({rows} rows)\n{names}", fontsize="medium")
    ax.grid(True, alpha=0.3)
    _legend_below(ax, ncol=4)
    return ax


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
    frames = _check_frames("frames", frames)
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


def _picks(n: int, intermediate: int) -> np.ndarray:
    return np.unique(np.linspace(0, n - 1, intermediate + 2).round().astype(int))


def _frame_trace(configuration, path, frames) -> list[np.ndarray]:
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
    path = _check_path(model, path)
    target_points = _check_targets(targets)
    frames = _check_frames("frames", frames)
    _check_ax(ax, three_d=True)
    intermediate = checks.check_integer("intermediate", intermediate, 0, 10_000)
    elevation, azimuth = checks.check_vector("view", view, 2)
    configuration = Configuration(model)
    for name, kind in frames:
        configuration.frame_id(name, kind)  # an unknown frame: UnknownFrame, before drawing
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    ax3d: Axes3D = _axes(ax, projection="3d")
    picks = _picks(len(path), intermediate)
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
    for k, trace in enumerate(_frame_trace(configuration, path, frames)):
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
    _equal_3d(ax3d, np.vstack(points))
    ax3d.view_init(float(elevation), float(azimuth))
    ax3d.set_xlabel("x [m]", fontsize="small")
    ax3d.set_ylabel("y [m]", fontsize="small")
    ax3d.set_zlabel("z [m]", fontsize="small")
    ax3d.tick_params(labelsize="x-small")
    from matplotlib.ticker import MaxNLocator

    for axis in (ax3d.xaxis, ax3d.yaxis, ax3d.zaxis):
        axis.set_major_locator(MaxNLocator(4))
    ax3d.set_title("robot: start, intermediate, final")
    _legend_below(ax3d, ncol=2)
    return ax3d


def _equal_3d(ax, points: np.ndarray) -> None:
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
    path = _check_path(model, path)
    target_points = _check_targets(targets)
    frame = checks.check_frame_name("frame", frame)
    frame_type = _check_frame_type("frame_type", frame_type)
    _check_ax(ax)
    intermediate = checks.check_integer("intermediate", intermediate, 0, 10_000)
    configuration = Configuration(model)
    configuration.frame_id(frame, frame_type)  # an unknown frame: UnknownFrame, before drawing
    ax = _axes(ax)
    (tip,) = _frame_trace(configuration, path, [(frame, frame_type)])
    ax.plot(tip[:, 0], tip[:, 1], color="tab:orange", lw=1, label="tip path")
    picks = _picks(len(path), intermediate)
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
    _legend_below(ax, ncol=4)
    return ax


# ----------------------------------------------------------------------------- figure
def plot_result(
    result: ProblemResult, path: str | os.PathLike | None = None, dpi: int = 80
) -> Figure:
    """A figure of a :class:`qpik.problem.ProblemResult`: task error per level and error
    per goal frame (top), joints and singular values of the goal frames' Jacobian
    (bottom), all along the path, and the robot on the right (3D, or from above for
    planar arms). The QP residual per step is :func:`plot_level_errors`'s. Saved to
    ``path`` when given (drawn on a bare :class:`matplotlib.figure.Figure`, Agg canvas: no
    GUI, pyplot's state untouched); returns the figure."""
    _check_result(result)
    if path is not None:
        path = checks.check_path("path", path)
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
    x, xlabel = _path_axis(result)
    time = x if result.trace is not None else None
    plot_task_errors(result, fig.add_subplot(grid[0, 0]))
    plot_frame_errors(result, fig.add_subplot(grid[0, 1]))
    frames = list(dict.fromkeys((f.frame, f.frame_type) for g in problem.goals for f in g.frames))
    targets = [f.target.position for g in problem.goals for f in g.frames]
    if planar:
        plot_planar_arm(model, result.path, targets, *frames[0], fig.add_subplot(grid[:, 2]))
    else:
        plot_robot(
            model, result.path, targets, frames, fig.add_subplot(grid[:, 2], projection="3d")
        )
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
