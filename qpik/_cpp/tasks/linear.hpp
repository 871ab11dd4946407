// A task linear in the configuration (qpik's CouplingTask of linear couplings: a URDF
// mimic, a joint or fixed-tendon equality of degree 1): residual r(q) = C q - offset over
// qpos, constant Jacobian J (nv columns). One summation order, shared by the compiled step
// (diffik/fused.hpp) and the task's own compute_error (qpik.tasks.coupling), so the two
// paths agree bit for bit.
#pragma once

#include "../common.hpp"

namespace qpik::tasks {

// r_i = sum_t form(i, t) q[t] - form(i, nq) (t = 0 .. nq - 1, in that order) into r (k);
// form (k, nq + 1): the coefficients over qpos, then the offset.
inline void linear_residual(CMatRef form, const double* qpos, double* r) {
    const i64 nq = form.cols - 1;
    for (i64 i = 0; i < form.rows; ++i) {
        const double* c = form.row(i);
        double s = 0.0;
        for (i64 t = 0; t < nq; ++t) s += c[t] * qpos[t];
        r[i] = s - c[nq];
    }
}

// Rows row:row+k of a linear task, weighted as mink weights any task: A = diag(cost) J,
// b = cost (-gain r), r by linear_residual; returns lm_damping |b|^2. jac (k, nv) the
// constant Jacobian, form (k, nq + 1), cost (k,), r (k) scratch.
inline double linear_rows_into(MatRef A, double* b, i64 row, CMatRef jac, CMatRef form,
                               const double* qpos, const double* cost, double gain,
                               double lm_damping, double* r) {
    const i64 k = jac.rows, nv = jac.cols;
    linear_residual(form, qpos, r);
    double mu = 0.0;
    for (i64 i = 0; i < k; ++i) {
        const double* ji = jac.row(i);
        for (i64 j = 0; j < nv; ++j) A(row + i, j) = cost[i] * ji[j];
        b[row + i] = cost[i] * (-gain * r[i]);
        mu += b[row + i] * b[row + i];
    }
    return lm_damping * mu;
}

}  // namespace qpik::tasks
