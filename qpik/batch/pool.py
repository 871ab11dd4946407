r"""Batch inverse kinematics: many independent :func:`qpik.solve` calls, on every core of
this machine (a process pool) or on a Ray cluster.

A batch is a list of target mappings ``{frame: target}`` (world frame, metres; see
:func:`qpik.solve`), solved with the same options. The results do not depend on how the
batch is run:

* target ``i`` is solved with its own seed, :func:`target_seed(seed, i) <target_seed>`,
  derived from the batch seed and the index alone: serial, 2 workers, 64 chunks or a Ray
  cluster give bitwise the same configurations;
* each worker loads the robot once (a name, a path or an ``MjModel``; a
  :class:`qpik.Configuration` sends its model and uses its ``q`` as ``q0``) and then
  solves chunks of consecutive targets;
* on Linux workers are forked: they start in milliseconds with the compiled kernels of
  the parent; a batch whose serial time, estimated from its first solve, is below
  ``pool_threshold`` seconds is solved in-process all the same.

Errors are raised in the calling process with their type: the targets are checked (frames,
shapes, NaN) and the first target is solved in-process (options) before any worker starts;
a target that fails in a worker is solved again here to raise its error.

Layers: :func:`solve_many` (a list in, a list of :class:`qpik.IKResult` out);
:func:`iter_solve` (chunks in, ``(start, results)`` out as they finish, for batches that do
not fit in memory); :func:`solve_file` (a targets file in, a results file written chunk by
chunk and resumed, behind ``qpik batch``). :func:`qpik.reachability` runs on the same
machinery.

Ray comes with the ``cluster`` extra (``pip install 'qpik[cluster]'``, with pyarrow for
Parquet results); the workers of a remote cluster need qpik (and the robot files given by
path) installed on every node.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import math
import os
import sys
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

if TYPE_CHECKING:  # multiprocessing and concurrent.futures load when a pool starts
    import multiprocessing.context
    from concurrent.futures import Future, ProcessPoolExecutor

from ..core import checks
from ..errors import InvalidArgumentType, InvalidInput, InvalidTarget, MissingExtra, QpikError
from ..igm.result import IKResult, Reason
from ..igm.session import IKSession, solve
from ..igm.targets import MAX_TARGET_DISTANCE, FrameKey, RobotLike, TargetLike, parse_target
from ..model.configuration import resolve_robot
from ..model.frames import resolve_frame
from ..model.rotations import ORTHONORMAL_TOLERANCE, nearest_rotation
from ..options import SolveOptions, resolve

_SOLVE = solve  # qpik.solve; tests replace qpik.batch.solve to inject failures

__all__ = [
    "check_chunk_size",
    "check_seed",
    "check_targets",
    "solve_call",
    "BACKENDS",
    "Chunk",
    "WorkerError",
    "check_workers",
    "iter_solve",
    "prepare_robot",
    "progress_bar",
    "ray_init",
    "solve_many",
    "target_seed",
]


class WorkerError(QpikError, RuntimeError):
    """A worker process died, or failed on a target in a way that does not recur here."""


#: Where a batch runs: ``"process"`` (a pool on this machine) or ``"ray"`` (a Ray cluster).
BACKENDS = ("process", "ray")

#: Chunks submitted ahead of the workers, per worker (bounds memory on huge batches).
_AHEAD = 3


def target_seed(seed: int, index: int) -> int:
    """The seed :func:`solve_many` gives target ``index`` of a batch run with ``seed``:
    ``qpik.solve(robot, targets[i], seed=target_seed(seed, i), **options)`` reproduces
    entry ``i`` of the batch. A 64-bit BLAKE2b hash of ``(seed, index)`` only, so it does
    not depend on chunking, workers or backend, and costs a microsecond."""
    digest = hashlib.blake2b(f"qpik-batch:{int(seed)}:{int(index)}".encode(), digest_size=8)
    return int.from_bytes(digest.digest(), "little")


def check_seed(seed: int | None) -> int:
    """The batch's entropy: ``seed`` itself, or fresh entropy for ``None``."""
    if seed is None:
        # numpy types entropy as any SeedSequence's; a fresh one's is an int
        return int(np.random.SeedSequence().entropy)  # type: ignore[arg-type]
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InvalidInput(f"seed must be a non-negative integer or None, got {seed!r}")
    return int(seed)


def check_workers(workers: int | None, backend: str = "process") -> int | None:
    """Validate ``workers`` (``None``: every core, or for Ray every CPU of the cluster)."""
    if backend not in BACKENDS:
        raise InvalidInput(f"unknown backend {backend!r}; expected one of: {', '.join(BACKENDS)}")
    if workers is None:
        return (os.cpu_count() or 1) if backend == "process" else None
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise InvalidInput(f"workers must be a positive integer or None, got {workers!r}")
    return int(workers)


# --- the robot a worker loads -------------------------------------------------------------


def prepare_robot(robot: RobotLike) -> tuple[Any, mujoco.MjModel, np.ndarray | None]:
    """``(spec, model, q0)``: what workers load (a name, an absolute path or an
    ``MjModel``), the model loaded here (:func:`qpik.robots.resolve_robot`), and the start
    configuration a :class:`qpik.Configuration` carries (else ``None``)."""
    model, q0 = resolve_robot(robot)
    spec: Any = model
    if isinstance(robot, (str, os.PathLike)):
        text = os.fspath(robot)
        spec = os.path.abspath(text) if os.path.exists(text) else text
    return spec, model, q0


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


class _StackedTargets(Sequence):
    """Targets ``{key: (positions[i], rotations[i])}`` (or ``{key: positions[i]}``) of one
    frame key, held as stacked float64 arrays: a slice is a view, and a chunk of them
    pickles as two arrays (a worker's transport costs a few microseconds per target).
    The values are those :func:`qpik.igm.targets.parse_target` reads from the originals
    (``float(x)`` of each number), so the solves are bitwise the same."""

    __slots__ = ("key", "positions", "rotations")

    def __init__(self, key: Any, positions: np.ndarray, rotations: np.ndarray | None):
        self.key, self.positions, self.rotations = key, positions, rotations

    def __len__(self) -> int:
        return self.positions.shape[0]

    def __getitem__(self, index):
        if isinstance(index, slice):
            rotations = None if self.rotations is None else self.rotations[index]
            return _StackedTargets(self.key, self.positions[index], rotations)
        if self.rotations is None:
            return {self.key: self.positions[index]}
        return {self.key: (self.positions[index], self.rotations[index])}

    def __reduce__(self) -> tuple:
        positions = np.ascontiguousarray(self.positions)
        rotations = None if self.rotations is None else np.ascontiguousarray(self.rotations)
        return (_StackedTargets, (self.key, positions, rotations))


def _stack_targets(model: mujoco.MjModel, targets_list: Sequence) -> _StackedTargets | None:
    """The batch as :class:`_StackedTargets`, checked at once, when every entry is
    ``{key: (position, rotation)}`` (or ``{key: position}``) with one and the same frame
    key and numbers of the right shapes, all plainly valid (finite, rotations within half
    of :func:`qpik.igm.targets.parse_target`'s tolerance, inside its distance bound); else
    ``None``, and :func:`check_targets` checks them one by one (and names a bad one)."""
    if not targets_list:
        return None
    first = targets_list[0]
    if type(first) is not dict or len(first) != 1:
        return None
    (key,) = first
    with_rotation = type(first[key]) is tuple and len(first[key]) == 2
    positions, rotations = [], []
    try:
        for targets in targets_list:
            if type(targets) is not dict or len(targets) != 1:
                return None
            value = targets[key]
            if with_rotation:
                if type(value) is not tuple or len(value) != 2:
                    return None
                positions.append(value[0])
                rotations.append(value[1])
            else:
                positions.append(value)
        n = len(positions)
        P = np.array(positions, dtype=float)
        R = np.array(rotations, dtype=float) if with_rotation else None
    except (KeyError, TypeError, ValueError):
        return None
    if P.shape != (n, 3) or (R is not None and R.shape != (n, 3, 3)):
        return None
    if not (np.isfinite(P).all() and np.abs(P).max() <= MAX_TARGET_DISTANCE):
        return None
    if R is not None:
        if not np.isfinite(R).all():
            return None
        defect = np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max()
        if not (defect <= 0.5e-6 and (np.linalg.det(R) > 0.5).all()):
            return None
        # each target as parse_target reads it: the nearest rotation (the same function,
        # one matrix at a time, so that the solves are bitwise those of single targets)
        off = np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max(axis=(1, 2))
        for i in np.flatnonzero(off > 0.5 * ORTHONORMAL_TOLERANCE):
            R[i] = nearest_rotation(R[i])
    resolve_frame(model, key, argument="targets_list[0]")  # an unknown frame raises here
    return _StackedTargets(key, P, R)


def solve_call(
    options: SolveOptions | str | None, solve_options: Mapping[str, Any], q0: np.ndarray | None
) -> dict[str, Any]:
    """The keywords every solve of a batch gets: ``q0`` and ``stack`` as given (``q0``
    defaulting to a Configuration's ``q``), and the other options folded into one
    :class:`qpik.SolveOptions`, validated here (a bad option raises in the caller, typed,
    before any worker starts). A batch's ``seed`` is its own argument: target ``i`` gets
    :func:`target_seed(seed, i) <target_seed>`, whatever ``options.seed``."""
    keywords = dict(solve_options)
    call: dict[str, Any] = {k: keywords.pop(k) for k in ("q0", "stack") if k in keywords}
    call["options"] = resolve(options).replace(**keywords)
    if q0 is not None:
        call.setdefault("q0", q0)
    return call


# --- the work of one worker ---------------------------------------------------------------


@dataclass(frozen=True)
class Chunk:
    """Consecutive targets of a batch: ``targets[k]`` is target ``start + k``."""

    start: int
    targets: Sequence[Mapping[FrameKey, TargetLike]]


@dataclass(frozen=True)
class _Failure:
    """A target whose solve raised in a worker (re-raised, typed, in the caller)."""

    index: int
    targets: Mapping
    error: str


#: The options key that carries ``histories`` to the workers (never passed to solve).
_HISTORIES = "_qpik_batch_histories"
#: Per-iteration fields of an IKResult that a batch drops unless ``histories=True``.
_HISTORY_FIELDS = ("residual_history", "error_history", "path")


def _without_histories(result: IKResult) -> IKResult:
    """``result`` (fresh from a solve: changed in place) with its per-iteration
    diagnostics emptied (their defaults): a batch sends about 5x less data back."""
    # a class is hashable; mypy checks type[IKResult] against the instances' __hash__
    for name, factory in _history_defaults(type(result)):  # type: ignore[arg-type]
        setattr(result, name, factory())
    return result


@functools.lru_cache(maxsize=4)
def _history_defaults(cls: type) -> tuple[tuple[str, Any], ...]:
    return tuple(
        (f.name, f.default_factory)
        for f in dataclasses.fields(cls)
        if f.name in _HISTORY_FIELDS and f.default_factory is not dataclasses.MISSING
    )


class _ChunkSolver:
    """One worker's state: the robot, loaded once, and the batch options."""

    def __init__(self, spec: Any, entropy: int, options: Mapping[str, Any]):
        self.model = resolve_robot(spec)[0]
        self.entropy = entropy
        self.options = dict(options)
        self.histories = bool(self.options.pop(_HISTORIES, False))
        # A session reads the model once; it keeps no state between solves, so its
        # results are those of qpik.solve, bitwise.
        self.session = IKSession(self.model)

    def solve(self, index: int, targets: Mapping) -> IKResult:
        seed = target_seed(self.entropy, index)
        if solve is _SOLVE:
            result = self.session.solve(targets, seed=seed, **self.options)
        else:  # qpik.batch.solve replaced (tests)
            result = solve(self.model, targets, seed=seed, **self.options)
        return result if self.histories else _without_histories(result)

    def solve_chunk(self, chunk: Chunk) -> tuple[int, list[IKResult | _Failure]]:
        results: list[IKResult | _Failure] = []
        for offset, targets in enumerate(chunk.targets):
            index = chunk.start + offset
            try:
                results.append(self.solve(index, targets))
            except Exception as exc:  # re-raised with its type by the caller
                results.append(_Failure(index, targets, f"{type(exc).__name__}: {exc}"))
        return chunk.start, results


_WORKER: dict[str, _ChunkSolver] = {}  # per worker process, set by its initializer


def _init_worker(spec: Any, entropy: int, options: Mapping[str, Any]) -> None:
    _die_with_parent()
    _WORKER["solver"] = _ChunkSolver(spec, entropy, options)


def _die_with_parent() -> None:
    """A pool worker must not outlive its parent (killed, say, by SIGKILL or an
    uncaught SIGTERM): on Linux the kernel sends it SIGTERM when the parent dies."""
    import signal

    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # not a handler forked from the parent
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, int(signal.SIGTERM), 0, 0, 0)
    except (OSError, AttributeError):  # no prctl: workers then rely on a clean shutdown
        return
    if os.getppid() == 1:  # the parent died before prctl took effect
        os._exit(1)


@dataclass(frozen=True)
class _PackedChunk:
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


def _pack_chunk(chunk: Chunk) -> Chunk | _PackedChunk:
    """``chunk`` as a :class:`_PackedChunk` when its targets allow, else as it is."""
    targets = chunk.targets
    if isinstance(targets, _StackedTargets):  # already arrays
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
    return _PackedChunk(
        chunk.start, key, np.stack(positions), np.stack(rotations) if with_rotation else None
    )


def _solve_chunk_in_worker(chunk: Chunk | _PackedChunk) -> tuple[int, Any]:
    solver = _WORKER["solver"]
    if isinstance(chunk, _PackedChunk):
        chunk = chunk.unpack()
    start, results = solver.solve_chunk(chunk)
    return start, (results if solver.histories else _pack(results))


#: Reasons by their index in a packed chunk.
_REASON_LIST = tuple(Reason)
_REASON_INDEX = {reason: i for i, reason in enumerate(_REASON_LIST)}


@dataclass(frozen=True)
class _PackedResults:
    """A worker's chunk of results without histories, as a few arrays: several times
    cheaper to pickle and unpickle than the :class:`IKResult` objects (the parent's share
    of a pool's CPU, which competes with the workers). Values travel bitwise (float64)."""

    q: np.ndarray  # (k, nq)
    floats: np.ndarray  # (k, 3): position_error, orientation_error, solve_time
    ints: np.ndarray  # (k, 4): converged, reason index, iterations, restarts_used
    frame_errors: list
    engines: list


def _pack(results: list[IKResult | _Failure]) -> list[IKResult | _Failure] | _PackedResults:
    """``results`` packed (:class:`_PackedResults`) when they are all plain IKResults of one
    shape, else as they are."""
    if not results or any(type(r) is not IKResult for r in results):
        return results
    plain: list[IKResult] = results  # type: ignore[assignment]
    try:
        q = np.stack([r.q for r in plain])
        floats = np.array(
            [(r.position_error, r.orientation_error, r.solve_time) for r in plain], dtype=float
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
    if q.dtype != np.float64 or floats.shape != (len(plain), 3):
        return results
    return _PackedResults(
        q, floats, ints, [r.frame_errors for r in plain], [r.engine for r in plain]
    )


def _unpack(results: Any) -> list[IKResult | _Failure]:
    """The results of a chunk as :func:`_pack` sent them."""
    if not isinstance(results, _PackedResults):
        return results
    reasons = _REASON_LIST
    return [
        IKResult(
            q.copy(),
            bool(converged),
            reasons[reason],
            iterations,
            restarts,
            position_error,
            orientation_error,
            solve_time,
            frame_errors,
            engine=engine,
        )
        for q, (position_error, orientation_error, solve_time), (
            converged,
            reason,
            iterations,
            restarts,
        ), frame_errors, engine in zip(
            results.q,
            results.floats.tolist(),
            results.ints.tolist(),
            results.frame_errors,
            results.engines,
        )
    ]


def _ray_solve_chunk(
    batch: str, spec: Any, entropy: int, options: Mapping[str, Any], chunk: Chunk
) -> tuple[int, list[IKResult | _Failure]]:
    """A Ray task. Ray reuses its worker processes, so a worker loads the robot at its
    first chunk of batch ``batch`` and keeps it for the next ones."""
    if batch not in _WORKER:
        _WORKER.clear()
        _WORKER[batch] = _ChunkSolver(spec, entropy, options)
    return _WORKER[batch].solve_chunk(chunk)


def _mp_context() -> multiprocessing.context.BaseContext:
    """``fork`` on Linux: workers start in milliseconds and inherit the compiled kernels
    and the loaded modules (a fresh interpreter, ``forkserver`` or ``spawn``, takes seconds
    to import qpik). Elsewhere ``spawn``, the platform's default: scripts then need an
    ``if __name__ == "__main__":`` guard."""
    import multiprocessing

    if sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("fork")
    return multiprocessing.get_context("spawn")


def _ray():
    try:
        import ray
    except ImportError as exc:
        raise MissingExtra("solve_many(backend='ray')", "cluster", "ray") from exc
    return ray


def ray_init(address: str | None = None, workers: int | None = None) -> Any:
    """Connect to Ray: the running session if there is one, else ``address`` (``"auto"``,
    ``"ray://host:10001"``, ...), else a local Ray with ``workers`` CPUs. Returns the
    ``ray`` module. A local Ray started here stays up for later batches (``ray.shutdown()``
    stops it)."""
    ray = _ray()
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
        if address in (None, "local"):
            kwargs["num_cpus"] = workers
        else:
            kwargs["address"] = address
        ray.init(**kwargs)
    return ray


# --- running chunks -------------------------------------------------------------------------


def iter_solve(
    robot: RobotLike,
    chunks: Iterable[Chunk],
    *,
    seed: int | None = 0,
    workers: int | None = None,
    backend: str = "process",
    address: str | None = None,
    histories: bool = False,
    options: SolveOptions | str | None = None,
    **solve_options: Any,
) -> Iterator[tuple[int, list[IKResult]]]:
    """Solve chunks of a batch and yield ``(start, results)`` as each chunk finishes (in
    completion order, not index order). ``workers=1`` solves in this process, in order.
    The workers stop when the iterator is exhausted or closed. Chunks are read lazily, a
    few per worker ahead, so ``chunks`` may be a generator over a huge batch. The targets
    are not checked here (see :func:`solve_many`, also for ``histories``)."""
    entropy = check_seed(seed)
    workers = check_workers(workers, backend)
    spec, model, q0 = prepare_robot(robot)
    call = solve_call(options, solve_options, q0)
    call[_HISTORIES] = histories
    yield from iter_prepared(spec, model, chunks, entropy, workers, backend, address, call)


def iter_prepared(
    spec: Any,
    model: mujoco.MjModel,
    chunks: Iterable[Chunk],
    entropy: int,
    workers: int | None,
    backend: str,
    address: str | None,
    options: dict[str, Any],
) -> Iterator[tuple[int, list[IKResult]]]:
    """:func:`iter_solve` once its arguments are checked and the robot loaded."""
    if backend == "ray":
        yield from _iter_ray(spec, chunks, entropy, workers, address, options)
        return
    if address is not None:
        raise InvalidInput("address is a Ray address: pass backend='ray' with it")
    if workers == 1:
        local = _ChunkSolver(model, entropy, options)
        for chunk in chunks:
            yield _raise_failures(local, local.solve_chunk(chunk))
        return
    yield from _iter_pool(spec, model, chunks, entropy, workers, options)


def _iter_pool(
    spec: Any,
    model: mujoco.MjModel,
    chunks: Iterable[Chunk],
    entropy: int,
    workers: int | None,
    options: dict[str, Any],
) -> Iterator[tuple[int, list[IKResult]]]:
    """Chunks solved by a process pool, a few per worker submitted ahead."""
    local = _ChunkSolver(model, entropy, options)
    context = _mp_context()
    forked = context.get_start_method() == "fork"
    from concurrent.futures import FIRST_COMPLETED, wait

    pool_class, broken = _pool_classes()
    executor = pool_class(
        max_workers=workers,
        mp_context=context,
        initializer=_init_worker,
        # A forked worker has the model already (no file to read again).
        initargs=(model if forked else spec, entropy, options),
    )
    try:
        pending: set[Future] = set()
        source = iter(chunks)
        while True:
            _submit_ahead(source, pending, _AHEAD * (workers or 1), executor)
            if not pending:
                return
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            try:
                items = sorted((future.result() for future in done), key=lambda item: item[0])
                items = [(start, _unpack(results)) for start, results in items]
            except broken as exc:
                raise WorkerError(
                    "a worker process died (out of memory, killed, or a script that starts "
                    "workers without an `if __name__ == '__main__':` guard)"
                ) from exc
            for item in items:
                yield _raise_failures(local, item)
    finally:
        executor.shutdown(wait=True, cancel_futures=True)


def _submit_ahead(
    source: Iterator[Chunk], pending: set[Future], ahead: int, executor: ProcessPoolExecutor
) -> None:
    """Submit chunks from ``source`` until ``ahead`` are pending (or none remain)."""
    while len(pending) < ahead:
        chunk = next(source, None)
        if chunk is None:
            return
        pending.add(executor.submit(_solve_chunk_in_worker, _pack_chunk(chunk)))


def _iter_ray(spec, chunks, entropy, workers, address, options):
    ray = ray_init(address, workers)
    remote = ray.remote(num_cpus=1)(_ray_solve_chunk)
    local = _ChunkSolver(spec, entropy, options)
    spec_ref = ray.put(spec) if not isinstance(spec, str) else spec
    options_ref = ray.put(options)
    batch = f"ray-batch-{options_ref.hex()}"  # one per call: workers reload per batch
    capacity = workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
    pending: list = []
    source = iter(chunks)
    exhausted = False
    try:
        while True:
            while not exhausted and len(pending) < _AHEAD * capacity:
                chunk = next(source, None)
                if chunk is None:
                    exhausted = True
                else:
                    pending.append(remote.remote(batch, spec_ref, entropy, options_ref, chunk))
            if not pending:
                return
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                yield _raise_failures(local, ray.get(ref))
    finally:
        for ref in pending:
            ray.cancel(ref)


def _raise_failures(local: _ChunkSolver, item) -> tuple[int, list[IKResult]]:
    """Re-solve in this process a target that failed in a worker, so that its error is
    raised here with its type."""
    start, results = item
    for result in results:
        if isinstance(result, _Failure):
            local.solve(result.index, result.targets)
            raise WorkerError(f"target {result.index} failed in a worker: {result.error}")
    return start, results


def solve_many(
    robot: RobotLike,
    targets_list: Sequence[Mapping[FrameKey, TargetLike]],
    *,
    seed: int | None = 0,
    workers: int | None = None,
    backend: str = "process",
    address: str | None = None,
    progress: bool = True,
    chunk_size: int | None = None,
    pool_threshold: float = 1.0,
    histories: bool = False,
    options: SolveOptions | str | None = None,
    **solve_options: Any,
) -> list[IKResult]:
    """Solve a batch of IK problems (one ``{frame: target}`` mapping each, world frame,
    metres) with the same :func:`qpik.solve` options, on every core by default.

    Args:
        robot: a name, a path, an ``MjModel`` or a :class:`qpik.Configuration` (its ``q``
            is the start ``q0`` of every solve unless ``q0`` is passed).
        targets_list: the problems; entry ``i`` of the result solves ``targets_list[i]``.
        seed: batch seed; target ``i`` is solved with :func:`target_seed(seed, i)
            <target_seed>`, so the results are bitwise the same whatever ``workers``,
            ``chunk_size`` or ``backend`` (``None``: fresh entropy).
        workers: processes (``None``: ``os.cpu_count()``; for Ray, every CPU of the
            cluster); ``1`` solves in this process.
        backend: ``"process"`` (a process pool on this machine) or ``"ray"`` (needs
            ``pip install 'qpik[cluster]'``).
        address: Ray address of an existing cluster (``"auto"``, ``"ray://host:10001"``);
            ``None`` joins the running Ray session or starts a local one.
        progress: a progress bar with rate and ETA on stderr (tqdm), shown on runs longer
            than 2 s.
        chunk_size: targets per task (default: about four chunks per worker, at most 64).
        pool_threshold: [s] a batch whose serial time, estimated from its first solve,
            is below this is solved in this process (no workers start).
        histories: keep each result's per-iteration ``residual_history``,
            ``error_history`` and ``path``; by default they are left empty (a batch then
            moves about 5x less data between processes).
        options: the :class:`qpik.SolveOptions` (or a preset name) of every solve;
            ``options.seed`` is not used (see ``seed``).
        **solve_options: :func:`qpik.solve`'s keywords (``q0``, ``stack``, and options
            overriding ``options``), passed to every solve.
    """
    if isinstance(targets_list, (str, bytes, Mapping)) or not isinstance(targets_list, Iterable):
        raise InvalidArgumentType(
            "targets_list", "a list of targets mappings", checks.type_name(targets_list)
        )
    targets_list = list(targets_list)
    entropy = check_seed(seed)
    workers = check_workers(workers, backend)
    check_chunk_size(chunk_size, optional=True)
    spec, model, q0 = prepare_robot(robot)
    stacked = _stack_targets(model, targets_list)
    if stacked is None:
        check_targets(model, targets_list)
    source: Sequence[Mapping[FrameKey, TargetLike]] = targets_list if stacked is None else stacked
    call = solve_call(options, solve_options, q0)
    call[_HISTORIES] = histories
    results: list[IKResult] = []
    for _start, chunk_results in stream_chunks(
        spec,
        model,
        len(targets_list),
        lambda start, stop: source[start:stop],
        entropy=entropy,
        workers=workers,
        backend=backend,
        address=address,
        progress=progress,
        chunk_size=chunk_size,
        pool_threshold=pool_threshold,
        options=call,
        ordered=True,
    ):
        results.extend(chunk_results)
    return results


def check_chunk_size(chunk_size: int | None, optional: bool = False) -> None:
    """:class:`qpik.InvalidInput` unless ``chunk_size`` is an int >= 1 (or ``None`` when
    ``optional``)."""
    if chunk_size is None and optional:
        return
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1:
        raise InvalidInput(f"chunk_size must be a positive integer, got {chunk_size!r}")


def stream_chunks(
    spec: Any,
    model: mujoco.MjModel,
    n: int,
    targets_at: Callable[[int, int], Sequence[Mapping]],
    *,
    entropy: int,
    workers: int | None,
    backend: str,
    address: str | None,
    progress: bool,
    chunk_size: int | None,
    pool_threshold: float,
    options: dict[str, Any],
    ordered: bool = False,
) -> Iterator[tuple[int, list[IKResult]]]:
    """Solve targets ``0..n-1`` (``targets_at(start, stop)`` builds a slice on demand) and
    yield ``(start, results)`` per chunk, in index order if ``ordered``.

    Target 0 is solved first, in this process: bad options raise here, typed, and its time
    tells whether starting workers is worth it (see ``pool_threshold``)."""
    if n == 0:
        return
    bar = progress_bar(n, progress)
    try:
        start_time = time.perf_counter()
        first = _ChunkSolver(model, entropy, options).solve(0, targets_at(0, 1)[0])
        estimate = (time.perf_counter() - start_time) * (n - 1)
        bar.update(1)
        yield 0, [first]
        serial = backend == "process" and (workers == 1 or estimate < pool_threshold)
        workers = 1 if serial else workers
        capacity = workers or os.cpu_count() or 1
        size = chunk_size or max(1, min(64, math.ceil((n - 1) / (4 * capacity))))
        chunks = (Chunk(s, targets_at(s, min(s + size, n))) for s in range(1, n, size))
        solved = iter_prepared(spec, model, chunks, entropy, workers, backend, address, options)
        counted = _counted(solved, bar)
        yield from (_in_order(counted, 1) if ordered else counted)
    finally:
        bar.close()


def _counted(
    items: Iterable[tuple[int, list[IKResult]]], bar: Any
) -> Iterator[tuple[int, list[IKResult]]]:
    """``items``, each counted on the progress bar as it passes."""
    for start, results in items:
        bar.update(len(results))
        yield start, results


def _in_order(
    items: Iterable[tuple[int, list[IKResult]]], following: int
) -> Iterator[tuple[int, list[IKResult]]]:
    """Chunks ``(start, results)`` arriving in any order, yielded in index order from
    ``following`` (each held until those before it have arrived)."""
    waiting: dict[int, list[IKResult]] = {}
    for start, results in items:
        waiting[start] = results
        while following in waiting:
            ready = waiting.pop(following)
            yield following, ready
            following += len(ready)


def progress_bar(total: int, enabled: bool = True, initial: int = 0, desc: str = "IK") -> Any:
    """A tqdm bar (rate, ETA) on stderr, shown once a run has lasted 2 s. It starts no
    monitor thread, so that worker processes can still be forked safely."""
    from tqdm.auto import tqdm

    class _Bar(tqdm):
        monitor_interval = 0

    return _Bar(
        total=total,
        initial=initial,
        unit="IK",
        desc=desc,
        disable=not enabled,
        delay=2.0,
        smoothing=0.1,
        dynamic_ncols=True,
    )


#: Names of concurrent.futures.process, loaded with multiprocessing when a pool starts.
_POOL_NAMES = ("ProcessPoolExecutor", "BrokenProcessPool")


def _pool_classes() -> tuple[type[ProcessPoolExecutor], type[Exception]]:
    """``(ProcessPoolExecutor, BrokenProcessPool)``, as this module's globals (where
    tests replace the executor), imported on first use."""
    names = globals()
    if any(name not in names for name in _POOL_NAMES):
        from concurrent.futures import process

        for name in _POOL_NAMES:
            names.setdefault(name, getattr(process, name))
    return names["ProcessPoolExecutor"], names["BrokenProcessPool"]


def __getattr__(name: str) -> Any:
    """The pool's classes, :data:`_POOL_NAMES`, load on first use."""
    if name.startswith("__"):  # the import system's probes (__path__, ...): not a reason
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    if name in _POOL_NAMES:
        return _pool_classes()[_POOL_NAMES.index(name)]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
