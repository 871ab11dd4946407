"""Problem files: every shipped file loads and solves; malformed files name the file, the
field and what was expected."""

from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from conftest import has_erd

import qpik
from qpik.problem import TASK_TYPES, problem_files

TASKS = problem_files()
TASKS_DIR = Path(__file__).resolve().parents[2] / "tasks"

#: Expected outcome of each shipped file.
CONVERGED = {
    "panda_holding_force": True,
    "panda_obstacle_avoidance": True,
    "panda_pose_reach": True,
    "planar_2r_singularity": True,
    "planar_4r_priorities": True,
    "planar_4r_self_motion": True,
    "talos_both_hands": True,
    "ur5e_velocity_limits": True,
}


#: Shipped files that need example-robot-data (the robots extra).
NEEDS_ERD = {"talos_both_hands"}


def test_every_shipped_file_is_listed():
    assert sorted(p.stem for p in TASKS) == sorted(CONVERGED)


@pytest.fixture(scope="module")
def solved():
    return {
        path.stem: qpik.load_problem(path).solve()
        for path in TASKS
        if path.stem not in NEEDS_ERD or has_erd()
    }


@pytest.mark.parametrize("name", sorted(CONVERGED))
def test_shipped_file_solves(solved, name):
    if name not in solved:
        pytest.skip("needs qpik[robots] (example-robot-data)")
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


# ------------------------------------------------------------------ range checks (issue 13)
def _with_solver(line: str) -> str:
    return BASE + f"\n[solver]\n{line}\n"


def _with_task_option(line: str) -> str:
    return BASE.replace('type = "position"', f'type = "position"\n{line}')


@pytest.mark.parametrize(
    "text, field",
    [
        (_with_task_option("lm_damping = -1"), "levels[0].tasks[0].lm_damping"),
        (_with_task_option("lm_damping = nan"), "levels[0].tasks[0].lm_damping"),
        (_with_task_option("lm_damping = inf"), "levels[0].tasks[0].lm_damping"),
        (_with_task_option("gain = 1.5"), "levels[0].tasks[0].gain"),
        (_with_task_option("gain = nan"), "levels[0].tasks[0].gain"),
        (_with_task_option("cost = 1e300"), "levels[0].tasks[0].cost"),
        (_with_task_option("cost = [1.0, 1e300, 1.0]"), "levels[0].tasks[0].cost"),
        (_with_task_option("cost = -inf"), "levels[0].tasks[0].cost"),
        (_with_solver("max_damping = nan"), "solver.max_damping"),
        (_with_solver("max_damping = -1"), "solver.max_damping"),
        (_with_solver("lower_trust = 1.5"), "solver.lower_trust"),
        (_with_solver("lower_trust = -0.5"), "solver.lower_trust"),
        (_with_solver("singular_threshold = inf"), "solver.singular_threshold"),
        (_with_solver("damping = -1e-6"), "solver.damping"),
        (_with_solver("tol_position = -1"), "solver.tol_position"),
        (_with_solver("tol_position = nan"), "solver.tol_position"),
        (_with_solver("tol_orientation = 0"), "solver.tol_orientation"),
        (_with_solver("time_budget = inf"), "solver.time_budget"),
        (_with_solver("time_budget = nan"), "solver.time_budget"),
        (_with_solver("time_budget = 1e300"), "solver.time_budget"),
        (_with_solver("seed = -1"), "solver.seed"),
        (_with_solver("restarts = 1000000000"), "solver.restarts"),
        (_with_solver("max_iters = 0"), "solver.max_iters"),
        (_with_solver("alpha = 0"), "solver.alpha"),
        (_with_solver("beta = inf"), "solver.beta"),
        (_with_solver("stall_window = 0"), "solver.stall_window"),
        (_with_solver("max_step = [1e300, 0.5]"), "solver.max_step[0]"),
        (_with_solver("max_step = [0.2, 0]"), "solver.max_step[1]"),
        (BASE + "\n[limits]\nvelocity = [1.0, inf]\n", "limits.velocity"),
        (BASE + "\n[limits]\nvelocity = [1.0, 1e-300]\n", "limits.velocity[1]"),
        (BASE + "\n[limits]\nvelocity = { q1 = 1.0, q2 = inf }\n", "limits.velocity.q2"),
        (
            BASE.replace("position = [1.0, 1.0, 0.0]", "position = [1e200, 1.0, 0.0]"),
            "target.position",
        ),
        (
            BASE.replace("position = [1.0, 1.0, 0.0]", "position = [1, 1, 0]\nrpy = [1e300, 0, 0]"),
            "target.rpy",
        ),
        (BASE.replace("q0 = [0.3, 0.6]", "q0 = [0.3, nan]"), "q0"),
        (
            BASE.replace("robot", 'mode = "track"\nrobot', 1) + "\n[track]\ndt = inf\nsteps = 3\n",
            "track.dt",
        ),
        (
            BASE.replace("robot", 'mode = "track"\nrobot', 1)
            + "\n[track]\ndt = 0.01\nsteps = 1000000000000\n",
            "track.steps",
        ),
        (BASE + "\n[statics]\nforce = [1e300, 0, 0]\n", "statics.force"),
        (BASE + "\n[statics]\npayload_direction = [0, 0, 0]\n", "statics.payload_direction"),
    ],
)
def test_every_number_is_range_checked_at_load_time(tmp_path, text, field):
    path = write(tmp_path, text)
    with pytest.raises(qpik.ProblemFileError) as info:
        qpik.load_problem(path)
    assert info.value.field == field and info.value.path == str(path), str(info.value)
    assert str(path) in str(info.value) and repr(field) in str(info.value)


def test_huge_quaternion_and_payload_direction_are_normalised_without_overflow(tmp_path):
    text = (
        BASE.replace('type = "position"', 'type = "frame"').replace(
            "position = [1.0, 1.0, 0.0]",
            "position = [1.0, 1.0, 0.0]\nquaternion = [1e300, 0, 0, 1e300]",
        )
        + "\n[statics]\npayload_direction = [0, 1e-320, 0]\n"
    )
    problem = qpik.load_problem(write(tmp_path, text))
    expected = np.zeros(9)
    mujoco.mju_quat2Mat(expected, np.array([1.0, 0.0, 0.0, 1.0]) / math.sqrt(2.0))
    np.testing.assert_allclose(problem.goals[0].target.rotation, expected.reshape(3, 3), atol=1e-15)
    np.testing.assert_array_equal(problem.statics["payload_direction"], [0.0, 1.0, 0.0])


def test_non_utf8_file_names_the_byte(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(BASE.replace('"planar_2r"', '"planar_2r" # caf\xe9').encode("latin-1"))
    with pytest.raises(qpik.ProblemFileError, match=r"UTF-8.*byte \d+ \(line \d+\)") as info:
        qpik.load_problem(path)
    assert info.value.field == "(file)"


def test_byte_order_mark_is_accepted(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + BASE.encode())
    assert qpik.load_problem(path).model.nv == 2


@pytest.mark.parametrize("nesting", ["[" * 3000 + "]" * 3000, "{a = " * 3000 + "1" + "}" * 3000])
def test_deeply_nested_file_is_a_problem_file_error(tmp_path, nesting):
    path = write(tmp_path, f"x = {nesting}\n")
    with pytest.raises(qpik.ProblemFileError, match="nested") as info:
        qpik.load_problem(path)
    assert info.value.field == "(file)"


def test_robot_name_too_long_is_a_problem_file_error(tmp_path):
    path = write(tmp_path, BASE.replace('"planar_2r"', '"' + "x" * 5000 + '.xml"'))
    with pytest.raises(qpik.ProblemFileError) as info:
        qpik.load_problem(path)
    assert info.value.field == "robot"


UNNAMED_FIRST_KEY = """<mujoco model="keys">
  <compiler angle="radian"/>
  <worldbody>
    <body name="l1"><joint name="j1" axis="0 0 1" range="-3 3"/>
      <geom type="capsule" fromto="0 0 0 1 0 0" size="0.05"/>
      <body name="l2" pos="1 0 0"><joint name="j2" axis="0 0 1" range="-3 3"/>
        <geom type="capsule" fromto="0 0 0 1 0 0" size="0.05"/><site name="ee" pos="1 0 0"/>
      </body>
    </body>
  </worldbody>
  <keyframe><key qpos="0.5 0.5"/><key name="home" qpos="1.0 -1.0"/></keyframe>
</mujoco>
"""


def test_q0_keyframe_by_name_when_an_unnamed_keyframe_comes_first(tmp_path):
    (tmp_path / "keys.xml").write_text(UNNAMED_FIRST_KEY)
    text = BASE.replace('"planar_2r"', '"keys.xml"').replace("q0 = [0.3, 0.6]", 'q0 = "home"')
    problem = qpik.load_problem(write(tmp_path, text))
    assert problem.q0.tolist() == [1.0, -1.0]


def test_q0_within_tolerance_outside_a_limit_is_clamped_and_iterates_stay_inside(tmp_path):
    upper = qpik.Configuration(qpik.load_robot("planar_2r")).upper
    q0 = f"q0 = [0.3, {float(upper[1]) + 5e-7!r}]"
    text = BASE.replace("q0 = [0.3, 0.6]", q0).replace(
        "position = [1.0, 1.0, 0.0]", "position = [0.5, 1.5, 0.0]"
    )
    problem = qpik.load_problem(write(tmp_path, text))
    assert problem.q0[1] == upper[1]
    result = problem.solve()
    for q in result.path:
        assert np.all(q <= upper) and np.all(q >= -upper)


def test_report_says_which_collisions_were_checked(solved):
    result = solved["panda_obstacle_avoidance"]
    collisions = result.to_dict()["collisions"]
    limit = result.problem.build_limits()[-1]
    model = result.problem.model
    names = [(model.geom(a).name, model.geom(b).name) for a, b in limit.geom_id_pairs]
    assert collisions["pairs"] == [list(pair) for pair in names]
    assert collisions["min_distance"] == 0.01
    # the closest pair along the path, from MuJoCo's mj_geomDistance independently
    data = mujoco.MjData(model)
    closest = np.inf
    for q in result.path:
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        for a, b in limit.geom_id_pairs:
            closest = min(closest, mujoco.mj_geomDistance(model, data, a, b, 2.0, None))
    assert collisions["path_distance"] == pytest.approx(closest, abs=1e-12)
    assert collisions["path_distance"] >= 0.01 - 1e-3  # d_min - 1 mm
    assert "collisions checked: 31 geom pair(s) kept 0.01 m apart" in result.summary()
    plain = solved["panda_pose_reach"]
    assert plain.to_dict()["collisions"] is None and "collisions" not in plain.summary()


def test_solve_mode_with_collision_limits_excludes_a_target_inside_an_obstacle(tmp_path):
    base = (TASKS_DIR / "panda_pose_reach.toml").read_text()
    ball = '[[obstacles]]\nshape = "sphere"\nsize = [0.05]\nposition = [0.45, 0.25, 0.40]\n'
    inside = base.replace('q0 = "home"\n', 'q0 = "home"\n\n' + ball, 1)
    inside = inside.replace("restarts = 10", "restarts = 2")
    free = qpik.load_problem(write(tmp_path, inside)).solve()
    assert free.converged  # no collision limit: the tip goes into the ball
    checked = inside.replace("position = true", "position = true\n[limits.collision]", 1)
    result = qpik.load_problem(write(tmp_path, checked)).solve()
    assert not result.converged
    collisions = result.to_dict()["collisions"]
    assert collisions["distance"] >= 0.005 - 1e-4  # the default d_min, 5 mm
    assert "collisions checked" in result.summary()
