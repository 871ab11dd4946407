"""``[[obstacles]]`` and ``[limits.collision]`` of a problem file.

``[[obstacles]]``: geoms fixed in the world, added to the robot's model with
:func:`qpik.scene.add_obstacle` (they collide with the robot's collision geoms)::

    [[obstacles]]
    shape = "sphere"            # "sphere", "box" or "capsule"
    size = [0.06]               # MuJoCo's geom size [m]: [radius] / [hx, hy, hz] / [r, half_length]
    position = [0.4, 0.2, 0.5]  # centre [m], world frame
    name = "ball"               # optional (default obstacle<k>)

``[limits.collision]``: collision avoidance (:class:`qpik.limits.CollisionAvoidanceLimit`)
over the pairs the model's own geometry lets collide (:func:`qpik.limits.collision_pairs`):
``scene`` (robot against the world's geoms: obstacles, floor; default true), ``self``
(robot against itself, adjacent bodies excluded; default false), or explicit
``pairs = [[["link7", "hand"], ["ball"]], ...]`` (geom groups, any contact bits) instead
(then without ``scene`` and ``self``, which it replaces);
``min_distance`` [m] (default 0.005), ``detection_distance`` [m] (default 0.05, above
``min_distance``), ``gain`` in (0, 1] (default 0.85).
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from ..errors import QpikError
from ..limits import CollisionAvoidanceLimit, model_collision_limit
from ..model.scene import SHAPES, add_obstacle
from .reader import MAX_LENGTH, Reader, describe

__all__ = ["build_collision", "read_collision", "read_obstacles"]

_OBSTACLE_KEYS = {"shape", "size", "position", "name"}
_COLLISION_KEYS = {"scene", "self", "pairs", "min_distance", "detection_distance", "gain"}


def read_obstacles(reader: Reader, data: dict, model: mujoco.MjModel) -> mujoco.MjModel:
    """The model with the file's ``[[obstacles]]`` added (the model itself if none)."""
    if "obstacles" not in data:
        return model
    entries = data["obstacles"]
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise reader.fail("obstacles", f"[[obstacles]] tables, got {describe(entries)}")
    for i, entry in enumerate(entries):
        where = f"obstacles[{i}]"
        reader.unknown_keys(entry, _OBSTACLE_KEYS, where)
        shape = reader.get(entry, "shape", where, str, f"one of {', '.join(SHAPES)}")
        if shape not in SHAPES:
            raise reader.fail(f"{where}.shape", f"one of {', '.join(SHAPES)}, got {shape!r}")
        count, layout = SHAPES[shape][1], SHAPES[shape][2]
        size = entry.get("size")
        if isinstance(size, (int, float)) and not isinstance(size, bool):
            size = [size]
        sizes = reader.bounded_vector(
            size, f"{where}.size", count, f"{layout} in metres", MAX_LENGTH
        )
        if not np.all(sizes > 0):
            raise reader.fail(f"{where}.size", f"{layout}, positive numbers [m]")
        position = reader.bounded_vector(
            entry.get("position"), f"{where}.position", 3, "[x, y, z] in metres", MAX_LENGTH
        )
        name = (
            reader.get(entry, "name", where, str, "a geom name", None) if "name" in entry else None
        )
        try:
            model = add_obstacle(model, shape, sizes, position, name=name)
        except QpikError as exc:
            raise reader.fail(where, str(exc)) from exc
    return model


def read_collision(reader: Reader, data: dict, model: mujoco.MjModel) -> dict[str, Any] | None:
    """``[limits.collision]``, validated (``scene``, ``self``, ``pairs``, distances [m],
    ``gain``), or None; the limit is built once here, so that a file naming no pair fails
    on load."""
    limits = data.get("limits", {})
    if not isinstance(limits, dict) or "collision" not in limits:
        return None
    where = "limits.collision"
    table = reader.table(
        limits, "collision", "limits", _COLLISION_KEYS, "a [limits.collision] table"
    )
    out: dict[str, Any] = {
        "scene": reader.get(table, "scene", where, bool, "true or false", True),
        "self": reader.get(table, "self", where, bool, "true or false", False),
        "min_distance": 0.005,
        "detection_distance": 0.05,
        "gain": 0.85,
    }
    for key, rule in (
        ("min_distance", "distance"),
        ("detection_distance", "distance"),
        ("gain", "gain"),
    ):
        if key in table:
            out[key] = float(reader.number(table[key], f"{where}.{key}", rule))
    if "pairs" in table:
        for chooser in ("self", "scene"):  # (they choose the model's pairs: none with pairs)
            if chooser in table:
                raise reader.fail(
                    f"{where}.{chooser}",
                    f"absent where pairs are given ({chooser} chooses the model's own pairs, "
                    "which pairs replaces): give pairs, or self / scene",
                )
        pairs = reader.get(table, "pairs", where, list, "a list of [[geoms], [geoms]] pairs")
        for i, pair in enumerate(pairs):
            ok = (
                isinstance(pair, list)
                and len(pair) == 2
                and all(
                    isinstance(group, list) and group and all(isinstance(g, str) for g in group)
                    for group in pair
                )
            )
            if not ok:
                raise reader.fail(
                    f"{where}.pairs[{i}]", f"[[geom names], [geom names]], got {describe(pair)}"
                )
        out["pairs"] = pairs
    try:
        build_collision(model, out)
    except QpikError as exc:  # a geom of pairs unknown, or no pair left: name the field
        field = f"{where}.pairs" if "pairs" in out else where
        if "detection_distance" in str(exc) and "detection_distance" in table:
            field = f"{where}.detection_distance"
        raise reader.fail(field, str(exc)) from exc
    return out


def build_collision(model: mujoco.MjModel, spec: dict[str, Any]) -> CollisionAvoidanceLimit:
    """The collision limit of a validated ``[limits.collision]`` table."""
    common = {
        "gain": spec["gain"],
        "minimum_distance_from_collisions": spec["min_distance"],
        "collision_detection_distance": spec["detection_distance"],
    }
    if "pairs" in spec:
        pairs = [(list(a), list(b)) for a, b in spec["pairs"]]
        return CollisionAvoidanceLimit(model, pairs, respect_contype=False, **common)
    return model_collision_limit(model, scene=spec["scene"], self_collision=spec["self"], **common)
