"""The one-call step (qpik.diffik.compiled) on what users bring: floating bases (free joint), ball
joints, CoM tasks, mink's RelativeFrameTask, collision rows in the same call. Rows equal
mink's objective to 1e-12; steps equal the general path's."""

from __future__ import annotations

import mink
import mujoco
import numpy as np
import pytest

import qpik
from qpik import _engine

DT = 0.01


def _qp_step(solver: qpik.IKSolver, configuration) -> qpik.StepResult:
    """The step by the QP path (the tasks' and limits' own rows, then the core's cascade)."""
    return qpik.StepResult.of(solver._qp_step(configuration, DT), 0.0)


# A floating torso with two hinge legs, a ball "neck", a slide joint and a hinge arm.
XML = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <body name="torso" pos="0 0 1">
      <freejoint name="root"/>
      <geom name="torso_geom" type="box" size="0.2 0.15 0.3" mass="10"/>
      <body name="left_leg" pos="0 0.1 -0.3">
        <joint name="left_hip" type="hinge" axis="0 1 0" range="-1.5 1.5" limited="true"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.4" size="0.05" mass="2"/>
        <body name="left_shin" pos="0 0 -0.4">
          <joint name="left_knee" type="hinge" axis="0 1 0" range="-2 0.1" limited="true"/>
          <geom name="left_shin_geom" type="capsule" fromto="0 0 0 0 0 -0.4" size="0.04" mass="1.5"/>
          <site name="left_foot" pos="0 0 -0.4"/>
        </body>
      </body>
      <body name="right_leg" pos="0 -0.1 -0.3">
        <joint name="right_hip" type="hinge" axis="0 1 0" range="-1.5 1.5" limited="true"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.4" size="0.05" mass="2"/>
        <body name="right_shin" pos="0 0 -0.4">
          <joint name="right_knee" type="hinge" axis="0 1 0" range="-2 0.1" limited="true"/>
          <geom name="right_shin_geom" type="capsule" fromto="0 0 0 0 0 -0.4" size="0.04" mass="1.5"/>
          <site name="right_foot" pos="0 0 -0.4"/>
        </body>
      </body>
      <body name="head" pos="0 0 0.35">
        <joint name="neck" type="ball"/>
        <geom type="sphere" size="0.1" mass="1"/>
        <site name="eye" pos="0.1 0 0.05"/>
      </body>
      <body name="arm" pos="0 0.2 0.2">
        <joint name="shoulder_slide" type="slide" axis="1 0 0" range="-0.1 0.1" limited="true"/>
        <joint name="shoulder" type="hinge" axis="0 1 0" range="-2 2" limited="true"/>
        <geom name="arm_geom" type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
        <site name="hand" pos="0.3 0 0"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


#: The same robot with a hinge neck: hinge/slide joints and the free joint only, where
#: the compiled rows equal the general path's bitwise (a ball joint's error, by MuJoCo's
#: mj_differentiatePos, equals the port to round-off only).
XML_NO_BALL = XML.replace('<joint name="neck" type="ball"/>',
                          '<joint name="neck" type="hinge" axis="0 0 1"/>')  # fmt: skip


@pytest.fixture(scope="module")
def robot():
    model = mujoco.MjModel.from_xml_string(XML)
    return model, qpik.Configuration(model)


@pytest.fixture(scope="module")
def robot_no_ball():
    model = mujoco.MjModel.from_xml_string(XML_NO_BALL)
    return model, qpik.Configuration(model)


def _velocity_limit(model):
    neck = [1.0, 2.0, 1.5] if model.joint("neck").type == mujoco.mjtJoint.mjJNT_BALL else 1.0
    speeds = {"left_hip": 2.0, "left_knee": 3.0, "right_hip": 2.0, "neck": neck,
              "shoulder_slide": 0.5, "shoulder": 4.0}  # fmt: skip
    return mink.VelocityLimit(model, speeds)


def _random_q(rng, model, spread=0.5):
    q = model.qpos0.copy()
    q[0:3] = [0.1, -0.2, 1.1] + rng.uniform(-0.2, 0.2, 3)
    q[3:7] = mink.SO3.exp(rng.normal(size=3) * spread).wxyz
    for j in range(model.njnt):
        kind, a = model.jnt_type[j], model.jnt_qposadr[j]
        if kind == mujoco.mjtJoint.mjJNT_BALL:
            q[a : a + 4] = mink.SO3.exp(rng.normal(size=3) * spread * 2).wxyz
        elif kind != mujoco.mjtJoint.mjJNT_FREE:
            lo, hi = model.jnt_range[j]
            q[a] = rng.uniform(lo, hi)
    return q


def _tasks(model):
    com = qpik.tasks.ComTask(cost=[1.0, 2.0, 0.5], lm_damping=0.2, body="torso")
    relative = mink.RelativeFrameTask(
        "hand", "site", "left_foot", "site", position_cost=[1.0, 0.5, 2.0], orientation_cost=0.3,
        gain=0.8, lm_damping=0.1,
    )  # fmt: skip
    return [
        mink.FrameTask("left_foot", "site", position_cost=1.0, orientation_cost=1.0),
        qpik.tasks.FrameTask("eye", "site", position_cost=0.5, orientation_cost=0.2, gain=0.6),
        mink.ComTask(cost=1.5, gain=0.7),
        com,
        relative,
        mink.PostureTask(model, cost=np.linspace(0.05, 0.2, model.nv), gain=0.9, lm_damping=0.3),
        qpik.tasks.PostureTask(model, cost=0.1),
        mink.DampingTask(model, cost=np.linspace(0.2, 0.5, model.nv)),
        qpik.tasks.DampingTask(model, cost=0.1),
    ]


def _set_targets(rng, model, configuration, tasks):
    for task in tasks:
        if isinstance(task, mink.FrameTask):
            pose = configuration.get_transform_frame_to_world(task.frame_name, task.frame_type)
            task.set_target(pose @ mink.SE3.exp(rng.normal(size=6) * 0.2))
        elif isinstance(task, mink.RelativeFrameTask):
            pose = configuration.get_transform(
                task.frame_name, task.frame_type, task.root_name, task.root_type
            )
            task.set_target(pose @ mink.SE3.exp(rng.normal(size=6) * 0.2))
        elif isinstance(task, (mink.ComTask, qpik.tasks.ComTask)):
            task.set_target(configuration.data.subtree_com[1] + rng.uniform(-0.1, 0.1, 3))
        elif isinstance(task, mink.PostureTask) and not isinstance(task, mink.DampingTask):
            task.set_target(_random_q(rng, model))


def test_rows_equal_minks_objective(robot):
    """Each task as its own level: the kernel's ``A^T A + mu I``, ``-A^T b`` equal each
    task's own compute_qp_objective (mink's arithmetic) to 1e-12."""
    model, configuration = robot
    rng = np.random.default_rng(2)
    tasks = _tasks(model)
    damping = 1e-3
    limits = [mink.ConfigurationLimit(model), _velocity_limit(model)]
    solver = qpik.IKSolver(model, [[t] for t in tasks], limits, damping=damping)
    plan = solver._plan
    assert plan is not None
    for _ in range(40):
        configuration.update(_random_q(rng, model))
        _set_targets(rng, model, configuration, tasks)
        args = plan.gather(configuration)
        plan.write_settings(DT, solver.damping, solver._core)
        code, reg, _, _ = plan.kernel.rows(*args, plan.no_rows, plan.no_h)
        assert code == 0
        a = plan.arrays
        starts = a["starts"]
        for k, task in enumerate(tasks):
            A = a["A"][starts[k] : starts[k + 1]]
            b = a["b"][starts[k] : starts[k + 1]]
            mu = reg[k] - damping
            H = A.T @ A + mu * np.eye(model.nv)
            c = -A.T @ b
            objective = task.compute_qp_objective(configuration)
            scale = max(1.0, np.abs(objective.H).max())
            np.testing.assert_allclose(H, objective.H, rtol=0, atol=1e-12 * scale)
            np.testing.assert_allclose(c, objective.c, rtol=0, atol=1e-12 * scale)
            # and the rows themselves equal the task's own Jacobian and error
            J, e = task.compute_jacobian(configuration), task.compute_error(configuration)
            np.testing.assert_allclose(A, task.cost[:, None] * J, rtol=0, atol=1e-12)
            np.testing.assert_allclose(b, -task.gain * task.cost * e, rtol=0, atol=1e-12)
            np.testing.assert_array_equal(a["w"][starts[k] : starts[k + 1]], task.cost)


def test_ball_joint_error_equals_mujoco(robot):
    """The posture error of a ball joint equals mj_differentiatePos, near and far (angles
    past pi, unnormalised quaternions)."""
    model, configuration = robot
    rng = np.random.default_rng(4)
    task = mink.PostureTask(model, cost=1.0)
    solver = qpik.IKSolver(model, [task])
    plan = solver._plan
    for k in range(300):
        q = _random_q(rng, model, spread=(1e-9, 1e-4, 0.5, 2.0, 4.0)[k % 5])
        adr = model.jnt_qposadr[model.joint("neck").id]
        q[adr : adr + 4] *= rng.uniform(0.5, 2.0)
        configuration.update(q)
        target = _random_q(rng, model)
        target[adr : adr + 4] = -target[adr : adr + 4] if k % 2 else target[adr : adr + 4]
        task.set_target(target)
        args = plan.gather(configuration)
        plan.write_settings(DT, solver.damping, solver._core)
        assert plan.kernel.rows(*args, plan.no_rows, plan.no_h)[0] == 0
        np.testing.assert_allclose(plan.arrays["b"], -task.compute_error(configuration), 0, 1e-12)


@pytest.mark.parametrize("frame_class", [qpik.tasks.FrameTask, mink.FrameTask])
@pytest.mark.parametrize("ball", [False, True])
def test_floating_step_equals_the_general_path(robot, robot_no_ball, frame_class, ball):
    """Feet / CoM / hand relative to the torso / posture with position and velocity
    limits: the compiled step equals the general path (to round-off; bitwise without the
    relative task with qpik's frame task and no ball joint), limits binding or not, and
    names the same active limits.

    The relative task's rows differ from mink's by round-off only (mink multiplies its 6x6
    adjoint and jlog into the Jacobians with numpy's matmul, the kernel with loops in a
    fixed order). Issue 21: at one state (no ball, qpik's frame task) the posture level
    sat on a vertex of bound rows pinned by the levels above, and that round-off decided
    whether it was certified: the general path kept level 2's answer (kept_previous), the
    compiled one solved it, 2e-10 apart. Pinned rows are now eliminated before the level
    (drop_pinned) and both paths solve it, equal to ~1e-16."""
    model, configuration = robot if ball else robot_no_ball
    rng = np.random.default_rng(9)
    feet = [frame_class(f, "site", position_cost=1.0, orientation_cost=1.0) for f in
            ("left_foot", "right_foot")]  # fmt: skip
    com = qpik.tasks.ComTask(cost=1.0)
    relative = mink.RelativeFrameTask("hand", "site", "torso", "body", 1.0, 0.1)
    posture = qpik.tasks.PostureTask(model, cost=0.1)
    limits = [mink.ConfigurationLimit(model), _velocity_limit(model)]
    exact = frame_class is qpik.tasks.FrameTask and not ball
    solvers = [
        (qpik.IKSolver(model, [feet, [com], [relative], [posture]], limits), False),
        (qpik.IKSolver(model, [feet, [com], [posture]], limits), exact),
    ]
    bound = 0
    for solver, bitwise in solvers:
        assert solver._plan is not None
        for _ in range(40):
            configuration.update(_random_q(rng, model))
            _set_targets(rng, model, configuration, feet + [com, relative, posture])
            fused = solver.step(configuration, DT)
            general = _qp_step(solver, configuration)
            if bitwise:
                assert np.array_equal(fused.displacement, general.displacement)
                assert fused.residuals == general.residuals
            else:
                np.testing.assert_allclose(fused.displacement, general.displacement, atol=1e-11)
            assert fused.status == general.status
            assert fused.active_limits == general.active_limits
            bound += bool(fused.active_limits)
    assert bound > 0


def test_collision_rows_in_the_one_call_step(robot_no_ball):
    """A CollisionAvoidanceLimit: its rows go into the compiled call (no second solve);
    the step equals the general path bitwise."""
    model, configuration = robot_no_ball
    rng = np.random.default_rng(13)
    feet = [qpik.tasks.FrameTask(f, "site", 1.0, 1.0) for f in ("left_foot", "right_foot")]
    posture = qpik.tasks.PostureTask(model, cost=0.1)
    collision = mink.CollisionAvoidanceLimit(
        model, [(["left_shin_geom", "right_shin_geom"], ["floor"])], minimum_distance_from_collisions=0.05,
        collision_detection_distance=0.5,
    )  # fmt: skip
    limits = [mink.ConfigurationLimit(model), collision]
    solver = qpik.IKSolver(model, [feet, [posture]], limits)
    assert solver._plan is not None and solver._plan.general_limits == [collision]
    solver._plan._rows_then_cascade = None  # the auto solver never takes the two-call route
    rows_seen = 0
    for _ in range(40):
        configuration.update(_random_q(rng, model))
        _set_targets(rng, model, configuration, feet + [posture])
        general = _qp_step(solver, configuration)
        fused = solver.step(configuration, DT)
        assert np.array_equal(fused.displacement, general.displacement)
        assert fused.status == general.status
        assert fused.active_limits == general.active_limits
        rows = solver._plan.limits.general_rows(solver._plan.general_limits, configuration, DT)
        rows_seen += rows is not None and rows[0].shape[0] > 0
    assert rows_seen > 0


def test_subclasses_supply_their_rows_and_unknown_frames_take_the_general_path(robot):
    model, _ = robot

    class MyCom(mink.ComTask):
        pass

    class MyRelative(mink.RelativeFrameTask):
        pass

    assert qpik.IKSolver(model, [mink.ComTask(1.0)])._plan is not None
    # a subclass may change the rows: it supplies them itself (its own methods, each step)
    plan = qpik.IKSolver(model, [MyCom(1.0)])._plan
    assert plan is not None and not plan.coms and len(plan.rows_tasks) == 1
    relative = MyRelative("hand", "site", "torso", "body", 1.0, 1.0)
    plan = qpik.IKSolver(model, [relative])._plan
    assert plan is not None and not plan.relatives and len(plan.rows_tasks) == 1
    assert qpik.IKSolver(model, [qpik.tasks.ComTask(body="nowhere")])._plan is None
    ball_limited = mujoco.MjModel.from_xml_string(
        XML.replace('<joint name="neck" type="ball"/>',
                    '<joint name="neck" type="ball" range="0 1" limited="true"/>')
    )  # fmt: skip
    limits = [mink.ConfigurationLimit(ball_limited)]
    # (its cone's row: a general row of the compiled step, no longer the QP path)
    plan = qpik.IKSolver(ball_limited, [mink.ComTask(1.0)], limits)._plan
    assert plan is not None and len(plan.general_limits) == 1


def test_unset_targets_raise_as_the_general_path(robot):
    model, configuration = robot
    configuration.update(_random_q(np.random.default_rng(0), model))
    for task in (mink.ComTask(1.0), qpik.tasks.ComTask(),
                 mink.RelativeFrameTask("hand", "site", "torso", "body", 1.0, 1.0)):  # fmt: skip
        solver = qpik.IKSolver(model, [task])
        assert solver._plan is not None
        with pytest.raises(mink.TargetNotSet):
            solver.step(configuration, DT)


def test_kernel_rejects_bad_arguments(robot):
    model, configuration = robot
    configuration.update(_random_q(np.random.default_rng(1), model))
    tasks = _tasks(model)
    _set_targets(np.random.default_rng(1), model, configuration, tasks)
    solver = qpik.IKSolver(model, [tasks[:5], tasks[5:]], [mink.ConfigurationLimit(model)])
    plan = solver._plan
    args = list(plan.gather(configuration))
    warm = plan.cold
    nv = model.nv
    plan.write_settings(DT, solver.damping, solver._core)
    good = (*args, plan.no_rows, plan.no_h, warm, False, 100)
    assert plan.kernel.step(*good)[0] == 0
    bad = {
        0: np.zeros(model.nq - 1),  # qpos
        1: np.zeros((0, 3)),  # no site poses
        7: np.zeros((1, 3)),  # subtree_com too short
        8: np.zeros((2, nv - 1)),  # G
        9: np.zeros(3),  # h of another length than G
        10: np.zeros((3, nv), dtype=np.int8),  # warm: 2 levels
    }
    for index, value in bad.items():
        call = list(good)
        call[index] = value
        with pytest.raises(ValueError):
            plan.kernel.step(*call)
    a = dict(plan.arrays)
    a["tasks"] = np.array([[9, 0, 0, 0]], dtype=np.int64)
    names = ["A", "b", "w", "starts", "tasks", "jac", "frames", "frame_data", "posture_data",
             "posture_map", "cfg_dof", "cfg_qadr", "cfg_data", "vel_dof", "vel_limit",
             "settings", "com_jac", "com_body", "com_data", "rel_jac", "rel_frames",
             "rel_data"]  # fmt: skip
    with pytest.raises(ValueError):
        _engine.diffik.Kernel(*[a[n] for n in names], model.nq)
    a = dict(plan.arrays)
    a["posture_map"] = a["posture_map"].copy()
    a["posture_map"][-1, 1] = model.nq
    with pytest.raises(ValueError):
        _engine.diffik.Kernel(*[a[n] for n in names], model.nq)
    a = dict(plan.arrays)
    a["A"] = a["A"].astype(np.float32)  # held arrays are never copies
    with pytest.raises(TypeError):
        _engine.diffik.Kernel(*[a[n] for n in names], model.nq)


@pytest.mark.parametrize("ball", [False, True])
def test_floating_step_does_not_depend_on_history(robot, robot_no_ball, ball):
    """The compiled step keeps its rows, boxes and cascade storage from step to step: the
    same state and targets give bitwise the same step on a fresh solver, and on one that
    has stepped through other states, targets and binding limits in between."""
    model, configuration = robot if ball else robot_no_ball
    tasks = _tasks(model)
    levels = [tasks[:2], tasks[2:4], [tasks[4]], tasks[5:]]
    limits = [mink.ConfigurationLimit(model), _velocity_limit(model)]

    def step_at(solver, seed):
        rng = np.random.default_rng(seed)
        configuration.update(_random_q(rng, model))
        _set_targets(rng, model, configuration, tasks)
        result = solver.step(configuration, DT)
        return (result.displacement.tobytes(), tuple(result.residuals),
                tuple(result.status), tuple(result.active_limits))  # fmt: skip

    solver = qpik.IKSolver(model, levels, limits)
    assert solver._plan is not None
    first = step_at(solver, 1)
    for seed in range(100, 125):  # other problems on the same solver
        step_at(solver, seed)
    assert step_at(solver, 1) == first
    assert step_at(qpik.IKSolver(model, levels, limits), 1) == first
