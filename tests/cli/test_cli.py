"""The command line: each command exits 0 on valid input and 2 with a reason otherwise."""

from __future__ import annotations

import pytest

from qpik.cli import main


def test_robots_lists_bundled_models(capsys):
    assert main(["robots"]) == 0
    out = capsys.readouterr().out
    assert "panda: 7 DoF" in out and "planar_2r: 2 DoF" in out and "sites:  ee" in out


def test_fk_prints_pose_and_jacobian(capsys):
    assert main(["fk", "planar_2r", "--q", "0.785398", "0.001"]) == 0
    out = capsys.readouterr().out
    assert "-1.4149" in out and "0.7064" in out and "position" in out


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["fk", "nope"], "unknown robot 'nope'"),
        (["fk", "planar_2r", "--q", "1", "2", "3"], "expected (2,)"),
        (["fk", "planar_2r", "--frame", "tip"], "available sites: ee"),
    ],
)
def test_fk_errors(argv, fragment, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert fragment in err and err.count("\n") == 1


def test_batch_commands_take_a_preset_and_overrides():
    import argparse

    from qpik.cli._common import add_solve_arguments, solve_options_from_args

    parser = argparse.ArgumentParser()
    add_solve_arguments(parser, "target")
    args = parser.parse_args(["--preset", "fast", "--max-iters", "7"])
    assert solve_options_from_args(args) == {"options": "fast", "max_iters": 7}
    assert solve_options_from_args(parser.parse_args([])) == {"options": None}
