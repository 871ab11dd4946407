// mink's EqualityConstraintTask (and qpik's): its rows are MuJoCo's equality constraint rows
// as mj_makeConstraint leaves them in the MjData (efc_type mjCNSTR_EQUALITY, efc_id the
// equality's id; efc_pos the residual, efc_J the Jacobian, dense or sparse), in efc order,
// for the equalities the task regulates; each weighted as mink weights any task: A = cost J,
// b = cost (-gain efc_pos), the LM term lm_damping |b|^2 (its squares summed in order), the
// cost of a row its equality's (mink's _cost by the equality's position in the task). One
// routine for the compiled step (diffik/fused.hpp) and the task's rows on the QP path
// (qpik.diffik.rows), so the two agree bit for bit.
#pragma once

#include <cstdint>

#include "../common.hpp"

namespace qpik::tasks {

constexpr std::int32_t kEqualityConstraint = 0;  // mjCNSTR_EQUALITY

// The MjData's constraint rows (views; sizes checked by the caller: J nefc * nv dense, or
// rownnz / rowadr (nefc) and colind (the length of J) with every column in [0, nv)).
struct EfcRows {
    i64 nefc = 0;
    i64 nv = 0;
    bool sparse = false;
    const double* J = nullptr;
    const double* pos = nullptr;
    const std::int32_t* type = nullptr;
    const std::int32_t* id = nullptr;
    const std::int32_t* rownnz = nullptr;
    const std::int32_t* rowadr = nullptr;
    const std::int32_t* colind = nullptr;
};

// The task's rows into rows row:row+k of A and b, their costs into w (k returned; at most
// max_rows written, -1 where more rows belong to the task): position[e] is the task's
// position of equality e (neq entries, -1: not the task's), cost[position] its cost. mu
// receives lm |b|^2.
inline i64 equality_rows_into(MatRef A, double* b, double* w, i64 row, i64 max_rows, const EfcRows& efc,
                              const i64* position, i64 neq, const double* cost, double gain, double lm, double& mu) {
    const i64 n = efc.nv;
    i64 k = 0;
    double sq = 0.0;
    for (i64 r = 0; r < efc.nefc; ++r) {
        if (efc.type[r] != kEqualityConstraint) continue;
        const i64 e = efc.id[r];
        if (e < 0 || e >= neq || position[e] < 0) continue;
        if (k == max_rows) return -1;
        const double c = cost[position[e]];
        double* ar = A.row(row + k);
        if (efc.sparse) {
            for (i64 j = 0; j < n; ++j) ar[j] = c * 0.0;
            const i64 adr = efc.rowadr[r];
            for (i64 t = 0; t < efc.rownnz[r]; ++t) ar[efc.colind[adr + t]] = c * efc.J[adr + t];
        } else {
            const double* jr = efc.J + r * n;
            for (i64 j = 0; j < n; ++j) ar[j] = c * jr[j];
        }
        b[row + k] = c * (-gain * efc.pos[r]);
        w[row + k] = c;
        sq += b[row + k] * b[row + k];
        ++k;
    }
    mu = lm * sq;
    return k;
}

}  // namespace qpik::tasks
