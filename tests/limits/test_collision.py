"""qpik's CollisionAvoidanceLimit: rows in displacement units (mink's times dt), checked
against finite differences of MuJoCo's distance, pushing back inside d_min, typed errors
when no pair is left, and the Panda kept >= 9 mm from a sphere on its straight path."""

from __future__ import annotations

import mink
import mujoco
import numpy as np
import pytest
from mink_contact_rows import assert_rows_near_minks, minks_blas_rows, use_minks_arithmetic

import qpik
from qpik.limits import CollisionAvoidanceLimit, geom_distance, joint_limits
from qpik.scene import add_obstacle
from qpik.tasks import PositionTask, PostureTask

ARM = ["link4", "link5", "link6", "link7", "hand"]
DT = 0.01

TWO_LINK = """
<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <geom name="ball" type="sphere" size="0.2" pos="1.2 0.8 0"/>
    <body name="link1">
      <joint name="q1" axis="0 0 1" range="-3 3"/>
      <geom name="link1" type="capsule" size="0.04" fromto="0 0 0 1 0 0"/>
      <body name="link2" pos="1 0 0">
        <joint name="q2" axis="0 0 1" range="-3 3"/>
        <geom name="link2" type="capsule" size="0.04" fromto="0 0 0 1 0 0"/>
        <site name="ee" pos="1 0 0"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _two_link():
    return mujoco.MjModel.from_xml_string(TWO_LINK)


def test_rows_are_minks_times_dt_and_push_back_inside_d_min(monkeypatch):
    """The rows are mink's (bitwise with mink's own loop summing its final product term by
    term; within ulps of its BLAS product: tests/mink_contact_rows.py) and its right sides
    times dt."""
    use_minks_arithmetic(monkeypatch)
    model = _two_link()
    configuration = qpik.Configuration(model, [0.3, 0.2])
    kwargs = dict(minimum_distance_from_collisions=0.05, collision_detection_distance=0.5)
    ours = CollisionAvoidanceLimit(model, [(["link1", "link2"], ["ball"])], **kwargs)
    theirs = mink.CollisionAvoidanceLimit(model, [(["link1", "link2"], ["ball"])], **kwargs)
    for dt in (0.01, 0.002):
        a = ours.compute_qp_inequalities(configuration, dt)
        b = theirs.compute_qp_inequalities(configuration, dt)
        finite = np.isfinite(b.h)
        assert a.G.shape[0] == finite.sum() >= 1
        np.testing.assert_array_equal(a.G, b.G[finite])
        assert_rows_near_minks(a.G, minks_blas_rows(theirs, configuration, dt).G[finite])
        np.testing.assert_allclose(a.h, b.h[finite] * dt, rtol=1e-14)
        # rows_in_play: the same rows, the pairs in range and a row's fewest nonzero entries
        G, h, pairs, fewest = ours.rows_in_play(configuration, dt)
        np.testing.assert_array_equal(G, a.G)
        np.testing.assert_array_equal(h, a.h)
        assert pairs == np.flatnonzero(finite).tolist()
        assert fewest == np.count_nonzero(G, axis=1).min()
    # Inside d_min the row asks the distance to grow by gain * (d_min - d) [m].
    configuration.update([0.34, 0.2])
    distance = geom_distance(configuration, "link2", "ball")
    assert 0 < distance < 0.05
    rows = ours.compute_qp_inequalities(configuration, DT)
    assert rows.h.min() == pytest.approx(0.85 * (distance - 0.05), abs=1e-12)
    assert theirs.compute_qp_inequalities(configuration, DT).h[
        np.isfinite(theirs.compute_qp_inequalities(configuration, DT).h)
    ].min() == pytest.approx(0.0)


def test_rows_are_the_distance_derivative(rng):
    model = _two_link()
    configuration = qpik.Configuration(model)
    limit = CollisionAvoidanceLimit(
        model,
        [(["link1", "link2"], ["ball"])],
        minimum_distance_from_collisions=0.0,
        collision_detection_distance=2.0,
    )
    for q in ([0.3, 0.2], [0.55, 0.1], [0.6, 0.3]):
        configuration.update(q)
        rows = limit.compute_qp_inequalities(configuration, DT)
        for row, (g1, g2) in zip(rows.G, limit.geom_id_pairs):
            h = 1e-6
            numeric = np.zeros(2)
            for i in range(2):
                values = []
                for sign in (1, -1):
                    shifted = np.array(q, dtype=float)
                    shifted[i] += sign * h
                    configuration.update(shifted)
                    values.append(geom_distance(configuration, g1, g2, cap=2.0))
                numeric[i] = (values[0] - values[1]) / (2 * h)
            configuration.update(q)
            np.testing.assert_allclose(-row, numeric, atol=1e-6)  # G dq = -(change of d)


def test_no_pair_raises_saying_why():
    model = qpik.load_robot("panda")
    scene = add_obstacle(model, "sphere", 0.05, [0.5, 0.0, 0.5], name="ball")
    visual = [f"{name}_visual" for name in ARM]  # contype = conaffinity = 0
    with pytest.raises(qpik.CollisionPairError, match="contype") as info:
        CollisionAvoidanceLimit(scene, [(visual, ["ball"])])
    assert "'hand_visual'" in str(info.value) and "respect_contype=False" in str(info.value)
    # The obstacle's own bits allow contact: mink's rule needs both sides.
    assert scene.geom("ball").contype == 1
    limit = CollisionAvoidanceLimit(scene, [(visual, ["ball"])], respect_contype=False)
    assert len(limit.geom_id_pairs) == len(ARM)
    # The collision geoms (named after the links) collide with the obstacle as they are.
    assert len(CollisionAvoidanceLimit(scene, [(ARM, ["ball"])]).geom_id_pairs) == len(ARM)
    with pytest.raises(qpik.CollisionPairError, match="parent and child"):
        CollisionAvoidanceLimit(scene, [(["link6"], ["link7"])], respect_contype=False)
    with pytest.raises(qpik.CollisionPairError, match="same body"):
        CollisionAvoidanceLimit(scene, [(["link0"], ["ball"])], respect_contype=False)
    with pytest.raises(qpik.UnknownFrame, match="available geoms"):
        CollisionAvoidanceLimit(scene, [(["wrist"], ["ball"])])
    with pytest.raises(qpik.CollisionPairError, match="empty"):
        CollisionAvoidanceLimit(scene, [])
    with pytest.raises(qpik.LimitDefinitionError, match="collision_detection_distance"):
        CollisionAvoidanceLimit(
            scene,
            [(ARM, ["ball"])],
            minimum_distance_from_collisions=0.02,
            collision_detection_distance=0.01,
            respect_contype=False,
        )


def _reach_through_sphere(limit_factory, steps=400):
    """The Panda's site ee from home to a goal 0.45 m to the side, a sphere of radius 6 cm
    centred on the straight segment; a position task above a posture. Returns the closest
    distance of the arm to the sphere over the steps, the final goal error, the final ee
    and the sphere centre."""
    base = qpik.load_robot("panda")
    start = qpik.Configuration(base, base.key_qpos[0]).frame_pose("ee")[0]
    goal = start + np.array([0.0, 0.45, 0.0])
    centre = 0.5 * (start + goal)
    model = add_obstacle(base, "sphere", 0.06, centre, name="ball")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    tip = PositionTask("ee", gain=0.1)
    tip.set_target(goal)
    posture = PostureTask(model, cost=0.05)
    posture.set_target(model.key_qpos[0])
    solver = qpik.IKSolver(model, [[tip], [posture]], [limit_factory(model), *joint_limits(model)])
    closest = np.inf
    for _ in range(steps):
        result = solver.step(configuration, DT)
        assert result.status[0] == "solved"
        configuration.integrate_inplace(result.velocity, DT)
        assert configuration.within_limits()
        closest = min(closest, *(geom_distance(configuration, g, "ball") for g in ARM))
    ee = configuration.frame_pose("ee")[0]
    return closest, float(np.linalg.norm(ee - goal)), ee, centre


def test_panda_goes_around_a_sphere_on_its_straight_path():
    closest, error, ee, centre = _reach_through_sphere(
        lambda model: CollisionAvoidanceLimit(
            model,
            [(ARM, ["ball"])],
            minimum_distance_from_collisions=0.01,
            collision_detection_distance=0.1,
        )
    )
    assert closest >= 0.009  # d_min = 10 mm, kept to 1 mm at every step
    assert error <= 0.02
    assert ee[1] > centre[1] + 0.06  # past the sphere


def test_mink_rows_in_velocity_units_let_the_panda_into_the_sphere():
    """What qpik's limit fixes: mink's bound gain (d - d_min) / dt on a displacement."""

    def mink_limit(model):
        model.geom_contype[:] = 1
        model.geom_conaffinity[:] = 1
        return mink.CollisionAvoidanceLimit(
            model,
            [(ARM, ["ball"])],
            minimum_distance_from_collisions=0.01,
            collision_detection_distance=0.1,
        )

    closest, *_ = _reach_through_sphere(mink_limit, steps=200)
    assert closest < 0.0


def test_minks_limits_under_qpiks_names_raise_typed_errors():
    model = qpik.load_robot("panda")
    limit = qpik.limits.ConfigurationLimit(model)
    assert type(limit) is mink.ConfigurationLimit  # mink's object: its box fast path applies
    assert isinstance(limit, qpik.limits.ConfigurationLimit)
    assert isinstance(qpik.limits.VelocityLimit(model, {"joint1": 2.0}), qpik.limits.VelocityLimit)
    for bad, match in [
        (lambda: qpik.limits.ConfigurationLimit(model, gain=-1), "gain"),
        (lambda: qpik.limits.ConfigurationLimit(model, gain=np.nan), "gain"),
        (lambda: qpik.limits.ConfigurationLimit("panda"), "MjModel"),
        (lambda: qpik.limits.VelocityLimit(model, {"elbow": 1.0}), "joint1, joint2"),
        (lambda: qpik.limits.VelocityLimit(model, {"joint1": -1.0}), "> 0"),
        (lambda: qpik.limits.VelocityLimit(model, {"joint1": np.nan}), "> 0"),
    ]:
        with pytest.raises(qpik.LimitDefinitionError, match=match):
            bad()


def test_collision_and_support_rows_appear_in_the_built_qp():
    model = _two_link()
    configuration = qpik.Configuration(model, [0.3, 0.2])
    limit = CollisionAvoidanceLimit(
        model,
        [(["link1", "link2"], ["ball"])],
        minimum_distance_from_collisions=0.05,
        collision_detection_distance=0.5,
    )
    posture = PostureTask(model, cost=1.0)
    posture.set_target([1.0, 0.0])
    problem = qpik.IKSolver(model, [[posture]], [limit]).build(configuration, DT)
    rows = limit.compute_qp_inequalities(configuration, DT)
    np.testing.assert_array_equal(problem.G, rows.G)
    np.testing.assert_array_equal(problem.h, rows.h)
    far = qpik.Configuration(model, [-1.0, 0.0])  # out of detection range: no row at all
    assert qpik.IKSolver(model, [[posture]], [limit]).build(far, DT).G.shape[0] == 0


@pytest.mark.parametrize(
    "name", ["minimum_distance_from_collisions", "collision_detection_distance", "bound_relaxation"]
)
@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_a_distance_or_relaxation_that_is_not_finite_is_refused(name, value):
    model = qpik.load_robot("panda")
    scene = add_obstacle(model, "sphere", 0.05, [0.5, 0.0, 0.5], name="ball")
    with pytest.raises(qpik.LimitDefinitionError, match=f"{name} must be finite|{name}"):
        CollisionAvoidanceLimit(scene, [(ARM, ["ball"])], **{name: value})


def test_a_pair_whose_geoms_touch_gives_no_direction_and_blocks_nothing():
    """Pins h12's audit: at the Panda's home, link5 and link7 touch; their row's normal is
    round-off (|G| ~ 5e-18, h = 0), and the step failed (numerical_failure, NoSolutionFound
    from solve_ik) where dq = 0 meets every limit and mink steps. Such a row is a zero row
    (qpik.limits.collision.NEGLIGIBLE_ROW): met, left out; the step is the one without the pair."""
    import mink

    from qpik.limits.collision import NEGLIGIBLE_ROW

    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    task = mink.FrameTask("link7", "body", position_cost=1.0, orientation_cost=1.0)
    task.set_target(
        configuration.get_transform_frame_to_world("link7", "body")
        @ mink.SE3.from_translation(np.array([0.02, -0.03, 0.01]))
    )
    names = [model.joint(i).name for i in range(5)]
    velocity = mink.VelocityLimit(model, dict(zip(names, [0.4, 0.5, 1.1, 0.9, 0.2])))
    touching = mink.CollisionAvoidanceLimit(
        model, [(["link5"], ["link7"])], minimum_distance_from_collisions=0.005,
        collision_detection_distance=0.01,
    )  # fmt: skip
    row = touching.compute_qp_inequalities(configuration, 0.001)
    assert 0.0 < np.abs(row.G).max() <= NEGLIGIBLE_ROW and row.h.tolist() == [0.0]
    for limits in ([velocity, touching], [velocity]):
        solver = qpik.IKSolver(model, [[task]], limits)
        step = solver.step(configuration, 0.001)
        assert step.ok, step.status
    with_pair = qpik.solve_ik(configuration, [task], 0.001, "daqp", limits=[velocity, touching])
    without = qpik.solve_ik(configuration, [task], 0.001, "daqp", limits=[velocity])
    np.testing.assert_allclose(with_pair, without, atol=1e-9)
    ours = qpik.solve_ik(
        configuration, [task], 0.001, "daqp", damping=1e-6, limits=[velocity, touching]
    )
    theirs = mink.solve_ik(
        configuration, [task], 0.001, "daqp", damping=1e-6, limits=[velocity, touching]
    )
    np.testing.assert_allclose(ours, theirs, atol=1e-8)


def test_the_engine_counts_negligible_rows_as_numpy_takes_them(rng):
    # boxes' check counts negligible rows (largest |entry| in (0, NEGLIGIBLE_ROW]) in the
    # engine (row_stats), then flushes them with NumPy: the count is NumPy's, NaN and inf
    # included.
    from qpik._engine import limits as engine
    from qpik.limits.collision import NEGLIGIBLE_ROW

    for _ in range(300):
        p, n = int(rng.integers(0, 6)), int(rng.integers(1, 9))
        G = rng.normal(size=(p, n)) * 10.0 ** rng.integers(-22, 2, size=(p, 1))
        G[rng.random((p, n)) < 0.3] = 0.0
        G[rng.random((p, n)) < 0.05] = rng.choice([np.nan, np.inf, -np.inf, 1e-12, -1e-12])
        largest = np.abs(G).max(axis=1) if p else np.zeros(0)
        expected = int(((largest <= NEGLIGIBLE_ROW) & (largest > 0.0)).sum())
        assert engine.row_stats(G, np.zeros(p), NEGLIGIBLE_ROW)[3] == expected
