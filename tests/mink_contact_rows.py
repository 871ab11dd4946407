"""mink's contact rows without its BLAS product, for the bitwise tests of the collision rows.

mink's ``compute_contact_normal_jacobian`` ends with ``normal @ (J2 - J1)``: NumPy hands
that product to its BLAS, whose kernel depends on the CPU (OpenBLAS picks it at run time),
and some kernels fuse multiply-adds (OpenBLAS 0.3.30's SkylakeX ``dgemv``: rows one ulp
off the Haswell kernel's). qpik's rows are the sums ``n0 d0 + n1 d1 + n2 d2`` in order,
with no fused multiply-add, on every machine. The tests compare them bitwise with mink's
own loop run on that same sum (``use_minks_arithmetic``), and with mink's BLAS product to
a few ulps (``minks_blas_rows``, ``assert_rows_near_minks``)."""

from __future__ import annotations

import mink.limits.collision_avoidance_limit as _mink_collision
import mujoco
import numpy as np

_minks_blas = _mink_collision.compute_contact_normal_jacobian


def contact_normal_jacobian(
    model, data, geom1_id, geom2_id, fromto, normal, jac1, jac2
) -> np.ndarray:
    """mink's compute_contact_normal_jacobian, its final product summed term by term in
    order (elementwise NumPy: no BLAS, no fused multiply-add)."""
    normal[:] = fromto[3:] - fromto[:3]
    mujoco.mju_normalize3(normal)
    geom_bodyid = model.geom_bodyid
    mujoco.mj_jac(model, data, jac2, None, fromto[3:], geom_bodyid[geom2_id])
    mujoco.mj_jac(model, data, jac1, None, fromto[:3], geom_bodyid[geom1_id])
    jac2 -= jac1
    return normal[0] * jac2[0] + normal[1] * jac2[1] + normal[2] * jac2[2]


def assert_rows_near_minks(G: np.ndarray, theirs: np.ndarray) -> None:
    """``G`` within a few ulps of mink's BLAS rows ``theirs``: each entry a sum of three
    products of a unit normal's components with point-Jacobian entries [m] (lever arms of a
    robot's size), fused or not, so within 8 eps (1 + the row's largest entry) [m]."""
    assert G.shape == theirs.shape
    if G.size:
        scale = 1.0 + np.abs(theirs).max(axis=1, keepdims=True)
        assert np.all(np.abs(G - theirs) <= 8 * np.finfo(float).eps * scale)


def minks_blas_rows(limit, configuration, dt: float):
    """mink's own ``limit.compute_qp_inequalities(configuration, dt)``, its BLAS product
    included (also while :func:`use_minks_arithmetic` is in effect)."""
    patched = _mink_collision.compute_contact_normal_jacobian
    _mink_collision.compute_contact_normal_jacobian = _minks_blas
    try:
        return limit.compute_qp_inequalities(configuration, dt)
    finally:
        _mink_collision.compute_contact_normal_jacobian = patched


def use_minks_arithmetic(monkeypatch) -> None:
    """mink's collision limits make their rows by :func:`contact_normal_jacobian` until the
    test ends (``monkeypatch``: pytest's fixture)."""
    monkeypatch.setattr(_mink_collision, "compute_contact_normal_jacobian", contact_normal_jacobian)
