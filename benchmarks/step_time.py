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
basis, damping and level-above answer), on a sample of states (a reference answer that
leaves its rows by more than 1e-9 is counted apart, not compared: DAQP's, on 2 fixed-Talos
levels, by 1.8e-7 and 7.7e-7, at a lower objective than the feasible optimum that quadprog
and the core agree on); also the per-level statuses over every state.

* **Issue 20, the peers** (``--peers on|off|only|talos``; each skipped with a line when PlaCo,
  pink, pinocchio or daqp is missing: ``pip install -e '.[compare]'``):

  - *Panda beside PlaCo and pink*: example-robot-data's Panda (the same URDF loaded by
    qpik's MuJoCo model, PlaCo and pink; poses checked equal), a pose task on
    ``panda_hand_tcp`` over a posture (cost 0.1), position + velocity limits (the URDF's),
    regimes ``free`` and ``both bind``; the same states for qpik's two strict levels (twice:
    by default qpik also holds the URDF's finger mimic, ``panda_finger_joint2`` following
    ``panda_finger_joint1``, a MuJoCo joint equality, as a level above the stack; with
    ``couplings=False`` it solves the peers' problem, which moves the two fingers
    independently: the row to compare with them; and once more as one weighted level with
    ``couplings=False``, the problem of PlaCo's "both soft", pink's and mink's), PlaCo's
    ``KinematicsSolver`` (frame task hard + posture soft; and both soft with mink's weights,
    1 and 0.1^2, which is mink's problem), pink + daqp and mink + daqp. Besides the times:
    each answer's frame and posture errors after the step, its largest difference from
    qpik's dq and its velocity-limit excess; PlaCo's failures (a hard task it cannot meet
    raises). Step times exclude each library's kinematics update before the step (printed
    apart).
  - *Talos, floating base*: feet held / CoM / both hands / posture, 300 closed-loop steps
    (:func:`talos_peers`): times and task errors of qpik's four levels, PlaCo (feet hard,
    the rest soft) and mink + daqp (one weighted level, the same weights); and qpik on
    PlaCo's problem (the feet a strict level, the rest one weighted level below it with
    PlaCo's weights). Per half (in reach, out of reach), how each closed loop moves: its
    joint speeds' rms and the share of steps where a joint's speed changes sign
    (:func:`_chatter`: a loop shaking between two corners of its velocity box).

    python benchmarks/step_time.py [--states 400] [--talos-states 200] [--no-talos]
    python benchmarks/step_time.py --peers only [--peer-states 400] [--talos-steps 300]
    python benchmarks/step_time.py --peers talos [--talos-steps 300]   # the Talos peers alone
        [--talos-methods qpik,placo]   # only those methods (keys: TALOS_METHODS)
    python benchmarks/step_time.py --instructions [--count-states 100]  # valgrind's counts
    python benchmarks/step_time.py --cache [--count-states 100]  # hot / flushed / interleaved

* **Instructions per step** (``--instructions``; needs valgrind): the Panda and Talos peer
  problems (qpik's strict levels, qpik on PlaCo's problem, PlaCo), each method alone in its
  own process, the same states for all (Talos: qpik's own closed-loop configurations),
  counted by valgrind (:func:`count_instructions`): a figure no machine load moves, to
  compare two versions of qpik by, and qpik's work with PlaCo's (the times above add how
  fast each code's instructions run). About two minutes a method (two counted runs each).
"""

from __future__ import annotations

import argparse
import time

import mink
import numpy as np
import qpsolvers
from bench_cli import at_least  # benchmarks/bench_cli.py (this folder is on sys.path)
from daqp_hier import daqp_hierarchical  # benchmarks/daqp_hier.py (daqp imported when called)

import qpik
from qpik.core import kernels as K
from qpik.limits import velocity_limit_from_model
from qpik.tasks import FrameTask, PostureTask

DT = 0.01


REFERENCES = ("daqp", "quadprog")  # independent exact QP solvers (qpsolvers backends)


#: A reference answer that violates its QP's rows by more than this (scaled by 1 + |h|) is
#: not exact: it is counted apart, not compared (DAQP leaves rows violated by 1e-7 on some
#: fixed-Talos levels, with a lower objective than the feasible optimum).
REFERENCE_VIOLATION = 1e-9


def exact_reference(solver: qpik.IKSolver, configuration, result) -> tuple[dict, dict]:
    """Largest difference, in dq, between the core's answer to each level's reduced QP and
    each reference solver's answer to the same reduced QP (built along the core's own
    cascade: the same null-space basis, the same damping, the level above's answer), per
    reference (NaN where a reference fails); and per reference, the count of levels where
    its answer violates the rows (:data:`REFERENCE_VIOLATION`; not compared)."""
    problem = solver.build(configuration, DT)
    n = problem.n
    A, b, w, starts, reg = problem.stacked()
    lb, ub, G, h = problem.lb, problem.ub, problem.G, problem.h
    d = np.clip(np.zeros(n), lb, ub)
    Z = np.eye(n)
    worst = dict.fromkeys(REFERENCES, 0.0)
    infeasible: dict = {}
    available = [name for name in REFERENCES if name in qpsolvers.available_solvers]
    for k in range(len(problem.levels)):
        s0, s1 = starts[k], starts[k + 1]
        if s1 > s0:  # the rows the levels above pinned leave Z, as in the core
            Z = K.drop_pinned(Z, d, lb, ub, G, h)
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
            elif (Gq @ y - hq > REFERENCE_VIOLATION * (1.0 + np.abs(hq))).any():
                infeasible[name] = infeasible.get(name, 0) + 1
            elif not np.isnan(worst[name]):
                worst[name] = max(worst[name], float(np.abs(Z @ (z - y)).max()))
        d = np.clip(d + Z @ z, lb, ub)
        Z = Zn
    return {name: worst[name] for name in available}, infeasible


CPU_TIMES: dict = {}  # method -> CPU times [us] of the last time_methods call


def time_methods(
    methods: dict, states: list, set_state, block: int = 50, refresh: dict | None = None
) -> dict:
    """Wall times [us] of each method over the same states (and, in :data:`CPU_TIMES`,
    this process's CPU times: on a shared machine they are the steadier figure).

    ``refresh`` maps a method to its own library's kinematics update at a state, run again
    after ``set_state`` (which updates every library) and just before that method's timed
    call: each method then starts, as in a control loop, right after its own update, and
    none gains from having been updated last."""
    times = {name: [] for name in methods}
    cpu = {name: [] for name in methods}
    for start in range(0, len(states), block):
        chunk = states[start : start + block]
        for name, step in methods.items():
            for state in chunk:
                configuration = set_state(state)
                if refresh and name in refresh:
                    refresh[name](state)
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
        infeasible: dict = {}
        counts = np.zeros(len(solver.levels), dtype=int)
        for i, state in enumerate(states):
            c = set_state(state)
            result = solver.step(c, DT)
            statuses.update(str(s) for s in result.status)
            bad += any(s in ("kept_previous", "max_iter") for s in result.status)
            active = solver._core.active_sets
            if active is not None:
                counts += active.any(axis=1)
            if i % stride == 0:
                differences, off_rows = exact_reference(solver, c, result)
                for ref, count in off_rows.items():
                    infeasible[ref] = infeasible.get(ref, 0) + count
                for ref, difference in differences.items():
                    if np.isnan(difference):
                        failed += 1
                    else:
                        worst[ref] = max(worst.get(ref, 0.0), difference)
        binding = counts if binding is None else binding
        extra[name] = (
            "max |dq - ref| per level: "
            + ", ".join(f"{ref} {value:.1e}" for ref, value in worst.items())
            + (f" ({failed} references failed)" if failed else "")
            + "".join(
                f" ({n} {ref} answers off their rows by > {REFERENCE_VIOLATION:g}: not compared)"
                for ref, n in infeasible.items()
            )
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


# ------------------------------------------------------------------ issue 20: PlaCo, pink
PEER_MODULES = {"placo": "placo", "pink": "pink", "pinocchio": "pinocchio", "daqp": "daqp"}


def peers_found() -> dict:
    """``{name: version or None}`` for PlaCo, pink, pinocchio and daqp."""
    from importlib import metadata, util

    found = {}
    for name, module in PEER_MODULES.items():
        if util.find_spec(module) is None:
            found[name] = None
            continue
        dist = {"pink": "pin-pink", "pinocchio": "pin"}.get(name, name)
        try:
            found[name] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            found[name] = "?"
    return found


def _placo_robot(urdf):
    """PlaCo's RobotWrapper of an example-robot-data URDF (its package:// mesh URIs made
    absolute: PlaCo loads the meshes), no collision pairs."""
    import placo

    text = urdf.read_text()
    for folder in urdf.parents:
        if folder.name == "example-robot-data":
            text = text.replace("package://example-robot-data/", f"{folder}/")
    return placo.RobotWrapper(str(urdf.parent), placo.Flags.ignore_collisions, text)


class _PlacoMap:
    """MuJoCo <-> PlaCo (pinocchio) configurations and velocities, joints matched by name;
    with ``floating``, MuJoCo's free joint (x, y, z, qw, qx, qy, qz) and pinocchio's
    free-flyer (x, y, z, qx, qy, qz, qw)."""

    def __init__(self, model, robot, floating: bool):
        import mujoco

        self.floating = floating
        self.mj_q, self.pl_q, self.mj_v, self.pl_v, self.names = [], [], [], [], []
        for j in range(model.njnt):
            if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
                continue
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)
            self.names.append(name)
            self.mj_q.append(model.jnt_qposadr[j])
            self.pl_q.append(robot.get_joint_offset(name))
            self.mj_v.append(model.jnt_dofadr[j])
            self.pl_v.append(robot.get_joint_v_offset(name))
        self.mj_q, self.pl_q = np.array(self.mj_q), np.array(self.pl_q)
        self.mj_v, self.pl_v = np.array(self.mj_v), np.array(self.pl_v)
        self.nq, self.nv = robot.model.nq, robot.model.nv

    def to_placo(self, q):
        out = np.zeros(self.nq)
        out[6] = 1.0  # identity free-flyer (masked when the base is fixed)
        if self.floating:
            out[:3] = q[:3]
            out[3:7] = q[[4, 5, 6, 3]]
        out[self.pl_q] = q[self.mj_q]
        return out

    def to_mujoco(self, q_placo, nq):
        out = np.zeros(nq)
        if self.floating:
            out[:3] = q_placo[:3]
            out[3:7] = q_placo[[6, 3, 4, 5]]
        out[self.mj_q] = q_placo[self.pl_q]
        return out

    def dq_to_mujoco(self, dq, nv):
        out = np.zeros(nv)
        out[self.mj_v] = dq[self.pl_v]
        return out


def _pose(position, rotation):
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = position
    return T


def _rotvec_error(rotation, target):
    from scipy.spatial.transform import Rotation

    return float(np.linalg.norm(Rotation.from_matrix(rotation @ target.T).as_rotvec()))


def _report_peers(title, times, references, extra=None) -> None:
    """Medians [us] and the ratios of each method's median to each reference's."""
    print(f"\n{title}")
    head = f"  {'method':40s} {'median us':>10s} {'p95 us':>9s}"
    head += "".join(f" {'/' + short:>11s}" for short in references.values())
    print(head)
    for name, t in times.items():
        median = float(np.median(t))
        line = f"  {name:40s} {median:10.1f} {np.percentile(t, 95):9.1f}"
        for ref in references:
            line += f" {median / float(np.median(times[ref])):11.2f}"
        if extra and name in extra:
            line += f"   {extra[name]}"
        print(line)


def _panda_states(configuration, home, frame: str, n: int, rng, regime: str) -> list:
    """``n`` states ``(q, p, R, posture)`` of the Panda peers' regime ``regime``: ``q``
    uniform within 0.6 rad of ``home`` (clipped to the limits), the frame's target its pose
    there moved by up to 1 mm and 1 mrad (``both bind``: 0.3 m and 0.5 rad), the posture
    target ``q`` moved by 1e-4 rad (``both bind``: up to 1.5 rad). Both ``q`` and the
    posture target keep the URDF's finger mimic (:func:`_on_mimics`): a state the robot
    can be in, as a closed loop's are."""
    from scipy.spatial.transform import Rotation

    model = configuration.model
    nv = model.nv
    states = []
    for _ in range(n):
        q = np.clip(home + rng.uniform(-0.6, 0.6, nv), configuration.lower, configuration.upper)
        q = _on_mimics(model, q)
        configuration.update(q)
        p, R = configuration.frame_pose(frame, "body")
        far = regime == "both bind"
        p = p + rng.uniform(-1, 1, 3) * (0.3 if far else 0.001)
        R = Rotation.from_rotvec(rng.uniform(-1, 1, 3) * (0.5 if far else 0.001)).as_matrix() @ R
        move = rng.uniform(-1.5, 1.5, nv) if far else 1e-4
        posture = _on_mimics(model, np.clip(q + move, configuration.lower, configuration.upper))
        states.append((q, p, R, posture))
    return states


def _on_mimics(model, q: np.ndarray) -> np.ndarray:
    """``q`` ``(nq,)`` with each active joint equality between two joints met (a URDF
    mimic): the first joint's coordinate set from the second's by the equality's
    polynomial, ``q1 - q1_0 = sum_k c_k (q2 - q2_0)^k`` (MuJoCo's joint equality, ``_0``
    at ``qpos0``). Random draws, each joint on its own, leave the Panda's two fingers up to
    4 cm apart, where the mimic holds them together: qpik's default level then spends the
    step closing that gap, a start no robot or closed loop gives it."""
    import mujoco

    from qpik.model.couplings import model_couplings

    q = np.array(q, dtype=float)
    for e in range(model.neq):
        if model.eq_type[e] != mujoco.mjtEq.mjEQ_JOINT or model.eq_obj2id[e] < 0:
            continue
        if not model.eq_active0[e]:
            continue
        a1 = model.jnt_qposadr[model.eq_obj1id[e]]
        a2 = model.jnt_qposadr[model.eq_obj2id[e]]
        s = q[a2] - model.qpos0[a2]
        q[a1] = model.qpos0[a1] + np.polyval(model.eq_data[e, 4::-1], s)
    couplings = model_couplings(model)
    assert couplings is None or couplings.error(q) < 1e-12, "a mimic left unmet"
    return q


def _panda_placo(urdf, frame: str, frame_priority: str):
    """PlaCo's solver of the Panda peers' problem: the frame task ``frame_priority`` (hard
    or soft, weight 1), the posture soft with weight 0.01 (mink's cost 0.1, squared), joint
    and velocity limits; ``(robot, solver, frame task, posture task)``."""
    import placo

    robot = _placo_robot(urdf)
    solver = placo.KinematicsSolver(robot)
    solver.mask_fbase(True)
    solver.enable_joint_limits(True)
    solver.enable_velocity_limits(True)
    solver.dt = DT
    task = solver.add_frame_task(frame, np.eye(4))
    task.configure("frame", frame_priority, 1.0, 1.0)
    posture = solver.add_joints_task()
    posture.configure("posture", "soft", 0.01)  # mink's cost 0.1, squared
    return robot, solver, task, posture


def panda_peers(n_states: int, rng: np.random.Generator, regimes=("free", "both bind")) -> None:
    """Panda (example-robot-data's URDF, 9 DoF), a pose task over a posture, position and
    velocity limits: qpik's two strict levels, PlaCo (frame task hard, posture soft; and
    both soft with mink's weights), pink + daqp and mink + daqp (one weighted level: pose
    cost 1, posture cost 0.1), on the same states, interleaved in blocks."""
    import pink
    import pinocchio
    from ik_methods import pinocchio_robot
    from pink.limits import ConfigurationLimit as PinkConfigurationLimit
    from pink.limits import VelocityLimit as PinkVelocityLimit

    from qpik.robots import locate_robot

    robot_name, frame = "erd:panda", "panda_hand_tcp"
    model = qpik.load_robot(robot_name)
    urdf = locate_robot(robot_name)
    configuration = qpik.Configuration(model)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
    home = configuration.mid_q()

    ours = (
        FrameTask(frame, "body", position_cost=1.0, orientation_cost=1.0),
        PostureTask(model, 0.1),
    )
    auto = qpik.IKSolver(model, [[ours[0]], [ours[1]]], limits)
    # The URDF's finger mimic (panda_finger_joint2 follows joint1) is a MuJoCo joint
    # equality, which qpik holds by default as a level above the stack (StepOptions
    # couplings); PlaCo, pink and mink move the two fingers independently. The same
    # problem as theirs: the two levels alone.
    uncoupled = qpik.IKSolver(model, [[ours[0]], [ours[1]]], limits, couplings=False)
    # PlaCo's "both soft" problem (and mink's, pink's): the two tasks one weighted level.
    weighted = qpik.IKSolver(model, [[ours[0], ours[1]]], limits, couplings=False)
    theirs = (mink.FrameTask(frame, "body", position_cost=1.0, orientation_cost=1.0),
              mink.PostureTask(model, 0.1))  # fmt: skip

    robot_pin = pinocchio_robot(robot_name, model, frame, "body")
    pink_configuration = pink.Configuration(
        robot_pin.model, robot_pin.model.createData(), robot_pin.q_to_pinocchio(home)
    )
    pink_tasks = [pink.FrameTask(frame, position_cost=1.0, orientation_cost=1.0),
                  pink.PostureTask(cost=0.1)]  # fmt: skip
    pink_limits = [PinkConfigurationLimit(robot_pin.model), PinkVelocityLimit(robot_pin.model)]

    placos = {kind: _panda_placo(urdf, frame, kind) for kind in ("hard", "soft")}
    mapping = _PlacoMap(model, placos["hard"][0], floating=False)
    # The same pose of the frame in both models at the start.
    robot = placos["hard"][0]
    robot.state.q = mapping.to_placo(home)
    robot.update_kinematics()
    configuration.update(home)
    gap = np.abs(
        robot.get_T_world_frame(frame)[:3, 3] - configuration.frame_pose(frame, "body")[0]
    ).max()
    assert gap < 1e-9, f"PlaCo's and MuJoCo's {frame} differ by {gap} m"

    def random_states(regime):
        return _panda_states(configuration, home, frame, n_states, rng, regime)

    def set_state(state):
        q, p, R, posture = state
        configuration.update(q)
        se3 = mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(R), p)
        for task, post in (ours, theirs):
            task.set_target(se3)
            post.set_target(posture)
        pink_configuration.update(robot_pin.q_to_pinocchio(q))
        pink_tasks[0].set_target(pin_se3(R, p))
        pink_tasks[1].set_target(robot_pin.q_to_pinocchio(posture))
        joints = {name: float(posture[a]) for name, a in zip(mapping.names, mapping.mj_q)}
        for robot, _solver, task, post in placos.values():
            robot.state.q = mapping.to_placo(q)
            robot.update_kinematics()
            task.T_world_frame = _pose(p, R)
            post.set_joints(joints)
        return configuration

    def pin_se3(R, p):
        return pinocchio.SE3(np.asarray(R, float), np.asarray(p, float))

    failures = {}

    def placo_step(kind):
        solver = placos[kind][1]

        def step(_c):
            try:
                return solver.solve(True)
            except Exception:  # infeasible hard task: PlaCo raises (QPError)
                failures[kind] = failures.get(kind, 0) + 1
                return None

        return step

    names = {
        "qpik": "qpik IKSolver.step, 2 levels + mimic",
        "qpik2": "qpik IKSolver.step, couplings=False",
        "qpikw": "qpik 1 weighted level, couplings=False",
        "hard": "PlaCo solve(True), frame hard/posture soft",
        "soft": "PlaCo solve(True), both soft (mink's w)",
        "pink": "pink + daqp, 1 weighted level",
        "mink": "mink + daqp, 1 weighted level",
    }
    methods = {
        names["qpik"]: lambda c: auto.step(c, DT),
        names["qpik2"]: lambda c: uncoupled.step(c, DT),
        names["qpikw"]: lambda c: weighted.step(c, DT),
        names["hard"]: placo_step("hard"),
        names["soft"]: placo_step("soft"),
        names["pink"]: lambda c: pink.solve_ik(
            pink_configuration, pink_tasks, DT, solver="daqp", damping=1e-6, limits=pink_limits
        ),
        names["mink"]: lambda c: mink.solve_ik(
            c, list(theirs), DT, "daqp", damping=1e-6, limits=limits
        ),
    }

    def placo_refresh(kind):
        return lambda state: placos[kind][0].update_kinematics()

    refresh = {
        names["qpik"]: lambda state: configuration.update(state[0]),
        names["qpik2"]: lambda state: configuration.update(state[0]),
        names["qpikw"]: lambda state: configuration.update(state[0]),
        names["mink"]: lambda state: configuration.update(state[0]),
        names["hard"]: placo_refresh("hard"),
        names["soft"]: placo_refresh("soft"),
        names["pink"]: lambda state: pink_configuration.update(robot_pin.q_to_pinocchio(state[0])),
    }

    def answers(state):
        """Each method's dq (MuJoCo's order) at the state, untimed; None where it failed."""
        out = {}
        c = set_state(state)
        out[names["qpik"]] = auto.step(c, DT).velocity * DT
        c = set_state(state)
        out[names["qpik2"]] = uncoupled.step(c, DT).velocity * DT
        c = set_state(state)
        out[names["qpikw"]] = weighted.step(c, DT).velocity * DT
        for kind in ("hard", "soft"):
            c = set_state(state)
            try:
                out[names[kind]] = mapping.dq_to_mujoco(placos[kind][1].solve(False), model.nv)
            except Exception:
                out[names[kind]] = None
        c = set_state(state)
        v = pink.solve_ik(
            pink_configuration, pink_tasks, DT, solver="daqp", damping=1e-6, limits=pink_limits
        )
        out[names["pink"]] = robot_pin.v_to_mujoco(v) * DT
        c = set_state(state)
        out[names["mink"]] = (
            mink.solve_ik(c, list(theirs), DT, "daqp", damping=1e-6, limits=limits) * DT
        )
        return out

    print(
        f"\nPanda (erd:panda URDF, nv = {model.nv}; PlaCo, pink and qpik's MuJoCo model load the "
        f"same file), pose task on {frame} + posture (cost 0.1), position + velocity limits, "
        f"dt = {DT} s; found: " + ", ".join(f"{k} {v}" for k, v in peers_found().items())
    )
    for regime in regimes:
        states = random_states(regime)
        failures.clear()
        times = time_methods(methods, states, set_state, refresh=refresh)
        # Answers: the frame's error after the step (FK of q + dq), the posture's, and the
        # largest difference from qpik's dq; the velocity limits' largest excess.
        vmax = limits[1].limit * DT
        stats = {name: [] for name in methods}
        for state in states[:: max(1, len(states) // 100)]:
            q, p, R, posture = state
            dqs = answers(state)
            for name, dq in dqs.items():
                if dq is None:
                    continue
                qn = q + dq  # hinge joints, fixed base
                configuration.update(np.clip(qn, configuration.lower, configuration.upper))
                pn, Rn = configuration.frame_pose(frame, "body")
                stats[name].append((
                    1e3 * np.linalg.norm(pn - p), 1e3 * _rotvec_error(Rn, R),
                    float(np.linalg.norm(qn - posture)),
                    float(np.abs(dq - dqs[names["qpik"]]).max()),
                    float(max(0.0, (np.abs(dq[limits[1].indices]) - vmax).max())),
                ))  # fmt: skip
        extra = {}
        for name, rows in stats.items():
            if not rows:
                extra[name] = "failed on every sampled state"
                continue
            a = np.array(rows)
            extra[name] = (
                f"after the step: frame {a[:, 0].mean():.3f} mm {a[:, 1].mean():.3f} mrad, "
                f"posture {a[:, 2].mean():.3f} rad, |dq - qpik's| max {a[:, 3].max():.1e}, "
                f"velocity excess max {a[:, 4].max():.1e}"
            )
        for kind in ("hard", "soft"):
            if failures.get(kind):
                extra[names[kind]] += (
                    f", FAILED (raised) on {failures[kind]} of {len(states)} timed steps"
                )
        refs = {names["hard"]: "PlaCo hard", names["soft"]: "PlaCo soft", names["mink"]: "mink"}
        _report_peers(
            f"  regime '{regime}', {len(states)} states (per-step wall time; ratio: median / "
            "the reference's)", times, refs, extra,
        )  # fmt: skip
    _print_update_costs(
        configuration, home, placos["hard"][0], mapping, pink_configuration, robot_pin
    )


def _print_update_costs(configuration, q, robot, mapping, pink_configuration=None, robot_pin=None):
    """The kinematics updates before a step (not counted in the step times above)."""
    rows = {"qpik/mink Configuration.update": lambda: configuration.update(q)}
    q_placo = mapping.to_placo(q)

    def placo_update():
        robot.state.q = q_placo
        robot.update_kinematics()

    rows["PlaCo update_kinematics"] = placo_update
    if pink_configuration is not None:
        q_pin = robot_pin.q_to_pinocchio(q)
        rows["pink Configuration.update"] = lambda: pink_configuration.update(q_pin)
    medians = {}
    for name, call in rows.items():
        t = []
        for _ in range(300):
            t0 = time.perf_counter()
            call()
            t.append(time.perf_counter() - t0)
        medians[name] = 1e6 * float(np.median(t))
    print(
        "  kinematics update before a step (not in the step times): "
        + ", ".join(f"{name} {value:.1f} us" for name, value in medians.items())
    )


class _TalosScene:
    """The floating erd Talos problem of :func:`talos_peers` (and of ``--instructions``):
    the model, its position and velocity limits, ``half_sitting``, the feet held where they
    start, the CoM swaying between the feet over ``n_steps`` steps, both hands circling
    (from the middle on the left hand's target 0.6 m away, out of reach), the posture at
    ``half_sitting``."""

    feet = ("left_sole_link", "right_sole_link")
    hands = ("gripper_left_base_link", "gripper_right_base_link")

    def __init__(self, n_steps: int):
        from qpik.robots import locate_robot

        self.n_steps = n_steps
        self.model = model = qpik.load_robot("erd:talos", floating_base=True)
        self.urdf = locate_robot("erd:talos")
        self.home = model.key_qpos[0].copy()
        self.limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
        self.probe = probe = qpik.Configuration(model, self.home)
        self.foot_poses = [probe.frame_pose(f, "body") for f in self.feet]
        self.com0 = probe.data.subtree_com[1].copy()
        self.hand_starts = [probe.frame_pose(h, "body")[0] for h in self.hands]
        self.half = 0.5 * abs(self.foot_poses[0][0][1] - self.foot_poses[1][0][1])

    def targets_at(self, k: int):
        """Step ``k``'s CoM target and the two hands' position targets [m, world]."""
        com = self.com0 + np.array(
            [0.0, 0.5 * self.half * np.sin(2 * np.pi * k / self.n_steps), 0.0]
        )
        angle = 2 * np.pi * k / 100
        circle = 0.05 * np.array([0.0, np.cos(angle) - 1.0, np.sin(angle)])
        away = np.array([0.6, 0.3, 0.2]) if k >= self.n_steps // 2 else np.zeros(3)
        return com, [self.hand_starts[0] + circle + away, self.hand_starts[1] + circle]

    def stack(self, kind: str = "qpik", com_cost: float | None = None) -> list:
        """The four levels (feet, CoM, hands, posture) of qpik's tasks (``kind`` "qpik") or
        mink's (costs 10 on the feet and the CoM: mink weighs, qpik ranks); ``com_cost``
        overrides the CoM task's cost."""
        from qpik.tasks import ComTask

        F = FrameTask if kind == "qpik" else mink.FrameTask
        C = ComTask if kind == "qpik" else mink.ComTask
        P = PostureTask if kind == "qpik" else mink.PostureTask
        w = 1.0 if kind == "qpik" else 10.0  # qpik: levels, not weights
        foot = [F(f, "body", position_cost=w, orientation_cost=w) for f in self.feet]
        for task, (p, R) in zip(foot, self.foot_poses):
            task.set_target(mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(R), p))
        hand = [F(h, "body", position_cost=1.0, orientation_cost=0.0) for h in self.hands]
        posture = P(self.model, 0.1)
        posture.set_target(self.home)
        return [foot, [C(w if com_cost is None else com_cost)], hand, [posture]]

    def set_targets(self, levels: list, k: int) -> None:
        """Step ``k``'s targets on the CoM and hand tasks of ``levels`` (a :meth:`stack`)."""
        com, hand_targets = self.targets_at(k)
        levels[1][0].set_target(com)
        for task, target in zip(levels[2], hand_targets):
            task.set_target(mink.SE3.from_translation(target))

    def set_placo_targets(self, com_task, hand_tasks, k: int) -> None:
        """Step ``k``'s targets on PlaCo's CoM and hand tasks (of :meth:`placo`)."""
        com, hand_targets = self.targets_at(k)
        com_task.target_world = com
        for task, target in zip(hand_tasks, hand_targets):
            task.target_world = target

    def placo(self, robot, mapping, polygon=None):
        """PlaCo's solver of the problem on ``robot`` at ``half_sitting``: the feet hard; CoM,
        hands and posture soft (weights 100, 1, 0.01); joint and velocity limits; with
        ``polygon`` (corners [m]), its CoM polygon constraint (2 cm margin). Returns
        ``(robot, solver, com_task, hand_tasks)``; PlaCo's frames checked equal to MuJoCo's."""
        import placo

        solver = placo.KinematicsSolver(robot)
        solver.enable_joint_limits(True)
        solver.enable_velocity_limits(True)
        solver.dt = DT
        for f, (p, R) in zip(self.feet, self.foot_poses):
            task = solver.add_frame_task(f, _pose(p, R))
            task.configure(f, "hard", 1.0, 1.0)
        com_task = solver.add_com_task(self.com0)
        com_task.configure("com", "soft", 100.0)
        hand_tasks = []
        for h, p in zip(self.hands, self.hand_starts):
            task = solver.add_position_task(h, p)
            task.configure(h, "soft", 1.0)
            hand_tasks.append(task)
        posture = solver.add_joints_task()
        posture.set_joints({n: float(self.home[a]) for n, a in zip(mapping.names, mapping.mj_q)})
        posture.configure("posture", "soft", 0.01)
        if polygon is not None:
            solver.add_com_polygon_constraint([np.array(c) for c in polygon], 0.02)
        robot.state.q = mapping.to_placo(self.home)
        robot.update_kinematics()
        gaps = [
            np.abs(robot.get_T_world_frame(f)[:3, 3] - self.probe.frame_pose(f, "body")[0]).max()
            for f in self.feet + self.hands
        ]
        assert max(gaps) < 1e-9, f"PlaCo's and MuJoCo's frames differ by {max(gaps)} m"
        return robot, solver, com_task, hand_tasks


#: The methods of the Talos peer section (``--talos-methods``), by key.
TALOS_METHODS = ("qpik", "qpik1", "qpikp", "qpiks", "placo", "placos", "daqph", "mink")


#: A joint speed [rad/s or m/s] above which _chatter counts a sign change between two steps.
CHATTER_SPEED = 0.2


def _chatter(v: np.ndarray) -> tuple[float, float]:
    """``v`` (steps, nv): a closed loop's joint speeds over a stretch of steps. Their rms
    [rad/s, m/s], and the share [%] of the pairs (dof, two consecutive steps) where the dof's
    speed changes sign with both speeds above :data:`CHATTER_SPEED`: about 0 for a loop that
    tracks smoothly or comes to rest, up to 100 on a dof that shakes between two vertices of
    its velocity box."""
    if len(v) < 2:
        return float("nan"), float("nan")
    both = (np.abs(v[1:]) > CHATTER_SPEED) & (np.abs(v[:-1]) > CHATTER_SPEED)
    flips = np.mean(both & (np.sign(v[1:]) != np.sign(v[:-1])))
    return float(np.sqrt(np.mean(v**2))), float(100 * flips)


def talos_peers(n_steps: int = 300, methods: tuple | None = None) -> None:
    """Talos (example-robot-data, floating base), feet held (6-D) / CoM swaying between the
    feet / both hands (position; from the middle on the left hand's target is 0.6 m away, out
    of reach) / posture, position and velocity limits, each method in its own closed loop at
    100 Hz from half_sitting, stepped in lockstep (the order rotating): qpik's four strict
    levels, without and with one second-order correction pass
    (:attr:`qpik.StepOptions.correction_passes`: the held levels' remainder at ``q (+) dq``
    shifted out of their targets and the step solved again); PlaCo with its two (feet hard;
    CoM, hands and posture soft, weights 100, 1, 0.01), and qpik on that same problem (the
    feet a strict level, CoM, hands and posture one weighted level with costs 10, 1, 0.1,
    the square roots of PlaCo's weights); mink + daqp's one weighted level
    (costs 10, 10, 1, 0.1: the same weights); DAQP's hierarchical mode on qpik's four
    levels' rows (:func:`_daqp_hierarchical`: the strict hierarchy solved by the field's
    dedicated solver, no certificate; its time is ``daqp.solve``'s alone, the rows made by
    :meth:`qpik.IKSolver.build` not counted). With the feet's support polygon besides
    (2 cm margin, the soles' collision meshes): qpik's four levels with
    :class:`qpik.limits.SupportPolygonLimit` (its hull made from the feet at every step),
    and PlaCo's problem with its CoM polygon constraint on the polygon at the start (its
    corners given once: the feet are held). Task errors are measured by MuJoCo's
    kinematics at each method's configuration after each step.

    The feet are held exactly in each step's rows (qpik's level 0, PlaCo's hard task), so
    what remains after the step is its second-order remainder, the curvature of the legs'
    and the free joint's motion: about ``c |dq_legs|^2`` (``dq_legs``: the step's free-joint
    and leg entries, by mj_differentiatePos from the configuration before to the one
    after), ``c`` of the same size for qpik and PlaCo (it depends on the step's direction,
    not on the solver). The report gives each method's rms of ``|dq_legs|`` and the median
    of ``feet error / |dq_legs|^2``: where that median is alike, a larger feet error comes
    from larger steps, not from a less exact one. mink's feet are weighted, not held, and
    keep a first-order error besides (a larger median). The corrected qpik row removes the
    second-order term itself: what it leaves is of third order (a smaller median).

    ``methods`` (keys of :data:`TALOS_METHODS`, ``--talos-methods``): only those, interleaved
    the same way (the others' rows left out; a ratio column only where its reference ran),
    e.g. qpik's four levels and PlaCo alone, to see whether one of them is slower in a run as
    a whole."""
    import mujoco
    from scipy.spatial import ConvexHull

    from qpik.limits import SupportPolygonLimit
    from qpik.tasks import ComTask

    scene = _TalosScene(n_steps)
    model, home, limits, probe = scene.model, scene.home, scene.limits, scene.probe
    feet, hands, foot_poses = scene.feet, scene.hands, scene.foot_poses
    targets_at, stack, set_targets = scene.targets_at, scene.stack, scene.set_targets

    ours, theirs = stack("qpik"), stack("mink")
    auto = qpik.IKSolver(model, ours, limits)
    # The same four levels with one second-order correction pass (StepOptions
    # correction_passes): the held levels' targets shifted by their remainder at q (+) dq.
    ours_corrected = stack("qpik")
    corrected = qpik.IKSolver(model, ours_corrected, limits, correction_passes=1)
    # PlaCo's own problem by qpik: the feet a strict level, CoM, hands and posture one
    # weighted level below with PlaCo's weights (100, 1, 0.01: costs 10, 1, 0.1).
    ours_placo = stack("qpik")
    ours_placo[1] = [ComTask(10.0)]
    placo_problem = qpik.IKSolver(
        model, [ours_placo[0], ours_placo[1] + ours_placo[2] + ours_placo[3]], limits
    )
    # The four levels with the feet's support polygon (SupportPolygonLimit, 2 cm margin, the
    # soles' collision meshes: its hull recomputed from the feet every step), and PlaCo's
    # problem with its CoM polygon constraint on that polygon at the start (PlaCo takes the
    # polygon's corners as given; the feet are held, so it stays the same).
    support = SupportPolygonLimit(model, list(feet), margin=0.02)
    ours_support = stack("qpik")
    supported = qpik.IKSolver(model, ours_support, [*limits, support])
    solvers = {
        "qpik": (auto, ours),
        "qpik1": (corrected, ours_corrected),
        "qpikp": (placo_problem, ours_placo),
        "qpiks": (supported, ours_support),
    }
    flat = [t for level in theirs for t in level]
    ground = support.support_points(probe)
    polygon = ground[ConvexHull(ground).vertices]  # counter-clockwise corners

    robot = _placo_robot(scene.urdf)
    mapping = _PlacoMap(model, robot, floating=True)
    placos = {
        "placo": scene.placo(robot, mapping),
        "placos": scene.placo(_placo_robot(scene.urdf), mapping, polygon),
    }

    # DAQP's hierarchical mode on the rows of qpik's four levels (IKSolver.build, not timed)
    ours_daqp = stack("qpik")
    daqp_rows = qpik.IKSolver(model, ours_daqp, limits)
    names = ("qpik", "qpik1", "qpikp", "qpiks", "daqph", "mink")
    configs = {name: qpik.Configuration(model, home) for name in names}
    label = {
        "qpik": "qpik IKSolver.step, 4 strict levels",
        "qpik1": "qpik 4 levels + 1 correction",
        "qpikp": "qpik 2 levels: feet / PlaCo's soft",
        "qpiks": "qpik 4 levels + support polygon",
        "placo": "PlaCo solve(True), feet hard + 3 soft",
        "placos": "PlaCo, the same + CoM polygon",
        "daqph": "DAQP hierarchical, qpik's 4 levels",
        "mink": "mink + daqp, 1 weighted level",
    }
    binding = 0  # qpik's steps where the polygon binds
    times = {name: [] for name in label.values()}
    errors = {name: [] for name in label.values()}
    failed = dict.fromkeys(label.values(), 0)
    # the CoM's margin after each step of the methods that hold the polygon
    margins: dict = {label["qpiks"]: [], label["placos"]: []}
    measure = qpik.Configuration(model, home)
    # The dofs whose motion moves the feet: the free joint's and every joint above a sole.
    legs = set()
    for f in feet:
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f)
        while body > 0:
            start = model.body_dofadr[body]
            legs.update(range(start, start + model.body_dofnum[body]))
            body = model.body_parentid[body]
    legs = np.array(sorted(legs))
    previous = dict.fromkeys(label, home)
    # each step's displacement (mj_differentiatePos from the configuration before)
    steps: dict = {name: [] for name in label.values()}
    dq = np.zeros(model.nv)

    def step(name, k):
        nonlocal binding
        if name in placos:
            robot, solver, com_task, hand_tasks = placos[name]
            scene.set_placo_targets(com_task, hand_tasks, k)
            t0 = time.perf_counter()
            try:
                solver.solve(True)
            except Exception:
                failed[label[name]] += 1
            elapsed = time.perf_counter() - t0
            robot.update_kinematics()
            return elapsed, mapping.to_mujoco(robot.state.q, model.nq)
        c = configs[name]
        if name == "daqph":
            set_targets(ours_daqp, k)
            solve = _daqp_hierarchical(daqp_rows.build(c, DT))
            t0 = time.perf_counter()
            x, exitflag = solve()
            elapsed = time.perf_counter() - t0
            if exitflag < 0:
                failed[label[name]] += 1
                x = np.zeros(model.nv)
            c.update(c.integrate(x / DT, DT))
            return elapsed, c.q
        set_targets(solvers[name][1] if name in solvers else theirs, k)
        t0 = time.perf_counter()
        if name in solvers:
            result = solvers[name][0].step(c, DT)
            v = result.velocity
        else:
            v = mink.solve_ik(c, flat, DT, "daqp", damping=1e-6, limits=limits)
        elapsed = time.perf_counter() - t0
        if name == "qpiks":
            binding += any("SupportPolygon" in a for a in result.active_limits)
        c.update(c.integrate(v, DT))
        return elapsed, c.q

    order = [name for name in label if methods is None or name in methods]
    for name in set(label) - set(order):
        del times[label[name]], errors[label[name]]
    for k in range(n_steps):
        com, hand_targets = targets_at(k)
        for i in range(len(order)):
            name = order[(k + i) % len(order)]
            elapsed, q = step(name, k)
            times[label[name]].append(elapsed)
            mujoco.mj_differentiatePos(model, dq, 1.0, previous[name], q)
            previous[name] = q.copy()
            steps[label[name]].append(dq.copy())
            measure.update(q)
            foot_err = max(
                max(1e3 * np.linalg.norm(measure.frame_pose(f, "body")[0] - p),
                    1e3 * _rotvec_error(measure.frame_pose(f, "body")[1], R))
                for f, (p, R) in zip(feet, foot_poses)
            )  # fmt: skip
            com_err = 1e3 * np.linalg.norm(measure.data.subtree_com[1] - com)
            hand_err = [
                1e3 * np.linalg.norm(measure.frame_pose(h, "body")[0] - t)
                for h, t in zip(hands, hand_targets)
            ]
            errors[label[name]].append((foot_err, com_err, *hand_err))
            if label[name] in margins:
                margins[label[name]].append(support.com_margin(measure))
    extra = {}
    h = n_steps // 2
    for name, rows in errors.items():
        a = np.array(rows)
        moves = np.array(steps[name])
        s = np.linalg.norm(moves[:, legs], axis=1)
        speeds = moves / DT
        moved = s > 1e-6
        extra[name] = (
            f"feet {a[:, 0].mean():.3f} (max {a[:, 0].max():.3f}), CoM {a[:, 1].mean():.2f} "
            f"(max {a[:, 1].max():.2f}), right hand {a[:, 3].mean():.2f}, left hand in reach "
            f"{a[:h, 2].mean():.2f} / out of reach {a[h:, 2].mean():.1f}; |dq_legs| rms "
            f"{np.sqrt(np.mean(s**2)):.3f}, feet / |dq_legs|^2 median "
            f"{np.median(a[moved, 0] / s[moved] ** 2):.0f}; median us in reach "
            f"{1e6 * np.median(times[name][:h]):.1f} / out of reach "
            f"{1e6 * np.median(times[name][h:]):.1f}"
            + "; joint speed rms, sign changes: in reach {:.2f}, {:.1f} % / out of reach "
            "{:.2f}, {:.1f} %".format(*_chatter(speeds[:h]), *_chatter(speeds[h:]))
            + (f"; {name.split()[0]} failed on {failed[name]} steps" if failed[name] else "")
            + (f"; the polygon binds on {binding} steps" if name == label["qpiks"] else "")
            + (
                f"; CoM margin min {1e3 * min(margins[name]):.1f} mm"
                if name in (label["qpiks"], label["placos"])
                else ""
            )
        )
    _report_peers(
        f"\nTalos (erd:talos, floating base, nv = {model.nv}), feet / CoM / hands / posture, "
        f"position + velocity limits, {n_steps} steps at 100 Hz, each method in its own closed "
        "loop (per-step wall time; ratio: median / the reference's; task errors after each "
        "step, mean [mm, feet: max of mm and mrad], by MuJoCo's kinematics; the left hand's "
        "target is 0.6 m out of reach in the second half; |dq_legs|: the step's free-joint "
        "and leg entries [m, rad]: the feet error after a step is its second-order term)",
        {name: 1e6 * np.array(t) for name, t in times.items()},
        {label[k]: short for k, short in (("placo", "PlaCo"), ("mink", "mink")) if k in order},
        extra,
    )
    _print_update_costs(configs["qpik"], home, robot, mapping)


def _daqp_hierarchical(problem: qpik.core.HierarchyProblem):
    """``solve() -> (dq, exitflag)``: ``problem`` (a :meth:`qpik.IKSolver.build`) by DAQP's
    hierarchical mode (:func:`daqp_hier.daqp_hierarchical`, as benchmarks/hqp.py calls it:
    the limits its first level, each task level's weighted rows soft equalities)."""
    levels = [(level.A, level.b) for level in problem.levels]
    daqp_solve = daqp_hierarchical(problem.lb, problem.ub, problem.G, problem.h, levels)

    def solve() -> tuple[np.ndarray, int]:
        x, _, exitflag, _ = daqp_solve()
        return np.asarray(x, dtype=float), int(exitflag)

    return solve


# ----------------------------------------------------------------- instruction counts
#: The methods of --instructions, per case: (key, label).
COUNT_METHODS = {
    "panda": (
        ("qpik", "qpik IKSolver.step, 2 levels + mimic"),
        ("qpik2", "qpik IKSolver.step, couplings=False"),
        ("placo", "PlaCo solve(True), frame hard/posture soft"),
    ),
    "talos": (
        ("qpik", "qpik IKSolver.step, 4 strict levels"),
        ("qpikp", "qpik 2 levels: feet / PlaCo's soft"),
        ("placo", "PlaCo solve(True), feet hard + 3 soft"),
    ),
}


def _count_case(case: str, method: str, n: int):
    """The states of an --instructions case (``n`` of them) and, for ``method``,
    ``(set_state(k), step())``: ``set_state`` updates the method's kinematics and targets at
    state ``k`` (counted in both runs), ``step`` is the call measured. Panda: the peers'
    problem of :func:`panda_peers`, states of its ``free`` regime. Talos: the problem of
    :func:`talos_peers` (:class:`_TalosScene`), at the configurations of qpik's own closed
    loop of its four levels, the same states for every method."""
    from qpik.robots import locate_robot

    if case == "panda":
        frame = "panda_hand_tcp"
        model = qpik.load_robot("erd:panda")
        limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model)]
        configuration = qpik.Configuration(model)
        rng = np.random.default_rng(0)
        states = _panda_states(configuration, configuration.mid_q(), frame, n, rng, "free")
        if method.startswith("qpik"):
            tasks = (
                FrameTask(frame, "body", position_cost=1.0, orientation_cost=1.0),
                PostureTask(model, 0.1),
            )
            solver = qpik.IKSolver(
                model, [[tasks[0]], [tasks[1]]], limits, couplings=method == "qpik"
            )

            def set_state(k):
                q, p, R, posture = states[k]
                configuration.update(q)
                tasks[0].set_target(
                    mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(R), p)
                )
                tasks[1].set_target(posture)

            return set_state, lambda: solver.step(configuration, DT)
        robot, solver, task, posture_task = _panda_placo(locate_robot("erd:panda"), frame, "hard")
        mapping = _PlacoMap(model, robot, floating=False)

        def set_state(k):
            q, p, R, posture = states[k]
            robot.state.q = mapping.to_placo(q)
            robot.update_kinematics()
            task.T_world_frame = _pose(p, R)
            posture_task.set_joints(
                {j: float(posture[a]) for j, a in zip(mapping.names, mapping.mj_q)}
            )

        return set_state, lambda: solver.solve(True)
    scene = _TalosScene(n)
    model = scene.model
    configuration = qpik.Configuration(model, scene.home)
    # The states: qpik's own closed loop (four strict levels) from half_sitting.
    levels = scene.stack()
    reference = qpik.IKSolver(model, levels, scene.limits)
    states = []
    for k in range(n):
        states.append(configuration.q.copy())
        scene.set_targets(levels, k)
        velocity = reference.step(configuration, DT).velocity
        configuration.update(configuration.integrate(velocity, DT))
    if method.startswith("qpik"):
        levels = scene.stack(com_cost=1.0 if method == "qpik" else 10.0)
        stacked = levels if method == "qpik" else [levels[0], levels[1] + levels[2] + levels[3]]
        solver = qpik.IKSolver(model, stacked, scene.limits)

        def set_state(k):
            configuration.update(states[k])
            scene.set_targets(levels, k)

        return set_state, lambda: solver.step(configuration, DT)
    robot = _placo_robot(scene.urdf)
    mapping = _PlacoMap(model, robot, floating=True)
    robot, solver, com_task, hand_tasks = scene.placo(robot, mapping)

    def set_state(k):
        robot.state.q = mapping.to_placo(states[k])
        robot.update_kinematics()
        scene.set_placo_targets(com_task, hand_tasks, k)

    return set_state, lambda: solver.solve(True)


def _count_child(case: str, method: str, mode: str, n: int) -> None:
    """The process valgrind counts: the case set up, then ``n`` states, each set and (mode
    ``step``) stepped; mode ``base`` sets them only (the difference is the steps' count)."""
    set_state, step = _count_case(case, method, n)
    set_state(0)  # one step in both runs: the first one's set-up is not counted
    try:
        step()
    except Exception:
        pass
    for k in range(n):
        set_state(k)
        if mode == "step":
            try:
                step()
            except Exception:  # PlaCo raises where a hard task cannot be met
                pass


def count_instructions(cases: list, n: int) -> None:
    """Instructions per step of each method, counted by valgrind (callgrind's instruction
    count of the whole process, the run that steps less the run that only sets the states:
    the same set-up, the same states and kinematics updates). A count is a property of the
    code and the inputs, not of the machine's load: the figure to compare two versions by,
    or qpik with PlaCo (which runs in the same process kind); it is not a time (instructions
    per cycle differ between codes)."""
    import os
    import re
    import shutil
    import subprocess
    import sys

    if shutil.which("valgrind") is None:
        print("\ninstruction counts skipped: valgrind is not installed")
        return
    if peers_found().get("placo") is None:
        print("\ninstruction counts skipped: PlaCo is not installed (pip install -e '.[compare]')")
        return
    env = dict(os.environ, PYTHONHASHSEED="0", OPENBLAS_NUM_THREADS="1")

    def collected(case, method, mode):
        cmd = [
            "valgrind",
            "--tool=callgrind",
            "--callgrind-out-file=/dev/null",
            sys.executable,
            __file__,
            "--count-child",
            case,
            method,
            mode,
            str(n),
        ]
        run = subprocess.run(cmd, env=env, capture_output=True, text=True)
        found = re.findall(r"Collected\s*:\s*(\d+)", run.stderr)
        if run.returncode != 0 or not found:
            tail = [line for line in run.stderr.splitlines() if not line.startswith("==")][-3:]
            print(f"  {case} {method} ({mode}): the counted run failed: {' / '.join(tail)}")
            return None
        return int(found[-1])

    for case in cases:
        print(f"\ninstructions per step, {case} ({n} states; valgrind, each method alone):")
        counts = {}
        for key, label in COUNT_METHODS[case]:
            step, base = collected(case, key, "step"), collected(case, key, "base")
            counts[label] = None if step is None or base is None else (step - base) / n
        ref = counts[COUNT_METHODS[case][-1][1]]
        for label, value in counts.items():
            if value is None:
                print(f"  {label:44s} {'failed':>12s}")
                continue
            ratio = f"/PlaCo {value / ref:5.2f}" if ref else ""
            print(f"  {label:44s} {value:12,.0f}   {ratio}")


#: Bytes written between the timed steps of --cache's "flushed" regime: twice this machine
#: class's L2 (2 MiB a core), so that neither the step's code nor its data is left in L1 or
#: L2 (the last-level cache, hundreds of MiB on a server, is not flushed).
FLUSH_BYTES = 4 * 2**20


def cache_regimes(cases: list, n: int, reps: int = 2) -> None:
    """Median time per step of the --instructions methods (qpik's strict levels, qpik on
    PlaCo's problem where there is one, PlaCo) at the same states in three cache states:
    ``hot`` (each method's steps back to back: its code and data stay in L1/L2), ``flushed``
    (FLUSH_BYTES written between the state's update and the step: both start in the last-level
    cache) and ``interleaved`` (at each state every method's step in turn, the order rotating:
    each starts after the others ran, as in :func:`panda_peers` and :func:`talos_peers`).
    Where the ratio to PlaCo is about 1 hot and above 1 flushed, the gap is the step's
    footprint (code and data brought back from the last-level cache), not its instructions;
    where it is above 1 hot too, the instructions (or their dependence chains)."""
    if peers_found().get("placo") is None:
        print("\ncache regimes skipped: PlaCo is not installed (pip install -e '.[compare]')")
        return
    buffer = np.zeros(FLUSH_BYTES // 8)

    def timed(set_state, step, k, flush=False):
        set_state(k)
        if flush:
            buffer[:] += 1.0
        t0 = time.perf_counter()
        try:
            step()
        except Exception:  # PlaCo raises where a hard task cannot be met
            pass
        return time.perf_counter() - t0

    for case in cases:
        methods = COUNT_METHODS[case]
        runs = {label: _count_case(case, key, n) for key, label in methods}
        for set_state, step in runs.values():  # (set-up outside the timings)
            timed(set_state, step, 0)
        halves = {"": range(n)} if case == "panda" else {
            " in reach": range(n // 2), " out of reach": range(n // 2, n)
        }  # fmt: skip
        times = {(label, regime, half): [] for label in runs for regime in ("hot", "flushed",
                 "interleaved") for half in halves}  # fmt: skip
        labels = list(runs)
        for _ in range(reps):
            for half, ks in halves.items():
                for label, (set_state, step) in runs.items():
                    for regime, flush in (("hot", False), ("flushed", True)):
                        times[(label, regime, half)] += [
                            timed(set_state, step, k, flush) for k in ks
                        ]
                for i, k in enumerate(ks):
                    for j in range(len(labels)):
                        label = labels[(i + j) % len(labels)]
                        times[(label, "interleaved", half)].append(timed(*runs[label], k))
        what = "free regime" if case == "panda" else "qpik's closed-loop states"
        print(f"\ncache regimes, {case} ({n} states, {what}; median us a step, x {reps}; "
              f"ratio to PlaCo's in the same regime):")  # fmt: skip
        for half in halves:
            print(f"  {'method' + half:44s} {'hot':>14s} {'flushed':>14s} {'interleaved':>14s}")
            ref = labels[-1]
            for label in labels:
                cells = []
                for regime in ("hot", "flushed", "interleaved"):
                    value = 1e6 * np.median(times[(label, regime, half)])
                    base = 1e6 * np.median(times[(ref, regime, half)])
                    cells.append(f"{value:7.1f} ({value / base:4.2f})")
                print(f"  {label:44s} " + " ".join(f"{c:>14s}" for c in cells))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--states", type=at_least(1), default=400)
    parser.add_argument("--talos-states", type=at_least(1), default=400)
    parser.add_argument("--no-talos", action="store_true")
    parser.add_argument("--seed", type=at_least(0), default=0)
    parser.add_argument(
        "--peers",
        choices=["on", "off", "only", "talos"],
        default="on",
        help="issue 20's sections beside PlaCo and pink (erd:panda, Talos floating): on "
        "(after qpik's own), off, only them, or talos (only the floating-Talos one)",
    )
    parser.add_argument(
        "--peer-states", type=at_least(1), default=400, help="erd:panda states a regime"
    )
    parser.add_argument(
        "--talos-steps", type=at_least(2), default=300, help="closed-loop Talos steps"
    )
    parser.add_argument(
        "--talos-methods",
        default=",".join(TALOS_METHODS),
        help="the Talos peer section's methods, comma-separated keys of "
        f"{', '.join(TALOS_METHODS)} (default: all), e.g. qpik,placo",
    )
    parser.add_argument(
        "--instructions",
        action="store_true",
        help="instructions per step of qpik and PlaCo (Panda, Talos), counted by valgrind "
        "(a figure no machine load changes), then exit",
    )
    parser.add_argument(
        "--cache",
        action="store_true",
        help="the --instructions methods' times hot, after a cache flush and interleaved "
        "(where the gap to PlaCo lies: instructions or footprint), then exit",
    )
    parser.add_argument("--count-states", type=at_least(1), default=100, help="states a count")
    parser.add_argument("--count-child", nargs=4, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.count_child:
        case, method, mode, n = args.count_child
        _count_child(case, method, mode, int(n))
        return
    if args.instructions:
        count_instructions(["panda", "talos"], args.count_states)
        return
    if args.cache:
        cache_regimes(["panda", "talos"], args.count_states * 3)
        return
    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    model = qpik.load_robot("panda")
    posture = PostureTask(model, 1.0)
    configuration = qpik.Configuration(model)
    posture.set_target(configuration.q)
    qpik.IKSolver(model, posture).step(configuration, DT)  # loads (or compiles) the kernels
    first = time.perf_counter() - t0
    print(f"first step of the process (the C++ engine is built ahead of time): {first:.3f} s")
    if args.peers not in ("only", "talos"):
        panda(args.states, rng)
        if not args.no_talos:
            talos(args.talos_states)
    if args.peers == "off":
        return
    found = peers_found()
    missing = [name for name, version in found.items() if version is None]
    if missing:
        print(f"\npeers skipped: {', '.join(missing)} not installed (pip install -e '.[compare]')")
        return
    if args.peers != "talos":
        panda_peers(args.peer_states, rng)
    if not args.no_talos or args.peers == "talos":
        methods = tuple(m for m in args.talos_methods.split(",") if m)
        unknown = sorted(set(methods) - set(TALOS_METHODS))
        if unknown or not methods:
            parser.error(f"--talos-methods: unknown {unknown}; known: {', '.join(TALOS_METHODS)}")
        talos_peers(args.talos_steps, methods)


if __name__ == "__main__":
    import bench_cli  # benchmarks/bench_cli.py (this folder is on sys.path)

    bench_cli.run(main)
