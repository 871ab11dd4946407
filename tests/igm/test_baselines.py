"""The lecture's IGM baselines (:mod:`qpik.baselines`): the loop with the pseudoinverse and
damped least-squares steps, and its task error."""

from __future__ import annotations

import mink
import numpy as np
import pytest
from conftest import configuration_of

from qpik.igm.baselines import (
    IGM_REASONS,
    damped_least_squares_igm,
    pose_error,
    pseudoinverse_igm,
    pseudoinverse_step,
)


# ------------------------------------------------------------------ IGM baselines
def _reachable_2r(rng, count):
    """Positions of the 2R tip at elbows away from the singularities q2 = 0, +-pi."""
    configuration = configuration_of("planar_2r")
    for _ in range(count):
        q = np.array([rng.uniform(-np.pi, np.pi), rng.uniform(0.4, 2.6) * rng.choice([-1, 1])])
        configuration.update(q)
        yield configuration.frame_pose("ee")[0]


@pytest.mark.parametrize("igm", [pseudoinverse_igm, damped_least_squares_igm])
def test_igm_baselines_converge_on_2r_targets(igm, rng):
    configuration = configuration_of("planar_2r", [0.3, 1.0])
    for i, position in enumerate(_reachable_2r(rng, 20)):
        result = igm(configuration, "ee", position, seed=i)
        assert result.converged and result.reason == "converged", result
        assert result.position_error <= 1e-4 and result.orientation_error == 0.0
        check = configuration_of("planar_2r", result.q)
        np.testing.assert_allclose(check.frame_pose("ee")[0], position, atol=1e-4)
        assert check.within_limits(tol=0.0)
    np.testing.assert_array_equal(configuration.q, [0.3, 1.0])  # left unchanged


@pytest.mark.parametrize("igm", [pseudoinverse_igm, damped_least_squares_igm])
def test_igm_baselines_converge_on_arm_poses(igm, rng):
    model_configuration = configuration_of("panda")
    for i in range(5):
        model_configuration.update(model_configuration.random_q(rng))
        position, rotation = model_configuration.frame_pose("ee")
        start = configuration_of("panda", model_configuration.mid_q())
        result = igm(start, "ee", position, rotation, seed=i, time_budget=1.0)
        assert result.converged, result
        assert result.position_error <= 1e-4 and result.orientation_error <= 1e-3
        assert configuration_of("panda", result.q).within_limits(tol=0.0)


def test_igm_out_of_reach_reports_why_and_stays_within_limits():
    configuration = configuration_of("planar_2r", [0.3, 1.0])
    result = pseudoinverse_igm(configuration, "ee", np.array([5.0, 0.0, 0.0]), restarts=2, seed=0)
    assert not result.converged and result.reason in IGM_REASONS
    assert result.reason in ("stalled", "max_iters") and result.restarts_used == 2
    assert configuration_of("planar_2r", result.q).within_limits(tol=0.0)


@pytest.mark.parametrize("igm", [pseudoinverse_igm, damped_least_squares_igm])
def test_igm_baselines_converge_where_each_error_is_within_its_tolerance(igm):
    """Converged means each error within its own tolerance, as qpik.solve decides (not their
    scaled sum): a start 0.7 of each tolerance away is converged at once, by both."""
    import qpik

    configuration = configuration_of("ur5e", qpik.load_robot("ur5e").key_qpos[0])
    p, R = configuration.frame_pose("ee")
    target = (p + [7e-5, 0.0, 0.0], mink.SO3.exp(np.array([0.0, 0.0, 7e-4])).as_matrix() @ R)
    ours = igm(configuration, "ee", *target, max_iters=0, restarts=0)
    solved = qpik.solve(configuration.model, {"ee": target}, q0=configuration.q, max_iters=0)
    assert ours.converged and ours.reason == "converged" and ours.iterations == 0
    assert solved.converged


@pytest.mark.parametrize(
    "args, keywords, error",
    [
        (([np.nan, 0.0, 0.0],), {}, "InvalidTarget"),
        (([1.0, 1.0],), {}, "InvalidTarget"),
        (("abc",), {}, "InvalidTarget"),
        (([1.0, 1.0, 0.0], 2.0 * np.eye(3)), {}, "InvalidTarget"),
        (([1.0, 1.0, 0.0],), {"seed": -1}, "InvalidInput"),
        (([1.0, 1.0, 0.0],), {"seed": "x"}, "InvalidInput"),
        (([1.0, 1.0, 0.0],), {"rcond": -1.0}, "InvalidOption"),
        (([1.0, 1.0, 0.0],), {"rcond": np.nan}, "InvalidOption"),
        (([1.0, 1.0, 0.0],), {"clip": "yes"}, "InvalidOption"),
    ],
)
def test_igm_baselines_bad_input_is_typed(args, keywords, error):
    import qpik

    configuration = configuration_of("planar_2r", [0.3, 0.5])
    with pytest.raises(getattr(qpik.errors, error)):
        pseudoinverse_igm(configuration, "ee", *args, **keywords)
    with pytest.raises(qpik.errors.InvalidInput, match="configuration"):
        pseudoinverse_igm("planar_2r", "ee", [1.0, 1.0, 0.0])
    for damping in (-1.0, 0.0, np.nan, True):
        with pytest.raises(qpik.errors.InvalidOption, match="damping"):
            damped_least_squares_igm(configuration, "ee", [1.0, 1.0, 0.0], damping=damping)


def test_pinv_step_at_the_2r_singularity_is_huge():
    """Near the stretched 2R (q2 = 1e-3), asking for motion along the arm costs a joint step
    of order 1 / q2 with the pseudoinverse; damped least squares stays bounded."""
    configuration = configuration_of("planar_2r", [0.0, 1e-3])
    position, _ = configuration.frame_pose("ee")
    target = position - np.array([0.01, 0.0, 0.0])  # 1 cm back along the stretched arm
    J = configuration.frame_jacobian("ee")[:3]
    c = pose_error(configuration, "ee", target, None)
    np.testing.assert_allclose(c, [-0.01, 0.0, 0.0], atol=1e-12)
    pinv = pseudoinverse_step(J, c)
    assert np.linalg.norm(pinv) > 1000 * np.linalg.norm(c)  # about 22 rad for 1 cm
    dls = damped_least_squares_igm(configuration, "ee", target, max_iters=1, restarts=0)
    assert dls.iterations == 1
    assert np.linalg.norm(dls.q - configuration.q) <= 0.01 / (2 * 0.05)  # |c| / (2 damping)


def test_pose_error_rotation_matches_so3_log(rng):
    configuration = configuration_of("ur5e")
    configuration.update(configuration.random_q(rng))
    position, rotation = configuration.frame_pose("ee")
    for angle in (0.3, np.pi - 1e-6, np.pi):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        target = mink.SO3.exp(angle * axis).as_matrix() @ rotation
        c = pose_error(configuration, "ee", position + 0.1, target)
        np.testing.assert_allclose(c[:3], 0.1, atol=1e-12)
        assert np.linalg.norm(c[3:]) == pytest.approx(angle, abs=1e-9)
        np.testing.assert_allclose(mink.SO3.exp(c[3:]).as_matrix() @ rotation, target, atol=1e-9)


def test_damped_least_squares_step_takes_lambda_where_the_pseudoinverse_takes_its_square():
    """The two damping conventions, as both docstrings state: the baseline's ``damping`` is
    the textbook's lambda, :func:`qpik.analysis.damped_pseudoinverse`'s is lambda^2 (mink's);
    checked against the closed form J^T (J J^T + lambda^2 I)^-1 xi."""
    from qpik.analysis import damped_pseudoinverse
    from qpik.igm.baselines import damped_least_squares_step

    rng = np.random.default_rng(4)
    J, xi = rng.normal(size=(2, 4)), rng.normal(size=2)
    lam = 0.05
    closed = J.T @ np.linalg.solve(J @ J.T + lam**2 * np.eye(2), xi)
    np.testing.assert_allclose(damped_least_squares_step(J, xi, lam), closed, rtol=1e-12)
    np.testing.assert_allclose(damped_pseudoinverse(J, lam**2) @ xi, closed, rtol=1e-10)
