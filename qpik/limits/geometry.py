r"""Collision pairs and contact footprints from the model's own geometry.

A model states which of its geoms collide, as MuJoCo Menagerie's models do: *collision*
geoms have contact bits (``contype``/``conaffinity``; Menagerie puts them in group 3), and
*visual* geoms have none (``contype = conaffinity = 0``, group 2). This module reads that:

* :func:`collision_geoms`: the geoms that take part in contact;
* :func:`collision_pairs`: the geom pairs MuJoCo's contact filter would test, split into
  robot--scene pairs (a robot geom against a geom fixed to the world body itself: the floor,
  an obstacle of :func:`qpik.scene.add_obstacle`) and self-collision pairs (two geoms of the
  robot). The filter is MuJoCo's: the contact bits must match
  (``contype1 & conaffinity2 || contype2 & conaffinity1``), geoms of one body (or of bodies
  welded together) never pair, adjacent bodies (a parent and its child) never pair, nor
  bodies named in the model's ``<contact><exclude>``; the model's explicit ``<pair>`` elements
  are added. Adjacent bodies are excluded also where one is welded to the world (a fixed
  base and the first link), which MuJoCo leaves to an ``<exclude>``; the geoms of the world
  body itself (the scene) are adjacent to nothing, so an obstacle pairs with the first
  link too.
* :func:`always_in_contact`: the self-collision pairs that overlap in every pose the joint
  ranges allow (sampled), which no step can separate: a URDF without an SRDF's
  ``<disable_collisions>`` (erd Baxter's elbow links, Tiago's hand) has them;
* :func:`model_collision_limit`: a :class:`qpik.limits.CollisionAvoidanceLimit` over those
  pairs, less the ones always in contact;
* :func:`collision_clearance`, :func:`closest_pair`, :func:`collision_limits`,
  :func:`checked_pairs`: how far a
  configuration is from breaking the collision limits of a list of limits, and which
  pairs they check (full IK, reachability maps and problem files report them);
* :func:`contact_footprint`: the ground footprint of a contact frame's collision geometry,
  used by :class:`qpik.limits.SupportPolygonLimit` when no footprint is given.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import mink
import mujoco
import numpy as np

from ..core import checks
from ..errors import CollisionPairError, InvalidArgumentType, LimitDefinitionError
from ..model.configuration import FrameType
from ..model.frames import check_model_type, excluded_body_pairs
from .collision import (
    CollisionAvoidanceLimit,
    contact_bits_match,
    near_pairs,
    welded_parent_and_child,
    welded_together,
)

__all__ = [
    "checked_pairs",
    "closest_pair",
    "collision_clearance",
    "collision_geoms",
    "collision_limits",
    "collision_pairs",
    "always_in_contact",
    "contact_footprint",
    "model_collision_limit",
]


def collision_geoms(model: mujoco.MjModel, *, robot_only: bool = False) -> list[int]:
    """Ids of the geoms that take part in contact (``contype`` or ``conaffinity`` nonzero),
    sorted; ``robot_only``: leave out the geoms of the world body (floor, obstacles)."""
    check_model_type("model", model)
    robot_only = checks.check_bool("robot_only", robot_only)
    return [
        g
        for g in range(model.ngeom)
        if (model.geom_contype[g] or model.geom_conaffinity[g])
        and not (robot_only and model.geom_bodyid[g] == 0)
    ]


def _filtered(model: mujoco.MjModel, a: int, b: int, excluded: set[tuple[int, int]]) -> bool:
    """Whether MuJoCo's contact filter (plus the parent-child rule at the world) drops the
    geom pair ``(a, b)``."""
    if not contact_bits_match(model, a, b) or welded_together(model, a, b):
        return True
    body_a, body_b = int(model.geom_bodyid[a]), int(model.geom_bodyid[b])
    weld_a, weld_b = int(model.body_weldid[body_a]), int(model.body_weldid[body_b])
    adjacent = model.body_parentid[body_a] == body_b or model.body_parentid[body_b] == body_a
    if adjacent and body_a and body_b:  # the world body's own geoms are never adjacent
        return True
    filter_parent = not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT
    if filter_parent and weld_a and weld_b and welded_parent_and_child(model, a, b):
        return True
    return (min(body_a, body_b), max(body_a, body_b)) in excluded


def collision_pairs(
    model: mujoco.MjModel, *, scene: bool = True, self_collision: bool = True
) -> list[tuple[int, int]]:
    """Geom id pairs ``(a, b)``, ``a < b``, sorted, that the model lets collide:
    ``scene``: a robot geom against a geom of the world body; ``self_collision``: two robot
    geoms (on bodies other than the world body). The filter is MuJoCo's: the contact bits
    match, the geoms are on different welds that are not parent and child, nor excluded by
    the model's ``<contact><exclude>``; the model's ``<pair>`` elements are added."""
    check_model_type("model", model)
    checks.check_bool("scene", scene)
    checks.check_bool("self_collision", self_collision)
    excluded = excluded_body_pairs(model)
    geoms = collision_geoms(model)
    pairs = set()
    for i, a in enumerate(geoms):
        for b in geoms[i + 1 :]:
            world = (model.geom_bodyid[a] == 0) + (model.geom_bodyid[b] == 0)
            if world == 2 or (world == 1 and not scene) or (world == 0 and not self_collision):
                continue
            if not _filtered(model, a, b, excluded):
                pairs.add((a, b))
    for a, b in zip(model.pair_geom1, model.pair_geom2, strict=True):  # explicit <pair>s
        a, b = int(min(a, b)), int(max(a, b))
        world = (model.geom_bodyid[a] == 0) + (model.geom_bodyid[b] == 0)
        if (world == 1 and scene) or (world == 0 and self_collision):
            pairs.add((a, b))
    return sorted(pairs)


#: Poses :func:`always_in_contact` samples (besides ``qpos0`` and the keyframes).
ALWAYS_SAMPLES = 32


def _geom_pairs(model: mujoco.MjModel, pairs: Any) -> list[tuple[int, int]]:
    """``pairs`` checked: (geom id, geom id) pairs of ints in ``[0, ngeom)``, each sorted."""
    listed = isinstance(pairs, (list, tuple)) or (isinstance(pairs, np.ndarray) and pairs.ndim)
    if not listed:  # (a str, a number, a 0-d array: nothing to iterate over)
        raise InvalidArgumentType(
            "pairs", "a list of (geom id, geom id) pairs", checks.type_name(pairs)
        )
    checked = []
    for pair in pairs:
        ints = isinstance(pair, (list, tuple)) or (isinstance(pair, np.ndarray) and pair.ndim == 1)
        ints = ints and len(pair) == 2
        ints = ints and all(
            isinstance(g, (int, np.integer)) and not isinstance(g, (bool, np.bool_)) for g in pair
        )
        if not ints:
            raise InvalidArgumentType("pairs", "(geom id, geom id) pairs of ints", repr(pair)[:60])
        a, b = int(pair[0]), int(pair[1])
        if not (0 <= a < model.ngeom and 0 <= b < model.ngeom):
            raise LimitDefinitionError(f"pairs: geom id out of range [0, {model.ngeom}): {(a, b)}")
        checked.append((min(a, b), max(a, b)))
    return checked


def _sampled_poses(model: mujoco.MjModel, samples: int) -> list[np.ndarray]:
    """``qpos0``, the keyframes, and ``samples`` poses drawn uniformly in the joint ranges
    (seed 0; unlimited hinges in [-pi, pi]; free, ball and unlimited slide joints at
    ``qpos0``)."""
    poses = [model.qpos0.copy(), *(np.array(model.key_qpos[k]) for k in range(model.nkey))]
    rng = np.random.default_rng(0)
    for _ in range(samples):
        q = model.qpos0.copy()
        for j in range(model.njnt):
            kind, adr = int(model.jnt_type[j]), int(model.jnt_qposadr[j])
            low, high = model.jnt_range[j]
            limited = bool(model.jnt_limited[j]) and high > low
            if kind == int(mujoco.mjtJoint.mjJNT_HINGE):
                q[adr] = rng.uniform(low, high) if limited else rng.uniform(-math.pi, math.pi)
            elif kind == int(mujoco.mjtJoint.mjJNT_SLIDE) and limited:
                q[adr] = rng.uniform(low, high)
        poses.append(q)
    return poses


def always_in_contact(
    model: mujoco.MjModel,
    pairs: Sequence[tuple[int, int]],
    *,
    samples: int = ALWAYS_SAMPLES,
    distance: float = 0.0,
) -> list[tuple[int, int]]:
    """The self-collision pairs among ``pairs`` (geom ids, both on moving bodies of the
    robot) that penetrate (MuJoCo's contact distance below 0), or with ``distance`` > 0 come
    closer than ``distance`` [m] (``mj_geomDistance``, the distance the collision rows
    measure), at ``qpos0``, at every keyframe and at each of ``samples`` poses drawn
    uniformly in the joint ranges (a fixed seed: the same pairs on every call; unlimited
    hinges in [-pi, pi]; free, ball and unlimited slide joints at ``qpos0``): MoveIt's
    "always in collision", for a collision limit that keeps pairs ``distance`` apart. No
    step can separate such a pair by that much, and its collision row would make every step
    infeasible (erd Tiago's finger phalanges touch, 1e-5 m apart, in every pose).
    Robot--scene pairs are never in the list (an obstacle may overlap the robot where it
    starts). With ``distance`` 0, MuJoCo's own contact filter decides what its collision
    detection tests, so a pair it never tests (an explicit ``<pair>`` aside) is never in the
    list either. Raises a typed :class:`qpik.QpikError` naming ``pairs``, ``samples`` or
    ``distance`` for bad input."""
    check_model_type("model", model)
    samples = checks.check_integer("samples", samples, 0, 100_000)
    distance = checks.check_real("distance", distance, minimum=0.0)
    wanted = {
        (a, b)
        for a, b in _geom_pairs(model, pairs)
        if model.geom_bodyid[a] != 0 and model.geom_bodyid[b] != 0
    }
    if not wanted or model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT:
        return []
    data = mujoco.MjData(model)
    for q in _sampled_poses(model, samples):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        wanted &= _close_pairs(model, data, wanted, distance)
        if not wanted:
            return []
    return sorted(wanted)


def _close_pairs(
    model: mujoco.MjModel, data: mujoco.MjData, pairs: set, distance: float
) -> set[tuple[int, int]]:
    """The pairs (geom ids, sorted) closer than ``distance`` at ``data``'s kinematics:
    penetrating contacts of MuJoCo's collision detection where ``distance`` is 0, else each
    pair's ``mj_geomDistance`` below ``distance``."""
    if distance > 0.0:
        fromto = np.zeros(6)
        return {
            (a, b)
            for a, b in pairs
            if mujoco.mj_geomDistance(model, data, a, b, distance, fromto) < distance
        }
    mujoco.mj_collision(model, data)
    touching = set()
    for c in range(data.ncon):
        contact = data.contact[c]
        if contact.dist < 0:
            a, b = int(contact.geom[0]), int(contact.geom[1])
            touching.add((min(a, b), max(a, b)))
    return touching


class _ModelCollisionLimit(CollisionAvoidanceLimit):
    """:class:`CollisionAvoidanceLimit` over pairs already filtered by
    :func:`collision_pairs`: a geom of the world body itself (an obstacle, the floor) pairs
    with the robot's first link too, which mink's rule drops as "parent and child"."""

    #: The self-collision pairs left out (:func:`always_in_contact`), geom ids.
    always_in_contact: list[tuple[int, int]] = []  # noqa: RUF012 (set per instance)

    def _reject(self, model: mujoco.MjModel, a: int, b: int) -> str | None:
        body_a, body_b = int(model.geom_bodyid[a]), int(model.geom_bodyid[b])
        moving = model.body_weldid[body_a] != 0 or model.body_weldid[body_b] != 0
        if (body_a == 0 or body_b == 0) and moving:
            return None  # the scene against a moving robot geom: never adjacent
        return super()._reject(model, a, b)


def model_collision_limit(  # noqa: PLR0913 (the pair filters and mink's four numbers)
    model: mujoco.MjModel,
    *,
    scene: bool = True,
    self_collision: bool = True,
    geoms: Sequence[int | str] | None = None,
    gain: float = 0.85,
    minimum_distance_from_collisions: float = 0.005,
    collision_detection_distance: float = 0.01,
    bound_relaxation: float = 0.0,
    keep_always_in_contact: bool = False,
) -> CollisionAvoidanceLimit:
    """A :class:`CollisionAvoidanceLimit` over the pairs the model lets collide
    (:func:`collision_pairs`): robot against scene (``scene``) and robot against itself
    (``self_collision``), less the self-collision pairs :func:`always_in_contact` finds
    (unless ``keep_always_in_contact``), which the limit lists as ``always_in_contact``
    (geom id pairs). A URDF's SRDF ``<disable_collisions>`` pairs are already excluded by
    :func:`qpik.load_robot`.

    Args:
        model: the robot or scene model (obstacles from :func:`qpik.scene.add_obstacle`).
        scene: check the robot's collision geoms against the world body's (floor,
            obstacles).
        self_collision: check the robot's collision geoms against each other.
        geoms: only pairs with at least one of these geoms (names or ids; default: all).
        gain, minimum_distance_from_collisions, collision_detection_distance,
            bound_relaxation: :class:`CollisionAvoidanceLimit`'s, in [m] where a distance.
        keep_always_in_contact: keep the pairs that come closer than
            ``minimum_distance_from_collisions`` in every pose too (overlapping, or touching
            as erd Tiago's finger phalanges do; their rows then make every step infeasible
            until the relaxation of :mod:`qpik.diffik.recovery` frees them).

    Raises :class:`qpik.CollisionPairError` when the model has no such pair (no collision
    geom, or every pair excluded), naming what was asked.
    """
    numbers = {
        "gain": gain,
        "minimum_distance_from_collisions": minimum_distance_from_collisions,
        "collision_detection_distance": collision_detection_distance,
        "bound_relaxation": bound_relaxation,
    }
    for name, value in numbers.items():  # each named before any pair is looked at
        checks.check_real(name, value)
    keep_always_in_contact = checks.check_bool("keep_always_in_contact", keep_always_in_contact)
    pairs = collision_pairs(model, scene=scene, self_collision=self_collision)
    if geoms is not None:
        if (
            isinstance(geoms, (str, bytes))
            or not isinstance(geoms, (list, tuple, np.ndarray))
            or _ndim(geoms) != 1
        ):
            raise InvalidArgumentType(
                "geoms", "a list of geom names or ids", checks.type_name(geoms)
            )
        wanted = set()
        for geom in geoms:
            if not isinstance(geom, (str, int, np.integer)) or isinstance(geom, bool):
                raise InvalidArgumentType("geoms", "geom names or ids", checks.type_name(geom))
            gid = (
                mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
                if isinstance(geom, str)
                else int(geom)
            )
            if not 0 <= gid < model.ngeom:
                raise LimitDefinitionError(f"unknown geom {geom!r}")
            wanted.add(gid)
        pairs = [(a, b) for a, b in pairs if a in wanted or b in wanted]
    always = []
    if not keep_always_in_contact:
        always = always_in_contact(
            model, pairs, distance=max(minimum_distance_from_collisions, 0.0)
        )
    if always:
        dropped = set(always)
        pairs = [pair for pair in pairs if pair not in dropped]
    if not pairs:
        asked = " and ".join(
            what for what, on in (("robot-scene", scene), ("self-collision", self_collision)) if on
        )
        raise CollisionPairError(
            f"the model has no {asked or 'collision'} pair to check: "
            f"{len(collision_geoms(model, robot_only=True))} robot geom(s) with contact bits "
            "(contype/conaffinity), "
            f"{len(collision_geoms(model)) - len(collision_geoms(model, robot_only=True))} "
            "in the world (add one with qpik.scene.add_obstacle)"
            + (f"; {len(always)} pair(s) always in contact left out" if always else "")
        )
    limit = _ModelCollisionLimit(
        model,
        [([a], [b]) for a, b in pairs],
        gain=gain,
        minimum_distance_from_collisions=minimum_distance_from_collisions,
        collision_detection_distance=collision_detection_distance,
        bound_relaxation=bound_relaxation,
    )
    limit.always_in_contact = always
    return limit


# ---------------------------------------------------------------------- clearance
def collision_limits(limits: Iterable | str | None) -> list[mink.CollisionAvoidanceLimit]:
    """The collision limits among ``limits`` (qpik's and mink's
    :class:`CollisionAvoidanceLimit`, subclasses included), in order; none for ``None`` or
    a string such as ``"joint"``."""
    if limits is None or isinstance(limits, str):
        return []
    return [limit for limit in limits if isinstance(limit, mink.CollisionAvoidanceLimit)]


def _label(model: mujoco.MjModel, geom: int) -> str:
    """A geom's name, else ``geom <id> (body '<name>')``."""
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
    if name:
        return name
    body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, model.geom_bodyid[geom])
    return f"geom {geom} (body {body!r})"


def checked_pairs(limits: Iterable | str | None) -> list[tuple[str, str]]:
    """The geom pairs the collision limits among ``limits`` check, as geom labels (the
    name, else ``geom<id>``), each pair once, in the limits' order."""
    out: dict[tuple[str, str], None] = {}
    for limit in collision_limits(limits):
        for a, b in limit.geom_id_pairs:
            out[(_label(limit.model, int(a)), _label(limit.model, int(b)))] = None
    return list(out)


def closest_pair(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    limits: Iterable | str | None,
    cap: float = 1.0,
) -> tuple[tuple[str, str], float, float] | None:
    """``((geom, geom), distance, margin)``: the pair of the collision limits among
    ``limits`` with the smallest margin ``d - d_min`` [m] at the kinematics in ``data``
    (``mj_kinematics`` done), its distance ``d`` [m] and that margin: negative when the
    pair is closer than its limit's ``minimum_distance_from_collisions`` ``d_min``, below
    ``-d_min`` when it penetrates. Distances are MuJoCo's ``mj_geomDistance``, capped at
    ``d_min + cap`` (a smaller ``cap`` is faster; exact whenever the margin is below
    ``cap``); the first pair among equals. ``None`` when ``limits`` holds no collision
    limit."""
    found = collision_limits(limits)
    if not found:
        return None
    best: tuple[int, int, mujoco.MjModel, float, float] | None = None
    for limit in found:
        d_min = float(limit.minimum_distance_from_collisions)
        for a, b in limit.geom_id_pairs:
            distance = mujoco.mj_geomDistance(model, data, int(a), int(b), d_min + cap, None)
            if best is None or distance - d_min < best[4]:
                best = (int(a), int(b), limit.model, distance, distance - d_min)
    assert best is not None  # a collision limit has at least one pair
    a, b, owner, distance, margin = best
    return (_label(owner, a), _label(owner, b)), float(distance), float(margin)


def collision_clearance(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    limits: Iterable | str | None,
    cap: float = 1.0,
) -> float | None:
    """The smallest margin ``d - d_min`` [m] over every pair that the collision limits
    among ``limits`` check (:func:`closest_pair`'s margin, same ``cap``); ``None`` when
    ``limits`` holds no collision limit. The pairs that the compiled culling
    (:class:`qpik.limits.collision.PairCulling`) proves farther than ``d_min + cap`` are
    not handed to ``mj_geomDistance``, which would return ``d_min + cap`` for them: they
    count as that (the same value, and most of a many-pair robot's 1,200 pairs)."""
    found = collision_limits(limits)
    if not found:
        return None
    smallest = math.inf
    for limit in found:
        d_min = float(limit.minimum_distance_from_collisions)
        pairs = limit.geom_id_pairs
        if limit.model is model and len(pairs):
            near = near_pairs(limit, model, data, d_min + cap)
            if len(near) < len(pairs):
                smallest = min(smallest, (d_min + cap) - d_min)
            pairs = [pairs[i] for i in near]
        for a, b in pairs:
            distance = mujoco.mj_geomDistance(model, data, int(a), int(b), d_min + cap, None)
            smallest = min(smallest, distance - d_min)
    return smallest


# ---------------------------------------------------------------------- footprints
#: Unit directions sampling a sphere's surface (the 6 axes, 12 edge and 8 corner
#: directions of a cube): a sphere or a capsule's end projects on the ground inside their
#: hull, whose width is within 8 % of the true one.
_SPHERE = np.array(
    [
        v
        for v in np.array(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1])).reshape(3, -1).T
        if np.any(v)
    ],
    dtype=float,
)
_SPHERE /= np.linalg.norm(_SPHERE, axis=1, keepdims=True)
_CIRCLE = np.column_stack(
    [
        np.cos(np.linspace(0, 2 * np.pi, 16, endpoint=False)),
        np.sin(np.linspace(0, 2 * np.pi, 16, endpoint=False)),
    ]
)


def _geom_points(model: mujoco.MjModel, g: int) -> np.ndarray:
    """Points ``(k, 3)`` [m] in geom ``g``'s frame whose hull is (or bounds closely) the
    geom: box corners, mesh vertices, samples of spheres, capsules, cylinders, ellipsoids."""
    size = model.geom_size[g]
    kind = int(model.geom_type[g])
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
        return signs * size
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        return _SPHERE * size[0]
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        ends = np.array([[0, 0, -size[1]], [0, 0, size[1]]])
        return np.vstack([end + _SPHERE * size[0] for end in ends])
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        rim = np.column_stack([_CIRCLE * size[0], np.zeros(len(_CIRCLE))])
        return np.vstack([rim + [0, 0, -size[1]], rim + [0, 0, size[1]]])
    if kind == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        return _SPHERE * size[:3]
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        mesh = int(model.geom_dataid[g])
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        return np.asarray(model.mesh_vert[start : start + count], dtype=float)
    return np.zeros((0, 3))  # planes, height fields: no footprint


def contact_footprint(model: mujoco.MjModel, frame_type: FrameType, frame_id: int) -> np.ndarray:
    """The points ``(k, 3)`` [m], in the contact frame's own axes, whose ground projection
    is the frame's footprint: the vertices (boxes, meshes) or surface samples (spheres,
    capsules, cylinders, ellipsoids) of the collision geoms (:func:`collision_geoms`) on the
    frame's body and on every body welded to it (a sole link fixed under an ankle).

    A geom frame uses that geom alone, whatever its contact bits. A body without collision
    geoms falls back to its geoms of group 3 (Menagerie's collision group), then to every
    geom of the welded bodies. Raises :class:`qpik.LimitDefinitionError` when there is no
    geometry at all."""
    model_data = mujoco.MjData(model)  # qpos0: the geoms' poses in the frame are fixed
    mujoco.mj_kinematics(model, model_data)
    if frame_type is FrameType.GEOM:
        geoms = [frame_id]
        body = int(model.geom_bodyid[frame_id])
        origin, rotation = model_data.geom_xpos[frame_id], model_data.geom_xmat[frame_id]
    else:
        body = frame_id if frame_type is FrameType.BODY else int(model.site_bodyid[frame_id])
        if frame_type is FrameType.BODY:
            origin, rotation = model_data.xpos[frame_id], model_data.xmat[frame_id]
        else:
            origin, rotation = model_data.site_xpos[frame_id], model_data.site_xmat[frame_id]
        weld = int(model.body_weldid[body])
        bodies = {b for b in range(model.nbody) if model.body_weldid[b] == weld} if weld else {body}
        on_bodies = [g for g in range(model.ngeom) if model.geom_bodyid[g] in bodies]
        colliding = [g for g in on_bodies if model.geom_contype[g] or model.geom_conaffinity[g]]
        group3 = [g for g in on_bodies if model.geom_group[g] == 3]
        geoms = colliding or group3 or on_bodies
    frame_rotation = rotation.reshape(3, 3)
    points = []
    for g in geoms:
        local = _geom_points(model, g)
        world = model_data.geom_xpos[g] + local @ model_data.geom_xmat[g].reshape(3, 3).T
        points.append((world - origin) @ frame_rotation)
    stacked = np.vstack(points) if points else np.zeros((0, 3))
    if not len(stacked):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body)
        raise LimitDefinitionError(
            f"contact frame on body {name!r} has no geometry to take a footprint from: give "
            "footprint=[[x, y], ...] (a sole's corners [m] in the frame's x-y axes)"
        )
    return stacked


def _ndim(value: Any) -> int:
    """``np.ndim(value)``, or -1 for a ragged nesting NumPy cannot shape."""
    try:
        return int(np.ndim(value))
    except (TypeError, ValueError):
        return -1
