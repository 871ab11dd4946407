"""Full IK (the inverse geometric model): iterate differential IK steps until the targets
are met, with restarts.

- :mod:`.session`: :func:`solve` and :class:`IKSession`, and the call of the compiled
  engine (:mod:`qpik.igm.kernels`);
- :mod:`.prepared`: what a solve reads from a model once, and the per-model cache of
  :func:`solve`;
- :mod:`.qp_engine`: the ``"qp"`` engine, the same loop on :class:`qpik.IKSolver` steps;
- :mod:`.restarts`, :mod:`.targets`, :mod:`.result`: the restart loop, what a target may
  be, what a solve returns;
- :mod:`.baselines`: the pseudoinverse and damped-least-squares reference loops.
"""

from .result import IKResult, Reason
from .session import IKSession, solve

__all__ = ["IKResult", "IKSession", "Reason", "solve"]
