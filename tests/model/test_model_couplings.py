"""Issue 22 items 2-4: the model's couplings hold by default (full IK on both engines,
IKSolver steps), the compiled full IK takes models with joints of any type off the
target's chain, full IK keeps level 0 when a lower level is out of reach, and ball-joint
ranges hold in differential IK. References: MuJoCo's own constraint rows (efc_pos,
efc_J), forward kinematics (mj_kinematics) on the returned q, and the other engine."""

from __future__ import annotations

import pathlib

import mujoco
import numpy as np
import pytest
from conftest import three_link_arm

import qpik
from qpik.errors import RobotFileError
from qpik.limits import joint_limits
from qpik.model import KinematicChain, model_couplings
from qpik.tasks import ComTask, CouplingTask, FrameTask, PositionTask, PostureTask

DATA = pathlib.Path(__file__).parents[1] / "data" / "menagerie"
ROBOTS = pathlib.Path(__file__).parents[2] / "robots"

_INERTIA = '<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'  # noqa: E501
MIMIC_URDF = f"""<robot name="mimic">
  <link name="base"/>
  <link name="l1">{_INERTIA}</link>
  <link name="l2">{_INERTIA}</link>
  <link name="l3">{_INERTIA}</link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/>
    <mimic joint="j2" multiplier="0.5" offset="0.1"/></joint>
</robot>"""

#: A joint coupling with a cubic polynomial, one without a second joint, and a fixed
#: tendon equality; a connect constraint, which the couplings do not take.
MJCF = (
    """
<mujoco>
  <worldbody>
"""
    + three_link_arm()
    + """    <body name="d" pos="0 1 0">
      <joint name="d1" axis="0 0 1" range="-1 1"/>
      <joint name="d2" axis="0 1 0" range="-1 1"/>
      <geom type="sphere" size="0.05"/>
    </body>
  </worldbody>
  <tendon>
    <fixed name="t1"><joint joint="a1" coef="0.5"/><joint joint="d1" coef="-1"/></fixed>
    <fixed name="t2"><joint joint="d2" coef="2"/></fixed>
  </tendon>
  <equality>
    <joint name="poly" joint1="c1" joint2="b1" polycoef="0.05 0.5 0.2 -0.1 0.03"/>
    <joint name="pin" joint1="c2" polycoef="0.02 0 0 0 0"/>
    <tendon name="ten" tendon1="t1" tendon2="t2" polycoef="0 0.7 0.1 0 0"/>
    <connect name="loop" body1="d" body2="a" anchor="0 0 0"/>
  </equality>
</mujoco>
"""
)


def _mimic(tmp_path: pathlib.Path) -> mujoco.MjModel:
    path = tmp_path / "mimic.urdf"
    path.write_text(MIMIC_URDF)
    return mujoco.MjModel.from_xml_path(str(path))


def _fk_body(model: mujoco.MjModel, q: np.ndarray, body: str) -> np.ndarray:
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    return data.body(body).xpos.copy()


# ---------------------------------------------------------------- the coupling rows
def test_coupling_rows_are_mujocos_own(tmp_path):
    """Residuals and Jacobians of a URDF mimic, a polynomial joint coupling, a pinned
    joint and a fixed-tendon coupling equal MuJoCo's efc_pos / efc_J (to round-off), and
    the Jacobian matches central finite differences of the residual."""
    rng = np.random.default_rng(0)
    mimic = _mimic(tmp_path)
    model = mujoco.MjModel.from_xml_string(MJCF)
    couplings = model_couplings(model)
    assert couplings is not None
    assert couplings.names == ("poly", "pin", "ten")
    assert couplings.skipped == ("loop (a connect constraint)",)
    for m in (mimic, model):
        c = model_couplings(m)
        assert c is not None
        for _ in range(5):
            q = rng.uniform(-0.9, 0.9, m.nq)
            pos, jac = _efc_rows(m, q)  # the couplings are the first equalities
            pos, jac = pos[: len(c)], jac[: len(c)]
            np.testing.assert_allclose(c.residual(q), pos, rtol=0, atol=1e-12)
            np.testing.assert_allclose(c.jacobian(q), jac, rtol=0, atol=1e-12)
            h = 1e-6
            fd = np.column_stack(
                [(c.residual(q + h * e) - c.residual(q - h * e)) / (2 * h) for e in np.eye(m.nq)]
            )
            np.testing.assert_allclose(c.jacobian(q), fd, rtol=0, atol=1e-8)
    with pytest.raises(qpik.InvalidConfiguration):
        couplings.residual(np.zeros(2))
    with pytest.raises(qpik.TaskDefinitionError):
        CouplingTask(mujoco.MjModel.from_xml_path(str(ROBOTS / "panda.xml")))


def _efc_rows(model: mujoco.MjModel, q: np.ndarray):
    """MuJoCo's rows of every equality of ``model`` (unnamed) at ``q``."""
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    rows = np.flatnonzero(data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
    jac = data.efc_J.reshape(data.nefc, model.nv) if not mujoco.mj_isSparse(model) else None
    if jac is None:
        jac = np.zeros((data.nefc, model.nv))
        mujoco.mju_sparse2dense(
            jac, data.efc_J, data.efc_J_rownnz, data.efc_J_rowadr, data.efc_J_colind
        )
    return data.efc_pos[rows].copy(), jac[rows].copy()


# ------------------------------------------------------------------------- full IK
@pytest.mark.parametrize("engine", ["auto", "qp"])
def test_full_ik_keeps_a_urdf_mimic(tmp_path, engine):
    """Reachable targets of the mimic arm (drawn on the coupled manifold): every solve
    converges with the coupling held (checked on q itself) and the body where forward
    kinematics puts it; with couplings=False the solver breaks it (what issue 22
    measured: up to 0.97 rad)."""
    model = _mimic(tmp_path)
    rng = np.random.default_rng(1)
    broken = 0.0
    for i in range(10):
        q = np.array([rng.uniform(-2, 2), rng.uniform(-1.5, 1.5), 0.0])
        q[2] = 0.1 + 0.5 * q[1]
        target = _fk_body(model, q, "l3")
        result = qpik.solve(model, {("l3", "body"): target}, seed=i, engine=engine)
        assert result.converged
        assert result.engine == "qp"  # the coupling moves a joint of the chain
        assert abs(result.q[2] - (0.1 + 0.5 * result.q[1])) <= 1e-9
        assert result.coupling_error <= 1e-9
        assert np.linalg.norm(_fk_body(model, result.q, "l3") - target) <= 1e-4
        free = qpik.solve(model, {("l3", "body"): target}, seed=i, engine=engine, couplings=False)
        broken = max(broken, abs(free.q[2] - (0.1 + 0.5 * free.q[1])))
    assert broken > 0.1
    with pytest.raises(qpik.InvalidInput, match="coupling"):
        qpik.solve(model, {("l3", "body"): target}, engine="compiled")


def test_xarm7_gripper_coupling_holds_in_full_ik():
    """Menagerie's xarm7: the gripper's driver joints are coupled (a joint equality), off
    the TCP's chain. The compiled engine takes the solve and keeps them where they are
    (restarts included); a start that breaks the coupling goes to the "qp" engine, which
    restores it."""
    model = qpik.load_robot(str(DATA / "xarm7.xml"))
    couplings = model_couplings(model)
    assert couplings is not None and len(couplings) == 1
    home = model.key_qpos[0].copy()
    configuration = qpik.Configuration(model, home)
    p, rotation = configuration.frame_pose("link_tcp", "site")
    target = (p + np.array([0.05, 0.1, -0.05]), rotation)
    result = qpik.solve(model, {"link_tcp": target}, q0=home, seed=0)
    assert result.converged and result.engine == "compiled"
    np.testing.assert_array_equal(result.q[7:], home[7:])  # off the chain: untouched
    assert result.coupling_error == 0.0
    broken = home.copy()
    left, right = (model.joint(n).qposadr[0] for n in ("left_driver_joint", "right_driver_joint"))
    broken[left], broken[right] = 0.6, 0.2
    result = qpik.solve(model, {"link_tcp": target}, q0=broken, seed=0)
    assert result.engine == "qp"
    # that start also opens the fingers' connect loop closures, which qpik does not hold:
    # target and coupling met, yet no convergence is claimed at a q that breaks the model
    assert not result.converged and result.reason == "constraint"
    assert result.constraint_error > 1e-3 and result.position_error <= 1e-4
    assert abs(result.q[left] - result.q[right]) <= 1e-9
    assert result.coupling_error <= 1e-9
    data = mujoco.MjData(model)
    data.qpos[:] = result.q
    mujoco.mj_kinematics(model, data)
    assert np.linalg.norm(data.site("link_tcp").xpos - target[0]) <= 1e-4


# --------------------------------------------------------------- differential IK
def test_iksolver_holds_the_coupling_above_the_stack(tmp_path):
    """IKSolver steps: a posture task pulling the mimic joint away from its leader leaves
    the coupling held (a linear coupling: exactly after the first step, the start's
    violation removed); the step reports the stack's levels only. couplings=False: the
    posture wins and the coupling breaks."""
    model = _mimic(tmp_path)
    posture = PostureTask(model, cost=1.0)
    posture.set_target(np.array([0.0, 0.4, -1.0]))  # j3 asked far from 0.1 + 0.5 j2
    for couplings in (True, False):
        configuration = qpik.Configuration(model, np.array([0.0, 0.2, 0.5]))  # broken
        solver = qpik.IKSolver(model, [[posture]], joint_limits(model), couplings=couplings)
        for _ in range(100):
            result = solver.step(configuration, 0.01)
            configuration.integrate_inplace(result.velocity, 0.01)
        q = configuration.q
        error = abs(q[2] - (0.1 + 0.5 * q[1]))
        assert len(result.residuals) == len(result.status) == 1
        if couplings:
            assert error <= 1e-9
            assert result.coupling_residual is not None and result.coupling_residual <= 1e-9
            problem = solver.build(configuration, 0.01)
            assert [level.name for level in problem.levels] == ["couplings", "level 0"]
        else:
            assert error > 0.5 and result.coupling_residual is None
    with pytest.raises(qpik.InvalidOption):
        qpik.StepOptions(couplings=1)


# ------------------------------------------------------- free joints off the chain
def _panda_with_cube() -> mujoco.MjModel:
    spec = mujoco.MjSpec.from_file(str(ROBOTS / "panda.xml"))
    cube = spec.worldbody.add_body(name="cube", pos=[0.5, 0.2, 0.03])
    cube.add_freejoint(name="cube_free")
    cube.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.02] * 3, mass=0.1)
    return spec.compile()


def test_compiled_full_ik_ignores_a_free_cube_off_the_chain():
    """The Panda with a free cube (Menagerie's mjx_single_cube layout): the compiled
    engine takes the solve (issue 22: the "qp" engine at 5.4 ms before), moves only the
    arm, and agrees with the "qp" engine and forward kinematics; the cube stays put, also
    across restarts."""
    model = _panda_with_cube()
    assert model.nq == 14 and model.nv == 13
    bare = qpik.load_robot("panda")
    start = bare.key_qpos[0] if bare.nkey else qpik.Configuration(bare).mid_q()
    q0 = np.concatenate([start, [0.5, 0.2, 0.03, 0.6, 0.0, 0.8, 0.0]])
    p, rotation = qpik.Configuration(model, q0).frame_pose("ee")
    target = (p + np.array([0.05, -0.1, 0.05]), rotation)
    compiled = qpik.solve(model, {"ee": target}, q0=q0, restarts=0, seed=0)
    general = qpik.solve(model, {"ee": target}, q0=q0, restarts=0, seed=0, engine="qp")
    assert compiled.engine == "compiled" and general.engine == "qp"
    assert compiled.converged and general.converged
    assert np.abs(compiled.q - general.q).max() <= 1e-9
    np.testing.assert_array_equal(compiled.q[7:], q0[7:])
    assert compiled.path.shape[1] == model.nq
    np.testing.assert_array_equal(
        compiled.path[:, 7:], np.broadcast_to(q0[7:], (len(compiled.path), 7))
    )  # noqa: E501
    data = mujoco.MjData(model)
    data.qpos[:] = compiled.q
    mujoco.mj_kinematics(model, data)
    assert np.linalg.norm(data.site("ee").xpos - target[0]) <= 1e-4
    # the same answer as on the bare arm, bitwise: the chain is the same
    alone = qpik.solve(bare, {"ee": target}, q0=start, restarts=0, seed=0)
    np.testing.assert_array_equal(alone.q, compiled.q[:7])
    # an unreachable pose: restarts draw the arm's joints only
    far = qpik.solve(model, {"ee": (p + np.array([0.0, 0.0, 0.5]), rotation)}, q0=q0,
                     restarts=3, seed=1, max_iters=20)  # fmt: skip
    assert far.engine == "compiled" and far.restarts_used == 3
    np.testing.assert_array_equal(far.q[7:], q0[7:])


def test_a_ball_joint_on_the_chain_still_goes_to_the_qp_engine():
    model = mujoco.MjModel.from_xml_string(BALL_ARM)
    with pytest.raises(ValueError, match="ball"):
        KinematicChain.from_model(model, "tip")
    chain = KinematicChain.from_model(model, "other")  # the ball joint is off its chain
    assert chain.covers_q is False and chain.packed().nq == 1
    result = qpik.solve(model, {"tip": np.array([0.1, 0.0, 0.45])}, seed=0)
    assert result.engine == "qp"
    with pytest.raises(qpik.InvalidInput, match="compiled"):
        qpik.solve(model, {"tip": np.array([0.1, 0.0, 0.45])}, engine="compiled")
    other = qpik.solve(model, {"other": np.array([0.7, 0.3, 0.0])}, seed=0)
    assert other.engine == "compiled"


BALL_ARM = """
<mujoco>
  <worldbody>
    <body name="base">
      <joint name="neck" type="ball" range="0 60" limited="true"/>
      <geom type="capsule" fromto="0 0 0 0 0 0.5" size="0.05" mass="1"/>
      <site name="tip" pos="0 0 0.5"/>
    </body>
    <body name="arm" pos="0.5 0 0">
      <joint name="swing" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
      <site name="other" pos="0.3 0 0"/>
    </body>
  </worldbody>
</mujoco>
"""


# ------------------------------------------------ level 0 kept when lower levels fail
def test_full_ik_keeps_level_0_with_a_hand_out_of_reach():
    """G1, floating: feet (and CoM) in level 0, a hand 2 m away in level 1, posture in
    level 2. The solve does not converge (the hand) but returns the feet where they were
    to tol_position, by forward kinematics on the returned q (issue 22: 34-44 mm off;
    0.9-1.4 mm on this trimmed model before), and says which levels met tolerance."""
    model = qpik.load_robot(str(DATA / "g1.xml"))
    home = model.key_qpos[0].copy()
    configuration = qpik.Configuration(model, home)
    feet = [
        FrameTask(f, "site", position_cost=1.0, orientation_cost=1.0)
        for f in ("left_foot", "right_foot")
    ]
    for task in feet:
        task.set_target_from_configuration(configuration)
    com = ComTask(cost=1.0)
    com.set_target_from_configuration(configuration)
    hand = PositionTask("left_palm", "site")
    posture = PostureTask(model, cost=0.1)
    posture.set_target_from_configuration(configuration)
    far = configuration.frame_pose("left_palm", "site")[0] + np.array([2.0, 0.5, 0.5])
    result = qpik.solve(
        model, {"left_palm": far}, q0=home, stack=[[*feet, com], [hand], [posture]],
        seed=0, restarts=3,
    )  # fmt: skip
    assert not result.converged
    assert result.levels_met[:2] == (True, False)
    data = mujoco.MjData(model)
    for q in (home, result.q):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        if q is home:
            before = {
                f: (data.site(f).xpos.copy(), data.site(f).xmat.copy())
                for f in ("left_foot", "right_foot")
            }  # noqa: E501
    for f, (position, xmat) in before.items():
        assert np.linalg.norm(data.site(f).xpos - position) <= 1e-4
        rotation = xmat.reshape(3, 3).T @ data.site(f).xmat.reshape(3, 3)
        assert np.arccos(np.clip((np.trace(rotation) - 1) / 2, -1, 1)) <= 1e-3
    # and the hand got as close as the legs and arm allow (not left at the start)
    start = np.linalg.norm(configuration.frame_pose("left_palm", "site")[0] - far)
    assert result.frame_errors["left_palm"][0] < start - 0.3


@pytest.mark.parametrize("dt", [0.01, 0.05, 0.2])
def test_ball_joint_range_holds_with_the_trust_region(dt):
    """A 60 degree ball range holds under a posture task 2.5 rad away, for steps up to
    0.2 s (the default trust region, on a model without velocity limits)."""
    from conftest import BALL

    model = mujoco.MjModel.from_xml_string(BALL)
    bound = float(model.jnt_range[0, 1])
    configuration = qpik.Configuration(model)
    posture = PostureTask(model, cost=1.0)
    target = np.zeros(4)
    mujoco.mju_axisAngle2Quat(target, np.array([1.0, 0.0, 0.0]), 2.5)
    posture.set_target(target)
    solver = qpik.IKSolver(model, [posture], joint_limits(model))
    worst = 0.0
    for _ in range(200):
        result = solver.step(configuration, dt)
        configuration.integrate_inplace(result.velocity, dt)
        quat = configuration.q[:4]
        worst = max(worst, 2 * float(np.arctan2(np.linalg.norm(quat[1:]), abs(quat[0]))))
    assert bound - 0.01 < worst <= bound + 1e-9


def test_fixed_arm_keeps_level_0_when_level_1_is_out_of_reach():
    """The Panda: the flange's position in level 0 (reachable), link 4's in level 1 two
    metres away (provably out of reach). The answer holds the flange on its target by
    forward kinematics and reports level 0 met, level 1 not."""
    model = qpik.load_robot("panda")
    home = model.key_qpos[0] if model.nkey else qpik.Configuration(model).mid_q()
    configuration = qpik.Configuration(model, home)
    goal = configuration.frame_pose("ee")[0] + np.array([0.1, 0.1, -0.1])
    far = configuration.frame_pose("link4", "body")[0] + np.array([2.0, 0.0, 0.0])
    tip, elbow = PositionTask("ee"), PositionTask("link4", "body")
    result = qpik.solve(
        model, {"ee": goal, ("link4", "body"): far}, q0=home, stack=[[tip], [elbow]], seed=0,
        restarts=2,
    )  # fmt: skip
    assert not result.converged
    assert result.levels_met == (True, False)
    data = mujoco.MjData(model)
    data.qpos[:] = result.q
    mujoco.mj_kinematics(model, data)
    assert np.linalg.norm(data.site("ee").xpos - goal) <= 1e-4
    # level 1 did move link 4 toward its target (within the room level 0 leaves)
    start = np.linalg.norm(configuration.frame_pose("link4", "body")[0] - far)
    assert np.linalg.norm(data.body("link4").xpos - far) < start


@pytest.mark.parametrize("multiplier", ["1e300", "-2e6", "nan"])
def test_a_coupling_whose_rows_overflow_is_refused_at_load(tmp_path, multiplier):
    """A ``<mimic>`` multiplier of 1e300 made the coupling row ``[-1e300, 1]``: every level
    of a step ended ``kept_previous`` with certificates of inf (benchmarks/fuzz.py --seed
    7304, case robot_gen:319). Such a file is refused with the equality and joints named;
    a gear ratio up to COUPLING_COEF_MAX (1e6) loads."""
    path = tmp_path / "mimic.urdf"
    path.write_text(MIMIC_URDF.replace('multiplier="0.5"', f'multiplier="{multiplier}"'))
    with pytest.raises(RobotFileError, match="j3") as caught:
        qpik.load_robot(path)
    assert "j2" in str(caught.value)
    path.write_text(MIMIC_URDF.replace('multiplier="0.5"', 'multiplier="-1e6"'))
    assert qpik.load_robot(path).neq == 1
