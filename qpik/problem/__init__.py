r"""IK problem files: a robot, a task stack, limits, solver options and goals, in TOML.

:func:`load_problem` reads and validates a file; :meth:`Problem.solve` runs it and returns
a :class:`ProblemResult`. Every error in a file raises :class:`qpik.ProblemFileError`,
which names the file, the field (dotted, e.g. ``levels[0].tasks[1].type``) and what was
expected. The shipped examples live in the repository's ``tasks/`` folder.

Schema (units: metres, radians, seconds; positions and rotations in the world frame)::

    name = "panda_pose_reach"          # optional, default: the file's stem
    description = "..."                # optional
    robot = "panda"                    # bundled name (qpik robots), "erd:NAME", or a path
                                       # to an .xml/.urdf file relative to this file
    floating_base = false              # true: a free joint at the root (humanoids)
    q0 = "home"                        # start: a list of nq numbers, "mid" (default),
                                       # "qpos0", or a keyframe name of the model ("home")
    mode = "solve"                     # "solve" (default): qpik.solve per goal (the IGM);
                                       # "track": differential IK steps with IKSolver

    [[levels]]                         # level 0: the highest priority
    [[levels.tasks]]
    type = "frame"                     # one of TASK_TYPES (below)
    frame = "ee"                       # frame name (frame, position, orientation,
    frame_type = "site"                #   manipulability); site (default), body or geom;
                                       #   both left out: the robot's tool frame
                                       #   (qpik.robots.tool_frame)
    position_cost = 1.0                # frame tasks: position_cost, orientation_cost;
    orientation_cost = 1.0             #   other tasks: cost (a number or a list)
    gain = 1.0                         # in (0, 1]; optional
    target = { position = [0.5, 0.2, 0.4], rpy = [3.14159, 0, 0] }   # optional

    [[levels]]                         # level 1: acts in the null space of level 0
    [[levels.tasks]]
    type = "posture"
    cost = 0.01
    target = { q = "home" }            # posture target: q list, "start" (default), "mid",
                                       # "qpos0" or a keyframe name

    [target]                           # the goal: exactly one of [target] / [[waypoints]]
    frame = "ee"                       # default: the frame of the first task of level 0
    position = [0.5, 0.2, 0.4]         # required
    rpy = [3.14159, 0.0, 0.785398]     # optional rotation (see below)
    # or several frames reached together (both hands), instead of the fields above:
    # [[target.frames]]                # (in waypoints: [[waypoints.frames]])
    # frame = "gripper_left_base_link"
    # frame_type = "body"
    # position = [0.3, 0.4, 1.0]

    [limits]
    position = true                    # joint position limits (default true)
    velocity = 0.5                     # false / absent: none; a number: that fraction of
                                       # the model's velocity_limit; a list of nv values
                                       # [rad/s]; or a table {joint = value}
    [limits.support]                   # optional: the CoM's ground projection stays in
    frames = ["left_sole_link", "right_sole_link"]   # the support polygon of these frames
    frame_type = "body"                #   (site by default)
    margin = 0.02                      #   [m] inside every edge (at most the polygon's
                                       #   inscribed radius at q0, checked on load)
    footprint = [[0.1, 0.05], [0.1, -0.05], [-0.1, 0.05], [-0.1, -0.05]]  # [m], each
                                       #   frame's x-y axes (default: the contact body's
                                       #   collision geometry)

    [solver]                           # all optional: a qpik.SolveOptions preset and
    preset = "default"                 #   overrides of its fields (problem.solve_options);
                                       #   default "default" (solve), "tracking" (track)
    solver = "osqp"                    # QP backend
    tol_position = 1e-4                # [m]
    tol_orientation = 1e-3             # [rad]
    max_iters = 100                    # per attempt (solve mode)
    restarts = 20                      # random restarts (solve mode)
    seed = 0                           # default 0: the same restarts every run
    time_budget = 1.0                  # [s] per goal (solve mode)
    alpha = 1.0                        # gain of the goal tasks without their own gain
                                       #   (solve mode)
    beta = 1.0                         # step scale (solve mode)
    max_step = [0.2, 0.5]              # trust region [m, rad], or false (solve mode)
    singular_threshold = 0.05          # adaptive damping (DampingLaw), both modes
    max_damping = 0.05                 #   (adaptive_damping = false switches it off)
    lower_trust = 0.0                  #   levels below a damped one held near it (0 to 1)
    damping = 1e-6                     # constant Tikhonov term, both modes

    [track]                            # mode = "track" only
    dt = 0.01                          # [s] per step
    steps = 300                        # steps per goal
    stop_at_goal = false               # stop a goal's steps once within tolerance

    [statics]                          # optional: statics at the final configuration
    frame = "ee"                       # default: the goal frame
    force = [0, 0, -20]                # [N], world axes, on the robot at the frame origin
    torque = [0, 0, 0]                 # [N m], optional
    payload_direction = [0, 0, -1]     # optional: max_payload along this direction

Task types (:data:`TASK_TYPES`; how each is read and built: :data:`TASK_KINDS`, one entry
per type) and their classes: ``frame`` (:class:`mink.FrameTask`,
6 rows, error in the frame's local axes), ``position`` / ``orientation``
(:class:`qpik.tasks.PositionTask` / :class:`~qpik.tasks.OrientationTask`, 3 world-aligned
rows), ``posture`` (:class:`mink.PostureTask`), ``joint_limit_distance``
(:class:`~qpik.tasks.JointLimitDistanceTask`), ``manipulability``
(:class:`~qpik.tasks.ManipulabilityTask`, with ``rows = "pose" | "position"``),
``damping`` (:class:`mink.DampingTask`) and ``com`` (:class:`mink.ComTask`, target
``position``). A task target left out holds the start value (the frame's start pose, the
start posture, the start centre of mass, at ``q0`` for every goal and waypoint, in both
modes); a task on a goal frame (its name and type) gets the goal, and every part of a goal
must be steered (a position by a frame or position task, a rotation by a frame or
orientation task). A goal
may name several frames (``frames = [...]``): they are reached together (both hands),
while tasks on other frames (the feet) hold their start pose.

Rotations: ``rpy = [roll, pitch, yaw]`` [rad], extrinsic x-y-z, ``R = Rz(yaw) Ry(pitch)
Rx(roll)``; or ``quaternion = [w, x, y, z]`` (MuJoCo's order, normalised on load); or
``matrix = [[r00, r01, r02], [r10, r11, r12], [r20, r21, r22]]`` (rows). At most one.

Numbers are range-checked on load (:data:`RANGES`): every number must be finite;
positions, centre-of-mass targets and joint values within +-:data:`MAX_LENGTH`, ``rpy``
angles within +-:data:`MAX_ANGLE` rad, costs in [0, :data:`MAX_COST`], forces and torques
within +-:data:`MAX_WRENCH`, and each ``[solver]`` / ``[track]`` / task option within its
interval (e.g. ``gain`` in (0, 1], ``lm_damping`` in [0, 1e6], ``time_budget`` in
(0, 86400] s, ``seed`` in [0, 2^63 - 1], ``track.steps`` in [1, 1e6]). A ``q0`` outside a
joint limit by at most 1e-6 (the tolerance of :meth:`qpik.Configuration.check_limits`) is
clamped onto it. The file must be UTF-8 (a byte-order mark is allowed).

Modes (:data:`MODES`). ``solve``: each goal (the target, or each waypoint in turn, from the
previous result) is one :func:`qpik.solve` with ``stack`` = the levels and the goal's frames as
targets; in a solve the gain of the level-0 position and orientation tasks on the goal
frames is the solver's ``alpha`` where the task gives no ``gain`` of its own.
``track``: :class:`qpik.IKSolver` steps of ``dt`` from ``q0`` toward each goal in turn,
``steps`` steps each, under the limits (a velocity limit bounds each step to
``v_max dt``); the result is a :class:`TrackTrace`. Either way the problem has converged
when the final configuration of every goal is within ``tol_position`` and
``tol_orientation`` of each of its frames.

Layout: :mod:`.reader` (TOML and typed values), :mod:`.specs` (task specs and the task
registry), :mod:`.goals` (goals, one or several frames), :mod:`.limits` (``[limits]``),
:mod:`.solver` (``[solver]``: a :class:`qpik.SolveOptions`), :mod:`.loader`
(:class:`Problem`, :func:`load_problem`), :mod:`.modes` (run modes), :mod:`.report`
(results, statics, JSON).
"""

from __future__ import annotations

from .goals import FrameGoal, Goal
from .loader import Problem, load_problem, problem_files
from .modes import MODES
from .reader import MAX_ANGLE, MAX_COST, MAX_LENGTH, MAX_WRENCH, RANGES
from .report import ErrorCurve, ProblemResult, StaticsReport, TrackTrace
from .specs import TASK_KINDS, TASK_TYPES, TaskKind, TaskSpec

__all__ = [
    "MAX_ANGLE",
    "MAX_COST",
    "MAX_LENGTH",
    "MAX_WRENCH",
    "MODES",
    "RANGES",
    "TASK_KINDS",
    "TASK_TYPES",
    "ErrorCurve",
    "FrameGoal",
    "Goal",
    "Problem",
    "ProblemResult",
    "StaticsReport",
    "TaskKind",
    "TaskSpec",
    "TrackTrace",
    "load_problem",
    "problem_files",
]
