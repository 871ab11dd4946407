// The prioritised cascade: solve_cascade and the per-level helpers it calls (named for
// Python in qpik/core/kernels.py). The signature of solve_cascade is the contract the
// diffik layer (diffik/fused.hpp) calls.
#pragma once

#include <optional>
#include <stdexcept>

#include "../common.hpp"
#include "certify.hpp"
#include "linalg.hpp"
#include "qp.hpp"

namespace qpik::core {

// What solve_cascade returns (per level arrays have L entries).
struct CascadeResult {
    Vec dq;            // (n,)
    IVec status;       // (L,)
    Vec sigma;         // (L,)
    Vec lam2;          // (L,)
    IVec iterations;   // (L,)
    BVec active;       // (L, n + p) row-major: the final active sets
    Vec residuals;     // (L,) |A_k dq - b_k|
    Vec certificate;   // (L, 4) row-major: primal, stationarity, dual, complementarity
    double primal = 0.0;  // the final dq's largest scaled row violation (box and general)
    // With defer_sigma: the levels whose sigma was proved above the damping's threshold and the
    // cutoff (project_level's defer_floor; sigma NaN in `sigma`): L header entries (-1, or the
    // offset of the level's record), then each record: kind, rows, cols, need_null, rank_tol
    // and the matrix (rows, cols): R's first p rows (kind 0) or M itself (kind 1, the last
    // level's, before its QR); deferred_sigma gives the sigma the ranking would have given.
    // Empty without defer_sigma.
    Vec deferred;
};

// (AZ, sigma, rank, Zn) of project_level.
struct Projection {
    Mat AZ;
    double sigma = kInf;
    i64 rank = 0;
    Mat Zn;
};

// The level's QP in null-space coordinates (H, c, C, lo, hi) of reduced_qp.
struct ReducedQP {
    Mat H;
    Vec c;
    Mat C;
    Vec lo;
    Vec hi;
    // H's diagonal as mtm_into made it, before the regularisation was added (hraw_ok: H and
    // hraw are the current level's; normal_factor makes N = (A Z)^T A Z + s^2 I from them)
    Vec hraw;
    bool hraw_ok = false;
};

namespace detail {
// A Jacobi rotation of project_level (rows i, j), logged for Q's columns.
struct Rotation {
    i64 i, j;
    double cs, sn;
};

// The storage of nnls (kept by a caller that solves often; sizes only grow).
struct NnlsScratch {
    Vec res, w, s, f;
    BVec passive;
    IVec P;
    Mat MP;
    LsScratch ls;
    // the passive columns' QR kept from one added column to the next (nnls_into)
    Mat V, Rc;
    Vec vn, qy, col;
    IVec out, act;                   // the non-passive columns; the residual's
    std::vector<const double*> cols;  // the columns (nnls_cols)
    Mat MT;                           // nnls_into's M transposed
    // drop_pinned's spanning certificate (span_pins)
    IVec pset, pperm;
    Vec pw, pb, pc, pu;
    Mat PN, PR, PQ;
    QRScratch pqr;
};
}  // namespace detail

// The storage of one solver's cascade, kept from one solve to the next by its owner (the
// Python HierarchySolver, a compiled step's kernel): the matrices and vectors of every
// level, sized when first needed and resized only when a size grows, so a solve of the
// same sizes allocates them no more. Nothing carries from one solve to the next but
// capacity: each buffer is sized and filled before it is read (the same bits as fresh
// storage). One per solver, never shared between threads.
struct Workspace {
    Mat G_eq;  // solve_cascade_rows' equilibrated general rows (detail::equilibrated_rows)
    Vec h_eq;
    Mat Z, Ztmp;
    // solve_cascade_into: the general rows in reach of the box (rows_in_reach) and the others
    IVec g_kept;
    Vec reach_cols;  // rows_in_reach's per-column bounds (3 n)
    Mat g_in, g_out;
    Vec h_in, h_out;
    std::vector<i8> warm_in, active_in;
    Mat A_flush;  // the cascade's A with its rows' round-off entries zero (flushed_rows)
    // project_level's proved full rank (defer_floor): R's rows kept for deferred_sigma
    bool deferred = false;
    int defer_kind = 0;  // 0: R's first p rows; 1: M itself (not yet factored)
    Mat defer_R;
    Projection pr;
    ReducedQP qp;
    LSForm ls;
    QPScratch qps;
    CertScratch cs;
    // project_level
    Mat Mt, Q, R, Qt, Qr;
    IVec perm, null_cols;
    Vec sq, sv;
    IVec clean;
    std::vector<detail::Rotation> log;
    QRScratch qr;
    // reduced_qp, ls_form, the cascade; gsq: |G_j|^2 per general row (row_sq_of)
    Mat GZ;
    Vec gsq;
    // the box of the levels below a damped level (lower_trust: trust_box)
    Vec trust_lb, trust_ub;
    // the feasibility check of a level-0 infeasibility claim (feasible_after_all)
    Mat eye;
    Vec zeros;
    BVec cold_rows;
    double h_reg = 0.0;  // reduced_objective's reg where it left H to make_h (h_later)
    Vec e, c1, c2, Gd, zd, Zz, Ad;
    // drop_pinned
    std::vector<Vec> normals;
    IVec owner;
    Vec sum;
    detail::NnlsScratch nnls;
    IVec state, others, pinned;
    IVec pin_keep, pin_touched;  // drop_pinned's coordinates no pinned normal touches, and the others
    // primal_guess: its working set (rows, sides), multipliers, candidate and row products
    IVec pg_rows, pg_sides, pg_next, pg_next_sides;
    Vec pg_u, pg_z, pg_cz, pg_norm;
    BVec box_pinned;
    Mat pin_gram, pin_factor;  // the independence test's Gram matrix and its factor
    Mat N;
    Vec y, u, res;
    // the cascade's level answer
    Vec z, free_z, rz;  // rz: the row-space try's candidate (solve_cascade_into)
    IVec final_rows, final_sides;
    // level_residuals' A x - b; the result a caller of solve_cascade_into may keep here (its
    // storage reused by the next solve; every entry written by each)
    Vec lres;
    CascadeResult result;
    // The stacked problem a binding builds from the levels (qpik/_cpp/bind_core.cpp,
    // solve_levels): every entry written for each call.
    struct Stacked {
        Mat A;
        Vec b, w, reg;
        IVec starts;
        BVec warm_zero;
    } stacked;
};

namespace detail {

// Whether some general row G_j x <= h_j is unmet at every x of the box lb <= x <= ub: its
// least value over the box, sum_i min(G_ji lb_i, G_ji ub_i) (-inf where an unbounded side
// enters), is above h_j by more than kCertify times the row's scale (|h_j| plus
// sum_i |G_ji| max(|lb_i|, |ub_i|)): a proof of infeasibility that needs no solve. A row
// that no displacement moves (G_j = 0, or entries of 1e-20 against a box of 0.03: erd Panda's
// collision pair between bodies no joint separates) with h_j < 0 is the usual one; the dual
// method skips a row of norm 0 (or nearly) and would end numerical_failure there.
inline bool row_unmet_in_box(CMatRef G, CVecRef h, CVecRef lb, CVecRef ub) {
    const i64 p = G.rows, n = G.cols;
    for (i64 j = 0; j < p; ++j) {
        if (!(std::fabs(h[j]) < kBig)) continue;
        const double* g = G.row(j);
        double least = 0.0, scale = std::fabs(h[j]);
        bool bounded = true;
        for (i64 i = 0; i < n && bounded; ++i) {
            if (g[i] == 0.0) continue;
            const double side = g[i] > 0.0 ? lb[i] : ub[i];
            if (!(std::fabs(side) < kBig) || !std::isfinite(g[i])) {
                bounded = false;
                break;
            }
            least += g[i] * side;
            scale += std::fabs(g[i]) * pymax(std::fabs(lb[i]), std::fabs(ub[i]));
        }
        if (bounded && least > h[j] + kCertify * scale) return true;
    }
    return false;
}

// kFlushEps: see solve_cascade_into.
constexpr double kFlushEps = 2.220446049250313e-16;
// A itself where no row has a nonzero entry at or below kFlushEps n |row|_max, else a copy in
// `store` with those entries zero.
inline CMatRef flushed_rows(CMatRef A, Mat& store) {
    using namespace simd;
    const i64 m = A.rows, n = A.cols;
    const double rel = kFlushEps * static_cast<double>(n);
    // A row's largest |a| (top) and smallest nonzero |a| (low), two lanes at a time (a NaN
    // makes neither: its comparisons are false; the largest and smallest of a set are exact
    // in any order).
    const v2d zero = splat(0.0), inf = splat(kInf);
    auto scan = [&](const double* a, double& top, double& low) {
        v2d hi = zero, lo = inf;
        i64 j = 0;
        for (; j + 2 <= n; j += 2) {
            const v2d v = vabs(load(a + j));
            hi = v > hi ? v : hi;
            const v2d nz = v > zero ? v : inf;
            lo = nz < lo ? nz : lo;
        }
        top = pymax(hi[0], hi[1]);
        low = std::min(lo[0], lo[1]);
        for (; j < n; ++j) {
            const double v = std::fabs(a[j]);
            top = pymax(top, v);
            if (v > 0.0 && v < low) low = v;
        }
    };
    // A row's entries at or below rel top are flushed; a row with inf is left as it is (for
    // the checks), as is a row with no such entry (its smallest nonzero one above the cut).
    auto cut_of = [rel](double top) { return std::isfinite(top) ? rel * top : 0.0; };
    i64 first = -1;
    double top = 0.0, low = 0.0;
    for (i64 i = 0; i < m && first < 0; ++i) {
        scan(A.row(i), top, low);
        if (low <= cut_of(top)) first = i;
    }
    if (first < 0) return A;
    shape(store, m, n);
    const size_t bytes = static_cast<size_t>(n) * sizeof(double);
    for (i64 i = 0; i < first; ++i) std::memcpy(store.row(i), A.row(i), bytes);
    for (i64 i = first; i < m; ++i) {
        const double* a = A.row(i);
        double* s = store.row(i);
        if (i > first) scan(a, top, low);
        const double cut = cut_of(top);
        if (!(low <= cut)) {  // (nothing to flush in this row)
            std::memcpy(s, a, bytes);
            continue;
        }
        // s_j = 0 where a_j != 0 and |a_j| <= cut, else a_j (two lanes at a time)
        const v2d cv = splat(cut);
        i64 j = 0;
        for (; j + 2 <= n; j += 2) {
            const v2d x = load(a + j);
            const v2d flushed = (x != zero) & (vabs(x) <= cv) ? zero : x;
            simd::store(s + j, flushed);
        }
        for (; j < n; ++j) s[j] = a[j] != 0.0 && std::fabs(a[j]) <= cut ? 0.0 : a[j];
    }
    return store.cref();
}

// Whether every entry of A is finite.
inline bool all_finite(CMatRef A) {
    for (i64 i = 0; i < A.rows; ++i)
        for (i64 j = 0; j < A.cols; ++j)
            if (!std::isfinite(A(i, j))) return false;
    return true;
}

// Whether diag(1/w) A is the identity (square, every weight positive).
inline bool unit_rows(CMatRef A, CVecRef w) {
    i64 m = A.rows, n = A.cols;
    if (m != n) return false;
    for (i64 i = 0; i < m; ++i) {
        if (!(w[i] > 0.0)) return false;
        for (i64 j = 0; j < n; ++j)
            if (A(i, j) != (i == j ? w[i] : 0.0)) return false;
    }
    return true;
}

// Per level, |A_k x - b_k| over all its rows, into out (r: scratch).
inline void level_residuals_into(CMatRef A, CVecRef b, VecRefT<const i64> starts, const Vec& x, Vec& r, Vec& out) {
    mv_into(A, x.data(), r);
    for (i64 i = 0; i < A.rows; ++i) r[i] = r[i] - b[i];
    i64 L = starts.size() - 1;
    shape(out, static_cast<size_t>(L));  // every entry written below
    for (i64 k = 0; k < L; ++k) {
        double s = 0.0;
        for (i64 i = starts[k]; i < starts[k + 1]; ++i) s += r[i] * r[i];
        out[k] = std::sqrt(s);
    }
}

inline Vec level_residuals(CMatRef A, CVecRef b, VecRefT<const i64> starts, const Vec& x) {
    Vec r, out;
    level_residuals_into(A, b, starts, x, r, out);
    return out;
}

}  // namespace detail

namespace detail {

// The rotation (cs, sn) of one-sided Jacobi that makes two rows orthogonal (alpha, beta their
// squared norms, gamma != 0 their product): x' = cs x - sn y, y' = sn x + cs y with
// tan(theta) = t = sign(zeta) / (|zeta| + sqrt(1 + zeta^2)), zeta = (beta - alpha) / (2 gamma)
// (Rutishauser's root, |theta| <= pi/4), written with fewer divisions and roots on the
// rotation's critical path:
// - |zeta| >= 2^27 (an angle below 2^-28, the common case once the rows are nearly
//   orthogonal): t^2 < 2^-56, so cs = 1 / sqrt(1 + t^2) rounds to 1 and sn = t = 1 / (2 zeta)
//   to within 2^-56 relative: cs = 1, sn = gamma / (beta - alpha) (one division);
// - |zeta| >= 2^7: with x = gamma / (beta - alpha) = 1 / (2 zeta) (|x| <= 2^-8, u = x^2 <=
//   2^-16), tan(2 theta) = 2 x, so t = x (1 - t^2) = x (1 - u + 2 u^2 - 5 u^3 + 14 u^4 ...)
//   and cs = cos(theta) = 1 - u / 2 + 11 u^2 / 8 - 69 u^3 / 16 + 1843 u^4 / 128 ...: both
//   through u^3 (the terms left out below 2^-59 relative), sn = cs t (one division);
// - otherwise, with d = beta - alpha, g = 2 gamma, h = hypot(d, g): t = sign(zeta) |g| /
//   (|d| + h), 1 + t^2 = 2 h / (|d| + h), so cs = (|d| + h) r, sn = sign(zeta) |g| r with
//   r = 1 / sqrt(2 h (|d| + h)) (two roots and one division rather than three divisions and
//   two roots; no cancellation: |d| + h adds two nonnegative numbers);
// - where d^2 + g^2 or 2 h (|d| + h) could overflow or underflow (|d| or |g| above 1e150, or
//   both below 1e-150), the textbook formulas from zeta.
// (Always inlined: a call would pass cs and sn through memory on the round's critical path.)
__attribute__((always_inline)) inline void jacobi_rotation(double alpha, double beta, double gamma, double& cs, double& sn) {
    const double d = beta - alpha, g = 2.0 * gamma;
    const double ad = std::fabs(d), ag = std::fabs(g);
    if (ag <= 0x1p-27 * ad) {
        cs = 1.0;
        sn = gamma / d;  // sign(zeta) |g| / (2 |d|) = g / (2 d)
        return;
    }
    if (ag <= 0x1p-7 * ad) {
        const double x = gamma / d, u = x * x;
        const double t = x * (1.0 - u * (1.0 - u * (2.0 - 5.0 * u)));
        cs = 1.0 - u * (0.5 - u * (1.375 - u * 4.3125));
        sn = cs * t;
        return;
    }
    if (ad < 1e150 && ag < 1e150 && (ad > 1e-150 || ag > 1e-150)) {
        const double h = std::sqrt(d * d + g * g);
        const double u = ad + h;
        const double r = 1.0 / std::sqrt(2.0 * h * u);
        const bool negative = d != 0.0 && ((d < 0.0) != (g < 0.0));  // zeta < 0 (zeta = +-0 counts as >= 0)
        cs = u * r;
        sn = (negative ? -ag : ag) * r;
        return;
    }
    const double zeta = d / g;
    const double tt = (zeta >= 0.0 ? 1.0 : -1.0) / (std::fabs(zeta) + std::sqrt(1.0 + zeta * zeta));
    cs = 1.0 / std::sqrt(1.0 + tt * tt);
    sn = cs * tt;
}

// Whether rows of squared norms alpha, beta with product gamma count as orthogonal:
// gamma == 0 or |gamma| <= 1e-15 sqrt(alpha) sqrt(beta), decided by gamma^2 <= 1e-30 alpha
// beta (no root) where alpha beta lies in [1e-250, 1e250] (neither side then overflows or
// leaves the normal range: gamma^2 <= alpha beta to round-off); else by the roots of alpha and
// beta apart (alpha beta itself would overflow, every pair then found orthogonal, or
// underflow, none).
// A row whose squared norm is 0 as summed (every entry below about 1e-162, its squares
// underflowing) counts as orthogonal to any other: no rotation can make it more so, and
// one with it is by an angle whose sine underflows too (0 or a subnormal), so that it
// changes neither row: the pair was found not orthogonal again, sweep after sweep, up to
// the sweeps' bound (60, 3 M instructions a level on mink's arm_dual_panda, whose free
// object joint's zero rows, turned by the Gram matrix's eigenvectors, kept such residues).
// floor: a squared norm at or below which a row counts as orthogonal to any other (rank_rows':
// far below the rank cutoff, so that neither the rank, nor sigma, nor the null directions
// move beyond round-off; its rotations only turned the null rows' noise against the others,
// sweep after sweep: 13 sweeps on mink's arm_dual_panda level, a few without).
inline bool jacobi_orthogonal(double alpha, double beta, double gamma, double floor = 0.0) {
    if (gamma == 0.0 || alpha <= floor || beta <= floor) return true;
    const double ab = alpha * beta;
    if (ab >= 1e-250 && ab <= 1e250) return gamma * gamma <= 1e-30 * ab;
    return std::fabs(gamma) <= 1e-15 * (std::sqrt(alpha) * std::sqrt(beta));
}

// The pairs of p rows in a round-robin order (the circle method), into start (rounds + 1),
// pi and pj (p (p - 1) / 2 each): p - 1 rounds of p / 2 disjoint pairs (p even), or p rounds
// of (p - 1) / 2 (p odd: one row rests each round); every pair once a sweep. Returns the
// number of rounds. Within a round no two pairs share a row, so their products, rotations and
// sums are independent (they overlap in the processor's pipeline, where the cyclic-by-row
// order chains every rotation on the one before). at: scratch of p + 1 entries.
inline i64 jacobi_rounds(i64 p, i64* start, i64* pi, i64* pj, i64* at) {
    const i64 n = p + (p & 1);  // with a resting slot p where p is odd
    // p even: row 0 at the fixed position 0, the others at positions 1..; p odd: the resting
    // slot at position 0 and rows 0.. at positions 1.. (p = 3: the cyclic order (0, 1),
    // (0, 2), (1, 2))
    for (i64 k = 0; k < n; ++k) at[k] = (p & 1) ? (k == 0 ? p : k - 1) : k;
    i64 np = 0;
    for (i64 r = 0; r + 1 < n; ++r) {
        start[r] = np;
        for (i64 k = 0; k < n / 2; ++k) {
            const i64 a = at[k], b = at[n - 1 - k];
            if (a >= p || b >= p) continue;
            pi[np] = a < b ? a : b;
            pj[np] = a < b ? b : a;
            ++np;
        }
        const i64 last = at[n - 1];  // position 0 fixed, the others turn by one
        for (i64 k = n - 1; k > 1; --k) at[k] = at[k - 1];
        at[1] = last;
    }
    const i64 rounds = n > 1 ? n - 1 : 0;
    start[rounds] = np;
    return rounds;
}

// x . y over n = C (C > 0, known to the compiler) or cols entries, summed in four lanes (by t
// mod 4; where n mod 4 >= 2, the last pair in lanes 0 and 1), the lanes added as (0 + 2) +
// (1 + 3), then an odd n's last entry.
template <int C>
inline double jacobi_dot(const double* x, const double* y, i64 cols) {
    using namespace simd;
    const i64 n = C > 0 ? C : cols;
    v2d a = splat(0.0), b = splat(0.0);
    i64 t = 0;
    // (n >= 4: the lanes start from their first products rather than from +0 plus them, one
    // add less on the rotations' critical path: the same sums but for the sign of an exact
    // zero, which neither a square's sum (never -0) nor a product gamma (gamma == 0 is
    // orthogonal whatever its sign) shows)
    if (n >= 4) {
        a = load(x) * load(y);
        b = load(x + 2) * load(y + 2);
        t = 4;
    }
#pragma GCC unroll 2
    for (; t + 4 <= n; t += 4) {
        a += load(x + t) * load(y + t);
        b += load(x + t + 2) * load(y + t + 2);
    }
    if (t + 2 <= n) {
        a += load(x + t) * load(y + t);
        t += 2;
    }
    a += b;
    double s = a[0] + a[1];
    if (t < n) s += x[t] * y[t];
    return s;
}

// x . x as jacobi_dot sums it.
template <int C>
inline double jacobi_sq(const double* x, i64 cols) {
    return jacobi_dot<C>(x, x, cols);
}

// The rotation of two rows (x' = cs x - sn y, y' = sn x + cs y, as jacobi_rows), and their
// squared norms summed as jacobi_sq sums them, in the same pass.
template <int C>
inline void jacobi_turn(double* x, double* y, double cs, double sn, i64 cols, double& sx, double& sy) {
    using namespace simd;
    const i64 n = C > 0 ? C : cols;
    const v2d c2 = splat(cs), s2 = splat(sn);
    v2d ax = splat(0.0), bx = splat(0.0), ay = splat(0.0), by = splat(0.0);
    auto turn = [&](i64 t, v2d& accx, v2d& accy) {
        const v2d u = load(x + t), v = load(y + t);
        const v2d un = c2 * u - s2 * v;
        const v2d vn = s2 * u + c2 * v;
        store(x + t, un);
        store(y + t, vn);
        accx += un * un;
        accy += vn * vn;
    };
    i64 t = 0;
    if (n >= 4) {  // (the sums from their first squares, as jacobi_dot's)
        auto first = [&](i64 t0, v2d& accx, v2d& accy) {
            const v2d u = load(x + t0), v = load(y + t0);
            const v2d un = c2 * u - s2 * v;
            const v2d vn = s2 * u + c2 * v;
            store(x + t0, un);
            store(y + t0, vn);
            accx = un * un;
            accy = vn * vn;
        };
        first(0, ax, ay);
        first(2, bx, by);
        t = 4;
    }
#pragma GCC unroll 2
    for (; t + 4 <= n; t += 4) {
        turn(t, ax, ay);
        turn(t + 2, bx, by);
    }
    if (t + 2 <= n) {
        turn(t, ax, ay);
        t += 2;
    }
    ax += bx;
    ay += by;
    double qx = ax[0] + ax[1], qy = ay[0] + ay[1];
    if (t < n) {
        const double u = x[t], v = y[t];
        const double un = cs * u - sn * v, vn = sn * u + cs * v;
        x[t] = un;
        y[t] = vn;
        qx += un * un;
        qy += vn * vn;
    }
    sx = qx;
    sy = qy;
}

// One-sided Jacobi on p rows (row i at base + i stride, each C or cols long), by the rounds of disjoint pairs of
// jacobi_rounds until a sweep rotates nothing: s[i] = |row i|^2 (jacobi_sq) on return,
// recomputed only after the row was rotated (a row left alone keeps its bits). The rotations
// are appended to log (in the order applied) when log_rotations. A pair found orthogonal is
// checked again only after one of its rows was rotated: clean[i p + j] the time (a count of
// checks and rotations, from 1) it was last found orthogonal, stamp[i] the time row i was last
// rotated (0 if never); a pair is clean when found orthogonal after both its rows were last
// rotated (its rows and norms are then the same bits, so the check would give the same
// answer). A round is taken in chunks of up to kJacobiChunk pairs: their products, then their
// checks and rotation angles, then their rotations (independent work side by side).
constexpr int kJacobiChunk = 8;

template <int C>
inline void jacobi_sweeps(double* base, i64 stride, i64 p, i64 cols, bool log_rotations, double* s, i64* clean,
                          i64* stamp, const i64* start, const i64* pi, const i64* pj, i64 rounds,
                          std::vector<Rotation>& log, double floor = 0.0) {
    auto row = [&](i64 i) { return base + i * stride; };
    constexpr int kBatch = 32;
    Rotation batch[kBatch];
    int nb = 0;
    i64 now = 0;
    for (int sweep = 0; sweep < 60; ++sweep) {
        bool rotated = false;
        for (i64 round = 0; round < rounds; ++round) {
            for (i64 k0 = start[round]; k0 < start[round + 1]; k0 += kJacobiChunk) {
                const i64 k1 = std::min(k0 + kJacobiChunk, start[round + 1]);
                i64 ti[kJacobiChunk], tj[kJacobiChunk];
                double gam[kJacobiChunk];
                int nt = 0;
                for (i64 k = k0; k < k1; ++k) {
                    const i64 i = pi[k], j = pj[k];
                    const i64 c = clean[i * p + j];
                    if (c > stamp[i] && c > stamp[j]) continue;
                    ti[nt] = i;
                    tj[nt] = j;
                    gam[nt] = jacobi_dot<C>(row(i), row(j), cols);
                    ++nt;
                }
                i64 ri[kJacobiChunk], rj[kJacobiChunk];
                double cs[kJacobiChunk], sn[kJacobiChunk];
                int nr = 0;
                for (int q = 0; q < nt; ++q) {
                    const i64 i = ti[q], j = tj[q];
                    if (jacobi_orthogonal(s[i], s[j], gam[q], floor)) {
                        clean[i * p + j] = ++now;
                        continue;
                    }
                    jacobi_rotation(s[i], s[j], gam[q], cs[nr], sn[nr]);
                    ri[nr] = i;
                    rj[nr] = j;
                    ++nr;
                }
                for (int q = 0; q < nr; ++q) {
                    const i64 i = ri[q], j = rj[q];
                    jacobi_turn<C>(row(i), row(j), cs[q], sn[q], cols, s[i], s[j]);
                    if (log_rotations) {
                        batch[nb++] = Rotation{i, j, cs[q], sn[q]};
                        if (nb == kBatch) {
                            log.insert(log.end(), batch, batch + nb);
                            nb = 0;
                        }
                    }
                    stamp[i] = stamp[j] = ++now;
                }
                if (nr) rotated = true;
            }
        }
        if (!rotated) break;
    }
    if (nb) log.insert(log.end(), batch, batch + nb);
}

// jacobi_sweeps for p <= kJacobiFixed rows of C <= kJacobiFixed entries: the rows, their
// squared norms, the pairs' stamps and the order on the stack (no store to a row can then
// alias the norms or the order), copied back at the end; the same operations as
// jacobi_sweeps<0> on R's rows (the same bits), the loops over a row unrolled.
constexpr i64 kJacobiFixed = 16;

template <int C>
inline void jacobi_row_norms_fixed(Mat& R, i64 p, bool log_rotations, Vec& sq, std::vector<Rotation>& log,
                                   double floor = 0.0) {
    constexpr int P = static_cast<int>(kJacobiFixed);
    alignas(16) double W[P][C];
    double s[P];
    for (i64 i = 0; i < p; ++i) {
        std::memcpy(W[i], R.row(i), sizeof(double) * C);
        s[i] = jacobi_sq<C>(W[i], C);
    }
    log.clear();
    i64 clean[P * P], stamp[P];
    for (i64 i = 0; i < p; ++i) {
        stamp[i] = 0;
        for (i64 j = 0; j < p; ++j) clean[i * p + j] = 0;
    }
    i64 start[P + 1], pi[P * (P - 1) / 2], pj[P * (P - 1) / 2], at[P + 1];
    const i64 rounds = jacobi_rounds(p, start, pi, pj, at);
    jacobi_sweeps<C>(&W[0][0], C, p, C, log_rotations, s, clean, stamp, start, pi, pj, rounds, log, floor);
    sq.resize(static_cast<size_t>(p));  // every entry written
    for (i64 i = 0; i < p; ++i) {
        sq[i] = s[i];
        std::memcpy(R.row(i), W[i], sizeof(double) * C);
    }
}

// jacobi_rounds' order for P rows, made at compile time (jacobi_square), with touch[i] the
// bits of the pairs that hold row i.
template <int P>
struct JacobiOrder {
    static constexpr int kPairs = P * (P - 1) / 2;
    int rounds = 0;
    int start[P + 1] = {};
    int pi[kPairs] = {};
    int pj[kPairs] = {};
    std::uint64_t touch[P] = {};
    constexpr JacobiOrder() {
        const int n = P + (P & 1);
        int at[P + 2] = {};
        for (int k = 0; k < n; ++k) at[k] = (P & 1) ? (k == 0 ? P : k - 1) : k;
        int np = 0;
        for (int r = 0; r + 1 < n; ++r) {
            start[r] = np;
            for (int k = 0; k < n / 2; ++k) {
                const int a = at[k], b = at[n - 1 - k];
                if (a >= P || b >= P) continue;
                pi[np] = a < b ? a : b;
                pj[np] = a < b ? b : a;
                touch[pi[np]] |= std::uint64_t{1} << np;
                touch[pj[np]] |= std::uint64_t{1} << np;
                ++np;
            }
            const int last = at[n - 1];
            for (int k = n - 1; k > 1; --k) at[k] = at[k - 1];
            at[1] = last;
        }
        rounds = n > 1 ? n - 1 : 0;
        start[rounds] = np;
    }
};

// jacobi_row_norms_fixed for a square block (p = cols = P, 2 <= P <= kJacobiSquare): the same
// rounds, the same products, checks, rotations and sums in the same order (the same bits),
// with the order known to the compiler (every round unrolled, no index loaded) and the clean
// pairs held as bits (a pair's bit set when found orthogonal, cleared when one of its rows is
// rotated: the stamps' rule). Within a round the pairs share no row, so each pair's work is
// its own whatever the order they are taken in.
constexpr int kJacobiSquare = 8;

template <int P>
inline void jacobi_row_norms_square(Mat& R, bool log_rotations, Vec& sq, std::vector<Rotation>& log,
                                    double floor = 0.0) {
    static constexpr JacobiOrder<P> ord{};
    constexpr int kRound = P / 2;  // pairs per round, at most
    alignas(16) double W[P][P];
    double s[P];
    for (int i = 0; i < P; ++i) {
        std::memcpy(W[i], R.row(i), sizeof(double) * P);
        s[i] = jacobi_sq<P>(W[i], P);
    }
    log.clear();
    constexpr int kBatch = 32;
    Rotation batch[kBatch];
    int nb = 0;
    std::uint64_t clean = 0;
    for (int sweep = 0; sweep < 60; ++sweep) {
        bool rotated = false;
#pragma GCC unroll 16
        for (int round = 0; round < ord.rounds; ++round) {
            const int k0 = ord.start[round], k1 = ord.start[round + 1];
            double gam[kRound] = {}, cs[kRound] = {}, sn[kRound] = {};
            bool act[kRound], rot[kRound];
#pragma GCC unroll 16
            for (int k = k0; k < k1; ++k) {
                act[k - k0] = !(clean & (std::uint64_t{1} << k));
                if (act[k - k0]) gam[k - k0] = jacobi_dot<P>(W[ord.pi[k]], W[ord.pj[k]], P);
            }
#pragma GCC unroll 16
            for (int k = k0; k < k1; ++k) {
                const int q = k - k0, i = ord.pi[k], j = ord.pj[k];
                rot[q] = false;
                if (!act[q]) continue;
                if (jacobi_orthogonal(s[i], s[j], gam[q], floor)) {
                    clean |= std::uint64_t{1} << k;
                    continue;
                }
                jacobi_rotation(s[i], s[j], gam[q], cs[q], sn[q]);
                rot[q] = true;
            }
#pragma GCC unroll 16
            for (int k = k0; k < k1; ++k) {
                const int q = k - k0, i = ord.pi[k], j = ord.pj[k];
                if (!rot[q]) continue;
                jacobi_turn<P>(W[i], W[j], cs[q], sn[q], P, s[i], s[j]);
                if (log_rotations) {
                    batch[nb++] = Rotation{i, j, cs[q], sn[q]};
                    if (nb == kBatch) {
                        log.insert(log.end(), batch, batch + nb);
                        nb = 0;
                    }
                }
                clean &= ~(ord.touch[i] | ord.touch[j]);
                rotated = true;
            }
        }
        if (!rotated) break;
    }
    if (nb) log.insert(log.end(), batch, batch + nb);
    sq.resize(static_cast<size_t>(P));  // every entry written
    for (int i = 0; i < P; ++i) {
        sq[i] = s[i];
        std::memcpy(R.row(i), W[i], sizeof(double) * P);
    }
}

// One-sided Jacobi on the first p rows of R (each cols long): jacobi_sweeps, the rows rotated
// in place; sq[i] = |row i|^2 on return; clean: scratch (the pairs' stamps and the order).
inline void jacobi_row_norms(Mat& R, i64 p, i64 cols, bool log_rotations, Vec& sq, IVec& clean,
                             std::vector<Rotation>& log, double floor = 0.0) {
    if (p == cols) {
        switch (p) {
            case 2: return jacobi_row_norms_square<2>(R, log_rotations, sq, log, floor);
            case 3: return jacobi_row_norms_square<3>(R, log_rotations, sq, log, floor);
            case 4: return jacobi_row_norms_square<4>(R, log_rotations, sq, log, floor);
            case 5: return jacobi_row_norms_square<5>(R, log_rotations, sq, log, floor);
            case 6: return jacobi_row_norms_square<6>(R, log_rotations, sq, log, floor);
            case 7: return jacobi_row_norms_square<7>(R, log_rotations, sq, log, floor);
            case 8: return jacobi_row_norms_square<8>(R, log_rotations, sq, log, floor);
            default: break;
        }
    }
    if (p <= kJacobiFixed) {
        switch (cols) {
            case 1: return jacobi_row_norms_fixed<1>(R, p, log_rotations, sq, log, floor);
            case 2: return jacobi_row_norms_fixed<2>(R, p, log_rotations, sq, log, floor);
            case 3: return jacobi_row_norms_fixed<3>(R, p, log_rotations, sq, log, floor);
            case 4: return jacobi_row_norms_fixed<4>(R, p, log_rotations, sq, log, floor);
            case 5: return jacobi_row_norms_fixed<5>(R, p, log_rotations, sq, log, floor);
            case 6: return jacobi_row_norms_fixed<6>(R, p, log_rotations, sq, log, floor);
            case 7: return jacobi_row_norms_fixed<7>(R, p, log_rotations, sq, log, floor);
            case 8: return jacobi_row_norms_fixed<8>(R, p, log_rotations, sq, log, floor);
            case 9: return jacobi_row_norms_fixed<9>(R, p, log_rotations, sq, log, floor);
            case 10: return jacobi_row_norms_fixed<10>(R, p, log_rotations, sq, log, floor);
            case 11: return jacobi_row_norms_fixed<11>(R, p, log_rotations, sq, log, floor);
            case 12: return jacobi_row_norms_fixed<12>(R, p, log_rotations, sq, log, floor);
            case 13: return jacobi_row_norms_fixed<13>(R, p, log_rotations, sq, log, floor);
            case 14: return jacobi_row_norms_fixed<14>(R, p, log_rotations, sq, log, floor);
            case 15: return jacobi_row_norms_fixed<15>(R, p, log_rotations, sq, log, floor);
            case 16: return jacobi_row_norms_fixed<16>(R, p, log_rotations, sq, log, floor);
            default: break;
        }
    }
    sq.resize(static_cast<size_t>(p));  // every entry written
    for (i64 i = 0; i < p; ++i) sq[i] = jacobi_sq<0>(R.row(i), cols);
    log.clear();
    // clean: p p pair stamps, p row stamps, then the order (p + 1 round starts, the pairs' i
    // and j, p + 1 of scratch)
    const i64 npairs = p * (p - 1) / 2;
    clean.assign(static_cast<size_t>(p * p + p + (p + 1) + 2 * npairs + (p + 1)), 0);
    i64* stamp = clean.data() + p * p;
    i64* start = stamp + p;
    i64* pi = start + p + 1;
    i64* pj = pi + npairs;
    i64* at = pj + npairs;
    const i64 rounds = jacobi_rounds(p, start, pi, pj, at);
    jacobi_sweeps<0>(R.row(0), R.cols, p, cols, log_rotations, sq.data(), clean.data(), stamp, start, pi, pj, rounds,
                     log, floor);
}

// R's first p rows (cols long) replaced by V^T R, V the eigenvectors of R R^T (rows of R
// that span the same space, nearly orthogonal, with the same singular values); left as they
// are where QL does not converge (false).
// G = R R^T of R's first p rows (cols long).
inline void gram_into(const Mat& R, i64 p, i64 cols, Mat& G) {
    G.zeros(p, p);
    for (i64 i = 0; i < p; ++i) {
        const double* ri = R.row(i);
        for (i64 j = i; j < p; ++j) {
            double g = dot(ri, R.row(j), cols);
            G(i, j) = g;
            G(j, i) = g;
        }
    }
}

// The least and the largest eigenvalue of R R^T (R's first p rows, cols long: the squares
// of their least and largest singular values) by sym_eigen without vectors; false where QL
// does not converge or an eigenvalue is not finite.
inline bool gram_extremes(const Mat& R, i64 p, i64 cols, Workspace& ws, double& low, double& high) {
    Mat& G = ws.Q;
    gram_into(R, p, cols, G);
    Vec& d = ws.qr.norms;
    if (!sym_eigen(G, d, ws.qr.x, ws.Qt, false)) return false;
    low = kInf;
    high = -kInf;
    for (i64 i = 0; i < p; ++i) {
        if (!std::isfinite(d[i])) return false;  // (non-finite rows: the plain ranking decides)
        low = pymin(low, d[i]);
        high = pymax(high, d[i]);
    }
    return true;
}

inline bool gram_precondition(Mat& R, i64 p, i64 cols, Workspace& ws) {
    Mat& G = ws.Q;
    gram_into(R, p, cols, G);
    if (!sym_eigen(G, ws.qr.norms, ws.qr.x, ws.Qt)) return false;
    Mat& T = ws.Qr;
    T.zeros(p, cols);
    for (i64 k = 0; k < p; ++k) {
        double* tk = T.row(k);
        const double* vk = G.row(k);
        for (i64 i = 0; i < p; ++i) axpy(tk, vk[i], R.row(i), cols);
    }
    for (i64 k = 0; k < p; ++k) std::memcpy(R.row(k), T.row(k), static_cast<size_t>(cols) * sizeof(double));
    return true;
}

// A Z where no row of A holds more than one nonzero entry (a posture task's rows, a
// selection), into C: entry (i, j) = +0 plus A(i, t) Z(t, j) for the row's nonzero A(i, t)
// (+0 where it has none), the sum mm_into makes (its zero entries of A skipped, the one
// product added to +0): the same bits, without its scan of pairs of rows. False, nothing
// written, where some row holds two (or A has more than 256 rows).
inline bool one_per_row_product(CMatRef A, CMatRef Z, Mat& C) {
    constexpr i64 kRows = 256;
    const i64 m = A.rows, k = A.cols, n = Z.cols;
    if (m > kRows) return false;
    i64 at[kRows];
    // (per row: the count of nonzero entries (x != 0.0: a NaN counts) and the last one's
    // index, two entries a step without a branch on each, the count checked every eight)
    using namespace simd;
    const v2i zero_i = v2i{0, 0};
    for (i64 i = 0; i < m; ++i) {
        const double* ai = A.row(i);
        v2i cnt = zero_i, pos = v2i{-1, -1}, idx = v2i{0, 1};
        const v2i two = v2i{2, 2};
        i64 t = 0;
        while (t + 2 <= k) {
            const i64 stop = std::min<i64>(k, t + 8);
            for (; t + 2 <= stop; t += 2) {
                const v2i nz = (load(ai + t) != splat(0.0));
                cnt -= nz;
                pos = (idx & nz) | (pos & ~nz);
                idx += two;
            }
            if (cnt[0] + cnt[1] > 1) return false;
        }
        i64 c = cnt[0] ? pos[0] : cnt[1] ? pos[1] : -1;
        if (t < k && ai[t] != 0.0) {
            if (c >= 0) return false;
            c = t;
        }
        at[i] = c;
    }
    shape(C, m, n);  // every entry written below
    for (i64 i = 0; i < m; ++i) {
        double* ci = C.row(i);
        if (at[i] < 0) {
            for (i64 j = 0; j < n; ++j) ci[j] = 0.0;
            continue;
        }
        const double a = A(i, at[i]);
        const double* zt = Z.row(at[i]);
        i64 j = 0;
        const v2d av = splat(a);
        for (; j + 2 <= n; j += 2) store(ci + j, splat(0.0) + av * load(zt + j));
        for (; j < n; ++j) ci[j] = 0.0 + a * zt[j];
    }
    return true;
}

// 1 / w where w is a power of two in [2^-1000, 2^1000] (the reciprocal exact), else 0: there
// x * (1 / w) is x / w bit for bit (the same real number x 2^-k, rounded the same way; a NaN
// x passes through either), a product in place of a division (project_level's M = diag(1/w)
// A Z: unit weights, most often).
inline double exact_reciprocal(double w) {
    std::uint64_t u;
    std::memcpy(&u, &w, sizeof u);
    if ((u & 0x000FFFFFFFFFFFFFull) != 0 || !(w >= 0x1p-1000 && w <= 0x1p1000)) return 0.0;
    return 1.0 / w;
}

// dst (cols, rows) = the transpose of the rows src(0..rows-1) (cols entries each): dst(j, i) =
// src(i)[j], copies only, two rows by two columns a step (a 2x2 block: two loads, two
// shuffles, two stores), the odd last row and column one entry at a time.
template <class SrcRow>
inline void transpose_rows(SrcRow src, i64 rows, i64 cols, Mat& dst) {
    using namespace simd;
    shape(dst, cols, rows);  // every entry copied
    i64 i = 0;
    for (; i + 2 <= rows; i += 2) {
        const double* s0 = src(i);
        const double* s1 = src(i + 1);
        i64 j = 0;
        for (; j + 2 <= cols; j += 2) {
            v2d a = load(s0 + j), b = load(s1 + j);
            store(dst.row(j) + i, __builtin_shuffle(a, b, v2i{0, 2}));
            store(dst.row(j + 1) + i, __builtin_shuffle(a, b, v2i{1, 3}));
        }
        if (j < cols) {
            dst(j, i) = s0[j];
            dst(j, i + 1) = s1[j];
        }
    }
    if (i < rows) {
        const double* s0 = src(i);
        for (i64 j = 0; j < cols; ++j) dst(j, i) = s0[j];
    }
}

// null_basis's E (r, c) where householder_qr left M's zero rows out (ws.qr.compact): the same
// bits from the reflectors on the rows it took (map). A null column e_t at a row t left out
// is e_t: every reflector's x is finite (vn finite) and +0 at t, so its sum x_t 1 + (+-0) ...
// is +0 from +0.0 and each entry becomes e - (+-0) = e. Every other null column (e_t, t in
// map, or Theta^T e_t, t < p: rows below p, all in map) is +0 at the rows left out and stays
// so while the factors S are finite (+0 - (+0) S_j), adding +0 products to its sums: it is
// reflected on map's rows alone (the same operations in the same order), then put back.
// false (nothing of E written) where some vn or S is not finite: E is made as before.
__attribute__((noinline)) inline bool null_basis_compact(i64 p, bool rotated_null, Workspace& ws, Mat& E) {
    const IVec& null_cols = ws.null_cols;
    const IVec& map = ws.qr.map;
    i64 r = ws.qr.V.cols, c = static_cast<i64>(null_cols.size()), rc = static_cast<i64>(map.size());
    if (p > rc) return false;
    for (i64 i = 0; i < p; ++i)
        if (!std::isfinite(ws.qr.vn[static_cast<size_t>(i)])) return false;
    // pos[t]: row t's place in map (-1: left out); kept: the null columns on map's rows
    IVec& pos = ws.qr.pos;
    pos.assign(static_cast<size_t>(r), -1);
    for (i64 t = 0; t < rc; ++t) pos[map[t]] = t;
    i64 ce = 0;
    for (i64 q = 0; q < c; ++q)
        if (pos[null_cols[q]] >= 0) ce += 1;
    Mat& Ec = ws.qr.Ec;
    Mat& T = ws.qr.T;  // Theta (p, p) where rotated
    if (rotated_null) {
        T.set_eye(p);
        for (const Rotation& g : ws.log) jacobi_rows(T.row(g.i), T.row(g.j), g.cs, g.sn, p);
    }
    Ec.zeros(rc, ce);
    {
        i64 k = 0;
        for (i64 q = 0; q < c; ++q) {
            i64 col = null_cols[q];
            if (pos[col] < 0) continue;
            if (rotated_null && col < p)
                for (i64 t = 0; t < p; ++t) Ec(t, k) = T(col, t);
            else
                Ec(pos[col], k) = 1.0;
            k += 1;
        }
    }
    Vec& S = ws.qr.S;
    S.resize(static_cast<size_t>(std::max<i64>(ce, 1)));
    for (i64 i = p - 1; i >= 0; --i) {
        double vn = ws.qr.vn[static_cast<size_t>(i)];
        if (vn == 0.0) continue;
        detail::reflect_columns(Ec.row(0), ce, i, rc - i, 0, ce, ws.qr.Vc.row(i) + i, vn, S.data());
        for (i64 j = 0; j < ce; ++j)
            if (!std::isfinite(S[j])) return false;
    }
    E.zeros(r, c);
    i64 k = 0;
    for (i64 q = 0; q < c; ++q) {
        i64 col = null_cols[q];
        if (pos[col] < 0) {
            E(col, q) = 1.0;
            continue;
        }
        for (i64 t = 0; t < rc; ++t) E(map[t], q) = Ec(t, k);
        k += 1;
    }
    return true;
}

// Zn = Z Q_null of project_level: Q's columns p.. and, where a null direction is among the
// first p (rotated_null), Q Theta^T's columns null_cols, Theta the logged rotations, from the
// reflectors householder_qr kept (Q is never formed). Whichever costs fewer operations by
// the sizes alone (so the same inputs take the same path): Y = Z H_0 ... H_{p-1} (the
// reflectors applied to Z's rows, (n, r)), or E = H_0 ... H_{p-1} [e_c or Theta^T e_c] (the
// null columns alone, (r, c)) then Z E (E itself when Z is the identity).
inline void null_basis(CMatRef Z, bool z_eye, i64 p, bool rotated_null, Workspace& ws, Mat& Zn) {
    const IVec& null_cols = ws.null_cols;
    i64 n = Z.rows, r = Z.cols;
    i64 c = static_cast<i64>(null_cols.size());
    double span = 0.0;  // sum over the reflectors of their lengths
    for (i64 i = 0; i < p; ++i) span += static_cast<double>(r - i);
    double cost_right = 4.0 * static_cast<double>(n) * span;
    double cost_left = 4.0 * static_cast<double>(c) * span;
    if (!z_eye) cost_left += 2.0 * static_cast<double>(n) * static_cast<double>(r) * static_cast<double>(c);
    if (rotated_null) cost_left += static_cast<double>(ws.log.size()) * 6.0 * static_cast<double>(p);
    if (rotated_null) cost_right += static_cast<double>(ws.log.size()) * 6.0 * static_cast<double>(n);
    if (cost_right < cost_left) {
        // Y^T = H_{p-1} ... H_0 Z^T, held as Yt (r, n): reflector i reflects rows i.. of Yt
        // (reflect_columns: per entry of Y, the sum and update apply_reflectors_right makes
        // on Y's row, the same products in the same order: the same bits), Y's columns
        // contiguous rows (the rotations below act on them in place).
        Mat& Yt = ws.Q;
        if (z_eye) {
            Yt.set_eye(r);
        } else {
            transpose_rows([&Z](i64 i) { return Z.row(i); }, n, r, Yt);
        }
        Vec& S = ws.qr.S;
        if (S.size() < static_cast<size_t>(n)) S.resize(static_cast<size_t>(n));  // written before read
        for (i64 i = 0; i < p; ++i) {
            double vn = ws.qr.vn[static_cast<size_t>(i)];
            if (vn == 0.0) continue;
            detail::reflect_columns(Yt.row(0), n, i, r - i, 0, n, ws.qr.V.row(i) + i, vn, S.data());
        }
        if (rotated_null)
            for (const Rotation& g : ws.log) jacobi_rows(Yt.row(g.i), Yt.row(g.j), g.cs, g.sn, n);
        transpose_rows([&Yt, &null_cols](i64 q) { return Yt.row(null_cols[q]); }, c, n, Zn);
        return;
    }
    Mat& E = ws.Qr;
    if (ws.qr.compact && null_basis_compact(p, rotated_null, ws, E)) {
        if (z_eye) std::swap(Zn, E);
        else mm_into(Z, E.cref(), Zn);
        return;
    }
    E.zeros(r, c);
    if (rotated_null) {
        Mat& T = ws.Qt;  // Theta (p, p): the logged rotations of the identity's rows
        T.set_eye(p);
        for (const Rotation& g : ws.log) jacobi_rows(T.row(g.i), T.row(g.j), g.cs, g.sn, p);
        for (i64 q = 0; q < c; ++q) {
            i64 col = null_cols[q];
            if (col < p)
                for (i64 t = 0; t < p; ++t) E(t, q) = T(col, t);
            else
                E(col, q) = 1.0;
        }
    } else {
        for (i64 q = 0; q < c; ++q) E(null_cols[q], q) = 1.0;
    }
    apply_reflectors_left(E, ws.qr, p);
    if (z_eye) std::swap(Zn, E);
    else mm_into(Z, E.cref(), Zn);
}

}  // namespace detail

// Project a level (A, w) into the null space Z of the levels above (see project_level in
// qpik/core/kernels.py).
// need_null false (the last level with rows: no level below uses Zn): the same AZ, sigma and
// rank, without Q, its rotations or Zn (Zn then has no columns).
// z_eye: Z is exactly the identity (the first level with rows, nothing pinned above it):
// the products with Z are written without forming them, the same bits (see below).
// Levels of this many rows or more to rank are turned first (see below).
constexpr i64 kTurnRows = 8;
// ... and ranked by the eigenvalues of R R^T alone when the least is at least this times the
// largest (condition number 10 or less).
constexpr double kConditioned = 1e-2;
constexpr double kGraded = 0.1;

namespace detail {

// Whether every singular value of R's first p rows (cols long) is proved above both `floor`
// and 2 rank_tol max(1, |R|_F) (so above project_level's cutoff rank_tol max(1, sigma_max))
// with room for the round-off of any method that computes them: by a Cholesky factorization
// of R R^T - tau I, tau = t^2 + kProvedSlack |R|_F^2 (t the larger bound). It succeeds (every
// pivot positive) only where R R^T - tau I + E is positive definite, E its round-off (|E| a
// few p^2 eps |R|_F^2, with the Gram's own), so that sigma_min^2 > t^2 + (kProvedSlack - a few
// p^2 eps) |R|_F^2: a margin, far above the round-off of Jacobi's or the Gram eigenvalues'
// sigma (a few p eps |R|_F^2 in sigma^2), that keeps their sigma above t too. False where
// any entry is not finite, p is above kProvedRows (the slack no longer far above p^2 eps),
// or a pivot is not positive (the caller ranks the rows itself).
constexpr double kProvedSlack = 1e-11;
constexpr i64 kProvedRows = 64;
// The test of singular_values_above on a Gram matrix G (p, p) of trace f2: whether the
// Cholesky factorization of G - tau I (cholesky_into, into ws.Qt) finds every pivot positive.
inline bool gram_above(const Mat& G, i64 p, double f2, double floor, double rank_tol, Workspace& ws) {
    if (!(f2 < kInf)) return false;  // (NaN or inf: then some entry of G is not finite)
    double t = pymax(floor, 2.0 * rank_tol * pymax(1.0, std::sqrt(f2)));
    double tau = t * t + kProvedSlack * f2;
    if (!(tau < kInf)) return false;
    shape(ws.Qt, p, p);  // (cholesky_into writes the lower triangle it reads)
    return cholesky_into(G.cref(), p, tau, ws.Qt.ref());
}

inline bool singular_values_above(const Mat& R, i64 p, i64 cols, double floor, double rank_tol, Workspace& ws) {
    if (p > kProvedRows || p <= 0) return false;
    Mat& G = ws.Q;
    gram_into(R, p, cols, G);  // R R^T
    double f2 = 0.0;
    for (i64 i = 0; i < p; ++i) f2 += G(i, i);
    return gram_above(G, p, f2, floor, rank_tol, ws);
}

// singular_values_above for the singular values of M (rows, cols), cols <= kProvedRows, from
// its own Gram matrix M^T M (no QR: its round-off, a few rows eps |M|_F^2, is far inside the
// margin too).
inline bool columns_above(const Mat& M, double floor, double rank_tol, Workspace& ws) {
    const i64 c = M.cols;
    if (c > kProvedRows || c <= 0 || M.rows > 4 * kProvedRows) return false;
    Mat& G = ws.Q;
    mtm_into(M.cref(), G);
    double f2 = 0.0;
    for (i64 i = 0; i < c; ++i) f2 += G(i, i);
    return gram_above(G, c, f2, floor, rank_tol, ws);
}

// The ranking of project_level: the singular values of R's first p rows (cols long) by
// one-sided Jacobi (or, well conditioned, the eigenvalues of R R^T), sigma the least above
// rank_tol max(1, the largest), rank their count, ws.null_cols the rows below the cutoff (in
// order), ws.log the rotations Zn needs; returns whether a null direction is among the first
// p (Q's columns rotated). R's rows are rotated (ws.Mt: scratch).
// The squared row norm at or below which Jacobi leaves a row of R alone (jacobi_orthogonal's
// floor): kJacobiNegligible times the rank cutoff rank_tol max(1, top), top R's largest row
// norm (at most the largest singular value): a row that small is null whatever its
// rotations, and turning it against another row moves that row's norm by its square over
// the other's (rank and sigma unchanged beyond round-off) and the null directions by its
// ratio to the other's.
constexpr double kJacobiNegligible = 1e-9;
inline double negligible_rows(const Mat& R, i64 p, i64 cols, double rank_tol) {
    double top = 0.0;
    for (i64 i = 0; i < p; ++i) top = pymax(top, row_sq(R.row(i), cols));
    const double bound = kJacobiNegligible * rank_tol * pymax(1.0, std::sqrt(top));
    return bound * bound;
}

inline bool rank_rows(Mat& R, i64 p, i64 cols, double rank_tol, bool need_null, Workspace& ws, double& sigma_out,
                      i64& rank_out) {
    Mat& Mt = ws.Mt;
    // Singular values of the top block of R (p, cols) by one-sided Jacobi rotations of its
    // rows, the same rotations applied to Q's columns, so that Mt[:, perm] = (Q Theta^T)
    // (Theta R) with the rows of Theta R orthogonal: their norms are the singular values,
    // Q's rotated columns the left singular vectors (pivoted QR first makes Jacobi converge
    // in a few sweeps).
    // With many rows, the rows are first turned by the eigenvectors of their Gram matrix R R^T
    // (symmetric QL, O(p^3)): nearly orthogonal, so that Jacobi, which decides the singular
    // values as before (the norms of rows it made orthogonal), ends in a sweep or two rather
    // than five or more (clustered singular values). Turned, Q's first p columns are no longer
    // followed, so the turn decides only a full rank, far from the cutoff (every singular value
    // above 2 cutoff; the last level of 16 rows or more: whatever it finds): then Zn is Q's
    // columns p.. alone, and sigma the least singular value. Otherwise the rows are restored
    // and ranked as without the turn (the rotations logged for Zn's null directions).
    std::vector<Rotation>& log = ws.log;
    Vec& sq = ws.sq;
    Vec& sv = ws.sv;
    bool final_turn = !need_null && p >= 16;
    bool turned = false;
    // A last row of R within 2 rank_tol max(1, |R's first row|) bounds the least singular
    // value by 2 cutoff (every row's norm lies between sigma_min and sigma_max): neither the
    // eigenvalues nor the turn can decide, and neither is taken.
    // A last row below kGraded times the first (graded rows, a condition number above 1 /
    // kGraded): the plain Jacobi converges in a few sweeps by itself, and is taken as is.
    bool roomy = false;
    if (p >= kTurnRows) {
        double last = std::sqrt(row_sq(R.row(p - 1), cols)), first = std::sqrt(row_sq(R.row(0), cols));
        roomy = last > 2.0 * rank_tol * pymax(1.0, first) && last >= kGraded * first;
    }
    double top = 0.0;
    bool decided = false;
    if (roomy) {
        // Well conditioned (the least eigenvalue of R R^T at least kConditioned times the
        // largest, each found within a few p eps of the largest: sigma to 1e-13 or so): the
        // singular values are the square roots of the eigenvalues, no rotation needed; a full
        // rank when the least is above 2 cutoff.
        double low = 0.0, high = 0.0;
        if (gram_extremes(R, p, cols, ws, low, high) && high > 0.0 && low >= kConditioned * high) {
            top = std::sqrt(high);
            double least = std::sqrt(low);
            if (least > 2.0 * rank_tol * pymax(1.0, top)) {
                decided = true;
                sv.assign(static_cast<size_t>(p), least);
                log.clear();
            }
        }
    }
    bool turn = !decided && (final_turn || roomy);
    if (turn) {
        if (!final_turn) {  // R's rows kept in Mt (free once factored) for the plain ranking
            shape(Mt, p, cols);  // every entry copied
            for (i64 i = 0; i < p; ++i) std::memcpy(Mt.row(i), R.row(i), static_cast<size_t>(cols) * sizeof(double));
        }
        turned = gram_precondition(R, p, cols, ws);
    }
    // The rotations are logged only where Zn may need them: a null direction among R's first p
    // rows. Where R's last diagonal entry lies far above the cutoff (pivoted QR: |R_ii| falls
    // with i, and the least singular value lies near the last in practice), Jacobi runs
    // without the log, R's rows kept in Mt; should a null direction among the first p turn up
    // after all, the rows are restored and Jacobi run again with the log (the same rotations:
    // the same bits either way).
    bool spare = false;
    for (int pass = 0; pass < 2 && !decided; ++pass) {
        bool log_now = need_null && !turned;
        if (log_now && std::fabs(R(p - 1, p - 1)) > 1e4 * rank_tol * pymax(1.0, std::fabs(R(0, 0)))) {
            shape(Mt, p, cols);  // every entry copied
            for (i64 i = 0; i < p; ++i) std::memcpy(Mt.row(i), R.row(i), static_cast<size_t>(cols) * sizeof(double));
            log_now = false;
            spare = true;
        }
        jacobi_row_norms(R, p, cols, log_now, sq, ws.clean, log, negligible_rows(R, p, cols, rank_tol));
        sv.assign(static_cast<size_t>(p), 0.0);
        top = 0.0;
        for (i64 i = 0; i < p; ++i) {
            sv[i] = std::sqrt(sq[i]);
            top = pymax(top, sv[i]);
        }
        if (!turned || final_turn) break;
        double far = 2.0 * rank_tol * pymax(1.0, top);
        bool clear = true;
        for (i64 i = 0; i < p; ++i)
            if (!(sv[i] > far)) clear = false;
        if (clear) break;
        turned = false;
        for (i64 i = 0; i < p; ++i) std::memcpy(R.row(i), Mt.row(i), static_cast<size_t>(cols) * sizeof(double));
    }
    double cutoff = rank_tol * pymax(1.0, top);
    i64 rank = 0;
    double sigma = kInf;
    IVec& null_cols = ws.null_cols;
    null_cols.clear();
    for (i64 i = 0; i < p; ++i) {
        if (sv[i] > cutoff) {
            rank += 1;
            sigma = pymin(sigma, sv[i]);
        } else {
            null_cols.push_back(i);
        }
    }
    bool rotated_null = !null_cols.empty();
    if (rotated_null && spare) {
        for (i64 i = 0; i < p; ++i) std::memcpy(R.row(i), Mt.row(i), static_cast<size_t>(cols) * sizeof(double));
        jacobi_row_norms(R, p, cols, true, sq, ws.clean, log, negligible_rows(R, p, cols, rank_tol));
    }
    sigma_out = sigma;
    rank_out = rank;
    return rotated_null;
}

}  // namespace detail

inline void project_level(CMatRef A, CVecRef w, CMatRef Z, double rank_tol, bool need_null, Workspace& ws,
                          Projection& out, bool z_eye = false, double defer_floor = -1.0) {
    bool az_made = false;
    if (z_eye) {
        // mm(A, I) where A is finite: each nonzero A(i, t) adds A(i, t) to entry t and a
        // (finite) A(i, t) * 0 = +-0 to the others, from +0: the entry A(i, j) where it is
        // nonzero, else +0. Written while A's entries are checked (a non-finite one: mm_into
        // writes AZ again).
        // (Two entries a step: an entry's bits kept where it is != 0.0, cleared (+0) where it
        // is +-0, the same select; x - x == 0 exactly where x is finite.)
        using namespace simd;
        shape(out.AZ, A.rows, A.cols);  // every entry written
        bool finite = true;
        const v2d zero = splat(0.0);
        v2i fin = v2i{-1, -1};
        for (i64 i = 0; i < A.rows; ++i) {
            const double* ai = A.row(i);
            double* zi = out.AZ.row(i);
            i64 j = 0;
            for (; j + 2 <= A.cols; j += 2) {
                v2d x = load(ai + j);
                fin &= ((x - x) == zero);
                v2i bits;
                std::memcpy(&bits, &x, sizeof x);
                bits &= (x != zero);
                std::memcpy(&x, &bits, sizeof x);
                store(zi + j, x);
            }
            for (; j < A.cols; ++j) {
                const double a = ai[j];
                finite &= std::isfinite(a);
                zi[j] = a != 0.0 ? a : 0.0;
            }
        }
        az_made = finite && fin[0] != 0 && fin[1] != 0;
    }
    if (!az_made && !detail::one_per_row_product(A, Z, out.AZ)) mm_into(A, Z, out.AZ);
    i64 m = A.rows;
    i64 r = Z.cols;
    i64 keep = 0;
    for (i64 i = 0; i < m; ++i)
        if (w[i] > 0.0) keep += 1;
    if (keep == 0 || r == 0) {
        out.sigma = kInf;
        out.rank = 0;
        out.Zn.zeros(Z.rows, Z.cols);
        for (i64 i = 0; i < Z.rows; ++i)
            for (i64 j = 0; j < Z.cols; ++j) out.Zn(i, j) = Z(i, j);
        return;
    }
    if (detail::unit_rows(A, w)) {
        out.sigma = 1.0;
        out.rank = r;
        out.Zn.zeros(Z.rows, 0);
        return;
    }
    // The singular values come from the rows of R, the pivoted QR of M^T or M, M = diag(1/w)
    // A Z over the kept rows (keep, r). Where Zn is needed, M^T (r, keep) is factored: its Q
    // holds the null directions. Otherwise the factor with the shorter rows: M (keep, r)
    // when keep > r (R's rows r long rather than keep; the same singular values, to
    // round-off), else M^T.
    bool tall = !need_null && keep > r;
    Mat& Mt = ws.Mt;
    if (tall) {
        shape(Mt, keep, r);  // every entry written below
        i64 k = 0;
        for (i64 i = 0; i < m; ++i) {
            if (!(w[i] > 0.0)) continue;
            const double* src = out.AZ.row(i);
            double* dst = Mt.row(k);
            const double inv = detail::exact_reciprocal(w[i]);
            // (two entries a step: the same product or quotient per lane)
            i64 j = 0;
            if (inv != 0.0) {
                const simd::v2d iv = simd::splat(inv);
                for (; j + 2 <= r; j += 2) simd::store(dst + j, simd::load(src + j) * iv);
                for (; j < r; ++j) dst[j] = src[j] * inv;
            } else {
                const simd::v2d wv = simd::splat(w[i]);
                for (; j + 2 <= r; j += 2) simd::store(dst + j, simd::load(src + j) / wv);
                for (; j < r; ++j) dst[j] = src[j] / w[i];
            }
            k += 1;
        }
    } else {
        // Two kept rows at a time (columns k, k + 1 of Mt): each entry the same product (or
        // quotient) per lane, then a 2x2 transpose (copies).
        using namespace simd;
        shape(Mt, r, keep);  // every entry written below
        auto next_kept = [&w, m](i64 i) {
            while (i < m && !(w[i] > 0.0)) ++i;
            return i;
        };
        auto scaled = [](v2d u, double inv, double wi) { return inv != 0.0 ? u * splat(inv) : u / splat(wi); };
        i64 k = 0;
        for (i64 i = next_kept(0); i < m;) {
            const i64 i1 = next_kept(i + 1);
            const double inv = detail::exact_reciprocal(w[i]);
            if (i1 < m) {
                const double inv1 = detail::exact_reciprocal(w[i1]);
                const double* a0 = out.AZ.row(i);
                const double* a1 = out.AZ.row(i1);
                i64 j = 0;
                for (; j + 2 <= r; j += 2) {
                    v2d u0 = scaled(load(a0 + j), inv, w[i]), u1 = scaled(load(a1 + j), inv1, w[i1]);
                    store(Mt.row(j) + k, __builtin_shuffle(u0, u1, v2i{0, 2}));
                    store(Mt.row(j + 1) + k, __builtin_shuffle(u0, u1, v2i{1, 3}));
                }
                if (j < r) {
                    Mt(j, k) = inv != 0.0 ? a0[j] * inv : a0[j] / w[i];
                    Mt(j, k + 1) = inv1 != 0.0 ? a1[j] * inv1 : a1[j] / w[i1];
                }
                k += 2;
                i = next_kept(i1 + 1);
                continue;
            }
            if (inv != 0.0) {
                for (i64 j = 0; j < r; ++j) Mt(j, k) = out.AZ(i, j) * inv;
            } else {
                for (i64 j = 0; j < r; ++j) Mt(j, k) = out.AZ(i, j) / w[i];
            }
            k += 1;
            i = m;
        }
    }
    if (tall && defer_floor >= 0.0 && detail::columns_above(Mt, defer_floor, rank_tol, ws)) {
        // The last level, more rows than directions: its singular values (M's) proved above the
        // cutoff and defer_floor from M^T M (see below), so that its rank is r and its damping
        // 0; the QR and the ranking are left to deferred_sigma, from a copy of M (the same
        // QR, the same ranking: the same bits).
        ws.deferred = true;
        ws.defer_kind = 1;
        ws.defer_R = Mt;
        out.sigma = kNaN;
        out.rank = r;
        out.Zn.zeros(Z.rows, 0);
        return;
    }
    i64 cols = Mt.cols;  // R's row length
    Mat& R = ws.R;
    // Q is never formed: the reflectors are kept where Zn needs them (applied to Z, or to the
    // identity's null columns only).
    ws.qr.keep_reflectors = need_null;
    householder_qr(Mt.cref(), true, ws.Q, R, ws.perm, false, ws.qr);
    ws.qr.keep_reflectors = false;
    i64 p = std::min(r, keep);
    double sigma = kInf;
    i64 rank = 0;
    IVec& null_cols = ws.null_cols;
    bool rotated_null = false;
    if (defer_floor >= 0.0 && detail::singular_values_above(R, p, cols, defer_floor, rank_tol, ws)) {
        // Every singular value proved above the cutoff and above defer_floor (the damping's
        // threshold: no damping): the full rank, the null directions Q's columns p.. alone,
        // as the ranking below would find them; sigma itself is left to the caller, from a
        // copy of R's rows (deferred_sigma: the same ranking, the same bits), NaN here.
        sigma = kNaN;
        rank = p;
        null_cols.clear();
        ws.deferred = true;
        ws.defer_kind = 0;
        shape(ws.defer_R, p, cols);  // every entry copied
        for (i64 i = 0; i < p; ++i)
            std::memcpy(ws.defer_R.row(i), R.row(i), static_cast<size_t>(cols) * sizeof(double));
    } else {
        rotated_null = detail::rank_rows(R, p, cols, rank_tol, need_null, ws, sigma, rank);
    }
    for (i64 i = p; i < r; ++i) null_cols.push_back(i);
    out.sigma = sigma;
    out.rank = rank;
    if (!need_null) {
        out.Zn.zeros(Z.rows, 0);
        return;
    }
    detail::null_basis(Z, z_eye, p, rotated_null, ws, out.Zn);
}

inline Projection project_level(CMatRef A, CVecRef w, CMatRef Z, double rank_tol, bool need_null = true) {
    Workspace ws;
    Projection out;
    project_level(A, w, Z, rank_tol, need_null, ws, out);
    return out;
}

namespace detail {

// Level k's record of CascadeResult::deferred (its header entry set to the record's offset).
inline void defer_record(Vec& store, i64 k, int kind, bool need_null, double rank_tol, const Mat& R) {
    const i64 p = R.rows, cols = R.cols;
    store[static_cast<size_t>(k)] = static_cast<double>(store.size());
    store.push_back(static_cast<double>(kind));
    store.push_back(static_cast<double>(p));
    store.push_back(static_cast<double>(cols));
    store.push_back(need_null ? 1.0 : 0.0);
    store.push_back(rank_tol);
    store.insert(store.end(), R.a.data(), R.a.data() + p * cols);
}

}  // namespace detail

// The sigma of level k of a CascadeResult::deferred store (len entries; L levels): the
// ranking's (detail::rank_rows) on the rows kept, the bits project_level would have
// returned; `fallback` where level k has no record. Throws std::invalid_argument on a
// malformed store.
inline double deferred_sigma(const double* store, i64 len, i64 L, i64 k, double fallback) {
    auto bad = [] { throw std::invalid_argument("deferred_sigma: malformed store"); };
    if (L < 0 || k < 0 || k >= L || len < L) bad();
    const double at = store[k];
    if (at == -1.0) return fallback;
    if (!(at >= static_cast<double>(L) && at + 5.0 <= static_cast<double>(len)) || at != std::floor(at)) bad();
    const i64 o = static_cast<i64>(at);
    const double kind = store[o], rd = store[o + 1], cd = store[o + 2];
    auto whole = [](double x, double hi) { return x >= 1.0 && x <= hi && x == std::floor(x); };
    if (!(kind == 0.0 || kind == 1.0) || !whole(rd, 1e6) || !whole(cd, 1e6)) bad();
    const i64 rows = static_cast<i64>(rd), cols = static_cast<i64>(cd);
    if ((kind == 0.0 ? rows : cols) > detail::kProvedRows || o + 5 + rows * cols > len) bad();
    const bool need_null = store[o + 3] != 0.0;
    const double rank_tol = store[o + 4];
    thread_local Workspace ws;
    Mat& R = ws.R;
    i64 p = rows;
    if (kind == 0.0) {  // R's first p rows
        shape(R, rows, cols);  // every entry copied
        std::memcpy(R.a.data(), store + o + 5, static_cast<size_t>(rows * cols) * sizeof(double));
    } else {  // M (rows, cols): project_level's QR of it first
        Mat& M = ws.Mt;
        shape(M, rows, cols);  // every entry copied
        std::memcpy(M.a.data(), store + o + 5, static_cast<size_t>(rows * cols) * sizeof(double));
        ws.qr.keep_reflectors = need_null;
        householder_qr(M.cref(), true, ws.Q, R, ws.perm, false, ws.qr);
        ws.qr.keep_reflectors = false;
        p = std::min(rows, cols);
    }
    double sigma = kInf;
    i64 rank = 0;
    detail::rank_rows(R, p, cols, rank_tol, need_null, ws, sigma, rank);
    return sigma;
}

// lambda^2 driven by sigma: max_damping^2 (1 - (sigma / threshold)^2) below the threshold.
inline double damping_of(double sigma, double threshold, double max_damping) {
    if (!(sigma < threshold)) return 0.0;
    double ratio = sigma / threshold;
    return max_damping * max_damping * (1.0 - ratio * ratio);
}

// The lambda^2 a level gets (see level_damping in qpik/core/kernels.py).
inline double level_damping(CMatRef A, CVecRef b, CVecRef w, const double* d, double sigma, double threshold,
                            double max_damping, double error_scale) {
    if (!(max_damping > 0.0)) return 0.0;
    double lam = damping_of(sigma, threshold, max_damping);
    if (lam > 0.0) {
        double wmax = 0.0;
        for (i64 i = 0; i < w.size(); ++i) wmax = pymax(wmax, w[i]);
        lam *= wmax * wmax;
        if (error_scale > 0.0) {
            Vec e = mv(A, d);
            for (i64 i = 0; i < A.rows; ++i) e[i] = e[i] - b[i];
            lam *= pymin(1.0, std::sqrt(dot(e.data(), e.data(), A.rows)) / error_scale);
        }
    }
    return lam;
}

// H = (A Z)^T A Z with reg on its diagonal (reduced_objective's, the same bits).
inline void make_h(CMatRef AZ, double reg, ReducedQP& out) {
    mtm_into(AZ, out.H);
    out.hraw.resize(static_cast<size_t>(AZ.cols));
    for (i64 i = 0; i < AZ.cols; ++i) {
        out.hraw[i] = out.H(i, i);
        out.H(i, i) += reg;
    }
    out.hraw_ok = true;
}

// The objective (H, c) of reduced_qp.
// z_eye: Z is exactly the identity (Z^T d then written without the product, see there).
// h_later (where the caller makes H itself when it needs it, make_h with ws.h_reg): where c is
// zero in every entry, H is not made here (*h_later set; ws.h_reg its diagonal's reg). The
// floor's reg needs H's diagonal alone, summed as mtm_into sums it (+0 plus A Z(t, i)^2 over
// t in order: its zero entries' squares +0, which leave the sum as it is): the same reg and c.
// defer: H is not made here whatever c is (*h_later set): the cascade tries the level's
// row-space answer first (see solve_cascade_into), which needs no H.
inline void reduced_objective(CMatRef A, CVecRef b, CMatRef AZ, CMatRef Z, const double* d, double reg,
                              Workspace& ws, ReducedQP& out, bool z_eye = false, bool* h_later = nullptr,
                              bool defer = false) {
    i64 r = Z.cols;
    if (h_later) *h_later = false;
    out.hraw_ok = false;  // (until H is made below, or by make_h)
    // A d and Z^T d are kept (ws.Ad, ws.c2) for ls_form, free_answer and exact_level: the
    // same products they would make again.
    Vec& Ad = ws.Ad;
    mv_into(A, d, Ad);
    // (The elementwise loops below two entries a step: the same operation per lane.)
    using namespace simd;
    Vec& e = ws.e;
    shape(e, static_cast<size_t>(A.rows));
    {
        i64 i = 0;
        for (; i + 2 <= A.rows; i += 2) store(e.data() + i, load(Ad.data() + i) - load(b.p + i));
        for (; i < A.rows; ++i) e[i] = Ad[i] - b[i];
    }
    Vec& c1 = ws.c1;
    Vec& c2 = ws.c2;
    mtv_into(AZ, e.data(), c1);
    bool eye = z_eye && Z.rows == r;
    if (eye) {  // d finite: d_i - d_i == 0 exactly
        const v2d zero = splat(0.0);
        v2i fin = v2i{-1, -1};
        i64 i = 0;
        for (; i + 2 <= r; i += 2) {
            v2d x = load(d + i);
            fin &= ((x - x) == zero);
        }
        eye = fin[0] != 0 && fin[1] != 0;
        for (; eye && i < r; ++i) eye = std::isfinite(d[i]);
    }
    if (eye) {
        // Z = I, d finite: mtv_into's sum for entry c is +0 plus d_c (where d_c != 0) and terms
        // d_i 0 = +-0, which is d_c + 0.0.
        shape(c2, static_cast<size_t>(r));
        const v2d zero = splat(0.0);
        i64 i = 0;
        for (; i + 2 <= r; i += 2) store(c2.data() + i, load(d + i) + zero);
        for (; i < r; ++i) c2[i] = d[i] + 0.0;
    } else {
        mtv_into(Z, d, c2);
    }
    bool later = h_later != nullptr;
    for (i64 i = 0; later && !defer && i < r; ++i) later = c1[i] == 0.0 && c2[i] == 0.0;
    double big = 0.0;
    if (later) {
        for (i64 i = 0; i < r; ++i) {
            double acc = 0.0;
            for (i64 t = 0; t < AZ.rows; ++t) acc += AZ(t, i) * AZ(t, i);
            big = pymax(big, acc);
        }
    } else {
        mtm_into(AZ, out.H);
        for (i64 i = 0; i < r; ++i) big = pymax(big, out.H(i, i));
    }
    reg = pymax(reg, 1e-14 * (1.0 + big));
    shape(out.c, static_cast<size_t>(r));
    {
        const v2d rv = splat(reg);
        i64 i = 0;
        for (; i + 2 <= r; i += 2) store(out.c.data() + i, load(c1.data() + i) + rv * load(c2.data() + i));
        for (; i < r; ++i) out.c[i] = c1[i] + reg * c2[i];
    }
    if (later) {
        for (i64 i = 0; later && !defer && i < r; ++i) later = out.c[i] == 0.0;
        ws.h_reg = reg;
        if (later) {
            *h_later = true;
            return;
        }
        mtm_into(AZ, out.H);
    }
    out.hraw.resize(static_cast<size_t>(r));
    for (i64 i = 0; i < r; ++i) {
        out.hraw[i] = out.H(i, i);
        out.H(i, i) += reg;
    }
    out.hraw_ok = true;
}

// Box row i's bounds in null-space coordinates at d (the level's rows C z with C's row i Z's
// row i): lb_i - d_i and ub_i - d_i, an absent bound (beyond kBig) infinite. reduced_rows',
// rows_hold_at's and the row-space guess's.
inline double box_lo(CVecRef lb, const double* d, i64 i) { return lb[i] > -kBig ? lb[i] - d[i] : -kInf; }
inline double box_hi(CVecRef ub, const double* d, i64 i) { return ub[i] < kBig ? ub[i] - d[i] : kInf; }

// The rows (C, lo, hi) of reduced_qp. have_gz: ws.GZ and ws.Gd already hold G Z and G d
// (computed as below, by dual_stops_at_once).
// z_eye: Z is exactly the identity (a box row's norm is then 1: +0 plus 1 and 0 * 0 terms).
inline void reduced_rows(CMatRef Z, const double* d, CVecRef lb, CVecRef ub, CMatRef G, CVecRef h, Workspace& ws,
                         ReducedQP& out, bool have_gz = false, const double* gsq = nullptr, bool z_eye = false) {
    i64 n = Z.rows, r = Z.cols;
    i64 p = G.rows;
    shape(out.C, n + p, r);  // every entry, bound written below
    shape(out.lo, static_cast<size_t>(n + p));
    shape(out.hi, static_cast<size_t>(n + p));
    if (Z.stride == r) {  // Z's rows contiguous: one copy
        if (n > 0 && r > 0) std::memcpy(out.C.row(0), Z.row(0), static_cast<size_t>(n * r) * sizeof(double));
    } else {
        for (i64 i = 0; i < n; ++i) std::memcpy(out.C.row(i), Z.row(i), static_cast<size_t>(r) * sizeof(double));
    }
    for (i64 i = 0; i < n; ++i) {
        out.lo[i] = box_lo(lb, d, i);
        out.hi[i] = box_hi(ub, d, i);
    }
    if (p) {
        Mat& GZ = ws.GZ;
        if (!have_gz) mm_into(G, Z, GZ);
        if (r > 0) std::memcpy(out.C.row(n), GZ.row(0), static_cast<size_t>(p * r) * sizeof(double));  // GZ (p, r)
        Vec& Gd = ws.Gd;
        if (!have_gz) mv_into(G, d, Gd);
        for (i64 j = 0; j < p; ++j) {
            out.lo[n + j] = -kInf;
            out.hi[n + j] = h[j] - Gd[j];
        }
    }
    // (with Z = I a box row's norm 1 is above 1e-20: its bounds stay)
    // Each row's |c|^2 as dot sums it (eight rows a pass by detail::sq8: the same sums).
    auto test = [&](i64 i, double norm) {
        double size = 1.0;
        if (i >= n) size = gsq ? gsq[i - n] : row_sq_of(G, i - n);
        if (norm <= 1e-20 * size) {
            out.lo[i] = -kInf;
            out.hi[i] = kInf;
        }
    };
    i64 i = z_eye && r == n ? n : 0;
    for (; i + 8 <= n + p; i += 8) {
        const double* rows[8];
        for (int k = 0; k < 8; ++k) rows[k] = out.C.row(i + k);
        double sq[8];
        detail::sq8(rows, r, sq);
        for (int k = 0; k < 8; ++k) test(i + k, sq[k]);
    }
    for (; i < n + p; ++i) test(i, dot(out.C.row(i), out.C.row(i), r));
}

// The level's QP in null-space coordinates dq = d + Z z (see reduced_qp).
inline void reduced_qp(CMatRef A, CVecRef b, CMatRef AZ, CMatRef Z, const double* d, double reg, CVecRef lb,
                       CVecRef ub, CMatRef G, CVecRef h, Workspace& ws, ReducedQP& out) {
    reduced_objective(A, b, AZ, Z, d, reg, ws, out);
    reduced_rows(Z, d, lb, ub, G, h, ws, out);
}

inline ReducedQP reduced_qp(CMatRef A, CVecRef b, CMatRef AZ, CMatRef Z, const double* d, double reg,
                            CVecRef lb, CVecRef ub, CMatRef G, CVecRef h) {
    Workspace ws;
    ReducedQP out;
    reduced_qp(A, b, AZ, Z, d, reg, lb, ub, G, h, ws, out);
    return out;
}

// lb[dofs] = max(lb[dofs], lower), ub[dofs] = min(ub[dofs], upper) in place.
inline void tighten(VecRef lb, VecRef ub, VecRefT<const i64> dofs, CVecRef lower, CVecRef upper) {
    for (i64 k = 0; k < dofs.size(); ++k) {
        i64 i = dofs[k];
        if (lower[k] > lb[i]) lb[i] = lower[k];
        if (upper[k] < ub[i]) ub[i] = upper[k];
    }
}

// The merged box of hard and recoverable bounds; returns the first dof whose hard bounds
// conflict (entries from there on are left 0), else -1.
inline i64 merge_boxes(CVecRef hard_lb, CVecRef hard_ub, CVecRef pos_lb, CVecRef pos_ub, Vec& lb, Vec& ub) {
    i64 n = hard_lb.size();
    zero_fill(lb, static_cast<size_t>(n));
    zero_fill(ub, static_cast<size_t>(n));
    for (i64 i = 0; i < n; ++i) {
        if (hard_lb[i] > hard_ub[i]) return i;
        double lo = pymax(hard_lb[i], pos_lb[i]);
        double hi = pymin(hard_ub[i], pos_ub[i]);
        if (lo > hi) {
            if (pos_ub[i] < hard_lb[i]) {
                lo = hi = hard_lb[i];
            } else if (pos_lb[i] > hard_ub[i]) {
                lo = hi = hard_ub[i];
            }
        }
        lb[i] = lo;
        ub[i] = hi;
    }
    return -1;
}

namespace detail {

// The level's objective as least squares in z (see LSForm): B = [A Z; sqrt(rho) I].
// kept: ws.Ad and ws.c2 hold A d and Z^T d as reduced_objective computed them (the same
// products, not made again).
inline void ls_form(CMatRef A, CVecRef b, CMatRef AZ, CMatRef Z, const double* d, double rho, Workspace& ws,
                    LSForm& ls, bool kept = false) {
    i64 m = A.rows, r = AZ.cols;
    bool reg = rho > 0.0;
    ls.reg = reg;
    shape(ls.B, m + (reg ? r : 0), r);  // A Z's rows copied, sqrt(rho) I's zeroed then set
    if (reg) zero_small(ls.B.row(m), static_cast<size_t>(r * r));  // (16-byte stores: no memset call)
    shape(ls.f, static_cast<size_t>(ls.B.rows));
    Vec& e = kept ? ws.Ad : ws.e;
    if (!kept) mv_into(A, d, e);
    if (AZ.stride == r) {  // A Z's rows contiguous: one copy
        if (m > 0 && r > 0) std::memcpy(ls.B.row(0), AZ.row(0), static_cast<size_t>(m * r) * sizeof(double));
    } else {
        for (i64 i = 0; i < m; ++i)
            if (r) std::memcpy(ls.B.row(i), AZ.row(i), static_cast<size_t>(r) * sizeof(double));
    }
    for (i64 i = 0; i < m; ++i) ls.f[i] = b[i] - e[i];
    if (reg) {
        double s = std::sqrt(rho);
        Vec& zd = kept ? ws.c2 : ws.zd;
        if (!kept) mtv_into(Z, d, zd);
        for (i64 j = 0; j < r; ++j) {
            ls.B(m + j, j) = s;
            ls.f[m + j] = -s * zd[j];
        }
    }
}

inline LSForm ls_form(CMatRef A, CVecRef b, CMatRef AZ, CMatRef Z, const double* d, double rho) {
    Workspace ws;
    LSForm ls;
    ls_form(A, b, AZ, Z, d, rho, ws, ls);
    return ls;
}

// x = d + Z z (mv_into's sums). z_eye: Z is exactly the identity; with z finite each sum is
// +0 plus z_i and terms 0 z_t = +-0, which is z_i + 0.0 (the same bits without the product).
inline void add_step(CMatRef Z, const Vec& d, const Vec& z, bool z_eye, Vec& Zz, Vec& x) {
    i64 n = static_cast<i64>(d.size());
    bool eye = z_eye && Z.rows == n && Z.cols == n;
    for (i64 i = 0; eye && i < n; ++i) eye = std::isfinite(z[i]);
    if (eye) {
        for (i64 i = 0; i < n; ++i) x[i] = d[i] + (z[i] + 0.0);
        return;
    }
    mv_into(Z, z.data(), Zz);
    for (i64 i = 0; i < n; ++i) x[i] = d[i] + Zz[i];
}

// zref = -Z^T d (mtv_into's sum, negated), from ztd = Z^T d when the caller has it.
inline void neg_ztd(CMatRef Z, const Vec& d, const double* ztd, Vec& zref) {
    if (ztd) {
        shape(zref, static_cast<size_t>(Z.cols));
        for (i64 i = 0; i < Z.cols; ++i) zref[i] = -ztd[i];
        return;
    }
    mtv_into(Z, d.data(), zref);
    for (auto& v : zref) v = -v;
}

// The final answer's round-off outside its box put back on the bound: only violations up to
// kSnap (1 + |bound|), so A_j x moves by round-off at most (larger ones are reported by the
// certificate, never hidden).
constexpr double kSnap = 1e-12;
inline void snap_to_box(Vec& d, CVecRef lb, CVecRef ub) {
    for (size_t i = 0; i < d.size(); ++i) {
        if (d[i] < lb[i] && lb[i] - d[i] <= kSnap * (1.0 + std::fabs(lb[i]))) d[i] = lb[i];
        if (d[i] > ub[i] && d[i] - ub[i] <= kSnap * (1.0 + std::fabs(ub[i]))) d[i] = ub[i];
    }
}

// Whether z = 0 (x = d) meets every row of the reduced QP.
inline bool zero_feasible(CVecRef lo, CVecRef hi) {
    for (i64 i = 0; i < lo.size(); ++i)
        if (lo[i] > 0.0 || hi[i] < 0.0) return false;
    return true;
}

// (below; exact_level's answer for an empty working set)
inline bool free_answer(const LSForm& ls, CMatRef Ak, CVecRef bk, double rho, CMatRef Z, const Vec& d, CVecRef lb,
                        CVecRef ub, CMatRef G, CVecRef h, Vec& z, Certificate& cert, CertScratch& es,
                        const double* gsq, const double* ztd, bool z_eye, const ReducedQP* qp,
                        const QPScratch* made, const Vec* row_space);

// (below; exact_level's first candidate for a damped level with a few active rows)
inline bool eq_candidate(const LSForm& ls, const ReducedQP& qp, double rho, i64 m, const IVec& rows,
                         const IVec& sides, i64 q, const QPScratch* made, CertScratch& es, Vec& z, Vec& u);

// The final active set of a certified candidate: the first q rows of its working set (rows,
// sides) whose multiplier u is positive, in order.
inline void positive_rows(const IVec& rows, const IVec& sides, const Vec& u, i64 q, IVec& final_rows,
                          IVec& final_sides) {
    final_rows.clear();
    final_sides.clear();
    for (i64 j = 0; j < q; ++j) {
        if (u[j] > 0.0) {
            final_rows.push_back(rows[j]);
            final_sides.push_back(sides[j]);
        }
    }
}

// The rows of the working set (rows, sides: C's rows, their signs; the first q) that are
// independent in order: each kept unless its normal side_j C[row_j] lies within kDependent of
// the span of those kept before it (the test eqp_ls makes of the whole set, on R's diagonal).
inline void independent_rows(CMatRef C, const IVec& rows, const IVec& sides, i64 q, IVec& kept_rows,
                             IVec& kept_sides) {
    const i64 r = C.cols;
    kept_rows.clear();
    kept_sides.clear();
    ImplicitQR qr;
    qr.r = r;
    qr.q = 0;
    shape(qr.R, r, 0);
    Vec col(static_cast<size_t>(r));
    double scale = 0.0;
    for (i64 j = 0; j < q && qr.q < r; ++j) {
        const double side = static_cast<double>(sides[j]);
        const double* cj = C.row(rows[j]);
        double norm = 0.0;
        for (i64 i = 0; i < r; ++i) {
            col[i] = side * cj[i];
            norm += col[i] * col[i];
        }
        const i64 k = qr.q;
        qr.append(col.data());
        const double pivot = std::fabs(qr.R(k, k));
        if (!(pivot > kDependent * pymax(pymax(scale, std::sqrt(norm)), 1e-300))) {
            qr.truncate(k);
            continue;
        }
        scale = pymax(scale, pivot);
        kept_rows.push_back(rows[j]);
        kept_sides.push_back(sides[j]);
    }
}

// The level's candidate on a working set (set_candidate, below exact_level): the row-space
// form on a row-space level of box rows, else eq_candidate's.
inline bool set_candidate(const LSForm& ls, const ReducedQP& qp, double rho, i64 m, CMatRef Z, const double* d,
                          CVecRef lb, CVecRef ub, const IVec& rows, const IVec& sides, i64 q, const QPScratch* made,
                          CertScratch& es, Vec& z, Vec& u);

// exact_level's second primal active set (after the first's candidate failed): a row within
// this of the working set's span never blocks (kNearDependent in the first).
constexpr double kNearDependentRetry = 1e-6;

// One level made exact: the dual active set's rows (sol) re-solved on their canonical
// active set without regularisation, then certified; else the primal active set from a
// feasible point, certified. Returns true with z, the working set and the certificate when
// one of them holds; else false with the best candidate's certificate.
inline bool exact_level(const QPResult& sol, const LSForm& ls, const ReducedQP& qp, CMatRef Ak, CVecRef bk,
                        double rho, CMatRef Z, const Vec& d, CVecRef lb, CVecRef ub, CMatRef G, CVecRef h,
                        i64 max_iter, bool lower, Vec& z, Certificate& cert, IVec& final_rows,
                        IVec& final_sides, CertScratch* cs = nullptr, const Vec* free_z = nullptr,
                        const Certificate* free_cert = nullptr, const double* gsq = nullptr,
                        const double* ztd = nullptr, bool z_eye = false, const QPScratch* made = nullptr) {
    // ztd: Z^T d as mtv_into computes it, when the caller has it (the same product); z_eye: Z
    // is exactly the identity (certify_level's). made: the dual method's storage (its L:
    // qp.H's factor, as solve_qp makes it), when the caller has it (eq_candidate, as
    // normal_candidate, takes it where it is N's factor bit for bit, else makes N's).
    if (!cs) {  // storage of its own, only when the caller keeps none
        CertScratch local;
        return exact_level(sol, ls, qp, Ak, bk, rho, Z, d, lb, ub, G, h, max_iter, lower, z, cert, final_rows,
                           final_sides, &local, free_z, free_cert, gsq, ztd, z_eye, made);
    }
    i64 n = static_cast<i64>(d.size());
    CertScratch& es = *cs;
    IVec& rows = es.xrows;
    IVec& sides = es.xsides;
    rows.clear();
    sides.clear();
    Vec& u = es.xu;
    u.clear();
    cert = Certificate{};
    double best = kInf;
    es.has_best = false;
    double best_feasible = kInf;
    Vec& x = es.xx;
    zero_fill(x, static_cast<size_t>(n));
    auto certify = [&](const Vec& zc) {
        add_step(Z, d, zc, z_eye, es.xZz, x);
        Certificate c = certify_level(Ak, bk, rho, Z, x, lb, ub, G, h, rows, sides, u,
                                      static_cast<i64>(rows.size()), true, cs, gsq, z_eye, &qp.C,
                                      max_abs(zc, static_cast<i64>(zc.size())));
        if (c.worst() < best || std::isnan(cert.primal)) {
            best = c.worst();
            cert = c;
        }
        if (c.holds() && c.rows_relative) {  // the final active set: the rows with a positive multiplier
            positive_rows(rows, sides, u, static_cast<i64>(rows.size()), final_rows, final_sides);
            return true;
        }
        if (c.primal <= kCertify && c.rows_relative && c.worst() < best_feasible) {
            // (a feasible candidate not certified: kept for certified_by_refined_multipliers,
            // which the cascade tries last)
            best_feasible = c.worst();
            es.xbest = zc;
            es.has_best = true;
        }
        return false;
    };
    Vec& zc = es.xzc;
    zc.clear();
    bool have_dual = false;
    if (sol.status == SOLVED) {
        // The dual method's final working set (by row): its rows with a zero multiplier
        // included, where the floor's tie-break held the point on them.
        i64 q = canonical_set(sol.working.size() == sol.active.size() ? sol.working : sol.active, rows, sides);
        if (q == 0 && free_z && free_cert) {
            // free_answer made this re-solve and its certificate, which failed: the same
            // candidate and certificate, not made again.
            zc = *free_z;
            have_dual = true;
            cert = *free_cert;
            best = cert.worst();
        }
        // Of the minimisers, the one nearest x = 0 (z = -Z^T d), the tie-break the dual
        // method's floor makes: canonical (no dependence on the path or the warm start).
        if (q == 0 && !have_dual) {
            // An empty working set (cold or warm): free_answer's candidates in its order, the
            // same bits as where the cascade calls it; where none holds, its QR re-solve and
            // certificate (eqp_ls's with no rows) go on as the dual candidate.
            have_dual = true;
            if (free_answer(ls, Ak, bk, rho, Z, d, lb, ub, G, h, zc, cert, es, gsq, ztd, z_eye, &qp, nullptr,
                            nullptr)) {
                final_rows.clear();
                final_sides.clear();
                z = zc;
                return true;
            }
            best = cert.worst();
        }
        if (!have_dual && q > 0 &&
            set_candidate(ls, qp, rho, Ak.rows, Z, d.data(), lb, ub, rows, sides, q, made, es, zc, u)) {
            // A damped level with a few active rows: the normal equations' candidate first
            // (set_candidate: eq_candidate's, or its row-space form on a level of few rows),
            // taken only where its certificate holds; else the QR re-solve below as before
            // (this candidate's certificate not kept: the same cert, best and start as
            // without it).
            Certificate kept = cert;
            double kept_best = best;
            if (certify(zc)) {
                z = zc;
                return true;
            }
            cert = kept;
            best = kept_best;
        }
        Vec& zref = es.xzref;
        neg_ztd(Z, d, ztd, zref);
        if (!have_dual &&
            eqp_ls(ls, qp.C.cref(), CVecRef(qp.lo), CVecRef(qp.hi), rows, sides, q, zref, zc, u, nullptr, cs)) {
            have_dual = true;
            if (certify(zc)) {
                z = zc;
                return true;
            }
        }
        if (!have_dual && q > 0) {
            // The working set's rows depend on one another in Z (eqp_ls declined it: a row
            // within kDependent of the others' span, as box rows whose Z rows are parallel):
            // the same re-solve on its independent rows, in order (each row the others left
            // out is met where they are, to that tolerance; the certificate checks every row).
            IVec kept_rows, kept_sides;
            detail::independent_rows(qp.C.cref(), rows, sides, q, kept_rows, kept_sides);
            if (static_cast<i64>(kept_rows.size()) < q) {
                rows = kept_rows;
                sides = kept_sides;
                const i64 qk = static_cast<i64>(rows.size());
                if (eqp_ls(ls, qp.C.cref(), CVecRef(qp.lo), CVecRef(qp.hi), rows, sides, qk, zref, zc, u, nullptr,
                           cs)) {
                    have_dual = true;
                    if (certify(zc)) {
                        z = zc;
                        return true;
                    }
                }
            }
        }
    }
    // The start: z = 0 (the level above's certified answer, or the clipped zero) where it
    // is feasible (canonical), else the dual method's own iterate where that is.
    Vec& start = es.xstart;
    start.assign(static_cast<size_t>(qp.H.rows), 0.0);
    if (!lower && !zero_feasible(CVecRef(qp.lo), CVecRef(qp.hi))) {
        if (have_dual && cert.primal <= kCertify) {
            start = zc;
        } else if (sol.x.size() == start.size() && (sol.status == SOLVED || sol.status == MAX_ITER)) {
            Vec Zz = mv(Z, sol.x.data());
            for (i64 i = 0; i < n; ++i) x[i] = d[i] + Zz[i];
            if (!(certify_level(Ak, bk, rho, Z, x, lb, ub, G, h, {}, {}, {}, 0, false).primal <= kCertify)) return false;
            start = sol.x;
        } else {
            return false;
        }
    }
    Vec& again = es.xagain;
    again = start;
    bool pok = primal_active_set(ls, qp.C.cref(), CVecRef(qp.lo), CVecRef(qp.hi), start, rows, sides, u, max_iter);
    if (pok) {
        if (certify(start)) {
            z = start;
            return true;
        }
    }
    // Tight rows nearly dependent at a degenerate vertex: a row whose normal lies just
    // outside kNearDependent of the working set's span (1.2e-8 at a Panda's posture level,
    // three dofs on their bounds whose rows of Z are positively dependent to 1e-10) blocks
    // the step at once and joins the set, whose multipliers (1e10) then cancel beyond any
    // certificate; the level was kept where moving one free dof to its bound lowered its
    // objective (tests/data/exactness/hqp_near_dependent_pins.npz). Once more from the same
    // start with such rows (within kNearDependentRetry) never blocking: each candidate is
    // certified as any other (a row so passed is met to its certificate's tolerance or the
    // candidate fails), so only a level no candidate certified changes.
    static_assert(kNearDependentRetry > kNearDependent, "the retry must pass more rows than the first try");
    start = again;
    pok = primal_active_set(ls, qp.C.cref(), CVecRef(qp.lo), CVecRef(qp.hi), start, rows, sides, u, max_iter,
                            kNearDependentRetry);
    if (pok && certify(start)) {
        z = start;
        return true;
    }
    return false;
}

// Whether the dual method, cold, stops at once on the level's QP (qp's H and c; its rows
// C, lo, hi those reduced_rows writes, not formed): H's Cholesky factor exists and the
// unconstrained minimiser x0 = -H^-1 c violates no row by more than tol. Each test is
// solve_qp's, with the same bits: x0 by the same factor and solves, a row's norm, bounds and
// C x0 as reduced_rows and most_violated compute them (C's rows are Z's and G Z's). solve_level
// then returns x0 with an empty working set, and the level's answer is exact_level's re-solve
// with no rows (free_answer).
// factored: whether ws.qps then holds H's factor and x0 as solve_qp computes them (its
// `factored` argument); have_gz: whether ws.GZ and ws.Gd hold G Z and G d as reduced_rows
// computes them.
inline bool factor_x0(const ReducedQP& qp, Workspace& ws, bool& factored);
inline bool rows_hold_at(CMatRef Z, const double* d, CVecRef lb, CVecRef ub, CMatRef G, CVecRef h, double tol,
                         Workspace& ws, bool& have_gz, bool z_eye, const double* gsq, const Vec& x);
inline bool dual_stops_at_once(const ReducedQP& qp, CMatRef Z, const double* d, CVecRef lb, CVecRef ub, CMatRef G,
                               CVecRef h, double tol, Workspace& ws, bool& factored, bool& have_gz,
                               bool z_eye = false, const double* gsq = nullptr, bool* deferred = nullptr) {
    // deferred (where the caller can finish the test, stops_finished): where c is zero in every
    // entry, the rows are tested at x0 = 0 (see below) and H is not factored (nor read: it may
    // not be made yet, reduced_objective's h_later); where they hold, *deferred is set and true
    // returned; where they fail, false with factored false.
    i64 r = Z.cols;
    QPScratch& qs = ws.qps;
    Vec& x = qs.x;
    factored = have_gz = false;
    if (deferred) *deferred = false;
    bool zero_c = deferred != nullptr;
    for (i64 i = 0; zero_c && i < r; ++i) zero_c = qp.c[i] == 0.0;
    if (zero_c) {
        // c = +-0: x0 = -H^-1 c from a finite factor is +-0 in every entry (each solve's sums
        // and quotients of zeros), and every test reads x0 only through sums from +0 of terms
        // C(i, t) x0_t (+-0 for a finite entry, NaN for a non-finite one whatever the zero's
        // sign; a test of NaN is false either way) or x0_i + 0.0: the same decisions at x0 = +0.
        // Only where the rows hold does the answer differ from factoring first, and only where
        // H's factor does not exist or x0 is not finite (the general path then, free_answer's
        // certified answer now).
        x.assign(static_cast<size_t>(r), 0.0);
        if (rows_hold_at(Z, d, lb, ub, G, h, tol, ws, have_gz, z_eye, gsq, x)) {
            *deferred = true;
            return true;
        }
        // (no factor: solve_qp makes it, as it makes x0, where the level is cold - as it is here
        // - the same bits as from factored; and where it does not exist, NUMERICAL as before)
        return false;
    }
    if (!factor_x0(qp, ws, factored)) return false;
    return rows_hold_at(Z, d, lb, ub, G, h, tol, ws, have_gz, z_eye, gsq, x);
}

// H's factor (ws.qps.L) and x0 = -H^-1 c (ws.qps.x) as solve_qp computes them: false where the
// factor does not exist (factored false) or x0 is not finite (factored true).
inline bool factor_x0(const ReducedQP& qp, Workspace& ws, bool& factored) {
    i64 r = qp.H.rows;
    QPScratch& qs = ws.qps;
    Mat& Lm = qs.L;
    zero_upper(Lm, r);  // cholesky_into writes the rest before reading it
    factored = false;
    if (!cholesky_into(qp.H.cref(), r, 0.0, Lm.ref())) return false;
    Vec& mc = qs.mc;
    mc.resize(static_cast<size_t>(r));
    for (i64 i = 0; i < r; ++i) mc[i] = -qp.c[i];
    forward_into(Lm.cref(), mc, qs.y);
    Vec& x = qs.x;
    backward_into(Lm.cref(), qs.y, x);
    factored = true;
    // A non-finite x0: the general path decides (most_violated's unit rows read one entry).
    for (i64 i = 0; i < r; ++i)
        if (!std::isfinite(x[i])) return false;
    return true;
}

// dual_stops_at_once after it deferred H's factor (*deferred) and free_answer found no answer:
// the factor and x0 now, and whether the dual method stops at once (the rows held at x0 = 0:
// the factor exists and x0 is finite), with factored as dual_stops_at_once would leave it.
inline bool stops_finished(const ReducedQP& qp, Workspace& ws, bool& factored) {
    return factor_x0(qp, ws, factored);
}

// The side a row c leaves at cx = c . x, its norm |c| > 0 and its bounds lo <= cx <= hi (each
// absent past kBig), to tol relative to the bound: +1 below lo, -1 above hi, 0 where it holds
// (the dual method's test of a violated row: rows_hold_at's, primal_guess's); `by` the
// violation (cx's distance past the bound over |c|, infinite where cx is), 0 where it holds.
inline i64 leaving_side(double lo, double hi, double cx, double norm, double tol, double& by) {
    by = 0.0;
    if (lo > -kBig) {
        const double v = (lo - cx) / norm;
        if (v > tol * (1.0 + std::fabs(lo)) && v > 0.0) {
            by = v;
            return 1;
        }
    }
    if (hi < kBig) {
        const double v = (cx - hi) / norm;
        if (v > tol * (1.0 + std::fabs(hi)) && v > 0.0) {
            by = v;
            return -1;
        }
    }
    return 0;
}

// Whether x0 (r,) violates no row of the level's QP by more than tol (dual_stops_at_once's
// tests; G Z and G d made and kept, have_gz).
inline bool rows_hold_at(CMatRef Z, const double* d, CVecRef lb, CVecRef ub, CMatRef G, CVecRef h, double tol,
                         Workspace& ws, bool& have_gz, bool z_eye, const double* gsq, const Vec& x) {
    i64 n = Z.rows, r = Z.cols, p = G.rows;
    // Row c (r,) with bounds lo, hi (reduced_rows: size 1 for a box row, |g|^2 for a general
    // one). C x0 summed over every column: for a finite x0 the same value as most_violated's
    // one-entry sum on a unit row (the other terms are zeros), so the same decision.
    // Z = I: box row i is row i of the identity, norm = 1 and cx = x[i] + 0.0, the sums' values
    // (+0 plus one term 1 or x[i], the others 0 * 0 or 0 * x_t = +-0; x0 finite).
    // The sums of a row (norm = |c|^2, cx = c . x0), two rows a pass (one a lane; each sum in
    // index order from +0, the scalar loop's operations).
    auto sums2 = [&](const double* c0, const double* c1, double& n0, double& x0, double& n1, double& x1) {
        using namespace simd;
        v2d nn = splat(0.0), cc = splat(0.0);
        for (i64 t = 0; t < r; ++t) {
            v2d ct = v2d{c0[t], c1[t]};
            nn = nn + ct * ct;
            cc = cc + ct * splat(x[t]);
        }
        n0 = nn[0];
        x0 = cc[0];
        n1 = nn[1];
        x1 = cc[1];
    };
    auto sums1 = [&](const double* c, double& norm, double& cx) {
        norm = 0.0;
        cx = 0.0;
        for (i64 t = 0; t < r; ++t) {
            norm += c[t] * c[t];
            cx += c[t] * x[t];
        }
    };
    // Eight rows a pass (four pairs of lanes: eight sums in flight), each row's sums as sums2's.
    auto sums8 = [&](const double* const* c, double* nsq, double* cx) {
        using namespace simd;
        v2d n0 = splat(0.0), n1 = splat(0.0), n2 = splat(0.0), n3 = splat(0.0);
        v2d x0 = splat(0.0), x1 = splat(0.0), x2 = splat(0.0), x3 = splat(0.0);
        const double *c0 = c[0], *c1 = c[1], *c2 = c[2], *c3 = c[3], *c4 = c[4], *c5 = c[5], *c6 = c[6],
                     *c7 = c[7];
        for (i64 t = 0; t < r; ++t) {
            v2d xt = splat(x[t]);
            v2d a = v2d{c0[t], c1[t]}, b = v2d{c2[t], c3[t]}, e = v2d{c4[t], c5[t]}, f = v2d{c6[t], c7[t]};
            n0 = n0 + a * a;
            x0 = x0 + a * xt;
            n1 = n1 + b * b;
            x1 = x1 + b * xt;
            n2 = n2 + e * e;
            x2 = x2 + e * xt;
            n3 = n3 + f * f;
            x3 = x3 + f * xt;
        }
        nsq[0] = n0[0], nsq[1] = n0[1], nsq[2] = n1[0], nsq[3] = n1[1];
        nsq[4] = n2[0], nsq[5] = n2[1], nsq[6] = n3[0], nsq[7] = n3[1];
        cx[0] = x0[0], cx[1] = x0[1], cx[2] = x1[0], cx[3] = x1[1];
        cx[4] = x2[0], cx[5] = x2[1], cx[6] = x3[0], cx[7] = x3[1];
    };
    // Whether rows i0..i1 - 1 of M (its rows' norms and products with x; rows j, j + 1 summed
    // together, eight rows a pass where there are) hold a row `test` finds violated, decided in
    // row order.
    auto violated = [&](const auto& M, i64 i0, i64 i1, const auto& test) {
        i64 i = i0;
        for (; r >= 16 && i + 8 <= i1; i += 8) {  // (short rows: sums2's pairs cost less)
            const double* rows[8];
            for (int k = 0; k < 8; ++k) rows[k] = M.row(i + k);
            double nsq[8], cx[8];
            sums8(rows, nsq, cx);
            for (int k = 0; k < 8; ++k)
                if (test(i + k, nsq[k], cx[k])) return true;
        }
        for (; i + 2 <= i1; i += 2) {
            double n0, x0, n1, x1;
            sums2(M.row(i), M.row(i + 1), n0, x0, n1, x1);
            if (test(i, n0, x0) || test(i + 1, n1, x1)) return true;
        }
        for (; i < i1; ++i) {
            double norm, cx;
            sums1(M.row(i), norm, cx);
            if (test(i, norm, cx)) return true;
        }
        return false;
    };
    auto decide = [&](double norm, double cx, double lo, double hi, double size) {
        if (norm <= 1e-20 * size) return false;  // no constraint (reduced_rows)
        double by;
        return leaving_side(lo, hi, cx, std::sqrt(norm), tol, by) != 0;
    };
    // General rows first (the rows a binding level meets most often); G Z and G d are kept for
    // reduced_rows (have_gz).
    if (p) {
        Mat& GZ = ws.GZ;
        if (z_eye && all_finite(G)) {
            // mm(G, I) written without forming it (as project_level's A Z): the entry G(i, j)
            // where it is nonzero, else +0 (every other term a finite G(i, t) * 0 = +-0 added
            // to a sum from +0).
            GZ.zeros(p, n);
            for (i64 i = 0; i < p; ++i) {
                const double* gi = G.row(i);
                double* dst = GZ.row(i);
                for (i64 j = 0; j < n; ++j)
                    if (gi[j] != 0.0) dst[j] = gi[j];
            }
        } else {
            mm_into(G, Z, GZ);
        }
        Vec& Gd = ws.Gd;
        mv_into(G, d, Gd);
        have_gz = true;
        auto general = [&](i64 j, double norm, double cx) {
            double size = gsq ? gsq[j] : row_sq_of(G, j);
            return decide(norm, cx, -kInf, h[j] - Gd[j], size);
        };
        if (violated(GZ, 0, p, general)) return false;
    }
    auto box = [&](i64 i, double norm, double cx) {
        double lo = box_lo(lb, d, i);
        double hi = box_hi(ub, d, i);
        return decide(norm, cx, lo, hi, 1.0);
    };
    i64 i = 0;
    if (z_eye && r == n) {
        for (; i < n; ++i)
            if (box(i, 1.0, x[i] + 0.0)) return false;
    }
    return !violated(Z, i, n, box);
}

// Rows i0..i1 - 1 of B zref into f0 (sized to B's rows), each row's sum as mv_into makes it
// (over t in order from 0.0: the same bits whichever rows are taken together).
inline void b_zref_rows(const LSForm& ls, const Vec& zref, Vec& f0, i64 i0, i64 i1) {
    const Mat& B = ls.B;
    const i64 n = B.cols;
    const double* x = zref.data();
    i64 i = i0;
    for (; i + 4 <= i1; i += 4)
        dot4(B.row(i), B.row(i + 1), B.row(i + 2), B.row(i + 3), x, n, f0[i], f0[i + 1], f0[i + 2], f0[i + 3]);
    for (; i + 2 <= i1; i += 2) dot2(B.row(i), B.row(i + 1), x, n, f0[i], f0[i + 1]);
    for (; i < i1; ++i) {
        const double* bi = B.row(i);
        double acc = 0.0;
        for (i64 j = 0; j < n; ++j) acc += bi[j] * x[j];
        f0[i] = acc;
    }
}

// Whether B zref = f exactly (eqp_ls's right-hand side f - B zref with no rows, computed as
// eqp_ls does, is zero in every entry), with B finite and below 1e100 in every entry and zref
// finite (free_answer's shortcut). B zref (es.f0) is made four rows at a time, up to the first
// rows that differ from f: done = the rows made (the rest, where free_answer's QR needs
// them, made there: the same bits as one mv_into).
inline bool residual_free(const LSForm& ls, const Vec& zref, CertScratch& es, i64& done) {
    Vec& f0 = es.f0;
    const i64 mb = ls.B.rows;
    f0.resize(static_cast<size_t>(mb));  // entries 0..done - 1 written below
    done = 0;
    while (done < mb) {
        const i64 next = std::min(done + 4, mb);
        b_zref_rows(ls, zref, f0, done, next);
        const i64 from = done;
        done = next;
        for (i64 i = from; i < next; ++i)
            if (ls.f[i] - f0[i] != 0.0) return false;
    }
    for (double v : zref)
        if (!std::isfinite(v)) return false;
    for (i64 i = 0; i < ls.B.rows; ++i)
        for (i64 j = 0; j < ls.B.cols; ++j)
            if (!(std::fabs(ls.B(i, j)) <= 1e100)) return false;
    return true;
}

// The free level's answer by the normal equations (free_answer's second candidate), a function
// of B = [A Z; s I] and f alone (ls_form's; s = sqrt(rho)), as the QR re-solve is: where rho > 0
// and trace B^T B <= kNormalCond s^2 (B^T B's condition number at most kNormalCond, its least
// eigenvalue being at least s^2), B has full column rank and one least-squares minimiser, which
// x0 = N^-1 B^T f solves, N = (A Z)^T A Z + s^2 I (mtm_into of B's first m rows, s * s added to
// its diagonal) by its Cholesky factor (cholesky_into on a zeroed r x r matrix); z = x0 + N^-1
// B^T (f - B x0) is one step of refinement by the same factor from B's own residual (the error
// of the normal equations, about cond eps, multiplied by about cond eps again). False (no
// candidate) where a condition fails or N's factor does not exist.
// Not rho itself (nor qp's c): two paths may pass rho an ulp apart with the same s, B and f (the
// IK step's fused and general paths sum a level's LM terms in different orders), and the QR's
// answer sees rho only through s. N is qp.H bit for bit where s * s == rho and qp.H had no
// floor added (reduced_objective: the same mtm_into, then + reg, reg = rho where rho >= 2e-14
// (1 + max diag H)); there made, dual_stops_at_once's factor of qp.H (ws.qps.L: the same
// cholesky_into on a zeroed r x r matrix), is taken rather than made again: the same bits.
// Either way the candidate is the same bits on every path to it (cold or warm, cascade or
// level by level, fused or general).
// normal_factor: N's factor under those conditions (L, in made->L or es.BW), false where one
// fails; normal_candidate and eq_candidate (below) both start from it.
constexpr double kNormalCond = 1e10;
inline bool normal_factor(const LSForm& ls, const ReducedQP& qp, double rho, i64 m, const QPScratch* made,
                          CertScratch& es, CMatRef& L) {
    i64 r = ls.B.cols;
    if (!ls.reg || r <= 0 || ls.B.rows != m + r || static_cast<i64>(ls.f.size()) != m + r) return false;
    CMatRef AZ = ls.B.cref().rows_slice(0, m);
    double s = ls.B(m, 0);
    double s2 = s * s;
    double trace = 0.0;  // trace (A Z)^T A Z, summed by rows
    for (i64 i = 0; i < m; ++i) {
        const double* ai = AZ.row(i);
        for (i64 j = 0; j < r; ++j) trace += ai[j] * ai[j];
    }
    if (!(s2 > 0.0) || !(trace + static_cast<double>(r) * s2 <= kNormalCond * s2)) return false;
    bool same = made != nullptr && s2 == rho && qp.H.rows == r && qp.H.cols == r && made->L.rows == r &&
                made->L.cols == r;
    double big = 0.0;
    for (i64 i = 0; same && i < r; ++i) big = pymax(big, qp.H(i, i));
    same = same && rho >= 2e-14 * (1.0 + big);
    if (same) {
        L = made->L.cref();
    } else {
        Mat& N = es.N;  // eqp_ls's N and BW, unused with no rows until the QR
        if (qp.hraw_ok && qp.H.rows == r && qp.H.cols == r && static_cast<i64>(qp.hraw.size()) == r) {
            // (A Z)^T A Z from qp.H, made by the same mtm_into of the same A Z: its entries off
            // the diagonal, and on it mtm_into's before the regularisation (qp.hraw): the same
            // bits as mtm_into here, without its m r^2 products (s * s != rho by an ulp, or a
            // floor added to H: its factor not N's)
            shape(N, r, r);
            std::memcpy(N.a.data(), qp.H.a.data(), static_cast<size_t>(r * r) * sizeof(double));
            for (i64 i = 0; i < r; ++i) N(i, i) = qp.hraw[i];
        } else {
            mtm_into(AZ, N);
        }
        for (i64 i = 0; i < r; ++i) N(i, i) += s2;
        Mat& Lm = es.BW;
        Lm.zeros(r, r);
        if (!cholesky_into(N.cref(), r, 0.0, Lm.ref())) return false;
        L = Lm.cref();
    }
    return true;
}

inline bool normal_candidate(const LSForm& ls, const ReducedQP& qp, double rho, i64 m, const QPScratch* made,
                             CertScratch& es, Vec& z) {
    CMatRef L;
    if (!normal_factor(ls, qp, rho, m, made, es, L)) return false;
    i64 r = ls.B.cols;
    CMatRef AZ = ls.B.cref().rows_slice(0, m);
    double s = ls.B(m, 0);
    // x0 = N^-1 B^T f (B^T f from A Z's rows and the diagonal alone: B's last r rows are s I)
    Vec& g = es.g;
    mtv_into(AZ, ls.f.data(), g);
    for (i64 j = 0; j < r; ++j) g[j] += s * ls.f[m + j];
    forward_into(L, g, es.wy);
    Vec& x0 = es.t;
    backward_into(L, es.wy, x0);
    // z = x0 + N^-1 B^T (f - B x0)
    Vec& res = es.e;
    mv_into(AZ, x0.data(), res);
    for (i64 i = 0; i < m; ++i) res[i] = ls.f[i] - res[i];
    mtv_into(AZ, res.data(), g);
    for (i64 j = 0; j < r; ++j) g[j] += s * (ls.f[m + j] - s * x0[j]);
    forward_into(L, g, es.wy);
    backward_into(L, es.wy, es.r);
    z.resize(static_cast<size_t>(r));
    for (i64 i = 0; i < r; ++i) z[i] = x0[i] + es.r[i];
    return true;
}

// free_answer's candidate on a damped level of few rows (m rows, r free directions,
// row_space_level: a humanoid's feet or CoM level, an arm's frame task), in
// place of normal_candidate's: the same minimiser of 1/2 |B z - f|^2 (B = [M; s I], M = A Z,
// f = [f1; f2], ls_form's) through the space of M's rows. With z = f2 / s + v, v minimises
// |M v - e|^2 + s^2 |v|^2, e = f1 - M f2 / s, whose answer is v = M^T K^-1 e, K = M M^T +
// s^2 I (m x m, its Cholesky factor), with no cancellation (the terms of z add, none is the
// difference of two large ones); then one step of refinement, z += N^-1 B^T (f - B z) by
// N^-1 = (I - M^T K^-1 M) / s^2 (row_space_refine). The conditions are normal_factor's
// (rho > 0, trace B^T B <= kNormalCond s^2: K's condition number is at most N's bound), so
// the candidate is as accurate as normal_candidate's (more, on Talos' feet: 4e-16 against
// 1e-15 of a long-double solve). A function of B and f alone: every path to free_answer
// (the cascade's cold level, exact_level's empty working set, warm or cold) makes the same
// bits. False (no candidate: normal_candidate's then) where a condition fails, K's factor
// does not exist or an entry is not finite.
// The levels row_space_candidate takes: fewer rows than free directions, and either at most
// half as many (a humanoid's feet: 12 rows, 38 directions) or at most kRowSpaceFew (a frame
// task's 6 rows on an arm of 7 to 9 dofs), where K's factor costs little against H's (r x r)
// and the level binds no row most often. (A humanoid's hands, 12 rows against 23 directions
// under the feet and CoM, bind most steps: there the try would cost more than it saves.)
constexpr i64 kRowSpaceFew = 8;
inline bool row_space_level(i64 m, i64 r) { return m < r && (2 * m <= r || m <= kRowSpaceFew); }

// The row-space form's factor: with M = A Z (B's first m rows) and s = sqrt(rho) (B's row m),
// K = M M^T + s^2 I (m x m, its lower triangle) and its Cholesky factor into Lm; false where
// normal_factor's trace bound fails (trace M M^T + r s^2 > kNormalCond s^2) or the factor
// does not exist. row_space_candidate's and row_space_set_candidate's.
inline bool row_space_factor(const LSForm& ls, i64 m, Mat& K, Mat& Lm) {
    const i64 r = ls.B.cols;
    CMatRef M = ls.B.cref().rows_slice(0, m);
    const double s = ls.B(m, 0);
    const double s2 = s * s;
    double trace = 0.0;  // trace M M^T (normal_factor's sum)
    for (i64 i = 0; i < m; ++i) {
        const double* mi = M.row(i);
        for (i64 j = 0; j < r; ++j) trace += mi[j] * mi[j];
    }
    if (!(s2 > 0.0) || !(trace + static_cast<double>(r) * s2 <= kNormalCond * s2)) return false;
    K.zeros(m, m);
    for (i64 i = 0; i < m; ++i) {
        for (i64 j = 0; j <= i; ++j) K(i, j) = dot(M.row(i), M.row(j), r);
        K(i, i) += s2;
    }
    Lm.zeros(m, m);
    return cholesky_into(K.cref(), m, 0.0, Lm.ref());
}

// refine false: the first solve alone (K's factor left in es.BW for row_space_refine, which
// then makes the same bits as refine true).
inline void row_space_refine(const LSForm& ls, i64 m, CertScratch& es, Vec& z);
inline bool row_space_candidate(const LSForm& ls, i64 m, CertScratch& es, Vec& z, bool refine = true) {
    i64 r = ls.B.cols;
    if (!ls.reg || m <= 0 || !row_space_level(m, r) || ls.B.rows != m + r || static_cast<i64>(ls.f.size()) != m + r)
        return false;
    // (K in normal_factor's storage: free_answer takes one candidate or the other)
    if (!row_space_factor(ls, m, es.N, es.BW)) return false;
    CMatRef M = ls.B.cref().rows_slice(0, m);
    const double s = ls.B(m, 0);
    CMatRef L = es.BW.cref();
    // out = g2 / s + M^T K^-1 (g1 - M g2 / s): the minimiser for the right-hand side [g1; g2]
    auto solve = [&](const double* g1, const double* g2, Vec& out) {
        out.resize(static_cast<size_t>(r));
        for (i64 j = 0; j < r; ++j) out[j] = g2[j] / s;
        Vec& e = es.e;
        e.resize(static_cast<size_t>(m));
        for (i64 i = 0; i < m; ++i) e[i] = g1[i] - dot(M.row(i), out.data(), r);
        forward_into(L, e, es.wy);
        backward_into(L, es.wy, es.g);
        for (i64 i = 0; i < m; ++i) axpy(out.data(), es.g[i], M.row(i), r);
    };
    solve(ls.f.data(), ls.f.data() + m, z);
    if (!finite_block(z.data(), 1, r, r)) return false;
    if (refine) row_space_refine(ls, m, es, z);
    return refine ? finite_block(z.data(), 1, r, r) : true;
}

inline void row_space_refine(const LSForm& ls, i64 m, CertScratch& es, Vec& z) {
    i64 r = ls.B.cols;
    CMatRef M = ls.B.cref().rows_slice(0, m);
    const double s = ls.B(m, 0);
    const double s2 = s * s;
    CMatRef L = es.BW.cref();
    // One step of refinement: z += N^-1 g, g = B^T (f - B z) (the normal equations' error,
    // small), by N^-1 = (I - M^T K^-1 M) / s^2 (g's part in M's row space, where N^-1 is
    // (M^T M + s^2 I)^-1 and the subtraction cancels, is about eps / s^2 relative off in a
    // correction that is itself about cond(K) eps relative: far below the answer's ulp).
    Vec& res = es.t;
    res.resize(static_cast<size_t>(m));
    for (i64 i = 0; i < m; ++i) res[i] = ls.f[i] - dot(M.row(i), z.data(), r);
    Vec& g = es.r;
    g.resize(static_cast<size_t>(r));
    for (i64 j = 0; j < r; ++j) g[j] = s * (ls.f[m + j] - s * z[j]);
    for (i64 i = 0; i < m; ++i) axpy(g.data(), res[i], M.row(i), r);
    Vec& e = es.e;
    e.resize(static_cast<size_t>(m));
    for (i64 i = 0; i < m; ++i) e[i] = dot(M.row(i), g.data(), r);
    forward_into(L, e, es.wy);
    backward_into(L, es.wy, es.g);
    for (i64 i = 0; i < m; ++i) axpy(g.data(), -es.g[i], M.row(i), r);
    for (i64 j = 0; j < r; ++j) z[j] = z[j] + g[j] / s2;
}

// The Schur complement S (q x q by rows, its lower triangle) factored in place (Cholesky);
// false where a pivot is not finite or below S_jj / kNormalCond (a row within about 1e-5 of
// the others' span in the metric S is made in): eq_candidate's and row_space_set_candidate's.
inline bool schur_factor(Vec& S, i64 q) {
    for (i64 j = 0; j < q; ++j) {
        double sjj = S[j * q + j], dj = sjj;
        for (i64 k = 0; k < j; ++k) dj -= S[j * q + k] * S[j * q + k];
        if (!(std::isfinite(sjj) && dj > 0.0 && sjj <= kNormalCond * dj)) return false;
        double ljj = std::sqrt(dj);
        S[j * q + j] = ljj;
        for (i64 i = j + 1; i < q; ++i) {
            double a = S[i * q + j];
            for (i64 k = 0; k < j; ++k) a -= S[i * q + k] * S[j * q + k];
            S[i * q + j] = a / ljj;
        }
    }
    return true;
}

// du = S^-1 du in place, by schur_factor's factor (forward, then backward substitution).
inline void schur_solve(const Vec& S, i64 q, Vec& du) {
    for (i64 j = 0; j < q; ++j) {
        double acc = du[j];
        for (i64 k = 0; k < j; ++k) acc -= S[j * q + k] * du[k];
        du[j] = acc / S[j * q + j];
    }
    for (i64 j = q - 1; j >= 0; --j) {
        double acc = du[j];
        for (i64 k = j + 1; k < q; ++k) acc -= S[k * q + j] * du[k];
        du[j] = acc / S[j * q + j];
    }
}

// The refinement's right-hand side from B's own residual at z: g = B^T (f - B z) (res: f - B z's
// first m entries), B = [M; s I] (ls_form): eq_candidate's and row_space_set_candidate's.
inline void residual_gradient(const LSForm& ls, CMatRef M, i64 m, double s, const Vec& z, Vec& res, Vec& g) {
    const i64 r = ls.B.cols;
    mv_into(M, z.data(), res);
    for (i64 i = 0; i < m; ++i) res[i] = ls.f[i] - res[i];
    mtv_into(M, res.data(), g);
    for (i64 j = 0; j < r; ++j) g[j] += s * (ls.f[m + j] - s * z[j]);
}

// exact_level's candidate on a damped level with a few active rows (0 < q <= kEqCandidateRows):
// the minimiser of 1/2 |B z - f|^2 with the working set's rows held as equalities (n_j^T z =
// rhs_j, n_j = side_j C[row_j], as eqp_ls writes them) and its multipliers (B^T (B z - f) =
// sum_j u_j n_j), from N = B^T B's factor L (normal_factor: its conditions, its bits) and the
// Schur complement S = V^T V, V = L^-1 [n_1 .. n_q] (its Cholesky factor, q x q): with w =
// L^-1 B^T f, u = S^-1 (rhs - V^T w) and z = L^-T (w + V u); then one step of refinement by
// the same factors from B's own residual (B^T (f - B z) + N u and rhs - N^T z; normal_candidate's
// step with the rows added). With rho > 0 the minimiser is unique: this is eqp_ls's answer to
// round-off, and a function of B, f, the rows and the final working set alone (never of the
// dual method's path: cold and warm starts give the same bits). False (no candidate) where
// normal_factor's conditions fail (its trace bound) or a pivot of S is below S_jj /
// kNormalCond (a row within about 1e-5 of the others' span in N's metric): those levels take
// the QR re-solve. Small levels (r < kRegFoldMin, eqp_ls's fold's bound), where the dense QR
// costs little, keep it: the normal equations' answer differs from the QR's by about
// eps |B|^2 / s^2 relative on an ill-conditioned one (6e-12 with s = 1e-3, |B| = 0.75:
// tests/fixtures/core.npz's case 184, r = 5, past that test's 1e-12).
constexpr i64 kEqCandidateRows = 16;
static_assert(kEqCandidateRows <= kForwardRows, "eq_candidate solves its rows by forward_rows_into");
inline bool eq_candidate(const LSForm& ls, const ReducedQP& qp, double rho, i64 m, const IVec& rows,
                         const IVec& sides, i64 q, const QPScratch* made, CertScratch& es, Vec& z, Vec& u) {
    i64 r = ls.B.cols;
    if (q <= 0 || q > kEqCandidateRows || q >= r || r < kRegFoldMin || qp.C.cols != r) return false;
    CMatRef L;
    if (!normal_factor(ls, qp, rho, m, made, es, L)) return false;
    CMatRef AZ = ls.B.cref().rows_slice(0, m);
    double s = ls.B(m, 0);
    const size_t rs = static_cast<size_t>(r), qs = static_cast<size_t>(q);
    // V's rows L^-1 n_j (eV: q x r; forward_into's bits, the q solves side by side), and rhs_j
    Mat& V = es.eV;
    shape(V, q, r);
    Vec& col = es.ecol;  // the normals n_j (q x r, by rows)
    col.resize(qs * rs);
    Vec& w = es.wy;
    Vec& rhs = es.erhs;
    rhs.resize(qs);
    for (i64 j = 0; j < q; ++j) {
        double side = static_cast<double>(sides[j]);
        const double* cj = qp.C.row(rows[j]);
        for (i64 i = 0; i < r; ++i) col[j * r + i] = cj[i] * side;
        rhs[j] = rhs_of(CVecRef(qp.lo), CVecRef(qp.hi), rows[j], sides[j]);
    }
    forward_rows_into(L, col.data(), q, r, V.row(0));
    // S = V V^T (its lower triangle) and its Cholesky factor in place (eS, q x q by rows)
    Vec& S = es.eS;
    S.assign(qs * qs, 0.0);
    for (i64 j = 0; j < q; ++j) {
        // S(j, k) = V_j . V_k, each sum from +0 in index order (dot4's and dot2's lanes: four or
        // two k a pass, the same sums)
        const double* vj = V.row(j);
        double* sj = S.data() + j * q;
        i64 k = 0;
        for (; k + 4 <= j + 1; k += 4)
            dot4(V.row(k), V.row(k + 1), V.row(k + 2), V.row(k + 3), vj, r, sj[k], sj[k + 1], sj[k + 2], sj[k + 3]);
        for (; k + 2 <= j + 1; k += 2) dot2(V.row(k), V.row(k + 1), vj, r, sj[k], sj[k + 1]);
        for (; k <= j; ++k) {
            const double* vk = V.row(k);
            double acc = 0.0;
            for (i64 i = 0; i < r; ++i) acc += vj[i] * vk[i];
            sj[k] = acc;
        }
    }
    if (!schur_factor(S, q)) return false;
    // One step: (dz, du) solving H dz - N du = g, N^T dz = t (g: es.g, t: es.et)
    Vec& g = es.g;
    Vec& t = es.et;
    Vec& dz = es.edz;
    Vec& du = es.edu;
    du.resize(qs);
    auto step = [&]() {
        forward_into(L, g, w);  // w = L^-1 g
        // du_j = (t_j - V_j . w - sum_k<j S(j, k) du_k) / S(j, j), each term taken from t_j in
        // order: the first sums for every j first (two j a pass, one a lane), then the rest
        i64 j = 0;
        for (; j + 2 <= q; j += 2) {
            using namespace simd;
            const double *v0 = V.row(j), *v1 = V.row(j + 1);
            v2d acc = v2d{t[j], t[j + 1]};
            for (i64 i = 0; i < r; ++i) acc = acc - v2d{v0[i], v1[i]} * splat(w[i]);
            du[j] = acc[0];
            du[j + 1] = acc[1];
        }
        for (; j < q; ++j) du[j] = minus_dot(t[j], V.row(j), w.data(), r);
        schur_solve(S, q, du);
        for (i64 j = 0; j < q; ++j) axpy(w.data(), du[j], V.row(j), r);  // w + V du
        backward_into(L, w, dz);
    };
    // (z, u) from zero: g = B^T f, t = rhs
    mtv_into(AZ, ls.f.data(), g);
    for (i64 j = 0; j < r; ++j) g[j] += s * ls.f[m + j];
    t = rhs;
    step();
    z.assign(dz.begin(), dz.end());
    u.assign(du.begin(), du.end());
    // refined from B's residual: g = B^T (f - B z) + N u, t = rhs - N^T z
    residual_gradient(ls, AZ, m, s, z, es.e, g);
    for (i64 j = 0; j < q; ++j) {
        double side = static_cast<double>(sides[j]);
        const double* cj = qp.C.row(rows[j]);
        double nz = 0.0;
        for (i64 i = 0; i < r; ++i) {
            double e = cj[i] * side;
            g[i] += u[j] * e;
            nz += e * z[i];
        }
        t[j] = rhs[j] - nz;
    }
    step();
    for (i64 i = 0; i < r; ++i) z[i] = z[i] + dz[i];
    for (i64 j = 0; j < q; ++j) u[j] = u[j] + du[j];
    return true;
}

// eq_candidate's minimiser and multipliers in the row-space form of row_space_candidate, on a
// level of few rows (row_space_level, r >= kRegFoldMin) whose working set holds box rows only
// (n_j = side_j Z_i, rhs_j from lb - d or ub - d as reduced_rows and rhs_of make them): with
// M = A Z (m x r), s^2 = rho, N = M^T M + s^2 I is never formed or factored; its inverse is
// applied as (v - M^T K^-1 M v) / s^2, K = M M^T + s^2 I (m x m, its Cholesky factor). With
// P = N^-1 [n_1 .. n_q] and the Schur complement S = [n_j]^T P (q x q, its factor, eq_candidate's
// pivot test), each step solves N dz - [n_j] du = g, [n_j]^T dz = t as dz = N^-1 g + P du,
// du = S^-1 (t - [n_j]^T N^-1 g); first g = B^T f, t = rhs, then one step of refinement from
// B's own residual (eq_candidate's). The same minimiser as eq_candidate to round-off (the
// same conditions: normal_factor's trace bound), at a cost of a few m-row solves rather than
// N's r x r product and factor: a humanoid's CoM (m = 3, r = 26) or feet (12, 38). A function
// of B, f, Z, d, the bounds and the rows alone (set_candidate takes it on every path, cold or
// warm: the same bits). False (no candidate) where a condition fails, a factor does not exist
// or an entry is not finite.
inline bool row_space_set_candidate(const LSForm& ls, i64 m, CMatRef Z, const double* d, CVecRef lb, CVecRef ub,
                                    const IVec& rows, const IVec& sides, i64 q, CertScratch& es, Vec& z, Vec& u) {
    const i64 r = ls.B.cols, n = Z.rows;
    if (!ls.reg || m <= 0 || !row_space_level(m, r) || r < kRegFoldMin || q <= 0 || q > kEqCandidateRows ||
        q >= r || Z.cols != r || ls.B.rows != m + r || static_cast<i64>(ls.f.size()) != m + r)
        return false;
    for (i64 j = 0; j < q; ++j)
        if (rows[j] < 0 || rows[j] >= n) return false;  // (a general row: eq_candidate's)
    if (!row_space_factor(ls, m, es.rK, es.rL)) return false;
    CMatRef M = ls.B.cref().rows_slice(0, m);
    const double s = ls.B(m, 0);
    const double s2 = s * s;
    CMatRef L = es.rL.cref();
    // out = N^-1 v = (v - M^T K^-1 M v) / s^2 (out and v distinct)
    auto ninv = [&](const double* v, double* out) {
        Vec& e = es.re;
        e.resize(static_cast<size_t>(m));
        for (i64 i = 0; i < m; ++i) e[i] = dot(M.row(i), v, r);
        forward_into(L, e, es.ry);
        backward_into(L, es.ry, es.rw);
        for (i64 j = 0; j < r; ++j) out[j] = v[j];
        for (i64 i = 0; i < m; ++i) axpy(out, -es.rw[i], M.row(i), r);
        for (i64 j = 0; j < r; ++j) out[j] = out[j] / s2;
    };
    // the normals (rows of Nn) and right-hand sides
    Mat& Nn = es.rN;
    shape(Nn, q, r);  // every entry written
    Vec& rhs = es.rrhs;
    rhs.resize(static_cast<size_t>(q));
    for (i64 j = 0; j < q; ++j) {
        const i64 i = rows[j];
        const double side = static_cast<double>(sides[j]);
        const double* zi = Z.row(i);
        double* nj = Nn.row(j);
        for (i64 c = 0; c < r; ++c) nj[c] = zi[c] * side;
        rhs[j] = sides[j] > 0 ? box_lo(lb, d, i) : -box_hi(ub, d, i);
        if (!std::isfinite(rhs[j])) return false;
    }
    Mat& P = es.rP;
    shape(P, q, r);  // every entry written
    for (i64 j = 0; j < q; ++j) ninv(Nn.row(j), P.row(j));
    // S = [n_j]^T P (its lower triangle) and its Cholesky factor in place (q x q by rows)
    const size_t qs = static_cast<size_t>(q);
    Vec& S = es.rS;
    S.assign(qs * qs, 0.0);
    for (i64 j = 0; j < q; ++j)
        for (i64 k = 0; k <= j; ++k) S[j * q + k] = dot(Nn.row(j), P.row(k), r);
    if (!schur_factor(S, q)) return false;
    Vec& g = es.rg;
    Vec& t = es.rt;
    Vec& dz = es.rdz;
    Vec& du = es.rdu;
    dz.resize(static_cast<size_t>(r));
    du.resize(qs);
    auto step = [&]() {
        ninv(g.data(), dz.data());
        for (i64 j = 0; j < q; ++j) du[j] = t[j] - dot(Nn.row(j), dz.data(), r);
        schur_solve(S, q, du);
        for (i64 j = 0; j < q; ++j) axpy(dz.data(), du[j], P.row(j), r);
    };
    // (z, u) from zero: g = B^T f, t = rhs
    mtv_into(M, ls.f.data(), g);
    for (i64 j = 0; j < r; ++j) g[j] += s * ls.f[m + j];
    t.assign(rhs.begin(), rhs.end());
    step();
    z.assign(dz.begin(), dz.end());
    u.assign(du.begin(), du.end());
    // refined from B's residual: g = B^T (f - B z) + [n_j] u, t = rhs - [n_j]^T z
    residual_gradient(ls, M, m, s, z, es.rresid, g);
    for (i64 j = 0; j < q; ++j) {
        const double* nj = Nn.row(j);
        axpy(g.data(), u[j], nj, r);
        t[j] = rhs[j] - dot(nj, z.data(), r);
    }
    step();
    for (i64 i = 0; i < r; ++i) z[i] = z[i] + dz[i];
    for (i64 j = 0; j < q; ++j) u[j] = u[j] + du[j];
    return finite_block(z.data(), 1, r, r) && finite_block(u.data(), 1, q, q);
}

// The level's candidate on a working set, the same on every path (exact_level's, primal_guess's,
// row_space_guess's): row_space_set_candidate's where it makes one, else eq_candidate's.
inline bool set_candidate(const LSForm& ls, const ReducedQP& qp, double rho, i64 m, CMatRef Z, const double* d,
                          CVecRef lb, CVecRef ub, const IVec& rows, const IVec& sides, i64 q, const QPScratch* made,
                          CertScratch& es, Vec& z, Vec& u) {
    if (row_space_set_candidate(ls, m, Z, d, lb, ub, rows, sides, q, es, z, u)) return true;
    return eq_candidate(ls, qp, rho, m, rows, sides, q, made, es, z, u);
}

// A guessed set's candidate zc (its multipliers u >= 0, every row met) certified as exact_level
// certifies one (certify_level at x = d + Z zc into es.xx, with the set's rows and multipliers;
// C: the level's rows in null-space coordinates where made, else nullptr: the same bits);
// where it holds, its certificate and final set (the rows of positive multiplier).
// primal_guess's and row_space_guess's.
inline bool guess_certified(CMatRef Ak, CVecRef bk, double rho, CMatRef Z, const Vec& d, CVecRef lb, CVecRef ub,
                            CMatRef G, CVecRef h, const IVec& rows, const IVec& sides, const Vec& u, const Vec& zc,
                            const double* gsq, bool z_eye, const Mat* C, CertScratch& es, Certificate& cert,
                            IVec& final_rows, IVec& final_sides) {
    const i64 q = static_cast<i64>(rows.size());
    Vec& x = es.xx;
    zero_fill(x, static_cast<size_t>(Z.rows));
    add_step(Z, d, zc, z_eye, es.xZz, x);
    Certificate c = certify_level(Ak, bk, rho, Z, x, lb, ub, G, h, rows, sides, u, q, true, &es, gsq, z_eye, C,
                                  max_abs(zc, static_cast<i64>(zc.size())));
    if (!(c.holds() && c.rows_relative)) return false;
    cert = c;
    positive_rows(rows, sides, u, q, final_rows, final_sides);
    return true;
}

// primal_guess's bounds: the rows a guess starts from, and its tries.
constexpr i64 kGuessRows = 8;
constexpr i64 kGuessTries = 6;

// The start and the tries of a guessed working set (primal_guess's and row_space_guess's), in
// ws.pg_rows / ws.pg_sides. guess_start: the rows a point leaves (leaves(i): the side row i
// leaves, 0 where it holds), in row order; false where stop() after one, where there are none,
// or where there would be more than most_rows. guess_settle: each try makes the set's
// candidate and multipliers (candidate(q) into zc and u); the set loses every row of negative
// multiplier where there is one (in order; false where none is left or a multiplier is not
// finite), else gains every row violated at the candidate (at(zc), then leaves(i); made again
// in row order; false where stop() or more than grow_cap rows), else it has settled: true. At
// most kGuessTries tries (tries: the candidates made); false where a candidate is not made.
template <class Leaves, class Stop>
inline bool guess_start(Workspace& ws, i64 rows_all, i64 most_rows, const Leaves& leaves, const Stop& stop) {
    IVec& rows = ws.pg_rows;
    IVec& sides = ws.pg_sides;
    rows.clear();
    sides.clear();
    for (i64 i = 0; i < rows_all; ++i) {
        const i64 side = leaves(i);
        if (side == 0) continue;
        if (stop() || static_cast<i64>(rows.size()) == most_rows) return false;
        rows.push_back(i);
        sides.push_back(side);
    }
    return !rows.empty();
}

template <class Candidate, class At, class Leaves, class Stop>
inline bool guess_settle(Workspace& ws, i64 rows_all, i64 grow_cap, i64& tries, const Candidate& candidate,
                         const At& at, const Leaves& leaves, const Stop& stop) {
    IVec& rows = ws.pg_rows;
    IVec& sides = ws.pg_sides;
    const Vec& u = ws.pg_u;
    const Vec& zc = ws.pg_z;
    for (tries = 0; tries < kGuessTries;) {
        const i64 q = static_cast<i64>(rows.size());
        ++tries;
        if (!candidate(q)) return false;
        // every row of a negative multiplier leaves the set (in order)
        i64 kept = 0;
        for (i64 j = 0; j < q; ++j) {
            if (!std::isfinite(u[j])) return false;
            if (u[j] < 0.0) continue;
            rows[kept] = rows[j];
            sides[kept] = sides[j];
            ++kept;
        }
        if (kept < q) {
            if (kept == 0) return false;  // (no set left: the free answer, which was not taken)
            rows.resize(static_cast<size_t>(kept));
            sides.resize(static_cast<size_t>(kept));
            continue;
        }
        // else every row violated at the candidate joins it: the set made again in row order,
        // its rows and the violated ones
        at(zc);
        IVec& next = ws.pg_next;
        IVec& next_sides = ws.pg_next_sides;
        next.clear();
        next_sides.clear();
        for (i64 i = 0, j = 0; i < rows_all; ++i) {
            i64 side;
            if (j < q && rows[j] == i) {
                side = sides[j++];
            } else if ((side = leaves(i)) == 0) {
                continue;
            }
            next.push_back(i);
            next_sides.push_back(side);
        }
        if (stop()) return false;
        if (static_cast<i64>(next.size()) > q) {
            if (static_cast<i64>(next.size()) > grow_cap) return false;
            std::swap(rows, next);
            std::swap(sides, next_sides);
            continue;
        }
        return true;  // every multiplier >= 0 and every row met
    }
    return false;
}

// A cold level whose dual method would not stop at once (its unconstrained minimiser x0 = ws.qps.x,
// H's factor in ws.qps.L, violates a row), before the dual method: the working set guessed from x0,
// as a primal-dual active set, checked at each try by the final candidate of exact_level itself. It
// starts from the rows x0 violates (each on the side it leaves, leaving_side: the dual method's own
// test), where there are at most kGuessRows of them (a level far from its target, whose x0 leaves
// much of its box, or a weighted level of many rows, needs more tries than the dual method costs);
// at each try eq_candidate gives the minimiser with the set held as equalities and its multipliers;
// the set loses every row of negative multiplier where there is one, else gains every row violated
// at the candidate, else the candidate is certified as exact_level certifies its own (certify_level
// with the set's rows and multipliers). At most kGuessTries tries; false (nothing written but
// scratch) where the set leaves eq_candidate's reach, a try makes no candidate, or the tries end
// without a certified one: the dual method then solves the level as before. Where it holds, the
// answer is exact_level's on the same set (the same eq_candidate, certify_level and final set: its
// rows of positive multiplier), which is the dual method's final set wherever the optimal set is
// unique (rho > 0: the minimiser is unique; a row of zero multiplier at the optimum may be in one
// set and not the other, the same point to round-off), so the level's answer is the one the dual
// method and exact_level would give, a function of the level's problem alone. tries: the candidates
// made.
inline bool primal_guess(const LSForm& ls, const ReducedQP& qp, CMatRef Ak, CVecRef bk, double rho, CMatRef Z,
                         const Vec& d, CVecRef lb, CVecRef ub, CMatRef G, CVecRef h, double tol, const double* gsq,
                         bool z_eye, Workspace& ws, Certificate& cert, IVec& final_rows, IVec& final_sides,
                         i64& tries) {
    tries = 0;
    const i64 n = Z.rows, r = Z.cols, p = G.rows, rows_all = n + p;
    if (qp.C.rows != rows_all || qp.C.cols != r || r < kRegFoldMin) return false;
    const QPScratch& qs = ws.qps;
    if (qs.L.rows != r || static_cast<i64>(qs.x.size()) != r) return false;
    for (i64 i = 0; i < r; ++i)
        if (!std::isfinite(qs.x[i])) return false;
    CertScratch& es = ws.cs;
    IVec& rows = ws.pg_rows;
    IVec& sides = ws.pg_sides;
    Vec& u = ws.pg_u;
    Vec& zc = ws.pg_z;
    Vec& cz = ws.pg_cz;
    Vec& norm = ws.pg_norm;
    shape(cz, static_cast<size_t>(rows_all));
    // Each row's norm (0: no constraint, reduced_rows' infinite bounds) and C x at a point x
    // (cz), dot's sums (row_norms_into's and dot8's: eight rows a pass, the same sums).
    row_norms_into(qp.C.cref(), norm);
    auto products = [&](const double* x) {
        i64 i = 0;
        for (; i + 8 <= rows_all; i += 8) {
            const double* c8[8];
            for (int k = 0; k < 8; ++k) c8[k] = qp.C.row(i + k);
            dot8(c8, x, r, cz.data() + i);
        }
        for (; i < rows_all; ++i) cz[i] = dot(qp.C.row(i), x, r);
    };
    // The side row i leaves at the point whose products are cz (leaving_side; 0 for a row
    // that is no constraint: norm 0, or both bounds absent); `infinite` set where it leaves
    // by an infinite amount (the guess then ends: the dual method's to judge).
    bool infinite = false;
    auto leaves = [&](i64 i) -> i64 {
        const double lo = qp.lo[i], hi = qp.hi[i];
        if (!(norm[i] > 0.0) || (lo <= -kBig && hi >= kBig)) return 0;
        double by;
        const i64 side = leaving_side(lo, hi, cz[i], norm[i], tol, by);
        infinite |= std::isinf(by);
        return side;
    };
    // (more rows than kGuessRows, or past eq_candidate's reach, end the guess at once; the set
    // then grows as far as a candidate is made: empty, past kEqCandidateRows or q >= r, none)
    const i64 most_rows = std::min<i64>(std::min<i64>(kEqCandidateRows, kGuessRows), r - 1);
    auto stop = [&]() { return infinite; };
    products(qs.x.data());
    if (!guess_start(ws, rows_all, most_rows, leaves, stop)) return false;
    auto candidate = [&](i64 q) {
        return set_candidate(ls, qp, rho, Ak.rows, Z, d.data(), lb, ub, rows, sides, q, &qs, es, zc, u);
    };
    auto at = [&](const Vec& z) { products(z.data()); };
    if (!guess_settle(ws, rows_all, rows_all, tries, candidate, at, leaves, stop)) return false;
    // certified as exact_level certifies
    return guess_certified(Ak, bk, rho, Z, d, lb, ub, G, h, rows, sides, u, zc, gsq, z_eye, &qp.C, es, cert,
                           final_rows, final_sides);
}

// A cold level of few rows (row_space_level, r >= kRegFoldMin) whose row-space candidate z0
// (row_space_candidate's first solve, ws.rz) leaves a row of the box: primal_guess's working
// set, guessed from z0 in the row-space form (row_space_set_candidate), before H, its factor
// and the level's rows in null-space coordinates are made. It starts from the box rows z0
// leaves (each on the side it leaves, leaving_side's test), at most kGuessRows of them; each
// try makes the set's candidate and multipliers; the set loses every row of negative
// multiplier where there is one, else gains every box row violated at the candidate (in row
// order), else the candidate is certified as exact_level certifies it (certify_level with the
// set's rows and multipliers). At most kGuessTries tries; false (nothing written but scratch)
// where a general row is violated, the set leaves the candidate's reach, a try makes no
// candidate, or the tries end uncertified: the level then goes on as before (H, the dual
// stop, primal_guess, the dual method). Where it holds, the answer is exact_level's on the same
// set (set_candidate takes the row-space form there: the same candidate, certificate and final
// set, its rows of positive multiplier), so the level's answer is the one every other path
// gives it: a humanoid's CoM level with a gripper on its bound (Talos), or its feet level with
// the legs at their limits, in a few m-row solves. have_gz: ws.GZ and ws.Gd hold G Z and G d
// (rows_hold_at). tries: the candidates made.
inline bool row_space_guess(const LSForm& ls, CMatRef Ak, CVecRef bk, double rho, CMatRef Z, const Vec& d,
                            CVecRef lb, CVecRef ub, CMatRef G, CVecRef h, double tol, const double* gsq, bool z_eye,
                            bool have_gz, Workspace& ws, const Vec& z0, Certificate& cert, IVec& final_rows,
                            IVec& final_sides, i64& tries) {
    tries = 0;
    const i64 n = Z.rows, r = Z.cols, p = G.rows, m = Ak.rows, rows_all = n + p;
    if (!ls.reg || !row_space_level(m, r) || r < kRegFoldMin || static_cast<i64>(z0.size()) != r) return false;
    if (p > 0 && !(have_gz && ws.GZ.rows == p && ws.GZ.cols == r && static_cast<i64>(ws.Gd.size()) == p))
        return false;
    CertScratch& es = ws.cs;
    Vec& norm = ws.pg_norm;  // |Z_i| and |G_j Z| (0: no constraint, reduced_rows' test)
    shape(norm, static_cast<size_t>(rows_all));
    for (i64 i = 0; i < n; ++i) {
        const double nn = dot(Z.row(i), Z.row(i), r);
        norm[i] = nn <= 1e-20 ? 0.0 : std::sqrt(nn);
    }
    for (i64 j = 0; j < p; ++j) {
        const double nn = dot(ws.GZ.row(j), ws.GZ.row(j), r);
        const double size = gsq ? gsq[j] : row_sq_of(G, j);
        norm[n + j] = nn <= 1e-20 * size ? 0.0 : std::sqrt(nn);
    }
    // The side row i leaves at the point z (0: it holds, or no constraint); `general` set where
    // a general row leaves (the guess then ends: the general path's to judge), `infinite` where
    // one leaves by an infinite amount.
    bool general = false, infinite = false;
    const double* z = z0.data();
    auto leaves = [&](i64 i) -> i64 {
        if (!(norm[i] > 0.0)) return 0;
        double lo, hi, cx;
        if (i < n) {
            lo = box_lo(lb, d.data(), i);
            hi = box_hi(ub, d.data(), i);
            cx = dot(Z.row(i), z, r);
        } else {
            lo = -kInf;
            hi = h[i - n] - ws.Gd[i - n];
            cx = dot(ws.GZ.row(i - n), z, r);
        }
        if (lo <= -kBig && hi >= kBig) return 0;
        double by;
        const i64 side = leaving_side(lo, hi, cx, norm[i], tol, by);
        infinite |= std::isinf(by);
        if (side != 0 && i >= n) general = true;
        return side;
    };
    auto stop = [&]() { return general || infinite; };
    const i64 most_rows = std::min<i64>(std::min<i64>(kEqCandidateRows, kGuessRows), r - 1);
    if (!guess_start(ws, rows_all, most_rows, leaves, stop)) return false;
    IVec& rows = ws.pg_rows;
    IVec& sides = ws.pg_sides;
    auto candidate = [&](i64 q) {
        return row_space_set_candidate(ls, m, Z, d.data(), lb, ub, rows, sides, q, es, ws.pg_z, ws.pg_u);
    };
    auto at = [&](const Vec& zc) { z = zc.data(); };
    if (!guess_settle(ws, rows_all, most_rows, tries, candidate, at, leaves, stop)) return false;
    // certified as exact_level certifies
    return guess_certified(Ak, bk, rho, Z, d, lb, ub, G, h, rows, sides, ws.pg_u, ws.pg_z, gsq, z_eye, nullptr, es,
                           cert, final_rows, final_sides);
}

// exact_level after a dual method that stopped at once (dual_stops_at_once), and exact_level's
// own answer for an empty working set (q == 0, cold or warm): of the least-squares minimisers,
// the one nearest x = 0 (eqp_ls with no rows from zref = -Z^T d), certified; true when its
// certificate holds (else exact_level goes on from there: the caller then takes the general
// path). Its candidates, in this order on every path: zref where B zref = f already
// (residual_free: the QR's own bits), normal_candidate where qp is given and its conditions
// hold, then the QR re-solve; the first whose certificate holds is the answer, and where none
// does z and cert are the QR's.
// made: dual_stops_at_once's factor of qp.H (ws.qps), else nullptr (normal_candidate then
// factors N itself: the same bits).
inline bool free_answer(const LSForm& ls, CMatRef Ak, CVecRef bk, double rho, CMatRef Z, const Vec& d, CVecRef lb,
                        CVecRef ub, CMatRef G, CVecRef h, Vec& z, Certificate& cert, CertScratch& es,
                        const double* gsq = nullptr, const double* ztd = nullptr, bool z_eye = false,
                        const ReducedQP* qp = nullptr, const QPScratch* made = nullptr,
                        const Vec* row_space = nullptr) {
    // row_space: row_space_candidate's answer, made by the caller (the same bits).
    i64 n = static_cast<i64>(d.size()), r = Z.cols;
    IVec& rows = es.xrows;
    IVec& sides = es.xsides;
    rows.clear();
    sides.clear();
    Vec& zref = es.xzref;
    neg_ztd(Z, d, ztd, zref);
    Vec& u = es.xu;
    Vec& Zz = es.xZz;
    Vec& x = es.xx;
    auto certified = [&]() {
        x.resize(static_cast<size_t>(n));
        add_step(Z, d, z, z_eye, Zz, x);
        cert = certify_level(Ak, bk, rho, Z, x, lb, ub, G, h, rows, sides, u, 0, true, &es, gsq, z_eye, nullptr,
                             max_abs(z, static_cast<i64>(z.size())));
        return cert.holds() && cert.rows_relative;
    };
    i64 made_rows = 0;  // the rows of B zref residual_free made (es.f0)
    if (residual_free(ls, zref, es, made_rows)) {
        // The level is already met at zref (B zref = f): eqp_ls's least-squares step y is then
        // zero, its entries +-0 by the signs of the QR's pivots (every reflection of a zero
        // right-hand side leaves it zero; each back-substitution divides a zero by a finite
        // pivot; B is finite and far from overflow, so the QR's entries are finite). z = zref +
        // y differs from zref + (+0) at most in the sign of a zero entry, which no sum of Z z
        // (from +0, Z finite) sees: x, its certificate and the level's answer d + Z z are the
        // same bits without the QR. z itself is read past here only when the certificate fails
        // (exact_level's free_z): then eqp_ls makes it as before.
        z.resize(static_cast<size_t>(r));
        for (i64 i = 0; i < r; ++i) z[i] = zref[i] + 0.0;
        u.clear();
        if (certified()) return true;
    }
    // The second candidate: row_space_candidate's where it applies (few rows), else
    // normal_candidate's.
    bool second = false;
    if (qp) {
        if (row_space) {
            z = *row_space;
            second = true;
        } else {
            second = row_space_candidate(ls, Ak.rows, es, z) || normal_candidate(ls, *qp, rho, Ak.rows, made, es, z);
        }
    }
    if (second) {
        u.clear();
        if (certified()) return true;
    }
    // eqp_ls with no rows from zref, its steps for q = 0 (the same bits): z = zref + y, y the
    // least-norm step of min |B y - (f - B zref)| (lstsq of a copy of B); B zref is es.f0,
    // which residual_free began (its rows from made_rows on made here: the sums mv_into, as
    // eqp_ls, would make).
    es.qr.r = r;
    es.qr.q = 0;
    z = zref;
    u.clear();
    if (r > 0) {
        i64 mb = ls.B.rows;
        Mat& BW = es.BW;
        BW.rows = mb;
        BW.cols = r;
        BW.a.assign(ls.B.a.begin(), ls.B.a.begin() + mb * r);
        Vec& f0 = es.f0;
        b_zref_rows(ls, zref, f0, made_rows, mb);
        for (i64 i = 0; i < mb; ++i) f0[i] = ls.f[i] - f0[i];
        Vec& y = es.y;
        lstsq_into(BW, f0, y, es.ls, ls.reg);  // B itself: its sqrt(rho) I rows mostly zeros
        for (i64 i = 0; i < r; ++i) z[i] = z[i] + y[i];
    }
    return certified();
}

}  // namespace detail

namespace detail {

// True when every one of the n entries is finite (finite_block of one row).
inline bool all_finite(const double* p, i64 n) { return finite_block(p, 1, n, n); }

// y[c] = (a x[c]) / b, c < n (two lanes a pass; a = -1: -x[c] / b).
inline void scale_div(double* y, const double* x, double a, double b, i64 n) {
    using namespace simd;
    const v2d av = splat(a), bv = splat(b);
    i64 c = 0;
    for (; c + 2 <= n; c += 2) store(y + c, (av * load(x + c)) / bv);
    for (; c < n; ++c) y[c] = (a * x[c]) / b;
}

// y[c] += x[c], c < n.
inline void add_into(double* y, const double* x, i64 n) {
    using namespace simd;
    i64 c = 0;
    for (; c + 2 <= n; c += 2) store(y + c, load(y + c) + load(x + c));
    for (; c < n; ++c) y[c] += x[c];
}

// res = y - sum_a u[js[a]] col[js[a]] over a = 0..k-1: each entry's sum in that order from
// +0.0 (axpy's products and additions, two columns a pass), then subtracted from y.
inline void residual_of(const double* const* col, const double* u, const i64* js, i64 k, const double* y, i64 r,
                        Vec& res) {
    using namespace simd;
    zero_fill(res, static_cast<size_t>(r));
    double* o = res.data();
    i64 a = 0;
    for (; a + 2 <= k; a += 2) {
        const double *x = col[js[a]], *z = col[js[a + 1]];
        const double ua = u[js[a]], ub = u[js[a + 1]];
        const v2d av = splat(ua), bv = splat(ub);
        i64 i = 0;
        for (; i + 2 <= r; i += 2) store(o + i, (load(o + i) + av * load(x + i)) + bv * load(z + i));
        for (; i < r; ++i) o[i] = (o[i] + ua * x[i]) + ub * z[i];
    }
    if (a < k) axpy(o, u[js[a]], col[js[a]], r);
    i64 i = 0;
    for (; i + 2 <= r; i += 2) store(o + i, load(y + i) - load(o + i));
    for (; i < r; ++i) o[i] = y[i] - o[i];
}

// Lawson-Hanson non-negative least squares: u >= 0 minimising |M u - y| (M (r, t), given by
// its columns: col[j] points to column j's r entries); at most 3 t + 10 steps of each loop
// (round-off cannot make it cycle for ever).
// The least-squares problem on the passive columns is solved from a QR of them kept while
// columns are only added (Householder reflections, each new column reflected by the ones
// before: O(r np) a step rather than a new factorisation): the usual path of the method.
// Once a column leaves the passive set, or a new column is (nearly) dependent on the
// passive ones (|R_kk| <= 1e-8 max(|R_ii|, |column|): far above lstsq's own zero pivots, so
// that the kept QR only ever solves well-conditioned systems), every later step takes the
// pivoted, minimum-norm lstsq of the passive columns instead.
// The residual y - M u and the gradient M^T (y - M u) are the sums mv_into and mtv_into
// make (each entry summed in index order from +0.0): M u's entry i over the columns j in
// order, M^T x's entry j over the rows i in order (the terms of the rows with x_i = 0
// left out). finite (every entry of the t columns finite) lets them leave out terms that
// are +-0: a column j with u_j = +0 adds (finite) (+0) = +-0 to each entry of M u, and a
// row with x_i = 0 adds +-0 to each entry of M^T x, which leaves a sum from +0.0 as it is
// (such a sum is never -0: x + y is -0 in round to nearest only for x = y = -0); without
// it every term is taken as mv_into and mtv_into take them. Only the non-passive entries of
// the gradient are read (the column to add), so only those are summed.
inline void nnls_cols(const double* const* col, i64 r, i64 t, bool finite, const Vec& y, NnlsScratch& ws, Vec& u) {
    zero_fill(u, static_cast<size_t>(t));
    BVec& passive = ws.passive;
    passive.assign(static_cast<size_t>(t), 0);
    double ynorm = std::sqrt(dot(y.data(), y.data(), r));
    double wtol = 1e-14 * (1.0 + ynorm);
    i64 cap = 3 * t + 10;
    // The kept QR: reflector k in V's row k (entries k..r-1), vn[k] = |v_k|^2 (0: none);
    // Rc is R (row c: entries c..np-1); qy = Q^T y; P the columns in the order they were
    // added.
    bool inc = true;
    i64 np = 0;
    double rmax = 0.0;
    IVec& P = ws.P;
    P.clear();
    ws.V.zeros(std::min(r, t), r);
    ws.Rc.zeros(std::min(r, t), std::min(r, t));
    zero_fill(ws.vn, static_cast<size_t>(std::min(r, t)));
    ws.qy = y;
    // Adds column a to the kept QR; false (nothing kept changed but V's row np) when it is
    // (nearly) dependent on the passive columns or there is no room.
    auto add_column = [&](i64 a) {
        if (np >= r) return false;
        Vec& c = ws.col;
        c.resize(static_cast<size_t>(r));
        const double* ca = col[a];
        for (i64 i = 0; i < r; ++i) c[i] = ca[i];
        double cn = std::sqrt(dot(c.data(), c.data(), r));
        for (i64 k = 0; k < np; ++k) {
            double vnk = ws.vn[static_cast<size_t>(k)];
            if (vnk == 0.0) continue;
            const double* v = ws.V.row(k);
            // (dot and axmy: the same sum in order from 0.0 and the same updates)
            double sk = dot(v + k, c.data() + k, r - k);
            sk = 2.0 * sk / vnk;
            axmy(c.data() + k, sk, v + k, r - k);
        }
        // (dot: the sums of squares in order from 0.0)
        double alpha = std::sqrt(dot(c.data() + np, c.data() + np, r - np));
        double diag = c[np];
        double* v = ws.V.row(np);
        double vn = 0.0;
        if (alpha != 0.0) {
            if (c[np] > 0.0) alpha = -alpha;
            for (i64 i = 0; i < np; ++i) v[i] = 0.0;
            for (i64 i = np; i < r; ++i) v[i] = c[i];
            v[np] -= alpha;
            vn = dot(v + np, v + np, r - np);
            if (vn != 0.0) diag = alpha;
        }
        if (!(std::fabs(diag) > 1e-8 * pymax(rmax, cn)) || !std::isfinite(diag)) return false;
        ws.vn[static_cast<size_t>(np)] = vn;
        if (vn != 0.0) {
            double sq = dot(v + np, ws.qy.data() + np, r - np);
            sq = 2.0 * sq / vn;
            axmy(ws.qy.data() + np, sq, v + np, r - np);
        }
        for (i64 i = 0; i < np; ++i) ws.Rc(i, np) = c[i];  // R's column np
        ws.Rc(np, np) = diag;
        rmax = pymax(rmax, std::fabs(diag));
        P.push_back(a);
        np += 1;
        return true;
    };
    Vec& res = ws.res;
    Vec& w = ws.w;
    shape(w, static_cast<size_t>(t));  // only the non-passive entries written and read
    IVec& out = ws.out;
    IVec& act = ws.act;
    out.resize(static_cast<size_t>(t));  // the first no written, then read
    act.resize(static_cast<size_t>(t));  // the first na written, then read
    // act: the columns of the residual's sums, in order (finite: those with u_j != 0, all
    // passive: a non-passive column's u_j is +0; else every column); out: the non-passive
    // columns, in order. Both are kept from one step to the next where the step only added
    // a column whose solve was positive at once (every passive u_j > 0 then), else built
    // again.
    bool lists = false;
    i64 na = 0, no = 0;
    for (i64 outer = 0; outer < cap; ++outer) {
        if (!lists) {
            na = no = 0;
            for (i64 j = 0; j < t; ++j) {
                if (passive[j]) {
                    if (!finite || u[j] != 0.0) act[na++] = j;
                } else {
                    out[no++] = j;
                    if (!finite) act[na++] = j;
                }
            }
            lists = true;
        }
        // res = y - M u (mv_into's sums: see above)
        residual_of(col, u.data(), act.data(), na, y.data(), r, res);
        // w = M^T res (-gradient; mtv_into's sums) on the non-passive columns
        if (finite) {
            i64 a = 0;
            for (; a + 4 <= no; a += 4)
                dot4(col[out[a]], col[out[a + 1]], col[out[a + 2]], col[out[a + 3]], res.data(), r, w[out[a]],
                     w[out[a + 1]], w[out[a + 2]], w[out[a + 3]]);
            for (; a + 2 <= no; a += 2) dot2(col[out[a]], col[out[a + 1]], res.data(), r, w[out[a]], w[out[a + 1]]);
            for (; a < no; ++a) w[out[a]] = dot(col[out[a]], res.data(), r);
        } else {
            for (i64 a = 0; a < no; ++a) {
                const double* cj = col[out[a]];
                double acc = 0.0;
                for (i64 i = 0; i < r; ++i)
                    if (res[i] != 0.0) acc += res[i] * cj[i];
                w[out[a]] = acc;
            }
        }
        i64 add = -1, at = -1;
        double best = wtol;
        for (i64 a = 0; a < no; ++a) {
            i64 j = out[a];
            if (w[j] > best) {
                best = w[j];
                add = j;
                at = a;
            }
        }
        if (add < 0) break;
        passive[add] = 1;
        bool quick = false;  // the solve positive at once
        for (i64 inner = 0; inner < cap; ++inner) {
            Vec& s = ws.s;
            if (inc && inner == 0 && add_column(add)) {
                s.resize(static_cast<size_t>(np));
                for (i64 c = np - 1; c >= 0; --c) {  // R s = (Q^T y)[:np]
                    const double* rc = ws.Rc.row(c);
                    double acc = ws.qy[c];
                    i64 j = c + 1;
                    for (; j + 4 <= np; j += 4) {  // (in order, four a pass)
                        acc -= rc[j] * s[j];
                        acc -= rc[j + 1] * s[j + 1];
                        acc -= rc[j + 2] * s[j + 2];
                        acc -= rc[j + 3] * s[j + 3];
                    }
                    for (; j < np; ++j) acc -= rc[j] * s[j];
                    s[c] = acc / rc[c];
                }
            } else {
                inc = false;
                P.clear();
                for (i64 j = 0; j < t; ++j)
                    if (passive[j]) P.push_back(j);
                i64 nq = static_cast<i64>(P.size());
                Mat& MP = ws.MP;
                shape(MP, r, nq);  // every entry copied
                for (i64 k = 0; k < nq; ++k) {
                    const double* cp = col[P[k]];
                    for (i64 i = 0; i < r; ++i) MP(i, k) = cp[i];
                }
                ws.f = y;
                lstsq_into(MP, ws.f, s, ws.ls);
            }
            i64 np2 = static_cast<i64>(P.size());
            bool positive = true;
            for (i64 k = 0; k < np2; ++k)
                if (!(s[k] > 0.0)) positive = false;
            if (positive) {
                for (i64 k = 0; k < np2; ++k) u[P[k]] = s[k];
                quick = inner == 0;
                break;
            }
            inc = false;  // a column leaves: the kept QR no longer matches
            double alpha = 1.0;
            i64 hit = -1;
            for (i64 k = 0; k < np2; ++k) {
                double uk = u[P[k]];
                if (!(s[k] > 0.0)) {
                    double a = uk / (uk - s[k]);
                    if (hit < 0 || a < alpha) {
                        alpha = a;
                        hit = k;
                    }
                }
            }
            for (i64 k = 0; k < np2; ++k) {
                double& uk = u[P[k]];
                uk += alpha * (s[k] - uk);
                if (k == hit || !(uk > 0.0)) {
                    uk = 0.0;
                    passive[P[k]] = 0;
                }
            }
            if (inner == 0 && !passive[add]) return;  // round-off: the row just added left at once
        }
        if (quick) {  // add leaves out and joins act (finite; else act holds every column)
            for (i64 a = at; a + 1 < no; ++a) out[a] = out[a + 1];
            no -= 1;
            if (finite) {
                i64 a = na;
                for (; a > 0 && act[a - 1] > add; --a) act[a] = act[a - 1];
                act[a] = add;
                na += 1;
            }
        } else {
            lists = false;
        }
    }
}

// nnls_cols of M (r, t) given as a matrix.
inline void nnls_into(const Mat& M, const Vec& y, NnlsScratch& ws, Vec& u) {
    i64 r = M.rows, t = M.cols;
    Mat& MT = ws.MT;
    shape(MT, t, r);  // every entry written
    for (i64 i = 0; i < r; ++i)
        for (i64 j = 0; j < t; ++j) MT(j, i) = M(i, j);
    std::vector<const double*>& col = ws.cols;
    col.resize(static_cast<size_t>(t));
    for (i64 j = 0; j < t; ++j) col[j] = MT.row(j);
    nnls_cols(col.data(), r, t, all_finite(MT.a.data(), r * t), y, ws, u);
}

inline Vec nnls(const Mat& M, const Vec& y) {
    NnlsScratch ws;
    Vec u;
    nnls_into(M, y, ws, u);
    return u;
}

// A row is active at a candidate's point, for certified_by_refined_multipliers, where its
// slack is at most this times its scale (1 + |bound|; a general row's |G_j| + |h_j|).
constexpr double kRefinedActive = 1e-12;
// ... and a box row whose slack is at most this times 1 + |bound| (its point's rounding, a
// few eps) is met exactly there.
constexpr double kSnapBound = 8.0 * 2.220446049250313e-16;

// The last fallback of a level that no candidate certified (exact_level, then the point the
// level keeps): the feasible candidate exact_level certified best (es.xbest), with its
// multipliers found again and its stationarity summed in extended precision.
//
// At a degenerate vertex (more rows active than free directions, some of them nearly
// dependent in Z) every set of multipliers that makes the gradient vanish can be huge (2e6
// against a gradient of 1e-2): the gradient is a difference of nearly parallel normals.
// Rounded to double, such multipliers leave a residual of eps |u| |c| whatever their fit, which
// the certificate does not count as scale (a cancellation proves nothing), so an optimum
// fails on stationarity. Here:
// - the point is put exactly on each bound it meets to its own rounding (kSnapBound);
// - every row active at the point (kRefinedActive) takes part, each with its side;
// - u >= 0 minimising |sum_k u_k s_k Z^T c_k - Z^T grad| (nnls_cols, in double) chooses the
//   rows (its passive set; where that has more than r, the least kept out until r remain);
// - their multipliers are the least-squares solution again, in long double (x86-64's 64-bit
//   significand: eps 5.4e-20; Householder QR), the gradient Z^T grad and a general row's
//   normal summed in long double too;
// - the certificate in double at the point with those rows and (rounded) multipliers gives
//   primal, dual, complementarity and each component's scale; its stationarity is taken
//   again from the long double residual: per component, (|residual| + a bound on the long
//   double sums' own round-off) over the scale the double certificate uses, max(ssc, hsc,
//   kSizeFloor big), never the multipliers' terms.
// True, with cert, z and the final rows (those with u_k > 0), only where every measure holds;
// false, with nothing of them written, otherwise. Answers that another path certified never
// reach it (the same bits as without it). Where long double is double (MSVC, macOS on arm64)
// the bounds are double's and it proves no more than the double certificate.
inline bool certified_by_refined_multipliers(CMatRef Ak, CVecRef bk, double rho, CMatRef Z, const Vec& d,
                                             CVecRef lb, CVecRef ub, CMatRef G, CVecRef h, const ReducedQP& qp,
                                             bool z_eye, const double* gsq, CertScratch& es, NnlsScratch& ns,
                                             Vec& z, Certificate& cert, IVec& final_rows, IVec& final_sides) {
    using ld = long double;
    const i64 n = static_cast<i64>(d.size()), r = Z.cols, p = G.rows, m = Ak.rows;
    if (!es.has_best || static_cast<i64>(es.xbest.size()) != r || qp.C.rows != n + p || qp.C.cols != r || r == 0 ||
        Z.rows != n)
        return false;
    const Vec& zb = es.xbest;  // (certify_level below leaves it as it is)
    Vec& x = es.xx;
    x.resize(static_cast<size_t>(n));
    add_step(Z, d, zb, z_eye, es.xZz, x);
    if (!finite_block(x.data(), 1, n, n)) return false;
    // the rows active at x, each with its side (+1 lower, -1 upper)
    IVec& rows = es.xrows;
    IVec& sides = es.xsides;
    rows.clear();
    sides.clear();
    for (i64 i = 0; i < n; ++i) {
        // (a bound the point meets to its own rounding, kSnapBound, is met exactly: x = d + Z z
        // rounded leaves it 1e-17 off either side, which with multipliers of 1e6 the
        // complementarity measure would count; the move is round-off of x, far below what
        // any row above sees)
        // (finite bounds only: an unbounded side, +-inf or beyond kBig, is never met)
        const bool low = std::fabs(lb[i]) < kBig, high = std::fabs(ub[i]) < kBig;
        if (low && std::fabs(x[i] - lb[i]) <= kSnapBound * (1.0 + std::fabs(lb[i]))) x[i] = lb[i];
        else if (high && std::fabs(ub[i] - x[i]) <= kSnapBound * (1.0 + std::fabs(ub[i]))) x[i] = ub[i];
        if (low && x[i] - lb[i] <= kRefinedActive * (1.0 + std::fabs(lb[i]))) {
            rows.push_back(i);
            sides.push_back(1);
        }
        if (high && ub[i] - x[i] <= kRefinedActive * (1.0 + std::fabs(ub[i]))) {
            rows.push_back(i);
            sides.push_back(-1);
        }
    }
    for (i64 j = 0; j < p; ++j) {
        if (!(std::fabs(h[j]) < kBig)) continue;
        const double gn = gsq ? std::sqrt(gsq[j]) : std::sqrt(row_sq_of(G, j));
        if (h[j] - dot(G.row(j), x.data(), n) <= kRefinedActive * (gn + std::fabs(h[j]))) {
            rows.push_back(n + j);
            sides.push_back(-1);
        }
    }
    const i64 t = static_cast<i64>(rows.size());
    if (t == 0) return false;  // (no row: the point's own certificate was the one tried)
    // the gradient at x in null-space coordinates, y = Z^T (A^T (A x - b) + rho x), in long
    // double (yl), and in double (y, for the first fit)
    std::vector<ld>& yl = es.ny;
    yl.assign(static_cast<size_t>(r), 0.0L);
    {
        std::vector<ld>& v = es.nres;
        v.assign(static_cast<size_t>(n), 0.0L);
        for (i64 i = 0; i < m; ++i) {
            const double* ai = Ak.row(i);
            ld ri = -static_cast<ld>(bk[i]);
            for (i64 j = 0; j < n; ++j) ri += static_cast<ld>(ai[j]) * static_cast<ld>(x[j]);
            for (i64 j = 0; j < n; ++j) v[j] += static_cast<ld>(ai[j]) * ri;
        }
        for (i64 j = 0; j < n; ++j) v[j] += static_cast<ld>(rho) * static_cast<ld>(x[j]);
        for (i64 i = 0; i < n; ++i) {
            const double* zi = Z.row(i);
            for (i64 c = 0; c < r; ++c) yl[c] += static_cast<ld>(zi[c]) * v[i];
        }
    }
    Vec& y = es.y;
    y.resize(static_cast<size_t>(r));
    for (i64 c = 0; c < r; ++c) y[c] = static_cast<double>(yl[c]);
    // the signed normals s_k Z^T c_k: a box row's is Z's row (exact); a general row's summed
    // in long double (Ml), and rounded for the fits (M)
    std::vector<ld>& Ml = es.nMl;
    Ml.assign(static_cast<size_t>(t * r), 0.0L);
    Mat& M = es.nM;
    shape(M, t, r);
    std::vector<const double*>& cols = es.ncols;
    cols.resize(static_cast<size_t>(t));
    for (i64 k = 0; k < t; ++k) {
        const ld s = static_cast<ld>(sides[k]);
        ld* mk = Ml.data() + k * r;
        if (rows[k] < n) {
            const double* zi = Z.row(rows[k]);
            for (i64 c = 0; c < r; ++c) mk[c] = s * static_cast<ld>(zi[c]);
        } else {
            const double* g = G.row(rows[k] - n);
            for (i64 i = 0; i < n; ++i) {
                if (g[i] == 0.0) continue;
                const double* zi = Z.row(i);
                for (i64 c = 0; c < r; ++c) mk[c] += static_cast<ld>(g[i]) * static_cast<ld>(zi[c]);
            }
            for (i64 c = 0; c < r; ++c) mk[c] *= s;
        }
        double* md = M.row(k);
        for (i64 c = 0; c < r; ++c) md[c] = static_cast<double>(mk[c]);
        if (!finite_block(md, 1, r, r)) return false;
        cols[k] = md;
    }
    Vec& u = es.xu;
    nnls_cols(cols.data(), r, t, true, y, ns, u);
    // the passive rows' multipliers again, in long double: the least-squares solution of
    // Ml_P u_P = yl by Householder QR (no pivoting: NNLS kept the passive columns independent
    // to its tolerance); its residual is then round-off of long double, eps_ld |M| |u|, where
    // in double a nearly dependent set leaves eps |M| |u| (the test below needs the former)
    IVec& pas = es.npas;
    pas.clear();
    for (i64 k = 0; k < t; ++k)
        if (u[k] > 0.0) pas.push_back(k);
    // (more passive columns than free directions: dependent; the least kept out, in order of
    // their double multipliers, until there are r: the least-squares solution of the rest)
    while (static_cast<i64>(pas.size()) > r) {
        size_t least = 0;
        for (size_t j = 1; j < pas.size(); ++j)
            if (u[pas[j]] < u[pas[least]]) least = j;
        pas.erase(pas.begin() + static_cast<std::ptrdiff_t>(least));
    }
    const i64 kp = static_cast<i64>(pas.size());
    if (kp == 0) return false;
    std::vector<ld>& ul = es.nu;  // the multipliers in long double
    {
        std::vector<ld>& a = es.nMP;  // (r, kp) by rows: a[c * kp + j] = Ml[pas[j]][c]
        a.assign(static_cast<size_t>(r * kp), 0.0L);
        for (i64 c = 0; c < r; ++c)
            for (i64 j = 0; j < kp; ++j) a[c * kp + j] = Ml[pas[j] * r + c];
        std::vector<ld>& q = es.nq;  // the right-hand side, reflected with the columns
        q.assign(yl.begin(), yl.end());
        std::vector<ld>& vh = es.nv;
        vh.resize(static_cast<size_t>(r));
        for (i64 j = 0; j < kp; ++j) {
            ld norm2 = 0.0L;
            for (i64 i = j; i < r; ++i) norm2 += a[i * kp + j] * a[i * kp + j];
            const ld norm = std::sqrt(norm2);
            if (!(norm > 0.0L) || !std::isfinite(static_cast<double>(norm))) return false;
            const ld alpha = a[j * kp + j] > 0.0L ? -norm : norm;
            for (i64 i = j; i < r; ++i) vh[i] = a[i * kp + j];
            vh[j] -= alpha;
            ld vn2 = 0.0L;
            for (i64 i = j; i < r; ++i) vn2 += vh[i] * vh[i];
            if (vn2 > 0.0L) {
                for (i64 k = j + 1; k < kp; ++k) {
                    ld sk = 0.0L;
                    for (i64 i = j; i < r; ++i) sk += vh[i] * a[i * kp + k];
                    sk = 2.0L * sk / vn2;
                    for (i64 i = j; i < r; ++i) a[i * kp + k] -= sk * vh[i];
                }
                ld sq = 0.0L;
                for (i64 i = j; i < r; ++i) sq += vh[i] * q[i];
                sq = 2.0L * sq / vn2;
                for (i64 i = j; i < r; ++i) q[i] -= sq * vh[i];
            }
            a[j * kp + j] = alpha;
        }
        ul.assign(static_cast<size_t>(t), 0.0L);
        for (i64 j = kp - 1; j >= 0; --j) {
            ld acc = q[j];
            for (i64 k = j + 1; k < kp; ++k) acc -= a[j * kp + k] * ul[pas[k]];
            ul[pas[j]] = acc / a[j * kp + j];
        }
        for (i64 k = 0; k < t; ++k) u[k] = static_cast<double>(ul[k]);
        if (!finite_block(u.data(), 1, t, t)) return false;
    }
    // yl - Ml^T ul in long double, each component a compensated (Neumaier) sum: the
    // multipliers ul themselves (u, rounded to double, for certify_level's signs and
    // complementarity), whose rounding would leave eps |u| |M|; the sum's own error then
    // at most 2 eps_ld mu + O(t^2 eps_ld^2) mu (mu: the size of its terms), not t eps_ld mu
    std::vector<ld>& res = es.nres;
    res.resize(static_cast<size_t>(r));
    for (i64 c = 0; c < r; ++c) {
        ld sum = yl[c], carry = 0.0L;
        for (i64 k = 0; k < t; ++k) {
            if (ul[k] == 0.0L) continue;
            const ld term = -(ul[k] * Ml[k * r + c]);
            const ld next = sum + term;
            if (std::fabs(sum) >= std::fabs(term)) carry += (sum - next) + term;
            else carry += (term - next) + sum;
            sum = next;
        }
        res[c] = sum + carry;
    }
    for (i64 k = 0; k < t; ++k)
        if (u[k] < 0.0) return false;  // (a sign the row's side does not allow)
    // the certificate in double: primal, dual, complementarity and the scales
    Certificate c = certify_level(Ak, bk, rho, Z, x, lb, ub, G, h, rows, sides, u, t, true, &es, gsq, z_eye, &qp.C,
                                  max_abs(zb, r));
    if (!(c.primal <= kCertify && c.dual <= kCertify && c.complementarity <= kCertify && c.rows_relative))
        return false;
    if (!c.holds()) {
        // the stationarity from the long double residual, over certify_level's own scale
        // (its sizes ssc, hsc and vs, as it left them in es; big as it takes it)
        double S = 0.0, bmax = 0.0;
        for (i64 k = 0; k < r; ++k) S = pymax(S, es.ssc[k]);
        double big = S;
        for (i64 i = 0; i < n; ++i) big = pymax(big, es.vs[i]);
        for (i64 i = 0; i < m; ++i) bmax = pymax(bmax, std::fabs(bk[i]));
        if (rho > 0.0) big = pymax(big, std::sqrt(rho) * bmax);
        // the long double sums' own round-off, bounded by eps_ld times the size of their
        // terms: the residual's 2 + (t + 2)^2 eps_ld (products rounded once each, a
        // compensated sum; the multipliers' |u_k| |M_kc|, summed as mu), with a general
        // row's normal n more (a plain sum); the gradient's n + m + 2 (at most ssc_c)
        const ld eps = std::numeric_limits<ld>::epsilon();
        const ld tl = static_cast<ld>(t + 2);
        const ld mult_terms = (2.0L + tl * tl * eps + static_cast<ld>(p > 0 ? n : 0)) * eps;
        const ld grad_terms = static_cast<ld>(n + m + 2) * eps;
        double stat = 0.0;
        for (i64 k = 0; k < r; ++k) {
            ld mu = 0.0L;
            for (i64 j = 0; j < t; ++j) mu += std::fabs(ul[j] * Ml[j * r + k]);
            const double bound = static_cast<double>(std::fabs(res[k]) + mult_terms * mu +
                                                     grad_terms * static_cast<ld>(es.ssc[k]));
            const double ss = pymax(pymax(es.ssc[k], es.hsc[k]), kSizeFloor * big);
            if (!(ss > 0.0)) return false;
            stat = pymax(stat, bound / ss);
        }
        if (!(stat <= kCertify)) return false;
        c.stationarity = stat;
    }
    cert = c;
    z = zb;
    positive_rows(rows, sides, u, t, final_rows, final_sides);
    return true;
}

// certified_by_refined_multipliers at the point the level keeps, d itself (z = 0), where no
// feasible candidate of exact_level was left to try (none, or its own try failed): at a
// degenerate vertex (every free direction blocked by rows on their bounds, multipliers of 1e3
// or more) the dual method's candidates can all fail while d is the level's optimum (erd
// Romeo LAAS small, exact mode: 39 dofs on their bounds, d within 3e-14 of the independent
// reference's objective, yet the level was kept_previous). The same tests as for a candidate:
// true only where every measure holds at d (snapped to the bounds it meets to its rounding),
// with cert, z = 0 and the final rows written; the answer is then d as the level above left it
// (to that snap).
inline bool kept_point_by_refined_multipliers(CMatRef Ak, CVecRef bk, double rho, CMatRef Z, const Vec& d,
                                              CVecRef lb, CVecRef ub, CMatRef G, CVecRef h, const ReducedQP& qp,
                                              bool z_eye, const double* gsq, CertScratch& es, NnlsScratch& ns,
                                              Vec& z, Certificate& cert, IVec& final_rows, IVec& final_sides) {
    const i64 r = Z.cols;
    if (r == 0) return false;
    const bool had = es.has_best;
    Vec saved;
    std::swap(saved, es.xbest);
    es.xbest.assign(static_cast<size_t>(r), 0.0);
    es.has_best = true;
    const bool ok = certified_by_refined_multipliers(Ak, bk, rho, Z, d, lb, ub, G, h, qp, z_eye, gsq, es, ns, z,
                                                     cert, final_rows, final_sides);
    std::swap(saved, es.xbest);
    es.has_best = had;
    return ok;
}

}  // namespace detail

constexpr double kPinned = 1e-12;  // tight rows whose unit normals sum, with weights u >= 0, to
                                   // within this (1 + sum u) are positively dependent: pinned
// ... and (1 + sum u) at most this: weights beyond it cancel in normals that are themselves
// nearly positively dependent, so their round-off (1e-14 in the normal of a row of Z of norm
// 1e-3, say) could stand for any residual, whatever the move it leaves (a finger on its limit,
// the arm pinned at a vertex: residual 0.026 at sum u = 9e13, which pinned the finger, where
// it was free to move 0.002; erd Centauro: residual 9e-8 at sum u = 8e8 from normals 3e-9
// off orthogonal to a dof's unit direction, which pinned that free dof). Such a row is not
// pinned: its own test's residual is the move that leaves it free, or it stays a row.
constexpr double kPinnedWeight = 1e6;
// drop_pinned's test of every tight row at once (one NNLS): a residual within this, with
// weights summing to at most kPinnedAllWeight, pins them all.
constexpr double kPinnedAll = 1e-13;
constexpr double kPinnedAllWeight = 100.0;
// A row pinned with the row tested has a weight above this times their sum: a weight of the
// NNLS's round-off (1e-12 of the sum, where the others' dependence is exact) does not pin its
// row, which its own test then decides (Tiago: two rows on their bounds pinned with weights
// 4.7e-12 and 6.1e-12, free to move 0.02 rad; the posture below ended 0.2 % above its optimum).
constexpr double kPinnedWith = 1e-8;
// drop_pinned's independence test: the tight rows' unit normals pin nothing where their Gram
// matrix less this multiple of I has a Cholesky factor (least singular value above 1e-5).
constexpr double kPinFreeGram = 1e-10;

namespace detail {
// drop_pinned's shortcut once a row's test has pinned a set P (weights w > 0, w_j = 1 for the
// row tested: |N_P w| within the test's tolerance) whose normals span every null-space
// direction (|P| > r, the pivoted QR's r diagonal entries all above kSpanWell times the
// first): then -n_i lies in the cone of P for every other tight row i (any combination
// N_P c = -n_i, moved along w until non-negative: u = c + lam w), so each would be pinned by
// its own test. The combination is computed (c from the QR on P's r pivot columns) and its
// residual |n_i + N_P u| checked, far inside the test's own tolerance (kSpanMargin kPinned
// (1 + sum u), the sum at most kPinnedWeight); the rows so shown are pinned without their NNLS, the
// others (none in practice: a few 1e-15 against a tolerance of 1e-12 or more) keep it.
constexpr double kSpanWell = 1e-6;
constexpr double kSpanMargin = 1e-2;
__attribute__((noinline)) inline void span_pins(const std::vector<Vec>& normals, i64 r, i64 t, i64 j, const IVec& others, const Vec& u,
                      double total, IVec& state, NnlsScratch& ws) {
    IVec& P = ws.pset;
    Vec& w = ws.pw;
    P.clear();
    w.clear();
    P.push_back(j);
    w.push_back(1.0);
    for (size_t s = 0; s < others.size(); ++s)
        if (u[s] > kPinned * total) {
            P.push_back(others[s]);
            w.push_back(u[s]);
        }
    i64 np = static_cast<i64>(P.size());
    if (np <= r) return;
    Mat& N = ws.PN;
    shape(N, r, np);  // every entry written
    for (i64 k = 0; k < np; ++k)
        for (i64 c = 0; c < r; ++c) N(c, k) = normals[P[k]][c];
    ws.pqr.keep_reflectors = true;
    householder_qr(N.cref(), true, ws.PQ, ws.PR, ws.pperm, false, ws.pqr);
    const Mat& R = ws.PR;
    double top = std::fabs(R(0, 0));
    if (!(top > 0.0) || !std::isfinite(top)) return;
    for (i64 i = 0; i < r; ++i)
        if (!(std::fabs(R(i, i)) > kSpanWell * top) || !std::isfinite(R(i, i))) return;
    Vec& b = ws.pb;
    Vec& cv = ws.pc;
    Vec& uu = ws.pu;
    b.resize(static_cast<size_t>(r));
    cv.resize(static_cast<size_t>(r));
    uu.resize(static_cast<size_t>(np));
    for (i64 i = 0; i < t; ++i) {
        if (state[i] != 0) continue;
        const double* ni = normals[i].data();
        for (i64 c = 0; c < r; ++c) b[c] = -ni[c];
        for (i64 k = 0; k < r; ++k) {  // b = Q^T b (H_0 first)
            double vn = ws.pqr.vn[static_cast<size_t>(k)];
            if (vn == 0.0) continue;
            const double* x = ws.pqr.V.row(k);
            double sk = 0.0;
            for (i64 c = k; c < r; ++c) sk += x[c] * b[c];
            sk = 2.0 * sk / vn;
            for (i64 c = k; c < r; ++c) b[c] -= sk * x[c];
        }
        for (i64 k = r - 1; k >= 0; --k) {  // R[:r, :r] c = b
            double acc = b[k];
            for (i64 q = k + 1; q < r; ++q) acc -= R(k, q) * cv[q];
            cv[k] = acc / R(k, k);
        }
        for (i64 k = 0; k < np; ++k) uu[k] = 0.0;
        for (i64 k = 0; k < r; ++k) uu[ws.pperm[k]] = cv[k];
        double lam = 0.0;
        for (i64 k = 0; k < np; ++k)
            if (uu[k] < 0.0) lam = pymax(lam, -uu[k] / w[k]);
        double sum = 1.0;
        for (i64 k = 0; k < np; ++k) {
            uu[k] += lam * w[k];
            if (uu[k] < 0.0) uu[k] = 0.0;
            sum += uu[k];
        }
        double rr = 0.0;
        for (i64 c = 0; c < r; ++c) {
            double e = ni[c];
            for (i64 k = 0; k < np; ++k) e += uu[k] * normals[P[k]][c];
            rr += e * e;
        }
        double rn = std::sqrt(rr);
        if (std::isfinite(sum) && sum <= kPinnedWeight && rn <= kSpanMargin * kPinned * sum) state[i] = 1;
    }
}
}  // namespace detail

namespace detail {
// A tight box row whose row of Z (the dof's motion per unit of the null-space coordinates) has
// a squared norm of at most kRowRoundOff eps moves its dof by 1e-8 of any other's at most:
// drop_pinned leaves it out of the pinning test (it pins nothing, and nothing pins it). Its
// normalised normal, the direction of that tiny row, would otherwise join the test at full
// weight: erd Romeo's posture, exact mode, was left 3.2e-6 above its optimum by the pins such
// a row of 1.16e-8 made (tests/data/exactness/hqp_held_dof_roundoff_row.npz). The row itself
// stays in Z as it is, a constraint of the level's QP like any other: such a row can be the
// small but exact part of a null direction (erd UR10: a dof's 2.95e-8 that keeps A Z = 0
// where a wrist joint's Jacobian column is 5e-9), and making it 0 would leave the levels
// above a direction they move (tests/data/exactness/hqp_small_null_component.npz).
constexpr double kRowRoundOff = 4.0;
}  // namespace detail

namespace detail {
// The pivoted QR of the pinned normals N (rows: null-space coordinates, columns: normals), its
// reflectors kept in ws.qr (R first, form_q false: the same R and pivots; Q is formed from the
// reflectors only where some of its columns are used), and its rank: the leading diagonal
// entries of R above 1e-10 of the first.
inline i64 pinned_rank(const Mat& N, Workspace& ws) {
    bool kept = ws.qr.keep_reflectors;
    ws.qr.keep_reflectors = true;
    householder_qr(N.cref(), true, ws.Q, ws.R, ws.perm, false, ws.qr);
    ws.qr.keep_reflectors = kept;
    const Mat& R = ws.R;
    double top = std::fabs(R(0, 0));
    i64 rank = 0;
    for (i64 i = 0; i < std::min(N.rows, N.cols); ++i) {
        if (std::fabs(R(i, i)) > 1e-10 * top) rank = i + 1;
        else break;
    }
    return rank;
}

// A pinned box row's dof no longer moves: its row of Z, round-off now, is made 0 (the dof is
// held exactly; a task on it sees no round-off gradient in null-space coordinates).
inline void hold_pinned_rows(Mat& Z, const BVec& box_pinned) {
    for (i64 i = 0; i < Z.rows; ++i) {
        if (!box_pinned[i]) continue;
        double nn = 0.0;
        for (i64 c = 0; c < Z.cols; ++c) nn += Z(i, c) * Z(i, c);
        if (nn <= 1e-24)
            for (i64 c = 0; c < Z.cols; ++c) Z(i, c) = 0.0;
    }
}
}  // namespace detail

namespace detail {
// drop_pinned's elimination of the pinned directions: the pivoted QR of the pinned normals on
// the null-space coordinates they touch (`touched`), Q formed from its reflectors where some
// of its columns are used (apply_reflectors_right on the identity: the operations
// householder_qr's form_q makes on Q's rows), and Z's touched columns times Q's columns
// rank.. (their complement), then Z's untouched columns (`keep`) as they are. Returns whether
// Z changed.
inline bool eliminate_pinned(Mat& Z, const std::vector<Vec>& normals, const IVec& pinned, const IVec& touched,
                             const IVec& keep, const BVec& box_pinned, Workspace& ws) {
    const i64 n = Z.rows, e = static_cast<i64>(pinned.size());
    const i64 rs = static_cast<i64>(touched.size()), kc = static_cast<i64>(keep.size());
    Mat& N = ws.N;
    shape(N, rs, e);  // every entry written
    for (i64 s = 0; s < e; ++s)
        for (i64 a = 0; a < rs; ++a) N(a, s) = normals[pinned[s]][touched[a]];
    const i64 rank = pinned_rank(N, ws);
    if (rank == 0) return false;
    if (rank == rs && kc == 0) {  // every direction pinned: Z has no columns left
        shape(Z, n, 0);
        return true;
    }
    Mat& Q = ws.Q;
    Mat& Qc = ws.Qr;  // Q's columns rank..rs-1
    if (rank < rs) {
        Q.set_eye(rs);
        apply_reflectors_right(Q, ws.qr, std::min(rs, e));
        shape(Qc, rs, rs - rank);  // every entry copied
        for (i64 a = 0; a < rs; ++a)
            for (i64 j = rank; j < rs; ++j) Qc(a, j - rank) = Q(a, j);
    }
    if (kc == 0) {
        mm_into(Z.cref(), Qc.cref(), ws.Ztmp);  // (every coordinate touched: Z Qc itself)
    } else {
        // Z's touched columns times Qc (mm_into's sums), then the untouched columns
        Mat& Zs = ws.Mt;  // (project_level's scratch: made again by each projection)
        shape(Zs, n, rs);  // every entry copied
        for (i64 i = 0; i < n; ++i) {
            const double* zi = Z.row(i);
            double* out = Zs.row(i);
            for (i64 a = 0; a < rs; ++a) out[a] = zi[touched[a]];
        }
        Mat& P = ws.Qt;  // (the same)
        if (rank < rs) mm_into(Zs.cref(), Qc.cref(), P);
        Mat& Zt = ws.Ztmp;
        shape(Zt, n, rs - rank + kc);  // every entry written
        const size_t head = static_cast<size_t>(rs - rank);
        for (i64 i = 0; i < n; ++i) {
            const double* zi = Z.row(i);
            double* out = Zt.row(i);
            if (head) std::memcpy(out, P.row(i), head * sizeof(double));
            for (i64 q = 0; q < kc; ++q) out[rs - rank + q] = zi[keep[q]];
        }
    }
    std::swap(Z, ws.Ztmp);
    hold_pinned_rows(Z, box_pinned);
    return true;
}
}  // namespace detail

// The rows tight at d whose movement the levels above have pinned, and Z without their
// directions. At d (z = 0) the rows on their bound (box rows within kSnap (1 + |bound|) of
// lb or ub, general rows within kSnap (|g| + |h|) of h; both sides of a zero-width box row),
// with normals n_j in null-space coordinates (the feasible moves: n_j^T z >= 0), are
// pinned together when they are positively dependent (sum_j u_j n_j = 0, u_j > 0): every
// feasible move keeps each of them on its bound, n_j^T z = 0 (Gordan). Pinned rows are
// equalities of every level from here on: held as two opposing inequalities, the round-off
// in their normals makes a thin wedge of the feasible set, or closes it (tiny entries in
// the normals of other tight rows then fix a free direction too), and the level ends
// uncertified though it is feasible and solvable. They are eliminated exactly instead: Z
// becomes Z Q2, Q2 the orthonormal complement of their normals (pivoted Householder QR),
// so that they are met to round-off and the rows left in null-space coordinates constrain
// the free directions only. Each tight row is tested by the non-negative least squares
// min |n_j + sum_{i != j} u_i n_i| (u >= 0): a residual within kPinned (1 + sum u), the sum
// at most kPinnedWeight, pins j and the rows of weight above that; else the residual is a feasible move that leaves j
// (and every row it moves off its bound) free. Returns whether Z changed.
inline bool drop_pinned(Mat& Z, const Vec& d, CVecRef lb, CVecRef ub, CMatRef G, CVecRef h, Workspace& ws,
                        const double* gsq = nullptr) {
    i64 n = Z.rows, r = Z.cols, p = G.rows;
    if (r == 0) return false;
    std::vector<Vec>& normals = ws.normals;  // the first t in use (their storage kept)
    i64 t = 0;
    auto next_normal = [&]() -> Vec& {
        if (t == static_cast<i64>(normals.size())) normals.emplace_back();
        return normals[static_cast<size_t>(t++)];
    };
    IVec& owner = ws.owner;  // the dof of a box row's normal, -1 for a general row
    owner.clear();
    auto tight = [&](double di, double bound) {
        return std::fabs(bound) < kBig && std::fabs(di - bound) <= detail::kSnap * (1.0 + std::fabs(bound));
    };
    for (i64 i = 0; i < n; ++i) {
        bool at_lb = tight(d[i], lb[i]), at_ub = tight(d[i], ub[i]);
        if (!at_lb && !at_ub) continue;  // no normal (its row's norm unused)
        const double* zi = Z.row(i);
        double nn = dot(zi, zi, r);
        // (no constraint in null-space coordinates (reduced_qp), or too small to pin: kRowRoundOff)
        if (!(nn > detail::kRowRoundOff * 2.220446049250313e-16)) continue;
        double norm = std::sqrt(nn);
        for (double side : {1.0, -1.0}) {
            if (!(side > 0.0 ? at_lb : at_ub)) continue;
            Vec& v = next_normal();
            shape(v, static_cast<size_t>(r));  // every entry written
            detail::scale_div(v.data(), zi, side, norm, r);
            owner.push_back(i);
        }
    }
    if (p) {
        for (i64 j = 0; j < p; ++j) {
            if (!(h[j] < kBig)) continue;
            double gg = gsq ? gsq[j] : row_sq_of(G, j);
            double gd = dot(G.row(j), d.data(), n);  // (in order from 0.0)
            if (!(std::fabs(gd - h[j]) <= detail::kSnap * (std::sqrt(gg) + std::fabs(h[j])))) continue;
            Vec& v = next_normal();
            // v = G_j Z: v[c] = +0 plus G(j, s) Z(s, c) over the nonzero G(j, s) in s order (the
            // sums of axpy rows from zero, eight or two columns a pass in registers).
            shape(v, static_cast<size_t>(r));  // every entry written
            const double* gj = G.row(j);
            {
                using namespace simd;
                double* vp = v.data();
                i64 c = 0;
                for (; c + 8 <= r; c += 8) {
                    v2d a0 = splat(0.0), a1 = splat(0.0), a2 = splat(0.0), a3 = splat(0.0);
                    for (i64 s = 0; s < n; ++s) {
                        const double g = gj[s];
                        if (g == 0.0) continue;
                        const v2d gv = splat(g);
                        const double* zt = Z.row(s) + c;
                        a0 += gv * load(zt);
                        a1 += gv * load(zt + 2);
                        a2 += gv * load(zt + 4);
                        a3 += gv * load(zt + 6);
                    }
                    store(vp + c, a0);
                    store(vp + c + 2, a1);
                    store(vp + c + 4, a2);
                    store(vp + c + 6, a3);
                }
                for (; c + 2 <= r; c += 2) {
                    v2d a0 = splat(0.0);
                    for (i64 s = 0; s < n; ++s) {
                        const double g = gj[s];
                        if (g != 0.0) a0 += splat(g) * load(Z.row(s) + c);
                    }
                    store(vp + c, a0);
                }
                for (; c < r; ++c) {
                    double a0 = 0.0;
                    for (i64 s = 0; s < n; ++s) {
                        const double g = gj[s];
                        if (g != 0.0) a0 += g * Z(s, c);
                    }
                    vp[c] = a0;
                }
            }
            double nn = dot(v.data(), v.data(), r);
            if (!(nn > 1e-20 * gg)) {
                t -= 1;  // not kept: its storage is reused by the next one
                continue;
            }
            double norm = std::sqrt(nn);
            detail::scale_div(v.data(), v.data(), -1.0, norm, r);  // -x / norm
            owner.push_back(-1);
        }
    }
    if (t < 2) return false;
    {
        // Gordan's alternative, cheaply: with s the sum of the normals, n_i^T s >= c |s| for
        // every i (c > 0) bounds every residual the test below computes from below,
        // |n_j + sum u_i n_i| >= c (1 + sum u) (u >= 0), far above kPinned (1 + sum u) when
        // c > 1e-9: no row is pinned, the answer the test would give (Z unchanged).
        Vec& sum = ws.sum;
        zero_fill(sum, static_cast<size_t>(r));
        for (i64 j = 0; j < t; ++j) {
            const Vec& v = normals[static_cast<size_t>(j)];
            detail::add_into(sum.data(), v.data(), r);
        }
        double sn = std::sqrt(dot(sum.data(), sum.data(), r));
        bool free = sn > 0.0;
        for (i64 j = 0; j < t && free; ++j)
            if (!(dot(normals[j].data(), sum.data(), r) > 1e-9 * sn)) free = false;
        if (free) return false;
    }
    if (t <= r) {
        // Independent normals pin nothing: where the Gram matrix M = N^T N of the unit
        // normals less kPinFreeGram I has a Cholesky factor, M's least eigenvalue is above
        // kPinFreeGram less the round-off of forming and factoring it (about t r eps, far
        // below), so |N w| >= 1e-5 |w| >= 1e-5 (1 + sum u) / sqrt(t) for w = (1, u), u >= 0:
        // every residual the test below computes is far above kPinned (1 + sum u), and it
        // would mark every row free (Z unchanged): the same answer, without its NNLS (one a
        // row). A non-finite normal makes a NaN pivot: the test below decides.
        Mat& M = ws.pin_gram;
        shape(M, t, t);
        for (i64 i = 0; i < t; ++i)
            for (i64 j = 0; j <= i; ++j) M(i, j) = dot(normals[i].data(), normals[j].data(), r);
        Mat& L = ws.pin_factor;
        L.zeros(t, t);
        if (cholesky_into(M.cref(), t, kPinFreeGram, L.ref())) return false;
    }
    IVec& state = ws.state;  // 1 pinned, -1 free, 0 not known yet
    state.assign(static_cast<size_t>(t), 0);
    // The NNLS below read the normals in place (col: the columns of the matrix of each).
    std::vector<const double*>& col = ws.nnls.cols;
    col.resize(static_cast<size_t>(t));
    bool finite = true;
    for (i64 j = 0; j < t && finite; ++j) finite = detail::all_finite(normals[j].data(), r);
    // res = (sum_s u_s col[s]) - y, the sum mv_into makes of the matrix of columns col[0..k)
    // (each entry over s in order from +0.0; with finite columns, the terms of u_s = +0
    // left out: they add +-0, see nnls_cols).
    Vec& res = ws.res;
    auto combine = [&](i64 k, const Vec& u) {
        zero_fill(res, static_cast<size_t>(r));
        for (i64 s = 0; s < k; ++s)
            if (!finite || u[s] != 0.0) axpy(res.data(), u[s], col[s], r);
        for (i64 c = 0; c < r; ++c) res[c] = res[c] - ws.y[c];
    };
    if (2 * t >= 3 * r) {
        // Many more tight rows than null-space directions (t >= 1.5 r: one NNLS a row would
        // take several, each pinning at most r + 1 rows; with fewer, one or two usually do,
        // and this test would add one). Every row at once first, in one NNLS rather than one a row: u = 1 + v, v >= 0
        // minimising |N 1 + N v| (N the normals as columns). With |N u| within kPinnedAll and
        // sum u within kPinnedAllWeight, each row j has the weights u_i / u_j (u_j >= 1):
        // residual |N u| / u_j within kPinnedAll, far inside the row's own test below
        // (kPinned (1 + sum u), sum u >= 0), so that the test would pin every row: all are
        // pinned. Else, a residual far above any the test accepts (kPinned kPinnedWeight
        // (1 + sum u)) is a feasible move (NNLS's optimality: n_i^T N u >= 0 for every i, to
        // its tolerance), and the rows it moves off their bounds are free, as the test marks
        // them; the test then goes on with the others.
        for (i64 s = 0; s < t; ++s) col[s] = normals[s].data();
        Vec& y = ws.y;
        shape(y, static_cast<size_t>(r));  // every entry written
        for (i64 c = 0; c < r; ++c) y[c] = -ws.sum[c];
        Vec& u = ws.u;  // v
        detail::nnls_cols(col.data(), r, t, finite, y, ws.nnls, u);
        combine(t, u);  // N (1 + v) = N v - y
        double total = 0.0;
        for (i64 s = 0; s < t; ++s) total += 1.0 + u[s];
        double rn = std::sqrt(dot(res.data(), res.data(), r));
        if (rn <= kPinnedAll && total <= kPinnedAllWeight) {
            for (i64 j = 0; j < t; ++j) state[j] = 1;
        } else if (rn > kPinned * kPinnedWeight * (1.0 + total)) {
            for (i64 i = 0; i < t; ++i)
                if (dot(normals[i].data(), res.data(), r) > 1e-9 * rn) state[i] = -1;
        }
    }
    for (i64 j = 0; j < t; ++j) {
        if (state[j] != 0) continue;
        IVec& others = ws.others;
        others.clear();
        for (i64 i = 0; i < t; ++i)
            if (i != j && state[i] >= 0) others.push_back(i);
        i64 k = static_cast<i64>(others.size());
        for (i64 s = 0; s < k; ++s) col[s] = normals[others[s]].data();
        Vec& y = ws.y;
        shape(y, static_cast<size_t>(r));  // every entry written
        for (i64 c = 0; c < r; ++c) y[c] = -normals[j][c];
        Vec& u = ws.u;
        detail::nnls_cols(col.data(), r, k, finite, y, ws.nnls, u);
        combine(k, u);  // n_j + sum u_i n_i
        double total = 1.0;
        for (i64 s = 0; s < k; ++s) total += u[s];
        double rn = std::sqrt(dot(res.data(), res.data(), r));
        if (total <= kPinnedWeight && rn <= kPinned * total) {
            state[j] = 1;
            i64 np = 1;  // (the rows pinned with j: span_pins only where they can span)
            for (i64 s = 0; s < k; ++s)
                if (u[s] > kPinnedWith * total) {
                    state[others[s]] = 1;
                    np += 1;
                }
            bool left = false;
            for (i64 i = j + 1; i < t && !left && np > r; ++i) left = state[i] == 0;
            if (left) detail::span_pins(normals, r, t, j, others, u, total, state, ws.nnls);
        } else {
            state[j] = -1;  // res moves j off its bound, and every row it moves off its own
            for (i64 i = 0; i < t; ++i)
                if (state[i] == 0 && dot(normals[i].data(), res.data(), r) > 1e-9 * rn) state[i] = -1;
        }
    }
    IVec& pinned = ws.pinned;
    pinned.clear();
    BVec& box_pinned = ws.box_pinned;
    box_pinned.assign(static_cast<size_t>(n), 0);
    for (i64 j = 0; j < t; ++j) {
        if (state[j] != 1) continue;
        pinned.push_back(j);
        if (owner[j] >= 0) box_pinned[owner[j]] = 1;
    }
    i64 e = static_cast<i64>(pinned.size());
    if (e == 0) return false;
    // The null-space coordinates no pinned normal touches (every normal's entry there +-0: a
    // column of Z on dofs that no pinned row moves, as e_i of a dof that no task above moved)
    // are orthogonal to the pinned span exactly and stay in Z as they are: eliminate_pinned's
    // QR is of the touched coordinates alone. Reflected with the
    // others, such a coordinate could be a pivot row, and the complement's basis then mixes it
    // with the rest by the round-off of the pivots, amplified by the smallest (1.3e-8 of a
    // dof's unit direction spread on another's in erd Centauro's posture level after 30 pins
    // of pivots down to 1e-8: the certificate's multipliers, fit to that Z, then proved a
    // point 0.8 % above the posture's optimum with three free dofs left on their bounds).
    IVec& touched = ws.pin_touched;
    IVec& keep = ws.pin_keep;
    touched.clear();
    keep.clear();
    for (i64 c = 0; c < r; ++c) {
        bool any = false;
        for (i64 s = 0; s < e && !any; ++s) any = normals[pinned[s]][c] != 0.0;
        (any ? touched : keep).push_back(c);
    }
    if (touched.empty()) return false;
    return detail::eliminate_pinned(Z, normals, pinned, touched, keep, box_pinned, ws);
}

inline bool drop_pinned(Mat& Z, const Vec& d, CVecRef lb, CVecRef ub, CMatRef G, CVecRef h) {
    Workspace ws;
    return drop_pinned(Z, d, lb, ub, G, h, ws);
}

// One level made exact and certified from a QP answer's active set (the level-by-level
// path of qpik.core.hierarchy): (ok, z, certificate, final active set).
struct CertifiedLevel {
    bool ok = false;
    Vec z;
    Certificate cert;
    BVec active;
};

inline CertifiedLevel certified_level(CMatRef Ak, CVecRef bk, CMatRef AZ, CMatRef Z, const Vec& d, double rho,
                                      CVecRef lb, CVecRef ub, CMatRef G, CVecRef h, VecRefT<const i8> active,
                                      i64 status, i64 max_iter, bool lower) {
    i64 n = static_cast<i64>(d.size()), p = G.rows;
    ReducedQP qp = reduced_qp(Ak, bk, AZ, Z, d.data(), rho, lb, ub, G, h);
    QPResult sol;
    sol.status = status;
    sol.active.assign(active.begin(), active.end());
    LSForm ls = detail::ls_form(Ak, bk, AZ, Z, d.data(), rho);
    CertifiedLevel out;
    IVec rows, sides;
    out.ok = detail::exact_level(sol, ls, qp, Ak, bk, rho, Z, d, lb, ub, G, h, max_iter, lower, out.z, out.cert,
                                 rows, sides);
    if (!out.ok && std::isnan(out.cert.primal)) {  // the kept point's certificate (see solve_cascade)
        out.cert = certify_level(Ak, bk, rho, Z, d, lb, ub, G, h, {}, {}, {}, 0);
    }
    out.active.assign(static_cast<size_t>(n + p), 0);
    for (size_t j = 0; j < rows.size(); ++j) out.active[rows[j]] = static_cast<i8>(sides[j]);
    if (!out.ok) zero_fill(out.z, static_cast<size_t>(Z.cols));
    return out;
}

namespace detail {
// The levels below a failed one are not solved; each still gets the certificate of the
// returned point x (no working set, the levels above the failed one held: Z), so every
// figure of the result is a number that says which conditions fail there.
inline void certify_unreached(CascadeResult& res, CMatRef A, CVecRef b, VecRefT<const i64> starts, CVecRef reg,
                              CMatRef Z, const Vec& x, CVecRef lb, CVecRef ub, CMatRef G, CVecRef h, i64 from) {
    i64 L = starts.size() - 1;
    for (i64 j = from; j < L; ++j) {
        i64 s0 = starts[j], s1 = starts[j + 1];
        Certificate c = certify_level(A.rows_slice(s0, s1), b.slice(s0, s1), reg[j], Z, x, lb, ub, G, h, {}, {}, {},
                                      0, s1 > s0 && Z.cols > 0);
        double* cj = res.certificate.data() + 4 * j;
        cj[0] = c.primal;
        cj[1] = s1 > s0 && Z.cols > 0 ? c.stationarity : 0.0;
        cj[2] = cj[3] = 0.0;
    }
}
}  // namespace detail

// All levels of a hierarchy in one call; see solve_cascade in qpik/core/kernels.py for
// the arguments (A (M, n), b, w (M,), starts (L + 1,), reg (L,), lb, ub (n,), G (p, n),
// h (p,), warm (L, n + p) int8). Into res: every field of it written (its storage reused,
// so that a caller that keeps res, ws.result say, allocates no result vectors on a solve
// of the same sizes; nothing of a previous result is read), but for a caller that reads
// no residuals (residuals false) or no primal (primal false): where every level was
// reached, those are then left as they are (not computed; nothing else depends on them).
namespace detail {
// The check of the dual method's infeasibility claim at level 0: where H is nearly singular
// (a level that leaves dofs out, no regularisation), its floor can make the dual method stop
// on a row it could meet (rows with empty interior, such as an equality written as two
// inequalities, at a tight box). The nearest point to z = 0 that meets the rows is found by
// the same dual method on the identity Hessian (well conditioned, c = 0); where that finds a
// point the rows hold at (certified primal feasibility), the level is solved by exact_level
// from it (its candidates, then the primal active set from that feasible point) and true is
// returned with z, cert and the final active set written. Where it finds none, the claim
// stands (false; nothing written but scratch).
inline bool feasible_after_all(const ReducedQP& qp, const LSForm& ls, CMatRef Ak, CVecRef bk, double rho, CMatRef Z,
                               const Vec& d, CVecRef lb, CVecRef ub, CMatRef G, CVecRef h, i64 max_iter, double tol,
                               const double* gsq, const double* ztd, bool z_eye, Workspace& ws, Vec& z,
                               Certificate& cert, IVec& final_rows, IVec& final_sides) {
    const i64 r = qp.H.rows, m = qp.C.rows;
    ws.eye.set_eye(r);
    ws.zeros.assign(static_cast<size_t>(r), 0.0);
    ws.cold_rows.assign(static_cast<size_t>(m), 0);
    QPResult feas = solve_level(ws.eye.cref(), CVecRef(ws.zeros), qp.C.cref(), CVecRef(qp.lo), CVecRef(qp.hi),
                                VecRefT<const i8>(ws.cold_rows.data(), m), max_iter, tol, false, false, true, ws.qps,
                                false);
    if (feas.status != SOLVED || feas.x.size() != static_cast<size_t>(r)) return false;
    Vec& x = ws.cs.xx;
    x.resize(d.size());
    add_step(Z, d, feas.x, z_eye, ws.cs.xZz, x);
    if (!(certify_level(Ak, bk, rho, Z, x, lb, ub, G, h, {}, {}, {}, 0, false, &ws.cs, gsq, z_eye).primal <= kCertify))
        return false;
    return exact_level(feas, ls, qp, Ak, bk, rho, Z, d, lb, ub, G, h, max_iter, false, z, cert, final_rows,
                       final_sides, &ws.cs, nullptr, nullptr, gsq, ztd, z_eye, nullptr);
}
}  // namespace detail

namespace detail {
// The box of the levels below a level damped at sigma < threshold, with lower_trust = K > 0
// (DampingLaw.lower_trust): each dof i with both bounds finite kept within s (ub_i - lb_i) / 2
// of c_i, d_i (the answer so far) put in its box, s = K min(1, sigma / threshold), and within
// its box; a dof with an infinite bound keeps its box. The new box is inside the old and holds
// c, so every level below still has the levels above' answer as a feasible point (d itself
// where it is in the box, as the cascade keeps it, to round-off). (Near a singularity
// the null space of the damped level turns by O(1) between two configurations one step apart,
// and the levels below, moving their full step in it, make a closed loop cycle: a step they
// take there is held to where that null space is still the one they were solved in.)
inline void trust_box(const Vec& d, double s, CVecRef lb, CVecRef ub, Vec& tlb, Vec& tub) {
    const i64 n = lb.size();
    tlb.resize(static_cast<size_t>(n));
    tub.resize(static_cast<size_t>(n));
    for (i64 i = 0; i < n; ++i) {
        const double lo = lb[i], hi = ub[i], di = d[i];
        if (!(std::fabs(lo) < kBig && std::fabs(hi) < kBig)) {
            tlb[i] = lo;
            tub[i] = hi;
            continue;
        }
        const double half = s * (0.5 * (hi - lo));
        const double c = pymin(pymax(di, lo), hi);
        tlb[i] = pymax(lo, c - half);
        tub[i] = pymin(hi, c + half);
    }
}

// General rows of a norm outside [kRowNormLow, kRowNormHigh] (a user's rows written in other
// units) are divided by their norm, h with them (an absent h, kBig or more, kept): the same
// feasible set, and every measure of the certificate is relative to |g| already; the dual
// method's tolerances and the re-solves' systems are in the rows' units, and a row of norm
// 1e10 over two dofs (h = 1e7) left its level numerical_failure on every backend (norm 1e9
// was solved). Rows within the range, every row of the usual problems, are used as they
// are (the same bits). Returns whether G and h were copied into Gs and hs.
constexpr double kRowNormLow = 1e-6, kRowNormHigh = 1e6;
// sq: each row's |g_j|^2 (row_sq_of, as the cascade keeps them in ws.gsq), written; where
// rows were scaled, those of Gs.
inline bool equilibrated_rows(CMatRef G, CVecRef h, Mat& Gs, Vec& hs, Vec& sq) {
    const i64 p = G.rows, n = G.cols;
    shape(sq, static_cast<size_t>(p));
    // a finite nonzero row with a finite bound and a norm outside [kRowNormLow, kRowNormHigh]
    const auto scaled = [&](i64 j) {
        const double nn2 = sq[j];
        return std::isfinite(nn2) && nn2 > 0.0 &&
               (nn2 < kRowNormLow * kRowNormLow || nn2 > kRowNormHigh * kRowNormHigh) && h[j] < kBig;
    };
    bool any = false;
    for (i64 j = 0; j < p; ++j) {
        sq[j] = row_sq_of(G, j);
        any = any || scaled(j);
    }
    if (!any) return false;
    shape(Gs, p, n);  // every entry written
    hs.resize(static_cast<size_t>(p));
    for (i64 j = 0; j < p; ++j) {
        const bool scale = scaled(j);
        const double nn = std::sqrt(sq[j]);
        const double* gj = G.row(j);
        double* out = Gs.row(j);
        for (i64 i = 0; i < n; ++i) out[i] = scale ? gj[i] / nn : gj[i];
        hs[static_cast<size_t>(j)] = scale ? h[j] / nn : h[j];
    }
    for (i64 j = 0; j < p; ++j) sq[j] = row_sq_of(Gs.cref(), j);
    return true;
}

inline void solve_cascade_rows(CMatRef A_in, CVecRef b, CVecRef w, VecRefT<const i64> starts, CVecRef reg,
                               CVecRef lb, CVecRef ub, CMatRef G_in, CVecRef h_in, double threshold,
                               double max_damping, double error_scale, double rank_tol, i64 max_iter, double tol,
                               MatRefT<const i8> warm, bool canonical, Workspace& ws, CascadeResult& res,
                               bool residuals, bool primal, bool defer_sigma, double lower_trust = 0.0) {
    (void)canonical;  // every answer ends in the canonical exact re-solve (warm or cold)
    const bool equilibrated = equilibrated_rows(G_in, h_in, ws.G_eq, ws.h_eq, ws.gsq);
    const CMatRef G = equilibrated ? ws.G_eq.cref() : G_in;
    const CVecRef h = equilibrated ? CVecRef(ws.h_eq) : h_in;
    // Entries of a task row at or below kFlushEps n times its largest are its round-off (the
    // products that made it: 1e-18 in a row of 6e-4 where a dof moves nothing), zero here: a
    // level of small rank would otherwise keep them, amplified by 1 / sigma, in the direction
    // it eliminates from Z, which couples them with every row that direction touches (erd
    // Tiago dual: a free direction of three dofs lost to every level below). The same A
    // where no entry is that small (no copy).
    const CMatRef A = detail::flushed_rows(A_in, ws.A_flush);
    i64 n = lb.size();
    i64 p = G.rows;
    i64 L = starts.size() - 1;
    // v.assign(m, x) inline (no call; the storage kept unless it grows)
    auto fill = [](auto& v, size_t m, auto x) {
        if (v.size() != m) v.resize(m);
        std::fill(v.begin(), v.end(), x);  // (a memset for the int8 active sets)
    };
    fill(res.status, static_cast<size_t>(L), i64{NOT_REACHED});
    fill(res.sigma, static_cast<size_t>(L), kInf);
    fill(res.lam2, static_cast<size_t>(L), 0.0);
    fill(res.iterations, static_cast<size_t>(L), i64{0});
    fill(res.active, static_cast<size_t>(L * (n + p)), i8{0});
    fill(res.certificate, static_cast<size_t>(4 * L), kNaN);
    fill(res.deferred, static_cast<size_t>(defer_sigma ? L : 0), -1.0);
    // no damping where sigma is at or above this (level_damping): sigma is then deferred
    const double defer_floor = !defer_sigma ? -1.0 : max_damping > 0.0 ? threshold : 0.0;
    res.primal = 0.0;
    Vec& d = res.dq;
    zero_fill(d, static_cast<size_t>(n));
    for (i64 i = 0; i < n; ++i) {
        if (d[i] < lb[i]) d[i] = lb[i];
        if (d[i] > ub[i]) d[i] = ub[i];
    }
    // |G_j|^2 of every general row, summed once (the same sums drop_pinned, reduced_rows,
    // dual_stops_at_once and certify_level would each make): equilibrated_rows wrote them.
    const double* gsq = ws.gsq.data();
    Mat& Z = ws.Z;
    Z.set_eye(n);
    bool z_eye = true;  // Z is still exactly the identity (nothing pinned, no level projected)
    // After a solved level, its null space (project_level's Zn) is Z for the levels below.
    auto take_null_space = [&]() {
        std::swap(Z, ws.pr.Zn);
        z_eye = false;
    };
    i64 last = -1;  // the last level with rows: no level below it uses its null space
    for (i64 k = 0; k < L; ++k)
        if (starts[k + 1] > starts[k]) last = k;
    for (i64 k = 0; k < L; ++k) {
        i64 s0 = starts[k], s1 = starts[k + 1];
        // Below a damped level, with lower_trust: the box shrunk around d (trust_box).
        if (lower_trust > 0.0 && k > 0 && res.lam2[k - 1] > 0.0 && res.status[k - 1] == SOLVED &&
            res.sigma[k - 1] < threshold) {
            trust_box(d, lower_trust * pymin(1.0, res.sigma[k - 1] / threshold), lb, ub, ws.trust_lb, ws.trust_ub);
            lb = CVecRef(ws.trust_lb);
            ub = CVecRef(ws.trust_ub);
        }
        // The rows the levels above pinned on their bounds become equalities, eliminated
        // from Z (see drop_pinned): this level and the ones below move only where they can.
        if (s1 > s0 && drop_pinned(Z, d, lb, ub, G, h, ws, gsq)) z_eye = false;
        i64 r = Z.cols;
        if (s1 == s0 || r == 0) {
            // Nothing to choose (no rows, or no freedom left): optimal wherever the levels
            // above left x; the certificate is the rows' feasibility there.
            res.status[k] = SOLVED;
            double* ck = res.certificate.data() + 4 * k;
            ck[0] = certify_level(A.rows_slice(0, 0), b.slice(0, 0), 0.0, Z.cref(), d, lb, ub, G, h, {}, {}, {}, 0,
                                  false, &ws.cs, gsq).primal;
            ck[1] = ck[2] = ck[3] = 0.0;
            continue;
        }
        CMatRef Ak = A.rows_slice(s0, s1);
        CVecRef bk = b.slice(s0, s1);
        CVecRef wk = w.slice(s0, s1);
        Projection& pr = ws.pr;
        ws.deferred = false;
        project_level(Ak, wk, Z.cref(), rank_tol, k < last, ws, pr, z_eye, defer_floor);
        if (ws.deferred) detail::defer_record(res.deferred, k, ws.defer_kind, k < last, rank_tol, ws.defer_R);
        double lam = level_damping(Ak, bk, wk, d.data(), pr.sigma, threshold, max_damping, error_scale);
        res.sigma[k] = pr.sigma;
        res.lam2[k] = lam;
        double rho = reg[k] + lam;
        ReducedQP& qp = ws.qp;
        bool cold = true, h_later = false;
        for (i64 i = 0; i < n + p && cold; ++i) cold = warm(k, i) == 0;
        // A cold damped level of few rows (row_space_level: a humanoid's feet or CoM) first
        // tries its row-space answer (row_space_candidate, free_answer's second candidate): where
        // it meets every row to the dual method's tol and its certificate holds, the level is
        // solved without H (r x r) or its factor; else H is made and the level goes on below
        // as any other (the same path, the same bits as without the try).
        const bool row_space = cold && rho > 0.0 && detail::row_space_level(Ak.rows, r);
        // (cold, c = 0, or the row-space try: H made only where the general path below needs it)
        reduced_objective(Ak, bk, pr.AZ.cref(), Z.cref(), d.data(), rho, ws, qp, z_eye, cold ? &h_later : nullptr,
                          row_space);
        LSForm& ls = ws.ls;
        detail::ls_form(Ak, bk, pr.AZ.cref(), Z.cref(), d.data(), rho, ws, ls, true);
        const double* ztd = ws.c2.data();  // Z^T d (reduced_objective)
        Certificate cert;
        bool kept_optimal = false;  // no candidate certified, but the kept point d is an optimum
        Vec& z = ws.z;
        IVec& final_rows = ws.final_rows;
        IVec& final_sides = ws.final_sides;
        bool exact = false;
        bool factored = false, have_gz = false;
        // The level solved by free_answer's answer (its certificate cert): d + Z z, as
        // free_answer computed it for the certificate (ws.cs.xx: the same product and sums).
        auto take_free = [&]() {
            double* ck = res.certificate.data() + 4 * k;
            ck[0] = cert.primal;
            ck[1] = cert.stationarity;
            ck[2] = cert.dual;
            ck[3] = cert.complementarity;
            std::memcpy(d.data(), ws.cs.xx.data(), static_cast<size_t>(n) * sizeof(double));
            res.status[k] = SOLVED;
            take_null_space();
        };
        // The level solved by a guessed set (row_space_guess, primal_guess): its candidates made
        // as its iterations, its final set, then take_free's.
        auto take_guess = [&](i64 tries) {
            res.iterations[k] = tries;
            for (size_t j = 0; j < final_rows.size(); ++j)
                res.active[k * (n + p) + final_rows[j]] = static_cast<i8>(final_sides[j]);
            take_free();  // (its certificate, d + Z z from ws.cs.xx, solved, Z for below)
        };
        if (row_space) {
            Vec& rz = ws.rz;
            bool gz = false;
            // (the rows tested at the first solve; refined only where they hold: the same bits
            // as row_space_candidate's)
            const bool made_rz = detail::row_space_candidate(ls, Ak.rows, ws.cs, rz, false);
            const bool hold = made_rz && detail::rows_hold_at(Z.cref(), d.data(), lb, ub, G, h, tol, ws, gz, z_eye,
                                                              gsq, rz);
            if (hold &&
                (detail::row_space_refine(ls, Ak.rows, ws.cs, rz), detail::finite_block(rz.data(), 1, r, r)) &&
                detail::free_answer(ls, Ak, bk, rho, Z.cref(), d, lb, ub, G, h, z, cert, ws.cs, gsq, ztd, z_eye, &qp,
                                    nullptr, &rz)) {
                take_free();
                continue;
            }
            // Where rz leaves box rows: the working set guessed from them in the row-space form
            // (row_space_guess), before H is made; its answer is exact_level's on its set.
            i64 tries = 0;
            if (made_rz && !hold &&
                detail::row_space_guess(ls, Ak, bk, rho, Z.cref(), d, lb, ub, G, h, tol, gsq, z_eye, gz, ws, rz,
                                        cert, final_rows, final_sides, tries)) {
                take_guess(tries);
                continue;
            }
            if (h_later) make_h(pr.AZ.cref(), ws.h_reg, qp);
            h_later = false;
        }
        // A level no row binds: the answer of the general path below when the dual method
        // stops at once (no row formed, no dual method run; the same bits).
        // (c = 0 with every row met at z = 0: H's factor only where free_answer finds no answer)
        bool deferred = false;
        bool stops = cold && detail::dual_stops_at_once(qp, Z.cref(), d.data(), lb, ub, G, h, tol, ws, factored, have_gz,
                                                        z_eye, gsq, &deferred);
        if (stops && detail::free_answer(ls, Ak, bk, rho, Z.cref(), d, lb, ub, G, h, z, cert, ws.cs, gsq, ztd,
                                         z_eye, &qp, factored ? &ws.qps : nullptr)) {
            take_free();
            continue;
        }
        if (h_later) make_h(pr.AZ.cref(), ws.h_reg, qp);
        if (stops && deferred) stops = detail::stops_finished(qp, ws, factored);
        reduced_rows(Z.cref(), d.data(), lb, ub, G, h, ws, qp, have_gz, gsq, z_eye);
        // Level 0 with no feasible point, no optimum to certify: primal feasibility at the
        // point returned; the other measures do not apply and are 0.
        auto infeasible_certificate = [&]() {
            Certificate c = certify_level(Ak, bk, rho, Z.cref(), d, lb, ub, G, h, {}, {}, {}, 0, false, &ws.cs, gsq);
            c.stationarity = c.dual = c.complementarity = 0.0;
            return c;
        };
        // A cold damped level whose unconstrained minimiser leaves a row: the working set
        // guessed from it first (detail::primal_guess); where its candidate is certified, the
        // level's answer is exact_level's on that set, and the dual method does not run.
        i64 tries = 0;
        if (cold && !stops && factored && rho > 0.0 &&
            detail::primal_guess(ls, qp, Ak, bk, rho, Z.cref(), d, lb, ub, G, h, tol, gsq, z_eye, ws, cert,
                                 final_rows, final_sides, tries)) {
            take_guess(tries);
            continue;
        }
        QPResult sol = solve_level(qp.H.cref(), CVecRef(qp.c), qp.C.cref(), CVecRef(qp.lo), CVecRef(qp.hi),
                                   VecRefT<const i8>(warm.row(k), n + p), max_iter, tol, k > 0, false, true, ws.qps,
                                   factored);
        res.iterations[k] = sol.iterations;
        i64 st = sol.status;
        if (st == INFEASIBLE && k == 0 &&
            detail::feasible_after_all(qp, ls, Ak, bk, rho, Z.cref(), d, lb, ub, G, h, max_iter, tol, gsq, ztd, z_eye,
                                       ws, z, cert, final_rows, final_sides)) {
            // The dual method's claim did not hold: the level solved from a feasible point.
            st = SOLVED;
            exact = true;
        } else if (st == INFEASIBLE && k == 0) {
            cert = infeasible_certificate();
        } else {
            // The dual method stopped at once (stops: sol is x0 with no working set), so
            // exact_level's first candidate is free_answer's, held in ws.free_z and tried.
            Certificate tried = cert;
            if (stops) ws.free_z = z;
            exact = detail::exact_level(sol, ls, qp, Ak, bk, rho, Z.cref(), d, lb, ub, G, h, max_iter, k > 0, z, cert,
                                        final_rows, final_sides, &ws.cs, stops ? &ws.free_z : nullptr,
                                        stops ? &tried : nullptr, gsq, ztd, z_eye, &ws.qps);
            if (!exact && tol > 0.0 && (sol.status == SOLVED || sol.status == NUMERICAL)) {
                // The dual method stopped on rows its tolerance took as met, which the
                // certificate, relative to the answer's size (rows_relative), does not: at
                // nanometre scales (a start a few nm outside two support rows, a box bound at
                // 0) no candidate then holds, though the level is feasible. Once more with no
                // tolerance, every violated row entering the working set; only where the first
                // try certified nothing (every certified answer is as before, bit for bit).
                QPResult again = solve_level(qp.H.cref(), CVecRef(qp.c), qp.C.cref(), CVecRef(qp.lo),
                                             CVecRef(qp.hi), VecRefT<const i8>(warm.row(k), n + p), max_iter, 0.0,
                                             k > 0, false, true, ws.qps, false);
                if (again.status == SOLVED &&
                    detail::exact_level(again, ls, qp, Ak, bk, rho, Z.cref(), d, lb, ub, G, h, max_iter, k > 0, z,
                                        cert, final_rows, final_sides, &ws.cs, nullptr, nullptr, gsq, ztd, z_eye,
                                        &ws.qps)) {
                    exact = true;
                    res.iterations[k] += again.iterations;
                }
            }
            if (!exact) {
                // No candidate certified: the certificate of the point the level keeps (x = d,
                // no working set). Where it holds, d is itself an optimum (the level's gradient
                // vanishes there in Z, every row met: a level whose rows no free direction
                // moves, or that the levels above already met) and the level is solved there.
                // Else, where no candidate was certified at all, it says which conditions fail.
                Certificate at_d = certify_level(Ak, bk, rho, Z.cref(), d, lb, ub, G, h, {}, {}, {}, 0, true, &ws.cs,
                                                 gsq);
                if (at_d.holds() && at_d.rows_relative) {
                    kept_optimal = true;
                    cert = at_d;
                } else if (detail::certified_by_refined_multipliers(Ak, bk, rho, Z.cref(), d, lb, ub, G, h, qp, z_eye,
                                                                    gsq, ws.cs, ws.nnls, z, cert, final_rows,
                                                                    final_sides) ||
                           detail::kept_point_by_refined_multipliers(Ak, bk, rho, Z.cref(), d, lb, ub, G, h, qp,
                                                                     z_eye, gsq, ws.cs, ws.nnls, z, cert, final_rows,
                                                                     final_sides)) {
                    exact = true;  // (its x in ws.cs.xx, as exact_level leaves a certified one)
                } else if (std::isnan(cert.primal)) {
                    cert = at_d;
                }
            }
        }
        double* ck = res.certificate.data() + 4 * k;
        ck[0] = cert.primal;
        ck[1] = cert.stationarity;
        ck[2] = cert.dual;
        ck[3] = cert.complementarity;
        if (!exact && !kept_optimal)
            std::memcpy(res.active.data() + k * (n + p), sol.active.data(), static_cast<size_t>(n + p));
        if (kept_optimal) {
            // d stays; no working set (the row was zeroed when res.active was sized)
            res.status[k] = SOLVED;
        } else if (exact) {
            // Projected, not clipped: a lower level moves only in Z (A_j x of the levels
            // above stays put to round-off); its certificate covers the rows' feasibility.
            // d + Z z, as exact_level computed it for the certificate that held (ws.cs.xx: the
            // same product and sums).
            std::memcpy(d.data(), ws.cs.xx.data(), static_cast<size_t>(n) * sizeof(double));
            // the final active set alone (the row was zeroed when res.active was sized)
            for (size_t j = 0; j < final_rows.size(); ++j)
                res.active[k * (n + p) + final_rows[j]] = static_cast<i8>(final_sides[j]);
            res.status[k] = SOLVED;
        } else if (k > 0 && st != MAX_ITER) {
            res.status[k] = KEPT_PREVIOUS;  // the level above's answer is kept
            continue;
        } else {
            res.status[k] = st == INFEASIBLE || st == MAX_ITER ? st : NUMERICAL;
            if (k == 0 && res.status[0] == NUMERICAL && detail::row_unmet_in_box(G, h, lb, ub)) {
                // A general row that no displacement in the box meets (row_unmet_in_box: one
                // that no displacement moves, G_j = 0 or 1e-20, with h_j < 0, say), which the
                // dual method skips: level 0 is infeasible (the proof is the row and the box),
                // as where the dual method finds it so: its primal measure at d, the others 0
                // (a caller may then relax the rows, qpik.diffik.recovery).
                res.status[0] = INFEASIBLE;
                cert = infeasible_certificate();
                ck[0] = cert.primal;
                ck[1] = ck[2] = ck[3] = 0.0;
            }
            detail::snap_to_box(d, lb, ub);
            detail::level_residuals_into(A, b, starts, d, ws.lres, res.residuals);
            res.primal = certify_level(A.rows_slice(0, 0), b.slice(0, 0), 0.0, Z.cref(), d, lb, ub, G, h, {}, {},
                                       {}, 0, false).primal;
            detail::certify_unreached(res, A, b, starts, reg, Z.cref(), d, lb, ub, G, h, k + 1);
            return;
        }
        take_null_space();
    }
    detail::snap_to_box(d, lb, ub);
    if (residuals) detail::level_residuals_into(A, b, starts, d, ws.lres, res.residuals);
    // The general rows (and the box) rechecked at the final answer.
    if (primal)
        res.primal = certify_level(A.rows_slice(0, 0), b.slice(0, 0), 0.0, Z.cref(), d, lb, ub, G, h, {}, {}, {},
                                   0, false, &ws.cs, gsq).primal;
}

}  // namespace detail

// The general rows that no displacement in the box can bring to their bound: row j where
// its largest value over the box, reach_j = sum_i max(g_ji lb_i, g_ji ub_i) (every bound
// finite where g_ji != 0), is below h_j by more than kScreen (S_j + |h_j|) + kScreenAbs |g_j|_1
// (S_j = sum_i |g_ji| max(|lb_i|, |ub_i|): the sum's size; the second term covers a point
// off the box by the cascade's snap), and every row with h_j absent (>= kBig). Such a row is
// met with slack at every point the cascade keeps or tries in the box: it never binds, never
// enters a working set, and its primal measure is 0 there; the levels are solved as without
// it (a humanoid's support polygon far from the CoM: 26 dense rows, none in play). Returns
// how many rows are kept, their indices in `kept`.
inline constexpr double kScreen = 1e-6;
inline constexpr double kScreenAbs = 1e-9;

inline i64 rows_in_reach(CMatRef G, CVecRef h, CVecRef lb, CVecRef ub, IVec& kept, Vec& cols) {
    const i64 p = G.rows, n = G.cols;
    kept.clear();
    // Per column, once: its bounds where both are finite (else 0 and 0, and the column marked
    // open), and max(|lb_i|, |ub_i|).
    cols.resize(static_cast<size_t>(3 * n));
    double *lo = cols.data(), *hi = lo + n, *big = hi + n;
    for (i64 i = 0; i < n; ++i) {
        const bool closed = lb[i] > -kBig && ub[i] < kBig;
        lo[i] = closed ? lb[i] : 0.0;
        hi[i] = closed ? ub[i] : 0.0;
        big[i] = closed ? pymax(std::fabs(lb[i]), std::fabs(ub[i])) : -1.0;  // (-1: open)
    }
    for (i64 j = 0; j < p; ++j) {
        if (h[j] >= kBig) continue;  // absent (h NaN is kept below: the cascade's to judge)
        const double* gj = G.row(j);
        // The sums in index order, as term by term over the nonzero entries: an entry 0
        // adds +-0 (its column's bounds finite here), which leaves each sum as it was (none
        // is ever -0). A non-finite entry makes the test below fail (inf or NaN sums), as
        // it keeps its row; an open column under a nonzero entry keeps it too.
        double reach = 0.0, size = 0.0, g1 = 0.0;
        bool open = false;
        for (i64 i = 0; i < n; ++i) {
            const double g = gj[i], a = std::fabs(g);
            reach += g > 0.0 ? g * hi[i] : g * lo[i];
            size += a * pymax(big[i], 0.0);
            g1 += a;
            open |= (g != 0.0) & (big[i] < 0.0);
        }
        if (!open && std::isfinite(h[j]) && h[j] - reach > kScreen * (size + std::fabs(h[j])) + kScreenAbs * g1)
            continue;
        kept.push_back(j);
    }
    return static_cast<i64>(kept.size());
}

// The lexicographic cascade of the levels (A, b, w; starts: each level's first row) under
// the box lb <= x <= ub and the general rows G x <= h, into res (detail::solve_cascade_rows,
// the levels one by one). The general rows out of reach of the box (rows_in_reach) are left
// out of it, and res.active has a zero entry for each of them (L x (n + p) as ever); the
// final primal measure (primal) covers them too.
inline void solve_cascade_into(CMatRef A, CVecRef b, CVecRef w, VecRefT<const i64> starts, CVecRef reg,
                               CVecRef lb, CVecRef ub, CMatRef G, CVecRef h, double threshold, double max_damping,
                               double error_scale, double rank_tol, i64 max_iter, double tol, MatRefT<const i8> warm,
                               bool canonical, Workspace& ws, CascadeResult& res, bool residuals = true,
                               bool primal = true, bool defer_sigma = false, double lower_trust = 0.0) {
    const i64 p = G.rows, n = lb.size(), L = starts.size() - 1;
    const i64 q = p ? rows_in_reach(G, h, lb, ub, ws.g_kept, ws.reach_cols) : 0;
    if (q == p) {
        detail::solve_cascade_rows(A, b, w, starts, reg, lb, ub, G, h, threshold, max_damping, error_scale, rank_tol,
                                   max_iter, tol, warm, canonical, ws, res, residuals, primal, defer_sigma, lower_trust);
        return;
    }
    // The rows kept (and their warm entries), the others apart for the final primal measure.
    const IVec& kept = ws.g_kept;
    shape(ws.g_in, q, n);
    ws.h_in.resize(static_cast<size_t>(q));
    shape(ws.g_out, p - q, n);
    ws.h_out.resize(static_cast<size_t>(p - q));
    ws.warm_in.resize(static_cast<size_t>(L * (n + q)));
    for (i64 j = 0, k = 0, o = 0; j < p; ++j) {
        const bool in = k < q && kept[k] == j;
        double* dst = in ? ws.g_in.row(k) : ws.g_out.row(o);
        std::memcpy(dst, G.row(j), static_cast<size_t>(n) * sizeof(double));
        (in ? ws.h_in[k++] : ws.h_out[o++]) = h[j];
    }
    for (i64 l = 0; l < L; ++l) {
        i8* row = ws.warm_in.data() + l * (n + q);
        for (i64 i = 0; i < n; ++i) row[i] = warm(l, i);
        for (i64 k = 0; k < q; ++k) row[n + k] = warm(l, n + kept[k]);
    }
    detail::solve_cascade_rows(A, b, w, starts, reg, lb, ub, ws.g_in.cref(), CVecRef(ws.h_in), threshold, max_damping,
                               error_scale, rank_tol, max_iter, tol,
                               MatRefT<const i8>(ws.warm_in.data(), L, n + q), canonical, ws, res, residuals, primal,
                               defer_sigma, lower_trust);
    // res.active back to every row: L x (n + p), a left-out row's entries 0.
    std::vector<i8>& act = ws.active_in;
    act.assign(res.active.begin(), res.active.end());
    res.active.assign(static_cast<size_t>(L * (n + p)), i8{0});
    for (i64 l = 0; l < L; ++l) {
        const i8* src = act.data() + l * (n + q);
        i8* dst = res.active.data() + l * (n + p);
        std::memcpy(dst, src, static_cast<size_t>(n));
        for (i64 k = 0; k < q; ++k) dst[n + kept[k]] = src[n + k];
    }
    if (primal && p > q) {  // the rows left out, at the answer (0 where they hold, as proved)
        const Certificate out = certify_level(A.rows_slice(0, 0), b.slice(0, 0), 0.0, CMatRef(nullptr, n, 0),
                                              res.dq, lb, ub, ws.g_out.cref(), CVecRef(ws.h_out), {}, {}, {}, 0,
                                              false, &ws.cs);
        res.primal = pymax(res.primal, out.primal);
    }
}

// solve_cascade_into a result of its own.
inline CascadeResult solve_cascade(CMatRef A, CVecRef b, CVecRef w, VecRefT<const i64> starts,
                                   CVecRef reg, CVecRef lb, CVecRef ub, CMatRef G, CVecRef h,
                                   double threshold, double max_damping, double error_scale,
                                   double rank_tol, i64 max_iter, double tol,
                                   MatRefT<const i8> warm, bool canonical, Workspace& ws) {
    CascadeResult res;
    solve_cascade_into(A, b, w, starts, reg, lb, ub, G, h, threshold, max_damping, error_scale, rank_tol, max_iter,
                       tol, warm, canonical, ws, res);
    return res;
}

// solve_cascade with storage of its own (allocated for this one call).
inline CascadeResult solve_cascade(CMatRef A, CVecRef b, CVecRef w, VecRefT<const i64> starts,
                                   CVecRef reg, CVecRef lb, CVecRef ub, CMatRef G, CVecRef h,
                                   double threshold, double max_damping, double error_scale,
                                   double rank_tol, i64 max_iter, double tol,
                                   MatRefT<const i8> warm, bool canonical) {
    Workspace ws;
    return solve_cascade(A, b, w, starts, reg, lb, ub, G, h, threshold, max_damping, error_scale, rank_tol, max_iter,
                         tol, warm, canonical, ws);
}

}  // namespace qpik::core
