"""Compiled kinematics (qpik.model) against MuJoCo, finite differences, closed forms, and
the compiled IGM's building blocks against independent solvers."""

from __future__ import annotations

import itertools

import mujoco
import numpy as np
import pytest
from conftest import central_difference, load_or_skip
from scipy.spatial.transform import Rotation

import qpik
from qpik.igm import kernels as IGM
from qpik.model import KinematicChain, chain_support, joint_limit_arrays
from qpik.model import kernels as K

ERD_ARMS = [
    ("erd:panda", "panda_hand_tcp"),
    ("erd:ur3", "tool0"),
    ("erd:ur5", "tool0"),
    ("erd:ur10", "tool0"),
    ("erd:xarm7", "link_eef"),
    ("erd:kinova", "j2s6s200_end_effector"),
    ("erd:z1", "gripperStator"),
]


def _load(name: str) -> mujoco.MjModel:
    return load_or_skip(name)


def _frames(model: mujoco.MjModel):
    """Every site, every body but the world, and a few geoms."""
    for i in range(model.nsite):
        yield i, qpik.FrameType.SITE
    for i in range(1, model.nbody):
        yield i, qpik.FrameType.BODY
    for i in range(min(model.ngeom, 4)):
        yield i, qpik.FrameType.GEOM


def _mujoco_pose_jacobian(model, data, frame, kind):
    pos = {"site": data.site_xpos, "body": data.xpos, "geom": data.geom_xpos}[kind.value]
    mat = {"site": data.site_xmat, "body": data.xmat, "geom": data.geom_xmat}[kind.value]
    jac = np.zeros((6, model.nv))
    function = {"site": mujoco.mj_jacSite, "body": mujoco.mj_jacBody, "geom": mujoco.mj_jacGeom}
    function[kind.value](model, data, jac[:3], jac[3:], frame)
    return pos[frame].copy(), mat[frame].reshape(3, 3).copy(), jac


@pytest.mark.parametrize("robot", qpik.list_robots() + [name for name, _ in ERD_ARMS])
def test_pose_and_jacobian_equal_mujoco(robot):
    model = _load(robot)
    if chain_support(model) is not None:
        pytest.skip(chain_support(model))
    data = mujoco.MjData(model)
    lower, upper = joint_limit_arrays(model)
    lo = np.where(np.isfinite(lower), lower, -np.pi)
    hi = np.where(np.isfinite(upper), upper, np.pi)
    rng = np.random.default_rng(7)
    chains = [(f, k, KinematicChain.from_model(model, f, k)) for f, k in _frames(model)]
    worst = 0.0
    for _ in range(10):
        q = rng.uniform(lo, hi)
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        for frame, kind, chain in chains:
            position, rotation, jacobian = _mujoco_pose_jacobian(model, data, frame, kind)
            mine_p, mine_r = chain.pose(q)
            mine_j = chain.jacobian(q)
            worst = max(
                worst,
                np.abs(mine_p - position).max(),
                np.abs(mine_r - rotation).max(),
                np.abs(mine_j - jacobian).max(),
            )
    assert worst <= 1e-12, worst


def test_jacobian_equals_finite_differences():
    model = qpik.load_robot("ur5e")
    chain = KinematicChain.from_model(model, "ee", "site")
    configuration = qpik.Configuration(model)
    configuration.update(configuration.random_q(np.random.default_rng(3)))
    numeric = central_difference(configuration, lambda c: c.frame_pose("ee"))
    np.testing.assert_allclose(chain.jacobian(configuration.q), numeric, atol=1e-8)


def test_slide_joint_and_qpos0_reference():
    xml = """
    <mujoco><worldbody><body name="base" pos="0.1 0 0.2" quat="0.9 0.1 0.3 0.2">
      <joint name="s" type="slide" axis="1 1 0" ref="0.3" range="-0.5 0.5"/>
      <geom size="0.05"/>
      <body name="arm" pos="0 0 0.4">
        <joint name="h" type="hinge" axis="0 1 1" pos="0.05 0 0" ref="0.7" range="-2 2"/>
        <joint name="h2" type="hinge" axis="1 0 0" range="-2 2"/>
        <geom size="0.05"/><site name="tip" pos="0.3 0.1 0" quat="0.7 0.7 0 0"/>
      </body></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    chain = KinematicChain.from_model(model, "tip", "site")
    for q in ([0.1, -1.0, 0.5], [-0.4, 1.5, -1.9], [0.3, 0.7, 0.0]):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        position, rotation, jacobian = _mujoco_pose_jacobian(model, data, 0, qpik.FrameType.SITE)
        p, r = chain.pose(q)
        np.testing.assert_allclose(p, position, atol=1e-12)
        np.testing.assert_allclose(r, rotation, atol=1e-12)
        np.testing.assert_allclose(chain.jacobian(q), jacobian, atol=1e-12)
    lower, upper = joint_limit_arrays(model)
    bound = chain.reach_bound(lower, upper)
    rng = np.random.default_rng(0)
    for _ in range(500):
        q = rng.uniform(lower, upper)
        assert np.linalg.norm(chain.pose(q)[0] - bound.center) <= bound.radius + 1e-12


def test_unsupported_joints_are_named():
    xml = """<mujoco><worldbody><body name="b"><freejoint name="float"/><geom size="0.1"/>
    <body name="c"><joint name="ball" type="ball"/><geom size="0.1"/></body></body>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    assert "free joint" in chain_support(model) and "'float'" in chain_support(model)
    with pytest.raises(ValueError, match="free joint"):
        KinematicChain.from_model(model, "c", "body")


def test_unknown_frame_lists_names():
    model = qpik.load_robot("panda")
    with pytest.raises(qpik.UnknownFrame, match="ee"):
        KinematicChain.from_model(model, "gripper", "site")


# ------------------------------------------------------------------ reach bound
def test_reach_bound_closed_form_planar_arms():
    for robot, radius in (("planar_2r", 2.0), ("planar_4r", 4.0)):
        model = qpik.load_robot(robot)
        chain = KinematicChain.from_model(model, "ee", "site")
        bound = chain.reach_bound(*joint_limit_arrays(model))
        np.testing.assert_allclose(bound.radius, radius, atol=1e-12)
        np.testing.assert_allclose(bound.center, model.body_pos[1], atol=1e-12)


@pytest.mark.parametrize("robot", ["panda", "ur5e", "erd:ur5", "erd:xarm7", "erd:kinova"])
def test_reach_bound_holds_and_is_not_loose(robot):
    model = _load(robot)
    frame = {"erd:ur5": "tool0", "erd:xarm7": "link_eef", "erd:kinova": "j2s6s200_end_effector"}
    kind = "body" if robot.startswith("erd:") else "site"
    chain = KinematicChain.from_model(model, frame.get(robot, "ee"), kind)
    lower, upper = joint_limit_arrays(model)
    bound = chain.reach_bound(lower, upper)
    lo = np.where(np.isfinite(lower), lower, -np.pi)
    hi = np.where(np.isfinite(upper), upper, np.pi)
    rng = np.random.default_rng(1)
    distances = [
        np.linalg.norm(chain.pose(rng.uniform(lo, hi))[0] - bound.center) for _ in range(3000)
    ]
    assert max(distances) <= bound.radius
    assert bound.radius <= 1.5 * max(distances)  # a bound that rules targets out
    assert bound.excludes(bound.center + [bound.radius + 1e-3, 0, 0], 1e-4)
    assert not bound.excludes(bound.center + [bound.radius, 0, 0], 1e-4)


# ---------------------------------------------------------------- kernel pieces
def test_rotation_log_against_scipy():
    rng = np.random.default_rng(2)
    vectors = [rng.normal(size=3) for _ in range(50)]
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    vectors += [axis * a for a in (0.0, 1e-9, 1e-6, 1.0, np.pi - 1e-3, np.pi - 1e-7, np.pi)]
    for v in vectors:
        v = np.asarray(v, float)
        if np.linalg.norm(v) > np.pi:
            v = v / np.linalg.norm(v) * (np.linalg.norm(v) % np.pi)
        R = Rotation.from_rotvec(v).as_matrix()
        out = np.empty(3)
        angle = K.rotation_log(R, out)
        expected = Rotation.from_matrix(R).as_rotvec()
        if np.isclose(np.linalg.norm(expected), np.pi, atol=1e-6):
            # at pi both signs are the same rotation
            assert min(np.abs(out - expected).max(), np.abs(out + expected).max()) < 1e-6
        else:
            np.testing.assert_allclose(out, expected, atol=1e-12)
        np.testing.assert_allclose(angle, np.linalg.norm(expected), atol=1e-12)


def test_left_jacobian_inverse_binding_matches_the_rotations_helper():
    from qpik.model.rotations import left_jacobian_inverse as so3_left_jacobian_inverse

    for phi in ([0.1, -0.2, 0.3], [1e-8, 0.0, 2e-8], [1.0, 2.0, -0.5]):
        out = np.empty((3, 3))
        K.left_jacobian_inverse(np.array(phi), out)
        np.testing.assert_allclose(out, so3_left_jacobian_inverse(np.array(phi)), atol=1e-12)


def test_smallest_singular_value_against_svd():
    rng = np.random.default_rng(4)
    gram = np.empty((7, 7))
    for m, n in ((6, 7), (6, 6), (3, 7), (6, 4), (6, 2)):
        A = np.zeros((6, n))
        A[:m] = rng.normal(size=(m, n))
        A[:m, 0] = A[:m, 1] * 1e-3 + A[:m, 0] * 1e-4  # nearly singular
        expected = np.linalg.svd(A[:m], compute_uv=False)[min(m, n) - 1]
        got = IGM.smallest_singular_value(A, m, n, gram)
        assert abs(got - expected) <= 1e-7 * max(1.0, expected), (m, n, got, expected)
        # With a threshold: exact below it, inf at or above it.
        for threshold in (0.5 * expected, 2.0 * expected + 1e-3):
            got = IGM.smallest_singular_value(A, m, n, gram, threshold)
            if expected < threshold:
                assert abs(got - expected) <= 1e-7 * max(1.0, expected)
            else:
                assert got == np.inf


def _brute_force_box_qp(H, g, lb, ub):
    """Every active set (free / lower / upper per variable) until the feasible KKT point
    with the right multiplier signs (H is positive definite: it is the unique minimiser)."""
    n = len(g)
    for pattern in itertools.product((0, -1, 1), repeat=n):
        fixed = np.array(pattern)
        x = np.where(fixed < 0, lb, np.where(fixed > 0, ub, 0.0))
        free = fixed == 0
        if free.any():
            rhs = -(g[free] + H[np.ix_(free, ~free)] @ x[~free])
            x[free] = np.linalg.solve(H[np.ix_(free, free)], rhs)
        if np.any(x < lb - 1e-12) or np.any(x > ub + 1e-12):
            continue
        grad = H @ x + g
        if np.all(grad[fixed < 0] >= -1e-10) and np.all(grad[fixed > 0] <= 1e-10):
            return x
    return None


def test_box_qp_against_brute_force_and_the_core_qp():
    from qpik.core import kernels as core

    rng = np.random.default_rng(5)
    for trial in range(300):
        n = 1 + trial % 5
        M = rng.normal(size=(n + 2, n))
        H = M.T @ M + 1e-3 * np.eye(n)
        g = rng.normal(size=n) * 3
        lb = -rng.uniform(0.0, 1.0, n)
        ub = rng.uniform(0.0, 1.0, n)
        if trial % 7 == 0:
            lb[0] = -np.inf
        x = np.empty(n)
        status, _ = IGM.box_qp(H, g, lb, ub, x, 4 * n + 20)
        assert status == 0
        reference = _brute_force_box_qp(H, g, np.where(np.isfinite(lb), lb, -1e300), ub)
        np.testing.assert_allclose(x, reference, atol=1e-10)
        y, core_status, _, _ = core.solve_qp(
            H, g, np.eye(n), np.maximum(lb, -1e20), ub, np.zeros(n, np.int8), 100, 1e-12, False
        )
        assert int(core_status) == 0
        np.testing.assert_allclose(x, y, atol=1e-10)


def test_splitmix64_stream_matches_reference():
    def reference(seed, count):
        mask = 2**64 - 1
        state = seed
        for _ in range(count):
            state = (state + 0x9E3779B97F4A7C15) & mask
            z = state
            z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
            z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
            z ^= z >> 31
            yield (z >> 11) * 2.0**-53

    for seed in (0, 1, 2**63 + 5):
        state = np.array([seed], dtype=np.uint64)
        got = [IGM.uniform(state) for _ in range(5)]
        assert got == list(reference(seed, 5))
    # SplitMix64's published first output for seed 0 is 0xE220A8397B1DCDAF.
    assert list(reference(0, 1))[0] == (0xE220A8397B1DCDAF >> 11) * 2.0**-53


def test_bodies_chain_joints_is_the_union_of_the_chains():
    """bodies_chain_joints walks each body above the given ones once: the same set as the
    union of body_chain_joints over them (the collision limit's joints in the full IK's
    idle_qpos, which took 14 ms of every Talos solve with a chain per geom of 883 pairs)."""
    from qpik.model.chain import bodies_chain_joints, body_chain_joints

    model = mujoco.MjModel.from_xml_string(
        """<mujoco><worldbody>
        <body name="t"><joint name="t0"/><joint name="t1" axis="1 0 0"/><geom size="0.1"/>
          <body name="l1"><joint/><geom size="0.1"/><body name="l2"><joint/><geom size="0.1"/>
          </body></body>
          <body name="r1"><joint/><geom size="0.1"/><body name="r2"><geom size="0.1"/>
            <body name="r3"><joint/><geom size="0.1"/></body></body></body>
        </body>
        <body name="free"><freejoint/><geom size="0.1"/></body>
        </worldbody></mujoco>"""
    )
    rng = np.random.default_rng(0)
    for _ in range(50):
        bodies = rng.integers(0, model.nbody, size=int(rng.integers(0, 6))).tolist()
        union: set[int] = set()
        for body in bodies:
            union |= body_chain_joints(model, body)
        assert bodies_chain_joints(model, bodies) == union
    assert bodies_chain_joints(model, []) == set()
    assert bodies_chain_joints(model, [0]) == set()  # the world has no joint
