"""Limits given to an IKSolver that do not fit it: a limit built for another robot's model
(LimitDefinitionError at construction, where its ranges were applied to the solver's joints
before), and a limit whose own rows are not finite or not a Constraint at all
(LimitDefinitionError naming it at the step, where NaN rows were dropped and None or
strings raised AttributeError from inside the plan)."""

from __future__ import annotations

import mink
import numpy as np
import pytest

import qpik
from qpik.errors import LimitDefinitionError
from qpik.tasks import FrameTask, PostureTask

DT = 0.01


def _panda():
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    posture = PostureTask(model, cost=1.0)
    target = model.key_qpos[0].copy()
    target[0] = 5.0  # beyond joint1's range [-2.8973, 2.8973]
    posture.set_target(target)
    return model, configuration, posture


def test_a_limit_built_for_another_model_is_refused():
    """A position, velocity or collision limit built from another robot's model (a UR5e's
    for a Panda solver, a Panda's for a UR5e's) is refused when the solver is built; a limit
    built from a second load of the solver's own robot file is the same robot (same
    answer as the solver's own model's)."""
    model, configuration, posture = _panda()
    ur5e = qpik.load_robot("ur5e")
    for limit in (
        qpik.limits.ConfigurationLimit(ur5e),
        mink.ConfigurationLimit(ur5e),
        qpik.limits.model_collision_limit(ur5e),
    ):
        with pytest.raises(LimitDefinitionError, match="another model"):
            qpik.IKSolver(model, [[posture]], [limit])
    with pytest.raises(LimitDefinitionError, match="another model"):
        qpik.IKSolver(
            ur5e, [[PostureTask(ur5e, cost=1.0)]], [qpik.limits.velocity_limit_from_model(model)]
        )
    same_file = qpik.load_robot("panda")
    ours = qpik.IKSolver(model, [[posture]], [qpik.limits.ConfigurationLimit(model)])
    theirs = qpik.IKSolver(model, [[posture]], [qpik.limits.ConfigurationLimit(same_file)])
    np.testing.assert_array_equal(
        ours.step(configuration, DT).velocity, theirs.step(configuration, DT).velocity
    )
    for _ in range(300):  # the Panda's own range holds
        configuration.integrate_inplace(theirs.step(configuration, DT).velocity, DT)
    assert configuration.q[0] <= model.jnt_range[0][1] + 1e-9


class _Rows(mink.Limit):
    def __init__(self, constraint):
        self.constraint = constraint

    def compute_qp_inequalities(self, configuration, dt):
        return self.constraint


def _frame_solver(limits, **keywords):
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    ee = FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    p, R = configuration.frame_pose("ee")
    ee.set_target(mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(R), p + [0.05, 0, 0]))
    return qpik.IKSolver(model, [[ee]], limits, **keywords), configuration


@pytest.mark.parametrize("solver", ["auto", "osqp"])
@pytest.mark.parametrize(
    ("G", "h", "match"),
    [
        (np.eye(7)[:1], np.array([np.nan]), "not finite"),
        (np.full((1, 7), np.nan), np.array([0.0]), "not finite"),
        (np.r_[[np.inf], np.zeros(6)][None], np.array([0.0]), "not finite"),
        (np.eye(7)[:1], np.array([-np.inf]), "not finite"),
        (np.eye(7)[:1] + np.eye(7)[1:2], np.array([-np.inf]), "not finite"),
        ("a", "b", "arrays of numbers"),
        (None, np.array([1.0]), "not finite"),
    ],
)
def test_a_limit_whose_rows_are_not_finite_is_refused(solver, G, h, match):
    """A limit whose compute_qp_inequalities gives NaN (in h or G), an infinite G entry,
    h = -inf or rows that are not numbers: LimitDefinitionError naming the limit (the step
    answered as if the limit were absent before, raised AttributeError, or, for -inf,
    reported numerical_failure)."""
    ik, configuration = _frame_solver([_Rows(mink.limits.Constraint(G=G, h=h))], solver=solver)
    with pytest.raises(LimitDefinitionError, match=f"_Rows.*{match}"):
        ik.step(configuration, DT)


@pytest.mark.parametrize("returned", [None, (np.eye(7), np.ones(7)), "rows"])
def test_a_limit_that_returns_no_constraint_is_refused(returned):
    """A limit whose compute_qp_inequalities returns no Constraint (None, a tuple, a
    string): LimitDefinitionError naming it (AttributeError 'inactive' before)."""
    ik, configuration = _frame_solver([_Rows(returned)])
    with pytest.raises(LimitDefinitionError, match="_Rows: compute_qp_inequalities returned"):
        ik.step(configuration, DT)


def test_rows_that_never_bind_and_inactive_limits_are_answered():
    """What a limit may give: h = +inf (a row that never binds, as mink's collision rows out
    of range), an inactive Constraint (G and h None), rows as lists: the step answers as
    without the limit (a finite row that does not bind)."""
    free, configuration = _frame_solver([])
    reference = free.step(configuration, DT).velocity
    for constraint in (
        mink.limits.Constraint(G=np.eye(7)[:2], h=np.array([np.inf, np.inf])),
        mink.limits.Constraint(),
        mink.limits.Constraint(G=[[0.0] * 6 + [1.0]], h=[1e3]),
    ):
        ik, configuration = _frame_solver([_Rows(constraint)])
        np.testing.assert_allclose(ik.step(configuration, DT).velocity, reference, atol=1e-12)


def test_a_position_limit_of_a_model_with_other_joint_names_says_which():
    """The same robot with two joint names swapped: its position limit is refused, and the
    message names the joint that differs (not two identical size summaries)."""
    import mujoco

    model = qpik.load_robot("ur5e")
    path = qpik.robots.robot_path("ur5e")
    text = path.read_text()
    for a, b in (('"wrist_3_joint"', '"TMP"'), ('"shoulder_pan_joint"', '"wrist_3_joint"'),
                 ('"TMP"', '"shoulder_pan_joint"')):  # fmt: skip
        text = text.replace(a, b)
    swapped = mujoco.MjModel.from_xml_string(text, {})
    posture = PostureTask(model, cost=1.0)
    with pytest.raises(LimitDefinitionError, match="joint 'wrist_3_joint' where the solver"):
        qpik.IKSolver(model, [[posture]], [qpik.limits.ConfigurationLimit(swapped)])


def test_a_model_with_nan_geometry_is_named_when_the_solver_is_built():
    model = qpik.load_robot("panda")
    model.body_pos[2] = np.nan  # (an array edited in place)
    with pytest.raises(qpik.errors.InvalidInput, match="model: the model's body_pos of body"):
        qpik.IKSolver(model, [[PostureTask(model, cost=1.0)]])


def test_a_step_result_copies_and_pickles_with_every_field():
    """A lean step's result (its fields read from the solver's live arrays on first access)
    pickles and deep-copies with every field, equal to the original's, and keeps no tie to
    the solver (was an untyped TypeError: 'cannot pickle Kernel object')."""
    import copy
    import pickle

    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    posture = PostureTask(model, cost=0.1)
    posture.set_target(model.key_qpos[0] * 0.9)
    solver = qpik.IKSolver(model, [[posture]], qpik.limits.joint_limits(model))
    step = solver.step(configuration, 0.01)
    for twin in (pickle.loads(pickle.dumps(step)), copy.deepcopy(step)):
        np.testing.assert_array_equal(twin.velocity, step.velocity)
        np.testing.assert_array_equal(twin.displacement, step.displacement)
        assert twin.status == step.status and twin.certificate == step.certificate
        assert twin.active_limits == step.active_limits
        assert twin.residuals == step.residuals and twin.sigma_min == step.sigma_min


def test_the_engine_counts_bad_entries_as_numpy_does(rng):
    # constraint_rows counts a limit's bad entries in the engine (C-ordered float64 rows):
    # G's entries that are not finite, h's NaN and -inf, as NumPy's isfinite and h > -inf,
    # and the fewest nonzero entries of a row (NaN and inf count as nonzero).
    from qpik._engine import limits as engine

    for _ in range(200):
        p, n = int(rng.integers(0, 5)), int(rng.integers(1, 8))
        G, h = rng.normal(size=(p, n)), rng.normal(size=p)
        for a in (G, h):
            a[rng.random(a.shape) < 0.1] = rng.choice([np.nan, np.inf, -np.inf])
        G[rng.random(G.shape) < 0.3] = 0.0
        fewest = int(np.count_nonzero(G, axis=1).min()) if p else n
        expected = (np.count_nonzero(~np.isfinite(G)), np.count_nonzero(~(h > -np.inf)), fewest)
        assert engine.row_stats(G, h, 1e-12)[:3] == expected


def test_a_user_limit_s_negligible_row_is_left_out_and_its_arrays_kept():
    # A user limit's row of entries at most NEGLIGIBLE_ROW (h = 0) is a zero row, met and
    # left out: the step is bitwise the one with only its other row (the engine counts it,
    # NumPy flushes it); the limit's own arrays are never written.
    G = np.zeros((2, 7))
    G[0, :2] = 1.0, 1.0
    G[1, 2:4] = 1e-13, -1e-13
    h = np.array([0.01, 0.0])
    G0, h0 = G.copy(), h.copy()
    ik, configuration = _frame_solver([_Rows(mink.limits.Constraint(G=G, h=h))])
    step = ik.step(configuration, DT)
    bare, _ = _frame_solver([_Rows(mink.limits.Constraint(G=G0[:1].copy(), h=h0[:1].copy()))])
    np.testing.assert_array_equal(step.velocity, bare.step(configuration, DT).velocity)
    np.testing.assert_array_equal(G, G0)
    np.testing.assert_array_equal(h, h0)
