"""Every error qpik raises derives from :class:`QpikError`.

Errors keep the fields that explain them (the joint, the value, the bounds, the valid
names) so that callers can react programmatically, and their message says what to fix.
"""

from __future__ import annotations

from collections.abc import Sequence


from .core.errors import InvalidInput, MissingExtra, QpikError  # noqa: F401 (re-exported)


class UnknownRobot(QpikError, KeyError):
    """A robot name that is neither bundled nor an ``erd:`` name nor a file."""

    def __init__(self, name: str, available: Sequence[str], erd: bool = False):
        self.name = name
        self.available = list(available)
        if erd:
            message = (
                f"unknown robot {name!r}; example-robot-data's robots are: "
                f"{', '.join(self.available)} (qpik robots --erd lists them)"
            )
        else:
            message = (
                f"unknown robot {name!r}; bundled robots are: {', '.join(self.available)} "
                "(or pass a path to an .xml/.urdf file, or 'erd:NAME' for example-robot-data)"
            )
        super().__init__(message)

    def __str__(self) -> str:  # KeyError would otherwise quote the message
        return str(self.args[0])


class RobotFileError(QpikError):
    """A robot file that cannot be read or compiled."""

    def __init__(self, path: str, reason: str):
        self.path = path
        self.reason = reason
        super().__init__(f"cannot load robot file {path}: {reason}")


class UnknownFrame(QpikError, KeyError):
    """A frame name that the model does not have (for the given frame type)."""

    def __init__(self, name: str | int, frame_type: str, available: Sequence[str]):
        self.name = name
        self.frame_type = frame_type
        self.available = list(available)
        super().__init__(
            f"{frame_type} {name!r} does not exist in the model; available "
            f"{frame_type}s: {', '.join(self.available) or '(none)'}"
        )

    def __str__(self) -> str:
        return str(self.args[0])


class UnknownFrameType(QpikError, ValueError):
    """A frame type other than body, site or geom."""


class InvalidConfiguration(QpikError, ValueError):
    """A configuration vector of the wrong length, or with NaN / inf entries."""

    def __init__(self, message: str, index: int | None = None):
        self.index = index
        super().__init__(message)


class InvalidTarget(QpikError, ValueError):
    """A target that is malformed (wrong shape, NaN, not a rotation)."""


class JointLimitViolation(QpikError, ValueError):
    """A configuration outside the joint limits."""

    def __init__(self, joint: str, index: int, value: float, lower: float, upper: float):
        self.joint = joint
        self.index = index
        self.value = value
        self.lower = lower
        self.upper = upper
        super().__init__(
            f"joint {joint!r} (q[{index}]) = {value:.6g} is outside its limits "
            f"[{lower:.6g}, {upper:.6g}]"
        )


class InfeasibleLimits(QpikError, ValueError):
    """Limits that no velocity can satisfy (for example lower > upper)."""


class NoSolutionFound(QpikError, RuntimeError):
    """The QP of the highest priority level could not be solved, even after fallbacks."""

    def __init__(self, solver: str, status: str, level: int = 0):
        self.solver = solver
        self.status = status
        self.level = level
        super().__init__(
            f"solver {solver!r} found no solution for priority level {level}: {status}"
        )


class ProblemFileError(QpikError, ValueError):
    """A malformed IK problem file: names the file, the field and what was expected."""

    def __init__(self, path: str, field: str, expected: str):
        self.path = path
        self.field = field
        self.expected = expected
        super().__init__(f"{path}: field {field!r}: {expected}")


class CollisionPairError(QpikError, ValueError):
    """A collision-avoidance limit that would check no geom pair: says why (the geoms'
    ``contype``/``conaffinity``, welded or parent-child bodies) and names the geoms."""


class SceneError(QpikError, ValueError):
    """An obstacle that cannot be added to a model (shape, size, position, name)."""
