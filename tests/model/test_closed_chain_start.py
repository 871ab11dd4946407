"""The default start of full IK on a model with a closed linkage (a gripper's four-bar:
connect constraints, which no level holds). Mid-range values of the linkage's joints,
taken one joint at a time, break its closure, and a solve that does not move them could
never converge (every target ended with reason ``constraint``, as on Menagerie's Stanford
TidyBot with its Robotiq 2F-85). References: MuJoCo's own constraint residuals and
Jacobian rows (``efc_pos``, ``efc_J``) and forward kinematics on the returned ``q``."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import qpik
from qpik.model.couplings import (
    closed_chain_start,
    equality_dofs,
    unheld_equalities,
    unheld_equality_errors,
)

#: A planar two-link arm (tool site on link2) carrying a parallelogram linkage: two cranks
#: joined by a coupler, closed by a connect constraint (met at qpos0 = 0). The cranks'
#: ranges differ, so their mid-range values (0.25, 0.5) open the loop.
LINKAGE = """<mujoco><compiler angle="radian"/><worldbody>
  <body name="link1"><joint name="j1" axis="0 0 1" range="-2 2"/>
    <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/>
    <body name="link2" pos="0.3 0 0"><joint name="j2" axis="0 0 1" range="-2 2"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/>
      <site name="tool" pos="0.3 0 0"/>
      <body name="crank_a" pos="0.1 0 0"><joint name="ja" axis="0 0 1" range="-1 1.5"/>
        <geom type="capsule" fromto="0 0 0 0 0.1 0" size="0.01"/>
        <body name="coupler" pos="0 0.1 0"><joint name="jc" axis="0 0 1" range="-1.5 1"/>
          <geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.01"/></body></body>
      <body name="crank_b" pos="0.2 0 0"><joint name="jb" axis="0 0 1" range="-0.5 1.5"/>
        <geom type="capsule" fromto="0 0 0 0 0.1 0" size="0.01"/></body>
    </body></body>
</worldbody><equality><connect body1="coupler" body2="crank_b" anchor="0.1 0 0"/></equality>
</mujoco>"""


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(LINKAGE)


def _plain_mid(model: mujoco.MjModel) -> np.ndarray:
    lo, hi = model.jnt_range[:, 0], model.jnt_range[:, 1]
    return 0.5 * (lo + hi)


def test_equality_dofs_are_the_linkage_s(model) -> None:
    """The dofs that close the loop: the cranks' and the coupler's, not the arm's, whose
    motion carries the whole loop rigidly. MuJoCo's efc_J at a closed loop agrees: its
    row's nonzero columns are these dofs."""
    unheld = unheld_equalities(model)
    assert unheld.tolist() == [0]
    dofs = equality_dofs(model, unheld)
    names = sorted(model.joint(int(model.dof_jntid[d])).name for d in dofs)
    assert names == ["ja", "jb", "jc"]
    data = mujoco.MjData(model)
    data.qpos[:] = [0.4, -0.7, 0.3, -0.3, 0.3]  # a parallelogram: closed
    mujoco.mj_fwdPosition(model, data)
    rows = np.flatnonzero(data.efc_type[: data.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
    assert rows.size == 3 and np.abs(data.efc_pos[rows]).max() <= 1e-12
    jac = data.efc_J[: data.nefc * model.nv].reshape(data.nefc, model.nv)[rows]
    np.testing.assert_array_equal(np.flatnonzero(np.abs(jac).max(axis=0) > 1e-12), dofs)


def test_mid_q_keeps_the_loop_closed(model) -> None:
    """Configuration.mid_q and IKSession.mid_q: the arm at mid-range, the linkage at
    qpos0, where MuJoCo's residual of the loop is zero (it is 0.1 m at the plain mid)."""
    plain = _plain_mid(model)
    unheld = unheld_equalities(model)
    assert max(unheld_equality_errors(model, plain, unheld)) > 1e-2
    expected = plain.copy()
    expected[2:] = 0.0
    for q in (qpik.Configuration(model).mid_q(), qpik.IKSession(model).mid_q()):
        np.testing.assert_array_equal(q, expected)
        assert max(unheld_equality_errors(model, q, unheld)) <= 1e-12


def test_default_start_converges_on_a_model_with_a_closed_linkage(model) -> None:
    """qpik.solve without q0 meets a pose of the tool and claims convergence: the
    linkage keeps its closed qpos0 values (before: reason "constraint" on every target)."""
    rng = np.random.default_rng(0)
    data = mujoco.MjData(model)
    for _ in range(10):
        q = np.zeros(model.nq)
        q[:2] = rng.uniform(-1.5, 1.5, 2)
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        target = (data.site("tool").xpos.copy(), data.site("tool").xmat.reshape(3, 3).copy())
        result = qpik.solve(model, {"tool": target}, seed=0)
        assert result.converged, result.reason
        assert result.constraint_error <= 1e-9
        data.qpos[:] = result.q
        mujoco.mj_kinematics(model, data)
        assert np.linalg.norm(data.site("tool").xpos - target[0]) <= 1e-4
        np.testing.assert_array_equal(result.q[2:], 0.0)


def test_a_start_that_opens_the_loop_is_still_reported(model) -> None:
    """An explicit q0 is the user's: a q0 with the loop opened keeps it open (the solve
    does not move joints off the tool's chain), and the result says so."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    target = (data.site("tool").xpos.copy(), data.site("tool").xmat.reshape(3, 3).copy())
    result = qpik.solve(model, {"tool": target}, q0=_plain_mid(model), seed=0)
    assert not result.converged and result.reason == "constraint"
    assert result.constraint_error > 1e-2


def test_models_without_unheld_equalities_keep_the_plain_mid_range() -> None:
    """A model whose qpos0 does not meet its loop better, and one with none: q unchanged."""
    model = mujoco.MjModel.from_xml_string(LINKAGE)
    plain = _plain_mid(model)
    lower, upper = model.jnt_range[:, 0], model.jnt_range[:, 1]
    # qpos0 outside a range that the clip then moves: no better, so q is kept
    clipped = closed_chain_start(model, plain, lower, np.minimum(upper, -0.2))
    np.testing.assert_array_equal(clipped, plain)
    panda = qpik.load_robot("panda")
    c = qpik.Configuration(panda)
    lo, hi = c.lower, c.upper
    limited = np.isfinite(lo) & np.isfinite(hi)
    expected = panda.qpos0.copy()
    expected[limited] = 0.5 * (lo[limited] + hi[limited])
    np.testing.assert_array_equal(c.mid_q(), expected)
