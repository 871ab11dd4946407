"""Properties of qpik.solve and qpik.solve_many on any input (issue 13): a typed error or
a valid result (finite, within the joint limits, converged only within tolerance by
independent FK), and the same answer bit for bit for the same seed."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from properties_common import (
    ROBOTS,
    any_float,
    assert_converged_claim,
    assert_finite,
    assert_within_limits,
    fk,
    load,
    not_a_number,
    props,
    q_from_unit,
    typed_or_value,
)

import qpik

unit = st.lists(st.floats(0.0, 1.0), min_size=7, max_size=7)


@st.composite
def targets(draw, model):
    """A reachable position or pose (FK of a configuration within the limits), or a
    malformed one."""
    kind = draw(st.sampled_from(["position", "pose", "pose", "bad"]))
    position, rotation = fk(model, q_from_unit(model, draw(unit)))
    if kind == "position":
        return position, None, position
    if kind == "pose":
        return (position, rotation), rotation, position
    bad = draw(
        st.one_of(
            st.lists(any_float, min_size=0, max_size=5),
            st.tuples(st.lists(any_float, min_size=3, max_size=3), st.just(np.eye(3) * 2)),
            st.just([1.0, [1.0, 0.0]]),
            st.just("abc"),
            st.just(position * 1e300),
            not_a_number,
        )
    )
    return bad, None, None


#: Option values, valid and not; solves stay short (few restarts and iterations).
options = st.fixed_dictionaries(
    {},
    optional={
        "tol_position": st.one_of(st.sampled_from([1e-4, 1e-3]), any_float, not_a_number),
        "tol_orientation": st.one_of(st.sampled_from([1e-3, 1e-2]), any_float),
        "max_iters": st.one_of(st.integers(-2, 60), st.sampled_from([2.5, "10", None])),
        "time_budget": st.one_of(st.none(), any_float, st.just("1")),
        "seed": st.one_of(st.integers(-5, 2**70), st.sampled_from([1.5, "a", None])),
        "alpha": st.one_of(st.floats(0.1, 1.0), any_float),
        "beta": st.one_of(st.floats(0.1, 1.0), any_float),
        "damping": st.one_of(st.sampled_from([1e-6, 1e-3, 0.0]), any_float),
        "max_step": st.one_of(
            st.none(),
            st.tuples(st.floats(0.01, 1.0), st.floats(0.01, 1.0)),
            st.tuples(any_float, any_float),
            st.sampled_from([(1.0,), "x"]),
        ),
        "stall_window": st.one_of(st.integers(-1, 8), st.just(1.5)),
        "solver": st.sampled_from(["osqp", "daqp", "quadprog", "nope"]),
        "frame": st.sampled_from(
            [
                "ee",
                ("ee", "site"),
                ("ee",),
                ("ee", "site", "x"),
                ("ee", "bogus"),
                None,
                3,
                "x" * 300,
            ]
        ),
    },
)


@props(40)
@given(
    robot=st.sampled_from(ROBOTS),
    data=st.data(),
    opts=options,
    restarts=st.integers(0, 1),
    q0_unit=st.one_of(st.none(), unit),
)
def test_solve_gives_a_typed_error_or_a_valid_result(robot, data, opts, restarts, q0_unit):
    model = load(robot)
    target, rotation, position = data.draw(targets(model))
    frame = opts.pop("frame", "ee")
    q0 = None if q0_unit is None else q_from_unit(model, q0_unit)
    result, error = typed_or_value(
        lambda: qpik.solve(robot, {frame: target}, q0=q0, restarts=restarts, **opts)
    )
    if error is not None:
        return
    assert result.q.shape == (model.nq,)
    assert_finite(result, "result")
    assert_within_limits(model, result.q)
    if position is not None:
        assert_converged_claim(
            model,
            result,
            "ee",
            position,
            rotation,
            opts.get("tol_position", 1e-4),
            opts.get("tol_orientation", 1e-3),
        )


@props(12)
@given(
    robot=st.sampled_from(ROBOTS),
    target_unit=unit,
    seed=st.integers(0, 2**63 - 1),
    pose=st.booleans(),
)
def test_same_seed_same_answer_whatever_ran_before(robot, target_unit, seed, pose):
    model = load(robot)
    position, rotation = fk(model, q_from_unit(model, target_unit))
    target = (position, rotation) if pose else position
    first = qpik.solve(robot, {"ee": target}, seed=seed, restarts=2)
    # other solves in between, one of them failing inside the solver
    qpik.solve(robot, {"ee": position * 0.5}, seed=seed + 1, restarts=1, max_iters=7)
    typed_or_value(lambda: qpik.solve(robot, {"ee": [math.nan, 0, 0]}))
    typed_or_value(lambda: qpik.solve(robot, {"ee": position * 1e6}, max_step=None, restarts=0))
    second = qpik.solve(robot, {"ee": target}, seed=seed, restarts=2)
    assert first.q.tobytes() == second.q.tobytes()
    assert (first.converged, first.iterations, first.reason) == (
        second.converged,
        second.iterations,
        second.reason,
    )
    assert_converged_claim(model, first, "ee", position, rotation if pose else None, 1e-4, 1e-3)


@props(8)
@given(
    robot=st.sampled_from(ROBOTS),
    units=st.lists(unit, min_size=0, max_size=3),
    seed=st.one_of(st.integers(0, 2**32), st.sampled_from([-1, None, "a", 1.5])),
    workers=st.sampled_from([None, 1, 0, -1]),
)
def test_solve_many_gives_typed_errors_or_valid_results(robot, units, seed, workers):
    model = load(robot)
    positions = [fk(model, q_from_unit(model, u))[0] for u in units]
    batch = [{"ee": p} for p in positions]
    results, error = typed_or_value(
        lambda: qpik.solve_many(
            robot, batch, seed=seed, workers=workers, progress=False, restarts=1
        )
    )
    if error is not None:
        return
    assert len(results) == len(batch)
    for result, position in zip(results, positions):
        assert_finite(result)
        assert_within_limits(model, result.q)
        assert_converged_claim(model, result, "ee", position, None, 1e-4, 1e-3)
    if isinstance(seed, int) and seed >= 0 and batch:
        again = qpik.solve_many(robot, batch, seed=seed, workers=1, progress=False, restarts=1)
        assert [r.q.tobytes() for r in again] == [r.q.tobytes() for r in results]
