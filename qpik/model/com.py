"""The Jacobian of a subtree's centre of mass in O(nv), from MuJoCo's com-based dof axes.

``mj_jacSubtreeCom`` sums the Jacobians of the subtree's bodies one by one (6.4 us for the
floating Talos, 61 bodies and 38 dofs). A dof of body ``b`` moves the bodies of ``B``'s
subtree that lie in ``b``'s own subtree: all of ``b``'s when ``b`` is in ``B``'s subtree, all
of ``B``'s when ``b`` lies above ``B``, none otherwise. Their mass-weighted sum is one point's
Jacobian column scaled, ``scale (v + omega x (c - subtree_com[root]))``, with ``c`` the
centre of the moved part (``subtree_com[b]`` or ``subtree_com[B]``) and ``scale`` its share of
``B``'s mass (``m_b / m_B`` or 1). :func:`subtree_com_chain` finds ``c``'s body and the
scale per dof once per model and body; :func:`subtree_com_jacobian` evaluates the columns
(compiled, ``qpik._cpp/model/com.hpp``). Equal to MuJoCo's to round-off
(``tests/model/test_com_jacobian.py``).
"""

from __future__ import annotations

import mujoco
import numpy as np

from . import kernels as _kernels

__all__ = ["SubtreeComChain", "subtree_com_chain", "subtree_com_jacobian"]

#: ``(point, root, scale)``: per dof, the body whose subtree centre the column uses, the
#: dof's tree root (the point ``cdof``'s linear part is taken at) and the mass share
#: (0: the dof moves none of the subtree).
SubtreeComChain = tuple[np.ndarray, np.ndarray, np.ndarray]


def subtree_com_chain(model: mujoco.MjModel, body: int) -> SubtreeComChain | None:
    """The per-dof chain of body ``body``'s subtree centre of mass (see the module), or None
    when the subtree has no mass (its centre is undefined: MuJoCo's own function answers)."""
    nv = model.nv
    parent = model.body_parentid
    mass = float(model.body_subtreemass[body])
    if not mass > 0.0:
        return None
    point = np.zeros(nv, np.int64)
    root = np.zeros(nv, np.int64)
    scale = np.zeros(nv)
    for d in range(nv):
        b = int(model.dof_bodyid[d])
        root[d] = int(model.body_rootid[b])
        above = b  # is B an ancestor of b (or b itself)?
        while above > body:
            above = int(parent[above])
        if above == body:  # b in B's subtree (B = 0: every body)
            point[d] = b
            scale[d] = float(model.body_subtreemass[b]) / mass
            continue
        below = body  # is b an ancestor of B?
        while below > b:
            below = int(parent[below])
        if below == b:
            point[d] = body
            scale[d] = 1.0
    return point, root, scale


def subtree_com_jacobian(
    data: mujoco.MjData, chain: SubtreeComChain, out: np.ndarray
) -> np.ndarray:
    """``d c / d q`` ``(3, nv)`` [m per unit of dq], world frame, of the subtree centre of mass
    whose chain :func:`subtree_com_chain` made, at ``data``'s kinematics (its ``cdof`` and
    ``subtree_com``, as ``mj_kinematics`` and ``mj_comPos`` leave them), into ``out``."""
    _kernels.subtree_com_jacobian(data.cdof, data.subtree_com, *chain, out)
    return out
