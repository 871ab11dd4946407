// A frame task's rows from MuJoCo's pose and world-aligned Jacobian (ported from the
// kernels of qpik/tasks/frame.py, same operations in the same order): mink's error
// log(T_fw^-1 T_tw), its jlog, and the weighted rows diag(cost) (-jlog) [R^T Jp; R^T Jr].
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "../common.hpp"
#include "../core/linalg.hpp"
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

namespace frame_detail {

// Whether every x[0..N) is finite: x * 0.0 is +-0 for a finite x and NaN otherwise, and
// their sum (from +0) compares equal to 0 exactly when every term is +-0.
// (Four sums, k mod 4, each from +0: each is +-0 exactly when its terms are all finite;
// shorter chains of dependent adds than one sum.)
template <int N>
inline bool all_finite(const double* x) {
    double acc[4] = {0.0, 0.0, 0.0, 0.0};
#pragma GCC unroll 36
    for (int k = 0; k < N; ++k) acc[k & 3] += x[k] * 0.0;
    return (acc[0] + acc[1]) + (acc[2] + acc[3]) == 0.0;
}

// Whether column j of jac (6, nv) is exactly zero (+-0 entries): every bit but the sign
// is 0 exactly for +-0 (a NaN or an infinity has exponent bits).
inline bool zero_column(CMatRef jac, i64 j) {
    std::uint64_t bits = 0;
#pragma GCC unroll 6
    for (i64 k = 0; k < 6; ++k) {
        std::uint64_t u;
        std::memcpy(&u, &jac(k, j), sizeof u);
        bits |= u;
    }
    return (bits << 1) == 0;
}

// The shape of a finite jlog (row-major 6x6): 0 general, 1 the lower-left block exactly
// zero (as se3_jlog writes it), 2 the identity exactly (se3_jlog near 0).
inline int jlog_shape(const double* jlog) {
    double low = 0.0;
#pragma GCC unroll 3
    for (int i = 3; i < 6; ++i) low += std::fabs(jlog[6 * i]) + std::fabs(jlog[6 * i + 1]) + std::fabs(jlog[6 * i + 2]);
    if (low != 0.0) return 0;
    for (int i = 0; i < 6; ++i)
        for (int k = 0; k < 6; ++k)
            if (jlog[6 * i + k] != (i == k ? 1.0 : 0.0)) return 1;
    return 2;
}

// sum_{k = K0}^{5} row[k] col[k], from +0 in order of k.
template <int K0>
inline double dot6_from(const double* row, const double* col) {
    double acc = 0.0;
#pragma GCC unroll 6
    for (int k = K0; k < 6; ++k) acc += row[k] * col[k];
    return acc;
}

}  // namespace frame_detail

// Rows row:row+6 of a frame task written into A (rows >= row + 6, nv) and b: A =
// diag(cost) (-jlog) [R^T Jp; R^T Jr], b = -gain cost e; returns lm_damping |b|^2. `jac` is
// MuJoCo's world-aligned Jacobian (6, nv), xmat the frame's rotation (row-major 9), jlog
// row-major 6x6 (36). `local` is scratch of 6 * nv doubles.
inline double frame_rows_into(MatRef A, double* b, i64 row, CMatRef jac, const double* xmat,
                              const double* jlog, const double* error, const double* cost,
                              double gain, double lm_damping, double* local) {
    using namespace frame_detail;
    const i64 nv = jac.cols;
    if (all_finite<9>(xmat) && all_finite<36>(jlog)) {
        // Column by column, each entry by the same sums as below; a column of the
        // Jacobian that is exactly zero (a dof off the frame's chain) gives local entries
        // +0 (0.0 + finite * 0, in any order) and so A entries -cost[i] * 0.0, written
        // without the sums: the same bits.
        // A column whose local entries are all finite: a term jlog[i][k] col[k] with
        // jlog[i][k] exactly zero is +-0, and acc (+0 at the start, never -0: a sum is -0
        // only of two -0) plus +-0 is acc; such terms are left out (the same bits).
        // Every row is first filled with its zero column's entry (contiguous stores), then
        // the other columns written over it.
        const int shape = jlog_shape(jlog);
        for (i64 i = 0; i < 6; ++i) {
            const core::simd::v2d zc = core::simd::splat(-cost[i] * 0.0);
            double* Ai = &A(row + i, 0);
            i64 j = 0;
            for (; j + 2 <= nv; j += 2) core::simd::store(Ai + j, zc);
            if (j < nv) Ai[j] = zc[0];
        }
        for (i64 j = 0; j < nv; ++j) {
            if (zero_column(jac, j)) continue;
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
            const bool sparse = shape != 0 && all_finite<6>(col);
            if (sparse && shape == 2) {
                for (i64 i = 0; i < 6; ++i) A(row + i, j) = -cost[i] * (0.0 + col[i]);
            } else if (sparse) {
                for (i64 i = 0; i < 3; ++i) A(row + i, j) = -cost[i] * dot6_from<0>(jlog + 6 * i, col);
                for (i64 i = 3; i < 6; ++i) A(row + i, j) = -cost[i] * dot6_from<3>(jlog + 6 * i, col);
            } else {
                for (i64 i = 0; i < 6; ++i) A(row + i, j) = -cost[i] * dot6_from<0>(jlog + 6 * i, col);
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


// relative_frame_rows_into: the round-off of a Jacobian difference, in eps of its terms' sizes.
constexpr double kRelativeCancel = 16.0;

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
    // A dof that moves both frames alike (the chain they share: a floating base, the links
    // above both) cancels in the difference to the round-off of its terms, not to zero: kept,
    // those entries (1e-15 against a row of 0.07: a finger relative to its neighbour, the base
    // dofs' lever arms of 1 m) make the task's gradient on those dofs their round-off, which
    // no move can meet (the level stays uncertified: stationarity 1.2e-9 in exact mode, erd
    // ANYmal-Kinova, Tiago, Alex). An entry within kRelativeCancel eps of its terms' sizes
    // is that round-off, and is zero.
    for (i64 i = 0; i < 6; ++i) {
        for (i64 j = 0; j < nv; ++j) {
            double acc = 0.0, size = 0.0;
            for (i64 k = 0; k < 6; ++k) {
                const double t = adj[6 * i + k] * lr[k * nv + j];
                acc += t;
                size += std::fabs(t);
            }
            const double lfij = lf[i * nv + j];
            const double dij = lfij - acc;
            size += std::fabs(lfij);
            diff[i * nv + j] = std::fabs(dij) <= kRelativeCancel * 2.220446049250313e-16 * size ? 0.0 : dij;
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
