"""Random IK stacks on real robots, every level checked against an independent reference.

Each stack: 1-3 levels of 1-2 frame tasks on random bodies (position, with or without
orientation; targets 0.2 m away, often out of reach), over a posture; position and velocity
limits; three closed-loop steps. Exact mode (``damping=0``, ``damping_law=None``) and
constant damping (``1e-6``): every level must end ``solved`` and, level by level, be no
worse than quadprog's answer with the levels above held at qpik's task values
(``tests/exactness_oracle.py``), with no row violated. The exact mode found the defect of
``test_exact_mode_unreachable_rows.py`` (a link one joint turns).

Not here: erd's iCub and Tiago, where two upper levels can have singular values just above
the rank cutoff (1.2e-9, 7.4e-8): the null space they leave rotates by about 1e-3 between
two exact methods, and the posture level's objective then differs from the reference's by a
few per cent (each answer optimal in its own null space)."""

from __future__ import annotations

from collections import Counter

import mink
import mujoco
import numpy as np
import pytest
from conftest import load_or_skip, requires_erd
from exactness_oracle import Problem
from test_exactness import compare

import qpik
from qpik.core import HierarchySolver, LevelStatus
from qpik.limits import velocity_limit_from_model
from qpik.tasks import FrameTask, PostureTask

pytestmark = [pytest.mark.slow, requires_erd]


def _oracle_problem(solver: qpik.IKSolver, configuration, dt: float) -> tuple:
    """The step's core problem and the same levels for the oracle (row weights folded)."""
    problem = solver.build(configuration, dt)
    levels = []
    for level in problem.levels:
        w = level.weights
        A, b = (level.A, level.b) if w is None else (level.A * w[:, None], level.b * w)
        levels.append((A, b, float(level.regularization)))
    return problem, Problem(levels, problem.lb, problem.ub, problem.G, problem.h, "ik", True)


@pytest.mark.parametrize("damping", [0.0, 1e-6])
@pytest.mark.parametrize("name", ["erd:panda", "erd:ur5", "erd:talos", "erd:romeo"])
def test_random_stacks_are_solved_and_no_worse_than_the_reference(name, damping):
    model = load_or_skip(name)
    bodies = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i) for i in range(1, model.nbody)]
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    rng = np.random.default_rng(20261203)
    total = Counter()
    for _ in range(25):
        levels = []
        for _ in range(int(rng.integers(1, 4))):
            levels.append([
                FrameTask(
                    bodies[int(rng.integers(len(bodies)))], "body", position_cost=1.0,
                    orientation_cost=float(rng.choice([0.0, 1.0])),
                )
                for _ in range(int(rng.integers(1, 3)))
            ])  # fmt: skip
        posture = PostureTask(model, 0.1)
        posture.set_target(model.qpos0)
        levels.append([posture])
        solver = qpik.IKSolver(model, levels, limits, damping=damping, damping_law=None)
        configuration = qpik.Configuration(model, qpik.Configuration(model).mid_q())
        for _ in range(3):
            for level in levels[:-1]:
                for task in level:
                    p, R = configuration.frame_pose(task.frame_name, "body")
                    target = mink.SE3.from_rotation_and_translation(
                        mink.SO3.from_matrix(R), p + rng.normal(size=3) * 0.2
                    )
                    task.set_target(target)
            result = solver.step(configuration, 0.01)
            assert all(s is LevelStatus.SOLVED for s in result.status), (
                [s.value for s in result.status],
                [c.stationarity for c in result.certificate],
                [[t.frame_name for t in lv] for lv in levels[:-1]],
            )
            problem, oracle = _oracle_problem(solver, configuration, 0.01)
            total += compare(oracle, HierarchySolver(damping_law=None).solve(problem))
            configuration.integrate_inplace(result.velocity, 0.01)
    assert total["worse"] == 0 and total["violation"] == 0, total
    assert total["compared"] >= 0.8 * total["solved"], total
