"""Where ``qpik reach`` and ``qpik reachmap`` write, checked before the work (audit h7): a
figure format whose program is missing, an ``--out`` that cannot be written, the path a
map is saved at, ``--min-distance`` without ``--collision``."""

from __future__ import annotations

import shutil
import types

import pytest

from qpik.cli import main

REACHMAP = ["reachmap", "ur5e", "--frame", "ee", "--region", "0.3", "0", "0.3", "0.5", "0.2"]
REACHMAP += ["0.5", "--resolution", "0.2", "--orientations", "0", "--workers", "1"]

PLANAR = """
robot = "planar_2r"
[[levels]]
[[levels.tasks]]
type = "position"
frame = "ee"
[target]
position = [1.0, 1.0, 0.0]
"""


@pytest.fixture
def no_map(monkeypatch):
    """``qpik reachmap`` with its map computation failing the test: the checks must come
    first."""

    def computed(*args, **kwargs):
        pytest.fail("the map was computed before the check")

    monkeypatch.setattr("qpik.cli.reachmap.reachability", computed)


def test_a_figure_format_whose_program_is_missing_exits_2_before_solving(
    tmp_path, monkeypatch, capsys, no_map
):
    pytest.importorskip("matplotlib")
    from qpik.plots.base import missing_tool

    monkeypatch.setattr(shutil, "which", lambda program: None)  # no TeX here
    assert "xelatex" in missing_tool("pgf") and missing_tool("png") is None
    argv = REACHMAP + ["--out", str(tmp_path / "m.npz"), "--plot", str(tmp_path / "m.pgf")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--plot" in err and "xelatex" in err and "internal error" not in err
    solved = types.SimpleNamespace(solve=lambda: pytest.fail("solved before the check"))
    monkeypatch.setattr("qpik.cli.reach.load_problem", lambda path: solved)
    assert main(["reach", "p.toml", "--plot", str(tmp_path / "r.pgf"), "--quiet"]) == 2
    assert "xelatex" in capsys.readouterr().err


def test_reachmap_out_and_plot_that_cannot_be_written_exit_2_before_the_map(
    tmp_path, capsys, no_map
):
    missing = tmp_path / "no" / "such" / "folder"
    (tmp_path / "folder.npz").mkdir()
    for path in (missing / "m.npz", tmp_path / "folder.npz"):
        assert main(REACHMAP + ["--out", str(path), "--quiet"]) == 2
        assert "--out" in capsys.readouterr().err
    argv = REACHMAP + ["--out", str(tmp_path / "m.npz"), "--plot", str(missing / "m.png")]
    pytest.importorskip("matplotlib")
    assert main(argv) == 2
    assert "--plot" in capsys.readouterr().err


def test_reachmap_says_the_path_it_saved(tmp_path, capsys):
    assert main(REACHMAP + ["--out", str(tmp_path / "mymap")]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last == f"saved {tmp_path / 'mymap.npz'}"
    assert (tmp_path / "mymap.npz").exists() and not (tmp_path / "mymap").exists()


def test_min_distance_without_collision_is_an_error(tmp_path, capsys, no_map):
    argv = REACHMAP + ["--out", str(tmp_path / "m.npz"), "--min-distance", "0.01"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--min-distance" in err and "--collision" in err


def test_reach_plot_in_a_missing_folder_exits_2_before_solving(tmp_path, monkeypatch, capsys):
    pytest.importorskip("matplotlib")
    (tmp_path / "p.toml").write_text(PLANAR)
    figure = tmp_path / "missing" / "r.png"
    assert main(["reach", str(tmp_path / "p.toml"), "--plot", str(figure), "--quiet"]) == 2
    assert "--plot" in capsys.readouterr().err


def test_reach_json_in_a_missing_folder_exits_2_before_solving(tmp_path, monkeypatch, capsys):
    """Audit (CLI): --json into a folder that does not exist was found only after the
    solve (its report printed, the result lost); it is checked first, as --plot is."""
    import qpik.problem

    (tmp_path / "p.toml").write_text(PLANAR)
    solved = []
    original = qpik.problem.Problem.solve
    monkeypatch.setattr(
        qpik.problem.Problem, "solve", lambda self: solved.append(1) or original(self)
    )
    out = tmp_path / "missing" / "r.json"
    assert main(["reach", str(tmp_path / "p.toml"), "--json", str(out), "--quiet"]) == 2
    assert "--json" in capsys.readouterr().err and not solved
