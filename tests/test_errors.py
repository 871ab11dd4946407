"""Every bad input of the foundation raises a typed error that names the problem."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import configuration_of

import qpik


def test_unknown_robot_lists_available_names():
    with pytest.raises(qpik.UnknownRobot, match="planar_2r") as info:
        qpik.load_robot("no_such_robot")
    assert "panda" in info.value.available
    assert isinstance(info.value, qpik.QpikError)


def test_unknown_frame_lists_frames_of_that_type():
    configuration = configuration_of("ur5e")
    with pytest.raises(qpik.UnknownFrame, match="available sites: ee"):
        configuration.frame_pose("gripper")
    with pytest.raises(qpik.UnknownFrame, match="tool0"):
        configuration.frame_jacobian("gripper", "body")


def test_unknown_frame_type():
    configuration = configuration_of("ur5e")
    with pytest.raises(qpik.UnknownFrameType, match="body, site, geom"):
        configuration.frame_pose("ee", "joint")


def test_unknown_frame_through_mink_task_is_typed():
    import mink

    configuration = configuration_of("ur5e")
    task = mink.FrameTask("gripper", "site", position_cost=1.0, orientation_cost=1.0)
    with pytest.raises(qpik.UnknownFrame):
        task.set_target_from_configuration(configuration)


@pytest.mark.parametrize(
    "q, fragment",
    [
        ([0.0, 0.0, 0.0], r"shape \(3,\), expected \(2,\)"),
        ([0.0, np.nan], r"q\[1\] \(joint 'q2'\) is nan"),
        ([np.inf, 0.0], r"q\[0\] \(joint 'q1'\) is inf"),
    ],
)
def test_bad_configuration_names_the_index(q, fragment):
    with pytest.raises(qpik.InvalidConfiguration, match=fragment):
        configuration_of("planar_2r", q)
    configuration = configuration_of("planar_2r")
    with pytest.raises(qpik.InvalidConfiguration, match=fragment):
        configuration.update(q)


def test_bad_velocity():
    configuration = configuration_of("planar_2r")
    with pytest.raises(qpik.InvalidConfiguration, match=r"v\[1\]"):
        configuration.integrate([0.0, np.nan], 0.1)


def test_unreadable_files_name_the_path(tmp_path):
    missing = tmp_path / "missing.xml"
    with pytest.raises(qpik.RobotFileError, match="missing.xml"):
        qpik.load_robot(missing)
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='x'><link name='a'>")
    with pytest.raises(qpik.RobotFileError, match="broken.urdf.*not well-formed"):
        qpik.load_robot(broken)
    wrong_root = tmp_path / "wrong.xml"
    wrong_root.write_text("<html/>")
    with pytest.raises(qpik.RobotFileError, match="expected <mujoco> or <robot>"):
        qpik.load_robot(wrong_root)
    bad_mjcf = tmp_path / "bad.xml"
    bad_mjcf.write_text(
        "<mujoco><worldbody><body><joint type='nonsense'/></body></worldbody></mujoco>"
    )
    with pytest.raises(qpik.RobotFileError, match="bad.xml"):
        qpik.load_robot(bad_mjcf)


def test_erd_without_the_extra_names_it(monkeypatch):
    from importlib import metadata

    def missing(name):
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(metadata, "distribution", missing)
    with pytest.raises(qpik.MissingExtra, match=r"qpik\[robots\]"):
        qpik.load_robot("erd:panda")
