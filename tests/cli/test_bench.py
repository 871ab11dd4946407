"""The IK success benchmark (benchmarks/ik_bench.py, benchmarks/ik_methods.py) and
``qpik bench``, which runs it from a source checkout."""

from __future__ import annotations

import dataclasses
import json
import sys
import warnings

import numpy as np
import pytest
from conftest import has_erd

from qpik.cli import main
from qpik.cli.bench import BENCHMARKS, harness
from qpik.robots import load_robot

if not (BENCHMARKS / "ik_bench.py").is_file():  # an sdist: benchmarks/ is not shipped
    pytest.skip("the benchmark harness lives in the source checkout", allow_module_level=True)
bench = harness()


@pytest.fixture(scope="module")
def small_run() -> dict:
    # No time budget: success must not depend on how loaded the machine is.
    return bench.run_ik_success(["ur5e", "panda"], n=5, budget=None, progress=False)


def test_benchmark_result_structure(small_run):
    protocol = small_run["protocol"]
    assert protocol["n"] == 5 and protocol["budget_s"] is None
    assert protocol["tol_position_m"] == 1e-4 and protocol["tol_orientation_rad"] == 1e-3
    assert list(small_run["robots"]) == ["ur5e", "panda"]
    assert protocol["methods"] == bench.available_methods()
    for robot, dof in (("ur5e", 6), ("panda", 7)):
        entry = small_run["robots"][robot]
        assert entry["nv"] == entry["arm_dof"] == dof
        assert (entry["frame"], entry["frame_type"]) == ("ee", "site")
        assert list(entry["methods"]) == protocol["methods"]
        for summary in entry["methods"].values():
            assert summary["n"] == 5 and 0 <= summary["successes"] <= 5
            assert summary["success_rate"] == summary["successes"] / 5
            assert summary["first_attempt_successes"] <= summary["successes"]
            assert 0 < summary["median_ms"] <= summary["p95_ms"] <= summary["max_ms"]
            assert summary["mean_ms"] > 0 and summary["mean_iterations"] >= 0
            assert summary["limit_violations"] == 0
            assert sum(summary["failure_reasons"].values()) == 5 - summary["successes"]
    json.dumps(small_run)  # JSON-ready


def test_qpik_solves_every_small_target(small_run):
    for robot in ("ur5e", "panda"):
        summary = small_run["robots"][robot]["methods"]["qpik"]
        assert summary["successes"] == 5, summary["failure_examples"]


def test_table_has_a_row_per_robot_and_method(small_run):
    table = bench.format_table(small_run)
    rows = [line for line in table.splitlines() if line.startswith(("ur5e ", "panda "))]
    assert len(rows) == 2 * len(bench.available_methods())
    assert "100.00% (5/5)" in table and "median ms" in table and "mean ms" in table


def test_unknown_method_and_frame_are_named():
    with pytest.raises(ValueError, match="known: qpik, pinv, dls, mink"):
        bench.run_ik_success(["ur5e"], n=1, methods=["newton"], progress=False)
    with pytest.raises(ValueError, match="no tool frame known"):
        bench.robot_frame("mystery", _model_without_ee())


def _model_without_ee():
    import mujoco

    return mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><joint/><geom size='0.1'/></body></worldbody></mujoco>"
    )


def test_tracik_protocol_per_axis_and_published_figures():
    protocol = dataclasses.replace(bench.TRACIK, budget=None)  # no wall clock in tests
    results = bench.run_ik_success(
        ["ur5e", "panda"], n=4, methods=["qpik"], protocol=protocol, progress=False
    )
    assert results["protocol"]["per_axis"] and results["protocol"]["tol_position_m"] == 1e-5
    for entry in results["robots"].values():
        assert entry["methods"]["qpik"]["successes"] == 4
    table = bench.format_table(results)
    assert "1e-05 m on each axis" in table and "TRAC-IK published" in table
    assert "Panda 99.88% 0.37 ms" in table  # beside the bundled panda


def test_per_axis_is_looser_than_the_norm():
    """An error of 0.9e-5 on each of x, y, z passes per axis, fails as a norm (1.56e-5)."""
    small = np.full(3, 0.9e-5)
    assert bench.within_tolerance(small, np.zeros(3), 1e-5, 1e-5, per_axis=True)
    assert not bench.within_tolerance(small, np.zeros(3), 1e-5, 1e-5, per_axis=False)
    assert not bench.within_tolerance(np.zeros(3), [0, 0, 1.1e-5], 1e-5, 1e-5, per_axis=True)
    assert bench.within_tolerance(np.zeros(3), [0, 0, 0.5e-3], 1e-4, 1e-3, per_axis=False)


def test_check_goals_verdicts():
    def summary(rate, mean, median, n=100):
        return {
            "success_rate": rate,
            "successes": int(rate * n),
            "n": n,
            "mean_ms": mean,
            "median_ms": median,
        }

    headline = {
        "robots": {
            "a": {"arm_dof": 6, "methods": {"qpik": summary(1.0, 0.2, 0.15)}},
            "b": {"arm_dof": 7, "methods": {"qpik": summary(0.99, 0.5, 0.3)}},
            "planar": {"arm_dof": 2, "methods": {"qpik": summary(0.5, 9.0, 9.0)}},
        }
    }
    second = {"robots": {"a": {"arm_dof": 6, "methods": {"qpik": summary(1.0, 1, 1)}}}}
    lines = bench.check_goals(headline, second)
    assert "met: a: success 100.00% >= 99.9%" in lines
    assert "MISSED: b: success 99.00% >= 99.9%" in lines
    assert not any("planar" in line for line in lines)  # not a 6- or 7-DoF arm
    assert any(line.startswith("MISSED: mean over all arms 0.350 ms") for line in lines)
    assert any(line.startswith("MISSED: median of the slowest arm 0.300") for line in lines)
    assert "met: a: 100.00% under the second protocol (goal 100.0%)" in lines


def test_robot_frame_falls_back_to_the_tool_frame_rule():
    model = _model_without_ee()
    name, kind = bench.robot_frame("erd:mystery", model)
    assert kind in (bench.FrameType.BODY, bench.FrameType.SITE) and name


# ------------------------------------------------------------------ CLI
def test_cli_bench_writes_table_and_json(tmp_path, capsys):
    out = tmp_path / "bench.json"
    argv = ["bench", "--robots", "planar_2r", "--n", "3", "--methods", "qpik", "pinv"]
    assert main([*argv, "--quiet", "--json", str(out)]) == 0
    captured = capsys.readouterr()
    assert "planar_2r" in captured.out and "qpik" in captured.out and "pinv" in captured.out
    assert captured.err == ""
    data = json.loads(out.read_text())
    assert data["protocol"]["n"] == 3 and data["protocol"]["methods"] == ["qpik", "pinv"]
    assert data["robots"]["planar_2r"]["methods"]["qpik"]["n"] == 3


def test_cli_bench_unknown_robot_exits_2(capsys):
    assert main(["bench", "--robots", "nope", "--n", "1", "--quiet"]) == 2
    assert "unknown robot 'nope'" in capsys.readouterr().err


# ------------------------------------------------------------------ pink (qpik[compare])


_PINK_ROBOTS = ["ur5e", "panda"] + (["erd:panda", "erd:ur5", "erd:kinova"] if has_erd() else [])


@pytest.mark.parametrize("robot", _PINK_ROBOTS)
def test_pinocchio_robot_matches_mujoco(robot, rng):
    """Joint orders mapped by name (erd:kinova has continuous joints, (cos, sin) in
    pinocchio): the same frame pose at random configurations, velocities round-trip."""
    pin = pytest.importorskip("pinocchio")
    pytest.importorskip("pink")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # dropped meshes; pinocchio's misplaced MJCF site
        model = load_robot(robot)
        frame, frame_type = bench.robot_frame(robot, model)
        robot_pin = bench.pinocchio_robot(robot, model, frame, frame_type)
    configuration = bench.Configuration(model)
    data = robot_pin.model.createData()
    for _ in range(5):
        q = configuration.random_q(rng)
        configuration.update(q)
        pin.framesForwardKinematics(robot_pin.model, data, robot_pin.q_to_pinocchio(q))
        position, rotation = configuration.frame_pose(frame, frame_type)
        np.testing.assert_allclose(data.oMf[robot_pin.frame].translation, position, atol=1e-9)
        np.testing.assert_allclose(data.oMf[robot_pin.frame].rotation, rotation, atol=1e-9)
    v = rng.normal(size=model.nv)
    np.testing.assert_array_equal(robot_pin.v_to_mujoco(robot_pin.v_to_pinocchio(v)), v)


@pytest.mark.parametrize("robot", ["ur5e", "panda"] + (["erd:panda"] if has_erd() else []))
def test_pink_method_solves_small_targets(robot):
    pytest.importorskip("pinocchio")
    pytest.importorskip("pink")
    assert "pink" in bench.available_methods()
    results = bench.run_ik_success([robot], n=3, methods=["pink"], budget=None, progress=False)
    entry = results["robots"][robot]
    assert entry["skipped"] == {}
    summary = entry["methods"]["pink"]
    assert summary["successes"] == 3, summary["failure_examples"]
    assert summary["limit_violations"] == 0
    assert "pink" in bench.format_table(results)


def test_pink_missing_is_skipped_with_the_extra_named(monkeypatch):
    monkeypatch.setitem(sys.modules, "pink", None)  # import pink -> ImportError
    assert "pink" not in bench.available_methods()
    results = bench.run_ik_success(
        ["planar_2r"], n=1, methods=["qpik", "pink"], budget=None, progress=False
    )
    entry = results["robots"]["planar_2r"]
    assert list(entry["methods"]) == ["qpik"]
    assert "pip install -e '.[compare]'" in entry["skipped"]["pink"]
    assert "pink skipped on planar_2r" in bench.format_table(results)


def test_cli_bench_outside_a_checkout_says_so(monkeypatch, tmp_path, capsys):
    import qpik.cli.bench as cli_bench

    monkeypatch.setattr(cli_bench, "BENCHMARKS", tmp_path / "benchmarks")
    assert main(["bench", "--robots", "planar_2r", "--n", "1", "--quiet"]) == 2
    assert "source checkout" in capsys.readouterr().err


# ------------------------------------------------------------------ issue 20's peers
_ERD_ARMS = ["erd:panda", "erd:ur5"] if has_erd() else []


def test_oneshot_method_solves_small_targets():
    results = bench.run_ik_success(["panda"], n=3, methods=["oneshot"], budget=None, progress=False)
    summary = results["robots"]["panda"]["methods"]["oneshot"]
    assert summary["successes"] == 3, summary["failure_examples"]


@pytest.mark.parametrize("method, module", [("tracik", "pytracik"), ("rtb_lm", "roboticstoolbox")])
@pytest.mark.parametrize("robot", _ERD_ARMS)
def test_peer_method_solves_small_targets(method, module, robot):
    """TRAC-IK and the Toolbox's ik_LM, on the same URDF as qpik's robot, judged by the
    harness (MuJoCo's forward kinematics of the q they return, joint limits)."""
    pytest.importorskip(module)
    assert method in bench.peer_methods()
    protocol = dataclasses.replace(bench.TRACIK, budget=None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        results = bench.run_ik_success(
            [robot], n=3, methods=[method], protocol=protocol, progress=False
        )
    entry = results["robots"][robot]
    assert entry["skipped"] == {}
    summary = entry["methods"][method]
    assert summary["successes"] >= 2, summary["failure_examples"]  # TRAC-IK: a 1 s timeout
    assert summary["limit_violations"] == 0


@pytest.mark.parametrize("method, module", [("tracik", "pytracik"), ("rtb_lm", "roboticstoolbox")])
def test_peer_method_skips_a_robot_without_urdf(method, module):
    pytest.importorskip(module)
    results = bench.run_ik_success(
        ["planar_2r"], n=1, methods=["qpik", method], budget=None, progress=False
    )
    assert "URDF" in results["robots"]["planar_2r"]["skipped"][method]


def test_peer_goals_verdicts():
    def summary(rate, mean):
        return {"success_rate": rate, "successes": int(rate * 100), "n": 100, "mean_ms": mean}

    headline = {
        "robots": {
            "erd:ur5": {
                "methods": {
                    "qpik": summary(1.0, 0.1),
                    "rtb_lm": summary(1.0, 0.3),
                    "oneshot": summary(1.0, 0.2),
                    "tracik": summary(0.99, 0.4),
                }
            },
        }
    }
    lines = bench.check_peer_goals(headline)
    assert "met: erd:ur5: qpik success 100.00% >= 99.95%" in lines
    assert any(line.startswith("met: erd:ur5: qpik mean / ik_LM mean 0.33") for line in lines)
    assert any(
        line.startswith("MISSED: erd:ur5: qpik.solve (one-shot) mean / IKSession mean 2.00")
        for line in lines
    )
    assert any(line.startswith("beside: erd:ur5: TRAC-IK 99.00%") for line in lines)


@pytest.mark.parametrize(
    "script, arguments, named",
    [
        ("ik_success.py", ["--robots", "no_such_robot", "--n", "1"], "no_such_robot"),
        ("batch.py", ["--robot", "ur5e", "--frame", "no_such_site", "--n", "1"], "no_such_site"),
        ("real_robots.py", ["no_such_folder"], "no_such_folder"),
        ("step_time.py", ["--talos-steps", "0"], "argument --talos-steps: must be at least 2"),
        ("batch.py", ["--n", "0"], "argument --n: must be at least 1, got 0"),
        ("fuzz.py", ["--workers", "0"], "argument --workers: must be at least 1"),
        ("fuzz.py", ["--timeout", "nan"], "argument --timeout: must be a finite number"),
        ("ik_success.py", ["--seed", "-1"], "argument --seed: must be at least 0"),
    ],
)
def test_benchmark_scripts_end_bad_arguments_with_one_line_and_status_2(
    script, arguments, named, tmp_path
):
    """A benchmark script given an unknown robot, frame or folder, or a count or a duration
    out of range (``bench_cli.at_least``, ``positive_float``), prints one line naming it
    (``SCRIPT: error: ...``, benchmarks/bench_cli.py) and exits with status 2, as the
    qpik command line does: no traceback."""
    import subprocess

    run = subprocess.run(
        [sys.executable, str(BENCHMARKS / script), *arguments],
        capture_output=True, text=True, cwd=tmp_path, timeout=120,
    )  # fmt: skip
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert "Traceback" not in run.stderr and named in lines[-1]
    assert lines[-1].startswith(f"{script}: error:")


def test_step_time_daqp_hierarchical_row_holds_the_top_level():
    """benchmarks/step_time.py's ``DAQP hierarchical`` row (``_daqp_hierarchical``): DAQP's
    hierarchical mode on the rows of :meth:`qpik.IKSolver.build`. On the bundled Panda with
    a reachable position task above a posture, both solvers meet the top level within the
    box (DAQP minimises row-normalised slacks, so only what every strict hierarchy must
    agree on is compared: the level-0 task value, and the box). The limits are DAQP's
    first level even where there is no general row (its levels are all soft: with the box
    in level 0's range, a level-0 target beyond the box moved the box instead)."""
    pytest.importorskip("daqp")
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import step_time
    finally:
        sys.path.remove(str(BENCHMARKS))
    from qpik import Configuration, IKSolver
    from qpik.tasks import FrameTask, PostureTask

    model = load_robot("panda")
    configuration = Configuration(model)
    configuration.update(configuration.mid_q())
    frame = FrameTask("ee", "site", position_cost=1.0, orientation_cost=0.0)
    position, rotation = configuration.frame_pose("ee", "site")
    import mink

    target = mink.SE3.from_rotation_and_translation(
        mink.SO3.from_matrix(rotation), position + [0.002, -0.001, 0.001]
    )
    frame.set_target(target)
    posture = PostureTask(model, 0.1)
    posture.set_target(configuration.q + 0.05)
    solver = IKSolver(model, [[frame], [posture]], [mink.ConfigurationLimit(model)])
    dt = 0.01
    problem = solver.build(configuration, dt)
    x, exitflag = step_time._daqp_hierarchical(problem)()
    assert exitflag >= 0
    ours = solver.step(configuration, dt).velocity * dt
    top = problem.levels[0]
    scale = np.abs(top.b).max()
    # (qpik's step is damped, DAQP holds a met level through its soft slacks, rho_soft:
    # both to about 1e-5 of the target here)
    np.testing.assert_allclose(top.A @ ours, top.b, rtol=0, atol=1e-4 * scale)
    np.testing.assert_allclose(top.A @ x, top.b, rtol=0, atol=1e-4 * scale)
    assert np.all(x >= problem.lb - 1e-9) and np.all(x <= problem.ub + 1e-9)
    # a target beyond the step's box: both stop on the box, about as close to the target
    frame.set_target(
        mink.SE3.from_rotation_and_translation(
            mink.SO3.from_matrix(rotation), position + [0.02, -0.01, 0.01]
        )
    )
    problem = solver.build(configuration, dt)
    x, exitflag = step_time._daqp_hierarchical(problem)()
    assert exitflag >= 0
    ours = solver.step(configuration, dt).velocity * dt
    top = problem.levels[0]
    assert np.all(x >= problem.lb - 1e-9) and np.all(x <= problem.ub + 1e-9)
    miss, ours_miss = np.linalg.norm(top.A @ x - top.b), np.linalg.norm(top.A @ ours - top.b)
    assert ours_miss > 1e-3 and ours_miss <= miss <= 1.1 * ours_miss
