"""Triangle meshes of a MuJoCo model's geoms, for drawing (numpy only, no viser).

Each drawable geom becomes a :class:`GeomMesh`: vertices [m] in the frame of the geom,
the geom's pose in the frame of its body, and its colour. Mesh geoms take their
vertices and faces from the compiled model (``model.mesh_vert`` / ``mesh_face``, already
expressed in the geom's frame); spheres, capsules, ellipsoids, cylinders and boxes are
tessellated here. Planes, height fields and SDF geoms are not drawn (the viewer draws a
ground grid instead).

Which geoms: MuJoCo models usually separate *visual* geoms (``contype = conaffinity =
0``) from *collision* geoms (either nonzero). :func:`geom_meshes` draws the visual ones,
or the collision ones for a model that has no visual geom (a URDF loaded without its
visual meshes), or the collision ones only (``which="collision"``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import mujoco
import numpy as np

from ..core import checks

__all__ = ["GeomMesh", "collision_geoms", "geom_meshes", "primitive_mesh", "visual_geoms"]

#: Geom types drawn as tessellated primitives or as the model's meshes.
_DRAWN = {
    int(mujoco.mjtGeom.mjGEOM_SPHERE),
    int(mujoco.mjtGeom.mjGEOM_CAPSULE),
    int(mujoco.mjtGeom.mjGEOM_ELLIPSOID),
    int(mujoco.mjtGeom.mjGEOM_CYLINDER),
    int(mujoco.mjtGeom.mjGEOM_BOX),
    int(mujoco.mjtGeom.mjGEOM_MESH),
}


@dataclass(frozen=True)
class GeomMesh:
    """A geom as triangles.

    Attributes:
        geom: the geom's id; ``name``: its name (``geom_<id>`` when it has none).
        body: id of the body it moves with (0: the world, a fixed obstacle).
        vertices: ``(v, 3)`` [m], in the geom's frame; ``faces``: ``(f, 3)`` vertex indices.
        position: ``(3,)`` [m], the geom's origin in its body's frame.
        wxyz: ``(4,)``, the geom's orientation in its body's frame (MuJoCo's quaternion
            order, w first).
        rgba: ``(4,)`` colour in [0, 1] (the material's when the geom has one).
        collision: whether the geom takes part in contacts (``contype`` or
            ``conaffinity`` nonzero).
    """

    geom: int
    name: str
    body: int
    vertices: np.ndarray
    faces: np.ndarray
    position: np.ndarray
    wxyz: np.ndarray
    rgba: np.ndarray
    collision: bool


def _is_collision(model: mujoco.MjModel, geom: int) -> bool:
    return bool(model.geom_contype[geom] or model.geom_conaffinity[geom])


def _drawable(model: mujoco.MjModel, geom: int) -> bool:
    return int(model.geom_type[geom]) in _DRAWN


def visual_geoms(model: mujoco.MjModel) -> list[int]:
    """Ids of the drawable geoms with ``contype = conaffinity = 0`` (visual only)."""
    return [g for g in range(model.ngeom) if _drawable(model, g) and not _is_collision(model, g)]


def collision_geoms(model: mujoco.MjModel) -> list[int]:
    """Ids of the drawable geoms that take part in contacts."""
    return [g for g in range(model.ngeom) if _drawable(model, g) and _is_collision(model, g)]


def geom_meshes(
    model: mujoco.MjModel, which: Literal["visual", "collision"] = "visual"
) -> list[GeomMesh]:
    """The geoms to draw as :class:`GeomMesh` es.

    Args:
        model: the MuJoCo model.
        which: ``"visual"``: the visual geoms, or the collision geoms of a *body* that has
            no visual geom (so that every body is drawn once; the world's geoms, such as
            obstacles, are always drawn); ``"collision"``: the collision geoms only.

    A ``model`` that is not an ``MjModel`` raises :class:`qpik.InvalidArgumentType`,
    another ``which`` :class:`qpik.InvalidOption`.
    """
    checks.check_instance("model", model, mujoco.MjModel, "a mujoco.MjModel")
    checks.check_choice("which", which, ("visual", "collision"))
    if which == "collision":
        ids = collision_geoms(model)
    else:
        visual = visual_geoms(model)
        with_visual = {int(model.geom_bodyid[g]) for g in visual}
        extra = [g for g in collision_geoms(model) if int(model.geom_bodyid[g]) not in with_visual]
        ids = sorted(visual + extra)
    out = []
    for g in ids:
        mesh = _mesh_of(model, g)
        if mesh is None:
            continue
        vertices, faces = mesh
        matid = int(model.geom_matid[g])
        rgba = model.mat_rgba[matid] if matid >= 0 else model.geom_rgba[g]
        if rgba[3] <= 0.0:  # invisible geoms stay invisible
            continue
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom_{g}"
        out.append(
            GeomMesh(
                geom=g,
                name=name,
                body=int(model.geom_bodyid[g]),
                vertices=vertices,
                faces=faces,
                position=model.geom_pos[g].copy(),
                wxyz=model.geom_quat[g].copy(),
                rgba=np.asarray(rgba, dtype=float).copy(),
                collision=_is_collision(model, g),
            )
        )
    return out


def _mesh_of(model: mujoco.MjModel, g: int) -> tuple[np.ndarray, np.ndarray] | None:
    kind = int(model.geom_type[g])
    if kind == int(mujoco.mjtGeom.mjGEOM_MESH):
        mesh = int(model.geom_dataid[g])
        if mesh < 0:
            return None
        v0, nv = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        f0, nf = int(model.mesh_faceadr[mesh]), int(model.mesh_facenum[mesh])
        vertices = np.asarray(model.mesh_vert[v0 : v0 + nv], dtype=float).copy()
        faces = np.asarray(model.mesh_face[f0 : f0 + nf], dtype=np.int64).copy()
        return vertices, faces
    return primitive_mesh(kind, model.geom_size[g])


def primitive_mesh(
    kind: int, size: np.ndarray, segments: int = 24
) -> tuple[np.ndarray, np.ndarray]:
    """Vertices ``(v, 3)`` [m] and faces ``(f, 3)`` of a MuJoCo primitive in its own frame.

    Args:
        kind: a ``mujoco.mjtGeom`` value: sphere, capsule, ellipsoid, cylinder or box.
        size: the geom's ``size`` (MuJoCo's meaning: radii and half lengths [m]).
        segments: points around a circle.
    """
    if kind == int(mujoco.mjtGeom.mjGEOM_BOX):
        return _box(np.asarray(size[:3], dtype=float))
    if kind == int(mujoco.mjtGeom.mjGEOM_SPHERE):
        return _capsule(float(size[0]), 0.0, segments)
    if kind == int(mujoco.mjtGeom.mjGEOM_ELLIPSOID):
        vertices, faces = _capsule(1.0, 0.0, segments)
        return vertices * np.asarray(size[:3], dtype=float), faces
    if kind == int(mujoco.mjtGeom.mjGEOM_CAPSULE):
        return _capsule(float(size[0]), float(size[1]), segments)
    if kind == int(mujoco.mjtGeom.mjGEOM_CYLINDER):
        return _cylinder(float(size[0]), float(size[1]), segments)
    raise ValueError(f"no primitive mesh for geom type {kind}")


def _box(half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    faces = np.array(
        [
            [0, 1, 3], [0, 3, 2],  # x-
            [4, 6, 7], [4, 7, 5],  # x+
            [0, 4, 5], [0, 5, 1],  # y-
            [2, 3, 7], [2, 7, 6],  # y+
            [0, 2, 6], [0, 6, 4],  # z-
            [1, 5, 7], [1, 7, 3],  # z+
        ]
    )  # fmt: skip
    return corners * half, faces


def _capsule(radius: float, half_length: float, segments: int) -> tuple[np.ndarray, np.ndarray]:
    """A sphere (``half_length = 0``) or a capsule along z: rings of a UV sphere, the upper
    half shifted up by ``half_length`` and the lower half down."""
    rings = max(segments // 2, 4)
    if rings % 2:
        rings += 1
    theta = np.linspace(0.0, np.pi, rings + 1)  # from the top pole
    phi = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    vertices = []
    for i, t in enumerate(theta):
        z = radius * np.cos(t) + (half_length if i <= rings // 2 else -half_length)
        r = radius * np.sin(t)
        vertices.append(np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full_like(phi, z)]))
    if half_length > 0:  # the equator twice: once up, once down (the cylinder between)
        upper = vertices[: rings // 2 + 1]
        equator = vertices[rings // 2].copy()
        equator[:, 2] -= 2 * half_length
        vertices = upper + [equator] + vertices[rings // 2 + 1 :]
    grid = np.vstack(vertices)
    return grid, _ring_faces(len(vertices), segments)


def _ring_faces(n_rings: int, segments: int) -> np.ndarray:
    faces = []
    for i in range(n_rings - 1):
        for j in range(segments):
            a = i * segments + j
            b = i * segments + (j + 1) % segments
            c = (i + 1) * segments + j
            d = (i + 1) * segments + (j + 1) % segments
            faces.append([a, c, b])
            faces.append([b, c, d])
    return np.array(faces, dtype=np.int64)


def _cylinder(radius: float, half_length: float, segments: int) -> tuple[np.ndarray, np.ndarray]:
    phi = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    circle = np.column_stack([radius * np.cos(phi), radius * np.sin(phi)])
    top = np.column_stack([circle, np.full(segments, half_length)])
    bottom = np.column_stack([circle, np.full(segments, -half_length)])
    centres = np.array([[0.0, 0.0, half_length], [0.0, 0.0, -half_length]])
    vertices = np.vstack([top, bottom, centres])
    faces = _ring_faces(2, segments).tolist()
    top_c, bottom_c = 2 * segments, 2 * segments + 1
    for j in range(segments):
        k = (j + 1) % segments
        faces.append([top_c, j, k])
        faces.append([bottom_c, segments + k, segments + j])
    return vertices, np.array(faces, dtype=np.int64)


def ground_height(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """Where the viewer draws its ground grid [m, world z]: 0, or, for a robot whose geoms
    hang more than 0.1 m below 0 at ``data`` (a fixed-base humanoid held by its pelvis at
    the origin), the lowest geom's bottom (its bounding sphere's), so that the robot stands
    on the grid rather than through it. A model with a plane (a floor) keeps 0."""
    plane = int(mujoco.mjtGeom.mjGEOM_PLANE)
    kept = model.geom_type != plane
    if not kept.all() or not kept.any():  # (a floor plane: the ground is the model's own)
        return 0.0
    lowest = float(np.min(data.geom_xpos[kept, 2] - model.geom_rbound[kept]))
    return lowest if lowest < -0.1 else 0.0
