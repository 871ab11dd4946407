"""Regression tests of what the fuzz campaigns of issue 25 found after seed 99 (seeds 31337,
2027, 5150 and the two leftovers of seed 99): one test per class, each checking the class's
property (a typed error naming the argument the bad value came in, every returned figure
finite or documented), cheap enough for the default run.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import qpik
from qpik import statics


# --------------------------------------------------------------------------------------
# Class (seed 99, signature:774): solve_many(robot=Configuration outside its limits) named
# q0, an argument the caller never passed; the error names the robot, as qpik.solve does.
@pytest.mark.parametrize("workers", [1, 2])
def test_solve_many_names_the_robot_whose_q_is_outside(workers: int) -> None:
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, np.zeros(model.nq))  # joint4 range < 0
    targets = [{"ee": np.array([0.4, 0.0, 0.5])}] * 2
    with pytest.raises(qpik.JointLimitViolation, match="^robot") as caught:
        qpik.solve_many(configuration, targets, workers=workers)
    assert caught.value.where.startswith("robot")
    with pytest.raises(qpik.JointLimitViolation, match="^robot"):
        qpik.solve(configuration, targets[0])
    with pytest.raises(qpik.JointLimitViolation, match="^q0"):  # an explicit q0 is q0
        qpik.solve_many(model, targets, q0=np.zeros(model.nq), workers=1)


def test_solve_many_starts_from_the_robot_q_as_solve_does() -> None:
    model = qpik.load_robot("panda")
    mid = model.jnt_range.mean(axis=1)
    configuration = qpik.Configuration(model, mid + 0.1)
    target = {"ee": np.array([0.4, 0.1, 0.5])}
    batch = qpik.solve_many(configuration, [target], workers=1, seed=3)
    seed = qpik.batch.worker.target_seed(3, 0)
    single = qpik.solve(configuration, target, seed=seed)
    assert np.array_equal(batch[0].q, single.q)


# --------------------------------------------------------------------------------------
# Class (seed 99, reading): PayloadLimit.force was NaN when no magnitude s >= 0 can be
# held. It is 0.0 then (feasible false); +inf only where no limit binds (documented).
def test_infeasible_payload_is_zero_not_nan() -> None:
    model = qpik.load_robot("ur5e")  # the motors hold its weight: nothing holds it with 0
    configuration = qpik.Configuration(model, np.array([0.0, -1.0, 1.0, 0.0, 0.5, 0.0]))
    weak = statics.max_payload(configuration, "ee", [0.0, 0.0, -1.0], np.zeros((model.nv, 2)))
    assert weak.force == 0.0 and not weak.feasible and not weak.holds_gravity
    assert not any(math.isnan(x) for x in weak.interval)
    strong = statics.max_payload(configuration, "ee", [0.0, 0.0, -1.0])
    assert strong.feasible and 0.0 < strong.force < math.inf
