"""QP backends for one level's reduced QP, used when a backend is forced (``solver=...``)
or as the fallback of the exact active-set kernel.

Each solves ``min 1/2 x^T H x + c^T x s.t. lo <= C x <= hi`` (``x`` of fixed size ``n``,
``C`` with a fixed number of rows). The OSQP backend keeps one workspace per level and size:
it is set up once with a dense pattern (explicit zeros kept); later solves update the
values and warm-start. The others go through :mod:`qpsolvers`. Answers are polished by the
caller on the active set they identify, so a backend's tolerance and warm start change
speed, not the answer.
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import scipy.sparse as sp

from ..errors import InvalidInput, MissingExtra
from . import kernels as K

__all__ = [
    "BACKENDS",
    "OSQP_DEFAULTS",
    "OSQP_SETTINGS",
    "OSQPWorkspace",
    "QPSOLVERS_SETTINGS",
    "QPSolution",
    "QPWorkspace",
    "check_backend_options",
    "check_osqp_settings",
    "made_exact",
    "make_workspace",
    "working_set_with_violated",
]

_INF = 1e20  # what OSQP treats as infinity

#: OSQP settings qpik uses (tight tolerances; polishing is done by qpik's active-set
#: kernel instead of OSQP's, which prints on every polish that finds no active row).
OSQP_DEFAULTS: dict[str, Any] = {
    "eps_abs": 1e-7,
    "eps_rel": 1e-7,
    "max_iter": 4000,
    "polishing": False,
    "warm_starting": True,
    "verbose": False,
    "check_termination": 5,
    "adaptive_rho": True,
    # A fixed interval: OSQP's default (0) may derive it from the measured setup time
    # (adaptive_rho_fraction), which would make the iterates depend on the machine's load.
    "adaptive_rho_interval": 50,
    "scaling": 10,
}

#: The OSQP settings a caller may give (``backend_options``), each with the values OSQP's
#: own ``validate_settings`` accepts: ``(kind, low, high, open)`` (open: both ends
#: excluded); kind ``"int"``,
#: ``"bool"`` or ``"float"``. Checked when the workspace is made (:func:`check_osqp_settings`),
#: so that no solve starts from a setting OSQP would refuse at its setup (it prints an
#: error and fails; the step would then quietly fall back to the dual method).
OSQP_SETTINGS: dict[str, tuple[str, float, float, bool]] = {
    "eps_abs": ("float", 0.0, math.inf, False),
    "eps_rel": ("float", 0.0, math.inf, False),
    "eps_prim_inf": ("float", 0.0, math.inf, False),
    "eps_dual_inf": ("float", 0.0, math.inf, False),
    "max_iter": ("int", 1, 2**31 - 1, False),
    "polishing": ("bool", 0, 1, False),
    "warm_starting": ("bool", 0, 1, False),
    "verbose": ("bool", 0, 1, False),
    "adaptive_rho": ("bool", 0, 1, False),
    "scaled_termination": ("bool", 0, 1, False),
    "check_termination": ("int", 0, 2**31 - 1, False),
    "adaptive_rho_interval": ("int", 0, 2**31 - 1, False),
    "scaling": ("int", 0, 2**31 - 1, False),
    "rho": ("float", 0.0, math.inf, True),
    "sigma": ("float", 0.0, math.inf, True),
    "alpha": ("float", 0.0, 2.0, True),
    "delta": ("float", 0.0, math.inf, True),
    "adaptive_rho_tolerance": ("float", 1.0, math.inf, False),
    "time_limit": ("float", 0.0, math.inf, False),
}


#: OSQP's earlier names of settings, which it still takes (mink passes ``polish``).
OSQP_ALIASES: dict[str, str] = {"polish": "polishing", "warm_start": "warm_starting"}


#: The settings of the qpsolvers backends whose keywords qpik checks, in
#: :data:`OSQP_SETTINGS`' form: DAQP's (``daqp.solve``'s keywords, the tolerances positive;
#: the constraint senses, break points and starts are qpik's to set, not a caller's) and
#: quadprog's (``factorized``, False only: qpik passes the Hessian). Checked when the
#: workspace is made (:func:`check_backend_options`): a value the backend would refuse at
#: its first solve, or silently read as another (DAQP takes ``True`` for an iteration
#: limit of 1), is an :class:`qpik.InvalidInput` naming it. proxqp's and clarabel's many
#: settings are left to the backend (an unknown name: :class:`qpik.InvalidInput` at the
#: first solve).
QPSOLVERS_SETTINGS: dict[str, dict[str, tuple[str, float, float, bool]]] = {
    "daqp": {
        "primal_tol": ("float", 0.0, math.inf, True),
        "dual_tol": ("float", 0.0, math.inf, True),
        "zero_tol": ("float", 0.0, math.inf, True),
        "pivot_tol": ("float", 0.0, math.inf, True),
        "progress_tol": ("float", 0.0, math.inf, True),
        "cycle_tol": ("int", 0, 2**31 - 1, False),
        "iter_limit": ("int", 1, 2**31 - 1, False),
        "fval_bound": ("float", 0.0, math.inf, True),
        "eps_prox": ("float", 0.0, math.inf, False),
        "eta_prox": ("float", 0.0, math.inf, True),
        "rho_soft": ("float", 0.0, math.inf, True),
        "w_soft": ("float", 0.0, math.inf, False),
        "rel_subopt": ("float", 0.0, math.inf, False),
        "abs_subopt": ("float", 0.0, math.inf, False),
        "sing_tol": ("float", 0.0, math.inf, True),
        "refactor_tol": ("float", 0.0, math.inf, True),
        "time_limit": ("float", 0.0, math.inf, False),
        "eq_reduction": ("bool", 0, 1, False),
        "presolve": ("bool", 0, 1, False),
    },
    # (qpik passes quadprog the Hessian itself, not the inverse of its factor)
    "quadprog": {"factorized": ("bool", 0, 0, False)},
}


def _check_values(
    backend: str, table: dict[str, tuple[str, float, float, bool]], given: dict[str, Any]
) -> None:
    """Each of ``given``'s values (its names all in ``table``) checked against its entry:
    a bool where the backend takes 0 or 1 (a range ``(0, 0)``: False only), an int where it
    takes an integer, a number in the entry's range; else :class:`qpik.InvalidInput` naming
    ``backend``'s setting."""
    for name, value in given.items():
        kind, low, high, open_low = table[name]
        if kind == "bool":  # (low, high: 0, 1 for either; 0, 0 for False only)
            ok = isinstance(value, (bool, np.bool_)) or (
                isinstance(value, (int, np.integer)) and value in (0, 1)
            )
            ok = ok and low <= value <= high
            expected = "True or False" if low < high else repr(bool(low))
        elif kind == "int":
            ok = isinstance(value, (int, np.integer)) and not isinstance(value, bool)
            ok = ok and low <= value <= high
            expected = f"an integer in [{low}, {high}]"
        else:
            ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
                value, bool
            )
            # (compared only where it is a number: a str or None is named below, not a
            # bare TypeError from the comparison)
            inside = ok and (low < value < high if open_low else low <= value <= high)
            ok = inside and not (math.isinf(value) and high < math.inf)
            bracket = "(" if open_low else "["
            end = ")" if open_low or high == math.inf else "]"
            expected = f"a number in {bracket}{low:g}, {high:g}{end}"
        if not ok:
            raise InvalidInput(f"{backend} setting {name!r} must be {expected}, got {value!r}")


def check_osqp_settings(options: dict | None) -> dict[str, Any]:
    """``options`` checked, by OSQP's names (:data:`OSQP_ALIASES` renamed): an unknown OSQP
    setting or a value outside what OSQP accepts (:data:`OSQP_SETTINGS`; ``eps_abs`` and
    ``eps_rel`` not both 0; a bool where OSQP takes 0 or 1, an int where it takes an
    integer) is a :class:`qpik.InvalidInput` naming the setting."""
    given = {OSQP_ALIASES.get(name, name): value for name, value in (options or {}).items()}
    unknown = set(given) - set(OSQP_SETTINGS)
    if unknown:
        raise InvalidInput(f"unknown OSQP settings: {', '.join(sorted(unknown))}")
    _check_values("OSQP", OSQP_SETTINGS, given)
    settings = {**OSQP_DEFAULTS, **given}
    if settings["eps_abs"] == 0 and settings["eps_rel"] == 0:
        raise InvalidInput("OSQP settings eps_abs and eps_rel cannot both be 0")
    return given


def check_backend_options(solver: str, options: dict | None) -> None:
    """``options`` (``backend_options``) checked for the backend ``solver``: OSQP's by
    :func:`check_osqp_settings`; DAQP's and quadprog's names and values by
    :data:`QPSOLVERS_SETTINGS` (an unknown name: :class:`qpik.InvalidInput`
    ``"backend_options: daqp takes no option 'x'"``, as at a solve); the other backends'
    at their first solve."""
    if solver == "osqp":
        check_osqp_settings(options)
        return
    table = QPSOLVERS_SETTINGS.get(solver)
    if table is None or not options:
        return
    for name in options:
        if name not in table:
            raise InvalidInput(f"backend_options: {solver} takes no option {name!r}")
    _check_values(solver, table, dict(options))


@dataclass
class QPSolution:
    """Outcome of one backend solve: ``x`` (None when not found), the backend's status
    ("solved", "max_iter", "primal_infeasible", ...), iterations, time [s]."""

    x: np.ndarray | None
    status: str
    iterations: int
    solve_time: float

    @property
    def found(self) -> bool:
        """Only a converged solve counts: an iteration-capped one is never "found"."""
        return self.x is not None and self.status == "solved"


class QPWorkspace(Protocol):
    """What a backend provides: ``solve`` a QP of fixed size, reusing what it can."""

    name: str

    def solve(
        self, H: np.ndarray, c: np.ndarray, C: np.ndarray, lo: np.ndarray, hi: np.ndarray
    ) -> QPSolution: ...


class OSQPWorkspace:
    """A persistent OSQP workspace for dense QPs of size ``n`` with ``m`` rows."""

    name = "osqp"

    def __init__(self, n: int, m: int, options: dict | None = None):
        import osqp

        self._osqp = osqp
        self.n, self.m = n, m
        self.settings = {**OSQP_DEFAULTS, **check_osqp_settings(options)}
        rows, cols = np.triu_indices(n)
        order = np.lexsort((rows, cols))
        self._h_rows, self._h_cols = rows[order], cols[order]
        self._solver: Any = None  # an osqp.OSQP once set up (osqp has no type stubs)
        self._status_names = {
            int(v): k.removeprefix("OSQP_").lower()
            for k, v in osqp.SolverStatus.__members__.items()
        }
        self.setups = 0

    def _setup(self, H, c, C, lo, hi) -> None:
        n, m = self.n, self.m
        h_indptr = np.concatenate([[0], np.cumsum(np.arange(1, n + 1))])
        P = sp.csc_matrix((H[self._h_rows, self._h_cols], self._h_rows, h_indptr), shape=(n, n))
        A = sp.csc_matrix(
            (C.ravel(order="F"), np.tile(np.arange(m), n), np.arange(0, m * n + 1, m)),
            shape=(m, n),
        )
        solver = self._osqp.OSQP()
        solver.setup(P, c, A, lo, hi, **self.settings)
        self._solver = solver
        self.setups += 1

    def solve(self, H, c, C, lo, hi) -> QPSolution:
        """Update the workspace's values and solve (set up on the first call)."""
        lo = np.maximum(lo, -_INF)
        hi = np.minimum(hi, _INF)
        start = time.perf_counter()
        if not (np.isfinite(H).all() and np.isfinite(c).all() and np.isfinite(C).all()):
            # (OSQP's setup would print its own error from C; the exact cascade answers)
            return QPSolution(None, "non_finite", 0, time.perf_counter() - start)
        if self._solver is None:
            self._setup(H, c, C, lo, hi)
        else:
            self._update(H[self._h_rows, self._h_cols], C.ravel(order="F"), c, lo, hi)
        x, status_val, iterations = self._solve()
        status = self._status_names.get(status_val, "unknown")
        if status == "max_iter_reached":
            status = "max_iter"
        if status != "solved" or x is None or not np.all(np.isfinite(x)):
            x = None
        return QPSolution(x, status, iterations, time.perf_counter() - start)

    def _update(self, Px, Ax, q, lo, hi) -> None:
        """New values, same sparsity. Through OSQP's compiled solver object directly when
        it is there (osqp >= 1.0): the Python wrapper's update and solve spend more time
        on bookkeeping (derivative caches, an info namespace) than OSQP on these QPs."""
        native = getattr(self._solver, "_solver", None)
        if native is None or not hasattr(native, "update_data_mat"):  # pragma: no cover
            self._solver.update(Px=Px, Ax=Ax, q=q, l=lo, u=hi)  # another osqp layout
            return
        native.update_data_vec(q=q, l=lo, u=hi)
        native.update_data_mat(P_x=Px, P_i=None, A_x=Ax, A_i=None)

    def _solve(self) -> tuple[np.ndarray | None, int, int]:
        """``(x or None, status value, iterations)`` of one OSQP solve."""
        native = getattr(self._solver, "_solver", None)
        if native is None or not hasattr(native, "solution"):  # pragma: no cover
            result = self._solver.solve(raise_error=False)  # another osqp layout
            x = None if result.x is None else np.array(result.x)
            return x, int(result.info.status_val), int(result.info.iter)
        native.solve()
        info = native.info
        x = native.solution.x
        return (None if x is None else np.array(x)), int(info.status_val), int(info.iter)


class QPSolversWorkspace:
    """A backend through :mod:`qpsolvers` (daqp, quadprog, proxqp, clarabel). Nothing is
    kept between solves; ``options`` are passed to the solver."""

    def __init__(self, name: str, n: int, m: int, options: dict | None = None):
        import qpsolvers

        if name not in qpsolvers.available_solvers:
            raise MissingExtra(f"QP backend {name!r}", "solvers", _PACKAGES.get(name, name))
        self._qpsolvers = qpsolvers
        self.name = name
        self.n, self.m = n, m
        check_backend_options(name, options)
        self.options = dict(options or {})
        self.setups = 0

    def solve(self, H, c, C, lo, hi) -> QPSolution:
        """Solve with the backend (one-sided rows ``G x <= h`` built from the finite
        bounds)."""
        start = time.perf_counter()
        upper = np.isfinite(hi) & (hi < _INF)
        lower = np.isfinite(lo) & (lo > -_INF)
        G = np.vstack([C[upper], -C[lower]])
        h = np.concatenate([hi[upper], -lo[lower]])
        problem = self._qpsolvers.Problem(
            0.5 * (H + H.T), c, G if len(h) else None, h if len(h) else None
        )
        try:
            solution = self._qpsolvers.solve_problem(problem, solver=self.name, **self.options)
        except TypeError as exc:  # an option the backend does not know: the caller's to fix
            unknown = re.search(r"unexpected keyword argument '([^']+)'", str(exc))
            if unknown is None:
                return QPSolution(None, f"error: {exc}", 0, time.perf_counter() - start)
            raise InvalidInput(
                f"backend_options: {self.name} takes no option {unknown.group(1)!r}"
            ) from None
        except Exception as exc:  # backends raise many kinds
            return QPSolution(None, f"error: {exc}", 0, time.perf_counter() - start)
        x = solution.x if solution.found else None
        if x is not None and not np.all(np.isfinite(x)):
            x = None
        status = "solved" if x is not None else "infeasible_or_failed"
        return QPSolution(
            None if x is None else np.asarray(x),
            status,
            _iterations(solution.extras),
            time.perf_counter() - start,
        )


def _iterations(extras: Any) -> int:
    """The backend's iteration count where qpsolvers passes it on (quadprog's
    ``iterations``, proxqp's ``info.iter``); 0 where it does not (daqp, clarabel)."""
    if not isinstance(extras, dict):
        return 0
    count = extras.get("iterations")
    if count is None and extras.get("info") is not None:
        count = getattr(extras["info"], "iter", None)
    try:
        return int(np.ravel(count)[0]) if count is not None else 0
    except (TypeError, ValueError, IndexError):
        return 0


#: Packages behind the qpsolvers backends, for error messages.
_PACKAGES = {"daqp": "daqp", "quadprog": "quadprog", "proxqp": "proxsuite", "clarabel": "clarabel"}

#: Backend names: "osqp" keeps a workspace; the others go through qpsolvers.
BACKENDS = ("osqp", "daqp", "quadprog", "proxqp", "clarabel")


def make_workspace(
    solver: str, n: int, m: int, options: dict | None = None
) -> OSQPWorkspace | QPSolversWorkspace:
    """A workspace of the named backend for QPs with ``n`` variables and ``m`` rows."""
    if solver == "osqp":
        return OSQPWorkspace(n, m, options)
    if solver not in BACKENDS:
        raise InvalidInput(f"unknown QP solver {solver!r}; known solvers: {', '.join(BACKENDS)}")
    return QPSolversWorkspace(solver, n, m, options)


def working_set_with_violated(
    z: np.ndarray | None,
    act: np.ndarray | None,
    C: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    size: int,
) -> np.ndarray:
    """The working set a level's answer ``z`` (reduced coordinates) is made exact on: the
    solver's own (``act``: +1 on a row's lower bound, -1 on its upper; zeros where None),
    plus every row ``z`` leaves strictly outside its bounds, however little. A backend's
    (or the dual method's) answer may leave a row outside by its tolerance, which the
    certificate's primal measure (scaled by ``1 + |bound|``) accepts where the bounds
    are themselves that small: a velocity limit of 1.5 rad/s at ``dt = 1e-9`` is a bound
    of 1.5e-9, and 5.5e-12 past it is a 0.4 % overshoot. Held, the row is met exactly
    by the re-solve (its multiplier is then >= 0: the answer pushed against it)."""
    guess = np.zeros(size, np.int8) if act is None else np.array(act, np.int8)
    if z is None or C.shape[0] == 0:
        return guess
    Cz = C @ z
    free = guess == 0
    guess[free & (Cz < lo)] = 1
    guess[free & (Cz > hi)] = -1
    return guess


def made_exact(
    x: np.ndarray, qp: tuple, max_iter: int, tol: float, lower: bool
) -> tuple[np.ndarray, int, np.ndarray]:
    """A backend's answer ``x`` made exact: the kernel's canonical cold solve of the same
    QP, so the answer never depends on the backend (or its warm start); where that fails
    numerically, the kernel started from the active set the backend identified. ``qp``:
    the level's ``(H, c, C, lo, hi)``. Returns ``(z, status code, active)``."""
    H, c, C, lo, hi = qp
    cold = np.zeros(C.shape[0], dtype=np.int8)
    z, st, _, act = K.solve_level(H, c, C, lo, hi, cold, max_iter, tol, lower, True)
    if st != K.SOLVED:
        guess = K.active_guess(x, C, lo, hi)
        z2, st2, _, act2 = K.solve_level(H, c, C, lo, hi, guess, max_iter, tol, lower, True)
        if st2 == K.SOLVED:
            z, st, act = z2, st2, act2
    return z, st, act
