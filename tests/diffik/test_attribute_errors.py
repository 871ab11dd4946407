"""A task's target, cost, gain or LM damping assigned directly (not by its setters) to what
does not fit its rows: TaskDefinitionError naming the task, on the compiled step (the lean
step declines such a value and the gathered step reports it) and on the QP path, never
NumPy's ValueError from inside the plan. Frame and pose tasks are checked in
tests/tasks/test_pose_compiled.py; these are the CoM, posture, damping and relative-frame
tasks (qpik's and mink's). Below them: a gain out of [0, 1] (InvalidGain) and a frame
target that is not a rotation (InvalidTarget), set after the solver was built."""

from __future__ import annotations

import mink
import numpy as np
import pytest

import qpik
from qpik.errors import TaskDefinitionError
from qpik.tasks import ComTask, DampingTask, PostureTask, RelativeFrameTask

DT = 0.01


def _com(model, configuration, cls):
    task = cls(cost=1.0)
    task.set_target(configuration.data.subtree_com[1] + 0.01)
    return task


def _posture(model, configuration, cls):
    task = cls(model, cost=0.1)
    task.set_target(configuration.q)
    return task


def _relative(model, configuration, cls):
    task = cls("ee", "site", "link0", "body", position_cost=1.0, orientation_cost=1.0)
    task.set_target(mink.SE3.from_translation(np.array([0.3, 0.0, 0.5])))
    return task


CASES = [
    (_com, ComTask, "target_com", np.zeros(5)),
    (_com, ComTask, "target_com", "abc"),
    (_com, ComTask, "cost", np.ones(5)),
    (_com, ComTask, "gain", "x"),
    (_com, mink.ComTask, "target_com", np.zeros(5)),
    (_com, mink.ComTask, "lm_damping", [1.0, 2.0]),
    (_posture, PostureTask, "target_q", np.zeros(5)),
    (_posture, PostureTask, "cost", np.ones(5)),
    (_posture, PostureTask, "gain", [1.0, 2.0]),
    (_posture, mink.PostureTask, "target_q", np.zeros(5)),
    (_posture, DampingTask, "cost", np.ones(5)),
    (_posture, DampingTask, "lm_damping", "x"),
    (_relative, RelativeFrameTask, "cost", np.ones(3)),
    (_relative, mink.RelativeFrameTask, "gain", "x"),
]


@pytest.mark.parametrize(("make", "cls", "name", "value"), CASES)
def test_an_attribute_that_does_not_fit_is_a_typed_error(make, cls, name, value):
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    task = make(model, configuration, cls)
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    frame.set_target_from_configuration(configuration)
    solver = qpik.IKSolver(model, [[frame], [task]], [mink.ConfigurationLimit(model)])
    solver.step(configuration, DT)
    solver.step(configuration, DT)  # (the lean step's lane, where it applies)
    setattr(task, name, value)
    with pytest.raises(TaskDefinitionError, match=cls.__name__):
        solver.step(configuration, DT)
    with pytest.raises(TaskDefinitionError, match=cls.__name__):
        solver.qp_solution(configuration, DT)


def _limits_solver():
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    p = configuration.frame_pose("ee", "site")[0]
    frame.set_target(mink.SE3.from_translation(p + 0.2))  # far: the speeds bind
    position = mink.ConfigurationLimit(model)
    speeds = {model.joint(j).name: 1.0 for j in range(model.njnt)}
    velocity = mink.VelocityLimit(model, speeds)
    solver = qpik.IKSolver(model, [[frame]], [position, velocity])
    solver.step(configuration, DT)
    solver.step(configuration, DT)
    return solver, configuration, position, velocity


@pytest.mark.parametrize(
    ("which", "name", "value"),
    [
        ("position", "gain", "x"),
        ("position", "gain", np.ones(3)),
        ("velocity", "limit", np.ones(3)),
        ("velocity", "limit", "x"),
    ],
)
def test_a_limit_attribute_that_does_not_fit_is_a_typed_error(which, name, value):
    """A position limit's gain or a velocity limit's speeds set directly to what does not
    fit its dofs: LimitDefinitionError naming the limit, on the compiled step and on the QP
    path (not NumPy's ValueError or TypeError, nor tighten's)."""
    from qpik.errors import LimitDefinitionError

    solver, configuration, position, velocity = _limits_solver()
    limit = position if which == "position" else velocity
    setattr(limit, name, value)
    with pytest.raises(LimitDefinitionError, match=type(limit).__name__):
        solver.step(configuration, DT)
    with pytest.raises(LimitDefinitionError, match=type(limit).__name__):
        solver.qp_solution(configuration, DT)


@pytest.mark.parametrize("kind", [np.asarray, list])
def test_new_speeds_of_a_velocity_limit_hold_on_every_path(kind):
    """A velocity limit given new speeds after the solver was built (a new array: mink's is
    read-only): the compiled step reads them each step, as the QP path and mink do (it kept
    the speeds of the plan's build before), on the lane and on the QP path alike."""
    solver, configuration, _position, velocity = _limits_solver()
    assert np.abs(solver.step(configuration, DT).velocity).max() == pytest.approx(1.0)
    velocity.limit = kind(np.asarray(velocity.limit) * 0.1)
    stepped = solver.step(configuration, DT).velocity
    reference = solver.qp_solution(configuration, DT).velocity
    assert np.abs(stepped).max() == pytest.approx(0.1)
    np.testing.assert_allclose(stepped, reference, rtol=0, atol=1e-12)
    assert solver._plan._plain_data is configuration.data  # (the lane took the step)


@pytest.mark.parametrize("how", ["in place", "new array"])
def test_new_bounds_of_a_position_limit_hold_on_every_path(how):
    """A position limit given new bounds after the solver was built (a joint's range
    narrowed around the start): the compiled step reads them each step, as the QP path and
    mink do (it kept the bounds of the plan's build before, and stepped past the new ones),
    on the lane and on the QP path alike."""
    solver, configuration, position, _velocity = _limits_solver()
    free = solver.step(configuration, DT).velocity
    q = configuration.q
    dof = int(np.argmax(np.abs(free)))  # the joint that moves most
    adr = int(solver.model.jnt_qposadr[solver.model.dof_jntid[dof]])
    room = 0.1 * abs(free[dof]) * DT  # a tenth of its free step
    lower, upper = np.array(position.lower), np.array(position.upper)
    lower[adr], upper[adr] = q[adr] - room, q[adr] + room
    if how == "in place":
        position.lower[:] = lower
        position.upper[:] = upper
    else:
        position.lower, position.upper = lower, upper
    stepped = solver.step(configuration, DT).velocity
    reference = solver.qp_solution(configuration, DT).velocity
    assert abs(stepped[dof]) * DT <= position.gain * room * (1 + 1e-12)
    np.testing.assert_allclose(stepped, reference, rtol=0, atol=1e-12)
    assert solver._plan._plain_data is configuration.data  # (the lane took the step)
    fresh = qpik.IKSolver(solver.model, solver.levels, solver.limits)
    np.testing.assert_allclose(fresh.step(configuration, DT).velocity, stepped, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("name", "value"),
    [("lower", "flip"), ("upper", "nan"), ("lower", np.zeros(3)), ("upper", "x")],
)
def test_position_bounds_that_do_not_fit_are_a_typed_error(name, value):
    """A position limit's bounds set after the build to what leaves a joint no range
    (InfeasibleLimits, as for mink's min_distance_from_limits beyond half a range), a NaN or
    what does not fit the model's coordinates (LimitDefinitionError), naming the limit on
    the compiled step, on the QP path and at a new solver's build, never a step taken
    against them."""
    from qpik.errors import InfeasibleLimits, LimitDefinitionError

    solver, configuration, position, _velocity = _limits_solver()
    error = InfeasibleLimits if isinstance(value, str) and value == "flip" else LimitDefinitionError
    bounds = np.array(getattr(position, name))
    if isinstance(value, str) and value == "flip":
        bounds[position.indices[2]] = position.upper[position.indices[2]] + 1.0
        value = bounds
    elif isinstance(value, str) and value == "nan":
        bounds[position.indices[0]] = np.nan
        value = bounds
    setattr(position, name, value)
    with pytest.raises(error, match="ConfigurationLimit"):
        solver.step(configuration, DT)
    with pytest.raises(error, match="ConfigurationLimit"):
        solver.qp_solution(configuration, DT)
    with pytest.raises(error, match="ConfigurationLimit"):
        qpik.IKSolver(solver.model, solver.levels, solver.limits).step(configuration, DT)


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("model", None),
        ("options", qpik.StepOptions()),
        ("levels", []),
        ("limits", []),
        ("solver", "osqp"),
        ("rank_tolerance", 1e-3),
    ],
)
def test_what_a_solver_was_built_from_is_read_only(name, value):
    """IKSolver's model, options, levels, limits, backend and rank tolerance are fixed at
    construction (the plan, the core and the boxes were built from them): assigning one is
    qpik's ReadOnlyAttribute (also an AttributeError) naming it, not an assignment the steps
    would silently ignore; the solver steps on as before."""
    from qpik.errors import ReadOnlyAttribute

    solver, configuration, _position, _velocity = _limits_solver()
    before = solver.step(configuration, DT).velocity.copy()
    with pytest.raises(ReadOnlyAttribute, match=f"IKSolver.{name} is fixed") as info:
        setattr(solver, name, value)
    assert isinstance(info.value, AttributeError) and info.value.attribute == name
    np.testing.assert_array_equal(solver.step(configuration, DT).velocity, before)
    assert isinstance(solver.levels, tuple) and all(isinstance(x, tuple) for x in solver.levels)
    assert isinstance(solver.limits, tuple) and solver.solver == "auto"


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("collision_detection_distance", None),
        ("gain", "x"),
        ("minimum_distance_from_collisions", "x"),
    ],
)
def test_a_collision_limit_attribute_that_does_not_fit_is_a_typed_error(name, value):
    """A collision limit's attribute set directly to what its rows cannot use (with pairs
    in play): LimitDefinitionError naming the limit on both paths, not a TypeError."""
    from qpik.errors import LimitDefinitionError
    from qpik.limits import model_collision_limit

    model = qpik.load_robot("ur5e")
    configuration = qpik.Configuration(model, qpik.Configuration(model).mid_q())
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    frame.set_target_from_configuration(configuration)
    collision = model_collision_limit(model)
    solver = qpik.IKSolver(model, [[frame]], [mink.ConfigurationLimit(model), collision])
    solver.step(configuration, DT)
    collision.collision_detection_distance = 10.0  # every pair in play
    setattr(collision, name, value)
    with pytest.raises(LimitDefinitionError, match="CollisionAvoidanceLimit"):
        solver.step(configuration, DT)
    with pytest.raises(LimitDefinitionError, match="CollisionAvoidanceLimit"):
        solver.qp_solution(configuration, DT)


class _WrongRows:
    """A user limit whose rows G have the wrong number of columns."""

    def compute_qp_inequalities(self, configuration, dt):
        nv = configuration.model.nv
        return mink.Constraint(G=np.ones((2, nv + 1)), h=np.ones(2))


def test_a_user_limit_with_rows_of_the_wrong_shape_is_a_typed_error():
    from qpik.errors import LimitDefinitionError

    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    frame.set_target_from_configuration(configuration)
    solver = qpik.IKSolver(model, [[frame]], [_WrongRows()])
    with pytest.raises(LimitDefinitionError, match="_WrongRows"):
        solver.step(configuration, DT)


@pytest.mark.parametrize("value", ["x", -1.0, np.nan, np.ones(3), 1e300])
def test_a_solver_damping_that_is_no_damping_is_refused(value):
    """IKSolver.damping set to what StepOptions would refuse: refused where it is set, with
    qpik's typed error (not a TypeError from the compiled step's call later, nor a negative
    damping taken); the solver keeps its damping and steps on."""
    from qpik.errors import QpikError

    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    frame = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    frame.set_target_from_configuration(configuration)
    solver = qpik.IKSolver(model, [[frame]], [mink.ConfigurationLimit(model)], damping=1e-4)
    solver.step(configuration, DT)
    with pytest.raises(QpikError, match="damping"):
        solver.damping = value
    assert solver.damping == 1e-4
    assert np.isfinite(solver.step(configuration, DT).velocity).all()
    solver.damping = 1e-3
    assert (
        solver.damping == 1e-3 and solver.build(configuration, DT).levels[0].regularization == 1e-3
    )


def _frame_case(cls, configuration):
    """A task on link7 (a relative one: the ee site in link0), the target 5 cm away, and
    the attribute to change with its new value."""
    if cls in (qpik.tasks.RelativeFrameTask, mink.RelativeFrameTask):
        task = cls("ee", "site", "link0", "body", position_cost=1.0, orientation_cost=1.0)
        task.set_target(mink.SE3.from_translation(np.array([0.4, 0.1, 0.5])))
        return task, ("root_name", "link1")
    p = configuration.frame_pose("link7", "body")[0] + 0.05
    if cls is qpik.tasks.PositionTask:
        task = cls("link7", "body")
        task.set_target(p)
    else:
        task = cls("link7", "body", position_cost=1.0, orientation_cost=1.0)
        task.set_target(mink.SE3.from_translation(p))
    return task, ("frame_name", "link5")


@pytest.mark.parametrize(
    "cls",
    [
        qpik.tasks.FrameTask,
        mink.FrameTask,
        qpik.tasks.PositionTask,
        qpik.tasks.RelativeFrameTask,
        mink.RelativeFrameTask,
    ],
)
def test_a_frame_changed_after_the_build_is_the_one_the_step_tracks(cls):
    """A task's frame (its name, a relative task's root) set to another frame after
    the solver was built: the compiled step no longer answers for the frame it was built
    with (it did, silently: a wrong answer); it answers for the new one, with the bits of a
    solver built after the change (its plan made again), as the QP path does to round-off;
    set back, the compiled step (its lane) answers again, with its first bits."""
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    task, (name, other) = _frame_case(cls, configuration)
    solver = qpik.IKSolver(model, [[task]], [mink.ConfigurationLimit(model)])
    solver.step(configuration, DT)
    before = solver.step(configuration, DT).velocity.copy()
    assert solver._plan._plain_data is configuration.data
    original = getattr(task, name)
    setattr(task, name, other)
    changed = solver.step(configuration, DT).velocity
    fresh = qpik.IKSolver(model, [[task]], [mink.ConfigurationLimit(model)])
    np.testing.assert_array_equal(changed, fresh.step(configuration, DT).velocity)
    reference = solver.qp_solution(configuration, DT).velocity
    np.testing.assert_allclose(changed, reference, rtol=0, atol=1e-12)
    assert np.abs(changed - before).max() > 1e-3
    setattr(task, name, original)
    solver.step(configuration, DT)
    np.testing.assert_array_equal(solver.step(configuration, DT).velocity, before)
    assert solver._plan._plain_data is configuration.data


def _mink_frame(configuration, offset=(0.001, 0.0, 0.0)):
    task = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    p, R = configuration.frame_pose("ee")
    rotation = mink.SO3.from_matrix(R)
    task.set_target(mink.SE3.from_rotation_and_translation(rotation, p + np.asarray(offset)))
    return task


def _gain_limits(model, kind):
    if kind == "none":
        return []
    if kind == "box":
        return [mink.ConfigurationLimit(model)]
    return [mink.ConfigurationLimit(model), qpik.limits.model_collision_limit(model)]


@pytest.mark.parametrize("solver", ["auto", "osqp"])
@pytest.mark.parametrize("limits", ["none", "box", "general rows"])
def test_a_gain_set_out_of_range_after_the_build_is_invalid_gain(solver, limits):
    """A task gain changed after the solver was built to what the constructors refuse
    (-1, 2, NaN): InvalidGain at assignment for qpik's tasks (the solver used it as is
    before: a velocity -1 or 2 times the gain-1 one), at the next step for mink's own
    classes (their gains are guarded on the compiled step, checked where they are written
    and on the QP path), on every path; a valid new gain is used, as by a new solver."""
    from qpik.errors import InvalidGain

    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    ours = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    ours.set_target(_mink_frame(configuration).transform_target_to_world)
    ik = qpik.IKSolver(model, [[ours]], _gain_limits(model, limits), solver=solver)
    ik.step(configuration, DT)
    for gain in (-1.0, 2.0):
        with pytest.raises(InvalidGain, match="FrameTask 'ee'"):
            ours.gain = gain
    assert ours.gain == 1.0
    frame = _mink_frame(configuration)
    posture = mink.PostureTask(model, cost=0.1)
    posture.set_target(model.key_qpos[0])
    ik = qpik.IKSolver(model, [[frame], [posture]], _gain_limits(model, limits), solver=solver)
    ik.step(configuration, DT)
    ik.step(configuration, DT)  # (the lane, where it applies)
    for task, label in ((frame, "FrameTask 'ee'"), (posture, "PostureTask")):
        for gain in (-1.0, 2.0, np.nan):
            task.gain = gain
            with pytest.raises(InvalidGain, match=label):
                ik.step(configuration, DT)
            with pytest.raises(InvalidGain, match=label):
                ik.qp_solution(configuration, DT)
        task.gain = 0.5
        fresh = qpik.IKSolver(model, ik.levels, ik.limits, solver=solver)
        np.testing.assert_allclose(
            ik.step(configuration, DT).velocity,
            fresh.step(configuration, DT).velocity,
            rtol=0,
            atol=1e-9,
        )
        # a valid new gain: the kernel takes the step itself (its lean result), no guard
        if solver == "auto" and limits != "general rows":
            assert "_src" in ik.step(configuration, DT).__dict__
        task.gain = 1.0


@pytest.mark.parametrize("solver", ["auto", "osqp"])
def test_a_mink_frame_target_that_is_not_an_se3_is_invalid_target(solver):
    """mink's FrameTask.set_target takes anything: a 4x4 matrix as its target raised
    AttributeError ('wxyz_xyz') from the plan's gather; now InvalidTarget naming the task,
    on the compiled step and on the QP path."""
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    frame = _mink_frame(configuration)
    ik = qpik.IKSolver(model, [[frame]], solver=solver)
    ik.step(configuration, DT)
    frame.set_target(np.eye(4))
    with pytest.raises(qpik.InvalidTarget, match="FrameTask 'ee'.*mink.SE3"):
        ik.step(configuration, DT)
    with pytest.raises(qpik.InvalidTarget, match="FrameTask 'ee'.*mink.SE3"):
        ik.qp_solution(configuration, DT)


def test_a_mink_frame_target_with_a_zero_quaternion_is_invalid_target_where_qpik_reads_it():
    """mink's FrameTask with a zero-quaternion target (no rotation; its orientation error
    reads 0): InvalidTarget naming the task where qpik's Python reads the target (the QP
    path, a forced backend's compiled rows). qpik's own FrameTask refuses it at set_target
    (tests/tasks/test_tasks.py)."""
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    p = configuration.frame_pose("ee")[0]
    frame = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    frame.set_target(mink.SE3(np.r_[0.0, 0.0, 0.0, 0.0, p]))
    ik = qpik.IKSolver(model, [[frame]])
    with pytest.raises(qpik.InvalidTarget, match="zero quaternion"):
        ik.qp_solution(configuration, DT)
    with pytest.raises(qpik.InvalidTarget, match="zero quaternion"):
        qpik.IKSolver(model, [[frame]], solver="osqp").step(configuration, DT)


def test_a_mink_frame_target_with_a_zero_quaternion_on_the_default_step():
    """The default solver's compiled step with mink's own FrameTask and a zero-quaternion
    target: the kernel declines it (Kernel.load_sources: code -1) and the general way names
    it (InvalidTarget), also after steps that took the lean way with a valid target."""
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    p = configuration.frame_pose("ee")[0]
    frame = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    frame.set_target(mink.SE3(np.r_[0.0, 0.0, 0.0, 0.0, p]))
    with pytest.raises(qpik.InvalidTarget):
        qpik.IKSolver(model, [[frame]]).step(configuration, DT)
    frame.set_target(mink.SE3(np.r_[1.0, 0.0, 0.0, 0.0, p]))
    solver = qpik.IKSolver(model, [[frame]])
    for _ in range(3):
        solver.step(configuration, DT)
    frame.set_target(mink.SE3(np.r_[0.0, 0.0, 0.0, 0.0, p]))
    with pytest.raises(qpik.InvalidTarget):
        solver.step(configuration, DT)
