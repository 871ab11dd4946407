"""The IGM solver: convergence, honest failure, limits, determinism."""

from __future__ import annotations

import mink
import numpy as np
import pytest
from conftest import configuration_of, load_or_skip

import qpik
from qpik.igm.result import REASONS


def reachable_pose(robot, rng, frame="ee"):
    configuration = configuration_of(robot)
    configuration.update(configuration.random_q(rng))
    return configuration.frame_pose(frame)


@pytest.mark.parametrize("robot", ["planar_2r", "planar_4r"])
def test_planar_positions_converge(robot, rng):
    model = qpik.load_robot(robot)
    for i in range(20):
        position, _ = reachable_pose(robot, rng)
        result = qpik.solve(model, {"ee": position}, seed=i)
        assert result.converged, result
        assert result.reason == "converged" and result.position_error <= 1e-4
        configuration = qpik.Configuration(model, result.q)
        np.testing.assert_allclose(configuration.frame_pose("ee")[0], position, atol=1e-4)
        assert configuration.within_limits(tol=0.0)


def test_lecture_4r_target_minus1_2():
    result = qpik.solve("planar_4r", {"ee": [-1.0, 2.0, 0.0]}, q0=[0.76, 0.90, 0.69, 1.19])
    assert result.converged and result.position_error <= 1e-4


@pytest.mark.parametrize("robot", ["ur5e", "panda"])
def test_arm_poses_converge_in_several_target_forms(robot, rng):
    model = qpik.load_robot(robot)
    for i in range(15):
        position, rotation = reachable_pose(robot, rng)
        matrix = np.eye(4)
        matrix[:3, :3], matrix[:3, 3] = rotation, position
        target = [
            (position, rotation),
            matrix,
            mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), position),
        ][i % 3]
        result = qpik.solve(model, {"ee": target}, seed=i)
        assert result.converged, result
        assert result.position_error <= 1e-4 and result.orientation_error <= 1e-3
        configuration = qpik.Configuration(model, result.q)
        assert configuration.within_limits(tol=0.0)
        np.testing.assert_allclose(configuration.frame_pose("ee")[0], position, atol=1e-4)


def test_several_frames_at_once(rng):
    model = qpik.load_robot("panda")
    configuration = configuration_of("panda")
    configuration.update(configuration.random_q(rng))
    targets = {
        "ee": configuration.frame_pose("ee"),
        ("link4", "body"): configuration.frame_pose("link4", "body")[0],
    }
    result = qpik.solve(model, targets, seed=1)
    assert result.converged, result
    assert set(result.frame_errors) == {"ee", "link4"}


def test_out_of_reach_reports_reason_and_stays_in_limits():
    result = qpik.solve("panda", {"ee": [3.0, 0.0, 0.5]}, restarts=2, seed=0)
    assert not result.converged
    assert result.reason == "unreachable" and result.reason in REASONS
    assert result.iterations == 0 and result.position_error > 1.0
    configuration = qpik.Configuration(qpik.load_robot("panda"), result.q)
    assert configuration.within_limits(tol=0.0)


def test_start_at_the_2r_singularity_converges():
    result = qpik.solve("planar_2r", {"ee": [1.2, 0.8, 0.0]}, q0=[0.0, 0.0], restarts=0)
    assert result.converged and result.restarts_used == 0, result


def test_same_seed_same_result(rng):
    position, rotation = reachable_pose("panda", rng)
    first = qpik.solve("panda", {"ee": (position, rotation)}, seed=7)
    second = qpik.solve("panda", {"ee": (position, rotation)}, seed=7)
    np.testing.assert_array_equal(first.q, second.q)
    assert first.iterations == second.iterations


def test_time_budget_and_max_iters_are_reasons(rng):
    position, rotation = reachable_pose("panda", rng)
    for engine in ("compiled", "qp"):
        result = qpik.solve("panda", {"ee": (position, rotation)}, time_budget=0.0, engine=engine)
        assert result.reason == "time_budget" and not result.converged
    result = qpik.solve("panda", {"ee": [0.5, 0.3, 0.2]}, max_iters=1, restarts=0)
    assert result.reason in ("max_iters", "converged")
    assert result.iterations <= 1


def test_alpha_beta_lecture_recursion():
    # Small alpha and beta: the lecture's recursion converges, more slowly.
    fast = qpik.solve("planar_2r", {"ee": [1.2, 0.8, 0.0]}, q0=[0.3, 0.5], restarts=0)
    slow = qpik.solve(
        "planar_2r",
        {"ee": [1.2, 0.8, 0.0]},
        q0=[0.3, 0.5],
        alpha=0.5,
        beta=0.5,
        max_iters=500,
        restarts=0,
        max_step=None,
    )
    assert fast.converged and slow.converged and slow.iterations > fast.iterations


def test_custom_stack_gets_the_targets(rng):
    model = qpik.load_robot("panda")
    position, rotation = reachable_pose("panda", rng)
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    posture = qpik.tasks.PostureTask(model, cost=0.01)
    posture.set_target(qpik.Configuration(model).mid_q())
    result = qpik.solve(model, {"ee": (position, rotation)}, stack=[[frame], [posture]], seed=3)
    assert result.converged, result
    with pytest.raises(qpik.InvalidTarget, match="no task in the given stack"):
        qpik.solve(model, {"flange": position}, stack=[[frame]])


def test_a_minks_own_frame_task_in_a_stack_gets_the_targets(rng):
    """mink's FrameTask (not qpik's subclass) is set the solve's target too: one with a
    stale target of its own is not driven there, one without a target does not raise."""
    model = qpik.load_robot("panda")
    position, rotation = reachable_pose("panda", rng)
    posture = mink.PostureTask(model, cost=0.01)
    posture.set_target(qpik.Configuration(model).mid_q())
    stale = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    stale.set_target_from_configuration(qpik.Configuration(model))
    unset = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    reference = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    answers = [
        qpik.solve(model, {"ee": (position, rotation)}, stack=[[task], [posture]], seed=3)
        for task in (stale, unset, reference)
    ]
    for result in answers:
        assert result.converged, result
        reached = qpik.Configuration(model, result.q).frame_pose("ee")[0]
        assert np.linalg.norm(reached - position) <= 1e-3
    np.testing.assert_array_equal(answers[0].q, answers[2].q)
    # the caller's task gets its own target back after the solve
    assert unset.transform_target_to_world is None


def test_bad_inputs():
    with pytest.raises(qpik.InvalidTarget, match="finite"):
        qpik.solve("panda", {"ee": [0.3, np.nan, 0.5]})
    with pytest.raises(qpik.UnknownFrame, match="ee"):
        qpik.solve("panda", {"gripper": [0.3, 0.0, 0.5]})
    with pytest.raises(qpik.JointLimitViolation, match="joint4"):
        qpik.solve("panda", {"ee": [0.3, 0.0, 0.5]}, q0=[0, 0, 0, 0.5, 0, 1, 0])
    with pytest.raises(qpik.InvalidTarget, match="shape"):
        qpik.solve("panda", {"ee": [0.3, 0.0]})
    with pytest.raises(qpik.InvalidTarget, match="no targets"):
        qpik.solve("panda", {})


def test_history_and_path_of_the_returned_attempt(rng):
    position, rotation = reachable_pose("ur5e", rng)
    result = qpik.solve("ur5e", {"ee": (position, rotation)}, seed=2)
    assert result.converged
    assert result.path.shape[1] == 6 and len(result.path) == len(result.error_history)
    np.testing.assert_array_equal(result.path[-1], result.q)
    assert result.error_history[-1] == (result.position_error, result.orientation_error)
    assert result.error_history[0][0] > result.error_history[-1][0]


def test_custom_stack_keeps_the_users_gains(rng):
    model = qpik.load_robot("panda")
    position, rotation = reachable_pose("panda", rng)
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0, gain=0.7)
    qpik.solve(model, {"ee": (position, rotation)}, stack=[frame], seed=1)
    assert frame.gain == 0.7


def test_editing_a_model_in_place_is_seen_by_the_next_solve():
    model = qpik.load_robot("planar_2r")
    target = {"ee": [1.2, 0.8, 0.0]}
    assert qpik.solve(model, target, q0=[0.3, 0.5]).converged
    model.jnt_range[1] = [0.0, 0.2]  # narrow q2: the target is now out of reach
    result = qpik.solve(model, target, q0=[0.3, 0.1], restarts=3)
    assert not result.converged and 0.0 <= result.q[1] <= 0.2 + 1e-12


# ------------------------------------------------------------- engines agree
@pytest.mark.parametrize("robot", ["panda", "ur5e", "planar_4r"])
def test_compiled_engine_takes_the_exact_qp_step(robot, rng):
    """Without singularity damping, one iteration of the compiled engine equals IKSolver's
    step with its exact QP (same level, trust region and limit box), from starts where
    limits bind and where not."""
    model = qpik.load_robot(robot)
    configuration = qpik.Configuration(model)
    for i in range(8):
        position, rotation = reachable_pose(robot, rng)
        target = {"ee": (position, rotation) if robot != "planar_4r" else position}
        q0 = configuration.random_q(rng)
        if i % 2:  # start at a limit
            q0[0] = configuration.lower[0]
        kwargs = dict(q0=q0, max_iters=1, restarts=0, seed=0, damping_law=None)
        compiled = qpik.solve(model, target, engine="compiled", **kwargs)
        reference = qpik.solve(model, target, engine="qp", solver="auto", **kwargs)
        assert compiled.engine == "compiled" and reference.engine == "qp"
        np.testing.assert_allclose(compiled.path[1], reference.path[1], atol=1e-9, rtol=0)


def _reference_step(model, frame, target, q, law, damping=1e-6, max_step=(0.2, 0.5)):
    """One IGM step from its definition, with numpy's SVD and scipy's bounded least squares
    (BVLS): the damped pose level under the 0.95 joint-limit box."""
    from scipy.optimize import lsq_linear
    from scipy.spatial.transform import Rotation

    from qpik.model.rotations import left_jacobian_inverse as so3_left_jacobian_inverse

    configuration = qpik.Configuration(model, q)
    position, rotation = configuration.frame_pose(frame)
    jacobian = configuration.frame_jacobian(frame)
    rotation_error = Rotation.from_matrix(rotation @ target[1].T).as_rotvec()
    error = np.concatenate([position - target[0], rotation_error])
    ep, eo = np.linalg.norm(error[:3]), np.linalg.norm(error[3:])
    gain = min(1.0, max_step[0] / ep, max_step[1] / eo)
    A = np.vstack([jacobian[:3], so3_left_jacobian_inverse(rotation_error) @ jacobian[3:]])
    b = -gain * error
    sigma = np.linalg.svd(A, compute_uv=False)[min(A.shape) - 1]
    lam2 = 0.0
    if sigma < law.singular_threshold:
        lam2 = law.max_damping**2 * (1 - (sigma / law.singular_threshold) ** 2)
        lam2 *= min(1.0, np.linalg.norm(b) / law.error_scale)
    reg = damping + lam2
    nv = model.nv
    lower, upper = configuration.lower, configuration.upper
    solution = lsq_linear(
        np.vstack([A, np.sqrt(reg) * np.eye(nv)]),
        np.concatenate([b, np.zeros(nv)]),
        bounds=(np.minimum(0.95 * (lower - q), 0), np.maximum(0.95 * (upper - q), 0)),
        method="bvls",
        tol=1e-15,
    )
    # Backtracking: halve a step that increases |e_p|^2 + |e_o|^2, at most three times.
    energy = ep**2 + eo**2
    for halving in range(4):
        step = q + 0.5**halving * solution.x
        configuration.update(step)
        p, r = configuration.frame_pose(frame)
        new = np.sum((p - target[0]) ** 2) + Rotation.from_matrix(r @ target[1].T).magnitude() ** 2
        if new < energy:
            break
    return step, sigma


@pytest.mark.parametrize("robot", ["panda", "ur5e"])
def test_compiled_step_with_damping_equals_its_definition(robot, rng):
    model = qpik.load_robot(robot)
    configuration = qpik.Configuration(model)
    damped = 0
    for i in range(12):
        target = reachable_pose(robot, rng)
        q0 = configuration.random_q(rng)
        if i % 3 == 0:  # near a wrist singularity: joint 5 (UR) / 6 (panda) almost straight
            q0[4 if robot == "ur5e" else 5] = 0.02 if robot == "ur5e" else 0.02 + 0.0
            q0 = np.clip(q0, configuration.lower, configuration.upper)
        result = qpik.solve(model, {"ee": target}, q0=q0, max_iters=1, restarts=0, seed=0)
        expected, sigma = _reference_step(model, "ee", target, q0, qpik.options.IGM_DAMPING)
        damped += sigma < qpik.options.IGM_DAMPING.singular_threshold
        np.testing.assert_allclose(result.path[1], expected, atol=1e-8, rtol=0)
    assert damped > 0  # the damped branch was exercised


def test_engine_choice_is_checked():
    with pytest.raises(qpik.InvalidInput, match="engine"):
        qpik.solve("panda", {"ee": [0.4, 0.0, 0.5]}, engine="fast")
    model = qpik.load_robot("panda")
    with pytest.raises(qpik.InvalidInput, match="engine='compiled' needs"):
        qpik.solve(model, {"ee": [0.4, 0, 0.5], "link4": [0.2, 0, 0.5]}, engine="compiled")
    assert qpik.solve("panda", {"ee": [0.4, 0.0, 0.5]}).engine == "compiled"


# -------------------------------------------------------------- determinism
def _digest(result) -> bytes:
    return result.q.tobytes() + bytes([result.converged]) + str(result.iterations).encode()


def _targets(robot, n, seed):
    rng = np.random.default_rng(seed)
    return [reachable_pose(robot, rng) for _ in range(n)]


HARD = dict(tol_position=1e-6, tol_orientation=1e-6, max_iters=8, restarts=6)


def test_same_answer_after_other_solves_and_in_another_session():
    targets = _targets("ur5e", 6, 11)
    first = [qpik.solve("ur5e", {"ee": t}, seed=3, **HARD) for t in targets]
    session = qpik.IKSession("ur5e")
    for t in _targets("ur5e", 20, 12):  # unrelated solves in between, some with restarts
        session.solve({"ee": t}, seed=9, **HARD)
    again = [session.solve({"ee": t}, seed=3, **HARD) for t in targets]
    other = qpik.IKSession(qpik.load_robot("ur5e"))
    third = [other.solve({"ee": t}, seed=3, **HARD) for t in targets]
    general = [qpik.solve("ur5e", {"ee": t}, seed=3, engine="qp", **HARD) for t in targets[:2]]
    general_again = [
        qpik.solve("ur5e", {"ee": t}, seed=3, engine="qp", **HARD) for t in targets[:2]
    ]
    assert any(r.restarts_used > 0 for r in first)  # the restarts' stream matters
    assert [_digest(r) for r in first] == [_digest(r) for r in again] == [_digest(r) for r in third]
    assert [_digest(r) for r in general] == [_digest(r) for r in general_again]


def test_same_answer_first_in_a_fresh_process():
    import subprocess
    import sys

    targets = _targets("panda", 3, 21)
    here = [qpik.solve("panda", {"ee": t}, seed=5, **HARD).q for t in targets]
    code = (
        "import numpy as np, qpik, sys\n"
        "data = np.load(sys.argv[1])\n"
        "out = [qpik.solve('panda', {'ee': (p, r)}, seed=5, tol_position=1e-6, "
        "tol_orientation=1e-6, max_iters=8, restarts=6).q for p, r in zip(data['p'], data['r'])]\n"
        "sys.stdout.write(np.array(out).tobytes().hex())\n"
    )
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        path = f"{folder}/targets.npz"
        np.savez(path, p=np.array([t[0] for t in targets]), r=np.array([t[1] for t in targets]))
        output = subprocess.run(
            [sys.executable, "-c", code, path], capture_output=True, text=True, check=True
        ).stdout
    fresh = np.frombuffer(bytes.fromhex(output), dtype=float).reshape(3, -1)
    assert fresh.tobytes() == np.array(here).tobytes()


def test_seed_forms():
    target = {"ee": _targets("ur5e", 1, 4)[0]}
    a = qpik.solve("ur5e", target, seed=np.random.default_rng(8), **HARD)
    b = qpik.solve("ur5e", target, seed=np.random.default_rng(8), **HARD)
    c = qpik.solve("ur5e", target, seed=np.random.SeedSequence(8), **HARD)
    d = qpik.solve("ur5e", target, seed=np.random.SeedSequence(8), **HARD)
    e = qpik.solve("ur5e", target, seed=2**70, **HARD)
    assert _digest(a) == _digest(b) and _digest(c) == _digest(d)
    assert e.q.shape == (6,)


# ---------------------------------------------------------------- unreachable
def test_unreachable_is_answered_at_once_on_both_engines():
    far = [0.0, 0.0, 3.0]
    compiled = qpik.solve("ur5e", {"ee": far})
    assert compiled.reason == "unreachable" and compiled.iterations == 0
    assert compiled.restarts_used == 0 and compiled.engine == "compiled"
    model = qpik.load_robot("panda")
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=0.0)
    general = qpik.solve(model, {"ee": (far, np.eye(3))}, stack=[frame])
    assert general.reason == "unreachable" and general.iterations == 0
    # Just inside the bound: iterated, not ruled out.
    bound = qpik.IKSession(model).reach_bound("ee")
    inside = bound.center + [bound.radius - 1e-3, 0, 0]
    assert qpik.solve(model, {"ee": inside}, restarts=0).reason != "unreachable"


def test_every_reachable_target_is_iterated(rng):
    for robot in ("planar_2r", "planar_4r", "ur5e", "panda"):
        session = qpik.IKSession(robot)
        for _ in range(100):
            position, _ = reachable_pose(robot, rng)
            assert not session.reach_bound("ee").excludes(position, 0.0)


# ------------------------------------------------------------------ validation
@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(tol_position=0), "tol_position"),
        (dict(tol_position=-1), "tol_position"),
        (dict(tol_position=float("nan")), "tol_position"),
        (dict(tol_orientation=float("inf")), "tol_orientation"),
        (dict(tol_orientation="1e-3"), "tol_orientation"),
        (dict(time_budget=float("inf")), "time_budget"),
        (dict(time_budget=float("nan")), "time_budget"),
        (dict(time_budget=-1.0), "time_budget"),
        (dict(restarts=-1), "restarts"),
        (dict(restarts=1.5), "restarts"),
        (dict(restarts=True), "restarts"),
        (dict(max_iters=-1), "max_iters"),
        (dict(max_iters=10**9), "max_iters"),
        (dict(stall_window=0), "stall_window"),
        (dict(seed=-1), "seed"),
        (dict(seed="abc"), "seed"),
        (dict(seed=1.5), "seed"),
        (dict(alpha=2.0), "alpha"),
        (dict(beta=0.0), "beta"),
        (dict(max_step=(0.1,)), "max_step"),
        (dict(max_step=(0.1, -1.0)), "max_step"),
        (dict(damping=-1.0), "damping"),
        (dict(damping_law="strong"), "damping_law"),
        (dict(limits="all"), "limits"),
    ],
)
def test_bad_options_name_the_argument(kwargs, name):
    with pytest.raises(qpik.InvalidInput, match=name):
        qpik.solve("planar_2r", {"ee": [1.0, 1.0, 0.0]}, **kwargs)


@pytest.mark.parametrize(
    "good, bad",
    [
        (dict(max_iters=1), dict(max_iters=True)),
        (dict(max_iters=50), dict(max_iters=50.0)),
        (dict(restarts=0), dict(restarts=False)),
        (dict(stall_window=1), dict(stall_window=True)),
    ],
)
def test_an_option_is_checked_whatever_was_solved_before(good, bad):
    """A value equal to the last solve's (True == 1, 50.0 == 50) but of a type refused is
    refused in a session that solved with the valid one too (the options memo compares
    types as well)."""
    session = qpik.IKSession("ur5e")
    session.solve({"ee": [0.4, 0.1, 0.3]}, seed=0, **good)
    for fresh in (False, True):
        with pytest.raises(qpik.InvalidOption, match=next(iter(bad))):
            (qpik.IKSession("ur5e") if fresh else session).solve(
                {"ee": [0.4, 0.1, 0.3]}, seed=0, **bad
            )


@pytest.mark.parametrize("key", [None, 3, ("ee",), (1, "site"), ("ee", "site", 0), b"ee"])
def test_bad_frame_keys_are_typed_errors(key):
    with pytest.raises(qpik.InvalidInput, match="frame key"):
        qpik.solve("planar_2r", {key: [1.0, 1.0, 0.0]})


def test_bad_frame_type_and_targets():
    with pytest.raises(qpik.UnknownFrameType):
        qpik.solve("planar_2r", {("ee", "joint"): [1.0, 1.0, 0.0]})
    with pytest.raises(qpik.InvalidTarget, match="not a rotation"):
        qpik.solve("panda", {"ee": ([0.4, 0, 0.5], 2 * np.eye(3))})
    with pytest.raises(qpik.InvalidTarget, match="finite"):
        qpik.solve("panda", {"ee": ([0.4, 0, 0.5], np.full((3, 3), np.nan))})
    with pytest.raises(qpik.InvalidTarget):
        qpik.solve("panda", {"ee": "here"})
    with pytest.raises(qpik.InvalidInput, match="mapping"):
        qpik.solve("panda", [("ee", [0.4, 0.0, 0.5])])


def test_huge_budget_returns():
    # A pose a planar arm cannot take (tilted out of its plane): every attempt stalls, and
    # restarts=None with a budget stops after MAX_AUTO_RESTARTS.
    from scipy.spatial.transform import Rotation

    tilted = Rotation.from_rotvec([0.5, 0.0, 0.0]).as_matrix()
    result = qpik.solve("planar_2r", {"ee": ([1.0, 1.0, 0.0], tilted)}, time_budget=1e300)
    assert not result.converged
    assert result.restarts_used == qpik.options.MAX_AUTO_RESTARTS


# A reachable Panda pose (forward kinematics of this q) that 20 restarts miss: every one of
# those attempts ends blocked at a joint limit.
HARD_PANDA_Q = [-1.3112442847710999, 0.8879239088593973, 1.1947678194236544, -3.033074414548327,
                2.531297971140878, 2.4269590023353884, 2.4292851694955373]  # fmt: skip


def test_default_restarts_continue_within_the_work_budget():
    # restarts=None, no time budget: up to DEFAULT_RESTARTS restarts while the iterations
    # stay below DEFAULT_WORK_ATTEMPTS * max_iters. Attempts that end early (blocked at a
    # limit) leave room for more restarts than the 20 the iterations of 20 full attempts
    # would buy, and the hard pose converges.
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, np.array(HARD_PANDA_Q))
    target = {"ee": configuration.frame_pose("ee", "site")}
    capped = qpik.solve(model, target, seed=0, restarts=20)
    assert not capped.converged and capped.restarts_used == 20
    result = qpik.solve(model, target, seed=0)
    assert result.converged and 20 < result.restarts_used <= qpik.options.DEFAULT_RESTARTS
    assert result.iterations < qpik.options.DEFAULT_WORK_ATTEMPTS * 100
    again = qpik.solve(model, target, seed=0)  # deterministic: no clock involved
    assert again.restarts_used == result.restarts_used
    assert np.array_equal(again.q, result.q)


@pytest.mark.parametrize("engine", ["compiled", "qp"])
def test_work_budget_bounds_a_solve_no_attempt_can_finish(engine):
    # The tilted pose of a planar arm: every attempt fails. With max_iters 3 the budget
    # (63 iterations) ends the restarts before DEFAULT_RESTARTS; with the default 100 the
    # restarts run out first. Either way no attempt starts past the budget.
    from scipy.spatial.transform import Rotation

    tilted = Rotation.from_rotvec([0.5, 0.0, 0.0]).as_matrix()
    target = {"ee": ([1.0, 1.0, 0.0], tilted)}
    for max_iters in (3, 100):
        result = qpik.solve("planar_2r", target, seed=0, engine=engine, max_iters=max_iters)
        budget = qpik.options.DEFAULT_WORK_ATTEMPTS * max_iters
        assert not result.converged and result.engine == engine
        assert result.restarts_used <= qpik.options.DEFAULT_RESTARTS
        assert result.iterations < budget + max_iters  # the last attempt started below it
        assert result.iterations >= budget or result.restarts_used == qpik.options.DEFAULT_RESTARTS
    # Restarts given: no work budget, those restarts are all run.
    result = qpik.solve("planar_2r", target, seed=0, engine=engine, max_iters=3, restarts=40)
    assert result.restarts_used == 40


def test_baseline_loop_keeps_the_work_budget():
    from scipy.spatial.transform import Rotation

    configuration = qpik.Configuration(qpik.load_robot("planar_2r"))
    tilted = Rotation.from_rotvec([0.5, 0.0, 0.0]).as_matrix()
    result = qpik.baselines.damped_least_squares_igm(
        configuration, "ee", np.array([1.0, 1.0, 0.0]), tilted, max_iters=3, seed=0
    )
    assert not result.converged
    assert 3 * qpik.options.DEFAULT_WORK_ATTEMPTS <= result.iterations
    assert result.iterations < 3 * (qpik.options.DEFAULT_WORK_ATTEMPTS + 1)


# ------------------------------------------------------------ level-0 tasks
def test_convergence_covers_every_level0_task(rng):
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model)
    q0 = configuration.mid_q()
    configuration.update(q0)
    hold = qpik.tasks.FrameTask("link4", "body", position_cost=1.0, orientation_cost=1.0)
    hold.set_target(configuration.get_transform_frame_to_world("link4", "body"))
    # A target reachable with link4 held: move the last three joints only.
    q_goal = q0.copy()
    q_goal[4:] += rng.uniform(-0.4, 0.4, 3)
    configuration.update(q_goal)
    goal = configuration.frame_pose("ee")
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    result = qpik.solve(model, {"ee": goal}, q0=q0, stack=[[hold], [frame]], seed=0)
    assert result.converged, result
    configuration.update(q0)
    held_position, held_rotation = configuration.frame_pose("link4", "body")
    configuration.update(result.q)
    position, rotation = configuration.frame_pose("link4", "body")
    assert np.linalg.norm(position - held_position) <= 1e-4  # tol_position
    angle = np.arccos(np.clip((np.trace(rotation @ held_rotation.T) - 1) / 2, -1, 1))
    assert angle <= 1e-3  # tol_orientation
    # Level 0 that cannot be met (a posture far from the start, cost 1, one joint frozen
    # by the limits) is never reported converged, even when the frame target is met.
    posture = qpik.tasks.PostureTask(model, cost=1.0)
    far = q0.copy()
    far[0] = configuration.upper[0] + 1.0  # outside the limits: unreachable posture
    posture.set_target(far)
    result = qpik.solve(model, {"ee": goal}, q0=q0, stack=[[posture], [frame]], restarts=1)
    assert not result.converged and result.reason != "converged"


def test_task_errors_rule():
    from qpik.igm.qp_engine import task_errors as _task_errors

    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model)
    configuration.update(configuration.mid_q())
    position, rotation = configuration.frame_pose("ee")
    task = qpik.tasks.PositionTask("ee", "site")
    task.set_target(position + [0.003, 0.0, 0.004])
    assert _task_errors(task, configuration) == pytest.approx((0.005, 0.0))
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=0.0)
    assert _task_errors(frame, configuration) is None  # no target yet
    frame.set_target(
        mink.SE3.from_rotation_and_translation(
            mink.SO3.exp(np.array([0.0, 0.0, 0.2])) @ mink.SO3.from_matrix(rotation), position
        )
    )
    p, o = _task_errors(frame, configuration)
    assert p == pytest.approx(0.0, abs=1e-12) and o == 0.0  # orientation not regulated


def test_session_on_a_configuration_and_on_a_floating_model():
    configuration = configuration_of("ur5e", [0.1, -1.0, 1.2, -0.5, 0.4, 0.2])
    session = qpik.IKSession(configuration)
    position, _ = configuration.frame_pose("ee")
    result = session.solve({"ee": position + [0.01, 0.0, 0.0]}, restarts=0)
    np.testing.assert_array_equal(result.path[0], configuration.q)  # its q is the start
    assert result.converged and result.engine == "compiled"
    xml = """<mujoco><worldbody><body name="base"><freejoint/><geom size="0.1"/>
      <body name="link" pos="0 0 0.2"><joint name="hinge" axis="0 1 0" range="-1 1"/>
      <geom size="0.05"/><site name="tip" pos="0.3 0 0"/></body></body></worldbody></mujoco>"""
    import mujoco

    floating = qpik.IKSession(mujoco.MjModel.from_xml_string(xml))
    assert floating.reach_bound("tip") is None
    result = floating.solve({"tip": [0.5, 0.2, 0.4]}, seed=0)
    assert result.engine == "qp" and result.converged, result


def test_results_keep_only_their_attempt(rng):
    position, rotation = reachable_pose("panda", rng)
    result = qpik.solve("panda", {"ee": (position, rotation)}, seed=1)
    assert result.path.base is None or result.path.base.shape == result.path.shape
    assert len(result.residual_history) == len(result.path) - 1
    assert list(result.error_history)[-1] == result.error_history[-1]
    import pickle

    again = pickle.loads(pickle.dumps(result))
    np.testing.assert_array_equal(again.q, result.q)
    assert again.error_history == result.error_history


def test_unknown_solver_is_named_on_both_engines():
    for engine in ("compiled", "qp"):
        with pytest.raises(qpik.InvalidInput, match="unknown QP solver 'nope'"):
            qpik.solve("panda", {"ee": [0.4, 0.0, 0.5]}, solver="nope", engine=engine)


def test_options_object_presets_and_keywords_agree_bitwise():
    target = {"ee": [0.4, 0.1, 0.5]}
    by_keywords = qpik.solve("panda", target, seed=3, tol_position=1e-3, max_iters=50)
    options = qpik.SolveOptions(seed=3, tol_position=1e-3, max_iters=50)
    by_options = qpik.solve("panda", target, options=options)
    np.testing.assert_array_equal(by_keywords.q, by_options.q)
    # a keyword overrides the options; a preset name is options
    override = qpik.solve("panda", target, options=options, max_iters=0)
    assert override.iterations == 0
    fast = qpik.solve("panda", target, options="fast", seed=3)
    same = qpik.solve("panda", target, seed=3, **_fields(qpik.PRESETS["fast"]))
    np.testing.assert_array_equal(fast.q, same.q)
    session = qpik.IKSession("panda", options="fast")
    np.testing.assert_array_equal(session.solve(target, seed=3).q, fast.q)
    with pytest.raises(qpik.InvalidOption, match="preset"):
        qpik.solve("panda", target, options="quickest")
    with pytest.raises(qpik.InvalidOption) as info:
        qpik.solve("panda", target, stall_window=0)
    assert info.value.field == "stall_window"


def _fields(options):
    return {
        "tol_position": options.tol_position,
        "tol_orientation": options.tol_orientation,
        "max_iters": options.max_iters,
        "restarts": options.restarts,
    }


def test_solve_gives_the_callers_stack_back_unchanged():
    model = qpik.load_robot("panda")
    start = qpik.Configuration(model, qpik.IKSession(model).mid_q())
    position, rotation = start.frame_pose("ee")
    pose = qpik.tasks.PoseTask("ee", "site", gain=0.7)
    position_task = qpik.tasks.PositionTask("ee", "site", gain=0.9)
    position_task.set_target(position)
    target = (position + [0.05, 0.0, -0.05], rotation)
    result = qpik.solve(model, {"ee": target}, stack=[[pose], [position_task]], seed=0)
    assert result.converged, result
    assert pose.target_position is None and pose.target_rotation is None and pose.gain == 0.7
    np.testing.assert_array_equal(position_task.target, position)
    assert position_task.gain == 0.9
    with pytest.raises(qpik.InvalidTarget):  # raised mid-solve: still given back
        qpik.solve(model, {"ee": target[0]}, stack=[[pose]])
    assert pose.target_position is None


def test_reasons_are_string_enums():
    import json

    from qpik.igm.result import Reason

    result = qpik.solve("planar_2r", {"ee": [5.0, 0.0, 0.0]})
    assert result.reason is Reason.UNREACHABLE and result.reason == "unreachable"
    assert json.dumps({"reason": result.reason}) == '{"reason": "unreachable"}'
    assert f"{result.reason}" == str(result.reason) == "unreachable"
    assert set(REASONS) == {r.value for r in Reason} - {"diverged"}


def test_the_trust_region_bounds_target_tasks_below_level_0():
    """max_step scales the gains of the tasks on target frames whatever their level (a
    held frame in level 0, the goal in level 1): the first iterate moves the frame by
    about max_step, not by the whole error."""
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model)
    q0 = configuration.mid_q()
    configuration.update(q0)
    hold = qpik.tasks.PositionTask("link2", "body")
    hold.set_target(configuration.frame_pose("link2", "body")[0])
    start = configuration.frame_pose("ee")[0]
    goal = start + np.array([0.0, 0.25, -0.1])
    frame = qpik.tasks.PositionTask("ee")
    result = qpik.solve(
        model, {"ee": goal}, q0=q0, stack=[[hold], [frame]], seed=0, max_step=(0.02, 0.5)
    )
    assert result.converged, result
    configuration.update(result.path[1])
    first = np.linalg.norm(configuration.frame_pose("ee")[0] - start)
    assert 0.01 < first < 0.03, first  # the whole error is 0.27 m
    assert len(result.path) > 10


def test_a_target_on_the_workspace_boundary_converges_in_one_attempt():
    """erd:kinova (Jaco2) with its elbow all but straight at the target (q[2] = 3.137, pi - 5e-3:
    sigma_min of the pose Jacobian there about 1e-4): the damping slows each step near the
    answer to a few percent. An attempt within NEAR_TARGET tolerances goes on while the stall
    window sees progress, instead of ending at the first blocked step (each attempt from these
    starts used to end singular at 1.3 - 2.5e-5 m, and the TRAC-IK protocol's 5 ms ran out on
    restarts)."""
    from qpik.igm.kernels import BLOCKED, NEAR_TARGET

    assert NEAR_TARGET > 1.0 and 0.0 < BLOCKED < 1.0
    model = load_or_skip("erd:kinova")
    frame = ("j2s6s200_end_effector", "body")
    configuration = qpik.Configuration(model)
    target_q = np.array([-0.823, 4.512, 3.137, -2.161, 3.055, -0.442])
    configuration.update(target_q)
    jacobian = configuration.frame_jacobian(*frame)
    assert np.linalg.svd(jacobian, compute_uv=False)[-1] < 3e-4  # near-singular at the answer
    target = configuration.frame_pose(*frame)
    session = qpik.IKSession(model)
    rng = np.random.default_rng(5)
    for _ in range(6):
        result = session.solve(
            {frame: target}, q0=configuration.random_q(rng), restarts=0,
            tol_position=1e-5, tol_orientation=1e-5,
        )  # fmt: skip
        assert result.converged, (result.reason, result.position_error, result.iterations)
        assert result.position_error <= 1e-5 and result.orientation_error <= 1e-5


def test_both_engines_take_the_same_steps_from_an_exactly_singular_start():
    """The bundled UR5e from its default start q = 0, where its frame rows have a singular
    value of 3.7e-17 (of 2.1): a structural zero by the cascade's rank rule, not a
    singularity to damp. Both engines take the same steps (the compiled one followed the
    Gram matrix's least eigenvalue and damped fully: its first iterate was 0.234 rad off)."""
    import mujoco

    model = qpik.load_robot("ur5e")
    data = mujoco.MjData(model)
    data.qpos[:] = [0.3, -1.2, 1.4, -0.8, 1.1, 0.4]
    mujoco.mj_kinematics(model, data)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "ee")
    target = {"ee": (data.site_xpos[site].copy(), data.site_xmat[site].reshape(3, 3).copy())}
    assert np.allclose(qpik.Configuration(model).mid_q(), 0.0)
    results = [qpik.solve(model, target, seed=0, engine=e, restarts=0) for e in ("compiled", "qp")]
    first = [np.asarray(r.path)[1] for r in results]
    assert np.abs(first[0] - first[1]).max() <= 1e-9
    assert all(r.converged for r in results)
    assert results[0].iterations == results[1].iterations
    assert np.abs(np.asarray(results[0].q) - np.asarray(results[1].q)).max() <= 1e-9
