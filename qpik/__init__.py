"""qpik: inverse kinematics of robots as constrained QPs with strict task priorities."""

from . import analysis, baselines, limits, statics, tasks
from .configuration import Configuration, FrameType, frame_names, joint_names
from .batch import solve_many
from .converge import IKResult, solve
from .errors import (
    InfeasibleLimits,
    InvalidConfiguration,
    InvalidInput,
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
from .problem import load_problem
from .robots import list_robots, load_robot

__version__ = "0.1.0"

__all__ = [
    "DampingLaw",
    "IKResult",
    "IKSolver",
    "StepResult",
    "baselines",
    "limits",
    "solve",
    "solve_ik",
    "solve_many",
    "tasks",
    "Configuration",
    "FrameType",
    "InfeasibleLimits",
    "InvalidConfiguration",
    "InvalidInput",
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
    "load_problem",
    "load_robot",
    "statics",
]
