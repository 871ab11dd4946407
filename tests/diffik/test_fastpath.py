"""mink's own tasks in the one-call step (qpik.diffik.compiled), and the forced-backend shortcut of
qpik.solve_ik: rows equal mink's, answers equal the general path's."""

from __future__ import annotations

import zlib

import mink
import numpy as np
import pytest
from conftest import three_link_arm

import qpik
from qpik.limits import velocity_limit_from_model

DT = 0.01


def _qp_step(solver: qpik.IKSolver, configuration) -> qpik.StepResult:
    """The step by the QP path (the tasks' and limits' own rows, then the core's cascade)."""
    return qpik.StepResult.of(solver._qp_step(configuration, DT), 0.0)


@pytest.fixture(scope="module")
def panda():
    model = qpik.load_robot("panda")
    return model, qpik.Configuration(model)


def _random_state(rng, model, configuration, tasks, reach=0.3):
    """A random configuration within the limits, and random targets for ``tasks``."""
    home = model.key_qpos[0]
    q = np.clip(home + rng.uniform(-0.6, 0.6, model.nv), configuration.lower, configuration.upper)
    configuration.update(q)
    for task in tasks:
        if isinstance(task, mink.FrameTask):
            pose = configuration.get_transform_frame_to_world(task.frame_name, task.frame_type)
            offset = mink.SE3.exp(rng.normal(size=6) * reach)
            task.set_target(pose @ offset)
        elif isinstance(task, mink.PostureTask) and not isinstance(task, mink.DampingTask):
            task.set_target(
                np.clip(q + rng.uniform(-1, 1, model.nv), configuration.lower, configuration.upper)
            )


def _mink_tasks(model):
    return [
        mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=0.3, lm_damping=0.5),
        mink.FrameTask("link5", "body", position_cost=[1.0, 0.5, 2.0], orientation_cost=0.0),
        mink.PostureTask(model, cost=np.linspace(0.01, 0.1, model.nv), gain=0.7),
        mink.DampingTask(model, cost=np.linspace(0.2, 0.5, model.nv)),
        qpik.tasks.DampingTask(model, cost=0.1),
    ]


def test_minks_tasks_rows_equal_minks_objective(panda):
    """Each task as its own level: the compiled rows' objective ``A^T A + mu I``,
    ``-A^T b`` equals mink's compute_qp_objective to 1e-12."""
    model, configuration = panda
    rng = np.random.default_rng(5)
    tasks = _mink_tasks(model)
    damping = 1e-3
    solver = qpik.IKSolver(model, [[t] for t in tasks], [mink.ConfigurationLimit(model)],
                           damping=damping)  # fmt: skip
    plan = solver._plan
    assert plan is not None
    for _ in range(30):
        _random_state(rng, model, configuration, tasks)
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
            np.testing.assert_array_equal(a["w"][starts[k] : starts[k + 1]], task.cost)


@pytest.mark.parametrize("solver_name", ["auto", "quadprog"])
def test_minks_tasks_compiled_step_equals_the_general_path(panda, solver_name):
    pytest.importorskip("quadprog")
    model, configuration = panda
    rng = np.random.default_rng(11)
    tasks = _mink_tasks(model)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    levels = [[tasks[0]], [tasks[1], tasks[3]], [tasks[2], tasks[4]]]
    solver = qpik.IKSolver(model, levels, limits, solver=solver_name)
    assert solver._plan is not None
    for _ in range(30):
        _random_state(rng, model, configuration, tasks)
        fused = solver.step(configuration, DT)
        general = _qp_step(solver, configuration)
        np.testing.assert_allclose(fused.displacement, general.displacement, rtol=0, atol=1e-12)
        assert fused.status == general.status


def test_the_compiled_step_carries_every_levels_certificate(panda):
    """The one-call step returns the certificate of each level (it once came back empty:
    the binding cut the info array to its first five rows), equal to the general path's
    to round-off, and ``solved`` levels are certified."""
    model, configuration = panda
    rng = np.random.default_rng(3)
    tasks = _mink_tasks(model)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    levels = [[tasks[0]], [tasks[1], tasks[3]], [tasks[2], tasks[4]]]
    solver = qpik.IKSolver(model, levels, limits)
    assert solver._plan is not None
    for _ in range(20):
        _random_state(rng, model, configuration, tasks)
        fused = solver.step(configuration, DT)
        general = _qp_step(solver, configuration)
        assert len(fused.certificate) == len(levels) == len(general.certificate)
        for status, ours, theirs in zip(fused.status, fused.certificate, general.certificate):
            values = np.array([ours.primal, ours.stationarity, ours.dual, ours.complementarity])
            reference = np.array(
                [theirs.primal, theirs.stationarity, theirs.dual, theirs.complementarity]
            )
            assert np.all(np.isfinite(values))
            np.testing.assert_allclose(values, reference, rtol=0, atol=1e-9)
            if status == "solved":
                assert values.max() <= qpik.core.CERTIFICATE_TOLERANCE


@pytest.mark.parametrize("backend", ["quadprog", "daqp", "osqp"])
def test_forced_backend_shortcut_gives_the_forced_paths_answer(panda, backend):
    """qpik.solve_ik's solvers answer a forced backend by the exact one-call step when it
    solves every level: the forced path's displacement (bitwise where no limit binds, to
    round-off where one does: the same active-set solve, the cascade's sums in C++)."""
    pytest.importorskip(backend)
    model, configuration = panda
    rng = np.random.default_rng(17)
    tasks = _mink_tasks(model)[:3]
    slow = mink.VelocityLimit(model, {model.joint(j).name: 0.3 for j in range(7)})
    for limits in ([mink.ConfigurationLimit(model)], [mink.ConfigurationLimit(model), slow]):
        for levels in ([tasks], [[tasks[0]], [tasks[1]], [tasks[2]]]):
            solver = qpik.IKSolver(model, levels, limits, solver=backend, damping=1e-4)
            shortcut = qpik.IKSolver(model, levels, limits, solver=backend, damping=1e-4)
            shortcut.exact_shortcut = True
            bound = 0
            for _ in range(25):
                _random_state(rng, model, configuration, tasks, reach=0.5)
                a = solver.step(configuration, DT)
                b = shortcut.step(configuration, DT)
                np.testing.assert_allclose(a.displacement, b.displacement, rtol=0, atol=1e-12)
                assert a.status == b.status
                bound += bool(a.active_limits)
            if len(limits) > 1:
                assert bound > 0  # the limits did bind in some steps


def test_solve_ik_with_minks_tasks_matches_mink(panda):
    model, configuration = panda
    rng = np.random.default_rng(23)
    tasks = _mink_tasks(model)[:4]
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    for _ in range(20):
        _random_state(rng, model, configuration, tasks, reach=0.1)
        ours = qpik.solve_ik(configuration, tasks, DT, "quadprog", 1e-3, limits=limits)
        theirs = mink.solve_ik(configuration, tasks, DT, "quadprog", 1e-3, limits=limits)
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-8)


def test_unknown_task_types_still_use_their_own_methods(panda):
    """A subclass of mink's FrameTask (its own rows) and a custom task work at any level
    through their methods: the compiled step takes their rows from them."""
    model, configuration = panda
    configuration.update(model.key_qpos[0])

    class Shifted(mink.FrameTask):
        def _error_and_jacobian(self, configuration):
            error, jacobian = super()._error_and_jacobian(configuration)
            return error + 0.01, jacobian

    class Zero(mink.Task):
        def __init__(self):
            super().__init__(cost=np.ones(2), gain=1.0)

        def compute_error(self, configuration):
            return configuration.q[:2] - 0.1

        def compute_jacobian(self, configuration):
            return np.eye(2, model.nv)

    frame = Shifted("ee", "site", position_cost=1.0, orientation_cost=1.0)
    frame.set_target_from_configuration(configuration)
    posture = mink.PostureTask(model, cost=0.1)
    posture.set_target(model.key_qpos[0])
    plain = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    plain.set_target_from_configuration(configuration)
    for levels in ([[frame], [posture]], [[Zero()], [frame, posture]]):
        solver = qpik.IKSolver(model, levels, [mink.ConfigurationLimit(model)])
        assert solver._plan is not None
        supplied = [task for task, _, _ in solver._plan.rows_tasks]
        assert frame in supplied and posture not in supplied
        result = solver.step(configuration, DT)
        assert result.ok
        swapped = [[plain if t is frame else t for t in level] for level in levels]
        reference = qpik.IKSolver(model, swapped, [mink.ConfigurationLimit(model)])
        # the subclass's own error was used: the step differs from the plain task's
        assert (
            np.abs(result.displacement - reference.step(configuration, DT).displacement).max()
            > 1e-6
        )


@pytest.mark.parametrize("solver_name", ["auto", "quadprog"])
def test_collision_limits_take_the_compiled_rows_with_the_general_paths_answer(solver_name):
    """mink's CollisionAvoidanceLimit in a plan: its rows from its own methods, the tasks'
    rows and the box compiled; bitwise the general path's answer (qpik's tasks), and equal
    to round-off with the forced-backend shortcut."""
    pytest.importorskip("quadprog")
    import mujoco

    xml = """
    <mujoco>
      <worldbody>
        <geom name="floor" type="plane" size="2 2 0.1"/>
        <geom name="post" type="capsule" fromto="0.35 0 0 0.35 0 0.6" size="0.05"/>
        <body name="l1" pos="0 0 0.3">
          <joint name="j1" type="hinge" axis="0 0 1" range="-3 3"/>
          <geom name="g1" type="capsule" fromto="0 0 0 0.25 0 0" size="0.04"/>
          <body name="l2" pos="0.25 0 0">
            <joint name="j2" type="hinge" axis="0 1 0" range="-2.5 2.5"/>
            <geom name="g2" type="capsule" fromto="0 0 0 0.25 0 0" size="0.04"/>
            <body name="l3" pos="0.25 0 0">
              <joint name="j3" type="hinge" axis="0 1 0" range="-2.5 2.5"/>
              <geom name="g3" type="capsule" fromto="0 0 0 0.15 0 0" size="0.03"/>
              <site name="tip" pos="0.15 0 0"/>
            </body>
          </body>
        </body>
      </worldbody>
    </mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    configuration = qpik.Configuration(model, np.zeros(model.nq))
    pairs = [(["g2", "g3"], ["floor", "post"])]
    collision = mink.CollisionAvoidanceLimit(
        model, pairs, minimum_distance_from_collisions=0.05, collision_detection_distance=0.3
    )
    limits = [mink.ConfigurationLimit(model), collision,
              mink.VelocityLimit(model, {"j1": 2.0, "j2": 2.0, "j3": 2.0})]  # fmt: skip
    rng = np.random.default_rng(3)
    for frame_class in (qpik.tasks.FrameTask, mink.FrameTask):
        frame = frame_class("tip", "site", position_cost=1.0, orientation_cost=0.0)
        posture = qpik.tasks.PostureTask(model, cost=1e-2)
        solver = qpik.IKSolver(model, [[frame], [posture]], limits, solver=solver_name)
        assert solver._plan is not None and solver._plan.general_limits == [collision]
        shortcut = qpik.IKSolver(model, [[frame], [posture]], limits, solver=solver_name)
        shortcut.exact_shortcut = True
        rows_seen = 0
        for _ in range(40):
            q = rng.uniform(-1.5, 1.5, model.nq)
            configuration.update(q)
            target = configuration.get_transform_frame_to_world("tip", "site")
            frame.set_target(mink.SE3.from_translation(rng.uniform(-0.3, 0.3, 3)) @ target)
            posture.set_target(np.zeros(model.nq))
            try:
                general = _qp_step(solver, configuration)
            except qpik.QpikError:
                continue
            fused = solver.step(configuration, DT)
            if frame_class is qpik.tasks.FrameTask:
                assert np.array_equal(fused.displacement, general.displacement)
            else:
                np.testing.assert_allclose(fused.displacement, general.displacement, atol=1e-12)
            assert fused.status == general.status
            assert fused.active_limits == general.active_limits
            other = shortcut.step(configuration, DT)
            np.testing.assert_allclose(other.displacement, general.displacement, atol=1e-12)
            rows = solver._plan.limits.general_rows(
                solver._plan.general_limits, configuration, DT
            )  # None: a one-dof row, general path
            rows_seen += rows is not None and rows[0].shape[0] > 0
        assert rows_seen > 0


def test_the_core_solvers_warm_start_api(panda):
    """The core solver's public warm start: ``active_sets`` after a solve, ``warm_sets``
    only with warm starts on and the shape matching, ``warm_start_from`` and ``reset``;
    the compiled step keeps its active sets there, as the QP path does."""
    levels = [qpik.core.Level(np.eye(3), np.array([2.0, 0.0, -2.0]))]
    box = (-np.ones(3), np.ones(3))
    warm = qpik.core.HierarchySolver(warm_start=True)
    cold = qpik.core.HierarchySolver()
    assert warm.active_sets is None and warm.warm_sets(1, 3) is None
    for core in (warm, cold):
        core.solve(qpik.core.HierarchyProblem(levels, *box, np.zeros((0, 3)), np.zeros(0)))
        assert core.active_sets is not None and core.active_sets.shape == (1, 3)
    assert warm.warm_sets(1, 3) is warm.active_sets and warm.warm_sets(2, 3) is None
    assert cold.warm_sets(1, 3) is None
    given = np.zeros((1, 3), dtype=np.int8)
    warm.warm_start_from(given)
    assert warm.active_sets is given
    warm.reset()
    assert warm.active_sets is None
    model, configuration = panda
    task = mink.FrameTask("ee", "site", 1.0, 1.0)
    task.set_target(configuration.get_transform_frame_to_world("ee", "site"))
    solver = qpik.IKSolver(model, [[task]], [mink.ConfigurationLimit(model)], warm_start=True)
    assert solver._plan is not None
    solver.step(configuration, DT)
    assert solver._core.active_sets.shape == (1, model.nv)


@pytest.mark.parametrize("backend", [None, "quadprog"])
def test_solve_ik_kept_solver_shortcut_is_the_full_paths_answer(panda, backend):
    """qpik.solve_ik with a kept solver answers by SolverCache.velocity (the compiled
    step on a mink.Configuration read in place, no result object): bitwise the answer of
    the full path (a fresh solver's step on the configuration's qpik view)."""
    pytest.importorskip("quadprog")
    model, _ = panda
    configuration = mink.Configuration(model)
    rng = np.random.default_rng(29)
    tasks = _mink_tasks(model)[:3]
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    qpik.clear_caches()
    for _ in range(15):
        q = model.key_qpos[0] + rng.uniform(-0.4, 0.4, model.nq)
        configuration.update(q)
        _random_state(rng, model, qpik.Configuration.sharing(configuration), tasks, reach=0.3)
        ours = qpik.solve_ik(configuration, tasks, DT, backend, 1e-3, limits=limits)
        fresh = qpik.IKSolver(model, [tasks], limits, damping=1e-3, max_joint_speed=None,
                              **({"solver": backend} if backend else {}))  # fmt: skip
        fresh.exact_shortcut = True
        full = fresh.step(qpik.Configuration.sharing(configuration), DT)
        assert np.array_equal(ours, full.velocity)
        assert qpik.solve_ik(configuration, tasks, DT, backend, 1e-3, limits=limits) is not ours
    assert len(qpik.diffik.mink_compat.SOLVERS) == 1


# ------------------------------------------------- rows supplied by the task itself
#: A chain with joint and tendon couplings (qpik's CouplingTask level) and a connect
#: constraint (mink's EqualityConstraintTask).
COUPLED = (
    """
<mujoco>
  <option jacobian="sparse"/>
  <worldbody>
"""
    + three_link_arm()
    + """    <body name="d" pos="0 0.6 0">
      <joint name="d1" axis="0 0 1" range="-1 1"/>
      <joint name="d2" axis="0 1 0" range="-1 1"/>
      <geom type="capsule" fromto="0 0 0 0 -0.3 0" size="0.02"/>
      <site name="dtip" pos="0 -0.3 0"/>
    </body>
  </worldbody>
  <tendon>
    <fixed name="t1"><joint joint="a1" coef="0.5"/><joint joint="d1" coef="-1"/></fixed>
    <fixed name="t2"><joint joint="d2" coef="2"/></fixed>
  </tendon>
  <equality>
    <joint name="poly" joint1="c1" joint2="b1" polycoef="0.05 0.5 0.2 -0.1 0.03"/>
    <tendon name="ten" tendon1="t1" tendon2="t2" polycoef="0 0.7 0.1 0 0"/>
    <connect name="loop" body1="d" body2="c" anchor="0 -0.3 0"/>
  </equality>
</mujoco>
"""
)


def _supplied(solver: qpik.IKSolver) -> list:
    """The tasks whose rows the solver's plan takes from their own methods."""
    assert solver._plan is not None
    return [task for task, _, _ in solver._plan.rows_tasks]


def _compiled_equals_qp(solver: qpik.IKSolver, configuration, compiled: bool = True) -> None:
    """One step by :meth:`IKSolver.step`: the compiled step answered (the QP path was not
    called; ``compiled=False``: it was), with the QP path's velocity (to 1e-12), statuses
    and certificates."""
    calls = []
    qp_step = solver._qp_step

    def counted(*args):
        calls.append(1)
        return qp_step(*args)

    solver._qp_step = counted  # type: ignore[method-assign]
    try:
        fused = solver.step(configuration, DT)
    finally:
        del solver._qp_step
    assert bool(calls) is not compiled
    general = qpik.StepResult.of(solver._qp_step(configuration, DT), 0.0, solver._coupling_level)
    # (two computations of one answer, the rows summed in other orders: round-off, which an
    # ill-conditioned level amplifies; 1e-11 of the velocity's size, at least 1e-11 rad/s.
    # The DoF-freezing stack over 15,000 random states: at most 3.7e-12 of it.)
    scale = max(1.0, float(np.abs(general.velocity).max()))
    np.testing.assert_allclose(fused.velocity, general.velocity, rtol=0, atol=1e-11 * scale)
    assert fused.status == general.status
    for ours, theirs in zip(fused.certificate, general.certificate, strict=True):
        np.testing.assert_allclose(
            [ours.primal, ours.stationarity, ours.dual, ours.complementarity],
            [theirs.primal, theirs.stationarity, theirs.dual, theirs.complementarity],
            rtol=0, atol=1e-9,
        )  # fmt: skip


def _random_targets(rng, model, configuration, tasks) -> None:
    """Random targets near the current pose for qpik's pose tasks (and mink's, see
    :func:`_random_state`)."""
    for task in tasks:
        if isinstance(task, (qpik.tasks.PositionTask, qpik.tasks.PoseTask)) or isinstance(
            task, qpik.tasks.OrientationTask
        ):
            position, rotation = configuration.frame_pose(task.frame_name, task.frame_type)
            turn = mink.SO3.exp(rng.normal(size=3) * 0.3).as_matrix()
            position = position + rng.normal(size=3) * 0.1
            if isinstance(task, qpik.tasks.PositionTask):
                task.set_target(position)
            elif isinstance(task, qpik.tasks.OrientationTask):
                task.set_target(turn @ rotation)
            else:
                task.set_target(position, turn @ rotation)


def _panda_kind(name: str, model):
    if name == "position":
        return qpik.tasks.PositionTask("ee", "site", cost=[1.0, 0.5, 2.0], lm_damping=0.3)
    if name == "orientation":
        return qpik.tasks.OrientationTask("ee", "site", cost=0.7, gain=0.8)
    if name == "pose":
        return qpik.tasks.PoseTask("ee", "site", 1.0, 0.4, lm_damping=0.2)
    if name == "dof_freezing":
        return qpik.tasks.DofFreezingTask(model, [1, 4])
    if name == "kinetic_energy":
        task = qpik.tasks.KineticEnergyRegularizationTask(cost=1e-3)
        task.set_dt(DT)
        return task
    if name == "joint_limit_distance":
        return qpik.tasks.JointLimitDistanceTask(cost=2.0, lm_damping=0.1)
    assert name == "manipulability"
    return qpik.tasks.ManipulabilityTask("ee", "site", rows="position", cost=0.5)


@pytest.mark.parametrize(
    "kind",
    ["position", "orientation", "pose", "dof_freezing", "kinetic_energy",
     "joint_limit_distance", "manipulability"],
)  # fmt: skip
def test_tasks_that_supply_their_rows_take_the_compiled_step(panda, kind):
    """qpik's pose and secondary tasks and mink's DoF-freezing and kinetic-energy tasks
    under a frame task, above a posture: the compiled step answers, equal to the QP
    path's. qpik's world-frame pose tasks, its joint-limit distance, the DoF-freezing task
    (a linear task) and the kinetic-energy task (the factor of its (H, c), M(q) by the
    kernel) and the manipulability task are computed by the kernel itself
    (qpik/_cpp/tasks/pose.hpp, joint_limits.hpp, linear.hpp, kinetic.hpp,
    manipulability.hpp): no rows supplied."""
    model, configuration = panda
    rng = np.random.default_rng(zlib.crc32(kind.encode()))  # (hash() of a str varies by process)
    task = _panda_kind(kind, model)
    frame = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=0.1)
    posture = mink.PostureTask(model, cost=0.05)
    levels = [[frame], [task], [posture]]
    if kind == "dof_freezing":
        levels = [[task], [frame], [posture]]
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    solver = qpik.IKSolver(model, levels, limits)
    computed = ("position", "orientation", "pose", "joint_limit_distance", "dof_freezing")
    computed += ("kinetic_energy", "manipulability")
    assert _supplied(solver) == ([] if kind in computed else [task])
    for _ in range(15):
        _random_state(rng, model, configuration, [frame, posture])
        _random_targets(rng, model, configuration, [task])
        _compiled_equals_qp(solver, configuration)


@pytest.mark.parametrize("solver_name", ["auto", "quadprog"])
def test_a_stack_mixing_kinds_at_several_levels(panda, solver_name):
    """Kernel-computed and self-supplied tasks side by side on three levels, several with
    LM terms (their sum per level in the stack's order): the compiled step answers, equal
    to the QP path's."""
    pytest.importorskip("quadprog")
    model, configuration = panda
    rng = np.random.default_rng(21)
    position = qpik.tasks.PositionTask("ee", "site", cost=1.0, lm_damping=0.2)
    frame = mink.FrameTask("link5", "body", position_cost=0.5, orientation_cost=0.0,
                           lm_damping=0.1)  # fmt: skip
    orientation = qpik.tasks.OrientationTask("ee", "site", cost=0.5)
    freeze = qpik.tasks.DofFreezingTask(model, [6])
    posture = qpik.tasks.PostureTask(model, cost=0.02, lm_damping=0.05)
    energy = qpik.tasks.KineticEnergyRegularizationTask(cost=1e-4)
    energy.set_dt(DT)
    levels = [
        [position, frame],
        [orientation, freeze, posture],
        [qpik.tasks.ManipulabilityTask("ee", "site", lm_damping=0.3),
         qpik.tasks.JointLimitDistanceTask(lm_damping=0.2), energy,
         mink.DampingTask(model, cost=0.01)],
    ]  # fmt: skip
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    solver = qpik.IKSolver(model, levels, limits, solver=solver_name)
    # (the frame task and qpik's two pose tasks are the kernel's frames, the joint-limit
    # distance, the DoF freezing and the kinetic energy the kernel's too, the manipulability
    # task a fourth frame)
    assert len(_supplied(solver)) == 0 and len(solver._plan.frames) == 4
    tasks = [t for level in levels for t in level]
    for _ in range(15):
        _random_state(rng, model, configuration, tasks)
        _random_targets(rng, model, configuration, tasks)
        posture.set_target(configuration.q + rng.uniform(-0.3, 0.3, model.nv))
        _compiled_equals_qp(solver, configuration)


def test_couplings_and_equality_constraints_take_the_compiled_step():
    """qpik's coupling level (the model's joint and tendon equalities) and mink's
    EqualityConstraintTask (every equality, the connect constraint's 3 rows among them):
    the compiled step answers, equal to the QP path's. The coupling level supplies its rows;
    the equality task is the kernel's (kind 15: MuJoCo's constraint rows read by it)."""
    import mujoco

    from qpik.diffik.layout import EQUALITY_KIND

    model = mujoco.MjModel.from_xml_string(COUPLED)
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(8)
    equality = qpik.tasks.EqualityConstraintTask(model, cost=[1.0, 2.0, 0.5], lm_damping=0.1)
    position = qpik.tasks.PositionTask("tip", "site")
    posture = mink.PostureTask(model, cost=0.1)
    limits = [mink.ConfigurationLimit(model)]
    for levels in ([[position], [posture]], [[equality], [position, posture]]):
        solver = qpik.IKSolver(model, levels, limits)
        supplied = _supplied(solver)
        assert isinstance(supplied[0], qpik.tasks.CouplingTask)  # the coupling level
        assert equality not in supplied
        kinds = solver._plan.arrays["tasks"][:, 0].tolist()
        assert (EQUALITY_KIND in kinds) is (levels[0] == [equality])
        for _ in range(10):
            q = rng.uniform(-0.5, 0.5, model.nq) * 0.5
            configuration.update(q)
            position.set_target(configuration.frame_pose("tip", "site")[0] + 0.05)
            posture.set_target(q + rng.uniform(-0.2, 0.2, model.nq))
            _compiled_equals_qp(solver, configuration)


def test_an_unknown_task_supplies_its_rows_at_level_one(panda):
    """A user's task of an unknown type (mink's contract: error, Jacobian, cost, LM
    damping) at level 1 beside a kernel task: the compiled step takes its rows from its
    own methods and answers as the QP path does, a task that gives only a rank-deficient
    (H, c) too (its factor keeps a zero row for each zero eigenvalue: the same shape at every
    step). One whose rows do not have its declared count sends the step to the QP path."""
    model, configuration = panda
    rng = np.random.default_rng(4)

    class Elbow(mink.Task):
        k = 2

        def __init__(self):
            super().__init__(cost=np.array([1.0, 0.3]), gain=0.5, lm_damping=0.4)

        def compute_error(self, configuration):
            return np.sin(configuration.q[:2]) - 0.2

        def compute_jacobian(self, configuration):
            jacobian = np.zeros((2, model.nv))
            jacobian[:, :2] = np.diag(np.cos(configuration.q[:2]))
            return jacobian

    class Miscounted(Elbow):
        k = 3  # declares 3 rows, returns 2

    class Flat(mink.tasks.task.BaseTask):  # (H, c) only, H of rank 1
        def compute_qp_objective(self, configuration):
            H = np.zeros((model.nv, model.nv))
            H[0, 0] = 1.0
            return mink.Objective(H, np.zeros(model.nv))

    frame = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=0.5)
    posture = mink.PostureTask(model, cost=0.05)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    elbow = Elbow()
    solver = qpik.IKSolver(model, [[frame], [elbow, posture]], limits)
    assert _supplied(solver) == [elbow]
    for _ in range(15):
        _random_state(rng, model, configuration, [frame, posture])
        _compiled_equals_qp(solver, configuration)
    for odd, compiled in ((Miscounted(), False), (Flat(), True)):
        solver = qpik.IKSolver(model, [[frame], [odd, posture]], limits)
        assert _supplied(solver) == [odd]
        _random_state(rng, model, configuration, [frame, posture])
        _compiled_equals_qp(solver, configuration, compiled=compiled)


def test_kinetic_energy_task_of_any_cost_is_compiled(panda):
    """mink's KineticEnergyRegularizationTask (an (H, c)-only task) beside a frame task in
    one level, as mink's kinetic_energy_reg example stacks them (its default cost is 0): the
    compiled step answers at every cost, 0 included, as the QP path does (H = 0 gave a
    factor with no rows, which sent every step to the QP path: 2.2x mink's time per call).
    The kernel computes it (kind 13: zero rows at cost 0), no rows supplied."""
    from qpik.diffik.layout import KINETIC_KIND

    model, configuration = panda
    rng = np.random.default_rng(11)
    frame = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=0.0)
    energy = qpik.tasks.KineticEnergyRegularizationTask(cost=0.0)
    energy.set_dt(DT)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    solver = qpik.IKSolver(model, [[frame, energy]], limits)
    assert _supplied(solver) == []
    assert KINETIC_KIND in solver._plan.arrays["tasks"][:, 0].tolist()
    for cost in (0.0, 1e-5, 0.0, 1e-2):
        energy.cost = cost
        _random_state(rng, model, configuration, [frame])
        _compiled_equals_qp(solver, configuration)
    # mink.solve_ik's problem: one weighted level, damping 1e-12, no trust region
    energy.cost = 0.0
    _random_state(rng, model, configuration, [frame], reach=0.05)
    velocity = qpik.solve_ik(configuration, [frame, energy], DT, damping=1e-12)
    jacobian = frame.compute_jacobian(configuration)[:3]
    error = -frame.compute_error(configuration)[:3]
    closed = jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + 1e-12 * np.eye(3), error) / DT
    assert np.all(np.isfinite(velocity))
    np.testing.assert_allclose(velocity, closed, rtol=0, atol=1e-9)
