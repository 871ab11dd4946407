"""The result object of the one-call solve (K.solve_levels: arrays made through NumPy's C
API, fields set by cascade._fill_result) behaves as one made field by field: the same
attributes in the same order, lazy certificates, repr, pickling, copies, and the same values
as the result built by the generic setattr (kinds without the fill function)."""

from __future__ import annotations

import copy
import pickle

import numpy as np

from qpik.core import HierarchyProblem, HierarchyResult, HierarchySolver, Level, cascade
from qpik.core import kernels as K

FIELDS = [
    "x",
    "status",
    "residuals",
    "sigma",
    "damping",
    "iterations",
    "active",
    "backend",
    "_cert",
    "primal",
]


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
    args = (problem.levels, problem.lb, problem.ub, problem.G, problem.h, t, m, e, s.rank_tolerance)
    return K.solve_levels(
        *args, s.max_iter, s.tolerance, None, None, None, kinds, s._cascade_workspace
    )


def _same(a: HierarchyResult, b: HierarchyResult) -> None:
    assert type(a) is type(b) is HierarchyResult
    assert a.certificate == b.certificate  # (built on first access: then in both)
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


def test_fields_in_order_and_lazy_certificate():
    r = HierarchySolver().solve(_problem())
    assert list(vars(r)) == FIELDS
    assert r.ok and len(r.status) == 3 and r.backend == ["auto"] * 3
    certs = r.certificate
    assert len(certs) == 3 and r.certificate is certs
    assert list(vars(r)) == [f for f in FIELDS if f != "_cert"] + ["certificate"]


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
