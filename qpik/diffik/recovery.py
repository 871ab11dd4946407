"""Recoverable general rows: a step whose limits admit no displacement at all.

A collision row asks a pair that is closer than its ``minimum_distance_from_collisions``
to separate by ``gain * (d_min - d)`` within the step. Deep inside (a start in contact, a
disturbance), that separation can exceed what the box allows: the trust region
(:attr:`qpik.StepOptions.max_joint_speed`), the velocity limits and the position limits.
Level 0 is then infeasible, and without recovery the robot would stay where it is at
every step (velocity zero, status ``infeasible``), never leaving the contact.

As position limits are recoverable (a start outside them steers back as fast as the other
limits allow), so are the collision rows and the support polygon's
(:func:`qpik.diffik.boxes.relaxable`; the rows of other limits stay hard): where level 0
is infeasible, each such row ``g_i dq <= h_i`` is relaxed by the smallest slack ``s`` in
the least-squares sense (``s_i = 0`` on the hard rows; the rows of one limit kind alone
where relaxing them suffices, the others hard: a collision row a step can meet is not
relaxed because the support polygon's cannot be; and with the support polygons' contact
frames held, ``C dq = 0``, where that leaves a step: :func:`contact_rows`),

.. math::

    \\min_{dq, s} \\tfrac12 |s|^2 + \\tfrac12 \\epsilon^2 |dq|^2 \\quad \\text{s.t.}
    \\quad G\\, dq - s \\le h, \\quad lb \\le dq \\le ub,

solved exactly by the core (:class:`qpik.core.HierarchySolver`, no damping, no
regularisation; ``epsilon`` = :data:`SLACK_STEP_WEIGHT`, 1e-6, keeps the problem strictly
convex). The step is then the cascade on the relaxed rows ``G dq <= h + s`` (plus a small
margin, :data:`RELAXATION_MARGINS`): it separates as fast as the box allows. Level 0 is
still reported ``infeasible`` (the limits as given admit no step), the levels below refer
to the relaxed rows, and :attr:`qpik.StepResult.relaxation` holds ``s`` (per general row,
in the row's units; ``None`` where nothing was relaxed). Contradictory box bounds and hard
rows stay infeasible (no slack of these rows helps them): the step is then zero, as before.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..core import HierarchyProblem, HierarchySolver, Level, LevelStatus
from ..limits import SupportPolygonLimit
from ..model.configuration import Configuration
from .boxes import LimitRows

__all__ = ["RELAXATION_MARGINS", "SLACK_STEP_WEIGHT", "contact_rows", "least_slack", "relaxed_rows"]

#: A relaxed row's bound is ``h_i + s_i + margin * (|g_i| + |h_i|)``, the margins tried in
#: this order until level 0 of the relaxed step is solved: the slack problem's answer meets
#: its rows to the certificate's tolerance (1e-9, scaled by ``|g_i| + |h_i|``), but the
#: relaxed rows can meet at a degenerate vertex (the support polygon's edges, several
#: collision pairs) where level 0 is not certified until the set is a little wider.
RELAXATION_MARGINS = (1e-9, 1e-6, 1e-4, 1e-2)
#: The slack problem also weighs the step ``x`` by this (``|s|^2 + 1e-12 |x|^2``): without
#: it ``x`` is free in a singular objective, and the core's certificate can fail by a hair
#: (stationarity 1.8e-9 on a humanoid's support polygon). Its effect on ``s`` is of order
#: 1e-12 of the step's size, far below the relaxed rows' margin; every answer ``(x, s)``
#: still meets ``G x - s <= h``, so the rows relaxed by ``s`` admit ``x``.
SLACK_STEP_WEIGHT = 1e-6


def contact_rows(limits: Sequence, configuration: Configuration) -> np.ndarray | None:
    """The rows ``C`` (6 per contact frame: its world-aligned Jacobian ``[v; omega]``) of
    the contact frames of the support polygons among ``limits``
    (:class:`qpik.limits.SupportPolygonLimit`), or None without one: the slack problem holds
    them, ``C x = 0`` (:func:`least_slack`), as the polygon is made of them and a task of a
    higher (or the same) level holds them (its docs); relaxed rows that let the feet move
    give the stack no step that holds them, and the polygon then moves with the feet."""
    rows = [
        configuration.frame_jacobian(name, kind)
        for limit in limits
        if isinstance(limit, SupportPolygonLimit)
        for name, kind, _ in limit.frames
    ]
    return np.vstack(rows) if rows else None


def least_slack(limits: LimitRows, held: np.ndarray | None = None) -> np.ndarray | None:
    """The least-squares slack ``s`` (p,) of the relaxable general rows
    (:attr:`LimitRows.relaxable`; 0 on the others, which stay hard) that makes the rows
    feasible within the box (module docstring), or ``None`` where no row may relax, the
    box is empty or no step within the box meets the hard rows.

    Entries of ``G`` whose largest effect over the box is below round-off of their row
    (``1e-14`` of ``|h_i| + sum_j |g_ij| max(|lb_j|, |ub_j|)``: a collision row's
    Jacobian along a dof that cannot move the pair, say 1e-15) are dropped in this problem
    only; the core would otherwise not certify an optimum whose stationarity they touch at
    1e-17. Rows that every step in the box meets (their largest value over the box at most
    ``h_i``) take no slack and are left out of the problem: the optimum is the same, and a
    robot with many collision pairs within the detection distance solves a problem of the
    few rows a step can break. It is solved first by Newton's method on ``x`` alone
    (:func:`_hinge_newton`: a least squares of ``n`` variables per round, each certified),
    and by the slack problem (``n`` plus one variable per row) only where that does not
    settle. On erd Tiago from ``qpos0`` (374 collision rows, its hand's links in contact) a
    full IK with two restarts took 0.31 s rather than 3.8 s; on 68 recovered steps of six erd
    robots both ways agree to 8e-15. Where the core does not certify its answer, a
    feasible slack is taken instead:
    the one that lets the relaxable rows admit the core's step ``x`` (or, where that step
    is outside the box or breaks a hard row, the box's point nearest 0),
    ``s_i = max(0, g_i x - h_i)``: not the least, but the relaxed rows then admit a step.

    ``held``: rows ``C`` that the slack problem holds, ``C x = 0`` (a support polygon's
    contact frames: :func:`contact_rows`), where that leaves a step; else they are left out."""
    G, h, lb, ub, relax = limits.G, limits.h, limits.lb, limits.ub, limits.relaxable
    p, n = G.shape
    if p == 0 or relax is None or not relax.any() or not np.all(lb <= ub):
        return None
    if held is not None and held.size:
        # The held rows, C x = 0 as two hard rows each: the least slack with them, else
        # (they leave no step within the box and the hard rows) the least slack without.
        with_held = dataclasses.replace(
            limits,
            G=np.vstack([G, held, -held]),
            h=np.concatenate([h, np.zeros(2 * held.shape[0])]),
            row_names=[*limits.row_names, *[""] * (2 * held.shape[0])],
            relaxable=np.concatenate([relax, np.zeros(2 * held.shape[0], dtype=bool)]),
        )
        slack = least_slack(with_held)
        if slack is not None:
            return slack[:p]
    # The rows of one limit kind alone where that suffices (the others hard): a collision
    # row that a step can meet is not relaxed because the support polygon's cannot be.
    kinds = [_kind(name) for name in limits.row_names]
    relaxed_kinds = sorted({kinds[i] for i in np.flatnonzero(relax)})
    if len(relaxed_kinds) > 1:
        best = None
        for kind in relaxed_kinds:
            alone = relax & np.array([k == kind for k in kinds])
            slack = _least_slack(dataclasses.replace(limits, relaxable=alone))
            if slack is not None and (best is None or slack @ slack < best @ best):
                best = slack
        if best is not None:
            return best
    return _least_slack(limits)


def _kind(row_name: str) -> str:
    """The limit class a general row's name gives (``"CollisionAvoidanceLimit row 3"``,
    ``"joint4 upper (SupportPolygonLimit)"``). A class name has no space or parenthesis; a
    joint's name may have both (MuJoCo takes any): the bound's form, which ends in the
    class in parentheses, is read first, from its last ``(``."""
    if row_name.endswith(")"):
        return row_name[row_name.rfind("(") + 1 : -1]
    return row_name.rsplit(" row ", 1)[0] if " row " in row_name else row_name


def _least_slack(limits: LimitRows) -> np.ndarray | None:
    """:func:`least_slack` of every relaxable row together (no row held)."""
    G, h, lb, ub, relax = limits.G, limits.h, limits.lb, limits.ub, limits.relaxable
    p, n = G.shape
    if p == 0 or relax is None or not relax.any() or not np.all(lb <= ub):
        return None
    reach = np.maximum(np.abs(lb), np.abs(ub))
    with np.errstate(invalid="ignore"):  # 0 * inf: a zero entry on an unbounded dof
        effect = np.where(G == 0.0, 0.0, np.abs(G) * reach)
    bounded = np.isfinite(effect)  # an entry on an unbounded dof is never dropped
    scale = np.abs(h) + np.where(bounded, effect, 0.0).sum(axis=1)
    G = np.where(bounded & (effect <= 1e-14 * scale[:, None]), 0.0, G)
    # A row that every step in the box meets (its largest value over the box, sum_j
    # max(g_ij lb_j, g_ij ub_j), at most h_i) needs no slack and bounds nothing the box does
    # not: it is left out (a collision pair within the detection distance but farther than
    # any step moves it; most of a many-pair robot's rows). The problem keeps its optimum.
    with np.errstate(invalid="ignore"):  # 0 * inf: a zero entry on an unbounded dof
        highest = np.where(G == 0.0, 0.0, np.maximum(G * lb, G * ub)).sum(axis=1)
    needed = ~(np.isfinite(highest) & (highest <= h))
    relax_kept = relax[needed]
    G, h_kept = G[needed], h[needed]
    tolerance = RELAXATION_MARGINS[0] * _row_scale(limits)
    newton = _hinge_newton(G, h_kept, relax_kept, lb, ub)
    if newton is not None:
        slack = np.zeros(p)
        slack[needed] = newton
        return np.where(slack > tolerance, slack, 0.0)
    k = int(relax_kept.sum())
    objective = np.zeros((n + k, n + k))  # |s|^2, and |x|^2 at SLACK_STEP_WEIGHT^2
    objective[:n, :n] = SLACK_STEP_WEIGHT * np.eye(n)
    objective[n:, n:] = np.eye(k)
    rows = np.hstack([G, -np.eye(G.shape[0])[:, relax_kept]])
    free = np.full(k, np.inf)
    problem = HierarchyProblem(
        [Level(objective, np.zeros(n + k), 0.0)],
        np.concatenate([lb, -free]), np.concatenate([ub, free]), rows, h_kept,
    )  # fmt: skip
    result = HierarchySolver("auto", damping_law=None).solve(problem)
    if result.status[0] == LevelStatus.SOLVED and np.all(np.isfinite(result.x)):
        slack = np.zeros(p)
        slack[np.flatnonzero(needed)[relax_kept]] = result.x[n:]
        # below the first margin: round-off, or the step weight's pull (a row x can meet)
        return np.where(slack > tolerance, slack, 0.0)
    for x in (result.x[:n], np.clip(0.0, lb, ub)):
        if not (np.all(np.isfinite(x)) and np.all((lb <= x) & (x <= ub))):
            continue
        excess = limits.G @ x - h
        if np.all(excess[~relax] <= tolerance[~relax]):  # the hard rows hold at x
            return np.where(relax & (excess > 0.0), excess, 0.0)
    return None


#: The most active sets :func:`_hinge_newton` tries before the slack problem takes over.
NEWTON_ROUNDS = 30


def _hinge_newton(
    G: np.ndarray, h: np.ndarray, relax: np.ndarray, lb: np.ndarray, ub: np.ndarray
) -> np.ndarray | None:
    """The least-squares slack by Newton's method on ``x`` alone: the slack problem is
    ``min_x 1/2 sum_i max(0, g_i x - h_i)^2 + 1/2 eps^2 |x|^2`` over the box and the hard rows
    (``s_i = max(0, g_i x - h_i)`` at its optimum), a convex function whose gradient is that
    of the least squares of the rows it breaks, ``A = {i relaxable: g_i x > h_i}``. From the
    box's point nearest 0, each round solves that least squares exactly (the core, certified;
    ``n`` variables rather than ``n`` plus one per row) and takes the rows the answer breaks;
    where they are the same rows, the answer meets the optimality conditions of the whole
    problem (the same gradient, the same constraints) and its slack is returned (0 on the
    hard rows). None where a round is not certified, the sets cycle, or
    :data:`NEWTON_ROUNDS` pass: the slack problem itself decides then."""
    n = G.shape[1]
    G_hard, h_hard = G[~relax], h[~relax]
    step_rows, step_targets = SLACK_STEP_WEIGHT * np.eye(n), np.zeros(n)
    solver = HierarchySolver("auto", damping_law=None)
    x = np.clip(0.0, lb, ub)
    active = relax & (G @ x - h > 0.0)
    seen: set[bytes] = set()
    for _ in range(NEWTON_ROUNDS):
        key = active.tobytes()
        if key in seen:
            return None
        seen.add(key)
        rows = np.vstack([G[active], step_rows])
        targets = np.concatenate([h[active], step_targets])
        problem = HierarchyProblem([Level(rows, targets, 0.0)], lb, ub, G_hard, h_hard)
        result = solver.solve(problem)
        if result.status[0] != LevelStatus.SOLVED or not np.all(np.isfinite(result.x)):
            return None
        x = result.x
        excess = G @ x - h
        broken = relax & (excess > 0.0)
        if np.array_equal(broken, active):
            return np.where(broken, excess, 0.0)
        active = broken
    return None


def relaxed_rows(limits: LimitRows, slack: np.ndarray, margin: float) -> LimitRows:
    """``limits`` with each general row that needs slack relaxed to
    ``h_i + s_i + margin (|g_i| + |h_i|)`` (the others as they are)."""
    h = np.where(slack > 0.0, limits.h + slack + margin * _row_scale(limits), limits.h)
    return dataclasses.replace(limits, h=h)


def _row_scale(limits: LimitRows) -> np.ndarray:
    """Each general row's scale ``|g_i| + |h_i|`` (the certificate's, for a row's
    violation)."""
    return np.linalg.norm(limits.G, axis=1) + np.abs(limits.h)
