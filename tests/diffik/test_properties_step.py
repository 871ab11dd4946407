"""Properties of IKSolver.step and qpik.solve_ik on random stacks, limits and arguments
(issue 13): a typed error or a finite velocity that keeps the next configuration within
the joint limits and every joint under its velocity limit; the same inputs give the same
velocity bit for bit, whatever ran before."""

from __future__ import annotations

import math

import mink
import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from properties_common import (
    ROBOTS,
    any_float,
    assert_finite,
    assert_within_limits,
    fk,
    limits_of,
    load,
    props,
    q_from_unit,
    typed_or_value,
)

import qpik
from qpik import tasks as T

unit = st.lists(st.floats(0.0, 1.0), min_size=7, max_size=7)
cost = st.one_of(st.sampled_from([1.0, 0.1, 0.0]), any_float)
gain = st.one_of(st.just(1.0), st.floats(0.05, 1.0), any_float)
lm_damping = st.one_of(st.sampled_from([0.0, 1e-3]), any_float)


@st.composite
def task_specs(draw):
    kind = draw(
        st.sampled_from(
            [
                "frame",
                "position",
                "orientation",
                "posture",
                "damping",
                "manipulability",
                "joint_limit_distance",
                "com",
            ]
        )
    )
    spec = {
        "type": kind,
        "target": draw(unit),
        "far": draw(st.sampled_from([None, None, None, 1e300, math.nan])),
    }
    for name, strategy in (("cost", cost), ("gain", gain), ("lm_damping", lm_damping)):
        if draw(st.booleans()) and draw(st.booleans()):
            spec[name] = draw(strategy)
    if kind == "manipulability":
        spec["rows"] = draw(st.sampled_from(["pose", "position", "orientation", "bogus"]))
    return spec


def build_task(spec: dict, model, configuration):
    kind = spec["type"]
    options = {k: spec[k] for k in ("cost", "gain", "lm_damping") if k in spec}
    position, rotation = fk(model, q_from_unit(model, spec["target"]))
    if spec["far"] is not None:
        position = np.full(3, spec["far"])
    if kind == "frame":
        options = {("position_cost" if k == "cost" else k): v for k, v in options.items()}
        task = T.FrameTask(
            "ee", "site", **{"position_cost": 1.0, "orientation_cost": 1.0, **options}
        )
        task.set_target(
            mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), position)
        )
    elif kind == "position":
        task = T.PositionTask("ee", "site", **options)
        task.set_target(position)
    elif kind == "orientation":
        task = T.OrientationTask("ee", "site", **options)
        task.set_target(rotation)
    elif kind == "posture":
        task = T.PostureTask(model, **{"cost": 1.0, **options})
        task.set_target(q_from_unit(model, spec["target"]))
    elif kind == "damping":
        task = T.DampingTask(
            model, **{"cost": 1.0, **{k: v for k, v in options.items() if k == "cost"}}
        )
    elif kind == "manipulability":
        options.pop("lm_damping", None)
        task = T.ManipulabilityTask("ee", "site", rows=spec["rows"], **options)
    elif kind == "joint_limit_distance":
        task = T.JointLimitDistanceTask(**options)
    else:
        task = T.ComTask(**{"cost": 1.0, **options})
        task.set_target(position)
    return task


limit_specs = st.lists(
    st.one_of(
        st.tuples(st.just("config"), st.one_of(st.sampled_from([0.95, 0.5, 1.0]), any_float)),
        st.tuples(st.just("velocity"), st.one_of(st.sampled_from([1.0, 0.1, 5.0]), any_float)),
    ),
    max_size=2,
)


def build_limits(model, specs):
    limits = []
    velocity = None
    for kind, value in specs:
        if kind == "config":
            limits.append(qpik.limits.ConfigurationLimit(model, gain=value))
        else:
            names = qpik.joint_names(model)
            limits.append(qpik.limits.VelocityLimit(model, {n: value for n in names}))
            velocity = value
    return limits, velocity


@props(40)
@given(
    robot=st.sampled_from(ROBOTS),
    levels=st.lists(st.lists(task_specs(), min_size=1, max_size=2), min_size=1, max_size=3),
    limit_spec=limit_specs,
    q_unit=unit,
    dt=st.one_of(st.sampled_from([0.01, 0.002, 0.1]), any_float),
    solver=st.sampled_from(["osqp", "daqp", "quadprog"]),
    damping=st.one_of(st.sampled_from([1e-6, 1e-3, 0.0]), any_float),
    entry=st.sampled_from(["step", "solve_ik"]),
)
def test_step_gives_a_typed_error_or_a_safe_finite_velocity(
    robot, levels, limit_spec, q_unit, dt, solver, damping, entry
):
    model = load(robot)
    configuration = qpik.Configuration(model, q_from_unit(model, q_unit))

    def step():
        stack = [[build_task(t, model, configuration) for t in level] for level in levels]
        limits, _ = build_limits(model, limit_spec)
        if entry == "solve_ik":
            return np.asarray(
                qpik.solve_ik(
                    configuration, stack, dt, limits=limits, solver=solver, damping=damping
                )
            )
        result = qpik.IKSolver(model, stack, limits, solver=solver, damping=damping).step(
            configuration, dt
        )
        assert_finite(result, "step", allow=(".solve_time",))
        return np.asarray(result.velocity)

    velocity, error = typed_or_value(step)
    if error is not None:
        return
    assert velocity.shape == (model.nv,)
    assert_finite(velocity, "velocity")
    _, v_max = build_limits(model, limit_spec)
    if v_max is not None:
        assert np.max(np.abs(velocity)) <= v_max * (1 + 1e-6) + 1e-12
    if any(kind == "config" for kind, _ in limit_spec):
        q_next = configuration.integrate(velocity, dt)
        assert_within_limits(model, q_next, "q after the step", tol=1e-7)


@props(15)
@given(
    robot=st.sampled_from(ROBOTS),
    target_unit=unit,
    q_unit=unit,
    solver=st.sampled_from(["osqp", "daqp", "quadprog"]),
)
def test_same_inputs_same_velocity_whatever_ran_before(robot, target_unit, q_unit, solver):
    model = load(robot)
    position, rotation = fk(model, q_from_unit(model, target_unit))
    q = q_from_unit(model, q_unit)

    def velocity():
        task = T.FrameTask("ee", "site", position_cost=1.0, orientation_cost=0.5)
        task.set_target(
            mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), position)
        )
        posture = T.PostureTask(model, cost=1e-2)
        posture.set_target(q_from_unit(model, np.full(7, 0.5)))
        solver_ = qpik.IKSolver(
            model, [[task], [posture]], [qpik.limits.ConfigurationLimit(model)], solver=solver
        )
        return solver_.step(qpik.Configuration(model, q), 0.01).velocity.copy()

    first = velocity()
    # unrelated work in between, including a failing step
    typed_or_value(lambda: qpik.solve(robot, {"ee": position * 1e6}, max_step=None, restarts=0))
    bad = T.PositionTask("ee", "site")
    bad.set_target(np.full(3, 1e300))
    typed_or_value(
        lambda: qpik.IKSolver(model, [[bad]], solver=solver).step(
            qpik.Configuration(model, q), 0.01
        )
    )
    assert first.tobytes() == velocity().tobytes()
    lower, upper = limits_of(model)
    assert np.all(np.isfinite(first))
    del lower, upper
