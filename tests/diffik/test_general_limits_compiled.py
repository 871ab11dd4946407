"""qpik's collision avoidance (its CollisionAvoidanceLimit, the model's pairs by
model_collision_limit) and its support polygon are general-row limits of the compiled step
(layout.GENERAL_LIMITS): their rows come from their own methods each step, as on the QP
path, and the step is the QP path's to round-off, with the same statuses and the same
limits named active (before, any of them sent every step to the QP path: the humanoid
example's cycle took 1.05 ms, now 0.55)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import FLOATING, has_erd

import qpik
from qpik.limits import CollisionAvoidanceLimit, SupportPolygonLimit, joint_limits
from qpik.scene import add_obstacle
from qpik.tasks import FrameTask, OrientationTask, PositionTask, PostureTask

DT = 0.01
ARM = ["link4", "link5", "link6", "link7", "hand"]


def expected_sigma(reference) -> list:
    """The QP path's smallest singular value per level (its own computation: round-off)."""
    return qpik.StepResult.of(reference, 0.0).sigma_min


def _closed_loop(solver, configuration, steps, kind):
    """Steps of ``solver`` in closed loop, each compared with its QP path at that state:
    the largest velocity difference [rad/s] and the steps where a row of ``kind`` binds."""
    worst = 0.0
    names = 0
    for _ in range(steps):
        result = solver.step(configuration, DT)
        # the step deferred the sigmas it could (its records kept for the result), as the
        # lean step does: the step is not the one that resolves them all
        info, row, _skip, deferred = result.__dict__["_info"]
        assert deferred is not None
        # in one kernel call, into the lean step's output rows (Kernel.rows_into)
        assert row is not None and info is solver._plan._out[2]
        reference = solver.qp_solution(configuration, DT)
        fast = solver.compiled_velocity(configuration, DT)  # (the sigmas deferred: the same)
        assert fast is not None
        np.testing.assert_array_equal(fast[0], result.velocity)
        assert [str(s) for s in fast[1]] == [str(s) for s in result.status]
        # the step's deferred sigmas, resolved when read: the kernel's own, bitwise
        core = solver._core
        whole = solver._plan._gathered_step(configuration, DT, solver._damping, core, False)
        assert whole is not None
        np.testing.assert_array_equal(np.array(result.sigma_min), whole[2][1])
        np.testing.assert_array_equal(whole[1], result.velocity)  # (one call: the same bits)
        np.testing.assert_allclose(
            result.sigma_min, expected_sigma(reference), rtol=1e-8, atol=1e-12
        )
        worst = max(worst, float(np.abs(result.velocity - reference.velocity).max()))
        assert [str(s) for s in result.status] == [str(s) for s in reference.status]
        expected = qpik.StepResult.of(reference, 0.0)
        assert sorted(result.active_limits) == sorted(expected.active_limits)
        names += any(kind in name for name in result.active_limits)
        assert not any(name.startswith("_") for name in result.active_limits)  # (public names)
        configuration.integrate_inplace(result.velocity, DT)
    return worst, names


def _panda_past_a_ball(kind: str = "pairs"):
    """The Panda whose tool's straight path (0.45 m along y) passes a ball of 6 cm: its
    model, start configuration, tool task, posture and collision limit (the arm's last links
    against the ball, or ``kind="model"``: every pair of the model)."""
    base = qpik.load_robot("panda")
    start = qpik.Configuration(base, base.key_qpos[0]).frame_pose("ee")[0]
    goal = start + np.array([0.0, 0.45, 0.0])
    model = add_obstacle(base, "sphere", 0.06, 0.5 * (start + goal), name="ball")
    if kind == "pairs":
        avoid = CollisionAvoidanceLimit(
            model, [(ARM, ["ball"])], minimum_distance_from_collisions=0.01,
            collision_detection_distance=0.1,
        )  # fmt: skip
    else:
        avoid = qpik.limits.model_collision_limit(
            model, minimum_distance_from_collisions=0.01, collision_detection_distance=0.1
        )
    configuration = qpik.Configuration(model, model.key_qpos[0])
    tip = PositionTask("ee", gain=0.1)
    tip.set_target(goal)
    posture = PostureTask(model, cost=0.05)
    posture.set_target(model.key_qpos[0])
    return model, configuration, tip, posture, avoid


@pytest.mark.parametrize("kind", ["pairs", "model"])
def test_collision_rows_of_qpik_take_the_compiled_step(kind):
    model, configuration, tip, posture, avoid = _panda_past_a_ball(kind)
    solver = qpik.IKSolver(model, [[tip], [posture]], [avoid, *joint_limits(model)])
    assert solver._plan is not None and solver._plan.general_limits == [avoid]
    worst, names = _closed_loop(solver, configuration, 120, "Collision")
    assert worst <= 1e-9 and names > 0  # (steps that a collision row bounds)


def test_the_one_call_step_with_collision_rows_answers_as_a_fresh_solver():
    """The one-call step with general rows (Kernel.rows_into, its answers in the output rows
    the lean step shares) gives each state's answer bit for bit whatever ran before: the
    closed loop's steps, the same states in reverse in a second solver (its output rows
    turned over more than once), and each state in a fresh solver; qpik.solve_ik alike."""
    model, configuration, tip, posture, avoid = _panda_past_a_ball()
    stack, limits = [[tip], [posture]], [avoid, *joint_limits(model)]
    loop = qpik.IKSolver(model, stack, limits)
    states, answers, seen = [], [], 0
    for _ in range(150):  # (more steps than OUTPUT_ROWS: the rows are allocated again)
        states.append(configuration.q.copy())
        result = loop.step(configuration, DT)
        answers.append(result.velocity.copy())
        seen += any("Collision" in name for name in result.active_limits)
        configuration.integrate_inplace(result.velocity, DT)
    assert seen > 0  # (states where a collision row binds)
    other = qpik.IKSolver(model, stack, limits)
    for q, v in zip(states[::-1], answers[::-1]):
        configuration.update(q)
        np.testing.assert_array_equal(other.step(configuration, DT).velocity, v)
    for k in range(0, 150, 37):
        configuration.update(states[k])
        fresh = qpik.IKSolver(model, stack, limits).step(configuration, DT)
        np.testing.assert_array_equal(fresh.velocity, answers[k])
        tasks = [tip, posture]
        first = qpik.solve_ik(configuration, tasks, DT, "daqp", limits=limits)
        for j in (k, 149 - k):  # (another state between: the kept solver's rows turn)
            configuration.update(states[j])
            qpik.solve_ik(configuration, tasks, DT, "daqp", limits=limits)
        configuration.update(states[k])
        np.testing.assert_array_equal(
            qpik.solve_ik(configuration, tasks, DT, "daqp", limits=limits), first
        )


@pytest.mark.skipif(not has_erd(), reason="needs example-robot-data (the robots extra)")
def test_the_support_polygon_takes_the_compiled_step():
    model = qpik.load_robot("erd:talos", floating_base=True)
    configuration = qpik.Configuration(model, model.key("half_sitting").qpos)
    feet = [FrameTask(f, "body", position_cost=1.0, orientation_cost=1.0)
            for f in ("left_sole_link", "right_sole_link")]  # fmt: skip
    for task in feet:
        task.set_target_from_configuration(configuration)
    hand = PositionTask("gripper_left_base_link", "body", gain=0.2)
    hand.set_target(configuration.frame_pose("gripper_left_base_link", "body")[0] + [0.4, 0.3, 0.1])
    torso = OrientationTask("torso_2_link", "body", gain=0.5)
    torso.set_target(np.eye(3))
    posture = PostureTask(model, cost=1e-2)
    posture.set_target(model.key("half_sitting").qpos)
    sole = [(0.1, 0.05), (0.1, -0.05), (-0.1, 0.05), (-0.1, -0.05)]
    support = SupportPolygonLimit(model, ["left_sole_link", "right_sole_link"], margin=0.02,
                                  footprint=sole)  # fmt: skip
    solver = qpik.IKSolver(
        model, [feet, [hand], [torso], [posture]], [*joint_limits(model, 0.9), support]
    )
    assert solver._plan is not None and solver._plan.general_limits == [support]
    worst, names = _closed_loop(solver, configuration, 60, "SupportPolygonLimit")
    assert worst <= 1e-9 and names > 0
    assert support.com_margin(configuration) >= 0.02 - 1e-3


#: two limited ball joints (mink's googly_eyes example): mink's ConfigurationLimit bounds
#: each one's rotation angle by a row a^T dq <= gain (max_angle - angle)
EYES = """
<mujoco>
  <worldbody>
    <body name="face" pos="0 0 1.1">
      <geom type="box" size="0.05 0.4 0.4"/>
      <body name="left_eye" pos="0.05 0.18 0.08">
        <joint name="left_eye" type="ball" range="0 0.7"/>
        <geom type="sphere" size="0.12"/>
        <site name="left_eye"/>
      </body>
      <body name="right_eye" pos="0.05 -0.18 0.08">
        <joint name="right_eye" type="ball" range="0 0.7"/>
        <geom type="sphere" size="0.12"/>
        <site name="right_eye"/>
      </body>
      <body name="jaw" pos="0.05 0 -0.3">
        <joint name="jaw" type="hinge" axis="0 1 0" range="-0.2 0.4"/>
        <geom type="box" size="0.02 0.1 0.02"/>
        <site name="jaw"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_ball_joint_rows_of_a_position_limit_take_the_compiled_step():
    """A mink ConfigurationLimit on a model with limited ball joints: its cones' rows are
    general rows of the compiled step (mink's own rows, with its hinge's bounds as the
    kernel's box), the step is the QP path's to round-off, with the same limits named
    active (before, every step took the QP path: mink's googly_eyes example ran at 2.3x
    mink's time per call, now about 1x). mink.solve_ik's answers are qpik.solve_ik's."""
    import mink
    import mujoco

    model = mujoco.MjModel.from_xml_string(EYES)
    configuration = qpik.Configuration(model)
    eyes = ["left_eye", "right_eye"]
    aim = [FrameTask(e, "site", position_cost=0.0, orientation_cost=1.0) for e in eyes]
    jaw = PositionTask("jaw", "site", gain=0.5)
    jaw.set_target(configuration.frame_pose("jaw", "site")[0] + [0.1, 0.0, 0.0])
    limits = [
        mink.ConfigurationLimit(model),
        mink.VelocityLimit(model, dict.fromkeys(eyes, np.full(3, 4.0))),
    ]
    solver = qpik.IKSolver(model, [aim + [jaw]], limits)
    plan = solver._plan
    assert plan is not None and [type(g).__name__ for g in plan.general_limits] == ["BallJointRows"]
    binds = 0
    rng = np.random.default_rng(2)
    for turn in range(80):
        if turn % 20 == 0:  # far targets: the cones bind
            for task in aim:
                task.set_target(mink.SE3.exp(np.r_[0, 0, 0, rng.normal(size=3) * 1.5]))
        result = solver.step(configuration, DT)
        reference = solver.qp_solution(configuration, DT)
        np.testing.assert_allclose(result.velocity, reference.velocity, rtol=0, atol=1e-9)
        assert [str(s) for s in result.status] == [str(s) for s in reference.status]
        names = qpik.StepResult.of(reference, 0.0).active_limits
        assert sorted(result.active_limits) == sorted(names)
        binds += any(name.startswith("ConfigurationLimit row") for name in names)
        tasks = [*aim, jaw]
        mink_answer = mink.solve_ik(configuration, tasks, DT, "daqp", 1e-6, limits=limits)
        np.testing.assert_allclose(
            qpik.solve_ik(configuration, tasks, DT, "daqp", 1e-6, limits=limits),
            mink_answer, rtol=0, atol=1e-7,
        )  # fmt: skip
        # the cones' rows: mink's, bitwise
        ours = plan.general_limits[0].compute_qp_inequalities(configuration, DT)
        theirs = limits[0].compute_qp_inequalities(configuration, DT)
        boxed = 2 * len(limits[0].indices)
        assert np.array_equal(ours.G[boxed:], theirs.G[boxed:])
        assert np.array_equal(ours.h[boxed:], theirs.h[boxed:])
        assert not ours.G[:boxed].any() and np.isinf(ours.h[:boxed]).all()
        compact = plan.general_limits[0].compact_rows(configuration, DT)
        if compact is not None:  # (the rows in play, as general_rows takes them)
            G, h, row_names = compact
            kept = [boxed + i for i in range(len(theirs.h) - boxed) if theirs.G[boxed + i].any()]
            assert np.array_equal(G, theirs.G[kept]) and np.array_equal(h, theirs.h[kept])
            assert row_names == [f"ConfigurationLimit row {r}" for r in kept]
        configuration.integrate_inplace(result.velocity, DT)
    assert binds > 0


def test_a_free_joint_velocity_limit_takes_the_compiled_step():
    """mink's FreeJointVelocityLimit (mink 1.3): its angular bounds are velocity entries of
    the kernel's box, its linear rows (R^T, the base's rotation) general rows (views:
    qpik.diffik.mink_limits); the step is the QP path's to round-off with the same limits
    named, and mink's answer to mink's problem. Where a linear row bounds one dof (an
    upright base: R^T's rows are unit vectors) it stays a general row of the compiled step
    (the QP path folds it into the box: the same bound, the same optimum to round-off).
    Before, the limit sent every step to the QP path (a floating Talos stack: 3.6x mink's
    time a call), and an upright base every step still (3.5x)."""
    import mink
    import mujoco

    model = mujoco.MjModel.from_xml_string(FLOATING)
    configuration = qpik.Configuration(model)
    tip = PositionTask("ee", "site", gain=0.5)
    tip.set_target(configuration.frame_pose("ee", "site")[0])
    base = PostureTask(model, cost=1e-2)
    base.set_target(configuration.q)
    free = mink.FreeJointVelocityLimit(model, max_linear_velocity=0.3, max_angular_velocity=0.5)
    limits = [mink.ConfigurationLimit(model), free]
    solver = qpik.IKSolver(model, [[tip], [base]], limits)
    plan = solver._plan
    assert plan is not None and [type(g).__name__ for g in plan.general_limits] == [
        "FreeJointLinear"
    ]
    upright = solver.compiled_velocity(configuration, DT)  # (one-dof rows: general rows)
    assert upright is not None
    np.testing.assert_allclose(
        upright[0], solver.qp_solution(configuration, DT).velocity, rtol=0, atol=1e-12
    )
    rng = np.random.default_rng(4)
    compiled = names = 0
    for turn in range(60):
        if turn % 15 == 0:
            tip.set_target(configuration.frame_pose("ee", "site")[0] + rng.normal(size=3))
        if turn == 30:  # a new angular bound, read at the next step
            free.angular_max = np.array([0.2, 0.3, 0.1])
        result = solver.step(configuration, DT)
        reference = solver.qp_solution(configuration, DT)
        np.testing.assert_allclose(result.velocity, reference.velocity, rtol=0, atol=1e-9)
        expected = qpik.StepResult.of(reference, 0.0).active_limits
        assert sorted(result.active_limits) == sorted(expected)
        names += any("FreeJointVelocityLimit" in name for name in expected)
        fast = solver.compiled_velocity(configuration, DT)  # (its sigmas deferred)
        if fast is not None:
            compiled += 1
            np.testing.assert_array_equal(fast[0], result.velocity)
            assert [str(s) for s in fast[1]] == [str(s) for s in result.status]
        view = plan.general_limits[0].compute_qp_inequalities(configuration, DT)
        theirs_rows = free.compute_qp_inequalities(configuration, DT)
        linear = [0, 1, 2, 6, 7, 8]  # (mink's rows: linear, angular, then their negations)
        assert np.array_equal(view.G, theirs_rows.G[linear])
        assert np.array_equal(view.h, theirs_rows.h[linear])
        fresh = qpik.IKSolver(model, [[tip], [base]], limits).step(configuration, DT)
        np.testing.assert_array_equal(fresh.velocity, result.velocity)
        ours = qpik.solve_ik(configuration, [tip, base], DT, "daqp", 1e-6, limits=limits)
        theirs = mink.solve_ik(configuration, [tip, base], DT, "daqp", 1e-6, limits=limits)
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-7)
        configuration.integrate_inplace(result.velocity, DT)
    assert compiled >= 58 and names > 0


def test_an_upright_base_free_joint_limit_binds_on_the_compiled_step():
    """An upright, then yawed, floating base whose vertical speed the FreeJointVelocityLimit
    bounds (its vertical row on one dof, a general row of the compiled step): where the task
    asks for more, the row binds, and the step is the QP path's (which folds the row into
    the box) to round-off, named as there, and mink's answer."""
    import mink
    import mujoco

    model = mujoco.MjModel.from_xml_string(FLOATING)
    configuration = qpik.Configuration(model)
    tip = PositionTask("ee", "site", gain=1.0)
    base = PostureTask(model, cost=1e-2)
    base.set_target(configuration.q)
    free = mink.FreeJointVelocityLimit(model, max_linear_velocity=0.05, max_angular_velocity=0.5)
    limits = [mink.ConfigurationLimit(model), free]
    solver = qpik.IKSolver(model, [[tip], [base]], limits)
    for yaw in (0.0, 0.3):
        q = configuration.q.copy()
        q[3:7] = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]  # (about z: R^T's third row e_z)
        configuration.update(q)
        assert configuration.data.xmat[free.base_body_id][[2, 5]].tolist() == [0.0, 0.0]
        tip.set_target(configuration.frame_pose("ee", "site")[0] + [0.0, 0.0, 0.5])  # up
        fast = solver.compiled_velocity(configuration, DT)
        assert fast is not None
        result = solver.step(configuration, DT)
        reference = solver.qp_solution(configuration, DT)
        np.testing.assert_allclose(result.velocity, reference.velocity, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(fast[0], result.velocity)
        assert abs(result.velocity[2]) == pytest.approx(0.05, rel=1e-12)  # the row binds
        expected = qpik.StepResult.of(reference, 0.0).active_limits
        assert any("FreeJointVelocityLimit" in name for name in result.active_limits)
        assert any("FreeJointVelocityLimit" in name for name in expected)
        ours = qpik.solve_ik(configuration, [tip, base], DT, "daqp", 1e-6, limits=limits)
        theirs = mink.solve_ik(configuration, [tip, base], DT, "daqp", 1e-6, limits=limits)
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-7)


_TWO_LINKS = """<mujoco><compiler angle="radian"/><worldbody>
<body name="l1"><joint name="j1" axis="0 0 1" range="-3 3"/>
  <geom name="g1" type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
  <body name="l2" pos="0.3 0 0"><joint name="j2" axis="0 0 1" range="-3 3"/>
    <geom name="g2" type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
    <site name="ee" pos="0.3 0 0"/></body></body>
<body name="ball" mocap="true" pos="0.15 0.12 0"><geom name="gb" type="sphere" size="0.04"/>
</body></worldbody></mujoco>"""


@pytest.mark.parametrize("kind", ["qpik", "mink", "model"])
def test_a_collision_row_on_one_dof_takes_the_compiled_step(kind):
    """A collision pair whose link one joint moves (the first link of a planar arm and a
    mocap ball): its row bounds one dof, which the QP path folds into the box. The compiled
    step keeps it a general row (before, every such step went to the QP path): where the
    tip's target swings the link into the ball, the row binds, and each step is the QP
    path's to round-off, with the same statuses and the same limits named active (the row
    as the box bound the QP path makes of it: ``"j1 upper (CollisionAvoidanceLimit)"``)."""
    import mink
    import mujoco

    model = mujoco.MjModel.from_xml_string(_TWO_LINKS)
    kwargs = dict(minimum_distance_from_collisions=0.01, collision_detection_distance=0.2)
    if kind == "model":  # (every pair: the second link's rows on two dofs beside)
        avoid = qpik.limits.model_collision_limit(model, **kwargs)
    else:
        cls = CollisionAvoidanceLimit if kind == "qpik" else mink.CollisionAvoidanceLimit
        avoid = cls(model, [(["g1"], ["gb"])], **kwargs)
    configuration = qpik.Configuration(model, np.array([0.0, 0.5]))
    tip = PositionTask("ee", "site", gain=0.5)
    tip.set_target(np.array([0.0, 0.6, 0.0]))  # (j1 turns toward the ball)
    posture = PostureTask(model, cost=0.05)
    posture.set_target(configuration.q)
    solver = qpik.IKSolver(model, [[tip], [posture]], [avoid, *joint_limits(model)])
    worst, names = _closed_loop(solver, configuration, 40, "j1 upper (CollisionAvoidanceLimit)")
    assert worst <= 1e-12 and names >= 20
    # A fresh solver at the last state (its names and rows made anew): bitwise the same step
    used = solver.step(configuration, DT)
    fresh = qpik.IKSolver(model, [[tip], [posture]], [avoid, *joint_limits(model)])
    again = fresh.step(configuration, DT)
    np.testing.assert_array_equal(again.velocity, used.velocity)
    assert again.active_limits == used.active_limits
    rows = avoid.compute_qp_inequalities(configuration, DT)
    counts = np.count_nonzero(rows.G[np.isfinite(rows.h)], axis=1)
    assert 1 in counts.tolist()  # (a row in play on one dof)


def test_correction_passes_with_collision_rows_take_the_compiled_step(monkeypatch):
    """With ``correction_passes=1`` and a collision limit (general rows) the corrected step
    is the kernel's (``Kernel.correct_run``; before, every step went to the QP path's
    corrected step, several times slower): along the Panda's path past a ball, each step
    is the QP path's corrected step to round-off, with the same statuses and limits named
    active, collision rows among them, and no step falls to the QP path."""
    model, configuration, tip, posture, avoid = _panda_past_a_ball()
    solver = qpik.IKSolver(
        model, [[tip], [posture]], [avoid, *joint_limits(model)], correction_passes=1
    )
    in_step = {"on": False, "qp": 0}
    qp_corrected = qpik.IKSolver._corrected

    def counted(self, *args):
        in_step["qp"] += in_step["on"]
        return qp_corrected(self, *args)

    monkeypatch.setattr(qpik.IKSolver, "_corrected", counted)
    plain = qpik.IKSolver(model, [[tip], [posture]], [avoid, *joint_limits(model)])
    named = corrected = 0
    for _ in range(120):
        in_step["on"] = True
        result = solver.step(configuration, DT)
        in_step["on"] = False
        reference = solver.qp_solution(configuration, DT)
        np.testing.assert_allclose(result.velocity, reference.velocity, rtol=0, atol=1e-9)
        assert [str(s) for s in result.status] == [str(s) for s in reference.status]
        expected = qpik.StepResult.of(reference, 0.0)
        assert sorted(result.active_limits) == sorted(expected.active_limits)
        np.testing.assert_allclose(result.sigma_min, expected.sigma_min, rtol=1e-8, atol=1e-12)
        named += any("Collision" in name for name in result.active_limits)
        corrected += bool(
            np.abs(result.velocity - plain.step(configuration, DT).velocity).max() > 1e-9
        )
        configuration.integrate_inplace(result.velocity, DT)
    assert in_step["qp"] == 0 and named > 0 and corrected > 20  # (the passes changed the steps)
    # a fresh solver at the last state, after other solves in this process: bitwise the same
    used = solver.step(configuration, DT)
    fresh = qpik.IKSolver(
        model, [[tip], [posture]], [avoid, *joint_limits(model)], correction_passes=1
    ).step(configuration, DT)
    np.testing.assert_array_equal(fresh.velocity, used.velocity)
    assert fresh.active_limits == used.active_limits
