"""What a full-IK loop returns: :class:`Outcome`, the base of its results (:class:`IKResult`
of :func:`qpik.solve`, :class:`qpik.igm.baselines.IGMResult` of the baselines), and why it
ended, :class:`Reason`.

Reasons are a string-valued :class:`enum.Enum`: ``result.reason == "converged"`` holds, and
JSON, CSV and the CLI print the plain string.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

__all__ = ["IGM_REASONS", "REASONS", "IKResult", "LazyRows", "Outcome", "Reason"]


class Reason(str, enum.Enum):
    """Why a solve (or a baseline IGM loop) ended; :attr:`CONVERGED` is the only success.
    Compares equal to its string value; ``str()`` and ``format()`` give the value."""

    CONVERGED = "converged"
    MAX_ITERS = "max_iters"
    TIME_BUDGET = "time_budget"
    STALLED = "stalled"
    AT_LIMIT = "at_limit"
    SINGULAR = "singular"
    UNREACHABLE = "unreachable"
    DIVERGED = "diverged"
    CONSTRAINT = "constraint"

    def __str__(self) -> str:
        return self.value

    def __format__(self, format_spec: str) -> str:
        return str.__format__(self, format_spec)

    @property
    def description(self) -> str:
        """What the reason means, in a sentence."""
        return _DESCRIPTIONS[self]


_DESCRIPTIONS = {
    Reason.CONVERGED: "every frame and every level-0 task is within tolerance",
    Reason.MAX_ITERS: "the iteration limit of the last attempt was reached",
    Reason.TIME_BUDGET: "the time budget ran out",
    Reason.STALLED: "no progress, for no diagnosed reason (the target may be out of reach)",
    Reason.AT_LIMIT: "no progress while a joint limit binds",
    Reason.SINGULAR: "no progress at a singular configuration",
    Reason.UNREACHABLE: "a target position is farther from the base than the arm reaches "
    "(provably: the chain's reach bound); answered without iterating",
    Reason.DIVERGED: "the step was not finite",
    Reason.CONSTRAINT: "the targets are within tolerance, but q breaks an active equality "
    "constraint of the model that qpik does not hold (a connect or weld constraint: "
    "IKResult.constraint_error; hold it with mink's EqualityConstraintTask in level 0)",
}

#: The reasons :func:`qpik.solve` gives, with their meaning (read-only).
REASONS: Mapping[str, str] = MappingProxyType(
    {r.value: r.description for r in Reason if r is not Reason.DIVERGED}
)
#: The reasons of the baseline loops (:func:`qpik.igm.baselines.igm`), with their meaning.
IGM_REASONS: Mapping[str, str] = MappingProxyType(
    {
        Reason.CONVERGED.value: "the frame is within tolerance of its target",
        Reason.MAX_ITERS.value: Reason.MAX_ITERS.description,
        Reason.TIME_BUDGET.value: Reason.TIME_BUDGET.description,
        Reason.STALLED.value: "no progress (a 5 % decrease of the error) for stall_window steps",
        Reason.DIVERGED.value: Reason.DIVERGED.description,
    }
)


@dataclass
class Outcome:
    """What every full-IK loop reports, the base of its results: :class:`IKResult`
    (:func:`qpik.solve`, :meth:`qpik.IKSession.solve`, :func:`qpik.solve_many`) and
    :class:`qpik.igm.baselines.IGMResult` (the baselines' loops) derive from it, so the same
    things have the same names in both.

    Attributes:
        q: the best configuration found ``(nq,)``.
        converged: whether the targets are within tolerance at ``q``.
        reason: a :class:`Reason` (a string).
        iterations: IK steps taken, all attempts together.
        restarts_used: random restarts made after the first attempt.
        position_error: largest frame position error at ``q`` [m].
        orientation_error: largest frame orientation error at ``q`` [rad] (0 without
            orientation targets).
        solve_time: wall time [s].
    """

    q: np.ndarray
    converged: bool
    reason: Reason
    iterations: int
    restarts_used: int
    position_error: float
    orientation_error: float
    solve_time: float = 0.0


@dataclass
class IKResult(Outcome):
    """The outcome of :func:`qpik.solve`: the fields of :class:`Outcome` (``q`` within the
    limits the solve kept: the joint limits by default, none with ``limits=None``;
    ``converged`` when every frame and every level-0 task is within tolerance and ``q``
    breaks none of the model's equality constraints (see ``constraint_error``); ``reason``
    one of :data:`REASONS`), and:

    Attributes:
        frame_errors: per frame, ``(position_error [m], orientation_error [rad])``.
        residual_history: per iteration of the returned attempt, each level's QP residual
            ``|A_k dq - b_k|`` (what the solver minimised at that step).
        error_history: per iteration of the returned attempt (its start first), the largest
            frame ``(position_error [m], orientation_error [rad])``.
        path: the configurations of the returned attempt, its start first ``(k, nq)``.
        engine: ``"compiled"`` or ``"qp"`` (see :mod:`qpik.igm.session`).
        levels_met: per level of the stack (level 0 first; the default stack has one),
            whether every task of it with a target is within tolerance at ``q`` (the
            rule of :mod:`qpik.igm.session`); with the feet in level 0 and a hand out of
            reach in level 1, ``(True, False, ...)``.
        coupling_error: the largest residual of the model's couplings at ``q``
            (:func:`qpik.model.model_couplings`) [rad or m]; 0 without couplings.
        constraint_error: the largest residual at ``q`` of the model's active equality
            constraints that qpik does not hold (connect and weld constraints:
            :func:`qpik.model.couplings.unheld_equalities`; MuJoCo's residuals) [m, or
            rad for a weld's rotation]; 0 without such constraints. A solve whose
            targets are met at a ``q`` that breaks one (beyond ``tol_position`` /
            ``tol_orientation``) is not converged: its reason is ``constraint``.
    """

    frame_errors: dict[str, tuple[float, float]] = field(default_factory=dict)
    residual_history: Sequence[list[float]] = field(default_factory=list, repr=False)
    error_history: Sequence[tuple[float, float]] = field(default_factory=list, repr=False)
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), repr=False)
    engine: str = "qp"
    levels_met: tuple[bool, ...] = ()
    coupling_error: float = 0.0
    constraint_error: float = 0.0

    def __str__(self) -> str:
        state = "converged" if self.converged else f"not converged ({self.reason})"
        return (
            f"IK {state} in {self.iterations} iterations, {self.restarts_used} restarts, "
            f"{1e3 * self.solve_time:.2f} ms: position error {self.position_error:.3g} m, "
            f"orientation error {self.orientation_error:.3g} rad\n"
            f"q = {np.array2string(self.q, precision=4)}"
        )


class LazyRows(Sequence):
    """A read-only sequence of the rows of a 2-D array, each converted on access (to a
    list, or a tuple): the compiled engine's histories, built only when read. The rows are
    ``array[first:, columns]`` (``columns``: ``slice(start, stop)``), sliced on access."""

    __slots__ = ("_array", "_columns", "_first", "_kind")

    def __init__(
        self,
        array: np.ndarray,
        kind: type = list,
        first: int = 0,
        start: int = 0,
        stop: int | None = None,
    ):
        self._array = array
        self._kind = kind
        self._first = first
        self._columns = slice(start, stop)

    def __len__(self) -> int:
        return max(0, self._array.shape[0] - self._first)

    def _rows(self) -> np.ndarray:
        return self._array[self._first :, self._columns]

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self._kind(row) for row in self._rows()[index].tolist()]
        return self._kind(self._rows()[index].tolist())

    def __eq__(self, other) -> bool:
        return list(self) == list(other)

    def __repr__(self) -> str:
        return repr(list(self))
