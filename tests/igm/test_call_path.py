"""The compiled engine's call path (issue 20): the per-frame plan of fixed kernel arguments,
the start box and parse_target's fast path give the answers of the general path, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

import qpik
from qpik.igm.targets import parse_target
from qpik.model.rotations import nearest_rotation


def _rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_fast_path_targets_equal_the_general_path():
    p, R = np.array([0.3, 0.2, 0.4]), _rotation(0.3)
    fast = parse_target((p, R))
    general = parse_target((p.tolist(), R.tolist()))  # lists: the general path
    assert fast.position.tobytes() == general.position.tobytes()
    assert fast.rotation is not None and general.rotation is not None
    assert fast.rotation.tobytes() == general.rotation.tobytes()
    assert fast.position is not p and fast.rotation is not R  # copies
    skewed = R + 1e-12  # orthonormal within 1e-6 but not 1e-14: projected (general path)
    assert parse_target((p, skewed)).rotation.tobytes() == nearest_rotation(skewed).tobytes()


@pytest.mark.parametrize(
    "target",
    [
        (np.array([np.nan, 0.0, 0.0]), np.eye(3)),
        (np.array([2e9, 0.0, 0.0]), np.eye(3)),
        (np.zeros(3), np.full((3, 3), np.nan)),
        (np.zeros(3), 2.0 * np.eye(3)),
        (np.zeros(3), np.eye(3).T[:, ::-1]),  # not C-contiguous, det < 0
        (np.zeros(4), np.eye(3)),
    ],
)
def test_fast_path_rejects_as_the_general_path(target):
    with pytest.raises(qpik.InvalidTarget):
        parse_target(target)


def test_plans_follow_the_options():
    """A session reuses its plan while the options are the same and rebuilds it when they
    change: every answer equals a fresh session's."""
    session = qpik.IKSession("ur5e")
    target = {"ee": [0.3, 0.2, 0.4]}
    for keywords in ({}, {"max_iters": 7}, {}, {"limits": None}, {"tol_position": 1e-3}, {}):
        got = session.solve(target, seed=3, **keywords)
        want = qpik.IKSession("ur5e").solve(target, seed=3, **keywords)
        assert got.q.tobytes() == want.q.tobytes() and got.iterations == want.iterations


def test_a_plans_kept_scratch_gives_a_fresh_runs_bits():
    """A plan keeps its run's scratch (kinematics, step, paths) for the next run with the same
    options: after pose, position-only, unreachable, restarted and capped solves in any order,
    every answer (q, path, histories) equals a fresh session's, bit for bit."""
    rng = np.random.default_rng(5)
    targets = []
    for k in range(8):
        position = rng.uniform([-0.5, -0.5, 0.1], [0.5, 0.5, 0.7])
        if k % 4 == 1:
            targets.append({"ee": position})  # position only
        elif k % 4 == 3:
            targets.append({"ee": (position * 10.0, _rotation(0.1 * k))})  # out of reach
        else:
            targets.append({"ee": (position, _rotation(0.3 * k))})
    for keywords in ({"max_iters": 6, "restarts": 2}, {"tol_position": 1e-6}):
        session = qpik.IKSession("ur5e")
        for seed, target in [*enumerate(targets), *enumerate(targets[::-1])]:
            got = session.solve(target, seed=seed, **keywords)
            want = qpik.IKSession("ur5e").solve(target, seed=seed, **keywords)
            assert got.q.tobytes() == want.q.tobytes()
            assert got.path.tobytes() == want.path.tobytes()
            assert list(got.error_history) == list(want.error_history)
            assert list(got.residual_history) == list(want.residual_history)
            assert (got.iterations, got.restarts_used, got.reason) == (
                want.iterations,
                want.restarts_used,
                want.reason,
            )


def test_start_box_checks_and_clips():
    session = qpik.IKSession("ur5e")
    target = {"ee": [0.3, 0.2, 0.4]}
    q0 = session.mid_q()
    q0[0] = np.nan
    with pytest.raises(qpik.InvalidConfiguration):
        session.solve(target, q0=q0)
    q0 = session.mid_q()
    q0[1] = session._upper[1] + 1e-3
    with pytest.raises(qpik.JointLimitViolation):
        session.solve(target, q0=q0)
    q0[1] = session._upper[1] + 1e-7  # within 1e-6: clipped
    result = session.solve(target, q0=q0, max_iters=0, restarts=0)
    assert result.path[0][1] == session._upper[1]


@pytest.mark.parametrize("offset", [0.0, 0.01, 5.0])
def test_a_frame_no_joint_moves_keeps_the_start(offset):
    """A frame on a body fixed to the world (its chain has no joint: an empty index, not
    "every coordinate"): the answer is the start, met or unreachable, and the compiled
    plan copies the whole start into q and path (it returned zeros once)."""
    model = qpik.load_robot("ur5e")
    start = np.clip(model.qpos0 + 0.3, model.jnt_range[:, 0], model.jnt_range[:, 1])
    configuration = qpik.Configuration(model, start)
    p, _ = configuration.frame_pose("base_link", "body")
    session = qpik.IKSession(configuration)
    for _ in range(2):  # the plan built, then reused
        result = session.solve({("base_link", "body"): p + offset})
        assert result.engine == "compiled"
        assert result.q.tobytes() == start.tobytes()
        assert result.path.shape == (1, model.nq) and result.path[0].tobytes() == start.tobytes()
        assert result.converged == (offset == 0.0)


def _same(a: qpik.IKResult, b: qpik.IKResult) -> None:
    assert a.q.tobytes() == b.q.tobytes() and a.path.tobytes() == b.path.tobytes()
    assert (a.converged, a.reason, a.iterations, a.restarts_used) == (
        b.converged, b.reason, b.iterations, b.restarts_used,
    )  # fmt: skip
    assert (a.position_error, a.orientation_error) == (b.position_error, b.orientation_error)
    assert list(a.error_history) == list(b.error_history)
    assert list(a.residual_history) == list(b.residual_history)
    assert a.frame_errors == b.frame_errors and a.levels_met == b.levels_met
    assert (a.engine, a.coupling_error, a.constraint_error) == (
        b.engine, b.coupling_error, b.constraint_error,
    )  # fmt: skip


def _ur5e_pose(seed: int) -> tuple:
    """The UR5e and its ``ee`` pose ``(p, R)`` at a random configuration drawn with ``seed``
    (a reachable target)."""
    model = qpik.load_robot("ur5e")
    configuration = qpik.Configuration(model)
    configuration.update(configuration.random_q(np.random.default_rng(seed)))
    return model, configuration.frame_pose("ee")


def _general(session: qpik.IKSession, monkeypatch, targets, **keywords) -> qpik.IKResult:
    """``session.solve`` with the lean lane turned off (the general path)."""
    with monkeypatch.context() as patch:
        patch.setattr(qpik.IKSession, "_lean", lambda *args: None)
        return session.solve(targets, **keywords)


def _count_lean(monkeypatch, calls: list) -> None:
    """Count the solves the lean lane answers (``calls``): by ``_lean``'s
    ``kernels.igm_lean_run``, or by the compiled lane ``_make_lane`` makes
    (``kernels.session_lane``) where it answers."""
    from qpik.igm import kernels

    real_run, real_lane = kernels.igm_lean_run, kernels.session_lane

    class Counted:
        def __init__(self, *args):
            self.lane = real_lane(*args)

        def solve(self, *args):
            result = self.lane.solve(*args)
            if result is not None:
                calls.append(2)
            return result

    monkeypatch.setattr(kernels, "igm_lean_run", lambda *args: calls.append(1) or real_run(*args))
    monkeypatch.setattr(kernels, "session_lane", Counted)


def test_the_lean_lane_gives_the_general_paths_answers(monkeypatch):
    """IKSession's lean lane (one (position, rotation) target, a plan made for the options,
    limits 'joint'): the general path's answers bit for bit, with int and Generator seeds, q0
    given or not, a time budget or not; and the lane is taken (one compiled call) on every
    solve but the first of a run with the same options (which makes the plan): by ``_lean``
    on the second, which makes the compiled lane, and by that lane on the others."""
    model = qpik.load_robot("ur5e")
    lean, general = qpik.IKSession(model), qpik.IKSession(model)
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(3)
    calls: list = []
    _count_lean(monkeypatch, calls)
    runs = ({}, {"tol_position": 1e-6}, {"time_budget": 10.0, "restarts": 3})
    for keywords in runs:
        for k in range(15):
            configuration.update(configuration.random_q(rng))
            target = configuration.frame_pose("ee")
            q0 = configuration.random_q(rng) if k % 2 else None
            seeds = (k, k) if k % 3 else (np.random.default_rng(k), np.random.default_rng(k))
            a = lean.solve({"ee": target}, q0=q0, seed=seeds[0], **keywords)
            b = _general(general, monkeypatch, {"ee": target}, q0=q0, seed=seeds[1], **keywords)
            _same(a, b)
    assert calls == [1] + [2] * 13 + [1] + [2] * 13 + [1] + [2] * 13


def test_the_lean_lanes_option_check_is_the_options_memos(monkeypatch):
    """The lane reads its options from the session's memo only for the same keywords, of the
    same types and values (in any order): an equal value of another type (np.float64 for a
    float) goes through the options' checks (then the lane again); every answer is a fresh
    session's."""
    model, pose = _ur5e_pose(6)
    session = qpik.IKSession(model)
    target = {"ee": pose}
    calls: list = []
    _count_lean(monkeypatch, calls)
    runs = (
        {"tol_position": 1e-6, "restarts": 3},
        {"restarts": 3, "tol_position": 1e-6},
        {"restarts": 3, "tol_position": np.float64(1e-6)},
        {"tol_position": 1e-6, "restarts": 3},
    )
    for keywords in runs:
        for seed in (1, np.random.default_rng(1)):
            got = session.solve(target, seed=seed, **keywords)
            fresh = np.random.default_rng(1) if isinstance(seed, np.random.Generator) else 1
            _same(got, _general(qpik.IKSession(model), monkeypatch, target, seed=fresh, **keywords))
    # Lane calls per run of two solves: the first run's second (its first makes the plan);
    # both of the second (the memo's options, in another order: the same plan); then new
    # options (np.float64), whose first solve makes their plan; then the first run's again,
    # against the memo of the third (types differ): its options made again, and their plan.
    # (by _lean, which makes the compiled lane: 1; by that lane: 2)
    assert calls == [1] + [2, 2] + [1] + [1]


@pytest.mark.parametrize(
    "q0, error",
    [
        (np.full(6, np.nan), qpik.InvalidConfiguration),
        (np.full(6, 10.0), qpik.JointLimitViolation),
        (np.zeros(5), qpik.InvalidConfiguration),
    ],
)
def test_the_lean_lane_leaves_bad_starts_to_the_general_path(q0, error):
    model = qpik.load_robot("ur5e")
    session = qpik.IKSession(model)
    target = qpik.Configuration(model).frame_pose("ee")
    _warm(session, {"ee": target})
    with pytest.raises(error):
        session.solve({"ee": target}, q0=q0)


def test_the_lean_lane_leaves_other_targets_and_starts_to_the_general_path(monkeypatch):
    """Lists, a skewed rotation (projected by the general path), a list start, a NaN target:
    the answers (or errors) of the general path."""
    model, (p, R) = _ur5e_pose(1)
    session, reference = qpik.IKSession(model), qpik.IKSession(model)
    _warm(session, {"ee": (p, R)})
    for target, q0 in (((p, R + 1e-12), None), ((p.tolist(), R), None), ((p, R), [0.1] * 6)):
        expected = _general(reference, monkeypatch, {"ee": target}, q0=q0, seed=5)
        _same(session.solve({"ee": target}, q0=q0, seed=5), expected)
    with pytest.raises(qpik.InvalidTarget):
        session.solve({"ee": (np.array([np.nan, 0.0, 0.0]), R)})


def test_the_lean_lane_starts_from_a_configurations_q(monkeypatch):
    """qpik.solve on a Configuration (its q the default start) and a session made from one:
    the lean lane's answers are the general path's."""
    model = qpik.load_robot("ur5e")
    configuration = qpik.Configuration(model)
    configuration.update(configuration.random_q(np.random.default_rng(4)))
    start = qpik.Configuration(model, configuration.random_q(np.random.default_rng(5)))
    target = {"ee": configuration.frame_pose("ee")}
    session = qpik.IKSession(start)
    for _ in range(3):  # the plan made, then the compiled lane, which answers the third
        a, b = session.solve(target, seed=2), qpik.solve(start, target, seed=2)
    assert session._prepared.lane is not None
    _same(a, _general(qpik.IKSession(start), monkeypatch, target, seed=2))
    _same(b, a)


def _warm(session: qpik.IKSession, targets: dict, **keywords) -> None:
    """Two solves of ``targets``: the first makes the frame's plan, the second (by
    ``_lean``) the compiled lane of these options, which takes the solves after them."""
    for _ in range(2):
        session.solve(targets, **keywords)
    assert session._prepared.lane is not None


@pytest.mark.parametrize(
    "seed",
    [
        7,
        2**64 + 5,
        np.int64(7),
        np.random.SeedSequence(9),
        np.random.Generator(np.random.MT19937(4)),
        np.random.Generator(np.random.PCG64(4)),
        np.random.Generator(np.random.Philox(4)),
    ],
    ids=["int", "int past 2**64", "np.int64", "SeedSequence", "MT19937", "PCG64", "Philox"],
)
def test_the_compiled_lane_draws_every_seeds_state_as_the_general_path(seed, monkeypatch):
    """Every kind of seed (a Generator of a raw-uint64 bit generator: one draw in the lane;
    the others through rng_state) gives the general path's answer, and advances a
    Generator by the same draw."""
    import copy

    model, pose = _ur5e_pose(8)
    session = qpik.IKSession(model)
    target = {"ee": pose}
    calls: list = []
    _count_lean(monkeypatch, calls)
    _warm(session, target, restarts=4)
    twin = copy.deepcopy(seed)
    got = session.solve(target, seed=seed, restarts=4)
    assert calls == [1, 2]  # (the second solve by _lean, this one by the compiled lane)
    want = _general(qpik.IKSession(model), monkeypatch, target, seed=twin, restarts=4)
    _same(got, want)
    if isinstance(seed, np.random.Generator):
        assert seed.integers(2**62) == twin.integers(2**62)  # (the same state after)


@pytest.mark.parametrize(
    "keywords, error",
    [
        ({"seed": -1}, qpik.InvalidInput),
        ({"seed": 1.5}, qpik.InvalidInput),
        ({"tol_position": -1.0}, qpik.InvalidOption),
        ({"no_such_option": 1}, qpik.InvalidOption),
        ({"q0": np.zeros(7)}, qpik.InvalidConfiguration),
    ],
)
def test_the_compiled_lane_leaves_bad_arguments_to_the_general_path(keywords, error, monkeypatch):
    """Arguments the lane does not take raise the general path's typed errors, and the
    lane still answers the next plain solve."""
    model = qpik.load_robot("ur5e")
    session = qpik.IKSession(model)
    target = {"ee": qpik.Configuration(model).frame_pose("ee")}
    calls: list = []
    _count_lean(monkeypatch, calls)
    _warm(session, target, seed=0)
    with pytest.raises(error):
        session.solve(target, **keywords)
    plain = session.solve(target, seed=0, stack=None)
    assert calls[-1] == 2 and calls.count(2) == 1  # (only the plain solve by the lane)
    _same(plain, qpik.IKSession(model).solve(target, seed=0))


def test_the_compiled_lane_follows_a_model_edited_in_place_and_pickling():
    """A model edited in place after the lane was made: the solve is a fresh session's (the
    watch makes a new preparation, with no lane); a pickled session (the lane not pickled)
    solves as before."""
    import pickle

    model, pose = _ur5e_pose(2)
    session = qpik.IKSession(model)
    target = {"ee": pose}
    _warm(session, target, seed=1)
    before = session.solve(target, seed=1)
    copy = pickle.loads(pickle.dumps(session))
    assert copy._prepared.lane is None
    for _ in range(3):
        _same(copy.solve(target, seed=1), before)
    model.jnt_range[1] = [-0.5, 0.5]
    edited = session.solve(target, seed=1)
    _same(edited, qpik.IKSession(model).solve(target, seed=1))
    assert edited.q[1] >= -0.5 - 1e-12 and edited.q[1] <= 0.5 + 1e-12


def test_the_qp_engines_lent_scratch_gives_a_fresh_runs_bits():
    """The "qp" engine's solves borrow their session's scratch configuration and joint
    limits (IKSession._qp_problem): on a floating-base humanoid, after multi-frame,
    unreachable, restarted and custom-limit solves in any order, every answer (q, path,
    histories) equals a fresh session's, bit for bit."""
    model = _floating_arms()
    rng = np.random.default_rng(7)
    configuration = qpik.Configuration(model)
    hands = ("left", "right")
    targets = []
    for k in range(6):
        configuration.update(configuration.random_q(rng))
        goal = {h: configuration.frame_pose(h, "site")[0] for h in hands}
        if k % 3 == 2:
            goal["left"] = goal["left"] + 5.0  # out of reach of the arm (the base is free)
        targets.append(goal)
    custom = [qpik.limits.ConfigurationLimit(model, gain=0.5)]
    session = qpik.IKSession(model)
    for seed, target in [*enumerate(targets), *enumerate(targets[::-1])]:
        for keywords in ({"max_iters": 8, "restarts": 1}, {"limits": custom, "max_iters": 5}):
            got = session.solve(target, seed=seed, engine="qp", **keywords)
            want = qpik.IKSession(model).solve(target, seed=seed, engine="qp", **keywords)
            assert got.q.tobytes() == want.q.tobytes()
            assert got.path.tobytes() == want.path.tobytes()
            assert list(got.error_history) == list(want.error_history)
            assert list(got.residual_history) == list(want.residual_history)


def _floating_arms():
    import mujoco

    arm = """<body name="{s}1" pos="0 {y} 0"><joint name="{s}a" axis="0 0 1" range="-2 2"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
      <body name="{s}2" pos="0.3 0 0"><joint name="{s}b" axis="0 1 0" range="-2 2"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
        <site name="{s}" pos="0.3 0 0"/></body></body>"""
    xml = (
        '<mujoco><compiler angle="radian"/><worldbody><body name="base"><freejoint/>'
        '<geom type="box" size="0.1 0.1 0.1"/>'
        + arm.format(s="left", y=0.15)
        + arm.format(s="right", y=-0.15)
        + "</body></worldbody></mujoco>"
    )
    return mujoco.MjModel.from_xml_string(xml)


def test_the_compiled_lane_answers_mixed_calls_as_fresh_sessions(monkeypatch):
    """A warm session's solves over a mix of frame keys, target forms, starts, seeds and
    options (good and bad, in a seeded random order): each answer, or each typed error, is a
    fresh session's (the general path), bit for bit."""
    import random

    model, (p, R) = _ur5e_pose(1)
    # (the lane's calls several times over in each list, so that it takes about a third)
    keys = ["ee", "ee", ("ee", "site"), "nope"]
    targets = [(p, R)] * 6 + [(p.tolist(), R), (p, R[:, ::-1]), (p.astype(np.float32), R), p]
    mid = qpik.Configuration(model).mid_q()
    starts = [None, mid, mid + 0.1] * 2
    starts += [np.full(6, 10.0), np.zeros(5), [0.1] * 6]
    seeds = [0, 7, 2**70, np.random.SeedSequence(3), -1]
    options = [{}] * 4 + [
        {"stack": None},
        {"restarts": 3},
        {"restarts": 3.0},
        {"tol_position": "x"},
    ]
    session = qpik.IKSession(model)
    calls: list = []
    _count_lean(monkeypatch, calls)
    _warm(session, {"ee": (p, R)}, seed=0)
    rng = random.Random(0)

    def outcome(solver, keywords):
        try:
            result = solver.solve({rng_key: rng_target}, **keywords)
        except qpik.QpikError as exc:
            return type(exc).__name__
        return result.q.tobytes(), result.path.tobytes(), result.iterations, result.reason

    answered = 0
    for _ in range(120):
        rng_key, rng_target = rng.choice(keys), rng.choice(targets)
        keywords = {"q0": rng.choice(starts), "seed": rng.choice(seeds), **rng.choice(options)}
        _warm(session, {"ee": (p, R)}, seed=0)  # (the lane of the default options again)
        before = calls.count(2)
        got = outcome(session, keywords)
        by_lane = calls.count(2) > before
        assert got == outcome(qpik.IKSession(model), keywords)
        answered += by_lane
    assert answered >= 10  # (17 of the 120: the others are not the lane's to take)
