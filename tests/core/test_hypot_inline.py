"""The dual method's inline hypot (qpik/_cpp/core/qp.hpp, hypot_inline: glibc's algorithm where
no step leaves the normal range, the library call elsewhere) against the C library's own
``hypot`` (NumPy's ``np.hypot``), bit for bit: over the whole exponent range, near the 2^+-450
switch points, at close and far ratios, signed zeros, subnormals, infinities and NaN."""

from __future__ import annotations

import numpy as np

from qpik.core import kernels as K


def _inline(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    out = np.empty_like(x)
    K.hypot_inline(np.ascontiguousarray(x), np.ascontiguousarray(y), out)
    return out


def _library(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    with np.errstate(all="ignore"):  # (overflow to inf is the answer there)
        return np.hypot(x, y)


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    nan = np.isnan(a) & np.isnan(b)  # (NaN: any payload; the library's own there)
    return bool(np.array_equal(a.view(np.int64)[~nan], b.view(np.int64)[~nan]))


def test_random_pairs_over_the_exponent_range() -> None:
    rng = np.random.default_rng(20261203)
    n = 400_000
    x = rng.uniform(1.0, 2.0, n) * np.exp2(rng.integers(-1074, 1023, n).astype(float))
    y = rng.uniform(1.0, 2.0, n) * np.exp2(rng.integers(-1074, 1023, n).astype(float))
    x *= rng.choice([-1.0, 1.0], n)
    y *= rng.choice([-1.0, 1.0], n)
    assert _same_bits(_inline(x, y), _library(x, y))


def test_close_magnitudes_where_the_correction_decides() -> None:
    rng = np.random.default_rng(7)
    n = 400_000
    x = rng.standard_normal(n) * np.exp2(rng.integers(-60, 60, n).astype(float))
    y = x * rng.uniform(-4.0, 4.0, n)  # ratios where h <= 2 ay and where not
    assert _same_bits(_inline(x, y), _library(x, y))
    z = x * (1.0 + rng.uniform(-1e-8, 1e-8, n))  # nearly equal
    assert _same_bits(_inline(x, z), _library(x, z))


def test_switch_points_and_special_values() -> None:
    edges = []
    for e in (-450, 450, -54, 54, -511, 511, -1022, 1023):
        p = np.exp2(float(e))
        edges += [np.nextafter(p, 0.0), p, np.nextafter(p, np.inf)]
    special = [0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 1.0, 3.0, 1e308,
               np.finfo(float).max, np.inf, -np.inf, np.nan]  # fmt: skip
    values = np.array(edges + special + [1.0 + 2.0**-52, 0.75])
    x, y = np.meshgrid(values, values)
    x, y = x.ravel().copy(), y.ravel().copy()
    assert _same_bits(_inline(x, y), _library(x, y))
    assert _same_bits(_inline(y, x), _library(y, x))
