"""Invariants shared by the property tests (tests/*/test_properties_*.py, issue 13).

Every public entry point, on any input, either raises a :class:`qpik.QpikError` or returns
a valid result: finite numbers, joints within their limits, ``converged`` only when an
independent forward kinematics (MuJoCo on a fresh ``MjData``) agrees within tolerance, and
the same answer bit for bit for the same input and seed.

The hypothesis settings are derandomized, with fixed small example counts and no example
database, so that the default test run is fast and always runs the same examples.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import os

import mujoco
import numpy as np
from hypothesis import HealthCheck, Phase, event, settings
from hypothesis import strategies as st

import qpik

ROBOTS = ("planar_2r", "planar_4r", "panda", "ur5e")


def props(max_examples: int) -> settings:
    """Hypothesis settings of the property tests: derandomized, ``max_examples`` cases."""
    return settings(
        max_examples=max_examples,
        derandomize=True,
        deadline=None,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
        print_blob=True,
        # no shrinking by default (it can take minutes on a failure); QPIK_PROPS_SHRINK=1
        # turns it on to find the smallest failing example
        phases=(Phase.explicit, Phase.reuse, Phase.generate)
        + ((Phase.shrink,) if os.environ.get("QPIK_PROPS_SHRINK") else ()),
        report_multiple_bugs=False,
    )


#: Floats from every corner: NaN, infinities, subnormals, huge and tiny magnitudes.
any_float = st.one_of(
    st.sampled_from(
        [0.0, -0.0, 1.0, -1.0, 0.5, 1e-300, 5e-324, 1e300, -1e300, math.nan, math.inf, -math.inf]
    ),
    st.floats(allow_nan=True, allow_infinity=True),
)
#: Things that are not numbers, but that callers pass anyway.
not_a_number = st.sampled_from([None, "1", "x", [1.0], (1.0, 2.0), {}, True, object()])


def load(robot: str) -> mujoco.MjModel:
    return qpik.load_robot(robot)


def limits_of(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """Lower / upper ``(nq,)`` of the limited hinge and slide joints, read from the model
    itself (inf elsewhere)."""
    lower = np.full(model.nq, -np.inf)
    upper = np.full(model.nq, np.inf)
    for j in range(model.njnt):
        if model.jnt_limited[j] and model.jnt_type[j] in (
            mujoco.mjtJoint.mjJNT_HINGE,
            mujoco.mjtJoint.mjJNT_SLIDE,
        ):
            adr = model.jnt_qposadr[j]
            lower[adr], upper[adr] = model.jnt_range[j]
    return lower, upper


def q_from_unit(model: mujoco.MjModel, unit) -> np.ndarray:
    """A configuration within the limits from numbers in [0, 1] (one per qpos)."""
    lower, upper = limits_of(model)
    lo = np.where(np.isfinite(lower), lower, -np.pi)
    hi = np.where(np.isfinite(upper), upper, np.pi)
    unit = np.resize(np.asarray(unit, dtype=float), model.nq)
    return lo + unit * (hi - lo)


def fk(model: mujoco.MjModel, q, frame: str = "ee", frame_type: str = "site"):
    """World position and rotation of a frame: MuJoCo on a fresh MjData (independent of
    qpik's configuration and caches)."""
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    if frame_type == "site":
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, frame)
        return data.site_xpos[i].copy(), data.site_xmat[i].reshape(3, 3).copy()
    i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, frame)
    return data.xpos[i].copy(), data.xmat[i].reshape(3, 3).copy()


def angle_between(r1: np.ndarray, r2: np.ndarray) -> float:
    cosine = (np.trace(r1 @ r2.T) - 1.0) / 2.0
    return float(math.acos(min(1.0, max(-1.0, cosine))))


#: Documented infinities: a level without singular values has ``sigma_min = inf``.
INF_ALLOWED = (".sigma_min",)


def assert_finite(value, where: str = "result", allow: tuple[str, ...] = ()) -> None:
    """Every number reachable from ``value`` (dataclass fields, arrays, lists, dicts) is
    finite, except at paths ending with one of ``allow``; under a path containing one
    of :data:`INF_ALLOWED` +inf is allowed (NaN never)."""
    if any(where.endswith(a) for a in allow):
        return
    if any(a in where for a in INF_ALLOWED):
        values = np.asarray(value, dtype=float) if not isinstance(value, dict) else None
        if values is not None:
            assert not np.any(np.isnan(values)), f"{where} = {value}"
            assert np.all(values > -np.inf), f"{where} = {value}"
            return
    if isinstance(value, (bool, str, bytes, type(None), enum.Enum)):
        return
    if isinstance(value, (int, float, np.integer, np.floating)):
        assert math.isfinite(float(value)), f"{where} = {value}"
        return
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "fc":
            assert np.all(np.isfinite(value)), f"{where} has non-finite entries: {value}"
        return
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        for field in dataclasses.fields(value):
            assert_finite(getattr(value, field.name), f"{where}.{field.name}", allow)
        return
    if isinstance(value, dict):
        for key, item in value.items():
            assert_finite(item, f"{where}[{key!r}]", allow)
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            assert_finite(item, f"{where}[{i}]", allow)


def assert_within_limits(model: mujoco.MjModel, q, where: str = "q", tol: float = 1e-9) -> None:
    lower, upper = limits_of(model)
    q = np.asarray(q)
    outside = np.flatnonzero((q < lower - tol) | (q > upper + tol))
    assert not outside.size, (
        f"{where}[{outside[0]}] = {q[outside[0]]!r} outside "
        f"[{lower[outside[0]]!r}, {upper[outside[0]]!r}]"
    )


def typed_or_value(call):
    """``(value, None)`` or ``(None, error)`` for a :class:`qpik.QpikError`; any other
    exception propagates (and fails the test)."""
    try:
        value = call()
    except qpik.QpikError as error:
        assert str(error), f"{type(error).__name__} without a message"
        event(f"typed error {type(error).__name__}")
        return None, error
    event("valid result")
    return value, None


def assert_converged_claim(
    model, result, frame: str, position, rotation, tol_position: float, tol_orientation: float
) -> None:
    """``result.converged`` implies the frame is within tolerance by independent FK."""
    if not result.converged:
        return
    p, r = fk(model, result.q, frame)
    error = float(np.linalg.norm(p - np.asarray(position, dtype=float)))
    assert error <= tol_position * (1 + 1e-9), f"converged with position error {error}"
    if rotation is not None:
        angle = angle_between(r, np.asarray(rotation, dtype=float))
        assert angle <= tol_orientation * (1 + 1e-6) + 1e-12, f"converged, angle {angle}"
