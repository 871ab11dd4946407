"""Batches on disk, behind ``qpik batch``: targets files in (:func:`load_targets`: ``.npz``
or ``.csv``, positions [m] and optional quaternions ``w x y z``, world frame; read and
checked in :mod:`qpik.batch.target_files`), results files out (:func:`solve_file`: ``.npz``
or Parquet), written chunk by chunk and resumed. The solving itself is
:mod:`qpik.batch.pool`'s.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import sys
import time
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
import numpy.typing as npt

from ..core import checks
from ..errors import InvalidInput, MissingExtra
from ..igm.result import IKResult
from ..igm.targets import FrameKey, RobotLike
from ..model.frames import resolve_frame
from ..options import SolveOptions
from .pool import Batch, BatchKeywords, iter_prepared, progress_bar
from .ray import ray_init
from .target_files import (
    TargetArrays,
    check_target_arrays,
    load_targets,
    rotations_from_quaternions,
)

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = [
    "RESULT_FIELDS",
    "BatchRun",
    "TargetArrays",
    "check_out_not_targets",
    "load_targets",
    "rotations_from_quaternions",
    "solve_file",
]


#: The per-target fields of a results file, with their dtypes.
RESULT_FIELDS: dict[str, npt.DTypeLike] = {
    "converged": bool,
    "reason": "U16",
    "position_error": float,
    "orientation_error": float,
    "iterations": np.int64,
    "restarts_used": np.int64,
    "time": float,
}


@dataclass
class BatchRun:
    """What :func:`solve_file` did: targets in the file, chunks solved before this run
    and in it (and targets in it), whether every chunk is now done, the wall time of this
    run [s], and over every target done, how many converged and why the others did not."""

    out: str
    total: int
    chunks: int
    chunks_before: int
    chunks_solved: int
    complete: bool
    elapsed: float
    converged: int = 0
    targets_solved: int = 0
    reasons: dict[str, int] | None = None

    def summary(self) -> str:
        """What the run did, as ``qpik batch`` prints it: chunks and targets done (before
        this run and now), the rate [targets/s], and the reasons counted."""
        solved = self.chunks_solved
        lines = [
            f"{self.out}: {self.chunks_before + solved}/{self.chunks} chunks of {self.total} "
            f"targets done ({self.chunks_before} before this run, {solved} now)"
        ]
        rate = self.targets_solved / self.elapsed if self.elapsed > 0 else 0.0
        lines.append(
            f"this run: {self.targets_solved} targets in {self.elapsed:.1f} s ({rate:.0f} IK/s)"
        )
        if self.complete and self.reasons is not None:
            reasons = ", ".join(f"{k} {v}" for k, v in sorted(self.reasons.items()))
            lines.append(f"converged {self.converged}/{self.total}; reasons: {reasons}")
        elif not self.complete:
            lines.append("incomplete: run the same command again to resume")
        return "\n".join(lines)


def _atomic_savez(path: str, **arrays) -> None:
    """Write an npz so that a reader never sees half a file (temporary file, rename). The
    temporary file is hidden (``.NAME.tmpPID.npz``): one a full disk or a kill leaves behind
    is no chunk file, and the next run removes it (:func:`_remove_leftovers`)."""
    folder, name = os.path.split(path)
    tmp = os.path.join(folder, f".{name}{_TMP}{os.getpid()}.npz")
    np.savez(tmp, **arrays)
    os.replace(tmp, path)


#: The mark of a temporary file of :func:`_atomic_savez` / :func:`_atomic_json`.
_TMP = ".tmp"
#: A finished chunk's file in a run's folder: ``chunk_<start, 10 digits>.npz``.
_CHUNK = re.compile(r"chunk_(\d{10})\.npz")


def _atomic_json(path: str, value: Any) -> None:
    """Write JSON so that a reader never sees half a file (hidden temporary file, rename)."""
    folder, name = os.path.split(path)
    tmp = os.path.join(folder, f".{name}{_TMP}{os.getpid()}")
    with open(tmp, "w") as stream:
        json.dump(value, stream, indent=1)
    os.replace(tmp, path)


def _remove_leftovers(folder: str, name: str) -> None:
    """Remove the temporary files a killed or full-disk write of ``name`` in ``folder``
    (the results file, or any file of a run's chunk folder when ``name`` is ``""``) left:
    ``.NAME.tmpPID...``, and the ``NAME.tmpPID.npz`` of versions before 0.2."""
    try:
        names = os.listdir(folder or ".")
    except OSError:
        return
    for entry in names:
        hidden = entry.startswith(f".{name}") and _TMP in entry
        old = bool(name) and entry.startswith(f"{name}{_TMP}") and entry.endswith(".npz")
        old = old or (not name and entry.startswith("chunk_") and _TMP in entry)
        writer = re.search(re.escape(_TMP) + r"(\d+)", entry)
        if (hidden or old) and not (writer and _alive(int(writer.group(1)))):
            try:  # (a live writer's file is left: another run on the same out, say)
                os.remove(os.path.join(folder, entry))
            except OSError:
                pass


def _alive(pid: int) -> bool:
    """Whether a process ``pid`` runs (this one's writes never leave a file to remove)."""
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError, OverflowError):
        return True
    return True


def _pyarrow():
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError as exc:
        raise MissingExtra("Parquet results", "cluster", "pyarrow") from exc
    return pyarrow


def _write_results(path: str, table: Mapping[str, np.ndarray], meta: Mapping[str, Any]) -> None:
    """Write the results table to ``path`` (npz, or Parquet with one row per target and
    ``q`` a fixed-size list column), atomically; ``meta`` goes along as JSON."""

    if not path.endswith(".parquet"):
        _atomic_savez(path, **table, **_meta_arrays(meta))
        return
    pa = _pyarrow()
    q = np.asarray(table["q"], dtype=float)
    columns = {"index": pa.array(np.arange(len(q)))}
    columns["q"] = pa.FixedSizeListArray.from_arrays(pa.array(q.ravel()), q.shape[1])
    for name in (*RESULT_FIELDS, "done"):
        columns[name] = pa.array(table[name])
    arrow = pa.table(columns).replace_schema_metadata({"qpik": json.dumps(meta)})
    tmp = f"{path}.tmp{os.getpid()}.parquet"
    pa.parquet.write_table(arrow, tmp)
    os.replace(tmp, path)


def _read_results(path: str) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """``(meta, table)`` of a results file written by :func:`_write_results`."""

    if not path.endswith(".parquet"):
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            return meta, {name: data[name] for name in ("q", *RESULT_FIELDS, "done")}
    pa = _pyarrow()
    arrow = pa.parquet.read_table(path)
    meta = json.loads(arrow.schema.metadata[b"qpik"])
    q = arrow.column("q").combine_chunks()
    table = {"q": q.flatten().to_numpy().reshape(len(q), q.type.list_size)}
    for name in (*RESULT_FIELDS, "done"):
        values = arrow.column(name).to_numpy(zero_copy_only=False)
        table[name] = values.astype(RESULT_FIELDS.get(name, bool))
    return meta, table


def solve_file(
    robot: RobotLike,
    frame: FrameKey,
    targets: str | os.PathLike | TargetArrays,
    out: str | os.PathLike,
    *,
    max_chunks: int | None = None,
    overwrite: bool = False,
    options: SolveOptions | str | None = None,
    **keywords: Unpack[BatchKeywords],
) -> BatchRun:
    """Solve a targets file (see :func:`load_targets`) for ``frame`` and write the results
    to ``out`` (``.npz``, or ``.parquet`` with pyarrow: ``pip install -e '.[cluster]'``)
    chunk by chunk; a rerun with the same ``out`` resumes. ``targets`` may also be a
    :class:`TargetArrays`, checked as a file is (:func:`check_target_arrays`), before any
    solve; ``out`` may not be the targets file (``InvalidInput``, whatever ``overwrite``).

    Each finished chunk is saved at once, atomically, in the folder ``out + ".chunks"``;
    ``out`` itself is rewritten every few seconds and at the end, with every row: ``q``
    ``(N, nq)``, ``converged``, ``reason``, ``position_error`` [m], ``orientation_error``
    [rad], ``iterations``, ``restarts_used``, ``time`` [s] (unsolved rows: NaN, ``False``,
    ``"pending"``) and ``done`` ``(N,)``. When every chunk is done, the folder is removed.
    A rerun skips the chunks already done; it refuses (``InvalidInput``) to mix runs whose
    targets, robot (its name, and its compiled content: :func:`model_fingerprint`, so an
    edited file of the same name is another robot), frame, seed, chunk size or options
    differ, unless ``overwrite``.
    ``max_chunks`` (an int >= 0) stops after that many new chunks (resume later; ``0``
    solves nothing: it checks the inputs and writes ``out`` with every row pending).
    Target ``i`` is solved with :func:`target_seed(seed, i)
    <qpik.batch.worker.target_seed>`: the file's rows are the same as
    :func:`qpik.solve_many`'s, however the run was split. ``options`` and the keywords:
    as for :func:`qpik.solve_many` (``chunk_size`` defaults to 128 here;
    ``pool_threshold`` and ``histories`` do not apply).
    """
    start_time = time.perf_counter()
    if max_chunks is not None:
        max_chunks = checks.check_integer("max_chunks", max_chunks, 0, sys.maxsize)
    checks.check_bool("overwrite", overwrite)
    out = _check_out(out)
    if isinstance(targets, TargetArrays):
        arrays = check_target_arrays(targets)
    else:
        check_out_not_targets(out, targets)
        arrays = load_targets(targets)
    unused = ("pool_threshold", "histories")
    batch = Batch.prepare(robot, options, keywords, unused, chunk_size=128)
    chunk_size = batch.run.chunk_size or 128
    model, spec = batch.model, batch.setup.spec
    resolve_frame(model, frame, argument="frame")
    n = len(arrays)
    meta = {
        "robot": spec if isinstance(spec, str) else f"MjModel(nq={model.nq})",
        "model": model_fingerprint(model),
        "frame": list(frame) if isinstance(frame, tuple) else frame,
        "targets": arrays.fingerprint(),
        "n": n,
        "nq": int(model.nq),
        "seed": batch.setup.entropy,
        "chunk_size": chunk_size,
        "options": _described(batch),
    }
    results = _ResultsFile(out, meta, overwrite)
    before = len(results.done)
    todo = [s for s in range(0, n, chunk_size) if s not in results.done]
    if max_chunks is not None:
        todo = todo[:max_chunks]
    if len(todo) <= 1:
        batch = batch.with_workers(1)
    if todo and batch.run.backend == "ray":  # a cluster that does not answer: no folder left
        ray_init(batch.run.address, batch.workers)
    results.begin(todo)
    solved = targets_solved = 0
    bar = progress_bar(n, batch.run.progress, initial=int(results.table["done"].sum()))
    try:
        chunks = (arrays.chunk(frame, s, min(s + chunk_size, n)) for s in todo)
        for start, chunk in iter_prepared(batch, chunks):
            results.add(start, chunk)
            solved += 1
            targets_solved += len(chunk)
            bar.update(len(chunk))
    finally:
        bar.close()
        results.end(solved)
    return results.report(before, solved, targets_solved, time.perf_counter() - start_time)


def model_fingerprint(model: mujoco.MjModel) -> str:
    """A digest of ``model``'s whole compiled content (its MJB bytes, ``mj_saveModel``): the
    same for the same file loaded again, another for any edit (a joint range, a body's
    pose), so that a results file is not resumed with another robot under the same name."""
    buffer = np.empty(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return hashlib.sha256(buffer.tobytes()).hexdigest()[:32]


def _check_out(out: str | os.PathLike) -> str:
    """``out`` as a str ending in ``.npz`` or ``.parquet`` (pyarrow then importable)."""
    out = checks.check_path("out", out)
    if not out.endswith((".npz", ".parquet")):
        raise InvalidInput(f"out must be an .npz or .parquet file, got {out!r}")
    if out.endswith(".parquet"):
        _pyarrow()  # before solving, naming the extra
    return out


def check_out_not_targets(out: str, targets: Any, name: str = "out") -> None:
    """:class:`qpik.InvalidInput` naming ``name`` when ``out`` is the targets file itself
    (the same path, a link to it or a hard link: a results file over it, or
    ``overwrite``, would destroy the targets)."""
    if not isinstance(targets, (str, os.PathLike)) or not isinstance(os.fspath(targets), str):
        return  # load_targets names a targets argument of another type
    path = os.fspath(targets)
    same = os.path.realpath(out) == os.path.realpath(path)
    if not same and os.path.exists(out) and os.path.exists(path):
        same = os.path.samefile(out, path)  # a hard link
    if same:
        flag = "--overwrite" if name.startswith("--") else "overwrite=True"
        raise InvalidInput(
            f"{name} {out!r} is the targets file {path!r}: the results would replace the "
            f"targets (refused even with {flag}); write them to another file"
        )


def _described(batch: Batch) -> dict:
    """The options of a run as the results file records them (a rerun must match): the
    resolved :class:`qpik.SolveOptions` every solve gets (``--preset default`` and no
    preset, or a default value given, are the same run), and ``q0`` / ``stack`` as given."""
    described = {k: repr(v) for k, v in sorted(batch.setup.call.items()) if k != "options"}
    described["options"] = repr(batch.options)
    return described


class _ResultsFile:
    """The results file ``out`` of a run, its table and its folder of finished chunks
    (``out + ".chunks"``, with ``meta.json``): resumed from an earlier run with the same
    ``meta``, refused (``InvalidInput``) when the earlier run's differs."""

    def __init__(self, out: str, meta: dict[str, Any], overwrite: bool):
        self.out, self.meta = out, meta
        self.folder = out + ".chunks"
        self.meta_path = os.path.join(self.folder, "meta.json")
        if overwrite:
            shutil.rmtree(self.folder, ignore_errors=True)
            if os.path.exists(out):
                os.remove(out)
        n, size = meta["n"], meta["chunk_size"]
        self.chunks = len(range(0, n, size))
        self.table = _empty_table(n, meta["nq"])
        previous = _previous_run(out, self.folder, self.meta_path, self.table)
        self.resumed = previous is not None
        self.done: set[int] = set()
        if previous is not None:
            old_meta, self.done = previous
            different = [k for k in meta if old_meta.get(k) != meta[k]]
            if different == ["model"]:
                different = ["model (the robot's content: its file edited since?)"]
            if different:
                raise InvalidInput(
                    f"{out} holds a run with different {', '.join(different)}: pass another "
                    "--out, or --overwrite to start again"
                )
        self.last_write, self.write_cost = time.perf_counter(), 0.0

    @property
    def complete(self) -> bool:
        """Whether every chunk is done."""
        return len(self.done) == self.chunks

    def begin(self, todo: Sequence[int]) -> None:
        """Create the chunk folder and its ``meta.json`` when chunks remain to solve."""
        if todo:
            os.makedirs(self.folder, exist_ok=True)
            if not os.path.exists(self.meta_path):
                _atomic_json(self.meta_path, self.meta)

    def add(self, start: int, results: Sequence[IKResult]) -> None:
        """Save a finished chunk at once; rewrite ``out`` every few seconds (at least 20
        times as long as a write takes)."""
        rows = _rows(results, self.table["q"].shape[1])
        _atomic_savez(os.path.join(self.folder, f"chunk_{start:010d}.npz"), **rows)
        _fill(self.table, start, rows)
        self.done.add(start)
        now = time.perf_counter()
        if now - self.last_write > max(5.0, 20.0 * self.write_cost):
            _write_results(self.out, self.table, self.meta)
            self.write_cost, self.last_write = time.perf_counter() - now, time.perf_counter()

    def report(self, before: int, solved: int, targets_solved: int, elapsed: float) -> BatchRun:
        """What a run did: ``before`` chunks done before it, ``solved`` chunks and
        ``targets_solved`` targets in it, in ``elapsed`` seconds."""
        table = self.table
        return BatchRun(
            self.out,
            len(table["done"]),
            self.chunks,
            before,
            solved,
            self.complete,
            elapsed,
            int(table["converged"].sum()),
            targets_solved,
            dict(Counter(str(reason) for reason in table["reason"])),
        )

    def end(self, solved: int) -> None:
        """Write ``out`` (when anything changed), and drop the folder once complete."""
        if solved or not self.resumed:
            _write_results(self.out, self.table, self.meta)
        if self.complete:
            shutil.rmtree(self.folder, ignore_errors=True)


def _empty_table(n: int, nq: int) -> dict[str, np.ndarray]:
    table: dict[str, np.ndarray] = {"q": np.full((n, nq), np.nan)}
    for name, dtype in RESULT_FIELDS.items():
        if dtype is float:
            table[name] = np.full(n, np.nan)
        elif dtype == "U16":
            table[name] = np.full(n, "pending", dtype="U16")
        else:
            table[name] = np.zeros(n, dtype=dtype)
    table["done"] = np.zeros(n, dtype=bool)
    return table


def _rows(results: Sequence[IKResult], nq: int) -> dict[str, np.ndarray]:
    return {
        "q": np.array([r.q for r in results], dtype=float).reshape(len(results), nq),
        "converged": np.array([r.converged for r in results], dtype=bool),
        "reason": np.array([r.reason for r in results], dtype="U16"),
        "position_error": np.array([r.position_error for r in results], dtype=float),
        "orientation_error": np.array([r.orientation_error for r in results], dtype=float),
        "iterations": np.array([r.iterations for r in results], dtype=np.int64),
        "restarts_used": np.array([r.restarts_used for r in results], dtype=np.int64),
        "time": np.array([r.solve_time for r in results], dtype=float),
    }


def _fill(table: dict[str, np.ndarray], start: int, rows: Mapping[str, np.ndarray]) -> None:
    stop = start + len(rows["converged"])
    for name, values in rows.items():
        table[name][start:stop] = values
    table["done"][start:stop] = True


def _meta_arrays(meta: Mapping[str, Any]) -> dict[str, np.ndarray]:

    return {"meta": np.array(json.dumps(meta))}


def _previous_run(out: str, folder: str, meta_path: str, table: dict[str, np.ndarray]):
    """``(meta, finished chunk starts)`` of an earlier run over ``out`` (``None`` if there
    was none); the finished rows are copied into ``table`` (when its shape matches)."""
    _remove_leftovers(os.path.dirname(out), os.path.basename(out))
    meta, done = _saved_file(out, table)
    if os.path.isdir(folder):
        _remove_leftovers(folder, "")
    if os.path.exists(meta_path):
        try:
            with open(meta_path) as stream:
                meta = json.load(stream)
        except (OSError, ValueError) as exc:
            if any(_CHUNK.fullmatch(name) for name in os.listdir(folder)):
                raise InvalidInput(
                    f"{meta_path} is not readable ({exc}): the run's chunks cannot be told "
                    "apart from another run's; pass --overwrite (overwrite=True) to start "
                    "again"
                ) from None
            os.remove(meta_path)  # (written before any chunk, then the run stopped)
            return None if meta is None else (meta, done)
        _saved_chunks(folder, table, done)
    return None if meta is None else (meta, done)


def _saved_file(out: str, table: dict[str, np.ndarray]) -> tuple[dict | None, set[int]]:
    """The meta and the finished chunks of the results file ``out``, rows into ``table``."""
    done: set[int] = set()
    if not os.path.exists(out):
        return None, done
    try:
        meta, saved = _read_results(out)
    except MissingExtra:
        raise
    except Exception as exc:
        raise InvalidInput(
            f"{out} exists and is not a qpik batch results file ({exc}): pass another "
            "--out, or --overwrite"
        ) from None
    if saved["q"].shape == table["q"].shape:
        size = int(meta.get("chunk_size", 1))
        for start in range(0, len(table["done"]), size):
            if saved["done"][start : start + size].all():
                done.add(start)
                for name in table:
                    table[name][start : start + size] = saved[name][start : start + size]
    return meta, done


def _saved_chunks(folder: str, table: dict[str, np.ndarray], done: set[int]) -> None:
    """Add the chunk files of ``folder`` not in ``done`` to ``table`` and ``done``."""
    n = len(table["done"])
    for name in sorted(os.listdir(folder)):
        match = _CHUNK.fullmatch(name)
        if match is None:
            continue
        start = int(match.group(1))
        if start in done or start >= n:
            continue
        with np.load(os.path.join(folder, name), allow_pickle=False) as data:
            rows = {key: data[key] for key in ("q", *RESULT_FIELDS)}
        if rows["q"].shape[1:] == table["q"].shape[1:]:
            _fill(table, start, rows)
            done.add(start)
