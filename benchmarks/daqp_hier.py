"""DAQP's hierarchical mode on a hierarchy of least-squares levels under a box and general
rows, as benchmarks/hqp.py and step_time.py's Talos peer section call it."""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence

import numpy as np


def daqp_hierarchical(
    lb: np.ndarray,
    ub: np.ndarray,
    G: np.ndarray,
    h: np.ndarray,
    levels: Sequence[tuple[np.ndarray, np.ndarray]],
) -> Callable[[], tuple]:
    """``solve() -> daqp.solve's (x, fval, exitflag, info)`` for the levels ``(A_k, b_k)``
    (``min |A_k x - b_k|`` in priority order) under ``lb <= x <= ub`` and ``G x <= h``:
    ``daqp.solve(None, None, A, bu, bl, sense, break_points=...)`` (DAQP 0.11) with the
    limits as its first level (the box as simple bounds, then the general rows) and each
    level's rows as soft equalities. DAQP softens every level, the first included, so the
    limits keep a level of their own even with no general row: in the first task level's
    range, a target beyond the box would move the box. DAQP minimises each level's
    row-normalised slacks, a strict hierarchy's answer but not the objective
    ``|A_k x - b_k|^2``'s; infinite bounds become its 1e30. The arrays are made here, so
    that a timed ``solve()`` is DAQP's call alone."""
    import daqp

    m = G.shape[0]
    A = np.ascontiguousarray(np.vstack([G] + [A_k for A_k, _ in levels]), dtype=float)
    targets = [b_k for _, b_k in levels]
    bu = np.clip(np.concatenate([ub, h, *targets]).astype(float), -1e30, 1e30)
    bl = np.clip(np.concatenate([lb, np.full(m, -1e30), *targets]).astype(float), -1e30, 1e30)
    sense = np.zeros(bu.shape[0], dtype=np.int32)
    ends = [lb.shape[0] + m]
    for A_k, _ in levels:
        ends.append(ends[-1] + A_k.shape[0])
    breaks = np.array(ends, dtype=np.int32)
    return functools.partial(daqp.solve, None, None, A, bu, bl, sense, break_points=breaks)
