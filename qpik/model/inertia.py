"""The joint-space inertia matrix ``M(q)`` by the compiled engine (``qpik/_cpp/model/
inertia.hpp``): the composite rigid body algorithm with MuJoCo's ``mj_crb`` operations in
its order, from an MjData's ``cinert`` and ``cdof`` (``mj_comPos``, which
:meth:`qpik.Configuration.update` and :meth:`mink.Configuration.update` run). Bitwise the
matrix of ``mj_makeM`` then ``mj_fullM`` (tested on the shipped robots and mink's example
models), on models whose armature is the dofs' own: where an actuator or a tendon adds
armature (``actuator_armature``, ``tendon_armature``), :func:`inertia_tree` is None and
MuJoCo's own functions serve.

The kinetic-energy task (:class:`qpik.tasks.KineticEnergyRegularizationTask`, and mink's)
takes its rows from here on both of the step's paths, the compiled step and the QP path
(:func:`qpik.diffik.rows.task_rows`), so the two agree bit for bit.
"""

from __future__ import annotations

import mujoco
import numpy as np

from .._engine import model as _model

__all__ = ["inertia_matrix", "inertia_tree"]


def inertia_tree(model: mujoco.MjModel) -> tuple[np.ndarray, ...] | None:
    """``(body_parent, dof_body, dof_parent, armature, fixed)``: the model's tree as the
    engine makes ``M(q)`` on it (int64 ``(nbody,)``, ``(nv,)``, ``(nv,)``; float ``(nv,)``
    armature, and ``fixed`` (nv,): a simple dof's constant diagonal ``dof_M0``, NaN for
    the others); None where an actuator or a tendon adds armature to ``M``."""
    for name in ("actuator_armature", "tendon_armature"):
        extra = getattr(model, name, None)
        if extra is not None and np.any(np.asarray(extra) != 0.0):
            return None
    i64 = np.int64
    fixed = np.where(model.dof_simplenum > 0, model.dof_M0, np.nan)
    return (
        model.body_parentid.astype(i64),
        model.dof_bodyid.astype(i64),
        model.dof_parentid.astype(i64),
        np.array(model.dof_armature, dtype=float),
        np.ascontiguousarray(fixed, dtype=float),
    )


def inertia_matrix(data: mujoco.MjData, tree: tuple[np.ndarray, ...]) -> np.ndarray:
    """``M(q)`` (nv, nv) [kg m^2 for hinges, kg for slides] of ``data`` (its ``cinert`` and
    ``cdof``, as ``mj_comPos`` left them) on ``tree`` (:func:`inertia_tree`)."""
    return _model.inertia_matrix(data.cinert, data.cdof, *tree)
