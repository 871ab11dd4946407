"""Regression tests of the 16 classes of bad outcomes an independent fuzz campaign found
(issue 25; ``FINDINGS.md`` of the reliability cases), one or more per class, built from
each class's reproducer (its files copied into ``tests/data/reliability``), and the two
defects found by reading (``ManipulabilityTask`` rows).

Each test checks the class's property, not only its case: a wrong type raises a
``QpikError`` that is also a ``TypeError`` (and a ``ValueError``); a mink error leaves
qpik as qpik's counterpart (also mink's class); every figure a result reports matches
MuJoCo's forward kinematics of its returned ``q``; no returned value is NaN or inf; no
step leaves a limit.
"""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import mink
import mujoco
import numpy as np
import pytest

import qpik
from qpik import analysis, statics
from qpik.core import checks
from qpik.errors import InvalidArgumentType

DATA = Path(__file__).parents[1] / "data" / "reliability"
VALID = DATA / "planar_4r_valid.toml"  # tasks/planar_4r_priorities.toml, as shipped


def _erd_installed() -> bool:
    try:
        return "talos" in qpik.robots.erd_robots()
    except qpik.QpikError:
        return False


HAS_ERD = _erd_installed()


def _typed_type_error(error: BaseException) -> None:
    assert isinstance(error, qpik.QpikError)
    assert isinstance(error, TypeError) and isinstance(error, ValueError)


def _fk_position(model: mujoco.MjModel, q: np.ndarray, name: str, kind: str) -> np.ndarray:
    """World position of a frame by MuJoCo's own kinematics (independent of qpik)."""
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    obj = {"body": mujoco.mjtObj.mjOBJ_BODY, "site": mujoco.mjtObj.mjOBJ_SITE}[kind]
    i = mujoco.mj_name2id(model, obj, name)
    return (data.xpos if kind == "body" else data.site_xpos)[i].copy()


def _goal_position_error(problem, goal, q: np.ndarray) -> float:
    return max(
        float(
            np.linalg.norm(
                _fk_position(problem.model, q, f.frame, f.frame_type.value) - f.target.position
            )
        )
        for f in goal.frames
    )


# ------------------------------------------------------------ 1. misreport · problem
@pytest.mark.skipif(not HAS_ERD, reason="needs example-robot-data (erd:talos)")
def test_class01_problem_errors_match_forward_kinematics_with_several_frames_per_goal():
    problem = qpik.load_problem(DATA / "talos_both_hands_p469.toml")
    result = problem.solve()
    tol = problem.solve_options.tol_position
    for goal, r in zip(problem.goals, result.results):
        fk = _goal_position_error(problem, goal, r.q)
        assert abs(r.position_error - fk) <= 1e-6 * max(1.0, fk)
        for frame in goal.frames:
            own = np.linalg.norm(
                _fk_position(problem.model, r.q, frame.frame, frame.frame_type.value)
                - frame.target.position
            )
            assert abs(r.frame_errors[frame.frame][0] - own) <= 1e-9
        if r.converged:
            assert fk <= tol
    assert result.converged == all(r.converged for r in result.results)


def test_class01_a_misreported_solve_is_corrected_from_its_returned_q():
    """The problem layer recomputes what a solve reports from its ``q``: a result whose
    figures (or claim) disagree with forward kinematics comes back corrected."""
    from qpik.problem.modes import _measured

    problem = qpik.load_problem(VALID)
    goal = problem.goals[0]
    q = problem.q0
    wrong = qpik.IKResult(
        q=q,
        converged=True,
        reason=qpik.Reason.CONVERGED,
        iterations=1,
        restarts_used=0,
        position_error=0.0,
        orientation_error=0.0,
    )
    fixed = _measured(problem, goal, wrong)
    fk = _goal_position_error(problem, goal, q)
    assert fixed.position_error == pytest.approx(fk, abs=1e-12)
    assert fk > problem.solve_options.tol_position
    assert not fixed.converged and fixed.reason == "stalled"
    assert dataclasses.replace(fixed, converged=True).q is q


def test_class01_track_errors_are_those_of_each_recorded_q(tmp_path):
    """Track mode: entry ``k`` of the trace's errors is the FK error of ``q[k]`` against
    the goal it works toward, also where a waypoint ends and the next begins."""
    text = VALID.read_text()
    text = text.replace(
        '[target]\nframe = "ee"\nposition = [2.0, 0.0, 0.0]',
        '[[waypoints]]\nframe = "ee"\nposition = [2.0, 0.0, 0.0]\n'
        '[[waypoints]]\nframe = "ee"\nposition = [1.5, 1.0, 0.0]',
    ).replace("steps = 200", "steps = 60")
    assert "[[waypoints]]" in text
    path = tmp_path / "two_waypoints.toml"
    path.write_text(text)
    problem = qpik.load_problem(path)
    result = problem.solve()
    trace = result.trace
    index = result.goal_index
    for k, q in enumerate(trace.q):
        fk = _goal_position_error(problem, problem.goals[index[k]], q)
        assert trace.position_error[k] == pytest.approx(fk, abs=1e-9)


# --------------------------------------------------------- 2. untyped · load_problem
@pytest.mark.parametrize("wrap", [bytes, lambda p: 42, lambda p: None, lambda p: [p]])
def test_class02_load_problem_of_a_wrong_type_raises_a_typed_type_error(wrap):
    path = str(DATA / "planar_4r_p313.toml")
    argument = wrap(path.encode()) if wrap is bytes else wrap(path)
    with pytest.raises(InvalidArgumentType, match="path must be") as info:
        qpik.load_problem(argument)
    _typed_type_error(info.value)


def test_class02_load_problem_takes_str_and_path():
    assert qpik.load_problem(str(VALID)).name == "planar_4r_priorities"
    assert qpik.load_problem(VALID).mode == "track"


# ---------------------------------------------------------- 3. nonfinite · robot
def test_class03_a_robot_beyond_float_range_is_refused_at_load(tmp_path):
    shutil.copy(DATA / "huge_origin_r488.urdf", tmp_path / "r488.urdf")
    with pytest.warns(UserWarning, match="collision mesh"):
        with pytest.raises(qpik.RobotFileError, match="within 1e\\+06 m"):
            qpik.load_robot(tmp_path / "r488.urdf")


def test_class03_statics_never_return_nan_even_on_a_model_built_outside_load_robot():
    xml = """<mujoco><worldbody><body pos="1e300 0 0"><joint type="hinge" axis="0 1 0"/>
    <inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    with pytest.raises(qpik.RobotFileError):
        qpik.load_robot(model)
    configuration = qpik.Configuration(model)
    for call in (statics.gravity_torques, statics.holding_torques):
        try:
            tau = call(configuration)
        except qpik.InvalidInput:
            continue
        assert np.isfinite(tau).all()


# ----------------------------------------------- 4. untyped · IKSolver.step (ball)
def test_class04_joint_limit_distance_task_on_a_ball_joint_model():
    model = qpik.load_robot(DATA / "ball_entities_r190.xml")
    assert model.nq == 4 and model.nv == 3
    configuration = qpik.Configuration(model)
    task = qpik.tasks.PositionTask("ee", "site")
    task.set_target(configuration.frame_pose("ee", "site")[0] + 0.05)
    limits = qpik.limits.joint_limits(model)
    solver = qpik.IKSolver(model, [[task], [qpik.tasks.JointLimitDistanceTask()]], limits)
    step = solver.step(configuration, 0.01)
    assert step.velocity.shape == (3,) and np.isfinite(step.velocity).all()


def test_class04_joint_limit_distance_jacobian_matches_finite_differences_on_mixed_joints():
    xml = """<mujoco><worldbody><body><freejoint/><geom size="0.1"/>
      <body pos="0.3 0 0"><joint type="ball"/><geom size="0.05"/>
      <body pos="0.3 0 0"><joint name="h" type="hinge" range="-1 2"/><geom size="0.05"/>
      <body pos="0.3 0 0"><joint name="s" type="slide" range="-0.2 0.5"/><geom size="0.05"/>
      </body></body></body></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    configuration = qpik.Configuration(model)
    q = configuration.q.copy()
    q[7 + 4] = 1.3  # hinge
    q[7 + 4 + 1] = 0.4  # slide
    configuration.update(q)
    task = qpik.tasks.JointLimitDistanceTask()
    jacobian = task.compute_jacobian(configuration)
    assert jacobian.shape == (1, model.nv)
    numeric = np.zeros(model.nv)
    for k in range(model.nv):
        values = []
        for sign in (1, -1):
            qk = q.copy()
            velocity = np.zeros(model.nv)
            velocity[k] = sign * 1e-6
            mujoco.mj_integratePos(model, qk, velocity, 1.0)
            configuration.update(qk)
            values.append(task.compute_error(configuration)[0])
        numeric[k] = (values[0] - values[1]) / 2e-6
    configuration.update(q)
    np.testing.assert_allclose(jacobian[0], numeric, atol=1e-7)


# ------------------------------------------- 5. untyped · IKSolver.step (IndexError)
def test_class05_a_velocity_limit_of_the_wrong_length_is_a_typed_error():
    with pytest.raises(qpik.RobotFileError, match="one per dof"):
        qpik.load_robot(DATA / "velocity_limit_length_r636.xml")
    model = mujoco.MjModel.from_xml_path(str(DATA / "velocity_limit_length_r636.xml"))
    with pytest.raises(qpik.LimitDefinitionError, match="one per dof"):
        qpik.limits.joint_limits(model)


# ------------------------------------- 6-9. untyped · statics / analysis: configuration
NOT_CONFIGURATIONS = [np.zeros(4), "panda", None, "model"]


@pytest.mark.parametrize("bad", NOT_CONFIGURATIONS)
@pytest.mark.parametrize(
    "call",
    [
        lambda c: statics.joint_torques(c, "ee", [0, 0, 1]),
        lambda c: statics.gravity_torques(c),
        lambda c: statics.holding_torques(c),
        lambda c: statics.max_payload(c, "ee", [0, 0, -1]),
        lambda c: statics.joint_torque_limits(c),
        lambda c: statics.wrench_from_torques(c, "ee", [0, 0]),
        lambda c: statics.force_ellipsoid(c, "ee"),
        lambda c: analysis.manipulability_gradient(c, "ee"),
        lambda c: analysis.analyze(c, "ee"),
        lambda c: analysis.self_motion(c, "ee", [0, 0]),
    ],
)
def test_classes06_to_09_a_wrong_configuration_raises_a_typed_type_error(call, bad):
    if isinstance(bad, str) and bad == "model":
        bad = qpik.load_robot("planar_2r")  # an MjModel (class 9)
    with pytest.raises(InvalidArgumentType, match="configuration must be") as info:
        call(bad)
    _typed_type_error(info.value)


# -------------------------------------------------- 10. untyped · statics.max_payload
@pytest.mark.parametrize(
    "kwargs",
    [
        {"torque_limits": "x"},
        {"torque_limits": {"a": 1}},
        {"direction": "xyz"},
        {"direction": None},
        {"gravity": "no"},
    ],
)
def test_class10_max_payload_arguments_of_a_wrong_type(kwargs):
    configuration = qpik.Configuration(qpik.load_robot("planar_2r"), np.zeros(2))
    arguments = {"direction": [0.0, 0.0, -1.0], **kwargs}
    with pytest.raises(InvalidArgumentType) as info:
        statics.max_payload(configuration, "ee", **arguments)
    _typed_type_error(info.value)


def test_class10_the_reproducer():
    configuration = qpik.Configuration(qpik.load_robot("planar_2r"), np.zeros(2))
    direction = np.array([2.002957655029717e299, 6.079125347936855e299, -2.73434438759306e299])
    with pytest.raises(InvalidArgumentType, match="torque_limits"):
        statics.max_payload(configuration, "ee", direction, "x", "site", False)
    payload = statics.max_payload(configuration, "ee", direction, [5.0, 5.0], "site", False)
    unit = (direction / 1e299) / np.linalg.norm(direction / 1e299)
    np.testing.assert_allclose(payload.direction, unit)
    assert np.linalg.norm(payload.direction) == pytest.approx(1.0)


# ------------------------------------------------------ 11. limit · ConfigurationLimit
def test_class11_a_configuration_limit_without_range_is_refused():
    model = qpik.load_robot("planar_2r")
    with pytest.raises(qpik.LimitDefinitionError, match="no range") as info:
        qpik.limits.ConfigurationLimit(model, gain=0.5, min_distance_from_limits=10.0)
    assert isinstance(info.value, mink.LimitDefinitionError)
    assert qpik.limits.ConfigurationLimit(model, min_distance_from_limits=3.0) is not None


def _stacked_limit_step(limit_factory):
    model = qpik.load_robot("planar_2r")
    configuration = qpik.Configuration(model, np.array([-2.080012034791277, -0.0322402]))
    posture = qpik.tasks.PostureTask(model, cost=1.0, gain=0.1)
    posture.set_target(np.array([-1.4327381082266486, 0.8689742304639796]))
    limits = [
        *qpik.limits.joint_limits(model, 1.0),
        qpik.limits.ConfigurationLimit(model, gain=0.95),
        limit_factory(model),
    ]
    solver = qpik.IKSolver(model, [[posture]], limits, solver="osqp", rank_tolerance=1e-3)
    return model, configuration, solver.step(configuration, 0.004694)


def test_class11_stacked_configuration_limits_with_other_gains_hold():
    model, configuration, step = _stacked_limit_step(
        lambda m: qpik.limits.ConfigurationLimit(m, gain=0.5, min_distance_from_limits=1.0)
    )
    q = configuration.q + step.displacement
    assert np.all(q >= model.jnt_range[:, 0] + 1.0 - 1e-9)
    assert np.all(q <= model.jnt_range[:, 1] - 1.0 + 1e-9)


def test_class11_a_raw_mink_limit_without_range_is_infeasible_not_silently_left():
    with pytest.raises(qpik.InfeasibleLimits):
        _stacked_limit_step(
            lambda m: mink.ConfigurationLimit(m, gain=0.5, min_distance_from_limits=10.0)
        )


# ---------------------------------------------------------- 12. nonfinite · dt range
@pytest.mark.parametrize("dt", [5e-324, 1e-300, checks.DT_MIN / 2, 1e300])
def test_class12_kinetic_energy_task_set_dt_takes_the_documented_range(dt):
    task = qpik.tasks.KineticEnergyRegularizationTask(cost=0.1)
    with pytest.raises(qpik.InvalidOption, match="dt"):
        task.set_dt(dt)
    task.set_dt(checks.DT_MIN)
    task.set_dt(checks.DT_MAX)


@pytest.mark.parametrize("dt", ["0.01", None, True])
def test_class12_a_dt_of_a_wrong_type_is_a_typed_type_error(dt):
    with pytest.raises(InvalidArgumentType) as info:
        checks.check_dt(dt)
    _typed_type_error(info.value)


def _planar_4r_step(dt: float):
    model = qpik.load_robot("planar_4r")
    configuration = qpik.Configuration(
        model, np.array([-1.4426016604562846, -1.9810804268643696, 0.1076368, 0.2825762])
    )
    t0 = qpik.tasks.KineticEnergyRegularizationTask(cost=0.1)
    t0.set_dt(0.01)
    t1 = qpik.tasks.PoseTask("link4", "body", position_cost=0.1, orientation_cost=1.0)
    t1.set_target_from_configuration(configuration)
    t2 = qpik.tasks.PositionTask("link4", "geom", cost=10.0, gain=0.5)
    t2.set_target(np.array([1.9224600770198352, 1.3554182166365283, 0.0]))
    return qpik.IKSolver(model, [[t0, t1], [t2]], []).step(configuration, dt)


def test_class12_steps_in_range_are_finite():
    for dt in (checks.DT_MIN, 0.01, 1.0):
        step = _planar_4r_step(dt)
        assert np.isfinite(step.velocity).all() and np.isfinite(step.displacement).all()


@pytest.mark.parametrize("dt", [5e-324, 1e-300, 1e300])
def test_class12_a_step_outside_the_dt_range_raises(dt):
    with pytest.raises(qpik.InvalidOption, match="dt"):
        _planar_4r_step(dt)


# -------------------------------------------- 13-16. untyped · mink errors in a step
def _kinetic_energy_step(call: str):
    model = qpik.load_robot("planar_4r")
    configuration = qpik.Configuration(model, np.array([-1.53, -0.95, 0.16, 1.31]))
    energy = qpik.tasks.KineticEnergyRegularizationTask(cost=0.0)
    com = qpik.tasks.ComTask(cost=10.0, gain=1.0, lm_damping=1.0)
    com.set_target_from_configuration(configuration)
    limits = qpik.limits.joint_limits(model, 1.0)
    if call == "step":
        return qpik.IKSolver(model, [energy, com], limits).step(configuration, 1.0)
    return qpik.solve_ik(configuration, [[energy, com]], 0.01, limits=limits)


def _relative_frame_step(call: str, task_class=qpik.tasks.RelativeFrameTask):
    model = qpik.load_robot("ur5e")
    configuration = qpik.Configuration(model, np.zeros(6))
    relative = task_class(
        "ee", "site", "base_link", "body", position_cost=0.0, orientation_cost=1.0
    )
    damping = qpik.tasks.DampingTask(model, cost=0.0)
    freeze = qpik.tasks.DofFreezingTask(model, dof_indices=[0, 1])
    limits = [qpik.limits.ConfigurationLimit(model, gain=1.0, min_distance_from_limits=0.01)]
    if call == "step":
        return qpik.IKSolver(model, [[damping], [relative, freeze]], limits).step(
            configuration, 0.076312
        )
    return qpik.solve_ik(configuration, [[relative]], 0.000202, limits=limits)


@pytest.mark.parametrize("call", ["step", "solve_ik"])
def test_classes13_and_15_a_kinetic_energy_task_without_dt_raises_qpiks_error(call):
    with pytest.raises(qpik.IntegrationTimestepNotSet) as info:
        _kinetic_energy_step(call)
    assert isinstance(info.value, mink.IntegrationTimestepNotSet)
    assert isinstance(info.value, qpik.QpikError)


@pytest.mark.parametrize("call", ["step", "solve_ik"])
def test_classes14_and_16_a_relative_frame_task_without_target_raises_qpiks_error(call):
    with pytest.raises(qpik.TargetNotSet) as info:
        _relative_frame_step(call)
    assert isinstance(info.value, mink.TargetNotSet)
    assert isinstance(info.value, qpik.QpikError)


@pytest.mark.parametrize("cost", [np.inf, np.nan, -1.0, "x"])
def test_class15_a_kinetic_energy_cost_must_be_finite_and_nonnegative(cost):
    with pytest.raises(qpik.TaskDefinitionError) as info:
        qpik.tasks.KineticEnergyRegularizationTask(cost=cost)
    assert isinstance(info.value, mink.TaskDefinitionError)


def test_classes13_to_16_qpiks_tasks_are_minks():
    for name in ("KineticEnergyRegularizationTask", "RelativeFrameTask", "DofFreezingTask"):
        assert issubclass(getattr(qpik.tasks, name), getattr(mink, name))


def test_classes14_and_16_a_raw_mink_task_without_target_raises_qpiks_error():
    with pytest.raises(qpik.TargetNotSet):
        _relative_frame_step("step", mink.RelativeFrameTask)


@pytest.mark.parametrize(
    ("mink_error", "qpik_class"),
    [
        (mink.TargetNotSet("RelativeFrameTask"), qpik.TargetNotSet),
        (mink.IntegrationTimestepNotSet("X"), qpik.IntegrationTimestepNotSet),
        (mink.InvalidTarget("bad"), qpik.InvalidTarget),
        (mink.InvalidConstraint("bad"), qpik.InvalidConstraint),
        (mink.NoSolutionFound("osqp"), qpik.NoSolutionFound),
        (mink.exceptions.MinkError("other"), qpik.errors.MinkFailure),
    ],
)
def test_every_mink_error_has_a_qpik_counterpart_that_is_also_minks(mink_error, qpik_class):
    translated = qpik.errors.as_qpik_error(mink_error)
    assert isinstance(translated, qpik_class) and isinstance(translated, type(mink_error))
    with pytest.raises(qpik_class):
        with qpik.errors.qpik_errors():
            raise mink_error


# ------------------------------------------------ found by reading: ManipulabilityTask
@pytest.mark.parametrize("rows", ["orientation", "position", "pose", ("vx", "wz")])
def test_manipulability_task_jacobian_matches_finite_differences(rows):
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model)
    q = configuration.mid_q() + 0.1
    configuration.update(q)
    task = qpik.tasks.ManipulabilityTask("ee", "site", rows=rows)
    jacobian = task.compute_jacobian(configuration)[0]
    numeric = np.zeros(model.nv)
    for k in range(model.nv):
        step = np.zeros(model.nv)
        step[k] = 1e-6
        configuration.update(q + step)
        plus = task.compute_error(configuration)[0]
        configuration.update(q - step)
        minus = task.compute_error(configuration)[0]
        numeric[k] = (plus - minus) / 2e-6
    configuration.update(q)
    np.testing.assert_allclose(jacobian, numeric, atol=1e-6)


@pytest.mark.parametrize("rows", ["nonsense", "", 5, None, ("vx", "vx")])
def test_manipulability_task_rejects_unknown_rows(rows):
    with pytest.raises(qpik.InvalidInput):
        qpik.tasks.ManipulabilityTask("ee", "site", rows=rows)


# ------------------------------------------------------------- the checks themselves
def test_check_real_ranges_and_types():
    assert checks.check_real("x", np.float32(0.5), 0.0, 1.0) == 0.5
    with pytest.raises(qpik.InvalidOption, match=r"x must be a finite number in \[0, 1\]"):
        checks.check_real("x", 2.0, 0.0, 1.0)
    with pytest.raises(qpik.InvalidOption):
        checks.check_real("x", float("nan"))
    for bad in ("1", None, True, [1.0]):
        with pytest.raises(InvalidArgumentType):
            checks.check_real("x", bad)


@pytest.mark.parametrize("frame", [[1, 2], np.zeros(3), {"a": 1}])
def test_an_unhashable_frame_name_is_a_typed_type_error(frame):
    configuration = qpik.Configuration(qpik.load_robot("planar_2r"))
    with pytest.raises(InvalidArgumentType) as info:
        statics.joint_torques(configuration, frame, [0, 0, 1])
    _typed_type_error(info.value)


@pytest.mark.parametrize("target", ["x", b"x", None, 3.0, object(), {"a": 1}])
def test_a_target_of_a_wrong_type_is_invalid_target(target):
    tasks = [
        qpik.tasks.PositionTask("ee"),
        qpik.tasks.RelativeFrameTask("ee", "site", "link1", "body", 1.0, 1.0),
    ]
    for task in tasks:
        with pytest.raises(qpik.InvalidTarget):
            task.set_target(target)


@pytest.mark.parametrize("q", ["x", b"x", {"a": 1}, object()])
def test_joint_limit_distance_of_a_wrong_type_is_typed(q):
    with pytest.raises(qpik.InvalidInput):
        analysis.joint_limit_distance(q, [0.0, 0.0], [1.0, 1.0])
