r"""Strict task priorities as a cascade of QPs, one persistent workspace per level.

The variable of every level is the displacement ``dq = v dt`` (``nv``). Level ``k`` has the
weighted residual ``A_k dq - b_k`` of its tasks (``A = diag(cost) J``, ``b = -gain cost e``)
and solves

.. math::

    \min_{dq} \tfrac12 \|A_k dq - b_k\|^2 + \tfrac12 (\delta + \mu_k + \lambda_k^2) \|dq\|^2
    \quad \text{s.t.} \quad dq \in d_{k-1} + \mathcal{N}_{k-1}, \;
    lb \le dq \le ub, \; G dq \le h

where :math:`d_{k-1}` is the solution of the level above and :math:`\mathcal{N}_{k-1}` the
null space of the rows of every level above (``N_{-1}`` is everything). Writing
``dq = d + P z`` with ``P`` the orthogonal projector onto that null space, each level is a
QP in ``z`` whose only constraints are the limits: it is always feasible (``z = 0`` is the
level above's solution) and a lower level cannot change any higher level's ``A_j dq``
(up to the rank tolerance), whatever the solver's tolerance.

Damping (singularity robustness), per level, from that level's smallest singular value
*after projection* into the null space of the levels above (so algorithmic singularities,
where two levels conflict, count as well as kinematic ones)::

    sigma  = the r-th singular value of A_k P, r = min(rows_k, nv - rank of the levels above)
    lambda^2 = max_damping^2 * (1 - (sigma / singular_threshold)^2)   if sigma < singular_threshold
             = 0                                                        otherwise

(Nakamura & Hanafusa 1986; Chiaverini 1997). Far from singularities the step is the exact
(prioritised) least-squares step; near them it is damped least squares with the damping
growing smoothly to ``max_damping^2``, which bounds the step by ``|b| / (2 max_damping)``.
``delta`` (``damping``) is a small constant Tikhonov term on every level, as in mink, and
``mu_k`` the tasks' own Levenberg-Marquardt terms.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import mink
import mujoco
import numpy as np
from scipy.linalg import lapack

from .configuration import Configuration, joint_names
from .errors import InfeasibleLimits, InvalidInput, InvalidTarget, NoSolutionFound
from .qp import OSQPSettings, make_workspace, solve_linear
from .tasks import BaseTask

__all__ = ["DampingLaw", "IKSolver", "Stack", "StepResult", "normalize_stack", "solve_ik"]


@dataclass(frozen=True)
class DampingLaw:
    """Adaptive damping from the smallest (projected) singular value of a level.

    Attributes:
        singular_threshold: ``sigma`` below which damping starts (units of the level's
            weighted Jacobian, e.g. [m/rad] for a position task of cost 1).
        max_damping: ``lambda`` reached at ``sigma = 0``.
        error_scale: if set, damping also fades with the level's error (see ``__call__``);
            :func:`qpik.solve` uses this, velocity control does not.
    """

    singular_threshold: float = 0.05
    max_damping: float = 0.05
    error_scale: float | None = None

    def __call__(self, sigma: float, error_norm: float | None = None) -> float:
        """``lambda^2`` for smallest singular value ``sigma``.

        With ``error_scale`` set, ``lambda^2`` is further scaled by
        ``min(1, |b| / error_scale)`` (``|b|`` the level's weighted error): damping fades as
        the error vanishes, in the spirit of Levenberg-Marquardt (Sugihara 2011), so that an
        iterative solve converges quickly to targets at or near singular configurations;
        the step stays bounded by ``sqrt(|b| error_scale) / (2 max_damping)``.
        """
        if not sigma < self.singular_threshold:
            return 0.0
        ratio = sigma / self.singular_threshold
        lam2 = self.max_damping**2 * (1.0 - ratio * ratio)
        if self.error_scale is not None and error_norm is not None:
            lam2 *= min(1.0, error_norm / self.error_scale)
        return lam2


@dataclass
class StepResult:
    """What one differential IK step computed.

    Attributes:
        velocity: joint velocity ``(nv,)`` [rad/s or m/s] (``displacement / dt``).
        displacement: ``dq = velocity * dt`` ``(nv,)``.
        residuals: per level, the norm of its weighted residual ``|A_k dq - b_k|`` at the
            final ``dq``.
        sigma_min: per level, the smallest singular value that drove its damping.
        damping: per level, ``lambda^2`` applied.
        active_limits: the limits that bind at the final ``dq``, e.g.
            ``"joint4 upper (ConfigurationLimit)"``.
        status: per level: ``"solved"``, ``"solved_after_retry"``, ``"relaxed"`` (level solved
            without its general inequality rows, which could not be met), ``"kept_previous"``
            (the level failed; the level above's ``dq`` is kept) or ``"failed"``.
        iterations: per level, solver iterations (0 where the backend does not report them).
        solve_time: wall time of the whole step [s].
    """

    velocity: np.ndarray
    displacement: np.ndarray
    sigma_min: list[float]
    damping: list[float]
    status: list[str]
    iterations: list[int]
    solve_time: float
    _levels: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = field(
        default_factory=list, repr=False
    )  # per level: (A, b, dq right after that level was solved)
    _name_active_limits: Callable[[], list[str]] | None = field(default=None, repr=False)
    _active_limits: list[str] | None = field(default=None, repr=False)

    @property
    def residuals(self) -> list[float]:
        """Per level, ``|A_k dq - b_k|`` at the final ``dq`` (NaN for levels not reached)."""
        values = [_norm(A @ self.displacement - b) for A, b, _ in self._levels]
        return values + [float("nan")] * (len(self.status) - len(values))

    @property
    def level_residuals_at_solve(self) -> list[float]:
        """Per level, ``|A_k dq - b_k|`` right after level ``k`` was solved (lower levels
        must leave it unchanged: the tests of strict priority compare the two)."""
        return [_norm(A @ d - b) for A, b, d in self._levels]

    @property
    def active_limits(self) -> list[str]:
        """The limits that bind at the final ``dq`` (named on first access)."""
        if self._active_limits is None:
            names = self._name_active_limits() if self._name_active_limits else []
            self._active_limits = names
        return self._active_limits

    @property
    def ok(self) -> bool:
        """True when every level was solved (possibly after a retry)."""
        return all(s in ("solved", "solved_after_retry") for s in self.status)


#: A task stack: a task, a list of tasks (one weighted level), or a list of levels, each a
#: task or a list of tasks (level 0 first). See :func:`normalize_stack`.
Stack = BaseTask | Sequence[BaseTask | Sequence[BaseTask]]


def normalize_stack(stack: Stack) -> list[list[BaseTask]]:
    """Levels from a stack description.

    * a task: one level with that task;
    * a sequence of tasks only: **one** level (weighted, like ``mink.solve_ik``);
    * a sequence whose items are tasks or sequences of tasks, at least one a sequence: one
      level per item, item 0 the highest priority.
    """
    if isinstance(stack, BaseTask):
        return [[stack]]
    items = list(stack)
    if not items:
        raise InvalidInput("the task stack is empty")
    if all(isinstance(item, BaseTask) for item in items):
        return [items]
    levels = []
    for index, item in enumerate(items):
        level = [item] if isinstance(item, BaseTask) else list(item)
        if not level or not all(isinstance(t, BaseTask) for t in level):
            raise InvalidInput(
                f"level {index} of the stack must be a task or a non-empty list of tasks, "
                f"got {item!r}"
            )
        levels.append(level)
    return levels


def _level_residual(
    tasks: Sequence[BaseTask], configuration: Configuration, nv: int
) -> tuple[np.ndarray, np.ndarray, float]:
    """Stacked weighted residual ``(A, b, mu)`` of a level: objective ``1/2 |A dq - b|^2``.

    Tasks that only provide ``(H, c)`` are factored as ``H = A^T A``, ``A^T b = -c``.
    Rows with zero weight are dropped (they would count as lost rank).
    """
    if len(tasks) == 1:
        residual = tasks[0].compute_qp_residual(configuration)
        if residual is not None:
            A, b, mu = residual
            if A.ndim != 2:
                A, b = np.atleast_2d(A), np.atleast_1d(b)
            nonzero = A.any(axis=1)
            if not nonzero.all():
                A, b = A[nonzero], b[nonzero]
            return A, b, float(mu)
    A_parts, b_parts = [], []
    mu = 0.0
    for task in tasks:
        residual = task.compute_qp_residual(configuration)
        if residual is None:
            H, c = task.compute_qp_objective(configuration)
            values, vectors = np.linalg.eigh(0.5 * (H + H.T))
            keep = values > 1e-12 * max(1.0, float(values.max(initial=0.0)))
            root = np.sqrt(values[keep])
            A_parts.append(root[:, None] * vectors[:, keep].T)
            b_parts.append(-(vectors[:, keep].T @ c) / root)
        else:
            weighted_jacobian, weighted_error, task_mu = residual
            A_parts.append(np.atleast_2d(weighted_jacobian))
            b_parts.append(np.atleast_1d(weighted_error))
            mu += float(task_mu)
    A = np.vstack(A_parts) if A_parts else np.zeros((0, nv))
    b = np.concatenate(b_parts) if b_parts else np.zeros(0)
    nonzero = np.any(A != 0.0, axis=1)
    if not nonzero.all():
        A, b = A[nonzero], b[nonzero]
    return A, b, mu


@dataclass(frozen=True)
class _RowStructure:
    """Rows of a limit's ``G``: single-dof upper / lower bounds (row, dof, 1/coefficient),
    general rows, and empty rows; ``unique`` when no dof is bounded twice on one side."""

    upper_rows: np.ndarray
    upper_dofs: np.ndarray
    upper_scale: np.ndarray
    lower_rows: np.ndarray
    lower_dofs: np.ndarray
    lower_scale: np.ndarray
    general: np.ndarray
    empty: np.ndarray | None
    unique: bool


def _configuration_box(limit: mink.ConfigurationLimit, configuration: Configuration, dt: float):
    """mink's ConfigurationLimit as box bounds on ``dq`` (hinge/slide joints: dof = qpos)."""
    q = configuration.data.qpos[limit.indices]
    upper = limit.gain * (limit.upper[limit.indices] - q)
    lower = -limit.gain * (q - limit.lower[limit.indices])
    return limit.indices, lower, upper


def _velocity_box(limit: mink.VelocityLimit, configuration: Configuration, dt: float):
    """mink's VelocityLimit as box bounds on ``dq``: ``|dq| <= v_max dt``."""
    bound = limit.limit * dt
    return limit.indices, -bound, bound


#: Limits whose rows are known to be single-dof bounds, computed directly as boxes (exact
#: type match: a subclass may change the rows). Used on models whose joints are all
#: hinges or slides; other limits go through ``compute_qp_inequalities``.
_BOX_LIMITS = {mink.ConfigurationLimit: _configuration_box, mink.VelocityLimit: _velocity_box}


def _norm(vector: np.ndarray) -> float:
    """Euclidean norm of a small vector (0 for an empty one)."""
    return float(np.sqrt(vector @ vector))


def _svd(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Singular values and right singular vectors (rows of ``Vt``) of a small matrix."""
    if matrix.shape[0] == 0:
        return np.zeros(0), np.zeros((0, matrix.shape[1]))
    _, s, vt, info = lapack.dgesdd(matrix, full_matrices=0)
    if info != 0:  # pragma: no cover - LAPACK failure, fall back to numpy's driver
        _, s, vt = np.linalg.svd(matrix, full_matrices=False)
    return s, vt


class IKSolver:
    """Differential IK with strict priorities, keeping one QP workspace per level.

    Args:
        model: the MuJoCo model (its ``nv`` fixes the QP size).
        stack: the task stack (see :func:`normalize_stack`); tasks are kept by reference,
            so ``task.set_target(...)`` between steps is how targets move.
        limits: mink or qpik limits, enforced at every level.
        solver: ``"osqp"`` (default; persistent workspaces, warm starts) or a qpsolvers
            backend (``"daqp"``, ``"quadprog"``, ``"proxqp"``) with the same semantics.
        damping: constant Tikhonov term ``delta`` on every level.
        damping_law: the adaptive (singularity) damping, see :class:`DampingLaw`.
        rank_tolerance: singular values below ``rank_tolerance * max(1, sigma_max)`` of a
            level's projected rows are treated as zero when locking that level.
        fast_path: first solve each level's QP without its inequalities (one linear solve);
            if that minimiser satisfies every limit it *is* the QP's solution (the QP is
            strictly convex), and the QP solver is called only when a limit binds. Exact;
            ``False`` sends every level to the QP solver.
        osqp_settings: OSQP settings (default :class:`qpik.qp.OSQPSettings`: tolerances
            1e-7, then an exact active-set refinement).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        stack: Stack,
        limits: Sequence[mink.Limit] = (),
        *,
        solver: str = "osqp",
        damping: float = 1e-6,
        damping_law: DampingLaw | None = DampingLaw(),
        rank_tolerance: float = 1e-9,
        fast_path: bool = True,
        osqp_settings: OSQPSettings | None = None,
    ):
        if damping < 0 or not np.isfinite(damping):
            raise InvalidInput(f"damping must be finite and >= 0, got {damping}")
        self.model = model
        self.levels = normalize_stack(stack)
        self.limits = list(limits)
        self.solver = solver
        self.damping = float(damping)
        self.damping_law = damping_law
        self.rank_tolerance = rank_tolerance
        self._nv = model.nv
        make_workspace(solver, 1, 1)  # fail early, naming the extra, if the backend is missing
        self._workspaces: list = [None] * len(self.levels)
        names = joint_names(model)
        self._dof_names = [names[model.dof_jntid[i]] for i in range(model.nv)]
        self._eye = np.eye(self._nv)
        self._structure_cache: dict[int, tuple] = {}
        self._no_rows = np.zeros((0, self._nv))
        self._bounds = tuple(np.empty(self._nv) for _ in range(4))  # scratch for _limit_rows
        self._scalar_joints = model.nq == model.nv and bool(
            np.all(
                np.isin(model.jnt_type, [mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE])
            )
        )
        self.fast_path = fast_path
        self.osqp_settings = osqp_settings

    @property
    def workspace_setups(self) -> int:
        """How many QP workspaces were built so far (OSQP: one per level, once)."""
        return sum(getattr(ws, "setups", 0) for ws in self._workspaces if ws is not None)

    # ----------------------------------------------------------------- limits
    def _row_structure(self, limit, G: np.ndarray) -> _RowStructure:
        """How a limit's rows split into single-dof bounds and general rows. Cached while
        ``G`` is unchanged (mink's position and velocity limits return the same ``G``)."""
        key = id(limit)
        cached = self._structure_cache.get(key)
        if cached is not None and cached[0].shape == G.shape and np.array_equal(cached[0], G):
            return cached[1]
        nonzero = G != 0.0
        count = nonzero.sum(axis=1)
        unit = np.flatnonzero(count == 1)
        dofs = np.argmax(nonzero[unit], axis=1) if unit.size else np.zeros(0, dtype=int)
        coefficients = G[unit, dofs]
        up = coefficients > 0
        empty = np.flatnonzero(count == 0)
        structure = _RowStructure(
            upper_rows=unit[up],
            upper_dofs=dofs[up],
            upper_scale=1.0 / coefficients[up],
            lower_rows=unit[~up],
            lower_dofs=dofs[~up],
            lower_scale=1.0 / coefficients[~up],
            general=np.flatnonzero(count > 1),
            empty=empty if empty.size else None,
            unique=len(set(dofs[up].tolist())) == up.sum()
            and len(set(dofs[~up].tolist())) == (~up).sum(),
        )
        self._structure_cache[key] = (G.copy(), structure)
        return structure

    def _limit_rows(self, configuration: Configuration, dt: float):
        """Box bounds ``lb <= dq <= ub`` and general rows ``G dq <= h`` of all limits, and
        the per-limit box contributions (to name the active limits afterwards)."""
        hard_lb, hard_ub, pos_lb, pos_ub = self._bounds
        hard_lb.fill(-np.inf)
        hard_ub.fill(np.inf)
        pos_lb.fill(-np.inf)
        pos_ub.fill(np.inf)
        contributions = []  # (name, dofs, bounds) for each side of each limit
        general_G, general_h, general_names = [], [], []
        for limit in self.limits:
            box = _BOX_LIMITS.get(type(limit)) if self._scalar_joints else None
            if box is not None:
                dofs, lower, upper = box(limit, configuration, dt)
                if len(dofs):
                    if isinstance(limit, mink.ConfigurationLimit):
                        lb, ub = pos_lb, pos_ub
                    else:
                        lb, ub = hard_lb, hard_ub
                    ub[dofs] = np.minimum(ub[dofs], upper)
                    lb[dofs] = np.maximum(lb[dofs], lower)
                    name = type(limit).__name__
                    contributions.append((name, dofs, upper))
                    contributions.append((name, dofs, lower))
                continue
            constraint = limit.compute_qp_inequalities(configuration, dt)
            if constraint.inactive:
                continue
            G = constraint.G if constraint.G.ndim == 2 else np.atleast_2d(constraint.G)
            h = np.atleast_1d(constraint.h)
            name = type(limit).__name__
            recoverable = isinstance(limit, mink.ConfigurationLimit) or getattr(
                limit, "recoverable", False
            )
            structure = self._row_structure(limit, G)
            if structure.empty is not None and np.any(h[structure.empty] < 0):
                raise InfeasibleLimits(f"{name} has a row 0 . dq <= {h[structure.empty].min():.3g}")
            lb, ub = (pos_lb, pos_ub) if recoverable else (hard_lb, hard_ub)
            for rows, dofs, scale, side, pick in (
                (structure.upper_rows, structure.upper_dofs, structure.upper_scale, ub, np.minimum),
                (structure.lower_rows, structure.lower_dofs, structure.lower_scale, lb, np.maximum),
            ):
                if rows.size:
                    bounds = h[rows] * scale
                    if structure.unique:
                        side[dofs] = pick(side[dofs], bounds)
                    else:
                        pick.at(side, dofs, bounds)
                    contributions.append((name, dofs, bounds))
            if structure.general.size:
                general_G.append(G[structure.general])
                general_h.append(h[structure.general])
                general_names.extend(f"{name} row {int(r)}" for r in structure.general)
        if (hard_lb > hard_ub).any():
            i = int(np.flatnonzero(hard_lb > hard_ub)[0])
            raise InfeasibleLimits(
                f"limits on {self._dof_names[i]} need {hard_lb[i]:.6g} <= dq <= "
                f"{hard_ub[i]:.6g}: no displacement satisfies them"
            )
        # Position limits are recoverable: where they conflict with the hard limits (a start
        # outside the limits that cannot be left in one step), move toward them at the
        # hard limit's pace.
        lb = np.maximum(hard_lb, pos_lb)
        ub = np.minimum(hard_ub, pos_ub)
        conflict = lb > ub
        if conflict.any():
            too_high = conflict & (pos_ub < hard_lb)
            too_low = conflict & (pos_lb > hard_ub)
            lb[too_high] = ub[too_high] = hard_lb[too_high]
            lb[too_low] = ub[too_low] = hard_ub[too_low]
        G = np.vstack(general_G) if general_G else self._no_rows
        h = np.concatenate(general_h) if general_h else np.zeros(0)
        return lb, ub, G, h, contributions, general_names

    # ------------------------------------------------------------------- step
    def step(self, configuration: Configuration, dt: float) -> StepResult:
        """Solve the stack at ``configuration`` for a step of ``dt`` [s]."""
        if not dt > 0 or not np.isfinite(dt):
            raise InvalidInput(f"dt must be a positive number of seconds, got {dt}")
        start = time.perf_counter()
        nv = self._nv
        lb, ub, G, h, contributions, general_names = self._limit_rows(configuration, dt)
        m_general = G.shape[0]
        d = np.zeros(nv)
        P = self._eye
        locked_rank = 0
        statuses, sigmas, dampings, iterations = [], [], [], []
        solved_levels = []
        eye = self._eye
        for k, tasks in enumerate(self.levels):
            A, b, mu = _level_residual(tasks, configuration, nv)
            if not math.isfinite(float(b @ b)):
                raise InvalidTarget(
                    f"priority level {k}: a task error is not finite (a NaN or inf target?) "
                    f"in {', '.join(type(t).__name__ for t in tasks)}"
                )
            if A.shape[0] == 0 or locked_rank >= nv:
                statuses.append("solved")
                sigmas.append(np.inf)
                dampings.append(0.0)
                iterations.append(0)
                solved_levels.append((A, b, d))
                continue
            first = locked_rank == 0  # nothing locked yet: P = I, d = 0
            AP = A if first else A @ P
            s, Vt = _svd(AP)
            expected = min(A.shape[0], nv - locked_rank)
            sigma = float(s[expected - 1]) if expected > 0 and expected <= s.size else 0.0
            if self.damping_law is None:
                lam2 = 0.0
            elif self.damping_law.error_scale is None:
                lam2 = self.damping_law(sigma)
            else:
                lam2 = self.damping_law(sigma, _norm(b - A @ d))
            reg = self.damping + mu + lam2
            if first:
                H = AP.T @ AP
                H.flat[:: nv + 1] += reg
                c = -(AP.T @ b) if not d.any() else AP.T @ (A @ d - b) + reg * d
                M = np.vstack([eye, G]) if m_general else eye
            else:
                # P (A^T A + reg I) P on N, identity on its complement (pins z there).
                H = AP.T @ AP + (reg - 1.0) * P
                H.flat[:: nv + 1] += 1.0
                c = AP.T @ (A @ d - b) + reg * (P @ d)
                M = np.vstack([P, G @ P]) if m_general else P
            if m_general:
                lower = np.concatenate([lb - d, np.full(m_general, -np.inf)])
                upper = np.concatenate([ub - d, h - G @ d])
            else:
                lower, upper = lb - d, ub - d
            z, status, its = self._solve_level(k, H, c, M, lower, upper, m_general)
            if z is not None:
                d = d + (z if first else P @ z)
                # Box limits hold exactly, not to the solver's tolerance.
                np.maximum(d, lb, out=d)
                np.minimum(d, ub, out=d)
            statuses.append(status)
            sigmas.append(sigma)
            dampings.append(lam2)
            iterations.append(its)
            solved_levels.append((A, b, d))
            if z is None and k == 0:
                break
            # Lock this level's rows for the levels below.
            tol = self.rank_tolerance * max(1.0, float(s[0]) if s.size else 1.0)
            r = int(np.count_nonzero(s > tol))
            if r:
                V = Vt[:r].T
                P = (eye if first else P) - V @ V.T
                locked_rank += r
        return StepResult(
            velocity=d / dt,
            displacement=d,
            sigma_min=sigmas,
            damping=dampings,
            _name_active_limits=lambda: self._active_limits(
                d, lb, ub, G, h, contributions, general_names
            ),
            status=statuses + ["not_reached"] * (len(self.levels) - len(statuses)),
            iterations=iterations,
            solve_time=time.perf_counter() - start,
            _levels=solved_levels,
        )

    def _solve_level(self, k, H, c, M, lower, upper, m_general):
        """Solve level ``k``; on failure retry cold with more iterations, then without the
        general inequality rows. Returns ``(z or None, status, iterations)``."""
        if self.fast_path:
            x = solve_linear(H, -c)
            if x is not None:
                Mx = M @ x
                if (Mx <= upper).all() and (Mx >= lower).all():
                    return x, "solved", 0
        rows = M.shape[0]
        workspace = self._workspaces[k]
        if workspace is None or workspace.m != rows:
            workspace = self._workspaces[k] = make_workspace(
                self.solver, self._nv, rows, self.osqp_settings
            )
        solution = workspace.solve(H, c, M, lower, upper)
        if solution.found:
            return solution.x, "solved", solution.iterations
        workspace.reset(cold=True, scale_iterations=10)
        retry = workspace.solve(H, c, M, lower, upper)
        workspace.reset(scale_iterations=1)
        if retry.found:
            return retry.x, "solved_after_retry", solution.iterations + retry.iterations
        if m_general:
            relaxed_lower = lower.copy()
            relaxed_upper = upper.copy()
            relaxed_lower[self._nv :] = -np.inf
            relaxed_upper[self._nv :] = np.inf
            workspace.reset(cold=True)
            relaxed = workspace.solve(H, c, M, relaxed_lower, relaxed_upper)
            if relaxed.found:
                return relaxed.x, "relaxed", relaxed.iterations
        return None, ("failed" if k == 0 else "kept_previous"), retry.iterations

    def _active_limits(self, d, lb, ub, G, h, contributions, general_names) -> list[str]:
        tol = 1e-9
        active = []
        for side, bound, at_bound in (
            ("upper", ub, np.isfinite(ub) & (d >= ub - tol)),
            ("lower", lb, np.isfinite(lb) & (d <= lb + tol)),
        ):
            for i in np.flatnonzero(at_bound):
                source = next(
                    (
                        name
                        for name, dofs, bounds in contributions
                        if np.any((dofs == i) & (np.abs(bounds - bound[i]) <= tol))
                    ),
                    "limit",
                )
                active.append(f"{self._dof_names[i]} {side} ({source})")
        if G.shape[0]:
            for j in np.flatnonzero(G @ d >= h - 1e-7):
                active.append(general_names[j])
        return active


def solve_ik(
    configuration: Configuration,
    stack: Stack,
    dt: float,
    *,
    limits: Sequence[mink.Limit] = (),
    solver: str = "osqp",
    damping: float = 1e-6,
) -> np.ndarray:
    """One differential IK step: the joint velocity ``(nv,)`` [rad/s] for a step of ``dt`` [s].

    A one-shot convenience around :class:`IKSolver` (which keeps workspaces between steps
    and should be preferred in loops). Raises :class:`qpik.NoSolutionFound` only when the
    highest priority level cannot be solved even after the fallbacks.
    """
    solver_ = IKSolver(configuration.model, stack, limits, solver=solver, damping=damping)
    result = solver_.step(configuration, dt)
    if result.status[0] == "failed":
        raise NoSolutionFound(solver, result.status[0], level=0)
    return result.velocity
