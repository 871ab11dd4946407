"""An interactive viewer in the browser: drag a target, watch the robot follow.

``qpik view PROBLEM.toml`` on the command line, or from Python::

    import qpik.viewer

    viewer = qpik.viewer.Viewer("tasks/panda_pose_reach.toml")   # or a model, a robot name
    print(viewer.url)                                            # http://127.0.0.1:8080/
    viewer.set_target("ee", [0.4, 0.2, 0.5])                     # [m], world frame
    viewer.serve(seconds=2)                                      # then closes

The page shows the robot (the model's visual geoms: meshes where it has them, primitives
otherwise; its collision geoms on request), a transform handle on every goal frame and a
frame marker where the frame actually is, a panel per level (status, residual, damping,
active limits; red when the level cannot be met, grey while a robot moved by hand is not
solved for yet), the solve time of the last drag, the
joints as sliders and ``q`` as a list to copy, a play button for track-mode problems,
and the support polygon and centre of mass where the problem has one.

Dragging a handle re-solves the stack from the current configuration with
:class:`qpik.IKSolver` steps (:class:`LiveSolve`): strict priorities, the problem's
limits and damping, its tolerances. A problem's full-IK options that need restarts
(``restarts``, ``time_budget``) do not apply: a drag moves the robot continuously.

The viewer needs the ``viewer`` extra (viser); without it :class:`Viewer` raises
:class:`qpik.MissingExtra`, while :class:`LiveSolve` and :mod:`.geometry` need only numpy
and MuJoCo. The server listens on 127.0.0.1 unless told otherwise: anyone who can reach
the port can move the targets.
"""

from __future__ import annotations

from .app import DEFAULT_HOST, DEFAULT_PORT, Viewer, default_stack, import_viser
from .geometry import GeomMesh, geom_meshes
from .live import GoalFrame, LevelReport, LiveSolve, SolveReport
from .panels import level_html

__all__ = [
    "DEFAULT_HOST",
    "DEFAULT_PORT",
    "GeomMesh",
    "GoalFrame",
    "LevelReport",
    "LiveSolve",
    "SolveReport",
    "Viewer",
    "default_stack",
    "geom_meshes",
    "import_viser",
    "level_html",
]
