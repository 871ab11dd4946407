// sin, cos and atan2 of the compiled engine, the same bits on every machine.
//
// The C library picks its sin, cos and atan2 when the process starts, by the CPU: glibc
// 2.36 on x86-64 runs variants compiled for FMA and AVX2 where the CPU has them, and a
// plain SSE2 build elsewhere, and the two round differently on about 0.05 % of arguments
// (sin(x) one ulp apart). The engine's answers then depended on the machine, which its
// build flags (-ffp-contract=off, no -march, no -ffast-math) exist to prevent: the IGM's
// answers and the frame-task rows changed under GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX2,-FMA
// on the same machine. These are plain C++ of IEEE additions, multiplications and
// divisions, compiled with the engine's flags: the same bits wherever the engine runs.
//
// Accuracy: within about one ulp of the exact value (tests/model/test_detmath.py measures
// it against an exact reference on random and hard arguments, and each constant below
// against its value recomputed by integer arithmetic).
// * sin, cos: x = k pi/2 + r, |r| <= pi/4 (about), r as a sum r_hi + r_lo. Below
//   2^19 pi/2 by Cody and Waite's reduction with pi/2 in three parts (P1 and P2 of 33
//   bits: k P1 and k P2 are exact); above it by Payne and Hanek's (x times the bits of
//   2/pi that matter, in integer arithmetic). Then Taylor series to the 17th power on
//   [-pi/4, pi/4] (truncation below 2^-60 there) with the r_lo correction.
// * atan2: the angle in [0, pi/2] of (|x|, |y|) from atan(t), t = min / max in [0, 1]
//   with its tail: atan(t) = atan(k/16) + atan(u), u = (t - k/16) / (1 + t k/16),
//   |u| <= 1/32, the series of atan(u) to the 13th power; then the quadrant, each sum in
//   two parts. C99's special values (signed zeros, infinities, NaN).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

namespace qpik::dm {

namespace detail {

// pi/2 = P1 + P2 + P3 (P1, P2: 33 significant bits; P3: 53), 119 bits in all.
constexpr double kP1 = 0x1.921fb544p+0;
constexpr double kP2 = 0x1.0b4611a6p-34;
constexpr double kP3 = 0x1.3198a2e037073p-69;
constexpr double kInvPio2 = 0x1.45f306dc9c883p-1;  // 2/pi, rounded
constexpr double kPio2Hi = 0x1.921fb54442d18p+0;   // pi/2 = hi + lo
constexpr double kPio2Lo = 0x1.1a62633145c07p-54;
constexpr double kPiHi = 0x1.921fb54442d18p+1;  // pi = hi + lo
constexpr double kPiLo = 0x1.1a62633145c07p-53;
// Cody and Waite's reduction holds below this |x| (|k| < 2^19: k P1, k P2 exact).
constexpr double kMedium = 0x1.921fb544p+19;

// The fraction bits of 2/pi, b_1 b_2 ... (2/pi = 0.b_1 b_2 ...), 64 a word from b_1: 1216
// bits, enough for the largest double (x < 2^1024 needs bits up to 971 + 194).
constexpr std::uint64_t kTwoOverPi[19] = {
    0xa2f9836e4e441529ULL, 0xfc2757d1f534ddc0ULL, 0xdb6295993c439041ULL, 0xfe5163abdebbc561ULL,
    0xb7246e3a424dd2e0ULL, 0x06492eea09d1921cULL, 0xfe1deb1cb129a73eULL, 0xe88235f52ebb4484ULL,
    0xe99c7026b45f7e41ULL, 0x3991d639835339f4ULL, 0x9c845f8bbdf9283bULL, 0x1ff897ffde05980fULL,
    0xef2f118b5a0a6d1fULL, 0x6d367ecf27cb09b7ULL, 0x4f463f669e5fea2dULL, 0x7527bac7ebe5f17bULL,
    0x3d0739f78a5292eaULL, 0x6bfb5fb11f8d5d08ULL, 0x56033046fc7b6babULL};

// Taylor coefficients (-1)^n / (2n+1)! (n = 1..8) and (-1)^n / (2n)! (n = 2..8), rounded.
constexpr double kS[8] = {-0x1.5555555555555p-3, 0x1.1111111111111p-7,  -0x1.a01a01a01a01ap-13,
                          0x1.71de3a556c734p-19, -0x1.ae64567f544e4p-26, 0x1.6124613a86d09p-33,
                          -0x1.ae7f3e733b81fp-41, 0x1.952c77030ad4ap-49};
constexpr double kC[7] = {0x1.5555555555555p-5,  -0x1.6c16c16c16c17p-10, 0x1.a01a01a01a01ap-16,
                          -0x1.27e4fb7789f5cp-22, 0x1.1eed8eff8d898p-29,  -0x1.93974a8c07c9dp-37,
                          0x1.ae7f3e733b81fp-45};
// atan(k/16) = hi + lo, k = 0..16.
constexpr double kAtanHi[17] = {
    0.0,                   0x1.ff55bb72cfdeap-5, 0x1.fd5ba9aac2f6ep-4, 0x1.7b97b4bce5b02p-3, 0x1.f5b75f92c80ddp-3,
    0x1.362773707ebccp-2,  0x1.6f61941e4def1p-2, 0x1.a64eec3cc23fdp-2, 0x1.dac670561bb4fp-2, 0x1.0657e94db30d0p-1,
    0x1.1e00babdefeb4p-1,  0x1.345f01cce37bbp-1, 0x1.4978fa3269ee1p-1, 0x1.5d58987169b18p-1, 0x1.700a7c5784634p-1,
    0x1.819d0b7158a4dp-1,  0x1.921fb54442d18p-1};
constexpr double kAtanLo[17] = {
    0.0,                    -0x1.c934d86d23f1dp-60, -0x1.cd37686760c17p-59, 0x1.347b0b4f881cap-58,
    0x1.8ab6e3cf7afbdp-57,  -0x1.963a544b672d8p-57, -0x1.c63aae6f6e918p-56, -0x1.24dec1b50b7ffp-56,
    0x1.a2b7f222f65e2p-56,  -0x1.d5b495f6349e6p-56, -0x1.928df287a668fp-58, 0x1.1021137c71102p-55,
    0x1.2419a87f2a458p-56,  0x1.0028e4bc5e7cap-57,  -0x1.8c34d25aadef6p-56, -0x1.bf76229d3b917p-56,
    0x1.1a62633145c07p-55};
// (-1)^n / (2n+1), n = 1..6, rounded.
constexpr double kA[6] = {-0x1.5555555555555p-2, 0x1.999999999999ap-3, -0x1.2492492492492p-3,
                          0x1.c71c71c71c71cp-4,  -0x1.745d1745d1746p-4, 0x1.3b13b13b13b14p-4};

// The nearest integer to v (|v| < 2^51), ties to even: the round-to-nearest of the sum.
inline double nearest_int(double v) {
    constexpr double kShift = 0x1.8p52;
    const double t = v + kShift;  // (not folded away: no -ffast-math)
    return t - kShift;
}

// a + b = s + e exactly (Knuth's two-sum).
inline void two_sum(double a, double b, double& s, double& e) {
    s = a + b;
    double bb = s - a;
    e = (a - (s - bb)) + (b - bb);
}

// a b = p + e exactly (Dekker's product: 27-bit halves, no fused multiply-add), for
// |a|, |b| well inside the range (the reduction's values).
inline void two_prod(double a, double b, double& p, double& e) {
    constexpr double kSplit = 134217729.0;  // 2^27 + 1
    p = a * b;
    double ta = kSplit * a, ah = ta - (ta - a), al = a - ah;
    double tb = kSplit * b, bh = tb - (tb - b), bl = b - bh;
    e = ((ah * bh - p) + ah * bl + al * bh) + al * bl;
}

// x = k pi/2 + (r_hi + r_lo) for |x| >= kMedium (finite), Payne and Hanek's way: with
// x = m 2^e (m < 2^53 an integer), x 2/pi mod 4 is m times 192 bits of 2/pi from b_j
// (j = max(1, e - 1): the bits before them add multiples of 4, the ones after less than
// 2^-138), in 32-bit limbs. Returns k mod 4.
inline int reduce_large(double x, double& r_hi, double& r_lo) {
    std::uint64_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    const int biased = static_cast<int>((bits >> 52) & 0x7ff);
    const std::uint64_t m = (bits & ((1ULL << 52) - 1)) | (1ULL << 52);
    const int e = biased - 1075;  // x = m 2^e
    const int j = e - 1 > 1 ? e - 1 : 1;  // first bit b_j of the window
    // w: bits b_j .. b_{j+191} of 2/pi as six 32-bit limbs, most significant first
    std::uint32_t w[6];
    for (int i = 0; i < 6; ++i) {
        std::uint32_t limb = 0;
        for (int s = 0; s < 32; ++s) {
            const int b = j + 32 * i + s;  // bit b_b, b >= 1
            const int word = (b - 1) / 64, within = (b - 1) % 64;
            const std::uint32_t bit = static_cast<std::uint32_t>((kTwoOverPi[word] >> (63 - within)) & 1ULL);
            limb = (limb << 1) | bit;
        }
        w[i] = limb;
    }
    // p = m w (53 x 192 bits) in eight 32-bit limbs, least significant first
    const std::uint32_t mlimb[2] = {static_cast<std::uint32_t>(m & 0xffffffffULL), static_cast<std::uint32_t>(m >> 32)};
    std::uint32_t p[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (int a = 0; a < 2; ++a) {
        std::uint64_t carry = 0;
        for (int i = 0; i < 6; ++i) {
            const int at = a + i;
            std::uint64_t t = static_cast<std::uint64_t>(mlimb[a]) * w[5 - i] + p[at] + carry;
            p[at] = static_cast<std::uint32_t>(t & 0xffffffffULL);
            carry = t >> 32;
        }
        for (int at = a + 6; at < 8 && carry; ++at) {
            std::uint64_t t = static_cast<std::uint64_t>(p[at]) + carry;
            p[at] = static_cast<std::uint32_t>(t & 0xffffffffULL);
            carry = t >> 32;
        }
    }
    // x 2/pi = p 2^-sh (mod 4), sh = j + 191 - e >= 190
    const int sh = j + 191 - e;
    auto bit_at = [&](int b) -> std::uint64_t {  // bit b of p (0: least significant)
        return b < 0 || b >= 256 ? 0ULL : static_cast<std::uint64_t>((p[b / 32] >> (b % 32)) & 1U);
    };
    int q = static_cast<int>(bit_at(sh) | (bit_at(sh + 1) << 1));
    // the fraction f: its 192 bits below bit sh, g[0] most significant (f = sum g_i 2^-i)
    std::uint8_t g[192];
    for (int i = 0; i < 192; ++i) g[i] = static_cast<std::uint8_t>(bit_at(sh - 1 - i));
    const bool negative = g[0] != 0;  // f >= 1/2: the nearer multiple is k + 1, and f - 1
    if (negative) {  // 1 - f: the two's complement of the 192 bits
        q = (q + 1) & 3;
        int carry = 1;
        for (int i = 191; i >= 0; --i) {
            int v = (g[i] ^ 1) + carry;
            g[i] = static_cast<std::uint8_t>(v & 1);
            carry = v >> 1;
        }
    }
    // |f| as a double-double from its leading 106 bits (the smallest |f| of a double,
    // about 2^-62, leaves 130 bits below its leading one)
    int lead = 0;
    while (lead < 192 && g[lead] == 0) ++lead;
    auto read53 = [&](int from) -> double {  // bits from .. from + 52 as an integer
        std::uint64_t v = 0;
        for (int i = from; i < from + 53; ++i) v = (v << 1) | (i < 192 ? g[i] : 0U);
        return static_cast<double>(v);  // exact (< 2^53)
    };
    double f_hi = 0.0, f_lo = 0.0;
    if (lead < 192) {
        // the bit g[lead] has weight 2^-(lead + 1)
        const double a1 = std::ldexp(read53(lead), -(lead + 53));
        const double a2 = std::ldexp(read53(lead + 53), -(lead + 106));
        two_sum(a1, a2, f_hi, f_lo);
    }
    double p_hi, p_err;
    two_prod(f_hi, kPio2Hi, p_hi, p_err);
    const double tail = p_err + (f_hi * kPio2Lo + f_lo * kPio2Hi);
    two_sum(p_hi, tail, r_hi, r_lo);
    if (negative) {
        r_hi = -r_hi;
        r_lo = -r_lo;
    }
    if (x < 0.0) {
        r_hi = -r_hi;
        r_lo = -r_lo;
        q = (4 - q) & 3;
    }
    return q;
}

// x = k pi/2 + (r_hi + r_lo), |r_hi| <= pi/4 (and a little more), finite x; returns k mod 4.
inline int reduce(double x, double& r_hi, double& r_lo) {
    const double ax = std::fabs(x);
    if (ax <= 0x1.921fb54442d18p-1) {  // pi/4
        r_hi = x;
        r_lo = 0.0;
        return 0;
    }
    if (ax < kMedium) {
        const double k = nearest_int(x * kInvPio2);
        const double a = x - k * kP1;  // exact (k P1 exact, Sterbenz)
        double s, e;
        two_sum(a, -(k * kP2), s, e);  // (k P2 exact)
        const double t = e - k * kP3;
        r_hi = s + t;
        r_lo = (s - r_hi) + t;
        const long long ki = static_cast<long long>(k);
        return static_cast<int>(ki & 3);
    }
    return reduce_large(x, r_hi, r_lo);
}

// sin(r_hi + r_lo) and cos(r_hi + r_lo), |r_hi| <= pi/4 (about).
inline void kernel(double r, double rl, double& s, double& c) {
    const double z = r * r;
    const double v = z * r;
    const double ps = kS[1] + z * (kS[2] + z * (kS[3] + z * (kS[4] + z * (kS[5] + z * (kS[6] + z * kS[7])))));
    s = r + (v * (kS[0] + z * ps) + rl * (1.0 - 0.5 * z));
    const double pc = kC[0] + z * (kC[1] + z * (kC[2] + z * (kC[3] + z * (kC[4] + z * (kC[5] + z * kC[6])))));
    const double hz = 0.5 * z;
    const double w = 1.0 - hz;
    c = w + (((1.0 - w) - hz) + (z * z * pc - r * rl));
}

// atan(t + tl) = hi + lo for 0 <= t <= 1, tl the tail of t (|tl| <= ulp(t)).
inline void atan01(double t, double tl, double& hi, double& lo) {
    const int k = static_cast<int>(t * 16.0 + 0.5);  // 0..16
    if (k == 0) {
        const double z = t * t;
        const double p = t * z * (kA[0] + z * (kA[1] + z * (kA[2] + z * (kA[3] + z * (kA[4] + z * kA[5])))));
        const double tail = p + tl * (1.0 - z);  // (atan' = 1 / (1 + t^2))
        hi = t + tail;
        lo = (t - hi) + tail;
        return;
    }
    // u = (t + tl - c) / (1 + t c) = u0 + u_lo, c = k/16: t - c exact, 1 + t c as
    // d_hi + d_lo, u0's residual exact; then atan(c) + u0 summed exactly, the small terms
    // after: one rounding of the whole at the end.
    const double c = static_cast<double>(k) * 0.0625;
    const double nh = t - c;
    double tc, tce;
    two_prod(t, c, tc, tce);
    const double d_hi = 1.0 + tc;
    const double d_lo = ((1.0 - d_hi) + tc) + tce;
    const double u0 = nh / d_hi;
    double pu, pe;
    two_prod(u0, d_hi, pu, pe);
    const double u_lo = ((((nh - pu) - pe) + tl) - u0 * d_lo) / d_hi;
    const double z = u0 * u0;
    const double p = u0 * z * (kA[0] + z * (kA[1] + z * (kA[2] + z * (kA[3] + z * (kA[4] + z * kA[5])))));
    double sum, err;
    two_sum(kAtanHi[k], u0, sum, err);
    const double tail = err + (kAtanLo[k] + (u_lo + p));
    hi = sum + tail;
    lo = (sum - hi) + tail;
}

// a / b = q + ql, ql the first-order tail ((a - q b) / b, the residual exact), for positive
// a <= b; ql = 0 where a or b lies outside [2^-500, 2^500] (Dekker's product would
// overflow or lose its tail there).
inline void divide(double a, double b, double& q, double& ql) {
    q = a / b;
    ql = 0.0;
    if (a >= 0x1p-500 && b <= 0x1p500) {
        double pq, pe;
        two_prod(q, b, pq, pe);
        ql = ((a - pq) - pe) / b;
    }
}

// base + s (hi + lo) as one double, s = +-1, base = bh + bl: the sum in two parts.
inline double add_angle(double bh, double bl, double s, double hi, double lo) {
    double r, e;
    two_sum(bh, s * hi, r, e);
    return r + (e + (bl + s * lo));
}

}  // namespace detail

// sin(x) and cos(x) [x in rad] at once (one reduction).
inline void sincos(double x, double& s, double& c) {
    if (!std::isfinite(x)) {
        s = c = x - x;  // NaN (inf - inf, or NaN itself)
        return;
    }
    if (std::fabs(x) < 0x1p-27) {  // sin x = x, cos x = 1 to within half an ulp (-0 kept)
        s = x;
        c = 1.0;
        return;
    }
    double r, rl;
    const int q = detail::reduce(x, r, rl);
    double sr, cr;
    detail::kernel(r, rl, sr, cr);
    switch (q) {
        case 0: s = sr; c = cr; break;
        case 1: s = cr; c = -sr; break;
        case 2: s = -sr; c = -cr; break;
        default: s = -cr; c = sr; break;
    }
}

inline double sin(double x) {
    double s, c;
    sincos(x, s, c);
    return s;
}

inline double cos(double x) {
    double s, c;
    sincos(x, s, c);
    return c;
}

// atan2(y, x) [rad, in [-pi, pi]], with C99's special values.
inline double atan2(double y, double x) {
    if (std::isnan(x) || std::isnan(y)) return x + y;
    if (y == 0.0) {
        if (x > 0.0 || (x == 0.0 && !std::signbit(x))) return y;  // +-0
        return std::copysign(detail::kPiHi + detail::kPiLo, y);  // x < 0 or x = -0
    }
    if (x == 0.0) return std::copysign(detail::kPio2Hi + detail::kPio2Lo, y);
    if (std::isinf(x)) {
        if (std::isinf(y)) {
            const double quarter = 0x1.921fb54442d18p-1;  // pi/4
            return std::copysign(x > 0.0 ? quarter : 3.0 * quarter, y);
        }
        return x > 0.0 ? std::copysign(0.0, y) : std::copysign(detail::kPiHi + detail::kPiLo, y);
    }
    if (std::isinf(y)) return std::copysign(detail::kPio2Hi + detail::kPio2Lo, y);
    const double ax = std::fabs(x), ay = std::fabs(y);
    double t, tl, hi, lo, a;
    if (ay <= ax) {  // angle atan(ay / ax), or pi less it
        detail::divide(ay, ax, t, tl);
        detail::atan01(t, tl, hi, lo);
        a = x > 0.0 ? hi + lo : detail::add_angle(detail::kPiHi, detail::kPiLo, -1.0, hi, lo);
    } else {  // pi/2 less atan(ax / ay), or pi/2 plus it
        detail::divide(ax, ay, t, tl);
        detail::atan01(t, tl, hi, lo);
        a = detail::add_angle(detail::kPio2Hi, detail::kPio2Lo, x > 0.0 ? -1.0 : 1.0, hi, lo);
    }
    return std::copysign(a, y);
}

}  // namespace qpik::dm
