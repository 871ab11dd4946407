// The exact dense QP of the core: the dual active-set
// method of Goldfarb and Idnani with a canonical KKT re-solve (solve_qp), its robust
// per-level wrapper (solve_level) and the active-set guess from an approximate answer.
// One fixed order of floating-point operations: the same inputs give the same bits.
#pragma once

#include <cmath>

#include "linalg.hpp"

namespace qpik::core {

// Status codes shared with qpik.core.hierarchy.LevelStatus (keep in sync).
enum Status : i64 { SOLVED = 0, MAX_ITER = 1, INFEASIBLE = 2, KEPT_PREVIOUS = 3, NUMERICAL = 4, NOT_REACHED = 5 };

constexpr double kBig = 1e20;          // bounds beyond this are treated as absent
constexpr double kDegenerate = 1e-9;   // multipliers / slacks this small make a set degenerate
constexpr double kRoundoff = 1e-11;    // violations this small at a degenerate vertex are round-off
constexpr double kDependent = 1e-10;   // a normal this close to the working set's span depends on it
constexpr double kVerify = 1e-8;       // a final violation above this (relative) is a failure

// (x, status, iterations, active) of solve_qp / solve_level.
struct QPResult {
    Vec x;
    i64 status = SOLVED;
    i64 iterations = 0;
    BVec active;
    BVec working;  // the final working set (every row in it, +1 lower / -1 upper), when known
};

// The storage solve_qp / solve_level work in, kept between calls by a caller that solves
// often (sizes only grow: no allocation once they are reached). Nothing in it carries from
// one call to the next but capacity: every buffer is sized and filled before it is read.
struct QPScratch {
    Mat L, J, JT, R;
    Vec mc, y, x, u, d, z, r, normal, norms, lo2, hi2, cx;
    IVec act_row, act_side, unit, rows, dense;
    Vec CT, slot_e, unit_thr, cxd;  // see RowScan
    IVec slot_row, slot_of, unit_rows;
    BVec in_set;
    Vec rot;  // rotate_in's coefficients
};

namespace detail {

// M (r, r) with +0 strictly above the diagonal, the rest of its storage left as it was (for a
// triangular factor that writes every entry on and below the diagonal before reading it).
inline void zero_upper(Mat& M, i64 r) {
    shape(M, r, r);
    for (i64 i = 0; i + 1 < r; ++i) zero_small(M.row(i) + i + 1, static_cast<size_t>(r - i - 1));
}

inline double rhs_of(CVecRef lo, CVecRef hi, i64 row, i64 side) { return side > 0 ? lo[row] : -hi[row]; }

// Minimiser with the working set held as equalities and its multipliers, by the
// null-space method; ok false when the normals are dependent (or W^T H W is not PD).
inline bool kkt_solve(CMatRef H, CMatRef L, CVecRef c, CMatRef C, CVecRef lo, CVecRef hi,
                      const IVec& act_row, const IVec& act_side, i64 q, Vec& x, Vec& u) {
    i64 n = L.rows;
    if (q == 0) {
        Vec mc(static_cast<size_t>(n));
        for (i64 i = 0; i < n; ++i) mc[i] = -c[i];
        x = backward_vec(L, forward_vec(L, mc));
        u.assign(0, 0.0);
        return true;
    }
    Mat N(n, q);
    Vec rhs(static_cast<size_t>(q));
    for (i64 j = 0; j < q; ++j) {
        double side = static_cast<double>(act_side[j]);
        for (i64 i = 0; i < n; ++i) N(i, j) = C(act_row[j], i) * side;
        rhs[j] = rhs_of(lo, hi, act_row[j], act_side[j]);
    }
    Mat Q, R;
    IVec perm;
    householder_qr(N.cref(), false, Q, R, perm);
    double scale = 0.0;
    for (i64 i = 0; i < q; ++i) scale = pymax(scale, std::fabs(R(i, i)));
    for (i64 i = 0; i < q; ++i) {
        if (std::fabs(R(i, i)) <= 1e-13 * pymax(scale, 1e-300)) {
            zero_fill(x, static_cast<size_t>(n));
            zero_fill(u, static_cast<size_t>(q));
            return false;
        }
    }
    Vec t(static_cast<size_t>(q));
    for (i64 i = 0; i < q; ++i) {  // R1^T t = rhs
        double acc = rhs[i];
        for (i64 k = 0; k < i; ++k) acc -= R(k, i) * t[k];
        t[i] = acc / R(i, i);
    }
    Mat Y = columns(Q.cref(), 0, q);
    x = mv(Y.cref(), t.data());
    if (q < n) {
        Mat W = columns(Q.cref(), q, n);
        Mat Wt = transposed(W.cref());
        Mat Hr = mm(Wt.cref(), mm(H, W.cref()).cref());
        Mat Lr;
        if (!cholesky(Hr.cref(), Lr)) {
            zero_fill(u, static_cast<size_t>(q));
            return false;
        }
        Vec hx = mv(H, x.data());
        for (i64 i = 0; i < n; ++i) hx[i] = hx[i] + c[i];
        Vec g = mtv(W.cref(), hx.data());
        for (auto& v : g) v = -v;
        Vec y = backward_vec(Lr.cref(), forward_vec(Lr.cref(), g));
        Vec wy = mv(W.cref(), y.data());
        for (i64 i = 0; i < n; ++i) x[i] = x[i] + wy[i];
    }
    Vec hx = mv(H, x.data());
    for (i64 i = 0; i < n; ++i) hx[i] = hx[i] + c[i];
    Vec grad = mtv(Y.cref(), hx.data());
    zero_fill(u, static_cast<size_t>(q));
    for (i64 i = q - 1; i >= 0; --i) {  // R1 u = Y^T (H x + c)
        double acc = grad[i];
        for (i64 k = i + 1; k < q; ++k) acc -= R(i, k) * u[k];
        u[i] = acc / R(i, i);
    }
    return true;
}

inline double max_abs(const Vec& u, i64 q) {
    double big = 0.0;
    for (i64 j = 0; j < q; ++j) big = pymax(big, std::fabs(u[j]));
    return big;
}

// Eight rows' dot products with one vector (a[k] . x), or their squares (sq8: a[k] . a[k]):
// each row's sum in index order from 0.0, as dot sums it (one per lane of four pairs: the same
// bits, eight independent sums in flight).
inline void dot8(const double* const* a, const double* x, i64 n, double* out) {
    using namespace simd;
    v2d s0 = splat(0.0), s1 = splat(0.0), s2 = splat(0.0), s3 = splat(0.0);
    const double *a0 = a[0], *a1 = a[1], *a2 = a[2], *a3 = a[3], *a4 = a[4], *a5 = a[5], *a6 = a[6], *a7 = a[7];
    for (i64 t = 0; t < n; ++t) {
        v2d xt = splat(x[t]);
        s0 += v2d{a0[t], a1[t]} * xt;
        s1 += v2d{a2[t], a3[t]} * xt;
        s2 += v2d{a4[t], a5[t]} * xt;
        s3 += v2d{a6[t], a7[t]} * xt;
    }
    out[0] = s0[0];
    out[1] = s0[1];
    out[2] = s1[0];
    out[3] = s1[1];
    out[4] = s2[0];
    out[5] = s2[1];
    out[6] = s3[0];
    out[7] = s3[1];
}

inline void sq8(const double* const* a, i64 n, double* out) {
    using namespace simd;
    v2d s0 = splat(0.0), s1 = splat(0.0), s2 = splat(0.0), s3 = splat(0.0);
    const double *a0 = a[0], *a1 = a[1], *a2 = a[2], *a3 = a[3], *a4 = a[4], *a5 = a[5], *a6 = a[6], *a7 = a[7];
    for (i64 t = 0; t < n; ++t) {
        v2d v0 = v2d{a0[t], a1[t]}, v1 = v2d{a2[t], a3[t]}, v2 = v2d{a4[t], a5[t]}, v3 = v2d{a6[t], a7[t]};
        s0 += v0 * v0;
        s1 += v1 * v1;
        s2 += v2 * v2;
        s3 += v3 * v3;
    }
    out[0] = s0[0];
    out[1] = s0[1];
    out[2] = s1[0];
    out[3] = s1[1];
    out[4] = s2[0];
    out[5] = s2[1];
    out[6] = s3[0];
    out[7] = s3[1];
}

// Per row |C_i| (sqrt of dot(C_i, C_i): the same sums, eight rows a pass by sq8).
inline void row_norms_into(CMatRef C, Vec& norms) {
    norms.resize(static_cast<size_t>(C.rows));
    i64 i = 0;
    for (; i + 8 <= C.rows; i += 8) {
        const double* rows[8];
        for (int k = 0; k < 8; ++k) rows[k] = C.p + (i + k) * C.stride;
        double sq[8];
        sq8(rows, C.cols, sq);
        for (int k = 0; k < 8; ++k) norms[i + k] = std::sqrt(sq[k]);
    }
    for (; i < C.rows; ++i) {
        const double* ci = C.p + i * C.stride;
        norms[i] = std::sqrt(dot(ci, ci, C.cols));
    }
}

inline Vec row_norms(CMatRef C) {
    Vec norms;
    row_norms_into(C, norms);
    return norms;
}

// Per row, the column of its single entry when the row is +-e_j, else -1.
inline void unit_columns_into(CMatRef C, IVec& unit) {
    unit.assign(static_cast<size_t>(C.rows), -1);
    for (i64 i = 0; i < C.rows; ++i) {
        i64 col = -1;
        for (i64 j = 0; j < C.cols; ++j) {
            if (C(i, j) != 0.0) {
                if (col >= 0 || std::fabs(C(i, j)) != 1.0) {
                    col = -2;
                    break;
                }
                col = j;
            }
        }
        if (col >= 0) unit[i] = col;
    }
}

inline IVec unit_columns(CMatRef C) {
    IVec unit;
    unit_columns_into(C, unit);
    return unit;
}

// The most violated constraint (row, side) at x; row -1 when every one holds within tol.
// C x is taken for the rows that need it first, four rows a pass (dot4: each row's sum in
// index order from 0.0, the same bits as dot), into cx (scratch; rows is scratch too).
inline void most_violated(const double* x, CMatRef C, CVecRef lo, CVecRef hi, const BVec& skip,
                          double tol, const Vec& norms, const IVec& unit, i64& best_row, i64& best_side,
                          Vec& cx, IVec& rows, const IVec* dense = nullptr) {
    i64 m = C.rows, n = C.cols;
    double best = 0.0;
    best_row = -1;
    best_side = 0;
    shape(cx, static_cast<size_t>(m));  // read only where written below
    if (static_cast<i64>(rows.size()) < m) rows.resize(static_cast<size_t>(m));  // the first k in use
    i64 k = 0, t = 0;
    if (dense) {  // the rows with norms[i] != 0 and unit[i] < 0, in order (the caller's)
        for (i64 i : *dense)
            if (!skip[i]) rows[k++] = i;
    } else {
        for (i64 i = 0; i < m; ++i)
            if (!skip[i] && norms[i] != 0.0 && unit[i] < 0) rows[k++] = i;
    }
    for (; t + 4 <= k; t += 4) {
        i64 a = rows[t], b = rows[t + 1], c = rows[t + 2], d = rows[t + 3];
        dot4(C.row(a), C.row(b), C.row(c), C.row(d), x, n, cx[a], cx[b], cx[c], cx[d]);
    }
    for (; t + 2 <= k; t += 2) dot2(C.row(rows[t]), C.row(rows[t + 1]), x, n, cx[rows[t]], cx[rows[t + 1]]);
    for (; t < k; ++t) cx[rows[t]] = dot(C.row(rows[t]), x, n);
    for (i64 i = 0; i < m; ++i) {
        if (skip[i]) continue;
        double norm = norms[i];
        if (norm == 0.0) continue;
        double ci = unit[i] >= 0 ? 0.0 + C(i, unit[i]) * x[unit[i]] : cx[i];
        if (lo[i] > -kBig) {
            double v = (lo[i] - ci) / norm;
            if (v > tol * (1.0 + std::fabs(lo[i])) && v > best) {
                best = v;
                best_row = i;
                best_side = 1;
            }
        }
        if (hi[i] < kBig) {
            double v = (ci - hi[i]) / norm;
            if (v > tol * (1.0 + std::fabs(hi[i])) && v > best) {
                best = v;
                best_row = i;
                best_side = -1;
            }
        }
    }
}

inline void most_violated(const double* x, CMatRef C, CVecRef lo, CVecRef hi, const BVec& skip,
                          double tol, const Vec& norms, const IVec& unit, i64& best_row, i64& best_side) {
    Vec cx;
    IVec rows;
    most_violated(x, C, lo, hi, skip, tol, norms, unit, best_row, best_side, cx, rows);
}

// most_violated's work, laid out once per solve_qp (C, lo, hi, tol fixed): the dense rows'
// normals transposed (column j of CT the normal of the row in slot j, columns padded to an
// even count with zeros), so C x of them is taken two rows a vector; per slot its row, bounds,
// norm and thresholds tol (1 + |bound|), NaN for an absent bound (no v exceeds it); the unit
// rows (norm != 0) in order. Slots 0..live-1 hold the dense rows not in the working set
// (scan_enter / scan_leave swap a row's column out of / back into that range): C x is taken
// of those alone (each column's sum on its own, so the order of the slots changes no bits).
// Needs tol >= 0 (a violation then has bound - C x > 0, so the division is taken only there).
struct RowScan {
    i64 kd = 0, ld = 0, live = 0;
};

// with_norms: norms[i] of the rows in dense taken here (the sums of row_norms_into: each row's
// squares in index order from +0, then sqrt); false, and nothing past CT done, where one is 0.
inline bool row_scan_init(CMatRef C, CVecRef lo, CVecRef hi, double tol, Vec& norms, const IVec& unit,
                          const IVec& dense, QPScratch& ws, RowScan& rs, bool with_norms) {
    i64 m = C.rows, n = C.cols;
    rs.kd = static_cast<i64>(dense.size());
    rs.ld = (rs.kd + 1) & ~static_cast<i64>(1);
    rs.live = rs.kd;
    Vec& CT = ws.CT;
    shape(CT, static_cast<size_t>(n * rs.ld));
    i64 ld = rs.ld;
    // Two rows a pass (adjacent columns of CT, one store); an odd last row with the zero pad.
    bool zero = false;
    for (i64 j = 0; j < ld; j += 2) {
        const double* c0 = C.row(dense[j]);
        double* dst = CT.data() + j;
        bool pair = j + 1 < rs.kd;
        const double* c1 = pair ? C.row(dense[j + 1]) : c0;
        if (with_norms) {
            simd::v2d sq = simd::splat(0.0);
            if (pair) {
                for (i64 k = 0; k < n; ++k, dst += ld) {
                    simd::v2d v{c0[k], c1[k]};
                    simd::store(dst, v);
                    sq = sq + v * v;
                }
            } else {
                for (i64 k = 0; k < n; ++k, dst += ld) {
                    simd::v2d v{c0[k], 0.0};
                    simd::store(dst, v);
                    sq = sq + v * v;
                }
            }
            double n0 = std::sqrt(sq[0]);
            norms[dense[j]] = n0;
            zero = zero || n0 == 0.0;
            if (pair) {
                double n1 = std::sqrt(sq[1]);
                norms[dense[j + 1]] = n1;
                zero = zero || n1 == 0.0;
            }
        } else if (pair) {
            for (i64 k = 0; k < n; ++k, dst += ld) simd::store(dst, simd::v2d{c0[k], c1[k]});
        } else {
            for (i64 k = 0; k < n; ++k, dst += ld) simd::store(dst, simd::v2d{c0[k], 0.0});
        }
    }
    if (zero) return false;
    // Per slot: lo, hi, norm, the two thresholds (5 entries at 5 j).
    shape(ws.slot_e, static_cast<size_t>(5 * ld));
    ws.slot_row.resize(static_cast<size_t>(ld));
    ws.slot_of.assign(static_cast<size_t>(m), -1);  // (-1: not a dense row)
    for (i64 j = 0; j < rs.kd; ++j) {
        i64 i = dense[j];
        ws.slot_row[j] = i;
        ws.slot_of[i] = j;
        double* e = ws.slot_e.data() + 5 * j;
        e[0] = lo[i];
        e[1] = hi[i];
        e[2] = norms[i];
        e[3] = lo[i] > -kBig ? tol * (1.0 + std::fabs(lo[i])) : kNaN;
        e[4] = hi[i] < kBig ? tol * (1.0 + std::fabs(hi[i])) : kNaN;
    }
    if (ld > rs.kd) ws.slot_row[rs.kd] = -1;
    ws.unit_rows.clear();
    for (i64 i = 0; i < m; ++i)
        if (norms[i] != 0.0 && unit[i] >= 0) ws.unit_rows.push_back(i);
    shape(ws.unit_thr, static_cast<size_t>(2 * m));  // the unit rows' thresholds
    for (i64 i : ws.unit_rows) {
        ws.unit_thr[2 * i] = lo[i] > -kBig ? tol * (1.0 + std::fabs(lo[i])) : kNaN;
        ws.unit_thr[2 * i + 1] = hi[i] < kBig ? tol * (1.0 + std::fabs(hi[i])) : kNaN;
    }
    return true;
}

// Slots a and b of RowScan traded (their CT columns and entries).
inline void scan_swap(QPScratch& ws, const RowScan& rs, i64 n, i64 a, i64 b) {
    if (a == b) return;
    i64 ld = rs.ld;
    double* pa = ws.CT.data() + a;
    double* pb = ws.CT.data() + b;
    for (i64 k = 0; k < n; ++k, pa += ld, pb += ld) {
        double t = *pa;
        *pa = *pb;
        *pb = t;
    }
    double* ea = ws.slot_e.data() + 5 * a;
    double* eb = ws.slot_e.data() + 5 * b;
    for (int t = 0; t < 5; ++t) std::swap(ea[t], eb[t]);
    i64 ra = ws.slot_row[a], rb = ws.slot_row[b];
    ws.slot_row[a] = rb;
    ws.slot_row[b] = ra;
    ws.slot_of[ra] = b;
    ws.slot_of[rb] = a;
}

// Row `row` joins the working set (out of the live slots) / leaves it (back in).
inline void scan_enter(QPScratch& ws, RowScan& rs, i64 n, i64 row) {
    i64 s = ws.slot_of[row];
    if (s < 0 || s >= rs.live) return;
    scan_swap(ws, rs, n, s, rs.live - 1);
    rs.live -= 1;
}

inline void scan_leave(QPScratch& ws, RowScan& rs, i64 n, i64 row) {
    i64 s = ws.slot_of[row];
    if (s < rs.live) return;  // (also s = -1: not dense)
    scan_swap(ws, rs, n, s, rs.live);
    rs.live += 1;
}

// most_violated(x, ...) by RowScan (the same bits and answer: each dense row's C x summed in
// index order from +0, as dot; v as there. most_violated keeps the first largest v in the order
// of rows (lower bound before upper): here the largest v with the least 2 row + (side < 0),
// the same pick in any order of the rows, v > 0 being never NaN).
inline void most_violated_scan(const double* x, CMatRef C, CVecRef lo, CVecRef hi, const BVec& skip,
                               const Vec& norms, const IVec& unit, const RowScan& rs,
                               QPScratch& ws, i64& best_row, i64& best_side) {
    using namespace simd;
    i64 n = C.cols, ld = rs.ld;
    i64 nl = (rs.live + 1) & ~static_cast<i64>(1);
    const double* CT = ws.CT.data();
    Vec& out = ws.cxd;
    shape(out, static_cast<size_t>(ld));
    i64 j = 0;
    for (; j + 16 <= nl; j += 16) {  // eight sums in flight (each column's in order of k)
        v2d a0 = splat(0.0), a1 = splat(0.0), a2 = splat(0.0), a3 = splat(0.0);
        v2d a4 = splat(0.0), a5 = splat(0.0), a6 = splat(0.0), a7 = splat(0.0);
        const double* p = CT + j;
        for (i64 k = 0; k < n; ++k, p += ld) {
            v2d xk = splat(x[k]);
            a0 = a0 + load(p) * xk;
            a1 = a1 + load(p + 2) * xk;
            a2 = a2 + load(p + 4) * xk;
            a3 = a3 + load(p + 6) * xk;
            a4 = a4 + load(p + 8) * xk;
            a5 = a5 + load(p + 10) * xk;
            a6 = a6 + load(p + 12) * xk;
            a7 = a7 + load(p + 14) * xk;
        }
        double* o = out.data() + j;
        store(o, a0);
        store(o + 2, a1);
        store(o + 4, a2);
        store(o + 6, a3);
        store(o + 8, a4);
        store(o + 10, a5);
        store(o + 12, a6);
        store(o + 14, a7);
    }
    for (; j + 8 <= nl; j += 8) {
        v2d a = splat(0.0), b = splat(0.0), c = splat(0.0), e = splat(0.0);
        const double* p = CT + j;
        for (i64 k = 0; k < n; ++k, p += ld) {
            v2d xk = splat(x[k]);
            a = a + load(p) * xk;
            b = b + load(p + 2) * xk;
            c = c + load(p + 4) * xk;
            e = e + load(p + 6) * xk;
        }
        store(out.data() + j, a);
        store(out.data() + j + 2, b);
        store(out.data() + j + 4, c);
        store(out.data() + j + 6, e);
    }
    for (; j + 4 <= nl; j += 4) {
        v2d a = splat(0.0), b = splat(0.0);
        const double* p = CT + j;
        for (i64 k = 0; k < n; ++k, p += ld) {
            v2d xk = splat(x[k]);
            a = a + load(p) * xk;
            b = b + load(p + 2) * xk;
        }
        store(out.data() + j, a);
        store(out.data() + j + 2, b);
    }
    for (; j + 2 <= nl; j += 2) {
        v2d a = splat(0.0);
        const double* p = CT + j;
        for (i64 k = 0; k < n; ++k, p += ld) a = a + load(p) * splat(x[k]);
        store(out.data() + j, a);
    }
    double best = 0.0;
    i64 best_pos = -1;  // 2 row + (side < 0)
    auto take = [&](double v, i64 pos) {
        if (v > best || (v == best && pos < best_pos)) {
            best = v;
            best_pos = pos;
        }
    };
    const double* e = ws.slot_e.data();
    const i64* slot_row = ws.slot_row.data();
    for (i64 s = 0; s < rs.live; ++s, e += 5) {
        double ci = out[s];
        double a = e[0] - ci;
        double b = ci - e[1];
        if (!(a > 0.0) && !(b > 0.0)) continue;
        i64 i = slot_row[s];
        if (a > 0.0) {
            double v = a / e[2];
            if (v > e[3]) take(v, 2 * i);
        }
        if (b > 0.0) {
            double v = b / e[2];
            if (v > e[4]) take(v, 2 * i + 1);
        }
    }
    const double* th = ws.unit_thr.data();
    for (i64 i : ws.unit_rows) {
        if (skip[i]) continue;
        i64 u = unit[i];
        double ci = 0.0 + C(i, u) * x[u];
        double a = lo[i] - ci;
        if (a > 0.0) {
            double v = a / norms[i];
            if (v > th[2 * i]) take(v, 2 * i);
        }
        double b = ci - hi[i];
        if (b > 0.0) {
            double v = b / norms[i];
            if (v > th[2 * i + 1]) take(v, 2 * i + 1);
        }
    }
    if (best_pos < 0) {
        best_row = -1;
        best_side = 0;
    } else {
        best_row = best_pos >> 1;
        best_side = (best_pos & 1) ? -1 : 1;
    }
}

inline double dual_floor(const Vec& u, i64 q) { return 1e-12 * (1.0 + max_abs(u, q)); }

// Primal feasibility of x and dual feasibility of the multipliers u.
inline bool kkt_ok(const Vec& x, const Vec& u, CMatRef C, CVecRef lo, CVecRef hi, i64 q, double tol) {
    double floor = dual_floor(u, q);
    for (i64 j = 0; j < q; ++j)
        if (u[j] < -floor) return false;
    BVec skip(static_cast<size_t>(C.rows), 0);
    i64 row, side;
    most_violated(x.data(), C, lo, hi, skip, tol, row_norms(C), unit_columns(C), row, side);
    return row < 0;
}

// Whether a working set is the QP's unique optimal active set (strict complementarity).
inline bool strictly_optimal(const Vec& x, const Vec& u, CMatRef C, CVecRef lo, CVecRef hi,
                             const IVec& act_row, i64 q) {
    double big = max_abs(u, q);
    for (i64 j = 0; j < q; ++j)
        if (u[j] <= kDegenerate * (1.0 + big)) return false;
    i64 m = C.rows, n = C.cols;
    BVec working(static_cast<size_t>(m), 0);
    for (i64 j = 0; j < q; ++j) working[act_row[j]] = 1;
    for (i64 i = 0; i < m; ++i) {
        if (working[i]) continue;
        double cx = 0.0, norm = 0.0;
        for (i64 j = 0; j < n; ++j) {
            cx += C(i, j) * x[j];
            norm += C(i, j) * C(i, j);
        }
        norm = std::sqrt(norm);
        if (norm == 0.0) continue;
        double margin = kDegenerate * norm;
        if (lo[i] > -kBig && cx - lo[i] <= margin * (1.0 + std::fabs(lo[i]))) return false;
        if (hi[i] < kBig && hi[i] - cx <= margin * (1.0 + std::fabs(hi[i]))) return false;
    }
    return true;
}

// L^-T of a lower-triangular L, stored transposed (row i of the result is column i of
// L^-T): every update of the dual method touches J's columns, contiguous this way.
inline void inverse_transpose_into(const Mat& L, Mat& J, Mat& JT) {
    i64 n = L.rows;
    J.zeros(n, n);
    for (i64 i = 0; i < n; ++i) {
        J(i, i) = 1.0 / L(i, i);
        for (i64 k = i + 1; k < n; ++k) {
            J(i, k) = minus_dot(0.0, L.row(k) + i, J.row(i) + i, k - i) / L(k, k);
        }
    }
    transposed_into(J.cref(), JT);
}

// inverse_transpose_into's JT alone, with the same bits: row k of JT (column k of J) is
// -(sum over t < k of L(k, t) JT(t, :)) / L(k, k), each entry's sum from +0 in the order of t
// (minus_dot's). Four entries i0..i0+3 a pass in registers, t from i0: an entry i > t meets
// JT(t, i) = 0 (a structural zero), L(k, t) * 0 = +-0 taken from +0 leaves +0, as if its sum
// had not started (L finite; else axmy passes, entry i only from t = i on).
inline void inverse_transpose_into(const Mat& L, Mat& JT) {
    using namespace simd;
    i64 n = L.rows;
    zero_upper(JT, n);  // row k's entries 0..k are written below
    // Whether every entry on and below the diagonal is finite: x - x is +0 for a finite x and
    // NaN otherwise, and a sum of them is 0 only when every one is +0 (two lanes a pass).
    bool finite = true;
    {
        v2d acc = splat(0.0);
        double tail = 0.0;
        for (i64 k = 0; k < n; ++k) {
            const double* lk = L.row(k);
            i64 t = 0;
            for (; t + 2 <= k + 1; t += 2) {
                v2d x = load(lk + t);
                acc += x - x;
            }
            if (t <= k) tail += lk[t] - lk[t];
        }
        finite = (acc[0] + acc[1]) + tail == 0.0;
    }
    for (i64 k = 0; k < n; ++k) {
        double* jk = JT.row(k);
        const double* lk = L.row(k);
        double lkk = lk[k];
        if (!finite) {
            for (i64 t = 0; t < k; ++t) axmy(jk, lk[t], JT.row(t), t + 1);
            for (i64 i = 0; i < k; ++i) jk[i] = jk[i] / lkk;
            jk[k] = 1.0 / lkk;
            continue;
        }
        v2d dv = splat(lkk);
        i64 i0 = 0;
        for (; i0 + 6 < k; i0 += 8) {  // entries i0..i0+7 (as below: four sums in flight)
            v2d a = splat(0.0), b = splat(0.0), c = splat(0.0), e = splat(0.0);
            const double* p = JT.row(i0) + i0;
            for (i64 t = i0; t < k; ++t, p += n) {
                v2d l = splat(lk[t]);
                a = a - l * load(p);
                b = b - l * load(p + 2);
                c = c - l * load(p + 4);
                e = e - l * load(p + 6);
            }
            store(jk + i0, a / dv);
            store(jk + i0 + 2, b / dv);
            store(jk + i0 + 4, c / dv);
            store(jk + i0 + 6, e / dv);
        }
        for (; i0 + 2 < k; i0 += 4) {  // entries i0..i0+3 (those >= k written below or zero)
            v2d a = splat(0.0), b = splat(0.0);
            const double* p = JT.row(i0) + i0;
            for (i64 t = i0; t < k; ++t, p += n) {
                v2d l = splat(lk[t]);
                a = a - l * load(p);
                b = b - l * load(p + 2);
            }
            store(jk + i0, a / dv);
            store(jk + i0 + 2, b / dv);
        }
        for (; i0 < k; i0 += 2) {  // entries i0, i0 + 1 (i0 + 1 <= k)
            v2d a = splat(0.0);
            const double* p = JT.row(i0) + i0;
            for (i64 t = i0; t < k; ++t, p += n) a = a - splat(lk[t]) * load(p);
            store(jk + i0, a / dv);
        }
        jk[k] = 1.0 / lkk;
    }
}

// d = J^T n; z = J2 d2 (primal direction); r = R^-1 d1 (dual direction). JT is J
// transposed (see inverse_transpose).
// d0, d1: for a row not a unit row, only d[d0:d1] is taken afresh (the others hold J^T n of
// JT's rows as they still are, with the same normal: the same values).
inline void directions(const Mat& JT, const Mat& R, const Vec& normal, i64 unit, i64 q, Vec& d, Vec& z, Vec& r,
                       i64 d0 = 0, i64 d1 = -1) {
    i64 n = JT.rows;
    if (unit >= 0) {
        for (i64 i = 0; i < n; ++i) d[i] = 0.0 + JT(i, unit) * normal[unit];
    } else {
        i64 i = d0, e = d1 >= 0 ? d1 : n;
        for (; i + 8 <= e; i += 8) {
            const double* rows[8];
            for (int k = 0; k < 8; ++k) rows[k] = JT.row(i + k);
            dot8(rows, normal.data(), n, d.data() + i);
        }
        for (; i + 4 <= e; i += 4)
            dot4(JT.row(i), JT.row(i + 1), JT.row(i + 2), JT.row(i + 3), normal.data(), n, d[i], d[i + 1], d[i + 2],
                 d[i + 3]);
        for (; i + 2 <= e; i += 2) dot2(JT.row(i), JT.row(i + 1), normal.data(), n, d[i], d[i + 1]);
        for (; i < e; ++i) {
            const double* ji = JT.row(i);
            double acc = 0.0;
            for (i64 k = 0; k < n; ++k) acc += ji[k] * normal[k];
            d[i] = acc;
        }
    }
    // r first: its back substitution is one serial chain (each r[i] waits on r[i + 1]), which
    // z's independent sums below then fill in around (the same operations either way).
    for (i64 i = q - 1; i >= 0; --i) {
        const double* ri = R.row(i);
        double acc = d[i];
        i64 j = i + 1;
        for (; j + 2 <= q; j += 2) {  // (the same chain of operations, two a pass)
            acc -= ri[j] * r[j];
            acc -= ri[j + 1] * r[j + 1];
        }
        if (j < q) acc -= ri[j] * r[j];
        r[i] = acc / ri[i];
    }
    // z[k] = sum_{i >= q} J(k, i) d[i], i in order from +0 (eight entries a pass in registers,
    // then four, two, one: the sums axpy over JT's rows makes).
    {
        using namespace simd;
        i64 k = 0;
        for (; k + 16 <= n; k += 16) {  // eight sums in flight
            v2d a0 = splat(0.0), a1 = splat(0.0), a2 = splat(0.0), a3 = splat(0.0);
            v2d a4 = splat(0.0), a5 = splat(0.0), a6 = splat(0.0), a7 = splat(0.0);
            for (i64 i = q; i < n; ++i) {
                const double* ji = JT.row(i) + k;
                v2d di = splat(d[i]);
                a0 = a0 + di * load(ji);
                a1 = a1 + di * load(ji + 2);
                a2 = a2 + di * load(ji + 4);
                a3 = a3 + di * load(ji + 6);
                a4 = a4 + di * load(ji + 8);
                a5 = a5 + di * load(ji + 10);
                a6 = a6 + di * load(ji + 12);
                a7 = a7 + di * load(ji + 14);
            }
            double* o = z.data() + k;
            store(o, a0);
            store(o + 2, a1);
            store(o + 4, a2);
            store(o + 6, a3);
            store(o + 8, a4);
            store(o + 10, a5);
            store(o + 12, a6);
            store(o + 14, a7);
        }
        for (; k + 8 <= n; k += 8) {
            v2d a = splat(0.0), b = splat(0.0), e = splat(0.0), f = splat(0.0);
            for (i64 i = q; i < n; ++i) {
                const double* ji = JT.row(i) + k;
                v2d di = splat(d[i]);
                a = a + di * load(ji);
                b = b + di * load(ji + 2);
                e = e + di * load(ji + 4);
                f = f + di * load(ji + 6);
            }
            store(z.data() + k, a);
            store(z.data() + k + 2, b);
            store(z.data() + k + 4, e);
            store(z.data() + k + 6, f);
        }
        for (; k + 4 <= n; k += 4) {
            v2d a = splat(0.0), b = splat(0.0);
            for (i64 i = q; i < n; ++i) {
                const double* ji = JT.row(i) + k;
                v2d di = splat(d[i]);
                a = a + di * load(ji);
                b = b + di * load(ji + 2);
            }
            store(z.data() + k, a);
            store(z.data() + k + 2, b);
        }
        for (; k + 2 <= n; k += 2) {
            v2d a = splat(0.0);
            for (i64 i = q; i < n; ++i) a = a + splat(d[i]) * load(JT.row(i) + k);
            store(z.data() + k, a);
        }
        for (; k < n; ++k) {
            double a = 0.0;
            for (i64 i = q; i < n; ++i) a += d[i] * JT(i, k);
            z[k] = a;
        }
    }
}

// Partial (dual) step and the blocking working constraint (-1: none).
inline double dual_step(const Vec& u, const Vec& r, i64 q, i64& drop) {
    double t1 = kInf;
    drop = -1;
    for (i64 j = 0; j < q; ++j) {
        if (r[j] > 0.0) {
            double t = u[j] / r[j];
            if (t < t1) {
                t1 = t;
                drop = j;
            }
        }
    }
    return t1;
}

// Full (primal) step; inf when the candidate's normal depends on the working set's.
inline double primal_step(const Vec& d, const Vec& z, const Vec& normal, double slack, i64 q) {
    double outside = 0.0, total = 0.0;
    i64 n = static_cast<i64>(d.size());
    i64 i = 0;
    for (; i < q && i < n; ++i) total += d[i] * d[i];
    for (; i < n; ++i) {
        double sq = d[i] * d[i];
        total += sq;
        outside += sq;
    }
    double zn = dot(z.data(), normal.data(), static_cast<i64>(z.size()));
    if (outside > kDependent * kDependent * total && zn > 0.0) return pymax(-slack / zn, 0.0);
    return kInf;
}

// The Givens sweeps of rotate_in (up: rotations j = hi - 1 down to lo + 1 on rows j - 1, j)
// and drop_constraint (down: j = lo .. hi - 2 on rows j, j + 1) applied to columns
// [t, t + 2 W) of a row-major matrix (row stride ld) in one pass, each row loaded and
// stored once: the row both rotations of a step meet is held in registers (`carry`).
// rot: per rotation j, its cc, ss and xny each twice (lanes), at rot + 6 j. Every entry
// undergoes givens_rows's operations (a' = a cc + b ss, b' = xny (a + a') - b) in the same
// order: the same bits.
template <int W>
inline void sweep_up(double* base, i64 ld, i64 t, i64 lo, i64 hi, const double* rot) {
    using namespace simd;
    double* pj = base + (hi - 1) * ld + t;
    v2d c[W];
#pragma GCC unroll 4
    for (int w = 0; w < W; ++w) c[w] = load(pj + 2 * w);
    for (i64 j = hi - 1; j > lo; --j, pj -= ld) {
        const double* rj = rot + 6 * j;
        v2d cv = load(rj), sv = load(rj + 2), xv = load(rj + 4);
        double* pa = pj - ld;
#pragma GCC unroll 4
        for (int w = 0; w < W; ++w) {
            v2d a = load(pa + 2 * w);
            v2d an = a * cv + c[w] * sv;
            store(pj + 2 * w, xv * (a + an) - c[w]);
            c[w] = an;
        }
    }
#pragma GCC unroll 4
    for (int w = 0; w < W; ++w) store(pj + 2 * w, c[w]);
}

template <int W>
inline void sweep_down(double* base, i64 ld, i64 t, i64 lo, i64 hi, const double* rot) {
    using namespace simd;
    double* pj = base + lo * ld + t;
    v2d c[W];
#pragma GCC unroll 4
    for (int w = 0; w < W; ++w) c[w] = load(pj + 2 * w);
    for (i64 j = lo; j < hi - 1; ++j, pj += ld) {
        const double* rj = rot + 6 * j;
        v2d cv = load(rj), sv = load(rj + 2), xv = load(rj + 4);
        double* pb = pj + ld;
#pragma GCC unroll 4
        for (int w = 0; w < W; ++w) {
            v2d b = load(pb + 2 * w);
            v2d an = c[w] * cv + b * sv;
            store(pj + 2 * w, an);
            c[w] = xv * (c[w] + an) - b;
        }
    }
#pragma GCC unroll 4
    for (int w = 0; w < W; ++w) store(pj + 2 * w, c[w]);
}

// Below this many columns rotate_in / drop_constraint rotate JT one rotation at a time, as
// each rotation's coefficients are made (givens_rows), not in one sweep after them all.
// (Tried: 48, the rotation of JT's rows filling the wait of the coefficients' serial chain of
// hypots: +0.4% instructions on the humanoid core and no time gain beyond the noise of a
// shared machine.)
constexpr i64 kSweepMin = 12;

// Every column of an n-column matrix by sweep_up / sweep_down (the last odd column by the
// scalar loop, givens_rows's tail).
inline void sweep(bool up, double* base, i64 n, i64 lo, i64 hi, const double* rot) {
    i64 t = 0;
    if (up) {
        for (; t + 8 <= n; t += 8) sweep_up<4>(base, n, t, lo, hi, rot);
        for (; t + 4 <= n; t += 4) sweep_up<2>(base, n, t, lo, hi, rot);
        for (; t + 2 <= n; t += 2) sweep_up<1>(base, n, t, lo, hi, rot);
    } else {
        for (; t + 8 <= n; t += 8) sweep_down<4>(base, n, t, lo, hi, rot);
        for (; t + 4 <= n; t += 4) sweep_down<2>(base, n, t, lo, hi, rot);
        for (; t + 2 <= n; t += 2) sweep_down<1>(base, n, t, lo, hi, rot);
    }
    for (; t < n; ++t) {
        if (up) {
            double* pj = base + (hi - 1) * n + t;
            double c = *pj;
            for (i64 j = hi - 1; j > lo; --j, pj -= n) {
                const double* rj = rot + 6 * j;
                double a = pj[-n];
                double an = a * rj[0] + c * rj[2];
                *pj = rj[4] * (a + an) - c;
                c = an;
            }
            *pj = c;
        } else {
            double* pj = base + lo * n + t;
            double c = *pj;
            for (i64 j = lo; j < hi - 1; ++j, pj += n) {
                const double* rj = rot + 6 * j;
                double b = pj[n];
                double an = c * rj[0] + b * rj[2];
                *pj = an;
                c = rj[4] * (c + an) - b;
            }
            *pj = c;
        }
    }
}

// std::hypot(x, y) with the same bits, inline (no call): glibc's algorithm (2.35 on: one sqrt
// and a correction, without FMA) where no step of it can leave the normal range (both in
// [2^-450, 2^450], or the smaller 0), so that any scaling the library applies there is exact
// and changes no bit; the library call itself for the rest. Checked bit for bit against the
// library's on 4e7 random pairs over the whole exponent range and the special values
// (tests/core/test_hypot_inline.py checks it against the library in every run).
inline double hypot_inline(double x, double y) {
    double ax = std::fabs(x), ay = std::fabs(y);
    if (ax < ay) std::swap(ax, ay);
    // (NaN compares false: !(ax <= 2^450) takes it to the library)
    if (!(ax <= 0x1p+450)) return std::hypot(x, y);
    if (!(ay >= 0x1p-450)) return ay == 0.0 ? ax + ay : std::hypot(x, y);
    if (ay <= ax * 0x1p-54) return ax + ay;
    double h = std::sqrt(ax * ax + ay * ay);
    double t1, t2;
    if (h <= 2.0 * ay) {
        double delta = h - ay;
        t1 = ax * (2.0 * delta - ax);
        t2 = (delta - 2.0 * (ax - ay)) * delta;
    } else {
        double delta = h - ax;
        t1 = 2.0 * delta * (ax - 2.0 * ay);
        t2 = (4.0 * delta - ay) * ay + delta * delta;
    }
    return h - (t1 + t2) / (2.0 * h);
}

// The rotation of entries j - 1, j of d that zeroes d[j] (rotate_in's): false where both are
// zero (no rotation); else (cc, ss) with cc >= 0 (or NaN), d[j - 1] = +-hypot and d[j] = 0.
inline bool givens_of(Vec& d, i64 j, double& cc, double& ss) {
    cc = d[j - 1];
    ss = d[j];
    double h = hypot_inline(cc, ss);
    if (h == 0.0) return false;
    d[j] = 0.0;
    ss /= h;
    cc /= h;
    if (cc < 0.0) {
        cc = -cc;
        ss = -ss;
        d[j - 1] = -h;
    } else {
        d[j - 1] = h;
    }
    return true;
}

inline void rotate_in_givens(Mat& JT, Vec& d, i64 q, Vec& rot);

// Add a constraint: one Householder reflection H of JT's rows q..n-1 (J's columns) so that
// only d[:q+1] is non-zero (d = J^T n, so H d is d of the reflected rows): x = d[q:] - alpha
// e_0, alpha = -sign(d[q]) |d[q:]| (no cancellation in x), H = I - 2 x x^T / |x|^2, applied
// to JT's rows q.. by reflect_columns (householder_qr's reflection of R's rows, the same
// operations). One norm where the Givens rotations chain n - q - 1 hypots (each waiting on
// the one before), and fewer operations a row. d[q] becomes alpha (R's new diagonal entry:
// its sign is free, as the Givens form's). Where d[q:]'s largest entry is outside [1e-140,
// 1e140] (a square could leave the normal range) or not finite, the Givens rotations
// (rotate_in_givens: hypot's scaling, and the old bits).
inline void rotate_in(Mat& JT, Vec& d, i64 q, Vec& rot) {
    i64 n = JT.rows;
    if (n - 1 <= q) return;
    double x0 = d[q];
    double big = std::fabs(x0), sig = 0.0;
    for (i64 i = q + 1; i < n; ++i) {
        double a = std::fabs(d[i]);
        if (!(a <= big)) big = a;  // (a NaN stays)
        sig += d[i] * d[i];
    }
    if (!(big >= 1e-140 && big <= 1e140)) {
        rotate_in_givens(JT, d, q, rot);
        return;
    }
    if (sig == 0.0) return;  // d[q+1:] zero already
    double alpha = std::sqrt(x0 * x0 + sig);
    if (x0 > 0.0) alpha = -alpha;
    d[q] = x0 - alpha;  // x = d[q:], |x|^2 = (x0 - alpha)^2 + sig
    double vn = d[q] * d[q] + sig;
    shape(rot, static_cast<size_t>(JT.cols));  // (reflect_columns' sums S: written before read)
    detail::reflect_columns(JT.a.data(), JT.cols, q, n - q, 0, JT.cols, d.data() + q, vn, rot.data());
    d[q] = alpha;
    for (i64 i = q + 1; i < n; ++i) d[i] = 0.0;
}

// rotate_in by Givens rotations of J's columns (JT's rows; the fallback above). The
// rotations' coefficients depend on d alone: taken first, in order (into rot, see sweep_up;
// cc -1 marks a skipped one, h = 0), then applied to JT by sweep (the same bits as
// givens_rows one rotation at a time).
inline void rotate_in_givens(Mat& JT, Vec& d, i64 q, Vec& rot) {
    i64 n = JT.rows;
    if (n - 1 <= q) return;
    if (n < kSweepMin) {  // one rotation at a time (the same bits; see kSweepMin)
        for (i64 j = n - 1; j > q; --j) {
            double cc, ss;
            if (givens_of(d, j, cc, ss)) givens_rows(JT.row(j - 1), JT.row(j), cc, ss, ss / (1.0 + cc), n);
        }
        return;
    }
    shape(rot, static_cast<size_t>(6 * n));
    bool skipped = false;
    for (i64 j = n - 1; j > q; --j) {
        double cc, ss;
        if (!givens_of(d, j, cc, ss)) {
            skipped = true;
            rot[6 * j] = -1.0;  // (a rotation's cc is >= 0 or NaN)
            continue;
        }
        double xny = ss / (1.0 + cc);
        double* rj = rot.data() + 6 * j;
        rj[0] = rj[1] = cc;
        rj[2] = rj[3] = ss;
        rj[4] = rj[5] = xny;
    }
    if (!skipped) {
        sweep(true, JT.row(0), n, q, n, rot.data());
        return;
    }
    // A rotation skipped (h = 0, rare): one rotation at a time, in the same order.
    for (i64 j = n - 1; j > q; --j) {
        const double* rj = rot.data() + 6 * j;
        if (rj[0] == -1.0) continue;
        givens_rows(JT.row(j - 1), JT.row(j), rj[0], rj[2], rj[4], n);
    }
}

// Remove working constraint `drop` of q and restore R's triangle (and J).
inline void drop_constraint(Mat& JT, Mat& R, Vec& u, IVec& act_row, IVec& act_side, BVec& in_set, i64 drop,
                            i64 q, Vec& rot) {
    using namespace simd;
    i64 n = JT.rows;
    in_set[act_row[drop]] = 0;
    for (i64 j = drop; j < q - 1; ++j) {
        act_row[j] = act_row[j + 1];
        act_side[j] = act_side[j + 1];
        u[j] = u[j + 1];
    }
    // R's columns drop + 1 .. q - 1 one to the left. R is upper triangular with exact zeros
    // below: column j + 1 has rows <= j + 1 only, and the rows below are zeros in both
    // columns; so row i moves its columns max(drop, i - 1) + 1 .. q - 1 (one copy a row).
    for (i64 i = 0; i < q; ++i) {
        i64 j0 = std::max<i64>(drop, i - 1);
        double* ri = R.row(i);
        for (i64 j = j0; j < q - 1; ++j) ri[j] = ri[j + 1];  // (a few entries: no call)
    }
    u[q - 1] = u[q];
    u[q] = 0.0;
    for (i64 i = 0; i < q; ++i) R(i, q - 1) = 0.0;  // (rows >= q of it are zeros)
    q -= 1;
    if (drop >= q) return;
    // R's rotations in order (each needs the one before), their coefficients kept in rot as
    // rotate_in's; then JT's in one sweep (sweep_down), the same bits as one at a time.
    shape(rot, static_cast<size_t>(6 * n));
    bool skipped = false;
    for (i64 j = drop; j < q; ++j) {
        double* rj = rot.data() + 6 * j;
        double cc = R(j, j);
        double ss = R(j + 1, j);
        double h = hypot_inline(cc, ss);
        if (h == 0.0) {
            skipped = true;
            rj[0] = -1.0;
            continue;
        }
        cc /= h;
        ss /= h;
        R(j + 1, j) = 0.0;
        if (cc < 0.0) {
            R(j, j) = -h;
            cc = -cc;
            ss = -ss;
        } else {
            R(j, j) = h;
        }
        double xny = ss / (1.0 + cc);
        givens_rows(R.row(j) + j + 1, R.row(j + 1) + j + 1, cc, ss, xny, q - j - 1);
        if (n < kSweepMin) {  // JT's rotation now (the same bits; see kSweepMin)
            givens_rows(JT.row(j), JT.row(j + 1), cc, ss, xny, n);
            continue;
        }
        rj[0] = rj[1] = cc;
        rj[2] = rj[3] = ss;
        rj[4] = rj[5] = xny;
    }
    if (n < kSweepMin) return;
    if (!skipped) {
        sweep(false, JT.row(0), n, drop, q + 1, rot.data());
        return;
    }
    for (i64 j = drop; j < q; ++j) {
        const double* rj = rot.data() + 6 * j;
        if (rj[0] == -1.0) continue;
        givens_rows(JT.row(j), JT.row(j + 1), rj[0], rj[2], rj[4], n);
    }
}

inline void mark(BVec& active, const IVec& act_row, const IVec& act_side, i64 q) {
    for (i64 j = 0; j < q; ++j) active[act_row[j]] = static_cast<i8>(act_side[j]);
}

// The cold answer with its KKT conditions checked (stationarity as a backward error, u >= 0).
inline QPResult verified(CMatRef H, CVecRef c, CMatRef C, const Vec& x, const Vec& u, const IVec& act_row,
                         const IVec& act_side, i64 q, i64 iterations) {
    i64 m = C.rows;
    i64 n = static_cast<i64>(x.size());
    QPResult res{x, SOLVED, iterations, BVec(static_cast<size_t>(m), 0), {}};
    double floor = dual_floor(u, q);
    Vec g = mv(H, x.data());
    for (i64 i = 0; i < n; ++i) g[i] = g[i] + c[i];
    Vec size(static_cast<size_t>(n));
    for (i64 i = 0; i < n; ++i) size[i] = std::fabs(c[i]);
    for (i64 i = 0; i < n; ++i)
        for (i64 j = 0; j < n; ++j) size[i] += std::fabs(H(i, j) * x[j]);
    for (i64 j = 0; j < q; ++j) {
        if (u[j] < -floor) {
            res.status = NUMERICAL;
            return res;
        }
        if (u[j] > floor) res.active[act_row[j]] = static_cast<i8>(act_side[j]);
        double us = u[j] * static_cast<double>(act_side[j]);
        for (i64 i = 0; i < n; ++i) {
            double term = us * C(act_row[j], i);
            g[i] -= term;
            size[i] += std::fabs(term);
        }
    }
    double scale = 1.0;
    for (i64 i = 0; i < n; ++i) scale = pymax(scale, size[i]);
    for (i64 i = 0; i < n; ++i) {
        if (std::fabs(g[i]) > kVerify * scale) {
            res.status = NUMERICAL;
            return res;
        }
    }
    return res;
}

// Re-solve the KKT system on the canonical active set (positive multipliers, by row).
inline QPResult polish(CMatRef H, CMatRef L, CVecRef c, CMatRef C, CVecRef lo, CVecRef hi, const Vec& x,
                       const Vec& u, const IVec& act_row, const IVec& act_side, i64 q, i64 iterations,
                       double tol) {
    i64 m = C.rows;
    i64 n = L.rows;
    BVec active(static_cast<size_t>(m), 0);
    double floor = dual_floor(u, q);
    for (i64 j = 0; j < q; ++j)
        if (u[j] > floor) active[act_row[j]] = static_cast<i8>(act_side[j]);
    IVec rows(static_cast<size_t>(n + 1)), sides(static_cast<size_t>(n + 1));
    i64 k = 0;
    for (i64 i = 0; i < m; ++i) {
        if (active[i] != 0) {
            rows[k] = i;
            sides[k] = active[i];
            k += 1;
        }
    }
    Vec xp, up;
    bool ok = kkt_solve(H, L, c, C, lo, hi, rows, sides, k, xp, up);
    if (ok && kkt_ok(xp, up, C, lo, hi, k, pymax(tol, 1e-9)))
        return QPResult{std::move(xp), SOLVED, iterations, std::move(active), {}};
    return QPResult{x, NUMERICAL, iterations, std::move(active), {}};
}

// Bounds widened by scale (1 + |bound|) (1 + i / m), distinct per row.
inline void widened(CVecRef lo, CVecRef hi, double scale, Vec& lo2, Vec& hi2) {
    i64 m = lo.size();
    zero_fill(lo2, static_cast<size_t>(m));
    zero_fill(hi2, static_cast<size_t>(m));
    double denom = static_cast<double>(std::max<i64>(m, 1));
    for (i64 i = 0; i < m; ++i) {
        double eps = scale * (1.0 + static_cast<double>(i) / denom);
        lo2[i] = lo[i] > -kBig ? lo[i] - eps * (1.0 + std::fabs(lo[i])) : lo[i];
        hi2[i] = hi[i] < kBig ? hi[i] + eps * (1.0 + std::fabs(hi[i])) : hi[i];
    }
}

// (true, answer) when the warm active set is still the QP's unique optimal one.
inline bool warm_answer(CMatRef H, CMatRef L, CVecRef c, CMatRef C, CVecRef lo, CVecRef hi,
                        VecRefT<const i8> warm, double tol, IVec& act_row, IVec& act_side, QPResult& out) {
    i64 m = C.rows;
    i64 n = L.rows;
    i64 q = 0;
    for (i64 i = 0; i < m; ++i)
        if (warm[i] != 0) q += 1;
    if (q == 0 || q > n) return false;
    q = 0;
    for (i64 i = 0; i < m; ++i) {
        if (warm[i] != 0) {
            act_row[q] = i;
            act_side[q] = warm[i];
            q += 1;
        }
    }
    Vec x, u;
    bool ok = kkt_solve(H, L, c, C, lo, hi, act_row, act_side, q, x, u);
    if (ok && strictly_optimal(x, u, C, lo, hi, act_row, q)) {
        // Where every multiplier is above polish's dual_floor (strictly_optimal's bound, unless
        // a NaN passed its tests), polish would take these rows in this (row) order and its
        // kkt_solve would give these bits: its answer without the second solve, only its
        // check left. Otherwise polish itself.
        double floor = dual_floor(u, q);
        bool all_rows = true;
        for (i64 j = 0; j < q; ++j) all_rows = all_rows && u[j] > floor;
        if (all_rows) {
            if (!kkt_ok(x, u, C, lo, hi, q, pymax(tol, 1e-9))) return false;
            BVec active(static_cast<size_t>(m), 0);
            for (i64 j = 0; j < q; ++j) active[act_row[j]] = static_cast<i8>(act_side[j]);
            out = QPResult{std::move(x), SOLVED, 0, std::move(active), {}};
            return true;
        }
        QPResult polished = polish(H, L, c, C, lo, hi, x, u, act_row, act_side, q, 0, tol);
        if (polished.status == SOLVED) {
            out = std::move(polished);
            return true;
        }
    }
    return false;
}

}  // namespace detail

// Solve min 1/2 x^T H x + c^T x s.t. lo <= C x <= hi exactly (see solve_qp in
// qpik/core/kernels.py). H (n, n), c (n,), C (m, n), lo/hi/warm (m,).
// raw: return the final iterate and working set without the checks and the re-solve (the
// cascade makes every answer exact and certifies it itself, qpik/_cpp/core/certify.hpp).
// factored: ws.L already holds H's Cholesky factor (lower triangle of ws.L, zeros above) and
// ws.x the unconstrained minimiser -H^-1 c, computed as below (the cascade's
// dual_stops_at_once), and warm has no row: the same steps from there.
inline QPResult solve_qp(CMatRef H, CVecRef c, CMatRef C, CVecRef lo, CVecRef hi, VecRefT<const i8> warm,
                         i64 max_iter, double tol, bool canonical, bool raw, QPScratch& ws, bool factored = false) {
    using namespace detail;
    i64 n = H.rows;
    i64 m = C.rows;
    BVec active(static_cast<size_t>(m), 0);
    Mat& Lm = ws.L;
    if (!factored) {
        detail::zero_upper(Lm, n);  // cholesky_into writes the rest before reading it
        if (!cholesky_into(H, n, 0.0, Lm.ref()))
            return QPResult{Vec(static_cast<size_t>(n), 0.0), NUMERICAL, 0, std::move(active), {}};
    }
    CMatRef L = Lm.cref();
    IVec& act_row = ws.act_row;
    IVec& act_side = ws.act_side;
    act_row.assign(static_cast<size_t>(n + 1), 0);
    act_side.assign(static_cast<size_t>(n + 1), 0);
    i64 q = 0;
    if (!factored) {
        QPResult polished;
        if (warm_answer(H, L, c, C, lo, hi, warm, tol, act_row, act_side, polished)) {
            polished.working = polished.active;  // strictly optimal: every row has u > 0
            return polished;
        }
    }
    Vec& x = ws.x;
    if (!factored) {
        Vec& mc = ws.mc;
        mc.resize(static_cast<size_t>(n));
        for (i64 i = 0; i < n; ++i) mc[i] = -c[i];
        forward_into(L, mc, ws.y);
        backward_into(L, ws.y, x);
    }
    inverse_transpose_into(Lm, ws.JT);
    Mat& J = ws.JT;
    Mat& R = ws.R;
    // R: read only where written (its upper triangle as columns are added, and the entry
    // below the diagonal drop_constraint moves there), so not cleared.
    shape(R, n, n);
    double r_norm = 1.0;
    Vec& u = ws.u;
    zero_fill(u, static_cast<size_t>(n + 1));
    Vec& d = ws.d;
    Vec& z = ws.z;
    Vec& r = ws.r;
    zero_fill(d, static_cast<size_t>(n));
    zero_fill(z, static_cast<size_t>(n));
    zero_fill(r, static_cast<size_t>(n + 1));
    BVec& in_set = ws.in_set;
    in_set.assign(static_cast<size_t>(m), 0);
    Vec& norms = ws.norms;
    IVec& unit = ws.unit;
    unit_columns_into(C, unit);
    IVec& dense = ws.dense;  // the rows most_violated takes C x of
    dense.clear();
    RowScan scan;
    bool scanned = tol >= 0.0;  // RowScan's condition
    if (scanned) {
        // The norms as row_norms_into takes them: a unit row's is sqrt(+0 + ... + 1 + ...) = 1
        // exactly; the others' summed as CT is laid out (row_scan_init).
        norms.resize(static_cast<size_t>(m));
        for (i64 i = 0; i < m; ++i) {
            if (unit[i] >= 0)
                norms[i] = 1.0;
            else
                dense.push_back(i);
        }
        if (!row_scan_init(C, lo, hi, tol, norms, unit, dense, ws, scan, true)) {
            // A zero row (norm 0, no candidate): laid out again without it (rare).
            i64 k = 0;
            for (i64 i : dense)
                if (norms[i] != 0.0) dense[k++] = i;
            dense.resize(static_cast<size_t>(k));
            row_scan_init(C, lo, hi, tol, norms, unit, dense, ws, scan, false);
        }
    } else {
        row_norms_into(C, norms);
        for (i64 i = 0; i < m; ++i)
            if (norms[i] != 0.0 && unit[i] < 0) dense.push_back(i);
    }
    Vec& normal = ws.normal;
    zero_fill(normal, static_cast<size_t>(n));
    i64 iterations = 0;
    while (true) {
        i64 row, side;
        if (scanned)
            most_violated_scan(x.data(), C, lo, hi, in_set, norms, unit, scan, ws, row, side);
        else
            most_violated(x.data(), C, lo, hi, in_set, tol, norms, unit, row, side, ws.cx, ws.rows, &dense);
        if (row < 0) {
            BVec working(static_cast<size_t>(m), 0);
            mark(working, act_row, act_side, q);
            QPResult out;
            if (raw) {
                BVec act(static_cast<size_t>(m), 0);
                double floor = dual_floor(u, q);
                for (i64 j = 0; j < q; ++j)
                    if (u[j] > floor) act[act_row[j]] = static_cast<i8>(act_side[j]);
                return QPResult{x, SOLVED, iterations, std::move(act), std::move(working)};
            }
            if (canonical) {
                QPResult polished = polish(H, L, c, C, lo, hi, x, u, act_row, act_side, q, iterations, tol);
                if (polished.status == SOLVED) {
                    polished.working = std::move(working);
                    return polished;
                }
            }
            QPResult ver = verified(H, c, C, x, u, act_row, act_side, q, iterations);
            if (ver.status == SOLVED || canonical) {
                ver.working = std::move(working);
                return ver;
            }
            QPResult polished = polish(H, L, c, C, lo, hi, x, u, act_row, act_side, q, iterations, tol);
            out = polished.status == SOLVED ? std::move(polished) : std::move(ver);
            out.working = std::move(working);
            return out;
        }
        double sd = static_cast<double>(side);
        {
            const double* cr = C.row(row);
            simd::v2d sv = simd::splat(sd);
            i64 k = 0;
            for (; k + 2 <= n; k += 2) simd::store(normal.data() + k, simd::load(cr + k) * sv);
            for (; k < n; ++k) normal[k] = cr[k] * sd;
        }
        double rhs = rhs_of(lo, hi, row, side);
        u[q] = 0.0;
        i64 d0 = 0, d1 = -1;  // the rows of d to take afresh (see directions)
        while (true) {
            iterations += 1;
            if (iterations > max_iter) {
                mark(active, act_row, act_side, q);
                return QPResult{x, MAX_ITER, iterations, std::move(active), {}};
            }
            directions(J, R, normal, unit[row], q, d, z, r, d0, d1);
            i64 drop;
            double t1 = dual_step(u, r, q, drop);
            double slack = dot(normal.data(), x.data(), n) - rhs;
            double t2 = primal_step(d, z, normal, slack, q);
            double t = pymin(t1, t2);
            if (t == kInf) {
                double nn = std::sqrt(dot(normal.data(), normal.data(), n));
                if (n == 0) throw BadArgument("solve_qp: zero-size array to reduction operation maximum");
                // np.abs(x).max(): the first NaN, else the largest.
                double xmax = std::fabs(x[0]);
                if (!std::isnan(xmax)) {
                    for (i64 k = 1; k < n; ++k) {
                        double v = std::fabs(x[k]);
                        if (std::isnan(v)) {
                            xmax = v;
                            break;
                        }
                        if (v > xmax) xmax = v;
                    }
                }
                if (-slack <= kRoundoff * (nn * (1.0 + xmax) + std::fabs(rhs))) {
                    in_set[row] = 1;
                    if (scanned) scan_enter(ws, scan, n, row);
                    break;
                }
                mark(active, act_row, act_side, q);
                return QPResult{x, INFEASIBLE, iterations, std::move(active), {}};
            }
            bool full = t2 <= t1;
            if (full) {
                // JT and d's rotation first (they read neither x nor u): where the step is
                // degenerate, x and u stay as they are (the step taken and undone before).
                rotate_in(J, d, q, ws.rot);
                for (i64 i = 0; i < q + 1; ++i) R(i, q) = d[i];
                if (std::fabs(d[q]) <= 1e-14 * r_norm) {
                    u[q] = 0.0;
                    in_set[row] = 1;
                    if (scanned) scan_enter(ws, scan, n, row);
                    break;
                }
                axpy(x.data(), t, z.data(), n);  // x[k] += t * z[k] (t = t2 < inf)
                axmy(u.data(), t, r.data(), q);  // u[j] -= t * r[j]
                u[q] += t;
                r_norm = pymax(r_norm, std::fabs(d[q]));
                act_row[q] = row;
                act_side[q] = side;
                in_set[row] = 1;
                if (scanned) scan_enter(ws, scan, n, row);
                q += 1;
                break;
            }
            if (t2 < kInf) axpy(x.data(), t, z.data(), n);  // x[k] += t * z[k]
            axmy(u.data(), t, r.data(), q);  // u[j] -= t * r[j]
            u[q] += t;
            i64 left = act_row[drop];
            drop_constraint(J, R, u, act_row, act_side, in_set, drop, q, ws.rot);
            if (scanned) scan_leave(ws, scan, n, left);
            d0 = drop;  // drop_constraint turned JT's rows drop..q - 1 only
            d1 = q;
            q -= 1;
        }
    }
}

// Rows at a bound at an approximate solution x: +1 lower, -1 upper.
inline BVec active_guess(CVecRef x, CMatRef C, CVecRef lo, CVecRef hi) {
    i64 m = C.rows, n = C.cols;
    BVec guess(static_cast<size_t>(m), 0);
    for (i64 i = 0; i < m; ++i) {
        double cx = 0.0;
        for (i64 j = 0; j < n; ++j) cx += C(i, j) * x[j];
        double scale = 1e-6 * (1.0 + std::fabs(cx));
        if (std::isfinite(lo[i]) && cx <= lo[i] + scale) guess[i] = 1;
        if (std::isfinite(hi[i]) && cx >= hi[i] - scale) guess[i] = -1;
    }
    return guess;
}

// solve_qp for one level, robust to degenerate vertices (rows widened by 1e-11, 1e-9).
inline QPResult solve_qp(CMatRef H, CVecRef c, CMatRef C, CVecRef lo, CVecRef hi, VecRefT<const i8> warm,
                         i64 max_iter, double tol, bool canonical, bool raw = false) {
    QPScratch ws;
    return solve_qp(H, c, C, lo, hi, warm, max_iter, tol, canonical, raw, ws);
}

// factored: see solve_qp (its first call only; the widened retries factor H again).
inline QPResult solve_level(CMatRef H, CVecRef c, CMatRef C, CVecRef lo, CVecRef hi, VecRefT<const i8> warm,
                            i64 max_iter, double tol, bool lower, bool canonical, bool raw, QPScratch& ws,
                            bool factored = false) {
    QPResult res = solve_qp(H, c, C, lo, hi, warm, max_iter, tol, canonical, raw, ws, factored);
    i64 st = res.status;
    if (st == SOLVED || st == MAX_ITER || (st == INFEASIBLE && !lower)) return res;
    i64 its = res.iterations;
    i64 m = lo.size();
    BVec cold(static_cast<size_t>(m), 0);
    for (double scale : {1e-11, 1e-9}) {
        Vec& lo2 = ws.lo2;
        Vec& hi2 = ws.hi2;
        detail::widened(lo, hi, scale, lo2, hi2);
        res = solve_qp(H, c, C, CVecRef(lo2), CVecRef(hi2), VecRefT<const i8>(cold), max_iter, tol, canonical, raw,
                       ws);
        its += res.iterations;
        res.iterations = its;
        if (res.status == SOLVED) return res;
    }
    return res;
}

inline QPResult solve_level(CMatRef H, CVecRef c, CMatRef C, CVecRef lo, CVecRef hi, VecRefT<const i8> warm,
                            i64 max_iter, double tol, bool lower, bool canonical, bool raw = false) {
    QPScratch ws;
    return solve_level(H, c, C, lo, hi, warm, max_iter, tol, lower, canonical, raw, ws);
}

}  // namespace qpik::core
