"""The viewer's checks of bad input: typed errors naming the argument, never a hang, an
untyped exception or a value silently ignored (headless: no browser, port 0)."""

from __future__ import annotations

import socket
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import qpik
from qpik.cli import main
from qpik.errors import (
    InvalidArgumentType,
    InvalidConfiguration,
    InvalidInput,
    InvalidOption,
    InvalidTarget,
)
from qpik.viewer import LiveSolve, default_stack, geom_meshes

TASKS = Path(__file__).resolve().parents[2] / "tasks"
#: An address no machine has as its own (TEST-NET-1, RFC 5737): binding it fails at once.
FOREIGN_HOST = "192.0.2.1"


@pytest.fixture
def no_thread_left():
    """Fails a test that leaves a thread running (a viser server, the solver thread)."""
    before = set(threading.enumerate())
    yield
    deadline = time.monotonic() + 2.0
    while True:
        left = [t for t in threading.enumerate() if t not in before and t.is_alive()]
        if not left or time.monotonic() > deadline:
            break
        time.sleep(0.02)
    assert not left, [t.name for t in left]


@pytest.fixture(scope="module")
def panda():
    model = qpik.load_robot("panda")
    return model, qpik.Configuration(model, model.key("home").qpos)


def _live(panda, **kwargs) -> LiveSolve:
    model, configuration = panda
    return LiveSolve(model, default_stack(configuration), q0=configuration.q, **kwargs)


def _viewer(**kwargs):
    pytest.importorskip("viser")
    from qpik.viewer import Viewer

    kwargs.setdefault("port", 0)
    kwargs.setdefault("solve_start", False)
    return Viewer("panda", **kwargs)


# ------------------------------------------------------------ 1: host and port, no hang
@pytest.mark.parametrize(
    ("serving", "error", "field"),
    [
        ({"port": -1}, InvalidOption, "port"),
        ({"port": 70000}, InvalidOption, "port"),
        ({"port": 1.5}, InvalidArgumentType, "port"),
        ({"port": True}, InvalidArgumentType, "port"),
        ({"host": 3}, InvalidArgumentType, "host"),
        ({"host": None}, InvalidArgumentType, "host"),
        ({"host": FOREIGN_HOST}, InvalidOption, "host"),
        ({"host": "999.1.1.1"}, InvalidOption, "host"),
        ({"collision": "yes"}, InvalidArgumentType, "collision"),
        ({"solve_start": 1}, InvalidArgumentType, "solve_start"),
        ({"label": 5}, InvalidArgumentType, "label"),
    ],
)
def test_viewer_refuses_a_bad_host_or_port_without_hanging(serving, error, field, no_thread_left):
    start = time.monotonic()
    with pytest.raises(error, match=field) as caught:
        _viewer(**serving)
    assert time.monotonic() - start < 5.0
    assert getattr(caught.value, "field", None) == field or field in str(caught.value)


def test_listen_port_takes_the_next_port_when_busy():
    from qpik.viewer.server import listen_port

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert port < listen_port("127.0.0.1", port) <= port + 1000
    assert listen_port("127.0.0.1", 0) == 0
    assert listen_port("", 0) == 0


def test_server_start_that_never_reports_times_out(monkeypatch, no_thread_left):
    from qpik.viewer import server

    release = threading.Event()
    stopped = threading.Event()

    class Hanging:  # a ViserServer whose thread never reports that it listens
        def __init__(self, **_):
            release.wait(5.0)

        def stop(self):
            stopped.set()

    monkeypatch.setattr(server, "SERVER_START_TIMEOUT", 0.2)
    start = time.monotonic()
    with pytest.raises(InvalidInput, match="did not start"):
        server.start_server(SimpleNamespace(ViserServer=Hanging), "127.0.0.1", 0, "x")
    assert time.monotonic() - start < 2.0
    release.set()  # it starts after all: stopped, not leaked
    assert stopped.wait(2.0)

    class Failing:
        def __init__(self, **_):
            raise OSError("boom")

    with pytest.raises(OSError, match="boom"):
        server.start_server(SimpleNamespace(ViserServer=Failing), "127.0.0.1", 0, "x")


def test_view_command_refuses_an_unusable_host(capsys):
    pytest.importorskip("viser")
    args = ["view", "panda", "--headless", "--seconds", "1", "--port", "0", "--host"]
    start = time.monotonic()
    assert main([*args, FOREIGN_HOST]) == 2
    assert time.monotonic() - start < 10.0
    assert "cannot listen on" in capsys.readouterr().err


# ------------------------------------------------------------ 2: solve settings' ranges
@pytest.mark.parametrize(
    ("settings", "field"),
    [
        ({"max_step": (0.0, 0.0)}, "max_step[0]"),
        ({"max_step": (np.nan, 1.0)}, "max_step[0]"),
        ({"max_step": (0.1, -1.0)}, "max_step[1]"),
        ({"max_step": 0.1}, "max_step"),
        ({"max_step": (0.1, 0.2, 0.3)}, "max_step"),
        ({"max_iterations": -5}, "max_iterations"),
        ({"max_iterations": 2.5}, "max_iterations"),
        ({"max_iterations": 10**6}, "max_iterations"),
        ({"tol_position": np.nan}, "tol_position"),
        ({"tol_position": 0.0}, "tol_position"),
        ({"tol_orientation": -1e-3}, "tol_orientation"),
        ({"settle": -1.0}, "settle"),
        ({"settle": "small"}, "settle"),
        ({"dt": 0.0}, "dt"),
    ],
)
def test_live_solve_range_checks_its_settings(panda, settings, field):
    with pytest.raises(InvalidInput) as caught:
        _live(panda, **settings)
    assert field in str(caught.value)
    if isinstance(caught.value, InvalidOption):
        assert caught.value.field.startswith(field.split("[")[0])


def test_live_solve_settings_in_range_are_kept(panda):
    live = _live(panda, max_step=np.array([0.1, 0.3]), max_iterations=0, settle=1e-5)
    assert live.max_step == (0.1, 0.3) and live.max_iterations == 0 and live.settle == 1e-5
    assert _live(panda, max_step=None).max_step is None
    with pytest.raises(InvalidOption, match="max_iterations"):
        live.solve(max_iterations=-1)


def test_viewer_range_checks_max_iterations(no_thread_left):
    with pytest.raises(InvalidOption, match="max_iterations"):
        _viewer(max_iterations=-1)
    with _viewer() as viewer, pytest.raises(InvalidOption, match="max_iterations"):
        viewer.set_target("ee", viewer.target("ee").position, max_iterations=-1)


# ------------------------------------------------------------ 3: typed errors, set_q
@pytest.mark.parametrize(
    ("position", "rotation"),
    [
        ([0.4, 0.2], None),
        ("abc", None),
        ([0.4, np.nan, 0.5], None),
        ([0.4, 0.2, 0.5], [1.0, 0.0]),
        ([0.4, 0.2, 0.5], [0.0, 0.0, 0.0, 0.0]),
        ([0.4, 0.2, 0.5], np.zeros((3, 3))),
        ([0.4, 0.2, 0.5], "x"),
    ],
)
def test_live_set_target_refuses_a_malformed_pose(panda, position, rotation):
    live = _live(panda)
    before = live.goals["ee"].target
    with pytest.raises(InvalidTarget):
        live.set_target("ee", position, rotation)
    assert live.goals["ee"].target is before


def test_live_set_target_takes_a_quaternion_or_a_matrix(panda):
    live = _live(panda)
    target = live.set_target("ee", [0.4, 0.2, 0.5], [2.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(target.rotation, np.eye(3))
    target = live.set_target("ee", [0.4, 0.2, 0.5], np.eye(3))
    np.testing.assert_allclose(target.position, [0.4, 0.2, 0.5])


def test_live_solve_refuses_malformed_arguments(panda):
    model, configuration = panda
    stack = default_stack(configuration)
    with pytest.raises(InvalidTarget, match="targets\\['ee'\\]"):
        LiveSolve(model, stack, targets={"ee": "x"})
    with pytest.raises(InvalidOption, match="not a goal frame"):
        LiveSolve(model, stack, targets={"link7": [0.4, 0.2, 0.5]})
    with pytest.raises(InvalidArgumentType, match="targets"):
        LiveSolve(model, stack, targets=[1, 2, 3])
    live = LiveSolve(model, stack, targets={"ee": [0.4, 0.2, 0.5]})
    np.testing.assert_allclose(live.goals["ee"].target.position, [0.4, 0.2, 0.5])
    with pytest.raises(InvalidInput, match="level_names"):
        LiveSolve(model, stack, level_names=[["a"]])
    with pytest.raises(InvalidArgumentType, match=r"level_names\[1\]"):
        LiveSolve(model, stack, level_names=[["a"], "b"])
    with pytest.raises(InvalidArgumentType, match=r"level_names\[0\]\[0\]"):
        LiveSolve(model, stack, level_names=[[1], ["b"]])
    assert LiveSolve(model, stack, level_names=[["a"], ["b"]]).solve(0).levels[1].tasks == ["b"]
    with pytest.raises(InvalidArgumentType, match="model"):
        LiveSolve(3, stack)
    live = _live(panda)
    with pytest.raises(InvalidOption, match="no handle"):
        live.set_target("nosuch", [0.4, 0.2, 0.5])
    with pytest.raises(InvalidArgumentType, match="frame"):
        live.goal(["ee"])


def test_geometry_and_default_stack_refuse_a_non_model(panda):
    model, _ = panda
    with pytest.raises(InvalidArgumentType, match="model"):
        geom_meshes(3)
    with pytest.raises(InvalidOption, match="which"):
        geom_meshes(model, which="bogus")
    with pytest.raises(InvalidArgumentType, match="which"):
        geom_meshes(model, which=None)
    with pytest.raises(InvalidArgumentType, match="configuration"):
        default_stack(3)
    with pytest.raises(InvalidArgumentType, match="configuration"):
        default_stack(model)


def test_viewer_typed_errors_and_set_q_clips_into_the_limits(panda, no_thread_left):
    model, _ = panda
    lower, upper = model.jnt_range[:, 0], model.jnt_range[:, 1]
    # a start outside the limits is clipped (no slider out of range), and set_q alike
    with _viewer(q0=[5.0] * 7) as viewer:
        np.testing.assert_allclose(viewer.q, np.clip([5.0] * 7, lower, upper))
        with pytest.raises(InvalidTarget):
            viewer.set_target("ee", [0.4, 0.2])
        with pytest.raises(InvalidOption, match="nosuch"):
            viewer.target("nosuch")
        with pytest.raises(InvalidOption, match="nosuch"):
            viewer.frame_pose("nosuch")
        viewer.set_q([5.0] * 7)
        assert np.all(viewer.q >= lower) and np.all(viewer.q <= upper)
        np.testing.assert_allclose(viewer.q, np.clip([5.0] * 7, lower, upper))
        for i, slider in viewer._sliders.items():
            assert slider.value == pytest.approx(viewer.q[i])
        with pytest.raises(InvalidConfiguration):
            viewer.set_q([0.0] * 3)
        with pytest.raises(InvalidConfiguration):
            viewer.set_q([np.nan] * 7)
        inside = (lower + upper) / 2
        viewer.set_q(inside)
        np.testing.assert_allclose(viewer.q, inside)


# ------------------------------------------------------------ 4: goals given as one name
def test_goals_given_as_one_name(panda, no_thread_left):
    model, configuration = panda
    live = LiveSolve(model, default_stack(configuration), goals="ee")
    assert list(live.goals) == ["ee"]
    with pytest.raises(InvalidArgumentType, match="goals"):
        LiveSolve(model, default_stack(configuration), goals=3)
    with pytest.raises(qpik.UnknownFrame, match="nosuch"):
        LiveSolve(model, default_stack(configuration), goals="nosuch")
    with _viewer(goals="ee") as viewer:
        assert viewer.goals == ["ee"]


def test_viewer_of_a_problem_with_a_subset_of_its_goals(no_thread_left):
    pytest.importorskip("viser")
    from qpik.viewer import Viewer

    problem = TASKS / "talos_both_hands.toml"
    with Viewer(problem, port=0, solve_start=False, goals="gripper_left_base_link") as viewer:
        assert viewer.goals == ["gripper_left_base_link"]
