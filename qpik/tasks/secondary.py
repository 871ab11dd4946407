"""Secondary objectives, meant for lower priority levels (the lecture's ``zeta``).

Both are scalar tasks: the error is a scalar measure ``w(q)``, the Jacobian its gradient
``dw/dq`` (1, nv), so ``J dq = -gain * w`` moves ``q`` along the gradient. Placed below a
frame task, the QP restricts that motion to the null space of the frame task: the lecture's
``qdot = J^+ xi + N(q) zeta``.
"""

from __future__ import annotations

import mink
import numpy as np

from ..configuration import Configuration, FrameType
from ..errors import mink_errors_as_qpik

# These tasks read what only qpik.Configuration has (frame_pose, frame_jacobian, lower, upper), so
# their compute_* methods narrow mink's ``configuration: mink.Configuration`` (hence the
# ``type: ignore[override]``); qpik's entry points (qpik.mink_api) turn a mink
# configuration into a qpik one before any task sees it.


class JointLimitDistanceTask(mink.Task):
    """Keep joints away from their limits.

    Error ``w(q)``: :func:`qpik.analysis.joint_limit_distance`, the mean squared distance of
    each joint from its mid-range, normalised by its range (0 at mid-range, 1/8 at the limits
    for every joint). Unlimited joints do not count.
    """

    k = 1

    def __init__(self, cost: float = 1.0, gain: float = 0.5, lm_damping: float = 0.0):
        with mink_errors_as_qpik(type(self).__name__):
            super().__init__(np.array([float(cost)]), gain, lm_damping)

    def compute_error(self, configuration: Configuration) -> np.ndarray:  # type: ignore[override]
        from ..analysis import joint_limit_distance

        return np.array(
            [joint_limit_distance(configuration.q, configuration.lower, configuration.upper)]
        )

    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:  # type: ignore[override]
        from ..analysis import joint_limit_distance_gradient

        gradient = joint_limit_distance_gradient(
            configuration.q, configuration.lower, configuration.upper
        )
        return gradient[None, :]


class ManipulabilityTask(mink.Task):
    """Raise the manipulability ``m(q) = sqrt(det J J^T)`` of a frame.

    Error ``e = -m(q)``; ``J dq = -gain * e`` asks each step for an increase of ``gain * m``
    along the gradient of ``m``. ``rows`` selects ``"pose"`` (6 rows) or ``"position"`` (3).
    """

    k = 1

    def __init__(
        self,
        frame_name: str,
        frame_type: FrameType | str = FrameType.SITE,
        rows: str = "pose",
        cost: float = 1.0,
        gain: float = 0.1,
        lm_damping: float = 0.0,
    ):
        with mink_errors_as_qpik(type(self).__name__):
            super().__init__(np.array([float(cost)]), gain, lm_damping)
        self.frame_name = frame_name
        self.frame_type = FrameType.parse(frame_type)
        self.rows = rows

    def compute_error(self, configuration: Configuration) -> np.ndarray:  # type: ignore[override]
        from ..analysis import manipulability

        jacobian = configuration.frame_jacobian(self.frame_name, self.frame_type)
        if self.rows == "position":
            jacobian = jacobian[:3]
        return np.array([-manipulability(jacobian)])

    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:  # type: ignore[override]
        from ..analysis import manipulability_gradient

        gradient = manipulability_gradient(
            configuration, self.frame_name, self.frame_type.value, rows=self.rows
        )
        return -np.asarray(gradient)[None, :]
