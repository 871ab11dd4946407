"""The secondary tasks' rows each step: JointLimitDistanceTask keeps its limited joints
while the limits stay the same (the values of qpik.analysis' public functions to round-off,
and the new limits once a model's ranges change in place); the manipulability gradient
uses a scratch MjData kept per model, so its answer does not depend on what ran before and
the caller's data is not touched."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import load_or_skip

import qpik
from qpik.analysis import joint_limit_distance, joint_limit_distance_gradient
from qpik.model.gradients import manipulability_gradient
from qpik.tasks import JointLimitDistanceTask


def _reference(task, configuration):
    qpos, dofs = task._indices(configuration)
    args = (configuration.q[qpos], configuration.lower[qpos], configuration.upper[qpos])
    jacobian = np.zeros((1, configuration.model.nv))
    jacobian[0, dofs] = joint_limit_distance_gradient(*args)
    return np.array([joint_limit_distance(*args)]), jacobian


@pytest.mark.parametrize("name", ["panda", "erd:talos"])
def test_joint_limit_distance_rows_are_the_public_functions(name):
    """The Panda's 7 joints and Talos' 32: the task's compiled row (a sum in joint order)
    against qpik.analysis' NumPy functions (np.sum's pairwise grouping: round-off apart),
    and its rows exactly its error and Jacobian weighted."""
    model = load_or_skip(name)
    rng = np.random.default_rng(3)
    task = JointLimitDistanceTask(cost=2.0, gain=0.4)
    bounds = qpik.Configuration(model)
    for _ in range(30):
        q = np.clip(model.qpos0 + rng.uniform(-1.0, 1.0, model.nq), bounds.lower, bounds.upper)
        configuration = qpik.Configuration(model, q)
        error, jacobian = _reference(task, configuration)
        ours_error, ours_jacobian = (
            task.compute_error(configuration),
            task.compute_jacobian(configuration),
        )
        np.testing.assert_allclose(ours_error, error, rtol=1e-14, atol=0)
        np.testing.assert_allclose(ours_jacobian, jacobian, rtol=1e-14, atol=0)
        A, b, _ = task.compute_qp_residual(configuration)
        np.testing.assert_array_equal(A, 2.0 * ours_jacobian)
        np.testing.assert_array_equal(b, 2.0 * (-0.4 * ours_error))


def test_joint_limit_distance_follows_limits_changed_in_place():
    model = qpik.load_robot("panda")
    task = JointLimitDistanceTask()
    configuration = qpik.Configuration(model, model.qpos0)
    before = task.compute_error(configuration).copy()
    model.jnt_range[0] = [-0.5, 0.1]  # joint 1's range, halved and shifted
    configuration = qpik.Configuration(model, model.qpos0)
    error, jacobian = _reference(task, configuration)
    np.testing.assert_allclose(task.compute_error(configuration), error, rtol=1e-14, atol=0)
    np.testing.assert_allclose(task.compute_jacobian(configuration), jacobian, rtol=1e-14, atol=0)
    assert error[0] != before[0]


def test_manipulability_gradient_does_not_depend_on_what_ran_before():
    model = qpik.load_robot("panda")
    rng = np.random.default_rng(4)
    a = qpik.Configuration(model, model.qpos0 + rng.uniform(-1.0, 1.0, model.nq))
    b = qpik.Configuration(model, model.qpos0 + rng.uniform(-1.0, 1.0, model.nq))
    qvel_before = a.data.qvel.copy()
    first = manipulability_gradient(a, "ee", "site")
    manipulability_gradient(b, "ee", "site", rows="position")
    np.testing.assert_array_equal(manipulability_gradient(a, "ee", "site"), first)
    np.testing.assert_array_equal(a.data.qvel, qvel_before)
    # central differences of the manipulability along each joint
    from qpik.analysis import manipulability

    h, numeric = 1e-6, np.zeros(model.nv)
    for k in range(model.nv):
        values = []
        for sign in (1.0, -1.0):
            q = a.q.copy()
            q[k] += sign * h
            probe = qpik.Configuration(model, q)
            values.append(manipulability(probe.frame_jacobian("ee", "site")))
        numeric[k] = (values[0] - values[1]) / (2 * h)
    np.testing.assert_allclose(first, numeric, rtol=1e-6, atol=1e-8)


def test_manipulability_task_rows_are_its_error_and_jacobian():
    """compute_qp_residual (one frame Jacobian) against compute_error / compute_jacobian
    (each its own), bit for bit, for each row choice."""
    from qpik.tasks import ManipulabilityTask

    model = qpik.load_robot("panda")
    rng = np.random.default_rng(9)
    for rows in ("pose", "position", "orientation"):
        task = ManipulabilityTask("ee", "site", rows=rows, cost=0.5, gain=0.3)
        for _ in range(5):
            configuration = qpik.Configuration(model, model.qpos0 + rng.uniform(-1, 1, model.nq))
            A, b, _ = task.compute_qp_residual(configuration)
            np.testing.assert_array_equal(A, 0.5 * task.compute_jacobian(configuration))
            np.testing.assert_array_equal(b, 0.5 * (-0.3 * task.compute_error(configuration)))


@pytest.mark.parametrize("name", ["panda", "erd:talos"])
def test_joint_limit_distance_in_the_compiled_step_has_the_qp_paths_bits(name):
    """A frame task, the joint-limit distance, a posture, position and velocity limits: the
    kernel computes the joint-limit row itself (no task supplies its rows), and each step's
    velocity equals the QP path's (the task's own compiled row) bit for bit; with a
    correction pass too (the kernel's weighted errors of the held levels)."""
    import mink

    from qpik.limits import velocity_limit_from_model
    from qpik.tasks import FrameTask, PostureTask

    model = load_or_skip(name)
    rng = np.random.default_rng(12)
    frame_name, kind = ("ee", "site") if name == "panda" else ("gripper_left_base_link", "body")
    frame = FrameTask(frame_name, kind, position_cost=1.0, orientation_cost=1.0)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    posture = PostureTask(model, cost=0.05)
    for passes in (0, 1):
        task = JointLimitDistanceTask(cost=1.5, gain=0.5, lm_damping=0.1)
        solver = qpik.IKSolver(
            model, [[frame], [task], [posture]], limits, correction_passes=passes
        )
        assert solver._plan is not None and not solver._plan.rows_tasks
        bounds = qpik.Configuration(model)
        for _ in range(8):
            q = np.clip(model.qpos0 + rng.uniform(-0.6, 0.6, model.nq), bounds.lower, bounds.upper)
            configuration = qpik.Configuration(model, q)
            frame.set_target_from_configuration(configuration)
            posture.set_target(q)
            result = solver.step(configuration, 0.01)
            if passes == 0:
                reference = solver.qp_solution(configuration, 0.01)
                np.testing.assert_array_equal(result.velocity, reference.velocity)
            assert all(s == "solved" for s in result.status)


@pytest.mark.parametrize(("name", "value"), [("cost", np.ones(2)), ("gain", "x")])
def test_joint_limit_distance_attribute_that_does_not_fit_is_a_typed_error(name, value):
    """The task's cost or gain set directly to what its row cannot take: TaskDefinitionError
    naming it, on the compiled step (which hands it to the QP path) and the QP path."""
    import mink

    from qpik.errors import TaskDefinitionError
    from qpik.tasks import FrameTask, PostureTask

    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    frame = FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    frame.set_target_from_configuration(configuration)
    posture = PostureTask(model, cost=0.1)
    posture.set_target(model.key_qpos[0])
    task = JointLimitDistanceTask()
    solver = qpik.IKSolver(model, [[frame], [task], [posture]], [mink.ConfigurationLimit(model)])
    solver.step(configuration, 0.01)
    setattr(task, name, value)
    with pytest.raises(TaskDefinitionError, match="JointLimitDistanceTask"):
        solver.step(configuration, 0.01)
    with pytest.raises(TaskDefinitionError, match="JointLimitDistanceTask"):
        solver.qp_solution(configuration, 0.01)


@pytest.mark.parametrize("solver_name", ["auto", "osqp"])
def test_an_objective_that_overflows_is_a_typed_error(solver_name):
    """mink's kinetic-energy task with a cost of 1e300 and a time step of 1e-9: its (H, c)
    overflows; the step raises TaskDefinitionError naming it, not NumPy's LinAlgError from
    factoring an infinite H (benchmarks/fuzz.py --seed 7323, case stack:577)."""
    import mink

    from qpik.errors import TaskDefinitionError
    from qpik.tasks import KineticEnergyRegularizationTask, PositionTask

    model = qpik.load_robot("ur5e")
    configuration = qpik.Configuration(model, model.key_qpos[0] if model.nkey else model.qpos0)
    position = PositionTask("ee", "site")
    position.set_target_from_configuration(configuration)
    energy = KineticEnergyRegularizationTask(cost=1e300)
    energy.set_dt(1e-9)
    solver = qpik.IKSolver(
        model, [[position], [energy]], [mink.ConfigurationLimit(model)], solver=solver_name
    )
    with pytest.raises(TaskDefinitionError, match="KineticEnergyRegularizationTask"):
        solver.step(configuration, 0.01)


@pytest.mark.parametrize(
    "solver_name, kind",
    [("quadprog", "manipulability"), ("daqp", "frame"), ("auto", "manipulability")],
)
def test_a_damping_that_overflows_is_a_typed_error(solver_name, kind):
    """A task of cost 1e300 at UR5e's singular zero pose: the damping law's lambda^2 scales
    with the square of the level's largest weight, which overflows; the step raises
    InvalidTarget (as where the rows overflow) or answers with every number finite, never a
    damping of inf (benchmarks/fuzz.py --seed 7333, cases step:86 and step:317)."""
    import mink

    from qpik.errors import InvalidTarget
    from qpik.tasks import FrameTask, ManipulabilityTask

    model = qpik.load_robot("ur5e")
    configuration = qpik.Configuration(model, model.qpos0)
    if kind == "manipulability":
        task = ManipulabilityTask("ee", "site", rows="position", cost=1e300, gain=0.0)
    else:
        task = FrameTask("ee", "site", position_cost=1e300, orientation_cost=1e300)
        task.set_target_from_configuration(configuration)
    speeds = {model.joint(j).name: 1.0 for j in range(model.njnt)}
    solver = qpik.IKSolver(
        model, [[task]], [mink.VelocityLimit(model, speeds)], solver=solver_name, damping=1e-3
    )
    for _ in range(3):
        try:
            result = solver.step(configuration, 0.002)
        except InvalidTarget:
            continue
        assert np.isfinite(result.velocity).all()
        assert np.isfinite(result.damping).all() and np.isfinite(result.residuals).all()


@pytest.mark.parametrize(
    "robot, q0, rows", [("planar_2r", [0.3, 0.7], [0, 1]), ("panda", None, "position")]
)
def test_the_manipulability_task_raises_manipulability(robot, q0, rows):
    """Pins h11's audit: the task lowered m (its error -m driven to 0: toward a
    singularity). Its error is now 1 / m, so each unconstrained step raises m by about
    gain * m, as documented, and a loop of steps ends at a larger m (planar 2R: the
    elbow at 90 degrees, m = l1 l2 = 1)."""
    from qpik.analysis import manipulability
    from qpik.tasks import ManipulabilityTask

    model = qpik.load_robot(robot)
    configuration = qpik.Configuration(model, model.key_qpos[0] if q0 is None else q0)
    task = ManipulabilityTask("ee", rows=rows)

    def m(c):
        return manipulability(c.frame_jacobian("ee", "site")[task._row_index])

    assert task.compute_error(configuration)[0] == pytest.approx(1.0 / m(configuration))
    start = m(configuration)
    free = qpik.IKSolver(model, [[task]], max_joint_speed=None).step(configuration, 0.01)
    after = qpik.Configuration(model, configuration.integrate(free.velocity, 0.01))
    assert m(after) == pytest.approx(start * (1.0 + task.gain), rel=0.05)
    # (near m's maximum no step meets the asked increase: the defaults' trust region and
    # damping bound the steps there)
    solver = qpik.IKSolver(model, [[task]])
    for _ in range(200):
        configuration.integrate_inplace(solver.step(configuration, 0.01).velocity, 0.01)
    assert m(configuration) > 1.4 * start
    if robot == "planar_2r":
        assert m(configuration) == pytest.approx(1.0, abs=1e-3)


def test_the_manipulability_task_is_idle_where_m_is_zero():
    """At an exact singularity (the 2R arm stretched), with more rows than dofs (m = 0 for
    every q) and with rows of rank deficient to round-off (6 pose rows of a link 3 joints
    move: m is round-off, 1 / m was noise of 1e16 and its row 1e32, h12's audit): error 0
    and a zero row, never inf or NaN."""
    from qpik.tasks import ManipulabilityTask

    model = qpik.load_robot("planar_2r")
    panda = qpik.load_robot("panda")
    link3 = qpik.Configuration(panda, panda.key_qpos[0])  # (3 joints move link3's 6 rows)
    cases = [(model, [0.3, 0.0], [0, 1], "ee"), (model, [0.3, 0.7], "pose", "ee")]
    for robot, q, rows, frame in [*cases, (panda, link3.q, "pose", "link3")]:
        configuration = qpik.Configuration(robot, q)
        kind = "body" if frame == "link3" else "site"
        task = ManipulabilityTask(frame, kind, rows=rows)
        assert task.compute_error(configuration).tolist() == [0.0]
        assert np.all(task.compute_jacobian(configuration) == 0.0)
        A, b, _ = task.compute_qp_residual(configuration)
        assert np.all(A == 0.0) and np.all(b == 0.0)


@pytest.mark.parametrize(
    "robot, rows", [("planar_2r", [0, 1]), ("panda", "position"), ("ur5e", "position")]
)
def test_lm_damping_settles_the_manipulability_task_at_its_maximum(robot, rows):
    """As the class documents: with lm_damping = 0 the steps near the maximum of m go back
    and forth at the trust region's size (no step meets the increase asked); with
    lm_damping = 30 each step there is a gradient step of log m, and the arm settles at the
    maximum (the planar 2R: m = l1 l2 = 1)."""
    import mink

    from qpik.tasks import ManipulabilityTask

    model = qpik.load_robot(robot)
    last = {}
    for lm in (0.0, 30.0):
        configuration = qpik.Configuration(model, model.key_qpos[0] if model.nkey else None)
        if robot == "planar_2r":
            configuration.update(np.array([0.3, 0.3]))
        task = ManipulabilityTask("ee", "site", rows=rows, lm_damping=lm)
        solver = qpik.IKSolver(model, [[task]], [mink.ConfigurationLimit(model)])
        for _ in range(600):
            velocity = solver.step(configuration, 0.01).velocity
            configuration.integrate_inplace(velocity, 0.01)
        last[lm] = (np.abs(velocity * 0.01).max(), task._value(configuration))
    assert last[0.0][0] > 0.01  # the trust region's pi rad/s x 0.01 s, every step
    assert last[30.0][0] < 1e-12 and last[30.0][1] >= last[0.0][1] - 1e-3
    if robot == "planar_2r":
        assert last[30.0][1] == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("cost", [1e151, 1e155])
@pytest.mark.parametrize("solver_name", ["auto", "quadprog"])
def test_rows_too_large_to_square_are_refused_on_every_path(cost, solver_name):
    """Audit (numerical extremes): a FrameTask of cost 1e155 at level 0 (its rows about 1e154,
    finite, their squares not) was answered 'solved' with its certificate holding, yet the
    step ignored the task (its error unchanged, the posture level moving instead): the
    certificate's sizes overflowed to inf and read every measure as 0. As
    docs/guides/errors.md says, such a cost is refused with InvalidTarget naming the level,
    on the compiled step and the QP path alike (rows past 1e150: qpik.diffik.result.squarable);
    a cost of 1 still answers."""
    import mink

    from qpik.errors import InvalidTarget
    from qpik.tasks import FrameTask, PostureTask

    model = qpik.load_robot("panda")
    home = model.key_qpos[0]
    for c in (1.0, cost):
        configuration = qpik.Configuration(model, home)
        p, R = configuration.frame_pose("ee")
        ee = FrameTask("ee", "site", position_cost=c, orientation_cost=c)
        target = mink.SO3.from_matrix(R), p + np.array([0.01, -0.02, 0.015])
        ee.set_target(mink.SE3.from_rotation_and_translation(*target))
        posture = PostureTask(model, cost=1.0)
        posture.set_target(home + 0.3)
        solver = qpik.IKSolver(
            model, [[ee], [posture]], qpik.limits.joint_limits(model), damping=0.0,
            solver=solver_name,
        )  # fmt: skip
        if c == 1.0:
            assert solver.step(configuration, 0.01).ok
            continue
        with pytest.raises(InvalidTarget, match="priority level 0.*too large to square"):
            solver.step(configuration, 0.01)
