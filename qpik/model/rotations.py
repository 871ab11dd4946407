r"""Rotations: the orientation error of qpik, and rotation-matrix and quaternion helpers
(NumPy arrays in and out; the log and the inverse left Jacobian are the compiled ones of
:mod:`qpik.model.lie`, which the IGM and the frame tasks use too).

Conventions:

- rotation matrices ``R`` (3, 3) map frame coordinates to world coordinates;
- quaternions are MuJoCo's ``(w, x, y, z)``;
- a *rotation vector* is ``axis * angle`` [rad], ``angle`` in ``[0, pi]``;
- the orientation error of a frame at ``R_current`` toward ``R_target`` is the world-frame
  rotation vector ``log(R_target R_current^T)``: the rotation, about world axes, that takes
  the current orientation onto the target. It pairs with the angular rows ``omega`` of a
  world-aligned Jacobian ``[v; omega]`` as ``p_target - p`` pairs with ``v``: ``J dq = e``
  moves toward the target to first order.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from ..core import checks
from . import lie

__all__ = [
    "left_jacobian_inverse",
    "matrix_to_quaternion",
    "nearest_rotation",
    "orientation_angle",
    "orientation_error",
    "quaternion_to_matrix",
    "rotation_defect",
    "rotation_from_vector",
    "rotation_vector",
    "rpy_to_matrix",
    "skew",
]

#: A matrix whose ``max |R R^T - I|`` is above this is replaced by its nearest rotation
#: (:func:`nearest_rotation`): below it, every formula of the angle between two
#: orientations (``acos`` of the trace included) agrees within 1e-7 rad.
ORTHONORMAL_TOLERANCE = 1e-14


def skew(v: npt.ArrayLike) -> np.ndarray:
    """The cross-product matrix ``[v]`` (3, 3): ``[v] w = v x w``."""
    x, y, z = np.asarray(v, dtype=float)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rotation_vector(R: npt.ArrayLike) -> np.ndarray:
    """``log(R)`` as a rotation vector (axis * angle, angle in [0, pi]) [rad], shape (3,).

    Accurate over the whole range (:func:`qpik.model.lie.rotation_log`): the angle is
    ``atan2(|v|, (tr R - 1) / 2)`` with ``v`` the skew part of ``R`` (no loss near 0, where
    ``acos`` of the trace loses half the digits), and near pi the axis comes from the
    symmetric part ``R + R^T = 2 cos I + 2 (1 - cos) u u^T``, its sign from the skew part.
    """
    out = np.empty(3)
    lie.rotation_log(_matrix(R), out)
    return out


def orientation_error(R_current: npt.ArrayLike, R_target: npt.ArrayLike) -> np.ndarray:
    """The world-frame rotation vector ``log(R_target R_current^T)`` (3,) [rad] that takes
    the orientation ``R_current`` onto ``R_target`` (both frame-to-world rotations)."""
    current = checks.check_matrix("R_current", R_current, (3, 3))
    target = checks.check_matrix("R_target", R_target, (3, 3))
    return rotation_vector(target @ current.T)


def orientation_angle(R_current: npt.ArrayLike, R_target: npt.ArrayLike) -> float:
    """The angle [rad], in [0, pi], between two orientations: the norm of
    :func:`orientation_error`, from ``atan2`` (accurate near 0 and pi)."""
    M = np.asarray(R_target, dtype=float) @ np.asarray(R_current, dtype=float).T
    return float(lie.rotation_log(_matrix(M), np.empty(3)))


def rotation_from_vector(phi: npt.ArrayLike) -> np.ndarray:
    """``exp([phi])``: the rotation matrix (3, 3) of rotation vector ``phi`` [rad]
    (Rodrigues' formula)."""
    phi = np.asarray(phi, dtype=float)
    theta = math.sqrt(float(phi @ phi))
    K = skew(phi)
    if theta < 1e-8:  # second-order series
        return np.eye(3) + K + 0.5 * (K @ K)
    return (
        np.eye(3)
        + (math.sin(theta) / theta) * K
        + ((1.0 - math.cos(theta)) / (theta * theta)) * (K @ K)
    )


def left_jacobian_inverse(phi: npt.ArrayLike) -> np.ndarray:
    """Inverse left Jacobian of SO(3) at rotation vector ``phi`` [rad], (3, 3):
    ``d log(R) = J_l^-1(phi) omega`` for a world-frame perturbation ``dR = [omega] R``
    (:func:`qpik.model.lie.so3_ljacinv`)."""
    out = np.empty(9)
    lie.so3_ljacinv(out, np.ascontiguousarray(phi, dtype=float).reshape(3))
    return out.reshape(3, 3)


def quaternion_to_matrix(quaternion: npt.ArrayLike) -> np.ndarray:
    """Rotation matrix (3, 3) of a quaternion ``(w, x, y, z)`` (normalised first), or
    matrices (k, 3, 3) of quaternions (k, 4). As MuJoCo's ``mju_quat2Mat`` for unit ones."""
    q = np.asarray(quaternion, dtype=float)
    single = q.ndim == 1
    q = np.atleast_2d(q)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    out = np.empty((q.shape[0], 3, 3))
    out[:, 0, 0] = w * w + x * x - y * y - z * z
    out[:, 1, 1] = w * w - x * x + y * y - z * z
    out[:, 2, 2] = w * w - x * x - y * y + z * z
    out[:, 0, 1] = 2 * (x * y - w * z)
    out[:, 0, 2] = 2 * (x * z + w * y)
    out[:, 1, 0] = 2 * (x * y + w * z)
    out[:, 1, 2] = 2 * (y * z - w * x)
    out[:, 2, 0] = 2 * (x * z - w * y)
    out[:, 2, 1] = 2 * (y * z + w * x)
    return out[0] if single else out


def matrix_to_quaternion(R: npt.ArrayLike) -> np.ndarray:
    """Unit quaternion ``(w, x, y, z)`` (4,) of rotation matrix ``R``, with ``w >= 0``
    (Shepperd's method: the largest of the four squared components is taken first)."""
    R = np.asarray(R, dtype=float)
    trace = R[0, 0] + R[1, 1] + R[2, 2]
    squares = np.array([trace, R[0, 0], R[1, 1], R[2, 2]])
    best = int(np.argmax(squares))
    if best == 0:
        w = 0.5 * math.sqrt(max(1.0 + trace, 0.0))
        quat = np.array(
            [
                w,
                (R[2, 1] - R[1, 2]) / (4 * w),
                (R[0, 2] - R[2, 0]) / (4 * w),
                (R[1, 0] - R[0, 1]) / (4 * w),
            ]
        )
    else:
        i = best - 1
        j, k = (i + 1) % 3, (i + 2) % 3
        r = math.sqrt(max(1.0 + R[i, i] - R[j, j] - R[k, k], 0.0))
        quat = np.empty(4)
        quat[1 + i] = 0.5 * r
        quat[0] = (R[k, j] - R[j, k]) / (2 * r)
        quat[1 + j] = (R[j, i] + R[i, j]) / (2 * r)
        quat[1 + k] = (R[k, i] + R[i, k]) / (2 * r)
    quat /= np.linalg.norm(quat)
    return -quat if quat[0] < 0 else quat


def rpy_to_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` (3, 3): fixed-axis roll, then pitch, then yaw [rad]
    (the URDF ``rpy`` convention)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def nearest_rotation(R: npt.ArrayLike) -> np.ndarray:
    """The rotation matrix nearest to ``R`` (3, 3) in the Frobenius norm (``U V^T`` of its
    SVD), or ``R`` itself (as a float array) when it is already orthonormal within
    :data:`ORTHONORMAL_TOLERANCE`. Targets accepted within a tolerance of being a rotation
    go through it once, so that the orientation errors reported against them are those of
    a rotation: the same whatever formula measures them (an ``acos`` of the trace of a
    matrix 1e-9 off orthonormal is off by 3e-5 rad near 0)."""
    R = np.asarray(R, dtype=float)
    if R.shape == (3, 3) and not rotation_defect(R) > ORTHONORMAL_TOLERANCE:
        return R  # one compiled pass (rotation_defect: inf where det R <= 0, never here)
    U, _, Vt = np.linalg.svd(R)
    if np.linalg.det(U @ Vt) < 0.0:  # det R <= 0 is rejected before reaching here
        U[:, -1] = -U[:, -1]
    return U @ Vt


def rotation_defect(R: npt.ArrayLike) -> float:
    """``max |R R^T - I|`` of a (3, 3) matrix, or inf when it has a non-finite entry, another
    shape, or ``det R <= 0``: a matrix is a rotation within ``tol`` when this is ``<= tol``."""
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3):
        return math.inf
    return float(lie.rotation_defect(np.ascontiguousarray(R)))


def _matrix(R: npt.ArrayLike) -> np.ndarray:
    """``R`` as a C-contiguous float (3, 3) array, as the compiled routines take it."""
    return np.ascontiguousarray(R, dtype=float).reshape(3, 3)
