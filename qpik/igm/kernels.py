r"""Compiled C++ kernels of the full-IK loop (``qpik/_cpp/igm``: ``box_qp.hpp``,
``igm.hpp``; bound as :mod:`qpik._engine.igm`), with the loop's constants. Every kernel takes
plain arrays (no MuJoCo call happens inside); ``tests/model/test_engine_model.py`` checks them bit
for bit against recorded answers (``tests/fixtures/model.npz``).

The IGM (:func:`igm_solve`): per iteration, the damped least-squares step of the pose error
under box bounds (joint limits), solved exactly by an active-set method
(:func:`box_qp`), with the trust region, the damping law fading with the error, backtracking
(a step that increases the error is halved, up to ``BACKTRACKS`` times), stall detection
(``stall_window`` iterations without the score falling below ``PROGRESS`` times its value at
the window's start; and at once when a step is blocked: its QP residual ``|A dx - b|`` above
``BLOCKED`` times ``|b|``, so that it achieves less than a tenth of the decrease it asks for,
because the joint limits or the singularity damping stop it, while its score is above
``NEAR_TARGET``) and restarts from a
deterministic random stream (SplitMix64): odd restarts draw from the central
``RESTART_SPREAD`` of the restart box, even ones from all of it (starts near mid-range
converge more often; the full box keeps the draws diverse). A level with no more rows than
dofs takes its step from its Gram matrix ``A A^T`` (built once for the singular-value test):
``A^T (A A^T + reg I)^-1 b`` when that lies within the joint-limit box, :func:`box_qp` on
``A^T A + reg I`` from there otherwise.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .._engine import igm as _igm
from ..core.backends import check_backend_options

if TYPE_CHECKING:
    from ..options import SolveOptions

#: Gain of the joint-limit box (mink's ConfigurationLimit default): a step covers at most
#: this fraction of the distance to a limit.
LIMIT_GAIN = 0.95
# Reasons (codes) returned by igm_solve; names in qpik.igm.result.REASONS.
CONVERGED = 0
MAX_ITERS = 1
TIME_BUDGET = 2
STALLED = 3
AT_LIMIT = 4
SINGULAR = 5
UNREACHABLE = 6
#: Halvings of a step that increases the error (see igm_solve).
BACKTRACKS = 3
#: An attempt progresses when its score falls below this fraction of the score at the
#: start of its stall window.
PROGRESS = 0.95
#: Iterations between two reads of the clock (clock_gettime(CLOCK_MONOTONIC), the clock of
#: time.perf_counter, so ``deadline`` is a perf_counter value).
CLOCK_EVERY = 8
#: Every other restart draws from this fraction of the restart box, around its center.
RESTART_SPREAD = 0.6
#: An attempt ends (stalled, at_limit or singular) at a step whose QP residual
#: ``|A dx - b|`` exceeds this fraction of ``|b|`` (the joint-limit box or the singularity
#: damping leave it less than 10 % of the decrease it asks for): on the TRAC-IK protocol's
#: targets such attempts almost never converge, and ending them a stall window earlier
#: saves about 10 % of the iterations (benchmarks/ik_success.py).
BLOCKED = 0.9
#: ... but only while the attempt's score (``ep / tol_position + eo / tol_orientation``) is
#: above this; nearer, the stall window alone decides. A target on the workspace's boundary
#: (an elbow straight: sigma_min about 1e-4 at the answer) is reached by steps that the
#: damping slows to a few percent each, and the early end left every attempt at 1.3 - 2.5
#: times the tolerance (erd:kinova: hundreds of restarts, then out of its 5 ms).
NEAR_TARGET = 10.0
REASON_NAMES = (
    "converged",
    "max_iters",
    "time_budget",
    "stalled",
    "at_limit",
    "singular",
    "unreachable",
)

# --------------------------------------------------------------------- box QP
#: ``box_qp(H, g, lb, ub, x, max_iter) -> (status, iterations)``: ``min 1/2 x^T H x + g^T x
#: s.t. lb <= x <= ub`` (H positive definite), exactly, by a primal active-set method from
#: ``clip(0, lb, ub)``; status 0 solved, 1 iteration cap (``x`` feasible, not optimal), 2
#: ``H`` not positive definite.
box_qp = _igm.box_qp
#: ``box_qp_with(H, g, lb, ub, x, max_iter, workspace)``: :func:`box_qp` with its scratch
#: (:func:`box_qp_workspace`) given.
box_qp_with = _igm._box_qp


def box_qp_workspace(n: int) -> tuple[np.ndarray, ...]:
    """Scratch of :func:`box_qp_with` for ``n`` variables."""
    return (
        np.empty(n, dtype=np.int8),
        np.empty(n, dtype=np.int64),
        np.empty((n, n)),
        np.empty(n),
        np.empty(n),
        np.empty(n),
    )


# ------------------------------------------------------- smallest singular value
#: ``smallest_singular_value(A, m, nv, G, threshold=0.0) -> float``: the ``min(r, nv)``-th
#: singular value of ``A[:m]`` (``r`` its rows that are not identically zero), from the
#: smaller Gram matrix built in the scratch ``G``; with ``threshold > 0``, inf when it is at
#: least ``threshold``.
smallest_singular_value = _igm._smallest_singular_value

# ----------------------------------------------------------------------- RNG
#: ``uniform(state) -> float``: a uniform draw in [0, 1) from the SplitMix64 stream
#: ``state`` (uint64 (1,), advanced in place).
uniform = _igm.uniform

# ------------------------------------------------------------------------ IGM
#: ``igm_solve(chain, target_p, target_R, has_rot, q0, bounds, reach, options, int_options,
#: rng_state, deadline, path, hist, info)``: the whole IGM solve of one frame target (see
#: :func:`qpik.solve` for the rule).
#:
#: * ``chain``: a :class:`Chain`, or the tuple of chain arrays
#:   (:class:`qpik.model.KinematicChain`).
#: * ``target_p`` (3,), ``target_R`` (3, 3): the target in the world frame; ``has_rot``:
#:   False for a position-only target.
#: * ``q0`` (nq,): start, within the limits.
#: * ``bounds`` (4, nq): lower and upper joint limits (+-inf where none), then the box that
#:   random restarts draw from.
#: * ``reach`` (4,): center (3,) [m] and radius [m] of the frame's reach bound; a target
#:   farther than ``radius + tol_position`` from the center ends the solve at once
#:   (UNREACHABLE).
#: * ``options`` (float64): tol_position, tol_orientation, alpha, beta, max_step_position,
#:   max_step_orientation (inf: none), singular_threshold, max_damping, error_scale (<= 0:
#:   none), damping, limit_gain, rank_tolerance (singular values at or below it times
#:   ``max(1, sigma_max)`` are structural zeros, not a singularity, as in the cascade; a
#:   caller's 11 floats read 0 there: no such cut).
#: * ``int_options`` (int64): max_iters, restarts, stall_window, check_time (0/1), and
#:   optionally the iteration budget (:attr:`qpik.SolveOptions.iteration_budget`: no new
#:   attempt starts once the solve's iterations reach it; -1 or absent: none).
#: * ``rng_state``: uint64 (1,) SplitMix64 state, advanced in place.
#: * ``deadline``: ``time.perf_counter()`` value at which the budget ends (if checked).
#: * ``path`` (2, max_iters + 1, nq), ``hist`` (2, max_iters + 1, 3): per attempt slot, the
#:   iterates and, per iterate, (position error [m], orientation error [rad], QP residual of
#:   the step that left it).
#: * ``info`` (int64, 6): reason code, total iterations, restarts used, slot of the
#:   returned attempt (its last iterate is the answer), its number of iterates, QP solves
#:   that hit the iteration cap.
igm_solve = _igm.igm_solve
#: ``igm_run(chain, target_p, target_R, has_rot, q0, bounds, reach, options, int_options,
#: rng_state, deadline) -> (code, iterations, restarts_used, path, hist)``: :func:`igm_solve`
#: with its scratch allocated inside; ``path`` (k, nq) and ``hist`` (k, 3) are the returned
#: attempt's rows (new arrays), the other results those of ``info``.
igm_run = _igm.igm_run
#: ``igm_plan(chain, index, nfull, bounds, reach, options, int_options)``: the arguments of
#: :func:`igm_plan_run` that do not change between solves (``chain`` a compiled
#: :class:`qpik.model.KinematicChain` chain over the coordinates ``index`` of
#: configurations of ``nfull`` coordinates), checked and copied once.
igm_plan = _igm._IgmPlan
#: ``igm_plan_run(plan, target_p, target_R, q_full, rng_state, deadline) -> (code,
#: iterations, restarts_used, q, path, hist, position_error, orientation_error)``:
#: :func:`igm_run` with the fixed arguments of ``plan`` (:func:`igm_plan`) on its coordinates
#: ``index`` (``None``: all) of the whole configuration ``q_full``; ``target_R`` None: a
#: position-only target. ``q`` (the answer) and the rows of ``path`` are whole configurations
#: (the other coordinates as in ``q_full``), the errors those of ``q`` (:class:`qpik.IKSession`'s
#: call: its result needs no NumPy call of its own). ``rng_state`` is a plain int in
#: ``[0, 2**64)`` (the stream's state, not written back).
igm_plan_run = _igm._igm_plan_run
#: ``igm_lean_run(plan, position, rotation, q, start_box, rng_state, deadline,
#: orthonormal_tolerance, max_distance) -> tuple | None``: :func:`igm_plan_run` of a
#: ``(position, rotation)`` target from the start ``q`` in one call, where :func:`target_ok`
#: holds and ``q`` (a float64 ``(nfull,)`` array) passes ``start_box.check`` (clipped into a
#: copy, as it does); else ``None``, nothing run (:class:`qpik.IKSession`'s lean lane: the
#: general path then answers or raises).
igm_lean_run = _igm._igm_lean_run
#: ``session_lane(base, memo_keywords, kernel_options, frames, start_box, budget, mid, seed,
#: consts, orthonormal_tolerance, max_distance)``: :class:`qpik.IKSession`'s lean solve in one
#: compiled call for one options memo (``PreparedRobot.make_lane``); its ``solve(defaults,
#: robot_q, targets, keywords, start_time)`` returns the :class:`qpik.IKResult`, or ``None``
#: (nothing drawn or run) where the session's general path answers.
session_lane = _igm._SessionLane
#: ``target_ok(position, rotation, orthonormal_tolerance, max_distance) -> bool``: whether
#: a target pair is float64 C-contiguous arrays (3,) and (3, 3), finite, whose rotation is
#: orthonormal within ``orthonormal_tolerance`` (``max |R R^T - I|``, ``det R > 0``) and whose
#: position is within ``max_distance`` [m] of the origin (each coordinate)
#: (:func:`qpik.igm.targets.parse_target`'s fast path).
target_ok = _igm._target_ok
#: ``start_box(lower, upper, tol)``: a start's joint-limit box, copied once; its
#: ``check(q)`` is :func:`qpik.model.kernels.start_defect` ``(q, lower, upper, tol)``.
start_box = _igm._StartBox

assert (CONVERGED, UNREACHABLE, BACKTRACKS, CLOCK_EVERY) == (
    _igm.CONVERGED,
    _igm.UNREACHABLE,
    _igm.BACKTRACKS,
    _igm.CLOCK_EVERY,
)
assert (PROGRESS, RESTART_SPREAD, BLOCKED, NEAR_TARGET) == (
    _igm.PROGRESS,
    _igm.RESTART_SPREAD,
    _igm.BLOCKED,
    _igm.NEAR_TARGET,
)


def kernel_options(s: SolveOptions) -> tuple[np.ndarray, np.ndarray]:
    """The float and int option arrays of :func:`igm_solve` for the options ``s`` (their
    backend settings checked for the backend ``s.step`` names, so that a solve of either
    engine refuses what the backend would: :func:`qpik.core.backends.check_backend_options`)."""
    step = s.step
    if step.backend_options:
        check_backend_options(step.solver, dict(step.backend_options))
    law = s.damping_law
    max_step = s.max_step if s.max_step is not None else (np.inf, np.inf)
    options = np.array(
        [
            s.tol_position,
            s.tol_orientation,
            s.alpha,
            s.beta,
            max_step[0],
            max_step[1],
            law.singular_threshold if law is not None else 0.0,
            law.max_damping if law is not None else 0.0,
            law.error_scale if law is not None and law.error_scale is not None else 0.0,
            s.damping,
            LIMIT_GAIN,
            s.step.rank_tolerance,
        ]
    )
    budget = s.iteration_budget
    int_options = np.array(
        [
            s.max_iters,
            s.effective_restarts,
            s.stall_window,
            int(s.time_budget is not None),
            -1 if budget is None else budget,
        ],
        dtype=np.int64,
    )
    return options, int_options
