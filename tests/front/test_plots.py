"""Figures of problem results (qpik.plots): what each panel draws, legends off the data,
the 3D robot picture from body positions (issue 15)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import qpik

pytest.importorskip("matplotlib")

from matplotlib.figure import Figure  # noqa: E402

from qpik import plots  # noqa: E402

PLANAR = """
robot = "planar_2r"
q0 = [0.3, 0.6]
[[levels]]
[[levels.tasks]]
type = "position"
frame = "ee"
[[waypoints]]
position = [1.0, 1.0, 0.0]
[[waypoints]]
position = [0.5, 1.5, 0.0]
"""

PANDA_TRACK = """
robot = "panda"
q0 = "home"
mode = "track"
[[levels]]
[[levels.tasks]]
type = "frame"
frame = "ee"
[[levels]]
[[levels.tasks]]
type = "posture"
cost = 0.01
[target]
position = [0.31, 0.096, 0.345]
rpy = [3.14159265, 0.0, 0.0]
[track]
dt = 0.05
steps = 30
"""


@pytest.fixture(scope="module")
def planar(tmp_path_factory):
    path = tmp_path_factory.mktemp("planar") / "planar.toml"
    path.write_text(PLANAR)
    return qpik.load_problem(path).solve()


@pytest.fixture(scope="module")
def panda(tmp_path_factory):
    path = tmp_path_factory.mktemp("panda") / "panda.toml"
    path.write_text(PANDA_TRACK)
    return qpik.load_problem(path).solve()


def _legends_below_their_axes(fig: Figure) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is None:
            continue
        box, area = legend.get_window_extent(renderer), ax.get_window_extent(renderer)
        assert box.y1 <= area.y0 + 1, ax.get_title()  # below the data area


@pytest.mark.parametrize("name", ["planar", "panda"])
def test_plot_result_panels_and_legends_off_the_data(request, tmp_path, name):
    result = request.getfixturevalue(name)
    out = tmp_path / f"{name}.png"
    fig = plots.plot_result(result, out)
    assert out.read_bytes()[:4] == b"\x89PNG"
    titles = [ax.get_title() for ax in fig.axes]
    assert titles[:2] == ["task error per priority level", "error per goal frame"]
    assert any(t.startswith("joints along the path") for t in titles)
    assert any(t.startswith("singular values") for t in titles)
    robot = [ax for ax in fig.axes if "start, intermediate, final" in ax.get_title()]
    assert len(robot) == 1
    assert (robot[0].name == "3d") is (name == "panda")  # planar arms: seen from above
    _legends_below_their_axes(fig)


def test_task_error_panel_draws_task_errors_not_qp_residuals(planar):
    ax = Figure().add_subplot()
    plots.plot_task_errors(planar, ax)
    curves = planar.task_errors()
    lines = [line for line in ax.get_lines() if line.get_label().startswith("L0")]
    assert len(lines) == len(curves) == 1
    y = lines[0].get_ydata()
    assert len(y) == len(planar.path)  # along the path, every iterate
    assert y[0] > 0.1 and y[-1] < 1e-4  # the task error, from the start to the goal
    # a goal start is marked where the second waypoint begins
    assert any("goal 1" in text.get_text() for text in ax.texts)


def test_joints_and_sigma_are_drawn_along_the_path(panda):
    fig = Figure()
    ax_q, ax_s = fig.subplots(1, 2)
    time = np.arange(len(panda.path)) * panda.trace.dt
    plots.plot_joints(panda.problem.model, panda.path, ax_q, time)
    plots.plot_singular_values(panda.problem.model, panda.path, "ee", ax=ax_s, time=time)
    assert len(panda.path) == 31
    for ax in (ax_q, ax_s):
        data = [line for line in ax.get_lines() if len(line.get_xdata()) > 2]
        assert data and all(len(line.get_xdata()) == len(panda.path) for line in data)


def test_many_joints_name_only_those_that_move_most():
    model = qpik.load_robot("panda")
    path = np.tile(model.key("home").qpos, (5, 1))
    path[:, 3] += np.linspace(0, 0.5, 5)  # joint4 moves most
    ax = Figure().add_subplot()
    from qpik.plots import curves

    old = curves.MAX_NAMED
    try:
        curves.MAX_NAMED = 3
        plots.plot_joints(model, path, ax)
    finally:
        curves.MAX_NAMED = old
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "joint4" in labels and len(labels) == 4 and labels[-1] == f"{model.njnt - 3} others"


def test_robot_segments_follow_body_positions():
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key("home").qpos)
    segments = plots.robot_segments(model, configuration, [("ee", "site")])
    assert segments.shape == (model.nbody - 1 + 1, 2, 3)
    np.testing.assert_allclose(segments[0, 1], configuration.data.xpos[1])
    np.testing.assert_allclose(segments[-1, 1], configuration.frame_pose("ee")[0])


def test_robot_picture_of_a_floating_base_leaves_the_world_out():
    xml = """<mujoco><worldbody>
      <body name="base" pos="0 0 1"><freejoint/><geom size="0.1"/>
        <body name="arm" pos="0.5 0 0"><joint axis="0 0 1"/><geom size="0.1"/></body>
      </body></worldbody></mujoco>"""
    import mujoco

    model = mujoco.MjModel.from_xml_string(xml)
    configuration = qpik.Configuration(model)
    segments = plots.robot_segments(model, configuration)
    assert segments.shape == (1, 2, 3)  # base -> arm only, no world -> base
    fig = Figure()
    ax = fig.add_subplot(projection="3d")
    plots.plot_robot(model, np.tile(configuration.q, (3, 1)), targets=[np.ones(3)], ax=ax)
    assert [t.get_text() for t in ax.get_legend().get_texts()][:2] == ["start", "intermediate"]


def test_the_levels_own_targets_and_the_scenes_obstacles_are_drawn(tmp_path):
    """A lower level's frame target (no goal names its frame) is marked on the robot panel
    with its label, and a problem file's obstacle is drawn there: what the figure is about
    in tasks/planar_4r_priorities.toml and tasks/panda_obstacle_avoidance.toml."""
    tasks = Path(__file__).resolve().parents[2] / "tasks"
    priorities = qpik.load_problem(tasks / "planar_4r_priorities.toml")
    (label, position), *rest = plots.level_targets(priorities)
    assert not rest and label == "L1 link3 target"
    np.testing.assert_array_equal(position, [0.0, 2.0, 0.0])
    priorities.steps = 5
    fig = plots.plot_result(priorities.solve())
    arm = next(ax for ax in fig.axes if "top view" in ax.get_title())
    marks = [line for line in arm.get_lines() if line.get_label() == "L1 link3 target"]
    assert len(marks) == 1 and list(marks[0].get_xydata()[0]) == [0.0, 2.0]

    obstacle = qpik.load_problem(tasks / "panda_obstacle_avoidance.toml")
    obstacle.steps = 5
    fig = plots.plot_result(obstacle.solve())
    robot = next(ax for ax in fig.axes if ax.name == "3d")
    drawn = [c for c in robot.collections if c.get_label() == "obstacle"]
    assert len(drawn) == 1
    ((kind, size, centre, rotation),) = plots.robot.world_geoms(obstacle.model)
    corners = np.array(plots.robot.geom_surface(kind, size, centre, rotation)).reshape(3, -1)
    np.testing.assert_allclose(np.linalg.norm(corners.T - centre, axis=1), size[0], atol=1e-12)
    # the posture's error is joint space: its legend names the unit
    ax = Figure().add_subplot()
    plots.plot_task_errors(obstacle.solve(), ax)
    assert any(line.get_label() == "L1 posture [rad or m]" for line in ax.get_lines())
    assert ax.get_ylabel() == "error: [m] solid, [rad or m] dotted"


def test_task_targets_of_a_wrong_form_are_refused():
    model = qpik.load_robot("planar_2r")
    path = np.zeros((2, model.nq))
    for bad in (
        "L1 target",
        lambda: 1,
        {"L1": [0, 0, 0]},
        [("L1", [0.0, 1.0])],
        [(1, [0.0, 1.0, 0.0])],
        [("L1", [np.nan] * 3)],
    ):
        with pytest.raises(qpik.QpikError, match="task_targets"):
            plots.plot_planar_arm(model, path, task_targets=bad)


def test_a_figure_path_of_no_figure_format_is_refused(planar, tmp_path):
    with pytest.raises(qpik.errors.InvalidInput, match=r"path .*\.png"):
        plots.plot_result(planar, tmp_path / "figure.txt")
    with pytest.raises(qpik.errors.InvalidArgumentType, match="path"):
        plots.plot_result(planar, 3)
    assert plots.check_figure_path("path", tmp_path / "a.PDF").endswith("a.PDF")


UNREACHABLE = """
robot = "planar_2r"
q0 = [0.3, 0.3]
[[levels]]
[[levels.tasks]]
type = "position"
frame = "ee"
[target]
position = [3.0, 0.0, 0.0]
"""


def test_a_path_of_one_configuration_is_drawn_with_markers(tmp_path):
    """An unreachable target is refused at the start: a path of one configuration, whose
    error panels showed nothing (a line of one point is invisible) and whose arm was
    labelled "start" in the light shade."""
    path = tmp_path / "unreachable.toml"
    path.write_text(UNREACHABLE)
    result = qpik.load_problem(path).solve()
    assert len(result.path) == 1 and not result.converged
    fig = plots.plot_result(result, tmp_path / "unreachable.png")
    for ax in fig.axes[:2]:  # the task and frame error panels
        curves = [line for line in ax.get_lines() if len(line.get_xdata()) == 1]
        assert curves, ax.get_title()
        for line in curves:
            assert line.get_marker() not in ("None", None, "") and line.get_markevery() == [0]
        assert ax.get_xlim() == (-1.0, 1.0)  # whole-number ticks around the one iterate
    arm = next(ax for ax in fig.axes if "top view" in ax.get_title())
    labels = [line.get_label() for line in arm.get_lines()]
    assert "start = final" in labels
    tip = next(line for line in arm.get_lines() if line.get_label() == "tip path")
    assert tip.get_markevery() == [0]
    # a curve whose points all lie on lines has no markers, as before
    assert plots.base.lone_points(np.array([1.0, 2.0, np.nan, 3.0, 4.0])) == {}
    assert plots.base.lone_points(np.array([1.0, np.nan, 3.0, np.nan]))["markevery"] == [0, 2]


@pytest.mark.parametrize("slices", [0, 1, 4])
def test_a_map_figure_keeps_its_title_and_labels_inside(tmp_path, slices):
    """``slices=0`` made a 5-inch figure whose one-line title was clipped at both edges."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    rmap = qpik.reachability(
        "ur5e",
        "ee",
        region=[[-0.5, -0.5, 0.0], [0.5, 0.5, 0.6]],
        resolution=0.25,
        orientations=0,
        workers=1,
        progress=False,
    )
    fig = rmap.plot(tmp_path / "map.png", slices=slices)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    inside = fig.bbox
    title = next(text for text in fig.texts if text.get_text().startswith("reachability"))
    texts = [title] + [ax.yaxis.label for ax in fig.axes[:1]]
    for text in texts:
        box = text.get_window_extent(renderer)
        assert box.x0 >= inside.x0 and box.x1 <= inside.x1, text.get_text()
        assert box.y1 <= inside.y1, text.get_text()
    if slices == 1:  # the one slice is the middle layer (was the lowest: linspace's [low])
        (panel,) = [ax for ax in fig.axes if ax.get_title().startswith("z = ")]
        heights = np.unique(rmap.centers[:, 2])
        middle = heights[(len(heights) - 1) // 2 : len(heights) // 2 + 1]
        assert float(panel.get_title().split()[2]) == pytest.approx(middle.mean(), abs=0.13)


def test_the_viewer_names_the_model_it_shows():
    """h17's audit: the title read "qpik: model" for every robot (mj_id2name of the model
    object gives None): the model's own name (<mujoco model=...>)."""
    from qpik.viewer.app import _model_name

    assert _model_name(qpik.load_robot("panda")) == "panda"
    assert _model_name(qpik.load_robot("ur5e")) == "ur5e"


def test_a_curve_under_another_says_so_in_the_legend():
    """An audit of the figures: a curve drawn exactly under a later one (a humanoid's left
    and right feet) left a legend entry whose line is nowhere; its entry now says which
    curve covers it, and a curve apart from the others keeps its plain label."""
    from qpik.plots.base import legend_below

    ax = Figure().add_subplot()
    x = np.arange(10.0)
    ax.semilogy(x, 10.0**-x, label="left foot")
    ax.semilogy(x, 10.0**-x * (1 + 1e-4), label="right foot")
    ax.semilogy(x, 10.0 ** (-x / 2), label="hand")
    legend_below(ax)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["left foot (under right foot)", "right foot", "hand"]


def test_level_errors_take_rows_of_different_lengths_and_paths_need_their_folder(tmp_path):
    from qpik.plots import plot_level_errors
    from qpik.plots.base import check_figure_path

    ax = plot_level_errors([[1.0, 2.0], [3.0]], ax=Figure().add_subplot())
    assert len(ax.lines) == 2
    with pytest.raises(qpik.InvalidInput, match="folder"):
        check_figure_path("path", tmp_path / "missing" / "x.png")
    assert check_figure_path("path", tmp_path / "x.png").endswith("x.png")
