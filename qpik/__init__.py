"""qpik: inverse kinematics of robots as constrained QPs with strict task priorities."""

from . import analysis, baselines, limits, statics, tasks
from .configuration import Configuration, FrameType, frame_names, joint_names
from .errors import (
    InfeasibleLimits,
    InvalidConfiguration,
    InvalidTarget,
    JointLimitViolation,
    MissingExtra,
    NoSolutionFound,
    ProblemFileError,
    QpikError,
    RobotFileError,
    UnknownFrame,
    UnknownFrameType,
    UnknownRobot,
)
from .hierarchy import DampingLaw, IKSolver, StepResult, solve_ik
from .robots import list_robots, load_robot

__version__ = "0.1.0"

__all__ = [
    "DampingLaw",
    "IKSolver",
    "StepResult",
    "baselines",
    "limits",
    "solve_ik",
    "tasks",
    "Configuration",
    "FrameType",
    "InfeasibleLimits",
    "InvalidConfiguration",
    "InvalidTarget",
    "JointLimitViolation",
    "MissingExtra",
    "NoSolutionFound",
    "ProblemFileError",
    "QpikError",
    "RobotFileError",
    "UnknownFrame",
    "UnknownFrameType",
    "UnknownRobot",
    "__version__",
    "analysis",
    "frame_names",
    "joint_names",
    "list_robots",
    "load_robot",
    "statics",
]
