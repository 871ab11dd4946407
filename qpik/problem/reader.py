"""Reading a problem file: the TOML text, and typed access to its tables.

Every failure raises :class:`qpik.ProblemFileError` naming the file, the field (dotted:
``levels[0].tasks[1].type``) and what was expected. The value readers here know nothing
of tasks, goals or modes; :mod:`qpik.problem.specs` and :mod:`qpik.problem.loader` say
which field holds what.

Units: metres, radians, seconds, newtons; positions and rotations in the world frame.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..core import checks
from ..errors import ProblemFileError, QpikError
from ..model.configuration import Configuration, FrameType
from ..model.frames import frame_id
from ..model.robots import tool_frame
from ..model.rotations import (
    nearest_rotation,
    quaternion_to_matrix,
    rotation_defect,
    rpy_to_matrix,
)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: Largest magnitude of a length [m] (target positions, centre of mass, joint values in a
#: posture or q0 [rad or m]) a file may give: beyond it a squared error overflows.
MAX_LENGTH = 1e6
#: Largest magnitude of an angle [rad] in ``rpy``.
MAX_ANGLE = 100.0
#: Largest task cost or weight: the QP holds its square next to unit-scale terms.
MAX_COST = 1e6
#: Largest force [N] or torque [N m] of a ``[statics]`` table.
MAX_WRENCH = 1e9

#: Allowed range ``(low, high, low_open)`` of every number of ``[solver]``, ``[track]``
#: and the task options, inclusive (``low_open``: ``low`` itself excluded).
RANGES: dict[str, tuple[float, float, bool]] = {
    "solver.tol_position": (1e-12, 1e3, False),  # [m]
    "solver.tol_orientation": (1e-12, math.pi, False),  # [rad]
    "solver.max_iters": (1, 100_000, False),
    "solver.restarts": (0, 100_000, False),
    "solver.seed": (0, 2**63 - 1, False),
    "solver.time_budget": (0.0, 86_400.0, True),  # [s]
    "solver.alpha": (0.0, 1.0, True),
    "solver.beta": (0.0, 100.0, True),
    "solver.max_step": (0.0, MAX_LENGTH, True),  # [m, rad]
    "solver.singular_threshold": (0.0, 1e3, False),
    "solver.max_damping": (0.0, 1e6, False),
    "solver.lower_trust": (0.0, 1.0, False),
    "solver.damping": (0.0, 1e6, False),
    "solver.stall_window": (1, 100_000, False),
    "track.dt": (1e-9, 1e3, False),  # [s]
    "track.steps": (1, 1_000_000, False),
    "gain": (0.0, 1.0, True),
    "lm_damping": (0.0, 1e6, False),
    "velocity": (1e-9, 1e6, False),  # [rad/s or m/s]
    "margin": (0.0, 1.0, False),  # [m]
    "distance": (0.0, MAX_LENGTH, False),  # [m] ([limits.collision])
}

#: The keys of a rotation, at most one per table.
ROTATION_KEYS = ("rpy", "quaternion", "matrix")

_MISSING: Any = object()


def describe(value: object) -> str:
    """``value`` for a message: its TOML kind and its text, cut at 40 characters."""
    kind = {
        bool: "a boolean",
        int: "an integer",
        float: "a number",
        str: "a string",
        list: "a list",
        dict: "a table",
    }.get(type(value), type(value).__name__)
    text = repr(value)
    return f"{kind} ({text if len(text) <= 40 else text[:37] + '...'})"


def dotted(where: str, key: str | int) -> str:
    """The field name of ``key`` inside ``where`` (``levels[0]`` + ``tasks``)."""
    if isinstance(key, int):
        return f"{where}[{key}]"
    return f"{where}.{key}" if where else key


def read_toml(path: Path) -> dict:
    """The parsed TOML document at ``path`` (UTF-8, a byte-order mark allowed)."""
    name = str(path)
    try:
        raw = path.read_bytes()
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the path
        reason = getattr(exc, "strerror", None) or exc
        raise ProblemFileError(name, "(file)", f"a readable TOML file ({reason})") from exc
    text = checks.utf8_text(raw, name, "(file)", "UTF-8 text (TOML)")  # (a BOM is harmless)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ProblemFileError(name, "(file)", f"valid TOML ({exc})") from exc
    except RecursionError:
        raise ProblemFileError(
            name, "(file)", "TOML nested at most a few hundred levels deep (arrays or tables)"
        ) from None


class Reader:
    """Typed access to the parsed tables of one file; every failure is a
    :class:`qpik.ProblemFileError` naming the file and the field."""

    _EXPECTED = {str: "a string", float: "a number", int: "an integer", bool: "true or false"}

    def __init__(self, path: str):
        self.path = path

    def fail(self, field_name: str, expected: str) -> ProblemFileError:
        """The error to raise for ``field_name``."""
        return ProblemFileError(self.path, field_name, expected)

    def get(
        self,
        table: dict,
        key: str,
        where: str,
        kind,
        expected: str | None = None,
        default: Any = _MISSING,
    ) -> Any:
        """``table[key]`` of type ``kind`` (an int is accepted as a float, a bool never as
        a number); ``default`` when absent, else the field is required."""
        name = dotted(where, key)
        expected = expected or self._EXPECTED.get(kind, "a value")
        if key not in table:
            if default is _MISSING:
                raise self.fail(name, f"missing; expected {expected}")
            return default
        value = table[key]
        if kind is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if kind in (int, float) and isinstance(value, bool):
            raise self.fail(name, f"expected {expected}, got {value!r}")
        if not isinstance(value, kind):
            raise self.fail(name, f"expected {expected}, got {describe(value)}")
        return value

    def vector(self, value, name: str, size: int | None, expected: str) -> np.ndarray:
        """A finite vector of ``size`` numbers (any size when None)."""
        if not isinstance(value, list) or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) for x in value
        ):
            raise self.fail(name, f"expected {expected}, got {describe(value)}")
        array = np.asarray(value, dtype=float)
        if size is not None and array.shape != (size,):
            raise self.fail(name, f"expected {expected}, got {len(value)} numbers")
        if not np.all(np.isfinite(array)):
            raise self.fail(name, f"expected {expected} (finite), got {value!r}")
        return array

    def number(self, value, name: str, rule: str, expected: str | None = None) -> float:
        """Check a number against :data:`RANGES` ``[rule]``: finite, within the range."""
        low, high, low_open = RANGES[rule]
        interval = f"{'(' if low_open else '['}{low:g}, {high:g}]"
        expected = f"{expected or 'a number'} in {interval}"
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(name, f"expected {expected}, got {describe(value)}")
        finite = isinstance(value, int) or math.isfinite(value)  # ints: no float overflow
        ok = finite and (value > low if low_open else value >= low) and value <= high
        if not ok:
            raise self.fail(name, f"expected {expected}, got {value!r}")
        return value

    def bounded_vector(
        self, value, name: str, size: int | None, expected: str, bound: float
    ) -> np.ndarray:
        """:meth:`vector` whose entries are at most ``bound`` in magnitude."""
        array = self.vector(value, name, size, expected)
        big = np.flatnonzero(np.abs(array) > bound)
        if big.size:
            i = int(big[0])
            raise self.fail(
                name,
                f"expected {expected}, each within [-{bound:g}, {bound:g}]; "
                f"entry {i} is {float(array[i])!r}",
            )
        return array

    def position(self, table: dict, key: str, where: str) -> np.ndarray:
        """A required point ``[x, y, z]`` [m] within :data:`MAX_LENGTH`."""
        expected = "[x, y, z] in metres"
        value = self.get(table, key, where, list, expected)
        return self.bounded_vector(value, dotted(where, key), 3, expected, MAX_LENGTH)

    def table(
        self,
        data: dict,
        key: str,
        where: str,
        allowed: Iterable[str],
        expected: str,
        default: Any = _MISSING,
    ) -> dict:
        """The sub-table ``data[key]``, with only ``allowed`` keys."""
        table = self.get(data, key, where, dict, expected, default)
        self.unknown_keys(table, allowed, dotted(where, key))
        return table

    def unknown_keys(self, table: dict, allowed: Iterable[str], where: str) -> None:
        """Raise on the first key of ``table`` not in ``allowed`` (typos are errors)."""
        allowed = set(allowed)
        for key in table:
            if key not in allowed:
                raise self.fail(
                    dotted(where, key),
                    f"unknown field; expected one of: {', '.join(sorted(allowed))}",
                )

    # ------------------------------------------------------------ robot-aware values
    def rotation(self, table: dict, where: str) -> np.ndarray | None:
        """The rotation matrix of ``rpy`` / ``quaternion`` / ``matrix`` in ``table``, if
        any (``rpy``: extrinsic x-y-z, ``R = Rz(yaw) Ry(pitch) Rx(roll)``)."""
        given = [k for k in ROTATION_KEYS if k in table]
        if len(given) > 1:
            raise self.fail(
                f"{where}.{given[1]}", f"give at most one of {', '.join(ROTATION_KEYS)}"
            )
        if not given:
            return None
        key = given[0]
        name = f"{where}.{key}"
        if key == "rpy":
            roll, pitch, yaw = self.bounded_vector(
                table[key], name, 3, "[roll, pitch, yaw] in radians", MAX_ANGLE
            )
            return rpy_to_matrix(roll, pitch, yaw)
        if key == "quaternion":
            return self._quaternion(table[key], name)
        return self._matrix(table[key], name)

    def _quaternion(self, value, name: str) -> np.ndarray:
        quat = self.vector(value, name, 4, "[w, x, y, z] (nonzero)")
        scale = float(np.max(np.abs(quat)))
        if scale > 0.0:  # scaled first: the norm of [1e300, ...] would overflow
            quat = quat / scale
        if scale == 0.0 or float(np.linalg.norm(quat)) * scale < 1e-9:
            raise self.fail(name, "expected a nonzero quaternion [w, x, y, z]")
        return quaternion_to_matrix(quat)

    def _matrix(self, rows, name: str) -> np.ndarray:
        if not isinstance(rows, list) or len(rows) != 3:
            raise self.fail(name, f"expected 3 rows of 3 numbers, got {describe(rows)}")
        matrix = np.array(
            [self.vector(r, f"{name}[{i}]", 3, "3 numbers") for i, r in enumerate(rows)]
        )
        if not rotation_defect(matrix) <= 1e-6:
            raise self.fail(name, "expected a rotation matrix (R R^T = I, det R = +1)")
        return nearest_rotation(matrix)

    def configuration(
        self,
        value,
        name: str,
        model: mujoco.MjModel,
        start: Configuration,
        *,
        allow_start: bool,
    ) -> np.ndarray:
        """A configuration ``(nq,)`` from a list of ``nq`` numbers or a name: ``"mid"``,
        ``"qpos0"``, ``"start"`` (when ``allow_start``) or a keyframe of the model."""
        # keyframes by name, with their own index (unnamed keyframes cannot be chosen)
        named: dict[str, int] = {}
        for k in range(model.nkey):
            key_name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, k)
            if key_name and key_name not in named:
                named[key_name] = k
        names = ["mid", "qpos0"] + (["start"] if allow_start else []) + list(named)
        expected = f"a list of {model.nq} numbers or one of: {', '.join(names)}"
        if not isinstance(value, str):
            return self.bounded_vector(value, name, model.nq, expected, MAX_LENGTH)
        if value == "mid":
            return start.mid_q()
        if value == "qpos0":
            return model.qpos0.copy()
        if value == "start" and allow_start:
            return start.q
        if value not in named:
            raise self.fail(name, f"expected {expected}, got {value!r}")
        q = model.key_qpos[named[value]].copy()
        if not np.all(np.isfinite(q)):
            raise self.fail(name, f"keyframe {value!r} of the model has non-finite qpos")
        return q

    def frame_type(self, table: dict, where: str) -> FrameType:
        """``table``'s ``frame_type`` (default ``site``), named ``where.frame_type``."""
        kind_text = self.get(table, "frame_type", where, str, "site, body or geom", "site")
        try:
            return FrameType.parse(kind_text)
        except QpikError as exc:
            raise self.fail(f"{where}.frame_type", str(exc)) from exc

    def frame(self, table: dict, where: str, model: mujoco.MjModel) -> tuple[str, FrameType]:
        """``frame`` and ``frame_type`` (default ``site``) of ``table``, checked against
        the model; both left out: the robot's tool frame (:func:`qpik.robots.tool_frame`)."""
        if "frame" not in table and "frame_type" not in table:
            tool = tool_frame(model)
            return tool.name, FrameType(tool.frame_type)
        frame = self.get(table, "frame", where, str, "a frame name (e.g. 'ee')")
        kind = self.frame_type(table, where)
        try:
            frame_id(model, frame, kind)
        except QpikError as exc:  # UnknownFrame: lists the valid names
            raise self.fail(f"{where}.frame", str(exc)) from exc
        return frame, kind

    def cost(
        self, table: dict, key: str, where: str, size: int | None, default: float
    ) -> float | np.ndarray:
        """A cost in [0, :data:`MAX_COST`]: a number, or (``size`` given) ``size`` numbers."""
        if key not in table:
            return default
        value = table[key]
        name = f"{where}.{key}"
        interval = f"in [0, {MAX_COST:g}]"
        expected = f"a number {interval}" + (
            f" or a list of {size} numbers {interval}" if size else ""
        )
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            cost = float(value)
            if not (math.isfinite(cost) and 0 <= cost <= MAX_COST):
                raise self.fail(name, f"expected {expected}, got {value!r}")
            return cost
        if size is None:
            raise self.fail(name, f"expected {expected}, got {describe(value)}")
        vector = self.bounded_vector(value, name, size, expected, MAX_COST)
        if np.any(vector < 0):
            raise self.fail(name, f"expected {expected}, got {value!r}")
        return vector

    def direction(self, value, name: str) -> np.ndarray:
        """A unit direction from a nonzero ``[x, y, z]`` (normalised without overflow)."""
        direction = self.bounded_vector(value, name, 3, "a nonzero direction [x, y, z]", MAX_WRENCH)
        scale = float(np.max(np.abs(direction)))
        if scale == 0.0:
            raise self.fail(name, "expected a nonzero direction [x, y, z]")
        direction = direction / scale  # scaled first: no underflow / overflow in the norm
        return direction / np.linalg.norm(direction)
