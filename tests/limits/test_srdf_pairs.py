"""Collision pairs that no step can use: a URDF's SRDF ``<disable_collisions>`` (loaded as
MuJoCo contact excludes by :func:`qpik.load_robot`) and the self-collision pairs that
overlap in every pose (:func:`qpik.limits.always_in_contact`, left out by
:func:`qpik.limits.model_collision_limit`)."""

from __future__ import annotations

import warnings

import mink
import mujoco
import numpy as np
import pytest
from conftest import requires_erd

import qpik
from qpik.limits import always_in_contact, collision_pairs, model_collision_limit
from qpik.scene import add_obstacle
from qpik.tasks import PostureTask

_INERTIAL = (
    '<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" '
    'iyz="0"/></inertial>'
)


def _link(name: str) -> str:
    return (
        f'<link name="{name}">{_INERTIAL}<collision><geometry><sphere radius="0.05"/>'
        "</geometry></collision></link>"
    )


def _joint(name: str, parent: str, child: str) -> str:
    return (
        f'<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
        '<origin xyz="0.2 0 0"/><axis xyz="0 0 1"/><limit lower="-2" upper="2"/></joint>'
    )


URDF = (
    '<?xml version="1.0"?><robot name="chain4"><link name="base_link"/>'
    + "".join(_link(f"l{i}") for i in range(1, 5))
    + _joint("j1", "base_link", "l1")
    + _joint("j2", "l1", "l2")
    + _joint("j3", "l2", "l3")
    + _joint("j4", "l3", "l4")
    + "</robot>"
)

SRDF = """<robot name="chain4">
  <disable_collisions link1="l1" link2="l3" reason="Never"/>
  <disable_collisions link1="l1" link2="no_such_link" reason="User"/>
  <disable_default_collisions link="l4"/>
  <enable_collisions link1="l4" link2="l1"/>
</robot>"""


def _body_pairs(model: mujoco.MjModel) -> set[tuple[str, str]]:
    return {
        tuple(
            sorted((model.body(model.geom_bodyid[a]).name, model.body(model.geom_bodyid[b]).name))
        )
        for a, b in collision_pairs(model)
    }


def test_srdf_disable_collisions_become_excludes(tmp_path):
    urdf = tmp_path / "chain4.urdf"
    urdf.write_text(URDF)
    (tmp_path / "chain4.srdf").write_text(SRDF)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        found = qpik.load_robot(urdf)
        bare = qpik.load_robot(urdf, srdf=False)
    # l1-l3: disabled; l2-l4: l4's default disabled; l1-l4: enabled again (the unknown link
    # is skipped; adjacent links never pair anyway).
    assert _body_pairs(bare) == {("l1", "l3"), ("l1", "l4"), ("l2", "l4")}
    assert _body_pairs(found) == {("l1", "l4")}
    # MuJoCo's own collision detection follows them: l1 and l3 folded onto each other.
    data = mujoco.MjData(found)
    data.qpos[:] = [0.0, np.pi, 0.0, 0.0]  # l3 back at l1
    mujoco.mj_forward(found, data)
    assert data.ncon == 0
    data_bare = mujoco.MjData(bare)
    data_bare.qpos[:] = data.qpos
    mujoco.mj_forward(bare, data_bare)
    assert data_bare.ncon == 1


MJCF = """<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <body name="base" pos="0 0 0.5">
      <joint name="j0" axis="0 0 1" range="-1 1"/>
      <geom name="base_g" type="sphere" size="0.05"/>
      <body name="a" pos="0.2 0 0">
        <joint name="ja" axis="0 0 1" range="-0.1 0.1"/>
        <geom name="a_g" type="capsule" fromto="0 0 0 0.3 0 0" size="0.05"/>
      </body>
      <body name="b" pos="0.2 0.05 0">
        <joint name="jb" axis="1 0 0" range="-0.1 0.1"/>
        <geom name="b_g" type="capsule" fromto="0 0 0 0.3 0 0" size="0.05"/>
      </body>
      <body name="d" pos="-0.2 0 0">
        <joint name="jd" axis="0 0 1" range="-3 3"/>
        <geom name="d_g" type="sphere" size="0.05" pos="0 0.15 0"/>
      </body>
      <body name="e" pos="-0.29 0.15 0">
        <joint name="je" axis="0 0 1" range="-0.1 0.1"/>
        <geom name="e_g" type="sphere" size="0.05" pos="0 0 0"/>
      </body>
    </body>
  </worldbody>
</mujoco>"""


def _names(model, pairs):
    return {tuple(sorted((model.geom(a).name, model.geom(b).name))) for a, b in pairs}


def test_always_in_contact_is_the_pairs_no_pose_separates(tmp_path):
    path = tmp_path / "five.xml"
    path.write_text(MJCF)
    model = qpik.load_robot(path)
    # a and b overlap at their roots in every pose; d and e overlap at qpos0 only (d turns
    # away); a crate around the base overlaps it in every pose but is scene, never listed.
    scene = add_obstacle(model, "box", [0.08, 0.08, 0.08], [0.0, 0.0, 0.5], name="crate")
    pairs = collision_pairs(scene)
    assert {("a_g", "b_g"), ("d_g", "e_g")} <= _names(scene, pairs)
    assert any("crate" in p for p in _names(scene, pairs))
    assert _names(scene, always_in_contact(scene, pairs)) == {("a_g", "b_g")}
    # the same list on every call, and none with no sample but qpos0 would be larger
    assert always_in_contact(scene, pairs) == always_in_contact(scene, pairs)
    assert _names(scene, always_in_contact(scene, pairs, samples=0)) >= {("a_g", "b_g")}
    with pytest.raises(qpik.QpikError, match="samples"):
        always_in_contact(scene, pairs, samples=-1)
    for bad in ("a_g", [(0,)], [(0, "b")], [(True, 1)], 3):
        with pytest.raises(qpik.QpikError, match="pairs"):
            always_in_contact(scene, bad)
    with pytest.raises(qpik.QpikError, match="out of range"):
        always_in_contact(scene, [(0, scene.ngeom)])


def test_model_collision_limit_leaves_out_the_pairs_always_in_contact():
    model = mujoco.MjModel.from_xml_string(MJCF)
    limit = model_collision_limit(model)
    kept = model_collision_limit(model, keep_always_in_contact=True)
    assert _names(model, limit.always_in_contact) == {("a_g", "b_g")}
    assert kept.always_in_contact == []
    assert len(kept.geom_id_pairs) == len(limit.geom_id_pairs) + 1
    # The pair that no step separates makes level 0 infeasible; without it the step is
    # solved (and d turns away from e, which it overlaps at qpos0).
    posture = PostureTask(model, 1.0)
    posture.set_target(model.qpos0)
    statuses = {}
    for name, collision in (("default", limit), ("kept", kept)):
        solver = qpik.IKSolver(model, [[posture]], [mink.ConfigurationLimit(model), collision])
        configuration = qpik.Configuration(model)
        result = solver.step(configuration, 0.05)  # (the trust region: 0.16 rad a step)
        statuses[name] = [s.value for s in result.status]
        if name == "default":
            assert abs(result.velocity[3]) > 0  # jd moves d off e
    assert statuses == {"default": ["solved"], "kept": ["infeasible"]}
    with pytest.raises(qpik.QpikError, match="keep_always_in_contact"):
        model_collision_limit(model, keep_always_in_contact="yes")


@requires_erd
def test_erd_robots_keep_only_pairs_a_step_can_meet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        talos = qpik.load_robot("erd:talos")
        bare = qpik.load_robot("erd:talos", srdf=False)
        tiago = qpik.load_robot("erd:tiago")  # no SRDF beside it
    left = ("arm_left_5_link", "arm_left_7_link")  # their meshes overlap in every pose
    assert left not in _body_pairs(talos) and left in _body_pairs(bare)
    # Without the SRDF the sampled poses find the same pair always in contact.
    limit = model_collision_limit(bare)
    found = {
        tuple(sorted((bare.body(bare.geom_bodyid[a]).name, bare.body(bare.geom_bodyid[b]).name)))
        for a, b in limit.always_in_contact
    }
    assert left in found
    # Tiago's hand: fingers modelled inside the palm
    assert model_collision_limit(tiago).always_in_contact
    # From half_sitting a Talos step under its SRDF's pairs is solved at every level.
    posture = PostureTask(talos, 0.1)
    posture.set_target(talos.key("half_sitting").qpos)
    solver = qpik.IKSolver(
        talos, [[posture]], [mink.ConfigurationLimit(talos), model_collision_limit(talos)]
    )
    configuration = qpik.Configuration(talos, talos.key("half_sitting").qpos)
    assert [s.value for s in solver.step(configuration, 0.01).status] == ["solved"]


TOUCHING = """<mujoco>
  <worldbody>
    <body name="p" pos="0 0 0.5">
      <joint name="jp" axis="0 0 1" range="-1 1"/>
      <geom name="p_g" type="box" size="0.1 0.1 0.1"/>
      <body name="q" pos="0 0 0.2002">
        <joint name="jq" axis="0 0 1" range="-1 1"/>
        <geom name="q_g" type="sphere" size="0.01" contype="0" conaffinity="0"/>
        <body name="r" pos="0 0 0">
          <joint name="jr" axis="0 0 1" range="-1 1"/>
          <geom name="r_g" type="sphere" size="0.1"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>"""


def test_pairs_always_within_the_minimum_distance_are_left_out():
    """A sphere that turns on a box's top, 2e-4 m above it in every pose (grandparent and
    grandchild, so MuJoCo tests the pair): never in contact, always within 5 mm. With the
    limit's default 5 mm it is left out (``distance``), as erd Tiago's finger phalanges
    (1e-5 m apart in every pose) now are; a full IK on Tiago with its collision limit then
    reaches a target in front of it within its joint limits (before: ``at_limit`` after 19
    iterations, 0.065 m off, every step level-0 infeasible; ``qpik reachmap --collision self`` reached none of 8
    voxels in 109 s, now all 8 in 0.4 s)."""
    model = mujoco.MjModel.from_xml_string(TOUCHING)
    pairs = collision_pairs(model)
    assert _names(model, pairs) == {("p_g", "r_g")}
    assert always_in_contact(model, pairs) == []  # no penetration
    assert _names(model, always_in_contact(model, pairs, distance=0.005)) == {("p_g", "r_g")}
    assert always_in_contact(model, pairs, distance=1e-4) == []  # 2e-4 apart
    with pytest.raises(qpik.CollisionPairError, match="always in contact"):
        model_collision_limit(model)  # (its only pair left out)
    kept = model_collision_limit(model, minimum_distance_from_collisions=1e-4)
    assert kept.always_in_contact == []
    for bad in (-1.0, float("nan"), "5 mm"):
        with pytest.raises(qpik.QpikError, match="distance"):
            always_in_contact(model, pairs, distance=bad)


@requires_erd
def test_tiago_full_ik_with_its_collision_limit_reaches_in_front():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tiago = qpik.load_robot("erd:tiago")
    limit = model_collision_limit(tiago)
    names = {
        tuple(
            sorted((tiago.body(tiago.geom_bodyid[a]).name, tiago.body(tiago.geom_bodyid[b]).name))
        )
        for a, b in limit.always_in_contact
    }
    assert ("hand_index_flex_2_link", "hand_index_flex_3_link") in names
    result = qpik.solve(
        tiago,
        {"arm_tool_link": np.array([0.4, -0.4, 0.7])},
        limits=[mink.ConfigurationLimit(tiago), limit],
        seed=0,
    )
    assert result.converged, (result.reason, result.position_error)
    data = mujoco.MjData(tiago)
    data.qpos[:] = result.q
    mujoco.mj_kinematics(tiago, data)
    fromto = np.zeros(6)
    closest = min(
        mujoco.mj_geomDistance(tiago, data, a, b, 0.05, fromto) for a, b in limit.geom_id_pairs
    )
    assert closest >= 0.005 - 1e-6
    assert qpik.Configuration(tiago, result.q).within_limits(1e-9)


@pytest.mark.parametrize("cap", [1.0, 0.05, 1e-3])
def test_collision_clearance_skips_far_pairs_with_the_same_answer(cap):
    """collision_clearance hands mj_geomDistance only the pairs the culling keeps; the far
    ones count as mj_geomDistance would return them (d_min + cap): the same value, bit for bit,
    as every pair's distance taken."""
    import math

    from qpik.limits import collision_clearance

    model = qpik.load_robot("panda")
    limit = model_collision_limit(model, collision_detection_distance=0.05)
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(5)
    for _ in range(40):
        configuration.update(configuration.random_q(rng))
        d_min = float(limit.minimum_distance_from_collisions)
        every = math.inf
        for a, b in limit.geom_id_pairs:
            distance = mujoco.mj_geomDistance(
                model, configuration.data, int(a), int(b), d_min + cap, None
            )
            every = min(every, distance - d_min)
        assert collision_clearance(model, configuration.data, [limit], cap) == every


@pytest.mark.parametrize(
    "pairs",
    [np.array(3), np.array([1, 2]), [np.array(5)], [np.array([[0, 1]])], "ab", 3, [(0,)]],
)
def test_always_in_contact_refuses_pairs_that_are_no_list_of_pairs(pairs):
    """``pairs`` a 0-d array, a flat array, 0-d or 2-d items, a str, a number: the typed
    error naming ``pairs``, not Python's "iteration over a 0-d array" (fuzz seed 7342, case
    signature:147)."""
    from qpik.errors import InvalidArgumentType

    with pytest.raises(InvalidArgumentType, match="pairs"):
        always_in_contact(qpik.load_robot("planar_2r"), pairs=pairs)
