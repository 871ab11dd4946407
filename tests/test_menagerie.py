"""The robots users bring (issue 22): tool frames as the model names them, on trimmed copies
of MuJoCo Menagerie models (``tests/data/menagerie``: meshes removed, licences beside)
and on example-robot-data."""

from __future__ import annotations

import warnings
from importlib import metadata
from pathlib import Path

import mujoco
import pytest

import qpik
from qpik.cli import main
from qpik.robots import gripper_joints, tool_frame

MENAGERIE = Path(__file__).resolve().parent / "data" / "menagerie"


def menagerie(name: str, **kwargs) -> mujoco.MjModel:
    return qpik.load_robot(MENAGERIE / f"{name}.xml", **kwargs)


def _has_erd() -> bool:
    try:
        metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return False
    return True


requires_erd = pytest.mark.skipif(not _has_erd(), reason="needs qpik[robots]")


def _moved_by_gripper(model: mujoco.MjModel, body: int) -> bool:
    grippers = set(gripper_joints(model))
    while body > 0:
        joints = range(model.body_jntadr[body], model.body_jntadr[body] + model.body_jntnum[body])
        if grippers.intersection(joints):
            return True
        body = int(model.body_parentid[body])
    return False


# ----------------------------------------------------------------------- tool frames
@pytest.mark.parametrize(
    ("name", "frame"),
    [
        ("ur5e", "attachment_site"),  # Menagerie's flange site
        ("iiwa14", "attachment_site"),
        ("xarm7", "link_tcp"),  # the TCP site between the fingers, not a finger
        ("g1", "left_palm"),  # a humanoid: its hand's site, not a finger of the hand
        ("h1", "left_wrist"),
    ],
)
def test_tool_frame_is_the_models_flange_or_tcp_site(name, frame):
    model = menagerie(name)
    tool = tool_frame(model)
    assert (tool.name, tool.frame_type) == (frame, "site"), tool
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, frame)
    assert not _moved_by_gripper(model, int(model.site_bodyid[site]))


def test_gripper_joints_are_the_fingers_and_knuckles():
    model = menagerie("xarm7")
    names = {model.joint(j).name for j in gripper_joints(model)}
    assert names == {
        f"{side}_{part}_joint"
        for side in ("left", "right")
        for part in ("driver", "finger", "inner_knuckle")
    }
    assert not gripper_joints(menagerie("ur5e"))


ARM_WITH_FINGERS = """
<mujoco>
  <worldbody>
    <body name="link1">
      <joint name="j1" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.04"/>
      <body name="link2" pos="0 0 0.3">
        <joint name="j2" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04"/>
        <body name="{hand}" pos="0.3 0 0">
          <geom type="box" size="0.02 0.05 0.02"/>
          <body name="left_finger" pos="0.05 0.02 0">
            <joint name="finger_joint1" type="slide" axis="0 1 0" range="0 0.04"/>
            <geom type="box" size="0.03 0.005 0.01"/>
            <site name="{finger_site}" pos="0.03 0 0"/>
          </body>
          <body name="right_finger" pos="0.05 -0.02 0">
            <joint name="finger_joint2" type="slide" axis="0 -1 0" range="0 0.04"/>
            <geom type="box" size="0.03 0.005 0.01"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_tool_frame_is_never_a_finger(tmp_path):
    # No known name: the end of the arm (the hand the fingers branch from), not a finger,
    # although the fingers' slide joints make their chains the longest.
    path = tmp_path / "arm.xml"
    path.write_text(ARM_WITH_FINGERS.format(hand="palm_link", finger_site="marker"))
    tool = tool_frame(qpik.load_robot(path))
    assert (tool.name, tool.frame_type) == ("palm_link", "body") and "longest chain" in tool.reason
    # A TCP's name on a finger is skipped too: the hand's name wins.
    path.write_text(ARM_WITH_FINGERS.format(hand="hand", finger_site="tcp"))
    tool = tool_frame(qpik.load_robot(path))
    assert (tool.name, tool.frame_type) == ("hand", "body")


def test_prefixed_names_match_and_the_site_wins_over_the_body(tmp_path):
    text = ARM_WITH_FINGERS.format(hand="arm_flange", finger_site="marker").replace(
        '<geom type="box" size="0.02 0.05 0.02"/>',
        '<geom type="box" size="0.02 0.05 0.02"/><site name="left/pinch_site" pos="0.1 0 0"/>',
    )
    path = tmp_path / "arm.xml"
    path.write_text(text)
    tool = tool_frame(qpik.load_robot(path))
    assert (tool.name, tool.frame_type) == ("left/pinch_site", "site")  # a TCP before a flange


def test_bundled_robots_keep_site_ee():
    for name in qpik.list_robots():
        assert tool_frame(qpik.load_robot(name)).name == "ee"


# ------------------------------------------------------------------------------ demo
@pytest.mark.parametrize("robot", ["panda", "ur5e", "planar_4r"])
def test_demo_on_the_bundled_robots(robot, capsys):
    assert main(["demo", "--robot", robot]) == 0
    assert "site 'ee'" in capsys.readouterr().out


def test_demo_on_a_menagerie_arm(capsys):
    assert main(["demo", "--robot", str(MENAGERIE / "xarm7.xml")]) == 0
    out = capsys.readouterr().out
    assert "site 'link_tcp'" in out and "converged" in out


@requires_erd
@pytest.mark.parametrize(
    ("robot", "frame"),
    [
        ("erd:panda", "panda_hand_tcp"),
        ("erd:ur5", "tool0"),
        ("erd:talos", "wrist_left_ft_tool_link"),
    ],
)
def test_demo_on_example_robot_data(robot, frame, capsys):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # dropped .dae meshes
        assert main(["demo", "--robot", robot]) == 0
    assert f"body '{frame}'" in capsys.readouterr().out
