"""qpik.scene.add_obstacle: a new model with the obstacle, the robot's part bit for bit."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest
from conftest import has_erd

import qpik
from qpik.limits import geom_distance
from qpik.scene import add_obstacle

ROBOT_ARRAYS = [
    "qpos0",
    "body_pos",
    "body_quat",
    "body_mass",
    "body_inertia",
    "body_ipos",
    "body_subtreemass",
    "jnt_range",
    "jnt_axis",
    "dof_armature",
    "key_qpos",
    "numeric_data",
    "jnt_actfrcrange",
    "actuator_gear",
]


def _sources():
    sources = [("panda", False), ("ur5e", False)]
    if has_erd():
        sources += [("erd:panda", False), ("erd:talos", True)]
    return sources


@pytest.mark.parametrize("source, floating", _sources())
def test_obstacles_leave_the_robot_bit_for_bit(source, floating):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = qpik.load_robot(source, floating_base=floating)
    ngeom = model.ngeom
    scene = add_obstacle(model, "sphere", 0.05, [0.4, 0.0, 0.5])
    scene = add_obstacle(scene, "box", [0.1, 0.2, 0.3], [0.4, 0.3, 0.5], name="wall")
    scene = add_obstacle(scene, "capsule", [0.03, 0.2], [-0.4, 0.0, 0.3])
    assert model.ngeom == ngeom  # the model passed in is unchanged
    assert scene.ngeom == ngeom + 3
    for name in ROBOT_ARRAYS:
        np.testing.assert_array_equal(getattr(scene, name), getattr(model, name), err_msg=name)
    # Same kinematics: frames at a random configuration are bitwise equal.
    q = qpik.Configuration(model).random_q(np.random.default_rng(0))
    a, b = qpik.Configuration(model, q), qpik.Configuration(scene, q)
    np.testing.assert_array_equal(a.data.xpos, b.data.xpos)
    np.testing.assert_array_equal(a.data.xmat, b.data.xmat)
    for name, shape, size in [
        ("obstacle0", mujoco.mjtGeom.mjGEOM_SPHERE, [0.05, 0, 0]),
        ("wall", mujoco.mjtGeom.mjGEOM_BOX, [0.1, 0.2, 0.3]),
        ("obstacle1", mujoco.mjtGeom.mjGEOM_CAPSULE, [0.03, 0.2, 0]),
    ]:
        geom = scene.geom(name)
        assert geom.type == shape and geom.bodyid == 0
        np.testing.assert_array_equal(geom.size, size)
        assert geom.contype == 1 and geom.conaffinity == 1


def test_sphere_distance_is_the_closed_form():
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    hand_centre = configuration.data.geom_xpos[model.geom("link5").id]  # link5: sphere r=0.06
    centre = hand_centre + np.array([0.0, 0.25, 0.0])
    scene = add_obstacle(model, "sphere", 0.1, centre, name="ball")
    configuration = qpik.Configuration(scene, scene.key_qpos[0])
    assert geom_distance(configuration, "link5", "ball") == pytest.approx(0.25 - 0.06 - 0.1)


@pytest.mark.parametrize(
    "args, kwargs, match",
    [
        (("cone", 0.1, [0, 0, 0]), {}, "sphere, box, capsule"),
        (("sphere", [0.1, 0.2], [0, 0, 0]), {}, r"\[radius\]"),
        (("box", [0.1, 0.2], [0, 0, 0]), {}, "half_x"),
        (("capsule", [0.1, -0.2], [0, 0, 0]), {}, "positive"),
        (("sphere", 0.1, [0, np.nan, 0]), {}, "position"),
        (("sphere", 0.1, [0, 0]), {}, "position"),
        (("sphere", 0.1, [0, 0, 0]), {"name": "hand"}, "already has a geom named 'hand'"),
        (("sphere", "big", [0, 0, 0]), {}, "numbers"),
    ],
)
def test_bad_obstacles_raise_scene_error(args, kwargs, match):
    model = qpik.load_robot("panda")
    with pytest.raises(qpik.SceneError, match=match):
        add_obstacle(model, *args, **kwargs)


def test_model_not_built_by_load_robot_says_how_to_fix():
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
    with pytest.raises(qpik.SceneError, match="qpik.load_robot"):
        add_obstacle(model, "sphere", 0.1, [0, 0, 0])
    with pytest.raises(qpik.SceneError, match="MjModel"):
        add_obstacle("panda", "sphere", 0.1, [0, 0, 0])
