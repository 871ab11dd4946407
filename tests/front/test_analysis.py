"""qpik.analysis reproduces the lecture "The Jacobian matrix (a tool for analysis)"."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import configuration_of
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import qpik
from qpik import analysis as an
from qpik.errors import InfeasibleLimits, InvalidInput

A = np.array([[1.0, 2.0], [3.0, 6.0]])
Q1 = np.array([0.76, 0.90, 0.69, 1.19])
Q9 = np.array([1.81, 2.06, -1.70, -1.16])
PLANAR = ("vx", "vy")


def planar_2r_jacobian(q1: float, q2: float) -> np.ndarray:
    return configuration_of("planar_2r", [q1, q2]).frame_jacobian("ee")[:2]


def finite_difference(f, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    return np.array([(f(q + h * e) - f(q - h * e)) / (2 * h) for e in np.eye(q.size)])


# ------------------------------------------------------------- A x = b (case 1)
def test_singular_square_system_without_solution():
    solutions = an.solution_set(A, [3.0, 2.0])
    assert solutions.kind == "none" and solutions.rank == 1
    assert solutions.residual > 1.0
    # the least-squares solution: J^T (J x - b) = 0
    np.testing.assert_allclose(A.T @ (A @ solutions.particular - [3.0, 2.0]), 0, atol=1e-12)


def test_singular_square_system_with_infinitely_many_solutions():
    b = np.array([3.0, 9.0])
    solutions = an.solution_set(A, b)
    assert solutions.kind == "infinite" and solutions.rank == 1
    np.testing.assert_allclose(A @ solutions.particular, b, atol=1e-12)
    assert solutions.null_basis.shape == (2, 1)
    direction = solutions.null_basis[:, 0] * np.sign(solutions.null_basis[0, 0])
    np.testing.assert_allclose(direction, np.array([2.0, -1.0]) / np.sqrt(5), atol=1e-12)
    # the particular solution has the least norm: it is orthogonal to N(A)
    assert abs(solutions.particular @ direction) < 1e-12
    np.testing.assert_allclose(A @ solutions.general([7.5]), b, atol=1e-12)
    assert np.linalg.det(A) == pytest.approx(0.0, abs=1e-12)


def test_nonsingular_square_system_has_a_unique_solution():
    J = planar_2r_jacobian(0.3, 1.2)
    solutions = an.solution_set(J, [0.1, -0.2])
    assert solutions.kind == "unique" and solutions.null_basis.shape == (2, 0)
    np.testing.assert_allclose(solutions.particular, np.linalg.solve(J, [0.1, -0.2]))


def test_rectangular_system_cases():
    J = configuration_of("planar_4r", Q1).frame_jacobian("ee")[:2]  # 2 x 4, m < n
    solutions = an.solution_set(J, [0.3, -0.1])
    assert solutions.kind == "infinite" and solutions.null_basis.shape == (4, 2)
    np.testing.assert_allclose(J @ solutions.general([1.0, -2.0]), [0.3, -0.1], atol=1e-12)
    # with the z row, vz is not in the range of J: no solution
    J3 = configuration_of("planar_4r", Q1).frame_jacobian("ee")[:3]
    assert an.solution_set(J3, [0.3, -0.1, 1.0]).kind == "none"
    assert an.solution_set(J3, [0.3, -0.1, 0.0]).kind == "infinite"


# ------------------------------------------------------------------- 2R singularity
def test_planar_2r_determinant_is_sin_q2(rng):
    for q1, q2 in rng.uniform(-np.pi, np.pi, size=(20, 2)):
        J = planar_2r_jacobian(q1, q2)
        assert np.linalg.det(J) == pytest.approx(np.sin(q2), abs=1e-12)
        assert an.manipulability(J) == pytest.approx(abs(np.sin(q2)), abs=1e-12)
        assert an.rank(J) == 2


@pytest.mark.parametrize("q2", [0.0, np.pi, -np.pi])
def test_planar_2r_loses_rank_exactly_at_q2_0_and_pi(q2, rng):
    for q1 in rng.uniform(-np.pi, np.pi, size=5):
        J = planar_2r_jacobian(q1, q2)
        assert an.rank(J) == 1
        assert an.degree_of_redundancy(J) == 1
        assert an.condition_number(J) > 1e12
        report = an.singularity(J)
        assert report.singular and report.rank == 1
        # stretched (q2 = 0): the lost direction is radial, along the arm
        radial = np.array([np.cos(q1), np.sin(q1)])
        assert abs(report.lost_directions[:, 0] @ radial) == pytest.approx(1.0, abs=1e-9)
        np.testing.assert_allclose(J @ report.null_motions, 0, atol=1e-12)


def test_planar_2r_near_singularity_matches_the_lecture_digits():
    J = planar_2r_jacobian(np.pi / 4, 0.001)
    np.testing.assert_array_equal(np.round(J, 4), [[-1.4149, -0.7078], [1.4135, 0.7064]])
    inverse = np.linalg.inv(J)
    np.testing.assert_array_equal(
        np.round(inverse / 1000, 4), [[0.7064, 0.7078], [-1.4135, -1.4149]]
    )
    np.testing.assert_allclose(an.pseudoinverse(J), inverse, rtol=1e-9)
    assert an.rank(J) == 2  # numerically full rank...
    report = an.singularity(J)  # ...but flagged as near a singularity
    assert report.singular and report.rank == 1  # rank at tol = 1e-3
    # the joint motion that (nearly) produces nothing: q1 one way, q2 twice the other
    motion = report.null_motions[:, 0] * np.sign(report.null_motions[0, 0])
    np.testing.assert_allclose(motion, np.array([1.0, -2.0]) / np.sqrt(5), atol=1e-3)
    assert report.sigma_min == pytest.approx(np.sin(0.001) / np.linalg.norm(J, 2), rel=1e-3)
    assert an.condition_number(J) > 1000
    assert not an.singularity(planar_2r_jacobian(np.pi / 4, 1.0)).singular


@pytest.mark.parametrize("damping", [1e-4, 1e-2, 1.0])
def test_damped_pseudoinverse_stays_bounded_where_the_inverse_explodes(damping):
    bound = 1 / (2 * np.sqrt(damping))
    for q2 in (0.001, 0.0, 1e-8, np.pi):
        J = planar_2r_jacobian(np.pi / 4, q2)
        assert np.linalg.norm(an.damped_pseudoinverse(J, damping), 2) <= bound * (1 + 1e-12)
    J = planar_2r_jacobian(np.pi / 4, 0.001)
    assert np.abs(np.linalg.inv(J)).max() > 1000
    assert np.linalg.norm(np.linalg.inv(J), 2) > 1000 > 1 / (2 * np.sqrt(1e-4)) == 50


def test_damped_pseudoinverse_bound_is_attained_and_formula():
    damping = 0.04
    J = np.diag([np.sqrt(damping), 3.0])  # a singular value equal to sqrt(damping)
    norm = np.linalg.norm(an.damped_pseudoinverse(J, damping), 2)
    assert norm == pytest.approx(1 / (2 * np.sqrt(damping)), rel=1e-12)
    J = np.random.default_rng(1).normal(size=(3, 5))
    expected = J.T @ np.linalg.inv(J @ J.T + damping * np.eye(3))
    np.testing.assert_allclose(an.damped_pseudoinverse(J, damping), expected, atol=1e-12)


# ------------------------------------------------------- 4R redundancy and self-motion
def test_planar_4r_position_task_has_redundancy_2():
    configuration = configuration_of("planar_4r", Q1)
    J = configuration.frame_jacobian("ee")[:3]
    assert an.degree_of_redundancy(J) == 2
    report = an.analyze(configuration, "ee", rows="position")
    assert report.rank == 2 and report.redundancy == 2
    # the out-of-plane row vz is the one lost direction
    assert report.singular
    np.testing.assert_allclose(np.abs(report.lost_directions[:, 0]), [0, 0, 1], atol=1e-12)
    planar = an.analyze(configuration, "ee", rows=PLANAR)
    assert planar.rank == 2 and planar.redundancy == 2 and not planar.singular


@pytest.mark.parametrize("q", [Q1, Q9])
def test_lecture_configurations_reach_p_e(q):
    position, _ = configuration_of("planar_4r", q).frame_pose("ee")
    np.testing.assert_allclose(position, [-1.0, 2.0, 0.0], atol=0.03)


def test_self_motion_keeps_the_tip_still_while_q_moves():
    configuration = configuration_of("planar_4r", Q1)
    start, _ = configuration.frame_pose("ee")
    path = an.self_motion(configuration, "ee", -np.ones(4), steps=500, step_size=0.01)
    assert path.shape == (501, 4)
    np.testing.assert_array_equal(path[0], Q1)
    np.testing.assert_array_equal(configuration.q, Q1)  # the caller's q is unchanged
    probe = configuration.copy()
    drift = []
    for q in path:
        probe.update(q)
        drift.append(np.linalg.norm(probe.frame_pose("ee")[0] - start))
    assert max(drift) < 1e-6
    assert np.linalg.norm(path[-1] - path[0]) >= 1.0
    assert np.abs(np.diff(path, axis=0)).sum() >= 1.0
    # each step is a null-space motion: small and steady
    assert np.linalg.norm(np.diff(path, axis=0), axis=1).max() < 0.05


def test_self_motion_pose_rows_keep_the_panda_hand_still(rng):
    configuration = configuration_of("panda", [0.0, 0.2, 0.0, -1.8, 0.0, 2.0, 0.8])
    start, rotation = configuration.frame_pose("ee")
    zeta = rng.normal(size=7)
    path = an.self_motion(configuration, "ee", zeta, steps=50, step_size=0.02, rows="pose")
    probe = configuration.copy()
    probe.update(path[-1])
    position, rotation_end = probe.frame_pose("ee")
    assert np.linalg.norm(position - start) < 1e-6
    assert np.linalg.norm(rotation_end - rotation) < 1e-6
    assert np.linalg.norm(path[-1] - path[0]) > 0.05


def test_nullspace_step_solves_the_task_and_keeps_zeta_in_the_null_space(rng):
    J = configuration_of("panda", [0.0, 0.2, 0.0, -1.8, 0.0, 2.0, 0.8]).frame_jacobian("ee")
    xi = rng.normal(size=6)
    zeta = rng.normal(size=7)
    qdot = an.nullspace_step(J, xi, zeta)
    np.testing.assert_allclose(J @ qdot, xi, atol=1e-10)
    N = an.null_space(J)
    np.testing.assert_allclose(qdot - an.pseudoinverse(J) @ xi, N @ (N.T @ zeta), atol=1e-10)


# -------------------------------------------------------------- 7-DoF arm, pose task
def test_panda_pose_task_has_redundancy_1(rng):
    configuration = configuration_of("panda")
    checked = 0
    while checked < 5:
        configuration.update(configuration.random_q(rng))
        J = configuration.frame_jacobian("ee")
        if an.singular_values(J)[-1] < 0.05:
            continue  # away from singularities
        checked += 1
        N = an.null_space(J)
        assert N.shape == (7, 1) and an.degree_of_redundancy(J) == 1
        np.testing.assert_allclose(J @ N, 0, atol=1e-12)
        np.testing.assert_allclose(N.T @ N, np.eye(1), atol=1e-12)
        report = an.analyze(configuration, "ee")
        assert (report.rank, report.redundancy, report.singular) == (6, 1, False)


# ------------------------------------------------------------------ properties
@st.composite
def wide_matrices(draw) -> np.ndarray:
    m = draw(st.integers(1, 6))
    n = draw(st.integers(m, 8))
    elements = st.floats(-10, 10, allow_nan=False, allow_infinity=False)
    J = draw(arrays(float, (m, n), elements=elements))
    if draw(st.booleans()) and m > 1:  # make it rank deficient: a repeated row
        J[-1] = J[0]
    return J


@settings(max_examples=150, deadline=None)
@given(wide_matrices())
def test_rank_nullity_and_pseudoinverse_properties(J):
    m, n = J.shape
    N = an.null_space(J)
    r = an.rank(J)
    assert r + N.shape[1] == n
    assert an.degree_of_redundancy(J) == N.shape[1] <= n
    np.testing.assert_allclose(N.T @ N, np.eye(N.shape[1]), atol=1e-10)
    scale = max(1.0, np.abs(J).max())
    np.testing.assert_allclose(J @ N, 0, atol=1e-10 * scale)
    pinv = an.pseudoinverse(J)
    assert pinv.shape == (n, m)
    # rounding error of J J^+ J grows with the condition of the part that is inverted
    s = an.singular_values(J)[:r]
    kept_condition = s[0] / s[-1] if r else 1.0
    np.testing.assert_allclose(J @ pinv @ J, J, atol=1e-12 * scale * kept_condition)


@settings(max_examples=100, deadline=None)
@given(wide_matrices(), st.floats(1e-6, 10.0))
def test_damped_pseudoinverse_bound_holds_for_any_matrix(J, damping):
    norm = np.linalg.norm(an.damped_pseudoinverse(J, damping), 2)
    assert norm <= 1 / (2 * np.sqrt(damping)) * (1 + 1e-9)


def test_manipulability_and_condition_number_edge_cases():
    assert an.manipulability(np.ones((3, 2))) == 0.0  # m > n: sqrt det J J^T = 0
    assert an.condition_number(A) == np.inf or an.condition_number(A) > 1e15
    assert an.condition_number(np.zeros((2, 3))) == np.inf
    np.testing.assert_array_equal(an.null_space(np.zeros((2, 3))), np.eye(3))
    assert an.rank(np.zeros((2, 3))) == 0
    J = np.diag([2.0, 0.5])
    assert an.manipulability(J) == pytest.approx(1.0)
    assert an.condition_number(J) == pytest.approx(4.0)
    assert an.rank(np.diag([1.0, 1e-4]), tol=1e-3) == 1
    assert an.null_space(np.diag([1.0, 1e-4]), tol=1e-3).shape == (2, 1)
    np.testing.assert_allclose(an.pseudoinverse(np.diag([1.0, 1e-4]), tol=1e-3), np.diag([1, 0]))


# -------------------------------------------------------------- secondary criteria
def test_joint_limit_distance_is_the_liegeois_measure():
    lower = np.array([-1.0, 0.0, -np.inf, 2.0])
    upper = np.array([1.0, 4.0, np.inf, 2.0])
    assert an.joint_limit_distance([0.0, 2.0, 123.0, 2.0], lower, upper) == 0.0
    # at a limit each limited joint contributes (1/2)^2; n = 4 joints
    assert an.joint_limit_distance([1.0, 0.0, 0.0, 2.0], lower, upper) == pytest.approx(
        (0.25 + 0.25) / 8
    )
    q = np.array([0.3, 3.1, -5.0, 2.0])
    expected = ((0.3 / 2) ** 2 + (1.1 / 4) ** 2) / 8
    assert an.joint_limit_distance(q, lower, upper) == pytest.approx(expected)
    gradient = an.joint_limit_distance_gradient(q, lower, upper)
    np.testing.assert_allclose(
        gradient, finite_difference(lambda x: an.joint_limit_distance(x, lower, upper), q)
    )
    assert gradient[2] == gradient[3] == 0.0


def test_joint_limit_distance_on_a_robot(rng):
    configuration = configuration_of("panda")
    lower, upper = configuration.lower, configuration.upper
    assert an.joint_limit_distance(configuration.mid_q(), lower, upper) == 0.0
    assert an.joint_limit_distance(lower, lower, upper) == pytest.approx(1 / 8)
    q = configuration.random_q(rng)
    gradient = an.joint_limit_distance_gradient(q, lower, upper)
    assert gradient.shape == (7,)
    # moving against the gradient moves away from the limits
    assert an.joint_limit_distance(q - 0.1 * gradient, lower, upper) < an.joint_limit_distance(
        q, lower, upper
    )


def test_joint_limit_distance_rejects_bad_limits():
    with pytest.raises(InfeasibleLimits, match=r"lower\[1\]"):
        an.joint_limit_distance([0.0, 0.0], [-1.0, 1.0], [1.0, 0.0])
    with pytest.raises(InvalidInput, match="expected"):
        an.joint_limit_distance_gradient([0.0, 0.0], [-1.0], [1.0])
    with pytest.raises(InvalidInput, match="nan"):
        an.joint_limit_distance([np.nan], [-1.0], [1.0])


@pytest.mark.parametrize(
    "robot, frame_type, frame, rows",
    [
        ("panda", "site", "ee", "pose"),
        ("panda", "site", "ee", "position"),
        ("panda", "body", "link5", "position"),
        ("ur5e", "site", "ee", "pose"),
        ("planar_4r", "site", "ee", PLANAR),
    ],
)
def test_manipulability_gradient_matches_finite_differences(robot, frame_type, frame, rows, rng):
    configuration = configuration_of(robot)
    configuration.update(configuration.random_q(rng))
    q0 = configuration.q
    idx = list(an.row_indices(rows))
    probe = configuration.copy()

    def w(q):
        probe.update(q)
        return an.manipulability(probe.frame_jacobian(frame, frame_type)[idx])

    gradient = an.manipulability_gradient(configuration, frame, frame_type, rows)
    np.testing.assert_allclose(gradient, finite_difference(w, q0), atol=1e-7)
    np.testing.assert_array_equal(configuration.q, q0)  # the caller's q is unchanged


def test_manipulability_gradient_of_the_2r_is_cos_q2():
    configuration = configuration_of("planar_2r", [0.4, 0.7])
    gradient = an.manipulability_gradient(configuration, "ee", rows=PLANAR)
    np.testing.assert_allclose(gradient, [0.0, np.cos(0.7)], atol=1e-12)
    # pose rows on a planar arm: m > n, w = 0 everywhere
    np.testing.assert_array_equal(an.manipulability_gradient(configuration, "ee"), [0, 0])


# -------------------------------------------------------------------- the report
def test_analyze_report_and_its_text():
    configuration = configuration_of("panda", [0.0, 0.2, 0.0, -1.8, 0.0, 2.0, 0.8])
    report = an.analyze(configuration, "ee")
    J = configuration.frame_jacobian("ee")
    assert report.rows == an.ROW_NAMES and report.jacobian.shape == (6, 7)
    np.testing.assert_allclose(report.singular_values, np.linalg.svd(J, compute_uv=False))
    assert report.manipulability == pytest.approx(np.sqrt(np.linalg.det(J @ J.T)))
    assert report.condition_number == pytest.approx(np.linalg.cond(J))
    text = str(report)
    assert "degree of redundancy  1" in text and "singular              no" in text
    near = str(an.analyze(configuration_of("planar_2r", [np.pi / 4, 0.001]), "ee", rows=PLANAR))
    assert "near a singularity" in near and "0.707 vx + 0.708 vy" in near
    at = str(an.analyze(configuration_of("planar_2r", [0.3, 0.0]), "ee", rows=PLANAR))
    assert "at a singularity, rank 1 < 2" in at


def test_public_api():
    assert qpik.analysis is an
    for name in an.__all__:
        assert hasattr(an, name), name
    assert "analysis" in qpik.__all__


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    "call, fragment",
    [
        (lambda: an.rank([[1.0, np.nan]]), r"J\[0, 1\] is nan"),
        (lambda: an.null_space([1.0, 2.0]), r"shape \(2,\), expected a 2-D"),
        (lambda: an.singular_values(np.zeros((0, 3))), "m, n >= 1"),
        (lambda: an.solution_set(A, [1.0, 2.0, 3.0]), r"xi has shape \(3,\), expected \(2,\)"),
        (lambda: an.solution_set(A, [1.0, np.inf]), r"xi\[1\] is inf"),
        (lambda: an.nullspace_step(A, [1.0, 2.0], [1.0]), r"zeta has shape"),
        (lambda: an.damped_pseudoinverse(A, 0.0), "must be > 0"),
        (lambda: an.rank(A, tol=-1.0), "tol is -1.0"),
        (lambda: an.rank([["a", "b"]]), "not a numeric matrix"),
    ],
)
def test_bad_input_raises_invalid_input(call, fragment):
    with pytest.raises(InvalidInput, match=fragment) as info:
        call()
    assert isinstance(info.value, qpik.QpikError) and isinstance(info.value, ValueError)


def test_bad_rows_and_frames():
    configuration = configuration_of("planar_4r", Q1)
    with pytest.raises(InvalidInput, match="expected one of: pose, position"):
        an.analyze(configuration, "ee", rows="linear")
    with pytest.raises(InvalidInput, match="rows are named vx vy vz wx wy wz"):
        an.analyze(configuration, "ee", rows=("vx", "q"))
    with pytest.raises(qpik.UnknownFrame, match="available sites: ee"):
        an.self_motion(configuration, "tip", np.ones(4))
    with pytest.raises(InvalidInput, match=r"zeta has shape \(3,\), expected \(4,\)"):
        an.self_motion(configuration, "ee", np.ones(3))
    with pytest.raises(TypeError, match="qpik.Configuration"):
        an.analyze(np.zeros(4), "ee")


# ------------------------------------------------------- extreme scales (issue 13)
@pytest.mark.parametrize("scale", [1e-300, 1e-150, 1e150, 1e300])
def test_matrix_functions_are_exact_at_extreme_scales(scale):
    rng = np.random.default_rng(3)
    J = rng.normal(size=(3, 5))
    s = an.singular_values(J)
    np.testing.assert_allclose(an.singular_values(J * scale), s * scale, rtol=1e-13)
    np.testing.assert_allclose(an.pseudoinverse(J * scale) * scale, an.pseudoinverse(J), rtol=1e-12)
    np.testing.assert_allclose(
        an.null_space(J * scale) @ an.null_space(J * scale).T,
        an.null_space(J) @ an.null_space(J).T,
        atol=1e-13,
    )
    assert an.rank(J * scale) == 3 and an.degree_of_redundancy(J * scale) == 2
    np.testing.assert_allclose(an.condition_number(J * scale), s[0] / s[-1], rtol=1e-12)
    if abs(np.log10(scale)) <= 150:  # D(c J, c^2 d) = D(J, d) / c
        np.testing.assert_allclose(
            an.damped_pseudoinverse(J * scale, 0.1 * scale**2) * scale,
            an.damped_pseudoinverse(J, 0.1),
            rtol=1e-12,
        )
    report = an.singularity(J * scale, tol=1e-3 * scale)
    assert np.isfinite(report.sigma_min) and not report.singular


def test_damped_pseudoinverse_of_huge_and_tiny_matrices_is_finite_and_bounded():
    rng = np.random.default_rng(4)
    J = rng.normal(size=(6, 7))
    for scale, damping in [(1e200, 1e-3), (1e-200, 1e-3), (1e300, 1e300), (1.0, 1e300)]:
        D = an.damped_pseudoinverse(J * scale, damping)
        assert np.all(np.isfinite(D))
        assert np.linalg.norm(D, 2) <= 1 / (2 * np.sqrt(damping)) * (1 + 1e-12)
    # s / (s^2 + d) ~ 1 / s for huge singular values: D ~ pinv
    np.testing.assert_allclose(
        an.damped_pseudoinverse(J * 1e200, 1e-3) * 1e200, an.pseudoinverse(J), rtol=1e-10
    )


def test_manipulability_in_logs_does_not_overflow_early():
    J = np.diag([1e200, 1e-100, 1e-90])
    assert an.manipulability(J) == pytest.approx(1e10, rel=1e-12)
    assert an.manipulability(np.diag([1e200, 1e200])) == np.inf  # exceeds the float range
    assert an.manipulability(np.diag([1e-200, 1e-200])) == 0.0  # underflows, as it should


def test_joint_limit_distance_with_limits_near_the_float_range():
    q = np.array([1e307, -1e307, 0.5])
    lower = np.array([-1e308, -1e308, 0.0])
    upper = np.array([1e308, 1e308, 1.0])
    w = an.joint_limit_distance(q, lower, upper)
    gradient = an.joint_limit_distance_gradient(q, lower, upper)
    assert w == pytest.approx((0.05**2 + 0.05**2) / 6, rel=1e-12)
    # (q - mid) / (n span^2) = ratio / (n span), span = 2e308 (itself beyond the range)
    expected = [0.05 / 3 / 1e308 / 2, -0.05 / 3 / 1e308 / 2, 0.0]
    np.testing.assert_allclose(gradient, expected, rtol=1e-12)


@pytest.mark.parametrize(
    "call",
    [
        lambda: an.solution_set(np.eye(2) * 1e-300, [1e300, 0.0]),
        lambda: an.pseudoinverse(np.eye(2) * 1e-310, tol=0.0),
        lambda: an.joint_limit_distance([1e300], [0.0], [1e-300]),
        lambda: an.joint_limit_distance_gradient([1.0], [0.0], [1e-300]),
        lambda: an.singular_values(np.full((2, 2), 1.7e308)),
    ],
)
def test_results_beyond_the_float_range_raise_invalid_input(call):
    with pytest.raises(InvalidInput, match="overflows the float range"):
        call()


@pytest.mark.parametrize(
    "call",
    [
        lambda: an.rank(A, tol="x"),
        lambda: an.null_space(A, tol=[1.0]),
        lambda: an.damped_pseudoinverse(A, "x"),
        lambda: an.damped_pseudoinverse(A, None),
    ],
)
def test_non_numeric_tol_and_damping_raise_invalid_input(call):
    with pytest.raises(InvalidInput):
        call()


def test_wrong_configuration_type_is_a_typed_type_error():
    with pytest.raises(qpik.errors.InvalidArgumentType, match="configuration must be") as info:
        an.manipulability_gradient(np.zeros(4), "ee")
    assert isinstance(info.value, TypeError) and isinstance(info.value, qpik.QpikError)


_SLIDE_ARM = """<mujoco><compiler angle="radian"/><worldbody>
<body name="cart"><joint name="rail" type="slide" axis="1 0 0" range="-1 1"/>
  <geom type="box" size="0.1 0.1 0.05"/>
  <body name="l1" pos="0 0 0.1"><joint name="j1" axis="0 0 1" range="-3 3"/>
    <joint name="j2" axis="0 1 0" range="-2 2"/>
    <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
    <body name="l2" pos="0.3 0 0"><joint name="lift" type="slide" axis="0 0 1" range="-0.2 0.2"/>
      <joint name="j3" axis="1 0 0" range="-3 3"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
      <site name="ee" pos="0.3 0.05 0"/></body></body></body>
</worldbody></mujoco>"""


@pytest.mark.parametrize("robot", ["panda", "ur5e", "slide_arm"])
def test_manipulability_gradient_in_closed_form_is_mj_jacdots(robot, rng, monkeypatch):
    """On a chain of hinges and slides the gradient comes from the kinematic Hessian in
    closed form (``gradients._chain_gradient``): equal to the sum over ``mj_jacDot`` at
    each joint velocity ``e_k`` (the way taken for ball and free joints) to round-off, on
    random configurations, for every row choice (slides and two joints on one body too)."""
    import mujoco

    from qpik.model import gradients

    if robot == "slide_arm":
        configuration = qpik.Configuration(mujoco.MjModel.from_xml_string(_SLIDE_ARM))
    else:
        configuration = configuration_of(robot)
    states = [configuration.random_q(rng) for _ in range(30)]
    rows_choices = ["pose", "position", "orientation", ["vx", "wz"]]
    fast = []
    for q in states:
        configuration.update(q)
        fast += [
            gradients.manipulability_terms(configuration, "ee", "site", r) for r in rows_choices
        ]
    monkeypatch.setattr(gradients, "hinge_slide_chain", lambda model, body: None)
    k = 0
    for q in states:
        configuration.update(q)
        for rows in rows_choices:
            value, reference = gradients.manipulability_terms(configuration, "ee", "site", rows)
            assert fast[k][0] == value  # the value itself: the same bits
            scale = max(np.abs(reference).max(), 1e-12)
            np.testing.assert_allclose(fast[k][1], reference, rtol=0, atol=1e-12 * scale)
            k += 1


def test_a_free_or_ball_joint_takes_mj_jacdot():
    """A chain with a free or ball joint (its dofs' axes turn with it) is differentiated by
    ``mj_jacDot``, not in closed form; the gradient still matches finite differences."""
    import mujoco
    from conftest import BALL, FLOATING

    from qpik.model import gradients

    for xml, frame in ((FLOATING, "ee"), (BALL, "eye")):
        model = mujoco.MjModel.from_xml_string(xml)
        body = int(model.site_bodyid[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, frame)])
        assert gradients.hinge_slide_chain(model, body) is None


def test_a_model_with_no_degree_of_freedom_is_named():
    import mujoco

    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body name="b"><geom size=".1"/><site name="s"/></body>'
        "</worldbody></mujoco>"
    )
    with pytest.raises(qpik.errors.InvalidInput, match=r"no degree of freedom \(nv = 0\)"):
        an.analyze(qpik.Configuration(model), "s")


def test_the_report_s_condition_number_is_inf_with_more_rows_than_dofs():
    """Audit (analysis): the planar 2R's six pose rows were reported singular (rank 2 < 6,
    manipulability 0) with a condition number of 4.7 (the two dofs' singular values only);
    the report's condition number is inf there, as it documents at a singularity."""
    model = qpik.load_robot("planar_2r")
    configuration = qpik.Configuration(model, np.array([0.3, 0.7]))
    report = qpik.analysis.analyze(configuration, "ee", rows="pose")
    assert report.singular and report.manipulability == 0.0
    assert report.condition_number == np.inf
    planar = qpik.analysis.analyze(configuration, "ee", rows=["vx", "vy"])
    assert np.isfinite(planar.condition_number) and not planar.singular


def test_a_tol_equal_to_a_singular_value_splits_no_function():
    """Audit (analysis): with tol equal to a singular value (J's smallest, as
    singular_values returns it), rank said 1 while null_space was (3, 1), pseudoinverse
    inverted the value and singularity's rank was 2 - each recomputed the SVD with another
    routine, and the strict > tol test fell differently in the last bit (on 3,000 random
    matrices: 647 pseudoinverses, 735 null spaces). They share one rank decision now."""
    rng = np.random.default_rng(0)
    for _ in range(400):
        m, n = (int(k) for k in rng.integers(1, 7, 2))
        J = rng.normal(size=(m, n))
        tol = float(an.singular_values(J)[-1])
        r = an.rank(J, tol)
        report = an.singularity(J, tol)
        P = an.pseudoinverse(J, tol)
        assert r + an.null_space(J, tol).shape[1] == n == r + an.degree_of_redundancy(J, tol)
        assert report.rank == r and report.null_motions.shape[1] == n - r
        assert np.linalg.matrix_rank(P, tol=1e-9 * max(1.0, np.abs(P).max())) == r
