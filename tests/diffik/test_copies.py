"""Copies and pickles of a solver: ``copy.copy``, ``copy.deepcopy`` and ``pickle`` give a
solver that steps on its own tasks by the compiled step (its plan made again from them), bit
for bit as a new solver built from them, and leaves the original as it was. Before, a deep
copy shared the original's plan (bound to the original's tasks) and its model was copied,
so that every step of the copy took the QP path (20 times slower), and a pickle or a deep
copy of a solver whose backend had made an OSQP workspace raised an untyped ``TypeError``."""

from __future__ import annotations

import copy
import pickle

import mink
import numpy as np
import pytest

import qpik
from qpik.core import HierarchyProblem, HierarchySolver, Level
from qpik.tasks import ComTask, FrameTask, PostureTask

DT = 0.01


def _pickled(obj):
    return pickle.loads(pickle.dumps(obj))


COPIES = {"copy": copy.copy, "deepcopy": copy.deepcopy, "pickle": _pickled}


def _panda(com: bool = False):
    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model, model.key_qpos[0])
    frame = FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0)
    start = configuration.get_transform_frame_to_world("ee", "site")
    frame.set_target(start.multiply(mink.SE3.from_translation(np.array([0.05, 0.0, 0.0]))))
    posture = PostureTask(model, 0.1)
    posture.set_target(configuration.q)
    levels = [[frame], [posture]]
    if com:
        centre = ComTask(1.0)
        centre.set_target_from_configuration(configuration)
        levels.insert(1, [centre])
    limits = [mink.ConfigurationLimit(model), mink.VelocityLimit(model, {"joint1": 1.0})]
    return model, configuration, qpik.IKSolver(model, levels, limits), start


def _fresh(solver: qpik.IKSolver, configuration, dt: float = DT) -> np.ndarray:
    return (
        qpik.IKSolver(solver.model, solver.levels, solver.limits).step(configuration, dt).velocity
    )


@pytest.mark.parametrize("com", [False, True], ids=["frame+posture", "frame+com+posture"])
@pytest.mark.parametrize("how", list(COPIES))
def test_copy_steps_on_its_own_tasks_by_the_compiled_step(how, com):
    model, configuration, solver, start = _panda(com)
    before = solver.step(configuration, DT).velocity.copy()
    twin = COPIES[how](solver)
    assert twin._plan is not None and twin._plan is not solver._plan
    if how == "pickle":  # (a model of its own: configurations are built on it)
        assert twin.model is not model
        twin_configuration = qpik.Configuration(twin.model, configuration.q)
    else:  # (the same model, shared: the configurations built on it serve both)
        assert twin.model is model
        twin_configuration = configuration
    assert (twin.levels[0][0] is solver.levels[0][0]) == (how == "copy")
    rng = np.random.default_rng(3)
    for _ in range(4):  # the two stepped in turn, each with targets of its own
        for each, c in ((solver, configuration), (twin, twin_configuration)):
            offset = mink.SE3.from_translation(rng.normal(scale=0.05, size=3))
            each.levels[0][0].set_target(start.multiply(offset))
            q = model.key_qpos[0] + rng.normal(scale=0.05, size=model.nq)
            c.update(q)
            velocity = each.step(c, DT).velocity
            np.testing.assert_array_equal(velocity, _fresh(each, c))
            # by the compiled step, not the QP path
            compiled = each.compiled_velocity(c, DT)
            assert compiled is not None
            np.testing.assert_array_equal(compiled[0], velocity)
    # the original, back at its first state, answers as it did
    if how != "copy":  # (a shallow copy shares the tasks, whose targets moved)
        solver.levels[0][0].set_target(
            start.multiply(mink.SE3.from_translation(np.array([0.05, 0.0, 0.0])))
        )
        configuration.update(model.key_qpos[0])
        np.testing.assert_array_equal(solver.step(configuration, DT).velocity, before)


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_copy_of_a_solver_with_an_osqp_workspace(how):
    pytest.importorskip("osqp")
    model, configuration, solver, start = _panda()
    solver.step(configuration, DT)
    solver._core.solver = "osqp"  # (the core's setting: its backend then keeps a workspace)
    far = start.multiply(mink.SE3.from_translation(np.array([0.5, 0.5, 0.5])))
    solver.levels[0][0].set_target(far)
    velocity = solver.step(configuration, DT).velocity
    assert solver._core._workspaces  # (an OSQP workspace was made: it does not pickle)
    twin = COPIES[how](solver)
    assert twin._core.solver == "osqp" and not twin._core._workspaces
    c = configuration if how == "deepcopy" else qpik.Configuration(twin.model, configuration.q)
    np.testing.assert_array_equal(twin.step(c, DT).velocity, velocity)


@pytest.mark.parametrize("how", list(COPIES))
def test_hierarchy_solver_copies(how):
    pytest.importorskip("osqp")
    rng = np.random.default_rng(0)
    A0, A1 = rng.normal(size=(2, 5)), rng.normal(size=(3, 5))
    problem = HierarchyProblem(
        [Level(A0, rng.normal(size=2)), Level(A1, 10 * rng.normal(size=3))],
        lb=-0.3 * np.ones(5),
        ub=0.3 * np.ones(5),
        G=np.zeros((0, 5)),
        h=np.zeros(0),
    )
    solver = HierarchySolver("osqp", warm_start=True)
    first = solver.solve(problem)
    twin = COPIES[how](solver)
    assert twin.solver == "osqp" and twin.warm_start
    assert twin.settings_version != solver.settings_version
    np.testing.assert_array_equal(twin.solve(problem).x, HierarchySolver("osqp").solve(problem).x)
    np.testing.assert_array_equal(solver.solve(problem).x, first.x)
