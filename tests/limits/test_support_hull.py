"""The support polygon's compiled hull (``qpik._engine.limits.support_hull``) against SciPy's
Qhull: the same edges (outward unit normals, offsets) on random point sets, every point
inside, counter-clockwise from the lowest-x point; no polygon where the points span no area;
and ``SupportPolygonLimit.hull`` raising its typed error there."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull

import qpik
from qpik._engine import limits as engine
from qpik.limits import SupportPolygonLimit


def _edges(normals: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """The edges as rows (n_x, n_y, o), sorted: a set to compare up to order."""
    rows = np.column_stack([normals, offsets])
    return rows[np.lexsort(rows.T[::-1])]


def _check_ccw(points: np.ndarray, normals: np.ndarray, offsets: np.ndarray) -> None:
    """The edges turn left, the first leaving the lowest-x point (the lowest y among
    equal x) and the last arriving there."""
    e = len(normals)
    for k in range(e):
        a, b = normals[k], normals[(k + 1) % e]
        assert a[0] * b[1] - a[1] * b[0] > 0  # the normal turns counter-clockwise
    lowest = points[np.lexsort((points[:, 1], points[:, 0]))[0]]
    assert abs(normals[0] @ lowest + offsets[0]) <= 1e-12
    assert abs(normals[-1] @ lowest + offsets[-1]) <= 1e-12
    assert normals[0][1] < 0 or (normals[0][1] == 0 and normals[0][0] > 0)  # going right


def test_random_sets_give_qhull_s_edges(rng):
    for trial in range(300):
        n = int(rng.integers(3, 40))
        points = rng.normal(size=(n, 2)) * rng.uniform(0.01, 3.0) + rng.normal(size=2)
        normals, offsets = engine.support_hull(points)
        hull = ConvexHull(points)
        ref = _edges(hull.equations[:, :2], hull.equations[:, 2])
        assert len(offsets) == len(ref), trial
        np.testing.assert_allclose(_edges(normals, offsets), ref, atol=1e-12, rtol=0)
        np.testing.assert_allclose(np.hypot(*normals.T), 1.0, atol=1e-15)
        assert (points @ normals.T + offsets).max() <= 1e-12
        _check_ccw(points, normals, offsets)


def test_two_soles_are_a_hexagon_in_order():
    # Two 0.2 x 0.1 m soles 0.2 m apart: the hull is the outer rectangle (the inner corners
    # are inside), its four edges counter-clockwise from the lowest-x, lowest-y corner.
    sole = np.array([[0.1, 0.05], [0.1, -0.05], [-0.1, 0.05], [-0.1, -0.05]])
    points = np.vstack([sole + [0.0, 0.1], sole - [0.0, 0.1]])
    normals, offsets = engine.support_hull(points)
    np.testing.assert_array_equal(normals, [[0, -1], [1, 0], [0, 1], [-1, 0]])
    np.testing.assert_allclose(offsets, [-0.15, -0.1, -0.15, -0.1], atol=1e-16, rtol=0)


def test_collinear_repeated_and_round_off_points_are_no_vertices():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    # midpoints of edges, a repeated corner, a point off an edge by round-off
    extra = np.array([[0.5, 0.0], [1.0, 0.5], [0.0, 0.0], [0.3, 1.0 + 1e-17], [0.7, -1e-16]])
    normals, offsets = engine.support_hull(np.vstack([square, extra]))
    assert len(offsets) == 4
    np.testing.assert_allclose(_edges(normals, offsets), _edges(*engine.support_hull(square)))


@pytest.mark.parametrize(
    "points",
    [
        np.zeros((0, 2)),
        np.array([[0.0, 0.0], [1.0, 1.0]]),
        np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [0.5, 0.5]]),  # collinear
        np.array([[1.0, 2.0]] * 5),  # one point
        np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 1e-13]]),  # a sliver: area 5e-14 m^2
        np.array([[0.0, 0.0], [1.0, 0.0], [0.0, np.nan]]),
        np.array([[0.0, 0.0], [1.0, 0.0], [np.inf, 1.0]]),
    ],
)
def test_no_area_gives_no_polygon(points):
    normals, offsets = engine.support_hull(points)
    assert normals.shape == (0, 2) and offsets.shape == (0,)


def test_a_line_of_nearly_equal_x_keeps_its_lowest_point():
    # x sorted by round-off along x = 0: (0, 2), (1e-155, 0), (5e-48, 1), then (1, 0). The
    # chain goes down then back up the line; (1e-155, 0) is a corner of the triangle.
    points = np.array([[0.0, 2.0], [1.0, 0.0], [4.9e-48, 1.0], [1.8e-155, 0.0]])
    normals, offsets = engine.support_hull(points)
    assert len(offsets) == 3
    assert (points @ normals.T + offsets).max() <= 1e-15
    ref = ConvexHull(points[[0, 1, 3]])
    np.testing.assert_allclose(
        _edges(normals, offsets), _edges(ref.equations[:, :2], ref.equations[:, 2]), atol=1e-15
    )


@pytest.mark.parametrize("scale", [2.0**-300, 1e-120, 1.0, 3e90, 2.0**600])
def test_the_hull_does_not_depend_on_the_unit(rng, scale):
    # The chain's tests run on the points scaled by a power of two: the same vertices at any
    # scale (no square overflowing or underflowing), normals the same, offsets scaled.
    points = rng.normal(size=(30, 2))
    normals, offsets = engine.support_hull(points)
    n2, o2 = engine.support_hull(points * scale)
    np.testing.assert_allclose(n2, normals, atol=1e-15)
    np.testing.assert_allclose(o2 / scale, offsets, rtol=1e-14, atol=1e-15)


def test_bad_shapes_raise_value_error():
    with pytest.raises(ValueError, match=r"\(n, 2\)"):
        engine.support_hull(np.zeros((4, 3)))
    with pytest.raises(TypeError):
        engine.support_hull(np.zeros(4))


@settings(max_examples=150, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(-10, 10, allow_nan=False, allow_infinity=False),
            st.floats(-10, 10, allow_nan=False, allow_infinity=False),
        ),
        min_size=3,
        max_size=24,
    )
)
def test_any_points_lie_inside_their_hull(coords):
    points = np.array(coords, dtype=float)
    normals, offsets = engine.support_hull(points)
    if not len(offsets):
        return  # no area (SciPy's Qhull would raise on most such sets)
    assert np.all(np.isfinite(normals)) and np.all(np.isfinite(offsets))
    np.testing.assert_allclose(np.hypot(*normals.T), 1.0, atol=1e-14)
    scale = 1.0 + np.abs(points).max()
    # a point dropped as turning the chain by less than 1e-10 lies at most that far out
    assert (points @ normals.T + offsets).max() <= 1e-9 * scale
    # each edge touches the set: its line passes through a point
    assert np.abs(points @ normals.T + offsets).min(axis=0).max() <= 1e-12 * scale


def test_the_limit_raises_its_typed_error_without_area():
    xml = """<mujoco><worldbody><body name="b"><freejoint/><geom size="0.1"/>
      <site name="s1" pos="0 0 0"/><site name="s2" pos="0.1 0 0"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    limit = SupportPolygonLimit(model, ["s1", "s2"])
    with pytest.raises(qpik.InvalidInput, match="span no area"):
        limit.hull(qpik.Configuration(model))


def test_points_and_rows_are_the_formulas_in_numpy(rng):
    # Frames of every kind (a body, a site, a geom): the engine's ground points, hull and rows
    # against the same formulas in NumPy.
    xml = """<mujoco><worldbody><body name="b" pos="0 0 1"><freejoint/>
      <geom name="g" type="box" size="0.1 0.05 0.02" pos="0.3 0 -1"/>
      <site name="s" pos="-0.3 0.2 -1"/>
      <body name="arm"><joint name="j" axis="0 1 0"/><geom size="0.05" pos="0.5 0 0"/></body>
    </body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    limit = SupportPolygonLimit(
        model, ["b", "s", "g"], margin=0.01, footprint=[[0.05, 0.02], [-0.05, 0.02], [0.0, -0.03]]
    )
    configuration = qpik.Configuration(model)
    for _ in range(5):
        q = configuration.q.copy()
        q[:3] += rng.normal(size=3) * 0.05
        q[3:7] = rng.normal(size=4) * 0.1 + [1.0, 0.0, 0.0, 0.0]
        q[3:7] /= np.linalg.norm(q[3:7])
        q[7] = rng.uniform(-1.0, 1.0)
        configuration.update(q)
        data = configuration.data
        placed = [(data.xpos[1], data.xmat[1]), (data.site_xpos[0], data.site_xmat[0]),
                  (data.geom_xpos[0], data.geom_xmat[0])]  # fmt: skip
        numpy_points = np.vstack(
            [(x + f @ R.reshape(3, 3).T)[:, :2] for (x, R), f in zip(placed, limit.footprints)]
        )
        np.testing.assert_allclose(limit.support_points(configuration), numpy_points, atol=1e-15)
        normals, offsets = limit.hull(configuration)
        G, h, fewest = limit.rows_in_play(configuration, 0.01)
        jac = np.empty((3, model.nv))
        mujoco.mj_jacSubtreeCom(model, data, jac, 1)
        np.testing.assert_allclose(G, normals @ jac[:2], atol=1e-15)
        com = data.subtree_com[1, :2]
        np.testing.assert_allclose(h, 0.95 * (-0.01 - offsets - normals @ com), atol=1e-15)
        assert fewest == np.count_nonzero(G, axis=1).min()
        rows = limit.compute_qp_inequalities(configuration, 0.01)
        assert rows.G.tobytes() == G.tobytes() and rows.h.tobytes() == h.tobytes()


def test_the_engine_s_support_calls_check_their_arrays():
    positions, rotations = np.zeros((2, 3)), np.tile(np.eye(3).ravel(), (2, 1))
    square = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    with pytest.raises(ValueError, match="one footprint a frame"):
        engine.support_points(positions, rotations, [square])
    with pytest.raises(ValueError, match=r"\(F, 9\)"):
        engine.support_points(positions, rotations[:, :4], [square, square])
    with pytest.raises(ValueError, match=r"\(k, 3\)"):
        engine.support_points(positions, rotations, [square, square[:, :2]])
    with pytest.raises(ValueError, match="jac"):
        engine.support_rows(positions, rotations, [square, square], np.zeros((1, 4)), 0, 0, 0, 1)
    G, h, fewest = engine.support_rows(
        positions, rotations, [square, square[:1]], np.ones((3, 4)), 0.5, 0.5, 0.0, 1.0
    )
    assert G.shape == (4, 4) and h.shape == (4,) and fewest == 4


def test_footprints_changed_to_a_bad_shape_raise_a_typed_error():
    xml = """<mujoco><worldbody><body name="b"><freejoint/><geom size="0.1"/>
      <site name="s1" pos="0 0 0"/><site name="s2" pos="0.3 0 0"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    limit = SupportPolygonLimit(model, ["s1", "s2"], footprint=[[0.1, 0.1], [0.1, -0.1]])
    configuration = qpik.Configuration(model)
    assert len(limit.hull(configuration)[0]) == 4
    for bad in (
        [np.zeros((2, 2)), np.zeros((2, 3))],
        [np.zeros((2, 3))],
        [np.full((2, 3), np.nan)] * 2,
    ):
        limit.footprints = bad
        with pytest.raises(qpik.LimitDefinitionError, match="footprints"):
            limit.hull(configuration)


def test_a_com_on_the_shrunk_edge_makes_no_negative_round_off_bound():
    """Audit (limits): with the CoM exactly on the margin's edge, a support row's bound is 0,
    and its round-off (-2.6e-17 m) made the start infeasible by that much: 277 of 300 steps
    of a humanoid pushing its CoM outward ended numerical_failure with a zero step. A bound
    within round-off of 0 is 0 now (support_rows), on the compiled step and here alike."""
    import warnings

    import qpik
    from qpik.limits import SupportPolygonLimit

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        talos = qpik.load_robot("erd:talos", floating_base=True)
    feet = ["left_sole_link", "right_sole_link"]
    configuration = qpik.Configuration(talos, talos.key("half_sitting").qpos)
    _, h0, _ = SupportPolygonLimit(talos, feet, margin=0.0).rows_in_play(configuration, 0.01)
    edge = float(h0.min()) / SupportPolygonLimit(talos, feet).gain
    negatives = 0
    for k in range(-8, 9):  # margins a few ulps around the CoM's distance to the edge
        margin = edge * (1.0 + k * 2.220446049250313e-16)
        _, h, _ = SupportPolygonLimit(talos, feet, margin=margin).rows_in_play(configuration, 0.01)
        negatives += int((h < 0).sum())
        assert h.min() >= 0.0 or h.min() < -1e-12  # never a round-off negative bound
    assert negatives < 17 * len(h0)  # (margins past the edge do cut it by more)


def test_a_ball_on_its_range_makes_no_negative_round_off_bound():
    """The same for a ball joint on its range: its start sits on a vertex of the polytope,
    whose faces' bounds are 0; their round-off (-1e-16 rad) made 297 of 300 steps end
    numerical_failure. Within round-off of 0 they are 0 now (ball_rows)."""
    from qpik.limits.ball import ball_rows

    rng = np.random.default_rng(4)
    for _ in range(200):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        rho = rng.uniform(0.2, 3.0)
        _, bounds = ball_rows(axis * rho, rho, int(rng.integers(0, 3)))
        assert bounds.min() >= 0.0 or bounds.min() < -1e-12


def test_points_inside_leave_the_hull_bitwise_as_it_was(rng):
    # The engine leaves out, before its sort, the points well inside the octagon of the
    # extreme points (the inner sides of two mesh soles): the hull is the one of the points
    # without them, bit for bit, and Qhull's edges.
    for trial in range(200):
        k = int(rng.integers(20, 160))
        t = np.sort(rng.uniform(0.0, 2.0 * np.pi, k))
        sole = np.column_stack(
            [0.11 * np.sign(np.cos(t)) * np.abs(np.cos(t)) ** 0.2,
             0.06 * np.sign(np.sin(t)) * np.abs(np.sin(t)) ** 0.2]
        )  # fmt: skip
        yaw = rng.uniform(-0.4, 0.4)
        turn = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
        far = rng.normal(size=2) * [1.0, 1e3][trial % 2]  # (far from 0: differences first)
        points = np.vstack([sole + [0.0, 0.1], sole @ turn.T + [rng.uniform(-0.1, 0.1), -0.1]])
        points = np.vstack([points, rng.uniform(-0.05, 0.05, size=(k, 2))]) + far
        normals, offsets = engine.support_hull(points)
        rim = points[np.sort(ConvexHull(points).vertices)]
        rim_normals, rim_offsets = engine.support_hull(rim)
        np.testing.assert_array_equal(normals, rim_normals)
        np.testing.assert_array_equal(offsets, rim_offsets)
        assert (points @ normals.T + offsets).max() <= 1e-9 * (1.0 + np.abs(far).max())


def test_support_rows_make_negligible_rows_zero_as_the_step_s_rule(rng):
    # The engine flushes the polygon's rows whose entries are all at most NEGLIGIBLE_ROW
    # (a CoM the joints barely move), as qpik.diffik.boxes does for every other limit's rows;
    # the fewest nonzero entries are counted after it.
    from qpik.limits.collision import NEGLIGIBLE_ROW

    sole = np.array([[0.1, 0.05, 0.0], [0.1, -0.05, 0.0], [-0.1, 0.05, 0.0], [-0.1, -0.05, 0.0]])
    positions = np.array([[0.0, 0.1, 0.0], [0.0, -0.1, 0.0]])
    rotations = np.tile(np.eye(3).ravel(), (2, 1))
    for scale in (1.0, 1e-13, 1e-20, np.nan):
        jac = rng.normal(size=(3, 9)) * (1e-13 if np.isnan(scale) else scale)
        jac[:, 0] = 0.0
        jac[0, 1] = scale if np.isnan(scale) else jac[0, 1]  # (a NaN row is not negligible)
        raw, h_raw, _ = engine.support_rows(
            positions, rotations, [sole, sole], jac, 0.0, 0.0, 0.01, 0.9
        )
        G, h, fewest = engine.support_rows(
            positions, rotations, [sole, sole], jac, 0.0, 0.0, 0.01, 0.9, NEGLIGIBLE_ROW
        )
        largest = np.abs(raw).max(axis=1)
        expected = raw.copy()
        expected[(largest <= NEGLIGIBLE_ROW) & (largest > 0.0)] = 0.0
        np.testing.assert_array_equal(G, expected)
        np.testing.assert_array_equal(h, h_raw)
        assert fewest == np.count_nonzero(expected, axis=1).min()
        assert (fewest == 0) == (scale < 1e-12)  # (False for NaN)
