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
