"""qpik.igm.restarts: the restart loop shared by qpik.solve's qp engine and the baselines,
tested on scripted attempts (no robot, no wall clock); and what restarts draw on a robot."""

from __future__ import annotations

import mujoco
import numpy as np

import qpik
from qpik.igm.restarts import Attempt, Clock, StallWindow, run_attempts
from qpik.igm.result import Reason
from qpik.model.chain import chain_qpos_mask
from qpik.model.robots import locate_robot


class _Clock(Clock):
    """A clock that runs out after ``ticks`` checks."""

    def __init__(self, ticks: int | None = None):
        super().__init__(0.0, None)
        self.ticks = ticks

    def out_of_time(self) -> bool:
        if self.ticks is None:
            return False
        self.ticks -= 1
        return self.ticks < 0


def _script(*outcomes):
    queue = list(outcomes)
    starts = []
    return (lambda: queue.pop(0)), (lambda: starts.append(1)), starts


def test_stops_at_the_first_converged_attempt_and_keeps_it():
    attempt, restart, starts = _script(
        Attempt(False, 5.0, Reason.STALLED, "a"),
        Attempt(True, 0.5, Reason.CONVERGED, "b"),
        Attempt(True, 0.1, Reason.CONVERGED, "c"),
    )
    best, reason, used = run_attempts(attempt, restart, 10, _Clock())
    assert (best.payload, reason, used, len(starts)) == ("b", Reason.CONVERGED, 1, 1)


def test_best_of_failed_attempts_and_the_last_reason():
    attempt, restart, _ = _script(
        Attempt(False, 5.0, Reason.STALLED, "a"),
        Attempt(False, 2.0, Reason.AT_LIMIT, "b"),
        Attempt(False, 3.0, Reason.SINGULAR, "c"),
    )
    best, reason, used = run_attempts(attempt, restart, 2, _Clock())
    assert (best.payload, reason, used) == ("b", Reason.SINGULAR, 2)


def test_a_start_to_beat_and_ties_keep_the_first():
    start = Attempt(False, 1.0, Reason.MAX_ITERS, "start")
    attempt, restart, _ = _script(Attempt(False, 1.0, Reason.STALLED, "a"))
    best, reason, used = run_attempts(attempt, restart, 0, _Clock(), start)
    assert (best.payload, reason, used) == ("start", Reason.STALLED, 0)


def test_time_budget_ends_the_loop_with_its_reason():
    attempt, restart, _ = _script(*(Attempt(False, 1.0, Reason.STALLED, i) for i in range(9)))
    best, reason, used = run_attempts(attempt, restart, 100, _Clock(ticks=2))
    assert (reason, used) == (Reason.TIME_BUDGET, 2)


def test_stall_window_counts_iterations_without_five_percent_progress():
    """The qp engine's stall rule is the compiled engine's (qpik.igm.kernels.PROGRESS)."""
    from qpik.igm.kernels import PROGRESS

    assert PROGRESS == 0.95
    stall = StallWindow(100.0, 2)
    assert stall.update(97.0) is False  # 3 %: no progress (1 of 2)
    assert stall.update(94.0) is False  # 6 %: progress, the window restarts at 94
    assert stall.update(90.0) is False  # within 5 % of 94 (1 of 2)
    assert stall.update(89.5) is True  # two in a row within 5 % of 94


def test_restarts_keep_joints_off_the_targets_chains_at_the_start():
    """Panda + a free cube (issue 22): restarts draw only the joints that move the target
    frame, on both engines; the cube's qpos (a pose that is not its qpos0) is untouched."""
    spec = mujoco.MjSpec.from_file(str(locate_robot("panda")))
    cube = spec.worldbody.add_body(name="cube", pos=[0.5, 0.2, 0.03])
    cube.add_freejoint(name="cube_free")
    cube.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.02] * 3, mass=0.1)
    model = spec.compile()
    moved = chain_qpos_mask(model, [("ee", "site")])
    assert moved[:7].all() and not moved[7:].any()
    q0 = np.concatenate(
        [qpik.Configuration(model).mid_q()[:7], [0.4, -0.1, 0.2, 0.6, 0.0, 0.8, 0.0]]
    )
    p, rotation = qpik.Configuration(model, q0).frame_pose("ee")
    far = (p + np.array([0.0, 0.0, 0.6]), rotation)  # out of reach: every restart runs
    for engine in ("compiled", "qp"):
        result = qpik.solve(
            model, {"ee": far}, q0=q0, restarts=3, seed=1, max_iters=20, engine=engine
        )
        assert result.engine == engine and result.restarts_used == 3
        # bitwise on both engines (the qp engine keeps the joints nothing moves)
        np.testing.assert_array_equal(result.q[7:], q0[7:])
        np.testing.assert_array_equal(result.path[:, 7:], np.tile(q0[7:], (len(result.path), 1)))
        assert np.abs(result.q[:7] - q0[:7]).max() > 1e-3  # the arm moved


_HINGE = """<mujoco><compiler angle="radian"/><worldbody><body name="link">
<joint name="j" type="hinge" axis="0 0 1" range="-1 1"/>
<geom type="capsule" fromto="0 0 0 1 0 0" size="0.05"/><site name="tip" pos="1 0 0"/>
</body></worldbody></mujoco>"""


def test_compiled_engine_ends_an_attempt_at_a_blocked_step():
    # A hinge limited to [-1, 1] rad and a target on its circle at 1.5 rad (within the reach
    # bound): the steps are the qp engine's until the joint nears its limit; there the
    # box leaves the step less than a tenth of the decrease it asks for (residual above
    # BLOCKED |b|) and the compiled engine ends the attempt at once, where the qp engine
    # waits for its stall window or a vanishing step.
    from qpik.igm.kernels import BLOCKED

    model = mujoco.MjModel.from_xml_string(_HINGE)
    target = np.array([np.cos(1.5), np.sin(1.5), 0.0])
    kwargs = dict(restarts=0, stall_window=1000, max_iters=100, seed=0)
    compiled = qpik.solve(model, {"tip": target}, engine="compiled", **kwargs)
    reference = qpik.solve(model, {"tip": target}, engine="qp", **kwargs)
    assert compiled.reason == reference.reason == Reason.AT_LIMIT
    k = len(compiled.path)
    assert compiled.iterations == k  # the blocked step is counted, not taken
    assert reference.iterations > compiled.iterations
    np.testing.assert_allclose(compiled.path, reference.path[:k], atol=1e-9, rtol=0)
    # The blocked step is the reference's k-th: residual above BLOCKED times what it asked.
    gain = min(1.0, 0.2 / compiled.error_history[-1][0])
    asked = gain * compiled.error_history[-1][0]
    assert reference.residual_history[k - 1][0] > BLOCKED * asked
    assert all(
        r[0] <= BLOCKED * min(1.0, 0.2 / e[0]) * e[0]
        for r, e in zip(compiled.residual_history, compiled.error_history)
    )
