"""Batches on a Ray cluster (``solve_many(..., backend="ray")``): :func:`ray_init` connects,
and :func:`iter_ray` runs a batch's chunks as Ray tasks, a few per CPU ahead. Ray comes with
the ``cluster`` extra (``pip install -e '.[cluster]'``); the workers of a remote cluster
need qpik (and the robot files given by path) installed on every node.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Iterable, Iterator
from typing import Any

from ..errors import InvalidInput, MissingExtra, RayConnectionError
from ..igm.result import IKResult
from .chunks import Chunk, Failure
from .worker import WORKER, ChunkSolver, WorkerSetup, raise_failures

__all__ = ["RayConnectionError", "check_address", "iter_ray", "ray_init"]

#: What an address may be, as the errors say it.
_ADDRESS_FORMS = (
    "'auto' (the Ray cluster running on this machine), 'ray://HOST:PORT' (a Ray Client "
    "server, port 10001 by default), 'HOST:PORT' (a cluster's head, from one of its nodes) "
    "or 'local' (start Ray here)"
)


def check_address(address: str | None) -> None:
    """Check a Ray address before anything runs: ``None``, ``"auto"``, ``"local"``,
    ``"ray://HOST:PORT"`` or ``"HOST:PORT"`` (port 1 to 65535), else
    :class:`qpik.InvalidInput`; a ``ray://`` address without Ray Client's dependencies
    (``pip install "ray[client]"``) raises :class:`qpik.MissingExtra`."""
    if address is None or address in ("auto", "local"):
        return
    client = address.startswith("ray://")
    host, colon, port = address.removeprefix("ray://").rpartition(":")
    valid = (
        bool(colon and host.strip("[]"))
        and not any(c.isspace() or c == "/" for c in host)
        and port.isdigit()
        and 0 < int(port) < 65536
    )
    if not valid:
        raise InvalidInput(f"Ray address {address!r} is not one of: {_ADDRESS_FORMS}")
    if client and not _has_ray_client():
        error = MissingExtra(f"the Ray Client address {address!r}", "cluster", "ray[client]")
        error.msg = (  # what str() shows of an ImportError
            f"the Ray Client address {address!r} needs Ray's client dependencies (grpcio), "
            'which the cluster extra does not install: pip install "ray[client]"'
        )
        error.args = (error.msg,)
        raise error


def _has_ray_client() -> bool:
    """Whether Ray Client's dependencies are installed (Ray checks for ``grpc``)."""
    return importlib.util.find_spec("grpc") is not None


def _ray() -> Any:
    try:
        import ray
    except ImportError as exc:
        raise MissingExtra("solve_many(backend='ray')", "cluster", "ray") from exc
    return ray


def ray_init(address: str | None = None, workers: int | None = None) -> Any:
    """Connect to Ray: the running session if there is one, else ``address`` (``"auto"``,
    ``"ray://host:10001"``, ...: :func:`check_address`), else a local Ray with ``workers``
    CPUs. Returns the ``ray`` module. A local Ray started here stays up for later batches
    (``ray.shutdown()`` stops it). No cluster at ``address``: :class:`RayConnectionError`."""
    check_address(address)
    ray = _ray()
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
        if address in (None, "local"):
            kwargs["num_cpus"] = workers
        else:
            kwargs["address"] = address
        try:
            ray.init(**kwargs)
        except (ConnectionError, TimeoutError) as exc:  # Ray's own advice names its CLI
            raise RayConnectionError(address, _first_sentence(exc), _ADDRESS_FORMS) from exc
        except ValueError as exc:  # an address that Ray reads otherwise than check_address
            raise InvalidInput(f"Ray address {address!r}: {_first_sentence(exc)}") from exc
    return ray


def _first_sentence(exc: BaseException) -> str:
    """The first sentence of an error's message (Ray's next ones advise its own flags)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text.split(". ", 1)[0].rstrip(".")


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
