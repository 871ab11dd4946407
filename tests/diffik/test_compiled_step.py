"""The compiled step's own parts (qpik.diffik.compiled): linear couplings computed by the
kernel (task kind LINEAR), the MjData arrays attached to the kernel once, and the
StepResult read lazily from the kernel's info; each against the QP path or the eager
result, bit for bit."""

from __future__ import annotations

import mink
import mujoco
import numpy as np
import pytest
from conftest import three_link_arm

import qpik
from qpik.diffik.result import StepResult
from qpik.tasks import CouplingTask, FrameTask, PostureTask

DT = 0.01

#: A chain with linear couplings only: a mimic-like joint equality (degree 1, with an
#: offset) and a fixed-tendon equality of degree 1; the kernel computes their level.
LINEAR = (
    """
<mujoco>
  <worldbody>
"""
    + three_link_arm()
    + """    <body name="d" pos="0 0.6 0">
      <joint name="d1" axis="0 0 1" range="-1 1"/>
      <joint name="d2" axis="0 1 0" range="-1 1"/>
      <geom type="capsule" fromto="0 0 0 0 -0.3 0" size="0.02"/>
    </body>
  </worldbody>
  <tendon>
    <fixed name="t1"><joint joint="a1" coef="0.5"/><joint joint="d1" coef="-1"/></fixed>
    <fixed name="t2"><joint joint="d2" coef="2"/><joint joint="c2" coef="0.3"/></fixed>
  </tendon>
  <equality>
    <joint name="mimic" joint1="c1" joint2="b1" polycoef="0.05 -0.7 0 0 0"/>
    <tendon name="ten" tendon1="t1" tendon2="t2" polycoef="0.01 0.7 0 0 0"/>
  </equality>
</mujoco>
"""
)


@pytest.fixture(scope="module")
def linear():
    model = mujoco.MjModel.from_xml_string(LINEAR)
    return model, qpik.Configuration(model)


def _random(rng, model, configuration, frame, posture) -> None:
    """A random configuration within the limits (its couplings broken a little), random
    targets."""
    q = rng.uniform(-0.8, 0.8, model.nq) * np.array([1, 1, 1, 0.1, 1, 1])
    configuration.update(np.clip(q, configuration.lower, configuration.upper))
    position = configuration.frame_pose("tip", "site")[0] + rng.uniform(-0.2, 0.2, 3)
    frame.set_target(mink.SE3.from_translation(position))
    posture.set_target(configuration.q + rng.uniform(-0.5, 0.5, model.nq))


def test_linear_couplings_take_the_kernel_and_equal_the_qp_path_bitwise(linear):
    """Linear couplings (degree-1 joint and tendon equalities with offsets): the plan's
    kernel computes their level (no rows supplied from Python), and each step equals the
    QP path's bit for bit (velocity, coupling residual, statuses, certificates); the
    couplings' residual after the step is the level's."""
    model, configuration = linear
    rng = np.random.default_rng(20)
    frame = FrameTask("tip", "site", position_cost=1.0, orientation_cost=0.0)
    posture = PostureTask(model, 0.1)
    limits = [mink.ConfigurationLimit(model), mink.VelocityLimit(model, {"a1": 2.0, "d1": 1.0})]
    solver = qpik.IKSolver(model, [[frame], [posture]], limits)
    assert solver._plan is not None and not solver._plan.rows_tasks
    assert [type(task) for task, _, _ in solver._plan.linears] == [CouplingTask]
    coupling = solver._plan.linears[0][0]
    for _ in range(30):
        _random(rng, model, configuration, frame, posture)
        compiled = solver.step(configuration, DT)
        general = StepResult.of(solver._qp_step(configuration, DT), 0.0, True)
        assert np.array_equal(compiled.velocity, general.velocity)
        assert compiled.coupling_residual == general.coupling_residual
        assert compiled.status == general.status
        assert compiled.certificate == general.certificate
        assert compiled.residuals == general.residuals
        # Linear couplings on hinge/slide joints: r(q + dq) = r(q) + J dq, the level's
        # residual (cost 1, gain 1): zero unless the limits hold a coupled joint back.
        q = configuration.integrate(compiled.velocity, DT)
        after = float(np.linalg.norm(coupling.couplings.residual(q)))
        assert abs(after - compiled.coupling_residual) <= 1e-12


def test_linear_residual_is_the_couplings_own(linear):
    """CouplingTask's compiled residual (one summation order over qpos) equals the
    couplings' own residual to round-off, and its rows are mink's weighting of it."""
    model, configuration = linear
    task = CouplingTask(model, cost=2.0, gain=0.5)
    assert task.linear_form is not None
    rng = np.random.default_rng(3)
    for _ in range(20):
        configuration.update(rng.uniform(-1, 1, model.nq) * 0.5)
        error = task.compute_error(configuration)
        np.testing.assert_allclose(
            error, task.couplings.residual(configuration.q), rtol=0, atol=1e-15
        )
        jacobian, b, mu = task.compute_qp_residual(configuration)
        assert np.array_equal(b, task.cost * (-task.gain * error)) and mu == 0.0
        assert np.array_equal(jacobian, task.cost[:, None] * task.compute_jacobian(configuration))


def test_a_nonlinear_coupling_still_supplies_its_rows():
    """A polynomial coupling has no linear form: its rows come from its own methods."""
    model = mujoco.MjModel.from_xml_string(LINEAR.replace('"0.05 -0.7 0 0 0"', '"0 1 0.2 0 0"'))
    assert CouplingTask(model).linear_form is None
    solver = qpik.IKSolver(model, [[PostureTask(model, 0.1)]], [mink.ConfigurationLimit(model)])
    assert solver._plan is not None and not solver._plan.linears
    assert [type(task) for task, _, _ in solver._plan.rows_tasks] == [CouplingTask]


def test_the_kernel_runs_only_on_attached_and_checked_arrays(linear):
    """Kernel.run needs an MjData attached first; attach checks the arrays' shapes; a
    step on another MjData attaches it (the answers follow the configuration's data)."""
    model, configuration = linear
    frame = FrameTask("tip", "site", position_cost=1.0, orientation_cost=0.0)
    posture = PostureTask(model, 0.1)
    solver = qpik.IKSolver(model, [[frame], [posture]], [mink.ConfigurationLimit(model)])
    plan = solver._plan
    assert plan is not None
    warm = np.zeros((plan.levels, model.nv), np.int8)
    with pytest.raises(ValueError, match="attach"):
        plan.kernel.run(plan.no_rows, plan.no_h, warm, True, 100)
    data = configuration.data
    arrays = (data.qpos, data.site_xpos, data.site_xmat, data.xpos, data.xmat, data.geom_xpos,
              data.geom_xmat, data.subtree_com)  # fmt: skip
    with pytest.raises(ValueError):
        plan.kernel.attach(data, data.qpos[:-1], *arrays[1:])
    with pytest.raises(ValueError):
        plan.kernel.attach(data, *arrays[:1], np.zeros((0, 3)), *arrays[2:])  # the tip site
    rng = np.random.default_rng(5)
    _random(rng, model, configuration, frame, posture)
    other = qpik.Configuration(model, configuration.q)
    first = solver.step(configuration, DT).velocity
    assert np.array_equal(solver.step(other, DT).velocity, first)
    other.update(np.clip(configuration.q + 0.1, configuration.lower, configuration.upper))
    assert not np.array_equal(solver.step(other, DT).velocity, first)
    assert np.array_equal(solver.step(configuration, DT).velocity, first)


def test_the_lazy_result_equals_the_eager_one(panda_model_and_configuration):
    """IKSolver.step's result (its per-level lists read from the kernel's info on first
    access) equals StepResult.of the compiled Solution of the same step, field by field;
    an unknown attribute still raises AttributeError."""
    model, configuration = panda_model_and_configuration
    frame = FrameTask("hand", "body", position_cost=1.0, orientation_cost=1.0)
    posture = PostureTask(model, 0.1)
    limits = [mink.ConfigurationLimit(model), qpik.limits.velocity_limit_from_model(model)]
    solver = qpik.IKSolver(model, [[frame], [posture]], limits, warm_start=False)
    rng = np.random.default_rng(9)
    for reach in (0.001, 0.5):
        q = np.clip(model.key_qpos[0] + rng.uniform(-0.5, 0.5, model.nq),
                    configuration.lower, configuration.upper)  # fmt: skip
        configuration.update(q)
        pose = configuration.get_transform_frame_to_world("hand", "body")
        frame.set_target(pose @ mink.SE3.exp(rng.normal(size=6) * reach))
        posture.set_target(q + rng.uniform(-1, 1, model.nq))
        lazy = solver.step(configuration, DT)
        solution = solver.compiled_solution(configuration, DT)
        assert solution is not None
        eager = StepResult.of(solution, lazy.solve_time)
        for name in ("velocity", "displacement"):
            assert np.array_equal(getattr(lazy, name), getattr(eager, name))
        for name in ("residuals", "sigma_min", "damping", "status", "iterations", "certificate"):
            assert getattr(lazy, name) == getattr(eager, name), name
        assert lazy.coupling_residual is None and lazy.active_limits == eager.active_limits
    with pytest.raises(AttributeError):
        lazy.no_such_field  # noqa: B018


@pytest.fixture(scope="module")
def panda_model_and_configuration():
    model = qpik.load_robot("panda")
    return model, qpik.Configuration(model)
