r"""The model's couplings: the joint and fixed-tendon equality constraints it states.

MuJoCo states a coupling of two scalar joints (MJCF ``<equality><joint>``, and the URDF
``<mimic>`` tag, which MuJoCo's URDF import turns into one) as

.. math::

    r(q) = (q_1 - q_{1,0}) - p(q_2 - q_{2,0}) = 0, \qquad
    p(x) = c_0 + c_1 x + c_2 x^2 + c_3 x^3 + c_4 x^4,

with ``q_{i,0}`` the joints' ``qpos0`` and ``c`` the ``polycoef`` (``eq_data[:5]``); without
``joint2``, :math:`r = q_1 - q_{1,0} - c_0`. A ``<equality><tendon>`` states the same of
two tendons' lengths (their ``tendon_length0`` as references); qpik takes the fixed
tendons' (a linear combination ``sum_i coef_i q_i`` of scalar joints). The Jacobian of a
row is :math:`\partial r / \partial q_1 - p'(x)\, \partial r / \partial q_2`, exact: the
rows are MuJoCo's own ``efc_pos`` and ``efc_J`` of these constraints (checked in
tests/model/test_model_couplings.py).

:class:`Couplings` holds these rows of a model (:func:`model_couplings`); qpik keeps them
as the top priority of every differential step (:class:`qpik.IKSolver`, option
``StepOptions.couplings``) and of full IK (:func:`qpik.solve`). The equalities it does not
take (connect and weld loop closures, spatial tendons, inactive ones) are listed in
:attr:`Couplings.skipped`; add mink's :class:`mink.EqualityConstraintTask` to a level for
those. :func:`unheld_equalities` lists the active ones and :func:`unheld_equality_errors`
measures them at a configuration (MuJoCo's own residuals): a full-IK solve does not claim
convergence at a ``q`` that breaks one (:attr:`qpik.IKResult.constraint_error`).

Units: the residual of a joint coupling is in the joints' units [rad or m].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
import numpy.typing as npt

from ..core.checks import check_vector
from ..errors import InvalidConfiguration
from .chain import QPOS_WIDTH, body_chain_joints
from .frames import check_model_type
from .scratch import scratch_data

__all__ = [
    "Couplings",
    "closed_chain_start",
    "default_start",
    "equality_dofs",
    "model_couplings",
    "unheld_equalities",
    "unheld_equality_errors",
]

_SCALAR = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


@dataclass(frozen=True, eq=False)
class Couplings:
    """The coupling rows of a model (build with :func:`model_couplings`).

    Each row ``i`` couples two linear measures of ``q``, ``s_1 = a_1 . q[qadr]`` and
    ``s_2 = a_2 . q[qadr]`` (a joint's coordinate, or a fixed tendon's length):
    ``r_i = (s_1 - ref_1) - p_i(s_2 - ref_2)``.

    Attributes:
        names: each row's equality name (``"equality #k"`` when unnamed).
        qadr: the qpos addresses of the coupled joints ``(m,)``.
        dofs: their dof addresses ``(m,)`` (the same joints, in the same order).
        first, second: the measures' coefficients ``(rows, m)`` over those joints
            (``second`` is zero on a row without a second joint or tendon).
        reference: ``(rows, 2)``: ``ref_1``, ``ref_2`` (at ``qpos0``).
        poly: ``(rows, 5)``: the polynomial's coefficients ``c_0 ... c_4``.
        has_second: ``(rows,)`` whether a row has a second joint or tendon.
        nq, nv: the model's sizes.
        skipped: the model's equalities not taken, each ``"name (why)"``.
    """

    names: tuple[str, ...]
    qadr: np.ndarray = field(repr=False)
    dofs: np.ndarray = field(repr=False)
    first: np.ndarray = field(repr=False)
    second: np.ndarray = field(repr=False)
    reference: np.ndarray = field(repr=False)
    poly: np.ndarray = field(repr=False)
    has_second: np.ndarray = field(repr=False)
    nq: int = 0
    nv: int = 0
    skipped: tuple[str, ...] = ()

    def __len__(self) -> int:
        return len(self.names)

    def _q(self, q: npt.ArrayLike) -> np.ndarray:
        return check_vector("q", q, self.nq, error=InvalidConfiguration)

    def _measures(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = q[self.qadr]
        s1 = self.first @ x - self.reference[:, 0]
        s2 = np.where(self.has_second, self.second @ x - self.reference[:, 1], 0.0)
        return s1, s2

    def residual(self, q: npt.ArrayLike) -> np.ndarray:
        """The rows' residuals ``r(q)`` ``(rows,)`` [the joints' units]."""
        s1, s2 = self._measures(self._q(q))
        c = self.poly
        value = c[:, 0] + s2 * (c[:, 1] + s2 * (c[:, 2] + s2 * (c[:, 3] + s2 * c[:, 4])))
        return s1 - value

    def jacobian(self, q: npt.ArrayLike) -> np.ndarray:
        """``dr/dq`` in the tangent space ``(rows, nv)``."""
        _, s2 = self._measures(self._q(q))
        c = self.poly
        slope = c[:, 1] + s2 * (2.0 * c[:, 2] + s2 * (3.0 * c[:, 3] + s2 * 4.0 * c[:, 4]))
        slope = np.where(self.has_second, slope, 0.0)
        jacobian = np.zeros((len(self.names), self.nv))
        jacobian[:, self.dofs] = self.first - slope[:, None] * self.second
        return jacobian

    def linear_form(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(rows, offset)`` with ``r(q) = rows @ q[qadr] - offset`` when every coupling
        is linear (a URDF mimic, a joint equality of degree 1; :meth:`residual` expanded),
        else None. Its Jacobian is then constant."""
        if np.any(self.poly[:, 2:]):
            return None
        c1 = np.where(self.has_second, self.poly[:, 1], 0.0)
        rows = self.first - c1[:, None] * self.second
        second_ref = np.where(self.has_second, self.reference[:, 1], 0.0)
        return rows, self.reference[:, 0] + self.poly[:, 0] - c1 * second_ref

    def error(self, q: npt.ArrayLike) -> float:
        """The largest ``|r_i(q)|`` (0 without rows)."""
        r = self.residual(q)
        return float(np.abs(r).max()) if r.size else 0.0


def _tendon_terms(model: mujoco.MjModel, tendon: int) -> dict[int, float] | None:
    """``{joint: coef}`` of a fixed tendon, ``None`` for a spatial one."""
    adr, num = int(model.tendon_adr[tendon]), int(model.tendon_num[tendon])
    terms: dict[int, float] = {}
    for w in range(adr, adr + num):
        if int(model.wrap_type[w]) != int(mujoco.mjtWrap.mjWRAP_JOINT):
            return None
        j = int(model.wrap_objid[w])
        if int(model.jnt_type[j]) not in _SCALAR:
            return None
        terms[j] = terms.get(j, 0.0) + float(model.wrap_prm[w])
    return terms


def model_couplings(model: mujoco.MjModel) -> Couplings | None:
    """The active joint and fixed-tendon equalities of ``model`` as :class:`Couplings`, or
    ``None`` when it states none (whatever else it states: see
    :attr:`Couplings.skipped`, which a ``None`` answer does not carry)."""
    rows: list[tuple[str, dict[int, float], dict[int, float], float, float, np.ndarray]] = []
    skipped: list[str] = []
    check_model_type("model", model)
    joint_eq, tendon_eq = int(mujoco.mjtEq.mjEQ_JOINT), int(mujoco.mjtEq.mjEQ_TENDON)
    for e in range(model.neq):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_EQUALITY, e) or f"equality #{e}"
        kind = int(model.eq_type[e])
        if not model.eq_active0[e]:
            skipped.append(f"{name} (inactive)")
            continue
        id1, id2 = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])
        poly = np.array(model.eq_data[e, :5], dtype=float)
        if kind == joint_eq:
            a1 = {id1: 1.0}
            a2 = {id2: 1.0} if id2 >= 0 else {}
            ref1 = float(model.qpos0[model.jnt_qposadr[id1]])
            ref2 = float(model.qpos0[model.jnt_qposadr[id2]]) if id2 >= 0 else 0.0
        elif kind == tendon_eq:
            t1 = _tendon_terms(model, id1)
            t2 = _tendon_terms(model, id2) if id2 >= 0 else {}
            if t1 is None or t2 is None:
                skipped.append(f"{name} (a spatial tendon)")
                continue
            a1, a2 = t1, t2
            ref1 = float(model.tendon_length0[id1])
            ref2 = float(model.tendon_length0[id2]) if id2 >= 0 else 0.0
        else:
            what = mujoco.mjtEq(kind).name[5:].lower()
            skipped.append(f"{name} (a {what} constraint)")
            continue
        rows.append((name, a1, a2, ref1, ref2, poly))
    if not rows:
        return None
    joints = sorted({j for row in rows for j in (*row[1], *row[2])})
    column = {j: k for k, j in enumerate(joints)}
    first = np.zeros((len(rows), len(joints)))
    second = np.zeros((len(rows), len(joints)))
    for i, (_, a1, a2, *_rest) in enumerate(rows):
        for j, coef in a1.items():
            first[i, column[j]] += coef
        for j, coef in a2.items():
            second[i, column[j]] += coef
    return Couplings(
        names=tuple(row[0] for row in rows),
        qadr=np.array([model.jnt_qposadr[j] for j in joints], dtype=np.int64),
        dofs=np.array([model.jnt_dofadr[j] for j in joints], dtype=np.int64),
        first=first,
        second=second,
        reference=np.array([[row[3], row[4]] for row in rows], dtype=float),
        poly=np.array([row[5] for row in rows], dtype=float),
        has_second=np.array([bool(row[2]) for row in rows]),
        nq=model.nq,
        nv=model.nv,
        skipped=tuple(skipped),
    )


#: The equality types :func:`model_couplings` takes as rows (the others are not held).
_HELD = (int(mujoco.mjtEq.mjEQ_JOINT), int(mujoco.mjtEq.mjEQ_TENDON))


def unheld_equalities(model: mujoco.MjModel) -> np.ndarray:
    """Ids of the model's active equalities that :func:`model_couplings` does not take as
    rows (connect and weld constraints, spatial tendons, flex ones): nothing in qpik holds
    them (an empty array for most robots)."""
    ids = []
    for e in range(model.neq):
        if not model.eq_active0[e]:
            continue
        kind = int(model.eq_type[e])
        if kind == _HELD[1]:
            id2 = int(model.eq_obj2id[e])
            spatial = _tendon_terms(model, int(model.eq_obj1id[e])) is None or (
                id2 >= 0 and _tendon_terms(model, id2) is None
            )
            if not spatial:
                continue
        elif kind == _HELD[0]:
            continue
        ids.append(e)
    return np.array(ids, dtype=np.int64)


def _scratch_data(model: mujoco.MjModel) -> mujoco.MjData:
    """The scratch MjData of :func:`unheld_equality_errors` (:func:`.scratch.scratch_data`)."""
    return scratch_data(model, "couplings")


def unheld_equality_errors(
    model: mujoco.MjModel, q: npt.ArrayLike, equalities: npt.ArrayLike
) -> tuple[float, float]:
    """``(position [m], rotation [rad])``: the largest residuals at ``q`` of the
    equalities ``equalities`` (ids, from :func:`unheld_equalities`), MuJoCo's ``efc_pos``
    (a weld's rotation rows, ``torquescale * sin(angle / 2) * axis``, as the angle
    ``2 |row| / torquescale``; every other row is a length)."""
    equalities = np.asarray(equalities, dtype=np.int64)
    if equalities.size == 0:
        return 0.0, 0.0
    data = _scratch_data(model)
    mujoco.mj_resetData(model, data)
    data.qpos[:] = q
    mujoco.mj_fwdPosition(model, data)
    n = data.nefc
    wanted = set(equalities.tolist())
    equality = int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)
    kinds, ids = data.efc_type[:n].tolist(), data.efc_id[:n].tolist()
    rows = [r for r in range(n) if kinds[r] == equality and ids[r] in wanted]
    position = rotation = 0.0
    weld = int(mujoco.mjtEq.mjEQ_WELD)
    seen: dict[int, int] = {}
    for row in rows:
        e = int(data.efc_id[row])
        k = seen[e] = seen.get(e, -1) + 1  # the row's index within its equality
        value = abs(float(data.efc_pos[row]))
        if int(model.eq_type[e]) == weld and k >= 3:
            scale = float(model.eq_data[e, 10]) or 1.0  # torquescale
            rotation = max(rotation, 2.0 * value / abs(scale))
        else:
            position = max(position, value)
    return position, rotation


def _loop_joints(model: mujoco.MjModel, equalities: npt.ArrayLike) -> list[int]:
    """The joints (sorted ids) of :func:`equality_dofs`."""
    kinds = {int(mujoco.mjtEq.mjEQ_CONNECT), int(mujoco.mjtEq.mjEQ_WELD)}
    site = int(mujoco.mjtObj.mjOBJ_SITE)
    loop: set[int] = set()
    for e in np.asarray(equalities, dtype=np.int64).tolist():
        if int(model.eq_type[e]) not in kinds:
            continue
        bodies = []
        for obj in (int(model.eq_obj1id[e]), int(model.eq_obj2id[e])):
            if int(model.eq_objtype[e]) == site and obj >= 0:
                obj = int(model.site_bodyid[obj])
            bodies.append(max(obj, 0))
        loop |= body_chain_joints(model, bodies[0]) ^ body_chain_joints(model, bodies[1])
    return sorted(loop)


def equality_dofs(model: mujoco.MjModel, equalities: npt.ArrayLike) -> np.ndarray:
    """The dofs (sorted ids) that close the loops of the connect and weld equalities among
    ``equalities`` (ids): those of the joints that move one of an equality's two bodies (or
    sites' bodies) and not the other. The dofs on both chains carry the loop rigidly. Other
    kinds of equality add none."""
    return np.flatnonzero(np.isin(model.dof_jntid, _loop_joints(model, equalities)))


def closed_chain_start(
    model: mujoco.MjModel,
    q: npt.ArrayLike,
    lower: np.ndarray,
    upper: np.ndarray,
    unheld: np.ndarray | None = None,
) -> np.ndarray:
    """``q`` (a start, ``(nq,)``) with the closed chains that the model's unheld equalities
    close (a gripper's four-bar linkage: connect or weld constraints, which no level holds,
    :func:`unheld_equalities`; ``unheld``: their ids where the caller has them) set back to
    ``qpos0``, where that breaks them less.

    The joints reset are those that close the loops (the joints of :func:`equality_dofs`), their
    ``qpos0`` clipped to ``[lower, upper]`` (``(nq,)`` [rad or m]). Mid-range values of a
    linkage's joints, taken one joint at a time, break its closure (by 28 mm on the Robotiq
    2F-85), and a full-IK solve that does not move them cannot converge (reason
    ``constraint``). Returns ``q`` itself (a copy) where the model has no unheld equality or
    ``qpos0`` does not meet them better."""
    q = np.array(q, dtype=np.float64)
    if unheld is None:
        unheld = unheld_equalities(model)
    joints = _loop_joints(model, unheld) if unheld.size else []
    if not joints:
        return q
    candidate = q.copy()
    for joint in joints:
        start = int(model.jnt_qposadr[joint])
        stop = start + QPOS_WIDTH[int(model.jnt_type[joint])]
        candidate[start:stop] = model.qpos0[start:stop]
        if stop - start == 1:
            candidate[start] = min(max(candidate[start], lower[start]), upper[start])
    if max(unheld_equality_errors(model, candidate, unheld)) < max(
        unheld_equality_errors(model, q, unheld)
    ):
        return candidate
    return q


def default_start(
    model: mujoco.MjModel, lower: np.ndarray, upper: np.ndarray, unheld: np.ndarray | None = None
) -> np.ndarray:
    """Full IK's default start ``(nq,)``: ``qpos0`` with every joint limited on both sides
    (``lower``, ``upper``: ``(nq,)`` [rad or m]) at mid-range, then the closed chains of the
    unheld equalities at ``qpos0`` where that meets them better (:func:`closed_chain_start`;
    ``unheld``: their ids where the caller has them)."""
    q = model.qpos0.copy()
    limited = np.isfinite(lower) & np.isfinite(upper)
    q[limited] = 0.5 * (lower[limited] + upper[limited])
    return closed_chain_start(model, q, lower, upper, unheld)
