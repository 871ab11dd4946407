"""The compiled culling of collision pairs (qpik/_cpp/limits/collision.hpp): its distance
bounds never exceed MuJoCo's mj_geomDistance (the reference) on every geom type, so the
rows of mink's CollisionAvoidanceLimit computed from the culled pairs
(qpik.limits.collision.mink_collision_rows) are bitwise mink's own, unculled rows (mink's
loop with its final product summed term by term, and within ulps of its BLAS product:
tests/mink_contact_rows.py); the solve_ik answers stay bitwise those of the unculled limit."""

from __future__ import annotations

import mink
import mujoco
import numpy as np
import pytest
from mink_contact_rows import (
    assert_rows_near_minks,
    contact_normal_jacobian,
    minks_blas_rows,
    use_minks_arithmetic,
)

import qpik
from qpik._engine import limits as engine
from qpik.limits.collision import CULLING_SLACK, PairCulling, mink_collision_rows

# Every geom type the culling bounds (plane, sphere, capsule, ellipsoid, cylinder, box, mesh)
# on a chain of hinges and a free body, so that random configurations bring every pair of
# types close together, apart and into penetration.
SHAPES = """
<mujoco>
  <compiler angle="radian"/>
  <asset>
    <mesh name="wedge" vertex="0 0 0  0.12 0 0  0 0.08 0  0 0 0.1  0.05 0.05 0.07"/>
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1" pos="0 0 -0.3"/>
    <geom name="post" type="box" size="0.05 0.08 0.3" pos="0.35 0.1 0" euler="0.2 0.1 0.4"/>
    <geom name="ball" type="sphere" size="0.07" pos="-0.2 0.25 0.1"/>
    <body name="a">
      <joint name="a" axis="0 0 1" range="-3 3"/>
      <geom name="a" type="capsule" size="0.04" fromto="0 0 0 0.3 0 0"/>
      <body name="b" pos="0.3 0 0">
        <joint name="b" axis="0 1 0" range="-3 3"/>
        <geom name="b" type="cylinder" size="0.03 0.1" pos="0.1 0 0" euler="0 1.57 0"/>
        <body name="c" pos="0.2 0 0">
          <joint name="c" axis="1 0 0" range="-3 3"/>
          <geom name="c_box" type="box" size="0.03 0.05 0.02" pos="0.05 0 0"/>
          <geom name="c_ell" type="ellipsoid" size="0.04 0.02 0.03" pos="0.1 0.03 0"/>
          <body name="d" pos="0.15 0 0">
            <joint name="d" axis="0 0 1" range="-3 3"/>
            <geom name="d_mesh" type="mesh" mesh="wedge" pos="0.05 0 0"/>
            <geom name="d_ball" type="sphere" size="0.025" pos="0.15 0 0"/>
          </body>
        </body>
      </body>
    </body>
    <body name="free" pos="0 0.2 0">
      <freejoint/>
      <geom name="f_box" type="box" size="0.04 0.03 0.05"/>
      <geom name="f_cap" type="capsule" size="0.02 0.06" pos="0 0.08 0"/>
    </body>
  </worldbody>
</mujoco>
"""


def _shapes():
    return mujoco.MjModel.from_xml_string(SHAPES)


def _random_configurations(model, rng, count):
    """Configurations over the whole range of the hinges; the free body anywhere near."""
    for _ in range(count):
        q = model.qpos0.copy()
        for j in range(model.njnt):
            a = model.jnt_qposadr[j]
            if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
                q[a : a + 3] = rng.uniform(-0.5, 0.5, 3)
                w = rng.normal(size=4)
                q[a + 3 : a + 7] = w / np.linalg.norm(w)
            elif model.jnt_limited[j]:
                q[a] = rng.uniform(*model.jnt_range[j])
        yield q


def test_bounds_never_exceed_mujocos_distance(rng):
    """For every geom pair of every type, a pair the culling drops at a threshold is farther
    apart than the threshold by MuJoCo's own distance (mj_geomDistance, capped well above)."""
    model = _shapes()
    data = mujoco.MjData(model)
    ngeom = model.ngeom
    pairs = np.array([(a, b) for a in range(ngeom) for b in range(a + 1, ngeom)], dtype=np.int64)
    culling = PairCulling(pairs)
    dropped = 0
    for q in _random_configurations(model, rng, 100):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        for threshold in (-0.01, 0.0, 0.02, 0.1):
            kept = set(culling.candidates(model, data, threshold))
            for k, (a, b) in enumerate(pairs):
                if k in kept:
                    continue
                dropped += 1
                distance = mujoco.mj_geomDistance(model, data, a, b, threshold + 1.0, None)
                assert distance > threshold, (model.geom(a).name, model.geom(b).name, threshold)
    assert dropped > 500  # the culling does drop pairs


@pytest.mark.parametrize("broadphase", [True, False])
def test_mink_rows_are_minks_bitwise(rng, broadphase, monkeypatch):
    """mink_collision_rows gives the rows of mink's limit that are in play, bitwise, on
    random configurations of every pair of geom types (penetrating ones included)."""
    use_minks_arithmetic(monkeypatch)
    model = _shapes()
    geoms = list(range(model.ngeom))
    kwargs = dict(minimum_distance_from_collisions=0.01, collision_detection_distance=0.08)
    limit = mink.CollisionAvoidanceLimit(model, [(geoms, geoms)], broadphase=broadphase, **kwargs)
    every = mink.CollisionAvoidanceLimit(model, [(geoms, geoms)], broadphase=False, **kwargs)
    configuration = mink.Configuration(model)
    seen = 0
    for q in _random_configurations(model, rng, 150):
        configuration.update(q)
        reference = every.compute_qp_inequalities(configuration, 0.01)
        G, h, kept, _ = mink_collision_rows(limit, configuration, 0.01)
        in_play = np.flatnonzero(np.isfinite(reference.h))
        assert kept == in_play.tolist()
        np.testing.assert_array_equal(G, reference.G[in_play])
        np.testing.assert_array_equal(h, reference.h[in_play])
        assert_rows_near_minks(G, minks_blas_rows(every, configuration, 0.01).G[in_play])
        seen += len(kept)
    assert seen > 100


def test_solve_ik_with_minks_collision_limit_is_bitwise_unculled(rng):
    """qpik.solve_ik with mink's collision limit (culled pairs) answers bitwise as with the
    same limit checking every pair, along a trajectory that brings the arm to the post."""
    model = _shapes()
    geoms = list(range(model.ngeom))
    kwargs = dict(minimum_distance_from_collisions=0.01, collision_detection_distance=0.1)
    culled = mink.CollisionAvoidanceLimit(model, [(geoms, geoms)], **kwargs)
    every = mink.CollisionAvoidanceLimit(model, [(geoms, geoms)], broadphase=False, **kwargs)
    configuration = mink.Configuration(model)
    task = mink.FrameTask("d", "body", position_cost=1.0, orientation_cost=0.0)
    posture = mink.PostureTask(model, cost=1e-3)
    posture.set_target_from_configuration(configuration)
    rows = 0
    for step in range(40):
        target = np.array([0.35 + 0.1 * np.sin(step / 5), 0.1, 0.1 * np.cos(step / 7)])
        task.set_target(mink.SE3.from_translation(target))
        limits = [mink.ConfigurationLimit(model), culled]
        v = qpik.solve_ik(configuration, [task, posture], 0.01, "quadprog", limits=limits)
        w = qpik.solve_ik(
            configuration, [task, posture], 0.01, "quadprog", limits=limits[:1] + [every]
        )
        np.testing.assert_array_equal(v, w)
        rows += len(mink_collision_rows(culled, configuration, 0.01)[2])
        configuration.integrate_inplace(v, 0.01)
    assert rows > 0


def test_qpiks_limit_rows_equal_with_and_without_culling(rng):
    """qpik's CollisionAvoidanceLimit culls the same way (broadphase=True) and gives the
    rows of checking every pair (broadphase=False)."""
    model = _shapes()
    geoms = list(range(model.ngeom))
    culled = qpik.limits.CollisionAvoidanceLimit(model, [(geoms, geoms)])
    every = qpik.limits.CollisionAvoidanceLimit(model, [(geoms, geoms)], broadphase=False)
    configuration = qpik.Configuration(model)
    for q in _random_configurations(model, rng, 60):
        configuration.update(q)
        a = culled.compute_qp_inequalities(configuration, 0.01)
        b = every.compute_qp_inequalities(configuration, 0.01)
        if a.inactive:
            assert b.inactive
            continue
        np.testing.assert_array_equal(a.G, b.G)
        np.testing.assert_array_equal(a.h, b.h)


def test_culling_follows_a_model_changed_in_place():
    """The culling reads the model's geom sizes at each call: a geom grown in place is
    checked again."""
    model = _shapes()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    ball, post = model.geom("ball").id, model.geom("post").id
    culling = PairCulling([(ball, post)])
    assert culling.candidates(model, data, 0.01) == []
    model.geom_size[ball, 0] = 1.0
    model.geom_rbound[ball] = 1.0
    assert culling.candidates(model, data, 0.01) == [0]
    assert CULLING_SLACK > 0


def test_bad_arguments_raise_value_errors():
    model = _shapes()
    data = mujoco.MjData(model)
    args = (model.geom_type, model.geom_size, model.geom_aabb, model.geom_rbound)
    out = np.empty(1, dtype=np.int64)
    with pytest.raises(ValueError, match="out of range"):
        engine.collision_candidates(
            np.array([[0, model.ngeom]]), *args, data.geom_xpos, data.geom_xmat, 0.1, out
        )
    with pytest.raises(ValueError, match="geom_xmat"):
        engine.collision_candidates(
            np.array([[0, 1]]), *args, data.geom_xpos, data.geom_xmat[:, :3].copy(), 0.1, out
        )
    with pytest.raises(ValueError, match="out must hold"):
        engine.collision_candidates(
            np.array([[0, 1], [1, 2]]), *args, data.geom_xpos, data.geom_xmat, 0.1, out
        )


def test_a_limits_culling_goes_with_the_limit():
    """The culling kept for a limit (by its identity) is dropped when the limit is."""
    import gc

    from qpik.limits import collision

    model = _shapes()
    geoms = list(range(model.ngeom))
    limit = mink.CollisionAvoidanceLimit(model, [(geoms, geoms)])
    configuration = mink.Configuration(model)
    mink_collision_rows(limit, configuration, 0.01)
    key = id(limit)
    assert key in collision._CULLINGS
    del limit
    gc.collect()
    assert key not in collision._CULLINGS


def test_panda_contact_rows_are_minks_bitwise(rng, monkeypatch):
    """The contact rows made by the compiled engine (PairCulling.contact_rows: MuJoCo's
    mj_jac arithmetic along each body's dof chain) are mink's bitwise, for mink's limit and
    qpik's own, on the bundled Panda's links against each other and an obstacle, over random
    configurations."""
    from qpik.limits import CollisionAvoidanceLimit
    from qpik.scene import add_obstacle

    use_minks_arithmetic(monkeypatch)
    model = add_obstacle(qpik.load_robot("panda"), "sphere", 0.08, [0.45, 0.0, 0.45], name="ball")
    links = ["link3", "link4", "link5", "link6", "link7", "hand"]
    pairs = [(links[3:], links[:2]), (links, ["ball"])]
    kwargs = dict(minimum_distance_from_collisions=0.02, collision_detection_distance=0.25)
    theirs = mink.CollisionAvoidanceLimit(model, pairs, broadphase=False, **kwargs)
    ours = CollisionAvoidanceLimit(model, pairs, **kwargs)
    configuration = qpik.Configuration(model)
    lower, upper = configuration.lower, configuration.upper
    seen = 0
    for _ in range(60):
        configuration.update(rng.uniform(lower, upper))
        reference = theirs.compute_qp_inequalities(configuration, 0.01)
        in_play = np.flatnonzero(np.isfinite(reference.h))
        G, h, kept, _ = mink_collision_rows(theirs, configuration, 0.01)
        assert kept == in_play.tolist()
        np.testing.assert_array_equal(G, reference.G[in_play])
        np.testing.assert_array_equal(h, reference.h[in_play])
        assert_rows_near_minks(G, minks_blas_rows(theirs, configuration, 0.01).G[in_play])
        # qpik's own limit (its pairs in its own order): mink's function on each pair in range
        expected, bounds = [], []
        for g1, g2 in ours.geom_id_pairs:
            fromto = np.empty(6)
            d = mujoco.mj_geomDistance(model, configuration.data, g1, g2, 0.25, fromto)
            if d >= 0.25 - 1e-12:
                continue
            row = contact_normal_jacobian(
                model, configuration.data, g1, g2, fromto, np.empty(3), *np.empty((2, 3, model.nv))
            )
            expected.append((-1.0 if d >= 0 else 1.0) * row)
            bounds.append(0.85 * (d - 0.02))
        rows = ours.compute_qp_inequalities(configuration, 0.01)
        assert rows.inactive == (not expected)
        if expected:
            np.testing.assert_array_equal(rows.G, np.array(expected))
            np.testing.assert_array_equal(rows.h, np.array(bounds))
        seen += len(kept) + len(expected)
    assert seen > 60


def test_contact_normal_rows_refuse_bad_arguments():
    """The engine's contact rows check every index and shape: ValueError, never a read out of
    bounds."""
    n, cdof, com = 3, np.zeros((3, 6)), np.zeros((2, 3))
    args = dict(
        starts=np.array([0, 1, 2]), dofs=np.array([0, 1]), roots=np.array([0, 1]),
        which=[0], fromto=np.zeros((1, 6)), dist=[0.0],
    )  # fmt: skip

    def call(**given):
        a = {**args, **given}
        return engine.contact_normal_rows(
            cdof, com, a["starts"], a["dofs"], a["roots"], a["which"], a["fromto"], a["dist"],
            0.85, 0.005, 0.0, 0.01, True,
        )  # fmt: skip

    G, h, fewest = call()
    assert G.shape == (1, n) and h.shape == (1,) and fewest == 0  # (cdof 0: a zero row)
    bad = {
        "dofs": np.array([0, 3]),
        "roots": np.array([0, 2]),
        "which": [1],
        "starts": np.array([0, 2, 1]),
        "fromto": np.zeros((1, 5)),
        "dist": [],
    }
    for name, value in bad.items():
        with pytest.raises(ValueError):
            call(**{name: value})
    for which in ([2**62], [-1]):  # (no overflow in the check)
        with pytest.raises(ValueError):
            call(which=which)
