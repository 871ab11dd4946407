"""A whole-body humanoid stack on floating Talos (example-robot-data), 2 s at 100 Hz.

Priorities (level 0 first), under joint position and velocity limits (the URDF's) and the
support-polygon limit (the CoM's ground projection inside the feet's convex hull, 2 cm
margin), which hold at every level:

* level 0: both feet fixed where they start (6-D pose tasks on the sole links);
* level 1: both hands to targets: the left one reachable, the right one 1.5 m to the
  side, out of reach (the arm stretches toward it as far as the levels above allow);
* level 2: torso upright (orientation of ``torso_2_link``, world-aligned);
* level 3: posture: the SRDF's ``half_sitting`` (loaded as a keyframe).

Each 10 ms cycle is the four-level step, then one Newton step of level 0 alone (the feet):
a step holds the feet to first order only, and this correction removes the second-order
drift (``|dq|^2``) that fast whole-body motion leaves on them. The stack runs at 90 % of
the URDF's velocity limits and the correction at 10 %, so the cycle stays within them.

The robot starts in ``half_sitting``. Per run it prints the feet error (the worst over
all steps; goal 1e-5 m), the hands' final errors, the smallest CoM margin, the median and
worst step time, and the joint position and velocity violations (goal 0).

Run: ``python examples/humanoid_talos.py [--steps N]`` (needs the ``robots`` extra: from
the checkout, ``pip install -e '.[robots]'``).
"""

from __future__ import annotations

import argparse
import time
import warnings

import mujoco
import numpy as np

import qpik
from qpik.limits import SupportPolygonLimit, joint_limits
from qpik.tasks import FrameTask, OrientationTask, PositionTask, PostureTask

FEET = ("left_sole_link", "right_sole_link")
HANDS = ("gripper_left_base_link", "gripper_right_base_link")
#: Talos's sole: 0.20 m x 0.10 m, centred on the sole link (x forward).
SOLE = [[0.1, 0.05], [0.1, -0.05], [-0.1, 0.05], [-0.1, -0.05]]


def run(steps: int = 200, dt: float = 0.01, verbose: bool = True) -> dict:
    """Run the stack for ``steps`` steps of ``dt`` [s]; returns the figures it prints."""
    with warnings.catch_warnings():  # the URDF's .dae meshes are dropped, with a warning
        warnings.simplefilter("ignore")
        model = qpik.load_robot("erd:talos", floating_base=True)
    configuration = qpik.Configuration(model, model.key("half_sitting").qpos)

    feet = [FrameTask(name, "body", position_cost=1.0, orientation_cost=1.0) for name in FEET]
    for task in feet:
        task.set_target_from_configuration(configuration)
    hands = [PositionTask(name, "body", gain=0.2) for name in HANDS]
    left, _ = configuration.frame_pose(HANDS[0], "body")
    right, _ = configuration.frame_pose(HANDS[1], "body")
    targets = [left + [0.25, 0.05, 0.15], right + [0.3, -1.5, 0.3]]  # the second: unreachable
    for task, target in zip(hands, targets):
        task.set_target(target)
    torso = OrientationTask("torso_2_link", "body", gain=0.5)
    torso.set_target(np.eye(3))
    posture = PostureTask(model, cost=1e-2)
    posture.set_target(model.key("half_sitting").qpos)

    support = SupportPolygonLimit(model, FEET, margin=0.02, footprint=SOLE)
    # The whole stack gets 90 % of the URDF's velocity limits; the remaining 10 % is the
    # budget of the contact correction below, so their sum stays within the URDF's.
    solver = qpik.IKSolver(
        model, [feet, hands, [torso], [posture]], [*joint_limits(model, 0.9), support]
    )
    correction = qpik.IKSolver(model, [feet], [*joint_limits(model, 0.1), support])
    vmax = configuration.velocity_limits()
    lower, upper = configuration.lower, configuration.upper

    feet_position = feet_rotation = 0.0
    com_margin = np.inf
    position_violation = velocity_violation = 0.0
    times, statuses = [], set()
    for _ in range(steps):
        q_start = configuration.q
        start = time.perf_counter()
        result = solver.step(configuration, dt)
        configuration.integrate_inplace(result.velocity, dt)
        # One Newton step on the feet alone: the step above holds them to first order;
        # this removes its second-order drift (|dq|^2), well below 1e-5 m.
        fix = correction.step(configuration, dt)
        configuration.integrate_inplace(fix.velocity, dt)
        times.append(time.perf_counter() - start)
        statuses.update(str(s) for s in result.status)
        q = configuration.q
        velocity = np.empty(model.nv)
        mujoco.mj_differentiatePos(model, velocity, dt, q_start, q)
        for task in feet:
            error = task.compute_error(configuration)
            feet_position = max(feet_position, float(np.linalg.norm(error[:3])))
            feet_rotation = max(feet_rotation, float(np.linalg.norm(error[3:])))
        com_margin = min(com_margin, support.com_margin(configuration))
        position_violation = max(
            position_violation, float(np.max(np.maximum(lower - q, q - upper), initial=0.0))
        )
        velocity_violation = max(
            velocity_violation, float(np.max(np.abs(velocity) - vmax, initial=0.0))
        )
    hand_errors = [float(np.linalg.norm(t.compute_error(configuration))) for t in hands]
    figures = {
        "steps": steps,
        "feet_error": feet_position,
        "feet_rotation_error": feet_rotation,
        "hand_errors": hand_errors,
        "com_margin": float(com_margin),
        "step_time_median": float(np.median(times[1:] if len(times) > 1 else times)),
        "step_time_max": float(np.max(times[1:] if len(times) > 1 else times)),
        "first_step_time": float(times[0]),
        "position_violation": max(position_violation, 0.0),
        "velocity_violation": max(velocity_violation, 0.0),
        "statuses": sorted(statuses),
        "nv": model.nv,
    }
    if verbose:
        print(f"floating Talos ({model.nv} dofs), {steps} steps of {dt * 1e3:.0f} ms, 4 levels")
        print(
            f"  feet error, worst step            {feet_position:.2e} m, {feet_rotation:.2e} rad "
            "(goal <= 1e-5 m)"
        )
        print(
            f"  hand errors at the end [m]        left {hand_errors[0]:.4f}  "
            f"right {hand_errors[1]:.4f} (out of reach)"
        )
        print(
            f"  CoM margin in the support polygon {com_margin * 1e3:.1f} mm "
            "(smallest; the limit asks 20 mm, to first order)"
        )
        later = times[1:] if len(times) > 1 else times
        print(
            f"  cycle time (step + correction)    median {np.median(later) * 1e3:.2f} ms, "
            f"max {np.max(later) * 1e3:.2f} ms; first {times[0] * 1e3:.0f} ms (warm-up)"
        )
        print(f"  joint position violation          {figures['position_violation']:.2e} rad")
        print(f"  joint velocity violation          {figures['velocity_violation']:.2e} rad/s")
        print(f"  level statuses seen               {', '.join(figures['statuses'])}")
    return figures


def main(argv: list[str] | None = None) -> int:
    """Command line: ``--steps N`` (default 200, 2 s). Exit 0 when the feet stayed within
    1e-5 m and no joint position or velocity limit was crossed, else 1."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200, help="steps of 10 ms (default 200)")
    figures = run(parser.parse_args(argv).steps)
    ok = (
        figures["feet_error"] <= 1e-5
        and figures["position_violation"] <= 1e-9
        and figures["velocity_violation"] <= 1e-9
    )
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
