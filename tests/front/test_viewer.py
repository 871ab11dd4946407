"""The viewer without a browser: geometry of the geoms, the live solve behind a drag, the
level panels, ``qpik view`` and the missing extra. (In a browser: test_viewer_browser.py.)"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

import qpik
from qpik.cli import main
from qpik.problem import load_problem
from qpik.viewer import LiveSolve, default_stack, geom_meshes, level_html
from qpik.viewer.geometry import primitive_mesh
from qpik.viewer.live import LevelReport

TASKS = Path(__file__).resolve().parents[2] / "tasks"
ROOT = Path(__file__).resolve().parents[2]


def _volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


@pytest.mark.parametrize(
    "kind, size, volume",
    [
        (mujoco.mjtGeom.mjGEOM_BOX, [0.1, 0.2, 0.3], 8 * 0.1 * 0.2 * 0.3),
        (mujoco.mjtGeom.mjGEOM_SPHERE, [0.1, 0, 0], 4 / 3 * np.pi * 0.1**3),
        (mujoco.mjtGeom.mjGEOM_CAPSULE, [0.05, 0.2, 0], np.pi * 0.05**2 * (0.4 + 4 / 3 * 0.05)),
        (mujoco.mjtGeom.mjGEOM_CYLINDER, [0.05, 0.2, 0], np.pi * 0.05**2 * 0.4),
        (mujoco.mjtGeom.mjGEOM_ELLIPSOID, [0.1, 0.2, 0.3], 4 / 3 * np.pi * 0.1 * 0.2 * 0.3),
    ],
)
def test_primitive_meshes_are_closed_and_face_outward(kind, size, volume):
    vertices, faces = primitive_mesh(int(kind), np.array(size, dtype=float), segments=48)
    # outward faces: the signed volume is positive and close to the solid's
    assert _volume(vertices, faces) == pytest.approx(volume, rel=0.03)
    # closed: with coincident vertices merged (the poles), every edge of a face of nonzero
    # area is shared by exactly two faces
    _, weld = np.unique(np.round(vertices, 9), axis=0, return_inverse=True)
    faces = weld.reshape(-1)[faces]
    faces = faces[
        (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    ]
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert set(counts.tolist()) == {2}


def test_panda_geoms_are_primitives_in_their_bodies():
    model = qpik.load_robot("panda")
    meshes = geom_meshes(model)
    assert meshes and all(m.body > 0 for m in meshes)
    assert {m.geom for m in meshes} <= set(range(model.ngeom))
    for mesh in meshes:
        assert mesh.vertices.shape[1] == 3 and mesh.faces.max() < len(mesh.vertices)
        assert np.allclose(mesh.position, model.geom_pos[mesh.geom])


def test_mesh_geoms_come_from_the_model():
    xml = """<mujoco><asset><mesh name="tet" vertex="0 0 0  1 0 0  0 1 0  0 0 1"/></asset>
    <worldbody><body name="b"><freejoint/><geom type="mesh" mesh="tet" contype="0"
    conaffinity="0"/><geom type="box" size=".1 .1 .1"/></body>
    <geom name="obstacle" type="sphere" size="0.1" pos="1 0 0" contype="0" conaffinity="0"/>
    <geom name="floor" type="plane" size="1 1 .1"/></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    visual = geom_meshes(model, "visual")
    kinds = {int(model.geom_type[m.geom]) for m in visual}
    assert int(mujoco.mjtGeom.mjGEOM_MESH) in kinds  # the mesh, from mesh_vert/mesh_face
    assert len(visual[0].faces) == 4 or any(len(m.faces) == 4 for m in visual)
    assert "obstacle" in {m.name for m in visual}  # a world geom: drawn where it stands
    assert "floor" not in {m.name for m in visual}  # planes: the grid instead
    collision = geom_meshes(model, "collision")
    assert [int(model.geom_type[m.geom]) for m in collision] == [int(mujoco.mjtGeom.mjGEOM_BOX)]


def _panda_live(**kwargs) -> LiveSolve:
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key("home").qpos)
    return LiveSolve(model, default_stack(configuration), q0=configuration.q, **kwargs)


def test_live_solve_follows_a_moved_target():
    live = _panda_live()
    assert list(live.goals) == ["ee"]
    position, rotation = live.configuration.frame_pose("ee")
    goal = position + [0.05, -0.1, 0.08]
    live.set_target("ee", goal, rotation)
    report = live.solve()
    assert report.converged and report.steps >= 1
    assert np.linalg.norm(live.configuration.frame_pose("ee")[0] - goal) < 1e-4
    assert [level.status for level in report.levels] == ["solved", "solved"]
    assert report.levels[0].state == "met" and report.levels[0].goal_error is not None
    assert report.levels[1].goal_error is None
    assert report.solve_time > 0


def test_live_solve_marks_an_unreachable_goal_red():
    live = _panda_live()
    rotation = live.configuration.frame_pose("ee")[1]
    live.set_target("ee", [2.0, 0.0, 0.5], rotation)
    report = live.solve()
    assert not report.converged
    assert report.levels[0].state == "unmet" and not report.levels[0].ok
    within = live.configuration.check_limits  # limits hold all along
    within()
    html = level_html(report.levels[0])
    assert "cannot be met" in html and "#c62828" in html and "qpik-unmet" in html


def test_a_robot_moved_by_hand_is_pending_not_unmet():
    """h17's audit: moving a joint slider (set_q, then a report of no step) marked level 0
    red, "cannot be met", with status solved and residual 0: it is "pending", status "not
    solved yet", until the next solve (which meets it)."""
    live = _panda_live()
    live.solve()
    q = live.q
    q[0] += 0.03
    live.set_q(q)
    report = live.solve(max_iterations=0)
    level = report.levels[0]
    assert level.state == "pending" and level.ok and level.status == "not solved yet"
    html = level_html(level)
    assert "not solved since the robot moved" in html and "qpik-pending" in html
    assert live.solve().levels[0].state == "met"


def test_a_level_without_a_goal_is_pending_after_the_robot_moved():
    """An audit of the viewer: after a joint slider (set_q) the posture level, which holds
    no goal frame, showed green "met" with a residual of 0 made up: it is pending, its
    residual and damping shown as a dash (NaN), until the next solve."""
    live = _panda_live()
    live.solve()
    q = live.q
    q[0] += 0.5
    live.set_q(q)
    report = live.solve(max_iterations=0)
    posture = report.levels[-1]
    assert posture.goal_error is None and posture.state == "pending"
    assert np.isnan(posture.residual) and np.isnan(posture.damping)
    html = level_html(posture)
    assert "residual: &ndash;" in html and "nan" not in html
    assert live.solve().levels[-1].state in ("met", "compromise")


def test_the_summary_shows_the_worst_angle_and_a_closed_viewer_refuses_calls():
    """The summary's goal error: the worst position and the worst angle over the goals (it
    showed the angle of the frame with the worst position); a closed viewer's set_target
    and set_q, and serve(seconds="x"), are typed errors."""
    pytest.importorskip("viser")
    from qpik.viewer import Viewer

    with Viewer("panda", port=0) as viewer:
        position, rotation = viewer.frame_pose("ee")
        tilted = rotation @ np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # 90 deg
        report = viewer.set_target("ee", position, tilted, max_iterations=0)
        text = viewer._solve_md.content
        worst = max(e[1] for e in report.goal_errors.values())
        assert f"{np.degrees(worst):.3f}&deg;" in text
    with pytest.raises(qpik.InvalidInput, match="closed"):
        viewer.set_target("ee", position)
    with pytest.raises(qpik.InvalidInput, match="closed"):
        viewer.set_q(viewer.live.configuration.q)
    with pytest.raises(qpik.QpikError, match="seconds"):
        Viewer("panda", port=0).serve("x")


def test_a_position_only_goal_shows_no_orientation_error():
    """h17's audit: a position-only goal showed ", 0.000 deg" in its level's goal error."""
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key("home").qpos)
    stack = [[qpik.tasks.PositionTask("ee")], [qpik.tasks.PostureTask(model, cost=0.01)]]
    stack[1][0].set_target(configuration.q)
    live = LiveSolve(model, stack, q0=configuration.q)
    live.set_target("ee", configuration.frame_pose("ee")[0] + [0.05, 0.0, 0.0])
    level = live.solve().levels[0]
    assert np.isnan(level.goal_error[1]) and level.state == "met"
    html = level_html(level)
    assert "goal error:" in html and "&deg;" not in html


def test_live_solve_of_a_problem_uses_its_stack_limits_and_goal():
    from qpik.viewer.app import live_of_problem

    problem = load_problem(TASKS / "panda_pose_reach.toml")
    live = live_of_problem(problem, None, None, None, 20)
    assert list(live.goals) == ["ee"]
    assert np.allclose(live.goals["ee"].target.position, problem.goals[0].target.position)
    assert live.level_names == [["position ee", "orientation ee"], ["posture"]]
    assert len(live.limits) == len(problem.build_limits())
    report = live.solve(max_iterations=200)
    assert report.converged
    result = problem.solve()  # the file's own solve reaches the same pose
    assert result.converged


def test_trust_region_and_level0_correction_hold_the_feet():
    """Floating Talos: a hand dragged far out of reach moves neither foot (level 0)."""
    from qpik.limits import ConfigurationLimit
    from qpik.tasks import FrameTask, PositionTask, PostureTask

    model = qpik.load_robot("erd:talos", floating_base=True)
    start = model.key("half_sitting").qpos
    configuration = qpik.Configuration(model, start)
    feet = [FrameTask(f, "body", 1.0, 1.0) for f in ("left_sole_link", "right_sole_link")]
    for task in feet:
        task.set_target_from_configuration(configuration)
    hand = PositionTask("gripper_left_base_link", "body")
    hand.set_target_from_configuration(configuration)
    posture = PostureTask(model, cost=1e-2)
    posture.set_target(start)
    live = LiveSolve(
        model,
        [feet, [hand], [posture]],
        [ConfigurationLimit(model)],
        goals=["gripper_left_base_link"],
        q0=start,
    )
    far = live.goals["gripper_left_base_link"].target.position + [0.0, 1.5, 0.0]
    live.set_target("gripper_left_base_link", far)
    report = live.solve(max_iterations=30)
    assert report.levels[0].state == "met" and report.levels[1].state == "unmet"
    assert live.level0_error() <= 1e-4


def test_level_html_states():
    base = dict(index=1, tasks=["posture"], status="solved", residual=0.1, damping=0.0)
    for state, colour in (("met", "#2e7d32"), ("compromise", "#b26a00"), ("unmet", "#c62828")):
        html = level_html(LevelReport(**base, active_limits=["j upper"], state=state))
        assert colour in html and "Level 1" in html and "status: <b>solved</b>" in html


def test_qpik_imports_without_viser_and_the_viewer_names_its_extra():
    code = (
        "import sys; sys.modules['viser'] = None\n"
        "import qpik, qpik.viewer\n"
        "from qpik.errors import MissingExtra\n"
        "try:\n"
        "    qpik.viewer.Viewer('panda')\n"
        "except MissingExtra as exc:\n"
        "    print('extra:', exc.extra)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT
    )
    assert out.returncode == 0, out.stderr
    assert "extra: viewer" in out.stdout


def test_view_command_checks_its_arguments(capsys, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", str(TASKS / "panda_pose_reach.toml"), "--mujoco", "--seconds", "1"]) == 2
    assert "needs a display" in capsys.readouterr().err
    assert main(["view", "panda", "--port", "70000"]) == 2
    assert main(["view", "panda", "--seconds", "-1"]) == 2
    assert main(["view", str(TASKS / "panda_pose_reach.toml"), "--floating-base"]) == 2


def test_view_serves_for_n_seconds_then_exits(capsys):
    pytest.importorskip("viser")
    code = main(
        [
            "view",
            str(TASKS / "panda_pose_reach.toml"),
            "--headless",
            "--seconds",
            "0.5",
            "--port",
            "0",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "serving http://127.0.0.1:" in out and "goal frames: ee" in out


def test_viewer_python_api_and_handle_drag():
    pytest.importorskip("viser")
    from qpik.viewer import Viewer
    from qpik.viewer.app import _wxyz

    with Viewer("panda", port=0) as viewer:
        assert viewer.url.startswith("http://127.0.0.1:") and viewer.goals == ["ee"]
        position, rotation = viewer.frame_pose("ee")
        report = viewer.set_target("ee", position + [0.0, 0.1, 0.0], rotation)
        assert report.converged
        assert np.linalg.norm(viewer.frame_pose("ee")[0] - position - [0.0, 0.1, 0.0]) < 1e-4
        # what a drag of the handle in the page sends: solved by the solver thread
        handle = SimpleNamespace(position=position + [0.0, 0.0, 0.05], wxyz=_wxyz(rotation))
        viewer._on_handle("ee")(SimpleNamespace(target=handle, phase="update"))
        for _ in range(300):
            if viewer.drag_times:
                break
            import time

            time.sleep(0.02)
        assert viewer.drag_times
        with pytest.raises(qpik.QpikError):
            viewer.set_target("nope", position)
        viewer.set_q(viewer.live.configuration.q)


def test_the_ground_grid_is_under_a_robot_that_hangs_below_the_origin():
    """h17's audit: `qpik view erd:talos` (fixed base at the pelvis) drew the robot sunk
    through the grid at z = 0: the grid goes under its lowest geom; a model with a floor
    plane, or an arm on the ground, keeps it at 0."""
    import warnings

    from qpik.viewer.geometry import ground_height

    arm = qpik.load_robot("panda")
    assert ground_height(arm, qpik.Configuration(arm, arm.key("home").qpos).data) == 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            talos = qpik.load_robot("erd:talos")
        except qpik.QpikError:
            pytest.skip("erd:talos does not load here")
    data = qpik.Configuration(talos, talos.key("half_sitting").qpos).data
    ground = ground_height(talos, data)
    assert -1.3 < ground < -1.0  # (the soles about 1.02 m below the pelvis)
