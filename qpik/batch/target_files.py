"""Targets files in (:func:`load_targets`: ``.npz`` or ``.csv``, positions [m] and optional
quaternions ``w x y z``, world frame) and targets given as arrays (:class:`TargetArrays`,
checked as a file is: :func:`check_target_arrays`), for :func:`qpik.batch.files.solve_file`.
"""

from __future__ import annotations

import hashlib
import os
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core import checks
from ..errors import InvalidInput, InvalidTarget, ProblemFileError
from ..igm.targets import MAX_TARGET_DISTANCE, FrameKey
from .chunks import Chunk

__all__ = [
    "TargetArrays",
    "check_target_arrays",
    "load_targets",
    "rotations_from_quaternions",
]


@dataclass(frozen=True)
class TargetArrays:
    """Targets of one frame, as arrays: positions ``(N, 3)`` [m] and optionally rotation
    matrices ``(N, 3, 3)``, both in the world frame."""

    positions: np.ndarray
    rotations: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.positions)

    def chunk(self, frame: FrameKey, start: int, stop: int) -> Chunk:
        """Targets ``start:stop`` as ``{frame: target}`` mappings."""
        if self.rotations is None:
            targets = [{frame: p} for p in self.positions[start:stop]]
        else:
            targets = [
                {frame: (p, r)}
                for p, r in zip(self.positions[start:stop], self.rotations[start:stop])
            ]
        return Chunk(start, targets)

    def fingerprint(self) -> str:
        """A hash of the targets (resuming checks that they did not change)."""

        digest = hashlib.sha256(np.ascontiguousarray(self.positions, dtype=float).tobytes())
        if self.rotations is not None:
            digest.update(np.ascontiguousarray(self.rotations, dtype=float).tobytes())
        return digest.hexdigest()[:16]


def rotations_from_quaternions(quaternions: np.ndarray, source: str = "quaternions") -> np.ndarray:
    """Rotation matrices ``(N, 3, 3)`` from unit quaternions ``(N, 4)`` in MuJoCo's
    order ``w x y z``. A quaternion whose norm is not 1 within 1e-3 raises (it is most
    likely in another order or not a rotation); within that, it is normalised."""
    from scipy.spatial.transform import Rotation

    quaternions = np.asarray(quaternions, dtype=float)
    if quaternions.ndim != 2 or quaternions.shape[1] != 4:
        raise InvalidInput(f"{source}: expected shape (N, 4) (w x y z), got {quaternions.shape}")
    norms = np.linalg.norm(quaternions, axis=1)
    bad = np.flatnonzero(~np.isfinite(norms) | (np.abs(norms - 1.0) > 1e-3))
    if bad.size:
        raise InvalidInput(
            f"{source}[{bad[0]}] = {quaternions[bad[0]]} is not a unit quaternion (w x y z); "
            f"{bad.size} row(s) are not"
        )
    return Rotation.from_quat(quaternions / norms[:, None], scalar_first=True).as_matrix()


def load_targets(path: str | os.PathLike) -> TargetArrays:
    """Read a targets file: an ``.npz`` with ``positions`` ``(N, 3)`` [m] and optionally
    ``quaternions`` ``(N, 4)`` (``w x y z``), or a ``.csv`` with columns ``x, y, z`` and
    optionally ``qw, qx, qy, qz`` (a header line naming them, or 3 or 7 unnamed columns).
    World frame. Malformed files raise :class:`qpik.ProblemFileError` naming the field."""

    path = checks.check_path("targets", path)
    if not os.path.isfile(path):
        raise ProblemFileError(path, "TARGETS", "no such file")
    if path.lower().endswith(".csv"):
        positions, quaternions = _read_csv(path)
    else:
        positions, quaternions = _read_npz(path)
    defect = _positions_defect(positions)
    if defect is not None:  # before any solve: a bad row would stop the run midway
        raise ProblemFileError(path, "positions", defect)
    rotations = None
    if quaternions is not None:
        if quaternions.shape != (len(positions), 4):
            raise ProblemFileError(
                path,
                "quaternions",
                f"shape ({len(positions)}, 4) (w x y z), got {quaternions.shape}",
            )
        try:
            rotations = rotations_from_quaternions(quaternions)
        except InvalidInput as exc:
            raise ProblemFileError(path, "quaternions", str(exc)) from None
    return TargetArrays(positions, rotations)


def check_target_arrays(targets: TargetArrays) -> TargetArrays:
    """``targets`` checked as :func:`load_targets` checks a file, before any solve:
    ``positions`` ``(N, 3)`` real numbers [m], finite and within
    :data:`~qpik.igm.targets.MAX_TARGET_DISTANCE` of the world origin; ``rotations``
    ``None`` or one rotation matrix per position, ``(N, 3, 3)``, each as
    :func:`qpik.igm.targets.parse_target` takes it (``|R R^T - I| <= 1e-6``, ``det R >
    0``). Returns them as float arrays; a defect raises :class:`qpik.InvalidTarget` naming
    the field (``targets.positions``, ``targets.rotations``) and the first bad row."""
    positions = _given_array("positions", targets.positions)
    defect = _positions_defect(positions)
    if defect is not None:
        raise InvalidTarget(f"targets.positions: {defect}")
    if targets.rotations is None:
        return TargetArrays(positions)
    rotations = _given_array("rotations", targets.rotations)
    n = len(positions)
    if rotations.shape != (n, 3, 3):
        raise InvalidTarget(
            f"targets.rotations: shape ({n}, 3, 3), one rotation per position, got "
            f"{rotations.shape}"
        )
    with np.errstate(invalid="ignore", over="ignore"):
        off = np.abs(rotations @ rotations.transpose(0, 2, 1) - np.eye(3)).max(axis=(1, 2))
        determinants = np.linalg.det(rotations) if n else np.zeros(0)
    bad = np.flatnonzero(~((off <= 1e-6) & (determinants > 0.0)))
    if bad.size:
        raise InvalidTarget(
            f"targets.rotations: rotation matrices (|R R^T - I| <= 1e-6, det R > 0); row "
            f"{bad[0]} is not ({bad.size} row(s) are not): {rotations[bad[0]].tolist()}"
        )
    return TargetArrays(positions, rotations)


def _given_array(field: str, value: Any) -> np.ndarray:
    """A field of a :class:`TargetArrays` as a float array: real numbers only (else
    :class:`qpik.InvalidTarget` naming ``targets.<field>``)."""
    try:
        return checks.float_array(value, booleans=False)
    except (TypeError, ValueError) as exc:
        raise InvalidTarget(f"targets.{field}: an array of real numbers ({exc})") from None


def _positions_defect(positions: np.ndarray) -> str | None:
    """What is wrong with target positions (the first bad row named), or ``None``: shape
    ``(N, 3)``, finite, within :data:`~qpik.igm.targets.MAX_TARGET_DISTANCE` of the
    origin (a farther target is refused by every solve)."""
    if positions.ndim != 2 or positions.shape[1] != 3:
        return f"shape (N, 3) [m], got {positions.shape}"
    bad = np.flatnonzero(~np.isfinite(positions).all(axis=1))
    if bad.size:
        return f"finite values; row {bad[0]} is not"
    far = np.flatnonzero(np.abs(positions).max(axis=1, initial=0.0) > MAX_TARGET_DISTANCE)
    if far.size:
        return (
            f"positions within {MAX_TARGET_DISTANCE:g} m of the world origin; row {far[0]} is "
            f"{positions[far[0]].tolist()} ({far.size} row(s) farther)"
        )
    return None


def _read_npz(path: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Positions ``(N, 3)`` and quaternions ``(N, 4)`` or ``None`` of an npz targets file."""
    try:
        with open(path, "rb") as stream:  # closed whatever np.load raises
            return _npz_targets(path, np.load(stream, allow_pickle=False))
    except ProblemFileError:
        raise
    except Exception as exc:  # not a zip, pickled objects, ...
        raise ProblemFileError(path, "TARGETS", f"an .npz or .csv file ({exc})") from None


def _npz_targets(path: str, loaded: Any) -> tuple[np.ndarray, np.ndarray | None]:
    """Positions and quaternions of what ``np.load`` read from an npz targets file."""
    if not isinstance(loaded, np.lib.npyio.NpzFile):
        raise ProblemFileError(
            path, "TARGETS", "an .npz archive with a positions array, not a bare .npy array"
        )
    with loaded as data:
        if "positions" not in data:
            raise ProblemFileError(
                path, "positions", f"an (N, 3) array [m]; the file has {sorted(data)}"
            )
        positions = _real_array(path, "positions", data["positions"])
        quaternions = None
        if "quaternions" in data:
            quaternions = _real_array(path, "quaternions", data["quaternions"])
    return positions, quaternions


def _real_array(path: str, field: str, array: np.ndarray) -> np.ndarray:
    """``array``, an entry of a targets file, as floats: real numbers only (a complex,
    string or boolean array raises :class:`qpik.ProblemFileError`, naming the field;
    casting would drop imaginary parts or read text silently)."""
    if array.dtype.kind not in "iuf":
        raise ProblemFileError(path, field, f"an array of real numbers, got dtype {array.dtype}")
    return np.asarray(array, dtype=float)


def _read_csv(path: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Positions ``(N, 3)`` and quaternions ``(N, 4)`` or ``None`` of a CSV targets file."""
    lines = _csv_lines(path)
    if not lines:
        raise ProblemFileError(path, "CSV", "a header x,y,z[,qw,qx,qy,qz] or rows of numbers")
    first_number, first = lines[0]
    try:
        [float(cell) for cell in first.split(",")]
        header = False
    except ValueError:
        header = True
    rows = lines[1:] if header else lines
    if not rows:
        raise ProblemFileError(
            path, "CSV", f"at least one row of targets after the header (line {first_number})"
        )
    width = len(rows[0][1].split(","))
    columns = [c.strip().lower() for c in first.split(",")] if header else []
    if header and len(columns) != width:
        raise ProblemFileError(
            path,
            f"CSV line {rows[0][0]}",
            f"{len(columns)} values, one per column of the header (line {first_number}: "
            f"{first.strip()!r}), got {width}",
        )
    for number, line in rows:
        cells = line.split(",")
        if len(cells) != width:
            raise ProblemFileError(
                path,
                f"CSV line {number}",
                f"{width} values as on line {rows[0][0]}, got {len(cells)}: {line.strip()!r}",
            )
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            # (the rows as read above, comments and blank lines out: the file read once)
            table = np.loadtxt([line for _, line in rows], delimiter=",", ndmin=2)
    except ValueError as exc:
        raise _bad_cell(path, rows) or ProblemFileError(
            path, "CSV", f"numbers separated by commas ({exc})"
        ) from None
    if table.shape != (len(rows), width):  # loadtxt read the lines otherwise
        raise ProblemFileError(path, "CSV", f"{len(rows)} rows of {width} numbers")
    if header:
        return _named_columns(path, table, columns)
    if table.shape[1] not in (3, 7):
        raise ProblemFileError(
            path, "CSV", f"3 (x y z) or 7 (x y z qw qx qy qz) columns, got {table.shape[1]}"
        )
    return table[:, :3], (table[:, 3:] if table.shape[1] == 7 else None)


def _bad_cell(path: str, rows: list[tuple[int, str]]) -> ProblemFileError | None:
    """The error naming the first cell of ``rows`` that is not a number (``None`` if all
    are numbers)."""
    for number, line in rows:
        for column, cell in enumerate(line.split(","), start=1):
            try:
                float(cell)
            except ValueError:
                return ProblemFileError(
                    path, f"CSV line {number}", f"a number in column {column}, got {cell.strip()!r}"
                )
    return None


def _csv_lines(path: str) -> list[tuple[int, str]]:
    """The lines of a CSV file that hold something, as ``(line number, text)`` (1-based;
    blank lines and ``#`` comments left out, as :func:`numpy.loadtxt` does); a file that
    is not UTF-8 text raises :class:`qpik.ProblemFileError` naming the line."""
    with open(path, "rb") as stream:
        raw = stream.read()
    text = checks.utf8_text(raw, path, "CSV", "UTF-8 text")
    if "\0" in text:
        nul_line = text[: text.index("\0")].count("\n") + 1
        raise ProblemFileError(path, "CSV", f"text without NUL bytes; line {nul_line} has one")
    kept = []
    for number, line in enumerate(text.splitlines(), start=1):
        content = line.split("#", 1)[0]
        if content.strip():
            kept.append((number, content))
    return kept


def _named_columns(
    path: str, table: np.ndarray, columns: list[str]
) -> tuple[np.ndarray, np.ndarray | None]:
    """The columns ``x, y, z`` and, when all are present, ``qw, qx, qy, qz``."""
    repeated = sorted({c for c in columns if columns.count(c) > 1})
    if repeated:
        raise ProblemFileError(path, "CSV header", f"each column named once; {repeated} repeat")
    missing = [c for c in ("x", "y", "z") if c not in columns]
    if missing:
        raise ProblemFileError(path, "CSV header", f"columns x, y, z; missing {missing}")
    positions = table[:, [columns.index(c) for c in ("x", "y", "z")]]
    quaternion_columns = ("qw", "qx", "qy", "qz")
    present = [c in columns for c in quaternion_columns]
    if any(present) and not all(present):
        raise ProblemFileError(path, "CSV header", "all of qw, qx, qy, qz or none")
    quaternions = table[:, [columns.index(c) for c in quaternion_columns]] if all(present) else None
    return positions, quaternions
