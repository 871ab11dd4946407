"""Every example runs at a small size (Agg backend, no display)."""

from __future__ import annotations

import runpy
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

SMALL = {
    "singularity_2r.py": ["--steps", "3"],
    "self_motion_4r.py": ["--steps", "10"],
    "reach_7dof_priorities.py": ["--max-iters", "20"],
    "payload.py": ["--n", "2"],
    "track_100hz.py": ["--steps", "20", "--every", "10"],
    "humanoid_talos.py": ["--steps", "3"],
    "collision_panda.py": ["--steps", "30"],
    "viewer_panda.py": ["--headless", "--seconds", "1", "--port", "0"],
    "viewer_humanoid.py": ["--headless", "--seconds", "1", "--port", "0"],
}


def test_every_example_is_listed():
    assert sorted(p.name for p in EXAMPLES.glob("*.py")) == sorted(SMALL)


@pytest.mark.parametrize("name", sorted(SMALL))
def test_example_runs(name, monkeypatch, capsys):
    if name.startswith("viewer_"):
        pytest.importorskip("viser")  # the viewer extra
    monkeypatch.setenv("MPLBACKEND", "Agg")
    module = runpy.run_path(str(EXAMPLES / name), run_name="example")
    assert module["__doc__"] and callable(module["main"])
    assert module["main"](SMALL[name]) == 0
    assert capsys.readouterr().out.strip()


def test_example_plot(tmp_path, monkeypatch, capsys):
    pytest.importorskip("matplotlib")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    module = runpy.run_path(str(EXAMPLES / "self_motion_4r.py"), run_name="example")
    out = tmp_path / "self_motion.png"
    assert module["main"](["--steps", "5", "--plot", str(out)]) == 0
    assert out.read_bytes()[:4] == b"\x89PNG"
