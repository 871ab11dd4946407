"""The restart loop of the IGM, shared by :func:`qpik.solve`'s ``"qp"`` engine and the
baselines (:func:`qpik.igm.baselines.igm`); the compiled engine runs the same rules in
:func:`qpik.igm.kernels.igm_solve`.

The rules:

* an *attempt* iterates from a start until it converges, reaches ``max_iters``, runs out
  of time, or stops making progress: ``stall_window`` iterations without a 5 % decrease
  of its score (:class:`StallWindow`); the compiled engine also ends an attempt at a
  step that the joint limits or the singularity damping block (its QP residual above
  :data:`qpik.igm.kernels.BLOCKED` times the decrease it asks for) while its score is
  above :data:`qpik.igm.kernels.NEAR_TARGET`;
* while it has not converged, restarts (``restarts`` of them at most), time and
  iterations (:attr:`qpik.SolveOptions.iteration_budget`, over all attempts) remain, the
  loop starts a new attempt from a random configuration;
* the best attempt is returned: a converged one over one that did not, then the lowest
  score (the first attempt among equals); attempts that carry a lexicographic ``key`` (a
  stack of several levels) compare by it instead.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np

from ..errors import InvalidInput
from .kernels import PROGRESS
from .result import Reason

__all__ = ["Attempt", "Clock", "Seed", "StallWindow", "rng_state", "run_attempts"]

#: Bit generators whose raw output is their next 64-bit draw: for these,
#: ``bit_generator.random_raw()`` is ``integers(0, 2**64 - 1, dtype=np.uint64,
#: endpoint=True)`` (one draw; the generator advances alike), without its argument handling.
RAW_UINT64 = (np.random.PCG64, np.random.PCG64DXSM, np.random.SFC64, np.random.Philox)
#: What a solve's ``seed`` may be (see :func:`qpik.solve`).
Seed = int | np.random.Generator | np.random.SeedSequence | None


def rng_state(seed: Seed) -> int:
    """The SplitMix64 state (an int in ``[0, 2**64)``) of ``seed``: an int >= 0, a Generator
    (one draw), a SeedSequence, or None (fresh entropy: not reproducible)."""
    if seed is None:  # 64 bits from the OS (a SeedSequence's hashing costs ~25 us a call)
        return int.from_bytes(os.urandom(8), "little")
    if isinstance(seed, np.random.Generator):
        if type(seed.bit_generator) in RAW_UINT64:  # the same draw, ~10x cheaper
            return seed.bit_generator.random_raw()
        return int(seed.integers(0, 2**64 - 1, dtype=np.uint64, endpoint=True))
    if isinstance(seed, np.random.SeedSequence):
        return int(seed.generate_state(1, np.uint64)[0])
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed >= 0:
        if seed < 2**64:
            return int(seed)
        return int(np.random.SeedSequence(int(seed)).generate_state(1, np.uint64)[0])
    raise InvalidInput(
        f"seed must be an int >= 0, a numpy Generator or SeedSequence, or None; got {seed!r}"
    )


P = TypeVar("P")


class StallWindow:
    """Counts iterations without progress: ``update(score)`` is True once
    ``stall_window`` consecutive scores have not gone below ``PROGRESS`` (95 %) of the
    score at the window's start (the compiled engine's rule,
    :data:`qpik.igm.kernels.PROGRESS`)."""

    __slots__ = ("_best", "_since", "_window")

    def __init__(self, score: float, window: int):
        self._best = score
        self._since = 0
        self._window = window

    def update(self, score: float) -> bool:
        """Record one iteration's score; whether the attempt has stalled."""
        if score < PROGRESS * self._best:
            self._best, self._since = score, 0
            return False
        self._since += 1
        return self._since >= self._window


class Clock:
    """The time budget [s] of a solve, from ``start`` (``time.perf_counter()``)."""

    __slots__ = ("budget", "start")

    def __init__(self, start: float, budget: float | None):
        self.start = start
        self.budget = budget

    def out_of_time(self) -> bool:
        """Whether the budget (if any) is spent."""
        return self.budget is not None and time.perf_counter() - self.start > self.budget

    def elapsed(self) -> float:
        """Seconds since the start."""
        return time.perf_counter() - self.start


@dataclass
class Attempt(Generic[P]):
    """The outcome of one attempt: whether it converged, its final score (lower is
    better), why it ended, and whatever the caller keeps of it (``payload``)."""

    converged: bool
    score: float
    reason: Reason
    payload: P
    #: A lexicographic rank that replaces ``score`` when both attempts have one (a stack
    #: of several levels: level 0's error first, see :mod:`qpik.igm.qp_engine`).
    key: tuple[float, ...] = ()

    def beats(self, other: Attempt | None) -> bool:
        """Converged over not converged, then a strictly lower key (or score)."""
        if other is None:
            return True
        if self.converged != other.converged:
            return self.converged
        if self.key and other.key:
            return self.key < other.key
        return self.score < other.score


def run_attempts(
    attempt: Callable[[], Attempt[P]],
    restart: Callable[[], None],
    restarts: int,
    clock: Clock,
    best: Attempt[P] | None = None,
    budget: int | None = None,
    spent: Callable[[], int] | None = None,
) -> tuple[Attempt[P], Reason, int]:
    """Run ``attempt`` from the current start, then after each ``restart()`` (which draws a
    new start), until one converges, ``restarts`` restarts are spent, the clock runs out or
    the iterations reach ``budget``.

    Args:
        attempt: runs one attempt from the current start.
        restart: moves to a new random start.
        restarts: restarts allowed after the first attempt.
        clock: the solve's time budget.
        best: an outcome to beat (e.g. the start itself); ``None``: the first attempt is
            kept whatever its score.
        budget: iterations over all attempts after which no new attempt starts
            (:attr:`qpik.SolveOptions.iteration_budget`); ``None``: none.
        spent: the iterations run so far (read only with a ``budget``).

    Returns:
        ``(best attempt, reason, restarts used)``: ``reason`` is ``CONVERGED`` when the
        best attempt converged, else why the last attempt ended (``TIME_BUDGET`` when the
        clock ran out).
    """
    used = 0
    while True:
        outcome = attempt()
        if best is None or outcome.beats(best):
            best = outcome
        # (an attempt converged, whatever ended its loop: a level-0 finish after a
        # multi-level stack's iterations ran out can converge it, its reason still theirs)
        reason = Reason.CONVERGED if outcome.converged else outcome.reason
        timed_out = clock.out_of_time()
        exhausted = budget is not None and spent is not None and spent() >= budget
        if reason is Reason.CONVERGED or used >= restarts or timed_out or exhausted:
            if timed_out and reason is not Reason.CONVERGED:
                reason = Reason.TIME_BUDGET
            break
        used += 1
        restart()
    return best, (Reason.CONVERGED if best.converged else reason), used
