"""Reachability maps: the SO(3) grid, the reach bound against MuJoCo's forward kinematics,
a planar map against the closed form, determinism, files, figures, the CLI."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import qpik
from qpik.batch.reachability_map import ReachabilityMap, _reach_bounds, reach_bound, so3_grid
from qpik.cli import main


def geodesic(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation angles [rad] between every rotation of ``a`` and every one of ``b``."""
    cosines = (np.einsum("aij,bij->ab", a, b) - 1.0) / 2.0
    return np.arccos(np.clip(cosines, -1.0, 1.0))


def test_so3_grid_is_rotations_spread_more_evenly_than_random():
    grid = so3_grid(64)
    assert grid.shape == (64, 3, 3)
    np.testing.assert_allclose(
        np.einsum("kji,kjl->kil", grid, grid), np.tile(np.eye(3), (64, 1, 1)), atol=1e-12
    )
    np.testing.assert_allclose(np.linalg.det(grid), 1.0, atol=1e-12)
    random = Rotation.random(64, random_state=0).as_matrix()
    probes = Rotation.random(4000, random_state=1).as_matrix()
    # Uniform on SO(3): the mean rotation matrix vanishes.
    assert np.abs(grid.mean(axis=0)).max() < 0.05

    # Separation (smallest pairwise angle) and covering (largest distance of a probe to the
    # set) both beat an i.i.d. uniform sample of the same size.
    def separation(r):
        d = geodesic(r, r)
        return d[~np.eye(len(r), dtype=bool)].min()

    assert separation(grid) > 2.0 * separation(random)
    assert geodesic(probes, grid).min(axis=1).max() < geodesic(probes, random).min(axis=1).max()
    np.testing.assert_array_equal(so3_grid(64), grid)  # deterministic
    with pytest.raises(qpik.InvalidInput, match="orientations"):
        so3_grid(0)


@pytest.mark.parametrize("robot", ["ur5e", "panda", "planar_2r"])
def test_reach_bounds_hold_for_sampled_configurations(robot):
    model = qpik.load_robot(robot)
    bounds = _reach_bounds(model, "ee")  # ours (first) and the IK engine's
    assert len(bounds) == 2
    np.testing.assert_array_equal(bounds[0][0], reach_bound(robot, "ee")[0])
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(0)
    points = []
    for _ in range(2000):
        configuration.update(configuration.random_q(rng))
        points.append(configuration.frame_pose("ee")[0])
    for center, radius in bounds:
        distances = np.linalg.norm(np.array(points) - center, axis=1)
        assert distances.max() <= radius + 1e-9
        assert distances.max() > 0.8 * radius  # and it is not vacuous


def test_reach_bound_closed_forms():
    center, radius = reach_bound("planar_2r", "ee")  # two unit links from the origin
    np.testing.assert_allclose(center, 0.0, atol=1e-12)
    assert radius == pytest.approx(2.0)
    xml = """
    <mujoco><worldbody><body pos="0 0 0.5">
      <joint name="lift" type="slide" axis="0 0 1" range="-0.1 0.3"/><geom size="0.05"/>
      <body pos="0 0 0.2"><joint name="yaw" type="hinge" axis="0 0 1"/>
        <geom size="0.05"/><site name="tip" pos="0.4 0 0"/></body>
    </body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    center, radius = reach_bound(model, "tip")
    np.testing.assert_allclose(center, [0, 0, 0.5])
    # travel 0.3 + anchor to anchor 0.2 + hinge anchor to tip 0.4
    assert radius == pytest.approx(0.9)
    free = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><freejoint/><geom size='0.1'/><site name='s'/></body>"
        "</worldbody></mujoco>"
    )
    assert reach_bound(free, "s")[1] == math.inf


def test_planar_map_matches_the_closed_form():
    # Two unit links: a point of the plane is reachable iff its distance to the base is <= 2.
    region = [[-2.5, -2.5, 0.0], [2.5, 2.5, 0.0]]
    rmap = qpik.reachability(
        "planar_2r", "ee", region=region, resolution=0.5, orientations=0, workers=1, progress=False
    )
    assert rmap.shape == (10, 10, 1) and rmap.centers.shape == (100, 3)
    assert rmap.fraction.shape == (100,)
    np.testing.assert_allclose(rmap.centers[:, 2], 0.0)
    radius = np.linalg.norm(rmap.centers, axis=1)
    inside, outside = radius < 2.0 - 1e-3, radius > 2.0 + 1e-3
    assert rmap.fraction[inside].min() == 1.0
    assert rmap.fraction[outside].max() == 0.0
    assert rmap.skipped[outside].all() and not rmap.skipped[inside].any()
    assert rmap.solves == int((~rmap.skipped).sum())
    assert rmap.grid.shape == (10, 10, 1)


def test_orientation_map_is_deterministic_and_round_trips(tmp_path):
    pytest.importorskip("matplotlib")
    options = dict(
        region=[[0.2, -0.2, 0.3], [0.6, 0.2, 0.5]],
        resolution=0.2,
        orientations=3,
        restarts=2,
        progress=False,
    )
    serial = qpik.reachability("ur5e", "ee", workers=1, **options)
    pooled = qpik.reachability("ur5e", "ee", workers=2, **options)
    assert serial.reached.shape == (len(serial.centers), 3)
    np.testing.assert_array_equal(serial.reached, pooled.reached)
    np.testing.assert_allclose(serial.fraction * 3, np.round(serial.fraction * 3))
    assert serial.fraction.max() > 0  # this box is well inside the ur5e's workspace
    # Each entry is a solve of (centre, rotation) with the batch's seed for its index.
    from qpik.batch.worker import target_seed

    first = qpik.solve(
        "ur5e",
        {"ee": (serial.centers[0], serial.orientations[1])},
        restarts=2,
        seed=target_seed(0, 1),
    )
    assert first.converged == serial.reached[0, 1]
    serial.save(tmp_path / "m.npz")
    loaded = ReachabilityMap.load(tmp_path / "m.npz")
    np.testing.assert_array_equal(loaded.fraction, serial.fraction)
    np.testing.assert_array_equal(loaded.orientations, serial.orientations)
    assert (loaded.shape, loaded.frame, loaded.reach) == (serial.shape, "ee", serial.reach)
    assert loaded.engines == serial.engines == {"compiled": serial.solves}
    loaded.plot(tmp_path / "m.png")
    assert (tmp_path / "m.png").stat().st_size > 10_000


def test_given_rotations_and_bad_inputs():
    rotations = np.stack([np.eye(3), np.diag([1.0, -1.0, -1.0])])
    rmap = qpik.reachability(
        "ur5e",
        "ee",
        region=[[0.4, 0.1, 0.3]] * 2,
        resolution=0.1,
        orientations=rotations,
        workers=1,
        progress=False,
    )
    assert rmap.shape == (1, 1, 1) and rmap.reached.shape == (1, 2)
    good = dict(region=[[0, 0, 0], [1, 1, 1]], resolution=0.5, orientations=2, progress=False)
    with pytest.raises(qpik.InvalidInput, match="region"):
        qpik.reachability("ur5e", "ee", **{**good, "region": [0, 0, 1]})
    with pytest.raises(qpik.InvalidInput, match="resolution"):
        qpik.reachability("ur5e", "ee", **{**good, "resolution": 0.0})
    with pytest.raises(qpik.InvalidInput, match=r"orientations\[0\]"):
        qpik.reachability("ur5e", "ee", **{**good, "orientations": 2 * np.eye(3)[None]})
    with pytest.raises(qpik.InvalidInput, match="orientations"):
        qpik.reachability("ur5e", "ee", **{**good, "orientations": np.zeros((2, 4))})
    with pytest.raises(qpik.UnknownFrame, match="gripper"):
        qpik.reachability("ur5e", "gripper", **good)
    with pytest.raises(qpik.InvalidInput, match="coarser"):
        qpik.reachability("ur5e", "ee", **{**good, "resolution": 1e-4})


def test_reachmap_cli_saves_map_and_figure(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    out, png = tmp_path / "map.npz", tmp_path / "map.png"
    argv = ["reachmap", "planar_2r", "--frame", "ee", "--region", "-2.2", "-2.2", "0"]
    argv += ["2.2", "2.2", "0", "--resolution", "0.55", "--orientations", "0", "--workers", "1"]
    assert main(argv + ["--out", str(out), "--plot", str(png)]) == 0
    assert "voxels" in capsys.readouterr().out
    with np.load(out) as data:
        assert data["centers"].shape == (64, 3) and data["fraction"].shape == (64,)
    assert png.stat().st_size > 10_000
    assert (
        main(
            argv[:4]
            + ["--region", "0", "0", "0", "1", "1", "1", "--resolution", "-1", "--out", str(out)]
        )
        == 2
    )
    assert "resolution" in capsys.readouterr().err


def test_a_free_cube_in_the_scene_keeps_the_compiled_map():
    """Panda + a free cube (issue 22): the map takes the same per-frame chain check as
    qpik.solve, so every solve goes to the compiled engine, the engine's reach bound is
    kept, and the map is the bare arm's."""
    panda = qpik.load_robot("panda")
    spec = mujoco.MjSpec.from_file(str(_panda_path()))
    cube = spec.worldbody.add_body(name="cube", pos=[0.5, 0.2, 0.03])
    cube.add_freejoint(name="cube_free")
    cube.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.02] * 3, mass=0.1)
    scene = spec.compile()
    assert len(_reach_bounds(scene, "ee")) == len(_reach_bounds(panda, "ee")) == 2
    options = dict(
        region=[[-0.9, -0.9, -0.3], [0.9, 0.9, 1.2]],
        resolution=0.3,
        orientations=2,
        workers=1,
        seed=0,
        progress=False,
    )
    bare = qpik.reachability(panda, "ee", **options)
    with_cube = qpik.reachability(scene, "ee", **options)
    assert with_cube.engines == {"compiled": with_cube.solves} and with_cube.solves > 0
    np.testing.assert_array_equal(with_cube.skipped, bare.skipped)
    np.testing.assert_array_equal(with_cube.reached, bare.reached)


def _panda_path():
    from qpik.model.robots import locate_robot

    return locate_robot("panda")
