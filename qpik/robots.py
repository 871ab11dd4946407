"""Load robot models: bundled MJCF files, your own MJCF or URDF, or example-robot-data.

``load_robot(source, *, floating_base=False, srdf=None)`` accepts:

* the name of a bundled model (``qpik.list_robots()``): ``"planar_2r"``, ``"panda"``, ...;
* a path to an MJCF ``.xml`` file or a ``.urdf`` file;
* a ``mujoco.MjModel`` (returned as is);
* ``"erd:NAME"``: a URDF that the package ``example-robot-data`` ships
  (``"erd:panda"``, ``"erd:ur5"``, ``"erd:talos"``, ...; every name: :func:`erd_robots`;
  install it with ``pip install 'qpik[robots]'``).

URDF import keeps what inverse kinematics needs and works around what real files contain:

* links attached by fixed joints (tool frames such as ``panda_hand`` or ``tool0``) are kept
  as bodies, not fused into their parent, so they can be used as frames;
* ``continuous`` joints become hinge joints *without* limits (``lower``/``upper`` = -/+inf);
* ``<limit velocity=...>`` [rad/s or m/s] becomes the model's custom numeric
  ``velocity_limit`` (one value per dof, 0 where a dof has none), which
  :func:`qpik.limits.joint_limits` turns into a velocity limit; ``<limit effort=...>``
  [N m or N] is MuJoCo's joint ``actuatorfrcrange``, which :mod:`qpik.statics` reads where
  no actuator drives the joint;
* visual geometry is discarded, and collision meshes that MuJoCo cannot read (``.dae``)
  or cannot find are dropped, with one warning naming them; the kinematics is unchanged.

Floating base. URDF files (and most MJCF files) attach the root link to the world rigidly.
``floating_base=True`` adds a free joint named ``root_joint`` (Pinocchio's name for it) to
the root body: ``q = [x, y, z, qw, qx, qy, qz, joints...]`` (MuJoCo's quaternion order,
world frame), ``v = [linear velocity (world), angular velocity (local), joints...]``.

Named configurations. An SRDF beside the URDF (same stem, or the longest SRDF stem that
prefixes the URDF's, in the URDF's folder or a sibling ``srdf/`` folder; or the file given
as ``srdf=``) has its ``<group_state>`` entries loaded as MuJoCo keyframes
(``model.key("half_sitting")``), usable as ``q0 = "half_sitting"`` in problem files. Joints
a state does not name keep ``qpos0``; ``root_joint`` values (Pinocchio's ``x y z qx qy qz
qw``) set the free joint's pose when the base floats.

Every model ``load_robot`` builds also carries how it was built (a custom text element
named :data:`SOURCE_TEXT`: the file, ``floating_base``, ``srdf``, as JSON), so that
:func:`qpik.scene.add_obstacle` can rebuild it, bit for bit, with more geoms.

Tool frame. :func:`tool_frame` names the frame a command uses when none is given: the site
``ee`` if the model has one; else the first known tool link (:data:`TOOL_LINKS`) found; else
the last body of the longest chain (most hinge/slide joints from the world; ties: the
deepest body, then the lowest id).
"""

from __future__ import annotations

import json
import os
import re
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from importlib import metadata, resources
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from .errors import InvalidInput, MissingExtra, RobotFileError, UnknownRobot

__all__ = [
    "ERD_ROBOTS",
    "SOURCE_TEXT",
    "TOOL_LINKS",
    "ToolFrame",
    "erd_path",
    "erd_robots",
    "erd_robots_folder",
    "find_srdf",
    "list_robots",
    "load_robot",
    "locate_robot",
    "resolve_robot",
    "robot_path",
    "robot_spec",
    "robots_dir",
    "tool_frame",
]

#: Mesh formats MuJoCo reads.
_READABLE_MESHES = {".stl", ".obj", ".msh"}

#: Name of the free joint ``floating_base=True`` adds (Pinocchio's and the SRDFs' name).
ROOT_JOINT = "root_joint"

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

#: Link names known to be a robot's tool frame, in the order :func:`tool_frame` tries them.
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
    "panda_hand",
)


def robots_dir() -> Path:
    """The folder holding the bundled robot files.

    In an installed wheel they live in ``qpik/_robots``; in a source checkout (or an
    editable install) they are the repository's top-level ``robots/`` folder.
    """
    packaged = Path(str(resources.files("qpik"))) / "_robots"
    if packaged.is_dir():
        return packaged
    return Path(__file__).resolve().parent.parent / "robots"


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
    """Load a robot model (see the module docstring for what ``source`` may be).

    Args:
        source: a bundled name, ``"erd:NAME"``, a path to an ``.xml``/``.urdf`` file, or
            an ``MjModel`` (returned as is; ``floating_base`` and ``srdf`` must then be
            left at their defaults).
        floating_base: add a free joint ``root_joint`` at the root body (a humanoid or a
            legged robot whose base moves in the world).
        srdf: an SRDF file whose named states become keyframes; ``None`` (default) or
            ``True``: look for one beside a URDF; ``False``: none.
    """
    if isinstance(source, mujoco.MjModel):
        if floating_base or srdf not in (None, False):
            raise RobotFileError(
                "<MjModel>", "floating_base and srdf apply when loading a file, not to a model"
            )
        return source
    if not isinstance(source, (str, os.PathLike)):
        raise InvalidInput(
            f"load_robot expects a name, a path or an MjModel, got {type(source).__name__}"
        )
    path = locate_robot(source)
    return _load_file(path, floating_base=floating_base, srdf=srdf)


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


def resolve_robot(
    robot: Any,
    *,
    relative_to: str | os.PathLike | None = None,
    floating_base: bool = False,
) -> tuple[mujoco.MjModel, np.ndarray | None]:
    """The one resolver of what qpik's entry points accept as a robot: ``(model, q)``.

    Args:
        robot: a :class:`qpik.Configuration` (its model, and a copy of its ``q``: the
            caller's start), a ``mujoco.MjModel`` (as is, ``q`` ``None``), or anything
            :func:`locate_robot` resolves (a bundled name, ``"erd:NAME"``, a path), loaded
            with :func:`load_robot` (``q`` ``None``).
        relative_to: the folder a relative path is read from (default: the working
            directory).
        floating_base: passed to :func:`load_robot` for a file.

    Raises :class:`qpik.InvalidInput` naming ``robot`` for anything else, and
    :func:`load_robot`'s errors.
    """
    from .configuration import Configuration  # robots is imported by configuration's users

    if isinstance(robot, Configuration):
        return robot.model, robot.q
    if isinstance(robot, mujoco.MjModel):
        return robot, None
    if isinstance(robot, (str, os.PathLike)):
        path = locate_robot(robot, relative_to=relative_to)
        return load_robot(path, floating_base=floating_base), None
    raise InvalidInput(
        "robot must be a robot name, 'erd:NAME', a path, a mujoco.MjModel or a "
        f"qpik.Configuration, got {type(robot).__name__}"
    )


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
    recipe = {
        "path": str(path.resolve()),
        "floating_base": bool(floating_base),
        "srdf": srdf if srdf in (None, False, True) else str(Path(os.fspath(srdf)).resolve()),
        "obstacles": [],
    }
    spec.add_text(name=SOURCE_TEXT, data=json.dumps(recipe))
    try:
        return spec.compile()
    except ValueError as exc:  # pragma: no cover - the model compiled a moment ago
        raise RobotFileError(str(path), str(exc).strip()) from exc


def robot_spec(
    path: str | os.PathLike,
    *,
    floating_base: bool = False,
    srdf: str | os.PathLike | bool | None = None,
) -> mujoco.MjSpec:
    """The ``mujoco.MjSpec`` :func:`load_robot` compiles for a file (same arguments): edit
    it (add bodies, geoms, sites) and ``compile()`` it for a model of your own."""
    path = Path(os.fspath(path))
    try:
        is_file = path.is_file()
    except (OSError, ValueError) as exc:
        raise RobotFileError(str(path)[:200], f"not a usable file name ({exc})") from None
    if not is_file:
        raise RobotFileError(str(path), "no such file")
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise RobotFileError(str(path), f"not UTF-8 text ({exc})") from None
    except OSError as exc:
        raise RobotFileError(str(path), str(exc)) from exc
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise RobotFileError(str(path), f"not well-formed XML ({exc})") from exc
    velocities: dict[str, float] = {}
    try:
        if root.tag == "robot":
            velocities = _urdf_velocities(root)
            spec = mujoco.MjSpec.from_string(_prepare_urdf(root, path))
            _drop_bad_meshes(spec, path)
        elif root.tag == "mujoco":
            spec = mujoco.MjSpec.from_file(str(path))
        else:
            raise RobotFileError(
                str(path), f"root element is <{root.tag}>, expected <mujoco> or <robot>"
            )
        if floating_base:
            _add_free_joint(spec, path)
        model = spec.compile()
    except ValueError as exc:  # MuJoCo's parse and compile errors
        raise RobotFileError(str(path), str(exc).strip()) from exc
    _check_finite(model, path)
    if velocities:
        _add_velocity_numeric(spec, model, velocities)
    srdf_path = None
    if srdf in (None, True) and root.tag == "robot":
        srdf_path = find_srdf(path)
    elif srdf not in (None, False, True):
        srdf_path = Path(os.fspath(srdf))
        if not srdf_path.is_file():
            raise RobotFileError(str(srdf_path), "no such SRDF file")
    if srdf_path is not None:
        _add_srdf_keyframes(spec, model, srdf_path)
    return spec


#: Model arrays that must be finite (MuJoCo compiles NaN / inf numbers in a file as is).
_FINITE_FIELDS = (
    "body_pos",
    "body_quat",
    "body_ipos",
    "body_iquat",
    "body_mass",
    "body_inertia",
    "jnt_pos",
    "jnt_axis",
    "jnt_range",
    "dof_damping",
    "dof_armature",
    "dof_frictionloss",
    "geom_pos",
    "geom_quat",
    "geom_size",
    "site_pos",
    "site_quat",
    "actuator_gear",
    "actuator_ctrlrange",
    "actuator_forcerange",
    "qpos0",
)


def _check_finite(model: mujoco.MjModel, path: Path) -> None:
    """Raise :class:`RobotFileError` naming the first non-finite number of the model."""
    if not np.all(np.isfinite(model.opt.gravity)):
        raise RobotFileError(str(path), f"gravity is not finite: {model.opt.gravity}")
    for name in _FINITE_FIELDS:
        values = np.asarray(getattr(model, name))
        bad = np.argwhere(~np.isfinite(values))
        if bad.size:
            row = int(bad[0][0])
            what = name.split("_", 1)[0]
            obj = {
                "body": mujoco.mjtObj.mjOBJ_BODY,
                "jnt": mujoco.mjtObj.mjOBJ_JOINT,
                "dof": mujoco.mjtObj.mjOBJ_DOF,
                "geom": mujoco.mjtObj.mjOBJ_GEOM,
                "site": mujoco.mjtObj.mjOBJ_SITE,
                "actuator": mujoco.mjtObj.mjOBJ_ACTUATOR,
            }.get(what)
            label = (mujoco.mj_id2name(model, obj, row) if obj is not None else None) or row
            raise RobotFileError(
                str(path), f"{name} of {what} {label!r} is not finite: {values[row]}"
            )


def _resolve_mesh(filename: str, urdf_path: Path) -> Path | None:
    """Resolve a URDF mesh reference (relative, absolute, ``package://`` or ``file://``)."""
    if filename.startswith("file://"):
        candidate = Path(filename[7:])
        return candidate if candidate.is_file() else None
    if filename.startswith("package://"):
        package, _, rest = filename[len("package://") :].partition("/")
        # Look for a folder named like the package above the URDF file.
        for parent in urdf_path.resolve().parents:
            for base in (parent / package, parent / "robots" / package):
                if (base / rest).is_file():
                    return base / rest
            if parent.name == package and (parent / rest).is_file():
                return parent / rest
        return None
    candidate = Path(filename)
    if not candidate.is_absolute():
        candidate = urdf_path.resolve().parent / candidate
    return candidate if candidate.is_file() else None


def _prepare_urdf(root: ET.Element, path: Path) -> str:
    """Rewrite a URDF so that MuJoCo keeps fixed links and drops unusable meshes."""
    dropped: list[str] = []
    for link in root.iter("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
        for collision in link.findall("collision"):
            mesh = collision.find("geometry/mesh")
            if mesh is None:
                continue
            filename = mesh.get("filename", "")
            resolved = _resolve_mesh(filename, path)
            if resolved is None or resolved.suffix.lower() not in _READABLE_MESHES:
                dropped.append(filename)
                link.remove(collision)
            else:
                mesh.set("filename", str(resolved))
    if dropped:
        warnings.warn(
            f"{path}: dropped {len(dropped)} collision mesh(es) MuJoCo cannot read or find "
            f"(kinematics kept): {', '.join(sorted(set(dropped))[:5])}"
            + (" ..." if len(set(dropped)) > 5 else ""),
            stacklevel=5,
        )
    _positive_inertias(root, path)
    for old in root.findall("mujoco"):
        root.remove(old)
    extension = ET.SubElement(root, "mujoco")
    ET.SubElement(
        extension,
        "compiler",
        fusestatic="false",
        discardvisual="true",
        strippath="false",
        balanceinertia="true",
        boundmass="1e-6",
        boundinertia="1e-9",
        angle="radian",
    )
    return ET.tostring(root, encoding="unicode")


def _drop_bad_meshes(spec: mujoco.MjSpec, path: Path) -> None:
    """Compile, and drop each collision mesh MuJoCo rejects (an ASCII STL, a mesh of no
    volume) with the geoms that use it, until the model compiles; one warning names them."""
    dropped = []
    for _ in range(len(spec.meshes) + 1):
        try:
            spec.compile()
            break
        except ValueError as exc:
            message = str(exc)
            match = re.search(r"Element name '([^']*)'", message)
            mesh = None
            if match and ("mesh" in message.lower() or "stl" in message.lower()):
                mesh = next((m for m in spec.meshes if m.name == match.group(1)), None)
            if mesh is None:
                break  # not a mesh error: the caller compiles again and reports it
            for geom in list(spec.geoms):
                if geom.meshname == mesh.name:
                    spec.delete(geom)
            dropped.append(Path(mesh.file).name)
            spec.delete(mesh)
    if dropped:
        warnings.warn(
            f"{path}: dropped {len(dropped)} collision mesh(es) MuJoCo rejects "
            f"(kinematics kept): {', '.join(sorted(set(dropped))[:5])}",
            stacklevel=5,
        )


def _positive_inertias(root: ET.Element, path: Path) -> None:
    """Replace inertia matrices MuJoCo rejects (a full inertia that is not positive
    definite: rounded CAD exports) by the nearest one with eigenvalues >= 1e-9 [kg m^2];
    the kinematics is unchanged."""
    fixed = []
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    for link in root.iter("link"):
        inertia = link.find("inertial/inertia")
        if inertia is None:
            continue
        try:
            xx, xy, xz, yy, yz, zz = (float(inertia.get(k, "0")) for k in keys)
        except ValueError:
            continue
        matrix = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        if not np.all(np.isfinite(matrix)):
            continue
        values, vectors = np.linalg.eigh(matrix)
        coupled = bool(xy or xz or yz)  # MuJoCo checks a full inertia's eigenvalues
        if values.min() >= 0 and not (coupled and values.min() <= 1e-12 * abs(values).max()):
            continue  # diagonal zeros are MuJoCo's boundinertia's to fix
        matrix = vectors @ np.diag(np.maximum(values, 1e-9)) @ vectors.T
        for key, value in zip(keys, matrix[np.triu_indices(3)]):
            inertia.set(key, repr(float(value)))
        fixed.append(link.get("name", "?"))
    if fixed:
        warnings.warn(
            f"{path}: {len(fixed)} link inertia(s) not positive definite, made positive "
            f"(kinematics kept): {', '.join(fixed[:5])}" + (" ..." if len(fixed) > 5 else ""),
            stacklevel=6,
        )


def _urdf_velocities(root: ET.Element) -> dict[str, float]:
    """Joint name -> ``<limit velocity>`` [rad/s or m/s] for joints that declare one > 0."""
    velocities = {}
    for joint in root.iter("joint"):
        if joint.get("type") in ("fixed", "floating", "planar"):
            continue
        limit = joint.find("limit")
        if limit is None or limit.get("velocity") is None:
            continue
        try:
            value = float(limit.get("velocity"))
        except ValueError:
            continue
        if value > 0 and np.isfinite(value):
            velocities[joint.get("name", "")] = value
    return velocities


def _add_velocity_numeric(
    spec: mujoco.MjSpec, model: mujoco.MjModel, velocities: dict[str, float]
) -> None:
    """The custom numeric ``velocity_limit`` ``(nv,)``: the URDF's values, 0 = none."""
    data = np.zeros(model.nv)
    for name, value in velocities.items():
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if j >= 0 and int(model.jnt_type[j]) in (
            int(mujoco.mjtJoint.mjJNT_HINGE),
            int(mujoco.mjtJoint.mjJNT_SLIDE),
        ):
            data[model.jnt_dofadr[j]] = value
    for numeric in spec.numerics:
        if numeric.name == "velocity_limit":
            spec.delete(numeric)
    spec.add_numeric(name="velocity_limit", data=data.tolist())


def _add_free_joint(spec: mujoco.MjSpec, path: Path) -> None:
    roots = []
    body = spec.worldbody.first_body()
    while body is not None:
        roots.append(body)
        body = spec.worldbody.next_body(body)
    if len(roots) != 1:
        raise RobotFileError(
            str(path),
            f"floating_base needs one root body under the world, found {len(roots)}: "
            f"{', '.join(b.name for b in roots) or '(none)'}",
        )
    root = roots[0]
    if root.first_joint() is not None:
        raise RobotFileError(
            str(path),
            f"floating_base: the root body {root.name!r} already has a joint "
            f"({root.first_joint().name!r})",
        )
    joint = root.add_freejoint()
    joint.name = ROOT_JOINT


def find_srdf(urdf: str | os.PathLike) -> Path | None:
    """The SRDF that goes with a URDF, or ``None`` (rule in the module docstring)."""
    urdf = Path(urdf)
    folders = [urdf.parent, urdf.parent.parent / "srdf"]
    candidates = [p for folder in folders if folder.is_dir() for p in folder.glob("*.srdf")]
    exact = [p for p in candidates if p.stem == urdf.stem]
    if exact:
        return exact[0]
    prefixes = [p for p in candidates if urdf.stem.startswith(p.stem)]
    if prefixes:
        return max(prefixes, key=lambda p: (len(p.stem), str(p)))
    return None


def _add_srdf_keyframes(spec: mujoco.MjSpec, model: mujoco.MjModel, path: Path) -> bool:
    """The SRDF's ``<group_state>`` entries as keyframes; True if any was added."""
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        raise RobotFileError(str(path), f"cannot read SRDF ({exc})") from exc
    existing = {key.name for key in spec.keys}
    added = False
    for state in root.iter("group_state"):
        name = state.get("name")
        if not name or name in existing:
            continue
        qpos = model.qpos0.copy()
        for joint in state.iter("joint"):
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint.get("name", ""))
            if j < 0:
                continue
            try:
                values = [float(x) for x in joint.get("value", "").split()]
            except ValueError as exc:
                raise RobotFileError(
                    str(path), f"group_state {name!r}: joint {joint.get('name')!r}: {exc}"
                ) from exc
            adr = model.jnt_qposadr[j]
            kind = int(model.jnt_type[j])
            if kind == int(mujoco.mjtJoint.mjJNT_FREE) and len(values) == 7:
                x, y, z, qx, qy, qz, qw = values
                qpos[adr : adr + 7] = [x, y, z, qw, qx, qy, qz]
            elif kind == int(mujoco.mjtJoint.mjJNT_BALL) and len(values) == 4:
                qx, qy, qz, qw = values
                qpos[adr : adr + 4] = [qw, qx, qy, qz]
            elif len(values) == 1 and kind in (
                int(mujoco.mjtJoint.mjJNT_HINGE),
                int(mujoco.mjtJoint.mjJNT_SLIDE),
            ):
                qpos[adr] = values[0]
        spec.add_key(name=name, qpos=qpos.tolist())
        existing.add(name)
        added = True
    return added


# --------------------------------------------------------------------- tool frame
@dataclass(frozen=True)
class ToolFrame:
    """A robot's tool frame: ``name`` and ``frame_type`` (``"site"`` or ``"body"``), and
    ``reason``, the rule that chose it (for the commands to print)."""

    name: str
    frame_type: str
    reason: str


def tool_frame(model: mujoco.MjModel) -> ToolFrame:
    """The robot's tool frame (rule in the module docstring)."""
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "ee") >= 0:
        return ToolFrame("ee", "site", "the site named ee")
    for name in TOOL_LINKS:
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) >= 0:
            return ToolFrame(name, "body", "a known tool link (no site 'ee')")
    if model.nbody < 2:
        raise RobotFileError("<model>", "the model has no body to use as a tool frame")
    scalar = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    joints = np.zeros(model.nbody, dtype=int)
    depth = np.zeros(model.nbody, dtype=int)
    for b in range(1, model.nbody):  # parents come before children
        parent = model.body_parentid[b]
        own = sum(
            int(model.jnt_type[j]) in scalar
            for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b])
        )
        joints[b] = joints[parent] + own
        depth[b] = depth[parent] + 1
    best = max(range(1, model.nbody), key=lambda b: (joints[b], depth[b], -b))
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, best) or str(best)
    return ToolFrame(name, "body", "the last link of the longest chain (no site 'ee')")
