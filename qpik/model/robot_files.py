"""Robot files into ``mujoco.MjSpec``: MJCF as MuJoCo reads it, and URDF with the
workarounds real files need; a floating base, SRDF keyframes, and a check that every
number of the model is finite (:func:`robot_spec`, behind :func:`qpik.load_robot`).

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

Collision pairs. The same SRDF's ``<disable_collisions link1=... link2=...>`` entries (each
pair MoveIt's setup assistant found adjacent, in collision in the default pose, always in
collision, or never in collision, or that its author excluded) become MuJoCo contact
excludes between the two links' bodies (``model.exclude_signature``), as Pinocchio's
``removeCollisionPairs`` and PlaCo read them: :func:`qpik.limits.collision_pairs` and
:func:`qpik.limits.model_collision_limit` leave them out, and so does MuJoCo's own
collision detection. Without them, links whose collision meshes overlap in every pose
(erd Talos's ``arm_left_5_link`` and ``arm_left_7_link``, PR2's ``base_link`` and
``r_shoulder_pan_link``) make a collision row no step can meet. ``srdf=False`` reads
neither the states nor the pairs.
"""

from __future__ import annotations

import os
import re
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import cast

import mujoco
import numpy as np

from ..core import checks
from ..errors import RobotFileError
from .frames import FRAME_OBJECTS, excluded_body_pairs

__all__ = ["LENGTH_FIELDS", "ROOT_JOINT", "check_lengths", "find_srdf", "robot_spec"]

#: Mesh formats MuJoCo reads.
_READABLE_MESHES = {".stl", ".obj", ".msh"}

#: Name of the free joint ``floating_base=True`` adds (Pinocchio's and the SRDFs' name).
ROOT_JOINT = "root_joint"


def robot_spec(
    path: str | os.PathLike,
    *,
    floating_base: bool = False,
    srdf: str | os.PathLike | bool | None = None,
) -> mujoco.MjSpec:
    """The ``mujoco.MjSpec`` :func:`qpik.load_robot` compiles for a file (same arguments):
    edit it (add bodies, geoms, sites) and ``compile()`` it for a model of your own.
    Raises :class:`qpik.RobotFileError` naming the file and what is wrong with it."""
    path = Path(os.fspath(path))
    root = _read_xml(path)
    velocities = _urdf_velocities(root) if root.tag == "robot" else {}
    try:
        spec = _parse(root, path)
        if floating_base:
            _add_free_joint(spec, path)
        model = spec.compile()
    except ValueError as exc:  # MuJoCo's parse and compile errors
        raise RobotFileError(str(path), str(exc).strip()) from exc
    _check_finite(model, path)
    check_lengths(model, str(path))
    if root.tag == "robot":
        _check_urdf_limits(root, path)
    if velocities:
        _add_velocity_numeric(spec, model, velocities)
    srdf_path = _srdf_path(srdf, root, path)
    if srdf_path is not None:
        srdf_root = _read_srdf(srdf_path)
        _add_srdf_keyframes(spec, model, srdf_root, srdf_path)
        _add_srdf_exclusions(spec, model, srdf_root)
    return spec


def _read_xml(path: Path) -> ET.Element:
    """The root element of an XML file (UTF-8, a BOM allowed)."""
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
        return ET.fromstring(text)
    except ET.ParseError as exc:
        raise RobotFileError(str(path), f"not well-formed XML ({exc})") from exc


def _parse(root: ET.Element, path: Path) -> mujoco.MjSpec:
    """The spec of a URDF (prepared, unreadable meshes dropped) or MJCF file."""
    if root.tag == "robot":
        spec = mujoco.MjSpec.from_string(_prepare_urdf(root, path))
        _drop_bad_meshes(spec, path)
        return spec
    if root.tag == "mujoco":
        return mujoco.MjSpec.from_file(str(path))
    raise RobotFileError(str(path), f"root element is <{root.tag}>, expected <mujoco> or <robot>")


def _srdf_path(srdf: str | os.PathLike | bool | None, root: ET.Element, path: Path) -> Path | None:
    """The SRDF to read: the one given, or for a URDF with ``srdf`` None/True the one found
    beside it (:func:`find_srdf`)."""
    if srdf in (None, True):
        return find_srdf(path) if root.tag == "robot" else None
    if srdf is False:
        return None
    srdf_path = Path(os.fspath(cast("str | os.PathLike", srdf)))  # None, True, False handled
    if not srdf_path.is_file():
        raise RobotFileError(str(srdf_path), "no such SRDF file")
    return srdf_path


#: Model arrays that must be finite (MuJoCo compiles NaN / inf numbers in a file as is).
#: The object type named by the prefix of a model field (``body_``, ``jnt_``, ...).
_FIELD_OBJECTS = {
    **{kind.value: obj for kind, obj in FRAME_OBJECTS.items()},
    "jnt": mujoco.mjtObj.mjOBJ_JOINT,
    "dof": mujoco.mjtObj.mjOBJ_DOF,
    "actuator": mujoco.mjtObj.mjOBJ_ACTUATOR,
    "key": mujoco.mjtObj.mjOBJ_KEY,
}
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
    "jnt_actfrcrange",  # a URDF's <limit effort>: inf would be an unbounded torque limit
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
    "key_qpos",  # an MJCF <key qpos> or an SRDF <group_state> value of NaN or inf
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
            obj = _FIELD_OBJECTS.get(what)
            label = (mujoco.mj_id2name(model, obj, row) if obj is not None else None) or row
            raise RobotFileError(
                str(path), f"{name} of {what} {label!r} is not finite: {values[row]}"
            )


#: The model arrays of positions [m] that :func:`check_lengths` bounds.
LENGTH_FIELDS = ("body_pos", "body_ipos", "jnt_pos", "site_pos", "geom_pos")


def check_lengths(model: mujoco.MjModel, where: str) -> None:
    """Raise :class:`RobotFileError` naming ``where`` for a position of :data:`LENGTH_FIELDS`
    (body, joint, site, geom, centre of mass) that is not finite or farther than
    :data:`qpik.core.checks.MAX_LENGTH` [m] from its parent (MuJoCo's dynamics overflow:
    NaN gravity torques)."""
    for name in LENGTH_FIELDS:
        values = np.asarray(getattr(model, name))
        bad = ~(np.abs(values) <= checks.MAX_LENGTH)  # NaN too
        if bad.any():
            row = int(np.argwhere(bad)[0][0])
            raise RobotFileError(
                where,
                f"{name}[{row}] = {values[row].tolist()}: positions must be finite and within "
                f"{checks.MAX_LENGTH:g} m",
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


def _check_urdf_limits(root: ET.Element, path: Path) -> None:
    """Raise :class:`RobotFileError` naming the file and the joint for what MuJoCo would load
    as another robot without an error: a revolute or prismatic joint whose ``<limit lower
    upper>`` is empty (lower above upper: MuJoCo loads it unlimited, where the same range in
    MJCF is an error); a joint name used twice (the second joint loses its name, and its
    velocity limit goes to the first); a ``<limit velocity>`` that is not a number >= 0 or
    an ``effort`` of NaN (dropped: no limit). A ``<mimic>`` of a joint that does not exist or
    does not move (MuJoCo drops the coupling) and equal bounds (which MuJoCo reads as no
    limit) get a warning naming the joint. (Other numbers that do not parse are MuJoCo's to
    report.)"""
    # (the robot's own joints: a <transmission> names its joint in a <joint> element too)
    joints = {joint.get("name"): joint.get("type") for joint in root.findall("joint")}
    seen: set[str | None] = set()
    for joint in root.findall("joint"):
        name = joint.get("name")
        if name in seen:
            raise RobotFileError(str(path), f"joint name {name!r} is used by two joints")
        seen.add(name)
        mimic = joint.find("mimic")
        if mimic is not None and joints.get(mimic.get("joint")) not in (
            "revolute", "continuous", "prismatic",
        ):  # fmt: skip
            other = mimic.get("joint")
            why = "does not exist" if other not in joints else f"is {joints[other]}"
            warnings.warn(  # (erd Alex's Psyonic hands ship such a mimic: loaded, not refused)
                f"{path}: joint {name!r}: <mimic joint={other!r}> names a joint that {why}: "
                "the coupling is dropped (the joint moves freely)",
                stacklevel=5,
            )
        limit = joint.find("limit")
        if limit is not None and joint.get("type") not in ("fixed", "floating", "planar"):
            for key in ("velocity", "effort"):
                text = limit.get(key)
                try:
                    bad = text is not None and not float(text) >= 0.0
                except ValueError:
                    bad = key == "velocity"  # (an effort that does not parse: MuJoCo's)
                if bad:
                    raise RobotFileError(
                        str(path), f'joint {name!r}: <limit {key}="{text}"> is not a number >= 0'
                    )
        if joint.get("type") not in ("revolute", "prismatic") or limit is None:
            continue
        try:
            lower = float(limit.get("lower", "0"))
            upper = float(limit.get("upper", "0"))
        except ValueError:
            continue
        if lower > upper:
            raise RobotFileError(
                str(path),
                f'joint {joint.get("name", "?")!r}: <limit lower="{limit.get("lower")}" '
                f'upper="{limit.get("upper")}"> is empty (lower above upper); swap them, '
                "or make the joint continuous for no limit",
            )
        if lower == upper:
            warnings.warn(
                f"{path}: joint {joint.get('name', '?')!r} has lower = upper = {lower:g}, "
                "which MuJoCo reads as no limit: make it a fixed joint to lock it",
                stacklevel=5,
            )


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
    for link in root.iter("link"):
        inertia = link.find("inertial/inertia")
        if inertia is not None and _fix_inertia(inertia):
            fixed.append(link.get("name", "?"))
    if fixed:
        warnings.warn(
            f"{path}: {len(fixed)} link inertia(s) not positive definite, made positive "
            f"(kinematics kept): {', '.join(fixed[:5])}" + (" ..." if len(fixed) > 5 else ""),
            stacklevel=6,
        )


_INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


def _fix_inertia(inertia: ET.Element) -> bool:
    """Make one ``<inertia>`` positive definite in place; whether it had to be."""
    try:
        xx, xy, xz, yy, yz, zz = (float(inertia.get(k, "0")) for k in _INERTIA_KEYS)
    except ValueError:
        return False
    matrix = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    if not np.all(np.isfinite(matrix)):
        return False
    values, vectors = np.linalg.eigh(matrix)
    coupled = bool(xy or xz or yz)  # MuJoCo checks a full inertia's eigenvalues
    if values.min() >= 0 and not (coupled and values.min() <= 1e-12 * abs(values).max()):
        return False  # diagonal zeros are MuJoCo's boundinertia's to fix
    matrix = vectors @ np.diag(np.maximum(values, 1e-9)) @ vectors.T
    for key, value in zip(_INERTIA_KEYS, matrix[np.triu_indices(3)]):
        inertia.set(key, repr(float(value)))
    return True


def _urdf_velocities(root: ET.Element) -> dict[str, float]:
    """Joint name -> ``<limit velocity>`` [rad/s or m/s] for joints that declare one > 0."""
    velocities = {}
    for joint in root.iter("joint"):
        if joint.get("type") in ("fixed", "floating", "planar"):
            continue
        limit = joint.find("limit")
        velocity = None if limit is None else limit.get("velocity")
        if velocity is None:
            continue
        try:
            value = float(velocity)
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
    # the file's keyframes name the fixed-base coordinates: the free joint's come first,
    # the root body's pose in the file (its qpos0) and no velocity (else MuJoCo would read
    # the arm's values as the base's)
    base = [*map(float, root.pos), *map(float, root.quat)]
    for key in spec.keys:
        if len(key.qpos):
            key.qpos = base + list(key.qpos)
        if len(key.qvel):
            key.qvel = [0.0] * 6 + list(key.qvel)
    # the free joint's 6 dofs come first (the root body is the first): a velocity_limit
    # numeric the file carries (one value per dof) gets 6 zeros (no limit) in front
    for numeric in spec.numerics:
        if numeric.name == "velocity_limit":
            data = [0.0] * 6 + list(numeric.data)
            numeric.size = len(data)
            numeric.data = data


def find_srdf(urdf: str | os.PathLike) -> Path | None:
    """The SRDF that goes with a URDF, or ``None``: in the URDF's folder or a sibling
    ``srdf/`` folder, the one named as the URDF, else the longest name the URDF's name
    starts with."""
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


def _read_srdf(path: Path) -> ET.Element:
    """The root element of an SRDF file."""
    try:
        return ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        raise RobotFileError(str(path), f"cannot read SRDF ({exc})") from exc


def _add_srdf_exclusions(spec: mujoco.MjSpec, model: mujoco.MjModel, root: ET.Element) -> None:
    """The SRDF's ``<disable_collisions>`` pairs as contact excludes between the two links'
    bodies (every reason: Adjacent, Default, Always, Never, User), and the pairs of a
    ``<disable_default_collisions link=...>`` link with every other body except those an
    ``<enable_collisions>`` names; links that are not bodies of the model are skipped."""

    def body(name: str | None) -> int:
        return -1 if not name else mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)

    done = excluded_body_pairs(model)
    enabled = {
        (min(a, b), max(a, b))
        for a, b in (
            (body(e.get("link1")), body(e.get("link2"))) for e in root.iter("enable_collisions")
        )
    }
    wanted = [(body(e.get("link1")), body(e.get("link2"))) for e in root.iter("disable_collisions")]
    for e in root.iter("disable_default_collisions"):
        a = body(e.get("link"))
        wanted += [(a, b) for b in range(1, model.nbody) if (min(a, b), max(a, b)) not in enabled]
    for a, b in wanted:
        pair = (min(a, b), max(a, b))
        if a <= 0 or b <= 0 or a == b or pair in done:
            continue
        done.add(pair)
        spec.add_exclude(bodyname1=model.body(a).name, bodyname2=model.body(b).name)


def _add_srdf_keyframes(
    spec: mujoco.MjSpec, model: mujoco.MjModel, root: ET.Element, path: Path
) -> bool:
    """The SRDF's ``<group_state>`` entries as keyframes; True if any was added."""
    existing = {key.name for key in spec.keys}
    added = False
    for state in root.iter("group_state"):
        name = state.get("name")
        if not name or name in existing:
            continue
        qpos = model.qpos0.copy()
        for joint in state.iter("joint"):
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint.get("name", ""))
            if j >= 0:
                _set_joint_value(model, qpos, j, _srdf_values(joint, name, path))
        spec.add_key(name=name, qpos=qpos.tolist())
        existing.add(name)
        added = True
    return added


def _srdf_values(joint: ET.Element, state: str, path: Path) -> list[float]:
    """The numbers of an SRDF ``<joint value="...">`` (finite)."""
    try:
        values = [float(x) for x in joint.get("value", "").split()]
    except ValueError as exc:
        raise RobotFileError(
            str(path), f"group_state {state!r}: joint {joint.get('name')!r}: {exc}"
        ) from exc
    if not all(np.isfinite(values)):
        raise RobotFileError(
            str(path),
            f"group_state {state!r}: joint {joint.get('name')!r}: value "
            f"{joint.get('value')!r} is not finite",
        )
    return values


_FREE, _BALL = int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_BALL)
_SCALAR = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


def _set_joint_value(model: mujoco.MjModel, qpos: np.ndarray, j: int, values: list[float]) -> None:
    """Write joint ``j``'s SRDF values into ``qpos`` (a free joint's ``x y z qx qy qz qw``
    and a ball's ``qx qy qz qw`` reordered to MuJoCo's ``w`` first); values of the wrong
    count are skipped."""
    adr = model.jnt_qposadr[j]
    kind = int(model.jnt_type[j])
    if kind == _FREE and len(values) == 7:
        x, y, z, qx, qy, qz, qw = values
        qpos[adr : adr + 7] = [x, y, z, qw, qx, qy, qz]
    elif kind == _BALL and len(values) == 4:
        qx, qy, qz, qw = values
        qpos[adr : adr + 4] = [qw, qx, qy, qz]
    elif kind in _SCALAR and len(values) == 1:
        qpos[adr] = values[0]
