"""Reachability-map files (:meth:`qpik.ReachabilityMap.load`): the ``.npz`` that
:meth:`qpik.ReachabilityMap.save` writes, read back with every field checked. A file that
cannot be read, is not such a map, or has a field of the wrong type, shape or range (the
arrays against each other and against the JSON ``meta`` entry) raises
:class:`qpik.ProblemFileError` naming the file and the field.
"""

from __future__ import annotations

import json
import math
import zipfile
from collections.abc import Callable
from typing import Any

import numpy as np

from ..core import checks
from ..errors import ProblemFileError

__all__ = ["MAP_ARRAYS", "read_map_file"]

#: The array fields of a :class:`qpik.ReachabilityMap`, saved as arrays of its ``.npz``
#: (its other fields are in the JSON ``meta`` entry).
MAP_ARRAYS = ("centers", "fraction", "reached", "skipped", "orientations", "region", "base")


def read_map_file(path: str) -> dict[str, Any]:
    """The fields of the map saved at ``path`` (the keywords of
    :class:`qpik.ReachabilityMap`), checked; :class:`qpik.ProblemFileError` naming the
    file and the field otherwise."""

    def fail(field_name: str, expected: str) -> ProblemFileError:
        return ProblemFileError(path, field_name, expected)

    def unreadable(exc: BaseException) -> ProblemFileError:
        reason = getattr(exc, "strerror", None) or exc
        return fail("(file)", f"a readable .npz file written by ReachabilityMap.save ({reason})")

    try:
        stream = open(path, "rb")  # closed below, whatever np.load raises
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the path
        raise unreadable(exc) from None
    with stream:
        try:
            archive = np.load(stream, allow_pickle=False)
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise unreadable(exc) from None
        if not isinstance(archive, np.lib.npyio.NpzFile):
            raise fail("(file)", "an .npz archive written by ReachabilityMap.save, not an array")
        with archive as data:
            raw = _read_arrays(data, fail)
    values = _map_meta(raw.pop("meta"), fail)
    values.update(_map_arrays(raw, values, fail))
    return values


def _read_arrays(data: Any, fail: Callable[[str, str], Exception]) -> dict[str, np.ndarray]:
    """The ``meta`` entry and the :data:`MAP_ARRAYS` of an open npz archive."""
    names = sorted(data.files)
    raw: dict[str, np.ndarray] = {}
    for name in ("meta", *MAP_ARRAYS):
        if name not in names:
            raise fail(name, f"an array of a reachability map; the file has {names}")
        try:
            raw[name] = np.asarray(data[name])
        except Exception as exc:  # a truncated member, pickled objects, ...
            raise fail(name, f"a readable array ({type(exc).__name__}: {exc})") from None
    return raw


def _map_meta(meta: np.ndarray, fail: Callable[[str, str], Exception]) -> dict[str, Any]:
    """The fields of a map's JSON ``meta`` entry, checked."""
    if meta.shape != () or meta.dtype.kind != "U":
        raise fail("meta", f"a JSON string, got a {meta.dtype} array of shape {meta.shape}")
    try:
        document = json.loads(str(meta))
    except (ValueError, RecursionError) as exc:
        raise fail("meta", f"valid JSON ({exc})") from None
    if not isinstance(document, dict):
        raise fail("meta", f"a JSON object, got {type(document).__name__}")
    reader = _MetaReader(document, fail)
    for name in ("shape", "resolution", "frame", "robot", "reach", "solve_options"):
        if name not in document:
            raise fail(f"meta.{name}", f"present; meta has {sorted(document)}")
    shape = document["shape"]
    if not (
        isinstance(shape, list)
        and len(shape) == 3
        and all(type(n) is int and n >= 1 for n in shape)
    ):
        raise fail("meta.shape", f"3 positive integers (nx, ny, nz), got {shape!r}")
    values: dict[str, Any] = {
        "shape": (shape[0], shape[1], shape[2]),
        "resolution": reader.number("resolution", positive=True),
        "frame": reader.text("frame"),
        "robot": reader.text("robot"),
        "reach": reader.number("reach", inf=True),
        "solve_options": reader.check(
            "solve_options",
            lambda v: isinstance(v, dict) and all(isinstance(x, str) for x in v.values()),
            "an object of option reprs",
        ),
    }
    # Fields that older maps lack: their defaults then.
    if "seed" in document:
        values["seed"] = reader.check(
            "seed", lambda v: type(v) is int and v >= 0, "an integer >= 0"
        )
    if "elapsed" in document:
        values["elapsed"] = reader.number("elapsed")
    if "engines" in document:
        values["engines"] = reader.check(
            "engines",
            lambda v: isinstance(v, dict) and all(type(n) is int and n >= 0 for n in v.values()),
            "solve counts per engine",
        )
    if "collision_pairs" in document:
        pairs = reader.check("collision_pairs", _is_pair_list, "a list of geom name pairs")
        values["collision_pairs"] = [(a, b) for a, b in pairs]
    if document.get("collision_distance") is not None:
        values["collision_distance"] = reader.number("collision_distance", low=-math.inf)
    return values


def _is_pair_list(value: Any) -> bool:
    """Whether ``value`` is a list of ``[name, name]`` lists (JSON's collision pairs)."""
    return isinstance(value, list) and all(
        isinstance(p, list) and len(p) == 2 and all(isinstance(g, str) for g in p) for p in value
    )


class _MetaReader:
    """Checked reads of the entries of a map's ``meta`` object; a bad one raises
    ``fail("meta.NAME", expected)``."""

    def __init__(self, document: dict[str, Any], fail: Callable[[str, str], Exception]):
        self.document, self.fail = document, fail

    def check(self, name: str, test: Callable[[Any], bool], expected: str) -> Any:
        value = self.document[name]
        if not test(value):
            raise self.fail(f"meta.{name}", f"{expected}, got {value!r}")
        return value

    def number(
        self, name: str, low: float = 0.0, *, inf: bool = False, positive: bool = False
    ) -> float:
        """A number >= ``low`` (> with ``positive``), finite (or +inf with ``inf``)."""

        def test(v: Any) -> bool:
            if not checks.is_real(v) or not (math.isfinite(v) or (inf and v == math.inf)):
                return False
            return v > low if positive else v >= low

        span = "" if math.isinf(low) else f" {'>' if positive else '>='} {low:g}"
        return float(self.check(name, test, f"a number{span}"))

    def text(self, name: str) -> str:
        return self.check(name, lambda v: isinstance(v, str), "a string")


def _map_arrays(
    raw: dict[str, np.ndarray], meta: dict[str, Any], fail: Callable[[str, str], Exception]
) -> dict[str, np.ndarray]:
    """A map's arrays, checked against each other and against its ``meta``."""
    nx, ny, nz = meta["shape"]
    voxels = nx * ny * nz

    def real(name: str, shape: tuple[int | None, ...], what: str) -> np.ndarray:
        array = raw[name]
        fits = array.ndim == len(shape) and all(
            want is None or got == want for got, want in zip(array.shape, shape)
        )
        wanted = "(" + ", ".join("K" if n is None else str(n) for n in shape) + ")"
        if array.dtype.kind not in "iuf" or not fits:
            raise fail(
                name, f"{what}: real numbers of shape {wanted}, got {array.dtype} {array.shape}"
            )
        array = array.astype(float)
        if not np.isfinite(array).all():
            raise fail(name, f"{what}: finite numbers")
        return array

    def flags(name: str, shape: tuple[int, ...], what: str) -> np.ndarray:
        array = raw[name]
        if array.dtype != bool or array.shape != shape:
            raise fail(name, f"{what}: booleans of shape {shape}, got {array.dtype} {array.shape}")
        return array

    where = f"the grid of meta.shape {list(meta['shape'])}"
    centers = real("centers", (voxels, 3), f"voxel centres [m], one per voxel of {where}")
    resolution = meta["resolution"]
    index = np.stack(np.meshgrid(*(np.arange(n) for n in (nx, ny, nz)), indexing="ij"), -1)
    expected = centers[0] + index.reshape(-1, 3) * resolution
    if not np.allclose(centers, expected, rtol=0.0, atol=1e-6 * resolution + 1e-12):
        raise fail("centers", f"{where} with meta.resolution {resolution:g} m, in C order")
    orientations = real("orientations", (None, 3, 3), "rotation matrices")
    gram = orientations @ orientations.transpose(0, 2, 1) - np.eye(3)
    if len(orientations) and not (
        np.abs(gram).max() <= 1e-6 and (np.linalg.det(orientations) > 0.0).all()
    ):
        raise fail("orientations", "rotation matrices (orthonormal, det +1)")
    count = max(1, len(orientations))
    reached = flags("reached", (voxels, count), "per voxel and orientation")
    skipped = flags("skipped", (voxels,), "per voxel")
    fraction = real("fraction", (voxels,), "one per voxel")
    if ((fraction < 0.0) | (fraction > 1.0)).any():
        raise fail("fraction", "fractions in [0, 1]")
    if not np.allclose(fraction, reached.mean(axis=1), rtol=0.0, atol=1e-9):
        raise fail("fraction", "the fraction of each voxel's orientations reached (reached)")
    if (reached[skipped]).any():
        raise fail("skipped", "voxels skipped without IK, none of them reached")
    return {
        "centers": centers,
        "fraction": fraction,
        "reached": reached,
        "skipped": skipped,
        "orientations": orientations,
        "region": real("region", (2, 3), "opposite corners of the box [m]"),
        "base": real("base", (3,), "the reach-bound centre [m]"),
    }
