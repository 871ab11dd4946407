"""Run modes of a problem file (``mode = ...``), one function each in :data:`MODES`.

* ``solve``: each goal (the target, or each waypoint in turn, from the previous result)
  is one :func:`qpik.solve` with ``stack`` = the levels and every frame of the goal as a
  target; the gain of the level-0 tasks on the goal frames is the solver's ``alpha`` (where
  the task gives no gain of its own), and left-out task targets hold ``q0`` at every goal.
* ``track``: :class:`qpik.IKSolver` steps of ``dt`` from ``q0`` toward each goal in turn,
  ``steps`` steps each, under the limits (a velocity limit bounds each step to
  ``v_max dt``); the result carries a :class:`~qpik.problem.report.TrackTrace`.

A mode returns ``(results, trace, converged, reason)``. Either way the problem has
converged when the final configuration of every goal is within ``tol_position`` [m] and
``tol_orientation`` [rad] of each of its frames.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from ..diffik.solver import IKSolver
from ..igm.qp_engine import set_frame_target
from ..igm.result import IKResult, Reason
from ..igm.session import solve
from ..model.configuration import Configuration
from ..model.couplings import model_couplings, unheld_equalities, unheld_equality_errors
from .goals import Goal
from .report import Problem, TrackTrace

#: What a mode returns: per-goal results (solve), the trace (track), converged, reason.
ModeOutcome = tuple[list[IKResult], TrackTrace | None, bool, str]


def _failed_goal(problem: Problem, index: int) -> str:
    return "target" if len(problem.goals) == 1 else f"waypoint {index}"


def run_solve(problem: Problem) -> ModeOutcome:
    """``mode = "solve"``: one :func:`qpik.solve` per goal, each from the previous answer."""
    q = problem.q0
    results = []
    # Targets left out hold the problem's start (q0) at every goal, as in track mode.
    start = Configuration(problem.model, q)
    alpha = problem.solve_options.alpha
    for goal in problem.goals:
        frames = {frame.frame for frame in goal.frames}
        stack = [
            [_goal_gain(spec, spec.build(problem.model, start), k, frames, alpha) for spec in level]
            for k, level in enumerate(problem.levels)
        ]
        result = solve(
            problem.model,
            goal.targets(),
            q0=q,
            stack=stack,
            options=problem.solve_options,
            limits=problem.build_limits(),
        )
        results.append(_measured(problem, goal, result))
        q = result.q
    failed = [i for i, r in enumerate(results) if not r.converged]
    if not failed:
        return results, None, True, "converged"
    return results, None, False, f"{_failed_goal(problem, failed[0])}: {results[failed[0]].reason}"


def _goal_gain(spec, task, level: int, frames: set, alpha: float):
    """``task``, with the solver's ``alpha`` as its gain where it is a level-0 task on a
    goal frame (the reference: the gain of the goal tasks in a solve) and its own ``gain``
    is not given in the file."""
    if level == 0 and spec.kind.goal and spec.frame in frames and "gain" not in spec.options:
        task.gain = alpha
    return task


def _measured(problem: Problem, goal: Goal, result: IKResult) -> IKResult:
    """``result`` with its figures computed from its returned ``q``: each goal frame's
    errors by forward kinematics (:meth:`Goal.errors`), the largest of them, and a claim of
    convergence withdrawn (reason ``stalled``) where a frame is outside the tolerance."""
    configuration = Configuration(problem.model, result.q)
    errors = {f.frame: f.error(configuration) for f in goal.frames}
    position = max(p for p, _ in errors.values())
    orientation = max(o for _, o in errors.values())
    options = problem.solve_options
    within = position <= options.tol_position and orientation <= options.tol_orientation
    converged = bool(result.converged and within)
    return dataclasses.replace(
        result,
        position_error=position,
        orientation_error=orientation,
        frame_errors=errors,
        converged=converged,
        reason=result.reason if converged or not result.converged else Reason.STALLED,
    )


class _Recorder:
    """The per-step records of a tracking run."""

    def __init__(self, configuration: Configuration, error: tuple[float, float]):
        self.q = [configuration.q]
        self.errors = [error]
        self.velocity: list[np.ndarray] = []
        self.residuals: list[list[float]] = []
        self.sigma: list[list[float]] = []
        self.times: list[float] = []
        self.goal: list[int] = []
        self.active: list[int] = []

    def add(self, configuration: Configuration, step, goal: int, error) -> None:
        self.q.append(configuration.q)
        self.velocity.append(step.velocity.copy())
        self.residuals.append(list(step.residuals))
        self.sigma.append(list(step.sigma_min))
        self.times.append(step.solve_time)
        self.goal.append(goal)
        self.active.append(len(step.active_limits))
        self.errors.append(error)


def run_track(problem: Problem) -> ModeOutcome:
    """``mode = "track"``: ``steps`` :class:`qpik.IKSolver` steps of ``dt`` per goal."""
    options = problem.solve_options
    configuration = problem.start_configuration()
    levels = problem.build_stack(configuration)
    solver = IKSolver(problem.model, levels, problem.build_limits(), options=options.step)
    tol_p, tol_o = options.tol_position, options.tol_orientation

    def within(error: tuple[float, float]) -> bool:
        return error[0] <= tol_p and error[1] <= tol_o

    # Each recorded error is that of the recorded q against the goal it works toward
    # (the goal of its step; the start's is the first goal's): what forward kinematics of
    # the returned path gives, entry by entry.
    record = _Recorder(configuration, problem.goals[0].worst_error(configuration))
    reached: list[bool] = []
    for index, goal in enumerate(problem.goals):
        for frame in goal.frames:
            set_frame_target(levels, frame.frame, frame.target, frame.frame_type)
        error = goal.worst_error(configuration)
        for _ in range(problem.steps):
            if problem.stop_at_goal and within(error):
                break
            step = solver.step(configuration, problem.dt)
            configuration.integrate_inplace(step.velocity, problem.dt)
            error = goal.worst_error(configuration)
            record.add(configuration, step, index, error)
        reached.append(within(error))
    broken = _broken_equalities(problem, configuration.q) if all(reached) else ""
    trace = _trace(problem, record, all(reached) and not broken)
    if trace.converged:
        return [], trace, True, "converged"
    if broken:
        trace.reason = broken
        return [], trace, False, broken
    where = _failed_goal(problem, reached.index(False))
    reason = f"{where}: not within tolerance after {problem.steps} steps of {problem.dt} s"
    trace.reason = reason
    return [], trace, False, reason


def _broken_equalities(problem: Problem, q: np.ndarray) -> str:
    """Why ``q`` is no answer though every goal is reached: it breaks a joint or tendon
    equality of the model that the steps hold (their coupling level, which moves toward it
    at the steps' pace from a start that breaks it) by more than ``tol_position``, or an
    active connect or weld equality (which no level holds) beyond the tolerances; ``""``
    when it breaks none (as :func:`qpik.solve` judges, reason ``constraint``)."""
    options = problem.solve_options
    couplings = model_couplings(problem.model) if options.step.couplings else None
    if couplings is not None and couplings.error(q) > options.tol_position:
        return (
            f"{Reason.CONSTRAINT}: the goals are reached, but q breaks a joint or tendon "
            f"equality of the model by {couplings.error(q):.3g} (its level had not met it yet)"
        )
    unheld = unheld_equalities(problem.model)
    if unheld.size == 0:
        return ""
    position, rotation = unheld_equality_errors(problem.model, q, unheld)
    if position <= options.tol_position and rotation <= options.tol_orientation:
        return ""
    return (
        f"{Reason.CONSTRAINT}: the goals are reached, but q breaks a connect or weld equality "
        f"of the model, which qpik does not hold (residual {max(position, rotation):.3g})"
    )


def _trace(problem: Problem, record: _Recorder, converged: bool) -> TrackTrace:
    # a robot without dofs records velocities of size 0: reshape(-1, 0) cannot tell rows
    velocity = np.array(record.velocity, dtype=float).reshape(
        len(record.velocity), problem.model.nv
    )
    ratio = float("nan")
    if problem.velocity_limits is not None and len(velocity):
        ratio = float(np.max(np.abs(velocity) / problem.velocity_limits))
    error = np.array(record.errors)
    return TrackTrace(
        dt=problem.dt,
        q=np.array(record.q),
        velocity=velocity,
        residuals=record.residuals,
        sigma_min=record.sigma,
        step_time=np.array(record.times),
        goal_index=np.array(record.goal, dtype=int),
        active_limits=np.array(record.active, dtype=int),
        position_error=error[:, 0],
        orientation_error=error[:, 1],
        max_velocity_ratio=ratio,
        converged=converged,
        reason="converged",
    )


#: The run modes, by the name a file gives in ``mode``.
MODES: dict[str, Callable[[Problem], ModeOutcome]] = {"solve": run_solve, "track": run_track}
