"""The full-IK front door audit's findings (a new user's calls of qpik.solve): each once
gave an answer the docs do not describe."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import qpik
from qpik.tasks import OrientationTask, PoseTask, PositionTask

_SLIDE_ARM = """<mujoco><compiler angle="radian" autolimits="true"/><worldbody>
<body name="carriage"><joint name="s" type="slide" axis="1 0 0" range="0 0.2"/>
 <geom type="box" size=".05 .05 .05"/>
 <body name="arm"><joint name="h" type="hinge" axis="0 0 1" range="-3 3"/>
  <geom type="capsule" fromto="0 0 0 0.5 0 0" size=".02"/><site name="ee" pos="0.5 0 0"/></body>
</body></worldbody></mujoco>"""


def _site(model, q, name="ee"):
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    return data.site_xpos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)].copy()


@pytest.mark.parametrize("engine", ["auto", "qp"])
def test_limits_none_reaches_past_a_slide_s_range(engine):
    """limits=None: a target 1.5 m out needs the slide at 1.0, outside its range [0, 0.2];
    the joint-limited reach bound (the slide's half travel) answered it 'unreachable' at
    once. It converges now (checked by MuJoCo's kinematics); with the joint limits it is
    still unreachable."""
    model = mujoco.MjModel.from_xml_string(_SLIDE_ARM)
    target = np.array([1.5, 0.0, 0.0])
    free = qpik.solve(model, {"ee": target}, seed=0, limits=None, engine=engine)
    assert free.converged and np.linalg.norm(_site(model, free.q) - target) < 1e-6
    limited = qpik.solve(model, {"ee": target}, seed=0, engine=engine)
    assert not limited.converged and limited.reason is qpik.Reason.UNREACHABLE


def test_a_custom_stack_s_task_takes_only_its_own_frame_type():
    """A target on body 'hand' went to a stack task on geom 'hand' (matched by name only):
    the solve stalled after 1,107 iterations. It is refused now; one task per frame type
    takes each of two targets of the same name, and the pair converges."""
    model = qpik.load_robot("panda")
    target = np.array([0.4, 0.2, 0.5])
    with pytest.raises(qpik.InvalidTarget, match="regulates the body 'hand'"):
        qpik.solve(model, {("hand", "body"): target}, stack=[[PositionTask("hand", "geom")]])
    first = qpik.solve(model, {("hand", "body"): target}, seed=0)
    data = mujoco.MjData(model)
    data.qpos[:] = first.q
    mujoco.mj_kinematics(model, data)
    geom = data.geom_xpos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "hand")].copy()
    stack = [[PositionTask("hand", "body"), PositionTask("hand", "geom")]]
    both = qpik.solve(
        model, {("hand", "body"): target, ("hand", "geom"): geom}, stack=stack, seed=0
    )
    assert both.converged and both.iterations < 20


@pytest.mark.parametrize(
    "task, target, match",
    [
        (PositionTask, "pose", "a rotation no task steers"),
        (OrientationTask, "pose", "a position no task steers"),
        (OrientationTask, "position", "a position no task steers"),
        (PoseTask, "position", "position-only target"),
    ],
)
def test_a_target_part_no_task_steers_is_refused(task, target, match):
    """A (p, R) target on a frame only a PositionTask regulates ran 2,120 iterations and
    88 restarts to 'stalled' (the rotation measured, never steered); an OrientationTask
    alone, 813 iterations to 'at_limit'. Refused at once now, as problem files refuse it."""
    model = qpik.load_robot("panda")
    p, R = np.array([0.4, 0.2, 0.5]), np.diag([1.0, -1.0, -1.0])
    goal = (p, R) if target == "pose" else p
    with pytest.raises(qpik.InvalidTarget, match=match):
        qpik.solve(model, {"ee": goal}, stack=[[task("ee")]], seed=0)


@pytest.mark.parametrize("bad", [[np.nan, 0.0, 0.0], [1.0, 2.0], None])
def test_a_bad_target_among_several_names_its_frame(bad):
    """With several frames, a malformed target's InvalidTarget did not say whose it was."""
    model = qpik.load_robot("panda")
    targets = {"ee": [0.4, 0.2, 0.5], ("hand", "body"): bad, ("link4", "body"): [0.1, 0, 0.5]}
    with pytest.raises(qpik.InvalidTarget, match=r"target of \('hand', 'body'\)"):
        qpik.solve(model, targets, seed=0)


def test_damping_law_takes_no_bool_for_a_number():
    """DampingLaw(max_damping=True) was taken as 1.0 (lower_trust refused True): a flag
    where a number was meant is refused on every field; NumPy's reals are taken."""
    for name in ("singular_threshold", "max_damping", "error_scale", "lower_trust"):
        for flag in (True, np.bool_(True)):
            with pytest.raises(qpik.InvalidInput, match=name):
                qpik.DampingLaw(**{name: flag})
    assert qpik.DampingLaw(singular_threshold=np.float32(0.05)).singular_threshold == 0.05


def test_a_converged_attempt_of_a_multi_level_stack_ends_the_restarts():
    """A two-level stack with max_iters=1: the first attempt converged in its level-0
    finish, yet every restart ran (restarts=20: 428 iterations, 20 restarts used, the
    first attempt returned). The solve now ends at the first converged attempt, and
    max_iters bounds an attempt at max_iters + 20 (the documented level-0 finish)."""
    import mink

    model = qpik.load_robot("panda")
    home = model.key_qpos[0]
    target = (np.array([0.45, 0.25, 0.40]), np.diag([1.0, -1.0, -1.0]))
    answers = []
    for restarts in (0, 5, 20):
        posture = mink.PostureTask(model, cost=0.1)
        posture.set_target(home)
        stack = [[PositionTask("ee"), OrientationTask("ee")], [posture]]
        result = qpik.solve(
            model, {"ee": target}, q0=home, stack=stack, seed=0, max_iters=1, restarts=restarts
        )
        assert result.converged and result.restarts_used == 0 and result.iterations <= 21
        answers.append(result.q)
    assert all(np.array_equal(q, answers[0]) for q in answers)


def test_a_mink_configuration_is_a_robot_and_its_start():
    """Audit (full IK): qpik.solve(mink.Configuration) was refused with 'robot must be ... a
    qpik.Configuration, got Configuration'. It is read in place as qpik's: its model and a
    copy of its q as the start, the same bits as a qpik.Configuration of that q."""
    import mink

    model = qpik.load_robot("panda")
    configuration = mink.Configuration(model)
    configuration.update(model.key_qpos[0])
    target = {"ee": [0.4, 0.2, 0.5]}
    result = qpik.solve(configuration, target, seed=0)
    same = qpik.solve(qpik.Configuration(model, model.key_qpos[0]), target, seed=0)
    assert result.converged and np.array_equal(result.q, same.q)
    assert np.array_equal(configuration.q, model.key_qpos[0])  # (the caller's, untouched)
    assert qpik.IKSession(configuration).solve(target, seed=0).converged


def test_singular_tol_none_is_numpy_s_default():
    """Audit (analysis): analyze(singular_tol=None) took the smallest float as the
    threshold (its default computed from no singular values); None is numpy's default,
    relative to the largest singular value, as rank's tol."""
    from qpik import analysis

    J = np.array([[1.0, 0.0], [0.0, 1e-17]])
    report = analysis.singularity(J, None)
    assert report.singular and report.tol == pytest.approx(2 * np.finfo(float).eps)
