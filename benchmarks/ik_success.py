"""IK success rate and time on reachable pose targets: TRAC-IK's protocol as the headline,
qpik's coarser protocol second (issue 11; the logic is benchmarks/ik_bench.py).

Headline, TRAC-IK's protocol (Beeson & Ames 2015): per robot, N random configurations
within the limits mapped by forward kinematics to targets for its tool frame (fixed seed);
every solve starts at mid-range; success = position error <= 1e-5 m on each axis and
rotation-vector error <= 1e-5 rad on each axis, joints within limits, all within 5 ms of wall
time. Reported: success, the mean time over all solves (TRAC-IK's figure), median, p95 and
mean iterations; TRAC-IK's published figures beside (UR5 99.17 % 0.37 ms, Panda 99.88 %
0.37 ms, Jaco2 99.92 % 0.35 ms, iiwa14 99.92 % 0.28 ms; C++, its machine).

Second table: success = 1e-4 m and 1e-3 rad (norms), within 50 ms.

Robots: the bundled ur5e and panda, and every 6- and 7-DoF arm of example-robot-data that
loads (erd:panda, ur3, ur5, ur10, xarm7, talos_left_arm, kinova = Jaco2, z1; iiwa is not in
example-robot-data). Goals, checked here and printed (never by tests): >= 99.9 % on every
arm, mean <= 0.3 ms, median <= 0.25 ms under the headline; 100.0 % under the second.

Also printed: ``import qpik`` against ``import mujoco, mink``, the first ``IKSession.solve``
and the first ``IKSolver.step`` in a fresh process (building the session or solver not
counted), a 5 ms budget on the first call, the fixed cost of a call (a target already met at
the start: validation, one forward kinematics and the result) and the time of ``qpik reach
tasks/panda_pose_reach.toml``. ``--first-use`` measures the same in a fresh virtual
environment made from a fresh clone of this checkout's HEAD, after timing its install (the
C++ engine's compile included, and alone), which is what a new user meets.

Wall times include whatever else the machine runs; the CPU figures beside them (thread CPU
time per solve, process CPU time of each run, of the fixed-cost calls and of the fresh
processes) show the solver's own time on a shared machine, and each run's CPU / wall ratio
how much of a core it was given.

    python benchmarks/ik_success.py                  # N = 1000 per robot, about 1 min
    python benchmarks/ik_success.py --n 10000        # the full run
    python benchmarks/ik_success.py --robots erd:ur5 panda --n 200 --methods qpik dls
        [--skip-second] [--first-use] [--json OUT]
    python benchmarks/ik_success.py --first-use --startup-only   # only the first-use figures
    python benchmarks/ik_success.py --robots erd:panda erd:ur5 erd:xarm7 erd:kinova \
        --n 1000 --skip-second                       # issue 20: qpik beside TRAC-IK, ik_LM

Methods (default): ``qpik`` (IKSession.solve), ``oneshot`` (qpik.solve, no session) and the
whole-IK peers installed (``pip install -e '.[compare]'``): ``tracik`` (TRAC-IK, pytracik)
and ``rtb_lm`` (the Robotics Toolbox's C++ ik_LM), built from the same URDF file as qpik's
``erd:`` robot and judged by the same checks (benchmarks/ik_methods.py); they skip the
bundled MJCF robots. Issue 20's goals are printed after issue 11's. TRAC-IK runs two
threads at once (KDL's Newton and an SQP): its thread CPU time counts only the calling one.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import ik_bench as bench  # benchmarks/ik_bench.py (this folder is on sys.path)
import numpy as np
from bench_cli import at_least  # benchmarks/bench_cli.py (this folder is on sys.path)

from qpik import QpikError

ROOT = Path(__file__).resolve().parent.parent


def _fresh_process(code: str, python: str = sys.executable, cwd: Path = ROOT) -> str:
    return subprocess.run(
        [python, "-c", code], capture_output=True, text=True, check=True, cwd=cwd
    ).stdout


_STARTUP = """
import time
t0, c0 = time.perf_counter(), time.process_time()
import qpik
t1, c1 = time.perf_counter(), time.process_time()
session = qpik.IKSession("panda")
t2 = time.perf_counter()
result = session.solve({"ee": [0.4, 0.1, 0.5]})
t3 = time.perf_counter()
import mink
model = qpik.load_robot("ur5e")
configuration = qpik.Configuration(model)
task = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
task.set_target(configuration.get_transform_frame_to_world("ee", "site"))
solver = qpik.IKSolver(model, [[task]], [mink.ConfigurationLimit(model)])
t4 = time.perf_counter()
solver.step(configuration, 0.01)
t5 = time.perf_counter()
budget = qpik.solve(
    "ur5e", {"ee": [0.3, 0.2, 0.4]}, options=qpik.SolveOptions(time_budget=0.005)
)
print(t1 - t0, c1 - c0, t3 - t2, t5 - t4, budget.reason, budget.solve_time, result.converged)
"""
_PEERS_IMPORT = """
import time
t0 = time.perf_counter()
import mujoco, mink
print(time.perf_counter() - t0)
"""


def _children_cpu() -> float:
    """CPU time [s] (user + system) of the finished child processes so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _timed_command(command: list[str], cwd: Path) -> tuple[float, float]:
    """Wall and CPU time [s] of one run of ``command``."""
    cpu = _children_cpu()
    tic = time.perf_counter()
    subprocess.run(command, capture_output=True, check=False, cwd=cwd)
    return time.perf_counter() - tic, _children_cpu() - cpu


def startup_figures(python: str = sys.executable, root: Path = ROOT, runs: int = 9) -> dict:
    """Fresh-process figures with the interpreter ``python`` (median of ``runs``): ``import
    qpik`` against ``import mujoco, mink``, the first ``IKSession.solve`` and
    ``IKSolver.step``, a 5 ms budget on the first call, and ``qpik reach`` on the shipped
    panda problem against ``python -c "import mujoco, mink"`` (both as whole commands)."""
    rows, peers = [], []
    for _ in range(runs):  # interleaved: a drift of the machine's speed hits both alike
        rows.append(_fresh_process(_STARTUP, python=python, cwd=root).split())
        peers.append(float(_fresh_process(_PEERS_IMPORT, python=python, cwd=root)))
    out: dict = {
        "import_s": float(np.median([float(r[0]) for r in rows])),
        "import_cpu_s": float(np.median([float(r[1]) for r in rows])),
        "import_mujoco_mink_s": float(np.median(peers)),
        # the median of the paired differences (each qpik process against the peers' next)
        "import_over_s": float(np.median([float(r[0]) - p for r, p in zip(rows, peers)])),
        "first_session_solve_s": float(np.median([float(r[2]) for r in rows])),
        "first_step_s": float(np.median([float(r[3]) for r in rows])),
        "budget_reasons": sorted({r[4] for r in rows}),
        "budget_first_call_s": float(max(float(r[5]) for r in rows)),
    }
    script = str(Path(python).parent / "qpik")
    reach, bare = [], []
    for _ in range(runs):  # interleaved, as above
        reach.append(_timed_command([script, "reach", "tasks/panda_pose_reach.toml"], root))
        bare.append(_timed_command([python, "-c", "import mujoco, mink"], root))
    out["qpik_reach_s"] = float(np.median([r[0] for r in reach]))
    out["qpik_reach_first_s"] = reach[0][0]
    out["qpik_reach_cpu_s"] = float(np.median([r[1] for r in reach]))
    out["python_import_mujoco_mink_s"] = float(np.median([r[0] for r in bare]))
    return out


def first_use(workdir: Path) -> dict:
    """Clone this checkout's HEAD into ``workdir``, make a fresh virtual environment there
    and install it as the README says (``pip install -e ".[dev,robots]"``, timed: packages
    come from pip's cache where it has them), then time a from-scratch build of the C++
    engine alone, and the fresh-process figures of :func:`startup_figures` in that
    environment. The first ``qpik reach`` after the install is the first use."""
    clone = workdir / "qpik"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
    subprocess.run([sys.executable, "-m", "venv", str(clone / ".venv")], check=True)
    python = str(clone / ".venv" / "bin" / "python")
    subprocess.run([python, "-m", "pip", "install", "-q", "--upgrade", "pip"], check=True)
    tic = time.perf_counter()
    subprocess.run(
        [python, "-m", "pip", "install", "-q", "-e", ".[dev,robots]"],
        check=True, cwd=clone, capture_output=True,
    )  # fmt: skip
    install = time.perf_counter() - tic
    # The build requirements (nanobind's CMake package) into the environment, for the
    # engine's separate build below: pip's install built it in an isolated environment.
    text = (clone / "pyproject.toml").read_text()
    requires = json.loads(re.search(r"^requires = (\[.*\])$", text, re.M).group(1))
    subprocess.run(
        [python, "-m", "pip", "install", "-q", *requires, "ninja", "cmake"],
        check=True, capture_output=True,
    )  # fmt: skip
    cmake = [
        str(clone / ".venv" / "bin" / "cmake"), "-S", ".", "-B", "build/first-use", "-G",
        "Ninja", f"-DPython_EXECUTABLE={python}",
    ]  # fmt: skip
    subprocess.run(cmake, check=True, cwd=clone, capture_output=True)
    compile_wall, compile_cpu = _timed_command([cmake[0], "--build", "build/first-use"], clone)
    out = {"install_s": install, "compile_s": compile_wall, "compile_cpu_s": compile_cpu}
    first_reach = _timed_command(
        [str(clone / ".venv" / "bin" / "qpik"), "reach", "tasks/panda_pose_reach.toml"], clone
    )
    out["qpik_reach_very_first_s"] = first_reach[0]
    out.update(startup_figures(python, clone))
    return out


def print_startup(st: dict) -> None:
    """The fresh-process figures, with the issue-20 goals beside them."""
    if "install_s" in st:
        print(
            f"install (fresh clone, fresh venv, pip install -e '.[dev,robots]'): "
            f"{st['install_s']:.1f} s; the C++ engine's compile alone: "
            f"{st['compile_s']:.1f} s wall / {st['compile_cpu_s']:.1f} s CPU (goal <= 90 s); "
            f"the very first qpik reach: {st['qpik_reach_very_first_s']:.2f} s"
        )
    if os.environ.get("PYTHONDONTWRITEBYTECODE"):
        print(
            "note: PYTHONDONTWRITEBYTECODE is set here: no module's bytecode is cached, so "
            "every fresh process below compiles qpik's (and its dependencies') sources again"
        )
    over = st["import_over_s"]
    ratio = st["qpik_reach_s"] / st["python_import_mujoco_mink_s"]
    print(
        f"fresh process (median): import qpik {st['import_s']:.3f} s against import mujoco, "
        f"mink {st['import_mujoco_mink_s']:.3f} s: +{over:.3f} s, median of the paired "
        "differences, interleaved (goal <= 0.2 s)"
    )
    print(
        f"qpik reach tasks/panda_pose_reach.toml {st['qpik_reach_s']:.2f} s (first "
        f"{st['qpik_reach_first_s']:.2f} s) against python -c 'import mujoco, mink' "
        f"{st['python_import_mujoco_mink_s']:.2f} s: {ratio:.2f}x (goal <= 1.5x)"
    )
    print(
        f"first IKSession.solve {1e3 * st['first_session_solve_s']:.2f} ms (goal <= 2 ms), "
        f"first IKSolver.step {1e3 * st['first_step_s']:.2f} ms (goal <= 1 ms), "
        f"5 ms budget on the first call: reasons {st['budget_reasons']}, slowest "
        f"{1e3 * st['budget_first_call_s']:.2f} ms"
    )


def fixed_cost(robot: str = "panda", repeats: int = 2000) -> dict:
    """Median wall and CPU (process) time [us] of a call whose target is met at the start
    (0 iterations), through an IKSession and through qpik.solve."""
    import qpik

    session = qpik.IKSession(robot)
    configuration = qpik.Configuration(session.model)
    configuration.update(session.mid_q())
    target = {"ee": configuration.frame_pose("ee")}
    session.solve(target)
    out = {}
    for name, call in (
        ("session_us", lambda: session.solve(target, seed=1)),
        ("solve_us", lambda: qpik.solve(session.model, target, seed=1)),
    ):
        times, cpu_times = [], []
        for _ in range(repeats):
            cpu = time.process_time()
            tic = time.perf_counter()
            call()
            times.append(time.perf_counter() - tic)
            cpu_times.append(time.process_time() - cpu)
        out[name] = 1e6 * float(np.median(times))
        out[name.replace("_us", "_cpu_us")] = 1e6 * float(np.median(cpu_times))
    return out


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", help="robots (default: bench.default_robots())")
    parser.add_argument("--n", type=at_least(1), default=bench.DEFAULT_N, help="targets per robot")
    parser.add_argument(
        "--methods",
        nargs="+",
        default=["qpik", "oneshot", *bench.peer_methods()],
        choices=list(bench.METHODS),
        help="methods (default: qpik, oneshot and the peers installed: tracik rtb_lm; "
        "baselines: pinv dls mink pink)",
    )
    parser.add_argument("--seed", type=at_least(0), default=0, help="seed of the targets")
    parser.add_argument("--skip-second", action="store_true", help="only the headline")
    parser.add_argument(
        "--first-use",
        action="store_true",
        help="fresh clone + fresh venv: install and compile time, then the startup figures",
    )
    parser.add_argument(
        "--startup-only", action="store_true", help="only the startup (or first-use) figures"
    )
    parser.add_argument("--json", metavar="OUT", help="write the results as JSON to OUT")
    args = parser.parse_args(argv)
    robots = args.robots or bench.default_robots()
    for robot in robots:  # an unknown robot or a bad file: its typed error, before any run
        try:
            bench.load_quietly(robot)
        except QpikError as exc:
            parser.error(f"--robots {robot}: {exc}")
    with os.popen("uptime") as stream:
        load = stream.read().strip()
    print(f"machine: {os.cpu_count()} cores; {load}")
    found = bench.peer_methods()
    missing = [name for name in bench.PEERS if name not in found]
    print(
        f"peers found: {', '.join(found) or 'none'}"
        + (f"; missing (pip install -e '.[compare]'): {', '.join(missing)}" if missing else "")
        + f"; methods run: {', '.join(args.methods)}"
    )
    if args.first_use:
        with tempfile.TemporaryDirectory() as workdir:
            startup = first_use(Path(workdir))
    else:
        startup = startup_figures()
    if args.startup_only:
        print_startup(startup)
        return {"startup": startup}
    headline = _timed_run(robots, args, bench.TRACIK)
    bench.print_table(headline)
    _print_cpu(headline)
    second = None
    if not args.skip_second:
        print()
        second = _timed_run(robots, args, bench.COARSE)
        bench.print_table(second)
        _print_cpu(second)
    if "qpik" in args.methods:
        print("\nGoals (issue 11), qpik:")
        print("\n".join("  " + line for line in bench.check_goals(headline, second)))
        peer_lines = bench.check_peer_goals(headline)
        if peer_lines:
            print("\nGoals (issue 20), qpik beside the peers, TRAC-IK protocol:")
            print("\n".join("  " + line for line in peer_lines))
    extra = {"fixed_cost": fixed_cost(), "startup": startup}
    f = extra["fixed_cost"]
    print(
        f"\nfixed cost of a call (target met at the start, median of 2000): "
        f"IKSession.solve {f['session_us']:.1f} us wall / {f['session_cpu_us']:.1f} us CPU, "
        f"qpik.solve {f['solve_us']:.1f} us wall / {f['solve_cpu_us']:.1f} us CPU"
    )
    print_startup(startup)
    results = {"headline": headline, "second": second, **extra}
    if args.json:
        with open(args.json, "w") as stream:
            json.dump(results, stream, indent=2)
    return results


def _timed_run(robots: list[str], args: argparse.Namespace, protocol) -> dict:
    """One protocol's run, with its wall and process CPU time: CPU / wall below 1 is the
    share of a core the machine left the benchmark (the rest went to other processes)."""
    cpu = time.process_time()
    tic = time.perf_counter()
    results = bench.run_ik_success(
        robots, n=args.n, methods=args.methods, seed=args.seed, protocol=protocol
    )
    wall, cpu = time.perf_counter() - tic, time.process_time() - cpu
    results["run"] = {"wall_s": wall, "process_cpu_s": cpu}
    print(
        f"{protocol.name} run: {wall:.1f} s wall, {cpu:.1f} s process CPU "
        f"(CPU / wall {cpu / wall:.2f})"
    )
    return results


def _print_cpu(results: dict) -> None:
    parts = [
        f"{robot} {method} {s['cpu_mean_ms']:.3f}/{s['cpu_median_ms']:.3f}"
        for robot, entry in results["robots"].items()
        for method, s in entry["methods"].items()
    ]
    print("cpu ms (mean/median, thread CPU time): " + ", ".join(parts))


if __name__ == "__main__":
    import bench_cli  # benchmarks/bench_cli.py (this folder is on sys.path)

    bench_cli.run(main)
