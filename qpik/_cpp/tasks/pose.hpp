// qpik's world-frame pose tasks (qpik/tasks/pose.py): the rows of PositionTask (part 1),
// OrientationTask (part 2) and PoseTask (part 3) from MuJoCo's frame pose and world-aligned
// Jacobian. One routine for both paths: the compiled step (diffik/fused.hpp) and the tasks'
// own compute_qp_residual (bound in qpik._engine.tasks), so their rows are the same bits.
#pragma once

#include "../common.hpp"
#include "../model/so3.hpp"

namespace qpik::tasks {

// Which rows of a frame's pose a task regulates (bits: 1 position, 2 orientation).
enum PosePart : i64 { POSE_POSITION = 1, POSE_ORIENTATION = 2, POSE_FULL = 3 };

// The rows of part `part` (3, or 6 for POSE_FULL).
inline i64 pose_part_rows(i64 part) { return part == POSE_FULL ? 6 : 3; }

// Entries of a pose task's data: target position (3) [m], target rotation (row-major 9),
// cost (up to 6), gain, lm_damping.
constexpr i64 kPoseTarget = 12;

// The error e of `part` (3 or 6 entries: position p - p* [m], then the rotation vector
// log(R R*^T) [rad], world frame) at the frame pose (xpos, xmat row-major) with target
// (kPoseTarget entries), and, where the part has orientation rows, Jl^-1(e_rot) into jinv
// (row-major 9). Returns the row count.
inline i64 pose_error(const double* xpos, const double* xmat, const double* target, i64 part, double* error,
                      double* jinv) {
    i64 r = 0;
    if (part & POSE_POSITION) {
        for (i64 i = 0; i < 3; ++i) error[i] = xpos[i] - target[i];
        r = 3;
    }
    if (part & POSE_ORIENTATION) {
        const double* Rt = target + 3;  // R* (row-major)
        double M[9];                    // R R*^T: M(i, j) = sum_k R(i, k) R*(j, k)
        for (i64 i = 0; i < 3; ++i)
            for (i64 j = 0; j < 3; ++j) {
                double acc = 0.0;
                for (i64 k = 0; k < 3; ++k) acc += xmat[3 * i + k] * Rt[3 * j + k];
                M[3 * i + j] = acc;
            }
        model::rotation_log(M, error + r);
        model::so3_ljacinv(jinv, error + r);
        r += 3;
    }
    return r;
}

// The weighted rows of `part` at the frame pose (xpos, xmat) with world-aligned Jacobian
// jac (6, nv) and target: A rows row:row+k = diag(cost) J, J = [Jv; Jl^-1(e_rot) Jw] (the
// part's rows), b = cost * (-gain e) (pose_error's e). Returns lm_damping |b|^2.
inline double pose_rows_into(MatRef A, double* b, i64 row, CMatRef jac, const double* xpos,
                             const double* xmat, const double* target, i64 part, const double* cost,
                             double gain, double lm_damping) {
    const i64 nv = jac.cols;
    double error[6], jinv[9];
    const i64 k = pose_error(xpos, xmat, target, part, error, jinv);
    i64 r = 0;
    if (part & POSE_POSITION) {
        for (i64 i = 0; i < 3; ++i) {
            const double c = cost[i];
            double* Ai = &A(row + i, 0);
            const double* Ji = &jac(i, 0);
            for (i64 j = 0; j < nv; ++j) Ai[j] = c * Ji[j];
        }
        r = 3;
    }
    if (part & POSE_ORIENTATION) {
        const double* J0 = &jac(3, 0);
        const double* J1 = &jac(4, 0);
        const double* J2 = &jac(5, 0);
        for (i64 i = 0; i < 3; ++i) {
            const double c = cost[r + i];
            const double a0 = jinv[3 * i], a1 = jinv[3 * i + 1], a2 = jinv[3 * i + 2];
            double* Ai = &A(row + r + i, 0);
            for (i64 j = 0; j < nv; ++j) Ai[j] = c * (((0.0 + a0 * J0[j]) + a1 * J1[j]) + a2 * J2[j]);
        }
    }
    double mu = 0.0;
    for (i64 i = 0; i < k; ++i) {
        b[row + i] = cost[i] * (-gain * error[i]);
        mu += b[row + i] * b[row + i];
    }
    return lm_damping * mu;
}

}  // namespace qpik::tasks
