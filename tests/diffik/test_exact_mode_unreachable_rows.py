"""Exact mode (``damping=0``, ``damping_law=None``) with a task whose rows no dof moves.

A pose task on ``panda_link1`` (example-robot-data's Panda): one dof turns the link, so its
three position rows are zero while their targets lie out of reach, and its yaw row is met.
The level's gradient at the answer is round-off (2e-17), and so are the sizes of the terms
that survive in it, while the least-squares solve mixes the unreachable targets (|b| ~ 0.3)
into every component: 51 of 180 such steps ended ``kept_previous`` at stationarity 1.0 (on
Talos, level 0 ``numerical_failure``). The certificate's floor for a component's scale now
also takes ``max|A| max|b|`` where the test fails on the terms alone
(``qpik/_cpp/core/certify.hpp``); the core problem of one such step is
``tests/data/exactness/hqp_rows_no_dof_moves.npz`` (solved and certified by
``test_exactness.test_reproducers_are_solved_and_certified``)."""

from __future__ import annotations

import mink
import numpy as np
import pytest
from conftest import requires_erd

import qpik
from qpik.core import HierarchySolver
from qpik.limits import velocity_limit_from_model
from qpik.tasks import FrameTask, PostureTask

pytestmark = requires_erd


@pytest.mark.parametrize("body", ["panda_link0", "panda_link1", "panda_link2"])
def test_unreachable_rows_step_is_solved(body):
    model = qpik.load_robot("erd:panda")
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    for seed in range(20):
        rng = np.random.default_rng(seed)
        task = FrameTask(body, "body", position_cost=1.0, orientation_cost=1.0)
        posture = PostureTask(model, 0.1)
        posture.set_target(model.qpos0)
        solver = qpik.IKSolver(model, [[task], [posture]], limits, damping=0.0, damping_law=None)
        configuration = qpik.Configuration(model, qpik.Configuration(model).mid_q())
        for _ in range(3):
            p, R = configuration.frame_pose(body, "body")
            offset = rng.normal(size=3) * 0.2
            target = mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(R), p + offset)
            task.set_target(target)
            result = solver.step(configuration, 0.01)
            assert all(s.value == "solved" for s in result.status), (seed, result.certificate)
            # The core's answer to the same rows: the same statuses, certified.
            core = HierarchySolver(damping_law=None).solve(solver.build(configuration, 0.01))
            assert all(s.value == "solved" for s in core.status)
            assert all(c.holds for c in core.certificate)
            configuration.integrate_inplace(result.velocity, 0.01)
