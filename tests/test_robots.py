"""Robot loading: bundled models, URDF import specifics, example-robot-data."""

from __future__ import annotations

import math
import warnings
from importlib import metadata

import mujoco
import numpy as np
import pytest

import qpik
from qpik.robots import ERD_ROBOTS

URDF = """<?xml version="1.0"?>
<robot name="tool_arm">
  <link name="base_link"/>
  <link name="upper">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><geometry><mesh filename="package://fake_description/meshes/upper.dae"/></geometry></visual>
    <collision><geometry><mesh filename="meshes/upper.dae"/></geometry></collision>
  </link>
  <link name="fore">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><cylinder radius="0.03" length="0.4"/></geometry></collision>
  </link>
  <link name="tool0"/>
  <joint name="shoulder" type="revolute">
    <parent link="base_link"/><child link="upper"/>
    <origin xyz="0 0 0.5" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="10" velocity="1"/>
  </joint>
  <joint name="elbow" type="continuous">
    <parent link="upper"/><child link="fore"/>
    <origin xyz="0.4 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>
  </joint>
  <joint name="tool_mount" type="fixed">
    <parent link="fore"/><child link="tool0"/>
    <origin xyz="0.3 0 0" rpy="0 0 1.5707963267948966"/>
  </joint>
</robot>
"""


def test_list_robots_has_the_required_models():
    assert {"planar_2r", "planar_4r", "ur5e", "panda"} <= set(qpik.list_robots())


def test_every_bundled_robot_has_site_ee_and_limits(bundled_robot):
    model = qpik.load_robot(bundled_robot)
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "ee") >= 0
    assert model.jnt_limited.all()


def test_bundled_dof():
    assert [qpik.load_robot(n).nv for n in ("planar_2r", "planar_4r", "ur5e", "panda")] == [
        2,
        4,
        6,
        7,
    ]


def test_mjmodel_passes_through():
    model = qpik.load_robot("planar_2r")
    assert qpik.load_robot(model) is model


def test_urdf_with_fixed_tool_link_and_dae_mesh(tmp_path):
    path = tmp_path / "tool_arm.urdf"
    path.write_text(URDF)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = qpik.load_robot(path)
    messages = [str(w.message) for w in caught if "dropped" in str(w.message)]
    assert len(messages) == 1 and "upper.dae" in messages[0]
    configuration = qpik.Configuration(model)
    # The fixed tool link survives as a body.
    assert "tool0" in qpik.frame_names(model, "body")
    # Continuous joints are unlimited.
    elbow = model.joint("elbow").qposadr[0]
    assert configuration.lower[elbow] == -np.inf and configuration.upper[elbow] == np.inf
    shoulder = model.joint("shoulder").qposadr[0]
    assert configuration.lower[shoulder] == pytest.approx(-2.0)
    # FK by hand: shoulder about z at height 0.5, elbow about the upper link's y.
    for q1, q2 in [(0.0, 0.0), (0.3, -0.7), (-1.2, 2.0)]:
        q = np.zeros(model.nq)
        q[shoulder], q[elbow] = q1, q2
        configuration.update(q)
        reach = 0.4 + 0.3 * math.cos(q2)
        expected = np.array([reach * math.cos(q1), reach * math.sin(q1), 0.5 - 0.3 * math.sin(q2)])
        position, rotation = configuration.frame_pose("tool0", "body")
        np.testing.assert_allclose(position, expected, atol=1e-9)
        # tool0's x axis = fore's y axis (yaw of +pi/2 at the mount).
        fore_y = np.array([-math.sin(q1), math.cos(q1), 0.0])
        np.testing.assert_allclose(rotation[:, 0], fore_y, atol=1e-9)


def _has_erd() -> bool:
    try:
        metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return False
    return True


@pytest.mark.skipif(not _has_erd(), reason="example-robot-data not installed (qpik[robots])")
@pytest.mark.parametrize("name", ["panda", "ur5"])
def test_erd_robots_load_with_tool_frames(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = qpik.load_robot(f"erd:{name}")
    bodies = qpik.frame_names(model, "body")
    assert ("panda_hand" if name == "panda" else "tool0") in bodies


def test_erd_unknown_name_lists_known(monkeypatch):
    if not _has_erd():
        pytest.skip("example-robot-data not installed")
    with pytest.raises(qpik.UnknownRobot, match="erd:panda"):
        qpik.load_robot("erd:nonexistent")
    assert "ur5" in ERD_ROBOTS
