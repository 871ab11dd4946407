"""The engine core: a hierarchical QP solver that knows only matrices.

Levels ``(A_k, b_k, regularisation_k)``, box bounds and general rows go in; a solution
and a per-level report come out. Nothing here imports MuJoCo or mink (a test checks it):
tasks and limits (:mod:`qpik.tasks`, :mod:`qpik.limits`) turn a robot configuration into
rows, and :class:`qpik.IKSolver` hands them to this core.
"""

from ..errors import InvalidInput, MissingExtra, QpikError
from .cascade import (
    CERTIFICATE_TOLERANCE,
    DEFAULT_DAMPING,
    SOLVERS,
    DampingLaw,
    HierarchyProblem,
    HierarchyResult,
    HierarchySolver,
    Level,
    LevelCertificate,
    LevelStatus,
    solve_hierarchy,
)

__all__ = [
    "CERTIFICATE_TOLERANCE",
    "DEFAULT_DAMPING",
    "SOLVERS",
    "DampingLaw",
    "HierarchyProblem",
    "HierarchyResult",
    "HierarchySolver",
    "InvalidInput",
    "Level",
    "LevelCertificate",
    "LevelStatus",
    "MissingExtra",
    "QpikError",
    "solve_hierarchy",
]
