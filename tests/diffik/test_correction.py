"""Second-order correction of a step (qpik.StepOptions.correction_passes).

A step holds its held levels' linearisation ``J dq = -gain e`` exactly, but after ``q <- q (+)
dq`` (MuJoCo's mj_integratePos) a held task keeps the remainder ``e(q (+) dq) - e(q) - J
dq``, of order ``|dq|^2``. A correction pass shifts the held levels' targets by that
remainder and solves again with the same rows and limits, so what is left is of order
``|dq|^3``: halving the step divides it by about 8 (by 4 without the correction, by 16 with
two passes). The frames' errors here are measured by MuJoCo's kinematics (positions and the
angle of the relative rotation), not by the tasks' own error functions; the limits are checked
on the integrated configuration; the correction is recomputed independently (the tasks'
``compute_error`` on the hierarchy that ``IKSolver.build`` returns, solved by the core)."""

from __future__ import annotations

import mink
import mujoco
import numpy as np
import pytest
from conftest import has_erd
from scipy.spatial.transform import Rotation
from test_couple_fastpath import MIMIC  # the same mimic chain

import qpik
from qpik.core import HierarchyProblem, HierarchySolver, Level, LevelStatus
from qpik.limits import velocity_limit_from_model
from qpik.options import StepOptions
from qpik.tasks import ComTask, FrameTask, PostureTask

DT = 0.01
FEET = ("left_sole_link", "right_sole_link")
HANDS = ("gripper_left_base_link", "gripper_right_base_link")


requires_erd = pytest.mark.skipif(not has_erd(), reason="needs qpik[robots]")


def _held(configuration, frame, kind="body", cls=FrameTask):
    """A frame task whose target is the frame's pose now."""
    task = cls(frame, kind, position_cost=1.0, orientation_cost=1.0)
    position, rotation = configuration.frame_pose(frame, kind)
    task.set_target(
        mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), position)
    )
    return task


def _frame_error(probe, q, frame, kind, position, rotation) -> float:
    """max(|p - p*| [m], angle(R*^T R) [rad]) of ``frame`` at ``q``, by MuJoCo's kinematics."""
    probe.update(q)
    p, R = probe.frame_pose(frame, kind)
    return max(
        float(np.linalg.norm(p - position)), Rotation.from_matrix(rotation.T @ R).magnitude()
    )


def _fast_step(ik, configuration):
    """``ik.step`` where it must be the compiled step's (the QP path would fail the test)."""

    def qp_path(*_args):
        pytest.fail("the step took the QP path")

    ik._corrected = ik._qp_step = qp_path
    try:
        return ik.step(configuration, DT)
    finally:
        del ik._corrected, ik._qp_step


def _solved(result) -> bool:
    return all(s == LevelStatus.SOLVED for s in result.status) and all(
        c.holds for c in result.certificate
    )


# --------------------------------------------------------------------------- options
@pytest.mark.parametrize("value", [-1, 11, 1.5, True, "1", None, np.array([1, 2])])
def test_bad_correction_passes_raise_naming_the_field(value):
    with pytest.raises(qpik.InvalidOption, match="correction_passes"):
        StepOptions(correction_passes=value)
    model = qpik.load_robot("panda")
    with pytest.raises(qpik.InvalidOption, match="correction_passes"):
        qpik.IKSolver(model, [PostureTask(model, 1.0)], correction_passes=value)


def test_correction_passes_are_an_option_field():
    assert StepOptions().correction_passes == 0
    options = StepOptions(correction_passes=np.int64(2))
    assert options.correction_passes == 2 and type(options.correction_passes) is int
    assert StepOptions().replace(correction_passes=1).correction_passes == 1
    model = qpik.load_robot("panda")
    solver = qpik.IKSolver(model, [PostureTask(model, 1.0)], correction_passes=3)
    assert solver.options.correction_passes == 3


# ------------------------------------------------------------------------ fixed arm


def _limits(model, limits: str) -> list:
    """Position limits, and the velocity limits too where ``limits`` is ``"all"``."""
    chosen = [mink.ConfigurationLimit(model)]
    if limits == "all":
        chosen.append(velocity_limit_from_model(model))
    return chosen


def _panda(
    passes=0,
    solver="auto",
    frame_class=FrameTask,
    limits="all",
    orientation=1.0,
    model=None,
    **keywords,
):
    """Panda: frame task on the site "ee" at level 0, posture at level 1 (``model``: the
    model to use, so that solvers compared share it and both take the compiled step)."""
    model = model or qpik.load_robot("panda")
    q0 = model.key_qpos[0].copy()
    configuration = qpik.Configuration(model, q0)
    frame = frame_class("ee", "site", position_cost=1.0, orientation_cost=orientation)
    posture = PostureTask(model, 0.1)
    posture.set_target(q0)
    chosen = _limits(model, limits)
    ik = qpik.IKSolver(
        model, [[frame], [posture]], chosen, solver=solver, correction_passes=passes, **keywords
    )
    return model, configuration, frame, ik


def _target(configuration, frame, scale):
    """``frame``'s target: the site's pose moved by ``scale`` (5 cm, 4 cm; 0.5 rad)."""
    p, R = configuration.frame_pose("ee", "site")
    turn = Rotation.from_rotvec(scale * np.array([0.0, 0.3, 0.4])).as_matrix()
    target_p, target_R = p + scale * np.array([0.05, -0.04, 0.03]), turn @ R
    frame.set_target(
        mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(target_R), target_p)
    )
    return target_p, target_R


@pytest.mark.parametrize("solver", ["auto", "quadprog"])
def test_arm_frame_error_after_the_step_falls_to_third_order(solver):
    """On a fixed-base arm with the frame task met at level 0, the error left after
    integrating the step is the remainder: it quarters when the step halves; corrected, it
    falls by about 8 (two passes: 16) and is far below the uncorrected one. (No limit binds
    here, so that the step scales with the target, and no constant damping, whose residual,
    of first order, would hide the third; the tests below have both.)"""
    ratios, smallest = {}, {}
    for passes in (0, 1, 2):
        model, configuration, frame, ik = _panda(
            passes, solver, limits="position", max_joint_speed=None, damping=0.0
        )
        probe = qpik.Configuration(model)
        errors, steps = [], []
        for scale in (0.08, 0.04, 0.02):
            target = _target(configuration, frame, scale)
            result = ik.step(configuration, DT)
            assert _solved(result)
            q = configuration.integrate(result.velocity, DT)
            errors.append(_frame_error(probe, q, "ee", "site", *target))
            steps.append(np.linalg.norm(result.displacement))
        assert 1.9 < steps[0] / steps[1] < 2.1 and 1.9 < steps[1] / steps[2] < 2.1
        ratios[passes] = errors[1] / errors[2]
        smallest[passes] = errors[0]
    assert 3.8 < ratios[0] < 4.2
    assert 7 < ratios[1] < 9
    assert 14 < ratios[2] < 18
    assert smallest[1] < 0.1 * smallest[0] and smallest[2] < 0.1 * smallest[1]


def test_arm_limits_hold_and_levels_stay_solved_with_corrections():
    """The frame's position held at level 0, the posture pulling joint 7 beyond its upper
    limit (from 0.05 rad below it) and joint 2 far: position and velocity limits bind; every
    corrected step keeps both (on the integrated configuration) and every level's
    certificate is solved."""
    model, configuration, frame, ik = _panda(2, orientation=0.0)
    posture = ik.levels[1][0]
    upper = model.jnt_range[:, 1]
    lower = model.jnt_range[:, 0]
    q = configuration.q.copy()
    q[6] = upper[6] - 0.05
    configuration.update(q)
    target = q.copy()
    target[6] = upper[6] + 0.5
    target[1] += 1.0  # far: the velocity limit binds
    posture.set_target(target)
    velocity = velocity_limit_from_model(model)
    vmax = np.full(model.nv, np.inf)
    vmax[velocity.indices] = velocity.limit
    bound = set()
    for k in range(80):
        _target(configuration, frame, 0.02 * np.sin(k / 10))
        result = ik.step(configuration, DT)
        assert _solved(result)
        assert np.all(np.abs(result.velocity) <= vmax * (1 + 1e-12))
        q = configuration.integrate(result.velocity, DT)
        assert np.all(q >= lower - 1e-12) and np.all(q <= upper + 1e-12)
        bound.update(name.split()[-1] for name in result.active_limits)
        configuration.update(q)
    assert {"(ConfigurationLimit)", "(VelocityLimit)"} <= bound


def test_unmet_levels_are_not_corrected():
    """An unreachable frame target (2 m away): no level is held, the corrected step is the
    uncorrected one bit for bit."""
    model, configuration, frame, plain = _panda(0)
    _, _, frame2, corrected = _panda(1, model=model)
    for f in (frame, frame2):
        f.set_target(mink.SE3.from_translation(np.array([2.0, 0.0, 0.5])))
    a = _fast_step(plain, configuration)
    b = _fast_step(corrected, configuration)
    assert np.array_equal(a.displacement, b.displacement)
    assert a.residuals == b.residuals


def _independent_correction(ik, configuration, passes=1):
    """The corrected step recomputed outside the solver: the hierarchy of ``build``, each
    held task's remainder by its own ``compute_error`` at ``q (+) dq`` (a fresh
    configuration), the shifted hierarchy solved by the core's cascade; and the held levels
    (by :func:`qpik.diffik.correction.held_levels` on the uncorrected QP-path step)."""
    from qpik.diffik.correction import held_levels
    from qpik.diffik.result import solve_rows

    tasks, limits = ik._rows(configuration, DT)
    levels_held = {
        k for k, h in enumerate(held_levels(tasks, solve_rows(ik._core, tasks, limits, DT))) if h
    }
    problem = ik.build(configuration, DT)
    core = HierarchySolver("auto", rank_tolerance=ik.rank_tolerance, damping_law=ik.damping_law)
    d = core.solve(problem).x
    probe = qpik.Configuration(ik.model)
    for _ in range(passes):
        probe.update(configuration.integrate(d / DT, DT))
        levels = []
        for k, level in enumerate(problem.levels):
            b = level.b.copy()
            if k in levels_held:
                row = 0
                for task in ik.levels[k]:
                    cost = np.broadcast_to(task.cost, task.compute_error(configuration).shape)
                    n = cost.shape[0]
                    remainder = (
                        cost * (task.compute_error(probe) - task.compute_error(configuration))
                        - level.A[row : row + n] @ d
                    )
                    b[row : row + n] -= remainder
                    row += n
            levels.append(Level(level.A, b, level.regularization, level.weights, level.name))
        shifted = HierarchyProblem(
            levels, problem.lb, problem.ub, problem.G, problem.h, problem.row_names
        )
        d = core.solve(shifted).x
    return d, levels_held


@pytest.mark.parametrize("frame_class", ["kernel", "rows"])
def test_arm_corrected_step_equals_an_independent_correction(frame_class):
    """The compiled step's correction (the kernel's errors, or for a FrameTask subclass the
    task's own rows and errors) and the QP path's equal the correction recomputed from
    ``build`` to round-off."""
    cls = FrameTask if frame_class == "kernel" else type("Sub", (FrameTask,), {})
    for passes in (1, 2):
        _, configuration, frame, ik = _panda(passes, frame_class=cls)
        assert ik._plan is not None
        for scale in (0.02, -0.015):
            _target(configuration, frame, scale)
            fast = _fast_step(ik, configuration)
            qp = ik._corrected(configuration, DT, passes)
            reference, held = _independent_correction(ik, configuration, passes)
            assert held == {0}  # the frame, not the posture
            np.testing.assert_allclose(fast.displacement, reference, atol=1e-12)
            np.testing.assert_allclose(qp.displacement, reference, atol=1e-12)


def test_corrected_step_does_not_depend_on_history():
    """Warm starts (and the steps before) change no bit of a corrected step."""
    model, configuration, frame, cold = _panda(1)
    _, _, frame2, warm = _panda(1, warm_start=True, model=model)
    states = []
    for k in range(6):
        for f in (frame, frame2):
            _target(configuration, f, 0.03 * (k + 1))
        a = _fast_step(cold, configuration)
        b = _fast_step(warm, configuration)
        assert np.array_equal(a.displacement, b.displacement)
        states.append((configuration.q.copy(), 0.03 * (k + 1), a.displacement.copy()))
        configuration.update(configuration.integrate(a.velocity, DT))
    _, fresh_configuration, frame3, fresh = _panda(1, model=model)
    for q, scale, d in reversed(states):
        fresh_configuration.update(q)
        _target(fresh_configuration, frame3, scale)
        assert np.array_equal(_fast_step(fresh, fresh_configuration).displacement, d)


# -------------------------------------------------------------------- floating Talos
def _talos(passes, limits="all", com_cost=1.0, **keywords):
    model = qpik.load_robot("erd:talos", floating_base=True)
    home = model.key_qpos[0].copy()
    configuration = qpik.Configuration(model, home)
    feet = [_held(configuration, f) for f in FEET]
    com = ComTask(com_cost)
    com.set_target(configuration.data.subtree_com[1].copy())
    hands = [FrameTask(h, "body", position_cost=1.0, orientation_cost=0.0) for h in HANDS]
    posture = PostureTask(model, 0.1)
    posture.set_target(home)
    chosen = _limits(model, limits)
    ik = qpik.IKSolver(
        model, [feet, [com], hands, [posture]], chosen, correction_passes=passes, **keywords
    )
    return model, configuration, feet, com, hands, ik


def _feet_error(probe, q, feet_poses) -> float:
    return max(_frame_error(probe, q, f, "body", p, R) for f, (p, R) in zip(FEET, feet_poses))


@requires_erd
def test_talos_feet_error_after_the_step_falls_to_third_order():
    """Floating Talos, feet held at level 0 and CoM at level 1 while the hands move: the
    feet's error after integrating the step quarters when the step halves; corrected, it
    falls by about 8 and is far below the uncorrected one; the CoM likewise."""
    ratios, largest, com_errors = {}, {}, {}
    for passes in (0, 1):
        model, configuration, _feet, com, hands, ik = _talos(
            passes, limits="position", max_joint_speed=None, damping=0.0
        )
        probe = qpik.Configuration(model)
        poses = [configuration.frame_pose(f, "body") for f in FEET]
        errors = []
        for scale in (0.4, 0.2, 0.1):
            for task, h in zip(hands, HANDS):
                p = configuration.frame_pose(h, "body")[0]
                task.set_target(mink.SE3.from_translation(p + scale * np.array([0.05, 0, 0.04])))
            result = ik.step(configuration, DT)
            assert _solved(result)
            q = configuration.integrate(result.velocity, DT)
            errors.append(_feet_error(probe, q, poses))
            if scale == 0.4:
                probe.update(q)
                com_errors[passes] = np.linalg.norm(probe.data.subtree_com[1] - com.target_com)
        ratios[passes] = errors[1] / errors[2]
        largest[passes] = errors[0]
    assert 3.0 < ratios[0] < 4.5
    assert 6.5 < ratios[1] < 10
    assert largest[1] < 0.1 * largest[0]
    assert com_errors[1] < 0.3 * com_errors[0]


@requires_erd
def test_talos_closed_loop_keeps_feet_limits_and_certificates():
    """A short closed loop (CoM sway, hands on circles, the left hand out of reach from the
    middle on), position and velocity limits and the trust region: the corrected steps keep
    the feet 5x closer than the plain ones, every limit holds on the integrated
    configuration, every level's certificate is solved, and the unreachable hand's level is
    not corrected (its residual stays as large)."""
    n = 40
    runs = {}
    for passes in (0, 1):
        model, configuration, _feet, com, hands, ik = _talos(passes)
        probe = qpik.Configuration(model)
        poses = [configuration.frame_pose(f, "body") for f in FEET]
        starts = [configuration.frame_pose(h, "body")[0] for h in HANDS]
        com0 = com.target_com.copy()
        lower, upper = ik.limits[0].lower, ik.limits[0].upper
        free = model.jnt_qposadr[1]  # the first hinge's qpos address (after the free joint)
        velocity = ik.limits[1]
        vmax = np.full(model.nv, np.pi)
        vmax[velocity.indices] = velocity.limit
        feet, hand_residuals = [], []
        for k in range(n):
            com.set_target(com0 + np.array([0.0, 0.03 * np.sin(2 * np.pi * k / n), 0.0]))
            angle = 2 * np.pi * k / 20
            circle = 0.05 * np.array([0.0, np.cos(angle) - 1.0, np.sin(angle)])
            away = np.array([0.6, 0.3, 0.2]) if k >= n // 2 else np.zeros(3)
            for task, start, extra in zip(hands, starts, (away, np.zeros(3))):
                task.set_target(mink.SE3.from_translation(start + circle + extra))
            result = ik.step(configuration, DT)
            assert _solved(result)
            assert np.all(np.abs(result.velocity) <= vmax * (1 + 1e-12))
            q = configuration.integrate(result.velocity, DT)
            assert np.all(q[free:] >= lower[free:] - 1e-12)
            assert np.all(q[free:] <= upper[free:] + 1e-12)
            feet.append(_feet_error(probe, q, poses))
            hand_residuals.append(result.residuals[2])
            configuration.update(q)
        runs[passes] = (np.mean(feet), np.array(hand_residuals))
    assert runs[1][0] < 0.2 * runs[0][0]
    out = slice(n // 2 + 2, n)  # the left hand out of reach: a level the step only approaches
    np.testing.assert_allclose(runs[1][1][out], runs[0][1][out], rtol=0.05)


@requires_erd
def test_talos_compiled_and_qp_corrections_agree_with_an_independent_one():
    """On the floating Talos (feet, CoM: the kernel's frame and CoM errors) the compiled and
    QP paths' corrections equal the independent one to round-off."""
    model, configuration, _feet, _com, hands, ik = _talos(1)
    assert ik._plan is not None
    for task, h in zip(hands, HANDS):
        p = configuration.frame_pose(h, "body")[0]
        task.set_target(mink.SE3.from_translation(p + np.array([0.01, 0.0, 0.008])))
    fast = _fast_step(ik, configuration)
    qp = ik._corrected(configuration, DT, 1)
    reference, held = _independent_correction(ik, configuration)
    assert {0, 1} <= held  # the feet and the CoM
    np.testing.assert_allclose(fast.displacement, reference, atol=1e-11)
    np.testing.assert_allclose(qp.displacement, reference, atol=1e-11)
    assert _solved(fast)


# ------------------------------------------------------------------------- couplings


def test_mimic_coupling_level_and_the_tip_are_corrected_on_both_paths():
    """A mimic (the coupling level above the stack, solved by the pair fast path) and a
    position task at the tip: the compiled correction equals the QP path's to round-off,
    the coupling still holds, the tip's error after the step falls well below the
    uncorrected one; compiled_velocity leaves a corrected solver to the QP path, whose
    ``qp_solution`` is the corrected step."""
    model = mujoco.MjModel.from_xml_string(MIMIC)
    q = np.array([0.3, 0.4, 0.05 - 0.7 * 0.4, 0.02])
    errors = {}
    for passes in (0, 1):
        configuration = qpik.Configuration(model, q)
        tip = FrameTask("tip", "site", position_cost=1.0, orientation_cost=0.0)
        p = configuration.frame_pose("tip", "site")[0]
        target = p + np.array([0.01, -0.01, 0.01])
        tip.set_target(mink.SE3.from_translation(target))
        posture = PostureTask(model, 0.01)
        posture.set_target(np.zeros(model.nq))
        ik = qpik.IKSolver(
            model, [[tip], [posture]], [mink.ConfigurationLimit(model)], correction_passes=passes
        )
        assert ik._plan is not None and ik._coupling_level
        fast = _fast_step(ik, configuration)
        assert _solved(fast) and fast.coupling_residual < 1e-12
        if passes:
            qp = ik.qp_solution(configuration, DT)
            np.testing.assert_allclose(fast.displacement, qp.displacement, atol=1e-13)
            assert ik.compiled_velocity(configuration, DT) is None
            assert ik.compiled_solution(configuration, DT) is None
        after = qpik.Configuration(model, configuration.integrate(fast.velocity, DT))
        assert abs(after.q[2] - (0.05 - 0.7 * after.q[1])) < 1e-12
        errors[passes] = np.linalg.norm(after.frame_pose("tip", "site")[0] - target)
    assert errors[1] < 0.05 * errors[0]
