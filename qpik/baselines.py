"""Reference methods: the lecture's pseudoinverse, damped least squares, and the classical
two-level null-space projection. Used as references in tests and as baselines in
benchmarks; they know nothing of joint limits.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "damped_least_squares_step",
    "nullspace_projection_step",
    "pseudoinverse_step",
]


def pseudoinverse_step(J: np.ndarray, xi: np.ndarray, rcond: float = 1e-15) -> np.ndarray:
    """The lecture's step: ``qdot = J^+ xi`` (least-norm; least-squares if ``xi`` is not
    reachable). Unbounded near singularities: at the 2R point ``q2 = 0.001`` it is ~1000x
    the task velocity."""
    return np.linalg.pinv(J, rcond=rcond) @ xi


def damped_least_squares_step(J: np.ndarray, xi: np.ndarray, damping: float) -> np.ndarray:
    """Damped least squares: ``qdot = J^T (J J^T + damping^2 I)^-1 xi``; its norm is at
    most ``|xi| / (2 damping)``."""
    m = J.shape[0]
    return J.T @ np.linalg.solve(J @ J.T + damping**2 * np.eye(m), xi)


def nullspace_projection_step(
    J1: np.ndarray, xi1: np.ndarray, J2: np.ndarray, xi2: np.ndarray, rcond: float = 1e-8
) -> np.ndarray:
    """Classical two-level priority: ``J1^+ xi1 + (J2 N1)^+ (xi2 - J2 J1^+ xi1)`` with
    ``N1 = I - J1^+ J1`` (Nakamura, Hanafusa & Yoshikawa 1987). Singular values below
    ``rcond`` times the largest count as zero: ``N1`` carries round-off of order
    ``1e-15 cond(J1)`` that a tighter cut would invert."""
    J1_pinv = np.linalg.pinv(J1, rcond=rcond)
    first = J1_pinv @ xi1
    N1 = np.eye(J1.shape[1]) - J1_pinv @ J1
    return first + np.linalg.pinv(J2 @ N1, rcond=rcond) @ (xi2 - J2 @ first)


# --------------------------------------------------------------------------------------------
# The lecture's inverse geometric model (IGM) as a loop, with the pseudoinverse or damped
# least squares step: references for qpik.solve and baselines of benchmarks/ik_success.py.
# (Appended below the step functions; hence the late imports.)

import math  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import dataclass  # noqa: E402

from .configuration import Configuration, FrameType  # noqa: E402

__all__ += [
    "IGM_REASONS",
    "IGMResult",
    "damped_least_squares_igm",
    "igm",
    "pose_error",
    "pseudoinverse_igm",
]

#: Why an IGM loop ended; ``converged`` is the only success.
IGM_REASONS = {
    "converged": "the frame is within tolerance of its target",
    "max_iters": "the iteration limit of the last attempt was reached",
    "time_budget": "the time budget ran out",
    "stalled": "no progress (1 % of the error) for stall_window steps",
    "diverged": "the step was not finite",
}


@dataclass
class IGMResult:
    """The outcome of an IGM loop (:func:`igm`).

    Attributes:
        q: the best configuration found ``(nq,)``; within the limits when ``clip`` is on.
        converged: whether the frame is within tolerance at ``q``.
        reason: one of :data:`IGM_REASONS`.
        iterations: steps taken, all attempts together.
        restarts_used: random restarts made after the first attempt.
        position_error: distance of the frame origin to its target at ``q`` [m].
        orientation_error: angle of ``R R_des^T`` at ``q`` [rad].
        solve_time: wall time [s].
    """

    q: np.ndarray
    converged: bool
    reason: str
    iterations: int
    restarts_used: int
    position_error: float
    orientation_error: float
    solve_time: float


def _rotation_vector(rotation: np.ndarray) -> np.ndarray:
    """``log(R)`` as a rotation vector (axis * angle) [rad]."""
    cosine = min(1.0, max(-1.0, (np.trace(rotation) - 1.0) / 2.0))
    angle = math.acos(cosine)
    skew = np.array(
        [
            rotation[2, 1] - rotation[1, 2],
            rotation[0, 2] - rotation[2, 0],
            rotation[1, 0] - rotation[0, 1],
        ]
    )
    if angle < 1e-8:
        return 0.5 * skew
    if angle > math.pi - 1e-4:
        # sin(angle) -> 0: take the axis from the symmetric part,
        # (R + R^T) / 2 - cos I = (1 - cos) a a^T, and its sign from the skew part.
        symmetric = 0.5 * (rotation + rotation.T) - cosine * np.eye(3)
        column = int(np.argmax(np.diag(symmetric)))
        axis = symmetric[:, column] / math.sqrt(max(symmetric[column, column], 1e-300))
        if axis @ skew < 0:
            axis = -axis
        return angle * axis / np.linalg.norm(axis)
    return angle / (2.0 * math.sin(angle)) * skew


def pose_error(
    configuration: Configuration,
    frame: str,
    target_position: np.ndarray,
    target_rotation: np.ndarray | None,
    frame_type: FrameType | str = FrameType.SITE,
) -> np.ndarray:
    """The lecture's task error ``c = [p_des - p; log(R_des R^T)]`` in the world frame:
    ``(6,)`` ([m], [rad]), or ``(3,)`` without a target rotation. It matches the rows of
    :meth:`Configuration.frame_jacobian` ``[v; omega]``: ``J dq = c`` moves toward the target
    (to first order)."""
    position, rotation = configuration.frame_pose(frame, frame_type)
    c_position = np.asarray(target_position, dtype=float) - position
    if target_rotation is None:
        return c_position
    return np.concatenate([c_position, _rotation_vector(target_rotation @ rotation.T)])


#: A step rule: ``(configuration, J, c) -> dq`` with ``J (m, nv)`` the frame's world-aligned
#: Jacobian rows and ``c (m,)`` the task error (:func:`pose_error`) at ``configuration``.
StepRule = Callable[[Configuration, np.ndarray, np.ndarray], np.ndarray]


def igm(
    configuration: Configuration,
    frame: str,
    target_position: np.ndarray,
    target_rotation: np.ndarray | None,
    step: StepRule,
    *,
    frame_type: FrameType | str = FrameType.SITE,
    q0: np.ndarray | None = None,
    tol_position: float = 1e-4,
    tol_orientation: float = 1e-3,
    max_iters: int = 100,
    time_budget: float | None = None,
    restarts: int = 20,
    seed: int | np.random.Generator | None = None,
    alpha: float = 1.0,
    beta: float = 1.0,
    stall_window: int = 5,
    clip: bool = True,
) -> IGMResult:
    r"""The lecture's inverse geometric model with any step rule:

    .. math:: c_i = x_{des} - x(q_i), \qquad \dot q = \mathrm{step}(J(q_i), \alpha c_i),
        \qquad q_{i+1} = \mathrm{clip}(q_i + \beta \dot q)

    until the frame is within ``tol_position`` [m] and ``tol_orientation`` [rad]. With
    ``clip`` the joint positions are clipped into the limits after each step (the step rule
    itself knows nothing of them). The stopping and restart rules are those of
    :func:`qpik.solve`: an attempt ends after ``max_iters`` steps, or after
    ``stall_window`` steps without a 1 % decrease of ``max(|p| / tol_position + |theta| /
    tol_orientation)``; then the loop restarts from a random configuration within the limits
    while ``restarts`` and ``time_budget`` [s] remain. The best iterate over all attempts is
    returned. ``configuration`` is left unchanged; ``q0`` defaults to its ``q``.
    """
    start_time = time.perf_counter()
    work = Configuration(configuration.model, configuration.q if q0 is None else q0)
    kind = FrameType.parse(frame_type)
    rows = slice(0, 3) if target_rotation is None else slice(0, 6)
    lower, upper = work.lower, work.upper
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)

    def errors(c: np.ndarray) -> tuple[float, float]:
        return float(np.linalg.norm(c[:3])), float(np.linalg.norm(c[3:])) if c.size > 3 else 0.0

    def score(position_error: float, orientation_error: float) -> float:
        return position_error / tol_position + orientation_error / tol_orientation

    c = pose_error(work, frame, target_position, target_rotation, kind)
    best_q, best_errors = work.q, errors(c)
    best_score = score(*best_errors)
    iterations = attempt = 0
    reason = "max_iters"
    while True:
        current = score(*errors(c))
        window_start, since_progress, attempt_reason = current, 0, "max_iters"
        for _ in range(max_iters):
            if current <= 1.0:
                attempt_reason = "converged"
                break
            if time_budget is not None and time.perf_counter() - start_time > time_budget:
                attempt_reason = "time_budget"
                break
            J = work.frame_jacobian(frame, kind)[rows]
            dq = step(work, J, alpha * c)
            iterations += 1
            if not np.all(np.isfinite(dq)):
                attempt_reason = "diverged"
                break
            q = work.integrate(beta * dq, 1.0)
            if clip:
                q = np.clip(q, lower, upper)
            work.update(q)
            c = pose_error(work, frame, target_position, target_rotation, kind)
            current = score(*errors(c))
            if current < 0.99 * window_start:
                window_start, since_progress = current, 0
            else:
                since_progress += 1
                if since_progress >= stall_window:
                    attempt_reason = "stalled"
                    break
        else:
            if current <= 1.0:
                attempt_reason = "converged"
        if current < best_score:
            best_q, best_errors, best_score = work.q, errors(c), current
        reason = attempt_reason
        out_of_time = time_budget is not None and time.perf_counter() - start_time > time_budget
        if attempt_reason == "converged" or attempt >= restarts or out_of_time:
            if out_of_time and attempt_reason != "converged":
                reason = "time_budget"
            break
        attempt += 1
        work.update(work.random_q(rng))
        c = pose_error(work, frame, target_position, target_rotation, kind)
    converged = best_score <= 1.0
    return IGMResult(
        q=best_q,
        converged=converged,
        reason="converged" if converged else reason,
        iterations=iterations,
        restarts_used=attempt,
        position_error=best_errors[0],
        orientation_error=best_errors[1],
        solve_time=time.perf_counter() - start_time,
    )


def pseudoinverse_igm(
    configuration: Configuration,
    frame: str,
    target_position: np.ndarray,
    target_rotation: np.ndarray | None = None,
    *,
    rcond: float = 1e-15,
    **options,
) -> IGMResult:
    """The lecture's plain IGM: ``q <- clip(q + beta J^+ alpha c)`` with the 6-D pose error
    ``c`` (:func:`pose_error`; 3-D without a target rotation), joint positions clipped into
    the limits after each step, random restarts as in :func:`igm` (whose ``options`` it
    takes). Near a singularity the step is unbounded (see :func:`pseudoinverse_step`)."""
    return igm(
        configuration,
        frame,
        target_position,
        target_rotation,
        lambda _configuration, J, c: pseudoinverse_step(J, c, rcond),
        **options,
    )


def damped_least_squares_igm(
    configuration: Configuration,
    frame: str,
    target_position: np.ndarray,
    target_rotation: np.ndarray | None = None,
    *,
    damping: float = 0.05,
    **options,
) -> IGMResult:
    """The IGM loop of :func:`pseudoinverse_igm` with the damped least-squares step
    ``J^T (J J^T + damping^2 I)^-1 c`` (:func:`damped_least_squares_step`); ``damping`` is
    constant, in the task's mixed units ([m] and [rad])."""
    return igm(
        configuration,
        frame,
        target_position,
        target_rotation,
        lambda _configuration, J, c: damped_least_squares_step(J, c, damping),
        **options,
    )
