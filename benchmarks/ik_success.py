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

Also printed: ``import qpik`` and the first solve in a fresh process (numba's cache warm),
the fixed cost of a call (a target already met at the start: validation, one forward
kinematics and the result), the time of ``qpik reach tasks/panda_pose_reach.toml``, and with
``--compile`` the first-call compile time of the kernels in a fresh numba cache.

Wall times include whatever else the machine runs; the CPU figures beside them (thread CPU
time per solve, process CPU time of each run, of the fixed-cost calls and of the fresh
processes) show the solver's own time on a shared machine, and each run's CPU / wall ratio
how much of a core it was given.

    python benchmarks/ik_success.py                  # N = 1000 per robot, about 1 min
    python benchmarks/ik_success.py --n 10000        # the full run
    python benchmarks/ik_success.py --robots erd:ur5 panda --n 200 --methods qpik dls
        [--skip-second] [--compile] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import ik_bench as bench  # benchmarks/ik_bench.py (this folder is on sys.path)
import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def _fresh_process(code: str, env: dict | None = None) -> str:
    return subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        env={**os.environ, **(env or {})},
        cwd=ROOT,
    ).stdout


_STARTUP = """
import time
t0, c0 = time.perf_counter(), time.process_time()
import qpik
t1, c1 = time.perf_counter(), time.process_time()
result = qpik.solve("panda", {"ee": [0.4, 0.1, 0.5]})
t2, c2 = time.perf_counter(), time.process_time()
print(t1 - t0, t2 - t1, c1 - c0, c2 - c1, result.converged)
"""


def _children_cpu() -> float:
    """CPU time [s] (user + system) of the finished child processes so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def startup_figures(compile_too: bool) -> dict:
    """``import qpik``, the first solve in a fresh process, ``qpik reach`` on the shipped
    panda problem (warm numba cache), and with ``compile_too`` the same first solve with an
    empty numba cache (the compile time)."""
    _fresh_process(_STARTUP)  # make sure the cache is warm
    out = {}
    runs = [_fresh_process(_STARTUP).split() for _ in range(3)]
    out["import_s"] = float(np.median([float(r[0]) for r in runs]))
    out["first_solve_s"] = float(np.median([float(r[1]) for r in runs]))
    out["import_cpu_s"] = float(np.median([float(r[2]) for r in runs]))
    out["first_solve_cpu_s"] = float(np.median([float(r[3]) for r in runs]))
    reach, reach_cpu = [], []
    for _ in range(3):
        cpu = _children_cpu()
        tic = time.perf_counter()
        subprocess.run(
            [str(Path(sys.executable).parent / "qpik"), "reach", "tasks/panda_pose_reach.toml"],
            capture_output=True,
            check=False,
            cwd=ROOT,
        )
        reach.append(time.perf_counter() - tic)
        reach_cpu.append(_children_cpu() - cpu)
    out["qpik_reach_s"] = float(np.median(reach))
    out["qpik_reach_cpu_s"] = float(np.median(reach_cpu))
    if compile_too:
        with tempfile.TemporaryDirectory() as cache:
            run = _fresh_process(_STARTUP, {"NUMBA_CACHE_DIR": cache}).split()
        out["first_solve_cold_cache_s"] = float(run[1])
    return out


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
    parser.add_argument("--n", type=int, default=bench.DEFAULT_N, help="targets per robot")
    parser.add_argument(
        "--methods",
        nargs="+",
        default=["qpik"],
        choices=list(bench.METHODS),
        help="methods (default: qpik; baselines: pinv dls mink pink)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the targets")
    parser.add_argument("--skip-second", action="store_true", help="only the headline")
    parser.add_argument(
        "--compile", action="store_true", help="also time the first call with an empty cache"
    )
    parser.add_argument("--json", metavar="OUT", help="write the results as JSON to OUT")
    args = parser.parse_args(argv)
    robots = args.robots or bench.default_robots()
    with os.popen("uptime") as stream:
        load = stream.read().strip()
    print(f"machine: {os.cpu_count()} cores; {load}")
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
    extra = {"fixed_cost": fixed_cost(), "startup": startup_figures(args.compile)}
    f, st = extra["fixed_cost"], extra["startup"]
    print(
        f"\nfixed cost of a call (target met at the start, median of 2000): "
        f"IKSession.solve {f['session_us']:.1f} us wall / {f['session_cpu_us']:.1f} us CPU, "
        f"qpik.solve {f['solve_us']:.1f} us wall / {f['solve_cpu_us']:.1f} us CPU"
    )
    print(
        f"fresh process, warm numba cache (wall / CPU): import qpik {st['import_s']:.2f} / "
        f"{st['import_cpu_s']:.2f} s, first solve {st['first_solve_s']:.2f} / "
        f"{st['first_solve_cpu_s']:.2f} s; qpik reach tasks/panda_pose_reach.toml "
        f"{st['qpik_reach_s']:.2f} / {st['qpik_reach_cpu_s']:.2f} s"
    )
    if "first_solve_cold_cache_s" in st:
        cold = st["first_solve_cold_cache_s"]
        print(f"first solve with an empty numba cache (compile): {cold:.1f} s")
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
    main()
