"""Differential IK: one step of a task stack under limits, as a cascade of QPs.

- :mod:`.solver`: :class:`IKSolver`, the entry point of a step;
- :mod:`.rows`: the task stack as levels of weighted rows;
- :mod:`.boxes`: the limits as box bounds and general rows, and the names of those that
  bind;
- :mod:`.compiled`: the compiled step, one C++ call per step for the stacks it covers;
- :mod:`.result`: :class:`StepResult`, and what either path of a step hands back;
- :mod:`.correction`: second-order correction passes of a step (opt-in,
  :attr:`qpik.StepOptions.correction_passes`);
- :mod:`.mink_compat`: mink's entry points (:func:`solve_ik`, :func:`build_ik`) with qpik
  underneath.
"""

from .mink_compat import SOLVERS, SolverCache, build_ik, solve_ik
from .result import StepResult
from .rows import Stack, normalize_stack
from .solver import DampingLaw, IKSolver, LevelStatus

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
