// The whole IGM solve of one frame target (named for Python in qpik/igm/kernels.py;
// recorded answers pin its bits): per iteration, the damped least-squares step of the pose
// error under box bounds (joint limits), solved exactly by box_qp, with the trust region,
// the damping law fading with the error, backtracking (a step that increases the error is
// halved, up to BACKTRACKS times), stall detection (a window without progress, or a step
// blocked by the limits or the damping: residual above BLOCKED |b|, while the score is above
// NEAR_TARGET) and restarts from a
// deterministic random stream (SplitMix64): odd restarts draw from the central
// RESTART_SPREAD of the restart box, even ones from all of it.
#pragma once

#include <time.h>

#include <memory>
#include <type_traits>

#include "../common.hpp"
#include "../core/linalg.hpp"
#include "../model/chain.hpp"
#include "../model/so3.hpp"
#include "box_qp.hpp"

namespace qpik::igm {

using model::Chain;

// Reasons (codes) returned by igm_solve; names in qpik.converge.REASONS.
constexpr i64 CONVERGED = 0;
constexpr i64 MAX_ITERS = 1;
constexpr i64 TIME_BUDGET = 2;
constexpr i64 STALLED = 3;
constexpr i64 AT_LIMIT = 4;
constexpr i64 SINGULAR = 5;
constexpr i64 UNREACHABLE = 6;
constexpr int BACKTRACKS = 3;
constexpr double PROGRESS = 0.95;
constexpr i64 CLOCK_EVERY = 8;
constexpr double RESTART_SPREAD = 0.6;
constexpr double BLOCKED = 0.9;
// A blocked step ends the attempt only while its score (ep / tol_p + eo / tol_o) is above
// this: within it the window decides. A target on the workspace's boundary (an elbow straight,
// sigma_min ~ 1e-4 at the answer) is reached by steps that the damping slows to a few percent
// each: the early end left such an attempt at 1.3 - 2.5 times the tolerance, every time, and
// erd:kinova used its 5 ms on hundreds of restarts.
constexpr double NEAR_TARGET = 10.0;

// ------------------------------------------------------------------------- RNG, clock
// A uniform draw in [0, 1) from the SplitMix64 stream state (advanced in place).
inline double uniform(std::uint64_t& state) {
    state += 0x9E3779B97F4A7C15ULL;
    std::uint64_t z = state;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    z = z ^ (z >> 31);
    return static_cast<double>(z >> 11) * (1.0 / 9007199254740992.0);
}

// Python's time.perf_counter() on Linux: CLOCK_MONOTONIC, as CPython converts it.
inline double now() {
    timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    i64 ns = static_cast<i64>(ts.tv_sec) * 1000000000LL + static_cast<i64>(ts.tv_nsec);
    return static_cast<double>(ns) / 1e9;
}

// ------------------------------------------------------- smallest singular value
// Smallest eigenvalue of the symmetric G[:n, :n] by cyclic Jacobi (G overwritten): the
// general size (n > 6, only through the binding: a level has at most 6 rows).
inline double jacobi_smallest_eigenvalue(MatRef G, i64 n) {
    for (int sweep = 0; sweep < 50; ++sweep) {
        double off = 0.0;
        double diag = 0.0;
        for (i64 i = 0; i < n; ++i) {
            diag += G(i, i) * G(i, i);
            for (i64 j = i + 1; j < n; ++j) off += G(i, j) * G(i, j);
        }
        if (off <= 1e-30 * diag || off == 0.0) break;
        for (i64 p = 0; p < n - 1; ++p) {
            for (i64 q = p + 1; q < n; ++q) {
                if (G(p, q) == 0.0) continue;
                double theta = (G(q, q) - G(p, p)) / (2.0 * G(p, q));
                double t = (theta >= 0.0 ? 1.0 : -1.0) / (std::fabs(theta) + std::sqrt(theta * theta + 1.0));
                double c = 1.0 / std::sqrt(t * t + 1.0);
                double s = t * c;
                for (i64 k = 0; k < n; ++k) {
                    double gkp = G(k, p);
                    double gkq = G(k, q);
                    G(k, p) = c * gkp - s * gkq;
                    G(k, q) = s * gkp + c * gkq;
                }
                for (i64 k = 0; k < n; ++k) {
                    double gpk = G(p, k);
                    double gqk = G(q, k);
                    G(p, k) = c * gpk - s * gqk;
                    G(q, k) = s * gpk + c * gqk;
                }
            }
        }
    }
    double smallest = G(0, 0);
    for (i64 i = 1; i < n; ++i)
        if (G(i, i) < smallest) smallest = G(i, i);
    return smallest;
}

// smallest_eigenvalue's body, n an i64 or a compile-time size (std::integral_constant: the
// same operations in the same order, so the same bits, with the loops unrolled).
// Smallest eigenvalue of the symmetric G[:n, :n] (G overwritten): Householder reduction to
// tridiagonal form, then the implicit QL iteration with Wilkinson's shift on its
// eigenvalues (EISPACK's tql1); n <= 6 in fixed-size scratch, else cyclic Jacobi. Both are
// backward stable: each eigenvalue to about eps |G| (absolute).
template <class Size>
inline double smallest_eigenvalue_sized(MatRef G, Size n) {
    constexpr i64 N = 6;
    if (n <= 0) return kInf;
    double total = 0.0;
    for (i64 i = 0; i < n; ++i)
        for (i64 j = 0; j < n; ++j) total += std::fabs(G(i, j));
    if (n > N || !(total < kInf)) return jacobi_smallest_eigenvalue(G, n);  // NaN, inf: as before
    double d[N], e[N], v[N], w[N];
    // Householder: column k's entries below the subdiagonal reflected away, G <- H G H on
    // the trailing block (symmetric rank-2 update).
    for (i64 k = 0; k + 2 < n; ++k) {
        double scale = 0.0;
        for (i64 i = k + 1; i < n; ++i) scale += std::fabs(G(i, k));
        if (!(scale > 0.0)) {  // already reduced
            e[k] = 0.0;
            continue;
        }
        double inv_scale = 1.0 / scale;
        double h = 0.0;
        for (i64 i = k + 1; i < n; ++i) {
            v[i] = G(i, k) * inv_scale;
            h += v[i] * v[i];
        }
        double f = v[k + 1];
        double g = f >= 0.0 ? -std::sqrt(h) : std::sqrt(h);
        e[k] = scale * g;
        h -= f * g;  // v^T v / 2, v = x - g e1
        v[k + 1] = f - g;
        double inv_h = 1.0 / h;
        double vp = 0.0;
        for (i64 i = k + 1; i < n; ++i) {
            double s = 0.0;
            for (i64 j = k + 1; j < n; ++j) s += G(i, j) * v[j];
            w[i] = s * inv_h;  // p = G v / h
            vp += v[i] * w[i];
        }
        double K = 0.5 * vp * inv_h;
        for (i64 i = k + 1; i < n; ++i) w[i] -= K * v[i];  // w = p - K v
        for (i64 i = k + 1; i < n; ++i) {
            for (i64 j = k + 1; j <= i; ++j) {
                double x = G(i, j) - (v[i] * w[j] + w[i] * v[j]);
                G(i, j) = x;
                G(j, i) = x;
            }
        }
    }
    for (i64 i = 0; i < n; ++i) d[i] = G(i, i);
    if (n >= 2) e[n - 2] = G(n - 1, n - 2);
    e[n - 1] = 0.0;
    // Implicit QL: e[i] couples d[i] and d[i + 1]; an off-diagonal negligible beside its two
    // diagonals splits the matrix. At most 60 iterations per eigenvalue (never reached on
    // finite input; NaN input ends there).
    for (i64 l = 0; l < n; ++l) {
        for (int iter = 0; iter < 60; ++iter) {
            i64 m = l;
            for (; m + 1 < n; ++m) {
                double dd = std::fabs(d[m]) + std::fabs(d[m + 1]);
                if (!(std::fabs(e[m]) > 2.220446049250313e-16 * dd)) break;
            }
            if (m == l) break;
            double g = (d[l + 1] - d[l]) / (2.0 * e[l]);
            double r = std::sqrt(g * g + 1.0);
            g = d[m] - d[l] + e[l] / (g + (g >= 0.0 ? r : -r));
            double s = 1.0, c = 1.0, p = 0.0;
            bool split = false;
            for (i64 i = m - 1; i >= l; --i) {
                double f = s * e[i];
                double b = c * e[i];
                r = std::sqrt(f * f + g * g);
                e[i + 1] = r;
                if (r == 0.0) {  // underflow: d[i + 1] is an eigenvalue of the rest
                    d[i + 1] -= p;
                    e[m] = 0.0;
                    split = true;
                    break;
                }
                double inv_r = 1.0 / r;
                s = f * inv_r;
                c = g * inv_r;
                g = d[i + 1] - p;
                r = (d[i] - g) * s + 2.0 * c * b;
                p = s * r;
                d[i + 1] = g + p;
                g = c * r - b;
            }
            if (split) continue;
            d[l] -= p;
            e[l] = g;
            e[m] = 0.0;
        }
    }
    double smallest = d[0];
    for (i64 i = 1; i < n; ++i)
        if (d[i] < smallest) smallest = d[i];
    return smallest;
}

// The smallest eigenvalue of a Gram matrix G[:N, :N] (symmetric positive semidefinite, N <= 6;
// G left unchanged), clamped at 0, by Laguerre's iteration on its characteristic polynomial
// from x = 0: each step factors G - x I = L L^T (Cholesky) and, from S1 = tr (G - x I)^-1
// = |L^-1|_F^2 and S2 = |(G - x I)^-1|_F^2, takes x += N / (S1 + sqrt((N - 1)(N S2 - S1^2))).
// Every root real, the iterates rise monotonically to the smallest one (cubically near it);
// the loop ends when a step is below round-off (4 eps tr G), or when G - x I no longer
// factors (x has reached it). A G that does not factor at 0 (numerically singular) gives 0.
// Accuracy: a backward-stable factorization per step, so the answer is within a few eps |G|
// of the eigenvalue (tests/model/test_model_igm.py asks 64 eps |G| against LAPACK). Cost on
// the IGM's 6 x 6 levels: 3 to 4 factorizations, about 1.8k instructions (Householder + QL,
// smallest_eigenvalue: about 4.6k). Returns -1 (the caller then runs smallest_eigenvalue) on
// non-finite input or after 40 steps (never seen).
template <int N>
inline double laguerre_smallest_eigenvalue(CMatRef G) {
    double g[N * N], L[N * N], W[N * N], inv[N];
    double trace = 0.0;
    for (int i = 0; i < N; ++i) {
#pragma GCC unroll 8
        for (int j = 0; j < N; ++j) g[i * N + j] = G(i, j);
        trace += g[i * N + i];
    }
    if (!(trace > 0.0) || !(trace < kInf)) return trace == 0.0 ? 0.0 : -1.0;
    const double tiny = 4.0 * 2.220446049250313e-16 * trace;
    double x = 0.0;
    for (int step = 0; step < 40; ++step) {
        // L L^T = G - x I (inv: 1 / diag L)
#pragma GCC unroll 8
        for (int j = 0; j < N; ++j) {
            double d = g[j * N + j] - x;
#pragma GCC unroll 8
            for (int k = 0; k < j; ++k) d -= L[j * N + k] * L[j * N + k];
            if (!(d > 0.0)) return x;  // x at (or, by round-off, past) the smallest eigenvalue
            d = std::sqrt(d);
            double r = 1.0 / d;
            inv[j] = r;
#pragma GCC unroll 8
            for (int i = j + 1; i < N; ++i) {
                double t = g[i * N + j];
#pragma GCC unroll 8
                for (int k = 0; k < j; ++k) t -= L[i * N + k] * L[j * N + k];
                L[i * N + j] = t * r;
            }
        }
        // W = L^-1 (lower triangular), column by column
#pragma GCC unroll 8
        for (int c = 0; c < N; ++c) {
            W[c * N + c] = inv[c];
#pragma GCC unroll 8
            for (int i = c + 1; i < N; ++i) {
                double t = 0.0;
#pragma GCC unroll 8
                for (int k = c; k < i; ++k) t -= L[i * N + k] * W[k * N + c];
                W[i * N + c] = t * inv[i];
            }
        }
        // (G - x I)^-1 = W^T W: S1 its trace, S2 its squared Frobenius norm
        double s1 = 0.0, s2 = 0.0;
#pragma GCC unroll 8
        for (int a = 0; a < N; ++a) {
#pragma GCC unroll 8
            for (int b = a; b < N; ++b) {
                double m = 0.0;
#pragma GCC unroll 8
                for (int k = b; k < N; ++k) m += W[k * N + a] * W[k * N + b];
                s1 += a == b ? m : 0.0;
                s2 += (a == b ? 1.0 : 2.0) * m * m;
            }
        }
        constexpr double n = N;
        double disc = (n - 1.0) * (n * s2 - s1 * s1);
        double dx = n / (s1 + std::sqrt(disc > 0.0 ? disc : 0.0));
        if (!(dx < kInf)) return -1.0;
        x += dx;
        if (dx <= tiny) return x;
    }
    return -1.0;
}

// Smallest eigenvalue of the symmetric G[:n, :n] (G overwritten): smallest_eigenvalue_sized,
// its loops unrolled for the usual sizes (6: a pose level, 3: a position level).
inline double smallest_eigenvalue(MatRef G, i64 n) {
    if (n == 6) return smallest_eigenvalue_sized(G, std::integral_constant<i64, 6>{});
    if (n == 3) return smallest_eigenvalue_sized(G, std::integral_constant<i64, 3>{});
    return smallest_eigenvalue_sized(G, n);
}

// The smallest eigenvalue of a Gram matrix G[:n, :n], clamped at 0 (what the damping law
// reads: sigma_min^2): laguerre_smallest_eigenvalue for n <= 6 (G unchanged), else (or
// should it not settle) smallest_eigenvalue (G overwritten).
inline double gram_smallest_eigenvalue(MatRef G, i64 n) {
    double e = -1.0;
    switch (n) {
        case 1: e = laguerre_smallest_eigenvalue<1>(G); break;
        case 2: e = laguerre_smallest_eigenvalue<2>(G); break;
        case 3: e = laguerre_smallest_eigenvalue<3>(G); break;
        case 4: e = laguerre_smallest_eigenvalue<4>(G); break;
        case 5: e = laguerre_smallest_eigenvalue<5>(G); break;
        case 6: e = laguerre_smallest_eigenvalue<6>(G); break;
        default: break;
    }
    if (e >= 0.0) return e;
    e = smallest_eigenvalue(G, n);
    return 0.0 > e ? 0.0 : e;
}

// The min(r, nv)-th singular value of A[:m], r its rows not identically zero, from the
// smaller Gram matrix built in the scratch G. With threshold > 0, inf when that value is
// at least threshold (one Cholesky of G - threshold^2 I decides). Scratch: rows (m,), L.
// Not core::min_singular (one-sided Jacobi on a copy it allocates, for the cascade's
// certificate): this one runs every IGM iteration, so it allocates nothing, skips zero
// rows, takes either Gram side (r > nv too), and answers "at least threshold" with one
// Cholesky instead of computing the value.
inline double smallest_singular_value_in(CMatRef A, i64 m, i64 nv, MatRef G, double threshold, i64* rows,
                                         MatRef L) {
    i64 r = 0;
    for (i64 i = 0; i < m; ++i) {
        for (i64 k = 0; k < nv; ++k) {
            if (A(i, k) != 0.0) {
                rows[r] = i;
                r += 1;
                break;
            }
        }
    }
    if (r == 0) return kInf;
    bool by_rows = r <= nv;
    i64 n = by_rows ? r : nv;
    i64 inner = by_rows ? nv : r;
    for (i64 a = 0; a < n; ++a) {
        for (i64 c = a; c < n; ++c) {
            double s = 0.0;
            if (by_rows) {
                const double* ra = A.row(rows[a]);
                const double* rc = A.row(rows[c]);
                for (i64 k = 0; k < inner; ++k) s += ra[k] * rc[k];
            } else {
                for (i64 k = 0; k < inner; ++k) s += A(rows[k], a) * A(rows[k], c);
            }
            G(a, c) = s;
            G(c, a) = s;
        }
    }
    if (threshold > 0.0 && core::cholesky_into(G, n, threshold * threshold, L)) return kInf;
    return std::sqrt(gram_smallest_eigenvalue(G, n));
}

// The cascade's rank rule (project_level, qpik/_cpp/core/cascade.hpp): directions of a level
// whose singular values are at or below rank_tol max(1, sigma_max) are structural zeros, not
// a singularity, and the damping law reads the least singular value above that cut. The
// Gram matrix cannot tell them apart (its least eigenvalue carries eps sigma_max^2 of
// round-off: a structural zero's 1e-17 reads as 1e-8), so where it gave a sigma below the
// damping threshold and within 1e-7 max(1, |A|_F) (a larger one leaves every singular value
// above the cut), A[:m]'s vectors (rows, or columns where m > cols; p <= 6 of them) are
// orthogonalised in turn, largest remaining first, twice each (Gram-Schmidt with pivoting
// and reorthogonalisation: A's vectors = Lo W, Lo lower triangular, W orthonormal rows): a
// vector's remainder then has the absolute accuracy eps |A|, and the remainders at or below
// the cut (rank_tol max(1, |A|_F), within sqrt(p) of sigma_max's; no singular value falls in
// between where it is a structural zero's 1e-17 or a singularity's 1e-7 and more) are the
// structural zeros. Where there are some (a UR5e's frame rows at q = 0: 3.7e-17 of 2.1; a
// Jaco2's at mid-range: three), the least singular value of the kept columns of Lo is
// returned (the least above the cut; inf where none is kept); else sigma as given, the same
// bits as without this. rank_tol <= 0, or more than 6 vectors: sigma as given.
inline double structural_sigma(CMatRef A, i64 m, double sigma, double rank_tol) {
    if (!(rank_tol > 0.0)) return sigma;
    const i64 nc = A.cols;
    double frob2 = 0.0;
    for (i64 i = 0; i < m; ++i)
        for (i64 k = 0; k < nc; ++k) frob2 += A(i, k) * A(i, k);
    if (!(frob2 > 0.0) || !(frob2 < kInf)) return sigma;
    const double scale = core::pymax(1.0, std::sqrt(frob2));
    if (sigma > core::pymax(1e-7, 10.0 * rank_tol) * scale) return sigma;
    const bool by_rows = m <= nc;
    const i64 p = by_rows ? m : nc, len = by_rows ? nc : m;
    if (p > 6 || len > 64) return sigma;
    double V[6 * 64], Lo[36] = {}, W[6 * 64];
    for (i64 i = 0; i < p; ++i)
        for (i64 k = 0; k < len; ++k) V[i * len + k] = by_rows ? A(i, k) : A(k, i);
    // Remainders R = V (orthogonalised in place); Lo[i][j] = <V_i, W_j> summed over both passes
    bool used[6] = {};
    const double cut = rank_tol * scale;
    i64 kept = 0;
    for (i64 step = 0; step < p; ++step) {
        i64 best = -1;
        double best2 = -1.0;
        for (i64 i = 0; i < p; ++i) {
            if (used[i]) continue;
            double n2 = 0.0;
            for (i64 k = 0; k < len; ++k) n2 += V[i * len + k] * V[i * len + k];
            if (n2 > best2) {
                best2 = n2;
                best = i;
            }
        }
        used[best] = true;
        const double norm = std::sqrt(best2);
        if (!(norm > cut)) break;  // every remainder left is at most this: structural zeros
        double* w = W + step * len;
        for (i64 k = 0; k < len; ++k) w[k] = V[best * len + k] / norm;
        Lo[best * 6 + step] = norm;
        for (int pass = 0; pass < 2; ++pass) {
            for (i64 i = 0; i < p; ++i) {
                if (used[i]) continue;
                double t = 0.0;
                for (i64 k = 0; k < len; ++k) t += V[i * len + k] * w[k];
                for (i64 k = 0; k < len; ++k) V[i * len + k] -= t * w[k];
                Lo[i * 6 + step] += t;
            }
        }
        kept = step + 1;
    }
    if (kept == p) return sigma;  // no structural zero: as given
    if (kept == 0) return kInf;
    // The least singular value of Lo's kept columns (p x kept): of M = their Gram matrix
    double M[36];
    for (i64 a = 0; a < kept; ++a) {
        for (i64 c = a; c < kept; ++c) {
            double t = 0.0;
            for (i64 i = 0; i < p; ++i) t += Lo[i * 6 + a] * Lo[i * 6 + c];
            M[a * kept + c] = M[c * kept + a] = t;
        }
    }
    return std::sqrt(core::pymax(0.0, gram_smallest_eigenvalue(MatRef(M, kept, kept), kept)));
}

// ------------------------------------------------------------------------ the IGM
struct Target {
    const double* p;  // (3,)
    const double* R;  // (3, 3)
    bool has_rot;
};

struct Settings {
    CMatRef bounds;  // (4, nq)
    const double* options;
    const i64* int_options;
    double deadline;
};

struct Record {
    double* path;  // (2, n, nq)
    double* hist;  // (2, n, 3)
    i64 n;         // max_iters + 1
    i64 nq;
    double* path_at(i64 slot, i64 index) const { return path + (slot * n + index) * nq; }
    double* hist_at(i64 slot, i64 index) const { return hist + (slot * n + index) * 3; }
};

// Scratch of the kinematics and of the step.
struct Work {
    model::FastChain chain;
    Mat axes, anchors;
    double position[3], rotation[9];
    Mat jac;
    double error[6] = {0, 0, 0, 0, 0, 0};
    double rot_err[3] = {0, 0, 0};
    double M[9];
    Work(const Chain& c, i64 nq) : chain(model::fast_chain(c)), axes(c.njnt, 3), anchors(c.njnt, 3), jac(6, nq) {}
};

struct QPWork {
    Mat A;
    Vec b;
    double Jinv[9];
    Mat H;
    Vec g, lb, ub, dx, q_base;
    Mat gram;
    IVec rows;
    Mat L;
    Mat G;  // (6, 6): the level's Gram matrix A A^T (rows m <= 6)
    Vec y;  // (6,)
    BoxQPScratch box;
    QPWork(i64 nc, i64 nq)
        : A(6, nc), b(6), H(nc, nc), g(static_cast<size_t>(nc)), lb(static_cast<size_t>(nc)),
          ub(static_cast<size_t>(nc)), dx(static_cast<size_t>(nc)), q_base(static_cast<size_t>(nq)),
          gram(nc > 6 ? nc : 6, nc > 6 ? nc : 6), rows(6), L(nc > 6 ? nc : 6, nc > 6 ? nc : 6), G(6, 6), y(6),
          box(nc) {}
};

// The scratch of one igm_solve (kinematics and step), reusable by the next solve on the same
// chain and nq: every entry a solve reads it writes first, so a reused workspace gives the
// bits of a fresh one (bind_igm.cpp's _IgmPlan keeps one).
struct Workspace {
    Work w;
    QPWork qw;
    Vec q;  // (nq,): the iterate
    Workspace(const Chain& c, i64 nq) : w(c, nq), qw(c.njnt, nq), q(static_cast<size_t>(nq)) {}
};

struct Errors {
    double ep, eo;
};

// Error [p - p_t; log(R R_t^T)] into error; returns (position error [m], orientation
// error [rad]).
inline Errors pose_error(const double* position, const double* rotation, const Target& t, double* error,
                         double* rot_err, double* M) {
    for (int i = 0; i < 3; ++i) error[i] = position[i] - t.p[i];
    double ep = std::sqrt(error[0] * error[0] + error[1] * error[1] + error[2] * error[2]);
    if (!t.has_rot) return {ep, 0.0};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            M[3 * i + j] = rotation[3 * i] * t.R[3 * j] + rotation[3 * i + 1] * t.R[3 * j + 1] +
                           rotation[3 * i + 2] * t.R[3 * j + 2];
    double eo = model::rotation_log(M, rot_err);
    for (int i = 0; i < 3; ++i) error[3 + i] = rot_err[i];
    return {ep, eo};
}

// Forward kinematics, Jacobian and pose error at q into work.
inline Errors evaluate(const Chain&, const double* q, const Target& t, Work& w) {
    model::fast_fk_jac(w.chain, q, w.axes.ref(), w.anchors.ref(), w.position, w.rotation, w.jac.ref());
    return pose_error(w.position, w.rotation, t, w.error, w.rot_err, w.M);
}

inline void record(const Record& rec, i64 slot, i64 index, const double* q, double ep, double eo) {
    double* p = rec.path_at(slot, index);
    for (i64 j = 0; j < rec.nq; ++j) p[j] = q[j];
    double* h = rec.hist_at(slot, index);
    h[0] = ep;
    h[1] = eo;
}

// Why an attempt stopped progressing: a binding joint limit, else a singularity, else
// stalled.
inline i64 stall_reason(bool active, double sigma, double threshold) {
    if (active) return AT_LIMIT;
    return sigma < threshold ? SINGULAR : STALLED;
}

// The target level A dx = b over the chain's dofs cols: A = [J_v; Jl^-1 J_w], b = -gain e.
inline void target_level(const Mat& jac, const i64* cols, i64 nc, const double* error, const double* rot_err,
                         bool has_rot, double gain, Mat& A, double* b, double* Jinv) {
    for (int i = 0; i < 3; ++i) {
        for (i64 c = 0; c < nc; ++c) A(i, c) = jac(i, cols[c]);
        b[i] = -gain * error[i];
    }
    if (has_rot) {
        model::so3_ljacinv(Jinv, rot_err);
        for (int i = 0; i < 3; ++i) {
            for (i64 c = 0; c < nc; ++c) {
                i64 j = cols[c];
                A(3 + i, c) = Jinv[3 * i] * jac(3, j) + Jinv[3 * i + 1] * jac(4, j) + Jinv[3 * i + 2] * jac(5, j);
            }
            b[3 + i] = -gain * error[3 + i];
        }
    }
}

struct Regularisation {
    double reg, sigma;
};

// (damping + lambda^2, sigma) from the level's smallest singular value sigma (inf: at
// least the threshold): the adaptive damping law.
inline Regularisation damping_law(double sigma, const double* b, i64 m, const double* options) {
    double threshold = options[6], max_damping = options[7], error_scale = options[8], reg = options[9];
    if (sigma < threshold) {
        double ratio = sigma / threshold;
        double lam2 = max_damping * max_damping * (1.0 - ratio * ratio);
        if (error_scale > 0.0) {
            double bnorm = 0.0;
            for (i64 i = 0; i < m; ++i) bnorm += b[i] * b[i];
            bnorm = std::sqrt(bnorm);
            double f = bnorm / error_scale;
            lam2 *= f < 1.0 ? f : 1.0;  // Python's min(1.0, f)
        }
        reg += lam2;
    }
    return {reg, sigma};
}

// (damping + lambda^2, sigma): the adaptive damping of the level and its smallest
// singular value (inf when not computed).
inline Regularisation regularisation(const Mat& A, const double* b, i64 m, Mat& gram, const double* options,
                                     i64* rows, Mat& L) {
    double threshold = options[6];
    if (!(threshold > 0.0)) return {options[9], kInf};
    double sigma = smallest_singular_value_in(A.cref(), m, A.cols, gram.ref(), threshold, rows, L.ref());
    if (sigma < threshold) sigma = structural_sigma(A.cref(), m, sigma, options[11]);
    return damping_law(sigma, b, m, options);
}

// G[:m, :m] = A[:m] A[:m]^T (each entry summed over the dofs in order, as
// smallest_singular_value_in sums it).
inline void row_gram(const Mat& A, i64 m, Mat& G) {
    i64 nc = A.cols;
    for (i64 a = 0; a < m; ++a) {
        const double* ra = A.row(a);
        for (i64 c = a; c < m; ++c) {
            const double* rc = A.row(c);
            double s = 0.0;
            for (i64 k = 0; k < nc; ++k) s += ra[k] * rc[k];
            G(a, c) = s;
            G(c, a) = s;
        }
    }
}

// regularisation() of a level with no more rows than dofs (m <= A.cols) from its Gram
// matrix G = A A^T (row_gram; left unchanged): the same sigma, bit for bit (the Gram
// matrix of its nonzero rows is G's submatrix), without building it again.
inline Regularisation regularisation_gram(const Mat& A, const double* b, i64 m, const Mat& G, Mat& gram,
                                          const double* options, i64* rows, Mat& L) {
    double threshold = options[6];
    if (!(threshold > 0.0)) return {options[9], kInf};
    i64 r = 0;
    for (i64 i = 0; i < m; ++i) {
        for (i64 k = 0; k < A.cols; ++k) {
            if (A(i, k) != 0.0) {
                rows[r] = i;
                r += 1;
                break;
            }
        }
    }
    double sigma = kInf;
    if (r > 0) {
        for (i64 a = 0; a < r; ++a)
            for (i64 c = 0; c < r; ++c) gram(a, c) = G(rows[a], rows[c]);
        if (!core::cholesky_into(gram.cref(), r, threshold * threshold, L.ref())) {
            sigma = std::sqrt(gram_smallest_eigenvalue(gram.ref(), r));
            if (sigma < threshold) sigma = structural_sigma(A.cref(), m, sigma, options[11]);
        }
    }
    return damping_law(sigma, b, m, options);
}

// The unconstrained minimiser of |A dx - b|^2 + reg |dx|^2 in the row space,
// dx = A^T (G + reg I)^-1 b (G = A A^T, m x m), into dx; false (dx untouched) when
// G + reg I is not positive definite. Scratch: L (m, m), y (m,).
inline bool row_space_step(const Mat& A, const double* b, i64 m, const Mat& G, double reg, Mat& L, double* y,
                           double* dx) {
    if (!core::cholesky_into(G.cref(), m, -reg, L.ref())) return false;
    for (i64 i = 0; i < m; ++i) {
        double s = b[i];
        for (i64 k = 0; k < i; ++k) s -= L(i, k) * y[k];
        y[i] = s / L(i, i);
    }
    for (i64 i = m - 1; i >= 0; --i) {
        double s = y[i];
        for (i64 k = i + 1; k < m; ++k) s -= L(k, i) * y[k];
        y[i] = s / L(i, i);
    }
    for (i64 j = 0; j < A.cols; ++j) {
        double s = 0.0;
        for (i64 i = 0; i < m; ++i) s += A(i, j) * y[i];
        dx[j] = s;
    }
    return true;
}

// The damped least-squares QP of the level, H = A^T A + reg I, g = -A^T b, under the box
// limit_gain (limits - q) of the dofs cols (it always holds 0).
inline void box_problem(const Mat& A, const double* b, i64 m, double reg, Mat& H, double* g) {
    i64 nc = A.cols;
    for (i64 i = 0; i < nc; ++i) {
        double s = 0.0;
        for (i64 k = 0; k < m; ++k) s += A(k, i) * b[k];
        g[i] = -s;
        for (i64 j = i; j < nc; ++j) {
            s = 0.0;
            for (i64 k = 0; k < m; ++k) s += A(k, i) * A(k, j);
            H(i, j) = s;
            H(j, i) = s;
        }
        H(i, i) += reg;
    }
}

// The box of the step on the dofs cols: limit_gain (limits - q), widened to hold 0.
inline void step_box(const double* q, const i64* cols, i64 nc, const double* lower, const double* upper,
                     double limit_gain, double* lb, double* ub) {
    for (i64 i = 0; i < nc; ++i) {
        i64 d = cols[i];
        lb[i] = limit_gain * (lower[d] - q[d]);
        ub[i] = limit_gain * (upper[d] - q[d]);
        if (lb[i] > 0.0) lb[i] = 0.0;
        if (ub[i] < 0.0) ub[i] = 0.0;
    }
}

// Whether lb <= x <= ub (false on NaN).
inline bool within_box(const double* x, const double* lb, const double* ub, i64 n) {
    for (i64 i = 0; i < n; ++i)
        if (!(lb[i] <= x[i] && x[i] <= ub[i])) return false;
    return true;
}

// ------------------------------------------------ the row-space step, sizes fixed
// row_gram, regularisation_gram and row_space_step for M rows and NC dofs known at compile
// time (the usual 6 x 6 and 6 x 7 levels): the same operations in the same order, so the
// same bits, with the loops unrolled. G is (6, 6).
template <int M>
inline bool cholesky_fixed(const double* G, double shift, double* L) {
    for (int j = 0; j < M; ++j) {
        double s = G[j * 6 + j] - shift;
#pragma GCC unroll 8
        for (int k = 0; k < j; ++k) s -= L[j * 6 + k] * L[j * 6 + k];
        if (!(s > 0.0)) return false;
        double d = std::sqrt(s);
        L[j * 6 + j] = d;
        for (int i = j + 1; i < M; ++i) {
            double t = G[i * 6 + j];
#pragma GCC unroll 8
            for (int k = 0; k < j; ++k) t -= L[i * 6 + k] * L[j * 6 + k];
            L[i * 6 + j] = t / d;
        }
    }
    return true;
}

// (rg, whether the row-space minimiser is in dx): see level_step.
template <int M, int NC>
inline bool row_step_fixed(QPWork& qw, const double* options, Regularisation& rg) {
    const double* a = qw.A.a.data();  // (M, NC), stride NC
    const double* b = qw.b.data();
    double* G = qw.G.a.data();  // (6, 6)
    for (int i = 0; i < M; ++i) {
        for (int c = i; c < M; ++c) {
            double s = 0.0;
#pragma GCC unroll 8
            for (int k = 0; k < NC; ++k) s += a[i * NC + k] * a[c * NC + k];
            G[i * 6 + c] = s;
            G[c * 6 + i] = s;
        }
    }
    bool zero_row = false;
    for (int i = 0; i < M && !zero_row; ++i) {
        int k = 0;
        while (k < NC && a[i * NC + k] == 0.0) ++k;
        zero_row = k == NC;
    }
    double L[36];
    double threshold = options[6];
    if (!(threshold > 0.0)) {
        rg = {options[9], kInf};
    } else if (zero_row) {
        rg = regularisation_gram(qw.A, b, M, qw.G, qw.gram, options, qw.rows.data(), qw.L);
    } else {
        double sigma = kInf;
        if (!cholesky_fixed<M>(G, threshold * threshold, L)) {
            for (int i = 0; i < M; ++i)
                for (int c = 0; c < M; ++c) qw.gram(i, c) = G[i * 6 + c];
            sigma = std::sqrt(gram_smallest_eigenvalue(qw.gram.ref(), M));
            if (sigma < threshold) sigma = structural_sigma(qw.A.cref(), M, sigma, options[11]);
        }
        rg = damping_law(sigma, b, M, options);
    }
    if (!cholesky_fixed<M>(G, -rg.reg, L)) return false;
    double y[M];
    for (int i = 0; i < M; ++i) {
        double t = b[i];
        for (int k = 0; k < i; ++k) t -= L[i * 6 + k] * y[k];
        y[i] = t / L[i * 6 + i];
    }
    for (int i = M - 1; i >= 0; --i) {
        double t = y[i];
        for (int k = i + 1; k < M; ++k) t -= L[k * 6 + i] * y[k];
        y[i] = t / L[i * 6 + i];
    }
    double* dx = qw.dx.data();
    for (int j = 0; j < NC; ++j) {
        double t = 0.0;
#pragma GCC unroll 8
        for (int i = 0; i < M; ++i) t += a[i * NC + j] * y[i];
        dx[j] = t;
    }
    return true;
}

// The step of the target level into qw.dx: the damped least-squares QP
// min 1/2 |A dx - b|^2 + reg/2 |dx|^2 under the step box, with reg from the damping law.
// A level with no more rows than dofs (m <= nc, the usual 6 x 6 or 6 x 7) builds its
// m x m Gram matrix G = A A^T once, for the singular-value test and for the row-space
// minimiser A^T (G + reg I)^-1 b; when that lies within the box it is the QP's answer
// (box_qp's first iterate, no bound held); otherwise box_qp continues from it on
// H = A^T A + reg I. counts: QP solves and capped QP solves, added to.
inline Regularisation level_step(QPWork& qw, i64 m, const double* q, const i64* cols, const double* lower,
                                 const double* upper, const double* options, i64* counts) {
    const Mat& A = qw.A;
    const double* b = qw.b.data();
    i64 nc = A.cols;
    step_box(q, cols, nc, lower, upper, options[10], qw.lb.data(), qw.ub.data());
    counts[0] += 1;
    Regularisation rg;
    bool free_step = false;
    if (m <= nc) {
        if (m == 6 && nc == 7) {
            free_step = row_step_fixed<6, 7>(qw, options, rg);
        } else if (m == 6 && nc == 6) {
            free_step = row_step_fixed<6, 6>(qw, options, rg);
        } else {
            row_gram(A, m, qw.G);
            rg = regularisation_gram(A, b, m, qw.G, qw.gram, options, qw.rows.data(), qw.L);
            free_step = row_space_step(A, b, m, qw.G, rg.reg, qw.L, qw.y.data(), qw.dx.data());
        }
        if (free_step && within_box(qw.dx.data(), qw.lb.data(), qw.ub.data(), nc)) return rg;
    } else {
        rg = regularisation(A, b, m, qw.gram, options, qw.rows.data(), qw.L);
    }
    box_problem(A, b, m, rg.reg, qw.H, qw.g.data());
    BoxQPResult qp = box_qp_from(qw.H.cref(), qw.g.data(), qw.lb.data(), qw.ub.data(), qw.dx.data(), 4 * nc + 20,
                                 qw.box.work(), free_step ? qw.dx.data() : nullptr);
    if (qp.status != 0) counts[1] += 1;
    return rg;
}

// |x[:n]|.
inline double norm(const double* x, i64 n) {
    double s = 0.0;
    for (i64 i = 0; i < n; ++i) s += x[i] * x[i];
    return std::sqrt(s);
}

struct StepFacts {
    double residual, step_norm;
    bool active;
};

// (|A dx - b|, |dx|, whether a limited joint's bound is active) of a step.
inline StepFacts step_facts(const Mat& A, const double* b, i64 m, const double* dx, i64 nc, const i64* cols,
                            const double* lb, const double* ub, const double* lower, const double* upper) {
    double residual = 0.0;
    for (i64 k = 0; k < m; ++k) {
        double s = -b[k];
        for (i64 j = 0; j < nc; ++j) s += A(k, j) * dx[j];
        residual += s * s;
    }
    double step_norm = 0.0;
    bool active = false;
    for (i64 j = 0; j < nc; ++j) {
        step_norm += dx[j] * dx[j];
        i64 d = cols[j];
        bool at_lower = dx[j] <= lb[j] && lower[d] > -kInf;
        if (at_lower || (dx[j] >= ub[j] && upper[d] < kInf)) active = true;
    }
    return {std::sqrt(residual), std::sqrt(step_norm), active};
}

// q = clip(q_base + t dx) on the dofs cols, halving t while the error does not decrease,
// up to BACKTRACKS times; returns the errors at q.
inline Errors line_search(const Chain& c, const Target& target, double* q, const double* q_base,
                          const double* dx, const i64* cols, i64 nc, double t, const double* lower,
                          const double* upper, double ep, double eo, Work& w) {
    double previous = ep * ep + eo * eo;
    for (int attempt_step = 0; attempt_step < BACKTRACKS + 1; ++attempt_step) {
        for (i64 k = 0; k < nc; ++k) {
            i64 j = cols[k];
            q[j] = q_base[j] + t * dx[k];
            if (q[j] < lower[j]) q[j] = lower[j];
            if (q[j] > upper[j]) q[j] = upper[j];
        }
        Errors e = evaluate(c, q, target, w);
        ep = e.ep;
        eo = e.eo;
        if (ep * ep + eo * eo < previous || attempt_step == BACKTRACKS) break;
        t *= 0.5;
    }
    return {ep, eo};
}

// The target task's gain under the trust region.
inline double trust_gain(double alpha, double ep, double eo, bool has_rot, double max_step_p, double max_step_o) {
    double gain = alpha;
    if (ep > 0.0 && max_step_p / ep < gain) gain = max_step_p / ep;
    if (has_rot && eo > 0.0 && max_step_o / eo < gain) gain = max_step_o / eo;
    return gain;
}

struct AttemptResult {
    i64 reason, length;
    double current;
    bool out_of_time;
};

// One attempt of the IGM from q (advanced in place); its iterates go to attempt slot
// slot. counts: QP solves and capped QP solves, added to.
inline AttemptResult attempt(const Chain& c, const Target& target, double* q, const Settings& settings,
                             const Record& rec, i64 slot, Work& w, QPWork& qw, i64* counts) {
    const i64* cols = c.jnt_dadr;
    i64 nc = c.njnt;
    const double* lower = settings.bounds.row(0);
    const double* upper = settings.bounds.row(1);
    const double* options = settings.options;
    double tol_p = options[0], tol_o = options[1], alpha = options[2], beta = options[3];
    double max_step_p = options[4], max_step_o = options[5], threshold = options[6];
    i64 max_iters = settings.int_options[0], stall_window = settings.int_options[2];
    i64 check_time = settings.int_options[3];
    i64 m = target.has_rot ? 6 : 3;
    Errors e = evaluate(c, q, target, w);
    double ep = e.ep, eo = e.eo;
    i64 length = 0;
    record(rec, slot, length, q, ep, eo);
    rec.hist_at(slot, 0)[2] = 0.0;
    length += 1;
    double current = ep / tol_p + eo / tol_o;
    double window_start = current;
    i64 since_progress = 0;
    i64 nq = rec.nq;
    for (i64 it = 0; it < max_iters; ++it) {
        if (ep <= tol_p && eo <= tol_o) return {CONVERGED, length, current, false};
        if (check_time != 0 && (it % CLOCK_EVERY == 0) && now() > settings.deadline)
            return {TIME_BUDGET, length, current, true};
        double gain = trust_gain(alpha, ep, eo, target.has_rot, max_step_p, max_step_o);
        target_level(w.jac, cols, nc, w.error, w.rot_err, target.has_rot, gain, qw.A, qw.b.data(), qw.Jinv);
        Regularisation rg = level_step(qw, m, q, cols, lower, upper, options, counts);
        StepFacts f = step_facts(qw.A, qw.b.data(), m, qw.dx.data(), nc, cols, qw.lb.data(), qw.ub.data(), lower,
                                 upper);
        rec.hist_at(slot, it + 1)[2] = f.residual;
        // A step that achieves less than 1 - BLOCKED of the decrease it asks for: the
        // joint limits or the singularity damping block the target from here.
        if (current > NEAR_TARGET && f.residual > BLOCKED * norm(qw.b.data(), m))
            return {stall_reason(f.active, rg.sigma, threshold), length, current, false};
        for (i64 j = 0; j < nq; ++j) qw.q_base[j] = q[j];
        e = line_search(c, target, q, qw.q_base.data(), qw.dx.data(), cols, nc, beta, lower, upper, ep, eo, w);
        ep = e.ep;
        eo = e.eo;
        record(rec, slot, length, q, ep, eo);
        length += 1;
        current = ep / tol_p + eo / tol_o;
        if (f.step_norm < 1e-9) return {stall_reason(f.active, rg.sigma, threshold), length, current, false};
        if (current < PROGRESS * window_start) {
            window_start = current;
            since_progress = 0;
        } else {
            since_progress += 1;
        }
        if (since_progress >= stall_window)
            return {stall_reason(f.active, rg.sigma, threshold), length, current, false};
    }
    if (ep <= tol_p && eo <= tol_o) return {CONVERGED, length, current, false};
    return {MAX_ITERS, length, current, false};
}

// Whether target_p is farther from the reach ball's center than its radius plus tol_p.
inline bool beyond_reach(const double* target_p, const double* reach, double tol_p) {
    double d0 = target_p[0] - reach[0];
    double d1 = target_p[1] - reach[1];
    double d2 = target_p[2] - reach[2];
    return std::sqrt(d0 * d0 + d1 * d1 + d2 * d2) > reach[3] + tol_p + 1e-9 * (1.0 + reach[3]);
}

// Whether an attempt beats the best so far: converged beats not, then the score.
inline bool better(bool done, double score, bool best_done, double best_score) {
    return (done && !best_done) || (done == best_done && score < best_score);
}

// The start of restart attempt (1, 2, ...), drawn into q: odd restarts from the central
// RESTART_SPREAD of the restart box, even ones from all of it.
inline void restart_start(double* q, i64 nq, const double* sample_lo, const double* sample_hi, i64 attempt_no,
                          std::uint64_t& rng_state) {
    double spread = attempt_no % 2 == 0 ? 1.0 : RESTART_SPREAD;
    for (i64 j = 0; j < nq; ++j) {
        double u = 0.5 + spread * (uniform(rng_state) - 0.5);
        q[j] = sample_lo[j] + (sample_hi[j] - sample_lo[j]) * u;
    }
}

// The iteration budget of int_options (len entries): its fifth entry, -1 (none) where it
// has four.
inline i64 iteration_budget(const i64* int_options, i64 len) { return len >= 5 ? int_options[4] : -1; }

// The whole IGM solve of one frame target (see qpik.igm.kernels.igm_solve for the
// arguments). path (2, max_iters + 1, nq), hist (2, max_iters + 1, 3) and info (6,) are
// written; rng_state advanced. budget: no new attempt starts once the solve's iterations
// reach it (SolveOptions.iteration_budget; -1: none).
// ws: a Workspace(c, nq) to use (its contents do not matter), or nullptr (one made here).
inline void igm_solve(const Chain& c, const Target& target, const double* q0, i64 nq, CMatRef bounds,
                      const double* reach, const double* options, const i64* int_options, i64 budget,
                      std::uint64_t& rng_state, double deadline, const Record& rec, i64* info,
                      Workspace* ws = nullptr) {
    i64 restarts = int_options[1], check_time = int_options[3];
    const double* sample_lo = bounds.row(2);
    const double* sample_hi = bounds.row(3);
    std::unique_ptr<Workspace> own;
    if (ws == nullptr) {
        own.reset(new Workspace(c, nq));
        ws = own.get();
    }
    Work& w = ws->w;
    QPWork& qw = ws->qw;
    Settings settings{bounds, options, int_options, deadline};
    Vec& q = ws->q;
    std::copy(q0, q0 + nq, q.begin());
    i64 counts[2] = {0, 0};
    if (beyond_reach(target.p, reach, options[0])) {
        Errors e = evaluate(c, q.data(), target, w);
        record(rec, 0, 0, q.data(), e.ep, e.eo);
        rec.hist_at(0, 0)[2] = 0.0;
        for (int i = 0; i < 6; ++i) info[i] = 0;
        info[0] = UNREACHABLE;
        info[4] = 1;
        return;
    }
    double best_score = kInf;
    i64 best_slot = 0, best_len = 1, best_reason = MAX_ITERS, reason = MAX_ITERS;
    i64 slot = 0, attempt_no = 0;
    bool out_of_time = false;
    while (true) {
        AttemptResult r = attempt(c, target, q.data(), settings, rec, slot, w, qw, counts);
        reason = r.reason;
        out_of_time = r.out_of_time;
        bool done = reason == CONVERGED;
        if (attempt_no == 0 || better(done, r.current, best_reason == CONVERGED, best_score)) {
            best_score = r.current;
            best_slot = slot;
            best_len = r.length;
            best_reason = reason;
            slot = 1 - slot;
        }
        if (done || attempt_no >= restarts || (budget >= 0 && counts[0] >= budget)) break;
        if (check_time != 0 && (out_of_time || now() > deadline)) {
            out_of_time = true;
            break;
        }
        attempt_no += 1;
        restart_start(q.data(), nq, sample_lo, sample_hi, attempt_no, rng_state);
    }
    i64 final_reason = reason;
    if (best_reason == CONVERGED)
        final_reason = CONVERGED;
    else if (out_of_time)
        final_reason = TIME_BUDGET;
    info[0] = final_reason;
    info[1] = counts[0];
    info[2] = attempt_no;
    info[3] = best_slot;
    info[4] = best_len;
    info[5] = counts[1];
}

}  // namespace qpik::igm
