"""Issue 23 items 6 and 7: ``qpik --version`` and the version's one source, the changelog,
ruff's pin, ``--json -`` on stdout, ``qpik batch``'s skip count, one-line warnings,
``q`` outside the limits in ``qpik statics``/``qpik analyze``, the default solver in
``--help``."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

import qpik
from qpik.cli import main
from qpik.problem import problem_files

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[2]
TASKS = {path.stem: path for path in problem_files()}
#: Panda's joint4 range is [-3.0718, -0.0698]: 0 is outside it, -1.5 inside.
PANDA_INSIDE = ["0", "0", "0", "-1.5", "0", "1.5", "0.8"]
PANDA_OUTSIDE = ["0", "0", "0", "0", "0", "1.5", "0.8"]


# --- version, changelog, ruff pin ------------------------------------------------------
def test_version_flag_prints_the_package_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out == f"qpik {qpik.__version__}\n"
    assert re.fullmatch(r"\d+\.\d+\.\d+", qpik.__version__)


def test_version_is_written_once():
    """pyproject.toml has no version of its own: scikit-build-core reads ``__version__``
    from qpik/__init__.py (the regex provider)."""
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in pyproject["project"]
    assert "version" in pyproject["project"]["dynamic"]
    metadata = pyproject["tool"]["scikit-build"]["metadata"]["version"]
    assert metadata == {
        "provider": "scikit_build_core.metadata.regex",
        "input": "qpik/__init__.py",
    }
    regex = pytest.importorskip("scikit_build_core.metadata.regex")
    cwd = os.getcwd()
    try:
        os.chdir(ROOT)
        found = regex.dynamic_metadata("version", {"input": "qpik/__init__.py"})
    finally:
        os.chdir(cwd)
    assert found == qpik.__version__
    written = (ROOT / "qpik/__init__.py").read_text().splitlines()
    assert sum(line.startswith("__version__ =") for line in written) == 1


def test_changelog_has_this_release():
    text = (ROOT / "CHANGELOG.md").read_text()
    assert text.startswith("# Changelog")
    assert f"## [{qpik.__version__}]" in text
    for heading in ("### Added", "### Changed", "### Fixed"):
        assert heading in text


def test_ruff_is_pinned_in_the_dev_extra():
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    (ruff,) = [r for r in pyproject["project"]["optional-dependencies"]["dev"] if "ruff" in r]
    assert re.fullmatch(r"ruff==\d+\.\d+\.\d+", ruff)


# --- --help names the default solver ---------------------------------------------------
def test_help_names_the_default_solver(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "qpik's compiled active-set solver (the default" in out
    assert "OSQP solver" not in out and "--version" in out and "--verbose" in out


# --- --json - ---------------------------------------------------------------------------
def test_reach_json_dash_prints_json_on_stdout(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["reach", str(TASKS["panda_pose_reach"]), "--json", "-"]) == 0
    captured = capsys.readouterr()
    data = json.loads(captured.out)  # stdout is the JSON alone
    assert data["converged"] is True
    assert "goal frame" in captured.err and "converged" in captured.err  # the report
    assert not (tmp_path / "-").exists()


def test_reach_json_dash_quiet_prints_only_json(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    argv = ["reach", str(TASKS["planar_4r_self_motion"]), "--quiet", "--json", "-"]
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["converged"] is True and captured.err == ""
    assert list(tmp_path.iterdir()) == []


def test_bench_json_dash_prints_json_on_stdout(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    argv = ["bench", "--robots", "planar_2r", "--n", "2", "--methods", "qpik", "--quiet"]
    assert main([*argv, "--json", "-"]) == 0
    captured = capsys.readouterr()
    data = json.loads(captured.out)
    assert data["protocol"]["n"] == 2 and "planar_2r" in data["robots"]
    assert "planar_2r" in captured.err  # the table
    assert list(tmp_path.iterdir()) == []


# --- qpik batch says what it skips ------------------------------------------------------
def _write_targets(path: Path, count: int = 6) -> None:
    configuration = qpik.Configuration(qpik.load_robot("ur5e"))
    rng = np.random.default_rng(0)
    positions = []
    for _ in range(count):
        configuration.update(configuration.random_q(rng))
        positions.append(configuration.frame_pose("ee")[0].copy())
    np.savez(path, positions=np.array(positions))


def test_batch_rerun_says_how_many_targets_it_skips(tmp_path, capsys):
    _write_targets(tmp_path / "t.npz")
    out = tmp_path / "r.npz"
    argv = ["batch", str(tmp_path / "t.npz"), "--robot", "ur5e", "--frame", "ee"]
    argv += ["--out", str(out), "--chunk-size", "2", "--workers", "1", "--restarts", "2"]
    assert main(argv + ["--max-chunks", "1"]) == 3
    first = capsys.readouterr().out
    assert "skipped" not in first  # a first run skips nothing
    assert main(argv) == 0  # resumes: chunk 0 skipped, 1 and 2 solved
    resumed = capsys.readouterr().out
    assert f"skipped 2 of 6 targets (1 chunks): already solved in {out}" in resumed
    assert "nothing left" not in resumed
    assert main(argv) == 0  # a rerun of a finished run solves nothing
    again = capsys.readouterr().out
    assert "skipped 6 of 6 targets (3 chunks)" in again and "nothing left to do" in again
    assert main(argv + ["--quiet"]) == 0
    assert capsys.readouterr().out == ""
    assert main(argv + ["--overwrite"]) == 0
    assert "skipped" not in capsys.readouterr().out


# --- warnings on one line ---------------------------------------------------------------
def _warning_command(args) -> int:
    warnings.warn("first line\n  second line", UserWarning, stacklevel=1)
    print("answered")
    return 0


@pytest.mark.filterwarnings("always::UserWarning")  # the test raises one to see it printed
def test_warnings_are_one_line_each(monkeypatch, capsys):
    import qpik.cli.fk as fk

    monkeypatch.setattr(fk, "run", _warning_command)
    before = warnings.showwarning
    assert main(["fk", "planar_2r"]) == 0
    captured = capsys.readouterr()
    assert captured.out == "answered\n"
    assert captured.err == "qpik fk: warning: first line second line (UserWarning)\n"
    assert warnings.showwarning is before  # restored after the command


def test_verbose_leaves_warnings_to_python(monkeypatch, capsys):
    import qpik.cli.fk as fk

    monkeypatch.setattr(fk, "run", _warning_command)
    for argv in (["--verbose", "fk", "planar_2r"], ["fk", "planar_2r", "-v"]):
        with pytest.warns(UserWarning, match="first line"):  # Python's own handling
            assert main(argv) == 0
        assert "qpik fk: warning" not in capsys.readouterr().err


SCRIPT = """
import warnings, qpik.cli, qpik.cli.fk as fk

def run(args):
    warnings.warn("first line\\n  second line", RuntimeWarning, stacklevel=1)
    return 0

fk.run = run
qpik.cli.main({argv!r})
"""


@pytest.mark.parametrize("verbose", [False, True])
def test_warnings_in_a_real_process(verbose, tmp_path):
    """Outside pytest's warning capture: Python's format (file, line, the source line) only
    with --verbose."""
    argv = ["--verbose"] * verbose + ["fk", "planar_2r"]
    script = tmp_path / "warn.py"
    script.write_text(textwrap.dedent(SCRIPT.format(argv=argv)))
    run = subprocess.run(
        [sys.executable, str(script)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    if verbose:
        assert "RuntimeWarning: first line" in run.stderr
        assert "warnings.warn(" in run.stderr  # the source line
    else:
        assert run.stderr == "qpik fk: warning: first line second line (RuntimeWarning)\n"


# --- q outside the limits ---------------------------------------------------------------
@pytest.mark.parametrize(
    "command",
    [["statics", "--force", "0", "0", "-10"], ["analyze"]],
    ids=["statics", "analyze"],
)
def test_q_outside_the_limits_is_said_on_stderr(command, capsys):
    name, *extra = command
    assert main([name, "panda", "--q", *PANDA_OUTSIDE, *extra]) == 0  # exit code unchanged
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1
    assert captured.err.startswith(f"qpik {name}: warning: q is outside the joint limits: ")
    assert "joint 'joint4' (q[3]) = 0 is outside its limits [-3.0718, -0.0698]" in captured.err
    assert "q = " in captured.out  # answered all the same
    assert main([name, "panda", "--q", *PANDA_INSIDE, *extra]) == 0
    assert capsys.readouterr().err == ""


def test_q_outside_the_limits_counts_every_joint(capsys):
    q = ["3", "0", "0", "0", "0", "1.5", "0.8"]  # joint1 (range +-2.8973) and joint4
    assert main(["analyze", "panda", "--q", *q]) == 0
    err = capsys.readouterr().err
    assert "joint 'joint1' (q[0]) = 3" in err and "(and 1 more)" in err


def test_statics_help_says_what_it_does_outside_the_limits(capsys):
    with pytest.raises(SystemExit):
        main(["statics", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "outside the joint limits is answered too, with a one-line warning" in out


def test_robots_details_without_erd_is_refused(capsys):
    assert main(["robots", "--details"]) == 2
    err = capsys.readouterr().err
    assert err == (
        "qpik robots: error: --details applies with --erd only (the bundled robots are "
        "always listed in full)\n"
    )


def test_what_c_code_writes_to_stderr_becomes_one_line_warnings(capfd):
    """MuJoCo's compiler writes ``WARNING: ...`` and a blank line straight to the process's
    stderr (a URDF mimic it ignores, say): the command prints it in its own warning format."""
    import os

    from qpik.cli._common import c_warnings_as_lines

    with c_warnings_as_lines("robots"):
        os.write(2, b"WARNING: <mimic> on joint 'q2' ignored\n\n")
        os.write(2, b"qpik robots: warning: a mesh dropped (UserWarning)\n")  # (already ours)
    assert capfd.readouterr().err == (
        "qpik robots: warning: <mimic> on joint 'q2' ignored\n"
        "qpik robots: warning: a mesh dropped (UserWarning)\n"
    )
