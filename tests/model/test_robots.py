"""Robot loading: bundled models, URDF import specifics, example-robot-data."""

from __future__ import annotations

import math
import warnings

import mujoco
import numpy as np
import pytest
from conftest import has_erd, requires_erd

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


@pytest.mark.skipif(not has_erd(), reason="example-robot-data not installed (qpik[robots])")
@pytest.mark.parametrize("name", ["panda", "ur5"])
def test_erd_robots_load_with_tool_frames(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = qpik.load_robot(f"erd:{name}")
    bodies = qpik.frame_names(model, "body")
    assert ("panda_hand" if name == "panda" else "tool0") in bodies


def test_erd_unknown_name_lists_known(monkeypatch):
    if not has_erd():
        pytest.skip("example-robot-data not installed")
    with pytest.raises(qpik.UnknownRobot, match="erd:panda"):
        qpik.load_robot("erd:nonexistent")
    assert "ur5" in ERD_ROBOTS


# ------------------------------------------------------------ example-robot-data


def _quiet_load(source, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return qpik.load_robot(source, **kwargs)


def _erd_names() -> list[str]:
    return list(qpik.robots.erd_robots()) if has_erd() else []


def _check_erd_robot(name):
    model = _quiet_load(f"erd:{name}")
    assert model.nbody >= 2
    tool = qpik.robots.tool_frame(model)
    assert tool.name in qpik.frame_names(model, tool.frame_type)
    floating = _quiet_load(f"erd:{name}", floating_base=True)
    assert floating.nv == model.nv + 6


#: One robot per quirk: a mesh MuJoCo rejects (alex), non-positive-definite inertias (tiago),
#: an SRDF with a root pose (talos), quadrupeds, arms.
QUIRKS = ["alex_nub_hands", "tiago_no_hand", "talos", "go2", "ur10", "xarm7", "kinova"]


@requires_erd
@pytest.mark.parametrize("name", QUIRKS)
def test_erd_robots_with_quirks_load(name):
    _check_erd_robot(name)


@pytest.mark.slow
@requires_erd
@pytest.mark.parametrize("name", _erd_names())
def test_every_erd_robot_loads(name):
    """Every robot example-robot-data ships (about 40 s: ``pytest -m slow``)."""
    _check_erd_robot(name)


@requires_erd
@pytest.mark.parametrize("name", ["talos", "go1", "solo12", "panda"])
def test_floating_base_adds_a_free_root_joint(name):
    fixed = _quiet_load(f"erd:{name}")
    floating = _quiet_load(f"erd:{name}", floating_base=True)
    assert floating.nq == fixed.nq + 7 and floating.nv == fixed.nv + 6
    assert floating.joint("root_joint").type == mujoco.mjtJoint.mjJNT_FREE
    # With the base at the root body's rest pose, every body is where the fixed model has it.
    rng = np.random.default_rng(1)
    q = qpik.Configuration(fixed).random_q(rng)
    base = floating.qpos0[:7]
    a = qpik.Configuration(fixed, q)
    b = qpik.Configuration(floating, np.concatenate([base, q]))
    np.testing.assert_allclose(b.data.xpos, a.data.xpos, atol=1e-12)


@requires_erd
def test_talos_half_sitting_comes_from_the_srdf():
    import xml.etree.ElementTree as ET

    model = _quiet_load("erd:talos", floating_base=True)
    key = model.key("half_sitting").qpos
    srdf = qpik.robots.erd_robots_folder() / "talos_data/srdf/talos.srdf"
    state = next(
        s for s in ET.parse(srdf).getroot().iter("group_state") if s.get("name") == "half_sitting"
    )
    for joint in state.iter("joint"):
        values = [float(v) for v in joint.get("value").split()]
        adr = model.joint(joint.get("name")).qposadr[0]
        if joint.get("name") == "root_joint":  # Pinocchio's x y z qx qy qz qw
            np.testing.assert_array_equal(
                key[adr : adr + 7], values[:3] + [values[6], *values[3:6]]
            )
        else:
            assert key[adr] == values[0]
    # Half sitting puts the soles on the ground.
    configuration = qpik.Configuration(model, key)
    for sole in ("left_sole_link", "right_sole_link"):
        assert abs(configuration.frame_pose(sole, "body")[0][2]) < 1e-4
    # Without a floating base the state's joints still load (the root pose is skipped).
    fixed = _quiet_load("erd:talos")
    np.testing.assert_array_equal(fixed.key("half_sitting").qpos, key[7:])
    assert _quiet_load("erd:talos", srdf=False).nkey == 0


def test_srdf_given_or_found_beside_the_urdf(tmp_path):
    (tmp_path / "urdf").mkdir()
    urdf = tmp_path / "urdf" / "tool_arm.urdf"
    urdf.write_text(URDF)
    srdf = """<robot name="tool_arm">
      <group_state name="ready" group="arm">
        <joint name="shoulder" value="0.5"/><joint name="elbow" value="-1.25"/>
        <joint name="no_such_joint" value="3"/>
      </group_state>
    </robot>"""
    (tmp_path / "srdf").mkdir()
    (tmp_path / "srdf" / "tool_arm.srdf").write_text(srdf)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        found = qpik.load_robot(urdf)
        other = tmp_path / "poses.srdf"
        other.write_text(srdf.replace("ready", "folded"))
        given = qpik.load_robot(urdf, srdf=other)
        with pytest.raises(qpik.RobotFileError, match="no such SRDF"):
            qpik.load_robot(urdf, srdf=tmp_path / "missing.srdf")
    np.testing.assert_array_equal(found.key("ready").qpos, [0.5, -1.25])
    np.testing.assert_array_equal(given.key("folded").qpos, [0.5, -1.25])


def test_urdf_velocity_and_effort_limits_are_imported(tmp_path):
    path = tmp_path / "tool_arm.urdf"
    path.write_text(URDF)
    model = _quiet_load(path)
    configuration = qpik.Configuration(model)
    # shoulder: velocity 1 rad/s, effort 10 N m; elbow (continuous, no <limit>): none.
    np.testing.assert_array_equal(configuration.velocity_limits(), [1.0, np.inf])
    limits = qpik.limits.joint_limits(model)
    velocity = [lim for lim in limits if isinstance(lim, qpik.limits.VelocityLimit)]
    assert len(velocity) == 1 and velocity[0].limit.tolist() == [1.0]
    assert model.jnt_actfrcrange[model.joint("shoulder").id].tolist() == [-10.0, 10.0]


@requires_erd
@pytest.mark.parametrize("name", ["panda", "ur5", "talos"])
def test_erd_velocity_limits_are_the_urdfs(name):
    import xml.etree.ElementTree as ET

    model = _quiet_load(f"erd:{name}")
    path = qpik.robots.erd_path(name)
    vmax = qpik.Configuration(model).velocity_limits()
    for joint in ET.parse(path).getroot().iter("joint"):
        limit = joint.find("limit")
        if joint.get("type") in ("fixed", None) or limit is None or limit.get("velocity") is None:
            continue
        assert vmax[model.joint(joint.get("name")).dofadr[0]] == float(limit.get("velocity"))
    assert any(
        isinstance(lim, qpik.limits.VelocityLimit) for lim in qpik.limits.joint_limits(model)
    )


@requires_erd
def test_readme_recipe_bounds_joint_velocities_on_erd_panda():
    from qpik.tasks import FrameTask, JointLimitDistanceTask

    model = _quiet_load("erd:panda")
    configuration = qpik.Configuration(model)
    stretched = configuration.mid_q()
    stretched[3] = -0.1  # elbow almost straight: a near-singular pose
    configuration.update(stretched)
    task = FrameTask("panda_hand_tcp", "body", position_cost=1.0, orientation_cost=1.0)
    position, rotation = configuration.frame_pose("panda_hand_tcp", "body")
    import mink

    task.set_target(
        mink.SE3.from_rotation_and_translation(
            mink.SO3.from_matrix(rotation), position + [0.3, 0.2, 0.1]
        )
    )
    solver = qpik.IKSolver(
        model, [[task], [JointLimitDistanceTask()]], qpik.limits.joint_limits(model)
    )
    vmax = configuration.velocity_limits()
    for _ in range(30):
        step = solver.step(configuration, 0.01)
        assert np.all(np.abs(step.velocity) <= vmax + 1e-9)
        configuration.integrate_inplace(step.velocity, 0.01)


@requires_erd
def test_unknown_erd_name_lists_example_robot_datas_robots():
    with pytest.raises(qpik.UnknownRobot) as info:
        qpik.load_robot("erd:nonexistent")
    message = str(info.value)
    assert "example-robot-data" in message and "bundled" not in message
    assert "erd:talos" in message and "erd:go1" in message


def test_tool_frame_rules(tmp_path):
    assert qpik.robots.tool_frame(qpik.load_robot("panda")).name == "ee"  # the site ee
    path = tmp_path / "tool_arm.urdf"
    path.write_text(URDF)
    tool = qpik.robots.tool_frame(_quiet_load(path))
    assert (tool.name, tool.frame_type) == ("tool0", "body") and "flange's name" in tool.reason
    # No known name: the end of the longest chain (down through fixed links).
    path.write_text(URDF.replace("tool0", "link_end"))
    tool = qpik.robots.tool_frame(_quiet_load(path))
    assert tool.name == "link_end" and "longest chain" in tool.reason


def test_floating_base_errors(tmp_path):
    with pytest.raises(qpik.RobotFileError, match="already has a joint"):
        qpik.load_robot(qpik.robots.robot_path("planar_2r"), floating_base=True)
    with pytest.raises(qpik.RobotFileError, match="not to a model"):
        qpik.load_robot(qpik.load_robot("panda"), floating_base=True)


@requires_erd
def test_problem_file_starts_from_an_srdf_state(tmp_path):
    problem = tmp_path / "talos.toml"
    problem.write_text(
        'robot = "erd:talos"\nq0 = "half_sitting"\n'
        '[[levels]]\n[[levels.tasks]]\ntype = "position"\nframe = "gripper_left_base_link"\n'
        'frame_type = "body"\n[target]\nposition = [0.3, 0.4, 1.0]\n'
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loaded = qpik.load_problem(problem)
    np.testing.assert_array_equal(loaded.q0, loaded.model.key("half_sitting").qpos)


def test_problem_velocity_scale_leaves_unlimited_dofs_free(tmp_path):
    (tmp_path / "arm.urdf").write_text(URDF)
    (tmp_path / "p.toml").write_text(
        'robot = "arm.urdf"\nmode = "track"\n[[levels]]\n[[levels.tasks]]\ntype = "position"\n'
        'frame = "tool0"\nframe_type = "body"\n[target]\nposition = [0.5, 0.2, 0.4]\n'
        "[limits]\nvelocity = 0.5\n[track]\ndt = 0.01\nsteps = 5\n"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        problem = qpik.load_problem(tmp_path / "p.toml")
    # shoulder: 0.5 x the URDF's 1 rad/s; the continuous elbow declares none.
    np.testing.assert_array_equal(problem.velocity_limits, [0.5, np.inf])
    (velocity,) = [
        lim for lim in problem.build_limits() if isinstance(lim, qpik.limits.VelocityLimit)
    ]
    assert velocity.limit.tolist() == [0.5]


def test_resolve_robot_is_the_one_resolver(tmp_path):
    import shutil

    from qpik.robots import locate_robot, resolve_robot, robot_path

    model, q = resolve_robot("planar_2r")
    assert model.nq == 2 and q is None
    assert resolve_robot(model) == (model, None)
    configuration = qpik.Configuration(model, [0.3, -0.2])
    same, q = resolve_robot(configuration)
    assert same is model and q.tolist() == [0.3, -0.2]
    q[0] = 9.0  # a copy: the caller's configuration is untouched
    assert configuration.q[0] == 0.3
    with pytest.raises(qpik.InvalidInput, match="robot must be"):
        resolve_robot(3.0)
    with pytest.raises(qpik.UnknownRobot):
        resolve_robot("no_such_robot")
    # a relative path is read from relative_to (a problem file's folder)
    shutil.copy(robot_path("planar_2r"), tmp_path / "arm.xml")
    assert locate_robot("arm.xml", relative_to=tmp_path) == tmp_path / "arm.xml"
    assert resolve_robot("arm.xml", relative_to=tmp_path)[0].nq == 2
    assert locate_robot("planar_2r", relative_to=tmp_path) == robot_path("planar_2r")


@pytest.mark.filterwarnings("ignore:.*collision mesh")  # (the URDF's .dae mesh, dropped)
def test_urdf_empty_joint_limit_is_a_robot_file_error(tmp_path):
    """Pins repro_14: a URDF <limit lower="1.0" upper="-1.0"> is a RobotFileError naming the
    file and the joint (MuJoCo would load the joint unlimited; the same range in MJCF is an
    error too)."""
    path = tmp_path / "inverted.urdf"
    path.write_text(URDF.replace('lower="-2" upper="2"', 'lower="1.0" upper="-1.0"'))
    with pytest.raises(qpik.RobotFileError, match="shoulder") as info:
        qpik.load_robot(path)
    assert info.value.path == str(path) and "lower above upper" in str(info.value)
    mjcf = tmp_path / "inverted.xml"
    mjcf.write_text(
        '<mujoco><worldbody><body><joint name="j1" limited="true" range="1 -1"/>'
        '<geom size="0.1"/></body></worldbody></mujoco>'
    )
    with pytest.raises(qpik.RobotFileError):
        qpik.load_robot(mjcf)
    path.write_text(URDF.replace('lower="-2" upper="2"', 'lower="-1.0" upper="1.0"'))
    assert qpik.load_robot(path).jnt_limited[0]  # an ordinary range still loads limited


@pytest.mark.parametrize(
    "site, expected",
    [("EE", "EE"), ("link_grasp_center", "link_grasp_center"), ("Arm/EE", "Arm/EE")],
)
def test_tool_site_names_match_in_any_case_and_grasp_centres(site, expected):
    """Spot's site is ``EE`` and Stretch's ``link_grasp_center`` (Menagerie): they are the
    tool frame, not a wrist link or a marker body found on a longer chain."""
    import mujoco

    from qpik.robots import tool_frame

    model = mujoco.MjModel.from_xml_string(
        f"""<mujoco><worldbody><body name="link1"><joint name="j1" axis="0 0 1"/>
          <geom size=".05"/><body name="link2" pos="0 0 .3"><joint name="j2"/>
          <geom size=".05"/><body name="aruco_top_wrist" pos="0 0 .3"><joint name="j3"/>
          <geom size=".02"/></body><site name="{site}" pos="0 0 .2"/></body></body>
        </worldbody></mujoco>"""
    )
    frame = tool_frame(model)
    assert (frame.frame_type, frame.name) == ("site", expected), frame


def _chain_mjcf(bodies: list[tuple[str, str | None, str]]) -> str:
    """An MJCF of nested bodies ``(name, joint name or None, parent name)`` ('world': the
    world body), hinges about z, each 0.1 m from its parent."""
    children: dict[str, list] = {}
    for name, joint, parent in bodies:
        children.setdefault(parent, []).append((name, joint))

    def body(name: str, joint: str | None) -> str:
        inner = f'<joint name="{joint}" axis="0 0 1" range="-1 1"/>' if joint else ""
        inner += '<geom size="0.01"/>'
        inner += "".join(body(c, j) for c, j in children.get(name, []))
        return f'<body name="{name}" pos="0.1 0 0">{inner}</body>'

    world = "".join(body(c, j) for c, j in children.get("world", []))
    return f"<mujoco><worldbody>{world}</worldbody></mujoco>"


def test_tool_frame_is_moved_by_the_arm_and_ends_it():
    """Pins the h9 audit's tool frames: a robot whose every joint has a finger's name (erd
    finger_edu) is its own arm, its tip the tool (was its base, which no joint moves: rank
    0); a link named wrist above the wrist's roll joint is not the tool (erd so101: was
    wrist_link, one joint short); a hand alone (Allegro) is tooled at a fingertip, not at
    its palm that nothing moves; a palm with fingers below it stays a humanoid's tool."""
    import mujoco

    finger = _chain_mjcf(
        [
            ("finger_base_link", None, "world"),
            ("finger_upper_link", "finger_base_to_upper_joint", "finger_base_link"),
            ("finger_middle_link", "finger_upper_to_middle_joint", "finger_upper_link"),
            ("finger_tip_link", "finger_middle_to_lower_joint", "finger_middle_link"),
        ]
    )
    tool = qpik.robots.tool_frame(mujoco.MjModel.from_xml_string(finger))
    assert tool.name == "finger_tip_link" and "longest chain" in tool.reason
    arm = [
        ("base", None, "world"),
        ("upper_arm_link", "shoulder", "base"),
        ("wrist_link", "wrist_flex", "upper_arm_link"),
        ("gripper_link", "wrist_roll", "wrist_link"),
        ("jaw", "gripper", "gripper_link"),
    ]
    assert qpik.robots.tool_frame(mujoco.MjModel.from_xml_string(_chain_mjcf(arm))).name == (
        "gripper_link"
    )
    # a wrist joint named for the gripper and an axis (erd Alex's LeftGripperYaw) is the arm's
    yaw = [*arm[:3], ("wrist_roll_link", "LeftWristRoll", "wrist_link"), ("nub", "LeftGripperYaw", "wrist_roll_link")]  # fmt: skip
    assert qpik.robots.tool_frame(mujoco.MjModel.from_xml_string(_chain_mjcf(yaw))).name == "nub"
    fingers = [(f"f{i}_{k}", f"f{i}_j{k}", f"f{i}_{k - 1}" if k else "palm") for i in range(3) for k in range(2)]  # fmt: skip
    hand = _chain_mjcf([("palm", None, "world"), *fingers])
    tool = qpik.robots.tool_frame(mujoco.MjModel.from_xml_string(hand))
    assert tool.name != "palm" and tool.name.endswith("_1")
    humanoid = _chain_mjcf([("torso", None, "world"), ("palm", "wrist_yaw", "torso"), *fingers])
    assert qpik.robots.tool_frame(mujoco.MjModel.from_xml_string(humanoid)).name == "palm"


@pytest.mark.parametrize("name", ["ur5e", "panda"])
def test_a_floating_base_keeps_the_files_keyframes_on_their_joints(name):
    """Pins h16's audit: with floating_base=True a file's keyframe (MJCF <key>) was read in
    the new coordinates, its arm values written onto the free joint (the base turned, every
    arm joint 0; panda's then outside its limits). The free joint's entries come first: the
    root body's pose, no velocity; the tool is where the fixed-base keyframe puts it."""
    fixed = qpik.load_robot(name)
    floating = qpik.load_robot(name, floating_base=True)
    assert floating.nkey == fixed.nkey >= 1
    for k in range(fixed.nkey):
        np.testing.assert_array_equal(floating.key_qpos[k][7:], fixed.key_qpos[k])
        np.testing.assert_array_equal(floating.key_qpos[k][:7], [0, 0, 0, 1, 0, 0, 0])
        np.testing.assert_array_equal(floating.key_qvel[k][6:], fixed.key_qvel[k])
        on_base = qpik.Configuration(floating, floating.key_qpos[k]).frame_pose("ee")
        for got, want in zip(
            on_base, qpik.Configuration(fixed, fixed.key_qpos[k]).frame_pose("ee")
        ):
            np.testing.assert_allclose(got, want, atol=1e-12)


def test_a_placeholder_velocity_limit_leaves_the_trust_region_on():
    """A URDF's 1000 rad/s "no limit" (erd solo12 and bolt) made a velocity limit at that
    speed: no trust region, a 7.5 rad turn in one 10 ms step. Speeds of PLACEHOLDER_SPEED
    or more are left out (the trust region holds the dof); real ones are kept."""
    from qpik.limits import PLACEHOLDER_SPEED, joint_limits, velocity_limit_from_model

    xml = (
        '<mujoco><custom><numeric name="velocity_limit" data="1000 2"/></custom><worldbody>'
        '<body><joint name="a" range="-3 3"/><geom size=".1"/><body><joint name="b" '
        'range="-3 3"/><geom size=".1"/></body></body></worldbody></mujoco>'
    )
    model = mujoco.MjModel.from_xml_string(xml)
    assert PLACEHOLDER_SPEED <= 1000
    velocity = velocity_limit_from_model(model)
    assert velocity is not None and list(velocity.indices) == [1]
    configuration = qpik.Configuration(model)
    posture = qpik.tasks.PostureTask(model, cost=1.0)
    posture.set_target(np.array([2.5, 2.5]))
    step = qpik.IKSolver(model, [[posture]], joint_limits(model)).step(configuration, 0.01)
    np.testing.assert_allclose(np.abs(step.displacement), [math.pi * 0.01, 2.0 * 0.01])
    assert "a upper (trust region)" in step.active_limits


@requires_erd
def test_erd_solo12_steps_within_the_trust_region():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = qpik.load_robot("erd:solo12", floating_base=True)
    configuration = qpik.Configuration(model)
    posture = qpik.tasks.PostureTask(model, cost=1.0)
    target = configuration.q.copy()
    target[7:] += 3.0
    posture.set_target(target)
    limits = qpik.limits.joint_limits(model)
    step = qpik.IKSolver(model, [[posture]], limits).step(configuration, 0.01)
    assert np.abs(step.displacement).max() <= math.pi * 0.01 + 1e-12


_URDF = """<robot name="r">
  <link name="base"/><link name="a"/><link name="b"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="{v1}" effort="{e1}"/></joint>
  <joint name="{n2}" type="{t2}"><parent link="a"/><child link="b"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="{lo2}" upper="{hi2}" velocity="0.2" effort="1"/>{mimic}</joint>
</robot>"""


def _urdf(tmp_path, **fields):
    values = dict(v1="1", e1="1", n2="j2", t2="prismatic", lo2="-0.1", hi2="0.1", mimic="")
    values.update(fields)
    path = tmp_path / "r.urdf"
    path.write_text(_URDF.format(**values))
    return path


@pytest.mark.parametrize(
    ("fields", "words"),
    [
        ({"n2": "j1"}, "joint name 'j1' is used by two joints"),
        ({"v1": "abc"}, 'velocity="abc"'),
        ({"v1": "nan"}, 'velocity="nan"'),
        ({"v1": "-3"}, 'velocity="-3"'),
        ({"e1": "nan"}, 'effort="nan"'),
    ],
)
def test_a_urdf_mujoco_would_load_as_another_robot_is_refused(tmp_path, fields, words):
    """An audit of robot files: a joint name used twice (the second joint lost its name and
    the first took its 0.2 rad/s), a velocity that is not a number >= 0 and an effort of
    NaN (both dropped: no limit) loaded without an error."""
    with pytest.raises(qpik.RobotFileError, match=words):
        qpik.load_robot(_urdf(tmp_path, **fields))
    assert qpik.Configuration(qpik.load_robot(_urdf(tmp_path))).velocity_limits().tolist() == [
        1.0,
        0.2,
    ]


def test_a_dropped_mimic_and_equal_bounds_are_named_in_a_warning(tmp_path):
    mimic = '<mimic joint="nope" multiplier="1"/>'
    with pytest.warns(UserWarning, match="<mimic joint='nope'> names a joint that does not"):
        model = qpik.load_robot(_urdf(tmp_path, t2="revolute", lo2="-1", hi2="1", mimic=mimic))
    assert model.neq == 0
    with pytest.warns(UserWarning, match="lower = upper = 0"):
        qpik.load_robot(_urdf(tmp_path, lo2="0", hi2="0"))


def test_non_finite_keyframes_are_refused(tmp_path):
    path = tmp_path / "k.xml"
    path.write_text(
        '<mujoco><worldbody><body><joint name="j"/><geom size=".1"/></body></worldbody>'
        '<keyframe><key name="k1" qpos="nan"/></keyframe></mujoco>'
    )
    with pytest.raises(qpik.RobotFileError, match="key_qpos of key 'k1' is not finite"):
        qpik.load_robot(path)
