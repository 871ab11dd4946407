// A frame task's rows from MuJoCo's pose and world-aligned Jacobian (ported from the
// kernels of qpik/tasks/fast.py, same operations in the same order): mink's error
// log(T_fw^-1 T_tw), its jlog, and the weighted rows diag(cost) (-jlog) [R^T Jp; R^T Jr].
#pragma once

#include <vector>

#include "../common.hpp"
#include "../model/se3.hpp"

namespace qpik::tasks {

// mink's frame-task error (the body twist from the frame at (xpos, xmat) to `target`,
// wxyz_xyz) into error (6) and jlog(T_tw^-1 T_fw) into jlog (row-major 6x6, 36).
inline void frame_error_jlog(const double* xmat, const double* xpos, const double* target,
                             double* error, double* jlog) {
    double frame[7];
    model::xmat_xpos_to_wxyz_xyz(frame, xmat, xpos);
    model::se3_rminus(error, target, frame);
    double relative[7];
    model::se3_inverse_multiply(relative, target, frame);
    model::se3_jlog(jlog, relative);
}

// Rows row:row+6 of a frame task written into A (rows >= row + 6, nv) and b: A =
// diag(cost) (-jlog) [R^T Jp; R^T Jr], b = -gain cost e; returns lm_damping |b|^2. `jac` is
// MuJoCo's world-aligned Jacobian (6, nv), xmat the frame's rotation (row-major 9), jlog
// row-major 6x6 (36). `local` is scratch of 6 * nv doubles.
inline double frame_rows_into(MatRef A, double* b, i64 row, CMatRef jac, const double* xmat,
                              const double* jlog, const double* error, const double* cost,
                              double gain, double lm_damping, double* local) {
    const i64 nv = jac.cols;
    for (i64 i = 0; i < 3; ++i) {
        for (i64 j = 0; j < nv; ++j) {
            double a = 0.0;
            double r = 0.0;
            for (i64 k = 0; k < 3; ++k) {
                a += xmat[3 * k + i] * jac(k, j);
                r += xmat[3 * k + i] * jac(3 + k, j);
            }
            local[i * nv + j] = a;
            local[(3 + i) * nv + j] = r;
        }
    }
    double mu = 0.0;
    for (i64 i = 0; i < 6; ++i) {
        for (i64 j = 0; j < nv; ++j) {
            double acc = 0.0;
            for (i64 k = 0; k < 6; ++k) acc += jlog[6 * i + k] * local[k * nv + j];
            A(row + i, j) = -cost[i] * acc;
        }
        b[row + i] = cost[i] * (-gain * error[i]);
        mu += b[row + i] * b[row + i];
    }
    return lm_damping * mu;
}

inline double frame_rows_into(MatRef A, double* b, i64 row, CMatRef jac, const double* xmat,
                              const double* jlog, const double* error, const double* cost,
                              double gain, double lm_damping) {
    std::vector<double> local(static_cast<size_t>(6 * jac.cols));
    return frame_rows_into(A, b, row, jac, xmat, jlog, error, cost, gain, lm_damping, local.data());
}

}  // namespace qpik::tasks
