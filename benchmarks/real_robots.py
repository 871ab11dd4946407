"""The robots users bring (issue 22): qpik on MJCF models in MuJoCo Menagerie's layout.

Loads every model of a folder laid out as MuJoCo Menagerie is (``FOLDER/<robot>/<model>.xml``
with ``assets/``; mink's ``examples/`` folder is one), nothing downloaded. The folder is
mirrored into a temporary one (``benchmarks/mink_suite.py``'s mirror: files linked) where a
mesh file a model names but the folder lacks, or one MuJoCo refuses, is replaced by a small
tetrahedron (kinematics and collision capsules do not use meshes). ``scene*.xml`` files
and fragments that do not compile alone are skipped.

Per model it prints:

* the tool frame :func:`qpik.robots.tool_frame` chooses, and why; ``flange``: whether it is
  the model's flange or TCP site (a site named as :data:`qpik.robots.TCP_NAMES` or
  :data:`qpik.robots.FLANGE_NAMES` that no gripper joint moves) wherever it has one;
* the collision geoms (contact bits set) and the self-collision pairs the model lets collide
  (:func:`qpik.limits.collision_pairs`);
* fixed-base models whose tool frame moves: full-IK success with :class:`qpik.IKSession`
  at TRAC-IK's protocol (``--n`` reachable targets: forward kinematics of random
  configurations, start at mid-range, success = 1e-5 m and 1e-5 rad on each axis within
  5 ms, joints within limits); the same targets on the model plus a free cube off the
  arm's chain, without the 5 ms budget on both (deterministic): how many answers differ
  (converged flag, or the arm's ``q`` bitwise; goal 0); the largest coupling residual
  of the answers (:attr:`qpik.IKResult.coupling_error`, models with couplings; goal: within
  ``tol_position``);
* the same models: the README's collision example on the model: the tool frame from its
  start (keyframe 0, else mid-range) to a point 0.45 m to the side, a 6 cm ball
  (:func:`qpik.scene.add_obstacle`) midway, position task above a posture task, under
  :func:`qpik.limits.model_collision_limit` (robot against scene, ``d_min`` = 10 mm) and
  :func:`qpik.limits.joint_limits`, 400 steps at 100 Hz: the closest distance to the ball
  (goal: at least ``d_min - 1 mm``), the largest joint step [rad] of this blocked reach
  and how many steps exceed the documented bound (:attr:`qpik.StepOptions.max_joint_speed`
  times ``dt``; goal 0);
* floating-base models with feet (``*_foot`` sites, else ``*foot*``/``*sole*``/
  ``*ankle_roll*`` bodies): the support polygon of the feet from their collision geometry
  (:class:`qpik.limits.SupportPolygonLimit` with no footprint); mink's humanoid task set
  as levels (feet + CoM / hands / posture) with one hand 2 m out of reach, 50 steps at
  100 Hz: the feet's drift (goal: at most 1 mm) and the steps beyond the bound (goal 0).

The last lines list every goal and the models that miss it (none: all goals hold).

    python benchmarks/real_robots.py PATH/TO/menagerie-or-mink/examples [--n 100]
        [--only ur5e,iiwa14]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import mujoco
import numpy as np
from bench_cli import at_least  # benchmarks/bench_cli.py (this folder is on sys.path)
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mink_suite import mirror_examples  # noqa: E402

import qpik  # noqa: E402
from qpik.errors import QpikError  # noqa: E402
from qpik.limits import (  # noqa: E402
    SupportPolygonLimit,
    collision_geoms,
    collision_pairs,
    geom_distance,
    joint_limits,
    model_collision_limit,
)
from qpik.model.couplings import model_couplings  # noqa: E402
from qpik.robots import FLANGE_NAMES, TCP_NAMES, gripper_joints, tool_frame  # noqa: E402
from qpik.scene import add_obstacle  # noqa: E402
from qpik.tasks import ComTask, FrameTask, PositionTask, PostureTask  # noqa: E402

D_MIN = 0.01  # [m]
DT = 0.01  # [s]
BOUND = qpik.options.DEFAULT_MAX_JOINT_SPEED * DT  # [rad or m per step]: the trust region
TOL = 1e-5  # [m], [rad]: TRAC-IK's tolerance
#: A step's largest excess over the trust region that a certified answer may have: the box
#: row's violation scaled by 1 + |bound| is at most the certificate's tolerance.
BOX_TOLERANCE = qpik.core.CERTIFICATE_TOLERANCE * (1.0 + BOUND)


def model_files(folder: Path) -> list[Path]:
    """The robot models of a Menagerie-style folder: ``*/*.xml`` but ``scene*.xml``."""
    return sorted(p for p in folder.glob("*/*.xml") if not p.name.startswith("scene"))


def _has_free_joint(model: mujoco.MjModel) -> bool:
    return bool(np.any(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE))


def _moved_by_gripper(model: mujoco.MjModel) -> np.ndarray:
    """Per body: whether a gripper joint moves it."""
    grippers = set(gripper_joints(model))
    moved = np.zeros(model.nbody, dtype=bool)
    for b in range(1, model.nbody):
        own = range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b])
        moved[b] = moved[model.body_parentid[b]] or any(j in grippers for j in own)
    return moved


def flange_sites(model: mujoco.MjModel) -> list[str]:
    """The model's sites named as a TCP or a flange (Menagerie's ``attachment_site``,
    ``pinch_site``, ...) that no gripper joint moves."""
    moved = _moved_by_gripper(model)
    out = []
    for s in range(model.nsite):
        name = model.site(s).name
        if moved[model.site_bodyid[s]] or not name:
            continue
        for known in (*TCP_NAMES, *FLANGE_NAMES):
            if name == known or name.endswith("/" + known) or name.endswith("_" + known):
                out.append(name)
                break
    return out


def _targets(model: mujoco.MjModel, frame: tuple[str, str], n: int, seed: int = 0) -> list:
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(seed)
    targets = []
    for _ in range(n):
        configuration.update(configuration.random_q(rng))
        targets.append(configuration.frame_pose(*frame))
    return targets


def ik_success(model: mujoco.MjModel, frame: tuple[str, str], targets: list) -> dict:
    """TRAC-IK's protocol with :class:`qpik.IKSession` (module docstring)."""
    session = qpik.IKSession(model)
    configuration = qpik.Configuration(model)
    q0 = configuration.mid_q()
    session.solve({frame: targets[0]}, q0=q0)  # warm-up
    successes, times = 0, []
    for position, rotation in targets:
        tic = time.perf_counter()
        result = session.solve(
            {frame: (position, rotation)},
            q0=q0,
            tol_position=TOL,
            tol_orientation=TOL,
            time_budget=0.005,
        )
        elapsed = time.perf_counter() - tic
        times.append(elapsed)
        configuration.update(result.q)
        p, r = configuration.frame_pose(*frame)
        dp = np.abs(p - position).max()
        dr = np.abs(Rotation.from_matrix(r @ rotation.T).as_rotvec()).max()
        ok = dp <= TOL and dr <= TOL and elapsed <= 0.005 and configuration.within_limits()
        successes += bool(ok)
    return {"rate": successes / len(targets), "mean_ms": 1e3 * float(np.mean(times))}


def with_free_cube(path: Path) -> mujoco.MjModel:
    """The model of ``path`` plus a free 4 cm cube on the floor, off the arm's chain (its
    qpos after the robot's)."""
    spec = mujoco.MjSpec.from_file(str(path))
    cube = spec.worldbody.add_body(name="free_cube", pos=[0.7, 0.7, 0.02])
    cube.add_freejoint(name="free_cube_joint")
    cube.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.02] * 3, mass=0.1)
    return spec.compile()


def free_object_parity(
    model: mujoco.MjModel, scene: mujoco.MjModel, frame: tuple[str, str], targets: list
) -> dict:
    """The same targets, no time budget (deterministic), on the bare model and on the scene
    with a free cube: how many answers differ (converged flag, or the robot's ``q``
    bitwise), the converged counts, and the largest coupling residual."""
    bare, cubed = qpik.IKSession(model), qpik.IKSession(scene)
    q0 = qpik.Configuration(model).mid_q()
    q0_scene = np.concatenate([q0, scene.qpos0[model.nq :]])
    differ, converged, converged_scene, coupling = 0, 0, 0, 0.0
    engines: set[str] = set()
    for target in targets:
        options = {"tol_position": TOL, "tol_orientation": TOL, "seed": 0}
        a = bare.solve({frame: target}, q0=q0, **options)
        b = cubed.solve({frame: target}, q0=q0_scene, **options)
        converged += a.converged
        converged_scene += b.converged
        engines |= {a.engine, b.engine}
        same = a.converged == b.converged and np.array_equal(a.q, b.q[: model.nq])
        same = same and np.array_equal(b.q[model.nq :], q0_scene[model.nq :])
        differ += not same
        coupling = max(coupling, a.coupling_error, b.coupling_error)
    return {
        "differ": differ,
        "converged": converged,
        "converged_scene": converged_scene,
        "coupling": coupling,
        "engines": ",".join(sorted(engines)),
    }


def readme_reach(model: mujoco.MjModel, frame: tuple[str, str], steps: int = 400) -> dict:
    """The README's collision example on ``model`` (module docstring)."""
    q_start = model.key_qpos[0] if model.nkey else qpik.Configuration(model).mid_q()
    start = qpik.Configuration(model, q_start).frame_pose(*frame)[0]
    goal = start + np.array([0.0, 0.45, 0.0])
    scene = add_obstacle(model, "sphere", 0.06, 0.5 * (start + goal), name="ball")
    avoid = model_collision_limit(
        scene,
        self_collision=False,
        minimum_distance_from_collisions=D_MIN,
        collision_detection_distance=0.1,
    )
    ball_pairs = [g for pair in avoid.geom_id_pairs for g in pair if scene.geom(g).name != "ball"]
    tip = PositionTask(frame[0], frame_type=frame[1], gain=0.1)
    tip.set_target(goal)
    posture = PostureTask(scene, cost=0.05)
    posture.set_target(q_start)
    solver = qpik.IKSolver(scene, [[tip], [posture]], [avoid, *joint_limits(scene)])
    configuration = qpik.Configuration(scene, q_start)
    start_gap = min(geom_distance(configuration, g, "ball") for g in ball_pairs)
    closest, largest, beyond = np.inf, 0.0, 0
    for _ in range(steps):
        step = solver.step(configuration, DT)
        move = float(np.abs(step.velocity * DT).max())
        largest = max(largest, move)
        beyond += move > BOUND + BOX_TOLERANCE
        configuration.integrate_inplace(step.velocity, DT)
        closest = min(closest, *(geom_distance(configuration, g, "ball") for g in ball_pairs))
    error = float(np.linalg.norm(configuration.frame_pose(*frame)[0] - goal))
    return {
        "start_mm": 1e3 * start_gap,
        "closest_mm": 1e3 * closest,
        "step_rad": largest,
        "beyond": beyond,
        "error_mm": 1e3 * error,
    }


def _feet(model: mujoco.MjModel) -> list[tuple[str, str]]:
    sites = [model.site(s).name for s in range(model.nsite)]
    feet = [(s, "site") for s in sites if s.endswith("_foot")]
    if len(feet) >= 2:
        return feet
    bodies = [model.body(b).name for b in range(model.nbody)]
    for word in ("sole", "foot", "ankle_roll"):
        found = [(b, "body") for b in bodies if word in b.lower()]
        if len(found) >= 2:
            return found
    return []


def _hands(model: mujoco.MjModel) -> list[tuple[str, str]]:
    """A humanoid's hands: ``left``/``right`` sites, else bodies, named palm, hand or wrist."""
    for kind, count, name_of in (
        ("site", model.nsite, lambda i: model.site(i).name),
        ("body", model.nbody, lambda i: model.body(i).name),
    ):
        names = [name_of(i) for i in range(count)]
        for word in ("palm", "hand", "wrist"):
            found = [n for n in names if word in n.lower() and ("left" in n or "right" in n)]
            left = [n for n in found if "left" in n]
            right = [n for n in found if "right" in n]
            if left and right:
                return [(left[0], kind), (right[0], kind)]
    return []


def support(model: mujoco.MjModel, feet: list[tuple[str, str]]) -> str:
    limit = SupportPolygonLimit(model, feet)
    q = model.key_qpos[0] if model.nkey else model.qpos0
    configuration = qpik.Configuration(model, q)
    points = limit.support_points(configuration)
    size = np.ptp(points, axis=0)
    margin = limit.com_margin(configuration)
    return f"support {size[0]:.3f} x {size[1]:.3f} m, CoM {1e3 * margin:.0f} mm inside"


def feet_drift(model: mujoco.MjModel, feet: list, hands: list, steps: int = 50) -> dict:
    """mink's humanoid task set as levels (feet + CoM / hands / posture), the first hand
    2 m ahead of where it starts (out of reach): the feet's largest drift [m] and the steps
    beyond the bound."""
    configuration = qpik.Configuration(model, model.key_qpos[0] if model.nkey else None)
    foot_tasks = [FrameTask(f, k, position_cost=1.0, orientation_cost=1.0) for f, k in feet]
    for task in foot_tasks:
        task.set_target_from_configuration(configuration)
    com = ComTask(cost=1.0)
    com.set_target_from_configuration(configuration)
    hand_tasks = [PositionTask(h, k) for h, k in hands]
    for task, (h, k) in zip(hand_tasks, hands):
        task.set_target(configuration.frame_pose(h, k)[0])
    hand_tasks[0].set_target(configuration.frame_pose(*hands[0])[0] + np.array([2.0, 0.5, 0.5]))
    posture = PostureTask(model, cost=0.1)
    posture.set_target_from_configuration(configuration)
    solver = qpik.IKSolver(model, [[*foot_tasks, com], hand_tasks, [posture]], joint_limits(model))
    start = [configuration.frame_pose(f, k)[0].copy() for f, k in feet]
    drift, beyond = 0.0, 0
    for _ in range(steps):
        result = solver.step(configuration, DT)
        beyond += float(np.abs(result.velocity * DT).max()) > BOUND + BOX_TOLERANCE
        configuration.integrate_inplace(result.velocity, DT)
        for (f, k), p in zip(feet, start):
            drift = max(drift, float(np.linalg.norm(configuration.frame_pose(f, k)[0] - p)))
    return {"drift_mm": 1e3 * drift, "beyond": beyond}


#: The goals: name -> (what it says, per model the value and whether it holds).
GOALS = {
    "steps": "0 steps beyond the documented bound (max_joint_speed * dt)",
    "clearance": f"collision clearance >= d_min - 1 mm ({1e3 * (D_MIN - 1e-3):.0f} mm)",
    "feet": "feet drift <= 1 mm",
    "free": "full IK with a free object = the bare arm's (every answer)",
    "coupling": f"coupling residuals <= tol_position ({TOL:g} m)",
    "flange": "default tool frame = the flange/TCP site wherever the model has one",
}


class Report:
    """The misses of every goal, and how many models each goal was checked on."""

    def __init__(self) -> None:
        self.misses: dict[str, list[str]] = {goal: [] for goal in GOALS}
        self.checked: dict[str, int] = dict.fromkeys(GOALS, 0)

    def check(self, goal: str, label: str, holds: bool) -> str:
        self.checked[goal] += 1
        if not holds:
            self.misses[goal].append(label)
        return "" if holds else " MISS"

    def print(self) -> None:
        print("\ngoals:")
        for goal, text in GOALS.items():
            misses = self.misses[goal]
            state = "holds" if not misses else f"MISSED by {', '.join(misses)}"
            print(f"  {text}: {state} ({self.checked[goal]} model(s) checked)")


def run_arm(model, path, frame, label, n, report: Report) -> list[str]:
    """The fixed-base columns of one model: IK, free-object parity, couplings, README reach."""
    lines = []
    try:
        targets = _targets(model, frame, n)
        ik = ik_success(model, frame, targets)
        parity = free_object_parity(model, with_free_cube(path), frame, targets)
        miss = report.check("free", label, parity["differ"] == 0)
        text = (
            f"IK {100 * ik['rate']:.0f}% in 5 ms (mean {ik['mean_ms']:.2f} ms); no budget: "
            f"{parity['converged']}/{n} bare, {parity['converged_scene']}/{n} with a free "
            f"cube, {parity['differ']} answer(s) differ{miss} [{parity['engines']}]"
        )
        if model_couplings(model) is not None:
            miss = report.check("coupling", label, parity["coupling"] <= TOL)
            text += f"; coupling residual {parity['coupling']:.1e}{miss}"
        lines.append(text)
    except Exception as exc:  # noqa: BLE001 - report and go on
        lines.append(f"IK failed: {type(exc).__name__}: {str(exc)[:60]}")
    try:
        reach = readme_reach(model, frame)
        if reach["start_mm"] < 1e3 * D_MIN:  # the ball placed on the robot: not judged
            ball = f"ball {reach['closest_mm']:.1f} mm (placed on the robot: {reach['start_mm']:.1f} mm at the start, not judged)"  # noqa: E501
        else:
            miss_c = report.check("clearance", label, reach["closest_mm"] >= 1e3 * D_MIN - 1.0)
            ball = f"ball {reach['closest_mm']:.1f} mm{miss_c}"
        miss_s = report.check("steps", label, reach["beyond"] == 0)
        lines.append(
            f"README reach: {ball}, largest step "
            f"{reach['step_rad']:.4f} rad ({reach['beyond']} beyond {BOUND:.4f}){miss_s}, "
            f"final error {reach['error_mm']:.1f} mm"
        )
    except QpikError as exc:
        lines.append(f"README reach: {str(exc)[:70]}")
    return lines


def run_floating(model, label, report: Report) -> list[str]:
    """The floating-base columns: support polygon and feet drift."""
    feet, hands = _feet(model), _hands(model)
    if not feet:
        return ["floating base; no feet found"]
    text = f"feet {','.join(f for f, _ in feet)}: {support(model, feet)}"
    if hands:
        drift = feet_drift(model, feet, hands)
        miss_f = report.check("feet", label, drift["drift_mm"] <= 1.0)
        miss_s = report.check("steps", label, drift["beyond"] == 0)
        text += (
            f"; hand {hands[0][0]} out of reach: feet drift {drift['drift_mm']:.3f} mm{miss_f}, "
            f"{drift['beyond']} step(s) beyond {BOUND:.4f}{miss_s}"
        )
    return [text]


def _moves(model: mujoco.MjModel, frame: tuple[str, str]) -> bool:
    """Whether a joint moves the frame (a fixed hand's palm does not)."""
    kind, name = frame[1], frame[0]
    body = model.site(name).bodyid[0] if kind == "site" else model.body(name).id
    while body > 0:
        if model.body_jntnum[body]:
            return True
        body = model.body_parentid[body]
    return False


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path, help="a folder in MuJoCo Menagerie's layout")
    parser.add_argument(
        "--n", type=at_least(1), default=100, help="IK targets per arm (default 100)"
    )
    parser.add_argument("--only", default="", help="comma-separated model stems")
    args = parser.parse_args(argv)
    only = {s for s in args.only.split(",") if s}
    report = Report()
    with tempfile.TemporaryDirectory() as tmp:
        notes = mirror_examples(args.folder.resolve(), Path(tmp))
        print(f"{len(notes)} mesh file(s) replaced by a placeholder tetrahedron")
        for path in model_files(Path(tmp)):
            if only and path.stem not in only:
                continue
            label = f"{path.parent.name}/{path.name}"
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    model = qpik.load_robot(path)
            except (QpikError, ValueError) as exc:
                print(f"{label}: not loaded: {str(exc).splitlines()[0][-70:]}")
                continue
            try:
                tool = tool_frame(model)
            except QpikError as exc:
                print(f"{label}: no tool frame: {exc}")
                continue
            frame = (tool.name, tool.frame_type)
            sites = flange_sites(model)
            flange = ""
            if sites:
                holds = tool.frame_type == "site" and tool.name in sites
                flange = (
                    f" [flange/TCP sites: {', '.join(sites)}"
                    + report.check("flange", label, holds)
                    + "]"
                )
            ncoll = len(collision_geoms(model, robot_only=True))
            nself = len(collision_pairs(model, scene=False))
            print(
                f"{label}: nv {model.nv}, tool {tool.frame_type} {tool.name!r} ({tool.reason})"
                f"{flange}; {ncoll} collision geoms, {nself} self pairs"
            )
            if _has_free_joint(model):
                lines = run_floating(model, label, report)
            elif not _moves(model, frame):
                lines = ["the tool frame is fixed (no joint moves it): no IK"]
            else:
                lines = run_arm(model, path, frame, label, args.n, report)
            for line in lines:
                print(f"    {line}")
    report.print()


if __name__ == "__main__":
    import bench_cli  # benchmarks/bench_cli.py (this folder is on sys.path)

    bench_cli.run(main)
