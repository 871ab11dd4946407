"""SO(3) and SE(3), compiled (``qpik/_cpp/model/so3.hpp`` and ``se3.hpp``): the one home
of the rotation log, the inverse left Jacobian and mink's SE(3) arithmetic.

The SE(3) routines and the quaternion log are mink's (``mink/lie/_lie_ops_c.c``), ported
operation for operation so that a whole IK step can run in one compiled call; they equal
mink's to round-off (tests compare them to 1e-12). :mod:`qpik.model.rotations` holds the
NumPy-facing helpers built on these.

Poses are ``wxyz_xyz`` (7,): a unit quaternion ``(w, x, y, z)`` then a translation [m].
Tangents are ``[v; omega]`` (6,) [m, rad]. 3x3 matrices are row-major (9,), as MuJoCo's
``xmat``. Every function writes into its first (``rotation_log``: its second) argument, a
float64 C-contiguous array of the exact shape (never a silent copy): nothing is allocated.

* ``rotation_log(R, out) -> angle``: rotation vector [rad] of a rotation matrix (3, 3),
  accurate near 0 and near pi; returns the angle.
* ``so3_log(omega, wxyz)``: rotation vector [rad] of a unit quaternion.
* ``so3_ljacinv(out, omega)``: inverse left Jacobian of SO(3) (row-major 3x3 into (9,)).
* ``rotation_defect(R) -> float``: ``max |R R^T - I|`` (inf: not finite or ``det R <= 0``).
* ``xmat_xpos_to_wxyz_xyz(out, xmat, xpos)``: a MuJoCo frame as ``wxyz_xyz``.
* ``se3_log(tangent, T)``, ``se3_inverse_multiply(out, a, b)`` (``a^-1 b``),
  ``se3_rminus(tangent, a, b)`` (``log(b^-1 a)``), ``se3_jlog(jlog, T)`` (6, 6).
"""

from __future__ import annotations

from .._engine.model import rotation_defect, rotation_log
from .._engine.tasks import (
    EPS,
    se3_inverse_multiply,
    se3_jlog,
    se3_log,
    se3_rminus,
    so3_ljacinv,
    so3_log,
    xmat_xpos_to_wxyz_xyz,
)

__all__ = [
    "EPS",
    "rotation_defect",
    "rotation_log",
    "se3_inverse_multiply",
    "se3_jlog",
    "se3_log",
    "se3_rminus",
    "so3_ljacinv",
    "so3_log",
    "xmat_xpos_to_wxyz_xyz",
]
