"""drop_pinned: the rows pinned on their bounds by positively dependent normals are removed
from Z (its NNLS test of each tight row, the all-at-once test with many rows, the QR of the
pinned normals with and without directions left)."""

import numpy as np

from qpik.core.kernels import drop_pinned


def _call(Z, d, lb, ub, G=None, h=None):
    n = len(d)
    G = np.zeros((0, n)) if G is None else np.asarray(G, dtype=float)
    h = np.zeros(0) if h is None else np.asarray(h, dtype=float)
    return drop_pinned(
        np.ascontiguousarray(Z, dtype=float),
        np.asarray(d, float),
        np.asarray(lb, float),
        np.asarray(ub, float),
        np.ascontiguousarray(G),
        h,
    )


def test_free_rows_leave_z_as_it_is():
    Z = np.abs(np.random.default_rng(0).standard_normal((5, 3))) + 0.1  # normals in one orthant
    d = np.zeros(5)
    out = _call(Z, d, d, d + 1.0)  # every dof on its lower bound only
    assert out.shape == Z.shape and np.array_equal(out, Z)


def test_zero_width_row_is_removed_and_its_dof_held():
    Z = np.eye(4)
    d = np.zeros(4)
    lb = np.array([0.0, 0.0, -1.0, -1.0])
    ub = np.array([0.0, 1.0, 1.0, 1.0])  # dof 0 pinned (both sides), dof 1 on one side only
    out = _call(Z, d, lb, ub)
    assert out.shape == (4, 3)
    assert np.all(out[0] == 0.0)  # the pinned dof's row made exactly 0
    np.testing.assert_allclose(out.T @ out, np.eye(3), atol=1e-14)


def test_every_direction_pinned_leaves_no_column():
    Z = np.linalg.qr(np.random.default_rng(1).standard_normal((6, 3)))[0]
    d = np.random.default_rng(2).standard_normal(6)
    out = _call(Z, d, d, d)
    assert out.shape == (6, 0)


def test_opposite_general_rows_are_pinned():
    G = np.array([[1.0, 1.0], [-2.0, -2.0]])
    d = np.array([0.3, -0.1])
    out = _call(np.eye(2), d, np.full(2, -5.0), np.full(2, 5.0), G, G @ d)
    assert out.shape == (2, 1)
    np.testing.assert_allclose(np.abs(out[:, 0]), np.full(2, np.sqrt(0.5)), atol=1e-15)
    np.testing.assert_allclose(G @ out, 0.0, atol=1e-15)


def test_many_rows_all_at_once():
    # six tight rows in the plane (t >= 1.5 r): positively spanning -> nothing can move;
    # within a half-plane -> every row is free.
    d = np.zeros(2)
    box = (np.full(2, -1.0), np.full(2, 1.0))
    ang = np.linspace(0.0, 2 * np.pi, 6, endpoint=False)
    G = np.stack([np.cos(ang), np.sin(ang)], 1)
    assert _call(np.eye(2), d, *box, G, np.zeros(6)).shape == (2, 0)
    half = np.linspace(0.1, np.pi - 0.1, 6)
    G = np.stack([np.cos(half), np.sin(half)], 1)
    out = _call(np.eye(2), d, *box, G, np.zeros(6))
    assert np.array_equal(out, np.eye(2))


def test_pinned_subset_keeps_the_free_directions():
    # two opposite general rows pin one direction of three; a third row is tight but free
    G = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 1.0]])
    d = np.zeros(3)
    out = _call(np.eye(3), d, np.full(3, -1.0), np.full(3, 1.0), G, np.zeros(3))
    assert out.shape == (3, 2)
    np.testing.assert_allclose(out[0], 0.0, atol=1e-15)
    np.testing.assert_allclose(out.T @ out, np.eye(2), atol=1e-14)


def test_seeded_cases_repeat_bit_for_bit():
    # random tight sets, some with inf / NaN / -0 entries in Z: no error, the same bits on a
    # second call (nothing carried between calls), the same shape rules
    rng = np.random.default_rng(7)
    for _ in range(300):
        n = int(rng.integers(2, 10))
        r = int(rng.integers(1, n + 1))
        Z = rng.standard_normal((n, r))
        if rng.random() < 0.2:
            Z[rng.integers(n), rng.integers(r)] = rng.choice([np.inf, -np.inf, np.nan, -0.0])
        d = rng.standard_normal(n)
        lb = d - np.where(rng.random(n) < 0.4, 0.0, 1.0)
        ub = d + np.where(rng.random(n) < 0.4, 0.0, 1.0)
        k = int(rng.integers(0, 3 * r + 2))
        G = rng.standard_normal((k, n))
        if k >= 2:
            G[-1] = -(rng.random(k - 1) @ G[:-1])
        h = G @ d
        a = _call(Z, d, lb, ub, G, h)
        b = _call(Z, d, lb, ub, G, h)
        assert a.shape == b.shape and a.shape[0] == n and a.shape[1] <= r
        assert a.tobytes() == b.tobytes()


def test_centauro_posture_moves_the_dofs_no_pin_holds():
    """tests/data/exactness/pinned_span_untouched_coordinates.npz (erd Centauro, exact mode,
    random stacks at seed 32): a frame level, a level of zero columns on dofs 19, 26 and 32,
    then a posture. Thirty rows pinned after the second level (pivots down to 1e-8) left the
    unit directions of those dofs mixed with another's by 1.3e-8, and the posture's
    certificate, its multipliers fit to that Z, proved them on their lower bounds (level
    objective 5.135e-4, 0.8 % above the independent reference's 5.093e-4). Now the posture
    brings them to its target and meets the reference's objective."""
    from pathlib import Path

    from qpik.core import HierarchyProblem, HierarchySolver, Level

    z = np.load(
        Path(__file__).parents[1] / "data" / "exactness" / "pinned_span_untouched_coordinates.npz"
    )
    levels = [Level(z[f"A{k}"], z[f"b{k}"], float(z[f"reg{k}"]), z[f"w{k}"]) for k in range(3)]
    problem = HierarchyProblem(levels, z["lb"], z["ub"], z["G"], z["h"])
    result = HierarchySolver(damping_law=None).solve(problem)
    assert result.ok and all(c.holds for c in result.certificate)
    np.testing.assert_allclose(result.x[[19, 26, 32]], 0.0, atol=1e-12)
    A, b = z["A2"] * z["w2"][:, None], z["b2"] * z["w2"]
    objective = 0.5 * float(np.sum((A @ result.x - b) ** 2))
    assert objective <= 5.0934297390725e-4 * (1 + 1e-9), objective
    # The same bits from a solver whose workspace solved other problems first (its kept
    # storage, drop_pinned's included, carries nothing but capacity) and from a fresh one.
    used = HierarchySolver(damping_law=None)
    data = Path(__file__).parents[1] / "data" / "exactness"
    for other in sorted(data.glob("hqp_*.npz"))[:4]:
        o = np.load(other)
        lv = [Level(o[f"A{k}"], o[f"b{k}"], float(o[f"reg{k}"])) for k in range(int(o["L"]))]
        used.solve(HierarchyProblem(lv, o["lb"], o["ub"], o["G"], o["h"]))
    again = used.solve(problem)
    fresh = HierarchySolver(damping_law=None).solve(problem)
    assert np.array_equal(again.x, result.x) and np.array_equal(fresh.x, result.x)


def _pinned_by_reference(normals: np.ndarray) -> list[bool]:
    """drop_pinned's test of each tight row by scipy's NNLS (no qpik code): row j is pinned
    when min |n_j + sum_i u_i n_i| over u >= 0 is within 1e-12 (1 + sum u), sum u <= 1e6."""
    from scipy.optimize import nnls

    out = []
    for j in range(len(normals)):
        others = np.delete(normals, j, axis=0).T
        u, res = nnls(others, -normals[j]) if others.shape[1] else (np.zeros(0), 1.0)
        out.append(bool(res <= 1e-12 * (1 + u.sum()) and 1 + u.sum() <= 1e6))
    return out


def test_independent_tight_rows_pin_nothing():
    # Tight rows at most as many as Z's columns, their normals independent but not in one
    # half-space (no shortcut by their sum): Z comes back bit for bit, as scipy's NNLS of
    # each row says (no row pinned).
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(1500):
        n = int(rng.integers(3, 12))
        r = int(rng.integers(2, n + 1))
        Z = np.linalg.qr(rng.standard_normal((n, r)))[0]
        d = rng.standard_normal(n)
        t = int(rng.integers(2, r + 1))
        tight = rng.choice(n, size=t, replace=False)
        lb, ub = d - 1.0, d + 1.0
        lower = rng.random(t) < 0.5
        lb[tight[lower]] = d[tight[lower]]
        ub[tight[~lower]] = d[tight[~lower]]
        sides = np.where(lower, 1.0, -1.0)[:, None]
        normals = sides * Z[tight] / np.linalg.norm(Z[tight], axis=1)[:, None]
        if np.all(normals @ normals.sum(0) > 1e-9 * np.linalg.norm(normals.sum(0))):
            continue  # (the sum's shortcut decides these)
        if np.linalg.svd(normals, compute_uv=False)[-1] < 1e-4:
            continue
        assert not any(_pinned_by_reference(normals))
        out = _call(Z, d, lb, ub)
        assert out.shape == Z.shape and out.tobytes() == Z.tobytes()
        checked += 1
    assert checked > 40


def test_nearly_opposite_rows_are_decided_by_their_residual():
    # Two tight general rows on a plane, opposite up to eps in a second coordinate: within
    # the test's 1e-12 they are pinned together (one direction left); at 1e-6 they are not
    # (their Gram matrix is too close to singular for the independence shortcut, and the
    # NNLS residual frees them); at 1e-3 the shortcut itself leaves Z as it is.
    d = np.zeros(2)
    box = (np.full(2, -1.0), np.full(2, 1.0))
    for eps, columns in ((1e-13, 1), (1e-6, 2), (1e-3, 2)):
        G = np.array([[1.0, 0.0], [-1.0, eps]])
        out = _call(np.eye(2), d, *box, G, np.zeros(2))
        normals = -G / np.linalg.norm(G, axis=1)[:, None]
        assert any(_pinned_by_reference(normals)) == (columns == 1)
        assert out.shape == (2, columns)
        if columns == 2:
            assert np.array_equal(out, np.eye(2))
