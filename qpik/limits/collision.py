r"""Collision avoidance between geom pairs, in the units of qpik's variable ``dq = v dt``.

For a pair of geoms at distance ``d`` (MuJoCo's ``mj_geomDistance``: negative when they
penetrate) with nearest points ``p1``, ``p2`` and unit normal ``n = (p2 - p1) / |p2 - p1|``,
the distance changes to first order by ``n^T (J_2(p2) - J_1(p1)) dq`` [m] over a step
(``J_i`` the world-aligned translational Jacobians of the points, MuJoCo's ``mj_jac``). The
limit keeps it from closing faster than a fraction ``gain`` of the margin left above
``d_min`` (``minimum_distance_from_collisions``) in one step:

.. math::

    -n^T (J_2 - J_1)\, dq \le \text{gain}\,(d - d_\min) + \text{bound\_relaxation}

one general row per pair closer than ``collision_detection_distance``. Both sides are
displacements [m]: mink's :class:`mink.CollisionAvoidanceLimit` writes the right side as
``gain (d - d_min) / dt``, a velocity bound, which lets an IK whose variable is a
displacement close ``1 / dt`` times faster (100 times at 100 Hz). Inside ``d_min`` the
right side is negative: the row pushes the geoms apart (by ``gain`` of the intrusion per
step) instead of only stopping them, so the clearance recovers after the linearisation
error of a fast step (mink's row is 0 there, which keeps the intrusion).

Pairs follow mink's rules (no pair within one body or welded bodies, none between a parent
and a child body, and ``contype``/``conaffinity`` must allow contact unless
``respect_contype=False``). A limit that would check no pair raises
:class:`qpik.CollisionPairError` saying which rule removed the pairs and naming the geoms.
"""

from __future__ import annotations

import itertools
import weakref
from collections.abc import Callable, Sequence

import mink
import mujoco
import numpy as np

from .._engine import limits as _engine
from ..core import checks
from ..errors import CollisionPairError, InvalidArgumentType, LimitDefinitionError, UnknownFrame
from ..model.configuration import frame_names
from ..model.frames import check_model_type, frame_chains

#: A limit's row whose every entry is at most this in size carries no direction (a
#: collision pair whose geoms touch: the normal between two coincident points is round-off,
#: 1e-18, and the row "do not come closer" then pointed anywhere, made the step fail or
#: stopped a dof): it is a zero row, met where ``h >= 0`` and left out, and where
#: ``h < 0`` a row no displacement meets (the step then reports or relaxes it). Rows are in
#: the limit's units per unit of ``dq`` (m or rad): 1e-12 is far below any real row.
#: (:mod:`qpik.diffik.boxes` flushes such rows; the engine's support rows flush their own.)
NEGLIGIBLE_ROW = 1e-12

__all__ = [
    "CULLING_SLACK",
    "CollisionAvoidanceLimit",
    "PairCulling",
    "contact_bits_match",
    "geom_distance",
    "mink_collision_rows",
    "welded_parent_and_child",
    "welded_together",
]

Geom = int | str
CollisionPairs = Sequence[tuple[Sequence[Geom], Sequence[Geom]]]


# The pair rules of MuJoCo's contact filter, as mink's CollisionAvoidanceLimit states them
# (mink/limits/collision_avoidance_limit.py); one home for them in qpik (geometry.py's
# model filter uses them too).
def welded_together(model: mujoco.MjModel, a: int, b: int) -> bool:
    """Whether geoms ``a`` and ``b`` are on one body, or on bodies welded together."""
    weld = model.body_weldid
    return bool(weld[model.geom_bodyid[a]] == weld[model.geom_bodyid[b]])


def welded_parent_and_child(model: mujoco.MjModel, a: int, b: int) -> bool:
    """Whether the welds of geoms ``a`` and ``b`` are parent and child (each weld's parent
    taken at its own weld)."""
    weld, parent = model.body_weldid, model.body_parentid
    weld_a, weld_b = weld[model.geom_bodyid[a]], weld[model.geom_bodyid[b]]
    return bool(weld_a == weld[parent[weld_b]] or weld_b == weld[parent[weld_a]])


def contact_bits_match(model: mujoco.MjModel, a: int, b: int) -> bool:
    """MuJoCo's contype/conaffinity test: ``contype_a & conaffinity_b || contype_b &
    conaffinity_a``."""
    contype, conaffinity = model.geom_contype, model.geom_conaffinity
    return bool(contype[a] & conaffinity[b] or contype[b] & conaffinity[a])


#: Pairs whose distance is provably above the detection distance plus this much [m] are not
#: handed to ``mj_geomDistance`` (see :class:`PairCulling`). MuJoCo's colliders find a
#: separated pair's distance exactly (primitives) or to ``opt.ccd_tolerance`` (1e-6 m by
#: default; convex meshes), far inside this slack, so they would report no contact within
#: the detection distance for such a pair either: the rows are unchanged.
CULLING_SLACK = 1e-3


class PairCulling:
    """The geom pairs of a collision limit, culled by the compiled engine before any contact
    routine runs (``qpik/_cpp/limits/collision.hpp``).

    Each geom is bounded by a sphere, capsule (capsules, cylinders), oriented box (boxes,
    ellipsoids, meshes by their ``geom_aabb``) or half-space (planes), from the model's
    current ``geom_type``, ``geom_size``, ``geom_aabb`` and ``geom_rbound`` (mink's
    bounding-sphere test comes first) and the data's ``geom_xpos`` /
    ``geom_xmat``; a lower bound on each pair's distance follows (exact segment distances,
    separating axes). :meth:`candidates` keeps the pairs whose bound is at most a threshold:
    every pair closer than it, and a few more (height fields are always kept). It is
    exact as a filter: the rows of the pairs it drops are those ``mj_geomDistance`` leaves
    out, so a limit's rows are the same with and without it (tested against mink's on
    random configurations).

    :meth:`contact_rows` makes the pairs' rows in the compiled engine too."""

    def __init__(self, pairs: Sequence[tuple[int, int]]) -> None:
        self.pairs = np.ascontiguousarray(np.asarray(pairs, dtype=np.int64).reshape(-1, 2))
        self._out = np.empty(self.pairs.shape[0], dtype=np.int64)
        self._source: tuple = (None, None)  # the (model, data) whose arrays are in _arrays
        self._arrays: tuple = ()
        self._fromto = np.empty((self.pairs.shape[0], 6))  # mj_geomDistance's, per row
        self._fromto_rows = list(self._fromto)  # (their views, made once)
        self._chains: tuple = (None,)  # (model, starts, dofs, roots) of contact_rows

    def contact_rows(
        self, limit: mink.CollisionAvoidanceLimit, data: mujoco.MjData, dt: float, mink_units: bool
    ) -> tuple[np.ndarray, np.ndarray, list[int], int]:
        """``(G, h, kept, fewest)`` of the pairs of ``limit`` (this culling's) that
        ``mj_geomDistance`` finds within its detection distance at ``data`` (``mj_kinematics``
        and ``mj_comPos`` done; the pairs :meth:`candidates` keeps where ``limit.broadphase``,
        else every pair, as mink checks them): their indices
        ``kept``, their rows ``G`` (k, nv), ``sign n^T (J_2 - J_1)`` as mink's
        ``compute_contact_normal_jacobian`` makes them and signs them (``sign = -1`` where
        ``d >= 0``, else 1), their right sides ``h`` (k,) and the fewest nonzero entries of a
        row (nv where none), by the compiled engine (``_engine.limits.contact_normal_rows``:
        MuJoCo's ``mj_jac`` and ``mju_normalize3`` arithmetic). ``mink_units``: mink's
        limit (a pair left out where ``|d - distmax| < 1e-12``, ``h`` the velocity bound
        ``gain (d - d_min) / dt + relaxation`` where ``d > d_min``, else ``relaxation``);
        else qpik's (left out where ``d >= distmax - 1e-12``, ``h = gain (d - d_min) +
        relaxation`` [m])."""
        model = limit.model
        distmax = limit.collision_detection_distance
        indices: list | range = range(limit.max_num_contacts)
        if limit.broadphase:
            indices = self.candidates(model, data, distmax + CULLING_SLACK)
        chains = self._chains
        if chains[0] is not model:  # each pair's two bodies' dof chains (mj_jac's order)
            bodies = model.geom_bodyid[self.pairs.reshape(-1)]
            frames = np.stack([np.ones_like(bodies), bodies], axis=1)
            chains = self._chains = (model, *frame_chains(model, frames))
        ids, rows = self.pairs, self._fromto_rows
        dist: list[float] = []
        kept: list[int] = []
        for idx in indices:
            d = mujoco.mj_geomDistance(
                model, data, int(ids[idx, 0]), int(ids[idx, 1]), distmax, rows[len(kept)]
            )
            if abs(d - distmax) < 1e-12 if mink_units else d >= distmax - 1e-12:
                continue
            dist.append(d)
            kept.append(idx)
        G, h, fewest = _engine.contact_normal_rows(
            data.cdof, data.subtree_com, *chains[1:], kept, self._fromto, dist, float(limit.gain),
            float(limit.minimum_distance_from_collisions), float(limit.bound_relaxation),
            float(dt), mink_units,
        )  # fmt: skip
        return G, h, kept, fewest

    def candidates(self, model: mujoco.MjModel, data: mujoco.MjData, threshold: float) -> list:
        """Indices (ascending, into the pairs) of the pairs that may be within
        ``threshold`` [m] at ``data``'s geom placement (``mj_kinematics`` done)."""
        source = self._source
        if source[0] is not model or source[1] is not data:
            # Views on the model's and data's own memory (read at each call, so a geom
            # resized in place is seen), taken once per (model, data).
            self._arrays = (
                model.geom_type, model.geom_size, model.geom_aabb, model.geom_rbound,
                data.geom_xpos, data.geom_xmat,
            )  # fmt: skip
            self._source = (model, data)
        count = _engine.collision_candidates(
            self.pairs, *self._arrays, float(threshold), self._out
        )  # fmt: skip
        return self._out[:count].tolist()


#: Each limit's culling by the limit's id: (weak reference to the limit, the pair list it
#: was built from, the culling); an entry goes when its limit does.
_CULLINGS: dict[int, tuple] = {}


def _forget(key: int) -> Callable[[weakref.ref], None]:
    """The callback that drops the entry ``key`` when its limit goes."""

    def forget(_: weakref.ref) -> None:
        _CULLINGS.pop(key, None)

    return forget


def _culling(limit: mink.CollisionAvoidanceLimit) -> PairCulling:
    """The :class:`PairCulling` of ``limit``'s ``geom_id_pairs`` (kept while it holds the
    same list of the same length)."""
    pairs = limit.geom_id_pairs
    entry = _CULLINGS.get(id(limit))
    if (
        entry is None
        or entry[0]() is not limit
        or entry[1] is not pairs
        or entry[2].pairs.shape[0] != len(pairs)
    ):
        key = id(limit)
        entry = (weakref.ref(limit, _forget(key)), pairs, PairCulling(pairs))
        _CULLINGS[key] = entry
    return entry[2]


def near_pairs(
    limit: mink.CollisionAvoidanceLimit,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    threshold: float,
) -> list[int]:
    """Indices (ascending, into ``limit.geom_id_pairs``) of the pairs that may be within
    ``threshold`` [m] at ``data``'s geom placement (``mj_kinematics`` done): every pair
    closer than that, and a few more (:class:`PairCulling`, kept per limit)."""
    return _culling(limit).candidates(model, data, threshold)


def mink_collision_rows(
    limit: mink.CollisionAvoidanceLimit, configuration: mink.Configuration, dt: float
) -> tuple[np.ndarray, np.ndarray, list[int], int]:
    """The rows of mink's own :class:`mink.CollisionAvoidanceLimit` that are in play:
    ``(G, h, pairs, fewest)``, the rows ``G dq <= h`` of the pairs within the detection
    distance, those pairs' indices (ascending) into ``limit.geom_id_pairs`` and the fewest
    nonzero entries of a row (nv where there is none).

    They are the rows of :meth:`mink.CollisionAvoidanceLimit.compute_qp_inequalities` that
    are not left out (mink's other rows are zero, with ``h = inf``), computed by mink's own
    arithmetic (``mj_geomDistance``, mink's contact normal Jacobian; ``h`` in mink's units,
    a velocity bound ``gain (d - d_min) / dt``; :meth:`PairCulling.contact_rows`), so
    bitwise mink's where its final product ``n @ (J_2 - J_1)`` sums its three terms in
    order; NumPy hands that product to its BLAS, whose kernel on some CPUs fuses
    multiply-adds (OpenBLAS's SkylakeX ``dgemv``), and there mink's rows differ from these
    by an ulp. These rows are the same on every machine. The pairs out of range
    are culled first by :class:`PairCulling` instead of mink's bounding spheres (every pair
    is checked when ``limit.broadphase`` is False, as mink does)."""
    return _culling(limit).contact_rows(limit, configuration.data, dt, True)


def _geom_label(model: mujoco.MjModel, geom: int) -> str:
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
    if name:
        return repr(name)
    body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, model.geom_bodyid[geom])
    return f"geom {geom} (body {body!r})"


class CollisionAvoidanceLimit(mink.CollisionAvoidanceLimit):
    """Keep geom pairs at least ``minimum_distance_from_collisions`` apart [m].

    Args (mink's, same names and defaults):
        model: the MuJoCo model.
        geom_pairs: pairs of geom groups ``[(["hand", "link7"], ["obstacle"]), ...]``,
            geoms by name or id; every geom of the first group is checked against every
            geom of the second.
        gain: fraction in (0, 1] of the margin above ``d_min`` the pair may close per step.
        minimum_distance_from_collisions: ``d_min`` [m] (signed, as MuJoCo's distances: a
            negative one lets the pair penetrate that deep, as mink takes it).
        collision_detection_distance: pairs farther apart than this [m] get no row.
        bound_relaxation: added to every row's right side [m].
        broadphase: cull the pairs provably out of range before computing distances
            (:class:`PairCulling`; exact: the rows are those of checking every pair, which
            ``False`` does).
        respect_contype: apply MuJoCo's ``contype``/``conaffinity`` filter to the pairs
            (mink does). ``False`` checks the pairs you list whatever their contact bits
            (geoms that only exist for the IK, or a model whose geoms are visual only).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        geom_pairs: CollisionPairs,
        gain: float = 0.85,
        minimum_distance_from_collisions: float = 0.005,
        collision_detection_distance: float = 0.01,
        bound_relaxation: float = 0.0,
        broadphase: bool = True,
        *,
        respect_contype: bool = True,
    ):
        check_model_type("model", model)
        for name, value in (
            ("gain", gain),
            ("minimum_distance_from_collisions", minimum_distance_from_collisions),
            ("collision_detection_distance", collision_detection_distance),
            ("bound_relaxation", bound_relaxation),
        ):
            if not checks.is_real(value):
                raise InvalidArgumentType(name, "a real number", checks.type_name(value))
        gain = float(gain)
        minimum_distance_from_collisions = float(minimum_distance_from_collisions)
        collision_detection_distance = float(collision_detection_distance)
        bound_relaxation = float(bound_relaxation)
        checks.check_bool("broadphase", broadphase)
        checks.check_bool("respect_contype", respect_contype)
        if not 0.0 < gain <= 1.0:
            raise LimitDefinitionError(f"gain must be in (0, 1], got {gain}")
        for name, value in (
            ("minimum_distance_from_collisions", minimum_distance_from_collisions),
            ("collision_detection_distance", collision_detection_distance),
            ("bound_relaxation", bound_relaxation),
        ):
            if not np.isfinite(value):
                raise LimitDefinitionError(f"{name} must be finite, got {value}")
        if not collision_detection_distance > minimum_distance_from_collisions:
            raise LimitDefinitionError(
                f"collision_detection_distance ({collision_detection_distance}) must exceed "
                f"minimum_distance_from_collisions ({minimum_distance_from_collisions})"
            )
        self.respect_contype = respect_contype
        self._model_for_pairs = model
        groups = self._resolve_pairs(model, geom_pairs)
        self._groups = groups
        super().__init__(
            model,
            geom_pairs,
            gain=gain,
            minimum_distance_from_collisions=minimum_distance_from_collisions,
            collision_detection_distance=collision_detection_distance,
            bound_relaxation=bound_relaxation,
            broadphase=broadphase,
        )
        if not self.geom_id_pairs:
            raise CollisionPairError(self._why_no_pairs(model))

    # ----------------------------------------------------------------- pairs
    @staticmethod
    def _resolve_pairs(model: mujoco.MjModel, geom_pairs) -> list[tuple[list[int], list[int]]]:
        """Geom ids of each pair of groups; :class:`UnknownFrame` lists the geoms."""
        try:
            pairs = list(geom_pairs)
        except TypeError:
            raise LimitDefinitionError(
                f"geom_pairs must be a list of (group, group) pairs, got {geom_pairs!r}"
            ) from None
        if not pairs:
            raise CollisionPairError("geom_pairs is empty: give at least one (group, group) pair")
        resolved = []
        for k, pair in enumerate(pairs):
            if not isinstance(pair, (tuple, list)) or len(pair) != 2:
                raise LimitDefinitionError(
                    f"geom_pairs[{k}] must be a (group, group) pair, got {pair!r}"
                )
            ids = []
            for group in pair:
                group = [group] if isinstance(group, (str, int, np.integer)) else group
                if not isinstance(group, (list, tuple, np.ndarray)):
                    raise LimitDefinitionError(
                        f"geom_pairs[{k}] must hold geom names or ids, got {group!r}"
                    )
                group_ids = []
                for geom in group:
                    if not isinstance(geom, (str, int, np.integer)) or isinstance(geom, bool):
                        raise LimitDefinitionError(
                            f"geom_pairs[{k}] must hold geom names or ids, got {geom!r}"
                        )
                    if isinstance(geom, str):
                        gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
                    else:
                        gid = int(geom) if 0 <= int(geom) < model.ngeom else -1
                    if gid < 0:
                        raise UnknownFrame(geom, "geom", frame_names(model, "geom"))
                    group_ids.append(gid)
                ids.append(sorted(set(group_ids)))
            resolved.append((ids[0], ids[1]))
        return resolved

    def _construct_geom_id_pairs(self, geom_pairs) -> list[tuple[int, int]]:
        """mink's rules, with the contype filter optional; sorted (deterministic rows)."""
        model = self._model_for_pairs
        pairs = set()
        for group_a, group_b in self._resolve_pairs(model, geom_pairs):
            for a, b in itertools.product(group_a, group_b):
                if self._reject(model, a, b) is None:
                    pairs.add((min(a, b), max(a, b)))
        return sorted(pairs)

    def _reject(self, model: mujoco.MjModel, a: int, b: int) -> str | None:
        """Why mink's rules drop the pair ``(a, b)``, or None if it is kept."""
        if a == b or welded_together(model, a, b):
            return "same body (or bodies welded together)"
        if welded_parent_and_child(model, a, b):
            return "parent and child bodies"
        if self.respect_contype and not contact_bits_match(model, a, b):
            return "contype/conaffinity exclude contact"
        return None

    def _why_no_pairs(self, model: mujoco.MjModel) -> str:
        reasons: dict[str, list[str]] = {}
        for group_a, group_b in self._groups:
            for a, b in itertools.product(group_a, group_b):
                reason = self._reject(model, a, b) or "?"
                reasons.setdefault(reason, []).append(
                    f"{_geom_label(model, a)}-{_geom_label(model, b)}"
                )
        parts = []
        for reason, pairs in reasons.items():
            shown = ", ".join(pairs[:4]) + (" ..." if len(pairs) > 4 else "")
            parts.append(f"{len(pairs)} pair(s) dropped: {reason} ({shown})")
        message = "CollisionAvoidanceLimit found no geom pair to check: " + "; ".join(parts)
        if "contype/conaffinity exclude contact" in reasons:
            geoms = sorted({g for pair in self._groups for group in pair for g in group})
            bits = ", ".join(
                f"{_geom_label(model, g)}: contype={int(model.geom_contype[g])} "
                f"conaffinity={int(model.geom_conaffinity[g])}"
                for g in geoms[:6]
            )
            message += (
                f". Contact needs (contype1 & conaffinity2) or (contype2 & conaffinity1) "
                f"nonzero; {bits}. Set contype/conaffinity in the model, or pass "
                "respect_contype=False to check these pairs anyway"
            )
        return message

    # ------------------------------------------------------------------ rows
    def compute_qp_inequalities(
        self, configuration: mink.Configuration, dt: float
    ) -> mink.Constraint:
        """``G dq <= h`` [m]: one row per pair within ``collision_detection_distance``
        (rows of pairs out of range are left out; no row at all: an inactive constraint).
        ``dt`` is not used: both sides are displacements."""
        G, h, active, _ = self.rows_in_play(configuration, dt)
        if not active:
            return mink.Constraint()
        return mink.Constraint(G=G, h=h)

    def rows_in_play(
        self, configuration: mink.Configuration, dt: float
    ) -> tuple[np.ndarray, np.ndarray, list[int], int]:
        """:meth:`compute_qp_inequalities`' rows as ``(G, h, pairs, fewest)``: ``G dq <= h``
        [m], one row per pair within ``collision_detection_distance``, those pairs' indices
        (ascending) into ``geom_id_pairs`` and the fewest nonzero entries of a row (nv where
        there is none). ``dt`` is not used."""
        # Pairs provably out of range are culled first (PairCulling: the same rows as
        # checking every pair; mink's bounding-sphere broadphase is looser).
        return _culling(self).contact_rows(self, configuration.data, dt, False)

    def distances(self, configuration: mink.Configuration) -> dict[tuple[str, str], float]:
        """Distance [m] of every checked pair (``mj_geomDistance``, negative when they
        penetrate, capped at 1 m), keyed by the two geoms' labels."""
        out = {}
        for geom1, geom2 in self.geom_id_pairs:
            distance = mujoco.mj_geomDistance(
                self.model, configuration.data, geom1, geom2, 1.0, None
            )
            out[(_geom_label(self.model, geom1), _geom_label(self.model, geom2))] = distance
        return out


def geom_distance(
    configuration: mink.Configuration, geom1: Geom, geom2: Geom, cap: float = 1.0
) -> float:
    """Signed distance [m] between two geoms at the configuration (MuJoCo's
    ``mj_geomDistance``: negative when they penetrate, ``cap`` when farther apart)."""
    checks.check_instance(
        "configuration", configuration, mink.Configuration, "a qpik.Configuration"
    )
    cap = checks.check_real("cap", cap, 0.0)
    model = configuration.model
    ids = []
    for name, geom in (("geom1", geom1), ("geom2", geom2)):
        if isinstance(geom, str):
            gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
            if gid < 0:
                raise UnknownFrame(geom, "geom", frame_names(model, "geom"))
        else:
            gid = checks.check_index(name, geom, model.ngeom)
        ids.append(gid)
    return float(mujoco.mj_geomDistance(model, configuration.data, ids[0], ids[1], cap, None))
