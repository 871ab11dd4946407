"""The result object of the one-call solve (K.solve_levels: arrays made through NumPy's C
API, fields set by cascade._fill_result) behaves as one made field by field: the same
attributes in the same order, the per-level lists built on first access from its ``_raw``
bytes (residuals, damping, iterations, backend, sigma, certificate: the values the cascade
computed), repr, pickling, copies, and the same values as the result built by the generic
setattr (kinds without the fill function). A level whose rank the cascade proved full
without damping leaves its sigma deferred in ``_raw``, resolved on first access to the bits
the ranking gives without deferral."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

from qpik.core import HierarchyProblem, HierarchyResult, HierarchySolver, Level, cascade
from qpik.core import kernels as K

FIELDS = ["x", "status", "active", "_raw", "primal"]
LAZY = ["residuals", "damping", "iterations", "backend", "sigma", "certificate"]


def _problem(seed: int = 3, n: int = 7) -> HierarchyProblem:
    rng = np.random.default_rng(seed)
    levels = [
        Level(rng.standard_normal((3, n)), rng.standard_normal(3)),
        Level(rng.standard_normal((4, n)), rng.standard_normal(4), 1e-6, np.full(4, 2.0)),
        Level(np.eye(n), np.zeros(n), 1e-3),
    ]
    return HierarchyProblem(
        levels, -0.1 * np.ones(n), 0.1 * np.ones(n), rng.standard_normal((2, n)), np.ones(2)
    )


def _solve(problem: HierarchyProblem, kinds) -> HierarchyResult:
    s = HierarchySolver()
    t, m, e = s.damping_settings
    settings = (t, m, e, s.rank_tolerance, s.max_iter, s.tolerance, None, None, None, kinds)
    return K.solve_levels(
        problem.levels, problem.lb, problem.ub, problem.G, problem.h,
        (*settings, s._cascade_workspace, 0.0),
    )  # fmt: skip


def _same(a: HierarchyResult, b: HierarchyResult) -> None:
    assert type(a) is type(b) is HierarchyResult
    for name in LAZY:  # (each built on first access: then in both)
        assert getattr(a, name) == getattr(b, name)
    assert list(vars(a)) == list(vars(b))
    for name, value in vars(a).items():
        other = vars(b)[name]
        if isinstance(value, np.ndarray):
            assert value.dtype == other.dtype and value.shape == other.shape
            assert value.tobytes() == other.tobytes()
        else:
            assert value == other


def test_arrays_are_fresh_owned_c_contiguous():
    r = HierarchySolver().solve(_problem())
    for a, dtype, shape in ((r.x, np.float64, (7,)), (r.active, np.int8, (3, 9))):
        assert type(a) is np.ndarray and a.dtype == dtype and a.shape == shape
        assert a.base is None and a.flags.owndata and a.flags.c_contiguous and a.flags.writeable


def test_fields_in_order_and_lazy_lists():
    r = HierarchySolver().solve(_problem())
    assert list(vars(r)) == FIELDS
    assert r.ok and len(r.status) == 3
    for k, name in enumerate(LAZY):
        value = getattr(r, name)
        assert len(value) == 3 and getattr(r, name) is value  # built once, then kept
        assert list(vars(r)) == FIELDS + LAZY[: k + 1]
    assert r.backend == ["auto"] * 3
    assert all(type(i) is int and i >= 0 for i in r.iterations)
    assert all(type(v) is float for v in r.residuals + r.damping + r.sigma)
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        r.nope  # noqa: B018


def test_lazy_lists_are_the_cascade_s_values():
    """residuals, damping, iterations, sigma and the certificates of the one-call solve are
    bit for bit those of the cascade on the stacked arrays (K.solve_cascade's tuple)."""
    for seed in range(12):
        problem = _problem(seed, n=7 + seed % 4)
        s = HierarchySolver()
        r = s.solve(problem)
        t, m, e = s.damping_settings
        A, b, w, starts, reg = problem.stacked()
        L, n, p = len(problem.levels), problem.lb.shape[0], problem.G.shape[0]
        x, status, sigma, lam2, its, active, residuals, cert, primal = K.solve_cascade(
            A, b, w, starts, reg, problem.lb, problem.ub, problem.G, problem.h, t, m, e,
            s.rank_tolerance, s.max_iter or 10 * (n + p) + 50, s.tolerance,
            np.zeros((L, n + p), np.int8), True, None, s.lower_trust,
        )  # fmt: skip
        assert r.x.tobytes() == x.tobytes()
        assert np.array(r.residuals).tobytes() == np.asarray(residuals, float).tobytes()
        assert np.array(r.damping).tobytes() == np.asarray(lam2, float).tobytes()
        assert r.iterations == [int(i) for i in its]
        assert np.array(r.sigma).tobytes() == np.asarray(sigma, float).tobytes()
        got = np.array(
            [[c.primal, c.stationarity, c.dual, c.complementarity] for c in r.certificate]
        )
        assert got.tobytes() == np.asarray(cert, float).reshape(L, 4).tobytes()
        assert r.primal == primal


def _undeferred_sigma(problem: HierarchyProblem, s: HierarchySolver) -> list[float]:
    """The per-level sigma of K.solve_cascade (no deferral) on the problem's levels."""
    t, m, e = s.damping_settings
    A = np.vstack([lv.A for lv in problem.levels])
    b = np.concatenate([lv.b for lv in problem.levels])
    w = np.concatenate(
        [
            lv.weights if lv.weights is not None else (np.abs(lv.A).sum(1) > 0).astype(float)
            for lv in problem.levels
        ]
    )
    starts = np.cumsum([0] + [lv.A.shape[0] for lv in problem.levels]).astype(np.int64)
    reg = np.array([lv.regularization for lv in problem.levels])
    L, n, p = len(problem.levels), problem.lb.shape[0], problem.G.shape[0]
    out = K.solve_cascade(
        A, b, w, starts, reg, problem.lb, problem.ub, problem.G, problem.h, t, m, e,
        s.rank_tolerance, s.max_iter, s.tolerance, np.zeros((L, n + p), np.int8), True, None,
    )  # fmt: skip
    return out[2].tolist()


def test_deferred_sigma_is_the_ranking_s_bit_for_bit():
    """Every level's sigma, deferred or not, is the undeferred cascade's, bit for bit (the
    ranking run on the rows kept), and at least one level was deferred."""
    deferred = 0
    for seed in range(40):
        problem = _problem(seed, n=7 + seed % 5)
        for damping_law in (None, "default"):
            solver = HierarchySolver() if damping_law else HierarchySolver(damping_law=None)
            r = solver.solve(problem)
            deferred += len(vars(r)["_raw"]) > 8 * 8 * len(problem.levels)
            want = _undeferred_sigma(problem, solver)
            assert np.array(r.sigma).tobytes() == np.array(want).tobytes()
            assert all(not np.isnan(s) for s in r.sigma)
    assert deferred > 0


def test_fill_function_and_generic_setattr_agree():
    p = _problem()
    filled = _solve(p, cascade._KINDS)
    generic = _solve(p, cascade._KINDS[:4])
    _same(filled, generic)
    assert repr(filled) == repr(generic)
    _same(filled, HierarchySolver().solve(p))


def test_pickle_and_copies_keep_the_result():
    p = _problem()
    r = HierarchySolver().solve(p)
    copies = [pickle.loads(pickle.dumps(r)), copy.deepcopy(r), copy.copy(r)]
    assert all(list(vars(c)) == FIELDS for c in copies)
    for other in copies:
        _same(r, other)
        assert other.certificate == r.certificate
        assert repr(other) == repr(r)
    assert pickle.dumps(HierarchySolver().solve(p)) == pickle.dumps(HierarchySolver().solve(p))


def test_bad_kinds_fall_back_to_none():
    p = _problem()
    assert _solve(p, cascade._KINDS + (None,)) is None
    assert _solve(p, cascade._KINDS[:4] + (3,)) is None


def test_non_finite_entries_anywhere_go_to_the_checks():
    import pytest

    from qpik.errors import QpikError

    for n in (1, 6, 7):
        for bad in (np.nan, np.inf, -np.inf):
            for pos in range(n):
                p = _problem(n=n)
                p.levels[0].A[1, pos] = bad
                assert _solve(p, cascade._KINDS) is None
                with pytest.raises(QpikError):
                    HierarchySolver().solve(p)
                p = _problem(n=n)
                p.G[1, pos] = bad
                assert _solve(p, cascade._KINDS) is None


def test_resolve_sigma_rejects_a_malformed_store():
    """A store that does not hold what the cascade writes raises ValueError (never reads past
    it); a level without a record keeps its own value."""
    nan = float("nan")
    out = K.resolve_sigma(np.array([0.5, nan]), np.array([-1.0, -1.0]))
    assert out[0] == 0.5 and np.isnan(out[1])
    for store in (
        [5.0],  # shorter than L
        [2.0, 0.0],  # a record past the end
        [1.0, 0.0, 1.0, 1.0, 0.0, 1e-10],  # an offset into the header
        [2.0, -1.0, 3.0, 1.0, 1.0, 0.0, 1e-10, 1.0],  # an unknown kind
        [2.0, -1.0, 0.0, 1e9, 1.0, 0.0, 1e-10, 1.0],  # rows beyond the store
        [2.0, -1.0, 0.0, 2.5, 1.0, 0.0, 1e-10, 1.0],  # a fractional size
        [2.0, -1.0, 0.0, 65.0, 1.0, 0.0, 1e-10] + [1.0] * 65,  # more R rows than proved
    ):
        with pytest.raises(ValueError):
            K.resolve_sigma(np.array([nan, nan]), np.array(store))
    # a well-formed record of R = diag(2, 3): sigma 2
    store = np.array([2.0, -1.0, 0.0, 2.0, 2.0, 1.0, 1e-10, 2.0, 0.0, 0.0, 3.0])
    assert K.resolve_sigma(np.array([nan, 7.0]), store) == [2.0, 7.0]


def test_settings_of_another_type_raise_type_error():
    """K.solve_levels takes the solver's settings as one tuple; an entry of another type,
    an int past a double's or an int64's range, a tuple of another length or a workspace
    that is not one raise TypeError (never OverflowError), which HierarchySolver.solve
    answers by its general path."""
    p = _problem()
    args = HierarchySolver()._solve_levels_args()
    bad = [
        (10**400, *args[1:]),
        (*args[:4], 10**30, *args[5:]),
        (*args[:4], 7.0, *args[5:]),
        (*args[:10], "workspace", *args[11:]),
        args[:3],
        list(args),
    ]
    for settings in bad:
        with pytest.raises(TypeError, match="solve_levels: settings"):
            K.solve_levels(p.levels, p.lb, p.ub, p.G, p.h, settings)
    assert K.solve_levels(p.levels, p.lb, p.ub, p.G, p.h, args).ok
