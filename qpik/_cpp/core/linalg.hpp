// Dense linear algebra of the core: Cholesky, triangular solves, small products, QR and
// the smallest singular value.
//
// Every loop keeps one fixed order of floating-point operations, so that the same
// inputs give the same bits (the build uses -ffp-contract=off and no -ffast-math).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstring>
#include <type_traits>

#include "../common.hpp"

namespace qpik::core {

// M reshaped to (r, c), the storage kept, its entries left as they were (stale): for a
// matrix every entry of which is written before it is read (Mat::zeros fills it first).
// M.a never shrinks here (it may hold more than r c entries past the matrix's, never read):
// a matrix shaped smaller then larger again is not value-initialised each time it grows.
inline void shape(Mat& M, i64 r, i64 c) {
    M.rows = r;
    M.cols = c;
    if (M.a.size() < static_cast<size_t>(r * c)) M.a.resize(static_cast<size_t>(r * c));
}

// v of size n, its entries left as they were (every one written before it is read).
inline void shape(Vec& v, size_t n) { v.resize(n); }

// Python's min(a, b) / max(a, b) as Python evaluates them: the second argument wins only
// when strictly smaller / larger (so a NaN second argument never wins).
inline double pymin(double a, double b) { return b < a ? b : a; }
inline double pymax(double a, double b) { return b > a ? b : a; }

// Element-wise kernels two lanes at a time (GCC vector extensions: SSE2 on x86-64, NEON on
// aarch64, no -march needed). Each lane does exactly the scalar loop's IEEE operations on
// its element (a multiply, then an add; -ffp-contract=off keeps them unfused), so the bits
// are those of the plain loops; only independent elements share an instruction. Sums over
// an index (dot products) are never split: their order is the reference's.
namespace simd {
typedef double v2d __attribute__((vector_size(16)));
inline v2d load(const double* p) {
    v2d v;
    std::memcpy(&v, p, sizeof v);
    return v;
}
inline void store(double* p, v2d v) { std::memcpy(p, &v, sizeof v); }
inline v2d splat(double a) { return v2d{a, a}; }
// |v| per lane: the sign bit cleared, as std::fabs does.
typedef long long v2i __attribute__((vector_size(16)));
inline v2d vabs(v2d v) {
    v2i bits;
    std::memcpy(&bits, &v, sizeof v);
    bits &= v2i{0x7fffffffffffffffLL, 0x7fffffffffffffffLL};
    std::memcpy(&v, &bits, sizeof v);
    return v;
}
}  // namespace simd

// y[j] += |x[j]| * a, j < n (two lanes at a time, each the scalar loop's operations).
inline void abs_axpy(double* y, double a, const double* x, i64 n) {
    using namespace simd;
    v2d av = splat(a);
    i64 j = 0;
    for (; j + 2 <= n; j += 2) store(y + j, load(y + j) + vabs(load(x + j)) * av);
    for (; j < n; ++j) y[j] += std::fabs(x[j]) * a;
}

// abs_axpy(y, a, x, n), returning m = pymax(... pymax(pymax(0, |x[0]|), |x[1]|) ..., |x[n-1]|)
// from the same pass: the largest |x[j]| (NaN entries never win a pymax), taken over the
// even and the odd entries apart, then both (the largest of a set is exact, in any order).
inline double abs_axpy_max(double* y, double a, const double* x, i64 n) {
    using namespace simd;
    v2d av = splat(a), mv = splat(0.0);
    i64 j = 0;
    for (; j + 2 <= n; j += 2) {
        v2d ax = vabs(load(x + j));
        store(y + j, load(y + j) + ax * av);
        mv = ax > mv ? ax : mv;
    }
    double m = pymax(mv[0], mv[1]);
    for (; j < n; ++j) {
        y[j] += std::fabs(x[j]) * a;
        m = pymax(m, std::fabs(x[j]));
    }
    return m;
}

// y[j] += x[j] * a, s[j] += |x[j]| * b, h[j] += |x[j]| * c, j < n (two lanes at a time,
// each the scalar loop's operations).
inline void axpy3(double* y, double* s, double* h, const double* x, double a, double b, double c, i64 n) {
    using namespace simd;
    v2d av = splat(a), bv = splat(b), cv = splat(c);
    i64 j = 0;
    for (; j + 2 <= n; j += 2) {
        v2d xv = load(x + j);
        v2d ax = vabs(xv);
        store(y + j, load(y + j) + xv * av);
        store(s + j, load(s + j) + ax * bv);
        store(h + j, load(h + j) + ax * cv);
    }
    for (; j < n; ++j) {
        y[j] += x[j] * a;
        s[j] += std::fabs(x[j]) * b;
        h[j] += std::fabs(x[j]) * c;
    }
}

// axpy3(y, s, h, Z.row(i), a[i], b[i], c[i], Z.cols) for every row i of Z in order: four
// columns a pass (two pairs, a[i], b[i], c[i] broadcast once per row for both), then two,
// summed over i in registers (each entry the same operations in the same order).
inline void axpy3_rows(double* y, double* s, double* h, CMatRef Z, const double* a, const double* b,
                       const double* c) {
    using namespace simd;
    i64 n = Z.rows, r = Z.cols;
    i64 j = 0;
    for (; j + 4 <= r; j += 4) {
        v2d yv = load(y + j), sv = load(s + j), hv = load(h + j);
        v2d yw = load(y + j + 2), sw = load(s + j + 2), hw = load(h + j + 2);
        const double* p = Z.p + j;
        for (i64 i = 0; i < n; ++i, p += Z.stride) {
            const v2d xv = load(p), xw = load(p + 2);
            const v2d ax = vabs(xv), aw = vabs(xw);
            const v2d ai = splat(a[i]), bi = splat(b[i]), ci = splat(c[i]);
            yv = yv + xv * ai;
            yw = yw + xw * ai;
            sv = sv + ax * bi;
            sw = sw + aw * bi;
            hv = hv + ax * ci;
            hw = hw + aw * ci;
        }
        store(y + j, yv);
        store(s + j, sv);
        store(h + j, hv);
        store(y + j + 2, yw);
        store(s + j + 2, sw);
        store(h + j + 2, hw);
    }
    for (; j + 2 <= r; j += 2) {
        v2d yv = load(y + j), sv = load(s + j), hv = load(h + j);
        const double* p = Z.p + j;
        for (i64 i = 0; i < n; ++i, p += Z.stride) {
            v2d xv = load(p);
            v2d ax = vabs(xv);
            yv = yv + xv * splat(a[i]);
            sv = sv + ax * splat(b[i]);
            hv = hv + ax * splat(c[i]);
        }
        store(y + j, yv);
        store(s + j, sv);
        store(h + j, hv);
    }
    for (; j < r; ++j) {
        for (i64 i = 0; i < n; ++i) {
            double x = Z(i, j);
            y[j] += x * a[i];
            s[j] += std::fabs(x) * b[i];
            h[j] += std::fabs(x) * c[i];
        }
    }
}

// y[j] += a * x[j], j < n.
inline void axpy(double* y, double a, const double* x, i64 n) {
    using namespace simd;
    v2d av = splat(a);
    i64 j = 0;
    for (; j + 4 <= n; j += 4) {
        store(y + j, load(y + j) + av * load(x + j));
        store(y + j + 2, load(y + j + 2) + av * load(x + j + 2));
    }
    for (; j + 2 <= n; j += 2) store(y + j, load(y + j) + av * load(x + j));
    for (; j < n; ++j) y[j] += a * x[j];
}

// y[j] += a * x[j] and z[j] += b * x[j], j < n (axpy twice, x loaded once).
inline void axpy2(double* y, double* z, double a, double b, const double* x, i64 n) {
    using namespace simd;
    v2d av = splat(a), bv = splat(b);
    i64 j = 0;
    for (; j + 2 <= n; j += 2) {
        v2d xv = load(x + j);
        store(y + j, load(y + j) + av * xv);
        store(z + j, load(z + j) + bv * xv);
    }
    for (; j < n; ++j) {
        y[j] += a * x[j];
        z[j] += b * x[j];
    }
}

// y[j] -= a * x[j], j < n.
inline void axmy(double* y, double a, const double* x, i64 n) {
    using namespace simd;
    v2d av = splat(a);
    i64 j = 0;
    for (; j + 4 <= n; j += 4) {
        store(y + j, load(y + j) - av * load(x + j));
        store(y + j + 2, load(y + j + 2) - av * load(x + j + 2));
    }
    for (; j + 2 <= n; j += 2) store(y + j, load(y + j) - av * load(x + j));
    for (; j < n; ++j) y[j] -= a * x[j];
}

// Two dot products with one vector, sa = a . x and sb = b . x, each summed in index order
// from 0.0 as dot() does (one per lane: the same bits, twice the independent work).
// (Four terms a pass: the same additions in the same order, fewer loop instructions.)
inline void dot2(const double* a, const double* b, const double* x, i64 n, double& sa, double& sb) {
    using namespace simd;
    v2d acc = splat(0.0);
    i64 t = 0;
    for (; t + 4 <= n; t += 4) {
        acc += v2d{a[t], b[t]} * splat(x[t]);
        acc += v2d{a[t + 1], b[t + 1]} * splat(x[t + 1]);
        acc += v2d{a[t + 2], b[t + 2]} * splat(x[t + 2]);
        acc += v2d{a[t + 3], b[t + 3]} * splat(x[t + 3]);
    }
    for (; t < n; ++t) acc += v2d{a[t], b[t]} * splat(x[t]);
    sa = acc[0];
    sb = acc[1];
}

// Four dot products with one vector (a . x, b . x, c . x, d . x), each summed in index order
// from 0.0 as dot() does (one per lane of two pairs: the same bits; x[t] loaded once).
inline void dot4(const double* a, const double* b, const double* c, const double* d, const double* x, i64 n,
                 double& sa, double& sb, double& sc, double& sd) {
    using namespace simd;
    v2d acc0 = splat(0.0), acc1 = splat(0.0);
    i64 t = 0;
    for (; t + 2 <= n; t += 2) {
        v2d x0 = splat(x[t]), x1 = splat(x[t + 1]);
        acc0 += v2d{a[t], b[t]} * x0;
        acc1 += v2d{c[t], d[t]} * x0;
        acc0 += v2d{a[t + 1], b[t + 1]} * x1;
        acc1 += v2d{c[t + 1], d[t + 1]} * x1;
    }
    for (; t < n; ++t) {
        v2d xv = splat(x[t]);
        acc0 += v2d{a[t], b[t]} * xv;
        acc1 += v2d{c[t], d[t]} * xv;
    }
    sa = acc0[0];
    sb = acc0[1];
    sc = acc1[0];
    sd = acc1[1];
}

// sum_t G(j, t)^2, summed in index order from 0.0 (a general row's norm squared, as the
// cascade's functions sum it).
inline double row_sq_of(CMatRef G, i64 j) {
    double s = 0.0;
    for (i64 t = 0; t < G.cols; ++t) s += G(j, t) * G(j, t);
    return s;
}

// sum_t a[t]^2 for t < n, summed in index order from 0.0.
inline double row_sq(const double* a, i64 n) {
    double acc = 0.0;
    for (i64 t = 0; t < n; ++t) acc += a[t] * a[t];
    return acc;
}

// row_sq of two rows at once, one per lane (the same bits as two row_sq calls).
inline void row_sq2(const double* a, const double* b, i64 n, double& sa, double& sb) {
    using namespace simd;
    v2d acc = splat(0.0);
    for (i64 t = 0; t < n; ++t) {
        v2d v = v2d{a[t], b[t]};
        acc += v * v;
    }
    sa = acc[0];
    sb = acc[1];
}

// out[j] = sum_{t0 <= t < t1} M(t, j)^2 for j0 <= j < j1 (M row-major, row stride ld), each
// summed over t in order from 0.0 (a row at a time: contiguous, two columns per lane).
// (Four columns a pass summed over t in registers, then two: the same sums.)
inline void col_sq(const double* M, i64 ld, i64 t0, i64 t1, i64 j0, i64 j1, double* out) {
    using namespace simd;
    if (j1 - j0 >= 2) {
        i64 j = j0;
        for (; j + 4 <= j1; j += 4) {
            v2d a = splat(0.0), b = splat(0.0);
            const double* p = M + t0 * ld + j;
            for (i64 t = t0; t < t1; ++t, p += ld) {
                v2d u = load(p), v = load(p + 2);
                a += u * u;
                b += v * v;
            }
            store(out + j, a);
            store(out + j + 2, b);
        }
        for (; j + 2 <= j1; j += 2) {
            v2d a = splat(0.0);
            const double* p = M + t0 * ld + j;
            for (i64 t = t0; t < t1; ++t, p += ld) {
                v2d u = load(p);
                a += u * u;
            }
            store(out + j, a);
        }
        for (; j < j1; ++j) {
            double a = 0.0;
            for (i64 t = t0; t < t1; ++t) a += M[t * ld + j] * M[t * ld + j];
            out[j] = a;
        }
        return;
    }
    for (i64 j = j0; j < j1; ++j) out[j] = 0.0;
    for (i64 t = t0; t < t1; ++t) {
        const double* row = M + t * ld;
        i64 j = j0;
        for (; j + 2 <= j1; j += 2) {
            v2d v = load(row + j);
            store(out + j, load(out + j) + v * v);
        }
        for (; j < j1; ++j) out[j] += row[j] * row[j];
    }
}

// s[j] += x * M[j] (a row of column sums, accumulated one row at a time: each s[j] sums
// over the rows in their order, as a per-column loop would).
inline void acc_row(double* s, double x, const double* row, i64 n) { axpy(s, x, row, n); }

// The Jacobi rotation of two rows: a' = cs a - sn b, b' = sn a + cs b.
inline void jacobi_rows(double* a, double* b, double cs, double sn, i64 n) {
    using namespace simd;
    v2d c2 = splat(cs), s2 = splat(sn);
    i64 t = 0;
    for (; t + 2 <= n; t += 2) {
        v2d x = load(a + t), y = load(b + t);
        store(a + t, c2 * x - s2 * y);
        store(b + t, s2 * x + c2 * y);
    }
    for (; t < n; ++t) {
        double x = a[t], y = b[t];
        a[t] = cs * x - sn * y;
        b[t] = sn * x + cs * y;
    }
}

// jacobi_rows, then sa = |a'|^2 and sb = |b'|^2 as row_sq2 sums them (over t in order from
// 0.0, one row per lane: the same bits), in the same pass over the rows; with Dot, also
// sc = a' . c summed over t in order from 0.0 (the sum dot(a', c) and dot2's lane make).
template <bool Dot>
inline void jacobi_rows_sums(double* a, double* b, const double* c, double cs, double sn, i64 n, double& sa,
                             double& sb, double& sc) {
    using namespace simd;
    v2d c2 = splat(cs), s2 = splat(sn);
    v2d acc = splat(0.0);
    double g = 0.0;
    i64 t = 0;
    for (; t + 2 <= n; t += 2) {
        v2d x = load(a + t), y = load(b + t);
        v2d xn = c2 * x - s2 * y;
        v2d yn = s2 * x + c2 * y;
        store(a + t, xn);
        store(b + t, yn);
        v2d v0 = v2d{xn[0], yn[0]};
        v2d v1 = v2d{xn[1], yn[1]};
        acc += v0 * v0;
        acc += v1 * v1;
        if constexpr (Dot) {
            g += xn[0] * c[t];
            g += xn[1] * c[t + 1];
        }
    }
    for (; t < n; ++t) {
        double x = a[t], y = b[t];
        a[t] = cs * x - sn * y;
        b[t] = sn * x + cs * y;
        v2d v = v2d{a[t], b[t]};
        acc += v * v;
        if constexpr (Dot) g += a[t] * c[t];
    }
    sa = acc[0];
    sb = acc[1];
    sc = g;
}

inline void jacobi_rows_sq(double* a, double* b, double cs, double sn, i64 n, double& sa, double& sb) {
    double unused = 0.0;
    jacobi_rows_sums<false>(a, b, nullptr, cs, sn, n, sa, sb, unused);
}

inline void jacobi_rows_sq_dot(double* a, double* b, const double* c, double cs, double sn, i64 n, double& sa,
                               double& sb, double& sc) {
    jacobi_rows_sums<true>(a, b, c, cs, sn, n, sa, sb, sc);
}

// The Givens rotation of two rows as rotate_in / drop_constraint write it:
// a' = a cc + b ss, b' = xny (a + a') - b (four entries a pass, then two, then one: each
// entry's operations the same).
inline void givens_rows(double* a, double* b, double cc, double ss, double xny, i64 n) {
    using namespace simd;
    v2d c2 = splat(cc), s2 = splat(ss), x2 = splat(xny);
    i64 t = 0;
    for (; t + 4 <= n; t += 4) {
        v2d x = load(a + t), y = load(b + t);
        v2d x1 = load(a + t + 2), y1 = load(b + t + 2);
        v2d xn = x * c2 + y * s2;
        v2d xn1 = x1 * c2 + y1 * s2;
        store(a + t, xn);
        store(a + t + 2, xn1);
        store(b + t, x2 * (x + xn) - y);
        store(b + t + 2, x2 * (x1 + xn1) - y1);
    }
    for (; t + 2 <= n; t += 2) {
        v2d x = load(a + t), y = load(b + t);
        v2d xn = x * c2 + y * s2;
        store(a + t, xn);
        store(b + t, x2 * (x + xn) - y);
    }
    for (; t < n; ++t) {
        double x = a[t], y = b[t];
        a[t] = x * cc + y * ss;
        b[t] = xny * (x + a[t]) - y;
    }
}

// acc - x[0] y[0] - x[1] y[1] - ... - x[n-1] y[n-1], subtracted in that order (four terms
// a pass: fewer loop instructions, the same operations and bits as the plain loop).
inline double minus_dot(double acc, const double* x, const double* y, i64 n) {
    i64 i = 0;
    for (; i + 4 <= n; i += 4) {
        acc -= x[i] * y[i];
        acc -= x[i + 1] * y[i + 1];
        acc -= x[i + 2] * y[i + 2];
        acc -= x[i + 3] * y[i + 3];
    }
    for (; i < n; ++i) acc -= x[i] * y[i];
    return acc;
}

namespace detail {
// cholesky_into column by column (each entry's dot product summed at once, rows two or four a
// pass, one per lane).
inline bool cholesky_left(CMatRef G, i64 n, double shift, MatRef L) {
    for (i64 j = 0; j < n; ++j) {
        double s = G(j, j) - shift;
        const double* lj = L.p + j * L.stride;
        for (i64 k = 0; k < j; ++k) s -= lj[k] * lj[k];
        if (!(s > 0.0)) return false;
        double d = std::sqrt(s);
        L(j, j) = d;
        i64 i = j + 1;
        for (; i + 4 <= n; i += 4) {
            // Rows i .. i + 3 in one pass, one per lane: each minus_dot's subtractions in
            // order (the same bits).
            using namespace simd;
            const double* a = L.p + i * L.stride;
            const double* b = a + L.stride;
            const double* c = b + L.stride;
            const double* e = c + L.stride;
            v2d acc = v2d{G(i, j), G(i + 1, j)};
            v2d acc2 = v2d{G(i + 2, j), G(i + 3, j)};
            for (i64 k = 0; k < j; ++k) {
                v2d lk = splat(lj[k]);
                acc -= v2d{a[k], b[k]} * lk;
                acc2 -= v2d{c[k], e[k]} * lk;
            }
            L(i, j) = acc[0] / d;
            L(i + 1, j) = acc[1] / d;
            L(i + 2, j) = acc2[0] / d;
            L(i + 3, j) = acc2[1] / d;
        }
        for (; i + 2 <= n; i += 2) {
            // Rows i and i + 1 in one pass, one per lane: each minus_dot's subtractions in
            // order (the same bits).
            using namespace simd;
            const double* a = L.p + i * L.stride;
            const double* b = a + L.stride;
            v2d acc = v2d{G(i, j), G(i + 1, j)};
            for (i64 k = 0; k < j; ++k) acc -= v2d{a[k], b[k]} * splat(lj[k]);
            L(i, j) = acc[0] / d;
            L(i + 1, j) = acc[1] / d;
        }
        for (; i < n; ++i) L(i, j) = minus_dot(G(i, j), L.p + i * L.stride, lj, j) / d;
    }
    return true;
}

}  // namespace detail

namespace detail {
// Column j's sums for the 2 P rows i0.. (v2d a[p]: rows i0 + 2p, i0 + 2p + 1, holding G's
// entries on entry): a[p] -= T(k, i0 + 2p ..) T(k, j) for k < j in k order (T: L's columns
// as rows, row stride ldt). Each lane a chain of subtractions over k; P chains side by side.
template <int P>
__attribute__((always_inline)) inline void chol_chunk(const double* T, i64 ldt, i64 j, i64 i0, simd::v2d* a) {
    using namespace simd;
    v2d r[P];
#pragma GCC unroll 8
    for (int q = 0; q < P; ++q) r[q] = a[q];
    const double* tj = T + j;
    const double* ti = T + i0;
    for (i64 k = 0; k < j; ++k, tj += ldt, ti += ldt) {
        v2d x = splat(*tj);
#pragma GCC unroll 8
        for (int q = 0; q < P; ++q) r[q] -= load(ti + 2 * q) * x;
    }
#pragma GCC unroll 8
    for (int q = 0; q < P; ++q) a[q] = r[q];
}

inline void chol_chunk_n(const double* T, i64 ldt, i64 j, i64 i0, i64 P, simd::v2d* a) {
    switch (P) {
        case 1: chol_chunk<1>(T, ldt, j, i0, a); break;
        case 2: chol_chunk<2>(T, ldt, j, i0, a); break;
        case 3: chol_chunk<3>(T, ldt, j, i0, a); break;
        case 4: chol_chunk<4>(T, ldt, j, i0, a); break;
        case 5: chol_chunk<5>(T, ldt, j, i0, a); break;
        case 6: chol_chunk<6>(T, ldt, j, i0, a); break;
        case 7: chol_chunk<7>(T, ldt, j, i0, a); break;
        default: chol_chunk<8>(T, ldt, j, i0, a); break;
    }
}
}  // namespace detail

// Cholesky factor of G[:n, :n] - shift I written into the lower triangle of L[:n, :n]
// (G unchanged); false as soon as a pivot is not positive (L then holds a partial factor).
// Entry (i, j), j <= i: G(i, j) (less shift on the diagonal) minus L(i, k) L(j, k) for k < j,
// subtracted in k order, then divided by L(j, j) (off the diagonal) or its square root taken
// (on it): the operations of cholesky_left, the same bits.
// Column by column, L's columns also kept as the rows of T (on the stack): column j's rows
// j.. (its diagonal among them) two a lane, sixteen a pass, each lane's subtractions over
// k one chain, the pairs T(k, i..i+1) one load (a row's sums are latency-bound: the more
// rows a pass, the more chains side by side). The pairs start at even rows (the loads then
// meet the very stores that wrote them: no store-forwarding stall); below an odd j, the
// first pair's row j - 1 lane (above the diagonal) is summed but never stored to L, and T's
// column n is a zero pad (an odd last row's other lane).
inline bool cholesky_into(CMatRef G, i64 n, double shift, MatRef L) {
    using namespace simd;
    constexpr i64 kMax = 64;  // the largest n on the stack (T: 33 kB)
    // Below 24, the column-by-column form is as fast (each column's fixed cost here: the
    // root's and the divisions' latency before the next column's loads).
    if (n > kMax || n < 24) return detail::cholesky_left(G, n, shift, L);
    alignas(16) double T[kMax * (kMax + 2)];
    const i64 ldt = (n + 2) & ~i64(1);  // even: every pair 16-byte aligned
    const i64 ldg = G.stride, ldl = L.stride;
    for (i64 j = 0; j < n; ++j) {
        double* tj = T + j * ldt;  // L's column j, entries j+1.. (and the pad n)
        const i64 e = j & ~i64(1);  // the first pair's row
        const bool odd = j != e;    // the diagonal in the first pair's second lane
        double d = 0.0;
        v2d dv = splat(0.0);
        for (i64 i0 = e; i0 < n; i0 += 16) {
            const i64 P = std::min<i64>(8, (n - i0 + 1) / 2);
            const bool tail = i0 + 2 * P > n;  // the last pair's second lane: the pad
            v2d a[8];
            // G's column j: rows i0.. (row e = j - 1 above the diagonal, and the pad's lane
            // a copy of row n - 1: both summed, never stored to L).
            const double* g = G.p + i0 * ldg + j;
            const i64 full = tail ? P - 1 : P;
            for (i64 q = 0; q < full; ++q, g += 2 * ldg) a[q] = v2d{g[0], g[ldg]};
            if (tail) a[P - 1] = v2d{g[0], g[0]};
            // the diagonal less shift (x - +0 = x on the other lane, whatever x: the same bits)
            if (i0 == e) a[0] = a[0] - (odd ? v2d{0.0, shift} : v2d{shift, 0.0});
            detail::chol_chunk_n(T, ldt, j, i0, P, a);
            if (i0 == e) {
                double s = odd ? a[0][1] : a[0][0];
                if (!(s > 0.0)) return false;
                d = std::sqrt(s);
                L.p[j * ldl + j] = d;
                dv = splat(d);
            }
            double* l = L.p + i0 * ldl + j;
            i64 q = 0;
            if (i0 == e) {
                v2d v = a[0] / dv;
                store(tj + i0, v);
                if (!odd && !(tail && P == 1)) l[ldl] = v[1];
                q = 1;
                l += 2 * ldl;
            }
            for (; q < full; ++q, l += 2 * ldl) {
                v2d v = a[q] / dv;
                store(tj + i0 + 2 * q, v);
                l[0] = v[0];
                l[ldl] = v[1];
            }
            if (tail && q < P) {
                v2d v = a[q] / dv;
                store(tj + i0 + 2 * q, v);
                l[0] = v[0];
            }
        }
        tj[n] = 0.0;  // the pad (its lane never stored to L)
    }
    return true;
}

// Lower Cholesky factor of a symmetric matrix (zeros above the diagonal) and success.
inline bool cholesky(CMatRef H, Mat& L) {
    L = Mat(H.rows, H.rows);
    return cholesky_into(H, H.rows, 0.0, L.ref());
}

// L^-1 b for lower-triangular L into x (its storage kept; x is not b).
// (Rows i and i + 1 a pass, one per lane: row i + 1's subtractions over k < i run beside row
// i's, then its k = i one; each row's subtractions in order.)
inline void forward_into(CMatRef L, const Vec& b, Vec& x) {
    using namespace simd;
    i64 n = static_cast<i64>(b.size());
    x.resize(static_cast<size_t>(n));
    i64 i = 0;
    for (; i + 2 <= n; i += 2) {
        const double* l0 = L.row(i);
        const double* l1 = L.row(i + 1);
        v2d acc = v2d{b[i], b[i + 1]};
        for (i64 k = 0; k < i; ++k) acc -= v2d{l0[k], l1[k]} * splat(x[k]);
        x[i] = acc[0] / l0[i];
        x[i + 1] = (acc[1] - l1[i] * x[i]) / l1[i + 1];
    }
    for (; i < n; ++i) {
        double s = b[i];
        for (i64 k = 0; k < i; ++k) s -= L(i, k) * x[k];
        x[i] = s / L(i, i);
    }
}

// forward_into for q right-hand sides at once: row j of X (q x n, row-major, stride n) is
// L^-1 (row j of B), each by forward_into's own operations in its order (the same bits); the
// right-hand sides interleaved, so that their sums' chains run side by side (a triangular
// solve is bound by its one chain's latency). q <= kForwardRows.
constexpr i64 kForwardRows = 16;
inline void forward_rows_into(CMatRef L, const double* B, i64 q, i64 n, double* X) {
    using namespace simd;
    v2d acc[kForwardRows];
    i64 i = 0;
    for (; i + 2 <= n; i += 2) {
        const double* l0 = L.row(i);
        const double* l1 = L.row(i + 1);
        for (i64 j = 0; j < q; ++j) acc[j] = v2d{B[j * n + i], B[j * n + i + 1]};
        for (i64 k = 0; k < i; ++k) {
            const v2d lk = v2d{l0[k], l1[k]};
            for (i64 j = 0; j < q; ++j) acc[j] -= lk * splat(X[j * n + k]);
        }
        for (i64 j = 0; j < q; ++j) {
            double* x = X + j * n;
            x[i] = acc[j][0] / l0[i];
            x[i + 1] = (acc[j][1] - l1[i] * x[i]) / l1[i + 1];
        }
    }
    for (; i < n; ++i) {
        for (i64 j = 0; j < q; ++j) {
            double* x = X + j * n;
            double s = B[j * n + i];
            for (i64 k = 0; k < i; ++k) s -= L(i, k) * x[k];
            x[i] = s / L(i, i);
        }
    }
}

inline Vec forward_vec(CMatRef L, const Vec& b) {
    Vec x;
    forward_into(L, b, x);
    return x;
}

// L^-T b for lower-triangular L into x (its storage kept; x is not b).
inline void backward_into(CMatRef L, const Vec& b, Vec& x) {
    i64 n = static_cast<i64>(b.size());
    x.resize(static_cast<size_t>(n));
    for (i64 i = n - 1; i >= 0; --i) {
        double s = b[i];
        for (i64 k = i + 1; k < n; ++k) s -= L(k, i) * x[k];
        x[i] = s / L(i, i);
    }
}

// L^-T b for lower-triangular L.
inline Vec backward_vec(CMatRef L, const Vec& b) {
    Vec x;
    backward_into(L, b, x);
    return x;
}

// Whether no entry of A is zero (a product may then sum in register blocks: nothing to skip).
inline bool no_zero_entry(CMatRef A) {
    for (i64 r = 0; r < A.rows; ++r) {
        const double* ar = A.row(r);
        for (i64 t = 0; t < A.cols; ++t)
            if (ar[t] == 0.0) return false;
    }
    return true;
}

namespace detail {
// Whether every entry of the rows x cols block at p (rows `stride` apart) is finite: x - x is
// +0 for a finite x and NaN otherwise, and a sum of them is 0 only when every one is +0.
inline bool finite_block(const double* p, i64 rows, i64 cols, i64 stride) {
    using namespace simd;
    v2d acc = splat(0.0);
    double tail = 0.0;
    for (i64 i = 0; i < rows; ++i, p += stride) {
        i64 j = 0;
        for (; j + 2 <= cols; j += 2) {
            v2d x = load(p + j);
            acc += x - x;
        }
        if (j < cols) tail += p[j] - p[j];
    }
    return (acc[0] + acc[1]) + tail == 0.0;
}

// Rows r0..r1-1 of C = A @ B, each row zeroed then B's rows added (axpy, axpy2) where A's
// entry is nonzero, in t order: entry (i, j) is +0 plus the products A(i, t) B(t, j) of the
// nonzero A(i, t), added in t order. (Two rows a pass: B's row loaded once.)
inline void mm_rows(CMatRef A, CMatRef B, Mat& C, i64 r0, i64 r1) {
    i64 k = A.cols, n = B.cols;
    if (r1 > r0) zero_small(C.row(r0), static_cast<size_t>((r1 - r0) * n));  // C's rows contiguous
    i64 i = r0;
    for (; i + 2 <= r1; i += 2) {
        double* c0 = C.row(i);
        double* c1 = C.row(i + 1);
        for (i64 t = 0; t < k; ++t) {
            double a0 = A(i, t), a1 = A(i + 1, t);
            if (a0 != 0.0 && a1 != 0.0) axpy2(c0, c1, a0, a1, B.row(t), n);
            else if (a0 != 0.0) axpy(c0, a0, B.row(t), n);
            else if (a1 != 0.0) axpy(c1, a1, B.row(t), n);
        }
    }
    for (; i < r1; ++i) {
        double* ci = C.row(i);
        for (i64 t = 0; t < k; ++t) {
            double a = A(i, t);
            if (a != 0.0) axpy(ci, a, B.row(t), n);
        }
    }
}
}  // namespace detail

namespace detail {

// Rows r0..r3 of a product, columns j0 .. n (two or four at a time; the rest, an odd last
// column, left to the caller, whose column is returned): entry (r, j) = +0 plus AS[4 t + r]
// X(t, j) over t < k in t order, AS holding the four rows' entries broadcast to pairs and X
// rows `stride` apart (mm_into's and mtm_into's blocks: the same products in the same order).
// R < 4: the first R of the rows only (AS still four pairs a t; the others neither read nor
// written): each entry the same sum.
template <int R>
__attribute__((always_inline)) inline i64 blockr_rows(const simd::v2d* AS, const double* X, i64 stride, i64 k,
                                                      i64 j0, i64 n, double* r0, double* r1, double* r2,
                                                      double* r3) {
    using namespace simd;
    static_assert(R >= 2 && R <= 4, "two to four rows");
    i64 j = j0;
    for (; j + 4 <= n; j += 4) {
        v2d c0 = splat(0.0), c1 = splat(0.0), c2 = splat(0.0), c3 = splat(0.0);
        v2d d0 = splat(0.0), d1 = splat(0.0), d2 = splat(0.0), d3 = splat(0.0);
        const double* bp = X + j;
        const v2d* as = AS;
        for (i64 t = 0; t < k; ++t, bp += stride, as += 4) {
            v2d b0 = load(bp), b1 = load(bp + 2);
            v2d x = as[0];
            c0 += x * b0;
            d0 += x * b1;
            x = as[1];
            c1 += x * b0;
            d1 += x * b1;
            if constexpr (R >= 3) {
                x = as[2];
                c2 += x * b0;
                d2 += x * b1;
            }
            if constexpr (R >= 4) {
                x = as[3];
                c3 += x * b0;
                d3 += x * b1;
            }
        }
        store(r0 + j, c0);
        store(r0 + j + 2, d0);
        store(r1 + j, c1);
        store(r1 + j + 2, d1);
        if constexpr (R >= 3) {
            store(r2 + j, c2);
            store(r2 + j + 2, d2);
        }
        if constexpr (R >= 4) {
            store(r3 + j, c3);
            store(r3 + j + 2, d3);
        }
    }
    for (; j + 2 <= n; j += 2) {
        v2d c0 = splat(0.0), c1 = splat(0.0), c2 = splat(0.0), c3 = splat(0.0);
        const double* bp = X + j;
        const v2d* as = AS;
        for (i64 t = 0; t < k; ++t, bp += stride, as += 4) {
            v2d bt = load(bp);
            c0 += as[0] * bt;
            c1 += as[1] * bt;
            if constexpr (R >= 3) c2 += as[2] * bt;
            if constexpr (R >= 4) c3 += as[3] * bt;
        }
        store(r0 + j, c0);
        store(r1 + j, c1);
        if constexpr (R >= 3) store(r2 + j, c2);
        if constexpr (R >= 4) store(r3 + j, c3);
    }
    return j;
}

__attribute__((always_inline)) inline i64 block4_rows(const simd::v2d* AS, const double* X, i64 stride,
                                                      i64 k, i64 j0, i64 n, double* r0, double* r1,
                                                      double* r2, double* r3) {
    return blockr_rows<4>(AS, X, stride, k, j0, n, r0, r1, r2, r3);
}

// Column j of the same four rows (the odd last column block4_rows leaves): entry (r, j) =
// +0 plus AS[4 t + r] X(t, j) over t < k in t order, two rows a lane (two chains side by side
// rather than four sums one after the other). R < 4: the first R rows (R = 3: row 2's lane
// pairs with a +0 one, its result dropped).
template <int R>
__attribute__((always_inline)) inline void blockr_col(const simd::v2d* AS, const double* X, i64 stride, i64 k,
                                                      i64 j, double* r0, double* r1, double* r2, double* r3) {
    using namespace simd;
    v2d c01 = splat(0.0), c23 = splat(0.0);
    const double* bp = X + j;
    const v2d* as = AS;
    for (i64 t = 0; t < k; ++t, bp += stride, as += 4) {
        v2d x = splat(*bp);
        c01 += v2d{as[0][0], as[1][0]} * x;
        if constexpr (R == 3) c23 += v2d{as[2][0], 0.0} * x;
        if constexpr (R == 4) c23 += v2d{as[2][0], as[3][0]} * x;
    }
    r0[j] = c01[0];
    r1[j] = c01[1];
    if constexpr (R >= 3) r2[j] = c23[0];
    if constexpr (R >= 4) r3[j] = c23[1];
}

__attribute__((always_inline)) inline void block4_col(const simd::v2d* AS, const double* X, i64 stride, i64 k,
                                                      i64 j, double* r0, double* r1, double* r2, double* r3) {
    blockr_col<4>(AS, X, stride, k, j, r0, r1, r2, r3);
}

// Lays out rows a[0..R) (R of four pointers) for blockr_rows: AS[4 t + r] = (a[r][t], a[r][t]),
// t < k, two t a step. False (at the first t where some row's entry is zero: == 0.0, as the
// scalar tests) where any entry is zero; AS then partly written.
template <int R>
__attribute__((always_inline)) inline bool splat_rows(const double* const* a, i64 k, simd::v2d* AS) {
    using namespace simd;
    i64 t = 0;
    const v2d zero = splat(0.0);
    for (; t + 2 <= k; t += 2) {
        v2d x[R];
        v2i z = v2i{0, 0};
#pragma GCC unroll 4
        for (int r = 0; r < R; ++r) {
            x[r] = load(a[r] + t);
            z |= (x[r] == zero);
        }
        if ((z[0] | z[1]) != 0) return false;
#pragma GCC unroll 4
        for (int r = 0; r < R; ++r) {
            AS[4 * t + r] = __builtin_shuffle(x[r], v2i{0, 0});
            AS[4 * t + 4 + r] = __builtin_shuffle(x[r], v2i{1, 1});
        }
    }
    for (; t < k; ++t) {
        bool zero_entry = false;
#pragma GCC unroll 4
        for (int r = 0; r < R; ++r) zero_entry |= a[r][t] == 0.0;
        if (zero_entry) return false;
#pragma GCC unroll 4
        for (int r = 0; r < R; ++r) AS[4 * t + r] = splat(a[r][t]);
    }
    return true;
}

}  // namespace detail

// A @ B (skipping zero entries of A, as the reference does) into C (its storage kept).
// Each entry (i, j) is +0 plus the products A(i, t) B(t, j) of the nonzero A(i, t), added in t
// order. Four rows of A with no zero entry (A's entries, each broadcast to a pair, laid out
// once for them): blocks of C (four rows, four or two columns) summed in registers over t,
// from +0 (the same products in the same order: the same bits; an odd last column by
// detail::block4_col); other rows by detail::mm_rows.
inline void mm_into(CMatRef A, CMatRef B, Mat& C) {
    using namespace simd;
    i64 m = A.rows, k = A.cols, n = B.cols;
    constexpr i64 kSplat = 256;  // the most columns of A laid out on the stack (16 kB)
    shape(C, m, n);              // every entry written below
    i64 i = 0;
    if (n >= 2 && k <= kSplat && m >= 2) {
        v2d AS[4 * kSplat];
        for (; i + 4 <= m; i += 4) {
            const double* a[4] = {A.row(i), A.row(i + 1), A.row(i + 2), A.row(i + 3)};
            if (!detail::splat_rows<4>(a, k, AS)) {
                detail::mm_rows(A, B, C, i, i + 4);
                continue;
            }
            i64 j = detail::block4_rows(AS, B.p, B.stride, k, 0, n, C.row(i), C.row(i + 1), C.row(i + 2),
                                        C.row(i + 3));
            if (j < n)
                detail::block4_col(AS, B.p, B.stride, k, j, C.row(i), C.row(i + 1), C.row(i + 2), C.row(i + 3));
        }
        // The last three or two rows (no zero entry): the same blocks on those rows alone.
        if (m - i == 3) {
            const double* a[3] = {A.row(i), A.row(i + 1), A.row(i + 2)};
            if (detail::splat_rows<3>(a, k, AS)) {
                i64 j = detail::blockr_rows<3>(AS, B.p, B.stride, k, 0, n, C.row(i), C.row(i + 1), C.row(i + 2),
                                               nullptr);
                if (j < n)
                    detail::blockr_col<3>(AS, B.p, B.stride, k, j, C.row(i), C.row(i + 1), C.row(i + 2), nullptr);
                i = m;
            }
        } else if (m - i == 2) {
            const double* a[2] = {A.row(i), A.row(i + 1)};
            if (detail::splat_rows<2>(a, k, AS)) {
                i64 j = detail::blockr_rows<2>(AS, B.p, B.stride, k, 0, n, C.row(i), C.row(i + 1), nullptr, nullptr);
                if (j < n) detail::blockr_col<2>(AS, B.p, B.stride, k, j, C.row(i), C.row(i + 1), nullptr, nullptr);
                i = m;
            }
        }
    }
    detail::mm_rows(A, B, C, i, m);
}

// A @ B (skipping zero entries of A, as the reference does).
inline Mat mm(CMatRef A, CMatRef B) {
    Mat C;
    mm_into(A, B, C);
    return C;
}

namespace detail {
// Rows r0..r1-1 of the upper triangle of C = A^T A: C(i, j) for j >= i is +0 plus the products
// A(t, i) A(t, j) of the nonzero A(t, i), added in t order (row i of C zeroed from i on, then
// A's rows added by axpy where A(t, i) is nonzero).
// (Where A has at most kList rows: row i's list of the nonzero A(t, i) made first, then each
// entry C(i, j) summed in registers over it, columns eight, two or one at a time: the same
// products added in the same order to +0, each entry stored once. A row with an entry not
// finite is made again by the axpy passes below: only there could a NaN meet another NaN of
// another sign or payload, where the one kept follows the operand order the compiler picks;
// with every entry finite, every product and sum was finite and the bits are the same.)
inline void mtm_rows(CMatRef A, Mat& C, i64 r0, i64 r1) {
    i64 m = A.rows, n = A.cols;
    constexpr i64 kList = 256;
    if (m <= kList) {
        using namespace simd;
        i64 ts[kList];
        double as[kList];
        const double* A0 = A.p;
        const i64 lda = A.stride;
        for (i64 i = r0; i < r1; ++i) {
            i64 nt = 0;
            for (i64 t = 0; t < m; ++t) {
                const double a = A0[t * lda + i];
                if (a != 0.0) {
                    ts[nt] = t;
                    as[nt] = a;
                    ++nt;
                }
            }
            double* ci = C.row(i);
            v2d fin = splat(0.0);  // the sum of c - c over the row's entries: 0 where all finite
            double fin1 = 0.0;
            i64 j = i;
            for (; j + 8 <= n; j += 8) {
                v2d c0 = splat(0.0), c1 = splat(0.0), c2 = splat(0.0), c3 = splat(0.0);
                for (i64 a = 0; a < nt; ++a) {
                    const double* bp = A0 + ts[a] * lda + j;
                    const v2d x = splat(as[a]);
                    c0 += x * load(bp);
                    c1 += x * load(bp + 2);
                    c2 += x * load(bp + 4);
                    c3 += x * load(bp + 6);
                }
                store(ci + j, c0);
                store(ci + j + 2, c1);
                store(ci + j + 4, c2);
                store(ci + j + 6, c3);
                fin += ((c0 - c0) + (c1 - c1)) + ((c2 - c2) + (c3 - c3));
            }
            for (; j + 2 <= n; j += 2) {
                v2d c0 = splat(0.0);
                for (i64 a = 0; a < nt; ++a) c0 += splat(as[a]) * load(A0 + ts[a] * lda + j);
                store(ci + j, c0);
                fin += c0 - c0;
            }
            for (; j < n; ++j) {
                double c0 = 0.0;
                for (i64 a = 0; a < nt; ++a) c0 += as[a] * A0[ts[a] * lda + j];
                ci[j] = c0;
                fin1 += c0 - c0;
            }
            if (!((fin[0] + fin[1]) + fin1 == 0.0)) {  // (rare) the row again, as below
                zero_small(ci + i, static_cast<size_t>(n - i));
                for (i64 t = 0; t < m; ++t) {
                    const double* at = A.row(t);
                    double a = at[i];
                    if (a != 0.0) axpy(ci + i, a, at + i, n - i);
                }
            }
        }
        return;
    }
    for (i64 i = r0; i < r1; ++i) zero_small(C.row(i) + i, static_cast<size_t>(n - i));
    for (i64 t = 0; t < m; ++t) {
        const double* at = A.row(t);
        for (i64 i = r0; i < r1; ++i) {
            double a = at[i];
            if (a != 0.0) axpy(C.row(i) + i, a, at + i, n - i);
        }
    }
}
}  // namespace detail

// A^T @ A (symmetric, computed once per pair) into C (its storage kept): C(i, j) is +0 plus
// the products A(t, i) A(t, j) of the nonzero A(t, i), added in t order, for j >= i; the lower
// triangle copied from the upper one.
// (Four rows of C whose columns of A hold no zero entry (A(t, i..i+3) broadcast to pairs once,
// on the stack): the upper triangle's blocks of four rows and four or two columns summed in
// registers over t from +0 (the same products in the same order: the same bits; a block's
// entries below the diagonal are overwritten by the copy), up to the first block with a zero;
// the rows from there by detail::mtm_rows.)
inline void mtm_into(CMatRef A, Mat& C) {
    using namespace simd;
    // A's rows with no nonzero entry add no product to any entry (every one skipped): where
    // there are such rows (and the rest fit on the stack), the others are copied together,
    // in order (the same products in the same order), so that the register blocks below
    // can take them.
    constexpr i64 kCompact = 4096;  // the most entries copied (32 kB)
    double kept[kCompact];
    if (A.rows * A.cols <= kCompact && A.rows >= 4 && A.cols >= 4) {
        auto zero_row = [&](i64 t) {
            const double* at = A.row(t);
            for (i64 c = 0; c < A.cols; ++c)
                if (at[c] != 0.0) return false;
            return true;
        };
        i64 first = 0;
        while (first < A.rows && !zero_row(first)) ++first;
        if (first < A.rows) {
            for (i64 t = 0; t < first; ++t)
                std::memcpy(kept + t * A.cols, A.row(t), static_cast<size_t>(A.cols) * sizeof(double));
            i64 nz = first;
            for (i64 t = first + 1; t < A.rows; ++t) {
                if (zero_row(t)) continue;
                std::memcpy(kept + nz * A.cols, A.row(t), static_cast<size_t>(A.cols) * sizeof(double));
                ++nz;
            }
            A = CMatRef(kept, nz, A.cols);
        }
    }
    i64 m = A.rows, n = A.cols;
    shape(C, n, n);  // the upper triangle summed from +0, the lower one copied from it
    constexpr i64 kSplat = 256;  // the most rows of A laid out on the stack (16 kB)
    i64 i = 0;
    if (n >= 4 && m <= kSplat) {
        v2d AS[4 * kSplat];
        for (; i + 4 <= n; i += 4) {
            bool zero = false;
            const v2d z0 = splat(0.0);
            for (i64 t = 0; t < m; ++t) {
                const double* at = A.row(t) + i;
                v2d lo = load(at), hi = load(at + 2);
                v2i z = (lo == z0) | (hi == z0);  // (== 0.0 per entry, as the scalar tests)
                zero = (z[0] | z[1]) != 0;
                if (zero) break;
                AS[4 * t] = __builtin_shuffle(lo, v2i{0, 0});
                AS[4 * t + 1] = __builtin_shuffle(lo, v2i{1, 1});
                AS[4 * t + 2] = __builtin_shuffle(hi, v2i{0, 0});
                AS[4 * t + 3] = __builtin_shuffle(hi, v2i{1, 1});
            }
            if (zero) break;  // this row and the rest by mtm_rows (one pass over A)
            i64 j = detail::block4_rows(AS, A.p, A.stride, m, i, n, C.row(i), C.row(i + 1), C.row(i + 2),
                                        C.row(i + 3));
            if (j < n)
                detail::block4_col(AS, A.p, A.stride, m, j, C.row(i), C.row(i + 1), C.row(i + 2), C.row(i + 3));
        }
    }
    detail::mtm_rows(A, C, i, n);
    // The lower triangle copied from the upper one (copies only), by 2x2 blocks: rows r, r+1
    // from columns r, r+1 of rows j, j+1 < r (two loads, two shuffles, two stores), then the
    // one entry C(r + 1, r) of the diagonal block; an odd last row one entry at a time.
    i64 r = 0;
    for (; r + 2 <= n; r += 2) {
        double* c0 = C.row(r);
        double* c1 = C.row(r + 1);
        for (i64 j = 0; j < r; j += 2) {
            v2d u0 = load(C.row(j) + r), u1 = load(C.row(j + 1) + r);
            store(c0 + j, __builtin_shuffle(u0, u1, v2i{0, 2}));
            store(c1 + j, __builtin_shuffle(u0, u1, v2i{1, 3}));
        }
        c1[r] = c0[r + 1];
    }
    for (; r < n; ++r)
        for (i64 j = 0; j < r; ++j) C(r, j) = C(j, r);
}

// A^T @ A (symmetric, computed once per pair).
inline Mat mtm(CMatRef A) {
    Mat C;
    mtm_into(A, C);
    return C;
}

// A @ x into y (its storage kept).
inline void mv_into(CMatRef A, const double* x, Vec& y) {
    i64 m = A.rows, n = A.cols;
    y.resize(static_cast<size_t>(m));
    i64 i = 0;
    for (; i + 4 <= m; i += 4)
        dot4(A.row(i), A.row(i + 1), A.row(i + 2), A.row(i + 3), x, n, y[i], y[i + 1], y[i + 2], y[i + 3]);
    for (; i + 2 <= m; i += 2) dot2(A.row(i), A.row(i + 1), x, n, y[i], y[i + 1]);
    for (; i < m; ++i) {
        const double* ai = A.row(i);
        double acc = 0.0;
        for (i64 j = 0; j < n; ++j) acc += ai[j] * x[j];
        y[i] = acc;
    }
}

// A @ x.
inline Vec mv(CMatRef A, const double* x) {
    Vec y;
    mv_into(A, x, y);
    return y;
}

// A^T @ x into y (its storage kept).
inline void mtv_into(CMatRef A, const double* x, Vec& y) {
    i64 m = A.rows, n = A.cols;
    y.assign(static_cast<size_t>(n), 0.0);
    for (i64 i = 0; i < m; ++i) {
        double a = x[i];
        if (a != 0.0) axpy(y.data(), a, A.row(i), n);
    }
}

// A^T @ x.
inline Vec mtv(CMatRef A, const double* x) {
    Vec y;
    mtv_into(A, x, y);
    return y;
}

// x @ y for vectors of length n.
// (Four terms a pass, added in index order.)
inline double dot(const double* x, const double* y, i64 n) {
    double acc = 0.0;
    i64 i = 0;
    for (; i + 4 <= n; i += 4) {
        acc += x[i] * y[i];
        acc += x[i + 1] * y[i + 1];
        acc += x[i + 2] * y[i + 2];
        acc += x[i + 3] * y[i + 3];
    }
    for (; i < n; ++i) acc += x[i] * y[i];
    return acc;
}

// Columns c0:c1 of M, copied.
inline Mat columns(CMatRef M, i64 c0, i64 c1) {
    Mat out(M.rows, c1 - c0);
    for (i64 i = 0; i < M.rows; ++i)
        for (i64 j = c0; j < c1; ++j) out(i, j - c0) = M(i, j);
    return out;
}

inline void transposed_into(CMatRef M, Mat& out) {
    shape(out, M.cols, M.rows);  // every entry written
    for (i64 i = 0; i < M.rows; ++i)
        for (i64 j = 0; j < M.cols; ++j) out(j, i) = M(i, j);
}

inline Mat transposed(CMatRef M) {
    Mat out;
    transposed_into(M, out);
    return out;
}

// Smallest singular value of M (p, m), p <= m, by one-sided Jacobi rotations of its rows
// (Hestenes).
inline double min_singular(CMatRef M) {
    i64 p = M.rows, m = M.cols;
    Mat U(p, m);
    for (i64 i = 0; i < p; ++i)
        for (i64 k = 0; k < m; ++k) U(i, k) = M(i, k);
    for (int sweep = 0; sweep < 60; ++sweep) {
        bool rotated = false;
        for (i64 i = 0; i < p - 1; ++i) {
            for (i64 j = i + 1; j < p; ++j) {
                double* ui_ = U.row(i);
                double* uj_ = U.row(j);
                double alpha = 0.0, beta = 0.0, gamma = 0.0;
                for (i64 k = 0; k < m; ++k) {
                    alpha += ui_[k] * ui_[k];
                    beta += uj_[k] * uj_[k];
                    gamma += ui_[k] * uj_[k];
                }
                if (gamma == 0.0 || std::fabs(gamma) <= 1e-15 * std::sqrt(alpha * beta)) continue;
                rotated = true;
                double zeta = (beta - alpha) / (2.0 * gamma);
                double t = (zeta >= 0.0 ? 1.0 : -1.0) / (std::fabs(zeta) + std::sqrt(1.0 + zeta * zeta));
                double cs = 1.0 / std::sqrt(1.0 + t * t);
                double sn = cs * t;
                for (i64 k = 0; k < m; ++k) {
                    double ui = ui_[k];
                    double uj = uj_[k];
                    ui_[k] = cs * ui - sn * uj;
                    uj_[k] = sn * ui + cs * uj;
                }
            }
        }
        if (!rotated) break;
    }
    double smallest = kInf;
    for (i64 i = 0; i < p; ++i) {
        double norm = 0.0;
        for (i64 k = 0; k < m; ++k) norm += U(i, k) * U(i, k);
        smallest = pymin(smallest, std::sqrt(norm));
    }
    return smallest;
}

namespace detail {

// sqrt(a^2 + b^2) without overflow (IEEE operations only: the same bits everywhere).
inline double safe_hypot(double a, double b) {
    a = std::fabs(a);
    b = std::fabs(b);
    if (a < b) std::swap(a, b);
    if (a == 0.0) return 0.0;
    double q = b / a;
    return a * std::sqrt(1.0 + q * q);
}

}  // namespace detail

// Eigenvectors of the symmetric V (n, n), in place: on return row k of V is the k-th
// eigenvector (V^T on return holds them as columns) and d[k] its eigenvalue (unsorted).
// Householder tridiagonalisation then the implicit QL method (EISPACK tred2 / tql2, as JAMA
// writes them), every loop in one fixed order. false where QL did not converge in 30 n
// iterations (V then holds no meaning).
// vectors false: the eigenvalues alone (the same d; V then holds no meaning, Vt is not used):
// neither the reflections are accumulated nor the QL rotations applied to vectors.
inline bool sym_eigen(Mat& V, Vec& d, Vec& e, Mat& Vt, bool vectors = true) {
    i64 n = V.rows;
    d.assign(static_cast<size_t>(n), 0.0);
    e.assign(static_cast<size_t>(n), 0.0);
    if (n == 0) return true;
    for (i64 j = 0; j < n; ++j) d[j] = V(n - 1, j);
    for (i64 i = n - 1; i > 0; --i) {
        double scale = 0.0, h = 0.0;
        for (i64 k = 0; k < i; ++k) scale += std::fabs(d[k]);
        if (scale == 0.0) {
            e[i] = d[i - 1];
            for (i64 j = 0; j < i; ++j) {
                d[j] = V(i - 1, j);
                V(i, j) = 0.0;
                V(j, i) = 0.0;
            }
        } else {
            for (i64 k = 0; k < i; ++k) {
                d[k] /= scale;
                h += d[k] * d[k];
            }
            double f = d[i - 1];
            double g = std::sqrt(h);
            if (f > 0.0) g = -g;
            e[i] = scale * g;
            h = h - f * g;
            d[i - 1] = f - g;
            for (i64 j = 0; j < i; ++j) e[j] = 0.0;
            // (columns j, j + 1 side by side: their sums g as two independent chains in the
            // lanes of one vector, each e[k] updated by column j then j + 1 as in the loop
            // over j one at a time: the same operations in the same order per value)
            i64 j = 0;
            for (; j + 1 < i; j += 2) {
                using namespace simd;
                const double f0 = d[j], f1 = d[j + 1];
                V(j, i) = f0;
                double g0 = e[j] + V(j, j) * f0;
                g0 += V(j + 1, j) * d[j + 1];
                e[j + 1] += V(j + 1, j) * f0;
                V(j + 1, i) = f1;
                const double g1 = e[j + 1] + V(j + 1, j + 1) * f1;
                v2d gg = v2d{g0, g1};
                for (i64 k = j + 2; k <= i - 1; ++k) {
                    const double* vk = V.row(k) + j;
                    gg += load(vk) * splat(d[k]);
                    e[k] = (e[k] + vk[0] * f0) + vk[1] * f1;
                }
                e[j] = gg[0];
                e[j + 1] = gg[1];
            }
            for (; j < i; ++j) {
                f = d[j];
                V(j, i) = f;
                g = e[j] + V(j, j) * f;
                for (i64 k = j + 1; k <= i - 1; ++k) {
                    g += V(k, j) * d[k];
                    e[k] += V(k, j) * f;
                }
                e[j] = g;
            }
            f = 0.0;
            for (i64 j = 0; j < i; ++j) {
                e[j] /= h;
                f += e[j] * d[j];
            }
            double hh = f / (h + h);
            for (i64 j = 0; j < i; ++j) e[j] -= hh * d[j];
            // (columns j, j + 1 in the lanes of one vector: the same operations per entry)
            j = 0;
            for (; j + 1 < i; j += 2) {
                using namespace simd;
                const double f0 = d[j], g0 = e[j];
                const v2d f2 = v2d{f0, d[j + 1]}, g2 = v2d{g0, e[j + 1]};
                V(j, j) -= (f0 * e[j] + g0 * d[j]);
                for (i64 k = j + 1; k <= i - 1; ++k) {
                    double* vk = V.row(k) + j;
                    store(vk, load(vk) - (f2 * splat(e[k]) + g2 * splat(d[k])));
                }
                d[j] = V(i - 1, j);
                V(i, j) = 0.0;
                d[j + 1] = V(i - 1, j + 1);
                V(i, j + 1) = 0.0;
            }
            for (; j < i; ++j) {
                f = d[j];
                g = e[j];
                for (i64 k = j; k <= i - 1; ++k) V(k, j) -= (f * e[k] + g * d[k]);
                d[j] = V(i - 1, j);
                V(i, j) = 0.0;
            }
        }
        d[i] = h;
    }
    if (!vectors) {
        // The tridiagonal's diagonal, as the accumulation below leaves it in d.
        for (i64 j = 0; j < n; ++j) d[j] = V(j, j);
    }
    for (i64 i = 0; i < n - 1 && vectors; ++i) {
        V(n - 1, i) = V(i, i);
        V(i, i) = 1.0;
        double h = d[i + 1];
        if (h != 0.0) {
            for (i64 k = 0; k <= i; ++k) d[k] = V(k, i + 1) / h;
            for (i64 j = 0; j <= i; ++j) {
                double g = 0.0;
                for (i64 k = 0; k <= i; ++k) g += V(k, i + 1) * V(k, j);
                for (i64 k = 0; k <= i; ++k) V(k, j) -= g * d[k];
            }
        }
        for (i64 k = 0; k <= i; ++k) V(k, i + 1) = 0.0;
    }
    if (vectors) {
        for (i64 j = 0; j < n; ++j) {
            d[j] = V(n - 1, j);
            V(n - 1, j) = 0.0;
        }
        V(n - 1, n - 1) = 1.0;
    }
    e[0] = 0.0;
    // QL on the rows of Vt = V^T (a rotation of columns i, i+1 of V is one of rows: contiguous).
    if (vectors) transposed_into(V.cref(), Vt);
    for (i64 i = 1; i < n; ++i) e[i - 1] = e[i];
    e[n - 1] = 0.0;
    double f = 0.0, tst1 = 0.0;
    const double eps = 2.220446049250313e-16;
    i64 budget = 30 * n;
    for (i64 l = 0; l < n; ++l) {
        tst1 = pymax(tst1, std::fabs(d[l]) + std::fabs(e[l]));
        i64 m = l;
        while (m < n) {
            if (std::fabs(e[m]) <= eps * tst1) break;
            ++m;
        }
        if (m == n) m = n - 1;
        if (m > l) {
            do {
                if (--budget < 0) return false;
                double g = d[l];
                double p = (d[l + 1] - g) / (2.0 * e[l]);
                double r = detail::safe_hypot(p, 1.0);
                if (p < 0) r = -r;
                d[l] = e[l] / (p + r);
                d[l + 1] = e[l] * (p + r);
                double dl1 = d[l + 1];
                double h = g - d[l];
                for (i64 i = l + 2; i < n; ++i) d[i] -= h;
                f = f + h;
                p = d[m];
                double c = 1.0, c2 = 1.0, c3 = 1.0;
                double el1 = e[l + 1];
                double s = 0.0, s2 = 0.0;
                for (i64 i = m - 1; i >= l; --i) {
                    c3 = c2;
                    c2 = c;
                    s2 = s;
                    g = c * e[i];
                    h = c * p;
                    r = detail::safe_hypot(p, e[i]);
                    e[i + 1] = s * r;
                    s = e[i] / r;
                    c = p / r;
                    p = c * d[i] - s * g;
                    d[i + 1] = h + s * (c * g + s * d[i]);
                    // columns i, i+1 of V: new i+1 = s v_i + c v_{i+1}, new i = c v_i - s v_{i+1}
                    if (vectors) jacobi_rows(Vt.row(i), Vt.row(i + 1), c, s, n);
                }
                p = -s * s2 * c3 * el1 * e[l] / dl1;
                e[l] = s * p;
                d[l] = c * p;
            } while (std::fabs(e[l]) > eps * tst1);
        }
        d[l] = d[l] + f;
        e[l] = 0.0;
    }
    if (vectors) std::swap(V, Vt);
    return true;
}

namespace detail {

// reflect_row_set's pass over the 2 L columns j.. (L pairs) and, with Odd, the one column
// after them (a scalar lane): s summed over t in order in registers, stored to S, then the
// columns updated (and their norms of rows 1.., Norms). Every column's sum is its own chain
// over t: the more columns a pass holds, the more chains run side by side (the sums are
// latency-bound: one add a row per chain).
// Vn: vn is not given but summed here, |x|^2 over t in order from 0.0 in the sum's pass (the
// chain reflect() would sum before the pass: the same bits, its latency hidden by the
// columns' sums), returned in vn_out; where it is 0, nothing is updated (false returned).
template <int L, bool Odd, bool Norms, class Row, bool Vn = false>
__attribute__((always_inline)) inline bool reflect_block(Row row, i64 size, i64 j, const double* x, double vn,
                                                         double* S, double* N, double* vn_out = nullptr) {
    using namespace simd;
    constexpr int LA = L > 0 ? L : 1;
    v2d s[LA], nn[LA];
    double so = 0.0, no = 0.0, vs = 0.0;
#pragma GCC unroll 8
    for (int l = 0; l < L; ++l) s[l] = nn[l] = splat(0.0);
    for (i64 t = 0; t < size; ++t) {
        const double* p = row(t) + j;
        double xs = x[t];
        v2d xt = splat(xs);
#pragma GCC unroll 8
        for (int l = 0; l < L; ++l) s[l] += xt * load(p + 2 * l);
        if constexpr (Odd) so += xs * p[2 * L];
        if constexpr (Vn) vs += xs * xs;
    }
    if constexpr (Vn) {
        *vn_out = vs;
        if (vs == 0.0) return false;
        vn = vs;
    }
    v2d two = splat(2.0), vv = splat(vn);
#pragma GCC unroll 8
    for (int l = 0; l < L; ++l) {
        s[l] = two * s[l] / vv;
        store(S + j + 2 * l, s[l]);
    }
    if constexpr (Odd) {
        so = 2.0 * so / vn;
        S[j + 2 * L] = so;
    }
    // Row t's update (its squares added to the norms where Acc: rows 1..).
    auto update = [&](i64 t, auto acc) __attribute__((always_inline)) {
        constexpr bool Acc = decltype(acc)::value;
        double* q = row(t) + j;
        double xs = x[t];
        v2d xt = splat(xs);
#pragma GCC unroll 8
        for (int l = 0; l < L; ++l) {
            v2d u = load(q + 2 * l) - xt * s[l];
            store(q + 2 * l, u);
            if constexpr (Acc) nn[l] += u * u;
        }
        if constexpr (Odd) {
            double u0 = q[2 * L] - xs * so;
            q[2 * L] = u0;
            if constexpr (Acc) no += u0 * u0;
        }
    };
    if constexpr (Norms) {
        if (size > 0) update(0, std::false_type{});
        for (i64 t = 1; t < size; ++t) update(t, std::true_type{});
#pragma GCC unroll 8
        for (int l = 0; l < L; ++l) store(N + j + 2 * l, nn[l]);
        if constexpr (Odd) N[j + 2 * L] = no;
    } else {
        for (i64 t = 0; t < size; ++t) update(t, std::false_type{});
    }
    return true;
}

// The last 1..17 columns from j in one pass (n pairs and, where n is odd, the column after).
// Vn: |x|^2 summed in that pass (vn not read) into *vn_out, and false, nothing updated, where it
// is 0 (reflect_block's Vn); else true.
template <bool Norms, bool Vn = false, class Row>
inline bool reflect_tail(Row row, i64 size, i64 j, i64 n, const double* x, double vn, double* S, double* N,
                         double* vn_out = nullptr) {
    switch (n) {
        case 1: return reflect_block<0, true, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 2: return reflect_block<1, false, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 3: return reflect_block<1, true, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 4: return reflect_block<2, false, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 5: return reflect_block<2, true, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 6: return reflect_block<3, false, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 7: return reflect_block<3, true, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 8: return reflect_block<4, false, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 9: return reflect_block<4, true, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 10: return reflect_block<5, false, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 11: return reflect_block<5, true, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 12: return reflect_block<6, false, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 13: return reflect_block<6, true, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 14: return reflect_block<7, false, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 15: return reflect_block<7, true, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 16: return reflect_block<8, false, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        case 17: return reflect_block<8, true, Norms, Row, Vn>(row, size, j, x, vn, S, N, vn_out);
        default: return false;
    }
}

// The Householder reflection (x, |x|^2 = vn) applied to w columns of the rows row(0..size-1)
// (row(t): a pointer to the first of them in row t): per column, s_j = 2 (sum_t x[t] M(t, j)) / vn,
// then M(t, j) -= s_j x[t]. Up to 17 columns in one pass (pairs, and an odd last column as a
// scalar lane): s_j summed over t in order in registers, then those columns updated; wider
// sets by passes of sixteen (or eight) columns first. Per column the same operations in the
// same order whatever the blocking (reflect_columns: contiguous rows; certify.hpp's
// reflect_rows: a subset of a matrix's rows).
// Norms: also N[j] = sum_{t >= 1} M(t, j)^2 of the updated columns, summed over t in order
// from 0.0 in the update's pass (the sums col_sq makes of rows 1..size-1 afterwards: the same
// bits, without reading the rows again).
template <class Row, bool Norms = false>
inline void reflect_row_set(Row row, i64 size, i64 w, const double* x, double vn, double* S, double* N = nullptr) {
    i64 j = 0;
    while (w - j > 17) {
        if (w - j >= 24) {
            reflect_block<8, false, Norms>(row, size, j, x, vn, S, N);
            j += 16;
        } else {
            reflect_block<4, false, Norms>(row, size, j, x, vn, S, N);
            j += 8;
        }
    }
    reflect_tail<Norms>(row, size, j, w - j, x, vn, S, N);
}

// reflect_row_set on columns j0..m-1 of rows i..i+size-1 of M (row stride ld).
// N: also N[j - j0] = |M[i+1 : i+size, j]|^2 of the updated columns (reflect_row_set's Norms).
inline void reflect_columns(double* M, i64 ld, i64 i, i64 size, i64 j0, i64 m, const double* x, double vn,
                            double* S, double* N = nullptr) {
    i64 w = m - j0;
    if (w <= 0) return;
    double* base = M + i * ld + j0;
    auto row = [base, ld](i64 t) { return base + t * ld; };
    if (N) reflect_row_set<decltype(row), true>(row, size, w, x, vn, S, N);
    else reflect_row_set<decltype(row), false>(row, size, w, x, vn, S);
}

// Column pivoting step: bring the column of largest remaining norm to position i.
inline void swap_pivot(Mat& R, Vec& norms, IVec& perm, i64 i) {
    i64 best = i;
    for (i64 j = i + 1; j < R.cols; ++j)
        if (norms[j] > norms[best]) best = j;
    if (best != i) {
        for (i64 t = 0; t < R.rows; ++t) std::swap(R(t, i), R(t, best));
        std::swap(norms[i], norms[best]);
        std::swap(perm[i], perm[best]);
    }
}

// The Householder reflection zeroing R[i+1:, i], applied to R (left) and Q (right; Q
// with no rows: R only, the same R). norms: on entry norms[i] = |R[i:, i]|^2 as column_norms
// sums it (householder_qr's pivoting keeps them so: the reflection's sum of squares is taken
// from it); where R was reflected (true returned), also norms[j] = |R[i+1:, j]|^2 for j >= i
// (column_norms(R, i + 1, norms)'s sums, from the reflection's pass; norms[i] too).
inline bool reflect(Mat& R, Mat& Q, Vec& x, Vec& S, i64 i, double* keep_x = nullptr, double* keep_vn = nullptr,
                    double* norms = nullptr) {
    i64 r = Q.rows, m = R.cols;
    i64 size = R.rows - i;
    if (keep_vn) *keep_vn = 0.0;
    double alpha = 0.0;
    if (norms) {
        // norms[i] is already this sum: |R[i:, i]|^2 summed over the rows in order from 0.0
        // (column_norms, or the previous reflection's pass, then swap_pivot), the same bits
        // without its serial chain of additions.
        for (i64 t = 0; t < size; ++t) x[t] = R(i + t, i);
        alpha = norms[i];
    } else {
        for (i64 t = 0; t < size; ++t) {
            x[t] = R(i + t, i);
            alpha += x[t] * x[t];
        }
    }
    alpha = std::sqrt(alpha);
    if (alpha == 0.0) return false;
    if (x[0] > 0.0) alpha = -alpha;
    x[0] -= alpha;
    if (norms && r == 0 && m - i >= 1 && m - i <= 17) {
        // (R alone, the columns in one pass: |x|^2 summed in that pass, reflect_block's Vn)
        double* base = R.row(i) + i;
        const i64 ld = R.cols;
        auto rowp = [base, ld](i64 t) { return base + t * ld; };
        double vn = 0.0;
        if (!reflect_tail<true, true>(rowp, size, 0, m - i, x.data(), 0.0, S.data(), norms + i, &vn)) return false;
        if (keep_vn) {
            *keep_vn = vn;
            std::memcpy(keep_x + i, x.data(), static_cast<size_t>(size) * sizeof(double));
        }
        return true;
    }
    double vn = 0.0;
    for (i64 t = 0; t < size; ++t) vn += x[t] * x[t];
    if (vn == 0.0) return false;
    if (keep_vn) {
        *keep_vn = vn;
        std::memcpy(keep_x + i, x.data(), static_cast<size_t>(size) * sizeof(double));
    }
    reflect_columns(R.row(0), R.cols, i, size, i, m, x.data(), vn, S.data(), norms ? norms + i : nullptr);
    i64 row = 0;
    // (four rows a pass, then two: each row's sum in t order from 0.0, one per lane)
    for (; row + 4 <= r; row += 4) {
        double* q0 = Q.row(row) + i;
        double* q1 = Q.row(row + 1) + i;
        double* q2 = Q.row(row + 2) + i;
        double* q3 = Q.row(row + 3) + i;
        double s0, s1, s2, s3;
        dot4(q0, q1, q2, q3, x.data(), size, s0, s1, s2, s3);
        axmy(q0, 2.0 * s0 / vn, x.data(), size);
        axmy(q1, 2.0 * s1 / vn, x.data(), size);
        axmy(q2, 2.0 * s2 / vn, x.data(), size);
        axmy(q3, 2.0 * s3 / vn, x.data(), size);
    }
    for (; row + 2 <= r; row += 2) {
        double* q0 = Q.row(row) + i;
        double* q1 = Q.row(row + 1) + i;
        double s0, s1;
        dot2(q0, q1, x.data(), size, s0, s1);
        axmy(q0, 2.0 * s0 / vn, x.data(), size);
        axmy(q1, 2.0 * s1 / vn, x.data(), size);
    }
    for (; row < r; ++row) {
        double* qr = Q.row(row);
        double s = 0.0;
        for (i64 t = 0; t < size; ++t) s += qr[i + t] * x[t];
        s = 2.0 * s / vn;
        axmy(qr + i, s, x.data(), size);
    }
    return true;
}

// norms[j] = |R[start:, j]|^2 for the columns from start on.
inline void column_norms(const Mat& R, i64 start, Vec& norms) {
    i64 j0 = std::max<i64>(start, 0);
    col_sq(R.a.data(), R.cols, start, R.rows, j0, R.cols, norms.data());
}

}  // namespace detail

// The scratch vectors of householder_qr (kept by a caller that factors often). With
// keep_reflectors, V row i holds step i's Householder vector x (entries i..r-1 of the row,
// the rest 0) and vn[i] = |x|^2 (0 where the step reflected nothing), so that
// Q = H_0 H_1 ... H_{k-1}, H_i = I - 2 x x^T / vn[i], can be applied without forming it.
// compact: the last factorisation left out M's zero rows (see householder_qr): map lists the
// rows it took, in order, and Vc holds the reflectors on those rows alone (Vc(i, t) =
// V(i, map[t]); V's other entries are +0).
struct QRScratch {
    Vec norms, x, S;
    bool keep_reflectors = false;
    Mat V;
    Vec vn;
    bool compact = false;
    IVec map;
    Mat Rc, Vc;
    // null_basis's scratch where compact (cascade.hpp: null_basis_compact)
    IVec pos;
    Mat Ec, T;
};

namespace detail {

// Whether every entry of the row is +0 (its bits all zero).
inline bool plus_zero_row(const double* a, i64 n) {
    for (i64 j = 0; j < n; ++j) {
        std::uint64_t u;
        std::memcpy(&u, a + j, sizeof u);
        if (u != 0) return false;
    }
    return true;
}

// householder_qr's steps on R (r, m) in place (Q: no rows, or R's rows' Q), the reflectors
// into V (V: null where not kept) and ws.vn. check: false as soon as a step's factors S are
// not all finite (the rest not done).
inline bool qr_steps(Mat& R, bool pivot, Mat& Q, IVec& perm, QRScratch& ws, Mat* V, bool check) {
    i64 r = R.rows, m = R.cols;
    perm.assign(static_cast<size_t>(m), 0);
    for (i64 j = 0; j < m; ++j) perm[j] = j;
    // (norms, x and S sized only: each entry written before it is read)
    Vec& norms = ws.norms;
    shape(norms, static_cast<size_t>(m));
    if (pivot) column_norms(R, 0, norms);
    Vec& x = ws.x;
    Vec& S = ws.S;
    shape(x, static_cast<size_t>(r));
    shape(S, static_cast<size_t>(m));
    i64 steps = std::min(r, m);
    if (V) {
        V->zeros(steps, r);
        ws.vn.assign(static_cast<size_t>(steps), 0.0);
    }
    for (i64 i = 0; i < steps; ++i) {
        if (pivot) swap_pivot(R, norms, perm, i);
        // (with pivoting, the next step's column norms summed in the reflection's pass)
        double* nrm = pivot ? norms.data() : nullptr;
        bool done = V ? reflect(R, Q, x, S, i, V->row(i), &ws.vn[static_cast<size_t>(i)], nrm)
                      : reflect(R, Q, x, S, i, nullptr, nullptr, nrm);
        if (check && done)
            for (i64 j = 0; j < m - i; ++j)
                if (!std::isfinite(S[j])) return false;
        if (pivot && !done) column_norms(R, i + 1, norms);
    }
    return true;
}

}  // namespace detail

// ... and at least this many zero entries in the columns (a few short columns: the copies cost
// more than the reflections they save).
constexpr i64 kZeroRowsLeftOut = 8;
constexpr i64 kZeroWorkLeftOut = 96;
namespace detail {
// householder_qr's factorisation without M's zero rows (see there): false, nothing of R, perm or
// the reflectors kept, where there are fewer than kZeroRowsLeftOut or a step's factors are not
// finite. (Out of line: the common path's code as it was.)
__attribute__((noinline)) inline bool householder_qr_compact(CMatRef M, bool pivot, Mat& Q, Mat& R, IVec& perm,
                                                             QRScratch& ws) {
    i64 r = M.rows, m = M.cols;
    i64 steps = std::min(r, m);
    i64 zeros = 0;
    for (i64 t = steps; t < r && zeros + (r - t) >= kZeroRowsLeftOut; ++t)
        if (plus_zero_row(M.row(t), m)) zeros += 1;
    if (zeros < kZeroRowsLeftOut || zeros * m < kZeroWorkLeftOut) return false;
    IVec& map = ws.map;
    map.clear();
    for (i64 t = 0; t < r; ++t)
        if (t < steps || !plus_zero_row(M.row(t), m)) map.push_back(t);
    i64 rc = static_cast<i64>(map.size());
    Mat& Rc = ws.Rc;
    shape(Rc, rc, m);  // every entry copied
    for (i64 t = 0; t < rc; ++t) std::memcpy(Rc.row(t), M.row(map[t]), static_cast<size_t>(m) * sizeof(double));
    Q.zeros(0, rc);
    Mat* V = ws.keep_reflectors ? &ws.Vc : nullptr;
    if (!qr_steps(Rc, pivot, Q, perm, ws, V, true)) return false;
    R.zeros(r, m);
    for (i64 t = 0; t < rc; ++t) std::memcpy(R.row(map[t]), Rc.row(t), static_cast<size_t>(m) * sizeof(double));
    if (V) {
        ws.V.zeros(steps, r);
        for (i64 i = 0; i < steps; ++i) {
            double* v = ws.V.row(i);
            const double* vc = ws.Vc.row(i);
            for (i64 t = i; t < rc; ++t) v[map[t]] = vc[t];
        }
    }
    Q.zeros(0, r);
    ws.compact = true;
    return true;
}
}  // namespace detail

// QR of M (r, m) by Householder reflections, optionally with column pivoting:
// M[:, perm] = Q R, Q (r, r) orthogonal, R (r, m) upper trapezoidal. Q, R, perm and the
// scratch keep their storage (no allocation unless a size grows).
// Zero rows: a row of M past the first min(r, m) whose entries are all +0 (a level's rows
// that leave some dofs out: the feet of a floating robot, Z the identity) is never a pivot
// row, and every reflection with finite factors leaves it as it is: its x entry is +0, so it
// adds +-0 to each sum (from +0.0: no change; its +0 squares add nothing to the norms
// either) and each of its entries becomes +0 - (+-0) = +0. Where Q is not formed, such rows
// are left out of the steps (the same R, perm, norms, reflectors and vn: the steps on the
// other rows are the same operations in the same order), the rows put back as +0 after;
// should a step's factors not be finite, the factorisation is made again on every row.
inline void householder_qr(CMatRef M, bool pivot, Mat& Q, Mat& R, IVec& perm, bool form_q, QRScratch& ws) {
    i64 r = M.rows, m = M.cols;
    i64 steps = std::min(r, m);
    ws.compact = false;
    // (only where it saves more than the copies cost: at least kZeroRowsLeftOut zero rows and
    // kZeroWorkLeftOut zero entries; a few of a small M, as a Panda's fingers in its frame
    // task, or a pinned normal or two, are reflected with the others)
    if (!form_q && r - steps >= kZeroRowsLeftOut && (r - steps) * m >= kZeroWorkLeftOut &&
        detail::householder_qr_compact(M, pivot, Q, R, perm, ws))
        return;
    shape(R, r, m);  // every entry copied
    for (i64 i = 0; i < r && m > 0; ++i) std::memcpy(R.row(i), M.row(i), static_cast<size_t>(m) * sizeof(double));
    if (form_q) Q.set_eye(r);
    else Q.zeros(0, r);  // no rows: R and perm only (the same R)
    // (qr_steps' loop, written out: the common path as it was compiled before the compact one)
    perm.assign(static_cast<size_t>(m), 0);
    for (i64 j = 0; j < m; ++j) perm[j] = j;
    // (norms, x and S sized only: each entry written before it is read)
    Vec& norms = ws.norms;
    shape(norms, static_cast<size_t>(m));
    if (pivot) detail::column_norms(R, 0, norms);
    Vec& x = ws.x;
    Vec& S = ws.S;
    shape(x, static_cast<size_t>(r));
    shape(S, static_cast<size_t>(m));
    if (ws.keep_reflectors) {
        ws.V.zeros(steps, r);
        ws.vn.assign(static_cast<size_t>(steps), 0.0);
    }
    for (i64 i = 0; i < steps; ++i) {
        if (pivot) detail::swap_pivot(R, norms, perm, i);
        // (with pivoting, the next step's column norms summed in the reflection's pass)
        double* nrm = pivot ? norms.data() : nullptr;
        bool done = ws.keep_reflectors
                        ? detail::reflect(R, Q, x, S, i, ws.V.row(i), &ws.vn[static_cast<size_t>(i)], nrm)
                        : detail::reflect(R, Q, x, S, i, nullptr, nullptr, nrm);
        if (pivot && !done) detail::column_norms(R, i + 1, norms);
    }
}

// Y (rows, r) <- Y H_0 H_1 ... H_{k-1} for the first k reflectors kept by householder_qr
// (ws.keep_reflectors): Y = I gives Q; Y = Z gives Z Q without forming Q. Per reflector and
// row, the operations reflect() does on Q's rows.
inline void apply_reflectors_right(Mat& Y, const QRScratch& ws, i64 k) {
    i64 r = ws.V.cols, n = Y.rows;
    for (i64 i = 0; i < k; ++i) {
        double vn = ws.vn[static_cast<size_t>(i)];
        if (vn == 0.0) continue;
        const double* x = ws.V.row(i) + i;
        i64 size = r - i;
        i64 row = 0;
        for (; row + 4 <= n; row += 4) {
            double* q0 = Y.row(row) + i;
            double* q1 = Y.row(row + 1) + i;
            double* q2 = Y.row(row + 2) + i;
            double* q3 = Y.row(row + 3) + i;
            double s0, s1, s2, s3;
            dot4(q0, q1, q2, q3, x, size, s0, s1, s2, s3);
            axmy(q0, 2.0 * s0 / vn, x, size);
            axmy(q1, 2.0 * s1 / vn, x, size);
            axmy(q2, 2.0 * s2 / vn, x, size);
            axmy(q3, 2.0 * s3 / vn, x, size);
        }
        for (; row + 2 <= n; row += 2) {
            double* q0 = Y.row(row) + i;
            double* q1 = Y.row(row + 1) + i;
            double s0, s1;
            dot2(q0, q1, x, size, s0, s1);
            axmy(q0, 2.0 * s0 / vn, x, size);
            axmy(q1, 2.0 * s1 / vn, x, size);
        }
        for (; row < n; ++row) {
            double* qr = Y.row(row) + i;
            double s = 0.0;
            for (i64 t = 0; t < size; ++t) s += qr[t] * x[t];
            axmy(qr, 2.0 * s / vn, x, size);
        }
    }
}

// E (r, c) <- H_0 H_1 ... H_{k-1} E (reflectors kept by householder_qr, applied last to
// first): Q's columns Q e without forming Q, at (r - i) c per reflector.
inline void apply_reflectors_left(Mat& E, QRScratch& ws, i64 k) {
    i64 r = ws.V.cols, c = E.cols;
    ws.S.resize(static_cast<size_t>(std::max<i64>(c, 1)));
    for (i64 i = k - 1; i >= 0; --i) {
        double vn = ws.vn[static_cast<size_t>(i)];
        if (vn == 0.0) continue;
        detail::reflect_columns(E.row(0), c, i, r - i, 0, c, ws.V.row(i) + i, vn, ws.S.data());
    }
}

inline void householder_qr(CMatRef M, bool pivot, Mat& Q, Mat& R, IVec& perm, bool form_q = true) {
    QRScratch ws;
    householder_qr(M, pivot, Q, R, perm, form_q, ws);
}

}  // namespace qpik::core
