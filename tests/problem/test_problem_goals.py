"""Problem files: several frames per goal, the humanoid file, the support-polygon limit,
the task registry, and the errors along the path (issue 15)."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import has_erd as _has_erd

import qpik
from qpik.problem import TASK_KINDS, TaskKind, problem_files
from qpik.tasks import PostureTask

README = Path(__file__).resolve().parents[2] / "tasks" / "README.md"

TWO_FRAMES = """
robot = "panda"
q0 = "home"
mode = "{mode}"

[[levels]]
[[levels.tasks]]
type = "position"
frame = "ee"
[[levels.tasks]]
type = "position"
frame = "link4"
frame_type = "body"

[[levels]]
[[levels.tasks]]
type = "posture"
cost = 0.01
target = {{ q = "home" }}

[target]
[[target.frames]]
frame = "ee"
position = [0.31, 0.096, 0.345]
[[target.frames]]
frame = "link4"
frame_type = "body"
position = [-0.101, -0.031, 0.642]
{extra}
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "problem.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    "mode, extra",
    [("solve", ""), ("track", "[track]\ndt = 0.05\nsteps = 200\nstop_at_goal = true\n")],
)
def test_two_frames_in_one_goal_are_reached_together(tmp_path, mode, extra):
    problem = qpik.load_problem(write(tmp_path, TWO_FRAMES.format(mode=mode, extra=extra)))
    goal = problem.goals[0]
    assert [f.frame for f in goal.frames] == ["ee", "link4"]
    assert goal.frame == "ee" and goal.target is goal.frames[0].target  # the first frame
    assert set(goal.targets()) == {("ee", "site"), ("link4", "body")}
    result = problem.solve()
    assert result.converged, result.reason
    configuration = qpik.Configuration(problem.model, result.q)
    tol = 1e-4 if mode == "solve" else 1e-4 * (1 + 1e-9)
    for position_error, _ in goal.errors(configuration):
        assert position_error <= tol
    if mode == "solve":  # each frame's errors in the summary
        assert "    ee: " in result.summary() and "    link4: " in result.summary()
    data = json.loads(problem.to_json())
    assert [f["frame"] for f in data["goals"][0]["frames"]] == ["ee", "link4"]
    assert data["goals"][0]["frame"] == "ee"


def test_inline_frames_form_is_the_same(tmp_path):
    text = TWO_FRAMES.format(mode="solve", extra="").split("[target]")[0] + (
        "[target]\nframes = [{frame = 'ee', position = [0.31, 0.096, 0.345]}, "
        "{frame = 'link4', frame_type = 'body', position = [-0.101, -0.031, 0.642]}]\n"
    )
    tables = qpik.load_problem(write(tmp_path, TWO_FRAMES.format(mode="solve", extra="")))
    inline = qpik.load_problem(write(tmp_path, text))
    assert inline.goals[0].to_dict() == tables.goals[0].to_dict()


def test_waypoints_with_frames(tmp_path):
    head = TWO_FRAMES.format(mode="solve", extra="").split("[target]")[0]
    text = head + (
        "[[waypoints]]\n[[waypoints.frames]]\nframe = 'ee'\nposition = [0.31, 0.096, 0.345]\n"
        "[[waypoints]]\nframe = 'ee'\nposition = [0.35, -0.10, 0.40]\n"
    )
    problem = qpik.load_problem(write(tmp_path, text))
    assert [len(g.frames) for g in problem.goals] == [1, 1]
    assert problem.goals[0].field == "waypoints[0]"
    assert problem.goals[0].frames[0].field == "waypoints[0].frames[0]"


GOAL_ERRORS = [
    ("frames = []", "target.frames", "at least one frame"),
    ("frames = [1]", "target.frames[0]", "expected a table"),
    ("frames = 'ee'", "target.frames", "a list of frame tables"),
    (
        "frames = [{frame = 'ee', position = [0.4, 0, 0.4]}, {frame = 'ee', position = [0.4, 0, 0.5]}]",
        "target.frames[1].frame",
        "not already in target.frames",
    ),
    (
        "frames = [{frame = 'ee', position = [0.4, 0, 0.4]}, {frame = 'link2', frame_type = 'body', position = [0, 0, 0.4]}]",
        "target.frames[1].frame",
        "no task regulates the body 'link2'",
    ),
    (
        "frames = [{frame = 'ee', position = [0.4, 0, 0.4], speed = 1}]",
        "target.frames[0].speed",
        "unknown field",
    ),
    (
        "position = [0.4, 0, 0.4]\nframes = [{frame = 'ee', position = [0.4, 0, 0.4]}]",
        "target.position",
        "unknown field",
    ),
    ("frames = [{frame = 'ee'}]", "target.frames[0].position", "missing"),
]


@pytest.mark.parametrize("goal, field, fragment", GOAL_ERRORS)
def test_malformed_goal_frames_name_the_field(tmp_path, goal, field, fragment):
    head = TWO_FRAMES.format(mode="solve", extra="").split("[target]")[0]
    path = write(tmp_path, head + "[target]\n" + goal + "\n")
    with pytest.raises(qpik.ProblemFileError) as info:
        qpik.load_problem(path)
    assert info.value.field == field and info.value.path == str(path), str(info.value)
    assert fragment in str(info.value)


SUPPORT_ERRORS = [
    ("frames = []", "limits.support.frames", "frame names"),
    ("frames = ['nope']\nframe_type = 'body'", "limits.support.frames[0].frame", "nope"),
    ("frames = ['link7']\nframe_type = 'body'\nmargin = -1", "limits.support.margin", "[0, 1]"),
    (
        "frames = ['link7']\nframe_type = 'body'\nfootprint = [[0.1]]",
        "limits.support.footprint[0]",
        "[x, y]",
    ),
    ("frames = ['link7']\nframe_type = 'body'\nfeet = 2", "limits.support.feet", "unknown field"),
    ("margin = 0.1", "limits.support.frames", "missing"),
    # one frame, one footprint point: a polygon of no area, found on load at the start
    ("frames = ['link7']\nframe_type = 'body'\nfootprint = [[0, 0]]", "limits.support", "no area"),
]


@pytest.mark.parametrize("table, field, fragment", SUPPORT_ERRORS)
def test_malformed_support_limit_names_the_field(tmp_path, table, field, fragment):
    text = TWO_FRAMES.format(mode="solve", extra="[limits.support]\n" + table + "\n")
    path = write(tmp_path, text)
    with pytest.raises(qpik.ProblemFileError) as info:
        qpik.load_problem(path)
    assert info.value.field == field, str(info.value)
    assert fragment in str(info.value)


def test_floating_base_must_be_a_boolean(tmp_path):
    path = write(tmp_path, "floating_base = 1\n" + TWO_FRAMES.format(mode="solve", extra=""))
    with pytest.raises(qpik.ProblemFileError) as info:
        qpik.load_problem(path)
    assert info.value.field == "floating_base"


# ------------------------------------------------------------------ task registry
def test_every_task_type_is_documented_in_the_readme():
    text = README.read_text()
    for name in TASK_KINDS:
        assert f"| `{name}` |" in text, name


def test_a_new_task_type_is_one_registry_entry(tmp_path, monkeypatch):
    def build(spec, model, start):
        task = PostureTask(model, **spec.options)
        task.set_target(start.q if spec.posture is None else spec.posture)
        return task

    kind = TaskKind(PostureTask, build, costs=(("cost", "nv", 0.5),), target=("q",))
    monkeypatch.setitem(TASK_KINDS, "hold_posture", kind)
    text = TWO_FRAMES.format(mode="solve", extra="").replace(
        'type = "posture"', 'type = "hold_posture"'
    )
    problem = qpik.load_problem(write(tmp_path, text))
    spec = problem.levels[1][0]
    assert spec.type == "hold_posture" and spec.kind is kind
    assert isinstance(problem.build_stack()[1][0], PostureTask)
    bad = text.replace("cost = 0.01", "gain = 0.5\nspeed = 1")
    with pytest.raises(qpik.ProblemFileError) as info:
        qpik.load_problem(write(tmp_path, bad))
    assert info.value.field == "levels[1].tasks[0].speed"


def test_registry_fields_match_the_task_constructors():
    """Every option a kind reads is a keyword of its class (or of its builder's class)."""
    import inspect

    for name, kind in TASK_KINDS.items():
        parameters = inspect.signature(kind.cls.__init__).parameters
        if any(p.kind is p.VAR_KEYWORD for p in parameters.values()):
            continue  # mink's FrameTask wrapper takes **kwargs
        for option in (*kind.options, *(c[0] for c in kind.costs), *kind.choices):
            assert option in parameters, (name, option)


# ------------------------------------------------------------------ errors along the path
@pytest.mark.parametrize(
    "mode, extra", [("solve", ""), ("track", "[track]\ndt = 0.05\nsteps = 40\n")]
)
def test_task_and_frame_errors_follow_the_path(tmp_path, mode, extra):
    result = qpik.load_problem(write(tmp_path, TWO_FRAMES.format(mode=mode, extra=extra))).solve()
    path = result.path
    assert len(result.goal_index) == len(path)
    np.testing.assert_array_equal(path[0], result.problem.q0)
    assert not any(np.array_equal(a, b) for a, b in zip(path[:-1], path[1:]) if mode == "solve")
    tasks = result.task_errors()
    assert [c.label for c in tasks] == [
        "L0 position ee",
        "L0 position link4",
        "L1 posture",
    ]
    assert all(len(c.values) == len(path) for c in tasks)
    assert tasks[0].unit == "m" and tasks[2].unit == "rad or m"  # (a posture: joint space)
    frames = result.frame_errors()
    assert [c.label for c in frames] == ["ee position", "link4 position"]
    for curve in frames:
        assert curve.values[0] > 1e-2 and curve.values[-1] <= 1e-4 * (1 + 1e-9)
    # the task error of a goal task is the frame's error
    np.testing.assert_allclose(tasks[0].values, frames[0].values, atol=1e-12)


# ------------------------------------------------------------------ the humanoid file
@pytest.mark.skipif(not _has_erd(), reason="needs qpik[robots] (example-robot-data)")
def test_humanoid_file_reaches_with_both_hands_and_keeps_its_feet():
    path = next(p for p in problem_files() if p.stem == "talos_both_hands")
    with warnings.catch_warnings():  # the URDF's meshes are dropped, with a warning
        warnings.simplefilter("ignore")
        problem = qpik.load_problem(path)
    assert problem.model.nv == 38 and len(problem.goals) == 2
    assert all(len(g.frames) == 2 for g in problem.goals)
    result = problem.solve()
    assert result.converged, result.reason
    start = problem.start_configuration()
    final = qpik.Configuration(problem.model, result.q)
    for foot in ("left_sole_link", "right_sole_link"):
        p0, r0 = start.frame_pose(foot, "body")
        p1, r1 = final.frame_pose(foot, "body")
        assert np.linalg.norm(p1 - p0) <= 1e-4
        assert np.linalg.norm(r1 - r0) <= 1e-3
    for frame in problem.goals[-1].frames:
        assert frame.error(final)[0] <= 1e-4
    support = problem.build_limits()[-1]
    assert isinstance(support, qpik.limits.SupportPolygonLimit)
    assert support.com_margin(final) >= 0.0  # the CoM over the soles
