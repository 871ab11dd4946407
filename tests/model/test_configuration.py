"""Configuration: FK and Jacobians against closed forms and finite differences."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from conftest import central_difference, configuration_of
from scipy.spatial.transform import Rotation

import qpik


def planar_tip(q: np.ndarray) -> np.ndarray:
    """Closed-form tip of a planar arm with unit links."""
    angles = np.cumsum(q)
    return np.array([np.cos(angles).sum(), np.sin(angles).sum(), 0.0])


@pytest.mark.parametrize("name, n", [("planar_2r", 2), ("planar_4r", 4)])
def test_planar_fk_matches_closed_form(name, n, rng):
    configuration = configuration_of(name)
    for _ in range(100):
        q = rng.uniform(-np.pi, np.pi, n)
        configuration.update(q)
        position, rotation = configuration.frame_pose("ee")
        np.testing.assert_allclose(position, planar_tip(q), atol=1e-12)
        np.testing.assert_allclose(
            rotation, Rotation.from_euler("z", q.sum()).as_matrix(), atol=1e-12
        )


def test_planar_2r_jacobian_is_the_lectures(rng):
    configuration = configuration_of("planar_2r")
    for _ in range(100):
        q1, q2 = rng.uniform(-np.pi, np.pi, 2)
        configuration.update([q1, q2])
        s1, c1, s12, c12 = np.sin(q1), np.cos(q1), np.sin(q1 + q2), np.cos(q1 + q2)
        expected = np.array([[-s1 - s12, -s12], [c1 + c12, c12]])
        np.testing.assert_allclose(configuration.frame_jacobian("ee")[:2], expected, atol=1e-12)


def test_lecture_2r_singular_point_digits():
    configuration = configuration_of("planar_2r", [np.pi / 4, 0.001])
    J = configuration.frame_jacobian("ee")[:2]
    np.testing.assert_allclose(J, [[-1.4149, -0.7078], [1.4135, 0.7064]], atol=5e-5)


def test_lecture_4r_q1_reaches_minus1_2():
    configuration = configuration_of("planar_4r", [0.76, 0.90, 0.69, 1.19])
    position, _ = configuration.frame_pose("ee")
    assert np.linalg.norm(position[:2] - np.array([-1.0, 2.0])) < 0.02


def _dh_standard(d, a, alpha, q):
    T = np.eye(4)
    for di, ai, al, qi in zip(d, a, alpha, q):
        ct, st, ca, sa = math.cos(qi), math.sin(qi), math.cos(al), math.sin(al)
        T = T @ np.array(
            [
                [ct, -st * ca, st * sa, ai * ct],
                [st, ct * ca, -ct * sa, ai * st],
                [0, sa, ca, di],
                [0, 0, 0, 1],
            ]
        )
    return T


def _dh_craig(d, a, alpha, q):
    T = np.eye(4)
    for di, ai, al, qi in zip(d, a, alpha, q):
        ct, st, ca, sa = math.cos(qi), math.sin(qi), math.cos(al), math.sin(al)
        T = T @ np.array(
            [
                [ct, -st, 0, ai],
                [st * ca, ct * ca, -sa, -di * sa],
                [st * sa, ct * sa, ca, di * ca],
                [0, 0, 0, 1],
            ]
        )
    return T


def test_ur5e_matches_published_dh(rng):
    configuration = configuration_of("ur5e")
    d = [0.1625, 0, 0, 0.1333, 0.0997, 0.0996]
    a = [0, -0.425, -0.3922, 0, 0, 0]
    alpha = [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0]
    for _ in range(20):
        q = configuration.random_q(rng)
        configuration.update(q)
        T = _dh_standard(d, a, alpha, q)
        position, rotation = configuration.frame_pose("ee")
        np.testing.assert_allclose(position, T[:3, 3], atol=1e-9)
        np.testing.assert_allclose(rotation, T[:3, :3], atol=1e-9)


def test_panda_matches_published_craig_dh(rng):
    configuration = configuration_of("panda")
    a = [0, 0, 0, 0.0825, -0.0825, 0, 0.088, 0]
    d = [0.333, 0, 0.316, 0, 0.384, 0, 0, 0.107]
    alpha = [0, -np.pi / 2, np.pi / 2, np.pi / 2, -np.pi / 2, np.pi / 2, np.pi / 2, 0]
    hand = np.eye(4)
    hand[:3, :3] = Rotation.from_euler("z", -np.pi / 4).as_matrix()
    tcp = np.eye(4)
    tcp[2, 3] = 0.1034
    for _ in range(20):
        q = configuration.random_q(rng)
        configuration.update(q)
        T = _dh_craig(d, a, alpha, [*q, 0.0]) @ hand @ tcp
        position, rotation = configuration.frame_pose("ee")
        np.testing.assert_allclose(position, T[:3, 3], atol=1e-9)
        np.testing.assert_allclose(rotation, T[:3, :3], atol=1e-9)
    # Franka's documented "ready" pose puts the TCP at (0.307, 0, 0.487).
    configuration.update([0, -np.pi / 4, 0, -3 * np.pi / 4, 0, np.pi / 2, np.pi / 4])
    np.testing.assert_allclose(configuration.frame_pose("ee")[0], [0.307, 0, 0.487], atol=1e-3)


def test_jacobian_matches_finite_differences(bundled_robot, rng):
    configuration = configuration_of(bundled_robot)
    for _ in range(20):
        configuration.update(configuration.random_q(rng))
        numeric = central_difference(configuration, lambda c: c.frame_pose("ee"))
        np.testing.assert_allclose(configuration.frame_jacobian("ee"), numeric, atol=1e-6)


def test_frame_types_accept_enum_and_string():
    configuration = configuration_of("ur5e")
    by_enum = configuration.frame_pose("tool0", qpik.FrameType.BODY)
    by_string = configuration.frame_pose("tool0", "body")
    np.testing.assert_array_equal(by_enum[0], by_string[0])
    # tool0 body and ee site coincide on the bundled UR5e.
    np.testing.assert_allclose(by_enum[0], configuration.frame_pose("ee")[0], atol=1e-12)


def test_limits_and_integration():
    configuration = configuration_of("panda")
    assert configuration.lower.shape == (7,) and np.all(configuration.lower < configuration.upper)
    assert configuration.upper[3] == pytest.approx(-0.0698)
    q0 = configuration.mid_q()
    configuration.update(q0)
    v = np.arange(7) * 0.1
    q1 = configuration.integrate(v, 0.5)
    np.testing.assert_allclose(q1, q0 + 0.5 * v)
    np.testing.assert_array_equal(configuration.q, q0)  # integrate does not move q
    configuration.integrate_inplace(v, 0.5)
    np.testing.assert_allclose(configuration.q, q1)
    configuration.q[0] = 100.0  # .q is a copy
    np.testing.assert_allclose(configuration.q, q1)
    np.testing.assert_allclose(configuration.velocity_limits(), [2.175] * 4 + [2.61] * 3)


def test_check_limits_names_the_joint():
    configuration = configuration_of("panda")
    q = configuration.mid_q()
    q[3] = 0.5
    configuration.update(q)
    assert not configuration.within_limits()
    with pytest.raises(qpik.JointLimitViolation, match="joint4") as info:
        configuration.check_limits()
    assert info.value.index == 3 and info.value.upper == pytest.approx(-0.0698)


def test_mink_tasks_accept_a_qpik_configuration():
    import mink

    configuration = configuration_of("panda")
    configuration.update(configuration.mid_q())
    task = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    task.set_target_from_configuration(configuration)
    np.testing.assert_allclose(task.compute_error(configuration), 0.0, atol=1e-12)


BALL = """
<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <body name="base" pos="0 0 1">
      <freejoint name="root"/>
      <geom type="sphere" size="0.1"/>
      <body name="arm">
        <joint name="shoulder" type="ball" range="0 0.5"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/>
        <body name="fore" pos="0.3 0 0">
          <joint name="wrist" type="ball"/>
          <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _ball_q(model, shoulder_angle: float, wrist_angle: float = 2.5) -> np.ndarray:
    q = model.qpos0.copy()
    axis = np.array([0.0, 0.6, 0.8])
    for name, angle in (("shoulder", shoulder_angle), ("wrist", wrist_angle)):
        adr = model.joint(name).qposadr[0]
        q[adr : adr + 4] = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])
    return q


def test_ball_joint_limits_are_checked():
    import mujoco

    model = mujoco.MjModel.from_xml_string(BALL)
    configuration = qpik.Configuration(model, _ball_q(model, 0.4))
    assert configuration.within_limits()
    configuration.check_limits()
    angles = configuration.ball_angles()
    assert angles["shoulder"] == pytest.approx(0.4) and angles["wrist"] == pytest.approx(2.5)
    configuration.update(_ball_q(model, 1.0))  # a rotation of 1 rad against a 0.5 rad range
    assert not configuration.within_limits()
    with pytest.raises(qpik.JointLimitViolation) as info:
        configuration.check_limits()
    error = info.value
    assert error.joint == "shoulder" and error.value == pytest.approx(1.0) and error.upper == 0.5
    configuration.check_limits(safety_break=False)  # mink's signature: nothing raised
    # The angle of q and -q (the same rotation) is the same; the unlimited wrist never fails.
    q = _ball_q(model, 0.45, wrist_angle=3.1)
    adr = model.joint("shoulder").qposadr[0]
    q[adr : adr + 4] *= -1
    configuration.update(q)
    assert configuration.within_limits()


def test_velocity_limit_zero_means_none():
    import mujoco

    model = mujoco.MjModel.from_xml_string(
        BALL.replace(
            "</worldbody>",
            '</worldbody><custom><numeric name="velocity_limit" '
            'data="0 0 0 0 0 0 2 2 2 0 0 0"/></custom>',
        )
    )
    limits = qpik.Configuration(model).velocity_limits()
    np.testing.assert_array_equal(limits, [np.inf] * 6 + [2.0] * 3 + [np.inf] * 3)


def test_check_within_limits_is_check_limits_without_mjdata():
    """check_within_limits raises what Configuration.check_limits raises (the same joint,
    index, value and bounds), hinge and limited ball joints alike; IKSession's start check
    uses it on models with free or ball joints (a Configuration, 0.4 ms on a humanoid)."""
    from qpik.errors import JointLimitViolation
    from qpik.model.configuration import check_within_limits

    model = mujoco.MjModel.from_xml_string(
        """<mujoco><compiler angle="radian"/><worldbody><body><freejoint/><geom size="0.1"/>
        <body><joint name="h" range="-0.5 0.5"/><geom size="0.1"/>
        <body><joint name="b" type="ball" range="0 0.7"/><geom size="0.1"/></body></body>
        </body></worldbody></mujoco>"""
    )
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(1)
    raised = 0
    for _ in range(200):
        q = model.qpos0.copy()
        q[7] = rng.uniform(-0.8, 0.8)
        quat = rng.normal(size=4) * np.array([8.0, 1.0, 1.0, 1.0])
        q[8:12] = quat / np.linalg.norm(quat)
        configuration.update(q)

        def outcome(check):
            try:
                check()
            except JointLimitViolation as exc:
                return (exc.joint, exc.index, exc.value, exc.lower, exc.upper)
            return None

        expected = outcome(configuration.check_limits)
        got = outcome(
            lambda q=q: check_within_limits(model, q, configuration.lower, configuration.upper)
        )
        assert got == expected
        raised += expected is not None
    assert 20 < raised < 180  # both outcomes exercised


@pytest.mark.parametrize("joint", ["root", "wrist"])
def test_quaternions_zero_tiny_or_huge_are_normalised(joint):
    """Pins repro_04: a free or ball joint's quaternion whose norm MuJoCo's normalisation would
    underflow or overflow ([1e200, 1e200, 0, 0]) is the rotation it scales; a zero one is the
    identity (MuJoCo's reading and mink's; it raised InvalidConfiguration, which failed
    mink's own tests run on qpik)."""
    model = mujoco.MjModel.from_xml_string(BALL)
    adr = model.joint(joint).qposadr[0] + (3 if joint == "root" else 0)
    q = _ball_q(model, 0.3)
    q[adr : adr + 4] = [1.0, 1.0, 0.0, 0.0]  # 90 deg about x
    reference = qpik.Configuration(model, q).frame_pose("fore", "body")
    for scale in (1e200, 1e-200, 5e-324):
        scaled = q.copy()
        scaled[adr : adr + 4] *= scale
        configuration = qpik.Configuration(model, scaled)
        for got, want in zip(configuration.frame_pose("fore", "body"), reference):
            np.testing.assert_allclose(got, want, atol=1e-12)
        np.testing.assert_array_equal(scaled[adr : adr + 2], [scale, scale])  # not written to
        np.testing.assert_allclose(configuration.q[adr : adr + 4], [0.5**0.5, 0.5**0.5, 0, 0])
    # a zero quaternion is the identity, as MuJoCo reads it and mink takes it (np.zeros(nq)
    # as a configuration, in mink's own tests)
    q[adr : adr + 4] = 0.0
    identity = q.copy()
    identity[adr] = 1.0
    configuration = qpik.Configuration(model, q)
    np.testing.assert_array_equal(configuration.q, identity)
    for got, want in zip(
        configuration.frame_pose("fore", "body"),
        qpik.Configuration(model, identity).frame_pose("fore", "body"),
    ):
        np.testing.assert_array_equal(got, want)


def test_floating_panda_quaternion_of_1e200_is_the_unit_ones_rotation():
    """Pins repro_04 on the floating-base panda: [1e200, 1e200, 0, 0] and [1e-200, ...] are
    the rotation of [1, 1, 0, 0]; [0, 0, 0, 0] is the identity."""
    model = qpik.load_robot("panda", floating_base=True)
    arm = [0, 0, 0, -1, 0, 1, 0]
    want = qpik.Configuration(model, np.r_[0, 0, 0, 1, 1, 0, 0, arm]).frame_pose("ee")[0]
    for scale in (1e200, 1e-200):
        q = np.r_[0, 0, 0, scale, scale, 0, 0, arm]
        got = qpik.Configuration(model, q).frame_pose("ee")[0]
        np.testing.assert_allclose(got, want, atol=1e-12)
    zero = qpik.Configuration(model, np.r_[0, 0, 0, 0, 0, 0, 0, arm])
    np.testing.assert_array_equal(zero.q[3:7], [1.0, 0.0, 0.0, 0.0])


def test_integrate_to_a_non_finite_q_raises_and_leaves_q():
    """Pins repro_05: a finite velocity too large to integrate (1e300 rad/s of a free joint:
    a NaN quaternion; 1e300 x 1e10 on a hinge: inf) raises InvalidConfiguration naming the
    velocity, and integrate_inplace then leaves q as it was."""
    floating = qpik.Configuration(qpik.load_robot("panda", floating_base=True))
    v = np.zeros(floating.model.nv)
    v[3] = 1e300
    before = floating.q
    with pytest.raises(qpik.InvalidConfiguration, match=r"velocity entries v\[0:6\].*root_joint"):
        floating.integrate(v, 1.0)
    with pytest.raises(qpik.InvalidConfiguration, match="too large to integrate"):
        floating.integrate_inplace(v, 1.0)
    np.testing.assert_array_equal(floating.q, before)
    assert np.isfinite(floating.frame_pose("ee")[0]).all()
    arm = qpik.Configuration(qpik.load_robot("panda"))
    with pytest.raises(qpik.InvalidConfiguration, match=r"velocity entries v\[0\]") as info:
        arm.integrate(np.full(7, 1e300), 1e10)
    assert info.value.index == 0
    v = np.full(7, 0.1)  # an ordinary step still integrates
    np.testing.assert_allclose(arm.integrate(v, 0.5), arm.q + 0.05)


def test_a_complex_or_text_configuration_or_velocity_is_refused_not_cast():
    model = qpik.load_robot("panda")
    for q in (np.zeros(model.nq, complex), np.array(["0"] * model.nq), [0.0] * 6 + [1j]):
        with pytest.raises(qpik.InvalidConfiguration, match="real numbers, got"):
            qpik.Configuration(model, q)
    configuration = qpik.Configuration(model)
    with pytest.raises(qpik.errors.InvalidArgumentType, match="velocity"):
        configuration.integrate([0.0] * 6 + [1j], 0.01)
    np.testing.assert_array_equal(qpik.Configuration(model, np.zeros(model.nq, int)).q, 0.0)


def test_a_copied_or_unpickled_configuration_updates_as_a_new_one():
    """A deep copy or pickle of a Configuration that has been updated: its update(q) moves
    its own q and kinematics (update's kept views of data were copied apart from the data,
    so the copy's update wrote where nothing read)."""
    import copy
    import pickle

    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    configuration.update(model.key_qpos[0] * 0.5)
    q1 = model.key_qpos[0] * 0.9
    fresh = qpik.Configuration(model, q1)
    for twin in (copy.deepcopy(configuration), pickle.loads(pickle.dumps(configuration))):
        twin.update(q1)
        np.testing.assert_array_equal(twin.q, q1)
        np.testing.assert_array_equal(twin.frame_pose("ee")[0], fresh.frame_pose("ee")[0])
    np.testing.assert_array_equal(configuration.q, model.key_qpos[0] * 0.5)  # (untouched)
