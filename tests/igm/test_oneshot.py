"""qpik.solve(model, ...) keeps the robot's preparation per model (qpik.igm.prepared.PREPARED):
the same bits as a fresh IKSession, never a stale answer for a model edited in place, no
model kept alive, and qpik.clear_caches() empties it."""

from __future__ import annotations

import gc
import weakref

import numpy as np
import pytest

import qpik
from qpik.igm.prepared import PREPARED, PreparedRobots


def _targets(model, n, seed=0, frame="ee"):
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        configuration.update(configuration.random_q(rng))
        out.append({frame: configuration.frame_pose(frame)})
    return out


def _same(a, b):
    assert a.q.tobytes() == b.q.tobytes()
    assert (a.reason, a.iterations, a.restarts_used) == (b.reason, b.iterations, b.restarts_used)
    assert a.path.tobytes() == b.path.tobytes()
    assert list(a.error_history) == list(b.error_history)
    assert a.frame_errors == b.frame_errors and a.engine == b.engine


@pytest.mark.parametrize("robot", ["ur5e", "panda"])
def test_one_shot_answers_are_a_fresh_sessions_bitwise(robot):
    qpik.clear_caches()
    model = qpik.load_robot(robot)
    for i, target in enumerate(_targets(model, 12)):
        kwargs = dict(seed=i, tol_position=1e-5, tol_orientation=1e-5)
        if i % 3 == 1:
            kwargs["q0"] = qpik.IKSession(model).mid_q() + 0.01
        if i % 4 == 2:
            kwargs["options"] = "precise"
        first = qpik.solve(model, target, **kwargs)  # prepares (or reuses) the model
        again = qpik.solve(model, target, **kwargs)  # from the cache
        fresh = qpik.IKSession(model).solve(target, **kwargs)
        _same(first, fresh)
        _same(again, fresh)
    assert len(PREPARED) >= 1
    configuration = qpik.Configuration(model, qpik.IKSession(model).mid_q())
    target = _targets(model, 1, seed=5)[0]
    _same(
        qpik.solve(configuration, target, seed=3),
        qpik.IKSession(configuration).solve(target, seed=3),
    )


def test_a_model_edited_in_place_is_prepared_anew():
    qpik.clear_caches()
    model = qpik.load_robot("ur5e")
    target = _targets(model, 1, seed=2)[0]
    before = qpik.solve(model, target, seed=1)
    prepared = PREPARED.get(model)
    # narrow a joint's range: the limits, the mid-range start and the reach bound change
    model.jnt_range[1] = [-0.5, 0.3]
    after = qpik.solve(model, target, seed=1)
    assert PREPARED.get(model) is not prepared
    _same(after, qpik.IKSession(model).solve(target, seed=1))
    assert after.q.tobytes() != before.q.tobytes()
    # a body moved in place: the chain changes
    model.body_pos[2, 2] += 0.05
    moved = qpik.solve(model, target, seed=1)
    _same(moved, qpik.IKSession(model).solve(target, seed=1))
    # a site moved in place
    model.site_pos[0] += 0.01
    _same(qpik.solve(model, target, seed=1), qpik.IKSession(model).solve(target, seed=1))


def test_the_cache_keeps_no_model_alive_and_clears():
    qpik.clear_caches()
    model = qpik.load_robot("planar_2r")
    qpik.solve(model, {"ee": [1.0, 0.5, 0.0]}, seed=0)
    assert len(PREPARED) == 1
    ref = weakref.ref(model)
    del model
    gc.collect()
    assert ref() is None and len(PREPARED) == 0
    model = qpik.load_robot("planar_2r")
    qpik.solve(model, {"ee": [1.0, 0.5, 0.0]}, seed=0)
    assert len(PREPARED) == 1
    qpik.clear_caches()
    assert len(PREPARED) == 0


def test_the_cache_is_bounded_and_tells_models_apart():
    cache = PreparedRobots(max_models=2)
    models = [qpik.load_robot("planar_2r") for _ in range(3)]
    models[1].jnt_range[0] = [-0.1, 0.1]
    prepared = [cache.get(m) for m in models]
    assert len(cache) == 2
    assert prepared[0] is not prepared[1]  # equal names, different arrays: never shared
    assert not np.array_equal(prepared[0].lower, prepared[1].lower)
    assert cache.get(models[2]) is prepared[2]
    assert cache.get(models[0]) is not prepared[0]  # evicted first, prepared again


def test_chains_and_sessions_copy_and_pickle():
    """The compiled chain object is rebuilt from the arrays when a chain (or a session
    holding chains) is pickled or deep-copied."""
    import copy
    import pickle

    from qpik.model import KinematicChain

    model = qpik.load_robot("ur5e")
    chain = KinematicChain.from_model(model, "ee")
    q = np.linspace(-1.0, 1.0, model.nq)
    for other in (pickle.loads(pickle.dumps(chain)), copy.deepcopy(chain)):
        assert all(a.tobytes() == b.tobytes() for a, b in zip(chain.pose(q), other.pose(q)))
        assert chain.jacobian(q).tobytes() == other.jacobian(q).tobytes()
    session = qpik.IKSession(model)
    target = {"ee": [0.3, 0.2, 0.4]}
    first = session.solve(target, seed=1)
    _same(copy.deepcopy(session).solve(target, seed=1), first)


def test_an_unreachable_answer_reports_every_level():
    """A target beyond the reach bound ends the solve at once; levels_met still has one
    entry per level of the stack (here the default one, with its secondary level)."""
    near = qpik.solve("panda", {"ee": [0.4, 0.0, 0.5]}, engine="qp", seed=0, secondary=True)
    far = qpik.solve("panda", {"ee": [5.0, 0.0, 0.5]}, engine="qp", seed=0, secondary=True)
    assert far.reason == "unreachable" and not far.converged
    assert len(near.levels_met) == len(far.levels_met) == 2
    assert far.levels_met[0] is False


def test_generator_seeds_draw_as_integers_does():
    """A numpy Generator seed takes one 64-bit draw: the same answer as the int that
    ``integers(0, 2**64 - 1, dtype=uint64, endpoint=True)`` gives, and the generator is
    left where that call leaves it, for every bit generator (the fast draw of the common
    ones included)."""
    session = qpik.IKSession("ur5e")
    target = {"ee": ([0.3, 0.2, 0.4], np.eye(3))}
    for kind in (np.random.PCG64, np.random.SFC64, np.random.Philox, np.random.MT19937):
        given, twin = np.random.Generator(kind(3)), np.random.Generator(kind(3))
        a = session.solve(target, seed=given, restarts=3, tol_position=1e-13)
        seed = int(twin.integers(0, 2**64 - 1, dtype=np.uint64, endpoint=True))
        b = session.solve(target, seed=seed, restarts=3, tol_position=1e-13)
        assert a.q.tobytes() == b.q.tobytes() and a.restarts_used == b.restarts_used > 0
        assert given.random() == twin.random()


def test_couplings_off_the_chain_are_measured_once_and_reported():
    """example-robot-data's panda has its fingers coupled (a URDF mimic) off the arm's
    chain: the compiled engine's answer reports the couplings' error at the start (their
    joints stay), as Couplings.error measures it at the answer."""
    session = qpik.IKSession("erd:panda")
    couplings = session._prepared.couplings
    assert couplings is not None and len(couplings) > 0
    frame = (qpik.robots.tool_frame(session.model).name, "body")
    start = session.mid_q()
    for finger in (0.01, 0.02, 0.01):
        q0 = start.copy()
        q0[couplings.qadr] = finger  # held: both fingers at the same opening
        result = session.solve({frame: [0.4, 0.1, 0.5]}, q0=q0)
        assert result.engine == "compiled"
        assert result.coupling_error == couplings.error(result.q) == couplings.error(q0)
    q0[couplings.qadr[0]] += 1e-3  # broken at the start: the "qp" engine restores it
    assert session.solve({frame: [0.4, 0.1, 0.5]}, q0=q0).engine == "qp"


def test_a_model_edited_into_an_empty_range_raises_infeasible_limits():
    """Pins repro_13: a joint range edited in place to an empty one (lower above upper) is an
    InfeasibleLimits naming the joint, from qpik.solve and from a held IKSession (at every
    solve until the range is mended), not a converged answer outside the range."""
    qpik.clear_caches()
    model = qpik.load_robot("panda")
    target = {"ee": [0.4, 0.2, 0.5]}
    model.jnt_range[0] = [0.5, 0.4]
    with pytest.raises(qpik.InfeasibleLimits, match="joint1"):
        qpik.solve(model, target, seed=0)
    model = qpik.load_robot("panda")
    session = qpik.IKSession(model)
    session.solve(target, seed=0)
    model.jnt_range[0] = [1.0, -1.0]
    for _ in range(2):  # the refused model stays refused
        with pytest.raises(qpik.InfeasibleLimits, match=r"joint1.*\[1, -1\]"):
            session.solve(target, seed=0)
    model.jnt_range[0] = [-1.0, 1.0]
    result = session.solve(target, seed=0)
    assert -1.0 <= result.q[0] <= 1.0
    model.jnt_range[0] = [np.nan, 1.0]  # a NaN range: InvalidInput, naming the joint
    with pytest.raises(qpik.InvalidInput, match="joint1"):
        session.solve(target, seed=0)


@pytest.mark.parametrize(
    "field, row, value, named",
    [
        ("body_pos", 2, np.nan, "body_pos of body 'link1'"),
        ("site_pos", 0, np.inf, "site_pos of site 'ee'"),
        ("jnt_axis", 3, np.nan, "jnt_axis of joint 'joint4'"),
        ("body_pos", 1, 1e300, "body_pos of body 'link0'"),
    ],
)
def test_a_model_edited_into_nan_geometry_raises_naming_the_field(field, row, value, named):
    """Pins repro_15: a NaN (or inf, or absurdly large) number edited into the model's
    geometry is an InvalidInput naming the field and its body, site or joint, raised
    before any solve runs, never an answer with a NaN error."""
    qpik.clear_caches()
    model = qpik.load_robot("panda")
    getattr(model, field)[row] = value
    with pytest.raises(qpik.InvalidInput, match=named):
        qpik.solve(model, {"ee": [0.4, 0.2, 0.5]}, seed=0)
    with pytest.raises(qpik.InvalidInput, match=named):
        qpik.IKSession(model)


def test_a_start_quaternion_is_checked_and_normalised():
    """Pins repro_04 through qpik.solve: a q0 whose free-joint quaternion is zero starts at
    the identity, as MuJoCo and mink read it (the same answer as [1, 0, 0, 0]);
    [1e200, 1e200, 0, 0] solves as [1, 1, 0, 0]."""
    model = qpik.load_robot("panda", floating_base=True)
    arm = [0, 0, 0, -1, 0, 1, 0]
    target = {"ee": [0.4, 0.2, 0.5]}
    zero = qpik.solve(model, target, q0=np.r_[0, 0, 0, 0, 0, 0, 0, arm], seed=0)
    identity = qpik.solve(model, target, q0=np.r_[0, 0, 0, 1, 0, 0, 0, arm], seed=0)
    np.testing.assert_array_equal(zero.q, identity.q)
    unit = qpik.solve(model, target, q0=np.r_[0, 0, 0, 0.5**0.5, 0.5**0.5, 0, 0, arm], seed=0)
    huge = qpik.solve(model, target, q0=np.r_[0, 0, 0, 1e200, 1e200, 0, 0, arm], seed=0)
    assert huge.converged == unit.converged
    np.testing.assert_allclose(huge.q, unit.q, atol=1e-9)


@pytest.mark.parametrize(
    "target",
    [
        np.array([0.4 + 0.3j, 0.1, 0.4]),  # (a float conversion drops the imaginary part)
        [0.4, 0.1j, 0.4],
        np.array(["0.4", "0.1", "0.4"]),
        (np.array([0.4 + 0j, 0.1, 0.4]), np.eye(3)),
        np.array([True, False, True]),
    ],
)
def test_a_target_of_no_real_numbers_is_refused(target):
    """Complex, string or boolean targets are InvalidTarget, not converted (a complex one
    was solved at its real part, reported converged, with only numpy's ComplexWarning)."""
    with pytest.raises(qpik.InvalidTarget, match="real numbers"):
        qpik.solve("ur5e", {"ee": target}, seed=0)


def test_one_frame_named_twice_is_refused():
    """'ee' and ('ee', 'site') name one frame: two targets for it were solved as a conflict
    (reason at_limit); now InvalidTarget naming both keys."""
    with pytest.raises(qpik.InvalidTarget, match=r"twice \('ee' and \('ee', 'site'\)\)"):
        qpik.IKSession("panda").solve({"ee": [0.4, 0.2, 0.5], ("ee", "site"): [0.3, 0.0, 0.6]})


def test_a_limited_ball_joints_range_holds_in_a_default_solve():
    """limits="joint" (the default) holds a limited ball joint's range too: 13 of 40
    answers here left b1's 1.2 rad cone (up to 2.1 rad), reported converged."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(
        """<mujoco><compiler angle="radian"/><worldbody>
      <body name="l1" pos="0 0 0.1"><joint name="b1" type="ball" range="0 1.2"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.4" size="0.03"/>
        <body name="l2" pos="0 0 0.4"><joint name="h2" type="hinge" axis="0 1 0" range="-2 2"/>
          <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.03"/>
          <body name="l3" pos="0 0 0.3"><joint name="b3" type="ball"/>
            <geom type="capsule" fromto="0 0 0 0 0 0.1" size="0.02"/>
            <site name="tip" pos="0 0 0.12"/>
    </body></body></body></worldbody></mujoco>"""
    )
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)

    def angle(quat):
        return 2 * np.arccos(min(1.0, abs(quat[0]) / np.linalg.norm(quat)))

    for i in range(40):
        u = rng.normal(size=4)
        while angle(u) > 1.2:
            u = rng.normal(size=4)
        v = rng.normal(size=4)
        data.qpos[:] = np.r_[u / np.linalg.norm(u), rng.uniform(-2, 2), v / np.linalg.norm(v)]
        mujoco.mj_kinematics(model, data)
        target = (data.site_xpos[0].copy(), data.site_xmat[0].reshape(3, 3).copy())
        result = qpik.solve(model, {"tip": target}, seed=i)
        assert angle(np.asarray(result.q)[:4]) <= 1.2 + 1e-9, (i, result.reason)


def test_a_configurations_mocap_poses_are_where_the_solve_works():
    """An arm on a mocap base that the configuration moved (data.mocap_pos) is solved
    there (qpik.solve and IKSession given the configuration): the answer reaches the
    target in that configuration's world, and the caller's model is left as it was."""
    import mujoco

    xml = """<mujoco><compiler angle="radian"/><worldbody><body name="base" mocap="true">
      <body name="l1"><joint name="j1" axis="0 0 1" range="-3 3"/><geom size="0.02"/>
       <body name="l2" pos="1 0 0"><joint name="j2" axis="0 0 1" range="-3 3"/>
        <geom size="0.02"/><site name="ee" pos="1 0 0"/></body></body></body>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    configuration = qpik.Configuration(model)
    configuration.data.mocap_pos[0] = [5.0, 0.0, 0.0]
    configuration.update(np.array([0.3, 0.4]))
    target = np.array([6.0, 0.8, 0.0])  # 1.28 m from the moved base (reach 2 m)
    check = qpik.Configuration(model)
    check.data.mocap_pos[0] = [5.0, 0.0, 0.0]
    for result in (
        qpik.solve(configuration, {"ee": target}, seed=0),
        qpik.IKSession(configuration).solve({"ee": target}, seed=0),
    ):
        assert result.converged, result
        check.update(result.q)
        assert np.linalg.norm(check.frame_pose("ee")[0] - target) <= 1e-4
    assert model.body_pos[1].tolist() == [0.0, 0.0, 0.0]
