"""Frame rows on a floating base against MuJoCo's own integration (mj_integratePos: the free
joint's linear velocity in the world frame, its angular velocity in the body frame).

A step's rows are the derivative of the frame error along ``t -> q (+) t dq`` as MuJoCo
integrates it, so what a held level-0 frame task keeps after the step is the second-order
remainder of the step alone: it quarters when the step is halved (a frame mix-up between
the rows and the integration would leave a first-order error, which halves)."""

from __future__ import annotations

import mink
import mujoco
import numpy as np
import pytest
from conftest import central_difference, has_erd

import qpik
from qpik.limits import velocity_limit_from_model
from qpik.tasks import FrameTask, PostureTask

FEET = ("left_sole_link", "right_sole_link")
HANDS = ("gripper_left_base_link", "gripper_right_base_link")


pytestmark = pytest.mark.skipif(not has_erd(), reason="needs qpik[robots]")


def _talos():
    model = qpik.load_robot("erd:talos", floating_base=True)
    return model, model.key_qpos[0].copy()


def _held(configuration, frame):
    task = FrameTask(frame, "body", position_cost=1.0, orientation_cost=1.0)
    position, rotation = configuration.frame_pose(frame, "body")
    task.set_target(
        mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), position)
    )
    return task


def test_frame_jacobian_is_the_derivative_along_mujoco_integration(rng):
    model, home = _talos()
    configuration = qpik.Configuration(model, home)
    tasks = [_held(configuration, f) for f in FEET]
    for _ in range(3):
        q = home.copy()
        q[:3] += rng.uniform(-0.3, 0.3, 3)
        quaternion = rng.normal(size=4)
        q[3:7] = quaternion / np.linalg.norm(quaternion)
        q[7:] += rng.uniform(-0.2, 0.2, model.nq - 7)
        configuration.update(q)
        for task in tasks:
            np.testing.assert_allclose(
                task.compute_jacobian(configuration),
                central_difference(configuration, task.compute_error),
                atol=2e-6,
            )


def test_held_feet_keep_only_the_second_order_remainder_of_a_step():
    model, home = _talos()
    configuration = qpik.Configuration(model, home)
    feet = [_held(configuration, f) for f in FEET]
    hands = [FrameTask(h, "body", position_cost=1.0, orientation_cost=0.0) for h in HANDS]
    for task, h in zip(hands, HANDS):
        position = configuration.frame_pose(h, "body")[0]
        task.set_target(mink.SE3.from_translation(position + np.array([0.05, 0.0, 0.04])))
    posture = PostureTask(model, 0.1)
    posture.set_target(home)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    solver = qpik.IKSolver(model, [feet, hands, [posture]], limits)
    probe = qpik.Configuration(model, home)

    def errors(c):
        return np.concatenate([t.compute_error(c) for t in feet])

    dt = 0.01
    for _ in range(4):
        velocity = solver.step(configuration, dt).velocity
        dq = velocity * dt
        e0 = errors(configuration)
        J = np.vstack([t.compute_jacobian(configuration) for t in feet])
        # The level holds in the rows (up to the constant damping 1e-6 of every level).
        assert np.abs(e0 + J @ dq).max() <= 1e-3 * np.abs(e0).max() + 1e-12
        remainders = []
        for t in (1.0, 0.5):
            q = configuration.q.copy()
            mujoco.mj_integratePos(model, q, dq, t)
            probe.update(q)
            remainders.append(np.abs(errors(probe) - e0 - t * (J @ dq)).max())
        assert remainders[0] > 1e-7  # the step is large enough to see its curvature
        assert 3.8 <= remainders[0] / remainders[1] <= 4.2
        configuration.update(configuration.integrate(velocity, dt))


def test_relative_frame_level_on_a_shared_chain_is_certified():
    """erd ANYmal-Kinova, floating: a position task of the gripper's link 6 relative to link 4
    (tests/data/exactness/relative_frame_shared_chain.npz: the middle configuration and the
    target of random stacks at seed 42), exact mode. The base's dofs and the arm's joints
    above link 4 move both frames alike; the difference of the two frames' Jacobians left
    them entries of 1e-15 (their round-off, against rows of 0.07), a gradient no move could
    meet: the level ended numerical_failure at stationarity 1.2e-9. Those entries are now
    exactly 0 (the compiled rows) and the level is certified."""
    import warnings
    from pathlib import Path

    from conftest import load_or_skip

    from qpik.core import LevelStatus
    from qpik.tasks import RelativeFrameTask

    load_or_skip("erd:anymal-kinova")  # (skipped where it does not load)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # dropped collision meshes
        model = qpik.load_robot("erd:anymal-kinova", floating_base=True)
    case = np.load(
        Path(__file__).parents[1] / "data" / "exactness" / "relative_frame_shared_chain.npz"
    )
    configuration = qpik.Configuration(model, case["q"])
    task = RelativeFrameTask(
        "j2s6s200_link_6", "body", "j2s6s200_link_4", "body",
        position_cost=1.0, orientation_cost=0.0,
    )  # fmt: skip
    task.set_target(mink.SE3(case["target"]))
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    solver = qpik.IKSolver(model, [[task]], limits, damping=0.0, damping_law=None)
    result = solver.step(configuration, 0.01)
    assert result.status == [LevelStatus.SOLVED], (result.status, result.certificate)
    assert result.certificate[0].holds
