"""SE(3) routines of mink's compiled Lie-group module (``mink/lie/_lie_ops_c.c``), ported
operation for operation to C++ (``qpik/_cpp/model/se3.hpp``, bound in
``qpik._engine.tasks``) so that a whole IK step can run in one compiled call.

Poses are ``wxyz_xyz`` (7,): a unit quaternion ``(w, x, y, z)`` then a translation [m].
Tangents are ``[v; omega]`` (6,) [m, rad]. 3x3 matrices are row-major (9,), as MuJoCo's
``xmat``. Every function writes into its first argument (a float64 C-contiguous array of
the exact shape: never a silent copy): nothing is allocated, and the arithmetic is done in
the same order as mink's C code (tests compare them to 1e-12).

* ``so3_log(omega, wxyz)``: rotation vector [rad] of a unit quaternion.
* ``so3_ljacinv(out, omega)``: SO(3) left Jacobian inverse (row-major 3x3 into (9,)).
* ``xmat_xpos_to_wxyz_xyz(out, xmat, xpos)``: a MuJoCo frame as ``wxyz_xyz``.
* ``se3_log(tangent, T)``, ``se3_inverse_multiply(out, a, b)`` (``a^-1 b``),
  ``se3_rminus(tangent, a, b)`` (``log(b^-1 a)``), ``se3_jlog(jlog, T)`` (6, 6).
"""

from __future__ import annotations

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
    "se3_inverse_multiply",
    "se3_jlog",
    "se3_log",
    "se3_rminus",
    "so3_ljacinv",
    "so3_log",
    "xmat_xpos_to_wxyz_xyz",
]
