"""Batches on a Ray cluster (``solve_many(..., backend="ray")``): :func:`ray_init` connects,
and :func:`iter_ray` runs a batch's chunks as Ray tasks, a few per CPU ahead. Ray comes with
the ``cluster`` extra (``pip install -e '.[cluster]'``); the workers of a remote cluster
need qpik (and the robot files given by path) installed on every node.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Any

from ..errors import MissingExtra
from ..igm.result import IKResult
from .chunks import Chunk, Failure
from .worker import WORKER, ChunkSolver, WorkerSetup, raise_failures

__all__ = ["iter_ray", "ray_init"]


def _ray() -> Any:
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


def iter_ray(
    setup: WorkerSetup,
    chunks: Iterable[Chunk],
    workers: int | None,
    address: str | None,
    ahead: int,
) -> Iterator[tuple[int, list[IKResult]]]:
    """Chunks solved as Ray tasks, ``ahead`` per CPU submitted ahead (``workers`` CPUs, or
    every CPU of the cluster), yielded as they finish."""
    ray = ray_init(address, workers)
    remote = ray.remote(num_cpus=1)(_ray_solve_chunk)
    local = ChunkSolver(setup)
    setup_ref = ray.put(setup)
    batch = f"ray-batch-{setup_ref.hex()}"  # one per call: workers reload per batch
    capacity = workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
    pending: list = []
    source = iter(chunks)
    exhausted = False
    try:
        while True:
            while not exhausted and len(pending) < ahead * capacity:
                chunk = next(source, None)
                if chunk is None:
                    exhausted = True
                else:
                    pending.append(remote.remote(batch, setup_ref, chunk))
            if not pending:
                return
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                yield raise_failures(local, ray.get(ref))
    finally:
        for ref in pending:
            ray.cancel(ref)


def _ray_solve_chunk(
    batch: str, setup: WorkerSetup, chunk: Chunk
) -> tuple[int, list[IKResult | Failure]]:
    """A Ray task. Ray reuses its worker processes, so a worker loads the robot at its
    first chunk of batch ``batch`` and keeps it for the next ones."""
    if batch not in WORKER:
        WORKER.clear()
        WORKER[batch] = ChunkSolver(setup)
    return WORKER[batch].solve_chunk(chunk)
