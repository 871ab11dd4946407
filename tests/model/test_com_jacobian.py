"""The O(nv) Jacobian of a subtree's centre of mass (qpik.model.com) against MuJoCo's own
``mj_jacSubtreeCom``, on every body of floating and fixed robots at random configurations;
its chain's corner cases; bad arguments raise ValueError."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import qpik
from qpik.model import kernels as K
from qpik.model.com import subtree_com_chain, subtree_com_jacobian


def _random_state(model: mujoco.MjModel, data: mujoco.MjData, rng: np.random.Generator) -> None:
    q = model.qpos0.copy()
    for j in range(model.njnt):
        a = model.jnt_qposadr[j]
        kind = model.jnt_type[j]
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            q[a : a + 3] = rng.normal(size=3)
            quat = rng.normal(size=4)
            q[a + 3 : a + 7] = quat / np.linalg.norm(quat)
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            quat = rng.normal(size=4)
            q[a : a + 4] = quat / np.linalg.norm(quat)
        else:
            q[a] = rng.uniform(-1.5, 1.5)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)


@pytest.mark.parametrize(
    "name, keywords",
    [("erd:talos", {"floating_base": True}), ("erd:talos", {}), ("erd:panda", {})],
)
def test_equals_mujoco_on_every_body(name, keywords):
    model = qpik.load_robot(name, **keywords)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(4):
        _random_state(model, data, rng)
        for body in range(model.nbody):
            chain = subtree_com_chain(model, body)
            if chain is None:
                assert model.body_subtreemass[body] == 0.0
                continue
            want = np.zeros((3, model.nv))
            mujoco.mj_jacSubtreeCom(model, data, want, body)
            got = subtree_com_jacobian(data, chain, np.full((3, model.nv), np.nan))
            worst = max(worst, float(np.abs(got - want).max() / max(1.0, np.abs(want).max())))
            assert np.array_equal(got == 0.0, want == 0.0) or np.abs(got - want).max() < 1e-15
    assert worst < 1e-14


def test_free_joint_columns_and_a_massless_subtree():
    """The free joint's translations move the whole robot's centre one for one; a subtree of
    no mass has no chain (MuJoCo's function answers)."""
    model = qpik.load_robot("erd:talos", floating_base=True)
    data = mujoco.MjData(model)
    _random_state(model, data, np.random.default_rng(1))
    J = subtree_com_jacobian(data, subtree_com_chain(model, 1), np.empty((3, model.nv)))
    np.testing.assert_allclose(J[:, :3], np.eye(3), rtol=0, atol=1e-15)
    spec = mujoco.MjSpec.from_string(
        "<mujoco><worldbody><body name='a'><joint type='hinge'/><geom size='.1' mass='1'/>"
        "<body name='b'><site name='s'/></body></body></worldbody></mujoco>"
    )
    light = spec.compile()
    assert subtree_com_chain(light, light.body("b").id) is None
    assert subtree_com_chain(light, light.body("a").id) is not None


def test_bad_arguments_raise_value_error():
    model = qpik.load_robot("erd:panda")
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    point, root, scale = subtree_com_chain(model, 1)
    out = np.empty((3, model.nv))
    bad_point = point.copy()
    bad_point[np.flatnonzero(scale)[0]] = model.nbody
    for args in (
        (data.cdof[:, :5].copy(), data.subtree_com, point, root, scale, out),
        (data.cdof, data.subtree_com, point[:-1], root, scale, out),
        (data.cdof, data.subtree_com, bad_point, root, scale, out),
        (data.cdof, data.subtree_com, point, root, scale, np.empty((3, model.nv + 1))),
    ):
        with pytest.raises((ValueError, TypeError)):
            K.subtree_com_jacobian(*args)
