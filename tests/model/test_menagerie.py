"""The robots users bring (issue 22): tool frames as the model names them, collision pairs
and support polygons from the model's own geometry; on trimmed copies of MuJoCo Menagerie
models (``tests/data/menagerie``: meshes removed, licences beside), the bundled robots and
example-robot-data."""

from __future__ import annotations

import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest
from conftest import requires_erd
from scipy.spatial import ConvexHull

import qpik
from qpik.cli import main
from qpik.limits import (
    SupportPolygonLimit,
    collision_geoms,
    collision_pairs,
    joint_limits,
    model_collision_limit,
)
from qpik.robots import gripper_joints, tool_frame
from qpik.scene import add_obstacle
from qpik.tasks import PositionTask, PostureTask

MENAGERIE = Path(__file__).resolve().parents[1] / "data" / "menagerie"


def menagerie(name: str, **kwargs) -> mujoco.MjModel:
    return qpik.load_robot(MENAGERIE / f"{name}.xml", **kwargs)


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
    path.write_text(ARM_WITH_FINGERS.format(hand="arm_end", finger_site="marker"))
    tool = tool_frame(qpik.load_robot(path))
    assert (tool.name, tool.frame_type) == ("arm_end", "body") and "longest chain" in tool.reason
    # A TCP's name on a finger is skipped too: the hand's name wins.
    path.write_text(ARM_WITH_FINGERS.format(hand="hand", finger_site="tcp"))
    tool = tool_frame(qpik.load_robot(path))
    assert (tool.name, tool.frame_type) == ("hand", "body")
    # A hand's name followed by "_link" (booster_t1's left_hand_link) is a hand's name.
    path.write_text(ARM_WITH_FINGERS.format(hand="left_hand_link", finger_site="marker"))
    tool = tool_frame(qpik.load_robot(path))
    assert (tool.name, tool.frame_type) == ("left_hand_link", "body")
    assert "a hand's name" in tool.reason


@requires_erd
def test_a_hands_fingers_named_index_to_pinky_are_never_the_tool_frame():
    """erd Alex with Psyonic hands: fingers named Left_index_q1 ... Left_pinky_q2 (only the
    thumb has a gripper word): the tool frame is no finger (before: Left_index_anchor, moved
    by two finger joints), the palm the fingers branch from; erd human's midline joints
    (middle_lumbar_Z: one finger word alone) stay the body's, its tool frame a hand."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # dropped meshes
        model = qpik.load_robot("erd:alex_psyonic_hands")
    tool = tool_frame(model)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, tool.name)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    mujoco.mj_jacBody(model, data, jacp, jacr, body)
    fingers = gripper_joints(model)
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in fingers]
    assert {"Left_index_q1", "Left_pinky_q2", "Left_thumb_q1"} <= set(names)
    dofs = [int(model.jnt_dofadr[j]) for j in fingers]
    assert np.abs(jacp[:, dofs]).max() == 0.0 and np.abs(jacr[:, dofs]).max() == 0.0
    assert tool.name == "Left_thumb_base"  # (its fixed child: where every finger attaches)
    human = qpik.load_robot("erd:human")
    assert gripper_joints(human) == []
    assert tool_frame(human).name == "left_hand"


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


# ------------------------------------------------------- collision from the model's geometry


@pytest.mark.parametrize("name", ["panda", "ur5e"])
def test_bundled_arms_split_visual_and_collision_geoms(name):
    model = qpik.load_robot(name)
    colliding = collision_geoms(model)
    assert colliding
    for g in range(model.ngeom):
        if g in colliding:  # Menagerie's collision class: group 3, massless here
            assert model.geom_group[g] == 3 and model.geom_contype[g] == 1
            assert model.geom(g).name + "_visual" in qpik.frame_names(model, "geom")
        else:  # visual: no contact, group 2, the link's mass
            assert model.geom_group[g] == 2 and model.geom_conaffinity[g] == 0
    # Every moving body has a collision geom.
    moving = {b for b in range(1, model.nbody) if model.body_weldid[b] != 0}
    welds = {int(model.body_weldid[model.geom_bodyid[g]]) for g in colliding}
    assert {int(model.body_weldid[b]) for b in moving} <= welds


def test_collision_geoms_carry_no_mass():
    # The same model with the collision geoms deleted: masses and inertias bit for bit.
    spec = mujoco.MjSpec.from_file(str(qpik.robots.robot_path("panda")))
    full = spec.compile()
    for geom in list(spec.geoms):
        if geom.classname.name == "collision":
            spec.delete(geom)
    bare = spec.compile()
    assert bare.ngeom == full.ngeom // 2
    for field in ("body_mass", "body_inertia", "body_ipos", "body_iquat", "body_pos"):
        assert np.array_equal(getattr(bare, field), getattr(full, field)), field


@pytest.mark.parametrize(("name", "loader"), [("panda", qpik.load_robot), ("g1", menagerie)])
def test_collision_pairs_hold_every_contact_mujoco_finds(name, loader, rng):
    model = loader(name)
    pairs = set(collision_pairs(model))
    data = mujoco.MjData(model)
    found = 0
    for _ in range(300):
        configuration = qpik.Configuration(model)
        data.qpos[:] = configuration.random_q(rng)
        mujoco.mj_forward(model, data)
        for contact in data.contact[: data.ncon]:
            a, b = sorted((int(contact.geom1), int(contact.geom2)))
            adjacent = model.body_parentid[model.geom_bodyid[a]] == model.geom_bodyid[b] or (
                model.body_parentid[model.geom_bodyid[b]] == model.geom_bodyid[a]
            )
            assert (a, b) in pairs or adjacent, (model.geom(a).name, model.geom(b).name)
            found += 1
    assert found  # random configurations do collide


def test_collision_pairs_exclude_adjacent_and_excluded_bodies():
    model = qpik.load_robot("panda")
    names = {(model.geom(a).name, model.geom(b).name) for a, b in collision_pairs(model)}
    assert ("link3", "link5") in names and ("link1", "link7") in names
    assert ("link6", "link7") not in names and ("link3", "link4") not in names  # adjacent
    assert ("link2", "link4") not in names  # the model's <exclude>
    assert ("link6", "hand") not in names  # hand is welded to link7: adjacent to link6
    data = mujoco.MjData(model)
    data.qpos[:] = model.key_qpos[0]
    mujoco.mj_forward(model, data)
    assert data.ncon == 0  # no pair in contact at home


def test_obstacles_collide_with_the_robot_by_default():
    for model in (qpik.load_robot("panda"), menagerie("ur5e")):
        scene = add_obstacle(model, "box", [0.1, 0.1, 0.1], [0.5, 0.0, 0.3], name="crate")
        pairs = collision_pairs(scene, self_collision=False)
        crate = scene.geom("crate").id
        assert pairs and all(crate in pair for pair in pairs)
        robot = {g for pair in pairs for g in pair} - {crate}
        assert robot == {
            g
            for g in collision_geoms(scene, robot_only=True)
            if model.body_weldid[scene.geom_bodyid[g]]
        }


def test_model_collision_limit_needs_a_pair():
    scene_only = model_collision_limit(
        add_obstacle(qpik.load_robot("panda"), "sphere", 0.05, [0.5, 0, 0.5]),
        self_collision=False,
    )
    assert len(scene_only.geom_id_pairs) == 8  # link1..link7 and the hand (link1 too)
    with pytest.raises(qpik.CollisionPairError, match="robot-scene"):
        model_collision_limit(qpik.load_robot("panda"), self_collision=False)


DT = 0.01


def test_readme_reach_keeps_its_clearance_with_the_models_pairs():
    base = qpik.load_robot("panda")
    start = qpik.Configuration(base, base.key_qpos[0]).frame_pose("ee")[0]
    goal = start + np.array([0.0, 0.45, 0.0])
    model = add_obstacle(base, "sphere", 0.06, 0.5 * (start + goal), name="ball")
    avoid = model_collision_limit(
        model, minimum_distance_from_collisions=0.01, collision_detection_distance=0.1
    )
    tip = PositionTask("ee", gain=0.1)
    tip.set_target(goal)
    posture = PostureTask(model, cost=0.05)
    posture.set_target(model.key_qpos[0])
    solver = qpik.IKSolver(model, [[tip], [posture]], [avoid, *joint_limits(model)])
    configuration = qpik.Configuration(model, model.key_qpos[0])
    closest = np.inf
    for _ in range(300):
        configuration.integrate_inplace(solver.step(configuration, DT).velocity, DT)
        closest = min(closest, *avoid.distances(configuration).values())
    assert closest >= 0.009  # d_min = 10 mm, every pair (ball and self), to 1 mm
    assert np.linalg.norm(configuration.frame_pose("ee")[0] - goal) <= 0.02


# ------------------------------------------------------------ support from the feet's geometry
def _talos():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return qpik.load_robot("erd:talos", floating_base=True)


@requires_erd
def test_talos_support_polygon_from_the_feet_meshes():
    talos = _talos()
    configuration = qpik.Configuration(talos, talos.key("half_sitting").qpos)
    feet = ["left_sole_link", "right_sole_link"]
    limit = SupportPolygonLimit(talos, feet)  # no footprint: the feet's collision meshes
    points = limit.support_points(configuration)
    x, y = points[:, 0], points[:, 1]
    assert 0.18 < x.max() - x.min() < 0.3  # Talos's soles: about 0.22 m long
    assert 0.25 < y.max() - y.min() < 0.4  # two 0.13 m soles 0.17 m apart
    assert 0.04 < limit.com_margin(configuration) < 0.14
    # An explicit footprint still overrides the geometry.
    sole = [[0.1, 0.05], [0.1, -0.05], [-0.1, 0.05], [-0.1, -0.05]]
    explicit = SupportPolygonLimit(talos, feet, footprint=sole)
    assert np.allclose(np.ptp(explicit.support_points(configuration)[:, 0]), 0.2, atol=0.01)


@pytest.mark.parametrize(("name", "length"), [("g1", 0.19), ("h1", 0.2)])
def test_menagerie_humanoid_support_from_spheres_and_capsules(name, length):
    model = menagerie(name)
    configuration = qpik.Configuration(model, model.key_qpos[0] if model.nkey else None)
    limit = SupportPolygonLimit(model, ["left_foot", "right_foot"])
    x = limit.support_points(configuration)[:, 0]
    assert x.max() - x.min() == pytest.approx(length, abs=0.03)
    assert limit.com_margin(configuration) > 0.0  # the keyframe stands


FOOT = """
<mujoco>
  <asset>
    <mesh name="wedge" vertex="-0.1 -0.05 0  0.1 -0.05 0  0.1 0.05 0  -0.1 0.05 0  0 0 0.05"/>
  </asset>
  <worldbody>
    <body name="pelvis" pos="0 0 0.6">
      <freejoint/>
      <geom type="box" size="0.1 0.15 0.05"/>
      <body name="left_ankle" pos="0 0.12 -0.5">
        <joint name="left_knee" axis="0 1 0"/>
        <geom type="sphere" size="0.03" contype="0" conaffinity="0" group="2"/>
        <body name="left_sole" pos="0 0 -0.08">
          <geom type="box" size="0.1 0.05 0.01" pos="0.02 0 0"/>
        </body>
      </body>
      <body name="right_ankle" pos="0 -0.12 -0.5">
        <joint name="right_knee" axis="0 1 0"/>
        <body name="right_sole" pos="0 0 -0.08">
          <geom type="mesh" mesh="wedge"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_support_polygon_is_the_boxes_and_meshes_projection():
    model = mujoco.MjModel.from_xml_string(FOOT)
    configuration = qpik.Configuration(model)
    limit = SupportPolygonLimit(model, ["left_ankle", "right_sole"])  # a box, a mesh
    # The box's corners (on the sole welded under the ankle) and the wedge's base, exactly.
    box = [(x, y) for x in (-0.08, 0.12) for y in (0.07, 0.17)]
    wedge = [(x, y) for x in (-0.1, 0.1) for y in (-0.17, -0.07)]
    expected = ConvexHull(np.array(box + wedge))
    normals, offsets = limit.hull(configuration)
    assert len(normals) == len(expected.equations)
    com = limit.com(configuration)[:2]
    margin = float(-(expected.equations[:, :2] @ com + expected.equations[:, 2]).max())
    assert limit.com_margin(configuration) == pytest.approx(margin, abs=1e-6)  # float32 mesh
    assert margin > 0.05


# ------------------------------------------------------------------------- problem files
TASKS = Path(__file__).resolve().parents[2] / "tasks"


def test_problem_file_obstacles_and_collision_limits():
    from qpik.problem import load_problem

    problem = load_problem(TASKS / "panda_obstacle_avoidance.toml")
    assert problem.model.geom("ball").size[0] == pytest.approx(0.06)
    limit = problem.build_limits()[-1]
    pairs = {
        (problem.model.geom(a).name, problem.model.geom(b).name) for a, b in limit.geom_id_pairs
    }
    assert ("ball", "hand") in pairs and ("link1", "link7") in pairs  # scene and self
    result = problem.solve()
    assert result.converged
    configuration = problem.start_configuration()
    closest = np.inf
    for q in result.trace.q:
        configuration.update(q)
        closest = min(closest, *limit.distances(configuration).values())
    # min_distance = 10 mm; track mode's first large steps close to 7.6 mm (the same reach
    # through IKSolver keeps 9.3 mm): step bounds are issue 22's item 1.
    assert closest >= 0.005
    assert problem.to_dict()["limits"]["collision"]["self"] is True


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ('[[obstacles]]\nshape = "cone"\nsize = [0.1]\nposition = [0, 0, 0]', "obstacles[0].shape"),
        ('[[obstacles]]\nshape = "box"\nsize = [0.1]\nposition = [0, 0, 0]', "obstacles[0].size"),
        ('[[obstacles]]\nshape = "sphere"\nsize = 0.1\nposition = [0, 0]', "obstacles[0].position"),
        ("[limits.collision]\nself = false", "limits.collision"),  # no obstacle: no pair
        ("[limits.collision]\nmin_distance = 0.1\ndetection_distance = 0.05", "limits.collision"),
        ('[limits.collision]\npairs = [["link7", "ball"]]', "limits.collision.pairs[0]"),
        ("[limits.collision]\nwhat = 1", "limits.collision.what"),
    ],
)
def test_problem_file_collision_errors_name_the_field(tmp_path, text, field):
    from qpik.problem import load_problem

    path = tmp_path / "p.toml"
    head = 'robot = "panda"\n[[levels]]\n[[levels.tasks]]\ntype = "position"\nframe = "ee"\n'
    path.write_text(head + "[target]\nposition = [0.3, 0.2, 0.5]\n" + text + "\n")
    with pytest.raises(qpik.ProblemFileError, match=field.replace("[", r"\[").replace("]", r"\]")):
        load_problem(path)
