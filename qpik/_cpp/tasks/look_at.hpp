// The weighted residual of mink's LookAtTask (point a frame's axis at a world point), as its
// compute_qp_residual defines it, from MuJoCo's pose and world-aligned Jacobian of the frame:
//   r = R^T (p* - p), n = max(|r|, eps), d = r / n, e = a - d,
//   J = (I - d d^T) (J_v - [r]x J_w) / n   (J_v = R^T jacp, J_w = R^T jacr: the frame's),
// weighted: A = cost J (row i by cost[i]), b = cost (-gain e), mu = lm_damping |b|^2.
// Used by qpik.diffik.rows (the QP path and the compiled step's rows alike).
#pragma once

#include <cmath>

#include "../common.hpp"

namespace qpik::tasks {

// jac (6, nv) row-major: jacp then jacr (MuJoCo's mj_jac*); xmat (9) row-major; A (3, nv)
// and b (3) written. Returns mu.
inline double look_at_residual(const double* jac, i64 nv, const double* xmat, const double* xpos,
                               const double* target, const double* axis, const double* cost, double gain,
                               double lm_damping, double eps, double* A, double* b) {
    const double* R = xmat;
    double w[3] = {target[0] - xpos[0], target[1] - xpos[1], target[2] - xpos[2]};
    double r[3];
    for (int i = 0; i < 3; ++i) r[i] = R[0 * 3 + i] * w[0] + R[1 * 3 + i] * w[1] + R[2 * 3 + i] * w[2];
    double n = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
    if (!(n >= eps)) n = std::isnan(n) ? n : eps;
    const double d[3] = {r[0] / n, r[1] / n, r[2] / n};
    // P = I - d d^T; S = [r]x
    double P[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) P[i][j] = (i == j ? 1.0 : 0.0) - d[i] * d[j];
    const double S[3][3] = {{0.0, -r[2], r[1]}, {r[2], 0.0, -r[0]}, {-r[1], r[0], 0.0}};
    double mu = 0.0;
    for (int i = 0; i < 3; ++i) {
        const double e = axis[i] - d[i];
        b[i] = cost[i] * (-gain * e);
        mu += b[i] * b[i];
    }
    const double* jp = jac;
    const double* jr = jac + 3 * nv;
    for (i64 c = 0; c < nv; ++c) {
        double v[3], o[3], m[3];
        for (int i = 0; i < 3; ++i) {  // the frame's blocks: R^T jacp, R^T jacr
            v[i] = R[0 * 3 + i] * jp[c] + R[1 * 3 + i] * jp[nv + c] + R[2 * 3 + i] * jp[2 * nv + c];
            o[i] = R[0 * 3 + i] * jr[c] + R[1 * 3 + i] * jr[nv + c] + R[2 * 3 + i] * jr[2 * nv + c];
        }
        for (int i = 0; i < 3; ++i) m[i] = v[i] - (S[i][0] * o[0] + S[i][1] * o[1] + S[i][2] * o[2]);
        for (int i = 0; i < 3; ++i)
            A[i * nv + c] = cost[i] * ((P[i][0] * m[0] + P[i][1] * m[1] + P[i][2] * m[2]) / n);
    }
    return lm_damping * mu;
}

}  // namespace qpik::tasks
