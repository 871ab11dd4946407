"""The compiled model kernels (qpik._engine.model / .igm, through qpik.model.kernels)
against answers recorded from the former numba kernels (tests/fixtures/model.npz, written
by tests/fixtures/record_model.py): equal to 1e-12, and counted bitwise; and bad
arguments raise ValueError (or TypeError for a wrong dtype) instead of crashing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from qpik.igm import kernels as IGM
from qpik.model import kernels as K

FIXTURE = Path(__file__).parents[1] / "fixtures" / "model.npz"


@pytest.fixture(scope="module")
def recorded():
    return dict(np.load(FIXTURE))


def _chain(d, name):
    return tuple(d[f"chain_{name}_{i}"] for i in range(11))


class _Tally:
    """Compares got/expected pairs: 1e-12 (absolute, relative above 1) and bitwise."""

    def __init__(self):
        self.total = 0
        self.bitwise = 0
        self.worst = 0.0

    def add(self, name, got, expected):
        got = np.asarray(got)
        expected = np.asarray(expected)
        assert got.shape == expected.shape, name
        assert got.dtype.kind == expected.dtype.kind or {got.dtype.kind, expected.dtype.kind} <= {
            "i",
            "u",
        }, name
        self.total += 1
        if got.tobytes() == expected.astype(got.dtype).tobytes():
            self.bitwise += 1
            return
        if got.dtype.kind == "f":
            same_nan = np.isnan(got) == np.isnan(expected)
            assert same_nan.all(), name
            finite = np.isfinite(expected)
            assert (got[~finite] == expected[~finite]).all() or np.isnan(expected[~finite]).all(), (
                name
            )
            diff = np.abs(got[finite] - expected[finite])
            scale = np.maximum(1.0, np.abs(expected[finite]))
            worst = float((diff / scale).max()) if diff.size else 0.0
            self.worst = max(self.worst, worst)
            assert worst <= 1e-12, (name, worst)
        else:
            np.testing.assert_array_equal(got, expected, err_msg=name)


@pytest.fixture(scope="module")
def tally():
    t = _Tally()
    yield t
    print(f"\nmodel engine vs numba fixture: {t.bitwise}/{t.total} outputs bitwise equal, "
          f"max relative difference {t.worst:.3g}")  # fmt: skip


def test_kinematics(recorded, tally):
    d = recorded
    for name in ("panda", "ur5e", "planar_2r", "planar_4r"):
        chain = _chain(d, name)
        for k, q in enumerate(d[f"fk_{name}_q"]):
            nv = d[f"fk_{name}_J"].shape[2]
            p, R, J = np.empty(3), np.empty((3, 3)), np.empty((6, nv))
            K.fk_jac(chain, q, p, R, J, True)
            tally.add(f"fk {name} {k}", np.concatenate([p, R.ravel(), J.ravel()]), np.concatenate(
                [d[f"fk_{name}_p"][k], d[f"fk_{name}_R"][k].ravel(), d[f"fk_{name}_J"][k].ravel()]
            ))  # fmt: skip
            p2, R2 = np.empty(3), np.empty((3, 3))
            K.fk_jac(chain, q, p2, R2, np.empty((6, nv)), False)
            assert p2.tobytes() == p.tobytes() and R2.tobytes() == R.tobytes()
        for k, q in enumerate(d[f"fk_{name}_q"][:10]):
            center = np.empty(3)
            radius = K.reach_radius(chain, q, center)
            assert isinstance(radius, float)
            tally.add(f"reach {name} {k}", np.append(center, radius),
                      np.append(d[f"reach_{name}_center"][k], d[f"reach_{name}_radius"][k]))  # fmt: skip
    got = K.quat2mat(d["quat_in"])
    assert got.dtype == np.float64 and got.shape == (len(d["quat_in"]), 3, 3)
    tally.add("quat2mat", got, d["quat_out"])


def test_rotations(recorded, tally):
    d = recorded
    for k, R in enumerate(d["rot_in"]):
        out = np.empty(3)
        angle = K.rotation_log(np.ascontiguousarray(R), out)
        tally.add(f"log {k}", np.append(out, angle), np.append(d["rot_log"][k], d["rot_angle"][k]))
        tally.add(f"defect {k}", K.rotation_defect(R), d["rot_defect"][k])
        code = K.target_defect(d["tdef_p"][k], R, bool(d["tdef_has_rot"][k]))
        assert isinstance(code, int)
        tally.add(f"target_defect {k}", code, d["tdef_out"][k])
    for k, phi in enumerate(d["jl_in"]):
        out = np.empty((3, 3))
        K.left_jacobian_inverse(phi, out)
        tally.add(f"jl {k}", out, d["jl_out"][k])
    for k in range(len(d["sv_m"])):
        m, n = int(d["sv_m"][k]), int(d["sv_n"][k])
        A = np.ascontiguousarray(d["sv_A"][k][:, :n])
        gram = np.empty((max(6, n), max(6, n)))
        got = IGM.smallest_singular_value(A, m, n, gram, float(d["sv_thr"][k]))
        tally.add(f"sv {k}", got, d["sv_out"][k])
    # the default threshold is 0 (always computed)
    A = np.ascontiguousarray(d["sv_A"][1][:, : int(d["sv_n"][1])])
    assert np.isfinite(IGM.smallest_singular_value(A, 6, A.shape[1], np.empty((9, 9))))


def test_box_qp(recorded, tally):
    d = recorded
    for k in range(len(d["qp_status"])):
        n, cap = (int(v) for v in d["qp_n"][k])
        H = np.ascontiguousarray(d["qp_H"][k][:n, :n])
        args = (d["qp_g"][k][:n].copy(), d["qp_lb"][k][:n].copy(), d["qp_ub"][k][:n].copy())
        x = np.empty(n)
        status, iterations = IGM.box_qp(H, *args, x, cap)
        assert isinstance(status, int) and isinstance(iterations, int)
        tally.add(f"box_qp {k}", [status, iterations], [d["qp_status"][k], d["qp_iters"][k]])
        if status != 2:  # x is partial on a singular block
            tally.add(f"box_qp x {k}", x, d["qp_x"][k][:n])
        y = np.empty(n)
        assert IGM.box_qp_with(H, *args, y, cap, IGM.box_qp_workspace(n)) == (status, iterations)
        assert status == 2 or y.tobytes() == x.tobytes()


def test_uniform(recorded, tally):
    d = recorded
    for seed, expected in zip(d["rng_seeds"], d["rng_draws"]):
        state = np.array([seed], dtype=np.uint64)
        draws = [IGM.uniform(state) for _ in range(20)]
        assert all(isinstance(u, float) for u in draws)
        tally.add(f"uniform {seed}", draws + [float(state[0])], expected)


@pytest.mark.parametrize("arm", ["panda", "ur5e"])
def test_igm_solve(recorded, tally, arm):
    d = recorded
    chain, reach = _chain(d, arm), d[f"igm_{arm}_reach"]
    keys = ("p", "R", "has_rot", "q0", "bounds", "options", "int_options", "seed")
    cases = zip(*(d[f"igm_{arm}_{key}"] for key in keys))
    start = 0
    hist_all = d[f"igm_{arm}_hist"]
    for k, (p, R, has_rot, q0, bounds, fopts, iopts, seed) in enumerate(cases):
        n = int(iopts[0]) + 1
        path, hist = np.zeros((2, n, q0.shape[0])), np.zeros((2, n, 3))
        info = np.zeros(6, dtype=np.int64)
        state = np.array([seed], dtype=np.uint64)
        q_start = q0.copy()
        IGM.igm_solve(chain, p, R, bool(has_rot), q_start, bounds, reach, fopts, iopts, state,
                    np.inf, path, hist, info)  # fmt: skip
        assert q_start.tobytes() == q0.tobytes()  # the start is not written
        tally.add(f"igm {arm} {k} info", info, d[f"igm_{arm}_info"][k])
        assert state[0] == d[f"igm_{arm}_state"][k]
        slot, length = int(info[3]), int(info[4])
        tally.add(f"igm {arm} {k} q", path[slot, length - 1], d[f"igm_{arm}_q"][k])
        tally.add(f"igm {arm} {k} hist", hist[slot, :length], hist_all[start : start + length])
        tally.add(
            f"igm {arm} {k} path", path[slot, :length].sum(axis=0), d[f"igm_{arm}_path_sum"][k]
        )
        start += length
    assert start == hist_all.shape[0]


def test_igm_time_budget_uses_the_perf_counter_clock(recorded):
    """A deadline in the past (a time.perf_counter value) stops the first attempt at its
    first clock read; one far ahead never does."""
    import time

    d = recorded
    chain, reach = _chain(d, "ur5e"), d["igm_ur5e_reach"]
    p, R, q0, bounds = (d[f"igm_ur5e_{key}"][0] for key in ("p", "R", "q0", "bounds"))
    fopts = d["igm_ur5e_options"][0]
    iopts = d["igm_ur5e_int_options"][0].copy()
    iopts[3] = 1
    n = int(iopts[0]) + 1
    for deadline, expect_budget in (
        (time.perf_counter() - 1.0, True),
        (time.perf_counter() + 3600, False),
    ):
        path, hist, info = np.zeros((2, n, 6)), np.zeros((2, n, 3)), np.zeros(6, dtype=np.int64)
        q = q0.copy()
        q[0] += 0.5  # not converged at the start
        IGM.igm_solve(chain, p, R, True, q, bounds, reach, fopts, iopts, np.array([1], np.uint64),
                    deadline, path, hist, info)  # fmt: skip
        if expect_budget:
            assert info[0] == IGM.TIME_BUDGET and info[1] == 0 and info[4] == 1
        else:
            assert info[0] != IGM.TIME_BUDGET


def _igm_args(d):
    chain, reach = _chain(d, "ur5e"), d["igm_ur5e_reach"]
    p, R, q0, bounds = (d[f"igm_ur5e_{key}"][0] for key in ("p", "R", "q0", "bounds"))
    fopts, iopts = d["igm_ur5e_options"][0], d["igm_ur5e_int_options"][0]
    n = int(iopts[0]) + 1
    return dict(
        chain=chain, target_p=p, target_R=R, has_rot=True, q0=q0.copy(), bounds=bounds, reach=reach,
        options=fopts, int_options=iopts, rng_state=np.array([1], np.uint64), deadline=np.inf,
        path=np.zeros((2, n, 6)), hist=np.zeros((2, n, 3)), info=np.zeros(6, dtype=np.int64),
    )  # fmt: skip


def test_bad_arguments_raise_instead_of_crashing(recorded):
    d = recorded
    good = _igm_args(d)
    IGM.igm_solve(**good)
    bad_values = {
        "target_p": np.zeros(4),
        "target_R": np.eye(4),
        "q0": np.zeros(5),
        "bounds": good["bounds"][:3],
        "reach": np.zeros(3),
        "options": good["options"][:5],
        "int_options": good["int_options"][:2],
        "path": np.zeros((2, 3, 6)),
        "hist": np.zeros((2, good["hist"].shape[1], 2)),
        "info": np.zeros(5, dtype=np.int64),
        "rng_state": np.zeros(2, dtype=np.uint64),
    }
    for key, value in bad_values.items():
        with pytest.raises(ValueError):
            IGM.igm_solve(**{**good, key: value})
    chain = list(good["chain"])
    for index, value in ((6, chain[6] + 100), (7, chain[7] - 100), (2, chain[2][::-1].copy()),
                         (4, np.zeros((2, 3))), (1, np.zeros((3, 3)))):  # fmt: skip
        broken = chain.copy()
        broken[index] = value
        with pytest.raises(ValueError):
            IGM.igm_solve(**{**good, "chain": tuple(broken)})
    with pytest.raises(ValueError):
        IGM.igm_solve(**{**good, "chain": tuple(chain[:10])})
    with pytest.raises(ValueError):
        IGM.igm_solve(**{**good, "chain": tuple(chain[:3]) + ("x",) + tuple(chain[4:])})
    # written arrays of the wrong dtype are refused, never silently copied
    with pytest.raises(TypeError):
        IGM.igm_solve(**{**good, "info": np.zeros(6, dtype=np.int32)})
    with pytest.raises(TypeError):
        IGM.uniform(np.array([1], dtype=np.int64))
    with pytest.raises(TypeError):
        K.rotation_log(np.eye(3), np.zeros(3, dtype=np.float32))

    ur5e = _chain(d, "ur5e")
    with pytest.raises(ValueError):
        K.fk_jac(ur5e, np.zeros(6), np.empty(3), np.empty((3, 3)), np.empty((6, 5)), True)
    with pytest.raises(ValueError):
        K.fk_jac(ur5e, np.zeros(5), np.empty(3), np.empty((3, 3)), np.empty((6, 6)), True)
    with pytest.raises(ValueError):
        K.fk_jac(ur5e, np.zeros(6), np.empty(4), np.empty((3, 3)), np.empty((6, 6)), True)
    with pytest.raises(ValueError):
        K.reach_radius(ur5e, np.zeros(6), np.empty(2))
    with pytest.raises(ValueError):
        K.quat2mat(np.zeros((2, 3)))
    with pytest.raises(ValueError):
        K.rotation_log(np.eye(3)[:2].copy(), np.empty(3))
    with pytest.raises(ValueError):
        K.rotation_defect(np.eye(2))
    with pytest.raises(ValueError):
        K.target_defect(np.zeros(2), np.eye(3), True)
    with pytest.raises(ValueError):
        K.left_jacobian_inverse(np.zeros(3), np.empty((3, 2)))
    with pytest.raises(ValueError):
        IGM.box_qp(np.eye(3), np.zeros(2), -np.ones(3), np.ones(3), np.empty(3), 10)
    with pytest.raises(ValueError):
        IGM.box_qp_with(np.eye(3), np.zeros(3), -np.ones(3), np.ones(3), np.empty(3), 10,
                  IGM.box_qp_workspace(2))  # fmt: skip
    with pytest.raises(ValueError):
        IGM.box_qp_with(np.eye(3), np.zeros(3), -np.ones(3), np.ones(3), np.empty(3), 10, (1, 2))
    with pytest.raises(ValueError):
        IGM.smallest_singular_value(np.ones((6, 3)), 7, 3, np.empty((6, 6)))
    with pytest.raises(ValueError):
        IGM.smallest_singular_value(np.ones((6, 3)), 6, 3, np.empty((2, 2)))
    with pytest.raises(ValueError):
        IGM.uniform(np.zeros(2, dtype=np.uint64))


# --- the chain object (qpik._engine.model.Chain) and igm_run -------------------------------
def _compiled(d, name):
    chain = _chain(d, name)
    nq = d[f"fk_{name}_q"].shape[1]
    nv = d[f"fk_{name}_J"].shape[2]
    return K.Chain(chain, nq, nv)


def test_chain_object_gives_the_recorded_answers(recorded, tally):
    """The chain checked and copied once (K.Chain) gives the tuple's bits in every kernel."""
    d = recorded
    for name in ("panda", "ur5e", "planar_2r", "planar_4r"):
        compiled = _compiled(d, name)
        for k, q in enumerate(d[f"fk_{name}_q"]):
            nv = d[f"fk_{name}_J"].shape[2]
            p, R, J = np.empty(3), np.empty((3, 3)), np.empty((6, nv))
            K.fk_jac(compiled, q, p, R, J, True)
            tally.add(f"fk object {name} {k}", np.concatenate([p, R.ravel(), J.ravel()]),
                      np.concatenate([d[f"fk_{name}_p"][k], d[f"fk_{name}_R"][k].ravel(),
                                      d[f"fk_{name}_J"][k].ravel()]))  # fmt: skip
        for k, q in enumerate(d[f"fk_{name}_q"][:10]):
            center = np.empty(3)
            radius = K.reach_radius(compiled, q, center)
            tally.add(f"reach object {name} {k}", np.append(center, radius),
                      np.append(d[f"reach_{name}_center"][k], d[f"reach_{name}_radius"][k]))  # fmt: skip


@pytest.mark.parametrize("arm", ["panda", "ur5e"])
def test_igm_run_gives_the_recorded_answers(recorded, tally, arm):
    """igm_run (scratch allocated inside, the returned attempt's rows out) on the chain
    object: igm_solve's recorded answers, bitwise."""
    d = recorded
    keys = ("p", "R", "has_rot", "q0", "bounds", "options", "int_options", "seed")
    cases = zip(*(d[f"igm_{arm}_{key}"] for key in keys))
    compiled = K.Chain(_chain(d, arm), d[f"igm_{arm}_q0"].shape[1], d[f"igm_{arm}_q0"].shape[1])
    start = 0
    hist_all = d[f"igm_{arm}_hist"]
    for k, (p, R, has_rot, q0, bounds, fopts, iopts, seed) in enumerate(cases):
        state = np.array([seed], dtype=np.uint64)
        q_start = q0.copy()
        code, iterations, restarts, path, hist = IGM.igm_run(
            compiled, p, R, bool(has_rot), q_start, bounds, d[f"igm_{arm}_reach"], fopts, iopts,
            state, np.inf,
        )  # fmt: skip
        assert q_start.tobytes() == q0.tobytes()
        info = d[f"igm_{arm}_info"][k]
        length = int(info[4])
        assert (code, iterations, restarts) == tuple(int(v) for v in info[:3])
        assert path.shape == (length, q0.shape[0]) and hist.shape == (length, 3)
        assert state[0] == d[f"igm_{arm}_state"][k]
        tally.add(f"igm_run {arm} {k} q", path[-1], d[f"igm_{arm}_q"][k])
        tally.add(f"igm_run {arm} {k} hist", hist, hist_all[start : start + length])
        tally.add(f"igm_run {arm} {k} path", path.sum(axis=0), d[f"igm_{arm}_path_sum"][k])
        start += length
    assert start == hist_all.shape[0]


def test_chain_object_and_igm_run_refuse_bad_arguments(recorded):
    d = recorded
    chain = _chain(d, "ur5e")
    with pytest.raises(ValueError):
        K.Chain(chain[:10], 6, 6)
    with pytest.raises(ValueError):
        K.Chain(chain, 5, 6)  # a joint coordinate beyond nq
    with pytest.raises(ValueError):
        K.Chain(chain, 6, -1)
    broken = list(chain)
    broken[6] = chain[6] + 100
    with pytest.raises(ValueError):
        K.Chain(tuple(broken), 6, 6)
    compiled = K.Chain(chain, 6, 6)
    assert (compiled.nbody, compiled.njnt) == (chain[0].shape[0], chain[3].shape[0])
    with pytest.raises(ValueError):
        K.fk_jac(compiled, np.zeros(5), np.empty(3), np.empty((3, 3)), np.empty((6, 6)), True)
    with pytest.raises(ValueError):
        K.fk_jac(compiled, np.zeros(6), np.empty(3), np.empty((3, 3)), np.empty((6, 5)), True)
    with pytest.raises(ValueError):
        K.reach_radius(compiled, np.zeros(4), np.empty(3))
    good = _igm_args(d)
    args = dict(good, chain=compiled)
    for key in ("path", "hist", "info"):
        args.pop(key)
    IGM.igm_run(**args)
    for key, value in {"q0": np.zeros(5), "bounds": good["bounds"][:3], "reach": np.zeros(3),
                       "options": good["options"][:5], "int_options": good["int_options"][:2],
                       "target_p": np.zeros(4), "rng_state": np.zeros(2, np.uint64)}.items():  # fmt: skip
        with pytest.raises(ValueError):
            IGM.igm_run(**{**args, key: value})
    with pytest.raises(ValueError):
        IGM.igm_run(**{**args, "int_options": np.array([-1, 0, 5, 0])})
    with pytest.raises(ValueError):
        IGM.igm_run(**{**args, "chain": "not a chain"})


def test_start_defect():
    lower, upper = np.array([-1.0, -np.inf, 0.0]), np.array([1.0, np.inf, 0.5])
    q = np.array([1.0 + 5e-7, 7.0, -5e-7])
    assert K.start_defect(q, lower, upper, 1e-6) == (0, -1)
    np.testing.assert_array_equal(q, np.clip([1.0 + 5e-7, 7.0, -5e-7], lower, upper))
    assert K.start_defect(np.array([0.0, np.nan, 9.0]), lower, upper, 1e-6) == (1, 1)
    assert K.start_defect(np.array([0.0, 0.0, 9.0]), lower, upper, 1e-6) == (2, 2)
    with pytest.raises(ValueError):
        K.start_defect(np.zeros(2), lower, upper, 1e-6)
    with pytest.raises(TypeError):
        K.start_defect(np.zeros(3, dtype=np.float32), lower, upper, 1e-6)


def test_array_watch():
    a, b = np.arange(5.0), np.zeros((2, 3), dtype=np.int64)
    watch = K.ArrayWatch([a, b, np.zeros(0)])
    assert watch.unchanged()
    b[1, 2] = 4
    assert not watch.unchanged()
    b[1, 2] = 0
    assert watch.unchanged()
    a[0] = -0.0  # another bit pattern: a change
    assert not watch.unchanged()
    with pytest.raises(ValueError):
        K.ArrayWatch([np.zeros((3, 3))[:, 0]])  # not contiguous


def test_hessian_weights_on_a_planar_arm_and_bad_arguments():
    """``hessian_weights`` on a planar 2R arm (unit links, q2 = 0.7, tool at the tip): the
    derivative of its manipulability ``|sin q2|`` weighted as the gradient takes it, against
    the closed form ``cos q2``; wrong shapes and dofs off the model raise ValueError."""
    q2 = 0.7
    # J = [v; omega] at the tip, base frame at q1 = 0 (hinges about z)
    p1, p2 = np.array([1.0 + np.cos(q2), np.sin(q2)]), np.array([np.cos(q2), np.sin(q2)])
    jac = np.zeros((6, 2))
    jac[0], jac[1] = [-p1[1], -p2[1]], [p1[0], p2[0]]
    jac[5] = 1.0
    rows = jac[[0, 1]]
    U, s, Vt = np.linalg.svd(rows)
    weights = np.zeros((6, 2))
    weights[[0, 1]] = (U * [s[1], s[0]]) @ Vt
    out = np.empty(2)
    K.hessian_weights(jac, weights, np.array([0, 1]), out)
    np.testing.assert_allclose(out, [0.0, np.cos(q2)], atol=1e-14)
    for args in (
        (jac[:5], weights, np.array([0, 1]), out),
        (jac, weights[:, :1], np.array([0, 1]), out),
        (jac, weights, np.array([0, 2]), out),
        (jac, weights, np.array([-1]), out),
        (jac, weights, np.array([0, 1]), np.empty(3)),
    ):
        with pytest.raises(ValueError):
            K.hessian_weights(*args)
