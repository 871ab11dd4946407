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
* on Linux workers are forked: they start at once with the compiled kernels of the
  parent; a batch whose serial time, estimated from its first solve, is below
  ``pool_threshold`` seconds is solved in-process all the same.

Errors are raised in the calling process with their type: the targets are checked (frames,
shapes, NaN) and the first target is solved in-process (options) before any worker starts;
a target that fails in a worker is solved again here to raise its error.

Entry points: :func:`solve_many` (a list in, a list of :class:`qpik.IKResult` out);
:func:`iter_solve` (chunks in, ``(start, results)`` out as they finish, for batches that do
not fit in memory); :func:`qpik.batch.files.solve_file` (a targets file in, a results file
written chunk by chunk and resumed, behind ``qpik batch``); :func:`qpik.reachability`. They
take the keywords of :class:`BatchKeywords`: how the batch runs (:class:`BatchOptions`) and
the keywords of every solve. What travels to the workers is in :mod:`qpik.batch.chunks`,
what a worker does in :mod:`qpik.batch.worker`, Ray in :mod:`qpik.batch.ray`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
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

    from typing_extensions import Unpack

from ..core import checks
from ..errors import InvalidArgumentType, InvalidInput
from ..igm.result import IKResult
from ..igm.session import SolveArguments
from ..igm.targets import FrameKey, RobotLike, TargetLike
from ..model.configuration import resolve_robot
from ..options import SolveOptions, resolve
from .chunks import Chunk, check_targets, pack_chunk, stack_targets, unpack_results
from .ray import check_address, iter_ray, ray_init
from .worker import (
    ChunkSolver,
    WorkerError,
    WorkerSetup,
    init_worker,
    raise_failures,
    solve_chunk_in_worker,
    target_seed,
)

__all__ = [
    "BACKENDS",
    "Batch",
    "BatchKeywords",
    "BatchOptions",
    "Chunk",
    "WorkerError",
    "check_chunk_size",
    "check_run",
    "chunk_starts",
    "check_seed",
    "check_targets",
    "check_workers",
    "iter_prepared",
    "iter_solve",
    "max_process_workers",
    "prepare_robot",
    "progress_bar",
    "ray_init",
    "solve_call",
    "solve_many",
    "stream_chunks",
    "target_seed",
    "WORKERS_PER_CORE",
]

#: Where a batch runs: ``"process"`` (a pool on this machine) or ``"ray"`` (a Ray cluster).
BACKENDS = ("process", "ray")

#: Chunks submitted ahead of the workers, per worker (bounds memory on huge batches).
_AHEAD = 3
#: The most processes a pool starts per core of this machine (``os.cpu_count()``): a
#: larger ``workers`` is capped to it (IK is CPU-bound: more would only compete for the
#: cores, and a typo such as ``workers=10**6`` would fork until the machine gives up).
WORKERS_PER_CORE = 4
#: The default chunks are guided (:func:`chunk_starts`): each takes a share of what is left,
#: between these sizes. Each chunk costs the caller a round trip (pickling, the pool's
#: bookkeeping), which competes with the workers for the cores: large chunks while much is
#: left, small ones at the end, so that the workers finish together.
_MAX_CHUNK = 1024
_MIN_CHUNK = 16


@dataclass(frozen=True)
class BatchOptions:
    """How a batch runs: the keywords of :func:`solve_many`, :func:`iter_solve`,
    :func:`qpik.reachability` and :func:`qpik.batch.files.solve_file` besides those of each
    solve.

    Attributes:
        seed: batch seed; target ``i`` is solved with :func:`target_seed(seed, i)
            <target_seed>`, so the results are bitwise the same whatever ``workers``,
            ``chunk_size`` or ``backend`` (``None``: fresh entropy). Default ``0``.
        workers: processes (``None``: ``os.cpu_count()``; for Ray, every CPU of the
            cluster); ``1`` solves in this process. A process pool starts at most one
            worker per chunk of the batch and at most :data:`WORKERS_PER_CORE` per core
            of this machine (more would only compete for the cores): a larger count is
            harmless, capped to that.
        backend: ``"process"`` (a process pool on this machine) or ``"ray"`` (needs
            ``pip install -e '.[cluster]'``).
        address: Ray address of an existing cluster (``"auto"``, ``"ray://host:10001"``);
            ``None`` joins the running Ray session or starts a local one.
        progress: a progress bar with rate and ETA on stderr (tqdm), shown on runs longer
            than 2 s.
        chunk_size: targets per task (default: guided, each task a share of the targets
            left, from 1024 down to 16 at the end; a file's run: 128).
        pool_threshold: [s] a batch whose serial time, estimated from its first solve,
            is below this is solved in this process (no workers start); a number >= 0
            (``0``: always a pool when ``workers > 1``; ``math.inf``: never).
        histories: keep each result's per-iteration ``residual_history``,
            ``error_history`` and ``path``; by default they are left empty (a batch then
            moves several times less data between processes).
    """

    seed: int | None = 0
    workers: int | None = None
    backend: str = "process"
    address: str | None = None
    progress: bool = True
    chunk_size: int | None = None
    pool_threshold: float = 1.0
    histories: bool = False


class BatchKeywords(SolveArguments, total=False):
    """The keywords of the batch entry points: how the batch runs (the fields of
    :class:`BatchOptions`, which document them), and :func:`qpik.solve`'s keywords for every
    solve (``q0``, ``stack`` and the option keywords, :class:`qpik.options.SolveKeywords`)."""

    seed: int | None
    workers: int | None
    backend: str
    address: str | None
    progress: bool
    chunk_size: int | None
    pool_threshold: float
    histories: bool


def check_seed(seed: int | None) -> int:
    """The batch's entropy: ``seed`` itself, or fresh entropy for ``None``."""
    if seed is None:
        # numpy types entropy as any SeedSequence's; a fresh one's is an int
        return int(np.random.SeedSequence().entropy)  # type: ignore[arg-type]
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InvalidInput(f"seed must be a non-negative integer or None, got {seed!r}")
    return int(seed)


def check_workers(workers: int | None, backend: str = "process") -> int | None:
    """Validate ``workers`` (``None``: every core, or for Ray every CPU of the cluster).
    A daemonic process (a pool's worker, say) may not start processes: the process backend
    then solves in this process (``1``; the answers are the same, target by target)."""
    if backend not in BACKENDS:
        raise InvalidInput(f"unknown backend {backend!r}; expected one of: {', '.join(BACKENDS)}")
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1
    ):
        raise InvalidInput(f"workers must be a positive integer or None, got {workers!r}")
    if backend == "process":
        import multiprocessing  # loaded here (a pool's start loads it anyway)

        if multiprocessing.current_process().daemon:
            return 1
    if workers is None:
        return (os.cpu_count() or 1) if backend == "process" else None
    if backend == "process":
        return min(int(workers), max_process_workers())
    return int(workers)


def max_process_workers() -> int:
    """The most workers a process pool starts: :data:`WORKERS_PER_CORE` per core."""
    return WORKERS_PER_CORE * max(1, os.cpu_count() or 1)


def check_run(run: BatchOptions) -> BatchOptions:
    """``run`` with its flags and ``pool_threshold`` checked (the seed, the workers, the
    backend and the chunk size have their own checks): a non-bool ``progress`` or
    ``histories``, or a ``pool_threshold`` that is not a number raise
    :class:`qpik.InvalidArgumentType`; a negative or NaN ``pool_threshold``
    :class:`qpik.InvalidOption` (``math.inf`` is allowed: never a pool)."""
    progress = checks.check_bool("progress", run.progress)
    histories = checks.check_bool("histories", run.histories)
    threshold = run.pool_threshold
    if not (checks.is_real(threshold) and float(threshold) == math.inf):
        threshold = checks.check_real("pool_threshold", threshold, 0.0, unit="s")
    if run.address is not None and not isinstance(run.address, str):
        raise InvalidArgumentType(
            "address", "a Ray address (a str) or None", type(run.address).__name__
        )
    if run.backend == "ray":
        check_address(run.address)  # before anything starts: a malformed address, a missing extra
    return dataclasses.replace(
        run, progress=progress, histories=histories, pool_threshold=float(threshold)
    )


def check_chunk_size(chunk_size: int | None, optional: bool = False) -> int | None:
    """``chunk_size`` as an int (a numpy integer too, as for ``workers``);
    :class:`qpik.InvalidInput` unless it is an integer >= 1, not a bool (or ``None`` when
    ``optional``)."""
    if chunk_size is None and optional:
        return None
    if (
        isinstance(chunk_size, (bool, np.bool_))
        or not isinstance(chunk_size, (int, np.integer))
        or chunk_size < 1
    ):
        raise InvalidInput(f"chunk_size must be a positive integer, got {chunk_size!r}")
    return int(chunk_size)


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


def solve_call(
    options: SolveOptions | str | None, solve_options: Mapping[str, Any]
) -> dict[str, Any]:
    """The keywords every solve of a batch gets: ``q0`` and ``stack`` as given, and the
    other options folded into one :class:`qpik.SolveOptions`, validated here (a bad option
    raises in the caller, typed, before any worker starts). A Configuration's ``q`` is not
    one of them: the workers' sessions start from it as ``qpik.solve(configuration)``
    does (:attr:`WorkerSetup.robot_q`). A batch's ``seed`` is its own argument: target
    ``i`` gets :func:`target_seed(seed, i) <target_seed>`, whatever ``options.seed``."""
    keywords = dict(solve_options)
    call: dict[str, Any] = {k: keywords.pop(k) for k in ("q0", "stack") if k in keywords}
    call["options"] = resolve(options).replace(**keywords)
    return call


@dataclass(frozen=True)
class Batch:
    """A batch ready to run: the setup of its workers (the robot as they load it, the
    entropy, the keywords of every solve), the model loaded here, the number of workers
    (checked), how it runs (:class:`BatchOptions`) and the solve keywords as given (files
    and maps record them)."""

    setup: WorkerSetup
    model: mujoco.MjModel
    workers: int | None
    run: BatchOptions
    keywords: Mapping[str, Any]

    @classmethod
    def prepare(
        cls,
        robot: RobotLike,
        options: SolveOptions | str | None,
        keywords: Mapping[str, Any],
        unused: Sequence[str] = (),
        **defaults: Any,
    ) -> Batch:
        """Check an entry point's arguments and load the robot: ``keywords`` (its
        :class:`BatchKeywords`) split into :class:`BatchOptions` (``defaults`` first) and
        the solve keywords; the ``unused`` batch options (which this entry point does
        not take) raise :class:`qpik.InvalidInput` when given."""
        given = dict(keywords)
        names = [f.name for f in dataclasses.fields(BatchOptions)]
        own = {name: given.pop(name) for name in names if name in given}
        for name in unused:
            if name in own:
                raise InvalidInput(
                    f"{name!r} does not apply here; it is not an option of this call"
                )
        run = check_run(BatchOptions(**{**defaults, **own}))
        entropy = check_seed(run.seed)
        workers = check_workers(run.workers, run.backend)
        run = dataclasses.replace(run, chunk_size=check_chunk_size(run.chunk_size, True))
        spec, model, q0 = prepare_robot(robot)
        call = solve_call(options, given)
        setup = WorkerSetup(spec, entropy, call, run.histories, q0)
        return cls(setup, model, workers, run, given)

    @property
    def options(self) -> SolveOptions:
        """The options of every solve."""
        return self.setup.call["options"]

    def local_solver(self) -> ChunkSolver:
        """A :class:`qpik.batch.worker.ChunkSolver` in this process, on the model loaded here."""
        return ChunkSolver(self.local_setup())

    def local_setup(self) -> WorkerSetup:
        """The workers' setup with the model loaded here (what a forked worker inherits)."""
        return dataclasses.replace(self.setup, spec=self.model)

    def with_workers(self, workers: int | None) -> Batch:
        """The same batch on ``workers`` workers."""
        return dataclasses.replace(self, workers=workers)


# --- running chunks -------------------------------------------------------------------------


def iter_solve(
    robot: RobotLike,
    chunks: Iterable[Chunk],
    *,
    options: SolveOptions | str | None = None,
    **keywords: Unpack[BatchKeywords],
) -> Iterator[tuple[int, list[IKResult]]]:
    """Solve chunks of a batch and yield ``(start, results)`` as each chunk finishes (in
    completion order, not index order). ``workers=1`` solves in this process, in order.
    The workers stop when the iterator is exhausted or closed. Chunks are read lazily, a
    few per worker ahead, so ``chunks`` may be a generator over a huge batch. The targets
    are not checked here. The keywords are :func:`solve_many`'s but ``progress``,
    ``chunk_size`` and ``pool_threshold``, which do not apply to given chunks."""
    unused = ("progress", "chunk_size", "pool_threshold")
    yield from iter_prepared(Batch.prepare(robot, options, keywords, unused), chunks)


def iter_prepared(batch: Batch, chunks: Iterable[Chunk]) -> Iterator[tuple[int, list[IKResult]]]:
    """:func:`iter_solve` once its arguments are checked and the robot loaded."""
    run = batch.run
    if run.backend == "ray":
        yield from iter_ray(batch.setup, chunks, batch.workers, run.address, _AHEAD)
        return
    if run.address is not None:
        raise InvalidInput("address is a Ray address: pass backend='ray' with it")
    if batch.workers == 1:
        local = batch.local_solver()
        for chunk in chunks:
            yield raise_failures(local, local.solve_chunk(chunk))
        return
    yield from _iter_pool(batch, chunks)


def _iter_pool(batch: Batch, chunks: Iterable[Chunk]) -> Iterator[tuple[int, list[IKResult]]]:
    """Chunks solved by a process pool, a few per worker submitted ahead; the pool has no
    more workers than there are chunks (the first ``workers`` are read to know)."""
    source = iter(chunks)
    first = list(itertools.islice(source, batch.workers or 1))
    if not first:
        return
    workers = min(batch.workers or 1, len(first))
    source = itertools.chain(first, source)
    local_setup = batch.local_setup()
    local = ChunkSolver(local_setup)
    context = _mp_context()
    forked = context.get_start_method() == "fork"
    from concurrent.futures import FIRST_COMPLETED, wait

    pool_class, broken = _pool_classes()
    executor = pool_class(
        max_workers=workers,
        mp_context=context,
        initializer=init_worker,
        # A forked worker has the model already (no file to read again), and takes this
        # process's solver as it is: the robot read, the target frame's chain prepared.
        initargs=(local if forked else batch.setup,),
    )
    try:
        pending: set[Future] = set()
        with _frozen_heap(forked):  # the first submission forks the workers
            _submit_ahead(source, pending, _AHEAD * workers, executor)
        while True:
            _submit_ahead(source, pending, _AHEAD * workers, executor)
            if not pending:
                return
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            try:
                items = sorted((future.result() for future in done), key=lambda item: item[0])
                items = [(start, unpack_results(results)) for start, results in items]
            except broken as exc:
                raise WorkerError(
                    "a worker process died (out of memory, killed, or a script that starts "
                    "workers without an `if __name__ == '__main__':` guard)"
                ) from exc
            for item in items:
                yield raise_failures(local, item)
    finally:
        executor.shutdown(wait=True, cancel_futures=True)


@contextlib.contextmanager
def _frozen_heap(freeze: bool) -> Iterator[None]:
    """While the workers fork: the caller's objects moved out of the garbage collector's
    reach (``gc.freeze``), so that a forked worker's collections neither walk them nor
    copy the memory pages they sit on (copy-on-write); the caller's own collector gets them
    back afterwards."""
    if not freeze:
        yield
        return
    import gc

    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def _submit_ahead(
    source: Iterator[Chunk], pending: set[Future], ahead: int, executor: ProcessPoolExecutor
) -> None:
    """Submit chunks from ``source`` until ``ahead`` are pending (or none remain)."""
    while len(pending) < ahead:
        chunk = next(source, None)
        if chunk is None:
            return
        pending.add(executor.submit(solve_chunk_in_worker, pack_chunk(chunk)))


def solve_many(
    robot: RobotLike,
    targets_list: Sequence[Mapping[FrameKey, TargetLike]],
    *,
    options: SolveOptions | str | None = None,
    **keywords: Unpack[BatchKeywords],
) -> list[IKResult]:
    """Solve a batch of IK problems (one ``{frame: target}`` mapping each, world frame,
    metres) with the same :func:`qpik.solve` options, on every core by default.

    Args:
        robot: a name, a path, an ``MjModel`` or a :class:`qpik.Configuration` (its ``q``
            is the start ``q0`` of every solve unless ``q0`` is passed).
        targets_list: the problems; entry ``i`` of the result solves ``targets_list[i]``.
        options: the :class:`qpik.SolveOptions` (or a preset name) of every solve;
            ``options.seed`` is not used (see ``seed``).
        **keywords: how the batch runs (``seed``, ``workers``, ``backend``, ``address``,
            ``progress``, ``chunk_size``, ``pool_threshold``, ``histories``: the fields of
            :class:`BatchOptions`, documented there), and :func:`qpik.solve`'s keywords for
            every solve (``q0``, ``stack``, and options overriding ``options``).
    """
    if isinstance(targets_list, (str, bytes, Mapping)) or not checks.is_iterable(targets_list):
        raise InvalidArgumentType(
            "targets_list", "a list of targets mappings", checks.type_name(targets_list)
        )
    targets_list = list(targets_list)
    batch = Batch.prepare(robot, options, keywords)
    stacked = stack_targets(batch.model, targets_list)
    if stacked is None:
        check_targets(batch.model, targets_list)
    source: Sequence[Mapping[FrameKey, TargetLike]] = targets_list if stacked is None else stacked
    results: list[IKResult] = []
    solved = stream_chunks(
        batch, len(targets_list), lambda start, stop: source[start:stop], ordered=True
    )
    for _start, chunk_results in solved:
        results.extend(chunk_results)
    return results


def stream_chunks(
    batch: Batch,
    n: int,
    targets_at: Callable[[int, int], Sequence[Mapping]],
    ordered: bool = False,
) -> Iterator[tuple[int, list[IKResult]]]:
    """Solve targets ``0..n-1`` (``targets_at(start, stop)`` builds a slice on demand) and
    yield ``(start, results)`` per chunk, in index order if ``ordered``.

    Target 0 is solved first, in this process: bad options raise here, typed, and its time
    tells whether starting workers is worth it (see ``pool_threshold``)."""
    if n == 0:
        return
    run = batch.run
    bar = progress_bar(n, run.progress)
    try:
        start_time = time.perf_counter()
        first = batch.local_solver().solve(0, targets_at(0, 1)[0])
        estimate = (time.perf_counter() - start_time) * (n - 1)
        bar.update(1)
        yield 0, [first]
        serial = run.backend == "process" and (batch.workers == 1 or estimate < run.pool_threshold)
        if serial:
            batch = batch.with_workers(1)
        capacity = batch.workers or os.cpu_count() or 1
        bounds = chunk_starts(1, n, capacity, run.chunk_size)
        chunks = (Chunk(s, targets_at(s, e)) for s, e in bounds)
        counted = _counted(iter_prepared(batch, chunks), bar)
        yield from (_in_order(counted, 1) if ordered else counted)
    finally:
        bar.close()


def chunk_starts(
    start: int, stop: int, workers: int, size: int | None = None
) -> Iterator[tuple[int, int]]:
    """The chunks ``(first, end)`` of targets ``start..stop - 1``: of ``size`` each, or by
    default guided (as OpenMP's ``schedule(guided)``): each chunk a ``1 / (2 workers)``
    share of the targets left, between ``_MIN_CHUNK`` and ``_MAX_CHUNK``. Results do not
    depend on the chunks (each target has its own seed)."""
    first = start
    while first < stop:
        if size is not None:
            step = size
        else:
            share = math.ceil((stop - first) / (2 * max(1, workers)))
            step = max(_MIN_CHUNK, min(_MAX_CHUNK, share))
        end = min(first + step, stop)
        yield first, end
        first = end


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


def _mp_context() -> multiprocessing.context.BaseContext:
    """``fork`` on Linux: workers start at once and inherit the compiled kernels and the
    loaded modules (a fresh interpreter, ``forkserver`` or ``spawn``, imports qpik again).
    Elsewhere ``spawn``, the platform's default: scripts then need an
    ``if __name__ == "__main__":`` guard."""
    import multiprocessing

    if sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("fork")
    return multiprocessing.get_context("spawn")


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
