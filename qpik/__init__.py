"""qpik: inverse kinematics of robots as constrained QPs with strict task priorities."""

from typing import TYPE_CHECKING, Any

from . import tasks
from .batch import solve_many
from .configuration import Configuration, FrameType, frame_names, joint_names
from .converge import PREPARED as _PREPARED
from .converge import IKResult, IKSession, solve
from .errors import (
    CollisionPairError,
    InfeasibleLimits,
    IntegrationTimestepNotSet,
    InvalidConfiguration,
    InvalidConstraint,
    InvalidDamping,
    InvalidGain,
    InvalidInput,
    InvalidKeyframe,
    InvalidMocapBody,
    InvalidOption,
    InvalidTarget,
    JointLimitViolation,
    LimitDefinitionError,
    MissingExtra,
    NoSolutionFound,
    ProblemFileError,
    QpikError,
    RobotFileError,
    SceneError,
    TargetNotSet,
    TaskDefinitionError,
    UnknownFrame,
    UnknownFrameType,
    UnknownRobot,
)
from .hierarchy import DampingLaw, IKSolver, StepResult
from .mink_api import SOLVERS as _SOLVERS
from .mink_api import build_ik, solve_ik
from .options import PRESETS, SolveOptions, StepOptions
from .reachability import ReachabilityMap, reachability
from .result import Reason
from .robots import list_robots, load_robot

__version__ = "0.2.0"  # the one place the version is written (pyproject.toml reads it)

if TYPE_CHECKING:  # imported on first use (see __getattr__); type checkers see them here
    from . import analysis, baselines, limits, scene, statics
    from .problem import load_problem

#: Names imported on first use, not by ``import qpik`` (they pull in modules a solve never
#: needs, scipy.spatial among them): name -> (module, attribute or None for the module).
_LAZY = {
    "analysis": ("qpik.analysis", None),
    "baselines": ("qpik.baselines", None),
    "limits": ("qpik.limits", None),
    "scene": ("qpik.scene", None),
    "statics": ("qpik.statics", None),
    "load_problem": ("qpik.problem", "load_problem"),
}


def __getattr__(name: str) -> Any:
    """Import the lazy names of :data:`_LAZY` on first use."""
    try:
        module_name, attribute = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'qpik' has no attribute {name!r}") from None
    import importlib

    module = importlib.import_module(module_name)
    value = module if attribute is None else getattr(module, attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


def clear_caches() -> None:
    """Forget what qpik keeps between calls: the :class:`IKSolver` objects that
    :func:`solve_ik` and :func:`build_ik` keep per model, task and limit objects
    (:class:`qpik.mink_api.SolverCache`), and the robots :func:`solve` prepared per model
    (:data:`qpik.converge.PREPARED`, a :class:`qpik.converge.PreparedRobots`). Answers never
    depend on them; only the time of the next call does."""
    _SOLVERS.clear()
    _PREPARED.clear()


__all__ = [
    "DampingLaw",
    "IKResult",
    "IKSession",
    "IKSolver",
    "PRESETS",
    "Reason",
    "SolveOptions",
    "StepOptions",
    "StepResult",
    "baselines",
    "limits",
    "solve",
    "build_ik",
    "clear_caches",
    "solve_ik",
    "solve_many",
    "reachability",
    "ReachabilityMap",
    "tasks",
    "Configuration",
    "FrameType",
    "CollisionPairError",
    "InfeasibleLimits",
    "IntegrationTimestepNotSet",
    "InvalidConstraint",
    "InvalidDamping",
    "InvalidGain",
    "InvalidKeyframe",
    "InvalidMocapBody",
    "LimitDefinitionError",
    "TargetNotSet",
    "TaskDefinitionError",
    "InvalidConfiguration",
    "InvalidInput",
    "InvalidOption",
    "InvalidTarget",
    "JointLimitViolation",
    "MissingExtra",
    "NoSolutionFound",
    "ProblemFileError",
    "QpikError",
    "RobotFileError",
    "SceneError",
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
    "scene",
    "statics",
]
