"""Kernel.go's warm argument (qpik/_cpp/bind_diffik.cpp): a C-contiguous int8 ndarray is read
directly, anything else is converted as a nanobind int8 array argument; both give the same
step bits; a value that is not an array raises TypeError, a wrong shape ValueError, and None
is a cold start."""

from __future__ import annotations

import mink
import numpy as np
import pytest

import qpik
from qpik.diffik.result import resolved_info
from qpik.limits import velocity_limit_from_model

DT = 0.01


def _solver(model, configuration):
    frame = qpik.tasks.FrameTask("panda_hand_tcp", "body", position_cost=1.0, orientation_cost=1.0)
    posture = qpik.tasks.PostureTask(model, 0.1)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    solver = qpik.IKSolver(model, [[frame], [posture]], limits, warm_start=True)
    configuration.update(configuration.mid_q())
    p, R = configuration.frame_pose("panda_hand_tcp", "body")
    frame.set_target(mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(R), p + 0.3))
    posture.set_target(
        np.clip(configuration.mid_q() + 1.0, configuration.lower, configuration.upper)
    )
    solver.step(configuration, DT)
    plan = solver._plan
    assert plan is not None
    return plan


def _go(plan, warm):
    code = plan.kernel.go(DT, 1e-12, 0, warm, True, 100)
    d, v, info, active, _, defer = plan._out
    return code, d[0].copy(), resolved_info(info[0], defer[0]).copy(), active[0].copy()


def test_warm_arrays_read_directly_or_converted_give_the_same_bits():
    model = qpik.load_robot("erd:panda")
    plan = _solver(model, qpik.Configuration(model))
    L, nv = plan.levels, plan.nv
    rng = np.random.default_rng(3)
    for _ in range(5):
        warm = rng.integers(-1, 2, size=(L, nv)).astype(np.int8)
        direct = _go(plan, warm)
        converted = _go(plan, warm.astype(np.int64))  # converted to int8
        strided = _go(plan, np.asfortranarray(warm))  # not C-contiguous: converted
        for got in (converted, strided):
            assert got[0] == direct[0]
            for a, b in zip(got[1:], direct[1:]):
                assert a.tobytes() == b.tobytes()
    cold = _go(plan, None)
    zeros = _go(plan, np.zeros((L, nv), np.int8))
    assert cold[0] == zeros[0]
    for a, b in zip(cold[1:], zeros[1:]):
        assert a.tobytes() == b.tobytes()


def test_bad_warm_arguments_raise():
    model = qpik.load_robot("erd:panda")
    plan = _solver(model, qpik.Configuration(model))
    L, nv = plan.levels, plan.nv
    with pytest.raises(TypeError):
        plan.kernel.go(DT, 1e-12, 0, "warm", True, 100)
    with pytest.raises(ValueError):
        plan.kernel.go(DT, 1e-12, 0, np.zeros((L, nv + 1), np.int8), True, 100)
    with pytest.raises(ValueError):
        plan.kernel.go(DT, 1e-12, 0, np.zeros((nv, L), np.int8), True, 100)
