"""The methods of the IK success benchmark (:mod:`ik_bench`), each bound to a robot and a
frame: qpik (:func:`qpik.IKSession.solve`, and ``oneshot``: :func:`qpik.solve` called with
the model each time, no session), the lecture's IGM with the pseudoinverse or damped
least squares (:mod:`qpik.igm.baselines`), mink and pink. mink and pink run their
``solve_ik`` as the step rule of the same restart loop (:func:`qpik.igm.baselines.igm`), so the
comparison isolates the step rule; pink runs on the robot as pinocchio loads it
(:class:`PinocchioRobot` maps the joint orders and checks the two models agree).

The whole-IK peers (issue 20), each with its own restarts and stopping rule, built from the
same URDF file as qpik's ``erd:`` robot (:class:`UrdfChain`: the chain from the URDF's root
link to the tool frame, its joints mapped to MuJoCo's by name, forward kinematics checked to
agree with MuJoCo's to 1e-9 at four configurations):

* ``tracik``: TRAC-IK (``pytracik``, C++: KDL's Newton and SQP run concurrently, random
  restarts), solve type Speed, its timeout the protocol's budget, its epsilon the protocol's
  tolerance (TRAC-IK's own per-axis check). pytracik 0.0.3 reads every joint limit of the
  URDF as 0 (its getters return zeros and every solve fails), so the limits are set from
  the model (the same URDF values; unlimited joints as TRAC-IK's continuous ones).
* ``rtb_lm``: the Robotics Toolbox's C++ ``ETS.ik_LM`` (Levenberg-Marquardt, method
  ``chan``, its defaults: 30 iterations a search, 100 searches, joint limits enforced), its
  residual tolerance ``E = 0.5 |e|^2 <= 0.5 tol^2`` (implies the per-axis and the norm
  criteria). It has no time budget: the harness judges its wall time.

Both skip (:class:`MethodUnavailable`) a robot that is not a URDF (the bundled MJCF ones),
or when their package is missing (``pip install -e '.[compare]'``).
"""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import mujoco
import numpy as np

from qpik import IKSession
from qpik import solve as qpik_solve
from qpik.errors import QpikError
from qpik.igm.baselines import damped_least_squares_igm, igm, pseudoinverse_igm
from qpik.model.configuration import Configuration, FrameType
from qpik.robots import locate_robot

#: Restarts allowed to every method: more than fit in the budget, so the budget binds.
RESTARTS = 100_000


@dataclass
class Outcome:
    """What a method returned for one target: its configuration, iterations (all attempts),
    restarts and its own reason for stopping."""

    q: np.ndarray
    iterations: int
    restarts: int
    reason: str


class Method(Protocol):
    """A method bound to a robot and frame: ``(position, rotation, q0, rng, budget) ->
    Outcome``."""

    def __call__(
        self,
        position: np.ndarray,
        rotation: np.ndarray,
        q0: np.ndarray,
        rng: np.random.Generator,
        budget: float,
    ) -> Outcome: ...


class MethodFactory(Protocol):
    """``make(model, frame, frame_type, robot=name, tol_position=.., tol_orientation=..) ->
    Method``: binds a method to a robot and the protocol's tolerances (what the method
    iterates to, [m] and [rad]); ``robot`` is the name the model was loaded from (methods
    that load the robot with another library need it). Raises :class:`MethodUnavailable`
    when the method cannot run on this robot here. Built by :func:`_method`."""

    def __call__(
        self,
        model: mujoco.MjModel,
        frame: str,
        frame_type: FrameType,
        *,
        robot: str | None,
        tol_position: float,
        tol_orientation: float,
    ) -> Method: ...


class MethodUnavailable(QpikError):
    """A method cannot run on a robot here (a package is missing, or its library cannot load
    the robot); the benchmark skips it on that robot and reports ``reason``."""

    def __init__(self, method: str, robot: str | None, reason: str):
        self.method = method
        self.robot = robot
        self.reason = reason
        super().__init__(f"{method} skipped on {robot}: {reason}")


def _qpik(model: mujoco.MjModel, frame: str, frame_type: FrameType, robot: str | None) -> dict:
    """qpik's own solve, on a session that reads the robot once (as a user would)."""
    session = IKSession(model)

    def solve(_configuration, frame, position, rotation, *, frame_type, **options):
        return session.solve({(frame, frame_type): (position, rotation)}, **options)

    return {"igm_function": solve}


def _in_restart_loop(
    model: mujoco.MjModel,
    frame: str,
    frame_type: FrameType,
    *,
    step: Callable | None = None,
    set_target: Callable[[np.ndarray, np.ndarray], None] | None = None,
    igm_function: Callable = igm,
    tol_position: float,
    tol_orientation: float,
) -> Method:
    """A method that runs ``step`` (a :data:`qpik.igm.baselines.StepRule`; ``None`` for an
    ``igm_function`` that has its own) in qpik's restart loop (:func:`qpik.igm.baselines.igm`,
    or an ``igm_function`` with its signature: qpik's own solve), after
    ``set_target(position, rotation)`` (for steps that hold a task of their own)."""
    configuration = Configuration(model)
    rule = () if step is None else (step,)

    def run(position, rotation, q0, rng, budget):
        if set_target is not None:
            set_target(position, rotation)
        result = igm_function(
            configuration,
            frame,
            position,
            rotation,
            *rule,
            frame_type=frame_type,
            q0=q0,
            time_budget=budget,
            restarts=RESTARTS,
            seed=rng,
            tol_position=tol_position,
            tol_orientation=tol_orientation,
        )
        return Outcome(result.q, result.iterations, result.restarts_used, result.reason)

    return run


def _method(parts: Callable[..., dict]) -> MethodFactory:
    """A :class:`MethodFactory` from ``parts(model, frame, frame_type, robot)``, which
    returns the keywords of :func:`_in_restart_loop` (``step``, ``set_target``,
    ``igm_function``): every method runs in the same restart loop."""

    def make(
        model: mujoco.MjModel,
        frame: str,
        frame_type: FrameType,
        *,
        robot: str | None = None,
        tol_position: float,
        tol_orientation: float,
    ) -> Method:
        return _in_restart_loop(
            model,
            frame,
            frame_type,
            tol_position=tol_position,
            tol_orientation=tol_orientation,
            **parts(model, frame, frame_type, robot),
        )

    return make


def _igm(igm_function: Callable) -> Callable[..., dict]:
    """The parts of a baseline loop of :mod:`qpik.igm.baselines` (its step is its own)."""
    return lambda model, frame, frame_type, robot: {"igm_function": igm_function}


def _mink(model: mujoco.MjModel, frame: str, frame_type: FrameType, robot: str | None) -> dict:
    import mink
    import qpsolvers

    backend = "daqp" if "daqp" in qpsolvers.available_solvers else "osqp"
    task = mink.FrameTask(
        frame, frame_type.value, position_cost=1.0, orientation_cost=1.0, lm_damping=1.0
    )
    limits = [mink.ConfigurationLimit(model)]

    def step(work, _J, _c):
        return mink.solve_ik(work, [task], 1.0, backend, damping=1e-3, limits=limits)

    def set_target(position, rotation):
        task.set_target(
            mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(rotation), position)
        )

    return {"step": step, "set_target": set_target}


@dataclass
class PinocchioRobot:
    """A robot loaded by pinocchio next to qpik's MuJoCo model of it, with the maps between
    the two joint orders (matched by joint name; pinocchio orders joints depth-first as it
    parses, MuJoCo as the file lists them).

    Attributes:
        model: the pinocchio model (kinematics only: no geometry).
        source: the file pinocchio loaded.
        frame: the pinocchio frame id of the benchmarked frame (same name as qpik's).
    """

    model: object  # pinocchio.Model (pinocchio is optional)
    source: str
    frame: int
    _mj_qpos: np.ndarray
    _pin_q: np.ndarray
    _circle: np.ndarray
    _mj_dof: np.ndarray
    _pin_v: np.ndarray

    def q_to_pinocchio(self, q: np.ndarray) -> np.ndarray:
        """A MuJoCo ``qpos`` ``(nq,)`` as a pinocchio configuration; a continuous joint
        (pinocchio's unbounded revolute, stored as ``(cos, sin)``) from its angle [rad]."""
        q_pin = np.zeros(self.model.nq)
        angle = q[self._mj_qpos]
        line = ~self._circle
        q_pin[self._pin_q[line]] = angle[line]
        q_pin[self._pin_q[self._circle]] = np.cos(angle[self._circle])
        q_pin[self._pin_q[self._circle] + 1] = np.sin(angle[self._circle])
        return q_pin

    def v_to_mujoco(self, v: np.ndarray) -> np.ndarray:
        """A pinocchio velocity ``(nv,)`` in MuJoCo's dof order."""
        v_mj = np.empty(self.model.nv)
        v_mj[self._mj_dof] = v[self._pin_v]
        return v_mj

    def v_to_pinocchio(self, v: np.ndarray) -> np.ndarray:
        """A MuJoCo velocity ``(nv,)`` in pinocchio's order."""
        v_pin = np.empty(self.model.nv)
        v_pin[self._pin_v] = v[self._mj_dof]
        return v_pin


def _pinocchio_source(robot: str) -> Path:
    """The file pinocchio should load for qpik robot name ``robot`` (qpik's resolver)."""
    return locate_robot(robot)


def pinocchio_robot(
    robot: str, model: mujoco.MjModel, frame: str, frame_type: FrameType | str = FrameType.SITE
) -> PinocchioRobot:
    """Load ``robot`` (a name :func:`qpik.load_robot` accepts, loaded as ``model``) with
    pinocchio: the same URDF file for ``erd:`` robots and ``.urdf`` paths
    (``buildModelFromUrdf``), the MJCF file for bundled robots and ``.xml`` paths
    (``buildModelFromMJCF``). Checks that both have the same 1-DoF joints (by name), the
    same position limits, and the same pose of ``frame`` at the mid-range and three random
    configurations (1e-9 m or rad); raises :class:`MethodUnavailable` saying which check
    failed, or why pinocchio could not load the file."""
    import pinocchio as pin

    def unavailable(reason: str) -> MethodUnavailable:
        return MethodUnavailable("pink", robot, reason)

    source, pin_model = _load_pinocchio(pin, robot, frame, unavailable)
    if FrameType.parse(frame_type) is FrameType.SITE:
        _place_site(pin, pin_model, model, frame, source.name)
    result = PinocchioRobot(
        pin_model,
        str(source),
        pin_model.getFrameId(frame),
        *_joint_maps(pin_model, model, unavailable),
    )
    _check_agreement(pin, result, model, frame, frame_type, unavailable)
    return result


def _load_pinocchio(pin, robot: str, frame: str, unavailable) -> tuple[Path, Any]:
    """The file pinocchio loads for ``robot`` and its model, with one frame ``frame``."""
    try:
        source = _pinocchio_source(robot)
    except (QpikError, ValueError) as exc:
        raise unavailable(str(exc)) from exc
    try:
        if source.suffix.lower() == ".urdf":
            pin_model = pin.buildModelFromUrdf(str(source))
        else:
            pin_model = pin.buildModelFromMJCF(str(source))
    except Exception as exc:  # pinocchio's parsers raise bare RuntimeError/ValueError
        raise unavailable(f"pinocchio cannot parse {source.name}: {exc}") from exc
    count = sum(f.name == frame for f in pin_model.frames)
    if count != 1:
        raise unavailable(
            f"pink addresses frames by name, and pinocchio's model of {source.name} has "
            f"{count} frames named {frame!r}"
        )
    return source, pin_model


def _joint_maps(pin_model, model: mujoco.MjModel, unavailable) -> tuple[np.ndarray, ...]:
    """Per MuJoCo joint (matched by name): its qpos address, pinocchio's q index, whether
    pinocchio stores it as (cos, sin), its dof address and pinocchio's v index."""
    names = [pin_model.names[i] for i in range(1, pin_model.njoints)]
    mj_names = [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or "" for j in range(model.njnt)
    ]
    if sorted(names) != sorted(mj_names) or pin_model.nv != model.nv:
        raise unavailable(
            f"joints differ: pinocchio {names} (nv {pin_model.nv}), MuJoCo {mj_names} "
            f"(nv {model.nv})"
        )
    scalar = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    mj_qpos, pin_q, circle, mj_dof, pin_v = [], [], [], [], []
    for j, name in enumerate(mj_names):
        joint = pin_model.joints[pin_model.getJointId(name)]
        if model.jnt_type[j] not in scalar:
            raise unavailable(f"joint {name!r} is not a hinge or slide joint")
        if joint.nv != 1 or joint.nq not in (1, 2):
            raise unavailable(f"pinocchio joint {name!r} is {joint.shortname()}, not 1-DoF")
        mj_qpos.append(model.jnt_qposadr[j])
        pin_q.append(joint.idx_q)
        circle.append(joint.nq == 2)
        mj_dof.append(model.jnt_dofadr[j])
        pin_v.append(joint.idx_v)
    return tuple(np.array(a) for a in (mj_qpos, pin_q, circle, mj_dof, pin_v))


def _check_agreement(pin, result: PinocchioRobot, model, frame, frame_type, unavailable) -> None:
    """The same position limits, and the same pose of ``frame`` at the mid-range and three
    random configurations (1e-9 m or rad)."""
    pin_model = result.model
    configuration = Configuration(model)
    lower, upper = configuration.lower, configuration.upper
    line = ~result._circle
    for bound, pin_bound, what in (
        (lower, pin_model.lowerPositionLimit, "lower"),
        (upper, pin_model.upperPositionLimit, "upper"),
    ):
        mine, theirs = bound[result._mj_qpos[line]], pin_bound[result._pin_q[line]]
        if not np.allclose(mine, theirs, rtol=0.0, atol=1e-9):
            raise unavailable(f"{what} position limits differ: MuJoCo {mine}, pinocchio {theirs}")
    data = pin_model.createData()
    rng = np.random.default_rng(0)
    for q in [configuration.mid_q()] + [configuration.random_q(rng) for _ in range(3)]:
        configuration.update(q)
        position, rotation = configuration.frame_pose(frame, frame_type)
        pin.framesForwardKinematics(pin_model, data, result.q_to_pinocchio(q))
        placement = data.oMf[result.frame]
        if not (
            np.allclose(placement.translation, position, rtol=0.0, atol=1e-9)
            and np.allclose(placement.rotation, rotation, rtol=0.0, atol=1e-9)
        ):
            raise unavailable(
                f"the pose of {frame!r} differs between pinocchio and MuJoCo at q = {q}"
            )


def _place_site(pin, pin_model, model: mujoco.MjModel, site: str, file: str) -> None:
    """Place the pinocchio frame of MJCF site ``site`` from its parent body's frame and the
    site's pose in that body (MuJoCo's ``site_pos``, ``site_quat``). pinocchio 4.1's MJCF
    parser composes a site with its body's pose relative to the parent body only, not to
    the joint, so a site on a body nested under another fixed body is misplaced (the
    bundled panda's ``ee`` loses the flange's 0.107 m); warns when it corrects the frame."""
    site_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
    body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, model.site_bodyid[site_id])
    bodies = [i for i, f in enumerate(pin_model.frames) if f.name == body and f.type == pin.BODY]
    frame_id = pin_model.getFrameId(site)
    frame = pin_model.frames[frame_id]
    if len(bodies) != 1 or pin_model.frames[bodies[0]].parentJoint != frame.parentJoint:
        return  # left as parsed; the forward-kinematics check decides
    rotation = np.empty(9)
    mujoco.mju_quat2Mat(rotation, model.site_quat[site_id])
    local = pin.SE3(rotation.reshape(3, 3), model.site_pos[site_id].copy())
    placement = pin_model.frames[bodies[0]].placement * local
    if placement.isApprox(frame.placement, 1e-12):
        return
    offset = np.linalg.norm(placement.translation - frame.placement.translation)
    frame.placement = placement
    pin_model.frames[frame_id] = frame
    warnings.warn(
        f"pinocchio {pin.__version__} misplaces MJCF site {site!r} of {file} by "
        f"{1e3 * offset:.1f} mm (nested fixed body {body!r}); placed it from body {body!r} "
        "and the site's pose in it",
        stacklevel=3,
    )


def _pink(model: mujoco.MjModel, frame: str, frame_type: FrameType, robot: str | None) -> dict:
    try:
        import pink
        import pinocchio as pin
        import qpsolvers
        from pink.exceptions import NoSolutionFound
        from pink.limits import ConfigurationLimit
    except ImportError as exc:
        raise MethodUnavailable(
            "pink", robot, f"{exc.name} is not installed: pip install -e '.[compare]'"
        ) from exc
    if robot is None:
        raise MethodUnavailable("pink", robot, "it loads the robot file, and got no robot name")
    robot_pin = pinocchio_robot(robot, model, frame, frame_type)
    backend = "daqp" if "daqp" in qpsolvers.available_solvers else "osqp"
    configuration = Configuration(model)
    pink_configuration = pink.Configuration(
        robot_pin.model, robot_pin.model.createData(), robot_pin.q_to_pinocchio(configuration.q)
    )
    task = pink.FrameTask(frame, position_cost=1.0, orientation_cost=1.0, lm_damping=1.0)
    limits = [ConfigurationLimit(robot_pin.model, config_limit_gain=0.95)]
    failed = np.full(model.nv, np.nan)  # a QP failure: the attempt ends as "diverged"

    def step(work, _J, _c):
        pink_configuration.update(robot_pin.q_to_pinocchio(work.q))
        try:
            velocity = pink.solve_ik(
                pink_configuration, [task], 1.0, backend, damping=1e-3, limits=limits
            )
        except NoSolutionFound:
            return failed
        return robot_pin.v_to_mujoco(velocity)

    def set_target(position, rotation):
        task.set_target(pin.SE3(np.asarray(rotation, float), np.asarray(position, float)))

    return {"step": step, "set_target": set_target}


def _oneshot(model: mujoco.MjModel, frame: str, frame_type: FrameType, robot: str | None) -> dict:
    """qpik's one-shot :func:`qpik.solve`, given the model on every call (no session)."""

    def solve(_configuration, frame, position, rotation, *, frame_type, **options):
        return qpik_solve(model, {(frame, frame_type): (position, rotation)}, **options)

    return {"igm_function": solve}


# ------------------------------------------------------------------ whole-IK peers (URDF)
@dataclass
class UrdfChain:
    """The serial chain of a URDF from its root link to ``tip``, beside qpik's model of it.

    Attributes:
        source: the URDF file (the one qpik's ``erd:`` robot is loaded from).
        base: the chain's first link (the URDF's root: MuJoCo's world frame).
        tip: the tool link.
        joints: the chain's moving joints, base to tip.
        qpos: their addresses in MuJoCo's ``qpos``.
        lower, upper: their limits in qpik's model ([-inf, inf] where unlimited).
    """

    source: Path
    base: str
    tip: str
    joints: list[str]
    qpos: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    def to_mujoco(self, q_chain: np.ndarray, q0: np.ndarray) -> np.ndarray:
        """``q0`` with the chain's joints set to ``q_chain`` (other joints: fingers, kept)."""
        q = np.array(q0, dtype=float)
        q[self.qpos] = q_chain
        return q


def urdf_chain(
    method: str, robot: str | None, model: mujoco.MjModel, frame: str, frame_type: FrameType
) -> UrdfChain:
    """The :class:`UrdfChain` of ``robot`` to ``frame`` (a body: a URDF link), or
    :class:`MethodUnavailable` saying why there is none."""
    if robot is None:
        raise MethodUnavailable(method, robot, "it loads the URDF file, and got no robot name")
    try:
        source = locate_robot(robot)
    except (QpikError, ValueError) as exc:
        raise MethodUnavailable(method, robot, str(exc)) from exc
    if source.suffix.lower() != ".urdf":
        raise MethodUnavailable(method, robot, f"it needs a URDF, and {source.name} is not one")
    if FrameType.parse(frame_type) is not FrameType.BODY:
        raise MethodUnavailable(method, robot, f"frame {frame!r} is not a body (URDF link)")
    parent = {j.find("child").get("link"): j for j in ET.parse(source).getroot().findall("joint")}
    joints, link = [], frame
    while link in parent:
        joint = parent[link]
        if joint.get("type") not in ("fixed", "floating", "planar"):
            joints.append(joint.get("name"))
        link = joint.find("parent").get("link")
    joints.reverse()
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)]
    missing = [name for name in joints if name not in names]
    if missing or not joints:
        raise MethodUnavailable(method, robot, f"chain joints {missing or joints} not in the model")
    configuration = Configuration(model)
    qpos = np.array([model.jnt_qposadr[names.index(name)] for name in joints])
    return UrdfChain(
        source, link, frame, joints, qpos, configuration.lower[qpos], configuration.upper[qpos]
    )


def _check_fk(method, robot, model, chain: UrdfChain, frame, frame_type, fk) -> None:
    """``fk(q_chain) -> (position, rotation)`` agrees with MuJoCo's pose of the frame at the
    mid-range and three random configurations (1e-9), else :class:`MethodUnavailable`."""
    configuration = Configuration(model)
    rng = np.random.default_rng(0)
    for q in [configuration.mid_q()] + [configuration.random_q(rng) for _ in range(3)]:
        configuration.update(q)
        position, rotation = configuration.frame_pose(frame, frame_type)
        theirs = fk(q[chain.qpos])
        if not (
            np.allclose(theirs[0], position, rtol=0.0, atol=1e-9)
            and np.allclose(theirs[1], rotation, rtol=0.0, atol=1e-9)
        ):
            raise MethodUnavailable(
                method, robot, f"its forward kinematics of {frame!r} differs from MuJoCo's"
            )


def _quaternion_xyzw(rotation: np.ndarray) -> np.ndarray:
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation, dtype=float).ravel())
    return quat[[1, 2, 3, 0]]  # MuJoCo's (w, x, y, z) -> (x, y, z, w)


def _tracik(
    model: mujoco.MjModel,
    frame: str,
    frame_type: FrameType,
    *,
    robot: str | None = None,
    tol_position: float,
    tol_orientation: float,
    per_axis: bool = True,
) -> Method:
    """TRAC-IK (``pytracik``) on the URDF chain to ``frame``; see the module docstring.
    TRAC-IK's epsilon bounds each axis: under a criterion on norms (``per_axis`` false) it is
    the tolerance / sqrt(3), so that its answers meet the norms."""
    try:
        import pytracik
    except ImportError as exc:
        raise MethodUnavailable(
            "tracik", robot, "pytracik is not installed: pip install -e '.[compare]'"
        ) from exc
    chain = urdf_chain("tracik", robot, model, frame, frame_type)
    text = chain.source.read_text()
    epsilon = min(tol_position, tol_orientation) / (1.0 if per_axis else np.sqrt(3.0))
    big = float(np.finfo(np.float32).max) * 2.0  # unlimited: TRAC-IK's continuous joint
    lower = [float(x) if np.isfinite(x) else -big for x in chain.lower]
    upper = [float(x) if np.isfinite(x) else big for x in chain.upper]
    solvers: dict = {}

    def solver(budget: float | None):
        timeout = 1.0 if budget is None else float(budget)
        if timeout not in solvers:
            instance = pytracik.TRAC_IK(
                chain.base, chain.tip, text, timeout, epsilon, pytracik.SolveType.Speed
            )
            pytracik.set_joint_limits(instance, lower, upper)
            solvers[timeout] = instance
        return solvers[timeout]

    def fk(q_chain):
        pose = pytracik.fk(solver(None), np.asarray(q_chain, dtype=float))
        return pose[:3, 3], pose[:3, :3]

    _check_fk("tracik", robot, model, chain, frame, frame_type, fk)
    n = len(chain.joints)

    def run(position, rotation, q0, rng, budget):
        x, y, z, w = _quaternion_xyzw(rotation)
        seed = np.ascontiguousarray(q0[chain.qpos], dtype=float)
        out = pytracik.ik(solver(budget), seed, *map(float, position), x, y, z, w)
        if out[0] < 0:  # no solution: the start, as a failure
            return Outcome(np.array(q0, dtype=float), 0, 0, "tracik_failed")
        return Outcome(chain.to_mujoco(out[1 : 1 + n], q0), 0, 0, "converged")

    return run


def _rtb_lm(
    model: mujoco.MjModel,
    frame: str,
    frame_type: FrameType,
    *,
    robot: str | None = None,
    tol_position: float,
    tol_orientation: float,
) -> Method:
    """The Robotics Toolbox's C++ ``ETS.ik_LM`` on the URDF chain to ``frame``."""
    try:
        import roboticstoolbox as rtb
        import xacrodoc.packages
    except ImportError as exc:
        raise MethodUnavailable(
            "rtb_lm", robot, f"{exc.name} is not installed: pip install -e '.[compare]'"
        ) from exc
    chain = urdf_chain("rtb_lm", robot, model, frame, frame_type)
    # The Toolbox expands the URDF with xacro, which must resolve package:// URIs.
    for folder in chain.source.parents:
        if folder.name == "example-robot-data":
            xacrodoc.packages.update_package_cache({"example-robot-data": str(folder)})
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ets = rtb.Robot.URDF(str(chain.source)).ets(start=chain.base, end=chain.tip)
    except Exception as exc:  # the Toolbox's parsers raise many kinds
        raise MethodUnavailable("rtb_lm", robot, f"the Toolbox cannot load it: {exc}") from exc
    if ets.n != len(chain.joints):
        raise MethodUnavailable(
            "rtb_lm", robot, f"its chain has {ets.n} joints, not {len(chain.joints)}"
        )

    def fk(q_chain):
        pose = np.asarray(ets.fkine(np.asarray(q_chain, dtype=float)).A)
        return pose[:3, 3], pose[:3, :3]

    _check_fk("rtb_lm", robot, model, chain, frame, frame_type, fk)
    tol = 0.5 * min(tol_position, tol_orientation) ** 2
    target = np.eye(4)

    def run(position, rotation, q0, rng, budget):
        target[:3, :3] = rotation
        target[:3, 3] = position
        solution = ets.ik_LM(target, q0=np.asarray(q0[chain.qpos], dtype=float), tol=tol)
        if not solution.success:
            return Outcome(np.array(q0, dtype=float), int(solution.iterations),
                           int(solution.searches), "rtb_failed")  # fmt: skip
        return Outcome(
            chain.to_mujoco(solution.q, q0),
            int(solution.iterations),
            max(int(solution.searches) - 1, 0),
            "converged",
        )

    return run


_tracik.per_axis = True  # type: ignore[attr-defined]  # ik_bench passes the criterion's


#: The benchmark's methods, in the table's order.
METHODS: dict[str, MethodFactory] = {
    "qpik": _method(_qpik),
    "pinv": _method(_igm(pseudoinverse_igm)),
    "dls": _method(_igm(damped_least_squares_igm)),
    "mink": _method(_mink),
    "pink": _method(_pink),
    "oneshot": _method(_oneshot),
    "tracik": _tracik,
    "rtb_lm": _rtb_lm,
}

#: The whole-IK peers (issue 20) and the module each needs.
PEERS: dict[str, str] = {"tracik": "pytracik", "rtb_lm": "roboticstoolbox"}


def peer_methods() -> list[str]:
    """The whole-IK peers installed here (``tracik``, ``rtb_lm``)."""
    import importlib.util

    return [name for name, module in PEERS.items() if importlib.util.find_spec(module)]


def available_methods() -> list[str]:
    """The methods that can run here (``mink`` needs mink and qpsolvers, ``pink`` pink and
    pinocchio: ``pip install -e '.[compare]'``)."""
    names = ["qpik", "pinv", "dls"]
    try:
        import mink  # noqa: F401
        import qpsolvers  # noqa: F401
    except ImportError:
        return names
    names.append("mink")
    try:
        import pink  # noqa: F401
        import pinocchio  # noqa: F401
    except ImportError:
        return names
    return names + ["pink"]
