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

Methods (:data:`METHODS`), run interleaved target by target (the order rotates from one
target to the next), so machine noise hits all alike. Every method restarts from a random
configuration within the limits when an attempt ends (100 iterations, or 5 iterations
without a 1 % decrease of the error), until it converges or the budget ends: the comparison
isolates the step rule.

* ``qpik``: :func:`qpik.solve` with OSQP, its default options.
* ``pinv``: the lecture's IGM, ``q <- q + J^+ c`` with the 6-D pose error, joint positions
  clipped into the limits after each step (:func:`qpik.baselines.pseudoinverse_igm`).
* ``dls``: the same loop with damped least squares, damping 0.05
  (:func:`qpik.baselines.damped_least_squares_igm`).
* ``mink``: ``mink.solve_ik`` (a ``FrameTask``, ``ConfigurationLimit``, solver daqp when
  installed else osqp, ``dt = 1``, ``damping = 1e-3`` as in mink's examples), integrated by
  mink, in the same restart loop (:func:`qpik.baselines.igm`); only when mink imports.

Finger joints: ``erd:panda`` has 9 DoF, 7 arm joints and 2 finger joints. The tool frame
``panda_hand_tcp`` is fixed to the hand, upstream of the fingers, so the finger columns of
its Jacobian are zero: every method's step leaves the fingers where they start (least-norm
steps: pseudoinverse, damped least squares, the QPs), at mid-range, or at their random value
after a restart; they do not change the pose. The benchmark reports the DoF that move the
frame (``arm_dof``) next to the model's ``nv``.
"""

from __future__ import annotations

import math
import platform
import sys
import time
import warnings
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import mujoco
import numpy as np

from .baselines import damped_least_squares_igm, igm, pseudoinverse_igm
from .configuration import Configuration, FrameType
from .converge import solve
from .errors import QpikError
from .robots import load_robot

__all__ = [
    "DEFAULT_BUDGET",
    "DEFAULT_N",
    "LIMIT_TOL",
    "METHODS",
    "ROBOT_FRAMES",
    "Outcome",
    "available_methods",
    "default_robots",
    "format_table",
    "print_table",
    "robot_frame",
    "run_ik_success",
]

#: Targets per robot by default.
DEFAULT_N = 1000
#: Time budget per solve [s].
DEFAULT_BUDGET = 0.05
#: Tolerance of the joint-limit check on returned configurations [rad or m].
LIMIT_TOL = 1e-6
#: Restarts allowed to every method: more than fit in the budget, so the budget binds.
RESTARTS = 100_000

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

#: Robots benchmarked by default: the bundled arms, then example-robot-data's when it is
#: installed (:func:`default_robots`).
_DEFAULT_BUNDLED = ("ur5e", "panda")
_DEFAULT_ERD = ("erd:panda", "erd:ur5", "erd:ur10", "erd:xarm7")


@dataclass
class Outcome:
    """What a method returned for one target: its configuration, iterations (all attempts),
    restarts and its own reason for stopping."""

    q: np.ndarray
    iterations: int
    restarts: int
    reason: str


class Method(Protocol):
    """A method bound to a robot and frame: ``(position, rotation, q0, rng, budget) ->
    Outcome``."""

    def __call__(
        self,
        position: np.ndarray,
        rotation: np.ndarray,
        q0: np.ndarray,
        rng: np.random.Generator,
        budget: float,
    ) -> Outcome: ...


#: ``make(model, frame, frame_type) -> Method``.
MethodFactory = Callable[[mujoco.MjModel, str, FrameType], Method]


def _qpik(model: mujoco.MjModel, frame: str, frame_type: FrameType) -> Method:
    def run(position, rotation, q0, rng, budget):
        result = solve(
            model,
            {(frame, frame_type): (position, rotation)},
            q0=q0,
            time_budget=budget,
            restarts=RESTARTS,
            seed=rng,
            solver="osqp",
        )
        return Outcome(result.q, result.iterations, result.restarts_used, result.reason)

    return run


def _igm_method(igm_function) -> MethodFactory:
    def make(model: mujoco.MjModel, frame: str, frame_type: FrameType) -> Method:
        configuration = Configuration(model)

        def run(position, rotation, q0, rng, budget):
            result = igm_function(
                configuration,
                frame,
                position,
                rotation,
                frame_type=frame_type,
                q0=q0,
                time_budget=budget,
                restarts=RESTARTS,
                seed=rng,
            )
            return Outcome(result.q, result.iterations, result.restarts_used, result.reason)

        return run

    return make


def _mink(model: mujoco.MjModel, frame: str, frame_type: FrameType) -> Method:
    import mink
    import qpsolvers

    backend = "daqp" if "daqp" in qpsolvers.available_solvers else "osqp"
    configuration = Configuration(model)
    task = mink.FrameTask(
        frame, frame_type.value, position_cost=1.0, orientation_cost=1.0, lm_damping=1.0
    )
    limits = [mink.ConfigurationLimit(model)]

    def step(work, _J, _c):
        return mink.solve_ik(work, [task], 1.0, backend, damping=1e-3, limits=limits)

    def run(position, rotation, q0, rng, budget):
        task.set_target(
            mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), position)
        )
        result = igm(
            configuration,
            frame,
            position,
            rotation,
            step,
            frame_type=frame_type,
            q0=q0,
            time_budget=budget,
            restarts=RESTARTS,
            seed=rng,
        )
        return Outcome(result.q, result.iterations, result.restarts_used, result.reason)

    return run


#: The benchmark's methods, in the table's order.
METHODS: dict[str, MethodFactory] = {
    "qpik": _qpik,
    "pinv": _igm_method(pseudoinverse_igm),
    "dls": _igm_method(damped_least_squares_igm),
    "mink": _mink,
}


def available_methods() -> list[str]:
    """The methods that can run here (``mink`` needs mink and qpsolvers)."""
    names = ["qpik", "pinv", "dls"]
    try:
        import mink  # noqa: F401
        import qpsolvers  # noqa: F401
    except ImportError:
        return names
    return names + ["mink"]


def default_robots() -> list[str]:
    """The bundled ``ur5e`` and ``panda``, plus ``erd:panda``, ``erd:ur5``, ``erd:ur10`` and
    ``erd:xarm7`` when example-robot-data is installed and they load."""
    robots = list(_DEFAULT_BUNDLED)
    for name in _DEFAULT_ERD:
        try:
            _load_quietly(name)
        except QpikError:
            continue
        robots.append(name)
    return robots


def _load_quietly(name: str) -> mujoco.MjModel:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # dropped collision meshes: kinematics unchanged
        return load_robot(name)


def robot_frame(name: str, model: mujoco.MjModel) -> tuple[str, FrameType]:
    """The tool frame benchmarked on robot ``name`` (:data:`ROBOT_FRAMES`, else site ``ee``);
    raises :class:`ValueError` naming the known robots when there is neither."""
    if name in ROBOT_FRAMES:
        return ROBOT_FRAMES[name]
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "ee") >= 0:
        return "ee", FrameType.SITE
    raise ValueError(
        f"no tool frame known for robot {name!r} and it has no site 'ee'; known robots: "
        + ", ".join(ROBOT_FRAMES)
    )


def _errors(configuration, frame, frame_type, position, rotation) -> tuple[float, float]:
    current_position, current_rotation = configuration.frame_pose(frame, frame_type)
    position_error = float(np.linalg.norm(current_position - position))
    cosine = (np.trace(current_rotation @ rotation.T) - 1.0) / 2.0
    return position_error, float(math.acos(min(1.0, max(-1.0, cosine))))


def _arm_dof(configuration: Configuration, frame: str, frame_type: FrameType) -> int:
    """Number of joints that move the frame (nonzero Jacobian columns at mid-range)."""
    configuration.update(configuration.mid_q())
    jacobian = configuration.frame_jacobian(frame, frame_type)
    return int(np.count_nonzero(np.abs(jacobian).max(axis=0) > 1e-12))


def _summary(records: list[dict], budget: float) -> dict:
    times = np.array([r["time"] for r in records])
    success = [r for r in records if r["success"]]
    failures = [r for r in records if not r["success"]]
    n = len(records)
    return {
        "n": n,
        "successes": len(success),
        "success_rate": len(success) / n if n else float("nan"),
        "first_attempt_successes": sum(r["restarts"] == 0 for r in success),
        "median_ms": 1e3 * float(np.median(times)) if n else float("nan"),
        "p95_ms": 1e3 * float(np.percentile(times, 95)) if n else float("nan"),
        "median_success_ms": (
            1e3 * float(np.median([r["time"] for r in success])) if success else float("nan")
        ),
        "median_iterations": float(np.median([r["iterations"] for r in records])) if n else 0,
        "median_restarts": float(np.median([r["restarts"] for r in records])) if n else 0,
        "limit_violations": sum(not r["within_limits"] for r in records),
        "failures": {
            "not_within_tolerance": sum(not r["within_tolerance"] for r in failures),
            "over_budget": sum(r["time"] > budget for r in failures),
            "outside_limits": sum(not r["within_limits"] for r in failures),
        },
        "failure_reasons": dict(Counter(r["reason"] for r in failures)),
        "failure_examples": [
            {key: r[key] for key in ("target", "reason", "position_error", "orientation_error")}
            | {
                "time_ms": 1e3 * r["time"],
                "iterations": r["iterations"],
                "restarts": r["restarts"],
            }
            for r in failures[:5]
        ],
    }


def run_ik_success(
    robots: Sequence[str] | None = None,
    n: int = DEFAULT_N,
    methods: Sequence[str] | None = None,
    seed: int = 0,
    budget: float = DEFAULT_BUDGET,
    progress: bool = True,
    *,
    tol_position: float = 1e-4,
    tol_orientation: float = 1e-3,
) -> dict:
    """Run the benchmark (see the module docstring) and return its results, JSON-ready:
    ``{"protocol": ..., "platform": ..., "robots": {robot: {"nv", "arm_dof", "frame",
    "frame_type", "time_s", "methods": {method: summary}}}}``. A summary holds ``n``,
    ``successes``, ``success_rate``, ``first_attempt_successes`` (successes without a
    restart: from the mid-range start alone), ``median_ms`` and ``p95_ms`` (wall time of
    every solve, failures included), ``median_success_ms``, ``median_iterations``,
    ``median_restarts``, ``limit_violations`` (returned configurations outside the limits),
    the failures by kind and by the method's reason, and up to five failure examples.

    ``robots``: names :func:`qpik.load_robot` accepts (default :func:`default_robots`);
    ``methods``: keys of :data:`METHODS` (default :func:`available_methods`); ``budget``:
    time per solve [s]; ``progress``: a progress line per robot on stderr.
    """
    robots = list(robots) if robots is not None else default_robots()
    methods = list(methods) if methods is not None else available_methods()
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise ValueError(f"unknown method(s) {unknown}; known: {', '.join(METHODS)}")
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    if not budget > 0:
        raise ValueError(f"budget must be > 0 seconds, got {budget}")
    results: dict = {
        "protocol": {
            "n": n,
            "seed": seed,
            "budget_s": budget,
            "tol_position_m": tol_position,
            "tol_orientation_rad": tol_orientation,
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
        model = _load_quietly(robot)
        frame, frame_type = robot_frame(robot, model)
        configuration = Configuration(model)
        configuration.frame_id(frame, frame_type)  # unknown frame: a clear error, early
        bound = {name: METHODS[name](model, frame, frame_type) for name in methods}
        target_rng = np.random.default_rng([seed, robot_index])
        targets = []
        for _ in range(n):
            configuration.update(configuration.random_q(target_rng))
            targets.append(configuration.frame_pose(frame, frame_type))
        q0 = configuration.mid_q()
        records: dict[str, list[dict]] = {name: [] for name in methods}
        start = time.perf_counter()
        for i, (position, rotation) in enumerate(targets):
            for k in range(len(methods)):
                name = methods[(i + k) % len(methods)]
                rng = np.random.default_rng([seed, robot_index, i, list(METHODS).index(name)])
                tic = time.perf_counter()
                outcome = bound[name](position, rotation, q0.copy(), rng, budget)
                elapsed = time.perf_counter() - tic
                configuration.update(outcome.q)
                position_error, orientation_error = _errors(
                    configuration, frame, frame_type, position, rotation
                )
                within_tolerance = (
                    position_error <= tol_position and orientation_error <= tol_orientation
                )
                within_limits = configuration.within_limits(LIMIT_TOL)
                records[name].append(
                    {
                        "target": i,
                        "success": within_tolerance and within_limits and elapsed <= budget,
                        "within_tolerance": within_tolerance,
                        "within_limits": within_limits,
                        "time": elapsed,
                        "iterations": outcome.iterations,
                        "restarts": outcome.restarts,
                        "reason": outcome.reason,
                        "position_error": position_error,
                        "orientation_error": orientation_error,
                    }
                )
            if progress:
                _report(robot, i + 1, n, start)
        elapsed_robot = time.perf_counter() - start
        if progress:
            _report(robot, None, n, start)
        results["robots"][robot] = {
            "nv": model.nv,
            "arm_dof": _arm_dof(configuration, frame, frame_type),
            "frame": frame,
            "frame_type": frame_type.value,
            "time_s": elapsed_robot,
            "methods": {name: _summary(records[name], budget) for name in methods},
        }
    return results


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


def format_table(results: dict) -> str:
    """The results as a text table: one row per robot and method."""
    protocol = results["protocol"]
    header = (
        f"{'robot':<11} {'DoF':>4} {'frame':<15} {'method':<6} {'success':>18} "
        f"{'1st try':>7} {'median ms':>9} {'p95 ms':>7} {'iters':>6} {'limit viol':>10}"
    )
    lines = [
        f"IK success: {protocol['n']} reachable pose targets per robot (seed "
        f"{protocol['seed']}), start at mid-range, success = position <= "
        f"{protocol['tol_position_m']:g} m, orientation <= {protocol['tol_orientation_rad']:g} "
        f"rad, within limits, within {1e3 * protocol['budget_s']:g} ms",
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
            success = f"{100 * s['success_rate']:.1f}% ({s['successes']}/{s['n']})"
            first = f"{100 * s['first_attempt_successes'] / s['n']:.1f}%"
            lines.append(
                f"{robot:<11} {dof:>4} {entry['frame']:<15} {method:<6} {success:>18} "
                f"{first:>7} {s['median_ms']:>9.2f} {s['p95_ms']:>7.2f} "
                f"{s['median_iterations']:>6.0f} {s['limit_violations']:>10d}"
            )
    lines.append(
        "DoF a+b: a joints move the frame, b (fingers) do not. 1st try: success without a "
        "restart (from mid-range alone). Times: wall time of every solve, failures included."
    )
    return "\n".join(lines)


def print_table(results: dict, stream=None) -> None:
    """Print :func:`format_table` to ``stream`` (default stdout)."""
    print(format_table(results), file=stream or sys.stdout)
