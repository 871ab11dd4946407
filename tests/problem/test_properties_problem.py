"""Properties of qpik.load_problem, Problem.solve and the CLI (in-process) on mutated
problem files and arguments (issue 13): a ProblemFileError naming the file and a field,
or a valid result; the CLI answers with exit code 0, 1 or 2 and never a traceback."""

from __future__ import annotations

import contextlib
import io
import math

import numpy as np
import pytest
import tomllib
from hypothesis import given
from hypothesis import strategies as st
from properties_common import (
    ROBOTS,
    angle_between,
    any_float,
    assert_finite,
    assert_within_limits,
    fk,
    props,
    typed_or_value,
)

import qpik
from qpik.cli import main
from qpik.problem import problem_files

FILES = {p.stem: p for p in problem_files()}


def toml_value(value) -> str:
    """A TOML literal (inline tables and arrays)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(type(value))


def to_toml(data: dict) -> str:
    return "".join(f"{key} = {toml_value(value)}\n" for key, value in data.items())


def leaves(value, path=()):
    """Paths to every scalar or list of scalars of a parsed TOML document."""
    if isinstance(value, dict):
        for key, item in value.items():
            yield from leaves(item, path + (key,))
    elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
        for i, item in enumerate(value):
            yield from leaves(item, path + (i,))
    else:
        yield path


toml_values = st.one_of(
    any_float,
    st.integers(-(2**63), 2**63 - 1),
    st.booleans(),
    st.text(max_size=20),
    st.sampled_from(["home", "mid", "qpos0", "start", "x" * 300, "track", "solve", "ee"]),
    st.lists(any_float, max_size=8),
    st.lists(st.floats(-2, 2), min_size=3, max_size=3),
    st.just({}),
)


@props(60)
@given(
    name=st.sampled_from(sorted(FILES)),
    picks=st.lists(st.tuples(st.integers(0, 10**6), toml_values), min_size=1, max_size=3),
)
def test_mutated_problem_files_load_or_name_the_field(tmp_path_factory, name, picks):
    data = tomllib.loads(FILES[name].read_text())
    for pick, value in picks:
        paths = list(leaves(data))
        node = data
        path = paths[pick % len(paths)]
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value
    folder = tmp_path_factory.mktemp("mutated")
    path = folder / f"{name}.toml"
    path.write_text(to_toml(data))
    problem, error = typed_or_value(lambda: qpik.load_problem(path))
    if error is not None:
        assert isinstance(error, qpik.ProblemFileError), repr(error)
        assert str(path) in str(error) and error.field
        return
    assert_finite(problem.q0, "problem.q0")
    assert_within_limits(problem.model, problem.q0, "problem.q0", tol=0.0)
    options = problem.solve_options
    work = (
        problem.steps * len(problem.goals)
        if problem.mode == "track"
        else (options.effective_restarts + 1) * options.max_iters * len(problem.goals)
    )
    if work > 3000:
        return
    result, error = typed_or_value(problem.solve)
    if error is not None:
        return
    assert_finite(result.q, "result.q")
    if problem.position_limits:
        for i, q in enumerate(result.path):
            assert_within_limits(problem.model, q, f"path[{i}]")
    if result.converged:
        tol_p, tol_o = options.tol_position, options.tol_orientation
        pairs = (
            [(problem.goals[-1], result.q)]
            if result.trace is not None
            else list(zip(problem.goals, [r.q for r in result.results]))
        )
        for goal, q in pairs:
            for frame in goal.frames:
                position, rotation = fk(problem.model, q, frame.frame, frame.frame_type.value)
                assert np.linalg.norm(position - frame.target.position) <= tol_p * (1 + 1e-9)
                if frame.target.rotation is not None:
                    assert angle_between(rotation, frame.target.rotation) <= tol_o * (1 + 1e-6)


@props(25)
@given(
    raw=st.one_of(
        st.binary(max_size=200),
        st.text(max_size=200),
        st.sampled_from(
            [b"x = " + b"[" * 3000 + b"]" * 3000, b"\xff\xfe robot = 1", b"\xef\xbb\xbf"]
        ),
    )
)
def test_arbitrary_bytes_are_a_problem_file_error_or_load(tmp_path_factory, raw):
    path = tmp_path_factory.mktemp("raw") / "raw.toml"
    path.write_bytes(raw if isinstance(raw, bytes) else raw.encode("utf-8", "surrogatepass"))
    _, error = typed_or_value(lambda: qpik.load_problem(path))
    assert error is None or isinstance(error, qpik.ProblemFileError)


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse's usage errors exit 2
            code = exc.code
    return code, out.getvalue(), err.getvalue()


words = st.one_of(
    st.sampled_from(ROBOTS + ("x" * 300, "", "erd:nope", "/", "nope.xml", "a\tb")),
    st.text(max_size=12),
)
numbers = st.one_of(any_float.map(repr), st.sampled_from(["nan", "inf", "-inf", "1e400", "x"]))


@props(40)
@given(
    command=st.sampled_from(["fk", "analyze", "statics"]),
    robot=words,
    q=st.lists(numbers, max_size=8),
    frame=st.sampled_from(["ee", "nope", "x" * 300, "link2"]),
    frame_type=st.sampled_from(["site", "body"]),
    force=st.lists(numbers, min_size=3, max_size=3),
)
def test_cli_answers_with_an_exit_code_never_a_traceback(
    command, robot, q, frame, frame_type, force
):
    argv = [command, robot, "--frame", frame, "--frame-type", frame_type]
    if q:
        argv += ["--q", *q]
    if command == "statics":
        argv += ["--force", *force]
    code, out, err = run_cli(argv)
    assert code in (0, 1, 2), (code, err)
    assert "Traceback" not in err and "Traceback" not in out
    if code == 2 and "usage:" not in err:
        assert err.startswith(f"qpik {command}: error: "), err
    if code == 0:
        tokens = out.replace("[", " ").replace("]", " ").split()
        assert "nan" not in tokens, out


@pytest.mark.parametrize("name", sorted(FILES))
def test_cli_reach_on_every_shipped_file_exits_0_or_1(name):
    code, _, err = run_cli(["reach", str(FILES[name]), "--quiet"])
    assert code in (0, 1) and "Traceback" not in err, err


def test_cli_internal_error_is_one_line_with_exit_70(monkeypatch):
    from qpik.cli import robots

    def broken(args):
        raise ZeroDivisionError("boom")

    monkeypatch.setattr(robots, "run", broken)
    monkeypatch.delenv("QPIK_DEBUG", raising=False)
    code, _, err = run_cli(["robots"])
    assert code == 70 and "Traceback" not in err
    assert (
        err.startswith("qpik robots: internal error: ZeroDivisionError: boom")
        and err.count("\n") == 1
    )
    monkeypatch.setenv("QPIK_DEBUG", "1")
    with pytest.raises(ZeroDivisionError):
        main(["robots"])
