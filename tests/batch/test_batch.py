"""Batch IK (qpik.batch, qpik batch): same answers serial, pooled, chunked or on Ray; typed
errors; results written chunk by chunk and resumed."""

from __future__ import annotations

import re
import shutil
import sys

import mujoco
import numpy as np
import pytest

import qpik
import qpik.batch.pool as batch
import qpik.batch.worker as worker
from qpik.batch import iter_solve, load_targets, solve_file
from qpik.batch.chunks import Chunk
from qpik.batch.worker import target_seed
from qpik.cli import main
from qpik.errors import InvalidInput
from qpik.robots import robot_path


def pose_targets(robot: str, count: int, seed: int = 0, frame: str = "ee") -> list[dict]:
    """Reachable pose targets (FK of random configurations within the limits)."""
    configuration = qpik.Configuration(qpik.load_robot(robot))
    rng = np.random.default_rng(seed)
    targets = []
    for _ in range(count):
        configuration.update(configuration.random_q(rng))
        position, rotation = configuration.frame_pose(frame)
        targets.append({frame: (position.copy(), rotation.copy())})
    return targets


#: 8 reachable ur5e poses and 2 far out of reach (those take the restart path).
TARGETS = pose_targets("ur5e", 8) + [{"ee": [2.0, 0.0, 0.3]}, {"ee": [0.0, -1.9, 0.8]}]


def assert_same(a: list[qpik.IKResult], b: list[qpik.IKResult]) -> None:
    assert len(a) == len(b)
    for i, (x, y) in enumerate(zip(a, b, strict=True)):
        np.testing.assert_array_equal(x.q, y.q, err_msg=f"target {i}")
        assert (x.converged, x.reason, x.iterations) == (y.converged, y.reason, y.iterations), i


def test_target_seed_depends_on_seed_and_index_only():
    seeds = [target_seed(7, i) for i in range(100)]
    assert len(set(seeds)) == 100
    assert seeds == [target_seed(7, i) for i in range(100)]
    assert target_seed(8, 0) != target_seed(7, 0)
    assert all(isinstance(s, int) and s >= 0 for s in seeds)


def test_each_entry_is_reproduced_by_solve_with_its_seed():
    results = qpik.solve_many("ur5e", TARGETS, seed=11, workers=1, progress=False)
    for i, result in enumerate(results):  # through a worker's IKSession: qpik.solve's q
        alone = qpik.solve("ur5e", TARGETS[i], seed=target_seed(11, i))
        np.testing.assert_array_equal(alone.q, result.q)
        assert (alone.converged, alone.reason, alone.iterations) == (
            result.converged,
            result.reason,
            result.iterations,
        )
    assert sum(r.converged for r in results[:8]) >= 6  # reachable poses, mostly solved
    assert [r.reason for r in results[8:]] == ["unreachable"] * 2


def test_serial_equals_process_pool_whatever_the_chunking():
    serial = qpik.solve_many("ur5e", TARGETS, seed=5, workers=1, progress=False)
    for chunk_size in (1, 3, None):
        pooled = qpik.solve_many(
            "ur5e",
            TARGETS,
            seed=5,
            workers=2,
            chunk_size=chunk_size,
            pool_threshold=0.0,
            progress=False,
        )
        assert_same(serial, pooled)
    # The whole batch again, reversed and in one process: no state carried between solves.
    backwards = qpik.solve_many("ur5e", TARGETS[::-1], seed=5, workers=1, progress=False)
    for i, result in enumerate(backwards[::-1]):
        alone = qpik.solve("ur5e", TARGETS[i], seed=target_seed(5, len(TARGETS) - 1 - i))
        np.testing.assert_array_equal(alone.q, result.q)


def test_pool_is_used_and_tiny_batches_stay_in_process(monkeypatch, pool_workers):
    started = pool_workers
    qpik.solve_many("ur5e", TARGETS[:3], seed=0, workers=2, progress=False)
    assert started == []  # three fast targets: a pool costs more than it saves
    options = dict(seed=0, pool_threshold=0.0, chunk_size=1, progress=False)
    qpik.solve_many("ur5e", TARGETS[:4], workers=2, **options)  # 3 chunks after target 0
    assert started == [2]
    monkeypatch.setattr(batch.os, "cpu_count", lambda: 3)
    qpik.solve_many("ur5e", TARGETS[:4], **options)
    assert started == [2, 3]  # workers=None: every core


def test_iter_solve_streams_chunks_and_a_configuration_gives_q0():
    model = qpik.load_robot("panda")
    q0 = model.key_qpos[0]
    targets = pose_targets("panda", 5, seed=2)
    chunks = [Chunk(0, targets[:2]), Chunk(2, targets[2:])]
    got = dict(iter_solve(qpik.Configuration(model, q0), chunks, seed=4, workers=1))
    assert sorted(got) == [0, 2] and len(got[0]) == 2 and len(got[2]) == 3
    for i, result in enumerate(got[0] + got[2]):
        alone = qpik.solve(model, targets[i], q0=q0, seed=target_seed(4, i))
        np.testing.assert_array_equal(alone.q, result.q)


def test_bad_inputs_raise_typed_errors_naming_the_argument():
    with pytest.raises(qpik.UnknownFrame, match="gripper"):
        qpik.solve_many("ur5e", [{"ee": [0.3, 0, 0.3]}, {"gripper": [0.3, 0, 0.3]}])
    with pytest.raises(qpik.InvalidTarget, match=r"targets_list\[1\]"):
        qpik.solve_many("ur5e", [{"ee": [0.3, 0, 0.3]}, {"ee": [np.nan, 0, 0.3]}])
    with pytest.raises(qpik.InvalidTarget, match=r"targets_list\[0\]"):
        qpik.solve_many("ur5e", [[0.3, 0, 0.3]])
    with pytest.raises(qpik.InvalidInput, match="workers"):
        qpik.solve_many("ur5e", TARGETS, workers=0)
    with pytest.raises(qpik.InvalidInput, match="backend"):
        qpik.solve_many("ur5e", TARGETS, backend="dask")
    with pytest.raises(qpik.InvalidInput, match="seed"):
        qpik.solve_many("ur5e", TARGETS, seed=-1)
    with pytest.raises(qpik.InvalidInput, match="chunk_size"):
        qpik.solve_many("ur5e", TARGETS, chunk_size=0)
    with pytest.raises(qpik.InvalidInput, match="robot"):
        qpik.solve_many(3.0, TARGETS)
    with pytest.raises(qpik.InvalidInput, match="alpha"):  # an option, checked in-process
        qpik.solve_many("ur5e", TARGETS, alpha=5.0, workers=2, progress=False)
    with pytest.raises(qpik.InvalidInput, match="backend='ray'"):
        qpik.solve_many("ur5e", TARGETS, address="auto", workers=2, pool_threshold=0.0)
    assert qpik.solve_many("ur5e", [], progress=False) == []


def test_an_error_in_a_worker_is_raised_with_its_type(monkeypatch):
    real_solve = worker.solve

    def failing(model, targets, **options):
        if np.allclose(targets["ee"][0], TARGETS[6]["ee"][0]):
            raise qpik.InvalidTarget("target 6 is cursed")
        return real_solve(model, targets, **options)

    monkeypatch.setattr(worker, "solve", failing)  # workers fork with the patch
    with pytest.raises(qpik.InvalidTarget, match="cursed"):
        qpik.solve_many("ur5e", TARGETS, workers=2, pool_threshold=0.0, progress=False)


def test_progress_bar_shows_rate_and_eta(capsys):
    qpik.solve_many("ur5e", TARGETS[:3], workers=1, progress=False)
    assert capsys.readouterr().err == ""
    bar = batch.progress_bar(10, True, initial=4)
    bar.update(1)
    text = str(bar)
    bar.close()
    assert "5/10" in text and "<" in text  # elapsed<remaining


# --- Ray ----------------------------------------------------------------------------------


def test_missing_ray_names_the_cluster_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(qpik.MissingExtra, match=r"qpik\[cluster\]"):
        qpik.solve_many("ur5e", TARGETS, backend="ray", progress=False)


def test_ray_results_equal_serial():
    ray = pytest.importorskip("ray")
    serial = qpik.solve_many("ur5e", TARGETS, seed=5, workers=1, progress=False)
    started_here = not ray.is_initialized()
    if started_here:
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        on_ray = qpik.solve_many(
            "ur5e", TARGETS, seed=5, backend="ray", chunk_size=3, progress=False
        )
        assert_same(serial, on_ray)
        model = qpik.load_robot("ur5e")  # an MjModel travels through the object store
        again = qpik.solve_many(model, TARGETS[:3], seed=5, backend="ray", progress=False)
        assert_same(serial[:3], again)
        region = [[0.3, -0.1, 0.3], [0.5, 0.1, 0.3]]  # a reachability map runs there too
        options = dict(region=region, resolution=0.2, orientations=2, progress=False)
        on_ray_map = qpik.reachability("ur5e", "ee", backend="ray", **options)
        local_map = qpik.reachability("ur5e", "ee", workers=1, **options)
        np.testing.assert_array_equal(on_ray_map.reached, local_map.reached)
    finally:
        if started_here:
            ray.shutdown()


# --- qpik batch: files, chunks, resume ----------------------------------------------------


def write_targets(path, targets=TARGETS[:8]):
    positions = np.array([t["ee"][0] for t in targets])
    quaternions = np.zeros((len(targets), 4))
    for q, t in zip(quaternions, targets):
        mujoco.mju_mat2Quat(q, t["ee"][1].ravel())
    np.savez(path, positions=positions, quaternions=quaternions)
    return positions, quaternions


def test_load_targets_npz_and_csv(tmp_path):
    positions, quaternions = write_targets(tmp_path / "t.npz")
    arrays = load_targets(tmp_path / "t.npz")
    np.testing.assert_allclose(arrays.positions, positions)
    for rotation, target in zip(arrays.rotations, TARGETS[:8]):
        np.testing.assert_allclose(rotation, target["ee"][1], atol=1e-12)
    table = np.hstack([positions, quaternions])
    np.savetxt(tmp_path / "t.csv", table, delimiter=",", header="x,y,z,qw,qx,qy,qz", comments="")
    from_csv = load_targets(tmp_path / "t.csv")
    np.testing.assert_allclose(from_csv.rotations, arrays.rotations, atol=1e-12)
    np.savetxt(tmp_path / "p.csv", positions, delimiter=",")
    assert load_targets(tmp_path / "p.csv").rotations is None


def test_malformed_targets_files_name_the_field(tmp_path):
    np.savez(tmp_path / "a.npz", points=np.zeros((3, 3)))
    with pytest.raises(qpik.ProblemFileError, match="positions"):
        load_targets(tmp_path / "a.npz")
    np.savez(tmp_path / "b.npz", positions=np.zeros((3, 2)))
    with pytest.raises(qpik.ProblemFileError, match=r"positions.*\(N, 3\)"):
        load_targets(tmp_path / "b.npz")
    np.savez(tmp_path / "c.npz", positions=np.zeros((2, 3)), quaternions=[[0, 0, 0, 2.0]] * 2)
    with pytest.raises(qpik.ProblemFileError, match="unit quaternion"):
        load_targets(tmp_path / "c.npz")
    np.savez(tmp_path / "d.npz", positions=[[0, np.inf, 0]])
    with pytest.raises(qpik.ProblemFileError, match="row 0"):
        load_targets(tmp_path / "d.npz")
    (tmp_path / "e.csv").write_text("a,b,c\n1,2,3\n")
    with pytest.raises(qpik.ProblemFileError, match="x, y, z"):
        load_targets(tmp_path / "e.csv")
    with pytest.raises(qpik.ProblemFileError, match="no such file"):
        load_targets(tmp_path / "missing.npz")


def test_batch_file_resumes_without_redoing_chunks(tmp_path, monkeypatch):
    write_targets(tmp_path / "t.npz")
    out = tmp_path / "r.npz"
    solved: list[int] = []
    real_solve = worker.solve

    def counting(model, targets, **options):
        solved.append(1)
        return real_solve(model, targets, **options)

    monkeypatch.setattr(worker, "solve", counting)
    first = solve_file("ur5e", "ee", tmp_path / "t.npz", out, chunk_size=3, workers=1, max_chunks=2)
    assert (first.chunks, first.chunks_solved, first.complete) == (3, 2, False)
    assert len(solved) == 6
    partial = np.load(out)
    assert partial["done"].tolist() == [True] * 6 + [False] * 2
    assert partial["reason"][7] == "pending" and np.isnan(partial["q"][7]).all()
    assert sorted(p.name for p in (tmp_path / "r.npz.chunks").iterdir()) == [
        "chunk_0000000000.npz",
        "chunk_0000000003.npz",
        "meta.json",
    ]
    second = solve_file("ur5e", "ee", tmp_path / "t.npz", out, chunk_size=3, workers=1)
    assert (second.chunks_before, second.chunks_solved, second.complete) == (2, 1, True)
    assert len(solved) == 8  # only the last chunk's two targets
    assert not (tmp_path / "r.npz.chunks").exists()
    third = solve_file("ur5e", "ee", tmp_path / "t.npz", out, chunk_size=3, workers=1)
    assert third.chunks_solved == 0 and len(solved) == 8
    data = np.load(out)
    arrays = load_targets(tmp_path / "t.npz")  # the file's rotations (from quaternions)
    as_read = [{"ee": (p, r)} for p, r in zip(arrays.positions, arrays.rotations)]
    expected = qpik.solve_many("ur5e", as_read, seed=0, workers=1, progress=False)
    np.testing.assert_array_equal(data["q"], np.array([r.q for r in expected]))
    assert data["converged"].all() and data["done"].all()
    assert data["reason"].tolist() == [r.reason for r in expected]
    np.testing.assert_array_equal(data["position_error"], [r.position_error for r in expected])
    assert (data["time"] > 0).all()


def test_batch_file_refuses_to_resume_with_an_edited_robot(tmp_path):
    """The same robot name (a file, or a model object) with other content: an interrupted
    run is not resumed with it (the rows would mix two robots); a reload of the same file
    is the same robot and resumes."""
    write_targets(tmp_path / "t.npz")
    arm = tmp_path / "arm.xml"
    shutil.copy(robot_path("ur5e"), arm)
    out = tmp_path / "r.npz"
    solve_file(str(arm), "ee", tmp_path / "t.npz", out, chunk_size=3, workers=1, max_chunks=1)
    text = arm.read_text()
    assert 'range="-3.14159265 3.14159265"' in text  # the elbow
    arm.write_text(text.replace('range="-3.14159265 3.14159265"', 'range="-0.5 0.5"', 1))
    with pytest.raises(InvalidInput, match="different model"):
        solve_file(str(arm), "ee", tmp_path / "t.npz", out, chunk_size=3, workers=1)
    edited = qpik.load_robot("ur5e")
    edited.jnt_range[2] = [-0.5, 0.5]
    out2 = tmp_path / "r2.npz"
    solve_file(qpik.load_robot("ur5e"), "ee", tmp_path / "t.npz", out2, chunk_size=3, workers=1,
               max_chunks=1)  # fmt: skip
    with pytest.raises(InvalidInput, match="different model"):
        solve_file(edited, "ee", tmp_path / "t.npz", out2, chunk_size=3, workers=1)
    resumed = solve_file(qpik.load_robot("ur5e"), "ee", tmp_path / "t.npz", out2, chunk_size=3,
                         workers=1)  # fmt: skip
    assert resumed.chunks_before == 1 and resumed.complete


def test_batch_cli_interrupted_then_resumed_with_workers(tmp_path, monkeypatch, capsys):
    write_targets(tmp_path / "t.npz")
    out = tmp_path / "r.npz"
    argv = ["batch", str(tmp_path / "t.npz"), "--robot", "ur5e", "--frame", "ee"]
    argv += ["--out", str(out), "--chunk-size", "2", "--quiet"]
    real_solve = worker.solve

    def interrupted(model, targets, **options):
        if np.allclose(targets["ee"][0], TARGETS[5]["ee"][0]):
            raise KeyboardInterrupt
        return real_solve(model, targets, **options)

    monkeypatch.setattr(worker, "solve", interrupted)
    assert main(argv + ["--workers", "1"]) == 130
    assert "resume" in capsys.readouterr().err
    assert np.load(out)["done"].sum() == 4  # chunks [0, 1] and [2, 3]
    monkeypatch.setattr(worker, "solve", real_solve)
    assert main(argv + ["--workers", "2"]) == 0
    data = np.load(out)
    assert data["done"].all() and data["converged"].all()
    # A rerun with other options would mix two runs: refused, exit 2.
    assert main(argv + ["--seed", "3"]) == 2
    assert "different seed" in capsys.readouterr().err
    assert main(argv + ["--seed", "3", "--overwrite", "--max-chunks", "1"]) == 3


def test_batch_cli_errors_exit_2(tmp_path, capsys):
    write_targets(tmp_path / "t.npz")
    base = ["batch", str(tmp_path / "t.npz"), "--robot", "ur5e", "--out", str(tmp_path / "r.npz")]
    assert main(base + ["--frame", "gripper"]) == 2
    assert "gripper" in capsys.readouterr().err
    assert (
        main(
            [
                "batch",
                str(tmp_path / "none.npz"),
                "--robot",
                "ur5e",
                "--frame",
                "ee",
                "--out",
                str(tmp_path / "r.npz"),
            ]
        )
        == 2
    )
    assert "no such file" in capsys.readouterr().err
    assert main(base[:-1] + [str(tmp_path / "r.txt"), "--frame", "ee"]) == 2
    assert ".npz" in capsys.readouterr().err


def test_parquet_results_resume_and_match_npz(tmp_path, monkeypatch):
    pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    write_targets(tmp_path / "t.npz")
    npz = solve_file("ur5e", "ee", tmp_path / "t.npz", tmp_path / "r.npz", chunk_size=3, workers=1)
    out = tmp_path / "r.parquet"
    first = solve_file("ur5e", "ee", tmp_path / "t.npz", out, chunk_size=3, workers=1, max_chunks=1)
    assert not first.complete and pq.read_table(out).column("done").to_pylist().count(True) == 3
    second = solve_file("ur5e", "ee", tmp_path / "t.npz", out, chunk_size=3, workers=1)
    assert (second.chunks_before, second.chunks_solved, second.complete) == (1, 2, True)
    assert npz.complete
    table = pq.read_table(out)
    data = np.load(tmp_path / "r.npz")
    q = np.array(table.column("q").to_pylist())
    np.testing.assert_array_equal(q, data["q"])
    assert table.column("reason").to_pylist() == data["reason"].tolist()
    assert table.column("index").to_pylist() == list(range(8))


def test_parquet_without_pyarrow_names_the_extra(tmp_path, monkeypatch):
    write_targets(tmp_path / "t.npz")
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    with pytest.raises(qpik.MissingExtra, match=r"qpik\[cluster\]"):
        solve_file("ur5e", "ee", tmp_path / "t.npz", tmp_path / "r.parquet", workers=1)


def test_public_names_exist_and_are_documented():
    import inspect

    import qpik.batch
    import qpik.batch.chunks
    import qpik.batch.files
    import qpik.batch.ray
    import qpik.batch.reachability_map as reach_module

    modules = (qpik.batch, batch, qpik.batch.files, reach_module, qpik.batch.chunks, worker)
    for module in (*modules, qpik.batch.ray):
        for name in module.__all__:
            obj = getattr(module, name)
            if inspect.isfunction(obj) or inspect.isclass(obj):
                assert obj.__doc__, f"{module.__name__}.{name} has no docstring"
            if inspect.isfunction(obj):
                hints = inspect.signature(obj)
                assert hints.return_annotation is not inspect.Signature.empty, name
    assert qpik.solve_many is batch.solve_many
    assert qpik.reachability is reach_module.reachability
    assert qpik.ReachabilityMap is reach_module.ReachabilityMap
    assert {"solve_many", "reachability", "ReachabilityMap"} <= set(qpik.__all__)


def test_batch_cli_sigterm_ends_like_ctrl_c(tmp_path, monkeypatch, capsys):
    import os
    import signal

    write_targets(tmp_path / "t.npz")
    out = tmp_path / "r.npz"
    argv = ["batch", str(tmp_path / "t.npz"), "--robot", "ur5e", "--frame", "ee"]
    argv += ["--out", str(out), "--chunk-size", "2", "--workers", "1", "--quiet"]
    real_solve = worker.solve

    def terminated(model, targets, **options):
        if np.allclose(targets["ee"][0], TARGETS[4]["ee"][0]):
            os.kill(os.getpid(), signal.SIGTERM)  # a scheduler preempting the job
        return real_solve(model, targets, **options)

    before = signal.getsignal(signal.SIGTERM)
    monkeypatch.setattr(worker, "solve", terminated)
    assert main(argv) == 130
    assert signal.getsignal(signal.SIGTERM) is before  # the CLI's handler is removed
    assert np.load(out)["done"].sum() == 4
    assert sorted(p.name for p in (tmp_path / "r.npz.chunks").glob("chunk_*")) == [
        "chunk_0000000000.npz",
        "chunk_0000000002.npz",
    ]


def test_histories_are_dropped_unless_asked_for():
    lean = qpik.solve_many("ur5e", TARGETS[:3], seed=2, workers=1, progress=False)
    full = qpik.solve_many("ur5e", TARGETS[:3], seed=2, workers=1, progress=False, histories=True)
    alone = qpik.solve("ur5e", TARGETS[2], seed=target_seed(2, 2))
    assert len(lean[2].path) == 0 and len(lean[2].residual_history) == 0
    np.testing.assert_array_equal(full[2].path, alone.path)
    assert list(full[2].error_history) == list(alone.error_history)
    for a, b in zip(lean, full, strict=True):
        np.testing.assert_array_equal(a.q, b.q)
        assert (a.reason, a.iterations, a.position_error) == (
            b.reason,
            b.iterations,
            b.position_error,
        )


def test_options_object_in_a_batch_matches_keywords_and_is_checked_here():
    by_keywords = qpik.solve_many("ur5e", TARGETS[:3], workers=1, progress=False, max_iters=30)
    options = qpik.SolveOptions(max_iters=30, seed=99)  # a batch's seed is its own argument
    by_options = qpik.solve_many("ur5e", TARGETS[:3], workers=1, progress=False, options=options)
    for a, b in zip(by_keywords, by_options):
        np.testing.assert_array_equal(a.q, b.q)
    fast = qpik.solve_many("ur5e", TARGETS[:2], workers=1, progress=False, options="fast")
    assert all(r.iterations <= 6 * 50 for r in fast)
    with pytest.raises(qpik.InvalidOption, match="max_iters"):
        qpik.solve_many("ur5e", TARGETS[:2], workers=2, progress=False, max_iters=-1)


def test_worker_transport_packs_bitwise():
    """Chunks of plain pose targets and their results travel between processes as stacked
    arrays (cheap to pickle); what arrives is what was sent, bitwise."""
    import pickle

    from qpik.batch import chunks as C

    model = qpik.load_robot("ur5e")
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(3)
    targets = []
    for _ in range(10):
        configuration.update(configuration.random_q(rng))
        targets.append({"ee": configuration.frame_pose("ee")})
    packed = C.pack_chunk(C.Chunk(5, targets))
    assert isinstance(packed, C.PackedChunk)
    chunk = pickle.loads(pickle.dumps(packed)).unpack()
    assert chunk.start == 5
    for sent, got in zip(targets, chunk.targets):
        assert sent["ee"][0].tobytes() == got["ee"][0].tobytes()
        assert sent["ee"][1].tobytes() == got["ee"][1].tobytes()
    positions = [{"ee": t["ee"][0]} for t in targets]
    assert C.pack_chunk(C.Chunk(0, positions)).rotations is None
    for odd in ([{"ee": [0.1, 0.2, 0.3]}], [{"ee": targets[0]["ee"]}, {"ee": [0.1, 0.2, 0.3]}],
                [{"ee": targets[0]["ee"], ("ee", "site"): targets[1]["ee"]}]):  # fmt: skip
        assert isinstance(C.pack_chunk(C.Chunk(0, odd)), C.Chunk)
    results = [C.without_histories(qpik.solve(model, t, seed=i)) for i, t in enumerate(targets)]
    results.append(C.without_histories(qpik.solve(model, {"ee": [3.0, 0.0, 0.4]}, seed=1)))
    back = C.unpack_results(pickle.loads(pickle.dumps(C.pack_results(results))))
    for a, b in zip(results, back, strict=True):
        assert a.q.tobytes() == b.q.tobytes() and a.reason is b.reason
        assert (a.converged, a.iterations, a.restarts_used, a.engine) == (
            b.converged, b.iterations, b.restarts_used, b.engine)  # fmt: skip
        assert np.array([a.position_error, a.orientation_error, a.solve_time]).tobytes() == (
            np.array([b.position_error, b.orientation_error, b.solve_time]).tobytes())  # fmt: skip
        assert a.frame_errors == b.frame_errors and a.path.shape == b.path.shape == (0, 0)
    assert C.pack_results([]) == []


def test_stacked_batches_are_checked_and_solved_as_the_plain_ones():
    """A batch of one frame's (position, rotation) targets is checked at once and sent as
    stacked arrays; the results are bitwise those of the same targets one by one, and a bad
    target still raises the typed error naming its index."""
    from qpik.batch import chunks as C

    model = qpik.load_robot("ur5e")
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(4)
    targets = []
    for _ in range(40):
        configuration.update(configuration.random_q(rng))
        position, rotation = configuration.frame_pose("ee")
        targets.append({"ee": (list(position), rotation)})  # lists too: read as parse_target does
    stacked = C.stack_targets(model, targets)
    assert stacked is not None and len(stacked) == 40 and len(stacked[5:9]) == 4
    assert stacked[3]["ee"][0].tolist() == targets[3]["ee"][0]
    serial = qpik.solve_many(model, targets, workers=1, progress=False)
    pooled = qpik.solve_many(model, targets, workers=2, pool_threshold=0.0, progress=False)
    one_by_one = [
        qpik.solve(model, t, seed=batch.target_seed(0, i), **{}) for i, t in enumerate(targets)
    ]
    for a, b, c in zip(serial, pooled, one_by_one, strict=True):
        assert a.q.tobytes() == b.q.tobytes() == c.q.tobytes()
    positions = [{"ee": t["ee"][0]} for t in targets]
    assert C.stack_targets(model, positions).rotations is None
    bad = list(targets)
    bad[7] = {"ee": (targets[7]["ee"][0], 2.0 * targets[7]["ee"][1])}
    assert C.stack_targets(model, bad) is None
    with pytest.raises(qpik.InvalidTarget, match=r"targets_list\[7\]"):
        qpik.solve_many(model, bad, workers=1, progress=False)
    mixed = [{"ee": targets[0]["ee"]}, {("ee", "site"): targets[1]["ee"]}]
    assert C.stack_targets(model, mixed) is None
    with pytest.raises(qpik.UnknownFrame):
        C.stack_targets(model, [{"nope": targets[0]["ee"]}])


def test_a_batch_mixing_poses_and_positions_is_stacked_and_pooled_as_serial():
    """Pose targets and position targets of one frame (benchmarks/batch.py's batch) are
    stacked at once; pooled results equal serial ones field for field (histories aside)."""
    from qpik.batch import chunks as C

    model = qpik.load_robot("ur5e")
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(5)
    targets: list[dict] = []
    for k in range(24):
        configuration.update(configuration.random_q(rng))
        position, rotation = configuration.frame_pose("ee")
        targets.append({"ee": (position, rotation)} if k % 4 else {"ee": list(position)})
    targets.append({"ee": [3.0, 0.0, 0.4]})  # out of reach
    stacked = C.stack_targets(model, targets)
    assert stacked is not None and stacked.posed is not None
    assert stacked[4]["ee"].tolist() == targets[4]["ee"] and len(stacked[3]["ee"]) == 2
    assert len(stacked[2:9]) == 7 and stacked[2:9][2]["ee"].tolist() == targets[4]["ee"]
    serial = qpik.solve_many(model, targets, workers=1, progress=False)
    pooled = qpik.solve_many(
        model, targets, workers=2, pool_threshold=0.0, chunk_size=5, progress=False
    )
    for a, b in zip(serial, pooled, strict=True):
        assert a.q.tobytes() == b.q.tobytes()
        for name in ("converged", "reason", "iterations", "restarts_used", "frame_errors"):
            assert getattr(a, name) == getattr(b, name), name
        for name in ("engine", "levels_met", "coupling_error", "constraint_error"):
            assert getattr(a, name) == getattr(b, name), name


@pytest.mark.parametrize("n", [1, 2, 17, 1000, 20401])
@pytest.mark.parametrize("workers", [1, 2, 16])
def test_guided_chunks_cover_the_targets_once_largest_first(n, workers):
    """Default chunks: consecutive, covering targets 1..n-1 once, each between the
    smallest and the largest default size (but the last), sizes never growing; a given
    chunk_size is used as it is."""
    from qpik.batch.pool import _MAX_CHUNK, _MIN_CHUNK, chunk_starts

    chunks = list(chunk_starts(1, n, workers))
    assert [s for s, _ in chunks] == [1, *(e for _, e in chunks[:-1])][: len(chunks)]
    assert (chunks[-1][1] if chunks else 1) == max(n, 1)
    sizes = [e - s for s, e in chunks]
    assert all(_MIN_CHUNK <= k <= _MAX_CHUNK for k in sizes[:-1])
    assert all(a >= b for a, b in zip(sizes, sizes[1:]))
    assert [e - s for s, e in chunk_starts(1, n, workers, 7)][:-1] == [7] * max(
        0, len(range(1, n, 7)) - 1
    )


def test_a_resume_survives_what_a_crash_leaves_and_hears_the_same_options(tmp_path, capsys):
    """An audit of batches: a chunk's temporary file left by a kill or a full disk
    (chunk_0000000003.npz.tmp4242.npz: it matched the chunk files' pattern) made every
    resume exit 70; an empty meta.json (written in place) too; and a resume with
    --preset default after no preset was refused as other options. Now the leftovers are
    removed, an unreadable meta.json with chunks is named (2), without chunks it is
    written again, and the resolved options are compared."""
    write_targets(tmp_path / "t.npz")
    out = tmp_path / "r.npz"
    argv = ["batch", str(tmp_path / "t.npz"), "--robot", "ur5e", "--frame", "ee"]
    argv += ["--out", str(out), "--chunk-size", "3", "--quiet", "--workers", "1"]
    assert main(argv + ["--max-chunks", "1"]) == 3
    chunks = tmp_path / "r.npz.chunks"
    first = chunks / "chunk_0000000000.npz"
    (chunks / "chunk_0000000003.npz.tmp4242.npz").write_bytes(first.read_bytes()[:100])
    (chunks / ".chunk_0000000003.npz.tmp4243.npz").write_bytes(first.read_bytes()[:100])
    (tmp_path / ".r.npz.tmp4244.npz").write_bytes(b"")
    assert main(argv + ["--max-chunks", "1", "--preset", "default"]) == 3
    assert sorted(p.name for p in chunks.iterdir()) == [
        "chunk_0000000000.npz",
        "chunk_0000000003.npz",
        "meta.json",
    ]
    assert not (tmp_path / ".r.npz.tmp4244.npz").exists()
    (chunks / "meta.json").write_text("")
    assert main(argv) == 2
    assert "meta.json is not readable" in capsys.readouterr().err
    assert main(argv + ["--overwrite"]) == 0
    reference = tmp_path / "ref.npz"
    assert main(argv[:6] + ["--out", str(reference), "--chunk-size", "3", "--quiet"]) == 0
    np.testing.assert_array_equal(np.load(out)["q"], np.load(reference)["q"])


def test_a_dead_worker_exits_75_with_the_resume_hint(tmp_path, monkeypatch, capsys):
    import qpik.cli.batch as batch_command

    def dies(*args, **kwargs):
        raise batch_command.WorkerError("a worker process died (killed)")

    write_targets(tmp_path / "t.npz")
    monkeypatch.setattr(batch_command, "solve_file", dies)
    argv = ["batch", str(tmp_path / "t.npz"), "--robot", "ur5e", "--frame", "ee"]
    assert main(argv + ["--out", str(tmp_path / "r.npz"), "--quiet"]) == 75
    assert "run the same command again to resume" in capsys.readouterr().err


def test_a_map_of_more_solves_than_its_cap_is_refused_before_solving():
    from qpik.batch import reachability
    from qpik.batch.reachability_map import MAX_SOLVES

    region = [[0.3, -0.1, 0.3], [0.5, 0.1, 0.5]]
    with pytest.raises(InvalidInput, match=re.escape(f"more than {MAX_SOLVES:.0e}")):
        reachability("ur5e", "ee", region=region, resolution=0.001, orientations=100_000)
