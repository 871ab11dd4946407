"""``[limits]`` of a problem file: joint position limits, velocity limits [rad/s or m/s]
and the support polygon of ``[limits.support]`` (the centre of mass's ground projection
inside the contact frames' footprints)."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from ..errors import QpikError
from ..limits import SupportPolygonLimit
from ..model.configuration import Configuration, joint_names
from .reader import MAX_LENGTH, Reader, describe

_SUPPORT_KEYS = {"frames", "frame_type", "margin", "footprint"}


def read_limits(reader: Reader, data: dict, model) -> tuple[bool, np.ndarray | None]:
    """``[limits]``: joint position limits on or off, and the velocity limits (nv,)."""
    table = reader.table(
        data, "limits", "", {"position", "velocity", "support", "collision"}, "a [limits] table", {}
    )
    position = reader.get(table, "position", "limits", bool, "true or false", True)
    value = table.get("velocity", False)
    if value is False:
        return position, None
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        velocity = _velocity_scale(reader, value, model)
    elif isinstance(value, list):
        velocity = reader.vector(value, "limits.velocity", model.nv, _velocity_expected(model))
        for i, v in enumerate(velocity):
            reader.number(float(v), f"limits.velocity[{i}]", "velocity", "a velocity")
    elif isinstance(value, dict):
        velocity = _velocity_table(reader, value, model)
    else:
        raise reader.fail(
            "limits.velocity", f"expected {_velocity_expected(model)}, got {describe(value)}"
        )
    if np.any(velocity <= 0):
        raise reader.fail("limits.velocity", f"expected {_velocity_expected(model)} (all > 0)")
    return position, velocity


def _velocity_expected(model: mujoco.MjModel) -> str:
    return (
        "false, a scale of the model's velocity_limit (> 0), a list of "
        f"{model.nv} velocities [rad/s] or a table {{joint = velocity}}"
    )


def _velocity_scale(reader: Reader, value: float, model: mujoco.MjModel) -> np.ndarray:
    """``value`` times the model's velocity_limit (dofs it leaves unlimited stay inf)."""
    base = Configuration(model).velocity_limits()
    if base is None:
        raise reader.fail(
            "limits.velocity",
            "a list or table of velocities: the model declares no velocity_limit to scale",
        )
    reader.number(value, "limits.velocity", "velocity", "a scale")
    velocity = float(value) * np.asarray(base, dtype=float)
    for i in np.flatnonzero(np.isfinite(base)):
        reader.number(
            float(velocity[i]),
            f"limits.velocity (x the velocity_limit of dof {i})",
            "velocity",
            "a velocity",
        )
    return velocity


def _velocity_table(reader: Reader, value: dict, model: mujoco.MjModel) -> np.ndarray:
    """A velocity [rad/s or m/s] per joint name; every joint needs one."""
    names = joint_names(model)
    velocity = np.full(model.nv, np.inf)
    for joint, v in value.items():
        if joint not in names:
            raise reader.fail(
                f"limits.velocity.{joint}", f"a joint name, one of: {', '.join(names)}"
            )
        reader.number(v, f"limits.velocity.{joint}", "velocity", "a velocity")
        velocity[np.flatnonzero(model.dof_jntid == names.index(joint))] = float(v)
    if np.any(np.isinf(velocity)):
        missing = [names[model.dof_jntid[i]] for i in np.flatnonzero(np.isinf(velocity))]
        raise reader.fail("limits.velocity", f"a velocity for every joint; missing: {missing}")
    return velocity


def read_support(
    reader: Reader, data: dict, model: mujoco.MjModel, start: Configuration | None = None
) -> dict[str, Any] | None:
    """``[limits.support]``: the centre of mass's ground projection stays within the
    support polygon of ``frames`` (their ``footprint`` corners [m] in each frame's x-y
    axes, default its origin), ``margin`` [m] inside. With ``start``, the polygon is made
    there once, so that one that spans no area fails on load, naming the table."""
    limits = data.get("limits", {})
    if "support" not in limits:
        return None
    table = reader.table(limits, "support", "limits", _SUPPORT_KEYS, "a [limits.support] table")
    where = "limits.support"
    frames = reader.get(table, "frames", where, list, "a list of contact frame names")
    if not frames or not all(isinstance(f, str) for f in frames):
        raise reader.fail(f"{where}.frames", f"expected frame names, got {describe(frames)}")
    frame_type = reader.frame_type(table, where).value  # (named as the table's own field)
    kinds = [
        reader.frame({"frame": name, "frame_type": frame_type}, f"{where}.frames[{i}]", model)[1]
        for i, name in enumerate(frames)
    ]
    kind = kinds[0]
    out: dict[str, Any] = {"frames": list(frames), "frame_type": kind.value, "margin": 0.0}
    if "margin" in table:
        out["margin"] = float(reader.number(table["margin"], f"{where}.margin", "margin"))
    if "footprint" in table:
        points = reader.get(table, "footprint", where, list, "a list of [x, y] points [m]")
        if not points:
            raise reader.fail(f"{where}.footprint", "expected at least one [x, y] point")
        out["footprint"] = np.array(
            [
                reader.bounded_vector(
                    p, f"{where}.footprint[{i}]", 2, "[x, y] in metres", MAX_LENGTH
                )
                for i, p in enumerate(points)
            ]
        )
    if start is not None:
        frame_list = [(name, kind) for name in frames]
        try:
            normals, offsets = SupportPolygonLimit(
                model, frame_list, out["margin"], out.get("footprint")
            ).hull(start)
        except QpikError as exc:
            raise reader.fail(where, str(exc)) from exc
        radius = _inscribed_radius(normals, offsets)
        if out["margin"] > radius:
            raise reader.fail(
                f"{where}.margin",
                f"a margin the support polygon holds: {out['margin']:g} m is wider than the "
                f"largest circle inside it at the start ({radius:.4g} m), so no ground point of "
                "the centre of mass would be inside",
            )
    return out


def _inscribed_radius(normals: np.ndarray, offsets: np.ndarray) -> float:
    """The radius [m] of the largest circle inside the polygon ``normals @ p + offsets <=
    0`` (unit outward normals): ``max r`` with ``normals @ p + r <= -offsets``, a small
    linear program."""
    from scipy.optimize import linprog

    A = np.hstack([normals, np.ones((len(offsets), 1))])
    answer = linprog(
        [0.0, 0.0, -1.0], A_ub=A, b_ub=-offsets, bounds=[(None, None), (None, None), (0, None)]
    )
    return float(answer.x[2]) if answer.status == 0 else 0.0
