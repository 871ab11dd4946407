"""Hierarchical QP benchmark: qpik's core against DAQP's hierarchical mode and against
quadprog / DAQP level by level, on the same problems (issue 21).

Problem sets:

* ``panda``: 7 variables, 2-3 levels (end-effector position, sometimes orientation, then
  posture), position and velocity boxes (intersected), targets beyond the box half the time;
* ``humanoid``: 35 variables, 4-5 levels (feet, CoM, two hands, posture, sometimes a gaze
  task), a box and 8 general rows;
* ``random``: the random hierarchies of tests/exactness_oracle.py (feasible kinds).

Solvers:

* ``qpik core``: ``HierarchySolver(damping_law=None).solve(problem)`` with regularisation 0,
  validation and the per-level certificate included;
* ``daqp hier``: ``daqp.solve(None, None, A, bu, bl, sense, break_points=...)`` (DAQP 0.11):
  the limits as level 0 (simple bounds first, then ``G x <= h``), each task level's rows as
  soft equalities ``A_k x = b_k`` (DAQP minimises its row-normalised slacks, level by level);
* ``quadprog lvl``: each level by quadprog in the null space of the held levels, with
  proximal iterations (quadprog needs a positive definite Hessian) - the test oracle;
* ``daqp lvl``: each level by ``daqp.solve`` on ``A_k^T A_k`` with the held levels' task
  values as equalities (``sense`` 5) and DAQP's automatic proximal regularisation.

Measures per solver and set: the median time per solve [us]; against the certified optimum
(qpik's answer where every level is solved - its certificate proves it - checked against
quadprog solving each level alone with the levels above held at qpik's values), how many
answers are lexicographically *worse* (the first level whose objective differs beyond issue
21's tolerance is higher) and the largest relative
excess there (over the optimum's objective, or ``1/2 |b_k|^2`` where that is larger); the
largest scaled row violation.

    PYTHONPATH=. python benchmarks/hqp.py [--count 40] [--repeat 20]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import daqp
import numpy as np
from bench_cli import at_least  # benchmarks/bench_cli.py (this folder is on sys.path)
from daqp_hier import daqp_hierarchical  # benchmarks/daqp_hier.py

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from exactness_oracle import (  # noqa: E402
    Infeasible,
    Problem,
    level_reference,
    lexicographic,
    objective,
    objective_tolerance,
    problems,
    scaled_violation,
)

from qpik.core import HierarchyProblem, HierarchySolver, Level  # noqa: E402

# ----------------------------------------------------------------------------- problems


def panda_problems(rng: np.random.Generator, count: int) -> list[Problem]:
    out = []
    n, dt = 7, 0.01
    for _ in range(count):
        J = rng.normal(size=(6, n)) * 0.4
        v = rng.normal(size=n) * rng.choice([0.5, 3.0])
        levels = [(J[:3], J[:3] @ v * dt, 0.0)]
        if rng.random() < 0.5:
            levels.append((J[3:], J[3:] @ (v + rng.normal(size=n)) * dt, 0.0))
        levels.append((np.eye(n), rng.normal(size=n) * 0.05, 0.0))
        q_room = rng.uniform(0.0, 0.5, (2, n))  # distance to the position limits [rad]
        vmax = 2.0 * dt
        lb = np.maximum(-q_room[0], -vmax)
        ub = np.minimum(q_room[1], vmax)
        out.append(Problem(levels, lb, ub, np.zeros((0, n)), np.zeros(0), "panda", True))
    return out


def humanoid_problems(rng: np.random.Generator, count: int) -> list[Problem]:
    out = []
    n, dt = 35, 0.01
    for _ in range(count):
        v = rng.normal(size=n)
        feet = rng.normal(size=(12, n)) * 0.3
        com = rng.normal(size=(3, n)) * 0.2
        hands = rng.normal(size=(12, n)) * 0.4
        levels = [
            (feet, np.zeros(12), 0.0),
            (com, com @ v * dt, 0.0),
            (hands, hands @ (v + rng.normal(size=n)) * dt, 0.0),
        ]
        if rng.random() < 0.5:
            gaze = rng.normal(size=(2, n)) * 0.3
            levels.append((gaze, gaze @ rng.normal(size=n) * dt, 0.0))
        levels.append((np.eye(n), rng.normal(size=n) * 0.05, 0.0))
        lb, ub = -rng.uniform(0.005, 0.03, n), rng.uniform(0.005, 0.03, n)
        G = rng.normal(size=(8, n)) * 0.2
        h = rng.uniform(0.0, 0.002, 8)
        out.append(Problem(levels, lb, ub, G, h, "humanoid", True))
    return out


def random_problems(count: int) -> list[Problem]:
    return [p for p in problems(4242, count * 8 // 7 + 1) if p.feasible][:count]


# ----------------------------------------------------------------------------- solvers


def core_problem(p: Problem) -> HierarchyProblem:
    return HierarchyProblem([Level(A, b, rho) for A, b, rho in p.levels], p.lb, p.ub, p.G, p.h)


_CORE = HierarchySolver(damping_law=None)


def solve_core(p: Problem, solver: HierarchySolver = _CORE):
    problem = core_problem(p)
    return lambda: solver.solve(problem)


def solve_daqp_hierarchical(p: Problem):
    solve = daqp_hierarchical(p.lb, p.ub, p.G, p.h, [(A, b) for A, b, _ in p.levels])
    return lambda: solve()[0]


def solve_quadprog_levels(p: Problem):
    def run():
        try:
            return lexicographic(p)[0][-1]
        except Infeasible:  # quadprog's round-off at a degenerate vertex
            return np.full(p.n, np.nan)

    return run


def solve_daqp_levels(p: Problem):
    n = p.n
    bound = np.full(p.G.shape[0], -1e30)

    def run():
        held_A, held_b = np.zeros((0, n)), np.zeros(0)
        x = np.clip(np.zeros(n), p.lb, p.ub)
        for A, b, rho in p.levels:
            H = A.T @ A + rho * np.eye(n)
            f = -(A.T @ b)
            C = np.vstack([p.G, held_A])
            bu = np.concatenate([p.ub, p.h, held_b])
            bl = np.concatenate([p.lb, bound, held_b])
            sense = np.zeros(bu.shape[0], dtype=np.int32)
            sense[n + p.G.shape[0] :] = 5
            H, C = np.ascontiguousarray(H), np.ascontiguousarray(C)
            x_new, _, flag, _ = daqp.solve(H, f, C, bu, bl, sense)
            if flag < 0:
                break
            x = x_new
            held_A = np.vstack([held_A, A])
            held_b = np.concatenate([held_b, A @ x])
        return x

    return run


SOLVERS = {
    "qpik core": solve_core,
    "daqp hier": solve_daqp_hierarchical,
    "quadprog lvl": solve_quadprog_levels,
    "daqp lvl": solve_daqp_levels,
}

# ----------------------------------------------------------------------------- measures


def timed(run, repeat: int) -> float:
    run()  # warm-up (and the answer's caches, if any)
    start = time.perf_counter()
    for _ in range(repeat):
        run()
    return (time.perf_counter() - start) / repeat


def lexicographic_gap(p: Problem, x: np.ndarray, x_opt: np.ndarray) -> tuple[bool, float]:
    """(worse, relative excess at the first differing level) of x against the optimum."""
    for A, b, rho in p.levels:
        f, f_opt = objective(A, b, rho, x), objective(A, b, rho, x_opt)
        tol = objective_tolerance(A, b, x, x_opt, f, f_opt)
        if f > f_opt + tol:  # relative to the optimum, or to 1/2 |b|^2 where that is ~0
            return True, (f - f_opt) / max(f_opt, 0.5 * float(b @ b), 1e-300)
        if f < f_opt - tol:
            return False, 0.0
    return False, 0.0


def optimum(p: Problem) -> tuple[np.ndarray, str]:
    """The certified optimum: qpik's answer when every level is solved (its certificate
    proves each level at the point it returned), checked level by level against quadprog
    solving that level alone with the levels above held at qpik's task values (the test
    oracle, tests/diffik/test_exactness.py); else the quadprog chain."""
    solver = HierarchySolver(damping_law=None)
    result = solver.solve(core_problem(p))
    if result.ok and all(c.holds for c in result.certificate):
        for k, (A, b, rho) in enumerate(p.levels):
            cut = Problem(p.levels[: k + 1], p.lb, p.ub, p.G, p.h, p.kind, True)
            x_k = solver.solve(core_problem(cut)).x
            try:
                x_ref, certified = level_reference(p, k, x_k)
            except Infeasible:
                continue
            if not certified or scaled_violation(x_ref, p.lb, p.ub, p.G, p.h) > 1e-10:
                continue
            f, f_ref = objective(A, b, rho, x_k), objective(A, b, rho, x_ref)
            if f > f_ref + objective_tolerance(A, b, x_k, x_ref, f, f_ref):
                return x_ref, "quadprog (qpik worse!)"
        return result.x, "qpik certified"
    try:
        return lexicographic(p)[0][-1], "quadprog"
    except Infeasible:
        return result.x, "qpik uncertified"


def run(count: int, repeat: int) -> None:
    rng = np.random.default_rng(21)
    sets = {
        "panda (7 vars, 2-3 levels)": panda_problems(rng, count),
        "humanoid (35 vars, 4-5 levels, 8 rows)": humanoid_problems(rng, count),
        "random (5-40 vars, 1-5 levels, 7 kinds)": random_problems(count),
    }
    print(f"{count} problems per set, {repeat} timed calls each; times are medians over problems")
    header = (
        f"{'set':42s} {'solver':13s} {'time [us]':>10s} {'worse':>6s} {'max excess':>11s} "
        f"{'max viol':>9s}"
    )
    print(header)
    print("-" * len(header))
    for name, ps in sets.items():
        optima = [optimum(p) for p in ps]
        uncertified = sum(source != "qpik certified" for _, source in optima)
        per_problem: dict = {}  # solver -> its time on each problem
        for solver_name, make in SOLVERS.items():
            times, worse, excess, viol, failed = [], 0, 0.0, 0.0, 0
            for p, (x_opt, _) in zip(ps, optima):
                runner = make(p)
                out = runner()
                x = out.x if hasattr(out, "x") else np.asarray(out)
                t = timed(runner, repeat if solver_name != "quadprog lvl" else max(1, repeat // 5))
                times.append(t)
                if not np.all(np.isfinite(x)):
                    failed += 1
                    continue
                w, e = lexicographic_gap(p, x, x_opt)
                worse += w
                excess = max(excess, e)
                viol = max(viol, scaled_violation(x, p.lb, p.ub, p.G, p.h))
            per_problem[solver_name] = times
            print(
                f"{name:42s} {solver_name:13s} {1e6 * statistics.median(times):10.1f} "
                f"{worse:4d}/{len(ps):<3d}{excess:10.2e} {viol:9.1e}"
                + (f"  ({failed} failed)" if failed else "")
            )
        if uncertified:
            print(f"{'':42s} ({uncertified} optima not from qpik's certificate)")
        ratio = statistics.median(
            a / b for a, b in zip(per_problem["qpik core"], per_problem["daqp hier"])
        )
        goal = (
            ""
            if name.startswith("random")
            else (f" (issue 21's goal <= 1.00: {'met' if ratio <= 1.0 else 'not met'})")
        )
        print(f"{'':42s} qpik core / daqp hier, median of the problems' ratios: {ratio:.3f}{goal}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=at_least(1), default=40, help="problems per set")
    parser.add_argument("--repeat", type=at_least(1), default=20, help="timed calls per problem")
    args = parser.parse_args()
    run(args.count, args.repeat)


if __name__ == "__main__":
    import bench_cli  # benchmarks/bench_cli.py (this folder is on sys.path)

    bench_cli.run(main)
