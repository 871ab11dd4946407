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
* a batch whose serial time, estimated from its first solve, is below ``pool_threshold``
  seconds is solved in-process: starting workers costs about that much.

Errors are raised in the calling process with their type: the targets are checked (frames,
shapes, NaN) and the first target is solved in-process (options) before any worker starts.

Ray comes with the ``cluster`` extra (``pip install 'qpik[cluster]'``); the workers of a
remote cluster need qpik (and the robot files given by path) installed on every node.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import sys
import threading
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from .configuration import Configuration, FrameType, frame_names
from .converge import FrameKey, IKResult, RobotLike, TargetLike, parse_target, solve
from .errors import InvalidInput, InvalidTarget, MissingExtra, QpikError, UnknownFrame
from .robots import load_robot

__all__ = [
    "BACKENDS",
    "Chunk",
    "iter_solve",
    "prepare_robot",
    "solve_many",
    "target_seed",
]

#: Where a batch runs: ``"process"`` (a pool on this machine) or ``"ray"`` (a Ray cluster).
BACKENDS = ("process", "ray")

#: Chunks submitted ahead of the workers, per worker (bounds memory on huge batches).
_AHEAD = 3


def target_seed(seed: int, index: int) -> int:
    """The seed :func:`solve_many` gives target ``index`` of a batch run with ``seed``:
    ``qpik.solve(robot, targets[i], seed=target_seed(seed, i), **options)`` reproduces
    entry ``i`` of the batch. Derived by :class:`numpy.random.SeedSequence` from
    ``(seed, index)`` only, so it does not depend on chunking, workers or backend."""
    sequence = np.random.SeedSequence(seed, spawn_key=(int(index),))
    return int(sequence.generate_state(1, dtype=np.uint64)[0])


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
        return os.cpu_count() or 1 if backend == "process" else None
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


class _ChunkSolver:
    """One worker's state: the robot, loaded once, and the batch options."""

    def __init__(self, spec: Any, entropy: int, options: Mapping[str, Any]):
        self.model = load_robot(spec)
        self.entropy = entropy
        self.options = dict(options)

    def solve(self, index: int, targets: Mapping) -> IKResult:
        return solve(self.model, targets, seed=target_seed(self.entropy, index), **self.options)

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
    _WORKER["solver"] = _ChunkSolver(spec, entropy, options)


def _solve_chunk_in_worker(chunk: Chunk) -> tuple[int, list[IKResult | _Failure]]:
    return _WORKER["solver"].solve_chunk(chunk)


def _ray_solve_chunk(spec: Any, entropy: int, options: Mapping[str, Any], chunk: Chunk):
    """A Ray task: the worker process keeps the robot loaded between tasks of a batch."""
    key = (spec if isinstance(spec, str) else id(spec), entropy, repr(sorted(options.items())))
    solver = _WORKER.get("ray")
    if solver is None or getattr(solver, "key", None) != key:
        solver = _ChunkSolver(spec, entropy, options)
        solver.key = key  # type: ignore[attr-defined]
        _WORKER["ray"] = solver
    return solver.solve_chunk(chunk)


def _mp_context() -> multiprocessing.context.BaseContext:
    """``fork`` where it is safe (POSIX, one thread): workers start in milliseconds;
    else ``forkserver``/``spawn`` (scripts then need ``if __name__ == "__main__":``)."""
    methods = multiprocessing.get_all_start_methods()
    if "fork" in methods and threading.active_count() == 1 and sys.platform != "darwin":
        return multiprocessing.get_context("fork")
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


def _ray():
    try:
        import ray
    except ImportError as exc:
        raise MissingExtra("solve_many(backend='ray')", "cluster", "ray") from exc
    return ray


def ray_init(address: str | None = None, workers: int | None = None):
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
    **solve_options: Any,
) -> Iterator[tuple[int, list[IKResult]]]:
    """Solve chunks of a batch and yield ``(start, results)`` as each chunk finishes (in
    completion order, not index order). ``workers=1`` solves in this process, in order.
    The workers stop when the iterator is exhausted or closed. Chunks are read lazily, a
    few per worker ahead, so ``chunks`` may be a generator over a huge batch. The targets
    are not checked here (see :func:`solve_many`)."""
    entropy = _check_seed(seed)
    workers = check_workers(workers, backend)
    spec, model, q0 = prepare_robot(robot)
    options = dict(solve_options)
    if q0 is not None:
        options.setdefault("q0", q0)
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
            for future in sorted(done, key=lambda f: f.result()[0]):
                yield _raise_failures(local, future.result())
    finally:
        executor.shutdown(wait=True, cancel_futures=True)


def _iter_ray(spec, chunks, entropy, workers, address, options):
    ray = ray_init(address, workers)
    remote = ray.remote(num_cpus=1)(_ray_solve_chunk)
    local = _ChunkSolver(spec, entropy, options)
    spec_ref = ray.put(spec) if not isinstance(spec, str) else spec
    options_ref = ray.put(options)
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
                    pending.append(remote.remote(spec_ref, entropy, options_ref, chunk))
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
            raise QpikError(f"target {result.index} failed in a worker: {result.error}")
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
        **solve_options: passed to every :func:`qpik.solve` call.
    """
    targets_list = list(targets_list)
    entropy = _check_seed(seed)
    workers = check_workers(workers, backend)
    spec, model, q0 = prepare_robot(robot)
    _check_targets(model, targets_list)
    n = len(targets_list)
    results: list[IKResult | None] = [None] * n
    if n == 0:
        return []
    if chunk_size is not None and (
        isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1
    ):
        raise InvalidInput(f"chunk_size must be a positive integer, got {chunk_size!r}")
    options = dict(solve_options)
    if q0 is not None:
        options.setdefault("q0", q0)
    bar = _progress_bar(n, progress)
    try:
        # The first target in this process: bad options raise here, typed, and its time
        # tells whether workers are worth starting.
        start_time = time.perf_counter()
        results[0] = solve(model, targets_list[0], seed=target_seed(entropy, 0), **options)
        estimate = (time.perf_counter() - start_time) * (n - 1)
        bar.update(1)
        serial = backend == "process" and (workers == 1 or estimate < pool_threshold)
        parallel_workers = 1 if serial else workers
        capacity = parallel_workers or 1
        size = chunk_size or max(1, min(64, math.ceil((n - 1) / (4 * capacity))))
        chunks = (
            Chunk(start, targets_list[start : start + size]) for start in range(1, n, size)
        )
        for start, chunk_results in iter_solve(
            spec if not isinstance(robot, Configuration) else model,
            chunks,
            seed=entropy,
            workers=parallel_workers,
            backend=backend,
            address=address,
            **options,
        ):
            results[start : start + len(chunk_results)] = chunk_results
            bar.update(len(chunk_results))
    finally:
        bar.close()
    return results  # type: ignore[return-value]


def _progress_bar(total: int, enabled: bool, initial: int = 0, desc: str = "IK"):
    """A tqdm bar (rate, ETA) on stderr, shown once a run has lasted 2 s."""
    from tqdm.auto import tqdm

    return tqdm(
        total=total,
        initial=initial,
        unit="IK",
        desc=desc,
        disable=not enabled,
        delay=2.0,
        smoothing=0.1,
        dynamic_ncols=True,
    )

