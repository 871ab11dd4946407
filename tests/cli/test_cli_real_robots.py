"""The command line on real robots: the tool frame chosen and said, effort limits in
``qpik statics``, example-robot-data listed, floating bases and free joints in plots."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import requires_erd

from qpik.cli import main

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


@requires_erd
@pytest.mark.parametrize("command", ["fk", "analyze"])
def test_commands_pick_the_tool_frame_and_say_which(command, capsys):
    assert main([command, "erd:ur5"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("frame: body 'tool0' (the body with a flange's name")
    assert "body 'tool0'" in out.splitlines()[2]


def test_bundled_robot_uses_site_ee_and_a_named_frame_finds_its_type(capsys):
    assert main(["fk", "ur5e", "--frame", "tool0"]) == 0
    out = capsys.readouterr().out
    assert "body 'tool0' in the world frame" in out and not out.startswith("frame:")
    assert main(["fk", "ur5e"]) == 0
    assert capsys.readouterr().out.startswith("frame: site 'ee' (the site named ee")


@requires_erd
def test_statics_on_erd_ur5_reads_the_urdf_efforts(capsys):
    argv = ["statics", "erd:ur5", "--q", "0", "-1.57", "1.57", "0", "0", "0"]
    assert main([*argv, "--force", "0", "0", "-20"]) == 0
    out = capsys.readouterr().out
    assert "[-150, 150]" in out and "[-28, 28]" in out and "[0, 0]" not in out
    assert "EXCEEDED" not in out and "within the actuator limits: yes" in out


@requires_erd
def test_robots_erd_lists_every_robot(capsys):
    assert main(["robots", "--erd"]) == 0
    out = capsys.readouterr().out
    assert "erd:talos " in out and "talos_data/robots/talos_reduced.urdf" in out
    assert "erd:go1 " in out and "erd:ur5 " in out


@requires_erd
def test_fk_floating_talos_from_half_sitting(capsys):
    argv = ["fk", "erd:talos", "--floating-base", "--key", "half_sitting"]
    assert main([*argv, "--frame", "left_sole_link"]) == 0
    out = capsys.readouterr().out
    assert "body 'left_sole_link' in the world frame" in out
    position = out.split("position [m] = [")[1].split("]")[0].split()
    assert abs(float(position[2])) < 1e-4  # the sole on the ground
    assert main([*argv, "--frame", "left_sole_link", "--q", "0"]) == 2
    assert "not both" in capsys.readouterr().err
    assert main(["fk", "erd:talos", "--key", "standing"]) == 2
    assert "half_sitting" in capsys.readouterr().err


FLOATING_ARM = """<mujoco model="floating_arm">
  <compiler angle="radian"/>
  <worldbody>
    <body name="base" pos="0 0 0.5">
      <freejoint name="root"/>
      <geom type="box" size="0.1 0.1 0.05" mass="5"/>
      <body name="shoulder" pos="0 0 0.05">
        <joint name="ball" type="ball" range="0 0.8"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.03" mass="1"/>
        <body name="fore" pos="0 0 0.3">
          <joint name="elbow" type="hinge" axis="0 1 0" range="-2 2"/>
          <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
          <site name="ee" pos="0.3 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

PROBLEM = """robot = "floating_arm.xml"
q0 = "qpos0"
mode = "track"
[[levels]]
[[levels.tasks]]
type = "position"
frame = "ee"
[[levels]]
[[levels.tasks]]
type = "posture"
cost = 0.1
[target]
position = [0.35, 0.1, 0.75]
[track]
dt = 0.01
steps = 20
"""


def test_reach_plot_with_free_and_ball_joints(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    (tmp_path / "floating_arm.xml").write_text(FLOATING_ARM)
    (tmp_path / "reach.toml").write_text(PROBLEM)
    figure = tmp_path / "reach.png"
    assert main(["reach", str(tmp_path / "reach.toml"), "--plot", str(figure), "--quiet"]) == 0
    assert Path(figure).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_joint_curves_cover_free_and_ball_joints():
    import mujoco
    import numpy as np

    from qpik.plots import joint_curves

    model = mujoco.MjModel.from_xml_string(FLOATING_ARM)
    q = np.tile(model.qpos0, (3, 1))
    q[1, 7:11] = [np.cos(0.3), np.sin(0.3), 0, 0]  # ball joint rotated by 0.6 rad
    labels = [label for label, _, _ in joint_curves(model, q)]
    assert labels == ["root x [m]", "root y [m]", "root z [m]", "root angle", "ball angle", "elbow"]
    _, ball, bounds = joint_curves(model, q)[4]
    np.testing.assert_allclose(ball, [0.0, 0.6, 0.0])
    assert bounds == (0.0, 0.8)


@requires_erd
def test_reach_uses_the_tool_frame_when_a_file_names_none(tmp_path, capsys):
    (tmp_path / "p.toml").write_text(
        'robot = "erd:ur5"\nq0 = [0, -1.2, 1.2, 0, 0, 0]\n'
        '[[levels]]\n[[levels.tasks]]\ntype = "position"\n'
        "[target]\nposition = [0.4, 0.2, 0.3]\n"
    )
    assert main(["reach", str(tmp_path / "p.toml")]) == 0
    out = capsys.readouterr().out
    assert out.startswith(
        "goal frame: body 'tool0' (the robot's tool frame: the body with a flange's name"
    )
