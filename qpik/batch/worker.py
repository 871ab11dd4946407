"""The work of one batch worker: :class:`ChunkSolver` loads the robot once and solves
chunks of targets, target ``i`` with its own seed :func:`target_seed`, so that the results
do not depend on how a batch is split; a target that raises becomes a :class:`Failure`,
solved again in the caller (:func:`raise_failures`) to raise its error there, typed. A
process pool's workers start with :func:`init_worker` and run :func:`solve_chunk_in_worker`.
"""

from __future__ import annotations

import hashlib
import os
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ..errors import QpikError
from ..igm.result import IKResult
from ..igm.session import IKSession, solve
from ..model.configuration import Configuration, resolve_robot
from .chunks import Chunk, Failure, PackedChunk, pack_results, without_histories

__all__ = [
    "WORKER",
    "ChunkSolver",
    "WorkerError",
    "WorkerSetup",
    "init_worker",
    "raise_failures",
    "solve_chunk_in_worker",
    "target_seed",
]

_SOLVE = solve  # qpik.solve; tests replace this module's solve to inject failures


class WorkerError(QpikError, RuntimeError):
    """A worker process died, or failed on a target in a way that does not recur here."""


def target_seed(seed: int, index: int) -> int:
    """The seed :func:`qpik.solve_many` gives target ``index`` of a batch run with ``seed``:
    ``qpik.solve(robot, targets[i], seed=target_seed(seed, i), **options)`` reproduces
    entry ``i`` of the batch. A 64-bit BLAKE2b hash of ``(seed, index)`` only, so it does
    not depend on chunking, workers or backend."""
    digest = hashlib.blake2b(f"qpik-batch:{int(seed)}:{int(index)}".encode(), digest_size=8)
    return int.from_bytes(digest.digest(), "little")


@dataclass(frozen=True)
class WorkerSetup:
    """What a worker needs to solve a batch's chunks: the robot as workers load it
    (``spec``: a name, a path or an ``MjModel``), the batch's entropy (its seed), the
    keywords of every solve (``call``: ``q0``, ``stack``, ``options``), whether results
    keep their per-iteration histories, and the ``q`` of a :class:`qpik.Configuration`
    passed as the robot (``robot_q``: the default start, named ``robot`` when it is
    outside the limits)."""

    spec: Any
    entropy: int
    call: Mapping[str, Any]
    histories: bool = False
    robot_q: Any = None


class ChunkSolver:
    """One worker's state: the robot, loaded once, and the batch's solve keywords."""

    def __init__(self, setup: WorkerSetup):
        self.model = resolve_robot(setup.spec)[0]
        self.entropy = setup.entropy
        self.options = dict(setup.call)
        self.histories = setup.histories
        # the robot as the caller passed it: a Configuration's q is the default start
        robot = self.model
        if setup.robot_q is not None:
            robot = Configuration(self.model, setup.robot_q)
        self.robot: Any = robot
        # A session reads the model once; it keeps no state between solves, so its
        # results are those of qpik.solve, bitwise.
        self.session = IKSession(robot)

    def solve(self, index: int, targets: Mapping) -> IKResult:
        seed = target_seed(self.entropy, index)
        if solve is _SOLVE:
            result = self.session.solve(targets, seed=seed, **self.options)
        else:  # this module's solve replaced (tests)
            result = solve(self.robot, targets, seed=seed, **self.options)
        return result if self.histories else without_histories(result)

    def solve_chunk(self, chunk: Chunk) -> tuple[int, list[IKResult | Failure]]:
        results: list[IKResult | Failure] = []
        for offset, targets in enumerate(chunk.targets):
            index = chunk.start + offset
            try:
                results.append(self.solve(index, targets))
            except Exception as exc:  # re-raised with its type by the caller
                results.append(Failure(index, targets, f"{type(exc).__name__}: {exc}"))
        return chunk.start, results


#: The solver of this worker process, set by its initializer (a Ray worker keys it by batch).
WORKER: dict[str, ChunkSolver] = {}


def init_worker(setup: WorkerSetup | ChunkSolver) -> None:
    """The initializer of a pool's worker process: its solver, made from ``setup``, or
    ``setup`` itself when it is one (a forked worker inherits the caller's, prepared)."""
    _die_with_parent()
    WORKER["solver"] = setup if isinstance(setup, ChunkSolver) else ChunkSolver(setup)


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


def solve_chunk_in_worker(chunk: Chunk | PackedChunk) -> tuple[int, Any]:
    """Solve ``chunk`` in a pool's worker; the results packed unless they keep histories."""
    solver = WORKER["solver"]
    if isinstance(chunk, PackedChunk):
        chunk = chunk.unpack()
    start, results = solver.solve_chunk(chunk)
    return start, (results if solver.histories else pack_results(results))


def raise_failures(local: ChunkSolver, item: tuple[int, list]) -> tuple[int, list[IKResult]]:
    """Re-solve in this process a target that failed in a worker, so that its error is
    raised here with its type."""
    start, results = item
    for result in results:
        if isinstance(result, Failure):
            local.solve(result.index, result.targets)
            raise WorkerError(f"target {result.index} failed in a worker: {result.error}")
    return start, results
