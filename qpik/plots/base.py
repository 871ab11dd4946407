"""What every figure of :mod:`qpik.plots` shares: matplotlib imported on first use, the
checks of the arguments, axes, colours, legends and goal markers."""

from __future__ import annotations

import os
from collections.abc import Sequence
from types import ModuleType
from typing import TYPE_CHECKING, TypedDict

import numpy as np

from ..core import checks
from ..errors import InvalidArgumentType, InvalidInput, MissingExtra
from ..model.configuration import Configuration, FrameType
from ..model.frames import check_model_type

if TYPE_CHECKING:  # matplotlib is optional and imported lazily
    import mujoco
    from matplotlib.axes import Axes


#: Errors below this are drawn at it (log scales cannot show 0).
FLOOR = 1e-12
#: At most this many curves are named in a legend; the rest are drawn thin and grey.
MAX_NAMED = 10


def require_matplotlib() -> ModuleType:
    """The ``matplotlib`` module, or :class:`qpik.errors.MissingExtra` naming the ``plots``
    extra."""
    try:
        import matplotlib
    except ImportError as exc:
        raise MissingExtra("plotting", "plots", "matplotlib") from exc
    return matplotlib


def check_figure_path(name: str, value: object) -> str:
    """``value`` as the path of a figure file (``str`` or ``os.PathLike``) whose extension
    matplotlib writes (``.png``, ``.pdf``, ``.svg``, ...) with what this machine has
    (:func:`missing_tool`: ``.pgf`` needs a TeX program); else :class:`InvalidInput` (a
    path of another type: :class:`InvalidArgumentType`) naming ``name``, as is a path whose
    folder does not exist. Needs matplotlib (:class:`qpik.errors.MissingExtra` without
    it): check before a long computation."""
    path = checks.check_path(name, value)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise InvalidInput(f"{name} {path!r}: its folder {folder!r} does not exist")
    require_matplotlib()
    from matplotlib.backend_bases import FigureCanvasBase

    formats = sorted(FigureCanvasBase.get_supported_filetypes())
    suffix = os.path.splitext(path)[1].lower().lstrip(".")
    if suffix not in formats:
        raise InvalidInput(
            f"{name} {path!r}: a figure file ending in one of "
            f"{', '.join('.' + f for f in formats)} (its extension names the format)"
        )
    missing = missing_tool(suffix)
    if missing is not None:
        raise InvalidInput(
            f"{name} {path!r}: the .{suffix} format needs {missing}; install it or choose "
            ".png, .pdf or .svg"
        )
    return path


#: The formats matplotlib writes through Agg and Pillow (which may lack a codec).
_PILLOW_FEATURES = {"jpg": "jpg", "jpeg": "jpg", "webp": "webp", "avif": "avif"}
_RASTER = ("png", "jpg", "jpeg", "tif", "tiff", "gif", "webp", "avif", "raw", "rgba")


def missing_tool(suffix: str) -> str | None:
    """What a figure format needs that this machine lacks, said in words (``None`` when
    nothing is missing): a program that matplotlib runs (``.pgf``: the TeX of
    ``rcParams['pgf.texsystem']``; ``rcParams['text.usetex']``: latex, and dvipng or
    dvips and Ghostscript; ``rcParams['ps.usedistiller']``: Ghostscript or xpdf's
    pdftops), or Pillow's codec (``.jpg``, ``.webp``, ``.avif``). Checked before a long
    computation, as the figure's file name is, so that it does not fail once drawn."""
    import shutil

    rc = require_matplotlib().rcParams
    programs: list[tuple[str, str]] = []  # (program, why)
    if suffix == "pgf":
        programs.append((rc["pgf.texsystem"], "rcParams['pgf.texsystem']"))
    if rc["text.usetex"]:
        programs.append(("latex", "rcParams['text.usetex']"))
        if suffix in _RASTER:
            programs.append(("dvipng", "rcParams['text.usetex']"))
        elif suffix in ("ps", "eps"):
            programs += [("dvips", "rcParams['text.usetex']"), ("gs", "rcParams['text.usetex']")]
    distiller = rc["ps.usedistiller"] if suffix in ("ps", "eps") else None
    if distiller in ("ghostscript", "xpdf"):
        programs.append(("gs", "rcParams['ps.usedistiller']"))
        if distiller == "xpdf":
            programs.append(("pdftops", "rcParams['ps.usedistiller']"))
    for program, why in programs:
        if shutil.which(program) is None:
            return f"the program {program!r} ({why}), not found on PATH"
    feature = _PILLOW_FEATURES.get(suffix)
    if feature is not None:
        from PIL import features

        if not features.check(feature):
            return f"Pillow built with {feature} support (matplotlib writes .{suffix} by Pillow)"
    return None


def pyplot() -> ModuleType:
    """``matplotlib.pyplot`` (:class:`qpik.errors.MissingExtra` without matplotlib)."""
    require_matplotlib()
    import matplotlib.pyplot as plt

    return plt


# ----------------------------------------------------------------------------- checks
# Each public function checks its arguments here, once, before it draws anything: a value
# of a wrong type raises InvalidArgumentType (a TypeError), a wrong shape or a NaN
# InvalidInput (a ValueError), each naming the argument.
def check_ax(ax, three_d: bool = False):
    """``ax``: ``None`` (new axes) or matplotlib axes (3D ones for a 3D plot)."""
    if ax is None:
        return None
    require_matplotlib()
    if three_d:
        from mpl_toolkits.mplot3d import Axes3D

        return checks.check_instance("ax", ax, Axes3D, "None or 3D matplotlib axes")
    from matplotlib.axes import Axes

    return checks.check_instance("ax", ax, Axes, "None or matplotlib axes")


def check_path(model: mujoco.MjModel, path) -> np.ndarray:
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


def check_frame_type(name: str, value) -> FrameType:
    """A frame type: a ``FrameType`` or one of the strings body, site, geom."""
    if not isinstance(value, (str, FrameType)):
        raise InvalidArgumentType(
            name, "a frame type ('body', 'site' or 'geom')", checks.type_name(value)
        )
    return FrameType.parse(value)


def check_frames(name: str, frames) -> list[tuple[str, FrameType]]:
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
        pairs.append((frame, check_frame_type(f"{name}[{i}][1]", pair[1])))
    return pairs


def check_targets(targets) -> np.ndarray:
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


def check_task_targets(task_targets) -> list[tuple[str, np.ndarray]]:
    """``task_targets``: ``(label, position (3,) [m])`` pairs (maybe none)."""
    expected = "a sequence of (label, [x, y, z]) pairs (m)"
    if not isinstance(task_targets, Sequence) or isinstance(task_targets, (str, bytes)):
        raise InvalidArgumentType("task_targets", expected, checks.type_name(task_targets))
    out = []
    for k, item in enumerate(task_targets):
        if not isinstance(item, (tuple, list)) or len(item) != 2 or not isinstance(item[0], str):
            raise InvalidArgumentType(f"task_targets[{k}]", expected, checks.type_name(item))
        out.append((item[0], checks.check_vector(f"task_targets[{k}]", item[1], 3)))
    return out


def check_along(name: str, value, n: int) -> np.ndarray | None:
    """``time`` or ``goal_index``: ``None`` or one finite number per configuration."""
    if value is None:
        return None
    array = checks.check_vector(name, value, n)
    if name == "goal_index":
        if not np.all(array == np.round(array)):
            raise InvalidInput(f"goal_index must hold whole numbers (goal indices), got {value}")
        return array.astype(int)
    return array


def check_label(name: str, value) -> str | None:
    """An axis label: ``None`` or a ``str``."""
    if value is None:
        return None
    return checks.check_instance(name, value, str, "a str or None")


def axes(ax, projection: str | None = None):
    if ax is not None:
        return ax
    if projection is None:
        return pyplot().subplots()[1]
    return pyplot().figure().add_subplot(projection=projection)


def palette() -> list[str]:
    return require_matplotlib().rcParams["axes.prop_cycle"].by_key()["color"]


def legend_below(ax: Axes, ncol: int = 2) -> None:
    """The legend under the axes (off the data), if anything is labelled; a curve drawn
    under a later one (a humanoid's left and right feet, an arm at rest by mid-path) says
    so in its entry, which would otherwise show a line
    nowhere to be seen (within a pixel of it as drawn)."""
    handles, labels = ax.get_legend_handles_labels()
    if not handles:
        return
    labels = _hidden_noted(ax, handles, labels)
    ax.legend(
        handles,
        labels,
        loc="upper center",
        bbox_to_anchor=(0.5, -0.16),
        fontsize="small",
        ncol=ncol,
        frameon=False,
    )


def _hidden_noted(ax: Axes, handles: list, labels: list[str]) -> list[str]:
    """``labels``, each line's that a later line covers on the drawn axes (the same x, its
    points within a pixel of the later one's, as the axes' current limits place them)
    followed by ``(under <the later one's label>)``."""
    out = list(labels)
    if hasattr(ax, "get_zlim"):  # (3D axes: a line's x, y say nothing of where it is drawn)
        return out
    ax.get_xlim(), ax.get_ylim()  # (the limits autoscaled now: the transform is current)
    data = []
    for handle in handles:
        get = getattr(handle, "get_data", None)
        points = None
        if get is not None:
            x, y = (np.asarray(v, dtype=float) for v in get())
            if x.ndim == 1 and x.shape == y.shape and len(x) and handle.get_visible():
                with np.errstate(all="ignore"):
                    pixels = ax.transData.transform(np.column_stack([x, y]))
                points = (x, pixels[:, 1])
        data.append(points)
    for i, first in enumerate(data):
        for j in range(i + 1, len(data)):
            later = data[j]
            if first is None or later is None or first[0].shape != later[0].shape:
                continue
            if not np.array_equal(first[0], later[0], equal_nan=True):
                continue
            a, b = first[1], later[1]
            shown = np.isfinite(a) & np.isfinite(b)
            if np.array_equal(np.isfinite(a), np.isfinite(b)) and shown.any():
                if np.abs(a[shown] - b[shown]).max() <= 1.0:
                    out[i] = f"{labels[i]} (under {labels[j]})"
                    break
    return out


def lone_points(values: np.ndarray) -> dict:
    """The keywords of ``ax.plot`` that mark with a dot each point of a curve ``values``
    (``(k,)``, or ``(k, d)``: a point per row) that no line reaches: finite, its
    neighbours not (a path of one configuration, a value between blanks). A line alone
    would draw nothing there; ``{}`` when every point is on a line."""
    finite = np.isfinite(np.asarray(values, dtype=float))
    if finite.ndim > 1:
        finite = finite.all(axis=tuple(range(1, finite.ndim)))
    before = np.concatenate(([False], finite[:-1]))
    after = np.concatenate((finite[1:], [False]))
    lone = np.flatnonzero(finite & ~before & ~after)
    if lone.size == 0:
        return {}
    return {"marker": "o", "markevery": lone.tolist(), "ms": 4}


def goal_starts(ax: Axes, x: np.ndarray, goal_index: np.ndarray | None) -> None:
    """Dotted vertical lines where a new goal (waypoint) begins, named at the top; and
    whole-number ticks when ``x`` counts iterations (a path of one point: the x axis
    from one before it to one after)."""
    if np.issubdtype(np.asarray(x).dtype, np.integer):
        from matplotlib.ticker import MaxNLocator

        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        if len(x) and np.min(x) == np.max(x):
            ax.set_xlim(float(x[0]) - 1.0, float(x[0]) + 1.0)
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


class PathAxis(TypedDict, total=False):
    """The x axis of a plot along a path: ``time`` ``(k,)`` [s] (default: the index),
    ``goal_index`` ``(k,)`` (the goal each point belongs to; its starts are marked) and
    ``xlabel``."""

    time: np.ndarray | None
    goal_index: np.ndarray | None
    xlabel: str | None
