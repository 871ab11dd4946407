"""Load robot models: bundled MJCF files, your own MJCF or URDF, or example-robot-data.

``load_robot(source)`` accepts:

* the name of a bundled model (``qpik.list_robots()``): ``"planar_2r"``, ``"panda"``, ...;
* a path to an MJCF ``.xml`` file or a ``.urdf`` file;
* a ``mujoco.MjModel`` (returned as is);
* ``"erd:NAME"``: the URDF that the package ``example-robot-data`` ships for robot NAME
  (``"erd:panda"``, ``"erd:ur5"``, ...; install it with ``pip install 'qpik[robots]'``).

URDF import keeps what inverse kinematics needs and works around what real files contain:

* links attached by fixed joints (tool frames such as ``panda_hand`` or ``tool0``) are kept
  as bodies, not fused into their parent, so they can be used as frames;
* ``continuous`` joints become hinge joints *without* limits (``lower``/``upper`` = -/+inf);
* visual geometry is discarded, and collision meshes that MuJoCo cannot read (``.dae``)
  or cannot find are dropped, with one warning naming them; the kinematics is unchanged.
"""

from __future__ import annotations

import os
import warnings
import xml.etree.ElementTree as ET
from importlib import metadata, resources
from pathlib import Path

import mujoco

from .errors import MissingExtra, RobotFileError, UnknownRobot

__all__ = [
    "ERD_ROBOTS",
    "erd_robots_folder",
    "list_robots",
    "load_robot",
    "robot_path",
    "robots_dir",
]

#: Mesh formats MuJoCo reads.
_READABLE_MESHES = {".stl", ".obj", ".msh"}

#: ``erd:`` names and the URDF each maps to inside example-robot-data's ``robots/`` folder.
ERD_ROBOTS: dict[str, str] = {
    "panda": "panda_description/urdf/panda.urdf",
    "ur3": "ur_description/urdf/ur3_robot.urdf",
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "ur10": "ur_description/urdf/ur10_robot.urdf",
    "xarm7": "xarm_description/urdf/xarm7.urdf",
    "talos_left_arm": "talos_data/robots/talos_left_arm.urdf",
    "kinova": "kinova_description/robots/kinova.urdf",
    "z1": "z1_description/urdf/z1.urdf",
    "double_pendulum": "double_pendulum_description/urdf/double_pendulum.urdf",
}


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
    if not path.is_file():
        raise UnknownRobot(name, list_robots())
    return path


def load_robot(source: str | os.PathLike | mujoco.MjModel) -> mujoco.MjModel:
    """Load a robot model (see the module docstring for what ``source`` may be)."""
    if isinstance(source, mujoco.MjModel):
        return source
    if not isinstance(source, (str, os.PathLike)):
        raise TypeError(
            f"load_robot expects a name, a path or an MjModel, got {type(source).__name__}"
        )
    text = os.fspath(source)
    if text.startswith("erd:"):
        return _load_erd(text[4:])
    path = Path(text)
    if path.suffix.lower() in (".xml", ".urdf") or os.sep in text or path.exists():
        return _load_file(path)
    return _load_file(robot_path(text))


def _load_file(path: Path) -> mujoco.MjModel:
    if not path.is_file():
        raise RobotFileError(str(path), "no such file")
    try:
        text = path.read_text()
    except OSError as exc:
        raise RobotFileError(str(path), str(exc)) from exc
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise RobotFileError(str(path), f"not well-formed XML ({exc})") from exc
    try:
        if root.tag == "robot":
            return mujoco.MjModel.from_xml_string(_prepare_urdf(root, path))
        if root.tag != "mujoco":
            raise RobotFileError(
                str(path), f"root element is <{root.tag}>, expected <mujoco> or <robot>"
            )
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:  # MuJoCo's compile errors
        raise RobotFileError(str(path), str(exc).strip()) from exc


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
            stacklevel=4,
        )
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


def _load_erd(name: str) -> mujoco.MjModel:
    base = erd_robots_folder()
    if name not in ERD_ROBOTS:
        raise UnknownRobot(f"erd:{name}", [f"erd:{n}" for n in ERD_ROBOTS])
    return _load_file(base / ERD_ROBOTS[name])


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
