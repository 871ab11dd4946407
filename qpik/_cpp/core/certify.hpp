// Exactness of a level: the least-squares KKT re-solve on an active set (no added
// regularisation), a primal active-set method (the independent fallback) and the level's
// certificate of optimality (primal feasibility, stationarity in the null space with the
// active rows' multipliers, dual signs, complementarity), each scaled by the size of the
// terms summed. See qpik/core/cascade.py (module doc, "Certificate") for the definitions
// and the tolerance kCertify.
#pragma once

#include <algorithm>
#include <cmath>
#include <optional>
#include <cstring>

#include "linalg.hpp"
#include "qp.hpp"

namespace qpik::core {

constexpr double kCertify = 1e-9;     // a level is SOLVED only when every scaled measure is <= this
constexpr double kRowsRelative = 1e-6;  // rows hold to this relative to |bound| + max|x| (rows_relative)
constexpr double kLsRank = 1e-14;     // |R_ii| <= this * |R_00| is a zero pivot of a least-squares QR
constexpr double kLsRankRef = 1e-13;  // ... and so is |R_ii| <= this * the untransformed matrix's largest column
                                      // norm (lstsq_into's ref): a column that reflections made of round-off
                                      // (seen at 1e-14 ref; a near-singular level's least pivot, 3.6e-13 ref in the
                                      // oracle sweep's seed 20261211, is a rank)
constexpr double kSizeFloor = 1e-5;   // a stationarity component's scale is at least this x the largest
constexpr double kDampedRoundOff = 4.0;  // ... and, on a damped level where that fails, this x eps cond(B) / kCertify
constexpr double kDampedFloorMax = 1e-2;  // ... up to this x the largest (cond(B) about 1e4)
constexpr double kDropRoundOff = 1e-14;  // primal_active_set: a multiplier (times its row's norm) above -this x the
                                          // gradient's size (ls_gradient_size) is round-off, never dropped
constexpr double kNearDependent = 1e-8;  // a row within this angle of the working set's span is
                                         // dependent on it (the primal active set does not add it)

// The four measures of a level's certificate (each a largest scaled violation).
struct Certificate {
    double primal = kNaN;          // rows (box and general) violated, scaled per row
    double stationarity = kNaN;    // Z^T (grad f - sum lambda_i c_i), per component / size of its terms
    double dual = kNaN;            // a multiplier of the wrong sign, scaled by the gradient's size
    double complementarity = kNaN; // multiplier x slack of a row held active, both scaled
    // The rows also hold relative to the numbers involved (not reported): a box row to
    // kRowsRelative (|bound| + max|x|), a general row to kRowsRelative (|g| max|x| + |h|).
    // For bounds of order 1 the primal measure's 1e-9 (1 + |bound|) is the tighter test;
    // for a tiny box (a step of dt = 1e-9 s: bounds of 1e-8) it would let a lower level
    // leave a velocity limit by percents, which this catches (exact_level then goes on).
    bool rows_relative = true;
    bool holds(double tol = kCertify) const {
        return primal <= tol && stationarity <= tol && dual <= tol && complementarity <= tol;
    }
    double worst() const {
        double w = 0.0;
        for (double v : {primal, stationarity, dual, complementarity}) w = std::isnan(v) ? kInf : pymax(w, v);
        return w;
    }
};

// The level's objective 1/2 |B z - f|^2 in null-space coordinates (B = [A Z; sqrt(rho) I],
// f = [b - A d; -sqrt(rho) Z^T d]); H = B^T B, c = -B^T f.
struct LSForm {
    Mat B;
    Vec f;
    bool reg = false;  // B holds the rows sqrt(rho) I (rho > 0): mostly zeros
};

namespace detail {

// Householder QR of N (r, q), q <= r, with the reflections kept (Q = H_0 H_1 ... H_{q-1}
// never formed): the same reflections and R as householder_qr without pivoting.
struct ImplicitQR {
    i64 r = 0, q = 0;
    Mat R;               // (r, q): R[:q] upper triangular
    std::vector<Vec> v;  // v[i] (r - i,)
    Vec beta;            // 2 / |v_i|^2, 0 for an identity step
    Vec vns;             // |v_i|^2, 0 for an identity step

    Vec S;               // scratch

    IVec len;            // len[i]: reflector i's vector is 0 past its first len[i] entries

    // (v's and S's storage is kept from one factor to the next: v[i] is read only where
    // beta[i] != 0, and is then this factor's.)
    // band >= 0: N's column i is exactly +0 below row i + band at step i, and so is every
    // column j > i there, but for entries a reflection never reached (N = [T; I] with T
    // band rows: lstsq's null-space basis; step i's vector then spans rows i..i + band,
    // the rows below it untouched). The reflections skip those rows: their terms are
    // x[t] * (a finite entry) = +-0, which leave a sum from +0 as it is, and their updates
    // subtract +-0 from +0 or a nonzero entry, which leaves it as it is: the same bits
    // (N finite; a reflection's sums finite, as they are unless N's entries near overflow).
    void factor(const Mat& N, i64 band = -1) {
        r = N.rows;
        q = N.cols;
        // N's (r, q) entries (its storage may hold more past them)
        R.rows = r;
        R.cols = q;
        R.a.assign(N.a.begin(), N.a.begin() + r * q);
        if (static_cast<i64>(v.size()) < q) v.resize(static_cast<size_t>(q));
        // (beta, vns, S, len and each v[i] are read through their first q / r - i entries
        // only: grown, never shrunk)
        zero_prefix(beta, static_cast<size_t>(q));
        zero_prefix(vns, static_cast<size_t>(q));
        if (S.size() < static_cast<size_t>(q)) S.resize(static_cast<size_t>(q));  // written by reflect_columns first
        if (len.size() < static_cast<size_t>(q)) len.resize(static_cast<size_t>(q));  // every entry written below
        for (i64 i = 0; i < q; ++i) {
            i64 size = r - i;
            step(i, band >= 0 ? std::min(size, band + 1) : size);
        }
    }
    // [N c] from the factor of N (made by factor with band -1, then appends): the same bits
    // as factor([N c]). Step i of factor reflects columns i.. of R, the new one among them,
    // each column by its own sums (reflect_columns: S = 2 (sum_t x_t R_{i+t}, in order from
    // +0) / |x|^2, then R_{i+t} - x_t S); here the earlier steps' reflections reach c in
    // their order by those operations, then step q reflects it alone. The earlier columns
    // are untouched by step q (step i reflects columns i.. only).
    void append(const double* c) {
        i64 qn = q + 1;
        Vec& w = Sc;  // the new column, reflected by steps 0..q-1 (contiguous)
        w.assign(c, c + r);
        for (i64 i = 0; i < q; ++i) {
            double vn = vns[static_cast<size_t>(i)];
            if (vn == 0.0) continue;  // (no reflection at step i)
            const double* x = v[static_cast<size_t>(i)].data();
            i64 used = len[static_cast<size_t>(i)];
            double* wi = w.data() + i;
            double s = 0.0;
            for (i64 t = 0; t < used; ++t) s += x[t] * wi[t];
            s = 2.0 * s / vn;
            for (i64 t = 0; t < used; ++t) wi[t] = wi[t] - x[t] * s;
        }
        Mat& T = Rt;
        shape(T, r, qn);
        for (i64 t = 0; t < r; ++t) {
            if (q) std::memcpy(T.row(t), R.row(t), static_cast<size_t>(q) * sizeof(double));
            T(t, q) = w[t];
        }
        std::swap(R, T);
        if (static_cast<i64>(v.size()) < qn) v.resize(static_cast<size_t>(qn));
        for (Vec* b : {&beta, &vns, &S})
            if (b->size() < static_cast<size_t>(qn)) b->resize(static_cast<size_t>(qn));
        if (len.size() < static_cast<size_t>(qn)) len.resize(static_cast<size_t>(qn));
        q = qn;
        beta[qn - 1] = 0.0;
        vns[qn - 1] = 0.0;
        step(qn - 1, r - (qn - 1));
    }

   private:
    Mat Rt;  // append's scratch
    Vec Sc;
    // factor's step i (reflector from R's column i, rows i..i + used - 1; columns i..q - 1 reflected)
    void step(i64 i, i64 used) {
        i64 size = r - i;
        Vec& x = v[static_cast<size_t>(i)];
        // entries 0..used-1 written below, the rest +0
        if (x.size() < static_cast<size_t>(size)) x.resize(static_cast<size_t>(size));
        zero_small(x.data() + used, static_cast<size_t>(size - used));
        len[static_cast<size_t>(i)] = used;
        double alpha = 0.0;
        for (i64 t = 0; t < used; ++t) {
            x[t] = R(i + t, i);
            alpha += x[t] * x[t];
        }
        alpha = std::sqrt(alpha);
        if (alpha == 0.0) return;
        if (x[0] > 0.0) alpha = -alpha;
        x[0] -= alpha;
        double vn = 0.0;
        for (i64 t = 0; t < used; ++t) vn += x[t] * x[t];
        if (vn == 0.0) return;
        reflect_columns(R.row(0), q, i, used, i, q, x.data(), vn, S.data());
        beta[i] = 2.0 / vn;
        vns[i] = vn;
    }

   public:
    // The factor of N's first p columns (p <= q): R's first p columns are final after step
    // p - 1 (step i reflects columns i.. only), and steps 0..p-1 are kept.
    void truncate(i64 p) {
        if (p >= q) return;
        Mat& T = Rt;
        shape(T, r, p);
        for (i64 t = 0; t < r; ++t)
            if (p) std::memcpy(T.row(t), R.row(t), static_cast<size_t>(p) * sizeof(double));
        std::swap(R, T);
        q = p;
    }
    // apply_t's reflections i0..i1-1 alone (finite false), in its order: apply_t(x) is
    // apply_t_range(x, 0, k) then apply_t_range(x, k, q), the same operations.
    void apply_t_range(double* x, i64 i0, i64 i1) const {
        for (i64 i = i0; i < i1; ++i) {
            if (beta[i] == 0.0) continue;
            const Vec& vi = v[i];
            i64 size = r - i;
            double s = dot(vi.data(), x + i, size);
            s *= beta[i];
            axmy(x + i, s, vi.data(), size);
        }
    }
    // x <- Q^T x (x of length r). finite: every entry of x is finite, so that the terms
    // past len[i] (vi[t] = 0) of a reflection's sum are +-0 and are skipped (the same bits);
    // its update still runs over every entry (x - s * 0 turns a -0 entry into +0).
    void apply_t(double* x, bool finite = false) const {
        for (i64 i = 0; i < q; ++i) {
            if (beta[i] == 0.0) continue;
            const Vec& vi = v[i];
            i64 size = r - i;
            i64 used = finite ? len[static_cast<size_t>(i)] : size;
            double s = dot(vi.data(), x + i, used);
            s *= beta[i];
            axmy(x + i, s, vi.data(), size);
        }
    }
    // apply_t (finite false) of each of the nc columns of X (r rows, row stride ld): per column,
    // reflection i's sum from +0 of v_i[t] X(i + t, c) over every t in order (dot's), times
    // beta_i, then X(i + t, c) -= s v_i[t] (axmy's): the same operations per column, taken a
    // column pair (or four) at a time in registers, with no calls and several sums in flight.
    void apply_t_cols(double* X, i64 ld, i64 nc) const {
        using namespace simd;
        for (i64 i = 0; i < q; ++i) {
            if (beta[i] == 0.0) continue;
            const double* vi = v[static_cast<size_t>(i)].data();
            const i64 size = r - i;
            const v2d bv = splat(beta[i]);
            double* Xi = X + i * ld;
            i64 c = 0;
            for (; c + 4 <= nc; c += 4) {
                v2d a0 = splat(0.0), a1 = splat(0.0);
                const double* p = Xi + c;
                for (i64 t = 0; t < size; ++t, p += ld) {
                    const v2d vt = splat(vi[t]);
                    a0 = a0 + vt * load(p);
                    a1 = a1 + vt * load(p + 2);
                }
                a0 = a0 * bv;
                a1 = a1 * bv;
                double* w = Xi + c;
                for (i64 t = 0; t < size; ++t, w += ld) {
                    const v2d vt = splat(vi[t]);
                    store(w, load(w) - a0 * vt);
                    store(w + 2, load(w + 2) - a1 * vt);
                }
            }
            for (; c + 2 <= nc; c += 2) {
                v2d a0 = splat(0.0);
                const double* p = Xi + c;
                for (i64 t = 0; t < size; ++t, p += ld) a0 = a0 + splat(vi[t]) * load(p);
                a0 = a0 * bv;
                double* w = Xi + c;
                for (i64 t = 0; t < size; ++t, w += ld) store(w, load(w) - a0 * splat(vi[t]));
            }
            for (; c < nc; ++c) {
                double a0 = 0.0;
                const double* p = Xi + c;
                for (i64 t = 0; t < size; ++t, p += ld) a0 += vi[t] * *p;
                a0 *= beta[i];
                double* w = Xi + c;
                for (i64 t = 0; t < size; ++t, w += ld) *w -= a0 * vi[t];
            }
        }
    }
    // BW (rows, nw) = entries q..q + nw - 1 of Q^T b_i for B's first `rows` rows b_i (each r
    // long): apply_t of each row. Four rows or more are taken as the columns of BT = B[:rows]^T
    // (apply_t_cols: the same operations per row). Where an entry of BT is then not finite, the
    // rows one at a time again (row: scratch): only there could a NaN meet another of another
    // sign or payload, where the one kept follows the operand order the compiler picks; with
    // every entry finite, every product and sum was finite, the same bits.
    void reflected_rows_into(const Mat& B, i64 rows, i64 nw, Mat& BT, Vec& row, Mat& BW) const {
        shape(BW, rows, nw);  // every entry written below
        if (rows >= 4) {  // (fewer: one at a time costs less than the transposes)
            shape(BT, r, rows);  // every entry written below
            for (i64 i = 0; i < rows; ++i) {
                const double* bi = B.row(i);
                for (i64 t = 0; t < r; ++t) BT(t, i) = bi[t];
            }
            apply_t_cols(BT.row(0), rows, rows);
            if (finite_block(BT.row(0), r, rows, rows)) {
                for (i64 i = 0; i < rows; ++i)
                    for (i64 j = 0; j < nw; ++j) BW(i, j) = BT(q + j, i);
                return;
            }
        }
        if (row.size() < static_cast<size_t>(r)) row.resize(static_cast<size_t>(r));  // first r entries used
        for (i64 i = 0; i < rows; ++i) {
            std::memcpy(row.data(), B.row(i), static_cast<size_t>(r) * sizeof(double));
            apply_t(row.data());
            std::memcpy(BW.row(i), row.data() + q, static_cast<size_t>(nw) * sizeof(double));
        }
    }
    // x <- Q x (finite: as apply_t).
    void apply(double* x, bool finite = false) const {
        for (i64 i = q - 1; i >= 0; --i) {
            if (beta[i] == 0.0) continue;
            const Vec& vi = v[i];
            i64 size = r - i;
            i64 used = finite ? len[static_cast<size_t>(i)] : size;
            double s = dot(vi.data(), x + i, used);
            s *= beta[i];
            axmy(x + i, s, vi.data(), size);
        }
    }
};


// The scratch of lstsq (kept by a caller that solves often; sizes only grow).
struct LsScratch {
    IVec perm;
    Vec norms, x, S, yp;
    std::vector<unsigned long long> mask;  // sparse_qr_steps
    IVec sup, fz;
    Mat N0;
    ImplicitQR qn;
    Mat R;       // reg_lstsq_into
    Vec c;
    IVec nz;     // reg_lstsq_rows_into
};

// The reflection of reflect_columns on rows sup[0..ns) (in order), columns i..k-1 of M:
// S_j = 2 (sum_a x_a M(sup_a, j)) / vn, each sum in order from +0, then M(sup_a, j) -=
// x_a S_j (the same operations, per column, as reflect_columns on those rows).
inline void reflect_rows(Mat& M, const i64* sup, i64 ns, i64 i, const double* x, double vn, double* S) {
    i64 k = M.cols;
    double* base = M.a.data() + i;
    reflect_row_set([base, sup, k](i64 a) { return base + sup[a] * k; }, ns, k - i, x, vn, S);
}

// col_sq (rows t0..t1-1, columns j0..j1-1, each summed over the rows in order from +0) on
// the rows whose mask has a bit in the column block (the others' entries there are +0,
// whose squares leave the sums as they are).
// Only the blocks of columns with a bit in need are summed (the others' out left as it is).
inline void masked_col_sq(const Mat& M, const unsigned long long* mask, i64 t0, i64 t1, i64 j0, i64 j1,
                          double* out, unsigned long long need) {
    using namespace simd;
    i64 k = M.cols;
    const double* A = M.a.data();
    auto bits = [](i64 j, i64 c) { return ((c >= 64 ? ~0ULL : ((1ULL << c) - 1ULL))) << j; };
    i64 j = j0;
    for (; j + 8 <= j1; j += 8) {
        unsigned long long bb = bits(j, 8);
        if (!(need & bb)) continue;
        v2d a = splat(0.0), b = splat(0.0), c = splat(0.0), d = splat(0.0);
        for (i64 t = t0; t < t1; ++t) {
            if (!(mask[t] & bb)) continue;
            const double* p = A + t * k + j;
            v2d u = load(p), v = load(p + 2), x = load(p + 4), z = load(p + 6);
            a += u * u;
            b += v * v;
            c += x * x;
            d += z * z;
        }
        store(out + j, a);
        store(out + j + 2, b);
        store(out + j + 4, c);
        store(out + j + 6, d);
    }
    for (; j + 4 <= j1; j += 4) {
        unsigned long long bb = bits(j, 4);
        if (!(need & bb)) continue;
        v2d a = splat(0.0), b = splat(0.0);
        for (i64 t = t0; t < t1; ++t) {
            if (!(mask[t] & bb)) continue;
            const double* p = A + t * k + j;
            v2d u = load(p), v = load(p + 2);
            a += u * u;
            b += v * v;
        }
        store(out + j, a);
        store(out + j + 2, b);
    }
    for (; j + 2 <= j1; j += 2) {
        unsigned long long bb = bits(j, 2);
        if (!(need & bb)) continue;
        v2d a = splat(0.0);
        for (i64 t = t0; t < t1; ++t) {
            if (!(mask[t] & bb)) continue;
            v2d u = load(A + t * k + j);
            a += u * u;
        }
        store(out + j, a);
    }
    for (; j < j1; ++j) {
        unsigned long long bb = 1ULL << j;
        if (!(need & bb)) continue;
        double a = 0.0;
        for (i64 t = t0; t < t1; ++t)
            if (mask[t] & bb) a += A[t * k + j] * A[t * k + j];
        out[j] = a;
    }
}

// The pivoted Householder steps of lstsq_into (k <= 64 columns) on the rows that can change:
// the same pivots, reflections, R and Q^T f bits, with the work of the rows a step cannot
// touch left out (a least-squares matrix [A Z; sqrt(rho) I] is mostly zeros: rho's rows
// hold one entry until a reflection reaches them, a task's Jacobian rows miss the joints
// it does not depend on).
// A row is clean when its entries and its f entry are finite and none is -0; a clean row's
// mask has a bit per column (in the current column order) that may be nonzero, every other
// entry being exactly +0 (an unclean row's mask is all ones: always taken). Step i's
// reflector x is column i below row i: on a clean row without bit i its entry is +0, so
// (1) the sums of the step (alpha, vn, the column products S_j, x . f) each get a term
// (+0) (finite entry) = +-0 there, which leaves a sum from +0 as it is (a sum from +0 is
// never -0); (2) the update M_tj - x_t S_j = M_tj - (+-0) leaves M_tj as it is when S_j is
// finite and M_tj is not -0 (clean), the same for f_t; so such rows are skipped, unless an
// S_j (or f's coefficient) is not finite, when they are updated as before and become
// unclean. A row the step updates gets the union of the updated rows' masks: where every
// one of them is +0 the column's S_j is 2 (+0) / vn = +0 and its entries stay +0. Row i
// is always updated (x_0 = R_ii - alpha). No update makes a -0 (x - y = -0 in round to
// nearest only for x = -0, y = +0), so clean rows stay clean. The remaining columns'
// norms are summed over the rows in order as col_sq does, a clean row adding only its
// masked entries (the others' squares are +0).
inline void sparse_qr_steps(Mat& M, Vec& f, IVec& perm, Vec& norms, LsScratch& ws) {
    using u64 = unsigned long long;
    i64 m = M.rows, k = M.cols;
    i64 steps = std::min(m, k);
    std::vector<u64>& mask = ws.mask;
    if (mask.size() < static_cast<size_t>(m)) mask.resize(static_cast<size_t>(m));
    const u64 all = k == 64 ? ~0ULL : ((1ULL << k) - 1ULL);
    // clean: no entry -0 (bits 0x8000...) or non-finite (exponent all ones)
    for (i64 t = 0; t < m; ++t) {
        const double* row = M.row(t);
        u64 b = 0, badv = 0;
        for (i64 j = 0; j < k; ++j) {
            u64 v;
            std::memcpy(&v, row + j, sizeof v);
            if (v << 1) b |= 1ULL << j;  // nonzero (either sign)
            badv |= static_cast<u64>(v == 0x8000000000000000ULL) | static_cast<u64>((v & 0x7ff0000000000000ULL) == 0x7ff0000000000000ULL);
        }
        mask[t] = badv ? all : b;
    }
    IVec& sup = ws.sup;
    if (sup.size() < static_cast<size_t>(m)) sup.resize(static_cast<size_t>(m));
    Vec& x = ws.x;  // x[t] for the updated rows, by position in sup
    Vec& S = ws.S;
    IVec& fz = ws.fz;  // the rows whose f entry is -0
    fz.clear();
    for (i64 t = 0; t < m; ++t)
        if (f[t] == 0.0 && std::signbit(f[t])) fz.push_back(t);
    for (i64 i = 0; i < steps; ++i) {
        i64 best = i;
        for (i64 j = i + 1; j < k; ++j)
            if (norms[j] > norms[best]) best = j;
        if (best != i) {
            std::swap(norms[i], norms[best]);
            std::swap(perm[i], perm[best]);
            // (a clean row without either bit holds +0 in both: nothing to swap)
            u64 pair = (1ULL << i) | (1ULL << best);
            for (i64 t = 0; t < m; ++t) {
                u64 b = mask[t];
                if (!(b & pair)) continue;
                std::swap(M(t, i), M(t, best));
                u64 bi = (b >> i) & 1ULL, bb = (b >> best) & 1ULL;
                if (bi != bb) mask[t] = b ^ pair;
            }
        }
        // The columns whose norms change: those with a bit in the updated rows (the union
        // mask un, row i's included). Elsewhere the updated rows and row i hold +0, which the
        // step leaves +0 (S_j = +0): the norm over rows i + 1.. is the one over rows i..
        // less a first term (+0) (+0), the same sum.
        u64 need = all;
        // the rows updated: row i and every row below with bit i
        i64 ns = 0;
        sup[ns++] = i;
        for (i64 t = i + 1; t < m; ++t)
            if ((mask[t] >> i) & 1ULL) sup[ns++] = t;
        double alpha = 0.0;
        for (i64 a = 0; a < ns; ++a) {
            x[a] = M(sup[a], i);
            alpha += x[a] * x[a];
        }
        alpha = std::sqrt(alpha);
        if (alpha != 0.0) {
            if (x[0] > 0.0) alpha = -alpha;
            x[0] -= alpha;
            double vn = dot(x.data(), x.data(), ns);
            if (vn != 0.0) {
                i64 w = k - i;
                reflect_rows(M, sup.data(), ns, i, x.data(), vn, S.data());
                bool fin = true;
                for (i64 j = 0; j < w; ++j) fin = fin && std::isfinite(S[j]);
                // f as lstsq_into updates it: its sum over the updated rows (the others' terms
                // (+0) (finite f_t) = +-0), every row updated (f_t - sf (+0) is f_t but for
                // f_t = -0, the rows in fz)
                double sf = 0.0;
                for (i64 a = 0; a < ns; ++a) sf += x[a] * f[sup[a]];
                sf = 2.0 * sf / vn;
                for (i64 a = 0; a < ns; ++a) f[sup[a]] -= sf * x[a];
                if (std::isfinite(sf)) {
                    // (a row made +0, or one no later step reaches, leaves the list)
                    size_t kept = 0;
                    for (i64 t : fz) {
                        if (t <= i) continue;
                        if (!((mask[t] >> i) & 1ULL)) f[t] -= sf * 0.0;
                        if (f[t] == 0.0 && std::signbit(f[t])) fz[kept++] = t;
                    }
                    fz.resize(kept);
                } else {
                    for (i64 t = i + 1; t < m; ++t)
                        if (!((mask[t] >> i) & 1ULL)) f[t] -= sf * 0.0;
                }
                u64 un = 0;
                for (i64 a = 0; a < ns; ++a) un |= mask[sup[a]];
                for (i64 a = 0; a < ns; ++a) mask[sup[a]] = un;
                need = un;
                if (!fin) {  // the skipped rows as before (x_t = +0), now unclean
                    i64 a = 0;
                    for (i64 t = i; t < m; ++t) {
                        if (a < ns && sup[a] == t) {
                            ++a;
                            continue;
                        }
                        axmy(M.row(t) + i, 0.0, S.data(), w);
                        mask[t] = all;
                    }
                    need = all;
                }
            }
        }
        // the remaining columns' norms (each summed over the rows below i in order)
        i64 j0 = i + 1;
        if (j0 >= k) continue;
        masked_col_sq(M, mask.data(), j0, m, j0, k, norms.data(), need);
    }
}

// min |M y - f| by Householder QR with column pivoting, into y (M (m, k) and f are
// overwritten); pivots below kLsRank |R_00| are zeros, and the solution is the one of
// least norm.
// sparse: M is mostly exact zeros (B = [A Z; sqrt(rho) I] itself), where the Householder
// steps skip the rows they cannot touch (sparse_qr_steps: the same bits).
// ref: the largest column norm of the matrix M was reflected from (eqp_ls's B, of which M = B W
// with W's columns orthonormal), 0 where M is that matrix itself. A pivot at or below kLsRankRef
// ref is zero whatever |R_00|: where every direction left is flat (B W zero but for round-off,
// about eps |B| times the reflections made), the relative test alone took round-off pivots for a
// rank and the step divided by them (|y| ~ 1e13 |f| / |B|).
inline void lstsq_into(Mat& M, Vec& f, Vec& y, LsScratch& ws, bool sparse_hint = false, double ref = 0.0) {
    i64 m = M.rows, k = M.cols;
    if (k == 0 || m == 0) {
        zero_fill(y, static_cast<size_t>(k));
        return;
    }
    shape(y, static_cast<size_t>(k));  // every entry written at the end (perm is a permutation)
    // The scratch (perm, norms, x, S, yp) is read through its first k / m entries only:
    // grown, never shrunk.
    IVec& perm = ws.perm;
    if (perm.size() < static_cast<size_t>(k)) perm.resize(static_cast<size_t>(k));
    for (i64 j = 0; j < k; ++j) perm[j] = j;
    Vec& norms = ws.norms;
    if (norms.size() < static_cast<size_t>(k)) norms.resize(static_cast<size_t>(k));
    col_sq(M.a.data(), k, 0, m, 0, k, norms.data());  // each summed over the rows in order
    i64 steps = std::min(m, k);
    Vec& x = ws.x;
    Vec& S = ws.S;
    // x[:size] written before read; S filled by reflect_columns
    if (x.size() < static_cast<size_t>(m)) x.resize(static_cast<size_t>(m));
    if (S.size() < static_cast<size_t>(k)) S.resize(static_cast<size_t>(k));
    bool sparse = sparse_hint && k >= 12 && k <= 64;  // (below 12 columns its bookkeeping costs more than it saves)
    for (i64 t = 0; sparse && t < m; ++t) sparse = std::isfinite(f[t]);  // (sparse_qr_steps skips f's terms)
    if (sparse) sparse_qr_steps(M, f, perm, norms, ws);
    for (i64 i = sparse ? steps : 0; i < steps; ++i) {
        i64 best = i;
        for (i64 j = i + 1; j < k; ++j)
            if (norms[j] > norms[best]) best = j;
        if (best != i) {
            for (i64 t = 0; t < m; ++t) std::swap(M(t, i), M(t, best));
            std::swap(norms[i], norms[best]);
            std::swap(perm[i], perm[best]);
        }
        i64 size = m - i;
        double alpha = 0.0;
        for (i64 t = 0; t < size; ++t) {
            x[t] = M(i + t, i);
            alpha += x[t] * x[t];
        }
        alpha = std::sqrt(alpha);
        if (alpha != 0.0) {
            if (x[0] > 0.0) alpha = -alpha;
            x[0] -= alpha;
            double vn = dot(x.data(), x.data(), size);
            if (vn != 0.0) {
                // the remaining columns' norms summed as the entries are updated
                reflect_columns(M.a.data(), M.cols, i, size, i, M.cols, x.data(), vn, S.data(),
                                norms.data() + i);
                double s = dot(x.data(), f.data() + i, size);
                s = 2.0 * s / vn;
                axmy(f.data() + i, s, x.data(), size);
                continue;
            }
        }
        // The remaining columns' norms, recomputed (each summed over t in order).
        col_sq(M.a.data(), k, i + 1, m, i + 1, k, norms.data());
    }
    double top = std::fabs(M(0, 0));
    i64 rank = 0;
    for (i64 i = 0; i < steps; ++i) {
        if (std::fabs(M(i, i)) > kLsRank * top && top > 0.0 && std::fabs(M(i, i)) > kLsRankRef * ref) rank = i + 1;
        else break;
    }
    Vec& yp = ws.yp;
    zero_prefix(yp, static_cast<size_t>(k));
    for (i64 i = rank - 1; i >= 0; --i) {
        double acc = f[i];
        for (i64 j = i + 1; j < rank; ++j) acc -= M(i, j) * yp[j];
        yp[i] = acc / M(i, i);
    }
    if (rank < k) {
        // The minimum-norm solution: the basic one less its component in the null space of
        // [R11 R12], spanned by the orthonormalised columns of [-R11^-1 R12; I].
        i64 nn = k - rank;
        Mat& N0 = ws.N0;
        N0.zeros(k, nn);
        for (i64 c = 0; c < nn; ++c) {
            N0(rank + c, c) = 1.0;
            for (i64 i = rank - 1; i >= 0; --i) {
                double acc = -M(i, rank + c);
                for (i64 j = i + 1; j < rank; ++j) acc -= M(i, j) * N0(j, c);
                N0(i, c) = acc / M(i, i);
            }
        }
        ImplicitQR& qn = ws.qn;  // yp - Qn Qn^T yp: zero the first nn entries of Q^T yp, then Q
        bool n0_finite = true;
        for (i64 i = 0; i < rank; ++i)
            for (i64 c = 0; c < nn; ++c) n0_finite = n0_finite && std::isfinite(N0(i, c));
        qn.factor(N0, n0_finite ? rank : -1);  // N0's columns: rank rows, then the identity's
        bool finite = true;
        for (i64 j = 0; j < k; ++j) finite = finite && std::isfinite(yp[j]);
        qn.apply_t(yp.data(), finite);
        for (i64 c = 0; c < nn; ++c) yp[c] = 0.0;
        finite = true;
        for (i64 j = 0; j < k; ++j) finite = finite && std::isfinite(yp[j]);
        qn.apply(yp.data(), finite);
    }
    for (i64 j = 0; j < k; ++j) y[perm[j]] = yp[j];
}

// min |M y - f| (lstsq_into on copies).
inline Vec lstsq(Mat M, Vec f) {
    LsScratch ws;
    Vec y;
    lstsq_into(M, f, y, ws);
    return y;
}

// x . y (n entries), two lanes (even and odd terms summed apart, then added).
inline double dot_2l(const double* x, const double* y, i64 n) {
    using namespace simd;
    v2d a = splat(0.0), b = splat(0.0);
    i64 i = 0;
    for (; i + 4 <= n; i += 4) {
        a += load(x + i) * load(y + i);
        b += load(x + i + 2) * load(y + i + 2);
    }
    for (; i + 2 <= n; i += 2) a += load(x + i) * load(y + i);
    a += b;
    double acc = a[0] + a[1];
    for (; i < n; ++i) acc += x[i] * y[i];
    return acc;
}

// min |M y - g|^2 + |s y - h|^2 (M (m, k) given by its columns, the rows of Mt (k, m, row
// stride m); g (m,), h (k,), s > 0) into y: the least-squares problem of [M; s I] with
// right-hand side [g; h], by Householder reflections that fold M's rows into R = s I one
// column at a time (step j reflects R's row j and M's rows, columns j.. only: R's rows below
// j are still s e_i, zero in those columns, and R's row j is still s e_j, c_j = h_j), then
// R y = c. No pivoting: taken only where [M; s I] is well conditioned enough for that,
// s^2 >= kRegFold max_j |M_j|^2 (its least singular value is at least s, so the pivoted QR
// finds no zero pivot either and the minimiser is the one lstsq_into's minimum-norm solution
// gives), with every entry of M, g, h finite; false (nothing written to y) otherwise. Mt and
// g are overwritten. O(m k^2) rather than lstsq_into's O((m + k) k^2) on [M; s I].
constexpr double kRegFold = 1e-10;
constexpr i64 kRegFoldMin = 12;  // eqp_ls folds only levels of this many free directions r (see there)
// The checks of reg_lstsq_into: s > 0 finite, M, g, h finite, s^2 >= kRegFold max_j |M_j|^2
// (norms[j] = |M_j|^2 given).
inline bool reg_fold_ok(const double* norms, i64 k, const Vec& g, i64 m, const double* h, double s) {
    if (!(s > 0.0) || !std::isfinite(s)) return false;
    double big = 0.0;
    bool fin = true;
    for (i64 j = 0; j < k; ++j) {
        big = pymax(big, norms[j]);
        fin = fin && std::isfinite(norms[j]) && std::isfinite(h[j]);
    }
    for (i64 t = 0; t < m; ++t) fin = fin && std::isfinite(g[t]);
    return fin && s * s >= kRegFold * big;
}
inline void reg_back(const Mat& R, const Vec& c, i64 k, Vec& y) {
    shape(y, static_cast<size_t>(k));
    for (i64 j = k - 1; j >= 0; --j) {
        double acc = c[j];
        const double* Rj = R.row(j);
        for (i64 l = j + 1; l < k; ++l) acc -= Rj[l] * y[l];
        y[j] = acc / Rj[j];
    }
}
// Mt (k, m): M's columns as rows (the layout for m > k: each step's work is k - j dot
// products and updates of length m).
inline bool reg_lstsq_into(double* Mt, i64 k, i64 m, Vec& g, const double* h, double s, Vec& y, LsScratch& ws) {
    Vec& norms = ws.norms;  // |M_j|^2
    if (norms.size() < static_cast<size_t>(k)) norms.resize(static_cast<size_t>(k));
    for (i64 j = 0; j < k; ++j) norms[j] = dot_2l(Mt + j * m, Mt + j * m, m);
    if (!reg_fold_ok(norms.data(), k, g, m, h, s)) return false;
    Mat& R = ws.R;  // R's strict upper triangle and diagonal, written step by step
    shape(R, k, k);
    Vec& c = ws.c;
    shape(c, static_cast<size_t>(k));
    for (i64 j = 0; j < k; ++j) {
        const double* vj = Mt + j * m;  // the reflector: (s - alpha, M_j)
        double sumv = dot_2l(vj, vj, m);  // |M_j|^2 now (the steps before changed it)
        double alpha = std::sqrt(s * s + sumv);  // the new R_jj is -alpha (s > 0)
        double v0 = s + alpha;
        double f2 = 2.0 / (v0 * v0 + sumv);
        double* Rj = R.row(j);
        for (i64 l = j + 1; l < k; ++l) {
            double* ml = Mt + l * m;
            double sl = f2 * dot_2l(vj, ml, m);  // (R_jl = 0 before the step)
            Rj[l] = -v0 * sl;
            axmy(ml, sl, vj, m);
        }
        double sc = f2 * (v0 * h[j] + dot_2l(vj, g.data(), m));
        c[j] = h[j] - v0 * sc;
        axmy(g.data(), sc, vj, m);
        Rj[j] = -alpha;
    }
    reg_back(R, c, k, y);
    return true;
}
// M (m, k) by rows (the layout for m <= k: each step's work is m products and updates of
// length k - j - 1, summed row by row).
inline bool reg_lstsq_rows_into(Mat& M, Vec& g, const double* h, double s, Vec& y, LsScratch& ws) {
    i64 m = M.rows, k = M.cols;
    Vec& norms = ws.norms;
    if (norms.size() < static_cast<size_t>(k)) norms.resize(static_cast<size_t>(k));
    col_sq(M.a.data(), k, 0, m, 0, k, norms.data());
    if (!reg_fold_ok(norms.data(), k, g, m, h, s)) return false;
    Mat& R = ws.R;
    shape(R, k, k);
    Vec& c = ws.c;
    shape(c, static_cast<size_t>(k));
    Vec& v = ws.x;  // column j of M
    if (v.size() < static_cast<size_t>(m)) v.resize(static_cast<size_t>(m));
    IVec& nz = ws.nz;
    if (nz.size() < static_cast<size_t>(m)) nz.resize(static_cast<size_t>(m));  // first nt used
    for (i64 j = 0; j < k; ++j) {
        double sumv = 0.0;
        for (i64 t = 0; t < m; ++t) {
            v[t] = M(t, j);
            sumv += v[t] * v[t];
        }
        double alpha = std::sqrt(s * s + sumv);
        double v0 = s + alpha;
        double f2 = 2.0 / (v0 * v0 + sumv);
        // the rows with v[t] != 0 (the others add and take +-0: skipped, as before)
        i64 nt = 0;
        for (i64 t = 0; t < m; ++t)
            if (v[t] != 0.0) nz[nt++] = t;
        double sc = v0 * h[j];
        for (i64 a = 0; a < nt; ++a) sc += v[nz[a]] * g[nz[a]];
        sc *= f2;
        // Per column l > j (R_jl = 0 before the step): S_l = f2 (+0 plus v[t] M(t, l) over the
        // nonzero v[t] in t order), R_jl = -v0 S_l, then M(t, l) -= v[t] S_l: the sums of axpy
        // into S and the updates of axmy from it, row by row, the same operations per entry,
        // taken a column pair at a time in registers (no calls, each entry read once).
        double* Rj = R.row(j);
        {
            using namespace simd;
            const v2d fv = splat(f2), nv = splat(-v0);
            const i64 ld = M.cols;
            double* M0 = M.a.data();
            i64 l = j + 1;
            for (; l + 4 <= k; l += 4) {
                v2d a0 = splat(0.0), a1 = splat(0.0);
                for (i64 a = 0; a < nt; ++a) {
                    const double* p = M0 + nz[a] * ld + l;
                    const v2d va = splat(v[nz[a]]);
                    a0 = a0 + va * load(p);
                    a1 = a1 + va * load(p + 2);
                }
                a0 = a0 * fv;
                a1 = a1 * fv;
                store(Rj + l, nv * a0);
                store(Rj + l + 2, nv * a1);
                for (i64 a = 0; a < nt; ++a) {
                    double* p = M0 + nz[a] * ld + l;
                    const v2d va = splat(v[nz[a]]);
                    store(p, load(p) - va * a0);
                    store(p + 2, load(p + 2) - va * a1);
                }
            }
            for (; l + 2 <= k; l += 2) {
                v2d a0 = splat(0.0);
                for (i64 a = 0; a < nt; ++a) a0 = a0 + splat(v[nz[a]]) * load(M0 + nz[a] * ld + l);
                a0 = a0 * fv;
                store(Rj + l, nv * a0);
                for (i64 a = 0; a < nt; ++a) {
                    double* p = M0 + nz[a] * ld + l;
                    store(p, load(p) - splat(v[nz[a]]) * a0);
                }
            }
            for (; l < k; ++l) {
                double a0 = 0.0;
                for (i64 a = 0; a < nt; ++a) a0 += v[nz[a]] * M0[nz[a] * ld + l];
                a0 *= f2;
                Rj[l] = -v0 * a0;
                for (i64 a = 0; a < nt; ++a) M0[nz[a] * ld + l] -= v[nz[a]] * a0;
            }
        }
        c[j] = h[j] - v0 * sc;
        for (i64 a = 0; a < nt; ++a) g[nz[a]] -= v[nz[a]] * sc;
        Rj[j] = -alpha;
    }
    reg_back(R, c, k, y);
    return true;
}

// B^T (B z - f): the level's reduced gradient H z + c, without any added regularisation.
inline Vec ls_gradient(const LSForm& ls, const Vec& z) {
    Vec r = mv(ls.B.cref(), z.data());
    for (size_t i = 0; i < r.size(); ++i) r[i] = r[i] - ls.f[i];
    return mtv(ls.B.cref(), r.data());
}

}  // namespace detail

namespace detail {
// W = Q[:, q:] (r, r - q) of the factor qr (a column at a time: Q e_{q+j}).
inline void null_columns(const ImplicitQR& qr, i64 r, i64 q, Vec& e, Mat& W) {
    i64 nw = r - q;
    W = Mat(r, nw);
    zero_fill(e, static_cast<size_t>(r));
    for (i64 j = 0; j < nw; ++j) {
        std::fill(e.begin(), e.end(), 0.0);
        e[q + j] = 1.0;
        qr.apply(e.data());
        for (i64 i = 0; i < r; ++i) W(i, j) = e[i];
    }
}

// What eqp_ls keeps from one call to the next for a caller whose working set changes by a
// row at a time (primal_active_set): the working set whose normals ws.qr factors (rows,
// sides), and B's rows reflected by that factor's first bq reflections (BQ, mb x r). A call
// on a working set sharing a first p rows with it truncates the factor to p columns and
// appends the rest (ImplicitQR::truncate, append), and reflects BQ by the reflections it
// lacks: the same bits as factoring and reflecting from scratch.
struct EqpKeep {
    bool valid = false;
    IVec rows, sides;
    Mat BQ;
    i64 bq = -1;  // -1: BQ not made
};
}  // namespace detail

// The exact minimiser of 1/2 |B z - f|^2 with the working set's rows held as equalities
// (n_j^T z = rhs_j, n_j = side_j C[row_j]) and their multipliers (B^T (B z - f) = N u);
// false when the normals are dependent. No regularisation is added: of the minimisers, the
// one closest to zref (zref moved onto the working set, then the least-norm least-squares
// step in the working set's null space W, by the pivoted QR of B W; where B = [A Z; s I]
// holds the regularisation's rows, r >= kRegFoldMin and q > 0, the unique minimiser from
// A Z W and s I instead: reg_lstsq_into). N's orthogonal factor
// is kept as reflections (O(q r) per product, never the O(q r^2) explicit Q); W_out, when
// asked for, is formed.
// The storage of eqp_ls and certify_level (kept by a caller that solves often).
struct CertScratch {
    detail::ImplicitQR qr;
    detail::LsScratch ls;
    Mat N, BW;
    Vec rhs, t, row, f0, y, wy, e, g, r;
    Vec gnorm, gx, v, vs, sc, ssc, zg, dx, zc, hs, hsc, ms, msc, v0;  // certify_level
    Vec rres, rsize, radx;              // certify_level's kept rows
    IVec keep;
    IVec xrows, xsides;                 // exact_level (qpik/_cpp/core/cascade.hpp)
    Vec xu, xx, xZz, xzc, xzref, xstart, xagain;
    Vec xbest;                          // exact_level's feasible candidate of least worst measure,
    bool has_best = false;              // for certified_by_refined_multipliers (cascade.hpp)
    Mat nM;                             // ... its signed row normals (t, r)
    std::vector<const double*> ncols;   // ... as nnls_cols' columns
    std::vector<long double> ny, nMl, nres, nMP, nq, nv, nu;  // ... in extended precision
    IVec npas;                          // ... the passive rows
    IVec xts;                           // eqp_ls's reflection rows
    Mat BT;                             // eqp_ls's B^T
    Mat eV;                             // exact_level's eq_candidate (qpik/_cpp/core/cascade.hpp)
    Vec eS, erhs, et, edz, edu, ecol;
    Mat rK, rL, rN, rP;                 // row_space_set_candidate (qpik/_cpp/core/cascade.hpp)
    Vec rS, rrhs, rg, rt, rdz, rdu, re, ry, rw, rresid;
};

namespace detail {
// B z into y, as mv_into(B, z) computes it. With the regularisation's rows (ls.reg: row m + j
// of B is sqrt(rho) e_j, its other entries +0, as ls_form writes them) and z finite, that
// row's sum from +0 adds terms (+0) z_t = +-0 and the one term s z_j: its value is
// s z_j + 0.0 (a -0 made +0), written without the sum; rows 0..m-1 are mv_into's (each row's
// sum the same in any grouping of the rows).
inline void ls_mv_into(const LSForm& ls, const double* z, Vec& y) {
    i64 mb = ls.B.rows, r = ls.B.cols;
    bool eye = ls.reg && mb >= r;
    for (i64 j = 0; eye && j < r; ++j) eye = std::isfinite(z[j]);
    if (!eye) {
        mv_into(ls.B.cref(), z, y);
        return;
    }
    i64 m = mb - r;
    y.resize(static_cast<size_t>(mb));
    i64 i = 0;
    for (; i + 4 <= m; i += 4)
        dot4(ls.B.row(i), ls.B.row(i + 1), ls.B.row(i + 2), ls.B.row(i + 3), z, r, y[i], y[i + 1], y[i + 2],
             y[i + 3]);
    for (; i + 2 <= m; i += 2) dot2(ls.B.row(i), ls.B.row(i + 1), z, r, y[i], y[i + 1]);
    for (; i < m; ++i) {
        const double* bi = ls.B.row(i);
        double acc = 0.0;
        for (i64 j = 0; j < r; ++j) acc += bi[j] * z[j];
        y[i] = acc;
    }
    for (i64 j = 0; j < r; ++j) y[m + j] = ls.B(m + j, j) * z[j] + 0.0;
}

// B^T x into y, as mtv_into(B, x) computes it. With the regularisation's rows (ls.reg) and
// their x entries finite, row m + j adds x_{m+j} s to y_j and x_{m+j} (+0) = +-0 to the
// other entries, which leaves them as they are (a sum from +0 is never -0): only the first.
inline void ls_mtv_into(const LSForm& ls, const double* x, Vec& y) {
    i64 mb = ls.B.rows, r = ls.B.cols;
    bool eye = ls.reg && mb >= r;
    for (i64 j = mb - r; eye && j < mb; ++j) eye = std::isfinite(x[j]);
    if (!eye) {
        mtv_into(ls.B.cref(), x, y);
        return;
    }
    i64 m = mb - r;
    y.assign(static_cast<size_t>(r), 0.0);
    for (i64 i = 0; i < m; ++i) {
        double a = x[i];
        if (a != 0.0) axpy(y.data(), a, ls.B.row(i), r);
    }
    for (i64 j = 0; j < r; ++j) {
        double a = x[m + j];
        if (a != 0.0) y[j] += a * ls.B(m + j, j);
    }
}
}  // namespace detail

inline bool eqp_ls(const LSForm& ls, CMatRef C, CVecRef lo, CVecRef hi, const IVec& act_row,
                   const IVec& act_side, i64 q, const Vec& zref, Vec& z, Vec& u, Mat* W_out = nullptr,
                   CertScratch* scratch = nullptr, detail::EqpKeep* keep = nullptr) {
    // keep: the state kept from this caller's previous call with the same scratch (see EqpKeep)
    if (!scratch) {  // storage of its own, only when the caller keeps none
        CertScratch local;
        return eqp_ls(ls, C, lo, hi, act_row, act_side, q, zref, z, u, W_out, &local);
    }
    i64 r = C.cols;
    i64 mb = ls.B.rows;
    z = zref;
    zero_fill(u, static_cast<size_t>(q));
    if (q > r) return false;
    CertScratch& ws = *scratch;
    detail::ImplicitQR& qr = ws.qr;
    if (q > 0) {
        Mat& N = ws.N;
        shape(N, r, q);  // every entry written below
        Vec& rhs = ws.rhs;
        shape(rhs, static_cast<size_t>(q));  // every entry written below
        for (i64 j = 0; j < q; ++j) {
            double side = static_cast<double>(act_side[j]);
            const double* cj = C.row(act_row[j]);
            double nz = 0.0;  // n_j . zref, summed as n_j is written
            for (i64 i = 0; i < r; ++i) {
                double e = cj[i] * side;
                N(i, j) = e;
                nz += e * zref[i];
            }
            rhs[j] = detail::rhs_of(lo, hi, act_row[j], act_side[j]) - nz;
        }
        i64 p = -1;  // the kept factor's first p columns are this one's
        if (keep && keep->valid && qr.r == r) {
            i64 qf = static_cast<i64>(keep->rows.size());
            p = 0;
            while (p < std::min(qf, q) && keep->rows[p] == act_row[p] && keep->sides[p] == act_side[p]) ++p;
        }
        if (p >= 0) {
            qr.truncate(p);
            Vec& col = ws.row;
            if (col.size() < static_cast<size_t>(r)) col.resize(static_cast<size_t>(r));  // first r entries used
            for (i64 j = p; j < q; ++j) {
                for (i64 i = 0; i < r; ++i) col[i] = N(i, j);
                qr.append(col.data());
            }
            if (keep->bq > p) keep->bq = -1;  // (BQ has reflections this factor lacks)
        } else {
            qr.factor(N);
            if (keep) keep->bq = -1;
        }
        if (keep) {
            keep->valid = true;
            keep->rows.assign(act_row.begin(), act_row.begin() + q);
            keep->sides.assign(act_side.begin(), act_side.begin() + q);
        }
        const Mat& R = qr.R;
        double scale = 0.0;
        for (i64 i = 0; i < q; ++i) scale = pymax(scale, std::fabs(R(i, i)));
        for (i64 i = 0; i < q; ++i)
            if (std::fabs(R(i, i)) <= kDependent * pymax(scale, 1e-300)) return false;
        Vec& t = ws.t;
        zero_prefix(t, static_cast<size_t>(r));  // read through its first r entries
        for (i64 i = 0; i < q; ++i) {  // R1^T t = rhs
            double acc = rhs[i];
            for (i64 k = 0; k < i; ++k) acc -= R(k, i) * t[k];
            t[i] = acc / R(i, i);
        }
        qr.apply(t.data());  // Y t
        for (i64 i = 0; i < r; ++i) z[i] = z[i] + t[i];
    } else {
        qr.r = r;
        qr.q = 0;
        if (keep) {
            keep->valid = true;
            keep->rows.clear();
            keep->sides.clear();
            keep->bq = -1;
        }
    }
    i64 nw = r - q;
    if (nw > 0) {
        Vec& y = ws.y;
        Vec& f0 = ws.f0;
        Mat& BW = ws.BW;
        bool done = false;
        if (q > 0 && ls.reg && mb >= r && r >= detail::kRegFoldMin) {
            // B = [A Z; s I] (ls_form): |B W y - f0|^2 = |A Z W y - f0_top|^2 + |s W y - f0_bot|^2,
            // and W's columns are orthonormal (W = Q[:, q:], Q^T W = [0; I]), so the second term
            // is |s y - W^T f0_bot|^2 + |Y^T f0_bot|^2 (the last independent of y): the same
            // minimiser from A Z W (only A Z's m rows reflected by Q, not B's m + r) and the
            // s I rows, by reg_lstsq_into where it applies (else the pivoted QR below).
            // A different algorithm from the QR of B W: the same minimiser to round-off, which
            // on a level whose B W is ill-conditioned moves the answer by about eps |B|^2 / s^2
            // relative (4e-12 with s = 1e-3, |B| = 0.75: tests/fixtures/core.npz's case 184,
            // r = 5). Small levels (r < kRegFoldMin), where the dense QR costs little, keep it.
            i64 m = mb - r;
            double s = ls.B(m, 0);
            Vec& row = ws.row;
            if (row.size() < static_cast<size_t>(r)) row.resize(static_cast<size_t>(r));  // first r entries used
            detail::ls_mv_into(ls, z.data(), f0);
            for (i64 i = 0; i < m; ++i) f0[i] = ls.f[i] - f0[i];
            for (i64 j = 0; j < r; ++j) row[j] = ls.f[m + j] - f0[m + j];
            qr.apply_t(row.data());  // Q^T f0_bot: its last nw entries are W^T f0_bot
            f0.resize(static_cast<size_t>(m));
            Vec& h = ws.t;  // W^T f0_bot (t is not read again)
            shape(h, static_cast<size_t>(nw));
            for (i64 j = 0; j < nw; ++j) h[j] = row[q + j];
            if (m <= nw) {
                // A Z W by rows (Q^T B_i^T for A Z's rows)
                qr.reflected_rows_into(ls.B, m, nw, ws.BT, row, BW);
                done = detail::reg_lstsq_rows_into(BW, f0, h.data(), s, y, ws.ls);
            } else {
                // X = (A Z)^T (r, m), then Q^T X (reflection i on rows i..): its rows q.. are
                // (A Z W)^T, the columns of A Z W
                Mat& X = BW;
                shape(X, r, m);  // every entry written below
                for (i64 t = 0; t < m; ++t) {
                    const double* bt = ls.B.row(t);
                    for (i64 j = 0; j < r; ++j) X(j, t) = bt[j];
                }
                // Reflection i on X's rows i..: per column c, S_c = beta (+0 plus vi[t] X(i + t, c)
                // over the nonzero vi[t] in t order), then X(i + t, c) -= vi[t] S_c (the sums and
                // updates of axpy into S and axmy from it, row by row: the same operations per
                // entry), a column pair at a time in registers (its entries read once, no calls).
                Vec& vs = ws.e;  // the nonzero vi[t] (their rows in ts)
                IVec& ts = ws.xts;
                if (vs.size() < static_cast<size_t>(r)) vs.resize(static_cast<size_t>(r));  // first nt used
                if (ts.size() < static_cast<size_t>(r)) ts.resize(static_cast<size_t>(r));
                for (i64 i = 0; i < q; ++i) {
                    double beta = qr.beta[i];
                    if (beta == 0.0) continue;
                    const double* vi = qr.v[static_cast<size_t>(i)].data();
                    i64 size = r - i;
                    i64 nt = 0;
                    for (i64 t = 0; t < size; ++t) {
                        if (vi[t] != 0.0) {
                            vs[nt] = vi[t];
                            ts[nt] = i + t;
                            ++nt;
                        }
                    }
                    using namespace simd;
                    const v2d bv = splat(beta);
                    const i64 ld = X.cols;
                    double* X0 = X.row(0);
                    i64 c = 0;
                    for (; c + 4 <= m; c += 4) {
                        v2d a0 = splat(0.0), a1 = splat(0.0);
                        for (i64 k = 0; k < nt; ++k) {
                            const double* xr = X0 + ts[k] * ld + c;
                            const v2d vk = splat(vs[k]);
                            a0 = a0 + vk * load(xr);
                            a1 = a1 + vk * load(xr + 2);
                        }
                        a0 = a0 * bv;
                        a1 = a1 * bv;
                        for (i64 k = 0; k < nt; ++k) {
                            double* xr = X0 + ts[k] * ld + c;
                            const v2d vk = splat(vs[k]);
                            store(xr, load(xr) - vk * a0);
                            store(xr + 2, load(xr + 2) - vk * a1);
                        }
                    }
                    for (; c + 2 <= m; c += 2) {
                        v2d a0 = splat(0.0);
                        for (i64 k = 0; k < nt; ++k) a0 = a0 + splat(vs[k]) * load(X0 + ts[k] * ld + c);
                        a0 = a0 * bv;
                        for (i64 k = 0; k < nt; ++k) {
                            double* xr = X0 + ts[k] * ld + c;
                            store(xr, load(xr) - splat(vs[k]) * a0);
                        }
                    }
                    for (; c < m; ++c) {
                        double a0 = 0.0;
                        for (i64 k = 0; k < nt; ++k) a0 += vs[k] * X0[ts[k] * ld + c];
                        a0 *= beta;
                        for (i64 k = 0; k < nt; ++k) X0[ts[k] * ld + c] -= vs[k] * a0;
                    }
                }
                done = detail::reg_lstsq_into(X.row(q), nw, m, f0, h.data(), s, y, ws.ls);
            }
        }
        if (!done) {  // B W = (B Q)[:, q:], row by row as (Q^T B_i^T)^T; pivoted, least norm
            if (q == 0) {  // Q = I: B itself
                BW.rows = mb;
                BW.cols = nw;
                BW.a.assign(ls.B.a.begin(), ls.B.a.begin() + mb * nw);
            } else if (keep) {
                // B's rows reflected by the factor's reflections: those kept (BQ, the first bq)
                // and the rest (apply_t's operations, in its order)
                Mat& BQ = keep->BQ;
                i64 from = keep->bq;
                if (from < 0 || BQ.rows != mb || BQ.cols != r) {
                    shape(BQ, mb, r);
                    std::memcpy(BQ.a.data(), ls.B.a.data(), static_cast<size_t>(mb * r) * sizeof(double));
                    from = 0;
                }
                for (i64 i = 0; i < mb; ++i) qr.apply_t_range(BQ.row(i), from, q);
                keep->bq = q;
                shape(BW, mb, nw);  // every entry written below
                for (i64 i = 0; i < mb; ++i)
                    std::memcpy(BW.row(i), BQ.row(i) + q, static_cast<size_t>(nw) * sizeof(double));
            } else {
                qr.reflected_rows_into(ls.B, mb, nw, ws.BT, ws.row, BW);
            }
            detail::ls_mv_into(ls, z.data(), f0);
            for (i64 i = 0; i < mb; ++i) f0[i] = ls.f[i] - f0[i];
            // (B W from B by reflections where q > 0: its pivots judged against B's scale too,
            // its largest column norm; B's column sums into lstsq_into's norms, which it
            // overwrites before it reads them)
            double ref = 0.0;
            if (q > 0) {
                Vec& norms = ws.ls.norms;
                if (norms.size() < static_cast<size_t>(r)) norms.resize(static_cast<size_t>(r));
                col_sq(ls.B.a.data(), ls.B.cols, 0, mb, 0, r, norms.data());
                for (i64 j = 0; j < r; ++j) ref = pymax(ref, norms[j]);
                ref = std::sqrt(ref);
            }
            detail::lstsq_into(BW, f0, y, ws.ls, q == 0 && ls.reg, ref);
        }
        Vec& wy = ws.wy;
        zero_prefix(wy, static_cast<size_t>(r));  // read through its first r entries
        for (i64 j = 0; j < nw; ++j) wy[q + j] = y[j];
        qr.apply(wy.data());  // W y
        for (i64 i = 0; i < r; ++i) z[i] = z[i] + wy[i];
    }
    if (W_out) detail::null_columns(qr, r, q, ws.e, *W_out);
    if (q > 0) {
        Vec& g = ws.g;
        detail::ls_mv_into(ls, z.data(), ws.r);  // B^T (B z - f), as ls_gradient
        for (size_t i = 0; i < ws.r.size(); ++i) ws.r[i] = ws.r[i] - ls.f[i];
        detail::ls_mtv_into(ls, ws.r.data(), g);
        qr.apply_t(g.data());  // Y^T g = (Q^T g)[:q]
        const Mat& R = qr.R;
        for (i64 i = q - 1; i >= 0; --i) {  // R1 u = Y^T g
            double acc = g[i];
            for (i64 k = i + 1; k < q; ++k) acc -= R(i, k) * u[k];
            u[i] = acc / R(i, i);
        }
    }
    return true;
}

// The canonical working set of an answer: the rows with a positive multiplier, by row.
inline i64 canonical_set(const BVec& active, IVec& act_row, IVec& act_side) {
    act_row.clear();
    act_side.clear();
    for (size_t i = 0; i < active.size(); ++i) {
        if (active[i] != 0) {
            act_row.push_back(static_cast<i64>(i));
            act_side.push_back(active[i]);
        }
    }
    return static_cast<i64>(act_row.size());
}

// The size of the terms of the gradient B^T (B z - f): max_i (|B|^T (|B| |z| + |f|))_i (the
// scale of its round-off, as certify_level's stationarity scale; in the units of a
// multiplier times its row's norm).
inline double ls_gradient_size(const LSForm& ls, const Vec& z) {
    i64 mb = ls.B.rows, r = ls.B.cols;
    Vec s(static_cast<size_t>(r), 0.0);
    for (i64 k = 0; k < mb; ++k) {
        const double* bk = ls.B.row(k);
        double t = std::fabs(ls.f[k]);
        for (i64 i = 0; i < r; ++i) t += std::fabs(bk[i]) * std::fabs(z[i]);
        for (i64 i = 0; i < r; ++i) s[i] += std::fabs(bk[i]) * t;
    }
    double big = 0.0;
    for (i64 i = 0; i < r; ++i) big = pymax(big, s[i]);
    return big;
}

// A primal active-set method for min 1/2 |B z - f|^2 s.t. lo <= C z <= hi from a feasible
// z (the independent fallback of a level): equality-constrained least-squares steps
// (eqp_ls), the blocking row added, the most negative multiplier dropped; a row within
// near_dependent of the working set's span never blocks (see below). Returns true
// with (z, rows, sides, u) at a KKT point, false after max_iter or a dependent set.
// A multiplier counts as negative only beyond the round-off of the gradient it balances
// (kDropRoundOff ls_gradient_size, not relative to the largest multiplier alone): where the
// face's minimiser needs no row (every multiplier round-off: 2e-17 to 6e-16 of that size on
// the rank-deficient reproducers of tests/core/test_fragile_levels.py) their signs are
// noise, and dropping one steps back onto the same row at once (alpha = 0), for ever. A
// real one is kept (7e-14 of it on a near-singular level, whose objective dropping it
// lowers by 1e-8 relative).
inline bool primal_active_set(const LSForm& ls, CMatRef C, CVecRef lo, CVecRef hi, Vec& z, IVec& act_row,
                              IVec& act_side, Vec& u, i64 max_iter, double near_dependent = kNearDependent) {
    i64 m = C.rows, r = C.cols;
    act_row.clear();
    act_side.clear();
    BVec in_set(static_cast<size_t>(m), 0);
    Vec norms = detail::row_norms(C);
    Vec zs, us;
    CertScratch ws;       // eqp_ls's storage, and its factor of the working set kept from one
    detail::EqpKeep keep;  // step to the next (the same bits as made anew)
    for (i64 it = 0; it < max_iter; ++it) {
        i64 q = static_cast<i64>(act_row.size());
        Mat W;  // the working set's null space W, made where a row may block (eqp_ls's W_out)
        bool have_w = false;
        if (!eqp_ls(ls, C, lo, hi, act_row, act_side, q, z, zs, us, nullptr, &ws, &keep)) return false;
        Vec p(static_cast<size_t>(r));
        double pn = 0.0;
        for (i64 i = 0; i < r; ++i) {
            p[i] = zs[i] - z[i];
            pn += p[i] * p[i];
        }
        pn = std::sqrt(pn);
        double alpha = 1.0;
        i64 block = -1, block_side = 0;
        for (i64 i = 0; i < m; ++i) {
            if (in_set[i] || norms[i] == 0.0) continue;
            double cp = 0.0, cz = 0.0;
            const double* ci = C.row(i);
            for (i64 j = 0; j < r; ++j) {
                cp += ci[j] * p[j];
                cz += ci[j] * z[j];
            }
            if (std::fabs(cp) <= 1e-14 * norms[i] * pn) continue;
            double a = kInf;
            i64 side = 0;
            if (cp < 0.0 && lo[i] > -kBig) {
                a = pymax(cz - lo[i], 0.0) / -cp;
                side = 1;
            } else if (cp > 0.0 && hi[i] < kBig) {
                a = pymax(hi[i] - cz, 0.0) / cp;
                side = -1;
            }
            if (a < alpha) {
                // A row (nearly) in the span of the working set's normals cannot block: moving in
                // the working set's null space changes it by at most kNearDependent |p| |c|.
                if (!have_w) {
                    detail::null_columns(ws.qr, r, q, ws.e, W);
                    have_w = true;
                }
                double out = 0.0;
                for (i64 j = 0; j < W.cols; ++j) {
                    double acc = 0.0;
                    for (i64 t = 0; t < r; ++t) acc += W(t, j) * ci[t];
                    out += acc * acc;
                }
                if (out <= near_dependent * near_dependent * norms[i] * norms[i]) continue;
                alpha = a;
                block = i;
                block_side = side;
            }
        }
        if (block >= 0) {
            for (i64 i = 0; i < r; ++i) z[i] += alpha * p[i];
            act_row.push_back(block);
            act_side.push_back(block_side);
            in_set[block] = 1;
            continue;
        }
        z = zs;
        // Optimal unless a multiplier is negative (scaled by its row's norm).
        double big = 0.0;
        for (i64 j = 0; j < q; ++j) big = pymax(big, std::fabs(us[j]) * norms[act_row[j]]);
        double worst = -1e-13 * pymax(big, 1e-300);
        i64 drop = -1;
        for (i64 j = 0; j < q; ++j) {
            double v = us[j] * norms[act_row[j]];
            if (v < worst) {
                worst = v;
                drop = j;
            }
        }
        if (drop >= 0 && worst >= -kDropRoundOff * ls_gradient_size(ls, z)) drop = -1;
        if (drop < 0) {
            u = us;
            return true;
        }
        in_set[act_row[drop]] = 0;
        act_row.erase(act_row.begin() + drop);
        act_side.erase(act_side.begin() + drop);
    }
    return false;
}

// The certificate of level (A, b, rho) at x = d + Z z (full space), the working set's rows
// (act_row, act_side; box rows 0..n-1, general rows n..n+p-1) with multipliers u >= 0 of
// their normals side * c_row. Every row of the problem (lb <= x <= ub, G x <= h) is checked
// for primal feasibility, a box row's violation scaled by 1 + |bound|, a general row's by
// |g| + |h|. Stationarity: s = Z^T (A^T (A x - b) + rho x - sum_j u_j side_j c_j), each
// component divided by the larger of |Z|^T (|A|^T (|A| |x| + |b|) + rho |x|) (the size
// of the objective's terms summed) and |Z|^T (|A|^T |A| dx + rho dx), dx_j = max_c |Z_jc|
// max_c (|Z|^T |x|)_c (the round-off a solve in Z leaves in every entry of x, relative to
// the largest null-space coordinate, times H), at least kSizeFloor
// times the largest size of the objective's terms, in
// null-space or full-space coordinates (big); or by the size of the multipliers' terms,
// |Z|^T sum_j u_j |c_j|, where that is larger, counted up to big only (a component the
// objective leaves out carries their cancellation's round-off; nearly dependent active
// rows whose huge multipliers cancel are still not certified); where that fails, the same
// with u = 0 (the objective's own gradient), which, where it holds, certifies the point with
// zero multipliers (dual and complementarity 0). Dual:
// max_j max(0, -u_j) |Z^T c_j| / S, S the largest of those sizes.
// Complementarity: max_j |u_j| |Z^T c_j| / S times row j's scaled distance to its bound.

inline Certificate certify_level(CMatRef A, CVecRef b, double rho, CMatRef Z, const Vec& x, CVecRef lb,
                                 CVecRef ub, CMatRef G, CVecRef h, const IVec& act_row, const IVec& act_side,
                                 const Vec& u, i64 q, bool stationarity = true, CertScratch* scratch = nullptr,
                                 const double* gsq = nullptr, bool z_eye = false, const Mat* C = nullptr,
                                 double zmax = 0.0) {
    // gsq: |G_j|^2 per general row as summed below (row_sq_of), when the caller has them.
    // z_eye: Z is exactly the identity (n, n); its products below are then written without
    // forming them where every term is finite (the same bits, see there).
    // C: the level's rows [Z; G Z] as reduced_rows writes them (n + p, r), when the caller has
    // them: an active row's Z^T c_row is then read there (see the dual measure below).
    if (!scratch) {  // storage of its own, only when the caller keeps none
        CertScratch local;
        return certify_level(A, b, rho, Z, x, lb, ub, G, h, act_row, act_side, u, q, stationarity, &local, gsq,
                             z_eye, C);
    }
    i64 n = static_cast<i64>(x.size()), r = Z.cols, p = G.rows;
    CertScratch& ws = *scratch;
    Certificate cert;
    double primal = 0.0, xmax = 0.0;
    bool relative = true;
    // xmax, two lanes (each lane's largest |x_i| that is not NaN, then the larger: the value
    // pymax's chain over i gives, a NaN never winning); whether any row is violated or an
    // entry is NaN, and whether every entry is finite.
    bool hit = false, xfin = true;
    {
        using namespace simd;
        v2d mv = splat(0.0);
        i64 i = 0;
        for (; i + 2 <= n; i += 2) {
            const v2d ax = vabs(load(x.data() + i));
            mv = ax > mv ? ax : mv;
        }
        xmax = pymax(mv[0], mv[1]);
        for (; i < n; ++i) xmax = pymax(xmax, std::fabs(x[i]));
        // (branch-free, two lanes: a lane's flags as the scalar tests; x * 0.0 is +-0 for a
        // finite x and NaN otherwise, so the lanes' sums of them are 0 exactly when every
        // entry is finite)
        v2i flag = v2i{0, 0};
        v2d z2 = splat(0.0);
        const v2d big = splat(kBig), nbig = splat(-kBig), zero = splat(0.0);
        for (i = 0; i + 2 <= n; i += 2) {
            const v2d xv = load(x.data() + i), l = load(lb.p + i), u = load(ub.p + i);
            flag |= ((l > nbig) & (l - xv > zero)) | ((u < big) & (xv - u > zero)) | (xv != xv);
            z2 += xv * zero;
        }
        hit = (flag[0] | flag[1]) != 0;
        xfin = z2[0] == 0.0 && z2[1] == 0.0;
        for (; i < n; ++i) {
            const double xi = x[i];
            hit |= (lb[i] > -kBig && lb[i] - xi > 0.0) | (ub[i] < kBig && xi - ub[i] > 0.0) | std::isnan(xi);
            xfin &= std::isfinite(xi);
        }
    }
    for (i64 i = 0; hit && i < n; ++i) {
        // Only a row violated (lb - x > 0, x - ub > 0) moves primal (>= +0: a quotient <= 0 or
        // NaN never wins pymax) or relative (its bound kRowsRelative (|bound| + xmax) is >= 0):
        // the same values as taking every row.
        if (lb[i] > -kBig && lb[i] - x[i] > 0.0) {
            primal = pymax(primal, (lb[i] - x[i]) / (1.0 + std::fabs(lb[i])));
            relative = relative && !(lb[i] - x[i] > kRowsRelative * (std::fabs(lb[i]) + xmax));
        }
        if (ub[i] < kBig && x[i] - ub[i] > 0.0) {
            primal = pymax(primal, (x[i] - ub[i]) / (1.0 + std::fabs(ub[i])));
            relative = relative && !(x[i] - ub[i] > kRowsRelative * (std::fabs(ub[i]) + xmax));
        }
        if (std::isnan(x[i])) primal = kInf;
    }
    Vec& gnorm = ws.gnorm;
    Vec& gx = ws.gx;
    shape(gnorm, static_cast<size_t>(p));  // every entry written below
    shape(gx, static_cast<size_t>(p));
    if (gsq) {
        // G x as mv_into sums it (each row in order from +0: the same sums as one row at a
        // time, four or two rows a pass)
        i64 j = 0;
        for (; j + 4 <= p; j += 4)
            dot4(G.row(j), G.row(j + 1), G.row(j + 2), G.row(j + 3), x.data(), n, gx[j], gx[j + 1], gx[j + 2],
                 gx[j + 3]);
        for (; j + 2 <= p; j += 2) dot2(G.row(j), G.row(j + 1), x.data(), n, gx[j], gx[j + 1]);
        for (; j < p; ++j) {
            double acc = 0.0;
            for (i64 i = 0; i < n; ++i) acc += G(j, i) * x[i];
            gx[j] = acc;
        }
    }
    for (i64 j = 0; j < p; ++j) {
        double nn = 0.0, acc = 0.0;
        if (gsq) {
            nn = gsq[j];
            acc = gx[j];
        } else {
            for (i64 i = 0; i < n; ++i) {
                nn += G(j, i) * G(j, i);
                acc += G(j, i) * x[i];
            }
        }
        gnorm[j] = std::sqrt(nn);
        gx[j] = acc;
        if (h[j] < kBig) {
            double scale = gnorm[j] + std::fabs(h[j]);
            double v = gx[j] - h[j];
            // (a row whose |g|^2 or g x overflowed, entries near 1e154: its violation unknown)
            if (v > 0.0 || std::isnan(v))
                primal = pymax(primal, scale > 0.0 && scale < kInf && !std::isnan(v) ? v / scale : kInf);
            relative = relative && !(v > kRowsRelative * (gnorm[j] * xmax + std::fabs(h[j])));
        }
    }
    cert.primal = primal;
    cert.rows_relative = relative;
    if (!stationarity) return cert;
    // Full-space gradient and the sizes of its terms.
    i64 m = A.rows;
    // The round-off a solve in Z leaves in x: its null-space coordinates are at most
    // zx = max_c (|Z|^T |x|)_c, and an error of eps zx in them moves x_j by up to
    // dx_j = zx max_c |Z_jc| (every dof the level moves, small entries of x included; 0 on
    // the dofs the levels above fixed). Each component of H x then carries the round-off of
    // |H| dx (hs = |A|^T |A| dx + rho dx), not only of its own terms |A|^T |A| |x| (a dof the
    // level leaves near 0 while others move).
    Vec& dx = ws.dx;
    dx.resize(static_cast<size_t>(n));  // every entry written below
    bool eye = z_eye && Z.rows == n && r == n;
    bool zfin = eye;  // every entry of Z finite (known where it is the identity; else from zc below)
    double zx_used = 0.0;  // the null-space size dx was made from (zx below)
    if (eye && xfin) {
        // Z = I, x finite: abs_axpy_max's sums zc_c = +0 + ... + |x_c| + ..., every other
        // term 0 |x_i| = +0, are |x_c|; each row's largest |Z_ic| is 1, so dx_i = 1 zx = zx,
        // zx = max_c |x_c| over c < r = n: xmax.
        for (i64 i = 0; i < n; ++i) dx[i] = xmax;
        zx_used = xmax;
    } else {
        Vec& zc = ws.zc;
        zero_prefix(zc, static_cast<size_t>(r));
        for (i64 i = 0; i < n; ++i) {
            const double* zi = Z.row(i);
            dx[i] = abs_axpy_max(zc.data(), std::fabs(x[i]), zi, r);
        }
        double zx = 0.0;
        // (zc_c sums |x_i| |Z_ic| >= 0 over every i: a Z_ic inf or NaN makes it inf or NaN, so
        // zc finite in every entry means Z is)
        zfin = true;
        for (i64 c = 0; c < r; ++c) {
            zx = pymax(zx, zc[c]);
            zfin &= std::isfinite(zc[c]);
        }
        for (i64 i = 0; i < n; ++i) dx[i] *= zx;
        zx_used = zx;
    }
    // Per row i: res_i = A_i x - b_i, size_i = |b_i| + sum |A_ij x_j|, adx_i = sum |A_ij| dx_j
    // (each summed in order of j); the rows with all three +-0 left out (their terms add
    // nothing). bmax = max |b_i| (pymax's value, in any order: no NaN ever wins).
    Vec& rres = ws.rres;
    Vec& rsize = ws.rsize;
    Vec& radx = ws.radx;
    IVec& keep = ws.keep;
    if (rres.size() < static_cast<size_t>(m)) {  // grown, never shrunk; entries written before read
        rres.resize(static_cast<size_t>(m));
        rsize.resize(static_cast<size_t>(m));
        radx.resize(static_cast<size_t>(m));
        keep.resize(static_cast<size_t>(m));
    }
    i64 nk = 0;
    double bmax = 0.0;
    i64 i0 = 0;
    {
        // Two rows a pass, one per lane: each lane's sums are the single row's, in the same
        // order (res from -b_i, size from |b_i|, adx from +0).
        using namespace simd;
        auto keep_lane = [&](i64 i, double res, double size, double adx) {
            if (res == 0.0 && size == 0.0 && adx == 0.0) return;
            rres[nk] = res;
            rsize[nk] = size;
            radx[nk] = adx;
            keep[nk++] = i;
        };
        for (; i0 + 4 <= m; i0 += 4) {  // four rows a pass: two pairs of lanes, as below
            const double* a0 = A.row(i0);
            const double* a1 = A.row(i0 + 1);
            const double* a2 = A.row(i0 + 2);
            const double* a3 = A.row(i0 + 3);
            v2d res = v2d{-b[i0], -b[i0 + 1]}, res2 = v2d{-b[i0 + 2], -b[i0 + 3]};
            v2d size = vabs(v2d{b[i0], b[i0 + 1]}), size2 = vabs(v2d{b[i0 + 2], b[i0 + 3]});
            bmax = pymax(bmax, size[0]);
            bmax = pymax(bmax, size[1]);
            bmax = pymax(bmax, size2[0]);
            bmax = pymax(bmax, size2[1]);
            v2d adx = splat(0.0), adx2 = splat(0.0);
            for (i64 j = 0; j < n; ++j) {
                const v2d xj = splat(x[j]), dj = splat(dx[j]);
                const v2d aj = v2d{a0[j], a1[j]}, aj2 = v2d{a2[j], a3[j]};
                const v2d ax = aj * xj, ax2 = aj2 * xj;
                res += ax;
                res2 += ax2;
                size += vabs(ax);
                size2 += vabs(ax2);
                adx += vabs(aj) * dj;
                adx2 += vabs(aj2) * dj;
            }
            keep_lane(i0, res[0], size[0], adx[0]);
            keep_lane(i0 + 1, res[1], size[1], adx[1]);
            keep_lane(i0 + 2, res2[0], size2[0], adx2[0]);
            keep_lane(i0 + 3, res2[1], size2[1], adx2[1]);
        }
        for (; i0 + 2 <= m; i0 += 2) {
            const double* a0 = A.row(i0);
            const double* a1 = A.row(i0 + 1);
            v2d res = v2d{-b[i0], -b[i0 + 1]};
            v2d size = vabs(v2d{b[i0], b[i0 + 1]});
            bmax = pymax(bmax, size[0]);
            bmax = pymax(bmax, size[1]);
            v2d adx = splat(0.0);
            for (i64 j = 0; j < n; ++j) {
                v2d aj = v2d{a0[j], a1[j]};
                v2d ax = aj * splat(x[j]);
                res += ax;
                size += vabs(ax);
                adx += vabs(aj) * splat(dx[j]);
            }
            for (int l = 0; l < 2; ++l) {
                if (res[l] == 0.0 && size[l] == 0.0 && adx[l] == 0.0) continue;
                rres[nk] = res[l];
                rsize[nk] = size[l];
                radx[nk] = adx[l];
                keep[nk++] = i0 + l;
            }
        }
    }
    for (i64 i = i0; i < m; ++i) {
        const double* ai = A.row(i);
        double res = -b[i], size = std::fabs(b[i]), adx = 0.0;
        bmax = pymax(bmax, size);
        for (i64 j = 0; j < n; ++j) {
            res += ai[j] * x[j];
            size += std::fabs(ai[j] * x[j]);
            adx += std::fabs(ai[j]) * dx[j];
        }
        if (res == 0.0 && size == 0.0 && adx == 0.0) continue;
        rres[nk] = res;
        rsize[nk] = size;
        radx[nk] = adx;
        keep[nk++] = i;
    }
    // v = A^T res + rho x, vs = |A|^T size + |rho x|, hs = |A|^T adx + |rho| dx: per entry j
    // from +0, the kept rows' terms in order of i, then rho's (the operations of adding each
    // row to zeroed vectors in turn); two columns a pass.
    Vec& hs = ws.hs;
    Vec& v = ws.v;
    Vec& vs = ws.vs;
    shape(hs, static_cast<size_t>(n));  // every entry written below
    shape(v, static_cast<size_t>(n));
    shape(vs, static_cast<size_t>(n));
    {
        using namespace simd;
        const v2d rv = splat(rho), arv = splat(std::fabs(rho));
        const double* rowp[64];  // the kept rows (a batch of up to 64)
        i64 j = 0;
        if (nk <= 64) {
            for (i64 t = 0; t < nk; ++t) rowp[t] = A.row(keep[t]);
            for (; j + 4 <= n; j += 4) {  // four columns a pass (each column's operations as below)
                v2d y0 = splat(0.0), s0 = splat(0.0), h0 = splat(0.0);
                v2d y1 = splat(0.0), s1 = splat(0.0), h1 = splat(0.0);
                for (i64 t = 0; t < nk; ++t) {
                    const v2d a0 = load(rowp[t] + j), a1 = load(rowp[t] + j + 2);
                    const v2d x0 = vabs(a0), x1 = vabs(a1);
                    const v2d rr = splat(rres[t]), rs = splat(rsize[t]), rd = splat(radx[t]);
                    y0 = y0 + a0 * rr;
                    y1 = y1 + a1 * rr;
                    s0 = s0 + x0 * rs;
                    s1 = s1 + x1 * rs;
                    h0 = h0 + x0 * rd;
                    h1 = h1 + x1 * rd;
                }
                const v2d xv0 = load(x.data() + j), xv1 = load(x.data() + j + 2);
                y0 += rv * xv0;
                y1 += rv * xv1;
                s0 += vabs(rv * xv0);
                s1 += vabs(rv * xv1);
                h0 += arv * load(dx.data() + j);
                h1 += arv * load(dx.data() + j + 2);
                store(v.data() + j, y0);
                store(v.data() + j + 2, y1);
                store(vs.data() + j, s0);
                store(vs.data() + j + 2, s1);
                store(hs.data() + j, h0);
                store(hs.data() + j + 2, h1);
            }
        }
        for (; j + 2 <= n; j += 2) {
            v2d yv = splat(0.0), sv = splat(0.0), hv = splat(0.0);
            for (i64 t = 0; t < nk; ++t) {
                const v2d av = load(A.row(keep[t]) + j);
                const v2d ax = vabs(av);
                yv = yv + av * splat(rres[t]);
                sv = sv + ax * splat(rsize[t]);
                hv = hv + ax * splat(radx[t]);
            }
            const v2d xv = load(x.data() + j);
            yv += rv * xv;
            sv += vabs(rv * xv);
            hv += arv * load(dx.data() + j);
            store(v.data() + j, yv);
            store(vs.data() + j, sv);
            store(hs.data() + j, hv);
        }
        for (; j < n; ++j) {
            double yv = 0.0, sv = 0.0, hv = 0.0;
            for (i64 t = 0; t < nk; ++t) {
                const double a = A(keep[t], j);
                yv += a * rres[t];
                sv += std::fabs(a) * rsize[t];
                hv += std::fabs(a) * radx[t];
            }
            yv += rho * x[j];
            sv += std::fabs(rho * x[j]);
            hv += std::fabs(rho) * dx[j];
            v[j] = yv;
            vs[j] = sv;
            hs[j] = hv;
        }
    }
    // ms: the sizes of the multipliers' terms, |u_k c_k| summed per entry (for the scale below,
    // where they count up to the level's largest objective size only).
    Vec& ms = ws.ms;
    Vec& v0 = ws.v0;  // the objective's own gradient, before the multipliers' terms
    if (q > 0) {
        zero_fill(ms, static_cast<size_t>(n));
        v0.assign(v.begin(), v.begin() + n);
    }
    for (i64 k = 0; k < q; ++k) {
        double lam = u[k] * static_cast<double>(act_side[k]);
        i64 row = act_row[k];
        if (row < n) {
            v[row] -= lam;
            ms[row] += std::fabs(lam);
        } else {
            for (i64 j = 0; j < n; ++j) {
                const double t = lam * G(row - n, j);
                v[j] -= t;
                ms[j] += std::fabs(t);
            }
        }
    }
    double S = 0.0;
    // sc = Z^T v, ssc = |Z|^T vs, each component summed over i in order (row by row).
    Vec& hsc = ws.hsc;
    Vec& sc = ws.sc;
    Vec& ssc = ws.ssc;
    if (sc.size() < static_cast<size_t>(r)) {  // grown, never shrunk: read through r entries
        sc.resize(static_cast<size_t>(r));
        ssc.resize(static_cast<size_t>(r));
        hsc.resize(static_cast<size_t>(r));
    }
    bool eye_sums = eye;
    if (eye_sums) {  // v, vs, hs all finite (their entries times 0.0 sum to 0: see above)
        using namespace simd;
        v2d z2 = splat(0.0);
        const v2d zero = splat(0.0);
        i64 j = 0;
        for (; j + 2 <= n; j += 2)
            z2 += (load(v.data() + j) * zero + load(vs.data() + j) * zero) + load(hs.data() + j) * zero;
        double z1 = z2[0] + z2[1];
        for (; j < n; ++j) z1 += (v[j] * 0.0 + vs[j] * 0.0) + hs[j] * 0.0;
        eye_sums = z1 == 0.0;
    }
    if (eye_sums) {
        // Z = I, every term finite: axpy3_rows' sum for component c is +0 plus v_c and
        // terms 0 v_i = +-0, which is v_c + 0.0 (a -0 made +0, as adding +0 first does);
        // the same for vs and hs.
        for (i64 c = 0; c < r; ++c) {
            sc[c] = v[c] + 0.0;
            ssc[c] = vs[c] + 0.0;
            hsc[c] = hs[c] + 0.0;
        }
    } else {
        zero_small(sc.data(), static_cast<size_t>(r));
        zero_small(ssc.data(), static_cast<size_t>(r));
        zero_small(hsc.data(), static_cast<size_t>(r));
        axpy3_rows(sc.data(), ssc.data(), hsc.data(), Z, v.data(), vs.data(), hs.data());
    }
    {
        // S = max_c ssc_c, two lanes (the value of pymax's chain: no NaN ever wins)
        using namespace simd;
        v2d mv = splat(0.0);
        i64 c = 0;
        for (; c + 2 <= r; c += 2) {
            const v2d sv = load(ssc.data() + c);
            mv = sv > mv ? sv : mv;
        }
        S = pymax(mv[0], mv[1]);
        for (; c < r; ++c) S = pymax(S, ssc[c]);
    }
    // A component whose own terms are tiny is measured against kSizeFloor S instead (the
    // round-off the other components feed into it), S at least the largest full-space size:
    // an entry of Z that is round-off where it is exactly 0 (a dof the levels above pinned)
    // feeds eps |v| into every component, which sizes in null-space coordinates alone do not
    // see when the level's whole gradient lies outside Z (a task on pinned dofs only).
    // (With eye_sums every vs_i is finite and equals ssc_i: none is larger than S.)
    double big = S;
    if (!eye_sums)
        for (i64 i = 0; i < n; ++i) big = pymax(big, vs[i]);
    // The regularisation's rows sqrt(rho) I meet b in the least-squares solve (Householder
    // mixes them): its round-off, eps sqrt(rho) |b|, is there even where A is zero (a task
    // no dof moves), which the sizes above do not see.
    if (rho > 0.0) big = pymax(big, std::sqrt(rho) * bmax);
    // The multipliers' terms in each component, msc = |Z|^T ms (summed as ssc is), count in
    // its scale up to big only: a component the objective leaves out (a dof only the active
    // rows hold) carries the round-off of their cancellation, eps |u| |c|, which the floor
    // kSizeFloor big does not see; capped at big, nearly dependent active rows whose huge
    // multipliers cancel to their own round-off still prove nothing (no component's scale
    // exceeds the level's largest objective size).
    Vec& msc = ws.msc;
    if (q > 0) {
        if (msc.size() < static_cast<size_t>(r)) msc.resize(static_cast<size_t>(r));
        if (eye) {
            for (i64 c = 0; c < r; ++c) msc[c] = ms[c];
        } else {
            zero_small(msc.data(), static_cast<size_t>(r));
            for (i64 i = 0; i < n; ++i) {
                const double* zi = Z.row(i);
                const double mi = ms[i];
                if (mi == 0.0) continue;
                for (i64 c = 0; c < r; ++c) msc[c] += std::fabs(zi[c]) * mi;
            }
        }
    }
    // floor: the size the floor kSizeFloor takes its share of (big, or the data's below)
    double floor = big;
    double size_floor = kSizeFloor;  // (raised below for a damped level where the test fails)
    auto stationarity_at = [&]() {
        double st = 0.0;
        for (i64 c = 0; c < r; ++c) {
            double ss = pymax(pymax(ssc[c], hsc[c]), size_floor * floor);
            if (q > 0) ss = pymax(ss, pymin(msc[c], big));
            // A component or its scale that overflowed (rows near 1e154: their products past
            // the double range) proves nothing: |sc| / inf would read 0, and pymax drops a NaN.
            if (!(ss < kInf) || std::isnan(sc[c])) st = kInf;
            else if (ss > 0.0) st = pymax(st, std::fabs(sc[c]) / ss);
            else if (sc[c] != 0.0) st = kInf;
        }
        return st;
    };
    double stat = stationarity_at();
    if (!(stat <= kCertify)) {
        // A level whose gradient vanishes at its answer to within its terms' round-off, where
        // those terms are themselves round-off (rows that no dof moves, their targets out of
        // reach; the rows that do move met exactly): the least-squares solve mixes every row
        // of B and f (Householder), so eps max|A| max|b| reaches every component whatever the
        // terms that survive in it. The floor takes that size too (only where the test failed
        // on the others: every certificate that held is the same).
        double amax = 0.0;
        for (i64 i = 0; i < m; ++i) {
            const double* ai = A.row(i);
            for (i64 j = 0; j < n; ++j) amax = pymax(amax, std::fabs(ai[j]));
        }
        if (amax * bmax > floor) {
            floor = amax * bmax;
            stat = stationarity_at();
        }
    }
    if (!(stat <= kCertify) && zmax > zx_used && zx_used > 0.0 && std::isfinite(zmax)) {
        // A step that cancels the point it started from (x = d + Z z, |z| far above |Z^T x|:
        // a level whose optimum is near 0, the levels above left d away from it) carries the
        // round-off of its null-space coordinates z, not of x's own: the same term hs with
        // zx = max |z| (dx, hs and hsc are linear in zx), where the test failed on the others.
        const double scale = zmax / zx_used;
        for (i64 c = 0; c < r; ++c) hsc[c] *= scale;
        stat = stationarity_at();
    }
    if (!(stat <= kCertify) && rho > 0.0) {
        // A damped level's solve (B = [A Z; sqrt(rho) I]) leaves a round-off of about
        // eps cond(B) in every null-space coordinate, cond(B) at most sqrt(1 + |A|_F^2 / rho)
        // (its least singular value is at least sqrt(rho)), which H feeds into every component
        // of the gradient: a component whose own terms are tiny carries up to
        // kDampedRoundOff eps cond(B) of the largest size, above the fixed floor where cond(B)
        // is above about 10 (erd Tiago dual, damping 1e-6: a free component at 4.4e-14 of a
        // gradient of size 0.5, cond(B) about 3e3, left a level kept_previous 1e-6 above its
        // optimum). Only where the test failed on the others: every certificate that held is
        // the same.
        double af2 = 0.0;
        for (i64 i = 0; i < m; ++i) af2 += dot(A.row(i), A.row(i), n);
        const double cond = std::sqrt(1.0 + af2 / rho);
        const double damped = kDampedRoundOff * 2.220446049250313e-16 * cond / kCertify;
        if (std::isfinite(damped) && damped > size_floor) {
            size_floor = pymin(damped, kDampedFloorMax);
            stat = stationarity_at();
        }
    }
    // No multipliers at all: where the candidate's leave stationarity failing, the same point
    // with u = 0, the objective's own gradient against the same scale without the
    // multipliers' terms. Where that holds, the point is a KKT point with zero multipliers
    // (dual and complementarity 0): a level whose gradient vanishes at the point to its
    // round-off (an objective at its minimum, 0 on a flat level; degenerate rows active with
    // round-off multipliers, whose terms are then the only ones in a component the objective
    // leaves out).
    if (q > 0 && !(stat <= kCertify)) {
        double stat0 = 0.0;
        for (i64 c = 0; c < r; ++c) {
            double s0 = 0.0;
            if (eye) {
                s0 = v0[c];
            } else {
                for (i64 i = 0; i < n; ++i) s0 += Z(i, c) * v0[i];
            }
            double ss = pymax(pymax(ssc[c], hsc[c]), size_floor * floor);
            if (!(ss < kInf) || std::isnan(s0)) stat0 = kInf;  // (an overflow, as above)
            else if (ss > 0.0) stat0 = pymax(stat0, std::fabs(s0) / ss);
            else if (s0 != 0.0) stat0 = kInf;
        }
        if (stat0 <= kCertify) {
            cert.stationarity = stat0;
            cert.dual = 0.0;
            cert.complementarity = 0.0;
            return cert;
        }
    }
    cert.stationarity = stat;
    double dual = 0.0, comp = 0.0;
    Vec& zg = ws.zg;
    if (zg.size() < static_cast<size_t>(r)) zg.resize(static_cast<size_t>(r));  // entries 0..r-1 zeroed before each use
    // C's rows, where given with Z finite: row i < n is Z's row i (copied), row n + j is G Z's
    // row j, +0 plus G(j, i) Z(i, c) over the nonzero G(j, i) in i order (mm_into, or its form
    // for Z = I: the same values) - the sums below but for their terms G(j, i) Z(i, c) with
    // G(j, i) = +-0, which with Z finite are +-0 and leave a sum from +0 as it is (never -0):
    // the same Z^T c_row, bit for bit, without the n axpy passes per active general row.
    const bool rows_c = C != nullptr && zfin && C->rows == n + p && C->cols == r;
    for (i64 k = 0; k < q; ++k) {
        i64 row = act_row[k];
        double zn = 0.0;  // |Z^T c_row|
        if (rows_c) {
            const double* cr = C->row(row);
            for (i64 c = 0; c < r; ++c) zn += cr[c] * cr[c];
        } else if (row < n) {
            const double* zr = Z.row(row);
            for (i64 c = 0; c < r; ++c) zn += zr[c] * zr[c];
        } else {
            // Z^T g, each component summed over i in order (row by row of Z).
            zero_small(zg.data(), static_cast<size_t>(r));
            const double* g = G.row(row - n);
            for (i64 i = 0; i < n; ++i) axpy(zg.data(), g[i], Z.row(i), r);
            for (i64 c = 0; c < r; ++c) zn += zg[c] * zg[c];
        }
        zn = std::sqrt(zn);
        double um = S > 0.0 ? u[k] * zn / S : (u[k] == 0.0 ? 0.0 : kInf);
        dual = pymax(dual, -um);
        double slack;
        if (row < n) {
            double bound = act_side[k] > 0 ? lb[row] : ub[row];
            slack = std::fabs(x[row] - bound) / (1.0 + std::fabs(bound));
        } else {
            double scale = gnorm[row - n] + std::fabs(h[row - n]);
            slack = scale > 0.0 ? std::fabs(gx[row - n] - h[row - n]) / scale : 0.0;
        }
        comp = pymax(comp, std::fabs(um) * slack);
    }
    cert.dual = dual;
    cert.complementarity = comp;
    return cert;
}

}  // namespace qpik::core
