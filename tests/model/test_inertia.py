"""The joint-space inertia matrix by the compiled engine (qpik.model.inertia): bitwise
MuJoCo's (mj_makeM then mj_fullM) on the shipped robots, on a floating base, and on
MuJoCo's "simple" dofs (dof_M0); None where actuators or tendons add armature; a bad tree
raises ValueError instead of reading out of bounds."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import qpik
from qpik._engine import model as engine_model
from qpik.model.inertia import inertia_matrix, inertia_tree

# A slider (two slides) carrying an arm (a hinge with armature), and a free body: MuJoCo
# counts the free body's dofs simple (a constant diagonal, dof_M0).
_XML = """<mujoco><worldbody>
<body name="slider"><joint name="x" type="slide" axis="1 0 0"/>
  <joint name="y" type="slide" axis="0 1 0"/><geom size=".1" mass="2"/>
  <body name="arm" pos="0 0 .2"><joint name="h" type="hinge" axis="0 0 1" armature="0.1"/>
    <geom type="capsule" fromto="0 0 0 .3 0 0" size=".03"/></body></body>
<body name="free" pos="1 0 0"><freejoint/><geom type="box" size=".1 .2 .3"/></body>
</worldbody>{extra}</mujoco>"""


def _mujoco_m(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    mujoco.mj_makeM(model, data)
    M = np.empty((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    return M


def _models():
    yield "panda", qpik.load_robot("panda")
    yield "ur5e", qpik.load_robot("ur5e")
    yield "slider and free body", mujoco.MjModel.from_xml_string(_XML.format(extra=""))


@pytest.mark.parametrize(
    "name, model", list(_models()), ids=lambda x: x if isinstance(x, str) else ""
)
def test_inertia_matrix_is_mujocos_bitwise(name, model):
    """At 30 random configurations, qpik.model.inertia.inertia_matrix equals MuJoCo's
    ``M`` bit for bit (its simple dofs' dof_M0 included), and is symmetric positive
    definite."""
    tree = inertia_tree(model)
    assert tree is not None
    data = mujoco.MjData(model)
    rng = np.random.default_rng(7)
    for _ in range(30):
        data.qpos[:] = model.qpos0 + rng.normal(0.0, 0.6, model.nq)
        mujoco.mj_normalizeQuat(model, data.qpos)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        M = inertia_matrix(data, tree)
        assert M.tobytes() == _mujoco_m(model, data).tobytes()
        assert np.array_equal(M, M.T)
        assert np.linalg.eigvalsh(M).min() > 0.0


def test_simple_dofs_are_counted():
    """The test model has simple dofs (the free body's), so the dof_M0 branch is tested."""
    model = mujoco.MjModel.from_xml_string(_XML.format(extra=""))
    assert model.dof_simplenum.any()
    assert np.isnan(inertia_tree(model)[4]).sum() == model.nv - 6


def test_actuator_or_tendon_armature_leaves_m_to_mujoco():
    """Armature that a tendon adds to M (tendon_armature) is not the engine's: no tree."""
    tendon = '<tendon><fixed name="t" armature="0.2"><joint joint="h" coef="1"/></fixed></tendon>'
    model = mujoco.MjModel.from_xml_string(_XML.format(extra=tendon))
    assert inertia_tree(model) is None


def test_a_bad_tree_raises():
    """A parent after its child, a dof's body out of range or shapes that differ raise
    ValueError (the tree is checked before anything is read)."""
    model = qpik.load_robot("panda")
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    tree = list(inertia_tree(model))
    bad_parent = tree[0].copy()
    bad_parent[2] = 5
    bad_body = tree[1].copy()
    bad_body[0] = model.nbody
    for changed in (
        (bad_parent, *tree[1:]),
        (tree[0], bad_body, *tree[2:]),
        (*tree[:3], tree[3][:2], tree[4]),
    ):
        with pytest.raises(ValueError):
            engine_model.inertia_matrix(data.cinert, data.cdof, *changed)
    with pytest.raises(ValueError):
        engine_model.inertia_matrix(data.cinert[:3], data.cdof, *tree)


def test_a_chain_of_slides_has_its_closed_form_inertia():
    """Three slides along one axis carrying 1, 2 and 3 kg: M in closed form (each joint
    moves every mass below it: M_ij = the mass below both), exactly."""
    xml = """<mujoco><worldbody><body><joint type="slide" axis="1 0 0"/>
      <geom type="box" size=".1 .1 .1" mass="1"/><body><joint type="slide" axis="1 0 0"/>
      <geom type="box" size=".1 .1 .1" mass="2"/><body><joint type="slide" axis="1 0 0"/>
      <geom type="box" size=".1 .1 .1" mass="3"/></body></body></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    expected = np.array([[6.0, 5.0, 3.0], [5.0, 5.0, 3.0], [3.0, 3.0, 3.0]])
    np.testing.assert_array_equal(inertia_matrix(data, inertia_tree(model)), expected)
