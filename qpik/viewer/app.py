"""The browser viewer (:class:`Viewer`), built on viser (the ``viewer`` extra).

viser serves a web page (its client is bundled: nothing is fetched from the internet)
and a websocket; the page draws the scene with WebGL, so it works on a machine without a
GPU or a display, and from a laptop's browser over the network.

Security: whoever reaches the port can move the robot's targets (and read the model).
The server therefore listens on ``127.0.0.1`` by default; ``host="0.0.0.0"`` (``qpik view
--host 0.0.0.0``) exposes it on every interface on purpose (prefer an SSH tunnel:
``ssh -L 8080:localhost:8080 host``).
"""

from __future__ import annotations

import html
import os
import threading
import time
import webbrowser
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, TypedDict, Unpack

import mujoco
import numpy as np
import numpy.typing as npt

from ..core import checks
from ..errors import InvalidArgumentType, InvalidInput, MissingExtra, QpikError
from ..igm.targets import Target
from ..model.configuration import Configuration, FrameType
from ..model.robots import load_robot, tool_frame
from ..problem import Problem, load_problem
from ..tasks import OrientationTask, PositionTask, PostureTask
from .geometry import GeomMesh, geom_meshes, ground_height
from .live import LiveSolve, SolveReport, check_max_iterations, goal_keys
from .panels import level_html
from .server import check_host, check_port, start_server

__all__ = ["DEFAULT_HOST", "DEFAULT_PORT", "Viewer", "import_viser"]

#: The default interface: this machine only (see the module docstring).
DEFAULT_HOST = "127.0.0.1"
#: The default port (viser takes the next free one when it is busy).
DEFAULT_PORT = 8080


def import_viser() -> Any:
    """The ``viser`` module; :class:`qpik.MissingExtra` naming the ``viewer`` extra when
    it is not installed."""
    try:
        import viser
    except ImportError as exc:
        raise MissingExtra("the viewer", "viewer", "viser") from exc
    return viser


def _rgb255(rgba: np.ndarray) -> tuple[int, int, int]:
    return tuple(int(round(255 * float(np.clip(c, 0, 1)))) for c in rgba[:3])  # type: ignore[return-value]


def _wxyz(matrix: np.ndarray) -> np.ndarray:
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.asarray(matrix, dtype=float).reshape(9))
    return quat


class Serving(TypedDict, total=False):
    """The keywords of :class:`Viewer` on how it serves and solves (see its docstring)."""

    host: str
    port: int
    collision: bool
    max_iterations: int
    label: str | None
    solve_start: bool


class Viewer:
    """An interactive viewer in the browser: the robot, a draggable handle on every goal
    frame with the IK re-solved as it moves, and a panel per level.

    Args:
        source: a :class:`qpik.problem.Problem`, the path of a problem file (``.toml``),
            an ``MjModel``, a :class:`qpik.Configuration`, or anything
            :func:`qpik.load_robot` takes (a bundled name, ``"erd:NAME"``, a path).
        levels: the task stack (level 0 first) for a model; default: the tool frame's
            position and orientation in level 0 and the start posture in level 1. A
            problem brings its own (and ignores this).
        limits: limits holding at every step (default: the problem's, or the joint
            position limits).
        goals: frames that get a handle: names or ``(name, frame_type)`` (one name alone:
            that frame); default: the problem's goal frames, or every frame a task of
            ``levels`` regulates.
        q0: start configuration ``(nq,)`` (default: the problem's, the configuration's,
            or the model's first keyframe, else ``qpos0``), clipped into the joint limits
            (as :meth:`set_q` clips).

    Keyword Args:
        host: interface to listen on, a str (default ``127.0.0.1``: this machine only).
        port: TCP port, an int in [0, 65535] (default 8080; 0 picks a free one; a busy
            one: the next free one).
        collision: draw the collision geoms too (translucent; a checkbox toggles them).
        max_iterations: IK steps per drag solve at most, an int in [0, 100000] (the range
            of :attr:`qpik.SolveOptions.max_iters`; default 20).
        label: the page's title (default: the problem's name, or the model's).
        solve_start: solve toward the goals before serving (default True).

    The server starts at once and runs in background threads until :meth:`close` (or the
    end of a ``with`` block); :meth:`serve` blocks while it serves. Solving from Python
    (:meth:`set_target`) updates every connected page.

    Raises :class:`qpik.InvalidOption` (or :class:`qpik.InvalidArgumentType` for the
    wrong type) for a keyword out of range, a ``host`` this machine cannot listen on
    (unresolvable, another machine's address) or a port it may not bind, and
    :class:`qpik.InvalidInput` when the server does not start within
    :data:`qpik.viewer.server.SERVER_START_TIMEOUT` seconds.
    """

    def __init__(
        self,
        source: Any,
        *,
        levels: Any = None,
        limits: Iterable[Any] | None = None,
        goals: Sequence[str | tuple[str, FrameType | str]] | None = None,
        q0: npt.ArrayLike | None = None,
        **serving: Unpack[Serving],
    ):
        checks.check_keywords("Viewer", dict(serving), Serving)
        host = check_host(serving.get("host", DEFAULT_HOST))
        port = check_port(serving.get("port", DEFAULT_PORT))
        collision = checks.check_bool("collision", serving.get("collision", False))
        max_iterations = check_max_iterations(serving.get("max_iterations", 20))
        label = serving.get("label")
        if label is not None and not isinstance(label, str):
            raise InvalidArgumentType("label", "a str or None", checks.type_name(label))
        solve_start = checks.check_bool("solve_start", serving.get("solve_start", True))
        viser = import_viser()
        self.started_at = time.perf_counter()
        self.problem: Problem | None = None
        self.live = self._make_live(source, levels, limits, goals, q0, max_iterations)
        self.model: mujoco.MjModel = self.live.model
        self.live.set_q(self._within_limits(self.live.q))
        self._lock = threading.RLock()
        self._pending: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._pending_lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._syncing = False
        self._playing = False
        self.drag_times: list[float] = []  # [s], the solve time behind each drag update
        self.report: SolveReport | None = None
        #: The support polygon's corners ``(k, 2)`` [m, world x-y] as last drawn (a stack
        #: with a support-polygon limit), else None.
        self.support_polygon: np.ndarray | None = None
        if solve_start:
            self.live.solve(max_iterations=max(200, max_iterations))
        name = label or (self.problem.name if self.problem is not None else _model_name(self.model))
        self.server: Any = start_server(viser, host, port, f"qpik: {name}")
        self.host = host
        try:
            self._build_scene(collision)
            self._build_gui(name)
            self._redraw(self.live.solve(max_iterations=0) if not solve_start else self._report())
        except BaseException:
            self.server.stop()
            raise
        self._worker = threading.Thread(target=self._work, name="qpik-viewer", daemon=True)
        self._worker.start()

    # ------------------------------------------------------------------ sources
    def _make_live(self, source, levels, limits, goals, q0, max_iterations) -> LiveSolve:
        if isinstance(source, Problem):
            self.problem = source
        elif isinstance(source, (str, os.PathLike)) and Path(source).suffix == ".toml":
            self.problem = load_problem(source)
        if self.problem is not None:
            return live_of_problem(self.problem, limits, goals, q0, max_iterations)
        if isinstance(source, Configuration):
            model = source.model
            start = source.q if q0 is None else q0
        else:
            model = source if isinstance(source, mujoco.MjModel) else load_robot(source)
            start = q0 if q0 is not None else (model.key_qpos[0] if model.nkey else None)
        configuration = Configuration(model, start)
        if levels is None:
            levels = default_stack(configuration)
        return LiveSolve(
            model,
            levels,
            limits,
            goals,
            configuration.q,
            max_iterations=max_iterations,
        )

    # ------------------------------------------------------------------ scene
    def _build_scene(self, collision: bool) -> None:
        scene = self.server.scene
        scene.set_up_direction("+z")
        data = self.live.configuration.data
        scene.add_grid("/ground", width=4.0, height=4.0, cell_size=0.1, section_size=0.5,
                       position=(0.0, 0.0, ground_height(self.model, data)))  # fmt: skip
        self._bodies: dict[int, Any] = {}
        self._collision_bodies: dict[int, Any] = {}
        self._add_geoms(geom_meshes(self.model, "visual"), "/robot", self._bodies, None)
        self._collision_drawn = False
        self._collision_visible = collision
        if collision:
            self._draw_collision()
        self._handles: dict[str, Any] = {}
        self._markers: dict[str, Any] = {}
        for name, goal in self.live.goals.items():
            target = goal.target
            wxyz = _wxyz(target.rotation) if target.rotation is not None else None
            if wxyz is None:
                wxyz = _wxyz(self.live.configuration.frame_pose(name, goal.frame_type)[1])
            handle = scene.add_transform_controls(
                f"/goals/{_node(name)}",
                scale=0.18,
                disable_rotations=not goal.rotation,
                position=target.position,
                wxyz=wxyz,
            )
            handle.on_update(self._on_handle(name))
            self._handles[name] = handle
            self._markers[name] = scene.add_frame(
                f"/frames/{_node(name)}", axes_length=0.08, axes_radius=0.006
            )
        self._support = self._support_limit()
        self._support_nodes: list[Any] = []
        centre, extent = _scene_bounds(self.model, data)
        self.server.initial_camera.look_at = tuple(centre)
        self.server.initial_camera.position = tuple(
            centre + np.array([1.25, -1.1, 0.7]) * max(extent, 0.5)
        )
        self.server.initial_camera.up = (0.0, 0.0, 1.0)

    def _add_geoms(
        self, meshes: list[GeomMesh], root: str, bodies: dict[int, Any], colour: Any
    ) -> None:
        scene = self.server.scene
        for mesh in meshes:
            if mesh.body not in bodies:
                bodies[mesh.body] = scene.add_frame(f"{root}/body{mesh.body}", show_axes=False)
            rgba = mesh.rgba if colour is None else np.asarray(colour, dtype=float)
            scene.add_mesh_simple(
                f"{root}/body{mesh.body}/geom{mesh.geom}",
                mesh.vertices,
                mesh.faces,
                color=_rgb255(rgba),
                opacity=None if rgba[3] >= 0.999 else float(rgba[3]),
                side="double",
                position=mesh.position,
                wxyz=mesh.wxyz,
            )

    def _draw_collision(self) -> None:
        if not self._collision_drawn:
            self._add_geoms(
                geom_meshes(self.model, "collision"),
                "/collision",
                self._collision_bodies,
                (1.0, 0.45, 0.1, 0.45),
            )
            self._collision_drawn = True
            self._move_bodies(self._collision_bodies)

    def _support_limit(self) -> Any:
        """The stack's support-polygon limit (drawn with the CoM), or None."""
        return next(
            (lim for lim in self.live.limits if type(lim).__name__ == "SupportPolygonLimit"),
            None,
        )

    def _move_bodies(self, bodies: dict[int, Any]) -> None:
        data = self.live.configuration.data
        for body, node in bodies.items():
            node.position = data.xpos[body].copy()
            node.wxyz = data.xquat[body].copy()

    def _draw_support(self) -> None:
        limit = self._support
        if limit is None:
            return
        from scipy.spatial import ConvexHull

        configuration = self.live.configuration
        points = limit.support_points(configuration)
        try:
            hull = points[ConvexHull(points).vertices]
        except Exception:  # degenerate footprints: draw nothing
            return
        self.support_polygon = hull.copy()
        z = 0.002
        ring = np.column_stack([hull, np.full(len(hull), z)])
        segments = np.stack([ring, np.roll(ring, -1, axis=0)], axis=1)
        com = limit.com(configuration)
        scene = self.server.scene
        if not self._support_nodes:
            self._support_nodes = [
                scene.add_line_segments(
                    "/support/polygon", segments, colors=(30, 120, 220), thickness=0.006
                ),
                scene.add_icosphere(
                    "/support/com", radius=0.025, color=(220, 40, 40), position=(com[0], com[1], z)
                ),
            ]
        else:
            self._support_nodes[0].points = segments
            self._support_nodes[1].position = (com[0], com[1], z)

    # ------------------------------------------------------------------ gui
    def _build_gui(self, name: str) -> None:
        gui = self.server.gui
        problem = self.problem
        what = f"robot `{problem.robot}`, mode `{problem.mode}`" if problem else "model"
        gui.add_markdown(f"**{html.escape(name)}** ({what}). Drag a handle: the IK re-solves.")
        self._solve_md = gui.add_markdown("solve: -")
        self._limits_md = gui.add_markdown("active limits: none")
        with gui.add_folder("Levels (level 0 first)"):
            self._level_html = [gui.add_html(level_html(level)) for level in self._report().levels]
        with gui.add_folder("Configuration"):
            self._q_text = gui.add_text(
                "q", _q_text(self.live.q), multiline=True, hint="the current q, to copy"
            )
        self._sliders: dict[int, Any] = {}
        with gui.add_folder("Joints", expand_by_default=False):
            lower, upper = self.live.configuration.lower, self.live.configuration.upper
            scalar = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
            for j in range(self.model.njnt):
                if int(self.model.jnt_type[j]) not in scalar:
                    continue
                i = int(self.model.jnt_qposadr[j])
                lo = float(lower[i]) if np.isfinite(lower[i]) else -np.pi
                hi = float(upper[i]) if np.isfinite(upper[i]) else np.pi
                joint = mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_JOINT, j) or str(j)
                slider = gui.add_slider(
                    joint, min=lo, max=hi, step=1e-3, initial_value=float(self.live.q[i])
                )
                slider.on_update(self._on_slider(i))
                self._sliders[i] = slider
        self._show_collision = gui.add_checkbox("collision geoms", self._collision_visible)
        self._show_collision.on_update(self._on_collision)
        if problem is not None and problem.mode == "track":
            self._play = gui.add_button("Play the track")
            self._play.on_click(lambda _: self.play(background=True))

    # ------------------------------------------------------------------ drawing
    def _report(self) -> SolveReport:
        if self.live.last is None:
            self.live.solve(max_iterations=0)
        assert self.live.last is not None
        return self.live.last

    def _redraw(self, report: SolveReport) -> None:
        self.report = report
        server = self.server
        with server.atomic():
            self._move_bodies(self._bodies)
            if self._collision_drawn:
                self._move_bodies(self._collision_bodies)
            for name, goal in self.live.goals.items():
                position, matrix = self.live.configuration.frame_pose(name, goal.frame_type)
                self._markers[name].position = position.copy()
                self._markers[name].wxyz = _wxyz(matrix)
            self._draw_support()
            for widget, level in zip(self._level_html, report.levels):
                widget.content = level_html(level)
            # The worst position and the worst angle, each over the goals (of those whose
            # orientation is regulated: none, no angle), not the angle of the worst position.
            errors = report.goal_errors
            worst = max((e[0] for e in errors.values()), default=0.0)
            goals = self.live.goals
            turned = [e[1] for n, e in errors.items() if n in goals and goals[n].rotation]
            angle = f", {np.degrees(max(turned)):.3f}&deg;" if turned else ""
            self._solve_md.content = (
                f"solve time: **{1000 * report.solve_time:.2f} ms** ({report.steps} steps, "
                f"{'converged' if report.converged else 'not converged'}); goal error "
                f"{1000 * worst:.2f} mm{angle}"
            )
            active = report.levels[0].active_limits if report.levels else []
            self._limits_md.content = "active limits: " + (
                html.escape(", ".join(active)) if active else "none"
            )
            self._syncing = True
            try:
                self._q_text.value = _q_text(report.q)
                for i, slider in self._sliders.items():
                    slider.value = float(np.clip(report.q[i], slider.min, slider.max))
            finally:
                self._syncing = False

    # ------------------------------------------------------------------ events
    def _on_handle(self, name: str):
        def callback(event: Any) -> None:
            handle = event.target
            with self._pending_lock:
                self._pending[name] = (
                    np.array(handle.position, dtype=float),
                    np.array(handle.wxyz, dtype=float),
                )
            self._wake.set()

        return callback

    def _on_slider(self, index: int):
        def callback(_: Any) -> None:
            if self._syncing:
                return
            with self._lock:
                q = self.live.q
                q[index] = float(self._sliders[index].value)
                self.live.set_q(q)
                self._redraw(self.live.solve(max_iterations=0))

        return callback

    def _on_collision(self, _: Any) -> None:
        visible = bool(self._show_collision.value)
        with self._lock:
            if visible:
                self._draw_collision()
            for node in self._collision_bodies.values():
                node.visible = visible

    def _work(self) -> None:
        """The solver thread: solves the latest handle poses (updates coalesce while a
        solve runs), then keeps solving a little while the goals are not reached."""
        settle = 0
        while not self._stop.is_set():
            if not self._wake.wait(timeout=0.05 if settle else 0.5):
                if settle <= 0:
                    continue
            self._wake.clear()
            with self._pending_lock:
                pending, self._pending = self._pending, {}
            if not pending and settle <= 0:
                continue
            with self._lock:
                if self._playing:
                    continue
                for name, (position, wxyz) in pending.items():
                    try:
                        self.live.set_target(name, position, wxyz)
                    except QpikError:  # a malformed pose from a page: ignore that update
                        continue
                report = self.live.solve()
                if pending:
                    self.drag_times.append(report.solve_time)
                    settle = 50
                settle = 0 if report.converged or report.steps == 0 else settle - 1
                self._redraw(report)

    # ------------------------------------------------------------------ python api
    @property
    def q(self) -> np.ndarray:
        """The current configuration ``(nq,)``."""
        with self._lock:
            return self.live.q

    @property
    def port(self) -> int:
        """The TCP port the server listens on."""
        return int(self.server.get_port())

    @property
    def url(self) -> str:
        """The page's address (``http://127.0.0.1:PORT/`` by default)."""
        host = self.host if self.host not in ("0.0.0.0", "::", "") else "127.0.0.1"
        return f"http://{host}:{self.port}/"

    def frame_pose(self, frame: str) -> tuple[np.ndarray, np.ndarray]:
        """Pose of a goal frame at the current ``q``: position ``(3,)`` [m] and rotation
        ``(3, 3)``, world frame."""
        with self._lock:
            goal = self.live.goal(frame)
            position, matrix = self.live.configuration.frame_pose(frame, goal.frame_type)
            return position.copy(), matrix.copy()

    def target(self, frame: str) -> Target:
        """The current target of goal frame ``frame`` (world frame)."""
        return self.live.goal(frame).target

    def set_target(
        self,
        frame: str,
        position: npt.ArrayLike,
        rotation: npt.ArrayLike | None = None,
        max_iterations: int | None = None,
    ) -> SolveReport:
        """Move goal frame ``frame``'s target, as a drag of its handle would, and solve.

        Args:
            frame: a goal frame (:attr:`goals`).
            position: ``(3,)`` [m], world frame.
            rotation: a 3x3 rotation matrix or a ``(4,)`` quaternion ``w, x, y, z`` (world
                frame); ignored for a position-only goal; left out: unchanged.
            max_iterations: IK steps at most (default: the viewer's).

        Returns the :class:`~qpik.viewer.SolveReport`; every connected page is updated
        (handle, robot, panels). On a closed viewer: :class:`qpik.InvalidInput`.
        """
        self._check_open("set_target")
        self.live.goal(frame)
        if max_iterations is not None:
            check_max_iterations(max_iterations)
        with self._lock:
            target = self.live.set_target(frame, position, rotation)
            handle = self._handles[frame]
            handle.position = target.position.copy()
            if target.rotation is not None:
                handle.wxyz = _wxyz(target.rotation)
            report = self.live.solve(max_iterations)
            self._redraw(report)
            return report

    @property
    def goals(self) -> list[str]:
        """The frames with a handle."""
        return list(self.live.goals)

    def set_q(self, q: npt.ArrayLike) -> None:
        """Show configuration ``q`` ``(nq,)`` (the next drag solves from it), clipped into
        the joint limits as the start ``q0`` is (the limits hold at every step, and the
        joint sliders span them); not ``nq`` finite numbers:
        :class:`qpik.InvalidConfiguration`; on a closed viewer: :class:`qpik.InvalidInput`."""
        self._check_open("set_q")
        q = self.live.configuration._validated(q)
        with self._lock:
            self.live.set_q(self._within_limits(q))
            self._redraw(self.live.solve(max_iterations=0))

    def _within_limits(self, q: np.ndarray) -> np.ndarray:
        """``q`` clipped into the joint position limits (unlimited joints unchanged)."""
        configuration = self.live.configuration
        return np.clip(q, configuration.lower, configuration.upper)

    def play(self, background: bool = False, realtime: bool = True) -> None:
        """Run a track-mode problem: from ``q0``, ``steps`` IK steps of ``dt`` toward each
        goal in turn, drawn as they go (at ``dt`` per step when ``realtime``)."""
        problem = self.problem
        if problem is None or problem.mode != "track":
            raise InvalidInput("play needs a problem file with mode = 'track'")
        if background:
            threading.Thread(target=self.play, kwargs={"realtime": realtime}, daemon=True).start()
            return
        with self._lock:
            if self._playing:
                return
            self._playing = True
            self.live.set_q(problem.q0)
        try:
            for goal in problem.goals:
                with self._lock:
                    for frame in goal.frames:
                        self.live.set_target(
                            frame.frame, frame.target.position, frame.target.rotation
                        )
                        self._handles[frame.frame].position = frame.target.position.copy()
                for _ in range(problem.steps):
                    if self._stop.is_set():
                        return
                    with self._lock:
                        report = self.live.solve(max_iterations=1)
                        self._redraw(report)
                    if realtime:
                        time.sleep(problem.dt)
        finally:
            self._playing = False

    def _check_open(self, what: str) -> None:
        """:class:`qpik.InvalidInput` naming ``what`` once :meth:`close` has run."""
        if self._stop.is_set():
            raise InvalidInput(f"{what}: the viewer is closed (close() ran); make a new one")

    def serve(self, seconds: float | None = None) -> None:
        """Serve until ``seconds`` [s] (a number >= 0) have passed (``None``: until Ctrl-C),
        then close; another ``seconds``: :class:`qpik.InvalidInput` naming it (the viewer
        is closed all the same)."""
        try:
            if seconds is not None:
                seconds = checks.check_real("seconds", seconds, 0.0, unit="s")
            deadline = None if seconds is None else time.monotonic() + float(seconds)
            while deadline is None or time.monotonic() < deadline:
                remaining = 0.2 if deadline is None else min(0.2, deadline - time.monotonic())
                if remaining > 0:
                    time.sleep(remaining)
        finally:
            self.close()

    def open_browser(self) -> bool:
        """Open the page in the default browser; whether one was started."""
        try:
            return bool(webbrowser.open(self.url))
        except webbrowser.Error:
            return False

    def close(self) -> None:
        """Stop the solver thread and the server (idempotent)."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._wake.set()
        self._worker.join(timeout=2.0)
        self.server.stop()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# ---------------------------------------------------------------------------- helpers
def default_stack(configuration: Configuration) -> list[list[Any]]:
    """The viewer's stack for a bare model: the tool frame's position and orientation in
    level 0 (:func:`qpik.robots.tool_frame`), the start posture in level 1."""
    checks.check_instance("configuration", configuration, Configuration, "a qpik.Configuration")
    model = configuration.model
    tool = tool_frame(model)
    position = PositionTask(tool.name, frame_type=tool.frame_type)
    orientation = OrientationTask(tool.name, frame_type=tool.frame_type)
    position.set_target_from_configuration(configuration)
    orientation.set_target_from_configuration(configuration)
    posture = PostureTask(model, cost=0.1)
    posture.set_target(configuration.q)
    return [[position, orientation], [posture]]


def live_of_problem(problem: Problem, limits, goals, q0, max_iterations: int) -> LiveSolve:
    start = problem.start_configuration()
    if q0 is not None:
        start.update(np.asarray(q0, dtype=float))
    levels = problem.build_stack(start)
    frames = problem.goals[0].frames
    keys = goal_keys(
        problem.model, goals if goals is not None else [(f.frame, f.frame_type) for f in frames]
    )
    names = {name for name, _ in keys}
    options = problem.solve_options
    level_names = [
        [f"{s.type} {s.frame}" if s.frame else s.type for s in level] for level in problem.levels
    ]
    return LiveSolve(
        problem.model,
        levels,
        problem.build_limits() if limits is None else limits,
        keys,
        start.q,
        targets={f.frame: f.target for f in frames if f.frame in names},
        dt=problem.dt if problem.mode == "track" else 1.0,
        step_options=options.step,
        tol_position=options.tol_position,
        tol_orientation=options.tol_orientation,
        max_iterations=max_iterations,
        max_step=options.max_step,
        level_names=level_names,
    )


def _node(name: str) -> str:
    return "".join(c if c.isalnum() or c in "_-" else "_" for c in name)


def _q_text(q: np.ndarray) -> str:
    return "[" + ", ".join(f"{x:.6f}" for x in q) + "]"


def _model_name(model: mujoco.MjModel) -> str:
    """The model's own name (``<mujoco model="...">``: the first of MuJoCo's names; its
    ``mj_id2name(..., mjOBJ_MODEL, 0)`` gives None), else ``"model"``."""
    name = bytes(model.names[: model.names.find(b"\0")]).decode("utf-8", "replace")
    return name or "model"


def _scene_bounds(model: mujoco.MjModel, data: mujoco.MjData) -> tuple[np.ndarray, float]:
    """Centre [m] and size [m] of the robot's bodies at the current configuration."""
    points = data.xpos[1:] if model.nbody > 1 else data.xpos
    lo, hi = points.min(axis=0), points.max(axis=0)
    return 0.5 * (lo + hi), float(np.max(hi - lo))
