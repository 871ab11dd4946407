"""qpik.options: one validated options object, its presets and its errors."""

from __future__ import annotations

import pickle

import pytest

import qpik
from qpik.core.cascade import DEFAULT_DAMPING
from qpik.options import IGM_DAMPING, PRESETS, SolveOptions, StepOptions, resolve


def test_defaults_are_those_documented():
    options = SolveOptions()
    assert (options.tol_position, options.tol_orientation) == (1e-4, 1e-3)
    assert (options.max_iters, options.restarts, options.effective_restarts) == (100, None, 100)
    assert options.iteration_budget == 21 * 100  # the work of 21 full attempts
    # restarts given, or a time budget: no iteration budget
    assert SolveOptions(restarts=20).iteration_budget is None
    assert SolveOptions(time_budget=1.0).iteration_budget is None
    assert SolveOptions(max_iters=7).iteration_budget == 21 * 7
    assert options.max_step == (0.2, 0.5) and options.limits == "joint"
    assert options.damping_law is IGM_DAMPING and options.solver == "auto"
    assert options.damping == 1e-6
    assert StepOptions().damping_law is DEFAULT_DAMPING
    assert SolveOptions(time_budget=1.0).effective_restarts == 1000
    assert PRESETS["default"] == options


def test_replace_routes_step_fields_and_keeps_the_original():
    base = SolveOptions()
    changed = base.replace(damping=1e-3, solver="osqp", max_iters=7)
    assert changed.step.damping == 1e-3 and changed.solver == "osqp" and changed.max_iters == 7
    assert base.damping == 1e-6 and base.max_iters == 100
    assert base.replace() is base


def test_presets():
    assert set(PRESETS) == {"default", "precise", "fast", "tracking"}
    assert resolve("fast") is PRESETS["fast"] and resolve(None) is PRESETS["default"]
    fast = SolveOptions.preset("fast", max_iters=3)
    assert fast.max_iters == 3 and fast.tol_position == PRESETS["fast"].tol_position
    assert PRESETS["precise"].tol_position < PRESETS["default"].tol_position
    assert PRESETS["tracking"].effective_restarts == 0
    assert PRESETS["tracking"].damping_law is DEFAULT_DAMPING  # no fading while tracking
    with pytest.raises(qpik.InvalidOption, match="preset name") as info:
        resolve("quick")
    assert info.value.field == "options"


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("tol_position", 0.0),
        ("tol_orientation", float("nan")),
        ("max_iters", -1),
        ("max_iters", 1.5),
        ("max_iters", True),
        ("time_budget", -1.0),
        ("restarts", -2),
        ("seed", -1),
        ("seed", 1.0),
        ("alpha", 1.5),
        ("beta", 0.0),
        ("stall_window", 0),
        ("max_step", (1.0,)),
        ("max_step", (1.0, -1.0)),
        ("secondary", 1),
        ("limits", "cartesian"),
        ("limits", [object()]),
        ("engine", "gpu"),
        ("solver", "gurobix"),
        ("damping", -1e-3),
        ("damping", 1e13),
        ("damping_law", 0.05),
        ("rank_tolerance", 1.0),
        ("warm_start", "yes"),
        ("backend_options", [1, 2]),
        ("bogus", 1),
    ],
)
def test_bad_values_raise_a_typed_error_naming_the_field(field, value):
    with pytest.raises(qpik.InvalidOption, match=field.split("[")[0]) as info:
        SolveOptions().replace(**{field: value})
    assert isinstance(info.value, qpik.InvalidInput) and info.value.field.startswith(field)
    clone = pickle.loads(pickle.dumps(info.value))  # errors cross process boundaries
    assert str(clone) == str(info.value) and clone.field == info.value.field


def test_options_are_hashable_values():
    a = SolveOptions(max_step=[0.1, 0.2], limits=[])
    b = SolveOptions(max_step=(0.1, 0.2), limits=())
    assert a == b and hash(a) == hash(b) and a.max_step == (0.1, 0.2)
    step = StepOptions(backend_options={"eps_abs": 1e-3})
    with pytest.raises(TypeError):
        step.backend_options["eps_abs"] = 1.0  # read-only
    hash(step)


def test_public_names_resolve():
    assert [name for name in qpik.__all__ if not hasattr(qpik, name)] == []
    for name in ("SolveOptions", "StepOptions", "PRESETS", "Reason"):
        assert name in qpik.__all__
    assert (
        "InvalidOption" in qpik.errors.__all__ and qpik.InvalidOption is qpik.errors.InvalidOption
    )
    import qpik.igm.session as session

    for name in session.__all__:
        assert hasattr(session, name), name


def test_the_option_keywords_are_the_options_fields():
    """SolveKeywords, which every entry point's signature reads, cannot drift from the
    dataclasses: one key per SolveOptions field (``seed`` aside: each entry point has its
    own) and per step field that a solve passes on to its StepOptions."""
    import dataclasses
    import typing

    from qpik.options import STEP_FIELDS, LoopKeywords, SolveKeywords

    solve_fields = {f.name for f in dataclasses.fields(SolveOptions)}
    step_fields = {f.name for f in dataclasses.fields(StepOptions)}
    assert set(SolveKeywords.__annotations__) | set(LoopKeywords.__annotations__) == (
        solve_fields - {"seed"}
    ) | set(STEP_FIELDS)
    assert set(SolveKeywords.__optional_keys__) == set(typing.get_type_hints(SolveKeywords))
    assert set(LoopKeywords.__annotations__) <= solve_fields
    assert set(STEP_FIELDS) <= step_fields
