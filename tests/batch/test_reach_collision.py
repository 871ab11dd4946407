"""Full IK, batches and reachability maps with collision limits (issue 22 item 6): a
position inside an obstacle is reached without collision limits and not with them, every
answer keeps the pairs apart (checked with MuJoCo's own mj_geomDistance), and a map says
whether it checked collisions, and which pairs."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import qpik
from qpik.batch.reachability_map import ReachabilityMap
from qpik.cli import main
from qpik.limits import (
    ConfigurationLimit,
    checked_pairs,
    closest_pair,
    collision_clearance,
    model_collision_limit,
)
from qpik.scene import add_obstacle

CENTRE = np.array([0.5, 0.0, 0.3])  # the block's centre [m]
ABOVE = np.array([0.5, 0.0, 0.6])  # clear of the block, reachable
D_MIN = 0.005
FAST = {"restarts": 2, "max_iters": 60, "seed": 3}


@pytest.fixture(scope="module")
def scene() -> mujoco.MjModel:
    return add_obstacle(qpik.load_robot("panda"), "box", [0.05, 0.05, 0.05], CENTRE, "block")


def collision_limits_of(model: mujoco.MjModel) -> list:
    collision = model_collision_limit(
        model,
        self_collision=False,
        minimum_distance_from_collisions=D_MIN,
        collision_detection_distance=0.05,
    )
    return [ConfigurationLimit(model), collision]


def smallest_distance(model: mujoco.MjModel, q: np.ndarray) -> float:
    """The smallest distance [m] between the block and any robot geom, from MuJoCo."""
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    block = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "block")
    robot = [g for g in range(model.ngeom) if model.geom_bodyid[g] != 0 and model.geom_contype[g]]
    return min(mujoco.mj_geomDistance(model, data, block, g, 1.0, None) for g in robot)


def test_clearance_helpers_agree_with_mujoco(scene):
    limits = collision_limits_of(scene)
    pairs = checked_pairs(limits)
    assert pairs and all("block" in pair for pair in pairs)
    assert checked_pairs("joint") == [] and checked_pairs(None) == []
    configuration = qpik.Configuration(scene)
    found = closest_pair(scene, configuration.data, limits)
    assert found is not None
    _pair, distance, margin = found
    assert distance == pytest.approx(smallest_distance(scene, configuration.q), abs=1e-12)
    assert margin == pytest.approx(distance - D_MIN, abs=1e-15)
    assert collision_clearance(scene, configuration.data, limits) == margin
    assert collision_clearance(scene, configuration.data, [ConfigurationLimit(scene)]) is None


def test_solve_excludes_a_position_inside_an_obstacle(scene):
    limits = collision_limits_of(scene)
    free = qpik.solve(scene, {"ee": CENTRE}, **FAST)
    assert free.converged and smallest_distance(scene, free.q) < 0  # through the block
    blocked = qpik.solve(scene, {"ee": CENTRE}, limits=limits, **FAST)
    assert not blocked.converged and blocked.engine == "qp"
    # the answer returned keeps the block d_min away (within tol_position)
    assert smallest_distance(scene, blocked.q) >= D_MIN - 1e-4
    above = qpik.solve(scene, {"ee": ABOVE}, limits=limits, **FAST)
    assert above.converged and smallest_distance(scene, above.q) >= D_MIN - 1e-4
    session = qpik.IKSession(scene)
    again = session.solve({"ee": CENTRE}, limits=limits, **FAST)
    assert not again.converged
    np.testing.assert_array_equal(again.q, blocked.q)  # deterministic


def test_solve_many_with_collision_limits(scene):
    limits = collision_limits_of(scene)
    targets = [{"ee": CENTRE}, {"ee": ABOVE}]
    results = qpik.solve_many(scene, targets, limits=limits, workers=2, **FAST)
    assert [r.converged for r in results] == [False, True]
    for r in results:
        assert smallest_distance(scene, r.q) >= D_MIN - 1e-4
    plain = qpik.solve_many(scene, targets, workers=1, **FAST)
    assert [r.converged for r in plain] == [True, True]


def test_reachability_map_excludes_poses_in_collision_and_says_so(scene, tmp_path):
    # two voxels: the block's centre (z = 0.3) and 0.1 m above it (z = 0.4, 5 cm clear)
    region = [[0.45, -0.05, 0.25], [0.55, 0.05, 0.45]]
    common = {"region": region, "resolution": 0.1, "orientations": 0, "workers": 1}
    bare = qpik.reachability(scene, "ee", progress=False, **common, **FAST)
    np.testing.assert_allclose(bare.centers[0], CENTRE, atol=1e-12)
    assert bare.fraction.tolist() == [1.0, 1.0]
    assert not bare.collisions_checked and bare.collision_distance is None
    assert "collisions not checked" in bare.summary()
    limits = collision_limits_of(scene)
    checked = qpik.reachability(scene, "ee", limits=limits, progress=False, **common, **FAST)
    assert checked.fraction.tolist() == [0.0, 1.0]
    assert checked.collisions_checked and checked.collision_distance == D_MIN
    assert checked.collision_pairs == checked_pairs(limits)
    text = checked.summary()
    assert "collisions checked" in text and "block" in text
    path = tmp_path / "map.npz"
    checked.save(path)
    loaded = ReachabilityMap.load(path)
    assert loaded.collision_pairs == checked.collision_pairs
    assert loaded.collision_distance == D_MIN and loaded.collisions_checked


def test_reachmap_cli_checks_collisions(tmp_path, capsys):
    spec = mujoco.MjSpec.from_file(str(qpik.robots.locate_robot("panda")))
    spec.worldbody.add_geom(
        name="block",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[0.05] * 3,
        pos=CENTRE,
        contype=1,
        conaffinity=1,
    )
    spec.compile()
    xml = tmp_path / "scene.xml"
    xml.write_text(spec.to_xml())
    out = tmp_path / "map.npz"
    args = ["reachmap", str(xml), "--frame", "ee", "--region", "0.45", "-0.05", "0.25"]
    args += ["0.55", "0.05", "0.45", "--resolution", "0.1", "--orientations", "0"]
    args += ["--restarts", "2", "--workers", "1", "--out", str(out), "--collision", "scene"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "collisions checked" in text and "block" in text
    rmap = ReachabilityMap.load(out)
    assert rmap.collisions_checked and rmap.fraction.tolist() == [0.0, 1.0]


def test_a_collision_limit_of_another_model_is_named(scene):
    """A scene's collision limit with a solve of the bare robot (one geom fewer): a typed
    error naming ``limits``, before any solve of a map."""
    limits = collision_limits_of(scene)
    with pytest.raises(qpik.InvalidOption, match="limits") as caught:
        qpik.solve("panda", {"ee": ABOVE}, limits=limits, **FAST)
    assert caught.value.field == "limits"
    with pytest.raises(qpik.InvalidOption, match="limits"):
        qpik.reachability(
            "panda", "ee", region=[[0.45, -0.05, 0.25], [0.55, 0.05, 0.35]], resolution=0.1,
            orientations=0, limits=limits, progress=False,
        )  # fmt: skip


def test_a_stack_of_levels_with_collision_limits(scene):
    """Position above a posture (two levels, the level-0 finishing steps too): the block's
    centre is not reached, the position above it is, and both answers keep d_min."""
    from qpik.tasks import PositionTask, PostureTask

    limits = collision_limits_of(scene)
    for target, reached in ((CENTRE, False), (ABOVE, True)):
        posture = PostureTask(scene, cost=0.1)
        posture.set_target(qpik.Configuration(scene).mid_q())
        stack = [[PositionTask("ee")], [posture]]
        result = qpik.solve(scene, {"ee": target}, stack=stack, limits=limits, **FAST)
        assert result.converged is reached and result.levels_met[0] is reached
        assert smallest_distance(scene, result.q) >= D_MIN - 1e-4
