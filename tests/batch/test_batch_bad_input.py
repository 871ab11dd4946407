"""Bad input to the batch layer (solve_many's run options and targets, targets files,
ReachabilityMap.load and plot, qpik batch / qpik reachmap flags): typed errors naming the
argument, file or field; never a hang, an untyped error or a value silently changed."""

from __future__ import annotations

import gc
import json
import math

import numpy as np
import pytest

import qpik
import qpik.batch.pool as batch
from qpik.batch import load_targets, solve_file
from qpik.cli import main

POSITIONS = [{"ee": [0.4, 0.1, 0.4]}, {"ee": [0.3, -0.1, 0.5]}, {"ee": [0.35, 0.0, 0.45]}]


def test_a_pool_starts_no_more_workers_than_chunks_nor_than_the_cap(monkeypatch, pool_workers):
    started = pool_workers
    serial = qpik.solve_many("ur5e", POSITIONS, seed=0, workers=1, progress=False)
    options = dict(seed=0, pool_threshold=0.0, progress=False)
    # Target 0 is solved here; 2 chunks of one target are left: 2 workers, not 10**6.
    pooled = qpik.solve_many("ur5e", POSITIONS, workers=10**6, chunk_size=1, **options)
    assert started == [2]
    # Default chunking: the 2 targets left are one chunk, so one worker.
    again = qpik.solve_many("ur5e", POSITIONS, workers=300, **options)
    assert started == [2, 1]
    for results in (pooled, again):
        for a, b in zip(serial, results, strict=True):
            np.testing.assert_array_equal(a.q, b.q)
    monkeypatch.setattr(batch.os, "cpu_count", lambda: 2)
    assert batch.check_workers(10**6) == batch.WORKERS_PER_CORE * 2 == batch.max_process_workers()
    assert batch.check_workers(3) == 3
    for bad in (0, -1, 2.0, True, "2"):
        with pytest.raises(qpik.InvalidInput, match="workers"):
            qpik.solve_many("ur5e", POSITIONS, workers=bad)


@pytest.mark.parametrize(
    ("keyword", "value", "error"),
    [
        ("pool_threshold", "x", qpik.InvalidArgumentType),
        ("pool_threshold", math.nan, qpik.InvalidOption),
        ("pool_threshold", -1.0, qpik.InvalidOption),
        ("pool_threshold", None, qpik.InvalidArgumentType),
        ("progress", "yes", qpik.InvalidArgumentType),
        ("progress", 1, qpik.InvalidArgumentType),
        ("histories", "x", qpik.InvalidArgumentType),
        ("address", 3, qpik.InvalidArgumentType),
    ],
)
def test_run_options_are_checked(keyword, value, error):
    with pytest.raises(error, match=keyword):
        qpik.solve_many("ur5e", POSITIONS, seed=0, workers=2, **{keyword: value})


def test_an_infinite_pool_threshold_solves_in_this_process(monkeypatch):
    monkeypatch.setattr(batch, "ProcessPoolExecutor", None)  # a pool would fail
    results = qpik.solve_many(
        "ur5e", POSITIONS, seed=0, workers=2, pool_threshold=math.inf, progress=False
    )
    assert len(results) == 3


COMPLEX = np.array([0.4 + 0.3j, 0.1, 0.4])


@pytest.mark.parametrize(
    "targets",
    [
        [{"ee": COMPLEX}],
        [{"ee": [0.4, 0.1, 0.4j]}],
        [POSITIONS[0], {"ee": COMPLEX}],
        [{"ee": (np.array([0.4, 0.1, 0.4]), np.eye(3).astype(complex))}],
        [POSITIONS[0], {"ee": np.array(["0.4", "0.1", "0.4"])}],
        [{"ee": np.array([True, False, True])}],
    ],
)
@pytest.mark.filterwarnings("error")  # numpy's ComplexWarning would be a silent cast
def test_complex_string_or_boolean_targets_are_refused(targets):
    with pytest.raises(qpik.InvalidTarget, match=rf"targets_list\[{len(targets) - 1}\]"):
        qpik.solve_many("ur5e", targets, seed=0, workers=1, progress=False)


def test_complex_region_or_orientations_of_a_map_are_refused():
    options = dict(resolution=0.2, progress=False, workers=1)
    region = [[0.2, -0.2, 0.2], [0.6, 0.2, 0.6]]
    with pytest.raises(qpik.InvalidArgumentType, match="region"):
        qpik.reachability("ur5e", "ee", region=np.array(region) * 1j, orientations=1, **options)
    with pytest.raises(qpik.InvalidArgumentType, match="orientations"):
        qpik.reachability("ur5e", "ee", region=region, orientations=np.eye(3)[None] + 0j, **options)


# --- targets files --------------------------------------------------------------------


def test_complex_or_text_arrays_in_a_targets_file_name_the_field(tmp_path):
    np.savez(tmp_path / "c.npz", positions=np.array([[0.4 + 0.3j, 0.1, 0.4]]))
    with pytest.raises(qpik.ProblemFileError, match="positions.*complex"):
        load_targets(tmp_path / "c.npz")
    quaternions = np.array([[1.0, 0, 0, 0]], dtype=complex)
    np.savez(tmp_path / "q.npz", positions=np.zeros((1, 3)), quaternions=quaternions)
    with pytest.raises(qpik.ProblemFileError, match="quaternions.*complex"):
        load_targets(tmp_path / "q.npz")
    np.savez(tmp_path / "s.npz", positions=np.array([["0.4", "0.1", "0.4"]]))
    with pytest.raises(qpik.ProblemFileError, match="positions"):
        load_targets(tmp_path / "s.npz")
    np.save(tmp_path / "bare.npy", np.zeros((2, 3)))
    (tmp_path / "bare.npy").rename(tmp_path / "bare.npz")
    with pytest.raises(qpik.ProblemFileError, match="bare"):
        load_targets(tmp_path / "bare.npz")
    with pytest.raises(qpik.InvalidArgumentType, match="targets"):
        load_targets(3)
    np.savez(tmp_path / "good.npz", positions=np.zeros((50, 3)))
    (tmp_path / "cut.npz").write_bytes((tmp_path / "good.npz").read_bytes()[:300])
    with pytest.raises(qpik.ProblemFileError, match="cut.npz.*TARGETS"):
        load_targets(tmp_path / "cut.npz")
    gc.collect()  # a file left open would warn now (ResourceWarning: an error in the suite)


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b"x,y,z\n", r"field 'CSV'.*at least one row.*line 1"),
        (b"", r"field 'CSV'"),
        (b"# only a comment\n\n", r"field 'CSV'"),
        (b"x,y,z\n0.4,0.1\n", r"CSV line 2.*3 values.*got 2"),
        (b"id,x,y,z\n0.4,0.1,0.4\n", r"CSV line 2.*4 values.*got 3"),
        (b"x,y,z\n0.4,0.1,0.4\n0.4,0.1\n", r"CSV line 3.*3 values as on line 2, got 2"),
        (b"x,y,z\n0.4,0.1,0.4\n0.4,a,0.4\n", r"CSV line 3.*column 2.*'a'"),
        (b"\xff\xfe\x00x\x00,\x00y\n", r"field 'CSV'.*UTF-8.*byte 0"),
        (b"x,y,z\n0.4,0.1,0.4\x00\n", r"field 'CSV'.*NUL.*line 2"),
        (b"x,x,y,z\n0.4,0.1,0.4,0.4\n", r"CSV header.*'x'"),
    ],
)
def test_malformed_csv_targets_name_the_file_and_the_line(tmp_path, content, match):
    path = tmp_path / "t.csv"
    path.write_bytes(content)
    with pytest.raises(qpik.ProblemFileError, match=match) as info:
        load_targets(path)
    assert info.value.path == str(path)


def test_good_csv_targets_still_load(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("\ufeff# targets\nX, Y ,z\n\n0.4,0.1,0.4\n0.3,0.0,0.5 # second\n")
    arrays = load_targets(path)
    np.testing.assert_array_equal(arrays.positions, [[0.4, 0.1, 0.4], [0.3, 0.0, 0.5]])
    path.write_text("0.4,0.1,0.4,1,0,0,0\n")
    assert load_targets(path).rotations.shape == (1, 3, 3)


def test_batch_cli_malformed_csv_and_complex_npz_exit_2(tmp_path, capsys):
    out = str(tmp_path / "r.npz")
    cases = {
        "short.csv": (b"x,y,z\n0.4,0.1\n", "line 2"),
        "header.csv": (b"x,y,z\n", "at least one row"),
        "binary.csv": (bytes(range(256)), "UTF-8"),
    }
    for name, (content, said) in cases.items():
        (tmp_path / name).write_bytes(content)
        argv = ["batch", str(tmp_path / name), "--robot", "ur5e", "--frame", "ee"]
        assert main(argv + ["--out", out, "--workers", "1", "--quiet"]) == 2, name
        err = capsys.readouterr().err
        assert name in err and said in err and err.count("\n") == 1, err
    np.savez(tmp_path / "c.npz", positions=np.array([[0.4 + 0.3j, 0.1, 0.4]]))
    argv = ["batch", str(tmp_path / "c.npz"), "--robot", "ur5e", "--frame", "ee", "--out", out]
    assert main(argv + ["--workers", "1", "--quiet"]) == 2
    assert "positions" in capsys.readouterr().err


def test_max_chunks_must_not_be_negative(tmp_path, capsys):
    (tmp_path / "t.csv").write_text("x,y,z\n0.4,0.1,0.4\n")
    out = tmp_path / "r.npz"
    argv = ["batch", str(tmp_path / "t.csv"), "--robot", "ur5e", "--frame", "ee"]
    argv += ["--out", str(out), "--workers", "1", "--quiet"]
    with pytest.raises(SystemExit) as info:
        main(argv + ["--max-chunks", "-1"])
    assert info.value.code == 2 and "--max-chunks" in capsys.readouterr().err
    assert not out.exists()
    assert main(argv + ["--max-chunks", "0"]) == 3  # documented: checks, solves nothing
    with np.load(out) as data:
        assert not data["done"].any()
    for bad, error in ((-1, qpik.InvalidOption), (1.5, qpik.InvalidArgumentType)):
        with pytest.raises(error, match="max_chunks"):
            solve_file("ur5e", "ee", tmp_path / "t.csv", out, max_chunks=bad, workers=1)
    with pytest.raises(qpik.InvalidArgumentType, match="overwrite"):
        solve_file("ur5e", "ee", tmp_path / "t.csv", out, overwrite="yes", workers=1)


# --- reachability maps ----------------------------------------------------------------


@pytest.fixture(scope="module")
def saved_map(tmp_path_factory):
    """A small map (8 voxels, 2 orientations), saved; and its arrays."""
    rmap = qpik.reachability(
        "ur5e",
        "ee",
        progress=False,
        restarts=0,
        workers=1,
        region=[[0.2, -0.2, 0.2], [0.6, 0.2, 0.6]],
        resolution=0.2,
        orientations=2,
    )
    path = tmp_path_factory.mktemp("map") / "good.npz"
    rmap.save(path)
    with np.load(path) as data:
        arrays = dict(data)
    return rmap, path, arrays


def _meta(arrays, **changes):
    meta = json.loads(str(arrays["meta"]))
    meta.update(changes)
    for name in [k for k, v in changes.items() if v is _DROP]:
        del meta[name]
    return np.array(json.dumps(meta))


_DROP = object()


def _variants(arrays):
    """Broken copies of a good map's arrays, with the field the error must name."""
    good = dict(arrays)
    fraction = good["fraction"]
    return {
        "foreign": ({"positions": np.zeros((3, 3))}, "meta"),
        "bad json": ({**good, "meta": np.array("not json")}, "meta"),
        "meta list": ({**good, "meta": np.array("[1, 2]")}, "meta"),
        "meta array": ({**good, "meta": np.zeros(3)}, "meta"),
        "no solve_options": ({**good, "meta": _meta(good, solve_options=_DROP)}, "solve_options"),
        "text resolution": ({**good, "meta": _meta(good, resolution="abc")}, "resolution"),
        "negative resolution": ({**good, "meta": _meta(good, resolution=-0.2)}, "resolution"),
        "bad shape": ({**good, "meta": _meta(good, shape=[2, 2])}, "shape"),
        "other grid": ({**good, "meta": _meta(good, shape=[1, 2, 4])}, "centers"),
        "other resolution": ({**good, "meta": _meta(good, resolution=0.3)}, "centers"),
        "text frame": ({**good, "meta": _meta(good, frame=3)}, "frame"),
        "nan reach": ({**good, "meta": _meta(good, reach=float("nan"))}, "reach"),
        "bad engines": ({**good, "meta": _meta(good, engines={"compiled": -1})}, "engines"),
        "bad pairs": ({**good, "meta": _meta(good, collision_pairs=[["a"]])}, "collision_pairs"),
        "missing centers": ({k: v for k, v in good.items() if k != "centers"}, "centers"),
        "nan fraction": ({**good, "fraction": np.full(8, np.nan)}, "fraction"),
        "fraction above 1": ({**good, "fraction": fraction + 2.0}, "fraction"),
        # (0.5 from each entry, within [0, 1): unlike 1 - fraction, never the same array,
        # a map whose every voxel has half its orientations reached included)
        "fraction not reached's": ({**good, "fraction": (fraction + 0.5) % 1.0}, "fraction"),
        "short fraction": ({**good, "fraction": fraction[:3]}, "fraction"),
        "centers 2-d": ({**good, "centers": np.zeros((3, 2))}, "centers"),
        "centers text": ({**good, "centers": good["centers"].astype(str)}, "centers"),
        "centers nan": ({**good, "centers": good["centers"] * np.nan}, "centers"),
        "centers complex": ({**good, "centers": good["centers"] + 0j}, "centers"),
        "reached ints": ({**good, "reached": good["reached"].astype(int)}, "reached"),
        "reached columns": ({**good, "reached": good["reached"][:, :1]}, "reached"),
        "skipped shape": ({**good, "skipped": good["skipped"][:2]}, "skipped"),
        "orientations": ({**good, "orientations": good["orientations"] * 2.0}, "orientations"),
        "region": ({**good, "region": np.zeros(6)}, "region"),
        "base": ({**good, "base": np.array([np.inf, 0, 0])}, "base"),
    }


def test_reachability_map_load_checks_the_file_and_names_the_field(saved_map, tmp_path):
    rmap, path, arrays = saved_map
    loaded = qpik.ReachabilityMap.load(path)
    np.testing.assert_array_equal(loaded.fraction, rmap.fraction)
    assert loaded.shape == rmap.shape and loaded.solve_options == {"restarts": "0"}
    # A map from before collisions and engines were saved still loads.
    old = tmp_path / "old.npz"
    np.savez(old, **{**arrays, "meta": _meta(arrays, collision_pairs=_DROP, engines=_DROP)})
    assert qpik.ReachabilityMap.load(old).collision_pairs == []
    for name, (content, field) in _variants(arrays).items():
        broken = tmp_path / f"{name.replace(' ', '_')}.npz"
        np.savez(broken, **content)
        with pytest.raises(qpik.ProblemFileError, match=field) as info:
            qpik.ReachabilityMap.load(broken)
        assert info.value.path == str(broken), name
        assert field in info.value.field, (name, info.value)


def test_reachability_map_load_of_a_missing_or_truncated_file(saved_map, tmp_path):
    _rmap, path, _arrays = saved_map
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(path.read_bytes()[:300])
    for bad in (truncated, tmp_path / "missing.npz", tmp_path):
        with pytest.raises(qpik.ProblemFileError, match=r"'\(file\)'") as info:
            qpik.ReachabilityMap.load(bad)
        assert info.value.path == str(bad)
    gc.collect()  # no file left open
    with pytest.raises(qpik.InvalidArgumentType, match="path"):
        qpik.ReachabilityMap.load(3)


def test_reachability_plot_checks_slices(saved_map, tmp_path):
    pytest.importorskip("matplotlib")
    rmap = saved_map[0]
    with pytest.raises(qpik.InvalidOption, match="slices"):
        rmap.plot(tmp_path / "m.png", slices=-3)
    for bad in (1.5, True, "2"):
        with pytest.raises(qpik.InvalidArgumentType, match="slices"):
            rmap.plot(tmp_path / "m.png", slices=bad)
    with pytest.raises(qpik.InvalidOption, match="dpi"):
        qpik.batch.reachability_map.plot_reachability(rmap, tmp_path / "m.png", dpi=-5)
    rmap.plot(tmp_path / "m.png", slices=0)  # the 3D view alone
    assert (tmp_path / "m.png").stat().st_size > 1000


def test_reachmap_cli_refuses_a_negative_minimum_distance(tmp_path, capsys):
    argv = ["reachmap", "ur5e", "--frame", "ee", "--region", "0.2", "-0.2", "0.2", "0.6"]
    argv += ["0.2", "0.6", "--resolution", "0.2", "--out", str(tmp_path / "m.npz")]
    for bad in ("-1", "nan", "inf", "x"):
        with pytest.raises(SystemExit) as info:
            main(argv + ["--collision", "self", "--min-distance", bad])
        assert info.value.code == 2
        assert "--min-distance" in capsys.readouterr().err
