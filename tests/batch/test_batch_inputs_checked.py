"""What a batch is given is checked before it runs (audit h7): targets passed as arrays, a
targets row beyond the distance bound, results written over the targets, numpy integers
as a chunk size, Ray addresses and clusters that do not answer; and what a map records
(its preset) and where it is saved."""

from __future__ import annotations

import pickle
import sys

import numpy as np
import pytest

import qpik
import qpik.batch.files as files_module
import qpik.batch.ray as ray_backend
from qpik.batch import TargetArrays, load_targets, solve_file
from qpik.cli import main

P3 = np.tile([0.4, 0.1, 0.4], (3, 1))
DOWN = np.diag([1.0, -1.0, -1.0])  # the tool pointing down
ONE_VOXEL = dict(region=[[0.3, 0.0, 0.3], [0.5, 0.2, 0.5]], resolution=0.2)


# --- targets as arrays ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("positions", "rotations", "field", "said"),
    [
        (P3, np.tile(DOWN, (2, 1, 1)), "rotations", r"shape \(3, 3, 3\).*got \(2, 3, 3\)"),
        (P3[:, :2], None, "positions", r"shape \(N, 3\)"),
        (np.vstack([P3[:2], [np.nan, 0.0, 0.0]]), None, "positions", "row 2"),
        (np.vstack([P3[:2], [1e20, 0.0, 0.0]]), None, "positions", r"1e\+09 m.*row 2"),
        (P3, np.stack([DOWN, DOWN, 2.0 * DOWN]), "rotations", "row 2"),
        (P3, np.stack([DOWN, DOWN, np.full((3, 3), np.nan)]), "rotations", "row 2"),
        (P3, np.stack([DOWN, DOWN, -np.eye(3)]), "rotations", "row 2"),  # det -1
        (P3 + 0j, None, "positions", "real numbers"),
        (P3, np.tile(DOWN, (3, 1, 1)).astype(str), "rotations", "real numbers"),
    ],
)
def test_target_arrays_are_checked_as_a_file_is_before_any_solve(
    tmp_path, monkeypatch, positions, rotations, field, said
):
    monkeypatch.setattr(files_module, "iter_prepared", None)  # a solve would fail untyped
    out = tmp_path / "r.npz"
    with pytest.raises(qpik.InvalidTarget, match=rf"targets\.{field}: .*{said}"):
        solve_file("ur5e", "ee", TargetArrays(positions, rotations), out, workers=1)
    assert not out.exists() and not (tmp_path / "r.npz.chunks").exists()


def test_good_target_arrays_still_solve_every_row(tmp_path):
    arrays = TargetArrays(P3[:2].tolist(), np.tile(DOWN, (2, 1, 1)))
    run = solve_file("ur5e", "ee", arrays, tmp_path / "r.npz", workers=1, progress=False)
    assert run.complete and run.total == 2 and "pending" not in run.reasons
    with np.load(tmp_path / "r.npz") as data:
        assert data["done"].all()


def test_a_targets_row_beyond_the_distance_bound_is_refused_on_load(tmp_path, capsys):
    positions = np.tile([0.4, 0.1, 0.4], (5, 1))
    positions[3] = [1e20, 0.0, 0.0]
    np.savez(tmp_path / "far.npz", positions=positions)
    with pytest.raises(qpik.ProblemFileError, match=r"far\.npz: field 'positions': .*row 3"):
        load_targets(tmp_path / "far.npz")
    out = tmp_path / "r.npz"
    argv = ["batch", str(tmp_path / "far.npz"), "--robot", "ur5e", "--frame", "ee"]
    assert main(argv + ["--out", str(out), "--workers", "2", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "far.npz" in err and "'positions'" in err and "row 3" in err
    assert not out.exists() and not (tmp_path / "r.npz.chunks").exists()


def test_results_over_the_targets_file_are_refused_even_with_overwrite(
    tmp_path, monkeypatch, capsys
):
    targets = tmp_path / "t.npz"
    np.savez(targets, positions=P3)
    before = targets.read_bytes()
    monkeypatch.chdir(tmp_path)
    argv = ["batch", "t.npz", "--robot", "ur5e", "--frame", "ee", "--workers", "1", "--quiet"]
    for out in ("t.npz", "./t.npz", str(targets)):
        for overwrite in ([], ["--overwrite"]):
            assert main(argv + ["--out", out, *overwrite]) == 2
            err = capsys.readouterr().err
            assert "--out" in err and "targets file" in err, err
    (tmp_path / "link.npz").symlink_to(targets)
    with pytest.raises(qpik.InvalidInput, match="out .*is the targets file"):
        solve_file("ur5e", "ee", "t.npz", "link.npz", overwrite=True, workers=1)
    assert targets.read_bytes() == before


def test_a_numpy_integer_chunk_size_is_taken_as_workers_is(tmp_path):
    targets = [{"ee": p} for p in P3]
    serial = qpik.solve_many("ur5e", targets, workers=1, progress=False)
    chunked = qpik.solve_many("ur5e", targets, workers=1, chunk_size=np.int64(2), progress=False)
    for a, b in zip(serial, chunked, strict=True):
        np.testing.assert_array_equal(a.q, b.q)
    out = tmp_path / "r.npz"
    run = solve_file("ur5e", "ee", TargetArrays(P3), out, chunk_size=np.int32(2), workers=1)
    assert run.complete and run.chunks == 2  # and the file's JSON meta took the size
    for bad in (np.bool_(True), True, 0, np.int64(-2), 2.0):
        with pytest.raises(qpik.InvalidInput, match="chunk_size"):
            qpik.solve_many("ur5e", targets, workers=1, chunk_size=bad)


# --- Ray addresses ----------------------------------------------------------------------


class _Unreachable:
    """What qpik calls of the ``ray`` module, for a cluster that is not there."""

    def __init__(self, error: Exception):
        self.error = error

    def is_initialized(self) -> bool:
        return False

    def init(self, **kwargs):
        raise self.error


NO_CLUSTER = ConnectionError(
    "Could not find any running Ray instance. Please specify the one to connect to by "
    "setting `--address` flag or `RAY_ADDRESS` environment variable."
)


def test_ray_addresses_are_checked_before_anything_runs(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", _Unreachable(AssertionError("init called")))
    targets = [{"ee": P3[0]}] * 2
    for bad in ("bogus", "ray://", "host:port", "ray://host", "host:0", "h:70000", "ray://a b:1"):
        with pytest.raises(qpik.InvalidInput, match="Ray address"):
            qpik.solve_many("ur5e", targets, backend="ray", address=bad, progress=False)
    monkeypatch.setattr(ray_backend, "_has_ray_client", lambda: False)
    with pytest.raises(qpik.MissingExtra, match=r'pip install "ray\[client\]"'):
        qpik.solve_many("ur5e", targets, backend="ray", address="ray://127.0.0.1:10001")


@pytest.mark.parametrize("address", ["auto", "ray://127.0.0.1:10001", "10.0.0.1:6379"])
def test_a_ray_cluster_that_does_not_answer_is_a_typed_error(monkeypatch, address):
    monkeypatch.setitem(sys.modules, "ray", _Unreachable(NO_CLUSTER))
    monkeypatch.setattr(ray_backend, "_has_ray_client", lambda: True)
    with pytest.raises(ray_backend.RayConnectionError) as info:
        qpik.solve_many("ur5e", [{"ee": P3[0]}], backend="ray", address=address)
    error = info.value
    assert isinstance(error, qpik.QpikError) and isinstance(error, ConnectionError)
    assert error.address == address and repr(address) in str(error)
    assert "`--address`" not in str(error)  # Ray's advice names its own command line
    assert str(pickle.loads(pickle.dumps(error))) == str(error)
    monkeypatch.setitem(sys.modules, "ray", _Unreachable(ValueError("Invalid address")))
    with pytest.raises(qpik.InvalidInput, match="Invalid address"):
        qpik.solve_many("ur5e", [{"ee": P3[0]}], backend="ray", address=address)


def test_ray_address_errors_exit_2_on_the_command_line(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", _Unreachable(NO_CLUSTER))
    monkeypatch.setattr(ray_backend, "_has_ray_client", lambda: False)
    np.savez(tmp_path / "t.npz", positions=P3)
    out = tmp_path / "r.npz"
    argv = ["batch", str(tmp_path / "t.npz"), "--robot", "ur5e", "--frame", "ee"]
    argv += ["--out", str(out), "--quiet", "--ray"]
    cases = {"ray://127.0.0.1:10001": "ray[client]", "bogus": "'bogus'", "auto": "'auto'"}
    for address, said in cases.items():
        assert main(argv + [address]) == 2
        err = capsys.readouterr().err
        assert said in err and "internal error" not in err, err
        assert not (tmp_path / "r.npz.chunks").exists()  # checked before the run began
    argv = ["reachmap", "ur5e", "--frame", "ee", "--region", "0.3", "0", "0.3", "0.5", "0.2"]
    argv += ["0.5", "--resolution", "0.2", "--out", str(tmp_path / "m.npz"), "--quiet"]
    assert main(argv + ["--ray", "bogus"]) == 2
    assert "'bogus'" in capsys.readouterr().err


# --- maps: the preset recorded, the file's name ------------------------------------------


def test_a_map_records_the_preset_it_was_solved_with(tmp_path):
    rmap = qpik.reachability(
        "ur5e", "ee", orientations=0, options="fast", workers=1, progress=False, **ONE_VOXEL
    )
    assert rmap.solve_options == {"options": "fast"}
    rmap.save(tmp_path / "m.npz")
    assert qpik.ReachabilityMap.load(tmp_path / "m.npz").solve_options == {"options": "'fast'"}
    argv = ["reachmap", "ur5e", "--frame", "ee", "--region", "0.3", "0", "0.3", "0.5", "0.2"]
    argv += ["0.5", "--resolution", "0.2", "--orientations", "0", "--workers", "1"]
    assert main(argv + ["--preset", "fast", "--out", str(tmp_path / "c.npz"), "--quiet"]) == 0
    recorded = qpik.ReachabilityMap.load(tmp_path / "c.npz").solve_options
    assert recorded["options"] == "'fast'"


def test_a_map_saved_without_npz_loads_by_the_same_name(tmp_path):
    rmap = qpik.reachability("ur5e", "ee", orientations=0, workers=1, progress=False, **ONE_VOXEL)
    written = rmap.save(tmp_path / "m")
    assert written == str(tmp_path / "m.npz") and not (tmp_path / "m").exists()
    loaded = qpik.ReachabilityMap.load(tmp_path / "m")
    np.testing.assert_array_equal(loaded.fraction, rmap.fraction)
    assert rmap.save(tmp_path / "n.npz") == str(tmp_path / "n.npz")
