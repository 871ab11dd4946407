r"""Strict priorities as a cascade of QPs in null-space coordinates (no robot here).

A problem has levels ``(A_k, b_k, reg_k)`` over one variable ``x`` (in qpik, the joint
displacement ``dq``, ``n = nv``), box bounds ``lb <= x <= ub`` and general rows
``G x <= h``, which hold at every level. Level ``k`` solves

.. math::

    \min_z \tfrac12 \|A_k (d + Z z) - b_k\|^2 + \tfrac12 (\rho_k + \lambda_k^2)\|d + Z z\|^2
    \quad\text{s.t.}\quad lb \le d + Z z \le ub,\; G (d + Z z) \le h

where ``d`` is the solution of the levels above and ``Z`` an orthonormal basis of the null
space of their rows (``Z = I`` at level 0). After the level, ``d <- d + Z z`` and ``Z``
shrinks to the null space of ``A_k Z`` (right singular vectors). A lower level moves only
in that null space, so it cannot change any ``A_j x`` of a level above: strict priority
holds exactly (up to round-off), whatever the QP solver's tolerance.

**Pinned rows.** Before each level, the rows on their bound at ``d`` (box and general;
both sides of a zero-width box row) whose normals in null-space coordinates are positively
dependent (``sum_j u_j n_j = 0``, ``u_j > 0``, to ``1e-12 (1 + sum u)``, that sum counted
up to ``1e6``) are pinned: no feasible move
takes any of them off its bound (the levels above put ``d`` on a vertex of the feasible
set within ``Z``). They are equalities from there on and leave ``Z`` exactly
(:func:`qpik.core.kernels.drop_pinned`; a pinned box row's dof keeps its value), so that
round-off in their normals cannot close the feasible set of a lower level that still has
free directions.

Each level's QP is solved exactly by the compiled dual active-set method of
:func:`qpik.core.kernels.solve_qp` (``solver="auto"``), which handles box bounds and general
rows alike; other backends (``"osqp"`` with a persistent workspace per level and reduced
size, or qpsolvers' ``"daqp"``, ``"quadprog"``, ``"proxqp"``, ``"clarabel"``) can be forced:
a backend proposes each level's active set, and the exact cascade, started from them,
answers (the same answer as ``"auto"``, bit for bit where the optimal sets are unique).

**Damping** (singularity robustness) is decided from the singular values of the level's
*unweighted* projected rows ``diag(1/w) A_k Z`` (``w`` the rows' costs), so it does not fire
because a task has a small cost. Singular values below ``rank_tol * max(1, sigma_max)`` are
structural zeros (a LookAt task's third row, a level that repeats one above) and are not
singularities. With ``sigma`` the smallest remaining one::

    lambda^2 = w_max^2 max_damping^2 (1 - (sigma / threshold)^2)   if sigma < threshold
             = 0                                                   otherwise

(Nakamura & Hanafusa 1986; Chiaverini 1997), ``w_max`` the level's largest row cost. Far
from singularities the step is the exact prioritised least-squares step.

**Rank** is decided by the singular values themselves (one-sided Jacobi on the R factor of a
pivoted QR, whose rotated Q columns are the left singular vectors): a direction is a rank
direction when its singular value exceeds ``rank_tol * max(1, sigma_max)``; ``Z`` shrinks by
exactly those directions' span. Directions below the cutoff are not held: a lower level may
change ``A_k x`` along them by at most ``rank_tol * max(1, sigma_max) |dx|``.

**Exactness.** The dual active set (Goldfarb-Idnani) needs a positive definite Hessian, so
it runs with a Tikhonov floor ``1e-14 (1 + max diag H)`` where ``rho_k + lambda_k^2`` is
smaller; it only *finds the active set*. The answer is then re-solved on that canonical
active set (rows with a positive multiplier, by row) as an equality-constrained least-squares
problem in ``[A_k Z; sqrt(rho) I]`` without any added regularisation (pivoted QR, least-norm
step; pivots below ``1e-14 |R_00|`` or 1e-13 of the rows' scale are zero), and **certified**
at the returned point ``x = d + Z z``:

* ``primal``: every box row ``(lb - x) / (1 + |lb|)``, ``(x - ub) / (1 + |ub|)`` and general
  row ``(g x - h) / (|g| + |h|)``, the largest positive one;
* ``stationarity``: ``s = Z^T (A_k^T (A_k x - b_k) + rho x - sum_j lambda_j c_j)`` over the
  active rows ``c_j`` with their signed multipliers, each component divided by the larger
  of ``|Z|^T (|A_k|^T (|A_k| |x| + |b_k|) + rho |x|)`` (the objective's terms) and
  ``|Z|^T (|A_k|^T |A_k| dx + rho dx)``, ``dx_j = max_c |Z_jc| max_c (|Z|^T |x|)_c`` (the
  round-off a solve in ``Z`` leaves in every entry of ``x`` it moves, relative to the
  largest null-space coordinate, times ``H``: a dof the level leaves near 0 while others
  move carries it, though its own terms are tiny), at least ``1e-6`` times the largest
  component's, or the largest full-space term's: round-off from the other components and
  from ``Z``; or by the size of the multipliers' terms ``|Z|^T sum_j |lambda_j| |c_j|``
  where that is larger, counted up to that largest size only: a component the objective
  leaves out, a dof that only the active rows hold, carries the round-off of their
  cancellation, while nearly dependent active rows whose huge multipliers cancel to their
  own round-off still prove nothing), the largest; where the candidate's multipliers leave
  it failing, the same with no multipliers (the objective's own gradient: a level whose
  gradient vanishes at the point to round-off, such as a slack level at ``s = 0`` with rows
  active at a degenerate vertex, is a KKT point with zero multipliers; dual and
  complementarity are then 0);
* ``dual``: a multiplier of the wrong sign, ``max(0, -u_j) |Z^T c_j| / S`` with ``S`` the
  largest stationarity size;
* ``complementarity``: ``|u_j| |Z^T c_j| / S`` times row ``j``'s scaled distance to its bound.

A level is ``solved`` only when all four are ``<= CERTIFICATE_TOLERANCE`` (1e-9). Otherwise
it falls back to an independent primal active-set method (equality-constrained
least-squares steps from ``z = 0``, the level above's answer; again where that fails, rows
within 1e-6 of the working set's span never blocking) and certifies that; only when none
holds does the level report another status (level 0: ``numerical_failure``; lower levels:
``kept_previous``), with the certificate of its best candidate saying which condition
failed. After a level, ``d <- d + Z z`` (projected, never clipped, so the levels above
keep ``A_j x`` to round-off); the answer's round-off outside the box (at most 1e-12
(1 + |bound|)) is put back on the bound, its rows rechecked (``HierarchyResult.primal``).

**Infeasibility** (level 0) is checked before it is reported: the dual method on the identity
Hessian seeks a point meeting every row (a nearly singular ``H``'s floor can mislead it); where
one is found, the level is solved from it, as above.

**Warm starts** only change which active set the dual method tries first; every answer ends
in the same canonical re-solve, so a warm start gives bitwise the cold start's answer when the
optimal active set is unique (and the same point to round-off at degenerate vertices, where
several active sets are optimal). :attr:`HierarchySolver.active_sets` holds the last solve's
active sets, :meth:`HierarchySolver.warm_start_from` sets them (a caller that solved the same
cascade by other means), and :meth:`HierarchySolver.reset` forgets them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InvalidInput, QpikError
from ..options import DEFAULT_DAMPING, SOLVERS, DampingLaw
from . import backends, checks
from . import kernels as K
from .certificate import (
    CERTIFICATE_TOLERANCE,
    STATUS_OF_CODE,
    LevelCertificate,
    LevelStatus,
    certificates,
    primal_violation,
)
from .settings import SolverSettings

__all__ = [
    "CERTIFICATE_TOLERANCE",
    "DEFAULT_DAMPING",
    "LevelCertificate",
    "DampingLaw",
    "HierarchyProblem",
    "HierarchyResult",
    "HierarchySolver",
    "Level",
    "LevelStatus",
    "SOLVERS",
    "STATUS_OF_CODE",
]


@dataclass
class Level:
    """One priority level: minimise ``1/2 |A x - b|^2 + 1/2 regularization |x|^2``.

    Attributes:
        A: (m, n) weighted rows (``diag(cost) J`` for tasks).
        b: (m,) weighted targets (``-gain diag(cost) e``).
        regularization: constant Tikhonov term (damping plus the tasks' LM terms) >= 0.
        weights: (m,) the rows' costs, used to judge rank and singularity in the units of
            the unweighted rows; ``None`` means 1 for every non-zero row.
        name: a label for messages (e.g. the task names).
    """

    A: np.ndarray
    b: np.ndarray
    regularization: float = 0.0
    weights: np.ndarray | None = None
    name: str = ""


@dataclass
class HierarchyProblem:
    """Levels (highest priority first) under limits that hold at every level.

    Attributes:
        levels: the levels.
        lb, ub: (n,) box bounds on ``x`` (``-inf``/``inf``, or a size of 1e20 or more, for
            none: OSQP's and qpOASES' convention).
        G, h: (p, n), (p,) general rows ``G x <= h`` (absent where ``h >= 1e20``).
        row_names: optional names of the general rows, for reports.
    """

    levels: list[Level]
    lb: np.ndarray
    ub: np.ndarray
    G: np.ndarray
    h: np.ndarray
    row_names: list[str] = field(default_factory=list)

    @property
    def n(self) -> int:
        """Size of the variable."""
        return len(self.lb)

    def stacked(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(A, b, w, starts, reg)``: the levels' rows stacked as the kernel takes them."""
        n = self.n
        As = [checks.level_rows(level.A, n) for level in self.levels]
        sizes = [a.shape[0] for a in As]
        starts = np.zeros(len(As) + 1, dtype=np.int64)
        np.cumsum(sizes, out=starts[1:])
        A = np.concatenate(As) if As else np.zeros((0, n))
        bs = [np.asarray(level.b, dtype=float).reshape(-1) for level in self.levels]
        b = np.concatenate(bs) if bs else np.zeros(0)
        weights = []
        for level, a in zip(self.levels, As):
            if level.weights is None:
                weights.append((np.abs(a).sum(axis=1) > 0).astype(float))
            else:
                weights.append(np.asarray(level.weights, dtype=float).reshape(-1))
        w = np.concatenate(weights) if weights else np.zeros(0)
        reg = np.array([float(level.regularization) for level in self.levels])
        return A, b, w, starts, reg

    def validate(self) -> None:
        """Types, shapes and finiteness; raises :class:`qpik.InvalidInput` naming the field."""
        lb = checks.check_array("lb", self.lb, "(n,)", ndim=1)
        ub = checks.check_array("ub", self.ub, "(n,)", ndim=1)
        G = checks.check_array("G", self.G, "(p, n)", ndim=2)
        h = checks.check_array("h", self.h, "(p,)", ndim=1)
        n = lb.shape[0]
        if ub.shape != (n,):
            raise InvalidInput(f"ub must have shape ({n},) as lb, got {ub.shape}")
        if G.shape[1] != n or h.shape != (G.shape[0],):
            raise InvalidInput(f"G must be (p, {n}) and h (p,), got {G.shape}, {h.shape}")
        checks.check_bounds_met(lb, ub, G, h)
        if not isinstance(self.levels, (list, tuple)):
            raise InvalidInput(f"levels must be a list of Level, got {type(self.levels).__name__}")
        for k, level in enumerate(self.levels):
            if not isinstance(level, Level):
                raise InvalidInput(f"level {k} must be a Level, got {type(level).__name__}")
            checks.check_level(k, level, n)


@dataclass
class HierarchyResult:
    """What :meth:`HierarchySolver.solve` computed.

    Attributes:
        x: the solution (n,) (``dq`` in qpik).
        status: per level, a :class:`LevelStatus`.
        residuals: per level, ``|A_k x - b_k|`` at the final ``x``, over all its rows.
        sigma: per level, the smallest singular value that drove its damping (inf when
            none).
        damping: per level, ``lambda^2`` applied.
        iterations: per level, active-set changes (or the backend's iterations: a
            forced backend's, whose workspace is kept warm between solves, so that its
            count is a speed figure that depends on what was solved before, unlike every
            other field; or, where the exact cascade did not settle, those of OSQP from a
            fresh workspace; 0 for daqp and clarabel, whose counts qpsolvers does not pass).
        active: per level, the active set of its QP: (n + p,) int8, +1 at a lower bound,
            -1 at an upper bound (box rows first, then the general rows).
        backend: per level, which backend produced the answer.
        certificate: per level, its :class:`LevelCertificate` at the point it returned
            (``solved`` only when it holds).
        primal: the final ``x``'s largest scaled row violation (box and general rows).
    """

    x: np.ndarray
    status: list[LevelStatus]
    residuals: list[float]
    sigma: list[float]
    damping: list[float]
    iterations: list[int]
    active: np.ndarray
    backend: list[str]
    certificate: list[LevelCertificate] = field(default_factory=list)
    primal: float = 0.0

    @property
    def ok(self) -> bool:
        """True when every level was solved."""
        return all(s is LevelStatus.SOLVED for s in self.status)

    def __getattr__(self, name: str):
        """The lists of :data:`_RAW_FIELDS`, built on first access from ``_raw`` (the bytes
        :func:`K.solve_levels` left: the same values; a deferred ``sigma`` resolved)."""
        d = self.__dict__
        raw = d.get("_raw") if name in _RAW_FIELDS else None
        if raw is None:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        L, k = len(d["status"]), _RAW_FIELDS[name]
        values = np.frombuffer(raw)
        if name == "certificate":  # (L, 4)
            value: list = certificates(values[k * L : (k + 4) * L])
        elif name == "sigma" and values.shape[0] > 8 * L:  # then levels' deferred sigma
            value = K.sigma_from_bytes(raw[k * L * 8 :], L)  # (its bytes from sigma's on)
        elif name == "backend":
            value = [_KINDS[3]] * L
        else:  # residuals, damping, iterations (whole numbers), sigma
            value = values[k * L : (k + 1) * L].tolist()
            value = [int(v) for v in value] if name == "iterations" else value
        d[name] = value
        return value


#: The lists built from a one-call result's ``_raw`` (their blocks; backend: a label per level).
_RAW_FIELDS = dict(residuals=0, damping=1, iterations=2, certificate=3, sigma=7, backend=-1)


def _residuals(A, b, starts, x) -> list[float]:
    r = A @ x - b
    return [float(np.sqrt(r[s0:s1] @ r[s0:s1])) for s0, s1 in zip(starts[:-1], starts[1:])]


def _fill_result(r, x, status, active, raw, primal):
    """The fields of ``r`` (``object.__new__(HierarchyResult)``) set as :func:`K.solve_levels`
    leaves them, in order (specialised stores: cheaper than the C setattr); returns ``r``."""
    r.x = x
    r.status = status
    r.active = active
    r._raw = raw
    r.primal = primal
    return r


#: What :func:`K.solve_levels` builds answers of (result, certificate, statuses, backend, setter).
_KINDS = (
    HierarchyResult,
    LevelCertificate,
    tuple(STATUS_OF_CODE[code] for code in range(6)),
    "auto",
    _fill_result,
)


class HierarchySolver(SolverSettings):
    """Solves :class:`HierarchyProblem` s. By default every level starts cold, so the same
    problem gives bitwise the same result whatever was solved before; backend workspaces
    (OSQP) are kept, and the active sets they find start the exact cascade, which answers.

    Args:
        solver: ``"auto"`` (exact compiled active set, OSQP as fallback if it does not
            settle) or a backend forced on every level with binding limits (``"osqp"``,
            ``"daqp"``, ``"quadprog"``, ``"proxqp"``, ``"clarabel"``).
        damping_law: adaptive damping, or ``None``.
        rank_tolerance: relative singular value below which a direction is not a rank.
        max_iter: iteration cap of the active-set solver per level (0: ``10 (n + p) + 50``).
        tolerance: feasibility tolerance of the limits (relative, per unit row norm).
        warm_start: try the previous call's active sets first (opt-in). Every answer, warm
            or cold, ends in the same canonical exact re-solve (module doc), so warm and
            cold starts agree bit for bit when the optimal active set is unique, and to
            round-off at degenerate vertices. Speed only, and today not a gain: the
            warm set's KKT check costs more than the dual iterations it saves.
        backend_options: passed to the forced backend (OSQP settings or qpsolvers kwargs).

    Each of these is also an attribute, checked when it is assigned as when it is given
    (:class:`qpik.core.settings.SolverSettings`: :class:`qpik.InvalidOption` naming it);
    the next solve uses the new value.
    """

    def __init__(
        self,
        solver: str = "auto",
        *,
        damping_law: DampingLaw | None = DEFAULT_DAMPING,
        rank_tolerance: float = 1e-9,
        max_iter: int = 0,
        tolerance: float = 1e-12,
        warm_start: bool = False,
        backend_options: dict | None = None,
    ):
        # (each setting checked by its property: qpik.core.settings)
        self.backend_options = backend_options
        self.solver = solver
        self.damping_law = damping_law
        self.rank_tolerance = rank_tolerance
        self.max_iter = max_iter
        self.tolerance = tolerance
        self.warm_start = warm_start
        self._warm: np.ndarray | None = None
        #: ``(stack, row)`` when the last solve's active sets are ``stack[row]``, not yet
        #: read (:meth:`warm_start_from_row`); it overrides ``_warm`` (then stale, not read).
        self._warm_row: tuple | None = None
        self._workspaces: dict = {}
        # The compiled cascade's storage, kept between solves (no state but capacity).
        self._cascade_workspace = K.CascadeWorkspace()

    def reset(self) -> None:
        """Forget the warm start and backend workspaces."""
        self._warm = self._warm_row = None
        self._workspaces.clear()

    @property
    def active_sets(self) -> np.ndarray | None:
        """The active sets of the last solve, ``(L, n + p)`` int8 (+1 at a lower bound, -1
        at an upper bound; box rows first, then the general rows); None before the first
        solve and after :meth:`reset`."""
        return self._last_active()

    def _last_active(self) -> np.ndarray | None:
        """The last solve's active sets (``_warm``, read from ``_warm_row`` first if set)."""
        pending = self._warm_row
        if pending is not None:
            stack, row = pending
            self._warm, self._warm_row = stack[row], None
        return self._warm

    def warm_sets(self, levels: int, rows: int) -> np.ndarray | None:
        """The active sets a solve of ``levels`` levels over ``rows = n + p`` rows starts
        from: :attr:`active_sets` when :attr:`warm_start` is on and their shape is
        ``(levels, rows)``, else None (a cold start)."""
        if not self.warm_start:
            return None
        warm = self._last_active()
        if warm is None or warm.shape != (levels, rows):
            return None
        return warm

    def warm_start_from(self, active: np.ndarray) -> None:
        """Take ``active`` (``(L, n + p)`` int8, as :attr:`active_sets`) as the last
        solve's active sets: the next solve of that shape starts from them when
        :attr:`warm_start` is on (for a caller that solved the same cascade in one
        compiled call, :mod:`qpik.diffik.compiled`)."""
        self._warm, self._warm_row = active, None

    def warm_start_from_row(self, stack: np.ndarray, row: int) -> None:
        """:meth:`warm_start_from` ``stack[row]``, the row read only when the active sets
        are asked for (``stack``'s row ``row`` must never be written again)."""
        self._warm_row = (stack, row)  # (it overrides _warm: _last_active reads it first)

    @property
    def workspace_setups(self) -> int:
        """How many backend workspaces were built so far (OSQP: at most one per level and
        reduced size; 0 with the default exact solver)."""
        return sum(getattr(ws, "setups", 0) for ws in self._workspaces.values())

    def _warm_for(self, levels: int, rows: int) -> np.ndarray:
        warm = self.warm_sets(levels, rows)
        return np.zeros((levels, rows), dtype=np.int8) if warm is None else warm

    def solve(self, problem: HierarchyProblem, *, validate: bool = True) -> HierarchyResult:
        """Solve the cascade. ``validate=False`` skips the shape/finiteness checks."""
        args = self._call_args
        if args is None:  # (settings changed since the last solve: SolverSettings._changed)
            args = self._call_args = self._solve_levels_args()
        if args:  # the solver "auto"
            # One compiled call: the checks, the stacking, the cascade and the result object
            # with its arrays (None where an argument fails a check or needs a conversion -
            # not a list or tuple of levels, not float64 C-contiguous arrays - or a level did
            # not settle: then the path below, which names the argument or falls back).
            try:
                if self._warm_start:  # (args[6]: the warm active sets, None in args)
                    args = (*args[:6], self._last_active(), *args[7:])
                result = K.solve_levels(
                    problem.levels, problem.lb, problem.ub, problem.G, problem.h, args
                )
            except TypeError:  # an argument of a type it does not take (None): the checks name it
                result = None
            if result is not None:
                self._warm, self._warm_row = result.active, None  # the next warm start
                return result
        if validate:
            problem.validate()
        A, b, w, starts, reg = problem.stacked()
        return self.solve_arrays(
            A, b, w, starts, reg,
            np.ascontiguousarray(problem.lb, dtype=float),
            np.ascontiguousarray(problem.ub, dtype=float),
            np.ascontiguousarray(problem.G, dtype=float),
            np.ascontiguousarray(problem.h, dtype=float),
        )  # fmt: skip

    def _solve_levels_args(self) -> tuple:
        """The arguments of the compiled ``solve_levels`` after the problem's five, from the
        settings (read once per change of them, not at every solve: :meth:`solve` keeps them
        until :meth:`SolverSettings._changed`); ``()`` for a forced backend. The warm
        active sets (index 6) are None here: a warm solve puts its own in."""
        if self._solver != "auto":
            return ()
        threshold, max_damping, error_scale = self.damping_settings
        return (
            threshold, max_damping, error_scale, self._rank_tolerance, self._max_iter,
            self._tolerance, None, None, None, _KINDS, self._cascade_workspace, self.lower_trust,
        )  # fmt: skip

    def solve_arrays(
        self,
        A: np.ndarray,
        b: np.ndarray,
        w: np.ndarray,
        starts: np.ndarray,
        reg: np.ndarray,
        lb: np.ndarray,
        ub: np.ndarray,
        G: np.ndarray,
        h: np.ndarray,
    ) -> HierarchyResult:
        """:meth:`solve` on the stacked form (:meth:`HierarchyProblem.stacked`): float64
        C-contiguous arrays, no checks. The IK layer's hot path."""
        n, p = lb.shape[0], G.shape[0]
        L = starts.shape[0] - 1
        if L == 0:
            x = np.clip(np.zeros(n), lb, ub)
            return HierarchyResult(x, [], [], [], [], [], np.zeros((0, n + p), np.int8), [])
        warm, warm_start, proposed = self._warm_for(L, n + p), self.warm_start, None
        if self.solver != "auto":
            # The forced backend proposes each level's active set, level by level; the exact
            # cascade, started from them, answers: its canonical re-solve, so the answer is
            # "auto"'s whichever backend proposed (bit for bit where the optimal active sets
            # are unique), and certified the same way.
            proposed = self._solve_levels(A, b, w, starts, reg, lb, ub, G, h, warm, fallback=False)
            warm, warm_start = proposed.active, True
        threshold, max_damping, error_scale = self.damping_settings
        x, status, sigma, lam2, its, active, residuals, cert, primal = K.solve_cascade(
            A, b, w, starts, reg, lb, ub, G, h, threshold, max_damping, error_scale,
            self.rank_tolerance, self.max_iter or 10 * (n + p) + 50, self.tolerance, warm,
            warm_start, self._cascade_workspace, self.lower_trust,
        )  # fmt: skip
        result = self._result((x, status, sigma, lam2, its, active, residuals, cert, primal), L)
        if result is None:
            # Rare: round-off cycling. The backend's own answer, else the cascade level by
            # level with OSQP as the fallback where the active set did not settle.
            if proposed is not None:
                return proposed
            return self._solve_levels(A, b, w, starts, reg, lb, ub, G, h, warm, fallback=True)
        if proposed is not None:
            result.iterations, result.backend = proposed.iterations, proposed.backend
        return result

    def _result(self, out, L: int) -> HierarchyResult | None:
        """The kernels' tuple as a result; None when a level did not settle (MAX_ITER or
        NUMERICAL: the caller redoes the cascade level by level)."""
        x, status, sigma, lam2, its, active, residuals, cert, primal = out
        codes = status.tolist()
        if K.MAX_ITER in codes or K.NUMERICAL in codes:
            return None
        self._warm, self._warm_row = active, None  # the next warm start (warm_start on)
        return HierarchyResult(
            x, [STATUS_OF_CODE[s] for s in codes], residuals.tolist(), sigma.tolist(),
            lam2.tolist(), its.tolist(), active, ["auto"] * L, certificates(cert), float(primal),
        )  # fmt: skip

    # ------------------------------------------------------------------ level by level
    def _box_below(self, k, d, lb, ub, lam2s, status, sigma, threshold):
        """Level ``k``'s box: below a damped level ``k - 1``, with
        :attr:`qpik.DampingLaw.lower_trust`, shrunk around ``d`` (the kernel's trust_box)."""
        trust = self.lower_trust
        if trust and k and lam2s[k - 1] > 0.0 and status[k - 1] == LevelStatus.SOLVED:
            return K.trust_box(d, trust * min(1.0, sigma[k - 1] / threshold), lb, ub)
        return lb, ub

    def _solve_levels(self, A, b, w, starts, reg, lb, ub, G, h, warm, *, fallback: bool):
        """The cascade in Python, one level at a time, with a backend per level: the
        forced backend, or (``fallback``) the exact kernel then OSQP where it fails."""
        n, p = lb.shape[0], G.shape[0]
        L = starts.shape[0] - 1
        threshold, max_damping, error_scale = self.damping_settings
        max_iter = self.max_iter or 10 * (n + p) + 50
        status = [LevelStatus.NOT_REACHED] * L
        sigma = [math.inf] * L
        lam2s = [0.0] * L
        its = [0] * L
        backend = [""] * L
        active = np.zeros((L, n + p), dtype=np.int8)
        certs = np.full((L, 4), np.nan)
        d = np.clip(np.zeros(n), lb, ub)
        Z = np.eye(n)
        for k in range(L):
            s0, s1 = int(starts[k]), int(starts[k + 1])
            lb, ub = self._box_below(k, d, lb, ub, lam2s, status, sigma, threshold)
            if s1 > s0:  # rows pinned on their bounds by the levels above: equalities
                Z = K.drop_pinned(Z, d, lb, ub, G, h)
            if s1 == s0 or Z.shape[1] == 0:
                status[k] = LevelStatus.SOLVED
                certs[k] = (primal_violation(d, lb, ub, G, h), 0.0, 0.0, 0.0)
                continue
            Ak, bk, wk = A[s0:s1], b[s0:s1], w[s0:s1]
            AZ, sig, _, Zn = K.project_level(Ak, wk, Z, self.rank_tolerance)
            lam = K.level_damping(Ak, bk, wk, d, sig, threshold, max_damping, error_scale)
            sigma[k], lam2s[k] = float(sig), float(lam)
            H, c, C, lo, hi = K.reduced_qp(Ak, bk, AZ, Z, d, float(reg[k]) + lam, lb, ub, G, h)
            z, st, it, act, used = self._solve_qp(k, H, c, C, lo, hi, warm[k], max_iter, fallback)
            its[k], backend[k] = it, used
            if act is not None:
                active[k] = act
            if st == K.INFEASIBLE and k == 0:
                # No optimum to certify: the measure that fails, primal feasibility, at the
                # point returned (the other measures do not apply and are 0).
                certs[k] = (primal_violation(d, lb, ub, G, h), 0.0, 0.0, 0.0)
            else:
                # The backend's active set, with the rows its answer leaves outside their
                # bounds, made exact (no added floor) and certified.
                guess = backends.working_set_with_violated(z, act, C, lo, hi, n + p)
                ok, z, cert, act2 = K.certified_level(
                    Ak, bk, AZ, Z, d, float(reg[k]) + lam, lb, ub, G, h,
                    np.ascontiguousarray(guess, np.int8), st, max_iter, k > 0,
                )  # fmt: skip
                certs[k] = cert
                if ok:
                    st, active[k] = K.SOLVED, act2
                elif st == K.SOLVED:
                    st = K.NUMERICAL
            if st == K.SOLVED:
                d = d + Z @ z  # projected, never clipped (the levels above stay put)
                status[k] = LevelStatus.SOLVED
            else:
                status[k] = (
                    STATUS_OF_CODE[st] if k == 0 or st == K.MAX_ITER else LevelStatus.KEPT_PREVIOUS
                )
                if k == 0:
                    break
                continue
            Z = Zn
        self._warm, self._warm_row = active, None  # the next warm start (warm_start on)
        # Round-off outside the box (<= 1e-12 (1 + |bound|)) put back on it, as the kernel does.
        snap = 1e-12
        low = (d < lb) & (lb - d <= snap * (1 + np.abs(lb)))
        high = (d > ub) & (d - ub <= snap * (1 + np.abs(ub)))
        d = np.where(low, lb, np.where(high, ub, d))
        for j in range(L):  # levels not reached: their certificate at the returned point
            if status[j] is LevelStatus.NOT_REACHED:
                s0, s1 = int(starts[j]), int(starts[j + 1])
                certs[j] = K.certify_point(A[s0:s1], b[s0:s1], float(reg[j]), Z, d, lb, ub, G, h)
        return HierarchyResult(
            d, status, _residuals(A, b, starts, d), sigma, lam2s, its, active, backend,
            certificates(certs), primal_violation(d, lb, ub, G, h),
        )  # fmt: skip

    def _solve_qp(self, k, H, c, C, lo, hi, warm, max_iter, fallback):
        """One level's reduced QP: ``(z, status code, iterations, active, backend)``.

        Forced backend: the unconstrained minimiser when no limit binds, else the backend,
        polished exactly on the active set it identifies; if the backend fails (iteration
        cap, error), the exact kernel answers instead. Fallback mode (the kernel did not
        settle): the kernel, then OSQP. Either way the answer is exact and does not depend
        on a backend's warm start; a result is labelled solved only when one solver
        converged."""
        exact = K.solve_qp
        if fallback:
            z, st, it, act = K.solve_level(
                H, c, C, lo, hi, warm, max_iter, self.tolerance, k > 0, self.warm_start
            )
            if st in (K.SOLVED, K.INFEASIBLE):
                return z, st, it, act, "auto"
            name = "osqp"
        else:
            z, st, it, act = exact(H, c, C, lo, hi, warm, 0, self.tolerance, True)
            if st == K.SOLVED and it == 0 and not act.any():
                return z, st, 0, act, self.solver
            name = self.solver
        solution = self._backend_solve(k, name, H, c, C, lo, hi, keep=not fallback)
        if solution is not None and solution.found:
            z, st, act = backends.made_exact(
                solution.x, (H, c, C, lo, hi), max_iter, self.tolerance, k > 0
            )
            return z, st, solution.iterations, act, name
        if fallback:
            code = K.MAX_ITER if solution is None or "max_iter" in solution.status else (
                K.INFEASIBLE if "infeasible" in solution.status else K.NUMERICAL
            )  # fmt: skip
            return None, code, 0 if solution is None else solution.iterations, None, name
        zeros = np.zeros(C.shape[0], dtype=np.int8)
        z, st, it, act = K.solve_level(
            H, c, C, lo, hi, zeros, max_iter, self.tolerance, k > 0, True
        )
        return z, st, it, act, f"{name} failed: auto"

    def _backend_solve(self, k, name, H, c, C, lo, hi, keep: bool = True):
        """The backend's solution, or None if it raised (its workspace is then dropped, so
        the next call starts a fresh one). ``keep=False``: a fresh workspace, not kept (the
        fallback's OSQP: its iterations then depend on this problem alone)."""
        key = (k, name, H.shape[0], C.shape[0])
        workspace = self._workspaces.get(key) if keep else None
        try:
            if workspace is None:
                workspace = backends.make_workspace(
                    name, H.shape[0], C.shape[0], self.backend_options
                )
            solution = workspace.solve(H, c, C, lo, hi)
        except QpikError:
            raise
        except Exception:  # a backend failure must not poison the solver
            self._workspaces.pop(key, None)
            return None
        if keep:
            self._workspaces[key] = workspace
        return solution


def solve_hierarchy(
    levels: Sequence[Level],
    lb: np.ndarray,
    ub: np.ndarray,
    G: np.ndarray | None = None,
    h: np.ndarray | None = None,
    **options: Any,
) -> HierarchyResult:
    """One-shot :class:`HierarchySolver` (``options`` are its arguments)."""
    try:
        lb = np.asarray(lb, dtype=float)
        ub = np.asarray(ub, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInput("lb and ub must be vectors of numbers") from None
    if lb.ndim != 1 or ub.shape != lb.shape:
        raise InvalidInput(
            f"lb and ub must be vectors (n,) of one length, got {lb.shape} and {ub.shape}"
        )
    n = int(lb.shape[0])
    problem = HierarchyProblem(
        list(levels),
        np.asarray(lb, dtype=float),
        np.asarray(ub, dtype=float),
        np.zeros((0, n)) if G is None else np.asarray(G, dtype=float),
        np.zeros(0) if h is None else np.asarray(h, dtype=float),
    )
    return HierarchySolver(**options).solve(problem)
