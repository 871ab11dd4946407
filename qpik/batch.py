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
import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from .configuration import Configuration, FrameType, frame_names
from .converge import (
    FrameKey,
    IKResult,
    IKSession,
    RobotLike,
    TargetLike,
    parse_target,
    solve,
)
from .errors import InvalidInput, InvalidTarget, MissingExtra, QpikError, UnknownFrame
from .robots import load_robot

_SOLVE = solve  # qpik.solve; tests replace qpik.batch.solve to inject failures

__all__ = [
    "BACKENDS",
    "RESULT_FIELDS",
    "BatchRun",
    "Chunk",
    "TargetArrays",
    "WorkerError",
    "check_workers",
    "iter_solve",
    "load_targets",
    "prepare_robot",
    "progress_bar",
    "ray_init",
    "rotations_from_quaternions",
    "solve_file",
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


def _check_seed(seed: int | None) -> int:
    """The batch's entropy: ``seed`` itself, or fresh entropy for ``None``."""
    if seed is None:
        return int(np.random.SeedSequence().entropy)
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
    ``MjModel``), the model loaded here, and the start configuration a
    :class:`qpik.Configuration` carries (else ``None``)."""
    if isinstance(robot, Configuration):
        return robot.model, robot.model, robot.q
    if isinstance(robot, mujoco.MjModel):
        return robot, robot, None
    if isinstance(robot, (str, os.PathLike)):
        text = os.fspath(robot)
        spec = os.path.abspath(text) if os.path.exists(text) else text
        return spec, load_robot(spec), None
    raise InvalidInput(
        f"robot must be a name, a path, an MjModel or a Configuration, got {type(robot).__name__}"
    )


_OBJ = {
    FrameType.SITE: mujoco.mjtObj.mjOBJ_SITE,
    FrameType.BODY: mujoco.mjtObj.mjOBJ_BODY,
    FrameType.GEOM: mujoco.mjtObj.mjOBJ_GEOM,
}


def _check_targets(model: mujoco.MjModel, targets_list: Sequence, offset: int = 0) -> None:
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
                _check_frame(model, key)
                known.add(key)
            try:
                parse_target(value)
            except InvalidTarget as exc:
                raise InvalidTarget(f"targets_list[{index}][{key!r}]: {exc}") from None


def _check_frame(model: mujoco.MjModel, key) -> None:
    if isinstance(key, tuple) and len(key) == 2:
        name, kind = key[0], FrameType.parse(key[1])
        if mujoco.mj_name2id(model, _OBJ[kind], name) < 0:
            raise UnknownFrame(name, kind.value, frame_names(model, kind))
        return
    if not isinstance(key, str):
        raise InvalidTarget(f"a frame is a name or (name, frame_type), got {key!r}")
    if all(mujoco.mj_name2id(model, obj, key) < 0 for obj in _OBJ.values()):
        raise UnknownFrame(
            key, "site or body", frame_names(model, "site") + frame_names(model, "body")
        )


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
    for name, factory in _history_defaults(type(result)):
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
        self.model = load_robot(spec)
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


def _solve_chunk_in_worker(chunk: Chunk) -> tuple[int, list[IKResult | _Failure]]:
    return _WORKER["solver"].solve_chunk(chunk)


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
    **solve_options: Any,
) -> Iterator[tuple[int, list[IKResult]]]:
    """Solve chunks of a batch and yield ``(start, results)`` as each chunk finishes (in
    completion order, not index order). ``workers=1`` solves in this process, in order.
    The workers stop when the iterator is exhausted or closed. Chunks are read lazily, a
    few per worker ahead, so ``chunks`` may be a generator over a huge batch. The targets
    are not checked here (see :func:`solve_many`, also for ``histories``)."""
    entropy = _check_seed(seed)
    workers = check_workers(workers, backend)
    spec, model, q0 = prepare_robot(robot)
    options = dict(solve_options)
    if q0 is not None:
        options.setdefault("q0", q0)
    options[_HISTORIES] = histories
    yield from _iter_prepared(spec, model, chunks, entropy, workers, backend, address, options)


def _iter_prepared(
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
    local = _ChunkSolver(model, entropy, options)
    executor = ProcessPoolExecutor(
        max_workers=workers,
        mp_context=_mp_context(),
        initializer=_init_worker,
        initargs=(spec, entropy, options),
    )
    try:
        pending: set[Future] = set()
        source = iter(chunks)
        exhausted = False
        while True:
            while not exhausted and len(pending) < _AHEAD * workers:
                chunk = next(source, None)
                if chunk is None:
                    exhausted = True
                else:
                    pending.add(executor.submit(_solve_chunk_in_worker, chunk))
            if not pending:
                return
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            try:
                items = sorted((future.result() for future in done), key=lambda item: item[0])
            except BrokenProcessPool as exc:
                raise WorkerError(
                    "a worker process died (out of memory, killed, or a script that starts "
                    "workers without an `if __name__ == '__main__':` guard)"
                ) from exc
            for item in items:
                yield _raise_failures(local, item)
    finally:
        executor.shutdown(wait=True, cancel_futures=True)


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
        **solve_options: passed to every :func:`qpik.solve` call.
    """
    targets_list = list(targets_list)
    entropy = _check_seed(seed)
    workers = check_workers(workers, backend)
    _check_chunk_size(chunk_size, optional=True)
    spec, model, q0 = prepare_robot(robot)
    _check_targets(model, targets_list)
    options = dict(solve_options)
    if q0 is not None:
        options.setdefault("q0", q0)
    options[_HISTORIES] = histories
    results: list[IKResult] = []
    for _start, chunk_results in _stream(
        spec,
        model,
        len(targets_list),
        lambda start, stop: targets_list[start:stop],
        entropy=entropy,
        workers=workers,
        backend=backend,
        address=address,
        progress=progress,
        chunk_size=chunk_size,
        pool_threshold=pool_threshold,
        options=options,
        ordered=True,
    ):
        results.extend(chunk_results)
    return results


def _check_chunk_size(chunk_size: int | None, optional: bool = False) -> None:
    if chunk_size is None and optional:
        return
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1:
        raise InvalidInput(f"chunk_size must be a positive integer, got {chunk_size!r}")


def _stream(
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
        waiting: dict[int, list[IKResult]] = {}
        following = 1
        for start, results in _iter_prepared(
            spec, model, chunks, entropy, workers, backend, address, options
        ):
            bar.update(len(results))
            if not ordered:
                yield start, results
                continue
            waiting[start] = results
            while following in waiting:
                ready = waiting.pop(following)
                yield following, ready
                following += len(ready)
    finally:
        bar.close()


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


# --- batches on disk: qpik batch ------------------------------------------------------------

#: The per-target fields of a results file, with their dtypes.
RESULT_FIELDS = {
    "converged": bool,
    "reason": "U16",
    "position_error": float,
    "orientation_error": float,
    "iterations": np.int64,
    "restarts_used": np.int64,
    "time": float,
}


@dataclass(frozen=True)
class TargetArrays:
    """Targets of one frame, as arrays: positions ``(N, 3)`` [m] and optionally rotation
    matrices ``(N, 3, 3)``, both in the world frame."""

    positions: np.ndarray
    rotations: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.positions)

    def chunk(self, frame: FrameKey, start: int, stop: int) -> Chunk:
        """Targets ``start:stop`` as ``{frame: target}`` mappings."""
        if self.rotations is None:
            targets = [{frame: p} for p in self.positions[start:stop]]
        else:
            targets = [
                {frame: (p, r)}
                for p, r in zip(self.positions[start:stop], self.rotations[start:stop])
            ]
        return Chunk(start, targets)

    def fingerprint(self) -> str:
        """A hash of the targets (resuming checks that they did not change)."""
        import hashlib

        digest = hashlib.sha256(np.ascontiguousarray(self.positions, dtype=float).tobytes())
        if self.rotations is not None:
            digest.update(np.ascontiguousarray(self.rotations, dtype=float).tobytes())
        return digest.hexdigest()[:16]


def rotations_from_quaternions(quaternions: np.ndarray, source: str = "quaternions") -> np.ndarray:
    """Rotation matrices ``(N, 3, 3)`` from unit quaternions ``(N, 4)`` in MuJoCo's
    order ``w x y z``. A quaternion whose norm is not 1 within 1e-3 raises (it is most
    likely in another order or not a rotation); within that, it is normalised."""
    from scipy.spatial.transform import Rotation

    quaternions = np.asarray(quaternions, dtype=float)
    if quaternions.ndim != 2 or quaternions.shape[1] != 4:
        raise InvalidInput(f"{source}: expected shape (N, 4) (w x y z), got {quaternions.shape}")
    norms = np.linalg.norm(quaternions, axis=1)
    bad = np.flatnonzero(~np.isfinite(norms) | (np.abs(norms - 1.0) > 1e-3))
    if bad.size:
        raise InvalidInput(
            f"{source}[{bad[0]}] = {quaternions[bad[0]]} is not a unit quaternion (w x y z); "
            f"{bad.size} row(s) are not"
        )
    return Rotation.from_quat(quaternions / norms[:, None], scalar_first=True).as_matrix()


def load_targets(path: str | os.PathLike) -> TargetArrays:
    """Read a targets file: an ``.npz`` with ``positions`` ``(N, 3)`` [m] and optionally
    ``quaternions`` ``(N, 4)`` (``w x y z``), or a ``.csv`` with columns ``x, y, z`` and
    optionally ``qw, qx, qy, qz`` (a header line naming them, or 3 or 7 unnamed columns).
    World frame. Malformed files raise :class:`qpik.ProblemFileError` naming the field."""
    from .errors import ProblemFileError

    path = os.fspath(path)
    if not os.path.isfile(path):
        raise ProblemFileError(path, "TARGETS", "no such file")
    quaternions = None
    if path.lower().endswith(".csv"):
        positions, quaternions = _read_csv(path)
    else:
        try:
            with np.load(path, allow_pickle=False) as data:
                if "positions" not in data:
                    raise ProblemFileError(
                        path, "positions", f"an (N, 3) array [m]; the file has {sorted(data)}"
                    )
                positions = np.asarray(data["positions"], dtype=float)
                if "quaternions" in data:
                    quaternions = np.asarray(data["quaternions"], dtype=float)
        except ProblemFileError:
            raise
        except Exception as exc:  # not a zip, pickled objects, ...
            raise ProblemFileError(path, "TARGETS", f"an .npz or .csv file ({exc})") from None
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise ProblemFileError(path, "positions", f"shape (N, 3) [m], got {positions.shape}")
    bad = np.flatnonzero(~np.isfinite(positions).all(axis=1))
    if bad.size:
        raise ProblemFileError(path, "positions", f"finite values; row {bad[0]} is not")
    rotations = None
    if quaternions is not None:
        if quaternions.shape != (len(positions), 4):
            raise ProblemFileError(
                path,
                "quaternions",
                f"shape ({len(positions)}, 4) (w x y z), got {quaternions.shape}",
            )
        try:
            rotations = rotations_from_quaternions(quaternions)
        except InvalidInput as exc:
            raise ProblemFileError(path, "quaternions", str(exc)) from None
    return TargetArrays(positions, rotations)


def _read_csv(path: str) -> tuple[np.ndarray, np.ndarray | None]:
    from .errors import ProblemFileError

    with open(path) as stream:
        first = stream.readline()
    try:
        [float(cell) for cell in first.split(",")]
        header = False
    except ValueError:
        header = True
    try:
        table = np.loadtxt(path, delimiter=",", skiprows=1 if header else 0, ndmin=2)
    except ValueError as exc:
        raise ProblemFileError(path, "CSV", f"numbers separated by commas ({exc})") from None
    columns = [c.strip().lower() for c in first.split(",")] if header else None
    if columns is None:
        if table.shape[1] not in (3, 7):
            raise ProblemFileError(
                path, "CSV", f"3 (x y z) or 7 (x y z qw qx qy qz) columns, got {table.shape[1]}"
            )
        return table[:, :3], (table[:, 3:] if table.shape[1] == 7 else None)
    missing = [c for c in ("x", "y", "z") if c not in columns]
    if missing:
        raise ProblemFileError(path, "CSV header", f"columns x, y, z; missing {missing}")
    positions = table[:, [columns.index(c) for c in ("x", "y", "z")]]
    quaternion_columns = ("qw", "qx", "qy", "qz")
    present = [c in columns for c in quaternion_columns]
    if any(present) and not all(present):
        raise ProblemFileError(path, "CSV header", "all of qw, qx, qy, qz or none")
    quaternions = table[:, [columns.index(c) for c in quaternion_columns]] if all(present) else None
    return positions, quaternions


@dataclass
class BatchRun:
    """What :func:`solve_file` did: targets in the file, chunks solved before this run
    and in it (and targets in it), whether every chunk is now done, the wall time of this
    run [s], and over every target done, how many converged and why the others did not."""

    out: str
    total: int
    chunks: int
    chunks_before: int
    chunks_solved: int
    complete: bool
    elapsed: float
    converged: int = 0
    targets_solved: int = 0
    reasons: dict[str, int] | None = None

    def summary(self) -> str:
        solved = self.chunks_solved
        lines = [
            f"{self.out}: {self.chunks_before + solved}/{self.chunks} chunks of {self.total} "
            f"targets done ({self.chunks_before} before this run, {solved} now)"
        ]
        rate = self.targets_solved / self.elapsed if self.elapsed > 0 else 0.0
        lines.append(
            f"this run: {self.targets_solved} targets in {self.elapsed:.1f} s ({rate:.0f} IK/s)"
        )
        if self.complete and self.reasons is not None:
            reasons = ", ".join(f"{k} {v}" for k, v in sorted(self.reasons.items()))
            lines.append(f"converged {self.converged}/{self.total}; reasons: {reasons}")
        elif not self.complete:
            lines.append("incomplete: run the same command again to resume")
        return "\n".join(lines)


def _atomic_savez(path: str, **arrays) -> None:
    """Write an npz so that a reader never sees half a file (temporary file, rename)."""
    tmp = f"{path}.tmp{os.getpid()}.npz"
    np.savez(tmp, **arrays)
    os.replace(tmp, path)


def _pyarrow():
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError as exc:
        raise MissingExtra("Parquet results", "cluster", "pyarrow") from exc
    return pyarrow


def _write_results(path: str, table: Mapping[str, np.ndarray], meta: Mapping[str, Any]) -> None:
    """Write the results table to ``path`` (npz, or Parquet with one row per target and
    ``q`` a fixed-size list column), atomically; ``meta`` goes along as JSON."""
    import json

    if not path.endswith(".parquet"):
        _atomic_savez(path, **table, **_meta_arrays(meta))
        return
    pa = _pyarrow()
    q = np.asarray(table["q"], dtype=float)
    columns = {"index": pa.array(np.arange(len(q)))}
    columns["q"] = pa.FixedSizeListArray.from_arrays(pa.array(q.ravel()), q.shape[1])
    for name in (*RESULT_FIELDS, "done"):
        columns[name] = pa.array(table[name])
    arrow = pa.table(columns).replace_schema_metadata({"qpik": json.dumps(meta)})
    tmp = f"{path}.tmp{os.getpid()}.parquet"
    pa.parquet.write_table(arrow, tmp)
    os.replace(tmp, path)


def _read_results(path: str) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """``(meta, table)`` of a results file written by :func:`_write_results`."""
    import json

    if not path.endswith(".parquet"):
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            return meta, {name: data[name] for name in ("q", *RESULT_FIELDS, "done")}
    pa = _pyarrow()
    arrow = pa.parquet.read_table(path)
    meta = json.loads(arrow.schema.metadata[b"qpik"])
    q = arrow.column("q").combine_chunks()
    table = {"q": q.flatten().to_numpy().reshape(len(q), q.type.list_size)}
    for name in (*RESULT_FIELDS, "done"):
        values = arrow.column(name).to_numpy(zero_copy_only=False)
        table[name] = values.astype(RESULT_FIELDS.get(name, bool))
    return meta, table


def solve_file(
    robot: RobotLike,
    frame: FrameKey,
    targets: str | os.PathLike | TargetArrays,
    out: str | os.PathLike,
    *,
    chunk_size: int = 128,
    seed: int = 0,
    workers: int | None = None,
    backend: str = "process",
    address: str | None = None,
    max_chunks: int | None = None,
    overwrite: bool = False,
    progress: bool = True,
    **solve_options: Any,
) -> BatchRun:
    """Solve a targets file (see :func:`load_targets`) for ``frame`` and write the results
    to ``out`` (``.npz``, or ``.parquet`` with pyarrow: ``pip install 'qpik[cluster]'``)
    chunk by chunk; a rerun with the same ``out`` resumes.

    Each finished chunk is saved at once, atomically, in the folder ``out + ".chunks"``;
    ``out`` itself is rewritten every few seconds and at the end, with every row: ``q``
    ``(N, nq)``, ``converged``, ``reason``, ``position_error`` [m], ``orientation_error``
    [rad], ``iterations``, ``restarts_used``, ``time`` [s] (unsolved rows: NaN, ``False``,
    ``"pending"``) and ``done`` ``(N,)``. When every chunk is done, the folder is removed.
    A rerun skips the chunks already done; it refuses (``InvalidInput``) to mix runs whose
    targets, robot, frame, seed, chunk size or options differ, unless ``overwrite``.
    ``max_chunks`` stops after that many new chunks (resume later). Target ``i`` is solved
    with :func:`target_seed(seed, i) <target_seed>`: the file's rows are the same as
    :func:`solve_many`'s, however the run was split.
    """
    import json
    import shutil

    start_time = time.perf_counter()
    out = os.fspath(out)
    if not out.endswith((".npz", ".parquet")):
        raise InvalidInput(f"out must be an .npz or .parquet file, got {out!r}")
    if out.endswith(".parquet"):
        _pyarrow()  # before solving, naming the extra
    arrays = targets if isinstance(targets, TargetArrays) else load_targets(targets)
    entropy = _check_seed(seed)
    workers = check_workers(workers, backend)
    _check_chunk_size(chunk_size)
    spec, model, q0 = prepare_robot(robot)
    _check_frame(model, frame)
    if q0 is not None:
        solve_options.setdefault("q0", q0)
    n = len(arrays)
    starts = list(range(0, n, chunk_size))
    meta = {
        "robot": spec if isinstance(spec, str) else f"MjModel(nq={model.nq})",
        "frame": list(frame) if isinstance(frame, tuple) else frame,
        "targets": arrays.fingerprint(),
        "n": n,
        "nq": int(model.nq),
        "seed": entropy,
        "chunk_size": chunk_size,
        "options": {k: repr(v) for k, v in sorted(solve_options.items())},
    }
    folder = out + ".chunks"
    meta_path = os.path.join(folder, "meta.json")
    if overwrite:
        shutil.rmtree(folder, ignore_errors=True)
        if os.path.exists(out):
            os.remove(out)
    done_starts: set[int] = set()
    table = _empty_table(n, model.nq)
    previous = _previous_run(out, folder, meta_path, table)
    if previous is not None:
        old_meta, done_starts = previous
        different = [k for k in meta if old_meta.get(k) != meta[k]]
        if different:
            raise InvalidInput(
                f"{out} holds a run with different {', '.join(different)}: pass another "
                "--out, or --overwrite to start again"
            )
    before = len(done_starts)
    todo = [s for s in starts if s not in done_starts]
    if max_chunks is not None:
        todo = todo[: max(0, int(max_chunks))]
    if todo:
        os.makedirs(folder, exist_ok=True)
        if not os.path.exists(meta_path):
            with open(meta_path, "w") as stream:
                json.dump(meta, stream, indent=1)
    solved = targets_solved = 0
    last_write, write_cost = time.perf_counter(), 0.0
    bar = progress_bar(n, progress, initial=int(table["done"].sum()))
    try:
        chunks = (arrays.chunk(frame, s, min(s + chunk_size, n)) for s in todo)
        for start, results in _iter_prepared(
            spec,
            model,
            chunks,
            entropy,
            workers if len(todo) > 1 else 1,
            backend,
            address,
            solve_options,
        ):
            rows = _rows(results, model.nq)
            _atomic_savez(os.path.join(folder, f"chunk_{start:010d}.npz"), **rows)
            _fill(table, start, rows)
            done_starts.add(start)
            solved += 1
            targets_solved += len(results)
            bar.update(len(results))
            now = time.perf_counter()
            if now - last_write > max(5.0, 20.0 * write_cost):
                _write_results(out, table, meta)
                write_cost, last_write = time.perf_counter() - now, time.perf_counter()
    finally:
        bar.close()
        if solved or previous is None:
            _write_results(out, table, meta)
    complete = len(done_starts) == len(starts)
    if complete:
        shutil.rmtree(folder, ignore_errors=True)
    reasons: dict[str, int] = {}
    for reason in table["reason"]:
        reasons[str(reason)] = reasons.get(str(reason), 0) + 1
    return BatchRun(
        out=out,
        total=n,
        chunks=len(starts),
        chunks_before=before,
        chunks_solved=solved,
        targets_solved=targets_solved,
        complete=complete,
        elapsed=time.perf_counter() - start_time,
        converged=int(table["converged"].sum()),
        reasons=reasons,
    )


def _empty_table(n: int, nq: int) -> dict[str, np.ndarray]:
    table = {"q": np.full((n, nq), np.nan)}
    for name, dtype in RESULT_FIELDS.items():
        if dtype is float:
            table[name] = np.full(n, np.nan)
        elif dtype == "U16":
            table[name] = np.full(n, "pending", dtype="U16")
        else:
            table[name] = np.zeros(n, dtype=dtype)
    table["done"] = np.zeros(n, dtype=bool)
    return table


def _rows(results: Sequence[IKResult], nq: int) -> dict[str, np.ndarray]:
    return {
        "q": np.array([r.q for r in results], dtype=float).reshape(len(results), nq),
        "converged": np.array([r.converged for r in results], dtype=bool),
        "reason": np.array([r.reason for r in results], dtype="U16"),
        "position_error": np.array([r.position_error for r in results], dtype=float),
        "orientation_error": np.array([r.orientation_error for r in results], dtype=float),
        "iterations": np.array([r.iterations for r in results], dtype=np.int64),
        "restarts_used": np.array([r.restarts_used for r in results], dtype=np.int64),
        "time": np.array([r.solve_time for r in results], dtype=float),
    }


def _fill(table: dict[str, np.ndarray], start: int, rows: Mapping[str, np.ndarray]) -> None:
    stop = start + len(rows["converged"])
    for name, values in rows.items():
        table[name][start:stop] = values
    table["done"][start:stop] = True


def _meta_arrays(meta: Mapping[str, Any]) -> dict[str, np.ndarray]:
    import json

    return {"meta": np.array(json.dumps(meta))}


def _previous_run(out: str, folder: str, meta_path: str, table: dict[str, np.ndarray]):
    """``(meta, finished chunk starts)`` of an earlier run over ``out`` (``None`` if there
    was none); the finished rows are copied into ``table`` (when its shape matches)."""
    import json

    done: set[int] = set()
    meta = None
    n = len(table["done"])
    if os.path.exists(out):
        try:
            meta, saved = _read_results(out)
        except MissingExtra:
            raise
        except Exception as exc:
            raise InvalidInput(
                f"{out} exists and is not a qpik batch results file ({exc}): pass another "
                "--out, or --overwrite"
            ) from None
        if saved["q"].shape == table["q"].shape:
            size = int(meta.get("chunk_size", 1))
            for start in range(0, n, size):
                if saved["done"][start : start + size].all():
                    done.add(start)
                    for name in table:
                        table[name][start : start + size] = saved[name][start : start + size]
    if os.path.exists(meta_path):
        with open(meta_path) as stream:
            meta = json.load(stream)
        for name in sorted(os.listdir(folder)):
            if not (name.startswith("chunk_") and name.endswith(".npz")):
                continue
            start = int(name[6:-4])
            if start in done or start >= n:
                continue
            with np.load(os.path.join(folder, name), allow_pickle=False) as data:
                rows = {key: data[key] for key in ("q", *RESULT_FIELDS)}
            if rows["q"].shape[1:] == table["q"].shape[1:]:
                _fill(table, start, rows)
                done.add(start)
    return None if meta is None else (meta, done)
