"""Shared fixtures: bundled robots and seeded random generators."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import qpik


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


@pytest.fixture(params=qpik.list_robots())
def bundled_robot(request) -> str:
    return request.param


@pytest.fixture
def pool_workers(monkeypatch) -> list:
    """The ``max_workers`` of every process pool solve_many starts, in order (the pool
    still runs: the recorder only watches its construction)."""
    import qpik.batch.pool as batch

    started: list = []

    class Recorder(batch.ProcessPoolExecutor):
        def __init__(self, *args, **kwargs):
            started.append(kwargs.get("max_workers"))
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(batch, "ProcessPoolExecutor", Recorder)
    return started


def warm_solves_give_cold_bits(problems: list, rounds: int = 1) -> int:
    """Each problem solved cold, then warm-started after the others (each order, twice in a
    row) by one warm solver per damping law (none, the default): the same answers and active
    sets bit for bit. Returns how many cold answers have no active row (summed over laws)."""
    from qpik.core import DampingLaw, HierarchySolver

    free = 0
    for law in (None, DampingLaw()):
        cold = [HierarchySolver(damping_law=law).solve(p) for p in problems]
        free += sum(not r.active.any() for r in cold)
        warm = HierarchySolver(damping_law=law, warm_start=True)
        for _round in range(rounds):
            for order in (range(len(problems)), reversed(range(len(problems)))):
                for i in order:
                    for _ in range(2):
                        result = warm.solve(problems[i])
                        assert result.ok, (i, result.status)
                        np.testing.assert_array_equal(result.x, cold[i].x, err_msg=str(i))
                        np.testing.assert_array_equal(result.active, cold[i].active)
    return free


def configuration_of(name: str, q=None) -> qpik.Configuration:
    """A fresh configuration of a bundled robot (fresh per test: tests never share state)."""
    return qpik.Configuration(qpik.load_robot(name), q)


def central_difference(configuration: qpik.Configuration, function, h: float = 1e-6):
    """d function(configuration) / dq by central differences along each tangent direction
    (columns of the result); ``function`` maps the configuration to an array, or to a
    ``(position, rotation)`` pair whose rotation part is differentiated through the log of
    the relative rotation (world frame). ``configuration`` ends where it started."""
    from scipy.spatial.transform import Rotation

    q = configuration.q
    model = configuration.model
    columns = []
    for i in range(model.nv):
        dq = np.zeros(model.nv)
        dq[i] = h
        values = []
        for sign in (1.0, -1.0):
            shifted = q.copy()
            mujoco.mj_integratePos(model, shifted, sign * dq, 1.0)
            configuration.update(shifted)
            values.append(function(configuration))
        plus, minus = values
        if isinstance(plus, tuple):
            linear = (plus[0] - minus[0]) / (2 * h)
            angular = Rotation.from_matrix(plus[1] @ minus[1].T).as_rotvec() / (2 * h)
            columns.append(np.concatenate([linear, angular]))
        else:
            columns.append((plus - minus) / (2 * h))
    configuration.update(q)
    return np.stack(columns, axis=1)


#: A head on a limited ball joint (range 60 degrees): tests of ball-joint limits.
BALL = """
<mujoco>
  <worldbody>
    <body name="base">
      <body name="head" pos="0 0 0.35">
        <joint name="neck" type="ball" range="0 60" limited="true"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.05" mass="1"/>
        <site name="eye" pos="0 0 0.3"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


#: a small floating robot (a free joint, two hinges, site "ee"): its free joint makes the
#: limits mink's rows (not boxes)
FLOATING = """
<mujoco>
  <worldbody>
    <body name="base">
      <freejoint/>
      <geom type="box" size="0.1 0.1 0.1" mass="1"/>
      <body name="link1" pos="0 0 0.1">
        <joint name="j1" type="hinge" axis="0 1 0" range="-1 1"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.03" mass="0.5"/>
        <body name="link2" pos="0 0 0.3">
          <joint name="j2" type="hinge" axis="0 1 0" range="-1.5 1.5"/>
          <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.03" mass="0.5"/>
          <site name="ee" pos="0 0 0.3"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def has_erd() -> bool:
    """Whether example-robot-data (the robots extra) is installed."""
    import qpik

    try:
        qpik.robots.erd_robots_folder()
    except qpik.QpikError:
        return False
    return True


#: Skips a test where example-robot-data (the robots extra) is not installed.
requires_erd = pytest.mark.skipif(not has_erd(), reason="needs qpik[robots]")


def load_or_skip(name: str, **keywords):
    """``qpik.load_robot(name, **keywords)`` with its warnings silenced (an
    example-robot-data URDF's dropped collision meshes); the test is skipped where the robot
    does not load here."""
    import warnings

    import pytest

    import qpik

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # dropped collision meshes
        try:
            return qpik.load_robot(name, **keywords)
        except qpik.QpikError as exc:
            pytest.skip(f"{name} does not load here: {exc}")


def three_link_arm(c1_range: str = "-2 2") -> str:
    """The MJCF body ``a`` that several tests' models share: hinges ``a1`` (z), ``b1`` and
    ``c1`` (y; ``c1`` in ``c1_range`` [rad]), a slide ``c2`` (x) and the site ``tip``."""
    return f"""
    <body name="a">
      <joint name="a1" axis="0 0 1" range="-2 2"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/>
      <body name="b" pos="0.3 0 0">
        <joint name="b1" axis="0 1 0" range="-2 2"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/>
        <body name="c" pos="0.3 0 0">
          <joint name="c1" axis="0 1 0" range="{c1_range}"/>
          <joint name="c2" type="slide" axis="1 0 0" range="-0.1 0.1"/>
          <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02"/>
          <site name="tip" pos="0.2 0 0"/>
        </body>
      </body>
    </body>
"""
