"""What a differential IK step returns: :class:`StepResult` for users, and
:class:`Solution`, what either path of a step (the compiled step or the core's QP
cascade, :func:`solve_rows`) hands back to :class:`qpik.IKSolver`: the displacement, each
level's report and certificate, and the limits of the step, so that the limits that bind
are named when asked for.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core import HierarchySolver, LevelCertificate, LevelStatus
from ..core.certificate import STATUS_OF_CODE, certificate_of
from ..core.kernels import resolve_sigma
from ..errors import InvalidTarget
from .boxes import LimitRows
from .rows import TaskRows

__all__ = ["Solution", "StepResult", "solve_rows"]


def resolved_info(info: np.ndarray, defer: np.ndarray) -> np.ndarray:
    """A kernel step's ``info`` (9, L) with the sigma of each level it deferred (NaN: its
    rank proved full, no damping; its record in ``defer``, the step's row of the kernel's
    ``defer`` output) resolved (a copy), or ``info`` itself where none was deferred."""
    sigma = info[1]
    if not np.isnan(sigma).any():
        return info
    info = info.copy()
    info[1] = resolve_sigma(sigma, defer)
    return info


@dataclass
class Solution:
    """One step as a path computed it, every level included (the couplings' level first
    when there is one): the displacement ``dq`` (nv,), the velocity ``dq / dt``, per level
    the residual, smallest singular value, ``lambda^2``, status, iterations and
    certificate, and ``limits()``, the step's :class:`~qpik.diffik.boxes.LimitRows`
    (computed when the active limits are asked for)."""

    displacement: np.ndarray
    velocity: np.ndarray
    residuals: list[float]
    sigma_min: list[float]
    damping: list[float]
    status: list[LevelStatus]
    iterations: list[int]
    certificate: list[LevelCertificate]
    limits: Callable[[], LimitRows]
    #: the general rows' slack when level 0 was infeasible (qpik.diffik.recovery), else None
    relaxation: np.ndarray | None = None

    @property
    def ok(self) -> bool:
        """True when every level was solved."""
        return all(s == LevelStatus.SOLVED for s in self.status)


#: Beyond this entry size a level's rows overflow when squared (its objective, its
#: certificate, a QP's ``P = A^T A``).
SQUARABLE = 1e150


def squarable(top: float, count: int) -> bool:
    """Whether a level's rows, whose largest entry is ``top`` (``count`` entries), square in
    double precision: at most 1e150, and ``top^2 count`` at most 1e300 (its objective and
    its certificate square and sum them). The compiled step's test (``Bound::safe``, where
    the step then takes this path): the same rows refused on both."""
    return top <= SQUARABLE and top * top * max(count, 1) <= 1e300


def solve_rows(core: HierarchySolver, tasks: TaskRows, limits: LimitRows, dt: float) -> Solution:
    """The core's cascade on a step's rows and limits (the QP path), as a
    :class:`Solution`; raises :class:`qpik.InvalidTarget` when a level's rows are too large
    to square (:func:`squarable`) or the answer is not finite."""
    for k in range(tasks.starts.shape[0] - 1):
        part = tasks.A[tasks.starts[k] : tasks.starts[k + 1]]
        top = float(np.abs(part).max()) if part.size else 0.0
        if not squarable(top, part.size):
            raise InvalidTarget(
                f"priority level {k}: its weighted rows reach {top:.3g}, too large to square "
                "in floating point (a cost near 1e150 or beyond?)"
            )
    result = core.solve_arrays(
        tasks.A, tasks.b, tasks.w, tasks.starts, tasks.reg, limits.lb, limits.ub, limits.G,
        limits.h,
    )  # fmt: skip
    d = result.x
    finite = math.isfinite(sum(result.residuals)) and math.isfinite(sum(result.damping))
    if not (math.isfinite(float(d @ d)) and finite):  # (damping: a weight past 1e154, squared)
        raise InvalidTarget(
            "the step or a level's residual is not finite: a level's rows are too large "
            "to square in floating point (a cost or target near 1e150 or beyond?)"
        )
    return Solution(
        displacement=d,
        velocity=d / dt,
        residuals=result.residuals,
        sigma_min=result.sigma,
        damping=result.damping,
        status=result.status,
        iterations=result.iterations,
        certificate=result.certificate,
        limits=lambda: limits,
    )


_new = object.__new__
#: The per-level lists of a :meth:`StepResult.lazy` result, read on first access.
_PER_LEVEL = frozenset(("residuals", "sigma_min", "damping", "status", "iterations", "certificate"))
#: What a :meth:`StepResult.lean` result reads on first access: the per-level lists, the
#: displacement, the couplings' residual and the limits.
_LEAN = _PER_LEVEL | {"displacement", "coupling_residual", "_limits"}


def _none() -> None:
    return None


@dataclass
class StepResult:
    """What one differential IK step computed.

    Attributes:
        velocity: joint velocity ``(nv,)`` [rad/s or m/s]: ``displacement / dt``, bit for
            bit.
        displacement: ``dq`` ``(nv,)``, the step the QP solved (``velocity * dt`` to
            rounding: 1 ulp).
        residuals: per level, the norm of its weighted residual ``|A_k dq - b_k|`` at the
            final ``dq``, over all its rows (zero Jacobian rows included).
        sigma_min: per level, the smallest singular value that drove its damping (inf
            when the level has none).
        damping: per level, ``lambda^2`` applied.
        status: per level, a :class:`~qpik.core.LevelStatus` (``"solved"``,
            ``"infeasible"``: level 0's limits admit no displacement, ``"kept_previous"``,
            ``"max_iter"``, ``"not_reached"``, ...).
        iterations: per level, active-set changes (or the forced backend's iterations,
            which depend on its warm workspace: a speed figure, unlike every other field;
            0 for daqp and clarabel, whose counts qpsolvers does not pass on).
        solve_time: wall time of the whole step [s].
        certificate: per level, its :class:`~qpik.core.LevelCertificate` (the largest
            scaled violation of primal feasibility, stationarity, dual signs and
            complementarity at the point it returned; ``solved`` only when each is at most
            :data:`~qpik.core.CERTIFICATE_TOLERANCE`, see :mod:`qpik.core.cascade`).
        coupling_residual: the residual ``|A dq - b|`` of the level of the model's
            couplings, solved above the stack (:attr:`qpik.StepOptions.couplings`);
            ``None`` when there is none. The lists above hold the stack's levels only.
        relaxation: ``None``, unless the limits admitted no displacement at all (level 0
            infeasible: say a collision pair deeper inside its minimum distance than one
            step can leave): then the general rows ``G dq <= h`` were relaxed by the least
            slack ``s`` (p,) [the rows' units] and the step solved on ``G dq <= h + s``
            (:mod:`qpik.diffik.recovery`): it separates as fast as the box allows, and the
            statuses and certificates refer to the relaxed rows.
    """

    velocity: np.ndarray
    displacement: np.ndarray
    residuals: list[float]
    sigma_min: list[float]
    damping: list[float]
    status: list[LevelStatus]
    iterations: list[int]
    solve_time: float
    certificate: list[LevelCertificate] = field(default_factory=list)
    # No class-level defaults for these two (default factories): a :meth:`lean` result
    # leaves them out of its ``__dict__`` and :meth:`__getattr__` reads them when asked.
    coupling_residual: float | None = field(default_factory=_none)
    _limits: Callable[[], LimitRows] | None = field(default_factory=_none, repr=False)
    _active_limits: list[str] | None = field(default=None, repr=False)
    relaxation: np.ndarray | None = None

    @classmethod
    def of(cls, solution: Solution, solve_time: float, couplings: bool = False) -> StepResult:
        """The result of ``solution``; with ``couplings`` its first level is the model's
        couplings' (reported as :attr:`coupling_residual`, left out of the lists)."""
        skip = int(couplings)
        return cls(
            velocity=solution.velocity,
            displacement=solution.displacement,
            residuals=list(solution.residuals)[skip:],
            sigma_min=list(solution.sigma_min)[skip:],
            damping=list(solution.damping)[skip:],
            status=list(solution.status)[skip:],
            iterations=list(solution.iterations)[skip:],
            solve_time=solve_time,
            certificate=list(solution.certificate)[skip:],
            coupling_residual=solution.residuals[0] if couplings else None,
            _limits=solution.limits,
            relaxation=solution.relaxation,
        )

    @classmethod
    def lazy(
        cls,
        velocity: np.ndarray,
        displacement: np.ndarray,
        info: np.ndarray,
        skip: int,
        solve_time: float,
        limits: Callable[[], LimitRows],
        row: int | None = None,
        deferred: np.ndarray | None = None,
    ) -> StepResult:
        """The result of a compiled step from the kernel's ``info`` (9, L) (rows: residual,
        sigma, lambda^2, status code, iterations, then the certificate's four measures;
        the couplings' level first when ``skip`` is 1), or from ``info[row]`` of a stack of
        them (K, 9, L) when ``row`` is given: the per-level lists are read from it on first
        access (the same values :meth:`of` gives; a control loop that reads only the
        velocity never builds them). ``deferred``: the kernel's records of the sigmas it
        deferred (NaN in ``info``), resolved then."""
        result = _new(cls)
        first = (0, 0) if row is None else (row, 0, 0)
        result.__dict__ = {
            "velocity": velocity,
            "displacement": displacement,
            "solve_time": solve_time,
            "coupling_residual": info.item(first) if skip else None,
            "_limits": limits,
            "_active_limits": None,
            "_info": (info, row, skip, deferred),
        }
        return result

    @classmethod
    def lean(cls, velocity: np.ndarray, solve_time: float, source: tuple) -> StepResult:
        """The result of a lean compiled step
        (:meth:`qpik.diffik.compiled.CompiledPlan.step_result`) with only its velocity and time
        set: ``source`` is ``(out, row, skip, plan, dt)``, the plan's output arrays ``out = (d,
        v, info, active, qpos)`` (stacks of rows, never written again at ``row``), the step's
        row, 1 when the first level is the couplings' (reported apart), and the plan and ``dt``
        that give the step's limits. Everything else (the displacement ``d[row]``, the per-level
        lists of ``info[row]``, the couplings' residual, the limits) is read from it on first
        access: the same values :meth:`of` gives, none of them built by a control loop that
        reads the velocity. (:meth:`qpik.IKSolver.step`'s plain lane makes the same object in
        its own frame: ``object.__new__`` and these three attributes.)"""
        result = _new(cls)
        result.velocity = velocity
        result.solve_time = solve_time
        result._src = source  # type: ignore[attr-defined]  # (not a field: __getattr__ reads it)
        return result

    def __getattr__(self, name: str) -> Any:
        """A field of a :meth:`lazy` or :meth:`lean` result, read now."""
        d = self.__dict__
        src = d.get("_src")
        if src is not None and name in _LEAN:
            out, row, skip, plan, dt = src
            if name == "displacement":
                value = d["displacement"] = out[0][row]
                return value
            if name == "coupling_residual":
                value = d["coupling_residual"] = out[2].item(row, 0, 0) if skip else None
                return value
            if name == "_limits":
                qpos = out[4][row]
                value = d["_limits"] = lambda: plan.lean_limits(qpos, dt)
                return value
            info = resolved_info(out[2][row], out[5][row])
        else:
            lazy = d.get("_info")
            if lazy is None or name not in _PER_LEVEL:
                raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
            info, row, skip, deferred = lazy
            if row is not None:
                info = info[row]
            if deferred is not None:
                info = resolved_info(info, deferred)
            del d["_info"]
        if "residuals" not in d:
            residuals, sigma, lam2, status, iterations, *cert = info.tolist()
            d.update(
                residuals=residuals[skip:],
                sigma_min=sigma[skip:],
                damping=lam2[skip:],
                status=[STATUS_OF_CODE[int(code)] for code in status[skip:]],
                iterations=[int(i) for i in iterations[skip:]],
                certificate=[certificate_of(list(row)) for row in zip(*cert)][skip:],
            )
        return d[name]

    def __getstate__(self) -> dict:
        """What a copy or a pickle takes: every field read now (a :meth:`lazy` or
        :meth:`lean` result reads its own from the solver's live arrays and plan, which are
        neither copied nor pickled) and the active limits named; the copy keeps no tie to
        the solver."""
        for name in ("displacement", "residuals", "coupling_residual"):
            getattr(self, name)
        self.active_limits  # noqa: B018 (named now, kept in _active_limits)
        state = {k: v for k, v in self.__dict__.items() if k not in ("_src", "_info")}
        state["_limits"] = None
        return state

    @property
    def active_limits(self) -> list[str]:
        """The limits that bind at the final ``dq``, e.g.
        ``"joint4 upper (ConfigurationLimit)"``. Named on first access, from the limit
        objects as they are then (a control loop that never reads it pays nothing): read it
        (or copy the result, which names them) before changing a limit's values."""
        if self._active_limits is None:
            limits = self._limits() if self._limits is not None else None
            self._active_limits = limits.active(self.displacement) if limits else []
        return self._active_limits

    @property
    def ok(self) -> bool:
        """True when every level was solved."""
        return all(s == LevelStatus.SOLVED for s in self.status)
