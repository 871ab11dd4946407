"""``qpik reach`` exit codes and outputs, and every command's --help example and errors."""

from __future__ import annotations

import json
import pathlib

import pytest

from qpik.cli import build_parser, main
from qpik.problem import problem_files

TASKS = {path.stem: path for path in problem_files()}

UNREACHABLE = """
robot = "planar_2r"
q0 = [0.3, 0.6]
[[levels]]
[[levels.tasks]]
type = "position"
frame = "ee"
[target]
position = [3.0, 0.0, 0.0]
[solver]
restarts = 1
max_iters = 20
"""


def test_reach_converged_exits_0(capsys):
    assert main(["reach", str(TASKS["panda_pose_reach"])]) == 0
    out = capsys.readouterr().out
    assert "converged" in out and "panda" in out


def test_reach_quiet_json_and_plot(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    out_json, out_png = tmp_path / "r.json", tmp_path / "r.png"
    argv = ["reach", str(TASKS["planar_4r_self_motion"]), "--quiet"]
    assert main(argv + ["--json", str(out_json), "--plot", str(out_png)]) == 0
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""
    data = json.loads(out_json.read_text())
    assert data["converged"] is True and data["trace"]["steps"] == 200
    assert out_png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_reach_not_converged_exits_1_with_reason(tmp_path, capsys):
    path = tmp_path / "far.toml"
    path.write_text(UNREACHABLE)
    assert main(["reach", str(path), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("qpik reach: not converged: target: ") and err.count("\n") == 1


@pytest.mark.parametrize(
    "text, fragment",
    [
        (UNREACHABLE.replace('type = "position"', 'type = "pos"'), "unknown task type 'pos'"),
        (UNREACHABLE.replace('frame = "ee"', 'frame = "hand"'), "available sites: ee"),
        (UNREACHABLE.replace("planar_2r", "r2d2"), "unknown robot 'r2d2'"),
        ("robot = [", "valid TOML"),
    ],
)
def test_reach_invalid_file_exits_2_with_one_line(tmp_path, capsys, text, fragment):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    assert main(["reach", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("qpik reach: error: ") and str(path) in err and fragment in err
    assert err.count("\n") == 1


def test_reach_missing_file_exits_2(tmp_path, capsys):
    assert main(["reach", str(tmp_path / "none.toml")]) == 2
    assert "readable TOML" in capsys.readouterr().err


COMMANDS = ["reach", "analyze", "statics", "robots", "fk", "demo"]


@pytest.mark.parametrize("command", COMMANDS)
def test_help_has_an_example(command, capsys):
    with pytest.raises(SystemExit) as info:
        main([command, "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "example" in out and f"qpik {command}" in out


def test_every_registered_command_has_an_epilog():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name, command in sub.choices.items():
        assert command.epilog and "qpik " + name in command.epilog, name


VALID = {
    "analyze": ["analyze", "planar_2r", "--q", "0.5", "0.5"],
    "statics": ["statics", "planar_2r", "--q", "0.5", "0.5", "--force", "0", "-1", "0"],
    "robots": ["robots"],
    "fk": ["fk", "planar_2r", "--q", "0.5", "0.5"],
    "demo": ["demo", "--robot", "planar_2r"],
}
INVALID = {
    "analyze": (["analyze", "nope"], "unknown robot 'nope'"),
    "statics": (["statics", "planar_2r", "--frame", "tip", "--force", "0", "0", "1"], "tip"),
    "fk": (["fk", "planar_2r", "--q", "1"], "expected (2,)"),
    "demo": (["demo", "--robot", "nope"], "unknown robot 'nope'"),
}


@pytest.mark.parametrize("command", sorted(VALID))
def test_command_valid_input_exits_0(command, capsys):
    assert main(VALID[command]) == 0
    assert capsys.readouterr().out


@pytest.mark.parametrize("command", sorted(INVALID))
def test_command_invalid_input_exits_2_with_reason(command, capsys):
    argv, fragment = INVALID[command]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"qpik {command}: error: ") and fragment in err


def test_unknown_option_exits_nonzero(capsys):
    with pytest.raises(SystemExit) as info:
        main(["robots", "--frobnicate"])
    assert info.value.code == 2
    assert "unrecognized arguments" in capsys.readouterr().err


def test_plot_without_matplotlib_names_the_extra(tmp_path, monkeypatch, capsys):
    import sys

    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib -> ImportError
    argv = ["reach", str(TASKS["panda_pose_reach"]), "--plot", str(tmp_path / "x.png")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "qpik[plots]" in err and err.count("\n") == 1
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("command", ["reach", "reachmap"])
def test_a_plot_file_of_no_figure_format_exits_2_before_solving(tmp_path, capsys, command):
    """``--plot out.txt``: exit 2 naming --plot and the formats, before the solve (not a
    crash after it, reported as a bug)."""
    import time

    out = tmp_path / "out.txt"
    if command == "reach":
        argv = ["reach", str(TASKS["panda_pose_reach"]), "--plot", str(out), "--quiet"]
    else:
        argv = ["reachmap", "ur5e", "--frame", "ee", "--region", "0", "0", "0", "1", "1", "1",
                "--resolution", "0.05", "--out", str(tmp_path / "m.npz"), "--plot", str(out),
                "--quiet"]  # fmt: skip
    start = time.perf_counter()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--plot" in err and ".png" in err and err.count("\n") == 1
    assert not out.exists() and not (tmp_path / "m.npz").exists()
    assert time.perf_counter() - start < 30  # (a reachmap of 8,000 voxels would take minutes)


def test_a_command_imports_no_other_command():
    """main() registers only the command its arguments name: ``qpik reach`` imports neither
    the batch nor the reachmap command (nor qpik.batch), about 30 ms of a 0.45 s first run
    here; a word that is no command still gets every command in the usage."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from qpik.cli import main\n"
        "assert main(['reach', 'tasks/panda_pose_reach.toml', '--quiet']) in (0, 1)\n"
        "print(sorted(m for m in sys.modules if m.startswith(('qpik.cli.', 'qpik.batch'))))\n"
    )
    root = pathlib.Path(__file__).parents[2]
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=root, capture_output=True, text=True, check=True
    ).stdout
    assert "qpik.cli.reach" in out
    for other in ("qpik.cli.batch", "qpik.cli.reachmap", "qpik.cli.view", "qpik.batch"):
        assert f"'{other}'" not in out, out


def test_a_word_that_is_no_command_gets_every_command(capsys):
    with pytest.raises(SystemExit) as info:
        main(["no-such-command"])
    assert info.value.code == 2
    assert "reachmap" in capsys.readouterr().err  # the usage names every command


def test_a_json_path_that_cannot_be_written_names_the_option(tmp_path, capsys):
    argv = ["reach", str(TASKS["planar_2r_singularity"]), "--json", str(tmp_path), "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("qpik reach: error: --json ") and "is a folder, not a file" in err
    assert err.count("\n") == 1
