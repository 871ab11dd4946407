"""The public names of qpik.problem and qpik.plots: __all__ matches what the modules
define (a hand-kept list must not drift), and the package's modules import cleanly."""

from __future__ import annotations

import importlib
import inspect

import pytest

import qpik.problem

MODULES = ["reader", "specs", "goals", "limits", "solver", "loader", "modes", "report"]


def _public(module) -> set[str]:
    return {
        name
        for name, value in vars(module).items()
        if not name.startswith("_")
        and not inspect.ismodule(value)
        and getattr(value, "__module__", module.__name__).startswith(module.__name__)
    }


def test_problem_all_is_importable_and_complete():
    for name in qpik.problem.__all__:
        assert hasattr(qpik.problem, name), name
    assert _public(qpik.problem) - {"annotations"} <= set(qpik.problem.__all__)
    assert qpik.load_problem is qpik.problem.load_problem


@pytest.mark.parametrize("name", MODULES)
def test_each_module_has_a_docstring(name):
    module = importlib.import_module(f"qpik.problem.{name}")
    assert module.__doc__ and len(module.__doc__.strip()) > 40


def test_plots_all_matches_its_functions():
    pytest.importorskip("matplotlib")
    from qpik import plots

    for name in plots.__all__:
        assert callable(getattr(plots, name)), name
    functions = {
        name
        for name, value in vars(plots).items()
        if inspect.isfunction(value)
        and value.__module__.startswith(plots.__name__)
        and name[0] != "_"
    }
    assert functions == {n for n in plots.__all__ if inspect.isfunction(getattr(plots, n))}
