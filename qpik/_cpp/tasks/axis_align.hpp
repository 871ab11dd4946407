// The weighted residual of mink's AxisAlignTask (align a frame's axis with a world
// direction), as its compute_qp_residual defines it, from MuJoCo's rotation and
// world-aligned angular Jacobian of the frame:
//   d = R^T t, e = a - d, J = -[d]x J_w   (J_w = R^T jacr: the frame's angular block),
// weighted: A = cost J (row i by cost[i]), b = cost (-gain e), mu = lm_damping |b|^2.
// Used by qpik.diffik.rows (the QP path and the compiled step's rows alike).
#pragma once

#include "../common.hpp"

namespace qpik::tasks {

// jacr (3, nv) row-major (MuJoCo's mj_jac* rotation rows); xmat (9) row-major; A (3, nv)
// and b (3) written. Returns mu.
inline double axis_align_residual(const double* jacr, i64 nv, const double* xmat, const double* target,
                                  const double* axis, const double* cost, double gain, double lm_damping,
                                  double* A, double* b) {
    const double* R = xmat;
    double d[3];
    for (int i = 0; i < 3; ++i) d[i] = R[0 * 3 + i] * target[0] + R[1 * 3 + i] * target[1] + R[2 * 3 + i] * target[2];
    // -[d]x
    const double S[3][3] = {{-0.0, d[2], -d[1]}, {-d[2], -0.0, d[0]}, {d[1], -d[0], -0.0}};
    double mu = 0.0;
    for (int i = 0; i < 3; ++i) {
        const double e = axis[i] - d[i];
        b[i] = cost[i] * (-gain * e);
        mu += b[i] * b[i];
    }
    for (i64 c = 0; c < nv; ++c) {
        double o[3];
        for (int i = 0; i < 3; ++i)  // the frame's block: R^T jacr
            o[i] = R[0 * 3 + i] * jacr[c] + R[1 * 3 + i] * jacr[nv + c] + R[2 * 3 + i] * jacr[2 * nv + c];
        for (int i = 0; i < 3; ++i) A[i * nv + c] = cost[i] * (S[i][0] * o[0] + S[i][1] * o[1] + S[i][2] * o[2]);
    }
    return lm_damping * mu;
}

}  // namespace qpik::tasks
