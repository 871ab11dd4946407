"""Second-order correction of a step (:attr:`qpik.StepOptions.correction_passes`).

A step holds its held levels' rows ``A_k dq = b_k`` (``A = diag(cost) J``, ``b = -gain cost
e``), but after ``q <- q (+) dq`` a held task keeps the remainder ``r = e(q (+) dq) - e(q) -
J dq``, of order ``|dq|^2``. A pass evaluates the held tasks' errors once at ``q (+) dq``
(one forward kinematics, no Jacobian), shifts those levels' targets, ``b <- b - cost r``
(``cost r = cost (e(q (+) dq) - e(q)) - A dq``), and solves the step again with the same
rows, damping and limits: what is left is of order ``|dq|^3``.

- :func:`held_levels`: the levels a step holds (the ones a pass shifts);
- :func:`qp_corrected`: the corrected step on the QP path (rows from the tasks, the core's
  cascade);
- :class:`LeanCorrection`: the passes of the compiled step (``Kernel.correct`` for the lean
  step, ``Kernel.correct_run`` for one with general rows; qpik/_cpp/diffik/fused.hpp decides
  the held levels by the same rule).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import mink
import mujoco
import numpy as np

from ..core import HierarchySolver, LevelStatus
from ..model.configuration import Configuration
from .boxes import LimitRows
from .result import Solution, solve_rows
from .rows import TaskRows, task_rows

__all__ = [
    "HELD_FRACTION",
    "HELD_ROUNDOFF",
    "LeanCorrection",
    "held_levels",
    "qp_corrected",
    "weighted_error",
]

#: A level is held when its residual is at most this fraction of its targets' norm, plus
#: :data:`HELD_ROUNDOFF` ``|A_k|_F |dq|`` (the kernel's ``kHeldFraction``, ``kHeldRoundoff``).
HELD_FRACTION, HELD_ROUNDOFF = 1e-2, 1e-9

#: ``Kernel.correct``'s answer when the pass went through (the kernel's OK).
_OK = 0


def held_levels(tasks: TaskRows, solution: Solution) -> list[bool]:
    """Per level, whether ``solution`` holds it: its status is solved and its residual
    ``|A_k dq - b_k| <= 1e-2 |b_k| + 1e-9 |A_k|_F |dq|``."""
    d = solution.displacement
    step = math.sqrt(float(d @ d))
    starts = tasks.starts.tolist()
    held = []
    for k, (s0, s1) in enumerate(zip(starts[:-1], starts[1:])):
        b, A = tasks.b[s0:s1], tasks.A[s0:s1]
        bound = (
            HELD_FRACTION * math.sqrt(float(b @ b))
            + HELD_ROUNDOFF * math.sqrt(float((A * A).sum())) * step
        )
        held.append(solution.status[k] == LevelStatus.SOLVED and solution.residuals[k] <= bound)
    return held


def weighted_error(task, configuration) -> tuple[int | None, np.ndarray | None]:
    """``(rows, cost e)`` of a task that follows mink's :class:`mink.Task` contract (rows
    ``diag(cost) J``, ``-gain cost e``), else ``(None, None)``."""
    if not isinstance(task, mink.Task):
        return None, None
    error = np.asarray(task.compute_error(configuration), dtype=float).reshape(-1)
    try:
        cost = np.broadcast_to(np.asarray(task.cost, dtype=float), error.shape)
    except ValueError:  # a cost that does not have the error's shape: not mink's rows
        return None, None
    return error.shape[0], cost * error


def _held_tasks(
    levels: Sequence[Sequence], view: Configuration, tasks: TaskRows, held: list[bool]
) -> list:
    """``(first row, last row, cost e(q), task)`` of each task of a held level that
    follows mink's :class:`mink.Task` contract (a level whose errors do not have its rows'
    shape is left out)."""
    corrected: list = []
    starts = tasks.starts.tolist()
    for k, level in enumerate(levels):
        if not held[k]:
            continue
        row, found = starts[k], []
        for task in level:
            size, weighted = weighted_error(task, view)
            if size is None or weighted is None:  # rows of its own: not corrected
                size = task_rows(task, view)[0].shape[0]
            else:
                found.append((row, row + size, weighted, task))
            row += size
        if row == starts[k + 1]:
            corrected += found
    return corrected


def _copy_mocap(aux: Configuration, data: mujoco.MjData) -> None:
    if aux.model.nmocap:
        aux.data.mocap_pos[...] = data.mocap_pos
        aux.data.mocap_quat[...] = data.mocap_quat


def qp_corrected(
    core: HierarchySolver,
    levels: Sequence[Sequence],
    configuration: mink.Configuration,
    dt: float,
    passes: int,
    rows: tuple[TaskRows, LimitRows],
    aux: Configuration,
) -> Solution:
    """The step with ``passes`` corrections on the QP path: ``rows`` (the step's task rows
    and limits at ``configuration``) solved by ``core``; then, on the levels it holds, each
    pass reads the held tasks' errors at ``q (+) dq`` (``aux``: a configuration of the
    model, updated there), shifts those levels' targets by the remainder and solves again
    with the same rows, damping and limits."""
    tasks, limits = rows
    solution = solve_rows(core, tasks, limits, dt)
    held = held_levels(tasks, solution)
    if not any(held):
        return solution
    corrected = _held_tasks(levels, Configuration.sharing(configuration), tasks, held)
    if not corrected:
        return solution
    A, b0 = tasks.A, tasks.b
    for _ in range(passes):
        _copy_mocap(aux, configuration.data)
        aux.update(configuration.integrate(solution.velocity, dt))
        d = solution.displacement
        b = b0.copy()
        for r0, r1, weighted, task in corrected:
            after = weighted_error(task, aux)[1]
            if after is not None and after.shape == weighted.shape:
                b[r0:r1] = b0[r0:r1] - ((after - weighted) - A[r0:r1] @ d)
        shifted = TaskRows(A, b, tasks.w, tasks.starts, tasks.reg)
        solution = solve_rows(core, shifted, limits, dt)
    return solution


@dataclass
class LeanCorrection:
    """The passes of one compiled plan's lean step (``Kernel.correct``): ``kernel`` the
    plan's, ``aux`` a configuration of its model attached to the kernel by ``attach_aux``,
    ``rows_tasks`` the tasks that supply their own rows (``(task, first row, last row)``),
    ``com`` whether a CoM task needs the subtree CoMs, ``rows`` the plan's row count,
    ``max_iter`` the cascade's cap."""

    kernel: Any
    aux: Configuration
    rows_tasks: list
    com: bool
    rows: int
    max_iter: int

    def run(
        self, configuration: mink.Configuration, velocity: np.ndarray, row: int, dt: float,
        passes: int,
    ) -> bool:  # fmt: skip
        """``passes`` corrections of the step in row ``row`` of the kernel's outputs
        (``velocity``: that row's view, rewritten by each pass): each integrates it, ``q (+)
        v dt`` as :meth:`mink.Configuration.integrate` does, runs MuJoCo's kinematics there
        on ``aux``, and has the kernel shift the held levels' targets by their remainder and
        solve again; the tasks that supply their own rows give their errors here. False where
        the QP path must answer."""
        e0: list | None = None
        for _ in range(passes):
            shift, e0 = self._at(configuration, velocity, dt, e0)
            if self.kernel.correct(row, shift, self.max_iter) != _OK:
                return False
        return True

    def run_gathered(
        self, configuration: mink.Configuration, dt: float, passes: int, general: tuple,
        step: tuple,
    ) -> tuple | None:  # fmt: skip
        """``passes`` corrections of the gathered step (``Kernel.correct_run``: a step with
        general rows, ``general`` its ``(G, h, ...)``) whose answer ``step`` is ``(d, v,
        info, active)``, as :meth:`run` makes them of the lean step's: the corrected ``(d, v,
        info, active)`` (the step as it was where no level is held), None where the QP path
        must answer."""
        G, h = general[0], general[1]
        d, v, info, active = step
        e0: list | None = None
        for k in range(passes):
            shift, e0 = self._at(configuration, v, dt, e0)
            out = self.kernel.correct_run(G, h, d, info, k == 0, shift, self.max_iter)
            if out is None:  # no level held: the step stands
                break
            if out[0] != _OK:
                return None
            _, d, v, info, active = out
        return d, v, info, active

    def _at(
        self, configuration: mink.Configuration, velocity: np.ndarray, dt: float, e0: list | None
    ) -> tuple[np.ndarray | None, list | None]:
        """A pass's kinematics: ``q (+) v dt`` as :meth:`mink.Configuration.integrate` does
        it, MuJoCo's kinematics there on ``aux``; ``(shift, e0)``: the remainders of the tasks
        that supply their own rows (None without such tasks) and their errors at ``q`` (made
        on the first pass)."""
        aux, rows_tasks = self.aux, self.rows_tasks
        model, data = aux.model, configuration.data
        qa = aux.data.qpos
        qa[...] = data.qpos
        mujoco.mj_integratePos(model, qa, velocity, dt)
        _copy_mocap(aux, data)
        if rows_tasks:  # tasks that supply their rows: their errors here
            aux.update(qa)
            if e0 is None:
                e0 = _row_errors(rows_tasks, Configuration.sharing(configuration))
            return _row_shift(rows_tasks, e0, _row_errors(rows_tasks, aux), self.rows), e0
        mujoco.mj_kinematics(model, aux.data)
        if self.com:
            mujoco.mj_comPos(model, aux.data)
        return None, e0


def _row_errors(rows_tasks: list, configuration: Configuration) -> list:
    """The weighted errors ``cost e`` of the tasks that supply their own rows (None for one
    that does not follow mink's :class:`mink.Task` contract, or whose error does not have
    its rows' shape: not corrected)."""
    out = []
    for task, r0, r1 in rows_tasks:
        size, error = weighted_error(task, configuration)
        out.append(error if size == r1 - r0 else None)
    return out


def _row_shift(rows_tasks: list, e0: list, e1: list, m: int) -> np.ndarray:
    """``Kernel.correct``'s ``shift`` (m,): ``cost (e(q (+) dq) - e(q))`` on the rows of
    the tasks that supply their own, NaN elsewhere."""
    shift = np.full(m, np.nan)
    for (_task, r0, r1), a, b in zip(rows_tasks, e0, e1):
        if a is not None and b is not None:
            shift[r0:r1] = b - a
    return shift
