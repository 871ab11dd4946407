// qpik's ManipulabilityTask: error e = 1 / m(q), m = sqrt(det J J^T) of the rows `idx` of a
// frame's world-aligned Jacobian [v; omega], and its Jacobian de/dq = -(dm/dq) / m^2, with
// dm/dq_a = <dJ/dq_a, W>, W = U diag(c) V^T (c_i = prod_{j != i} s_j) from the SVD J = U S
// V^T, dJ/dq by the kinematic Hessian in closed form (model/jac.hpp: hessian_weights on a
// chain of hinges and slides, hessian_weights_any where a ball or free joint moves the frame:
// what mj_jacDot gives). The task is idle (e = 0, a zero row) where m is 0 to
// round-off: more rows than dofs, the smallest singular value at most kRankFloor of the
// largest (qpik.tasks.secondary.RANK_FLOOR), or 1 / m^2 not a finite number. One routine
// for the compiled step (diffik/fused.hpp) and the task's own methods on the QP path
// (qpik.tasks.secondary), so the two agree bit for bit.
//
// The SVD is one-sided Jacobi (Hestenes) on the rows of J / max|J_ij|: plane rotations of
// pairs of rows until every pair is orthogonal to working precision (|b_p . b_q| <= 1e-15
// |b_p| |b_q|); then s_i = |b_i| max|J_ij|, v_i = b_i / |b_i| and u_i the i-th column of
// the rotations' product transposed. m is the product of the singular values with their
// exponents kept apart (frexp / ldexp: no overflow before the end, no log or exp). Only
// IEEE +, -, *, / and sqrt: the same bits on every machine.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "../common.hpp"
#include "../model/jac.hpp"

namespace qpik::tasks {

constexpr double kRankFloor = 1e-9;
constexpr double kJacobiTol = 1e-15;
constexpr int kJacobiSweeps = 60;

// Rows B (m, n, row-major) rotated in place until mutually orthogonal; Q (m, m) the
// rotations' product (B_out = Q B_in).
inline void jacobi_rows(double* B, i64 m, i64 n, double* Q) {
    for (i64 i = 0; i < m * m; ++i) Q[i] = 0.0;
    for (i64 i = 0; i < m; ++i) Q[i * m + i] = 1.0;
    for (int sweep = 0; sweep < kJacobiSweeps; ++sweep) {
        bool rotated = false;
        for (i64 p = 0; p + 1 < m; ++p) {
            for (i64 q = p + 1; q < m; ++q) {
                double* bp = B + p * n;
                double* bq = B + q * n;
                double alpha = 0.0, beta = 0.0, gamma = 0.0;
                for (i64 j = 0; j < n; ++j) {
                    alpha += bp[j] * bp[j];
                    beta += bq[j] * bq[j];
                    gamma += bp[j] * bq[j];
                }
                if (!(std::fabs(gamma) > kJacobiTol * std::sqrt(alpha) * std::sqrt(beta))) continue;
                const double zeta = (beta - alpha) / (2.0 * gamma);
                const double t = (zeta >= 0.0 ? 1.0 : -1.0) / (std::fabs(zeta) + std::sqrt(1.0 + zeta * zeta));
                if (t == 0.0) continue;  // (zeta^2 past the float range: nothing to rotate)
                const double c = 1.0 / std::sqrt(1.0 + t * t);
                const double s = c * t;
                for (i64 j = 0; j < n; ++j) {
                    const double x = bp[j], y = bq[j];
                    bp[j] = c * x - s * y;
                    bq[j] = s * x + c * y;
                }
                double* qp = Q + p * m;
                double* qq = Q + q * m;
                for (i64 j = 0; j < m; ++j) {
                    const double x = qp[j], y = qq[j];
                    qp[j] = c * x - s * y;
                    qq[j] = s * x + c * y;
                }
                rotated = true;
            }
        }
        if (!rotated) break;
    }
}

// The product of s[0:m] (each finite, > 0), its exponent kept apart from its mantissa.
inline double exponent_product(const double* s, i64 m) {
    double mant = 1.0;
    long expo = 0;
    for (i64 i = 0; i < m; ++i) {
        int e = 0;
        mant *= std::frexp(s[i], &e);
        expo += e;
        mant = std::frexp(mant, &e);
        expo += e;
    }
    if (expo > 2000) return std::numeric_limits<double>::infinity();
    if (expo < -2000) return 0.0;
    return std::ldexp(mant, static_cast<int>(expo));
}

inline i64 manipulability_scratch(i64 m, i64 n) { return (m + 7) * n + m * m + 2 * m + 6 * n; }

// e = 1 / m(q) (returned) and de/dq into de (n) of the rows idx[0:m] of jac (6, n), the frame's
// dofs chain[0], chain[stride], ... (count of them, root first: hessian_weights' order; a
// chain of hinges and slides where threshold is null, else any chain, its dofs' thresholds
// those of model::hessian_weights_any);
// 0 and a zero row where the task is idle (see above). scratch: at least
// manipulability_scratch(m, n) doubles. value (optional): m(q) where the task is not idle, else 0; singular (optional, m):
// the singular values, rows' order.
inline double inverse_manipulability(const double* jac, i64 n, const i64* idx, i64 m, const i64* chain, i64 count,
                                     i64 stride, double* scratch, double* de, double* value = nullptr,
                                     double* singular = nullptr, const i64* threshold = nullptr) {
    for (i64 j = 0; j < n; ++j) de[j] = 0.0;
    if (value != nullptr) *value = 0.0;
    if (m > n || m == 0) return 0.0;
    double* B = scratch;          // (m, n)
    double* W = B + m * n;        // (6, n)
    double* grad = W + 6 * n;     // (n)
    double* Q = grad + n;         // (m, m)
    double* s = Q + m * m;        // (m)
    double* c = s + m;            // (m)
    double* hs = c + m;           // (6 n): hessian_weights_any's
    double scale = 0.0;
    for (i64 i = 0; i < m; ++i)
        for (i64 j = 0; j < n; ++j) scale = std::max(scale, std::fabs(jac[idx[i] * n + j]));
    if (!(scale > 0.0)) return 0.0;  // (a zero Jacobian: m = 0)
    for (i64 i = 0; i < m; ++i)
        for (i64 j = 0; j < n; ++j) B[i * n + j] = jac[idx[i] * n + j] / scale;
    jacobi_rows(B, m, n, Q);
    double smax = 0.0, smin = std::numeric_limits<double>::infinity();
    for (i64 i = 0; i < m; ++i) {
        double sq = 0.0;
        for (i64 j = 0; j < n; ++j) sq += B[i * n + j] * B[i * n + j];
        const double sigma = std::sqrt(sq);
        for (i64 j = 0; j < n; ++j) B[i * n + j] = sigma > 0.0 ? B[i * n + j] / sigma : 0.0;  // v_i
        s[i] = sigma * scale;
        if (singular != nullptr) singular[i] = s[i];
        smax = std::max(smax, s[i]);
        smin = std::min(smin, s[i]);
    }
    if (!(smin > kRankFloor * smax)) return 0.0;  // (rank deficient to round-off)
    const double m_q = exponent_product(s, m);
    const double inv2 = 1.0 / (m_q * m_q);
    if (!(m_q > 0.0) || !std::isfinite(inv2)) return 0.0;
    if (value != nullptr) *value = m_q;
    for (i64 i = 0; i < m; ++i) c[i] = exponent_product(s, i) * exponent_product(s + i + 1, m - i - 1);
    // W = sum_i c_i u_i v_i^T on the rows idx (a row named twice: both terms), u_i = Q^T e_i
    for (i64 e = 0; e < 6 * n; ++e) W[e] = 0.0;
    for (i64 r = 0; r < m; ++r) {
        double* wr = W + idx[r] * n;
        for (i64 i = 0; i < m; ++i) {
            const double f = c[i] * Q[i * m + r];  // c_i (u_i)_r
            const double* vi = B + i * n;
            for (i64 j = 0; j < n; ++j) wr[j] += f * vi[j];
        }
    }
    if (threshold == nullptr)
        model::hessian_weights(jac, W, n, chain, count, grad, stride);
    else
        model::hessian_weights_any(jac, W, n, chain, count, grad, stride, threshold, hs);
    for (i64 j = 0; j < n; ++j) de[j] = -inv2 * grad[j];
    return 1.0 / m_q;
}

// The task's weighted row: A row = cost de, b = cost (-gain e), returns lm_damping b^2 (mink's
// weighted residual, in its operations' order).
inline double manipulability_row(double e, const double* de, i64 n, double cost, double gain, double lm,
                                 double* a_row, double* b) {
    for (i64 j = 0; j < n; ++j) a_row[j] = cost * de[j];
    *b = cost * (-gain * e);
    return lm * (*b * *b);
}

}  // namespace qpik::tasks
