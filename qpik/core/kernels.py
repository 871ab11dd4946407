r"""Compiled kernels of the core: an exact dense QP solver and the prioritised cascade.

Everything here takes and returns plain arrays; the kernels are compiled C++
(``qpik/_cpp/core``, the extension submodule ``qpik._engine.core``), built ahead of time
when the package is installed; recorded answers pin them bit for bit
(tests/fixtures/core.npz, tests/core/test_engine_core.py). Arrays a kernel writes into
(``cholesky_into``'s ``L``, ``tighten``'s ``lb``/``ub``) must be float64 and C-contiguous;
inputs of another dtype or layout are converted, and a wrong shape raises ValueError.

QP (:func:`solve_qp`)
    ``min 1/2 x^T H x + c^T x  s.t.  lo <= C x <= hi`` with ``H`` symmetric positive
    definite, by the dual active-set method of Goldfarb and Idnani (1983), the method of
    quadprog and eiquadprog. It starts from the unconstrained minimiser and adds violated
    constraints one at a time; it needs no feasible starting point, detects infeasibility,
    and ends in a finite number of steps (an iteration cap guards against round-off
    cycling). The factorisation of the working set is updated when a constraint is added
    (one Householder reflection of ``J``'s columns; Givens rotations where an entry is outside
    ``[1e-140, 1e140]``) or dropped (Givens rotations), ``O(n^2)`` per change.

    The answer is then *polished*: the KKT system of the final active set (constraints
    with a positive multiplier, in a canonical order) is solved once more from scratch.
    So the returned ``x`` depends only on ``(H, c, C, lo, hi)`` and on which active set is
    optimal, never on the path that found it. A warm start (the previous step's active
    set, tried first) is accepted only when that set is the unique optimal one (strict
    complementarity), which a cold start would find too: it changes the speed, never the
    answer, bit for bit.

Cascade (:func:`solve_cascade`)
    Levels ``(A_k, b_k)`` with regularisation, solved in the null space of the levels above
    through an orthonormal basis ``Z`` that shrinks level by level (see
    :mod:`qpik.core.cascade` for the maths).

Signatures:

- ``solve_qp(H, c, C, lo, hi, warm, max_iter, tol, canonical) -> (x, status, iterations,
  active)``; ``solve_level(..., tol, lower, canonical)`` the same, robust to degenerate
  vertices; ``active_guess(x, C, lo, hi) -> int8 (m,)``.
- ``project_level(A, w, Z, rank_tol) -> (AZ, sigma, rank, Zn)``;
  ``level_damping(A, b, w, d, sigma, threshold, max_damping, error_scale) -> float``;
  ``damping_of(sigma, threshold, max_damping) -> float``;
  ``hypot_inline(x, y, out)``: ``out[i]`` = the dual method's inline ``hypot(x[i], y[i])``;
  ``resolve_sigma(sigma, store) -> list``: the per-level ``sigma`` with each level the cascade
  deferred (NaN; its rank proved full and no damping) given the value its ranking gives;
  ``reduced_qp(A, b, AZ, Z, d, reg, lb, ub, G, h) -> (H, c, C, lo, hi)``.
- ``tighten(lb, ub, dofs, lower, upper)`` (in place); ``merge_boxes(hard_lb, hard_ub,
  pos_lb, pos_ub) -> (lb, ub, i)``.
- ``solve_cascade(A, b, w, starts, reg, lb, ub, G, h, threshold, max_damping,
  error_scale, rank_tol, max_iter, tol, warm, canonical, workspace=None) -> (dq, status,
  sigma, lam2, iterations, active, residuals, certificate, primal)``: ``certificate`` (L, 4) the
  levels' certificates (primal, stationarity, dual, complementarity; see
  :mod:`qpik.core.cascade`), ``primal`` the final answer's largest scaled row violation.
- ``solve_levels(levels, lb, ub, G, h, settings) -> result | None``, ``settings`` the tuple
  ``(threshold, max_damping, error_scale, rank_tol, max_iter, tol, warm, x, active, kinds,
  workspace, lower_trust)`` (a solver makes it once per change of its settings; a value of
  another type raises ``TypeError``): :func:`solve_cascade` from the
  levels themselves (a list or tuple of objects with ``A``, ``b``, ``regularization``,
  ``weights``; arrays read through the buffer protocol, float64 C-contiguous) with the checks of
  ``HierarchyProblem.validate``; dq written into the caller's ``x`` (n,) and the active sets into
  ``active`` ((L, n + p) int8), and the answer returned as ``kinds[0]`` (the result class: ``x``,
  ``status`` ``kinds[2][code]``, ``active``, ``primal``, and ``_raw``, the bytes its per-level
  lists are built from on first access: ``residuals``, ``damping``, ``iterations``, ``sigma``,
  ``certificate`` of ``kinds[1]``, ``backend`` ``kinds[3]``; an optional ``kinds[4]``,
  ``cascade._fill_result``, sets the fields). None, nothing written, where an argument fails a
  check or needs a conversion, or a level ended in ``MAX_ITER`` or ``NUMERICAL``
  (``max_iter <= 0``: ``10 (n + p) + 50``; ``warm`` None: cold).
- ``CascadeWorkspace()``: the storage of one solver's cascade, passed as ``workspace`` to
  :func:`solve_cascade` / :func:`solve_levels` so that repeated solves of the same sizes
  allocate no matrices (one per solver, never shared between threads; no state but
  capacity: the answers are the same bits with or without it).
- ``certified_level(A, b, AZ, Z, d, rho, lb, ub, G, h, active, status, max_iter, lower) -> (ok,
  z, certificate, active)``: one level made exact from a QP answer's active set.
- ``certify_point(A, b, rho, Z, x, lb, ub, G, h) -> certificate (4,)``: a level's
  certificate at ``x`` with no working set (the levels not reached).
- ``drop_pinned(Z, d, lb, ub, G, h) -> Z``: ``Z`` without the directions of the rows the
  levels above pinned on their bounds at ``d`` (positively dependent tight rows: implied
  equalities, eliminated exactly; ``Z`` itself when none). The cascade calls it before each
  level.
- ``cholesky_into(G, n, shift, L) -> bool``.
"""

from __future__ import annotations

import numpy as np

# The compiled core (the extension is one module for every layer; this is its core part).
from qpik._engine import core as _engine

# Status codes shared with qpik.core.cascade.LevelStatus (keep in sync).
SOLVED = 0
MAX_ITER = 1
INFEASIBLE = 2
KEPT_PREVIOUS = 3
NUMERICAL = 4
NOT_REACHED = 5

#: A bound of this size or more is absent (the compiled kernels' kBig, qp.hpp).
ABSENT_BOUND = 1e20
_DEGENERATE = 1e-9  # multipliers / slacks this small make an active set degenerate
_ROUNDOFF = 1e-11  # violations this small at a degenerate vertex are round-off
_DEPENDENT = 1e-10  # a normal this close to the working set's span depends on it
_VERIFY = 1e-8  # a final violation above this (relative) is a numerical failure

cholesky_into = _engine.cholesky_into
solve_qp = _engine.solve_qp
solve_level = _engine.solve_level
active_guess = _engine.active_guess
project_level = _engine.project_level
level_damping = _engine.level_damping
damping_of = _engine.damping_of
hypot_inline = _engine.hypot_inline
resolve_sigma = _engine.resolve_sigma


def sigma_from_bytes(raw: bytes, L: int) -> list[float]:
    """The per-level sigma from ``solve_levels``' deferred form (the bytes of the (L,) sigma,
    NaN where deferred, then the cascade's store of those levels' rows), resolved."""
    values = np.frombuffer(raw)
    return resolve_sigma(values[:L], values[L:])


reduced_qp = _engine.reduced_qp
tighten = _engine.tighten
merge_boxes = _engine.merge_boxes
solve_cascade = _engine.solve_cascade
CascadeWorkspace = _engine.CascadeWorkspace
certified_level = _engine.certified_level
certify_point = _engine.certify_point
solve_levels = _engine.solve_levels
drop_pinned = _engine.drop_pinned

assert (SOLVED, MAX_ITER, INFEASIBLE, KEPT_PREVIOUS, NUMERICAL, NOT_REACHED) == (
    _engine.SOLVED, _engine.MAX_ITER, _engine.INFEASIBLE, _engine.KEPT_PREVIOUS,
    _engine.NUMERICAL, _engine.NOT_REACHED,
)  # fmt: skip

__all__ = [
    "ABSENT_BOUND", "SOLVED", "MAX_ITER", "INFEASIBLE", "KEPT_PREVIOUS", "NUMERICAL", "NOT_REACHED",
    "CascadeWorkspace", "active_guess", "certified_level", "certify_point", "cholesky_into",
    "damping_of", "drop_pinned", "hypot_inline",
    "level_damping", "merge_boxes", "project_level", "reduced_qp", "resolve_sigma",
    "sigma_from_bytes", "solve_cascade", "solve_level",
    "solve_levels", "solve_qp", "tighten",
]  # fmt: skip


def trust_box(
    d: np.ndarray, s: float, lb: np.ndarray, ub: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The box of the levels below a damped level (:attr:`qpik.DampingLaw.lower_trust`), as
    the kernel's ``trust_box`` makes it: each dof with both bounds finite within
    ``s (ub - lb) / 2`` of ``d`` put in its box, and within its box; the others' box as it
    is."""
    finite = (np.abs(lb) < ABSENT_BOUND) & (np.abs(ub) < ABSENT_BOUND)
    half = s * (0.5 * (ub - lb))
    c = np.minimum(np.maximum(d, lb), ub)
    tlb = np.maximum(lb, c - half)
    tub = np.minimum(ub, c + half)
    return np.where(finite, tlb, lb), np.where(finite, tub, ub)
