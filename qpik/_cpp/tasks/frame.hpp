// A frame task's rows from MuJoCo's pose and world-aligned Jacobian (ported from the
// kernels of qpik/tasks/frame.py, same operations in the same order): mink's error
// log(T_fw^-1 T_tw), its jlog, and the weighted rows diag(cost) (-jlog) [R^T Jp; R^T Jr].
#pragma once

#include <cmath>
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

// The local (body-frame) Jacobian [R^T Jp; R^T Jr] (6, nv) into `local` (row-major) from
// MuJoCo's world-aligned one; xmat row-major 9.
inline void local_jacobian(double* local, CMatRef jac, const double* xmat) {
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
}

// Rows row:row+6 of a frame task written into A (rows >= row + 6, nv) and b: A =
// diag(cost) (-jlog) [R^T Jp; R^T Jr], b = -gain cost e; returns lm_damping |b|^2. `jac` is
// MuJoCo's world-aligned Jacobian (6, nv), xmat the frame's rotation (row-major 9), jlog
// row-major 6x6 (36). `local` is scratch of 6 * nv doubles.
inline double frame_rows_into(MatRef A, double* b, i64 row, CMatRef jac, const double* xmat,
                              const double* jlog, const double* error, const double* cost,
                              double gain, double lm_damping, double* local) {
    const i64 nv = jac.cols;
    bool finite = true;
    for (int k = 0; k < 9; ++k) finite = finite && std::isfinite(xmat[k]);
    for (int k = 0; k < 36; ++k) finite = finite && std::isfinite(jlog[k]);
    if (finite) {
        // Column by column, each entry by the same sums as below; a column of the
        // Jacobian that is exactly zero (a dof off the frame's chain) gives local entries
        // +0 (0.0 + finite * 0, in any order) and so A entries -cost[i] * 0.0, written
        // without the sums: the same bits.
        for (i64 j = 0; j < nv; ++j) {
            bool zero = true;
            for (i64 k = 0; k < 6; ++k) zero = zero && jac(k, j) == 0.0;
            if (zero) {
                for (i64 i = 0; i < 6; ++i) A(row + i, j) = -cost[i] * 0.0;
                continue;
            }
            double col[6];
            for (i64 i = 0; i < 3; ++i) {
                double a = 0.0;
                double r = 0.0;
                for (i64 k = 0; k < 3; ++k) {
                    a += xmat[3 * k + i] * jac(k, j);
                    r += xmat[3 * k + i] * jac(3 + k, j);
                }
                col[i] = a;
                col[3 + i] = r;
            }
            for (i64 i = 0; i < 6; ++i) {
                double acc = 0.0;
                for (i64 k = 0; k < 6; ++k) acc += jlog[6 * i + k] * col[k];
                A(row + i, j) = -cost[i] * acc;
            }
        }
    } else {
        local_jacobian(local, jac, xmat);
        for (i64 i = 0; i < 6; ++i) {
            for (i64 j = 0; j < nv; ++j) {
                double acc = 0.0;
                for (i64 k = 0; k < 6; ++k) acc += jlog[6 * i + k] * local[k * nv + j];
                A(row + i, j) = -cost[i] * acc;
            }
        }
    }
    double mu = 0.0;
    for (i64 i = 0; i < 6; ++i) {
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


// Rows row:row+6 of mink's RelativeFrameTask: the pose of frame f in root frame r, T_rf =
// T_wr^-1 T_wf, to target T_rt (wxyz_xyz): error log(T_rt^-1 T_rf) (the body twist, frame
// f's axes [m, rad]) and Jacobian jlog(T_rt^-1 T_rf) (fJ_f - Ad(T_rf^-1) rJ_r), with fJ_f,
// rJ_r the frames' body Jacobians; written as A = diag(cost) J, b = -gain cost e. Returns
// lm_damping |b|^2. jac_f, jac_r: MuJoCo's world-aligned Jacobians (6, nv); xmat row-major 9.
// `scratch` holds 18 nv doubles.
inline double relative_frame_rows_into(MatRef A, double* b, i64 row, CMatRef jac_f,
                                       const double* xmat_f, const double* xpos_f, CMatRef jac_r,
                                       const double* xmat_r, const double* xpos_r,
                                       const double* target, const double* cost, double gain,
                                       double lm_damping, double* scratch) {
    const i64 nv = jac_f.cols;
    double frame[7], root[7], rel[7], error[6], rel_to_target[7], jlog[36], inv[7], adj[36];
    model::xmat_xpos_to_wxyz_xyz(frame, xmat_f, xpos_f);
    model::xmat_xpos_to_wxyz_xyz(root, xmat_r, xpos_r);
    model::se3_inverse_multiply(rel, root, frame);
    model::se3_rminus(error, rel, target);
    model::se3_inverse_multiply(rel_to_target, target, rel);
    model::se3_jlog(jlog, rel_to_target);
    model::se3_inverse(inv, rel);
    model::se3_adjoint(adj, inv);
    double* lf = scratch;
    double* lr = scratch + 6 * nv;
    double* diff = scratch + 12 * nv;
    local_jacobian(lf, jac_f, xmat_f);
    local_jacobian(lr, jac_r, xmat_r);
    for (i64 i = 0; i < 6; ++i) {
        for (i64 j = 0; j < nv; ++j) {
            double acc = 0.0;
            for (i64 k = 0; k < 6; ++k) acc += adj[6 * i + k] * lr[k * nv + j];
            diff[i * nv + j] = lf[i * nv + j] - acc;
        }
    }
    double mu = 0.0;
    for (i64 i = 0; i < 6; ++i) {
        for (i64 j = 0; j < nv; ++j) {
            double acc = 0.0;
            for (i64 k = 0; k < 6; ++k) acc += jlog[6 * i + k] * diff[k * nv + j];
            A(row + i, j) = cost[i] * acc;
        }
        b[row + i] = cost[i] * (-gain * error[i]);
        mu += b[row + i] * b[row + i];
    }
    return lm_damping * mu;
}

// Rows row:row+3 of a CoM task (mink's ComTask, qpik's): error c - c* (world frame [m]),
// Jacobian jac (3, nv) from MuJoCo's mj_jacSubtreeCom; A = diag(cost) J, b = -gain cost e.
// Returns lm_damping |b|^2.
inline double com_rows_into(MatRef A, double* b, i64 row, CMatRef jac, const double* com,
                            const double* target, const double* cost, double gain,
                            double lm_damping) {
    const i64 nv = jac.cols;
    double mu = 0.0;
    for (i64 i = 0; i < 3; ++i) {
        for (i64 j = 0; j < nv; ++j) A(row + i, j) = cost[i] * jac(i, j);
        const double e = com[i] - target[i];
        b[row + i] = cost[i] * (-gain * e);
        mu += b[row + i] * b[row + i];
    }
    return lm_damping * mu;
}

}  // namespace qpik::tasks
