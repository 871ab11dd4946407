"""Every error qpik raises derives from :class:`QpikError`.

Errors keep the fields that explain them (the joint, the value, the bounds, the valid
names) so that callers can react programmatically, and their message says what to fix.

Each error that has a counterpart in mink also subclasses it (``except
mink.NotWithinConfigurationLimits`` catches :class:`JointLimitViolation`), and can be
constructed the way mink constructs its own (``JointLimitViolation(joint_id, value, lower,
upper, model)``) as well as qpik's way. Errors pickle (they cross process boundaries in
:func:`qpik.solve_many`).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any, Literal

import mink
import mujoco
import numpy as np
from mink.constants import FRAME_TO_COUNT_ATTR, FRAME_TO_ENUM

__all__ = [
    "CollisionPairError",
    "InfeasibleLimits",
    "IntegrationTimestepNotSet",
    "InvalidArgumentType",
    "InvalidConfiguration",
    "InvalidConstraint",
    "InvalidDamping",
    "InvalidGain",
    "InvalidInput",
    "InvalidKeyframe",
    "InvalidMocapBody",
    "InvalidOption",
    "InvalidTarget",
    "JointLimitViolation",
    "LimitDefinitionError",
    "MinkFailure",
    "MissingExtra",
    "NoSolutionFound",
    "ProblemFileError",
    "QpikError",
    "RayConnectionError",
    "ReadOnlyAttribute",
    "RobotFileError",
    "SceneError",
    "TargetNotSet",
    "TaskDefinitionError",
    "UnknownFrame",
    "UnknownFrameType",
    "UnknownRobot",
    "arguments_of",
    "as_qpik_error",
    "check_task_numbers",
    "mink_errors_as_qpik",
    "qpik_errors",
]


class QpikError(Exception):
    """Root of all qpik errors."""


class MissingExtra(QpikError, ImportError):
    """An optional dependency is needed: the message names the pip extra."""

    def __init__(self, feature: str, extra: str, package: str):
        self.feature = feature
        self.extra = extra
        self.package = package
        super().__init__(
            f"{feature} needs the package {package!r}, of the qpik[{extra}] extra: from a qpik "
            f'checkout, pip install -e ".[{extra}]" (or pip install {package})'
        )


class RayConnectionError(QpikError, ConnectionError):
    """No Ray cluster could be joined at a Ray address (``address=`` of the batch entry
    points, ``--ray`` of the command line). Fields: ``address``, ``reason`` (Ray's own
    message, its first sentence) and ``forms`` (the addresses accepted, as the message
    lists them)."""

    def __init__(self, address: str | None, reason: str, forms: str = ""):
        self.address = address
        self.reason = reason
        self.forms = forms
        super().__init__(
            f"no Ray cluster could be joined at address {address!r} ({reason}): start one "
            "(ray start --head) or give the address of a running one"
            + (f": {forms}" if forms else "")
            + "; --ray ADDRESS on the command line, address= in Python"
        )

    def __reduce__(self):
        return type(self), (self.address, self.reason, self.forms)


class InvalidInput(QpikError, ValueError):
    """An argument of the wrong type, shape or range, or with NaN / inf entries; the
    message names it."""


# ---------------------------------------------------------------- constructor helpers
# The two ways an error can be constructed, as signatures (bodies unused).
def _qpik_joint_limit_violation(joint, index, value, lower, upper, *, joint_id=None, where=""): ...
def _mink_not_within_limits(joint_id, value, lower, upper, model): ...
def _qpik_unknown_frame(name, frame_type, available): ...
def _mink_invalid_frame(frame_name, frame_type, model): ...


def _has_model(args: tuple, kwargs: dict) -> bool:
    """Whether constructor arguments carry a MuJoCo model (mink's way of constructing)."""
    return any(isinstance(a, mujoco.MjModel) for a in (*args, *kwargs.values()))


def _bind(signature_of: Callable, args: tuple, kwargs: dict) -> dict[str, Any]:
    """Arguments bound by name to ``signature_of``'s signature, defaults applied."""
    bound = inspect.signature(signature_of).bind(*args, **kwargs)
    bound.apply_defaults()
    return dict(bound.arguments)


def _names_of(model: mujoco.MjModel, frame_type: str) -> list[str]:
    """Names of the frames of one type in ``model`` (unnamed ones left out)."""
    kind = str(getattr(frame_type, "value", frame_type))
    if kind not in FRAME_TO_ENUM:
        return []
    count = getattr(model, FRAME_TO_COUNT_ATTR[kind])
    names = (mujoco.mj_id2name(model, FRAME_TO_ENUM[kind], i) for i in range(count))
    return [n for n in names if n]


def _rebuild(cls: type, args: tuple, kwargs: dict) -> Exception:
    """Unpickle an error by calling its constructor (keyword arguments included)."""
    return cls(*args, **kwargs)


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
        self._erd = erd
        super().__init__(message)

    def __str__(self) -> str:  # KeyError would otherwise quote the message
        return str(self.args[0])

    def __reduce__(self):
        return type(self), (self.name, self.available, self._erd)


class RobotFileError(QpikError):
    """A robot file that cannot be read or compiled."""

    def __init__(self, path: str, reason: str):
        self.path = path
        self.reason = reason
        super().__init__(f"cannot load robot file {path}: {reason}")

    def __reduce__(self):
        return type(self), (self.path, self.reason)


def _plural(kinds: str) -> str:
    """``"body"`` -> ``"bodies"``, ``"site, body or geom"`` -> ``"sites, bodies or geoms"``."""
    words = kinds.replace(",", " ,").split()
    plural = {"body": "bodies", "site": "sites", "geom": "geoms", "frame": "frames"}
    return " ".join(plural.get(word, word) for word in words).replace(" ,", ",")


class UnknownFrame(QpikError, mink.InvalidFrame, KeyError):
    """A frame name (or id) that the model does not have, for the given frame type.

    Also a :class:`mink.InvalidFrame`. Constructed as qpik does,
    ``UnknownFrame(name, frame_type, available)``, or as mink does,
    ``UnknownFrame(frame_name, frame_type, model)``. Fields: ``name``, ``frame_type`` and
    ``available`` (the valid names of that type).
    """

    def __init__(self, *args: Any, **kwargs: Any):
        if _has_model(args, kwargs):
            bound = _bind(_mink_invalid_frame, args, kwargs)
            name, frame_type = bound["frame_name"], bound["frame_type"]
            available = _names_of(bound["model"], frame_type)
        else:
            bound = _bind(_qpik_unknown_frame, args, kwargs)
            name, frame_type, available = bound["name"], bound["frame_type"], bound["available"]
        self.name = name
        self.frame_type = frame_type
        self.available = list(available)
        Exception.__init__(
            self,
            f"{frame_type} {name!r} does not exist in the model; available "
            f"{_plural(str(frame_type))}: {', '.join(self.available) or '(none)'}",
        )

    def __str__(self) -> str:  # KeyError would otherwise quote the message
        return str(self.args[0])

    def __reduce__(self):
        return type(self), (self.name, self.frame_type, self.available)


class UnknownFrameType(QpikError, mink.UnsupportedFrame, ValueError):
    """A frame type other than body, site or geom.

    Also a :class:`mink.UnsupportedFrame`. Constructed as qpik does, from a message, or as
    mink does, ``UnknownFrameType(frame_type, supported_types)``. Fields: ``frame_type``
    (``None`` when built from a message) and ``supported``.
    """

    def __init__(self, message_or_frame_type: str, supported_types: Sequence[str] | None = None):
        if supported_types is None:
            self.frame_type = None
            self.supported = list(mink.SUPPORTED_FRAMES)
            message = message_or_frame_type
        else:
            self.frame_type = message_or_frame_type
            self.supported = list(supported_types)
            message = (
                f"unknown frame type {self.frame_type!r}; expected one of: "
                f"{', '.join(self.supported)}"
            )
        Exception.__init__(self, message)

    def __reduce__(self):
        if self.frame_type is None:
            return type(self), (str(self),)
        return type(self), (self.frame_type, self.supported)


class InvalidConfiguration(QpikError, ValueError):
    """A configuration vector of the wrong length, or with NaN / inf entries."""

    def __init__(self, message: str, index: int | None = None):
        self.index = index
        super().__init__(message)


class InvalidTarget(QpikError, mink.InvalidTarget, ValueError):
    """A target that is malformed (wrong shape, NaN, not a rotation). Also a
    :class:`mink.InvalidTarget`."""


class JointLimitViolation(QpikError, mink.NotWithinConfigurationLimits, ValueError):
    """A configuration outside the joint limits.

    Also a :class:`mink.NotWithinConfigurationLimits`. Constructed as qpik does,
    ``JointLimitViolation(joint, index, value, lower, upper)`` (joint name, qpos index), or
    as mink does, ``JointLimitViolation(joint_id, value, lower, upper, model)``. Fields:
    ``joint`` (name), ``index`` (qpos index), ``value``, ``lower``, ``upper`` [rad or m] and
    ``joint_id`` (``None`` when not given).
    """

    def __init__(self, *args: Any, **kwargs: Any):
        joint_id: int | None
        if _has_model(args, kwargs):
            bound = _bind(_mink_not_within_limits, args, kwargs)
            model, joint_id = bound["model"], int(bound["joint_id"])
            joint = model.joint(joint_id).name or f"joint{joint_id}"
            index = int(model.jnt_qposadr[joint_id])
        else:
            bound = _bind(_qpik_joint_limit_violation, args, kwargs)
            joint, index, joint_id = bound["joint"], bound["index"], bound.get("joint_id")
        self.where = str(bound.get("where", ""))  # the argument the configuration came in
        self.joint = joint
        self.index = index
        self.joint_id = joint_id
        self.value = float(bound["value"])
        self.lower = float(bound["lower"])
        self.upper = float(bound["upper"])
        Exception.__init__(
            self,
            (f"{self.where}: " if self.where else "")
            + f"joint {joint!r} (q[{index}]) = {self.value:.6g} is outside its limits "
            f"[{self.lower:.6g}, {self.upper:.6g}]",
        )

    def __reduce__(self):
        return _rebuild, (
            type(self),
            (self.joint, self.index, self.value, self.lower, self.upper),
            {"joint_id": self.joint_id, "where": self.where},
        )


class InfeasibleLimits(QpikError, ValueError):
    """Limits that no velocity can satisfy (for example lower > upper)."""


class NoSolutionFound(QpikError, mink.NoSolutionFound, RuntimeError):
    """The QP of the highest priority level could not be solved, even after fallbacks.

    Also a :class:`mink.NoSolutionFound`. Constructed as qpik does,
    ``NoSolutionFound(solver, status, level)``, or as mink does, ``NoSolutionFound(solver)``
    (then the message is mink's own, word for word). Fields: ``solver``, ``status`` (the
    backend's or the level's status, ``None`` if unknown) and ``level``.
    """

    def __init__(self, solver: str, status: str | None = None, level: int = 0):
        self.solver = solver
        self.status = None if status is None else str(status)
        self.level = level
        if status is None:
            message = f"QP solver {solver} failed to find a solution."
        else:
            message = f"solver {solver!r} found no solution for priority level {level}: {status}"
        Exception.__init__(self, message)

    def __reduce__(self):
        return type(self), (self.solver, self.status, self.level)


class InvalidOption(InvalidInput):
    """An option of :mod:`qpik.options` (or the entry-point keyword of the same name) with
    the wrong type or range, or an unknown option name. Fields: ``field`` (the option's
    name), ``value`` and ``expected`` (what it must be)."""

    def __init__(self, field: str, value: Any, expected: str, message: str | None = None):
        self.field = field
        self.value = value
        self.expected = expected
        super().__init__(message or f"{field} must be {expected}, got {value!r}")

    def __reduce__(self):
        return type(self), (self.field, self.value, self.expected, str(self))


class ProblemFileError(QpikError, ValueError):
    """A malformed IK problem file: names the file, the field and what was expected."""

    def __init__(self, path: str, field: str, expected: str):
        self.path = path
        self.field = field
        self.expected = expected
        super().__init__(f"{path}: field {field!r}: {expected}")

    def __reduce__(self):
        return type(self), (self.path, self.field, self.expected)


class CollisionPairError(QpikError, ValueError):
    """A collision-avoidance limit that would check no geom pair: says why (the geoms'
    ``contype``/``conaffinity``, welded or parent-child bodies) and names the geoms."""


class SceneError(QpikError, ValueError):
    """An obstacle that cannot be added to a model (shape, size, position, name)."""


class TargetNotSet(QpikError, mink.TargetNotSet):
    """A task used before its target was set. Also a :class:`mink.TargetNotSet`;
    constructed the same way, ``TargetNotSet(cls_name)``. Field: ``task`` (class name)."""

    def __init__(self, cls_name: str):
        self.task = cls_name
        Exception.__init__(
            self,
            f"No target set for {cls_name}: call set_target(...) or "
            "set_target_from_configuration(configuration) first",
        )

    def __reduce__(self):
        return type(self), (self.task,)


class IntegrationTimestepNotSet(QpikError, mink.IntegrationTimestepNotSet):
    """A task that needs the step ``dt`` (e.g. kinetic-energy regularisation) used before
    ``set_dt``. Also a :class:`mink.IntegrationTimestepNotSet`; constructed the same way,
    ``IntegrationTimestepNotSet(cls_name)``. Field: ``task`` (class name)."""

    def __init__(self, cls_name: str):
        self.task = cls_name
        Exception.__init__(
            self, f"No integration timestep set for {cls_name}: call set_dt(dt) first"
        )

    def __reduce__(self):
        return type(self), (self.task,)


class InvalidGain(QpikError, mink.InvalidGain, ValueError):
    """A task gain outside [0, 1]. Also a :class:`mink.InvalidGain`."""


class InvalidDamping(QpikError, mink.InvalidDamping, ValueError):
    """A damping that is negative or not finite. Also a :class:`mink.InvalidDamping`."""


class InvalidConstraint(QpikError, mink.InvalidConstraint, ValueError):
    """An equality constraint that is unknown or inactive. Also a
    :class:`mink.InvalidConstraint`."""


class TaskDefinitionError(QpikError, mink.TaskDefinitionError, ValueError):
    """An ill-formed task (cost of the wrong shape, negative cost, ...). Also a
    :class:`mink.TaskDefinitionError`."""


class LimitDefinitionError(QpikError, mink.LimitDefinitionError, ValueError):
    """An ill-formed limit (negative gain, unknown joint, ...). Also a
    :class:`mink.LimitDefinitionError`."""


class InvalidKeyframe(QpikError, mink.InvalidKeyframe, KeyError):
    """A keyframe name the model does not have. Also a :class:`mink.InvalidKeyframe`.

    Constructed as mink does, ``InvalidKeyframe(keyframe_name, model)``, or with the valid
    names, ``InvalidKeyframe(keyframe_name, available)``. Fields: ``name``, ``available``.
    """

    def __init__(self, keyframe_name: str, model_or_available: mujoco.MjModel | Sequence[str]):
        if isinstance(model_or_available, mujoco.MjModel):
            model = model_or_available
            available = [model.key(i).name for i in range(model.nkey)]
        else:
            available = list(model_or_available)
        self.name = keyframe_name
        self.available = available
        Exception.__init__(
            self,
            f"keyframe {keyframe_name!r} does not exist in the model; available keyframes: "
            f"{', '.join(available) or '(none)'}",
        )

    def __str__(self) -> str:
        return str(self.args[0])

    def __reduce__(self):
        return type(self), (self.name, self.available)


class InvalidMocapBody(QpikError, mink.InvalidMocapBody, ValueError):
    """A body that is not a mocap body. Also a :class:`mink.InvalidMocapBody`.

    Constructed as mink does, ``InvalidMocapBody(mocap_name, model)``, or with the valid
    names, ``InvalidMocapBody(mocap_name, available)``. Fields: ``name``, ``available``.
    """

    def __init__(self, mocap_name: str, model_or_available: mujoco.MjModel | Sequence[str]):
        if isinstance(model_or_available, mujoco.MjModel):
            model = model_or_available
            available = [
                model.body(i).name for i in range(model.nbody) if model.body_mocapid[i] != -1
            ]
        else:
            available = list(model_or_available)
        self.name = mocap_name
        self.available = available
        Exception.__init__(
            self,
            f"body {mocap_name!r} is not a mocap body; mocap bodies: "
            f"{', '.join(available) or '(none)'}",
        )

    def __reduce__(self):
        return type(self), (self.name, self.available)


class InvalidArgumentType(InvalidInput, TypeError):
    """An argument of the wrong type (an array where a :class:`qpik.Configuration` is
    expected, a string where a number is): names the argument and the type expected.
    An :class:`InvalidInput` (so a ``ValueError``) and also a ``TypeError``: ``except
    TypeError``, ``except ValueError`` and ``except qpik.QpikError`` all catch it. Fields:
    ``argument``, ``expected``, ``got`` (the type's name)."""

    def __init__(self, argument: str, expected: str, got: str):
        self.argument = argument
        self.expected = expected
        self.got = got
        super().__init__(f"{argument} must be {expected}, got {got}")

    def __reduce__(self):
        return type(self), (self.argument, self.expected, self.got)


class ReadOnlyAttribute(QpikError, AttributeError):
    """An attribute fixed when its object was built (``IKSolver.solver``, its ``levels``,
    ``limits``, ``rank_tolerance``, ...) was assigned: the object would go on with what it
    was built from, so the assignment is refused. Also an ``AttributeError``. Fields:
    ``owner`` (the class's name), ``attribute`` and ``hint`` (what to do instead)."""

    def __init__(self, owner: str, attribute: str, hint: str):
        self.owner = owner
        self.attribute = attribute
        self.hint = hint
        super().__init__(f"{owner}.{attribute} is fixed when the {owner} is built: {hint}")

    def __reduce__(self):
        return type(self), (self.owner, self.attribute, self.hint)


class MinkFailure(QpikError, mink.MinkError):
    """Any other mink error raised while qpik ran a mink task or limit (the message is
    mink's). Also a :class:`mink.MinkError`."""


# ------------------------------------------------------------------ mink's errors
def _task_name(error: Exception) -> str:
    """The class name at the end of mink's ``No target set for X`` messages."""
    words = str(error).split()
    return words[-1] if words else "task"


#: mink's error classes whose qpik counterpart is built from the message alone.
_BY_MESSAGE: dict[type, type] = {
    mink.InvalidTarget: InvalidTarget,
    mink.InvalidGain: InvalidGain,
    mink.InvalidDamping: InvalidDamping,
    mink.InvalidConstraint: InvalidConstraint,
    mink.TaskDefinitionError: TaskDefinitionError,
    mink.LimitDefinitionError: LimitDefinitionError,
    mink.UnsupportedFrame: UnknownFrameType,
}


def as_qpik_error(error: BaseException) -> BaseException:
    """qpik's counterpart of a mink error (which also subclasses mink's class), or
    ``error`` itself when it is already a :class:`qpik.QpikError` or not mink's."""
    if isinstance(error, QpikError) or not isinstance(error, mink.MinkError):
        return error
    if isinstance(error, mink.TargetNotSet):
        return TargetNotSet(_task_name(error))
    if isinstance(error, mink.IntegrationTimestepNotSet):
        return IntegrationTimestepNotSet(_task_name(error))
    if isinstance(error, mink.NoSolutionFound):
        words = str(error).split()
        return NoSolutionFound(words[2] if len(words) > 2 else "unknown")
    for mink_class, qpik_class in _BY_MESSAGE.items():
        if isinstance(error, mink_class):
            return qpik_class(str(error))
    return MinkFailure(str(error))


@contextmanager
def qpik_errors() -> Iterator[None]:
    """Context manager: a mink error raised inside is re-raised as :func:`as_qpik_error`
    gives it (the original chained as its ``__cause__``)."""
    try:
        yield
    except mink.MinkError as error:
        translated = as_qpik_error(error)
        if translated is error:
            raise
        raise translated from error


def check_task_numbers(what: str, arguments: Mapping[str, Any]) -> None:
    """Raise :class:`TaskDefinitionError` naming the first weight, gain or damping of
    ``arguments`` (a task constructor's, name -> value) that is not a number or an array
    of numbers (``None``, a string, a set, a model): checked before anything else of the
    task, so that such a value is named whatever the model."""
    for name in sorted(_NUMBER_ARGUMENTS & set(arguments)):
        value = arguments[name]
        if _is_number(value):
            continue
        fails = value is None or isinstance(value, (str, bytes, dict, set))
        if not fails:
            try:
                fails = np.asarray(value, dtype=float).dtype.kind != "f"
            except (TypeError, ValueError, OverflowError):
                fails = True
        if fails:
            raise TaskDefinitionError(
                f"{what}: argument {name} is not valid (got {type(value).__name__} "
                f"{_short_repr(value)}: a number, or an array of numbers, is expected)"
            )


class mink_errors_as_qpik:  # lower case: used as a context manager, like contextlib's
    """Context manager for constructors of tasks built on mink's: a mink error is re-raised
    as its qpik counterpart (:func:`as_qpik_error`, which also subclasses it; a definition
    error's message prefixed with ``what``), and a value of a wrong kind (``cost="x"``,
    ``model="panda"``) as a ``TaskDefinitionError`` naming ``what`` and, when the
    constructor's ``arguments`` (name -> value) are given, the argument at fault: a
    ``model`` that is not an ``MjModel``, else the argument whose type or value the error
    quotes."""

    def __init__(self, what: str, arguments: Mapping[str, Any] | None = None):
        self.what = what
        self.arguments = arguments

    def __enter__(self) -> None:
        return None

    def __exit__(self, kind, error, tb) -> Literal[False]:
        if error is None or isinstance(error, QpikError):
            return False
        for mink_class, qpik_class in _BY_MESSAGE.items():
            if isinstance(error, mink_class):
                raise qpik_class(f"{self.what}: {error}") from None
        if isinstance(error, mink.MinkError):
            raise as_qpik_error(error) from error
        if isinstance(error, (TypeError, ValueError, AttributeError, IndexError)):
            culprit = self._culprit(error)
            if culprit is not None:
                name, value = culprit
                raise TaskDefinitionError(
                    f"{self.what}: argument {name} is not valid (got {type(value).__name__} "
                    f"{_short_repr(value)}: {error})"
                ) from None
        if isinstance(error, TypeError) and _signature_mismatch(str(error)):
            # a call that does not fit the signature: Python's message names the arguments
            raise TaskDefinitionError(f"{self.what}: {error}") from None
        if isinstance(error, (TypeError, ValueError)):
            raise TaskDefinitionError(
                f"{self.what}: costs, gain and lm_damping must be numbers ({error})"
            ) from None
        if isinstance(error, (AttributeError, IndexError)):  # an argument of a wrong kind
            raise TaskDefinitionError(f"{self.what}: invalid argument ({error})") from None
        return False

    def _culprit(self, error: BaseException) -> tuple[str, Any] | None:
        """``(name, value)`` of the argument ``error`` is about, when one can be told."""
        arguments = {k: v for k, v in (self.arguments or {}).items() if k != "self"}
        model = arguments.get("model", mujoco.MjModel)
        if model is not mujoco.MjModel and not isinstance(model, mujoco.MjModel):
            return "model", model
        arguments.pop("model", None)  # an MjModel: right there, so another argument is wrong
        text = str(error)
        for name, value in arguments.items():  # the type the error names: 'set', 'str',
            kind = type(value).__name__  # or qualified: 'mujoco._structs.MjModel'
            named = f"'{kind}'" in text or f".{kind}'" in text
            if named and not _is_number(value):
                return name, value
        quoted = [  # the value it quotes ('x', b'x'): the longest quote, so b'ee' beats 'ee'
            (len(repr(value)), name, value)
            for name, value in arguments.items()
            if isinstance(value, (str, bytes)) and value and repr(value) in text
        ]
        if quoted:
            _, name, value = max(quoted, key=lambda item: item[0])
            return name, value
        odd = [  # the one weight or gain that is not a plain number ([1.0, 2.0], "x")
            (name, value)
            for name, value in arguments.items()
            if name in _NUMBER_ARGUMENTS and not _is_number(value)
        ]
        return odd[0] if len(odd) == 1 else None


def arguments_of(function: Callable, *args: Any, **kwargs: Any) -> dict[str, Any]:
    """``function``'s arguments by name for this call (for :class:`mink_errors_as_qpik`);
    empty when they do not fit its signature (the call itself then says so)."""
    try:
        return dict(inspect.signature(function).bind(*args, **kwargs).arguments)
    except (TypeError, ValueError):
        return {}


#: The numeric arguments of task constructors (weights, gain, damping).
_NUMBER_ARGUMENTS = frozenset({"cost", "position_cost", "orientation_cost", "gain", "lm_damping"})


def _signature_mismatch(text: str) -> bool:
    """Whether a TypeError's message is Python's for a call that does not fit a signature
    ("takes 2 positional arguments", "missing 1 required", "unexpected keyword argument"),
    not a conversion's ("float() argument must be a string or a real number")."""
    return any(
        words in text
        for words in ("positional argument", "required positional", "keyword argument", "takes ")
    )


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _short_repr(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
