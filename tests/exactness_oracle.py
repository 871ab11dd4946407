"""An independent lexicographic reference for hierarchical least-squares QPs (no qpik code).

Problem: levels ``(A_k, b_k, rho_k)`` over ``x`` (n,), box ``lb <= x <= ub`` and general rows
``G x <= h`` at every level. Level ``k`` minimises ``1/2 |A_k x - b_k|^2 + 1/2 rho_k |x|^2``
over the limits with the levels above *held*: their task values ``A_j x = A_j x_j`` fixed
(x_j the reference's own answer there), their inequalities kept (they are the limits).

Each level is solved by quadprog in the null space of the held rows (numpy's SVD, the
documented rank rule: level by level, a singular value of ``A_k N`` is a rank direction when
it exceeds ``1e-9 max(1, sigma_max(A_k N))``), with proximal-point outer iterations
(``+ eps/2 |y - y_prev|^2``, quadprog needs a positive definite Hessian) until the point
settles, then *certified* by its KKT conditions with quadprog's multipliers (stationarity,
primal and dual feasibility, scaled as in issue 21). :func:`lexicographic` returns the
reference's answer per level and whether each level's certificate held.

Random hierarchies (:func:`random_problem`) are drawn as issue 21 says: 5-40 variables, 1-5
levels of 1-12 rows, eight kinds in equal shares (``KINDS``). Every feasible kind contains a
known feasible point; the ``infeasible`` kind's limits conflict by a margin, so feasibility is
known by construction, not from a solver.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import quadprog

KINDS = (
    "generic",
    "ik_like",
    "tight_boxes",
    "rank_deficient",
    "near_singular",
    "degenerate",
    "badly_scaled",
    "infeasible",
)


@dataclass
class Problem:
    """A hierarchy: ``levels`` of ``(A, b, rho)``; limits; its kind; ``feasible`` by construction."""

    levels: list
    lb: np.ndarray
    ub: np.ndarray
    G: np.ndarray
    h: np.ndarray
    kind: str
    feasible: bool

    @property
    def n(self) -> int:
        return self.lb.shape[0]


def _rows(rng, m, n):
    return rng.normal(size=(m, n))


def random_problem(rng: np.random.Generator, kind: str) -> Problem:
    """One random hierarchy of the given kind (see the module doc)."""
    n = int(rng.integers(5, 41))
    L = int(rng.integers(1, 6))
    sizes = [int(rng.integers(1, 13)) for _ in range(L)]
    width = rng.uniform(0.2, 2.0, n)
    lb, ub = -width * rng.uniform(0.3, 1.0, n), width * rng.uniform(0.3, 1.0, n)
    p = int(rng.integers(0, max(1, n // 3) + 1))
    G = rng.normal(size=(p, n))
    xf = np.zeros(n)  # a known feasible point
    h = G @ xf + rng.uniform(0.0, 1.0, p)
    levels = []
    feasible = True
    for m in sizes:
        A = _rows(rng, m, n)
        b = rng.normal(size=m) * rng.uniform(0.1, 3.0)
        levels.append([A, b, 0.0])
    if kind == "ik_like":
        dt = 0.01
        vmax = rng.uniform(0.5, 3.0, n)
        lb, ub = -vmax * dt, vmax * dt
        p = int(rng.integers(0, 5))
        G = rng.normal(size=(p, n)) * 0.1
        h = rng.uniform(0.0, 0.01, p)
        for level in levels[:-1]:
            level[0] = level[0][: min(6, level[0].shape[0])]
            level[1] = rng.normal(size=level[0].shape[0]) * 0.05
        levels[-1] = [np.eye(n), rng.normal(size=n) * 0.05, 0.0]
    elif kind == "tight_boxes":
        c = rng.uniform(-0.5, 0.5, n)
        w = 10.0 ** rng.uniform(-3, -2, n)
        lb, ub = c - w, c + w
        fixed = rng.random(n) < 0.1
        ub[fixed] = lb[fixed]
        xf = np.clip(np.zeros(n), lb, ub)
        xf = 0.5 * (lb + ub)
        h = G @ xf + rng.uniform(0.0, 0.1, p)
    elif kind == "rank_deficient":
        for k, level in enumerate(levels):
            A = level[0]
            if A.shape[0] >= 2:
                A[-1] = A[0] * rng.uniform(-2, 2)  # duplicated (scaled) row
            if A.shape[0] >= 3:
                A[-2] = A[0] + A[1]  # dependent row
            if k > 0 and rng.random() < 0.5:  # a row of the level above again
                above = levels[k - 1][0]
                A[0] = above[int(rng.integers(0, above.shape[0]))]
            level[1] = rng.normal(size=A.shape[0])
    elif kind == "near_singular":
        for level in levels:
            A = level[0]
            m = A.shape[0]
            U, _, Vt = np.linalg.svd(A, full_matrices=False)
            s = np.sort(10.0 ** rng.uniform(-1, 0.5, len(_)))[::-1]
            s[-1] = 10.0 ** rng.uniform(-12, -5)
            level[0] = (U * s) @ Vt
            level[1] = rng.normal(size=m)
    elif kind == "degenerate":
        # The unconstrained optimum of level 0 at a vertex of box and general rows.
        A0 = levels[0][0]
        x_star = np.where(rng.random(n) < 0.5, ub, lb)
        x_star[rng.random(n) < 0.5] = 0.0
        levels[0][1] = A0 @ x_star
        xf = x_star
        if p:
            G[: p // 2 + 1] = np.eye(n)[rng.integers(0, n, p // 2 + 1)]
            h = G @ xf + np.where(rng.random(p) < 0.6, 0.0, rng.uniform(0, 0.5, p))
            G = np.vstack([G, G[:1]])  # a duplicated row
            h = np.concatenate([h, h[:1]])
        for level in levels[1:]:
            level[1] = level[0] @ np.where(rng.random(n) < 0.5, ub, lb)
    elif kind == "badly_scaled":
        for level in levels:
            scale = 10.0 ** rng.uniform(-3, 3, level[0].shape[0])
            level[0] = level[0] * scale[:, None]
            level[1] = rng.normal(size=len(scale)) * 10.0 ** rng.uniform(-2, 5, len(scale))
        wide = rng.random(n) < 0.3
        lb[wide], ub[wide] = -1e3, 1e3
        if p:
            gs = 10.0 ** rng.uniform(-3, 3, p)
            G = G * gs[:, None]
            h = h * gs
    elif kind == "infeasible":
        feasible = False
        i = int(rng.integers(0, n))
        if rng.random() < 0.5 or n < 2:
            g = np.zeros(n)
            g[i] = 1.0
            G = np.vstack([G, g])
            h = np.concatenate([h, [lb[i] - rng.uniform(0.01, 1.0)]])  # x_i <= lb_i - margin
        else:
            j = (i + 1) % n
            g = np.zeros(n)
            g[i] = g[j] = 1.0
            G = np.vstack([G, g, -g])  # x_i + x_j <= -2 and >= 2 (well beyond the box)
            margin = lb[i] + lb[j] - 0.5
            h = np.concatenate([h, [margin, margin]])
    return Problem([tuple(level) for level in levels], lb, ub, G, h, kind, feasible)


def problems(seed: int, count: int) -> list[Problem]:
    """``count`` random hierarchies, the kinds in equal shares (in turn)."""
    rng = np.random.default_rng(seed)
    return [random_problem(rng, KINDS[i % len(KINDS)]) for i in range(count)]


# ----------------------------------------------------------------------------- reference


def null_space(M: np.ndarray, n: int, rtol: float = 1e-9) -> np.ndarray:
    """Orthonormal basis of the null space of M (rank by the singular values)."""
    if M.shape[0] == 0:
        return np.eye(n)
    _, S, Vt = np.linalg.svd(M)
    rank = int(np.sum(S > rtol * max(1.0, S[0]))) if S.size else 0
    return Vt[rank:].T


def scaled_violation(x, lb, ub, G, h) -> float:
    """Largest row violation, a box row's by ``1 + |bound|``, a general row's by ``|g| + |h|``."""
    v = 0.0
    lo, hi = np.isfinite(lb), np.isfinite(ub)
    if lo.any():
        v = max(v, float(np.max((lb[lo] - x[lo]) / (1 + np.abs(lb[lo])))))
    if hi.any():
        v = max(v, float(np.max((x[hi] - ub[hi]) / (1 + np.abs(ub[hi])))))
    if G.shape[0]:
        scale = np.linalg.norm(G, axis=1) + np.abs(h)
        v = max(v, float(np.max((G @ x - h) / np.where(scale > 0, scale, 1.0))))
    return v


def objective(A, b, rho, x) -> float:
    r = A @ x - b
    return 0.5 * float(r @ r) + 0.5 * rho * float(x @ x)


class Infeasible(Exception):
    """quadprog found the limits inconsistent."""


def _level(A, b, rho, lb, ub, G, h, x0, N, relax, margin=0.0):
    """min over y of the level at x = x0 + N y under the limits; returns (x, certified)."""
    n, r = N.shape
    if r == 0:
        return x0, True
    M = A @ N
    e = b - A @ x0
    H = M.T @ M + rho * np.eye(r)
    g = -(M.T @ e) + rho * (N.T @ x0)
    lo, hi = lb > -1e20, ub < 1e20
    fixed = lo & hi & (ub - lb <= 1e-14 * (1 + np.abs(lb)))  # equal bounds: an equality
    rows, rhs = [N[fixed]], [lb[fixed] - x0[fixed]]
    # C^T y >= rhs
    for mask, sign, bound in ((lo & ~fixed, 1.0, lb), (hi & ~fixed, -1.0, ub)):
        idx = np.flatnonzero(mask)
        rows.append(sign * N[idx])
        rhs.append(sign * (bound[idx] - x0[idx]))
    if G.shape[0]:
        rows.append(-(G @ N))
        rhs.append(-(h - G @ x0))
    C = np.vstack(rows)
    d = np.concatenate(rhs)
    norms = np.linalg.norm(C, axis=1)
    keep = norms > 1e-12 * max(1.0, float(norms.max(initial=0.0)))
    if np.any(~keep & (d > 1e-9 * (1 + np.abs(d)))):
        raise Infeasible
    meq = int(np.sum(keep[: int(fixed.sum())]))
    C, d = C[keep], d[keep]
    if relax:  # the level above's answer (y = 0) stays feasible despite its round-off
        d[meq:] = np.minimum(d[meq:], 0.0) - margin * (1 + np.abs(d[meq:]))
    eps = 1e-10 * (1.0 + float(np.max(np.diag(H)))) if r else 0.0
    y = np.zeros(r)
    f_prev = math.inf
    lam = np.zeros(C.shape[0])
    for _ in range(200):
        try:
            sol = quadprog.solve_qp(H + eps * np.eye(r), -(g - eps * y), C.T, d, meq)
        except ValueError as err:
            if "inconsistent" in str(err):
                raise Infeasible from None
            raise
        y_new, lam = sol[0], sol[4]
        if not np.isfinite(y_new).all():  # quadprog broke down (an ill-conditioned level)
            return x0 + N @ y, False  # (no reference: the case is not compared)
        f = 0.5 * y_new @ H @ y_new + g @ y_new
        step = float(np.max(np.abs(y_new - y)))
        y = y_new
        if step <= 1e-13 * (1 + float(np.max(np.abs(y)))) or abs(f_prev - f) <= 1e-16 * (
            1 + abs(f)
        ):
            break
        f_prev = f
    # quadprog's point holds its active rows only to its own round-off (its Hessian has the
    # proximal term's conditioning): re-solve the least-squares problem exactly on the rows
    # with a positive multiplier (numpy's SVD and lstsq) and keep that point where it is
    # feasible.
    act = np.arange(C.shape[0]) < meq
    act |= lam > 1e-12 * max(1.0, float(np.max(np.abs(lam), initial=0.0)))
    if act.any():
        Ca, da = C[act], d[act]
        y_p = np.linalg.lstsq(Ca, da, rcond=None)[0]
        Na = null_space(Ca, r, 1e-13)
        Ma = np.vstack([M, math.sqrt(rho) * np.eye(r)]) if rho > 0 else M
        ea = np.concatenate([e, -math.sqrt(rho) * (N.T @ x0)]) if rho > 0 else e
        w = np.linalg.lstsq(Ma @ Na, ea - Ma @ y_p, rcond=None)[0] if Na.shape[1] else np.zeros(0)
        y2 = y_p + Na @ w
        slack2 = C @ y2 - d
        # Kept where feasible even when its objective is higher: quadprog's lower value
        # then came from violating its active rows by its round-off.
        if float(np.min(slack2, initial=0.0)) >= -1e-14 * (
            1 + float(np.max(np.abs(d), initial=0.0))
        ):
            y = y2
    # Certificate of the reference (looser than the core's: proximal round-off).
    grad = H @ y + g
    stat = grad - C.T @ lam
    size = np.abs(M.T) @ (np.abs(M) @ np.abs(y) + np.abs(e)) + rho * np.abs(y) + np.abs(g) + 1e-300
    size = np.maximum(size, 1e-6 * size.max())
    slack = C @ y - d
    certified = (
        float(np.max(np.abs(stat) / size, initial=0.0)) <= 1e-6
        and float(np.min(lam[meq:], initial=0.0))
        >= -1e-9 * (1 + float(np.max(np.abs(lam), initial=0.0)))
        and float(np.max(np.abs(lam * slack) / (size.max() * (1 + np.abs(d))), initial=0.0)) <= 1e-6
    )
    return x0 + N @ y, certified


def held_null_space(levels, n: int) -> np.ndarray:
    """The directions the levels leave free, by the documented rank rule: level by level,
    the null space of ``A_k N`` (N the levels above's), a singular value being a rank
    direction when it exceeds ``1e-9 max(1, sigma_max(A_k N))``."""
    N = np.eye(n)
    for A in levels:
        if N.shape[1] == 0:
            break
        M = A @ N
        rows = np.abs(M).sum(axis=1) > 0
        N = N @ null_space(M[rows], N.shape[1]) if rows.any() else N
    return N


def lexicographic(problem: Problem):
    """The reference: ``(xs, certified)`` per level (xs[k] the answer after level k), or
    raises :class:`Infeasible` when level 0's limits are inconsistent."""
    n = problem.n
    x = None
    xs, certified = [], []
    for k, (A, b, rho) in enumerate(problem.levels):
        N = held_null_space([level[0] for level in problem.levels[:k]], n)
        x0 = np.zeros(n) if x is None else x
        if x is None:
            x0 = np.clip(x0, problem.lb, problem.ub)
        try:
            x, ok = _level(
                A, b, rho, problem.lb, problem.ub, problem.G, problem.h, x0, N, relax=k > 0
            )
        except Infeasible:
            if k == 0 and not problem.feasible:
                raise
            # quadprog's round-off at a degenerate vertex: the rows widened by 1e-12; the
            # answer may then violate a row by that much, so it is no feasible reference.
            x, _ = _level(
                A, b, rho, problem.lb, problem.ub, problem.G, problem.h, x0, N, True, 1e-12
            )
            if k == 0 and scaled_violation(x, problem.lb, problem.ub, problem.G, problem.h) > 1e-9:
                raise Infeasible from None
            ok = False
        xs.append(x)
        certified.append(ok)
    return xs, certified


def reference_answer(hierarchy, kind: str = "tight_boxes", certified_only: bool = False):
    """The reference's final answer to ``hierarchy`` (any object with ``levels`` of ``A``,
    ``b`` and ``regularization``, ``lb``, ``ub``, ``G`` and ``h``: a
    :class:`qpik.core.HierarchyProblem`, read as arrays), every level certified (asserted;
    ``certified_only``: None where a level is not)."""
    problem = Problem(
        [(level.A, level.b, level.regularization) for level in hierarchy.levels],
        hierarchy.lb, hierarchy.ub, hierarchy.G, hierarchy.h, kind, True,
    )  # fmt: skip
    xs, certified = lexicographic(problem)
    if certified_only and not all(certified):
        return None
    assert all(certified)
    return xs[-1]


def level_reference(problem: Problem, k: int, x_held: np.ndarray):
    """Level ``k`` alone, the levels above held at ``x_held``'s task values (``A_j x =
    A_j x_held``, j < k) and the limits kept, from ``x_held`` (feasible): ``(x, certified)``
    (certified False when quadprog needed the rows widened by 1e-12)."""
    n = problem.n
    N = held_null_space([A for A, _, _ in problem.levels[:k]], n)
    A, b, rho = problem.levels[k]
    try:
        return _level(A, b, rho, problem.lb, problem.ub, problem.G, problem.h, x_held, N, True)
    except Infeasible:
        x, _ = _level(
            A, b, rho, problem.lb, problem.ub, problem.G, problem.h, x_held, N, True, 1e-12
        )
        return x, False


def objective_tolerance(A, b, x_ours, x_ref, f_ours, f_ref, box: float = 0.0) -> float:
    """Issue 21: worse when above the reference by more than 1e-9 of the larger objective,
    or ``1/2 (1e-7 (|b| + |A| |x|))^2``, or ``1/2 (16 eps |A| box)^2``: the objective that a
    move of ``x`` by its own rounding within the box (``box``: the largest finite bound)
    makes, where the level's target and answer are both about 0 (objectives of 1e-38 against
    1e-50 are then both 0)."""
    a = float(np.linalg.norm(A, 2))
    size = float(np.linalg.norm(b)) + a * max(
        float(np.linalg.norm(x_ours)), float(np.linalg.norm(x_ref))
    )
    rounding = 16.0 * np.finfo(float).eps * a * box
    return max(1e-9 * max(f_ours, f_ref), 0.5 * (1e-7 * size) ** 2, 0.5 * rounding**2)


def box_size(lb, ub) -> float:
    """The largest finite bound of a box (0 where none is finite)."""
    bounds = np.abs(np.concatenate([np.asarray(lb, float), np.asarray(ub, float)]))
    bounds = bounds[np.isfinite(bounds) & (bounds < 1e20)]
    return float(bounds.max()) if bounds.size else 0.0
