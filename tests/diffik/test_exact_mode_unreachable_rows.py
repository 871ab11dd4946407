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


def test_relative_task_between_rigidly_attached_frames():
    """A relative-frame task between two frames no joint separates (UR5's ``tool0`` and
    ``wrist_3_link``: its rows are round-off, its target out of reach) over a posture met at
    the start: the posture level cancels level 0's round-off move, and ended kept_previous at
    stationarity 0.7 (the core problem of one such step: data/exactness/hqp_step_cancels_its_start.npz); now solved."""
    from qpik.tasks import RelativeFrameTask

    model = qpik.load_robot("erd:ur5")
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    task = RelativeFrameTask("tool0", "body", "wrist_3_link", "body", 1.0, 1.0)
    posture = PostureTask(model, 0.1)
    posture.set_target(model.qpos0)
    configuration = qpik.Configuration(model, qpik.Configuration(model).mid_q())
    rng = np.random.default_rng(0)
    for _ in range(5):
        task.set_target(mink.SE3.from_translation(rng.normal(size=3) * 0.2))
        solver = qpik.IKSolver(model, [[task], [posture]], limits)
        result = solver.step(configuration, 0.01)
        assert all(s.value == "solved" for s in result.status), result.certificate


def test_core_problem_of_a_cancelled_step_is_certified():
    """data/exactness/hqp_step_cancels_its_start.npz, cold and warm: every level solved, its
    certificate holding, level 0's task values kept by the posture level."""
    from pathlib import Path

    from qpik.core import HierarchyProblem, Level

    z = np.load(
        Path(__file__).resolve().parents[1]
        / "data"
        / "exactness"
        / "hqp_step_cancels_its_start.npz"
    )
    levels = [
        Level(z[f"A{k}"], z[f"b{k}"], float(z[f"reg{k}"]), z[f"w{k}"]) for k in range(int(z["L"]))
    ]
    problem = HierarchyProblem(levels, z["lb"], z["ub"], z["G"], z["h"])
    for warm in (False, True):
        result = HierarchySolver(damping_law=None, warm_start=warm).solve(problem)
        assert all(s.value == "solved" for s in result.status), result.certificate
        assert all(c.holds for c in result.certificate)
