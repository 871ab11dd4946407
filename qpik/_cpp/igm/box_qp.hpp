// The IGM's box QP: min 1/2 x^T H x + g^T x  s.t.  lb <= x <= ub (H positive definite),
// exactly, by a primal active-set method (named for Python in qpik/igm/kernels.py;
// recorded answers pin its bits).
#pragma once

#include "../common.hpp"

namespace qpik::igm {

// Scratch of box_qp for n variables (views; owned by BoxQPScratch or by NumPy arrays).
struct BoxQPWork {
    i8* state = nullptr;  // (n,) 0 free, -1 at lower, +1 at upper
    i64* free = nullptr;  // (n,)
    MatRef L;             // (n, n)
    double* target = nullptr;
    double* rhs = nullptr;
    double* y = nullptr;
};

struct BoxQPScratch {
    BVec state;
    IVec free;
    Mat L;
    Vec target, rhs, y;
    explicit BoxQPScratch(i64 n)
        : state(static_cast<size_t>(n)), free(static_cast<size_t>(n)), L(n, n),
          target(static_cast<size_t>(n)), rhs(static_cast<size_t>(n)), y(static_cast<size_t>(n)) {}
    BoxQPWork work() { return BoxQPWork{state.data(), free.data(), L.ref(), target.data(), rhs.data(), y.data()}; }
};

// Solve H[F, F] x_F = rhs_F by Cholesky (F: the first nfree of free); false if H[F, F]
// is not positive definite.
inline bool cholesky_solve_subset(CMatRef H, const double* rhs, const i64* free, i64 nfree, MatRef L,
                                  double* x, double* y) {
    for (i64 a = 0; a < nfree; ++a) {
        i64 i = free[a];
        for (i64 b = 0; b < a + 1; ++b) {
            i64 j = free[b];
            double s = H(i, j);
            for (i64 k = 0; k < b; ++k) s -= L(a, k) * L(b, k);
            if (a == b) {
                if (!(s > 0.0)) return false;
                L(a, a) = std::sqrt(s);
            } else {
                L(a, b) = s / L(b, b);
            }
        }
    }
    for (i64 a = 0; a < nfree; ++a) {
        double s = rhs[free[a]];
        for (i64 k = 0; k < a; ++k) s -= L(a, k) * y[k];
        y[a] = s / L(a, a);
    }
    for (i64 a = nfree - 1; a >= 0; --a) {
        double s = y[a];
        for (i64 k = a + 1; k < nfree; ++k) s -= L(k, a) * x[free[k]];
        x[free[a]] = s / L(a, a);
    }
    return true;
}

// The free variables (their count returned) and the right-hand side -g - H_fb x_b of
// their minimiser with the others held at their bounds (whose target is their value).
inline i64 free_rhs(CMatRef H, const double* g, const double* x, const i8* state, i64* free, double* target,
                    double* rhs) {
    i64 n = H.rows;
    i64 nfree = 0;
    for (i64 i = 0; i < n; ++i) {
        if (state[i] == 0) {
            free[nfree] = i;
            nfree += 1;
        } else {
            target[i] = x[i];
        }
    }
    for (i64 a = 0; a < nfree; ++a) {
        i64 i = free[a];
        double s = -g[i];
        for (i64 j = 0; j < n; ++j)
            if (state[j] != 0) s -= H(i, j) * x[j];
        rhs[i] = s;
    }
    return nfree;
}

struct Ratio {
    double step;
    i64 block;
    int side;
};

// The longest step in [0, 1] from x toward target that keeps the free variables in their
// bounds, and the variable that blocks it (-1: none) with its side (-1 lower, +1 upper).
inline Ratio ratio_test(const double* x, const double* target, const double* lb, const double* ub,
                        const i64* free, i64 nfree) {
    double step = 1.0;
    i64 block = -1;
    int side = 0;
    for (i64 a = 0; a < nfree; ++a) {
        i64 i = free[a];
        double d = target[i] - x[i];
        if (d < 0.0 && target[i] < lb[i]) {
            double t = (lb[i] - x[i]) / d;
            if (t < step) {
                step = t;
                block = i;
                side = -1;
            }
        } else if (d > 0.0 && target[i] > ub[i]) {
            double t = (ub[i] - x[i]) / d;
            if (t < step) {
                step = t;
                block = i;
                side = 1;
            }
        }
    }
    return Ratio{0.0 > step ? 0.0 : step, block, side};  // Python's max(step, 0.0)
}

// The held bound whose multiplier is the most negative, or -1 when every multiplier is >= 0.
inline i64 most_negative_multiplier(CMatRef H, const double* g, const double* x, const i8* state) {
    i64 n = H.rows;
    double worst = 0.0;
    i64 release = -1;
    for (i64 i = 0; i < n; ++i) {
        if (state[i] == 0) continue;
        double grad = g[i];
        for (i64 j = 0; j < n; ++j) grad += H(i, j) * x[j];
        double multiplier = state[i] < 0 ? grad : -grad;  // >= 0 at the optimum
        if (multiplier < worst - 1e-14 * (1.0 + std::fabs(grad))) {
            worst = multiplier;
            release = i;
        }
    }
    return release;
}

struct BoxQPResult {
    i64 status;  // 0 solved, 1 iteration cap, 2 singular free block
    i64 iterations;
};

// box_qp whose first iterate's target, the unconstrained minimiser -H^-1 g, is given as
// first (may alias x; nullptr: solved here).
inline BoxQPResult box_qp_from(CMatRef H, const double* g, const double* lb, const double* ub, double* x,
                               i64 max_iter, const BoxQPWork& w, const double* first) {
    i64 n = H.rows;
    if (first != nullptr && max_iter > 0) {
        for (i64 i = 0; i < n; ++i) w.target[i] = first[i];
    }
    for (i64 i = 0; i < n; ++i) {
        w.state[i] = 0;
        double lo = lb[i] > 0.0 ? lb[i] : 0.0;  // Python's max(0.0, lb[i])
        x[i] = ub[i] < lo ? ub[i] : lo;         // min(., ub[i])
    }
    for (i64 iteration = 0; iteration < max_iter; ++iteration) {
        i64 nfree = n;
        if (iteration == 0 && first != nullptr) {
            for (i64 i = 0; i < n; ++i) w.free[i] = i;
        } else {
            nfree = free_rhs(H, g, x, w.state, w.free, w.target, w.rhs);
            if (nfree > 0 && !cholesky_solve_subset(H, w.rhs, w.free, nfree, w.L, w.target, w.y))
                return {2, iteration};
        }
        Ratio r = ratio_test(x, w.target, lb, ub, w.free, nfree);
        for (i64 a = 0; a < nfree; ++a) {
            i64 i = w.free[a];
            x[i] += r.step * (w.target[i] - x[i]);
        }
        if (r.block >= 0) {  // a bound blocks the step: hold it and solve again
            x[r.block] = r.side < 0 ? lb[r.block] : ub[r.block];
            w.state[r.block] = static_cast<i8>(r.side);
            continue;
        }
        i64 release = most_negative_multiplier(H, g, x, w.state);
        if (release < 0) return {0, iteration + 1};
        w.state[release] = 0;
    }
    return {1, max_iter};
}

// box_qp with its scratch given: from the feasible point clip(0, lb, ub), the working set
// grows by the blocking bound of each ratio test and shrinks by the bound with the most
// negative multiplier (lowest index on ties), up to max_iter changes.
inline BoxQPResult box_qp(CMatRef H, const double* g, const double* lb, const double* ub, double* x,
                          i64 max_iter, const BoxQPWork& w) {
    return box_qp_from(H, g, lb, ub, x, max_iter, w, nullptr);
}

}  // namespace qpik::igm
