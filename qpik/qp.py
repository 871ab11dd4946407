"""Former home of the QP backends, now :mod:`qpik.core.backends`; kept so that
``from qpik.qp import ...`` and ``OSQPSettings`` keep working."""

from __future__ import annotations

from dataclasses import dataclass, fields

from .core.backends import BACKENDS, OSQP_DEFAULTS, OSQPWorkspace, QPSolution, make_workspace

__all__ = ["BACKENDS", "OSQPSettings", "OSQPWorkspace", "QPSolution", "make_workspace"]


@dataclass(frozen=True)
class OSQPSettings:
    """OSQP settings for ``IKSolver(..., solver="osqp", osqp_settings=...)``; the defaults
    are :data:`qpik.core.backends.OSQP_DEFAULTS`."""

    eps_abs: float = OSQP_DEFAULTS["eps_abs"]
    eps_rel: float = OSQP_DEFAULTS["eps_rel"]
    max_iter: int = OSQP_DEFAULTS["max_iter"]
    polishing: bool = OSQP_DEFAULTS["polishing"]
    warm_starting: bool = OSQP_DEFAULTS["warm_starting"]
    verbose: bool = OSQP_DEFAULTS["verbose"]
    check_termination: int = OSQP_DEFAULTS["check_termination"]

    def as_dict(self) -> dict:
        """The settings as OSQP keyword arguments."""
        return {f.name: getattr(self, f.name) for f in fields(self)}
