"""Findings of the fuzz campaign's boundary category and of the wheel check (issue 20), kept
as expected failures until the code they name is fixed (then they pass and the xfail
marks can go): bad input into a public entry point must raise a :class:`qpik.QpikError`,
and ``qpik reach tasks/<file>`` must find a shipped problem file from any folder.
"""

from __future__ import annotations

import numpy as np
import pytest

import qpik
from qpik.cli import main


def test_reach_shipped_problem_from_another_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["reach", "tasks/panda_pose_reach.toml", "--quiet"]) == 0


@pytest.mark.parametrize(
    "make",
    [
        lambda nq: (np.zeros(3), np.ones(3)),
        lambda nq: (np.zeros((2, nq)), np.ones(nq)),
        lambda nq: (np.array(["a"] * nq, dtype=object), np.ones(nq)),
    ],
    ids=["short", "2d", "object"],
)
def test_reach_bound_rejects_bad_limits(make):
    from qpik.model import KinematicChain

    model = qpik.load_robot("panda")
    chain = KinematicChain.from_model(model, "ee")
    with pytest.raises(qpik.QpikError):
        chain.reach_bound(*make(model.nq))


def test_posture_set_target_wrong_shape_is_typed():
    model = qpik.load_robot("panda")
    task = qpik.tasks.PostureTask(model, cost=1.0)
    with pytest.raises(qpik.QpikError):
        task.set_target(np.zeros(3))


def test_hierarchy_object_level_is_typed():
    from qpik.core import Level, solve_hierarchy

    A = np.array([["a", 1.0, 1.0], [1.0, 1.0, 1.0]], dtype=object)  # not numbers
    with pytest.raises(qpik.InvalidInput):
        solve_hierarchy([Level(A, np.ones(2), 1e-6)], -np.ones(3), np.ones(3))
    numbers = np.ones((2, 3), dtype=object)  # numbers held as objects: converted
    assert solve_hierarchy([Level(numbers, np.ones(2), 1e-6)], -np.ones(3), np.ones(3)).ok


_BOXES = """
import resource, numpy as np
resource.setrlimit(resource.RLIMIT_AS, (3 * 2**30, resource.getrlimit(resource.RLIMIT_AS)[1]))
import qpik._engine as e
z, i = np.zeros(6), np.arange(6, dtype=np.int64)
try:
    e.diffik.boxes(z, 0.01, i, -np.ones(6), np.ones(6), np.ones(6), i, np.ones(6), 2**31 - 1)
except ValueError:
    print("ValueError")
except MemoryError:
    print("MemoryError")
"""


def test_engine_boxes_rejects_n_beyond_qpos():
    import subprocess
    import sys
    from pathlib import Path

    root = str(Path(__file__).resolve().parents[2])
    out = subprocess.run(
        [sys.executable, "-c", _BOXES],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=root,
        env={"PYTHONPATH": root, "PATH": "/usr/bin:/bin"},
    )
    assert out.stdout.strip() == "ValueError", out.stdout + out.stderr
