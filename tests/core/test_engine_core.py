"""The compiled core kernels (qpik._engine.core) against the numba kernels they replace:
the answers recorded in tests/fixtures/core.npz (tests/fixtures/record_core.py, run on the
numba implementation) must come back bit for bit (at worst within 1e-12 of their scale);
and a bad argument raises ValueError instead of crashing the interpreter."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from qpik.core import kernels as K

FIXTURES = Path(__file__).parents[1] / "fixtures"


def _recorder():
    spec = importlib.util.spec_from_file_location("record_core", FIXTURES / "record_core.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def recorded():
    return _recorder().load(FIXTURES / "core.npz")


def _call(kernel, case):
    """Run ``kernel`` on a recorded case's inputs; ``{field: answer}``."""
    a = {k[3:]: v for k, v in case.items() if k.startswith("in_")}
    if kernel in ("solve_qp", "solve_level"):
        extra = (bool(a["lower"]),) if kernel == "solve_level" else ()
        fn = getattr(K, kernel)
        x, st, its, act = fn(
            a["H"],
            a["c"],
            a["C"],
            a["lo"],
            a["hi"],
            a["warm"],
            int(a["max_iter"]),
            float(a["tol"]),
            *extra,
            bool(a["canonical"]),
        )
        assert type(st) is int and type(its) is int
        assert x.dtype == np.float64 and act.dtype == np.int8
        return dict(x=x, status=st, its=its, active=act)
    if kernel == "active_guess":
        return dict(guess=K.active_guess(a["x"], a["C"], a["lo"], a["hi"]))
    if kernel == "project_level":
        AZ, sig, rank, Zn = K.project_level(a["A"], a["w"], a["Z"], float(a["rank_tol"]))
        assert type(sig) is float and type(rank) is int
        return dict(AZ=AZ, sigma=sig, rank=rank, Zn=Zn)
    if kernel == "level_damping":
        t, m, e = a["law"]
        return dict(
            lam=K.level_damping(a["A"], a["b"], a["w"], a["d"], float(a["sigma"]), t, m, e),
            damping_of=K.damping_of(float(a["sigma"]), t, m),
        )
    if kernel == "reduced_qp":
        H, c, C, lo, hi = K.reduced_qp(
            a["A"],
            a["b"],
            a["AZ"],
            a["Z"],
            a["d"],
            float(a["reg"]),
            a["lb"],
            a["ub"],
            a["G"],
            a["h"],
        )
        return dict(H=H, c=c, C=C, lo=lo, hi=hi)
    if kernel == "merge_boxes":
        lb, ub, i = K.merge_boxes(a["hard_lb"], a["hard_ub"], a["pos_lb"], a["pos_ub"])
        k = i if i >= 0 else lb.shape[0]
        return dict(lb=lb[:k], ub=ub[:k], i=i)
    if kernel == "tighten":
        lb, ub = a["lb"].copy(), a["ub"].copy()
        assert K.tighten(lb, ub, a["dofs"], a["lower"], a["upper"]) is None
        return dict(lb=lb, ub=ub)
    if kernel == "solve_cascade":
        t, m, e = a["law"]
        out = K.solve_cascade(
            a["A"],
            a["b"],
            a["w"],
            a["starts"],
            a["reg"],
            a["lb"],
            a["ub"],
            a["G"],
            a["h"],
            t,
            m,
            e,
            float(a["rank_tol"]),
            int(a["max_iter"]),
            float(a["tol"]),
            a["warm"],
            bool(a["canonical"]),
        )
        names = ("dq", "status", "sigma", "lam2", "its", "active", "residuals")
        dtypes = (np.float64, np.int64, np.float64, np.float64, np.int64, np.int8, np.float64)
        for value, dtype in zip(out, dtypes):
            assert value.dtype == dtype
        return dict(zip(names, out))
    raise KeyError(kernel)


def _compare(want, got):
    """(bitwise equal, relative difference) of two answers."""
    want = np.asarray(want)
    got = np.asarray(got)
    assert want.shape == got.shape, (want.shape, got.shape)
    if want.dtype.kind in "biu":
        assert np.array_equal(want, got.astype(want.dtype)), (want, got)
        return True, 0.0
    same_nan = np.isnan(want) == np.isnan(got)
    assert same_nan.all()
    finite = np.isfinite(want)
    assert np.array_equal(want[~finite & ~np.isnan(want)], got[~finite & ~np.isnan(want)])
    bitwise = (
        np.array_equal(want.view(np.int64), got.astype(np.float64).view(np.int64))
        if want.size
        else True
    )
    if not finite.any():
        return bitwise, 0.0
    scale = max(1.0, float(np.abs(want[finite]).max()))
    return bitwise, float(np.abs(want[finite] - got[finite]).max()) / scale


KERNELS = [
    "solve_qp",
    "solve_level",
    "active_guess",
    "project_level",
    "level_damping",
    "reduced_qp",
    "merge_boxes",
    "tighten",
    "solve_cascade",
]


#: The fields of an INFEASIBLE answer of the dual method compared with the recording: its
#: status and x. Which rows it passes through before it proves a level infeasible (its
#: iterations) and the active set it stops with are the path of the proof, and the rotation of
#: J decides them in the recorded degenerate infeasible QPs (equal rows, one with lo > hi):
#: since rotate_in reflects J's columns by one Householder reflection (the numba kernels took
#: Givens rotations), a dependent row's dual direction keeps a 1e-16 round-off entry that the
#: rotations left at or below 0, and the method steps through other rows first (e.g. 4 -> 5
#: iterations in solve_qp's case 168; 70 of the 322 infeasible answers among solve_qp's and
#: solve_level's 3,360 recorded cases).
INFEASIBLE_FIELDS = ("x", "status")


def _out_of_reach(case) -> bool:
    """A recorded cascade with a general row the box keeps below its bound (by far more than
    round-off): the cascade leaves such a row out (core::rows_in_reach)."""
    a = {k[3:]: v for k, v in case.items() if k.startswith("in_")}
    G, h, lb, ub = a["G"], a["h"], a["lb"], a["ub"]
    if not G.shape[0]:
        return False
    with np.errstate(invalid="ignore"):
        reach = np.where(G > 0, G * ub, np.where(G < 0, G * lb, 0.0)).sum(axis=1)
    return bool(np.any(h - reach > 1e-6 * (np.abs(h) + np.abs(reach) + 1.0)))


@pytest.mark.parametrize("kernel", KERNELS)
def test_engine_reproduces_the_numba_kernels(recorded, kernel):
    cases = recorded[kernel]
    assert cases
    outputs = equal = 0
    worst = 0.0
    fewer = 0
    for index, case in enumerate(cases):
        got = _call(kernel, case)
        if kernel in ("solve_qp", "solve_level") and case["out_status"] == K.INFEASIBLE:
            assert got["status"] == K.INFEASIBLE, (kernel, index)
            got = {field: got[field] for field in INFEASIBLE_FIELDS}
        if kernel == "solve_cascade" and _out_of_reach(case):
            # The cascade leaves out the general rows that no displacement in the box brings
            # to their bound (core::rows_in_reach): the dual method no longer passes through
            # them (cases 500 and 501: 4 -> 2 iterations at level 0, a row 0.56 below its
            # bound over the whole box), the same answer and active sets otherwise.
            its = got.pop("its")
            want = case["out_its"]
            assert np.all(its <= want), (index, its, want)
            fewer += int(np.any(its < want))
        for field, value in got.items():
            want = case["out_" + field]
            try:
                bitwise, diff = _compare(want, value)
            except AssertionError as err:
                raise AssertionError(f"{kernel} case {index} field {field}: {err}") from None
            assert diff <= 1e-12, (kernel, index, field, diff)
            outputs += 1
            equal += bitwise
            worst = max(worst, diff)
    print(
        f"{kernel}: {len(cases)} cases, {equal}/{outputs} outputs bitwise equal, max rel diff {worst:.3g}"
        + (f"; {fewer} with fewer iterations (a row out of reach left out)" if fewer else "")
    )


def test_status_codes_match_the_engine():
    from qpik._engine import core

    for name in ("SOLVED", "MAX_ITER", "INFEASIBLE", "KEPT_PREVIOUS", "NUMERICAL", "NOT_REACHED"):
        assert getattr(K, name) == getattr(core, name)


def _qp(n=3, m=4):
    rng = np.random.default_rng(0)
    M = rng.normal(size=(n + 1, n))
    return (
        M.T @ M + np.eye(n),
        rng.normal(size=n),
        rng.normal(size=(m, n)),
        -np.ones(m),
        np.ones(m),
        np.zeros(m, np.int8),
    )


def test_wrong_shapes_raise_value_error():
    H, c, C, lo, hi, warm = _qp()
    with pytest.raises(ValueError):
        K.solve_qp(H[:, :2], c, C, lo, hi, warm, 50, 1e-12, True)
    with pytest.raises(ValueError):
        K.solve_qp(H, c[:2], C, lo, hi, warm, 50, 1e-12, True)
    with pytest.raises(ValueError):
        K.solve_level(H, c, C, lo[:2], hi, warm, 50, 1e-12, True, True)
    with pytest.raises(ValueError):
        K.solve_qp(H, c, C, lo, hi, warm[:1], 50, 1e-12, True)
    with pytest.raises(ValueError):
        K.active_guess(c[:2], C, lo, hi)
    A = np.ones((2, 3))
    with pytest.raises(ValueError):
        K.project_level(A, np.ones(3), np.eye(3), 1e-10)
    with pytest.raises(ValueError):
        K.project_level(A, np.ones(2), np.eye(4), 1e-10)
    with pytest.raises(ValueError):
        K.reduced_qp(
            A,
            np.ones(2),
            np.ones((2, 3)),
            np.eye(3),
            np.zeros(2),
            0.0,
            -np.ones(3),
            np.ones(3),
            np.zeros((0, 3)),
            np.zeros(0),
        )
    with pytest.raises(ValueError):
        K.merge_boxes(-np.ones(3), np.ones(2), -np.ones(3), np.ones(3))
    lb, ub = -np.ones(3), np.ones(3)
    with pytest.raises(ValueError):
        K.tighten(lb, ub, np.array([5]), np.zeros(1), np.zeros(1))
    with pytest.raises(ValueError):
        K.tighten(lb, ub, np.array([-1]), np.zeros(1), np.zeros(1))
    with pytest.raises(ValueError):
        K.cholesky_into(np.eye(3), 4, 0.0, np.zeros((4, 4)))
    n = 3
    args = dict(
        A=np.ones((4, n)),
        b=np.zeros(4),
        w=np.ones(4),
        starts=np.array([0, 2, 4]),
        reg=np.zeros(2),
        lb=-np.ones(n),
        ub=np.ones(n),
        G=np.zeros((0, n)),
        h=np.zeros(0),
        threshold=0.0,
        max_damping=0.0,
        error_scale=0.0,
        rank_tol=1e-10,
        max_iter=50,
        tol=1e-12,
        warm=np.zeros((2, n), np.int8),
        canonical=True,
    )
    K.solve_cascade(**args)  # the valid call
    for key, bad in [
        ("starts", np.array([0, 2, 9])),
        ("starts", np.array([0, 3, 2])),
        ("starts", np.array([], np.int64)),
        ("warm", np.zeros((2, n + 1), np.int8)),
        ("reg", np.zeros(3)),
        ("b", np.zeros(3)),
        ("h", np.zeros(1)),
        ("G", np.zeros((1, n + 1))),
        ("A", np.ones((4, n + 1))),
    ]:
        with pytest.raises(ValueError):
            K.solve_cascade(**{**args, key: bad})


def test_outputs_are_never_written_through_a_converted_copy():
    """Arrays a kernel writes into must already be float64 C-contiguous (no silent copy)."""
    lb32 = -np.ones(3, np.float32)
    with pytest.raises(TypeError):
        K.tighten(lb32, np.ones(3), np.array([0]), np.zeros(1), np.zeros(1))
    L = np.zeros((6, 6))[:, ::2]  # not contiguous
    with pytest.raises(TypeError):
        K.cholesky_into(np.eye(3), 3, 0.0, L)
    lb, ub = -np.ones(3), np.ones(3)
    K.tighten(lb, ub, np.array([1, 1]), np.array([-0.5, -0.2]), np.array([0.3, 0.9]))
    assert lb.tolist() == [-1.0, -0.2, -1.0] and ub.tolist() == [1.0, 0.3, 1.0]
    L = np.zeros((3, 3))
    assert K.cholesky_into(4.0 * np.eye(3), 3, 0.0, L) is True
    assert np.array_equal(L, 2.0 * np.eye(3))
    assert K.cholesky_into(np.eye(3), 3, 2.0, L) is False


def test_inputs_of_another_layout_or_dtype_are_converted():
    H, c, C, lo, hi, warm = _qp()
    want = K.solve_qp(H, c, C, lo, hi, warm, 50, 1e-12, True)
    Cf = np.asfortranarray(C)
    got = K.solve_qp(H, c, Cf, lo, hi, warm.astype(np.int64), 50, 1e-12, True)
    assert np.array_equal(want[0], got[0]) and want[1:3] == got[1:3]


def test_the_one_call_result_is_the_stacked_paths_result():
    """HierarchySolver.solve's one compiled call builds its HierarchyResult in C++ (fields set
    as the dataclass __init__ would): the same values, types and certificates as the stacked
    path (solve_arrays), and objects that behave as the classes' own (frozen certificates)."""
    import dataclasses

    from qpik.core import HierarchyProblem, HierarchySolver, LevelCertificate, LevelStatus
    from qpik.core import Level as CoreLevel

    rng = np.random.default_rng(7)
    n, p = 9, 3
    for trial in range(20):
        levels = [
            CoreLevel(rng.normal(size=(m, n)), rng.normal(size=m), float(trial % 2) * 1e-3)
            for m in (3, 4, n)
        ]
        problem = HierarchyProblem(
            levels, -rng.uniform(0.05, 0.5, n), rng.uniform(0.05, 0.5, n),
            rng.normal(size=(p, n)), rng.uniform(0.0, 0.1, p),
        )  # fmt: skip
        solver = HierarchySolver(damping_law=None)
        fast = solver.solve(problem)
        assert np.array_equal(solver.active_sets, fast.active)
        slow = HierarchySolver(damping_law=None).solve_arrays(
            *problem.stacked(), problem.lb, problem.ub, problem.G, problem.h
        )
        assert type(fast) is type(slow)
        for f in dataclasses.fields(fast):
            a, b = getattr(fast, f.name), getattr(slow, f.name)
            if isinstance(a, np.ndarray):
                assert a.dtype == b.dtype and np.array_equal(a, b), f.name
            else:
                assert a == b, f.name
                assert [type(v) for v in a] == [type(v) for v in b] if isinstance(a, list) else True
        assert all(isinstance(s, LevelStatus) for s in fast.status)
        assert all(type(c) is LevelCertificate for c in fast.certificate)
        assert repr(fast) == repr(slow)
        with pytest.raises(dataclasses.FrozenInstanceError):
            fast.certificate[0].primal = 1.0  # type: ignore[misc]
