"""qpik: inverse kinematics of robots as constrained QPs with strict task priorities."""

from typing import TYPE_CHECKING, Any

from . import errors, tasks
from .diffik import SOLVERS as _SOLVERS
from .diffik import DampingLaw, IKSolver, StepResult, build_ik, solve_ik
from .errors import QpikError
from .igm import IKResult, IKSession, Reason, solve
from .igm.prepared import PREPARED as _PREPARED
from .model.configuration import Configuration, FrameType, frame_names, joint_names
from .options import PRESETS, SolveOptions, StepOptions
from .robots import list_robots, load_robot

__version__ = "0.2.0"  # the one place the version is written (pyproject.toml reads it)

if TYPE_CHECKING:  # imported on first use (see __getattr__); type checkers see them here
    from . import analysis, limits, scene, statics
    from .batch import ReachabilityMap, reachability, solve_many
    from .igm import baselines
    from .problem import load_problem

#: Names imported on first use, not by ``import qpik`` (they pull in modules a solve never
#: needs, scipy.spatial among them): name -> (module, attribute or None for the module).
_LAZY = {
    "analysis": ("qpik.analysis", None),
    "baselines": ("qpik.igm.baselines", None),
    "limits": ("qpik.limits", None),
    "scene": ("qpik.scene", None),
    "statics": ("qpik.statics", None),
    "load_problem": ("qpik.problem", "load_problem"),
    "solve_many": ("qpik.batch", "solve_many"),
    "reachability": ("qpik.batch", "reachability"),
    "ReachabilityMap": ("qpik.batch", "ReachabilityMap"),
}


def __getattr__(name: str) -> Any:
    """Import the lazy names of :data:`_LAZY` on first use."""
    if name in errors.__all__:  # every error class, as qpik.X too (their home: qpik.errors)
        return getattr(errors, name)
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
    return sorted(set(globals()) | set(_LAZY) | set(errors.__all__))


def clear_caches() -> None:
    """Forget what qpik keeps between calls: the :class:`IKSolver` objects that
    :func:`solve_ik` and :func:`build_ik` keep per model, task and limit objects
    (:class:`qpik.diffik.mink_compat.SolverCache`), and the robots :func:`solve` prepared per model
    (:data:`qpik.igm.prepared.PREPARED`, a :class:`qpik.igm.prepared.PreparedRobots`). Answers never
    depend on them; only the time of the next call does."""
    _SOLVERS.clear()
    _PREPARED.clear()


#: The front door, curated: the state, one step, full IK, batches, problem files, options,
#: the root error and the modules users reach through ``qpik.X``. Every error class is
#: ``qpik.errors.X`` (and ``qpik.X``).
__all__ = [
    "Configuration",
    "FrameType",
    "frame_names",
    "joint_names",
    "list_robots",
    "load_robot",
    "IKSolver",
    "StepResult",
    "DampingLaw",
    "solve_ik",
    "build_ik",
    "solve",
    "IKSession",
    "IKResult",
    "Reason",
    "solve_many",
    "reachability",
    "ReachabilityMap",
    "load_problem",
    "SolveOptions",
    "StepOptions",
    "PRESETS",
    "QpikError",
    "clear_caches",
    "tasks",
    "limits",
    "analysis",
    "statics",
    "scene",
    "baselines",
]
