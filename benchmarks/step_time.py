"""Per-step time of differential IK on the bundled 7-DoF arm, methods side by side.

Scenario: the `panda` tracks a pose target moving on a 10 cm circle at 100 Hz (dt = 10 ms):
level 0 a FrameTask on site `ee`, level 1 a posture (or joint-limit distance) task, under
position and velocity limits. Every method steps its own copy of the robot along the same
target trajectory; the methods alternate in blocks of ``--block`` steps (default 100) in
one run, so machine noise hits all alike (``--block 1`` alternates every step, which also
charges each method for the cache misses the others leave behind).

Methods: qpik + OSQP (two strict levels, with and without the exact unconstrained fast
path; and the same tasks as one weighted level, mink's problem), mink + osqp and
mink + daqp (the same tasks as one weighted level, as mink has no priorities), pink + daqp
(the same weighted level on the same MJCF file loaded by pinocchio; only when pink and
pinocchio import, ``pip install 'qpik[compare]'``, and with the posture secondary), and the
lecture's pseudoinverse step (no limits, no second task).

Every method's timed step starts from kinematics already computed at the current
configuration: mink's and qpik's configurations update after integration, and pink's
pinocchio configuration is brought to the new joint positions (joint orders mapped by name,
:func:`qpik.bench.pinocchio_robot`) after integration too, outside the timing.

    python benchmarks/step_time.py [--steps 2000] [--secondary posture|limit-distance]
"""

from __future__ import annotations

import argparse
import time
import warnings

import mink
import numpy as np

import qpik
from qpik.baselines import pseudoinverse_step
from qpik.bench import MethodUnavailable, pinocchio_robot
from qpik.limits import joint_limits
from qpik.tasks import FrameTask, JointLimitDistanceTask, PostureTask


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--secondary", choices=["posture", "limit-distance"], default="posture")
    parser.add_argument("--robot", default="panda")
    parser.add_argument(
        "--block",
        type=int,
        default=100,
        help="methods alternate every BLOCK steps (1: step by step, which also measures "
        "each method with the others' data in the CPU caches)",
    )
    args = parser.parse_args(argv)

    model = qpik.load_robot(args.robot)
    start = qpik.Configuration(model)
    start.update(model.key_qpos[0] if model.nkey else start.mid_q())
    limits = joint_limits(model)
    centre, rotation = start.frame_pose("ee")
    dt = 0.01

    def make_tasks():
        frame = FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
        if args.secondary == "posture":
            secondary = PostureTask(model, cost=0.1)
            secondary.set_target(start.q)
        else:
            secondary = JointLimitDistanceTask(cost=0.1)
        return frame, secondary

    methods = {}
    syncs = {}  # name -> callable(configuration), run after integration, outside the timing
    notes = []

    def add_qpik(name, fast_path, levels=2):
        frame, secondary = make_tasks()
        stack = [[frame], [secondary]] if levels == 2 else [frame, secondary]
        solver = qpik.IKSolver(model, stack, limits, fast_path=fast_path)
        methods[name] = (frame, lambda c: solver.step(c, dt).velocity)

    def add_mink(name, backend):
        frame, secondary = make_tasks()
        tasks = [frame, secondary]
        methods[name] = (
            frame,
            lambda c: mink.solve_ik(c, tasks, dt, backend, damping=1e-6, limits=limits),
        )

    def add_pink(name, backend):
        """pink's FrameTask + PostureTask as one weighted level, mink's costs and damping,
        under pink's ConfigurationLimit (mink's gain 0.95) and VelocityLimit (the model's
        velocity_limit), on the robot file loaded by pinocchio."""
        try:
            import pink
            import pinocchio as pin
            from pink.limits import ConfigurationLimit, VelocityLimit
        except ImportError as exc:
            notes.append(f"{name}: skipped, {exc.name} is not installed (qpik[compare])")
            return
        if args.secondary != "posture":
            notes.append(f"{name}: skipped, pink has no joint-limit distance task")
            return
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                robot = pinocchio_robot(args.robot, model, "ee", "site")
        except MethodUnavailable as exc:
            notes.append(f"{name}: skipped, {exc.reason}")
            return
        notes.extend(f"{name}: {w.message}" for w in caught)
        pink_configuration = pink.Configuration(
            robot.model, robot.model.createData(), robot.q_to_pinocchio(start.q)
        )
        frame = pink.FrameTask("ee", position_cost=1.0, orientation_cost=1.0)
        posture = pink.PostureTask(cost=0.1)
        posture.set_target(robot.q_to_pinocchio(start.q))
        tasks = [frame, posture]
        pink_limits = [ConfigurationLimit(robot.model, config_limit_gain=0.95)]
        velocity = start.velocity_limits()
        if velocity is not None:
            pink_limits.append(VelocityLimit(robot.model, robot.v_to_pinocchio(velocity)))

        class Target:
            def set_target(self, pose):
                frame.set_target(pin.SE3(pose.rotation().as_matrix(), pose.translation()))

        def step(_c):
            v = pink.solve_ik(
                pink_configuration, tasks, dt, backend, damping=1e-6, limits=pink_limits
            )
            return robot.v_to_mujoco(v)

        methods[name] = (Target(), step)
        syncs[name] = lambda c: pink_configuration.update(robot.q_to_pinocchio(c.q))

    def add_pinv():
        frame, _ = make_tasks()

        def step(c):
            J = c.frame_jacobian("ee")
            # mink's error is a local twist; use the world-aligned position/rotation error.
            target = frame.transform_target_to_world
            p_err = target.translation() - c.frame_pose("ee")[0]
            r_err = (
                target.rotation() @ mink.SO3.from_matrix(c.frame_pose("ee")[1]).inverse()
            ).log()
            return pseudoinverse_step(J, np.concatenate([p_err, r_err])) / dt

        methods["pseudoinverse (no limits)"] = (frame, step)

    add_qpik("qpik osqp, 2 levels", fast_path=True)
    add_qpik("qpik osqp, 2 levels, no fast path", fast_path=False)
    add_qpik("qpik osqp, 1 level (as mink)", fast_path=True, levels=1)
    add_mink("mink + osqp, 1 level", "osqp")
    add_mink("mink + daqp, 1 level", "daqp")
    add_pink("pink + daqp, 1 level", "daqp")
    add_pinv()

    configurations = {name: start.copy() for name in methods}
    times = {name: [] for name in methods}
    errors = {name: [] for name in methods}
    violations = dict.fromkeys(methods, 0)

    def target_pose(k):
        angle = 2 * np.pi * k / 400
        target = centre + 0.1 * np.array([np.cos(angle) - 1.0, np.sin(angle), 0.0])
        pose = mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), target)
        return target, pose

    for block_start in range(0, args.steps, args.block):
        block = range(block_start, min(block_start + args.block, args.steps))
        for name, (frame, step) in methods.items():
            configuration = configurations[name]
            for k in block:
                target, pose = target_pose(k)
                frame.set_target(pose)
                t0 = time.perf_counter()
                velocity = step(configuration)
                times[name].append(time.perf_counter() - t0)
                configuration.integrate_inplace(velocity, dt)
                if name in syncs:
                    syncs[name](configuration)
                if not configuration.within_limits(tol=1e-9):
                    violations[name] += 1
                errors[name].append(np.linalg.norm(configuration.frame_pose("ee")[0] - target))

    reference = np.median(times["qpik osqp, 2 levels"])
    print(
        f"robot {args.robot}, {args.steps} steps at dt = {dt} s, secondary = "
        f"{args.secondary}, methods alternating every {args.block} steps"
    )
    print(
        f"{'method':38s} {'median us':>10s} {'p95 us':>9s} {'x qpik':>7s} "
        f"{'track err mm':>13s} {'limit viol.':>11s}"
    )
    summary = {}
    for name in methods:
        t = np.array(times[name]) * 1e6
        median = float(np.median(t))
        summary[name] = {"median_us": median, "p95_us": float(np.percentile(t, 95))}
        print(
            f"{name:38s} {median:10.1f} {np.percentile(t, 95):9.1f} "
            f"{median / (reference * 1e6):7.2f} {1e3 * np.median(errors[name]):13.3f} "
            f"{violations[name]:11d}"
        )
    for note in notes:
        print(f"note, {note}")
    return summary


if __name__ == "__main__":
    main()
