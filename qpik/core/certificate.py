"""What a level of the cascade proves: its status (:class:`LevelStatus`) and its
certificate of optimality (:class:`LevelCertificate`: the largest scaled violation of each
KKT condition of the level's QP, with the tolerance that decides ``solved``)."""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from . import kernels as K

__all__ = [
    "CERTIFICATE_TOLERANCE",
    "STATUS_OF_CODE",
    "LevelCertificate",
    "LevelStatus",
    "certificate_of",
    "certificates",
]


class LevelStatus(str, enum.Enum):
    """How a level ended (string-valued: ``status == "solved"`` works)."""

    SOLVED = "solved"  #: the level's QP was solved exactly
    MAX_ITER = "max_iter"  #: the solver's iteration cap was hit and no fallback succeeded
    INFEASIBLE = "infeasible"  #: the limits admit no solution (level 0 only)
    KEPT_PREVIOUS = "kept_previous"  #: the level failed; the level above's answer is kept
    NUMERICAL = "numerical_failure"  #: the solver failed numerically
    NOT_REACHED = "not_reached"  #: a level above failed, this one was not solved

    def __str__(self) -> str:
        return self.value


#: The status of each kernel status code.
STATUS_OF_CODE = {
    K.SOLVED: LevelStatus.SOLVED,
    K.MAX_ITER: LevelStatus.MAX_ITER,
    K.INFEASIBLE: LevelStatus.INFEASIBLE,
    K.KEPT_PREVIOUS: LevelStatus.KEPT_PREVIOUS,
    K.NUMERICAL: LevelStatus.NUMERICAL,
    K.NOT_REACHED: LevelStatus.NOT_REACHED,
}

#: A level is ``solved`` only when every measure of its certificate is at most this.
CERTIFICATE_TOLERANCE = 1e-9

_CONDITIONS = ("primal", "stationarity", "dual", "complementarity")


@dataclass(frozen=True)
class LevelCertificate:
    """The proof of a level's optimality at its returned point: the largest scaled
    violation of each KKT condition of the level's QP (primal feasibility, stationarity,
    dual signs, complementarity); ``solved`` is claimed only when each is at most
    :data:`CERTIFICATE_TOLERANCE`. Level 0 infeasible: ``primal`` at the
    point returned and 0 for the others (no optimum to certify); a level the cascade kept:
    the certificate of the point it kept; a level never reached (after level 0 failed): the
    certificate of the returned point with no working set (primal feasibility and
    stationarity there, dual and complementarity 0), so it says which conditions fail."""

    primal: float = math.nan
    stationarity: float = math.nan
    dual: float = math.nan
    complementarity: float = math.nan

    @property
    def holds(self) -> bool:
        """Every measure at most :data:`CERTIFICATE_TOLERANCE`."""
        return not self.failed

    @property
    def failed(self) -> list[str]:
        """The conditions above the tolerance (or not computed)."""
        return [
            name for name in _CONDITIONS
            if not getattr(self, name) <= CERTIFICATE_TOLERANCE
        ]  # fmt: skip

    @classmethod
    def from_array(cls, row: Sequence[float] | np.ndarray) -> LevelCertificate:
        """From ``(primal, stationarity, dual, complementarity)``."""
        return cls(*(float(v) for v in row))


_new = object.__new__


def certificate_of(row: list[float]) -> LevelCertificate:
    """``LevelCertificate(*row)`` from four Python floats, without the frozen dataclass's
    per-field ``object.__setattr__`` (the same object)."""
    c = _new(LevelCertificate)
    c.__dict__.update(zip(_CONDITIONS, row))
    return c


def certificates(array: np.ndarray) -> list[LevelCertificate]:
    """Per level, from the kernels' (L, 4) array."""
    # tolist() gives Python floats in one pass (the same values as float() per element).
    rows = np.asarray(array, dtype=float).reshape(-1, 4).tolist()
    return [LevelCertificate(*row) for row in rows]


def primal_violation(
    x: np.ndarray, lb: np.ndarray, ub: np.ndarray, G: np.ndarray, h: np.ndarray
) -> float:
    """The largest scaled row violation at ``x``: a box row by ``1 + |bound|``, a general
    row ``g x <= h`` by ``|g| + |h|`` (the certificate's ``primal``)."""
    big = K.ABSENT_BOUND
    worst = 0.0
    with np.errstate(invalid="ignore"):
        lo = lb > -big
        if lo.any():
            worst = max(worst, float(np.max((lb[lo] - x[lo]) / (1 + np.abs(lb[lo])))))
        hi = ub < big
        if hi.any():
            worst = max(worst, float(np.max((x[hi] - ub[hi]) / (1 + np.abs(ub[hi])))))
        if G.shape[0]:
            scale = np.linalg.norm(G, axis=1) + np.abs(h)
            v = (G @ x - h) / np.where(scale > 0, scale, 1.0)
            worst = max(worst, float(np.max(v)))
    return worst
