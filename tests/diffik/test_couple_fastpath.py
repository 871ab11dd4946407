"""The compiled step's fast path for a coupling level of pairs (qpik/_cpp/diffik/couple.hpp):
the Panda's finger mimic and a mimic of another ratio, sign and offset. The level is solved
in closed form and the levels below on the pair's null direction; its answers equal the
general path's (the QP path: the core's cascade on every variable) to round-off and the
independent lexicographic reference (tests/exactness_oracle.py); the coupling level's
figures are those of its own answer; the step does not depend on the solver's history."""

from __future__ import annotations

from pathlib import Path

import mink
import mujoco
import numpy as np
import pytest
from conftest import three_link_arm
from exactness_oracle import Problem, lexicographic

import qpik
from qpik.core import LevelStatus
from qpik.diffik.result import StepResult
from qpik.limits import velocity_limit_from_model
from qpik.tasks import FrameTask, PostureTask

DT = 0.01

#: A chain whose only coupling is a mimic c1 = 0.05 - 0.7 b1 (a pair: the fast path), a
#: slide joint and a hinge on no coupling.
MIMIC = (
    """
<mujoco>
  <compiler angle="radian"/>
  <worldbody>
"""
    + three_link_arm("-0.5 0.5")
    + """  </worldbody>
  <equality>
    <joint name="mimic" joint1="c1" joint2="b1" polycoef="0.05 -0.7 0 0 0"/>
  </equality>
</mujoco>
"""
)


def _panda_states(rng, configuration, frame, posture, regime):
    """The benchmark's states (erd:panda): random q, a near (``free``) or far (``bind``)
    frame target, the fingers' mimic broken, held, or a finger on or beyond its limits."""
    model = configuration.model
    home = configuration.mid_q()
    q = np.clip(home + rng.uniform(-0.6, 0.6, model.nv), configuration.lower, configuration.upper)
    if rng.uniform() < 0.3:
        q[8] = q[7]
    if rng.uniform() < 0.3:
        q[7] = configuration.lower[7] + rng.choice([-0.01, 0.0, 0.01, 0.04, 0.05])
    configuration.update(q)
    p, R = configuration.frame_pose("panda_hand_tcp", "body")
    far = regime == "bind"
    p = p + rng.uniform(-1, 1, 3) * (0.3 if far else 0.001)
    rot = mink.SO3.exp(rng.uniform(-1, 1, 3) * (0.5 if far else 0.001))
    frame.set_target(mink.SE3.from_rotation_and_translation(rot @ mink.SO3.from_matrix(R), p))
    move = rng.uniform(-1.5, 1.5, model.nv) if far else 1e-4
    posture.set_target(np.clip(q + move, configuration.lower, configuration.upper))


def _mimic_states(rng, configuration, frame, posture, regime):
    model = configuration.model
    q = rng.uniform(-1.0, 1.0, model.nq) * np.array([1.5, 1.5, 0.6, 0.12])
    configuration.update(q)
    spread = 0.3 if regime == "bind" else 0.01
    position = configuration.frame_pose("tip", "site")[0] + rng.uniform(-spread, spread, 3)
    frame.set_target(mink.SE3.from_translation(position))
    posture.set_target(configuration.q + rng.uniform(-1.0, 1.0, model.nq))


def _robot(name):
    if name == "panda":
        model = qpik.load_robot("erd:panda")
        frame = FrameTask("panda_hand_tcp", "body", position_cost=1.0, orientation_cost=1.0)
        limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
        return model, frame, limits, _panda_states
    model = mujoco.MjModel.from_xml_string(MIMIC)
    frame = FrameTask("tip", "site", position_cost=1.0, orientation_cost=0.0)
    speeds = {"a1": 2.0, "b1": 1.0, "c1": 1.5, "c2": 0.3}
    limits = [mink.ConfigurationLimit(model), mink.VelocityLimit(model, speeds)]
    return model, frame, limits, _mimic_states


def _reference(solver, configuration, result):
    """The oracle's answer on the step's hierarchy (each level's regularisation with the
    damping the step applied), and whether it certified every level."""
    problem = solver.build(configuration, DT)
    lam2 = [0.0, *result.damping]  # the couplings' level is never damped here
    levels = [(lv.A, lv.b, lv.regularization + d) for lv, d in zip(problem.levels, lam2)]
    n = problem.lb.shape[0]
    xs, certified = lexicographic(
        Problem(levels, problem.lb, problem.ub, np.zeros((0, n)), np.zeros(0), "step", True)
    )
    return xs[-1], all(certified)


@pytest.mark.parametrize("name", ["panda", "mimic"])
def test_fast_path_equals_the_general_path_and_the_oracle(name):
    """Free and binding limits, couplings broken or held, a coupled joint on or beyond its
    limit: the step equals the QP path's to 1e-12 (statuses equal, every level solved), and
    the independent reference's to 1e-10 where that certified; the coupling residual is the
    one after the step."""
    model, frame, limits, states = _robot(name)
    configuration = qpik.Configuration(model)
    posture = PostureTask(model, 0.1)
    solver = qpik.IKSolver(model, [[frame], [posture]], limits)
    assert solver._plan is not None and solver._coupling_level
    couplings = solver._levels[0][0].couplings
    rng = np.random.default_rng(7)
    compared = 0
    for k in range(120):
        regime = "bind" if k % 2 else "free"
        states(rng, configuration, frame, posture, regime)
        fast = solver.step(configuration, DT)
        general = StepResult.of(solver._qp_step(configuration, DT), 0.0, True)
        assert fast.status == general.status
        assert all(s == LevelStatus.SOLVED for s in fast.status)
        assert all(c.holds for c in fast.certificate)
        scale = 1.0 + float(np.abs(general.displacement).max())
        reference, certified = _reference(solver, configuration, fast)
        gap = float(np.abs(fast.displacement - reference).max())
        if certified:
            assert gap <= 1e-10 * scale
        # The general path leaves the reference where its level below the frame found no
        # free direction (a finger on its limit: its drop_pinned); elsewhere both agree.
        if float(np.abs(general.displacement - reference).max()) <= 1e-10 * scale:
            compared += 1
            gap = float(np.abs(fast.displacement - general.displacement).max())
            assert gap <= 1e-12 * scale
            assert fast.coupling_residual == pytest.approx(general.coupling_residual, abs=1e-12)
            np.testing.assert_allclose(fast.residuals, general.residuals, rtol=0, atol=1e-12)
        q = configuration.integrate(fast.velocity, DT)
        after = float(np.linalg.norm(couplings.residual(q)))
        assert abs(after - fast.coupling_residual) <= 1e-12
    assert compared >= 100


@pytest.mark.parametrize("name", ["panda", "mimic"])
def test_fast_path_is_taken(name):
    """The coupling level never runs the dual method (its iterations are 0) where every
    coupled dof's box has width, on states where the general path runs it (a coupled
    joint's box binds); a dof held by its box (a joint beyond its limit) takes the general
    path."""
    model, frame, limits, states = _robot(name)
    configuration = qpik.Configuration(model)
    posture = PostureTask(model, 0.1)
    solver = qpik.IKSolver(model, [[frame], [posture]], limits)
    coupled = np.flatnonzero(np.abs(solver._levels[0][0].compute_jacobian(configuration)).sum(0))
    rng = np.random.default_rng(5)
    general_iterations = fast = 0
    for k in range(60):
        states(rng, configuration, frame, posture, "bind" if k % 2 else "free")
        solver.step(configuration, DT)
        info = solver._plan._out[2][solver._plan._row - 1]
        problem = solver.build(configuration, DT)
        if np.all(problem.lb[coupled] < problem.ub[coupled]):
            assert info[4][0] == 0.0  # the coupling level's iterations
            fast += 1
            general_iterations += solver._qp_step(configuration, DT).iterations[0]
    assert fast >= 30 and general_iterations > 0


@pytest.mark.parametrize("name", ["panda", "mimic"])
def test_fast_path_does_not_depend_on_history(name):
    """The same state and targets give bitwise the same step on a fresh solver and on one
    that stepped through other states (warm sets, kept storage) in between."""
    model, frame, limits, states = _robot(name)
    configuration = qpik.Configuration(model)
    posture = PostureTask(model, 0.1)
    levels = [[frame], [posture]]

    def step_at(solver, seed):
        rng = np.random.default_rng(seed)
        states(rng, configuration, frame, posture, "bind" if seed % 2 else "free")
        result = solver.step(configuration, DT)
        return (result.displacement.tobytes(), tuple(result.residuals), result.coupling_residual,
                tuple(result.status), tuple(result.certificate))  # fmt: skip

    solver = qpik.IKSolver(model, levels, limits)
    for seed in (1, 2):
        first = step_at(solver, seed)
        for other in range(100, 125):
            step_at(solver, other)
        assert step_at(solver, seed) == first
        assert step_at(qpik.IKSolver(model, levels, limits), seed) == first


@pytest.mark.parametrize("ratio, offset", [(-3.2, 0.02), (0.05, -0.1), (7.0, 0.0), (1.0, 0.0)])
def test_fast_path_on_other_ratios(ratio, offset):
    """Mimics of other ratios (either sign, small and large) and offsets, velocity limits
    tight or loose on either joint: the step equals the QP path's to 1e-12, statuses equal."""
    xml = MIMIC.replace('polycoef="0.05 -0.7 0 0 0"', f'polycoef="{offset} {ratio} 0 0 0"')
    model = mujoco.MjModel.from_xml_string(xml)
    configuration = qpik.Configuration(model)
    frame = FrameTask("tip", "site", position_cost=1.0, orientation_cost=0.0)
    posture = PostureTask(model, 0.1)
    rng = np.random.default_rng(11)
    for speeds in ({"b1": 0.05, "c1": 2.0}, {"b1": 2.0, "c1": 0.05}, {"b1": 0.5, "c1": 0.5}):
        limits = [mink.ConfigurationLimit(model), mink.VelocityLimit(model, speeds)]
        solver = qpik.IKSolver(model, [[frame], [posture]], limits)
        for k in range(15):
            q = rng.uniform(-1.0, 1.0, model.nq) * np.array([1.5, 2.2, 0.6, 0.12])
            if k % 3 == 0:
                q[2] = offset + ratio * q[1]  # the coupling held
            configuration.update(q)
            spread = 0.3 if k % 2 else 0.01
            position = configuration.frame_pose("tip", "site")[0] + rng.uniform(-spread, spread, 3)
            frame.set_target(mink.SE3.from_translation(position))
            posture.set_target(configuration.q + rng.uniform(-1.0, 1.0, model.nq))
            fast = solver.step(configuration, DT)
            general = StepResult.of(solver._qp_step(configuration, DT), 0.0, True)
            assert fast.status == general.status
            scale = 1.0 + float(np.abs(general.displacement).max())
            assert float(np.abs(fast.displacement - general.displacement).max()) <= 1e-12 * scale
            assert fast.coupling_residual == pytest.approx(general.coupling_residual, abs=1e-12)


def test_level_the_reduced_cascade_does_not_certify_goes_to_the_general_path():
    """erd Baxter (its gripper fingers' mimic, a pair: the fast path) under a CoM level, an
    orientation + CoM level, an axis-align level and a posture (tests/data/exactness/
    baxter_mimic_reduced_uncertified.npz: a state of random stacks at seed 2026). On the
    reduced variables y the second level's stationarity ended 1.01e-9, above the
    certificate's 1e-9 (kept_previous), where the general path's cascade on x certified it
    (2.9e-13). A level below that the reduced cascade does not solve leaves the step to the
    general path; the certificate of a damped level now also allows its solve's round-off
    (eps cond(B)), and the reduced cascade certifies the level itself. Either way: every level
    solved, the general path's answer to round-off."""
    from conftest import load_or_skip

    from qpik.tasks import AxisAlignTask, ComTask, OrientationTask

    model = load_or_skip("erd:baxter")
    data = Path(__file__).parents[1] / "data" / "exactness"
    case = np.load(data / "baxter_mimic_reduced_uncertified.npz")
    configuration = qpik.Configuration(model, case["q"])
    com0, com1 = ComTask(cost=1.0), ComTask(cost=1.0)
    com0.set_target(case["com0"])
    com1.set_target(case["com1"])
    orientation = OrientationTask("right_gripper_base_link", "body")
    orientation.set_target(mink.SO3.from_matrix(case["orientation"]))
    axis = AxisAlignTask("right_wrist", "body")
    axis.set_target(case["axis"])
    posture = PostureTask(model, 0.1)
    posture.set_target(case["posture"])
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    solver = qpik.IKSolver(model, [[com0], [orientation, com1], [axis], [posture]], limits)
    assert solver._plan is not None and solver._coupling_level  # the pair fast path applies
    fast = solver.step(configuration, DT)
    assert all(s is LevelStatus.SOLVED for s in fast.status), fast.status
    assert all(c.holds for c in fast.certificate)
    general = StepResult.of(solver._qp_step(configuration, DT), 0.0, True)
    assert general.status == fast.status
    scale = 1.0 + float(np.abs(general.displacement).max())
    assert float(np.abs(fast.displacement - general.displacement).max()) <= 1e-12 * scale
