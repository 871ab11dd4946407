"""Task kinds the compiled step now computes itself, where their rows were supplied from
Python at each step (issue 20: the fast path covers what users bring): qpik.solve_ik's
constraints (a frame task held as one, FrameConstraint, kind FRAME with UNIT_ROWS; a
DofFreezingTask, DofConstraint, kind LINEAR with UNIT_ROWS) and each task level's Tikhonov
term as a constant LM term; a DofFreezingTask in a level (kind LINEAR); mink's and qpik's
LookAtTask and AxisAlignTask (kinds 11 and 12). Their answers are bitwise those of the
same rows supplied from Python, mink's and the QP path's to round-off."""

from __future__ import annotations

import mink
import numpy as np
import pytest

import qpik
from qpik.diffik import mink_compat
from qpik.diffik.constraints import (
    ConstraintRows,
    DofConstraint,
    FrameConstraint,
    Tikhonov,
    constraint_level,
)
from qpik.diffik.layout import LINEAR_KIND, ROWS_KIND, UNIT_ROWS

DT = 0.01


def _setup():
    model = qpik.load_robot("panda")
    configuration = mink.Configuration(model)
    configuration.update_from_keyframe("home")
    task = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    posture = mink.PostureTask(model, cost=1e-2)
    posture.set_target(configuration.q)
    return model, configuration, task, posture


def _constraints(model, configuration, kind: str) -> list:
    held = mink.FrameTask("link3", "body", position_cost=1.0, orientation_cost=0.0)
    held.set_target_from_configuration(configuration)
    turned = qpik.tasks.FrameTask("link2", "body", position_cost=0.0, orientation_cost=1.0)
    turned.gain = 0.5
    turned.set_target_from_configuration(configuration)
    freeze = qpik.tasks.DofFreezingTask(model, dof_indices=[5, 6])
    theirs = mink.DofFreezingTask(model, dof_indices=[0, 6])
    com = mink.ComTask(cost=1.0)  # (not computed by the engine as a constraint: supplied)
    com.set_target_from_configuration(configuration)
    return {
        "frame": [held],
        "qpik frame, gain 0.5": [turned],
        "dofs": [theirs],
        "frame and dofs": [held, freeze],
        "dofs and CoM": [freeze, com],
    }[kind]


def _stack(own, levels, constraint_rows, damping):
    tikhonov = [Tikhonov(damping) for _ in levels]
    return [constraint_rows, *([*level, extra] for level, extra in zip(levels, tikhonov))]


KINDS = ["frame", "qpik frame, gain 0.5", "dofs", "frame and dofs", "dofs and CoM"]


@pytest.mark.parametrize("kind", KINDS)
def test_constraints_by_the_engine_answer_as_supplied_rows(kind):
    """A closed loop of qpik.solve_ik with constraints: each velocity bitwise the one of
    the same stack with every constraint's rows supplied from Python (ConstraintRows, a
    ROWS task of the plan), equal to mink.solve_ik's and to the QP path's to round-off;
    the plan computes the frame and DofFreezing constraints itself (UNIT_ROWS kinds) and
    holds the Tikhonov terms as constants (no task supplies rows but the CoM constraint)."""
    model, configuration, task, posture = _setup()
    constraints = _constraints(model, configuration, kind)
    start = configuration.get_transform_frame_to_world("ee", "site")
    own = mink_compat.as_configuration(configuration)
    level = constraint_level(constraints, own)
    native = [type(c) for c in level]
    supplied_ik = mink_compat._new_solver(
        own,
        _stack(own, [[task, posture]], [ConstraintRows([c], own) for c in constraints], 1e-6),
        "daqp",
        0.0,
        [mink.ConfigurationLimit(model)],
        {},
    )
    qpik.clear_caches()
    moved = 0.0
    for i in range(60):
        offset = 0.05 * np.array([np.sin(i / 4), np.cos(i / 5) - 1, np.sin(i / 3)])
        task.set_target(start.multiply(mink.SE3.from_translation(offset)))
        v = qpik.solve_ik(
            configuration, [task, posture], DT, "daqp", 1e-6,
            limits=[mink.ConfigurationLimit(model)], constraints=constraints,
        )  # fmt: skip
        supplied = supplied_ik.step(own, DT).velocity
        assert v.tobytes() == supplied.tobytes()
        theirs = mink.solve_ik(
            configuration, [task, posture], DT, "daqp", 1e-6,
            limits=[mink.ConfigurationLimit(model)], constraints=constraints,
        )  # fmt: skip
        np.testing.assert_allclose(v, theirs, rtol=0, atol=1e-8)
        moved = max(moved, float(np.abs(v).max()))
        configuration.integrate_inplace(v, DT)
    assert moved > 0.1  # (the loop moves: the constraints leave the arm free directions)
    ik = mink_compat._constrained_solver(
        own, [task, posture], "daqp", 1e-6, [mink.ConfigurationLimit(model)], constraints, {}
    )
    plan = ik._plan
    kinds = plan.arrays["tasks"][:, 0].tolist()
    assert sum(1 for k in kinds if k & UNIT_ROWS) == sum(t is not ConstraintRows for t in native)
    assert ((LINEAR_KIND | UNIT_ROWS) in kinds) == (DofConstraint in native)
    assert [type(t) for t, *_ in plan.rows_tasks] == [ConstraintRows] * native.count(ConstraintRows)
    assert kinds.count(ROWS_KIND) == len(plan.rows_tasks) + 1  # (+ the Tikhonov term)
    qp = ik.qp_solution(own, DT)
    np.testing.assert_allclose(ik.compiled_velocity(own, DT)[0], qp.velocity, rtol=0, atol=1e-9)


def test_constraint_wrappers_read_their_tasks():
    """FrameConstraint reads its task's target, gain and frame (so that the plan sees a
    change), with unit costs and no LM term; DofConstraint takes the task's Jacobian once
    (mink computes it once) and a zero residual; a level of tasks none of which the engine
    computes stays one ConstraintRows of them all."""
    model, configuration, *_ = _setup()
    own = mink_compat.as_configuration(configuration)
    held, freeze = _constraints(model, configuration, "frame and dofs")
    frame, dofs = constraint_level([held, freeze], own)
    assert type(frame) is FrameConstraint and type(dofs) is DofConstraint
    held.gain = 0.25
    assert frame.gain == 0.25 and frame.frame_name == "link3" and frame.frame_type == "body"
    assert frame.transform_target_to_world is held.transform_target_to_world
    assert np.array_equal(frame.cost, np.ones(6)) and frame.lm_damping == 0.0
    form, jacobian = dofs.linear_form
    assert np.array_equal(jacobian, freeze.compute_jacobian(configuration))
    assert not form.any() and form.shape == (2, model.nq + 1)
    with pytest.raises(ValueError):
        dofs.cost[0] = 2.0  # (read-only: the plan reads it at every step)
    com = _constraints(model, configuration, "dofs and CoM")[1]
    (level,) = constraint_level([com], own)
    assert type(level) is ConstraintRows and level.constraints == [com]


def test_a_constraint_level_takes_no_compiled_correction():
    """A plan with a constraint computed by the engine declines the compiled correction
    passes (their unit rows would need their scale at the corrected configuration): the QP
    path corrects the step, and the step is solved."""
    model, configuration, task, posture = _setup()
    own = mink_compat.as_configuration(configuration)
    held = _constraints(model, configuration, "frame")[0]
    start = configuration.get_transform_frame_to_world("ee", "site")
    task.set_target(start.multiply(mink.SE3.from_translation(np.array([0.03, 0.0, -0.02]))))
    stack = _stack(own, [[task, posture]], constraint_level([held], own), 1e-6)
    options = {"damping": 0.0, "couplings": False, "max_joint_speed": None}
    limits = [mink.ConfigurationLimit(model)]
    corrected = qpik.IKSolver(model, stack, limits, correction_passes=1, **options)
    result = corrected.step(own, DT)
    assert result.ok and np.abs(result.velocity).max() > 0.1
    assert not corrected._plan._correct(own, 0, DT, 1)
    # the QP path's corrected step: the same velocity as a solver that has no plan
    reference = qpik.IKSolver(model, stack, limits, correction_passes=1, **options)
    reference._plan = None
    assert reference.step(own, DT).velocity.tobytes() == result.velocity.tobytes()


def test_a_frame_constraint_takes_any_gain_and_names_its_task():
    """As mink and the rows supplied before: a frame constraint's gain set above 1 after the
    task was built is taken as it is (the same velocity as the supplied rows', bitwise),
    and what does not fit its rows is reported naming the user's task, not the wrapper."""
    model, configuration, task, posture = _setup()
    own = mink_compat.as_configuration(configuration)
    task.set_target_from_configuration(configuration)
    held = _constraints(model, configuration, "frame")[0]
    held.set_target(held.transform_target_to_world.multiply(
        mink.SE3.from_translation(np.array([0.01, 0.0, 0.0]))))  # fmt: skip
    held.gain = 2.0
    supplied = mink_compat._new_solver(
        own, _stack(own, [[task, posture]], [ConstraintRows([held], own)], 1e-6), "daqp", 0.0,
        None, {},
    )  # fmt: skip
    v = qpik.solve_ik(configuration, [task, posture], DT, "daqp", 1e-6, constraints=[held])
    assert np.abs(v).max() > 0.1
    assert v.tobytes() == supplied.step(own, DT).velocity.tobytes()
    held.transform_target_to_world = "x"
    with pytest.raises(qpik.InvalidTarget, match="FrameTask 'link3'"):
        qpik.solve_ik(configuration, [task, posture], DT, "daqp", 1e-6, constraints=[held])


class _OwnFreezing(mink.DofFreezingTask):
    """A subclass: not an exact type the kernel computes, so its rows are supplied."""


@pytest.mark.parametrize("make", [mink.DofFreezingTask, qpik.tasks.DofFreezingTask])
def test_a_dof_freezing_task_is_a_linear_task_of_the_kernel(make):
    """A DofFreezingTask in a level (mink's or qpik's) is a linear task of the plan (its
    Jacobian, its zero residual), not rows supplied at each step; with costs, gain and LM
    damping of its own, each step's velocity is bitwise the one of the same task's rows
    supplied from Python (a subclass), over a closed loop."""
    model, configuration, task, posture = _setup()
    own = mink_compat.as_configuration(configuration)
    start = configuration.get_transform_frame_to_world("ee", "site")
    ours, theirs = make(model, dof_indices=[1, 3]), _OwnFreezing(model, dof_indices=[1, 3])
    for t in (ours, theirs):
        t.cost = np.array([2.0, 0.5])
        t.gain, t.lm_damping = 0.7, 0.1
    solvers = [
        qpik.IKSolver(model, [[task], [t, posture]], [mink.ConfigurationLimit(model)])
        for t in (ours, theirs)
    ]
    assert not solvers[0]._plan.rows_tasks and solvers[1]._plan.rows_tasks
    assert LINEAR_KIND in solvers[0]._plan.arrays["tasks"][:, 0].tolist()
    for i in range(40):
        offset = 0.05 * np.array([np.sin(i / 4), np.cos(i / 5) - 1, np.sin(i / 3)])
        task.set_target(start.multiply(mink.SE3.from_translation(offset)))
        v, w = (s.step(own, DT).velocity for s in solvers)
        assert v.tobytes() == w.tobytes()
        own.update(own.integrate(v, DT))


class _OwnLookAt(mink.LookAtTask):
    """A subclass: its rows supplied (rows._COMPILED_RESIDUALS takes exact types only, so
    they are mink's own method's)."""


def _aim(task, kind: str, rng) -> None:
    if kind == "look_at":
        task.set_target(np.array([0.6, 0.0, 0.3]) + rng.normal(0.0, 0.2, 3))
    else:
        task.set_target(np.array([0.0, 0.3, 1.0]) + rng.normal(0.0, 0.3, 3))


@pytest.mark.parametrize("kind", ["look_at", "axis_align"])
@pytest.mark.parametrize("owner", ["mink", "qpik"])
def test_look_at_and_axis_align_are_tasks_of_the_kernel(kind, owner):
    """mink's and qpik's LookAtTask and AxisAlignTask are frames of the plan (kinds 11 and
    12: the kernel computes their rows from its own frame Jacobian, by the engine's
    look_at_residual / axis_align_residual), not rows supplied at each step: over a closed
    loop with costs, gain and LM damping of their own, each velocity is bitwise the one of
    the same rows supplied from Python (the QP path's rows, by the same engine functions),
    equal to the QP path's answer to round-off and to the rows of mink's own method (a
    subclass) to 1e-9; a plan with one leaves correction passes to the QP path."""
    from qpik.diffik.layout import AXIS_ALIGN_KIND, LOOK_AT_KIND

    model, configuration, task, posture = _setup()
    own = mink_compat.as_configuration(configuration)
    make = {
        ("mink", "look_at"): mink.LookAtTask,
        ("qpik", "look_at"): qpik.tasks.LookAtTask,
        ("mink", "axis_align"): mink.AxisAlignTask,
        ("qpik", "axis_align"): qpik.tasks.AxisAlignTask,
    }[owner, kind]
    rng = np.random.default_rng(3)
    aim = make("ee", "site", axis=np.array([0.0, 0.2, 1.0]), cost=0.7)
    aim.cost = np.array([1.0, 0.5, 2.0])  # (per row, set after the build)
    aim.gain, aim.lm_damping = 0.8, 0.05
    _aim(aim, kind, rng)
    frame = mink.FrameTask("link4", "body", position_cost=1.0, orientation_cost=0.0)
    frame.set_target_from_configuration(configuration)
    limits = [mink.ConfigurationLimit(model)]
    ik = qpik.IKSolver(model, [[frame], [aim], [posture]], limits)
    assert not ik._plan.rows_tasks
    code = LOOK_AT_KIND if kind == "look_at" else AXIS_ALIGN_KIND
    assert code in ik._plan.arrays["tasks"][:, 0].tolist()
    moved = 0.0
    for _ in range(30):
        _aim(aim, kind, rng)
        v = ik.step(own, DT).velocity.copy()
        qp = ik.qp_solution(own, DT).velocity
        assert v.tobytes() == qp.tobytes() or np.abs(v - qp).max() <= 1e-9
        moved = max(moved, float(np.abs(v).max()))
        own.update(own.integrate(v, DT))
    assert moved > 0.05
    assert not ik._plan._correct(own, 0, DT, 1)


def _moved_step(ik, own, task, start, i: int) -> np.ndarray:
    """Turn ``i`` of a closed loop: the frame task's target moved along a curve, the
    step's velocity, equal to the QP path's (bitwise, or to 1e-9)."""
    offset = 0.08 * np.array([np.sin(i / 4), np.cos(i / 5) - 1, np.sin(i / 3)])
    task.set_target(start.multiply(mink.SE3.from_translation(offset)))
    v = ik.step(own, DT).velocity.copy()
    qp = ik.qp_solution(own, DT).velocity
    assert v.tobytes() == qp.tobytes() or np.abs(v - qp).max() <= 1e-9
    return v


@pytest.mark.parametrize(
    "make", [mink.KineticEnergyRegularizationTask, qpik.tasks.KineticEnergyRegularizationTask]
)
def test_kinetic_energy_is_a_task_of_the_kernel(make):
    """A KineticEnergyRegularizationTask (mink's or qpik's) is a task of the plan (kind 13:
    the factor of (cost / dt^2) M(q), M made by the kernel), not rows supplied at each
    step: over a closed loop each velocity equals the QP path's (whose rows are the same
    engine routine's, bitwise) to round-off; its rows are M's factor to 1e-12 against
    MuJoCo's M; in one weighted level, qpik.solve_ik answers as mink.solve_ik to 1e-9; a
    cost of 0 gives zero rows, one below 0 and a missing time step raise typed errors."""
    from qpik.diffik.layout import KINETIC_KIND
    from qpik.diffik.rows import task_rows

    model, configuration, task, posture = _setup()
    own = mink_compat.as_configuration(configuration)
    start = configuration.get_transform_frame_to_world("ee", "site")
    energy = make(cost=2e-3)
    energy.set_dt(DT)
    ik = qpik.IKSolver(model, [[task], [energy, posture]], [mink.ConfigurationLimit(model)])
    assert not ik._plan.rows_tasks
    assert KINETIC_KIND in ik._plan.arrays["tasks"][:, 0].tolist()
    moved = 0.0
    for i in range(30):
        v = _moved_step(ik, own, task, start, i)
        A = task_rows(energy, own)[0]
        M = configuration.get_inertia_matrix()
        assert np.abs(A.T @ A - 2e-3 / DT**2 * M).max() <= 1e-12 * np.abs(M).max() / DT**2
        weighted = qpik.solve_ik(configuration, [task, posture, energy], DT, "daqp", 1e-6)
        theirs = mink.solve_ik(configuration, [task, posture, energy], DT, "daqp", 1e-6)
        assert np.abs(weighted - theirs).max() <= 1e-9 * max(1.0, np.abs(theirs).max())
        moved = max(moved, float(np.abs(v).max()))
        own.update(own.integrate(v, DT))
    assert moved > 0.05
    assert not ik._plan._correct(own, 0, DT, 1)  # (its correction: the QP path's)
    energy.cost = 0.0
    assert np.array_equal(task_rows(energy, own)[0], np.zeros((model.nv, model.nv)))
    assert ik.step(own, DT).velocity.shape == (model.nv,)
    energy.cost = -1.0
    with pytest.raises(qpik.TaskDefinitionError, match="KineticEnergyRegularizationTask"):
        ik.step(own, DT)
    energy.cost, energy.inv_dt_sq = 1e-3, None
    with pytest.raises(qpik.QpikError, match="set_dt"):
        ik.step(own, DT)


def test_manipulability_is_a_task_of_the_kernel():
    """qpik's ManipulabilityTask on a chain of hinges is a frame of the plan (kind 14: the
    kernel computes its row from its own frame Jacobian, by the engine's
    inverse_manipulability), not rows supplied at each step: over a closed loop each
    velocity equals the QP path's (its rows by the same routine) to round-off; its error
    and Jacobian equal NumPy's SVD with mj_jacDot's gradient (the former rows,
    qpik.model.gradients.manipulability_parts) to 1e-11 and central differences of m(q);
    rows changed after the build make the solver a new plan's (a guard), bitwise a fresh
    solver's."""
    from qpik.diffik.layout import MANIPULABILITY_KIND
    from qpik.model.gradients import manipulability_parts

    model, configuration, task, posture = _setup()
    own = mink_compat.as_configuration(configuration)
    start = configuration.get_transform_frame_to_world("ee", "site")
    manip = qpik.tasks.ManipulabilityTask("ee", "site", cost=0.5, gain=0.2, lm_damping=0.1)
    ik = qpik.IKSolver(model, [[task], [manip], [posture]], [mink.ConfigurationLimit(model)])
    assert not ik._plan.rows_tasks
    assert MANIPULABILITY_KIND in ik._plan.arrays["tasks"][:, 0].tolist()
    for i in range(25):
        v = _moved_step(ik, own, task, start, i)
        e, jacobian = manip.compute_error(own), manip.compute_jacobian(own)
        value, gradient, _ = manipulability_parts(own, "ee", "site")
        assert abs(e[0] - 1.0 / value) <= 1e-11 / value
        expected = -gradient / value**2
        assert np.abs(jacobian[0] - expected).max() <= 1e-11 * np.abs(expected).max()
        own.update(own.integrate(v, DT))
    q, h = own.q.copy(), 1e-6
    differences = np.empty(model.nv)
    for k in range(model.nv):
        values = []
        for sign in (1.0, -1.0):
            own.update(q + sign * h * np.eye(model.nv)[k])
            values.append(1.0 / manip.compute_error(own)[0])
        differences[k] = (values[0] - values[1]) / (2 * h)
    own.update(q)
    value = 1.0 / manip.compute_error(own)[0]
    np.testing.assert_allclose(-manip.compute_jacobian(own)[0] * value**2, differences, atol=1e-7)
    manip.rows = "position"  # (after the build: the plan's indices no longer the task's)
    plan = ik._plan
    v = ik.step(own, DT).velocity
    assert ik._plan is not plan  # (a guard: the plan of the task as it is now replaced it)
    fresh = qpik.IKSolver(model, [[task], [manip], [posture]], [mink.ConfigurationLimit(model)])
    assert v.tobytes() == fresh.step(own, DT).velocity.tobytes()


def test_manipulability_on_a_floating_base_is_the_kernels_too():
    """A manipulability task whose frame free and ball joints move (besides hinges and
    slides, a ball after a hinge on one body) is a task of the kernel too: the kinematic
    Hessian of any chain (hessian_weights_any, each dof's threshold from
    qpik.model.gradients.motion_chain) gives mj_jacDot's gradient (the former rows: NumPy's
    SVD and one mj_jacDot per dof, manipulability_parts) to 1e-11, for the pose and the
    position rows, and over a closed loop the step equals the QP path's."""
    import mujoco

    from qpik.diffik.layout import MANIPULABILITY_KIND
    from qpik.model.gradients import manipulability_parts

    xml = """<mujoco><worldbody><body name="base" pos="0 0 .1"><freejoint/><geom size=".1"/>
      <body name="l1" pos="0 0 .1"><joint type="ball"/>
        <geom type="capsule" fromto="0 0 0 0 0 .3" size=".03"/>
      <body name="l2" pos="0 0 .3"><joint axis="0 1 0"/><joint type="slide" axis="1 0 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 .3" size=".03"/>
      <body name="l3" pos="0 0 .3"><joint axis="1 0 0"/><joint type="ball"/><geom size=".03"/>
        <site name="tip" pos=".05 .02 .1"/></body></body></body></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(9)
    for rows in ("pose", "position"):
        manip = qpik.tasks.ManipulabilityTask("tip", "site", rows=rows, cost=0.5, lm_damping=1.0)
        assert manip.chain(configuration)[1] is not None  # (a ball or free joint moves it)
        for _ in range(20):
            q = model.qpos0 + rng.uniform(-0.7, 0.7, model.nq)
            mujoco.mj_normalizeQuat(model, q)
            configuration.update(q)
            value, gradient, _ = manipulability_parts(configuration, "tip", "site", rows=rows)
            expected = -gradient / value**2
            jacobian = manip.compute_jacobian(configuration)[0]
            assert np.abs(jacobian - expected).max() <= 1e-11 * np.abs(expected).max()
            assert abs(manip.compute_error(configuration)[0] - 1.0 / value) <= 1e-11 / value
    posture = qpik.tasks.PostureTask(model, cost=1e-2)
    posture.set_target(configuration.q)
    ik = qpik.IKSolver(model, [[manip], [posture]])
    assert not ik._plan.rows_tasks
    assert MANIPULABILITY_KIND in ik._plan.arrays["tasks"][:, 0].tolist()
    for _ in range(30):
        v = ik.step(configuration, DT).velocity.copy()
        qp = ik.qp_solution(configuration, DT).velocity
        assert v.tobytes() == qp.tobytes() or np.abs(v - qp).max() <= 1e-9
        configuration.integrate_inplace(v, DT)


_LOOP = """<mujoco><option jacobian="{jacobian}"/><worldbody>
<body name="a1"><joint name="a1" axis="0 0 1"/><geom type="capsule" fromto="0 0 0 .3 0 0" size=".02"/>
 <body name="a2" pos=".3 0 0"><joint name="a2" axis="0 0 1"/>
  <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02"/><site name="tipa" pos=".3 0 0"/></body></body>
<body name="b1" pos=".4 0 0"><joint name="b1" axis="0 0 1"/><geom type="capsule" fromto="0 0 0 0 .3 0" size=".02"/>
 <body name="b2" pos="0 .3 0"><joint name="b2" axis="0 0 1"/>
  <geom type="capsule" fromto="0 0 0 -.2 .1 0" size=".02"/></body></body>
<body name="w1" pos="0 1 0"><joint name="w1" axis="1 0 0"/><joint name="w2" axis="0 1 0"/>
 <geom type="capsule" fromto="0 0 0 0 0 .3" size=".02"/></body>
<body name="f" pos="0 1 .5"><joint name="fx" type="slide" axis="1 0 0"/><joint name="fz" axis="0 0 1"/>
 <geom size=".05"/></body>
</worldbody><equality>
<connect name="loop" body1="a2" body2="b2" anchor=".3 0 0"/>
<weld name="weld" body1="f" body2="w1" solref="0.02 1"/>
<joint name="couple" joint1="w1" joint2="a1" polycoef="0 0.5 0 0 0"/>
</equality></mujoco>"""


@pytest.mark.parametrize("jacobian", ["dense", "sparse"])
@pytest.mark.parametrize("owner", ["mink", "qpik"])
def test_equality_constraints_are_a_task_of_the_kernel(jacobian, owner):
    """mink's and qpik's EqualityConstraintTask (connect, weld and joint equalities; MuJoCo's
    dense and sparse Jacobians) are a task of the plan (kind 15: the kernel reads MuJoCo's
    constraint rows, efc_J and efc_pos), not rows supplied at each step: its rows equal
    mink's compute_qp_residual (A and b bitwise, the LM term to round-off); over a closed
    loop each velocity equals the QP path's (the same engine routine's rows) to round-off;
    qpik.solve_ik answers as mink.solve_ik to 1e-9; an equality switched off (fewer rows
    than planned) sends the step to the QP path, which answers with the rows there are."""
    import mujoco

    from qpik.diffik.layout import EQUALITY_KIND
    from qpik.diffik.rows import task_rows

    model = mujoco.MjModel.from_xml_string(_LOOP.format(jacobian=jacobian))
    configuration = mink.Configuration(model)
    configuration.update(np.array([0.5, 0.5, 1.5, 0.5, 0.1, 0.2, 0.3, 0.1]))
    make = mink.EqualityConstraintTask if owner == "mink" else qpik.tasks.EqualityConstraintTask
    equality = make(model, cost=[2.0, 1.0, 0.5], gain=0.8, lm_damping=0.05)
    posture = mink.PostureTask(model, cost=1e-2)
    target = configuration.q + 0.3
    posture.set_target(target)
    ik = qpik.IKSolver(model, [[equality], [posture]])
    assert not ik._plan.rows_tasks
    assert EQUALITY_KIND in ik._plan.arrays["tasks"][:, 0].tolist()
    assert ik._plan.arrays["eq_map"][0, 0] == 3 + 6 + 1
    own = mink_compat.as_configuration(configuration)
    start = float(np.abs(equality.compute_error(configuration)).max())
    for _ in range(30):
        A, b, mu, w = task_rows(equality, own)
        J, e, theirs = equality.compute_qp_residual(configuration)
        assert A.tobytes() == J.tobytes() and b.tobytes() == e.tobytes()
        assert abs(mu - theirs) <= 1e-15 * max(1.0, theirs)
        assert np.array_equal(w, equality.cost)
        v = ik.step(configuration, DT).velocity.copy()
        qp = ik.qp_solution(own, DT).velocity
        assert v.tobytes() == qp.tobytes() or np.abs(v - qp).max() <= 1e-9
        ours = qpik.solve_ik(configuration, [equality, posture], DT, "daqp", 1e-6)
        mink_v = mink.solve_ik(configuration, [equality, posture], DT, "daqp", 1e-6)
        assert np.abs(ours - mink_v).max() <= 1e-9 * max(1.0, np.abs(mink_v).max())
        configuration.integrate_inplace(v, DT)
    assert np.abs(equality.compute_error(configuration)).max() < 1e-3 < start  # (held)
    configuration.data.eq_active[1] = 0  # (the weld off: 4 rows where the plan has 10)
    configuration.update()
    calls = []
    qp_step = ik._qp_step
    ik._qp_step = lambda *a: calls.append(1) or qp_step(*a)  # type: ignore[method-assign]
    v = ik.step(configuration, DT).velocity
    del ik._qp_step
    assert calls and np.abs(v - ik.qp_solution(own, DT).velocity).max() <= 1e-9
    assert task_rows(equality, own)[0].shape == (4, model.nv)


def test_a_tendon_equality_is_held_on_a_qpik_configuration():
    """A tendon equality's rows need the tendons' kinematics (MuJoCo makes no row without
    mj_tendon): qpik.Configuration.update runs it before mj_makeConstraint, so the task sees
    the violation (|l1 - l2| = 0.8) and the closed loop of qpik.solve_ik (kind 15) meets it
    (newer mink's own test of the same model)."""
    import mujoco

    xml = """<mujoco><worldbody>
      <body><joint name="j1" type="slide" axis="1 0 0"/><geom size=".05" mass=".1"/></body>
      <body pos="0 1 0"><joint name="j2" type="slide" axis="1 0 0"/><geom size=".05" mass=".1"/></body>
      </worldbody><tendon><fixed name="t1"><joint joint="j1" coef="1"/></fixed>
      <fixed name="t2"><joint joint="j2" coef="1"/></fixed></tendon>
      <equality><tendon name="coupling" tendon1="t1" tendon2="t2"/></equality></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    configuration = qpik.Configuration(model, np.array([0.5, -0.3]))
    task = qpik.tasks.EqualityConstraintTask(model=model, cost=1.0)
    assert abs(abs(float(task.compute_error(configuration)[0])) - 0.8) < 1e-12
    for _ in range(100):
        velocity = qpik.solve_ik(configuration, [task], dt=0.1, solver="daqp", damping=1e-8)
        configuration.integrate_inplace(velocity, 0.1)
    lengths = configuration.data.ten_length
    assert abs(lengths[0] - lengths[1]) < 1e-6
    np.testing.assert_allclose(task.compute_error(configuration), 0.0, atol=1e-6)


def test_the_new_kinds_answer_the_same_bits_whatever_ran_before():
    """A solver with a kinetic-energy, a manipulability and a DoF-freezing task (kinds 13,
    14 and LINEAR) gives, at a state, bitwise the velocity of a fresh solver there after
    steps at other states (the kernel's scratch reused: nothing of a previous step read),
    and so does one with an equality-constraint task (kind 15)."""
    import mujoco

    def panda_solver():
        model, configuration, task, posture = _setup()
        energy = qpik.tasks.KineticEnergyRegularizationTask(cost=1e-3)
        energy.set_dt(DT)
        manip = qpik.tasks.ManipulabilityTask("ee", "site", cost=0.2, lm_damping=1.0)
        freeze = qpik.tasks.DofFreezingTask(model, dof_indices=[6])
        levels = [[task], [manip, energy], [freeze, posture]]
        start = configuration.get_transform_frame_to_world("ee", "site")
        task.set_target(start.multiply(mink.SE3.from_translation(np.array([0.05, -0.1, 0.02]))))
        return qpik.IKSolver(model, levels, [mink.ConfigurationLimit(model)]), configuration

    def loop_solver():
        model = mujoco.MjModel.from_xml_string(_LOOP.format(jacobian="sparse"))
        configuration = mink.Configuration(model)
        equality = qpik.tasks.EqualityConstraintTask(model, cost=1.0, lm_damping=0.1)
        posture = mink.PostureTask(model, cost=1e-2)
        posture.set_target(np.full(model.nq, 0.4))
        return qpik.IKSolver(model, [[equality], [posture]]), configuration

    rng = np.random.default_rng(5)
    for make in (panda_solver, loop_solver):
        ik, configuration = make()
        q = configuration.q + rng.uniform(-0.3, 0.3, configuration.model.nq)
        fresh, fresh_configuration = make()
        fresh_configuration.update(q)
        expected = fresh.step(fresh_configuration, DT).velocity.tobytes()
        for _ in range(5):  # (other states first)
            configuration.update(q + rng.uniform(-0.5, 0.5, q.size))
            ik.step(configuration, DT)
        configuration.update(q)
        assert ik.step(configuration, DT).velocity.tobytes() == expected
