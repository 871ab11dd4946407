// The prioritised cascade (ported from qpik/core/_kernels.py: solve_cascade and the
// per-level helpers it calls). Owned by the core port; the signature of solve_cascade is
// the contract the diffik layer (diffik/fused.hpp) calls.
#pragma once

#include <stdexcept>

#include "../common.hpp"
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
};

namespace detail {

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

// Per level, |A_k x - b_k| over all its rows.
inline Vec level_residuals(CMatRef A, CVecRef b, VecRefT<const i64> starts, const Vec& x) {
    Vec r = mv(A, x.data());
    for (i64 i = 0; i < A.rows; ++i) r[i] = r[i] - b[i];
    i64 L = starts.size() - 1;
    Vec out(static_cast<size_t>(L));
    for (i64 k = 0; k < L; ++k) {
        double s = 0.0;
        for (i64 i = starts[k]; i < starts[k + 1]; ++i) s += r[i] * r[i];
        out[k] = std::sqrt(s);
    }
    return out;
}

}  // namespace detail

// Project a level (A, w) into the null space Z of the levels above (see project_level in
// qpik/core/_kernels.py).
inline Projection project_level(CMatRef A, CVecRef w, CMatRef Z, double rank_tol) {
    Projection out;
    out.AZ = mm(A, Z);
    i64 m = A.rows;
    i64 r = Z.cols;
    i64 keep = 0;
    for (i64 i = 0; i < m; ++i)
        if (w[i] > 0.0) keep += 1;
    if (keep == 0 || r == 0) {
        out.sigma = kInf;
        out.rank = 0;
        out.Zn = columns(Z, 0, Z.cols);
        return out;
    }
    if (detail::unit_rows(A, w)) {
        out.sigma = 1.0;
        out.rank = r;
        out.Zn = Mat(Z.rows, 0);
        return out;
    }
    Mat Mt(r, keep);  // (diag(1/w) A Z)^T
    i64 k = 0;
    for (i64 i = 0; i < m; ++i) {
        if (w[i] > 0.0) {
            for (i64 j = 0; j < r; ++j) Mt(j, k) = out.AZ(i, j) / w[i];
            k += 1;
        }
    }
    Mat Q, R;
    IVec perm;
    householder_qr(Mt.cref(), true, Q, R, perm);
    double top = std::fabs(R(0, 0));
    double cutoff = rank_tol * pymax(1.0, top);
    i64 rank = 0;
    for (i64 i = 0; i < std::min(r, keep); ++i)
        if (std::fabs(R(i, i)) > cutoff) rank += 1;
    double sigma = kInf;
    if (rank > 0) {
        sigma = min_singular(CMatRef(R.a.data(), rank, R.cols));
        if (sigma <= cutoff) sigma = std::fabs(R(rank - 1, rank - 1));
    }
    Mat Qr = columns(Q.cref(), rank, Q.cols);
    out.Zn = mm(Z, Qr.cref());
    out.sigma = sigma;
    out.rank = rank;
    return out;
}

// lambda^2 driven by sigma: max_damping^2 (1 - (sigma / threshold)^2) below the threshold.
inline double damping_of(double sigma, double threshold, double max_damping) {
    if (!(sigma < threshold)) return 0.0;
    double ratio = sigma / threshold;
    return max_damping * max_damping * (1.0 - ratio * ratio);
}

// The lambda^2 a level gets (see level_damping in qpik/core/_kernels.py).
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

// The level's QP in null-space coordinates dq = d + Z z (see reduced_qp).
inline ReducedQP reduced_qp(CMatRef A, CVecRef b, CMatRef AZ, CMatRef Z, const double* d, double reg,
                            CVecRef lb, CVecRef ub, CMatRef G, CVecRef h) {
    i64 n = Z.rows, r = Z.cols;
    i64 p = G.rows;
    ReducedQP out;
    out.H = mtm(AZ);
    double big = 0.0;
    for (i64 i = 0; i < r; ++i) big = pymax(big, out.H(i, i));
    reg = pymax(reg, 1e-14 * (1.0 + big));
    for (i64 i = 0; i < r; ++i) out.H(i, i) += reg;
    Vec e = mv(A, d);
    for (i64 i = 0; i < A.rows; ++i) e[i] = e[i] - b[i];
    Vec c1 = mtv(AZ, e.data());
    Vec c2 = mtv(Z, d);
    out.c.assign(static_cast<size_t>(r), 0.0);
    for (i64 i = 0; i < r; ++i) out.c[i] = c1[i] + reg * c2[i];
    out.C = Mat(n + p, r);
    out.lo.assign(static_cast<size_t>(n + p), 0.0);
    out.hi.assign(static_cast<size_t>(n + p), 0.0);
    for (i64 i = 0; i < n; ++i)
        for (i64 j = 0; j < r; ++j) out.C(i, j) = Z(i, j);
    for (i64 i = 0; i < n; ++i) {
        out.lo[i] = lb[i] > -kBig ? lb[i] - d[i] : -kInf;
        out.hi[i] = ub[i] < kBig ? ub[i] - d[i] : kInf;
    }
    if (p) {
        Mat GZ = mm(G, Z);
        for (i64 i = 0; i < p; ++i)
            for (i64 j = 0; j < r; ++j) out.C(n + i, j) = GZ(i, j);
        Vec Gd = mv(G, d);
        for (i64 j = 0; j < p; ++j) {
            out.lo[n + j] = -kInf;
            out.hi[n + j] = h[j] - Gd[j];
        }
    }
    for (i64 i = 0; i < n + p; ++i) {
        double size = 1.0;
        if (i >= n) {
            size = 0.0;
            for (i64 t = 0; t < n; ++t) size += G(i - n, t) * G(i - n, t);
        }
        double norm = 0.0;
        for (i64 t = 0; t < r; ++t) norm += out.C(i, t) * out.C(i, t);
        if (norm <= 1e-20 * size) {
            out.lo[i] = -kInf;
            out.hi[i] = kInf;
        }
    }
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
    lb.assign(static_cast<size_t>(n), 0.0);
    ub.assign(static_cast<size_t>(n), 0.0);
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

// All levels of a hierarchy in one call; see solve_cascade in qpik/core/_kernels.py for
// the arguments (A (M, n), b, w (M,), starts (L + 1,), reg (L,), lb, ub (n,), G (p, n),
// h (p,), warm (L, n + p) int8).
inline CascadeResult solve_cascade(CMatRef A, CVecRef b, CVecRef w, VecRefT<const i64> starts,
                                   CVecRef reg, CVecRef lb, CVecRef ub, CMatRef G, CVecRef h,
                                   double threshold, double max_damping, double error_scale,
                                   double rank_tol, i64 max_iter, double tol,
                                   MatRefT<const i8> warm, bool canonical) {
    i64 n = lb.size();
    i64 p = G.rows;
    i64 L = starts.size() - 1;
    CascadeResult res;
    res.status.assign(static_cast<size_t>(L), NOT_REACHED);
    res.sigma.assign(static_cast<size_t>(L), kInf);
    res.lam2.assign(static_cast<size_t>(L), 0.0);
    res.iterations.assign(static_cast<size_t>(L), 0);
    res.active.assign(static_cast<size_t>(L * (n + p)), 0);
    Vec d(static_cast<size_t>(n), 0.0);
    for (i64 i = 0; i < n; ++i) {
        if (d[i] < lb[i]) d[i] = lb[i];
        if (d[i] > ub[i]) d[i] = ub[i];
    }
    Mat Z = Mat::eye(n);
    for (i64 k = 0; k < L; ++k) {
        i64 s0 = starts[k], s1 = starts[k + 1];
        i64 r = Z.cols;
        if (s1 == s0 || r == 0) {
            res.status[k] = SOLVED;
            continue;
        }
        CMatRef Ak = A.rows_slice(s0, s1);
        CVecRef bk = b.slice(s0, s1);
        CVecRef wk = w.slice(s0, s1);
        Projection pr = project_level(Ak, wk, Z.cref(), rank_tol);
        double lam = level_damping(Ak, bk, wk, d.data(), pr.sigma, threshold, max_damping, error_scale);
        res.sigma[k] = pr.sigma;
        res.lam2[k] = lam;
        ReducedQP qp = reduced_qp(Ak, bk, pr.AZ.cref(), Z.cref(), d.data(), reg[k] + lam, lb, ub, G, h);
        QPResult sol = solve_level(qp.H.cref(), CVecRef(qp.c), qp.C.cref(), CVecRef(qp.lo), CVecRef(qp.hi),
                                   VecRefT<const i8>(warm.row(k), n + p), max_iter, tol, k > 0, canonical);
        res.iterations[k] = sol.iterations;
        for (i64 i = 0; i < n + p; ++i) res.active[k * (n + p) + i] = sol.active[i];
        i64 st = sol.status;
        if (st == SOLVED) {
            Vec Zz = mv(Z.cref(), sol.x.data());
            for (i64 i = 0; i < n; ++i) d[i] = d[i] + Zz[i];
            for (i64 i = 0; i < n; ++i) {
                if (d[i] < lb[i]) d[i] = lb[i];
                if (d[i] > ub[i]) d[i] = ub[i];
            }
            res.status[k] = SOLVED;
        } else {
            res.status[k] = (k == 0 || st == MAX_ITER) ? st : KEPT_PREVIOUS;
            if (st == MAX_ITER || st == NUMERICAL || k == 0) {
                res.residuals = detail::level_residuals(A, b, starts, d);
                res.dq = std::move(d);
                return res;
            }
            continue;
        }
        Z = std::move(pr.Zn);
    }
    res.residuals = detail::level_residuals(A, b, starts, d);
    res.dq = std::move(d);
    return res;
}

}  // namespace qpik::core
