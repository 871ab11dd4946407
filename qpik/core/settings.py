"""The settings of a :class:`qpik.core.HierarchySolver`, checked where they are set.

Each setting is a property: the constructor's keyword and an assignment afterwards go through
the same check (a value of the wrong type or range raises :class:`qpik.InvalidOption` naming
the setting; an unknown backend :class:`qpik.InvalidInput`), so that no solve starts from a
setting it cannot use. Every assignment also gives :attr:`SolverSettings.settings_version` a
new number, unique across solvers: a compiled plan that copied the settings
(:class:`qpik.diffik.compiled.CompiledPlan`) compares it with the version it copied, and
copies them again where they changed.
"""

from __future__ import annotations

import itertools
import math
import numbers
import operator
from typing import Any

from ..errors import InvalidInput, InvalidOption
from ..options import SOLVERS, DampingLaw
from . import backends

__all__ = ["SolverSettings"]

#: The settings versions, unique across solvers (one plan never mistakes another solver's
#: settings for those it copied).
_VERSIONS = itertools.count(1)


class SolverSettings:
    """The checked settings of a hierarchical solver (see the module doc)."""

    _solver: str
    _damping_law: DampingLaw | None
    _rank_tolerance: float
    _max_iter: int
    _tolerance: float
    _warm_start: bool
    _backend_options: dict
    #: A new number at every assignment of a setting, never one another solver had (the
    #: plans that copy the settings compare it).
    settings_version: int = 0
    #: A solver's arguments made from the settings, None once they change (``_changed``).
    _call_args: tuple | None = None

    def __getstate__(self) -> dict:
        """The settings (copies and pickles), without the backend workspaces (OSQP's do not
        copy or pickle; a copy makes its own at its first solve) or the solver's warm start
        (a :class:`qpik.core.HierarchySolver`'s): a copy starts cold, which changes no answer."""
        state = self.__dict__.copy()
        state["_workspaces"] = {}
        state["_call_args"] = None
        for warm in ("_warm", "_warm_row"):
            if warm in state:
                state[warm] = None
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.settings_version = next(_VERSIONS)  # (a copy's settings are its own)

    def _changed(self) -> None:
        self.settings_version = next(_VERSIONS)
        self._call_args = None
        self._workspaces: dict = {}  # (a backend's workspaces were made for the old settings)

    @property
    def damping_settings(self) -> tuple[float, float, float]:
        """:attr:`damping_law` as the kernels take it: ``(singular_threshold, max_damping,
        error_scale)``, ``error_scale`` 0 for none; ``(1, 0, 0)`` without a law."""
        law = self.damping_law
        if law is None:
            return 1.0, 0.0, 0.0
        return (
            float(law.singular_threshold),
            float(law.max_damping),
            float(law.error_scale) if law.error_scale is not None else 0.0,
        )

    @property
    def lower_trust(self) -> float:
        """:attr:`qpik.DampingLaw.lower_trust` of :attr:`damping_law` (0 without a law)."""
        law = self.damping_law
        return 0.0 if law is None else float(law.lower_trust)

    @property
    def solver(self) -> str:
        """The QP backend of the levels where a limit binds: ``"auto"`` (the exact compiled
        active set) or a name of :data:`qpik.core.SOLVERS` (its optional extra installed)."""
        return self._solver

    @solver.setter
    def solver(self, value: str) -> None:
        if not isinstance(value, str) or value not in SOLVERS:
            raise InvalidInput(f"unknown QP solver {value!r}; known solvers: {', '.join(SOLVERS)}")
        if value != "auto":  # (fail here, naming the extra a backend needs)
            backends.make_workspace(value, 1, 1, getattr(self, "_backend_options", {}))
        self._solver = value
        self._changed()

    @property
    def damping_law(self) -> DampingLaw | None:
        """The adaptive damping law (a :class:`qpik.DampingLaw`, or None for none)."""
        return self._damping_law

    @damping_law.setter
    def damping_law(self, value: DampingLaw | None) -> None:
        if value is not None and not isinstance(value, DampingLaw):
            raise InvalidOption("damping_law", value, "a qpik.DampingLaw or None")
        self._damping_law = value
        self._changed()

    @property
    def rank_tolerance(self) -> float:
        """The relative rank tolerance of each level, in ``(0, 1)``."""
        return self._rank_tolerance

    @rank_tolerance.setter
    def rank_tolerance(self, value: float) -> None:
        number = _real(value)
        if not 0.0 < number < 1.0:
            raise InvalidOption("rank_tolerance", value, "a number in (0, 1)")
        self._rank_tolerance = number
        self._changed()

    @property
    def max_iter(self) -> int:
        """The cap on active-set changes per level (an int from 0 to 10**9; 0: ``10 (n + p) +
        50``)."""
        return self._max_iter

    @max_iter.setter
    def max_iter(self, value: int) -> None:
        try:
            number = operator.index(value)
        except TypeError:
            number = -1
        if isinstance(value, bool) or not 0 <= number <= 10**9:
            raise InvalidOption("max_iter", value, "an int from 0 to 10**9 (0: the default cap)")
        self._max_iter = number
        self._changed()

    @property
    def tolerance(self) -> float:
        """The feasibility tolerance of the limits (relative, per unit row norm; finite)."""
        return self._tolerance

    @tolerance.setter
    def tolerance(self, value: float) -> None:
        number = _real(value)
        if not math.isfinite(number):
            raise InvalidOption("tolerance", value, "a finite number")
        self._tolerance = number
        self._changed()

    @property
    def warm_start(self) -> bool:
        """Whether a solve tries the previous solve's active sets first (a bool)."""
        return self._warm_start

    @warm_start.setter
    def warm_start(self, value: bool) -> None:
        if not isinstance(value, bool):
            raise InvalidOption("warm_start", value, "True or False")
        self._warm_start = value
        self._changed()

    @property
    def backend_options(self) -> dict:
        """The forced backend's settings (OSQP settings or qpsolvers keywords; a dict)."""
        return self._backend_options

    @backend_options.setter
    def backend_options(self, value: dict | None) -> None:
        if value is not None and not isinstance(value, dict):
            raise InvalidOption("backend_options", value, "a dict of backend settings or None")
        # (a forced backend's names and values, checked here: OSQP's, DAQP's, quadprog's)
        backends.check_backend_options(getattr(self, "_solver", "auto"), value)
        self._backend_options = dict(value or {})
        self._changed()


def _real(value: Any) -> float:
    """``value`` as a float where it is a real number (Python's or NumPy's, not a bool),
    else NaN (which no check passes)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return math.nan
    return float(value)
