"""IK success-rate benchmark: reachable pose targets, methods side by side.

Protocol (issue 6). Per robot, ``n`` reachable targets: the pose of the robot's tool frame
(:data:`ROBOT_FRAMES`) at ``n`` configurations drawn uniformly within the joint limits
(unlimited joints: [-pi, pi]), from a fixed seed. Every solve starts at the mid-range
configuration. A solve succeeds when, at the configuration it returns, checked here and not
taken from the method's own report,

* the position error is <= ``tol_position`` (1e-4 m) and the orientation error (angle of
  ``R R_des^T``) <= ``tol_orientation`` (1e-3 rad),
* every joint lies within its limits (up to ``LIMIT_TOL``),
* and the wall time of the call is within ``budget`` (50 ms; also passed to the method as
  its time budget).

Methods (:data:`METHODS`), run interleaved target by target (in a fresh seeded random
order for each target), so machine noise, and what the method before leaves in the caches,
hit all alike. Every method restarts from a random
configuration within the limits when an attempt ends (100 iterations, or 5 iterations
without a 1 % decrease of the error), until it converges or the budget ends: the comparison
isolates the step rule.

* ``qpik``: :func:`qpik.solve` with OSQP, its default options.
* ``pinv``: the lecture's IGM, ``q <- q + J^+ c`` with the 6-D pose error, joint positions
  clipped into the limits after each step (:func:`qpik.igm.baselines.pseudoinverse_igm`).
* ``dls``: the same loop with damped least squares, damping 0.05
  (:func:`qpik.igm.baselines.damped_least_squares_igm`).
* ``mink``: ``mink.solve_ik`` (a ``FrameTask``, ``ConfigurationLimit``, solver daqp when
  installed else osqp, ``dt = 1``, ``damping = 1e-3`` as in mink's examples), integrated by
  mink, in the same restart loop (:func:`qpik.igm.baselines.igm`); only when mink imports.
* ``pink``: ``pink.solve_ik`` on the same robot loaded by pinocchio (the same URDF file for
  ``erd:`` robots, the MJCF file for bundled ones), with the same ``FrameTask``, a
  ``ConfigurationLimit`` (gain 0.95, mink's default), solver, ``dt`` and damping as ``mink``,
  in the same restart loop; joints are mapped between pinocchio's and MuJoCo's orders by name,
  and the limits and the frame's forward kinematics are checked to agree
  (:func:`pinocchio_robot`). Only when pink and pinocchio import (``pip install
  'qpik[compare]'``); on a robot pinocchio cannot load (or where a check fails), it is
  skipped with the reason (``skipped`` in the results, a line under the table). pinocchio
  4.1's MJCF parser misplaces the bundled panda's site ``ee`` (nested fixed bodies): its
  frame is rebuilt from its body's frame, with a note (``notes``).

Finger joints: ``erd:panda`` has 9 DoF, 7 arm joints and 2 finger joints. The tool frame
``panda_hand_tcp`` is fixed to the hand, upstream of the fingers, so the finger columns of
its Jacobian are zero: every method's step leaves the fingers where they start (least-norm
steps: pseudoinverse, damped least squares, the QPs), at mid-range, or at their random value
after a restart; they do not change the pose. The benchmark reports the DoF that move the
frame (``arm_dof``) next to the model's ``nv``.
"""

from __future__ import annotations

import platform
import sys
import time
import warnings
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from ik_methods import (
    METHODS,
    PEERS,
    MethodUnavailable,
    Outcome,
    PinocchioRobot,
    UrdfChain,
    available_methods,
    peer_methods,
    pinocchio_robot,
    urdf_chain,
)
from scipy.spatial.transform import Rotation

from qpik.errors import QpikError
from qpik.model.configuration import Configuration, FrameType
from qpik.robots import ERD_ROBOTS, erd_robots_folder, load_robot, tool_frame

__all__ = [
    "COARSE",
    "DEFAULT_BUDGET",
    "GOAL_MEAN_MS",
    "GOAL_MEDIAN_MS",
    "GOAL_SUCCESS",
    "TRACIK",
    "TRACIK_PUBLISHED",
    "IKProtocol",
    "check_goals",
    "check_peer_goals",
    "DEFAULT_N",
    "LIMIT_TOL",
    "METHODS",
    "ROBOT_FRAMES",
    "MethodUnavailable",
    "Outcome",
    "PinocchioRobot",
    "PEERS",
    "UrdfChain",
    "available_methods",
    "peer_methods",
    "urdf_chain",
    "default_robots",
    "format_table",
    "pinocchio_robot",
    "print_table",
    "robot_frame",
    "run_ik_success",
    "within_tolerance",
]

#: Targets per robot by default (the full run of the headline protocol uses 10,000).
DEFAULT_N = 1000
#: Time budget per solve [s] of the second protocol.
DEFAULT_BUDGET = 0.05
#: Tolerance of the joint-limit check on returned configurations [rad or m].
LIMIT_TOL = 1e-6


@dataclass(frozen=True)
class IKProtocol:
    """A success criterion: tolerances [m], [rad], the time budget per solve [s] (``None``:
    no limit, for tests) and whether the tolerances apply to each axis (TRAC-IK: each of
    x, y, z and of the rotation vector's components) or to the norms."""

    name: str
    tol_position: float
    tol_orientation: float
    budget: float | None
    per_axis: bool


#: TRAC-IK's protocol (Beeson & Ames 2015): 1e-5 on each axis of the position and of the
#: rotation vector, 5 ms per solve.
TRACIK = IKProtocol("trac-ik", 1e-5, 1e-5, 0.005, True)
#: qpik's earlier protocol (issue 6): 1e-4 m and 1e-3 rad (norms), 50 ms per solve.
COARSE = IKProtocol("coarse", 1e-4, 1e-3, DEFAULT_BUDGET, False)

#: TRAC-IK's published figures under its protocol: success rate and mean time over all
#: solves [ms] (C++), keyed by the robot they correspond to here.
TRACIK_PUBLISHED: dict[str, tuple[str, float, float]] = {
    "erd:ur5": ("UR5", 0.9917, 0.37),
    "erd:panda": ("Panda", 0.9988, 0.37),
    "panda": ("Panda", 0.9988, 0.37),
    "erd:kinova": ("Jaco2", 0.9992, 0.35),
    "erd:iiwa": ("iiwa14", 0.9992, 0.28),
}

#: Goals of issue 11 under the TRAC-IK protocol (success per arm, mean and median [ms]).
GOAL_SUCCESS = 0.999
GOAL_MEAN_MS = 0.3
GOAL_MEDIAN_MS = 0.25


#: The tool frame of each robot: ``name -> (frame, frame type)``. A bundled robot not listed
#: uses its site ``ee``.
ROBOT_FRAMES: dict[str, tuple[str, FrameType]] = {
    "ur5e": ("ee", FrameType.SITE),
    "panda": ("ee", FrameType.SITE),
    "planar_2r": ("ee", FrameType.SITE),
    "planar_4r": ("ee", FrameType.SITE),
    "erd:panda": ("panda_hand_tcp", FrameType.BODY),
    "erd:ur3": ("tool0", FrameType.BODY),
    "erd:ur5": ("tool0", FrameType.BODY),
    "erd:ur10": ("tool0", FrameType.BODY),
    "erd:xarm7": ("link_eef", FrameType.BODY),
    "erd:kinova": ("j2s6s200_end_effector", FrameType.BODY),
    "erd:z1": ("gripperStator", FrameType.BODY),
}

#: Robots benchmarked by default: the bundled arms, then every 6- and 7-DoF arm of
#: example-robot-data that loads (:func:`default_robots`).
_DEFAULT_BUNDLED = ("ur5e", "panda")
#: example-robot-data names that repeat another one's arm.
_ERD_DUPLICATES = {"talos_arm"}


def default_robots() -> list[str]:
    """The bundled ``ur5e`` and ``panda``, plus every arm of example-robot-data
    (:data:`qpik.robots.ERD_ROBOTS`) that loads here and whose tool frame is moved by 6 or 7
    joints (``erd:panda``, ``erd:ur3``, ``erd:ur5``, ``erd:ur10``, ``erd:xarm7``,
    ``erd:talos_left_arm``, ``erd:kinova``, ``erd:z1`` with example-robot-data 6)."""
    robots = list(_DEFAULT_BUNDLED)
    try:
        names = sorted(ERD_ROBOTS)
        erd_robots_folder()
    except QpikError:
        return robots
    for name in names:
        if name in _ERD_DUPLICATES:
            continue
        robot = f"erd:{name}"
        try:
            model = load_quietly(robot)
            frame, frame_type = robot_frame(robot, model)
        except (QpikError, ValueError):
            continue
        configuration = Configuration(model)
        if _arm_dof(configuration, frame, frame_type) in (6, 7) and model.nv <= 9:
            robots.append(robot)
    return robots


def load_quietly(name: str) -> mujoco.MjModel:
    """:func:`qpik.load_robot` of ``name`` without its warnings (dropped collision meshes:
    the kinematics are the same); raises its typed errors."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # dropped collision meshes: kinematics unchanged
        return load_robot(name)


def robot_frame(name: str, model: mujoco.MjModel) -> tuple[str, FrameType]:
    """The tool frame benchmarked on robot ``name``: :data:`ROBOT_FRAMES`, else the site
    ``ee``, else for an ``erd:`` robot :func:`qpik.robots.tool_frame`'s choice; raises
    :class:`ValueError` naming the known robots when there is none."""
    if name in ROBOT_FRAMES:
        return ROBOT_FRAMES[name]
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "ee") >= 0:
        return "ee", FrameType.SITE
    if name.startswith("erd:"):
        tool = tool_frame(model)
        return tool.name, FrameType.parse(tool.frame_type)
    raise ValueError(
        f"no tool frame known for robot {name!r} and it has no site 'ee'; known robots: "
        + ", ".join(ROBOT_FRAMES)
    )


def _errors(configuration, frame, frame_type, position, rotation) -> tuple[np.ndarray, np.ndarray]:
    """Position error ``p - p_des`` (3,) [m] and rotation vector ``log(R R_des^T)`` (3,)
    [rad], both in the world frame, at the configuration."""
    current_position, current_rotation = configuration.frame_pose(frame, frame_type)
    rotation_vector = Rotation.from_matrix(current_rotation @ rotation.T).as_rotvec()
    return current_position - position, rotation_vector


def within_tolerance(
    position_error: np.ndarray,
    rotation_vector: np.ndarray,
    tol_position: float,
    tol_orientation: float,
    per_axis: bool,
) -> bool:
    """Whether an error is within tolerance: each axis of the position error [m] and of the
    rotation vector [rad] (``per_axis``, TRAC-IK's criterion), or their norms."""
    p = np.asarray(position_error, dtype=float)
    r = np.asarray(rotation_vector, dtype=float)
    if per_axis:
        return bool(np.abs(p).max() <= tol_position and np.abs(r).max() <= tol_orientation)
    return bool(np.linalg.norm(p) <= tol_position and np.linalg.norm(r) <= tol_orientation)


def _arm_dof(configuration: Configuration, frame: str, frame_type: FrameType) -> int:
    """Number of joints that move the frame (nonzero Jacobian columns at mid-range)."""
    configuration.update(configuration.mid_q())
    jacobian = configuration.frame_jacobian(frame, frame_type)
    return int(np.count_nonzero(np.abs(jacobian).max(axis=0) > 1e-12))


def _stat(values: Sequence[float], statistic, scale: float = 1.0) -> float:
    """``scale * statistic(values)``, NaN for no values."""
    return scale * float(statistic(values)) if len(values) else float("nan")


def _summary(records: list[dict], budget: float | None) -> dict:
    # Complexity ~20 is the comprehensions' filters: one flat expression per metric.
    times = [r["time"] for r in records]
    success = [r for r in records if r["success"]]
    failures = [r for r in records if not r["success"]]
    n = len(records)
    return {
        "n": n,
        "successes": len(success),
        "success_rate": len(success) / n if n else float("nan"),
        "first_attempt_successes": sum(r["restarts"] == 0 for r in success),
        "mean_ms": _stat(times, np.mean, 1e3),
        "median_ms": _stat(times, np.median, 1e3),
        "p95_ms": _stat(times, lambda t: np.percentile(t, 95), 1e3),
        "max_ms": _stat(times, np.max, 1e3),
        "cpu_mean_ms": _stat([r["cpu_time"] for r in records], np.mean, 1e3),
        "cpu_median_ms": _stat([r["cpu_time"] for r in records], np.median, 1e3),
        "median_success_ms": _stat([r["time"] for r in success], np.median, 1e3),
        "mean_iterations": _stat([r["iterations"] for r in records], np.mean),
        "median_iterations": _stat([r["iterations"] for r in records], np.median),
        "median_restarts": _stat([r["restarts"] for r in records], np.median),
        "limit_violations": sum(not r["within_limits"] for r in records),
        "failures": {
            "not_within_tolerance": sum(not r["within_tolerance"] for r in failures),
            "over_budget": sum(budget is not None and r["time"] > budget for r in failures),
            "outside_limits": sum(not r["within_limits"] for r in failures),
        },
        "failure_reasons": dict(Counter(str(r["reason"]) for r in failures)),
        "failure_examples": [_example(r) for r in failures[:5]],
    }


def _example(record: dict) -> dict:
    """A failure, as the results list it."""
    keys = ("target", "reason", "position_error", "orientation_error")
    return {key: record[key] for key in keys} | {
        "time_ms": 1e3 * record["time"],
        "iterations": record["iterations"],
        "restarts": record["restarts"],
    }


def run_ik_success(
    robots: Sequence[str] | None = None,
    n: int = DEFAULT_N,
    methods: Sequence[str] | None = None,
    seed: int = 0,
    budget: float | None = DEFAULT_BUDGET,
    progress: bool = True,
    *,
    tol_position: float = 1e-4,
    tol_orientation: float = 1e-3,
    per_axis: bool = False,
    protocol: IKProtocol | None = None,
) -> dict:
    """Run the benchmark (see the module docstring) and return its results, JSON-ready:
    ``{"protocol": ..., "platform": ..., "robots": {robot: {"nv", "arm_dof", "frame",
    "frame_type", "time_s", "methods": {method: summary}, "skipped": {method: reason},
    "notes": {method: [message]}}}}``.
    A summary holds ``n``, ``successes``, ``success_rate``, ``first_attempt_successes``
    (successes without a restart: from the mid-range start alone), ``mean_ms`` (TRAC-IK's
    figure), ``median_ms``, ``p95_ms`` and ``max_ms`` (wall time of every solve, failures
    included), ``median_success_ms``, ``mean_iterations``, ``median_iterations``,
    ``median_restarts``, ``limit_violations`` (returned configurations outside the limits),
    the failures by kind and by the method's reason, and up to five failure examples.
    ``skipped``: ``{method: reason}`` for the methods that cannot run on that robot here
    (:class:`MethodUnavailable`; e.g. pink without pinocchio); they have no summary.
    ``notes``: ``{method: [message]}``, the warnings a method raised while binding to the
    robot (e.g. a frame of pinocchio's model that had to be corrected).

    ``robots``: names :func:`qpik.load_robot` accepts (default :func:`default_robots`);
    ``methods``: keys of :data:`METHODS` (default :func:`available_methods`); ``budget``:
    time per solve [s], or ``None`` for no limit (success then ignores time: tests use
    this, so that a loaded machine cannot fail them); ``tol_position`` [m] and
    ``tol_orientation`` [rad] apply to the norms, or with ``per_axis`` to each axis of the
    position error and of the rotation vector ``log(R R_des^T)`` (world frame); the
    methods iterate to the same numbers as norms, which implies both. ``protocol`` (e.g.
    :data:`TRACIK`) sets budget, tolerances and per_axis at once. ``progress``: a progress
    line per robot on stderr.
    """
    if protocol is not None:
        budget, per_axis = protocol.budget, protocol.per_axis
        tol_position, tol_orientation = protocol.tol_position, protocol.tol_orientation
    robots = list(robots) if robots is not None else default_robots()
    methods = list(methods) if methods is not None else available_methods()
    _check_arguments(methods, n, budget, tol_position, tol_orientation)
    criterion = _Criterion(tol_position, tol_orientation, per_axis, budget)
    results: dict = {
        "protocol": {
            "name": protocol.name if protocol is not None else "custom",
            "n": n,
            "seed": seed,
            "budget_s": budget,
            "tol_position_m": tol_position,
            "tol_orientation_rad": tol_orientation,
            "per_axis": per_axis,
            "limit_tol": LIMIT_TOL,
            "start": "mid-range configuration",
            "targets": "FK of uniform random q within the limits (unlimited: [-pi, pi])",
            "methods": methods,
        },
        "platform": {
            "python": platform.python_version(),
            "machine": platform.machine(),
            "processor": platform.processor(),
            "mujoco": mujoco.__version__,
        },
        "robots": {},
    }
    for robot_index, robot in enumerate(robots):
        results["robots"][robot] = _run_robot(
            robot, robot_index, methods, n, seed, criterion, progress
        )
    return results


def _check_arguments(methods, n, budget, tol_position, tol_orientation) -> None:
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise ValueError(f"unknown method(s) {unknown}; known: {', '.join(METHODS)}")
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    if budget is not None and not budget > 0:
        raise ValueError(f"budget must be > 0 seconds or None, got {budget}")
    if not (tol_position > 0 and tol_orientation > 0):
        raise ValueError("tolerances must be > 0")


@dataclass(frozen=True)
class _Criterion:
    """What counts as a success: tolerances [m], [rad], per axis or norms, budget [s]."""

    tol_position: float
    tol_orientation: float
    per_axis: bool
    budget: float | None


def _bind(model, frame, frame_type, robot, methods, criterion):
    """``(bound methods, skipped {method: reason}, notes {method: [warning]})``."""
    bound, skipped, notes = {}, {}, {}
    for name in methods:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            keywords = {
                "robot": robot,
                "tol_position": criterion.tol_position,
                "tol_orientation": criterion.tol_orientation,
            }
            if getattr(METHODS[name], "per_axis", False):  # TRAC-IK: its epsilon is per axis
                keywords["per_axis"] = criterion.per_axis
            try:
                bound[name] = METHODS[name](model, frame, frame_type, **keywords)
            except MethodUnavailable as exc:
                skipped[name] = exc.reason
        if caught:
            notes[name] = [str(w.message) for w in caught]
    return bound, skipped, notes


def _run_robot(robot, robot_index, methods, n, seed, criterion, progress) -> dict:
    """One robot's entry of the results: every method on the same ``n`` targets."""
    model = load_quietly(robot)
    frame, frame_type = robot_frame(robot, model)
    configuration = Configuration(model)
    configuration.frame_id(frame, frame_type)  # unknown frame: a clear error, early
    bound, skipped, notes = _bind(model, frame, frame_type, robot, methods, criterion)
    running = list(bound)
    # Warm-up, untimed: the first call of a method loads its compiled code.
    q_mid = configuration.mid_q()
    configuration.update(q_mid)
    home = configuration.frame_pose(frame, frame_type)
    for name in running:
        bound[name](*home, q_mid.copy(), np.random.default_rng(0), criterion.budget)
    target_rng = np.random.default_rng([seed, robot_index])
    targets = []
    for _ in range(n):
        configuration.update(configuration.random_q(target_rng))
        targets.append(configuration.frame_pose(frame, frame_type))
    q0 = configuration.mid_q()
    records: dict[str, list[dict]] = {name: [] for name in running}
    start = time.perf_counter()
    for i, target in enumerate(targets):
        # A fresh order for each target (seeded): a plain rotation keeps every method's
        # predecessor fixed (qpik always right after TRAC-IK, say), and a method's time
        # depends on what ran before it: TRAC-IK's working set evicts much of the caches
        # (on erd:ur5, a qpik solve right after one takes 0.059 ms against 0.037 ms after
        # the other methods). Shuffled, each method follows each other equally often.
        order = np.random.default_rng([seed, robot_index, i, 1 << 20]).permutation(len(running))
        for k in order:
            name = running[k]
            rng = np.random.default_rng([seed, robot_index, i, list(METHODS).index(name)])
            record = _timed(
                bound[name], configuration, (frame, frame_type), target, q0, rng, criterion.budget
            )
            records[name].append(_judged(record, i, criterion))
        if progress:
            _report(robot, i + 1, n, start)
    elapsed_robot = time.perf_counter() - start
    if progress:
        _report(robot, None, n, start)
    return {
        "nv": model.nv,
        "arm_dof": _arm_dof(configuration, frame, frame_type),
        "frame": frame,
        "frame_type": frame_type.value,
        "time_s": elapsed_robot,
        "methods": {name: _summary(records[name], criterion.budget) for name in running},
        "skipped": skipped,
        "notes": notes,
    }


_SETTLE_NOISE = 5e-6  # [s] the jitter of _other_threads_cpu's two clock reads


def _other_threads_cpu() -> float:
    """The CPU time [s] of this process's threads other than the calling one."""
    return time.process_time() - time.thread_time()


def _settle(limit: float = 0.01) -> None:
    """Wait, untimed, until this process's other threads stop running (at most ``limit``
    seconds). TRAC-IK runs its two solvers in threads that go on for tens of microseconds
    after ``ik`` returns (about 40 us of CPU per call on erd:ur5): without this wait that work
    overlaps the next method's timed call, and the same method always follows it."""
    end = time.perf_counter() + limit
    before = _other_threads_cpu()
    while time.perf_counter() < end:
        time.sleep(1e-4)
        now = _other_threads_cpu()
        if now - before <= _SETTLE_NOISE:
            return
        before = now


def _timed(method, configuration, frame_key, target, q0, rng, budget) -> dict:
    """Run one method on one target from ``q0``; the errors measured here, not taken from
    the method's report, at the configuration it returns."""
    position, rotation = target
    others = _other_threads_cpu()
    cpu = time.thread_time()
    tic = time.perf_counter()
    outcome = method(position, rotation, q0.copy(), rng, budget)
    elapsed = time.perf_counter() - tic
    cpu = time.thread_time() - cpu
    if _other_threads_cpu() - others > _SETTLE_NOISE:
        _settle()
    configuration.update(outcome.q)
    dp, dr = _errors(configuration, *frame_key, position, rotation)
    return {
        "dp": dp,
        "dr": dr,
        "within_limits": configuration.within_limits(LIMIT_TOL),
        "time": elapsed,
        "cpu_time": cpu,
        "outcome": outcome,
    }


def _judged(record: dict, target: int, criterion: _Criterion) -> dict:
    """A timed solve against the criterion, as the summary reads it."""
    dp, dr, outcome = record["dp"], record["dr"], record["outcome"]
    in_tolerance = within_tolerance(
        dp, dr, criterion.tol_position, criterion.tol_orientation, criterion.per_axis
    )
    in_time = criterion.budget is None or record["time"] <= criterion.budget
    return {
        "target": target,
        "success": in_tolerance and record["within_limits"] and in_time,
        "within_tolerance": in_tolerance,
        "within_limits": record["within_limits"],
        "time": record["time"],
        "cpu_time": record["cpu_time"],
        "iterations": outcome.iterations,
        "restarts": outcome.restarts,
        "reason": outcome.reason,
        "position_error": float(np.linalg.norm(dp)),
        "orientation_error": float(np.linalg.norm(dr)),
    }


def _report(robot: str, done: int | None, total: int, start: float, stream=sys.stderr) -> None:
    """Progress on stderr: a line per robot, redrawn about once a second on a terminal."""
    now = time.perf_counter() - start
    if done is None:
        stream.write(f"\r{robot}: {total}/{total} targets in {now:.0f} s\n")
        stream.flush()
        return
    if stream.isatty() and (done == 1 or int(now) != int(_report.last)):  # type: ignore[attr-defined]
        stream.write(f"\r{robot}: {done}/{total} targets, {now:.0f} s")
        stream.flush()
    _report.last = now  # type: ignore[attr-defined]


_report.last = 0.0  # type: ignore[attr-defined]


def _criterion(protocol: dict) -> str:
    axis = " on each axis" if protocol.get("per_axis") else ""
    budget = protocol["budget_s"]
    within = f"within {1e3 * budget:g} ms" if budget is not None else "no time limit"
    return (
        f"position <= {protocol['tol_position_m']:g} m{axis}, orientation <= "
        f"{protocol['tol_orientation_rad']:g} rad{axis} (rotation vector), within limits, "
        f"{within}"
    )


def format_table(results: dict) -> str:
    """The results as a text table: one row per robot and method, TRAC-IK's published
    figures beside the robots it published (under its own protocol)."""
    protocol = results["protocol"]
    header = (
        f"{'robot':<19} {'DoF':>4} {'frame':<22} {'method':<7} {'success':>22} "
        f"{'1st try':>7} {'mean ms':>7} {'median ms':>9} {'p95 ms':>7} {'iters':>6} "
        f"{'limit viol':>10}"
    )
    tracik = protocol.get("name") == TRACIK.name
    if tracik:
        header += f"  {'TRAC-IK published':<24}"
    lines = [
        f"IK success ({protocol.get('name', 'custom')} protocol): {protocol['n']} reachable "
        f"pose targets per robot (seed {protocol['seed']}), start at mid-range, success = "
        + _criterion(protocol),
        header,
        "-" * len(header),
    ]
    for robot, entry in results["robots"].items():
        dof = (
            f"{entry['arm_dof']}"
            if entry["arm_dof"] == entry["nv"]
            else f"{entry['arm_dof']}+{entry['nv'] - entry['arm_dof']}"
        )
        for method, s in entry["methods"].items():
            success = f"{100 * s['success_rate']:.2f}% ({s['successes']}/{s['n']})"
            first = f"{100 * s['first_attempt_successes'] / s['n']:.1f}%"
            line = (
                f"{robot:<19} {dof:>4} {entry['frame'][:22]:<22} {method:<7} {success:>22} "
                f"{first:>7} {s['mean_ms']:>7.3f} {s['median_ms']:>9.3f} {s['p95_ms']:>7.3f} "
                f"{s['mean_iterations']:>6.1f} {s['limit_violations']:>10d}"
            )
            if tracik and robot in TRACIK_PUBLISHED:
                arm, rate, mean = TRACIK_PUBLISHED[robot]
                line += f"  {arm} {100 * rate:.2f}% {mean:.2f} ms"
            lines.append(line)
    for robot, entry in results["robots"].items():
        for method, reason in entry.get("skipped", {}).items():
            lines.append(f"{method} skipped on {robot}: {reason}")
        for method, messages in entry.get("notes", {}).items():
            lines.extend(f"note, {method} on {robot}: {message}" for message in messages)
    lines.append(
        "DoF a+b: a joints move the frame, b (fingers) do not. 1st try: success without a "
        "restart (from mid-range alone). Times: wall time of every solve, failures included; "
        "iters: mean iterations per solve, restarts included."
    )
    if tracik:
        lines.append(
            "TRAC-IK published (Beeson & Ames 2015, C++, its own machine): success and mean "
            "time over all solves; iiwa14 is not in example-robot-data."
        )
    return "\n".join(lines)


def check_goals(headline: dict, second: dict | None = None, method: str = "qpik") -> list[str]:
    """Issue 11's goals, each as a line ``"met: ..."`` or ``"MISSED: ..."``: under the
    TRAC-IK protocol (``headline``), >= 99.9 % success on every 6- and 7-DoF arm, mean
    <= 0.3 ms and median <= 0.25 ms over all solves; under the second protocol, 100 %."""
    lines = []

    def verdict(ok: bool, text: str) -> None:
        lines.append(("met: " if ok else "MISSED: ") + text)

    entries = [
        (robot, entry["methods"][method])
        for robot, entry in headline["robots"].items()
        if method in entry["methods"] and entry["arm_dof"] in (6, 7)
    ]
    for robot, s in entries:
        verdict(
            s["success_rate"] >= GOAL_SUCCESS,
            f"{robot}: success {100 * s['success_rate']:.2f}% >= {100 * GOAL_SUCCESS:.1f}%",
        )
    if entries:
        times = [s["mean_ms"] * s["n"] for _, s in entries]
        mean = sum(times) / sum(s["n"] for _, s in entries)
        worst_mean = max(s["mean_ms"] for _, s in entries)
        worst_median = max(s["median_ms"] for _, s in entries)
        verdict(mean <= GOAL_MEAN_MS, f"mean over all arms {mean:.3f} ms <= {GOAL_MEAN_MS} ms")
        verdict(
            worst_mean <= GOAL_MEAN_MS,
            f"mean of the slowest arm {worst_mean:.3f} ms <= {GOAL_MEAN_MS} ms",
        )
        verdict(
            worst_median <= GOAL_MEDIAN_MS,
            f"median of the slowest arm {worst_median:.3f} ms <= {GOAL_MEDIAN_MS} ms",
        )
    if second is not None:
        for robot, entry in second["robots"].items():
            if method in entry["methods"]:
                s = entry["methods"][method]
                verdict(
                    s["successes"] == s["n"],
                    f"{robot}: {100 * s['success_rate']:.2f}% under the second protocol "
                    "(goal 100.0%)",
                )
    return lines


#: Issue 20's goals under the TRAC-IK protocol: success on these arms, qpik's mean [ms], the
#: ratio of its mean to ik_LM's, and of the one-shot qpik.solve's mean to the session's.
PEER_GOAL_ROBOTS = ("erd:panda", "erd:ur5", "erd:xarm7", "erd:kinova")
PEER_GOAL_SUCCESS = 0.9995
PEER_GOAL_MEAN_MS = 0.12
PEER_GOAL_RTB_RATIO = 0.5
PEER_GOAL_ONESHOT_RATIO = 1.2


def check_peer_goals(headline: dict) -> list[str]:
    """Issue 20's goals, each as ``"met: ..."`` or ``"MISSED: ..."``, on the arms of
    :data:`PEER_GOAL_ROBOTS` in ``headline`` (the TRAC-IK protocol): qpik (the session)
    >= 99.95 % success, mean <= 0.12 ms and <= half of ``rtb_lm``'s mean; ``oneshot``
    (qpik.solve) mean <= 1.2x the session's. Also, beside them, TRAC-IK's figures."""
    lines = []

    def verdict(ok: bool, text: str) -> None:
        lines.append(("met: " if ok else "MISSED: ") + text)

    for robot in PEER_GOAL_ROBOTS:
        entry = headline["robots"].get(robot)
        if entry is None or "qpik" not in entry["methods"]:
            continue
        methods = entry["methods"]
        s = methods["qpik"]
        verdict(
            s["success_rate"] >= PEER_GOAL_SUCCESS,
            f"{robot}: qpik success {100 * s['success_rate']:.2f}% >= "
            f"{100 * PEER_GOAL_SUCCESS:.2f}%",
        )
        verdict(
            s["mean_ms"] <= PEER_GOAL_MEAN_MS,
            f"{robot}: qpik mean {s['mean_ms']:.3f} ms <= {PEER_GOAL_MEAN_MS} ms",
        )
        if "rtb_lm" in methods:
            ratio = s["mean_ms"] / methods["rtb_lm"]["mean_ms"]
            verdict(
                ratio <= PEER_GOAL_RTB_RATIO,
                f"{robot}: qpik mean / ik_LM mean {ratio:.2f} <= {PEER_GOAL_RTB_RATIO} "
                f"(ik_LM {methods['rtb_lm']['mean_ms']:.3f} ms, "
                f"{100 * methods['rtb_lm']['success_rate']:.2f}%)",
            )
        if "tracik" in methods:
            t = methods["tracik"]
            lines.append(
                f"beside: {robot}: TRAC-IK {100 * t['success_rate']:.2f}% mean "
                f"{t['mean_ms']:.3f} ms; qpik mean / TRAC-IK mean "
                f"{s['mean_ms'] / t['mean_ms']:.2f}"
            )
        if "oneshot" in methods:
            ratio = methods["oneshot"]["mean_ms"] / s["mean_ms"]
            verdict(
                ratio <= PEER_GOAL_ONESHOT_RATIO,
                f"{robot}: qpik.solve (one-shot) mean / IKSession mean {ratio:.2f} <= "
                f"{PEER_GOAL_ONESHOT_RATIO} ({methods['oneshot']['mean_ms']:.3f} ms)",
            )
    return lines


def print_table(results: dict, stream=None) -> None:
    """Print :func:`format_table` to ``stream`` (default stdout)."""
    print(format_table(results), file=stream or sys.stdout)
