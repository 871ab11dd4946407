"""Problem files: every shipped file loads and solves; malformed files name the file, the
field and what was expected."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import qpik
from qpik.problem import TASK_TYPES, problem_files

TASKS = problem_files()

#: Expected outcome of each shipped file.
CONVERGED = {
    "panda_holding_force": True,
    "panda_pose_reach": True,
    "planar_2r_singularity": True,
    "planar_4r_priorities": True,
    "planar_4r_self_motion": True,
    "ur5e_velocity_limits": True,
}


def test_every_shipped_file_is_listed():
    assert sorted(p.stem for p in TASKS) == sorted(CONVERGED)


@pytest.fixture(scope="module")
def solved():
    return {path.stem: qpik.load_problem(path).solve() for path in TASKS}


@pytest.mark.parametrize("name", sorted(CONVERGED))
def test_shipped_file_solves(solved, name):
    result = solved[name]
    assert result.converged is CONVERGED[name], result.reason
    model = result.problem.model
    configuration = qpik.Configuration(model, result.q)
    assert configuration.within_limits()
    data = json.loads(result.to_json())
    assert data["converged"] is CONVERGED[name] and len(data["q"]) == model.nq
    assert json.loads(result.problem.to_json())["name"] == name


def test_singular_start_reaches_every_waypoint(solved):
    result = solved["planar_2r_singularity"]
    assert result.problem.q0.tolist() == [0.0, 0.0]
    assert len(result.results) == 3 and all(r.converged for r in result.results)


def test_self_motion_keeps_the_tip_and_moves_away_from_limits(solved):
    result = solved["planar_4r_self_motion"]
    trace = result.trace
    assert np.all(trace.position_error[10:] < 1e-3)  # the tip stays at (-1, 2)
    lower, upper = -np.pi * np.ones(4), np.pi * np.ones(4)
    distance = [qpik.analysis.joint_limit_distance(q, lower, upper) for q in trace.q]
    assert distance[-1] < 0.95 * distance[0]
    assert np.linalg.norm(trace.q[-1] - trace.q[0]) > 0.3  # a real self-motion


def test_priorities_lower_level_keeps_its_residual(solved):
    trace = solved["planar_4r_priorities"].trace
    assert trace.position_error[-1] < 1e-6
    # level 1 (gain 0.1) cannot reach: its residual is gain * 0.83 m
    assert trace.residuals[-1][1] == pytest.approx(0.1 * (math.sqrt(8) - 2), rel=1e-3)
    assert np.abs(trace.velocity[-1]).max() < 0.05  # at rest, no chattering


def test_velocity_limits_hold_while_tracking(solved):
    result = solved["ur5e_velocity_limits"]
    assert result.trace.max_velocity_ratio <= 1.0 + 1e-6
    assert result.trace.max_velocity_ratio > 0.99  # the limit binds on the way


def test_statics_report(solved):
    report = solved["panda_holding_force"].statics
    assert report.within_limits is True
    assert report.payload.feasible and report.payload.force > 20.0
    np.testing.assert_allclose(report.holding, -(report.gravity + report.tau), atol=1e-9)


# ------------------------------------------------------------------ malformed files
BASE = """
robot = "planar_2r"
q0 = [0.3, 0.6]

[[levels]]
[[levels.tasks]]
type = "position"
frame = "ee"

[target]
position = [1.0, 1.0, 0.0]
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "problem.toml"
    path.write_text(text)
    return path


def test_minimal_file_solves(tmp_path):
    result = qpik.load_problem(write(tmp_path, BASE)).solve()
    assert result.converged and result.problem.name == "problem"


@pytest.mark.parametrize(
    "text, field, fragment",
    [
        (BASE.replace('robot = "planar_2r"', ""), "robot", "missing"),
        (BASE.replace("[target]\nposition = [1.0, 1.0, 0.0]", ""), "target", "exactly one"),
        (BASE.replace('type = "position"', ""), "levels[0].tasks[0].type", "missing"),
        (BASE.replace("q0 = [0.3, 0.6]", 'q0 = "sideways"'), "q0", "mid, qpos0"),
        (BASE.replace("q0 = [0.3, 0.6]", "q0 = [0.3]"), "q0", "2 numbers"),
        (BASE.replace("q0 = [0.3, 0.6]", "q0 = [0.3, 9.0]"), "q0", "outside its limits"),
        (
            BASE.replace("position = [1.0, 1.0, 0.0]", 'position = "up"'),
            "target.position",
            "a string",
        ),
        (
            BASE.replace("position = [1.0, 1.0, 0.0]", "position = [1.0, 1.0]"),
            "target.position",
            "[x, y, z]",
        ),
        (BASE.replace('frame = "ee"', "frame = 3"), "levels[0].tasks[0].frame", "an integer"),
        (BASE + "\n[solver]\nmax_iters = 2.5\n", "solver.max_iters", "an integer"),
        (BASE + "\n[solver]\nmax_iter = 2\n", "solver.max_iter", "unknown field"),
        (BASE + "\n[limits]\nvelocity = 0.5\n", "limits.velocity", "no velocity_limit"),
        (
            BASE.replace('type = "position"', 'type = "pose"'),
            "levels[0].tasks[0].type",
            "unknown task type 'pose'",
        ),
        (
            BASE.replace('frame = "ee"', 'frame = "tip"'),
            "levels[0].tasks[0].frame",
            "available sites: ee",
        ),
        (BASE.replace('"planar_2r"', '"planar_9r"'), "robot", "unknown robot 'planar_9r'"),
        (BASE.replace('"planar_2r"', '"arm/missing.xml"'), "robot", "no such file"),
        (BASE.replace("[target]", "[target\n"), "(file)", "valid TOML"),
        (
            BASE.replace("position = [1.0, 1.0, 0.0]", "position = [1, 1, 0]\nrpy = [0, 0]"),
            "target.rpy",
            "[roll, pitch, yaw]",
        ),
        (BASE.replace("robot", 'mode = "fly"\nrobot', 1), "mode", '"solve" or "track"'),
        (BASE.replace("robot", 'mode = "track"\nrobot', 1), "track", "missing"),
    ],
)
def test_malformed_files(tmp_path, text, field, fragment):
    path = write(tmp_path, text)
    with pytest.raises(qpik.ProblemFileError) as info:
        qpik.load_problem(path)
    error = info.value
    assert error.path == str(path) and error.field == field
    message = str(error)
    assert str(path) in message and repr(field) in message and fragment in message, message


def test_unknown_task_type_lists_known_types(tmp_path):
    path = write(tmp_path, BASE.replace('type = "position"', 'type = "pose"'))
    with pytest.raises(qpik.ProblemFileError) as info:
        qpik.load_problem(path)
    assert all(name in str(info.value) for name in TASK_TYPES)


def test_missing_file(tmp_path):
    with pytest.raises(qpik.ProblemFileError, match="readable TOML"):
        qpik.load_problem(tmp_path / "absent.toml")


def test_robot_path_relative_to_the_file(tmp_path):
    robot = Path(qpik.robots.robot_path("planar_2r"))
    (tmp_path / "arm.xml").write_text(robot.read_text())
    problem = qpik.load_problem(write(tmp_path, BASE.replace('"planar_2r"', '"arm.xml"')))
    assert problem.model.nv == 2


def test_every_task_type_and_rotation_form_loads(tmp_path):
    text = """
robot = "panda"
q0 = "home"
[[levels]]
[[levels.tasks]]
type = "frame"
frame = "ee"
orientation_cost = 0.5
[[levels]]
[[levels.tasks]]
type = "orientation"
frame = "link7"
frame_type = "body"
target = { matrix = [[1, 0, 0], [0, -1, 0], [0, 0, -1]] }
[[levels.tasks]]
type = "position"
frame = "link4"
frame_type = "body"
[[levels.tasks]]
type = "posture"
cost = [1, 1, 1, 1, 1, 1, 1]
target = { q = "mid" }
[[levels.tasks]]
type = "joint_limit_distance"
[[levels.tasks]]
type = "manipulability"
frame = "ee"
rows = "position"
[[levels.tasks]]
type = "com"
cost = 0.1
[[levels.tasks]]
type = "damping"
cost = 0.01
[[waypoints]]
position = [0.4, 0.1, 0.5]
quaternion = [0, 1, 0, 0]
[[waypoints]]
position = [0.4, -0.1, 0.5]
rpy = [3.14159265, 0, 0]
[limits]
velocity = { joint1 = 2, joint2 = 2, joint3 = 2, joint4 = 2, joint5 = 2, joint6 = 2, joint7 = 2 }
"""
    problem = qpik.load_problem(write(tmp_path, text))
    kinds = [spec.type for level in problem.levels for spec in level]
    assert set(kinds) == set(TASK_TYPES)
    np.testing.assert_allclose(
        problem.goals[0].target.rotation, problem.goals[1].target.rotation, atol=1e-7
    )
    stack = problem.build_stack()
    assert [type(t) for t in stack[0]] == [qpik.tasks.FrameTask]
    result = problem.solve()
    assert result.converged, result.reason


def test_solve_mode_takes_a_constant_damping(tmp_path):
    path = tmp_path / "damped.toml"
    path.write_text(
        'robot = "planar_2r"\nq0 = [0.3, 0.5]\n\n[[levels]]\n[[levels.tasks]]\n'
        'type = "position"\nframe = "ee"\n\n[target]\nposition = [1.2, 0.8, 0.0]\n\n'
        "[solver]\ndamping = 1e-4\n"
    )
    result = qpik.load_problem(path).solve()
    assert result.converged, result.reason
