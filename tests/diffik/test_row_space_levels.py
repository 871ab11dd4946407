"""The floating Talos (example-robot-data) with four strict levels (feet, CoM, hands,
posture) and its position and velocity limits, in a closed loop whose CoM sways between the
feet and whose hands circle (step_time.py's first 40 steps): its CoM level binds a bound at
a quarter of them, which the row-space guess answers (row_space_guess in
qpik/_cpp/core/cascade.hpp). The compiled step equals the QP path bit for bit, every level
is solved, and where the damping law added no damping the step is the independent
lexicographic reference's where that certifies every level (quadprog level by level on the
problem IKSolver.build gives, tests/exactness_oracle.py)."""

from __future__ import annotations

import mink
import numpy as np
import pytest
from conftest import has_erd
from exactness_oracle import reference_answer

import qpik
from qpik.core import LevelStatus
from qpik.limits import velocity_limit_from_model
from qpik.tasks import ComTask, FrameTask, PostureTask

DT = 0.01
FEET = ("left_sole_link", "right_sole_link")
HANDS = ("gripper_left_base_link", "gripper_right_base_link")


@pytest.mark.skipif(not has_erd(), reason="needs qpik[robots]")
def test_talos_strict_levels_equal_the_qp_path_and_the_reference():
    model = qpik.load_robot("erd:talos", floating_base=True)
    home = model.key_qpos[0].copy()
    configuration = qpik.Configuration(model, home)
    feet = [FrameTask(f, "body", position_cost=1.0, orientation_cost=1.0) for f in FEET]
    for task in feet:
        task.set_target_from_configuration(configuration)
    com = ComTask(1.0)
    com0 = configuration.data.subtree_com[1].copy()
    hands = [FrameTask(h, "body", position_cost=1.0, orientation_cost=0.0) for h in HANDS]
    starts = [configuration.frame_pose(h, "body")[0] for h in HANDS]
    posture = PostureTask(model, 0.1)
    posture.set_target(home)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    solver = qpik.IKSolver(model, [feet, [com], hands, [posture]], limits)
    binding = compared = 0
    for k in range(40):
        com.set_target(com0 + [0.0, 0.04 * np.sin(2 * np.pi * k / 300), 0.0])
        angle = 2 * np.pi * k / 100
        circle = 0.05 * np.array([0.0, np.cos(angle) - 1.0, np.sin(angle)])
        for task, start in zip(hands, starts):
            task.set_target(mink.SE3.from_translation(start + circle))
        step = solver.step(configuration, DT)
        active = solver._core.active_sets  # (the compiled step's, before the QP path's)
        general = qpik.StepResult.of(solver._qp_step(configuration, DT), 0.0)
        assert np.array_equal(step.displacement, general.displacement), k
        assert step.status == general.status
        assert all(s is LevelStatus.SOLVED for s in step.status), (k, step.status)
        binding += bool(np.count_nonzero(active[1]))
        # (where the damping law acted, or quadprog left a level uncertified: no reference)
        x_ref = None
        if not any(step.damping):
            x_ref = reference_answer(solver.build(configuration, DT), certified_only=True)
        if x_ref is not None:
            scale = 1.0 + np.abs(x_ref).max()
            np.testing.assert_allclose(step.displacement, x_ref, atol=1e-9 * scale, rtol=0)
            compared += 1
        configuration.update(configuration.integrate(step.velocity, DT))
    assert binding >= 8, binding  # the CoM level binds a bound (11 of the 40 steps here)
    assert compared >= 30, compared
