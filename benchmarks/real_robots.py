"""The robots users bring (issue 22): qpik on MJCF models in MuJoCo Menagerie's layout.

Loads every model of a folder laid out as MuJoCo Menagerie is (``FOLDER/<robot>/<model>.xml``
with ``assets/``; mink's ``examples/`` folder is one), nothing downloaded. The folder is
mirrored into a temporary one (``benchmarks/mink_suite.py``'s mirror: files linked) where a
mesh file a model names but the folder lacks, or one MuJoCo refuses, is replaced by a small
tetrahedron (kinematics and collision capsules do not use meshes). ``scene*.xml`` files
and fragments that do not compile alone are skipped.

Per model it prints:

* the tool frame :func:`qpik.robots.tool_frame` chooses, and why;
* the collision geoms (contact bits set) and the self-collision pairs the model lets collide
  (:func:`qpik.limits.collision_pairs`);
* fixed-base models only: full-IK success with :class:`qpik.IKSession` at TRAC-IK's
  protocol (``--n`` reachable targets: forward kinematics of random configurations, start
  at mid-range, success = 1e-5 m and 1e-5 rad on each axis within 5 ms, joints within
  limits);
* fixed-base models only: the README's collision example on the model: the tool frame
  from its start (keyframe 0, else mid-range) to a point 0.45 m to the side, a 6 cm ball
  (:func:`qpik.scene.add_obstacle`) midway, position task above a posture task, under
  :func:`qpik.limits.model_collision_limit` (robot against scene, ``d_min`` = 10 mm) and
  :func:`qpik.limits.joint_limits`, 400 steps at 100 Hz: the closest distance to the ball
  (goal: at least ``d_min - 1 mm``) and the largest joint step [rad] (a blocked reach);
* floating-base models: the support polygon of the feet (``*_foot`` sites, else
  ``*foot*``/``*sole*``/``*ankle_roll*`` bodies) from their collision geometry
  (:class:`qpik.limits.SupportPolygonLimit` with no footprint): its size and the CoM margin
  at the start.

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
from qpik.robots import tool_frame  # noqa: E402
from qpik.scene import add_obstacle  # noqa: E402
from qpik.tasks import PositionTask, PostureTask  # noqa: E402

D_MIN = 0.01  # [m]
DT = 0.01  # [s]


def model_files(folder: Path) -> list[Path]:
    """The robot models of a Menagerie-style folder: ``*/*.xml`` but ``scene*.xml``."""
    return sorted(p for p in folder.glob("*/*.xml") if not p.name.startswith("scene"))


def _has_free_joint(model: mujoco.MjModel) -> bool:
    return bool(np.any(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE))


def ik_success(model: mujoco.MjModel, frame: tuple[str, str], n: int, seed: int = 0) -> dict:
    """TRAC-IK's protocol with :class:`qpik.IKSession` (module docstring)."""
    session = qpik.IKSession(model)
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(seed)
    targets = []
    for _ in range(n):
        configuration.update(configuration.random_q(rng))
        targets.append(configuration.frame_pose(*frame))
    q0 = configuration.mid_q()
    session.solve({frame: targets[0]}, q0=q0)  # warm-up
    successes, times = 0, []
    for position, rotation in targets:
        tic = time.perf_counter()
        result = session.solve(
            {frame: (position, rotation)},
            q0=q0,
            tol_position=1e-5,
            tol_orientation=1e-5,
            time_budget=0.005,
        )
        elapsed = time.perf_counter() - tic
        times.append(elapsed)
        configuration.update(result.q)
        p, r = configuration.frame_pose(*frame)
        dp = np.abs(p - position).max()
        dr = np.abs(Rotation.from_matrix(r @ rotation.T).as_rotvec()).max()
        ok = dp <= 1e-5 and dr <= 1e-5 and elapsed <= 0.005 and configuration.within_limits()
        successes += bool(ok)
    return {"rate": successes / n, "mean_ms": 1e3 * float(np.mean(times))}


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
    closest, largest = np.inf, 0.0
    for _ in range(steps):
        step = solver.step(configuration, DT)
        largest = max(largest, float(np.abs(step.velocity * DT).max()))
        configuration.integrate_inplace(step.velocity, DT)
        closest = min(closest, *(geom_distance(configuration, g, "ball") for g in ball_pairs))
    error = float(np.linalg.norm(configuration.frame_pose(*frame)[0] - goal))
    return {"closest_mm": 1e3 * closest, "step_rad": largest, "error_mm": 1e3 * error}


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


def support(model: mujoco.MjModel) -> str:
    feet = _feet(model)
    if not feet:
        return "no feet found"
    limit = SupportPolygonLimit(model, feet)
    q = model.key_qpos[0] if model.nkey else model.qpos0
    configuration = qpik.Configuration(model, q)
    points = limit.support_points(configuration)
    size = np.ptp(points, axis=0)
    margin = limit.com_margin(configuration)
    names = ",".join(name for name, _ in feet)
    return f"{names}: {size[0]:.3f} x {size[1]:.3f} m, CoM {1e3 * margin:.0f} mm inside"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path, help="a folder in MuJoCo Menagerie's layout")
    parser.add_argument("--n", type=int, default=100, help="IK targets per arm (default 100)")
    parser.add_argument("--only", default="", help="comma-separated model stems")
    args = parser.parse_args(argv)
    only = {s for s in args.only.split(",") if s}
    with tempfile.TemporaryDirectory() as tmp:
        notes = mirror_examples(args.folder.resolve(), Path(tmp))
        print(f"{len(notes)} mesh file(s) replaced by a placeholder tetrahedron")
        header = (
            f"{'model':<28}{'nv':>4}  {'tool frame':<34}{'coll':>5}{'self':>6}"
            f"{'IK ok':>8}{'mean ms':>9}{'ball mm':>9}{'step rad':>9}{'err mm':>8}"
        )
        print(header)
        print("-" * len(header))
        for path in model_files(Path(tmp)):
            if only and path.stem not in only:
                continue
            label = f"{path.parent.name}/{path.name}"[:27]
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    model = qpik.load_robot(path)
            except (QpikError, ValueError) as exc:
                print(f"{label:<28}  not loaded: {str(exc).splitlines()[0][:70]}")
                continue
            try:
                tool = tool_frame(model)
            except QpikError as exc:
                print(f"{label:<28}  no tool frame: {exc}")
                continue
            frame = (tool.name, tool.frame_type)
            kind = "site" if tool.frame_type == "site" else "body"
            cell = f"{kind} {tool.name}"[:33]
            ncoll = len(collision_geoms(model, robot_only=True))
            nself = len(collision_pairs(model, scene=False))
            line = f"{label:<28}{model.nv:>4}  {cell:<34}{ncoll:>5}{nself:>6}"
            if _has_free_joint(model):
                print(f"{line}  floating base; support: {support(model)}")
                continue
            try:
                ik = ik_success(model, frame, args.n)
                line += f"{100 * ik['rate']:>7.1f}%{ik['mean_ms']:>9.2f}"
            except Exception as exc:  # noqa: BLE001 - report and go on
                line += f"  IK failed: {type(exc).__name__}"
            try:
                reach = readme_reach(model, frame)
                line += (
                    f"{reach['closest_mm']:>9.1f}{reach['step_rad']:>9.3f}{reach['error_mm']:>8.1f}"
                )
            except QpikError as exc:
                line += f"  reach: {str(exc)[:50]}"
            print(line)
            print(f"{'':<34}({tool.reason})")


if __name__ == "__main__":
    main()
