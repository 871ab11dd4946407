"""Full IK (the inverse geometric model): iterate differential IK steps until the targets
are met, with restarts.

- :mod:`.session`: :func:`solve` and :class:`IKSession`, and the compiled engine's setup;
- :mod:`.qp_engine`: the ``"qp"`` engine, the same loop on :class:`qpik.IKSolver` steps;
- :mod:`.restarts`, :mod:`.targets`, :mod:`.result`: the restart loop, what a target may
  be, what a solve returns;
- :mod:`.kernels`: the compiled IGM;
- :mod:`.baselines`: the pseudoinverse and damped-least-squares reference loops.
"""

from .result import IKResult, Reason
from .session import IKSession, solve

__all__ = ["IKResult", "IKSession", "Reason", "solve"]
