"""The engine's own sin, cos and atan2 (qpik/_cpp/detmath.hpp, bound as
qpik._engine.model.sincos / atan2): its constants against their values recomputed here by
integer arithmetic, its accuracy against exact references (integer and rational arithmetic,
no floating-point library), C99's special values, and the reason it exists: the engine's
recorded answers stay bitwise the same in a process where glibc takes its plain (no FMA,
no AVX2) builds of its functions, which round some arguments differently."""

from __future__ import annotations

import math
import os
import platform
import re
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from qpik._engine import model as engine

ROOT = Path(__file__).resolve().parents[2]
HEADER = ROOT / "qpik" / "_cpp" / "detmath.hpp"
# glibc's tunable that hides the CPU's FMA and AVX2 from its function selection (the
# names of glibc 2.26 - 2.32 and of 2.33 on; a name glibc does not know is ignored).
PLAIN_LIBM = "glibc.cpu.hwcaps=-AVX2_Usable,-FMA_Usable,-AVX2,-FMA"

# ------------------------------------------------------------------ exact references
PI_BITS = 1400


def _atan_inv(n: int, bits: int) -> int:
    """atan(1/n) 2^bits, truncated (its alternating series in integers)."""
    one = 1 << (bits + 20)
    total, term, k, sign = 0, one // n, 1, 1
    while term:
        total += sign * (term // k)
        term //= n * n
        k += 2
        sign = -sign
    return total >> 20


#: pi to about 1400 bits (Machin: 16 atan(1/5) - 4 atan(1/239)).
PI = Fraction(
    (16 * _atan_inv(5, PI_BITS + 10) - 4 * _atan_inv(239, PI_BITS + 10)) >> 10, 1 << PI_BITS
)


def _sincos_small(r: Fraction) -> tuple[Fraction, Fraction]:
    """sin r and cos r for |r| <= 1, to 2^-320 relative to |r| (Taylor series in fixed
    point scaled to r's size)."""
    if r == 0:
        return Fraction(0), Fraction(1)
    bits = 320 + max(0, -math.floor(math.log2(abs(r))))
    one = 1 << bits
    x = (r.numerator << bits) // r.denominator
    s = c = 0
    term, n = x, 1
    while term:
        s += term if (n // 2) % 2 == 0 else -term
        term = term * x // one * x // one // ((n + 1) * (n + 2))
        n += 2
    term, n = one, 0
    while term:
        c += term if (n // 2) % 2 == 0 else -term
        term = term * x // one * x // one // ((n + 1) * (n + 2))
        n += 2
    return Fraction(s, one), Fraction(c, one)


def exact_sincos(x: float) -> tuple[Fraction, Fraction]:
    """sin x and cos x of the double x, to far below its ulp (x reduced by a multiple of
    pi/2 with 1400 bits of pi)."""
    pio2 = PI / 2
    k = round(Fraction(x) / pio2)
    s, c = _sincos_small(Fraction(x) - k * pio2)
    return [(s, c), (c, -s), (-s, -c), (-c, s)][k % 4]


def _atan01(t: Fraction, bits: int = 320) -> Fraction:
    """atan t for 0 <= t <= 1 (Euler's series, ratio t^2 / (1 + t^2) <= 1/2)."""
    one = 1 << bits
    y = t * t / (1 + t * t)
    y_fixed = (y.numerator << bits) // y.denominator
    first = t / (1 + t * t)
    term = (first.numerator << bits) // first.denominator
    total, n = 0, 0
    while term:
        total += term
        n += 1
        term = term * y_fixed // one * (2 * n) // (2 * n + 1)
    return Fraction(total, one)


def exact_atan2(y: float, x: float) -> Fraction:
    """atan2(y, x) of finite doubles, not both zero."""
    ax, ay = abs(Fraction(x)), abs(Fraction(y))
    if ay <= ax:
        a = _atan01(ay / ax)
        a = a if x > 0 else PI - a
    else:
        a = _atan01(ax / ay)
        a = PI / 2 - a if x > 0 else PI / 2 + a
    return a if math.copysign(1.0, y) > 0 else -a


def ulps(got: float, exact: Fraction) -> float:
    """|got - exact| in ulps of the exact value's double."""
    return float(abs(Fraction(got) - exact) / Fraction(math.ulp(float(exact))))


def _sincos(x) -> tuple[np.ndarray, np.ndarray]:
    x = np.ascontiguousarray(x, dtype=float)
    s, c = np.empty_like(x), np.empty_like(x)
    engine.sincos(x, s, c)
    return s, c


def _atan2(y, x) -> np.ndarray:
    y, x = np.ascontiguousarray(y, dtype=float), np.ascontiguousarray(x, dtype=float)
    out = np.empty_like(y)
    engine.atan2(y, x, out)
    return out


# ------------------------------------------------------------------------- constants
def _header_doubles(name: str) -> list[float]:
    """The hex-float literals of constant ``name`` in detmath.hpp (a scalar or an array)."""
    text = HEADER.read_text()
    match = re.search(rf"constexpr (?:double|std::uint64_t) {name}(?:\[\d+\])? = ([^;]*);", text)
    assert match, name
    body = match.group(1)
    if "ULL" in body:
        return [int(w, 16) for w in re.findall(r"0x[0-9a-f]+(?=ULL)", body)]
    return [float.fromhex(v) if v.lstrip("-").startswith("0x") else float(v)
            for v in re.findall(r"-?0x[0-9a-f.]+p[-+]?\d+|-?\d+\.\d+", body)]  # fmt: skip


def _rounded(value: Fraction, bits: int) -> float:
    """value rounded to ``bits`` significant bits (nearest), exactly as a double."""
    e = math.floor(math.log2(abs(value)))
    while Fraction(2) ** e > abs(value):
        e -= 1
    while Fraction(2) ** (e + 1) <= abs(value):
        e += 1
    scale = Fraction(2) ** (bits - 1 - e)
    return float(Fraction(round(value * scale)) / scale)


def test_constants_are_their_exact_values_rounded():
    """Every constant of detmath.hpp, recomputed from pi by integer arithmetic."""
    pio2 = PI / 2
    p1 = _rounded(pio2, 33)
    p2 = _rounded(pio2 - Fraction(p1), 33)
    p3 = _rounded(pio2 - Fraction(p1) - Fraction(p2), 53)
    assert _header_doubles("kP1") == [p1]
    assert _header_doubles("kP2") == [p2]
    assert _header_doubles("kP3") == [p3]
    assert _header_doubles("kInvPio2") == [float(2 / PI)]
    for name, value in (("kPio2", pio2), ("kPi", PI)):
        hi = float(value)
        assert _header_doubles(name + "Hi") == [hi]
        assert _header_doubles(name + "Lo") == [float(value - Fraction(hi))]
    bits = ((2 / PI).numerator << 1216) // (2 / PI).denominator
    words = [(bits >> (1216 - 64 * (i + 1))) & ((1 << 64) - 1) for i in range(19)]
    assert _header_doubles("kTwoOverPi") == words
    assert _header_doubles("kS") == [
        float(Fraction((-1) ** n, math.factorial(2 * n + 1))) for n in range(1, 9)
    ]
    assert _header_doubles("kC") == [
        float(Fraction((-1) ** n, math.factorial(2 * n))) for n in range(2, 9)
    ]
    assert _header_doubles("kA") == [float(Fraction((-1) ** n, 2 * n + 1)) for n in range(1, 7)]
    atan = [_atan01(Fraction(k, 16)) for k in range(17)]
    assert _header_doubles("kAtanHi") == [float(a) for a in atan]
    assert _header_doubles("kAtanLo") == [float(a - Fraction(float(a))) for a in atan]


# -------------------------------------------------------------------------- accuracy
def _hard_arguments() -> list[float]:
    """Arguments near multiples of pi/2 (a few ulps either side), at the ends of the
    reductions, and the double nearest a multiple of pi/2 (Kahan and McDonald's
    6381956970095103 2^797, within 2^-61 of one)."""
    near = []
    for k in [*range(-30, 31), 1000, 2**18, 2**19 - 1, 2**19 + 1, 2**40, 2**60]:
        base = k * math.pi / 2
        near += [base + d * math.ulp(base) for d in range(-2, 3)]
    edges = [float.fromhex("0x1.921fb544p+19") * f for f in (1 - 2**-52, 1.0, 1 + 2**-52)]
    worst = 6381956970095103 * 2.0**797
    return near + edges + [worst, -worst, math.pi / 4, -math.pi / 4, 2.0**-27, 2.0**-30,
                           5e-324, 1e-300, 1e300, sys.float_info.max, -sys.float_info.max]  # fmt: skip


def test_sin_and_cos_are_within_an_ulp():
    """sin and cos within 1 ulp of the exact values (about 0.75 at most seen) on random
    angles of every size, hard arguments included."""
    rng = np.random.default_rng(0)
    xs = list(rng.uniform(-7.0, 7.0, 300))
    xs += list(rng.uniform(-1.0, 1.0, 300) * 10.0 ** rng.uniform(-12, 308, 300))
    xs += _hard_arguments()
    s, c = _sincos(xs)
    worst = 0.0
    for x, si, ci in zip(xs, s, c):
        exact_s, exact_c = exact_sincos(x)
        worst = max(worst, ulps(si, exact_s), ulps(ci, exact_c))
    assert worst <= 1.0, worst


def test_atan2_is_within_an_ulp():
    """atan2 within 1 ulp (about 0.85 at most seen) in every quadrant, over magnitudes
    1e-5 - 1e5 and near the diagonals."""
    rng = np.random.default_rng(1)
    y = rng.uniform(-3.0, 3.0, 400) * 10.0 ** rng.uniform(-5, 5, 400)
    x = rng.uniform(-3.0, 3.0, 400) * 10.0 ** rng.uniform(-5, 5, 400)
    d = rng.uniform(0.5, 2.0, 100)
    y = np.concatenate([y, d, -d, d * (1 + 1e-9)])
    x = np.concatenate([x, d * (1 + 2**-50), -d, -d])
    got = _atan2(y, x)
    worst = max(ulps(g, exact_atan2(a, b)) for g, a, b in zip(got, y, x))
    assert worst <= 1.0, worst


def test_special_values():
    """C99's values at zeros, infinities and NaN; sin keeps the sign of zero."""
    s, c = _sincos([0.0, -0.0, math.inf, -math.inf, math.nan])
    assert s[0] == 0.0 and not math.copysign(1, s[0]) < 0 and c[0] == 1.0
    assert s[1] == 0.0 and math.copysign(1, s[1]) < 0 and c[1] == 1.0
    assert np.isnan(s[2:]).all() and np.isnan(c[2:]).all()
    pi, half, quarter = math.pi, math.pi / 2, math.pi / 4
    inf = math.inf
    cases = [
        (0.0, 1.0, 0.0), (-0.0, 1.0, -0.0), (0.0, -1.0, pi), (-0.0, -1.0, -pi),
        (0.0, 0.0, 0.0), (-0.0, 0.0, -0.0), (0.0, -0.0, pi), (-0.0, -0.0, -pi),
        (1.0, 0.0, half), (-1.0, -0.0, -half), (inf, inf, quarter), (-inf, inf, -quarter),
        (inf, -inf, 3 * quarter), (-inf, -inf, -3 * quarter), (1.0, inf, 0.0), (-1.0, inf, -0.0),
        (1.0, -inf, pi), (-1.0, -inf, -pi), (inf, 1.0, half), (-inf, -5.0, -half),
    ]  # fmt: skip
    got = _atan2([c[0] for c in cases], [c[1] for c in cases])
    for (y, x, expected), value in zip(cases, got):
        assert value == expected and math.copysign(1, value) == math.copysign(1, expected), (y, x)
    assert np.isnan(_atan2([math.nan, 1.0], [1.0, math.nan])).all()


def test_symmetries_and_bounds():
    """sin is odd and cos even bit for bit (the reductions are symmetric), both within
    [-1, 1]; atan2 is odd in y and within [-pi, pi]."""
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.uniform(-10.0, 10.0, 50000),
                        rng.uniform(-1.0, 1.0, 20000) * 10.0 ** rng.uniform(-300, 308, 20000)])  # fmt: skip
    s, c = _sincos(x)
    s_neg, c_neg = _sincos(-x)
    assert np.array_equal(s, -s_neg) and np.array_equal(c, c_neg)
    assert (np.abs(s) <= 1.0).all() and (np.abs(c) <= 1.0).all()
    assert np.abs(s * s + c * c - 1.0).max() <= 4 * np.finfo(float).eps
    y = rng.normal(size=50000) * 10.0 ** rng.uniform(-5, 5, 50000)
    a = _atan2(y, x[:50000])
    assert np.array_equal(a, -_atan2(-y, x[:50000]))
    assert (np.abs(a) <= math.pi).all()


def test_agrees_with_the_c_library_to_an_ulp():
    """Beside glibc's (or the platform's) functions: never more than one ulp apart."""
    rng = np.random.default_rng(2)
    x = rng.uniform(-20.0, 20.0, 20000)
    s, c = _sincos(x)
    theirs_s = np.array([math.sin(v) for v in x])
    theirs_c = np.array([math.cos(v) for v in x])
    assert (np.abs(s - theirs_s) <= np.spacing(np.abs(theirs_s))).all()
    assert (np.abs(c - theirs_c) <= np.spacing(np.abs(theirs_c))).all()
    y = rng.normal(size=20000)
    a = _atan2(y, x)
    theirs = np.array([math.atan2(u, v) for u, v in zip(y, x)])
    assert (np.abs(a - theirs) <= np.spacing(np.abs(theirs))).all()


# ----------------------------------------------------------------------- determinism
def _glibc_takes_tunables() -> bool:
    return platform.system() == "Linux" and platform.libc_ver()[0] == "glibc"


_LIBM_DIGEST = (
    "import hashlib, math, random; r = random.Random(7); h = hashlib.sha256(); "
    "[h.update(math.sin(r.uniform(-9, 9)).hex().encode()) for _ in range(200000)]; "
    "print(h.hexdigest())"
)


@pytest.mark.skipif(not _glibc_takes_tunables(), reason="glibc's tunables select its builds")
def test_engine_answers_are_the_same_with_the_plain_c_library():
    """The recorded-answer tests of the engine (its chain kinematics, IGM, Lie groups and
    fused step; tests/fixtures) pass bit for bit in a process where glibc runs its plain
    builds of sin, cos and atan2, which round about 0.05 % of arguments differently from
    its FMA builds (checked first: where the two agree, the CPU has no FMA and there is
    nothing to show)."""
    env = {**os.environ, "GLIBC_TUNABLES": PLAIN_LIBM}
    here = subprocess.run(
        [sys.executable, "-c", _LIBM_DIGEST], capture_output=True, text=True, check=True
    )
    plain = subprocess.run(
        [sys.executable, "-c", _LIBM_DIGEST], capture_output=True, text=True, check=True, env=env
    )
    if here.stdout == plain.stdout:
        pytest.skip("this CPU's C library gives the same sin in both builds (no FMA build taken)")
    tests = [
        str(ROOT / "tests" / "model" / "test_engine_model.py"),
        str(ROOT / "tests" / "tasks" / "test_engine_tasks.py"),
    ]
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider", *tests],
        capture_output=True, text=True, env=env, cwd=ROOT,
    )  # fmt: skip
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
