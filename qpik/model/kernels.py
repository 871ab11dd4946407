r"""Compiled C++ kernels of the kinematic chain and of rotations.

The kernels live in the compiled engine (``qpik/_cpp``: ``model/chain.hpp``,
``model/so3.hpp``; bound as :mod:`qpik._engine.model`); this module names them for the
Python side. Every kernel takes plain arrays (no MuJoCo call happens inside);
arrays they write into must already have the right dtype and layout (no silent copy), and
a wrong shape raises ValueError. ``tests/model/test_engine_model.py`` checks them bit for bit
against recorded answers (``tests/fixtures/model.npz``).

Kinematics follow MuJoCo's ``mj_kinematics`` (``engine_core_smooth.c``): per body on the
chain, ``p <- p + R body_pos``, ``R <- R body_rot``; then per joint of the body, the axis
``R axis`` and anchor ``p + R jnt_pos`` in the world frame; a hinge rotates ``R`` about its
local axis by ``q - qpos0`` and keeps the anchor fixed, a slide moves ``p`` along the axis
by ``q - qpos0``. The frame Jacobian (``mj_jac``) has, per dof, ``[u x (p_f - a); u]`` for a
hinge and ``[u; 0]`` for a slide (world-aligned, ``[v; omega]``).
"""

from __future__ import annotations

from .._engine import model as _model

HINGE = 0
SLIDE = 1

# ------------------------------------------------------------------ kinematics
#: ``Chain(arrays, nq, nv)``: the tuple of :class:`qpik.model.KinematicChain` (``arrays``)
#: checked and copied once into a small compiled struct; every kernel's ``chain`` argument
#: takes it (no per-call unpacking of eleven arrays) or the tuple itself.
Chain = _model.Chain
#: ``ArrayWatch(arrays)``: a copy of the bytes of C-contiguous arrays; ``unchanged()`` tells
#: whether they still hold them (one ``memcmp`` per array). It keeps no reference: the
#: arrays' memory must outlive its calls (the one-shot cache of :func:`qpik.solve` holds
#: views of a live model's arrays).
ArrayWatch = _model.ArrayWatch
#: ``fk_jac(chain, q, position, rotation, jac, want_jac)``: pose of the chain's frame at
#: ``q`` (world frame: ``position`` (3,) [m], ``rotation`` (3, 3)) and, if ``want_jac``, its
#: world-aligned Jacobian ``jac`` (6, nv) ``[v; omega]`` (columns of dofs off the chain are
#: zero), written in place. ``chain``: a :class:`Chain` or the tuple of
#: :class:`qpik.model.KinematicChain`.
fk_jac = _model.fk_jac
#: ``subtree_com_jacobian(cdof, subtree_com, point, root, scale, jac)``: the Jacobian ``jac``
#: (3, nv) [m per unit of dq], world frame, of a subtree's centre of mass from MuJoCo's ``cdof``
#: and ``subtree_com`` and the subtree's per-dof chain (:func:`qpik.model.com.subtree_com_chain`),
#: written in place, in O(nv).
subtree_com_jacobian = _model.subtree_com_jacobian
#: ``reach_radius(chain, q, center) -> float``: length of the path ``s_1 -> r_2 -> s_2 ->
#: ... -> s_m -> frame`` through the feet of the common perpendiculars of consecutive hinge
#: axes at ``q``; ``center`` receives ``s_1``. Without a hinge, the frame position and 0.
reach_radius = _model.reach_radius
#: ``start_defect(q, lower, upper, tol) -> (code, i)``: ``(1, i)`` for the first entry of
#: ``q`` that is not finite, ``(2, i)`` for the first outside ``[lower - tol, upper + tol]``,
#: else ``(0, -1)`` with ``q`` clipped into ``[lower, upper]`` in place (``np.clip``).
start_defect = _model.start_defect
#: ``quat2mat(quat) -> (k, 3, 3)``: rotation matrices of unit quaternions (k, 4) ``(w, x,
#: y, z)``.
quat2mat = _model.quat2mat
#: ``hessian_weights(jac, weights, chain, out)``: ``<dJ/dq_a, W>`` for every dof ``a`` into
#: ``out`` (nv,), ``jac`` (6, nv) ``[v; omega]`` a frame's Jacobian at its point, ``weights``
#: (6, nv), ``chain`` (int64) the dofs of a chain of hinges and slides, root first: the
#: kinematic Hessian in closed form (``model/jac.hpp``; 0 off the chain).
hessian_weights = _model.hessian_weights

# ------------------------------------------------------------------- rotations
#: ``rotation_log(R, out) -> angle``: rotation vector of ``R`` into ``out`` (accurate near 0
#: and near pi); :mod:`qpik.model.lie` is its home for Python callers.
rotation_log = _model.rotation_log
#: ``rotation_defect(R) -> float``: ``max |R R^T - I|``, or inf when an entry is not finite
#: or ``det R <= 0``.
rotation_defect = _model.rotation_defect
#: ``target_defect(position, rotation, has_rot) -> int``: 0 valid; 1 position not finite;
#: 2 rotation not finite; 3 not a rotation (``|R R^T - I| > 1e-6`` or ``det R <= 0``).
target_defect = _model.target_defect
#: ``left_jacobian_inverse(phi, out)``: inverse left Jacobian of SO(3) at rotation vector
#: ``phi`` into ``out`` (3, 3): the binding of ``so3_ljacinv`` (:mod:`qpik.model.lie`) that
#: writes a (3, 3) array.
left_jacobian_inverse = _model.left_jacobian_inverse

assert (HINGE, SLIDE) == (_model.HINGE, _model.SLIDE)
