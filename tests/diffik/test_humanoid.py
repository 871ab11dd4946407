"""The floating-Talos whole-body example, a few steps: feet held to 1e-5 m, the CoM inside
its support polygon, no joint position or velocity limit crossed."""

from __future__ import annotations

import runpy
from pathlib import Path

import pytest
from conftest import has_erd

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "humanoid_talos.py"


@pytest.mark.skipif(not has_erd(), reason="needs qpik[robots]")
def test_humanoid_stack_holds_the_feet_and_the_limits(capsys):
    run = runpy.run_path(str(EXAMPLE), run_name="example")["run"]
    figures = run(steps=8)
    assert figures["nv"] == 38  # 32 joints and a free base
    assert figures["feet_error"] <= 1e-5 and figures["feet_rotation_error"] <= 1e-5
    assert figures["position_violation"] == 0.0 and figures["velocity_violation"] == 0.0
    assert figures["com_margin"] >= 0.02 - 1e-3  # 20 mm asked, to first order
    left, right = figures["hand_errors"]
    assert right > 0.5  # out of reach: 1.5 m to the side
    out = capsys.readouterr().out
    for line in ("feet error", "hand errors", "CoM margin", "cycle time", "velocity violation"):
        assert line in out
