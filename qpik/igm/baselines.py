"""Reference methods of full and differential IK: the pseudoinverse, damped least-squares
and classical two-level null-space projection steps, and the inverse geometric model (IGM)
loop that iterates any of these steps (:func:`igm`, :func:`pseudoinverse_igm`,
:func:`damped_least_squares_igm`). Used as references in tests and as baselines in
benchmarks; the steps know nothing of joint limits (the loop clips into them).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import InvalidInput, InvalidOption
from ..model.configuration import Configuration, FrameType
from ..model.rotations import orientation_error
from ..options import PRESETS, LoopKeywords
from .restarts import Attempt, Clock, StallWindow, rng_state, run_attempts
from .result import IGM_REASONS, Outcome, Reason
from .targets import parse_target

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = [
    "IGM_REASONS",
    "IGMKeywords",
    "IGMResult",
    "damped_least_squares_igm",
    "damped_least_squares_step",
    "igm",
    "nullspace_projection_step",
    "pose_error",
    "pseudoinverse_igm",
    "pseudoinverse_step",
]


def pseudoinverse_step(J: np.ndarray, xi: np.ndarray, rcond: float = 1e-15) -> np.ndarray:
    """The pseudoinverse step: ``qdot = J^+ xi`` (least-norm; least-squares if ``xi`` is not
    reachable). Unbounded near singularities: its norm grows as the inverse of the smallest
    singular value of ``J``."""
    return np.linalg.pinv(J, rcond=rcond) @ xi


def damped_least_squares_step(J: np.ndarray, xi: np.ndarray, damping: float) -> np.ndarray:
    """Damped least squares: ``qdot = J^T (J J^T + damping^2 I)^-1 xi``; its norm is at
    most ``|xi| / (2 damping)``. ``damping`` is the textbook's ``lambda`` here, where
    :func:`qpik.analysis.damped_pseudoinverse` and the IK layer take ``lambda^2`` (mink's
    convention): this step is ``damped_pseudoinverse(J, damping**2) @ xi``."""
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


# ------------------------------------------------------------------------ the IGM loop
class IGMResult(Outcome):
    """The outcome of an IGM loop (:func:`igm`): the fields of
    :class:`qpik.igm.result.Outcome`, for its one frame (``q`` within the limits when ``clip``
    is on; ``reason`` one of :data:`IGM_REASONS`)."""


def pose_error(
    configuration: Configuration,
    frame: str,
    target_position: np.ndarray,
    target_rotation: np.ndarray | None,
    frame_type: FrameType | str = FrameType.SITE,
) -> np.ndarray:
    """The IGM's task error ``c = [p_des - p; log(R_des R^T)]`` in the world frame:
    ``(6,)`` ([m], [rad]), or ``(3,)`` without a target rotation. It matches the rows of
    :meth:`Configuration.frame_jacobian` ``[v; omega]``: ``J dq = c`` moves toward the target
    (to first order)."""
    position, rotation = configuration.frame_pose(frame, frame_type)
    c_position = np.asarray(target_position, dtype=float) - position
    if target_rotation is None:
        return c_position
    return np.concatenate([c_position, orientation_error(rotation, target_rotation)])


#: A step rule: ``(configuration, J, c) -> dq`` with ``J (m, nv)`` the frame's world-aligned
#: Jacobian rows and ``c (m,)`` the task error (:func:`pose_error`) at ``configuration``.
StepRule = Callable[[Configuration, np.ndarray, np.ndarray], np.ndarray]


class _Loop:
    """One IGM run: the work configuration, the frame, its target, and the step rule."""

    def __init__(
        self,
        work: Configuration,
        frame: str,
        kind: FrameType,
        target_position: np.ndarray,
        target_rotation: np.ndarray | None,
        step: StepRule,
        options: dict[str, Any],
    ) -> None:
        self.work, self.frame, self.kind = work, frame, kind
        self.target = (target_position, target_rotation)
        self.rows = slice(0, 3) if target_rotation is None else slice(0, 6)
        self.step = step
        self.options = options  # tol_position, tol_orientation, max_iters, alpha, beta, ...
        self.iterations = 0
        self.c = self.error()

    def error(self) -> np.ndarray:
        return pose_error(self.work, self.frame, *self.target, self.kind)

    def errors(self) -> tuple[float, float]:
        c = self.c
        return float(np.linalg.norm(c[:3])), float(np.linalg.norm(c[3:])) if c.size > 3 else 0.0

    def score(self) -> float:
        """``|p| / tol_position + |theta| / tol_orientation``: the progress measure of the
        stall rule and of the ranking of attempts (the compiled engine's)."""
        position, orientation = self.errors()
        return (
            position / self.options["tol_position"] + orientation / self.options["tol_orientation"]
        )

    def converged(self) -> bool:
        """Whether the frame is within ``tol_position`` and within ``tol_orientation``
        (each error within its own tolerance, as :func:`qpik.solve` decides)."""
        position, orientation = self.errors()
        o = self.options
        return position <= o["tol_position"] and orientation <= o["tol_orientation"]

    def outcome(self, reason: Reason) -> Attempt:
        converged = self.converged()
        if converged and reason is not Reason.CONVERGED:
            reason = Reason.CONVERGED
        return Attempt(converged, self.score(), reason, (self.work.q, self.errors()))

    def attempt(self, clock: Clock) -> Attempt:
        """Iterate from the work configuration's current ``q``."""
        o = self.options
        lower, upper = self.work.lower, self.work.upper
        current = self.score()
        stall = StallWindow(current, o["stall_window"])
        for _ in range(o["max_iters"]):
            if self.converged():
                break
            if clock.out_of_time():
                return self.outcome(Reason.TIME_BUDGET)
            J = self.work.frame_jacobian(self.frame, self.kind)[self.rows]
            dq = self.step(self.work, J, o["alpha"] * self.c)
            self.iterations += 1
            if not np.all(np.isfinite(dq)):
                return self.outcome(Reason.DIVERGED)
            q = self.work.integrate(o["beta"] * dq, 1.0)
            if o["clip"]:
                q = np.clip(q, lower, upper)
            self.work.update(q)
            self.c = self.error()
            current = self.score()
            if stall.update(current):
                return self.outcome(Reason.STALLED)
        return self.outcome(Reason.MAX_ITERS)  # (CONVERGED where the frame is within both)


class IGMKeywords(LoopKeywords, total=False):
    """The keywords of the IGM loops (:func:`igm` and the loops built on it): the loop
    options of :func:`qpik.solve` (:class:`qpik.options.LoopKeywords`, documented by
    :class:`qpik.SolveOptions`, whose defaults they take), and:

    Attributes:
        frame_type: the type of ``frame`` (default ``"site"``).
        q0: the start (default: the configuration's ``q``).
        seed: seed of the restarts' random configurations (an int, a numpy ``Generator``
            or ``None``: fresh entropy).
        clip: clip the joint positions into the limits after each step (default ``True``).
    """

    frame_type: FrameType | str
    q0: np.ndarray | None
    seed: int | np.random.Generator | None
    clip: bool


def igm(
    configuration: Configuration,
    frame: str,
    target_position: np.ndarray,
    target_rotation: np.ndarray | None,
    step: StepRule,
    **keywords: Unpack[IGMKeywords],
) -> IGMResult:
    r"""The inverse geometric model with any step rule:

    .. math:: c_i = x_{des} - x(q_i), \qquad \dot q = \mathrm{step}(J(q_i), \alpha c_i),
        \qquad q_{i+1} = \mathrm{clip}(q_i + \beta \dot q)

    until the frame is within ``tol_position`` [m] and ``tol_orientation`` [rad]. With
    ``clip`` the joint positions are clipped into the limits after each step (the step rule
    itself knows nothing of them). The stopping and restart rules are those of
    :func:`qpik.solve` (:mod:`qpik.igm.restarts`: the same loop): an attempt ends after
    ``max_iters`` steps, or after ``stall_window`` steps without a 5 % decrease of
    ``|p| / tol_position + |theta| / tol_orientation``; then the loop restarts from a random
    configuration within the limits while ``restarts`` and ``time_budget`` [s] remain. The
    best iterate over all attempts (and the start) is returned. The keywords
    (:class:`IGMKeywords`) are checked, and default, as :class:`qpik.SolveOptions`'s.
    ``configuration`` is left unchanged.
    """
    given: dict[str, Any] = dict(keywords)
    frame_type = FrameType.parse(given.pop("frame_type", FrameType.SITE))
    q0 = given.pop("q0", None)
    seed = given.pop("seed", None)
    clip = given.pop("clip", True)
    if not isinstance(clip, (bool, np.bool_)):
        raise InvalidOption("clip", clip, "True or False")
    settings = PRESETS["default"].replace(**given)
    if not isinstance(configuration, Configuration):
        raise InvalidInput(f"configuration must be a qpik.Configuration, got {configuration!r}")
    # The target as qpik.solve checks it (InvalidTarget: shape, finite, a rotation).
    target = parse_target(
        target_position if target_rotation is None else (target_position, target_rotation)
    )
    target_position, target_rotation = target.position, target.rotation
    clock = Clock(time.perf_counter(), settings.time_budget)
    work = Configuration(configuration.model, configuration.q if q0 is None else q0)
    # (a seed as qpik.solve takes it: an int >= 0, a Generator, a SeedSequence or None)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(rng_state(seed))
    options = {
        "tol_position": settings.tol_position,
        "tol_orientation": settings.tol_orientation,
        "max_iters": settings.max_iters,
        "alpha": settings.alpha,
        "beta": settings.beta,
        "stall_window": settings.stall_window,
        "clip": clip,
    }
    loop = _Loop(work, frame, frame_type, target_position, target_rotation, step, options)

    def restart() -> None:
        work.update(work.random_q(rng))
        loop.c = loop.error()

    start = loop.outcome(Reason.MAX_ITERS)
    attempts = settings.effective_restarts
    best, reason, used = run_attempts(
        lambda: loop.attempt(clock),
        restart,
        attempts,
        clock,
        start,
        budget=settings.iteration_budget,
        spent=lambda: loop.iterations,
    )
    q, (position_error, orientation_error) = best.payload
    return IGMResult(
        q=q,
        converged=best.converged,
        reason=reason,
        iterations=loop.iterations,
        restarts_used=used,
        position_error=position_error,
        orientation_error=orientation_error,
        solve_time=clock.elapsed(),
    )


def pseudoinverse_igm(
    configuration: Configuration,
    frame: str,
    target_position: np.ndarray,
    target_rotation: np.ndarray | None = None,
    *,
    rcond: float = 1e-15,
    **keywords: Unpack[IGMKeywords],
) -> IGMResult:
    """The pseudoinverse IGM: ``q <- clip(q + beta J^+ alpha c)`` with the 6-D pose error
    ``c`` (:func:`pose_error`; 3-D without a target rotation), joint positions clipped into
    the limits after each step, random restarts as in :func:`igm` (whose keywords it
    takes). Near a singularity the step is unbounded (see :func:`pseudoinverse_step`)."""

    if isinstance(rcond, bool) or not (
        isinstance(rcond, (int, float, np.floating)) and 0 <= rcond < 1
    ):
        raise InvalidOption("rcond", rcond, "a number in [0, 1)")

    def rule(_configuration: Configuration, J: np.ndarray, c: np.ndarray) -> np.ndarray:
        return pseudoinverse_step(J, c, rcond)

    return igm(configuration, frame, target_position, target_rotation, rule, **keywords)


def damped_least_squares_igm(
    configuration: Configuration,
    frame: str,
    target_position: np.ndarray,
    target_rotation: np.ndarray | None = None,
    *,
    damping: float = 0.05,
    **keywords: Unpack[IGMKeywords],
) -> IGMResult:
    """The damped least-squares IGM: the loop of :func:`pseudoinverse_igm` with the step
    ``J^T (J J^T + damping^2 I)^-1 c`` (:func:`damped_least_squares_step`); ``damping`` is
    constant, in the task's mixed units ([m] and [rad])."""

    if isinstance(damping, bool) or not (
        isinstance(damping, (int, float, np.floating)) and 0 < damping < math.inf
    ):
        raise InvalidOption("damping", damping, "a finite number > 0")

    def rule(_configuration: Configuration, J: np.ndarray, c: np.ndarray) -> np.ndarray:
        return damped_least_squares_step(J, c, damping)

    return igm(configuration, frame, target_position, target_rotation, rule, **keywords)
