"""Gradients of kinematic measures with respect to the configuration, from MuJoCo's
Jacobian derivatives (``mj_jacDot``)."""

from __future__ import annotations

import mujoco
import numpy as np
import scipy.linalg

from ..core import checks
from ..core.jacobian import Rows, manipulability, row_indices
from .configuration import Configuration, FrameType
from .scratch import scratch_data

__all__ = [
    "check_configuration",
    "frame_point",
    "manipulability_gradient",
    "manipulability_terms",
]


def frame_point(
    configuration: Configuration, data: mujoco.MjData, frame: str | int, frame_type: FrameType
) -> tuple[np.ndarray, int]:
    """World position of the frame origin in ``data`` and the body it moves with."""
    fid = configuration.frame_id(frame, frame_type)
    model = configuration.model
    if frame_type is FrameType.SITE:
        return data.site_xpos[fid].copy(), int(model.site_bodyid[fid])
    if frame_type is FrameType.GEOM:
        return data.geom_xpos[fid].copy(), int(model.geom_bodyid[fid])
    return data.xpos[fid].copy(), fid


def check_configuration(configuration: Configuration) -> None:
    """A :class:`qpik.Configuration`, else :class:`InvalidArgumentType` (a TypeError)."""
    checks.check_instance(
        "configuration",
        configuration,
        Configuration,
        "a qpik.Configuration (build one with qpik.Configuration(qpik.load_robot(name), q))",
    )


def manipulability_gradient(
    configuration: Configuration,
    frame: str | int,
    frame_type: FrameType | str = "site",
    rows: Rows = "pose",
) -> np.ndarray:
    """Gradient ``(nv,)`` of the manipulability ``sqrt(det J J^T)`` of a frame's Jacobian
    (the chosen ``rows``) w.r.t. the configuration (tangent space: ``q`` for hinges and
    slides).

    Analytic: with ``J = U S V^T``, ``dw/dq_k = sum_i (prod_{j != i} s_j) u_i^T (dJ/dq_k)
    v_i``, where ``dJ/dq_k`` is MuJoCo's ``mj_jacDot`` at joint velocity ``e_k``. This
    equals ``w tr(J^+ dJ/dq_k)`` away from singularities and stays finite at a
    singularity of rank ``m - 1`` (where ``w`` has a kink; one one-sided derivative is
    returned). Zero when ``m > n`` (``w`` is then identically 0). The caller's
    configuration is not changed.
    """
    return manipulability_terms(configuration, frame, frame_type, rows)[1]


def manipulability_terms(
    configuration: Configuration,
    frame: str | int,
    frame_type: FrameType | str = "site",
    rows: Rows = "pose",
) -> tuple[float, np.ndarray]:
    """The manipulability ``w`` of the frame's Jacobian rows
    (:func:`qpik.analysis.manipulability`) and its gradient (:func:`manipulability_gradient`)
    from one Jacobian: what a task needs each step."""
    check_configuration(configuration)
    kind = FrameType.parse(frame_type)
    idx = list(row_indices(rows))
    model = configuration.model
    nv = model.nv
    data = scratch_data(model, "gradients")  # (every input it reads is set here)
    data.qpos[:] = configuration.q
    if model.nmocap:
        data.mocap_pos[:] = configuration.data.mocap_pos
        data.mocap_quat[:] = configuration.data.mocap_quat
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    point, body = frame_point(configuration, data, frame, kind)
    jac = np.empty((6, nv))
    mujoco.mj_jac(model, data, jac[:3], jac[3:], point, body)
    value = manipulability(jac[idx])
    if len(idx) > nv:
        return value, np.zeros(nv)
    U, s, Vt = scipy.linalg.svd(jac[idx], full_matrices=False)
    singular = s.tolist()
    coefficients = np.empty(len(singular))
    for i in range(len(singular)):  # prod_{j != i} s_j, in order (np.prod's)
        product = 1.0
        for j, sj in enumerate(singular):
            if j != i:
                product *= sj
        coefficients[i] = product
    # sum_i c_i u_i^T dJ v_i = <dJ, W>, W = U diag(c) V^T (the rows idx)
    weights = np.zeros((6, nv))
    np.add.at(weights, idx, (U * coefficients) @ Vt)  # (a row named twice: both terms)
    gradient = np.empty(nv)
    jac_dot = np.empty((6, nv))
    for k in range(nv):
        data.qvel[:] = 0.0
        data.qvel[k] = 1.0
        mujoco.mj_comVel(model, data)
        mujoco.mj_jacDot(model, data, jac_dot[:3], jac_dot[3:], point, body)
        gradient[k] = np.vdot(jac_dot, weights)
    return value, gradient
