"""Fuzz campaign against qpik's public API (issue 13): bad input never crashes, hangs,
leaks an untyped error or returns NaN.

    python benchmarks/fuzz.py --n 10000              # the campaign (exit 1 on any bad outcome)
    python benchmarks/fuzz.py --n 300 --categories solve step
    python benchmarks/fuzz.py --case solve:17        # re-run one case here, with its traceback
    python benchmarks/fuzz.py --list                 # the categories

Each case is a plain-data *spec* (its ``repr`` is the reproduction), generated from
``(seed, category, index)`` by a generator that imports nothing from qpik. Cases run in
subprocess workers (one case at a time each, many cases per worker, so that state left
behind by earlier cases is exercised too); a worker that dies is a **crash**, a case over
``--timeout`` seconds is a **hang** (the worker is killed and replaced), and so is a case
that answers after more than ``--hang`` (5) seconds of its worker's CPU time (15 for a
worker's first case: issue 25's limits, measured in CPU so that other loads on the machine
do not count).

Outcomes of a case:

* ``ok``: a valid result: finite where a finite answer exists, joints within their
  limits, ``converged`` only when an independent forward kinematics (a fresh
  ``mujoco.MjData``) agrees within tolerance.
* ``typed``: a :class:`qpik.QpikError` (the contract for bad input).
* bad: ``untyped`` (any other exception, or a CLI traceback / unexpected exit code),
  ``nonfinite``, ``limits`` (a returned configuration outside its joint limits or a
  velocity over its limit), ``claim`` (converged, but not within tolerance), ``hang``,
  ``crash``, ``nondet`` (the same case twice, in a process with another history, gives a
  different answer bit for bit), ``stale`` (a solver whose tasks, limits or settings were
  changed after it stepped answers otherwise than a new one built from them).

Categories: solve, solve_many, step (``IKSolver.step`` and ``solve_ik`` with random
stacks and limits), problem (``load_problem`` + solve + ``qpik reach`` on mutated problem
files), robot_file (``load_robot`` on malformed MJCF / URDF and odd names, then FK,
statics, a solve), statics, analysis, cli (``qpik.cli.main`` in-process), determinism, and
two aimed at the compiled engine (``qpik._engine``, issue 20): boundary (the public entry
points that end in it: ``qpik.core.solve_hierarchy``, ``KinematicChain`` pose / Jacobian /
reach bound, ``Configuration``, task targets then ``IKSolver.step``, ``qpik.solve``'s
``q0`` and target, with odd arrays: float32 / int / object / big-endian, Fortran order,
strided, zero-stride, read-only, NaN / inf, empty, wrong shapes, 0-d, lists, 100 000 rows)
and engine (each kernel of ``qpik._engine`` called directly with the arguments recorded
from valid solves, one to three of them mutated likewise, scalars too, or two arrays
aliased; the kernels are private, so any Python exception is a clean refusal, counted as
typed, and only a crash or a hang is bad). Issue 25 added robot_gen (URDF / MJCF written on
the fly: odd inertias and masses, meshes, mimic joints, equalities), schema (problem files
from every field of the schema), stack (every task and limit type, qpik's and mink's, at
every level, extreme time steps), signature (a wrong type for every argument of every
public function) and erd (example-robot-data robots, fixed or floating, targets for one to
four bodies at once through qpik.solve, IKSolver.step, problem files and statics, every
reported error judged against MuJoCo's forward kinematics of the returned q). mutate: a
stack as ``stack`` draws one, stepped once (``IKSolver.step``, or ``solve_ik`` with its kept
solver), then one to three attributes of its tasks and limits assigned directly, valid
values and not (and sometimes the solver's damping or damping law), and stepped again,
against a new solver built from the changed objects: both a typed error, or answers
within 1e-9.

The table has one row per category; the exit status is 1 when any bad outcome occurred.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import math
import multiprocessing as mp
import multiprocessing.connection
import os
import random
import sys
import tempfile
import time
import traceback
from collections import Counter, defaultdict
from pathlib import Path

from bench_cli import (  # benchmarks/bench_cli.py (this folder is on sys.path)
    at_least,
    nonnegative_float,
    positive_float,
)

ROOT = Path(__file__).resolve().parent.parent
BAD = ("untyped", "nonfinite", "limits", "claim", "misreport", "message", "accepted", "refused")
BAD += ("hang", "crash", "nondet", "stale")
COLUMNS = ("ok", "typed") + BAD
CATEGORIES = (
    "solve",
    "solve_many",
    "step",
    "problem",
    "robot_file",
    "statics",
    "analysis",
    "cli",
    "determinism",
    "boundary",
    "engine",
    "robot_gen",
    "schema",
    "stack",
    "signature",
    "erd",
    "mutate",
)
ROBOTS = ("planar_2r", "planar_4r", "panda", "ur5e")
#: A case over this many seconds of its worker's CPU time is a hang (issue 25); the first
#: case of a worker gets three times as long. ``--hang`` sets it.
HANG = 5.0
#: ``(cpu seconds, "category:index")`` of every answered case (the summary lists the slowest).
CPU_TIMES: list = []
NAN, INF = float("nan"), float("inf")
WEIRD_FLOATS = (0.0, -0.0, 1e-300, -1.0, 1e300, NAN, INF, -INF, 1e-12, 1e12, 5e-324)
WEIRD_ANY = WEIRD_FLOATS + (None, "1", [1.0], True, 2**70, -1, (1.0,), {}, 3)


# =============================================================================== specs
# Generators: plain data only (no qpik import), deterministic in (seed, category, index).


def _table(data: dict, key: str) -> dict:
    """``data[key]`` as a table to edit; a scratch dict when an earlier edit made it a
    scalar (the file keeps that scalar, which is the error under test)."""
    value = data.setdefault(key, {})
    return value if isinstance(value, dict) else {}


def _maybe(r: random.Random, normal, weird, p_weird: float = 0.35):
    return r.choice(weird) if r.random() < p_weird else normal


def _solve_options(r: random.Random) -> dict:
    options: dict = {"restarts": r.choice([0, 1, 2])}
    # half the cases have valid options only (the valid paths need coverage too), the
    # other half one weird value per option in three on average
    p_weird = 0.0 if r.random() < 0.5 else 0.3
    table = {
        "tol_position": ([1e-4, 1e-3], [0.0, -1.0, NAN, INF, 1e-15, 1e3, "1e-4", None]),
        "tol_orientation": ([1e-3, 1e-2], [0.0, -1.0, NAN, INF, 1e3, None]),
        "max_iters": ([20, 50, 100], [0, -1, 1, 2.5, "10", True, 5000, None]),
        "time_budget": ([None, 2.0], [0.0, -1.0, NAN, INF, 1e300, 1e-9, "1", 5e-324]),
        "restarts": ([0, 1, 2], [-1, 2.5, None, True, "2", 10**30]),
        "seed": ([0, 1, 7], [-1, 2**70, 1.5, "a", None, "rng", NAN, True]),
        "alpha": ([1.0, 0.5], [0.0, -1.0, 2.0, NAN, INF, "1"]),
        "beta": ([1.0, 0.5], [0.0, -1.0, NAN, INF, 1e300]),
        "solver": (["osqp", "daqp", "quadprog"], ["nope", None, "", 3]),
        "stall_window": ([5, 3], [0, -1, 1.5, 10**9, None]),
        "damping_law": (
            ["default"],
            [
                None,
                ("law", 1e300, 1e300),
                ("law", NAN, 0.1),
                ("law", -1.0, 0.1),
                ("law", 0.05, INF),
                ("law", 0.0, 0.0),
            ],
        ),
        "max_step": (
            ["default", None],
            [
                (1.0,),
                (0.0, 0.0),
                (-1.0, 1.0),
                (NAN, 1.0),
                (INF, INF),
                "x",
                (1e-300, 1e-300),
                (1, 2, 3),
            ],
        ),
        "damping": ([1e-6, 1e-3], [0.0, -1.0, NAN, INF, 1e300, 1e-300]),
        "secondary": ([False, True], [None, "yes"]),
        "limits": (
            ["joint"],
            [
                None,
                "bogus",
                [],
                ["config_gain", 1.5],
                ["config_dist", 10.0],
                ["velocity", 0.5],
                ["velocity", 0.0],
                ["velocity", NAN],
            ],
        ),
    }
    for key, (normal, weird) in table.items():
        if r.random() < 0.45:
            options[key] = _maybe(r, r.choice(normal), weird, p_weird)
    # keep the worst legitimate work bounded: an unbounded time budget with huge restarts
    # is a long (not a hung) solve; max_iters 5000 only with few restarts
    if options.get("restarts") == 10**30 and options.get("time_budget") in (None, INF, 1e300):
        options["time_budget"] = 0.5
    return options


def _target(r: random.Random) -> dict:
    kind = r.choices(["reach", "reach_pose", "far", "raw", "se3", "matrix"], [4, 4, 1, 2, 1, 1])[0]
    spec = {"kind": kind, "q_seed": r.randrange(10**6)}
    if kind == "far":
        spec["scale"] = r.choice([10.0, 1e6, 1e200, 1e300, 1e308])
    elif kind == "raw":
        spec["value"] = r.choice(
            [
                [1.0, 1.0],
                [1.0, [1.0, 0.0]],
                "abc",
                [NAN, 0.0, 0.0],
                [INF, 0.0, 0.0],
                None,
                ([0.3, 0.0, 0.2], [[1, 0, 0], [0, 1, 0]]),
                ([0.3, 0.0, 0.2], [[2, 0, 0], [0, 1, 0], [0, 0, 1]]),
                ([0.3, 0.0, 0.2], [[1, 0, 0], [0, 1, 0], [0, 0, -1]]),
                ([0.3, 0.0, 0.2], [[NAN, 0, 0], [0, 1, 0], [0, 0, 1]]),
                [[1, 0, 0, 0.3], [0, 1, 0, 0], [0, 0, 1, 0.2], [0, 0, 0, 2]],
                [1e-320, 0.0, 0.0],
                [0.3, 0.0, 0.2, 0.0],
                {"x": 1},
                [True, False, True],
                ["1", "2", "3"],
                (None, None),
            ]
        )
    elif kind == "matrix":
        spec["perturb"] = r.choice([0.0, 1e-9, 1e-3, 0.5])
    return spec


def _frame_key(r: random.Random):
    return _maybe(
        r,
        r.choice(["ee", ("ee", "site")]),
        [
            None,
            3,
            "nope",
            ("ee",),
            ("ee", "site", "x"),
            ("ee", "bogus"),
            ("link2", "body"),
            ("ee", None),
            "",
            "x" * 300,
            b"ee",
            1.5,
            ("nope", "geom"),
        ],
        0.25,
    )


def _q_choice(r: random.Random):
    return _maybe(
        r,
        r.choice(["mid", "random", None]),
        [
            "outside_tiny",
            "outside",
            "nan",
            "short",
            "at_lower",
            "at_upper",
            "strings",
            "huge",
            "inside_tiny",
        ],
        0.3,
    )


def gen_solve(r: random.Random) -> dict:
    return {
        "robot": _maybe(r, r.choice(ROBOTS), ["x" * 300, "nope", "", None, 3, "erd:nope"], 0.05),
        "targets": _maybe(
            r,
            {"ee": None},
            ["empty", "none", "list", "two_frames", "bad_key"],
            0.1,
        ),
        "frame": _frame_key(r),
        "target": _target(r),
        "q0": _q_choice(r),
        "options": _solve_options(r),
    }


def gen_solve_many(r: random.Random) -> dict:
    spec = gen_solve(r)
    spec["count"] = r.choice([0, 1, 2, 3])
    spec["many"] = {
        "seed": _maybe(r, r.choice([0, 3]), [-1, None, 2**70, "a", 1.5], 0.2),
        "workers": _maybe(r, r.choice([None, 1]), [0, -1, 2.5, "2"], 0.15),
        "progress": False,
    }
    return spec


TASKS = (
    "frame",
    "position",
    "orientation",
    "posture",
    "damping",
    "manipulability",
    "joint_limit_distance",
    "com",
    "pose",
    "relative_frame",
    "kinetic_energy",
    "dof_freezing",
    "axis_align",
    "look_at",
    "equality",
)
#: Wrong-type values for any argument of a task's constructor (issue 25, item 2).
WRONG_TYPES = (None, "1", b"ee", [1.0, "x"], {}, object, 2**70, True, (1.0, None), 1j)
#: Time steps at and beyond every edge of the documented range [1e-9, 1e6] s.
EXTREME_DT = (5e-324, 1e-300, 9.99e-10, 1e-9, 1e6, 1.0000001e6, 1e300, -0.0, True, None, [0.01])


def _task(r: random.Random) -> dict:
    kind = r.choice(TASKS[:-1]) if r.random() < 0.97 else "equality"  # always refused
    task: dict = {"type": kind}
    if r.random() < 0.3:
        task["cost"] = r.choice([1.0, 0.1, 0.0, -1.0, NAN, INF, 1e300, [1.0, 2.0], "x"])
    if r.random() < 0.2:
        task["gain"] = r.choice([1.0, 0.5, 0.0, 1.5, -1.0, NAN])
    if r.random() < 0.2:
        task["lm_damping"] = r.choice([0.0, 1e-3, -1.0, NAN, INF, 1e300])
    if kind in ("frame", "position", "orientation", "manipulability"):
        task["frame"] = _maybe(r, "ee", ["nope", ("link2", "body")], 0.1)
    if kind in ("pose", "relative_frame", "axis_align", "look_at"):
        task["frame"] = _maybe(r, "ee", ["nope", ("link2", "body")], 0.1)
    if kind == "manipulability":
        task["rows"] = r.choice(["pose", "position", "orientation", "bogus", "pose"])
    if kind == "kinetic_energy":
        task["dt"] = _maybe(r, r.choice([0.01, 1.0, "unset"]), list(EXTREME_DT), 0.3)
    if kind == "dof_freezing":
        task["dofs"] = r.choice([[0], [0, 1], [], [-1], [99], [0, 0], "0", [0.5]])
    if kind in ("axis_align", "look_at"):
        task["axis"] = r.choice([(0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 0.0, 0.0), (NAN, 0, 1)])
    task["target"] = r.choice(["reach", "start", "far", "none", "nan"])
    if r.random() < 0.05:  # one argument of the constructor of a wrong type
        task["wrong"] = [
            r.choice(["frame", "frame_type", "cost", "gain", "lm_damping", "model"]),
            r.randrange(len(WRONG_TYPES)),
        ]
    return task


def gen_step(r: random.Random) -> dict:
    levels = [[_task(r) for _ in range(r.choice([1, 1, 2]))] for _ in range(r.choice([1, 2, 3]))]
    if r.random() < 0.05:
        levels = r.choice([[], [[]], "x", [None]])
    limits = []
    for _ in range(r.choice([0, 1, 1, 2, 3])):
        limits.append(
            r.choice(
                [
                    ["config", r.choice([0.95, 0.5, 1.0, 0.0, 1.5, NAN])],
                    ["config_dist", r.choice([0.0, 0.01, 10.0, -1.0])],
                    ["velocity", r.choice([1.0, 0.1, 1e-9, 0.0, -1.0, NAN, INF, 1e300])],
                    ["joint_limits", r.choice([1.0, 0.5, None, 0.0, -1.0, NAN, "1"])],
                    ["collision", r.choice([0.85, 0.5, 0.0, 1.5, NAN])],
                    ["support", r.choice([0.0, 0.02, -0.1, NAN, 1e300])],
                ]
            )
            if r.random() < 0.95
            else ["wrong", r.randrange(len(WRONG_TYPES))]
        )
    return {
        "robot": r.choice(ROBOTS),
        "levels": levels,
        "limits": limits,
        "solver": _maybe(r, r.choice(["osqp", "daqp", "quadprog"]), ["nope", None], 0.05),
        "damping": _maybe(r, r.choice([1e-6, 1e-3, 0.0]), [-1.0, NAN, INF, 1e300], 0.1),
        "damping_law": _maybe(
            r,
            "default",
            [None, ("law", 1e300, 1e300), ("law", 0.05, 1e-9), ("law", NAN, 0.05)],
            0.15,
        ),
        "dt": _maybe(
            r,
            r.choice([0.01, 0.002, 0.1]),
            [0.0, -0.01, NAN, INF, 1e-300, 1e300, "1", *EXTREME_DT],
            0.15,
        ),
        "q": _q_choice(r),
        "steps": r.choice([1, 2, 5]),
        "entry": r.choice(["step", "step", "solve_ik"]),
    }


# -- problem files
def _shipped_problems() -> list[Path]:
    return sorted((ROOT / "tasks").glob("*.toml"))


def _leaf_paths(value, path=()):
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _leaf_paths(v, path + (k,))
    elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
        for i, v in enumerate(value):
            yield from _leaf_paths(v, path + (i,))
    else:
        yield path


def gen_problem(r: random.Random) -> dict:
    files = [p.name for p in _shipped_problems()]
    spec = {
        "file": r.choice(files),
        "mutations": [],
        "raw": None,
        "solve": r.random() < 0.7,
        "cli": r.random() < 0.3,
    }
    roll = r.random()
    if roll < 0.06:
        spec["raw"] = r.choice(
            [
                "deep_array",
                "deep_table",
                "non_utf8",
                "truncate",
                "empty",
                "bom",
                "flip_bytes",
                "huge_line",
            ]
        )
        spec["raw_seed"] = r.randrange(10**6)
        return spec
    for _ in range(r.choice([0, 1, 1, 1, 2, 3])):
        spec["mutations"].append(
            {
                "op": r.choices(["set", "scale", "delete", "add", "special"], [4, 4, 1, 1, 2])[0],
                "factor": r.choice([0.5, 2.0, 0.9, 1.1, 1e-3, 1e3, -1.0, 0.0, 1e6]),
                "pick": r.randrange(10**6),
                "value": r.choice(
                    WEIRD_ANY
                    + (
                        1e-9,
                        0.5,
                        2,
                        10**7,
                        -(10**7),
                        "home",
                        "mid",
                        "qpos0",
                        "start",
                        "x" * 300,
                        [0.0, 0.0, 0.0],
                        [NAN, 0.0, 0.0],
                        [1e300, 0.0, 0.0],
                        [[1.0]],
                        "track",
                        "solve",
                        1e-6,
                        1e-7 + 1.0,
                    )
                ),
                "special": r.choice(
                    [
                        "lm_damping",
                        "max_damping",
                        "singular_threshold",
                        "cost",
                        "q0_key",
                        "q0_outside",
                        "robot",
                        "steps",
                        "velocity",
                        "time_budget",
                        "seed",
                        "dt",
                        "tol",
                        "statics",
                        "max_step",
                        "unnamed_key",
                    ]
                ),
            }
        )
    return spec


# -- robot files
def gen_robot_file(r: random.Random) -> dict:
    kind = r.choices(["mjcf", "urdf", "name"], [4, 4, 1])[0]
    spec: dict = {"kind": kind, "seed": r.randrange(10**6)}
    if kind == "name":
        spec["name"] = r.choice(
            [
                "x" * 300,
                "",
                "erd:",
                "erd:nope",
                "/",
                ".",
                "robots",
                "a\x00b",
                "nope.xml",
                "nope.urdf",
                "erd:" + "y" * 300,
                "/dev/null",
                "/proc/self/status",
                3,
                None,
                b"panda",
                "PANDA",
                "panda ",
                "tasks/panda_pose_reach.toml",
            ]
        )
        return spec
    spec["joints"] = r.choice([0, 1, 2, 3, 4])
    spec["joint_types"] = [
        r.choice(
            [
                "hinge",
                "hinge",
                "slide",
                "ball",
                "free",
                "continuous",
                "fixed",
                "floating",
                "planar",
                "bogus",
            ]
        )
        for _ in range(spec["joints"])
    ]
    spec["mutations"] = [
        {
            "what": r.choice(
                [
                    "pos",
                    "axis",
                    "range",
                    "mass",
                    "inertia",
                    "limit",
                    "velocity",
                    "effort",
                    "damping",
                    "armature",
                    "size",
                    "quat",
                    "name",
                    "mesh",
                    "unknown_tag",
                    "drop_attr",
                    "gravity",
                    "timestep",
                    "actuator",
                    "ctrlrange",
                    "keyframe",
                ]
            ),
            "value": r.choice(
                [
                    "nan",
                    "inf",
                    "-inf",
                    "1e400",
                    "-1",
                    "0",
                    "",
                    "abc",
                    "1e300",
                    "0 0 0",
                    "nan 0 0",
                    "1 2",
                    "1e-300",
                    "-1e300 1e300",
                    "1 0 0 0 0",
                    "1 -1",
                ]
            ),
            "pick": r.randrange(10**6),
        }
        for _ in range(r.choice([0, 1, 1, 2]))
    ]
    spec["raw"] = _maybe(r, None, ["non_utf8", "truncate", "deep", "bom", "doctype"], 0.1)
    return spec


def gen_statics(r: random.Random) -> dict:
    vec = [
        [0.0, 0.0, -20.0],
        [1.0, 2.0, 3.0],
        [NAN, 0, 0],
        [1e300, 1e300, 1e300],
        [INF, 0, 0],
        [1, 2],
        "x",
        None,
        [[1, 2, 3]],
        [0.0, 0.0, 0.0],
        [1e-300, 0, 0],
        [1e200, 0, 1e200],
    ]
    return {
        "robot": r.choice(ROBOTS),
        "q": _q_choice(r),
        "frame": _maybe(r, "ee", ["nope", 99, -1, "", ("link2",)], 0.1),
        "frame_type": _maybe(r, "site", ["body", "geom", "bogus", None, 3], 0.1),
        "force": _maybe(r, r.choice(vec[:2]), vec, 0.3),
        "torque": _maybe(r, None, vec, 0.3),
        "direction": _maybe(r, [0.0, 0.0, -1.0], vec, 0.3),
        "expressed_in": _maybe(r, "world", ["local", "bogus", None], 0.1),
        "tau": _maybe(r, "random", ["nan", "huge", "short", "zero"], 0.3),
        "rcond": _maybe(r, 1e-10, [0.0, -1.0, NAN, INF, 1.0, 2.0], 0.2),
        "rows": _maybe(r, (0, 1, 2), [(), (6,), (0, 0), (-1,), "pose", (0, 1, 2, 3, 4, 5)], 0.2),
        "torque_limits": _maybe(r, None, ["nan", "reversed", "zero", "short", "huge"], 0.2),
        "gravity": r.choice([True, False]),
        "wrenches": _maybe(r, "one", ["none", "bad", "many", "weird_frame"], 0.2),
    }


def gen_analysis(r: random.Random) -> dict:
    return {
        "m": r.choice([0, 1, 2, 3, 6]),
        "n": r.choice([0, 1, 2, 4, 7]),
        "scale": _maybe(r, 1.0, [1e-300, 1e300, 1e150, 1e-150, 0.0, 1e308, 5e-324], 0.35),
        "rank_drop": r.choice([0, 0, 1, 2]),
        "poison": _maybe(
            r,
            None,
            ["nan", "inf", "string", "ragged", "1d", "3d", "none", "bool", "complex", "object"],
            0.12,
        ),
        "tol": _maybe(r, None, [0.0, -1.0, NAN, INF, 1e300, 1e-300, "x"], 0.2),
        "damping": _maybe(r, r.choice([1e-3, 1.0]), [0.0, -1.0, NAN, INF, 1e300, 1e-300], 0.3),
        "xi_scale": _maybe(r, 1.0, [1e300, 1e-300, NAN, 0.0], 0.2),
        "robot": r.choice(ROBOTS),
        "q": _q_choice(r),
        "rows": _maybe(
            r,
            r.choice(["pose", "position"]),
            ["orientation", ("vx", "vy"), (0, 0), (), "bogus", (7,), (True,)],
            0.2,
        ),
        "limits": _maybe(r, "model", ["huge", "tiny", "nan", "reversed", "inf", "mixed"], 0.4),
        "steps": _maybe(r, 3, [0, -1, 2.5, "3"], 0.15),
        "step_size": _maybe(r, 0.01, [0.0, NAN, INF, 1e300, -0.01], 0.2),
        "frame": _maybe(r, "ee", ["nope", 99, -1], 0.1),
        "seed": r.randrange(10**6),
    }


def gen_cli(r: random.Random) -> dict:
    command = r.choice(["fk", "analyze", "statics", "robots", "reach", "demo", "batch", "reachmap"])
    robot = _maybe(
        r,
        r.choice(ROBOTS),
        ["x" * 300, "nope", "", "erd:nope", "/", "a.xml", "tasks/panda_pose_reach.toml"],
        0.3,
    )
    extra = r.choice(
        [
            [],
            ["--q", "0.1"],
            ["--q", "nan", "0"],
            ["--q", "1e300", "0"],
            ["--frame", "nope"],
            ["--frame", "x" * 300],
            ["--frame-type", "body", "--frame", "link2"],
            ["--q", "inf", "inf"],
            ["--frame-type", "bogus"],
            ["--rows", "vx", "vy"],
            ["--rows", "zz"],
            ["--position-only"],
            ["--force", "0", "0", "-20"],
            ["--force", "nan", "0", "0"],
            ["--force", "1e308", "1e308", "0"],
            ["--torque", "1", "2"],
            ["--local"],
            ["--seed", "-1"],
            ["--seed", "x"],
            ["--robot", "nope"],
            ["--q", "0", "0", "0", "0", "0", "0", "0"],
        ]
    )
    return {
        "command": command,
        "robot": robot,
        "extra": extra,
        "reach_file": r.choice([p.name for p in _shipped_problems()]),
        "problem": gen_problem(r) if command == "reach" and r.random() < 0.6 else None,
        "targets": r.choice(
            ["good", "nan", "huge", "empty", "ragged_csv", "quat_zero", "not_npz", "missing"]
        ),
        "batch_args": r.choice(
            [
                [],
                ["--chunk-size", "0"],
                ["--chunk-size", "-1"],
                ["--tol-position", "nan"],
                ["--max-iters", "-1"],
                ["--restarts", "-1"],
                ["--time-budget", "inf"],
                ["--seed", "-1"],
                ["--workers", "0"],
                ["--max-chunks", "1"],
                ["--frame", "nope"],
            ]
        ),
        "region": r.choice(
            [
                ["0", "0", "0", "0.4", "0.4", "0.4"],
                ["0", "0", "0", "nan", "1", "1"],
                ["1", "1", "1", "0", "0", "0"],
                ["0", "0", "0", "1e300", "1e300", "1e300"],
                ["0", "0", "0", "0", "0", "0"],
            ]
        ),
        "resolution": r.choice(["0.2", "0.4", "0", "-1", "nan", "inf", "1e-9", "1e300"]),
        "orientations": r.choice(["0", "1", "2", "-1", "1000000000"]),
    }


def gen_determinism(r: random.Random) -> dict:
    base = r.choice(["solve", "step", "solve_many", "problem"])
    generator = {
        "solve": gen_solve,
        "step": gen_step,
        "solve_many": gen_solve_many,
        "problem": gen_problem,
    }[base]
    spec = generator(r)
    if base in ("solve", "solve_many"):  # valid most of the time, so there is a q to compare
        spec["robot"], spec["frame"], spec["targets"] = r.choice(ROBOTS), "ee", {"ee": None}
        spec["target"] = {"kind": r.choice(["reach", "reach_pose"]), "q_seed": r.randrange(10**6)}
        spec["options"].pop("time_budget", None)
        spec["options"].pop("restarts", None)
        spec["options"]["restarts"] = r.choice([0, 2])
        # same seed, same answer: seed=None is documented as fresh entropy
        spec["options"]["seed"] = r.randrange(2**32)
        if "many" in spec:
            spec["many"]["seed"] = r.randrange(2**32)
    pollution = [
        {"category": c, "spec": GENERATORS[c](random.Random(r.randrange(10**9)))}
        for c in r.sample(["solve", "step", "problem", "statics", "analysis"], 2)
    ]
    return {"base": base, "spec": spec, "pollution": pollution}


# -- the compiled boundary (qpik._engine): odd arrays into the entry points that end there
#: What an array argument is turned into: dtype, layout, shape, values, read-only, ...
ARRAY_MUTATIONS = (
    "same",
    "float32",
    "float16",
    "int64",
    "bool",
    "complex",
    "object",
    "big_endian",
    "fortran",
    "strided",
    "transposed",
    "zero_stride",
    "readonly",
    "nan",
    "inf",
    "neg_inf",
    "subnormal",
    "1e308",
    "empty",
    "extra_row",
    "missing_col",
    "ndim_up",
    "ndim_down",
    "scalar",
    "list",
    "none",
    "huge",
)
#: What a scalar argument is turned into.
SCALAR_MUTATIONS = (
    "same",
    "nan",
    "inf",
    "neg",
    "zero",
    "int_max",
    "int_overflow",
    "huge",
    "none",
    "str",
    "float_for_int",
)
BOUNDARY_ENTRIES = (
    "hierarchy",
    "chain_pose",
    "chain_jacobian",
    "chain_reach",
    "configuration",
    "task_target",
    "solve_q0",
    "solve_target",
)


def gen_boundary(r: random.Random) -> dict:
    """A public entry point that ends in the engine, with one or two odd arrays."""
    entry = r.choice(BOUNDARY_ENTRIES)
    spec: dict = {"entry": entry, "robot": r.choice(ROBOTS), "seed": r.randrange(10**6)}
    spec["mutations"] = [
        (r.randrange(8), r.choice(ARRAY_MUTATIONS)) for _ in range(r.choice([1, 1, 2]))
    ]
    if entry == "hierarchy":
        spec["n"] = r.choice([1, 2, 3, 7, 12])
        spec["rows"] = [r.choice([0, 1, 3, 6]) for _ in range(r.choice([1, 2, 3]))]
        spec["p"] = r.choice([0, 0, 2, 5])
        spec["solver"] = r.choice([None, "osqp", "daqp", "quadprog", "qpik"])
        spec["regularization"] = _maybe(r, 1e-6, [0.0, -1.0, NAN, INF, 1e300], 0.2)
    if entry == "task_target":
        spec["task"] = r.choice(["position", "orientation", "pose", "posture", "frame", "com"])
        spec["solver"] = r.choice(["osqp", "daqp", "quadprog"])
    return spec


def gen_engine(r: random.Random) -> dict:
    """A raw call of a ``qpik._engine`` kernel: arguments recorded from a valid solve, one
    or two of them mutated (``pick`` / ``arg`` index the sorted recorded calls and their
    arguments at run time)."""
    spec: dict = {"pick": r.randrange(10**6), "mutations": []}
    for _ in range(r.choice([1, 1, 1, 2, 3])):
        if r.random() < 0.15:
            spec["mutations"].append((r.randrange(64), "alias"))
        else:
            spec["mutations"].append(
                (r.randrange(64), r.choice(ARRAY_MUTATIONS), r.choice(SCALAR_MUTATIONS))
            )
    return spec


# -- robots generated on the fly (issue 25, item 2): odd inertias, zero-length links,
# meshes missing or degenerate, mimic joints, continuous / fixed-only / floating bases,
# reversed or equal limits, NaN / inf attributes, equality constraints, odd names; loaded
# through every public door (load_robot, a path in qpik.solve, a problem file, the CLI).
GEN_URDF_JOINTS = ("revolute", "revolute", "continuous", "prismatic", "fixed", "mimic", "planar")
GEN_MJCF_JOINTS = ("hinge", "hinge", "slide", "ball", "fixed", "hinge", "hinge")
GEN_INERTIAS = ("ok", "ok", "ok", "zero", "negative", "nonpd", "huge", "tiny", "none", "nan")
GEN_MASSES = ("1", "1", "1", "0", "-1", "1e30", "1e-12", "nan", "inf")
GEN_LENGTHS = (0.3, 0.3, 0.3, 0.0, 1e-12, 2.0, 1e3)
GEN_LIMITS = ("ok", "ok", "ok", "reversed", "equal", "nan", "inf", "missing", "huge")
GEN_MESHES = ("none", "none", "none", "missing", "empty", "degenerate", "tiny", "ascii")
GEN_AXES = ("0 0 1", "0 0 1", "0 1 0", "1 0 0", "0 0 0", "nan 0 0", "0 0 5", "1e300 0 0")
GEN_NAMES = ("plain", "plain", "plain", "space", "unicode", "long", "dup", "dots", "numeric")


def gen_robot_gen(r: random.Random) -> dict:
    fmt = r.choice(["urdf", "mjcf"])
    joints = GEN_URDF_JOINTS if fmt == "urdf" else GEN_MJCF_JOINTS
    fixed_only = r.random() < 0.05
    links = [
        {
            "joint": "fixed" if fixed_only else r.choice(joints),
            "length": r.choice(GEN_LENGTHS) if r.random() < 0.4 else 0.3,
            "mass": r.choice(GEN_MASSES) if r.random() < 0.3 else "1",
            "inertia": r.choice(GEN_INERTIAS) if r.random() < 0.4 else "ok",
            "limit": r.choice(GEN_LIMITS) if r.random() < 0.4 else "ok",
            "mesh": r.choice(GEN_MESHES) if r.random() < 0.3 else "none",
            "axis": r.choice(GEN_AXES) if r.random() < 0.2 else "0 0 1",
            "mimic": r.choice(["1", "-2", "0", "nan", "1e300"]),
            "velocity": r.choice(["1", "1", "0", "-1", "nan", "1e300"]),
            "effort": r.choice(["10", "10", "0", "-5", "inf"]),
        }
        for _ in range(r.choice([1, 2, 3, 4, 5]))
    ]
    return {
        "format": fmt,
        "links": links,
        "base": r.choices(["fixed", "free", "floating_base"], [6, 1, 1])[0],
        "names": r.choice(GEN_NAMES),
        "equality": r.choice(["none", "none", "joint", "connect", "weld", "inactive", "bad"]),
        "entry": r.choice(["load", "load", "load", "problem", "solve_path", "cli"]),
        "q": r.choice(["mid", "random", "qpos0"]),
        "seed": r.randrange(10**6),
    }


# -- problem files written from every field of the schema (qpik/problem/*.py): a valid
# base per robot and mode, then one field set to a valid, boundary or invalid value.
#: (path, [(tag, value), ...]); tag: "v" valid, "b" boundary (valid), "x" invalid. Symbolic
#: values ("@...") are resolved against the model when the file is written.
_BAD_TYPES = [("x", "a"), ("x", True), ("x", [1.0]), ("x", {"a": 1})]


def _range_values(low, high, low_open, integer=False):
    step = (lambda v: v + 1) if integer else (lambda v: v * (1 + 1e-6) if v else 1e-300)
    down = (lambda v: v - 1) if integer else (lambda v: v * (1 - 1e-6) if v > 0 else -1e-300)
    out = [("x" if low_open else "b", low), ("b", high), ("x", down(low)), ("x", step(high))]
    if not integer:
        out += [("x", NAN), ("x", INF), ("x", -INF)]
    else:
        out += [("x", 1.5), ("x", 2**70)]
    return out + [("x", "a"), ("x", True)]


SCHEMA_SOLVER = {
    "tol_position": (1e-12, 1e3, False, False),
    "tol_orientation": (1e-12, math.pi, False, False),
    "max_iters": (1, 100_000, False, True),
    "restarts": (0, 100_000, False, True),
    "seed": (0, 2**63 - 1, False, True),
    "time_budget": (0.0, 86_400.0, True, False),
    "alpha": (0.0, 1.0, True, False),
    "beta": (0.0, 100.0, True, False),
    "singular_threshold": (0.0, 1e3, False, False),
    "max_damping": (0.0, 1e6, False, False),
    "lower_trust": (0.0, 1.0, False, False),
    "damping": (0.0, 1e6, False, False),
    "stall_window": (1, 100_000, False, True),
}
SCHEMA_SOLVE_ONLY = {"max_iters", "restarts", "time_budget", "alpha", "beta", "max_step", "seed"}
SCHEMA_SOLVE_ONLY |= {"stall_window"}
_POS = [("v", [0.3, 0.1, 0.2]), ("b", [1e6, 0.0, 0.0]), ("x", [1.01e6, 0.0, 0.0])]
_POS += [("x", [NAN, 0.0, 0.0]), ("x", [INF, 0.0, 0.0]), ("x", [1.0, 2.0]), ("x", "a")]
_POS += [("x", [[1.0, 2.0, 3.0]]), ("x", ["a", 0.0, 0.0]), ("x", [True, 0.0, 0.0])]
_RPY = [("v", [0.0, 0.0, 0.0]), ("b", [100.0, 0.0, 0.0]), ("x", [100.5, 0.0, 0.0])]
_RPY += [("x", [NAN, 0.0, 0.0]), ("x", [0.0, 0.0]), ("x", "a")]
_QUAT = [("v", [1.0, 0.0, 0.0, 0.0]), ("x", [0.0, 0.0, 0.0, 0.0]), ("x", [NAN, 0.0, 0.0, 1.0])]
_QUAT += [("x", [1.0, 0.0, 0.0]), ("b", [2.0, 0.0, 0.0, 0.0]), ("b", [1e308, 1e308, 0.0, 0.0])]
_MAT = [
    ("v", [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]),
    ("x", [[2.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]),
]
_MAT += [("x", [[1.0, 0], [0, 1.0]]), ("x", [[NAN, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])]
_MAT += [("x", [[-1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])]
_COST3 = [("v", 0.0), ("v", [1.0, 1.0, 0.0]), ("b", 1e6), ("x", 1.01e6), ("x", -1.0)]
_COST3 += [("x", NAN), ("x", INF), ("x", [1.0, 2.0]), ("x", "a"), ("x", [1.0, 1.0, -1.0])]
_GAIN = [("v", 0.5), ("b", 1.0), ("x", 0.0), ("x", 1.0000001), ("x", -0.1), ("x", NAN)]
_GAIN += [("x", "a"), ("x", True)]
_LMD = [("b", 0.0), ("b", 1e6), ("x", 1.01e6), ("x", -1.0), ("x", NAN), ("x", "a")]
_FT = [("v", "site"), ("x", "bogus"), ("x", 3), ("x", "SITE ")]
_FRAME = [("v", "ee"), ("x", "nope"), ("x", 3), ("x", ""), ("x", ["ee"])]
_VEC3 = [("v", [0.0, 0.0, -10.0]), ("b", [1e9, 0.0, 0.0]), ("x", [1.01e9, 0.0, 0.0])]
_VEC3 += [("x", [NAN, 0.0, 0.0]), ("x", [1.0]), ("x", "a")]
_Q = [("v", "mid"), ("v", "qpos0"), ("b", "@q_lower"), ("b", "@q_upper"), ("x", "@q_outside")]
_Q += [("x", "@q_nan"), ("x", "@q_short"), ("x", "@q_long"), ("x", "nokey"), ("x", 3)]
_Q += [("x", "@q_inf"), ("x", "@q_str")]
_TASK_TYPES = ("frame", "position", "orientation", "posture", "joint_limit_distance")
_TASK_TYPES += ("manipulability", "damping", "com")

SCHEMA_FIELDS: list[tuple[tuple, list]] = [
    (("name",), [("v", "n"), ("b", ""), ("x", 3), ("x", ["a"])]),
    (("description",), [("v", "d"), ("b", "x" * 10000), ("x", 1.5)]),
    (("robot",), [("x", "nope"), ("x", 3), ("x", ""), ("x", "missing.xml"), ("x", ["panda"])]),
    # True: valid where the robot's one root body has no joint yet (panda, ur5e), refused
    # naming floating_base where it has one (the planar arms): run_schema decides
    (("floating_base",), [("v", False), ("x", True), ("x", "yes"), ("x", 1)]),
    (("q0",), _Q),
    (("mode",), [("x", "x"), ("x", 1), ("x", "SOLVE")]),
    (("bogus_key",), [("x", 1)]),
    (("levels",), [("x", []), ("x", [[]]), ("x", "a"), ("x", [1]), ("x", [{"tasks": []}])]),
    (("levels", 0, "tasks", 0, "type"), [("x", "nope"), ("x", 3), ("v", "position")]),
    (("levels", 0, "tasks", 0), [("v", "@task:" + t) for t in _TASK_TYPES]),
    (("levels", 0, "tasks", 0, "frame"), _FRAME),
    (("levels", 0, "tasks", 0, "frame_type"), _FT),
    (("levels", 0, "tasks", 0, "cost"), _COST3),
    (("levels", 0, "tasks", 0, "gain"), _GAIN),
    (("levels", 0, "tasks", 0, "lm_damping"), _LMD),
    (("levels", 0, "tasks", 0, "bogus"), [("x", 1)]),
    (("levels", 0, "tasks", 0, "target", "position"), _POS),
    (("levels", 0, "tasks", 0, "target", "bogus"), [("x", 1)]),
    (("levels", 0, "name"), [("v", "reach"), ("x", 3)]),
    (("levels", 1, "tasks", 0, "cost"), [("v", 0.0), ("b", 1e6), ("x", -1.0), ("x", "@nv_short")]),
    # a posture target may lie outside the limits (the limits keep q inside)
    (
        ("levels", 1, "tasks", 0, "target", "q"),
        [(t if v != "@q_outside" else "b", v) for t, v in _Q],
    ),
    (("levels", 1, "tasks", 0), [("v", "@task:" + t) for t in _TASK_TYPES] + [("x", 3)]),
    (("levels", 1, "tasks", 0, "rows"), [("x", "nonsense"), ("x", 3)]),
    (("levels", 2), [("v", "@task:" + t) for t in _TASK_TYPES]),
    (("target", "frame"), _FRAME),
    (("target", "frame_type"), _FT),
    (("target", "position"), _POS),
    (("target", "rpy"), _RPY),
    (("target", "quaternion"), _QUAT),
    (("target", "matrix"), _MAT),
    (("target", "bogus"), [("x", 1)]),
    (("target",), [("x", 3), ("x", {}), ("x", "@both")]),
    (("waypoints",), [("v", "@waypoints"), ("x", []), ("x", "a"), ("x", [3]), ("x", "@frames")]),
    (("limits", "position"), [("v", True), ("v", False), ("x", "yes"), ("x", 1)]),
    (("limits", "velocity"), [("v", False), ("v", 1.0), ("v", 0.5), ("x", 0.0)]),
    (("limits", "velocity"), [("x", -1.0), ("x", NAN), ("x", "@nv_short"), ("v", "@nv_ones")]),
    (("limits", "velocity"), [("v", "@velocity_table"), ("x", "@velocity_table_short")]),
    (("limits", "velocity"), [("x", "@velocity_table_nan"), ("x", "a"), ("x", [-1.0])]),
    (("limits", "support"), [("v", {"frames": ["ee"]}), ("x", {"frames": []}), ("x", 3)]),
    # (1 m is within the field's range, but no robot's support polygon holds it at the
    # start: the loader refuses it, naming the field, as it must)
    (
        ("limits", "support", "margin"),
        [("b", 0.0), ("x", 1.0), ("x", 1.1), ("x", -0.1), ("x", NAN)],
    ),
    (("limits", "support", "footprint"), [("v", [[0.1, 0.1], [-0.1, 0.1], [0.0, -0.1]])]),
    (("limits", "support", "footprint"), [("x", []), ("x", [[1.0]]), ("x", [[NAN, 0.0]])]),
    (("limits", "support", "frame_type"), _FT),
    (("limits", "collision"), [("v", {}), ("v", {"self": True}), ("x", {"bogus": 1}), ("x", 3)]),
    (("limits", "collision", "min_distance"), [("b", 0.0), ("v", 0.01), ("x", -1.0), ("x", NAN)]),
    (("limits", "collision", "detection_distance"), [("v", 0.1), ("x", -1.0), ("x", INF)]),
    (("limits", "collision", "gain"), _GAIN),
    (("limits", "collision", "pairs"), [("x", [[["nope"], ["ball"]]]), ("x", 3), ("x", [])]),
    (("limits", "bogus"), [("x", 1)]),
    (("solver", "preset"), [("v", "default"), ("v", "tracking"), ("v", "fast"), ("x", "nope")]),
    (("solver", "solver"), [("v", "osqp"), ("v", "daqp"), ("v", "quadprog"), ("x", "nope")]),
    (("solver", "adaptive_damping"), [("v", True), ("v", False), ("x", 1)]),
    (("solver", "max_step"), [("v", [0.2, 0.5]), ("v", False), ("x", [0.0, 1.0]), ("x", [1.0])]),
    (("solver", "max_step"), [("x", "a"), ("x", [NAN, 1.0]), ("x", True), ("b", [1e6, 1e6])]),
    (("solver", "bogus"), [("x", 1)]),
    (("solver",), [("x", 3)]),
    (("track", "dt"), _range_values(1e-9, 1e3, False)),
    (("track", "steps"), _range_values(1, 1_000_000, False, True)),
    (("track", "stop_at_goal"), [("v", True), ("x", "yes")]),
    (("track", "bogus"), [("x", 1)]),
    (("statics", "frame"), _FRAME),
    # frame_type without frame: refused (it would be ignored)
    (("statics", "frame_type"), [("x", "site"), ("x", "bogus"), ("x", 3)]),
    (("statics", "force"), _VEC3),
    (("statics", "torque"), _VEC3),
    (("statics", "payload_direction"), [("v", [0.0, 0.0, -1.0]), ("x", [0.0, 0.0, 0.0])]),
    (("statics", "payload_direction"), [("x", [NAN, 0.0, 1.0]), ("x", [1e308, 1e308, 0.0])]),
    (("statics", "bogus"), [("x", 1)]),
    (
        ("obstacles",),
        [("v", "@obstacle:sphere"), ("v", "@obstacle:box"), ("v", "@obstacle:capsule")],
    ),
    (("obstacles",), [("x", "@obstacle:cone"), ("x", 3), ("x", [3]), ("x", "@obstacle:dup")]),
    (
        ("obstacles", 0, "size"),
        [("x", [-1.0]), ("x", [0.0]), ("x", [1.0, 2.0, 3.0, 4.0]), ("x", "a")],
    ),
    (("obstacles", 0, "position"), [("x", [NAN, 0.0, 0.0]), ("b", [1e6, 0.0, 0.0]), ("x", "a")]),
    (("obstacles", 0, "bogus"), [("x", 1)]),
]
SCHEMA_FIELDS += [(("solver", k), _range_values(*v)) for k, v in SCHEMA_SOLVER.items()]


def gen_schema(r: random.Random) -> dict:
    path, values = r.choice(SCHEMA_FIELDS)
    tag, value = r.choice(values)
    mode = r.choice(["solve", "solve", "track"])
    return {
        "robot": r.choice(ROBOTS),
        "mode": mode,
        "path": list(path),
        "tag": tag,
        "value": value,
        "goal": r.choice(["target", "target", "waypoints"]),
        "seed": r.randrange(10**6),
        "cli": r.random() < 0.3,
    }


# -- every task and limit type (qpik's and mink's) at every priority level
STACK_TASKS = TASKS[:-1] + (
    "mink_frame",
    "mink_posture",
    "mink_com",
    "mink_damping",
    "mink_relative",
    "mink_kinetic",
    "mink_freeze",
    "mink_look_at",
    "coupling",
)
STACK_LIMITS = (
    "config",
    "mink_config",
    "velocity",
    "mink_velocity",
    "joint_limits",
    "collision",
    "mink_collision",
    "support",
    "free_velocity",
    "ball",
)
STACK_DT = (1e-9, 1e6, 9.999e-10, 1.000001e6, 0.01, 0.01, 1.0, 1e-3)


def gen_stack(r: random.Random) -> dict:
    n_levels = r.choice([1, 2, 3, 4, 5])
    tasks = []
    for _ in range(r.choice([1, 2, 3, 4, 5, 6])):
        kind = r.choice(STACK_TASKS)
        task = {"type": kind}
        if kind == "coupling":  # the model's couplings (floaty: a joint equality)
            task.update(cost=r.choice([1.0, 0.0, 10.0]), gain=r.choice([1.0, 0.5, 0.0]))
        while not kind.startswith("mink") and kind != "coupling":
            task = _task(r)  # until one of this kind, with no wrong-type argument
            if task["type"] == kind and "wrong" not in task:
                break
        task.setdefault("target", r.choice(["reach", "start", "far", "none", "nan"]))
        task["level"] = r.randrange(n_levels)
        tasks.append(task)
    limits = []
    for _ in range(r.choice([0, 1, 2, 3, 4])):
        limits.append(
            [
                r.choice(STACK_LIMITS),
                r.choice([0.95, 0.5, 1.0, 0.1, 0.0]),
                r.choice([0.0, 0.0, 0.01, 0.1, 10.0]),
            ]
        )
    return {
        "robot": r.choice(ROBOTS + ("floaty", "floaty")),
        "levels": n_levels,
        "tasks": tasks,
        "limits": limits,
        "constraints": r.choice([[], [], ["freeze"], ["posture"]]),
        "dt": r.choice(STACK_DT),
        "q": r.choice(["mid", "random", "random", "inside_tiny", "outside"]),
        "steps": r.choice([1, 1, 2, 3]),
        "entry": r.choice(["step", "step", "solve_ik", "build_ik"]),
        "solver": r.choice(["auto", "osqp", "daqp", "quadprog"]),
    }


# -- example-robot-data robots (issue 25, item 2: many robots): humanoids, quadrupeds,
# hands, mobile manipulators, with mimic joints and equality constraints; targets for
# one to four of their bodies at once, reached by qpik.solve, IKSolver.step, a problem
# file (several frames per goal) and statics, judged by MuJoCo's forward kinematics.
ERD_NAMES = (
    "talos", "talos_full", "talos_arm", "talos_reduced", "romeo", "romeo_small", "icub",
    "icub_reduced", "g1_29dof_rev_1_0", "g1_29dof_with_hand_rev_1_0", "tiago", "tiago_pro",
    "tiago_no_hand", "pr2", "baxter", "panda", "panda_collision", "ur5", "ur10_robot",
    "ur3_gripper", "kinova", "xarm7", "z1", "so100", "so101", "allegro_left_hand",
    "alex_psyonic_hands", "anymal", "anymal-kinova", "go1", "go2", "b1-z1", "solo12",
    "bolt", "hyq_no_sensors", "simple_humanoid", "human", "centauro", "double_pendulum",
    "double_pendulum_continuous", "finger_edu", "iris_simple", "quadrotor_base",
    "borinot_flying_arm_2", "TwoDofs", "laikago", "quadruped", "alexander_v1.lowerBodyOnly",
)  # fmt: skip
ERD_ENTRIES = ("solve", "solve", "solve", "step", "step", "problem", "problem", "exercise")


def gen_erd(r: random.Random) -> dict:
    n_frames = r.choice([1, 1, 2, 2, 3, 4])
    return {
        "robot": r.choice(ERD_NAMES),
        "floating": r.random() < 0.3,
        "frames": [r.randrange(10**6) for _ in range(n_frames)],
        "rotation": [r.random() < 0.4 for _ in range(n_frames)],
        "offset": r.choice([0.0, 0.0, 0.0, 0.02, 0.3, 5.0]),
        "q0": r.choice(["mid", "mid", "random", "qpos0", "robot", "keyframe"]),
        "entry": r.choice(ERD_ENTRIES),
        "restarts": r.choice([0, 0, 1]),
        "max_iters": r.choice([10, 30, 60]),
        "solver": r.choice(["auto", "auto", "osqp", "daqp", "quadprog"]),
        "dt": r.choice([0.01, 0.01, 1.0, 1e-9, 1e6, 0.1]),
        "steps": r.choice([1, 2, 5]),
        "mode": r.choice(["solve", "track"]),
        "support": r.random() < 0.2,
        "velocity": r.choice([None, None, 0.5, 1.0]),
        "seed": r.randrange(10**6),
    }


# -- wrong types for every argument of every public function (by its signature)
SIGNATURE_TARGETS = (
    (
        "qpik.solve",
        "qpik.solve_many",
        "qpik.reachability",
        "qpik.load_robot",
        "qpik.load_problem",
        "qpik.frame_names",
        "qpik.joint_names",
        "qpik.Configuration",
        "qpik.IKSolver",
        "IKSolver.step",
        "qpik.IKSession",
        "IKSession.solve",
        "qpik.solve_ik",
        "qpik.build_ik",
        "qpik.DampingLaw",
        "qpik.SolveOptions",
        "qpik.StepOptions",
        "Configuration.frame_pose",
        "Configuration.frame_jacobian",
        "Configuration.integrate",
        "Configuration.integrate_inplace",
        "Configuration.update",
        "Configuration.check_limits",
        "Configuration.within_limits",
        "Problem.solve",
        "qpik.analysis.orientation_error",
        "qpik.tasks.CouplingTask",
        "qpik.tasks.EqualityConstraintTask",
        "qpik.limits.BallJointLimit",
        "qpik.limits.velocity_limit_from_model",
        "qpik.limits.limited_ball_joints",
        "qpik.limits.collision_geoms",
        "qpik.limits.geom_distance",
    )
    + tuple(
        f"qpik.analysis.{n}"
        for n in (
            "analyze",
            "condition_number",
            "damped_pseudoinverse",
            "degree_of_redundancy",
            "joint_limit_distance",
            "joint_limit_distance_gradient",
            "manipulability",
            "manipulability_gradient",
            "null_space",
            "nullspace_step",
            "pseudoinverse",
            "rank",
            "self_motion",
            "singular_values",
            "singularity",
            "solution_set",
        )
    )
    + tuple(
        f"qpik.statics.{n}"
        for n in (
            "force_ellipsoid",
            "gravity_torques",
            "holding_torques",
            "joint_torque_limits",
            "joint_torques",
            "max_payload",
            "wrench_from_torques",
        )
    )
    + tuple(
        f"qpik.plots.{n}"
        for n in (
            "is_planar",
            "joint_curves",
            "plot_joints",
            "plot_planar_arm",
            "plot_robot",
            "plot_singular_values",
            "robot_segments",
            "plot_level_errors",
        )
    )
    + tuple(
        f"qpik.tasks.{n}"
        for n in (
            "AxisAlignTask",
            "ComTask",
            "DampingTask",
            "DofFreezingTask",
            "FrameTask",
            "JointLimitDistanceTask",
            "KineticEnergyRegularizationTask",
            "LookAtTask",
            "ManipulabilityTask",
            "OrientationTask",
            "PoseTask",
            "PositionTask",
            "PostureTask",
            "RelativeFrameTask",
        )
    )
    + tuple(
        f"qpik.limits.{n}"
        for n in (
            "ConfigurationLimit",
            "VelocityLimit",
            "SupportPolygonLimit",
            "joint_limits",
            "model_collision_limit",
            "CollisionAvoidanceLimit",
            "collision_pairs",
            "always_in_contact",
        )
    )
)
#: Wrong values for any argument: (label, how to make it; made in the worker).
SIGNATURE_VALUES = (
    "none",
    "str",
    "bytes",
    "dict",
    "mjmodel",
    "nested",
    "int_array",
    "bool_array",
    "complex_array",
    "object_array",
    "array_3d",
    "array_0d",
    "empty_array",
    "bool",
    "huge_int",
    "neg_int",
    "nan",
    "inf",
    "object",
    "configuration",
    "lambda",
    "set",
    "str_array",
)


def gen_signature(r: random.Random) -> dict:
    return {
        "target": r.choice(SIGNATURE_TARGETS),
        "robot": r.choice(["planar_2r", "planar_4r", "panda"]),
        "pick": r.randrange(10**6),
        "value": r.choice(SIGNATURE_VALUES),
        "positional": r.random() < 0.3,
    }


# -- attributes changed after the build (stale state): a stack as gen_stack's, stepped once
# by IKSolver.step, then one to three attributes of its tasks and limits assigned directly
# (valid and not: a new cost, gain, frame, subtree, target, a position limit's narrowed
# bounds in place or anew, a velocity limit's speeds, ...), and stepped again. The oracle:
# a new IKSolver built from the same (changed) objects, stepped at the same configuration,
# gives the same outcome (both a typed error, or both answers within 1e-9): the solver that
# stepped before keeps nothing of what the change made stale.
def gen_mutate(r: random.Random) -> dict:
    spec = gen_stack(r)
    spec.update(entry=r.choice(["step", "step", "solve_ik"]), steps=1)
    spec["dt"] = r.choice([0.01, 0.01, 1e-3, 1.0])
    spec["q"] = r.choice(["mid", "random", "random"])
    for task in spec["tasks"]:  # (a stack that answers: the changes are what is under test)
        task["target"] = r.choice(["reach", "start"])
        for key in ("cost", "gain", "lm_damping", "wrong"):
            task.pop(key, None)
        if task["type"] == "coupling":
            task.update(cost=1.0, gain=1.0)
    spec["limits"] = [[kind, r.choice([0.95, 0.5, 1.0]), 0.0] for kind, *_ in spec["limits"]]
    spec["mutations"] = [
        (r.randrange(10**6), r.randrange(10**6), r.randrange(10**6), r.random() < 0.3)
        for _ in range(r.choice([1, 1, 2, 3]))
    ]
    # a solver setting changed too (IKSolver.damping / .damping_law: the settable ones)
    spec["setting"] = r.choice(
        [
            None,
            None,
            ["damping", r.choice([0.0, 1e-3, 1.0, -1.0, "x", NAN])],
            ["damping_law", r.choice(["none", "strong", "x"])],
        ]
    )
    return spec


GENERATORS = {
    "solve": gen_solve,
    "solve_many": gen_solve_many,
    "step": gen_step,
    "problem": gen_problem,
    "robot_file": gen_robot_file,
    "statics": gen_statics,
    "analysis": gen_analysis,
    "cli": gen_cli,
    "determinism": gen_determinism,
    "boundary": gen_boundary,
    "engine": gen_engine,
    "robot_gen": gen_robot_gen,
    "schema": gen_schema,
    "stack": gen_stack,
    "signature": gen_signature,
    "erd": gen_erd,
    "mutate": gen_mutate,
}


def make_spec(seed: int, category: str, index: int) -> dict:
    r = random.Random(f"{seed}:{category}:{index}")
    return GENERATORS[category](r)


# =============================================================================== execution
# Everything below runs in a worker (imports qpik lazily).
class Bad(Exception):
    """An invariant broken by a returned value: ``kind`` is one of BAD."""

    def __init__(self, kind: str, detail: str):
        super().__init__(f"{kind}: {detail}")
        self.kind = kind
        self.detail = detail


def _np():
    import numpy as np

    return np


# Complexity above 10: one branch per kind of (malformed) input this generator draws.
def _finite(value, where: str, allow=()) -> None:
    """Raise Bad('nonfinite') if any number reachable from ``value`` is NaN / inf."""
    np = _np()
    import dataclasses
    import enum

    if any(where.endswith(a) for a in allow):
        return
    # documented +inf: a level without singular values (sigma_min), a direction the
    # structure holds (ForceEllipsoid.lengths), no joint limit binding (PayloadLimit.force)
    # and the payload's interval (PayloadLimit.interval: unbounded where no limit binds)
    payload = where.endswith(("returned.force", ".lengths")) or ".interval[" in where
    if ".sigma_min" in where or payload:
        values = np.asarray(value, dtype=float)
        lower_end = ".interval[0]" in where  # unbounded below: -inf
        if np.any(np.isnan(values)) or (np.any(values == -np.inf) and not lower_end):
            raise Bad("nonfinite", f"{where} = {value}")
        return
    if isinstance(value, (bool, str, bytes, type(None), enum.Enum)):
        return
    if isinstance(value, (int, float, np.integer, np.floating)):
        if not math.isfinite(float(value)):
            raise Bad("nonfinite", f"{where} = {value}")
        return
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "fc" and not np.all(np.isfinite(value)):
            raise Bad("nonfinite", f"{where} has non-finite entries: {value.ravel()[:8]}")
        return
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        status = getattr(value, "status", None)
        certificate = getattr(value, "certificate", None)
        for f in dataclasses.fields(value):
            item = getattr(value, f.name)
            if f.name == "certificate" and isinstance(status, list) and certificate:
                # documented: NaN for a level never reached (level 0 failed before it)
                item = [c for c, s in zip(certificate, status) if str(s) != "not_reached"]
            _finite(item, f"{where}.{f.name}", allow)
        return
    if isinstance(value, dict):
        for k, v in value.items():
            _finite(v, f"{where}[{k!r}]", allow)
        return
    if isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            _finite(v, f"{where}[{i}]", allow)


def _digest(*arrays) -> str:
    np = _np()
    h = hashlib.sha256()
    for a in arrays:
        h.update(repr(type(a)).encode())
        if isinstance(a, np.ndarray):
            h.update(np.ascontiguousarray(a).tobytes())
        else:
            h.update(repr(a).encode())
    return h.hexdigest()[:16]


def _seed_of(spec) -> int:
    return int(hashlib.sha256(repr(spec).encode()).hexdigest()[:8], 16)


def _model(name):
    import qpik

    return qpik.load_robot(name)


def _limits_of(model):
    """Lower / upper ``(nq,)`` of the limited scalar joints (inf elsewhere), read from the
    model directly (not from qpik)."""
    np = _np()
    import mujoco

    lower = np.full(model.nq, -np.inf)
    upper = np.full(model.nq, np.inf)
    for j in range(model.njnt):
        # int(): a NumPy integer never equals a mjtJoint member (the test was always False)
        if model.jnt_limited[j] and int(model.jnt_type[j]) in (
            int(mujoco.mjtJoint.mjJNT_HINGE),
            int(mujoco.mjtJoint.mjJNT_SLIDE),
        ):
            adr = model.jnt_qposadr[j]
            lower[adr], upper[adr] = model.jnt_range[j]
    return lower, upper


def _check_within(model, q, where: str, tol: float = 1e-9, widen: float = 0.0) -> None:
    """q within the model's joint limits to tol (relative) plus widen [rad or m]."""
    np = _np()
    lower, upper = _limits_of(model)
    over = np.maximum(lower - q, q - upper)
    span = np.maximum(1.0, np.abs(np.where(np.isfinite(lower), lower, 0.0)))
    bad = np.flatnonzero(over > tol * span + widen)
    if bad.size:
        i = int(bad[0])
        raise Bad("limits", f"{where}[{i}] = {q[i]!r} outside [{lower[i]!r}, {upper[i]!r}]")


def _fk(model, q, frame: str, frame_type: str = "site"):
    """World position and rotation of a frame by MuJoCo on a fresh MjData."""
    _np()
    import mujoco

    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    obj = {
        "site": mujoco.mjtObj.mjOBJ_SITE,
        "body": mujoco.mjtObj.mjOBJ_BODY,
        "geom": mujoco.mjtObj.mjOBJ_GEOM,
    }[frame_type]
    i = mujoco.mj_name2id(model, obj, frame)
    if frame_type == "site":
        return data.site_xpos[i].copy(), data.site_xmat[i].reshape(3, 3).copy()
    if frame_type == "geom":
        return data.geom_xpos[i].copy(), data.geom_xmat[i].reshape(3, 3).copy()
    return data.xpos[i].copy(), data.xmat[i].reshape(3, 3).copy()


def _angle(r1, r2) -> float:
    """The angle [rad] of ``r1 r2^T``, both first projected onto SO(3) (an SVD), from
    MuJoCo's quaternion of it: ``2 atan2(|xyz|, |w|)`` (accurate near 0, unlike an
    ``acos`` of the trace)."""
    np = _np()
    import mujoco

    def project(r):
        u, _, vt = np.linalg.svd(np.asarray(r, dtype=float))
        return u @ vt

    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(project(r1) @ project(r2).T).ravel())
    return float(2.0 * math.atan2(float(np.linalg.norm(quat[1:])), abs(float(quat[0]))))


# Complexity above 10: one branch per kind of (malformed) input this generator draws.
def _q_value(kind, model, rng):
    np = _np()
    lower, upper = _limits_of(model)
    lo = np.where(np.isfinite(lower), lower, -np.pi)
    hi = np.where(np.isfinite(upper), upper, np.pi)
    if kind is None:
        return None
    if kind == "mid":
        return 0.5 * (lo + hi)
    if kind == "random":
        return rng.uniform(lo, hi)
    if kind == "outside_tiny":  # within check_limits' 1e-6 tolerance, outside the limit
        q = 0.5 * (lo + hi)
        q[0] = hi[0] + 5e-7
        return q
    if kind == "inside_tiny":
        q = 0.5 * (lo + hi)
        q[0] = hi[0] - 1e-12
        return q
    if kind == "outside":
        q = 0.5 * (lo + hi)
        q[-1] = hi[-1] + 0.5
        return q
    if kind == "at_lower":
        return lo.copy()
    if kind == "at_upper":
        return hi.copy()
    if kind == "nan":
        q = 0.5 * (lo + hi)
        q[0] = np.nan
        return q
    if kind == "short":
        return (0.5 * (lo + hi))[:-1]
    if kind == "strings":
        return ["a"] * model.nq
    if kind == "huge":
        return np.full(model.nq, 1e300)
    raise ValueError(kind)


def _weird_law(value):
    import qpik

    if value == "default":
        return ...
    if value is None:
        return None
    return qpik.DampingLaw(value[1], value[2])


def _make_limits(model, value):
    import qpik

    if value in ("joint", None, "bogus", []):
        return value
    kind, x = value
    if kind == "config_gain":
        return [qpik.limits.ConfigurationLimit(model, gain=x)]
    if kind == "config_dist":
        return [qpik.limits.ConfigurationLimit(model, min_distance_from_limits=x)]
    names = qpik.joint_names(model)
    return [
        qpik.limits.ConfigurationLimit(model),
        qpik.limits.VelocityLimit(model, {n: x for n in names}),
    ]


def _solve_target(spec_target: dict, model, rng, frame: str = "ee"):
    np = _np()
    kind = spec_target["kind"]
    local = np.random.default_rng(spec_target["q_seed"])
    if kind == "raw":
        return spec_target["value"]
    q = _q_value("random", model, local)
    position, rotation = _fk(model, q, frame)
    if kind == "reach":
        return position
    if kind == "reach_pose":
        return (position, rotation)
    if kind == "far":
        return position * spec_target["scale"] + spec_target["scale"]
    if kind == "se3":
        import mink

        return mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), position)
    matrix = np.eye(4)
    matrix[:3, :3] = rotation + spec_target["perturb"]
    matrix[:3, 3] = position
    return matrix


def _target_frame_name(frame) -> str | None:
    if isinstance(frame, str):
        return frame
    if isinstance(frame, tuple) and len(frame) == 2 and isinstance(frame[0], str):
        return frame[0]
    return None


def _solve_kwargs(spec: dict, model, rng) -> dict:
    o = dict(spec["options"])
    if "damping_law" in o:
        law = _weird_law(o["damping_law"])
        if law is ...:
            del o["damping_law"]
        else:
            o["damping_law"] = law
    if o.get("max_step") == "default":
        del o["max_step"]
    if "limits" in o:
        o["limits"] = _make_limits(model, o["limits"])
    if o.get("seed") == "rng":
        o["seed"] = _np().random.default_rng(5)
    q0 = _q_value(spec["q0"], model, rng)
    if q0 is not None:
        o["q0"] = q0
    return o


# Complexity above 10: one branch per variant of the case it runs and checks.
def _frame_kind(model, frame_key) -> tuple[str, str]:
    """``(name, "site" | "body" | "geom")`` of a target's frame key, as qpik resolves a
    bare name (a site first, then a body, then a geom)."""
    import mujoco

    name = _target_frame_name(frame_key)
    kind = frame_key[1] if isinstance(frame_key, tuple) else None
    if kind is None:
        kind = (
            "site"
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name) >= 0
            else (
                "body" if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) >= 0 else "geom"
            )
        )
    return str(name), str(getattr(kind, "value", kind))


def _fk_errors(model, q, name: str, kind: str, position, rotation) -> tuple[float, float]:
    """Position [m] and orientation [rad] errors of a frame at ``q`` by MuJoCo's forward
    kinematics on a fresh MjData (0 rad without a rotation target)."""
    np = _np()
    at, r = _fk(model, q, name, kind)
    error = float(np.linalg.norm(at - np.asarray(position, dtype=float)))
    return error, (0.0 if rotation is None else _angle(r, np.asarray(rotation, dtype=float)))


def _check_reported(where: str, reported: tuple, measured: tuple) -> None:
    """Bad('misreport') when a reported ``(position, orientation)`` error is off the
    forward kinematics' one: by more than 1e-6 * max(1 m, the error), or 1e-6 rad."""
    (p, o), (fp, fo) = (float(reported[0]), float(reported[1])), measured
    if not abs(p - fp) <= 1e-6 * max(1.0, fp):
        raise Bad("misreport", f"{where} position error {p!r} but FK says {fp!r}")
    if not abs(o - fo) <= 1e-6:
        raise Bad("misreport", f"{where} orientation error {o!r} but FK says {fo!r}")


def _check_claim(where: str, measured: tuple, tol_p: float, tol_o: float) -> None:
    """Bad('claim') when a converged result's FK errors exceed the tolerances."""
    error, angle = measured
    if not error <= tol_p * (1 + 1e-9) + 1e-15:
        raise Bad("claim", f"{where} converged with position error {error:.3g} > {tol_p}")
    if not angle <= tol_o * (1 + 1e-6) + 1e-9:
        raise Bad("claim", f"{where} converged with orientation error {angle:.3g} > {tol_o}")


def _ik_result_q(result, model, where: str):
    """The ``q`` of an IKResult, after the checks every IKResult passes: its type, the
    shape of ``q`` and finite fields."""
    np = _np()
    import qpik

    if not isinstance(result, qpik.IKResult):
        raise Bad("untyped", f"{where} is a {type(result).__name__}, not an IKResult")
    q = np.asarray(result.q)
    if q.shape != (model.nq,):
        raise Bad("untyped", f"{where}.q has shape {q.shape}")
    _finite(result, where)
    return q


def _check_ik_result(result, model, frame_key, target, kwargs, where="result") -> str:
    """Invariants of an IKResult; returns its digest."""
    from qpik.igm.session import parse_target

    q = _ik_result_q(result, model, where)
    limits = kwargs.get("limits", "joint")
    if limits == "joint" or (isinstance(limits, list) and limits):
        _check_within(model, q, f"{where}.q")
    name, kind = _frame_kind(model, frame_key)
    t = parse_target(target)
    measured = _fk_errors(model, q, name, kind, t.position, t.rotation)
    _check_reported(where, (result.position_error, result.orientation_error), measured)
    for key, reported in result.frame_errors.items():
        _check_reported(f"{where}.frame_errors[{key!r}]", reported, measured)
    if result.converged:
        tol_p = kwargs.get("tol_position", 1e-4)
        tol_o = kwargs.get("tol_orientation", 1e-3)
        _check_claim(where, measured, tol_p, tol_o)
    return _digest(q, result.converged, result.iterations, result.reason)


def run_solve(spec: dict) -> str:
    np = _np()
    import qpik

    rng = np.random.default_rng(_seed_of(spec))
    try:
        model = _model(spec["robot"])
    except qpik.QpikError:
        raise
    except TypeError as exc:
        if spec["robot"] is None or isinstance(spec["robot"], int):
            raise Typed(str(exc)) from None  # load_robot documents a TypeError for non-names
        raise
    target = _solve_target(spec["target"], model, rng)
    frame = spec["frame"]
    targets = {
        "empty": {},
        "none": None,
        "list": [target],
        "two_frames": {frame: target, ("link2", "body"): [0.0, 0.0, 0.0]},
        "bad_key": {frame: target, frame if isinstance(frame, str) else "ee": target},
    }.get(spec["targets"] if isinstance(spec["targets"], str) else "", {frame: target})
    kwargs = _solve_kwargs(spec, model, rng)
    result = qpik.solve(spec["robot"], targets, **kwargs)
    if not isinstance(targets, dict) or len(targets) != 1:
        _finite(result, "result")
        return _digest(np.asarray(result.q))
    # One entry: the frame asked for (two keys naming one frame leave the last target).
    frame, target = next(iter(targets.items()))
    return _check_ik_result(result, model, frame, target, kwargs)


def run_solve_many(spec: dict) -> str:
    np = _np()
    import qpik

    model = _model(spec["robot"]) if isinstance(spec["robot"], str) else None
    if model is None:
        raise Typed("robot is not a name")
    rng = np.random.default_rng(_seed_of(spec))
    kwargs = _solve_kwargs(spec, model, rng)
    kwargs.pop("seed", None)  # solve_many's own seed spawns one per target
    targets = [
        _solve_target(dict(spec["target"], q_seed=spec["target"]["q_seed"] + i), model, rng)
        for i in range(spec["count"])
    ]
    batch = [{spec["frame"]: t} for t in targets]
    solve_many = qpik.solve_many
    results = solve_many(spec["robot"], batch, **spec["many"], **kwargs)
    if len(results) != len(batch):
        raise Bad("untyped", f"{len(results)} results for {len(batch)} targets")
    digests = [
        _check_ik_result(res, model, spec["frame"], t, kwargs, f"results[{i}]")
        for i, (res, t) in enumerate(zip(results, targets))
    ]
    return _digest(*digests)


class Typed(Exception):
    """A documented non-qpik error of the harness' own making (counted as typed)."""


# Complexity above 10: one branch per kind of (malformed) input this generator draws.
def _build_task(task: dict, model, configuration, rng):
    np = _np()
    import mink

    import qpik
    from qpik import tasks as T

    kind = task["type"]
    o = {k: task[k] for k in ("cost", "gain", "lm_damping") if k in task}
    frame = task.get("frame", "ee")
    ftype = "site"
    if isinstance(frame, tuple):
        frame, ftype = frame
    target = task["target"]
    ctor_model = model  # what the constructors get (the harness keeps the real one)
    valid = (frame, ftype)  # the frame the harness's own targets are computed at
    if "wrong" in task:  # one argument of the constructor of a wrong type
        arg, index = task["wrong"]
        value = WRONG_TYPES[index]
        if arg == "frame":
            frame = value
        elif arg == "frame_type":
            ftype = value
        elif arg == "model":
            ctor_model = value
        else:
            o[arg] = value
    if kind in ("pose", "relative_frame", "kinetic_energy", "dof_freezing") or kind in (
        "axis_align",
        "look_at",
        "equality",
    ):
        return _build_more_task(
            task, kind, o, (frame, valid), ftype, model, ctor_model, configuration, rng
        )
    if kind == "frame":
        o = {("position_cost" if k == "cost" else k): v for k, v in o.items()}
        t = T.FrameTask(frame, ftype, **{"position_cost": 1.0, "orientation_cost": 1.0, **o})
    elif kind == "position":
        t = T.PositionTask(frame, ftype, **o)
    elif kind == "orientation":
        t = T.OrientationTask(frame, ftype, **o)
    elif kind == "posture":
        t = T.PostureTask(ctor_model, **{"cost": 1.0, **o})
    elif kind == "damping":
        o.pop("gain", None)
        o.pop("lm_damping", None)
        t = T.DampingTask(ctor_model, **{"cost": 1.0, **o})
    elif kind == "manipulability":
        o.pop("lm_damping", None)
        t = T.ManipulabilityTask(frame, ftype, rows=task["rows"], **o)
        return t
    elif kind == "joint_limit_distance":
        t = T.JointLimitDistanceTask(**o)
        return t
    else:
        t = T.ComTask(**{"cost": 1.0, **o})
    if target == "none":
        return t
    q = _q_value("random", model, rng)
    if kind in ("frame", "position", "orientation"):
        if target == "start":
            t.set_target_from_configuration(configuration)
            return t
        position, rotation = (
            _fk(model, q, *valid)
            if target == "reach"
            else (
                (np.full(3, 1e300), np.eye(3))
                if target == "far"
                else (np.full(3, np.nan), np.eye(3))
            )
        )
        if kind == "frame":
            t.set_target(
                mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), position)
            )
        elif kind == "position":
            t.set_target(position)
        else:
            t.set_target(rotation)
    elif kind == "posture":
        value = {
            "reach": q,
            "start": configuration.q,
            "far": np.full(model.nq, 1e300),
            "nan": np.full(model.nq, np.nan),
        }[target]
        t.set_target(value)
    elif kind == "com":
        value = {
            "reach": np.array([0.1, 0.0, 0.3]),
            "start": None,
            "far": np.full(3, 1e300),
            "nan": np.full(3, np.nan),
        }[target]
        if value is None:
            t.set_target_from_configuration(configuration)
        else:
            t.set_target(value)
    del qpik
    return t


# Complexity above 10: one branch per kind of task.
def _build_more_task(task, kind, o, frame, ftype, model, ctor_model, configuration, rng):
    """The task kinds beyond the first eight: every task type of ``qpik.tasks``. ``frame``
    is ``(the constructor's frame, (the valid frame, its type) the harness's own targets use)``."""
    np = _np()
    frame, valid = frame
    import mink
    import mujoco

    from qpik import tasks as T

    target = task["target"]
    if kind == "kinetic_energy":
        t = T.KineticEnergyRegularizationTask(cost=o.get("cost", 1.0))
        if task["dt"] != "unset":
            t.set_dt(task["dt"])
        return t
    if kind == "dof_freezing":
        return T.DofFreezingTask(ctor_model, dof_indices=task["dofs"], **{"gain": 1.0, **o})
    if kind == "equality":  # no bundled robot has equalities: a typed refusal
        return T.EqualityConstraintTask(ctor_model, cost=o.get("cost", 1.0))
    if kind in ("axis_align", "look_at"):
        cls = T.AxisAlignTask if kind == "axis_align" else T.LookAtTask
        t = cls(frame, ftype, axis=task["axis"], **o)
        if target == "start":
            t.set_target_from_configuration(configuration)
        elif target != "none":
            value = {"reach": [0.0, 0.0, 1.0], "far": [1e300, 0.0, 0.0], "nan": [NAN] * 3}
            t.set_target(np.array(value[target]))
        return t
    o = {("position_cost" if k == "cost" else k): v for k, v in o.items()}
    o = {"position_cost": 1.0, "orientation_cost": 1.0, **o}
    if kind == "relative_frame":
        root = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, 1) if model is not None else "x"
        t = T.RelativeFrameTask(frame, ftype, root, "body", **o)
    else:
        t = T.PoseTask(frame, ftype, **o)
    if target == "none":
        return t
    if target == "start":
        t.set_target_from_configuration(configuration)
        return t
    q = _q_value("random", model, rng)
    position, rotation = (
        _fk(model, q, *valid)
        if target == "reach"
        else ((np.full(3, 1e300), np.eye(3)) if target == "far" else (np.full(3, NAN), np.eye(3)))
    )
    if kind == "relative_frame":
        if target == "nan":
            t.set_target(np.full(7, NAN))  # not an SE3: InvalidTarget
        else:
            t.set_target(
                mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), position)
            )
    else:
        t.set_target(position, rotation)
    return t


# Complexity above 10: one branch per variant of the case it runs and checks.
def run_step(spec: dict) -> str:
    np = _np()
    import qpik

    model = _model(spec["robot"])
    rng = np.random.default_rng(_seed_of(spec))
    q = _q_value(spec["q"], model, rng)
    configuration = qpik.Configuration(model, q)
    levels = spec["levels"]
    if isinstance(levels, list):
        levels = [
            [_build_task(t, model, configuration, rng) for t in level]
            if isinstance(level, list)
            else level
            for level in levels
        ]
    limits = []
    velocity_limit = None
    for kind, x in spec["limits"]:
        if kind == "config":
            limits.append(qpik.limits.ConfigurationLimit(model, gain=x))
        elif kind == "config_dist":
            limits.append(qpik.limits.ConfigurationLimit(model, min_distance_from_limits=x))
        elif kind == "joint_limits":
            limits.extend(qpik.limits.joint_limits(model, x))
        elif kind == "collision":
            limits.append(qpik.limits.model_collision_limit(model, gain=x))
        elif kind == "support":
            limits.append(qpik.limits.SupportPolygonLimit(model, [("ee", "site")], margin=x))
        elif kind == "wrong":
            limits.append(WRONG_TYPES[x])
        else:
            limits.append(qpik.limits.VelocityLimit(model, {n: x for n in qpik.joint_names(model)}))
            velocity_limit = x
    has_config = any(k in ("config", "config_dist", "joint_limits") for k, _ in spec["limits"])
    start_inside = bool(np.all(np.isfinite(configuration.q))) and configuration.within_limits(0.0)
    law = _weird_law(spec["damping_law"])
    options = {"solver": spec["solver"], "damping": spec["damping"]}
    dt = spec["dt"]
    digests = []
    if spec["entry"] == "solve_ik":
        velocity = qpik.solve_ik(configuration, levels, dt, limits=limits, **options)
        steps_v = [np.asarray(velocity)]
        _finite(steps_v[0], "velocity")
    else:
        if law is not ...:
            options["damping_law"] = law
        solver = qpik.IKSolver(model, levels, limits, **options)
        steps_v = []
        for k in range(spec["steps"]):
            result = solver.step(configuration, dt)
            _finite(result, f"step[{k}]", allow=(".solve_time",))
            steps_v.append(np.asarray(result.velocity))
            if k + 1 < spec["steps"]:
                configuration.integrate_inplace(result.velocity, dt)
    for k, v in enumerate(steps_v):
        if v.shape != (model.nv,):
            raise Bad("untyped", f"velocity shape {v.shape}")
        if velocity_limit is not None and math.isfinite(velocity_limit) and velocity_limit > 0:
            if np.max(np.abs(v)) > velocity_limit * (1 + 1e-6) + 1e-12:
                raise Bad("limits", f"step {k}: |v| = {np.max(np.abs(v))} > {velocity_limit}")
        digests.append(v)
    if has_config and start_inside and spec["entry"] == "step" and spec["steps"] == 1:
        q_next = configuration.integrate(steps_v[0], dt)
        _finite(q_next, "q after the step")
        # a negative min_distance_from_limits widens the limits by as much (mink's meaning)
        widened = max([-x for k, x in spec["limits"] if k == "config_dist"] + [0.0])
        _check_within(model, q_next, "q after the step", tol=1e-7, widen=widened)
    return _digest(*digests)


# -- problem files
# Complexity above 10: one branch per kind of (malformed) input this generator draws.
def _toml_value(value) -> str:
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
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()) + "}"
    if value is None:
        return '"None"'
    return _toml_value(repr(value))


def _toml_key(key) -> str:
    key = str(key)
    return key if key and all(c.isalnum() or c in "_-" for c in key) else _toml_value(key)


def to_toml(data: dict) -> str:
    """A TOML text of ``data`` (inline tables; enough for the fuzzer's mutations)."""
    return "".join(f"{_toml_key(k)} = {_toml_value(v)}\n" for k, v in data.items())


def _set_path(data, path, value) -> None:
    node = data
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value


# Complexity above 10: one branch per kind of (malformed) input this generator draws.
def _special(data: dict, name: str, value, r: random.Random) -> None:
    levels = data.get("levels") or [{"tasks": [{}]}]
    first = levels[0]["tasks"][0] if isinstance(levels[0], dict) and levels[0].get("tasks") else {}
    solver = data.setdefault("solver", {}) if isinstance(data.get("solver", {}), dict) else {}
    if name == "lm_damping":
        first["lm_damping"] = r.choice([-1.0, NAN, INF, 1e300, 0.0, 1e-3])
    elif name == "max_damping":
        solver["max_damping"] = r.choice([NAN, -1.0, INF, 1e300, 0.0])
    elif name == "singular_threshold":
        solver["singular_threshold"] = r.choice([NAN, -1.0, INF, 1e300, 0.0])
    elif name == "cost":
        first[r.choice(["cost", "position_cost", "orientation_cost"])] = r.choice(
            [1e300, 1e200, 1e-300, INF, [1e300, 1.0, 1.0]]
        )
    elif name == "q0_key":
        data["q0"] = r.choice(["home", "", "keyframe0", "mid", "qpos0", "start"])
    elif name == "q0_outside":
        data["q0"] = r.choice(["outside", "outside_tiny"])
    elif name == "robot":
        data["robot"] = r.choice(
            [
                "x" * 300,
                "nope",
                "",
                "erd:nope",
                "../robots/panda.xml",
                "/etc/passwd",
                "a" * 5000 + ".xml",
                "erd:panda",
            ]
        )
    elif name == "steps":
        track = data.setdefault("track", {})
        if isinstance(track, dict):  # an earlier edit may have made it a scalar
            track["steps"] = r.choice([10**9, 0, -1, 10**20, 3])
    elif name == "velocity":
        _table(data, "limits")["velocity"] = r.choice(
            [1e-300, 1e300, INF, NAN, -1.0, 0.0, [1e-300] * 7, {"nope": 1.0}, 5e-324]
        )
    elif name == "time_budget":
        solver["time_budget"] = r.choice([INF, NAN, 1e300, 1e-300, 0.0])
    elif name == "seed":
        solver["seed"] = r.choice([-1, 2**62, 0])
    elif name == "dt":
        _table(data, "track")["dt"] = r.choice([INF, NAN, 1e300, 1e-300, 5e-324])
    elif name == "tol":
        solver[r.choice(["tol_position", "tol_orientation"])] = r.choice([1e-300, 1e300, INF, NAN])
    elif name == "statics":
        data["statics"] = {
            r.choice(["force", "torque", "payload_direction"]): r.choice(
                [[1e300, 1e300, 1e300], [NAN, 0, 0], [1e-300, 0, 0], [1e308, 1e308, 1e308]]
            )
        }
    elif name == "max_step":
        solver["max_step"] = r.choice([[1e300, 1e300], [0.0, 0.0], [-1.0, 1.0], [1e-300, 1.0]])
    elif name == "unnamed_key":
        data["q0"] = "home"
        data["robot"] = "unnamed_key"
    if isinstance(data.get("solver"), dict) and not data["solver"]:
        del data["solver"]


_UNNAMED_KEY_XML = """<mujoco model="unnamed_key">
  <compiler angle="radian"/>
  <worldbody>
    <body name="l1"><joint name="j1" type="hinge" axis="0 0 1" range="-3 3"/>
      <geom type="capsule" fromto="0 0 0 1 0 0" size="0.05"/>
      <body name="l2" pos="1 0 0"><joint name="j2" type="hinge" axis="0 0 1" range="-3 3"/>
        <geom type="capsule" fromto="0 0 0 1 0 0" size="0.05"/>
        <site name="ee" pos="1 0 0"/>
      </body>
    </body>
  </worldbody>
  <keyframe>
    <key qpos="0.5 0.5"/>
    <key name="home" qpos="1.0 -1.0"/>
  </keyframe>
</mujoco>
"""


# Complexity above 10: one branch per kind of (malformed) input this generator draws.
def write_problem(spec: dict, folder: Path) -> Path:
    """The (mutated) problem file of a spec, written into ``folder``."""
    import tomllib

    source = ROOT / "tasks" / spec["file"]
    path = folder / f"fuzz_{spec['file']}"
    r = random.Random(repr(spec))
    if spec["raw"] is not None:
        text = source.read_bytes()
        raw = spec["raw"]
        if raw == "deep_array":
            data = b"x = " + b"[" * 3000 + b"]" * 3000 + b"\n"
        elif raw == "deep_table":
            data = b"x = " + b"{a = " * 3000 + b"1" + b"}" * 3000 + b"\n"
        elif raw == "non_utf8":
            data = text.replace(b"robot", b"rob\xff\xfeot", 1)
        elif raw == "truncate":
            data = text[: r.randrange(len(text))]
        elif raw == "empty":
            data = b""
        elif raw == "bom":
            data = b"\xef\xbb\xbf" + text
        elif raw == "flip_bytes":
            data = bytearray(text)
            for _ in range(3):
                data[r.randrange(len(data))] = r.randrange(256)
            data = bytes(data)
        else:
            data = b'name = "' + b"a" * 2_000_000 + b'"\n' + text
        path.write_bytes(data)
        return path
    data = tomllib.loads(source.read_text())
    (folder / "unnamed_key.xml").write_text(_UNNAMED_KEY_XML)
    for mutation in spec["mutations"]:
        paths = list(_leaf_paths(data))
        op = mutation["op"]
        pick = paths[mutation["pick"] % len(paths)] if paths else None
        if op == "set" and pick:
            _set_path(data, pick, mutation["value"])
        elif op == "scale" and pick:  # a plausible edit: a number (or numbers) scaled
            node = data
            for k in pick[:-1]:
                node = node[k]
            value = node[pick[-1]]
            factor = mutation.get("factor", 2.0)
            if isinstance(value, bool) or isinstance(value, str):
                pass
            elif isinstance(value, (int, float)):
                node[pick[-1]] = (
                    type(value)(value * factor)
                    if isinstance(value, float)
                    else (max(0, int(value * factor)) if abs(value * factor) < 2**62 else value)
                )
            elif isinstance(value, list) and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value
            ):
                node[pick[-1]] = [float(v) * factor for v in value]
        elif op == "delete" and pick:
            node = data
            for k in pick[:-1]:
                node = node[k]
            del node[pick[-1]]
        elif op == "add":
            data[r.choice(["bogus", "solver", "limits", "track"])] = mutation["value"]
        else:
            _special(data, mutation["special"], mutation["value"], r)
    robot = data.get("robot")
    if robot == "unnamed_key":
        data["robot"] = "unnamed_key.xml"
        _fix_for_unnamed(data)
    elif isinstance(robot, str) and robot.startswith("../"):
        data["robot"] = str(ROOT / "robots" / Path(robot).name)
    if data.get("q0") in ("outside", "outside_tiny"):
        data["q0"] = _outside_q0(data, data["q0"])
    text = to_toml(data)
    path.write_text(text)
    return path


def _fix_for_unnamed(data: dict) -> None:
    data["levels"] = [{"tasks": [{"type": "position", "frame": "ee"}]}]
    data["target"] = {"position": [1.0, 1.0, 0.0]}
    data.pop("waypoints", None)
    data.pop("statics", None)
    data["mode"] = "solve"
    data.pop("track", None)
    data["limits"] = {"position": True}
    data.pop("solver", None)


def _outside_q0(data: dict, how: str):
    import qpik

    robot = data.get("robot")
    try:
        model = qpik.load_robot(robot)
    except Exception:
        return "mid"
    q = _q_value(how, model, None)
    return [float(x) for x in q]


# Complexity above 10: one branch per variant of the case it runs and checks.
def run_problem(spec: dict) -> str:
    _np()
    import qpik

    with tempfile.TemporaryDirectory() as folder:
        path = write_problem(spec, Path(folder))
        problem = qpik.load_problem(path)
        digests = [_digest(problem.q0)]
        _finite(problem.q0, "problem.q0")
        if problem.position_limits:
            _check_within(problem.model, problem.q0, "problem.q0", tol=0.0)
        o = problem.options
        work = (
            problem.steps * len(problem.goals)
            if problem.mode == "track"
            else (o.get("restarts", 20) + 1) * o.get("max_iters", 100) * len(problem.goals)
        )
        if spec["solve"] and work <= 6000:
            result = problem.solve()
            _finite(result.q, "result.q")
            _finite(
                result.to_dict(),
                "result.to_dict()",
                allow=("['solve_time']", "['step_time_mean']", "['step_time_max']"),
            )
            if problem.position_limits:
                _check_within(problem.model, result.q, "result.q")
                for i, q in enumerate(result.path):
                    _check_within(problem.model, q, f"result.path[{i}]")
            if problem.velocity_limits is not None and result.trace is not None:
                ratio = result.trace.max_velocity_ratio
                if ratio > 1 + 1e-6:
                    raise Bad("limits", f"max |v| / v_max = {ratio}")
            _check_problem_claim(problem, result)
            digests.append(_digest(result.q, result.converged))
        if spec["cli"] and work <= 6000:
            code, out, err = _cli(["reach", str(path), "--quiet"])
            _cli_check(code, err, (0, 1, 2))
    return _digest(*digests)


def _check_problem_claim(problem, result) -> None:
    """Every reported error of a problem's result against forward kinematics of the
    configuration it belongs to (every frame of every goal), and a claim of convergence
    against the tolerances."""
    tol_p = problem.solve_options.tol_position  # the preset's, or the file's own
    tol_o = problem.solve_options.tol_orientation

    def measure(goal, q) -> dict:
        return {
            f.frame: _fk_errors(
                problem.model, q, f.frame, f.frame_type.value, f.target.position, f.target.rotation
            )
            for f in goal.frames
        }

    def worst(errors: dict) -> tuple[float, float]:
        return max(p for p, _ in errors.values()), max(o for _, o in errors.values())

    if result.trace is not None:
        trace = result.trace
        for i, q in enumerate(trace.q):
            goal = problem.goals[int(trace.goal_index[i - 1]) if i else 0]
            reported = (trace.position_error[i], trace.orientation_error[i])
            _check_reported(f"trace[{i}]", reported, worst(measure(goal, q)))
        checks = [(problem.goals[-1], trace.q[-1])] if result.converged else []
    else:
        for k, (goal, r) in enumerate(zip(problem.goals, result.results)):
            errors = measure(goal, r.q)
            _check_reported(f"results[{k}]", (r.position_error, r.orientation_error), worst(errors))
            for frame, reported in r.frame_errors.items():
                if frame in errors:
                    where = f"results[{k}].frame_errors[{frame!r}]"
                    _check_reported(where, reported, errors[frame])
            if r.converged:
                _check_claim(f"results[{k}]", worst(errors), tol_p, tol_o)
        checks = list(zip(problem.goals, [r.q for r in result.results])) if result.converged else []
    for goal, q in checks:
        _check_claim("problem", worst(measure(goal, q)), tol_p, tol_o)


# -- CLI
def _cli(argv: list[str]) -> tuple[int, str, str]:
    from qpik.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse's usage errors
            code = exc.code if isinstance(exc.code, int) else 2
    return code, out.getvalue(), err.getvalue()


def _cli_check(code, err: str, allowed) -> None:
    if "Traceback" in err:
        raise Bad("untyped", f"traceback printed: {err[-300:]!r}")
    if code not in allowed:
        raise Bad("untyped", f"exit code {code!r}; stderr {err[-300:]!r}")
    if "nan" in err.lower().split() or " nan " in err:
        pass


# Complexity above 10: one branch per variant of the case it runs and checks.
def run_cli(spec: dict) -> str:
    command = spec["command"]
    if command == "robots":
        argv = ["robots"]
    elif command == "demo":
        argv = ["demo"] + [
            a for a in spec["extra"] if a.startswith("--seed") or a == "-1" or a == "x"
        ][:2]
        if any(a == "--robot" for a in spec["extra"]):
            argv += ["--robot", "nope"]
        argv += ["--robot", spec["robot"]] if spec["robot"] in ROBOTS else []
    elif command in ("batch", "reachmap"):
        return _run_cli_batch(spec)
    elif command == "reach":
        if spec["problem"] is not None:
            with tempfile.TemporaryDirectory() as folder:
                path = write_problem(spec["problem"], Path(folder))
                code, out, err = _cli(["reach", str(path), "--quiet"])
                _cli_check(code, err, (0, 1, 2))
                return _digest(code)
        argv = ["reach", str(ROOT / "tasks" / spec["reach_file"]), "--quiet"]
    else:
        argv = [command, spec["robot"]] + spec["extra"]
        if command == "statics" and "--force" not in argv:
            argv += ["--force", "0", "0", "-10"]
    code, out, err = _cli(argv)
    _cli_check(code, err, (0, 1, 2))
    for token in out.replace("[", " ").replace("]", " ").split():
        if token.lower() in ("nan", "-nan"):
            raise Bad("nonfinite", f"qpik {' '.join(argv)[:80]} printed nan")
    return _digest(code, out if command not in ("reach", "demo") else "")


def _targets_file(kind: str, folder: Path) -> Path:
    np = _np()
    if kind == "missing":
        return folder / "missing.npz"
    if kind == "not_npz":
        path = folder / "t.npz"
        path.write_bytes(b"not a zip file")
        return path
    if kind == "ragged_csv":
        path = folder / "t.csv"
        path.write_text("x,y,z\n0.3,0.1\n0.3,0.1,0.4,9\nnan,a,1\n")
        return path
    positions = {
        "good": np.array([[0.3, 0.1, 0.4], [0.4, -0.1, 0.3]]),
        "nan": np.array([[np.nan, 0.1, 0.4]]),
        "huge": np.array([[1e300, 0.0, 0.0]]),
        "empty": np.zeros((0, 3)),
        "quat_zero": np.array([[0.3, 0.1, 0.4]]),
    }[kind]
    path = folder / "t.npz"
    if kind == "quat_zero":
        np.savez(path, positions=positions, quaternions=np.zeros((1, 4)))
    else:
        np.savez(path, positions=positions)
    return path


def _run_cli_batch(spec: dict) -> str:
    """``qpik batch`` / ``qpik reachmap`` on small (or malformed) inputs, one worker."""
    robot = spec["robot"] if spec["robot"] in ROBOTS else "planar_2r"
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        if spec["command"] == "batch":
            argv = [
                "batch",
                str(_targets_file(spec["targets"], folder)),
                "--robot",
                robot,
                "--frame",
                "ee",
                "--out",
                str(folder / "out.npz"),
                "--workers",
                "1",
                "--quiet",
                "--restarts",
                "1",
                *spec["batch_args"],
            ]
            allowed = (0, 1, 2, 3)
        else:
            argv = [
                "reachmap",
                robot,
                "--frame",
                "ee",
                "--region",
                *spec["region"],
                "--resolution",
                spec["resolution"],
                "--orientations",
                spec["orientations"],
                "--out",
                str(folder / "map.npz"),
                "--workers",
                "1",
                "--quiet",
                "--restarts",
                "0",
            ]
            allowed = (0, 1, 2)
        code, out, err = _cli(argv)
        _cli_check(code, err, allowed)
        return _digest(code)


# -- robot files
# Complexity above 10: one branch per kind of (malformed) input this generator draws.
def _mjcf(spec: dict, r: random.Random) -> str:
    types = [
        {"continuous": "hinge", "fixed": "hinge", "floating": "free", "planar": "slide"}.get(t, t)
        for t in spec["joint_types"]
    ]
    attrs = defaultdict(dict)
    for m in spec["mutations"]:
        attrs[m["pick"] % max(1, len(types))][m["what"]] = m["value"]
    bodies = []
    for i, t in enumerate(types):
        a = attrs[i]
        joint = f'<joint name="{a.get("name", f"j{i}")}" type="{t}"'
        if t in ("hinge", "slide"):
            joint += f' axis="{a.get("axis", "0 0 1")}"'
            if r.random() < 0.7:
                joint += f' range="{a.get("range", "-2 2")}" limited="true"'
        if "damping" in a:
            joint += f' damping="{a["damping"]}"'
        if "armature" in a:
            joint += f' armature="{a["armature"]}"'
        joint += "/>"
        if t == "free" and i > 0:
            joint = ""
        geom = f'<geom type="capsule" fromto="0 0 0 0.3 0 0" size="{a.get("size", "0.03")}"'
        if "mass" in a:
            geom += f' mass="{a["mass"]}"'
        geom += "/>"
        extra = "<bogus/>" if "unknown_tag" in a else ""
        if "mesh" in a:
            extra += '<geom type="mesh" mesh="m0"/>'
        inertial = ""
        if "inertia" in a:
            inertial = f'<inertial pos="0 0 0" mass="1" diaginertia="{a["inertia"]}"/>'
        quat = f' quat="{a["quat"]}"' if "quat" in a else ""
        bodies.append(
            f'<body name="b{i}" pos="{a.get("pos", "0.3 0 0" if i else "0 0 0")}"{quat}>'
            f"{joint}{geom}{inertial}{extra}"
        )
    site = '<site name="ee" pos="0.3 0 0"/>'
    body_text = "".join(bodies) + site + "</body>" * len(bodies)
    if not bodies:
        body_text = '<body name="b0"><geom type="sphere" size="0.1"/>' + site + "</body>"
    if spec["raw"] == "deep":
        body_text = (
            "".join(
                f'<body name="d{k}" pos="0 0 0.01"><joint type="hinge"/><geom size="0.01"/>'
                for k in range(400)
            )
            + site
            + "</body>" * 400
        )
    g = next((m["value"] for m in spec["mutations"] if m["what"] == "gravity"), "0 0 -9.81")
    ts = next((m["value"] for m in spec["mutations"] if m["what"] == "timestep"), "0.002")
    asset = (
        '<asset><mesh name="m0" file="nope.stl"/></asset>'
        if any(m["what"] == "mesh" for m in spec["mutations"])
        else ""
    )
    actuator = ""
    if any(m["what"] in ("actuator", "ctrlrange", "effort") for m in spec["mutations"]) and types:
        cr = next((m["value"] for m in spec["mutations"] if m["what"] == "ctrlrange"), "-1 1")
        actuator = (
            f'<actuator><motor joint="j0" gear="{r.choice(["1", "nan", "1e300"])}" '
            f'ctrlrange="{cr}" ctrllimited="true"/></actuator>'
        )
    key = ""
    if any(m["what"] == "keyframe" for m in spec["mutations"]):
        key = '<keyframe><key qpos="nan"/></keyframe>'
    return (
        f'<mujoco model="fuzz"><option gravity="{g}" timestep="{ts}"/>{asset}'
        f"<worldbody>{body_text}</worldbody>{actuator}{key}</mujoco>"
    )


# Complexity above 10: one branch per kind of (malformed) input this generator draws.
def _urdf(spec: dict, r: random.Random) -> str:
    types = [
        {"hinge": "revolute", "slide": "prismatic", "ball": "spherical", "free": "floating"}.get(
            t, t
        )
        for t in spec["joint_types"]
    ]
    attrs = defaultdict(dict)
    for m in spec["mutations"]:
        attrs[m["pick"] % max(1, len(types))][m["what"]] = m["value"]
    links = ['<link name="base"/>']
    joints = []
    for i, t in enumerate(types):
        a = attrs[i]
        inertial = (
            f'<inertial><origin xyz="0 0 0"/><mass value="{a.get("mass", "1")}"/>'
            f'<inertia ixx="{a.get("inertia", "0.01")}" iyy="0.01" izz="0.01" ixy="0" '
            'ixz="0" iyz="0"/></inertial>'
        )
        visual = ""
        if "mesh" in a:
            visual = '<visual><geometry><mesh filename="package://nope/m.stl"/></geometry></visual>'
        collision = (
            f'<collision><geometry><cylinder radius="{a.get("size", "0.03")}" '
            'length="0.3"/></geometry></collision>'
        )
        links.append(f'<link name="{a.get("name", f"l{i}")}">{inertial}{visual}{collision}</link>')
        parent = "base" if i == 0 else attrs[i - 1].get("name", f"l{i - 1}")
        limit = ""
        if t in ("revolute", "prismatic") or "limit" in a:
            lo, hi = (a.get("limit", "-2 2").split() + ["2", "2"])[:2]
            limit = (
                f'<limit lower="{lo}" upper="{hi}" effort="{a.get("effort", "10")}" '
                f'velocity="{a.get("velocity", "1")}"/>'
            )
        extra = "<bogus/>" if "unknown_tag" in a else ""
        dyn = f'<dynamics damping="{a["damping"]}"/>' if "damping" in a else ""
        origin = f'<origin xyz="{a.get("pos", "0.3 0 0" if i else "0 0 0")}" rpy="0 0 0"/>'
        if "drop_attr" in a:
            origin = "<origin/>"
        joints.append(
            f'<joint name="j{i}" type="{t}"><parent link="{parent}"/>'
            f'<child link="{a.get("name", f"l{i}")}"/>{origin}'
            f'<axis xyz="{a.get("axis", "0 0 1")}"/>'
            f"{limit}{dyn}{extra}</joint>"
        )
    if spec["raw"] == "deep":
        for k in range(300):
            parent = "base" if k == 0 else f"d{k - 1}"
            links.append(
                f'<link name="d{k}"><inertial><mass value="0.1"/><inertia ixx="0.001" '
                'iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial></link>'
            )
            joints.append(
                f'<joint name="dj{k}" type="continuous"><parent link="{parent}"/>'
                f'<child link="d{k}"/><origin xyz="0 0 0.01"/><axis xyz="0 0 1"/></joint>'
            )
    return f'<?xml version="1.0"?><robot name="fuzz">{"".join(links)}{"".join(joints)}</robot>'


def run_robot_file(spec: dict) -> str:
    _np()
    import qpik

    if spec["kind"] == "name":
        name = spec["name"]
        try:
            model = qpik.load_robot(name)
        except TypeError as exc:
            if not isinstance(name, (str, os.PathLike)):
                raise Typed(str(exc)) from None
            raise
        return _exercise_model(model)
    r = random.Random(spec["seed"])
    text = _mjcf(spec, r) if spec["kind"] == "mjcf" else _urdf(spec, r)
    data = text.encode()
    if spec["raw"] == "non_utf8":
        data = data.replace(b'name="', b'name="\xff\xfe', 1)
    elif spec["raw"] == "truncate":
        data = data[: r.randrange(1, len(data))]
    elif spec["raw"] == "bom":
        data = b"\xef\xbb\xbf" + data
    elif spec["raw"] == "doctype":
        data = (
            b'<?xml version="1.0"?><!DOCTYPE x [<!ENTITY a "aaaaaaaaaa">]>'
            + data.split(b"?>", 1)[-1]
        )
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / ("robot.xml" if spec["kind"] == "mjcf" else "robot.urdf")
        path.write_bytes(data)
        model = qpik.load_robot(path)
    return _exercise_model(model)


def _exercise_model(model) -> str:
    """FK, statics, a short solve and an IK step on a model that loaded."""
    np = _np()
    import mujoco

    import qpik

    configuration = qpik.Configuration(model)
    q = configuration.q
    _finite(q, "qpos0")
    digests = [_digest(model.nq, model.nv)]
    gravity = qpik.statics.gravity_torques(configuration)
    _finite(gravity, "gravity_torques")
    sites = qpik.frame_names(model, "site")
    frame = sites[0] if sites else None
    if frame is not None:
        position, rotation = configuration.frame_pose(frame, "site")
        _finite((position, rotation), "frame_pose")
        jac = configuration.frame_jacobian(frame, "site")
        _finite(jac, "frame_jacobian")
        tau = qpik.statics.joint_torques(configuration, frame, [0.0, 0.0, -10.0])
        _finite(tau, "joint_torques")
        if model.nv:
            mid = configuration.mid_q()
            rng = np.random.default_rng(0)
            target = configuration.frame_pose(frame, "site")[0]
            result = qpik.solve(model, {frame: target}, q0=mid, restarts=1, max_iters=30, seed=rng)
            _check_ik_result(result, model, frame, target, {})
            step = qpik.IKSolver(
                model,
                [[qpik.tasks.PositionTask(frame, "site")]],
                [qpik.limits.ConfigurationLimit(model)],
            )
            step.levels[0][0].set_target(target + 0.05)
            out = step.step(qpik.Configuration(model, mid), 0.01)
            _finite(out, "step", allow=(".solve_time",))
            digests.append(_digest(result.q, np.asarray(out.velocity)))
    del mujoco
    return _digest(*digests)


# -- statics
def run_statics(spec: dict) -> str:
    np = _np()
    import qpik
    from qpik import statics as S

    model = _model(spec["robot"])
    rng = np.random.default_rng(_seed_of(spec))
    configuration = qpik.Configuration(model, _q_value(spec["q"], model, rng))
    frame, kind = spec["frame"], spec["frame_type"]
    out = []
    allow = (".force", ".interval[0]", ".interval[1]", ".interval")
    out.append(
        S.joint_torques(
            configuration, frame, spec["force"], spec["torque"], kind, spec["expressed_in"]
        )
    )
    out.append(S.gravity_torques(configuration))
    wrenches = {
        "one": [((frame, kind), spec["force"], spec["torque"])],
        "none": [],
        "bad": [("x",)],
        "many": [((frame, kind), spec["force"], None)] * 3,
        "weird_frame": [(("nope", "site"), spec["force"], None)],
    }[spec["wrenches"]]
    out.append(S.holding_torques(configuration, wrenches, spec["gravity"]))
    tau = {
        "random": rng.normal(size=model.nv),
        "nan": np.full(model.nv, np.nan),
        "huge": np.full(model.nv, 1e300),
        "short": np.zeros(model.nv - 1),
        "zero": np.zeros(model.nv),
    }[spec["tau"]]
    out.append(S.wrench_from_torques(configuration, frame, tau, kind, spec["rcond"]))
    out.append(S.force_ellipsoid(configuration, frame, kind, spec["rows"], spec["rcond"]))
    out.append(S.joint_torque_limits(configuration))
    limits = None
    if spec["torque_limits"] is not None:
        base = np.column_stack([-np.ones(model.nv) * 50, np.ones(model.nv) * 50])
        limits = {
            "nan": np.full((model.nv, 2), np.nan),
            "reversed": base[:, ::-1].copy(),
            "zero": np.zeros((model.nv, 2)),
            "short": base[:-1],
            "huge": base * 1e300,
        }[spec["torque_limits"]]
    payload = S.max_payload(configuration, frame, spec["direction"], limits, kind, spec["gravity"])
    for i, value in enumerate(out):
        _finite(value, f"out[{i}]", allow=(".lengths",) if i == 4 else ())
    _finite(payload, "payload", allow=allow)
    _check_payload(payload, "payload")
    return _digest(*[np.asarray(x) if isinstance(x, np.ndarray) else repr(x) for x in out])


def _check_payload(payload, where: str) -> None:
    """A PayloadLimit as documented: ``force`` never NaN, ``>= 0`` (``+inf`` when no limit
    binds), ``0.0`` exactly when nothing ``>= 0`` can be held (``feasible`` false); the
    interval without NaN."""
    force, (s_min, s_max) = payload.force, payload.interval
    if math.isnan(force) or force < 0 or math.isnan(s_min) or math.isnan(s_max):
        raise Bad("nonfinite", f"{where} = {payload}")
    if payload.feasible != (s_min <= s_max and s_max >= 0) or (
        not payload.feasible and force != 0.0
    ):
        raise Bad("claim", f"{where}: feasible {payload.feasible} with {payload}")


# -- analysis
# Complexity above 10: one branch per kind of (malformed) input this generator draws.
def _matrix(spec: dict, rng):
    np = _np()
    m, n = spec["m"], spec["n"]
    J = rng.normal(size=(m, n))
    if spec["rank_drop"] and m and n:
        U, s, Vt = np.linalg.svd(J, full_matrices=False)
        s[-min(spec["rank_drop"], s.size) :] = 0.0
        J = (U * s) @ Vt
    J = J * spec["scale"]
    poison = spec["poison"]
    if poison == "nan" and J.size:
        J[0, 0] = np.nan
    elif poison == "inf" and J.size:
        J[-1, -1] = np.inf
    elif poison == "string":
        return [["a"] * max(n, 1)] * max(m, 1)
    elif poison == "ragged":
        return [[1.0, 2.0], [1.0]]
    elif poison == "1d":
        return J.ravel()
    elif poison == "3d":
        return J[None]
    elif poison == "none":
        return None
    elif poison == "bool":
        return J > 0
    elif poison == "complex":
        return J + 1j
    elif poison == "object":
        return np.array([[object()]])
    return J


# Complexity above 10: one branch per variant of the case it runs and checks.
def run_analysis(spec: dict) -> str:
    np = _np()
    import qpik
    from qpik import analysis as A

    rng = np.random.default_rng(spec["seed"])
    J = _matrix(spec, rng)
    shape = np.shape(J) if spec["poison"] not in ("string", "ragged", "none", "object") else (1, 1)
    m, n = (shape + (1, 1))[:2] if len(shape) >= 2 else (1, 1)
    xi = rng.normal(size=m) * spec["xi_scale"]
    outputs = {}
    which = rng.integers(0, 13)
    tol = spec["tol"]
    call = [
        lambda: A.singular_values(J),
        lambda: A.rank(J, tol),
        lambda: A.null_space(J, tol),
        lambda: A.degree_of_redundancy(J, tol),
        lambda: A.pseudoinverse(J, tol),
        lambda: A.damped_pseudoinverse(J, spec["damping"]),
        lambda: A.manipulability(J),
        lambda: A.condition_number(J),
        lambda: A.solution_set(J, xi, tol),
        lambda: A.singularity(J, tol if tol is not None else A.SINGULAR_TOL),
        lambda: A.nullspace_step(J, xi, rng.normal(size=n), tol=tol),
        None,
        None,
    ][int(which)]
    if call is not None:
        outputs["matrix"] = call()
        allow = ("condition_number", ".tol") if which == 7 else ()
        value = outputs["matrix"]
        if which == 7:
            if isinstance(value, float) and math.isnan(value):
                raise Bad("nonfinite", "condition_number is nan")
        elif which == 6:
            if isinstance(value, float) and math.isnan(value):
                raise Bad("nonfinite", "manipulability is nan")
        else:
            _finite(value, "matrix result", allow=allow)
        return _digest(repr(value)[:2000])
    model = _model(spec["robot"])
    configuration = qpik.Configuration(model, _q_value(spec["q"], model, rng))
    lower, upper = configuration.lower.copy(), configuration.upper.copy()
    limits = {
        "model": (lower, upper),
        "huge": (np.full(model.nq, -1e308), np.full(model.nq, 1e308)),
        "tiny": (np.full(model.nq, -1e-300), np.full(model.nq, 1e-300)),
        "nan": (np.full(model.nq, np.nan), upper),
        "reversed": (upper, lower),
        "inf": (np.full(model.nq, -np.inf), np.full(model.nq, np.inf)),
        "mixed": (np.r_[-1e308, lower[1:]], np.r_[1e-300, upper[1:]]),
    }[spec["limits"]]
    q = configuration.q if spec["limits"] != "huge" else np.full(model.nq, 1e308)
    if which == 11:
        outputs["w"] = A.joint_limit_distance(q, *limits)
        outputs["grad"] = A.joint_limit_distance_gradient(q, *limits)
        _finite(outputs, "joint_limit_distance")
    else:
        frame = spec["frame"]
        outputs["report"] = A.analyze(configuration, frame, "site", spec["rows"], tol=tol)
        outputs["grad"] = A.manipulability_gradient(configuration, frame, "site", spec["rows"])
        outputs["path"] = A.self_motion(
            configuration,
            frame,
            rng.normal(size=model.nv),
            spec["steps"],
            spec["step_size"],
            spec["rows"],
        )
        _finite(outputs, "analysis", allow=(".condition_number", ".manipulability"))
    return _digest(repr(outputs)[:5000])


# -- the compiled boundary
#: Inputs whose answer need not be finite (non-finite or overflowing values went in).
_NONFINITE_IN = {"nan", "inf", "neg_inf", "1e308", "huge"}


def _mutate_array(a, how: str):
    """``a`` (a float64 ndarray) turned into the odd argument ``how`` names."""
    np = _np()
    a = np.array(a, dtype=float)
    if how == "same":
        return a
    if how in ("float32", "float16", "int64", "bool", "complex"):
        return a.astype(how)
    if how == "object":
        return a.astype(object)
    if how == "big_endian":
        return a.astype(">f8")
    if how == "fortran":
        return np.asfortranarray(a)
    if how == "strided":  # a view of every other element of a bigger array
        big = np.zeros(tuple(2 * s for s in a.shape) or (), dtype=float)
        view = big[tuple(slice(None, None, 2) for _ in a.shape)] if a.ndim else big
        view[...] = a
        return view
    if how == "transposed":
        return a.T
    if how == "zero_stride":
        return np.broadcast_to(a.ravel()[0] if a.size else 0.0, a.shape)
    if how == "readonly":
        a.setflags(write=False)
        return a
    if how in ("nan", "inf", "neg_inf", "subnormal", "1e308"):
        value = {"nan": np.nan, "inf": np.inf, "neg_inf": -np.inf, "subnormal": 5e-324}.get(
            how, 1e308
        )
        if a.size:
            a.flat[a.size // 2] = value
        return a
    if how == "empty":
        return np.zeros((0,) + a.shape[1:]) if a.ndim else np.zeros(0)
    if how == "extra_row":
        return (
            np.concatenate([a, a[:1] if len(a) else np.zeros((1,) + a.shape[1:])])
            if a.ndim
            else np.array([a, a])
        )
    if how == "missing_col":
        return a[..., :-1] if a.ndim and a.shape[-1] else a[None][:0]
    if how == "ndim_up":
        return a[None]
    if how == "ndim_down":
        return a.ravel() if a.ndim > 1 else (a.reshape(-1)[0] if a.size else np.float64(0.0))
    if how == "scalar":
        return np.float64(1.0)
    if how == "list":
        return a.tolist()
    if how == "none":
        return None
    if how == "huge":  # many rows (not so many that the copy itself runs out of memory)
        rows = max(1, 100_000 // max(1, int(np.prod(a.shape[1:]))) if a.ndim > 1 else 100_000)
        return np.ones((rows,) + a.shape[1:])
    raise ValueError(how)


def _mutate_scalar(x, how: str):
    integer = isinstance(x, (int,)) and not isinstance(x, bool)
    return {
        "same": x,
        "nan": float("nan"),
        "inf": float("inf"),
        "neg": -1 if integer else -1.0,
        "zero": 0 if integer else 0.0,
        "int_max": 2**31 - 1,
        "int_overflow": 2**64,
        "huge": 10**9 if integer else 1e300,
        "none": None,
        "str": "1",
        "float_for_int": 1.5,
    }[how]


def _apply(values: list, mutations, nonfinite: list):
    """``values`` (arrays) with the spec's mutations applied in place of some of them."""
    values = list(values)
    for index, how in mutations:
        k = index % len(values)
        values[k] = _mutate_array(values[k], how)
        if how in _NONFINITE_IN:
            nonfinite.append(how)
    return values


def _boundary_levels(spec, rng):
    np = _np()
    n = spec["n"]
    arrays = []
    for m in spec["rows"]:
        arrays += [rng.normal(size=(m, n)), rng.normal(size=m), np.ones(m)]
    return arrays


# Complexity above 10: one branch per entry point of the boundary.
def run_boundary(spec: dict) -> str:
    np = _np()
    import qpik

    rng = np.random.default_rng(spec["seed"])
    entry, mutations = spec["entry"], spec["mutations"]
    odd: list = []
    if entry == "hierarchy":
        from qpik.core import Level, solve_hierarchy

        n, p = spec["n"], spec["p"]
        base = _boundary_levels(spec, rng)
        base += [-np.ones(n), np.ones(n), rng.normal(size=(p, n)), np.abs(rng.normal(size=p))]
        values = _apply(base, mutations, odd)
        levels = [
            Level(values[3 * k], values[3 * k + 1], spec["regularization"], values[3 * k + 2])
            for k in range(len(spec["rows"]))
        ]
        lb, ub, G, h = values[-4:]
        options = {} if spec["solver"] is None else {"solver": spec["solver"]}
        result = solve_hierarchy(levels, lb, ub, G, h, **options)
        answer = [np.asarray(result.x)]
        if not odd and math.isfinite(spec["regularization"]):
            _finite(answer[0], "x")
        return _digest(*answer)
    model = _model(spec["robot"])
    lower, upper = _limits_of(model)
    q_mid = _q_value("mid", model, rng)
    if entry.startswith("chain"):
        from qpik.model import KinematicChain

        chain = KinematicChain.from_model(model, "ee")
        if entry == "chain_reach":
            lo, hi = _apply(
                [
                    np.where(np.isfinite(lower), lower, -1.0),
                    np.where(np.isfinite(upper), upper, 1.0),
                ],
                mutations,
                odd,
            )
            bound = chain.reach_bound(lo, hi)
            return _digest(repr(bound))
        (q,) = _apply([q_mid], mutations, odd)
        out = chain.pose(q) if entry == "chain_pose" else (chain.jacobian(q),)
        if not odd:
            _finite(out, entry)
        return _digest(*out)
    if entry == "configuration":
        (q,) = _apply([q_mid], mutations, odd)
        configuration = qpik.Configuration(model, q)
        position = configuration.get_transform_frame_to_world("ee", "site").translation()
        jac = configuration.get_frame_jacobian("ee", "site")
        if not odd:
            _finite([position, jac], entry)
        return _digest(np.asarray(position), np.asarray(jac))
    if entry == "task_target":
        configuration = qpik.Configuration(model, q_mid)
        kind = spec["task"]
        rot = np.eye(3)
        if kind == "position":
            task = qpik.tasks.PositionTask("ee", "site")
            (target,) = _apply([np.array([0.3, 0.1, 0.3])], mutations, odd)
            task.set_target(target)
        elif kind == "orientation":
            task = qpik.tasks.OrientationTask("ee", "site")
            (target,) = _apply([rot], mutations, odd)
            task.set_target(target)
        elif kind == "pose":
            task = qpik.tasks.PoseTask("ee", "site")
            position, rotation = _apply([np.array([0.3, 0.1, 0.3]), rot], mutations, odd)
            task.set_target(position, rotation)
        elif kind == "posture":
            task = qpik.tasks.PostureTask(model, cost=1.0)
            (target,) = _apply([q_mid], mutations, odd)
            task.set_target(target)
        elif kind == "com":
            task = qpik.tasks.ComTask(cost=1.0)
            (target,) = _apply([np.array([0.1, 0.0, 0.3])], mutations, odd)
            task.set_target(target)
        else:
            import mink

            task = qpik.tasks.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
            (wxyz_xyz,) = _apply([np.array([1.0, 0, 0, 0, 0.3, 0.1, 0.3])], mutations, odd)
            try:  # mink's own constructor (not qpik) checks the length only
                target = mink.SE3(wxyz_xyz)
            except Exception as exc:  # noqa: BLE001
                raise Typed(f"mink.SE3: {type(exc).__name__}") from exc
            task.set_target(target)
        solver = qpik.IKSolver(
            model, [[task]], [qpik.limits.ConfigurationLimit(model)], solver=spec["solver"]
        )
        result = solver.step(configuration, 0.01)
        if not odd:
            _finite(result, "step", allow=(".solve_time",))
        return _digest(np.asarray(result.velocity))
    if entry == "solve_q0":
        (q0,) = _apply([q_mid], mutations, odd)
        result = qpik.solve(model, {"ee": [0.3, 0.1, 0.3]}, q0=q0, restarts=0, max_iters=20, seed=0)
    else:
        (target,) = _apply([np.array([0.3, 0.1, 0.3])], mutations, odd)
        result = qpik.solve(model, {"ee": target}, restarts=0, max_iters=20, seed=0)
    if not odd:
        _finite(result.q, "q")
    return _digest(np.asarray(result.q))


#: Recorded calls of the engine's kernels, by name: (args, kwargs) of a valid solve.
_ENGINE_CALLS: dict = {}


def _engine_functions() -> dict:
    import qpik._engine as engine

    found = {}
    for sub in ("core", "model", "tasks", "limits", "diffik", "igm"):
        module = getattr(engine, sub, None)
        for name in dir(module):
            value = getattr(module, name)
            if callable(value) and not isinstance(value, type) and not name.startswith("_"):
                found[id(value)] = (f"{sub}.{name}", value)
    return found


def _record_engine_calls() -> dict:
    """Run a few valid solves with every engine kernel wrapped, keeping the arguments of
    the first two calls of each (copies)."""
    import copy

    np = _np()
    import qpik

    functions = _engine_functions()
    calls: dict = {}
    patched = []

    def wrap(name, function):
        def recorder(*args, **kwargs):
            if len(calls.setdefault(name, [])) < 2:
                calls[name].append((copy.deepcopy(args), copy.deepcopy(kwargs)))
            return function(*args, **kwargs)

        return recorder

    modules = [m for n, m in list(sys.modules.items()) if n.startswith("qpik") and m is not None]
    for module in modules:
        for attr, value in list(vars(module).items()):
            if id(value) in functions and not module.__name__.startswith("qpik._engine"):
                name, function = functions[id(value)]
                patched.append((module, attr, value))
                setattr(module, attr, wrap(name, function))
    try:
        with contextlib.suppress(Exception):
            for robot in ROBOTS:
                qpik.solve(robot, {"ee": [0.3, 0.1, 0.3]}, restarts=2, max_iters=30, seed=1)
                qpik.solve(robot, {"ee": [5.0, 5.0, 5.0]}, restarts=2, max_iters=10, seed=1)
        with contextlib.suppress(Exception):
            qpik.solve(
                "panda",
                {"ee": {"position": [0.4, 0.1, 0.5], "rotation": np.eye(3).tolist()}},
                restarts=1,
                seed=2,
            )
        model = qpik.load_robot("panda")
        for solver in ("osqp", "daqp", "quadprog"):
            with contextlib.suppress(Exception):
                task = qpik.tasks.PoseTask("ee", "site")
                task.set_target(np.array([0.4, 0.1, 0.4]), np.eye(3))
                qpik.IKSolver(
                    model, [[task]], [qpik.limits.ConfigurationLimit(model)], solver=solver
                ).step(qpik.Configuration(model), 0.01)
        with contextlib.suppress(Exception):
            from qpik.core import Level, solve_hierarchy

            rng = np.random.default_rng(0)
            solve_hierarchy(
                [Level(rng.normal(size=(3, 5)), rng.normal(size=3), 1e-6)],
                -np.ones(5),
                np.ones(5),
                rng.normal(size=(2, 5)),
                np.ones(2),
            )
        with contextlib.suppress(Exception):
            from qpik.model import KinematicChain

            chain = KinematicChain.from_model(model, "ee")
            chain.jacobian(np.zeros(model.nq))
            chain.reach_bound(*_limits_of(model))
        for path in _shipped_problems():
            with contextlib.suppress(Exception):
                qpik.load_problem(path).solve()
    finally:
        for module, attr, value in patched:
            setattr(module, attr, value)
    for name, call in _engine_recipes(calls).items():
        calls.setdefault(name, [call])
    return calls


def _engine_recipes(calls: dict) -> dict:
    """Valid calls of the kernels that the recording solves do not reach."""
    np = _np()
    rng = np.random.default_rng(0)
    M = rng.normal(size=(4, 4))
    spd = M @ M.T + 4 * np.eye(4)
    R = np.eye(3)
    pose = np.array([1.0, 0, 0, 0, 0.1, 0.2, 0.3])
    recipes = {
        "core.active_guess": ((np.zeros(4), rng.normal(size=(3, 4)), -np.ones(3), np.ones(3)), {}),
        "core.cholesky_into": ((spd, 4, 1e-9, np.zeros((4, 4))), {}),
        "core.damping_of": ((0.1, 0.05, 0.1), {}),
        "igm.box_qp": ((spd, np.ones(4), -np.ones(4), np.ones(4), np.zeros(4), 50), {}),
        "igm.uniform": ((np.array([12345], dtype=np.uint64),), {}),
        "limits.collision_candidates": (
            (
                np.array([[0, 1]], dtype=np.int64),
                np.array([3, 6], dtype=np.int32),
                np.array([[0.05, 0.2, 0.0], [0.1, 0.1, 0.1]]),
                np.zeros((2, 6)),
                np.array([0.25, 0.18]),
                np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0]]),
                np.tile(R.ravel(), (2, 1)),
                0.05,
                np.zeros(1, dtype=np.int64),
            ),
            {},
        ),
        "model.left_jacobian_inverse": ((np.array([0.1, 0.2, 0.3]), np.zeros((3, 3))), {}),
        "model.rotation_defect": ((R,), {}),
        "model.rotation_log": ((R, np.zeros(3)), {}),
        "tasks.se3_inverse_multiply": ((np.zeros(7), pose, pose.copy()), {}),
        "tasks.se3_jlog": ((np.zeros((6, 6)), pose), {}),
        "tasks.se3_log": ((np.zeros(6), pose), {}),
        "tasks.se3_rminus": ((np.zeros(6), pose, pose.copy()), {}),
        "tasks.so3_ljacinv": ((np.zeros(9), np.array([0.1, 0.2, 0.3])), {}),
        "tasks.so3_log": ((np.zeros(3), np.array([1.0, 0, 0, 0])), {}),
        "tasks.xmat_xpos_to_wxyz_xyz": ((np.zeros(7), R.ravel(), np.zeros(3)), {}),
    }
    if calls.get("diffik.fused_step"):  # fused_rows takes fused_step's first 21 arguments
        args, _ = calls["diffik.fused_step"][0]
        recipes["diffik.fused_rows"] = (tuple(args[:21]), {})
    return recipes


def run_engine(spec: dict) -> str:
    """A raw kernel call: any Python exception is a clean refusal (the kernels are private
    and document no error class), counted as typed; only crash and hang are bad."""
    import copy

    np = _np()
    if not _ENGINE_CALLS:
        _ENGINE_CALLS.update(_record_engine_calls())
    names = sorted(_ENGINE_CALLS)
    flat = [(name, k) for name in names for k in range(len(_ENGINE_CALLS[name]))]
    name, k = flat[spec["pick"] % len(flat)]
    args, kwargs = copy.deepcopy(_ENGINE_CALLS[name][k])
    values = list(args) + list(kwargs.values())
    for mutation in spec["mutations"]:
        index = mutation[0] % max(1, len(values))
        if not values:
            break
        if mutation[1] == "alias":  # the same array object for two arguments
            arrays = [i for i, v in enumerate(values) if isinstance(v, np.ndarray)]
            if len(arrays) >= 2:
                a = arrays[index % len(arrays)]
                b = arrays[(index + 1) % len(arrays)]
                values[b] = values[a]
            continue
        value = values[index]
        if isinstance(value, np.ndarray) and value.dtype == np.float64:
            values[index] = _mutate_array(value, mutation[1])
        elif isinstance(value, np.ndarray):  # index arrays: keep their dtype, break the shape
            how = (
                mutation[1]
                if mutation[1]
                in ("empty", "ndim_up", "readonly", "strided", "float32", "list", "none")
                else "empty"
            )
            values[index] = (
                value.astype(np.float32)
                if how == "float32"
                else (
                    _mutate_array(value, how).astype(value.dtype)
                    if how not in ("list", "none")
                    else _mutate_array(value, how)
                )
            )
        elif isinstance(value, (bool, int, float)):
            values[index] = _mutate_scalar(value, mutation[2])
        elif isinstance(value, tuple):  # a tuple of arrays (the chain's arrays)
            inner = list(value)
            j = mutation[0] % max(1, len(inner))
            if inner and isinstance(inner[j], np.ndarray):
                inner[j] = (
                    _mutate_array(inner[j], mutation[1]).astype(inner[j].dtype)
                    if mutation[1] in ("empty", "ndim_up", "extra_row", "missing_col")
                    else _mutate_array(inner[j], mutation[1])
                    if inner[j].dtype == np.float64
                    else inner[j][:0]
                )
            values[index] = tuple(inner)
    args = values[: len(args)]
    kwargs = dict(zip(kwargs, values[len(args) :], strict=True))
    function = {n: f for n, f in _engine_functions().values()}[name]
    try:
        out = function(*args, **kwargs)
    except MemoryError as exc:  # the arrays are small: a size argument went unchecked
        raise Bad("untyped", f"{name}: MemoryError (an unchecked size argument)") from exc
    except Exception as exc:  # noqa: BLE001 - a clean refusal
        raise Typed(f"{name}: {type(exc).__name__}") from exc
    return _digest(name, repr(type(out)))


# -- robots generated on the fly
def _gen_mesh(kind: str, folder: Path, name: str) -> str:
    import struct

    path = folder / f"{name}.stl"
    if kind == "empty":
        path.write_bytes(b"")
    elif kind == "ascii":
        path.write_text(
            "solid x\\nfacet normal 0 0 1\\nouter loop\\nvertex 0 0 0\\nvertex 1 0 0\\n"
            "vertex 0 1 0\\nendloop\\nendfacet\\nendsolid x\\n"
        )
    elif kind in ("degenerate", "tiny"):
        a = 0.01
        v = [(0.0, 0.0, 0.0), (a, 0.0, 0.0), (0.0, a, 0.0), (0.0, 0.0, a)]
        faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
        if kind == "degenerate":
            v = [(0.0, 0.0, 0.0)] * 4
        body = b"".join(
            struct.pack("<12fH", 0.0, 0.0, 0.0, *v[i], *v[j], *v[k], 0) for i, j, k in faces
        )
        path.write_bytes(b"\\0" * 80 + struct.pack("<I", len(faces)) + body)
    return path.name  # "missing": never written


def _gen_names(style: str, n: int) -> tuple[list[str], str]:
    """Link / body names and the tool frame's name of a generated robot."""
    pattern, tool = {
        "plain": ("l{}", "ee"),
        "space": ("link {}", "end effector"),
        "unicode": ("lien_é{}", "outil_ü"),
        "long": ("l" * 150 + "{}", "e" * 200),
        "dup": ("tip{}", f"tip{n - 1}"),
        "dots": ("a.b:c/{}", "t.o/o:l"),
        "numeric": ("{}", "0"),
    }[style]
    return [pattern.format(i) for i in range(n)], tool


_INERTIA_XML = {
    "ok": (0.01, 0.01, 0.01, 0.0, 0.0, 0.0),
    "zero": (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    "negative": (-0.01, 0.01, 0.01, 0.0, 0.0, 0.0),
    "nonpd": (1.0, 0.01, 0.01, 0.0, 0.0, 0.0),
    "offdiag": (0.01, 0.01, 0.01, 1.0, 0.0, 0.0),
    "huge": (1e30, 1e30, 1e30, 0.0, 0.0, 0.0),
    "tiny": (1e-30, 1e-30, 1e-30, 0.0, 0.0, 0.0),
    "nan": (NAN, 0.01, 0.01, 0.0, 0.0, 0.0),
}
_LIMIT_XML = {
    "ok": ("-2", "2"),
    "reversed": ("1", "-1"),
    "equal": ("0.5", "0.5"),
    "nan": ("nan", "1"),
    "inf": ("-inf", "inf"),
    "huge": ("-1e300", "1e300"),
}


# Complexity above 10: one branch per kind of generated feature.
def _gen_urdf(spec: dict, folder: Path) -> tuple[str, str, str]:
    names, _tool = _gen_names(spec["names"], len(spec["links"]))
    links = ['<link name="base"/>']
    joints = []
    parent = "base"
    for i, (link, name) in enumerate(zip(spec["links"], names)):
        inertial = ""
        if link["inertia"] != "none":
            xx, yy, zz, xy, xz, yz = _INERTIA_XML.get(link["inertia"], _INERTIA_XML["ok"])
            inertial = (
                f'<inertial><origin xyz="0 0 0"/><mass value="{link["mass"]}"/>'
                f'<inertia ixx="{xx}" iyy="{yy}" izz="{zz}" ixy="{xy}" ixz="{xz}" iyz="{yz}"/>'
                "</inertial>"
            )
        geometry = '<cylinder radius="0.03" length="0.3"/>'
        if link["mesh"] != "none":
            geometry = f'<mesh filename="{_gen_mesh(link["mesh"], folder, f"m{i}")}"/>'
        links.append(
            f'<link name="{name}">{inertial}<collision><geometry>{geometry}</geometry>'
            f"</collision></link>"
        )
        kind = link["joint"]
        jtype = "revolute" if kind == "mimic" else kind
        if i == 0 and spec["base"] == "free":
            jtype = "floating"
        length = 0.0 if i == 0 else spec["links"][i - 1]["length"]
        limit = ""
        if link["limit"] != "missing" and jtype in ("revolute", "prismatic"):
            lo, hi = _LIMIT_XML[link["limit"]]
            limit = (
                f'<limit lower="{lo}" upper="{hi}" effort="{link["effort"]}" '
                f'velocity="{link["velocity"]}"/>'
            )
        mimic = ""
        if kind == "mimic":
            mimic = (
                f'<mimic joint="j{i - 1 if i else 99}" multiplier="{link["mimic"]}" offset="0"/>'
            )
        joints.append(
            f'<joint name="j{i}" type="{jtype}"><parent link="{parent}"/><child link="{name}"/>'
            f'<origin xyz="{length} 0 0" rpy="0 0 0"/><axis xyz="{link["axis"]}"/>'
            f"{limit}{mimic}</joint>"
        )
        parent = name
    text = f'<?xml version="1.0"?><robot name="gen">{"".join(links)}{"".join(joints)}</robot>'
    path = folder / "robot.urdf"
    path.write_text(text, encoding="utf-8")
    return str(path), names[-1], "body"


# Complexity above 10: one branch per kind of generated feature.
def _gen_mjcf(spec: dict, folder: Path) -> tuple[str, str, str]:
    names, tool = _gen_names(spec["names"], len(spec["links"]))
    bodies, assets, joint_names = [], [], []
    for i, (link, name) in enumerate(zip(spec["links"], names)):
        pos = "0 0 0" if i == 0 else f"{spec['links'][i - 1]['length']} 0 0"
        kind = link["joint"]
        joint = ""
        if i == 0 and spec["base"] == "free":
            joint = f'<joint name="j{i}" type="free"/>'
        elif kind != "fixed":
            joint = f'<joint name="j{i}" type="{kind}"'
            if kind in ("hinge", "slide"):
                joint += f' axis="{link["axis"]}"'
                joint_names.append(f"j{i}")
                if link["limit"] != "missing":
                    joint += f' range="{" ".join(_LIMIT_XML[link["limit"]])}" limited="true"'
            elif kind == "ball" and link["limit"] not in ("missing", "reversed", "nan"):
                joint += ' range="0 1.5" limited="true"'
            joint += "/>"
        inertial = ""
        if link["inertia"] != "none":
            xx, yy, zz, xy, xz, yz = _INERTIA_XML.get(link["inertia"], _INERTIA_XML["ok"])
            inertial = (
                f'<inertial pos="0 0 0" mass="{link["mass"]}" '
                f'fullinertia="{xx} {yy} {zz} {xy} {xz} {yz}"/>'
            )
        geom = f'<geom type="capsule" fromto="0 0 0 {link["length"]} 0 0" size="0.03"/>'
        if link["mesh"] != "none":
            assets.append(f'<mesh name="m{i}" file="{_gen_mesh(link["mesh"], folder, f"m{i}")}"/>')
            geom = f'<geom type="mesh" mesh="m{i}"/>'
        bodies.append(f'<body name="{name}" pos="{pos}">{joint}{inertial}{geom}')
    site = f'<site name="{tool}" pos="{spec["links"][-1]["length"]} 0 0"/>'
    tree = "".join(bodies) + site + "</body>" * len(bodies)
    equality = ""
    eq = spec["equality"]
    if eq == "joint" and len(joint_names) >= 2:
        equality = (
            f'<joint joint1="{joint_names[1]}" joint2="{joint_names[0]}" polycoef="0 1 0 0 0"/>'
        )
    elif eq == "inactive" and len(joint_names) >= 2:
        equality = f'<joint joint1="{joint_names[1]}" joint2="{joint_names[0]}" active="false"/>'
    elif eq == "connect":
        equality = f'<connect body1="{names[-1]}" body2="world" anchor="0 0 0"/>'
    elif eq == "weld":
        equality = f'<weld body1="{names[-1]}"/>'
    elif eq == "bad":
        equality = '<joint joint1="nope"/>'
    velocities = " ".join(link["velocity"] for link in spec["links"] if link["joint"] != "fixed")
    custom = ""
    if any(link["velocity"] != "1" for link in spec["links"]):
        custom = f'<custom><numeric name="velocity_limit" data="{velocities or "1"}"/></custom>'
    text = (
        f'<mujoco model="gen"><asset>{"".join(assets)}</asset><worldbody>{tree}</worldbody>'
        f"{f'<equality>{equality}</equality>' if equality else ''}{custom}</mujoco>"
    )
    path = folder / "robot.xml"
    path.write_text(text, encoding="utf-8")
    return str(path), tool, "site"


def _gen_q(kind: str, model, rng):
    """A configuration within the model's limits: its qpos0, the middle of its ranges or a
    random one (ball and free joints: qpos0 moved along a random velocity)."""
    np = _np()
    import mujoco

    q = model.qpos0.copy()
    if kind == "qpos0":
        return q
    v = np.zeros(model.nv)
    for j in range(model.njnt):
        adr, dof = model.jnt_qposadr[j], model.jnt_dofadr[j]
        lo, hi = model.jnt_range[j]
        limited = bool(model.jnt_limited[j]) and lo < hi
        if int(model.jnt_type[j]) in (
            int(mujoco.mjtJoint.mjJNT_HINGE),
            int(mujoco.mjtJoint.mjJNT_SLIDE),
        ):
            lo, hi = (lo, hi) if limited else (-1.0, 1.0)
            q[adr] = 0.5 * (lo + hi) if kind == "mid" else rng.uniform(lo, hi)
        elif kind == "random":
            n = 3 if int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_BALL) else 6
            v[dof : dof + n] = rng.uniform(-0.3, 0.3, n)
    if kind == "random":
        mujoco.mj_integratePos(model, q, v, 1.0)
    return q


def _equality_residual(model, q, tol_p: float = 1e-4, tol_o: float = 1e-3) -> float:
    """The largest residual of the model's active equality constraints at ``q``, as a
    multiple of the tolerance a converged solve documents (``tol_position`` for every row
    but a weld's rotation rows, whose ``torquescale sin(angle / 2)`` is held to
    ``tol_orientation``): above 1, the constraint is broken."""
    np = _np()
    import mujoco

    if model.neq == 0:
        return 0.0
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    n = data.nefc
    worst, seen = 0.0, {}
    for row in np.flatnonzero(data.efc_type[:n] == mujoco.mjtConstraint.mjCNSTR_EQUALITY):
        e = int(data.efc_id[row])
        k = seen[e] = seen.get(e, -1) + 1
        tol = tol_p
        if int(model.eq_type[e]) == int(mujoco.mjtEq.mjEQ_WELD) and k >= 3:
            tol = 0.5 * tol_o * abs(float(model.eq_data[e, 10]) or 1.0)
        worst = max(worst, abs(float(data.efc_pos[row])) / tol)
    return worst


def _check_equality_claim(model, q, converged: bool, where: str, tols=(1e-4, 1e-3)) -> None:
    if converged and _equality_residual(model, q, *tols) > 1 + 1e-6:
        ratio = _equality_residual(model, q, *tols)
        raise Bad("claim", f"{where}: converged with equality residual {ratio:.3g} x its tolerance")


def _check_frame_pose(configuration, frame: str, ftype: str, where: str) -> None:
    """qpik's frame pose against MuJoCo's forward kinematics of the same q."""
    np = _np()
    position, rotation = configuration.frame_pose(frame, ftype)
    _finite((position, rotation), where)
    fp, fr = _fk(configuration.model, configuration.q, frame, ftype)
    if np.linalg.norm(np.asarray(position) - fp) > 1e-9 * max(1.0, np.linalg.norm(fp)):
        raise Bad("misreport", f"{where} position {position} but FK says {fp}")
    if _angle(rotation, fr) > 1e-7:
        raise Bad("misreport", f"{where} rotation off FK by {_angle(rotation, fr)} rad")


# Complexity above 10: every public entry point on one generated robot.
def _exercise_generated(model, frame: str, ftype: str, q0, target) -> str:
    np = _np()
    import qpik
    from qpik import analysis, statics

    cfg = qpik.Configuration(model, q0)
    _check_frame_pose(cfg, frame, ftype, "frame_pose")
    out = [statics.gravity_torques(cfg), statics.holding_torques(cfg)]
    out.append(statics.joint_torques(cfg, frame, [0.0, 0.0, -10.0], frame_type=ftype))
    _finite(out, "statics")
    limits_tau = statics.joint_torque_limits(cfg)
    if np.any(np.isnan(limits_tau)):
        raise Bad("nonfinite", f"joint_torque_limits = {limits_tau}")
    payload = statics.max_payload(cfg, frame, [0.0, 0.0, -1.0], frame_type=ftype)
    _check_payload(payload, "max_payload")
    ellipsoid = statics.force_ellipsoid(cfg, frame, ftype)
    if np.any(np.isnan(ellipsoid.lengths)) or np.any(ellipsoid.lengths < 0):
        raise Bad("nonfinite", f"force_ellipsoid lengths {ellipsoid.lengths}")  # inf documented
    _finite(ellipsoid.axes, "force_ellipsoid.axes")
    _finite(statics.wrench_from_torques(cfg, frame, out[2], ftype), "wrench_from_torques")
    report = analysis.analyze(cfg, frame, ftype)
    _finite(report, "analyze", allow=(".condition_number",))
    _finite(analysis.manipulability_gradient(cfg, frame, ftype), "manipulability_gradient")
    digests = [_digest(*out)]
    if model.nv == 0:
        return _digest(*digests)
    result = qpik.solve(model, {(frame, ftype): target}, q0=q0, restarts=1, max_iters=40, seed=0)
    _check_ik_result(result, model, (frame, ftype), target, {})
    _check_equality_claim(model, result.q, result.converged, "solve")
    task = qpik.tasks.PositionTask(frame, ftype)
    task.set_target(np.asarray(target) + 0.05)
    com = qpik.tasks.ComTask(cost=0.1)
    com.set_target_from_configuration(cfg)
    posture = qpik.tasks.PostureTask(model, cost=0.01)
    posture.set_target_from_configuration(cfg)
    limits = [
        qpik.limits.ConfigurationLimit(model, gain=0.95),
        qpik.limits.ConfigurationLimit(model, gain=0.3, min_distance_from_limits=0.01),
        *qpik.limits.joint_limits(model),
    ]
    step = qpik.IKSolver(model, [[task], [com], [posture]], limits).step(cfg, 0.01)
    _finite(step, "step", allow=(".solve_time",))
    inside = cfg.within_limits(0.0)
    if inside:
        _check_within(model, cfg.integrate(step.velocity, 0.01), "q after the step", tol=1e-7)
    v = qpik.solve_ik(cfg, [[task], [posture]], 0.01, limits=limits[:1])
    _finite(v, "solve_ik")
    if inside:
        _check_within(model, cfg.integrate(v, 0.01), "q after solve_ik", tol=1e-7)
    digests.append(_digest(result.q, np.asarray(step.velocity), np.asarray(v)))
    return _digest(*digests)


def _gen_problem_file(spec, folder: Path, path: str, frame, ftype, q0, target) -> Path:
    track = spec["seed"] % 3 == 0
    data = {
        "name": "generated",
        "robot": Path(path).name,
        "floating_base": spec["base"] == "floating_base",
        "q0": [float(x) for x in q0],
        "mode": "track" if track else "solve",
        "levels": [
            [{"type": "position", "frame": frame, "frame_type": ftype}],
            [{"type": "posture", "cost": 0.01}],
        ],
        "target": {"frame": frame, "frame_type": ftype, "position": [float(x) for x in target]},
        "statics": {"force": [0.0, 0.0, -10.0]},
    }
    if track:
        data["track"] = {"dt": 0.01, "steps": 30}
    else:
        data["solver"] = {"restarts": 1, "max_iters": 40}
    problem_path = folder / "problem.toml"
    problem_path.write_text(to_toml(data), encoding="utf-8")
    return problem_path


def _check_problem_run(problem, result) -> None:
    """A problem's result against the limits and forward kinematics."""
    _finite(result.q, "result.q")
    _finite(
        result.to_dict(),
        "result.to_dict()",
        allow=("['solve_time']", "['step_time_mean']", "['step_time_max']"),
    )
    if problem.position_limits:
        _check_within(problem.model, result.q, "result.q")
    if problem.velocity_limits is not None and result.trace is not None:
        if result.trace.max_velocity_ratio > 1 + 1e-6:
            raise Bad("limits", f"max |v| / v_max = {result.trace.max_velocity_ratio}")
    _check_problem_claim(problem, result)
    options = problem.solve_options
    tols = (options.tol_position, options.tol_orientation)
    _check_equality_claim(problem.model, result.q, result.converged, "problem", tols)


def _cli_json(path: Path) -> dict | None:
    """``qpik reach FILE --json -``: its exit code checked, its JSON parsed and finite."""
    import json

    code, out, err = _cli(["reach", str(path), "--json", "-"])
    _cli_check(code, err, (0, 1, 2))
    if code == 2:
        if not err.strip():
            raise Bad("message", "exit 2 with nothing on stderr")
        return None
    start = out.find("\n{")
    text = out[start + 1 :] if start >= 0 else out[out.find("{") :]
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise Bad("untyped", f"--json - printed no JSON: {exc}: {out[:200]!r}") from None
    _finite(data, "json", allow=("['solve_time']", "['step_time_mean']", "['step_time_max']"))
    if bool(data.get("converged")) != (code == 0):
        raise Bad("misreport", f"exit {code} but converged = {data.get('converged')}")
    return data


def run_robot_gen(spec: dict) -> str:
    np = _np()
    import qpik

    rng = np.random.default_rng(spec["seed"])
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        writer = _gen_urdf if spec["format"] == "urdf" else _gen_mjcf
        path, frame, ftype = writer(spec, folder)
        floating = spec["base"] == "floating_base"
        model = qpik.load_robot(path, floating_base=floating)
        q0 = _gen_q(spec["q"], model, rng)
        target = _fk(model, _gen_q("random", model, rng), frame, ftype)[0]
        entry = spec["entry"]
        if entry in ("problem", "cli"):
            problem_path = _gen_problem_file(spec, folder, path, frame, ftype, q0, target)
            if entry == "cli":
                return _digest(repr(_cli_json(problem_path) is None))
            problem = qpik.load_problem(problem_path)
            result = problem.solve()
            _check_problem_run(problem, result)
            return _digest(result.q)
        if entry == "solve_path" and not floating:
            result = qpik.solve(path, {(frame, ftype): target}, q0=q0, restarts=1, max_iters=40)
            _check_ik_result(result, model, (frame, ftype), target, {})
            _check_equality_claim(model, result.q, result.converged, "solve")
            return _digest(result.q)
        return _exercise_generated(model, frame, ftype, q0, target)


# -- problem files from every field of the schema
def _schema_value(value, model, spec, rng):
    """Resolve a symbolic ``@...`` value of SCHEMA_FIELDS against the model."""
    np = _np()
    if not (isinstance(value, str) and value.startswith("@")):
        return value
    lower, upper = _limits_of(model)
    lo = np.where(np.isfinite(lower), lower, -1.0)
    hi = np.where(np.isfinite(upper), upper, 1.0)
    mid = [float(x) for x in 0.5 * (lo + hi)]
    names = _schema_joint_names(model)
    if value == "@q_lower":
        return [float(x) for x in lo]
    if value == "@q_upper":
        return [float(x) for x in hi]
    if value == "@q_outside":
        return [float(hi[0] + 0.1)] + mid[1:]
    if value == "@q_nan":
        return [NAN] + mid[1:]
    if value == "@q_inf":
        return [INF] + mid[1:]
    if value == "@q_str":
        return ["a"] + mid[1:]
    if value == "@q_short":
        return mid[:-1]
    if value == "@q_long":
        return mid + [0.0]
    if value == "@nv_short":
        return [1.0] * (model.nv - 1)
    if value == "@nv_ones":
        return [1.0] * model.nv
    if value == "@velocity_table":
        return {n: 1.0 for n in names}
    if value == "@velocity_table_short":
        return {n: 1.0 for n in names[:-1]}
    if value == "@velocity_table_nan":
        return {n: NAN for n in names}
    if value.startswith("@task:"):
        return _schema_task(value[6:], model, spec["path"][:2] == ["levels", 0])
    if value.startswith("@obstacle:"):
        shape = value[10:]
        size = {"sphere": [0.05], "box": [0.05, 0.05, 0.05], "capsule": [0.03, 0.1]}
        entry = {"shape": shape, "size": size.get(shape, [0.05]), "position": [0.5, 0.5, 0.5]}
        if shape == "dup":
            entry = dict(entry, shape="sphere", size=[0.05], name="ob")
            return [entry, dict(entry)]
        return [entry]
    return value  # "@both", "@waypoints", "@frames": resolved by the caller


def _schema_joint_names(model) -> list[str]:
    import mujoco

    return [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)]


def _schema_task(kind: str, model, goal: bool) -> dict:
    """A valid task table of ``kind``: level 0's (``goal``) regulates the goal frame ee,
    with a position task beside it when ``kind`` cannot; others regulate a body."""
    import mujoco

    task: dict = {"type": kind}
    body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, model.nbody - 1)
    if kind in ("frame", "position", "orientation", "manipulability"):
        task.update(frame=body, frame_type="body")
    if kind in ("frame", "orientation"):
        task["target"] = {"rpy": [0.0, 0.0, 0.0]}
    if kind == "frame":
        task["target"]["position"] = [0.1, 0.1, 0.1]
    if kind == "posture":
        task["cost"] = 0.01
    if goal:
        return {"tasks": [{"type": "position", "frame": "ee", "frame_type": "site"}, task]}
    return task


# Complexity above 10: one branch per part of the schema.
def _schema_data(spec, model, rng) -> dict:
    """A valid problem of ``spec``'s robot and mode with ``spec``'s field set."""
    goal_q = _q_value("random", model, rng)
    position = [float(x) for x in _fk(model, goal_q, "ee", "site")[0]]
    data: dict = {"name": "schema", "robot": spec["robot"], "mode": spec["mode"], "q0": "mid"}
    data["levels"] = [
        {"tasks": [{"type": "position", "frame": "ee", "frame_type": "site"}]},
        {"tasks": [{"type": "posture", "cost": 0.01}]},
    ]
    goal = {"frame": "ee", "frame_type": "site", "position": position}
    if spec["goal"] == "waypoints":
        data["waypoints"] = [goal, dict(goal, position=[p * 0.9 for p in position])]
    else:
        data["target"] = goal
    if spec["mode"] == "track":
        data["track"] = {"dt": 0.01, "steps": 30}
    else:
        data["solver"] = {"restarts": 0, "max_iters": 30}
    path = spec["path"]
    value = _schema_value(spec["value"], model, spec, rng)
    head = path[0]
    if head in ("target", "waypoints") and path[-1] in ("rpy", "quaternion", "matrix"):
        # (a goal's rotation must be steered: an orientation task beside the position's)
        data["levels"][0]["tasks"].append({"type": "orientation", "frame": "ee"})
    if head == "track" and spec["mode"] != "track":
        data["track"] = {}
    if head == "levels" and len(path) > 1 and path[1] == 2:
        data["levels"].append({"tasks": [value]})
        return data
    if path == ["levels", 0, "tasks", 0] and isinstance(value, dict) and "tasks" in value:
        data["levels"][0] = value
        return data
    if head in ("target",) and spec["goal"] == "waypoints":
        data["target"] = data.pop("waypoints")[0]
    if head == "waypoints":
        data.pop("target", None)
        if value == "@waypoints":
            value = [goal, dict(goal, position=[p * 0.9 for p in position])]
        elif value == "@frames":
            value = [
                {
                    "frames": [
                        goal,
                        {"frame": "link2", "frame_type": "body", "position": [0.1, 0.0, 0.1]},
                    ]
                }
            ]
    if head == "target" and value == "@both":
        data["waypoints"] = [goal]
        return data
    if head == "limits" and len(path) > 1 and path[1] == "collision":
        data["obstacles"] = [{"shape": "sphere", "size": [0.05], "position": [0.5, 0.5, 0.5]}]
    if head == "limits" and len(path) > 2 and path[1] == "support":
        data.setdefault("limits", {})["support"] = {"frames": ["ee"]}
    if head == "obstacles" and len(path) > 1:
        data["obstacles"] = [{"shape": "sphere", "size": [0.05], "position": [0.5, 0.5, 0.5]}]
    node = data
    for k in path[:-1]:
        if isinstance(node, list):
            node = node[k]
            continue
        if k not in node:
            node[k] = {}
        node = node[k]
    node[path[-1]] = value
    return data


def _schema_field_name(path: list) -> str:
    """The name a message about ``path`` must give: its last key (an index: the key
    before it)."""
    keys = [k for k in path if isinstance(k, str)]
    if path[-1] == "bogus" or path[-1] == "bogus_key":
        return str(path[-1])
    if keys[-1] == "tasks" or (path[0] == "levels" and isinstance(path[-1], int)):
        return "levels"
    return keys[-1]


# Complexity above 10: one branch per outcome of a schema case.
def run_schema(spec: dict) -> str:
    np = _np()
    import qpik

    model = _model(spec["robot"])
    rng = np.random.default_rng(_seed_of(spec))
    data = _schema_data(spec, model, rng)
    invalid = spec["tag"] == "x"
    solve_only = spec["path"][0] == "solver" and spec["path"][-1] in SCHEMA_SOLVE_ONLY
    if solve_only and spec["mode"] == "track":
        invalid = True
    name = _schema_field_name(spec["path"])
    if spec["path"][0] == "track" and spec["mode"] != "track":
        invalid, name = True, "track"
    scale = spec["path"] == ["limits", "velocity"] and isinstance(spec["value"], float)
    declared = qpik.Configuration(model).velocity_limits()
    declared = declared is not None and np.any(np.isfinite(np.asarray(declared, dtype=float)))
    if scale and not declared:
        invalid = True  # a scale of the model's velocity_limit, which it does not declare
    # values whose validity depends on the robot, which the spec's tag cannot know
    if spec["path"] == ["q0"] and spec["value"] == "qpos0":
        invalid = not _within_limits(model, model.qpos0)  # panda's qpos0 is outside
    if spec["path"] == ["floating_base"] and spec["value"] is True:
        invalid = not _can_float(model)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "schema.toml"
        path.write_text(to_toml(data), encoding="utf-8")
        try:
            problem = qpik.load_problem(path)
        except qpik.QpikError as exc:
            if not invalid:
                raise Bad("refused", f"valid {spec['path']} = {spec['value']!r}: {exc}") from None
            if name not in str(exc) or "schema.toml" not in str(exc):
                raise Bad("message", f"{spec['path']}: message names no {name!r}: {exc}") from None
            raise
        if invalid:
            raise Bad("accepted", f"invalid {spec['path']} = {spec['value']!r} loaded")
        o = problem.options
        work = (
            problem.steps * len(problem.goals)
            if problem.mode == "track"
            else (o.get("restarts", 0) + 1) * o.get("max_iters", 100) * len(problem.goals)
        )
        digests = [_digest(problem.q0)]
        if work <= 3000:
            result = problem.solve()
            _check_problem_run(problem, result)
            digests.append(_digest(result.q, result.converged))
            if spec["cli"]:
                _cli_json(path)
    return _digest(*digests)


def _within_limits(model, q, tol: float = 1e-9) -> bool:
    """Whether ``q`` lies within the model's joint limits (read from the model)."""
    np = _np()
    lower, upper = _limits_of(model)
    span = np.maximum(1.0, np.abs(np.where(np.isfinite(lower), lower, 0.0)))
    return not np.any(np.maximum(lower - q, q - upper) > tol * span)


def _can_float(model) -> bool:
    """Whether a free joint can be added at the root: one body under the world, jointless."""
    roots = [b for b in range(1, model.nbody) if int(model.body_parentid[b]) == 0]
    return len(roots) == 1 and int(model.body_jntnum[roots[0]]) == 0


# -- every task and limit type at every level
_FLOATY_XML = """<mujoco model="floaty"><worldbody><body name="base" pos="0 0 0.5">
<freejoint name="root"/><geom type="box" size="0.1 0.1 0.1" mass="2"/>
<body name="link1" pos="0.1 0 0"><joint name="ball" type="ball" range="0 1.2"/>
<geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
<body name="link2" pos="0.3 0 0"><joint name="q1" type="hinge" axis="0 1 0" range="-2 2"/>
<geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
<body name="link3" pos="0.3 0 0"><joint name="q2" type="hinge" axis="0 0 1" range="-1.5 1.5"/>
<geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.03"/><site name="ee" pos="0.2 0 0"/>
</body></body></body></body>
<body name="obstacle" pos="0.6 0.4 0.5"><geom type="sphere" size="0.05"/></body>
</worldbody><equality><joint joint1="q2" joint2="q1" polycoef="0 0.5 0 0 0"/></equality>
</mujoco>"""
_FLOATY: list = []


def _stack_model(name: str):
    import qpik

    if name != "floaty":
        return _model(name)
    if not _FLOATY:
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "floaty.xml"
            path.write_text(_FLOATY_XML)
            _FLOATY.append(qpik.load_robot(path))
    return _FLOATY[0]


# Complexity above 10: one branch per kind of mink task.
def _mink_task(task: dict, model, configuration, rng):
    np = _np()
    import mink

    kind = task["type"]
    target = task["target"]
    link = "link2" if model.nbody > 2 else "ee"
    if kind == "mink_frame":
        t = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=0.5)
    elif kind == "mink_posture":
        t = mink.PostureTask(model, cost=0.1)
    elif kind == "mink_com":
        t = mink.ComTask(cost=1.0)
    elif kind == "mink_damping":
        return mink.DampingTask(model, cost=0.01)
    elif kind == "mink_relative":
        t = mink.RelativeFrameTask(
            "ee", "site", link, "body", position_cost=1.0, orientation_cost=0.1
        )
    elif kind == "mink_kinetic":
        t = mink.KineticEnergyRegularizationTask(cost=0.01)
        if target != "none":
            t.set_dt(0.01)
        return t
    elif kind == "mink_freeze":
        return mink.DofFreezingTask(model, dof_indices=[model.nv - 1])
    else:
        t = mink.LookAtTask("ee", "site", cost=1.0) if hasattr(mink, "LookAtTask") else None
        if target == "start" or target == "reach":
            t.set_target(np.array([1.0, 0.0, 0.0]))
        elif target != "none":
            t.set_target(np.array([1e300, 0.0, 0.0]) if target == "far" else np.full(3, NAN))
        return t
    if target == "none":
        return t
    if target == "start" or kind in ("mink_posture",) and target == "reach":
        t.set_target_from_configuration(configuration)
        return t
    if kind == "mink_com":
        t.set_target(
            np.array([0.1, 0.0, 0.3])
            if target == "reach"
            else np.full(3, 1e300 if target == "far" else NAN)
        )
        return t
    q = _gen_q("random", model, rng)
    position, rotation = _fk(model, q, "ee", "site")
    if target == "far":
        position = np.full(3, 1e300)
    elif target == "nan":
        position = np.full(3, NAN)
    pose = mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), position)
    t.set_target(pose)
    return t


# Complexity above 10: one branch per kind of limit.
def _stack_limit(kind: str, gain: float, distance: float, model):
    import mink

    import qpik

    names = [n for n in _schema_joint_names(model) if n not in ("root", "ball")]
    if kind == "config":
        return [qpik.limits.ConfigurationLimit(model, gain=gain, min_distance_from_limits=distance)]
    if kind == "mink_config":
        return [mink.ConfigurationLimit(model, gain=gain, min_distance_from_limits=distance)]
    if kind == "velocity":
        return [qpik.limits.VelocityLimit(model, {n: 0.5 + gain for n in names})], 0.5 + gain
    if kind == "mink_velocity":
        return [mink.VelocityLimit(model, {n: 0.5 + gain for n in names})], 0.5 + gain
    if kind == "joint_limits":
        return qpik.limits.joint_limits(model, gain)
    if kind == "collision":
        return [qpik.limits.model_collision_limit(model, gain=gain)]
    if kind == "mink_collision":
        geoms = list(range(model.ngeom))
        return [mink.CollisionAvoidanceLimit(model, [(geoms[:1], geoms[-1:])], gain=gain)]
    if kind == "support":
        return [qpik.limits.SupportPolygonLimit(model, [("ee", "site")], margin=distance)]
    if kind == "ball":
        return [qpik.limits.BallJointLimit(model)] if qpik.limits.limited_ball_joints(model) else []
    if model.nq == model.nv:
        return []
    return [mink.FreeJointVelocityLimit(model)] if hasattr(mink, "FreeJointVelocityLimit") else []


# Complexity above 10: one branch per variant of the case it runs and checks.
def run_stack(spec: dict) -> str:
    np = _np()
    import mink

    import qpik

    model = _stack_model(spec["robot"])
    rng = np.random.default_rng(_seed_of(spec))
    try:
        return _run_stack(spec, model, rng)
    except mink.exceptions.MinkError as exc:
        frames = traceback.extract_tb(exc.__traceback__)
        if isinstance(exc, qpik.QpikError) or any("/qpik/" in f.filename for f in frames):
            raise  # raised by qpik, or escaped through it (untyped)
        raise Typed(f"mink's own constructor: {exc}") from None


def _stack_objects(spec: dict, model, rng) -> tuple:
    """The configuration, levels and limits of a stack case (gen_stack)."""
    import qpik

    q = _gen_q("random", model, rng) if spec["q"] == "random" else _gen_q("mid", model, rng)
    if spec["q"] in ("inside_tiny", "outside") and model.nq == model.nv:
        q = _q_value(spec["q"], model, rng)
    configuration = qpik.Configuration(model, q)
    levels: list = [[] for _ in range(spec["levels"])]
    for task in spec["tasks"]:
        if task["type"] == "coupling":
            built = qpik.tasks.CouplingTask(model, cost=task["cost"], gain=task["gain"])
        elif task["type"].startswith("mink"):
            built = _mink_task(task, model, configuration, rng)
        else:
            built = _build_task(task, model, configuration, rng)
        levels[task["level"]].append(built)
    levels = [level for level in levels if level] or [[qpik.tasks.DampingTask(model, cost=1.0)]]
    limits = []
    for kind, gain, distance in spec["limits"]:
        made = _stack_limit(kind, gain, distance, model)
        if isinstance(made, tuple):
            made = made[0]
        limits.extend(made)
    return configuration, levels, limits


# Complexity above 10: one branch per variant of the case it runs and checks.
def _run_stack(spec: dict, model, rng) -> str:
    np = _np()
    import mink

    import qpik

    configuration, levels, limits = _stack_objects(spec, model, rng)
    speeds = [
        _stack_limit(kind, gain, distance, model)[1]
        for kind, gain, distance in spec["limits"]
        if kind in ("velocity", "mink_velocity")
    ]
    constraints = []
    if "freeze" in spec["constraints"]:
        constraints.append(mink.DofFreezingTask(model, dof_indices=[model.nv - 1]))
    if "posture" in spec["constraints"]:
        posture = mink.PostureTask(model, cost=1.0)
        posture.set_target_from_configuration(configuration)
        constraints.append(posture)
    dt = spec["dt"]
    has_config = any(k in ("config", "mink_config", "joint_limits") for k, *_ in spec["limits"])
    inside = bool(np.all(np.isfinite(configuration.q))) and configuration.within_limits(0.0)
    velocities = []
    if spec["entry"] == "build_ik":
        problems = qpik.build_ik(
            configuration, levels, dt, limits=limits, constraints=constraints or None
        )
        for k, p in enumerate(problems if isinstance(problems, list) else [problems]):
            _finite([p.P, p.q], f"build_ik[{k}]")
        return _digest(len(problems) if isinstance(problems, list) else 1)
    if spec["entry"] == "solve_ik":
        v = qpik.solve_ik(
            configuration,
            levels,
            dt,
            limits=limits,
            constraints=constraints or None,
            solver=None if spec["solver"] == "auto" else spec["solver"],
        )
        velocities.append(np.asarray(v))
        # Constraints hold exactly whenever the limits allow it (solve_ik's documented
        # rule): a start outside the position limits, or a collision row, may force the
        # frozen dof to move; judge the starts where nothing forces it.
        forced = not inside or any(k == "collision" for k, *_ in spec["limits"])
        frozen = constraints and "freeze" in spec["constraints"]
        if frozen and not forced and abs(v[model.nv - 1]) > 1e-9:
            raise Bad("limits", f"a frozen dof moves: v = {v[model.nv - 1]}")
    else:
        solver = qpik.IKSolver(model, levels, limits, solver=spec["solver"])
        for k in range(spec["steps"]):
            result = solver.step(configuration, dt)
            _finite(result, f"step[{k}]", allow=(".solve_time",))
            velocities.append(np.asarray(result.velocity))
            if k + 1 < spec["steps"]:
                configuration.integrate_inplace(result.velocity, dt)
    for k, v in enumerate(velocities):
        _finite(v, f"velocity[{k}]")
    if has_config and inside and len(velocities) == 1:
        q_next = configuration.integrate(velocities[0], dt)
        _finite(q_next, "q after the step")
        _check_within(model, q_next, "q after the step", tol=1e-7)
    ball = any(k in ("ball", "joint_limits") for k, *_ in spec["limits"])
    if ball and inside and len(velocities) == 1 and spec["entry"] != "build_ik":
        _check_ball_joints(model, configuration.integrate(velocities[0], dt), "q after the step")
    if speeds and len(velocities) == 1 and model.nq == model.nv:
        top = float(np.max(np.abs(velocities[0])))
        if top > min(speeds) * (1 + 1e-6) + 1e-12:
            raise Bad("limits", f"|v| = {top} > {min(speeds)}")
    return _digest(*velocities)


def _check_ball_joints(model, q, where: str, tol: float = 1e-7) -> None:
    """Every limited ball joint's rotation angle ``2 atan2(|xyz|, |w|)`` within its range,
    read from the quaternion (independent of qpik)."""
    import mujoco

    for j in range(model.njnt):
        if int(model.jnt_type[j]) != int(mujoco.mjtJoint.mjJNT_BALL) or not model.jnt_limited[j]:
            continue
        adr = int(model.jnt_qposadr[j])
        w, xyz = q[adr], q[adr + 1 : adr + 4]
        angle = 2.0 * math.atan2(math.sqrt(float(xyz @ xyz)), abs(float(w)))
        if angle > float(model.jnt_range[j, 1]) + tol:
            raise Bad("limits", f"{where}: ball joint {j} at {angle} rad > {model.jnt_range[j, 1]}")


# -- example-robot-data robots
def _check_targets_result(result, model, targets: dict, tols=(1e-4, 1e-3), where="result"):
    """An IKResult for several frames: its worst and per-frame errors against MuJoCo's
    forward kinematics of its ``q``, its claim against the tolerances (every frame and the
    model's equality constraints), its ``q`` within the joint limits and finite."""
    from qpik.igm.session import parse_target

    q = _ik_result_q(result, model, where)
    _check_within(model, q, f"{where}.q")
    measured = {}
    for key, target in targets.items():
        name, kind = _frame_kind(model, key)
        t = parse_target(target)
        measured[name] = _fk_errors(model, q, name, kind, t.position, t.rotation)
    worst = (max(p for p, _ in measured.values()), max(o for _, o in measured.values()))
    _check_reported(where, (result.position_error, result.orientation_error), worst)
    for name, reported in result.frame_errors.items():
        if name not in measured:
            raise Bad("misreport", f"{where}.frame_errors names {name!r}, not a target frame")
        _check_reported(f"{where}.frame_errors[{name!r}]", reported, measured[name])
    if result.converged:
        for name, errors in measured.items():
            _check_claim(f"{where}[{name!r}]", errors, *tols)
    _check_equality_claim(model, q, result.converged, where, tols)
    return _digest(q, result.converged, result.iterations, result.reason)


def _erd_model(spec: dict):
    import qpik

    if "talos" not in qpik.robots.erd_robots():
        raise Typed("example-robot-data is not installed")
    return qpik.load_robot("erd:" + spec["robot"], floating_base=spec["floating"])


def _erd_frames(spec: dict, model) -> list[str]:
    """Distinct bodies of the model (the world aside) picked by the spec's numbers."""
    import mujoco

    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i) for i in range(1, model.nbody)]
    names = [n for n in names if n]
    picked: list[str] = []
    for pick in spec["frames"]:
        if names:
            name = names[pick % len(names)]
            if name not in picked:
                picked.append(name)
    return picked


def _erd_q0(spec: dict, model, rng):
    if spec["q0"] == "keyframe" and model.nkey:
        return model.key_qpos[int(rng.integers(model.nkey))].copy()
    return _gen_q({"keyframe": "mid", "robot": "mid"}.get(spec["q0"], spec["q0"]), model, rng)


def _erd_targets(spec: dict, model, frames: list[str], rng) -> dict:
    q_goal = _gen_q("random", model, rng)
    targets = {}
    for name, rotation in zip(frames, spec["rotation"]):
        position, matrix = _fk(model, q_goal, name, "body")
        position = position + spec["offset"] * rng.standard_normal(3)
        targets[(name, "body")] = (position, matrix) if rotation else position
    return targets


def run_erd(spec: dict) -> str:
    np = _np()
    import qpik

    model = _erd_model(spec)
    rng = np.random.default_rng(spec["seed"])
    frames = _erd_frames(spec, model)
    if not frames or model.nv == 0:
        raise Typed("no body to reach, or no dof")
    q0 = _erd_q0(spec, model, rng)
    targets = _erd_targets(spec, model, frames, rng)
    entry = spec["entry"]
    if entry == "exercise":
        target = next(iter(targets.values()))
        return _exercise_generated(
            model,
            frames[0],
            "body",
            q0,
            np.asarray(target[0]) if isinstance(target, tuple) else target,
        )
    if entry == "step":
        return _erd_step(spec, model, frames, q0, targets)
    if entry == "problem":
        return _erd_problem(spec, model, frames, q0, targets)
    robot = model
    kwargs = {"restarts": spec["restarts"], "max_iters": spec["max_iters"], "seed": 0}
    if spec["q0"] == "robot":
        robot = qpik.Configuration(model, q0)
    else:
        kwargs["q0"] = q0
    if spec["solver"] != "auto":
        kwargs["solver"] = spec["solver"]
    result = qpik.solve(robot, targets, **kwargs)
    return _check_targets_result(result, model, targets)


def _erd_step(spec: dict, model, frames, q0, targets) -> str:
    """IKSolver.step on a stack over the robot's bodies: the targets split over two
    levels, the CoM, a posture; its limits and (on a floating base) the support polygon."""
    np = _np()
    import qpik

    cfg = qpik.Configuration(model, q0)
    tasks = []
    for (name, _), target in targets.items():
        if isinstance(target, tuple):
            task = qpik.tasks.PoseTask(name, "body", position_cost=1.0, orientation_cost=0.5)
            task.set_target(*target)
        else:
            task = qpik.tasks.PositionTask(name, "body")
            task.set_target(np.asarray(target))
        tasks.append(task)
    com = qpik.tasks.ComTask(cost=0.1)
    com.set_target_from_configuration(cfg)
    posture = qpik.tasks.PostureTask(model, cost=0.01)
    posture.set_target_from_configuration(cfg)
    stack = [tasks[:1], tasks[1:] + [com], [posture]]
    limits = list(qpik.limits.joint_limits(model))
    if spec["support"] and len(frames) >= 2:
        limits.append(qpik.limits.SupportPolygonLimit(model, [(f, "body") for f in frames[:2]]))
    kwargs = {} if spec["solver"] == "auto" else {"solver": spec["solver"]}
    solver = qpik.IKSolver(model, [level for level in stack if level], limits, **kwargs)
    velocity_limit = _velocity_limits_of(model)
    digests = []
    for _ in range(spec["steps"]):
        inside = cfg.within_limits(0.0)
        step = solver.step(cfg, spec["dt"])
        _finite(step, "step", allow=(".solve_time",))
        q_next = cfg.integrate(step.velocity, spec["dt"])
        _finite(q_next, "q after the step")
        if inside:
            _check_within(model, q_next, "q after the step", tol=1e-7)
            v = np.abs(np.asarray(step.velocity))
            over = v > velocity_limit * (1 + 1e-6) + 1e-9
            if over.any():
                i = int(np.flatnonzero(over)[0])
                raise Bad("limits", f"|v[{i}]| = {v[i]} over its limit {velocity_limit[i]}")
        cfg.update(q_next)
        digests.append(_digest(np.asarray(step.velocity)))
    return _digest(*digests)


def _velocity_limits_of(model):
    """``(nv,)`` the velocity limits qpik's joint_limits documents (the model's custom
    ``velocity_limit`` numeric or the URDF's), inf where none: read by qpik, so only
    respected-ness is judged, not the reading."""
    np = _np()
    import mink

    import qpik

    bound = np.full(model.nv, np.inf)
    for limit in qpik.limits.joint_limits(model):
        if isinstance(limit, mink.VelocityLimit):
            indices = np.asarray(limit.indices, dtype=int)
            bound[indices] = np.minimum(bound[indices], np.asarray(limit.limit, dtype=float))
    return bound


def _erd_problem(spec: dict, model, frames, q0, targets) -> str:
    """A problem file with several frames per goal (a [target] or two waypoints), levels
    over them, optional support polygon and velocity limits, judged by forward kinematics."""
    import qpik

    def frame_table(key, target) -> dict:
        position, rotation = target if isinstance(target, tuple) else (target, None)
        table = {"frame": key[0], "frame_type": "body", "position": [float(x) for x in position]}
        if rotation is not None:
            table["matrix"] = [[float(x) for x in row] for row in rotation]
        return table

    goal = [frame_table(k, t) for k, t in targets.items()]
    task_type = ["position" if not isinstance(t, tuple) else "frame" for t in targets.values()]
    level0 = [
        {"type": kind, "frame": key[0], "frame_type": "body"}
        for kind, key in zip(task_type, targets)
    ]
    data: dict = {
        "name": "erd",
        "robot": "erd:" + spec["robot"],
        "floating_base": spec["floating"],
        "q0": [float(x) for x in q0],
        "mode": spec["mode"],
        "levels": [level0[:2], level0[2:], [{"type": "posture", "cost": 0.01}]],
        "limits": {"position": True},
    }
    data["levels"] = [level for level in data["levels"] if level]
    if spec["offset"] == 0.02:
        data["waypoints"] = [{"frames": goal}, {"frames": goal[::-1]}]
    else:
        data["target"] = {"frames": goal}
    if spec["velocity"] is not None:
        data["limits"]["velocity"] = spec["velocity"]
    if spec["support"] and len(frames) >= 2:
        data["limits"]["support"] = {"frames": frames[:2], "frame_type": "body", "margin": 0.0}
    if spec["mode"] == "track":
        data["track"] = {"dt": 0.01, "steps": 20}
    else:
        data["solver"] = {"restarts": spec["restarts"], "max_iters": spec["max_iters"]}
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "erd.toml"
        path.write_text(to_toml(data), encoding="utf-8")
        problem = qpik.load_problem(path)
        result = problem.solve()
    _check_problem_run(problem, result)
    return _digest(result.q)


# -- wrong types for every argument of every public function
def _signature_value(label: str, model):
    np = _np()
    import qpik

    return {
        "none": None,
        "str": "x",
        "bytes": b"ee",
        "dict": {"a": 1},
        "mjmodel": model,
        "nested": [[1.0, [2.0]], 3.0],
        "int_array": np.arange(3),
        "bool_array": np.ones(3, dtype=bool),
        "complex_array": np.ones(3, dtype=complex),
        "object_array": np.array([1.0, "x", None], dtype=object),
        "array_3d": np.zeros((2, 2, 2)),
        "array_0d": np.array(1.0),
        "empty_array": np.zeros(0),
        "bool": True,
        "huge_int": 2**100,
        "neg_int": -(2**40),
        "nan": NAN,
        "inf": INF,
        "object": object(),
        "configuration": qpik.Configuration(model),
        "lambda": lambda *a: None,
        "set": {1.0, 2.0},
        "str_array": np.array(["a", "b", "c"]),
    }[label]


class _Ctx:
    """Valid arguments by parameter name, for one robot."""

    def __init__(self, robot: str, folder: Path):
        np = _np()
        import qpik

        self.robot = robot
        self.model = model = qpik.load_robot(robot)
        self.cfg = qpik.Configuration(model, _q_value("mid", model, None))
        self.position = self.cfg.frame_pose("ee", "site")[0]
        task = qpik.tasks.PositionTask("ee", "site")
        task.set_target(self.position + 0.01)
        self.task = task
        self.J = self.cfg.frame_jacobian("ee", "site")
        self.path = folder / "p.toml"
        self.path.write_text(
            to_toml(
                {
                    "robot": robot,
                    "levels": [[{"type": "position", "frame": "ee"}]],
                    "target": {"frame": "ee", "position": [float(x) for x in self.position]},
                    "solver": {"restarts": 0, "max_iters": 10},
                }
            )
        )
        lower, upper = _limits_of(model)
        self.values = {
            "robot": robot,
            "source": robot,
            "model": model,
            "configuration": self.cfg,
            "targets": {"ee": self.position},
            "targets_list": [{"ee": self.position}],
            "frame": "ee",
            "frame_name": "ee",
            "frame_type": "site",
            "root_name": "link1" if robot != "panda" else "link1",
            "root_type": "body",
            "q": self.cfg.q.copy(),
            "q0": self.cfg.q.copy(),
            "J": self.J,
            "xi": np.array([0.01, 0.0, 0.0, 0.0, 0.0, 0.0]),
            "zeta": np.ones(model.nv) * 0.1,
            "lower": np.where(np.isfinite(lower), lower, -3.0),
            "upper": np.where(np.isfinite(upper), upper, 3.0),
            "force": [0.0, 0.0, -1.0],
            "direction": [0.0, 0.0, -1.0],
            "tau": np.zeros(model.nv),
            "dt": 0.01,
            "tasks": [[task]],
            "stack": [[task]],
            "limits": [qpik.limits.ConfigurationLimit(model)],
            "pairs": [],  # (geom id pairs: always_in_contact's; none, a valid list)
            "path": str(self.path),
            "region": [[-0.1, -0.1, 0.0], [0.1, 0.1, 0.1]],
            "resolution": 0.1,
            "orientations": 1,
            "cost": 1.0,
            "position_cost": 1.0,
            "orientation_cost": 1.0,
            "dof_indices": [0],
            "velocities": {n: 1.0 for n in qpik.joint_names(model)},
            "contact_frames": [("ee", "site")],
            "damping": 0.01,
            "residual_history": [[0.1, 0.2], [0.05, 0.1]],
            "geom_pairs": [([0], [model.ngeom - 1])],
            "v": np.zeros(model.nv),
            "velocity": np.zeros(model.nv),
            "geom1": 0,
            "geom2": model.ngeom - 1,
            "R_current": np.eye(3),
            "R_target": np.eye(3),
        }


# Complexity above 10: one branch per kind of callable (method, class, function).
def _signature_call(spec: dict, ctx):
    """(callable, its signature, the valid arguments) of ``spec["target"]``."""
    import inspect

    import qpik

    name = spec["target"]
    np = _np()
    if name == "IKSolver.step":
        solver = qpik.IKSolver(ctx.model, [[ctx.task]], [qpik.limits.ConfigurationLimit(ctx.model)])
        fn = solver.step
    elif name == "IKSession.solve":
        fn = qpik.IKSession(ctx.robot).solve
    elif name.startswith("Configuration."):
        fn = getattr(qpik.Configuration(ctx.model, ctx.cfg.q), name.split(".")[1])
    elif name == "Problem.solve":
        fn = qpik.load_problem(ctx.path).solve
    else:
        import importlib

        module, attribute = name.rsplit(".", 1)
        fn = getattr(importlib.import_module(module), attribute)
    sig = inspect.signature(fn)
    args = {}
    for p in sig.parameters.values():
        if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            continue
        if p.default is p.empty or p.name in ("progress",):
            if p.name == "progress":
                args[p.name] = False
            elif p.name in ctx.values:
                args[p.name] = ctx.values[p.name]
            else:
                args[p.name] = _SIGNATURE_FALLBACK.get(p.name, None)
    if name in ("Configuration.integrate", "Configuration.integrate_inplace"):
        args = {"velocity": np.zeros(ctx.model.nv), "dt": 0.01}
    if name.startswith("qpik.plots."):
        import matplotlib

        matplotlib.use("Agg")
        if "path" in args:
            args["path"] = np.array([ctx.cfg.q, ctx.cfg.q])
    if name in ("qpik.solve_many", "qpik.reachability"):
        args.update(workers=1, max_iters=5, restarts=0)
    if name == "qpik.reachability":
        args["backend"] = "thread" if "thread" in str(sig) else "process"
    if name == "qpik.analysis.nullspace_step":
        args["zeta"] = np.ones(ctx.model.nv) * 0.1
    return fn, sig, args


_CLEARLY_WRONG = {"none", "bytes", "dict", "mjmodel", "object", "lambda", "set", "configuration"}


def _names_argument(text: str, name: str, value) -> bool:
    """Whether an error message names the argument: its name (any case, ``_`` or a
    space), or the offending value itself (a string or number; a key of a mapping)."""
    low = text.lower()
    if name.lower() in low or name.lower().replace("_", " ") in low:
        return True
    if isinstance(value, (str, int, float)) and not isinstance(value, bool):
        return str(value) in text or repr(value) in text
    if isinstance(value, dict):
        return any(str(k) in text for k in value)
    return False


_SIGNATURE_FALLBACK = {"curves": [], "result": None, "wrenches": ()}


# Complexity above 10: one branch per outcome of a wrong-type call.
def run_signature(spec: dict) -> str:
    import qpik

    with tempfile.TemporaryDirectory() as folder:
        ctx = _Ctx(spec["robot"], Path(folder))
        fn, sig, args = _signature_call(spec, ctx)
        params = [
            p
            for p in sig.parameters.values()
            if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD) and p.name != "progress"
        ]
        if not params:
            raise Typed("no parameter")
        param = params[spec["pick"] % len(params)]
        wrong = _signature_value(spec["value"], ctx.model)
        args[param.name] = wrong
        positional = []
        if spec["positional"] and param.kind in (
            param.POSITIONAL_ONLY,
            param.POSITIONAL_OR_KEYWORD,
        ):
            for p in params:
                if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) and p.name in args:
                    positional.append(args.pop(p.name))
                else:
                    break
        try:
            out = fn(*positional, **args)
        except qpik.QpikError as exc:
            # a value of a wrong type must be named; a value of the right type may fail
            # further on (no geom pair left, an unknown frame) with that reason instead
            wrong_type = isinstance(exc, TypeError) or spec["value"] in _CLEARLY_WRONG
            if spec["value"] == "none" and param.default is None:
                wrong_type = False  # None is this argument's default: a valid value
            if spec["value"] == "mjmodel" and param.name == "model":
                wrong_type = False  # an MjModel is what a model argument takes
            if wrong_type and not _names_argument(str(exc), param.name, wrong):
                detail = f"{spec['target']}({param.name}={spec['value']}): {str(exc)[:200]}"
                raise Bad("message", detail) from None
            raise
        if not spec["target"].endswith("condition_number"):
            _finite(out, "returned", allow=(".solve_time", ".elapsed", ".condition_number"))
        if spec["target"].startswith("qpik.plots."):
            import matplotlib.pyplot as plt

            plt.close("all")
        return _digest(repr(type(out)))


# -- attributes changed after the build
MUTABLE = (
    "cost", "position_cost", "orientation_cost", "gain", "lm_damping", "frame_name",
    "frame_type", "root_name", "root_type", "body", "target_q", "target_com", "lower",
    "upper", "limit", "minimum_distance_from_collisions", "collision_detection_distance",
    "dof_indices", "axis", "target_dir", "target_pos", "target", "target_position",
    "target_rotation", "margin", "bound_relaxation", "max_num_contacts", "geom_id_pairs",
    "inv_dt_sq", "joints", "subdivisions", "rows",
)  # fmt: skip


def _mutation_values(obj, name: str, model, configuration, rng) -> list:
    """Candidate new values of ``obj.name``, ``(valid, weird)``: each a list of
    ``(how, value)``, how "set" (an assignment) or "inplace" (an in-place write of an
    array's entries); valid ones within what the attribute takes, weird ones not."""
    np = _np()
    import mujoco

    current = getattr(obj, name)
    weird = [("set", v) for v in (NAN, -1.0, "x", None, np.ones(5), np.full(3, NAN))]
    if name in ("frame_name", "root_name"):
        kind = getattr(obj, "frame_type" if name == "frame_name" else "root_type", "body")
        obj_type = {"site": mujoco.mjtObj.mjOBJ_SITE, "geom": mujoco.mjtObj.mjOBJ_GEOM}.get(
            kind, mujoco.mjtObj.mjOBJ_BODY
        )
        count = {"site": model.nsite, "geom": model.ngeom}.get(kind, model.nbody)
        names = [mujoco.mj_id2name(model, obj_type, i) for i in range(count)]
        names = [n for n in names if n]
        return [("set", n) for n in names[-3:]], [("set", "nope"), ("set", 3)]
    if name in ("frame_type", "root_type"):
        return [("set", v) for v in ("body", "site", "geom")], [("set", "nope"), ("set", None)]
    if name == "body":
        valid = [("set", v) for v in (0, 1, model.nbody - 1)]
        return valid, [("set", v) for v in (model.nbody, -1, "x")]
    limited = isinstance(current, np.ndarray) and current.shape == (model.nq,)
    if name in ("lower", "upper") and limited and hasattr(obj, "indices"):
        q = configuration.q
        idx = np.asarray(obj.indices, dtype=np.int64)
        adr = model.jnt_qposadr[model.dof_jntid[idx]] if idx.size else idx
        narrowed = current.copy()
        room = np.abs(rng.normal(0.0, 0.05, size=adr.size))
        narrowed[adr] = q[adr] + (room if name == "upper" else -room)
        flipped = current.copy()
        if adr.size:
            flipped[adr[0]] = q[adr[0]] + (-1.0 if name == "upper" else 1.0)
        return [("inplace", narrowed), ("set", narrowed)], [("set", flipped)] + weird[:5]
    if isinstance(current, np.ndarray) and current.dtype.kind == "f" and current.ndim >= 1:
        scaled = current * rng.uniform(0.1, 3.0)
        zero = np.zeros_like(current)
        return [("set", scaled), ("inplace", scaled), ("set", zero)], weird
    if name == "dof_indices":
        return [("set", [0]), ("set", [model.nv - 1])], [("set", [model.nv]), ("set", [0, 0])]
    if name == "rows":
        return [("set", "position"), ("set", "orientation")], [("set", "bogus"), ("set", 3)]
    if name == "geom_id_pairs" and isinstance(current, list):
        return [("set", current[:1]), ("set", current[::-1])], [("set", [(0, 10**6)])]
    if isinstance(current, int) and not isinstance(current, bool):
        return [("set", current), ("set", max(1, current - 1))], [("set", -1), ("set", "x")]
    if isinstance(current, float):
        return [("set", float(current) * 0.5), ("set", 0.5)], weird[:4]
    if isinstance(current, (list, tuple)) and current:
        return [("set", type(current)(current[:1]))], [("set", "x"), ("set", None)]
    return [], weird


def _step_outcome(make, configuration, dt) -> tuple:
    """("ok", velocity) or ("typed", error class name) of ``make().step(configuration, dt)``
    (``make()`` None: of ``qpik.solve_ik`` by the case's call, its solver cache kept; an
    untyped error propagates: the harness counts it)."""
    np = _np()
    import qpik

    try:
        solver = make()
        if isinstance(solver, qpik.IKSolver):
            velocity = np.array(solver.step(configuration, dt).velocity)
        else:
            velocity = np.array(solver(configuration, dt))
    except qpik.QpikError as exc:
        return ("typed", type(exc).__name__)
    _finite(velocity, "velocity")
    return ("ok", velocity)


def run_mutate(spec: dict) -> str:
    np = _np()
    import mink

    import qpik

    model = _stack_model(spec["robot"])
    rng = np.random.default_rng(_seed_of(spec))
    try:
        configuration, levels, limits = _stack_objects(spec, model, rng)
    except mink.exceptions.MinkError as exc:
        if isinstance(exc, qpik.QpikError):
            raise
        raise Typed(f"mink's own constructor: {exc}") from None
    dt = spec["dt"]
    backend = None if spec["solver"] == "auto" else spec["solver"]
    if spec["entry"] == "solve_ik":  # mink's call, its kept solver (qpik's solver cache)
        qpik.clear_caches()

        def solver(configuration, dt):
            return qpik.solve_ik(configuration, levels, dt, solver=backend, limits=limits)

        def fresh_solver():
            qpik.clear_caches()
            return solver
    else:
        solver = qpik.IKSolver(model, levels, limits, solver=spec["solver"])
        settings: dict = {}

        def fresh_solver():
            return qpik.IKSolver(model, levels, limits, solver=spec["solver"], **settings)

    _step_outcome(lambda: solver, configuration, dt)  # the step that builds its state
    if spec["entry"] == "step" and spec.get("setting"):
        name, value = spec["setting"]
        if name == "damping_law":
            law = {"none": None, "strong": qpik.DampingLaw(0.3, 0.2, None)}.get(value, value)
            value = law
        try:
            setattr(solver, name, value)
            settings[name] = value
        except qpik.QpikError:
            pass  # (refused where it is set: the solver keeps its own)
    objects = [t for level in levels for t in level] + list(limits)
    applied = []
    for o_pick, a_pick, v_pick, weird in spec["mutations"]:
        obj = objects[o_pick % len(objects)]
        names = [n for n in MUTABLE if hasattr(obj, n) and not callable(getattr(obj, n))]
        if not names:
            continue
        name = names[a_pick % len(names)]
        valid, bad = _mutation_values(obj, name, model, configuration, rng)
        values = bad if weird or not valid else valid
        how, value = values[v_pick % len(values)]
        try:
            if how == "inplace":
                getattr(obj, name)[...] = value
            else:
                setattr(obj, name, value)
        except (AttributeError, TypeError, ValueError):
            continue  # (an attribute its class does not let be set, or not to this)
        applied.append(f"{type(obj).__name__}.{name} {how} {str(value)[:40]}")
    old = _step_outcome(lambda: solver, configuration, dt)
    fresh = _step_outcome(fresh_solver, configuration, dt)
    if old[0] != fresh[0]:
        typed = old[1] if old[0] == "typed" else fresh[1]
        detail = f"after {applied}: the solver {old[0]}, a new one {fresh[0]} ({typed})"
        raise Bad("stale", detail)
    if old[0] == "typed":
        raise Typed(old[1])
    gap = float(np.max(np.abs(old[1] - fresh[1]), initial=0.0))
    if gap > 1e-9 * (1.0 + float(np.max(np.abs(fresh[1]), initial=0.0))):
        raise Bad("stale", f"after {applied}: |v - v_new| = {gap:.3g} rad/s")
    return _digest(old[1])


# -- determinism
RUNNERS = {
    "solve": run_solve,
    "solve_many": run_solve_many,
    "step": run_step,
    "problem": run_problem,
    "robot_file": run_robot_file,
    "statics": run_statics,
    "analysis": run_analysis,
    "cli": run_cli,
    "boundary": run_boundary,
    "engine": run_engine,
    "robot_gen": run_robot_gen,
    "schema": run_schema,
    "stack": run_stack,
    "signature": run_signature,
    "erd": run_erd,
    "mutate": run_mutate,
}


def run_determinism(spec: dict) -> str:
    runner = RUNNERS[spec["base"]]
    first = _outcome(runner, spec["spec"])
    for p in spec["pollution"]:
        _outcome(RUNNERS[p["category"]], p["spec"])
    second = _outcome(runner, spec["spec"])
    # the outcome and the digest of the answer (the detail names temporary files)
    if (first[0], first[2]) != (second[0], second[2]):
        raise Bad("nondet", f"{spec['base']}: {first} then {second}")
    if first[0] in BAD:
        raise Bad(first[0], first[1])
    if first[0] == "typed":
        raise _TypedMarker(first[1])
    return first[2]


class _TypedMarker(Exception):
    pass


RUNNERS["determinism"] = run_determinism


def _outcome(runner, spec) -> tuple[str, str, str]:
    """(outcome, detail, digest) of one call; typed / untyped by the exception's class."""
    import warnings

    import qpik

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            digest = runner(spec)
        return ("ok", "", digest)
    except Bad as exc:
        return (exc.kind, exc.detail, "")
    except (qpik.QpikError, Typed, _TypedMarker) as exc:
        if isinstance(exc, _TypedMarker):
            return ("typed", str(exc), str(exc).split(":")[0])
        return ("typed", f"{type(exc).__name__}: {str(exc)[:300]}", type(exc).__name__)
    except Exception as exc:  # noqa: BLE001 - the point of the campaign
        tb = traceback.extract_tb(exc.__traceback__)
        where = next(
            (
                f"{Path(f.filename).name}:{f.lineno}"
                for f in reversed(tb)
                if "qpik" in f.filename or "mink" in f.filename
            ),
            "",
        )
        return ("untyped", f"{type(exc).__name__} at {where}: {str(exc)[:300]}", type(exc).__name__)


def _warm_up() -> None:
    """Import qpik (the compiled engine, MuJoCo, the QP solvers) and run each path once,
    so that no case's time includes loading or first-call setup; record the engine's
    kernel calls for the engine category."""
    import numpy as np

    import qpik

    for robot in ROBOTS:
        with contextlib.suppress(Exception):
            qpik.solve(robot, {"ee": [0.3, 0.1, 0.3]}, restarts=0, max_iters=5)
    model = qpik.load_robot("panda")
    for solver in ("osqp", "daqp", "quadprog"):
        with contextlib.suppress(Exception):
            task = qpik.tasks.PositionTask("ee", "site")
            task.set_target(np.array([0.4, 0.1, 0.4]))
            qpik.IKSolver(
                model, [[task]], [qpik.limits.ConfigurationLimit(model)], solver=solver
            ).step(qpik.Configuration(model), 0.01)
    for path in _shipped_problems()[:2]:
        with contextlib.suppress(Exception):
            qpik.load_problem(path)
    _ENGINE_CALLS.update(_record_engine_calls())


def _worker(conn, quiet: bool, memory_gib: float = 0.0) -> None:
    """Worker process: receive (category, spec), answer (outcome, detail, digest)."""
    if quiet:  # OSQP and MuJoCo print on the C side: silence the file descriptors too
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 1000))
    if memory_gib > 0:  # an unchecked size fails as MemoryError, not by swapping the machine
        import resource

        limit = int(memory_gib * 2**30)
        resource.setrlimit(resource.RLIMIT_AS, (limit, resource.getrlimit(resource.RLIMIT_AS)[1]))
    import faulthandler

    faulthandler.disable()
    _warm_up()
    conn.send("ready")
    while True:
        try:
            job = conn.recv()
        except EOFError:
            return
        if job is None:
            return
        category, spec = job
        start = time.process_time()
        outcome = _outcome(RUNNERS[category], spec)
        conn.send((*outcome, time.process_time() - start))


# =============================================================================== parent
class _Slot:
    def __init__(self, ctx, quiet: bool, memory_gib: float = 0.0):
        self.ctx = ctx
        self.quiet = quiet
        self.memory_gib = memory_gib
        self.start()

    def start(self) -> None:
        parent, child = self.ctx.Pipe()
        self.conn = parent
        self.process = self.ctx.Process(
            target=_worker, args=(child, self.quiet, self.memory_gib), daemon=True
        )
        self.process.start()
        child.close()
        self.job = None
        self.started = 0.0
        self.ready = False
        self.first = True
        self.cpu: list = getattr(self, "cpu", [])
        self.spawned = time.monotonic()

    def poll_ready(self, limit: float = 900.0) -> bool:
        """Whether the worker has warmed up (it sends "ready" once)."""
        if not self.ready and self.conn.poll():
            message = self.conn.recv()
            self.ready = message == "ready"
        if not self.ready and time.monotonic() - self.spawned > limit:
            raise RuntimeError(f"a fuzz worker did not start in {limit:.0f} s")
        if not self.ready and not self.process.is_alive():
            raise RuntimeError(f"a fuzz worker died while starting (exit {self.process.exitcode})")
        return self.ready

    def kill(self) -> None:
        self.process.kill()
        self.process.join()
        self.conn.close()


def run_campaign(
    jobs: list[tuple[str, int, dict]],
    workers: int,
    timeout: float,
    quiet: bool = True,
    progress: bool = True,
    memory_gib: float = 0.0,
) -> list[tuple]:
    """Run every job; returns (category, index, outcome, detail, digest, seconds)."""
    ctx = mp.get_context("spawn")
    slots = [_Slot(ctx, quiet, memory_gib) for _ in range(workers)]
    pending = list(reversed(jobs))
    results = []
    start = time.monotonic()
    last_print = start
    while pending or any(s.job for s in slots):
        _dispatch(slots, pending)
        ready = mp.connection.wait([s.conn for s in slots], timeout=0.2)
        now = time.monotonic()
        for s in slots:
            if s.job is not None:
                result = _collect(s, s.conn in ready, now, timeout)
                if result is not None:
                    results.append(result)
        finished = not pending and not any(s.job for s in slots)
        if progress and (now - last_print > 10 or finished):
            last_print = now
            bad = sum(1 for r in results if r[2] in BAD)
            print(
                f"  {len(results)}/{len(jobs)} cases, {bad} bad, {now - start:.0f} s",
                file=sys.stderr,
                flush=True,
            )
    _shutdown(slots)
    CPU_TIMES.extend(item for s in slots for item in s.cpu)
    return results


def _dispatch(slots: list, pending: list) -> None:
    """Give each idle, ready worker the next job."""
    for s in slots:
        if s.job is None and pending and s.poll_ready():
            s.job = pending.pop()
            s.conn.send((s.job[0], s.job[2]))
            s.started = time.monotonic()


def _collect(s, answered: bool, now: float, timeout: float) -> tuple | None:
    """The result of a worker's job once it answered, died or ran past ``timeout`` (the
    worker is then restarted); ``None`` while it is still running."""
    category, index, _spec = s.job
    elapsed = now - s.started
    if answered:
        try:
            outcome, detail, digest, cpu = s.conn.recv()
        except (EOFError, OSError):
            s.process.join(1)
            result = (category, index, "crash", f"worker died (exit {s.process.exitcode})", "")
            s.kill()
            s.start()
        else:
            # the issue's hang: over HANG s (the first case of a worker: 3 HANG), measured
            # as this worker's CPU time, which other loads on the machine do not inflate
            limit = HANG * (3.0 if s.first else 1.0)
            if cpu > limit and outcome not in BAD:
                outcome, detail = "hang", f"{cpu:.1f} s of CPU (over {limit:.0f} s)"
            result = (category, index, outcome, detail, digest)
            s.cpu.append((cpu, f"{category}:{index}"))
            s.first = False
    elif elapsed > timeout:
        result = (category, index, "hang", f"no answer in {timeout:.0f} s", "")
        s.kill()
        s.start()
    else:
        return None
    s.job = None
    return (*result, elapsed)


def _shutdown(slots: list) -> None:
    for s in slots:
        try:
            s.conn.send(None)
        except OSError:
            pass
        s.process.join(5)
        if s.process.is_alive():
            s.kill()


def table(results: list[tuple]) -> str:
    counts: dict[str, Counter] = defaultdict(Counter)
    for category, _, outcome, *_ in results:
        counts[category][outcome] += 1
    header = f"{'category':<12} {'cases':>6} " + " ".join(f"{c:>9}" for c in COLUMNS)
    lines = [header, "-" * len(header)]
    total: Counter = Counter()
    for category in CATEGORIES:
        if category not in counts:
            continue
        c = counts[category]
        total.update(c)
        lines.append(
            f"{category:<12} {sum(c.values()):>6} " + " ".join(f"{c[k]:>9}" for k in COLUMNS)
        )
    lines.append("-" * len(header))
    lines.append(
        f"{'all':<12} {sum(total.values()):>6} " + " ".join(f"{total[k]:>9}" for k in COLUMNS)
    )
    return "\n".join(lines)


#: Relative share of the cases per category.
WEIGHTS = {
    "solve": 3,
    "solve_many": 1,
    "step": 3,
    "problem": 2,
    "robot_file": 2,
    "statics": 2,
    "analysis": 2,
    "cli": 1,
    "determinism": 1,
    "boundary": 3,
    "engine": 3,
    "robot_gen": 3,
    "schema": 3,
    "stack": 3,
    "signature": 3,
    "erd": 3,
    "mutate": 3,
}


def parse(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=at_least(0), default=2000, help="number of cases (2000)")
    parser.add_argument("--seed", type=at_least(0), default=0, help="campaign seed (0)")
    parser.add_argument("--workers", type=at_least(1), default=2, help="worker processes (2)")
    parser.add_argument(
        "--timeout", type=positive_float, default=60.0, help="per-case limit [s] (60)"
    )
    parser.add_argument(
        "--hang", type=positive_float, default=HANG, help="CPU seconds that make a case a hang (5)"
    )
    parser.add_argument("--categories", nargs="+", choices=CATEGORIES, default=list(CATEGORIES))
    parser.add_argument(
        "--case",
        metavar="CATEGORY:INDEX",
        help="run one case in this process and print its spec and traceback",
    )
    parser.add_argument(
        "--memory",
        type=nonnegative_float,
        default=8.0,
        help="address-space limit of each worker [GiB] (8; 0: none)",
    )
    parser.add_argument("--show", type=at_least(0), default=40, help="bad cases listed (40)")
    parser.add_argument("--list", action="store_true", help="list the categories")
    parser.add_argument("--verbose", action="store_true", help="let workers print (OSQP, ...)")
    return parser.parse_args(argv)


def main(argv=None) -> int:
    args = parse(argv)
    if args.list:
        print("\n".join(CATEGORIES))
        return 0
    if args.case:
        return run_one(args.seed, args.case)
    jobs, repeats = make_jobs(args.n, args.seed, args.categories)
    print(
        f"fuzz: {len(jobs)} cases ({repeats} determinism repeats), seed {args.seed}, "
        f"{args.workers} workers, {args.timeout:.0f} s per case",
        flush=True,
    )
    global HANG
    HANG = args.hang
    start = time.monotonic()
    results = run_campaign(
        jobs, args.workers, args.timeout, quiet=not args.verbose, memory_gib=args.memory
    )
    wall = time.monotonic() - start
    final = cross_process(results)
    print(table(final))
    times = sorted(r[5] for r in final)
    if times:
        print(
            f"wall {wall:.0f} s; per case: median {1e3 * times[len(times) // 2]:.0f} ms, "
            f"max {times[-1]:.1f} s"
        )
    slowest = sorted(CPU_TIMES, reverse=True)[:5]
    print("most CPU: " + ", ".join(f"{name} {cpu:.1f} s" for cpu, name in slowest))
    bad = [r for r in final if r[2] in BAD]
    for category, index, outcome, detail, *_ in bad[: args.show]:
        print(f"  {outcome:<9} {category}:{index}  {detail}")
    if len(bad) > args.show:
        print(f"  ... and {len(bad) - args.show} more")
    typed = Counter(r[3].split(":")[0] for r in final if r[2] == "typed")
    print("typed errors: " + ", ".join(f"{k} {v}" for k, v in typed.most_common()))
    print(f"bad outcomes: {len(bad)}")
    return 1 if bad else 0


def run_one(seed: int, case: str) -> int:
    """``--case CATEGORY:INDEX``: one case in this process, its spec and traceback."""
    import qpik

    category, index = case.split(":")
    spec = make_spec(seed, category, int(index))
    print(f"spec = {spec!r}")
    try:
        digest = RUNNERS[category](spec)
        print(f"ok: digest {digest}")
    except (qpik.QpikError, Typed) as exc:
        print(f"typed: {type(exc).__name__}: {exc}")
    except Exception:
        traceback.print_exc()
        return 1
    return 0


def make_jobs(n: int, seed: int, chosen: list[str]) -> tuple[list[tuple], int]:
    """The campaign's jobs, shuffled, each determinism case then repeated (in another
    history); and the number of repeats."""
    total_weight = sum(WEIGHTS[c] for c in chosen)
    jobs = []
    for category in chosen:
        count = max(1, round(n * WEIGHTS[category] / total_weight))
        for index in range(count):
            jobs.append((category, index, make_spec(seed, category, index)))
    random.Random(seed).shuffle(jobs)
    repeats = [(c, i, s) for c, i, s in jobs if c == "determinism"]
    return jobs + [("determinism", -1 - i, s) for c, i, s in repeats], len(repeats)


def cross_process(results: list[tuple]) -> list[tuple]:
    """The results with each determinism repeat compared with its original: a different
    digest, or a different outcome (hangs aside), is ``nondet``; repeats are dropped."""
    by_index = {(r[0], r[1]): r for r in results}
    final = []
    for r in results:
        category, index = r[0], r[1]
        if not (category == "determinism" and index < 0):
            final.append(r)
            continue
        original = by_index.get(("determinism", -1 - index))
        if original is None:
            continue
        detail = None
        if original[2] == r[2] == "ok" and original[4] != r[4]:
            detail = f"digest {original[4]} in one worker, {r[4]} in another"
        elif original[2] != r[2] and "hang" not in (original[2], r[2]):
            detail = f"{original[2]} in one worker, {r[2]} in another"
        if detail is not None:
            final.append((category, -1 - index, "nondet", detail, "", r[5]))
    return final


if __name__ == "__main__":
    import bench_cli  # benchmarks/bench_cli.py (this folder is on sys.path)

    bench_cli.run(main)
