"""Frames of a MuJoCo model: the frame-type maps (object type, count, Jacobian, pose
arrays; mink's own, keyed by :class:`FrameType`) and the resolver of a frame key into
``(name, type, id)``.

A *frame* is a body, a site or a geom: each has a pose in the world frame (MuJoCo's
``xpos``/``xmat``, ``site_xpos``/``site_xmat``, ``geom_xpos``/``geom_xmat``). A *frame key*,
as the solve entry points take it, is either a name, looked up among the sites first, then
the bodies, then the geoms, or a ``(name, frame type)`` tuple naming the type.

Every module that turns a frame name into an object id goes through :func:`resolve_frame`
(or :func:`frame_id` when the type is known), so that an unknown name always raises the same
typed :class:`qpik.UnknownFrame`, listing the valid names.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any, NamedTuple

import mujoco
import numpy as np
from mink import constants as mink_constants

from ..core import checks
from ..errors import InvalidInput, UnknownFrame, UnknownFrameType

__all__ = [
    "FRAME_COUNTS",
    "FRAME_JACOBIANS",
    "FRAME_OBJECTS",
    "FRAME_POSITIONS",
    "FRAME_ROTATIONS",
    "check_frame_type",
    "check_model_type",
    "excluded_body_pairs",
    "FrameType",
    "ResolvedFrame",
    "frame_chains",
    "frame_id",
    "frame_name",
    "frame_names",
    "resolve_frame",
]


def excluded_body_pairs(model: mujoco.MjModel) -> set[tuple[int, int]]:
    """The body id pairs ``(a, b)``, ``a <= b``, of the model's contact excludes
    (``<contact><exclude>``, and a URDF's SRDF ``<disable_collisions>`` as
    :func:`qpik.load_robot` adds them), from ``model.exclude_signature``."""
    pairs = set()
    for signature in model.exclude_signature:
        a, b = int(signature) >> 16, int(signature) & 0xFFFF
        pairs.add((min(a, b), max(a, b)))
    return pairs


def check_model_type(name: str, value: Any) -> Any:
    """``value`` if it is a ``mujoco.MjModel``; else :class:`InvalidArgumentType` naming
    ``name`` (a robot name, a path or a configuration is not a model: see
    :func:`qpik.load_robot`)."""
    return checks.check_instance(
        name, value, mujoco.MjModel, "a mujoco.MjModel (see qpik.load_robot)"
    )


class FrameType(str, enum.Enum):
    """Kinds of frames a MuJoCo model has. The strings ``"body"``, ``"site"``, ``"geom"``
    are accepted wherever a ``FrameType`` is."""

    BODY = "body"
    SITE = "site"
    GEOM = "geom"

    @classmethod
    def parse(cls, value: FrameType | str) -> FrameType:
        """Convert a string or FrameType to a FrameType; :class:`qpik.UnknownFrameType`
        otherwise."""
        if isinstance(value, FrameType):
            return value
        try:
            return cls(str(value).lower())
        except ValueError:
            raise UnknownFrameType(
                f"unknown frame type {value!r}; expected one of: body, site, geom"
            ) from None


def check_frame_type(owner: str, name: str, value: Any) -> FrameType:
    """``value`` as a :class:`FrameType` for the argument ``name`` of ``owner`` (a class
    name); anything but body, site or geom (any case), a :class:`FrameType` included, raises
    :class:`qpik.UnknownFrameType` naming the argument (mink checks a frame type only at the
    first step)."""
    try:
        return FrameType.parse(value)
    except UnknownFrameType:
        raise UnknownFrameType(
            f"{owner}: {name} is {value!r}; expected one of: body, site, geom"
        ) from None


def _by_frame_type(mink_map: Mapping[str, Any]) -> Mapping[FrameType, Any]:
    """One of mink's frame maps (keyed ``"body"``, ``"site"``, ``"geom"``) keyed by
    :class:`FrameType` (a ``str`` enum: the plain strings still look it up)."""
    return MappingProxyType({FrameType(kind): value for kind, value in mink_map.items()})


#: The MuJoCo object type of each frame type (mink's ``FRAME_TO_ENUM``).
FRAME_OBJECTS: Mapping[FrameType, mujoco.mjtObj] = _by_frame_type(mink_constants.FRAME_TO_ENUM)
#: The ``MjModel`` attribute counting the frames of each type.
FRAME_COUNTS: Mapping[FrameType, str] = _by_frame_type(mink_constants.FRAME_TO_COUNT_ATTR)
#: MuJoCo's Jacobian function of each frame type (``mj_jacSite``, ``mj_jacBody``,
#: ``mj_jacGeom``; world-aligned, ``(model, data, jacp, jacr, id)``).
FRAME_JACOBIANS: Mapping[FrameType, Any] = _by_frame_type(mink_constants.FRAME_TO_JAC_FUNC)
#: The ``MjData`` attribute holding the world positions (n, 3) of each frame type.
FRAME_POSITIONS: Mapping[FrameType, str] = _by_frame_type(mink_constants.FRAME_TO_POS_ATTR)
#: The ``MjData`` attribute holding the world rotations (n, 9, row-major) of each type.
FRAME_ROTATIONS: Mapping[FrameType, str] = _by_frame_type(mink_constants.FRAME_TO_XMAT_ATTR)

#: The order in which a bare name is looked up.
SEARCH_ORDER: tuple[FrameType, ...] = (FrameType.SITE, FrameType.BODY, FrameType.GEOM)


class ResolvedFrame(NamedTuple):
    """A frame found in a model: its name, type and MuJoCo object id (index into
    ``model.site_*``, ``model.body_*`` or ``model.geom_*``)."""

    name: str
    type: FrameType
    id: int


def frame_names(model: mujoco.MjModel, frame_type: FrameType | str) -> list[str]:
    """Names of all frames of one type in ``model`` (unnamed frames are left out)."""
    check_model_type("model", model)
    kind = FrameType.parse(frame_type)
    obj = FRAME_OBJECTS[kind]
    names = (mujoco.mj_id2name(model, obj, i) for i in range(getattr(model, FRAME_COUNTS[kind])))
    return [n for n in names if n]


def frame_name(model: mujoco.MjModel, frame_type: FrameType | str, fid: int) -> str:
    """The name of frame ``fid`` of the given type, or ``"<type> #<id>"`` when unnamed."""
    kind = FrameType.parse(frame_type)
    return mujoco.mj_id2name(model, FRAME_OBJECTS[kind], int(fid)) or f"{kind.value} #{fid}"


def frame_id(
    model: mujoco.MjModel, name: str | int | np.integer, frame_type: FrameType | str
) -> int:
    """Id of the frame ``name`` (a name, or an id checked against the count) of the given
    type. Raises :class:`qpik.UnknownFrame` listing the valid names of that type, and
    :class:`qpik.UnknownFrameType` for a type other than body, site or geom."""
    kind = FrameType.parse(frame_type)
    if isinstance(name, str):
        fid = mujoco.mj_name2id(model, FRAME_OBJECTS[kind], name)
    elif isinstance(name, (int, np.integer)) and not isinstance(name, bool):
        fid = int(name)
        if not 0 <= fid < getattr(model, FRAME_COUNTS[kind]):
            fid = -1
    else:  # a tuple, a float, None: neither a frame name nor an id
        fid = -1
    if fid < 0:
        raise UnknownFrame(name, kind.value, frame_names(model, kind))
    return fid


def resolve_frame(
    model: mujoco.MjModel,
    key: Any,
    frame_type: FrameType | str | None = None,
    *,
    argument: str = "frame",
) -> ResolvedFrame:
    """Resolve a frame key into ``ResolvedFrame(name, type, id)``.

    Args:
        model: the MuJoCo model.
        key: a frame name (looked up among the sites, then the bodies, then the geoms),
            or a ``(name, frame type)`` tuple. With ``frame_type`` given, ``key`` is a
            name or an id of that type.
        frame_type: the type of a bare ``key``; ``None`` searches the three types.
        argument: what the caller calls ``key``, named in the error of a malformed key.

    Raises:
        qpik.InvalidInput: ``key`` is neither a str nor a ``(str, frame type)`` tuple
            (the message names ``argument``).
        qpik.UnknownFrameType: the tuple's (or ``frame_type``'s) type is not body, site
            or geom.
        qpik.UnknownFrame: no frame has that name; the error lists the valid names.
    """
    if isinstance(key, ResolvedFrame):
        key = (key.name, key.type)
    if isinstance(key, tuple) and len(key) == 2 and isinstance(key[0], str):
        name, kind = key[0], FrameType.parse(key[1])
        return ResolvedFrame(name, kind, frame_id(model, name, kind))
    if frame_type is not None:
        kind = FrameType.parse(frame_type)
        if not isinstance(key, (str, int, np.integer)) or isinstance(key, bool):
            raise InvalidInput(f"{argument}: a frame is a name (str) or an id (int), got {key!r}")
        fid = frame_id(model, key, kind)
        name = key if isinstance(key, str) else frame_name(model, kind, fid)
        return ResolvedFrame(name, kind, fid)
    if not isinstance(key, str):
        raise InvalidInput(
            f"{argument}: a frame key is a name (str) or (name, frame type), got {key!r}"
        )
    for kind in SEARCH_ORDER:
        fid = mujoco.mj_name2id(model, FRAME_OBJECTS[kind], key)
        if fid >= 0:
            return ResolvedFrame(key, kind, fid)
    available = [n for kind in SEARCH_ORDER for n in frame_names(model, kind)]
    raise UnknownFrame(key, "site, body or geom", available)


def frame_chains(model: mujoco.MjModel, frames: np.ndarray) -> tuple:
    """Per frame ``(kind, id)`` of ``frames``, the dofs that move it, in the order MuJoCo's
    ``mj_jac`` visits them (from its body's last dof up the ``dof_parentid`` chain; a body
    without dofs: its first moving ancestor's), and its body's root: ``(starts (F + 1,),
    dofs, roots (F,))``."""
    starts, dofs, roots = [0], [], []
    for kind, fid in frames.tolist():
        body = fid if kind == 1 else int((model.site_bodyid, model.geom_bodyid)[kind // 2][fid])
        roots.append(int(model.body_rootid[body]))
        while body and not model.body_dofnum[body]:
            body = int(model.body_parentid[body])
        da = int(model.body_dofadr[body] + model.body_dofnum[body]) - 1 if body else -1
        while da >= 0:
            dofs.append(da)
            da = int(model.dof_parentid[da])
        starts.append(len(dofs))
    return tuple(np.array(x, dtype=np.int64) for x in (starts, dofs, roots))
