"""Packaging of the compiled engine (issue 20): what the wheel and the sdist hold, the flags
the engine is compiled with, and the same bits from two processes.

The default run (< ~5 s) reads the build configuration (CMakeLists.txt, pyproject.toml),
the compile commands of any build already in ``build/`` and the bundled-file lookup, and
compares one solve's bytes across two processes. The full build (``python -m build`` of
the sdist and, from it, the wheel), installed into a fresh virtual environment and run
from outside the checkout, is ``slow`` (minutes: it compiles the engine and installs the
dependencies): ``pytest -m slow tests/package/test_wheel.py``.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[2]
ENGINE_SOURCES = ("module.cpp", "bind_core.cpp", "bind_model.cpp", "bind_tasks.cpp")
#: Flags that would make the answers depend on the machine or on the optimiser.
FORBIDDEN = ("-ffast-math", "-Ofast", "-march=native", "-mtune=native", "-funsafe-math")


def _cmake() -> str:
    return (ROOT / "CMakeLists.txt").read_text()


def _pyproject() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


# ------------------------------------------------------------------------------ fast
def test_engine_compile_options():
    """The engine's own options: -O2, no FMA contraction, no fast-math, no -march; -O2 also
    replaces CMake's Release default (-O3) and nanobind's -Os is off."""
    text = _cmake()
    options = re.search(r"target_compile_options\(_engine PRIVATE ([^)]*)\)", text)
    assert options, "no target_compile_options for _engine"
    flags = options.group(1).split()
    assert "-O2" in flags and "-ffp-contract=off" in flags
    assert not any(f.startswith(FORBIDDEN) for f in flags)
    assert re.search(r'set\(CMAKE_CXX_FLAGS_RELEASE "-O2 -DNDEBUG"\)', text)
    assert re.search(r"nanobind_add_module\(_engine\b[^)]*\bNOMINSIZE\b", text)
    assert "set(CMAKE_EXPORT_COMPILE_COMMANDS ON)" in text
    code = "\n".join(line.split("#")[0] for line in text.splitlines())  # comments aside
    assert not [f for f in FORBIDDEN if f in code]


def test_install_rules_and_wheel_config():
    """What the wheel gets: the module into qpik/, the stubs as qpik/_engine/*.pyi, robots/
    and tasks/ as qpik/_robots and qpik/_tasks; the C++ sources stay out of it."""
    text = _cmake()
    assert re.search(r"install\(TARGETS _engine LIBRARY DESTINATION qpik\)", text)
    assert re.search(r"install\(DIRECTORY robots/ DESTINATION qpik/_robots\)", text)
    assert re.search(r"install\(DIRECTORY tasks/ DESTINATION qpik/_tasks\)", text)
    stub = re.search(r"nanobind_add_stub\(([^)]*)\)", text)
    assert stub and "RECURSIVE" in stub.group(1) and "INSTALL_TIME" in stub.group(1)
    assert re.search(r"OUTPUT_PATH\s+qpik\b", stub.group(1))
    data = _pyproject()
    sk = data["tool"]["scikit-build"]
    assert sk["wheel"]["packages"] == ["qpik"]
    assert "qpik/_cpp/**" in sk["wheel"]["exclude"]
    assert sk["cmake"]["build-type"] == "Release"
    requires = data["build-system"]["requires"]
    # RECURSIVE stub generation: nanobind 2.9 (its submodule detection fixed in 2.9.2)
    assert any(re.fullmatch(r"nanobind>=2\.9\.2", r) for r in requires), requires
    assert (ROOT / "qpik" / "py.typed").is_file()
    for folder in ("robots", "tasks"):
        assert any((ROOT / folder).iterdir())


def _compile_commands() -> dict[str, list[str]]:
    """Engine source → its compile command (argv), from every build under build/."""
    found = {}
    for path in sorted(ROOT.glob("build/*/compile_commands.json")):
        for entry in json.loads(path.read_text()):
            name = Path(entry["file"]).name
            if name in ENGINE_SOURCES and "_cpp" in entry["file"]:
                argv = entry.get("arguments") or shlex.split(entry["command"])
                found[f"{path.parent.name}/{name}"] = argv
    return found


def check_flags(argv: list[str]) -> None:
    """The last optimisation level is -O2, -ffp-contract=off is there, nothing forbidden."""
    levels = [a for a in argv if re.fullmatch(r"-O[0-9sgz]?|-Ofast", a)]
    assert levels and levels[-1] == "-O2", levels
    contract = [a for a in argv if a.startswith("-ffp-contract=")]
    assert contract and contract[-1] == "-ffp-contract=off", contract
    assert not [a for a in argv if a.startswith(FORBIDDEN)]


def test_compile_commands_of_existing_builds():
    """The flags in effect, read from the compile commands of the builds in build/ (the dev
    build of CMakeLists.txt and the wheel's build/<tag>); skipped when there is none."""
    commands = _compile_commands()
    if not commands:
        pytest.skip("no build/*/compile_commands.json (build the engine first)")
    for where, argv in commands.items():
        try:
            check_flags(argv)
        except AssertionError as exc:
            raise AssertionError(f"{where}: {exc}") from None


def test_bundled_files_are_found():
    """The robots and problem files: qpik/_robots, qpik/_tasks in a wheel, the checkout's
    robots/ and tasks/ otherwise."""
    import qpik
    from qpik.problem import problem_files
    from qpik.robots import robots_dir

    assert {"panda", "planar_2r", "planar_4r", "ur5e"} <= set(qpik.list_robots())
    assert robots_dir().is_dir()
    names = {p.name for p in problem_files()}
    assert "panda_pose_reach.toml" in names


_SOLVE = """
import hashlib, numpy as np, qpik
h = hashlib.sha256()
for robot, target in [("panda", [0.4, 0.1, 0.5])]:
    r = qpik.solve(robot, {"ee": target}, seed=3, restarts=1)
    h.update(np.ascontiguousarray(r.q, dtype=np.float64).tobytes())
    h.update(repr((r.converged, r.iterations)).encode())
print(h.hexdigest())
"""


def test_same_bits_in_two_processes():
    """The same solve in two fresh processes (different hash seeds) gives the same bytes."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    runs = [
        subprocess.Popen(
            [sys.executable, "-c", _SOLVE],
            env=dict(env, PYTHONHASHSEED=seed),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for seed in ("1", "2")
    ]
    outputs = [p.communicate(timeout=120) for p in runs]
    for p, (_out, err) in zip(runs, outputs, strict=True):
        assert p.returncode == 0, err
    assert outputs[0][0] == outputs[1][0]


# ------------------------------------------------------------------------------ slow
def _run(argv, **kwargs) -> subprocess.CompletedProcess:
    result = subprocess.run(argv, capture_output=True, text=True, **kwargs)
    assert result.returncode == 0, f"{argv}\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    return result


def check_wheel_contents(names: list[str]) -> None:
    """What a wheel must and must not hold."""
    assert not [n for n in names if n.startswith("qpik/_cpp/") or n.endswith((".cpp", ".hpp"))]
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]
    assert len([n for n in names if re.fullmatch(r"qpik/_engine\..*\.(so|pyd)", n)]) == 1
    stubs = {n for n in names if n.startswith("qpik/_engine/")}
    assert "qpik/_engine/__init__.pyi" in stubs and len(stubs) >= 5, stubs
    assert "qpik/py.typed" in names
    for robot in ("panda", "planar_2r", "planar_4r", "ur5e"):
        assert f"qpik/_robots/{robot}.xml" in names
    assert "qpik/_tasks/panda_pose_reach.toml" in names
    assert "qpik/cli/__init__.py" in names


def check_sdist_contents(names: list[str]) -> None:
    top = names[0].split("/")[0]
    rel = {n.removeprefix(top + "/") for n in names}
    assert {"CMakeLists.txt", "pyproject.toml", "qpik/_cpp/module.cpp", "qpik/_cpp/bind.hpp"} <= rel
    assert {"robots/panda.xml", "tasks/panda_pose_reach.toml"} <= rel
    # no build products of a checkout (an in-tree engine module, caches, build folders)
    assert not [n for n in rel if n.endswith((".so", ".pyd", ".pyc")) or "__pycache__" in n]
    assert not [n for n in rel if n.startswith(("build/", "dist/"))]


@pytest.mark.slow
def test_sdist_wheel_install_and_run(tmp_path):
    """python -m build (the sdist, then the wheel from it), the wheel installed into a new
    virtual environment and used from a folder that is not the checkout."""
    build = pytest.importorskip("build")
    if not hasattr(build, "ProjectBuilder"):  # a checkout's build/ folder, not pypa/build
        pytest.skip("pypa/build is not installed (the checkout's build/ folder shadows it)")
    out = tmp_path / "dist"
    _run([sys.executable, "-m", "build", "--outdir", str(out), str(ROOT)], timeout=1800)
    (sdist,) = out.glob("qpik-*.tar.gz")
    (wheel,) = out.glob("qpik-*.whl")
    with tarfile.open(sdist) as archive:
        check_sdist_contents(archive.getnames())
    with zipfile.ZipFile(wheel) as archive:
        check_wheel_contents(archive.namelist())
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", str(venv)])
    python = venv / "bin" / "python"
    _run([str(python), "-m", "pip", "install", "-q", str(wheel)], timeout=1800)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    script = (
        "import qpik, qpik._engine, pathlib\n"
        "assert 'site-packages' in qpik.__file__, qpik.__file__\n"
        "from qpik.problem import problem_files\n"
        "from qpik.robots import robots_dir\n"
        "assert robots_dir().name == '_robots', robots_dir()\n"
        "assert set(qpik.list_robots()) >= {'panda', 'planar_2r', 'planar_4r', 'ur5e'}\n"
        "files = problem_files()\n"
        "assert files and all(p.parent.name == '_tasks' for p in files), files\n"
        "print(qpik.solve('panda', {'ee': [0.4, 0.1, 0.5]}).converged)\n"
        "print(next(p for p in files if p.name == 'panda_pose_reach.toml'))\n"
    )
    result = _run([str(python), "-c", script], cwd=elsewhere, env=env)
    converged, problem = result.stdout.split()
    assert converged == "True"
    _run([str(venv / "bin" / "qpik"), "reach", problem, "--quiet"], cwd=elsewhere, env=env)
    # the stubs are found by a type checker through the installed package
    site = Path(
        _run(
            [str(python), "-c", "import qpik; print(qpik.__file__)"], cwd=elsewhere, env=env
        ).stdout.strip()
    ).parent
    assert (site / "_engine" / "__init__.pyi").is_file()
    # the same answer as the checkout (the same flags, the same compiler)
    here = _run([sys.executable, "-c", _SOLVE], env=dict(env, PYTHONPATH=str(ROOT)))
    there = _run([str(python), "-c", _SOLVE], cwd=elsewhere, env=env)
    assert here.stdout == there.stdout
