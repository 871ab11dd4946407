"""Scenes: obstacles added to a robot model, for collision avoidance.

:func:`add_obstacle` returns a *new* model with one more geom fixed in the world (the
model passed in is left as it was): a ``"sphere"`` (``size = [radius]``), a ``"box"``
(``size = [half_x, half_y, half_z]``) or a ``"capsule"`` (``size = [radius, half_length]``,
axis along world z), centred at ``position`` [m] in the world frame. Obstacle geoms have
``contype = conaffinity = 1`` so MuJoCo's contact filter lets them pair with the robot's
colliding geoms, and they are drawn red, half transparent. Keyframes, velocity limits and
every other element of the model are kept.

A model is rebuilt from how it was built: every model :func:`qpik.load_robot` returns
carries its file, ``floating_base`` and ``srdf`` (:data:`qpik.robots.SOURCE_TEXT`), and
every model this module returns also its obstacles, so obstacles can be added one after the
other; the robot's part of the model is bitwise the one ``load_robot`` built. For a model
compiled elsewhere, load it with :func:`qpik.load_robot` first
(``qpik.load_robot("scene.xml")``).
"""

from __future__ import annotations

import json
import warnings

import mujoco
import numpy as np
import numpy.typing as npt

from ..core.checks import check_vector
from ..errors import SceneError
from .robots import SOURCE_TEXT, robot_spec

__all__ = ["SHAPES", "add_obstacle", "model_recipe"]

#: Obstacle shapes and the sizes each takes (MuJoCo's geom sizes) [m].
SHAPES: dict[str, tuple[mujoco.mjtGeom, int, str]] = {
    "sphere": (mujoco.mjtGeom.mjGEOM_SPHERE, 1, "[radius]"),
    "box": (mujoco.mjtGeom.mjGEOM_BOX, 3, "[half_x, half_y, half_z]"),
    "capsule": (mujoco.mjtGeom.mjGEOM_CAPSULE, 2, "[radius, half_length]"),
}


def model_recipe(model: mujoco.MjModel) -> dict:
    """How a model was built: ``{"path", "floating_base", "srdf", "obstacles"}``, which
    every model :func:`qpik.load_robot` and :func:`add_obstacle` return carries;
    :class:`qpik.errors.SceneError` for a model that does not say (one compiled
    elsewhere: load it with :func:`qpik.load_robot` first)."""
    tid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TEXT, SOURCE_TEXT)
    if tid < 0:
        raise SceneError(
            "this model does not say how it was built (it was not built by qpik.load_robot); "
            "load it with qpik.load_robot(path) and add obstacles to that model"
        )
    adr, size = model.text_adr[tid], model.text_size[tid]
    text = bytes(model.text_data[adr : adr + size]).rstrip(b"\0").decode()
    try:
        recipe = json.loads(text)
        if not isinstance(recipe, dict) or "path" not in recipe:
            raise ValueError("no path")
    except ValueError as exc:
        raise SceneError(f"the model's {SOURCE_TEXT!r} text is not qpik's ({exc})") from None
    return recipe


def _build(recipe: dict) -> mujoco.MjModel:
    """Rebuild a model from its recipe: the robot exactly as loaded, then the obstacles."""
    with warnings.catch_warnings():  # the load already warned about dropped meshes
        warnings.simplefilter("ignore")
        spec = robot_spec(
            recipe["path"], floating_base=recipe["floating_base"], srdf=recipe["srdf"]
        )
    for obstacle in recipe["obstacles"]:
        kind, count, _ = SHAPES[obstacle["shape"]]
        geom = spec.worldbody.add_geom()
        geom.name = obstacle["name"]
        geom.type = kind
        geom.size[:count] = obstacle["size"]
        geom.pos = obstacle["position"]
        geom.contype = 1
        geom.conaffinity = 1
        geom.rgba = [0.9, 0.2, 0.2, 0.5]
    spec.add_text(name=SOURCE_TEXT, data=json.dumps(recipe))
    try:
        return spec.compile()
    except ValueError as exc:  # pragma: no cover - a valid model plus valid geoms
        raise SceneError(f"the model with its obstacles does not compile: {exc}") from exc


def add_obstacle(
    model: mujoco.MjModel,
    shape: str,
    size: float | npt.ArrayLike,
    position: npt.ArrayLike,
    name: str | None = None,
) -> mujoco.MjModel:
    """A copy of ``model`` with an obstacle fixed in the world.

    Args:
        model: the robot (or scene) model; left unchanged.
        shape: ``"sphere"``, ``"box"`` or ``"capsule"``.
        size: MuJoCo's geom size [m]: sphere ``radius``; box half-sizes ``(3,)``;
            capsule ``(radius, half_length)`` (axis along world z).
        position: centre ``(3,)`` [m], world frame.
        name: the geom's name (default ``obstacle<k>``, the first free ``k``); use it in
            :class:`qpik.limits.CollisionAvoidanceLimit`'s ``geom_pairs``.
    """
    if not isinstance(model, mujoco.MjModel):
        raise SceneError(f"model must be a mujoco.MjModel, got {type(model).__name__}")
    if shape not in SHAPES:
        raise SceneError(f"shape {shape!r} is not one of: {', '.join(SHAPES)}")
    kind, count, layout = SHAPES[shape]
    try:
        sizes = np.atleast_1d(np.asarray(size, dtype=float))
        centre = np.asarray(position, dtype=float)
    except (TypeError, ValueError):
        raise SceneError(f"size and position must be numbers, got {size!r}, {position!r}") from None
    if sizes.shape != (count,) or not np.all(np.isfinite(sizes)) or not np.all(sizes > 0):
        raise SceneError(f"a {shape}'s size is {layout}, positive numbers [m]; got {size!r}")
    centre = check_vector("position", centre, 3, error=SceneError)
    existing = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(model.ngeom)}
    if name is None:
        k = 0
        while f"obstacle{k}" in existing:
            k += 1
        name = f"obstacle{k}"
    elif not isinstance(name, str) or not name:
        raise SceneError(f"name must be a non-empty string, got {name!r}")
    elif name in existing:
        raise SceneError(f"the model already has a geom named {name!r}; choose another name")
    recipe = model_recipe(model)
    recipe["obstacles"] = list(recipe.get("obstacles", [])) + [
        {"shape": shape, "size": sizes.tolist(), "position": centre.tolist(), "name": name}
    ]
    return _build(recipe)
