"""Tasks: mink's, re-exported so one import serves (with qpik's errors:
:mod:`qpik.tasks.mink_tasks`), and the ones qpik adds.

Every task follows mink's contract: ``compute_error(configuration) -> e (k,)``,
``compute_jacobian(configuration) -> J (k, nv)`` with ``J = de/dq``, a ``cost`` vector that
weights the rows and a ``gain`` in [0, 1]; the QP asks ``J dq = -gain * e``. Any task with
that contract works at any priority level of :class:`qpik.IKSolver`.
"""

from mink import Objective, Task
from mink.tasks.task import BaseTask

from .com import ComTask
from .coupling import CouplingTask
from .frame import FrameTask
from .mink_tasks import (
    AxisAlignTask,
    DofFreezingTask,
    EqualityConstraintTask,
    KineticEnergyRegularizationTask,
    LookAtTask,
    RelativeFrameTask,
)
from .pose import OrientationTask, PoseTask, PositionTask
from .posture import DampingTask, PostureTask
from .secondary import JointLimitDistanceTask, ManipulabilityTask

__all__ = [
    "AxisAlignTask",
    "BaseTask",
    "ComTask",
    "CouplingTask",
    "DampingTask",
    "DofFreezingTask",
    "EqualityConstraintTask",
    "FrameTask",
    "JointLimitDistanceTask",
    "KineticEnergyRegularizationTask",
    "LookAtTask",
    "ManipulabilityTask",
    "Objective",
    "OrientationTask",
    "PoseTask",
    "PositionTask",
    "PostureTask",
    "RelativeFrameTask",
    "Task",
]
