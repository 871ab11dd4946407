// An exact fast path for a first level of pair couplings (a URDF mimic: rows
// c (dq_j - r dq_i) = b), taken by fused_step before the general cascade.
//
// The level: min 1/2 |A_0 x - b_0|^2 + 1/2 rho |x|^2 on the box, every row on two dofs of
// its own (i, j). It splits into one two-variable QP per pair (and, for a dof on no row,
// x = clip(0), its only term rho x^2): each solved in closed form on the first active set
// (free, an edge, a vertex) that meets the KKT conditions as computed, then certified as
// the cascade certifies a level (certify_level at that point, Z = I). The levels below
// keep A_0 x = A_0 d0 (d0 the level's answer): x = d_perp + T y with T the unit null
// direction p = (a_j, -a_i) / |a| of each pair in the driver's column (the other dofs'
// columns unit) and d_perp d0's part along the rows. T has orthonormal columns, so
// |x|^2 = |y|^2 + |d_perp|^2: the levels below are the same QPs in y (rows A T, b - A d_perp,
// the same regularisation, the pair's box intersected into an interval of y), solved by
// the general cascade on n - pairs variables, then mapped back. The same optimum as the
// general path, to round-off: the bits differ. Anything else (general rows, a dof fixed by
// its box, a row under the rank cutoff, no candidate meeting the KKT conditions as
// computed, a failed certificate, a level below that the reduced cascade does not solve)
// leaves it to the general path.
#pragma once

#include <vector>

#include "../common.hpp"
#include "../core/cascade.hpp"

namespace qpik::diffik {

// v.assign(n, x) written inline (no call; the storage kept unless it grows): size n, every
// entry x.
template <class V, class T>
inline void fill_as(V& v, size_t n, T x) {
    if (v.size() != n) v.resize(n);
    std::fill(v.begin(), v.end(), x);  // (a memset for int8)
}

// One coupling row on dofs i < j: a1 x_i + a2 x_j, and its pieces.
struct CouplePair {
    i64 row = 0, i = 0, j = 0;
    double a1 = 0.0, a2 = 0.0;
    double p1 = 0.0, p2 = 0.0;  // the unit null direction (p1 > 0)
    double di = 0.0, dj = 0.0;  // d_perp on x_i, x_j
    // which dof's bound (and side, +1 lower, -1 upper) gives y's lower and upper bound
    i64 lo_dof = -1, lo_side = 0, hi_dof = -1, hi_side = 0;
};

// The storage of couple_step (sizes only grow; every entry written before it is read).
struct CoupleScratch {
    std::vector<CouplePair> pairs;
    IVec pair_of;  // (n,) the pair of a dof, else -1
    IVec dof;      // (n',) the dof of each reduced column (the driver for a pair)
    Mat Ar, eye;
    Vec br, lbr, ubr, d0, u, x;
    IVec startsr, rows, sides;
    IVec runs;   // (c, t, len) triples: reduced columns c:c+len are dofs t:t+len (on no pair)
    IVec pcols;  // the reduced columns of the pairs, in order
    std::vector<const CouplePair*> pcol_pair;  // the pair of each of pcols
    BVec warmr;
    core::CertScratch cs;
    // the reduced cascade's result and the answer's residual rows (kept: no allocation a step)
    core::CascadeResult low;
    Vec xs, rr;
};

namespace couple_detail {

// The pair's QP min 1/2 (a1 x1 + a2 x2 - beta)^2 + 1/2 rho (x1^2 + x2^2) on lo <= x <= hi:
// the first candidate (free, then each edge: x_k on a bound, then each vertex) inside its
// box whose bound rows' multipliers have their sign, as computed; false when none does.
// side[k]: +1 on the lower bound, -1 on the upper, 0 free; g the objective's gradient.
inline bool pair_qp(double a1, double a2, double beta, double rho, const double* lo,
                    const double* hi, double* x, i64* side, double* g) {
    const double a[2] = {a1, a2};
    auto grad = [&]() {
        const double r = a1 * x[0] + a2 * x[1] - beta;
        g[0] = a1 * r + rho * x[0];
        g[1] = a2 * r + rho * x[1];
    };
    auto inside = [&](i64 k) { return x[k] >= lo[k] && x[k] <= hi[k]; };
    auto bound = [&](i64 k, i64 s) { return s > 0 ? lo[k] : hi[k]; };
    auto usable = [](double v) { return std::fabs(v) < core::kBig; };
    const double t = beta / (a1 * a1 + a2 * a2 + rho);
    x[0] = a1 * t;
    x[1] = a2 * t;
    if (inside(0) && inside(1)) {
        side[0] = side[1] = 0;
        grad();
        return true;
    }
    for (i64 k = 0; k < 2; ++k) {
        const i64 o = 1 - k;
        for (i64 s : {1, -1}) {
            const double v = bound(k, s);
            if (!usable(v)) continue;
            x[k] = v;
            x[o] = a[o] * (beta - a[k] * v) / (a[o] * a[o] + rho);
            if (!inside(o)) continue;
            grad();
            if (static_cast<double>(s) * g[k] < 0.0) continue;
            side[k] = s;
            side[o] = 0;
            return true;
        }
    }
    for (i64 s0 : {1, -1}) {
        for (i64 s1 : {1, -1}) {
            x[0] = bound(0, s0);
            x[1] = bound(1, s1);
            if (!usable(x[0]) || !usable(x[1])) continue;
            grad();
            if (static_cast<double>(s0) * g[0] < 0.0 || static_cast<double>(s1) * g[1] < 0.0) continue;
            side[0] = s0;
            side[1] = s1;
            return true;
        }
    }
    return false;
}

// The pairs of level 0 (rows 0:m0 of A): each row with a positive weight and exactly two
// nonzero entries, on dofs no other row has and whose boxes have width; false otherwise.
inline bool find_pairs(CMatRef A, CVecRef w, i64 m0, CVecRef lb, CVecRef ub, CoupleScratch& s) {
    const i64 n = A.cols;
    s.pairs.clear();
    fill_as(s.pair_of, static_cast<size_t>(n), i64{-1});
    for (i64 r = 0; r < m0; ++r) {
        if (!(w[r] > 0.0)) return false;
        const double* ar = A.row(r);
        i64 cols[2] = {-1, -1}, count = 0;
        for (i64 t = 0; t < n; ++t) {
            if (ar[t] == 0.0) continue;
            if (count == 2) return false;
            cols[count++] = t;
        }
        if (count != 2) return false;
        for (i64 c : cols)
            if (s.pair_of[c] >= 0 || !(lb[c] < ub[c])) return false;
        CouplePair p;
        p.row = r;
        p.i = cols[0];
        p.j = cols[1];
        p.a1 = ar[p.i];
        p.a2 = ar[p.j];
        s.pair_of[p.i] = s.pair_of[p.j] = static_cast<i64>(s.pairs.size());
        s.pairs.push_back(p);
    }
    return !s.pairs.empty();
}

// y's interval of a pair from its dofs' boxes, x = d_perp + p y (p1 > 0); false when the
// two intervals miss each other by more than round-off (then the general path).
inline bool pair_interval(CouplePair& p, CVecRef lb, CVecRef ub, double ystar, double& lo,
                          double& hi) {
    lo = (lb[p.i] - p.di) / p.p1;
    hi = (ub[p.i] - p.di) / p.p1;
    p.lo_dof = p.hi_dof = p.i;
    p.lo_side = 1;
    p.hi_side = -1;
    const bool up = p.p2 > 0.0;
    const double lo_j = ((up ? lb[p.j] : ub[p.j]) - p.dj) / p.p2;
    const double hi_j = ((up ? ub[p.j] : lb[p.j]) - p.dj) / p.p2;
    if (lo_j > lo) {
        lo = lo_j;
        p.lo_dof = p.j;
        p.lo_side = up ? 1 : -1;
    }
    if (hi_j < hi) {
        hi = hi_j;
        p.hi_dof = p.j;
        p.hi_side = up ? -1 : 1;
    }
    if (lo > hi) {  // a single point, crossed by round-off
        if (lo - hi > core::detail::kSnap * (1.0 + std::fabs(ystar))) return false;
        lo = hi = ystar;
    }
    return true;
}

}  // namespace couple_detail

// The cascade (solve_cascade's arguments) by the fast path when level 0 is pair couplings
// (see above): true with `out` as solve_cascade fills it; false (out untouched) where the
// general path must solve.
inline bool couple_step(CMatRef A, CVecRef b, CVecRef w, VecRefT<const i64> starts, CVecRef reg,
                        CVecRef lb, CVecRef ub, CMatRef G, CVecRef h, double threshold,
                        double max_damping, double error_scale, double rank_tol, i64 max_iter,
                        double tol, MatRefT<const i8> warm, bool canonical, core::Workspace& ws,
                        CoupleScratch& s, core::CascadeResult& out, bool defer = false,
                        double lower_trust = 0.0) {
    using namespace couple_detail;
    const i64 n = A.cols, L = starts.size() - 1, M = A.rows, p = G.rows;
    // (the cheap structural tests first: a stack without couplings leaves at once)
    if (L < 2 || n < 2) return false;
    const i64 cols = n + p;  // (the active sets' row length, as the general path's)
    const i64 m0 = starts[1];
    if (m0 == 0 || !find_pairs(A, w, m0, lb, ub, s)) return false;
    // General rows out of reach of the box never bind: solve_cascade_into leaves them out
    // (its answer bitwise the one without them), and so does this path (their active entries
    // 0); a row in reach: the general path.
    if (p != 0 && core::rows_in_reach(G, h, lb, ub, ws.g_kept, ws.reach_cols) != 0) return false;
    // sigma: the rows of diag(1/w) A_0 are orthogonal (disjoint dofs): their norms are its
    // singular values; each must be a rank direction.
    double sigma = kInf, top = 0.0;
    for (const CouplePair& p : s.pairs) {
        const double m1 = p.a1 / w[p.row], m2 = p.a2 / w[p.row];
        const double sv = std::sqrt(m1 * m1 + m2 * m2);
        top = core::pymax(top, sv);
        sigma = core::pymin(sigma, sv);
    }
    if (!(sigma > rank_tol * core::pymax(1.0, top))) return false;
    // The start: the clipped zero (the cascade's).
    Vec& d0 = s.d0;
    zero_fill(d0, static_cast<size_t>(n));
    for (i64 i = 0; i < n; ++i) {
        if (d0[i] < lb[i]) d0[i] = lb[i];
        if (d0[i] > ub[i]) d0[i] = ub[i];
    }
    const CMatRef A0 = A.rows_slice(0, m0);
    const CVecRef b0 = b.slice(0, m0);
    const double lam = core::level_damping(A0, b0, w.slice(0, m0), d0.data(), sigma, threshold,
                                           max_damping, error_scale);
    const double rho = reg[0] + lam;
    if (!(rho > 0.0) || !std::isfinite(rho)) return false;
    // Level 0: a dof on no row keeps the clipped zero (its bound row active where 0 is
    // outside its box, multiplier rho |x|); each pair by pair_qp.
    IVec& rows = s.rows;
    IVec& sides = s.sides;
    Vec& u = s.u;
    rows.clear();
    sides.clear();
    u.clear();
    auto hold = [&](i64 dof, i64 side, double g) {
        rows.push_back(dof);
        sides.push_back(side);
        u.push_back(static_cast<double>(side) * g);
    };
    for (i64 t = 0; t < n; ++t) {
        const i64 k = s.pair_of[t];
        if (k < 0) {
            if (d0[t] != 0.0) hold(t, d0[t] > 0.0 ? 1 : -1, rho * d0[t]);
            continue;
        }
        CouplePair& p = s.pairs[k];
        if (t != p.i) continue;
        const double lo[2] = {lb[p.i], lb[p.j]}, hi[2] = {ub[p.i], ub[p.j]};
        double x[2], g[2];
        i64 side[2];
        if (!pair_qp(p.a1, p.a2, b[p.row], rho, lo, hi, x, side, g)) return false;
        d0[p.i] = x[0];
        d0[p.j] = x[1];
        const i64 dofs[2] = {p.i, p.j};
        for (i64 c = 0; c < 2; ++c)
            if (side[c] != 0) hold(dofs[c], side[c], g[c]);
    }
    // Z = I (n, n), kept from one step to the next (only couple_step writes it); certified
    // with z_eye (its products written without forming them: the same bits).
    if (s.eye.rows != n || s.eye.cols != n) s.eye.set_eye(n);
    const core::Certificate cert =
        core::certify_level(A0, b0, rho, s.eye.cref(), d0, lb, ub, G, h, rows, sides, u,
                            static_cast<i64>(rows.size()), true, &s.cs, nullptr, true);
    if (!(cert.holds() && cert.rows_relative)) return false;
    // The levels below in y: x = d_perp + T y.
    const i64 nr = n - static_cast<i64>(s.pairs.size());
    IVec& dof = s.dof;
    dof.resize(static_cast<size_t>(nr));  // nr entries: the dofs on no pair and each pair's i
    {
        size_t c = 0;
        for (i64 t = 0; t < n; ++t) {
            const i64 k = s.pair_of[t];
            if (k < 0 || s.pairs[k].i == t) dof[c++] = t;
        }
    }
    s.lbr.resize(static_cast<size_t>(nr));  // every entry written below
    s.ubr.resize(static_cast<size_t>(nr));
    for (i64 c = 0; c < nr; ++c) {
        const i64 t = dof[c];
        const i64 k = s.pair_of[t];
        if (k < 0) {
            s.lbr[c] = lb[t];
            s.ubr[c] = ub[t];
            continue;
        }
        CouplePair& p = s.pairs[k];
        const double norm = std::sqrt(p.a1 * p.a1 + p.a2 * p.a2);
        const double sign = p.a2 > 0.0 ? 1.0 : -1.0;
        p.p1 = sign * p.a2 / norm;
        p.p2 = -sign * p.a1 / norm;
        const double ya = (p.a1 * d0[p.i] + p.a2 * d0[p.j]) / norm;  // along the row
        p.di = ya * (p.a1 / norm);
        p.dj = ya * (p.a2 / norm);
        const double ystar = p.p1 * d0[p.i] + p.p2 * d0[p.j];
        if (!(p.p1 > 0.0) || p.p2 == 0.0) return false;
        if (!pair_interval(p, lb, ub, ystar, s.lbr[c], s.ubr[c])) return false;
    }
    // The reduced columns: runs of dofs on no pair (copied), then each pair's column (in
    // order of c, so shift sums its terms in the order of the columns).
    IVec& runs = s.runs;
    IVec& pcols = s.pcols;
    runs.clear();
    pcols.clear();
    for (i64 c = 0; c < nr; ++c) {
        const i64 t = dof[c];
        if (s.pair_of[t] >= 0) {
            pcols.push_back(c);
        } else if (!runs.empty() && runs[runs.size() - 3] + runs[runs.size() - 1] == c &&
                   runs[runs.size() - 2] + runs[runs.size() - 1] == t) {
            ++runs[runs.size() - 1];
        } else {
            runs.push_back(c);
            runs.push_back(t);
            runs.push_back(1);
        }
    }
    const i64 Mr = M - m0;
    core::shape(s.Ar, Mr, nr);  // every entry written below
    s.br.resize(static_cast<size_t>(Mr));
    // Each pair column's pair (in order of pcols), looked up once.
    std::vector<const CouplePair*>& pp = s.pcol_pair;
    pp.resize(pcols.size());
    for (size_t q = 0; q < pcols.size(); ++q) pp[q] = &s.pairs[s.pair_of[dof[pcols[q]]]];
    for (i64 r = 0; r < Mr; ++r) {
        const double* ar = A.row(m0 + r);
        double* dst = s.Ar.row(r);
        for (size_t q = 0; q < runs.size(); q += 3) {
            double* d = dst + runs[q];
            const double* src = ar + runs[q + 1];
            const i64 len = runs[q + 2];
            i64 e = 0;
            for (; e + 2 <= len; e += 2) core::simd::store(d + e, core::simd::load(src + e));
            if (e < len) d[e] = src[e];
        }
        double shift = 0.0;
        for (size_t q = 0; q < pcols.size(); ++q) {
            const CouplePair& p = *pp[q];
            const double ai = ar[p.i], aj = ar[p.j];
            dst[pcols[q]] = ai * p.p1 + aj * p.p2;
            shift += ai * p.di + aj * p.dj;
        }
        s.br[r] = b[m0 + r] - shift;
    }
    s.startsr.resize(static_cast<size_t>(L));
    for (i64 k = 1; k <= L; ++k) s.startsr[k - 1] = starts[k] - m0;
    // Warm sets of the reduced columns: a pair's from its bound rows (y's side).
    s.warmr.resize(static_cast<size_t>((L - 1) * nr));  // every entry written below
    for (i64 k = 1; k < L; ++k) {
        for (i64 c = 0; c < nr; ++c) {
            const i64 t = dof[c];
            const i64 pk = s.pair_of[t];
            i8 v = warm(k, t);
            if (pk >= 0 && v == 0) {
                const CouplePair& p = s.pairs[pk];
                const i8 vj = warm(k, p.j);
                v = p.p2 > 0.0 ? vj : static_cast<i8>(-vj);
            }
            s.warmr[static_cast<size_t>((k - 1) * nr + c)] = v;
        }
    }
    // Every field written by solve_cascade_into but its residuals and primal (the answer's
    // are computed below, in x).
    core::CascadeResult& low = s.low;
    core::solve_cascade_into(
        s.Ar.cref(), CVecRef(s.br), w.slice(m0, M), VecRefT<const i64>(s.startsr), reg.slice(1, L),
        CVecRef(s.lbr), CVecRef(s.ubr), CMatRef(nullptr, 0, nr), h, threshold, max_damping,
        error_scale, rank_tol, max_iter, tol, MatRefT<const i8>(s.warmr.data(), L - 1, nr),
        canonical, ws, low, false, false, defer, lower_trust);
    if (low.status[0] == core::INFEASIBLE) return false;  // the general path's handling
    // A level below not certified in y (kept_previous, a numerical failure): the general
    // path's cascade on x, whose round-off differs, may certify it (erd Baxter's gripper
    // mimic under an orientation + CoM level: stationarity 1.01e-9 in y, 2.9e-13 in x). Its
    // answer is then the step's, whatever it certifies.
    for (i64 k = 0; k + 1 < L; ++k)
        if (low.status[static_cast<size_t>(k)] != core::SOLVED) return false;
    // Back to x, snapped to the box as the cascade snaps; a larger excess: the general path.
    Vec& x = s.xs;
    x.resize(static_cast<size_t>(n));  // every entry written below (each pair's two dofs)
    for (i64 c = 0; c < nr; ++c) {
        const i64 t = dof[c];
        const i64 k = s.pair_of[t];
        if (k < 0) {
            x[t] = low.dq[c];
            continue;
        }
        const CouplePair& p = s.pairs[k];
        x[p.i] = p.di + p.p1 * low.dq[c];
        x[p.j] = p.dj + p.p2 * low.dq[c];
    }
    core::detail::snap_to_box(x, lb, ub);
    for (i64 i = 0; i < n; ++i)
        if (x[i] < lb[i] || x[i] > ub[i]) return false;
    // The result: level 0's own figures, then the levels below as the reduced cascade found them.
    out.dq.assign(x.begin(), x.end());
    // Level 0's entries here, every other one in the loop below.
    out.status.resize(static_cast<size_t>(L));
    out.sigma.resize(static_cast<size_t>(L));
    out.lam2.resize(static_cast<size_t>(L));
    out.iterations.resize(static_cast<size_t>(L));
    out.certificate.resize(static_cast<size_t>(4 * L));
    out.status[0] = core::SOLVED;
    out.sigma[0] = sigma;
    // the levels below's deferred sigma (defer): their header entries after level 0's (none),
    // each offset one further on, then their records as the reduced cascade left them
    out.deferred.clear();
    if (!low.deferred.empty()) {
        out.deferred.push_back(-1.0);
        for (i64 k = 0; k + 1 < L; ++k) {
            const double at = low.deferred[static_cast<size_t>(k)];
            out.deferred.push_back(at == -1.0 ? -1.0 : at + 1.0);
        }
        out.deferred.insert(out.deferred.end(), low.deferred.begin() + (L - 1), low.deferred.end());
    }
    out.lam2[0] = lam;
    out.iterations[0] = 0;
    out.certificate[0] = cert.primal;
    out.certificate[1] = cert.stationarity;
    out.certificate[2] = cert.dual;
    out.certificate[3] = cert.complementarity;
    fill_as(out.active, static_cast<size_t>(L * cols), i8{0});
    for (size_t q = 0; q < rows.size(); ++q)
        if (u[q] > 0.0) out.active[static_cast<size_t>(rows[q])] = static_cast<i8>(sides[q]);
    for (i64 k = 1; k < L; ++k) {
        out.status[k] = low.status[k - 1];
        out.sigma[k] = low.sigma[k - 1];
        out.lam2[k] = low.lam2[k - 1];
        out.iterations[k] = low.iterations[k - 1];
        for (i64 j = 0; j < 4; ++j) out.certificate[4 * k + j] = low.certificate[4 * (k - 1) + j];
        for (i64 c = 0; c < nr; ++c) {
            const i8 v = low.active[static_cast<size_t>((k - 1) * nr + c)];
            if (v == 0) continue;
            const i64 t = dof[c];
            const i64 pk = s.pair_of[t];
            i64 at = t, side = v;
            if (pk >= 0) {
                const CouplePair& p = s.pairs[pk];
                at = v > 0 ? p.lo_dof : p.hi_dof;
                side = v > 0 ? p.lo_side : p.hi_side;
            }
            out.active[static_cast<size_t>(k * cols + at)] = static_cast<i8>(side);
        }
    }
    core::detail::level_residuals_into(A, b, starts, out.dq, s.rr, out.residuals);
    out.primal = 0.0;  // x is inside its box (checked above)
    return true;
}

}  // namespace qpik::diffik
