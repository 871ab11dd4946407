"""What travels between a batch's caller and its workers: :class:`Chunk` (consecutive
targets), the same targets as stacked arrays (:class:`StackedTargets` for a whole batch,
:class:`PackedChunk` for one chunk), a chunk's results as a few arrays
(:class:`PackedResults`) and a target that failed (:class:`Failure`). Packed values travel
bitwise, and several times cheaper to pickle than the mappings and result objects; anything
that does not pack goes as it is.
"""

from __future__ import annotations

import dataclasses
import functools
import gc
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from ..core.checks import float_array
from ..errors import InvalidTarget
from ..igm.result import IKResult, Reason
from ..igm.targets import MAX_TARGET_DISTANCE, FrameKey, TargetLike, parse_target
from ..model.frames import resolve_frame
from ..model.rotations import ORTHONORMAL_TOLERANCE, nearest_rotation

__all__ = [
    "HISTORY_FIELDS",
    "Chunk",
    "Failure",
    "PackedChunk",
    "PackedResults",
    "StackedTargets",
    "check_targets",
    "pack_chunk",
    "pack_results",
    "stack_targets",
    "unpack_results",
    "without_histories",
]


@dataclass(frozen=True)
class Chunk:
    """Consecutive targets of a batch: ``targets[k]`` is target ``start + k``."""

    start: int
    targets: Sequence[Mapping[FrameKey, TargetLike]]


@dataclass(frozen=True)
class Failure:
    """A target whose solve raised in a worker (re-raised, typed, in the caller)."""

    index: int
    targets: Mapping
    error: str


def check_targets(model: mujoco.MjModel, targets_list: Sequence, offset: int = 0) -> None:
    """Typed errors, naming the index, for malformed targets or unknown frames."""
    known: set = set()
    for index, targets in enumerate(targets_list, start=offset):
        if not isinstance(targets, Mapping) or not targets:
            raise InvalidTarget(
                f"targets_list[{index}] must be a non-empty mapping {{frame: target}}, "
                f"got {type(targets).__name__}"
            )
        for key, value in targets.items():
            if key not in known:
                resolve_frame(model, key, argument=f"targets_list[{index}]")
                known.add(key)
            try:
                parse_target(value)
            except InvalidTarget as exc:
                raise InvalidTarget(f"targets_list[{index}][{key!r}]: {exc}") from None


class StackedTargets(Sequence):
    """Targets ``{key: (positions[i], rotations[i])}`` (or ``{key: positions[i]}``) of one
    frame key, held as stacked float64 arrays: a slice is a view, and a chunk of them
    pickles as two arrays. ``posed`` (bool (n,), or ``None``: every entry has a rotation
    when ``rotations`` is given) marks the entries with a rotation in a batch that mixes
    pose and position targets (the others' rows of ``rotations`` are unused). The values are
    those :func:`qpik.igm.targets.parse_target` reads from the originals (``float(x)`` of each
    number), so the solves are bitwise the same."""

    __slots__ = ("key", "posed", "positions", "rotations")

    def __init__(
        self,
        key: Any,
        positions: np.ndarray,
        rotations: np.ndarray | None,
        posed: np.ndarray | None = None,
    ):
        self.key, self.positions, self.rotations, self.posed = key, positions, rotations, posed

    def __len__(self) -> int:
        return self.positions.shape[0]

    def __getitem__(self, index):
        if isinstance(index, slice):
            rotations = None if self.rotations is None else self.rotations[index]
            posed = None if self.posed is None else self.posed[index]
            return StackedTargets(self.key, self.positions[index], rotations, posed)
        if self.rotations is None or (self.posed is not None and not self.posed[index]):
            return {self.key: self.positions[index]}
        return {self.key: (self.positions[index], self.rotations[index])}

    def __reduce__(self) -> tuple:
        positions = np.ascontiguousarray(self.positions)
        rotations = None if self.rotations is None else np.ascontiguousarray(self.rotations)
        posed = None if self.posed is None else np.ascontiguousarray(self.posed)
        return (StackedTargets, (self.key, positions, rotations, posed))


def stack_targets(model: mujoco.MjModel, targets_list: Sequence) -> StackedTargets | None:
    """The batch as :class:`StackedTargets`, checked at once, when every entry is
    ``{key: (position, rotation)}`` or ``{key: position}`` (the two forms may mix) with one
    and the same frame key and numbers of the right shapes, all plainly valid (finite,
    rotations within half of :func:`qpik.igm.targets.parse_target`'s tolerance, inside its
    distance bound); else ``None``, and :func:`check_targets` checks them one by one (and
    names a bad one)."""
    arrays = _stacked_arrays(targets_list)
    if arrays is None:
        return None
    key, P, R, posed = arrays
    if not (np.isfinite(P).all() and np.abs(P).max() <= MAX_TARGET_DISTANCE):
        return None
    if R is not None and not _plain_rotations(R):
        return None
    resolve_frame(model, key, argument="targets_list[0]")  # an unknown frame raises here
    return StackedTargets(key, P, R, posed)


def _stacked_arrays(
    targets_list: Sequence,
) -> tuple[Any, np.ndarray, np.ndarray | None, np.ndarray | None] | None:
    """``(key, positions (n, 3), rotations (n, 3, 3) or None, posed (n,) or None)`` when
    every entry of ``targets_list`` is ``{key: (position, rotation)}`` or ``{key:
    position}`` for one key, with values of those shapes (``posed``: which entries have a
    rotation, when they mix; the others' rotations are the identity, unused); else
    ``None``."""
    if not targets_list:
        return None
    first = targets_list[0]
    if type(first) is not dict or len(first) != 1:
        return None
    (key,) = first
    try:
        values = [_only_value(targets, key) for targets in targets_list]
        flags = [type(value) is tuple and len(value) == 2 for value in values]
        n = len(values)
        if all(flags):
            P = _real_stack([value[0] for value in values])
            R = _real_stack([value[1] for value in values])
            posed = None
        elif not any(flags):
            P, R, posed = _real_stack(values), None, None
        else:
            eye = np.eye(3)
            P = _real_stack([v[0] if f else v for v, f in zip(values, flags)])
            R = _real_stack([v[1] if f else eye for v, f in zip(values, flags)])
            posed = np.array(flags)
    except (KeyError, TypeError, ValueError):
        return None
    if P.shape != (n, 3) or (R is not None and R.shape != (n, 3, 3)):
        return None
    return key, P, R, posed


def _real_stack(values: list) -> np.ndarray:
    """``values`` stacked as a float64 array when they hold real numbers only (ints or
    floats, :func:`qpik.core.checks.float_array`); complex numbers, strings or booleans
    raise ``TypeError``: the batch is then checked target by target,
    and :func:`qpik.igm.targets.parse_target` names the bad one."""
    return float_array(np.array(values), booleans=False)  # (TypeError where they are not)


def _only_value(targets: Any, key: Any) -> Any:
    """The value of ``key`` in ``targets``, a dict of that one key (else ``KeyError``)."""
    if type(targets) is not dict or len(targets) != 1:
        raise KeyError(key)
    return targets[key]


def _plain_rotations(R: np.ndarray) -> bool:
    """Whether the rotations ``R`` (n, 3, 3) are finite and within half of
    :func:`qpik.igm.targets.parse_target`'s tolerance; those off by more than
    :data:`ORTHONORMAL_TOLERANCE` / 2 are replaced, in place, by the nearest rotation (the
    same function as for one target, one matrix at a time, so that the solves are bitwise
    those of single targets)."""
    if not np.isfinite(R).all():
        return False
    off = np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max(axis=(1, 2))
    if not (off.max() <= 0.5e-6 and (np.linalg.det(R) > 0.5).all()):
        return False
    for i in np.flatnonzero(off > 0.5 * ORTHONORMAL_TOLERANCE):
        R[i] = nearest_rotation(R[i])
    return True


#: Per-iteration fields of an IKResult that a batch drops unless ``histories=True``.
HISTORY_FIELDS = ("residual_history", "error_history", "path")


def without_histories(result: IKResult) -> IKResult:
    """``result`` (fresh from a solve: changed in place) with its per-iteration
    diagnostics emptied (their defaults): a batch then sends
    several times less data back."""
    # a class is hashable; mypy checks type[IKResult] against the instances' __hash__
    for name, factory in _history_defaults(type(result)):  # type: ignore[arg-type]
        setattr(result, name, factory())
    return result


@functools.lru_cache(maxsize=4)
def _history_defaults(cls: type) -> tuple[tuple[str, Any], ...]:
    return tuple(
        (f.name, f.default_factory)
        for f in dataclasses.fields(cls)
        if f.name in HISTORY_FIELDS and f.default_factory is not dataclasses.MISSING
    )


@dataclass(frozen=True)
class PackedChunk:
    """A chunk whose targets are all ``{key: (position (3,), rotation (3, 3))}`` (float64
    arrays) or ``{key: position (3,)}`` for one frame key: sent as stacked arrays, several
    times cheaper to pickle than the mappings (the values travel bitwise)."""

    start: int
    key: Any
    positions: np.ndarray  # (k, 3)
    rotations: np.ndarray | None  # (k, 3, 3), or None for position targets

    def unpack(self) -> Chunk:
        key = self.key
        if self.rotations is None:
            return Chunk(self.start, [{key: p} for p in self.positions])
        return Chunk(self.start, [{key: (p, r)} for p, r in zip(self.positions, self.rotations)])


def _is_vector(value: Any, shape: tuple[int, ...]) -> bool:
    return type(value) is np.ndarray and value.dtype == np.float64 and value.shape == shape


def pack_chunk(chunk: Chunk) -> Chunk | PackedChunk:
    """``chunk`` as a :class:`PackedChunk` when its targets allow, else as it is."""
    targets = chunk.targets
    if isinstance(targets, StackedTargets):  # already arrays
        return chunk
    if not targets or type(targets[0]) is not dict or len(targets[0]) != 1:
        return chunk
    (key,) = targets[0]
    positions, rotations = [], []
    with_rotation = type(targets[0][key]) is tuple
    for mapping in targets:
        if type(mapping) is not dict or len(mapping) != 1 or key not in mapping:
            return chunk
        value = mapping[key]
        if with_rotation:
            if not (
                type(value) is tuple
                and len(value) == 2
                and _is_vector(value[0], (3,))
                and _is_vector(value[1], (3, 3))
            ):
                return chunk
            positions.append(value[0])
            rotations.append(value[1])
        elif _is_vector(value, (3,)):
            positions.append(value)
        else:
            return chunk
    return PackedChunk(
        chunk.start, key, np.stack(positions), np.stack(rotations) if with_rotation else None
    )


#: The path of an unpacked result (empty, as without_histories leaves it), shared: read-only.
_NO_PATH = np.zeros((0, 0))
_NO_PATH.flags.writeable = False
#: Reasons by their index in a packed chunk.
_REASON_LIST = tuple(Reason)
_REASON_INDEX = {reason: i for i, reason in enumerate(_REASON_LIST)}


@dataclass(frozen=True)
class PackedResults:
    """A worker's chunk of results without histories, as a few arrays: several times
    cheaper to pickle and unpickle than the :class:`IKResult` objects (the parent's share
    of a pool's CPU, which competes with the workers). Values travel bitwise (float64), and
    every field a result without histories has travels (a pooled result equals a serial
    one)."""

    q: np.ndarray  # (k, nq)
    #: (k, 5): position_error, orientation_error, solve_time, coupling_error,
    #: constraint_error
    floats: np.ndarray
    ints: np.ndarray  # (k, 4): converged, reason index, iterations, restarts_used
    frame_errors: list
    engines: list
    levels_met: list


def pack_results(results: list[IKResult | Failure]) -> list[IKResult | Failure] | PackedResults:
    """``results`` packed (:class:`PackedResults`) when they are all plain IKResults of one
    shape, else as they are."""
    if not results or any(type(r) is not IKResult for r in results):
        return results
    plain: list[IKResult] = results  # type: ignore[assignment]
    try:
        q = np.stack([r.q for r in plain])
        floats = np.array(
            [
                (
                    r.position_error,
                    r.orientation_error,
                    r.solve_time,
                    r.coupling_error,
                    r.constraint_error,
                )
                for r in plain
            ],
            dtype=float,
        )
        ints = np.array(
            [
                (bool(r.converged), _REASON_INDEX[r.reason], r.iterations, r.restarts_used)
                for r in plain
            ],
            dtype=np.int64,
        )
    except (ValueError, TypeError, KeyError):  # ragged q, odd values: sent as they are
        return results
    if q.dtype != np.float64 or floats.shape != (len(plain), 5):
        return results
    return PackedResults(
        q,
        floats,
        ints,
        [r.frame_errors for r in plain],
        [r.engine for r in plain],
        [r.levels_met for r in plain],
    )


def unpack_results(results: Any) -> list[IKResult | Failure]:
    """The results of a chunk as :func:`pack_results` sent them."""
    if not isinstance(results, PackedResults):
        return results
    # The objects built here hold no reference cycles: the garbage collector's passes,
    # which these allocations would trigger, would find nothing (and took half the time).
    collecting = gc.isenabled()
    gc.disable()
    try:
        return _unpacked(results)
    finally:
        if collecting:
            gc.enable()


def _unpacked(results: PackedResults) -> list[IKResult | Failure]:
    reasons = _REASON_LIST
    return [
        IKResult(
            q.copy(),  # its own array, as a serial result's
            bool(converged),
            reasons[reason],
            iterations,
            restarts,
            position_error,
            orientation_error,
            solve_time,
            frame_errors,
            [],
            [],
            _NO_PATH,  # the histories' defaults (HISTORY_FIELDS)
            engine,
            levels_met,
            coupling_error,
            constraint_error,
        )
        for q, (position_error, orientation_error, solve_time, coupling_error, constraint_error), (
            converged,
            reason,
            iterations,
            restarts,
        ), frame_errors, engine, levels_met in zip(
            results.q,
            results.floats.tolist(),
            results.ints.tolist(),
            results.frame_errors,
            results.engines,
            results.levels_met,
        )
    ]
