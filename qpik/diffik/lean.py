"""The values a :class:`~qpik.diffik.compiled.CompiledPlan`'s kernel reads from the task
and limit objects itself at each lean step (``Kernel.set_slots`` / ``Kernel.set_sources``):
which view of the plan's arrays each value goes to, and where it comes from."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from .layout import DAMPING, DT, POSE_COST

__all__ = ["lean_slots", "lean_sources"]


def lean_slots(plan: Any) -> tuple[list, list]:
    """The views a :class:`~qpik.diffik.compiled.CompiledPlan`'s lean step fills (``dt``,
    ``damping``, then :func:`lean_sources`' values in order), and which take one number."""
    views: list = []
    scalar: list = []

    def add(view: np.ndarray, one: bool = False) -> None:
        views.append(view)
        scalar.append(one)

    def task(targets, cost, gain: np.ndarray, lm: np.ndarray) -> None:  # a task's values
        views.extend((*targets, cost, gain, lm))
        scalar.extend((*(False for _ in targets), False, True, True))

    a = plan.arrays
    settings = a["settings"]
    add(settings[DT : DT + 1], True)
    add(settings[DAMPING : DAMPING + 1], True)
    for *_, (row, target, cost), names in plan.frames:  # (names: a pose task's targets)
        g = 13 if names is None else POSE_COST + 6
        task((target,) if names is None else target, cost, row[g : g + 1], row[g + 1 : g + 2])
    for _task, (row, target, cost), damping in plan.postures:
        if not damping:  # a damping task's error is zero: no target
            add(target)
        add(cost)
        add(row[-2:-1], True)
        add(row[-1:], True)
    for *_, (row, target, cost) in plan.coms:
        task((target,), cost, row[6:7], row[7:8])
    for *_, (row, target, cost) in plan.relatives:
        task((target,), cost, row[13:14], row[14:15])
    lin = a["lin_data"]
    for _task, r0, cost_view in plan.linears:
        add(cost_view)
        add(lin[1, r0 : r0 + 1], True)
        add(lin[2, r0 : r0 + 1], True)
    for _task, row in plan.kinetics:  # its cost and 1 / dt^2
        add(row[0:1], True)
        add(row[1:2], True)
    for t, row in plan.equalities:  # its costs by position, gain, LM damping
        add(row[: len(t._cost)])
        add(row[-2:-1], True)
        add(row[-1:], True)
    _limit_slots(plan, add)
    return views, scalar


def _limit_slots(plan: Any, add: Callable) -> None:
    """:func:`lean_slots`' limits: the position limits' bounds and gains, the velocity
    limits' speeds, each view passed to ``add(view, scalar)``."""
    a = plan.arrays
    for _limit, e0, e1 in plan.config_limits:
        if e1 > e0:  # (a model without limited joints: no entries)
            add(a["cfg_data"][e0:e1, 0])
            add(a["cfg_data"][e0:e1, 1])
        add(a["cfg_data"][e0:e1, 2], True)
    for _limit, v0, v1 in plan.vel_limits:
        add(a["vel_limit"][v0:v1])


def lean_sources(plan: Any) -> tuple[list, int]:
    """Where the kernel reads the values of :func:`lean_slots` after ``dt`` and ``damping``
    (``Kernel.set_sources``, in the same order), and the index of the limits' first: each
    task's target, cost, gain and LM damping, the position limits' bounds and gains and the
    velocity limits' speeds, read by the kernel at each lean step (and the limits' at each
    gathered step, ``Kernel.load_limits``), as ``CompiledPlan.gather`` copies them (a value
    it does not take as it is, a target not set: ``gather`` writes them, or raises)."""
    sources: list = []

    def task(t, target=None, inner=None) -> None:  # (target: a name, or a tuple of them)
        if isinstance(target, tuple):
            sources.extend((t, name) for name in target)
        elif target is not None:
            sources.append((t, target) if inner is None else (t, target, inner))
        sources.extend(((t, "cost"), (t, "gain"), (t, "lm_damping")))

    for t, *_, names in plan.frames:  # (names: a world-frame pose task's targets)
        frame = names is None  # (a frame task: its SE3 target's wxyz_xyz)
        task(t, "transform_target_to_world" if frame else names, "wxyz_xyz" if frame else None)
    for t, _views, damping_task in plan.postures:
        task(t, None if damping_task else "target_q")
    for t, *_ in plan.coms:
        task(t, "target_com")
    for t, *_ in plan.relatives:
        task(t, "transform_target_to_root", "wxyz_xyz")
    for t, *_ in plan.linears:
        task(t)
    for t, _row in plan.kinetics:  # (a time step not set: None, which gather reports)
        sources.extend(((t, "cost"), (t, "inv_dt_sq")))
    for t, _row in plan.equalities:  # (mink 1.3's costs by position, _cost)
        sources.extend(((t, "_cost"), (t, "gain"), (t, "lm_damping")))
    first_limit = len(sources)
    _limit_sources(plan, sources)
    return sources, first_limit


def _limit_sources(plan: Any, sources: list) -> None:
    """:func:`lean_sources`' limits, appended to ``sources``: the position limits' bounds
    [rad or m] at each dof's qpos entry and gains, the velocity limits' speeds."""
    qadr = plan.arrays["cfg_qadr"]
    for limit, e0, e1 in plan.config_limits:  # bounds [rad or m] at each dof's qpos entry
        if e1 > e0:
            picked = qadr[e0:e1].tolist()
            sources.extend(((limit, "lower", picked), (limit, "upper", picked)))
        sources.append((limit, "gain"))
    sources.extend((limit, "limit") for limit, *_ in plan.vel_limits)
