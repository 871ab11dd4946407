"""Properties of qpik.analysis on any matrix and configuration (issue 13): an
InvalidInput / typed error or a finite result (``condition_number`` and
``manipulability`` may be +inf only where the exact value exceeds the float range or
sigma_min is 0), and the defining identities hold at every scale."""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from properties_common import (
    ROBOTS,
    any_float,
    assert_finite,
    load,
    props,
    q_from_unit,
    typed_or_value,
)

import qpik
from qpik import analysis as an

shapes = st.tuples(st.integers(0, 6), st.integers(0, 7))
wild = arrays(np.float64, shapes, elements=any_float)
scale = st.sampled_from([1.0, 1e-300, 1e-150, 1e150, 1e300, 5e-324, 1e308])


@st.composite
def matrices(draw):
    """Well-conditioned matrices at any scale, rank-deficient ones, and wild ones."""
    kind = draw(st.sampled_from(["scaled", "scaled", "deficient", "wild"]))
    if kind == "wild":
        return draw(wild)
    m, n = draw(st.integers(1, 6)), draw(st.integers(1, 7))
    J = draw(arrays(np.float64, (m, n), elements=st.floats(-1, 1)))
    if kind == "deficient" and min(m, n) > 1:
        U, s, Vt = np.linalg.svd(J, full_matrices=False)
        s[-1] = 0.0
        J = (U * s) @ Vt
    return J * draw(scale)


tols = st.one_of(st.none(), any_float)


@props(80)
@given(J=matrices(), tol=tols, damping=any_float, seed=st.integers(0, 1000))
def test_matrix_functions_give_invalid_input_or_finite_results(J, tol, damping, seed):
    rng = np.random.default_rng(seed)
    m, n = J.shape if J.ndim == 2 else (1, 1)
    xi = rng.normal(size=m)
    zeta = rng.normal(size=n)
    for name, call in [
        ("singular_values", lambda: an.singular_values(J)),
        ("rank", lambda: an.rank(J, tol)),
        ("null_space", lambda: an.null_space(J, tol)),
        ("degree_of_redundancy", lambda: an.degree_of_redundancy(J, tol)),
        ("pseudoinverse", lambda: an.pseudoinverse(J, tol)),
        ("damped_pseudoinverse", lambda: an.damped_pseudoinverse(J, damping)),
        ("solution_set", lambda: an.solution_set(J, xi, tol)),
        ("singularity", lambda: an.singularity(J, 1e-3 if tol is None else tol)),
        ("nullspace_step", lambda: an.nullspace_step(J, xi, zeta, tol=tol)),
    ]:
        value, error = typed_or_value(call)
        if error is None:
            assert_finite(value, name)
    for name, call in [
        ("manipulability", lambda: an.manipulability(J)),
        ("condition_number", lambda: an.condition_number(J)),
    ]:
        value, error = typed_or_value(call)
        if error is None:
            assert not math.isnan(value) and value >= 0, (name, value)


@props(40)
@given(J=matrices(), damping=st.floats(1e-12, 1e6))
def test_damped_pseudoinverse_is_bounded_and_equals_the_formula(J, damping):
    D, error = typed_or_value(lambda: an.damped_pseudoinverse(J, damping))
    if error is not None:
        return
    bound = 1.0 / (2.0 * math.sqrt(damping))
    assert np.linalg.norm(D, 2) <= bound * (1 + 1e-9)
    scale = float(np.max(np.abs(J))) if J.size else 1.0
    # the textbook formula is a reference only without overflow and on a well-conditioned
    # Gram matrix (scipy warns otherwise, and its answer is then no reference)
    if (
        1e-100 < scale < 1e100
        and np.linalg.cond(gram := J @ J.T + damping * np.eye(J.shape[0])) < 1e12
    ):
        reference = scipy.linalg.solve(gram, J, assume_a="pos").T
        np.testing.assert_allclose(D, reference, atol=1e-9 * bound, rtol=1e-7)


@props(40)
@given(J=matrices())
def test_pseudoinverse_satisfies_the_penrose_identities_at_any_scale(J):
    P, error = typed_or_value(lambda: an.pseudoinverse(J))
    if error is not None:
        return
    if an.rank(J) == 0:  # e.g. subnormal entries, under the default tol's floor
        assert not np.any(P)
        return
    scale = float(np.max(np.abs(J))) or 1.0
    Js = J / scale  # identities checked on the unit-scale matrix: P scale = (J / scale)^+
    Ps = P * scale
    np.testing.assert_allclose(Js @ Ps @ Js, Js, atol=1e-9)
    np.testing.assert_allclose(Ps @ Js @ Ps, Ps, atol=1e-9 * max(1.0, np.abs(Ps).max()) ** 2)


limits_kinds = st.sampled_from(["model", "huge", "tiny", "nan", "reversed", "inf", "mixed"])


@props(40)
@given(
    robot=st.sampled_from(ROBOTS),
    q_unit=st.lists(st.floats(0, 1), min_size=7, max_size=7),
    rows=st.sampled_from(["pose", "position", "orientation", ("vx", "vy"), (0, 0), "bogus"]),
    limits=limits_kinds,
    step_size=st.one_of(st.just(0.01), any_float),
    steps=st.integers(-1, 3),
    tol=tols,
    seed=st.integers(0, 100),
)
def test_configuration_functions_give_typed_errors_or_finite_results(
    robot, q_unit, rows, limits, step_size, steps, tol, seed
):
    model = load(robot)
    configuration = qpik.Configuration(model, q_from_unit(model, q_unit))
    lower, upper = configuration.lower, configuration.upper
    bounds = {
        "model": (lower, upper),
        "huge": (np.full(model.nq, -1e308), np.full(model.nq, 1e308)),
        "tiny": (np.full(model.nq, -1e-300), np.full(model.nq, 1e-300)),
        "nan": (np.full(model.nq, np.nan), upper),
        "reversed": (upper, lower),
        "inf": (np.full(model.nq, -np.inf), np.full(model.nq, np.inf)),
        "mixed": (np.r_[-1e308, lower[1:]], np.r_[1e-300, upper[1:]]),
    }[limits]
    for name, call in [
        ("joint_limit_distance", lambda: an.joint_limit_distance(configuration.q, *bounds)),
        (
            "joint_limit_distance_gradient",
            lambda: an.joint_limit_distance_gradient(configuration.q, *bounds),
        ),
        (
            "manipulability_gradient",
            lambda: an.manipulability_gradient(configuration, "ee", "site", rows),
        ),
        (
            "self_motion",
            lambda: an.self_motion(
                configuration,
                "ee",
                np.random.default_rng(seed).normal(size=model.nv),
                steps,
                step_size,
                rows,
            ),
        ),
    ]:
        value, error = typed_or_value(call)
        if error is None:
            assert_finite(value, name)
    report, error = typed_or_value(lambda: an.analyze(configuration, "ee", "site", rows, tol=tol))
    if error is None:
        assert_finite(report, "analyze", allow=(".condition_number",))
        assert not math.isnan(report.condition_number)
