"""Problem files' [solver] table: a qpik.SolveOptions preset plus overrides (issue 15)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import qpik

BASE = """
robot = "planar_2r"
q0 = [0.3, 0.6]
{mode}
[[levels]]
[[levels.tasks]]
type = "position"
frame = "ee"

[target]
position = [1.0, 1.0, 0.0]
{tables}
"""
TRACK = ('mode = "track"', "[track]\ndt = 0.05\nsteps = 50\n")


def load(tmp_path: Path, mode: str = "", tables: str = "") -> qpik.problem.Problem:
    path = tmp_path / "problem.toml"
    path.write_text(BASE.format(mode=mode, tables=tables))
    return qpik.load_problem(path)


def test_default_presets_per_mode(tmp_path):
    solve = load(tmp_path).solve_options
    assert solve == qpik.PRESETS["default"].replace(seed=0)
    track = load(tmp_path, *TRACK).solve_options
    assert track.step == qpik.PRESETS["tracking"].step


def test_preset_with_overrides(tmp_path):
    options = load(tmp_path, tables="[solver]\npreset = 'fast'\nmax_iters = 7\nmax_step = false\n")
    expected = qpik.SolveOptions.preset("fast", max_iters=7, max_step=None, seed=0)
    assert options.solve_options == expected
    assert options.options == {"preset": "fast", "max_iters": 7, "max_step": False}


def test_damping_law_fields_and_switch(tmp_path):
    tuned = load(tmp_path, tables="[solver]\nsingular_threshold = 0.1\nmax_damping = 0.2\n")
    law = tuned.solve_options.damping_law
    assert (law.singular_threshold, law.max_damping) == (0.1, 0.2)
    assert law.error_scale == qpik.PRESETS["default"].damping_law.error_scale  # kept
    assert law.lower_trust == 0.0
    trusted = load(tmp_path, tables="[solver]\nlower_trust = 1.0\n").solve_options.damping_law
    assert trusted.lower_trust == 1.0
    assert trusted.max_damping == qpik.PRESETS["default"].damping_law.max_damping
    off = load(tmp_path, tables="[solver]\nadaptive_damping = false\n")
    assert off.solve_options.damping_law is None and off.damping_law() is None


@pytest.mark.parametrize(
    "tables, field",
    [
        ("[solver]\npreset = 'quick'\n", "solver.preset"),
        ("[solver]\npreset = 3\n", "solver.preset"),
        ("[solver]\nsolver = 'nope'\n", "solver.solver"),
    ],
)
def test_bad_solver_fields_name_the_field(tmp_path, tables, field):
    with pytest.raises(qpik.ProblemFileError) as info:
        load(tmp_path, tables=tables)
    assert info.value.field == field, str(info.value)


def test_track_mode_rejects_solve_only_fields(tmp_path):
    with pytest.raises(qpik.ProblemFileError) as info:
        load(tmp_path, TRACK[0], TRACK[1] + "[solver]\nstall_window = 3\n")
    assert info.value.field == "solver.stall_window"


def test_runs_are_reproducible_without_a_seed(tmp_path):
    far = "[solver]\nmax_iters = 3\nrestarts = 4\n"  # restarts drawn from the default seed
    first = load(tmp_path, tables=far).solve()
    second = load(tmp_path, tables=far).solve()
    np.testing.assert_array_equal(first.q, second.q)
    assert first.results[0].restarts_used == second.results[0].restarts_used
