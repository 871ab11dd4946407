"""Load robot models: bundled MJCF files, your own MJCF or URDF, or example-robot-data.

``load_robot(source, *, floating_base=False, srdf=None)`` accepts:

* the name of a bundled model (``qpik.list_robots()``): ``"planar_2r"``, ``"panda"``, ...;
* a path to an MJCF ``.xml`` file or a ``.urdf`` file;
* a ``mujoco.MjModel`` (returned as is);
* ``"erd:NAME"``: a URDF that the package ``example-robot-data`` ships
  (``"erd:panda"``, ``"erd:ur5"``, ``"erd:talos"``, ...; every name: :func:`erd_robots`;
  from a checkout, ``pip install -e ".[robots]"``).

Reading a file (MJCF or URDF, with the workarounds URDF files need, a floating base and
SRDF keyframes) is :mod:`qpik.model.robot_files`'s; :func:`robot_spec` and :func:`find_srdf` are
re-exported here.

Every model ``load_robot`` builds also carries how it was built (a custom text element
named :data:`SOURCE_TEXT`: the file, ``floating_base``, ``srdf``, as JSON), so that
:func:`qpik.scene.add_obstacle` can rebuild it, bit for bit, with more geoms.

Tool frame. :func:`tool_frame` names the frame a command uses when none is given, trying in
order: the site ``ee`` (qpik's bundled robots); a site, then a body, named as a tool centre
point (:data:`TCP_NAMES`: ``pinch_site``, ``tcp_site``, ``link_tcp``, ``end_effector``,
``*_hand_tcp``, ...); a site, then a body, named as a flange (:data:`FLANGE_NAMES`:
``attachment_site``, ``tool0``, ``flange``, ...); a site, then a body, named as a hand
(:data:`HAND_NAMES`: ``left_palm``, ``right_wrist``, ``left_hand_link``: a humanoid's,
each name also followed by ``_link``); a known tool link
(:data:`TOOL_LINKS`); else the end of the longest chain. A name matches exactly or as the
end of a longer name after ``/`` or ``_`` (``left/gripper``, ``panda_hand_tcp``); among
several matches the one on the longest chain wins (ties: the lowest id). No rule ever
picks a frame moved by a gripper joint (:func:`gripper_joints`: a finger). The longest
chain's end is the first body that carries the most arm joints (hinge/slide joints that are
not a gripper's; ties: the lowest id), followed down through joint-less links while they
have a single child (a flange, a force sensor, up to a gripper's base where the fingers
branch).
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from importlib import metadata, resources
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..core import checks
from ..errors import InfeasibleLimits, InvalidInput, MissingExtra, RobotFileError, UnknownRobot
from .robot_files import (  # noqa: F401 (find_srdf, robot_spec: re-exported)
    LENGTH_FIELDS,
    ROOT_JOINT,
    check_lengths,
    find_srdf,
    robot_spec,
)

__all__ = [
    "ERD_ROBOTS",
    "FINGER_NAMES",
    "FLANGE_NAMES",
    "GRIPPER_WORDS",
    "HAND_NAMES",
    "SOURCE_TEXT",
    "TCP_NAMES",
    "TOOL_LINKS",
    "ToolFrame",
    "check_kinematic_model",
    "erd_path",
    "erd_robots",
    "erd_robots_folder",
    "find_srdf",
    "gripper_joints",
    "list_robots",
    "load_robot",
    "locate_robot",
    "robot_path",
    "robot_spec",
    "robots_dir",
    "tool_frame",
]

#: Name of the custom text element holding how a model was built (JSON).
SOURCE_TEXT = "qpik_source"

#: ``erd:`` names that are not simply the URDF's file stem (the names example-robot-data's
#: own loaders use), and the URDF each maps to inside example-robot-data's ``robots/``.
#: Every other URDF is reachable by its stem (see :func:`erd_robots`).
ERD_ROBOTS: dict[str, str] = {
    "panda": "panda_description/urdf/panda.urdf",
    "ur3": "ur_description/urdf/ur3_robot.urdf",
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "ur10": "ur_description/urdf/ur10_robot.urdf",
    "xarm7": "xarm_description/urdf/xarm7.urdf",
    "talos": "talos_data/robots/talos_reduced.urdf",
    "talos_box": "talos_data/robots/talos_reduced_box.urdf",
    "talos_full": "talos_data/robots/talos_full_v2.urdf",
    "talos_full_box": "talos_data/robots/talos_full_v2_box.urdf",
    "talos_arm": "talos_data/robots/talos_left_arm.urdf",
    "talos_left_arm": "talos_data/robots/talos_left_arm.urdf",
    "kinova": "kinova_description/robots/kinova.urdf",
    "z1": "z1_description/urdf/z1.urdf",
    "double_pendulum": "double_pendulum_description/urdf/double_pendulum.urdf",
    "anymal": "anymal_b_simple_description/robots/anymal.urdf",
    "anymal_c": "anymal_c_simple_description/urdf/anymal.urdf",
}

#: Names of a tool centre point (a gripper's pinch point, a TCP), as Menagerie (sites) and
#: URDF conventions (links) spell them, in the order :func:`tool_frame` tries them.
TCP_NAMES: tuple[str, ...] = (
    "tcp_site",
    "pinch_site",
    "pinch",
    "grasp_site",
    "grasp_center",
    "gripper_site",
    "eef_site",
    "ee_site",
    "end_effector_site",
    "hand_tcp",
    "link_tcp",
    "tcp",
    "tcp_link",
    "end_effector",
    "end_effector_link",
    "eef",
    "ee",
    "gripper",
)

#: Names of a flange (where a tool is mounted), tried after :data:`TCP_NAMES`.
FLANGE_NAMES: tuple[str, ...] = (
    "attachment_site",
    "attachment",
    "flange",
    "tool0",
    "tool_link",
    "tool_frame",
    "ee_link",
    "link_eef",
)

#: Names of a hand's frame (humanoids: ``left_palm``, ``right_wrist``), tried after
#: :data:`FLANGE_NAMES`.
HAND_NAMES: tuple[str, ...] = ("palm", "hand", "wrist")

#: Link names known to be a robot's tool frame (robots of example-robot-data whose names
#: follow no convention), tried after the TCP and flange names.
TOOL_LINKS: tuple[str, ...] = (
    "tool0",
    "tcp",
    "panda_hand_tcp",
    "link_tcp",
    "link_eef",
    "ee_link",
    "end_effector",
    "j2s6s200_end_effector",
    "gripperStator",
    "gripper_frame_link",
    "panda_hand",
)

#: Words that mark a gripper's joint (:func:`gripper_joints`; any case): the
#: bodies such a joint moves (fingers) are never a tool frame.
GRIPPER_WORDS: tuple[str, ...] = (
    "finger",
    "fngr",
    "driver",
    "gripper",
    "knuckle",
    "thumb",
    "jaw",
    "claw",
    "pad",
)

#: Fingers' names: a joint (or body) is a gripper's where one is a whole word of its name
#: (``Left_index_q1``) and the model's joints name two fingers (these or ``thumb``); part
#: of a word (``spring``) or alone in a model (erd human's ``middle_lumbar_Z``) they are not.
FINGER_NAMES: tuple[str, ...] = ("index", "middle", "ring", "pinky", "little")


def robots_dir() -> Path:
    """The folder holding the bundled robot files.

    In an installed wheel they live in ``qpik/_robots``; in a source checkout (or an
    editable install) they are the repository's top-level ``robots/`` folder.
    """
    packaged = Path(str(resources.files("qpik"))) / "_robots"
    if packaged.is_dir():
        return packaged
    return Path(__file__).resolve().parents[2] / "robots"


def list_robots() -> list[str]:
    """Names of the bundled robot models, sorted."""
    return sorted(p.stem for p in robots_dir().glob("*.xml"))


def robot_path(name: str) -> Path:
    """Path of the bundled model ``name``; raises :class:`UnknownRobot` if there is none."""
    path = robots_dir() / f"{name}.xml"
    try:
        found = bool(name) and path.is_file()
    except (OSError, ValueError):  # a name the OS rejects (too long, ...)
        found = False
    if not found:
        raise UnknownRobot(name, list_robots())
    return path


def load_robot(
    source: str | os.PathLike | mujoco.MjModel,
    *,
    floating_base: bool = False,
    srdf: str | os.PathLike | bool | None = None,
) -> mujoco.MjModel:
    """Load a robot model.

    Args:
        source: the name of a bundled model (:func:`list_robots`: ``"planar_2r"``,
            ``"panda"``, ...); ``"erd:NAME"``, a URDF that example-robot-data ships
            (:func:`erd_robots`; the ``robots`` extra); a path to an MJCF ``.xml`` or a
            ``.urdf`` file; or an ``MjModel`` (returned as is; ``floating_base`` and
            ``srdf`` must then be left at their defaults).
        floating_base: add a free joint ``root_joint`` at the root body (a humanoid or a
            legged robot whose base moves in the world).
        srdf: an SRDF file whose named states become keyframes and whose
            ``<disable_collisions>`` pairs become contact excludes; ``None`` (default) or
            ``True``: look for one beside a URDF; ``False``: none.
    """
    floating_base = checks.check_bool("floating_base", floating_base)
    if srdf is not None and not isinstance(srdf, bool):
        srdf = checks.check_path("srdf", srdf)
    if isinstance(source, mujoco.MjModel):
        if floating_base or srdf not in (None, False):
            raise RobotFileError(
                "<MjModel>", "floating_base and srdf apply when loading a file, not to a model"
            )
        check_model(source, "<MjModel>")
        return source
    checks.check_instance(
        "source", source, (str, os.PathLike), "a robot name, 'erd:NAME', a path or an MjModel"
    )
    path = locate_robot(source)
    return _load_file(path, floating_base=floating_base, srdf=srdf)


def check_model(model: mujoco.MjModel, where: str) -> None:
    """Raise :class:`RobotFileError` naming ``where`` for a model qpik cannot compute
    with: a position (body, joint, site, geom, centre of mass) that is not finite or
    farther than :data:`qpik.core.checks.MAX_LENGTH` [m] from its parent (MuJoCo's dynamics
    overflow: NaN gravity torques), a mass or inertia that is not finite, or a custom
    numeric ``velocity_limit`` whose length is not ``nv``."""
    check_lengths(model, where)
    for name in ("body_mass", "body_inertia"):
        if not np.isfinite(getattr(model, name)).all():
            raise RobotFileError(where, f"{name} has a NaN or inf entry")
    _check_axes_and_equalities(model, where)
    nid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, "velocity_limit")
    if nid >= 0 and int(model.numeric_size[nid]) != model.nv:
        raise RobotFileError(
            where,
            f"the custom numeric velocity_limit has {int(model.numeric_size[nid])} values; "
            f"it needs one per dof ({model.nv})",
        )


#: The model arrays a solve computes with (those :data:`qpik.igm.prepared.FINGERPRINT_FIELDS`
#: watches), checked by :func:`check_kinematic_model`, each with the object its rows name
#: (``None``: a qpos entry's joint); the positions [m] of :data:`LENGTH_FIELDS` are bounded.
_KINEMATIC_FIELDS: tuple[tuple[str, mujoco.mjtObj | None], ...] = (
    ("qpos0", None),
    ("jnt_axis", mujoco.mjtObj.mjOBJ_JOINT),
    ("jnt_pos", mujoco.mjtObj.mjOBJ_JOINT),
    ("body_pos", mujoco.mjtObj.mjOBJ_BODY),
    ("body_quat", mujoco.mjtObj.mjOBJ_BODY),
    ("site_pos", mujoco.mjtObj.mjOBJ_SITE),
    ("site_quat", mujoco.mjtObj.mjOBJ_SITE),
    ("geom_pos", mujoco.mjtObj.mjOBJ_GEOM),
    ("geom_quat", mujoco.mjtObj.mjOBJ_GEOM),
    ("eq_data", mujoco.mjtObj.mjOBJ_EQUALITY),
    ("tendon_length0", mujoco.mjtObj.mjOBJ_TENDON),
    ("wrap_prm", mujoco.mjtObj.mjOBJ_UNKNOWN),
)


def check_kinematic_model(model: mujoco.MjModel, where: str = "robot") -> None:
    """Raise a :class:`qpik.QpikError` naming ``where`` (the argument the model came in), the
    model field and its joint, body, site or geom, for a model a solve cannot compute with
    (an ``MjModel`` edited in place after it was loaded): :class:`qpik.InvalidInput` for a
    number that is not finite (a position also beyond :data:`qpik.core.checks.MAX_LENGTH`
    [m]) or a limited joint's NaN range, :class:`qpik.InfeasibleLimits` for a limited hinge
    or slide joint whose range is empty (lower above upper). Costs a few tens of
    microseconds: run it where a model is read (:class:`qpik.igm.prepared.PreparedRobot`),
    not per step."""
    for name, obj in _KINEMATIC_FIELDS:
        values = np.asarray(getattr(model, name))
        if name in LENGTH_FIELDS:
            bad = ~(np.abs(values) <= checks.MAX_LENGTH)  # NaN too
            need = f"finite and within {checks.MAX_LENGTH:g} m"
        else:
            bad = ~np.isfinite(values)
            need = "finite"
        if bad.any():
            row = int(np.argwhere(bad)[0][0])
            raise InvalidInput(
                f"{where}: the model's {name} of {_row_label(model, name, obj, row)} is "
                f"{values[row].tolist()}; the numbers a solve reads from the model must be "
                f"{need} (an array edited in place?)"
            )
    for j in np.flatnonzero(model.jnt_limited):
        lower, upper = (float(x) for x in model.jnt_range[j])
        label = _row_label(model, "jnt_range", mujoco.mjtObj.mjOBJ_JOINT, int(j))
        if np.isnan(lower) or np.isnan(upper):
            raise InvalidInput(
                f"{where}: the model's jnt_range of {label} is [{lower}, {upper}]; a limited "
                "joint's range must not be NaN"
            )
        if lower > upper and int(model.jnt_type[j]) in _SCALAR_JOINTS:
            raise InfeasibleLimits(
                f"{where}: the model's jnt_range of {label} is [{lower:.6g}, {upper:.6g}], "
                "empty (lower above upper): no configuration is within its limits"
            )


def _row_label(model: mujoco.MjModel, field: str, obj: mujoco.mjtObj | None, row: int) -> str:
    """``joint 'elbow'``, ``body #3``, ``qpos0[4] (joint 'elbow')``: what row ``row`` of the
    model field ``field`` belongs to."""
    if obj is None:  # a qpos entry: its joint
        j = int(np.searchsorted(model.jnt_qposadr, row, side="right")) - 1
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"#{j}"
        return f"entry {row} (joint {name!r})"
    kind = {"jnt": "joint", "eq": "equality", "wrap": "wrap"}.get(field.split("_")[0])
    kind = kind or field.split("_")[0]
    name = None if obj == mujoco.mjtObj.mjOBJ_UNKNOWN else mujoco.mj_id2name(model, obj, row)
    return f"{kind} {name!r}" if name else f"{kind} #{row}"


def _check_axes_and_equalities(model: mujoco.MjModel, where: str) -> None:
    """A hinge or slide joint's axis is a direction (MuJoCo normalises it when it compiles:
    an axis that overflows, ``1e300 0 0``, comes out zero, a joint that moves nothing while
    its quaternion scales the bodies below it); an equality's numbers (a URDF ``<mimic>``'s
    multiplier and offset, a ``polycoef``, anchors) are finite."""
    for j in range(model.njnt):
        if int(model.jnt_type[j]) not in _SCALAR_JOINTS:
            continue
        norm = float(np.linalg.norm(model.jnt_axis[j]))
        if not abs(norm - 1.0) <= 1e-6:
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"#{j}"
            raise RobotFileError(
                where,
                f"joint {name!r}: axis {model.jnt_axis[j].tolist()} after normalisation; an "
                "axis must be a nonzero direction of finite size (an axis of 1e300 "
                "overflows)",
            )
    for e in range(model.neq):
        _check_coupling_size(model, e, where)
        if not np.isfinite(model.eq_data[e]).all():
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_EQUALITY, e) or f"#{e}"
            if int(model.eq_type[e]) == int(mujoco.mjtEq.mjEQ_JOINT):
                joints = [int(model.eq_obj1id[e]), int(model.eq_obj2id[e])]
                names = [
                    mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"#{j}"
                    for j in joints
                    if j >= 0
                ]
                name += f" (joints {', '.join(names)})"
            raise RobotFileError(
                where,
                f"equality {name}: eq_data {model.eq_data[e].tolist()} has a NaN or inf "
                "entry (a URDF <mimic> multiplier or offset, an MJCF polycoef, anchor or "
                "relpose)",
            )


#: The largest coefficient of a joint or tendon coupling (a URDF ``<mimic>``'s multiplier or
#: offset, an MJCF ``polycoef``): a gear ratio of a million. Beyond it the coupling's rows
#: (``q2 - c1 q1 - ...``) make the products of a step overflow (1e300 x 1e9 = inf).
COUPLING_COEF_MAX = 1e6


def _check_coupling_size(model: mujoco.MjModel, e: int, where: str) -> None:
    """A joint or tendon equality's polynomial coefficients are at most
    :data:`COUPLING_COEF_MAX` in size (NaN and inf are named by the caller's check)."""
    if int(model.eq_type[e]) not in (int(mujoco.mjtEq.mjEQ_JOINT), int(mujoco.mjtEq.mjEQ_TENDON)):
        return
    coef = model.eq_data[e][:5]
    if not np.all(np.abs(coef[np.isfinite(coef)]) <= COUPLING_COEF_MAX):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_EQUALITY, e) or f"#{e}"
        kind = mujoco.mjtObj.mjOBJ_JOINT
        if int(model.eq_type[e]) == int(mujoco.mjtEq.mjEQ_TENDON):
            kind = mujoco.mjtObj.mjOBJ_TENDON
        names = [
            mujoco.mj_id2name(model, kind, int(i)) or f"#{int(i)}"
            for i in (model.eq_obj1id[e], model.eq_obj2id[e])
            if i >= 0
        ]
        raise RobotFileError(
            where,
            f"equality {name} (of {', '.join(names)}): coefficients {coef.tolist()}; a "
            f"coupling's coefficients (a URDF <mimic> multiplier or offset, an MJCF polycoef) "
            f"must be at most {COUPLING_COEF_MAX:g} in size",
        )


def locate_robot(
    source: str | os.PathLike, *, relative_to: str | os.PathLike | None = None
) -> Path:
    """The file of a robot source: a bundled name, ``"erd:NAME"``, or a path (``.xml`` /
    ``.urdf``, or any name with a path separator or naming an existing file), relative to
    the folder ``relative_to`` when given (a problem file's folder), else to the working
    directory.

    Raises :class:`UnknownRobot` (listing the bundled names) for an unknown name; a path is
    returned whether or not it exists (:func:`load_robot` then raises
    :class:`RobotFileError` naming it)."""
    checks.check_instance("robot", source, (str, bytes, os.PathLike), "a robot name or a path")
    text = os.fspath(source)
    if isinstance(text, bytes):
        text = os.fsdecode(text)
    if "\0" in text:
        raise UnknownRobot(repr(text), list_robots())
    if text.startswith("erd:"):
        return erd_path(text[4:])
    path = Path(text)
    if relative_to is not None and not path.is_absolute():
        path = Path(os.fspath(relative_to)) / path
    looks_like_path = path.suffix.lower() in (".xml", ".urdf") or os.sep in text or "/" in text
    if looks_like_path or _exists(path):
        return path
    return robot_path(text)


def _exists(path: Path) -> bool:
    """``path.exists()``, False for names the OS rejects (too long, ...)."""
    try:
        return path.exists()
    except (OSError, ValueError):
        return False


# ------------------------------------------------------------------ example-robot-data
def erd_robots_folder() -> Path:
    """The ``robots/`` folder that example-robot-data installs (it ships files, no module).

    Raises :class:`MissingExtra` naming the ``robots`` extra when it is not installed.
    """
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError as exc:
        raise MissingExtra("'erd:' robots", "robots", "example-robot-data") from exc
    marker = "share/example-robot-data/robots/"
    for file in dist.files or ():
        text = str(file).replace(os.sep, "/")
        if marker in text:
            root = text[: text.index(marker) + len(marker)]
            return Path(str(dist.locate_file(root)))
    raise RobotFileError(str(dist.locate_file("")), "example-robot-data has no robots folder")


def erd_robots() -> dict[str, Path]:
    """Every ``erd:`` name and its URDF, sorted by name.

    The names of :data:`ERD_ROBOTS` first (example-robot-data's loader names), then every
    other URDF the package ships under its file stem; a stem that several packages ship is
    prefixed with the package (``anymal_b_simple_description/.../anymal.urdf`` ->
    ``anymal_b_simple_anymal``)."""
    base = erd_robots_folder()
    found: dict[str, Path] = {}
    for name, relative in ERD_ROBOTS.items():
        if (base / relative).is_file():
            found[name] = base / relative
    urdfs = sorted(base.glob("*/**/*.urdf"))
    stems: dict[str, int] = {}
    for path in urdfs:
        stems[path.stem] = stems.get(path.stem, 0) + 1
    urdfs = [p for p in urdfs if "<link" in p.read_text(errors="replace")]  # ur3.urdf is empty
    for path in urdfs:
        package = path.relative_to(base).parts[0].removesuffix("_description")
        name = path.stem
        if stems[name] > 1 or found.get(name, path) != path:
            name = f"{package}_{path.stem}"
        found.setdefault(name, path)
    return dict(sorted(found.items()))


def erd_path(name: str) -> Path:
    """The URDF of ``erd:NAME``; :class:`UnknownRobot` lists every name otherwise."""
    if name in ERD_ROBOTS:  # the common names, without listing the package
        path = erd_robots_folder() / ERD_ROBOTS[name]
        if path.is_file():
            return path
    robots = erd_robots()
    if name not in robots:
        raise UnknownRobot(f"erd:{name}", [f"erd:{n}" for n in robots], erd=True)
    return robots[name]


# ------------------------------------------------------------------------- files
def _load_file(path: Path, *, floating_base: bool, srdf) -> mujoco.MjModel:
    spec = robot_spec(path, floating_base=floating_base, srdf=srdf)
    recipe: dict[str, Any] = {
        "path": os.path.abspath(path),  # as given: symlinks kept, as MuJoCo read it
        "floating_base": bool(floating_base),
        "srdf": srdf if srdf in (None, False, True) else str(Path(os.fspath(srdf)).resolve()),
        "obstacles": [],
    }
    spec.add_text(name=SOURCE_TEXT, data=json.dumps(recipe))
    try:
        model = spec.compile()
    except ValueError as exc:  # pragma: no cover - the model compiled a moment ago
        raise RobotFileError(str(path), str(exc).strip()) from exc
    check_model(model, str(path))
    return model


# --------------------------------------------------------------------- tool frame
@dataclass(frozen=True)
class ToolFrame:
    """A robot's tool frame: ``name`` and ``frame_type`` (``"site"`` or ``"body"``), and
    ``reason``, the rule that chose it (for the commands to print)."""

    name: str
    frame_type: str
    reason: str


def gripper_joints(model: mujoco.MjModel) -> list[int]:
    """Ids of the joints that belong to a gripper or a hand: hinge or slide joints whose name
    holds one of :data:`GRIPPER_WORDS` (``panda_finger_joint1``, ``gripper_left_joint``,
    ``left_driver_joint``) or has one of :data:`FINGER_NAMES` as a word in a model whose
    joints name two fingers (``Left_index_q1``), but not ``gripper`` with a wrist's axis
    word (``LeftGripperYaw``: a wrist joint that turns the gripper); or whose body's name
    does when no joint lies below that body (a finger link's unnamed joint; a wrist joint on
    a ``gripper_link`` with fingers below it is the arm's)."""
    checks.check_instance("model", model, mujoco.MjModel, "a mujoco.MjModel")
    below = np.zeros(model.nbody, dtype=bool)  # a joint on some body below b
    for b in range(model.nbody - 1, 0, -1):  # children come after parents
        if below[b] or model.body_jntnum[b]:
            below[model.body_parentid[b]] = True
    found = []
    named = [(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or "").lower() for j in
             range(model.njnt)]  # fmt: skip
    hand = len(set().union(*map(_fingers, named))) >= 2  # (FINGER_NAMES count: two named)
    for j in range(model.njnt):
        if int(model.jnt_type[j]) not in _SCALAR_JOINTS:
            continue
        body = int(model.jnt_bodyid[j])
        name = named[j]
        body_name = (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or "").lower()
        words = [word for word in GRIPPER_WORDS if word in name]
        if words == ["gripper"] and any(axis in name for axis in _WRIST_AXES):
            continue  # (a wrist joint that turns the gripper: erd Alex's LeftGripperYaw)
        by_body = not below[body] and (
            any(word in body_name for word in GRIPPER_WORDS) or (hand and bool(_fingers(body_name)))
        )
        if words or (hand and _fingers(name)) or by_body:
            found.append(j)
    return found


def _fingers(name: str) -> set[str]:
    """The fingers (:data:`FINGER_NAMES`, ``thumb``) whole words of a lower-case ``name``."""
    return {w for w in re.split(r"[^a-z0-9]+", name) if w in FINGER_NAMES or w == "thumb"}


_SCALAR_JOINTS = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
#: Axis words of a wrist joint: a joint named for the gripper and one of them turns the
#: gripper (the arm's), not a finger.
_WRIST_AXES = ("yaw", "roll", "pitch")


def _chains(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per body: arm joints from the world (hinge/slide, not a gripper's), depth, whether
    a gripper joint moves it (on it or on an ancestor), and whether the arm goes on below
    it (exactly one of its children's subtrees holds arm joints: a ``wrist_link`` above the
    wrist's roll joint, where a palm has a subtree per finger). A robot whose every joint
    is a gripper's (a finger, a hand alone) is its own arm: its joints are arm joints."""
    grippers = set(gripper_joints(model))
    scalar = [j for j in range(model.njnt) if int(model.jnt_type[j]) in _SCALAR_JOINTS]
    if scalar and grippers >= set(scalar):
        grippers = set()
    joints = np.zeros(model.nbody, dtype=int)
    depth = np.zeros(model.nbody, dtype=int)
    moved = np.zeros(model.nbody, dtype=bool)
    own_arm = np.zeros(model.nbody, dtype=int)  # arm joints on the body itself
    for b in range(1, model.nbody):  # parents come before children
        parent = model.body_parentid[b]
        own = range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b])
        own_arm[b] = sum(
            int(model.jnt_type[j]) in _SCALAR_JOINTS and j not in grippers for j in own
        )
        joints[b] = joints[parent] + own_arm[b]
        depth[b] = depth[parent] + 1
        moved[b] = moved[parent] or any(j in grippers for j in own)
    holds = own_arm > 0  # an arm joint in the body's subtree
    branches = np.zeros(model.nbody, dtype=int)  # children whose subtree holds one
    for b in range(model.nbody - 1, 0, -1):  # children come after parents
        if holds[b]:
            parent = model.body_parentid[b]
            holds[parent] = True
            branches[parent] += 1
    return joints, depth, moved, branches == 1


def _name_matches(name: str, known: str) -> bool:
    """Whether ``name`` is ``known`` or ends with it after ``/`` or ``_``, in any case
    (Spot's site ``EE``, a link ``Left_Palm``)."""
    name = name.lower()
    return name == known or name.endswith("/" + known) or name.endswith("_" + known)


def _named_tool(model: mujoco.MjModel, joints, moved, goes_on) -> ToolFrame | None:
    """The site or body whose name is a known tool centre point's, flange's or hand's (in
    that order; on the longest chain first), never one a gripper joint moves, nor one no arm
    joint moves (an arm's or a hand's base) where some body is; a wrist's name not where the
    arm goes on below it (``goes_on``: so101's ``wrist_link``, above its wrist roll; a palm
    has its fingers below it)."""
    site_body = model.site_bodyid
    sites = [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s) or "" for s in range(model.nsite)
    ]
    bodies = [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or "" for b in range(model.nbody)
    ]

    moving = bool(joints.max() > 0)

    def best(names: list[str], owner, known: str, hand: bool) -> int | None:
        hits = [i for i, n in enumerate(names) if n and _name_matches(n, known)]
        hits = [
            i
            for i in hits
            if not moved[owner(i)]
            and (joints[owner(i)] > 0 or not moving)
            and not (hand and goes_on[owner(i)])
        ]
        if not hits:
            return None
        return max(hits, key=lambda i: (joints[owner(i)], -i))

    # A hand's name may also end in "_link" (booster_t1's left_hand_link).
    hands = tuple(name for known in HAND_NAMES for name in (known, known + "_link"))
    for names, what in (
        (TCP_NAMES, "a tool centre point's name"),
        (FLANGE_NAMES, "a flange's name"),
        (hands, "a hand's name"),
    ):
        for known in names:
            # (a wrist's name, not where the arm goes on below it: its roll joint)
            hand = names is hands and known.startswith("wrist")
            site = best(sites, lambda s: int(site_body[s]), known, hand)
            if site is not None:
                return ToolFrame(sites[site], "site", f"the site with {what} ({known!r})")
            body = best(bodies, lambda b: b, known, hand)
            if body is not None and body > 0:
                return ToolFrame(bodies[body], "body", f"the body with {what} ({known!r})")
    return None


def _chain_end(model: mujoco.MjModel, joints, depth, moved) -> ToolFrame:
    """The end of the longest chain, then down through joint-less links with a single
    child (flange, sensor, ...)."""
    candidates = [b for b in range(1, model.nbody) if not moved[b]] or list(range(1, model.nbody))
    end = max(candidates, key=lambda b: (joints[b], -depth[b], -b))
    while True:
        children = [
            c for c in range(end + 1, model.nbody) if model.body_parentid[c] == end and not moved[c]
        ]
        every_child = sum(model.body_parentid[c] == end for c in range(end + 1, model.nbody))
        if every_child != 1 or len(children) != 1 or model.body_jntnum[children[0]]:
            break
        end = children[0]
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, end) or str(end)
    return ToolFrame(name, "body", "the end of the longest chain (no site 'ee', no known name)")


def tool_frame(model: mujoco.MjModel) -> ToolFrame:
    """The robot's tool frame, a site or a body, never one a gripper joint moves: the site
    named ``ee``; else a site or body with a known tool centre point's, flange's or hand's
    name; else a known tool link; else the end of the longest chain. Raises
    :class:`qpik.errors.RobotFileError` for a model with no body."""
    checks.check_instance("model", model, mujoco.MjModel, "a mujoco.MjModel")
    if model.nbody < 2:
        raise RobotFileError("<model>", "the model has no body to use as a tool frame")
    joints, depth, moved, goes_on = _chains(model)
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "ee") >= 0:
        return ToolFrame("ee", "site", "the site named ee")
    named = _named_tool(model, joints, moved, goes_on)
    if named is not None:
        return named
    for name in TOOL_LINKS:
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        if b > 0 and not moved[b] and joints[b] > 0:
            return ToolFrame(name, "body", "a known tool link (no site 'ee')")
    return _chain_end(model, joints, depth, moved)
