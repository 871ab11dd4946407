"""qpik.statics against independent references: MuJoCo's mj_applyFT, the lecture's per-joint
formula from MuJoCo's joint axes and anchors, MuJoCo's forward dynamics at rest, and a
brute-force scan for the payload limit."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from conftest import configuration_of, has_erd

import qpik
from qpik import statics
from qpik.errors import InvalidInput, QpikError, UnknownFrame, UnknownFrameType

ARMS = ["ur5e", "panda"]


def _point_and_body(configuration: qpik.Configuration, name: str, kind: str):
    position, _ = configuration.frame_pose(name, kind)
    fid = configuration.frame_id(name, kind)
    model = configuration.model
    body = {"site": model.site_bodyid, "geom": model.geom_bodyid}.get(kind)
    return position, (fid if body is None else int(body[fid]))


def _random_wrench(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    return rng.normal(scale=20.0, size=3), rng.normal(scale=2.0, size=3)


# ------------------------------------------------------------------ joint_torques
def test_joint_torques_equal_mj_applyFT(bundled_robot, rng):
    configuration = configuration_of(bundled_robot)
    model, data = configuration.model, configuration.data
    worst = 0.0
    for _ in range(100):
        configuration.update(configuration.random_q(rng))
        force, torque = _random_wrench(rng)
        point, body = _point_and_body(configuration, "ee", "site")
        expected = np.zeros(model.nv)
        mujoco.mj_applyFT(model, data, force, torque, point, body, expected)
        tau = statics.joint_torques(configuration, "ee", force, torque)
        worst = max(worst, np.abs(tau - expected).max())
    assert worst < 1e-10


@pytest.mark.parametrize("kind", ["body", "geom"])
def test_joint_torques_other_frame_types_equal_mj_applyFT(kind, rng):
    configuration = configuration_of("panda")
    model, data = configuration.model, configuration.data
    name = "hand" if kind == "body" else "link7"
    for _ in range(20):
        configuration.update(configuration.random_q(rng))
        force, torque = _random_wrench(rng)
        point, body = _point_and_body(configuration, name, kind)
        expected = np.zeros(model.nv)
        mujoco.mj_applyFT(model, data, force, torque, point, body, expected)
        tau = statics.joint_torques(configuration, name, force, torque, frame_type=kind)
        np.testing.assert_allclose(tau, expected, atol=1e-10)


def test_joint_torques_local_axes_are_rotated_to_world(bundled_robot, rng):
    configuration = configuration_of(bundled_robot)
    for _ in range(20):
        configuration.update(configuration.random_q(rng))
        force, torque = _random_wrench(rng)
        _, rotation = configuration.frame_pose("ee")
        local = statics.joint_torques(configuration, "ee", force, torque, expressed_in="local")
        world = statics.joint_torques(configuration, "ee", rotation @ force, rotation @ torque)
        np.testing.assert_allclose(local, world, atol=1e-10)


def test_joint_torques_equal_lecture_per_joint_formula(bundled_robot, rng):
    """tau_i = k_i . (r_i x f) + k_i . t with k_i, r_i from MuJoCo's xaxis and xanchor."""
    configuration = configuration_of(bundled_robot)
    model, data = configuration.model, configuration.data
    _, ee_body = _point_and_body(configuration, "ee", "site")
    ancestors = {ee_body}
    while ee_body:
        ee_body = int(model.body_parentid[ee_body])
        ancestors.add(ee_body)
    hinges = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    assert hinges
    for _ in range(50):
        configuration.update(configuration.random_q(rng))
        force, torque = _random_wrench(rng)
        p_e, _ = configuration.frame_pose("ee")
        tau = statics.joint_torques(configuration, "ee", force, torque)
        for j in hinges:
            k, r = data.xaxis[j], p_e - data.xanchor[j]
            expected = k @ np.cross(r, force) + k @ torque
            if model.jnt_bodyid[j] not in ancestors:
                expected = 0.0
            assert tau[model.jnt_dofadr[j]] == pytest.approx(expected, abs=1e-10)


def test_power_balance(bundled_robot, rng):
    """(J qdot) . w = qdot . (J^T w): the wrench delivers the power the joints receive."""
    configuration = configuration_of(bundled_robot)
    for _ in range(20):
        configuration.update(configuration.random_q(rng))
        qdot = rng.normal(size=configuration.model.nv)
        force, torque = _random_wrench(rng)
        twist = configuration.frame_jacobian("ee") @ qdot
        tau = statics.joint_torques(configuration, "ee", force, torque)
        assert twist @ np.concatenate([force, torque]) == pytest.approx(qdot @ tau, abs=1e-9)


# ----------------------------------------------------------- gravity and holding
def test_gravity_torques_equal_sum_of_weights_and_leave_data_unchanged(bundled_robot, rng):
    """Gravity produces sum_b J_com,b^T (m_b g); the configuration's data is not touched."""
    configuration = configuration_of(bundled_robot)
    model, data = configuration.model, configuration.data
    for _ in range(10):
        configuration.update(configuration.random_q(rng))
        data.qvel[:] = rng.normal(size=model.nv)  # the caller's velocity must not matter
        before = {k: getattr(data, k).copy() for k in ("qpos", "qvel", "qfrc_bias", "xpos")}
        expected = np.zeros(model.nv)
        jacp = np.zeros((3, model.nv))
        for b in range(1, model.nbody):
            mujoco.mj_jacBodyCom(model, data, jacp, None, b)
            expected += jacp.T @ (model.body_mass[b] * model.opt.gravity)
        np.testing.assert_allclose(statics.gravity_torques(configuration), expected, atol=1e-10)
        for key, value in before.items():
            np.testing.assert_array_equal(getattr(data, key), value)


def _rest_acceleration(model, q, wrenches, motor_torques) -> np.ndarray:
    """qacc from MuJoCo at q, zero velocity, wrenches in xfrc_applied (at each body's centre
    of mass) and motor torques in qfrc_applied."""
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    for point, body, force, torque in wrenches:
        data.xfrc_applied[body, :3] += force
        data.xfrc_applied[body, 3:] += torque + np.cross(point - data.xipos[body], force)
    data.qfrc_applied[:] = motor_torques
    mujoco.mj_forward(model, data)
    return data.qacc.copy()


@pytest.mark.parametrize("armature, damping", [(None, None), (0.5, 25.0)])
def test_holding_torques_keep_the_robot_at_rest(bundled_robot, armature, damping, rng):
    model = qpik.load_robot(bundled_robot)
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT  # contacts are not modelled
    if armature is not None:
        model.dof_armature[:] = armature
        model.dof_damping[:] = damping
    configuration = qpik.Configuration(model)
    other_body = int(model.jnt_bodyid[model.njnt // 2])  # a second contact, on a mid link
    other = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, other_body)
    worst, loose = 0.0, np.inf
    for _ in range(20):
        q = configuration.random_q(rng)
        configuration.update(q)
        (f1, t1), (f2, t2) = _random_wrench(rng), _random_wrench(rng)
        wrenches = [("ee", f1, t1), ((other, "body"), f2, t2)]
        holding = statics.holding_torques(configuration, wrenches)
        applied = [
            (*_point_and_body(configuration, "ee", "site"), f1, t1),
            (*_point_and_body(configuration, other, "body"), f2, t2),
        ]
        worst = max(worst, np.abs(_rest_acceleration(model, q, applied, holding)).max())
        # Sensitivity: without the contact term the robot accelerates.
        free = statics.holding_torques(configuration, [])
        loose = min(loose, np.abs(_rest_acceleration(model, q, applied, free)).max())
    assert worst < 1e-8
    assert loose > 1e-3


def test_holding_torques_without_gravity(rng):
    model = qpik.load_robot("ur5e")
    configuration = qpik.Configuration(model, qpik.Configuration(model).random_q(rng))
    force, torque = _random_wrench(rng)
    holding = statics.holding_torques(configuration, [("ee", force, torque)], gravity=False)
    tau = statics.joint_torques(configuration, "ee", force, torque)
    np.testing.assert_allclose(holding, -tau, atol=1e-12)
    gravity = statics.gravity_torques(configuration)
    np.testing.assert_allclose(statics.holding_torques(configuration), -gravity, atol=1e-12)
    model.opt.gravity[:] = 0.0
    applied = [(*_point_and_body(configuration, "ee", "site"), force, torque)]
    assert np.abs(_rest_acceleration(model, configuration.q, applied, holding)).max() < 1e-8


def test_holding_torques_accept_force_only_wrenches(rng):
    configuration = configuration_of("panda", configuration_of("panda").random_q(rng))
    force = np.array([1.0, -2.0, 3.0])
    np.testing.assert_allclose(
        statics.holding_torques(configuration, [("ee", force)]),
        statics.holding_torques(configuration, [(("ee", "site"), force, np.zeros(3))]),
    )


# -------------------------------------------------------------------- estimation
def _well_conditioned_q(configuration, rng, min_sigma=0.05):
    while True:
        q = configuration.random_q(rng)
        configuration.update(q)
        if np.linalg.svd(configuration.frame_jacobian("ee"), compute_uv=False)[-1] > min_sigma:
            return q


@pytest.mark.parametrize("robot", ARMS)
def test_wrench_from_torques_recovers_the_wrench(robot, rng):
    configuration = configuration_of(robot)
    for _ in range(20):
        _well_conditioned_q(configuration, rng)
        force, torque = _random_wrench(rng)
        tau = statics.joint_torques(configuration, "ee", force, torque)
        estimate = statics.wrench_from_torques(configuration, "ee", tau)
        assert estimate.observable and estimate.rank == 6
        assert estimate.unobservable.shape == (0, 6)
        np.testing.assert_allclose(estimate.force, force, atol=1e-8)
        np.testing.assert_allclose(estimate.torque, torque, atol=1e-8)
        assert np.abs(estimate.residual).max() < 1e-9


def test_wrench_from_torques_reports_unexplained_torque(rng):
    """On the 7-DoF arm, a torque outside range(J^T) shows up in the residual."""
    configuration = configuration_of("panda")
    _well_conditioned_q(configuration, rng)
    jacobian = configuration.frame_jacobian("ee")
    null = np.linalg.svd(jacobian)[2][-1]  # J null = 0, so null is orthogonal to range(J^T)
    force, torque = _random_wrench(rng)
    tau = statics.joint_torques(configuration, "ee", force, torque) + 3.0 * null
    estimate = statics.wrench_from_torques(configuration, "ee", tau)
    np.testing.assert_allclose(estimate.wrench, np.concatenate([force, torque]), atol=1e-8)
    np.testing.assert_allclose(estimate.residual, 3.0 * null, atol=1e-9)


def test_wrench_from_torques_at_a_wrist_singularity(rng):
    """UR5e with wrist 2 at zero: wrist 1 and wrist 3 axes are parallel, rank 5."""
    configuration = configuration_of("ur5e", [0.3, -1.2, 1.4, -0.7, 0.0, 0.5])
    data = configuration.data
    assert abs(abs(data.xaxis[3] @ data.xaxis[5]) - 1.0) < 1e-12
    force, torque = _random_wrench(rng)
    wrench = np.concatenate([force, torque])
    tau = statics.joint_torques(configuration, "ee", force, torque)
    estimate = statics.wrench_from_torques(configuration, "ee", tau)
    assert estimate.rank == 5 and not estimate.observable
    (direction,) = estimate.unobservable
    assert np.linalg.norm(direction) == pytest.approx(1.0)
    # The reported direction produces no joint torque: the lecture's formula per joint.
    p_e, _ = configuration.frame_pose("ee")
    for j in range(6):
        k, r = data.xaxis[j], p_e - data.xanchor[j]
        assert k @ np.cross(r, direction[:3]) + k @ direction[3:] == pytest.approx(0, abs=1e-10)
    # Everything else is recovered; the unobservable component is left out.
    observable_part = wrench - (wrench @ direction) * direction
    np.testing.assert_allclose(estimate.wrench, observable_part, atol=1e-8)
    # Away from the singularity every direction is observed again.
    configuration.update([0.3, -1.2, 1.4, -0.7, 0.3, 0.5])
    assert statics.wrench_from_torques(configuration, "ee", tau).rank == 6


def test_wrench_from_torques_radial_force_of_a_stretched_planar_arm():
    """Fewer than 6 DoF: the planar 2R arm senses 2 wrench directions; stretched along x,
    a force along the arm is carried by the structure and cannot be seen."""
    configuration = configuration_of("planar_2r", [0.0, 0.0])
    estimate = statics.wrench_from_torques(configuration, "ee", [0.0, 0.0])
    assert estimate.rank == 2 and estimate.unobservable.shape == (4, 6)
    radial = np.array([1.0, 0, 0, 0, 0, 0])
    assert np.linalg.norm(estimate.unobservable @ radial) == pytest.approx(1.0)
    configuration.update([0.0, 1.0])
    estimate = statics.wrench_from_torques(configuration, "ee", [0.0, 0.0])
    assert np.linalg.norm(estimate.unobservable @ radial) < 0.99


# -------------------------------------------------------------------- ellipsoid
def test_force_ellipsoid_is_dual_of_velocity_ellipsoid(bundled_robot, rng):
    configuration = configuration_of(bundled_robot)
    for rows in [(0, 1, 2), (3, 4, 5), tuple(range(6))]:
        _ = configuration.update(configuration.random_q(rng))
        ellipsoid = statics.force_ellipsoid(configuration, "ee", rows=rows)
        jacobian = configuration.frame_jacobian("ee")[list(rows)]
        axes, lengths = ellipsoid.axes, ellipsoid.lengths
        np.testing.assert_allclose(axes.T @ axes, np.eye(len(rows)), atol=1e-12)
        assert np.all(np.diff(lengths[np.isfinite(lengths)]) >= 0)
        for axis, length in zip(axes.T, lengths, strict=True):
            if np.isfinite(length):  # a force on the boundary needs unit joint torque norm
                assert np.linalg.norm(jacobian.T @ (length * axis)) == pytest.approx(1.0)
            else:  # held by the structure: no joint torque at all
                assert np.linalg.norm(jacobian.T @ axis) < 1e-7
        # Velocity ellipsoid J J^T = A diag(1 / L^2) A^T.
        inverse_sq = np.where(np.isfinite(lengths), 1.0 / lengths**2, 0.0)
        np.testing.assert_allclose(
            axes @ np.diag(inverse_sq) @ axes.T, jacobian @ jacobian.T, atol=1e-9
        )


def test_force_ellipsoid_of_the_planar_arm_matches_closed_form():
    q2 = 0.7
    configuration = configuration_of("planar_2r", [0.2, q2])
    ellipsoid = statics.force_ellipsoid(configuration, "ee")
    # Planar 2R with unit links: singular values s1 s2 = |sin q2| and s1^2 + s2^2 = tr(J J^T).
    lengths = ellipsoid.lengths
    assert np.isinf(lengths[2]) and abs(ellipsoid.axes[2, 2]) == pytest.approx(1.0)
    assert 1.0 / (lengths[0] * lengths[1]) == pytest.approx(abs(np.sin(q2)))
    trace = 1 + (1 + np.cos(q2)) ** 2 + np.sin(q2) ** 2  # |J col 1|^2 + |J col 2|^2
    assert lengths[0] ** -2 + lengths[1] ** -2 == pytest.approx(trace)


# ----------------------------------------------------------------------- payload
def test_joint_torque_limits_from_actuators():
    model = qpik.load_robot("ur5e")
    limits = statics.joint_torque_limits(qpik.Configuration(model))
    np.testing.assert_array_equal(limits[:, 1], [150, 150, 150, 28, 28, 28])
    np.testing.assert_array_equal(limits[:, 0], -limits[:, 1])
    model.actuator_gear[0, 0] = -2.0
    model.actuator_forcelimited[1] = 1
    model.actuator_forcerange[1] = (-10.0, 20.0)
    limits = statics.joint_torque_limits(qpik.Configuration(model))
    np.testing.assert_array_equal(limits[0], [-300, 300])
    np.testing.assert_array_equal(limits[1], [-10, 20])


def _brute_force_payload(configuration, direction, limits, gravity, top, steps=1501):
    """Largest s on a grid of ``steps`` points over [0, top] whose holding torques (MuJoCo,
    per s) are within the limits. The feasible magnitudes form an interval, so the grid is
    scanned in two passes of about sqrt(steps) points: a coarse one, then the cell after its
    last feasible point; returns that s and the grid step."""

    def holds(s):
        tau = statics.holding_torques(configuration, [("ee", s * direction)], gravity=gravity)
        return np.all((limits[:, 0] - 1e-9 <= tau) & (tau <= limits[:, 1] + 1e-9))

    grid = np.linspace(0.0, top, steps)
    stride = max(1, int(np.sqrt(steps)))
    coarse = [i for i in range(0, steps, stride) if holds(grid[i])]
    if not coarse:  # the interval may start inside a coarse cell: scan the whole grid
        fine = [i for i in range(steps) if holds(grid[i])]
        return (grid[fine[-1]] if fine else np.nan), top / (steps - 1)
    last = coarse[-1]
    fine = [i for i in range(last, min(last + stride, steps)) if holds(grid[i])]
    return grid[fine[-1]], top / (steps - 1)


@pytest.mark.parametrize("robot", ARMS)
@pytest.mark.parametrize("gravity", [True, False])
def test_max_payload_matches_brute_force_scan(robot, gravity, rng):
    configuration = configuration_of(robot)
    for _ in range(2):
        configuration.update(configuration.random_q(rng))
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        result = statics.max_payload(configuration, "ee", 5 * direction, gravity=gravity)
        np.testing.assert_allclose(result.direction, direction)
        limits = statics.joint_torque_limits(configuration)
        assert np.isfinite(result.force) and result.force > 0
        scanned, step = _brute_force_payload(
            configuration, direction, limits, gravity, top=1.5 * result.force
        )
        assert result.force - step <= scanned <= result.force + 1e-9
        # At the limit the limiting joint's holding torque is saturated.
        tau = statics.holding_torques(configuration, [("ee", result.force * direction)], gravity)
        names = [qpik.joint_names(configuration.model)[j] for j in configuration.model.dof_jntid]
        i = names.index(result.limiting_joint)
        assert min(abs(tau[i] - limits[i, 0]), abs(tau[i] - limits[i, 1])) < 1e-9


def test_max_payload_with_given_limits_and_when_gravity_cannot_be_held():
    configuration = configuration_of("ur5e", [0.0, -0.3, 0.4, -1.0, 1.2, 0.0])
    up = np.array([0.0, 0.0, 1.0])
    # The shoulder needs -57.4 N m to carry the arm: with -50 N m it cannot, but an upward
    # push of at least ~8 N helps it out.
    limits = np.array([[-5, 5], [-50, 10], [-20, 20], [-3, 3], [-3, 3], [-3, 3]], float)
    result = statics.max_payload(configuration, "ee", up, torque_limits=limits)
    assert not result.holds_gravity and result.feasible
    assert 7 < result.interval[0] < result.force < 30
    scanned, step = _brute_force_payload(configuration, up, limits, True, top=60, steps=1201)
    assert result.force - step <= scanned <= result.force + 1e-9
    # Symmetric limits as an (nv,) vector.
    symmetric = statics.max_payload(configuration, "ee", up, torque_limits=[5, 70, 20, 3, 3, 3])
    scanned, step = _brute_force_payload(
        configuration,
        up,
        np.array([[-5, 5], [-70, 70], [-20, 20], [-3, 3], [-3, 3], [-3, 3]]),
        True,
        top=60,
        steps=1201,
    )
    assert symmetric.holds_gravity and symmetric.force - step <= scanned <= symmetric.force
    # Motors that cannot carry anything: no magnitude can be held.
    weak = statics.max_payload(configuration, "ee", -up, torque_limits=np.zeros(6))
    assert not weak.holds_gravity and not weak.feasible and weak.force == 0.0


def test_max_payload_is_infinite_along_a_direction_the_structure_carries():
    configuration = configuration_of("planar_2r", [0.3, 0.8])
    result = statics.max_payload(configuration, "ee", [0, 0, -1])
    assert result.force == np.inf and result.limiting_joint is None and result.feasible


# ------------------------------------------------------------------- bad inputs
@pytest.mark.parametrize(
    "call, error, fragment",
    [
        (lambda c: statics.joint_torques(c, "ee", [np.nan, 0, 0]), InvalidInput, "force[0]"),
        (lambda c: statics.joint_torques(c, "ee", [1, 0]), InvalidInput, "expected (3,)"),
        (lambda c: statics.joint_torques(c, "ee", [1, 0, 0], [0, np.inf, 0]), InvalidInput, "torque[1]"),
        (lambda c: statics.joint_torques(c, "tip", [1, 0, 0]), UnknownFrame, "available sites: ee"),
        (lambda c: statics.joint_torques(c, "ee", [1, 0, 0], expressed_in="tool"), InvalidInput, "'world' or 'local'"),
        (lambda c: statics.joint_torques(c, "ee", [1, 0, 0], frame_type="link"), UnknownFrameType, "body, site, geom"),
        (lambda c: statics.holding_torques(c, [("ee",)]), InvalidInput, "wrenches[0]"),
        (lambda c: statics.holding_torques(c, [("ee", [1, 2])]), InvalidInput, "wrenches[0]: force"),
        (lambda c: statics.wrench_from_torques(c, "ee", [1.0, 2.0, 3.0]), InvalidInput, "tau has shape"),
        (lambda c: statics.max_payload(c, "ee", [0, 0, 0]), InvalidInput, "is zero"),
        (lambda c: statics.max_payload(c, "ee", [0, 0, 1], torque_limits=[1, 2, 3]), InvalidInput, "torque_limits"),
        (lambda c: statics.force_ellipsoid(c, "ee", rows=(0, 6)), InvalidInput, "rows"),
    ],
)  # fmt: skip
def test_bad_input_raises_clear_errors(call, error, fragment):
    configuration = configuration_of("planar_2r", [0.3, 0.5])
    with pytest.raises(error) as info:
        call(configuration)
    assert isinstance(info.value, QpikError)
    assert fragment in str(info.value)


def test_public_api():
    assert "statics" in qpik.__all__ and qpik.statics is statics
    for name in statics.__all__:
        assert hasattr(statics, name)
    with pytest.raises(TypeError, match="qpik.Configuration"):
        statics.gravity_torques(qpik.load_robot("planar_2r"))


# ------------------------------------------------------------- effort ranges (URDF)


JOINT_EFFORTS = """
<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <body name="l1">
      <joint name="a" axis="0 0 1" actuatorfrcrange="-30 40"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.02" mass="1"/>
      <body name="l2" pos="0.5 0 0">
        <joint name="b" axis="0 1 0" actuatorfrcrange="-5 5"/>
        <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.02" mass="1"/>
        <body name="l3" pos="0.5 0 0">
          <joint name="c" axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/>
          <site name="ee" pos="0.3 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="b" gear="10" ctrlrange="-1 1"/>
  </actuator>
</mujoco>
"""


def test_joint_effort_ranges_are_torque_limits_where_no_actuator_drives():
    model = mujoco.MjModel.from_xml_string(JOINT_EFFORTS)
    limits = statics.joint_torque_limits(qpik.Configuration(model))
    np.testing.assert_array_equal(limits[0], [-30, 40])  # no actuator: the joint's range
    np.testing.assert_array_equal(limits[1], [-5, 5])  # motor gives 10, the joint caps at 5
    np.testing.assert_array_equal(limits[2], [0, 0])  # neither: passive


@pytest.mark.skipif(not has_erd(), reason="needs qpik[robots]")
def test_erd_ur5_statics_uses_the_urdf_efforts():
    import warnings
    import xml.etree.ElementTree as ET

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = qpik.load_robot("erd:ur5")
    configuration = qpik.Configuration(model, [0, -1.57, 1.57, 0, 0, 0])
    limits = statics.joint_torque_limits(configuration)
    root = ET.parse(qpik.robots.erd_path("ur5")).getroot()
    for joint in root.iter("joint"):
        if joint.get("type") == "revolute":
            effort = float(joint.find("limit").get("effort"))
            dof = model.joint(joint.get("name")).dofadr[0]
            np.testing.assert_array_equal(limits[dof], [-effort, effort])
    payload = statics.max_payload(configuration, "tool0", [0, 0, -1], frame_type="body")
    assert payload.feasible and 0 < payload.force < np.inf and payload.holds_gravity


def test_a_force_limited_motor_with_a_tighter_ctrl_range_is_limited_by_its_ctrl():
    """Audit (statics): a motor with gear 3, ctrlrange [-2, 2] and forcerange [-100, 100]
    was taken as +-300 N m (gear x forcerange), and max_payload as 295 N; MuJoCo's own
    qfrc_actuator at the clamped controls is +-6 N m, and the joint holds 1.095 N. The
    limit is gear x (gain x ctrlrange clipped to forcerange) now, MuJoCo's at the extremes."""
    xml = """<mujoco><option gravity="0 0 -9.81"/><worldbody><body name="l">
      <joint name="j" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 1 0 0" size=".01" mass="0.5"/>
      <site name="tip" pos="1 0 0"/></body></worldbody>
      <actuator><motor joint="j" gear="3" ctrlrange="-2 2" forcerange="-100 100"/></actuator>
    </mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    configuration = qpik.Configuration(model)
    limits = qpik.statics.joint_torque_limits(configuration)
    data = mujoco.MjData(model)
    for k, ctrl in enumerate((-1e9, 1e9)):
        data.ctrl[:] = ctrl
        mujoco.mj_forward(model, data)
        assert limits[0, k] == pytest.approx(data.qfrc_actuator[0])
