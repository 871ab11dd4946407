"""Problem files say what the solver does (an audit of every task type, h16): the solver's
``alpha`` is the gain of the goal tasks in a solve, a left-out target holds the start at
every waypoint, a goal matches its task by frame type, every part of a goal is steered, and
options that would be silently ignored or impossible are refused on load."""

from __future__ import annotations

import numpy as np
import pytest

import qpik

REACH = """
robot = "panda"
q0 = "home"
[[levels]]
[[levels.tasks]]
type = "position"
frame = "ee"
{gain}
[target]
position = [0.45, 0.25, 0.40]
[solver]
alpha = {alpha}
restarts = 0
max_iters = 300
"""


def _load(tmp_path, text: str, name: str = "p.toml"):
    path = tmp_path / name
    path.write_text(text)
    return qpik.load_problem(path)


def test_alpha_is_the_gain_of_the_goal_tasks_in_a_solve(tmp_path):
    """[solver] alpha had no effect in solve mode (a given stack keeps its tasks' gains): now
    it is the level-0 goal tasks' gain unless a task gives its own."""
    iterations = {}
    for alpha in (1.0, 0.1):
        result = _load(tmp_path, REACH.format(gain="", alpha=alpha)).solve()
        assert result.converged
        iterations[alpha] = result.results[0].iterations
    assert iterations[0.1] > 5 * iterations[1.0]
    own = _load(tmp_path, REACH.format(gain="gain = 0.1", alpha=1.0)).solve()
    assert own.results[0].iterations == iterations[0.1]  # the task's own gain wins


WAYPOINTS = """
robot = "planar_4r"
q0 = [0.3, 0.6, -0.4, -0.6]
[[levels]]
[[levels.tasks]]
type = "position"
frame = "ee"
[[levels]]
[[levels.tasks]]
type = "posture"
cost = 0.01
[[waypoints]]
position = [1.5, 1.5, 0.0]
[[waypoints]]
position = [1.2, 2.0, 0.0]
"""


def test_a_left_out_target_holds_the_start_at_every_waypoint(tmp_path, monkeypatch):
    """The posture's "start" was the previous waypoint's answer in solve mode (q0 in track
    mode): every waypoint's stack now holds q0."""
    import qpik.problem.modes as modes

    stacks = []
    solve = modes.solve
    monkeypatch.setattr(modes, "solve", lambda *a, **k: stacks.append(k["stack"]) or solve(*a, **k))
    problem = _load(tmp_path, WAYPOINTS)
    problem.solve()
    assert len(stacks) == 2
    for stack in stacks:
        np.testing.assert_array_equal(stack[1][0].target_q, problem.q0)


@pytest.mark.parametrize(
    "goal, field, message",
    [
        ('frame = "hand"\nframe_type = "geom"\nposition = [0.4, 0, 0.4]', "target.frame", "geom"),
        ("position = [0.4, 0, 0.4]\nrpy = [0, 0, 0]", "target.rpy", "no task steers"),
    ],
)
def test_a_goal_is_matched_by_frame_type_and_every_part_is_steered(tmp_path, goal, field, message):
    """A geom goal was given to the body task of the same name (its error measured on the
    geom: stalled 5 cm off); a rotation on a frame only a position task regulates was
    measured, never steered (stalled, all restarts spent)."""
    text = (
        'robot = "panda"\nq0 = "home"\n[[levels]]\n[[levels.tasks]]\ntype = "position"\n'
        'frame = "hand"\nframe_type = "body"\n[target]\n' + goal + "\n"
    )
    if "frame_type" not in goal:
        text = text.replace('frame = "hand"\nframe_type = "body"', 'frame = "ee"')
    with pytest.raises(qpik.ProblemFileError, match=message) as info:
        _load(tmp_path, text)
    assert info.value.field == field


def test_an_orientation_only_frame_cannot_take_a_position_goal(tmp_path):
    text = (
        'robot = "panda"\nq0 = "home"\n[[levels]]\n[[levels.tasks]]\ntype = "orientation"\n'
        'frame = "ee"\n[target]\nposition = [0.4, 0, 0.4]\nrpy = [3.14, 0, 0]\n'
    )
    with pytest.raises(qpik.ProblemFileError, match="no task steers") as info:
        _load(tmp_path, text)
    assert info.value.field == "target.position"


def test_collision_pairs_with_self_or_scene_are_refused(tmp_path):
    text = REACH.format(gain="", alpha=1.0) + (
        '[limits.collision]\nself = true\npairs = [[["link7_collision"], ["link1_collision"]]]\n'
    )
    with pytest.raises(qpik.ProblemFileError, match="absent where pairs are given") as info:
        _load(tmp_path, text)
    assert info.value.field == "limits.collision.self"


@pytest.mark.filterwarnings("ignore")
def test_a_support_margin_wider_than_the_polygon_and_a_bad_frame_type_are_named(tmp_path):
    from conftest import load_or_skip

    load_or_skip("erd:talos")
    base = (
        'robot = "erd:talos"\nfloating_base = true\nq0 = "half_sitting"\nmode = "track"\n'
        '[[levels]]\n[[levels.tasks]]\ntype = "position"\nframe = "gripper_left_base_link"\n'
        'frame_type = "body"\n[target]\nframe = "gripper_left_base_link"\nframe_type = "body"\n'
        "position = [0.5, 0.3, 0.8]\n"
        '[limits.support]\nframes = ["left_sole_link", "right_sole_link"]\nframe_type = {ft}\n'
        "margin = {margin}\nfootprint = [[0.1, 0.05], [0.1, -0.05], [-0.1, 0.05], [-0.1, -0.05]]\n"
        "[track]\ndt = 0.01\nsteps = 2\n"
    )
    with pytest.raises(qpik.ProblemFileError, match="wider than the largest circle") as info:
        _load(tmp_path, base.format(ft='"body"', margin=0.5))
    assert info.value.field == "limits.support.margin"
    with pytest.raises(qpik.ProblemFileError) as info:
        _load(tmp_path, base.format(ft=3, margin=0.01))
    assert info.value.field == "limits.support.frame_type"
