"""Gradients of kinematic measures with respect to the configuration, from the Jacobian's
derivatives: in closed form on a chain of hinges and slides (the kinematic Hessian), else
MuJoCo's (``mj_jacDot``)."""

from __future__ import annotations

import mujoco
import numpy as np

from ..core import checks
from ..core.jacobian import Rows, entry_scale, row_indices, singular_value_product
from .configuration import Configuration, FrameType
from .frames import FRAME_POSITIONS
from .kernels import hessian_weights
from .scratch import scratch_data

__all__ = [
    "check_configuration",
    "dof_thresholds",
    "frame_body",
    "frame_point",
    "hinge_slide_chain",
    "manipulability_gradient",
    "manipulability_parts",
    "manipulability_svd",
    "manipulability_terms",
    "motion_chain",
]


def frame_point(
    configuration: Configuration, data: mujoco.MjData, frame: str | int, frame_type: FrameType
) -> tuple[np.ndarray, int]:
    """World position of the frame origin in ``data`` and the body it moves with."""
    fid = configuration.frame_id(frame, frame_type)
    point = getattr(data, FRAME_POSITIONS[frame_type])[fid].copy()
    return point, frame_body(configuration.model, fid, frame_type)


def frame_body(model: mujoco.MjModel, fid: int, frame_type: FrameType) -> int:
    """The body a frame (``fid``, of ``frame_type``) moves with."""
    if frame_type is FrameType.SITE:
        return int(model.site_bodyid[fid])
    if frame_type is FrameType.GEOM:
        return int(model.geom_bodyid[fid])
    return int(fid)


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
    v_i``, where ``dJ/dq_k`` is the kinematic Hessian in closed form on a chain of hinges and
    slides, else MuJoCo's ``mj_jacDot`` at joint velocity ``e_k`` (the same to round-off). This
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
    value, gradient, _ = manipulability_parts(configuration, frame, frame_type, rows)
    return value, gradient


def manipulability_parts(
    configuration: Configuration,
    frame: str | int,
    frame_type: FrameType | str = "site",
    rows: Rows = "pose",
) -> tuple[float, np.ndarray, np.ndarray]:
    """:func:`manipulability_terms` and the rows' singular values (descending; none where
    there are more rows than dofs), from the same Jacobian and decomposition."""
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
    if len(idx) > nv:
        return 0.0, np.zeros(nv), np.zeros(0)  # (w is 0 for every q: m > n)
    value, U, s, Vt = manipulability_svd(jac[idx])
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
    chain = hinge_slide_chain(model, body)
    if chain is not None:
        return value, _chain_gradient(jac, weights, chain, nv), s
    gradient = np.empty(nv)
    jac_dot = np.empty((6, nv))
    for k in range(nv):
        data.qvel[:] = 0.0
        data.qvel[k] = 1.0
        mujoco.mj_comVel(model, data)
        mujoco.mj_jacDot(model, data, jac_dot[:3], jac_dot[3:], point, body)
        gradient[k] = np.vdot(jac_dot, weights)
    return value, gradient, s


def manipulability_svd(J: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """``(w, U, s, Vt)`` of a finite ``(m, n)`` Jacobian, ``m <= n``: its manipulability
    ``w = sqrt(det J J^T)`` (the product of the singular values, summed in logs; 0 where one
    is 0) and its thin SVD ``J = U diag(s) Vt``, from one decomposition of ``J`` scaled to
    entries of at most 1 (as :func:`qpik.analysis.manipulability` scales it: no overflow
    inside LAPACK). The value is that function's to round-off; :class:`ManipulabilityTask`'s
    error and rows both take it from here."""
    scale = entry_scale(J)
    U, s, Vt = np.linalg.svd(J / scale, full_matrices=False)
    with np.errstate(over="ignore"):
        s = s * scale
    return singular_value_product(s), U, s, Vt


def hinge_slide_chain(model: mujoco.MjModel, body: int) -> np.ndarray | None:
    """The dofs that move ``body`` (root first: each one's axis and anchor move with the ones
    before it), where every one is a hinge's or a slide's; None where a ball or free joint
    moves it (its dofs' axes turn with it: :func:`manipulability_terms` then differentiates by
    ``mj_jacDot``)."""
    key = id(model), body
    cached = _CHAINS.get(key)
    if cached is not None and cached[0] is model:
        return cached[1]
    dofs = _body_dofs(model, body)
    kinds = {int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)}
    simple = all(int(model.jnt_type[model.dof_jntid[d]]) in kinds for d in dofs)
    chain = np.array(sorted(dofs), dtype=np.int64) if simple else None
    if len(_CHAINS) >= 64:
        _CHAINS.clear()
    _CHAINS[key] = (model, chain)
    return chain


def _body_dofs(model: mujoco.MjModel, body: int) -> list[int]:
    """The dofs of ``body`` and of every body above it (unsorted)."""
    dofs: list[int] = []
    b = body
    while b > 0:
        start, count = int(model.body_dofadr[b]), int(model.body_dofnum[b])
        dofs.extend(range(start, start + count))
        b = int(model.body_parentid[b])
    return dofs


def motion_chain(model: mujoco.MjModel, body: int) -> tuple[np.ndarray, np.ndarray | None]:
    """``(dofs, thresholds)``: the dofs that move ``body`` (root first, int64) and, where a
    ball or free joint is among them, each dof's threshold ``t`` (nv,) int64 of the
    kinematic Hessian that ``mj_jacDot`` differentiates (the engine's
    ``hessian_weights_any``): dof ``a`` turns column ``b``'s axis exactly where ``a < t[b]``
    (``t[b] = b`` for a hinge or a slide: the dofs before it; its body's last dof + 1 for a
    ball's or a free joint's rotational dof, whose axes turn with their own joint; 0 for a
    free joint's translational dof, whose axes stay the world's). ``thresholds`` is None on
    a chain of hinges and slides (:func:`hinge_slide_chain`: the engine's
    ``hessian_weights``)."""
    simple = hinge_slide_chain(model, body)
    if simple is not None:
        return simple, None
    key = id(model), body
    cached = _MOTION.get(key)
    if cached is not None and cached[0] is model:
        return cached[1]
    answer = np.array(sorted(_body_dofs(model, body)), dtype=np.int64), dof_thresholds(model)
    if len(_MOTION) >= 64:
        _MOTION.clear()
    _MOTION[key] = (model, answer)
    return answer


#: motion_chain's answers where a ball or free joint moves the body, by (model, body)
_MOTION: dict[tuple[int, int], tuple[mujoco.MjModel, tuple[np.ndarray, np.ndarray]]] = {}


def dof_thresholds(model: mujoco.MjModel) -> np.ndarray:
    """:func:`motion_chain`'s thresholds (nv,) int64 of every dof of ``model`` (a model's
    own: the same for every chain in it)."""
    thresholds = np.arange(model.nv, dtype=np.int64)
    free, ball = int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_BALL)
    for j in range(model.njnt):
        kind, first, body = (
            int(model.jnt_type[j]),
            int(model.jnt_dofadr[j]),
            int(model.jnt_bodyid[j]),
        )
        end = int(model.body_dofadr[body] + model.body_dofnum[body])
        if kind == free:
            thresholds[first : first + 3] = 0
            thresholds[first + 3 : first + 6] = end
        elif kind == ball:
            thresholds[first : first + 3] = end
    return thresholds


#: hinge_slide_chain's answers by (model, body): the model kept beside its id
_CHAINS: dict[tuple[int, int], tuple[mujoco.MjModel, np.ndarray | None]] = {}


def _chain_gradient(jac: np.ndarray, weights: np.ndarray, chain: np.ndarray, nv: int) -> np.ndarray:
    """``<dJ/dq_k, W>`` for every dof ``k``, ``J = [J_v; J_w]`` (6, nv) the frame's Jacobian
    at its point and ``W`` (6, nv) the weights, on a chain of hinges and slides (``chain``:
    its dofs, root first; the other dofs move nothing: 0): the kinematic Hessian in closed
    form (Haviland and Corke 2023, part I), by the engine (:data:`.kernels.hessian_weights`):
    what ``mj_jacDot`` gives at each joint velocity ``e_k``, to round-off, without a pass of
    MuJoCo's velocity kinematics per dof."""
    gradient = np.empty(nv)
    hessian_weights(jac, weights, chain, gradient)
    return gradient
