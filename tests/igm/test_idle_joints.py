"""The "qp" engine keeps the joints nothing in a solve moves bitwise where they start
(issue 22): which joints those are (qpik.igm.qp_engine.idle_qpos)."""

from __future__ import annotations

import mujoco
import numpy as np

import qpik
from qpik.igm.qp_engine import idle_qpos
from qpik.limits import ConfigurationLimit, model_collision_limit
from qpik.robots import locate_robot
from qpik.tasks import ComTask, JointLimitDistanceTask, PositionTask, PostureTask


def panda_and_cube() -> mujoco.MjModel:
    spec = mujoco.MjSpec.from_file(str(locate_robot("panda")))
    cube = spec.worldbody.add_body(name="cube", pos=[0.5, 0.2, 0.03])
    cube.add_freejoint(name="cube_free")
    cube.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.02] * 3, mass=0.1, contype=1)
    return spec.compile()


def test_idle_joints_are_those_no_task_limit_or_coupling_moves():
    model = panda_and_cube()
    cube = np.arange(model.nq) >= 7
    tip = PositionTask("ee")
    limits = [ConfigurationLimit(model)]
    assert np.array_equal(idle_qpos(model, [[tip]], limits, None), cube)
    secondary = [[tip], [JointLimitDistanceTask()]]  # the free joint has no limits
    assert np.array_equal(idle_qpos(model, secondary, limits, None), cube)
    for anything in (PostureTask(model, cost=1.0), ComTask()):  # may move every joint
        assert not idle_qpos(model, [[tip], [anything]], limits, None).any()
    collision = model_collision_limit(model, scene=False)  # the cube against the arm
    assert not idle_qpos(model, [[tip]], [*limits, collision], None).any()


def test_qp_engine_keeps_a_free_cube_bitwise():
    model = panda_and_cube()
    q0 = np.concatenate(
        [qpik.Configuration(model).mid_q()[:7], [0.4, -0.1, 0.2, 0.6, 0.0, 0.8, 0.0]]
    )
    p, rotation = qpik.Configuration(model, q0).frame_pose("ee")
    target = (p + np.array([0.05, 0.05, -0.05]), rotation)
    result = qpik.solve(model, {"ee": target}, q0=q0, engine="qp", secondary=True, seed=2)
    assert result.converged and result.engine == "qp"
    np.testing.assert_array_equal(result.path[:, 7:], np.tile(q0[7:], (len(result.path), 1)))
