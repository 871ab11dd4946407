"""Feasible levels that ended ``kept_previous`` by round-off (issue 21), now solved and
certified, robustly.

Three rank-deficient hierarchies of tests/exactness_oracle.py's generator (``problems(seed,
count)[index]``: 13 #283, 9101 #4587, 9202 #1603; the arrays saved in
tests/data/exactness/hqp_roundoff_drop_SEED_INDEX.npz). A level there has ``rho = 0`` and an
objective flat in most of its null space (rank 2 of 17 on 13 #283): the dual method's
floored Hessian (condition ~1e14) sets its point in the flat directions by round-off, and
the KKT re-solve on its working set can violate a row only the tie-break needs (7.5e-3 on
13 #283). The independent fallback, the primal active set, then reached a face whose
minimiser needs no row, took a round-off multiplier (-9e-16) for a negative one, dropped
its row and stepped back onto it for ever: the level kept the previous answer, and 1e-15
perturbations of A flipped the outcome (67, 50 and 17 of 200 runs).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from exactness_oracle import (
    box_size,
    level_reference,
    objective,
    objective_tolerance,
    scaled_violation,
)

from qpik.core import HierarchyProblem, HierarchySolver, Level, LevelStatus
from qpik.core import kernels as K

DATA = Path(__file__).parents[1] / "data" / "exactness"
CASES = sorted(DATA.glob("hqp_roundoff_drop_*.npz"))


def load(path: Path, scale=None) -> HierarchyProblem:
    z = np.load(path)
    levels = []
    for k in range(int(z["L"])):
        A = z[f"A{k}"]
        if scale is not None:
            A = A * scale[k]
        levels.append(Level(A, z[f"b{k}"], float(z[f"reg{k}"])))
    return HierarchyProblem(levels, z["lb"], z["ub"], z["G"], z["h"])


def assert_solved(problem: HierarchyProblem, result) -> None:
    assert all(s is LevelStatus.SOLVED for s in result.status), (result.status, result.certificate)
    for cert in result.certificate:
        assert cert.holds and not cert.failed, cert
    assert scaled_violation(result.x, problem.lb, problem.ub, problem.G, problem.h) <= 1e-9


def test_cases_present():
    assert len(CASES) == 3


def test_saved_arrays_are_the_generators():
    """The files are exactness_oracle's hierarchies (checked on the cheapest to regenerate)."""
    from exactness_oracle import problems

    z = np.load(DATA / "hqp_roundoff_drop_13_283.npz")
    p = problems(int(z["seed"]), int(z["index"]) + 1)[int(z["index"])]
    assert p.kind == str(z["category"])
    for k, (A, b, rho) in enumerate(p.levels):
        assert np.array_equal(A, z[f"A{k}"]) and np.array_equal(b, z[f"b{k}"])
        assert rho == float(z[f"reg{k}"])
    assert np.array_equal(p.G, z["G"]) and np.array_equal(p.lb, z["lb"])


@pytest.mark.parametrize("path", CASES, ids=lambda p: p.stem)
@pytest.mark.parametrize("exact", [True, False], ids=["exact", "defaults"])
def test_every_level_solved_and_certified(path, exact):
    problem = load(path)
    solver = HierarchySolver(damping_law=None) if exact else HierarchySolver()
    assert_solved(problem, solver.solve(problem))


@pytest.mark.parametrize("path", CASES, ids=lambda p: p.stem)
@pytest.mark.parametrize("exact", [True, False], ids=["exact", "defaults"])
def test_perturbed_variants_stay_solved(path, exact):
    """A perturbed by 1e-15 relative (entry by entry): every run solved and certified."""
    z = np.load(path)
    rng = np.random.default_rng(int(z["seed"]))
    solver = HierarchySolver(damping_law=None) if exact else HierarchySolver()
    L = int(z["L"])
    for _ in range(40):
        scale = [1.0 + 1e-15 * rng.standard_normal(z[f"A{k}"].shape) for k in range(L)]
        problem = load(path, scale)
        assert_solved(problem, solver.solve(problem))


@pytest.mark.parametrize("path", CASES, ids=lambda p: p.stem)
def test_level_by_level_path_solves(path):
    """The Python level-by-level path (certified_level on each backend answer) too."""
    problem = load(path)
    solver = HierarchySolver(damping_law=None)
    A, b, w, starts, reg = problem.stacked()
    n, p = problem.lb.shape[0], problem.G.shape[0]
    warm = np.zeros((len(starts) - 1, n + p), np.int8)
    result = solver._solve_levels(
        A, b, w, starts, reg, problem.lb, problem.ub, problem.G, problem.h, warm, fallback=True
    )
    assert_solved(problem, result)


@pytest.mark.parametrize("path", CASES, ids=lambda p: p.stem)
def test_not_worse_than_the_reference(path):
    """Each level against the independent reference (quadprog, the levels above held)."""
    from exactness_oracle import Problem

    problem = load(path)
    p = Problem(
        [(lv.A, lv.b, lv.regularization) for lv in problem.levels],
        problem.lb, problem.ub, problem.G, problem.h, "file", True,
    )  # fmt: skip
    solver = HierarchySolver(damping_law=None)
    for k, (A, b, rho) in enumerate(p.levels):
        cut = HierarchyProblem(problem.levels[: k + 1], p.lb, p.ub, p.G, p.h)
        x_k = solver.solve(cut).x
        x_ref, certified = level_reference(p, k, x_k)
        if not certified or scaled_violation(x_ref, p.lb, p.ub, p.G, p.h) > 1e-10:
            continue
        f_ours, f_ref = objective(A, b, rho, x_k), objective(A, b, rho, x_ref)
        tol = objective_tolerance(A, b, x_k, x_ref, f_ours, f_ref, box_size(p.lb, p.ub))
        assert f_ours <= f_ref + tol, (k, f_ours, f_ref)


def test_fallback_on_the_failing_level_itself():
    """13 #283's last level as the cascade met it (tests/data/exactness/
    level_roundoff_drop_13_283.npz: A, b, AZ, Z, d of the level, rho = 0, the dual method's
    working set): the re-solve on that set violates a row; the primal active set must stop
    where every multiplier is round-off, and the level is certified."""
    z = np.load(DATA / "level_roundoff_drop_13_283.npz")
    n, p = z["lb"].shape[0], z["G"].shape[0]
    ok, _, cert, _ = K.certified_level(
        z["A"], z["b"], z["AZ"], z["Z"], z["d"], float(z["rho"]), z["lb"], z["ub"], z["G"],
        z["h"], z["active"], K.SOLVED, 10 * (n + p) + 50, True,
    )  # fmt: skip
    assert ok, cert
    assert max(cert) <= 1e-9
