"""Per-step time and exactness of differential IK, qpik's modes beside mink's, in one run.

Scenarios (dt = 10 ms; every method solves the *same* list of states, so the work is
identical, and methods alternate in blocks so that machine noise hits all alike):

* **Panda, two levels** (level 0: a position-only FrameTask on site ``ee``; level 1: a
  PostureTask of cost 0.1), ConfigurationLimit + the model's VelocityLimit, in four regimes:
  ``free`` (nothing binds), ``lower binds`` (the posture target is far: velocity limits bind
  at level 1), ``both bind`` (the frame target is far too), ``circle`` (100 Hz tracking of a
  10 cm circle, the states of qpik's own trajectory).
* **Talos, four levels** (example-robot-data, 32 DoF, ``half_sitting``): both hands
  (position), torso upright (orientation), head orientation, posture; targets in reach and
  out of reach (the left hand 0.6 m away), under position and velocity limits.

Methods: ``qpik auto`` (the exact compiled active set, default), ``qpik osqp`` (OSQP forced
on every level where a limit binds, polished), ``mink + daqp`` and ``mink + osqp`` (the same
tasks as one weighted level: mink has no priorities). Exactness: the largest difference, in
dq, between the core's answer to each level's reduced QP and the answers of daqp and
quadprog (two independent exact QP solvers) to the same reduced QP (the core's null-space
basis, damping and level-above answer), on a sample of states; also the per-level
statuses over every state.

    python benchmarks/step_time.py [--states 400] [--talos-states 200] [--no-talos]
"""

from __future__ import annotations

import argparse
import time

import mink
import numpy as np
import qpsolvers

import qpik
from qpik.core import _kernels as K
from qpik.limits import velocity_limit_from_model
from qpik.tasks import FrameTask, PostureTask

DT = 0.01


REFERENCES = ("daqp", "quadprog")  # independent exact QP solvers (qpsolvers backends)


def exact_reference(solver: qpik.IKSolver, configuration, result) -> dict:
    """Largest difference, in dq, between the core's answer to each level's reduced QP and
    each reference solver's answer to the same reduced QP (built along the core's own
    cascade: the same null-space basis, the same damping, the level above's answer), per
    reference; NaN where a reference fails."""
    problem = solver.build(configuration, DT)
    n = problem.n
    A, b, w, starts, reg = problem.stacked()
    lb, ub, G, h = problem.lb, problem.ub, problem.G, problem.h
    d = np.clip(np.zeros(n), lb, ub)
    Z = np.eye(n)
    worst = dict.fromkeys(REFERENCES, 0.0)
    available = [name for name in REFERENCES if name in qpsolvers.available_solvers]
    for k in range(len(problem.levels)):
        s0, s1 = starts[k], starts[k + 1]
        if s1 == s0 or Z.shape[1] == 0:
            continue
        AZ, _, _, Zn = K.project_level(A[s0:s1], w[s0:s1], Z, solver.rank_tolerance)
        H, c, C, lo, hi = K.reduced_qp(
            A[s0:s1], b[s0:s1], AZ, Z, d, reg[k] + result.damping[k], lb, ub, G, h
        )
        zeros = np.zeros(C.shape[0], dtype=np.int8)
        z, status, _, _ = K.solve_level(H, c, C, lo, hi, zeros, 10_000, 1e-12, k > 0, False)
        upper, lower = np.isfinite(hi), np.isfinite(lo)
        Gq = np.vstack([C[upper], -C[lower]])
        hq = np.concatenate([hi[upper], -lo[lower]])
        for name in available:
            y = qpsolvers.solve_qp(H, c, Gq, hq, solver=name)
            if y is None or status != K.SOLVED:
                worst[name] = float("nan")
            elif not np.isnan(worst[name]):
                worst[name] = max(worst[name], float(np.abs(Z @ (z - y)).max()))
        d = np.clip(d + Z @ z, lb, ub)
        Z = Zn
    return {name: worst[name] for name in available}


CPU_TIMES: dict = {}  # method -> CPU times [us] of the last time_methods call


def time_methods(methods: dict, states: list, set_state, block: int = 50) -> dict:
    """Wall times [us] of each method over the same states (and, in :data:`CPU_TIMES`,
    this process's CPU times: on a shared machine they are the steadier figure)."""
    times = {name: [] for name in methods}
    cpu = {name: [] for name in methods}
    for start in range(0, len(states), block):
        chunk = states[start : start + block]
        for name, step in methods.items():
            for state in chunk:
                configuration = set_state(state)
                c0 = time.process_time()
                t0 = time.perf_counter()
                step(configuration)
                times[name].append(time.perf_counter() - t0)
                cpu[name].append(time.process_time() - c0)
    CPU_TIMES.clear()
    CPU_TIMES.update({name: np.array(t) * 1e6 for name, t in cpu.items()})
    return {name: np.array(t) * 1e6 for name, t in times.items()}


def report(title: str, times: dict, reference: str, extra: dict | None = None) -> None:
    print(f"\n{title} (ratio: median / {reference}'s; wall and CPU time)")
    print(
        f"  {'method':34s} {'median us':>10s} {'p95 us':>9s} {'p99 us':>9s} {'ratio':>7s}"
        f" {'CPU med':>8s} {'CPU ratio':>9s}"
    )
    ref = float(np.median(times[reference]))
    cpu_ref = float(np.median(CPU_TIMES[reference])) if reference in CPU_TIMES else np.nan
    for name, t in times.items():
        median = float(np.median(t))
        cpu = float(np.median(CPU_TIMES[name])) if name in CPU_TIMES else np.nan
        line = (
            f"  {name:34s} {median:10.1f} {np.percentile(t, 95):9.1f} "
            f"{np.percentile(t, 99):9.1f} {median / ref:7.2f} {cpu:8.1f} {cpu / cpu_ref:9.2f}"
        )
        if extra and name in extra:
            line += f"   {extra[name]}"
        print(line)


def compare(title, states, set_state, methods, solvers, reference="mink + daqp, 1 weighted level"):
    """Time every method on the states, then check the qpik solvers' exactness and
    statuses on them (every state for statuses, a sample for the exact reference)."""
    times = time_methods(methods, states, set_state)
    extra = {}
    stride = max(1, len(states) // 100)
    binding = None
    for name, solver in solvers.items():
        worst, bad, failed, statuses = {}, 0, 0, set()
        counts = np.zeros(len(solver.levels), dtype=int)
        for i, state in enumerate(states):
            c = set_state(state)
            result = solver.step(c, DT)
            statuses.update(str(s) for s in result.status)
            bad += any(s in ("kept_previous", "max_iter") for s in result.status)
            active = solver._core._warm
            if active is not None:
                counts += active.any(axis=1)
            if i % stride == 0:
                for ref, difference in exact_reference(solver, c, result).items():
                    if np.isnan(difference):
                        failed += 1
                    else:
                        worst[ref] = max(worst.get(ref, 0.0), difference)
        binding = counts if binding is None else binding
        extra[name] = (
            "max |dq - ref| per level: "
            + ", ".join(f"{ref} {value:.1e}" for ref, value in worst.items())
            + (f" ({failed} references failed)" if failed else "")
            + f", kept_previous/max_iter steps {bad}, "
            f"statuses {sorted(statuses)}"
        )
    binds = ", ".join(f"level {k}: {n}" for k, n in enumerate(binding))
    report(
        f"{title}\n  (limits bind, steps per level, {binds} of {len(states)})",
        times,
        reference,
        extra,
    )


def panda(n_states: int, rng: np.random.Generator) -> None:
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    home = model.key_qpos[0].copy() if model.nkey else configuration.mid_q()

    def tasks(kind="qpik"):
        cls_f = FrameTask if kind == "qpik" else mink.FrameTask
        cls_p = PostureTask if kind == "qpik" else mink.PostureTask
        return cls_f("ee", "site", position_cost=1.0, orientation_cost=0.0), cls_p(model, 0.1)

    def random_states(regime):
        states = []
        for _ in range(n_states):
            q = home + rng.uniform(-0.6, 0.6, model.nv)
            q = np.clip(q, configuration.lower, configuration.upper)
            configuration.update(q)
            p = configuration.frame_pose("ee")[0]
            offset = rng.uniform(-1, 1, 3) * (0.3 if regime == "both bind" else 0.001)
            move = rng.uniform(-1.5, 1.5, model.nv) if regime != "free" else 1e-4
            posture_target = np.clip(q + move, configuration.lower, configuration.upper)
            states.append((q, p + offset, posture_target))
        return states

    def circle_states():
        frame, posture = tasks()
        tracker = qpik.IKSolver(model, [[frame], [posture]], limits)
        states = []
        configuration.update(home)
        centre = configuration.frame_pose("ee")[0]
        q = home.copy()
        posture.set_target(home)
        for k in range(n_states):
            angle = 2 * np.pi * k / 400
            target = centre + 0.1 * np.array([np.cos(angle) - 1.0, np.sin(angle), 0.0])
            states.append((q.copy(), target, home))
            configuration.update(q)
            frame.set_target(mink.SE3.from_translation(target))
            q = configuration.integrate(tracker.step(configuration, DT).velocity, DT)
        return states

    def run(regime):
        states = circle_states() if regime == "circle" else random_states(regime)
        ours, forced_tasks, theirs = tasks(), tasks(), tasks("mink")
        auto = qpik.IKSolver(model, [[ours[0]], [ours[1]]], limits)
        forced = qpik.IKSolver(model, [[forced_tasks[0]], [forced_tasks[1]]], limits, solver="osqp")

        def set_state(state):
            q, target, posture_target = state
            configuration.update(q)
            pose = mink.SE3.from_translation(target)
            for frame, posture in (ours, forced_tasks, theirs):
                frame.set_target(pose)
                posture.set_target(posture_target)
            return configuration

        methods = {
            "qpik auto, 2 levels": lambda c: auto.step(c, DT),
            "qpik osqp, 2 levels": lambda c: forced.step(c, DT),
            "mink + daqp, 1 weighted level": lambda c: mink.solve_ik(
                c, list(theirs), DT, "daqp", damping=1e-6, limits=limits
            ),
            "mink + osqp, 1 weighted level": lambda c: mink.solve_ik(
                c, list(theirs), DT, "osqp", damping=1e-6, limits=limits
            ),
        }
        solvers = {"qpik auto, 2 levels": auto, "qpik osqp, 2 levels": forced}
        compare(f"  regime '{regime}', {len(states)} states", states, set_state, methods, solvers)

    print(f"Panda (nv = {model.nv}), 2 levels, ConfigurationLimit + VelocityLimit, dt = {DT} s")
    for regime in ("free", "lower binds", "both bind", "circle"):
        run(regime)


def talos(n_states: int) -> None:
    try:
        model = qpik.load_robot("erd:talos")
    except qpik.QpikError as exc:
        print(f"\nTalos skipped: {exc}")
        return
    configuration = qpik.Configuration(model)
    home = model.key_qpos[0].copy()
    configuration.update(home)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    hands = ("gripper_left_base_link", "gripper_right_base_link")

    def stack(kind="qpik"):
        F = FrameTask if kind == "qpik" else mink.FrameTask
        P = PostureTask if kind == "qpik" else mink.PostureTask
        left = F(hands[0], "body", position_cost=1.0, orientation_cost=0.0)
        right = F(hands[1], "body", position_cost=1.0, orientation_cost=0.0)
        torso = F("torso_2_link", "body", position_cost=0.0, orientation_cost=1.0)
        head = F("head_2_link", "body", position_cost=0.0, orientation_cost=1.0)
        return [[left, right], [torso], [head], [P(model, 0.1)]]

    # The states of qpik's own 100 Hz trajectory: both hands circle (5 cm) around their
    # start; from the middle on, the left hand's target is 0.6 m away, out of reach.
    starts = [configuration.frame_pose(hand, "body")[0] for hand in hands]
    upright = mink.SE3.from_rotation(
        mink.SO3.from_matrix(configuration.frame_pose("torso_2_link", "body")[1])
    )
    head_pose = mink.SE3.from_rotation(
        mink.SO3.from_matrix(configuration.frame_pose("head_2_link", "body")[1])
    )

    def targets_at(k):
        angle = 2 * np.pi * k / 200
        circle = 0.05 * np.array([0.0, np.cos(angle) - 1.0, np.sin(angle)])
        away = np.array([0.6, 0.3, 0.2]) if k >= n_states // 2 else np.zeros(3)
        return [starts[0] + circle + away, starts[1] + circle]

    def set_targets(levels, targets):
        for task, target in zip(levels[0], targets):
            task.set_target(mink.SE3.from_translation(target))
        levels[1][0].set_target(upright)
        levels[2][0].set_target(head_pose)
        levels[3][0].set_target(home)

    leader = stack()
    driver = qpik.IKSolver(model, leader, limits)
    states = []
    q = home.copy()
    for k in range(n_states):
        targets = targets_at(k)
        states.append((q.copy(), targets))
        configuration.update(q)
        set_targets(leader, targets)
        q = configuration.integrate(driver.step(configuration, DT).velocity, DT)

    ours, forced_tasks, theirs = stack(), stack(), stack("mink")
    auto = qpik.IKSolver(model, ours, limits)
    forced = qpik.IKSolver(model, forced_tasks, limits, solver="osqp")

    def set_state(state):
        q, targets = state
        configuration.update(q)
        for levels in (ours, forced_tasks, theirs):
            set_targets(levels, targets)
        return configuration

    flat = [t for level in theirs for t in level]
    methods = {
        "qpik auto, 4 levels": lambda c: auto.step(c, DT),
        "qpik osqp, 4 levels": lambda c: forced.step(c, DT),
        "mink + daqp, 1 weighted level": lambda c: mink.solve_ik(
            c, flat, DT, "daqp", damping=1e-6, limits=limits
        ),
    }
    solvers = {"qpik auto, 4 levels": auto, "qpik osqp, 4 levels": forced}
    compare(
        f"\nTalos (erd:talos, fixed base, nv = {model.nv}), 4 levels (hands / torso / head / "
        f"posture), {len(states)} states of a 100 Hz trajectory, the second half with the left "
        "hand's target 0.6 m out of reach",
        states, set_state, methods, solvers,
    )  # fmt: skip


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--states", type=int, default=400)
    parser.add_argument("--talos-states", type=int, default=400)
    parser.add_argument("--no-talos", action="store_true")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    model = qpik.load_robot("panda")
    posture = PostureTask(model, 1.0)
    configuration = qpik.Configuration(model)
    posture.set_target(configuration.q)
    qpik.IKSolver(model, posture).step(configuration, DT)  # loads (or compiles) the kernels
    first = time.perf_counter() - t0
    print(f"first step (kernels loaded from numba's cache, or compiled): {first:.2f} s")
    panda(args.states, rng)
    if not args.no_talos:
        talos(args.talos_states)


if __name__ == "__main__":
    main()
