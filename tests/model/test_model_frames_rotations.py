"""qpik.model.frames (the one frame resolver) and qpik.model.rotations (the one orientation
error) against MuJoCo's own functions, scipy and finite differences."""

from __future__ import annotations

import math
import pickle

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import qpik
from qpik.model import kernels as K
from qpik.model import rotations as rot
from qpik.model.frames import (
    FRAME_OBJECTS,
    FrameType,
    ResolvedFrame,
    frame_id,
    frame_names,
    resolve_frame,
)

_XML = """
<mujoco>
  <worldbody>
    <body name="base">
      <joint name="j0" type="hinge" axis="0 0 1"/>
      <geom name="shared" type="sphere" size="0.1"/>
      <site name="tip" pos="0 0 1"/>
      <body name="shared">
        <joint name="j1" type="hinge" axis="0 1 0"/>
        <geom type="capsule" size="0.05 0.2"/>
        <geom name="only_geom" type="sphere" size="0.05"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(_XML)


# --------------------------------------------------------------------------- frames
def test_frame_objects_is_mujocos_map():
    assert FRAME_OBJECTS[FrameType.SITE] == mujoco.mjtObj.mjOBJ_SITE
    assert FRAME_OBJECTS[FrameType.BODY] == mujoco.mjtObj.mjOBJ_BODY
    assert FRAME_OBJECTS[FrameType.GEOM] == mujoco.mjtObj.mjOBJ_GEOM
    assert set(FRAME_OBJECTS) == set(FrameType)
    with pytest.raises(TypeError):
        FRAME_OBJECTS[FrameType.SITE] = mujoco.mjtObj.mjOBJ_JOINT  # read-only


def test_frametype_is_the_one_of_qpik():
    assert qpik.FrameType is FrameType
    assert qpik.model.configuration.FrameType is FrameType
    assert pickle.loads(pickle.dumps(FrameType.GEOM)) is FrameType.GEOM


def test_resolve_search_order_sites_bodies_geoms(model):
    # "shared" is a body and a geom: the body wins; "only_geom" is found among the geoms.
    assert resolve_frame(model, "tip") == ResolvedFrame("tip", FrameType.SITE, 0)
    found = resolve_frame(model, "shared")
    assert found.type is FrameType.BODY
    assert found.id == mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "shared")
    found = resolve_frame(model, "only_geom")
    assert found.type is FrameType.GEOM
    assert found.id == mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "only_geom")
    name, kind, fid = resolve_frame(model, ("shared", "geom"))  # unpacks as a tuple
    assert (name, kind, fid) == ("shared", FrameType.GEOM, 0)


def test_resolve_with_a_type_and_ids(model):
    assert resolve_frame(model, "base", "body").id == 1
    assert resolve_frame(model, 1, FrameType.BODY) == ResolvedFrame("base", FrameType.BODY, 1)
    assert resolve_frame(model, 1, "geom").name == "geom #1"  # unnamed geom
    assert resolve_frame(model, resolve_frame(model, "tip")).id == 0


def test_resolve_unknown_names_list_the_valid_ones(model):
    with pytest.raises(qpik.UnknownFrame) as info:
        resolve_frame(model, "nope")
    assert info.value.available == ["tip", "world", "base", "shared", "shared", "only_geom"]
    assert "nope" in str(info.value)
    with pytest.raises(qpik.UnknownFrame) as info:
        resolve_frame(model, ("tip", "body"))
    assert info.value.available == ["world", "base", "shared"]
    with pytest.raises(qpik.UnknownFrame):
        resolve_frame(model, 7, "site")
    with pytest.raises(qpik.UnknownFrameType):
        resolve_frame(model, ("tip", "joint"))


@pytest.mark.parametrize("key", [None, 3, 1.5, ("tip",), ("tip", "site", 0), b"tip", ["tip"]])
def test_resolve_malformed_keys_name_the_argument(model, key):
    with pytest.raises(qpik.InvalidInput, match="targets"):
        resolve_frame(model, key, argument="targets")


def test_frame_id_and_names_agree_with_mujoco(model):
    for kind, obj in FRAME_OBJECTS.items():
        for name in frame_names(model, kind):
            assert frame_id(model, name, kind) == mujoco.mj_name2id(model, obj, name)
    with pytest.raises(qpik.UnknownFrame):
        frame_id(model, True, "body")  # a bool is not an id


# ------------------------------------------------------------------------ rotations
def _random_rotations(rng, count):
    return Rotation.random(count, random_state=rng).as_matrix()


def _near_pi(rng, count):
    out = []
    for _ in range(count):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = math.pi - 10.0 ** rng.uniform(-12, -1)
        out.append((Rotation.from_rotvec(angle * axis).as_matrix(), angle * axis))
    return out


def test_rotation_vector_matches_scipy(rng):
    for R in _random_rotations(rng, 200):
        expected = Rotation.from_matrix(R).as_rotvec()
        np.testing.assert_allclose(rot.rotation_vector(R), expected, atol=1e-12)


def test_rotation_vector_near_zero_and_pi(rng):
    for angle in (0.0, 1e-15, 1e-9, 1e-5):
        axis = np.array([0.6, 0.0, 0.8])
        R = Rotation.from_rotvec(angle * axis).as_matrix()
        np.testing.assert_allclose(rot.rotation_vector(R), angle * axis, atol=1e-16 + 1e-12 * angle)
    for R, expected in _near_pi(rng, 50):
        got = rot.rotation_vector(R)
        assert np.linalg.norm(got) == pytest.approx(np.linalg.norm(expected), abs=1e-9)
        # at pi, the axis sign is arbitrary: compare the rotations
        np.testing.assert_allclose(Rotation.from_rotvec(got).as_matrix(), R, atol=1e-12)


def test_rotation_vector_equals_the_compiled_kernel(rng):
    rotations = list(_random_rotations(rng, 100)) + [R for R, _ in _near_pi(rng, 20)]
    out = np.empty(3)
    for R in rotations:
        angle = K.rotation_log(np.ascontiguousarray(R), out)
        np.testing.assert_allclose(rot.rotation_vector(R), out, atol=1e-15)
        assert np.linalg.norm(out) == pytest.approx(angle, abs=1e-15)


def test_orientation_error_is_a_world_rotation_and_the_angle_its_norm(rng):
    for R_current, R_target in zip(_random_rotations(rng, 50), _random_rotations(rng, 50)):
        e = rot.orientation_error(R_current, R_target)
        # exp([e]) R_current = R_target: the rotation about world axes onto the target
        np.testing.assert_allclose(rot.rotation_from_vector(e) @ R_current, R_target, atol=1e-12)
        assert rot.orientation_angle(R_current, R_target) == pytest.approx(
            np.linalg.norm(e), abs=1e-12
        )
    R = _random_rotations(rng, 1)[0]
    assert rot.orientation_angle(R, R) == 0.0
    small = Rotation.from_rotvec([1e-9, 0, 0]).as_matrix() @ R
    assert rot.orientation_angle(R, small) == pytest.approx(1e-9, rel=1e-6)  # acos would lose it


def test_orientation_error_pairs_with_the_world_jacobian():
    """J_omega dq = d(orientation error toward a fixed target), to first order, with the
    inverse left Jacobian; checked by finite differences on the bundled panda."""
    configuration = qpik.Configuration(qpik.load_robot("panda"))
    q = configuration.mid_q()
    configuration.update(q)
    _, R_target = configuration.frame_pose("ee")
    R_target = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix() @ R_target
    J = configuration.frame_jacobian("ee")[3:]
    e0 = rot.orientation_error(configuration.frame_pose("ee")[1], R_target)
    h = 1e-7
    for i in range(configuration.model.nv):
        dq = np.zeros(configuration.model.nv)
        dq[i] = h
        configuration.update(q + dq)
        plus = rot.orientation_error(configuration.frame_pose("ee")[1], R_target)
        configuration.update(q - dq)
        minus = rot.orientation_error(configuration.frame_pose("ee")[1], R_target)
        # the error toward a fixed target decreases along omega: d e = -Jl^-1(-e) omega
        expected = -rot.left_jacobian_inverse(-e0) @ J[:, i]
        np.testing.assert_allclose((plus - minus) / (2 * h), expected, atol=1e-6)


def test_left_jacobian_inverse_matches_the_kernel(rng):
    out = np.empty((3, 3))
    for phi in [np.zeros(3), np.array([1e-8, 0, 0]), *rng.normal(size=(20, 3))]:
        K.left_jacobian_inverse(phi, out)
        np.testing.assert_allclose(rot.left_jacobian_inverse(phi), out, atol=1e-14)


def test_quaternions_match_mujoco(rng):
    quats = rng.normal(size=(100, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    batch = rot.quaternion_to_matrix(quats)
    for quat, R in zip(quats, batch):
        expected = np.zeros(9)
        mujoco.mju_quat2Mat(expected, quat)
        np.testing.assert_allclose(R, expected.reshape(3, 3), atol=1e-15)
        np.testing.assert_allclose(rot.quaternion_to_matrix(5.0 * quat), R, atol=1e-15)
        back = rot.matrix_to_quaternion(R)
        assert back[0] >= 0.0
        np.testing.assert_allclose(back, quat if quat[0] >= 0 else -quat, atol=1e-12)


def test_rpy_is_the_urdf_convention(rng):
    for roll, pitch, yaw in rng.uniform(-3, 3, size=(50, 3)):
        expected = Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix()  # extrinsic
        np.testing.assert_allclose(rot.rpy_to_matrix(roll, pitch, yaw), expected, atol=1e-14)


def test_rotation_from_vector_matches_scipy(rng):
    for phi in [np.zeros(3), np.array([0, 1e-10, 0]), *rng.normal(size=(50, 3))]:
        np.testing.assert_allclose(
            rot.rotation_from_vector(phi), Rotation.from_rotvec(phi).as_matrix(), atol=1e-14
        )


def test_rotation_defect():
    assert rot.rotation_defect(np.eye(3)) == 0.0
    assert rot.rotation_defect(np.diag([1.0, 1.0, -1.0])) == math.inf  # a reflection
    assert rot.rotation_defect(np.full((3, 3), np.nan)) == math.inf
    assert rot.rotation_defect(np.eye(2)) == math.inf
    assert rot.rotation_defect(np.diag([1.0, 1.0, 1.001])) == pytest.approx(0.002001)
