// qpik's JointLimitDistanceTask (qpik/tasks/secondary.py): its one row from the limited
// joints. One routine for both paths: the compiled step (diffik/fused.hpp, kind JOINT_LIMITS)
// and the task's own compute_qp_residual (bound in qpik._engine.tasks), so their rows are
// the same bits.
#pragma once

#include "../common.hpp"

namespace qpik::tasks {

// The joint-limit distance w(q) = sum_k ratio_k^2 / (2 n), ratio_k = 0.5 (q_k / half_k -
// mid_k / half_k), over the limited joints in joint order: joint(k, adr, dof, half, moh)
// gives slot k's qpos address, dof, half range and mid / half, and returns false for a slot
// that is not a limited joint (skipped); k = 0..slots-1. n counts every scalar joint,
// limited or not.
template <class Joint>
inline double joint_limit_distance_value(const double* qpos, i64 slots, Joint joint, double n) {
    double sum = 0.0;
    i64 adr, dof;
    double half, moh;
    for (i64 k = 0; k < slots; ++k) {
        if (!joint(k, adr, dof, half, moh)) continue;
        const double r = 0.5 * (qpos[adr] / half - moh);
        sum += r * r;
    }
    return n > 0.0 ? sum / (2.0 * n) : 0.0;
}

// Its weighted row: A row `row` = cost dw/dq (ratio_k / (2 n) / half_k on dof_k, cost 0
// elsewhere), b = cost (-gain w). Returns lm_damping b^2; w into *value when given.
template <class Joint>
inline double joint_limit_distance_row(MatRef A, double* b, i64 row, const double* qpos, i64 slots, Joint joint,
                                       double n, double cost, double gain, double lm_damping,
                                       double* value = nullptr) {
    double* Ar = &A(row, 0);
    const double zero = cost * 0.0;
    for (i64 j = 0; j < A.cols; ++j) Ar[j] = zero;
    const double two_n = 2.0 * n;
    i64 adr, dof;
    double half, moh;
    for (i64 k = 0; k < slots; ++k) {
        if (!joint(k, adr, dof, half, moh)) continue;
        const double r = 0.5 * (qpos[adr] / half - moh);
        Ar[dof] = cost * (r / two_n / half);
    }
    const double w = joint_limit_distance_value(qpos, slots, joint, n);
    if (value) *value = w;
    b[row] = cost * (-gain * w);
    return lm_damping * (b[row] * b[row]);
}

}  // namespace qpik::tasks
