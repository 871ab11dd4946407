"""The IGM solver: convergence, honest failure, limits, determinism."""

from __future__ import annotations

import mink
import numpy as np
import pytest
from conftest import configuration_of

import qpik
from qpik.converge import REASONS


def reachable_pose(robot, rng, frame="ee"):
    configuration = configuration_of(robot)
    configuration.update(configuration.random_q(rng))
    return configuration.frame_pose(frame)


@pytest.mark.parametrize("robot", ["planar_2r", "planar_4r"])
def test_planar_positions_converge(robot, rng):
    model = qpik.load_robot(robot)
    for i in range(20):
        position, _ = reachable_pose(robot, rng)
        result = qpik.solve(model, {"ee": position}, seed=i)
        assert result.converged, result
        assert result.reason == "converged" and result.position_error <= 1e-4
        configuration = qpik.Configuration(model, result.q)
        np.testing.assert_allclose(configuration.frame_pose("ee")[0], position, atol=1e-4)
        assert configuration.within_limits(tol=0.0)


def test_lecture_4r_target_minus1_2():
    result = qpik.solve("planar_4r", {"ee": [-1.0, 2.0, 0.0]}, q0=[0.76, 0.90, 0.69, 1.19])
    assert result.converged and result.position_error <= 1e-4


@pytest.mark.parametrize("robot", ["ur5e", "panda"])
def test_arm_poses_converge_in_several_target_forms(robot, rng):
    model = qpik.load_robot(robot)
    for i in range(15):
        position, rotation = reachable_pose(robot, rng)
        matrix = np.eye(4)
        matrix[:3, :3], matrix[:3, 3] = rotation, position
        target = [
            (position, rotation),
            matrix,
            mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), position),
        ][i % 3]
        result = qpik.solve(model, {"ee": target}, seed=i)
        assert result.converged, result
        assert result.position_error <= 1e-4 and result.orientation_error <= 1e-3
        configuration = qpik.Configuration(model, result.q)
        assert configuration.within_limits(tol=0.0)
        np.testing.assert_allclose(configuration.frame_pose("ee")[0], position, atol=1e-4)


def test_several_frames_at_once(rng):
    model = qpik.load_robot("panda")
    configuration = configuration_of("panda")
    configuration.update(configuration.random_q(rng))
    targets = {
        "ee": configuration.frame_pose("ee"),
        ("link4", "body"): configuration.frame_pose("link4", "body")[0],
    }
    result = qpik.solve(model, targets, seed=1)
    assert result.converged, result
    assert set(result.frame_errors) == {"ee", "link4"}


def test_out_of_reach_reports_reason_and_stays_in_limits():
    result = qpik.solve("panda", {"ee": [3.0, 0.0, 0.5]}, restarts=2, seed=0)
    assert not result.converged
    assert result.reason in REASONS and result.reason != "converged"
    assert result.position_error > 1.0
    configuration = qpik.Configuration(qpik.load_robot("panda"), result.q)
    assert configuration.within_limits(tol=0.0)


def test_start_at_the_2r_singularity_converges():
    result = qpik.solve("planar_2r", {"ee": [1.2, 0.8, 0.0]}, q0=[0.0, 0.0], restarts=0)
    assert result.converged and result.restarts_used == 0, result


def test_same_seed_same_result(rng):
    position, rotation = reachable_pose("panda", rng)
    first = qpik.solve("panda", {"ee": (position, rotation)}, seed=7)
    second = qpik.solve("panda", {"ee": (position, rotation)}, seed=7)
    np.testing.assert_array_equal(first.q, second.q)
    assert first.iterations == second.iterations


def test_time_budget_and_max_iters_are_reasons():
    out_of_reach = {"ee": [3.0, 0.0, 0.5]}
    assert qpik.solve("panda", out_of_reach, time_budget=0.0).reason == "time_budget"
    result = qpik.solve("panda", {"ee": [0.5, 0.3, 0.2]}, max_iters=1, restarts=0)
    assert result.reason in ("max_iters", "converged")
    assert result.iterations <= 1


def test_alpha_beta_lecture_recursion():
    # Small alpha and beta: the lecture's recursion converges, more slowly.
    fast = qpik.solve("planar_2r", {"ee": [1.2, 0.8, 0.0]}, q0=[0.3, 0.5], restarts=0)
    slow = qpik.solve(
        "planar_2r",
        {"ee": [1.2, 0.8, 0.0]},
        q0=[0.3, 0.5],
        alpha=0.5,
        beta=0.5,
        max_iters=500,
        restarts=0,
        max_step=None,
    )
    assert fast.converged and slow.converged and slow.iterations > fast.iterations


def test_custom_stack_gets_the_targets(rng):
    model = qpik.load_robot("panda")
    position, rotation = reachable_pose("panda", rng)
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    posture = qpik.tasks.PostureTask(model, cost=0.01)
    posture.set_target(qpik.Configuration(model).mid_q())
    result = qpik.solve(model, {"ee": (position, rotation)}, stack=[[frame], [posture]], seed=3)
    assert result.converged, result
    with pytest.raises(qpik.InvalidTarget, match="no task in the given stack"):
        qpik.solve(model, {"flange": position}, stack=[[frame]])


def test_bad_inputs():
    with pytest.raises(qpik.InvalidTarget, match="finite"):
        qpik.solve("panda", {"ee": [0.3, np.nan, 0.5]})
    with pytest.raises(qpik.UnknownFrame, match="ee"):
        qpik.solve("panda", {"gripper": [0.3, 0.0, 0.5]})
    with pytest.raises(qpik.JointLimitViolation, match="joint4"):
        qpik.solve("panda", {"ee": [0.3, 0.0, 0.5]}, q0=[0, 0, 0, 0.5, 0, 1, 0])
    with pytest.raises(qpik.InvalidTarget, match="shape"):
        qpik.solve("panda", {"ee": [0.3, 0.0]})
    with pytest.raises(qpik.InvalidTarget, match="no targets"):
        qpik.solve("panda", {})


def test_solve_many_is_deterministic_and_parallel(rng):
    targets = [{"ee": reachable_pose("ur5e", rng)} for _ in range(6)]
    serial = qpik.solve_many("ur5e", targets, seed=5, progress=False)
    again = qpik.solve_many("ur5e", targets, seed=5, progress=False)
    parallel = qpik.solve_many("ur5e", targets, seed=5, progress=False, workers=2)
    for a, b, c in zip(serial, again, parallel, strict=True):
        np.testing.assert_array_equal(a.q, b.q)
        np.testing.assert_array_equal(a.q, c.q)
    assert all(r.converged for r in serial)


def test_history_and_path_of_the_returned_attempt(rng):
    position, rotation = reachable_pose("ur5e", rng)
    result = qpik.solve("ur5e", {"ee": (position, rotation)}, seed=2)
    assert result.converged
    assert result.path.shape[1] == 6 and len(result.path) == len(result.error_history)
    np.testing.assert_array_equal(result.path[-1], result.q)
    assert result.error_history[-1] == (result.position_error, result.orientation_error)
    assert result.error_history[0][0] > result.error_history[-1][0]


def test_custom_stack_keeps_the_users_gains(rng):
    model = qpik.load_robot("panda")
    position, rotation = reachable_pose("panda", rng)
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0, gain=0.7)
    qpik.solve(model, {"ee": (position, rotation)}, stack=[frame], seed=1)
    assert frame.gain == 0.7


def test_clear_pool_after_editing_a_model(rng):
    model = qpik.load_robot("planar_2r")
    target = {"ee": [1.2, 0.8, 0.0]}
    assert qpik.solve(model, target, q0=[0.3, 0.5]).converged
    model.jnt_range[1] = [0.0, 0.2]  # narrow q2: the target is now out of reach
    qpik.converge.clear_pool()
    result = qpik.solve(model, target, q0=[0.3, 0.1], restarts=3)
    assert not result.converged and 0.0 <= result.q[1] <= 0.2 + 1e-12
