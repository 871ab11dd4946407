"""``qpik analyze``: prints the kinematic report; exits 2 with a one-line reason on bad input."""

from __future__ import annotations

import pytest

from qpik.cli import main


def test_analyze_panda_pose(capsys):
    assert main(["analyze", "panda", "--q", "0", "0.2", "0", "-1.8", "0", "2.0", "0.8"]) == 0
    out = capsys.readouterr().out
    assert "rows vx vy vz wx wy wz (m = 6 tasks, n = 7 DoF)" in out
    assert "degree of redundancy  1" in out and "rank                  6" in out
    assert "manipulability" in out and "singular              no" in out


def test_analyze_planar_4r_position_only(capsys):
    assert (
        main(["analyze", "planar_4r", "--q", "0.76", "0.90", "0.69", "1.19", "--position-only"])
        == 0
    )
    out = capsys.readouterr().out
    assert "degree of redundancy  2" in out and "rows vx vy vz" in out
    assert "1 vz" in out  # a planar arm cannot move out of its plane


def test_analyze_planar_2r_near_the_lecture_singularity(capsys):
    assert main(["analyze", "planar_2r", "--q", "0.785398", "0.001", "--rows", "vx", "vy"]) == 0
    out = capsys.readouterr().out
    assert "manipulability        0.001" in out and "condition number      5000" in out
    assert "near a singularity" in out


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["analyze", "nope"], "unknown robot 'nope'"),
        (["analyze", "planar_2r", "--q", "1", "2", "3"], "expected (2,)"),
        (["analyze", "planar_2r", "--q", "nan", "0"], "is nan"),
        (["analyze", "planar_2r", "--frame", "tip"], "available sites: ee"),
        (["analyze", "planar_2r", "--rows", "vx", "vx"], "without repeats"),
    ],
)
def test_analyze_errors(argv, fragment, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert fragment in err and err.count("\n") == 1


def test_analyze_rejects_both_row_options(capsys):
    with pytest.raises(SystemExit) as info:
        main(["analyze", "planar_2r", "--position-only", "--rows", "vx"])
    assert info.value.code == 2
