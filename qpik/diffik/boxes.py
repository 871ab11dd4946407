"""The limit side of a step: a solver's limits become box bounds ``lb <= dq <= ub`` and
general rows ``G dq <= h``, and the limits that bind at a step's ``dq`` get their names.

mink's ``ConfigurationLimit`` and ``VelocityLimit`` are computed directly as boxes on models
of hinge and slide joints; every other limit goes through its ``compute_qp_inequalities``,
whose single-dof rows fold into the box and whose other rows stay general. The trust region
(:attr:`qpik.StepOptions.max_joint_speed`) bounds the dofs that no velocity limit bounds.
Position limits are recoverable (a start outside them steers back), velocity limits and the
trust region hard; the two boxes merge by :func:`qpik.core.kernels.merge_boxes`.
:class:`LimitBoxes` holds one solver's limits; :class:`LimitRows` is what they give at one
configuration.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import mink
import mujoco
import numpy as np

from .._engine import limits as _limits_engine
from ..core import checks
from ..core.kernels import ABSENT_BOUND, merge_boxes, tighten
from ..errors import (
    InfeasibleLimits,
    InvalidArgumentType,
    InvalidInput,
    LimitDefinitionError,
    QpikError,
)
from ..limits.collision import NEGLIGIBLE_ROW, CollisionAvoidanceLimit, mink_collision_rows
from ..limits.support import SupportPolygonLimit
from ..model.configuration import Configuration, dof_names
from .limit_inputs import check_limit_model, constraint_rows, limit_name
from .mink_limits import angular_dofs

__all__ = ["BOX_LIMITS", "TRUST_REGION", "LimitBoxes", "LimitRows", "RowStructure", "relaxable"]

#: The name of the step's trust region in :attr:`qpik.StepResult.active_limits`.
TRUST_REGION = "trust region"

#: A box contribution ``(limit name, dofs, bounds)``: one side of one limit's box.
Contribution = tuple[str, np.ndarray, np.ndarray]


def limit_values(limit: Any) -> Any:
    """A position limit's gain (one number in ``(0, 1]``, as mink checks it when the limit
    is built) or a velocity limit's speeds (a float array, ``>= 0`` [rad/s or m/s]), as
    read; LimitDefinitionError naming the limit where it was set to another value later
    (the compiled step's kernel checks the same: ``Kernel.load_limits``). None for another
    limit."""
    if isinstance(limit, mink.ConfigurationLimit):
        gain = limit.gain
        try:
            valid = np.ndim(gain) == 0 and 0.0 < float(gain) <= 1.0
        except (TypeError, ValueError):
            valid = False
        if not valid:
            raise LimitDefinitionError(
                f"{limit_name(limit)}: its gain must be a number in (0, 1], got {gain!r}"
            )
        return gain
    if isinstance(limit, mink.VelocityLimit):
        try:
            speeds = np.asarray(limit.limit, dtype=float)
        except (TypeError, ValueError) as exc:
            raise LimitDefinitionError(
                f"{limit_name(limit)}: its limit must be speeds >= 0 ({exc})"
            ) from exc
        if not (speeds >= 0.0).all():
            raise LimitDefinitionError(
                f"{limit_name(limit)}: its limit must be speeds >= 0, got {limit.limit!r}"
            )
        return speeds
    return None


def limit_bounds(limit: mink.ConfigurationLimit, adr: np.ndarray) -> tuple[np.ndarray, ...]:
    """A position limit's bounds ``(lower, upper)`` [rad or m] at the qpos entries ``adr`` of
    its dofs: LimitDefinitionError naming the limit where they do not fit (bounds set after
    it was built) or one is NaN, InfeasibleLimits where a joint's lower bound is above its
    upper (no displacement meets them: as for mink's ``min_distance_from_limits`` of more
    than half a range)."""
    try:
        lower = np.asarray(limit.lower, dtype=float)
        upper = np.asarray(limit.upper, dtype=float)
        if lower.ndim != 1 or upper.ndim != 1:
            raise ValueError(f"bounds of shapes {lower.shape} and {upper.shape}")
        q_min, q_max = lower[adr], upper[adr]
    except (TypeError, ValueError, IndexError) as exc:
        raise LimitDefinitionError(
            f"{limit_name(limit)}: its lower and upper bounds do not fit its dofs ({exc})"
        ) from exc
    if np.isnan(q_min).any() or np.isnan(q_max).any():
        raise LimitDefinitionError(f"{limit_name(limit)}: a lower or upper bound is NaN")
    empty = np.flatnonzero(q_min > q_max)
    if empty.size:
        raise InfeasibleLimits(
            f"{limit_name(limit)}: the limits of dof {int(limit.indices[empty[0]])} are empty "
            "(its lower bound above its upper: bounds set so, or min_distance_from_limits "
            "more than half its range)"
        )
    return q_min, q_max


def _qpos_addresses(limit: mink.ConfigurationLimit) -> np.ndarray:
    """The qpos entries of a position limit's dofs (a free or ball joint moves them apart)."""
    model = limit.model
    return model.jnt_qposadr[model.dof_jntid[limit.indices]]


def _configuration_box(
    limit: mink.ConfigurationLimit, qpos: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """mink's ConfigurationLimit as box bounds on ``dq`` at ``qpos`` (nq,): its hinge and
    slide joints' rows (each dof's coordinate at its joint's qpos address)."""
    if len(limit.indices) == 0:  # no limited joint (mink keeps an empty float array)
        return np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0)
    adr = limit.indices
    if qpos.shape[0] != limit.model.nv:  # free or ball joints: dof index != qpos index
        adr = _qpos_addresses(limit)
    gain = float(limit_values(limit))
    q = qpos[adr]
    q_min, q_max = limit_bounds(limit, adr)  # (checked: set after the limit was built?)
    upper = gain * (q_max - q)
    lower = -gain * (q - q_min)
    return limit.indices, lower, upper


def _velocity_box(
    limit: mink.VelocityLimit, qpos: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """mink's VelocityLimit as box bounds on ``dq``: ``|dq| <= v_max dt`` (``limit.limit``
    read as floats, as the compiled step reads it)."""
    bound = limit_values(limit) * dt
    return limit.indices, -bound, bound


def _box_of(box: Callable, limit: Any, qpos: np.ndarray, dt: float) -> tuple[np.ndarray, ...]:
    """``box(limit, qpos, dt)`` (a BOX_LIMITS entry): LimitDefinitionError naming the limit
    where an attribute set directly (its gain, bounds or speeds) does not fit its dofs."""
    try:
        dofs, lower, upper = box(limit, qpos, dt)
        dofs = np.asarray(dofs, dtype=np.int64)
        lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    except QpikError:
        raise
    except (ValueError, TypeError, IndexError) as exc:
        raise LimitDefinitionError(f"{limit_name(limit)}: its rows failed ({exc})") from exc
    if not (lower.shape == upper.shape == dofs.shape and dofs.ndim == 1):
        raise LimitDefinitionError(
            f"{limit_name(limit)}: bounds of shape {lower.shape} for {dofs.shape[0]} dofs "
            "(a gain, bound or speed set to what does not fit?)"
        )
    return dofs, lower, upper


#: Limits whose rows are known to be single-dof bounds, computed directly as boxes (exact
#: type match: a subclass may change the rows).
BOX_LIMITS: dict[type, Callable[[Any, np.ndarray, float], tuple[np.ndarray, ...]]] = {
    mink.ConfigurationLimit: _configuration_box,
    mink.VelocityLimit: _velocity_box,
}


def _trust_region(nv: int, limits: Sequence, speed: float | None) -> tuple[np.ndarray, np.ndarray]:
    """``(dofs, speeds)`` of the trust region: the dofs that no velocity limit of
    ``limits`` bounds (mink's or qpik's ``VelocityLimit``), each at ``speed`` [rad/s or
    m/s]; empty when ``speed`` is None."""
    if speed is None:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    bounded = np.zeros(nv, dtype=bool)
    for limit in limits:
        if isinstance(limit, mink.VelocityLimit) and len(limit.indices):
            bounded[np.asarray(limit.indices, dtype=np.int64)] = True
    dofs = np.flatnonzero(~bounded).astype(np.int64)
    return dofs, np.full(dofs.size, float(speed))


def _add_sides(contributions: list, name: str, dofs: np.ndarray, lower, upper) -> None:
    """Both sides of a box as contributions, upper first."""
    contributions.append((name, dofs, upper))
    contributions.append((name, dofs, lower))


@dataclass(frozen=True)
class RowStructure:
    """Rows of a limit's ``G``: single-dof upper / lower bounds (row, dof, 1/coefficient),
    general rows, and empty rows; ``unique`` when no dof is bounded twice on one side."""

    upper_rows: np.ndarray
    upper_dofs: np.ndarray
    upper_scale: np.ndarray
    lower_rows: np.ndarray
    lower_dofs: np.ndarray
    lower_scale: np.ndarray
    general: np.ndarray
    empty: np.ndarray | None
    unique: bool

    @classmethod
    def of(cls, G: np.ndarray) -> RowStructure:
        """The structure of ``G`` (p, nv)."""
        nonzero = G != 0.0
        count = nonzero.sum(axis=1)
        unit = np.flatnonzero(count == 1)
        dofs = np.argmax(nonzero[unit], axis=1) if unit.size else np.zeros(0, dtype=int)
        coefficients = G[unit, dofs]
        up = coefficients > 0
        empty = np.flatnonzero(count == 0)
        return cls(
            upper_rows=unit[up],
            upper_dofs=dofs[up],
            upper_scale=1.0 / coefficients[up],
            lower_rows=unit[~up],
            lower_dofs=dofs[~up],
            lower_scale=1.0 / coefficients[~up],
            general=np.flatnonzero(count > 1),
            empty=empty if empty.size else None,
            unique=len(set(dofs[up].tolist())) == up.sum()
            and len(set(dofs[~up].tolist())) == (~up).sum(),
        )


@dataclass(frozen=True)
class LimitRows:
    """The limits at one configuration: the box ``lb <= dq <= ub`` (nv,), the general rows
    ``G dq <= h`` (p, nv) named ``row_names``, and (for naming the limits that bind)
    ``sources()``, the box's contributions ``(limit name, dofs, bounds)``."""

    lb: np.ndarray
    ub: np.ndarray
    G: np.ndarray
    h: np.ndarray
    row_names: list[str]
    sources: Callable[[], list[Contribution]]
    dof_names: Sequence[str]
    #: (p,) bool: the general rows that may be relaxed (:func:`relaxable`); None: none
    relaxable: np.ndarray | None = None

    def active(self, d: np.ndarray) -> list[str]:
        """The limits that bind at ``d``, e.g. ``"joint4 upper (ConfigurationLimit)"``, then
        the general rows that bind (by name)."""
        tol = 1e-9
        active = []
        contributions = None
        for side, bound, at_bound in (
            ("upper", self.ub, np.isfinite(self.ub) & (d >= self.ub - tol)),
            ("lower", self.lb, np.isfinite(self.lb) & (d <= self.lb + tol)),
        ):
            for i in np.flatnonzero(at_bound):
                if contributions is None:
                    contributions = self.sources()
                source = next(
                    (
                        name
                        for name, dofs, bounds in contributions
                        if np.any((dofs == i) & (np.abs(bounds - bound[i]) <= tol))
                    ),
                    "limit",
                )
                active.append(f"{self.dof_names[int(i)]} {side} ({source})")
        if self.G.shape[0]:
            # (a row whose h is ABSENT_BOUND or more bounds nothing: absent from the QP, not named)
            with np.errstate(over="ignore", invalid="ignore"):
                binding = (self.G @ d >= self.h - 1e-7) & (self.h < ABSENT_BOUND)
            for j in np.flatnonzero(binding):
                active.append(self.row_names[int(j)])
        return active


@dataclass
class _Collected:
    """What :meth:`LimitBoxes.rows` gathers from the limits' own rows: the side of the box
    they tighten, the box contributions, and the general rows ``G``, ``h`` and names."""

    lb: np.ndarray
    ub: np.ndarray
    contributions: list[Contribution]
    G: list[np.ndarray] = field(default_factory=list)
    h: list[np.ndarray] = field(default_factory=list)
    names: list[str] = field(default_factory=list)
    relax: list[np.ndarray] = field(default_factory=list)  # per part: rows that may relax


def relaxable(limit: Any) -> bool:
    """Whether a limit's general rows are recoverable (:mod:`qpik.diffik.recovery`): the
    collision rows (mink's :class:`mink.CollisionAvoidanceLimit` and qpik's) and the limits
    that say so (``relaxable_rows = True``: :class:`qpik.limits.SupportPolygonLimit`).
    Other limits' rows stay hard."""
    return isinstance(limit, mink.CollisionAvoidanceLimit) or bool(
        getattr(limit, "relaxable_rows", False)
    )


class LimitBoxes:
    """One solver's limits (mink's or qpik's), checked once, and what they give at each
    configuration: :meth:`rows` (the box and general rows of a step),
    :meth:`contributions` (the box limits' sides, to name the limits that bind) and
    :meth:`general_rows` (the rows of limits that stay general).

    Args:
        model: the robot's model.
        limits: the limits, enforced at every level.
        max_joint_speed: the trust region's speed [rad/s or m/s] on the dofs no velocity
            limit bounds, or None for none.
    """

    def __init__(
        self, model: mujoco.MjModel, limits: Iterable, max_joint_speed: float | None
    ) -> None:
        if (
            isinstance(limits, (str, bytes, Mapping))
            or not checks.is_iterable(limits)
            or (isinstance(limits, np.ndarray) and limits.ndim == 0)
        ):
            raise InvalidArgumentType("limits", "a list of limits", checks.type_name(limits))
        self.limits = list(limits)
        for limit in self.limits:
            _check_limit(limit, model)
            box = BOX_LIMITS.get(type(limit))
            if box is not None:
                # its values as a step reads them (attributes set after the limit was built:
                # the same typed errors here as at a step)
                _box_of(box, limit, model.qpos0, 1.0)
        nv = model.nv
        #: Each dof's name (in messages and active-limit names): its joint's, ``[k]`` added
        #: on a joint of several dofs (:func:`qpik.model.configuration.dof_names`).
        self.dof_names = dof_names(model)
        #: The trust region: the dofs that no velocity limit bounds, and their speed bound
        #: [rad/s or m/s] (empty when ``max_joint_speed`` is None).
        self.trust_dofs, self.trust_speeds = _trust_region(nv, self.limits, max_joint_speed)
        #: All joints hinges or slides: mink's box limits are computed directly.
        self.scalar_joints = model.nq == nv and bool(
            np.all(
                np.isin(model.jnt_type, [mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE])
            )
        )
        #: No general rows: ``G`` (0, nv).
        self.no_rows = np.zeros((0, nv))
        self._structures: dict[int, tuple[np.ndarray, RowStructure]] = {}
        #: general_rows' names of a limit's rows, by the limit, its rows' numbers and the
        #: rows on one dof (they change only when a pair comes in or out of range)
        self._row_names: dict[tuple, list[str]] = {}
        self._bounds = tuple(np.empty(nv) for _ in range(4))  # scratch of rows()

    def _trust_box(self, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The trust region as box bounds on ``dq``: ``|dq| <= speed dt`` (as mink's
        velocity limit, so that every path computes the same bits)."""
        bound = self.trust_speeds * dt
        return self.trust_dofs, -bound, bound

    def structure(self, limit, G: np.ndarray) -> RowStructure:
        """How a limit's rows split into single-dof bounds and general rows. Cached while
        ``G`` is unchanged (mink's position and velocity limits return the same ``G``)."""
        cached = self._structures.get(id(limit))
        if cached is not None and cached[0].shape == G.shape and np.array_equal(cached[0], G):
            return cached[1]
        structure = RowStructure.of(G)
        self._structures[id(limit)] = (G.copy(), structure)
        return structure

    def rows(self, configuration: Configuration, dt: float, fold: bool = True) -> LimitRows:
        """Box bounds ``lb <= dq <= ub`` and general rows ``G dq <= h`` of all limits at
        ``configuration`` for a step of ``dt`` [s]; raises :class:`qpik.InfeasibleLimits`
        where the box admits no displacement. ``fold=False``: the rows of the relaxable
        limits (:func:`relaxable`: collision rows, the support polygon) all stay general
        rows, their one-dof rows and their empty rows that no displacement meets included
        (for the step's recovery, :mod:`qpik.diffik.recovery`, where folding them made the
        box empty)."""
        hard_lb, hard_ub, pos_lb, pos_ub = self._bounds
        hard_lb.fill(-np.inf)
        hard_ub.fill(np.inf)
        pos_lb.fill(-np.inf)
        pos_ub.fill(np.inf)
        hard = _Collected(hard_lb, hard_ub, [])
        recoverable = _Collected(
            pos_lb, pos_ub, hard.contributions, hard.G, hard.h, hard.names, hard.relax
        )
        for limit in self.limits:
            side = hard
            if isinstance(limit, mink.ConfigurationLimit) or getattr(limit, "recoverable", False):
                side = recoverable
            box = BOX_LIMITS.get(type(limit)) if self.scalar_joints else None
            if box is None:
                limit_values(limit)  # (mink's rows take them as they are)
                if isinstance(limit, mink.ConfigurationLimit) and len(limit.indices):
                    limit_bounds(limit, _qpos_addresses(limit))
                if fold or side is recoverable or not relaxable(limit):
                    self._inequalities(limit, configuration, dt, side)
                else:
                    _unfolded(limit, configuration, dt, side)
                continue
            dofs, lower, upper = _box_of(box, limit, configuration.data.qpos, dt)
            if len(dofs):
                tighten(side.lb, side.ub, dofs, lower, upper)
                _add_sides(side.contributions, limit_name(limit), dofs, lower, upper)
        if self.trust_dofs.size:  # the trust region: a hard bound, as a velocity limit's
            dofs, lower, upper = self._trust_box(dt)
            tighten(hard_lb, hard_ub, dofs, lower, upper)
            _add_sides(hard.contributions, TRUST_REGION, dofs, lower, upper)
        lb, ub, i = merge_boxes(hard_lb, hard_ub, pos_lb, pos_ub)
        if i >= 0:
            raise InfeasibleLimits(
                f"limits on {self.dof_names[i]} need {hard_lb[i]:.6g} <= dq <= "
                f"{hard_ub[i]:.6g}: no displacement satisfies them"
            )
        G = np.vstack(hard.G) if hard.G else self.no_rows
        h = np.concatenate(hard.h) if hard.h else np.zeros(0)
        contributions = hard.contributions
        relax = np.concatenate(hard.relax) if hard.relax else np.zeros(0, dtype=bool)
        return LimitRows(lb, ub, G, h, hard.names, lambda: contributions, self.dof_names, relax)

    def _inequalities(self, limit, configuration: Configuration, dt: float, side: _Collected):
        """A limit's ``compute_qp_inequalities`` split into single-dof bounds (tightening
        ``side``'s box in place) and general rows (appended to ``side``)."""
        rows_of = _inequalities_of(limit, configuration, dt)
        if rows_of is None:
            return
        G, h, numbers, _ = rows_of
        name = limit_name(limit)
        structure = self.structure(limit, G)
        if structure.empty is not None and np.any(h[structure.empty] < 0):
            raise InfeasibleLimits(f"{name} has a row 0 . dq <= {h[structure.empty].min():.3g}")
        s = structure
        for rows, dofs, scale, bound, pick in (
            (s.upper_rows, s.upper_dofs, s.upper_scale, side.ub, np.minimum),
            (s.lower_rows, s.lower_dofs, s.lower_scale, side.lb, np.maximum),
        ):
            if rows.size:
                bounds = h[rows] * scale
                if structure.unique:
                    bound[dofs] = pick(bound[dofs], bounds)
                else:
                    pick.at(bound, dofs, bounds)
                side.contributions.append((name, dofs, bounds))
        if structure.general.size:
            side.G.append(G[structure.general])
            side.h.append(h[structure.general])
            side.relax.append(np.full(structure.general.size, relaxable(limit)))
            side.names.extend(
                f"{name} row {int(r if numbers is None else numbers[r])}" for r in structure.general
            )

    def contributions(self, qpos: np.ndarray, dt: float) -> list[Contribution]:
        """The box limits' contributions ``(name, dofs, bounds)`` at ``qpos`` (nq,), upper
        side first, then the trust region's (as :meth:`rows` lists them, for a step whose
        limits are box limits and general-row limits only)."""
        contributions: list[Contribution] = []
        for limit in self.limits:
            box = BOX_LIMITS.get(type(limit))
            if type(limit) is mink.FreeJointVelocityLimit and limit.angular_max is not None:
                # its angular rows, one dof each: the box's (.mink_limits.FreeJointAngular)
                dofs = angular_dofs(limit)
                bound = dt * np.asarray(limit.angular_max, dtype=float)
                _add_sides(contributions, limit_name(limit), dofs, -bound, bound)
            if box is None:  # a general-row limit
                continue
            dofs, lower, upper = _box_of(box, limit, qpos, dt)
            _add_sides(contributions, limit_name(limit), dofs, lower, upper)
        if self.trust_dofs.size:
            _add_sides(contributions, TRUST_REGION, *self._trust_box(dt))
        return contributions

    def _names_of(self, limit, rows, numbers: list[int] | None, one_dof: list) -> list[str]:
        """:meth:`general_rows`' names of a limit's kept ``rows`` (``numbers``: their rows in
        the limit's own, where not the same), a row on one dof named as the box bound the QP
        path makes of it (``one_dof``: :func:`_multi_dof_rows`'); kept by the rows."""
        if numbers is not None:
            kept: Any = tuple(numbers[r] for r in rows)
        else:
            kept = len(rows) if type(rows) is range else tuple(rows.tolist())
        key = (id(limit), kept, tuple(one_dof))
        part = self._row_names.get(key)
        if part is None:
            name = limit_name(limit)
            part = [f"{name} row {int(r if numbers is None else numbers[r])}" for r in rows]
            for k, dof, upper in one_dof:
                part[k] = f"{self.dof_names[dof]} {'upper' if upper else 'lower'} ({name})"
            if len(self._row_names) >= 256:
                self._row_names.clear()
            self._row_names[key] = part
        return part

    def general_rows(
        self, limits: Sequence, configuration: mink.Configuration, dt: float
    ) -> tuple[np.ndarray, np.ndarray, list[str]] | None:
        """``(G, h, names)`` of ``limits`` as :meth:`rows` takes them (empty rows dropped; a
        row on one dof, which :meth:`rows` makes a box bound, kept as a general row named as
        that bound: see :func:`_multi_dof_rows`), None when an empty row is infeasible
        (:meth:`rows` names it) or a limit's own ``compact_rows`` declines."""
        G_parts: list[np.ndarray] = []
        h_parts: list[np.ndarray] = []
        names: list[str] = []
        for limit in limits:
            compact = getattr(limit, "compact_rows", None)  # (rows in play, named: as below)
            if compact is not None:
                rows_in_play = compact(configuration, dt)
                if rows_in_play is None:
                    return None
                if rows_in_play is not NotImplemented:
                    if rows_in_play[0].shape[0]:
                        G_parts.append(rows_in_play[0])
                        h_parts.append(rows_in_play[1])
                        names.extend(rows_in_play[2])
                    continue
            rows_of = _inequalities_of(limit, configuration, dt)
            if rows_of is None or not rows_of[0].shape[0]:
                continue
            split = _multi_dof_rows(rows_of[0], rows_of[1], rows_of[3])
            if split is None:
                return None
            G, h, rows, one_dof = split
            if not len(rows):
                continue
            numbers = rows_of[2]
            G_parts.append(G)
            h_parts.append(h)
            names.extend(self._names_of(limit, rows, numbers, one_dof))
        if not G_parts:
            return self.no_rows, np.zeros(0), names
        G = np.ascontiguousarray(np.vstack(G_parts) if len(G_parts) > 1 else G_parts[0], float)
        h = np.ascontiguousarray(np.concatenate(h_parts) if len(h_parts) > 1 else h_parts[0], float)
        return G, h, names


def _multi_dof_rows(
    G: np.ndarray, h: np.ndarray, fewest: int | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray | range, list[tuple[int, int, bool]]] | None:
    """:meth:`LimitBoxes.general_rows`' rows of one limit: ``(G, h, rows, one_dof)`` its
    rows on one dof or more (``rows``: their numbers in ``G``; copies, not the limit's
    arrays, except where ``fewest`` says that every row is on two dofs or more: then they
    are new arrays, kept as they are) and, for each kept row on one dof, ``(k, dof,
    upper)``: its place in the kept rows, its dof and whether it bounds it from above. None
    where an empty row is infeasible (RowStructure.of's split, without its bookkeeping:
    these rows change each step; :meth:`LimitBoxes.rows` names it).

    A row on one dof stays a general row of the compiled step, where the QP path folds it
    into the box (``dq_i <= h / g``): the same feasible set, so the same optimum to
    round-off (before, such a row sent the step to the QP path: a collision pair whose
    link one joint moves, say)."""
    if fewest is not None and fewest >= 2:
        return G, h, range(G.shape[0]), []
    count = np.count_nonzero(G, axis=1)
    if count.min() >= 2:  # (every row on two dofs or more: all kept, in order)
        return G.copy(), h.copy(), range(count.size), []
    counts = count.tolist()  # (a few rows: Python's loops cost less than NumPy's calls)
    kept: np.ndarray | range = range(len(counts))
    if 0 in counts:
        if any(h[k] < 0 for k, c in enumerate(counts) if not c):
            return None
        kept = np.array([k for k, c in enumerate(counts) if c], dtype=np.intp)
        G, h = G[kept], h[kept]
        counts = [c for c in counts if c]
    else:
        G, h = G.copy(), h.copy()
    one_dof = []
    for k, c in enumerate(counts):
        if c == 1:
            dof = int(G[k].nonzero()[0][0])
            one_dof.append((k, dof, bool(G[k, dof] > 0.0)))
    return G, h, kept, one_dof


def _unfolded(limit, configuration: Configuration, dt: float, side: _Collected) -> None:
    """A relaxable limit's ``compute_qp_inequalities`` as general rows only (appended to
    ``side``): every row on one dof or more, and every empty row that no displacement
    meets (``0 <= h < 0``); the empty rows that hold are dropped."""
    rows_of = _inequalities_of(limit, configuration, dt)
    if rows_of is None:
        return
    G, h, numbers, _ = rows_of
    keep = np.flatnonzero(np.any(G != 0.0, axis=1) | (h < 0))
    if keep.size:
        name = limit_name(limit)
        side.G.append(G[keep])
        side.h.append(h[keep])
        side.relax.append(np.ones(keep.size, dtype=bool))
        side.names.extend(f"{name} row {int(r if numbers is None else numbers[r])}" for r in keep)


#: qpik's CollisionAvoidanceLimit's own rows (a subclass that keeps them is read as it is)
_QPIK_COLLISION_ROWS = CollisionAvoidanceLimit.compute_qp_inequalities
#: SupportPolygonLimit's own rows (likewise)
_SUPPORT_ROWS = SupportPolygonLimit.compute_qp_inequalities
_SUPPORT_ROWS_IN_PLAY = SupportPolygonLimit.rows_in_play


def _inequalities_of(
    limit, configuration: mink.Configuration, dt: float
) -> tuple[np.ndarray, np.ndarray, list[int] | None, int | None] | None:
    """A limit's rows ``(G, h, numbers, fewest)`` (None when inactive): its
    ``compute_qp_inequalities`` (``numbers`` None: row ``r`` is the limit's row ``r``;
    ``fewest`` None; for qpik's :class:`~qpik.limits.CollisionAvoidanceLimit` and
    :class:`~qpik.limits.SupportPolygonLimit` the fewest nonzero entries of a row too, from
    their ``rows_in_play``), or, for mink's own :class:`mink.CollisionAvoidanceLimit`,
    only the rows of the pairs in range (:func:`qpik.limits.collision.mink_collision_rows`: mink's
    rows, bitwise; its other rows are zero with ``h = inf``), ``numbers`` their row numbers
    in mink's and ``fewest`` the fewest nonzero entries of a row (new arrays: not the
    limit's own)."""
    rows: tuple[np.ndarray, np.ndarray, list[int] | None, int | None] | None
    flushed = False  # (its negligible rows already zero)
    try:
        if type(limit) is mink.CollisionAvoidanceLimit:
            rows = mink_collision_rows(limit, configuration, dt)
        elif (
            isinstance(limit, CollisionAvoidanceLimit)
            and type(limit).compute_qp_inequalities is _QPIK_COLLISION_ROWS
        ):
            # (its compute_qp_inequalities' rows, and the fewest nonzero entries of a row;
            # model_collision_limit's class too: a subclass with rows of its own keeps them)
            G, h, kept, fewest = limit.rows_in_play(configuration, dt)
            if not kept:
                return None
            rows = G, h, None, fewest
        elif (
            isinstance(limit, SupportPolygonLimit)
            and type(limit).compute_qp_inequalities is _SUPPORT_ROWS
        ):
            # (its rows and the fewest nonzero entries of a row, in one engine call, which
            # also makes its negligible rows zero)
            G, h, fewest = limit.rows_in_play(configuration, dt)
            rows = G, h, None, fewest
            flushed = type(limit).rows_in_play is _SUPPORT_ROWS_IN_PLAY
        else:
            rows = constraint_rows(limit, limit.compute_qp_inequalities(configuration, dt))
            if rows is None:
                return None
            flushed = rows[3] is not None  # (counted by constraint_rows: none negligible)
    except (ValueError, TypeError, IndexError) as exc:  # (an attribute set to what does not fit)
        if isinstance(exc, QpikError):
            raise
        raise LimitDefinitionError(f"{limit_name(limit)}: its rows failed ({exc})") from exc
    if rows is not None:
        G, h = rows[0], rows[1]
        nv = configuration.model.nv
        if not (G.ndim == 2 and G.shape[1] == nv and h.shape == (G.shape[0],)):
            raise LimitDefinitionError(
                f"{limit_name(limit)}: rows G of shape {G.shape} and h of shape {h.shape}; "
                f"G must be (p, {nv}) and h (p,)"
            )
        if (
            G.size
            and not flushed
            and (
                G.dtype != np.float64
                or h.dtype != np.float64
                or not (G.flags.c_contiguous and h.flags.c_contiguous)
                or _limits_engine.row_stats(G, h, NEGLIGIBLE_ROW)[3]
            )
        ):  # (the engine counts them without NumPy's temporaries: 0.3 us, NumPy's 5 us)
            largest = np.abs(G).max(axis=1)
            negligible = (largest <= NEGLIGIBLE_ROW) & (largest > 0.0)
            if negligible.any():  # (a new array: the limit's own stays as it gave it)
                G = G.copy()
                G[negligible] = 0.0
                rows = (G, h, rows[2], None)  # (the fewest nonzero entries: counted again)
    return rows


def _check_limit(limit, model: mujoco.MjModel) -> None:
    """A limit object (it has ``compute_qp_inequalities``) for ``model``
    (:func:`.limit_inputs.check_limit_model`) whose position ranges are not empty; raises
    :class:`qpik.InvalidInput`, :class:`qpik.LimitDefinitionError` or
    :class:`qpik.InfeasibleLimits`."""
    if not hasattr(limit, "compute_qp_inequalities"):
        raise InvalidInput(f"limits must be mink/qpik limits, got {limit!r}")
    check_limit_model(limit, model)
    if isinstance(limit, mink.ConfigurationLimit) and len(limit.indices):
        limit_bounds(limit, _qpos_addresses(limit))
