"""Differential IK: one step of a task stack under limits, as a cascade of QPs.

- :mod:`.solver`: :class:`IKSolver`, :class:`StepResult` (stack -> levels -> rows -> the
  core cascade);
- :mod:`.compiled`: the one-call compiled step for the stacks it covers;
- :mod:`.mink_compat`: mink's entry points (:func:`solve_ik`, :func:`build_ik`) with qpik
  underneath.
"""

from .mink_compat import SOLVERS, SolverCache, build_ik, solve_ik
from .solver import DampingLaw, IKSolver, LevelStatus, Stack, StepResult, normalize_stack

__all__ = [
    "SOLVERS",
    "DampingLaw",
    "IKSolver",
    "LevelStatus",
    "SolverCache",
    "Stack",
    "StepResult",
    "build_ik",
    "normalize_stack",
    "solve_ik",
]
