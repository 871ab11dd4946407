"""The compiled tasks-layer kernels (qpik._engine.tasks / .diffik) against the answers the
numba kernels gave, recorded in ``tests/fixtures/tasks.npz`` by
``tests/fixtures/record_tasks.py``: equal to 1e-12 (in practice bitwise; the count of
bitwise-equal outputs is printed), and wrong arguments raise ValueError."""

from __future__ import annotations

import pathlib

import numpy as np
import pytest

from qpik._engine import diffik as engine_diffik
from qpik._engine import tasks as engine_tasks
from qpik.diffik import compiled
from qpik.model import lie as _lie
from qpik.tasks import frame as fast

FIXTURE = pathlib.Path(__file__).parents[1] / "fixtures" / "tasks.npz"
STEP_ARGS = (
    "A", "b", "w", "starts", "tasks", "jac", "frames", "site_xpos", "site_xmat", "xpos",
    "xmat", "geom_xpos", "geom_xmat", "frame_data", "qpos", "posture_data", "cfg_dof",
    "cfg_data", "vel_dof", "vel_limit", "settings", "max_iter", "warm", "canonical",
)  # fmt: skip


@pytest.fixture(scope="module")
def fx():
    with np.load(FIXTURE) as data:
        return {k: data[k] for k in data.files}


class Tally:
    def __init__(self):
        self.total = self.bitwise = 0
        self.worst = 0.0

    def check(self, got, expected, what):
        got, expected = np.asarray(got), np.asarray(expected)
        assert got.shape == expected.shape, what
        self.total += 1
        # Bitwise: the same values and signs of zero (a NaN's sign bit is not compared:
        # x86 propagates an operand's NaN, whichever the compiler put first).
        numbers = ~np.isnan(expected)
        if np.array_equal(got, expected, equal_nan=True) and np.array_equal(
            np.signbit(got[numbers]), np.signbit(expected[numbers])
        ):
            self.bitwise += 1
            return
        diff = np.abs(got.astype(float) - expected.astype(float))
        finite = np.isfinite(expected)
        assert np.array_equal(np.isfinite(got), finite), what
        self.worst = max(self.worst, float(diff[finite].max(initial=0.0)))
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12, err_msg=what)

    def report(self, name):
        print(
            f"{name}: {self.bitwise}/{self.total} outputs bitwise equal, max diff {self.worst:.3g}"
        )


def test_lie_routines_equal_the_recorded_answers(fx):
    tally = Tally()
    targets, xmats, xposs, omegas = (
        fx["lie_target"],
        fx["lie_xmat"],
        fx["lie_xpos"],
        fx["lie_omega"],
    )
    for k in range(targets.shape[0]):
        frame, so3, lji = np.empty(7), np.empty(3), np.empty(9)
        log, invmul, rminus = np.empty(6), np.empty(7), np.empty(6)
        jlog, jlog_t = np.empty((6, 6)), np.empty((6, 6))
        _lie.xmat_xpos_to_wxyz_xyz(frame, xmats[k], xposs[k])
        _lie.so3_log(so3, targets[k])
        _lie.so3_ljacinv(lji, omegas[k])
        _lie.se3_log(log, targets[k])
        _lie.se3_inverse_multiply(invmul, targets[k], frame)
        _lie.se3_rminus(rminus, targets[k], frame)
        _lie.se3_jlog(jlog, invmul)
        _lie.se3_jlog(jlog_t, targets[k])
        error, fe_jlog = fast.frame_error_jlog(xmats[k], xposs[k], targets[k])
        for got, key in (
            (frame, "lie_frame"), (so3, "lie_so3_log"), (lji, "lie_so3_ljacinv"),
            (log, "lie_se3_log"), (invmul, "lie_inverse_multiply"), (rminus, "lie_rminus"),
            (jlog, "lie_jlog"), (jlog_t, "lie_jlog_target"), (error, "fe_error"),
            (fe_jlog, "fe_jlog"),
        ):  # fmt: skip
            tally.check(got, fx[key][k], f"{key}[{k}]")
    tally.report("Lie routines")
    assert tally.total == 10 * targets.shape[0]


def test_frame_rows_into_equals_the_recorded_answers(fx):
    tally = Tally()
    count, rows, nv = fx["fr_A"].shape
    for k in range(count):
        A, b = np.zeros((rows, nv)), np.zeros(rows)
        mu = fast.frame_rows_into(
            A, b, int(fx["fr_row"][k]), fx["fr_jac"][k], fx["fr_xmat"][k], fx["fr_jlog"][k],
            fx["fr_error"][k], fx["fr_cost"][k], float(fx["fr_gain"][k]), float(fx["fr_lm"][k]),
        )  # fmt: skip
        assert isinstance(mu, float)
        tally.check(A, fx["fr_A"][k], f"A[{k}]")
        tally.check(b, fx["fr_b"][k], f"b[{k}]")
        tally.check(mu, fx["fr_mu"][k], f"mu[{k}]")
    tally.report("frame_rows_into")


def _step_args(fx, prefix, s):
    args = []
    for name in STEP_ARGS:
        value = fx[prefix + name][s]
        if name == "max_iter":
            value = int(value)
        elif name == "canonical":
            value = bool(value)
        elif name in ("A", "b", "w"):
            value = np.full(value.shape, np.nan)  # every entry is written
        else:
            value = np.ascontiguousarray(value)
        args.append(value)
    return args


def kernel_call(args):
    """A recorded call (``STEP_ARGS``: a stack of frame and posture tasks on hinge joints)
    as ``(kernel, poses, warm, canonical, max_iter)``: the :class:`qpik.diffik.compiled.Kernel`
    over the recorded arrays, and its ``rows`` arguments (``step`` takes ``warm, canonical,
    max_iter`` after them)."""
    a = dict(zip(STEP_ARGS, args))
    qpos = a["qpos"]
    nv = nq = qpos.shape[0]
    posture_map = np.stack([np.zeros(nv, np.int64), np.arange(nv, dtype=np.int64)], axis=1)
    kernel = compiled.Kernel(
        a["A"], a["b"], a["w"], a["starts"], a["tasks"], a["jac"], a["frames"],
        a["frame_data"], a["posture_data"], posture_map, a["cfg_dof"], a["cfg_dof"],
        a["cfg_data"], a["vel_dof"], a["vel_limit"], a["settings"], np.zeros((0, 3, nv)),
        np.zeros(0, np.int64), np.zeros((0, 8)), np.zeros((0, 12, nv)),
        np.zeros((0, 4), np.int64), np.zeros((0, 15)), nq,
    )  # fmt: skip
    poses = (
        qpos, a["site_xpos"], a["site_xmat"], a["xpos"], a["xmat"], a["geom_xpos"],
        a["geom_xmat"], np.zeros((0, 3)), np.zeros((0, nv)), np.zeros(0),
    )  # fmt: skip
    return kernel, poses, a["warm"], a["canonical"], a["max_iter"]


def _rows(args):
    kernel, poses, *_ = kernel_call(args)
    return kernel.rows(*poses)


def _step(args):
    kernel, poses, warm, canonical, max_iter = kernel_call(args)
    return kernel.step(*poses, warm, canonical, max_iter)


@pytest.mark.parametrize("stack", ["two", "three", "flat"])
def test_kernel_rows_and_step_equal_the_recorded_answers(fx, stack):
    prefix = f"fused_{stack}_"
    tally = Tally()
    states = fx[prefix + "qpos"].shape[0]
    for s in range(states):
        args = _step_args(fx, prefix, s)
        code, reg, lb, ub = _rows(args)
        assert isinstance(code, int)
        assert code == fx[prefix + "rows_code"][s]
        tally.check(reg, fx[prefix + "rows_reg"][s], f"reg[{s}]")
        if code != compiled.CONFLICT:  # lb, ub are not defined then
            tally.check(lb, fx[prefix + "rows_lb"][s], f"lb[{s}]")
            tally.check(ub, fx[prefix + "rows_ub"][s], f"ub[{s}]")
        for j, key in enumerate(("A", "b", "w")):
            tally.check(args[j], fx[prefix + "rows_" + key][s], f"{key}[{s}]")
        args = _step_args(fx, prefix, s)
        code, d, v, info, active = _step(args)
        assert code == fx[prefix + "step_code"][s]
        assert active.dtype == np.int8 and info.dtype == np.float64
        for got, key in ((d, "d"), (v, "v"), (info, "info"), (active, "active")):
            tally.check(got, fx[prefix + "step_" + key][s], f"step {key}[{s}]")
    tally.report(f"fused ({stack}, {states} states)")
    assert tally.bitwise == tally.total


def _panda_args(fx):
    return _step_args(fx, "fused_two_", 0)


def test_wrong_shapes_raise_value_error(fx):
    with pytest.raises(ValueError):
        _lie.se3_log(np.empty(5), np.zeros(7))
    with pytest.raises(ValueError):
        _lie.se3_jlog(np.empty((6, 5)), np.array([1.0, 0, 0, 0, 0, 0, 0]))
    with pytest.raises(ValueError):
        _lie.se3_rminus(np.empty(6), np.zeros(6), np.zeros(7))
    with pytest.raises(ValueError):
        fast.frame_error_jlog(np.eye(3).ravel()[:8], np.zeros(3), np.zeros(7))
    with pytest.raises(ValueError):  # rows 3:9 do not fit in A
        fast.frame_rows_into(
            np.zeros((6, 7)), np.zeros(6), 3, np.zeros((6, 7)), np.eye(3).ravel(), np.eye(6),
            np.zeros(6), np.ones(6), 1.0, 0.0,
        )  # fmt: skip
    base = _panda_args(fx)
    bad_cases = {
        "A": np.zeros((base[0].shape[0], 6)),
        "b": np.zeros(base[1].shape[0] + 1),
        "starts": np.array([0, 3, 2], dtype=np.int64),
        "tasks": np.array([[0, 5, 0, 0]], dtype=np.int64),
        "jac": np.zeros((1, 6, 6)),
        "frames": np.array([[0, 99]], dtype=np.int64),
        "qpos": np.zeros(6),
        "cfg_dof": np.array([0, 1, 2, 3, 4, 5, 70], dtype=np.int64),
        "vel_dof": np.array([-1], dtype=np.int64),
        "settings": np.zeros(3),
        "warm": np.zeros((5, 7), dtype=np.int8),
    }
    for name, value in bad_cases.items():
        args = list(base)
        args[STEP_ARGS.index(name)] = value
        with pytest.raises(ValueError):
            _step(args)
        if name != "warm":
            with pytest.raises(ValueError):
                _rows(args)
    # Outputs are never silently copied: a float32 or read-only A is refused.
    args = list(base)
    args[0] = args[0].astype(np.float32)
    with pytest.raises(TypeError):
        _rows(args)
    frozen = np.empty(6)
    frozen.setflags(write=False)
    with pytest.raises(TypeError):
        _lie.se3_log(frozen, np.array([1.0, 0, 0, 0, 0, 0, 0]))
    assert engine_tasks.EPS == 1e-10 and engine_diffik.OK == 0


def test_boxes_equal_the_rows_box(fx):
    """``boxes`` on the columns of cfg_data (strided views, converted) gives the rows' box."""
    args = _panda_args(fx)
    code, _, lb, ub = _rows(args)
    cfg = args[STEP_ARGS.index("cfg_data")]
    qpos = args[STEP_ARGS.index("qpos")]
    lb2, ub2, bad = engine_diffik.boxes(
        qpos, float(args[20][0]), args[16], cfg[:, 0], cfg[:, 1], cfg[:, 2], args[18],
        args[19], qpos.shape[0],
    )  # fmt: skip
    assert bad == -1 and code == 0
    assert np.array_equal(lb, lb2) and np.array_equal(ub, ub2)
