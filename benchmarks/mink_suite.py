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
``DIR/ur5e_mj_description.xml`` linked to a local MuJoCo Menagerie's ``ur5e.xml``).
A test whose model is not there is skipped, counted as "needs a downloaded model".
``--robot-descriptions`` uses the installed ``robot_descriptions`` package instead (which
may download models itself). mink's tests need ``absl-py`` (in qpik's ``dev`` extra).

``--timing`` adds per-call times of ``qpik.solve_ik`` and ``mink.solve_ik`` (same solver,
same tasks: a frame task and a posture task; mink's default limits) on the bundled robots:
medians over repeated calls, and the ratio qpik / mink.

    python benchmarks/mink_suite.py --tests PATH/TO/mink/tests [--models DIR]
        [--robot-descriptions] [--timing] [--calls 2000] [-k EXPRESSION]
    python benchmarks/mink_suite.py --timing
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
        return mujoco.MjModel.from_xml_path(path)

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
    """Median per-call time of qpik.solve_ik and mink.solve_ik on the bundled robots."""
    import mink
    import numpy as np

    import qpik

    print(f"\nper-call time, {calls} calls each (frame + posture task, default limits)")
    print(
        f"{'robot':<8}{'solver':<10}{'mink [us]':>11}{'qpik [us]':>11}{'ratio':>8}{'max |dv|':>11}"
    )
    for robot, frame in (("ur5e", "ee"), ("panda", "ee")):
        model = qpik.load_robot(robot)
        rng = np.random.default_rng(0)
        configuration = qpik.Configuration(model, model.key("home").qpos)
        task = mink.FrameTask(frame, "site", position_cost=1.0, orientation_cost=1.0)
        start = configuration.get_transform_frame_to_world(frame, "site")
        posture = mink.PostureTask(model, cost=1e-2)
        posture.set_target(model.key("home").qpos)
        for solver in ("daqp", "quadprog"):
            times = {"mink": [], "qpik": []}
            worst = 0.0
            for i in range(calls):
                offset = rng.uniform(-0.05, 0.05, 3)
                task.set_target(mink.SE3.from_translation(offset) @ start)
                answers = {}
                order = ("mink", "qpik") if i % 2 == 0 else ("qpik", "mink")
                for name in order:
                    solve = mink.solve_ik if name == "mink" else qpik.solve_ik
                    t0 = time.perf_counter()
                    answers[name] = solve(configuration, [task, posture], 0.01, solver)
                    times[name].append(time.perf_counter() - t0)
                worst = max(worst, float(np.abs(answers["mink"] - answers["qpik"]).max()))
            m, q = (1e6 * float(np.median(times[k])) for k in ("mink", "qpik"))
            print(f"{robot:<8}{solver:<10}{m:>11.1f}{q:>11.1f}{q / m:>8.2f}{worst:>11.2e}")


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
    parser.add_argument("--calls", type=int, default=2000, help="calls per timing row")
    parser.add_argument("-k", dest="keyword", help="pytest -k expression")
    args = parser.parse_args(argv)
    if args.tests is None and not args.timing:
        parser.error("pass --tests PATH (mink's tests/ folder) and/or --timing")
    regressions = 0
    if args.tests is not None:
        models = None if args.robot_descriptions else (args.models or "")
        extra = ["-k", args.keyword] if args.keyword else []
        regressions = run_suite(args.tests.resolve(), models, extra)
    if args.timing:
        run_timing(args.calls)
    return 1 if regressions else 0


if __name__ == "__main__":
    sys.exit(main())
