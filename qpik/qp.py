"""QP backends: one small dense QP per priority level.

Each level solves

    minimise    1/2 x^T H x + c^T x
    subject to  lower <= M x <= upper

with ``x`` of fixed size ``n`` and ``M`` of a fixed number of rows. The OSQP backend keeps one
workspace alive per level: it is set up once with a dense sparsity pattern (explicit zeros
kept) and every later solve only *updates* the values and warm-starts from the previous
solution. Other backends go through :mod:`qpsolvers`.

Backends are looked up by name in :data:`BACKENDS`; a backend whose package is missing raises
:class:`qpik.MissingExtra` naming the extra to install.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import scipy.sparse as sp
from scipy.linalg import lapack

from .errors import InvalidInput, MissingExtra

__all__ = [
    "BACKENDS",
    "OSQPSettings",
    "OSQPWorkspace",
    "QPSolution",
    "QPWorkspace",
    "make_workspace",
    "refine_active_set",
    "solve_linear",
]

_INF = 1e20  # what OSQP treats as infinity (OSQP_INFTY is 1e30; any value above 1e20 works)


@dataclass
class QPSolution:
    """Outcome of one QP solve."""

    x: np.ndarray | None
    status: str  # "solved", "solved_inaccurate", "primal_infeasible", "max_iter", ...
    iterations: int
    solve_time: float  # [s]

    @property
    def found(self) -> bool:
        return self.x is not None and self.status in ("solved", "solved_inaccurate")


class QPWorkspace(Protocol):
    """What a backend provides: ``solve`` a QP of fixed size, reusing what it can."""

    name: str

    def solve(
        self, H: np.ndarray, c: np.ndarray, M: np.ndarray, lower: np.ndarray, upper: np.ndarray
    ) -> QPSolution: ...


@dataclass(frozen=True)
class OSQPSettings:
    """OSQP settings qpik uses: tight tolerances, then qpik's own active-set refinement
    (:func:`refine_active_set`), so that solutions are accurate to round-off and box limits
    hold (mink's defaults, 1e-3, let joints cross their limits on a few percent of solves).

    OSQP's own polishing is off: OSQP 1.x prints a line on every polish that finds no active
    constraint, whatever ``verbose`` says, which would flood a control loop's output."""

    eps_abs: float = 1e-7
    eps_rel: float = 1e-7
    max_iter: int = 4000
    polishing: bool = False
    warm_starting: bool = True
    verbose: bool = False
    check_termination: int = 5

    def as_dict(self) -> dict:
        return dict(self.__dict__)


class OSQPWorkspace:
    """A persistent OSQP workspace for dense QPs of size ``n`` with ``m`` constraint rows."""

    name = "osqp"

    def __init__(self, n: int, m: int, settings: OSQPSettings | None = None):
        import osqp

        self._osqp = osqp
        self.n, self.m = n, m
        self.settings = settings or OSQPSettings()
        # Dense upper-triangular pattern of H, column by column (CSC), and dense M.
        rows, cols = np.triu_indices(n)
        order = np.lexsort((rows, cols))
        self._h_rows, self._h_cols = rows[order], cols[order]
        self._solver = None
        self._status_names = {
            int(v): k.removeprefix("OSQP_").lower()
            for k, v in osqp.SolverStatus.__members__.items()
        }
        self.setups = 0  # how many times a workspace was built (tests check it stays 1)

    def _pattern(self, H: np.ndarray, M: np.ndarray) -> tuple[sp.csc_matrix, sp.csc_matrix]:
        n, m = self.n, self.m
        h_indptr = np.concatenate([[0], np.cumsum(np.arange(1, n + 1))])
        P = sp.csc_matrix((H[self._h_rows, self._h_cols], self._h_rows, h_indptr), shape=(n, n))
        a_indices = np.tile(np.arange(m), n)
        a_indptr = np.arange(0, m * n + 1, m)
        A = sp.csc_matrix((M.ravel(order="F"), a_indices, a_indptr), shape=(m, n))
        return P, A

    def _setup(self, H, c, M, lower, upper) -> None:
        P, A = self._pattern(H, M)
        self._solver = self._osqp.OSQP()
        self._solver.setup(P, c, A, lower, upper, **self.settings.as_dict())
        self.setups += 1

    def solve(
        self, H: np.ndarray, c: np.ndarray, M: np.ndarray, lower: np.ndarray, upper: np.ndarray
    ) -> QPSolution:
        lower = np.maximum(lower, -_INF)
        upper = np.minimum(upper, _INF)
        start = time.perf_counter()
        if self._solver is None:
            self._setup(H, c, M, lower, upper)
        # The extension object behind osqp.OSQP: calling it directly skips the Python
        # wrapper's per-call bookkeeping (about half the time of a small solve).
        ext = getattr(self._solver, "_solver", None)
        if ext is not None and hasattr(ext, "update_data_vec"):
            ext.update_data_vec(q=c, l=lower, u=upper)
            ext.update_data_mat(
                P_x=H[self._h_rows, self._h_cols], P_i=None, A_x=M.ravel(order="F"), A_i=None
            )
            ext.solve()
            status_val, iterations = int(ext.info.status_val), int(ext.info.iter)
            x_raw, y_raw = ext.solution.x, ext.solution.y
        else:  # pragma: no cover - other osqp versions
            self._solver.update(
                Px=H[self._h_rows, self._h_cols], Ax=M.ravel(order="F"), q=c, l=lower, u=upper
            )
            result = self._solver.solve(raise_error=False)
            status_val, iterations = int(result.info.status_val), int(result.info.iter)
            x_raw, y_raw = result.x, result.y
        status = self._status_names.get(status_val, "unknown")
        if status == "max_iter_reached":
            status = "max_iter"
        x = np.array(x_raw) if status in ("solved", "solved_inaccurate") else None
        if x is not None and not np.all(np.isfinite(x)):
            x, status = None, "non_finite"
        if x is not None:
            x = refine_active_set(H, c, M, lower, upper, x, np.asarray(y_raw))
        return QPSolution(x, status, iterations, time.perf_counter() - start)

    def reset(self, *, cold: bool = False, scale_iterations: int = 1) -> None:
        """Drop the warm start (``cold``) and/or raise the iteration limit."""
        if self._solver is None:
            return
        if cold:
            self._solver.warm_start(x=np.zeros(self.n), y=np.zeros(self.m))
        if scale_iterations != 1:
            self._solver.update_settings(max_iter=self.settings.max_iter * scale_iterations)


def solve_linear(A: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """``A^-1 b`` for a small dense square ``A`` (LAPACK gesv without numpy's wrapper
    overhead); ``None`` when ``A`` is singular or the result is not finite."""
    _, _, x, info = lapack.dgesv(A, b)
    if info != 0 or not np.isfinite(x).all():
        return None
    return x


def refine_active_set(
    H: np.ndarray,
    c: np.ndarray,
    M: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    dual_tol: float = 1e-9,
    feasibility_tol: float = 1e-10,
) -> np.ndarray:
    """Polish an approximate QP solution: solve the KKT system on the active set that the
    duals ``y`` identify (``y > 0``: upper bound active, ``y < 0``: lower bound active) and
    return that exact solution if it is primal and dual feasible; else return ``x``."""
    at_upper = (y > dual_tol) & (upper < _INF)  # rows without a finite bound cannot bind
    at_lower = (y < -dual_tol) & (lower > -_INF)
    active = at_upper | at_lower
    k = int(active.sum())
    n = len(x)
    if k == 0:
        refined = solve_linear(H, -c)
        if refined is None:
            return x
    else:
        A = M[active]
        b = np.where(at_upper[active], upper[active], lower[active])
        kkt = np.zeros((n + k, n + k))
        kkt[:n, :n] = H
        kkt[:n, n:] = A.T
        kkt[n:, :n] = A
        solution = solve_linear(kkt, np.concatenate([-c, b]))
        if solution is None:
            return x
        refined, multipliers = solution[:n], solution[n:]
        # Dual feasibility: an upper-active row pushes down (multiplier >= 0), a lower one up.
        signs = np.where(at_upper[active], 1.0, -1.0)
        if (signs * multipliers < -1e-9).any():
            return x
    Mx = M @ refined
    if (Mx > upper + feasibility_tol).any() or (Mx < lower - feasibility_tol).any():
        return x
    return refined


class QPSolversWorkspace:
    """A backend through :mod:`qpsolvers` (daqp, quadprog, proxqp, ...). Nothing is kept
    between solves: these active-set solvers are fast to start on small dense problems."""

    def __init__(self, name: str, n: int, m: int):
        import qpsolvers

        if name not in qpsolvers.available_solvers:
            raise MissingExtra(f"QP backend {name!r}", "solvers", _PACKAGES.get(name, name))
        self._qpsolvers = qpsolvers
        self.name = name
        self.n, self.m = n, m
        self.setups = 0

    def solve(
        self, H: np.ndarray, c: np.ndarray, M: np.ndarray, lower: np.ndarray, upper: np.ndarray
    ) -> QPSolution:
        start = time.perf_counter()
        upper_rows = np.isfinite(upper) & (upper < _INF)
        lower_rows = np.isfinite(lower) & (lower > -_INF)
        G = np.vstack([M[upper_rows], -M[lower_rows]])
        h = np.concatenate([upper[upper_rows], -lower[lower_rows]])
        problem = self._qpsolvers.Problem(
            0.5 * (H + H.T), c, G if len(h) else None, h if len(h) else None
        )
        try:
            solution = self._qpsolvers.solve_problem(problem, solver=self.name)
        except Exception as exc:  # noqa: BLE001 - backends raise many kinds
            return QPSolution(None, f"error: {exc}", 0, time.perf_counter() - start)
        found = solution.found and solution.x is not None
        x = np.asarray(solution.x) if found else None
        status = "solved" if found else "infeasible_or_failed"
        return QPSolution(x, status, 0, time.perf_counter() - start)

    def reset(self, *, cold: bool = False, scale_iterations: int = 1) -> None:
        """Nothing to reset: no state is kept."""


#: Packages behind the qpsolvers backends, for error messages.
_PACKAGES = {"daqp": "daqp", "quadprog": "quadprog", "proxqp": "proxsuite", "clarabel": "clarabel"}

#: Backend names qpik knows. "osqp" keeps a workspace; the others go through qpsolvers.
BACKENDS = ("osqp", "daqp", "quadprog", "proxqp", "clarabel")


def make_workspace(
    solver: str, n: int, m: int, osqp_settings: OSQPSettings | None = None
) -> OSQPWorkspace | QPSolversWorkspace:
    """A workspace of the named backend for QPs with ``n`` variables and ``m`` rows."""
    if solver == "osqp":
        try:
            return OSQPWorkspace(n, m, osqp_settings)
        except ImportError as exc:  # pragma: no cover - osqp is a hard dependency
            raise MissingExtra("the OSQP backend", "solvers", "osqp") from exc
    if solver not in BACKENDS:
        raise InvalidInput(f"unknown QP solver {solver!r}; known solvers: {', '.join(BACKENDS)}")
    return QPSolversWorkspace(solver, n, m)
