"""Input checks shared by qpik's public entry points: one place that says what each kind
of argument may be, and one error for each way it can be wrong.

* A value of the wrong Python *type* (a string where a number is expected, an ``MjModel``
  or an array where a :class:`qpik.Configuration` is) raises
  :class:`qpik.errors.InvalidArgumentType`: a :class:`qpik.QpikError` that is also a
  ``TypeError``.
* A value of the right type outside its documented *range* (a NaN, a negative time step)
  raises :class:`qpik.InvalidOption`: a :class:`qpik.InvalidInput`, so also a
  ``ValueError``, naming the argument, the value and the range.
* An error that mink raises while qpik runs one of its tasks or limits is re-raised as
  qpik's counterpart (:func:`qpik.errors.as_qpik_error`), which also subclasses mink's:
  both kinds of ``except`` catch it.

Documented ranges (checked once, where the value enters qpik):

========================  ======================================================
``dt``                    :data:`DT_MIN` <= dt <= :data:`DT_MAX` [s]
a cost                    finite, >= 0
a gain                    in [0, 1]
a damping                 finite, >= 0
a length of the model     :data:`MAX_LENGTH` [m] at most (positions of bodies,
                          joints, sites, geoms and centres of mass)
========================  ======================================================

This module sits in the base layer: it imports only :mod:`qpik.errors` and
:mod:`qpik.options` from qpik (and NumPy, and mink for its error classes).
"""

from __future__ import annotations

import math
import operator
import os
from collections.abc import Iterable, Sequence
from typing import Any, Final, TypeVar

import numpy as np

from ..errors import (
    InvalidArgumentType,
    InvalidInput,
    InvalidOption,
    ProblemFileError,
)

__all__ = [
    "check_keywords",
    "check_matrix",
    "DT_MAX",
    "DT_MIN",
    "MAX_LENGTH",
    "check_array",
    "utf8_text",
    "check_bool",
    "check_choice",
    "check_dt",
    "check_finite_output",
    "check_frame_name",
    "check_index",
    "check_indices",
    "check_instance",
    "check_integer",
    "check_path",
    "check_real",
    "check_vector",
    "is_real",
    "type_name",
]

#: The shortest time step [s] an entry point accepts: below it ``dq / dt`` overflows for
#: displacements that are themselves representable (and no controller runs at a GHz).
DT_MIN: Final = 1e-9
#: The longest time step [s] an entry point accepts (a full-IK iteration uses ``dt = 1``).
DT_MAX: Final = 1e6
#: The largest coordinate [m] of a robot model (body, joint, site and geom positions,
#: centres of mass): beyond it products of lengths and masses overflow in MuJoCo's
#: dynamics (gravity torques, inertia) and the model cannot be a robot.
MAX_LENGTH: Final = 1e6

_T = TypeVar("_T")


def is_iterable(value: Any) -> bool:
    """Whether ``value`` can be iterated over: an ``Iterable`` that is not a 0-d NumPy
    array (which claims ``__iter__`` but raises a bare ``TypeError`` when iterated)."""
    return isinstance(value, Iterable) and not (isinstance(value, np.ndarray) and value.ndim == 0)


def type_name(value: Any) -> str:
    """The name of ``value``'s type, as error messages give it (``ndarray``, ``str``)."""
    return type(value).__name__


def is_real(value: Any) -> bool:
    """Whether ``value`` is a real number: a Python or NumPy int or float, or a 0-d
    NumPy array of one (a ``bool`` is not)."""
    if isinstance(value, (bool, np.bool_)):
        return False
    if isinstance(value, (int, float, np.integer, np.floating)):
        return True
    return isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf"


def check_instance(name: str, value: Any, cls: type[_T] | tuple[type, ...], expected: str) -> _T:
    """``value`` if it is an instance of ``cls``; else :class:`InvalidArgumentType` (a
    ``TypeError``) saying that ``name`` must be ``expected``."""
    if not isinstance(value, cls):
        raise InvalidArgumentType(name, expected, type_name(value))
    return value  # type: ignore[return-value]


def check_real(
    name: str,
    value: Any,
    minimum: float = -math.inf,
    maximum: float = math.inf,
    *,
    open_minimum: bool = False,
    unit: str = "",
) -> float:
    """``value`` as a finite float in ``[minimum, maximum]`` (``(minimum, maximum]`` with
    ``open_minimum``). Not a real number: :class:`InvalidArgumentType`; NaN, inf or out of
    range: :class:`qpik.InvalidOption`."""
    span = _span(minimum, maximum, open_minimum) + (f" [{unit}]" if unit else "")
    if not is_real(value):
        raise InvalidArgumentType(name, f"a real number{span}", type_name(value))
    try:
        number = float(value)
    except OverflowError:  # an int beyond the float range
        raise InvalidOption(name, value, f"a finite number{span}") from None
    above = number > minimum or (not open_minimum and number == minimum)
    if not (math.isfinite(number) and above and number <= maximum):
        raise InvalidOption(name, value, f"a finite number{span}")
    return number


def _span(minimum: float, maximum: float, open_minimum: bool) -> str:
    """`` > 0``, `` in [0, 1]``, ``""``: the range of :func:`check_real` in words."""
    low = ">" if open_minimum else ">="
    if math.isinf(minimum) and math.isinf(maximum):
        return ""
    if math.isinf(maximum):
        return f" {low} {minimum:g}"
    if math.isinf(minimum):
        return f" <= {maximum:g}"
    return f" in {'(' if open_minimum else '['}{minimum:g}, {maximum:g}]"


def check_dt(dt: Any, name: str = "dt") -> float:
    """The time step ``dt`` [s] as a float in [:data:`DT_MIN`, :data:`DT_MAX`]."""
    return check_real(name, dt, DT_MIN, DT_MAX, unit="s")


def check_bool(name: str, value: Any) -> bool:
    """``value`` if it is a ``bool`` (or NumPy bool); else :class:`InvalidArgumentType`."""
    if not isinstance(value, (bool, np.bool_)):
        raise InvalidArgumentType(name, "True or False", type_name(value))
    return bool(value)


def check_choice(name: str, value: Any, choices: Sequence[str]) -> str:
    """``value`` if it is one of the strings ``choices``: a non-string raises
    :class:`InvalidArgumentType`, another string :class:`qpik.InvalidOption`."""
    expected = f"one of {', '.join(map(repr, choices))}"
    if not isinstance(value, str):
        raise InvalidArgumentType(name, expected, type_name(value))
    if value not in choices:
        raise InvalidOption(name, value, expected)
    return value


def check_vector(
    name: str,
    value: Any,
    size: int | None = None,
    *,
    finite: bool = True,
    error: type[Exception] = InvalidInput,
) -> np.ndarray:
    """``value`` as a 1-D float array (of length ``size`` when given; finite unless
    ``finite=False``): the one finite-vector check of qpik.

    A wrong shape, a NaN / inf entry, or not numbers at all (a string, ``None``, objects)
    raises ``error``: a configuration check passes :class:`qpik.InvalidConfiguration`, a
    target check :class:`qpik.InvalidTarget`. With the default, :class:`qpik.InvalidInput`,
    not numbers at all raise its subclass :class:`InvalidArgumentType`."""
    expected = f"{size if size is not None else 'a vector of'} numbers"
    try:
        if value is None or isinstance(value, (str, bytes, dict)):
            raise TypeError(value)
        array = float_array(value)
    except (TypeError, ValueError):
        if error is InvalidInput:
            raise InvalidArgumentType(name, expected, type_name(value)) from None
        raise error(f"{name} must be {expected}, got {type_name(value)}") from None
    if array.ndim != 1 or (size is not None and array.shape != (size,)):
        want = f"({size},)" if size is not None else "(n,)"
        raise error(f"{name} has shape {array.shape}, expected {want}")
    if finite:
        bad = np.flatnonzero(~np.isfinite(array))
        if bad.size:
            i = int(bad[0])
            raise error(f"{name}[{i}] is {array[i]}; every entry must be finite")
    return array


def float_array(value: Any, booleans: bool = True) -> np.ndarray:
    """``value`` as a float64 array; complex numbers (whose imaginary parts a float cast
    drops), strings (which it would parse) and, with ``booleans=False``, booleans raise
    ``TypeError`` saying they are not real numbers, as what is not numbers at all does
    (``ValueError`` for a ragged nesting). The one real-numbers conversion of qpik."""
    array = value if type(value) is np.ndarray else np.asarray(value)
    if array.dtype.kind in ("cUSV" if booleans else "bcUSV"):
        raise TypeError(f"real numbers, got {array.dtype.name} values")
    return array.astype(float, copy=False)


def check_array(name: str, value: Any, expected: str, ndim: int | None = None) -> np.ndarray:
    """``value`` as a float array of any shape (the caller checks it), or of ``ndim``
    dimensions; not numbers at all: :class:`InvalidArgumentType` saying ``name`` must be
    ``expected``; other dimensions: :class:`qpik.InvalidInput`."""
    if value is None or isinstance(value, (str, bytes, dict)):
        raise InvalidArgumentType(name, expected, type_name(value))
    try:
        array = float_array(value)
    except (TypeError, ValueError):
        raise InvalidArgumentType(name, expected, type_name(value)) from None
    if ndim is not None and array.ndim != ndim:
        raise InvalidInput(f"{name} must be a {expected} array, got shape {array.shape}")
    return array


def check_matrix(name: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a finite float array of ``shape``: not numbers raises
    :class:`InvalidArgumentType`, another shape or a NaN / inf :class:`qpik.InvalidInput`,
    naming ``name``."""
    expected = "an array of shape " + str(shape)
    array = check_array(name, value, expected)
    if array.shape != shape:
        raise InvalidInput(f"{name} must have shape {shape}, got {array.shape}")
    if not np.isfinite(array).all():
        raise InvalidInput(f"{name} must be finite, got {array.tolist()}")
    return array


def utf8_text(raw: bytes, path: str, field: str, what: str) -> str:
    """The bytes of the file ``path`` as UTF-8 text, a byte-order mark dropped; else
    :class:`qpik.ProblemFileError` naming ``field``, expecting ``what``, and the first
    byte that is not UTF-8 with its line."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise ProblemFileError(
            path, field, f"{what}; byte {exc.start} (line {line}) is not valid UTF-8"
        ) from None
    return text.removeprefix("\ufeff")


def check_path(name: str, value: Any) -> str:
    """A file path: a ``str`` or an ``os.PathLike`` whose path is a ``str``, returned as
    a ``str``; anything else (``bytes`` included) raises :class:`InvalidArgumentType`."""
    expected = "a file path (str or pathlib.Path)"
    if isinstance(value, str):
        return value
    if isinstance(value, os.PathLike):
        path = os.fspath(value)
        if isinstance(path, str):
            return path
    raise InvalidArgumentType(name, expected, type_name(value))


def check_frame_name(name: str, value: Any) -> Any:
    """``value`` if it can name a frame: a ``str`` (or an int id, as mink takes); anything
    else (``None``, a list, bytes, a float, a bool) raises :class:`InvalidArgumentType`.
    Whether the frame exists is checked where it is looked up."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (str, int, np.integer)):
        raise InvalidArgumentType(name, "a frame name (a str)", type_name(value))
    return value


def check_finite_output(what: str, value: Any) -> Any:
    """``value`` if every entry is finite; else :class:`qpik.InvalidInput` saying that
    ``what`` overflowed (the inputs, e.g. the model's sizes, are beyond float range)."""
    array = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(array)):
        raise InvalidInput(
            f"{what} came out non-finite: the model or the arguments are too large to compute "
            "them in floating point (lengths beyond 1e6 m, masses or forces near 1e150?)"
        )
    return value


def check_integer(name: str, value: Any, minimum: int, maximum: int) -> int:
    """``value`` as an int in ``[minimum, maximum]``: not an int (a float, a string, a
    bool) raises :class:`InvalidArgumentType`, out of range :class:`qpik.InvalidOption`."""
    expected = f"an int in [{minimum}, {maximum}]"
    if isinstance(value, (bool, np.bool_)):
        raise InvalidArgumentType(name, expected, type_name(value))
    try:
        number = operator.index(value)
    except TypeError:
        raise InvalidArgumentType(name, expected, type_name(value)) from None
    if not minimum <= number <= maximum:
        raise InvalidOption(name, value, expected)
    return number


def check_index(name: str, value: Any, size: int) -> int:
    """``value`` as an int in ``[0, size)``: not an int raises
    :class:`InvalidArgumentType`, out of range :class:`qpik.InvalidOption`."""
    if isinstance(value, (bool, np.bool_)):
        raise InvalidArgumentType(name, f"an int in [0, {size})", type_name(value))
    try:
        index = operator.index(value)
    except TypeError:
        raise InvalidArgumentType(name, f"an int in [0, {size})", type_name(value)) from None
    if not 0 <= index < size:
        raise InvalidOption(name, value, f"an int in [0, {size})")
    return index


def check_indices(name: str, value: Any, size: int) -> list[int]:
    """``value`` as a list of distinct ints, each in ``[0, size)`` (a sequence of them; a
    string, a mapping or a non-int entry raise :class:`InvalidArgumentType`; an entry out
    of range or repeated :class:`qpik.InvalidOption`)."""
    expected = f"a sequence of distinct ints in [0, {size})"
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__iter__"):
        raise InvalidArgumentType(name, expected, type_name(value))
    indices = [check_index(f"{name}[{i}]", v, size) for i, v in enumerate(value)]
    if len(set(indices)) != len(indices):
        raise InvalidOption(name, value, expected)
    return indices


def check_keywords(where: str, given: dict[str, Any], allowed: Any) -> dict[str, Any]:
    """``given``, the ``**keywords`` of ``where``, if every name is a key of the
    ``TypedDict`` ``allowed``; else :class:`InvalidOption` naming the unknown keyword and
    listing the valid ones."""
    names = allowed.__annotations__
    for name in given:
        if name not in names:
            valid = ", ".join(sorted(names))
            raise InvalidOption(
                name, given[name], f"one of {valid}", f"{where} has no keyword {name!r} ({valid})"
            )
    return given


def check_bounds_met(lb: np.ndarray, ub: np.ndarray, G: np.ndarray, h: np.ndarray) -> None:
    """Limits with no NaN (and ``G`` finite) that some ``x`` can meet (the box's shapes
    checked before): -inf / +inf mean "no bound" only on the side they leave
    open, so ``lb = +inf``, ``ub = -inf`` or ``h = -inf`` is a bound nothing meets (a box
    or a row that cannot be meant, not an infeasible level to report), as is ``lb > ub``;
    raises :class:`qpik.InvalidInput` naming the first such entry."""
    if np.isnan(lb).any() or np.isnan(ub).any():
        raise InvalidInput("lb or ub contains NaN")
    if not np.isfinite(G).all():
        raise InvalidInput("G has a NaN or infinite entry (its rows must be finite)")
    if np.isnan(h).any():
        raise InvalidInput("h contains NaN")
    for name, values, wrong in (("lb", lb, np.inf), ("ub", ub, -np.inf), ("h", h, -np.inf)):
        bad = np.flatnonzero(values == wrong)
        if bad.size:
            raise InvalidInput(
                f"{name}[{bad[0]}] is {values[bad[0]]}: no x meets it "
                f"({'+inf' if wrong > 0 else '-inf'} is no bound only on the other side)"
            )
    crossed = np.flatnonzero(lb > ub)
    if crossed.size:
        i = crossed[0]
        raise InvalidInput(f"lb[{i}] = {lb[i]} > ub[{i}] = {ub[i]}: an empty box")


def check_level(k: int, level: Any, n: int) -> None:
    """Shapes and finiteness of :class:`qpik.core.Level` ``k`` of a problem on ``n``
    variables; raises :class:`qpik.InvalidInput` naming it."""
    try:
        A = float_array(level.A)
        b = float_array(level.b)
    except (TypeError, ValueError):
        raise InvalidInput(f"level {k} ({level.name}): A and b must be arrays of numbers") from None
    if A.ndim != 2 or A.shape[1] != n or b.shape != (A.shape[0],):
        raise InvalidInput(
            f"level {k} ({level.name}): A must be (m, {n}) and b (m,), got {A.shape} and {b.shape}"
        )
    if not (np.isfinite(A).all() and np.isfinite(b).all()):
        raise InvalidInput(f"level {k} ({level.name}): A or b is not finite")
    reg = level.regularization
    if not (is_real(reg) and math.isfinite(reg) and reg >= 0):
        raise InvalidInput(
            f"level {k} ({level.name}): regularization must be a finite number >= 0, got {reg!r}"
        )
    if level.weights is not None:
        try:
            weights = float_array(level.weights)
        except (TypeError, ValueError):
            raise InvalidInput(
                f"level {k} ({level.name}): weights must be ({A.shape[0]},) numbers"
            ) from None
        if weights.shape != (A.shape[0],):
            raise InvalidInput(f"level {k} ({level.name}): weights must be ({A.shape[0]},)")
        if not (np.isfinite(weights).all() and (weights >= 0).all()):
            raise InvalidInput(
                f"level {k} ({level.name}): weights (the rows' costs) must be finite and "
                f">= 0, got {weights}"
            )


def level_rows(A: Any, n: int) -> np.ndarray:
    """A level's checked ``A`` as a float64 ``(m, n)`` array (a 1-D row of ``n`` as one
    row); with ``n = 0``, its ``m`` empty rows (numpy cannot infer ``m`` from no entries)."""
    a = np.asarray(A, dtype=float)
    if n == 0:
        return a.reshape(a.shape[0] if a.ndim == 2 else 0, 0)
    return a.reshape(-1, n)


def as_float_dt(dt: Any) -> Any:
    """A real ``dt`` that is not a Python float (``np.float64``, as ``np.diff`` of time
    stamps gives; an int) as that float: the same step, on the paths that take a float
    only. Anything else (a bool, a string, an array) as given, for the checks to name."""
    if isinstance(dt, (int, np.integer, np.floating)) and not isinstance(dt, (bool, np.bool_)):
        return float(dt)
    return dt
