"""ComTask against mink's and finite differences; SupportPolygonLimit against a closed-form
square support and under an IK that pushes the CoM out."""

from __future__ import annotations

import warnings

import mink
import mujoco
import numpy as np
import pytest
from conftest import central_difference, configuration_of, has_erd, requires_erd

import qpik
from qpik.limits import SupportPolygonLimit, joint_limits
from qpik.tasks import ComTask

# A floating box (the "pelvis") on four point feet at (+-0.2, +-0.1) and an arm that moves
# the CoM: the support polygon is the rectangle [-0.2, 0.2] x [-0.1, 0.1].
QUADRUPED = """
<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <body name="base" pos="0 0 0.5">
      <freejoint name="root_joint"/>
      <geom type="box" size="0.2 0.1 0.05" mass="4"/>
      <site name="foot_fl" pos="0.2 0.1 -0.5"/>
      <site name="foot_fr" pos="0.2 -0.1 -0.5"/>
      <site name="foot_hl" pos="-0.2 0.1 -0.5"/>
      <site name="foot_hr" pos="-0.2 -0.1 -0.5"/>
      <body name="arm" pos="0 0 0.05">
        <joint name="yaw" axis="0 0 1" range="-3 3"/>
        <joint name="pitch" axis="0 1 0" range="-1.5 1.5"/>
        <geom type="capsule" fromto="0 0 0 0.8 0 0" size="0.02" mass="2"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""
FEET = ["foot_fl", "foot_fr", "foot_hl", "foot_hr"]


def _talos():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return qpik.load_robot("erd:talos", floating_base=True)


def _models():
    models = [
        ("panda", qpik.load_robot("panda")),
        ("quadruped", mujoco.MjModel.from_xml_string(QUADRUPED)),
    ]
    if has_erd():
        models.append(("talos", _talos()))
    return models


@pytest.mark.parametrize("name, model", _models(), ids=lambda x: x if isinstance(x, str) else "")
def test_com_task_equals_minks_and_finite_differences(name, model, rng):
    configuration = qpik.Configuration(model)
    ours = ComTask(cost=[1.0, 2.0, 0.5])
    theirs = mink.ComTask(cost=[1.0, 2.0, 0.5])
    target = rng.normal(size=3)
    ours.set_target(target)
    theirs.set_target(target)
    for _ in range(3):
        q = configuration.random_q(rng)
        if model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE:
            q[:3] = rng.normal(size=3)
            q[3:7] = rng.normal(size=4)
            q[3:7] /= np.linalg.norm(q[3:7])
        configuration.update(q)
        error, jacobian = ours.compute_error(configuration), ours.compute_jacobian(configuration)
        np.testing.assert_allclose(error, theirs.compute_error(configuration), rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            jacobian, theirs.compute_jacobian(configuration), rtol=0, atol=1e-12
        )
        numeric = central_difference(configuration, ours.compute_error)
        np.testing.assert_allclose(jacobian, numeric, atol=1e-7)
        # The CoM is MuJoCo's mass-weighted mean of the bodies' CoMs.
        mass = model.body_mass[1:]
        mean = (mass[:, None] * configuration.data.xipos[1:]).sum(0) / mass.sum()
        np.testing.assert_allclose(ours.com(configuration), mean, atol=1e-12)


def test_com_task_targets_and_costs_are_validated():
    task = ComTask()
    with pytest.raises(qpik.InvalidTarget, match="CoM target.*finite"):
        task.set_target([0.0, np.nan, 0.0])
    with pytest.raises(qpik.InvalidTarget):
        task.set_target([0.0, 1.0])
    with pytest.raises(mink.TaskDefinitionError, match=">= 0"):
        ComTask(cost=[1.0, -1.0, 1.0])
    configuration = configuration_of("panda")
    with pytest.raises(mink.TargetNotSet):
        task.compute_error(configuration)
    with pytest.raises(qpik.UnknownFrame, match="available bod"):
        ComTask(body="pelvis").set_target_from_configuration(configuration)


def test_com_task_drives_the_com_at_the_top_level():
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    task = ComTask(cost=1.0)
    start = task.com(configuration)
    task.set_target(start + [0.03, -0.02, 0.0])
    solver = qpik.IKSolver(model, [[task]], joint_limits(model))
    for _ in range(50):
        configuration.integrate_inplace(solver.step(configuration, 0.01).velocity, 0.01)
    np.testing.assert_allclose(task.com(configuration), task.target_com, atol=1e-6)


# -------------------------------------------------------------- support polygon
def _quadruped(q_arm=(0.0, 0.0)):
    model = mujoco.MjModel.from_xml_string(QUADRUPED)
    q = model.qpos0.copy()
    q[7:] = q_arm
    return model, qpik.Configuration(model, q)


def test_support_polygon_is_the_feet_rectangle_and_margin_is_the_edge_distance():
    model, configuration = _quadruped()
    limit = SupportPolygonLimit(model, FEET)
    normals, offsets = limit.hull(configuration)
    assert len(normals) == 4
    for yaw in np.linspace(-3, 3, 7):
        for pitch in (-1.2, 0.0, 0.9):
            configuration.update(np.concatenate([model.qpos0[:7], [yaw, pitch]]))
            x, y = configuration.data.subtree_com[1, :2]
            inside = min(0.2 - x, x + 0.2, 0.1 - y, y + 0.1)  # closed form (inside)
            if inside >= 0:
                assert limit.com_margin(configuration) == pytest.approx(inside, abs=1e-12)
            else:
                assert limit.com_margin(configuration) < 0
            # The rows at dq = 0 say the same: G 0 <= h iff inside (margin 0, gain 1).
            rows = SupportPolygonLimit(model, FEET, gain=1.0).compute_qp_inequalities(
                configuration, 0.01
            )
            assert (rows.h.min() >= 0) == (inside >= 0)
            assert rows.h.min() == pytest.approx(inside, abs=1e-12)


def test_support_polygon_rows_are_the_margin_derivative(rng):
    model, configuration = _quadruped((0.4, 0.3))
    limit = SupportPolygonLimit(model, FEET, margin=0.01, gain=1.0)
    rows = limit.compute_qp_inequalities(configuration, 0.01)
    normals, offsets = limit.hull(configuration)

    def signed(configuration):  # a_i^T c_xy + o_i for every edge (feet fixed in the world)
        return normals @ configuration.data.subtree_com[1, :2] + offsets

    numeric = central_difference(configuration, signed)
    np.testing.assert_allclose(rows.G, numeric, atol=1e-7)
    np.testing.assert_allclose(rows.h, -0.01 - signed(configuration), atol=1e-12)


def test_support_polygon_holds_against_a_com_task_pushing_out():
    model, configuration = _quadruped()
    push = ComTask(cost=[1.0, 1.0, 0.0], gain=0.5)
    push.set_target([0.0, 1.0, 0.0])  # far outside the feet, sideways
    # The base may not move (a posture on it at level 0): only the arm moves the CoM.
    base = mink.DofFreezingTask(model, dof_indices=list(range(6)))
    limit = SupportPolygonLimit(model, FEET, margin=0.02)
    speed = mink.VelocityLimit(model, {"yaw": 2.0, "pitch": 2.0})  # [rad/s]
    solver = qpik.IKSolver(model, [[base], [push]], [*joint_limits(model), speed, limit])
    margins = []
    for _ in range(200):
        result = solver.step(configuration, 0.01)
        configuration.integrate_inplace(result.velocity, 0.01)
        margins.append(limit.com_margin(configuration))
    assert min(margins) >= 0.02 - 1e-4  # first order: a small linearisation error at most
    assert margins[-1] == pytest.approx(0.02, abs=1e-3)  # pressed against the margin
    free = qpik.IKSolver(model, [[base], [push]], [*joint_limits(model), speed])
    configuration.update(model.qpos0)
    for _ in range(200):
        configuration.integrate_inplace(free.step(configuration, 0.01).velocity, 0.01)
    assert limit.com_margin(configuration) < 0  # without the limit the CoM leaves


def test_support_polygon_errors():
    model = mujoco.MjModel.from_xml_string(QUADRUPED)
    configuration = qpik.Configuration(model)
    with pytest.raises(qpik.UnknownFrame, match="foot_x"):
        SupportPolygonLimit(model, ["foot_fl", "foot_x"])
    with pytest.raises(qpik.LimitDefinitionError, match="non-empty"):
        SupportPolygonLimit(model, [])
    with pytest.raises(qpik.LimitDefinitionError, match="margin"):
        SupportPolygonLimit(model, FEET, margin=-0.1)
    with pytest.raises(qpik.LimitDefinitionError, match="footprint"):
        SupportPolygonLimit(model, FEET, footprint=[[0.0, 0.0, 0.0]])
    with pytest.raises(qpik.InvalidInput, match="span no area"):
        SupportPolygonLimit(model, ["foot_fl", "foot_fr"]).compute_qp_inequalities(
            configuration, 0.01
        )
    # Two feet with a sole each span an area.
    two = SupportPolygonLimit(
        model, ["foot_fl", "foot_hr"], footprint=[[0.05, 0.02], [-0.05, -0.02], [0.05, -0.02]]
    )
    assert len(two.hull(configuration)[0]) >= 4


@requires_erd
def test_talos_half_sitting_com_is_inside_its_feet():
    model = _talos()
    configuration = qpik.Configuration(model, model.key("half_sitting").qpos)
    sole = [[0.1, 0.05], [0.1, -0.05], [-0.1, 0.05], [-0.1, -0.05]]
    limit = SupportPolygonLimit(model, ["left_sole_link", "right_sole_link"], footprint=sole)
    margin = limit.com_margin(configuration)
    # Feet 0.17 m apart, soles 0.2 x 0.1 m: the CoM sits near the middle of that rectangle.
    assert 0.04 < margin < 0.14


def test_a_support_polygon_far_from_the_com_changes_no_bit_of_the_step():
    # The CoM near the middle of the feet and steps of at most 0.01 rad: no row of the
    # polygon can bind within the step's box, so the cascade leaves them all out
    # (core::rows_in_reach); the steps are bitwise those without the limit.
    model, configuration = _quadruped()
    speed = mink.VelocityLimit(model, {"yaw": 1.0, "pitch": 1.0})  # [rad/s]
    levels = [[mink.DofFreezingTask(model, dof_indices=list(range(6)))], [ComTask(cost=1.0)]]
    levels[1][0].set_target([0.05, 0.02, 0.0])
    with_limit = qpik.IKSolver(model, levels, [*joint_limits(model), speed,
                                               SupportPolygonLimit(model, FEET, margin=0.02)])  # fmt: skip
    without = qpik.IKSolver(model, levels, [*joint_limits(model), speed])
    other = qpik.Configuration(model, configuration.q)
    for _ in range(30):
        a, b = with_limit.step(configuration, 0.01), without.step(other, 0.01)
        assert a.velocity.tobytes() == b.velocity.tobytes()
        assert a.status == b.status and a.iterations == b.iterations
        assert not any("SupportPolygon" in name for name in a.active_limits)
        configuration.integrate_inplace(a.velocity, 0.01)
        other.integrate_inplace(b.velocity, 0.01)
