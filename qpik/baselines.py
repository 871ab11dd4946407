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
