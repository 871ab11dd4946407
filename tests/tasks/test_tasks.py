"""qpik's own tasks: Jacobians against finite differences of their errors."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import central_difference, configuration_of
from scipy.spatial.transform import Rotation

import qpik
from qpik.tasks import (
    JointLimitDistanceTask,
    ManipulabilityTask,
    OrientationTask,
    PoseTask,
    PositionTask,
)


def numeric_jacobian(task, configuration):
    return central_difference(configuration, task.compute_error)


def make_tasks(configuration, rng):
    other = configuration.copy()
    other.update(other.random_q(rng))
    position = PositionTask("ee")
    position.set_target(other.frame_pose("ee")[0])
    orientation = OrientationTask("ee")
    orientation.set_target(other.frame_pose("ee")[1])
    pose = PoseTask("ee")
    pose.set_target(*other.frame_pose("ee"))
    return [position, orientation, pose, JointLimitDistanceTask(), ManipulabilityTask("ee")]


@pytest.mark.parametrize("robot", ["ur5e", "panda"])
def test_task_jacobians_match_finite_differences(robot, rng):
    """Each task's Jacobian against central differences of its error, to 2e-5 plus 1e-8 of
    its largest entry: the manipulability's gradient reaches 2e4 near a singularity, where
    the differences' round-off (2e-5 there) depends on the BLAS kernel NumPy picks for the
    CPU (the test failed under OPENBLAS_CORETYPE=Sandybridge with a fixed 2e-5)."""
    configuration = configuration_of(robot)
    for _ in range(5):
        configuration.update(configuration.random_q(rng))
        for task in make_tasks(configuration, rng):
            J = task.compute_jacobian(configuration)
            np.testing.assert_allclose(
                J,
                numeric_jacobian(task, configuration),
                atol=2e-5 + 1e-8 * np.abs(J).max(),
                err_msg=type(task).__name__,
            )


def test_orientation_error_is_world_rotation_vector():
    configuration = configuration_of("panda", configuration_of("panda").mid_q())
    rotation = configuration.frame_pose("ee")[1]
    task = OrientationTask("ee")
    offset = Rotation.from_rotvec([0.1, -0.2, 0.05])
    task.set_target(offset.as_matrix().T @ rotation)
    np.testing.assert_allclose(task.compute_error(configuration), [0.1, -0.2, 0.05], atol=1e-12)


def test_bad_targets():
    with pytest.raises(qpik.InvalidTarget, match="position target.*finite"):
        PositionTask("ee").set_target([0.0, np.nan, 1.0])
    with pytest.raises(qpik.InvalidTarget, match="not a rotation"):
        OrientationTask("ee").set_target(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(qpik.TaskDefinitionError, match="position cost.*>= 0"):
        PositionTask("ee", cost=-1.0)


def test_pose_task_equals_position_and_orientation_tasks(rng):
    configuration = configuration_of("panda")
    configuration.update(configuration.random_q(rng))
    position, orientation, pose = make_tasks(configuration, rng)[:3]
    np.testing.assert_allclose(
        pose.compute_error(configuration),
        np.concatenate(
            [position.compute_error(configuration), orientation.compute_error(configuration)]
        ),
        atol=1e-12,
    )
    np.testing.assert_allclose(
        pose.compute_jacobian(configuration),
        np.vstack(
            [position.compute_jacobian(configuration), orientation.compute_jacobian(configuration)]
        ),
        atol=1e-12,
    )


def test_world_frame_tasks_take_mink_lie_groups():
    """OrientationTask and PoseTask take mink's SO3 / SE3 as targets, the same as matrices."""
    import mink

    from qpik.tasks import OrientationTask, PoseTask

    rotation = mink.SO3.exp(np.array([0.1, -0.2, 0.3]))
    position = np.array([0.1, 0.2, 0.3])
    by_group, by_matrix = OrientationTask("link1", "body"), OrientationTask("link1", "body")
    by_group.set_target(rotation)
    by_matrix.set_target(rotation.as_matrix())
    np.testing.assert_array_equal(by_group.target, by_matrix.target)
    pose, pose_matrix = PoseTask("link1", "body"), PoseTask("link1", "body")
    pose.set_target(mink.SE3.from_rotation_and_translation(rotation, position))
    pose_matrix.set_target(position, rotation.as_matrix())
    np.testing.assert_allclose(pose.target_position, pose_matrix.target_position, atol=1e-15)
    np.testing.assert_allclose(pose.target_rotation, pose_matrix.target_rotation, atol=1e-15)
    with pytest.raises(qpik.InvalidTarget, match="rotation is missing"):
        pose.set_target(position)
    with pytest.raises(qpik.InvalidTarget, match="one mink.SE3"):
        pose.set_target(mink.SE3.identity(), rotation)


def test_frame_task_target_must_be_an_se3_with_a_rotation():
    """qpik's FrameTask.set_target (and an assignment of its target) refuses what is not a
    mink.SE3 (np.eye(4): AttributeError from the step's plan before) and an SE3 whose
    quaternion is zero (read as orientation met, error 0, before): InvalidTarget naming the
    task; RelativeFrameTask's zero quaternion likewise. A NaN target is still the step's to
    report (tests/diffik/test_fused.py)."""
    import mink

    from qpik.tasks import FrameTask, RelativeFrameTask

    configuration = configuration_of("panda", configuration_of("panda").mid_q())
    p = configuration.frame_pose("ee")[0]
    task = FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    with pytest.raises(qpik.InvalidTarget, match="FrameTask 'ee'.*mink.SE3"):
        task.set_target(np.eye(4))
    with pytest.raises(qpik.InvalidTarget, match="FrameTask 'ee'.*zero quaternion"):
        task.set_target(mink.SE3(np.r_[0.0, 0.0, 0.0, 0.0, p]))
    with pytest.raises(qpik.InvalidTarget, match="zero quaternion"):
        task.transform_target_to_world = mink.SE3(np.r_[0.0, 0.0, 0.0, 0.0, p])
    assert task.transform_target_to_world is None  # (nothing kept)
    task.set_target(mink.SE3(np.r_[2.0, 0.0, 0.0, 0.0, p]))  # (a scaled quaternion: a rotation)
    task.set_target(mink.SE3.from_translation(np.array([np.nan, 0.0, 0.5])))
    relative = RelativeFrameTask("ee", "site", "link0", "body", 1.0, 1.0)
    with pytest.raises(qpik.InvalidTarget, match="RelativeFrameTask 'ee'.*zero quaternion"):
        relative.set_target(mink.SE3(np.r_[0.0, 0.0, 0.0, 0.0, p]))


@pytest.mark.parametrize("gain", [-1.0, 2.0, np.nan, np.float32(1.5), 3])
def test_a_gain_assigned_to_a_qpik_task_is_checked(gain):
    """A gain assigned after the task was built is checked as the constructor checks it
    (the solver reads it at every step; a gain of -1 or 2 was used as is before):
    InvalidGain naming the task, the task's gain unchanged. What is not one number (an
    array, a string) is left to the step (tests/diffik/test_attribute_errors.py)."""
    from qpik.tasks import ComTask, DampingTask, FrameTask, PostureTask, RelativeFrameTask

    model = qpik.load_robot("panda")
    tasks = [
        FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0),
        PostureTask(model, cost=0.1),
        DampingTask(model, cost=0.1),
        ComTask(),
        RelativeFrameTask("ee", "site", "link0", "body", 1.0, 1.0),
        PositionTask("ee"),
        PoseTask("ee"),
        JointLimitDistanceTask(),
        ManipulabilityTask("ee"),
    ]
    for task in tasks:
        before = task.gain
        with pytest.raises(qpik.InvalidGain, match=type(task).__name__):
            task.gain = gain
        assert task.gain is before
        for valid in (0.0, 0.5, 1, True, np.float32(0.25)):
            task.gain = valid
            assert task.gain is valid


def test_frame_tasks_take_a_mink_configuration_and_raise_qpiks_errors():
    """Pins h11's audit: PositionTask, OrientationTask and PoseTask read a mink.Configuration
    as qpik's (was an AttributeError: no frame_pose, no frame_id), with the same error and
    Jacobian; FrameTask before set_target raises qpik.TargetNotSet (was mink's, not a
    QpikError)."""
    import mink

    from qpik.tasks import FrameTask, OrientationTask, PoseTask, PositionTask

    model = qpik.load_robot("panda")
    theirs = mink.Configuration(model, model.key_qpos[0])
    ours = qpik.Configuration(model, model.key_qpos[0])
    for task in (PositionTask("ee"), OrientationTask("ee"), PoseTask("ee")):
        task.set_target_from_configuration(theirs)
        np.testing.assert_array_equal(task.compute_error(theirs), task.compute_error(ours))
        np.testing.assert_array_equal(task.compute_jacobian(theirs), task.compute_jacobian(ours))
        with pytest.raises(qpik.InvalidInput, match="configuration"):
            task.compute_error(model.key_qpos[0])
    unset = FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    for method in (unset.compute_error, unset.compute_jacobian):
        with pytest.raises(qpik.TargetNotSet):
            method(ours)
