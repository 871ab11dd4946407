"""mink's own test suite, run against qpik (issue 14's acceptance), and per-call times.

The suite runs twice in subprocesses, on the mink version installed here: once as is
("stock mink"), once with ``mink.solve_ik = qpik.solve_ik`` and
``mink.Configuration = qpik.Configuration`` set before any test module is imported ("mink +
qpik"). The table gives passed / failed / errors / skipped per run, then every test whose
outcome differs between the two runs (a regression is one that passes on stock mink and not
with qpik), with the first line of its failure.

This script downloads nothing. Pass the ``tests/`` folder of a mink checkout that matches
the installed mink version. mink's tests load robots through ``robot_descriptions``; the
script serves them from ``--models DIR`` (``DIR/<description name>.xml``, e.g.
``DIR/ur5e_mj_description.xml`` linked to a local MuJoCo Menagerie's ``ur5e.xml``; a link
is opened at its target, so that the meshes the model names relative to itself are found).
A test whose model is not there is skipped, counted as "needs a downloaded model".
``--robot-descriptions`` uses the installed ``robot_descriptions`` package instead (which
may download models itself). mink's tests need ``absl-py`` (in qpik's ``dev`` extra).

``--timing`` adds per-call times of ``qpik.solve_ik`` and ``mink.solve_ik`` (same solver,
same tasks: a frame task and a posture task; mink's default limits) on the bundled robots:
medians over repeated calls, and the ratio qpik / mink; on a ``qpik.Configuration`` and on
a ``mink.Configuration`` (the README's one-import example, with its own two-level call).

``--examples DIR`` runs mink's example scripts (``DIR/*.py``, e.g. the ``examples/`` folder
of a mink checkout with its MuJoCo models) headless, each in its own subprocess, nothing
downloaded: the folder is mirrored into a temporary one (links), a mesh file the models
name but the folder lacks (or one MuJoCo refuses) is replaced there by a small
tetrahedron (kinematics do not use meshes); ``mujoco.viewer.launch_passive`` is a fake
viewer whose ``is_running()`` holds for ``--iterations`` loop turns and which moves every
mocap body on a small deterministic trajectory (the scripts' targets); ``loop_rate_limiters``
is stubbed (no sleeping; installed or not). Every ``mink.solve_ik`` call of a script is
made by both ``mink.solve_ik`` and ``qpik.solve_ik`` on the same state (alternating which
goes first) and timed, and ``qpik.IKSolver`` with the same tasks as strict levels (each
task a level, posture/damping tasks last) is timed there too. A script runs twice, once
integrating mink's answer and once qpik's; the final task errors of the two runs are
compared. A script that cannot run (e.g. it needs ``dm_control``) is listed with why.

    python benchmarks/mink_suite.py --tests PATH/TO/mink/tests [--models DIR]
        [--robot-descriptions] [--timing] [--calls 2000] [-k EXPRESSION]
    python benchmarks/mink_suite.py --timing
    python benchmarks/mink_suite.py --examples PATH/TO/mink/examples [--iterations 300]
        [--only humanoid_g1,arm_aloha]
"""

from __future__ import annotations

import argparse
import importlib.metadata
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

from bench_cli import at_least  # benchmarks/bench_cli.py (this folder is on sys.path)

#: Loaded with ``-p`` into each pytest run, before test modules are imported.
_PLUGIN = '''
"""Set up one run of mink's suite: qpik patched in (QPIK_MINK_PATCH=1), and robot
descriptions served from a local folder (QPIK_MINK_MODELS) or skipped."""
import os
import sys
import types
import unittest

import mink

if os.environ.get("QPIK_MINK_PATCH") == "1":
    import qpik

    mink.solve_ik = qpik.solve_ik
    mink.Configuration = qpik.Configuration

MISSING = "needs a downloaded model"

if os.environ.get("QPIK_MINK_MODELS") is not None:
    import mujoco

    FOLDER = os.environ["QPIK_MINK_MODELS"]

    def load_robot_description(description_name, variant=None, **kwargs):
        path = os.path.join(FOLDER, f"{description_name}.xml") if FOLDER else ""
        if not path or not os.path.exists(path):
            raise unittest.SkipTest(f"{MISSING}: {description_name}")
        # A link's target: MuJoCo finds meshes relative to the model file's own folder.
        return mujoco.MjModel.from_xml_path(os.path.realpath(path))

    package = types.ModuleType("robot_descriptions")
    loaders = types.ModuleType("robot_descriptions.loaders")
    loader = types.ModuleType("robot_descriptions.loaders.mujoco")
    loader.load_robot_description = load_robot_description
    package.loaders, loaders.mujoco = loaders, loader
    package.__path__, loaders.__path__ = [], []
    sys.modules.update(
        {
            "robot_descriptions": package,
            "robot_descriptions.loaders": loaders,
            "robot_descriptions.loaders.mujoco": loader,
        }
    )
'''


def _outcomes(junit: Path) -> dict[str, tuple[str, str]]:
    """Per test id: (outcome, first line of the message) from a JUnit XML report."""
    results = {}
    for case in ET.parse(junit).getroot().iter("testcase"):
        name = f"{case.get('classname')}::{case.get('name')}"
        outcome, message = "passed", ""
        for tag in ("failure", "error", "skipped"):
            node = case.find(tag)
            if node is not None:
                outcome = {"failure": "failed", "error": "error", "skipped": "skipped"}[tag]
                text = node.get("message") or node.text or ""
                message = text.strip().splitlines()[0] if text.strip() else ""
                break
        results[name] = (outcome, message)
    return results


def _run_suite(tests: Path, patched: bool, models: str | None, extra: list[str], work: Path):
    """One pytest run of mink's suite in a subprocess; (outcomes, wall time [s])."""
    junit = work / ("qpik.xml" if patched else "stock.xml")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(work), env.get("PYTHONPATH", "")])
    env["QPIK_MINK_PATCH"] = "1" if patched else "0"
    if models is not None:
        env["QPIK_MINK_MODELS"] = models
    command = [
        sys.executable, "-m", "pytest", str(tests), "-q", "-p", "qpik_mink_plugin",
        "-p", "no:cacheprovider", "--continue-on-collection-errors", f"--junitxml={junit}",
        "--rootdir", str(tests), *extra,
    ]  # fmt: skip
    start = time.perf_counter()
    process = subprocess.run(command, env=env, capture_output=True, text=True, cwd=work)
    elapsed = time.perf_counter() - start
    if not junit.exists():
        sys.stderr.write(process.stdout[-3000:] + process.stderr[-3000:])
        raise SystemExit(f"pytest did not run ({'mink + qpik' if patched else 'stock mink'})")
    return _outcomes(junit), elapsed


def run_suite(tests: Path, models: str | None, extra: list[str]) -> int:
    """Both runs, the table, and the number of regressions."""
    if importlib.util.find_spec("absl") is None:
        raise SystemExit("mink's tests need absl-py: pip install absl-py (qpik's dev extra)")
    if not tests.is_dir():
        raise SystemExit(f"--tests {tests}: not a folder (mink's tests/ from a checkout)")
    version = importlib.metadata.version("mink")
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        (work / "qpik_mink_plugin.py").write_text(_PLUGIN)
        stock, stock_time = _run_suite(tests, False, models, extra, work)
        ours, our_time = _run_suite(tests, True, models, extra, work)
    print(f"mink {version}'s suite from {tests}: {len(stock)} tests")
    _print_counts(stock, stock_time, ours, our_time)
    regressions, fixed, other = _compare(stock, ours)
    for title, rows in (("regressions (pass on stock mink, not with qpik)", regressions),
                        ("pass with qpik only", fixed)):  # fmt: skip
        print(f"{title}: {len(rows)}")
        for test, (outcome, message) in rows:
            print(f"  {test}: {outcome}: {message[:150]}")
    for test, before, after in other:
        print(f"  {test}: {before[0]} -> {after[0]}: {after[1][:150]}")
    not_passing = sorted(t for t, (o, _) in stock.items() if o in ("failed", "error"))
    if not_passing:
        print(f"fail on stock mink too (environment or version): {len(not_passing)}")
        for test in not_passing:
            print(f"  {test}: {stock[test][1][:150]}")
    return len(regressions)


def _print_counts(stock: dict, stock_time: float, ours: dict, our_time: float) -> None:
    """The outcome counts of both runs, and the tests skipped for want of a model."""
    print(f"{'run':<14}{'passed':>8}{'failed':>8}{'errors':>8}{'skipped':>9}{'time [s]':>10}")
    for label, outcomes, elapsed in (
        ("stock mink", stock, stock_time),
        ("mink + qpik", ours, our_time),
    ):
        counts = [
            sum(o == k for o, _ in outcomes.values())
            for k in ("passed", "failed", "error", "skipped")
        ]
        print(
            f"{label:<14}"
            + "".join(f"{c:>8}" for c in counts[:3])
            + f"{counts[3]:>9}{elapsed:>10.1f}"
        )
    missing = sorted(t for t, (o, m) in ours.items() if o == "skipped" and "downloaded model" in m)
    if missing:
        print(f"needs a downloaded model (skipped in both runs): {len(missing)} tests")


def _compare(stock: dict, ours: dict) -> tuple[list, list, list]:
    """Tests whose outcome differs: regressions (passed on stock mink only), fixed (pass
    with qpik only), other changes."""
    regressions, fixed, other = [], [], []
    for test in sorted(set(stock) | set(ours)):
        before = stock.get(test, ("absent", ""))
        after = ours.get(test, ("absent", ""))
        if before[0] == after[0]:
            continue
        if before[0] == "passed":
            regressions.append((test, after))
        elif after[0] == "passed":
            fixed.append((test, before))
        else:
            other.append((test, before, after))
    return regressions, fixed, other


def run_timing(calls: int) -> None:
    """Median per-call time of qpik.solve_ik and mink.solve_ik on the bundled robots, on a
    qpik.Configuration and on a mink.Configuration (the README's one-import example: UR5e,
    frame + posture task, mink's default limits; its last row is the README's own call,
    two strict levels ``[[task], [posture]]`` with qpik's solver, against mink's one
    weighted level with DAQP)."""
    import mink
    import numpy as np

    import qpik

    print(f"\nper-call time, {calls} calls each (frame + posture task, default limits)")
    print(
        f"{'robot':<8}{'Configuration':<15}{'solver':<10}{'mink [us]':>11}{'qpik [us]':>11}"
        f"{'ratio':>8}{'max |dv|':>11}"
    )
    cases = [("ur5e", "ee", "qpik"), ("panda", "ee", "qpik"), ("ur5e", "ee", "mink")]
    for robot, frame, kind in cases:
        model = qpik.load_robot(robot)
        rng = np.random.default_rng(0)
        if kind == "qpik":
            configuration = qpik.Configuration(model, model.key("home").qpos)
        else:  # the README's example
            configuration = mink.Configuration(model)
            configuration.update_from_keyframe("home")
        task = mink.FrameTask(frame, "site", position_cost=1.0, orientation_cost=1.0)
        start = configuration.get_transform_frame_to_world(frame, "site")
        posture = mink.PostureTask(model, cost=1e-2)
        posture.set_target(model.key("home").qpos)
        solvers = ("daqp", "quadprog") + (("levels",) if kind == "mink" else ())
        for solver in solvers:
            times: dict[str, list[float]] = {"mink": [], "qpik": []}
            worst = 0.0
            for i in range(calls):
                offset = rng.uniform(-0.05, 0.05, 3)
                task.set_target(mink.SE3.from_translation(offset) @ start)
                answers = {}
                order = ("mink", "qpik") if i % 2 == 0 else ("qpik", "mink")
                for name in order:
                    t0 = time.perf_counter()
                    if name == "mink":
                        backend = "daqp" if solver == "levels" else solver
                        answers[name] = mink.solve_ik(configuration, [task, posture], 0.01, backend)
                    elif solver == "levels":
                        answers[name] = qpik.solve_ik(configuration, [[task], [posture]], 0.01)
                    else:
                        answers[name] = qpik.solve_ik(configuration, [task, posture], 0.01, solver)
                    times[name].append(time.perf_counter() - t0)
                if solver != "levels":
                    worst = max(worst, float(np.abs(answers["mink"] - answers["qpik"]).max()))
            m, q = (1e6 * float(np.median(times[k])) for k in ("mink", "qpik"))
            label = "qpik" if kind == "qpik" else "mink (README)"
            dv = f"{worst:>11.2e}" if solver != "levels" else f"{'levels':>11}"
            print(f"{robot:<8}{label:<15}{solver:<10}{m:>11.1f}{q:>11.1f}{q / m:>8.2f}{dv}")
    print(
        "README row 'levels': qpik's two strict levels [[task], [posture]], qpik's solver, "
        "against mink's one weighted level [task, posture] with DAQP (goal: ratio <= 0.5)"
    )
    _timing_free_joint(min(calls, 300))
    _timing_constraints(min(calls, 1000))
    _timing_tasks(min(calls, 1000))


#: A closed loop (two arms joined at their tips: a connect equality), a weld and a joint
#: equality, for the EqualityConstraintTask row of :func:`_timing_tasks`.
_EQUALITY_XML = """<mujoco><worldbody>
<body name="a1"><joint name="a1" axis="0 0 1"/>
 <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02"/>
 <body name="a2" pos=".3 0 0"><joint name="a2" axis="0 0 1"/>
  <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02"/><site name="tip" pos=".3 0 0"/></body>
</body>
<body name="b1" pos=".4 0 0"><joint name="b1" axis="0 0 1"/>
 <geom type="capsule" fromto="0 0 0 0 .3 0" size=".02"/>
 <body name="b2" pos="0 .3 0"><joint name="b2" axis="0 0 1"/>
  <geom type="capsule" fromto="0 0 0 -.2 .1 0" size=".02"/></body>
</body>
<body name="w1" pos="0 1 0"><joint name="w1" axis="1 0 0"/><joint name="w2" axis="0 1 0"/>
 <geom type="capsule" fromto="0 0 0 0 0 .3" size=".02"/></body>
<body name="f" pos="0 1 .5"><joint name="fx" type="slide" axis="1 0 0"/>
 <joint name="fz" axis="0 0 1"/><geom size=".05"/></body>
</worldbody><equality>
<connect name="loop" body1="a2" body2="b2" anchor=".3 0 0"/>
<weld name="weld" body1="f" body2="w1"/>
<joint name="couple" joint1="w1" joint2="a1" polycoef="0 0.5 0 0 0"/>
</equality></mujoco>"""


def _task_case(label: str, model, configuration):
    """One row of :func:`_timing_tasks`: the task beside a frame task and a posture."""
    import mink
    import numpy as np

    import qpik

    if label == "EqualityConstraintTask":
        return mink.EqualityConstraintTask(model, cost=[2.0, 1.0, 0.5], gain=0.8)
    if label == "KineticEnergyRegularizationTask":
        task = mink.KineticEnergyRegularizationTask(cost=1e-3)
        task.set_dt(0.01)
        return task
    if label == "DofFreezingTask (level)":
        return mink.DofFreezingTask(model, dof_indices=[0, 1])
    if label == "LookAtTask":
        task = mink.LookAtTask("ee", "site", axis=np.array([0.0, 0.0, 1.0]), cost=0.5)
        task.set_target(np.array([0.6, 0.1, 0.2]))
        return task
    if label == "AxisAlignTask":
        task = mink.AxisAlignTask("ee", "site", axis=np.array([0.0, 0.0, 1.0]), cost=0.5)
        task.set_target(np.array([0.0, 0.3, -1.0]))
        return task
    return qpik.tasks.ManipulabilityTask("ee", "site", cost=0.1, lm_damping=30.0)


def _timing_tasks(calls: int) -> None:
    """Per-call time of each task kind the compiled step computes beside mink's own
    (bundled Panda, a frame task and a posture, one weighted level, position limits, DAQP;
    the EqualityConstraintTask on a 4-arm model with a connect, a weld and a joint
    equality, with the posture), in closed loop on mink's answer; qpik's
    ManipulabilityTask, which mink lacks, solved by mink.solve_ik through the task's own
    methods."""
    import mink
    import mujoco
    import numpy as np

    import qpik

    print(f"\ntask kinds, {calls} closed-loop calls each (one weighted level; DAQP)")
    print(f"{'task':<34}{'mink [us]':>11}{'qpik [us]':>11}{'ratio':>8}{'max |dv|':>11}")
    labels = (
        "LookAtTask", "AxisAlignTask", "DofFreezingTask (level)",
        "KineticEnergyRegularizationTask", "ManipulabilityTask (qpik's)",
        "EqualityConstraintTask",
    )  # fmt: skip
    for label in labels:
        looped = label == "EqualityConstraintTask"
        if looped:
            model = mujoco.MjModel.from_xml_string(_EQUALITY_XML)
        else:
            model = qpik.load_robot("panda")
        configuration = mink.Configuration(model)
        if looped:
            configuration.update(np.array([0.5, 0.5, 1.5, 0.5, 0.1, 0.2, 0.3, 0.1]))
        else:
            configuration.update_from_keyframe("home")
        frame = "tip" if looped else "ee"
        turn = 0.0 if looped else 1.0
        task = mink.FrameTask(frame, "site", position_cost=1.0, orientation_cost=turn)
        start = configuration.get_transform_frame_to_world(frame, "site")
        posture = mink.PostureTask(model, cost=1e-2)
        posture.set_target(configuration.q)
        stack = [task, posture, _task_case(label, model, configuration)]
        limits = [mink.ConfigurationLimit(model)]
        m, q, worst = _closed_loop(configuration, task, start, calls, stack, limits=limits)
        print(f"{label:<34}{m:>11.1f}{q:>11.1f}{q / m:>8.2f}{worst:>11.2e}")


def _closed_loop(
    configuration, task, start, calls: int, tasks: list, **kwargs
) -> tuple[float, float, float]:
    """``(mink's median [us], qpik's, the largest |dv|)`` of ``calls`` closed-loop calls of
    mink.solve_ik and qpik.solve_ik in turn (which goes first alternating) on ``tasks``
    (dt 0.01 s, DAQP, damping 1e-6, ``kwargs``), the frame task's target moved along a curve
    about ``start``, mink's answer integrated."""
    import mink
    import numpy as np

    import qpik

    times: dict[str, list[float]] = {"mink": [], "qpik": []}
    worst = 0.0
    for i in range(calls):
        offset = 0.05 * np.array([np.sin(i / 40), np.cos(i / 50) - 1, np.sin(i / 30)])
        task.set_target(start.multiply(mink.SE3.from_translation(offset)))
        answers = {}
        for name in ("mink", "qpik") if i % 2 == 0 else ("qpik", "mink"):
            solve = mink.solve_ik if name == "mink" else qpik.solve_ik
            t0 = time.perf_counter()
            answers[name] = solve(configuration, tasks, 0.01, "daqp", 1e-6, **kwargs)
            times[name].append(time.perf_counter() - t0)
        worst = max(worst, float(np.abs(answers["mink"] - answers["qpik"]).max()))
        configuration.integrate_inplace(answers["mink"], 0.01)
    m, q = (1e6 * float(np.median(times[k])) for k in ("mink", "qpik"))
    return m, q, worst


def _timing_constraints(calls: int) -> None:
    """Per-call time with mink 1.3's ``constraints=`` (bundled Panda: frame + posture task,
    the hand's orientation held by a FrameTask constraint, then dofs 0 and 1 frozen by a
    DofFreezingTask; position limits; DAQP), in closed loop on mink's answer: qpik holds the
    constraints as a level above the tasks' (the compiled step, their rows scaled to unit
    norm at each call)."""
    import mink

    import qpik

    model = qpik.load_robot("panda")
    frame = "ee"
    print(f"\nconstraints=, {calls} closed-loop calls each (bundled Panda, frame + posture task)")
    print(f"{'constraint':<28}{'mink [us]':>11}{'qpik [us]':>11}{'ratio':>8}{'max |dv|':>11}")
    for label in ("FrameTask (orientation)", "DofFreezingTask (dofs 0, 1)"):
        configuration = mink.Configuration(model)
        configuration.update_from_keyframe("home")
        task = mink.FrameTask(frame, "site", position_cost=1.0, orientation_cost=1.0)
        start = configuration.get_transform_frame_to_world(frame, "site")
        posture = mink.PostureTask(model, cost=1e-2)
        posture.set_target(configuration.q)
        if label.startswith("FrameTask"):
            held = mink.FrameTask(frame, "site", position_cost=0.0, orientation_cost=1.0)
            held.set_target_from_configuration(configuration)
        else:
            held = mink.DofFreezingTask(model, dof_indices=[0, 1])
        limits = [mink.ConfigurationLimit(model)]
        m, q, worst = _closed_loop(
            configuration, task, start, calls, [task, posture], limits=limits, constraints=[held]
        )
        print(f"{label:<28}{m:>11.1f}{q:>11.1f}{q / m:>8.2f}{worst:>11.2e}")


def _timing_free_joint(calls: int) -> None:
    """Per-call time on a floating humanoid with mink 1.3's FreeJointVelocityLimit (Talos
    from example-robot-data: feet, CoM, a hand and posture in one weighted level; position,
    velocity and free-joint velocity limits; DAQP), in closed loop (mink's answer
    integrated, so that the base turns): qpik's compiled step takes the limit's angular
    bounds into its box and its linear rows as general rows. Then the same with two
    secondary objectives added: qpik's ManipulabilityTask on the other hand (its chain
    through the free joint: the kernel's Hessian of any chain; mink.solve_ik through the
    task's own methods) and mink's KineticEnergyRegularizationTask."""

    import qpik

    try:
        model = qpik.load_robot("erd:talos", floating_base=True)
    except qpik.QpikError as exc:  # (the robots extra: example-robot-data)
        print(f"\nfree-joint velocity limit: skipped ({exc})")
        return
    for extra in (False, True):
        m, q, worst = _free_joint_loop(model, calls, extra)
        what = " + manipulability + kinetic energy" if extra else ""
        print(
            f"\nfloating Talos (erd:talos), feet + CoM + hand + posture{what}, "
            f"FreeJointVelocityLimit, {calls} closed-loop calls, DAQP: mink {m:.1f} us, "
            f"qpik {q:.1f} us, ratio {q / m:.2f}, max |dv| {worst:.2e}"
        )


def _free_joint_loop(model, calls: int, extra: bool) -> tuple[float, float, float]:
    """:func:`_timing_free_joint`'s closed loop: ``(mink's median [us], qpik's, max |dv|)``."""
    import mink
    import numpy as np

    import qpik
    from qpik.limits import velocity_limit_from_model

    home = model.key("half_sitting").qpos.copy()
    configuration = mink.Configuration(model, home)
    feet = [
        mink.FrameTask(f, "body", position_cost=10.0, orientation_cost=10.0)
        for f in ("left_sole_link", "right_sole_link")
    ]
    for task in feet:
        task.set_target_from_configuration(configuration)
    hand = mink.FrameTask("gripper_left_base_link", "body", position_cost=1.0, orientation_cost=0.0)
    start = configuration.get_transform_frame_to_world("gripper_left_base_link", "body")
    com = mink.ComTask(10.0)
    com0 = configuration.data.subtree_com[1].copy()
    posture = mink.PostureTask(model, 0.1)
    posture.set_target(home)
    tasks = [*feet, com, hand, posture]
    if extra:
        reach = qpik.tasks.ManipulabilityTask(
            "gripper_right_base_link", "body", rows="position", cost=0.01, lm_damping=30.0
        )
        energy = mink.KineticEnergyRegularizationTask(cost=1e-4)
        energy.set_dt(0.01)
        tasks += [reach, energy]
    free = mink.FreeJointVelocityLimit(model, max_linear_velocity=0.2, max_angular_velocity=0.3)
    limits = [mink.ConfigurationLimit(model), velocity_limit_from_model(model), free]
    times: dict[str, list[float]] = {"mink": [], "qpik": []}
    worst = 0.0
    for i in range(calls):
        sway = np.array([np.sin(i / 20), 2 * np.sin(i / 30), -np.sin(i / 25)])
        com.set_target(com0 + 0.02 * sway)
        offset = np.array([0.2 * np.sin(i / 15), 0.1, 0.1 * np.cos(i / 10)])
        hand.set_target(start.multiply(mink.SE3.from_translation(offset)))
        answers = {}
        for name in ("mink", "qpik") if i % 2 == 0 else ("qpik", "mink"):
            solve = mink.solve_ik if name == "mink" else qpik.solve_ik
            t0 = time.perf_counter()
            answers[name] = solve(configuration, tasks, 0.01, "daqp", 1e-6, limits=limits)
            times[name].append(time.perf_counter() - t0)
        worst = max(worst, float(np.abs(answers["mink"] - answers["qpik"]).max()))
        configuration.integrate_inplace(answers["mink"], 0.01)
    m, q = (1e6 * float(np.median(times[k])) for k in ("mink", "qpik"))
    return m, q, worst


# ----------------------------------------------------------------- mink's example scripts
_TETRAHEDRON_OBJ = (
    "v 0 0 0\nv 0.02 0 0\nv 0 0.02 0\nv 0 0 0.02\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
)


def _tetrahedron_stl() -> bytes:
    """A binary STL (MuJoCo reads binary STL only) of the same small tetrahedron."""
    import struct

    v = [(0, 0, 0), (0.02, 0, 0), (0, 0.02, 0), (0, 0, 0.02)]
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    data = bytearray(b"placeholder".ljust(80, b" ") + struct.pack("<I", len(faces)))
    for face in faces:
        data += struct.pack("<3f", 0, 0, 0)
        for i in face:
            data += struct.pack("<3f", *v[i])
        data += struct.pack("<H", 0)
    return bytes(data)


def _write_placeholder(path: Path) -> None:
    """A small tetrahedron mesh at ``path`` (its extension picks the format)."""
    if path.is_symlink():
        path.unlink()
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".stl":
        path.write_bytes(_tetrahedron_stl())
    else:
        path.write_text(_TETRAHEDRON_OBJ)


def _glyph_polyline(points: int = 400):
    """An "M" traced as one polyline ``(points, 2)`` in [-0.08, 0.08]^2 [m] (the engraving
    example's patch): up the left stroke, down to the middle, up and down the right."""
    import numpy as np

    corners = np.array([[-0.08, -0.08], [-0.08, 0.08], [0.0, 0.0], [0.08, 0.08], [0.08, -0.08]])
    lengths = np.linalg.norm(np.diff(corners, axis=0), axis=1)
    at = np.linspace(0.0, lengths.sum(), points)
    cumulative = np.concatenate([[0.0], np.cumsum(lengths)])
    return np.stack([np.interp(at, cumulative, corners[:, k]) for k in range(2)], axis=1)


def _example_assets(target: Path) -> list[str]:
    """Placeholders for the binary assets mink 1.3's ``arm_panda_engrave`` reads next to it
    where the copy lacks them (a snapshot keeps text files): the glyph ``mujoco_M.png`` (an
    "M" drawn on a 64 x 64 grey image) and its toolpath ``mujoco_M_toolpath.npy`` (waypoints
    ``(x, y, lift)`` along that M at cut depth, lift 0). The example then runs on this M
    rather than MuJoCo's logo; returns notes on what was written."""
    import numpy as np

    notes: list[str] = []
    if not (target / "arm_panda_engrave.py").exists():
        return notes
    logo, toolpath = target / "mujoco_M.png", target / "mujoco_M_toolpath.npy"
    if not logo.exists():
        import imageio.v3 as iio

        image = np.zeros((64, 64), dtype=np.uint8)
        for x, y in _glyph_polyline(2000):
            i, j = int(round((0.08 - y) / 0.16 * 63)), int(round((x + 0.08) / 0.16 * 63))
            image[max(i - 3, 0) : i + 4, max(j - 3, 0) : j + 4] = 255
        iio.imwrite(logo, image)
        notes.append("examples/mujoco_M.png: missing (an M drawn)")
    if not toolpath.exists():
        path = _glyph_polyline()
        np.save(toolpath, np.concatenate([path, np.zeros((len(path), 1))], axis=1))
        notes.append("examples/mujoco_M_toolpath.npy: missing (along that M)")
    return notes


def _shell_inertia_on_meshes(xml: Path) -> str | None:
    """MuJoCo 4 refuses ``shellinertia="true"`` on a mesh geom ("for mesh geoms, inertia
    should be specified in the mesh asset"; mink 1.3's Stretch 3 uses it): the mirror's copy
    of the file (the link replaced) moves it to those meshes' assets (``inertia="shell"``).
    Inertia plays no part in kinematics. Returns a note, or None where nothing changed."""
    import re

    text = xml.read_text()
    geom = re.compile(r"<geom\b[^>]*>")
    names: set[str] = set()

    def drop(match: re.Match) -> str:
        element = match.group(0)
        mesh = re.search(r'\bmesh="([^"]+)"', element)
        if mesh is None or not re.search(r'\bshellinertia="true"', element):
            return element
        names.add(mesh.group(1))
        return re.sub(r'\s+shellinertia="true"', "", element)

    text = geom.sub(drop, text)
    if not names:
        return None

    def shell(match: re.Match) -> str:
        element = match.group(0)
        name = re.search(r'\bname="([^"]+)"', element)
        file = re.search(r'\bfile="([^"]+)"', element)
        key = name.group(1) if name else Path(file.group(1)).stem if file else None
        if key not in names or re.search(r"\binertia=", element):
            return element
        return element.replace("<mesh", '<mesh inertia="shell"', 1)

    text = re.sub(r"<mesh\b[^>]*>", shell, text)
    xml.unlink()  # the link to the source: a copy of our own
    xml.write_text(text)
    return f"{xml.parent.name}/{xml.name}: shellinertia moved to {len(names)} mesh asset(s)"


def _notes_by_model(notes: list[str]) -> str:
    """``mirror_examples``' notes (``"<model folder>/<file>: <why>"``) counted by model
    folder and reason, e.g. ``"unitree_g1 48 missing; hello_robot_stretch_3 1 shellinertia
    ..."``: one line, not one entry per mesh file."""
    counts: dict[tuple[str, str], int] = {}
    for note in notes:
        where, _, why = note.partition(": ")
        key = (where.split("/", 1)[0], why)
        counts[key] = counts.get(key, 0) + 1
    return "; ".join(f"{model} {count} {why}" for (model, why), count in sorted(counts.items()))


def mirror_examples(source: Path, target: Path) -> list[str]:
    """Mirror mink's examples folder into ``target`` (scripts copied, model files linked)
    and replace each missing or unloadable mesh by a placeholder; returns notes on what
    was replaced."""
    import re

    import mujoco

    notes = []
    for entry in sorted(source.iterdir()):
        if entry.is_file():
            (target / entry.name).write_bytes(entry.read_bytes())
        elif entry.is_dir():
            for folder, _, files in os.walk(entry):
                out = target / Path(folder).relative_to(source)
                out.mkdir(parents=True, exist_ok=True)
                for name in files:
                    os.symlink(os.path.join(folder, name), out / name)
    notes.extend(_example_assets(target))
    for xml in sorted(target.glob("*/*.xml")):
        note = _shell_inertia_on_meshes(xml)
        if note:
            notes.append(note)
    for xml in sorted(target.glob("*/*.xml")):
        for _ in range(50):  # one refused mesh per round
            try:
                spec = mujoco.MjSpec.from_file(str(xml))
            except Exception:
                break  # not a model on its own (a fragment for <include>)
            folder, prefix = xml.parent, xml.parent.name + "/"
            meshes = {}
            for mesh in spec.meshes:
                name = mesh.file[len(prefix) :] if mesh.file.startswith(prefix) else mesh.file
                if name:
                    meshes[mesh.name] = folder / spec.meshdir / name
            missing = [p for p in meshes.values() if not p.exists()]
            for path in missing:
                _write_placeholder(path)
                notes.append(f"{xml.parent.name}/{path.name}: missing")
            try:
                mujoco.MjModel.from_xml_path(str(xml))
                break
            except Exception as exc:  # a mesh MuJoCo refuses (e.g. too thin for inertia)
                found = re.search(r"mesh volume is too small: (\S+)", str(exc))
                if found is None or found.group(1) not in meshes:
                    break
                path = meshes[found.group(1)]
                _write_placeholder(path)
                notes.append(f"{xml.parent.name}/{path.name}: refused by MuJoCo")
    return sorted(set(notes))


#: Where qpik's damping law did not act, qpik's answer lies within this of the exact optimum
#: of mink's QP [rad/s] (the QPs are ill-conditioned: damping 1e-3 to 1e-12).
EXACT_DV = 1e-6

_EXAMPLE_CHILD = r'''
"""Run one of mink's example scripts headless (see benchmarks/mink_suite.py --examples)."""
import json, math, runpy, sys, time, types
import numpy as np

script, driver, iterations, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]

class RateLimiter:
    def __init__(self, frequency, name="rate limiter", warn=True):
        self.frequency, self.period, self.dt = frequency, 1.0 / frequency, 1.0 / frequency
        self.name, self.warn, self.next_tick, self.slack = name, warn, 0.0, 0.0
    def sleep(self):
        pass

stub = types.ModuleType("loop_rate_limiters")
stub.RateLimiter = stub.AsyncRateLimiter = RateLimiter
sys.modules["loop_rate_limiters"] = stub
try:
    import dm_control.viewer.user_input  # noqa: F401
except Exception:  # only key constants are used from it
    keys = types.ModuleType("dm_control.viewer.user_input")
    for i, key in enumerate(("KEY_ENTER", "KEY_SPACE", "KEY_UP", "KEY_DOWN", "KEY_LEFT",
                             "KEY_RIGHT", "KEY_ESCAPE", "KEY_TAB")):
        setattr(keys, key, 1000 + i)
    viewer_pkg = types.ModuleType("dm_control.viewer")
    viewer_pkg.user_input, viewer_pkg.__path__ = keys, []
    if "dm_control" not in sys.modules:
        try:
            import dm_control  # noqa: F401
        except Exception:
            package = types.ModuleType("dm_control")
            package.__path__ = []
            sys.modules["dm_control"] = package
    sys.modules["dm_control"].viewer = viewer_pkg
    sys.modules["dm_control.viewer"] = viewer_pkg
    sys.modules["dm_control.viewer.user_input"] = keys

import mujoco, mujoco.viewer
import mink
import qpik

class FakeViewer:
    """launch_passive's handle: runs ``iterations`` loop turns, moving the mocap bodies."""
    def __init__(self, model, data):
        self.model, self.data, self.turn, self.base = model, data, 0, None
        self.cam, self.opt = mujoco.MjvCamera(), mujoco.MjvOption()
        self.user_scn = mujoco.MjvScene(model, maxgeom=100)
        self.perturb = mujoco.MjvPerturb()
    def __enter__(self):
        return self
    def __exit__(self, *exc):
        return False
    def is_running(self):
        data = self.data
        if self.base is None:
            self.base = data.mocap_pos.copy()
        elif data.mocap_pos.shape[0]:
            t = 2 * math.pi * self.turn / 200.0
            for j in range(data.mocap_pos.shape[0]):
                data.mocap_pos[j] = self.base[j] + 0.02 * np.array(
                    [math.sin(t + j), math.cos(t + 2 * j) - 1.0, 0.5 * math.sin(2 * t + j)])
        self.turn += 1
        return self.turn <= iterations
    def sync(self, *args, **kwargs):
        pass
    def lock(self):  # (the real handle's lock, held while a script edits the scene)
        import contextlib
        return contextlib.nullcontext()
    def close(self):
        pass
    def update_hfield(self, *args, **kwargs):  # (a height field edited by a script)
        pass
    def update_mesh(self, *args, **kwargs):
        pass
    def update_texture(self, *args, **kwargs):
        pass

mujoco.viewer.launch_passive = lambda model, data, *a, **k: FakeViewer(model, data)

mink_solve_ik, qpik_solve_ik = mink.solve_ik, qpik.solve_ik
times = {"mink": [], "qpik": [], "levels": []}
state = {"calls": 0, "dv": 0.0, "last": None, "levels": {}, "levels_error": None,
         "rows": [0, 0, 0.0, 0],  # collision rows: checks, rows, max |diff|, other pairs
         "damped": 0, "dv_exact": 0.0, "ill_posed": 0,  # where the answers differ: see explain()
         "ref_quadprog": 0,  # states where DAQP's reference left a row (quadprog's taken)
         "qp_path": [0, 0], "in": None}  # calls the QP path answered: solve_ik's, the levels'

_qp_step = qpik.IKSolver._qp_step
def counted_qp_step(self, *args, **kwargs):
    """qpik's QP path (the compiled step did not take the call), counted per caller."""
    if state["in"] is not None:
        state["qp_path"][state["in"]] += 1
    return _qp_step(self, *args, **kwargs)
qpik.IKSolver._qp_step = counted_qp_step

def explain(configuration, tasks, dt, solver, damping, limits, velocity):
    """A state where qpik's and mink's answers differ: qpik's damping law acted (it adds
    damping near a singularity, by design: counted), or else qpik's answer against the exact
    optimum of mink's own QP (mink.build_ik solved by daqp, an independent exact solver;
    mink's answer itself may be inexact, e.g. OSQP's)."""
    from qpik.diffik.mink_compat import _solver, as_configuration
    own = as_configuration(configuration)
    ik, _ = _solver(own, tasks, solver, damping, limits, None, {})
    if any(d > 0.0 for d in ik.step(own, dt).damping):
        state["damped"] += 1
        return
    import qpsolvers
    problem = mink.build_ik(configuration, tasks, dt, damping, limits)
    # Where P's condition number times the rounding unit exceeds 1e-8, the QP as posed in
    # floating point (P = sum J^T W J + damping I, formed in double) is itself off the
    # tasks' least-squares problem by up to cond(P) eps |dq|: no solver's answer to it is a
    # reference there (daqp's, on kinetic_energy_reg's states with damping 1e-12, is 4e-5
    # rad/s from the closed form J^T (J J^T + damping I)^-1 e, which qpik's matches to 1e-14).
    # Those states are counted apart, not compared.
    if np.linalg.cond(problem.P) * np.finfo(float).eps > 1e-8:
        state["ill_posed"] += 1
        return
    ref = qpsolvers.solve_problem(problem, solver="daqp").x
    if ref is not None and problem.G is not None:
        # DAQP meets the rows to its own tolerance: where its answer leaves one by more than
        # 1e-9 (1 + |h|) (humanoid_g1's collision rows, by up to 4.5e-7 [rad], with an
        # objective below the feasible optimum), quadprog's (an exact dual active set) is the
        # reference; where that leaves one too, the state is not compared.
        def leaves(x):
            return bool(np.any(problem.G @ x - problem.h > 1e-9 * (1.0 + np.abs(problem.h))))
        if leaves(ref):
            state["ref_quadprog"] += 1
            ref = qpsolvers.solve_problem(problem, solver="quadprog").x
            if ref is not None and leaves(ref):
                ref = None
    if ref is not None:
        state["dv_exact"] = max(state["dv_exact"], float(np.abs(velocity - ref / dt).max()))

def levels_solver(configuration, tasks, solver, damping, limits):
    """qpik.IKSolver with each task a strict level (posture/damping tasks last)."""
    key = (tuple(map(id, tasks)), None if limits is None else tuple(map(id, limits)), damping)
    ik = state["levels"].get(key)
    if ik is None:
        model = configuration.model
        soft = [t for t in tasks if isinstance(t, (mink.PostureTask, mink.DampingTask))]
        levels = [[t] for t in tasks if t not in soft] + ([soft] if soft else [])
        limits = [mink.ConfigurationLimit(model)] if limits is None else list(limits)
        ik = qpik.IKSolver(model, levels, limits, damping=damping)
        state["levels"][key] = ik
    return ik

def solve_ik(configuration, tasks, dt, solver=None, damping=1e-12, safety_break=False,
             limits=None, constraints=None, **kwargs):
    answers = {}
    order = ("mink", "qpik") if state["calls"] % 2 == 0 else ("qpik", "mink")
    for name in order:
        solve = mink_solve_ik if name == "mink" else qpik_solve_ik
        state["in"] = 0 if name == "qpik" else None
        t0 = time.perf_counter()
        answers[name] = solve(configuration, tasks, dt, solver, damping, safety_break,
                              limits=limits, constraints=constraints, **kwargs)
        times[name].append(time.perf_counter() - t0)
        state["in"] = None
    if constraints is None and state["levels_error"] is None:
        try:
            ik = levels_solver(configuration, list(tasks), solver, damping, limits)
            state["in"] = 1
            t0 = time.perf_counter()
            ik.step(configuration, dt)
            times["levels"].append(time.perf_counter() - t0)
            state["in"] = None
        except Exception as exc:
            state["levels_error"] = f"{type(exc).__name__}: {exc}"[:120]
    for limit in limits or ():
        if type(limit) is mink.CollisionAvoidanceLimit:  # qpik's culled rows against mink's
            from qpik.limits.collision import mink_collision_rows
            reference = limit.compute_qp_inequalities(configuration, dt)
            G, h, kept, _ = mink_collision_rows(limit, configuration, dt)
            in_play = np.flatnonzero(np.isfinite(reference.h))
            check = state["rows"]
            check[0] += 1
            check[1] += len(kept)
            if in_play.tolist() != kept:
                check[3] += 1
            elif kept:
                check[2] = max(check[2], float(np.abs(G - reference.G[in_play]).max()),
                               float(np.abs(h - reference.h[in_play]).max()))
    state["calls"] += 1
    dv = float(np.abs(answers["mink"] - answers["qpik"]).max())
    state["dv"] = max(state["dv"], dv)
    if dv > 1e-9 and constraints is None and not kwargs:
        explain(configuration, list(tasks), dt, solver, damping, limits, answers["qpik"])
    state["last"] = (configuration, list(tasks), solver, limits)
    return answers[driver]

mink.solve_ik = solve_ik
result = {"error": None}
sys.argv = [script]  # (a script that parses options sees none: its defaults)
try:
    runpy.run_path(script, run_name="__main__")
except SystemExit as exc:
    if exc.code not in (None, 0):
        result["error"] = f"SystemExit: {exc.code}"[:160]
except BaseException as exc:
    result["error"] = f"{type(exc).__name__}: {exc}".splitlines()[0][:160]
if state["last"] is not None:
    configuration, tasks, solver, limits = state["last"]
    errors = []
    for task in tasks:
        try:
            errors.append(np.atleast_1d(task.compute_error(configuration)).tolist())
        except Exception:
            errors.append([])
    result.update(
        solver=solver,
        tasks=[type(t).__name__ for t in tasks],
        limits=None if limits is None else [type(l).__name__ for l in limits],
        errors=errors,
    )
result.update(calls=state["calls"], dv=state["dv"], levels_error=state["levels_error"],
              rows=state["rows"], damped=state["damped"], dv_exact=state["dv_exact"],
              ill_posed=state["ill_posed"], ref_quadprog=state["ref_quadprog"],
              qp_path=state["qp_path"],
              **{k: v for k, v in times.items()})
with open(out, "w") as f:
    json.dump(result, f)
'''


def _run_example(work: Path, script: Path, driver: str, iterations: int) -> dict:
    """One headless run of an example script in a subprocess (see ``_EXAMPLE_CHILD``)."""
    import json

    out = work / f"{script.stem}.{driver}.json"
    env = dict(os.environ)
    env.setdefault("MUJOCO_GL", "egl")
    command = [sys.executable, str(work / "_run_example.py"), str(script), driver,
               str(iterations), str(out)]  # fmt: skip
    process = subprocess.run(command, env=env, capture_output=True, text=True, cwd=script.parent)
    if not out.exists():
        tail = (process.stderr.strip().splitlines() or ["(no output)"])[-1]
        return {"error": f"crashed (exit {process.returncode}): {tail[:160]}", "calls": 0}
    return json.loads(out.read_text())


def run_examples(folder: Path, iterations: int, only: list[str] | None) -> None:
    """mink's example scripts from ``folder``, headless: per-call times of mink.solve_ik,
    qpik.solve_ik and qpik.IKSolver (strict levels) on the same states, and the final task
    errors of a run integrating mink's answers and one integrating qpik's."""
    import numpy as np

    if not folder.is_dir():
        raise SystemExit(f"--examples {folder}: not a folder (mink's examples/)")
    scripts = sorted(p for p in folder.glob("*.py") if not p.name.startswith("_"))
    if only:
        scripts = [p for p in scripts if p.stem in only]
    rows, failed = [], []
    with tempfile.TemporaryDirectory() as temp:
        work = Path(temp)
        notes = mirror_examples(folder, work)
        (work / "_run_example.py").write_text(_EXAMPLE_CHILD)
        for script in scripts:
            runs = {
                d: _run_example(work, work / script.name, d, iterations) for d in ("mink", "qpik")
            }
            error = runs["mink"]["error"] or runs["qpik"]["error"]
            if error or not runs["mink"]["calls"]:
                failed.append((script.stem, error or "no solve_ik call"))
                continue
            rows.append((script.stem, runs))
    version = importlib.metadata.version("mink")
    print(
        f"\nmink {version}'s example scripts from {folder}, {iterations} loop turns each; "
        "per-call medians [us]"
    )
    if notes:
        print(f"placeholders: {len(notes)} ({_notes_by_model(notes)})")
    header = (
        f"{'example':<22}{'solver':<10}{'calls':>6}{'mink':>9}{'qpik':>9}{'ratio':>7}"
        f"{'levels':>9}{'QP path':>9}{'max|dv|':>10}{'damped':>7}{'ill':>5}{'vs exact':>9}"
        f"{'|e| mink':>10}{'|e| qpik':>10}{'max|de|':>10}"
    )
    print(header)
    ratios: list[float] = []
    exact_miss: list[str] = []
    quadprog_refs: list[tuple[str, int]] = []
    for name, runs in rows:
        r = runs["mink"]
        med = {
            k: 1e6 * float(np.median(r[k])) if r[k] else float("nan")
            for k in ("mink", "qpik", "levels")
        }
        ratio = med["qpik"] / med["mink"]
        ratios.append(ratio)
        e_m = np.concatenate([np.asarray(e, float) for e in runs["mink"]["errors"]])
        e_q = np.concatenate([np.asarray(e, float) for e in runs["qpik"]["errors"]])
        de = float(np.abs(e_m - e_q).max()) if e_m.shape == e_q.shape and e_m.size else float("nan")
        dv = max(runs["mink"]["dv"], runs["qpik"]["dv"])
        damped = runs["mink"].get("damped", 0) + runs["qpik"].get("damped", 0)
        exact = max(runs["mink"].get("dv_exact", 0.0), runs["qpik"].get("dv_exact", 0.0))
        ill = runs["mink"].get("ill_posed", 0) + runs["qpik"].get("ill_posed", 0)
        refs = runs["mink"].get("ref_quadprog", 0) + runs["qpik"].get("ref_quadprog", 0)
        if refs:
            quadprog_refs.append((name, refs))
        if exact > EXACT_DV:
            exact_miss.append(name)
        # (the run integrating qpik's answers: every call of it was timed and counted)
        qp_calls, qp_levels = runs["qpik"].get("qp_path", [0, 0])
        print(
            f"{name:<22}{str(r['solver']):<10}{r['calls']:>6}{med['mink']:>9.1f}"
            f"{med['qpik']:>9.1f}{ratio:>7.2f}{med['levels']:>9.1f}"
            f"{f'{qp_calls}/{qp_levels}':>9}{dv:>10.1e}{damped:>7}{ill:>5}"
            f"{exact:>9.1e}{np.linalg.norm(e_m):>10.2e}{np.linalg.norm(e_q):>10.2e}{de:>10.1e}"
        )
    if ratios:
        print(
            f"ratio qpik / mink: median {np.median(ratios):.2f}, max {max(ratios):.2f} "
            f"(goal: <= 0.5 on every example)"
        )
        print(
            f"answers where they differ from mink's and qpik's damping law did not act, against "
            f"the exact optimum of mink's QP: within {EXACT_DV:g} rad/s on "
            + ("every example" if not exact_miss else f"all but {', '.join(exact_miss)}")
        )
    print(
        "columns: levels = qpik.IKSolver, each task a strict level (posture/damping last), "
        "qpik's own solver; QP path = calls of the run integrating qpik's answers that qpik's "
        "QP path answered (the compiled step did not take them): solve_ik's / the levels'; "
        "max|dv| = largest velocity difference on the same state; damped "
        "= states (of those that differ by more than 1e-9) where qpik's damping law added "
        "damping near a singularity (by design); ill = states of the others where mink's QP "
        "as formed in double is too ill-conditioned to be a reference (cond(P) eps > 1e-8: it "
        "is off its tasks' least-squares problem by up to cond(P) eps |dq|), not compared; vs "
        "exact = on the rest, qpik's largest difference from the exact optimum of mink's QP "
        "(mink.build_ik, daqp; quadprog's where daqp's answer leaves a row by more than "
        "1e-9 (1 + |h|): on "
        + (", ".join(f"{n} {c}" for n, c in quadprog_refs) or "no example")
        + " states); "
        "|e| = final task errors (run integrating mink's / qpik's answers), max|de| their "
        "largest difference"
    )
    for name, runs in rows:
        r = runs["mink"]
        print(
            f"  {name}: tasks {', '.join(r['tasks'])}; limits "
            f"{'mink default' if r['limits'] is None else ', '.join(r['limits']) or 'none'}"
            + (f"; levels: {r['levels_error']}" if r["levels_error"] else "")
        )
    for name, runs in rows:
        both = [runs[d].get("rows", [0, 0, 0.0, 0]) for d in ("mink", "qpik")]
        checks, count, other = (sum(r[i] for r in both) for i in (0, 1, 3))
        worst = max(r[2] for r in both)
        if checks:
            print(
                f"  {name}: mink's CollisionAvoidanceLimit rows, qpik's culled computation "
                f"against mink's on {checks} states (both runs): {count} rows in play, max |diff| "
                f"{worst:.1e}, {other} states with other pairs in play"
            )
    for name, why in failed:
        print(f"could not run {name}: {why}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tests", type=Path, help="mink's tests/ folder (a checkout)")
    parser.add_argument("--models", help="folder of <description name>.xml model files")
    parser.add_argument(
        "--robot-descriptions",
        action="store_true",
        help="load models with the installed robot_descriptions package (may download)",
    )
    parser.add_argument("--timing", action="store_true", help="per-call times vs mink")
    parser.add_argument("--calls", type=at_least(1), default=2000, help="calls per timing row")
    parser.add_argument("-k", dest="keyword", help="pytest -k expression")
    parser.add_argument("--examples", type=Path, help="mink's examples/ folder (a checkout)")
    parser.add_argument("--iterations", type=at_least(1), default=300, help="loop turns per script")
    parser.add_argument("--only", help="comma-separated script names (without .py)")
    args = parser.parse_args(argv)
    if args.tests is None and not args.timing and args.examples is None:
        parser.error("pass --tests PATH (mink's tests/ folder), --examples PATH and/or --timing")
    regressions = 0
    if args.tests is not None:
        models = None if args.robot_descriptions else (args.models or "")
        extra = ["-k", args.keyword] if args.keyword else []
        regressions = run_suite(args.tests.resolve(), models, extra)
    if args.timing:
        run_timing(args.calls)
    if args.examples is not None:
        only = args.only.split(",") if args.only else None
        run_examples(args.examples.resolve(), args.iterations, only)
    return 1 if regressions else 0


if __name__ == "__main__":
    import bench_cli  # benchmarks/bench_cli.py (this folder is on sys.path)

    bench_cli.run(main)
